"""Virtual CMM study: a user's plan and task, Monte Carlo through the exact simulator.

Each run draws a machine (the machine file's errors, the best estimate of
its state, plus one draw of every declared error term of the task), draws
the probing noise, simulates every touch the task uses on the exact
Pinocchio chain (:func:`sim.probe.simulate_touches`), fits the features
and evaluates the measurands (:mod:`core.vcmm`). Runs go in batches until
JCGM 101's adaptive rule (7.9) says every measurand's y, u, and coverage
interval ends are stable; then the budget: the same procedure with one
source at a time (the others at their best estimate, zero), reporting u.
Each run's error about its true value (measured minus the run's part on a
perfect machine without noise, :func:`true_values`) gives the interval
about the true value: a form's noise bias makes the measured value's own
interval miss it (review33a F6).

The part: each task feature's nominal surface is the exact primitive (plane,
cylinder for a circle, sphere, cylinder) through the plan's nominal
contact points, in the table frame W (the part moves with the table).
A plan row no task feature uses is not simulated: it cannot change a
measurand.

Run ``k`` of seed ``s`` draws from ``SeedSequence([s, k])`` alone: results
are identical per seed, however the runs are batched.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from core import vcmm as V
from core.exceptions import ConfigError, FitError, PlanError
from core.state import POSITIONS, POSITIONS_READINGS
from core.touches import ProbeStatus

#: Approach start before the nominal contact and search beyond it, m. find_contacts brackets the
#: contact with 7 samples, 1/6 of the travel apart; the nominal contact (0.4 of the travel) falls
#: between two, never on one (a root exactly on a sample costs ~30 bisection steps there).
CLEARANCE_M = 1.0e-3
OVERSHOOT_M = 1.5e-3
#: Probing feed (the campaign default, 240 mm/min), m/s.
FEED_MPS = 0.240 / 60.0
#: Largest distance of a plan's nominal contact from its feature's fitted primitive, m. A plan's
#: points are the user's; farther than this they do not describe one plane/circle/sphere/cylinder.
NOMINAL_FIT_TOL_M = 1.0e-6


@dataclass(frozen=True)
class Setting:
    """Everything a run needs, fixed for the study (SI, frame R for the touches)."""

    task: V.Task
    rows: dict           # feature -> rows of the used touches (indices into the used arrays)
    Xn_R: np.ndarray     # (k, 3) nominal tip centres at contact
    n_R: np.ndarray      # (k, 3) nominal outward normals
    rot_rad: np.ndarray | None   # (k, nrot)
    sdf_W: tuple         # one callable per feature: W points -> signed distance to the material, m
    group: np.ndarray    # (k,) feature index of each touch
    config: object       # sim.machine.MachineConfig: the best estimate of the machine
    probe: object        # sim.probe.ProbeConfig (noise: the task's or the machine's)
    sources: tuple       # names: declared terms, then the probe's repeatability
    targets: tuple = ()  # (k,) the plan's target of each used touch
    centre_R: np.ndarray | None = None   # (3,) the part's thermal centre: centroid of its probed surface points
    state: object = None  # core.state.MachineState: an identified state drawn from N(estimate, covariance)
    form_u: tuple = ()    # per task.forms: form_axis (W) or None
    t0_s: np.ndarray | None = None   # (k,) start of each touch's approach, s ([drift]; else 0)


#: The budget's name of an identified machine state (``--machine-state``), and its key among a run's draws.
STATE_SOURCE = "machine state"
STATE_KEY = (STATE_SOURCE, -1)


@dataclass(frozen=True)
class Surface:
    """A nominal feature surface as a signed distance to the material (+ outside), W, m.

    ``kind`` plane (``c`` a point, ``a`` the outward normal), ball (a circle's
    cylinder along Z when ``k`` = 2, a sphere when 3: centre ``c[:k]``, radius
    ``R``), cylinder (axis through ``c`` along ``a``). ``sign`` -1 for a hollow
    (bore). A plain dataclass, so a study can be shipped to Dask workers.
    """

    kind: str
    c: np.ndarray
    a: np.ndarray | None = None
    R: float = 0.0
    k: int = 3
    sign: float = 1.0

    def __call__(self, p: np.ndarray) -> np.ndarray:
        if self.kind == "plane":
            return (p - self.c) @ self.a
        if self.kind == "ball":
            return self.sign * (np.linalg.norm(p[:, :self.k] - self.c[:self.k], axis=1) - self.R)
        d = p - self.c
        return self.sign * (np.linalg.norm(d - np.outer(d @ self.a, self.a), axis=1) - self.R)


@dataclass(frozen=True)
class Expanded:
    """``surface`` grown by ``1 + e`` about ``c`` (exact: distances scale too)."""

    surface: object
    e: float
    c: np.ndarray

    def __call__(self, p: np.ndarray) -> np.ndarray:
        return (1.0 + self.e) * self.surface(self.c + (p - self.c) / (1.0 + self.e))


@dataclass(frozen=True)
class Formed:
    """``surface`` with the part's form: its boundary ``f(p)`` further out (``sdf - f``), W, m.

    ``f = a cos(k theta + phase)`` (``lobes`` k: theta the azimuth about the
    circle's Z / the cylinder's axis from ``e1``) or ``a cos(2 pi (p - c) . u /
    wavelength + phase)`` (plane, line: ``u`` along the surface). Evaluated at the
    tip centre, which has the azimuth / coordinate ``s`` of its foot on the nominal
    surface when it approaches along the normal: a point-contact model.
    """

    surface: Surface
    a: float
    phase: float
    lobes: int | None = None
    wavelength: float | None = None
    u: np.ndarray | None = None   # plane, line: unit, along the surface; cylinder: e1

    def f(self, p: np.ndarray) -> np.ndarray:
        sf = self.surface
        d = p - sf.c
        if self.lobes is None:
            return self.a * np.cos(2.0 * math.pi * (d @ self.u) / self.wavelength + self.phase)
        if sf.kind == "ball":
            th = np.arctan2(d[:, 1], d[:, 0])
        else:   # anticlockwise about the axis directed along its largest component, positive
            ax = sf.a if sf.a[np.argmax(np.abs(sf.a))] > 0 else -sf.a
            th = np.arctan2(d @ np.cross(ax, self.u), d @ self.u)
        return self.a * np.cos(self.lobes * th + self.phase)

    def __call__(self, p: np.ndarray) -> np.ndarray:
        return self.surface(p) - self.f(p)


def form_axis(sdf: Surface, form: V.PartForm) -> np.ndarray | None:
    """The unit direction ``u`` of a feature's form (:class:`Formed`), W; None for a circle."""
    if sdf.kind == "ball":
        return None
    if sdf.kind == "cylinder":
        ref = np.array([1.0, 0.0, 0.0]) if abs(sdf.a[0]) < 0.99 else np.array([0.0, 1.0, 0.0])
    elif form.along is None:   # a line: its direction z x n
        ref = np.cross([0.0, 0.0, 1.0], sdf.a)
    else:
        ref = np.asarray(form.along, float)
    u = ref - (ref @ sdf.a) * sdf.a
    if np.linalg.norm(u) < 1e-6:
        raise ConfigError(f"form.{form.feature}.along: the plane's normal; give an axis along the plane")
    return u / np.linalg.norm(u)


def _primitive_sdf(kind: str, p_W: np.ndarray, n_W: np.ndarray, r: float, name: str) -> Surface:
    """The exact primitive through the nominal contacts (``p_W`` tip centres, ``n_W`` outward normals, W)."""
    f = V.fit_feature(kind, p_W, n_W, r)  # the same fits as the measurands (tip centres, radius applied)
    if kind == "plane":
        sdf = Surface("plane", f.point, f.direction)
    elif kind == "line":   # the trace of a vertical face: the plane through the line, normal d x z
        sdf = Surface("plane", f.point, np.cross(f.direction, [0.0, 0.0, 1.0]))
    elif kind in ("circle", "sphere"):
        k = 2 if kind == "circle" else 3
        sdf = Surface("ball", f.point.copy(), None, f.radius, k,
                      1.0 if V._outside(p_W[:, :k], n_W[:, :k], f.point[:k]) else -1.0)
    else:
        sdf = Surface("cylinder", f.point, f.direction, f.radius, 3,
                      1.0 if V._outside(p_W, n_W, f.point, f.direction) else -1.0)
    dev = np.abs(sdf(p_W - r * n_W))
    worst = float(np.max(dev))
    if worst > NOMINAL_FIT_TOL_M:
        raise PlanError(f"feature {name!r}: the plan's nominal points are not on one {kind} "
                        f"(largest deviation {worst * 1e6:.3f} um > {NOMINAL_FIT_TOL_M * 1e6:g} um)")
    return sdf


