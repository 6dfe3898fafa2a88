"""One definition of each Impact Plate quantity, read off one trajectory (the model's or the solver's).

Every command that reports these (``hcmt evaluate``, ``hcmt predict`` / ``sweep`` and their ``--verify``,
``hcmt simulate``, the benchmarks) reads them here, so a printed name means one thing everywhere. A trajectory is
``world_pos [T, N, 2]`` (mm), a nodal von Mises ``stress [T, N]`` (MPa), the positions at rest ``rest [N, 2]``
(frame 0) and ``plate [N]`` (:func:`plate_mask`; the other body is the ball):

* **peak plate (ball) stress** (:func:`peak`): the largest stress over the body's nodes and *every* frame of the
  window; **where**: that node's position in that frame; **when** (**time of the peak**): that frame (the first
  frame that reaches it), in ms ``frame * frame_dt``;
* **rise time** (:func:`rise_frame`): the first frame whose plate stress reaches :data:`RISE_SHARE` (95 %) of the
  peak; not the time of the peak: the solver's peak is a plateau and its argmax frame swings on noise;
* **plate stress history** (:func:`body_history`): the plate's largest stress in each frame;
* **maximum deflection** (:func:`max_deflection`): ``max |u_y|`` over the plate's nodes and frames, ``u_y`` the
  vertical displacement from rest; **far-field deflection** (:func:`far_deflection`): the same over the plate's
  nodes beyond :data:`FAR_SHARE` of its radius (:func:`impact_groups`);
* **ghost ratio** (:func:`ghost_ratio`): the mean of the last :data:`GHOST_FRAMES` frames' plate stress history
  ÷ the peak plate stress: the stress left when the window ends;
* **contact window** (:func:`contact_window`): the frames from the ball's first touch to :data:`CONTACT_GRACE`
  frames after its last, a touch being a gap (:func:`contact_gap`, on the symmetry axis) of at most
  :data:`CONTACT_TOL`; **contact end** (:func:`contact_end_frame`): the frame after the last touch;
* **rebound** (:func:`rebounds`): the ball's mean vertical velocity over the window's last step is upward.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from hcmt.data.format import NodeType
from hcmt.errors import InputError
from hcmt.graph.contact import object_ids

#: the ball touches the plate when its lowest point on the axis is at most this far above the plate's top (mm).
#: The solver's penalty contact penetrates 4-7 µm and opens 0-8 µm in the first frame after separation, but a
#: learned rollout's ball floats up to 26 µm above a plate it still loads (a thin plate, 70 µm position RMSE):
#: 50 µm, a sixth of the mesh size, tells touching from gone for both
CONTACT_TOL = 0.05
#: frames after the last touch still in the contact window (the stress wave needs a frame to leave the zone)
CONTACT_GRACE = 1
#: the rise time is the first frame at this share of the peak
RISE_SHARE = 0.95
#: the ghost ratio averages the plate stress history over this many last frames
GHOST_FRAMES = 10
#: plate nodes beyond this share of the plate's radius are its far field
FAR_SHARE = 0.5


# -- the bodies ----------------------------------------------------------------------------------------------------
def plate_mask(cells: np.ndarray, node_type: np.ndarray) -> np.ndarray:
    """[N] bool: the plate, i.e. the body holding the supported nodes (clamped HANDLE, or a ring's
    WALL_BOUNDARY), else the one holding NORMAL nodes; the other body is the impactor (OBSTACLE nodes)."""
    node_type = np.asarray(node_type).reshape(-1)
    obj = object_ids(np.asarray(cells), len(node_type))
    for kind in (NodeType.HANDLE, NodeType.WALL_BOUNDARY, NodeType.NORMAL):
        held = obj[node_type == kind]
        if len(held):
            return obj == held[0]
    raise InputError(
        "no clamped (HANDLE), supported (WALL_BOUNDARY) or NORMAL nodes: cannot tell the plate from the impactor"
    )


def impact_groups(rest: np.ndarray, plate: np.ndarray) -> dict[str, np.ndarray]:
    """Node masks ``ball``, ``contact`` (plate nodes with ``r = |x| <=`` :data:`FAR_SHARE` of the plate's radius)
    and ``far`` (plate nodes beyond it), ``rest`` the [N, 2] positions at rest (frame 0)."""
    r = np.abs(np.asarray(rest)[:, 0])
    edge = FAR_SHARE * r[plate].max()
    return {"ball": ~plate, "contact": plate & (r <= edge), "far": plate & (r > edge)}


# -- stress --------------------------------------------------------------------------------------------------------
def body_history(stress: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """[T] the body's largest stress in each frame (``stress`` [T, N] or [T, N, 1])."""
    s = np.asarray(stress, np.float64)
    s = s[..., 0] if s.ndim == 3 else s
    return s[:, np.asarray(mask, bool)].max(1)


def peak(stress: np.ndarray, mask: np.ndarray, frames: np.ndarray | None = None) -> tuple[float, int, int]:
    """(peak stress, its frame, its node): the largest stress over the body's nodes (``mask``) and frames (all, or
    those where ``frames`` [T] is True); the first frame, then the first node, that reaches it."""
    s = np.asarray(stress, np.float64)
    s = s[..., 0] if s.ndim == 3 else s
    nodes = np.flatnonzero(mask)
    sb = s[:, nodes]
    if frames is not None:
        if not np.any(frames):
            raise InputError("no frame to read the peak from", param="frames")
        sb = np.where(np.asarray(frames, bool)[:, None], sb, -np.inf)
    t, j = np.unravel_index(np.argmax(sb), sb.shape)
    return float(s[t, nodes[j]]), int(t), int(nodes[j])


def peak_fields(stress, mask, world_pos, frame_dt: float, body: str, frames=None) -> dict:
    """``peak_<body>_stress_mpa``, ``_where_mm`` (the node's position then), ``_when_ms``, ``_frame`` and
    ``_node`` of :func:`peak`."""
    value, t, node = peak(stress, mask, frames)
    return {
        f"peak_{body}_stress_mpa": value,
        f"peak_{body}_where_mm": [float(v) for v in world_pos[t, node]],
        f"peak_{body}_when_ms": float(t * frame_dt),
        f"peak_{body}_frame": t,
        f"peak_{body}_node": node,
    }


def rise_frame(
    history: np.ndarray, peak_value: float, frames: np.ndarray | None = None, share: float = RISE_SHARE
) -> int:
    """The first frame (of ``frames``, default all) whose ``history`` reaches ``share`` of ``peak_value``; the
    history's argmax when none does."""
    h = np.asarray(history, np.float64)
    ok = (h >= share * peak_value) & (np.ones(len(h), bool) if frames is None else np.asarray(frames, bool))
    return int(np.flatnonzero(ok)[0]) if ok.any() else int(np.argmax(h))


def ghost_ratio(history, peak_value: float, last: int = GHOST_FRAMES) -> float:
    """The mean of the last ``last`` frames' plate stress history ÷ the peak: the stress left at the window's end
    (NaN for a peak that is not positive)."""
    if not peak_value > 0:
        return float("nan")
    return float(np.mean(np.asarray(history, np.float64)[-last:]) / peak_value)


# -- deflection ----------------------------------------------------------------------------------------------------
def deflection(world_pos: np.ndarray, rest: np.ndarray, plate: np.ndarray) -> np.ndarray:
    """[T, plate nodes] the plate's vertical displacement from rest, ``u_y`` (mm, signed)."""
    return np.asarray(world_pos, np.float64)[:, plate, 1] - np.asarray(rest, np.float64)[None, plate, 1]


def max_deflection(world_pos: np.ndarray, rest: np.ndarray, plate: np.ndarray) -> float:
    """``max |u_y|`` over the plate's nodes and frames (mm)."""
    return float(np.abs(deflection(world_pos, rest, plate)).max())


def far_deflection(world_pos: np.ndarray, rest: np.ndarray, plate: np.ndarray) -> float:
    """``max |u_y|`` over the plate's far-field nodes (:func:`impact_groups`) and frames (mm)."""
    far = impact_groups(rest, plate)["far"]
    return float(np.abs(deflection(world_pos, rest, far)).max()) if far.any() else 0.0


# -- contact and rebound -------------------------------------------------------------------------------------------
def axis_nodes(rest: np.ndarray, plate: np.ndarray) -> tuple[int, int]:
    """(the ball's lowest node, the plate's top node) on the symmetry axis ``x = 0`` at rest."""
    axis = np.abs(rest[:, 0]) < 1e-6
    ball_axis, plate_axis = np.flatnonzero(~plate & axis), np.flatnonzero(plate & axis)
    if not len(ball_axis) or not len(plate_axis):
        raise InputError("no ball and plate nodes on the symmetry axis x = 0: not an Impact Plate mesh")
    return int(ball_axis[np.argmin(rest[ball_axis, 1])]), int(plate_axis[np.argmax(rest[plate_axis, 1])])


def contact_gap(world_pos: np.ndarray, rest: np.ndarray, plate: np.ndarray) -> np.ndarray:
    """[T] the gap between the ball's lowest point and the plate's top on the axis (mm; negative: penetration)."""
    ball_node, plate_node = axis_nodes(rest, plate)
    return world_pos[:, ball_node, 1] - world_pos[:, plate_node, 1]


def contact_frames(gap: np.ndarray, tol: float = CONTACT_TOL) -> list[int] | None:
    """[first, last] frame where the ball touches (gap <= ``tol``), None when it never does."""
    touch = np.flatnonzero(np.asarray(gap) <= tol)
    return [int(touch[0]), int(touch[-1])] if len(touch) else None


def contact_window(gap: np.ndarray, tol: float = CONTACT_TOL, grace: int = CONTACT_GRACE) -> np.ndarray:
    """[T] bool: the frames from the first touch to ``grace`` frames after the last (all False when none)."""
    out = np.zeros(len(gap), bool)
    touch = contact_frames(gap, tol)
    if touch:
        out[touch[0] : min(len(gap), touch[1] + grace + 1)] = True
    return out


def contact_end_frame(gap: np.ndarray, tol: float = CONTACT_TOL) -> int:
    """When the ball leaves: the frame after its last touch (the window's length when it touches in the last frame:
    censored; 1 when it never touches)."""
    touch = contact_frames(gap, tol)
    return touch[1] + 1 if touch else 1


def ball_vy_end(world_pos: np.ndarray, plate: np.ndarray) -> float:
    """The ball's mean vertical velocity over the window's last step (mm per frame)."""
    x = np.asarray(world_pos, np.float64)
    return float((x[-1, ~plate, 1] - x[-2, ~plate, 1]).mean())


def rebounds(world_pos: np.ndarray, plate: np.ndarray) -> bool:
    """Whether the ball rebounds: its mean vertical velocity over the window's last step is upward."""
    return ball_vy_end(world_pos, plate) > 0


# -- all of them ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ImpactQuantities:
    """Every quantity above of one trajectory (:func:`impact_summary`), under the names the design check's JSON
    reports them by and in its order. Stresses MPa (von Mises), lengths mm, times ms."""

    peak_plate_stress_mpa: float
    peak_plate_where_mm: list[float]  # (r, y) of the peak's node at its frame
    peak_plate_when_ms: float
    peak_plate_frame: int
    peak_plate_node: int
    peak_ball_stress_mpa: float
    peak_ball_where_mm: list[float]
    peak_ball_when_ms: float
    peak_ball_frame: int
    peak_ball_node: int
    peak_plate_t95_frame: int  # first frame at 95 % of the peak (the rise time)
    peak_plate_t95_ms: float  # > 0: the surrogate takes its log
    max_deflection_mm: float  # max |u_y| over the plate's nodes and frames
    far_deflection_mm: float
    contact_frames: list[int] | None  # [first, last] frame where the ball touches; None: it never does
    contact_end_ms: float
    ghost_ratio: float
    rebounds: bool
    plate_stress_history_mpa: list[float]  # the plate's peak stress per frame

    def to_json(self) -> dict:
        """The fields in order, as the JSON writes them."""
        return asdict(self)


def peak_values(stress, mask, world_pos, frame_dt: float, frames=None) -> tuple[float, list[float], float, int, int]:
    """(stress, where, when, frame, node) of :func:`peak`: the node's position in that frame, the time in ms."""
    value, t, node = peak(stress, mask, frames)
    return value, [float(v) for v in world_pos[t, node]], float(t * frame_dt), t, node


def impact_summary(
    world_pos: np.ndarray, stress: np.ndarray, rest: np.ndarray, plate: np.ndarray, frame_dt: float
) -> ImpactQuantities:
    """Every quantity above of one trajectory, as :class:`ImpactQuantities`."""
    x = np.asarray(world_pos)
    plate_peak, ball_peak = peak_values(stress, plate, x, frame_dt), peak_values(stress, ~plate, x, frame_dt)
    history = body_history(stress, plate)
    first = rise_frame(history, plate_peak[0])
    gap = contact_gap(x, rest, plate)
    return ImpactQuantities(
        *plate_peak,
        *ball_peak,
        peak_plate_t95_frame=first,
        peak_plate_t95_ms=float(max(first, 1) * frame_dt),
        max_deflection_mm=max_deflection(x, rest, plate),
        far_deflection_mm=far_deflection(x, rest, plate),
        contact_frames=contact_frames(gap),
        contact_end_ms=float(contact_end_frame(gap) * frame_dt),
        ghost_ratio=ghost_ratio(history, plate_peak[0]),
        rebounds=rebounds(x, plate),
        plate_stress_history_mpa=[float(v) for v in history],
    )
