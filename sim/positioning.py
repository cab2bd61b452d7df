"""An ISO 230-2 positioning test run on the virtual machine.

The axis under test is moved to ``m`` target positions ``P_i`` in ``n``
cycles, every target approached moving in ``+`` and moving in ``-``; a
virtual laser interferometer reads, at each stop, where the tool really is
relative to the workpiece along the axis, on the measuring line (the other
linear axes held at their ``line`` readings). The reading is

    ``P_ij = P_i + e_axis . (tip_W(actual) - tip_W(nominal))``

from the exact Pinocchio chain of :class:`sim.machine.Machine`, with the
time ``t_s`` and the direction of motion at the stop passed in, so any
:class:`~sim.errorfuncs.Drift` (thermal drift) and
:class:`~sim.errorfuncs.Reversal` (lost motion) in the machine's error
functions shows as it would on a real test, together with the angular
errors' Abbe offsets at the measuring line. The targets and the line are
readings (the stylus-tip centre, the machine's probe offsets J in effect),
so the errors a stop reads are those of the axis positions ``P_i + J``
(CONTRIBUTING.md, "Error conventions"): with a 150 mm probe on Z, a Z
test's target P_i reads the errors of Z at P_i + 150 mm. The log says so: a
machine with J not 0 writes it as ``tool_offset_mm``
(:data:`core.positioning.TOOL_OFFSET_KEY`), so a reader places the targets at
the axis positions (a compensation table built from the log,
:func:`hardware.linuxcnc.positioning_comp_file`). A random scatter (machine
repeatability plus instrument noise, normal, k = 1) is added from a
passed generator.

Test cycles (both are stated in the log's ``cycle_kind``):

``linear``
    each cycle runs up through all targets (approach ``+``), overruns the
    last by ``overrun``, comes back down through all targets (approach
    ``-``) and overruns the first; then the next cycle.
``pilgrim``
    each target in turn is approached ``n`` times from each side, going
    back and forth (``P_i - overrun -> P_i``, ``P_i + overrun -> P_i``)
    before the axis steps to the next target: a step cycle, ISO 230-2:2014
    Annex B's optional cycle, not the standard test (``vmt iso230-2`` says so).

Times come from the moves at ``feed`` plus a ``dwell`` at each stop (the
reading is taken at the end of the dwell). Units: SI inside (m, s); the
log is written in its own units (mm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core import iso
from core.exceptions import ConfigError
from core.positioning import CYCLE_KINDS, N_MIN, TOOL_OFFSET_KEY, PositioningLog, make_positioning_log
from core.units import MM, UM

#: Default feed between targets, m/s (2000 mm/min).
FEED_MPS = 2.0 / 60.0
#: Default dwell at each target before the reading, s.
DWELL_S = 2.0
#: Default overrun at each reversal, m.
OVERRUN_M = 5.0 * MM
#: Interior targets are shifted by a random r in [-p/4, p/4] (p: the
#: uniform spacing), ISO 230-2's ``P_i = (i - 1) p + r`` for an irregular
#: spacing that samples periodic (pitch) errors; the end targets keep the
#: measurement travel.
TARGET_JITTER = 0.25
#: Decimals (mm) of the targets written in the log: each target is the double nearest its commanded
#: decimal value, so the file shows ``84.971``, not the metre-to-millimetre conversion's
#: ``84.97099999999999`` (exact round trips either way; 1e-9 mm is far below any target's resolution).
TARGET_DECIMALS_MM = 9


@dataclass(frozen=True)
class PositioningPlan:
    """What the test does: targets, cycles, moves (SI units).

    Attributes
    ----------
    axis : str
        Linear axis under test (``X``, ``Y`` or ``Z``).
    targets_m : (m,) float
        Target readings P_i, ascending, m.
    cycles : int
        n, approaches per target and direction.
    cycle_kind : str
        ``linear`` or ``pilgrim``.
    overrun_m : float
        Travel beyond the target before each reversal, m.
    feed_mps : float
        Feed of every move, m/s.
    dwell_s : float
        Stop at a target before the reading, s.
    line_m : (3,) float
        Readings X, Y, Z of the measuring line, m (the axis's own entry is
        replaced by the target).
    """

    axis: str
    targets_m: tuple[float, ...]
    cycles: int
    cycle_kind: str
    overrun_m: float
    feed_mps: float
    dwell_s: float
    line_m: tuple[float, float, float]


def iso_targets(lo_m: float, hi_m: float, m: int, rng: np.random.Generator | None = None) -> np.ndarray:
    """``m`` targets over ``[lo, hi]``: ``P_i = lo + (i - 1) p + r_i`` (ISO 230-2).

    ``p = (hi - lo) / (m - 1)``; ``r_i`` uniform in ``[-p/4, p/4]`` for the
    interior targets (``TARGET_JITTER``), rounded to 1 µm, 0 at both ends;
    no ``rng``: a uniform spacing.
    """
    if m < 2:
        raise ConfigError(f"targets: need at least 2, got {m}")
    if not (np.isfinite(lo_m) and np.isfinite(hi_m) and lo_m < hi_m):
        raise ConfigError(f"measurement travel must be finite with min < max, got {lo_m / MM:g}..{hi_m / MM:g} mm")
    p = (hi_m - lo_m) / (m - 1)
    P = lo_m + p * np.arange(m)
    if rng is not None and m > 2:
        P[1:-1] += rng.uniform(-TARGET_JITTER * p, TARGET_JITTER * p, m - 2)
        P[1:-1] = np.round(P[1:-1] / 1e-6) * 1e-6  # commanded to 1 um, as a part program would
    return P


def positioning_plan(machine, axis: str, *, targets_m=None, n_targets: int = 11, travel_m=None,
                     cycles: int = 5, cycle_kind: str = "linear", overrun_m: float = OVERRUN_M,
                     feed_mps: float = FEED_MPS, dwell_s: float = DWELL_S, line_m=None,
                     rng: np.random.Generator | None = None) -> PositioningPlan:
    """An ISO 230-2 test plan for ``axis`` of ``machine``, checked against its strokes.

    Parameters
    ----------
    machine : sim.machine.Machine
    axis : str
        ``X``, ``Y`` or ``Z``.
    targets_m : (m,) float, optional
        Explicit targets, m; otherwise :func:`iso_targets` over
        ``travel_m`` (default: the stroke less the overrun at each end)
        with ``n_targets`` targets and ``rng`` for the irregular spacing.
    cycles, cycle_kind, overrun_m, feed_mps, dwell_s :
        See :class:`PositioningPlan`.
    line_m : (3,) float, optional
        Measuring line readings, m (default: the middle of each stroke).

    Raises
    ------
    ConfigError
        Unknown or rotary axis, a target or overrun point outside the
        stroke, fewer than 2 cycles or targets, a non-positive feed, a
        negative dwell or overrun, an unknown cycle kind.
    """
    strokes = machine.config.strokes
    if axis not in iso.LINEAR_AXES:
        raise ConfigError(f"axis {axis!r}: only the linear axes X, Y, Z can be tested "
                          "(a rotary axis needs the angular form of the test)")
    if cycle_kind not in CYCLE_KINDS:
        raise ConfigError(f"cycle kind {cycle_kind!r} is not one of {', '.join(CYCLE_KINDS)}")
    if int(cycles) != cycles or cycles < N_MIN:
        raise ConfigError(f"cycles must be a whole number >= {N_MIN}, got {cycles!r}")
    for name, v in (("overrun", overrun_m), ("dwell", dwell_s)):
        if not (np.isfinite(v) and v >= 0):
            raise ConfigError(f"{name} must be >= 0, got {v!r}")
    if not (np.isfinite(feed_mps) and feed_mps > 0):
        raise ConfigError(f"feed must be > 0, got {feed_mps!r}")
    lo, hi = strokes[axis]
    if targets_m is None:
        t_lo, t_hi = (lo + overrun_m, hi - overrun_m) if travel_m is None else (float(travel_m[0]), float(travel_m[1]))
        P = iso_targets(t_lo, t_hi, int(n_targets), rng)
    else:
        P = np.sort(np.asarray(targets_m, float).reshape(-1))
        if P.size < 2 or not np.all(np.isfinite(P)):
            raise ConfigError("targets: need at least 2 finite values")
        if np.any(np.diff(P) <= 0):
            raise ConfigError("targets must be distinct")
    if P[0] - overrun_m < lo - 1e-12 or P[-1] + overrun_m > hi + 1e-12:
        raise ConfigError(
            f"axis {axis}: targets {P[0] / MM:g}..{P[-1] / MM:g} mm with overrun {overrun_m / MM:g} mm "
            f"leave the stroke {lo / MM:g}..{hi / MM:g} mm")
    if line_m is None:
        line = tuple(0.5 * (strokes[a][0] + strokes[a][1]) for a in iso.LINEAR_AXES)
    else:
        line = tuple(float(v) for v in np.asarray(line_m, float).reshape(-1))
        if len(line) != 3 or not np.all(np.isfinite(line)):
            raise ConfigError(f"measuring line must be 3 finite readings X, Y, Z, got {line_m!r}")
        for a, v in zip(iso.LINEAR_AXES, line):
            if a != axis and not (strokes[a][0] <= v <= strokes[a][1]):
                raise ConfigError(f"measuring line: {a} = {v / MM:g} mm outside the stroke "
                                  f"{strokes[a][0] / MM:g}..{strokes[a][1] / MM:g} mm")
    return PositioningPlan(axis=axis, targets_m=tuple(float(p) for p in P), cycles=int(cycles),
                           cycle_kind=cycle_kind, overrun_m=float(overrun_m), feed_mps=float(feed_mps),
                           dwell_s=float(dwell_s), line_m=line)


def schedule(plan: PositioningPlan) -> dict[str, np.ndarray]:
    """The readings of ``plan`` in the order taken (no machine needed).

    Returns
    -------
    dict of (N,) arrays
        ``target_index`` (int), ``target_m``, ``cycle`` (int, 1-based),
        ``direction`` (+1 / -1: sign of the axis velocity arriving at the
        stop), ``t_s`` (end of the dwell; t = 0 at the start point
        ``P_1 - overrun``).
    """
    P = np.asarray(plan.targets_m)
    m, n, ov = P.size, plan.cycles, plan.overrun_m
    pos, t = P[0] - ov, 0.0
    out = {"target_index": [], "cycle": [], "direction": [], "t_s": []}

    def move(x):
        nonlocal pos, t
        t += abs(x - pos) / plan.feed_mps
        pos = x

    def read(i, j, d):
        nonlocal t
        move(P[i])
        t += plan.dwell_s
        out["target_index"].append(i)
        out["cycle"].append(j)
        out["direction"].append(d)
        out["t_s"].append(t)

    if plan.cycle_kind == "linear":
        for j in range(1, n + 1):
            for i in range(m):
                read(i, j, +1)
            move(P[-1] + ov)
            for i in range(m - 1, -1, -1):
                read(i, j, -1)
            move(P[0] - ov)
    else:  # pilgrim
        for i in range(m):
            for j in range(1, n + 1):
                move(P[i] - ov)
                read(i, j, +1)
                move(P[i] + ov)
                read(i, j, -1)
    res = {k: np.asarray(v) for k, v in out.items()}
    res["target_m"] = P[res["target_index"]]
    return res


def deviations_m(machine, plan: PositioningPlan, target_m, t_s, direction) -> np.ndarray:
    """Exact deviation along the axis at the measuring line, (N,) m.

    ``e_axis . (tip_W(actual) - tip_W(nominal))`` at readings ``line``
    with the axis at ``target_m``, at times ``t_s`` moving in
    ``direction`` (rotary axes at zero).
    """
    k = iso.LINEAR_AXES.index(plan.axis)
    target = np.asarray(target_m, float).reshape(-1)
    lin = np.tile(np.asarray(plan.line_m, float), (target.size, 1))
    lin[:, k] = target
    dirn = np.zeros((target.size, 3))
    dirn[:, k] = np.asarray(direction, float).reshape(-1)
    rot = np.zeros((target.size, len(machine.rotary_axes))) if machine.rotary_axes else None
    actual = machine.tip_W(lin, rot, t_s=np.asarray(t_s, float), direction=dirn)
    nominal = machine.tip_W_nominal(lin, rot)
    return actual[:, k] - nominal[:, k]


def simulate_positioning(machine, plan: PositioningPlan, rng: np.random.Generator, *,
                         noise_m: float = 0.0, meta: dict | None = None) -> PositioningLog:
    """Run ``plan`` on ``machine``: a ``positioning-log/1`` log (mm, s).

    Parameters
    ----------
    machine : sim.machine.Machine
    plan : PositioningPlan
    rng : numpy.random.Generator
        Draws the random scatter.
    noise_m : float
        Standard deviation (k = 1) of the random scatter of each reading
        (machine repeatability and instrument noise together), m.
    meta : dict, optional
        Extra metadata for the log.
    """
    if not (np.isfinite(noise_m) and noise_m >= 0):
        raise ConfigError(f"noise must be >= 0, got {noise_m!r}")
    s = schedule(plan)
    dev = deviations_m(machine, plan, s["target_m"], s["t_s"], s["direction"])
    if noise_m > 0:
        dev = dev + rng.normal(0.0, noise_m, dev.shape)
    # the commanded values in the log's unit: m -> mm leaves the last bits of a double off the decimal a
    # part program commands (84.971 mm read as 84.97099999999999); rounded to 1e-9 mm (1 pm, far below
    # the 1 um the targets are commanded to) each is the double nearest its decimal, written as such
    target_mm = np.round(s["target_m"] / MM, TARGET_DECIMALS_MM)
    name = getattr(machine.config, "name", "")
    m = {"axis": plan.axis, "machine": name,
         "instrument": "virtual laser interferometer (exact chain"
                       + (f", scatter {noise_m / UM:g} um k=1)" if noise_m else ")"),
         "cycle_kind": plan.cycle_kind,
         "line_mm": ",".join(f"{v / MM:g}" for v in plan.line_m),
         "overrun_mm": f"{plan.overrun_m / MM:g}", "feed_mm_min": f"{plan.feed_mps / MM * 60:g}",
         "dwell_s": f"{plan.dwell_s:g}"}
    J = np.asarray(machine.config.J_m, float)
    if np.any(J != 0):  # the targets are readings: the axis positions are target + J (TOOL_OFFSET_KEY)
        m[TOOL_OFFSET_KEY] = ",".join(repr(float(np.round(v / MM, 9))) for v in J)
    m.update({str(k): str(v) for k, v in (meta or {}).items()})
    return make_positioning_log(target_mm, s["cycle"], s["direction"], target_mm + dev / MM,
                                t_s=s["t_s"], meta=m, unit="mm", source=f"simulated {name} {plan.axis}")