def state_errors(state, values=None) -> dict:
    """The error functions of an identified state (:class:`core.state.MachineState`) for ``values``
    (SI, default its estimate): ``{symbol: sim.errorfuncs function}``."""
    from sim.errorfuncs import Constant, LinearTable, SplineTable

    out = {}
    for sym, (kind, x, v) in state.functions(values).items():
        if kind == "constant":
            out[sym] = Constant(float(v))
        else:
            out[sym] = (LinearTable if kind == "linear" else SplineTable)(tuple(x.tolist()), tuple(np.asarray(v).tolist()))
    return out


def prepare(plan, task: V.Task, spec, *, noise_um: float | None = None, state=None) -> Setting:
    """The study's fixed part from a plan (:class:`core.probelog.ProbeLog`), a task and a machine spec.

    ``noise_um`` (``--noise-um``) overrides the task's ``[probe] noise_um``,
    which overrides the machine file's probe; a standard deviation (k = 1).
    ``state`` (``--machine-state``, :func:`core.state.read_estimate`): an
    identified state; its symbols' errors replace the machine file's (the
    estimate is the best estimate, each run draws from N(estimate, covariance)),
    the machine file's other errors and the task's declared terms stay.
    """
    from sim.machine import Machine

    if plan.n == 0:
        raise PlanError(f"{plan.source}: the plan has no rows")
    cfg = spec.config
    if state is not None:
        chain_axes = Machine(dataclasses.replace(cfg, errors={})).chain.axes
        for sym in state.symbols:
            ax = V.iso.symbol(sym).axis
            if ax not in chain_axes:
                raise ConfigError(f"{state.source}: {sym}: axis {ax} is not in machine {cfg.name}'s chain {cfg.chain}")
        cfg = dataclasses.replace(cfg, errors={**dict(cfg.errors), **state_errors(state)})
    nominal = Machine(dataclasses.replace(cfg, errors={}))
    rot_deg = np.column_stack([plan.col(f"{a}_deg").astype(float) if plan.has(f"{a}_deg") else np.zeros(plan.n)
                               for a in "ABC"])
    rot_deg = np.nan_to_num(rot_deg)
    txt = {c: (plan.col(c).astype(str) if plan.has(c) else np.full(plan.n, "")) for c in ("target", "feature", "setup")}
    rows_all = V.feature_rows(task, txt["target"], txt["feature"], txt["setup"], rot_deg)
    used = np.unique(np.concatenate(list(rows_all.values())))
    where = {int(r): i for i, r in enumerate(used)}
    rows = {k: np.array([where[int(r)] for r in v]) for k, v in rows_all.items()}
    Xn_R = np.column_stack([plan.col(f"{c}n_mm").astype(float) for c in "XYZ"])[used] * 1e-3
    n_R = np.column_stack([plan.col(f"n{c}").astype(float) for c in "xyz"])[used]
    axes = nominal.rotary_axes
    extra = [a for a in "ABC" if a not in axes and np.any(rot_deg[used, "ABC".index(a)] != 0)]
    if extra:
        raise PlanError(f"{plan.source}: rows at {extra[0]} != 0, machine {cfg.name} has no {extra[0]} axis")
    rot = np.deg2rad(rot_deg[used][:, ["ABC".index(a) for a in axes]]) if axes else None
    tilted_xy_fits(task, rows, rot_deg[used], n_R)
    probe = spec.probe
    if plan.has("stylus_r_mm"):
        r_plan = plan.col("stylus_r_mm").astype(float)[used]
        if np.all(np.isfinite(r_plan)):
            if np.ptp(r_plan) > 1e-9:
                raise PlanError(f"{plan.source}: the task's touches have different stylus radii")
            probe = dataclasses.replace(probe, stylus_r_m=float(r_plan[0]) * 1e-3)  # the plan's stylus
    noise = noise_um if noise_um is not None else task.probe_noise_um
    if noise is not None:
        probe = dataclasses.replace(probe, repeatability_k2_m=2.0 * noise * 1e-6)
    r = probe.stylus_r_m
    p_W = nominal.tip_W_nominal(Xn_R, rot)
    T_R_W = nominal.T_R_W_nominal(rot, Xn_R)
    n_W = np.einsum("nji,nj->ni", T_R_W[:, :3, :3], n_R)
    sdfs, group = [], np.zeros(len(used), int)
    for k, f in enumerate(task.features):
        idx = rows[f.name]
        group[idx] = k
        try:
            sdfs.append(_primitive_sdf(f.kind, p_W[idx], n_W[idx], r, f.name))
        except FitError as e:
            raise PlanError(f"feature {f.name!r}: {e}") from None
    overlap = sum(len(v) for v in rows.values()) != len(used)
    if overlap:
        raise ConfigError(f"{task.source}: a plan row belongs to two features (each touch probes one surface)")
    names = [f.name for f in task.features]
    form_u = tuple(form_axis(sdfs[names.index(fm.feature)], fm) for fm in task.forms)
    sources = (tuple(t.source for t in task.declared) + ((V.PROBE_SOURCE,) if probe.sigma_m > 0 else ())
               + task.probe_sources + task.form_sources + task.drift_sources
               + (task.temperature.sources if task.temperature else ())
               + ((STATE_SOURCE,) if state is not None and state.factor.size else ()))
    if task.temperature is not None and rot is not None and np.any(rot != 0):
        raise ConfigError(f"{task.source}: [temperature] with rotary positions other than 0 is not supported "
                          "(the part's expansion is applied in the machine frame)")
    for t in task.declared:
        ax = V.iso.symbol(t.symbol).axis
        if ax not in nominal.chain.axes:
            raise ConfigError(f"{task.source}: declared.{t.symbol}: axis {ax} is not in machine {cfg.name}'s "
                              f"chain {cfg.chain}")
    declared_bounded(task, cfg.strokes)
    return Setting(task, rows, Xn_R, n_R, rot, tuple(sdfs), group, cfg, probe, sources,
                   tuple(txt["target"][used].tolist()), np.mean(p_W - r * n_W, axis=0), state, form_u,
                   touch_times(plan, task, used))


#: The trial slope (m/m, 100 um/m) of EXX and EYY by which :func:`state_scale` finds the measurands a state's
#: unknown scale moves: a run without noise with that slope added, against one without.
SCALE_TRIAL = 1e-4
#: A measurand moved by more than this (SI: m, or rad for an angle) at :data:`SCALE_TRIAL` carries the scale:
#: a length L moves by L x 1e-4 (2 um on a 20 mm diameter), a form error of a horizontal plane or a face across
#: X by nothing (the touches' contact search resolves 1e-14 m); 1 nm at 100 um/m is a sensitivity of 1e-5 m
#: per unit scale, far below any length a task measures and far above the simulator's rounding.
SCALE_CARRIED_SI = 1e-9


def state_scale(st: Setting) -> dict | None:
    """What ``st``'s identified state cannot carry: its scale, when the state says it is unknown
    (:attr:`core.state.MachineState.scale_unknown`: a self-calibration without a length reference), and the
    measurands it moves; None when the state knows its scale (or there is no state).

    Returns ``{"what": "scale", "why": the state's convention, "measurands": {name: [symbols whose slope
    moves it]}}``. Which measurands move is found, not assumed from their kind: each of EXX, EYY
    (:data:`core.state.SCALE_SYMBOLS`) gets a slope of :data:`SCALE_TRIAL` in a run without noise (the
    machine's structure with the state's estimate), and a measurand that moves by more than
    :data:`SCALE_CARRIED_SI` carries the scale. Such a measurand is refused (:func:`state_scale_check`)."""
    from core.state import SCALE_SYMBOLS
    from sim.machine import Machine

    state = st.state
    if state is None or state.scale_unknown is None:
        return None
    chain_axes = Machine(dataclasses.replace(st.config, errors={})).chain.axes
    syms = [sym for sym in SCALE_SYMBOLS if V.iso.symbol(sym).axis in chain_axes]
    y0 = V.evaluate(st.task, st.rows, simulate_run(st, {}, None, noise=False), st.n_R, st.probe.stylus_r_m, st.Xn_R)
    moved: dict = {}
    for sym in syms:
        p = simulate_run(st, {(sym, 1): SCALE_TRIAL}, None, noise=False)
        dy = V.evaluate(st.task, st.rows, p, st.n_R, st.probe.stylus_r_m, st.Xn_R) - y0
        for m, d in zip(st.task.measurands, dy):
            if abs(d) > SCALE_CARRIED_SI:
                moved.setdefault(m.name, []).append(sym)
    return {"what": "scale", "why": state.scale_unknown, "measurands": moved}


