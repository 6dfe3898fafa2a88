"""A surrogate, a model and a dataset that do not fit each other : the surrogate file records its
training data (format 2), one that differs from the model (frame window, frame interval, family, stress field,
units, parameter ranges, held values) is refused where they meet in one line naming it, one whose window is not
known to be the model's never ends the model's read-out window, and format 1 files (the shipped one) still load."""

import json
import random
import shutil

import numpy as np
import pytest

import hcmt.design.check as check_module
from hcmt.cli import main as cli
from hcmt.data.runs import PRETRAINED_DIR
from hcmt.design.check import check_designs
from hcmt.design.inputs import design_for
from hcmt.design.surrogate import Surrogate, SurrogateError, dataset_facts
from hcmt.design.surrogate_use import for_run
from hcmt.inference.run import Run

SHIPPED = PRETRAINED_DIR / "impact_plate_small.surrogate.json"


@pytest.fixture(scope="module")
def run():
    return Run.load("pretrained:impact_plate_small", "cpu")


def fitting(run) -> dict:
    """The shipped surrogate as a format 2 file whose recorded data is the model's own."""
    doc = json.loads(SHIPPED.read_text())
    doc["version"] = 2
    doc["dataset"] = dataset_facts(run.meta, "train", "stress", doc["answers"])
    return doc


def format1(doc: dict) -> dict:
    """A version 1 file of the same response surface: no ``dataset`` block (the shipped file of 2026-11 was one)."""
    old = {k: v for k, v in doc.items() if k != "dataset"}
    old["version"] = 1
    return old


def _drop_parameter(doc: dict, name: str = "mesh_size") -> None:
    j = doc["parameters"].index(name)
    doc["parameters"].pop(j)
    doc["fixed"][name] = doc["designs"][0][j]
    for row in doc["designs"]:
        row.pop(j)
    for k in doc["kernels"].values():
        k["length_scales"].pop(j)


def _narrow(doc: dict, name: str = "thickness") -> None:
    j = doc["parameters"].index(name)
    for row in doc["designs"]:
        row[j] *= 0.9  # the top of the range falls below the model's


#: a way a surrogate can differ from the model -> (how, a word its refusal names)
MISFITS = {
    "frames": (lambda d: d["dataset"].update(frames=10), "10 frames"),
    "frame interval": (lambda d: d["dataset"].update(frame_dt_ms=0.004), "0.004 ms"),
    "stress field": (lambda d: d["dataset"].update(stress_field="stress_max"), "stress_max"),
    "family": (lambda d: d["dataset"].update(families=["stack2"]), "families"),
    "design unit": (lambda d: d["dataset"]["units"].update(thickness="m"), "thickness in m"),
    "answer unit": (lambda d: d["dataset"]["answer_units"].update(peak_plate_stress_mpa="Pa"), "units"),
    "narrower range": (_narrow, "thickness"),
    "held value": (lambda d: d["fixed"].update(plate_half_length=10.0), "plate_half_length"),
    "other parameters": (_drop_parameter, "surrogate takes"),
}


def write(tmp_path, doc: dict, name: str = "s.json"):
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def test_a_fitting_surrogate_ends_the_window_and_old_files_still_load(run, tmp_path):
    doc = fitting(run)
    s, note, ends = for_run(run, write(tmp_path, doc))
    assert note is None and ends and s.dataset["frames"] == 90
    assert 0 < s.censored == doc["dataset"]["censored"] < len(s)  # some thick plates still on at the window's end
    old = write(tmp_path, format1(doc), "v1.json")
    assert Surrogate.load(old).dataset is None  # format 1: no dataset block, loads
    s1, note1, ends1 = for_run(run, old)  # format 1 given as a file: its window is not known
    assert not ends1 and "records no training window" in note1 and len(s1) == len(doc["designs"])
    assert for_run(run, True)[2]  # the model's own file is its window's


@pytest.mark.parametrize("kind", sorted(MISFITS))
def test_a_surrogate_that_does_not_fit_the_model_is_refused_in_one_line(run, tmp_path, kind):
    doc = fitting(run)
    change, word = MISFITS[kind]
    change(doc)
    path = write(tmp_path, doc)
    with pytest.raises(SurrogateError) as e:
        for_run(run, path)
    msg = str(e.value)
    assert e.value.param == "surrogate" and str(path) in msg and word in msg, msg
    assert "\n" not in msg and len(e.value.worded("--surrogate")) <= 300


