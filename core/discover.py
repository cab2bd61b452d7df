"""Model discovery: what the baseline gets wrong, why, and what fixing it gains.

Given a campaign, :func:`discover` fits the baseline model (the 2D
self-calibration of Ibaraki et al., eqs 1-18, :mod:`core.selfcal`), looks
for structure in its residuals, names the physical cause from a library of
candidate extensions, refits with the winner (and a second one when the
first leaves significant structure) and measures the gain in and out of
sample.

Every candidate is a physical model with few parameters, added as columns
to the baseline design ``dq = A theta`` (sign convention of CONTRIBUTING:
a tool error ``E`` gives ``dq = -n . E``):

``thermal_drift``
    offsets and scales of X and Y drifting linearly with time:
    ``-n_x t``, ``-n_y t``, ``-n_x x t``, ``-n_y y t``.
``periodic_axis_error``
    a periodic error of one axis, shorter than the error-map grid:
    ``-n_d sin(2 pi a / P)``, ``-n_d cos(2 pi a / P)`` for the axis ``a``
    and both directions ``d``, period ``P`` scanned.
``probe_lobing``
    pre-travel as a low-order Fourier series of the approach azimuth in
    the machine frame: ``cos k phi``, ``sin k phi``, k = 1..4.
``reversal``
    lost motion per axis: ``-n_a sign(d_a) / 2`` (``d`` approach direction).
``nonrigid``
    low-order coupling of X and Y that no rigid-body model can produce.
``outlier``
    a few touches deviating grossly: studentized deleted residuals beyond
    a Bonferroni bound, removed iteratively.

A candidate counts only when it holds up out of sample: an F test on the
added columns (Bonferroni over everything tried, including the scanned
periods), a lower BIC, and a lower cross-validated RMS over held-out
set-ups. The held-out set-up's own rigid parameters (its C-axis errors) are
refitted on it, everything else is predicted. When nothing passes, the
cause is ``none`` if the residuals show no structure and ``unexplained``
if they do: never a guess.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
from scipy import stats

from . import selfcal
from .exceptions import ConfigError, IdentifiabilityError
from .touches import Touches
from .units import MM, UM

CAUSES = ("none", "outlier", "thermal_drift", "periodic_axis_error", "probe_lobing", "reversal",
          "nonrigid", "unexplained")


@dataclass(frozen=True)
class Settings:
    """Decision thresholds of :func:`discover` (one documented place).

    Attributes
    ----------
    alpha : float
        Family-wise false-alarm rate of the F tests, shared (Bonferroni)
        over all candidates and every scanned period.
    cv_gain : float
        A candidate must reduce the cross-validated RMS below
        ``cv_gain`` times the current model's.
    outlier_alpha : float
        Family-wise rate of the studentized-residual outlier test.
    outlier_max_frac : float
        At most this fraction of touches may be called outliers; more
        points to a systematic effect, not dust.
    structure_alpha : float
        Family-wise rate of the residual structure tests (unexplained).
    grid_steps_mm : tuple of float
        Error-map grid steps tried for the baseline, finest first.
    select_grid : bool
        Choose among the identifiable grids by BIC of the baseline fit
        (default); False takes the finest identifiable one.
    max_findings : int
        Extensions added at most (besides outlier removal).
    periods : int
        Trial periods in the scan of the periodic candidate.
    """

    alpha: float = 1e-2
    cv_gain: float = 1.0
    outlier_alpha: float = 0.001
    outlier_max_frac: float = 0.05
    structure_alpha: float = 1e-5
    grid_steps_mm: tuple = (22.0, 30.0, 40.0, 55.0, 80.0)
    max_findings: int = 2
    periods: int = 160
    select_grid: bool = True


# ---------------------------------------------------------------------------
# the baseline
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Baseline:
    """The baseline design and everything discovery needs around it.

    Attributes
    ----------
    design : selfcal.Design
        The paper's model (eqs 1-18).
    A : (n, p) float
        ``design.A`` dense, plus the height columns when the touches lie at
        more than one Z level (see :func:`baseline`).
    C, d : gauge conditions ``C theta = d`` for all p columns.
    names : tuple of str
    own_cols : tuple of int arrays
        Per set-up, the columns that belong to it alone (its C-axis
        errors): refitted on a held-out set-up in cross-validation.
    """

    design: selfcal.Design
    A: np.ndarray
    C: np.ndarray
    d: np.ndarray
    names: tuple
    grid_step_m: float
    own_cols: tuple
    z_levels_m: tuple
    identifiable: bool = True
    why: str = ""


def _height_columns(t: Touches, des: selfcal.Design):
    """C-axis tilt and Abbe columns for touches at more than one Z level.

    The paper's model is planar: every touch at one height. Touches at
    another height (sphere equators above the pocket) also see the C-axis
    tilt error motions ``EAC``/``EBC`` (per set-up) and the angular errors
    of X and Y through the height difference ``dz``. The per-set-up tilt
    columns take the C-axis part and, for raised targets that sit at a few
    places (spheres), most of the rest; richer Abbe terms are not
    identifiable from two spheres. Without them the baseline calls the
    height effect an error. Returns (columns, names, per-set-up column indices
    within the block, gauge rows) or None for a single level.
    """
    z = t.pn_R[:, 2]
    zr = np.round(z, 6)
    levels, counts = np.unique(zr, return_counts=True)
    if levels.size < 2:
        return None
    z_ref = levels[np.argmax(counts)]
    dz = z - z_ref
    nx, ny = t.n_R[:, 0], t.n_R[:, 1]
    cols, names, own = [], [], []
    cn = [n.split("[", 1)[1].rstrip("]") for n in des.names[des.slices["EXC"]]]
    for j in range(len(des.setup_ids)):
        m = (t.setup == j).astype(float)
        own.append(np.array([len(cols), len(cols) + 1]))
        cols += [nx * dz * m, -ny * dz * m]
        names += [f"EBC,total[{cn[j]}]", f"EAC,total[{cn[j]}]"]
    # workpiece tilt in W is the same as shifting every raised target: fix the
    # reference set-up's tilt (two gauge conditions)
    ref = des.ref_setup
    gauge = [own[ref][0], own[ref][1]]
    return np.column_stack(cols), tuple(names), own, gauge, tuple(float(v) for v in levels)


def baseline(touches: Touches, grid_step_mm: float | None = None,
             settings: Settings = Settings(), yaw: str = "ECY") -> Baseline:
    """The 2D self-calibration design on the finest grid the data identify.

    With touches at several Z levels, per-set-up C-axis tilt columns are
    added (:func:`_height_columns`). When no grid makes the parameters
    identifiable (a symmetric part at C angles 90 deg apart is the classic
    case), the finest grid that meets the count condition of eq 6 is used
    all the same: residuals do not depend on the gauge, and the workpiece
    estimates are then reported as not identifiable (``identifiable`` False,
    ``why`` names the combinations).

    Raises
    ------
    IdentifiabilityError
        If no grid meets eq 6: discovery needs the same targets probed at
        two or more rotary-table angles, and more touches than unknowns.
    """
    steps = (grid_step_mm,) if grid_step_mm else settings.grid_steps_mm
    last = None
    fallback = None
    cands: list = []
    for st in steps:
        grid = selfcal.Grid.from_extent(touches.pn_R, st * MM)
        try:
            selfcal.check_count(touches, grid)
            des = selfcal.build_design(touches, grid, yaw=yaw)
        except IdentifiabilityError as e:
            last = e
            continue
        A = des.A.toarray()
        C, d, names = des.C, des.d, tuple(des.names)
        s = des.slices
        own = [np.array([s["EXC"].start + j, s["EYC"].start + j, s["ECC"].start + j])
               for j in range(len(des.setup_ids))]
        levels = (float(np.median(touches.pn_R[:, 2])),)
        h = _height_columns(touches, des)
        if h is not None:
            H, hn, hown, hg, levels = h
            p = A.shape[1]
            A = np.hstack([A, H])
            C = np.hstack([C, np.zeros((C.shape[0], H.shape[1]))])
            extra = np.zeros((len(hg), A.shape[1]))
            for r, c in enumerate(hg):
                extra[r, p + c] = 1.0
            C = np.vstack([C, extra])
            d = np.concatenate([d, np.zeros(len(hg))])
            names = names + hn
            own = [np.concatenate([o, p + ho]) for o, ho in zip(own, hown)]
        bl = dict(design=des, A=A, C=C, d=d, names=names, grid_step_m=st * MM, own_cols=tuple(own),
                  z_levels_m=levels)
        try:
            selfcal.solve(A, np.zeros(touches.n), C, d, names=names, sigma=1.0, covariance="none")
        except IdentifiabilityError as e:
            last = e
            if fallback is None:
                fallback = Baseline(**bl, identifiable=False, why=str(e))
            continue
        cands.append(Baseline(**bl))
    if cands:
        if len(cands) == 1 or not settings.select_grid:
            return cands[0]
        # the grid is part of the baseline model: the finest grid absorbs the
        # most (also of what discovery looks for), the coarsest the least;
        # the information criterion chooses, on the touches themselves
        y = touches.dq_m

        def bic(b):
            f = _fit(b.A, y)
            return _bic(f.rss, touches.n, f.Q.shape[1])

        return min(cands, key=bic)
    if fallback is not None:
        return fallback
    raise IdentifiabilityError(f"no baseline: the 2D self-calibration does not meet eq 6 on grids of "
                               f"{', '.join(f'{s:g}' for s in steps)} mm ({last})")


# ---------------------------------------------------------------------------
# linear algebra on the column space
# ---------------------------------------------------------------------------


def _basis(A: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Orthonormal basis (n, r) of the column space of A (columns scaled)."""
    if A.shape[1] == 0:
        return np.zeros((A.shape[0], 0))
    nrm = np.linalg.norm(A, axis=0)
    keep = nrm > 0
    As = A[:, keep] / nrm[keep]
    U, s, _ = sla.svd(As, full_matrices=False, lapack_driver="gesdd")
    r = int(np.sum(s > tol * s[0])) if s.size else 0
    return U[:, :r]


