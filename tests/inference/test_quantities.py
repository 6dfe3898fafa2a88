"""Each Impact Plate quantity (hcmt.inference.quantities) on a hand-made trajectory whose answers are known, and
the metrics that compare model and solver reading them the same way."""

import numpy as np
import pytest

from hcmt.errors import InputError
from hcmt.inference import quantities as q
from hcmt.inference.physics import impact_metrics
from impact_trajectory import DT, GAP, T, trajectory


def test_bodies_and_groups():
    x, stress, rest, cells, node_type = trajectory()
    plate = q.plate_mask(cells, node_type)
    np.testing.assert_array_equal(plate, [1, 1, 1, 1, 0, 0, 0])
    g = q.impact_groups(rest, plate)
    np.testing.assert_array_equal(np.flatnonzero(g["far"]), [1, 3])  # r = 2 > half the radius
    np.testing.assert_array_equal(np.flatnonzero(g["contact"]), [0, 2])


def test_peaks_where_and_when_over_every_frame():
    x, stress, rest, cells, node_type = trajectory()
    plate = q.plate_mask(cells, node_type)
    assert q.peak(stress, plate) == (650.0, 8, 2)  # every frame: the ghost is the peak
    assert q.peak(stress, ~plate) == (900.0, 4, 5)
    window = q.contact_window(q.contact_gap(x, rest, plate))
    assert q.peak(stress, plate, window) == (500.0, 4, 0)  # only when asked for a frame subset
    f = q.peak_fields(stress, plate, x, DT, "plate")
    assert f["peak_plate_where_mm"] == [0.0, -0.5] and f["peak_plate_when_ms"] == pytest.approx(8 * DT)
    with pytest.raises(InputError):
        q.peak(stress, plate, np.zeros(T, bool))


def test_history_rise_time_and_ghost_ratio():
    x, stress, rest, cells, node_type = trajectory()
    plate = q.plate_mask(cells, node_type)
    h = q.body_history(stress, plate)
    np.testing.assert_array_equal(h, [0, 0, 200, 400, 500, 300, 0, 0, 650, 650, 650, 650])
    assert q.rise_frame(h, 650.0) == 8  # first frame >= 617.5
    assert q.rise_frame(h, 500.0) == 4  # first frame >= 475
    assert q.rise_frame(h, 500.0, share=0.75) == 3  # >= 375
    assert q.ghost_ratio(h, 650.0) == pytest.approx((200 + 400 + 500 + 300 + 4 * 650) / 10 / 650)
    assert q.ghost_ratio(h, 650.0, last=4) == 1.0
    assert np.isnan(q.ghost_ratio(h, 0.0))


def test_deflection_maximum_and_far_field():
    x, stress, rest, cells, node_type = trajectory()
    plate = q.plate_mask(cells, node_type)
    u = q.deflection(x, rest, plate)
    assert u.shape == (T, 4) and u[4, 0] == pytest.approx(-0.06)
    assert q.max_deflection(x, rest, plate) == pytest.approx(0.06)
    assert q.far_deflection(x, rest, plate) == pytest.approx(0.01)


def test_contact_window_end_and_rebound():
    x, stress, rest, cells, node_type = trajectory()
    plate = q.plate_mask(cells, node_type)
    gap = q.contact_gap(x, rest, plate)
    np.testing.assert_allclose(gap, GAP, atol=1e-12)
    assert q.contact_frames(gap) == [2, 5]
    np.testing.assert_array_equal(np.flatnonzero(q.contact_window(gap)), [2, 3, 4, 5, 6])  # grace: one frame
    assert q.contact_end_frame(gap) == 6
    assert q.contact_frames(GAP + 1) is None and not q.contact_window(GAP + 1).any()
    assert q.rebounds(x, plate) and q.ball_vy_end(x, plate) == pytest.approx(0.2)
    falling = x.copy()
    falling[-1, 4:, 1] = falling[-2, 4:, 1] - 0.1
    assert not q.rebounds(falling, plate)


def test_impact_summary_holds_each_definition():
    x, stress, rest, cells, node_type = trajectory()
    s = q.impact_summary(x, stress, rest, q.plate_mask(cells, node_type), DT)
    assert s.peak_plate_stress_mpa == 650.0 and s.peak_plate_frame == 8 and s.peak_plate_node == 2
    assert s.peak_ball_stress_mpa == 900.0 and s.peak_ball_when_ms == pytest.approx(4 * DT)
    assert s.peak_plate_t95_frame == 8 and s.max_deflection_mm == pytest.approx(0.06)
    assert s.contact_frames == [2, 5] and s.contact_end_ms == pytest.approx(6 * DT) and s.rebounds
    assert s.ghost_ratio == pytest.approx(4000 / 10 / 650) and len(s.plate_stress_history_mpa) == T


def test_metrics_read_the_same_definitions():
    """impact_metrics (evaluate, predict --verify) on the same hand-made model / solver pair."""
    x, stress, rest, cells, node_type = trajectory()
    plate = q.plate_mask(cells, node_type)
    truth = stress.copy()
    truth[8:] = 0.0  # the solver has no ghost: its plate peak is 500 at frame 4
    m = impact_metrics(x, stress, x, truth, plate)
    assert m.peak_plate_stress_error_pct == pytest.approx(30.0) and m.peak_plate_frame_error == 4
    assert m.peak_ball_stress_error_pct == 0.0 and m.max_deflection_error_pct == 0.0
    assert m.model_ghost_ratio == pytest.approx(4000 / 10 / 650)
    assert m.solver_ghost_ratio == pytest.approx(1400 / 10 / 500)
    moved = x.copy()
    moved[3:, 3, 1] -= 0.004  # the far rim node 4 µm off in predicted frames 3..11 (start 2: frame 2 counts, 0 off)
    m = impact_metrics(moved, stress, x, truth, plate)
    assert m.far_deflection_error_um == pytest.approx(4.0 * 9 / 10 / 2)  # mean over 2 far nodes, 10 frames