def state_scale_check(st: Setting) -> tuple[str | None, str | None]:
    """``(refusal, notice)`` of the state's scale (:func:`state_scale`), each one line or None.

    A state whose scale is unknown (a 2D self-calibration without a length reference: ``vmt identify``
    without ``--delta-l-um``) has the scale as its gauge: EXX pinned to 0 at its last node as well as its
    first, so EXX and EYY lack one common slope, the tool tip's scale at the probed height (the axes' own
    scale with the pitch and yaw errors' Abbe terms). It is fixed, not estimated: no covariance of the
    state holds it, and a length measured with the state is off by that scale times the length (the demo's
    machine, its tip scale -28 um/m: a 120 mm face distance 3.0 um off from it alone, U95 3.5 um; a 20 mm
    bore's diameter 1.4 um off, U95 1.2, outside; tests/scenarios/test_vcmm_route37.py). An interval
    that leaves a known systematic effect out of its budget is no coverage interval (GUM, JCGM 100 3.2.4
    and 6.3.1), and nothing in the state bounds it, so no interval is given: a measurand the scale moves is
    refused, with the way to a state that holds it (``vmt identify --delta-l-um``, a length measured along
    X; an MFB state, whose bar is calibrated). The task's ``[declared]`` slopes are not taken to carry it:
    they are drawn apart for X and Y, while the missing scale is one for both (a diameter or a diagonal
    distance would get about 0.7 of its spread), and a declaration made for the machine file's errors
    (the shipped block task's 10 um/m) would pass as a bound on a scale it does not bound. A task whose
    measurands the scale does not move (a horizontal plane's flatness) runs, with a notice."""
    scale = state_scale(st)
    if not scale:
        return None, None
    src = st.state.source
    if not scale["measurands"]:
        return None, (f"{src}: its scale is unknown (identified without --delta-l-um); no measurand of the task "
                      "moves with it")
    names = ", ".join(repr(k) for k in scale["measurands"])
    return (f"{src}: its scale is unknown (a self-calibration without a length reference) and {names} move with "
            "it: no interval can hold an error nothing in the state bounds; identify with --delta-l-um (a length "
            "measured along X) or leave those measurands out; nothing run"), None


#: The rigid motions of the tool relative to the part by which :func:`state_gauge` finds the measurands an
#: identified state's gauge moves: ``(name, {(symbol, power): value SI})``, each a translation along one axis
#: (a constant on its positioning error) or a small rotation about one axis (two straightness slopes,
#: ``dx = -r y, dy = r x`` about Z, and likewise), of :data:`GAUGE_TRIAL_M` / :data:`GAUGE_TRIAL_RAD`. A
#: motion applies to a state that holds every symbol it uses: an identification fixes the constant of every
#: positioning table and the slope of every straightness table it estimates by a convention, never by
#: measuring it (no artefact is placed at a known spot of the machine frame): core.selfcal's gauge,
#: ``EXX(x_o) = EYY(y_o) = EXY(y_o) = EYX(x_o) = 0`` and ``EYX(x_N) = EXY(y_N) = 0`` (X, Y and the rotation
#: about Z, eqs 16-17), core.volumetric's ISO 230-1 conventions, positioning zero at the first node and
#: straightness zero at both end nodes (all three translations and rotations; X primary, Y secondary).
GAUGE_TRIAL_M = 1e-5
#: The trial rotation, rad: a position 100 mm from the axis moves by 1 um; a distance or an angle between two
#: features by its square only (L r^2 = 1e-11 m on 100 mm), far below :data:`SCALE_CARRIED_SI`.
GAUGE_TRIAL_RAD = 1e-5
GAUGE_MOTIONS = (
    ("X translation", {("EXX", 0): GAUGE_TRIAL_M}),
    ("Y translation", {("EYY", 0): GAUGE_TRIAL_M}),
    ("Z translation", {("EZZ", 0): GAUGE_TRIAL_M}),
    ("rotation about X", {("EZY", 1): GAUGE_TRIAL_RAD, ("EYZ", 1): -GAUGE_TRIAL_RAD}),
    ("rotation about Y", {("EXZ", 1): GAUGE_TRIAL_RAD, ("EZX", 1): -GAUGE_TRIAL_RAD}),
    ("rotation about Z", {("EYX", 1): GAUGE_TRIAL_RAD, ("EXY", 1): -GAUGE_TRIAL_RAD}),
)


def _moved(st: Setting, y0: np.ndarray, coeffs: dict) -> list:
    """Names of the task's measurands a noise-free run with ``coeffs`` moves by more than :data:`SCALE_CARRIED_SI`."""
    p = simulate_run(st, coeffs, None, noise=False)
    dy = V.evaluate(st.task, st.rows, p, st.n_R, st.probe.stylus_r_m, st.Xn_R) - y0
    return [m.name for m, d in zip(st.task.measurands, dy) if abs(d) > SCALE_CARRIED_SI]


def state_gauge(st: Setting) -> dict | None:
    """What ``st``'s identified state cannot carry by its gauge: the rigid motions of the machine frame it fixed
    by convention (:data:`GAUGE_MOTIONS`: those whose symbols it holds) and the measurands they move; None
    without a state.

    A position in the machine frame (``quantity = "position"``), a line's direction from +X, a profile against
    the nominal surface move with such a motion; a distance, a diameter, an angle between two features and a
    form do not. Which measurands move is found, not assumed from their kind: each motion in a run without
    noise against one without, as :func:`state_scale`. Returns ``{"what": "gauge", "motions": [names],
    "why": [the state's conventions on those symbols], "measurands": {name: [motions]}, "datums": {name:
    [task planes across its axis]}}``: a position along x, y or z can be stated as its distance from such a
    plane, which the gauge does not move."""
    from sim.machine import Machine

    state = st.state
    if state is None:
        return None
    chain_axes = Machine(dataclasses.replace(st.config, errors={})).chain.axes
    held = set(state.tables)
    motions = [(name, c) for name, c in GAUGE_MOTIONS
               if all(sym in held and V.iso.symbol(sym).axis in chain_axes for sym, _ in c)]
    syms = sorted({sym for _, c in motions for sym, _ in c})
    why = [cv for cv in state.conventions if any(cv.startswith(s) for s in syms) and "scale" not in cv]
    moved: dict = {}
    if motions:
        y0 = V.evaluate(st.task, st.rows, simulate_run(st, {}, None, noise=False), st.n_R, st.probe.stylus_r_m,
                        st.Xn_R)
        for name, c in motions:
            for m in _moved(st, y0, c):
                moved.setdefault(m, []).append(name)
    datums = {}
    for m in st.task.measurands:
        if m.name in moved and m.quantity == "position":
            k = "xyz".index(m.axis)
            datums[m.name] = [f.name for f, sdf in zip(st.task.features, st.sdf_W)
                              if f.kind == "plane" and f.name not in m.of and abs(sdf.a[k]) > 0.99]
    return {"what": "gauge", "motions": [n for n, _ in motions], "why": why, "measurands": moved,
            "datums": datums}


def state_gauge_check(st: Setting) -> str | None:
    """The refusal (one line) of a task with a measurand the state's gauge moves (:func:`state_gauge`), or None.

    An identification sees the machine's errors only up to a rigid motion of its frame (the part's place in
    it is unknown to the identification as well), and fixes that motion by convention (``EXX = 0`` at the
    first node ...): the state is right about the machine's frame only up to it, and no covariance holds it.
    A position in the machine frame measured with the state is off by the truth's offset there (the demo's
    MFB state: a bore's x 7.7 um off against a U95 of 3.6 um, session 37), an error nothing in the state
    bounds, so no interval is given (as for the scale, :func:`state_scale_check`). Such a measurand is
    stated from a datum the part has (a distance from a plane of the part across the axis), which the gauge
    does not move: the refusal names the task's planes that would serve."""
    g = state_gauge(st)
    if not g or not g["measurands"]:
        return None
    names = ", ".join(repr(k) for k in g["measurands"])
    order = [n for n, _ in GAUGE_MOTIONS]
    motions = sorted({mo for v in g["measurands"].values() for mo in v}, key=order.index)
    syms = {sym for n, c in GAUGE_MOTIONS if n in motions for sym, _ in c}
    conventions = [cv for cv in g["why"] if any(cv.startswith(s) for s in syms)]
    hints = []
    for m, planes in g["datums"].items():
        if planes:
            hints.append(f"{m!r} as a distance from " + " or ".join(repr(p) for p in planes))
        else:
            hints.append(f"{m!r} from a plane of the part across its axis (none in the task)")
    hint = ("; state " + ", ".join(hints)) if hints else ""
    conv = (f" ({', '.join(conventions[:3])}{', ...' if len(conventions) > 3 else ''})" if conventions else "")
    verb = "moves" if len(g["measurands"]) == 1 else "move"
    return (f"{st.state.source}: {names} {verb} with the state's gauge, the {', '.join(motions)} of the machine "
            f"frame its identification fixed by convention{conv}, not by measuring: no interval can hold an error "
            f"nothing in the state bounds{hint}; or leave {'it' if verb == 'moves' else 'those measurands'} out; "
            "nothing run")