def _new_directions(Q: np.ndarray, C: np.ndarray, tol: float = 1e-6):
    """Part of the columns of C outside span(Q): (basis, kept column indices)."""
    M = C - Q @ (Q.T @ C)
    keep = np.linalg.norm(M, axis=0) > tol * np.maximum(np.linalg.norm(C, axis=0), 1e-300)
    if not keep.any():
        return np.zeros((C.shape[0], 0)), keep
    return _basis(M[:, keep], tol=1e-8), keep


@dataclass(frozen=True)
class _Fit:
    Q: np.ndarray
    r: np.ndarray
    rss: float
    dof: int


def _fit(A: np.ndarray, y: np.ndarray) -> _Fit:
    Q = _basis(A)
    r = y - Q @ (Q.T @ y)
    return _Fit(Q, r, float(r @ r), int(len(y) - Q.shape[1]))


def _bic(rss: float, n: int, k: int) -> float:
    return n * np.log(max(rss, 1e-300) / n) + k * np.log(n)


#: Relative singular value below which a held-out set-up's prediction does not
#: extrapolate (truncated SVD of the column-scaled training design): without it,
#: grid nodes that the remaining set-ups barely see make the predicted residual
#: of the held-out set-up tens of micrometres, and the cross-validation noise.
CV_RCOND = 1e-2


