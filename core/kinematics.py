"""core's own kinematic error model: batched homogeneous transforms in numpy.

This is the identification side's model of a machine, written independently
of the simulator's Pinocchio chain (``sim.machine``); the two must agree to
rounding (tests/sim/test_machine.py checks it). It provides

- :func:`tip_W`: the exact stylus-tip centre in the workpiece frame W for a
  batch of axis readings and error values (homogeneous-transform product);
- :func:`sensitivity`: d tip_W / d(error value), analytic small displacement;
- :func:`jacobian_axes`: d tip_W / d(axis reading) with error values held;
- :func:`mfb_deviation`: the MFB paper's first-order equations 10-12.

The chain (the definition both implementations follow)
------------------------------------------------------
Every component frame coincides with the machine frame R when all axes are
at zero and all errors are zero. Walking a branch from the bed outward
(``core.chain``), each axis contributes, relative to the component it rides
on (e the axis direction; ``exp`` the rotation-vector exponential)::

    tool branch       linear k :  [exp(rel_k) | 0] . Trans(q_k e) . E_k
                      rotary k :  Trans(c_k + d_k) . [exp(rel_k) | 0] . E_k
                                  . Rot(e, theta_k) . Trans(-c_k)
    workpiece branch  linear k :  [exp(rel_k) | 0] . E_k^-1 . Trans(-q_k e)
                      rotary k :  Trans(c_k + d_k) . [exp(rel_k) | 0] . E_k^-1
                                  . Rot(e, -theta_k) . Trans(-c_k)

with ``E_k = [exp(skew(EA, EB, EC)) | (EX, EY, EZ)]`` the motion errors of
axis k, ``q_k = reading_k + J_k`` the axis position (the controller adds
the probe offset J of eq. 8), ``c_k`` a point
on the nominal rotary axis line and ``d_k`` its position errors (``EX0C``,
``EY0C``...). The tool branch ends with ``Trans(-J)`` at the stylus-tip
centre P (eq. 8); the workpiece branch ends at W.

Where the errors are evaluated: a linear axis's motion errors are functions
of its axis (joint) position ``q_k = reading_k + J_k`` (the carriage, what
its scale reads; ISO 230-1 errors along the travel; eq. 8 writes
``E_XX(X)``... of the joint parameters, the tool offset applied after),
a rotary axis's of its angle. This module takes the error VALUES (callers
evaluate them: ``sim.machine.Machine.error_values``, the tables of
``core.volumetric``, ``sim.compensation.ErrorModel``), so each caller adds
the pose's J before evaluating: two styli at the same carriage position
see the same error values. Hence on a perfect
machine with rotary axes at zero, tip_W equals the readings, and W rotates
as ``p_R = R(-C) p_W`` about the C line (self-calibration paper eq. 1).

ISO 230-1 convention (CONTRIBUTING.md, "Error conventions"): every error
value is the displacement of the TOOL relative to the WORKPIECE. A tool-
branch axis applies ``E_k`` to its moving carriage, after the nominal
motion (in the carriage's frame). A workpiece-branch axis moves its
component by the exact inverse, ``E_k^-1`` before the nominal motion (in
the carrier's frame), so that the carrier, and with it the tool, moves
relative to the component by ``Trans(q_k e) . E_k``: the same relative
motion, in the same frame (origin ``q_k e`` from the component's), as a
tool-branch axis. A table-moving X with ``EXX = +1 um`` puts the tool
1 um further in +X relative to the part than commanded, exactly as a
tool-moving X does. A rotary axis's ``E_k`` sits in its carrier's
non-rotating frame at the axis line: ``ECC`` is actual minus commanded C
of the tool relative to the part on both branches. Location errors are the
geometry of the axis lines (a linear axis's in R, a rotary axis's relative
to its carrier, below) and enter both branches alike.

Location rotations ``rel_k``: a rotary axis's orientation errors (``EA0C``,
``EB0C``) are relative to the component carrying it. A linear axis's
(``EC0Y``, ``EB0Z``, ``EA0Z``) orient its reference line in R (ISO 230-1,
X primary, Y secondary), so the rotation a linear axis inherits from its
carrier is undone across the axis and kept along it::

    rel_k = w_k - Pperp_k(cum_p),   cum_k = cum_p + rel_k,   cum_bed = 0

(``w_k`` the axis's location-error rotation vector, ``Pperp_k`` the
projection perpendicular to e, ``cum`` summed over the branch). For the
Mikron chain ``b-X-Y-Z`` this is exactly eq. 8 (``EC0Y`` before Y carries Y,
Z and the probe); for ``b-Y-X-Z`` (NMV3000) it keeps X along the machine X
axis, so the squareness only shifts X by ``-y EC0Y`` (eq. 4).

A location error moves its line, and with it what the axis carries: a C
line at ``+EX0C`` on the workpiece branch shifts the part by ``+EX0C``, the
tip relative to the part by ``-EX0C``. A rotary axis's position errors
``d_k`` sit in its carrier's frame too (``Trans(c_k + d_k)`` after the
carrier's transform): a C carried by A has its line in R, at A = 0, at
``d_C + w_C x (P - c_C) + d_A + w_A x (P - c_A)`` less A's error motions
there (CONTRIBUTING.md, "Error conventions"; ``tests/sim/test_iso_convention.py``).

Units: SI (m, rad); arrays batched over a leading axis n.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from . import iso
from .chain import Chain, parse_chain
from .exceptions import ConfigError

_E = {"X": 0, "Y": 1, "Z": 2, "A": 0, "B": 1, "C": 2}


# --------------------------------------------------------------------------- SO(3)
def skew(w: np.ndarray) -> np.ndarray:
    """(..., 3) -> (..., 3, 3) cross-product matrix."""
    w = np.asarray(w, float)
    K = np.zeros(w.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -w[..., 2], w[..., 1]
    K[..., 1, 0], K[..., 1, 2] = w[..., 2], -w[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -w[..., 1], w[..., 0]
    return K


def _coeffs(th: np.ndarray):
    """sin(t)/t, (1-cos t)/t^2, (t-sin t)/t^3 with series near 0."""
    small = th < 1e-4
    t = np.where(small, 1.0, th)
    t2 = th * th
    st = np.sin(t)
    a = np.where(small, 1 - t2 / 6, st / t)
    b = np.where(small, 0.5 - t2 / 24, (1 - np.cos(t)) / t**2)
    c = np.where(small, 1 / 6 - t2 / 120, (t - st) / t**3)
    return a, b, c


def exp_so3(w: np.ndarray) -> np.ndarray:
    """Rotation matrix ``exp(skew(w))`` (Rodrigues), (..., 3) -> (..., 3, 3)."""
    w = np.asarray(w, float)
    a, b, _ = _coeffs(np.linalg.norm(w, axis=-1))
    K = skew(w)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def left_jacobian_so3(w: np.ndarray) -> np.ndarray:
    """J_l(w): d exp(skew(w)) = skew(J_l dw) exp(skew(w)), (..., 3) -> (..., 3, 3)."""
    w = np.asarray(w, float)
    _, b, c = _coeffs(np.linalg.norm(w, axis=-1))
    K = skew(w)
    return np.eye(3) + b[..., None, None] * K + c[..., None, None] * (K @ K)


def _exp_and_left_jacobian(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(:func:`exp_so3`, :func:`left_jacobian_so3`) of the same w, the angle's coefficients and
    ``K @ K`` computed once for both (the same numbers as the two calls)."""
    w = np.asarray(w, float)
    a, b, c = _coeffs(np.linalg.norm(w, axis=-1))
    K = skew(w)
    KK = K @ K
    a, b, c = a[..., None, None], b[..., None, None], c[..., None, None]
    tmp = np.empty_like(K)  # (each sum I + x K + y KK in that order, in place: fewer temporaries, same numbers)
    R = np.multiply(a, K)
    R += np.eye(3)
    R += np.multiply(b, KK, out=tmp)
    Jl = np.multiply(b, K)
    Jl += np.eye(3)
    Jl += np.multiply(c, KK, out=tmp)
    return R, Jl


