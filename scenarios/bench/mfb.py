"""The multi-feature bar end to end: ``vmt scenario mfb-3axis`` in this process, and its gain.

Figures:

- ``mfb_3axis_end_to_end_s``: :func:`scenarios.mfb.run` of ``mfb-3axis``
  (simulation of the 17 measurements, points of interest, the extraction's
  gain, identification, Monte Carlo uncertainty, report, and since session 11 the
  plan's collision check), imports and the check's MuJoCo work zones warm, the gain
  and plan-check caches empty, as ``vmt scenario mfb-3axis`` spends it after its
  imports (and the zones' compiling); split by the run's progress steps into ``mfb_3axis_measure_s``
  (simulation + points of interest + gain), ``mfb_3axis_identify_s`` and
  ``mfb_3axis_uncertainty_s`` (Monte Carlo + report). Reference: the same
  run with the gain already cached (``mfb_3axis_gain_cached_s``). Each of these
  and the path before (next) the best of 3 runs, interleaved; every timed run here
  (these, the path before, the budget runs) starts with the plan-check cache empty,
  so each pays the same check and the ratios compare like runs.
- ``mfb_3axis_end_to_end_before_ref_s``: the same run in the same process by the path
  before issue 16's Monte Carlo work (:func:`before_shortcuts`: every design's nominal part
  from scratch, every Gauss-Newton row set recomputed whole with its Jacobian, the
  features fitted one by one with their checks, the kinematics of the rows one call per
  measurement, the gains' fits not shared, the measurements simulated one campaign each);
  ``mfb_3axis_end_to_end_max_theta_diff``
  between the two (m or rad).
- ``mfb_3axis_budget_run_s``: one Monte Carlo run of the budget (:func:`scenarios.mfb.budget_run`,
  attempt 1: every source drawn, no Monte Carlo of its own), beside
  ``mfb_3axis_budget_run_before_ref_s``, the same by the path before.
- ``mfb_3axis_identify_only_s``: :func:`core.volumetric.identify_volumetric` on
  that run's own inputs, beside ``mfb_3axis_identify_rows_before_ref_s``: the
  same with its rows built as before issue 19 (:func:`identify_before`), and
  ``mfb_3axis_identify_max_theta_diff`` between the two (m or rad).
- ``mfb_gain_s``: :func:`core.mfb.poi_noise_gain` of the three plans of
  ``mfb-3axis`` (batched light fits, shared between the plans as
  :func:`scenarios.mfb.run` shares them), beside ``mfb_gain_refit_reference_s``:
  the same gains by the previous path (:func:`gain_by_single_refits`: every
  perturbed feature refitted alone by the full :func:`core.fit.fit_cylinder`
  / :func:`core.fit.fit_plane`), on the same inputs in the same run, and
  ``mfb_gain_max_abs_diff`` between the two (dimensionless, |G| ~ 1).
- ``mfb_3axis_exact_tails_s``: the exact tails of the run's 19 residual tests (18 model-error
  shares and the between-node test: :func:`core.lsq.quadratic_form_sf`, on the saddlepoint contour
  since session 36) at their statistics, the weight sets recorded from one ``mfb-3axis`` run (seed 1,
  ``--mc 0``) with :data:`core.volumetric.EXACT_TAIL_NEAR_LEVEL` off (all 19 exact), beside
  ``mfb_3axis_exact_tails_imhof_ref_s``: the same tails by Imhof's quadrature
  (:func:`core.lsq._qf_sf_imhof`, the method before session 36) on the same weights; each the sum over
  the 19, best of 3, interleaved (:func:`exact_tails`). ``mfb_3axis_exact_tails_count`` the tails timed.
"""

from __future__ import annotations

import time

import numpy as np

#: figure -> its reference figure measured in the same run (ratio = figure / reference)
REFERENCES = {
    "mfb_3axis_end_to_end_s": "mfb_3axis_end_to_end_before_ref_s",
    "mfb_3axis_budget_run_s": "mfb_3axis_budget_run_before_ref_s",
    "mfb_gain_s": "mfb_gain_refit_reference_s",
    "mfb_3axis_identify_only_s": "mfb_3axis_identify_rows_before_ref_s",
    "mfb_3axis_exact_tails_s": "mfb_3axis_exact_tails_imhof_ref_s",
}
#: figure -> the issue's target
TARGETS = {"mfb_3axis_end_to_end_s": "< 1 s (issue 19 item 3)"}