def _cv_rms(A: np.ndarray, y: np.ndarray, setup: np.ndarray, own: tuple) -> float:
    """Leave-one-set-up-out RMS: predict a set-up from the others, refit its own columns.

    The training fit is a truncated-SVD least squares on the column-scaled
    design (:data:`CV_RCOND`), the same for every model compared.
    """
    sq, cnt = 0.0, 0
    for j, cols in enumerate(own):
        te = setup == j
        tr = ~te
        if te.sum() == 0 or tr.sum() == 0:
            continue
        Atr = A[tr]
        scale = np.linalg.norm(Atr, axis=0)
        used = scale > 1e-9 * scale.max()  # rounding dust (cos 90 deg) is no column
        theta = np.zeros(A.shape[1])
        sol, *_ = np.linalg.lstsq(Atr[:, used] / scale[used], y[tr], rcond=CV_RCOND)
        theta[used] = sol / scale[used]
        own_mask = np.zeros(A.shape[1], bool)
        own_mask[cols] = True
        pred_cols = used & ~own_mask
        e = y[te] - A[te][:, pred_cols] @ theta[pred_cols]
        Ao = A[te][:, own_mask]
        if Ao.size:
            c, *_ = np.linalg.lstsq(Ao, e, rcond=1e-10)
            e = e - Ao @ c
        sq += float(e @ e)
        cnt += int(te.sum())
    if cnt == 0:
        raise IdentifiabilityError("cross-validation needs at least two set-ups")
    return float(np.sqrt(sq / cnt))


# ---------------------------------------------------------------------------
# candidate extensions
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Extension:
    """Columns of one candidate cause, with what they mean."""

    cause: str
    columns: np.ndarray  # (n, k)
    labels: tuple  # k labels
    tries: int = 1  # hypotheses tried to find it (Bonferroni factor)
    info: dict = field(default_factory=dict)


def _geometry(t: Touches):
    x, y = t.pn_R[:, 0], t.pn_R[:, 1]
    L = max(np.ptp(x), np.ptp(y), 1e-3) / 2
    xc, yc = (x.max() + x.min()) / 2, (y.max() + y.min()) / 2
    T = max(np.ptp(t.t_s), 1e-9)
    tt = (t.t_s - t.t_s.min()) / T - 0.5
    return x, y, (x - xc) / L, (y - yc) / L, tt, T, L


def _temperature(t: Touches):
    """Mean of the log's temperature columns, centred (K), or None."""
    cols = [v for v in t.temps_C.values() if np.all(np.isfinite(v)) and np.ptp(v) > 0]
    if not cols:
        return None
    T = np.mean(cols, axis=0)
    return T - T.mean()


def ext_drift(t: Touches) -> Extension:
    """Thermal drift: X/Y offsets and scales changing linearly with time, or
    with the logged temperature when the log carries ``temp_*_C`` columns."""
    nx, ny = t.n_R[:, 0], t.n_R[:, 1]
    x, y, xs, ys, tt, T, L = _geometry(t)
    cols = [-nx * tt, -ny * tt, -nx * x * tt, -ny * y * tt]
    labels = ["x_offset", "y_offset", "x_scale", "y_scale"]
    dT = _temperature(t)
    if dT is not None:
        cols += [-nx * dT, -ny * dT, -nx * x * dT, -ny * y * dT]
        labels += ["x_offset_per_K", "y_offset_per_K", "x_scale_per_K", "y_scale_per_K"]
    return Extension("thermal_drift", np.column_stack(cols), tuple(labels), tries=len(cols),
                     info={"T_s": T, "pick_one": True})