def identification_lobing(doc: dict) -> dict | None:
    """The probe lobing an identification found in its residuals and left out of its covariance: an identify
    JSON's ``not_covered.approach_direction`` (core.selfcal: residuals that follow the approach azimuth, a
    pre-travel lobing, F test), or None (none found, or a file without the record: an MFB result, a bare
    ``vmt-estimate/1``)."""
    nc = doc.get("not_covered") if isinstance(doc, dict) else None
    ad = nc.get("approach_direction") if isinstance(nc, dict) else None
    return ad if isinstance(ad, dict) else None


def state_moved(st: Setting) -> list:
    """Names of the task's measurands the identified state moves at all: a run without noise at the state's
    estimate against runs at two draws from its covariance (fixed draws, ``default_rng(0)``); a measurand
    moved by more than :data:`SCALE_CARRIED_SI` depends on the state."""
    y0 = V.evaluate(st.task, st.rows, simulate_run(st, {}, None, noise=False), st.n_R, st.probe.stylus_r_m, st.Xn_R)
    rng = np.random.default_rng(0)
    moved: list = []
    for _ in range(2):
        for name in _moved(st, y0, {STATE_KEY: st.state.draw(rng)}):
            if name not in moved:
                moved.append(name)
    return [m.name for m in st.task.measurands if m.name in moved]


#: A probe lobing its identification found (:func:`identification_lobing`) is refused when it shifts one of the
#: state's tables by at least this share of that value's U95 at its worst phase (``not_covered.approach_direction
#: .shift[block].worst_phase_ratio_to_u95``, the part the design absorbs included; the visible part's
#: ``ratio_to_u95`` where the file has no worst phase); below it the task runs with a notice. 1: the state's
#: own values then leave their U95, so it is no longer the calibrated state its covariance says. Session 38's
#: coverage (nmv3000 realistic, an order-2 lobe, the exact simulator, 20 seeds a row; README "--machine-state"):
#: a 1.5 um lobe (ratios 6.7-8.3) covered 13/30 had it run, 0.6 um (2.6-3.5) 49/60, 0.3 um 56/60 (as the
#: lobing-free 53/60: refused at this ratio all the same, the cost of a rule read from the tables, not from the
#: task's measurands), 0.2 um (ratios 0.7-1.3: 13 of 20 run) 38/39 where run, 0.1 um (5 of 20 found, ratios
#: under 0.8) 55/60, as lobing-free.
LOBING_REFUSE_RATIO = 1.0


def _lobing_ratios(st: Setting, lobing: dict) -> list:
    """``[(block, worst-phase ratio to U95, largest shift, unit)]`` of the state's tables, largest ratio first."""
    out = []
    for b, v in (lobing.get("shift") or {}).items():
        if b not in st.state.symbols or not isinstance(v, dict):
            continue
        r = v.get("worst_phase_ratio_to_u95", v.get("ratio_to_u95"))
        if isinstance(r, (int, float)) and math.isfinite(r):
            shift = v.get("worst_phase", v.get("largest"))
            out.append((b, float(r), abs(float(shift)) if isinstance(shift, (int, float)) else float("nan"),
                        str(v.get("unit", ""))))
    return sorted(out, key=lambda t: -t[1])


def state_lobing_check(st: Setting, lobing: dict | None) -> tuple[str | None, str | None]:
    """``(refusal, notice)`` of the probe lobing the state's identification found (:func:`identification_lobing`),
    each one line or None.

    A self-calibration models the probe as lobing-free (Ibaraki et al. assume the pre-travel compensated):
    a lobing probe's pre-travel, which follows the approach azimuth in the machine frame while the part turns
    on C, is taken partly into the tables. core.selfcal tests the residuals for it and, when found, says so
    in ``not_covered.approach_direction``: each table's shift and its ratio to the value's U95 (the visible
    part, and at the lobe's worst phase with the part the design absorbs), none of it in the covariance.
    vcmm's runs draw the state from that covariance, so the bias passes to the measurands uncarried: on the
    demo's machine with the length known exactly, the demo's probe (order 2, 1.5 um) puts a 120 mm face
    distance 4.1 um and a 128 mm bore-bore distance 4.9 um off the truth, the lobing-free probe's state 1.0
    and 0.3 um, U95 about 3 um (session 38, the exact simulator). The file holds each block's shift only as
    its largest value, not its shape along the table, so it cannot be propagated to a measurand: when a
    table of the state is shifted by at least :data:`LOBING_REFUSE_RATIO` of its U95, a measurand the state
    moves is refused (the way out: compensate the probe's pre-travel, identify again); below it the task runs
    with a notice saying what is left out."""
    if lobing is None or st.state is None:
        return None, None
    moved = state_moved(st)
    if not moved:
        return None, None
    names = ", ".join(repr(k) for k in moved)
    amp, k = lobing.get("amplitude_um"), lobing.get("lobe_order")
    what = (f"a probe pre-travel lobing of order {k}, ~{amp:.2f} um" if isinstance(amp, (int, float))
            and isinstance(k, int) else "a probe pre-travel lobing")
    ratios = _lobing_ratios(st, lobing)
    said = ", ".join(f"{b} {sh:.2f} {u}, {r:.1f} x" for b, r, sh, u in ratios[:3])
    worst = ratios[0][1] if ratios else float("inf")   # a record without ratios: its size unknown, refused
    src = st.state.source
    if worst >= LOBING_REFUSE_RATIO:
        verb = "moves" if len(moved) == 1 else "move"
        return (f"{src}: its identification found {what} in its residuals and left it out of its covariance "
                f"(not_covered.approach_direction), its tables shifted by it up to "
                + (f"{said} their U95 (worst phase)" if ratios else "an amount the file does not state")
                + f"; {names} {verb} with the state: no interval can hold a bias nothing in the state carries; "
                "compensate the probe's pre-travel (calibrate its lobing) and identify again; nothing run"), None
    return None, (f"{src}: its identification found {what} in its residuals, left out of its covariance and of "
                  f"these intervals: it shifts the state's tables by at most {worst:.2f} x their U95 (worst phase; "
                  f"refused from {LOBING_REFUSE_RATIO:g} x)")


def lobing_entry(st: Setting, lobing: dict | None) -> dict | None:
    """``machine_state.cannot_carry``'s entry for a probe lobing the identification found and vcmm ran with (below
    :data:`LOBING_REFUSE_RATIO`): ``{"what": "lobing", "lobe_order", "amplitude_um", "worst_ratio_to_u95",
    "measurands": [names the state moves]}``; None without one."""
    if lobing is None or st.state is None:
        return None
    ratios = _lobing_ratios(st, lobing)
    return {"what": "lobing", "lobe_order": lobing.get("lobe_order"), "amplitude_um": lobing.get("amplitude_um"),
            "worst_ratio_to_u95": ratios[0][1] if ratios else None, "measurands": state_moved(st)}


def state_carry_check(st: Setting, lobing: dict | None = None) -> tuple[str | None, str | None]:
    """``(refusal, notice)``, each one line or None: the state's scale (:func:`state_scale_check`), gauge
    (:func:`state_gauge_check`) and, with ``lobing`` (:func:`identification_lobing` of its file), the probe
    lobing its identification found (:func:`state_lobing_check`), together: a task refused for more than one
    reason is refused once, naming each."""
    why_s, notice = state_scale_check(st)
    why_l, notice_l = state_lobing_check(st, lobing)
    whys = [w for w in (why_s, state_gauge_check(st), why_l) if w]
    if not whys:
        notices = [n for n in (notice, notice_l) if n]
        return None, ("\n".join(notices) if notices else None)
    src = f"{st.state.source}: "
    parts = [w.removeprefix(src).removesuffix("; nothing run") for w in whys]
    return src + "; and ".join(parts) + "; nothing run", None


def cannot_carry(st: Setting) -> list | None:
    """``machine_state.cannot_carry`` of the report: what the state cannot carry, the scale's entry
    (:func:`state_scale`, when the state's scale is unknown) and the gauge's (:func:`state_gauge`); None
    without a state."""
    if st.state is None:
        return None
    return [e for e in (state_scale(st), state_gauge(st)) if e is not None]


