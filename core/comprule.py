"""How much of each identified error a compensation applies, and what it is predicted to leave.

A compensation moves the machine by the estimate ``e^`` of each error ``e``. Estimating ``e`` with
standard uncertainty ``u`` (``e^ ~ N(e, u^2)``) and applying a fraction ``l`` of it leaves
``e - l e^``, of mean square ``(1 - l)^2 e^2 + l^2 u^2``: smallest at ``l* = e^2 / (e^2 + u^2)``.
Applying every identified value (``l = 1``, the rule before session 26) leaves ``u^2`` whatever
``e``: on a good machine it adds the whole uncertainty of terms the machine does not have
(``mfb-3axis --errors none``: 0 um before, X/Y/Z 2.75/1.43/2.27 um after the volumetric table,
review of session 26); leaving a term out (``l = 0``) leaves ``e^2``.

The rule (:func:`select_terms`), per error function (a table over its nodes, or a squareness):
``e^2`` estimated without bias by ``mean(e^2) - mean(u^2)`` over the nodes, so
``l = max(0, 1 - mean(u^2) / mean(e^2))`` (the positive-part James-Stein factor; ``u`` from the
identification's covariance, linear propagation, ``U95 = 2 u``). A term whose RMS is no more than
its RMS standard uncertainty (``RMS(e^) <= RMS(U95) / 2``) is left out; one ten times its RMS U95
is applied at 99.75 %. Tables are scaled whole, never node by node (steps in a table the
controller interpolates by its spline). Measured (session 26, 8 seeds, the exact simulator, worst
axis of the volumetric error over the node box, mean): a perfect machine 2.71 um after every term,
1.11 um after this rule; five injected errors 2.71 -> 1.46 um; the realistic machine (all 21 errors
present, several near their U95) 2.70 -> 3.07 um; a 95 %-significance cut (RMS > RMS U95) gave
0.62 / 1.40 / 4.19 um (docs/papers-mfb.md, "How much of each error a compensation applies").

:func:`predicted_residual` is the tool-tip deviation the compensation is predicted to leave over a
set of points, a rigid motion removed (what no artefact on the table sees), with two U95 per point
and axis: ``U95`` of what is left (the whole estimate's covariance: the applied part's error and
the estimate of what is not applied), and ``U95_added``, what the applied part may add (``l^2``
times its covariance): on a machine without errors the compensation's whole effect. Linear in the
errors through the chain (:func:`core.kinematics.tip_W`); the factors ``l`` are taken as given (their
own scatter is not propagated).
"""

from __future__ import annotations

import numpy as np

from . import iso
from .exceptions import ConfigError
from .kinematics import ChainGeometry, tip_W
from .state import MachineState
from .volumetric import spline_weights

#: The rule's factor is ``max(0, 1 - SHRINKAGE * mean(u^2) / mean(e^2))`` per error function: 1 is the
#: least-mean-square fraction (module doc); 0 applies every identified value whole (the rule before
#: session 26). Set by session 26's closed-loop study (docs/papers-mfb.md, "How much of each error a
#: compensation applies").
SHRINKAGE = 1.0


def select_terms(state: MachineState) -> dict:
    """``{symbol: decision}`` for every table and constant of ``state`` (an identification's estimate).

    Each decision: ``factor`` (the fraction applied, 0 to 1, module doc), ``rms`` and ``rms_u95``
    (um or urad, the symbol's unit, over its nodes), ``ratio`` (rms / rms_u95; None when rms_u95
    is 0) and ``reason`` (one sentence). A term whose U95 is zero at every node (a gauge's fixed
    values) is applied whole (nothing to add); one identified as zero is left out.
    """
    U = 2.0 * state.u
    out = {}
    idx = {s: np.atleast_1d(i) for s, (_, i) in state.tables.items()}
    idx.update({s: np.atleast_1d(i) for s, i in state.constants.items()})
    for s, i in idx.items():
        v, u = state.mean[i] * 1e6, U[i] * 1e6
        if not (np.isfinite(v).all() and np.isfinite(u).all()):
            raise ConfigError(f"select_terms: {s}: values and uncertainties must be finite")
        rms, rms_u = float(np.sqrt(np.mean(v ** 2))), float(np.sqrt(np.mean(u ** 2)))
        unit = "urad" if iso.symbol(s).angular else "um"
        if rms_u == 0.0:
            f, why = 1.0, "no uncertainty (the gauge's fixed values): applied as identified"
        elif rms == 0.0:
            f, why = 0.0, "identified as zero"
        else:
            f = max(0.0, 1.0 - SHRINKAGE * (rms_u / 2.0) ** 2 / rms ** 2)
            why = (f"RMS {rms:.3g} {unit} against RMS U95 {rms_u:.3g} {unit}: "
                   + (f"applied at {f:.3f} = 1 - (U95 / 2)^2 / RMS^2 (the fraction that leaves the least "
                      f"mean-square error)" if f > 0.0 else
                      "no larger than its standard uncertainty, left out (applying it would add more than "
                      "it removes)"))
        out[s] = {"factor": f, "applied": f > 0.0, "rms": rms, "rms_u95": rms_u,
                  "ratio": None if rms_u == 0.0 else rms / rms_u, "reason": why}
    return out