def ext_lobing(t: Touches, kmax: int = 4) -> Extension:
    """Probe lobing: pre-travel as a Fourier series of the approach azimuth (machine frame)."""
    phi = np.arctan2(t.d_R[:, 1], t.d_R[:, 0])
    cols, labels = [], []
    for k in range(1, kmax + 1):
        cols += [np.cos(k * phi), np.sin(k * phi)]
        labels += [f"cos{k}", f"sin{k}"]
    return Extension("probe_lobing", np.column_stack(cols), tuple(labels), info={"phi": phi})


def ext_reversal(t: Touches) -> Extension:
    """Reversal: lost motion of each axis, signed by its direction of motion at the touch."""
    s = np.where(np.abs(t.d_R) > 1e-9, np.sign(t.d_R), 0.0)
    C = np.column_stack([-t.n_R[:, 0] * s[:, 0] / 2, -t.n_R[:, 1] * s[:, 1] / 2])
    return Extension("reversal", C, ("x_lost_motion", "y_lost_motion"))


def ext_nonrigid(t: Touches) -> Extension:
    """Non-rigid coupling: X/Y errors varying jointly with x and y."""
    nx, ny = t.n_R[:, 0], t.n_R[:, 1]
    x, y, xs, ys, *_ = _geometry(t)
    C = np.column_stack([-nx * xs * ys, -ny * xs * ys, -nx * xs * xs * ys, -ny * xs * ys * ys,
                         -nx * xs * ys * ys, -ny * xs * xs * ys])
    return Extension("nonrigid", C, ("EX~xy", "EY~xy", "EX~x2y", "EY~xy2", "EX~xy2", "EY~x2y"))


def _periodic_columns(t: Touches, axis: int, P: float) -> np.ndarray:
    a = t.pn_R[:, axis]
    s, c = np.sin(2 * np.pi * a / P), np.cos(2 * np.pi * a / P)
    nx, ny = t.n_R[:, 0], t.n_R[:, 1]
    return np.column_stack([-nx * s, -nx * c, -ny * s, -ny * c])


def ext_periodic(t: Touches, Q: np.ndarray, r: np.ndarray, grid_step_m: float,
                 n_periods: int = 160) -> Extension:
    """Periodic axis error: scan the period along X and Y, keep the best.

    Periods from four times the smallest spacing of distinct positions
    (well sampled) up to the grid step: a periodic error shorter than the
    error map's grid (longer ones are the error map's job).
    """
    best = (-1.0, 0, 0.0)
    lo_all = []
    for axis in (0, 1):
        u = np.unique(np.round(t.pn_R[:, axis], 7))
        if u.size < 8:
            continue
        lo_all.append(max(4 * np.median(np.diff(u)), 1e-3))
    if not lo_all:
        return Extension("periodic_axis_error", np.zeros((t.n, 0)), (), tries=1)
    p_lo = min(lo_all)
    p_hi = grid_step_m
    if p_hi <= p_lo:
        return Extension("periodic_axis_error", np.zeros((t.n, 0)), (), tries=1)
    periods = np.geomspace(p_lo, p_hi, n_periods)
    for axis in (0, 1):
        for P in periods:
            B, _ = _new_directions(Q, _periodic_columns(t, axis, P))
            gain = float(np.sum((B.T @ r) ** 2))
            if gain > best[0]:
                best = (gain, axis, P)
    # refine the period around the best trial
    _, axis, P0 = best
    fine = np.geomspace(P0 / 1.03, P0 * 1.03, 41)
    gains = []
    for P in fine:
        B, _ = _new_directions(Q, _periodic_columns(t, axis, P))
        gains.append(float(np.sum((B.T @ r) ** 2)))
    P = float(fine[int(np.argmax(gains))])
    ax = "XY"[axis]
    # columns: -n_x (sin, cos), -n_y (sin, cos): the X and Y components of the error of axis ``ax``
    return Extension("periodic_axis_error", _periodic_columns(t, axis, P),
                     (f"EX{ax}_sin", f"EX{ax}_cos", f"EY{ax}_sin", f"EY{ax}_cos"),
                     tries=2 * n_periods, info={"axis": ax, "period_m": P})


# ---------------------------------------------------------------------------
# outliers and residual structure
# ---------------------------------------------------------------------------


def find_outliers(A: np.ndarray, y: np.ndarray, settings: Settings = Settings()) -> list[int]:
    """Indices (into y) of gross outliers: studentized deleted residuals, iteratively.

    Each pass removes the most extreme touch if its studentized deleted
    residual exceeds the Bonferroni bound ``t(1 - alpha / 2n, dof - 1)``;
    at most ``outlier_max_frac`` of the touches.
    """
    n = len(y)
    keep = np.ones(n, bool)
    out: list[int] = []
    for _ in range(max(1, int(settings.outlier_max_frac * n))):
        idx = np.flatnonzero(keep)
        f = _fit(A[idx], y[idx])
        if f.dof < 3:
            break
        h = np.sum(f.Q ** 2, axis=1)
        ok = h < 1 - 1e-9
        r = f.r
        s2 = (f.rss - np.where(ok, r ** 2 / np.where(ok, 1 - h, 1), 0)) / (f.dof - 1)
        tstat = np.where(ok, np.abs(r) / np.sqrt(np.maximum(s2, 1e-300) * np.where(ok, 1 - h, 1)), 0)
        k = int(np.argmax(tstat))
        bound = stats.t.isf(settings.outlier_alpha / (2 * len(idx)), f.dof - 1)
        if tstat[k] <= bound:
            break
        out.append(int(idx[k]))
        keep[idx[k]] = False
    return sorted(out)


