"""Blind campaign generator B: a blade plate on a table-type machine.

Written apart from ``sim/``, from the discovery engine and from generator A,
so that discovery tests cannot be tuned to any of them (issue 13, item 7).
Everything here (part, machine, timing, effects, the eq. 15 projection) is
this module's own.

The campaign
------------
*Part* (artefact frame W, mm; z = 0 on the plate top): a plate carrying

- ``blade``: a cambered blade boss (a closed periodic cubic spline through
  22 points of a 112 mm chord, 14 % thick, 5 % camber profile, staggered
  24 deg), 30 targets on its outer wall at z = +9 mm, irregularly spaced,
  the trailing edge avoided;
- ``pin1`` .. ``pin5``: five 10 mm pins on a partial circle of radius 92 mm
  (not centred on the blade), 4 touches each at z = +7 mm;
- ``slot``: a 16 mm wide slot at 28 deg, 5 touches on each inner wall at
  z = -5 mm (normals point into the slot, out of the material).

60 targets; every touch is on a vertical wall (normal in the XY plane).
Stylus ball radius 2.0 mm.

*Machine* (``V[w-C-X-Y-b-Z-(C)-t]``): the part sits on the C table, C on
the X table, X on the Y saddle, Y on the bed; the spindle head carries only
Z. X and Y therefore move the workpiece, not the tool. The C-axis centre
sits anywhere in machine coordinates (|X|, |Y| up to several hundred mm),
the part is clamped off-centre at a random angle.

*Schedules* (C angles, degrees, run in a shuffled order): see
:data:`SCHEDULES`. ``quarters`` (0/90/180/270) and ``thirds`` (0/120/240)
leave the workpiece NOT identifiable: smooth machine error fields that are
covariant under those rotations (``(f(x), f(y))`` with f odd for 90 deg,
the field ``(x^2 - y^2, -2xy)`` for 120 deg) fit the rigid-body model and
mimic a workpiece form. :class:`Truth` flags them.

*Timing*: a touch every 2-5 s (positioning at rapid, 2.5 mm approach at
240 mm/min, controller overhead), clearance moves between features, C
indexing with clamping, operator pauses between and inside set-ups, a
drift-check re-touch of the first targets at the end of each set-up.

*Temperatures*: every campaign logs ``temp_air_C`` (thermostat cycling of a
few minutes' period, an occasional door opening) and ``temp_spindle_C``
(spindle cooling after a warm-up). Only ``temperature_expansion`` ties an
error to one of them.

Sign conventions
----------------
Every machine error value here is the displacement of the TOOL relative to
the WORKPIECE (ISO 230-1 values read that way, whichever side of the bed
the axis is on). A table axis whose table really sits 1 um further in -X
than commanded has ``EXX = +1 um``. The log's ``X_mm`` is the stylus-tip
centre as the machine believes it, ``Xn_mm`` the nominal. With ``e`` the
tool-minus-workpiece error at the touch, ``G`` the part's deviation along
the outward normal ``n`` (positive: material farther out) and ``p`` the
pre-travel along the normal,

    dq = n . (X - Xn) = G - n . e - p          (paper eqs 3, 7, 12, 13)

so a tool that sits 1 um farther along +n than commanded must be driven
1 um deeper before it touches: dq = -1 um. The reading moves along the
commanded approach line ``d``: ``X = Xn + d * dq / (n . d)``.

The model is first order in the error motions, like the paper's eqs 12-13:
the displacement of the nominal contact is projected on the nominal normal.
The neglected second order (tangential error squared over twice the radius
of the ball-centre path) peaks on the pins (7 mm): 0.042 um in the worst of
30 campaigns, a tenth of the smallest noise.

Visible part
------------
:func:`visible_part` is this module's own implementation of the paper's
eq. 15 (with eqs 8-13): workpiece ``G`` per target, X/Y error motions on a
9 x 9 grid with linear interpolation (``EXX``, ``EYX``, ``EXY``, ``EYY``,
``ECY`` and the squareness ``EC0Y``), C-axis ``EXC``, ``EYC``, ``ECC`` per
set-up; the least-squares fit of eq. 18 is a projection, and what it leaves
of an effect's ``dq`` is what the baseline cannot absorb. The gauge (eqs
16-17) does not change that residual.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Callable, Mapping

import numpy as np
from scipy.interpolate import CubicSpline

from core.exceptions import ConfigError
from core.memo import Memo
from core.probelog import ProbeLog, make_log
from core.units import DEG, MM, UM, URAD

#: Millimetres per micrometre (this module computes in mm and reports in um).
UM_MM = UM / MM
#: The machine's kinematic chain (parsed by :func:`core.chain.parse_chain`).
CHAIN = "V[w-C-X-Y-b-Z-(C)-t]"
#: Stylus-ball radius, mm.
STYLUS_R_MM = 2.0
#: Approach length before the nominal contact, mm; approach feed, mm/s.
APPROACH_MM = 2.5
APPROACH_MM_S = 4.0
#: Rapid feed (mm/s), clearance lift between features (mm).
RAPID_MM_S = 130.0
CLEARANCE_MM = 30.0
#: Grid nodes per axis of the eq. 15 projection.
GRID_NODES = 9
#: Legendre degree of each axis function in the smooth identifiability model.
POLY_DEGREE = 6

#: C schedules (deg), name -> angles. Run order is shuffled per campaign.
SCHEDULES: Mapping[str, tuple[float, ...]] = MappingProxyType({
    "irregular3": (0.0, 97.0, 221.0),
    "thirds": (0.0, 120.0, 240.0),
    "quarters": (0.0, 90.0, 180.0, 270.0),
    "irregular4": (0.0, 62.0, 149.0, 253.0),
    "irregular5": (0.0, 71.0, 138.0, 215.0, 289.0),
    "offset6": (15.0, 58.0, 122.0, 187.0, 236.0, 318.0),
    "irregular7": (0.0, 44.0, 97.0, 160.0, 205.0, 262.0, 311.0),
    "irregular8": (0.0, 33.0, 81.0, 142.0, 188.0, 236.0, 275.0, 331.0),
})
#: Schedules whose workpiece the rigid-body model cannot identify (checked
#: numerically by :func:`workpiece_identifiability` in the tests).
NOT_IDENTIFIABLE = ("thirds", "quarters")


# ---------------------------------------------------------------------------
# effects


@dataclass(frozen=True)
class Effect:
    """One effect this generator can inject.

    Attributes
    ----------
    name : str
    kind : str
        ``"catalogue"``, ``"new_named"`` or ``"out_of_catalogue"``.
    acceptable : tuple of str
        Cause names a correct engine may answer.
    covariates : tuple of str
        Where the structure lives (axis-specific effects replace ``"axis"``
        by ``"x"`` or ``"y"`` per campaign).
    where : str
        The physics, in words.
    """

    name: str
    kind: str
    acceptable: tuple[str, ...]
    covariates: tuple[str, ...]
    where: str


def _fx(name, kind, covariates, where, acceptable=None):
    acc = acceptable if acceptable is not None else (
        ("unexplained",) if kind == "out_of_catalogue" else (name,))
    return Effect(name, kind, acc, covariates, where)


_EFFECTS = (
    _fx("none", "catalogue", (), "rigid-body machine errors, probing noise and a constant "
        "pre-travel residual only"),
    _fx("outlier", "catalogue", (), "2-5 touches hit a chip (dq up to +40 um) or skid on a "
        "burr (negative)"),
    _fx("thermal_drift", "catalogue", ("time", "time_in_setup", "x"),
        "an unmeasured heat source warms with axis activity (first-order lag, cools in "
        "pauses): head translation in X and Y and the X scale growing about its fixing point"),
    _fx("periodic_axis_error", "catalogue", ("axis",),
        "screw-pitch cyclic error of X or Y (pitch 8-20 mm, first and second harmonic)"),
    _fx("probe_lobing", "catalogue", ("approach_azimuth",),
        "three-lobe pre-travel of a kinematic probe held at one spindle orientation, "
        "with a small six-lobe part"),
    _fx("reversal", "catalogue", ("approach_azimuth",),
        "lost motion of X and Y: the error depends on the last direction each axis moved "
        "(approach, or the positioning move when the approach does not move that axis)"),
    _fx("nonrigid", "catalogue", ("x", "y"),
        "the saddle deforms with the table overhang: the X straightness grows with the "
        "Y position and the X position error depends on Y (products of quadratic shapes, "
        "outside any rigid-body stacking)"),
    _fx("c_drift", "new_named", ("time_in_setup",),
        "the C clamp creeps after each indexing: ECC rises like 1 - exp(-t/tau) within "
        "every set-up"),
    _fx("temperature_expansion", "new_named", ("temp_air", "x", "y"),
        "exposed X and Y scales follow temp_air_C (thermostat cycling, door opening) with "
        "different coefficients about their fixing points; reference 20 C"),
    _fx("stylus_bending", "new_named", ("approach_elevation",),
        "a long stylus bends less at trigger when the approach is inclined (friction on the "
        "wall unloads the seat): pre-travel p_h / (1 + k sin(elevation))"),
    _fx("lobing_per_setup", "new_named", ("approach_azimuth", "setup"),
        "three-lobe pre-travel whose orientation is random per set-up (probe loaded into an "
        "unoriented spindle before each set-up)"),
    _fx("local_scale_defect", "new_named", ("axis",),
        "a damaged spot on the X or Y scale, 1.5-3.5 mm wide, asymmetric bump"),
    _fx("part_change", "new_named", ("time", "feature"),
        "the slot closes as machining stresses relax: both walls move into the slot, more at "
        "its open end, like 1 - exp(-t/tau); a workpiece effect"),
    _fx("fixture_slip", "out_of_catalogue", ("time_in_setup", "setup"),
        "a clamp relaxes during one set-up: the part steps by a few um and turns about the "
        "clamp at one instant, then stays"),
    _fx("signal_latency", "out_of_catalogue", ("x", "y"),
        "the optical probe's trigger reaches the receiver later the farther the probe is "
        "from it: an isotropic pre-travel that grows with the squared distance to a receiver "
        "outside the working area"),
    _fx("reseat_settling", "out_of_catalogue", ("order",),
        "the probe's kinematic seat re-seats with a time constant of a few seconds: a touch "
        "made soon after the previous one starts with the stylus still displaced along the "
        "previous contact normal (depends on the time since and the normal of the previous "
        "touch)"),
    _fx("head_tram", "out_of_catalogue", ("z", "feature", "C"),
        "the spindle head is out of tram (Z tilted in XZ and YZ after a crash): features "
        "probed at different heights are shifted differently in the machine frame"),
    _fx("stylus_pickup", "out_of_catalogue", ("order", "time_in_setup"),
        "swarf and oil mist build up on the stylus ball with each touch (effective radius "
        "grows, saturating); the operator wipes the ball before some set-ups"),
)
EFFECTS: Mapping[str, Effect] = MappingProxyType({e.name: e for e in _EFFECTS})


def effects() -> dict[str, str]:
    """Every effect this generator injects, name -> kind.

    Returns
    -------
    dict[str, str]
        Kind is ``"catalogue"``, ``"new_named"`` or ``"out_of_catalogue"``.
    """
    return {e.name: e.kind for e in _EFFECTS}


# ---------------------------------------------------------------------------
# truth


@dataclass(frozen=True, eq=False)
class Truth:
    """What is really in a generated campaign.

    Per-row arrays follow the log's rows; per-target arrays follow
    ``targets``. Arrays are read-only.

    Attributes
    ----------
    effect, kind : str
    acceptable_causes : tuple of str
    covariates : tuple of str
        Where the effect's structure lives (time, time_in_setup, setup, C,
        x, y, z, approach_azimuth, approach_elevation, feature,
        temp_<name>, order).
    magnitude_um : float
        RMS over the rows of the effect's dq.
    visible_um : float
        RMS per row of what the paper's baseline (eq. 15, this module's
        projection) cannot absorb of the effect's dq.
    visible_sigmas : float
        ``visible_um / noise_um``.
    detectable : bool
        ``visible_sigmas >= 1``.
    noise_um : float
        Probing noise, 1 sigma (also when ``noisy=False``: then the nominal).
    effect_dq_um : (n,) float
        The effect's contribution to each row's dq (zero when effect_on is
        False).
    outlier_rows : tuple of int
        0-based rows hit by an outlier.
    targets : tuple of str
    workpiece_um : (n_targets,) float
        True normal deviation of the part at each target at the campaign
        start (positive: material farther out along the normal).
    workpiece_identifiable : bool
        The rigid-body model separates the part from the machine up to
        translation, rotation, scale and size (both the 9 x 9 grid model and
        a smooth degree-6 model, see :func:`workpiece_identifiability`).
    schedule_deg : tuple of float
        C angles in the order the set-ups were run.
    seed : int
    schedule : str
        Name in :data:`SCHEDULES` (``"custom"`` when given as angles).
    where : str
        The effect's physics in words.
    params : dict[str, float]
        The effect's drawn parameters (units in the keys); a plain dict so
        that a Truth pickles (for runs across processes).
    base_visible_um : float
        What the baseline cannot absorb of the base machine errors (should
        be far below the noise: the base machine is inside the model).
    centre_mm : tuple of float
        C-axis centre in machine coordinates (X, Y), mm.
    grid_x_mm, grid_y_mm : (9,) float
        Grid nodes of the eq. 15 projection.
    """

    effect: str
    kind: str
    acceptable_causes: tuple[str, ...]
    covariates: tuple[str, ...]
    magnitude_um: float
    visible_um: float
    visible_sigmas: float
    detectable: bool
    noise_um: float
    effect_dq_um: np.ndarray = field(repr=False)
    outlier_rows: tuple[int, ...]
    targets: tuple[str, ...]
    workpiece_um: np.ndarray = field(repr=False)
    workpiece_identifiable: bool
    schedule_deg: tuple[float, ...]
    seed: int
    schedule: str = ""
    where: str = ""
    params: Mapping[str, float] = field(default_factory=dict)
    base_visible_um: float = 0.0
    centre_mm: tuple[float, float] = (0.0, 0.0)
    grid_x_mm: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    grid_y_mm: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)


# ---------------------------------------------------------------------------
# the part


def _rot(a: float | np.ndarray) -> np.ndarray:
    """2-D rotation matrix (or a stack of them) by ``a`` rad, right-handed about +Z."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]]) if np.ndim(a) == 0 else np.stack(
        [np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def _perp(v: np.ndarray) -> np.ndarray:
    """(..., 2) rotated +90 deg about Z (the paper's R(90 deg))."""
    return np.stack([-v[..., 1], v[..., 0]], -1)


def _blade_points(chord_mm=112.0, camber=0.05, camber_at=0.4, thick=0.14, n=12):
    """Closed loop of control points of the blade section, unit chord then scaled.

    Own evaluation of a 4-digit-style section (closed trailing edge):
    half thickness ``5 t (0.2969 sqrt(x) - 0.126 x - 0.3516 x^2 + 0.2843 x^3
    - 0.1036 x^4)`` on a parabolic camber line. Counter-clockwise, starting
    at the trailing edge.
    """
    beta = np.linspace(0.0, math.pi, n)
    x = 0.5 * (1.0 - np.cos(beta))
    yt = 5 * thick * (0.2969 * np.sqrt(x) - 0.126 * x - 0.3516 * x**2 + 0.2843 * x**3 - 0.1036 * x**4)
    m, p = camber, camber_at
    yc = np.where(x < p, m / p**2 * (2 * p * x - x**2),
                  m / (1 - p)**2 * ((1 - 2 * p) + 2 * p * x - x**2))
    dyc = np.where(x < p, 2 * m / p**2 * (p - x), 2 * m / (1 - p)**2 * (p - x))
    th = np.arctan(dyc)
    upper = np.column_stack([x - yt * np.sin(th), yc + yt * np.cos(th)])
    lower = np.column_stack([x + yt * np.sin(th), yc - yt * np.cos(th)])
    loop = np.vstack([upper[::-1], lower[1:-1]])  # TE -> upper -> LE -> lower
    return (loop - [0.5, 0.0]) * chord_mm


@dataclass(frozen=True, eq=False)
class Part:
    """Nominal geometry of the blade plate, artefact frame W (mm).

    Attributes
    ----------
    target, feature : tuple of str
        Per target.
    p_W : (60, 3) float
        Nominal contact point, mm.
    n_W : (60, 2) float
        Outward unit normal (the z component is 0).
    s_blade : (30,) float
        Spline parameter (arc length of the control polygon, mm) of each
        blade target.
    blade : CubicSpline
        The blade contour, periodic, parameter in mm, value (x, y) in W.
    pins_mm : (5, 2) float
        Pin centres; ``pin_r_mm`` their radius.
    slot_centre_mm, slot_dir : (2,) float
        Slot centre and unit direction; ``slot_half_width_mm``.
    """

    target: tuple[str, ...]
    feature: tuple[str, ...]
    p_W: np.ndarray
    n_W: np.ndarray
    s_blade: np.ndarray
    blade: CubicSpline
    pins_mm: np.ndarray
    pin_r_mm: float
    slot_centre_mm: np.ndarray
    slot_dir: np.ndarray
    slot_half_width_mm: float

    @property
    def n(self) -> int:
        return len(self.target)


BLADE_STAGGER_DEG = 24.0
BLADE_OFFSET_MM = (-6.0, 4.0)
Z_BLADE_MM, Z_PIN_MM, Z_SLOT_MM = 9.0, 7.0, -5.0


@functools.lru_cache(maxsize=1)
def part() -> Part:
    """The blade plate (fixed nominal geometry, built once)."""
    loop = _blade_points() @ _rot(BLADE_STAGGER_DEG * DEG).T + BLADE_OFFSET_MM
    closed = np.vstack([loop, loop[:1]])
    s_knots = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    blade = CubicSpline(s_knots, closed, bc_type="periodic")
    perim = s_knots[-1]
    # 30 stations, quasi-uniform (golden ratio) away from the trailing edge (s = 0)
    frac = np.sort((np.arange(1, 31) * 0.6180339887498949) % 1.0)
    s_b = perim * (0.07 + 0.86 * frac)
    xy = blade(s_b)
    t = blade(s_b, 1)
    n_b = np.column_stack([t[:, 1], -t[:, 0]]) / np.linalg.norm(t, axis=1)[:, None]
    # pins on a partial circle around (8, -6)
    pin_ang = np.array([-160.0, -118.0, -71.0, -24.0, 21.0]) * DEG
    pins = np.array([8.0, -6.0]) + 92.0 * np.column_stack([np.cos(pin_ang), np.sin(pin_ang)])
    pin_r = 5.0
    local = np.array([0.0, 95.0, 185.0, 265.0]) * DEG
    p_pin, n_pin, ids_pin, f_pin = [], [], [], []
    for k, c in enumerate(pins):
        a = local + (17.0 + 29.0 * k) * DEG
        nn = np.column_stack([np.cos(a), np.sin(a)])
        p_pin.append(c + pin_r * nn)
        n_pin.append(nn)
        ids_pin += [f"P{k + 1}{'abcd'[i]}" for i in range(4)]
        f_pin += [f"pin{k + 1}"] * 4
    # slot: walls at +-8 mm from the centre line; normals point into the slot
    sc = np.array([-20.0, 70.0])
    sd = np.array([math.cos(28 * DEG), math.sin(28 * DEG)])
    sv = _perp(sd)
    hw = 8.0
    along = np.array([-18.0, -9.0, 0.0, 9.0, 18.0])
    p_sl = np.vstack([sc + hw * sv + along[:, None] * sd, sc - hw * sv + along[:, None] * sd])
    n_sl = np.vstack([np.tile(-sv, (5, 1)), np.tile(sv, (5, 1))])
    ids_sl = [f"SL{i + 1}" for i in range(5)] + [f"SR{i + 1}" for i in range(5)]
    p_xy = np.vstack([xy, *p_pin, p_sl])
    n_xy = np.vstack([n_b, *n_pin, n_sl])
    z = np.concatenate([np.full(30, Z_BLADE_MM), np.full(20, Z_PIN_MM), np.full(10, Z_SLOT_MM)])
    target = tuple([f"B{i + 1:02d}" for i in range(30)] + ids_pin + ids_sl)
    feature = tuple(["blade"] * 30 + f_pin + ["slot"] * 10)
    p_W = np.column_stack([p_xy, z])
    for a in (p_W, n_xy, s_b, pins, sc, sd):
        a.setflags(write=False)
    return Part(target, feature, p_W, n_xy, s_b, blade, pins, pin_r, sc, sd, hw)


def blade_curvature_per_mm(s: np.ndarray) -> np.ndarray:
    """Signed curvature of the blade contour at spline parameter ``s`` (1/mm;
    positive convex, the contour runs counter-clockwise)."""
    b = part().blade
    d1, d2 = b(s, 1), b(s, 2)
    return (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.linalg.norm(d1, axis=1) ** 3


# ---------------------------------------------------------------------------
# the campaign layout (nominal geometry, path, timing, temperatures)


@dataclass(frozen=True, eq=False)
class Layout:
    """One campaign's touches, nominal and path data (rows in touch order).

    All positions in the machine frame R (mm) unless named ``_T`` (table
    frame: the C table at C = 0, origin on the C axis). ``setup`` indexes
    ``angles_deg`` (the run order).
    """

    angles_deg: tuple[float, ...]
    centre_mm: np.ndarray          # (2,) C-axis centre
    z_top_mm: float                # machine Z of the plate top
    setup: np.ndarray              # (m,) int, run-order index
    target: np.ndarray             # (m,) int into part()
    repeat: np.ndarray             # (m,) bool: drift-check re-touch
    c_deg: np.ndarray              # (m,)
    q_T: np.ndarray                # (m, 2) contact point, table frame
    p_R: np.ndarray                # (m, 2) contact point, machine frame
    n_R: np.ndarray                # (m, 2) outward normal, machine frame
    xn_R: np.ndarray               # (m, 3) nominal tip centre
    d_R: np.ndarray                # (m, 3) approach direction
    elev_deg: np.ndarray           # (m,) approach elevation (downward positive)
    t_s: np.ndarray                # (m,) trigger time
    t_setup_s: np.ndarray          # (m,) start time of the row's set-up
    dt_prev_s: np.ndarray          # (m,) time since the previous trigger (inf: first)
    n_prev_R: np.ndarray           # (m, 2) previous touch's normal (0 for the first)
    move_sign: np.ndarray          # (m, 2) last direction of motion of X, Y at trigger
    touches_since_wipe: np.ndarray  # (m,) int
    temp_air_C: np.ndarray
    temp_spindle_C: np.ndarray
    active: tuple[tuple[float, float], ...]  # probing intervals (s)
    placement: tuple[float, float, float]    # part on the table: angle (rad), offset X, Y (mm)

    @property
    def m(self) -> int:
        return len(self.setup)


def _temperatures(rng: np.random.Generator, t: np.ndarray):
    """Air and spindle sensor readings at times ``t`` (s), deg C, 0.01 K steps."""
    period = rng.uniform(240.0, 600.0)
    amp = rng.uniform(0.3, 0.8)
    phase = rng.uniform(0, 1)
    tri = 2.0 * np.abs(2.0 * ((t / period + phase) % 1.0) - 1.0) - 1.0  # thermostat cycling
    air = rng.uniform(19.4, 21.2) + amp * tri
    if rng.random() < 0.6:  # a door opens
        t_d = rng.uniform(0.1, 0.9) * (t[-1] + 1.0)
        air = air - rng.uniform(0.3, 0.8) * np.where(t > t_d, np.exp(-(t - t_d) / 300.0), 0.0)
    spindle = rng.uniform(21.0, 23.0) + rng.uniform(2.0, 4.0) * np.exp(-t / rng.uniform(1200, 2500))
    air = np.round(air + rng.normal(0, 0.004, t.shape), 2)
    spindle = np.round(spindle + rng.normal(0, 0.004, t.shape), 2)
    return air, spindle


def _layout(rng: np.random.Generator, angles_deg: tuple[float, ...], centre_mm,
            repeats: bool) -> Layout:
    """Touch sequence, nominal geometry, path, timing and sensors of one campaign."""
    P = part()
    nc = len(angles_deg)
    centre = np.asarray(centre_mm, float)
    psi0 = rng.uniform(0, 2 * math.pi)                 # part clamped at a random angle
    off = rng.uniform(-22.0, 22.0, 2)                   # and off the C axis
    z_top = rng.uniform(-460.0, -260.0)
    R0 = _rot(psi0)
    q_all_T = P.p_W[:, :2] @ R0.T + off
    n_all_T = P.n_W @ R0.T
    feats = list(dict.fromkeys(P.feature))              # blade, pin1..5, slot
    members = {f: [i for i in range(P.n) if P.feature[i] == f] for f in feats}
    n_rep = (8 if nc <= 4 else 4 if nc <= 6 else 2) if repeats else 0
    elev_choices = np.array([0.0, 0.0, 0.0, 15.0, 30.0, 45.0])
    # the touch sequence of each set-up (features start elsewhere, directions alternate)
    setup, target, rep, elev, first = [], [], [], [], []
    gap_s, wiped = [], []
    pause_done = False
    for j, c in enumerate(angles_deg):
        start_f = (3 * j) % len(feats)
        seq: list[int] = []
        for f in feats[start_f:] + feats[:start_f]:
            idx = members[f]
            seq += idx if (j + feats.index(f)) % 2 == 0 else idx[::-1]
        seq += seq[:n_rep]                               # drift-check re-touches
        el_f = dict(zip(feats, rng.choice(elev_choices, len(feats))))
        setup += [j] * len(seq)
        target += seq
        rep += [False] * (len(seq) - n_rep) + [True] * n_rep
        elev += [float(el_f[P.feature[i]]) for i in seq]
        first += [True] + [False] * (len(seq) - 1)
        # C indexing and clamping, sometimes an operator pause, sometimes a long break
        g = 4.0 + abs(c - (angles_deg[j - 1] if j else 0.0)) / 30.0 + rng.uniform(2.0, 6.0)
        g += rng.uniform(60.0, 900.0) if (j and rng.random() < 0.35) else 0.0
        if j and not pause_done and rng.random() < 0.3:
            g += rng.uniform(900.0, 2400.0)
            pause_done = True
        gap_s.append(g)
        wiped.append(j == 0 or rng.random() < 0.5)      # operator wipes the stylus
    setup = np.array(setup)
    tgt = np.array(target)
    rep = np.array(rep)
    first = np.array(first)
    m = len(setup)
    ang = np.array(angles_deg, float)[setup]
    Rc = _rot(-ang * DEG)                                # (m, 2, 2): eq. 1, r p = R(-C) w p
    q_T = q_all_T[tgt]
    p_R = centre + np.einsum("mij,mj->mi", Rc, q_T)
    n_R = np.einsum("mij,mj->mi", Rc, n_all_T[tgt])
    el = np.array(elev) * DEG
    d_R = np.column_stack([-np.cos(el)[:, None] * n_R, -np.sin(el)])
    xn_R = np.column_stack([p_R + STYLUS_R_MM * n_R, z_top + P.p_W[tgt, 2]])
    start = xn_R - APPROACH_MM * d_R                     # where each approach begins
    home = np.array([*(centre + [0.0, 260.0]), z_top + 100.0])   # table parked for C indexing
    prev = np.vstack([home, start[:-1]])
    prev[first] = home
    feat = np.array(P.feature, dtype=object)[tgt]
    direct = ~first & ~rep & (feat == np.roll(feat, 1))
    mv = start - prev
    t_pos = np.where(direct, np.linalg.norm(mv, axis=1) / RAPID_MM_S + rng.uniform(0.3, 0.6, m),
                     (np.linalg.norm(mv[:, :2], axis=1) + 2 * CLEARANCE_MM) / RAPID_MM_S
                     + rng.uniform(0.8, 1.6, m))
    lead = t_pos + rng.uniform(0.4, 0.9, m) + APPROACH_MM / APPROACH_MM_S
    inc = lead.copy()
    inc[1:] += np.where(first[1:], 0.0, APPROACH_MM / 40.0 + 0.2)   # retract of the previous touch
    starts = np.flatnonzero(first)
    inc[starts] += np.array(gap_s)
    inc[0] += rng.uniform(60.0, 180.0)                   # probe qualification, part setting
    stall = rng.random(nc) < 0.15                        # a feed hold inside a set-up
    for j in np.flatnonzero(stall):
        rows = np.flatnonzero(setup == j)
        inc[rows[int(rng.integers(5, len(rows)))]] += rng.uniform(30.0, 240.0)
    t_s = np.round(np.cumsum(inc), 3)
    t_setup = (t_s - lead)[starts][setup]               # C clamped, first positioning begins
    ends = np.append(starts[1:], m) - 1
    active = tuple((float(t_setup[a]), float(t_s[b]) + 0.3) for a, b in zip(starts, ends))
    dt_prev = np.append(np.inf, np.diff(t_s))
    n_prev = np.vstack([np.zeros(2), n_R[:-1]])
    n_prev[first] = 0.0
    # last direction of motion of X and Y at each trigger: the moves before a
    # trigger are [retract of the previous touch, park for C indexing,
    # positioning, approach]; moves below 10 um do not count
    app = APPROACH_MM * d_R[:, :2]
    retract = np.vstack([np.zeros(2), -app[:-1]])
    park = np.zeros((m, 2))
    park[starts[1:]] = home[:2] - start[starts[1:] - 1, :2]
    moves = np.stack([retract, park, mv[:, :2], app], 1).reshape(4 * m, 2)
    moves = np.where(np.abs(moves) > 0.01, np.sign(moves), 0.0)
    last = np.maximum.accumulate(np.where(moves != 0, np.arange(4 * m)[:, None], 0), axis=0)
    sign = np.take_along_axis(moves, last, 0)[3::4]
    # touches since the stylus was last wiped
    since = np.arange(m) - starts[setup]
    carry = 0
    base = np.zeros(nc, int)
    for j in range(nc):
        base[j] = 0 if wiped[j] else carry
        carry = base[j] + int((setup == j).sum())
    air, spindle = _temperatures(rng, t_s)
    return Layout(tuple(float(a) for a in angles_deg), centre, float(z_top), setup, tgt, rep, ang,
                  q_T, p_R, n_R, xn_R, d_R, np.array(elev), t_s, t_setup, dt_prev, n_prev, sign,
                  since + base[setup], air, spindle, active, (float(psi0), *map(float, off)))


# ---------------------------------------------------------------------------
# the machine (base errors: inside the rigid-body model)


@dataclass(frozen=True)
class Machine:
    """Base geometric errors of the table-type machine.

    Physical description, converted to the tool-relative-to-workpiece
    error ``e`` by :func:`linear_error_mm`. Profiles are polynomials over
    the machine travel (u = X / 400 mm, v = Y / 300 mm); every term is a
    function of one axis, a rigid rotation or the squareness, so the base
    machine lies inside the paper's model (up to grid interpolation).

    Attributes (um, urad)
    ----------
    table_x_um : (3,) float
        Position error of the X table itself, coefficients of (u, u^2, u^3):
        how far the table really is along +X beyond its command.
    table_yx_um : (2,) float
        Straightness of the X table in Y, coefficients of (u^2, u^3).
    saddle_y_um, saddle_xy_um : likewise for the Y saddle (v).
    saddle_yaw_urad : (3,) float
        Yaw of the Y saddle, coefficients of (1, v, v^2), about a point
        ``saddle_pivot_mm`` (saddle frame).
    table_yaw_urad : float
        Constant yaw of the X table about ``table_pivot_mm``.
    squareness_urad : float
        ``EC0Y``: the Y motion turned about Z (tool relative to workpiece:
        ``e_x = -EC0Y * Y``).
    exc_um, eyc_um, ecc_urad : (n_setups,) float
        C-axis errors per set-up, tool relative to workpiece (eq. 13's
        ``EXC,total``, ``EYC,total``, ``ECC``).
    pretravel_um : float
        Constant pre-travel left after probe qualification (a size error).
    """

    table_x_um: tuple[float, float, float] = (0.0, 0.0, 0.0)
    table_yx_um: tuple[float, float] = (0.0, 0.0)
    saddle_y_um: tuple[float, float, float] = (0.0, 0.0, 0.0)
    saddle_xy_um: tuple[float, float] = (0.0, 0.0)
    saddle_yaw_urad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    saddle_pivot_mm: tuple[float, float] = (0.0, 0.0)
    table_yaw_urad: float = 0.0
    table_pivot_mm: tuple[float, float] = (0.0, 0.0)
    squareness_urad: float = 0.0
    exc_um: tuple[float, ...] = ()
    eyc_um: tuple[float, ...] = ()
    ecc_urad: tuple[float, ...] = ()
    pretravel_um: float = 0.0


def _random_machine(rng: np.random.Generator, angles_deg) -> Machine:
    a = np.array(angles_deg) * DEG
    u = rng.uniform
    ph = u(0, 2 * math.pi, 4)
    r1, r2 = u(0.5, 2.0), u(0.2, 1.0)
    exc = u(-15, 15) + r1 * np.cos(a + ph[0]) + r2 * np.cos(2 * a + ph[1]) + rng.normal(0, 0.3, len(a))
    eyc = u(-15, 15) + r1 * np.sin(a + ph[0]) + r2 * np.sin(2 * a + ph[1]) + rng.normal(0, 0.3, len(a))
    ecc = u(5, 12) * np.sin(a + ph[2]) + u(1, 4) * np.sin(2 * a + ph[3]) + rng.normal(0, 1.5, len(a))
    return Machine(
        table_x_um=(u(-8, 8), u(-4, 4), u(-3, 3)),
        table_yx_um=(u(-5, 5), u(-3, 3)),
        saddle_y_um=(u(-6, 6), u(-4, 4), u(-3, 3)),
        saddle_xy_um=(u(-5, 5), u(-3, 3)),
        saddle_yaw_urad=(u(-10, 10), u(-8, 8), u(-6, 6)),
        saddle_pivot_mm=(u(-200, 200), u(-150, 150)),
        table_yaw_urad=u(-10, 10),
        table_pivot_mm=(u(-100, 100), u(-100, 100)),
        squareness_urad=u(-30, 30),
        exc_um=tuple(exc), eyc_um=tuple(eyc), ecc_urad=tuple(ecc),
        pretravel_um=u(0.3, 1.2),
    )


def linear_error_mm(mc: Machine, xy_R: np.ndarray) -> np.ndarray:
    """Tool-relative-to-workpiece error of the X and Y axes at readings ``xy_R``.

    The X table and the Y saddle carry the workpiece: the table point under
    the (fixed) tool is displaced by ``D``; the tool relative to the
    workpiece is then displaced by ``e = -D``.

    Parameters
    ----------
    mc : Machine
    xy_R : (m, 2) float
        Axis readings X, Y (machine frame, mm).

    Returns
    -------
    (m, 2) float
        ``e`` in mm, machine frame.
    """
    x, y = xy_R[:, 0], xy_R[:, 1]
    u, v = x / 400.0, y / 300.0
    D = np.zeros_like(xy_R)
    tx, tyx = mc.table_x_um, mc.table_yx_um
    D[:, 0] += tx[0] * u + tx[1] * u**2 + tx[2] * u**3
    D[:, 1] += tyx[0] * u**2 + tyx[1] * u**3
    sy, sxy = mc.saddle_y_um, mc.saddle_xy_um
    D[:, 1] += sy[0] * v + sy[1] * v**2 + sy[2] * v**3
    D[:, 0] += sxy[0] * v**2 + sxy[1] * v**3
    D *= UM_MM
    # yaw of the saddle: the table point under the tool sits at (0, Y) - pivot
    # in saddle coordinates (the saddle is at -Y, the tool at the bed origin)
    eps_y = (mc.saddle_yaw_urad[0] + mc.saddle_yaw_urad[1] * v + mc.saddle_yaw_urad[2] * v**2) * URAD
    lever_y = np.column_stack([np.full_like(y, -mc.saddle_pivot_mm[0]), y - mc.saddle_pivot_mm[1]])
    D += eps_y[:, None] * _perp(lever_y)
    # constant yaw of the X table: the point under the tool is (X, Y) in table coordinates
    D += mc.table_yaw_urad * URAD * _perp(xy_R - mc.table_pivot_mm)
    e = -D
    e[:, 0] += -mc.squareness_urad * URAD * y   # EC0Y, eq. 4 sign, stated for e directly
    return e


def c_axis_error_mm(mc: Machine, setup: np.ndarray, p_R: np.ndarray, centre_mm) -> np.ndarray:
    """Tool-relative-to-workpiece error from the C axis at contact points ``p_R``.

    ``e = (EXC, EYC) + ECC * R(90 deg) (p - centre)`` (paper eq. 13, errors
    read as tool relative to workpiece: the workpiece really turned by
    ``-ECC`` and moved by ``-(EXC, EYC)``).
    """
    exc = np.asarray(mc.exc_um)[setup] * UM_MM
    eyc = np.asarray(mc.eyc_um)[setup] * UM_MM
    ecc = np.asarray(mc.ecc_urad)[setup] * URAD
    return np.column_stack([exc, eyc]) + ecc[:, None] * _perp(p_R - centre_mm)


def touch_dq_mm(n_R: np.ndarray, e_mm: np.ndarray, g_mm: np.ndarray,
                pretravel_mm: np.ndarray) -> np.ndarray:
    """Measured normal deviation of touches: ``dq = G - n . e - p``.

    Parameters
    ----------
    n_R : (m, 2) float
        Nominal outward normals, machine frame.
    e_mm : (m, 2) float
        Tool-relative-to-workpiece error at the touch, mm.
    g_mm : (m,) float
        Workpiece deviation along the normal (positive: material farther out).
    pretravel_mm : (m,) float
        Probe travel past contact, measured along the normal.
    """
    return g_mm - np.einsum("ij,ij->i", n_R, e_mm) - pretravel_mm


# ---------------------------------------------------------------------------
# the workpiece form


def _workpiece_um(rng: np.random.Generator) -> np.ndarray:
    """True normal deviation of each target, um (machining errors of the plate)."""
    P = part()
    g = np.zeros(P.n)
    # blade: low-order form error along the contour plus a dwell mark
    perim = P.blade.x[-1]
    s = P.s_blade / perim
    for k in range(2, 7):
        a, b = rng.normal(0, 2.5 / k, 2)
        g[:30] += a * np.cos(2 * math.pi * k * s) + b * np.sin(2 * math.pi * k * s)
    s0 = rng.uniform(0.1, 0.9)
    g[:30] -= rng.uniform(1.0, 3.0) * np.exp(-(((s - s0 + 0.5) % 1.0 - 0.5) / 0.03) ** 2)
    # pins: position and radius errors
    for k in range(5):
        sl = slice(30 + 4 * k, 34 + 4 * k)
        g[sl] = P.n_W[sl] @ rng.normal(0, 6.0, 2) + rng.normal(0, 2.0)
    # slot walls: offset and tilt along the slot
    along = np.array([-18.0, -9.0, 0.0, 9.0, 18.0]) / 18.0
    for w in range(2):
        g[50 + 5 * w:55 + 5 * w] = rng.normal(0, 4.0) + rng.normal(0, 3.0) * along
    return g


# ---------------------------------------------------------------------------
# the paper's baseline: eq. 15 design, projection, identifiability


def _hat(v: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """(m, N) linear-interpolation weights on ``nodes`` (eqs 8-11)."""
    k = np.clip(np.searchsorted(nodes, v, side="right") - 1, 0, len(nodes) - 2)
    z = (v - nodes[k]) / (nodes[k + 1] - nodes[k])
    H = np.zeros((len(v), len(nodes)))
    r = np.arange(len(v))
    H[r, k] = 1.0 - z
    H[r, k + 1] = z
    return H


def grid_nodes_mm(v: np.ndarray, n_nodes: int = GRID_NODES) -> np.ndarray:
    """Uniform grid nodes covering the readings ``v`` (mm) with 1 mm margin."""
    return np.linspace(v.min() - 1.0, v.max() + 1.0, n_nodes)


def _machine_columns(xy_R, n_R, setup, centre_mm, model, nodes):
    """Eq. 15 columns other than ``G``: X/Y error motions, EC0Y, C per set-up."""
    x, y = xy_R[:, 0], xy_R[:, 1]
    nx, ny = n_R[:, 0], n_R[:, 1]
    xc, yc = x - centre_mm[0], y - centre_mm[1]
    paper_abbe = [ny[:, None] * xc[:, None]]            # x * ECY(y) in Y: tool-side stacking
    if model == "grid":
        gx, gy = nodes if nodes is not None else (grid_nodes_mm(x), grid_nodes_mm(y))
        Fx, Fy = _hat(x, gx), _hat(y, gy)
        abbe = [paper_abbe[0] * Fy]
    elif model in ("poly", "poly_table"):
        def leg(v):
            lo, hi = v.min(), v.max()
            u = (2 * v - lo - hi) / max(hi - lo, 1e-9)
            return np.polynomial.legendre.legvander(u, POLY_DEGREE)
        Fx, Fy = leg(x), leg(y)
        # the paper's x * ECY(y), or y * ECX(x) in X (this machine's table stacking)
        abbe = [paper_abbe[0] * Fy] if model == "poly" else [nx[:, None] * yc[:, None] * Fx]
    else:
        raise ConfigError(f"model {model!r}: expected 'grid', 'poly' or 'poly_table'")
    S = np.zeros((len(x), int(setup.max()) + 1))
    S[np.arange(len(x)), setup] = 1.0
    rot = (_perp(xy_R - centre_mm) * n_R).sum(1)
    return np.hstack([nx[:, None] * Fx, ny[:, None] * Fx, nx[:, None] * Fy, ny[:, None] * Fy,
                      *abbe, (nx * yc)[:, None],
                      nx[:, None] * S, ny[:, None] * S, rot[:, None] * S])


def _one_hot(index: np.ndarray, n: int | None = None) -> np.ndarray:
    H = np.zeros((len(index), int(index.max()) + 1 if n is None else n))
    H[np.arange(len(index)), index] = 1.0
    return H


def paper_design(xy_R, n_R, setup, target, centre_mm, *, model: str = "grid",
                 nodes=None) -> tuple[np.ndarray, slice]:
    """The matrix A of the paper's eq. 15, one row per touch.

    Columns: X/Y error motions (``EXX``, ``EYX`` on X, ``EXY``, ``EYY``,
    ``ECY`` on Y, eqs 10-12), ``EC0Y``, per set-up ``EXC``, ``EYC``,
    ``ECC`` (eq. 13), then ``G`` per target (eq. 7). Signs are immaterial
    here (only the column space is used). No gauge is imposed (eqs 16-17
    only pick one solution and do not change the fitted dq).

    Parameters
    ----------
    xy_R : (m, 2) float
        Axis readings at the touch (nominal stylus centre), mm.
    n_R : (m, 2) float
        Outward normals, machine frame.
    setup, target : (m,) int
        Set-up and target index of each row.
    centre_mm : (2,) float
        C-axis centre (the paper's MCS origin).
    model : {"grid", "poly", "poly_table"}
        ``"grid"``: the paper's look-up tables on ``nodes`` (default: 9
        uniform nodes per axis over the readings). ``"poly"``: the same
        model with smooth axis functions (Legendre, degree
        :data:`POLY_DEGREE`), used for identifiability. ``"poly_table"``:
        smooth too, with the Abbe term of this machine's stacking (the X
        table on the Y saddle: ``y * ECX(x)`` in X) instead of the paper's
        ``x * ECY(y)`` in Y. (Both terms at once would admit the field
        ``r^2 (-y, x)``, covariant under every rotation: no single machine
        has both.)
    nodes : tuple of (N,) arrays, optional
        Grid nodes (x, y) for ``model="grid"``.

    Returns
    -------
    A : (m, p) float
    g_cols : slice
        The columns of ``G``.
    """
    M = _machine_columns(np.asarray(xy_R, float), np.asarray(n_R, float), np.asarray(setup),
                         np.asarray(centre_mm, float), model, nodes)
    G = _one_hot(np.asarray(target))
    return np.hstack([M, G]), slice(M.shape[1], M.shape[1] + G.shape[1])


def _svd(A: np.ndarray):
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    U, s, Vt = np.linalg.svd(A / norms, full_matrices=False)
    rank = int((s > s[0] * 1e-9).sum())
    return U, s, Vt, rank, norms


def visible_part(A: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """What the least-squares fit of eq. 18 leaves of ``dq`` (reference path).

    Parameters
    ----------
    A : (m, p) float
        Design of eq. 15 (:func:`paper_design`).
    dq : (m,) or (m, k) float

    Returns
    -------
    Same shape as ``dq``: ``dq`` minus its projection on the columns of A.
    """
    U, _, _, rank, _ = _svd(A)
    Ur = U[:, :rank]
    return dq - Ur @ (Ur.T @ dq)


class Projector:
    """The eq. 15 fit of one campaign, factorised once.

    ``G`` (one column per target) is eliminated exactly: projecting it out
    subtracts each target's mean. The remaining columns, with their target
    means removed, are factorised by one SVD; the same factorisation gives
    the residual (:meth:`residual`) and the workpiece patterns the design
    cannot see (:meth:`workpiece_null_dims`). Equal to :func:`visible_part`
    on the full matrix (tested).

    Parameters
    ----------
    xy_R, n_R, setup, target, centre_mm, model, nodes
        As :func:`paper_design`.
    """

    def __init__(self, xy_R, n_R, setup, target, centre_mm, *, model="grid", nodes=None):
        target = np.asarray(target)
        self._G = _one_hot(target)
        self._count = self._G.sum(0)
        M = _machine_columns(np.asarray(xy_R, float), np.asarray(n_R, float), np.asarray(setup),
                             np.asarray(centre_mm, float), model, nodes)
        self._M = M
        self.nodes = nodes if nodes is not None else (grid_nodes_mm(np.asarray(xy_R)[:, 0]),
                                                      grid_nodes_mm(np.asarray(xy_R)[:, 1]))
        U, s, Vt, rank, norms = _svd(self._demean(M))
        self._U = U[:, :rank]
        self._null = Vt[rank:].T / norms[:, None]

    def _mean(self, X):
        return (self._G.T @ X) / (self._count[:, None] if X.ndim == 2 else self._count)

    def _demean(self, X):
        return X - self._G @ self._mean(X)

    def residual(self, dq: np.ndarray) -> np.ndarray:
        """(m,) or (m, k): ``dq`` minus its least-squares fit by eq. 15."""
        r = self._demean(np.asarray(dq, float))
        return r - self._U @ (self._U.T @ r)

    def workpiece_null_dims(self, gauge: np.ndarray) -> int:
        """Workpiece patterns outside ``gauge`` that the design cannot see.

        A null vector (theta, g) of A has ``M theta`` constant per target
        and ``g = -mean_target(M theta)``. Zero means the workpiece is
        identifiable up to the gauge (:func:`gauge_columns`).
        """
        if self._null.shape[1] == 0:
            return 0
        N = -self._mean(self._M @ self._null)             # (n_targets, k)
        N = N / max(np.abs(N).max(), 1e-300)
        Ub, sb, _ = np.linalg.svd(N, full_matrices=False)
        B = Ub[:, sb > 1e-6]
        Q, _ = np.linalg.qr(gauge)
        out = B - Q @ (Q.T @ B)
        if out.size == 0:
            return 0
        return int((np.linalg.svd(out, compute_uv=False) > 1e-6).sum())


def gauge_columns(q_T: np.ndarray, n_T: np.ndarray) -> np.ndarray:
    """(n_targets, 5): workpiece patterns self-calibration cannot see.

    Translation in X and Y, rotation, scale and size (constant), as normal
    deviations of targets at table-frame points ``q_T`` with normals ``n_T``.
    """
    return np.column_stack([n_T[:, 0], n_T[:, 1], (_perp(q_T) * n_T).sum(1),
                            (q_T * n_T).sum(1), np.ones(len(q_T))])


def workpiece_identifiability(lay: Layout, grid: Projector | None = None) -> dict[str, int]:
    """Non-gauge workpiece null dimensions under the grid and the smooth model."""
    first = np.unique(lay.target, return_index=True)[1]   # every target appears
    q_T = lay.q_T[first]
    n_T = np.einsum("mji,mj->mi", _rot(-lay.c_deg[first] * DEG), lay.n_R[first])
    gauge = gauge_columns(q_T, n_T)
    grid = grid or Projector(lay.xn_R[:, :2], lay.n_R, lay.setup, lay.target, lay.centre_mm)
    out = {"grid": grid.workpiece_null_dims(gauge)}
    for model in ("poly", "poly_table"):
        out[model] = Projector(lay.xn_R[:, :2], lay.n_R, lay.setup, lay.target, lay.centre_mm,
                               model=model).workpiece_null_dims(gauge)
    return out


# ---------------------------------------------------------------------------
# effect models: each returns the effect's dq (um) at its natural size


@dataclass(frozen=True)
class _Ctx:
    lay: Layout
    rng: np.random.Generator


def _lobes(az: np.ndarray, phase: np.ndarray | float, a3: float, a6: float, ph6: float) -> np.ndarray:
    return a3 * np.cos(3 * (az - phase)) + a6 * np.cos(6 * (az - phase) - ph6)


def _az(lay: Layout) -> np.ndarray:
    return np.arctan2(lay.d_R[:, 1], lay.d_R[:, 0])


def _n_dot_e_um(lay: Layout, e_um: np.ndarray) -> np.ndarray:
    return -(lay.n_R * e_um).sum(1)


def _pretravel_dq_um(lay: Layout, p_um: np.ndarray) -> np.ndarray:
    """dq of a travel ``p`` past contact measured along the approach line: ``p n.d``.

    (A probe's own pre-travel is a stylus deflection along the contact force,
    i.e. along the normal on these walls, and enters as ``-p`` directly; a
    late latch of the position moves the reading along the approach.)
    """
    return p_um * (lay.n_R * lay.d_R[:, :2]).sum(1)


def _eff_none(c: _Ctx):
    return np.zeros(c.lay.m), {}, {}


def _eff_outlier(c: _Ctx):
    lay, rng = c.lay, c.rng
    k = int(rng.integers(2, 6))
    cand = np.flatnonzero(~lay.repeat)
    rows = np.sort(rng.choice(cand, k, replace=False))
    dq = np.zeros(lay.m)
    chip = rng.random(k) < 0.7
    dq[rows] = np.where(chip, rng.uniform(8.0, 40.0, k), -rng.uniform(6.0, 20.0, k))
    return dq, {"n_outliers": float(k)}, {"outlier_rows": tuple(int(r) for r in rows)}


def _activity_lag(lay: Layout, tau_s: float) -> np.ndarray:
    """First-order response (0..1) at each touch to heating while probing."""
    th, t_prev = 0.0, 0.0
    events = []
    for a, b in lay.active:
        events += [(a, 0.0), (b, 1.0)]                  # (time, level before it)
    out = np.empty(lay.m)
    ev = iter(sorted(events))
    nxt = next(ev, None)
    level = 0.0
    for r, t in enumerate(lay.t_s):
        while nxt is not None and nxt[0] <= t:
            th = level + (th - level) * math.exp(-(nxt[0] - t_prev) / tau_s)
            t_prev = nxt[0]
            level = 1.0 - nxt[1]
            nxt = next(ev, None)
        out[r] = level + (th - level) * math.exp(-(t - t_prev) / tau_s)
    return out


def _eff_thermal_drift(c: _Ctx):
    lay, rng = c.lay, c.rng
    tau = rng.uniform(600.0, 1500.0)
    th = _activity_lag(lay, tau) * rng.uniform(1.5, 3.0)          # K
    dx, dy = rng.choice([-1, 1], 2) * rng.uniform([2.0, 2.5], [4.0, 5.0])   # um/K
    alpha = rng.uniform(8.0, 15.0)                                 # um/m/K
    x_fix = lay.centre_mm[0] - rng.uniform(250.0, 450.0)
    e = np.column_stack([th * (dx + alpha * 1e-3 * (lay.xn_R[:, 0] - x_fix)), th * dy])
    return _n_dot_e_um(lay, e), {"tau_s": tau, "head_x_um_per_K": dx, "head_y_um_per_K": dy,
                                 "x_scale_um_per_m_K": alpha, "theta_max_K": float(th.max())}, {}


def _eff_periodic(c: _Ctx):
    lay, rng = c.lay, c.rng
    ax = int(rng.integers(0, 2))
    pitch = float(rng.choice([8.0, 10.0, 12.5, 16.0, 20.0]))
    a1, a2 = rng.uniform(1.0, 2.5), rng.uniform(0.2, 0.8)
    ph1, ph2 = rng.uniform(0, 2 * math.pi, 2)
    ph = 2 * math.pi * lay.xn_R[:, ax] / pitch
    e = np.zeros((lay.m, 2))
    e[:, ax] = a1 * np.sin(ph + ph1) + a2 * np.sin(2 * ph + ph2)
    return _n_dot_e_um(lay, e), {"axis_is_y": float(ax), "pitch_mm": pitch, "a1_um": a1,
                                 "a2_um": a2}, {"axis": "xy"[ax]}


def _eff_probe_lobing(c: _Ctx):
    lay, rng = c.lay, c.rng
    a3, a6 = rng.uniform(0.8, 2.0), rng.uniform(0.1, 0.5)
    ph, ph6 = rng.uniform(0, 2 * math.pi, 2)
    p = _lobes(_az(lay), ph, a3, a6, ph6)
    return -p, {"lobe3_um": a3, "lobe6_um": a6, "phase_rad": ph}, {}


def _eff_reversal(c: _Ctx):
    lay, rng = c.lay, c.rng
    b = rng.uniform(2.0, 8.0, 2)                                   # lost motion X, Y, um
    e = -0.5 * b * lay.move_sign                                   # lags its motion
    return _n_dot_e_um(lay, e), {"lost_motion_x_um": b[0], "lost_motion_y_um": b[1]}, {}


def _unit_coords(lay: Layout):
    xy = lay.xn_R[:, :2]
    lo, hi = xy.min(0), xy.max(0)
    return (2 * xy - lo - hi) / (hi - lo)


def _eff_nonrigid(c: _Ctx):
    lay, rng = c.lay, c.rng
    uv = _unit_coords(lay)
    u, v = uv[:, 0], uv[:, 1]
    k1, k2 = rng.choice([-1, 1], 2) * rng.uniform(4.0, 8.0, 2)
    e = np.column_stack([k2 * u * (v**2 - 1 / 3), k1 * (u**2 - 1 / 3) * (v**2 - 1 / 3)])
    return _n_dot_e_um(lay, e), {"x_of_xy2_um": k2, "y_of_x2y2_um": k1}, {}


def _eff_c_drift(c: _Ctx):
    lay, rng = c.lay, c.rng
    tau = rng.uniform(150.0, 500.0)
    total = rng.choice([-1, 1]) * rng.uniform(25.0, 60.0)          # urad per set-up
    per = total * (1 + 0.25 * rng.normal(size=len(lay.angles_deg)))
    ecc = per[lay.setup] * (1 - np.exp(-(lay.t_s - lay.t_setup_s) / tau)) * URAD
    e_um = ecc[:, None] * _perp(lay.p_R - lay.centre_mm) / UM_MM
    return _n_dot_e_um(lay, e_um), {"tau_s": tau, "ecc_creep_urad": total}, {}


def _eff_temperature(c: _Ctx):
    lay, rng = c.lay, c.rng
    ax, ay = rng.uniform(6.0, 15.0, 2)                             # um/m/K
    fix = lay.centre_mm + rng.choice([-1, 1], 2) * rng.uniform(200.0, 400.0, 2)
    dT = lay.temp_air_C - 20.0
    e = np.column_stack([ax * 1e-3 * dT * (lay.xn_R[:, 0] - fix[0]),
                         ay * 1e-3 * dT * (lay.xn_R[:, 1] - fix[1])])
    corr = float(np.corrcoef(lay.temp_air_C, lay.t_s)[0, 1])
    return _n_dot_e_um(lay, e), {"alpha_x_um_per_m_K": ax, "alpha_y_um_per_m_K": ay,
                                 "t_ref_C": 20.0, "x_fix_mm": fix[0], "y_fix_mm": fix[1],
                                 "corr_temp_time": corr}, {}


def _eff_stylus_bending(c: _Ctx):
    lay, rng = c.lay, c.rng
    ph, k = rng.uniform(3.0, 6.0), rng.uniform(0.4, 0.9)
    s = np.sin(lay.elev_deg * DEG)
    p_n = ph / (1 + k * s) - ph                                    # normal pre-travel change
    return -p_n, {"bend_horizontal_um": ph, "friction_unload": k}, {}


def _eff_lobing_per_setup(c: _Ctx):
    lay, rng = c.lay, c.rng
    a3, a6 = rng.uniform(0.8, 2.0), rng.uniform(0.1, 0.5)
    ph6 = rng.uniform(0, 2 * math.pi)
    phases = rng.uniform(0, 2 * math.pi, len(lay.angles_deg))
    p = _lobes(_az(lay), phases[lay.setup], a3, a6, ph6)
    return -p, {"lobe3_um": a3, "lobe6_um": a6}, {}


def _eff_local_defect(c: _Ctx):
    lay, rng = c.lay, c.rng
    ax = int(rng.integers(0, 2))
    pos = lay.xn_R[:, ax]
    w = rng.uniform(1.5, 3.5)
    for _ in range(50):
        x0 = pos[rng.integers(0, lay.m)] + rng.uniform(-0.5, 0.5)
        if (np.abs(pos - x0) < w).sum() >= 6:
            break
    a = rng.choice([-1, 1]) * rng.uniform(4.0, 8.0)
    z = (pos - x0) / w
    e = np.zeros((lay.m, 2))
    e[:, ax] = a * np.exp(-z**2) * (1 + 0.6 * z)
    return _n_dot_e_um(lay, e), {"axis_is_y": float(ax), "centre_mm": float(x0), "width_mm": w,
                                 "amplitude_um": a}, {"axis": "xy"[ax]}


def _slot_change_um(lay: Layout, rng: np.random.Generator):
    """Per-row slot wall displacement into the slot (um, positive = material out)."""
    P = part()
    tau = rng.uniform(1500.0, 4000.0)
    total = rng.uniform(3.0, 8.0)
    slot = np.array([P.feature[i] == "slot" for i in lay.target])
    along = (P.p_W[lay.target, :2] - P.slot_centre_mm) @ P.slot_dir / 18.0   # -1 .. 1
    shape = 0.55 + 0.45 * along                        # the open end (+) moves more
    return slot * total * shape * (1 - np.exp(-lay.t_s / tau)), tau, total


def _eff_part_change(c: _Ctx):
    g, tau, total = _slot_change_um(c.lay, c.rng)
    return g, {"tau_s": tau, "closure_um": total}, {}


def _eff_fixture_slip(c: _Ctx):
    lay, rng = c.lay, c.rng
    nc = len(lay.angles_deg)
    j = int(rng.integers(1, nc)) if nc > 1 else 0     # never the first set-up run
    rows = np.flatnonzero(lay.setup == j)
    k = rows[int(rng.integers(len(rows) // 4, 3 * len(rows) // 4))]
    after = np.arange(lay.m) >= k      # the part stays where it slipped (later set-ups
    #                                    see a rigid pose change, which their C terms absorb)
    # the part steps in the table frame and turns about a clamp on the plate edge
    a = rng.uniform(0, 2 * math.pi)
    shift_T = rng.uniform(2.0, 5.0) * np.array([math.cos(a), math.sin(a)])      # um
    turn = rng.choice([-1, 1]) * rng.uniform(10.0, 30.0) * URAD
    clamp_T = lay.q_T.mean(0) + rng.choice([-1, 1], 2) * [110.0, 80.0]
    u_T = shift_T + turn * _perp(lay.q_T - clamp_T) / UM_MM
    u_R = np.einsum("mij,mj->mi", _rot(-lay.c_deg * DEG), u_T)
    dq = np.where(after, (lay.n_R * u_R).sum(1), 0.0)  # the workpiece moved by u: dq = +n.u
    return dq, {"setup_index": float(j), "row": float(k),
                "shift_um": float(np.linalg.norm(shift_T)), "turn_urad": turn / URAD}, {}


def _eff_signal_latency(c: _Ctx):
    lay, rng = c.lay, c.rng
    ang = rng.uniform(0, 2 * math.pi)
    rx = lay.centre_mm + 600.0 * np.array([math.cos(ang), math.sin(ang)])
    d2 = ((lay.xn_R[:, :2] - rx) ** 2).sum(1) / 600.0**2
    p = rng.uniform(1.5, 3.5) * (d2 - d2.mean())      # um along the approach
    return _pretravel_dq_um(lay, p), {"receiver_x_mm": rx[0], "receiver_y_mm": rx[1]}, {}


def _eff_reseat(c: _Ctx):
    lay, rng = c.lay, c.rng
    rho, tau = rng.uniform(2.0, 5.0), rng.uniform(1.5, 4.0)
    resid = rho * np.exp(-lay.dt_prev_s / tau)          # first touch: dt = inf, nothing left
    e = resid[:, None] * lay.n_prev_R                  # stylus still pushed along +n_prev
    return _n_dot_e_um(lay, e), {"seat_offset_um": rho, "tau_s": tau}, {}


def _eff_head_tram(c: _Ctx):
    lay, rng = c.lay, c.rng
    tilt = rng.uniform(100.0, 300.0) * URAD
    a = rng.uniform(0, 2 * math.pi)
    z = lay.xn_R[:, 2] - lay.z_top_mm
    e = (z * tilt / UM_MM)[:, None] * np.array([math.cos(a), math.sin(a)])
    return _n_dot_e_um(lay, e), {"tilt_urad": tilt / URAD, "tilt_azimuth_rad": a}, {}


def _eff_stylus_pickup(c: _Ctx):
    lay, rng = c.lay, c.rng
    grow, n0 = rng.uniform(1.5, 4.0), rng.uniform(40.0, 120.0)
    dr = grow * (1 - np.exp(-lay.touches_since_wipe / n0))
    return dr, {"pickup_um": grow, "touches_scale": n0}, {}  # bigger ball: triggers earlier


_BUILDERS: dict[str, Callable[[_Ctx], tuple]] = {
    "none": _eff_none, "outlier": _eff_outlier, "thermal_drift": _eff_thermal_drift,
    "periodic_axis_error": _eff_periodic, "probe_lobing": _eff_probe_lobing,
    "reversal": _eff_reversal, "nonrigid": _eff_nonrigid, "c_drift": _eff_c_drift,
    "temperature_expansion": _eff_temperature, "stylus_bending": _eff_stylus_bending,
    "lobing_per_setup": _eff_lobing_per_setup, "local_scale_defect": _eff_local_defect,
    "part_change": _eff_part_change, "fixture_slip": _eff_fixture_slip,
    "signal_latency": _eff_signal_latency, "reseat_settling": _eff_reseat,
    "head_tram": _eff_head_tram, "stylus_pickup": _eff_stylus_pickup,
}


# ---------------------------------------------------------------------------
# the campaign

_OPTIONS = ("noise_um", "sigmas", "effect_on", "noisy", "schedule", "schedule_deg", "order",
            "centre_mm", "repeats", "identifiable", "perfect")


def reading_mm(xn_R: np.ndarray, n_R: np.ndarray, d_R: np.ndarray, dq_mm: np.ndarray) -> np.ndarray:
    """Axis readings at the trigger for normal deviations ``dq``.

    The machine moves along the commanded approach line through the
    nominal ``Xn`` with direction ``d``; the reading is where that line is
    when ``n . (X - Xn) = dq``: ``X = Xn + d dq / (n . d)``.

    Parameters
    ----------
    xn_R : (m, 3) float
        Nominal stylus-tip centres, machine frame, mm.
    n_R : (m, 2) float
        Outward normals (horizontal), machine frame.
    d_R : (m, 3) float
        Unit approach directions (``n . d < 0``).
    dq_mm : (m,) float

    Returns
    -------
    (m, 3) float, mm.
    """
    nd = (n_R * d_R[:, :2]).sum(1)
    return xn_R + (dq_mm / nd)[:, None] * d_R


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(v)))) if len(v) else 0.0


def _choose_schedule(rng, schedule, schedule_deg, identifiable):
    if schedule_deg is not None:
        ang = tuple(float(a) for a in schedule_deg)
        if not 2 <= len(ang) <= 12 or len(set(a % 360.0 for a in ang)) != len(ang):
            raise ConfigError(f"schedule_deg {schedule_deg!r}: need 2-12 distinct C angles")
        return "custom", ang
    if schedule is not None:
        if schedule not in SCHEDULES:
            raise ConfigError(f"schedule {schedule!r}: expected one of {', '.join(SCHEDULES)}")
        return schedule, SCHEDULES[schedule]
    names = [k for k in SCHEDULES
             if identifiable is None or (k not in NOT_IDENTIFIABLE) == bool(identifiable)]
    w = np.array([0.5 if k in NOT_IDENTIFIABLE else 1.0 for k in names])
    name = names[int(rng.choice(len(names), p=w / w.sum()))]
    return name, SCHEDULES[name]


def _run_order(rng, angles, order):
    if order is None:
        order = str(rng.choice(["random", "random", "sorted", "reversed"]))
    if order == "sorted":
        return tuple(angles)
    if order == "reversed":
        return tuple(angles[::-1])
    if order == "random":
        return tuple(angles[i] for i in rng.permutation(len(angles)))
    raise ConfigError(f"order {order!r}: expected 'random', 'sorted' or 'reversed'")


#: :func:`_analysis`'s answers by (schedule in run order, C-axis centre, placement, repeats),
#: all they depend on; shared between campaigns, only read. 32 (before: oldest dropped at 32).
_ANALYSES = Memo(32)


def _analysis(lay: Layout, repeats: bool) -> tuple[Projector, dict[str, int]]:
    """Eq. 15 projector and identifiability of a campaign's geometry, memoised.

    They depend only on the schedule in run order, the C-axis centre, the
    placement of the part and the repeats (not on timing or the effect), so
    every effect generated from one seed shares them.
    """
    def build():
        nodes = (grid_nodes_mm(lay.xn_R[:, 0]), grid_nodes_mm(lay.xn_R[:, 1]))
        proj = Projector(lay.xn_R[:, :2], lay.n_R, lay.setup, lay.target, lay.centre_mm, nodes=nodes)
        return proj, workpiece_identifiability(lay, proj)

    return _ANALYSES.get_or_compute((lay.angles_deg, *map(float, lay.centre_mm), lay.placement, repeats), build)


def generate(effect: str, seed: int, **options) -> tuple[ProbeLog, Truth]:
    """One campaign of the blade plate on the table-type machine.

    The campaign (schedule, run order, placement, machine, part, timing,
    noise) depends on ``seed`` only, not on ``effect``: the same seed with
    two effects, or with ``effect_on=False``, gives the same campaign with a
    different (or no) effect, and ``dq(on) - dq(off) == effect_dq_um``.

    Parameters
    ----------
    effect : str
        A name from :func:`effects`.
    seed : int
        Non-negative.
    noise_um : float, optional
        Probing noise, 1 sigma (default: drawn in 0.2-0.5 um).
    sigmas : float, optional
        Scale the effect so that its visible part (after the baseline has
        absorbed what it can) is this many noise sigmas per touch, RMS.
        Default: the effect's natural, physically drawn size.
    effect_on : bool
        False: the same campaign without the effect (the truth then says
        ``acceptable_causes=("none",)``, magnitude 0).
    noisy : bool
        False: no probing noise (``noise_um`` still the nominal sigma).
    schedule : str, optional
        A name in :data:`SCHEDULES` (default: drawn).
    schedule_deg : sequence of float, optional
        Custom C angles (overrides ``schedule``).
    order : {"random", "sorted", "reversed"}, optional
        Order the set-ups are run in (default: drawn).
    centre_mm : (2,) float, optional
        C-axis centre in machine coordinates (default: drawn over
        X -300..420, Y -280..260 mm).
    repeats : bool
        Drift-check re-touches at the end of each set-up (default True).
    identifiable : bool, optional
        When drawing the schedule, draw only identifiable (True) or only
        non-identifiable (False) ones.
    perfect : bool
        True: a perfect machine (no geometric error, no pre-travel) and a
        perfect part; only the effect and the noise remain (for exactness
        and hand-worked tests). Default False.

    Returns
    -------
    (ProbeLog, Truth)

    Raises
    ------
    ConfigError
        Unknown effect or option, or an option out of its domain.
    """
    unknown = sorted(set(options) - set(_OPTIONS))
    if unknown:
        raise ConfigError(f"gen_b.generate: unknown option {unknown[0]!r}; "
                          f"known: {', '.join(_OPTIONS)}")
    if effect not in EFFECTS:
        raise ConfigError(f"gen_b: unknown effect {effect!r}; expected one of {', '.join(EFFECTS)}")
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"gen_b: seed must be a non-negative integer, got {seed!r}")
    spec = EFFECTS[effect]
    effect_on = bool(options.get("effect_on", True))
    noisy = bool(options.get("noisy", True))
    sigmas = options.get("sigmas")
    if sigmas is not None and not (np.isfinite(sigmas) and sigmas >= 0):
        raise ConfigError(f"gen_b: sigmas must be a finite number >= 0, got {sigmas!r}")
    streams = np.random.SeedSequence([int(seed), 0x6E2B]).spawn(6)
    r_camp, r_lay, r_mach, r_work, r_eff, r_noise = (np.random.default_rng(s) for s in streams)
    sched_name, angles = _choose_schedule(r_camp, options.get("schedule"), options.get("schedule_deg"),
                                          options.get("identifiable"))
    run = _run_order(r_camp, angles, options.get("order"))
    centre = options.get("centre_mm")
    centre = (np.array([r_camp.uniform(-300, 420), r_camp.uniform(-280, 260)]) if centre is None
              else np.asarray(centre, float).reshape(2))
    noise_um = options.get("noise_um")
    noise_um = float(r_camp.uniform(0.2, 0.5) if noise_um is None else noise_um)
    if not (np.isfinite(noise_um) and noise_um > 0):
        raise ConfigError(f"gen_b: noise_um must be > 0, got {noise_um!r}")

    lay = _layout(r_lay, run, centre, bool(options.get("repeats", True)))
    mc = _random_machine(r_mach, run)
    g_um = _workpiece_um(r_work)
    if options.get("perfect", False):
        zeros = (0.0,) * len(run)
        mc = Machine(exc_um=zeros, eyc_um=zeros, ecc_urad=zeros)
        g_um = np.zeros_like(g_um)
    e_base = linear_error_mm(mc, lay.xn_R[:, :2]) + c_axis_error_mm(mc, lay.setup, lay.p_R, centre)
    machine_dq = touch_dq_mm(lay.n_R, e_base, np.zeros(lay.m), np.full(lay.m, mc.pretravel_um * UM_MM))
    dq_base = machine_dq + g_um[lay.target] * UM_MM

    # the paper's baseline (eq. 15) on this campaign's geometry
    proj, ident = _analysis(lay, bool(options.get("repeats", True)))
    gx, gy = proj.nodes

    eff_um, params, extra = _BUILDERS[effect](_Ctx(lay, r_eff))
    vis = proj.residual(np.column_stack([eff_um, machine_dq / UM_MM]))
    vis_unit = _rms(vis[:, 0])
    if sigmas is not None and effect != "none":
        if vis_unit < 1e-9:
            raise ConfigError(f"gen_b: effect {effect!r} is invisible on this campaign; cannot scale "
                              f"it to {sigmas} sigmas")
        scale = sigmas * noise_um / vis_unit
        eff_um = eff_um * scale
        params = {**params, "scale": scale}
    if not effect_on:
        eff_um = np.zeros(lay.m)
    visible_um = _rms(proj.residual(eff_um)) if effect_on else 0.0
    noise = r_noise.normal(0.0, noise_um, lay.m) if noisy else np.zeros(lay.m)
    dq = dq_base + (eff_um + noise) * UM_MM

    X = reading_mm(lay.xn_R, lay.n_R, lay.d_R, dq)
    P = part()
    tg = lay.target
    cols = {
        "setup": [f"C{a:g}" for a in lay.c_deg],
        "target": [P.target[i] for i in tg],
        "t_s": lay.t_s,
        "X_mm": X[:, 0], "Y_mm": X[:, 1], "Z_mm": X[:, 2],
        "Xn_mm": lay.xn_R[:, 0], "Yn_mm": lay.xn_R[:, 1], "Zn_mm": lay.xn_R[:, 2],
        "nx": lay.n_R[:, 0], "ny": lay.n_R[:, 1], "nz": np.zeros(lay.m),
        "feature": [P.feature[i] for i in tg],
        "C_deg": lay.c_deg,
        "dx": lay.d_R[:, 0], "dy": lay.d_R[:, 1], "dz": lay.d_R[:, 2],
        "wx_mm": P.p_W[tg, 0], "wy_mm": P.p_W[tg, 1], "wz_mm": P.p_W[tg, 2],
        "wnx": P.n_W[tg, 0], "wny": P.n_W[tg, 1], "wnz": np.zeros(lay.m),
        "status": ["ok"] * lay.m,
        "temp_air_C": lay.temp_air_C, "temp_spindle_C": lay.temp_spindle_C,
    }
    meta = {"machine": "table-type 4-axis vertical machining centre (C on X on Y; head carries Z)",
            "artefact": "blade plate: cambered blade boss, five pins, one slot",
            "stylus_r_mm": repr(STYLUS_R_MM), "kinematic_chain": CHAIN,
            "generator": "scenarios.blind.gen_b", "seed": str(int(seed))}
    # validate=False: the per-row checks cost more than the campaign; the tests
    # read every effect's log back through the validating reader instead
    log = make_log(cols, meta, source=f"<gen_b seed {seed}>", validate=False)

    covs = tuple(extra.get("axis", "x") if c == "axis" else c for c in spec.covariates)
    eff_ro = np.array(eff_um, float)
    wp = g_um.copy()
    for a in (eff_ro, wp, gx, gy):
        a.setflags(write=False)
    vis_sig = visible_um / noise_um
    truth = Truth(
        effect=effect, kind=spec.kind,
        acceptable_causes=spec.acceptable if effect_on else ("none",),
        covariates=covs if effect_on else (),
        magnitude_um=_rms(eff_um), visible_um=visible_um, visible_sigmas=vis_sig,
        detectable=bool(vis_sig >= 1.0), noise_um=noise_um, effect_dq_um=eff_ro,
        outlier_rows=tuple(extra.get("outlier_rows", ())) if effect_on else (),
        targets=P.target, workpiece_um=wp,
        workpiece_identifiable=not any(ident.values()),
        schedule_deg=tuple(run), seed=int(seed), schedule=sched_name, where=spec.where,
        params={k: float(v) for k, v in params.items()},
        base_visible_um=_rms(vis[:, 1]),
        centre_mm=(float(centre[0]), float(centre[1])), grid_x_mm=gx, grid_y_mm=gy)
    return log, truth