def declared_bounded(task: V.Task, strokes: dict) -> None:
    """Refuse a declared limit whose error leaves the machine file's bounds over the axis's stroke (the one
    check, :func:`sim.machinefile.bound_problem`), naming the task file and the key: each term at its bound,
    then each symbol's terms summed at their worst (review32d F4: ``slope_um_per_m = 1e12`` was refused
    only later, as touch 0's early trigger, naming neither file nor key)."""
    from sim.errorfuncs import Constant, Periodic, Polynomial
    from sim.machinefile import bound_problem

    by_sym: dict = {}
    for t in task.declared:
        s = V.iso.symbol(t.symbol)
        U = "urad" if s.angular else "um"
        key = {"constant": f"constant_{U}", "slope": f"slope_{U}_per_m", "quadratic": f"quadratic_{U}_per_m2",
               "periodic": f"periodic_{U}"}[t.term]
        f = (Periodic(t.bound, t.period) if t.term == "periodic" else
             Constant(t.bound) if t.power == 0 else Polynomial((0.0,) * t.power + (t.bound,)))
        said = bound_problem(s, f, strokes[s.axis], "a declared")
        if said is not None:
            raise ConfigError(f"{task.source}: declared.{t.symbol}.{key}: at its bound {said}")
        c = by_sym.setdefault(t.symbol, [0.0, 0.0, 0.0])   # constant (and periodic amplitude), slope, quadratic
        c[0 if t.term == "periodic" else t.power] += t.bound
    for sym, (c0, c1, c2) in by_sym.items():
        s = V.iso.symbol(sym)
        for sign in (1.0, -1.0):   # the slope's worst side of the stroke
            said = bound_problem(s, Polynomial((c0, sign * c1, c2)), strokes[s.axis], "a declared")
            if said is not None:
                raise ConfigError(f"{task.source}: declared.{sym}: its terms at their bounds, summed, {said}")


#: Largest |n_z| (R) of a circle's or line's nominal normal at a tilted rotary position (A or B not 0):
#: those features are fitted in R's XY plane (core.vcmm.fit_feature), right only about R's Z.
XY_FIT_NZ_MAX = 1e-6


def tilted_xy_fits(task: V.Task, rows: dict, rot_deg: np.ndarray, n_R: np.ndarray) -> None:
    """Refuse a circle or line probed where the table is tilted and its axis is not R's Z.

    Circles and lines are fitted in the machine frame's XY plane. Found beside review30d F1 (session
    30): two 20 mm bores 84.853 mm apart on the part, probed at A = -30 on the mikron-ucp710 (their
    axes 30 deg from R's Z), read "nominal 19.079043 mm" and 79.372539 mm apart, exit 0; at A = -90
    the fit failed with "points are collinear". A feature whose normals are horizontal in R (a bore
    whose axis the tilt brings onto R's Z) is fitted right and passes.
    """
    for f in task.features:
        if f.kind not in ("circle", "line"):
            continue
        idx = rows[f.name]
        tilt = rot_deg[idx][:, :2]
        nz = np.abs(n_R[idx, 2])
        if np.any(np.abs(tilt) > 1e-9) and nz.max() > XY_FIT_NZ_MAX:
            a, b = tilt[0]
            raise ConfigError(
                f"{task.source}: features.{f.name}: a {f.kind} probed at A={a:g} B={b:g} with normals "
                f"{nz.max():.3g} out of the machine's XY plane: a {f.kind} is fitted in that plane, so its axis "
                "must be the machine's Z there (probe it at rotary zero, or where the tilt brings its axis onto Z)")


def touch_times(plan, task: V.Task, used: np.ndarray) -> np.ndarray | None:
    """Start of each used touch's approach (k,) s for a task with ``[drift]`` (module doc of core.vcmm), else None."""
    if not task.drift:
        return None
    t = plan.col("t_s").astype(float) if plan.has("t_s") else np.full(plan.n, np.nan)
    if np.all(np.isfinite(t[used])):
        return t[used] - np.nanmin(t)
    if task.touches_per_min is None:
        raise ConfigError(f"{task.source}: [drift] needs the plan's t_s on every used row or "
                          "drift.touches_per_min")
    return used.astype(float) * 60.0 / task.touches_per_min


def machine_errors(st: Setting, coeffs: dict) -> dict:
    """The machine file's errors plus the drawn terms ``{(symbol, power): value SI}`` (a periodic
    term: ``{(symbol, "periodic", k): (amplitude SI, period m, phase rad)}``)."""
    from sim.errorfuncs import Constant, Drift, Periodic, Polynomial

    errs = dict(st.config.errors)
    for sym in [k[1] for k in coeffs if k[0] == "drift"]:
        f = Drift(offset_rate=coeffs[("drift", sym)])
        errs[sym] = errs[sym] + f if sym in errs else f
    coeffs = {k: v for k, v in coeffs.items() if k[0] not in ("probe", "form", "drift")}   # probe_of, part_sdfs
    if STATE_KEY in coeffs:   # a drawn identified state replaces its estimate
        errs.update(state_errors(st.state, coeffs.pop(STATE_KEY)))
    for key in [k for k in coeffs if len(k) == 3]:
        a, period, phase = coeffs.pop(key)
        f = Periodic(a, period, phase)
        errs[key[0]] = errs[key[0]] + f if key[0] in errs else f
    by_sym: dict[str, list] = {}
    for (sym, power), v in coeffs.items():
        c = by_sym.setdefault(sym, [0.0, 0.0, 0.0])
        c[power] += v
    for sym, c in by_sym.items():
        while len(c) > 1 and c[-1] == 0.0:
            c.pop()
        f = Constant(c[0]) if len(c) == 1 else Polynomial(tuple(c))
        errs[sym] = errs[sym] + f if sym in errs else f
    return errs


def probe_of(st: Setting, coeffs: dict):
    """The study's probe with a run's drawn pre-travel (``("probe", "pretravel")``: m, added) and
    lobing (``("probe", "lobing")``: (k, a, b) m, one more term) applied."""
    pre, lob = coeffs.get(("probe", "pretravel")), coeffs.get(("probe", "lobing"))
    if pre is None and lob is None:
        return st.probe
    p = st.probe
    if pre is not None:
        p = dataclasses.replace(p, pretravel_m=p.pretravel_m + pre)
    if lob is not None:
        p = dataclasses.replace(p, lobing_m=tuple(p.lobing_m) + (lob,))
    return p


def part_sdfs(st: Setting, coeffs: dict) -> tuple:
    """The features' surfaces with a run's drawn forms (``("form", feature)``: (amplitude m, phase rad))."""
    if not st.task.forms:
        return st.sdf_W
    out = list(st.sdf_W)
    names = [f.name for f in st.task.features]
    for fm, u in zip(st.task.forms, st.form_u):
        if ("form", fm.feature) in coeffs:
            a, phase = coeffs[("form", fm.feature)]
            k = names.index(fm.feature)
            out[k] = Formed(out[k], a, phase, fm.lobes, fm.wavelength, u)
    return tuple(out)


def simulate_run(st: Setting, coeffs: dict, rng: np.random.Generator | None, *, noise: bool = True,
                 machine=None, e_part: float = 0.0) -> np.ndarray:
    """Reported tip centres (k, 3) m of the used touches on the machine with ``coeffs`` drawn,
    the part grown by ``1 + e_part`` about its thermal centre."""
    from sim.machine import Machine
    from sim.probe import simulate_touches

    m = machine if machine is not None else Machine(dataclasses.replace(st.config, errors=machine_errors(st, coeffs)))
    k = len(st.Xn_R)
    sdfs = part_sdfs(st, coeffs)
    sdfs = sdfs if e_part == 0.0 else tuple(Expanded(f, e_part, st.centre_R) for f in sdfs)
    res = simulate_touches(m, probe_of(st, coeffs), rng if noise else None, st.Xn_R + CLEARANCE_M * st.n_R, -st.n_R,
                           np.full(k, CLEARANCE_M + OVERSHOOT_M), st.rot_rad, np.zeros(k) if st.t0_s is None else st.t0_s, np.full(k, FEED_MPS),
                           sdfs, st.group, np.broadcast_to(np.eye(4), (k, 4, 4)))
    bad = res.status != ProbeStatus.OK
    if bad.any():
        i = int(np.argmax(bad))
        raise PlanError(f"touch {i} of feature {st.task.features[st.group[i]].name!r}: {res.status[i]} "
                        f"(the machine's errors move it beyond +-{CLEARANCE_M * 1e3:g} mm of its target?)")
    return res.pos_R


