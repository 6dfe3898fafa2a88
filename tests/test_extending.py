"""The extension points of docs/extending.md: each step of adding a model, a panel family, a dataset or a
design-check quantity is checked here, so that a step left out fails a test instead of passing silently. And the
panel families' scenes and trajectories equal a direct construction from the design's fields."""

from __future__ import annotations

import inspect
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest

from hcmt.config import DATASET_NAMES, MODELS, ModelConfig, load_config
from hcmt.design.basics import QUANTITIES, value_problem
from hcmt.design.surrogate import ANSWER_UNITS
from hcmt.domains.adapters import ADAPTERS
from hcmt.domains.spec import dataset_spec
from hcmt.inference.quantities import ImpactQuantities
from hcmt.models import REGISTRY, build_model
from hcmt.models.attention import AttentionTap, recording
from hcmt.models.registry import REGISTRY as REGISTERED
from hcmt.sim.contact import PenaltyContact
from hcmt.sim.driver import simulate
from hcmt.sim.explicit import CentralDifference
from hcmt.sim.families import FEATURES, Feature
from hcmt.sim.mesh import impact_plate_mesh
from hcmt.sim.params import (
    BACKING_DENSITY,
    BACKING_POISSON,
    DESIGN_KEYS,
    DESIGN_UNITS,
    FAMILIES,
    FIRST_SCENE_KEYS,
    Settings,
    value_rules,
)
from hcmt.sim.sampling import sample_design
from hcmt.sim.scene import cell_materials, design_mesh, fixed_dofs, static_fields
from hcmt.sim.solver import build_model as fem, nodal_von_mises, stable_time_step

CONFIGS = Path(__file__).resolve().parents[1] / "src" / "hcmt" / "configs"


# -- a model -------------------------------------------------------------------------------------------------------
def test_every_model_name_is_registered_once():
    """hcmt.config.MODELS (what a config may name) and the models that registered themselves are the same."""
    assert set(MODELS) == set(REGISTRY) == set(REGISTERED)


@pytest.mark.parametrize("name", MODELS)
def test_a_registered_model_declares_builder_settings_and_every_attention_tap(name):
    info = REGISTRY[name]
    assert info.builder is not None and info.builder.model_name == name
    params = inspect.signature(info.builder.__init__).parameters
    assert set(info.arguments) <= set(params), "a declared argument the builder does not take"
    assert set(info.settings) <= {f.name for f in fields(ModelConfig)}, "a setting that is no model.* config key"
    model = build_model(name, 12, 7, 3, 3, hidden=16, heads=2, blocks=2, levels=1, L_C=1)
    taps = model.attention_taps()
    modules = [m for m in model.modules() if isinstance(m, AttentionTap)]
    assert {id(s.tap) for s in taps} == {id(m) for m in modules}, "an attention tap the model does not declare"
    assert info.has_attention == bool(taps)
    assert len({s.name for s in taps}) == len(taps)


def test_recording_refuses_a_tap_the_model_does_not_declare():
    model = build_model("mgn", 12, 7, 3, 3, hidden=16, blocks=1)
    model.extra = AttentionTap()
    with pytest.raises(RuntimeError, match="extra"), recording(model):
        pass


# -- a panel family ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("feature", FEATURES, ids=lambda f: f.name)
def test_a_family_feature_defines_its_rules_checks_mesh_scene_and_cost(feature):
    for method in ("rules", "check", "mesh", "scene", "cost"):
        assert getattr(type(feature), method) is not getattr(Feature, method), f"{feature.name} lacks {method}"
    assert feature.switch in feature.fields and set(feature.switches) <= set(feature.fields)
    for key in feature.fields:  # new design fields come after the first scene's, each with its unit
        assert DESIGN_KEYS.index(key) >= FIRST_SCENE_KEYS and key in DESIGN_UNITS
    assert feature.families and all(FAMILIES[name] is ranges for name, ranges in feature.families.items())


def test_every_field_after_the_first_scene_belongs_to_one_feature():
    owned = [key for f in FEATURES for key in f.fields]
    assert sorted(owned) == sorted(DESIGN_KEYS[FIRST_SCENE_KEYS:]) and len(set(owned)) == len(owned)
    assert list(FAMILIES) == ["mono", *(name for f in FEATURES for name in f.families)]


@pytest.mark.parametrize("feature", FEATURES, ids=lambda f: f.name)
def test_every_field_of_a_family_has_its_value_rule(feature):
    """Each field a feature owns has a value rule once its values turn it on (a switch alone, even off), as every
    field of the first scene has: Design.validate and a designs CSV's first checks refuse by these rules alone."""
    on = dict.fromkeys(feature.switches, 1.0)
    assert sorted(rule.param for rule in feature.rules({})) == sorted(feature.switches)
    assert {rule.param for rule in feature.rules(on)} == set(feature.fields), "a field without its rule"
    assert {rule.param for rule in value_rules(on)} >= set(feature.fields)
    assert {rule.param for rule in value_rules({})} >= set(DESIGN_KEYS[:FIRST_SCENE_KEYS])
    for key in feature.fields:  # the design check's first checks read them: a negative value is refused
        assert value_problem({**on, key: -1.0})[0] == key


@pytest.mark.parametrize("switch", [s for f in FEATURES for s in f.switches])
def test_a_designs_file_refuses_a_negative_family_size_before_a_model_loads(switch):
    """hcmt.design.basics' early checks of a designs CSV know every feature's size fields."""
    assert value_problem({switch: -1.0}) is not None


