"""Triangle meshes of the Impact Plate scene: a plate (structured, graded) and a half-disk ball (Delaunay, in
:mod:`hcmt.sim.impactor_mesh` with the pen's tip).

Geometry (half model, paper appendix "Impact Plate"): the symmetry line is ``x = 0``; the plate occupies
``[0, L] x [-t, 0]`` (top surface at ``y = 0``), the ball is the half disk ``x >= 0`` of radius ``R`` centred at
``(0, R + gap)``, so it starts ``gap`` above the plate. Units mm. In the axisymmetric formulation ``x`` is the
radius ``r`` and ``y`` the axis ``z``: the plate is a circular disk clamped at ``r = L`` and the ball a full sphere.

Node types (MeshGraphNets enum + SYMMETRIC, as the official HCMT data): plate NORMAL 0, ball OBSTACLE 1, every node
on ``x = 0`` (plate and ball) SYMMETRIC 7 (x fixed), plate nodes on ``x = L`` HANDLE 3 (clamped).
"""

from __future__ import annotations

import numpy as np

from hcmt.data.format import NodeType
from hcmt.errors import InputError
from hcmt.sim.impactor_mesh import ball_mesh, pen_tip_mesh

NORMAL, OBSTACLE, HANDLE, SYMMETRIC = NodeType.NORMAL, NodeType.OBSTACLE, NodeType.HANDLE, NodeType.SYMMETRIC
WALL_BOUNDARY = NodeType.WALL_BOUNDARY

#: Preset meshes: ``paper`` about 2,200 nodes (paper Table 6: 2,208), ``small`` about 400-600 nodes (CPU training).
PRESETS: dict[str, dict[str, float]] = {
    "paper": dict(thickness=0.75, ball_radius=3.5, mesh_size=0.125, plate_half_length=15.0),
    "small": dict(thickness=0.75, ball_radius=3.75, mesh_size=0.30, plate_half_length=12.0),
}


def graded_coordinates(length: float, h0: float, growth: float = 1.0, h_max: float | None = None) -> np.ndarray:
    """Coordinates ``0 = s_0 < ... < s_n = length``: spacing ``h0`` growing geometrically by ``growth`` up to
    ``h_max``, then rescaled so the last point lands exactly on ``length``."""
    if length <= 0 or h0 <= 0:
        raise InputError(f"graded_coordinates needs length > 0 and h0 > 0, got {length}, {h0}")
    h_max = h0 if h_max is None else max(h_max, h0)
    steps, total, h = [], 0.0, h0
    while total < length - 1e-9:  # hand-rolled: a 1-D geometric series clipped at h_max, a few hundred terms
        steps.append(h)
        total += h
        h = min(h * growth, h_max)
    s = np.concatenate([[0.0], np.cumsum(steps)])
    return s * (length / s[-1])


