"""Blind campaign generator A: probe logs that ``vmt discover`` has never seen.

Issue 13, item 7. Every campaign is a 2D self-calibration (Ibaraki et al.,
``shared/papers/ibaraki-selfcalibration-2d-freeform.txt``): the same targets
of a part on a rotary table probed at several C indexings. Everything here is
written apart from ``sim/`` and from ``core``'s models: its own part, its own
kinematic chain, its own contact solver, its own effects. Only the file
format is shared (``core.probelog``).

The part
--------
A plate with a polygonal pocket (regular hexagon, regular octagon or a
five-pointed star, circumradius 50-68 mm, depth 18-30 mm, walls probed at
1-3 depths), radial key slots (12-20 mm wide, 15-30 mm long) leaving the
middle of some polygon walls, a central boss (radius 10-18 mm, 1-2 depths)
and bores outside the pocket (radius 8-11 mm). The *symmetric* variant
(hexagon with two opposite slots: 2-fold; octagon with four: 4-fold) has
bores at the vertices (all six; every other one of the octagon's) and
probing patterns repeated with that symmetry;
the *asymmetric* variant has 1-3 slots, 1-3 bores at random places,
irregular point patterns and is often clamped 15-60 mm off the table
centre. True form deviations: every wall
has a position error, a tilt, a bow and a draft; every boss and bore a size
error, a position error, low harmonics (k = 2..4) and a draft; the part is
mounted a few um off the table centre and turned by tens of urad.

The machine
-----------
Three linear axes on the tool branch, stacked either ``b-Y-X-Z`` (X rides on
Y, the paper's eqs 4-5) or ``b-X-Y-Z`` (Y rides on X), and a rotary table C
on the bed, written in the ``kinematic_chain`` metadata. The tip position is
an exact composition of rigid motions (no first-order approximation)::

    YX:  p = y uY + tY(y) + RY(y) (x ex + tX(x) + RX(x) (z uZ))
    XY:  p = x ex + tX(x) + RX(x) (y uY + tY(y) + RY(y) (z uZ))

with ``t`` the translational error motions (EXX, EYX / EXY, EYY), ``R`` the
rotation (Rodrigues, exact) of the angular ones (EAX, EBX, ECX / EAY, EBY,
ECY), ``uY`` the Y stroke turned by the squareness EC0Y and ``uZ`` the Z
stroke turned by EA0Z, EB0Z. Each error motion is a smooth curve over the
axis travel: Chebyshev terms T1..T4 plus one long sine (period 300-700 mm),
amplitudes bounded so that the curvature stays below about 1e-3 um/mm^2 (a
piecewise-linear table with 20 mm nodes then follows it to 0.05 um). The
table: ``p_R = A p_P + b`` with the C line at ``centre + (EX0C, EY0C) +
(EXC(C), EYC(C))``, rotation ``-C + ECC(C)`` about it (paper eq. 1: C
positive clockwise), tilts EA0C + EAC(C), EB0C + EBC(C) about a pivot
80-150 mm below the part, and the part's mounting pose on the table.

A touch: the controller drives the reported axes along a straight line
``q(t) = q0 + t d`` (``d`` the approach direction, possibly 12 deg off the
normal in azimuth and up to 35 deg in elevation); the exact contact is the
root of ``phi(P(q(t))) = r`` (``phi`` the distance of the tip centre from
the true surface near the target, ``r`` the stylus radius), solved by
Newton's method to 2e-13 mm; the trigger comes after a further travel
``delta`` (pre-travel variation: zero unless an effect sets it) plus the
probing noise, which is drawn as a normal deviation (``dq`` noise exactly
N(0, noise_um)). The log reports ``q`` at the trigger.

Effects
-------
:func:`effects` lists them: ``none``, the catalogue causes, the new named
causes of issue 13 item 5 and out-of-catalogue effects. Each effect's physics
is in the docstring of its ``_fx_<name>`` function. An effect's strength is
set so that what the paper's model cannot absorb of it (its residual after a
least-squares projection on the eq. 15 columns on an 8-interval grid,
:func:`baseline_residual`) has an RMS of ``sigmas`` noise sigmas over the
rows it affects, ``sigmas`` drawn in [1, 6] (outliers: 8-30 sigma each),
within a physical limit per effect (``_Draw.amp_max``: e.g. lobing 6 um,
screw pitch 4 um, C creep 30 urad/min, expansion 25 um/m/K); where the limit
binds, the effect is weaker than asked and the truth says so (``capped``,
``visible_sigmas``). Where the schedule cannot identify the workpiece, a
machine-position effect can be wholly absorbed (visible ~0): that is the
physics, and the truth reports it.

Everything random comes from ``numpy.random.SeedSequence(seed)``: one
stream for the plan, one for the machine, one for the part, one for the
noise and one per effect, so ``effect_on=False`` (and every other effect at
the same seed) gives the same plan, machine, part and noise.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.linalg as sla
from numpy.polynomial import chebyshev as _cheb

from core.exceptions import ConfigError
from core.probelog import ProbeLog, make_log
from core.units import DEG, MM, UM, URAD

#: One micrometre in millimetres: this module works in the file's units (mm).
UM_MM = UM / MM

#: Effect name -> kind. ``none`` counts as a catalogue cause (its name is one).
EFFECTS: dict[str, str] = {
    "none": "catalogue",
    "outlier": "catalogue",
    "thermal_drift": "catalogue",
    "periodic_axis_error": "catalogue",
    "probe_lobing": "catalogue",
    "reversal": "catalogue",
    "nonrigid": "catalogue",
    "c_drift": "new_named",
    "temperature_expansion": "new_named",
    "stylus_bending": "new_named",
    "lobing_per_setup": "new_named",
    "local_scale_defect": "new_named",
    "part_change": "new_named",
    "probe_heating": "out_of_catalogue",
    "knock": "out_of_catalogue",
    "feed_latency": "out_of_catalogue",
    "reseat_hysteresis": "out_of_catalogue",
    "vibration": "out_of_catalogue",
    "thermal_bending": "out_of_catalogue",
}

PARTS = ("hexagon", "octagon", "star")
_SYMMETRY = {"hexagon": 6, "octagon": 8, "star": 5}
#: Sensors whose reading cycles with the coolant chiller (decorrelated from time).
CYCLIC_SENSORS = ("coolant", "scale", "column")
#: Sensors whose reading drifts slowly and smoothly.
SLOW_SENSORS = ("air", "bed")
#: Grid intervals per axis of the projection that defines "visible" (eq. 15 columns).
GRID_INTERVALS = 8
#: Newton step (mm) at which a contact solve stops: machine coordinates of
#: up to ~1000 mm carry a rounding floor of ~1e-13 mm, so 2e-13 mm is the
#: last step that still means something.
SOLVE_TOL_MM = 2e-13


def effects() -> dict[str, str]:
    """Every effect name with its kind: ``catalogue``, ``new_named`` or ``out_of_catalogue``."""
    return dict(EFFECTS)


# ---------------------------------------------------------------------------
# small geometry helpers
# ---------------------------------------------------------------------------
def rotation(v: np.ndarray) -> np.ndarray:
    """Exact rotation matrices (Rodrigues) of rotation vectors.

    ``R = cos(th) I + sinc(th) [v]x + ((1 - cos th) / th^2) v v^T``, with
    ``1 - cos th`` written as ``2 sin^2(th / 2)`` so that angles of urad
    keep their digits.

    Parameters
    ----------
    v : (n, 3) float
        Rotation vectors, rad.

    Returns
    -------
    (n, 3, 3) float
    """
    v = np.atleast_2d(np.asarray(v, float))
    th = np.sqrt(np.einsum("ij,ij->i", v, v))
    small = th < 1e-300
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0, np.sin(ths) / ths)
    b = np.where(small, 0.5, 2.0 * np.sin(ths / 2) ** 2 / ths ** 2)
    R = b[:, None, None] * v[:, :, None] * v[:, None, :]
    c = 1.0 - b * th ** 2
    av = a[:, None] * v
    R[:, 0, 0] += c
    R[:, 1, 1] += c
    R[:, 2, 2] += c
    R[:, 0, 1] -= av[:, 2]
    R[:, 1, 0] += av[:, 2]
    R[:, 0, 2] += av[:, 1]
    R[:, 2, 0] -= av[:, 1]
    R[:, 1, 2] -= av[:, 0]
    R[:, 2, 1] += av[:, 0]
    return R


def _rz(angle: np.ndarray) -> np.ndarray:
    """(n,) rad -> (n, 3, 3) right-handed rotations about Z."""
    angle = np.asarray(angle, float)
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros((len(angle), 3, 3))
    R[:, 0, 0] = c
    R[:, 0, 1] = -s
    R[:, 1, 0] = s
    R[:, 1, 1] = c
    R[:, 2, 2] = 1.0
    return R


def _mv(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Batched matrix-vector product: (n, 3, 3), (n, 3) -> (n, 3)."""
    return np.einsum("nij,nj->ni", A, v)


