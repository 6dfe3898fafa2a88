"""``generate_dataset(ranges=)`` (``hcmt generate impact-plate --range NAME=LO:HI``): a sampled parameter's range
replaced in the train, valid and test splits, the same draws mapped onto it; the variant splits keep their own
ranges; meta.json records the override; a dataset is only resumed with the same ranges."""

from __future__ import annotations

import json
from dataclasses import asdict

import numpy as np
import pytest

import hcmt
import hcmt.sim.generate as gen
import hcmt.sim.writer as writer
from hcmt.data.format import open_split
from hcmt.errors import InputError
from hcmt.sim.sampling import RANGES, VARIANTS, checked_ranges, family_ranges, sample_design

NARROW = {"thickness": (1.2, 1.25)}  # outside the small preset's 0.5-1.0: a draw inside it is the override's
TINY = hcmt.Settings(frames=4)


def fraction(value: float, span: tuple[float, float]) -> float:
    return (value - span[0]) / (span[1] - span[0])


@pytest.mark.parametrize("seed", range(6))
def test_an_override_maps_the_same_draw_onto_its_range_and_leaves_the_rest(seed):
    base = sample_design(np.random.default_rng(seed), "small")
    over = sample_design(np.random.default_rng(seed), "small", override=NARROW)
    lo, hi = NARROW["thickness"]
    assert lo <= over.thickness <= hi and not lo <= base.thickness <= hi
    # the same uniform draw, mapped onto the new range
    assert fraction(over.thickness, NARROW["thickness"]) == pytest.approx(
        fraction(base.thickness, RANGES["small"]["thickness"]), abs=1e-9
    )
    changed = {k for k, v in asdict(over).items() if v != asdict(base)[k]}
    assert changed == {"thickness"}  # every other parameter: the same stream, the same values


def test_an_override_of_the_edge_parameter_moves_the_edge_draws_with_it():
    """edge_fraction's thin plates lie in the lowest fifth of the overridden thickness range, not the preset's."""
    lo, hi = NARROW["thickness"]
    designs = [sample_design(np.random.default_rng(s), "small", edge_fraction=1.0, override=NARROW) for s in range(40)]
    thin = [
        d.thickness
        for d in designs
        if d.drop_height < RANGES["small"]["drop_height"][0] + 0.8 * np.diff(RANGES["small"]["drop_height"])[0]
    ]
    assert thin and all(lo <= t <= lo + 0.2 * (hi - lo) + 1e-12 for t in thin)
    assert all(lo <= d.thickness <= hi for d in designs)


@pytest.mark.parametrize("variant", [v for v in VARIANTS if "thickness" in VARIANTS[v]])
def test_a_variant_keeps_its_own_range(variant):
    lo, hi = VARIANTS[variant]["thickness"]
    assert family_ranges("small", variant=variant, override=NARROW)["thickness"] == (lo, hi)
    for seed in range(6):
        plain = sample_design(np.random.default_rng(seed), "small", variant)
        over = sample_design(np.random.default_rng(seed), "small", variant, override=NARROW)
        assert lo <= over.thickness <= hi and over.thickness == plain.thickness
        assert over == plain


def test_an_override_applies_beside_a_variant_to_the_parameters_it_leaves():
    """test_thicker replaces thickness alone: an overridden drop height follows the override there too (the
    variant split differs from the training ones in the variant's parameter, not in the others)."""
    span = (600.0, 650.0)
    for seed in range(6):
        d = sample_design(np.random.default_rng(seed), "small", "test_thicker", override={"drop_height": span})
        assert span[0] <= d.drop_height <= span[1]
        assert VARIANTS["test_thicker"]["thickness"][0] <= d.thickness <= VARIANTS["test_thicker"]["thickness"][1]


def test_family_parameters_can_be_overridden_only_where_every_family_samples_them():
    span = {"layer2_thickness": (0.12, 0.14)}
    assert checked_ranges("small", ("stack2",), span) == span
    assert family_ranges("small", "stack2", override=span)["layer2_thickness"] == span["layer2_thickness"]
    with pytest.raises(InputError, match="layer2_thickness is not a sampled parameter .* mono family") as e:
        checked_ranges("small", ("stack2", "mono"), span)
    assert e.value.param == "range"


