"""What the design check reads off an Impact Plate trajectory (predicted or simulated), and its derived read-outs.

:func:`summarize_fields` turns a trajectory's fields (``world_pos [T, N, 2]``, ``stress [T, N, 1]``, ``mesh_pos``,
``cells``, ``node_type``, ``modulus``) into the design check's numbers. Its default fields are always the
trajectory's own quantities (:func:`hcmt.inference.quantities.impact_summary`: peak plate and ball stress, where,
when, ``peak_plate_t95_ms`` (the rise time: the first frame at 95 % of the peak), maximum and far-field
deflection, the contact frames, ``contact_end_ms``, ``ghost_ratio``, ``rebounds`` and
``plate_stress_history_mpa``): for a learned model its stress head and its positions in every frame, nothing
else. They do not depend on the response surface.

``readout`` (:data:`READOUTS`, recorded as ``readout``) may add one *derived* read-out, every number of which lies
under its own name, prefixed by the read-out's (:func:`readout_key`), never under a default field's:

* ``raw`` (default): none; the model's own answer is the answer;
* ``contact``: ``contact_peak_plate_*`` from the frames where the predicted ball touches the plate only
  (:func:`hcmt.inference.quantities.contact_window`), the window ending no later than a bound on when the solver's
  ball leaves when one is given (the design check passes the response surface's :data:`CONTACT_END_BOUND`;
  ``contact_window_end_ms`` and ``contact_window_end_from`` say where it ended), and
  ``contact_plate_stress_history_mpa``: the stress head inside the window, after it the plate's free-vibration
  bending stress from its predicted deflection, ``σ ≈ k E t w_max / R²`` (Kirchhoff plate; ``k`` =
  :data:`BENDING_K`, fitted to 120 solver runs' post-separation frames). This read-out
  depends on the response surface and on a fitted constant: it hides what the model predicts after contact;
* ``element``: ``element_peak_plate_*`` and ``element_plate_stress_history_mpa`` from the solver's own element
  law (CST, St Venant-Kirchhoff) on the predicted positions. Measured: its peak is off by a median +459 % on 8
  designs (a 1 µm position error across a 0.3 mm element is a strain of 3e-3, 230 MPa in glass): for study.

docs/MODELS.md, "Ghost stress", has the comparison.
"""

from __future__ import annotations

import numpy as np

from hcmt.design.basics import DEFAULT_READOUT, READOUTS  # noqa: F401 (light: the parsers read them there)
from hcmt.design.summary import PlateReadout, Summary
from hcmt.errors import InputError
from hcmt.inference import quantities as q
from hcmt.inference.quantities import contact_gap, contact_window, ghost_ratio, plate_mask  # noqa: F401 (re-exported)
from hcmt.sim.solver import build_model, nodal_von_mises

#: the post-separation bending coefficient of the ``contact`` read-out: σ = k E t w_max / R² (median of
#: σ_plate / (E t w_max / R²) over the solver's post-separation frames of the 120 training runs of the model shipped
#: until 2026-12-04, which ranged 3.8-8.1: a property of the solver's plates, not of a model)
BENDING_K = 5.0
#: which bound of the response surface's 95 % interval of ``contact_end_ms`` ends the ``contact`` read-out's window:
#: ``lo``, the frames where the solver's ball has surely not left yet (docs/RESULTS.md "Ghost stress")
CONTACT_END_BOUND = "lo"
#: the keys a derived read-out reports under its own name (:func:`readout_key`)
DERIVED_KEYS = (
    "peak_plate_stress_mpa",
    "peak_plate_where_mm",
    "peak_plate_when_ms",
    "peak_plate_frame",
    "peak_plate_node",
    "peak_plate_t95_frame",
    "peak_plate_t95_ms",
    "plate_stress_history_mpa",
)


def check_readout(readout: str) -> str:
    """``readout`` when it is one of :data:`READOUTS`; InputError (param ``readout``) otherwise."""
    if readout not in READOUTS:
        raise InputError(f"must be one of {', '.join(READOUTS)}, got {readout!r}", param="readout")
    return readout


def readout_key(key: str, readout: str) -> str:
    """Where ``readout`` reports ``key``: the default field for ``raw`` and for keys it does not derive, else
    ``<readout>_<key>``."""
    return key if readout == "raw" or key not in DERIVED_KEYS else f"{readout}_{key}"


def chosen(summary: Summary, key: str) -> float:
    """``key`` (a field of :data:`DERIVED_KEYS`, or another of the summary's) as the summary's chosen read-out (its
    ``readout``) reports it."""
    return getattr(summary.chosen if key in DERIVED_KEYS else summary, key)


def bending_stress(
    world_pos: np.ndarray, mesh_pos: np.ndarray, plate: np.ndarray, modulus: np.ndarray, k: float = BENDING_K
) -> np.ndarray:
    """[T] the free plate's bending stress ``k E t w_max(t) / R²`` (MPa) from its deflection."""
    E = float(np.median(np.asarray(modulus).reshape(-1)[plate]))
    y, r = mesh_pos[plate, 1], mesh_pos[plate, 0]
    t, R = float(y.max() - y.min()), float(r.max())
    w = np.abs(q.deflection(world_pos, mesh_pos, plate)).max(1)
    return k * E * t * w / R**2