def _mtv(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Batched transposed product ``A^T v``."""
    return np.einsum("nji,nj->ni", A, v)


# ---------------------------------------------------------------------------
# the machine
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Curve:
    """A smooth error motion over an axis travel (no grid, no spline).

    ``value(q) = sum_k cheb[k] T_k(u) + sine[0] sin(2 pi q / sine[1] + sine[2])``
    with ``u = (2 q - lo - hi) / (hi - lo)``.

    Attributes
    ----------
    cheb : tuple of float
        Chebyshev coefficients (T0, T1, ...), in the curve's unit (um or urad).
    sine : tuple of float
        (amplitude in the curve's unit, period mm, phase rad); amplitude 0: none.
    lo, hi : float
        Travel, mm (machine frame).
    """

    cheb: tuple = (0.0,)
    sine: tuple = (0.0, 1.0, 0.0)
    lo: float = -500.0
    hi: float = 500.0

    def __call__(self, q: np.ndarray) -> np.ndarray:
        """Value at axis reading(s) ``q`` (mm), in the curve's unit."""
        q = np.asarray(q, float)
        u = (2 * q - self.lo - self.hi) / (self.hi - self.lo)
        v = _cheb.chebval(u, self.cheb)
        a, period, ph = self.sine
        if a:
            v = v + a * np.sin(2 * np.pi * q / period + ph)
        return v * np.ones_like(q)


@dataclass(frozen=True)
class Harmonics:
    """A function of the C angle: ``sum_k a_k cos(k C) + b_k sin(k C)`` plus a constant.

    Attributes
    ----------
    const : float
    a, b : tuple of float
        Cosine and sine coefficients of harmonics 1, 2, ... (unit of the quantity).
    """

    const: float = 0.0
    a: tuple = ()
    b: tuple = ()

    def __call__(self, c_rad: np.ndarray) -> np.ndarray:
        c = np.asarray(c_rad, float)
        v = np.full_like(c, self.const)
        for k, (ak, bk) in enumerate(zip(self.a, self.b), start=1):
            v = v + ak * np.cos(k * c) + bk * np.sin(k * c)
        return v


_ZERO = Curve()
_NOH = Harmonics()
#: Error motions of the linear axes (ISO 230-1 names); translations um, rotations urad.
LINEAR_ERRORS = ("EXX", "EYX", "EAX", "EBX", "ECX", "EXY", "EYY", "EAY", "EBY", "ECY")


@dataclass(frozen=True)
class Machine:
    """Generator A's machine: exact rigid-body chain with smooth errors.

    Attributes
    ----------
    stacking : {"YX", "XY"}
        ``"YX"``: X rides on Y (``V[w-C-b-Y-X-Z-(C)-t]``, paper eqs 4-5);
        ``"XY"``: Y rides on X.
    errors : dict[str, Curve]
        Error motions of X (functions of x) and Y (functions of y), keys in
        :data:`LINEAR_ERRORS`; um for E[XY][XY], urad for E[ABC][XY].
    EC0Y_urad, EA0Z_urad, EB0Z_urad : float
        Squareness of Y to X, of Z to Y and to X (ISO 230-1).
    centre_mm : (2,) tuple
        Nominal C line in the machine frame (X, Y), mm.
    z_top_mm : float
        Machine Z of the part's top face (the artefact frame's z = 0).
    EX0C_um, EY0C_um, EA0C_urad, EB0C_urad : float
        Location errors of the C axis average line.
    EXC, EYC : Harmonics
        Radial error motion of C (um), harmonics 2 and up.
    ECC : Harmonics
        Angular positioning error of C (urad), right-handed about Z.
    EAC, EBC : Harmonics
        Tilt error motion of C (urad).
    pivot_mm : float
        Height of the C tilt pivot below the part top, mm.
    scale_zero_mm : (3,) tuple
        Fixed points of the X, Y, Z scales (thermal effects expand about them).
    travel_mm : (3, 2) tuple
        Axis travels, mm.
    probe_offset_um : float
        Constant pre-travel left after the stylus calibration (a size error).
    """

    stacking: str = "YX"
    errors: dict = field(default_factory=dict)
    EC0Y_urad: float = 0.0
    EA0Z_urad: float = 0.0
    EB0Z_urad: float = 0.0
    centre_mm: tuple = (0.0, 0.0)
    z_top_mm: float = -300.0
    EX0C_um: float = 0.0
    EY0C_um: float = 0.0
    EA0C_urad: float = 0.0
    EB0C_urad: float = 0.0
    EXC: Harmonics = _NOH
    EYC: Harmonics = _NOH
    ECC: Harmonics = _NOH
    EAC: Harmonics = _NOH
    EBC: Harmonics = _NOH
    pivot_mm: float = 100.0
    scale_zero_mm: tuple = (0.0, 0.0, 0.0)
    travel_mm: tuple = ((-500.0, 500.0), (-400.0, 400.0), (-600.0, 0.0))
    probe_offset_um: float = 0.0

    @property
    def chain(self) -> str:
        """ISO 10791 chain string written in the log's metadata."""
        return "V[w-C-b-Y-X-Z-(C)-t]" if self.stacking == "YX" else "V[w-C-b-X-Y-Z-(C)-t]"

    def curve(self, name: str) -> Curve:
        return self.errors.get(name, _ZERO)

    def _axis_errors(self, axis: str, q: np.ndarray) -> np.ndarray:
        """(n, 5): E[X|Y]axis, E[Y|X]..., EA, EB, EC of one axis at readings q.

        The same values as calling each :class:`Curve`, evaluated together
        (one Chebyshev basis per axis): the contact solve calls this often.
        """
        names = (("EXX", "EYX", "EAX", "EBX", "ECX") if axis == "X"
                 else ("EXY", "EYY", "EAY", "EBY", "ECY"))
        curves = [self.curve(k) for k in names]
        out = np.zeros((len(q), 5))
        groups: dict = {}
        for i, c in enumerate(curves):
            groups.setdefault((c.lo, c.hi), []).append(i)
        for (lo, hi), idx in groups.items():
            deg = max(len(curves[i].cheb) for i in idx)
            u = (2 * q - lo - hi) / (hi - lo)
            T = np.empty((len(q), deg))
            T[:, 0] = 1.0
            if deg > 1:
                T[:, 1] = u
            for k in range(2, deg):
                T[:, k] = 2 * u * T[:, k - 1] - T[:, k - 2]
            C = np.zeros((deg, len(idx)))
            for j, i in enumerate(idx):
                C[: len(curves[i].cheb), j] = curves[i].cheb
            out[:, idx] = T @ C
        for i, c in enumerate(curves):
            a, period, ph = c.sine
            if a:
                out[:, i] += a * np.sin(2 * np.pi * q / period + ph)
        return out

    def tip_R(self, q: np.ndarray) -> np.ndarray:
        """Actual stylus-tip centre for reported axis readings.

        Parameters
        ----------
        q : (n, 3) float
            Reported X, Y, Z readings, mm.

        Returns
        -------
        (n, 3) float
            Tip centre in the machine frame R, mm (exact composition).
        """
        q = np.atleast_2d(q)
        x, y, z = q[:, 0], q[:, 1], q[:, 2]
        zer = np.zeros_like(x)
        ex_, ey_ = self._axis_errors("X", x), self._axis_errors("Y", y)
        tX = np.column_stack([ex_[:, 0], ex_[:, 1], zer]) * UM_MM
        tY = np.column_stack([ey_[:, 0], ey_[:, 1], zer]) * UM_MM
        RX = rotation(ex_[:, 2:] * URAD)
        RY = rotation(ey_[:, 2:] * URAD)
        e0y = self.EC0Y_urad * URAD
        uY = np.array([-np.sin(e0y), np.cos(e0y), 0.0])
        uZ = rotation(np.array([[self.EA0Z_urad, self.EB0Z_urad, 0.0]]) * URAD)[0] @ np.array([0.0, 0.0, 1.0])
        ex = np.array([1.0, 0.0, 0.0])
        zs = z[:, None] * uZ
        if self.stacking == "YX":
            inner = x[:, None] * ex + tX + _mv(RX, zs)
            return y[:, None] * uY + tY + _mv(RY, inner)
        inner = y[:, None] * uY + tY + _mv(RY, zs)
        return x[:, None] * ex + tX + _mv(RX, inner)

    def table(self, c_rad: np.ndarray, extra_rot_rad: np.ndarray | float = 0.0):
        """Pose of the table frame T in R for commanded C angles.

        Parameters
        ----------
        c_rad : (n,) float
            Commanded C, rad (positive clockwise: the table turns by -C).
        extra_rot_rad : (n,) float or float
            Added right-handed rotation about the C line (effects).

        Returns
        -------
        A : (n, 3, 3) float
            Rotation of T in R.
        b : (n, 3) float
            Origin of T in R (on the actual C line, at the part top), mm.
        """
        c_rad = np.asarray(c_rad, float)
        n = len(c_rad)
        o = np.column_stack([
            np.full(n, self.centre_mm[0]) + (self.EX0C_um + self.EXC(c_rad)) * UM_MM,
            np.full(n, self.centre_mm[1]) + (self.EY0C_um + self.EYC(c_rad)) * UM_MM,
            np.full(n, self.z_top_mm)])
        tilt = rotation(np.column_stack([self.EA0C_urad + self.EAC(c_rad),
                                         self.EB0C_urad + self.EBC(c_rad), np.zeros(n)]) * URAD)
        Rz = _rz(-c_rad + self.ECC(c_rad) * URAD + extra_rot_rad)
        h = np.array([0.0, 0.0, self.pivot_mm])
        # rotate about the pivot, h below the table origin
        b = o + _mv(tilt, np.broadcast_to(h, (n, 3))) - h
        return tilt @ Rz, b

    @staticmethod
    def perfect(centre_mm=(0.0, 0.0), z_top_mm=-300.0, stacking="YX") -> "Machine":
        """A machine without any error (for exactness checks)."""
        return Machine(stacking=stacking, centre_mm=tuple(centre_mm), z_top_mm=z_top_mm)


def _draw_machine(rng: np.random.Generator, centre: np.ndarray, z_top: float, stacking: str) -> Machine:
    """Realistic smooth errors of a compensated vertical machine with a rotary table."""
    lo_x, hi_x = centre[0] - rng.uniform(250, 600), centre[0] + rng.uniform(250, 600)
    lo_y, hi_y = centre[1] - rng.uniform(200, 450), centre[1] + rng.uniform(200, 450)
    s = lambda: rng.choice([-1.0, 1.0])  # noqa: E731

    def curve(lo, hi, a1, a2, a3, a4, sine_amp):
        period = rng.uniform(300, 700)
        return Curve(cheb=(0.0, s() * a1, s() * a2, s() * a3, s() * a4),
                     sine=(sine_amp, period, rng.uniform(0, 2 * np.pi)), lo=lo, hi=hi)

    u = rng.uniform
    err = {
        # positioning: scale error + curvature (um)
        "EXX": curve(lo_x, hi_x, u(3, 12), u(1, 5), u(0.5, 2.5), u(0.2, 1), u(0.3, 1.5)),
        "EYY": curve(lo_y, hi_y, u(3, 12), u(1, 5), u(0.5, 2.5), u(0.2, 1), u(0.3, 1.5)),
        # straightness (um): no linear term (ISO: reference line removed)
        "EYX": curve(lo_x, hi_x, 0.0, u(1, 4), u(0.5, 2), u(0.2, 0.8), u(0.2, 1.0)),
        "EXY": curve(lo_y, hi_y, 0.0, u(1, 4), u(0.5, 2), u(0.2, 0.8), u(0.2, 1.0)),
        # yaw (urad)
        "ECX": curve(lo_x, hi_x, u(2, 8), u(1, 5), u(0.5, 2), 0.0, u(0.3, 1.5)),
        "ECY": curve(lo_y, hi_y, u(2, 8), u(1, 5), u(0.5, 2), 0.0, u(0.3, 1.5)),
        # pitch and roll (urad): they only act through the tip's depth, kept small
        "EAX": curve(lo_x, hi_x, u(0, 1.5), u(0, 1), 0.0, 0.0, 0.0),
        "EBX": curve(lo_x, hi_x, u(0, 1.5), u(0, 1), 0.0, 0.0, 0.0),
        "EAY": curve(lo_y, hi_y, u(0, 1.5), u(0, 1), 0.0, 0.0, 0.0),
        "EBY": curve(lo_y, hi_y, u(0, 1.5), u(0, 1), 0.0, 0.0, 0.0),
    }

    def harm(kmin, amps):
        a, b = [], []
        for k in range(1, kmin + len(amps)):
            amp = amps[k - kmin] if k >= kmin else 0.0
            ph = rng.uniform(0, 2 * np.pi)
            a.append(amp * np.cos(ph))
            b.append(amp * np.sin(ph))
        return Harmonics(0.0, tuple(a), tuple(b))

    return Machine(
        stacking=stacking, errors=err,
        EC0Y_urad=s() * u(5, 40), EA0Z_urad=u(-2, 2), EB0Z_urad=u(-2, 2),
        centre_mm=(float(centre[0]), float(centre[1])), z_top_mm=float(z_top),
        EX0C_um=u(-20, 20), EY0C_um=u(-20, 20),
        EA0C_urad=u(-2, 2), EB0C_urad=u(-2, 2),
        EXC=harm(2, [u(0.2, 1.0), u(0.1, 0.5)]), EYC=harm(2, [u(0.2, 1.0), u(0.1, 0.5)]),
        ECC=harm(1, [u(3, 12), u(2, 8), u(1, 4)]),
        EAC=harm(1, [u(0, 0.8)]), EBC=harm(1, [u(0, 0.8)]),
        pivot_mm=u(80, 150),
        scale_zero_mm=(float(u(lo_x, hi_x)), float(u(lo_y, hi_y)), 0.0),
        travel_mm=((lo_x, hi_x), (lo_y, hi_y), (z_top - 200.0, 0.0)),
        probe_offset_um=u(-0.5, 0.5),
    )


# ---------------------------------------------------------------------------
# the part
# ---------------------------------------------------------------------------
PLANE, BOSS, BORE = 0, 1, 2


@dataclass(frozen=True)
class Part:
    """Targets of generator A's part, in the artefact (part) frame P.

    Attributes
    ----------
    name : str
        ``"<pocket>-pocket"`` plus ``"-sym"`` for the symmetric variant.
    symmetry : int
        Order m of the rotation (360/m deg) that maps the target set onto
        itself; 1 when the set has no rotational symmetry.
    target, feature : tuple of str
        Target ids and their feature ids, (N,).
    w_mm : (N, 3) float
        Nominal contact points, mm; z = 0 at the part top, negative below.
    wn : (N, 3) float
        Nominal unit normals out of the material (towards the stylus).
    shape : (N,) int
        0 plane (a wall), 1 boss (material inside a circle), 2 bore.
    centre_mm : (N, 2) float
        Circle centre of a boss or bore (NaN for walls).
    radius_mm : (N,) float
        Nominal circle radius (NaN for walls).
    form_um : (N,) float
        True form deviation at each target, um (positive: material farther
        out along ``wn``), before the mounting pose.
    """

    name: str
    symmetry: int
    target: tuple
    feature: tuple
    w_mm: np.ndarray
    wn: np.ndarray
    shape: np.ndarray
    centre_mm: np.ndarray
    radius_mm: np.ndarray
    form_um: np.ndarray

    @property
    def n(self) -> int:
        return len(self.target)


def _polygon(kind: str, R: float, th0: float, r_in_ratio: float) -> np.ndarray:
    """Pocket vertices, counter-clockwise, (k, 2) mm."""
    if kind == "star":
        ang = th0 + np.arange(10) * np.pi / 5
        rad = np.where(np.arange(10) % 2 == 0, R, R * r_in_ratio)
    else:
        m = _SYMMETRY[kind]
        ang = th0 + np.arange(m) * 2 * np.pi / m
        rad = np.full(m, R)
    return np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])


def _corner_margin(vprev, v, vnext, r, clear=1.5):
    """Distance along a wall from vertex ``v`` a tip of radius r must keep."""
    a, b = vprev - v, vnext - v
    cross = a[0] * b[1] - a[1] * b[0]
    gamma = np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))
    if cross < 0:  # convex corner of a CCW polygon (interior angle gamma < 180 deg)
        return r / np.tan(gamma / 2) + clear
    return r + clear


class _Targets:
    """Accumulates targets while a part is laid out."""

    def __init__(self):
        self.tid, self.feat, self.w, self.wn, self.shape, self.cen, self.rad = ([] for _ in range(7))

    def add(self, tid, feat, p, z, nrm, shape=PLANE, cen=(np.nan, np.nan), rad=np.nan):
        self.tid.append(tid)
        self.feat.append(feat)
        self.w.append([p[0], p[1], z])
        self.wn.append([nrm[0], nrm[1], 0.0])
        self.shape.append(shape)
        self.cen.append(list(cen))
        self.rad.append(rad)

    def __len__(self):
        return len(self.tid)


def _fractions(rng, n, regular):
    """n positions in (0, 1): evenly spread, or jittered."""
    f = (np.arange(n) + 0.5) / n
    return f if (regular or n == 1) else np.sort(f + rng.uniform(-0.3, 0.3, n) / n)


