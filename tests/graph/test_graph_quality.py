"""Scaled Jacobian and angles against closed-form values."""

import numpy as np

from hcmt.graph.quality import cell_angles, quality_summary, scaled_jacobian, signed_measure

EQUILATERAL = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3) / 2]])
REGULAR_TET = np.array([[1.0, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]])


def test_equilateral_triangle_and_regular_tetrahedron_score_one():
    assert np.isclose(scaled_jacobian(EQUILATERAL, np.array([[0, 1, 2]]))[0], 1.0)
    np.testing.assert_allclose(cell_angles(EQUILATERAL, np.array([[0, 1, 2]]))[0], 60.0)
    assert np.isclose(scaled_jacobian(REGULAR_TET, np.array([[0, 1, 2, 3]]))[0], 1.0)
    np.testing.assert_allclose(
        cell_angles(REGULAR_TET, np.array([[0, 1, 2, 3]]))[0], np.degrees(np.arccos(1 / 3))
    )  # 70.53 degrees


def test_right_triangle_and_corner_tetrahedron():
    right = np.array([[0.0, 0], [1, 0], [0, 1]])
    # min over corners of sin(angle), scaled by 2/sqrt(3): the 45-degree corners give sin 45
    assert np.isclose(scaled_jacobian(right, np.array([[0, 1, 2]]))[0], np.sin(np.pi / 4) * 2 / np.sqrt(3))
    np.testing.assert_allclose(np.sort(cell_angles(right, np.array([[0, 1, 2]]))[0]), [45, 45, 90])
    corner = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    # corner at the origin: det 1 over edge lengths 1*1*1; at (1,0,0): det 1 over 1*sqrt2*sqrt2 = 1/2 (the min)
    want = np.sqrt(2) * 0.5
    assert np.isclose(scaled_jacobian(corner, np.array([[0, 1, 2, 3]]))[0], want)
    dihedral = np.sort(cell_angles(corner, np.array([[0, 1, 2, 3]]))[0])
    np.testing.assert_allclose(dihedral, [np.degrees(np.arccos(1 / np.sqrt(3)))] * 3 + [90] * 3)


def test_orientation_and_surfaces():
    cw = np.array([[0, 2, 1]])
    assert signed_measure(EQUILATERAL, cw)[0] < 0
    assert np.isclose(scaled_jacobian(EQUILATERAL, cw)[0], 1.0)  # the magnitude is orientation-independent
    lifted = np.c_[EQUILATERAL, [0.0, 0.0, 0.0]] @ np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    assert np.isclose(scaled_jacobian(lifted, np.array([[0, 1, 2]]))[0], 1.0)  # a triangle in 3-D space


def test_summary_ignores_degenerate_cells():
    pos = np.r_[EQUILATERAL, [[2.0, 0.0]]]
    cells = np.array([[0, 1, 2], [0, 0, 3]])  # the second repeats a vertex
    s = quality_summary(pos, cells)
    assert s["cells"] == 1 and np.isclose(s["jacobian"], 1.0) and np.isclose(s["min_angle"], 60.0)
    assert np.isnan(quality_summary(pos, np.zeros((0, 3), np.int64))["jacobian"])