def structure_tests(t: Touches, r: np.ndarray, dof: int, bins: int = 8) -> dict:
    """p-values of residual structure against each variable the log carries.

    Binned one-way ANOVA of the residuals against time (within set-ups),
    X, Y, approach azimuth, temperature (when logged) and feature; each
    p-value is the probability of that much between-bin variance from
    structureless noise.
    """
    out = {}
    phi = np.arctan2(t.d_R[:, 1], t.d_R[:, 0])
    tt = np.zeros(t.n)
    for j in np.unique(t.setup):
        m = t.setup == j
        tt[m] = (t.t_s[m] - t.t_s[m].min()) / max(np.ptp(t.t_s[m]), 1e-9)
    variables = {"time_in_setup": tt, "x": t.pn_R[:, 0], "y": t.pn_R[:, 1], "approach_azimuth": phi}
    dT = _temperature(t)
    if dT is not None:
        variables["temperature"] = dT
    s2 = float(r @ r) / max(dof, 1)
    feats = sorted(set(t.feature.tolist()))
    if len(feats) > 1:  # categorical: one group per feature
        groups = [r[t.feature == f] for f in feats if np.sum(t.feature == f) > 1]
        if len(groups) > 1:
            F = (sum(len(g) * g.mean() ** 2 for g in groups) / len(groups)) / max(s2, 1e-300)
            out["feature"] = float(stats.f.sf(F, len(groups), max(dof, 1)))
    for name, v in variables.items():
        if np.ptp(v) <= 0:
            continue
        edges = np.quantile(v, np.linspace(0, 1, bins + 1))
        lab = np.clip(np.searchsorted(edges, v, side="right") - 1, 0, bins - 1)
        groups = [r[lab == b] for b in range(bins) if np.sum(lab == b) > 1]
        if len(groups) < 2:
            continue
        ss = sum(len(g) * g.mean() ** 2 for g in groups)
        k = len(groups)
        F = (ss / k) / max(s2, 1e-300)
        out[name] = float(stats.f.sf(F, k, max(dof, 1)))
    return out


# ---------------------------------------------------------------------------
# discovery
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Finding:
    """One named cause with the figures that support it."""

    cause: str
    evidence: dict
    params: dict
    rms_um: float


@dataclass(frozen=True)
class Discovery:
    """Everything :func:`discover` found (``to_report`` gives the spec's JSON)."""

    baseline_rms_um: float
    baseline_cv_rms_um: float
    baseline_n: int
    baseline_n_params: int
    findings: tuple
    extended_model: str
    extended_rms_um: float
    extended_cv_rms_um: float
    workpiece: tuple
    outlier_rows: tuple
    residuals_baseline_um: np.ndarray
    residuals_extended_um: np.ndarray
    structure_p: dict
    grid_step_mm: float
    conventions: tuple
    baseline_model: str = "selfcal-2d (Ibaraki eqs 1-18)"
    workpiece_identifiable: bool = True

    @property
    def cause(self) -> str:
        return self.findings[0].cause if self.findings else "none"

    def to_report(self) -> dict:
        """The discovery report of shared/spec/probe-log.md (plus extra keys)."""
        b_cv = self.baseline_cv_rms_um
        return {
            "baseline": {"model": self.baseline_model, "n": self.baseline_n,
                         "n_params": self.baseline_n_params, "rms_um": self.baseline_rms_um,
                         "grid_step_mm": self.grid_step_mm},
            "findings": [{"cause": f.cause, "evidence": f.evidence, "params": f.params, "rms_um": f.rms_um}
                         for f in self.findings],
            "cause": self.cause,
            "extended": {"model": self.extended_model, "rms_um": self.extended_rms_um,
                         "cv_rms_um": self.extended_cv_rms_um},
            "baseline_cv_rms_um": b_cv,
            "gain": {"rms_ratio": self.extended_rms_um / max(self.baseline_rms_um, 1e-300),
                     "cv_rms_ratio": self.extended_cv_rms_um / max(b_cv, 1e-300)},
            "workpiece": [dict(w) for w in self.workpiece],
            "workpiece_identifiable": self.workpiece_identifiable,
            "outlier_rows": [int(r) for r in self.outlier_rows],
            "residual_structure_p": self.structure_p,
            "conventions": list(self.conventions),
        }