def _hom(R=None, t=None, n=1) -> np.ndarray:
    T = np.zeros((n, 4, 4))
    T[:, 3, 3] = 1.0
    T[:, :3, :3] = np.eye(3) if R is None else R
    if t is not None:
        T[:, :3, 3] = t
    return T


# --------------------------------------------------------------------------- geometry
@dataclass(frozen=True)
class ChainGeometry:
    """The nominal geometry core needs besides the error values.

    Attributes
    ----------
    chain : Chain
    J_m : (3,) float
        Probe offsets (J_X, J_Y, J_Z) of MFB eq. 8, m: spindle gauge point
        minus stylus-tip centre, in R at nominal orientation.
    rotary_points_R_m : mapping axis -> (3,) float
        A point on each rotary axis's nominal line, in R, all axes at zero, m.
    """

    chain: Chain
    J_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotary_points_R_m: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)

    @staticmethod
    def of(chain: str | Chain, J_m=(0.0, 0.0, 0.0), rotary_points_R_m=None) -> "ChainGeometry":
        """Build from a chain string (or Chain), offsets and rotary points."""
        ch = parse_chain(chain) if isinstance(chain, str) else chain
        pts = {a: tuple(float(v) for v in (rotary_points_R_m or {}).get(a, (0.0, 0.0, 0.0)))
               for a in ch.rotary_axes}
        J = tuple(float(v) for v in J_m)
        if len(J) != 3 or not np.all(np.isfinite(J)):
            raise ConfigError(f"J_m must be 3 finite values, got {J_m!r}")
        return ChainGeometry(ch, J, pts)