def _layout(rng, kind, symmetric, r, n_setups):
    """Draw a layout (sizes, counts, slot walls) whose campaign has 150-400 touches."""
    m = _SYMMETRY[kind]
    for _attempt in range(2000):
        L = {"R": rng.uniform(56, 68) if kind == "star" else rng.uniform(50, 66),
             "r_in": rng.uniform(0.55, 0.62), "th0": rng.uniform(0, 2 * np.pi / m),
             "depth": rng.uniform(18, 30)}
        nd = int(rng.integers(1, 4))
        L["wall_z"] = -np.linspace(3.0, L["depth"] - 4.0, 4)[np.sort(rng.choice(4, nd, replace=False))]
        L["n_pts"] = int(rng.integers(1, 4)) if kind == "star" else int(rng.integers(2, 5))
        L["boss_R"] = rng.uniform(10, 14) if kind == "star" else rng.uniform(12, 18)
        L["boss_z"] = -np.array([4.0, L["depth"] - 5.0])[: int(rng.integers(1, 3))]
        L["n_boss"] = m * int(rng.integers(1, 3)) if symmetric else int(rng.integers(6, 13))
        L["bore_R"] = rng.uniform(8, 11)
        L["bore_z"] = -np.array([5.0, 12.0])[: int(rng.integers(1, 3))]
        # radial key slots from the middle of some walls (tangential normals:
        # what makes a part sensitive to the table's rotation)
        L["slot_w"] = rng.uniform(max(12.0, 2 * r + 4), 20.0)
        L["slot_l"] = rng.uniform(15.0, 30.0)
        L["slot_pts"] = int(rng.integers(1, 3))
        if kind == "star":
            slots = []
        elif symmetric:  # keep the symmetry that defeats the schedule: 2-fold / 4-fold
            step = m // 2 if kind == "hexagon" else 2
            slots = list(range(0, m, step))
        else:
            slots = sorted(rng.choice(m, size=int(rng.integers(1, 4)), replace=False).tolist())
        L["slots"] = slots
        if symmetric:  # towards the vertices: all six (hexagon), every other one (octagon)
            nb = m if kind == "hexagon" else m // 2
            L["bore_ang"] = L["th0"] + np.arange(nb) * 2 * np.pi / nb
            L["bore_rho"] = np.full(nb, L["R"] + L["bore_R"] + 6.0)
            L["n_bore_pts"] = int(rng.integers(3, 5))
        else:
            nb = int(rng.integers(1, 4))
            L["bore_ang"] = np.sort(rng.uniform(0, 2 * np.pi, nb))
            L["bore_rho"] = L["R"] + L["bore_R"] + rng.uniform(6, 20, nb)
            L["n_bore_pts"] = int(rng.integers(4, 7))
            if nb > 1 and np.min(np.diff(np.r_[L["bore_ang"], L["bore_ang"][0] + 2 * np.pi])) < 0.6:
                continue
        if slots and L["n_pts"] < 2:
            L["n_pts"] = 2
        if not _bores_clear(L, kind):
            continue
        n_walls = 10 if kind == "star" else m
        n_w = (len(L["wall_z"]) * (n_walls * L["n_pts"] + len(slots) * (2 * L["slot_pts"] + 1))
               + L["n_boss"] * len(L["boss_z"]) + len(L["bore_ang"]) * L["n_bore_pts"] * len(L["bore_z"]))
        if 150 <= n_w * n_setups <= 370:
            return L
    raise ConfigError(f"no part with 150-400 touches for {n_setups} set-ups")  # pragma: no cover


def _bores_clear(L, kind) -> bool:
    """True when every bore keeps 4 mm of material from the pocket and the slots."""
    V = _polygon(kind, L["R"], L["th0"], L["r_in"])
    hw, sl = L["slot_w"] / 2, L["slot_l"]
    for a_, rho in zip(L["bore_ang"], L["bore_rho"]):
        c = rho * np.array([np.cos(a_), np.sin(a_)])
        if np.min(np.hypot(*(V - c).T)) < L["bore_R"] + 4:
            return False
        for k in L["slots"]:
            a, b = V[k], V[(k + 1) % len(V)]
            t = (b - a) / np.linalg.norm(b - a)
            nrm = np.array([-t[1], t[0]])
            rel = c - (a + b) / 2
            u, v = rel @ t, -(rel @ nrm)  # along the wall, outward
            du = max(abs(u) - hw, 0.0)
            dv = max(v - sl, 0.0, -v)
            if np.hypot(du, dv) < L["bore_R"] + 4:
                return False
    return True


def _build_part(rng: np.random.Generator, kind: str, symmetric: bool, r_stylus: float,
                n_setups: int, perfect: bool) -> Part:
    """Draw a part whose campaign has 150-400 touches at ``n_setups`` set-ups."""
    m = _SYMMETRY[kind]
    L = _layout(rng, kind, symmetric, r_stylus, n_setups)
    V = _polygon(kind, L["R"], L["th0"], L["r_in"])
    T = _Targets()
    n_walls = len(V)
    clear = r_stylus + 1.5  # from a corner where the free space turns outward
    for k in range(n_walls):
        a, b = V[k], V[(k + 1) % n_walls]
        Lw = np.linalg.norm(b - a)
        t = (b - a) / Lw
        nrm = np.array([-t[1], t[0]])  # left of a CCW boundary: into the pocket
        ma = _corner_margin(V[k - 1], a, b, r_stylus)
        mb = _corner_margin(a, b, V[(k + 2) % n_walls], r_stylus)
        n_pts = L["n_pts"]
        if k in L["slots"]:  # two pieces of wall either side of the slot's mouth
            hw = L["slot_w"] / 2
            n1 = n_pts // 2
            pieces = [(ma, Lw / 2 - hw - clear, n1), (Lw / 2 + hw + clear, Lw - mb, n_pts - n1)]
        else:
            pieces = [(ma, Lw - mb, n_pts)]
        s_along = np.concatenate([lo + (hi - lo) * _fractions(rng, cnt, symmetric)
                                  for lo, hi, cnt in pieces if cnt])
        for di, z in enumerate(L["wall_z"]):
            for j, s_ in enumerate(s_along):
                T.add(f"wall{k + 1}-d{di + 1}-p{j + 1}", f"wall{k + 1}", a + s_ * t, z, nrm)
        if k in L["slots"]:
            mouth = (a + b) / 2
            hw, sl = L["slot_w"] / 2, L["slot_l"]
            e = clear + (sl - 2 * clear) * _fractions(rng, L["slot_pts"], symmetric)
            for di, z in enumerate(L["wall_z"]):
                for j, e_ in enumerate(e):  # side walls face each other
                    T.add(f"slot{k + 1}-d{di + 1}-a{j + 1}", f"slot{k + 1}", mouth + hw * t - e_ * nrm, z, -t)
                    T.add(f"slot{k + 1}-d{di + 1}-b{j + 1}", f"slot{k + 1}", mouth - hw * t - e_ * nrm, z, t)
                T.add(f"slot{k + 1}-d{di + 1}-e", f"slot{k + 1}", mouth - sl * nrm, z, nrm)
    # boss at the pocket centre
    b0 = rng.uniform(0, 2 * np.pi)
    nb = L["n_boss"]
    bang = b0 + (np.arange(nb) + (0 if symmetric else rng.uniform(-0.3, 0.3, nb))) * 2 * np.pi / nb
    for di, z in enumerate(L["boss_z"]):
        for j, a_ in enumerate(bang):
            u = np.array([np.cos(a_), np.sin(a_)])
            T.add(f"boss-d{di + 1}-p{j + 1}", "boss", L["boss_R"] * u, z, u, BOSS, (0.0, 0.0), L["boss_R"])
    # bores outside the pocket
    p0 = rng.uniform(0, 2 * np.pi)
    nbp = L["n_bore_pts"]
    for h, (ang, rho) in enumerate(zip(L["bore_ang"], L["bore_rho"])):
        c = rho * np.array([np.cos(ang), np.sin(ang)])
        if symmetric:  # the same pattern relative to the bore's polar angle
            pang = ang + p0 + np.arange(nbp) * 2 * np.pi / nbp
        else:
            pang = rng.uniform(0, 2 * np.pi) + (np.arange(nbp) + rng.uniform(-0.2, 0.2, nbp)) * 2 * np.pi / nbp
        for di, z in enumerate(L["bore_z"]):
            for j, a_ in enumerate(pang):
                u = np.array([np.cos(a_), np.sin(a_)])
                # out of the material: towards the bore axis
                T.add(f"bore{h + 1}-d{di + 1}-p{j + 1}", f"bore{h + 1}", c + L["bore_R"] * u, z, -u,
                      BORE, tuple(c), L["bore_R"])
    w, wn = np.array(T.w), np.array(T.wn)
    shape, cen, rad = np.array(T.shape), np.array(T.cen, float), np.array(T.rad)
    feat = tuple(T.feat)
    # the asymmetric part is often clamped off the table centre (the
    # artefact frame stays the table's: origin on the C line)
    if not symmetric and rng.random() < 0.7:
        a_ = rng.uniform(0, 2 * np.pi)
        off = rng.uniform(15, 60) * np.array([np.cos(a_), np.sin(a_)])
        w[:, :2] += off
        cen = cen + off
    form = np.zeros(len(feat)) if perfect else _draw_form(rng, feat, w, wn, shape, cen)
    if symmetric:
        order = 2 if kind == "hexagon" else 4  # what the slots keep
    else:
        order = 1
    del m
    return Part(name=f"{kind}-pocket" + ("-sym" if symmetric else ""), symmetry=order,
                target=tuple(T.tid), feature=feat, w_mm=w, wn=wn, shape=shape, centre_mm=cen,
                radius_mm=rad, form_um=form)


def _draw_form(rng, feat, w, wn, shape, cen) -> np.ndarray:
    """Smooth true form deviations (um) of every feature, at its targets."""
    G = np.zeros(len(feat))
    # one smooth field per face: a feature and one normal (a slot has three)
    key = [(f, tuple(np.round(n, 6))) if sh == PLANE else (f,) for f, n, sh in zip(feat, wn, shape)]
    for k_ in dict.fromkeys(key):
        idx = np.array([i for i, g in enumerate(key) if g == k_])
        z = w[idx, 2]
        draft = rng.normal(0, 0.08) * (z - z.mean())
        if shape[idx[0]] == PLANE:
            t = np.array([wn[idx[0], 1], -wn[idx[0], 0]])
            s = w[idx, :2] @ t
            span = max(np.ptp(s), 1.0)
            v = (s - s.mean()) / span * 2
            G[idx] = rng.normal(0, 2.0) + rng.normal(0, 1.5) * v + rng.normal(0, 1.0) * (v ** 2 - 1 / 3) + draft
        else:
            c = cen[idx[0]]
            ang = np.arctan2(w[idx, 1] - c[1], w[idx, 0] - c[0])
            g = rng.normal(0, 3.0) + draft
            shift = rng.normal(0, 3.0, 2)
            g = g + wn[idx, :2] @ shift
            for k in (2, 3, 4):
                g = g + rng.normal(0, 0.8 / k) * np.cos(k * ang + rng.uniform(0, 2 * np.pi))
            G[idx] = g
    return G


def _phi(part: Part, ti: np.ndarray, p_P: np.ndarray, G_mm: np.ndarray):
    """Distance of points from the true surface near their targets, and its gradient.

    Parameters
    ----------
    part : Part
    ti : (n,) int
        Target index of each point.
    p_P : (n, 3) float
        Points in the part frame, mm.
    G_mm : (n,) float
        True normal deviation of the surface at the target, mm (the surface
        near the target is the nominal one moved by G along ``wn``: a plane,
        or a circle of radius R + G (boss) / R - G (bore)).

    Returns
    -------
    phi : (n,) float
        Distance, mm, positive on the free side.
    grad : (n, 3) float
        Its gradient in P.
    """
    sh = part.shape[ti]
    wn = part.wn[ti]
    phi = np.einsum("ij,ij->i", wn, p_P - part.w_mm[ti]) - G_mm
    grad = wn.copy()
    circ = sh != PLANE
    if circ.any():
        v = p_P[circ, :2] - part.centre_mm[ti[circ]]
        rho = np.hypot(v[:, 0], v[:, 1])
        R = part.radius_mm[ti[circ]]
        g = G_mm[circ]
        boss = sh[circ] == BOSS
        phi[circ] = np.where(boss, rho - (R + g), (R - g) - rho)
        sgn = np.where(boss, 1.0, -1.0)
        grad[circ] = np.column_stack([sgn * v[:, 0] / rho, sgn * v[:, 1] / rho, np.zeros(len(rho))])
    return phi, grad