def structured_triangles(xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tensor grid ``xs x ys`` split into counter-clockwise triangles, the diagonal alternating in a
    checkerboard (criss-cross) so the mesh has no preferred shear direction."""
    nx, ny = len(xs), len(ys)
    X, Y = np.meshgrid(xs, ys, indexing="xy")  # [ny, nx]
    pos = np.stack([X.ravel(), Y.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="xy")
    a = (j * nx + i).ravel()  # lower-left
    b, c, d = a + 1, a + nx + 1, a + nx  # lower-right, upper-right, upper-left
    flip = ((i + j) % 2 == 1).ravel()
    t1 = np.where(flip[:, None], np.stack([a, b, d], 1), np.stack([a, b, c], 1))
    t2 = np.where(flip[:, None], np.stack([b, c, d], 1), np.stack([a, c, d], 1))
    return pos, np.concatenate([t1, t2]).astype(np.int64)


def plate_mesh(
    thickness: float,
    half_length: float,
    mesh_size: float,
    *,
    layers: int | None = None,
    growth: float = 1.0,
    h_max: float | None = None,
    y_growth: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Plate ``[0, L] x [-t, 0]``: x spacing ``mesh_size`` at the centre (graded by ``growth`` up to ``h_max``),
    ``layers`` element layers through the thickness (default ``max(4, round(t / mesh_size))``; fewer than 4 locks
    CST triangles in bending). ``y_growth > 1`` instead grades the layers like x (``mesh_size`` at the top, contact,
    surface, growing up to ``h_max``): used for the thick block of the Hertz check."""
    if layers is None:
        layers = max(4, int(round(thickness / mesh_size)))
    if layers < 4:
        raise InputError(f"plate needs at least 4 element layers through the thickness, got {layers}")
    xs = graded_coordinates(half_length, mesh_size, growth, h_max)
    if y_growth == 1.0:
        depth = np.linspace(0.0, thickness, layers + 1)
    else:  # graded from the top like x: first layer mesh_size, growing up to h_max
        depth = graded_coordinates(thickness, mesh_size, y_growth, h_max)
        if len(depth) < 5:
            raise InputError(f"graded plate has {len(depth) - 1} layers; at least 4 are needed")
    ys = -depth[::-1]
    return structured_triangles(xs, ys)


def layer_rows(thicknesses, mesh_size: float, minimum: int = 4) -> list[int]:
    """Element rows of each bonded layer: ``max(1, round(t_i / h))`` each, then one more row at a time to the layer
    with the tallest rows until the stack has ``minimum`` (fewer than 4 rows lock CST triangles in bending). One
    layer gets ``max(4, round(t / h))`` as :func:`plate_mesh`; two equal halves of a plate get the plate's rows."""
    t = np.asarray(thicknesses, float)
    rows = np.maximum(1, np.round(t / mesh_size)).astype(int)
    while rows.sum() < minimum:  # hand-rolled: at most 3 additions
        rows[int(np.argmax(t / rows))] += 1
    return rows.tolist()


def impact_plate_mesh(
    thickness: float,
    ball_radius: float,
    mesh_size: float,
    *,
    plate_half_length: float = 15.0,
    gap: float = 0.02,
    ball_mesh_size: float | None = None,
    plate_layers: int | None = None,
    plate_growth: float = 1.0,
    plate_h_max: float | None = None,
    plate_y_growth: float = 1.0,
    ball_growth: float = 1.0,
    ball_h_max: float | None = None,
    layers=None,
    support_radius: float = 0.0,
    backing_thickness: float = 0.0,
    impactor: str = "ball",
) -> dict[str, np.ndarray]:
    """The Impact Plate scene mesh: plate nodes first (the panel's layers, then a backing), then the impactor's.

    ``layers``: the thicknesses of a stack of bonded layers from the top (impact) face down, sharing nodes at their
    interfaces (:func:`layer_rows` rows each); default one layer of ``thickness``. Supports: the outer rim
    ``x = L`` clamped (HANDLE) unless ``support_radius`` > 0 (a simply supported ring: the bottom node at that
    radius WALL_BOUNDARY, its axial position fixed, the rim free) or ``backing_thickness`` > 0 (a bonded soft
    backing of that thickness under the panel, its bottom HANDLE, the rim free). ``impactor``: ``"ball"`` (a half
    disk of ``ball_radius``) or ``"pen"`` (:func:`~hcmt.sim.impactor_mesh.pen_tip_mesh` of that radius; its top face
    nodes are the ``rigid`` ones a rod holds).

    Returns ``mesh_pos [N,2] float64``, ``cells [C,3] int64`` (counter-clockwise), ``node_type [N] int64``,
    ``body [N] int64`` (0 plate, 1 impactor; the node type alone loses it on the symmetry line),
    ``cell_body [C] int64``, ``cell_layer [C] int64`` (0 = top layer, ..., the backing last; -1 impactor) and
    ``rigid [N] bool``. ``ball_mesh_size`` defaults to ``mesh_size`` (a pen tip's to ``min(mesh_size, r / 3)``).
    """
    layers = [thickness] if layers is None else [float(t) for t in layers]
    hb = _impactor_size(
        layers, ball_radius, mesh_size, plate_half_length, gap, ball_mesh_size, support_radius, impactor
    )
    plate = _plate_part(
        layers,
        plate_half_length,
        mesh_size,
        plate_growth,
        plate_h_max,
        support_radius,
        backing_thickness,
        plate_layers,
        plate_y_growth,
    )
    tip = _impactor_part(impactor, ball_radius, hb, ball_radius + gap, ball_growth, ball_h_max)
    return _joined(plate, tip, float(np.sum(layers)), plate_half_length, support_radius, backing_thickness)


def _impactor_size(
    layers: list[float],
    ball_radius: float,
    mesh_size: float,
    plate_half_length: float,
    gap: float,
    ball_mesh_size: float | None,
    support_radius: float,
    impactor: str,
) -> float:
    """:func:`impact_plate_mesh`'s lengths checked (one line each); returns the impactor's element size."""
    for name, v in (
        ("thickness", sum(layers)),
        ("ball_radius", ball_radius),
        ("mesh_size", mesh_size),
        ("plate_half_length", plate_half_length),
        ("gap", gap),
        *((f"layer {i + 1} thickness", t) for i, t in enumerate(layers)),
    ):
        if not np.isfinite(v) or v <= 0:
            raise InputError(f"{name} must be a positive finite length in mm, got {v}")
    if impactor not in ("ball", "pen"):
        raise InputError(f"impactor must be 'ball' or 'pen', got {impactor!r}")
    if plate_half_length <= ball_radius:
        raise InputError(f"plate_half_length ({plate_half_length} mm) must exceed ball_radius ({ball_radius} mm)")
    if mesh_size > sum(layers):
        raise InputError(f"mesh_size ({mesh_size} mm) must not exceed the plate thickness ({sum(layers)} mm)")
    if not 0 <= support_radius < plate_half_length:
        raise InputError(f"support_radius ({support_radius} mm) must lie inside the plate (0 .. {plate_half_length})")
    if impactor == "pen":
        return min(mesh_size, ball_radius / 3) if ball_mesh_size is None else ball_mesh_size
    hb = mesh_size if ball_mesh_size is None else ball_mesh_size
    if hb > ball_radius / 3:
        raise InputError(f"ball mesh size ({hb} mm) must be at most ball_radius / 3 ({ball_radius / 3:.3g} mm)")
    return hb


def _plate_part(
    layers: list[float],
    plate_half_length: float,
    mesh_size: float,
    plate_growth: float,
    plate_h_max: float | None,
    support_radius: float,
    backing_thickness: float,
    plate_layers: int | None,
    plate_y_growth: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions, cells, layer bounds from the top face down) of the plate: one block with its own rows when
    ``plate_layers`` or ``plate_y_growth`` is given (:func:`plate_mesh`, the Hertz check), else the layers' rows
    (:func:`layer_rows`), a backing under them, the ring's radius on a grid line."""
    if plate_layers is not None or plate_y_growth != 1.0:  # one block with its own rows (the Hertz check)
        if len(layers) > 1 or support_radius > 0 or backing_thickness > 0:
            raise InputError("plate_layers and plate_y_growth make one clamped block: no stack, ring or backing")
        p_pos, p_cells = plate_mesh(
            layers[0],
            plate_half_length,
            mesh_size,
            layers=plate_layers,
            growth=plate_growth,
            h_max=plate_h_max,
            y_growth=plate_y_growth,
        )
        return p_pos, p_cells, np.array([0.0, layers[0]])
    rows = layer_rows(layers, mesh_size)
    depth = [np.linspace(0.0, t, n + 1)[1:] for t, n in zip(layers, rows)]
    bounds = np.concatenate([[0.0], np.cumsum(layers)])
    if backing_thickness > 0:
        nb = max(2, int(round(backing_thickness / mesh_size)))
        depth.append(np.linspace(0.0, backing_thickness, nb + 1)[1:])
        bounds = np.append(bounds, bounds[-1] + backing_thickness)
    depth = np.concatenate([[0.0]] + [d + b for d, b in zip(depth, bounds[:-1])])
    xs = graded_coordinates(plate_half_length, mesh_size, plate_growth, plate_h_max)
    if support_radius > 0:  # the ring on a grid line: the nearest inner grid line moves there
        j = int(np.argmin(np.abs(xs[1:-1] - support_radius))) + 1
        xs[j] = support_radius
    p_pos, p_cells = structured_triangles(xs, -depth[::-1])
    return p_pos, p_cells, bounds


def _impactor_part(
    impactor: str, radius: float, mesh_size: float, center_y: float, growth: float, h_max: float | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions, cells, rigid nodes) of the impactor: a ball, none rigid, or a pen's tip, its top face rigid."""
    if impactor == "pen":
        b_pos, b_cells = pen_tip_mesh(radius, mesh_size, center_y)
        return b_pos, b_cells, np.abs(b_pos[:, 1] - center_y) < 1e-9 * radius
    b_pos, b_cells = ball_mesh(radius, mesh_size, center_y, growth=growth, h_max=h_max)
    return b_pos, b_cells, np.zeros(len(b_pos), bool)


def _joined(
    plate: tuple[np.ndarray, np.ndarray, np.ndarray],
    tip: tuple[np.ndarray, np.ndarray, np.ndarray],
    panel_depth: float,
    plate_half_length: float,
    support_radius: float,
    backing_thickness: float,
) -> dict[str, np.ndarray]:
    """:func:`impact_plate_mesh`'s arrays from its plate and impactor parts: plate first, node types of the support."""
    (p_pos, p_cells, bounds), (b_pos, b_cells, b_rigid) = plate, tip
    pos = np.concatenate([p_pos, b_pos])
    cells = np.concatenate([p_cells, b_cells + len(p_pos)])
    body = np.concatenate([np.zeros(len(p_pos), np.int64), np.ones(len(b_pos), np.int64)])
    node_type = _node_types(pos, body, bounds, panel_depth, plate_half_length, support_radius, backing_thickness)
    cell_body = np.concatenate([np.zeros(len(p_cells), np.int64), np.ones(len(b_cells), np.int64)])
    centroid_depth = -p_pos[p_cells, 1].mean(1)
    cell_layer = np.concatenate([np.searchsorted(bounds[1:-1], centroid_depth), np.full(len(b_cells), -1)]).astype(
        np.int64
    )
    rigid = np.concatenate([np.zeros(len(p_pos), bool), b_rigid])
    return dict(
        mesh_pos=pos,
        cells=cells,
        node_type=node_type,
        body=body,
        cell_body=cell_body,
        cell_layer=cell_layer,
        rigid=rigid,
    )


def _node_types(
    pos: np.ndarray,
    body: np.ndarray,
    bounds: np.ndarray,
    panel_depth: float,
    plate_half_length: float,
    support_radius: float,
    backing_thickness: float,
) -> np.ndarray:
    """[N] node types: NORMAL plate, OBSTACLE impactor; the support (a backing's bottom HANDLE, the ring's
    WALL_BOUNDARY node, else the clamped rim's HANDLE); SYMMETRIC on the axis."""
    tol = 1e-9 * max(plate_half_length, 1.0)
    node_type = np.where(body == 0, NORMAL, OBSTACLE).astype(np.int64)
    plate = body == 0
    if backing_thickness > 0:
        node_type[plate & (pos[:, 1] < -bounds[-1] + tol)] = HANDLE
    elif support_radius > 0:
        node_type[plate & (np.abs(pos[:, 0] - support_radius) < tol) & (pos[:, 1] < -panel_depth + tol)] = WALL_BOUNDARY
    else:
        node_type[plate & (pos[:, 0] > plate_half_length - tol)] = HANDLE
    node_type[np.abs(pos[:, 0]) < tol] = SYMMETRIC
    return node_type


def preset_mesh(preset: str = "small", **overrides) -> dict[str, np.ndarray]:
    """The mesh of a preset's nominal design (``paper`` ~2,200 nodes, ``small`` ~400-600 nodes)."""
    if preset not in PRESETS:
        raise InputError(f"unknown preset {preset!r}; expected one of {sorted(PRESETS)}")
    return impact_plate_mesh(**{**PRESETS[preset], **overrides})