def designs() -> dict:
    """One drawn design of each named family, and the combinations the families allow."""
    out = {f: sample_design(np.random.default_rng(7), "small", family=f) for f in FAMILIES}
    out["stack3+pen"] = replace(out["stack3"], pen_tip_radius=0.8, pen_mass=2.0)
    out["stack2+backing"] = replace(out["stack2"], backing_thickness=1.5, backing_modulus=20.0)
    out["stack2+ring"] = replace(out["stack2"], support_radius=8.0)
    return out


DESIGNS = designs()


@pytest.mark.parametrize("family", DESIGNS)
def test_a_drawn_design_is_of_its_family(family):
    assert DESIGNS[family].validate().family == family


def direct_scene(d) -> tuple[dict, np.ndarray]:
    """The mesh and the cells' (density, modulus, Poisson) written out from the design's fields alone."""
    pen = d.pen_tip_radius > 0
    panel = [(d.thickness, d.plate_density, d.plate_modulus, d.plate_poisson)] + [
        tuple(getattr(d, f"layer{k}_{m}") for m in ("thickness", "density", "modulus", "poisson"))
        for k in (2, 3, 4)
        if getattr(d, f"layer{k}_thickness") > 0
    ]
    mesh = impact_plate_mesh(
        d.thickness,
        d.pen_tip_radius if pen else d.ball_radius,
        d.mesh_size,
        plate_half_length=d.plate_half_length,
        gap=d.gap,
        layers=[p[0] for p in panel],
        support_radius=d.support_radius,
        backing_thickness=d.backing_thickness,
        impactor="pen" if pen else "ball",
    )
    backing = [(BACKING_DENSITY, d.backing_modulus, BACKING_POISSON)] if d.backing_thickness > 0 else []
    table = np.array([p[1:] for p in panel] + backing + [(d.ball_density, d.ball_modulus, d.ball_poisson)])
    return mesh, table[mesh["cell_layer"]]


@pytest.mark.parametrize("family", DESIGNS)
def test_a_familys_scene_equals_its_direct_construction(family):
    d = DESIGNS[family]
    mesh, materials = direct_scene(d)
    built = design_mesh(d)
    assert built.keys() == mesh.keys() and all(np.array_equal(built[k], mesh[k]) for k in mesh)
    assert np.array_equal(np.stack(cell_materials(d, built), 1), materials)
    density = static_fields(d, built)["density"][:, 0]
    tip = mesh["body"] == 1
    if d.pen_tip_radius > 0:  # the whole pen's mass over the revolved tip's volume
        p = mesh["mesh_pos"][mesh["cells"][mesh["cell_body"] == 1]]
        (ax, ay), (bx, by) = (p[:, 1] - p[:, 0]).T, (p[:, 2] - p[:, 0]).T
        area = 0.5 * np.abs(ax * by - ay * bx)
        volume = np.sum(2 * np.pi * p[:, :, 0].mean(1) * area)
        np.testing.assert_allclose(density[tip], d.ball_density + d.pen_mass / volume, rtol=1e-6)
    else:
        assert np.all(density[tip] == np.float32(d.ball_density))


@pytest.mark.parametrize("family", DESIGNS)
def test_a_familys_trajectory_equals_a_solve_built_by_hand(family):
    """simulate() bit for bit against the solver started directly from the written-out scene (same steps)."""
    d, settings = DESIGNS[family], Settings(frames=5)
    mesh, m = direct_scene(d)
    X = mesh["mesh_pos"]
    model = fem(
        X,
        mesh["cells"],
        m[:, 0],
        m[:, 1],
        m[:, 2],
        formulation=settings.formulation,
        bulk_viscosity=settings.bulk_viscosity,
    )
    substeps = int(np.ceil(settings.frame_dt / stable_time_step(model, settings.safety)))
    dt = settings.frame_dt / substeps
    sim = CentralDifference(
        model,
        fixed_dofs(mesh["node_type"]),
        dt,
        gravity=settings.gravity,
        contact=PenaltyContact(X, mesh["cells"], mesh["body"], model.mass, dt, alpha=settings.penalty),
        rigid=(mesh["rigid"], d.pen_mass),
    )
    v0 = np.zeros_like(X)
    v0[mesh["body"] == 1, 1] = -np.sqrt(2 * settings.gravity * d.drop_height)
    sim.start(X, v0)
    frames, stress = [], []
    for k in range(settings.frames):
        if k:
            sim.step(substeps)
        frames.append(sim.x.astype(np.float32))
        stress.append(nodal_von_mises(model, sim.x).astype(np.float32))
    out = simulate(d, settings).fields
    assert np.array_equal(out["world_pos"], np.stack(frames))
    assert np.array_equal(out["stress"][..., 0], np.stack(stress))


# -- a dataset -----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", DATASET_NAMES)
def test_a_dataset_has_an_adapter_and_its_configs(name):
    assert name in ADAPTERS and ADAPTERS[name].name == name
    assert (CONFIGS / f"{name}.yaml").is_file() and (CONFIGS / f"{name}_cpu.yaml").is_file()
    assert load_config(name).dataset == name
    assert dataset_spec(name)["node_in"] > 0


def test_every_adapter_is_a_dataset():
    assert set(ADAPTERS) == set(DATASET_NAMES)


# -- a design-check quantity ---------------------------------------------------------------------------------------
SUFFIX_UNITS = {"mpa": "MPa", "mm": "mm", "ms": "ms"}


@pytest.mark.parametrize("quantity", QUANTITIES)
def test_a_design_check_quantity_has_a_json_key_and_a_unit(quantity):
    assert quantity in {f.name for f in fields(ImpactQuantities)}, "no key in the design check's JSON"
    assert ANSWER_UNITS.get(quantity) == SUFFIX_UNITS[quantity.rsplit("_", 1)[1]], "no unit, or not its name's"


def test_every_answer_unit_is_a_quantity():
    assert set(ANSWER_UNITS) == set(QUANTITIES)