def gain_by_single_refits(p_R, feature, n_R, d_R, geom=None, h_m: float = 1e-7) -> np.ndarray:
    """The extraction's gain as :func:`core.mfb.poi_noise_gain` computed it before it was batched.

    Each touch is moved by +-``h_m`` along ``d_R`` in turn and its feature is
    refitted alone by the full fits (checks, residuals, covariance), then the
    points of interest it enters are recomputed: the reference the batched
    light path is measured and tested against (tests/core/test_mfb.py).
    Returns (3k, n), as :func:`core.mfb.poi_noise_gain`.
    """
    from core import mfb
    from core.fit import fit_cylinder, fit_plane

    geom = mfb.MFB if geom is None else geom
    p_R, d_R, n_R = (np.asarray(a, float) for a in (p_R, d_R, n_R))
    feature = np.asarray(feature, dtype=object)
    bf = mfb.fit_bar_features(p_R, feature, n_R)
    holes = mfb.poi_from_features(bf, geom).holes
    rods = set(bf.rod_point)
    pair = {i: mfb._rod_pair(i, rods) for i in holes}
    row = {i: k for k, i in enumerate(holes)}

    def o_rows(b, hs):
        P, out = {}, {}
        for i in hs:
            a, c = pair[i]
            for j in (a, c):
                if j not in P:
                    P[j] = mfb._rod_points(b, j)
            pl = fit_plane(np.vstack([P[a], P[c]]), normal_hint=b.probe_side)
            out[i] = mfb._meet(b.hole_point[i], b.hole_axis[i], pl.point, pl.normal)
        return out

    base = o_rows(bf, holes)
    G = np.zeros((3 * len(holes), len(p_R)))
    for f, idx in mfb._group(feature).items():
        if (i := mfb._num(f, "hole")) is not None:
            hs = [i] if i in row else []
        elif (j := mfb._num(f, "rod")) is not None or f[:5] in ("faceL", "faceR"):
            j = j if j is not None else int(f[5:])
            hs = [h for h in holes if j in pair[h]]
        else:
            continue
        for k, sgn in ((k, sgn) for k in idx for sgn in (1.0, -1.0)) if hs else ():
            q = p_R[idx].copy()
            q[list(idx).index(k)] += sgn * h_m * d_R[k]
            hp, ha, rp, ra = dict(bf.hole_point), dict(bf.hole_axis), dict(bf.rod_point), dict(bf.rod_axis)
            fp, fn = dict(bf.face_point), dict(bf.face_normal)
            if (i := mfb._num(f, "hole")) is not None:
                c = fit_cylinder(q, axis_hint=bf.hole_axis[i])
                hp[i], ha[i] = c.point, c.axis
            elif (j := mfb._num(f, "rod")) is not None:
                c = fit_cylinder(q, axis_hint=bf.rod_axis[j])
                rp[j], ra[j] = c.point, c.axis
            else:
                key = (f[4], int(f[5:]))
                pl = fit_plane(q, normal_hint=bf.face_normal[key])
                fp[key], fn[key] = pl.point, pl.normal
            new = o_rows(mfb.BarFeatures(hp, ha, rp, ra, fp, fn, bf.probe_side), hs)
            for h in hs:
                G[3 * row[h]:3 * row[h] + 3, k] += sgn * (new[h] - base[h]) / (2.0 * h_m)
    return G


class _WeightsEveryLookup(dict):
    """Spline weights recomputed at every lookup: the cost of ``core.volumetric`` before
    issue 19 (weights evaluated once per error symbol, 36 times per measurement)."""

    def __init__(self, nodes, q):
        super().__init__()
        self._nodes, self._q = nodes, q

    def __getitem__(self, a):
        from core import iso, volumetric as vol

        return vol.spline_weights(self._nodes[a], self._q[:, iso.LINEAR_AXES.index(a)])