# ---------------------------------------------------------------------------
# the plan (what the operator's macro does) and the campaign context
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Plan:
    """Rows of one campaign in the order the touches happened.

    Attributes
    ----------
    setup_ids : tuple of str
        Set-up ids in time order.
    C_deg : (n_setups,) float
        Commanded C of each set-up, time order.
    setup, target : (n,) int
        Set-up index and target index (into :class:`Part`) of each row.
    t_s : (n,) float
        Time of each touch (for a failed touch: when it gave up), s.
    d : (n, 3) float
        Unit approach direction, machine frame.
    feed_mm_min : (n,) float
        Probing feed.
    ok : (n,) bool
        False for a touch that did not trigger (status ``no_trigger``).
    temps : dict[str, (n,) float]
        Temperature sensor readings (``temp_<name>_C``), degC.
    r_mm : float
        Stylus tip radius.
    L_mm : float
        Approach distance (start of the probing move before the nominal contact).
    drift_check : (n,) bool
        Rows that re-touch the set-up's reference target.
    """

    setup_ids: tuple
    C_deg: np.ndarray
    setup: np.ndarray
    target: np.ndarray
    t_s: np.ndarray
    d: np.ndarray
    feed_mm_min: np.ndarray
    ok: np.ndarray
    temps: dict
    r_mm: float
    L_mm: float
    drift_check: np.ndarray

    @property
    def n(self) -> int:
        return len(self.setup)


def _schedule(rng: np.random.Generator, n_setups: int, symmetric: bool, part_kind: str):
    """C angles (deg, time order) and whether they make the workpiece unidentifiable.

    Non-identifiable schedules (only with the symmetric part): every angle a
    multiple of 90 deg on the 8-fold octagon, or of 180 deg on the 6-fold
    hexagon. Then the touched machine positions are the same set in every
    set-up, each with the same normal, and a form error with the part's
    symmetry is indistinguishable from an error field of the rigid model
    (odd axis curves under a half turn, x <-> y exchanged under a quarter
    turn): the workpiece is not identifiable.
    """
    if symmetric:
        step = {"octagon": 90.0, "hexagon": 180.0}[part_kind]
        k = int(round(360 / step))
        base = rng.uniform(0, 360)
        base = float(np.round(base / 5) * 5) if rng.random() < 0.5 else 0.0
        if k >= n_setups:
            ang = base + step * rng.permutation(k)[:n_setups]
        else:  # half turns only: repeat the two orientations
            ang = base + step * (np.arange(n_setups) % k)
            ang = ang[rng.permutation(n_setups)]
        return np.mod(ang, 360.0), False
    m = _SYMMETRY[part_kind]
    for _ in range(1000):
        if rng.random() < 0.4:
            ang = np.r_[0.0, rng.uniform(20, 340, n_setups - 1)]
        else:
            ang = rng.uniform(0, 360, n_setups)
        ang = np.round(ang * 2) / 2  # half degrees, as typed on a controller
        diff = np.abs((ang[:, None] - ang[None, :] + 180) % 360 - 180)
        if np.min(diff[np.triu_indices(n_setups, 1)]) < 20:
            continue
        sym = np.abs((diff + 1e-9) % (360 / m)) < 1e-6
        if sym.all():
            continue
        return rng.permutation(ang), True
    raise ConfigError("no irregular C schedule found")  # pragma: no cover


def _sensor_series(rng: np.random.Generator, name: str, t: np.ndarray, T_end: float) -> np.ndarray:
    """Readings of one temperature sensor at times ``t`` (degC, 0.01 resolution)."""
    if name in CYCLIC_SENSORS:
        # chiller hysteresis: warms slowly, is pulled down fast (asymmetric saw)
        P = rng.uniform(360, 900)
        ph = rng.uniform(0, 1)
        A = rng.uniform(0.5, 2.0)
        frac = (t / P + ph) % 1.0
        rise = rng.uniform(0.65, 0.85)
        saw = np.where(frac < rise, frac / rise, (1 - frac) / (1 - rise)) * 2 - 1
        T = rng.uniform(19.5, 21.5) + A * saw + rng.uniform(-0.2, 0.2) * t / max(T_end, 1.0)
    else:
        P = rng.uniform(1.5, 3.0) * max(T_end, 600.0)
        T = rng.uniform(19.0, 23.0) + rng.uniform(0.2, 0.8) * np.sin(2 * np.pi * t / P + rng.uniform(0, 2 * np.pi))
        if name == "bed":
            T = T.mean() + 0.4 * (T - T.mean())
    T = T + rng.normal(0, 0.004, len(t))
    return np.round(T, 2)