def _rigid_basis(P) -> np.ndarray:
    """(3n, 6) columns of a rigid motion ``t + w x (p - mean p)`` at points P (n, 3), x/y/z interleaved."""
    n = len(P)
    A = np.zeros((3 * n, 6))
    for i in range(3):
        A[i::3, i] = 1.0
    c = P - P.mean(axis=0)
    A[0::3, 4], A[0::3, 5] = c[:, 2], -c[:, 1]
    A[1::3, 3], A[1::3, 5] = -c[:, 2], c[:, 0]
    A[2::3, 3], A[2::3, 4] = c[:, 1], -c[:, 0]
    return A


def tip_map(state: MachineState, chain: str, P, J_m=(0.0, 0.0, 0.0), rotary_points_R_m=None,
            step: float = 1e-6) -> np.ndarray:
    """(3n, p) d tip deviation / d parameters at readings P (n, 3) (rotary axes at 0), rigid motion removed.

    The tables are looked up at the axis (joint) positions ``P + J_m`` (the state's tables are
    functions of the joint positions, :mod:`core.kinematics`).

    Each column: the tip moved by one parameter of ``state`` (a node value or a constant) by
    ``step`` (m or rad) through :func:`core.kinematics.tip_W`, divided by it (the chain's second
    order, ~step x arm, is 1e-6 of the column), projected off the rigid motions of the points.
    """
    P = np.atleast_2d(np.asarray(P, float))
    if P.ndim != 2 or P.shape[1] != 3 or not np.isfinite(P).all() or len(P) < 3:
        raise ConfigError("tip_map: points must be finite (n, 3), n >= 3")
    geom = ChainGeometry.of(chain, J_m, rotary_points_R_m)
    nr = len(geom.chain.rotary_axes)
    rot = None if not nr else np.zeros((len(P), nr))
    base = tip_W(geom, P, rot, None)
    G = np.zeros((3 * len(P), len(state.mean)))
    zeros = np.zeros(len(P))
    for s, (x, i) in state.tables.items():
        a = iso.LINEAR_AXES.index(iso.symbol(s).axis)
        W = spline_weights(x, P[:, a] + geom.J_m[a])
        for k, j in enumerate(np.atleast_1d(i)):
            G[:, j] = ((tip_W(geom, P, rot, {s: step * W[:, k]}) - base) / step).ravel()
    for s, j in state.constants.items():
        G[:, j] = ((tip_W(geom, P, rot, {s: zeros + step}) - base) / step).ravel()
    A = _rigid_basis(P)
    Q, _ = np.linalg.qr(A)
    return G - Q @ (Q.T @ G)


def line_map(state: MachineState, chain: str, axis: str, x_m, point_m, J_m=(0.0, 0.0, 0.0),
             rotary_points_R_m=None, ref_m: float | None = None, step: float = 1e-6) -> np.ndarray:
    """(k, p) d/d parameters of ``axis``'s component of the tool-tip deviation along ``axis``'s line.

    The line: the readings ``point_m`` (3,) m of the other two axes (``point_m``'s own entry of ``axis`` is
    not used), ``axis`` at the axis (joint) positions ``x_m`` (k,) m, i.e. readings ``x_m - J``; rotary axes
    at 0. A per-axis compensation table (LinuxCNC's, one value per joint position) that corrects this
    component is exact on that line and nowhere else where the errors depend on the other axes' positions
    (an angular error's Abbe arm, the other axes' straightness and squareness: module doc of
    :func:`line_table`). With ``ref_m`` each row is taken relative to the line's point at the axis position
    ``ref_m`` (the gauge of a positioning table: zero at its first node; a constant along the axis moves
    the whole work volume, which touching off the part's datum absorbs).

    Columns as :func:`tip_map`'s (one parameter of ``state`` moved by ``step`` through
    :func:`core.kinematics.tip_W`, divided by it: first order, the chain's second order ~ step x arm).
    """
    a = axis.upper() if isinstance(axis, str) else axis
    if a not in iso.LINEAR_AXES:
        raise ConfigError(f"line_map: axis must be X, Y or Z, got {axis!r}")
    i = iso.LINEAR_AXES.index(a)
    x = np.atleast_1d(np.asarray(x_m, float))
    pt = np.asarray(point_m, float)
    if x.ndim != 1 or not np.isfinite(x).all() or pt.shape != (3,) or not np.isfinite(pt).all():
        raise ConfigError("line_map: x_m must be finite (k,) and point_m three finite readings")
    xs = x if ref_m is None else np.r_[x, float(ref_m)]
    geom = ChainGeometry.of(chain, J_m, rotary_points_R_m)
    P = np.tile(pt, (len(xs), 1))
    P[:, i] = xs - geom.J_m[i]
    nr = len(geom.chain.rotary_axes)
    rot = None if not nr else np.zeros((len(P), nr))
    base = tip_W(geom, P, rot, None)[:, i]
    M = np.zeros((len(P), len(state.mean)))
    zeros = np.zeros(len(P))
    for s, (nodes, idx) in state.tables.items():
        b = iso.LINEAR_AXES.index(iso.symbol(s).axis)
        W = spline_weights(nodes, P[:, b] + geom.J_m[b])
        for k, j in enumerate(np.atleast_1d(idx)):
            M[:, j] = (tip_W(geom, P, rot, {s: step * W[:, k]})[:, i] - base) / step
    for s, j in state.constants.items():
        M[:, j] = (tip_W(geom, P, rot, {s: zeros + step})[:, i] - base) / step
    return M if ref_m is None else M[:-1] - M[-1]