def _touch_kinematics_each(prep, theta, slices, exact, jacobian):
    """``core.volumetric._touch_kinematics`` as before it was batched: one sensitivity and
    one tip_W call per measurement, each with its stylus's geometry (same outputs)."""
    from core import volumetric as vol

    idx = [i for i, pm in enumerate(prep) if pm["touches"]]
    if not idx or not (exact or jacobian):
        return None, None, {}
    S, tip, at, t0 = [], [], {}, 0
    for i in idx:
        pm = prep[i]
        at[i], t0 = t0, t0 + len(pm["qt"])
        v = vol._values(theta, slices, pm["W"], len(pm["qt"])) if exact else None
        if jacobian:
            S.append(vol.sensitivity(pm["g"], pm["qt"], pm["rott"], v, symbols=vol.MOTION + vol.SQUARENESS))
        if exact:
            tip.append(vol.tip_W(pm["g"], pm["qt"], pm["rott"], v))
    return (np.concatenate(S) if S else None), (np.concatenate(tip) if tip else None), at


def identify_before(args, kwargs):
    """``core.volumetric.identify_volumetric`` with its rows built as before issue 19: spline
    weights once per symbol, the (t, 3, n) Jacobian of the touches built then projected, the
    kinematics one call per measurement. (The shared rotations in ``core.kinematics.sensitivity``
    and the error-free tips in one call, :func:`core.volumetric._prepare_all`, are in both paths.)"""
    from core import volumetric as vol

    saved = vol._axis_weights, vol._projected_error_jacobian, vol._touch_kinematics
    vol._touch_kinematics = _touch_kinematics_each
    vol._axis_weights = _WeightsEveryLookup
    vol._projected_error_jacobian = lambda S, d, W, slices, n: np.einsum(
        "tj,tjn->tn", d, vol._error_jacobian(S, W, slices, n))
    try:
        return vol.identify_volumetric(*args, **kwargs)
    finally:
        vol._axis_weights, vol._projected_error_jacobian, vol._touch_kinematics = saved


class NeverKept(dict):
    """A cache that keeps nothing (core.volumetric's nominal designs before they were kept)."""

    def get_or_compute(self, key, compute, owner=None):
        return compute()


def rows_whole(rows):
    """``core.volumetric._rows`` as before its theta-independent parts were kept: ``rows`` (the
    real one) with no prepared parts and always with its Jacobian (also for the last residual).
    With :class:`NeverKept` as ``_NOMINAL``, the reference of the identification's shortcuts
    (here and tests/core/test_volumetric.py)."""
    def rows_before(*a, **k):
        k.pop("prep", None)
        k["jacobian"] = True
        return rows(*a, **k)

    return rows_before


def before_shortcuts():
    """Context manager: ``scenarios.mfb.run`` as before issue 16's Monte Carlo work (the
    reference of ``mfb_3axis_end_to_end_s``): the nominal design rebuilt at every
    identification, every ``_rows`` call recomputing its theta-independent parts and its
    Jacobian (also for the last residual), the bar's features fitted one by one by the
    validated single fits, placement by placement, the rows' kinematics one call per
    measurement, the gains' fits not shared between hole sets, the measurements simulated one
    campaign each (each plan validated each time; issue 19). (Not undone: the bar's program
    built once per run, the error-free tips in one call, the gain's planes PL_h in one batch.)"""
    import contextlib

    from core import mfb, volumetric as vol
    from sim import campaign

    @contextlib.contextmanager
    def ctx():
        rows, nominal, poi, pois = vol._rows, vol._NOMINAL, mfb.points_of_interest, mfb.points_of_interest_batched
        kin, fit_once, sim_all = vol._touch_kinematics, mfb._fit_once, campaign.simulate_measurements

        vol._rows, vol._NOMINAL = rows_whole(rows), NeverKept()
        mfb.points_of_interest_batched = lambda places, geom=mfb.MFB: [poi(p, f, n, geom) for p, f, n in places]
        vol._touch_kinematics = _touch_kinematics_each
        mfb._fit_once = lambda fits, *a: fit_once(None, *a)  # no fit shared between hole sets
        campaign.simulate_measurements = campaign._simulate_each_measurement  # one campaign each
        try:
            yield
        finally:
            vol._rows, vol._NOMINAL, mfb.points_of_interest_batched = rows, nominal, pois
            vol._touch_kinematics, mfb._fit_once, campaign.simulate_measurements = kin, fit_once, sim_all

    return ctx()