def draw(st: Setting, seed: int, run: int, active: tuple | None = None, swap: tuple | None = None):
    """Run ``run``'s draws: ``({(symbol, power): value}, noise generator, {thermal source: value})``.

    Every term draws from its own stream, so switching a source off (``active``)
    leaves the others' draws unchanged (the budget's runs share the full runs'
    draws); an inactive thermal source stays at its best estimate. ``swap``
    ``(run_b, sources)``: those sources draw as in run ``run_b`` (Sobol's
    pick-and-freeze, :func:`sobol_first_order`).
    """
    nd = len(st.task.declared)
    nt = nd + 1 + len(V.THERMAL_SOURCES)   # then: the state, the pre-travel, the lobing (a child keeps its index)
    nf = len(st.task.forms)   # the forms' then the drifts' streams come last: adding them leaves the others' draws
    ns = nt + 3 + nf + len(st.task.drift)
    ss = list(V.run_seeds(seed, run).spawn(ns))
    if swap is not None:
        ssb = V.run_seeds(seed, swap[0]).spawn(ns)
        names = ([t.source for t in st.task.declared] + [V.PROBE_SOURCE] + list(V.THERMAL_SOURCES)
                 + [STATE_SOURCE, V.PRETRAVEL_SOURCE, V.LOBING_SOURCE] + list(st.task.form_sources)
                 + list(st.task.drift_sources))
        ss = [b if n in swap[1] else a for a, b, n in zip(ss, ssb, names)]
    coeffs = {}
    for t, s in zip(st.task.declared, ss):
        if (active is None or t.source in active) and t.term == "periodic":
            a, phase = V.draw_periodic(t, np.random.default_rng(s))
            coeffs[(t.symbol, "periodic", len(coeffs))] = (a, t.period, phase)
        elif active is None or t.source in active:
            key = (t.symbol, t.power)
            coeffs[key] = coeffs.get(key, 0.0) + V.draw_term(t, np.random.default_rng(s))
    thermal = {}
    if st.task.temperature is not None:
        for name, s in zip(V.THERMAL_SOURCES, ss[nd + 1:]):
            if name in st.task.temperature.sources and (active is None or name in active):
                thermal[name] = st.task.temperature.draw(name, np.random.default_rng(s))
    if STATE_SOURCE in st.sources and (active is None or STATE_SOURCE in active):
        coeffs[STATE_KEY] = st.state.draw(np.random.default_rng(ss[nt]))
    task = st.task
    if task.pretravel is not None and (active is None or V.PRETRAVEL_SOURCE in active):
        coeffs[("probe", "pretravel")] = V.draw_term(task.pretravel, np.random.default_rng(ss[nt + 1]))
    if task.lobing is not None and (active is None or V.LOBING_SOURCE in active):
        a, psi = V.draw_periodic(task.lobing, np.random.default_rng(ss[nt + 2]))
        coeffs[("probe", "lobing")] = (int(task.lobing.period), a * math.cos(psi), a * math.sin(psi))
    for j, fm in enumerate(task.forms):
        if active is None or fm.source in active:
            coeffs[("form", fm.feature)] = V.draw_periodic(fm, np.random.default_rng(ss[nt + 3 + j]))
    for j, t in enumerate(task.drift):
        if active is None or t.source in active:
            coeffs[("drift", t.symbol)] = V.draw_term(t, np.random.default_rng(ss[nt + 3 + nf + j]))
    return coeffs, np.random.default_rng(ss[nd]), thermal


def _measure(st: Setting, coeffs: dict, rng, thermal: dict, *, noise: bool, machine=None) -> np.ndarray:
    """Reported tip centres of one run, corrected to 20 C when the task has a [temperature] table."""
    temp = st.task.temperature
    if temp is None:
        return simulate_run(st, coeffs, rng, noise=noise, machine=machine)
    e_p, e_s = temp.strains(thermal)
    if e_s != 0.0:
        machine = None
        coeffs = dict(coeffs)
        for sym in ("EXX", "EYY", "EZZ"):
            coeffs[(sym, 1)] = coeffs.get((sym, 1), 0.0) + e_s
    p = simulate_run(st, coeffs, rng, noise=noise, machine=machine, e_part=e_p)
    e_p0, e_s0 = temp.strains()
    return V.correct_to_20c(p, st.n_R, st.probe.stylus_r_m, e_p0, e_s0, st.centre_R, st.config.J_m)


def run_values(st: Setting, seed: int, runs, active: tuple | None = None, dq: list | None = None,
               swap: tuple | None = None) -> np.ndarray:
    """Measurand values (len(runs), m) SI of the given run indices (sources ``active``, None: all).

    ``dq``: a list to which each run's (k,) normal deviations of the touches,
    ``n . (reported - nominal)`` m, are appended (the report's worst touches).
    ``swap`` ``(offset, sources)``: run k draws those sources as run ``k + offset``.
    """
    noise = active is None or V.PROBE_SOURCE in active
    out = np.empty((len(runs), len(st.task.measurands)))
    r_st = st.probe.stylus_r_m
    fixed = None
    if (active is not None and not any(t.source in active for t in st.task.declared + st.task.drift)
            and STATE_SOURCE not in active):
        from sim.machine import Machine

        fixed = Machine(st.config)   # no declared term drawn: one machine for every run
    for i, k in enumerate(runs):
        coeffs, rng, thermal = draw(st, seed, int(k), active,
                                    None if swap is None else (int(k) + swap[0], swap[1]))
        p = _measure(st, coeffs, rng, thermal, noise=noise, machine=fixed)
        out[i] = V.evaluate(st.task, st.rows, p, st.n_R, r_st, st.Xn_R)
        if dq is not None:
            dq.append(np.einsum("ij,ij->i", p - st.Xn_R, st.n_R))
    return out


def true_values(st: Setting, seed: int, runs, y_nom: np.ndarray, perfect, *, progress=None, done_before: int = 0,
                dask: str | None = None) -> np.ndarray:
    """Each run's true measurand values (len(runs), m) SI: the part as that run drew it, measured at the
    plan's points by the perfect machine (``perfect``) without noise, drift or the probe's drawn terms,
    at 20 C, as ``y_nom`` is. Without a ``[form]`` the part is its nominal in every run: ``y_nom``
    repeated (no run simulated). The truth is taken at the plan's points (a form between them is
    not the measurand's).

    With a ``[form]`` each run is one simulation: they go to the Dask cluster ``dask`` in tasks of
    :data:`CHUNK_RUNS` as the measured runs do (each worker builds its own perfect machine), and
    ``progress(done_before + k, done_before + len(runs))`` counts them. The numbers are the same either way.
    """
    runs = [int(k) for k in runs]
    n = len(runs)
    if not st.task.forms:
        return np.broadcast_to(np.asarray(y_nom, float), (n, len(y_nom))).copy()
    chunks = [runs[i:i + CHUNK_RUNS] for i in range(0, n, CHUNK_RUNS)]
    if dask:
        from scenarios.parallel import pmap

        parts = pmap(_truth_chunk, [(st, seed, c) for c in chunks], dask=dask)
        if progress is not None:
            progress(done_before + n, done_before + n)
        return np.vstack(parts) if parts else np.empty((0, len(st.task.measurands)))
    out = np.empty((n, len(st.task.measurands)))
    k = 0
    for c in chunks:
        out[k:k + len(c)] = _truth_runs(st, seed, c, perfect)
        k += len(c)
        if progress is not None:
            progress(done_before + k, done_before + n)
    return out


def _truth_runs(st: Setting, seed: int, runs, perfect) -> np.ndarray:
    """The true values of ``runs`` (a ``[form]`` task): each run's drawn forms measured by ``perfect``."""
    out = np.empty((len(runs), len(st.task.measurands)))
    for i, k in enumerate(runs):
        coeffs = {key: v for key, v in draw(st, seed, int(k))[0].items() if key[0] == "form"}
        p = simulate_run(st, coeffs, None, noise=False, machine=perfect)
        out[i] = V.evaluate(st.task, st.rows, p, st.n_R, st.probe.stylus_r_m, st.Xn_R)
    return out


def _truth_chunk(task) -> np.ndarray:
    """A Dask task: the true values of a chunk of runs (module level: picklable; the worker builds the
    perfect machine, which does not travel)."""
    from sim.machine import Machine

    st, seed, runs = task
    return _truth_runs(st, seed, runs, Machine(dataclasses.replace(st.config, errors={})))


#: First run index of the Sobol matrices (apart from the adaptive runs, which count from 0).
SOBOL_FIRST_RUN = 10 ** 9


def sobol_samples(st: Setting, seed: int, n: int, progress=None, done_before: int = 0):
    """The pick-and-freeze samples: ``(f_A, f_B, {source: f_{A_B^i}})``, each (n, m) SI.

    ``A`` the runs ``N0 .. N0+n-1``, ``B`` the next ``n``, ``A_B^i`` the runs of ``A`` with
    source ``i`` drawn as in ``B`` (its own stream, :func:`draw`): ``n (k + 2)`` runs for ``k``
    sources.
    """
    N0 = SOBOL_FIRST_RUN
    fA = run_values(st, seed, range(N0, N0 + n))
    fB = run_values(st, seed, range(N0 + n, N0 + 2 * n))
    fAB = {}
    for i, src in enumerate(st.sources):
        if progress is not None:
            progress(done_before + (i + 2) * n, done_before + (len(st.sources) + 2) * n)
        fAB[src] = run_values(st, seed, range(N0, N0 + n), swap=(n, (src,)))
    return fA, fB, fAB


