"""A hand-made Impact Plate trajectory whose quantities are known (tests/inference/test_quantities.py has them)."""

import numpy as np

T = 12
DT = 0.002
#: the gap between the ball's lowest point and the plate's top, frame by frame: it touches (<= 0.05) in 2..5
GAP = np.array([0.3, 0.1, 0.04, 0.0, -0.005, 0.02, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2])
#: the plate's centre deflection (down), frame by frame
DIP = np.array([0, 0, 0.02, 0.05, 0.06, 0.04, 0.02, 0.0, 0.0, 0.0, 0.0, 0.0])


def trajectory():
    """A plate (nodes 0-3: top axis node 0, rim 1 and 3 at r = 2) and a ball (nodes 4-6, lowest axis node 4).
    Plate stress: 200, 400, 500, 300 at node 0 in frames 2-5, then a 'ghost' of 650 at node 2 from frame 8; ball
    stress 900 at node 5 in frame 4. The rim node 3 moves 0.01 down in frame 5."""
    rest = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, -0.5], [2.0, -0.5], [0.0, 0.3], [0.5, 0.8], [0.0, 1.3]])
    cells = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 6]])
    node_type = np.array([0, 3, 0, 3, 1, 1, 1])
    x = np.repeat(rest[None], T, 0).copy()
    x[:, [0, 2], 1] -= DIP[:, None]
    x[5, 3, 1] -= 0.01
    x[:, 4:, 1] += (x[:, 0, 1] + GAP - 0.3)[:, None]  # ball node 4 sits GAP above plate node 0
    stress = np.zeros((T, 7, 1))
    stress[2:6, 0, 0] = [200.0, 400.0, 500.0, 300.0]
    stress[8:, 2, 0] = 650.0
    stress[4, 5, 0] = 900.0
    return x, stress, rest, cells, node_type


def fields() -> dict:
    """The trajectory as the design check reads it (modulus: glass plate, steel ball)."""
    x, stress, rest, cells, node_type = trajectory()
    return {
        "world_pos": x,
        "stress": stress,
        "mesh_pos": rest,
        "cells": cells,
        "node_type": node_type,
        "modulus": np.array([7e4] * 4 + [2e5] * 3),
    }