@pytest.mark.parametrize(
    "ranges, words",
    [
        ({"foo": (1.0, 2.0)}, "foo is not a sampled parameter"),
        ({"thickness": (1.0, 0.5)}, "low <= high"),
        ({"thickness": (float("nan"), 1.0)}, "finite"),
        ({"drop_height": (500.0, float("inf"))}, "finite"),
        ({"thickness": (0.5,)}, "expected \\(low, high\\)"),
        ({"thickness": (0.01, 1.0)}, "mesh_size .* must not exceed thickness"),
        ({"plate_half_length": (2.0, 12.0)}, "plate_half_length .* must exceed the ball_radius"),
    ],
)
def test_bad_ranges_are_refused_before_anything_is_written(tmp_path, ranges, words, monkeypatch):
    monkeypatch.setattr(writer, "_run_one", lambda task: pytest.fail("work started"))
    with pytest.raises(InputError, match=words) as e:
        gen.generate_dataset(
            tmp_path / "d", preset="small", counts={"train": 1}, settings=TINY, progress=False, ranges=ranges
        )
    assert e.value.param == "range" and "\n" not in str(e.value)
    assert not (tmp_path / "d").exists()


def test_a_dataset_without_overrides_keeps_its_meta():
    """No ranges (or empty ones): meta.json as before the option, so older datasets still resume."""
    plain = gen.dataset_meta("small", 0, {"train": 1}, TINY)
    assert gen.dataset_meta("small", 0, {"train": 1}, TINY, ranges={}) == plain
    assert "range_overrides" not in plain["generator"]
    assert plain["generator"]["ranges"] == {k: list(v) for k, v in RANGES["small"].items()}


def test_generated_data_lies_in_the_overridden_range_and_meta_records_it(tmp_path):
    out, counts, seed = tmp_path / "d", {"train": 2, "test": 1, "test_thicker": 1}, 5
    gen.generate_dataset(out, preset="small", counts=counts, seed=seed, settings=TINY, progress=False, ranges=NARROW)
    generator = json.loads((out / "meta.json").read_text())["generator"]
    assert generator["range_overrides"] == {k: list(v) for k, v in NARROW.items()}
    assert generator["ranges"] == {k: list(NARROW.get(k, v)) for k, v in RANGES["small"].items()}
    lo, hi = NARROW["thickness"]
    for split in ("train", "test"):
        data = open_split(out, split)
        for i in range(counts[split]):
            attrs = data.attrs(i)
            assert lo <= attrs["thickness"] <= hi, (split, i, attrs["thickness"])
            drawn = sample_design(writer.trajectory_rng(seed, split, i), "small", override=NARROW)
            assert attrs["thickness"] == pytest.approx(drawn.thickness)
            assert attrs["drop_height"] == pytest.approx(drawn.drop_height)
    vlo, vhi = VARIANTS["test_thicker"]["thickness"]
    assert vlo <= open_split(out, "test_thicker").attrs(0)["thickness"] <= vhi  # the variant keeps its range

    # resuming the folder: the same ranges reuse everything; other ranges (or none) are refused, nothing changed
    files = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert (
        gen.generate_dataset(
            out, preset="small", counts=counts, seed=seed, settings=TINY, progress=False, ranges=NARROW
        )["simulated"]
        == 0
    )
    for other, words in (
        (
            {"thickness": (1.2, 1.3)},
            r"range_overrides.thickness \[1.2, 1.25\] there, "
            r"\[1.2, 1.3\] asked",
        ),
        (None, r"range_overrides \{'thickness': \[1.2, 1.25\]\} there, None asked"),
    ):
        with pytest.raises(InputError, match=words):
            gen.generate_dataset(
                out, preset="small", counts=counts, seed=seed, settings=TINY, progress=False, ranges=other
            )
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == files