def error_symbols(chain: Chain) -> tuple[str, ...]:
    """ISO symbols that act on ``chain``, in ``core.iso.SYMBOLS`` order.

    Motion errors of every axis, the squarenesses ``EC0Y``, ``EB0Z``,
    ``EA0Z`` and the location errors of every rotary axis.
    """
    out = []
    for s in iso.SYMBOLS:
        if s.axis not in chain.axes:
            continue
        if s.location and s.axis in iso.LINEAR_AXES and s.name not in iso.SQUARENESS:
            continue
        out.append(s.name)
    return tuple(out)


# --------------------------------------------------------------------------- chain build
def _col(values: Mapping, name: str, n: int) -> np.ndarray:
    v = values.get(name) if values else None
    if v is None:
        return np.zeros(n)
    v = np.asarray(v, float)
    if v.ndim == 0:
        return np.full(n, float(v))
    if v.shape != (n,):
        raise ConfigError(f"error value {name!r} has shape {v.shape}, expected () or ({n},)")
    return v


def _vec(values, names, n) -> np.ndarray:
    return np.stack([_col(values, nm, n) for nm in names], axis=-1)


def _branch(geom: ChainGeometry, side: str, lin, rot, values, n, J, derivs: bool = True):
    """Factors (n,4,4) of one branch, bed outward, and their derivative twists.

    Returns factors, dsym {symbol: [(i, xi (n,6))]}, dax {axis: [(i, xi)]};
    xi = (v, w) is the left-perturbation twist of factor i per unit change
    (empty when ``derivs`` is False: the poses only); ``J`` (n, 3): per-pose probe
    offsets, already checked (:func:`_probe_offsets`). Per axis: its
    location errors (:func:`_location_errors`), the rotation they leave relative to the
    axes below (:func:`_carried_rotation`), its motion errors (:func:`_motion_errors`),
    then the factors in chain order.
    """
    ch = geom.chain
    axes = ch.tool_axes if side == "tool" else ch.workpiece_from_bed
    s = 1.0 if side == "tool" else -1.0
    F: list[np.ndarray] = []
    dsym: dict[str, list] = {}
    dax: dict[str, list] = {}
    cum = np.zeros((n, 3))
    dcum: dict[str, np.ndarray] = {}  # d cum / d location symbol, (3,)

    def add(sym, i, xi):
        if derivs:
            dsym.setdefault(sym, []).append((i, xi))

    for a in axes:
        e = np.zeros(3)
        e[_E[a]] = 1.0
        w_loc, dw_loc, d_loc = _location_errors(a, values, n, lambda sym, xi: add(sym, len(F), xi))
        rel, drel, cum, dcum = _carried_rotation(a, e, w_loc, dw_loc, cum, dcum)
        # the tool branch moves its carriage by E; the workpiece branch its
        # component by the exact inverse E^-1 (the tool relative to the part: E)
        mot, t_E, R_E, E, Jl_E = _motion_errors(a, values, n, inverse=side != "tool", derivs=derivs)
        R_rel, Jl_rel = _exp_and_left_jacobian(rel) if derivs else (exp_so3(rel), None)
        L = _hom(R_rel, None, n)

        def add_rel(i):
            if not derivs:
                return
            for k, dv in drel.items():
                wv = Jl_rel @ np.asarray(dv)
                add(k, i, np.concatenate([np.zeros((n, 3)), wv], axis=1))

        def add_E(i):
            # left twists xi of E per unit value; for E^-1 the left twist is
            # -Ad(E^-1) xi = -(R^T (v - t x w), R^T w)
            if not derivs:
                return
            for j, m in enumerate(mot):
                if j < 3:
                    xi = np.zeros((n, 6))
                    xi[:, j] = 1.0
                else:
                    wv = Jl_E[:, :, j - 3]
                    xi = np.concatenate([-_cross_rows(wv, t_E), wv], axis=1)
                if side != "tool":
                    v, w = xi[:, :3], xi[:, 3:]
                    xi = -np.concatenate([np.einsum("nji,nj->ni", R_E, v - _cross_rows(t_E, w)),
                                          np.einsum("nji,nj->ni", R_E, w)], axis=1)
                add(m.name, i, xi)

        if a in iso.LINEAR_AXES:
            q = lin[:, ("X", "Y", "Z").index(a)] + J[:, _E[a]]
            add_rel(len(F))
            F.append(L)
            if side != "tool":  # E^-1 in the carrier's frame, before the motion
                add_E(len(F))
                F.append(E)
            dax.setdefault(a, []).append((len(F), np.broadcast_to(np.r_[s * e, 0, 0, 0], (n, 6))))
            F.append(_hom(None, (s * q)[:, None] * e, n))
            if side == "tool":  # E in the moving carriage, after the motion
                add_E(len(F))
                F.append(E)
        else:
            c = np.asarray(geom.rotary_points_R_m.get(a, (0.0, 0.0, 0.0)), float)
            th = rot[:, ch.rotary_axes.index(a)]
            F.append(_hom(None, c + d_loc, n))  # location-position twists added above
            add_rel(len(F))
            F.append(L)
            add_E(len(F))
            F.append(E)
            dax.setdefault(a, []).append((len(F), np.broadcast_to(np.r_[0, 0, 0, s * e], (n, 6))))
            F.append(_hom(exp_so3((s * th)[:, None] * e), None, n))
            F.append(_hom(None, -c, n))
    return F, dsym, dax