def _build_plan(rng: np.random.Generator, part: Part, C_deg: np.ndarray, r_mm: float,
                sensors: tuple, setup_style: str) -> Plan:
    """The operator's macro: route, approach directions, feeds, timing, sensors."""
    n_set = len(C_deg)
    feat = np.array(part.feature)
    z = part.w_mm[:, 2]
    # passes: the pocket at each depth (walls in CCW order), boss at each depth, each bore
    passes = []
    pocket = np.char.startswith(feat.astype(str), "wall") | np.char.startswith(feat.astype(str), "slot")
    centre = part.centre_mm[feat == "boss"][0]  # the pocket's centre
    ang = np.arctan2(part.w_mm[:, 1] - centre[1], part.w_mm[:, 0] - centre[0])
    for zz in sorted(set(z[pocket]), reverse=True):  # round the pocket, walls and slots
        idx = np.flatnonzero(pocket & (z == zz))
        passes.append(idx[np.argsort(ang[idx], kind="stable")])
    for zz in sorted(set(z[feat == "boss"]), reverse=True):
        passes.append(np.flatnonzero((feat == "boss") & (z == zz)))
    for f in dict.fromkeys(part.feature):
        if f.startswith("bore"):
            passes.append(np.flatnonzero(feat == f))
    passes = [passes[i] for i in rng.permutation(len(passes))]
    alternate = rng.random() < 0.6
    drift = rng.random() < 0.7
    ref = int(passes[0][0])
    rapid = rng.uniform(6000, 15000) / 60.0  # mm/s
    v_search = rng.uniform(200, 600) / 60.0  # first (search) touch, mm/s
    back_off = rng.uniform(0.5, 1.5)  # mm, before the measuring touch
    settle = rng.uniform(1.0, 4.0)  # s, after each positioning move (vibration, datum)
    # measuring feed (the second, slow touch: the one logged)
    base_feed = {"wall": rng.choice([40, 60, 80, 120]), "boss": rng.choice([30, 50, 80]),
                 "bore": rng.choice([20, 30, 50])}
    base_feed["slot"] = base_feed["wall"]
    overrides = np.ones(n_set)
    k_over = rng.choice(n_set, size=max(1, n_set // 2), replace=False)
    overrides[k_over] = rng.choice([0.5, 0.6, 0.8, 1.2, 1.5], size=len(k_over))
    L = rng.uniform(2.0, 5.0)
    omega_c = rng.uniform(15, 60)  # deg/s
    n_fail = int(rng.choice([0, 0, 0, 1, 2]))

    rows_s, rows_t, rows_drift = [], [], []
    for j in range(n_set):
        order = list(passes)
        if alternate and j % 2 == 1:
            order = [p[::-1] for p in order[::-1]]
        seq = ([ref] if drift else []) + [int(i) for p in order for i in p] + ([ref] if drift else [])
        rows_s += [j] * len(seq)
        rows_t += seq
        rows_drift += [drift and (k == 0 or k == len(seq) - 1) for k in range(len(seq))]
    n0 = len(rows_t)
    fail_at = set(rng.choice(np.arange(3, n0 - 1), size=n_fail, replace=False).tolist()) if n_fail else set()
    setup_, target_, ok_, dc_ = [], [], [], []
    for k in range(n0):
        if k in fail_at:  # a touch that did not trigger, retried at once
            setup_.append(rows_s[k])
            target_.append(rows_t[k])
            ok_.append(False)
            dc_.append(False)
        setup_.append(rows_s[k])
        target_.append(rows_t[k])
        ok_.append(True)
        dc_.append(rows_drift[k])
    setup_ = np.array(setup_)
    target_ = np.array(target_)
    ok_ = np.array(ok_)
    n = len(setup_)

    # approach directions: into the normal, some turned in azimuth, many inclined
    c_rad = C_deg[setup_] * DEG
    nR = _mv(_rz(-c_rad), part.wn[target_])
    beta = np.where(rng.random(n) < 0.55, 0.0, rng.uniform(-12, 12, n)) * DEG
    beta = np.where(part.shape[target_] == PLANE, beta, beta * 0.6)
    elev = np.where(rng.random(n) < 0.45, 0.0, rng.choice([-1, 1], n) * rng.uniform(5, 35, n)) * DEG
    dh = _mv(_rz(beta), -nR)[:, :2]
    d = np.column_stack([dh * np.cos(elev)[:, None], np.sin(elev)])
    d /= np.linalg.norm(d, axis=1)[:, None]

    kind = np.array([part.feature[i].rstrip("0123456789") for i in target_])
    feed = np.array([base_feed[k] for k in kind], float) * overrides[setup_]
    feed = np.round(feed / 5) * 5

    # timing
    c0 = np.zeros(2)  # positions relative to the C line are enough for travel times
    pos = np.column_stack([_mv(_rz(-c_rad), part.w_mm[target_] + r_mm * part.wn[target_])[:, :2] + c0,
                           part.w_mm[target_, 2]])
    start = pos - L * d
    t = np.empty(n)
    now = rng.uniform(5, 60)
    prev = None
    for k in range(n):
        if prev is not None:
            if setup_[k] != setup_[prev]:
                dc = abs(C_deg[setup_[k]] - C_deg[setup_[prev]])
                now += 2 * 40 / rapid + min(dc, 360 - dc) / omega_c + rng.uniform(3, 15)
                if rng.random() < 0.3:
                    now += rng.uniform(120, 900)  # the operator is called away
            elif part.feature[target_[k]] != part.feature[target_[prev]]:
                now += 2 * (abs(start[k, 2]) + 10) / rapid
            now += np.linalg.norm(start[k, :2] - start[prev, :2]) / rapid + 0.4
        now += settle
        if ok_[k]:  # search touch, back off, measuring touch
            now += L / v_search + back_off / rapid + back_off / (feed[k] / 60.0)
            t[k] = now
        else:  # searched twice the approach distance without a trigger
            now += 2 * L / v_search
            t[k] = now
        now += L / rapid
        prev = k
    t = np.round(t, 3)
    temps = {s: _sensor_series(rng, s, t, t[-1]) for s in sensors}
    if setup_style == "S":
        ids = tuple(f"S{j + 1}" for j in range(n_set))
    elif setup_style == "C":
        ids, seen = [], {}
        for c in C_deg:
            key = f"C{c:g}"
            seen[key] = seen.get(key, 0) + 1
            ids.append(key + ("" if seen[key] == 1 else f"#{seen[key]}"))
        ids = tuple(ids)
    else:
        ids = tuple("ABCDEFGH"[j] for j in range(n_set))
    return Plan(setup_ids=ids, C_deg=np.asarray(C_deg, float), setup=setup_, target=target_, t_s=t, d=d,
                feed_mm_min=feed, ok=ok_, temps=temps, r_mm=r_mm, L_mm=L, drift_check=np.array(dc_))


@dataclass(frozen=True)
class Campaign:
    """Everything fixed before the effect: part, plan, machine, mount, nominal geometry.

    Attributes
    ----------
    part : Part
    plan : Plan
    machine : Machine
    mount : (3,) float
        Part pose on the table: x, y shift (mm) and rotation (rad).
    Xn : (n, 3) float
        Nominal tip centre at contact, machine frame, mm.
    nR : (n, 3) float
        Nominal normal, machine frame.
    """

    part: Part
    plan: Plan
    machine: Machine
    mount: np.ndarray
    Xn: np.ndarray
    nR: np.ndarray

    @property
    def n(self) -> int:
        return self.plan.n

    # covariates the effects use
    @property
    def t(self) -> np.ndarray:
        return self.plan.t_s

    @property
    def t_in_setup(self) -> np.ndarray:
        s = self.plan.setup
        t0 = np.array([self.t[s == j].min() for j in range(len(self.plan.C_deg))])
        return self.t - t0[s]

    @property
    def azimuth(self) -> np.ndarray:
        d = self.plan.d
        return np.arctan2(d[:, 1], d[:, 0])

    @property
    def elevation(self) -> np.ndarray:
        return np.arcsin(np.clip(self.plan.d[:, 2], -1, 1))


def _nominal(part: Part, plan: Plan, centre: tuple, z_top: float):
    c_rad = plan.C_deg[plan.setup] * DEG
    Rz = _rz(-c_rad)
    w = part.w_mm[plan.target] + plan.r_mm * part.wn[plan.target]
    Xn = _mv(Rz, w) + np.array([centre[0], centre[1], z_top])
    nR = _mv(Rz, part.wn[plan.target])
    return Xn, nR


# ---------------------------------------------------------------------------
# touches: the exact contact solve
# ---------------------------------------------------------------------------
@dataclass
class Mods:
    """What an effect changes in the physics, per row (None: nothing).

    Attributes
    ----------
    dG_mm : (n,) float
        Extra material at the touched point (a chip, the part changing), mm.
    delta_mm : (n,) float
        Extra pre-travel along the approach (the trigger comes later), mm.
    tool : callable
        ``tool(q) -> (n, 3)``: added tip displacement (mm) for reported
        readings ``q`` (n, 3) mm, e.g. a thermal or periodic axis error.
    table_rot_rad : (n,) float
        Added rotation of the table about the C line, rad.
    part_pose : (n, 3) float
        Added part pose on the table: x, y (mm), rotation (rad).
    """

    dG_mm: np.ndarray | None = None
    delta_mm: np.ndarray | None = None
    tool: Callable | None = None
    table_rot_rad: np.ndarray | None = None
    part_pose: np.ndarray | None = None


def _part_pose(camp: Campaign, mods: Mods):
    """(A, b): part frame P in R per row, with the effect's table/part changes."""
    pl = camp.plan
    n = pl.n
    extra = mods.table_rot_rad if mods.table_rot_rad is not None else 0.0
    A_T, b_T = camp.machine.table(pl.C_deg[pl.setup] * DEG, extra)
    pose = np.broadcast_to(camp.mount, (n, 3)).copy()
    if mods.part_pose is not None:
        pose = pose + mods.part_pose
    Rm = _rz(pose[:, 2])
    m = np.column_stack([pose[:, :2], np.zeros(n)])
    return A_T @ Rm, b_T + _mv(A_T, m)


def simulate(camp: Campaign, mods: Mods | None = None, noise_dq_mm: np.ndarray | None = None) -> np.ndarray:
    """Reported axis readings at the trigger of every row.

    Parameters
    ----------
    camp : Campaign
    mods : Mods, optional
        The effect's changes (none by default).
    noise_dq_mm : (n,) float, optional
        Probing noise as a normal deviation, mm (zero by default).

    Returns
    -------
    (n, 3) float
        Reported X, Y, Z at the trigger, mm (rows that did not trigger too:
        the writer leaves them empty).
    """
    mods = mods or Mods()
    pl, part, mach = camp.plan, camp.part, camp.machine
    n = pl.n
    ti = pl.target
    d = pl.d
    q0 = camp.Xn - pl.L_mm * d
    A, b = _part_pose(camp, mods)
    G = part.form_um[ti] * UM_MM
    if mods.dG_mm is not None:
        G = G + mods.dG_mm
    d_P = _mtv(A, d)
    t = np.full(n, pl.L_mm)
    for _ in range(30):
        q = q0 + t[:, None] * d
        a = mach.tip_R(q)
        if mods.tool is not None:
            a = a + mods.tool(q)
        phi, grad = _phi(part, ti, _mtv(A, a - b), G)
        g = phi - pl.r_mm
        step = g / np.einsum("ij,ij->i", grad, d_P)
        t = t - step
        if np.max(np.abs(step)) < SOLVE_TOL_MM:
            break
    else:  # pragma: no cover - converges in 3-5 steps for errors of um
        raise RuntimeError("contact solve did not converge")
    delta = np.full(n, mach.probe_offset_um * UM_MM)
    if mods.delta_mm is not None:
        delta = delta + mods.delta_mm
    t = t + delta
    if noise_dq_mm is not None:
        t = t + noise_dq_mm / np.einsum("ij,ij->i", camp.nR, d)
    return q0 + t[:, None] * d


def dq_mm(camp: Campaign, q: np.ndarray) -> np.ndarray:
    """Normal deviation ``n . (q - Xn)`` of each row (spec eq.), mm."""
    return np.einsum("ij,ij->i", camp.nR, q - camp.Xn)


def workpiece_deviation_um(part: Part, pose: np.ndarray, dG_um: np.ndarray | None = None) -> np.ndarray:
    """True normal deviation of the part at each target in the table frame.

    The part's surface, moved by its form deviations and mounted with
    ``pose`` (x, y mm, rotation rad) on the table, is cut by each target's
    nominal normal line ``w + s wn`` (in the table frame); ``s`` is the
    paper's G_normal (positive: material farther out along ``wn``).

    Returns
    -------
    (N,) float, um
    """
    N = part.n
    ti = np.arange(N)
    G = (part.form_um + (0 if dG_um is None else dG_um)) * UM_MM
    R = _rz(np.full(N, pose[2]))
    m = np.array([pose[0], pose[1], 0.0])
    s = np.zeros(N)
    wn_P = _mtv(R, part.wn)
    for _ in range(30):
        p_T = part.w_mm + s[:, None] * part.wn
        phi, grad = _phi(part, ti, _mtv(R, p_T - m), G)
        step = phi / np.einsum("ij,ij->i", grad, wn_P)
        s = s - step
        if np.max(np.abs(step)) < SOLVE_TOL_MM:
            break
    return s / UM_MM


# ---------------------------------------------------------------------------
# what the paper's model can absorb (eq. 15 columns, own implementation)
# ---------------------------------------------------------------------------
def _hats(v: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """(n, k) piecewise-linear interpolation weights of ``v`` on ``nodes``."""
    k = np.clip(np.searchsorted(nodes, v, side="right") - 1, 0, len(nodes) - 2)
    f = (v - nodes[k]) / (nodes[k + 1] - nodes[k])
    H = np.zeros((len(v), len(nodes)))
    H[np.arange(len(v)), k] = 1 - f
    H[np.arange(len(v)), k + 1] = f
    return H


def baseline_columns(camp: Campaign, intervals: int = GRID_INTERVALS) -> np.ndarray:
    """The paper's eq. 15 design on the valid rows (own implementation).

    Columns: EXX, EYX on x nodes; EXY, EYY and the yaw (ECY on y nodes, or
    ECX on x nodes when Y rides on X) ; EC0Y; EXC,total, EYC,total, ECC per
    set-up; G per target. Nodes: ``intervals`` equal intervals over the
    touched range of each axis. Positions are the nominal tip centres
    relative to the nominal C line (eqs 1, 10-13).

    Returns
    -------
    (n_ok, p) float
    """
    pl = camp.plan
    ok = pl.ok
    p = camp.Xn[ok, :2] - np.array(camp.machine.centre_mm)
    nx, ny = camp.nR[ok, 0], camp.nR[ok, 1]
    gx = np.linspace(p[:, 0].min(), p[:, 0].max(), intervals + 1)
    gy = np.linspace(p[:, 1].min(), p[:, 1].max(), intervals + 1)
    Hx, Hy = _hats(p[:, 0], gx), _hats(p[:, 1], gy)
    cols = [-nx[:, None] * Hx, -ny[:, None] * Hx, -nx[:, None] * Hy, -ny[:, None] * Hy]
    if camp.machine.stacking == "YX":
        cols.append(-(ny * p[:, 0])[:, None] * Hy)
    else:
        cols.append((nx * p[:, 1])[:, None] * Hx)
    cols.append((nx * p[:, 1])[:, None])
    S = np.eye(len(pl.C_deg))[pl.setup[ok]]
    cols += [nx[:, None] * S, ny[:, None] * S, (-p[:, 1] * nx + p[:, 0] * ny)[:, None] * S]
    cols.append(np.eye(camp.part.n)[pl.target[ok]])
    A = np.hstack(cols)
    return A[:, np.linalg.norm(A, axis=0) > 0]


def _basis(camp: Campaign) -> np.ndarray:
    """Orthonormal basis of the columns' span (rank-revealing QR)."""
    A = baseline_columns(camp)
    A = A / np.linalg.norm(A, axis=0)
    Qf, R, _ = sla.qr(A, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    return Qf[:, d > 1e-9 * d[0]]


def baseline_residual(camp: Campaign, v: np.ndarray, Q: np.ndarray | None = None) -> np.ndarray:
    """What the paper's model cannot absorb of a per-row quantity.

    Parameters
    ----------
    camp : Campaign
    v : (n,) float
        A per-row contribution to dq (any unit); rows that did not trigger
        are ignored.

    Returns
    -------
    (n,) float
        Least-squares residual of ``v`` against :func:`baseline_columns`
        (NaN on rows that did not trigger).
    """
    Q = _basis(camp) if Q is None else Q
    ok = camp.plan.ok
    r = np.full(len(v), np.nan)
    vo = v[ok]
    r[ok] = vo - Q @ (Q.T @ vo)
    return r


def workpiece_null_dimension(camp: Campaign, tol: float = 1e-9) -> int:
    """Dimension of the workpiece part of the null space of :func:`baseline_columns`.

    4 for an identifiable design (the gauge: the workpiece shifted in X and
    Y, turned, and scaled with the machine); more when some form of the part
    is indistinguishable from a machine error.
    """
    A = baseline_columns(camp)
    A = A / np.linalg.norm(A, axis=0)
    _, s, Vt = np.linalg.svd(A, full_matrices=True)
    rank = int(np.sum(s > tol * s[0]))
    N = Vt[rank:].T
    G = N[-camp.part.n:]
    if G.size == 0:
        return 0
    sg = np.linalg.svd(G, compute_uv=False)
    return int(np.sum(sg > 1e-6))


# ---------------------------------------------------------------------------
# effects: each returns (params, covariates, local, build) from its own stream
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class _Draw:
    params: dict
    covariates: tuple
    build: Callable  # amp -> Mods
    local: bool = False
    scaled: bool = True
    report: Callable | None = None  # amp -> physical parameters (units in the keys)
    amp_max: float = np.inf  # physically plausible limit of the amplitude
    acceptable: tuple | None = None

    def physical(self, amp: float) -> dict:
        return {"amplitude_um": float(amp)} if self.report is None else self.report(amp)


def _warm(t: np.ndarray, tau: float) -> np.ndarray:
    return 1.0 - np.exp(-t / tau)


def _fx_none(rng, camp):
    """No effect: the rigid machine, the static part and the probing noise only."""
    return _Draw({}, (), lambda a: Mods(), scaled=False)


def _fx_outlier(rng, camp):
    """Chips and dust: 1-4 touches land on a particle on the surface.

    The stylus meets the particle (height h) before the surface, so the
    trigger comes early and the touch reads h of extra material (dq > 0).
    Heights 8-30 noise sigmas each (gross, as a chip is); the rows are
    random valid touches. Covariates: none (isolated rows).
    """
    ok = np.flatnonzero(camp.plan.ok)
    k = int(rng.integers(1, 5))
    rows = np.sort(rng.choice(ok[2:], size=k, replace=False))
    frac = rng.uniform(8, 30, k)  # in noise sigmas, scaled by the caller
    def build(amp):
        dG = np.zeros(camp.n)
        dG[rows] = frac * amp * UM_MM
        return Mods(dG_mm=dG)
    return _Draw({"rows": tuple(int(r) for r in rows), "heights_sigma": tuple(float(f) for f in frac)},
                 (), build, local=True, scaled=False)


def _fx_thermal_drift(rng, camp):
    """Machine warm-up: X and Y scale and offset drift with time.

    The machine structure warms up after the start (spindle and drives),
    with time constants tau1, tau2 of 3-15 min: the X and Y errors become
    ``E_X = w1(t) S_x (x - x0) + w2(t) O_x`` (and the same in Y), with
    ``w(t) = 1 - exp(-t / tau)``, ``x0`` the scale's fixed point, ``S`` in
    um/m and ``O`` in um. A slow squareness drift ``w1(t) K y`` goes with it.
    Covariate: time (and x, y).
    """
    mach = camp.machine
    tau1, tau2 = rng.uniform(200, 900, 2)
    Sx, Sy = rng.choice([-1, 1], 2) * rng.uniform(0.4, 1.0, 2) * 10.0  # um/m at amp 1
    Ox, Oy = rng.choice([-1, 1], 2) * rng.uniform(0.5, 1.5, 2)
    K = rng.normal(0, 2.0)  # urad
    t = camp.t
    x0, y0 = mach.scale_zero_mm[0], mach.scale_zero_mm[1]
    def build(amp):
        w1, w2 = _warm(t, tau1), _warm(t, tau2)
        def tool(q):
            ex = w1 * (Sx * 1e-6 * (q[:, 0] - x0) - K * URAD * (q[:, 1] - y0)) + w2 * Ox * UM_MM
            ey = w1 * Sy * 1e-6 * (q[:, 1] - y0) + w2 * Oy * UM_MM
            return amp * np.column_stack([ex, ey, np.zeros(len(q))])
        return Mods(tool=tool)
    return _Draw({"tau1_s": tau1, "tau2_s": tau2, "Sx_um_per_m": Sx, "Sy_um_per_m": Sy,
                  "Ox_um": Ox, "Oy_um": Oy, "K_urad": K}, ("time",), build,
                 report=lambda a: {"Sx_um_per_m": a * Sx, "Sy_um_per_m": a * Sy, "Ox_um": a * Ox,
                                   "Oy_um": a * Oy, "K_urad": a * K}, amp_max=10.0)


def _axis_spacing(camp: Campaign, ax: int) -> float:
    """Typical spacing (mm) of the touched positions along axis ``ax`` among
    the touches sensitive to it (|n_ax| >= 0.5): the 75th percentile gap."""
    ok = camp.plan.ok & (np.abs(camp.nR[:, ax]) >= 0.5)
    v = np.unique(np.round(camp.Xn[ok, ax], 3))
    if len(v) < 3:
        return 10.0
    return float(np.percentile(np.diff(v), 75))


def _fx_periodic_axis_error(rng, camp):
    """Screw-pitch error: a positioning error of X or Y periodic in its position.

    ``E_ax(q) = a sin(2 pi q_ax / P + phase)`` on the axis' own reading
    (machine frame), period P 4-20 mm and at least 2.5 times the typical
    spacing of the touched positions along that axis (so the data can
    resolve it). Covariate: x or y.
    """
    ax = int(rng.integers(0, 2))
    sp = _axis_spacing(camp, ax)
    P = rng.uniform(max(4.0, 2.5 * sp), 20.0) if 2.5 * sp < 20 else 20.0
    ph = rng.uniform(0, 2 * np.pi)
    def build(amp):
        def tool(q):
            e = np.zeros_like(q)
            e[:, ax] = amp * UM_MM * np.sin(2 * np.pi * q[:, ax] / P + ph)
            return e
        return Mods(tool=tool)
    return _Draw({"axis": "XY"[ax], "period_mm": P, "phase_rad": ph, "axis_spacing_mm": sp},
                 ("xy"[ax],), build, amp_max=4.0)


def _fx_probe_lobing(rng, camp):
    """Probe lobing: pre-travel varies with the approach azimuth in the machine frame.

    A kinematic probe with k = 2-4 seats (oriented spindle) needs more
    deflection to trigger in some directions: ``delta = a cos(k (phi_d -
    phi0))`` with ``phi_d`` the azimuth of the approach direction in the
    machine frame (mean removed by the stylus calibration). Covariate:
    approach_azimuth.
    """
    k = int(rng.integers(2, 5))
    ph0 = rng.uniform(0, 2 * np.pi / k)
    az = camp.azimuth
    def build(amp):
        return Mods(delta_mm=amp * UM_MM * np.cos(k * (az - ph0)))
    return _Draw({"lobes": k, "phase_rad": ph0}, ("approach_azimuth",), build, amp_max=6.0)


def _fx_reversal(rng, camp):
    """Lost motion (backlash): the axis lags by b/2 against its direction of motion.

    The X (or Y) carriage, driven through a screw read by a rotary encoder,
    trails the reading by b/2 in the direction it moves: ``E_ax = -(b/2)
    sign(v_ax)``, the sign of the approach along that axis (kept from the
    previous touch when the approach is nearly across it, |d_ax| < 0.05).
    Covariate: approach_azimuth (the approach sign along the axis).
    """
    ax = int(rng.integers(0, 2))
    d = camp.plan.d[:, ax]
    sgn = np.empty(camp.n)
    state = 1.0
    for i in range(camp.n):
        if abs(d[i]) >= 0.05:
            state = np.sign(d[i])
        sgn[i] = state
    def build(amp):
        def tool(q):
            e = np.zeros_like(q)
            e[:, ax] = -0.5 * amp * UM_MM * sgn
            return e
        return Mods(tool=tool)
    return _Draw({"axis": "XY"[ax]}, ("approach_azimuth",), build,
                 report=lambda a: {"lost_motion_um": float(a)}, amp_max=30.0)


def _fx_nonrigid(rng, camp):
    """A non-rigid machine: the error of one axis depends on the other's position.

    The carried axis' error along its own direction changes with the
    carrier's position beyond the rigid yaw coupling (the carriage's screw
    support and guide preload deflect differently along the carrier's
    stroke): ``E_X += a s(x) s(y)`` when X rides on Y, ``E_Y += a s(x) s(y)``
    when Y rides on X, with ``s`` sines of half-wavelength 100-250 mm over the
    machine's own coordinates. The rigid model (eqs 4-5) has no such term
    (its only x-y coupling is the yaw, ``x ECY(y)`` in E_Y, or ``-y ECX(x)``
    in E_X). Covariates: x and y.
    """
    which = 0 if camp.machine.stacking == "YX" else 1
    Lx, Ly = rng.uniform(100, 250, 2)
    px, py = rng.uniform(0, 2 * np.pi, 2)
    def build(amp):
        def tool(q):
            f = np.sin(np.pi * q[:, 0] / Lx + px) * np.sin(np.pi * q[:, 1] / Ly + py)
            e = np.zeros_like(q)
            e[:, which] = amp * UM_MM * f
            return e
        return Mods(tool=tool)
    return _Draw({"error_direction": "XY"[which], "half_wave_x_mm": Lx, "half_wave_y_mm": Ly},
                 ("x", "y"), build, amp_max=15.0)


def _fx_c_drift(rng, camp):
    """C-axis creep: the table keeps turning slowly after each indexing.

    The clamp of the rotary table does not hold fully against the worm's
    preload: after an indexing the table angle creeps at an initial rate
    ``r_j`` that slows with a time constant tau (5-20 min), ``ECC_j(t) =
    r_j tau (1 - exp(-t_j / tau))`` with ``t_j`` the time since the
    set-up's first touch; ``r_j`` is 0.5-1 of the amplitude (urad/min), of
    either sign, per set-up. Each set-up's mean angle is what the paper's
    ECC(C_j) absorbs; the creep is not. Covariate: time_in_setup.
    """
    n_set = len(camp.plan.C_deg)
    tau = rng.uniform(300, 1200)
    rj = rng.choice([-1, 1], n_set) * rng.uniform(0.5, 1.0, n_set)
    ts = camp.t_in_setup
    s = camp.plan.setup
    def build(amp):  # amp: creep rate, urad/min
        return Mods(table_rot_rad=amp * URAD * rj[s] * (tau / 60.0) * _warm(ts, tau))
    span = np.array([ts[s == j].max() for j in range(n_set)])
    return _Draw({"tau_s": tau, "rate_rel": tuple(float(a) for a in rj)}, ("time_in_setup",), build,
                 report=lambda a: {"rate_urad_per_min": tuple(float(a * v) for v in rj),
                                   "creep_in_setup_urad": tuple(float(a * v * tau / 60 * _warm(sp, tau))
                                                                for v, sp in zip(rj, span))},
                 amp_max=30.0)


def _fx_temperature_expansion(rng, camp, sensor=None):
    """Scale expansion driven by a temperature sensor (not by time).

    The X and Y scales (and the part's mounting) follow the temperature of
    the coolant loop: ``E_X = alpha_x (T - T_ref)(x - x0)`` and ``E_Y =
    alpha_y (T - T_ref)(y - y0)``, alpha in um/m/K, ``T_ref`` the mean
    reading, ``x0, y0`` the scales' fixed points. The chiller's hysteresis
    cycle (6-15 min) decorrelates the reading from time. Covariate:
    temp_<name>.
    """
    mach = camp.machine
    T = camp.plan.temps[sensor]
    Tref = float(np.mean(T))
    ax_, ay_ = rng.uniform(0.5, 1.0, 2) * rng.choice([-1, 1], 2)
    x0, y0 = mach.scale_zero_mm[0], mach.scale_zero_mm[1]
    def build(amp):
        def tool(q):
            dT = T - Tref
            return amp * 1e-6 * np.column_stack([ax_ * dT * (q[:, 0] - x0), ay_ * dT * (q[:, 1] - y0),
                                                 np.zeros(len(q))])
        return Mods(tool=tool)
    return _Draw({"sensor": f"temp_{sensor}_C", "T_ref_C": Tref, "alpha_x_rel": ax_, "alpha_y_rel": ay_},
                 (f"temp_{sensor}",), build,
                 report=lambda a: {"alpha_x_um_per_m_per_K": a * ax_, "alpha_y_um_per_m_per_K": a * ay_},
                 amp_max=25.0)


def _fx_stylus_bending(rng, camp):
    """Stylus bending: pre-travel depends on the approach elevation.

    A long stylus bends under the trigger force; how far depends on the
    angle e between the approach and the horizontal (the force's lever on
    the stylus): ``delta = a (c1 sin e + c2 (1 - cos e))`` with c1 (pushing
    up stiffens, down bends) and c2 drawn. Horizontal approaches are the
    calibration's, so delta(0) = 0. Covariate: approach_elevation.
    """
    c1 = rng.uniform(-1, 1)
    c2 = rng.choice([-1, 1]) * rng.uniform(1, 4)
    e = camp.elevation
    def build(amp):
        return Mods(delta_mm=amp * UM_MM * (c1 * np.sin(e) + c2 * (1 - np.cos(e))))
    return _Draw({"c1": c1, "c2": c2}, ("approach_elevation",), build, amp_max=10.0)


def _fx_lobing_per_setup(rng, camp):
    """Lobing of an unoriented spindle: the lobes turn from set-up to set-up.

    As probe_lobing, ``delta = a cos(k (phi_d - phi0_j))``, but the spindle
    is not oriented, so its angle (phi0_j) is new after each C indexing
    (the spindle was run in between). The phases are spread over at least a
    quarter of the lobe period. Covariates: approach_azimuth and setup.
    """
    k = int(rng.integers(2, 5))
    n_set = len(camp.plan.C_deg)
    per = 2 * np.pi / k
    for _ in range(100):
        ph = rng.uniform(0, per, n_set)
        dd = np.abs((ph[:, None] - ph[None, :] + per / 2) % per - per / 2)
        if dd.max() >= per / 4:
            break
    az = camp.azimuth
    s = camp.plan.setup
    def build(amp):
        return Mods(delta_mm=amp * UM_MM * np.cos(k * (az - ph[s])))
    return _Draw({"lobes": k, "phase_rad": tuple(float(p) for p in ph)},
                 ("approach_azimuth", "setup"), build, amp_max=6.0)


def _fx_local_scale_defect(rng, camp):
    """A local scale defect: an axis error confined to a few mm of travel.

    A damaged graduation (or a dent in the guideway) adds ``E_ax = a b((q_ax
    - q_c) / w)`` with ``b(u) = (1 + cos(pi u)) / 2`` for |u| < 1 (else 0),
    half-width w 2.5-6 mm, centred where touches sensitive to that axis are
    dense: finer than any error-map grid. Covariate: x or y.
    """
    ax = int(rng.integers(0, 2))
    sens = np.flatnonzero(camp.plan.ok & (np.abs(camp.nR[:, ax]) > 0.7))
    w = rng.uniform(2.5, 6.0)
    pos = camp.Xn[sens, ax]
    counts = np.array([np.sum(np.abs(pos - p) < w) for p in pos])
    cand = sens[counts >= max(3, np.percentile(counts, 75))]
    qc = float(camp.Xn[rng.choice(cand), ax] + rng.uniform(-0.3, 0.3) * w)
    def build(amp):
        def tool(q):
            u = (q[:, ax] - qc) / w
            e = np.zeros_like(q)
            e[:, ax] = amp * UM_MM * np.where(np.abs(u) < 1, (1 + np.cos(np.pi * u)) / 2, 0.0)
            return e
        return Mods(tool=tool)
    return _Draw({"axis": "XY"[ax], "centre_mm": qc, "half_width_mm": w}, ("xy"[ax],), build, local=True,
                 amp_max=10.0)


def _part_change_shape(rng, camp):
    part = camp.part
    feats = [f for f in dict.fromkeys(part.feature)
             if not f.startswith("slot") and sum(1 for g in part.feature if g == f) >= 3]
    f = str(rng.choice(feats))
    idx = np.array([i for i, g in enumerate(part.feature) if g == f])
    shape = np.zeros(part.n)
    if part.shape[idx[0]] == PLANE:  # the wall bows into the pocket, most in its middle
        t = np.array([part.wn[idx[0], 1], -part.wn[idx[0], 0]])
        s = part.w_mm[idx, :2] @ t
        half = max(np.ptp(s) / 2 * 1.15, 1.0)
        shape[idx] = 1 - ((s - s.mean()) / half) ** 2
        if np.ptp(shape[idx]) < 1e-9:
            shape[idx] = 1.0
    else:  # the ring ovalises
        c = part.centre_mm[idx[0]]
        ang = np.arctan2(part.w_mm[idx, 1] - c[1], part.w_mm[idx, 0] - c[0])
        shape[idx] = np.cos(2 * (ang - rng.uniform(0, np.pi)))
    return f, shape


def _fx_part_change(rng, camp):
    """The part relaxes: one feature's form drifts over the campaign.

    Clamping or machining stress relaxes in one feature: a wall bows into
    the pocket (most in its middle) or a boss/bore ovalises, ``dG_i(t) = a
    s_i (1 - exp(-t / tau)) / (1 - exp(-T / tau))`` (T the campaign's
    length, tau 10-60 min). A workpiece effect: the machine is unchanged.
    Covariates: time and feature.
    """
    f, shape = _part_change_shape(rng, camp)
    tau = rng.uniform(600, 3600)
    T = float(camp.t.max())
    rho = _warm(camp.t, tau) / _warm(np.array(T), tau)
    ti = camp.plan.target
    def build(amp):
        return Mods(dG_mm=amp * UM_MM * shape[ti] * rho)
    return _Draw({"feature": f, "tau_s": tau, "shape": shape}, ("time", "feature"), build, local=True,
                 amp_max=10.0)


def _fx_probe_heating(rng, camp):
    """The probe warms with use: pre-travel grows with the number of touches.

    Each trigger dissipates heat in the probe (its signal electronics and
    the stylus joint); the heat decays with a time constant of 10-40 min, so
    ``H_k = H_{k-1} exp(-dt / tau) + 1`` over the triggered touches and
    ``delta = a H_k / max H``.
    Long pauses cool it. Not a machine error and not the part: an
    out-of-catalogue effect. Covariates: order (touch count), time.
    """
    tau = rng.uniform(600, 2400)
    t = camp.t
    H = np.zeros(camp.n)
    h, t_prev = 0.0, None
    for i in np.flatnonzero(camp.plan.ok):  # a touch that did not trigger does not count
        if t_prev is not None:
            h *= np.exp(-(t[i] - t_prev) / tau)
        h += 1.0
        H[i] = h
        t_prev = t[i]
    H /= H.max()
    def build(amp):
        return Mods(delta_mm=amp * UM_MM * H)
    return _Draw({"tau_s": tau}, ("order", "time"), build, amp_max=8.0)


def _fx_knock(rng, camp):
    """A knock: the part is bumped during one set-up and stays moved.

    A collision (or a swarf clearance by the operator) shifts the part on
    the table by ``a`` in a random direction and turns it by ``a / 60 mm``
    at a random moment inside one set-up (after at least a quarter and
    before the last eighth of its touches). Later set-ups see a displaced
    part (the paper's per-set-up C terms absorb that); inside the set-up it
    is a step in time. Covariates: time_in_setup and setup.
    """
    pl = camp.plan
    n_set = len(pl.C_deg)
    j = int(rng.integers(0, n_set))
    rows = np.flatnonzero(pl.setup == j)
    k0 = rows[int(rng.integers(len(rows) // 4, len(rows) - len(rows) // 8))]
    t0 = camp.t[k0]
    ang = rng.uniform(0, 2 * np.pi)
    rs = rng.choice([-1, 1])
    after = camp.t >= t0
    def build(amp):
        pose = np.zeros((camp.n, 3))
        pose[after] = [amp * UM_MM * np.cos(ang), amp * UM_MM * np.sin(ang), rs * amp * UM_MM / 60.0]
        return Mods(part_pose=pose)
    return _Draw({"setup": pl.setup_ids[j], "t_knock_s": float(t0), "direction_rad": ang},
                 ("time_in_setup", "setup"), build, local=True,
                 report=lambda a: {"shift_um": float(a), "rotation_urad": float(rs * a / 60.0 * 1e3)},
                 amp_max=25.0)


def _fx_feed_latency(rng, camp):
    """Trigger latency: the error grows with the approach feed.

    The controller latches the axes a fixed latency after the probe's
    signal (not compensated): the reading overshoots by ``tau_l (v -
    v_ref)`` with ``v`` the probing feed and ``v_ref`` the feed of the
    stylus calibration (the campaign's median feed). The plan changes the
    feed override between set-ups, so a target is not always probed at the
    same feed. Covariates: feed (column ``feed_mm_min``), setup, feature.
    """
    v = camp.plan.feed_mm_min / 60.0
    vref = float(np.median(v))
    dv = (v - vref) / max(np.max(np.abs(v - vref)), 1e-9)
    def build(amp):
        return Mods(delta_mm=amp * UM_MM * dv)
    dvm = float(np.max(np.abs(v - vref)))
    return _Draw({"v_ref_mm_min": vref * 60.0, "dv_max_mm_s": dvm},
                 ("setup", "feature", "feed"), build,
                 report=lambda a: {"latency_ms": float(a * UM_MM / max(dvm, 1e-9) * 1e3), "amplitude_um": float(a)},
                 amp_max=8.0)


#: Cosine below which two approach directions count as a turn of more than 90 deg (reseat_hysteresis):
#: beyond the rounding of a perpendicular pair (1e-16), far inside any real turn's (90.1 deg: -1.7e-3).
TURN_COS_TOL = 1e-9


def _fx_reseat_hysteresis(rng, camp):
    """Kinematic reseat hysteresis: the first touch after a turn of the approach.

    When the approach direction turns by more than 90 deg from the previous
    touch's (including a touch that did not trigger), the probe's kinematic
    seat settles differently and that one touch needs ``h`` more travel;
    the next touch in the same direction is normal. Depends on the previous
    touch, not on this one: an out-of-catalogue effect. Covariates: order,
    approach_azimuth.
    """
    d = camp.plan.d
    flag = np.zeros(camp.n)
    # a turn of exactly 90 deg (perpendicular walls) is not "more than 90 deg": its cosine is 0 to
    # rounding, +-6e-17 by the BLAS kernel that rotated the plan (seed 1004, row 35: 0.0 under
    # OpenBLAS's SkylakeX kernels, -5.6e-17 under Haswell's), so it is compared beyond rounding
    flag[1:] = (np.einsum("ij,ij->i", d[1:], d[:-1]) < -TURN_COS_TOL).astype(float)
    def build(amp):
        return Mods(delta_mm=amp * UM_MM * flag)
    return _Draw({"rows_affected": int(flag.sum())}, ("order", "approach_azimuth"), build, amp_max=10.0)


def _fx_vibration(rng, camp):
    """A periodic disturbance in time: a hydraulic unit or chiller cycling.

    A pump cycling near the machine rocks the table relative to the spindle
    with a period of 25-150 s: ``E = a u sin(2 pi t / P + phase)`` with ``u``
    a fixed horizontal direction. Covariate: time (periodic).
    """
    P = rng.uniform(25, 150)
    ph = rng.uniform(0, 2 * np.pi)
    psi = rng.uniform(0, 2 * np.pi)
    t = camp.t
    def build(amp):
        s = amp * UM_MM * np.sin(2 * np.pi * t / P + ph)
        def tool(q):
            return np.column_stack([s * np.cos(psi), s * np.sin(psi), np.zeros(len(q))])
        return Mods(tool=tool)
    return _Draw({"period_s": P, "direction_rad": psi}, ("time",), build, amp_max=5.0)


def _fx_thermal_bending(rng, camp):
    """Thermal bending of the X guideway: straightness growing with warm-up.

    Heat from the spindle flows into the X guideway where the machine
    works, and the guideway bows there as it warms: ``EYX(x, t) = a w(t)
    ((x - xm) / h)^2`` with ``w(t) = 1 - exp(-t / tau)`` (tau 10-40 min),
    xm within 40 mm of the middle of the touched region and h 60-120 mm (a
    sag a at h from xm): an error quadratic in x, growing in time. Physically a thermal drift of a form the catalogue's
    drift model need not have, so ``thermal_drift`` is an acceptable name too.
    Covariates: time, x.
    """
    ok = camp.plan.ok
    xm = float(np.mean(camp.Xn[ok, 0])) + rng.uniform(-40, 40)
    h = rng.uniform(60, 120)
    tau = rng.uniform(600, 2400)
    w = _warm(camp.t, tau)
    def build(amp):
        def tool(q):
            e = np.zeros_like(q)
            e[:, 1] = amp * UM_MM * w * ((q[:, 0] - xm) / h) ** 2
            return e
        return Mods(tool=tool)
    return _Draw({"tau_s": tau, "x_mid_mm": xm, "half_length_mm": h}, ("time", "x"), build,
                 acceptable=("unexplained", "thermal_drift"), amp_max=30.0)


_FX = {name: globals()[f"_fx_{name}"] for name in EFFECTS}


# ---------------------------------------------------------------------------
# the truth and the public generator
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Truth:
    """What generated a campaign: the answer a discovery engine is judged against.

    Attributes
    ----------
    effect, kind : str
        Effect name and kind (see :func:`effects`).
    acceptable_causes : tuple of str
        Cause names a correct engine may answer.
    covariates : tuple of str
        Where the effect's structure lives (the spec's diagnosis names; plus
        ``feed`` for the ``feed_mm_min`` column).
    magnitude_um : float
        RMS of the effect's noise-free contribution to dq over the affected rows.
    visible_um : float
        RMS over the affected rows of what the paper's model cannot absorb of it
        (:func:`baseline_residual`).
    visible_sigmas : float
        ``visible_um / noise_um`` (the strength drawn in [1, 6], or given).
    peak_um : float
        Largest |contribution| of the effect on one row.
    noise_um : float
        Probing noise, 1 sigma, as a normal deviation (dq).
    physical : dict
        The effect's magnitudes in physical units (units in the keys): what
        was injected.
    capped : bool
        True when the asked strength needed more than the effect's physical
        limit: the effect was injected at the limit (weaker than asked).
    params : dict
        The effect's other parameters (units in the keys).
    affected_rows, outlier_rows : tuple of int
        0-based log rows the effect acts on (all valid rows for a global
        effect; for a local one, outlier, local_scale_defect, part_change,
        knock, the valid rows where it reaches 10 % of its largest value) /
        the chip rows of ``outlier``.
    effect_dq_um : (n,) float
        The effect's noise-free contribution to dq per row (NaN: no trigger).
    targets : tuple of str
    workpiece_um : (N,) float
        True normal deviation at each target (form + mounting pose, table
        frame), um, at the start of the campaign.
    workpiece_end_um : (N,) float
        The same at the end (differs only for part_change).
    workpiece_form_um : (N,) float
        Form alone (no mounting pose).
    workpiece_identifiable : bool
        False when the C schedule and the part's symmetry leave part of the
        form indistinguishable from machine errors.
    schedule_deg : tuple of float
        C of each set-up, time order.
    setup_ids : tuple of str
    part : str
    symmetry : int
    centre_mm : tuple
        Nominal C line, machine frame.
    model_gap_um : float
        RMS of what the paper's model cannot absorb of the effect-free,
        noise-free campaign (second-order terms, depth-dependent tilts, the
        grid's interpolation error): should be far below noise_um.
    machine : Machine
    mount : tuple
        Part pose on the table (x mm, y mm, rotation rad).
    seed : int
    """

    effect: str
    kind: str
    acceptable_causes: tuple
    covariates: tuple
    magnitude_um: float
    visible_um: float
    visible_sigmas: float
    peak_um: float
    noise_um: float
    physical: dict
    capped: bool
    params: dict
    affected_rows: tuple
    outlier_rows: tuple
    effect_dq_um: np.ndarray
    targets: tuple
    workpiece_um: np.ndarray
    workpiece_end_um: np.ndarray
    workpiece_form_um: np.ndarray
    workpiece_identifiable: bool
    schedule_deg: tuple
    setup_ids: tuple
    part: str
    symmetry: int
    centre_mm: tuple
    model_gap_um: float
    machine: Machine
    mount: tuple
    seed: int

    @property
    def detectable(self) -> bool:
        """True when what the paper's model cannot absorb is at least one noise sigma."""
        return self.visible_sigmas >= 1.0

    def workpiece(self) -> dict:
        """Target id -> true normal deviation (um) at the start of the campaign."""
        return dict(zip(self.targets, (float(v) for v in self.workpiece_um)))

    def defect_centres_mm(self) -> tuple:
        """A ``local_scale_defect``'s true centre and the centre the design cannot tell from it: ``((axis,
        centre_mm), ...)``, the drawn one first; empty for another effect.

        The frame is the engine's (``core.discover``'s ``evidence.centre_frame``): the machine's axis position, the
        frame of the log's nominal contact points ``Xn_mm``, ``Yn_mm``, which is where the defect is drawn (its
        centre near a touch's ``Xn`` along the axis). A part of even symmetry measured only at C angles 180 deg
        apart (every set-up at C or C + 180, a schedule :func:`_identifiable` calls not identifiable) has a touch
        at every position's image under the half turn about the C axis (``centre_mm``), on the target the turn
        maps onto, its normal reversed: a bump of the same axis at ``2 c - q`` moves the readings as the drawn one
        does beside the targets' and set-ups' own terms (gen_a local_scale_defect 1121: the two columns' parts
        outside the baseline equal to rounding), so no discovery can tell which one the machine has; that image
        follows the drawn centre. A four-fold part turned by quarter turns leaves no single image so (1017, 1065,
        1078, 1091: none found by the engine, each reported centre within its U95 of the drawn one): none is
        listed there (session 35, cat35).
        """
        if self.effect != "local_scale_defect" or "centre_mm" not in self.params:
            return ()
        ax = "XY".index(self.params["axis"])
        q = float(self.params["centre_mm"])
        out = [(self.params["axis"], q)]
        diff = np.mod(np.asarray(self.schedule_deg, float) - self.schedule_deg[0], 360.0)
        if self.symmetry % 2 == 0 and np.all(np.abs((diff + 1e-9) % 180.0) < 1e-6):
            out.append((self.params["axis"], float(2 * np.asarray(self.centre_mm, float)[ax] - q)))
        return tuple(out)


def _acceptable(effect: str, draw: _Draw) -> tuple:
    if draw.acceptable is not None:
        return draw.acceptable
    kind = EFFECTS[effect]
    if kind == "out_of_catalogue":
        return ("unexplained",)
    return (effect,)


def _rms(v: np.ndarray) -> float:
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v ** 2))) if v.size else 0.0


_OPTIONS = {"noise_um", "sigmas", "schedule_deg", "centre_mm", "part", "symmetric", "stacking",
            "effect_on", "noisy", "machine_errors", "part_errors", "machine"}


def build_campaign(seed: int, effect: str = "none", **options) -> Campaign:
    """The campaign of :func:`generate` before its effect: part, plan, machine, nominals.

    Same seed and options as :func:`generate` give the same campaign.
    """
    bad = set(options) - _OPTIONS
    if bad:
        raise ConfigError(f"unknown option {sorted(bad)[0]!r}; known: {', '.join(sorted(_OPTIONS))}")
    ss = np.random.SeedSequence(int(seed))
    r_plan, r_mach, r_part, r_mount = (np.random.default_rng(s) for s in ss.spawn(4))
    kind = options.get("part") or str(r_plan.choice(PARTS))
    if kind not in PARTS:
        raise ConfigError(f"part must be one of {PARTS}, got {kind!r}")
    sym_opt = options.get("symmetric")
    can_sym = kind in ("hexagon", "octagon")
    sym_draw = bool(r_plan.random() < 0.2)
    symmetric = (sym_draw if sym_opt is None else bool(sym_opt)) and can_sym
    if sym_opt and not can_sym:
        raise ConfigError(f"no unidentifiable schedule for the {kind} part (use hexagon or octagon)")
    sched = options.get("schedule_deg")
    n_set = int(r_plan.integers(3, 7)) if sched is None else len(sched)
    if sched is not None and not 1 <= n_set <= 12:
        raise ConfigError(f"schedule_deg needs 1-12 angles, got {n_set}")
    r_mm = float(r_plan.choice([1.0, 1.5, 2.0, 2.5, 3.0]))
    part = _build_part(r_part, kind, symmetric, r_mm, n_set, perfect=not options.get("part_errors", True))
    if sched is None:
        C, _ = _schedule(r_plan, n_set, symmetric, kind)
    else:
        C = np.asarray(sched, float)
    # the C line somewhere in the machine (at the origin for some seeds)
    centre = options.get("centre_mm")
    if centre is None:
        centre = (0.0, 0.0) if r_plan.random() < 0.3 else (float(np.round(r_plan.uniform(-400, 500), 3)),
                                                           float(np.round(r_plan.uniform(-300, 300), 3)))
    centre = (float(centre[0]), float(centre[1]))
    z_top = float(np.round(r_plan.uniform(-450, -250), 3))
    stacking = options.get("stacking") or str(r_plan.choice(["YX", "XY"]))
    if stacking not in ("YX", "XY"):
        raise ConfigError(f"stacking must be 'YX' or 'XY', got {stacking!r}")
    sensors = [s for s in SLOW_SENSORS if r_plan.random() < 0.5]
    cyc = str(r_plan.choice(CYCLIC_SENSORS))
    if r_plan.random() < 0.5 or effect == "temperature_expansion":
        sensors.append(cyc)
    style = str(r_plan.choice(["S", "C", "L"]))
    plan = _build_plan(r_plan, part, C, r_mm, tuple(sensors), style)
    machine = options.get("machine")
    if machine is None:
        machine = (_draw_machine(r_mach, np.array(centre), z_top, stacking)
                   if options.get("machine_errors", True) else Machine.perfect(centre, z_top, stacking))
    if options.get("part_errors", True):
        mount = np.array([r_mount.normal(0, 8e-3), r_mount.normal(0, 8e-3), r_mount.normal(0, 40e-6)])
    else:
        mount = np.zeros(3)
    Xn, nR = _nominal(part, plan, machine.centre_mm, machine.z_top_mm)
    return Campaign(part=part, plan=plan, machine=machine, mount=mount, Xn=Xn, nR=nR)


def _identifiable(part: Part, C_deg: np.ndarray) -> bool:
    """False when the schedule only turns a symmetric part onto itself in a
    way the rigid model can mimic (see :func:`_schedule`)."""
    if part.symmetry == 1:
        return True
    diff = np.mod(C_deg - C_deg[0], 360.0)
    for step in (90.0, 180.0):
        if part.symmetry % int(360 / step) == 0 and np.all(np.abs((diff + 1e-9) % step) < 1e-6):
            return False
    return True


def generate(effect: str, seed: int, **options) -> tuple[ProbeLog, Truth]:
    """One full probe-log/1 campaign of generator A and its truth.

    Parameters
    ----------
    effect : str
        A name from :func:`effects`.
    seed : int
        Everything random derives from it (plan, machine, part, noise: shared
        by all effects at one seed; the effect's own draws apart).
    **options
        ``noise_um`` (0.2-0.5 drawn), ``sigmas`` (visible strength in noise
        sigmas, drawn in [1, 6]), ``schedule_deg`` (C per set-up, time
        order), ``centre_mm`` (C line, machine X, Y), ``part`` ("hexagon",
        "octagon", "star"), ``symmetric`` (symmetric part with a schedule
        that cannot identify the workpiece), ``stacking`` ("YX", "XY"),
        ``effect_on`` (False: the same campaign without the effect),
        ``noisy`` (False: no probing noise), ``machine_errors`` and
        ``part_errors`` (False: perfect machine / part), ``machine`` (a
        :class:`Machine` to use).

    Returns
    -------
    log : ProbeLog
    truth : Truth

    Raises
    ------
    ConfigError
        Unknown effect or option, or an option out of range.
    """
    if effect not in EFFECTS:
        raise ConfigError(f"unknown effect {effect!r}; known: {', '.join(EFFECTS)}")
    camp = build_campaign(seed, effect, **options)
    ss = np.random.SeedSequence(int(seed))
    r_noise = np.random.default_rng(ss.spawn(5)[4])
    r_fx = np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(effect.encode())]))
    noise = options.get("noise_um")
    noise = float(np.round(r_noise.uniform(0.2, 0.5), 3)) if noise is None else float(noise)
    if noise < 0:
        raise ConfigError(f"noise_um must be >= 0, got {noise}")
    eps = r_noise.normal(0.0, 1.0, camp.n) * noise * UM_MM
    if not options.get("noisy", True):
        eps = np.zeros(camp.n)
    sig_ref = noise if noise > 0 else 0.3
    k_sig = options.get("sigmas")
    k_sig = float(r_fx.uniform(1.0, 6.0)) if k_sig is None else float(k_sig)
    ok = camp.plan.ok

    q_off = simulate(camp)
    dq_off = dq_mm(camp, q_off)
    Q = _basis(camp)
    model_gap = _rms(baseline_residual(camp, dq_off, Q)) / UM_MM

    on = options.get("effect_on", True) and effect != "none"
    if on:
        draw, amp = _draw_effect(effect, r_fx, camp, dq_off, Q, k_sig * sig_ref, sig_ref)
    else:  # the same first draw (its parameters go in the truth), nothing injected
        draw, amp = _effect_fn(effect, camp)(r_fx, camp), 0.0
    mods = draw.build(amp) if on else Mods()
    q_eff = simulate(camp, mods)
    d_eff = np.where(ok, dq_mm(camp, q_eff) - dq_off, np.nan)
    aff = _affected(draw, np.nan_to_num(d_eff), ok) if on else np.flatnonzero(ok)
    # the noise only adds travel after the contact: dq moves by eps exactly
    q = q_eff + (eps / np.einsum("ij,ij->i", camp.nR, camp.plan.d))[:, None] * camp.plan.d
    resid = baseline_residual(camp, np.nan_to_num(d_eff), Q)
    mag = _rms(d_eff[aff]) / UM_MM if on else 0.0
    vis = _rms(resid[aff]) / UM_MM if on else 0.0

    part = camp.part
    wp = workpiece_deviation_um(part, camp.mount)
    wp_end = wp
    params = dict(draw.params)
    if effect == "part_change":
        shape = params.pop("shape")
        wp_end = workpiece_deviation_um(part, camp.mount, amp * shape if on else None)
    out_rows = tuple(params.get("rows", ())) if (effect == "outlier" and on) else ()
    if effect == "outlier":
        params["heights_um"] = tuple(float(f * amp) for f in params["heights_sigma"]) if on else ()
    log = _write(camp, q, noise, seed)
    truth = Truth(
        effect=effect, kind=EFFECTS[effect], acceptable_causes=("none",) if effect == "none" else _acceptable(effect, draw),
        covariates=draw.covariates, magnitude_um=mag, visible_um=vis,
        visible_sigmas=vis / noise if (on and noise > 0) else 0.0, peak_um=float(np.nanmax(np.abs(d_eff)) / UM_MM) if on else 0.0,
        noise_um=noise,
        physical=draw.physical(amp) if on else {}, capped=bool(on and draw.scaled and amp >= draw.amp_max),
        params=params, affected_rows=tuple(int(r) for r in aff) if on else (), outlier_rows=out_rows,
        effect_dq_um=d_eff / UM_MM, targets=part.target, workpiece_um=wp, workpiece_end_um=wp_end,
        workpiece_form_um=part.form_um.copy(),
        workpiece_identifiable=_identifiable(part, camp.plan.C_deg),
        schedule_deg=tuple(float(c) for c in camp.plan.C_deg), setup_ids=camp.plan.setup_ids,
        part=part.name, symmetry=part.symmetry, centre_mm=camp.machine.centre_mm, model_gap_um=model_gap,
        machine=camp.machine, mount=tuple(float(v) for v in camp.mount), seed=int(seed))
    return log, truth


#: Draws of an effect's shape tried before settling for its amplitude limit.
MAX_DRAWS = 3


def _draw_effect(effect, rng, camp, dq_off, Q, target_um, sig_ref):
    """Draw the effect's shape and the amplitude whose visible RMS is ``target_um``.

    The amplitude is ``target / visible(amplitude 1)`` (the effects are
    linear in it to first order). When that exceeds the effect's physical
    limit ``amp_max``, the shape is drawn again (up to :data:`MAX_DRAWS`
    times) and at last the most visible shape is kept at its limit: then the
    effect is weaker than asked, which the truth reports (``capped``,
    ``visible_sigmas``).
    """
    fx = _effect_fn(effect, camp)
    best = None
    for _ in range(MAX_DRAWS):
        draw = fx(rng, camp)
        if not draw.scaled:
            return draw, (sig_ref if effect != "none" else 0.0)
        d1 = dq_mm(camp, simulate(camp, draw.build(1.0))) - dq_off
        aff = _affected(draw, d1, camp.plan.ok)
        vis1 = _rms(baseline_residual(camp, d1, Q)[aff]) / UM_MM
        amp = target_um / vis1 if vis1 > 0 else np.inf
        if amp <= draw.amp_max:
            return draw, amp
        if best is None or amp / draw.amp_max < best[1]:
            best = (draw, amp / draw.amp_max)
    return best[0], best[0].amp_max


def _effect_fn(effect: str, camp: Campaign) -> Callable:
    """The effect's draw function (rng, campaign) -> _Draw."""
    if effect == "temperature_expansion":  # driven by the campaign's cyclic sensor
        sensor = [s for s in camp.plan.temps if s in CYCLIC_SENSORS][0]
        return lambda r, c: _fx_temperature_expansion(r, c, sensor)
    return _FX[effect]


def _affected(draw: _Draw, d: np.ndarray, ok: np.ndarray) -> np.ndarray:
    if not draw.local:
        return np.flatnonzero(ok)
    a = np.abs(np.where(ok, d, 0.0))
    return np.flatnonzero(ok & (a >= 0.1 * a.max())) if a.max() > 0 else np.flatnonzero(ok)


def _write(camp: Campaign, q: np.ndarray, noise_um: float, seed: int) -> ProbeLog:
    pl, part = camp.plan, camp.part
    ok = pl.ok
    meas = lambda v: np.where(ok, v, np.nan)  # noqa: E731
    ti = pl.target
    cols = {
        "setup": [pl.setup_ids[s] for s in pl.setup],
        "target": [part.target[i] for i in ti],
        "t_s": meas(pl.t_s),
        "X_mm": meas(q[:, 0]), "Y_mm": meas(q[:, 1]), "Z_mm": meas(q[:, 2]),
        "Xn_mm": camp.Xn[:, 0], "Yn_mm": camp.Xn[:, 1], "Zn_mm": camp.Xn[:, 2],
        "nx": camp.nR[:, 0], "ny": camp.nR[:, 1], "nz": camp.nR[:, 2],
        "feature": [part.feature[i] for i in ti],
        "C_deg": pl.C_deg[pl.setup],
        "dx": pl.d[:, 0], "dy": pl.d[:, 1], "dz": pl.d[:, 2],
        "wx_mm": part.w_mm[ti, 0], "wy_mm": part.w_mm[ti, 1], "wz_mm": part.w_mm[ti, 2],
        "wnx": part.wn[ti, 0], "wny": part.wn[ti, 1], "wnz": part.wn[ti, 2],
        "stylus_r_mm": np.full(pl.n, pl.r_mm),
        "status": ["ok" if o else "no_trigger" for o in ok],
    }
    for s, T in pl.temps.items():
        cols[f"temp_{s}_C"] = T
    cols["feed_mm_min"] = pl.feed_mm_min
    meta = {"machine": f"blind-a vertical machining centre with rotary table ({camp.machine.stacking} stacking)",
            "artefact": part.name.removesuffix("-sym"), "stylus_r_mm": f"{pl.r_mm:g}",
            "kinematic_chain": camp.machine.chain, "generator": f"scenarios.blind.gen_a seed {int(seed)}"}
    return make_log(cols, meta, source=f"<blind-a seed {int(seed)}>")