def _params(ext: Extension, coef: np.ndarray, std: np.ndarray, t: Touches) -> dict:
    """Physical magnitudes of an extension's coefficients (units in the keys)."""
    p: dict = {}
    if ext.cause == "thermal_drift":
        T_h = ext.info["T_s"] / 3600
        for lab, c, s in zip(ext.labels, coef, std):
            if lab.endswith("_per_K"):
                unit = "um_per_K" if "offset" in lab else "ppm_per_K"
                p[f"{lab[:-6]}_{unit}"] = c * 1e6
                p[f"{lab[:-6]}_u_{unit}"] = s * 1e6
            elif lab.endswith("offset"):
                p[f"{lab}_drift_um_per_h"] = c / UM / T_h
                p[f"{lab}_drift_u_um_per_h"] = s / UM / T_h
            else:
                p[f"{lab}_drift_ppm_per_h"] = c * 1e6 / T_h
                p[f"{lab}_drift_u_ppm_per_h"] = s * 1e6 / T_h
    elif ext.cause == "periodic_axis_error":
        ax = ext.info["axis"]
        p["axis"] = ax
        p["period_mm"] = ext.info["period_m"] / MM
        c = dict(zip(ext.labels, coef))
        u = dict(zip(ext.labels, std))
        for sym in (f"EX{ax}", f"EY{ax}"):
            sn, cs = c.get(f"{sym}_sin", 0.0), c.get(f"{sym}_cos", 0.0)
            p[f"{sym}_amplitude_um"] = float(np.hypot(sn, cs)) / UM
            p[f"{sym}_phase_rad"] = float(np.arctan2(cs, sn))
        p["amplitude_u_um"] = float(np.max([u.get(k, 0.0) for k in u])) / UM if u else float("nan")
    elif ext.cause == "probe_lobing":
        phi = np.linspace(-np.pi, np.pi, 721)
        f = sum(c * (np.cos(k * phi) if lab.startswith("cos") else np.sin(k * phi))
                for lab, c in zip(ext.labels, coef) for k in [int(lab[3:])])
        for lab, c, s in zip(ext.labels, coef, std):
            p[f"{lab}_um"] = c / UM
            p[f"{lab}_u_um"] = s / UM
        p["pretravel_variation_pv_um"] = float(np.ptp(f)) / UM if np.ndim(f) else 0.0
    elif ext.cause == "reversal":
        for lab, c, s in zip(ext.labels, coef, std):
            p[f"{lab}_um"] = c / UM
            p[f"{lab}_u_um"] = s / UM
    else:
        for lab, c, s in zip(ext.labels, coef, std):
            p[f"{lab}_um"] = c / UM
            p[f"{lab}_u_um"] = s / UM
    return {k: (float(v) if not isinstance(v, str) else v) for k, v in p.items()}


@dataclass(frozen=True)
class _Estimate:
    theta: np.ndarray
    std: np.ndarray | None


def _solve_workpiece(bl: Baseline, A_ext: np.ndarray, y: np.ndarray, rows: np.ndarray) -> _Estimate:
    """Gauge-fixed estimate (theta, std) with the baseline's gauge conditions.

    When the design is not identifiable beyond the gauge, the minimum-norm
    solution that meets the gauge is returned without uncertainties.
    """
    k = A_ext.shape[1] - bl.A.shape[1]
    C = np.hstack([bl.C, np.zeros((bl.C.shape[0], k))])
    names = list(bl.names) + [f"ext[{i}]" for i in range(k)]
    if bl.identifiable:
        try:
            sol = selfcal.solve(A_ext[rows], y[rows], C, bl.d, names=names, covariance="full")
            return _Estimate(sol.theta, sol.std)
        except IdentifiabilityError:
            pass
    A = A_ext[rows]
    scale = np.linalg.norm(A) / max(np.linalg.norm(C), 1e-300) * 1e3
    M = np.vstack([A, scale * C])
    rhs = np.concatenate([y[rows], scale * bl.d])
    theta, *_ = np.linalg.lstsq(M, rhs, rcond=1e-12)
    return _Estimate(theta, None)