def _location_errors(a: str, values, n: int, add_translation):
    """(w_loc (n,3) rad, dw_loc {symbol: (3,)}, d_loc (n,3) m): the location errors of axis ``a``.

    The squarenesses of a linear axis; the position and orientation errors of
    a rotary axis (ISO 230-7). ``add_translation(symbol, xi)`` records the
    twist of each position error (a translation of the axis' first factor).
    """
    locs = [sy for sy in iso.symbols_of_axis(a, location=True)
            if a in iso.ROTARY_AXES or sy.name in iso.SQUARENESS]
    w_loc = np.zeros((n, 3))
    dw_loc: dict[str, np.ndarray] = {}
    d_loc = np.zeros((n, 3))
    for sy in locs:
        v = _col(values, sy.name, n)
        u = np.zeros(3)
        u[_E[sy.direction]] = 1.0
        if sy.angular:
            w_loc += v[:, None] * u
            dw_loc[sy.name] = u
        else:
            d_loc += v[:, None] * u
            add_translation(sy.name, np.broadcast_to(np.r_[u, 0, 0, 0], (n, 6)))  # Trans(c+d)
    return w_loc, dw_loc, d_loc


def _carried_rotation(a: str, e: np.ndarray, w_loc, dw_loc: dict, cum, dcum: dict):
    """(rel, drel, cum, dcum): the rotation of axis ``a``'s frame relative to the axes below.

    ``cum`` (n,3) is the orientation error accumulated so far and ``dcum`` its
    derivative per location symbol. A linear axis carries only the part of
    ``cum`` about its own direction ``e`` (a translation does not feel a
    rotation about itself); a rotary axis carries all of it.
    """
    if a in iso.LINEAR_AXES:
        perp = np.eye(3) - np.outer(e, e)
        rel = w_loc - cum @ perp
        drel = {k: -(perp @ v) for k, v in dcum.items()}
        for k, v in dw_loc.items():
            drel[k] = drel.get(k, 0.0) + v
        dcum = {k: np.outer(e, e) @ v for k, v in dcum.items()}
    else:
        rel = w_loc
        drel = dict(dw_loc)
        dcum = dict(dcum)
    for k, v in dw_loc.items():
        dcum[k] = dcum.get(k, 0.0) + v
    return rel, drel, cum + rel, dcum


def _motion_errors(a: str, values, n: int, inverse: bool = False, derivs: bool = True):
    """(symbols, t_E (n,3) m, R_E (n,3,3), E (n,4,4), Jl_E (n,3,3) or None): the six motion errors of axis ``a``.

    ``E = [R_E | t_E]``, or its exact inverse ``[R_E^T | -R_E^T t_E]`` when
    ``inverse`` (the workpiece branch); ``Jl_E`` only when ``derivs``.
    """
    mot = iso.symbols_of_axis(a, location=False)
    t_E = _vec(values, [m.name for m in mot[:3]], n)
    w_E = _vec(values, [m.name for m in mot[3:]], n)
    R_E, Jl_E = _exp_and_left_jacobian(w_E) if derivs else (exp_so3(w_E), None)
    if inverse:
        E = _hom(np.swapaxes(R_E, 1, 2), -np.einsum("nji,nj->ni", R_E, t_E), n)
    else:
        E = _hom(R_E, t_E, n)
    return mot, t_E, R_E, E, Jl_E