def plan_gain_inputs(name: str = "mfb-3axis") -> list[tuple]:
    """``(c_A, feature, wn_A, d_A)`` of each distinct hole set of a scenario's plan (nominal bar, 3 mm stylus)."""
    from scenarios.mfb import PLANS, _plan_for
    from sim import artefacts as A

    art = A.multi_feature_bar(deviations_m=np.zeros((12, 3)))
    out = []
    for holes in dict.fromkeys(tuple(ms.holes) for ms in PLANS[name]().measurements):
        pl = _plan_for(art, holes)
        out.append((pl.w_A + 3e-3 * pl.wn_A, pl.feature, pl.wn_A, -pl.wn_A))
    return out


def residual_test_weights(name: str = "mfb-3axis", seed: int = 1) -> list[tuple[np.ndarray, float]]:
    """``(weights, statistic)`` of every residual test's exact tail in one run of ``name`` (``--mc 0``), each
    computed (:data:`core.volumetric.EXACT_TAIL_NEAR_LEVEL` off for the run), as :func:`core.lsq.quadratic_form_sf`
    was called."""
    from core import lsq, volumetric as vol
    from scenarios import mfb as S

    seen, real, near = [], lsq.quadratic_form_sf, vol.EXACT_TAIL_NEAR_LEVEL

    def spy(weights, x=0.0, mult=None):
        seen.append((np.array(weights, float), float(x)))
        return real(weights, x, mult)

    lsq.quadratic_form_sf, vol.EXACT_TAIL_NEAR_LEVEL = spy, False
    try:
        S.run(name, seed=seed, mc_runs=0)
    finally:
        lsq.quadratic_form_sf, vol.EXACT_TAIL_NEAR_LEVEL = real, near
    return seen


def exact_tails(sets, rounds: int = 3) -> tuple[float, float]:
    """(contour s, Imhof s): the sum over ``sets`` of :func:`core.lsq.quadratic_form_sf` (the contour, its checks
    and scaling) and of :func:`core.lsq._qf_sf_imhof` on the same weights scaled as it scales them, the better of
    ``rounds`` each, interleaved (the order alternating between rounds)."""
    from core import lsq

    scaled = [(w / np.abs(w).max(), np.ones(w.size), x / np.abs(w).max()) for w, x in sets]
    con, imh = [], []
    for k in range(rounds):
        for which in ((0, 1) if k % 2 == 0 else (1, 0)):
            t0 = time.perf_counter()
            if which == 0:
                for w, x in sets:
                    lsq.quadratic_form_sf(w, x)
                con.append(time.perf_counter() - t0)
            else:
                for w, h, x in scaled:
                    lsq._qf_sf_imhof(w, h, x)
                imh.append(time.perf_counter() - t0)
    return min(con), min(imh)


