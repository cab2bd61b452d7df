"""Choice of the C angles for a 2D self-calibration (paper section 6).

The paper chose its C angles "based on the uncertainty analysis" (eqs 19,
20). :func:`optimise_angles` does that explicitly: with C_1 = 0 fixed, it
minimises the largest expanded uncertainty of the workpiece deviations G
(linear propagation, :mod:`core.uncertainty`) by coordinate search over a
degree grid, and reports the gain over a reference choice (e.g. the paper's
0, 75, 130, 210 deg).

:func:`example_cross_pocket` gives a nominal target set shaped like the
paper's Fig. 8 (cross-shaped pocket 36 mm wide plus two precision spheres,
92 points), so studies can run on a nominal design without simulation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .exceptions import ConfigError, IdentifiabilityError
from .selfcal import Grid, estimator, nominal_touches
from .uncertainty import K, U_PROBE_M, form_projector
from .units import MM


def example_cross_pocket(arm_m: float = 0.090, half_width_m: float = 0.018, spheres: bool = True,
                         sphere_r_m: float = 0.0127, sphere_at_m: float = 0.060):
    """Nominal targets of a cross-shaped pocket (Fig. 8 of the paper), W frame.

    Returns
    -------
    w_W : (N_w, 2) float
        Contact points, m (76 on the pocket, plus 8 per sphere on its equator).
    wn_W : (N_w, 2) float
        Outward normals (out of the material: into the pocket; away from a
        sphere's centre).
    ids : tuple of str
    """
    L, h = arm_m, half_width_m
    # counter-clockwise boundary: the pocket (free space) lies to the left
    V = np.array([(L, -h), (L, h), (h, h), (h, L), (-h, L), (-h, h), (-L, h), (-L, -h),
                  (-h, -h), (-h, -L), (h, -L), (h, -h)])
    pts, nrm, ids = [], [], []
    for e in range(12):
        a, b = V[e], V[(e + 1) % 12]
        d = b - a
        ln = np.linalg.norm(d)
        k = 3 if ln < 2 * h + 1e-9 else 8
        t = (np.arange(k) + 0.5) / k
        for ti in t:
            pts.append(a + ti * d)
            nrm.append(np.array([-d[1], d[0]]) / ln)
            ids.append(f"pocket{len(ids) + 1:02d}")
    if spheres:
        for s, c in enumerate(((sphere_at_m, sphere_at_m), (-sphere_at_m, -sphere_at_m))):
            for k in range(8):
                a = 2 * np.pi * k / 8
                u = np.array([np.cos(a), np.sin(a)])
                pts.append(np.array(c) + sphere_r_m * u)
                nrm.append(u)
                ids.append(f"sphere{s + 1}_{k + 1}")
    return np.array(pts), np.array(nrm), tuple(ids)


def targets_from_log(log):
    """The distinct targets of a plan or campaign, in the order they first appear.

    Returns
    -------
    w_W : (N_w, 2) float
        Nominal contact points from the ``wx_mm``, ``wy_mm`` columns, m.
    wn_W : (N_w, 2) float
        Unit outward normals from ``wnx``, ``wny``.
    ids : tuple of str

    Raises
    ------
    ConfigError
        A target without those columns.
    """
    ids, first = np.unique(log.col("target"), return_index=True)
    order = np.argsort(first)
    rows = first[order]
    w = np.column_stack([log.col("wx_mm"), log.col("wy_mm")])[rows] * MM
    wn = np.column_stack([log.col("wnx"), log.col("wny")])[rows]
    if not (np.all(np.isfinite(w)) and np.all(np.isfinite(wn))):
        raise ConfigError(f"{log.source}: needs wx_mm, wy_mm, wnx, wny (targets in W) for every target")
    return w, wn / np.linalg.norm(wn, axis=1, keepdims=True), tuple(ids[order])


def max_workpiece_U95(w_W, wn_W, c_deg, grid: Grid, u_probe_m: float = U_PROBE_M,
                      measure: str = "gauge") -> float:
    """Largest expanded (k = 2) uncertainty of G over the targets, m; inf if not identifiable.

    ``measure="gauge"`` (the default): of G as identified in the gauge of
    eqs 16-17, the one reading vmt compares with the paper's Figs. 18-19
    (``scenarios.crosspocket.U95_READING``). It is the default because the
    paper chose its angles on that quantity: case 2's angles "were designed
    based on the uncertainty analysis presented in Section 6" (section 5.1),
    and section 6 reports U95 of G as identified (Figs. 18-19).
    ``measure="form"``: of the workpiece form only (shift, rotation and
    scale removed, :func:`core.uncertainty.form_projector`), one part of
    that value, NOT the paper's quantity; it ranks designs differently
    (on :func:`example_cross_pocket`, 3 angles on a 30 deg grid, Spearman
    0.13 between the two readings), so it stays an option for a part whose
    datum is fixed by other means.

    Targets are evaluated at the nominal contact points on one level
    (:func:`core.selfcal.nominal_touches`): a nominal design, not the
    tip-centre design ``vmt identify`` builds from a log.
    """
    if measure not in ("form", "gauge"):
        raise ConfigError(f"measure must be 'form' or 'gauge', got {measure!r}")
    try:
        t = nominal_touches(w_W, wn_W, c_deg)
        des, est = estimator(t, grid)
    except IdentifiabilityError:
        return float("inf")
    gi = np.arange(des.n_params)[des.slices["G"]]
    if measure == "gauge":
        return float(K * est.std(u_probe_m, index=gi).max())
    Cg = est.covariance_of(gi)
    P = form_projector(des)
    return float(K * u_probe_m * np.sqrt(max(np.einsum("ij,jk,ik->i", P, Cg, P).max(), 0.0)))


@dataclass(frozen=True)
class AngleDesign:
    """Outcome of :func:`optimise_angles`.

    Attributes
    ----------
    c_deg : tuple of float
        Chosen C angles, degrees (first is 0).
    max_U95_m : float
        Largest expanded uncertainty of G with them, m.
    reference_deg : tuple of float or None
    reference_max_U95_m : float or None
    gain : float or None
        ``reference_max_U95_m / max_U95_m`` (> 1: the chosen angles are better).
    evaluations : int
        Designs evaluated.
    step_deg : float
    """

    c_deg: tuple
    max_U95_m: float
    reference_deg: tuple | None
    reference_max_U95_m: float | None
    gain: float | None
    evaluations: int
    step_deg: float


def optimise_angles(w_W, wn_W, n_angles: int, grid: Grid, *, step_deg: float = 5.0,
                    u_probe_m: float = U_PROBE_M, reference_deg=None, max_sweeps: int = 6,
                    measure: str = "gauge", exhaustive_max: int = 400, evaluate=None,
                    progress=None) -> AngleDesign:
    """C angles minimising the largest workpiece uncertainty (C_1 = 0 fixed).

    Coordinate search over the degree grid ``0, step, 2 step, ... < 360``
    from several starts (equally spaced and compressed spreads of angles,
    and the reference when it has ``n_angles`` angles on the grid): each
    angle but the first is moved in turn to its best grid value until a
    sweep brings no improvement; the best end point wins. A local method:
    it found the brute-force optimum in the tests, but does not prove it.

    Parameters
    ----------
    w_W, wn_W : (N_w, 2) float
        Targets and outward normals, W, m.
    n_angles : int
        Number of C angles (>= 2).
    grid : Grid
    step_deg : float
        Search grid, degrees (must divide 360).
    reference_deg : sequence of float, optional
        The choice to compare with.
    measure : {"gauge", "form"}
        Which workpiece uncertainty to minimise (see :func:`max_workpiece_U95`;
        default "gauge", the declared reading).
    exhaustive_max : int
        Evaluate every combination instead when there are at most this many.
    evaluate : callable, optional
        ``evaluate(list_of_angle_tuples) -> list of max U95`` (to run a sweep
        in parallel, see ``scenarios.parallel``); default serial.
    progress : callable, optional
        ``progress(done, total)``, called as designs are evaluated. ``total``
        counts the designs the search may need at most (every start running
        all ``max_sweeps``); a start that converges early counts its unused
        sweeps as done, so the time left is an upper bound.

    Raises
    ------
    ConfigError
        ``n_angles`` not an integer >= 2, ``step_deg`` not a divisor of 360
        of at least 0.5 deg (a grid of at most 720 angles), ``u_probe_m``
        not > 0, a reference angle not finite, too many angles for the grid.
    """
    cand = _check_search(n_angles, step_deg, u_probe_m, reference_deg, max_sweeps)
    n_angles, step_deg = int(n_angles), float(step_deg)
    if n_angles > cand.size:
        raise ConfigError(f"{n_angles} angles do not fit a {step_deg:g} deg grid")
    count = _Count(progress)
    serial = evaluate is None
    if serial:
        def evaluate(sets):
            out = []
            for s in sets:
                out.append(max_workpiece_U95(w_W, wn_W, s, grid, u_probe_m, measure))
                count.add(1)
            return out
    ev, cache = _cached(evaluate, count, ticks_new=serial)
    starts = _search_starts(cand, n_angles, reference_deg, step_deg)
    best, best_v = None, float("inf")
    from math import comb
    n_ref = 0 if reference_deg is None else 1
    per_start = 1 + max_sweeps * (n_angles - 1) * (cand.size - n_angles + 1)
    if comb(cand.size - 1, n_angles - 1) <= exhaustive_max:
        count.total = comb(cand.size - 1, n_angles - 1) + n_ref
        best, best_v = _exhaustive(cand, n_angles, ev)
        starts = []
    else:
        count.total = len(starts) * per_start + n_ref
    for k, st in enumerate(starts):  # coordinate search from every start (a local method: several starts)
        cur, cur_v = _coordinate_search(st, cand, ev, max_sweeps)
        count.add((k + 1) * per_start - count.done)     # the sweeps this start did not need
        if cur_v < best_v:
            best, best_v = cur, cur_v
    cur, cur_v = (best, best_v) if best is not None else (list(starts[0]), float("inf"))
    ref_v = gain = None
    ref = None
    if reference_deg is not None:
        ref = tuple(float(v) for v in reference_deg)
        ref_v = ev([ref])[0]
        gain = ref_v / cur_v if np.isfinite(cur_v) and cur_v > 0 else None
    count.add(count.total)
    if not np.isfinite(cur_v):
        raise IdentifiabilityError(f"no choice of {n_angles} C angles on a {step_deg:g} deg grid identifies the"
                                   " workpiece (eq 6: more angles or a coarser grid)")
    return AngleDesign(c_deg=tuple(sorted(cur)), max_U95_m=cur_v, reference_deg=ref, reference_max_U95_m=ref_v,
                       gain=gain, evaluations=len(cache), step_deg=float(step_deg))


def _check_search(n_angles, step_deg, u_probe_m, reference_deg, max_sweeps) -> np.ndarray:
    """The grid of candidate angles, deg, after checking the search settings (ConfigError)."""
    try:
        n_ok = int(n_angles) == n_angles
    except (TypeError, ValueError, OverflowError):
        n_ok = False
    if not n_ok or int(n_angles) < 2:
        raise ConfigError(f"n_angles must be >= 2 (an integer), got {n_angles}")
    step = float(step_deg)
    if not (np.isfinite(step) and 0 < step <= 360):
        raise ConfigError(f"step_deg must be > 0 and divide 360, got {step:g}")
    nsteps = 360.0 / step
    if abs(nsteps - round(nsteps)) > 1e-9 * nsteps:
        raise ConfigError(f"step_deg must divide 360, got {step:g}")
    if round(nsteps) > 720:
        raise ConfigError(f"step_deg {step:g} makes a grid of {round(nsteps)} angles: at most 720 (0.5 deg)")
    if not (np.isfinite(u_probe_m) and u_probe_m > 0):
        raise ConfigError(f"u_probe_m must be > 0, got {float(u_probe_m):g}")
    if reference_deg is not None and not np.all(np.isfinite(np.asarray(reference_deg, dtype=float))):
        raise ConfigError("reference angles must be finite degrees")
    if int(max_sweeps) < 1:
        raise ConfigError(f"max_sweeps must be >= 1, got {max_sweeps}")
    return step * np.arange(int(round(nsteps)))


class _Count:
    """Designs considered so far, of at most ``total``, reported as ``progress(done, total)``."""

    def __init__(self, progress):
        self.progress, self.done, self.total = progress, 0, 0

    def add(self, k: int) -> None:
        self.done = min(self.done + k, self.total)
        if self.progress is not None:
            self.progress(self.done, self.total)


def _cached(evaluate, count: _Count | None = None, ticks_new: bool = False):
    """(ev, cache): ``evaluate`` over angle sets, each distinct (sorted) set evaluated once.

    ``count`` is advanced by the sets each call considers (by the cached ones
    only when ``evaluate`` itself counts the new ones: ``ticks_new``).
    """
    cache: dict = {}

    def ev(sets):
        keys = [tuple(sorted(float(v) for v in s)) for s in sets]
        todo = [k for k in dict.fromkeys(keys) if k not in cache]
        if todo:
            for k, v in zip(todo, evaluate(todo)):
                cache[k] = float(v)
        if count is not None:
            count.add(len(keys) - (len(todo) if ticks_new else 0))
        return [cache[k] for k in keys]

    return ev, cache


def _search_starts(cand: np.ndarray, n_angles: int, reference_deg, step_deg: float) -> list:
    """Equally spaced and compressed spreads of angles (a symmetric part makes equal spacing
    degenerate), and the reference when it has ``n_angles`` angles on the grid, 0 among them."""
    starts = []
    for f in (1.0, 0.77, 0.55):
        st = tuple(float(cand[int(round(i * f * cand.size / n_angles)) % cand.size]) for i in range(n_angles))
        if len(set(st)) == n_angles:
            starts.append(st)
    if reference_deg is not None and len(reference_deg) == n_angles:
        r = tuple(float(v) % 360 for v in reference_deg)
        if 0.0 in r and all(abs(v / step_deg - round(v / step_deg)) < 1e-9 for v in r):
            starts.append(tuple(sorted(r)))
    return starts


def _exhaustive(cand: np.ndarray, n_angles: int, ev) -> tuple[list, float]:
    """(best angles, its value) over every set of ``n_angles`` grid angles with C_1 = 0."""
    import itertools

    allsets = [(0.0,) + tuple(float(v) for v in c) for c in itertools.combinations(cand[1:], n_angles - 1)]
    vals = ev(allsets)
    i = int(np.argmin(vals))
    return list(allsets[i]), vals[i]


def _coordinate_search(start, cand: np.ndarray, ev, max_sweeps: int) -> tuple[list, float]:
    """(angles, value) where no single angle but the first improves by moving on the grid."""
    cur, cur_v = list(start), ev([start])[0]
    for _ in range(max_sweeps):
        improved = False
        for j in range(1, len(cur)):
            others = set(cur[:j] + cur[j + 1:])
            trial = [cur[:j] + [float(c)] + cur[j + 1:] for c in cand if float(c) not in others]
            tv = ev(trial)
            i = int(np.argmin(tv))
            if tv[i] < cur_v * (1 - 1e-9):
                cur, cur_v, improved = trial[i], tv[i], True
        if not improved:
            break
    return cur, cur_v