def _inputs(geom, lin_m, rot_rad):
    lin = np.atleast_2d(np.asarray(lin_m, float))
    if lin.ndim != 2 or lin.shape[1] != 3:
        raise ConfigError(f"lin_m must be (n, 3), got shape {np.shape(lin_m)}")
    n = lin.shape[0]
    nr = len(geom.chain.rotary_axes)
    if rot_rad is None:
        rot = np.zeros((n, nr))
    else:
        rot = np.asarray(rot_rad, float).reshape(n, -1) if nr else np.zeros((n, 0))
        if rot.shape != (n, nr):
            raise ConfigError(f"rot_rad must be (n, {nr}) for {geom.chain.rotary_axes}, got {np.shape(rot_rad)}")
    return lin, rot, n


class _Pose:
    """A batch of rigid transforms being composed left to right: ``T <- T . factor``.

    Rotation ``R`` as (3, 3, n) (None while it is the identity) and translation
    ``t`` as (3, n): every product is a few rows of n numbers, no 4x4 matrices,
    and identity factors (errors absent or zero) are skipped, exactly.
    """

    def __init__(self, n: int):
        self.n, self.R, self.t = n, None, np.zeros((3, n))

    def translate(self, v) -> None:
        """T <- T . Trans(v), v (n,3) or (3,)."""
        v = np.asarray(v, float)
        vt = v.T if v.ndim == 2 else v[:, None]
        if not np.any(vt):
            return
        if self.R is None:
            self.t = self.t + vt
        else:
            R = self.R
            self.t = self.t + R[:, 0] * vt[0] + R[:, 1] * vt[1] + R[:, 2] * vt[2]

    def rotate(self, R) -> None:
        """T <- T . [R | 0], R (3,3,n) or None (identity)."""
        if R is None:
            return
        A = self.R
        self.R = R if A is None else A[:, 0, None] * R[None, 0] + A[:, 1, None] * R[None, 1] + A[:, 2, None] * R[None, 2]

    def rotate_about(self, k: int, th: np.ndarray) -> None:
        """T <- T . Rot(e_k, th), th (n,) rad."""
        R = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, self.n)) if self.R is None else self.R
        c, s = np.cos(th), np.sin(th)
        i, j = (k + 1) % 3, (k + 2) % 3  # e_i -> c e_i + s e_j, e_j -> -s e_i + c e_j
        out = np.empty((3, 3, self.n))
        out[:, k] = R[:, k]
        out[:, i] = c * R[:, i] + s * R[:, j]
        out[:, j] = c * R[:, j] - s * R[:, i]
        self.R = out

    def matrix(self) -> np.ndarray:
        """(n, 4, 4)."""
        T = _hom(n=self.n)
        if self.R is not None:
            T[:, :3, :3] = np.moveaxis(self.R, 2, 0)
        T[:, :3, 3] = self.t.T
        return T


def _exp_rows(w: np.ndarray) -> np.ndarray:
    """:func:`exp_so3` of rotation vectors (n,3) as (3,3,n): ``I + a K + b (w w^T - |w|^2 I)``."""
    w = np.asarray(w, float)
    x, y, z = w[:, 0], w[:, 1], w[:, 2]
    th2 = x * x + y * y + z * z
    a, b, _ = _coeffs(np.sqrt(th2))
    d = 1.0 - b * th2
    bx, by, bz = b * x, b * y, b * z
    ax, ay, az = a * x, a * y, a * z
    return np.stack([np.stack([d + bx * x, bx * y - az, bx * z + ay]),
                     np.stack([bx * y + az, d + by * y, by * z - ax]),
                     np.stack([bx * z - ay, by * z + ax, d + bz * z])])


