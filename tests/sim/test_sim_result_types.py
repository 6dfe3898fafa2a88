"""The solver's result and the Impact Plate quantities read off it are real types: on a real solve (a ball impact
over a short window), every field of :class:`hcmt.sim.driver.SimResult` (its :class:`SolveInfo` included) and of
:class:`hcmt.inference.quantities.ImpactQuantities` holds the type it declares (Python floats, not numpy scalars)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from hcmt.inference.quantities import impact_summary, plate_mask
from hcmt.sim.driver import simulate
from hcmt.sim.params import Design, Settings
from summaries import type_errors


def test_a_real_solve_and_its_quantities_hold_their_declared_types():
    settings = Settings(frames=12)
    r = simulate(Design(drop_height=30.0), settings)
    assert type_errors(r) == []
    assert r.fields["world_pos"].shape[0] == 12 and r.info.substeps > 0
    f = r.fields
    q = impact_summary(
        f["world_pos"], f["stress"], f["mesh_pos"], plate_mask(f["cells"], f["node_type"]), settings.frame_dt
    )
    assert type_errors(q) == []
    assert q.peak_plate_stress_mpa == float(np.max(f["stress"][:, plate_mask(f["cells"], f["node_type"])]))


def test_the_check_sees_a_numpy_scalar_where_a_float_is_declared():
    """The test above can fail: the solve's info with a numpy float for its wall time is named."""
    r = simulate(Design(drop_height=30.0), Settings(frames=3))
    bad = replace(r, info=replace(r.info, wall_time=np.float64(r.info.wall_time)))
    assert any("SolveInfo.wall_time" in e for e in type_errors(bad))