def sobol_first_order(st: Setting, seed: int, n: int, progress=None, done_before: int = 0) -> tuple[dict, dict]:
    """First-order Sobol indices of every source for every measurand and their standard errors,
    ``({source: (m,) float}, {source: (m,) float})``: :func:`core.vcmm.saltelli_first_order` of
    :func:`sobol_samples`. A measurand without variance gets NaN. The indices sum to 1 for an
    additive model; less means interactions.
    """
    return V.saltelli_first_order(*sobol_samples(st, seed, n, progress, done_before))


#: Runs per task shipped to a Dask worker (a batch of M runs is M / CHUNK_RUNS tasks).
CHUNK_RUNS = 10


def _chunk(task):
    """A Dask task: (values (n, m), dq (n, k)) of the runs ``runs`` (module level: picklable)."""
    st, seed, runs, active = task
    dq: list = []
    v = run_values(st, seed, runs, active, dq)
    return v, np.asarray(dq)


def _batch(st: Setting, seed: int, runs: np.ndarray, active, dq: list | None, dask: str | None) -> np.ndarray:
    """Values of one batch, serially or on a Dask cluster (the same numbers: run k draws from (seed, k) alone)."""
    if not dask:
        return run_values(st, seed, runs, active, dq)
    from scenarios.parallel import pmap

    parts = pmap(_chunk, [(st, seed, runs[i:i + CHUNK_RUNS], active) for i in range(0, len(runs), CHUNK_RUNS)],
                 dask=dask)
    if dq is not None:
        for _, d in parts:
            dq.extend(d)
    return np.vstack([v for v, _ in parts])


def adaptive(st: Setting, seed: int, active: tuple | None, which: str, first_run: int = 0, progress=None,
             done_before: int = 0, total_hint: int = 0, tolerance: np.ndarray | None = None,
             dq: list | None = None, dask: str | None = None):
    """JCGM 101 7.9.4: batches of M runs until every measurand is stable (or ``max_runs``).

    ``tolerance`` (m,) SI: a numerical tolerance per measurand (the budget's
    runs take the full result's, so a small contribution is not chased to
    digits the full u does not have); default the task's rule.
    Returns (values (N, m) SI, converged (m,) bool).
    """
    mc = st.task.mc
    M = mc.batch_runs
    vals = np.empty((0, len(st.task.measurands)))
    batches = []
    est_total = 2 * M
    while True:
        h = len(batches)
        runs = np.arange(first_run + h * M, first_run + (h + 1) * M)
        b = _batch(st, seed, runs, active, dq, dask)
        vals = np.vstack([vals, b])
        batches.append([[s.mean, s.u, s.low, s.high] for s in (V.mc_stats(b[:, j], mc.coverage)
                                                             for j in range(b.shape[1]))])
        arr = np.asarray(batches)  # (h, m, 4)
        checks = [V.adaptive_check(arr[:, j], float(vals[:, j].std(ddof=1)), mc.significant_digits,
                                   mc.tolerance if tolerance is None else float(tolerance[j]), which)
                  for j in range(arr.shape[1])]
        ok = np.array([c.stable for c in checks])
        n = len(vals)
        if len(batches) >= 2:
            # s shrinks like 1/sqrt(h): the batches still needed for 2 s <= delta
            need = max((c.h * (2 * (c.s if which == "all" else c.s[1:2]).max() / c.delta) ** 2
                        if c.delta > 0 else c.h) for c in checks)
            est_total = min(mc.max_runs, max(n + M, int(math.ceil(need)) * M))
        if progress is not None:
            progress(done_before + n, done_before + max(est_total, n) + total_hint)
        if ok.all() or n + M > mc.max_runs:
            return vals, ok


def _of_measurand(d: dict, j: int) -> dict | None:
    """``{source: (m,) float}`` -> ``{source: float or None (NaN)}`` of measurand ``j``; None when empty."""
    return {k: (None if not np.isfinite(v[j]) else float(v[j])) for k, v in d.items()} if d else None


def study(st: Setting, seed: int = 0, *, progress=None, budget: bool = True, dask: str | None = None,
          sobol_runs: int = 0) -> dict:
    """The full study: nominal values, the adaptive MC, the one-at-a-time budget.

    ``dask``: a scheduler address (``tcp://HOST:PORT``); each batch's runs go
    to its workers in tasks of :data:`CHUNK_RUNS`. The result is the same.

    Returns a dict ready for JSON (values in the measurands' report units),
    with the per-run values of the full MC under ``"runs"`` (SI) for tests.
    """
    from sim.machine import Machine

    t0 = time.perf_counter()
    task = st.task
    r_st = st.probe.stylus_r_m
    perfect = Machine(dataclasses.replace(st.config, errors={}))
    y_nom = V.evaluate(task, st.rows, simulate_run(st, {}, None, noise=False, machine=perfect), st.n_R, r_st,
                       st.Xn_R)
    y_best = V.evaluate(task, st.rows, _measure(st, {}, None, {}, noise=False, machine=Machine(st.config)),
                        st.n_R, r_st, st.Xn_R)
    guess = task.mc.batch_runs * 2 * (1 + (len(st.sources) if budget else 0))
    dq: list = []
    vals, ok = adaptive(st, seed, None, "all", progress=progress, total_hint=guess - 2 * task.mc.batch_runs,
                        dq=dq, dask=dask)
    dq_a = np.asarray(dq)
    done = len(vals)
    delta = np.array([task.mc.tolerance if task.mc.tolerance is not None else
                      V.numerical_tolerance(float(vals[:, j].std(ddof=1)), task.mc.significant_digits)
                      for j in range(vals.shape[1])])
    bud, bud_runs = {}, {}
    if budget:
        for i, src in enumerate(st.sources):
            left = (len(st.sources) - i - 1) * 2 * task.mc.batch_runs
            v, _ = adaptive(st, seed, (src,), "u", progress=progress, done_before=done, total_hint=left,
                            tolerance=delta, dask=dask)
            done += len(v)
            bud[src] = v.std(axis=0, ddof=1)
            bud_runs[src] = len(v)
    sob, sob_se = {}, {}
    if sobol_runs:
        sob, sob_se = sobol_first_order(st, seed, sobol_runs, progress=progress, done_before=done)
        done += sobol_runs * (len(st.sources) + 2)
    # the error about the true value, run by run (review33a F6: a form's noise bias left measured +- U95
    # covering the true flatness in 15 % of runs): the runs' own parts, so a drawn form is in the truth
    err = vals - true_values(st, seed, range(len(vals)), y_nom, perfect, progress=progress, done_before=done,
                             dask=dask)
    elapsed = time.perf_counter() - t0
    out = []
    for j, m in enumerate(task.measurands):
        s = V.mc_stats(vals[:, j], task.mc.coverage)
        es = V.error_stats(err[:, j], 0.5 * (s.high - s.low), task.mc.coverage)
        u_src = {k: float(v[j]) for k, v in bud.items()}
        ss = sum(x * x for x in u_src.values())
        out.append({
            "name": m.name, "quantity": m.quantity, "of": list(m.of), "axis": m.axis,
            "unit": m.unit, "u_unit": m.u_unit,
            "nominal": y_nom[j] * m.scale,
            "machine_best_estimate": y_best[j] * m.scale,
            "mean": s.mean * m.scale,
            "bias": (s.mean - y_nom[j]) * m.u_scale,
            "u": s.u * m.u_scale,
            "U": 0.5 * (s.high - s.low) * m.u_scale,
            "U95": 0.5 * (s.high - s.low) * m.u_scale if task.mc.coverage == 0.95 else None,
            "coverage": task.mc.coverage,
            "interval": [s.low * m.scale, s.high * m.scale],
            "error_mean": es.mean * m.u_scale,
            "error_interval": [es.low * m.u_scale, es.high * m.u_scale],
            "U_about_true": es.U_about_true * m.u_scale,
            "U95_about_true": es.U_about_true * m.u_scale if task.mc.coverage == 0.95 else None,
            "U_covers_true": es.covers,
            "biased": es.biased,
            "converged": bool(ok[j]),
            "tolerance": float(delta[j] * m.u_scale),
            "budget": [{"source": k, "u": u * m.u_scale, "share": (u * u / ss) if ss > 0 else 0.0,
                        "runs": bud_runs[k]} for k, u in u_src.items()],
            "budget_rss_over_u": (math.sqrt(ss) / s.u) if (budget and s.u > 0) else None,
            "sobol_first_order": _of_measurand(sob, j),
            "sobol_first_order_se": _of_measurand(sob_se, j),
        })
    return {"format": "vmt-vcmm/1", "machine": st.config.name, "task": task.source,
            "touches": int(len(st.Xn_R)), "runs": int(len(vals)), "batch_runs": task.mc.batch_runs,
            "seed": int(seed), "sources": list(st.sources),
            "machine_state": None if st.state is None else {
                "file": st.state.source, "symbols": list(st.state.symbols), "conventions": list(st.state.conventions),
                "interpolation": st.state.interpolation,
                "positions": POSITIONS_READINGS if st.state.at_readings else POSITIONS,
                # what the state cannot carry (sessions 37, 38): its scale when unknown, its gauge, the
                # measurands they move
                "cannot_carry": cannot_carry(st)},
            "declared": [{"source": t.source, "bound": t.bound * 1e6, "distribution": t.distribution,
                          "u": t.u * 1e6, "unit": ("urad" if V.iso.symbol(t.symbol).angular else "um")
                          + {0: "", 1: "/m", 2: "/m2"}[t.power],
                          **({"period_mm": t.period * 1e3} if t.period else {})} for t in task.declared],
            "probe_noise_um": st.probe.sigma_m * 1e6,
            "part_form": [{"source": f.source, "amplitude_um": f.bound * 1e6, "distribution": f.distribution,
                           **({"lobes": f.lobes} if f.lobes else {"wavelength_mm": f.wavelength * 1e3})}
                          for f in task.forms],
            "drift": [{"source": t.source, "bound_um_per_h": t.bound * 1e6 * 3600.0, "distribution": t.distribution}
                      for t in task.drift],
            "probe_declared": [{"source": src, "bound_um": t.bound * 1e6, "distribution": t.distribution,
                                **({"lobes": int(t.period)} if t.term == "lobing" else {})}
                               for src, t in ((V.PRETRAVEL_SOURCE, task.pretravel), (V.LOBING_SOURCE, task.lobing))
                               if t is not None],
            "runs_total": int(done), "elapsed_s": elapsed, "runs_per_s": done / elapsed if elapsed > 0 else None,
            "measurands": out,
            "touches_u": [{"target": st.targets[i], "feature": task.features[st.group[i]].name,
                           "u_dq_um": float(dq_a[:, i].std(ddof=1) * 1e6),
                           "mean_dq_um": float(dq_a[:, i].mean() * 1e6)} for i in range(dq_a.shape[1])],
            "values_si": vals}