def _branch_pose(geom: ChainGeometry, side: str, lin, rot, values, n: int, J=None) -> _Pose:
    """The product of :func:`_branch`'s factors, composed directly (poses only, no derivatives).
    ``J`` (n, 3) already checked (:func:`_probe_offsets`), or None: ``geom.J_m`` at every pose."""
    ch = geom.chain
    if J is None:
        J = _probe_offsets(geom, None, n)
    axes = ch.tool_axes if side == "tool" else ch.workpiece_from_bed
    s = 1.0 if side == "tool" else -1.0
    P = _Pose(n)
    cum = np.zeros((n, 3))
    dcum: dict[str, np.ndarray] = {}
    for a in axes:
        e = np.zeros(3)
        e[_E[a]] = 1.0
        w_loc, dw_loc, d_loc = _location_errors(a, values, n, lambda sym, xi: None)
        rel, _, cum, dcum = _carried_rotation(a, e, w_loc, dw_loc, cum, dcum)
        L = _exp_rows(rel) if np.any(rel) else None
        mot = iso.symbols_of_axis(a, location=False)
        t_E = _vec(values, [m.name for m in mot[:3]], n)
        w_E = _vec(values, [m.name for m in mot[3:]], n)
        R_E = _exp_rows(w_E) if np.any(w_E) else None
        if side != "tool":  # the exact inverse E^-1 = [R^T | -R^T t]
            if R_E is not None:
                R_E = np.swapaxes(R_E, 0, 1)
                t_E = -(R_E[:, 0] * t_E[:, 0] + R_E[:, 1] * t_E[:, 1] + R_E[:, 2] * t_E[:, 2]).T
            else:
                t_E = -t_E

        def apply_E():
            P.translate(t_E)
            P.rotate(R_E)

        if a in iso.LINEAR_AXES:
            q = lin[:, ("X", "Y", "Z").index(a)] + J[:, _E[a]]
            P.rotate(L)
            if side != "tool":
                apply_E()
            P.translate((s * q)[:, None] * e)
            if side == "tool":
                apply_E()
        else:
            c = np.asarray(geom.rotary_points_R_m.get(a, (0.0, 0.0, 0.0)), float)
            P.translate(c + d_loc)
            P.rotate(L)
            apply_E()
            P.rotate_about(_E[a], s * rot[:, ch.rotary_axes.index(a)])
            P.translate(-c)
    return P


def T_R_W(geom: ChainGeometry, lin_m, rot_rad=None, values=None) -> np.ndarray:
    """Actual pose of W in R, (n, 4, 4), for readings (n, 3) m, rotary (n, r) rad."""
    lin, rot, n = _inputs(geom, lin_m, rot_rad)
    return _branch_pose(geom, "workpiece", lin, rot, values or {}, n).matrix()


def T_R_P(geom: ChainGeometry, lin_m, rot_rad=None, values=None) -> np.ndarray:
    """Actual pose of the stylus-tip frame P in R, (n, 4, 4)."""
    lin, rot, n = _inputs(geom, lin_m, rot_rad)
    P = _branch_pose(geom, "tool", lin, rot, values or {}, n)
    P.translate(-np.asarray(geom.J_m, float))
    return P.matrix()


def _probe_offsets(geom: ChainGeometry, J_m, n: int) -> np.ndarray:
    """The probe offsets of each pose, (n, 3) m: ``J_m``, or ``geom.J_m`` at every pose (None).

    Poses taken with different styli (their offsets J) in one batch: each
    pose's numbers are the ones a call with ``geom.J_m`` = its row gives
    (the same sums and products, a column of J where a number was).
    """
    if J_m is None:
        return np.broadcast_to(np.asarray(geom.J_m, float), (n, 3))
    J = np.asarray(J_m, float)
    if J.shape != (n, 3) or not np.all(np.isfinite(J)):
        raise ConfigError(f"J_m must be finite (n, 3) = ({n}, 3) probe offsets, got shape {J.shape}")
    return J


def tip_W(geom: ChainGeometry, lin_m, rot_rad=None, values=None, J_m=None) -> np.ndarray:
    """Actual stylus-tip centre in W, (n, 3) m (exact transform product, no derivatives).

    Parameters
    ----------
    geom : ChainGeometry
    lin_m : (n, 3) float
        Axis readings X, Y, Z (tip centre as the machine believes it, R), m.
    rot_rad : (n, r) float, optional
        Rotary positions in ``geom.chain.rotary_axes`` order, rad.
    values : mapping ISO symbol -> scalar or (n,) float, optional
        Error values (m, rad) at each pose; absent symbols are zero.
    J_m : (n, 3) float, optional
        Probe offsets of each pose (m), instead of ``geom.J_m`` for all:
        several styli in one call.
    """
    lin, rot, n = _inputs(geom, lin_m, rot_rad)
    J = _probe_offsets(geom, J_m, n)
    values = values or {}
    W = _branch_pose(geom, "workpiece", lin, rot, values, n, J)
    P = _branch_pose(geom, "tool", lin, rot, values, n, J)
    P.translate(-J)
    d = P.t - W.t
    if W.R is None:
        return d.T.copy()
    return np.einsum("jin,jn->ni", W.R, d)


