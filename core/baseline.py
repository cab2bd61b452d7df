"""The model discovery starts from, as one object: design, gauge, covariates, residuals.

:func:`core.discover.discover_baseline` works on any linear(ised) model
``y = A theta + e`` that says

- what it explains: the design ``A`` (n, p) and the observations ``y``;
- what it cannot see: the gauge conditions ``C theta = d`` that fix its
  null space, and which columns are the *estimand* (the workpiece of a
  self-calibration, the error tables of a volumetric identification, the
  systematic deviations of a positioning test) with what of it no data can
  see (the workpiece's position, rotation and scale);
- how its rows group: the folds of the cross-validation (set-ups,
  placements, cycles: a held-out group's own columns are refitted on it,
  everything else is predicted) and the replicate groups (rows that are
  the same design row measured again: their scatter is pure noise);
- what its rows carry: the covariates (:class:`core.diagnosis.Covariate`)
  and the response modes through which a smooth function of a covariate
  acts on a row;
- the data the named causes of :mod:`core.causes` build their columns from.

:func:`planar` builds it for the 2D self-calibration of Ibaraki et al.
(eqs 1-18, :mod:`core.selfcal`); :func:`core.volumetric_baseline.volumetric`
(MFB) and the positioning baseline live beside their models.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from . import selfcal
from .diagnosis import Covariate, orth, pivoted_qr, qr_formed, qr_rank, qr_rss
from .exceptions import ConfigError, IdentifiabilityError
from .lsq import BlockDesign
from .probelog import decimal_quantum
from .touches import Touches

from .units import MM
#: Relative pivot of the column-scaled design below which a direction counts
#: as unseen (singular-value ratio; core.lsq.solve uses 1e-6).
RANK_TOL = 1e-7
#: The planar baseline's rank decisions (the grid's identifiability and BIC rank, the engine's baseline basis
#: and its gauge's unseen directions, :func:`core.discover._gauge_svd`) take their tolerance from the log's own
#: precision (:func:`precision_rank_tol`): a direction the design determines only through the rounding of the
#: printed nominal coordinates is unseen. review30c (session 30): the same campaign with ``Xn, Yn, Zn`` printed to
#: 4 decimals of a mm (0.1 um, as most controllers print) instead of 7 lost its workpiece ("not identifiable by
#: this design") and changed its grid (55 -> 80 mm), because two directions a full-precision log leaves at
#: |R_ii|/|R_00| 1e-9 (the gauge's: exact in exact coordinates) came out at 5e-7 and 1.7e-6, above RANK_TOL, and the
#: engine's own basis kept directions at 1.3e-9 to 2.2e-9 (its cut was 1e-9) that a shift of the campaign flipped
#: (rank30). False: RANK_TOL for the grid, 1e-9 for the engine's basis, 1e-6 for the gauge, as before session 30.
PRECISION_RANK = True
#: :func:`precision_rank_tol`'s factor on the coordinates' relative quantum ``q_rel = q / L`` (``q`` the step the
#: nominal X, Y are printed to, ``L`` their largest distance from the C axis). Measured on 18 of review30c's
#: campaigns (none, lobe3, screw_saw, backlash_x, feed_force, clamp_warp at seeds 300, 305, 310) printed to 3, 4,
#: 5 and 6 decimals, on every grid (360 designs; rank30, /tmp/rank30/s/margin.py): a direction made by the
#: rounding has |R_ii|/|R_00| 0.97-1.79 ``q_rel`` and, in the gauge's null space (column-scaled SVD), at most
#: 0.19 ``q_rel``; the real directions are at 2.7e3 ``q_rel`` and up (QR) and 66 ``q_rel`` and up (gauge SVD)
#: even at 3 decimals. 10 leaves a margin of 5.6 above the rounding and of 6.6 below the weakest real direction.
RANK_QUANTUM_FACTOR = 10.0
#: Largest dense planar design (bytes, n x p doubles); a larger one is kept as a
#: :class:`core.lsq.BlockDesign`, the targets' columns eliminated (a 1e5-row log: 1.1 GB dense).
DENSE_DESIGN_BYTES = 256 << 20


@dataclass(frozen=True)
class Baseline:
    """A linear baseline model and everything discovery needs around it.

    Attributes
    ----------
    kind : str
        ``"planar"``, ``"volumetric"`` or ``"positioning"``: which causes apply.
    model : str
        The model in words (report key ``baseline.model``).
    A : (n, p) float, or core.lsq.BlockDesign
        Design, SI units per unit parameter. A long planar log's (above
        :data:`DENSE_DESIGN_BYTES` dense) is a :class:`core.lsq.BlockDesign`:
        the targets' columns (one 1 per touch) kept as each row's target,
        the machine's columns dense; the engine eliminates the targets
        (means per target) instead of factoring ``n x p``.
    y : (n,) float
        Observations, m (or rad).
    names : tuple of str
        Parameter names, p.
    groups : (n,) int
        Cross-validation fold of each row (index into ``group_ids``).
    group_ids : tuple of str
    C, d : (k, p), (k,) float
        Gauge conditions ``C theta = d``.
    estimand : (q,) int
        Columns reported per id (the workpiece per target, ...).
    estimand_ids : tuple of str
    geometry : tuple of (q, 2) arrays or None
        ``(P_W, N_W)``: nominal point and normal of each estimand id in the
        part's frame (planar), for the form that self-calibration sees
        (shift, rotation, scale and offset removed); None when not planar.
    replicate : (n,) int
        Replicate group of each row (equal design rows); -1 for none.
    covariates : tuple of Covariate
    modes : (n, m) float
        Response modes (column ``j`` is mode ``j``), unit-free.
    mode_names : tuple of str
    rows : (n,) int
        Source log row of each observation (``outlier_rows`` are these).
    data : object
        What the causes of this kind read (``PlanarData`` ...).
    identifiable : bool
        The estimand is identifiable beyond the gauge.
    why : str
        When not: the combinations the data cannot see.
    conventions : tuple of str
    info : dict
        Kind-specific figures for the report (grid step ...); a planar one also
        its error map's ``grid`` (:class:`core.selfcal.Grid`, the smooth causes' knots).
    estimand_label : str
    whiten : (n, n) float or None
        When the rows' noise is correlated or of unequal size (the points of
        an MFB measurement share touches), ``A`` and ``y`` are already
        multiplied by this matrix (the inverse square root of their noise
        covariance, scaled to keep the rows' mean size), and the engine
        multiplies every other column it builds (causes, smooth terms) by
        it too, so that the tests see independent rows of one variance.
    qr : tuple or None
        :func:`core.diagnosis.pivoted_qr` of ``A`` when the builder already
        factored it (the planar grid choice does), so the engine does not
        factor it again; it names the matrix it factors and is ignored for
        any other (a replaced ``A``). None for a block design (it keeps its
        own factorisation, :meth:`core.lsq.BlockDesign.basis`).
    rank_tol : float or None
        The relative tolerance below which a direction of ``A`` is unseen (the
        pivoted QR's ``|R_ii| / |R_00|``; the gauge's column-scaled singular
        values at the larger of it and 1e-6): the planar baseline's
        :func:`precision_rank_tol`, the grid chosen by the same. None: the
        engine's own cuts (1e-9 for its basis, 1e-6 for the gauge).
    """

    kind: str
    model: str
    A: np.ndarray = field(repr=False)
    y: np.ndarray = field(repr=False)
    names: tuple = field(repr=False)
    groups: np.ndarray = field(repr=False)
    group_ids: tuple
    C: np.ndarray = field(repr=False)
    d: np.ndarray = field(repr=False)
    estimand: np.ndarray = field(repr=False)
    estimand_ids: tuple = field(repr=False)
    geometry: tuple | None = field(repr=False)
    replicate: np.ndarray = field(repr=False)
    covariates: tuple = field(repr=False)
    modes: np.ndarray = field(repr=False)
    mode_names: tuple = field(repr=False)
    rows: np.ndarray = field(repr=False)
    data: object = field(repr=False)
    identifiable: bool = True
    why: str = ""
    conventions: tuple = ()
    info: dict = field(default_factory=dict)
    estimand_label: str = "workpiece"
    whiten: np.ndarray | None = field(default=None, repr=False)
    qr: tuple | None = field(default=None, repr=False, compare=False)
    rank_tol: float | None = None

    @property
    def n(self) -> int:
        return len(self.y)

    def covariate(self, name: str) -> Covariate | None:
        return next((c for c in self.covariates if c.name == name), None)


# ---------------------------------------------------------------------------
# planar: the 2D self-calibration
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class PlanarData:
    """What the planar causes build their columns from (machine frame R, SI).

    Every coordinate is centred and scaled on the campaign itself, so the
    columns' span does not change when the campaign is moved in machine
    coordinates.

    Attributes
    ----------
    touches : Touches
        The planar touches (rows of the baseline), without the arrays no
        step after the baseline reads (:data:`PLANAR_TOUCHES_DROPPED`: None).
    x, y : (n,) float
        Nominal tip centre, m.
    xs, ys : (n,) float
        ``(x - x_c) / L``, ``(y - y_c) / L``: centred on the extent, scaled
        by its half-size ``L`` (unit-free, about -1..1).
    L_m : float
    nx, ny : (n,) float
        Normal components, R.
    azimuth, elevation : (n,) float
        Approach direction's azimuth ``atan2(d_y, d_x)`` and elevation
        ``asin(-d_z)`` (positive when the stylus moves down), rad.
    tau : (n,) float
        Time since the first touch over the campaign's span, 0..1.
    t_in : (n,) float
        Time since the set-up's first touch over the longest set-up's span, 0..1.
    c0_m : (2,) float
        C-axis centre in R (from the nominal positions of the same targets
        at different C), m; NaN when the log cannot tell.
    rot_m : (n,) float
        ``(R90 (p - c0)) . n``: the normal deviation per radian of a table
        rotation about the C axis (eq 13), m.
    wn_az : (n,) float
        Azimuth of the target's normal in the part's frame W, rad.
    grid_step_m : float
    span_s : float
    temps : dict[str, (n,) float]
    extra : dict[str, (n,) float]
        Other numeric columns of the log (a feed, a spindle load ...).
    """

    touches: Touches = field(repr=False)
    x: np.ndarray = field(repr=False)
    y: np.ndarray = field(repr=False)
    xs: np.ndarray = field(repr=False)
    ys: np.ndarray = field(repr=False)
    L_m: float
    nx: np.ndarray = field(repr=False)
    ny: np.ndarray = field(repr=False)
    azimuth: np.ndarray = field(repr=False)
    elevation: np.ndarray = field(repr=False)
    tau: np.ndarray = field(repr=False)
    t_in: np.ndarray = field(repr=False)
    c0_m: np.ndarray
    rot_m: np.ndarray = field(repr=False)
    wn_az: np.ndarray = field(repr=False)
    grid_step_m: float
    span_s: float
    temps: dict = field(repr=False)
    extra: dict = field(default_factory=dict, repr=False)


PLANAR_MODES = ("scalar", "x translation", "y translation", "x scale", "y scale", "x shear (by y)",
                "y shear (by x)")


def planar_modes(d: PlanarData) -> np.ndarray:
    """(n, 7) response modes: a scalar and an affine displacement field of the tip (R).

    ``dq = -n . E`` for a tip displacement ``E`` (CONTRIBUTING): columns
    ``1, -n_x, -n_y, -n_x xs, -n_y ys, -n_x ys, -n_y xs``.
    """
    one = np.ones_like(d.nx)
    return np.column_stack([one, -d.nx, -d.ny, -d.nx * d.xs, -d.ny * d.ys, -d.nx * d.ys, -d.ny * d.xs])


def _w_A(t: Touches):
    """Nominal contact points and normals in the part's frame A."""
    return t.w_A, t.wn_A


def c_axis_centre(t: Touches) -> np.ndarray:
    """(2,) C-axis centre in R from the nominal tip centres, m (NaN when not determinable).

    The same target at angles ``C_j`` and ``C_k`` sits at
    ``p_k - c0 = R(C_j - C_k) (p_j - c0)`` (eq 1, ``p = R(-C) w + c0``), linear
    in ``c0``; all pairs against each target's first touch are solved in the
    least-squares sense.
    """
    _, first = np.unique(t.target, return_index=True)
    j = first[np.searchsorted(np.unique(t.target), t.target)]
    c = t.rot_rad[:, 2]
    dc = c[j] - c
    use = np.abs(np.angle(np.exp(1j * dc))) > 1e-6
    if not use.any():
        return np.full(2, np.nan)
    R = selfcal.rot2(dc[use])  # (m, 2, 2)
    M = (np.eye(2)[None] - R).reshape(-1, 2)
    b = (t.pn_R[use, :2] - np.einsum("mab,mb->ma", R, t.pn_R[j[use], :2])).reshape(-1)
    sol, *_ = np.linalg.lstsq(M, b, rcond=None)
    return sol


def extra_columns(log, rows) -> dict:
    """Numeric columns of a probe log beyond the format's own, at ``rows``: name -> (n,) float.

    Columns the format defines (and ``temp_*_C``, read as temperatures)
    are left out, as are text columns and constant ones. Discovery tests
    the rest as covariates too: every covariate the log holds.
    """
    from .probelog import OPTIONAL, REQUIRED

    out = {}
    for name, v in log.columns.items():
        if name in REQUIRED or name in OPTIONAL or name.startswith("temp_"):
            continue
        try:
            a = np.asarray(v, float)[rows]
        except (TypeError, ValueError):
            continue
        if np.all(np.isfinite(a)) and np.ptp(a) > 0:
            out[name] = a
    return out


#: Arrays of the touches a planar baseline's data does not hold (None there): read only while the baseline is
#: built (the observations ``dq_m`` from ``p_R``, the workpiece's geometry and the normals' azimuths from ``wn_A``),
#: by no cause, test or report after it; 46 MiB at 1e6 rows, once the caller lets its touches go.
PLANAR_TOUCHES_DROPPED = ("p_R", "wn_A")


def planar_data(t: Touches, grid_step_m: float, extra: dict | None = None) -> PlanarData:
    """The centred, scaled geometry and times the planar causes use (the touches held without
    :data:`PLANAR_TOUCHES_DROPPED`)."""
    x, y = t.pn_R[:, 0], t.pn_R[:, 1]
    xc, yc = (x.max() + x.min()) / 2, (y.max() + y.min()) / 2
    L = max(np.ptp(x), np.ptp(y), 1e-3) / 2
    t0 = t.t_s.min()
    span = max(float(np.ptp(t.t_s)), 1e-9)
    tin = np.zeros(t.n)
    for j in np.unique(t.setup):
        m = t.setup == j
        tin[m] = t.t_s[m] - t.t_s[m].min()
    tin = tin / max(tin.max(), 1e-9)
    c0 = c_axis_centre(t)
    cc = c0 if np.all(np.isfinite(c0)) else np.array([xc, yc])
    rot = -t.n_R[:, 0] * (y - cc[1]) + t.n_R[:, 1] * (x - cc[0])
    _, wn = _w_A(t)
    if np.all(np.isfinite(wn[:, :2])):
        wn_az = np.arctan2(wn[:, 1], wn[:, 0])
    else:  # n_W = R(+C) n_R (eq 1 maps W to R by R(-C))
        wn_az = np.arctan2(t.n_R[:, 1], t.n_R[:, 0]) + t.rot_rad[:, 2]
    d = t.d_R
    return PlanarData(
        touches=dataclasses.replace(t, **dict.fromkeys(PLANAR_TOUCHES_DROPPED)), x=x, y=y, xs=(x - xc) / L,
        ys=(y - yc) / L, L_m=float(L), nx=t.n_R[:, 0], ny=t.n_R[:, 1],
        azimuth=np.arctan2(d[:, 1], d[:, 0]), elevation=np.arcsin(np.clip(-d[:, 2], -1, 1)),
        tau=(t.t_s - t0) / span, t_in=tin, c0_m=c0, rot_m=rot, wn_az=np.angle(np.exp(1j * wn_az)),
        grid_step_m=float(grid_step_m), span_s=span,
        temps={k: np.asarray(v, float) for k, v in t.temps_C.items()
               if np.all(np.isfinite(v)) and np.ptp(v) > 0},
        extra={k: np.asarray(v, float) for k, v in (extra or {}).items()})


def touch_history(t_s: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What the probe went through just before each touch: (log10 time since the previous touch, turn, deg).

    A kinematic seat that settles after each trigger (its error shrinking
    with the rest between touches) or that lands differently when the
    approach reverses (hysteresis of the seat) leaves residuals following
    these, not the time or the direction themselves. Touches are taken in
    time order (ties in log order); the first touch gets the median rest
    (it has no previous one, and an extreme value would give it a basis
    function of its own) and no turn.

    Parameters
    ----------
    t_s : (n,) float
        Touch times, s.
    d : (n, 3) float
        Unit approach directions (any frame: only angles between them count).

    Returns
    -------
    since : (n,) float
        ``log10`` of the time since the previous touch in s (floored at 1 ms).
    turn : (n,) float
        Angle between the approach and the previous touch's, deg, rounded
        to 1 deg (0: same direction, 180: reversed).
    """
    t_s = np.asarray(t_s, float)
    n = len(t_s)
    since = np.zeros(n)
    turn = np.zeros(n)
    if n < 2:
        return since, turn
    o = np.argsort(t_s, kind="stable")
    gap = np.diff(t_s[o])
    since[o[1:]] = np.log10(np.maximum(gap, 1e-3))
    since[o[0]] = float(np.median(since[o[1:]]))
    cosang = np.clip(np.sum(d[o[1:]] * d[o[:-1]], axis=1), -1.0, 1.0)
    turn[o[1:]] = np.round(np.degrees(np.arccos(cosang)))
    return since, turn


def planar_covariates(d: PlanarData, sparse: bool = False) -> tuple:
    """The covariates of a planar campaign (those that vary), with their bases.

    ``sparse`` (a long log's, beside a :class:`core.lsq.BlockDesign`): the
    approach azimuth per set-up (``azimuth_by_setup``, rows x 6 per set-up,
    each column non-zero on one set-up's rows) is kept as a sparse matrix.
    """
    t = d.touches
    allm = tuple(range(7))
    pos = (0, 1, 2)
    covs = [
        Covariate("time", t.t_s, "smooth", 6, allm, "time", "time"),
        Covariate("time_in_setup", d.t_in, "smooth", 5, allm, "time within each set-up", "time"),
        Covariate("setup", t.setup, "categorical", 0, allm, "the set-up", "time"),
        Covariate("x", d.x, "smooth", 8, pos, "the x position", "position"),
        Covariate("y", d.y, "smooth", 8, pos, "the y position", "position"),
        Covariate("approach_azimuth", d.azimuth, "circular", 4, (0,), "the approach azimuth (machine frame)",
                  "direction"),
        Covariate("order", np.arange(t.n, dtype=float), "smooth", 6, allm, "the touch order", "time"),
    ]
    su = np.unique(t.setup)
    if su.size >= 2:
        F = np.column_stack([f(k * d.azimuth) for k in (2, 3, 4) for f in (np.cos, np.sin)])
        if sparse:
            at = np.searchsorted(su, t.setup)  # each row's set-up's place among su
            B = sp.csr_matrix((F.ravel(), (np.repeat(np.arange(t.n), F.shape[1]),
                                           (at[:, None] * F.shape[1] + np.arange(F.shape[1])).ravel())),
                              shape=(t.n, F.shape[1] * su.size))
        else:
            B = np.hstack([F * (t.setup == j)[:, None] for j in su])
        covs.append(Covariate("azimuth_by_setup", B, "basis", B.shape[1], (0,),
                              "the approach azimuth, differently in each set-up", "direction"))
    xy = _xy_basis(d.xs, d.ys)
    covs.append(Covariate("xy", xy, "basis", xy.shape[1], (1, 2), "x and y jointly (non-separable)", "position"))
    from .causes import nyquist_period_m

    for name, v in (("x", d.x), ("y", d.y)):  # structure finer than a smooth term: a ripple along an axis
        covs.append(Covariate(f"{name}_periodic", v, "spectral", 0, (1, 2), f"the {name} position periodically",
                              "position", (nyquist_period_m(v), d.grid_step_m)))
    # an oscillation in time (a vibration, a cycling coolant): periods from twice the
    # typical time between touches to a third of the campaign
    dt = np.diff(np.sort(t.t_s))
    dt = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 0.0
    if dt > 0:
        covs.append(Covariate("time_periodic", t.t_s, "spectral", 0, (0, 1, 2), "time periodically", "time",
                              (2 * dt, d.span_s / 3)))
    cdeg = np.round(np.degrees(t.rot_rad[:, 2]), 6)
    nc = np.unique(cdeg).size
    if nc >= 3:
        covs.append(Covariate("C", t.rot_rad[:, 2], "circular", min(2, (nc - 1) // 2), allm, "the C angle", "time"))
    z = t.pn_R[:, 2]
    nz = np.unique(np.round(z, 7)).size
    if nz >= 2:
        covs.append(Covariate("z", z, "smooth", min(4, nz), pos, "the z position", "position"))
    if np.ptp(d.elevation) > np.radians(1.0):
        covs.append(Covariate("approach_elevation", d.elevation, "smooth", 3, (0,), "the approach elevation",
                              "direction"))
    feats = np.asarray(t.feature, dtype=object)
    if len(set(feats.tolist())) >= 2:
        key = np.array([f"{f}|{s}" for f, s in zip(feats, t.setup)], dtype=object)
        covs.append(Covariate("feature", key, "categorical", 0, pos, "the feature, differently in each set-up",
                              "feature"))
    since, turn = touch_history(t.t_s, t.d_R)
    if np.ptp(since) > 0:
        covs.append(Covariate("time_since_previous", since, "smooth", 4, (0,),
                              "the time since the previous touch", "history"))
    if np.unique(turn).size >= 2:
        covs.append(Covariate("turn_from_previous", turn, "smooth", 4, (0,),
                              "the turn of the approach from the previous touch's", "history"))
    for name, v in d.temps.items():
        short = name[5:-2] if name.startswith("temp_") and name.endswith("_C") else name
        covs.append(Covariate(f"temp_{short}", v, "smooth", 5, allm, f"the temperature {name}", "time"))
    for name, v in d.extra.items():
        covs.append(Covariate(name, v, "smooth", 5, allm, f"the column {name}", "other"))
    return tuple(covs)


def _xy_basis(xs, ys):
    """Products of Legendre polynomials ``P_i(xs) P_j(ys)``, i, j >= 1, i + j <= 4."""
    return np.column_stack(list(_xy_products(xs, ys)))


def _xy_products(xs, ys):
    """:func:`_xy_basis`'s columns one at a time (the same operations: the same numbers), so a caller can use
    each without the table (at 1e6 rows the six columns are 46 MiB, and a product of them with the normals as
    much again)."""
    P = [np.ones_like(xs), xs, (3 * xs ** 2 - 1) / 2, (5 * xs ** 3 - 3 * xs) / 2]
    R = [np.ones_like(ys), ys, (3 * ys ** 2 - 1) / 2, (5 * ys ** 3 - 3 * ys) / 2]
    for i in range(1, 4):
        for j in range(1, 4):
            if i + j <= 4:
                yield P[i] * R[j]


def centred_grid(p_R: np.ndarray, step_m: float) -> selfcal.Grid:
    """Nodes ``c + k step`` symmetric about the centre ``c`` of the points' extent.

    Anchored on the campaign, not on the machine's zero: moving the
    campaign in machine coordinates moves the grid with it.
    """
    nodes = []
    for c in (0, 1):
        v = p_R[:, c]
        mid = (v.max() + v.min()) / 2
        K = max(int(np.ceil((v.max() - mid) / step_m - 1e-9)), 1)
        nodes.append(mid + step_m * np.arange(-K, K + 1))
    return selfcal.Grid(*nodes)


#: The planar baseline carries the Abbe terms of the tool's angular errors over the stroke (``E_X += dz EB(x, y)``,
#: ``E_Y -= dz EA(x, y)`` taken linear, :class:`core.selfcal.HeightTerms`), the two shear parts the raised touches
#: see, when they identify them (:func:`core.selfcal.height_terms`' local rank test): the model ``vmt identify``
#: fits. Without them (before session 29) a realistic nmv3000's X pitch ramp ``EBX`` (98 urad/m) and Y roll ``EAY``
#: through the cross pocket's 25.7 mm sphere height left 0.107 um RMS noise-free (identify: 0.0185 um) that
#: discover read as ``unexplained`` ("residuals follow the feature, differently in each set-up") on 3/20 of the
#: regress study's seeds with the screw, 6/20 without (docs/discovery-studies.md, "Session 29: the 0.1 um discover
#: called unexplained ...", rs29). Built and OFF. Session 30 (abbe30, docs/discovery-studies.md "Session 30: the planar
#: baseline's Abbe columns ..."): on, 55 discover tests fail, reviewed one by one; on gen_b every effect 1000-1011
#: it moves 9 readings right -> wrong against 5 wrong -> right (part_change 1001, 1004, 1008, 1011 among them:
#: gen_a's and gen_b's machines carry almost no pitch or roll, and the two columns, nonzero on the raised touches
#: only, take part of an effect on a raised feature). False: the per-set-up tilt only, as before.
PLANAR_ABBE = False

#: Session 30 (abbe30): the Abbe shear columns (:data:`PLANAR_ABBE`) offered to the baseline's BIC choice beside the
#: grid instead of always taken: each grid is tried with and without them and BIC chooses among all (two columns
#: cost ``2 ln n``; on one grid given, BIC chooses whether they are taken). Built and OFF (docs/discovery-studies.md,
#: "Session 30: the planar baseline's Abbe columns ..."): on, the regress study names the screw alone 20/20 and
#: nothing 20/20 without it, gen_a/gen_b ``none`` 1000-1011 never take the columns, gen_a every effect 1000-1011
#: moves no name, but gen_b's moves 3 right -> wrong (part_change 1004, 1011, stylus_bending 1005) against 5 wrong
#: -> right: BIC judges the columns on residuals that still hold the effect. Acts only with :data:`PLANAR_ABBE`
#: off.
PLANAR_ABBE_BIC = False

#: Session 31 (abbe31): the Abbe shear columns (:data:`PLANAR_ABBE`) taken into the baseline only where the raised
#: touches show the shear's signature by a test of their own (:func:`abbe_raised_evidence`): the columns beyond the
#: baseline without them, fitted to its residual with one set-up left out at a time, predict the left-out set-up's
#: raised touches (the Abbe offset is the machine's: a function of the machine position, the same in every set-up),
#: and they leave at most this share of those touches' residual sum of squares (the held-out ratio). An effect on a
#: raised feature of the part (gen_b's closing slot, a bending stylus) follows the part or the set-up and is not
#: predicted across set-ups, where BIC (:data:`PLANAR_ABBE_BIC`) judged the columns on residuals that still held it.
#: Measured (docs/discovery-studies.md "Session 31: the planar Abbe columns judged beside the effect ..."): the regress study's
#: raised touches give 0.48-0.66 with the screw (its failing seeds 1, 10, 15: 0.48-0.53), 0.22-0.59 without; gen_b
#: every effect 1000-1011 0.667 and up (the nine campaigns ``PLANAR_ABBE`` cost: 0.74-1.04), gen_a 0.42 and up (two
#: below 0.6), gen_c 0.599 and up (one). At 0.6 on 1,000 tuning campaigns (gen_a/gen_b every effect 1000-1011 and none
#: to 1019, gen_c 200-219, the simulator 4000-4019): 0 right -> wrong, 2 wrong -> right (the simulator's thermal_drift
#: 4003, part_change 4017), no false alarm, every workpiece check as before; the shipped regress study passes.
#: On since session 31 (the lead, after the full suite with it on: only the simulator's none 1000 identity reference,
#: the regress study's pin and this rule's own older-test fixture move); judged on the session's blind seeds.
#: None: off (the columns only by :data:`PLANAR_ABBE` or :data:`PLANAR_ABBE_BIC`). Acts only with both off.
PLANAR_ABBE_GATE = 0.6
#: Largest dense design (bytes) :data:`PLANAR_ABBE_GATE`'s test forms; above it the columns are left out.
ABBE_GATE_DENSE_BYTES = 256 << 20


def abbe_raised_evidence(A0, H: np.ndarray, y: np.ndarray, setup: np.ndarray, tol: float) -> dict | None:
    """The raised touches' own evidence for the Abbe shear columns ``H`` beside the baseline design ``A0``.

    ``r`` the baseline's residual (``A0`` alone), ``Hp`` the columns beyond it. For each set-up ``j`` with raised
    touches (rows where ``H`` is non-zero): ``c`` fitted to ``r`` by ``Hp`` on every other set-up's rows, the
    left-out set-up's raised rows predicted; ``ratio`` = their summed squared prediction error over their summed
    ``r^2`` (1 and above: the columns predict nothing across set-ups; noise alone gives about ``1 + k / m``).
    Also ``share``: the columns' in-sample sum of squares over the raised rows' residual sum of squares (it can
    exceed 1: beyond the baseline the columns reach the other rows too), and
    ``F``: the columns' mean square against the raised rows' residual mean square beyond them. None where fewer
    than two set-ups have raised touches.
    """
    from .diagnosis import orth
    Q = orth(np.asarray(A0), tol=tol)
    r = y - Q @ (Q.T @ y)
    Hp = H - Q @ (Q.T @ H)
    raised = np.any(np.abs(H) > 0, axis=1)
    ids = np.unique(setup[raised])
    if ids.size < 2:
        return None
    press, ss0 = 0.0, 0.0
    for j in ids:
        out = setup == j
        c = np.linalg.lstsq(Hp[~out], r[~out], rcond=None)[0]
        m = out & raised
        e = r[m] - Hp[m] @ c
        press += float(e @ e)
        ss0 += float(r[m] @ r[m])
    c = np.linalg.lstsq(Hp, r, rcond=None)[0]
    ss_a = float(np.sum((Hp @ c) ** 2))
    rss_r = float(r[raised] @ r[raised])
    k = H.shape[1]
    m_r = int(raised.sum())
    rest = max(rss_r - ss_a, 1e-300)
    # (the raised rows' residual degrees of freedom taken as their count less the columns': the baseline's own
    # share of those rows is not counted, so F is on the low side)
    F = (ss_a / k) / (rest / max(m_r - k, 1))
    return {"ratio": press / max(ss0, 1e-300), "share": ss_a / max(rss_r, 1e-300), "F": F, "k": k,
            "raised": m_r, "setups": int(ids.size)}


def _abbe_shear_columns(t: Touches, des: selfcal.SelfCalDesign):
    """(columns (n, 2), names) of the Abbe terms' seen (shear) parts, or None when the raised touches do not
    identify them. :func:`core.selfcal.height_terms`' four slope columns (dEB/dx, dEB/dy, dEA/dx, dEA/dy) taken
    in the null space of its gauge rows on them (the twist and the growth of the raised targets about the C
    axis, which no touches see): the design's coordinates are about the C axis (:func:`planar`), where those
    rows read the Abbe block alone; where they do not (an off-centre design) the terms are left out."""
    ht = selfcal.height_terms(t, des, abbe="auto")
    if ht is None or not ht.abbe:
        return None
    ab = ht.blocks["ABBE"]
    rows = ht.C[2:]
    on, off = rows[:, ab], np.delete(rows, np.arange(ab.start, ab.stop), axis=1)
    if off.size and np.abs(off).max() > 1e-9 * max(1.0, np.abs(on).max()):
        return None
    u, s, vt = np.linalg.svd(on)
    N = vt[int(np.sum(s > 1e-12 * s.max())):].T
    return ht.A[:, ab] @ N, tuple(f"Abbe shear {i + 1} (height terms)" for i in range(N.shape[1]))


def _height_columns(t: Touches, des: selfcal.SelfCalDesign, abbe: bool | None = None):
    """C-axis tilt and Abbe columns for touches at more than one Z level.

    The paper's model is planar: every touch at one height. Touches at
    another height (sphere equators above the pocket) also see the C-axis
    tilt error motions ``EAC``/``EBC`` (per set-up) and the angular errors
    of X and Y through the height difference ``dz``: per-set-up columns
    ``n_x dz``, ``-n_y dz``. The reference set-up's pair is fixed (a tilt
    of the part in W is the same as shifting every raised target). With
    :data:`PLANAR_ABBE`, the angular errors' variation over the stroke
    too (:func:`_abbe_shear_columns`, two columns shared by every set-up);
    ``abbe`` True or False says so for this call (:data:`PLANAR_ABBE_BIC`'s
    two tries), None leaves it to :data:`PLANAR_ABBE`.
    Returns (columns, names, per-set-up column indices, gauge columns,
    levels) or None for a single level.
    """
    z = t.pn_R[:, 2]
    levels, counts = np.unique(np.round(z, 6), return_counts=True)
    if levels.size < 2:
        return None
    dz = z - levels[np.argmax(counts)]
    nx, ny = t.n_R[:, 0], t.n_R[:, 1]
    cols, names, own = [], [], []
    cn = [n.split("[", 1)[1].rstrip("]") for n in des.names[des.slices["EXC"]]]
    for j in range(len(des.setup_ids)):
        m = (t.setup == j).astype(float)
        own.append(np.array([len(cols), len(cols) + 1]))
        cols += [nx * dz * m, -ny * dz * m]
        names += [f"EBC,total[{cn[j]}]", f"EAC,total[{cn[j]}]"]
    ref = des.ref_setup
    ab = _abbe_shear_columns(t, des) if (PLANAR_ABBE if abbe is None else abbe) else None
    if ab is not None:
        cols += list(ab[0].T)
        names += list(ab[1])
    return np.column_stack(cols), tuple(names), own, [own[ref][0], own[ref][1]], tuple(float(v) for v in levels)


def _gated(t: Touches, des: selfcal.SelfCalDesign, h, tol: float, level: float):
    """``h`` (:func:`_height_columns` without the Abbe columns) with them where :func:`abbe_raised_evidence`'s
    held-out ratio is at most ``level`` (:data:`PLANAR_ABBE_GATE`). The test forms the dense design: a log whose
    design is above :data:`ABBE_GATE_DENSE_BYTES` is left without the columns (a bound of its own, not
    :data:`DENSE_DESIGN_BYTES`: whether the baseline is kept as a block design does not change the decision)."""
    ab = _abbe_shear_columns(t, des)
    if ab is None:
        return h
    p0 = des.A.shape[1] + h[0].shape[1]
    if 8 * t.n * (p0 + ab[0].shape[1]) > ABBE_GATE_DENSE_BYTES:
        return h
    ev = abbe_raised_evidence(np.hstack([des.A.toarray(), h[0]]), ab[0], t.dq_m, t.setup, tol)
    if ev is None or not ev["ratio"] <= level:
        return h
    H, hn, own, hg, levels = h
    return np.hstack([H, ab[0]]), hn + ab[1], own, hg, levels


#: :func:`precision_rank_tol` takes the step the log's text printed its nominal X, Y and normals to where finer than
#: their values' (session 31, rank31): a part whose nominals all lie on whole mm, printed ``10.0000000``, is exact
#: to 1e-7 mm, not rounded to 1 mm (before: q = 1 mm, a tolerance near 0.1, its workpiece lost). False: the values'
#: step alone (the behaviour before).
TEXT_STEPS = True


def precision_rank_tol(t: Touches, centre_m: np.ndarray) -> float:
    """The planar design's rank tolerance at the log's precision: ``max(RANK_TOL, RANK_QUANTUM_FACTOR * q_rel)``.

    ``q_rel`` is the larger of the nominal tip centres' quantum (X and Y printed to ``q`` mm,
    :func:`decimal_quantum`) over their largest distance ``L`` from the design's origin (the C axis, the
    coordinates the design is built in) and the normals' quantum (unit-free; components exactly 0 or +-1 left out:
    a log whose walls all lie along the axes, written ``1,0,0``, took ``q = 1`` and a tolerance of 10 before).
    The design's columns are built from these numbers (normals the reader normalised: the step they were printed
    to, ``Touches.n_step``); a direction exact in exact coordinates (the gauge's: the part's shift, rotation and
    size, the C-axis centre) is seen through their rounding at about ``q_rel`` (:data:`RANK_QUANTUM_FACTOR`), so no
    direction at that level is counted as determined. A full-precision log (7 decimals of a mm: ``q_rel`` about
    1e-9) keeps :data:`RANK_TOL`. Each step is the smaller of the values' (the fewest decimals that write them) and
    the text's (``Touches.text_steps``, the most decimals the file printed in the column, :data:`TEXT_STEPS`):
    values round by design (every nominal on a whole mm, printed ``10.0000000``) are exact, not rounded, and only
    the text says how many digits were printed (session 31, rank31: before, such a part took ``q`` = 1 mm, a
    tolerance near 0.1, and lost its workpiece). Touches not read from text (the simulator's, a log built in
    memory) have no text step: their values say it, as before.
    """
    xy = t.pn_R[:, :2] - np.asarray(centre_m, float)[:2]
    L = float(np.max(np.abs(xy))) if t.n else 0.0
    ts = (t.text_steps or {}) if TEXT_STEPS else {}

    def printed(q: float, cols) -> float:  # the values' step, or the text's where finer
        return min([q] + [ts[c] for c in cols if c in ts]) if all(c in ts for c in cols) else q

    q_pos = printed(decimal_quantum(t.pn_R[:, :2] / MM), ("Xn_mm", "Yn_mm")) * MM  # (the file's mm)
    # the normals' step: a component exactly 0 or +-1 is exact at any step (an axis-aligned wall), not a printed 1
    n = np.asarray(t.n_R, float)
    q_n = max(printed(decimal_quantum(n[~np.isin(np.abs(n), (0.0, 1.0))]), ("nx", "ny", "nz")),
              t.n_step)  # (n_step: normalised on reading, the values' step before it)
    q_rel = max(q_pos / L if L > 0 else 0.0, q_n)
    return max(RANK_TOL, RANK_QUANTUM_FACTOR * q_rel)


def _bic(rss: float, n: int, k: int) -> float:
    return n * np.log(max(rss, 1e-300) / n) + k * np.log(n)


#: Largest dense design (bytes, n x p doubles) :func:`planar` keeps in a caller's ``designs`` cache (the first
#: identifiable grid's, for the finer-map check's call on the same touches; its reflectors beside it, twice that
#: held while the caller's first search runs). Session 38 (fast38).
DESIGN_CACHE_BYTES = 16 << 20


#: :func:`planar` not comparing grids (``select_grid`` False on several) stops at the first identifiable one (the
#: one it takes; the grids after it were built and factored for nothing: four of the finer-map check's five designs
#: where 22 mm is identifiable). Exact; False builds them all, as before session 38 (fast38).
PLANAR_STOP_AT_FIRST = True


def _same_touches(a: Touches, b: Touches) -> bool:
    """Whether two touches hold the same values in every field (the same arrays, as a discovery's copies share
    them, at once; else compared; NaN equal to NaN)."""
    def same(u, v):
        if u is v:
            return True
        if isinstance(u, np.ndarray) or isinstance(v, np.ndarray):
            if not (isinstance(u, np.ndarray) and isinstance(v, np.ndarray)) or u.shape != v.shape \
                    or u.dtype != v.dtype:
                return False
            return bool(np.array_equal(u, v, equal_nan=u.dtype.kind in "fc"))
        if isinstance(u, dict) and isinstance(v, dict):
            return u.keys() == v.keys() and all(same(u[k], v[k]) for k in u)
        return u == v
    return all(same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(Touches))


def planar(t: Touches, grid_step_mm: float | None = None, grid_steps_mm=(22.0, 30.0, 40.0, 55.0, 80.0), *,
           select_grid: bool = True, yaw: str = "ECY", extra: dict | None = None,
           designs: dict | None = None) -> Baseline:
    """The 2D self-calibration baseline (eqs 1-18) on the grid the data choose.

    Touches with normals out of the XY plane must be removed by the caller.
    With touches at several Z levels, per-set-up C-axis tilt columns are
    added (:func:`_height_columns`). Grids are tried from ``grid_steps_mm``
    (or ``grid_step_mm`` alone), centred on the campaign
    (:func:`centred_grid`); among those whose design is identifiable beyond
    the gauge, BIC chooses (``select_grid``; else the finest), with
    :data:`PLANAR_ABBE_BIC` among each grid with and without the Abbe
    columns (on one grid given, whether they are taken). When none is
    (a symmetric part at C 90 deg apart), the finest grid that meets eq 6
    is used all the same: residuals do not depend on the gauge, and the
    workpiece is then reported as not identifiable.

    Where the grid is not compared (``select_grid`` False on several
    grids: the finest identifiable taken), the grids after the first
    identifiable one are not built (none of them could be taken).
    ``designs``: a cache a caller keeps between its calls on the same
    touches (:func:`core.discover.discover`'s first call and its finer-map
    check's): a call keeps there the first identifiable grid's design (a
    dense one up to :data:`DESIGN_CACHE_BYTES`), and a call that takes the
    first identifiable grid takes it from there rather than build the grids
    again, where the touches, grids, yaw and rank tolerance are the same
    (the same design, factorisation and choice: exact).

    Raises
    ------
    IdentifiabilityError
        No grid meets eq 6 (discovery needs the same targets at two or more
        C angles and more touches than unknowns).
    """
    steps = (grid_step_mm,) if grid_step_mm else tuple(grid_steps_mm)
    last = None
    fallback = None
    best: list = []

    def basis(item):
        """The grid's orthonormal basis (a dense design's Q formed when first asked: qr_formed)."""
        if item[-1] is None and not sp.issparse(item[2]):  # (a long log's sparse design: made again, Q by it)
            item[7] = qr_formed(item[7])
            item[-1] = orth(item[2], tol=tol, qr=item[7])
        return item[-1]

    def bic(item):
        Q = basis(item)
        if Q is None:  # (a long log's grid kept sparse as the best so far: its block basis made again to compare)
            Gs = item[1].slices["G"]
            Q = BlockDesign.from_sparse(item[2], np.arange(Gs.start, Gs.stop)).basis(tol)
        r = t.dq_m - Q @ (Q.T @ t.dq_m)
        return _bic(float(r @ r), t.n, Q.shape[1])

    def better(item, rank, best):
        """Whether the grid of ``item`` is BIC's choice over ``best`` ([score, item, bound]): its score, bound too.

        A dense design's Q is formed only for the grid chosen: its BIC is
        first taken from the reflectors (:func:`core.diagnosis.qr_rss`, the
        same number to rounding), with a safety margin on that rounding
        (``n 4e5 eps |y| / sqrt(rss)`` in BIC units, the residual's error
        taken as 4e5 eps |y|: a margin, not a proven bound; measured, the
        actual |BIC from the reflectors - BIC from the formed Q| is at most
        8e-6 of it on the 14 stored discover logs with dense grids and 4e-5
        on the benchmark's 1,800- and 4,800-touch logs); only where two
        grids' BICs differ by less than their margins are both formed and
        compared as ever. The choice is the one the formed BICs make.
        """
        if item[-1] is not None:  # (a block design's basis: its BIC formed; the first on a tie, the best kept sparse)
            score = bic(item)
            return (not best or score < best[0]), score, 0.0
        else:
            rss = qr_rss(item[7], t.dq_m, rank)
            score = _bic(rss, t.n, rank)
            bound = t.n * 4e5 * np.finfo(float).eps * np.linalg.norm(t.dq_m) / np.sqrt(max(rss, 1e-300))
        if not best:
            return True, score, bound
        if abs(score - best[0]) > bound + best[2]:
            return score < best[0], score, bound
        return bic(item) < bic(best[1]), score, bound

    # the design in coordinates about the C axis (the campaign's own origin): the
    # same matrix wherever the campaign sits in the machine
    c0 = c_axis_centre(t)
    if not np.all(np.isfinite(c0)):
        c0 = np.array([(t.pn_R[:, 0].max() + t.pn_R[:, 0].min()) / 2, (t.pn_R[:, 1].max() + t.pn_R[:, 1].min()) / 2])
    sh = np.array([c0[0], c0[1], 0.0])
    td = dataclasses.replace(t, pn_R=t.pn_R - sh, p_R=t.p_R - sh)
    tol = precision_rank_tol(t, sh) if PRECISION_RANK else RANK_TOL
    tries = [(st, ab) for st in steps for ab in ((False, True) if PLANAR_ABBE_BIC and not PLANAR_ABBE else (None,))]
    compare = (select_grid or len(steps) == 1) and len(tries) > 1
    # what determines the first identifiable grid's design and choice (with the touches: _same_touches)
    key = (tuple(tries), yaw, tol, PRECISION_RANK, PLANAR_ABBE, PLANAR_ABBE_BIC, PLANAR_ABBE_GATE,
           DENSE_DESIGN_BYTES)
    cached = designs.get("first") if designs is not None else None
    if not compare and cached is not None and cached[0] == key and _same_touches(cached[1], t):
        s0, des0, A0, C0, d0, names0, levels0, qr0, _ = cached[2]
        A0 = A0.copy()  # (the holder's own arrays: no baseline shares the cached ones)
        best = [0.0, [s0, des0, A0, C0.copy(), d0.copy(), names0, levels0, (qr0[0], qr0[1].copy(), A0), None], 0.0]
        tries = []
    first_seen = False  # (the first identifiable try met: the one a cache keeps)
    for st, ab in tries:
        grid = centred_grid(td.pn_R, st * MM)
        try:
            selfcal.check_count(td, grid)
            des = selfcal.build_design(td, grid, yaw=yaw)
        except IdentifiabilityError as e:
            last = e
            continue
        h = _height_columns(td, des, ab)
        if ab and (h is None or not any(n.startswith("Abbe shear") for n in h[1])):
            continue  # (no Abbe columns on this design: the try without them stands for it)
        if PLANAR_ABBE_GATE is not None and not PLANAR_ABBE and not PLANAR_ABBE_BIC and h is not None:
            h = _gated(td, des, h, tol, PLANAR_ABBE_GATE)
        p_all = des.A.shape[1] + (h[0].shape[1] if h is not None else 0)
        big = 8 * t.n * p_all > DENSE_DESIGN_BYTES
        A = des.A if big else des.A.toarray()
        C, d, names = des.C, des.d, tuple(des.names)
        levels = (float(np.median(t.pn_R[:, 2])),)
        if h is not None:
            H, hn, _, hg, levels = h
            p = A.shape[1]
            A = sp.hstack([A, sp.csr_matrix(H)]) if big else np.hstack([A, H])
            C = np.hstack([C, np.zeros((C.shape[0], H.shape[1]))])
            rows_g = np.zeros((len(hg), A.shape[1]))
            for r, c in enumerate(hg):
                rows_g[r, p + c] = 1.0
            C = np.vstack([C, rows_g])
            d = np.concatenate([d, np.zeros(len(hg))])
            names = names + hn
        if big:  # the targets' columns eliminated, only the machine's factored (lsq.BlockDesign)
            Gs = des.slices["G"]
            A_sparse = A
            A = BlockDesign.from_sparse(A, np.arange(Gs.start, Gs.stop))
            qr = None
            Q = A.basis(tol)
            rank = Q.shape[1]
        else:  # (Q formed only for the grid chosen: basis)
            qr = pivoted_qr(A, q=False)
            Q = None
            rank = qr_rank(qr[1], tol)
        item = [st, des, A, C, d, names, levels, qr, Q]
        # identifiable beyond the gauge: the gauge rows fix exactly the null space
        nullity = A.shape[1] - rank
        ident_here = nullity <= np.linalg.matrix_rank(C)
        if ident_here and not first_seen:
            first_seen = True
            if designs is not None and not big and 16 * A.size <= DESIGN_CACHE_BYTES:
                # (kept before better() forms this item's Q: its unformed factorisation, as built)
                designs["first"] = (key, t, list(item))
        if ident_here:  # the grid BIC chooses (the first on a tie), or the first: only the best kept so far
            # (BIC chooses the grid, or, on one grid given, whether the Abbe columns are taken)
            win, score, bound = (better(item, rank, best) if compare else (not best, 0.0, 0.0))
        if big:  # a long log's: kept as the sparse design, the block design made again for the grid chosen (one
            # dense block held at a time)
            item = [st, des, A_sparse, C, d, names, levels, None, None]
            del A_sparse  # (held by the item while it is the best: a grid not chosen lets its design go)
        if not ident_here:
            last = IdentifiabilityError(f"grid {st:g} mm: the design leaves {nullity - np.linalg.matrix_rank(C)} "
                                        "combination(s) beyond the gauge unseen (e.g. a symmetric part at C "
                                        "angles 90 deg apart)")
            if fallback is None and not best:
                fallback = (item, str(last))
            del item, A, Q, qr, des, h
            continue
        if win:
            best = [score, item, bound]
            fallback = None
        del item, A, Q, qr, des, h  # (the next grid's design is built without this one's, unless it is the best)
        if best and not compare and PLANAR_STOP_AT_FIRST:
            break  # (the first identifiable grid taken: no later one could be)
    cands = [best[1]] if best else []
    if not cands and fallback is None:
        raise IdentifiabilityError(f"no baseline: the 2D self-calibration does not meet eq 6 on grids of "
                                   f"{', '.join(f'{s:g}' for s in steps)} mm ({last})")
    if cands:
        item = cands[0]
        ident, why = True, ""
    else:
        item, why = fallback
        ident = False
    basis(item)  # (the chosen grid's Q formed: the engine starts from it)
    st, des, A, C, d, names, levels, qr, _ = item
    if sp.issparse(A):  # a long log's design, kept sparse while the grids were compared
        A = BlockDesign.from_sparse(A, np.arange(des.slices["G"].start, des.slices["G"].stop))
        # the sparse design let go before the data and covariates are made (its 183 MiB at 1e6 rows were held by
        # the grid's item and its SelfCalDesign until planar returned): what follows reads the design's names only
        des = dataclasses.replace(des, A=None, N=None)
        item[1] = item[2] = None
    data = planar_data(t, st * MM, extra)
    G = des.slices["G"]
    key = np.full(t.n, -1)
    pair = t.setup * len(t.target_ids) + t.target
    u, inv, cnt = np.unique(pair, return_inverse=True, return_counts=True)
    rep = cnt[inv] > 1
    key[rep] = pair[rep]
    conv = list(des.gauge)
    conv.append(f"design coordinates about the C axis at X {c0[0] / MM:.3f}, Y {c0[1] / MM:.3f} mm (the gauge's "
                "origin)")
    conv.append("workpiece estimates in the baseline's gauge (eqs 16-17)" if ident else
                "workpiece NOT identifiable by this design: " + why)
    model = "selfcal-2d (Ibaraki eqs 1-18)" + (
        f" + C-axis tilt and Abbe terms for {len(levels)} probing heights" if len(levels) > 1 else "")
    return Baseline(
        kind="planar", model=model, A=A, y=t.dq_m, names=names, groups=t.setup.copy(),
        group_ids=tuple(t.setup_ids), C=C, d=d, estimand=np.arange(G.start, G.stop),
        estimand_ids=tuple(des.target_ids), geometry=workpiece_geometry(t, data.c0_m), replicate=key,
        covariates=planar_covariates(data, sparse=isinstance(A, BlockDesign)), modes=planar_modes(data), mode_names=PLANAR_MODES,
        rows=np.asarray(t.row), data=data, identifiable=ident, why=why, conventions=tuple(conv),
        info={"grid_step_mm": st, "z_levels_mm": [v / MM for v in levels], "yaw": des.yaw,
              "grid": des.grid}, qr=qr, rank_tol=tol if PRECISION_RANK else None)  # the grid, not the design: its sparse A (177 MiB at 1e6 rows) read by none


def workpiece_geometry(t: Touches, c0_m: np.ndarray):
    """(P_W (N_w, 2), N_W (N_w, 2)): each target's nominal point and normal in one frame of the part.

    From the log's ``wx_mm ...`` columns when present; otherwise each
    target's first touch is turned back about the C-axis centre by its C
    angle (``w = R(C) (p - c0)``, eq 1). Either is good for removing a shift,
    rotation, scale and offset of the part (their span does not depend on
    which frame of the part is used).
    """
    first = {}
    for i in range(t.n):
        first.setdefault(int(t.target[i]), i)
    idx = np.array([first[k] for k in range(len(t.target_ids))])
    w, wn = _w_A(t)
    if np.all(np.isfinite(w[idx, :2])) and np.all(np.isfinite(wn[idx, :2])):
        return w[idx, :2].copy(), wn[idx, :2].copy()
    c0 = c0_m if np.all(np.isfinite(c0_m)) else np.zeros(2)
    R = selfcal.rot2(t.rot_rad[idx, 2])
    P = np.einsum("kab,kb->ka", R, t.pn_R[idx, :2] - c0)
    N = np.einsum("kab,kb->ka", R, t.n_R[idx, :2])
    return P, N


def check_planar(t: Touches) -> None:
    """Raise ConfigError unless the touches suit the planar baseline."""
    if t.n < 10:
        raise ConfigError(f"discover needs at least 10 valid touches with normals in the XY plane, got {t.n}")


# ---------------------------------------------------------------------------
# volumetric: the 21 errors of three linear axes from MFB placements
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class VolumetricData:
    """What the volumetric causes build their columns from (W frame, SI).

    One row per component (x, y, z in W) of each point of interest, in the
    order of :func:`core.volumetric.design`'s rows.

    Attributes
    ----------
    design : core.volumetric.VolumetricDesign
    comp : (n,) int
        Component of the row (0, 1, 2: x, y, z in W).
    meas : (n,) int
        Measurement of the row (index into ``meas_names``).
    meas_names, placements, styli : tuple of str
    placement, stylus : (n,) int
    t_s : (n,) float
        Time of the row's measurement, s.
    s : (n,) float
        Position of the row's point along its bar, centred on the bar and
        scaled by the half-length probed (-1..1).
    s_bar : (n,) float
        Position of the row's point along the whole bar, centred on the
        bar's middle and scaled by its half-length between the end holes
        (-1..1, :data:`core.mfb.MFB`'s holes; :data:`BAR_BENDING_ABOUT_BAR_MIDDLE`):
        where the bar's sag is symmetric, whatever holes were probed.
    g_perp : (n,) float
        The row's component of gravity perpendicular to the bar (gravity
        in W, :func:`gravity_W`: the machine's ``-z_R`` carried through the
        set-up's nominal table pose, less its part along the bar axis): how
        much a sag of the bar moves the point along this row.
    O_R : (n, 3) float
        The point's reading, machine frame, m.
    touch_cols : list
        Per measurement: (rows (int array), GW (len(rows), t) gain of the
        touches' shifts along their approach into those rows (W), d_W
        (t, 3) approach directions in W).
    x_bar : (n,) float
        The row's component of the bar's axis (x_A in W): how much a point
        moving along its bar moves this row (session 32; None where not
        built).
    """

    design: object = field(repr=False)
    comp: np.ndarray = field(repr=False)
    meas: np.ndarray = field(repr=False)
    meas_names: tuple
    placements: tuple
    styli: tuple
    placement: np.ndarray = field(repr=False)
    stylus: np.ndarray = field(repr=False)
    t_s: np.ndarray = field(repr=False)
    s: np.ndarray = field(repr=False)
    s_bar: np.ndarray = field(repr=False)
    g_perp: np.ndarray = field(repr=False)
    O_R: np.ndarray = field(repr=False)
    touch_cols: list = field(repr=False)
    x_bar: np.ndarray | None = field(default=None, repr=False)


#: Gravity in the machine's reference frame R, unit: ``-z_R``. An assumption: a vertical machine, whose R has its
#: z axis up (every machine of :mod:`scenarios.mfb` and the papers'; a horizontal machine would need its own).
GRAVITY_R = (0.0, 0.0, -1.0)
#: Whether the volumetric baseline's gravity (``VolumetricData.g_perp``, the ``bar_bending`` columns) is taken into
#: each measurement's W through its set-up's nominal table pose (``core.kinematics.T_R_W`` at the measurement's
#: rotary positions). W turns with the table: on the 5-axis plan X3 (A = -90) lies with gravity along -y_W, the
#: standing bars VXa/b/c (A = -90) along gravity (no sag), DXZ and AXZ (A = -90, C = -+45) at |g_perp| = 0.71.
#: Off: gravity is ``-z_W`` at every pose (sessions 13-30; review31c F4). A machine without rotary axes reads the
#: same either way (W does not turn: the same doubles, session 31).
BAR_GRAVITY_THROUGH_TABLE = True
#: Whether the ``bar_bending`` columns take the position along the bar from the bar's middle (hole 6.5 of the 12 of
#: :data:`core.mfb.MFB`, by the holes' labels: ``VolumetricData.s_bar``), where a bar on symmetric supports sags
#: symmetrically, rather than from the middle of the holes a measurement probed (``s``). Most measurements probe
#: part of the bar (3-axis: holes 1-8 or 1-7 on 14 of 17; 5-axis: e.g. 7-12, 5-9): a sag about the bar's middle is
#: then not the even quartic of the probed holes. Session 31 (bend31): the simulator's hidden sag (about the bar's
#: middle, scenarios.hidden) fitted from its effect alone by the bending columns read 1.15 of 3.90 um (mfb-3axis,
#: seed 4001) and 0.77 of 3.53 um (mfb-5axis, seed 4000) about the probed holes' middle, 3.90 and 3.54 about the
#: bar's. Off: about the probed holes (sessions 13-30). The ``along_bar`` covariate keeps ``s``.
BAR_BENDING_ABOUT_BAR_MIDDLE = True


def gravity_W(chain: str, rot_rad=(), rotary_points_R_m=None) -> np.ndarray:
    """(3,) gravity (unit) in the workpiece frame W at the rotary positions ``rot_rad`` (chain's rotary order, rad).

    ``R_RW^T GRAVITY_R`` with ``R_RW`` the nominal orientation of W in R
    (:func:`core.kinematics.T_R_W`, no errors: a table tilted by its
    angular errors turns gravity by urad, which moves a few-um sag by
    picometres). A chain without rotary axes (or with
    :data:`BAR_GRAVITY_THROUGH_TABLE` off): ``GRAVITY_R`` itself.
    """
    from . import kinematics as kin
    from .chain import parse_chain

    g = np.array(GRAVITY_R, float)
    ch = parse_chain(chain)
    if not BAR_GRAVITY_THROUGH_TABLE or not ch.rotary_axes:
        return g
    rot = np.asarray(rot_rad, float).reshape(1, -1)
    geom = kin.ChainGeometry.of(ch, (0.0, 0.0, 0.0), rotary_points_R_m)
    R = kin.T_R_W(geom, np.zeros((1, 3)), rot)[0, :3, :3]
    return R.T @ g


VOLUMETRIC_MODES = ("x (W)", "y (W)", "z (W)")
#: Cross-validation folds of the volumetric baseline: the holes, by their
#: number modulo this. Every placement is needed to see some errors (the plan
#: is built that way), so leaving one out extrapolates; leaving a quarter of
#: every bar's holes out interpolates, as a new measurement would.
VOLUMETRIC_FOLDS = 4

#: The volumetric baseline's observations reduced to first order at the exact solution
#: (:func:`core.volumetric.reduced_design`: ``y = r(theta) + A theta``, the exact model's residual at the
#: Gauss-Newton identification plus the first-order model there), not (2)'s own left side. (2) is first
#: order in the placement errors, and a bar turned by w (pitch, yaw) reads a length changed by
#: -(w_y^2 + w_z^2) / 2 (0.7 ppm from placement to placement at the default placement tolerance), which
#: no placement column absorbs and a scale drift between placements takes. Session 29 (docs/discovery-studies.md,
#: "the volumetric drift magnitudes' U95 and the placements"): 20 MFB campaigns (seeds 5-24, the test's
#: set-up, +-s injected), the thermal_drift magnitudes within their U95 39 -> 56 of 60 (+s), their error
#: over the standard uncertainty the U95 implies RMS 2.2-3.4 -> 1.0-1.3; without placement draws the same
#: campaigns read 55 of 60 either way. Off: (2)'s own left side (sessions 13-28).
VOLUMETRIC_REDUCED_AT_SOLUTION = True


def volumetric(meas, chain: str, nodes: dict, rotary_points_R_m=None, times_s: dict | None = None, *,
               sigma_probe_m: float | None = None, u_cal_m=None, cal_map=None) -> Baseline:
    """The volumetric MFB baseline: the first-order problem (2)/(3) of :mod:`core.volumetric` with its ISO gauge.

    Parameters
    ----------
    meas : sequence of core.volumetric.Measurement
    chain, nodes, rotary_points_R_m : as :func:`core.volumetric.design`
    times_s : dict measurement name -> time of the measurement (s), optional
        Without it, the measurements' order (one unit each).
    sigma_probe_m : float, optional
        The probe's declared repeatability (k = 1, along the approach), m.
    u_cal_m : (N, 3) float, optional
        The bar's declared calibration standard uncertainty per hole and
        direction of A (its certificate's U / 2), m; with ``sigma_probe_m``
        and :data:`VOLUMETRIC_BAR_CALIBRATION_NOISE`, the rows' noise
        covariance holds the bar's deviation from its calibration
        (:func:`_bar_calibration_columns`, :func:`_noise_whitening`).
    cal_map : (3N, 3N) float, optional
        How the calibration's independent errors reach the points
        (:func:`core.mfb.calibration_map`); None: one independent error per
        hole and direction.

    The rows are the points' deviations, one per W component; the folds of
    the cross-validation are the holes (:data:`VOLUMETRIC_FOLDS`); the
    estimand is the error tables (every motion error on its nodes and the
    squarenesses). The covariates: time, placement, stylus, position along
    the bar, x, y, z, component.

    The left side is (2)'s reduced to first order at the exact model's
    solution (:data:`VOLUMETRIC_REDUCED_AT_SOLUTION`,
    :func:`core.volumetric.reduced_design`): unweighted, its least squares
    is the identification's solution
    (:func:`core.volumetric.identify_volumetric`; the baseline's rows are
    whitened, which weights the fit a little differently), and what
    discovery fits beside it is fitted against the exact model's residuals,
    not against (2)'s second order in the placements' turns. The matrix is
    (2)'s, its null space exactly the gauge's.
    """
    from . import volumetric as vol
    from .mfb import MFB

    bar_u = _bar_noise_inputs(sigma_probe_m, u_cal_m, cal_map, MFB.n_holes)  # (refused before any work)
    meas = list(meas)
    if VOLUMETRIC_REDUCED_AT_SOLUTION:
        d, theta_x = vol.reduced_design(meas, chain, nodes, rotary_points_R_m)
    else:
        d, theta_x = vol.design(meas, chain, nodes, rotary_points_R_m), None
    names = [m.name for m in meas]
    places = list(dict.fromkeys(m.placement for m in meas))
    styli = list(dict.fromkeys(tuple(np.round(np.asarray(m.J_m, float), 6)) for m in meas))
    comp, mi, pl, st, t_s, s, sb, gp, O, touch, fold, point, xb = [], [], [], [], [], [], [], [], [], [], [], [], []
    half_bar = (MFB.n_holes - 1) / 2
    row = 0
    for i, m in enumerate(meas):
        k = len(m.holes)
        T = np.asarray(m.T_W_A, float)
        R = T[:3, :3]
        x_A = R[:, 0]
        g = gravity_W(chain, m.rot_rad, rotary_points_R_m)
        g_perp = g - (g @ x_A) * x_A
        sA = np.asarray(m.O_A, float)[:, 0]
        mid, half = (sA.max() + sA.min()) / 2, max(np.ptp(sA) / 2, 1e-9)
        t_i = float((times_s or {}).get(m.name, i))
        J = tuple(np.round(np.asarray(m.J_m, float), 6))
        for p in range(k):
            for c in range(3):
                comp.append(c)
                mi.append(i)
                pl.append(places.index(m.placement))
                st.append(styli.index(J))
                t_s.append(t_i)
                s.append((sA[p] - mid) / half)
                sb.append((int(m.holes[p]) - 1 - half_bar) / half_bar if BAR_BENDING_ABOUT_BAR_MIDDLE else s[-1])
                gp.append(g_perp[c])
                xb.append(x_A[c])
                O.append(np.asarray(m.O_R, float)[p])
                fold.append(int(m.holes[p]) % VOLUMETRIC_FOLDS)
                point.append(len(point) // 3)
        if m.G_A is not None and m.d_A is not None:
            t = np.asarray(m.G_A).shape[1]
            GW = np.einsum("ij,kjt->kit", R, np.asarray(m.G_A, float).reshape(k, 3, t)).reshape(3 * k, t)
            touch.append((np.arange(row, row + 3 * k), GW, np.asarray(m.d_A, float) @ R.T))
        row += 3 * k
    # rows the model removes (the roll component of the mistake-proofing holes: zero in the design and the
    # observation) carry nothing: left out, found by the pose's structure (core.volumetric.roll_rows). Until
    # session 38 by their values (any A or y != 0 kept the row): a pose 1e-16 off its exact entries kept them
    keep = ~np.concatenate([vol.roll_rows(m) for m in meas])
    new = np.cumsum(keep) - 1
    touch = [(new[r[keep[r]]], GW[keep[r]], dW) for r, GW, dW in touch]
    sel = np.flatnonzero(keep)
    comp = np.array(comp)[sel]
    fold = np.array(fold)[sel]
    n = len(sel)
    data = VolumetricData(d, comp, np.array(mi)[sel], tuple(names), tuple(places),
                          tuple(",".join(f"{v * 1e3:g}" for v in J) for J in styli), np.array(pl)[sel],
                          np.array(st)[sel], np.array(t_s, float)[sel], np.array(s)[sel], np.array(sb, float)[sel],
                          np.array(gp)[sel], np.array(O)[sel], touch, np.array(xb, float)[sel])
    L = (_bar_calibration_columns(meas, sel, *bar_u) if bar_u is not None else None)
    W = (_point_whitening(touch, n, np.array(point)[sel]) if L is None
         else _noise_whitening(touch, n, np.array(point)[sel], L))
    modes = np.eye(3)[comp]
    allm = (0, 1, 2)
    covs = [Covariate("placement", data.placement, "categorical", 0, allm, "the placement", "time"),
            Covariate("stylus", data.stylus, "categorical", 0, allm, "the stylus", "direction"),
            Covariate("along_bar", data.s, "smooth", 5, allm, "the position along the bar", "position"),
            Covariate("x", data.O_R[:, 0], "smooth", 6, allm, "the x position", "position"),
            Covariate("y", data.O_R[:, 1], "smooth", 6, allm, "the y position", "position"),
            Covariate("z", data.O_R[:, 2], "smooth", 6, allm, "the z position", "position")]
    if np.unique(data.t_s).size >= 3:
        covs.insert(0, Covariate("time", data.t_s, "smooth", min(5, np.unique(data.t_s).size), allm, "time", "time"))
    if VOLUMETRIC_ALONG_BAR_BY_MEASUREMENT and np.unique(data.meas).size >= 2:
        um_ = np.unique(data.meas)
        P = data.s[:, None] * (data.meas[:, None] == um_[None, :])
        covs.append(Covariate("along_bar_by_measurement", P, "basis", P.shape[1], allm,
                              "the position along the bar, differently in each measurement (a scale that changes)",
                              "time"))
    est = np.concatenate([np.arange(d.slices[s_].start, d.slices[s_].stop) for s_ in vol.MOTION + vol.SQUARENESS])
    return Baseline(
        kind="volumetric", model="volumetric MFB (Viprey eqs 8-12, touch model (3))", A=W @ d.A[sel],
        y=W @ d.y[sel], names=d.names, whiten=W,
        groups=np.array(fold), group_ids=tuple(f"holes = {k} mod {VOLUMETRIC_FOLDS}" for k in range(VOLUMETRIC_FOLDS)),
        C=d.C, d=np.zeros(d.C.shape[0]), estimand=est,
        estimand_ids=tuple(d.names[i] for i in est), geometry=None, replicate=np.full(n, -1),
        covariates=tuple(covs), modes=modes, mode_names=VOLUMETRIC_MODES, rows=sel, data=data,
        identifiable=not d.unseen.shape[1], why="" if not d.unseen.shape[1] else "the plan leaves combinations unseen",
        conventions=tuple(d.gauge) + (("rows whitened by each point's noise covariance (its touches' gain)",)
                                      if L is None else
                                      ("rows whitened by the noise covariance of the probing (each point's touches' "
                                       "gain, the declared repeatability) and of the bar's declared calibration "
                                       "(its deviation per hole, the same in every placement)",))
        + (("observations reduced to first order at the exact model's solution (placements turned: second order)",)
           if theta_x is not None else ()),
        info={"placements": len(places), "measurements": len(meas), "cv": False}
        | ({"noise_model": {"sigma_probe_um": float(sigma_probe_m) * 1e6,
                            "u_cal_um_max": float(np.max(u_cal_m)) * 1e6, "bar_calibration": True}}
           if L is not None else {}),
        estimand_label="error tables")


#: Whether the volumetric (MFB) baseline's diagnosis tests the position along the bar linearly, with its own slope
#: in each measurement and each component (``along_bar_by_measurement``): a scale that changes between placements (an
#: HVAC cycle's +-8 ppm on X, review30c's finding 4: points moved by up to 2.19 um read `none`, the plain
#: ``along_bar`` smooth, one function for every placement, at p = 1.6e-6 but 0.07 um, below the materiality of a
#: noise the effect itself inflated). Built and OFF: on, the HVAC scale reads `unexplained` 24 of 24 (4 and 8 ppm,
#: mfb-3axis seeds 1-12; none 20, outlier? 3, unexplained 1 before) and nothing else moves on campaigns whose bar is
#: as calibrated (44 plain: none 44; 12 monotone drifts: thermal_drift 12), but on the realistic bar that differs
#: from its calibration by 0.2-0.35 um per hole (``bar_cal_error``) the slopes take the bar's own error along each
#: placement's direction: 7 of 44 plain campaigns `none`/`outlier` -> `unexplained` (docs/discovery-studies.md, "Session 30:
#: MFB"). Session 30.
VOLUMETRIC_ALONG_BAR_BY_MEASUREMENT = False


#: Whether the volumetric (MFB) baseline's noise model holds the bar's declared calibration uncertainty when its
#: builder is given it (``u_cal_m`` with ``sigma_probe_m``: :func:`volumetric`). The bar's true form differs from
#: its calibration by a draw of that uncertainty (0.2-0.35 um per hole and direction on the simulated bar, 2-3 x the
#: 0.125 um touch noise); that draw is the same in every placement, so the residuals of the holes follow the
#: position along the bar, and discovery, whose rows were whitened by the touch noise alone, read it as the
#: machine's structure (session 35: 3 of 28 effect-free realistic-bar campaigns `unexplained`/`outlier?`; the
#: diagnosis "residuals follow the position along the bar: 0.13 um, p < 1e-6" on simulator 4007). A metrologist
#: declares the artefact's calibration uncertainty; residual structure consistent with it is not a cause. On, the
#: rows are whitened by the probing noise and the bar's calibration covariance together (generalised least
#: squares with the bar's deviation a random field of declared covariance: :func:`_noise_whitening`). Off: the
#: touch noise alone (sessions 13-35), whatever the builder is given. Session 36 (mfb36, docs/discovery-studies.md
#: "Session 36: MFB discovery judged with the bar's declared calibration").
VOLUMETRIC_BAR_CALIBRATION_NOISE = True


def _bar_noise_inputs(sigma_probe_m, u_cal_m, cal_map, n_holes: int):
    """(sigma_probe_m, u_cal (N, 3), cal_map or None) when the bar's calibration enters the noise model, else None;
    a bad input refused in one line (ConfigError)."""
    if u_cal_m is None and sigma_probe_m is None and cal_map is None:
        return None
    if u_cal_m is None or sigma_probe_m is None:
        raise ConfigError("volumetric: the bar's calibration uncertainty needs both u_cal_m and sigma_probe_m "
                          f"(got u_cal_m {'None' if u_cal_m is None else 'given'}, sigma_probe_m {sigma_probe_m!r})")
    sig = float(sigma_probe_m)
    if not (np.isfinite(sig) and sig > 0):
        raise ConfigError(f"volumetric: sigma_probe_m must be > 0 (the probe's repeatability, m), "
                          f"got {sigma_probe_m!r}")
    u = np.asarray(u_cal_m, float)
    if u.shape != (n_holes, 3) or not np.all(np.isfinite(u)) or np.any(u < 0):
        raise ConfigError(f"volumetric: u_cal_m must be finite values >= 0 of shape ({n_holes}, 3), got {u.shape}")
    M = None
    if cal_map is not None:
        M = np.asarray(cal_map, float)
        if M.shape != (3 * n_holes, 3 * n_holes) or not np.all(np.isfinite(M)):
            raise ConfigError(f"volumetric: cal_map must be a finite ({3 * n_holes}, {3 * n_holes}) matrix, "
                              f"got {M.shape}")
    if not VOLUMETRIC_BAR_CALIBRATION_NOISE or not np.any(u > 0):
        return None
    return sig, u, M


def _bar_calibration_columns(meas, sel, sigma_probe_m: float, u_cal: np.ndarray, cal_map) -> np.ndarray:
    """(n, 3N) how the bar's calibration errors reach the baseline's rows, in units of the probing sigma.

    A hole's true position in the bar frame A differs from its calibrated one
    (``Measurement.O_A``) by ``delta_h``, the same in every placement; its
    point then reads ``R_WA delta_h`` off in W (first order, at the nominal
    pose; the mistake-proofing holes without their z_A component, as the
    design's rows). ``delta = cal_map @ (u_cal * n)``, n independent standard
    normal (:func:`core.mfb.calibration_map`). Columns scaled by
    ``1 / sigma_probe_m``: ``L L^T`` beside the touches' gain ``G G^T`` is the
    rows' noise covariance over the probing variance."""
    from . import volumetric as vol

    N = u_cal.shape[0]
    rows = []
    for m in meas:
        T = np.asarray(m.T_W_A, float)
        R = T[:3, :3]
        zA = R[:, 2]
        Pz = np.eye(3) - np.outer(zA, zA)
        off = vol.mistake_proofing(m.O_A)
        blk = np.zeros((3 * len(m.holes), 3 * N))
        for a, h in enumerate(m.holes):
            blk[3 * a:3 * a + 3, 3 * (int(h) - 1):3 * int(h)] = Pz @ R if off[a] else R
        rows.append(blk)
    Bm = np.vstack(rows)[sel]
    if cal_map is not None:
        Bm = Bm @ cal_map
    return Bm * (u_cal.ravel() / sigma_probe_m)[None, :]


def _noise_whitening(touch_cols, n: int, point: np.ndarray, L: np.ndarray) -> np.ndarray:
    """(n, n) inverse square root of the rows' noise covariance: the probing noise of each point (its touches'
    gain, as :func:`_point_whitening`) plus the bar's calibration ``L L^T`` (:func:`_bar_calibration_columns`,
    in units of the probing variance), which couples the rows of one hole in every placement.

    The whitened rows are independent, of one variance (the probing noise's, scaled as
    :func:`_point_whitening` scales it) when the bar differs from its calibration as declared: generalised
    least squares with the bar's deviation a nuisance of known prior, the rows' sum of squares of the
    baseline and of every term beside it the chi-square the engine's tests take. The matrix is the symmetric
    inverse square root (each whitened row stays its own row's, less what the other placements of its hole
    say of the bar). Rows without touches carry the probing variance ``c^2`` (``c`` the points' mean gain)."""
    S = np.zeros((n, n))
    has = np.zeros(n, bool)
    scale = []
    for rows, GW, _ in touch_cols:
        for p in np.unique(point[rows]):
            r = rows[point[rows] == p]
            G = GW[point[rows] == p]
            S[np.ix_(r, r)] = G @ G.T
            has[r] = True
            scale.append(np.mean(np.diag(G @ G.T)))
    c = np.sqrt(np.mean(scale)) if scale else 1.0
    lone = np.flatnonzero(~has)
    S[lone, lone] = 1.0 / c ** 2
    S += L @ L.T
    w, V = np.linalg.eigh(S)
    ok = w > 1e-8 * max(w.max(), 1e-300)
    return c * ((V[:, ok] / np.sqrt(w[ok])) @ V[:, ok].T + V[:, ~ok] @ V[:, ~ok].T)


def _point_whitening(touch_cols, n: int, point: np.ndarray) -> np.ndarray:
    """(n, n) inverse square root of each point's noise covariance (a 3 x 3 block per point).

    A point's components come from shared touches: touch noise e
    (independent, one variance) reaches them as ``GW e``, covariance
    ``GW GW^T`` (up to the variance). Its inverse square root per point
    (eigen-decomposition, directions below 1e-8 of the largest left as they
    are) makes a point's rows independent and of one variance; the matrix
    is scaled so that the rows keep their mean size (residuals stay in
    micrometre-like units). Points are kept apart (neighbouring holes share
    rods, a correlation left in): the cross-validation folds are points,
    and whitening across them would mix the folds. Rows without touches are
    left unchanged.
    """
    W = np.eye(n)
    blocks, scale = [], []
    for rows, GW, _ in touch_cols:
        for p in np.unique(point[rows]):
            r = rows[point[rows] == p]
            Cm = GW[point[rows] == p] @ GW[point[rows] == p].T
            w, V = np.linalg.eigh(Cm)
            ok = w > 1e-8 * max(w.max(), 1e-300)
            blocks.append((r, (V[:, ok] / np.sqrt(w[ok])) @ V[:, ok].T + V[:, ~ok] @ V[:, ~ok].T))
            scale.append(np.mean(np.diag(Cm)))
    c = np.sqrt(np.mean(scale)) if scale else 1.0
    for r, Wi in blocks:
        W[np.ix_(r, r)] = c * Wi
    return W


# ---------------------------------------------------------------------------
# positioning: ISO 230-2 runs of one axis
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class PositioningData:
    """What the positioning causes build their columns from (SI).

    Attributes
    ----------
    x : (n,) float
        Target position, m (or rad for a rotary axis).
    xs : (n,) float
        Centred on the targets and scaled by their half-span (-1..1).
    L : float
        Half-span of the targets, m.
    t_s : (n,) float
        Time of each reading (or its order), s.
    tau : (n,) float
        Time since the first reading over the test's span, 0..1.
    direction : (n,) int
        +1 or -1.
    cycle : (n,) int
    """

    x: np.ndarray = field(repr=False)
    xs: np.ndarray = field(repr=False)
    L: float
    t_s: np.ndarray = field(repr=False)
    tau: np.ndarray = field(repr=False)
    direction: np.ndarray = field(repr=False)
    cycle: np.ndarray = field(repr=False)


#: Columns of the positioning baseline's ``time_by_direction`` covariate (0: none): the direction (+1/-1) times
#: the first Legendre polynomials of the normalised time (degree 1 to this), so that a reversal that grows or
#: shrinks through the test shows as structure. A + trend up and a - trend down cancel in a plain time smooth,
#: and the repeats of one target in one direction across cycles pool it as noise (review30c's backlash_grow3
#: 401: 1.53 um RMS left outside the per-target-and-direction means, true repeatability 0.62 um, read `none`
#: on a repeats' noise of 1.13 um with time at p = 0.004; docs/discovery-studies.md, "Session 30: positioning").
POSITIONING_TIME_BY_DIRECTION = 3


#: The positioning baseline's ``direction_by_cycle`` covariate: the direction (+1/-1) times each cycle's indicator,
#: a reversal of its own in each cycle (review31c rev_feed: the lost motion changing with the feed in alternate
#: cycles read `unexplained` with the diagnosis pointing at order and time; this says where it lives). Its columns
#: are taken beyond ``time_by_direction``'s (a reversal growing through the test is that one's: first there as
#: before). Session 31. False: not tested.
POSITIONING_DIRECTION_BY_CYCLE = True


def _time_by_direction_basis(tau: np.ndarray) -> np.ndarray:
    """(n, POSITIONING_TIME_BY_DIRECTION) Legendre polynomials P_1..P_k of ``2 tau - 1`` (tau in [0, 1])."""
    u = 2.0 * np.asarray(tau, float) - 1.0
    return np.polynomial.legendre.legvander(u, POSITIONING_TIME_BY_DIRECTION)[:, 1:]


#: Report unit of a rotary axis's positioning discovery: the one ``vmt iso230-2`` reports (core.positioning's
#: REPORT_UNIT, arc seconds), its targets named in degrees. The engine writes its figures as ``value * 1e6`` under
#: ``_um`` keys; a rotary baseline holds its readings in arcsec x 1e-6 (:data:`ROTARY_ENGINE_PER_RAD`) so that
#: those numbers are arc seconds, and :func:`positioning_report_units` names them so. Session 31 (review31 F11):
#: they were radians x 1e6 (urad) under ``_um`` keys and the targets radians x 1e3 under "mm" ('P=785.398mm+' for
#: 45 deg).
ROTARY_REPORT_UNIT = "arcsec"
#: Engine units per radian of a rotary positioning baseline: arc seconds per radian x 1e-6.
ROTARY_ENGINE_PER_RAD = 180.0 / np.pi * 3600.0 * 1e-6


def positioning_report_units(rep, unit: str):
    """A discovery report (or any part of it: dict, list, str) with its length unit renamed to ``unit``.

    Keys ``*_um`` and ``*_um_*`` (and ``noise_um``) become ``*_<unit>``; in text, ``µm``/``um`` after a number or
    a space, and ``_um`` in a parameter's name, become the unit. The values are not touched: they already are
    in ``unit`` (a rotary positioning baseline's engine unit, :data:`ROTARY_ENGINE_PER_RAD`). Identity for "um".
    """
    if unit == "um":
        return rep
    if isinstance(rep, dict):
        return {positioning_report_units(k, unit) if isinstance(k, str) else k: positioning_report_units(v, unit)
                for k, v in rep.items()}
    if isinstance(rep, (list, tuple)):
        return type(rep)(positioning_report_units(v, unit) for v in rep)
    if isinstance(rep, str):
        s = re.sub(r"_um(?=_|\b)", f"_{unit}", rep)
        s = s.replace("µm", unit)
        return re.sub(r"(?<=[\d\s])um\b", unit, s)
    return rep


#: A positioning run's report says its own words where the engine's are a planar campaign's (session 31, review31c):
#: a fold is a cycle, a row a reading ("one event (a touch, or one set-up's touches)", ``time_trend: 'per set-up'``,
#: "leave one group (set-up) out"). Applied to the report's text values (never to keys); False: the engine's words.
POSITIONING_REPORT_WORDS = True
_POSITIONING_WORDS = ((r"\bset-ups\b", "cycles"), (r"\bset-up\b", "cycle"), (r"\btouches\b", "readings"),
                      (r"\btouch\b", "reading"))


#: What a positioning baseline takes for the time when its log has no clock (no ``t_s``, or one with an empty cell):
#: the reading order. Said in its ``info["time"]`` (the report's ``baseline.time``) and in the words of the
#: covariates built on it (:func:`positioning`).
NO_CLOCK_TIME = "the reading order (the log has no clock)"
#: The unit a finding's time figure is in when the log has no clock: a key ending in ``_s`` (``time_constant_s``)
#: counts readings, and is named so in the report (``time_constant_readings``: :func:`positioning_report`).
NO_CLOCK_TIME_SUFFIX = "_readings"


def _no_clock_keys(rep: dict) -> dict:
    """The report ``rep`` of a positioning log without a clock with its findings' time figures named in readings:
    every parameter key ending in ``_s`` (the engine read the reading order as seconds) renamed ``..._readings``,
    wherever the finding names it (its params, U95, evidence keys, lists and words), and a rival named "a smooth
    term in time" said to be the reading order's."""
    keys = {k for f in rep.get("findings") or () for k in (f.get("params") or {}) if k.endswith("_s")}
    new = {k: k[:-2] + NO_CLOCK_TIME_SUFFIX for k in keys}
    pat = re.compile(r"\b(" + "|".join(re.escape(k) for k in sorted(keys)) + r")\b")

    def ren(o):
        if isinstance(o, dict):
            return {new.get(k, k) if isinstance(k, str) else k: ren(v) for k, v in o.items()}
        if isinstance(o, list):
            return [ren(v) for v in o]
        if isinstance(o, tuple):
            return tuple(ren(v) for v in o)
        if isinstance(o, str):   # (a rival named by its covariate: "a smooth term in time" is the order's)
            return re.sub(r"\bterm in time\b", "term in time (the reading order here)",
                          pat.sub(lambda m: new[m.group(1)], o) if keys else o)
        return o
    return {**rep, "findings": ren(rep["findings"])}


def positioning_report(rep: dict, bl: "Baseline") -> dict:
    """A positioning baseline's discovery report in its own words and units (:data:`POSITIONING_REPORT_WORDS`,
    :func:`positioning_report_units`); any other report as it is. A log without a clock (``info["time"]``,
    :data:`NO_CLOCK_TIME`): its findings' time figures named in readings (:func:`_no_clock_keys`; the diagnosis
    already says "the reading order", :func:`positioning`'s words)."""
    if bl.kind != "positioning":
        return rep
    if (bl.info or {}).get("time") == NO_CLOCK_TIME:
        rep = _no_clock_keys(rep)
    if POSITIONING_REPORT_WORDS:
        def words(o):
            if isinstance(o, dict):
                return {k: words(v) for k, v in o.items()}
            if isinstance(o, list):
                return [words(v) for v in o]
            if isinstance(o, str):
                for a, b in _POSITIONING_WORDS:
                    o = re.sub(a, b, o)
            return o
        rep = words(rep)
    return positioning_report_units(rep, bl.info.get("unit", "um"))


def positioning(target_m, direction, cycle, deviation_m, t_s=None, temps: dict | None = None,
                rotary: bool = False) -> Baseline:
    """The ISO 230-2 baseline: a systematic deviation per target and direction, plus repeatability.

    Parameters
    ----------
    target_m : (n,) float
        Commanded target ``P_i`` of each reading, m (rad for a rotary axis).
    direction : (n,) int or str
        ``+1``/``"+"`` or ``-1``/``"-"``: the approach direction.
    cycle : (n,) int
        Run ``j`` of each reading.
    deviation_m : (n,) float
        ``x_ij = P_ij - P_i`` (ISO 230-2), m.
    t_s : (n,) float, optional
        Time of each reading; the reading order when absent (said: ``info["time"]`` is then
        :data:`NO_CLOCK_TIME`, the time covariates' words name it, and the report's time figures are in
        readings, :func:`positioning_report`).
    temps : dict name -> (n,) float, optional
        Temperature sensors (``temp_<name>_C``).
    rotary : bool
        A rotary axis (targets and deviations in rad): the baseline holds them in arc seconds x 1e-6
        (:data:`ROTARY_ENGINE_PER_RAD`), names its targets in degrees (``P=45deg+``) and says
        ``unit: arcsec``, ``target_unit: deg`` in ``info``; the report's figures are then arc seconds
        (:func:`positioning_report_units` names them). A linear axis's baseline is as before.

    The design has one column per (target, direction): the mean
    unidirectional positional deviations of ISO 230-2. Whatever the axis
    does the same way in every cycle (its pitch error, a reversal that
    varies along it, a periodic error at the targets) is in those means;
    discovery looks for what changes between cycles (drift, warm-up,
    outliers) and for structure against time, order or temperature. The
    folds of the cross-validation are the cycles; replicates are the
    readings of one target in one direction (their scatter is the
    repeatability).

    Raises
    ------
    ConfigError
        Arrays of different lengths, fewer than two cycles, a direction
        other than +/-.
    """
    x = np.asarray(target_m, float).ravel()
    dev = np.asarray(deviation_m, float).ravel()
    if rotary:
        x, dev = x * ROTARY_ENGINE_PER_RAD, dev * ROTARY_ENGINE_PER_RAD
    cyc = np.asarray(cycle).ravel()
    dr = np.array([(1 if str(v).strip() in ("+", "1", "+1") else -1 if str(v).strip() in ("-", "-1") else 0)
                   for v in np.asarray(direction).ravel()])
    n = len(x)
    if not (len(dev) == len(cyc) == len(dr) == n) or n == 0:
        raise ConfigError("positioning: target, direction, cycle and deviation must have one value per reading")
    if np.any(dr == 0):
        raise ConfigError(f"positioning: direction must be + or -, got {np.asarray(direction).ravel()[dr == 0][0]!r}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(dev))):
        raise ConfigError("positioning: non-finite target or deviation")
    cyc_ids, cyc_idx = np.unique(cyc, return_inverse=True)
    if len(cyc_ids) < 2:
        raise ConfigError("positioning: discovery needs at least two cycles")
    t = np.arange(n, dtype=float) if t_s is None else np.asarray(t_s, float).ravel()
    tx = np.round(x / 1e-9).astype(np.int64)
    keys = list(dict.fromkeys(zip(tx.tolist(), dr.tolist())))
    col = np.array([keys.index(k) for k in zip(tx.tolist(), dr.tolist())])
    A = np.zeros((n, len(keys)))
    A[np.arange(n), col] = 1.0
    mid, L = (x.max() + x.min()) / 2, max(np.ptp(x) / 2, 1e-12)
    tau = (t - t.min()) / max(np.ptp(t), 1e-12)
    data = PositioningData(x, (x - mid) / L, float(L), t, tau, dr, cyc_idx)
    if rotary:   # (the target in degrees: arcsec x 1e-6 per engine unit, 1e-9 per key step)
        ids = tuple(f"P={k[0] * 1e-9 / ROTARY_ENGINE_PER_RAD * 180.0 / np.pi:.10g}deg{'+' if k[1] > 0 else '-'}"
                    for k in keys)
    else:
        ids = tuple(f"P={k[0] * 1e-6:g}mm{'+' if k[1] > 0 else '-'}" for k in keys)
    modes = np.ones((n, 1))
    clock = t_s is not None
    # (without a clock the time is the reading order, and the words say so: "residuals follow time" read as a clock)
    tw = "time" if clock else f"time, here {NO_CLOCK_TIME}"
    covs = [Covariate("time", t, "smooth", 6, (0,), tw, "time"),
            Covariate("cycle", cyc_idx, "categorical", 0, (0,), "the cycle", "time"),
            Covariate("position", x, "smooth", 6, (0,), "the target position", "position"),
            Covariate("position_by_cycle", np.column_stack([f * (cyc_idx == j) for j in range(len(cyc_ids))
                                                            for f in (data.xs, data.xs ** 2)]), "basis",
                      2 * len(cyc_ids), (0,), "the target position, differently in each cycle", "time"),
            Covariate("order", np.arange(n, dtype=float), "smooth", 6, (0,), "the reading order", "time")]
    if POSITIONING_TIME_BY_DIRECTION:
        covs.append(Covariate("time_by_direction", dr[:, None] * _time_by_direction_basis(tau), "basis",
                              POSITIONING_TIME_BY_DIRECTION, (0,),
                              f"{tw}, opposite in the two directions (a reversal that changes)", "time"))
    if POSITIONING_DIRECTION_BY_CYCLE:
        D = np.column_stack([dr * (cyc_idx == j) for j in range(len(cyc_ids))]).astype(float)
        if POSITIONING_TIME_BY_DIRECTION:   # beyond a reversal that changes smoothly through the test (its own line):
            # the combinations of the cycles' columns orthogonal to time_by_direction's (within the cycles' span: a
            # within-cycle trend, a drift's, is not a reversal per cycle)
            T = dr[:, None] * _time_by_direction_basis(tau)
            u, sv, vt = np.linalg.svd(T.T @ D)
            D = D @ vt[int(np.sum(sv > 1e-9 * max(sv.max(), 1e-300))):].T
    if POSITIONING_DIRECTION_BY_CYCLE and D.shape[1]:
        covs.append(Covariate("direction_by_cycle", D, "basis", D.shape[1], (0,),
                              "the direction, differently in each cycle (a reversal that changes from cycle to "
                              "cycle, beyond a smooth change through the test)", "time"))
    for name, v in (temps or {}).items():
        v = np.asarray(v, float)
        if np.all(np.isfinite(v)) and np.ptp(v) > 0:
            short = name[5:-2] if name.startswith("temp_") and name.endswith("_C") else name
            covs.append(Covariate(f"temp_{short}", v, "smooth", 5, (0,), f"the temperature {name}", "time"))
    return Baseline(
        kind="positioning", model="ISO 230-2 systematic deviation per target and direction", A=A, y=dev,
        names=ids, groups=cyc_idx, group_ids=tuple(str(c) for c in cyc_ids), C=np.zeros((0, A.shape[1])),
        d=np.zeros(0), estimand=np.arange(A.shape[1]), estimand_ids=ids, geometry=None, replicate=col,
        covariates=tuple(covs), modes=modes, mode_names=("deviation",), rows=np.arange(n), data=data,
        conventions=("x_ij = measured - target (ISO 230-2); one mean per target and direction",),
        info={"targets": int(len(np.unique(tx))), "cycles": int(len(cyc_ids)),
              **({"unit": ROTARY_REPORT_UNIT, "target_unit": "deg"} if rotary else {}),
              **({} if clock else {"time": NO_CLOCK_TIME})},
        estimand_label="mean unidirectional positional deviation")


def positioning_from_log(log) -> Baseline:
    """The positioning baseline of a ``positioning-log/1`` test (:mod:`core.positioning`).

    The valid readings as ISO 230-2 arranges them (:func:`core.positioning.arrange`
    and :func:`core.positioning.baseline`), converted to SI (mm -> m,
    deg -> rad), with the log's ``temp_*_C`` columns as covariates. A rotary
    axis (``unit: deg``) gives a rotary baseline (figures in arc seconds).
    """
    from . import positioning as pos
    from .units import DEG

    test = pos.arrange(log)
    pb = pos.baseline(test)
    k = DEG if pb.unit == "deg" else MM
    t = None if np.all(np.isnan(pb.t_s)) else np.where(np.isfinite(pb.t_s), pb.t_s, np.nan)
    if t is not None and np.any(np.isnan(t)):
        t = None  # a clock with holes: the reading order instead
    temps = {}
    for name, v in getattr(log, "extra", {}).items():
        if name.startswith("temp_") and name.endswith("_C"):
            temps[name] = np.asarray(v, float)[pb.row]
    return positioning(pb.target * k, pb.direction, pb.cycle, pb.deviation * k, t, temps, rotary=pb.unit == "deg")