def run() -> dict:
    from core import mfb
    from scenarios import mfb as S

    out: dict = {}
    inputs = plan_gain_inputs()
    t0 = time.perf_counter()
    fits: dict = {}
    G_new = [mfb.poi_noise_gain(*a, fits=fits) for a in inputs]
    t1 = time.perf_counter()
    G_ref = [gain_by_single_refits(*a) for a in inputs]
    t2 = time.perf_counter()
    out["mfb_gain_s"] = round(t1 - t0, 3)
    out["mfb_gain_refit_reference_s"] = round(t2 - t1, 3)
    out["mfb_gain_max_abs_diff"] = float(max(np.abs(a - b).max() for a, b in zip(G_new, G_ref)))

    from core import volumetric as vol

    S.run("mfb-3axis", mc_runs=20)  # imports and first-use caches warm
    ident = {}
    real = vol.identify_volumetric

    def spy(*a, **k):
        ident["args"] = (a, k)
        return real(*a, **k)

    # end to end (the gains' cache emptied each time) and the path before (as it ran: gains
    # cached), interleaved, best of 3 each: one run of ~1 s on a shared virtual machine moved
    # by 0.9-1.4 s between five back-to-back runs; the minimum is the run least disturbed
    # Every timed run pays the plan's collision check (run checks the 3-axis plan since session 11):
    # the plan-check cache emptied before each (its MuJoCo zones kept warm), so the end-to-end run
    # and its references differ only in what they are named for (the gains' cache, the shortcuts)
    t_run, t_cached, t_before, best = [], [], [], None
    for _ in range(3):
        stamps = {}
        S._GAINS.clear()
        S._CHECKS.clear()
        vol.identify_volumetric = spy
        try:
            t0 = time.perf_counter()
            S.run("mfb-3axis", progress=lambda k, n, st=stamps: st.setdefault(k, time.perf_counter()))
            t_end = time.perf_counter()
        finally:
            vol.identify_volumetric = real
        t_run.append(t_end - t0)
        if best is None or t_run[-1] <= min(t_run):
            best = (t0, t_end, stamps)
        S._CHECKS.clear()
        t0 = time.perf_counter()
        r_now = S.run("mfb-3axis")  # the gains cached, as the path before ran
        t_cached.append(time.perf_counter() - t0)
        S._CHECKS.clear()
        with before_shortcuts():
            t0 = time.perf_counter()
            r_before = S.run("mfb-3axis")
            t_before.append(time.perf_counter() - t0)
    t0, t_end, stamps = best
    sim_at, ident_at = stamps[S.PROGRESS_SIMULATED], stamps[S.PROGRESS_IDENTIFIED]
    out["mfb_3axis_end_to_end_s"] = round(t_end - t0, 3)
    out["mfb_3axis_measure_s"] = round(sim_at - t0, 3)
    out["mfb_3axis_identify_s"] = round(ident_at - sim_at, 3)
    out["mfb_3axis_uncertainty_s"] = round(t_end - ident_at, 3)
    out["mfb_3axis_end_to_end_before_ref_s"] = round(min(t_before), 3)
    out["mfb_3axis_gain_cached_s"] = round(min(t_cached), 3)
    out["mfb_3axis_end_to_end_max_theta_diff"] = float(np.abs(r_now.result.theta - r_before.result.theta).max())
    # the identification alone on the run's own inputs, as it is and as before, side by side
    t_new, t_old = [], []
    for _ in range(2):
        t0 = time.perf_counter()
        r_new = real(*ident["args"][0], **ident["args"][1])
        t_new.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        r_old = identify_before(*ident["args"])
        t_old.append(time.perf_counter() - t0)
    out["mfb_3axis_identify_only_s"] = round(min(t_new), 3)
    out["mfb_3axis_identify_rows_before_ref_s"] = round(min(t_old), 3)
    out["mfb_3axis_identify_max_theta_diff"] = float(np.abs(r_new.theta - r_old.theta).max())
    # one Monte Carlo run of the budget, now and before, side by side (warm: the first was run above)
    S.budget_run("mfb-3axis", 2)
    S._CHECKS.clear()
    t0 = time.perf_counter()
    b_now = S.budget_run("mfb-3axis", 1)
    out["mfb_3axis_budget_run_s"] = round(time.perf_counter() - t0, 3)
    S._CHECKS.clear()
    with before_shortcuts():
        t0 = time.perf_counter()
        b_before = S.budget_run("mfb-3axis", 1)
        out["mfb_3axis_budget_run_before_ref_s"] = round(time.perf_counter() - t0, 3)
    out["mfb_3axis_budget_run_max_error_diff"] = float(np.abs(b_now["error"] - b_before["error"]).max())
    # the residual tests' exact tails, on the contour and by Imhof's quadrature, on the same weight sets
    sets = residual_test_weights()
    t_con, t_imh = exact_tails(sets)
    out["mfb_3axis_exact_tails_s"] = round(t_con, 4)
    out["mfb_3axis_exact_tails_imhof_ref_s"] = round(t_imh, 4)
    out["mfb_3axis_exact_tails_count"] = len(sets)
    return out


if __name__ == "__main__":  # pragma: no cover - by hand: python -m scenarios.bench.mfb
    print(run())