def _cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (n,3) arrays (``np.cross``'s products, without its axis handling)."""
    out = np.empty_like(b)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _derivs(geom, lin_m, rot_rad, values, which, J_m=None):
    lin, rot, n = _inputs(geom, lin_m, rot_rad)
    J = _probe_offsets(geom, J_m, n)
    values = values or {}
    Fw, dsw, daw = _branch(geom, "workpiece", lin, rot, values, n, J)
    Ft, dst, dat = _branch(geom, "tool", lin, rot, values, n, J)
    Ft = Ft + [_hom(None, -J, n)]
    def prefixes(F):  # I, F0, F0 F1, ...: the last is the branch's pose (the products of _prod)
        pre = [_hom(n=n)]
        for f in F:
            pre.append(pre[-1] @ f)
        return pre

    def suffixes(F, end_point):
        suf = [None] * (len(F) + 1)
        suf[len(F)] = end_point
        for i in range(len(F) - 1, -1, -1):
            suf[i] = np.einsum("nij,nj->ni", F[i], suf[i + 1])
        return suf

    pre_w, pre_t = prefixes(Fw), prefixes(Ft)
    TW, TP = pre_w[-1], pre_t[-1]
    R_RW = TW[:, :3, :3]
    tipW = np.einsum("nji,nj->ni", R_RW, TP[:, :3, 3] - TW[:, :3, 3])
    p_end_t = np.tile([0.0, 0, 0, 1], (n, 1))
    p_end_w = np.concatenate([tipW, np.ones((n, 1))], axis=1)
    suf_t = suffixes(Ft, p_end_t)
    suf_w = suffixes(Fw, p_end_w)

    # R_RW^T times the rotation before factor i: shared by every symbol entering at factor i. Kept as (3, 3, n)
    # (row, column, pose) and each derivative as (3, n), so every product is a few contiguous rows of n numbers
    # (session 34: the einsums over (n, 3, 3) were a third of a sensitivity's time); the sums in the order numpy's
    # einsum took them on session 34's machine ("nji,njk->nik": j = 0, 1, 2; "nik,nk->ni": k = 0 + 2, then 1), where
    # the sensitivities were the einsums' bit for bit (the MFB's seven calls, 15 random chains of n = 1 to 1000);
    # another machine's einsum may order a sum of three otherwise (rounding, 1e-16 relative)
    RWt = np.ascontiguousarray(R_RW.transpose(1, 2, 0))  # [j, i] = R_RW[:, j, i]
    to_W: dict = {}
    at_end: dict = {}

    def rot_W(side, pre, i):
        M = to_W.get((side, i))
        if M is None:
            P = np.ascontiguousarray(pre[i][:, :3, :3].transpose(1, 2, 0))  # [j, k] = pre[i][:, j, k]
            M = to_W[(side, i)] = (RWt[0][:, None] * P[0][None] + RWt[1][:, None] * P[1][None]) + \
                RWt[2][:, None] * P[2][None]
        return M

    def end_of(side, suf, i):  # the branch's end point after factor i, (3, n)
        e = at_end.get((side, i))
        if e is None:
            e = at_end[(side, i)] = np.ascontiguousarray(suf[i][:, :3].T)
        return e

    def moved(M, xi, b):  # M (w x b + v) per pose, (3, n): _cross_rows, then einsum("nik,nk->ni")'s sums
        x = xi.T
        l0 = (x[4] * b[2] - x[5] * b[1]) + x[0]
        l1 = (x[5] * b[0] - x[3] * b[2]) + x[1]
        l2 = (x[3] * b[1] - x[4] * b[0]) + x[2]
        return (M[:, 0] * l0 + M[:, 2] * l2) + M[:, 1] * l1

    def d_of(entries_t, entries_w):  # (3, n)
        d = np.zeros((3, n))
        for i, xi in entries_t:
            d += moved(rot_W("t", pre_t, i), xi, end_of("t", suf_t, i))
        for i, xi in entries_w:
            d -= moved(rot_W("w", pre_w, i), xi, end_of("w", suf_w, i))
        return d

    if which == "sym":
        return d_of, dst, dsw, n
    return d_of, dat, daw, n


def sensitivity(geom: ChainGeometry, lin_m, rot_rad=None, values=None, symbols=None, J_m=None) -> np.ndarray:
    """d tip_W / d(error value), analytic small displacement, (n, 3, m).

    Exact derivative of :func:`tip_W` at the given error values (not only at
    zero): each error enters as a left twist of its factor, rotations through
    the left Jacobian of SO(3).

    Parameters
    ----------
    symbols : sequence of str, optional
        Columns, default :func:`error_symbols` of the chain. Units: m/m for
        translations, m/rad for rotations.
    J_m : (n, 3) float, optional
        Per-pose probe offsets (m), as :func:`tip_W`.
    """
    symbols = tuple(symbols) if symbols is not None else error_symbols(geom.chain)
    for s in symbols:
        iso.symbol(s)
    d_of, dt, dw, n = _derivs(geom, lin_m, rot_rad, values, "sym", J_m)
    out = np.empty((len(symbols), 3, n))
    for j, s in enumerate(symbols):
        out[j] = d_of(dt.get(s, []), dw.get(s, []))
    return np.ascontiguousarray(out.transpose(2, 1, 0))


def jacobian_axes(geom: ChainGeometry, lin_m, rot_rad=None, values=None) -> np.ndarray:
    """d tip_W / d(axis reading) with the error values held, (n, 3, 3 + r).

    Columns X, Y, Z (m/m) then the rotary axes in ``chain.rotary_axes``
    order (m/rad). The total derivative adds ``sensitivity @ d values/d pos``.
    """
    d_of, dt, dw, n = _derivs(geom, lin_m, rot_rad, values, "axis")
    cols = ("X", "Y", "Z") + geom.chain.rotary_axes
    out = np.empty((len(cols), 3, n))
    for j, a in enumerate(cols):
        out[j] = d_of(dt.get(a, []), dw.get(a, []))
    return np.ascontiguousarray(out.transpose(2, 1, 0))


# --------------------------------------------------------------------------- MFB eqs 10-12
def mfb_deviation(values: Mapping, p_w_m, R_f_R_w=None, p_f_w_m=None, J_m=(0.0, 0.0, 0.0)) -> np.ndarray:
    """First-order deviations (dX, dY, dZ) of MFB paper eqs. 10-12, (n, 3) m.

    ``delta = (X_true - X, ...)``: the change of the axis positions needed
    to bring the stylus tip to the same workpiece point, i.e. minus the tip
    positioning error, for the serial chain ``b-X-Y-Z-t`` (eq. 8).

    Parameters
    ----------
    values : mapping symbol -> scalar or (n,) float
        The 21 errors ``core.iso.TWENTY_ONE`` (m, rad) at the poses; absent
        ones are zero.
    p_w_m : (n, 3) float
        Probe centre (x, y, z) in the workpiece frame R_w, m.
    R_f_R_w : (3, 3) or (n, 3, 3) float, optional
        Workpiece orientation in the machine frame (a..i of eq. 8), default I.
    p_f_w_m : (3,) or (n, 3) float, optional
        Workpiece position in the machine frame, m, default 0.
    J_m : (3,) float
        Tool offsets J_X, J_Y, J_Z, m.
    """
    p = np.atleast_2d(np.asarray(p_w_m, float))
    n = p.shape[0]
    Rw = np.eye(3) if R_f_R_w is None else np.asarray(R_f_R_w, float)
    pf = np.zeros(3) if p_f_w_m is None else np.asarray(p_f_w_m, float)
    for k in values or {}:
        if iso.symbol(k).name not in iso.TWENTY_ONE:
            raise ConfigError(f"mfb_deviation takes the 21 linear-axis errors only, got {k!r}")
    E = {s: _col(values, s, n) for s in iso.TWENTY_ONE}
    Rw = np.broadcast_to(Rw, (n, 3, 3))
    pr = np.einsum("nij,nj->ni", Rw, p) + pf
    Fv, Gv = pr[:, 1], pr[:, 2]  # F = p_y + b x + e y + h z ; G = p_z + c x + f y + i z
    JX, JY, JZ = J_m
    dX = (-E["EXX"] - E["EXY"] - E["EXZ"]
          - (E["EB0Z"] + E["EBX"] + E["EBY"]) * Gv
          + (E["EC0Y"] + E["ECX"]) * Fv
          + E["EBZ"] * JZ
          - (E["ECY"] + E["ECZ"]) * JY)
    dY = (-E["EYX"] - E["EYY"] - E["EYZ"]
          + (E["EA0Z"] + E["EAX"] + E["EAY"]) * Gv
          - E["EAZ"] * JZ
          + (E["EC0Y"] + E["ECX"] + E["ECY"] + E["ECZ"]) * JX)
    dZ = (-E["EZX"] - E["EZY"] - E["EZZ"]
          - E["EAX"] * Fv
          + (E["EA0Z"] + E["EAY"] + E["EAZ"]) * JY
          - (E["EB0Z"] + E["EBX"] + E["EBY"] + E["EBZ"]) * JX)
    return np.stack([dX, dY, dZ], axis=1)