# --------------------------------------------------------------------------- the README's example part


def block_plan():
    """The README's example plan (probe-log/1, measured columns empty): a block on the table.

    Block x -40..40, y -30..30, z -30..0 mm (machine frame R at rotary zero),
    a through bore of 20 mm diameter centred at (10, 0): 8 touches at
    z = -10; faces x = -40 and x = +40, 4 touches each; the top face z = 0,
    8 touches clear of the bore. Stylus radius 3 mm.
    """
    r = 3.0
    rows = []   # (feature, target, surface point mm, outward normal)
    for k in range(8):
        a = np.deg2rad(22.5 + 45.0 * k)
        rows.append(("bore", f"B{k + 1:02d}", (10 + 10 * np.cos(a), 10 * np.sin(a), -10.0),
                     (-np.cos(a), -np.sin(a), 0.0)))
    for side, x, nx in (("left", -40.0, -1.0), ("right", 40.0, 1.0)):
        for k, (y, z) in enumerate(((-20, -10), (20, -10), (0, -20), (0, -5))):
            rows.append((side, f"{side[0].upper()}{k + 1:02d}", (x, y, z), (nx, 0.0, 0.0)))
    for k, (x, y) in enumerate(((-30, -20), (-30, 0), (-30, 20), (-15, -20), (-15, 20), (30, -20), (30, 20),
                                (10, -22))):
        rows.append(("top", f"T{k + 1:02d}", (x, y, 0.0), (0.0, 0.0, 1.0)))
    return plan_from_rows(rows, r, "vmt README example: block with a bore")


def plan_from_rows(rows, stylus_r_mm: float, title: str):
    """A probe-log/1 plan (measured columns empty, one set-up ``S1``) from ``(feature, target,
    surface point mm, outward normal)`` rows: the nominal tip centre is the point plus the radius
    along the normal."""
    from core.probelog import make_log

    n = len(rows)
    s = np.array([p for _, _, p, _ in rows], float)
    nn = np.array([v for _, _, _, v in rows], float)
    Xn = s + stylus_r_mm * nn
    nan = np.full(n, np.nan)
    cols = {"setup": ["S1"] * n, "target": [t for _, t, _, _ in rows], "t_s": nan, "X_mm": nan, "Y_mm": nan,
            "Z_mm": nan, "Xn_mm": Xn[:, 0], "Yn_mm": Xn[:, 1], "Zn_mm": Xn[:, 2], "nx": nn[:, 0], "ny": nn[:, 1],
            "nz": nn[:, 2], "feature": [f for f, _, _, _ in rows], "stylus_r_mm": np.full(n, stylus_r_mm)}
    return make_log(cols, {"plan": title, "stylus_r_mm": f"{stylus_r_mm:g}"})


def _true_in(m: dict) -> str:
    """``[measured - a, measured - b] unit`` of a measurand's error interval (a report JSON before the key: -)."""
    if "error_interval" not in m:
        return "-"
    lo, hi = m["error_interval"]
    tail = f" BIASED ({100 * m['U_covers_true']:.0f} %)" if m.get("biased") else ""
    return f"[measured {-hi:+.4f}, measured {-lo:+.4f}] {m['u_unit']}{tail}"


def write_report(folder, rep: dict, *, worst: int = 10):
    """A report folder (index.html): the measurands with U95 and interval, the budget chart, the worst touches.

    The worst touches are those whose normal deviation ``dq`` (reported minus
    nominal along the normal) scatters most over the Monte Carlo runs: where
    the machine's declared errors and the probe move the touches most.
    """
    from viz.figures import budget_figure
    from viz.report import Section, Table, write_report as write

    ms = rep["measurands"]
    rows = [(m["name"], m["quantity"], f"{m['nominal']:.6g} {m['unit']}", f"{m['bias']:+.4f}", f"{m['u']:.4f}",
             f"{m['U']:.4f}",
             f"[{m['interval'][0]:.6f}, {m['interval'][1]:.6f}] {m['unit']}", m["u_unit"],
             _true_in(m), f"{m['U_about_true']:.4f}" if "U_about_true" in m else "-",
             "yes" if m["converged"] else "NO (max_runs)") for m in ms]
    p = f"{100 * rep['measurands'][0]['coverage']:g} %"
    summary = Table(("measurand", "quantity", "nominal", "bias", "u", f"U ({p})", "coverage interval",
                     "unit of bias/u/U", f"true value in ({p})", "U about the true value", "converged"), rows,
                    caption=f"bias: Monte Carlo mean minus the value on a perfect machine; U: half the "
                            f"probabilistically symmetric {p} interval (JCGM 101 7.7) of the measured value; "
                            f"the true value: measured minus the {p} interval of the error (measured - true), "
                            f"or measured +- the U about it (BIASED: measured +- U covers the true value in "
                            f"fewer runs than {p}, said in %)")
    tw = sorted(rep["touches_u"], key=lambda t: -t["u_dq_um"])[:worst]
    touches = Table(("target", "feature", "u(dq) / µm", "mean dq / µm"),
                    [(t["target"], t["feature"], f"{t['u_dq_um']:.4f}", f"{t['mean_dq_um']:+.4f}") for t in tw])
    src = ", ".join(f"{d['source']} +-{d['bound']:g} {d['unit']} ({d['distribution']})" for d in rep["declared"])
    text = (f"Machine {rep['machine']}, task {rep['task']}, plan {rep.get('plan', '?')}: {rep['touches']} touches, "
            f"{rep['runs']} Monte Carlo runs (JCGM 101 adaptive, batches of {rep['batch_runs']}), "
            f"{rep['runs_total']} with the budget, seed {rep['seed']}. Declared: {src or 'none'}; probing "
            f"repeatability {rep['probe_noise_um']:g} um (k = 1).")
    secs = [Section("Measurands", text, tables=[summary]),
            Section("Budget", "u of each source alone (the others at their best estimate), beside the full u.",
                    figures={"budget": budget_figure(ms)}),
            Section("Worst touches", "The touches whose normal deviation scatters most over the runs.",
                    tables=[touches])]
    return write(folder, "Virtual CMM: task uncertainty", secs)