def element_stress(
    world_pos: np.ndarray, fields: dict, formulation: str = "axisymmetric", poisson: tuple[float, float] = (0.22, 0.3)
) -> np.ndarray:
    """[T, N] nodal von Mises of the solver's element law on given positions (``poisson``: plate, ball)."""
    plate = plate_mask(fields["cells"], fields["node_type"])
    cells = np.asarray(fields["cells"])
    cell_plate = plate[cells[:, 0]]
    E = np.asarray(fields["modulus"]).reshape(-1)[cells[:, 0]]
    nu = np.where(cell_plate, poisson[0], poisson[1])
    model = build_model(fields["mesh_pos"], cells, 1.0, E, nu, formulation=formulation)  # stress: no density
    return np.stack([nodal_von_mises(model, np.asarray(x, np.float64)) for x in world_pos])


def _plate_readout(stress, plate, x, frame_dt: float, frames=None, history=None, **contact) -> PlateReadout:
    """The plate's peak block (:data:`DERIVED_KEYS`) of a stress field read on ``frames`` (default all);
    ``contact``: the ``contact`` read-out's own fields (window end, bending constant)."""
    value, where, when, frame, node = q.peak_values(stress, plate, x, frame_dt, frames)
    history = q.body_history(stress, plate) if history is None else history
    first = q.rise_frame(history, value, frames)
    return PlateReadout(
        value,
        where,
        when,
        frame,
        node,
        peak_plate_t95_frame=first,
        peak_plate_t95_ms=float(max(first, 1) * frame_dt),
        plate_stress_history_mpa=[float(v) for v in history],
        **contact,
    )


def contact_readout(
    fields: dict, frame_dt: float, contact_end_ms: float | None = None, k: float = BENDING_K
) -> PlateReadout:
    """The ``contact`` read-out (module docstring): the JSON writes each field prefixed ``contact_``."""
    x, X = np.asarray(fields["world_pos"]), np.asarray(fields["mesh_pos"])
    plate = plate_mask(fields["cells"], fields["node_type"])
    window, source = contact_window(contact_gap(x, X, plate)), "the predicted ball's last touch"
    if not window.any():
        window, source = np.ones(len(x), bool), "the ball never touches: every frame"
    elif contact_end_ms is not None and np.isfinite(contact_end_ms):
        cut = max(int(np.floor(contact_end_ms / frame_dt)), int(np.flatnonzero(window)[0]))
        if window[cut + 1 :].any():
            window[cut + 1 :] = False
            source = f"the response surface's {CONTACT_END_BOUND} bound of when the solver's ball leaves"
    last = int(np.flatnonzero(window)[-1])
    history = q.body_history(fields["stress"], plate)
    after = np.arange(len(history)) > last
    history = np.where(after, bending_stress(x, X, plate, fields["modulus"], k), history)
    return _plate_readout(
        fields["stress"],
        plate,
        x,
        frame_dt,
        window,
        history,
        window_end_ms=float((last + 1) * frame_dt),
        window_end_from=source,
        bending_k=float(k),
    )


def contact_note(summaries: list[Summary]) -> str | None:
    """A one-line note when ``--readout contact`` changed nothing on these designs: on every one the model's own
    peak lies inside the contact window (:func:`contact_readout` reads the same frames' stress up to the ball's
    leaving and only replaces the stress after it), so the contact peak, and the calls made from it, are the raw
    ones. It can differ only where a model's peak comes after the ball has left ("ghost stress"); None otherwise,
    or for another read-out."""
    if not summaries or any(s.readout != "contact" for s in summaries):
        return None
    if any(s.derived.peak_plate_frame != s.peak_plate_frame for s in summaries):
        return None
    return (
        "--readout contact changes nothing here: on every design the model's own peak comes before the ball "
        "leaves the plate, so contact_* repeats its peak and the calls are the raw ones (the read-out differs "
        'only where a model\'s peak comes after the ball has left: docs/MODELS.md, "The contact read-out")'
    )


def element_readout(fields: dict, frame_dt: float) -> PlateReadout:
    """The ``element`` read-out (module docstring): the JSON writes each field prefixed ``element_``."""
    x = np.asarray(fields["world_pos"])
    plate = plate_mask(fields["cells"], fields["node_type"])
    return _plate_readout(element_stress(x, fields), plate, x, frame_dt)


def summarize_fields(
    fields: dict,
    frame_dt: float,
    readout: str = DEFAULT_READOUT,
    wall_s: float = 0.0,
    contact_end_ms: float | None = None,
) -> Summary:
    """The design check's numbers of one trajectory (module docstring): its own quantities, and with a derived
    ``readout`` that read-out's block (``derived``); ``contact_end_ms``: the ``contact`` read-out's bound on when
    the ball leaves (ignored by the others)."""
    check_readout(readout)
    x, X = np.asarray(fields["world_pos"]), np.asarray(fields["mesh_pos"])
    plate = plate_mask(fields["cells"], fields["node_type"])
    own = q.impact_summary(x, fields["stress"], X, plate, frame_dt)
    derived = (
        contact_readout(fields, frame_dt, contact_end_ms)
        if readout == "contact"
        else element_readout(fields, frame_dt)
        if readout == "element"
        else None
    )
    return Summary(**vars(own), readout=readout, derived=derived, wall_s=float(wall_s))


def history_correlation(model_stress: np.ndarray, solver_stress: np.ndarray, node: int) -> float:
    """Pearson correlation of one node's stress history [T], model against solver (NaN for a constant one)."""
    a, b = np.asarray(model_stress)[:, node].ravel(), np.asarray(solver_stress)[:, node].ravel()
    if a.std() == 0 or b.std() == 0:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])
