"""The 21 errors of three linear axes from MFB placements (Viprey 2016, sections 5-6).

Measurement model
-----------------
A *measurement* is one probing of the bar in one *placement* (a bar pose
on the table, and the rotary positions A, C of a 5-axis machine) with one
probe (offsets J, eq. 8). It yields the points of interest O_i as the
machine reads them (``O_R``: reported stylus-tip centres, :mod:`core.mfb`)
and, from the bar's calibration, where they really are on the bar
(``O_A``, eq. 4). The actual stylus tip at the reading is the true point::

    tip_W(O_R; E) = exp(xi_p) T_W_A,p O_A                          (1)

``tip_W`` is core's exact chain (:mod:`core.kinematics`), ``E`` the error
motions evaluated at the axis positions ``O_R + J`` (the joints, eq. 8:
the errors are functions of the joint parameters, the probe offset J
applied after them), ``T_W_A,p`` the nominal placement and
``xi_p = (v, w)`` the unknown placement error (6 nuisance values per
placement, shared by the measurements of that placement). To first order
(eqs 8-12, ``S = d tip_W / d E`` at E = 0, which for the chain b-X-Y-Z-t
is eqs 10-12 with the opposite sign)::

    y = T_W_A O_A - tip_W(O_R; 0) = S(O_R) E - v + skew(P) w        (2)

Model (2) evaluates the errors at ``O_R``, a constructed point no touch
sits on. ``O_i`` takes its height along the hole axis from the plane
``PL_i`` through the rods and faces 25 mm either side and up to 30 mm
across, so an error that varies over the bar is sampled there, not at the
hole (1-2 um on the realistic machine). With the touches of a measurement
(``Measurement.q_R``, ``c_A``, ``d_A``) vmt uses instead::

    tip_W(O_R; E) = tip_W(O_R; 0) + R_WA G_A e,
    e_t = d_t . (tip_W(q_t; E) - tip_W(q_t; 0))                   (3)

each touch t's actual stylus centre differs from its reading ``q_t`` by
the chain's error, whose component ``e_t`` along the approach ``d_t``
moves the trigger point, and the extraction's gain ``G_A = d O / d e``
(:func:`core.mfb.poi_noise_gain`, the same fits) carries the shifts into
the points of interest. A rigid shift or rotation of all touches moves
``O`` rigidly, so (3) has the gauge freedoms of (2); against the simulator
with the true error functions it agrees to <= 13 nm per point (against
2.5 um for (2)). The noise-free accuracy is then the tables' interpolation
of the truth, amplified by the plan's weakest direction.

``G_A`` is the extraction's gain at the nominal touches on the nominal bar,
taken from the normal shifts alone: the extraction (cylinder and plane fits,
axes met with planes) is not linear, and the real bar's touches sit elsewhere
(its calibrated deviations, the placement errors). Where the touches carry
their features and nominal normals (``Measurement.feature``, ``n_A``) the
Gauss-Newton can predict the points by the extraction itself::

    tip_W(O_R; E) = tip_W(O_R; 0) + X(tip_W(q; E)) - X(tip_W(q; 0))   (3')

``X`` the points of interest fitted from the touches
(:func:`core.mfb.points_of_interest_batched`, the fits that gave ``O_R``),
each touch at its actual tip: exact in the errors, the Jacobian (3)'s
(:data:`EXACT_EXTRACTION`; session 32: docs/papers-mfb.md, "The noise-free
residue").

Each motion error of an axis is a look-up table on nodes along that axis,
indexed by the axis (joint) position ``reading + J`` (the points of
interest of the bars laid along it, as the reference stylus reaches them), interpolated by a C2
cubic spline (section 6) where a point falls between nodes and along its
end tangent up to :data:`NODE_MARGIN_M` beyond the end nodes (the rods and
faces probed around the end holes; farther readings are refused); the three
squarenesses ``EC0Y``, ``EB0Z``, ``EA0Z`` are constants. The rotary axes'
errors of a 5-axis machine are constant within one placement and are
absorbed by its ``xi_p``, exactly.

Gauge (ISO 230-1 zero conventions, X primary, Y secondary)
------------------------------------------------------------
The placement errors make some combinations invisible to any bar: the
offset of every positioning and straightness table, the slope of every
straightness table (traded with the squarenesses and the frame), and the
constant part of the angular errors of axes carrying the table (a rotated
table is a rotated bar). :func:`design` computes the null space of (2)
and fixes it with the ISO conventions: always positioning zero at the first
node (``EX0X = 0``...) and straightness zero at both end nodes (the
end-point reference straight line, section 6); then, greedily, angular
errors zero at the first node, each only while it removes a null direction.

With the errors as functions of the axis (joint) positions (eq. 8), a
squareness, a straightness slope and a constant angular error are one
combination to first order, exactly, for every stylus: ``EB0Z`` tilts the
Z motion and what Z carries, the tool included, so the tip moves by
``EB0Z (Z - J_z)`` along x, which is an ``EXZ`` slope ``EB0Z * Z`` plus a
constant ``EBZ = EB0Z`` acting on the lever arm ``-J``; likewise ``EA0Z``
= ``-EYZ`` slope + constant ``EAZ`` and ``EC0Y`` = ``-EXY`` slope +
constant ``ECY`` (the angular term where the axis carries the tool: on a
table-side Y the constant ``ECY`` is a rotated bar, a placement's freedom,
and ``EC0Y`` is the slope alone). tests/core/test_volumetric.py checks the
identity on core's chain and in the 3-axis plan's design, and that the
gauge fixes exactly these. No bar can tell them apart: the redundancy is
physical. ISO 230-1 resolves it by
definition: a straightness is reported against its reference straight line
and a squareness is the angle between the axes' reference lines, so the
end-point convention (both ends of ``EXY``, ``EXZ``, ``EYZ`` zero) gives
the slope to the squareness; the constant ``EAZ``, ``EBZ``, ``ECZ`` that
remain move the tip by their lever arm, the stylus offset ``J``, and are
sensed by styli of different ``J`` (the plans' star styli and
extensions). (Until session 27, with the errors evaluated at the tip
readings, the three differed by stylus-dependent terms, 25-55 % of the
squareness's column in the 3-axis plan, so the plan seemed to separate
them and the gauge fixed those three tables at their first node only: a
separation a real machine, whose errors follow its carriage, does not
give.) A null
direction left after all conventions is a combination the plan cannot see:
:func:`identify_volumetric` raises :class:`~core.exceptions.IdentifiabilityError`
naming it (via :func:`core.lsq.solve`), never a silent solution.

Solution: joint least squares of all measurements (the paper's sequential
order, angular -> translational -> squareness, solves sub-blocks of the
same equations; jointly is the least-squares optimum and needs no
propagation of one stage's error into the next, so vmt solves jointly),
then Gauss-Newton on the exact equation (1) (``exact=True``).

Report form (:func:`iso_map`, :func:`iso_view`): every straightness table
against its end-point reference straight line (section 6), its slope kept
beside it (:func:`end_point_slopes`); identified and injected alike.

Uncertainty (:func:`uncertainty`): probing noise through the
points-of-interest extraction (:func:`core.mfb.poi_noise_gain`), the bar
calibration uncertainty (common to all placements) and the placement
errors (roll included), by linear propagation (sandwich of the
least-squares estimator) and by Monte Carlo (JCGM 101) through the same
estimator. Translation, pitch and yaw of a placement are estimated
(``xi_p``) and leave no first-order trace on E; the roll leaves a small
one (the calibrated offsets of the points from the bar axis).

Units SI inside; report helpers give um / urad.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from . import iso
from .memo import Memo
from .exceptions import ConfigError, IdentifiabilityError
from .kinematics import ChainGeometry, exp_so3, sensitivity, skew, tip_W
from .lsq import RANK_TOL, describe_direction, solve

MOTION = iso.LINEAR_MOTION
SQUARENESS = iso.SQUARENESS
#: Placement error: translation (W frame) and rotation about the bar's y_A, z_A
#: axes. The roll about the bar's own axis x_A moves no point of interest
#: except the two mistake-proofing holes (1.5 mm arm): it is left out and
#: those holes' observation along the bar's z_A is dropped instead (their
#: other components, and every other hole, are unaffected to first order).
NUISANCE = ("vx", "vy", "vz", "wyA", "wzA")
#: Singular-value ratio (column-scaled design, over the largest) below which a
#: direction is an exact null direction, fixed by an ISO convention (gauge
#: freedoms are ~1e-16 at the nominal readings, :func:`_nominal_readings`).
NULL_TOL = 1e-9
#: Least component (orthonormal, column-scaled) a convention must have along
#: the null space left for it to be taken (else it is redundant: exact null
#: directions give components of 1e-15 or of order 0.1).
GAUGE_MIN = 1e-6
#: Relative singular value of the gauge-fixed, column-scaled design below
#: which a combination counts as unseen and is named (IdentifiabilityError),
#: not solved with a huge band. 1e-5 is stricter than core.lsq.solve's
#: RANK_TOL (1e-12 in eigenvalues, 1e-6 in singular values), so the plan is
#: refused here, by name, before the solver would.
COND_TOL = 1e-5
#: How far (m) beyond the end nodes an axis position (reading + J) may lie; there the table
#: continues along its end tangent (:func:`spline_weights`). The nodes sit at
#: the points of interest (where the bar senses every error, see
#: scenarios.mfb); the rod and faces that give the last hole its height lie
#: 25 mm beyond it and their far flank 34 mm: 40 mm covers them. Nodes spanning
#: those touches instead put the end nodes where only one of the three
#: directions is sensed, and the end-point conventions hang every table on
#: them (U95 up to ~47 um / ~110 urad at 0.25 um probing noise). The tangent
#: continuation costs < 0.08 um / 0.16 urad noise-free on the realistic machine.
NODE_MARGIN_M = 0.040
#: Eigenvalue ratio passed to core.lsq.solve: its default.
SOLVE_RANK_TOL = RANK_TOL

#: The Gauss-Newton's prediction of a measurement whose touches carry their features (``Measurement.feature``,
#: ``n_A``): True, the exact extraction (3') of the module doc (the touches moved to their actual tips by the
#: errors at the current estimate and the points of interest fitted again, :func:`core.mfb.points_of_interest_batched`);
#: False, model (3)'s linear gain ``G_A`` taken at the nominal touches on the nominal bar. The Jacobian is (3)'s
#: either way. The default of :func:`identify_volumetric` (``extraction=None``; :func:`reduced_design`, discovery's
#: baseline, keeps (3) unless asked).
#: Session 32 (mfbx32, docs/papers-mfb.md "The noise-free residue"): set by the study there.
EXACT_EXTRACTION = True


@dataclass(frozen=True)
class Measurement:
    """Points of interest of one measurement (one placement, one probe).

    Attributes
    ----------
    name : str
    placement : str
        Placement id: measurements of one placement share the bar pose.
    holes : tuple of int
        1-based hole labels.
    O_R : (k, 3) float
        Points of interest as read by the machine (reported tip centres, R), m.
    O_A : (k, 3) float
        Their calibrated positions in the bar frame A (eq. 4), m.
    T_W_A : (4, 4) float
        Nominal placement of the bar in W, m.
    rot_rad : (r,) float
        Rotary positions of the placement (chain's rotary order), rad.
    J_m : (3,) float
        Probe offsets of this measurement (eq. 8), m.
    G_A : (3k, t) float or None
        Noise gain of the extraction in the bar frame: d O_A / d e per touch
        displacement e along its approach (:func:`core.mfb.poi_noise_gain`).
    q_R : (t, 3) float or None
        Readings of the touches the points of interest were fitted from (the
        columns of ``G_A``, same order), m. With ``q_R``, ``c_A`` and
        ``d_A`` the machine errors enter through the touches (model (3) of
        the module doc); without them, at ``O_R`` (model (2)).
    c_A : (t, 3) float or None
        Nominal stylus-centre contact points of those touches in A, m.
    d_A : (t, 3) float or None
        Their approach directions (unit, into the surface) in A.
    feature : tuple of str or None
        Each touch's feature id (``holeNN``, ``rodNN``, ``faceLNN``, ``faceRNN``: the probe log's
        ``feature`` column), same order as ``q_R``.
    n_A : (t, 3) float or None
        Each touch's nominal outward normal in A (the probe log's normal, the extraction's hints).
        With ``feature`` and ``n_A`` the identification can fit the points of interest again from
        the touches moved by the errors (:data:`EXACT_EXTRACTION`, model (3') of the module doc).
    """

    name: str
    placement: str
    holes: tuple
    O_R: np.ndarray = field(compare=False)
    O_A: np.ndarray = field(compare=False)
    T_W_A: np.ndarray = field(compare=False)
    rot_rad: tuple = ()
    J_m: tuple = (0.0, 0.0, 0.0)
    G_A: np.ndarray | None = field(default=None, compare=False)
    q_R: np.ndarray | None = field(default=None, compare=False)
    c_A: np.ndarray | None = field(default=None, compare=False)
    d_A: np.ndarray | None = field(default=None, compare=False)
    feature: tuple | None = field(default=None, compare=False)
    n_A: np.ndarray | None = field(default=None, compare=False)


@dataclass(frozen=True)
class VolumetricDesign:
    """The linear problem (2) for a set of measurements.

    Attributes
    ----------
    A : (m, n) float
    y : (m,) float
        Left side of (2), m.
    names : tuple of str
        Parameter names: ``EXX@x=-275mm``, ``EC0Y``, ``P03.wz``...
    slices : dict
        Symbol or placement -> slice into the parameters.
    nodes : dict axis -> (n_a,) float
    C : (k, n) float
        Gauge conventions chosen (rows), ``C theta = 0``.
    gauge : tuple of str
        The conventions, in words.
    null : (n, q) float
        Null space of A (before the gauge), columns in parameter units.
    rows : list of (measurement name, hole)
        One entry per point (three rows each).
    unseen : (n, q') float
        Combinations the plan cannot see beyond the conventions: null
        directions left and directions whose relative singular value in the
        gauge-fixed, column-scaled design is below :data:`COND_TOL`.
    sv_rel : (r,) float
        Singular values of the gauge-fixed, column-scaled design over the
        largest, descending (the plan's observability).
    """

    A: np.ndarray
    y: np.ndarray
    names: tuple
    slices: dict
    nodes: dict
    C: np.ndarray
    gauge: tuple
    null: np.ndarray
    rows: list
    unseen: np.ndarray = field(default=None, repr=False, compare=False)
    sv_rel: np.ndarray = field(default=None, repr=False, compare=False)

    def to_gauge(self, theta_true: np.ndarray) -> np.ndarray:
        """Express a parameter vector (e.g. the truth) in this design's ISO gauge.

        Adds the null-space combination that makes ``C theta = 0``: what the
        plan would identify from error-free data under the first-order model.
        """
        N, C = self.null, self.C
        if C.shape[0] == 0:
            return np.asarray(theta_true, float).copy()
        alpha = np.linalg.lstsq(C @ N, -C @ theta_true, rcond=None)[0]
        return theta_true + N @ alpha


def _geom(chain: str, J_m, rotary_points_R_m) -> ChainGeometry:
    return ChainGeometry.of(chain, J_m, rotary_points_R_m or {})


def spline_weights(nodes: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(len(u), len(nodes)) weights of the C2 cubic spline through the nodes.

    Not-a-knot end conditions for 4 nodes or more, natural for 2-3 (for 2
    the line through them), as ``sim``'s ``SplineTable`` fits; constant for
    one node. Beyond the end nodes (up to :data:`NODE_MARGIN_M`, checked by
    the caller) the spline continues along its end tangent (C1), as
    ``SplineTable`` does, never as a runaway cubic. (Before review31d F11,
    2-3 nodes were interpolated linearly and held beyond the ends, unlike
    this docstring, ``SplineTable`` and the vmt-comp/1 JSON's rule.)
    """
    nodes = np.asarray(nodes, float)
    u = np.asarray(u, float)
    k = len(nodes)
    if k == 1:
        return np.ones((len(u), 1))
    cs, d0, d1 = _basis(tuple(nodes.tolist()))
    W = cs(np.clip(u, nodes[0], nodes[-1]))
    lo, hi = u < nodes[0], u > nodes[-1]
    if lo.any() or hi.any():  # beyond the end nodes: the end tangent line (C1), no runaway cubic
        W[lo] += (u[lo] - nodes[0])[:, None] * d0[None, :]
        W[hi] += (u[hi] - nodes[-1])[:, None] * d1[None, :]
    return W


@functools.lru_cache(maxsize=64)
def _basis(nodes: tuple):
    """The cardinal C2 splines of a node tuple (not-a-knot; natural below 4 nodes) and their end slopes (cached:
    pure)."""
    x = np.asarray(nodes)
    cs = CubicSpline(x, np.eye(len(x)), bc_type="not-a-knot" if len(x) >= 4 else "natural")
    d = cs.derivative()
    return cs, d(x[0]), d(x[-1])


def _layout(meas, nodes):
    names, slices, n = [], {}, 0
    for s in MOTION:
        a = iso.symbol(s).axis
        k = len(nodes[a])
        slices[s] = slice(n, n + k)
        names += [f"{s}@{a.lower()}={v * 1e3:.6g}mm" for v in nodes[a]]
        n += k
    for s in SQUARENESS:
        slices[s] = slice(n, n + 1)
        names.append(s)
        n += 1
    places = list(dict.fromkeys(m.placement for m in meas))
    for p in places:
        slices[p] = slice(n, n + 5)
        names += [f"{p}.{q}" for q in NUISANCE]
        n += 5
    return names, slices, n, places


def _check(meas, nodes):
    if not meas:
        raise ConfigError("volumetric: no measurements")
    for a in iso.LINEAR_AXES:
        v = np.asarray(nodes.get(a, ()), float)
        if v.ndim != 1 or len(v) < 1 or not np.all(np.isfinite(v)) or np.any(np.diff(v) <= 0):
            raise ConfigError(f"volumetric: nodes[{a!r}] must be a strictly increasing finite 1-D array")
    for m in meas:
        O_R, O_A = np.asarray(m.O_R), np.asarray(m.O_A)
        if O_R.ndim != 2 or O_R.shape[1] != 3 or O_A.shape != O_R.shape:
            raise ConfigError(f"measurement {m.name!r}: O_R and O_A must be (k, 3), got {O_R.shape}, {O_A.shape}")
        if not np.all(np.isfinite(O_R)) or not np.all(np.isfinite(O_A)):
            raise ConfigError(f"measurement {m.name!r}: non-finite points of interest")
        if np.shape(m.T_W_A) != (4, 4):
            raise ConfigError(f"measurement {m.name!r}: T_W_A must be 4x4")
        if (m.feature is None) != (m.n_A is None):
            raise ConfigError(f"measurement {m.name!r}: feature and n_A go together (the exact extraction needs "
                              f"both), got only {'feature' if m.n_A is None else 'n_A'}")
        if m.feature is not None:
            if not _has_touches(m):
                raise ConfigError(f"measurement {m.name!r}: feature and n_A need the touches (q_R, c_A, d_A, G_A)")
            t = len(np.asarray(m.q_R))
            nA = np.asarray(m.n_A, float)
            if len(m.feature) != t or nA.shape != (t, 3) or not np.all(np.isfinite(nA)):
                raise ConfigError(f"measurement {m.name!r}: feature (t,) and n_A (t, 3) finite, one per touch "
                                  f"(t = {t}), got {len(m.feature)} and {nA.shape}")
        # the axis positions the errors are evaluated at (reading + J) must lie within the
        # nodes (at most NODE_MARGIN_M beyond, along the end tangent)
        q = (np.asarray(m.q_R, float) if _has_touches(m) else O_R) + np.asarray(m.J_m, float)
        for j, a in enumerate(iso.LINEAR_AXES):
            v = np.asarray(nodes[a], float)
            if len(v) > 1 and (q[:, j].min() < v[0] - NODE_MARGIN_M or q[:, j].max() > v[-1] + NODE_MARGIN_M):
                raise ConfigError(f"measurement {m.name!r}: axis positions (reading + J) reach {a} = "
                                  f"{q[:, j].min() * 1e3:.1f} .. "
                                  f"{q[:, j].max() * 1e3:.1f} mm, outside the {a} nodes "
                                  f"{v[0] * 1e3:.1f} .. {v[-1] * 1e3:.1f} mm (extend the nodes)")


def _axis_weights(nodes, q) -> dict:
    """axis -> (p, k_axis) spline weights at the axis positions q (p, 3) (reading + J: the
    tables are functions of the joint positions, module doc): one evaluation per axis,
    shared by the six motion errors of that axis (and by values and Jacobian)."""
    return {a: spline_weights(nodes[a], q[:, i]) for i, a in enumerate(iso.LINEAR_AXES)}


def _values(theta, slices, W, p):
    """Error values at the p readings of the weights W (:func:`_axis_weights`): symbol -> (p,)."""
    out = {s: W[iso.symbol(s).axis] @ theta[slices[s]] for s in MOTION}
    for s in SQUARENESS:
        out[s] = np.full(p, theta[slices[s]][0])
    return out


def _error_jacobian(S, W, slices, n):
    """(p, 3, n) d tip / d theta from the per-symbol sensitivity S (p, 3, 21) and weights W."""
    J = np.zeros((len(S), 3, n))
    for k, s in enumerate(MOTION):
        J[:, :, slices[s]] = S[:, :, k][:, :, None] * W[iso.symbol(s).axis][:, None, :]
    for k, s in enumerate(SQUARENESS):
        J[:, :, slices[s].start] = S[:, :, 18 + k]
    return J


def _projected_error_jacobian(S, d, W, slices, n):
    """(p, n) d (d . tip) / d theta: S (p, 3, 21) projected on the directions d (p, 3)
    first, then spread over the node weights W (no (p, 3, n) intermediate)."""
    Sd = np.einsum("tj,tjs->ts", d, S)
    J = np.zeros((len(S), n))
    for k, s in enumerate(MOTION):
        J[:, slices[s]] = Sd[:, k, None] * W[iso.symbol(s).axis]
    for k, s in enumerate(SQUARENESS):
        J[:, slices[s].start] = Sd[:, 18 + k]
    return J


def _has_touches(m) -> bool:
    return m.q_R is not None and m.c_A is not None and m.d_A is not None and m.G_A is not None


def _has_features(m) -> bool:
    """The touches carry what the exact extraction (3') needs: each one's feature id and nominal normal."""
    return _has_touches(m) and m.feature is not None and m.n_A is not None


#: :func:`_extracted`'s answers by the bytes of their inputs (the tips, each measurement's features, normals and
#: holes): a pure function, met again with the same tips by the identification's last residual, :func:`lack_of_fit`
#: and :func:`model_error_share` at the same theta, and by each new ``prep`` of the same measurements (the
#: error-free tips); the arrays kept read-only.
_EXTRACTED = Memo(8)


def _extracted(prep, tips) -> dict:
    """{measurement: its points of interest (k, 3), W} fitted from the tip positions ``tips`` (t_all, 3) of the
    touches of every measurement that carries its features (:func:`core.mfb.points_of_interest_batched`, the
    extraction of the readings: the same fits, in one batch; W is a rigid motion of R per measurement, so the
    fits are the same; the nominal normals in W are the hints). Kept in :data:`_EXTRACTED`."""
    import hashlib

    b = prep.batch
    idx = [i for i in b["at"] if prep[i]["features"]]
    if not idx:
        return {}
    h = hashlib.blake2b(np.ascontiguousarray(tips, float).tobytes(), digest_size=20)
    for i in idx:
        pm = prep[i]
        h.update(repr((i, b["at"][i], pm["name"], pm["holes"], pm["feature"])).encode())
        h.update(np.ascontiguousarray(pm["n_W"], float).tobytes())
    return _EXTRACTED.get_or_compute(h.digest(), lambda: _extract(prep, tips, idx))


def _extract(prep, tips, idx) -> dict:
    """:func:`_extracted` computed."""
    from . import mfb

    b = prep.batch
    pois = mfb.points_of_interest_batched(
        [(tips[b["at"][i]:b["at"][i] + len(prep[i]["qt"])], prep[i]["feature"], prep[i]["n_W"]) for i in idx])
    out = {}
    for i, poi in zip(idx, pois):
        if tuple(poi.holes) != prep[i]["holes"]:
            raise ConfigError(f"measurement {prep[i]['name']!r}: its touches' features give the points of holes "
                              f"{list(poi.holes)}, its points of interest are of holes {list(prep[i]['holes'])}")
        out[i] = poi.O_R
        out[i].setflags(write=False)  # shared by every later lookup
    return out


#: The bar's z_A within this angle (rad) of a W axis: a mistake-proofing hole's row along that axis is the roll
#: component the model drops, empty by the model's structure (:func:`roll_rows`). 1e-12 as
#: :data:`core.mfblog.SNAP`: a pose's rounding (written, read, fitted or turned by a computed angle: 1e-16) is
#: within it; any real tilt (a designed one degrees, a placement error micro-radians) is far outside.
ROLL_AXIS_TOL_RAD = 1.0e-12


def mistake_proofing(O_A) -> np.ndarray:
    """(k,) bool: which of the points ``O_A`` (k, 3), bar frame, are the mistake-proofing holes (1.5 mm off the
    bar's axis along y_A; the others lie on it to the calibration's um): their roll is dropped (:data:`NUISANCE`)."""
    return np.abs(np.asarray(O_A, float)[:, 1]) > 1e-4


def roll_rows(m) -> np.ndarray:
    """(3 k,) bool over measurement ``m``'s rows (its holes in order, each hole's W components x, y, z): the rows
    the model empties, each mistake-proofing hole's component along a W axis that the bar's z_A lies along
    (within :data:`ROLL_AXIS_TOL_RAD`): the roll, dropped from the residual and the design (:func:`_rows`).

    Decided by the pose's structure, not by the rows' values (session 38): the values are exactly zero only
    when the pose's other entries are, and a pose fitted from a log (:func:`core.mfblog.bar_pose_W` before its
    snap) or turned by a computed angle leaves them 1e-16 off, which kept 34 empty rows in a baseline (423 for
    389). A bar whose z_A lies along no W axis has no such row (its holes' three rows hold two components)."""
    off = mistake_proofing(m.O_A)
    zA = np.asarray(m.T_W_A, float)[:3, 2]
    zA = zA / np.linalg.norm(zA)
    along = np.array([np.hypot(*np.delete(zA, i)) <= ROLL_AXIS_TOL_RAD for i in range(3)])
    return (off[:, None] & along[None, :]).ravel()


def _prepare(m, chain, rotary_points, nodes) -> dict:
    """What :func:`_rows` computes of measurement ``m`` whatever theta: geometry, spline
    weights at the readings, the gain in W, the error-free tip positions (for the
    Gauss-Newton iterations of one identification to share)."""
    g = _geom(chain, m.J_m, rotary_points)
    q = np.asarray(m.O_R, float)
    k = len(q)
    nr = len(g.chain.rotary_axes)
    rot = np.tile(np.asarray(m.rot_rad, float).reshape(1, -1), (k, 1)) if nr else None
    T = np.asarray(m.T_W_A, float)
    zA = T[:3, 2]
    p = {"g": g, "q": q, "k": k, "rot": rot, "T": T, "touches": _has_touches(m), "features": False,
         "name": m.name, "holes": tuple(int(h) for h in m.holes),
         "P": np.asarray(m.O_A, float) @ T[:3, :3].T + T[:3, 3], "Pz": np.eye(3) - np.outer(zA, zA),
         "off": mistake_proofing(m.O_A)}
    if p["touches"]:
        qt = np.asarray(m.q_R, float)
        t = len(qt)
        p["qt"] = qt
        p["rott"] = np.tile(np.asarray(m.rot_rad, float).reshape(1, -1), (t, 1)) if nr else None
        p["W"] = _axis_weights(nodes, qt + np.asarray(g.J_m, float))
        p["d_W"] = np.asarray(m.d_A, float) @ T[:3, :3].T
        p["GW"] = np.einsum("ij,kjt->kit", T[:3, :3], np.asarray(m.G_A, float).reshape(k, 3, t))  # (k, 3, t)
        p["features"] = _has_features(m)
        if p["features"]:  # the extraction's inputs in W: each touch's feature and nominal normal (its hints)
            p["feature"] = tuple(str(f) for f in m.feature)
            p["n_W"] = np.asarray(m.n_A, float) @ T[:3, :3].T
    else:
        p["W"] = _axis_weights(nodes, q + np.asarray(g.J_m, float))
    return p


class _Prepared(list):
    """:func:`_prepare` of each measurement (a list), and ``batch``: the touches of every
    measurement with touches joined once (they do not depend on theta; every Gauss-Newton
    step's :func:`_touch_kinematics` and :func:`_rows` read them): ``at`` {measurement: its
    first row}, ``g`` the kinematic chain they share, ``qt`` (t, 3) readings, ``rott`` (t, r) or
    None, ``J`` (t, 3) each touch's probe offsets, ``W`` {axis: (t, k)} spline weights, ``d_W`` (t, 3) directions; None
    without touches."""

    batch: dict | None = None


def _prepare_all(meas, chain, rotary_points, nodes) -> _Prepared:
    """:func:`_prepare` of every measurement, with the error-free tips of the measurements with
    touches (at their points of interest, ``pred0``, and at their touches, ``tip0_t``) each
    in one kinematics call for all measurements (per-pose probe offsets, as :func:`_touch_kinematics`)."""
    prep = _Prepared(_prepare(m, chain, rotary_points, nodes) for m in meas)
    idx = [i for i, pm in enumerate(prep) if pm["touches"]]
    if not idx:
        return prep

    def join(key):  # the measurements' rows of prep[i][key], joined in order (None stays None)
        return None if prep[idx[0]][key] is None else np.concatenate([prep[i][key] for i in idx])

    def stylus(key):  # each of those rows' probe offsets J (its measurement's stylus)
        return np.concatenate([np.broadcast_to(prep[i]["g"].J_m, prep[i][key].shape) for i in idx])

    def starts(key):  # {measurement: its first row in join(key)}
        return dict(zip(idx, np.cumsum([0] + [len(prep[i][key]) for i in idx[:-1]]).tolist()))

    g = prep[idx[0]]["g"]
    prep.batch = b = {"at": starts("qt"), "g": g, "qt": join("qt"), "rott": join("rott"), "J": stylus("qt"),
                      "W": {a: np.concatenate([prep[i]["W"][a] for i in idx]) for a in iso.LINEAR_AXES},
                      "d_W": join("d_W")}
    for key, rows, at, tip in (("pred0", "q", starts("q"), tip_W(g, join("q"), join("rot"), None, J_m=stylus("q"))),
                               ("tip0_t", "qt", b["at"], tip_W(g, b["qt"], b["rott"], None, J_m=b["J"]))):
        for i, r0 in at.items():
            prep[i][key] = tip[r0:r0 + len(prep[i][rows])]
        b[key] = tip
    return prep


def _touch_kinematics(prep, theta, slices, exact, jacobian):
    """The touches of every measurement (:func:`_prepare_all`, its ``batch``) in one kinematics
    call: their sensitivity (t_all, 3, 21) when ``jacobian`` and exact tip positions (t_all, 3)
    when ``exact`` (else None), and each measurement's first row in them.

    The measurements share the chain and differ in their stylus: each touch carries
    its own probe offsets J (``J_m`` of :func:`core.kinematics.tip_W`), so every row is
    the number a call per measurement gives, bit for bit (tests/core/test_volumetric.py).
    """
    b = prep.batch
    if b is None or not (exact or jacobian):
        return None, None, {}
    vals = None
    if exact:
        each = [_values(theta, slices, prep[i]["W"], len(prep[i]["qt"])) for i in b["at"]]
        vals = {s: np.concatenate([v[s] for v in each]) for s in each[0]}
    g = b["g"]
    St = sensitivity(g, b["qt"], b["rott"], vals, symbols=MOTION + SQUARENESS, J_m=b["J"]) if jacobian else None
    tip = tip_W(g, b["qt"], b["rott"], vals, J_m=b["J"]) if exact else None
    return St, tip, b["at"]


def _rows(meas, chain, rotary_points, nodes, theta, slices, n, exact, jacobian=True, prep=None, extraction=False):
    """Jacobian and residual of (1) at theta: target - prediction (``jacobian=False``:
    the residual alone, the same numbers, Jacobian None: no sensitivity evaluated).
    ``prep``: :func:`_prepare` of each measurement (computed here when None). ``extraction`` (with
    ``exact``): the prediction of a measurement whose touches carry their features by the exact
    extraction (3') of the module doc, the Jacobian model (3)'s still."""
    Jrows, res, rows = [], [], []
    if prep is None:
        prep = _prepare_all(meas, chain, rotary_points, nodes)
    St_all, tip_all, at = _touch_kinematics(prep, theta, slices, exact, jacobian)
    ext = {}
    if exact and extraction and at:
        b = prep.batch
        if "fit0" not in b:  # the extraction of the error-free tips, once per prep (theta's change is fitted against it)
            b["fit0"] = _extracted(prep, b["tip0_t"])
        ext = _extracted(prep, tip_all)
    if jacobian and at:  # the touches' Jacobian rows (t_all, n), all measurements in one product
        Jt_all = _projected_error_jacobian(St_all, prep.batch["d_W"], prep.batch["W"], slices, n)
    for i, m in enumerate(meas):
        pm = prep[i]
        g, q, k, rot, T, W = pm["g"], pm["q"], pm["k"], pm["rot"], pm["T"], pm["W"]
        if pm["touches"]:
            # model (3): the errors act at the touches; the extraction's gain
            # carries each touch's normal shift into the points of interest
            qt, d_W, GW = pm["qt"], pm["d_W"], pm["GW"]
            t = len(qt)
            rows_t = slice(at[i], at[i] + t)
            if jacobian:
                J = (GW.reshape(3 * k, t) @ Jt_all[rows_t]).reshape(k, 3, n)
            pred = pm["pred0"]
            if i in ext:  # (3'): the touches moved to their actual tips and fitted again
                pred = pred + (ext[i] - prep.batch["fit0"][i])
            elif exact:
                e = np.einsum("tj,tj->t", d_W, tip_all[rows_t] - pm["tip0_t"])
                pred = pred + GW @ e
        else:
            vals = _values(theta, slices, W, k) if exact else None
            pred = tip_W(g, q, rot, vals)
            if jacobian:
                S = sensitivity(g, q, rot, vals, symbols=MOTION + SQUARENESS)  # (k, 3, 21)
                J = _error_jacobian(S, W, slices, n)
        P = pm["P"]
        xi = theta[slices[m.placement]] if exact else np.zeros(5)
        Rw = exp_so3(T[:3, 1:3] @ xi[3:])
        tgt = P @ Rw.T + xi[:3]
        r = tgt - pred
        # mistake-proofing holes: drop the component along the bar's z_A (roll)
        Pz, off = pm["Pz"], pm["off"]
        r[off] = r[off] @ Pz.T
        if jacobian:
            sl = slices[m.placement]
            J[:, :, sl.start:sl.start + 3] = -np.eye(3)
            J[:, :, sl.start + 3:sl.stop] = skew(P @ Rw.T) @ T[:3, 1:3]
            J[off] = np.einsum("ij,kjn->kin", Pz, J[off])
            Jrows.append(J.reshape(3 * k, n))
        res.append(r.ravel())
        rows += [(m.name, h) for h in m.holes]
    return (np.vstack(Jrows) if jacobian else None), np.concatenate(res), rows


def _null(A, tol=NULL_TOL):
    """Orthonormal null space of the column-scaled A, the scaling, and the singular values.

    Returns ``N_s (n, q)``, ``D (n,)`` (theta = D theta_s) and ``s`` (sorted, descending).
    """
    cn = np.linalg.norm(A, axis=0)
    D = np.where(cn > 0, 1.0 / np.where(cn > 0, cn, 1), 1.0)
    _, s, Vt = np.linalg.svd(A * D, full_matrices=True)
    s_full = np.zeros(A.shape[1])
    s_full[:len(s)] = s
    return Vt[s_full <= tol * s.max()].T, D, s


def _candidates(slices):
    """ISO 230-1 conventions in order of preference: (words, parameter index)."""
    out = []
    for s in MOTION:  # positioning zero at the first node (EX0X = 0 ...)
        if iso.symbol(s).kind == iso.Kind.POSITIONING:
            out.append((f"{s} = 0 at the first node", slices[s].start))
    for s in MOTION:  # end-point reference straight line (section 6)
        if iso.symbol(s).kind == iso.Kind.STRAIGHTNESS:
            out.append((f"{s} = 0 at the first node (end-point reference line)", slices[s].start))
            out.append((f"{s} = 0 at the last node (end-point reference line)", slices[s].stop - 1))
    for s in MOTION:  # constant part of angular errors (X primary, then Y, then Z)
        if iso.symbol(s).kind == iso.Kind.ANGULAR:
            out.append((f"{s} = 0 at the first node", slices[s].start))
    return out


def _gauge(N_s, slices, fixed=None):
    """Choose the ISO conventions that fix the null space (see module doc).

    ``N_s``: orthonormal null space in column-scaled coordinates. Each
    candidate (in the order of :func:`_candidates`) is taken while the
    null space left has a component of at least :data:`GAUGE_MIN` along
    it, so every convention removes one null direction and no convention
    is nearly redundant (which would leave the rest ill-conditioned).
    ``fixed``: use exactly these conventions (e.g. the gauge of the
    complete plan) instead of choosing.

    Returns ``C (k, n)``, the words, and the null directions left (n, q').
    """
    n = N_s.shape[0]
    cands = _candidates(slices)
    if fixed is not None:
        known = dict(cands)
        bad = [w for w in fixed if w not in known]
        if bad:
            raise ConfigError(f"unknown convention {bad[0]!r}")
        cands = [(w, known[w]) for w in fixed]
    N = N_s.copy()
    rows, words = [], []
    for w, idx in cands:
        v = N[idx] if N.shape[1] else np.zeros(0)
        if fixed is None and (not N.shape[1] or np.linalg.norm(v) < GAUGE_MIN):
            continue
        c = np.zeros(n)
        c[idx] = 1.0
        rows.append(c)
        words.append(w)
        if N.shape[1] and np.linalg.norm(v) > 1e-12:
            _, _, Vt = np.linalg.svd(v[None, :])
            N = N @ Vt[1:].T  # the part of the null space the convention leaves free
    return (np.array(rows) if rows else np.zeros((0, n))), tuple(words), N


def _nominal_readings(m, chain, rotary_points_R_m, points_A=None) -> np.ndarray:
    """(k, 3) readings a perfect machine gives at the nominal points of interest of ``m``.

    The nominal O_A: the calibrated ones rounded to 0.1 mm (the deviations
    are tens of um, the mistake-proofing shifts 1.5 mm); or ``points_A``
    (e.g. the nominal touches ``c_A``). Nominal tip_W is affine in the
    linear readings for fixed rotary positions; it is inverted.
    """
    g = _geom(chain, m.J_m, rotary_points_R_m)
    O_A = np.round(np.asarray(m.O_A, float), 4) if points_A is None else np.asarray(points_A, float)
    T = np.asarray(m.T_W_A, float)
    P = O_A @ T[:3, :3].T + T[:3, 3]
    nr = len(g.chain.rotary_axes)
    rot = np.asarray(m.rot_rad, float).reshape(1, -1) if nr else None
    q4 = np.vstack([np.zeros(3), np.eye(3)])
    t4 = tip_W(g, q4, None if rot is None else np.repeat(rot, 4, axis=0), None)
    M = (t4[1:] - t4[0]).T
    return np.linalg.solve(M, (P - t4[0]).T).T


def design(meas, chain: str, nodes: dict, rotary_points_R_m=None, gauge=None) -> VolumetricDesign:
    """The first-order problem (2), its null space and the ISO gauge (chosen, or ``gauge``)."""
    return _design(meas, chain, nodes, rotary_points_R_m, gauge)[0]


def _design(meas, chain, nodes, rotary_points_R_m, gauge) -> tuple:
    """(:func:`design`, :func:`_prepare` of each measurement)."""
    meas = list(meas)
    nodes = {a: np.asarray(v, float) for a, v in nodes.items()}
    _check(meas, nodes)
    names, slices, n, _ = _layout(meas, nodes)
    prep = _prepare_all(meas, chain, rotary_points_R_m, nodes)
    A, y, rows = _rows(meas, chain, rotary_points_R_m, nodes, np.zeros(n), slices, n, exact=False, prep=prep)
    key = _nominal_key(meas, chain, nodes, rotary_points_R_m, gauge, names)
    C, words, null, left, sv_rel = _NOMINAL.get_or_compute(
        key, lambda: _nominal_design(meas, chain, nodes, rotary_points_R_m, gauge, slices, n))
    return VolumetricDesign(A, y, tuple(names), slices, nodes, C, words, null, rows, left, sv_rel), prep


#: The plan's part of :func:`design` (null space, gauge, conditioning: nominal readings only),
#: by :func:`_nominal_key`: the same for every campaign of a plan (a Monte Carlo's runs).
#: Safe: the key hashes the measurements, chain, nodes, rotary points, gauge and names the
#: nominal design is made of; its arrays are only read. 8 plans (before: oldest dropped at 8).
_NOMINAL = Memo(8)


def _nominal_key(meas, chain, nodes, rotary_points_R_m, gauge, names) -> bytes:
    """A digest of everything :func:`_nominal_design` reads (not the readings, nor the measured O_R)."""
    import hashlib

    h = hashlib.blake2b(digest_size=32)

    def add(*xs):  # arrays by their shape and bytes, None and text by their repr
        for x in xs:
            if x is None or isinstance(x, str):
                h.update(repr(x).encode())
            else:
                a = np.ascontiguousarray(np.asarray(x, float))
                h.update(repr(a.shape).encode() + a.tobytes())
            h.update(b"|")

    rp = sorted((str(k), tuple(float(u) for u in np.ravel(v))) for k, v in (rotary_points_R_m or {}).items())
    add(chain, repr(rp), repr(None if gauge is None else tuple(gauge)), repr(tuple(names)))
    for a in sorted(nodes):
        add(a, nodes[a])
    for m in meas:
        add(str(m.placement), np.asarray(m.holes, float), np.asarray(m.J_m, float), np.asarray(m.T_W_A, float),
            np.asarray(m.rot_rad, float), np.round(np.asarray(m.O_A, float), 4), np.asarray(np.shape(m.O_R), float))
        if _has_touches(m):
            add(np.asarray(m.c_A, float), np.asarray(m.d_A, float), np.asarray(m.G_A, float))
        else:
            add(None)
    return h.digest()


def _nominal_design(meas, chain, nodes, rotary_points_R_m, gauge, slices, n) -> tuple:
    """(C, words, null, left, sv_rel) of :func:`design` from the plan's nominal readings."""
    # null space, gauge and conditioning from the plan's geometry: the
    # readings a perfect machine would give for the nominal bar (design O_A on
    # lines, no calibrated deviations). At the actual readings the micrometre
    # errors bend the bars by ~1e-5 relative, which turns exact gauge
    # freedoms (a constant table rotation) into 1e-6 "observations".
    from dataclasses import replace as _rep

    meas_r = [_rep(m, O_R=_nominal_readings(m, chain, rotary_points_R_m), O_A=np.round(np.asarray(m.O_A, float), 4),
                   q_R=_nominal_readings(m, chain, rotary_points_R_m, m.c_A) if _has_touches(m) else None)
              for m in meas]
    A_r, _, _ = _rows(meas_r, chain, rotary_points_R_m, nodes, np.zeros(n), slices, n, exact=False)
    N_s, D, _ = _null(A_r)
    C, words, left_s = _gauge(N_s, slices, gauge)
    # conditioning of the gauge-fixed problem: the scaled design without the
    # columns the conventions pin (they are unit picks)
    free = np.ones(n, bool)
    free[np.flatnonzero(np.any(C != 0, axis=0))] = False
    As = (A_r * D)[:, free]
    _, sv, Vt = np.linalg.svd(As, full_matrices=False)
    sv_rel = sv / sv.max()
    weak = []
    for j in np.flatnonzero(sv_rel < COND_TOL):
        v = np.zeros(n)
        v[free] = Vt[j]
        weak.append(D * v)
    left = D[:, None] * left_s
    if weak:
        left = np.column_stack([left] + weak)
    out = (C, words, D[:, None] * N_s, left, sv_rel)
    for a in (C, *out[2:]):
        a.setflags(write=False)  # shared by every design of the plan
    return out


@dataclass(frozen=True)
class ObservabilityReport:
    """What a plan can and cannot see.

    Attributes
    ----------
    n_params, rank : int
        Parameters of (2) and rank of its matrix.
    gauge : tuple of str
        ISO conventions needed (each removes one null direction).
    unidentifiable : tuple of str
        Combinations left after the conventions, or seen only below
        :data:`COND_TOL`, each as ``+0.71*EBX@x=.. -0.71*EXX@x=..``
        (largest terms, column-scaled, first).
    sv_rel : (r,) float
        Singular values of the gauge-fixed, column-scaled design over the
        largest, descending.
    weakest : tuple of str
        The three least-seen combinations (smallest singular values).
    """

    n_params: int
    rank: int
    gauge: tuple
    unidentifiable: tuple
    sv_rel: np.ndarray = field(default=None, repr=False, compare=False)
    weakest: tuple = ()

    @property
    def ok(self) -> bool:
        return not self.unidentifiable

    @property
    def sv_min_rel(self) -> float:
        return float(self.sv_rel[-1]) if self.sv_rel is not None and len(self.sv_rel) else 0.0


def _unseen(d: VolumetricDesign) -> list:
    U = d.unseen
    out = []
    for j in range(U.shape[1]):
        v = U[:, j] / d_scale(d)
        out.append(describe_direction(v / np.abs(v).max(), d.names))
    return out


def d_scale(d: VolumetricDesign) -> np.ndarray:
    """(n,) column scaling of the design (theta = D theta_s)."""
    cn = np.linalg.norm(d.A, axis=0)
    return np.where(cn > 0, 1.0 / np.where(cn > 0, cn, 1), 1.0)


def observability(meas, chain: str, nodes: dict, rotary_points_R_m=None, gauge=None) -> ObservabilityReport:
    """Rank, singular values and the error combinations a plan cannot see, by name.

    ``gauge``: the conventions of a reference (complete) plan; without it
    the conventions are chosen for this plan and may absorb a loss.
    """
    d = design(meas, chain, nodes, rotary_points_R_m, gauge)
    n = d.A.shape[1]
    D = d_scale(d)
    free = ~np.any(d.C != 0, axis=0)
    _, _, Vt = np.linalg.svd(d.A[:, free] * D[free], full_matrices=False)
    weakest = []
    for j in range(1, min(3, Vt.shape[0]) + 1):
        v = np.zeros(n)
        v[free] = Vt[-j]
        weakest.append(f"{d.sv_rel[-j]:.1e}: " + describe_direction(v / np.abs(v).max(), d.names))
    return ObservabilityReport(n, n - d.null.shape[1], d.gauge, tuple(_unseen(d)), d.sv_rel, tuple(weakest))


@dataclass(frozen=True)
class VolumetricResult:
    """Identified error tables.

    Attributes
    ----------
    theta : (n,) float
        All parameters (m, rad), names in ``design.names``.
    design : VolumetricDesign
    chain : str
    rotary_points_R_m : dict
    iterations : int
        Gauss-Newton iterations on the exact model (0: first order only).
    rms_m : float
        RMS of the residuals of (1) at the solution.
    K : (n, m) float
        The estimator at the solution: d theta / d y.
    extraction : bool
        The Gauss-Newton predicted the points by the exact extraction (3') where the touches carry their
        features (:data:`EXACT_EXTRACTION`); its residuals (:func:`lack_of_fit`) are taken the same way.
    """

    theta: np.ndarray
    design: VolumetricDesign
    chain: str
    rotary_points_R_m: dict
    iterations: int
    rms_m: float
    K: np.ndarray = field(repr=False, compare=False)
    extraction: bool = False

    def table(self, symbol: str) -> tuple[np.ndarray, np.ndarray]:
        """(nodes m, values m or rad) of one motion error; (empty, (1,)) for a squareness."""
        s = iso.symbol(symbol).name
        if s in SQUARENESS:
            return np.zeros(0), self.theta[self.design.slices[s]]
        return self.design.nodes[iso.symbol(s).axis], self.theta[self.design.slices[s]]

    def spline(self, symbol: str) -> CubicSpline:
        """C2 cubic spline (not-a-knot) through a motion error's table (section 6)."""
        x, v = self.table(symbol)
        if len(x) < 2:
            raise ConfigError(f"{symbol}: no table to interpolate")
        return CubicSpline(x, v, bc_type="not-a-knot" if len(x) >= 4 else "natural")

    def value(self, symbol: str, u) -> np.ndarray:
        """The error between nodes by the spline, at axis (joint) positions u (m, reading + J)."""
        s = iso.symbol(symbol).name
        if s in SQUARENESS:
            return np.full(np.shape(u), self.theta[self.design.slices[s]][0])
        x, v = self.table(s)
        return spline_weights(x, np.atleast_1d(u)) @ v

    def placement(self, name: str) -> np.ndarray:
        """(5,) estimated placement error (v m in W; w about y_A, z_A, rad)."""
        return self.theta[self.design.slices[name]]


def identify_volumetric(meas, chain: str, nodes: dict, rotary_points_R_m=None, *, exact: bool = True,
             max_iter: int = 10, tol_m: float = 1e-12, gauge=None, extraction: bool | None = None) -> VolumetricResult:
    """Identify the 21 errors from MFB measurements (eqs 8-12, then the exact model).

    ``extraction``: the Gauss-Newton's prediction of the measurements whose touches carry their
    features by the exact extraction (3') (None: :data:`EXACT_EXTRACTION`); the others by (3) or (2).

    Raises
    ------
    IdentifiabilityError
        The plan leaves an error combination unseen beyond the ISO
        conventions (named).
    """
    meas = list(meas)
    ext = _extraction(extraction) and exact
    d, prep = _design(meas, chain, nodes, rotary_points_R_m, gauge)
    theta, est, it, res = _identify(meas, chain, rotary_points_R_m, d, prep, exact, max_iter, tol_m, ext)
    m = d.A.shape[0]
    K = est.estimate(np.eye(m)) - est.estimate(np.zeros(m))[:, None]
    return VolumetricResult(theta, d, chain, dict(rotary_points_R_m or {}), it if exact else 0,
                            float(np.sqrt(np.mean(res ** 2))), K, ext)


def _extraction(extraction) -> bool:
    """``extraction`` as a bool (None: :data:`EXACT_EXTRACTION`), refused by name otherwise."""
    if extraction is None:
        return bool(EXACT_EXTRACTION)
    if not isinstance(extraction, (bool, np.bool_)):
        raise ConfigError(f"extraction must be True, False or None (the module's default), got {extraction!r}")
    return bool(extraction)


def _identify(meas, chain, rotary_points_R_m, d: VolumetricDesign, prep, exact: bool, max_iter: int, tol_m: float,
              extraction: bool = False):
    """(theta, estimator, iterations, residual of (1) at theta) of :func:`identify_volumetric` on its design ``d``
    and :func:`_prepare` of each measurement ``prep``; ``extraction``: the prediction by (3') (:func:`_rows`)."""
    if d.unseen.shape[1]:
        un = _unseen(d)
        raise IdentifiabilityError(f"the plan cannot identify {len(un)} combination(s) beyond the ISO "
                                   f"conventions: " + "; ".join(un[:6]))
    C = d.C
    sol = solve(d.A, d.y, C, np.zeros(len(C)), names=d.names, sigma=1e-6, covariance="none",
                rank_tol=SOLVE_RANK_TOL)
    theta = sol.theta
    est = sol.estimator
    it = 0
    res = d.y - d.A @ theta
    if exact:
        n = len(theta)
        for it in range(1, max_iter + 1):
            J, r, _ = _rows(meas, chain, rotary_points_R_m, d.nodes, theta, d.slices, n, exact=True, prep=prep,
                            extraction=extraction)
            # r = target - prediction; J = d(prediction - target)/d theta with the sign of (2)
            s2 = solve(J, r, C, np.zeros(len(C)), names=d.names, sigma=1e-6, covariance="none",
                rank_tol=SOLVE_RANK_TOL)
            theta = theta + s2.theta
            est = s2.estimator
            res = r - J @ s2.theta
            if np.abs(s2.theta).max() < tol_m:
                break
        _, res, _ = _rows(meas, chain, rotary_points_R_m, d.nodes, theta, d.slices, n, exact=True, jacobian=False,
                          prep=prep, extraction=extraction)
    return theta, est, it, res


def reduced_design(meas, chain: str, nodes: dict, rotary_points_R_m=None, gauge=None, extraction=False) -> tuple:
    """The first-order problem (2) with its left side reduced to first order at the exact solution.

    Returns ``(design, theta)``: :func:`design`'s matrix ``A`` (the placements' columns at the nominal
    poses, the errors' at zero: its null space the gauge's, exactly) with ``y = r(theta) + A theta``,
    ``r(theta)`` the residual of the exact model (1) at ``theta``, the Gauss-Newton solution of
    :func:`identify_volumetric`. The (unweighted) least squares of ``y`` on ``A`` under the gauge is that
    solution, to the Gauss-Newton's convergence, and a term added beside ``A`` (a linear model of something the tables do not hold) is fitted
    against what the exact model leaves, not against (2)'s own misfit. (2) is first order in the
    placement errors: a bar turned by ``w`` (pitch, yaw; ``U_PLACE`` 0.5, 1 mrad) moves its points by
    ``skew(w) P`` in (2) but by ``(exp(skew w) - I) P`` in fact, the difference ``skew(w)^2 P / 2``
    a change of the bar's apparent length by ``-(w_y^2 + w_z^2) / 2`` (0.6 ppm on average, 0.7 ppm
    from placement to placement): a scale per placement, which (2)'s placements cannot absorb and a
    scale drift between placements takes (session 29: the volumetric drift magnitudes' apparent drift
    of 1.2-2.2 ppm RMS over 20 campaigns, 2-3 times their standard uncertainty). ``theta`` None and
    :func:`design` itself where the plan leaves a combination unseen (no solution to reduce at).
    ``A`` is kept at the nominal poses, not taken at the solution: the exact model's Jacobian there turns
    (2)'s exact gauge freedoms into 1e-5 "observations" the engine's column space then holds (tried:
    the drift's U95 on a campaign without placement draws 1.25 -> 2.06 ppm, its estimate moved 1.2 ppm).
    A first-order remainder of the turns is left: noise-free, seed 5, the drift within 0.06-0.22 ppm
    (0.04 without placement draws; 1.2-1.5 ppm without the reduction).

    ``extraction``: the Gauss-Newton's prediction by the exact extraction (3') (None:
    :data:`EXACT_EXTRACTION`); False by default: discovery's baseline (:func:`core.baseline.volumetric`) keeps
    model (3)'s residuals until the exact extraction is measured on the discovery campaigns (session 32 measured
    it on the identification alone).
    """
    from dataclasses import replace as _rep

    meas = list(meas)
    d, prep = _design(meas, chain, nodes, rotary_points_R_m, gauge)
    if d.unseen.shape[1]:
        return d, None
    theta, _, _, r = _identify(meas, chain, rotary_points_R_m, d, prep, True, 10, 1e-12, _extraction(extraction))
    return _rep(d, y=r + d.A @ theta), theta


# --------------------------------------------------------------------------- ISO 230-1 report form
def iso_map(design_: VolumetricDesign) -> np.ndarray:
    """(n, n) linear map from the identification gauge to the ISO 230-1 report form.

    Every straightness table is reported against its end-point reference
    straight line (MFB paper section 6; ISO 230-1 3.4.8): the line through
    its first and last node values is subtracted. The gauge already zeroes
    both ends of ``EYX``, ``EZX``, ``EZY``; for ``EXY``, ``EXZ``, ``EYZ`` the
    slope removed is what the squareness convention leaves in the table: it
    is kept beside the table (:func:`end_point_slopes`), so the report still
    describes the machine. Everything else is unchanged. Apply the same map
    to the identified and to the injected values.
    """
    n = len(design_.names)
    L = np.eye(n)
    for s in MOTION:
        sy = iso.symbol(s)
        sl = design_.slices[s]
        x = design_.nodes[sy.axis]
        if sy.kind != iso.Kind.STRAIGHTNESS or len(x) < 2:
            continue
        u = (x - x[0]) / (x[-1] - x[0])
        L[sl, sl.start] -= 1.0 - u
        L[sl, sl.stop - 1] -= u
    return L


def end_point_slopes(design_: VolumetricDesign, theta: np.ndarray) -> dict:
    """Straightness symbol -> slope of its end-point reference line (rad) in the identification gauge."""
    out = {}
    for s in MOTION:
        sy = iso.symbol(s)
        x = design_.nodes[sy.axis]
        if sy.kind == iso.Kind.STRAIGHTNESS and len(x) >= 2:
            v = theta[design_.slices[s]]
            out[s] = float((v[-1] - v[0]) / (x[-1] - x[0]))
    return out


def iso_view(res: VolumetricResult) -> VolumetricResult:
    """The result in the ISO 230-1 report form (:func:`iso_map` applied to theta and K)."""
    from dataclasses import replace as _rep

    L = iso_map(res.design)
    return _rep(res, theta=L @ res.theta, K=L @ res.K)


# --------------------------------------------------------------------------- uncertainty
@dataclass(frozen=True)
class VolumetricUncertainty:
    """Uncertainty of the identified parameters.

    Attributes
    ----------
    u_lin : (n,) float
        Standard uncertainty by linear propagation (m, rad).
    U95_lin : (n,) float
        2 u_lin (coverage factor 2).
    lo95, hi95 : (n,) float
        Monte Carlo (JCGM 101) probabilistically symmetric 95 % interval
        of each parameter, m / rad (empty when runs = 0).
    U95_mc : (n,) float
        Half width of the MC interval.
    runs : int
    """

    u_lin: np.ndarray
    U95_lin: np.ndarray
    lo95: np.ndarray
    hi95: np.ndarray
    U95_mc: np.ndarray
    runs: int


def _input_maps(res: VolumetricResult, meas, n_holes):
    """Matrices mapping probing noise (per touch), bar calibration errors and
    placement errors (6 per placement: translation in A, rotation about x_A,
    y_A, z_A, the roll included) to y.

    The bar's maps are taken at its pose as identified (the nominal pose moved
    by the placement's estimated v, w: the pose the estimator ``res.K`` was
    linearised at), not at the nominal one: a bar set 1-2 mrad off in yaw
    otherwise leaks its placement uncertainty into the errors (EBX up to
    12 urad where the Monte Carlo shows 0.1)."""
    blocks, B = [], np.zeros((res.K.shape[1], 3 * n_holes))
    places = list(dict.fromkeys(m.placement for m in meas))
    Bp = np.zeros((res.K.shape[1], 6 * len(places)))
    r0 = 0
    for m in meas:
        T = _identified_pose(res, m)
        R = T[:3, :3]
        k = len(m.holes)
        P = np.asarray(m.O_A, float) @ R.T + T[:3, 3]
        c = 6 * places.index(m.placement)
        blk = np.zeros((k, 3, 6))
        blk[:, :, :3] = R  # translation along x_A, y_A, z_A
        for j in range(3):  # rotation about the bar's axes, about the origin of A
            blk[:, :, 3 + j] = np.cross(R[:, j], P - T[:3, 3])
        # the rows as the identification sees them: shifted holes without z_A
        zA = R[:, 2]
        off = mistake_proofing(m.O_A)
        blk[off] = np.einsum("ij,kjn->kin", np.eye(3) - np.outer(zA, zA), blk[off])
        Bp[r0:r0 + 3 * k, c:c + 6] = blk.reshape(3 * k, 6)
        r0 += 3 * k
    r0 = 0
    for m in meas:
        T = np.asarray(m.T_W_A, float)
        R = T[:3, :3]  # the readings' gain as the identification's rows carry it (nominal pose)
        R_id = _identified_pose(res, m)[:3, :3]  # d target / d O_A at the identified pose
        k = len(m.holes)
        if m.G_A is None:
            raise ConfigError(f"measurement {m.name!r} has no noise gain G_A (core.mfb.poi_noise_gain)")
        G = np.asarray(m.G_A, float)
        # y = T O_A - tip: a reading moved by dO_R (= R G e in W for a 3-axis
        # machine) lowers y by it; the sign does not matter for covariance.
        GR = np.einsum("ij,kjt->kit", R, G.reshape(k, 3, -1)).reshape(3 * k, -1)
        blocks.append((r0, GR))
        for a, h in enumerate(m.holes):
            B[r0 + 3 * a:r0 + 3 * a + 3, 3 * (h - 1):3 * h] = R_id
        r0 += 3 * k
    return blocks, B, Bp


def _identified_pose(res: VolumetricResult, m) -> np.ndarray:
    """(4, 4) the bar's pose of measurement ``m`` where the estimator ``res.K`` was
    linearised: T_W_A moved by its placement's v (W, m) and w (about y_A, z_A, rad), as
    the rows of (1) move it; T_W_A itself for a first-order result (``iterations`` 0:
    its rows are taken at zero placement errors)."""
    T = np.asarray(m.T_W_A, float)
    if not res.iterations:
        return T
    xi = res.theta[res.design.slices[m.placement]]
    Rw = exp_so3(T[:3, 1:3] @ xi[3:])
    out = np.eye(4)
    out[:3, :3] = Rw @ T[:3, :3]
    out[:3, 3] = Rw @ T[:3, 3] + xi[:3]
    return out


def _cal_columns(K, B, u_cal, cal_map) -> np.ndarray:
    """(n, 3N) ``K B cal_map diag(u_cal)``: the estimate's response to the calibration's
    independent errors (``cal_map`` None: one per point and direction)."""
    KB = K @ B
    if cal_map is not None:
        M = np.asarray(cal_map, float)
        if M.shape != (B.shape[1], B.shape[1]) or not np.all(np.isfinite(M)):
            raise ConfigError(f"cal_map must be a finite ({B.shape[1]}, {B.shape[1]}) matrix, got {M.shape}")
        KB = KB @ M
    return KB * u_cal.ravel()[None, :]


def ripple_columns(res: VolumetricResult, meas, chain: str, symbol: str, amplitude: float, period: float,
                   rotary_points_R_m=None) -> np.ndarray:
    """(n, 2) what a periodic error the tables cannot hold does to the estimate's error (a type B term).

    A ripple ``amplitude * sin(2 pi q / period + phi)`` in the motion error ``symbol`` (m or rad; ``q``
    its axis position, reading + J, m) is ``amplitude * (cos phi * s(q) + sin phi * c(q))`` with ``s = sin(2 pi q / period)``,
    ``c = cos(2 pi q / period)``. Each moves the rows of (1) as the identification's own model (3) moves them:
    every touch by its sensitivity to ``symbol`` along its approach, carried into the points of interest by the
    extraction's gain (model (2) at the points of interest for a measurement without touches), the shifted
    holes without z_A; the estimate moves by ``res.K`` of that (its linear map; the sensitivity taken at zero
    errors, a relative change of order the errors' slopes, 1e-4). The measurand moves too: the truth at the
    nodes holds the ripple (``amplitude * s`` and ``c`` at ``symbol``'s nodes, in the design's gauge,
    :meth:`VolumetricDesign.to_gauge`), which no table fitted through the plan's touches follows. Column 0 is
    ``amplitude * (K y(s) - s_nodes)``, column 1 the same of ``c``: for a phase phi the estimate's error moves by
    ``C[:, 0] cos phi + C[:, 1] sin phi``; for an unknown phase (uniform) its covariance is ``C C^T / 2``.
    ``res`` as identified (:func:`identify_volumetric`, its gauge); the report form's columns are
    ``iso_map(res.design) @ C``.
    """
    if symbol not in MOTION:
        raise ConfigError(f"ripple_columns: {symbol!r} is not a motion error ({', '.join(MOTION)})")
    if not (np.isfinite(amplitude) and np.isfinite(period) and period > 0):
        raise ConfigError(f"ripple_columns: amplitude finite and period > 0, got {amplitude!r}, {period!r}")
    meas = list(meas)
    prep = _prepare_all(meas, chain, rotary_points_R_m, res.design.nodes)
    ks, ax = MOTION.index(symbol), iso.LINEAR_AXES.index(iso.symbol(symbol).axis)
    if prep.batch is not None:
        St, _, at = _touch_kinematics(prep, None, res.design.slices, False, True)
        Sd = np.einsum("tj,tj->t", prep.batch["d_W"], St[:, :, ks])  # each touch along its approach
    w = 2.0 * np.pi / period
    cols = np.zeros((res.K.shape[1], 2))
    r0 = 0
    for i, pm in enumerate(prep):
        k = pm["k"]
        if pm["touches"]:
            t = len(pm["qt"])
            sd, x = Sd[at[i]:at[i] + t], pm["qt"][:, ax] + pm["g"].J_m[ax]
            dy = [(pm["GW"].reshape(3 * k, t) @ (sd * f(w * x))).reshape(k, 3) for f in (np.sin, np.cos)]
        else:
            S = sensitivity(pm["g"], pm["q"], pm["rot"], None, symbols=MOTION + SQUARENESS)[:, :, ks]
            x = pm["q"][:, ax] + pm["g"].J_m[ax]
            dy = [S * f(w * x)[:, None] for f in (np.sin, np.cos)]
        for j, r in enumerate(dy):
            r[pm["off"]] = r[pm["off"]] @ pm["Pz"].T
            cols[r0:r0 + 3 * k, j] = r.ravel()
        r0 += 3 * k
    d = res.design
    x_n = d.nodes[iso.symbol(symbol).axis]
    truth = np.zeros((len(d.names), 2))
    for j, f in enumerate((np.sin, np.cos)):
        truth[d.slices[symbol], j] = f(w * np.asarray(x_n, float))
        truth[:, j] = d.to_gauge(truth[:, j])
    return amplitude * (res.K @ cols - truth)


def _ripple_cols(ripples, K) -> np.ndarray | None:
    """The declared ripples' columns (:func:`ripple_columns`) side by side, (n, 2 r), checked; None when none.
    A value the gauge fixes (its row of ``K`` zero: the convention's, not estimated) keeps no uncertainty:
    its rows are set to zero (they hold the gauge projection's rounding, ~1e-22 m)."""
    if ripples is None or len(ripples) == 0:
        return None
    n = K.shape[0]
    C = np.hstack([np.asarray(c, float) for c in ripples])
    if C.shape != (n, 2 * len(ripples)) or not np.all(np.isfinite(C)):
        raise ConfigError(f"ripples: finite ({n}, 2) columns each (ripple_columns), got {C.shape}")
    C[~np.any(K != 0, axis=1)] = 0.0
    return C


def _model_error_cols(C, K) -> np.ndarray | None:
    """The model-error share's columns (:func:`model_error_share`), checked; None when none (or no column)."""
    if C is None:
        return None
    C = np.asarray(C, float)
    if C.ndim != 2 or C.shape[0] != K.shape[0] or not np.all(np.isfinite(C)):
        raise ConfigError(f"model_error: finite ({K.shape[0]}, c) columns (model_error_share), got {C.shape}")
    if C.shape[1] == 0:
        return None
    if C.shape[1] > K.shape[0]:  # as many columns as values at most (the same C C^T)
        Q, Rr = np.linalg.qr(C.T)
        C = Rr.T
    return C


def uncertainty(res: VolumetricResult, meas, sigma_probe_m: float, u_cal_m, *, runs: int = 1000,
                rng: np.random.Generator | None = None, u_place=None, cal_map=None,
                ripples=None, model_error=None) -> VolumetricUncertainty:
    """Linear propagation and Monte Carlo (JCGM 101) of probing noise, bar calibration and placement.

    Parameters
    ----------
    res : VolumetricResult
    meas : sequence of Measurement (with ``G_A``), as identified
    sigma_probe_m : float
        Standard deviation of one touch along its approach, m.
    u_cal_m : (N, 3) float
        Standard uncertainty of the bar's calibrated deviations, m.
    runs : int
        Monte Carlo trials (0: linear only).
    rng : np.random.Generator
    u_place : (6,) float, optional
        Standard uncertainty of each placement: translation along x_A, y_A,
        z_A (m), rotation about x_A (roll), y_A, z_A (rad); independent per
        placement. The estimator absorbs translation, pitch and yaw into
        the placement's nuisance values (share ~0); the roll, not
        estimated, moves the shifted holes along z_A (not used) and the
        points by roll x their calibrated offsets from the bar axis (um):
        a small share, propagated, not assumed.
    cal_map : (3N, 3N) float, optional
        How the calibration's errors reach the points: their (x, y, z)
        deviations, point by point, are off by ``cal_map @ (u_cal.ravel() * n)``,
        n independent standard normal (default: the identity, independent per
        point and direction). A multi-feature bar's heights come from its rods:
        :func:`core.mfb.calibration_map`.
    ripples : sequence of (n, 2) float, optional
        Declared periodic errors the tables cannot hold (:func:`ripple_columns`), each of unknown phase
        (uniform): a type B term, ``C C^T / 2`` in the linear propagation, ``C[:, 0] cos phi + C[:, 1] sin phi``
        with phi drawn uniform in the Monte Carlo (after every other draw: without ripples nothing moves).
    model_error : (n, c) float, optional
        The model-error share's columns (:func:`model_error_share`, ``columns``, in ``res``'s form): ``C C^T``
        in the linear propagation, ``C`` times standard normal draws in the Monte Carlo (drawn after the
        ripples: without it nothing moves).

    Linear propagation: ``u^2 = sum (K G)^2 sigma^2 + (K B u_cal)^2 +
    (K B_p u_place)^2`` (JCGM 100 eq. 13 for the linear estimator ``K``);
    Monte Carlo: the same estimator over ``runs`` joint draws of the inputs
    (JCGM 101, 95 % probabilistically symmetric interval); ``runs`` 0 or at least
    :data:`core.uncertainty.MC_MIN_RUNS` (of fewer the percentiles are the runs' extremes: of one, U95 = 0).
    """
    from .uncertainty import check_mc_runs

    runs = check_mc_runs(runs, zero_ok=True)
    meas = list(meas)
    u_cal = np.asarray(u_cal_m, float)
    if u_cal.ndim != 2 or u_cal.shape[1] != 3:
        raise ConfigError(f"u_cal_m must be (N, 3), got {u_cal.shape}")
    if not (np.isfinite(sigma_probe_m) and sigma_probe_m >= 0):
        raise ConfigError(f"sigma_probe_m must be >= 0, got {sigma_probe_m!r}")
    K = res.K
    blocks, B, Bp = _input_maps(res, meas, u_cal.shape[0])
    up = np.zeros(6) if u_place is None else np.asarray(u_place, float)
    if up.shape != (6,) or not np.all(np.isfinite(up)) or np.any(up < 0):
        raise ConfigError(f"u_place must be 6 finite values >= 0 (m, m, m, rad, rad, rad), got {u_place!r}")
    var = np.zeros(K.shape[0])
    for r0, GR in blocks:
        KG = K[:, r0:r0 + GR.shape[0]] @ GR
        var += sigma_probe_m ** 2 * np.einsum("ij,ij->i", KG, KG)
    KB = _cal_columns(K, B, u_cal, cal_map)
    var += np.einsum("ij,ij->i", KB, KB)
    KP = (K @ Bp) * np.tile(up, Bp.shape[1] // 6)[None, :]
    var += np.einsum("ij,ij->i", KP, KP)
    C = _ripple_cols(ripples, K)
    if C is not None:
        var += 0.5 * np.einsum("ij,ij->i", C, C)
    Cm = _model_error_cols(model_error, K)
    if Cm is not None:
        var += np.einsum("ij,ij->i", Cm, Cm)
    u = np.sqrt(var)
    lo = hi = U = np.zeros(0)
    if runs:
        if rng is None:
            raise ConfigError("uncertainty: Monte Carlo needs an np.random.Generator (rng)")
        d = np.zeros((K.shape[0], runs))
        for r0, GR in blocks:
            e = sigma_probe_m * rng.standard_normal((GR.shape[1], runs))
            d += K[:, r0:r0 + GR.shape[0]] @ (GR @ e)
        d += KB @ rng.standard_normal((KB.shape[1], runs))
        d += KP @ rng.standard_normal((KP.shape[1], runs))
        if C is not None:
            phi = rng.uniform(0.0, 2.0 * np.pi, (C.shape[1] // 2, runs))
            d += C[:, 0::2] @ np.cos(phi) + C[:, 1::2] @ np.sin(phi)
        if Cm is not None:
            d += Cm @ rng.standard_normal((Cm.shape[1], runs))
        lo = res.theta + np.percentile(d, 2.5, axis=1)
        hi = res.theta + np.percentile(d, 97.5, axis=1)
        U = 0.5 * (hi - lo)
    return VolumetricUncertainty(u, 2.0 * u, lo, hi, U, int(runs))


def covariance(res: VolumetricResult, meas, sigma_probe_m: float, u_cal_m, u_place=None, *,
               cal_map=None, ripples=None, model_error=None) -> np.ndarray:
    """(n, n) covariance of ``res.theta`` by linear propagation, the same inputs as :func:`uncertainty`.

    ``K G G^T K^T sigma^2`` per measurement plus ``(K B M) diag(u_cal^2) (K B M)^T`` (M = ``cal_map``,
    default the identity) plus the placements' plus ``C C^T / 2`` of each declared ripple (``ripples``)
    (JCGM 100 eq. 13 in matrix form); its diagonal is :func:`uncertainty`'s ``u_lin**2``.
    """
    u_cal = np.asarray(u_cal_m, float)
    if u_cal.ndim != 2 or u_cal.shape[1] != 3:
        raise ConfigError(f"u_cal_m must be (N, 3), got {u_cal.shape}")
    K = res.K
    blocks, B, Bp = _input_maps(res, list(meas), u_cal.shape[0])
    up = np.zeros(6) if u_place is None else np.asarray(u_place, float)
    cov = np.zeros((K.shape[0], K.shape[0]))
    for r0, GR in blocks:
        KG = K[:, r0:r0 + GR.shape[0]] @ GR
        cov += sigma_probe_m ** 2 * (KG @ KG.T)
    KB = _cal_columns(K, B, u_cal, cal_map)
    KP = (K @ Bp) * np.tile(up, Bp.shape[1] // 6)[None, :]
    cov = cov + KB @ KB.T + KP @ KP.T
    C = _ripple_cols(ripples, K)
    cov = cov if C is None else cov + 0.5 * (C @ C.T)
    Cm = _model_error_cols(model_error, K)
    return cov if Cm is None else cov + Cm @ Cm.T


def estimate(res: VolumetricResult, cov: np.ndarray) -> dict:
    """The ``vmt-estimate/1`` block (:mod:`core.state`) of an identification in its own gauge.

    ``res`` as identified (:func:`identify_volumetric`, not :func:`iso_view`): its tables are the
    machine's errors up to the conventions (a straightness keeps its slope). The 18 motion tables on
    their nodes (C2 spline, end tangents beyond) and the squarenesses are machine errors; the
    placements' nuisance values are named only.
    """
    from .state import estimate_doc

    d = res.design
    n = len(res.theta)
    symbols, at, units = [None] * n, [None] * n, ["um"] * n
    for s in MOTION + SQUARENESS:
        sy = iso.symbol(s)
        sl = d.slices[s]
        for k, i in enumerate(range(sl.start, sl.stop)):
            symbols[i] = s
            units[i] = "urad" if sy.angular else "um"
            if s in MOTION:
                at[i] = float(d.nodes[sy.axis][k])
    for i, nm in enumerate(d.names):
        if symbols[i] is None and nm.split(".")[-1].startswith("w"):
            units[i] = "urad"
    return estimate_doc(d.names, symbols, at, units, res.theta, cov,
                        method="MFB volumetric identification (Viprey 2016 eqs 8-12, exact Gauss-Newton); "
                               "covariance: probing noise, bar calibration, placements (linear propagation)",
                        interpolation="cubic-spline", conventions=d.gauge)


# --------------------------------------------------------------------------- reports and tables
def report(res: VolumetricResult, unc: VolumetricUncertainty | None = None, truth: np.ndarray | None = None,
           slopes: dict | None = None) -> dict:
    """JSON-ready dict: one entry per ISO symbol with node tables in um / urad.

    ``res`` as reported (:func:`iso_view`: straightness against the end-point
    line); ``slopes`` (:func:`end_point_slopes` of the identification) adds
    the removed line's slope to each straightness entry.
    """
    out = {}
    for s in MOTION + SQUARENESS:
        sy = iso.symbol(s)
        sl = res.design.slices[s]
        unit = sy.report_unit
        e = {"unit": unit, "kind": sy.kind.value,
             "identified": (res.theta[sl] * 1e6).tolist()}
        if s in MOTION:
            e["nodes_mm"] = (res.design.nodes[sy.axis] * 1e3).tolist()
        if unc is not None:
            U = unc.U95_mc if unc.runs else unc.U95_lin
            e["u95"] = (U[sl] * 1e6).tolist()
            e["u95_lin"] = (unc.U95_lin[sl] * 1e6).tolist()
        if truth is not None:
            e["injected"] = (truth[sl] * 1e6).tolist()
        if slopes is not None and s in slopes:
            e["end_point_slope_urad"] = slopes[s] * 1e6
        out[s] = e
    return out


def tables_json(res: VolumetricResult, unc: VolumetricUncertainty | None = None, slopes: dict | None = None) -> str:
    """Compensation tables for a controller with volumetric compensation (JSON text, ``vmt-comp/1``).

    The format (README, "Compensation files"): ``format`` ``"vmt-comp/1"``,
    ``chain`` (ISO 10791), ``sign_convention`` (ISO 230-1: every value is the
    tool's displacement relative to the workpiece, actual minus commanded),
    ``positions`` (the axis readings, stylus-tip centre in R, mm),
    ``interpolation``, ``extrapolation``, ``conventions`` (the gauge) and
    ``errors``: the 21 symbols, each with ``unit`` (um, urad), ``kind``,
    ``identified`` (values at ``nodes_mm``; one value for a squareness),
    ``u95`` / ``u95_lin`` when the uncertainty is given, and for a
    straightness ``end_point_slope_urad``: the table is reported against its
    end-point reference line (ISO 230-1); the error a controller corrects is
    ``identified + end_point_slope_urad * 1e-3 * (x_mm - nodes_mm[0])`` um
    (:func:`comp_tables`). ``res`` as reported (:func:`iso_view`), ``slopes``
    its straightness end-point slopes (:func:`end_point_slopes` of the
    identification).
    """
    doc = {"format": "vmt-comp/1", "chain": res.chain,
           "sign_convention": "ISO 230-1: each value is the tool's displacement relative to the workpiece "
                              "(actual minus commanded), whichever side of the bed the axis is on",
           "positions": "axis (joint) positions: the reading (stylus-tip centre) + the probe offsets J, in the machine frame R, mm",
           "rotary_points_mm": {a: [v * 1e3 for v in p] for a, p in (res.rotary_points_R_m or {}).items()},
           "conventions": list(res.design.gauge),
           "straightness_reference": "end-point straight line (slope in end_point_slope_urad)",
           "interpolation": "C2 cubic spline (not-a-knot) through the nodes",
           "extrapolation": "beyond the end nodes along the end tangent",
           "errors": report(res, unc, slopes=slopes)}
    return json.dumps(doc, indent=1)


def comp_tables(doc: dict, source: str = "vmt-comp/1") -> tuple[str, dict, dict, dict]:
    """The errors a controller corrects, from a ``vmt-comp/1`` document (SI).

    ``source`` names the document in every refusal (the file's path; review32d F1: the refusals named no
    file). Every value is bounded as a machine file's errors are (:data:`core.iso.MAX_LINEAR_UM`,
    :data:`core.iso.MAX_ANGULAR_URAD`): the identified values and, for a straightness, the table with its
    end-point line restored (what the controller corrects), each refusal naming the key.

    Returns
    -------
    chain : str
    tables : dict symbol -> ((k,) nodes m, (k,) values m or rad)
        The 18 motion errors; each straightness with its end-point line's
        slope restored (its constant is the gauge's: no artefact sees a
        constant shift). Each error (a squareness too) times its
        ``applied_factor`` (0 to 1, :mod:`core.comprule`; absent: 1).
    constants : dict symbol -> float
        The squarenesses, rad.
    rotary_points_R_m : dict axis -> (3,) float

    Raises
    ------
    ConfigError
        Not ``vmt-comp/1``, an error missing, a value not a number or beyond the bound, or tables of the
        wrong shape: one line naming ``source`` and the key.
    """
    def fail(msg):
        raise ConfigError(f"{source}: {msg}")

    def numbers(key, x):
        try:  # a string or a nested list in the file was a traceback (review32d F1)
            v = np.asarray(x, float)
        except (TypeError, ValueError):
            fail(f"{key} must be a number or a list of numbers, got {_short(x)}")
        if v.ndim > 1:
            fail(f"{key} must be a number or a list of numbers, got a nested list")
        return np.atleast_1d(v)

    if not isinstance(doc, dict) or doc.get("format") != "vmt-comp/1":
        fail("not a vmt-comp/1 document (format missing or other)")
    if "errors" not in doc:
        fail("'errors' missing")
    errs = doc["errors"]
    if not isinstance(errs, dict):
        fail(f"'errors' must be an object of the 21 errors by symbol, got {type(errs).__name__}")
    tables, const = {}, {}
    for s in MOTION + SQUARENESS:
        key = f"errors.{s}"
        if s not in errs:
            fail(f"{key} missing")
        e = errs[s]
        if not isinstance(e, dict):
            fail(f"{key} must be an object (identified, nodes_mm, ...), got {type(e).__name__}")
        if "identified" not in e:
            fail(f"{key}.identified missing")
        v = numbers(f"{key}.identified", e["identified"])
        sym = iso.symbol(s)
        U, bound = ("urad", iso.MAX_ANGULAR_URAD) if sym.angular else ("um", iso.MAX_LINEAR_UM)
        f = e.get("applied_factor", 1.0)  # absent: applied whole (files before session 26)
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not 0.0 <= f <= 1.0:
            fail(f"{key}.applied_factor must be a number from 0 to 1, got {f!r}")
        if s in SQUARENESS:
            if v.shape != (1,) or not np.isfinite(v).all():
                fail(f"{key}.identified must be one finite value")
        else:
            x = numbers(f"{key}.nodes_mm", e.get("nodes_mm", []))
            if x.shape != v.shape or len(x) < 1 or not (np.isfinite(x).all() and np.isfinite(v).all()):
                fail(f"{key}: nodes_mm and identified must be equal-length finite lists")
            if np.any(np.diff(x) <= 0):
                fail(f"{key}.nodes_mm must be strictly increasing")
        _within(fail, f"{key}.identified", v, U, bound)
        v_si = v * 1e-6 * float(f)  # the fraction of the identified error the controller corrects (core.comprule)
        if s in SQUARENESS:
            const[s] = float(v_si[0])
            continue
        x_si = x * 1e-3
        if "end_point_slope_urad" in e:
            k = numbers(f"{key}.end_point_slope_urad", e["end_point_slope_urad"])
            if k.shape != (1,) or not np.isfinite(k).all():
                fail(f"{key}.end_point_slope_urad must be one finite value")
            _within(fail, f"{key}.end_point_slope_urad", v + float(k[0]) * 1e-3 * (x - x[0]), U, bound,
                    " (the table with its end-point line restored)")
            v_si = v_si + float(f) * float(k[0]) * 1e-6 * (x_si - x_si[0])
        tables[s] = (x_si, v_si)
    pts = doc.get("rotary_points_mm") or {}
    if not isinstance(pts, dict):
        fail(f"rotary_points_mm must be an object axis -> [x, y, z] mm, got {type(pts).__name__}")
    out = {}
    for a, p in pts.items():
        q = numbers(f"rotary_points_mm.{a}", p)
        if q.shape != (3,) or not np.isfinite(q).all():
            fail(f"rotary_points_mm.{a} must be three finite numbers (mm)")
        out[a] = tuple(float(c) * 1e-3 for c in q)
    return str(doc.get("chain", "")), tables, const, out


def _short(x) -> str:
    r = repr(x)
    return r if len(r) <= 40 else r[:37] + "..."


def _within(fail, key, v, U, bound, what="") -> None:
    """Refuse values beyond +-``bound`` (the machine file's, core.iso), naming the key and the peak."""
    i = int(np.argmax(np.abs(v)))
    if abs(v[i]) > bound * (1 + 1e-9):
        fail(f"{key} reaches {v[i]:.6g} {U}{what}: beyond the +-{bound:g} {U} a compensation table's error "
             f"may have (as a machine file's: core.iso.MAX_{'ANGULAR_URAD' if U == 'urad' else 'LINEAR_UM'})")


# --------------------------------------------------------------------------- lack of fit (session 29)
#: The lack-of-fit test's level (:func:`lack_of_fit`): residuals whose sum of squares the inputs'
#: noise model gives a probability below this are reported as a model that does not fit (the tables
#: miss structure between or beyond their nodes, and the U95, which propagates only those inputs,
#: may under-cover). Set in session 29 (docs/papers-mfb.md, "Residuals against the noise model").
LACK_OF_FIT_P = 1e-3


def _noise_inputs(who: str, sigma_probe_m, u_cal_m, u_place) -> tuple[np.ndarray, np.ndarray]:
    """The residual tests' inputs checked (a bad one refused in one line naming ``who``): the probing sigma,
    the bar calibration's (N, 3) u and the placements' six u (None: none); returns (u_cal, u_place)."""
    if not (np.isfinite(sigma_probe_m) and sigma_probe_m >= 0):
        raise ConfigError(f"{who}: sigma_probe_m must be >= 0, got {sigma_probe_m!r}")
    u_cal = np.asarray(u_cal_m, float)
    if u_cal.ndim != 2 or u_cal.shape[1] != 3 or not np.all(np.isfinite(u_cal)):
        raise ConfigError(f"{who}: u_cal_m must be finite (N, 3), got {u_cal.shape}")
    up = np.zeros(6) if u_place is None else np.asarray(u_place, float)
    if up.shape != (6,) or not np.all(np.isfinite(up)) or np.any(up < 0):
        raise ConfigError(f"{who}: u_place must be 6 finite values >= 0, got {u_place!r}")
    return u_cal, up


@dataclass(frozen=True)
class LackOfFit:
    """The identification's residuals against what its inputs' noise alone would leave (:func:`lack_of_fit`).

    Attributes
    ----------
    rms_m : float
        RMS of the residuals of (1) at the solution, m.
    expected_rms_m : float
        Their RMS expected from the inputs (probing noise, bar calibration, placements), m.
    dof : float
        Satterthwaite's effective degrees of freedom of the sum of squares.
    p : float
        Probability of a sum of squares at least this large under the noise model.
    fits : bool
        ``p >= LACK_OF_FIT_P``.
    ratio : float
        The tested residuals' RMS over their probing-noise expectation (1 when the model fits).
    """

    rms_m: float
    expected_rms_m: float
    dof: float
    p: float
    fits: bool
    ratio: float

    def as_dict(self) -> dict:
        return {"rms_um": self.rms_m * 1e6, "expected_rms_um": self.expected_rms_m * 1e6,
                "tested_ratio": self.ratio, "dof": self.dof, "p": self.p, "level": LACK_OF_FIT_P,
                "fits": self.fits}


@dataclass(frozen=True)
class _ResidualNoise:
    """The residuals of an MFB identification and their noise model (:func:`_residual_noise`)."""

    prep: list          # the measurements' prepared rows (_prepare_all)
    r: np.ndarray       # (m,) residuals at the solution
    R: np.ndarray       # (m, m) d residual / d rows, I - J K
    Sp: np.ndarray      # (m, m) the probing noise's covariance of the rows (the shifted holes without z_A)
    RLc: np.ndarray     # (m, c) the bar calibration's and the placements' columns through R
    rp: np.ndarray      # r with the calibration/placement directions taken out
    Rp: np.ndarray      # R likewise
    Mp: np.ndarray      # Rp Sp Rp^T: what the probing noise alone leaves in rp
    of: tuple = ()      # (res, measurements, sigma_probe_m, u_cal, u_place, cal_map) it was computed for
    cache: dict = field(default_factory=dict, compare=False)  # _fine_kinematics, once for its users


def residual_noise(res: VolumetricResult, meas, sigma_probe_m: float, u_cal_m, u_place=None, *,
                   cal_map=None) -> _ResidualNoise:
    """The residuals' first-order noise model (:func:`_residual_noise`), to compute once and pass as ``noise=``
    to :func:`lack_of_fit`, :func:`model_error_share` and :func:`between_nodes_fit` with the same arguments
    (each computes it otherwise: the same numbers; session 34, the MFB run computed it two or three times).

    Raises
    ------
    ConfigError
        ``sigma_probe_m`` negative or not finite; ``u_cal_m`` not (N, 3); ``u_place`` not 6 values >= 0.
    """
    u_cal, up = _noise_inputs("residual_noise", sigma_probe_m, u_cal_m, u_place)
    return _residual_noise(res, list(meas), sigma_probe_m, u_cal, up, cal_map)


def _noise_of(who: str, noise: _ResidualNoise | None, res: VolumetricResult, meas: list, sigma_probe_m: float,
              u_cal: np.ndarray, up: np.ndarray, cal_map) -> _ResidualNoise:
    """``noise`` (:func:`residual_noise`) when it was computed for these inputs, else refused by ``who``;
    computed here when None."""
    if noise is None:
        return _residual_noise(res, meas, sigma_probe_m, u_cal, up, cal_map)
    o = noise.of
    if not (len(o) == 6 and o[0] is res and len(o[1]) == len(meas) and all(a is b for a, b in zip(o[1], meas))
            and o[2] == sigma_probe_m and np.array_equal(o[3], u_cal) and np.array_equal(o[4], up)
            and o[5] is cal_map):
        raise ConfigError(f"{who}: noise was computed for other inputs (residual_noise of the same result, "
                          "measurements, sigma_probe_m, u_cal_m, u_place and cal_map)")
    return noise


def _kinematics_of(res: VolumetricResult, nm: _ResidualNoise) -> dict:
    """:func:`_fine_kinematics` of ``nm``'s measurements, computed once for every user of ``nm``."""
    if "kin" not in nm.cache:
        nm.cache["kin"] = _fine_kinematics(res, nm.prep)
    return nm.cache["kin"]


def _residual_noise(res: VolumetricResult, meas: list, sigma_probe_m: float, u_cal: np.ndarray, up: np.ndarray,
                    cal_map) -> _ResidualNoise:
    """The residuals' first-order noise model, shared by :func:`lack_of_fit`, :func:`model_error_share` and
    :func:`between_nodes_fit` (:func:`residual_noise`: once for the three): the
    residuals are ``(I - J K) e`` of the inputs' errors ``e``; the probing noise through each measurement's
    extraction gain, the bar calibration through its rods' map and the placements give their covariance. The bar
    calibration and the placements move the residuals along a few directions (the bar's 36 deviations, 6 per
    placement), the same in every measurement: those are taken out (``rp``, ``Rp``, ``Mp``), so what is left is
    tested against the probing noise alone, over the many directions it spreads on (with them in, the
    calibration's few directions set the distribution: ~20 degrees of freedom, little power)."""
    d = res.design
    prep = _prepare_all(meas, res.chain, res.rotary_points_R_m, d.nodes)
    if res.iterations:
        J, r, _ = _rows(meas, res.chain, res.rotary_points_R_m, d.nodes, res.theta, d.slices, len(res.theta),
                        exact=True, prep=prep, extraction=res.extraction)
    else:
        J, r = d.A, d.y - d.A @ res.theta
    blocks, B, Bp = _input_maps(res, meas, u_cal.shape[0])
    m = len(r)
    Sp = np.zeros((m, m))  # the probing noise's covariance of the rows, block by measurement
    for r0, GR in blocks:
        Sp[r0:r0 + GR.shape[0], r0:r0 + GR.shape[0]] = sigma_probe_m ** 2 * (GR @ GR.T)
    Lc = np.hstack([_cal_columns(np.eye(m), B, u_cal, cal_map), Bp * np.tile(up, Bp.shape[1] // 6)[None, :]])
    Pz = np.eye(m)  # the rows of the shifted holes without z_A, as _rows gives the residuals
    r0 = 0
    for pm in prep:
        for h in np.flatnonzero(pm["off"]):
            Pz[r0 + 3 * h:r0 + 3 * h + 3, r0 + 3 * h:r0 + 3 * h + 3] = pm["Pz"]
        r0 += 3 * pm["k"]
    Sp = Pz @ Sp @ Pz.T
    R = np.eye(m) - J @ res.K
    RLc = R @ (Pz @ Lc)
    U, sv, _ = np.linalg.svd(RLc, full_matrices=False)
    U = U[:, sv > sv[0] * 1e-9] if len(sv) and sv[0] > 0 else U[:, :0]
    Rp = R - U @ (U.T @ R)
    return _ResidualNoise(prep, r, R, Sp, RLc, r - U @ (U.T @ r), Rp, Rp @ Sp @ Rp.T,
                          (res, tuple(meas), sigma_probe_m, u_cal, up, cal_map))


def lack_of_fit(res: VolumetricResult, meas, sigma_probe_m: float, u_cal_m, u_place=None, *,
                cal_map=None, noise: _ResidualNoise | None = None) -> LackOfFit | None:
    """Lack-of-fit test of an MFB identification: its residuals against the probing noise and the other inputs.

    The residuals ``r`` of (1) at the solution (``res`` as identified, :func:`identify_volumetric`) are, to
    first order, ``(I - J K) e`` of the inputs' errors ``e`` (``J`` the rows' Jacobian at the solution,
    ``K`` = ``res.K``): with the inputs' covariance ``L L^T`` (probing noise ``sigma_probe_m`` through each
    measurement's extraction gain, the bar calibration ``u_cal_m`` through ``cal_map``, the placements
    ``u_place``: :func:`covariance`'s maps, the holes' z_A rows dropped as the identification drops them),
    ``M = (I - J K) L L^T (I - J K)^T`` is the residuals' covariance, and ``r.r`` a sum of squares of mean
    ``tr M``, taken as ``c chi2(nu)`` (Satterthwaite: ``c = tr M^2 / tr M``, ``nu = (tr M)^2 / tr M^2``).
    A model that does not hold (an error with structure its tables cannot follow: a wave shorter than
    a few node spacings, a table run beyond its nodes) leaves more: ``p`` small. The U95 propagates
    only these inputs, so a model that does not fit may under-cover (review29b F2). The same moment
    reasoning as the self-calibration's :func:`core.uncertainty.model_error_budget` (its probing-noise
    expectation of ``r.r``), for the MFB's correlated inputs.

    Returns None when the inputs leave no residual variance (noise-free and nothing drawn: nothing to
    test against). ``noise``: :func:`residual_noise` of the same arguments (computed here when None).

    Raises
    ------
    ConfigError
        ``sigma_probe_m`` negative or not finite; ``u_cal_m`` not (N, 3); ``u_place`` not 6 values >= 0;
        ``noise`` computed for other inputs.
    """
    u_cal, up = _noise_inputs("lack_of_fit", sigma_probe_m, u_cal_m, u_place)
    nm = _noise_of("lack_of_fit", noise, res, list(meas), sigma_probe_m, u_cal, up, cal_map)
    r, R, Sp, RLc, rp, Mp = nm.r, nm.R, nm.Sp, nm.RLc, nm.rp, nm.Mp
    t_all = float(np.sum((R @ Sp) * R) + np.sum(RLc * RLc))  # tr M
    t1, t2 = float(np.trace(Mp)), float(np.sum(Mp * Mp))
    if not (t1 > 0 and t2 > 0 and t_all > 0):
        return None
    q = float(rp @ rp)
    nu = t1 * t1 / t2
    p = _satterthwaite_sf(q, t1, t2)
    return LackOfFit(float(np.sqrt(r @ r / len(r))), float(np.sqrt(t_all / len(r))), float(nu), p,
                     p >= LACK_OF_FIT_P, float(np.sqrt(q / t1)))


# --------------------------------------------------------------------------- model-error share (session 29)
#: Step of the fine tables that stand for what the MFB's tables cannot follow (:func:`model_error_share`), m:
#: :data:`core.uncertainty.MODEL_ERROR_STEP_M`'s 1 mm.
MFB_MODEL_ERROR_STEP_M = 1.0e-3
#: A table's model-error component enters the MFB's U95 when its residual statistic exceeds what the probing
#: noise alone gives by this many standard deviations (:data:`core.uncertainty.MODEL_ERROR_Z`'s rule). A
#: quadratic form of few effective degrees of freedom (1.4-8.8 on the plans' tables): on the noise-only first-
#: order null (session 30, small30; 600 draws x 18 tables each) z > 3 enters 1.56 % of the 5-axis plan's
#: tables (Mikron, errors none) and 1.97 % of the 3-axis plan's, not a normal's 0.135 % (docs/papers-mfb.md
#: "The share's gate on noise alone (session 30)"); the share is off and gated by the lack-of-fit test.
MFB_MODEL_ERROR_Z = 3.0
#: The exact gate's level (``p``: the statistic's tail probability under the probing noise alone, the weights
#: of ``W_T^T Mp W_T``, :func:`core.lsq.quadratic_form_sf`), used when :data:`MFB_MODEL_ERROR_EXACT_GATE`:
#: :data:`core.uncertainty.MODEL_ERROR_P`. On the draws above it enters 0.07 % and 0.19 %.
MFB_MODEL_ERROR_P = 1.3498980316300946e-3
#: Gate the MFB's shares on ``p < MFB_MODEL_ERROR_P`` instead of ``z > MFB_MODEL_ERROR_Z``: OFF, as the
#: self-calibration's (:data:`core.uncertainty.MODEL_ERROR_EXACT_GATE`: model error in several tables dilutes
#: each one's test there; not measured on the MFB's truths).
MFB_MODEL_ERROR_EXACT_GATE = False
#: The residual tests' exact tails (:func:`core.lsq.quadratic_form_sf`; Imhof's quadrature 10-80 ms each, 19 per
#: noisy run, a quarter of the share's CPU; the saddlepoint contour since session 36, 3-10 ms) only where one could
#: change a decision (session 35, mfb35): a tail
#: whose rigorous lower bound (:func:`_tail_lower_bound`) is at or above the level cannot fall below it, whatever
#: the exact value, so the decision is the exact tail's; where also Satterthwaite's scaled chi-square is at least
#: :data:`EXACT_TAIL_FACTOR` x the level, that approximate ``p`` is reported, labelled (JSON ``model_error.p_approx``:
#: the tables whose p it is; ``between_nodes.p_approx``). The levels: :data:`MFB_MODEL_ERROR_P` for the share's
#: tables (the exact gate's, also when that gate is off: then ``p`` decides nothing), :data:`BETWEEN_NODES_P` over
#: the intervals tested for the between-node test. The MFB run asks every table's exact tail where the lack-of-fit
#: gate opens (its shares reported with their p). docs/papers-mfb.md, "The residual tests' cost, and the exact
#: tails where they decide (session 35)".
#: OFF since session 37 (tail37): every residual test's p is the exact tail. On the contour the 19 tails of a run
#: cost 0.12 s CPU (median; 0.08-0.18 over mfb-3axis and mfb-5axis seeds 1-6), a default run 1.54 s against 1.39
#: with the rule (median of 14 alternating runs each, seeds 1-2, load ~17), and the rule's labelled approximations
#: were up to 17 % off the exact share p (median 5 %) and 63 % off the between-node p (0.00067 for 0.00108) on those
#: 12 runs; no decision moves either way (the rule's bound). docs/papers-mfb.md, "The exact tails everywhere
#: (session 37)".
EXACT_TAIL_NEAR_LEVEL = False
#: Satterthwaite's p at least this many times the level before it stands in for the exact tail
#: (:data:`EXACT_TAIL_NEAR_LEVEL`): the approximate p reported is then far from the level, and on the side the
#: decision (the lower bound's) took.
EXACT_TAIL_FACTOR = 10.0


def _chi2_sf(x, df):
    """``scipy.stats.chi2.sf(x, df)`` bit for bit, without importing scipy.stats (session 38: 0.5 s of CPU of a
    ``vmt scenario mfb-*`` process, which used nothing else of it): its tail is ``scipy.special.chdtrc(df, x)``
    (``chi2._sf``), and its wrapper's rules kept: 1 at ``x <= 0`` (the support's lower end), 0 at ``x = inf``,
    NaN where ``df <= 0`` or ``x`` is NaN (tests/core/test_volumetric_mfbfast38.py checks them against scipy.stats).
    A float for scalar inputs, else an array."""
    from scipy.special import chdtrc

    x, df = np.asarray(x, float), np.asarray(df, float)
    xb, dfb = np.broadcast_arrays(x, df)
    inside = (xb > 0) & (xb < np.inf) & (dfb > 0)
    out = np.where(xb <= 0, 1.0, 0.0)
    out[inside] = chdtrc(dfb[inside], xb[inside])
    out[~(dfb > 0) | np.isnan(xb)] = np.nan
    return float(out) if out.ndim == 0 else out


def _satterthwaite_sf(q: float, t1: float, t2: float) -> float:
    """Satterthwaite's tail of a quadratic form ``sum_j lam_j Z_j^2`` at ``q``: the scaled chi-square ``c chi2_nu``
    with the form's mean ``t1 = sum lam`` and ``t2 = sum lam^2`` (``c = t2 / t1``, ``nu = t1^2 / t2``), as the
    lack-of-fit test, the model-error share and the between-node test take it."""
    return float(_chi2_sf(q / (t2 / t1), t1 * t1 / t2))


def _tail_lower_bound(lam: np.ndarray, x: float) -> float:
    """A rigorous lower bound of ``P(sum_j lam_j Z_j^2 > x)`` (weights ``lam`` >= 0, ``Z_j`` independent standard
    normals): for each ``k`` the ``k`` largest weights are each at least the ``k``-th largest ``l_k`` and the others
    add a non-negative amount, so ``P >= P(l_k chi2_k > x)``; the largest of these over ``k``."""
    lam = np.sort(np.asarray(lam, float))[::-1]
    lam = lam[lam > 0]
    if not lam.size:
        return 1.0 if x < 0 else 0.0
    return float(np.max(_chi2_sf(x / lam, np.arange(1, lam.size + 1))))


def _tail(lam: np.ndarray, x: float, p_sat: float, level: float, exact: bool = False) -> tuple[float, bool]:
    """(p, approximate): the tail ``P(sum_j lam_j Z_j^2 > x)`` of a residual test (weights ``lam`` > 0, at least
    two), exact (:func:`core.lsq.quadratic_form_sf`: x > 0 here, so on the contour through the saddlepoint,
    :data:`core.lsq.QF_SADDLE_CONTOUR`; Imhof's quadrature until session 36) unless :data:`EXACT_TAIL_NEAR_LEVEL`
    and neither it nor its decision against ``level``
    can differ from what Satterthwaite's ``p_sat`` says: ``p_sat >= EXACT_TAIL_FACTOR * level`` and the rigorous
    lower bound :func:`_tail_lower_bound` ``>= level`` (the exact tail is then at or above the level). ``exact``:
    exact whatever the constant.

    The exact tail is never below the rigorous lower bound (session 35): Imhof's quadrature loses its accuracy when
    one weight dominates (the integrand then decays as for one degree of freedom): with weights (1, 1e-3, 1e-3) at
    x = 30 it returns 0 where the tail is at least chi2_1's 4.3e-8, which would reject a test at any level (mfb35:
    3 of 969 weight sets of real runs at the between-node test's per-interval level). Since session 36 the exact
    tail is the saddlepoint contour's (:data:`core.lsq.QF_SADDLE_CONTOUR`: relative error about 1e-14 there),
    which the bound no longer binds but at rounding; it stays for Imhof's quadrature (the contour off, or its
    fallback; docs/papers-mfb.md)."""
    from .lsq import quadratic_form_sf

    low = _tail_lower_bound(lam, x)
    if EXACT_TAIL_NEAR_LEVEL and not exact and p_sat >= EXACT_TAIL_FACTOR * level and low >= level:
        return float(p_sat), True
    return max(quadratic_form_sf(lam, x), low), False


@dataclass(frozen=True)
class ModelErrorShare:
    """What the residuals show the tables miss, per motion table (:func:`model_error_share`).

    Attributes
    ----------
    u : dict
        symbol -> the fine table's estimated standard deviation (m or rad; 0 when it did not enter).
    z : dict
        symbol -> its statistic's excess over the probing noise's expectation, in standard deviations.
    entered : tuple
        The symbols whose share entered (past the gate, z or p, and a positive variance).
    p : dict or None
        symbol -> its statistic's exact tail probability under the probing noise alone (the gate,
        :data:`MFB_MODEL_ERROR_P`).
    columns : (n, c) float
        The estimate's error from the entered shares, ``cov = C C^T`` (the design's gauge); (n, 0) when none.
    p_approx : tuple
        The symbols whose ``p`` is Satterthwaite's approximation, not the exact tail (:data:`EXACT_TAIL_NEAR_LEVEL`:
        their exact tail is provably at or above :data:`MFB_MODEL_ERROR_P`).
    """

    u: dict
    z: dict
    entered: tuple
    columns: np.ndarray
    p: dict | None = None
    p_approx: tuple = ()

    def as_dict(self) -> dict:
        def unit(s):
            return "urad" if iso.symbol(s).angular else "um"

        return {"entered": list(self.entered), "step_mm": MFB_MODEL_ERROR_STEP_M * 1e3,
                "gate": (f"p < {MFB_MODEL_ERROR_P:.3g}" if MFB_MODEL_ERROR_EXACT_GATE else f"z > {MFB_MODEL_ERROR_Z:g}"),
                "z_min": MFB_MODEL_ERROR_Z,
                "u": {s: {"u_" + unit(s): self.u[s] * 1e6, "z": self.z[s],
                          "p": None if self.p is None else self.p[s], "p_approx": s in self.p_approx}
                      for s in self.entered},
                "z": {s: round(float(v), 2) for s, v in self.z.items()},
                "p": None if self.p is None else {s: float(f"{v:.3g}") for s, v in self.p.items()},
                "p_approx": list(self.p_approx)}


def _fine_kinematics(res: VolumetricResult, prep) -> dict:
    """What :func:`_fine_rows` needs of the chain, the same for every table: the touches' sensitivity
    along their approach (t_all, 21) and each measurement's first touch in them (:func:`_touch_kinematics`),
    and the sensitivity of each measurement without touches (its index -> (k, 3, 21)). Computed once for
    the 18 tables (they were computed once per table before session 34: the same numbers, 18 times)."""
    out = {"Sd": None, "at": {}, "S": {}}
    if prep.batch is not None:
        St, _, at = _touch_kinematics(prep, None, res.design.slices, False, True)
        out["Sd"], out["at"] = np.einsum("tj,tjs->ts", prep.batch["d_W"], St), at
    for i, pm in enumerate(prep):
        if not pm["touches"]:
            out["S"][i] = sensitivity(pm["g"], pm["q"], pm["rot"], None, symbols=MOTION + SQUARENESS)
    return out


def _fine_grid(res: VolumetricResult, prep, symbol: str, step_m: float) -> tuple:
    """(lo, h, f, xs): ``symbol``'s fine table of :func:`_fine_rows`, hat functions ``h`` (about ``step_m``) apart from
    ``lo`` (f + 1 of them) over the axis positions the touches (``xs``, per measurement) and the nodes span."""
    ax = iso.LINEAR_AXES.index(iso.symbol(symbol).axis)
    x_n = np.asarray(res.design.nodes[iso.symbol(symbol).axis], float)
    xs = [pm["qt"][:, ax] + pm["g"].J_m[ax] if pm["touches"] else pm["q"][:, ax] + pm["g"].J_m[ax] for pm in prep]
    lo = min(float(x_n.min()), *(float(x.min()) for x in xs))
    hi = max(float(x_n.max()), *(float(x.max()) for x in xs))
    f = max(int(np.ceil((hi - lo) / step_m - 1e-9)), 1)
    return lo, (hi - lo) / f, f, xs


def _hat(x, lo: float, h: float, f: int) -> np.ndarray:
    """(len(x), f + 1): the fine table's hat functions (:func:`_fine_grid`) at the axis positions ``x``."""
    k = np.clip(np.floor((x - lo) / h).astype(int), 0, f - 1)
    z = (x - lo) / h - k
    W = np.zeros((len(x), f + 1))
    r = np.arange(len(x))  # one entry a row in each sum: the += of np.add.at's, without its slow loop (session 38)
    W[r, k] += 1 - z
    W[r, k + 1] += z
    return W


def _fine_values(res: VolumetricResult, prep, symbol: str, step_m: float) -> np.ndarray:
    """(n, f + 1): ``symbol``'s fine table (:func:`_fine_grid`) at its nodes, in the design's gauge (the S of
    :func:`_fine_rows`; session 35: computed only for the tables whose share enters)."""
    d = res.design
    lo, h, f, _ = _fine_grid(res, prep, symbol, step_m)
    S = np.zeros((len(d.names), f + 1))
    S[d.slices[symbol]] = _hat(np.asarray(d.nodes[iso.symbol(symbol).axis], float), lo, h, f)
    if d.C.shape[0]:  # Design.to_gauge of every column at once (one least-squares solve, f + 1 right-hand sides)
        S = S + d.null @ np.linalg.lstsq(d.C @ d.null, -d.C @ S, rcond=None)[0]
    return S


def _fine_rows(res: VolumetricResult, meas, prep, symbol: str, step_m: float, kin: dict | None = None,
               centres: bool = False, values: bool = True):
    """(Phi (m, f), S (n, f)): a fine table of ``symbol`` (hat functions ``step_m`` apart over the axis
    positions the touches and the nodes span) as the rows of (1) see it (as :func:`ripple_columns` carries a
    function of the axis position: each touch's sensitivity along its approach, the extraction's gain, the
    shifted holes without z_A), and its values at ``symbol``'s nodes in the design's gauge. ``kin``:
    :func:`_fine_kinematics` of ``prep`` (computed here when not given); ``centres``: also the hat functions'
    centres (f,) m, axis positions (a third value); ``values`` False: S is None (not computed: a caller that
    does not use it, :func:`between_nodes_fit`)."""
    ks = MOTION.index(symbol)
    kin = _fine_kinematics(res, prep) if kin is None else kin
    at = kin["at"]
    Sd = None if kin["Sd"] is None else kin["Sd"][:, ks]
    lo, h, f, xs = _fine_grid(res, prep, symbol, step_m)
    Phi = np.zeros((res.K.shape[1], f + 1))
    r0 = 0
    for i, (pm, x) in enumerate(zip(prep, xs)):
        k = pm["k"]
        H = _hat(x, lo, h, f)
        if pm["touches"]:
            t = len(x)
            dy = (pm["GW"].reshape(3 * k, t) @ (Sd[at[i]:at[i] + t, None] * H)).reshape(k, 3, f + 1)
        else:
            S = kin["S"][i][:, :, ks]
            dy = S[:, :, None] * H[:, None, :]
        dy[pm["off"]] = np.einsum("ij,kjf->kif", pm["Pz"], dy[pm["off"]])
        Phi[r0:r0 + 3 * k] = dy.reshape(3 * k, f + 1)
        r0 += 3 * k
    S = _fine_values(res, prep, symbol, step_m) if values else None
    return (Phi, S, lo + h * np.arange(f + 1)) if centres else (Phi, S)


def _fine_of(res: VolumetricResult, meas, nm: _ResidualNoise, symbol: str, step_m: float) -> tuple:
    """(Phi, centres, Rp Phi) of ``symbol``'s fine table (:func:`_fine_rows`, without the node values), computed
    once per noise model for :func:`model_error_share` and :func:`between_nodes_fit` (session 35: the between-node
    test made the 18 tables' rows and ``Rp Phi`` again after the share, the same numbers; ~0.2 s a 3-axis run)."""
    key = ("fine", symbol, step_m)
    if key not in nm.cache:
        Phi, _, c = _fine_rows(res, meas, nm.prep, symbol, step_m, _kinematics_of(res, nm), centres=True,
                               values=False)
        nm.cache[key] = (Phi, c, nm.Rp @ Phi)
    return nm.cache[key]


def model_error_share(res: VolumetricResult, meas, sigma_probe_m: float, u_cal_m, u_place=None, *,
                      cal_map=None, step_m: float = MFB_MODEL_ERROR_STEP_M,
                      z_min: float = MFB_MODEL_ERROR_Z, exact_p: bool = True, all_exact: bool = False,
                      noise: _ResidualNoise | None = None) -> ModelErrorShare | None:
    """The MFB's model-error share: per motion table, a fine table the residuals show the tables miss.

    :func:`core.uncertainty.model_error_budget`'s way for the MFB's correlated inputs: each motion table
    ``T`` gets a fine table ``e_T`` (hat functions ``step_m`` apart, independent values of variance
    ``s_T^2``) seen by the rows of (1) as ``Phi_T e_T`` (:func:`_fine_rows`); the estimate's error moves by
    ``G_T e_T``, ``G_T = K Phi_T - S_T`` (``S_T`` its node values, the measurand's share the tables do not
    follow, in the design's gauge). The residuals, with the bar calibration's and the placements' few
    directions projected out as :func:`lack_of_fit` does (``rp = P r``, ``Rp = P (I - J K)``), are
    ``Rp (sum_T Phi_T e_T + noise)``; with ``W_T = Rp Phi_T`` the statistic ``q_T = |W_T^T rp|^2`` has the
    probing noise's expectation ``tr(W_T^T Mp W_T)`` (``Mp`` the projected residuals' probing-noise
    covariance) and variance ``2 |W_T^T Mp W_T|_F^2`` (``z``: the excess in standard deviations); under
    the probing noise alone ``q_T`` is a quadratic form with the eigenvalues of ``W_T^T Mp W_T`` as weights,
    its exact tail probability ``p`` (:func:`core.lsq.quadratic_form_sf`); a table enters when ``z >
    z_min`` (or ``p`` below :data:`MFB_MODEL_ERROR_P` with :data:`MFB_MODEL_ERROR_EXACT_GATE`), and the
    entered tables' ``s_T^2`` solve the moment equations ``q_T -
    tr(W_T^T Mp W_T) = sum_U s_U^2 |W_T^T W_U|_F^2`` non-negative (the probing noise known).

    ``exact_p`` False (and :data:`MFB_MODEL_ERROR_EXACT_GATE` off, so the gate is z): ``p`` is not computed
    (None; about half the function's CPU, 18 numerical integrations), for a caller that keeps only the
    columns (the budget study's runs, :func:`scenarios.mfb.budget_run`); the shares are the same. With
    :data:`EXACT_TAIL_NEAR_LEVEL` (session 35) a table's ``p`` is Satterthwaite's where its exact tail provably
    cannot fall below :data:`MFB_MODEL_ERROR_P` (:func:`_tail`; ``p_approx`` names those tables); ``all_exact``:
    every table's exact (the MFB run asks it when the lack-of-fit gate opens).

    Returns None when there is no probing noise to test against (``sigma_probe_m`` 0). ``noise``:
    :func:`residual_noise` of the same arguments (computed here when None).

    Raises
    ------
    ConfigError
        ``sigma_probe_m`` negative or not finite; ``u_cal_m`` not (N, 3); ``u_place`` not 6 values >= 0;
        ``step_m`` not > 0; ``z_min`` not finite; ``noise`` computed for other inputs.
    """
    from scipy.optimize import nnls

    u_cal, up = _noise_inputs("model_error_share", sigma_probe_m, u_cal_m, u_place)
    if not (np.isfinite(step_m) and step_m > 0):
        raise ConfigError(f"model_error_share: step_m must be > 0, got {step_m!r}")
    if not np.isfinite(z_min):
        raise ConfigError(f"model_error_share: z_min must be finite, got {z_min!r}")
    if sigma_probe_m == 0:
        return None
    meas = list(meas)
    nm = _noise_of("model_error_share", noise, res, meas, sigma_probe_m, u_cal, up, cal_map)
    prep, rp, Rp, Mp = nm.prep, nm.rp, nm.Rp, nm.Mp
    syms = list(MOTION)
    fine = [_fine_of(res, meas, nm, s, step_m) for s in syms]  # (Phi, centres, Rp Phi), shared with between_nodes_fit
    Ws = []  # each W_T compressed to its column space (m, rank): W_T W_T^T unchanged
    # every W_T lies in Rp's column space (an orthonormal Q, one SVD): each W_T's SVD is Q times that of the
    # much shorter Q^T W_T (the same singular values and vectors to rounding; session 34, 2-4 x less CPU)
    Uq, sq, _ = np.linalg.svd(Rp, full_matrices=False)
    Q = Uq[:, sq > (sq[0] * 1e-12 if len(sq) and sq[0] > 0 else np.inf)]
    for _, _, RPhi in fine:
        Uw, sw, _ = np.linalg.svd(Q.T @ RPhi, full_matrices=False)
        keep = sw > (sw[0] * 1e-10 if len(sw) and sw[0] > 0 else np.inf)
        Ws.append(Q @ (Uw[:, keep] * sw[keep]))
    q = np.array([float(np.sum((W.T @ rp) ** 2)) for W in Ws])
    WM = [W.T @ Mp @ W for W in Ws]
    e0 = np.array([float(np.trace(a)) for a in WM])
    v0 = np.array([2.0 * float(np.sum(a * a)) for a in WM])
    z = np.where(v0 > 0, (q - e0) / np.sqrt(np.where(v0 > 0, v0, 1.0)), 0.0)
    pv = np.ones(len(syms))
    approx = []  # the tables whose p is Satterthwaite's (EXACT_TAIL_NEAR_LEVEL: their exact tail >= the level)
    exact_p = exact_p or MFB_MODEL_ERROR_EXACT_GATE
    for k, (a, qk) in enumerate(zip(WM, q) if exact_p else ()):
        lam = np.linalg.eigvalsh(a) if a.size else np.zeros(0)
        lam = lam[lam > (lam.max() * 1e-12 if lam.size and lam.max() > 0 else np.inf)]
        if lam.size >= 2:
            t1, t2 = float(lam.sum()), float(lam @ lam)
            pv[k], ap = _tail(lam, float(qk), _satterthwaite_sf(float(qk), t1, t2), MFB_MODEL_ERROR_P, all_exact)
            if ap:
                approx.append(syms[k])
        elif lam.size:  # one direction: a scaled chi-square of 1 degree
            pv[k] = float(_chi2_sf(float(qk) / lam[0], 1))
    kept = np.flatnonzero(pv < MFB_MODEL_ERROR_P) if MFB_MODEL_ERROR_EXACT_GATE else np.flatnonzero(z > z_min)
    s2 = np.zeros(len(syms))
    if kept.size:
        X = np.array([[float(np.sum((Ws[a].T @ Ws[b]) ** 2)) for b in kept] for a in kept])
        scale = np.sqrt((X ** 2).sum(axis=0))
        sol, _ = nnls(X / scale, q[kept] - e0[kept])
        s2[kept] = sol / scale
    # the node values (in the gauge) of the entered tables only (session 35: all 18 were computed)
    cols = [np.sqrt(s2[k]) * (res.K @ fine[k][0] - _fine_values(res, prep, syms[k], step_m))
            for k in np.flatnonzero(s2 > 0)]
    C = np.hstack(cols) if cols else np.zeros((res.K.shape[0], 0))
    C[~np.any(res.K != 0, axis=1)] = 0.0  # the values the gauge fixes keep no uncertainty
    return ModelErrorShare({s: float(np.sqrt(v)) for s, v in zip(syms, s2)},
                           {s: float(v) for s, v in zip(syms, z)},
                           tuple(s for s, v in zip(syms, s2) if v > 0), C,
                           {s: float(v) for s, v in zip(syms, pv)} if exact_p else None,
                           tuple(approx))


# --------------------------------------------------------------------------- between the nodes (session 34)
#: The level of the between-node test (:func:`between_nodes_fit`): the smallest interval's p times the number of
#: intervals tested (Bonferroni), below this, says the residuals show structure between two nodes of a table
#: that its interpolation does not follow. :data:`LACK_OF_FIT_P`'s 1e-3: about one false note in a thousand
#: runs whose model holds, whatever the number of intervals.
BETWEEN_NODES_P = 1e-3


@dataclass(frozen=True)
class BetweenNodes:
    """The residuals between two nodes of a table against the probing noise (:func:`between_nodes_fit`).

    Attributes
    ----------
    symbol : str
        The table of the interval whose statistic is least likely under the probing noise.
    interval_m : (float, float)
        Its two nodes, m (axis positions).
    p : float
        That interval's tail probability under the probing noise (exact: :func:`core.lsq.quadratic_form_sf`'s
        saddlepoint contour, Imhof's quadrature until session 36; Satterthwaite's when ``p_approx``).
    p_family : float
        ``p`` times the number of intervals tested (at most 1): what the test compares with its level.
    intervals : int
        The intervals tested (every table's intervals between consecutive nodes that the touches see).
    fits : bool
        ``p_family >= BETWEEN_NODES_P``.
    ratio : float
        That interval's statistic over its probing-noise expectation (1 when the interpolation holds).
    p_approx : bool
        ``p`` is Satterthwaite's, not the exact tail (:data:`EXACT_TAIL_NEAR_LEVEL`: the exact one is provably
        at or above the level, so ``fits`` is its decision).
    """

    symbol: str
    interval_m: tuple
    p: float
    p_family: float
    intervals: int
    fits: bool
    ratio: float
    p_approx: bool = False

    def as_dict(self) -> dict:
        unit = "urad" if iso.symbol(self.symbol).angular else "um"
        return {"symbol": self.symbol, "interval_mm": [v * 1e3 for v in self.interval_m], "p": self.p,
                "p_family": self.p_family, "intervals": self.intervals, "level": BETWEEN_NODES_P,
                "fits": self.fits, "tested_ratio": self.ratio, "unit": unit, "p_approx": self.p_approx}


def between_nodes_fit(res: VolumetricResult, meas, sigma_probe_m: float, u_cal_m, u_place=None, *,
                      cal_map=None, step_m: float = MFB_MODEL_ERROR_STEP_M,
                      noise: _ResidualNoise | None = None) -> BetweenNodes | None:
    """Between-node test of an MFB identification (review33a F5): does a table miss structure between two of
    its nodes, where the map follows the tables' interpolation and the U95 (of the node values) says nothing?

    :func:`lack_of_fit` tests all residuals at once: a local error (a 2 um bump 10 mm wide between two nodes
    69 mm apart) moves few of them and is diluted (review33a: p 0.01-0.04, no note, the map off by 1.9-2.4 x
    the nodes' U95 there). Here each table's fine table (:func:`model_error_share`'s hat functions ``step_m``
    apart) is cut into the intervals between its consecutive nodes; an interval's hat functions ``Phi_k``
    give the residual directions an error there alone would move, ``W_k = Rp Phi_k`` (the bar calibration's
    and placements' directions projected out, as in :func:`lack_of_fit`), and ``q_k = |W_k^T rp|^2`` is a
    quadratic form of the probing noise with the eigenvalues of ``W_k^T Mp W_k`` as weights: its tail by
    Satterthwaite's scaled chi-square on every interval, then exactly (:func:`core.lsq.quadratic_form_sf`: on
    the contour through the saddlepoint since session 36, Imhof's quadrature before) on the smallest (with :data:`EXACT_TAIL_NEAR_LEVEL`, session 35: only
    where it could change the decision, :func:`_tail`; else Satterthwaite's, ``p_approx``). The test: that ``p``
    times the number of intervals (Bonferroni) against :data:`BETWEEN_NODES_P`.

    Returns None when there is no probing noise (``sigma_probe_m`` 0) or no interval the touches see.
    ``noise``: :func:`residual_noise` of the same arguments (computed here when None).

    Raises
    ------
    ConfigError
        ``sigma_probe_m`` negative or not finite; ``u_cal_m`` not (N, 3); ``u_place`` not 6 values >= 0;
        ``step_m`` not > 0; ``noise`` computed for other inputs.
    """
    u_cal, up = _noise_inputs("between_nodes_fit", sigma_probe_m, u_cal_m, u_place)
    if not (np.isfinite(step_m) and step_m > 0):
        raise ConfigError(f"between_nodes_fit: step_m must be > 0, got {step_m!r}")
    if sigma_probe_m == 0:
        return None
    meas = list(meas)
    nm = _noise_of("between_nodes_fit", noise, res, meas, sigma_probe_m, u_cal, up, cal_map)
    rp, Mp = nm.rp, nm.Mp
    d = res.design
    rows = []  # (p Satterthwaite, symbol, (x0, x1), q, A)
    for s in MOTION:
        x_n = np.asarray(d.nodes[iso.symbol(s).axis], float)
        if len(x_n) < 2:
            continue
        _, c, RPhi = _fine_of(res, meas, nm, s, step_m)  # the share's when it ran (nm.cache)
        for x0, x1 in zip(x_n[:-1], x_n[1:]):
            cols = (c > x0 + 1e-9) & (c < x1 - 1e-9)
            W = RPhi[:, cols]
            if not W.size or not np.any(W):
                continue
            A = W.T @ Mp @ W
            t1, t2 = float(np.trace(A)), float(np.sum(A * A))
            if not (t1 > 0 and t2 > 0):
                continue
            q = float(np.sum((W.T @ rp) ** 2))
            rows.append((_satterthwaite_sf(q, t1, t2), s, (float(x0), float(x1)), q, A, t1))
    if not rows:
        return None
    p0, s, iv, q, A, t1 = min(rows, key=lambda r: r[0])
    lam = np.linalg.eigvalsh(A)
    lam = lam[lam > lam.max() * 1e-12] if lam.size and lam.max() > 0 else lam[:0]
    n = len(rows)
    approx = False
    if lam.size >= 2:  # the level of one interval: pf = p n >= BETWEEN_NODES_P where p >= BETWEEN_NODES_P / n
        p, approx = _tail(lam, q, p0, BETWEEN_NODES_P / n)
    elif lam.size:
        p = float(_chi2_sf(q / lam[0], 1))
    else:
        p = p0
    pf = min(1.0, p * n)
    return BetweenNodes(s, iv, float(p), float(pf), n, pf >= BETWEEN_NODES_P, float(q / t1), approx)