@pytest.mark.parametrize("seed", range(12))
def test_fuzz_combinations_of_misfits_are_all_refused(run, tmp_path, seed):
    rnd = random.Random(seed)
    kinds = rnd.sample(sorted(MISFITS), rnd.randint(1, 4))
    doc = fitting(run)
    for k in kinds:
        MISFITS[k][0](doc)
    with pytest.raises(SurrogateError, match="does not fit the model|surrogate takes") as e:
        for_run(run, write(tmp_path, doc))
    assert "\n" not in str(e.value) and len(e.value.worded("--surrogate")) <= 300, kinds


@pytest.mark.parametrize(
    "damage",
    [
        {"frames": "ten"},
        {"frames": 1},
        {"frame_dt_ms": -1},
        {"censored": -2},
        {"families": 3},
        {"stress_field": None, "frames": None},
        "drop frames",
    ],
)
def test_a_damaged_dataset_block_is_one_line(run, tmp_path, damage):
    doc = fitting(run)
    if damage == "drop frames":
        del doc["dataset"]["frames"]
    else:
        doc["dataset"].update(damage)
    path = write(tmp_path, doc)
    with pytest.raises(SurrogateError, match='"dataset" block') as e:
        Surrogate.load(path)
    assert str(path) in str(e.value) and "\n" not in str(e.value)


def test_a_window_that_never_saw_the_ball_leave_is_not_used(run, tmp_path, monkeypatch):
    """Every training run censored: its bound is the window's end, not the ball's; the check hands the read-out no
    bound (the model's own window stands), and a fitting file hands it the lower bounds."""
    designs = [("a", design_for(run)), ("b", design_for(run, thickness=0.95))]
    seen = []

    class Stop(Exception):
        pass

    def spy(run_, designs_, **kw):
        seen.append(kw["contact_end_ms"])
        raise Stop

    monkeypatch.setattr(check_module, "predict_chunks", spy)
    doc = fitting(run)
    for name, censored in (("fits.json", doc["dataset"]["censored"]), ("never.json", len(doc["designs"]))):
        doc["dataset"]["censored"] = censored
        with pytest.raises(Stop):
            check_designs(run, designs, progress=False, surrogate=write(tmp_path, doc, name), readout="contact")
    with pytest.raises(Stop):  # format 1 as a file
        check_designs(
            run, designs, progress=False, surrogate=write(tmp_path, format1(doc), "v1.json"), readout="contact"
        )
    lo = [iv["contact_end_ms"].lo for iv in Surrogate.load(SHIPPED).predict([d for _, d in designs])]
    assert seen[0] == pytest.approx(lo) and seen[1] is None and seen[2] is None
    assert "did the ball leave" in for_run(run, tmp_path / "never.json")[1]


@pytest.mark.slow
def test_predict_refuses_a_short_window_surrogate_before_any_answer(run, tmp_path, capsys):
    """The case that started it: a surrogate fitted on 10 frames beside a 90-frame model: one line naming --surrogate
    and the window, exit 2, no JSON written (before: the model's peak fell from 748 to 320 MPa and the call passed)."""
    doc = fitting(run)
    doc["dataset"].update(frames=10, censored=len(doc["designs"]))
    path, out = write(tmp_path, doc), tmp_path / "p.json"
    rc = cli(
        [
            "predict",
            "pretrained:impact_plate_small",
            "--design",
            "thickness=0.7",
            "--surrogate",
            str(path),
            "--yield-mpa",
            "500",
            "--json",
            str(out),
            "--no-progress",
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith(f"hcmt predict: error: --surrogate {path}: "), err
    assert "10 frames" in err[0] and "90 frames" in err[0] and len(err[0]) <= 300 and not out.exists()


@pytest.mark.slow
def test_fit_records_its_data_and_warns_of_a_window_that_ends_before_the_ball_leaves(impact_data, tmp_path, capsys):
    data = tmp_path / "data"
    shutil.copytree(impact_data, data)
    out = tmp_path / "s.json"
    assert cli(["surrogate", "fit", str(data), "--out", str(out), "--restarts", "0"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "warning" in err[0] and "before the ball leaves" in err[0] and "--frames" in err[0]
    facts = json.loads(out.read_text())["dataset"]
    meta = json.loads((data / "meta.json").read_text())
    assert facts["frames"] == meta["generator"]["settings"]["frames"] and facts["censored"] == facts["runs"] == 12
    assert facts["families"] == ["mono"] and facts["stress_field"] == "stress" and facts["units"]["thickness"] == "mm"
    assert np.isclose(facts["frame_dt_ms"], meta["dt"])