def applied_mean(state: MachineState, factors: dict) -> np.ndarray:
    """(p,) the part of ``state.mean`` a compensation applies: each symbol's values times its factor
    (``factors``: symbol -> fraction, 0 to 1; absent: 0)."""
    return _lam(state, factors) * state.mean


def line_table(state: MachineState, factors: dict, chain: str, axis: str, x_m, point_m, J_m=(0.0, 0.0, 0.0),
               rotary_points_R_m=None, ref_m: float | None = None) -> np.ndarray:
    """(k,) m: what a per-axis table on ``axis``'s line through ``point_m`` holds at the axis positions ``x_m``.

    The applied part of the estimate (:func:`applied_mean`) through :func:`line_map`: ``axis``'s component
    of the tool-tip deviation relative to the workpiece (ISO 230-1) along the line, zero at ``ref_m``. It is
    the positioning error ``E<axis><axis>`` plus, for X on a line at readings (y, z), the Abbe terms of X's
    own pitch and yaw (``EBX z - ECX y`` on a tool-side chain), the other axes' errors at that point being
    constants along the line: at readings 0 of the other two axes (zero Abbe arms) the table is
    ``E<axis><axis>`` itself, to the chain's second order.
    """
    return line_map(state, chain, axis, x_m, point_m, J_m, rotary_points_R_m, ref_m) @ applied_mean(state, factors)


def _lam(state: MachineState, factors: dict) -> np.ndarray:
    unknown = set(factors) - set(state.symbols)
    if unknown:
        raise ConfigError(f"predicted_residual: {sorted(unknown)} not in the estimate")
    lam = np.zeros(len(state.mean))
    for s, f in factors.items():
        f = float(f)
        if not 0.0 <= f <= 1.0:
            raise ConfigError(f"predicted_residual: {s}: factor {f!r} not in [0, 1]")
        lam[np.atleast_1d(state.tables[s][1] if s in state.tables else state.constants[s])] = f
    return lam


def rigid_projected(A, P) -> np.ndarray:
    """(3n, p) ``A`` (x/y/z interleaved rows at the points P (n, 3)) with the rigid motions of P projected
    off, as :func:`tip_map`'s columns are."""
    Q, _ = np.linalg.qr(_rigid_basis(np.atleast_2d(np.asarray(P, float))))
    return A - Q @ (Q.T @ A)


def predicted_residual(state: MachineState, factors: dict, G: np.ndarray, applied: np.ndarray | None = None) -> dict:
    """What compensating ``factors`` (symbol -> fraction applied; absent: 0) of ``state`` is predicted
    to leave at the points of ``G`` (:func:`tip_map`): ``residual`` (n, 3) m, the estimate of what is not
    applied, ``(1 - l) e^``; ``U95`` (n, 3) m, 2 sqrt of the diagonal of ``G cov G^T`` (every term's
    estimate is uncertain, whether its error is what the compensation leaves or is left whole);
    ``U95_added`` (n, 3) m, the same of ``G L cov L G^T``: what the applied part may add (module doc).

    ``applied`` (3n, p), optional: the compensation's own displacement per parameter at the same points
    (rigid motions projected off as ``G``'s), when it is not the tip deviation itself: per-axis tables on
    lines (:func:`line_map` at each point's axis positions; a table corrects only its axis's component, and
    as it is on its line wherever the other axes are). Then ``residual = G e^ - applied L e^`` and
    ``U95_added`` is of ``applied L cov L applied^T``; default ``G`` (each error corrected where it acts).
    """
    lam = _lam(state, factors)
    A = G if applied is None else applied
    if A.shape != G.shape:
        raise ConfigError(f"predicted_residual: applied map of shape {A.shape}, expected {G.shape}")
    r = G @ ((1.0 - lam) * state.mean) if applied is None else G @ state.mean - A @ (lam * state.mean)
    GF = G @ state.factor
    GLF = A @ (lam[:, None] * state.factor)
    U = 2.0 * np.sqrt(np.einsum("ij,ij->i", GF, GF))
    Ua = 2.0 * np.sqrt(np.einsum("ij,ij->i", GLF, GLF))
    return {"residual": r.reshape(-1, 3), "U95": U.reshape(-1, 3), "U95_added": Ua.reshape(-1, 3)}