def discover(t: Touches, *, grid_step_mm: float | None = None, settings: Settings = Settings(),
             chain: str | None = None) -> Discovery:
    """Find what the 2D self-calibration model gets wrong in a campaign.

    Parameters
    ----------
    t : Touches
        Valid touches (``core.touches.from_log``), at two or more C angles.
    grid_step_mm : float or None
        Error-map grid step of the baseline; None = chosen among
        ``settings.grid_steps_mm`` (see :func:`baseline`).
    chain : str or None
        The machine's ISO 10791 chain (the log's ``kinematic_chain``): which
        axis carries the other decides the rigid-body yaw term
        (:func:`core.selfcal.yaw_for_chain`); None = the paper's.

    Returns
    -------
    Discovery

    Raises
    ------
    IdentifiabilityError
        The baseline cannot be identified (one set-up, too few targets).
    """
    planar = np.abs(t.n_R[:, 2]) <= selfcal.NZ_MAX
    left_out = int(t.n - planar.sum())
    if left_out:
        # the planar model (eqs 1-18) takes touches with normals in XY; the rest
        # (sphere points off the equator, faces) are left out and said so
        t = t.subset(planar, reindex=True)
    if t.n < 10:
        raise ConfigError(f"discover needs at least 10 valid touches with normals in the XY plane, got {t.n}")
    bl = baseline(t, grid_step_mm, settings, yaw=selfcal.yaw_for_chain(chain))
    y = t.dq_m
    A0 = bl.A
    n = t.n
    all_rows = np.arange(n)

    # 0. baseline and a first outlier screen
    f0 = _fit(A0, y)
    out0 = find_outliers(A0, y, settings)
    rows = np.setdiff1d(all_rows, out0)

    def evaluate(A: np.ndarray, rows: np.ndarray):
        f = _fit(A[rows], y[rows])
        cv = _cv_rms(A[rows], y[rows], t.setup[rows], bl.own_cols)
        return f, cv

    # 1. compete: each round adds the candidate with the best out-of-sample gain
    A = A0
    chosen: list[tuple[Extension, dict]] = []
    f_cur, cv_cur = evaluate(A, rows)
    for _round in range(settings.max_findings):
        sub = t.subset(rows)
        exts = [ext_drift(sub), ext_lobing(sub), ext_reversal(sub), ext_nonrigid(sub),
                ext_periodic(sub, f_cur.Q, f_cur.r, bl.grid_step_m, settings.periods)]
        exts = [e for e in exts if e.cause not in {c.cause for c, _ in chosen}]
        scored = []
        for e in exts:
            if e.columns.shape[1] == 0:
                continue
            B, keep = _new_directions(f_cur.Q, e.columns)
            if e.info.get("pick_one") and B.shape[1] > 1:
                # a drift is one mechanism: take the single column that explains
                # most (the Bonferroni factor ``tries`` pays for the choice)
                gains = []
                for j in np.flatnonzero(keep):
                    Bj, _ = _new_directions(f_cur.Q, e.columns[:, [j]])
                    gains.append((float(np.sum((Bj.T @ f_cur.r) ** 2)), j, Bj))
                _, j, B = max(gains, key=lambda g: g[0])
                keep = np.zeros(e.columns.shape[1], bool)
                keep[j] = True
            k = B.shape[1]
            if k == 0 or f_cur.dof - k < 5:
                continue
            drss = float(np.sum((B.T @ f_cur.r) ** 2))
            rss1 = f_cur.rss - drss
            dof1 = f_cur.dof - k
            F = (drss / k) / max(rss1 / dof1, 1e-300)
            p = float(stats.f.sf(F, k, dof1))
            # Bonferroni: over the candidates, and within one over what its scan tried
            p_adj = min(1.0, p * len(exts) * e.tries)
            dbic = _bic(rss1, len(rows), k + (1 if e.cause == "periodic_axis_error" else 0)) - \
                _bic(f_cur.rss, len(rows), 0)
            scored.append({"ext": e, "k": k, "keep": keep, "F": F, "p": p, "p_adj": p_adj,
                           "dbic": dbic, "rss": rss1})
        # cross-validate the significant ones only (the rest cannot win)
        best = None
        for s in sorted(scored, key=lambda s: s["rss"]):
            if not (s["p_adj"] < settings.alpha and s["dbic"] < 0):
                continue
            Ae = np.hstack([A, _full_cols(t, s["ext"])[:, s["keep"]]])
            cv = _cv_rms(Ae[rows], y[rows], t.setup[rows], bl.own_cols)
            s["cv"] = cv
            if cv < settings.cv_gain * cv_cur and (best is None or s["dbic"] < best["dbic"]):
                best = s
        if best is None:
            break
        e = best["ext"]
        A = np.hstack([A, _full_cols(t, e)[:, best["keep"]]])
        evidence = {"F": best["F"], "p_value": best["p"], "p_adjusted": best["p_adj"],
                    "tries": int(best["ext"].tries), "candidates": len(exts), "delta_bic": best["dbic"], "added_params": int(best["k"]),
                    "cv_rms_before_um": cv_cur / UM, "cv_rms_after_um": best["cv"] / UM,
                    "rms_before_um": float(np.sqrt(f_cur.rss / len(rows))) / UM,
                    "rms_after_um": float(np.sqrt(best["rss"] / len(rows))) / UM}
        evidence["competitors"] = {s["ext"].cause: {"p_adjusted": s["p_adj"], "delta_bic": s["dbic"],
                                                    "cv_rms_um": s.get("cv", float("nan")) / UM}
                                   for s in scored if s is not best}
        chosen.append((Extension(e.cause, e.columns[:, best["keep"]],
                                 tuple(np.array(e.labels)[best["keep"]]), e.tries, e.info), evidence))
        f_cur, cv_cur = evaluate(A, rows)
        # outliers judged against the better model: a systematic effect is no dust
        out_new = find_outliers(A, y, settings)
        if out_new != list(np.setdiff1d(all_rows, rows)):
            rows = np.setdiff1d(all_rows, out_new)
            f_cur, cv_cur = evaluate(A, rows)

    outliers = sorted(set(all_rows) - set(rows))
    # final outlier check against the final model
    if chosen:
        outliers = find_outliers(A, y, settings)
        rows = np.setdiff1d(all_rows, outliers)
        f_cur, cv_cur = evaluate(A, rows)

    # 2. gauge-fixed estimates, per-finding magnitudes
    sol_b = _solve_workpiece(bl, A0, y, all_rows)
    sol_e = _solve_workpiece(bl, A, y, rows)
    cv_b = _cv_rms(A0, y, t.setup, bl.own_cols)
    p0 = bl.A.shape[1]
    findings = []
    o = p0
    for ext, ev in chosen:
        k = ext.columns.shape[1]
        coef = sol_e.theta[o:o + k]
        std = sol_e.std[o:o + k] if sol_e.std is not None else np.full(k, np.nan)
        o += k
        findings.append(Finding(ext.cause, ev, _params(ext, coef, std, t), ev["rms_after_um"]))
    struct = structure_tests(t.subset(rows), f_cur.r, f_cur.dof)
    n_struct = max(len(struct), 1)
    structured = {k: v for k, v in struct.items() if v * n_struct < settings.structure_alpha}
    if outliers:
        r_b = f0.r
        drss_out = float(np.sum(r_b[outliers] ** 2))
        findings.append(Finding(
            "outlier",
            {"rows": [int(t.row[i]) for i in outliers],
             "residual_um": [float(r_b[i] / UM) for i in outliers],
             "robust_sigma_um": float(1.4826 * np.median(np.abs(f_cur.r - np.median(f_cur.r))) / UM),
             "rss_removed_um2": drss_out / UM ** 2,
             "test": f"studentized deleted residual beyond Bonferroni t bound, alpha={settings.outlier_alpha}"},
            {"n_outliers": len(outliers),
             "max_deviation_um": float(np.max(np.abs(r_b[outliers])) / UM)},
            float(np.sqrt(f_cur.rss / len(rows)) / UM)))
    # best first: by the residual sum of squares each finding removed
    findings.sort(key=lambda f: -(f.evidence["rss_removed_um2"] if f.cause == "outlier" else
                                  (f.evidence["rms_before_um"] ** 2 - f.evidence["rms_after_um"] ** 2) * n))
    if structured:
        findings.append(Finding("unexplained", {"structure_p_values": structured,
                                                "test": "binned one-way ANOVA, Bonferroni over variables"},
                                {}, float(np.sqrt(f_cur.rss / len(rows)) / UM)))
    # workpiece per target
    G = bl.design.slices["G"]
    wp = []
    for i, tid in enumerate(bl.design.target_ids):
        wp.append({"target": tid, "baseline_um": float(sol_b.theta[G][i] / UM),
                   "extended_um": float(sol_e.theta[G][i] / UM),
                   "baseline_u95_um": float(2 * sol_b.std[G][i] / UM) if sol_b.std is not None else None,
                   "extended_u95_um": float(2 * sol_e.std[G][i] / UM) if sol_e.std is not None else None})
    model = "selfcal-2d" + (" + heights" if len(bl.z_levels_m) > 1 else "") + "".join(f" + {e.cause}" for e, _ in chosen) + (" - outliers" if outliers else "")
    res_b = f0.r
    res_e = np.full(n, np.nan)
    res_e[rows] = f_cur.r
    conv = list(bl.design.gauge)
    conv.append("workpiece estimates in the baseline's gauge (eqs 16-17)" if bl.identifiable else
                "workpiece NOT identifiable by this design (minimum-norm estimates shown): " + bl.why)
    if left_out:
        conv.append(f"{left_out} touches with normals out of the XY plane left out of the planar baseline")
    conv.append("cv: leave-one-set-up-out, held-out set-up's C-axis errors refitted on it")
    conv = tuple(conv)
    return Discovery(
        baseline_rms_um=float(np.sqrt(f0.rss / n) / UM), baseline_cv_rms_um=cv_b / UM, baseline_n=n,
        baseline_n_params=int(f0.Q.shape[1]), findings=tuple(findings), extended_model=model,
        extended_rms_um=float(np.sqrt(f_cur.rss / len(rows)) / UM), extended_cv_rms_um=cv_cur / UM,
        workpiece=tuple(wp), outlier_rows=tuple(int(t.row[i]) for i in outliers),
        residuals_baseline_um=res_b / UM, residuals_extended_um=res_e / UM, structure_p=struct,
        grid_step_mm=bl.grid_step_m / MM, conventions=conv, workpiece_identifiable=bl.identifiable,
        baseline_model="selfcal-2d (Ibaraki eqs 1-18)" + (
            f" + C-axis tilt and Abbe terms for {len(bl.z_levels_m)} probing heights"
            if len(bl.z_levels_m) > 1 else ""))


def _full_cols(t: Touches, e: Extension) -> np.ndarray:
    """Extension columns for every touch (recomputed on the full set)."""
    if e.cause == "thermal_drift":
        return ext_drift(t).columns
    if e.cause == "probe_lobing":
        return ext_lobing(t).columns
    if e.cause == "reversal":
        return ext_reversal(t).columns
    if e.cause == "nonrigid":
        return ext_nonrigid(t).columns
    if e.cause == "periodic_axis_error":
        return _periodic_columns(t, "XY".index(e.info["axis"]), e.info["period_m"])
    raise ConfigError(f"unknown extension {e.cause!r}")
