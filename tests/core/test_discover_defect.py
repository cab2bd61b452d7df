"""``local_scale_defect`` named only when the structure is one: confined along an axis, seen at two places.

A local scale defect is an axis' positioning error confined to a stretch
of the axis (:func:`core.causes.defect_scans`). Two things read like its
bump without being one, and both were named ``local_scale_defect`` before:

- the grid's piecewise linear map leaves a smooth error's curvature as
  cusps at its nodes, bumps a fifth to a half of a grid step wide
  (effect-free campaigns of tests/core/discover_synth.py, whose smooth
  errors the 55 mm grid cannot follow: seeds 8, 42, 135 and 140 of 0-199
  were named ``local_scale_defect``). The bump must explain what the same
  errors smooth over the whole axes (cubic splines on the grid's nodes,
  :func:`core.causes.smooth_error_map`) do not;
- a chip at one target in one set-up: what the bump explains comes from
  one position. It must come from two effective positions or more
  (:func:`core.discover._support`).
"""

from __future__ import annotations

import copy
import dataclasses
import functools

import numpy as np
import pytest

from core import baseline, causes
from core.diagnosis import orth
from core.discover import (MIN_SUPPORT, Settings, Term, _State, _demotion_reason, _explains_set_aside, _half_power_nc,
                           _support, discover)
from core.lsq import orth_of
import discover_synth as S
from tests.discover_helpers import discovered


@pytest.mark.parametrize("seed", [8, 42, 135, 140])
def test_a_smooth_residual_is_not_confidently_a_local_defect(seed):
    """Effect-free campaigns named local_scale_defect, confidently, before (main of 2026-12-03): now at most ambiguous.

    These seeds are the ones of 0-199 that failed; a test over all 200
    would take minutes. On these the confinement test has no power (the
    bump's signal outside the smooth error map is below the noncentrality
    giving 50 % power, :func:`core.discover._half_power_nc`), so the
    cause is not refused but named ambiguous, the smooth error map given
    as what the design cannot tell it from."""
    t, _ = S.campaign("none", seed)
    rep = discover(t).to_report()
    for f in rep["findings"]:
        if f["cause"] == "local_scale_defect":
            assert f["evidence"]["confidence"] == "ambiguous", f["evidence"].get("confidence_reason")
            assert f["evidence"]["indistinguishable_counter"] == "smooth error map"
    why = [r["reason"] for r in rep["rejected"] if r["cause"] == "local_scale_defect"]
    assert all(w.startswith("not confined") for w in why), why


def test_half_power_noncentrality_by_hand():
    """k = 1: the test |Z + sqrt(lam)| > z(alpha/2) has power Phi(sqrt(lam) - z) + Phi(-sqrt(lam) - z); solved
    with that normal form (not ncx2) it gives the same lam to 1e-6; more dof or a smaller alpha need more."""
    from scipy import optimize, stats
    for a in (0.05, 0.01 / 30):
        z = stats.norm.isf(a / 2)
        lam = optimize.brentq(lambda l: stats.norm.cdf(np.sqrt(l) - z) + stats.norm.cdf(-np.sqrt(l) - z) - 0.5, 1e-9, 100)
        assert _half_power_nc(1, a) == pytest.approx(lam, rel=1e-6)
    assert _half_power_nc(1, 0.05) < _half_power_nc(3, 0.05) < _half_power_nc(3, 0.001)


def test_a_rival_step_refusal_says_its_own_reason():
    """A support or confinement refusal is the reason whatever the rival share (the old inline expression,
    ``A or B or C if cond else D``, parsed as ``(A or B or C) if cond else D`` and gave the share text)."""
    st = Settings()
    low = {"kept": False, "rival_share": 0.1}
    assert _demotion_reason({**low, "not_supported": "not seen at two places: x"}, "x_R", st).startswith(
        "not seen at two places")
    assert _demotion_reason({**low, "not_confined": "not confined: y"}, "x_R", st).startswith("not confined")
    assert _demotion_reason(low, "x_R", st).startswith("explains only part of the structure in x_R")
    high = {"kept": False, "rival_share": 1.0, "counter": "finer grid", "counter_explained_ss_um2": 3.0}
    assert _demotion_reason(high, "x_R", st) == "a plainer explanation (finer grid) explains as much"
    assert _demotion_reason({**high, "not_confined": "not confined: y"}, "x_R", st) == "not confined: y"


def _chip(seed: int, amp_m: float):
    """An effect-free synthetic campaign with a chip on one target in one set-up (every touch of it there)."""
    rng = np.random.default_rng(1000 + seed)
    t, _ = S.campaign("none", seed)
    j = rng.integers(4)
    m = t.setup == j
    tg = rng.choice(np.unique(t.target[m]))
    dq = np.where(m & (t.target == tg), amp_m, 0.0)
    return dataclasses.replace(t, p_R=t.p_R + dq[:, None] * t.n_R)


def test_a_chip_at_one_position_is_not_a_local_defect():
    """A 2 um chip (6.7 sigma) on the touches of one target in one set-up, seeds 0-9: before, seeds 2 and 9
    were named local_scale_defect (main of 2026-12-03); now none is confidently. Seed 2 is named ambiguous:
    not for the chip (its bump's evidence spreads over 15 effective positions) but for the campaign's smooth
    residual, which the confinement test has no power to refuse there (as the effect-free seeds above)."""
    named = [(s, f.evidence["confidence"]) for s in range(10) for f in discover(_chip(s, 2e-6)).findings
             if f.cause == "local_scale_defect"]
    assert all(c == "ambiguous" for _, c in named), named


@pytest.mark.parametrize("mag_um", [1.2, 2.0])
def test_a_true_defect_is_still_named(mag_um):
    """The synthetic Gaussian bump (sigma 3 mm, written apart from the Hann columns) at 1.2 and 2 um over
    0.3 um noise, seeds 0-4: named on every one, as before."""
    for s in range(5):
        t, _ = S.campaign("local_scale_defect", s, mag_um * 1e-6)
        assert discover(t).cause == "local_scale_defect", s


def test_support_hand_worked():
    """Four positions; the evidence f . r per position summed: all at one -> 1 unit, split evenly over two -> 2."""
    lab = np.array([0, 0, 1, 1, 2, 2, 3, 3])
    E = np.array([[1.0, 1.0, 0.5, 0.5, 0.25, 0.25, 0.1, 0.1]]).T
    cause = causes.Cause("c", ("planar",), "machine", None, None, {}, support=lambda bl, info: lab)
    Q = np.zeros((8, 0))
    rows = np.arange(8)

    def units(r):
        return _support(None, cause, {}, _State(rows, Q, r, float(r @ r), 8), E)

    # the residual on position 0 only: f . r = (u . r) u_i r_i, all of it at position 0
    one = units(np.array([1.0, 1.0, 0, 0, 0, 0, 0, 0]))
    assert one["support_units"] == pytest.approx(1.0, rel=1e-12) and one["refused"]
    # r = E (the bump itself): f = r, the evidence r_i^2 per position 2, 0.5, 0.125, 0.02 -> 2.645 / 2
    full = units(E[:, 0].copy())
    assert full["support_units"] == pytest.approx(2.645 / 2.0, rel=1e-12) and full["refused"]
    # equal residuals at positions 0 and 1 on a column equal there: the two carry half each
    E2 = np.array([[1.0, 1.0, 1.0, 1.0, 0, 0, 0, 0]]).T
    two = _support(None, cause, {}, _State(rows, Q, E2[:, 0].copy(), 4.0, 8), E2)
    assert two["support_units"] == pytest.approx(2.0, rel=1e-12) and not two["refused"]
    assert MIN_SUPPORT == 2.0


def test_smooth_error_map_follows_a_quadratic_exactly():
    """A quadratic error of each table (E_XX(x), E_YX(x), E_XY(y), E_YY(y)) beyond the grid's linear map
    is inside span(baseline, smooth_error_map): the cubic splines on the grid's nodes hold any quadratic.
    Residual below 1e-9 of the error's norm (rounding of a 500-row least squares); the grid alone leaves
    a residual of several per cent of it."""
    t, _ = S.campaign("none", 0)
    bl = baseline.planar(t, grid_step_mm=55.0)
    d = bl.data
    u, v = (d.x - d.x.mean()) / 0.1, (d.y - d.y.mean()) / 0.1
    e = -d.nx * (u ** 2 + 0.3 * v ** 2) - d.ny * (0.7 * u ** 2 - v ** 2)
    A = bl.A.toarray() if hasattr(bl.A, "toarray") else np.asarray(bl.A)
    Q = orth_of(A)
    r0 = e - Q @ (Q.T @ e)
    assert np.linalg.norm(r0) > 0.02 * np.linalg.norm(e)  # the linear map alone does not follow it
    Qs = orth(np.hstack([Q, causes.smooth_error_map(bl)]))
    r = e - Qs @ (Qs.T @ e)
    assert np.linalg.norm(r) < 1e-9 * np.linalg.norm(e)


def test_path_count_hand_worked():
    """Davies' count on hand-made paths: trials that are one column (no length) count 1 per scan; two
    orthogonal unit columns (a path of length pi/2) count level / p*, p* solving p + (1/2) exp(-u/2) = level
    with u the chi-square(1) quantile of p (the bound written out by hand, solved by bisection here); the same for
    trials of two columns (a chi-square process of two degrees of freedom)."""
    from scipy import stats
    from core.discover import _path_tries
    n = 12
    st = _State(np.arange(n), np.zeros((n, 0)), np.zeros(n), 1.0, n)
    same = np.ones((5, n, 1))
    sc = causes.Scan(("b",), tuple({} for _ in range(5)), "x", lambda idx: same[np.asarray(idx)], path=True)
    assert _path_tries([sc], st, 0.01) == pytest.approx(1.0, rel=1e-9)
    assert _path_tries([sc, sc], st, 0.01) == pytest.approx(2.0, rel=1e-9)
    two = np.zeros((2, n, 1))
    two[0, 0, 0] = two[1, 1, 0] = 1.0
    sc2 = causes.Scan(("b",), ({}, {}), "x", lambda idx: two[np.asarray(idx)], path=True)
    lo, hi = 1e-12, 0.01
    for _ in range(200):
        mid = np.sqrt(lo * hi)
        if mid + 0.5 * np.exp(-stats.chi2.isf(mid, 1) / 2) > 0.01:
            hi = mid
        else:
            lo = mid
    assert _path_tries([sc2], st, 0.01) == pytest.approx(0.01 / lo, rel=1e-4)
    # trials of two columns (session 24: the periodic scan's four): one span throughout counts 1; two orthogonal
    # planes (principal angles pi/2, pi/2: a step of sqrt((pi^2/4 + pi^2/4) / 2) = pi/2) solve
    # p + (pi/2) sqrt(u) exp(-u/2) / sqrt(2 pi) = level, u the chi-square(2) quantile (a chi-square process of 2 dof)
    wide = np.zeros((5, n, 2))
    wide[:, 0, 0] = wide[:, 1, 1] = 1.0
    sc3 = causes.Scan(("a", "b"), tuple({} for _ in range(5)), "x", lambda idx: wide[np.asarray(idx)], path=True)
    assert _path_tries([sc3], st, 0.01) == pytest.approx(1.0, rel=1e-9)
    planes = np.zeros((2, n, 2))
    planes[0, 0, 0] = planes[0, 1, 1] = planes[1, 2, 0] = planes[1, 3, 1] = 1.0
    sc4 = causes.Scan(("a", "b"), ({}, {}), "x", lambda idx: planes[np.asarray(idx)], path=True)
    lo, hi = 1e-12, 0.01
    for _ in range(200):
        mid = np.sqrt(lo * hi)
        u = stats.chi2.isf(mid, 2)
        if mid + np.pi / 2 * np.sqrt(u) * np.exp(-u / 2) / np.sqrt(2 * np.pi) > 0.01:
            hi = mid
        else:
            lo = mid
    assert _path_tries([sc4], st, 0.01) == pytest.approx(0.01 / lo, rel=1e-4)


def test_the_defect_scan_count_holds_under_noise():
    """Pure noise beside an effect-free synthetic campaign's baseline (seed 0, 2000 draws): the scan's least
    p-value times its count falls below 0.05 at most 5 % of the time (plus 2.5 binomial sigma, 0.011) with
    the count raised to Davies' bound (core.discover._path_tries, 197 here: 3.1 %); the scan's own count,
    extent over half-width per width and axis (55 here), let it fall there 9.6 % of the time (and 7.75 % of
    400 draws on the simulator's campaign 3301): beside the baseline's per-target constants the bumps
    decorrelate faster than that. At 0.01: 1.9 % with the scan's count, 0.7 % with Davies'.

    This is the scanned grid's statistic. The engine refines the half-width (0.75-1.33 times a scanned
    one, core.discover._refine), which the count does not cover: a reviewer's 20,000 draws here had the
    refined statistic below 0.05 6.25 % of the time, 1.49 % below 0.01 and 0.83 % below 0.0056 (the old
    count: 17 %, 4.6 %, 2.9 %): still about 1.5 times the nominal level, not tested here.

    Each trial is one column: its F test's p-value falls as (c . r)^2 / |c|^2 rises (c the column beside the
    model), so the least p-value of a draw is that of the largest, from one product of the projected,
    normalised columns with every draw (as core.diagnosis.nested_f_batch tests them, one trial at a time)."""
    from scipy import special
    from core.diagnosis import IN_SPAN, take_rows
    from core.discover import _path_tries
    t, _ = S.campaign("none", 0)
    bl = baseline.planar(t, grid_step_mm=55.0)
    A = bl.A.toarray() if hasattr(bl.A, "toarray") else np.asarray(bl.A)
    Q = orth_of(A)
    rows = np.arange(bl.n)
    scans, count = causes.defect_scans(bl)
    st = _State(rows, Q, np.zeros(bl.n), 1.0, bl.n - Q.shape[1])
    davies = _path_tries(scans, st, 0.05)
    C = np.hstack([take_rows(sc.build(np.arange(sc.size)), rows, 1)[:, :, 0].T for sc in scans])
    C = C / np.linalg.norm(C, axis=0)
    P = C - Q @ (Q.T @ C)
    w = np.sum(P * P, axis=0)
    P = P[:, w > IN_SPAN ** 2] / np.sqrt(w[w > IN_SPAN ** 2])
    Z = np.random.default_rng(7).normal(size=(2000, bl.n)).T  # (the draws the loop over nested_f_batch made)
    Rz = Z - Q @ (Q.T @ Z)
    rss = np.sum(Rz * Rz, axis=0)
    ss = np.max((P.T @ Rz) ** 2, axis=0)
    pmin = special.fdtrc(1, st.dof - 1, ss / ((rss - ss) / (st.dof - 1)))
    bound = 0.05 + 2.5 * np.sqrt(0.05 * 0.95 / pmin.size)
    assert davies > count
    assert np.mean(pmin * max(davies, count) < 0.05) <= bound


def test_path_count_exact_arcs_beside_a_model():
    """Closed form, no solver: a path of length V on one scan, the bound p + V exp(-u/2) / pi at the single-trial
    p = P(chi2_1 > u) is the level; the count is level / p. Columns q + e1, q + e2 beside the model q (projected
    out: e1, e2, a quarter arc, V = pi/2) and three columns at 0, 30 and 60 degrees in a plane (V = pi/3, two
    steps of pi/6), at u = 12 and 20 (rel 1e-5: the solver's xtol 1e-6 on log p)."""
    from scipy import stats
    from core.discover import _path_tries
    n = 6
    q = np.zeros((n, 1))
    q[5, 0] = 1.0
    quarter = np.zeros((2, n, 1))
    quarter[0, 0, 0] = quarter[1, 1, 0] = 1.0
    quarter[:, 5, 0] = 1.0  # (inside the model: taken out before the angles are measured)
    a = np.radians([0.0, 30.0, 60.0])
    third = np.zeros((3, n, 1))
    third[:, 0, 0], third[:, 1, 0] = np.cos(a), np.sin(a)
    st = _State(np.arange(n), q, np.zeros(n), 1.0, n - 1)
    for cols, V in ((quarter, np.pi / 2), (third, np.pi / 3)):
        sc = causes.Scan(("b",), tuple({} for _ in cols), "x", lambda idx, c=cols: c[np.asarray(idx)], path=True)
        for u in (12.0, 20.0):
            p = stats.chi2.sf(u, 1)
            level = p + V * np.exp(-u / 2) / np.pi
            assert _path_tries([sc], st, level) == pytest.approx(level / p, rel=1e-5)


@pytest.mark.parametrize("block_bytes", [1, 8 * 6 * 2, 8 * 6 * 3, 32 << 20])
def test_path_count_does_not_depend_on_its_blocks(monkeypatch, block_bytes):
    """A long log's blocks hold fewer trials (PATH_BLOCK_BYTES; 6 rows here: 1, 2, 3 and 64 trials a block):
    the arc's length and so the count are the same. Nine columns at 0, 10, ..., 80 degrees in a plane beside
    the model q: V = 4 pi / 9 in eight steps, whichever steps fall across a block's edge (each block starts at
    the previous one's last trial); the count against the closed form level / p (rel 1e-5, the solver's xtol)."""
    from scipy import stats
    from core import discover as D
    monkeypatch.setattr(D, "PATH_BLOCK_BYTES", block_bytes)
    n = 6
    q = np.zeros((n, 1))
    q[5, 0] = 1.0
    a = np.radians(np.arange(0.0, 81.0, 10.0))
    cols = np.zeros((len(a), n, 1))
    cols[:, 0, 0], cols[:, 1, 0], cols[:, 5, 0] = np.cos(a), np.sin(a), 2.0
    st = _State(np.arange(n), q, np.zeros(n), 1.0, n - 1)
    sc = causes.Scan(("b",), tuple({} for _ in cols), "x", lambda idx: cols[np.asarray(idx)], path=True)
    p = stats.chi2.sf(14.0, 1)
    level = p + (4 * np.pi / 9) * np.exp(-14.0 / 2) / np.pi
    assert D._path_tries([sc], st, level) == pytest.approx(level / p, rel=1e-5)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_spread_smooth_error_is_still_refused_as_not_confined(seed):
    """A quadratic error of the tables (E_XX, E_YX, E_XY, E_YY; 10.6 um RMS, 0.54 um RMS beyond the 55 mm grid's
    linear map, inside the smooth error map exactly) over 0.3 um noise on synthetic seed 0's layout: the best
    bump of the defect scan beside the baseline is refused as not confined, for the smooth map explains
    significantly more beyond it (p ~1e-74 against alpha_family 0.0025), and is not called indistinguishable.
    Guards the refusal's added condition (the smooth map significant beyond the bump) against making it
    unreachable. (At a third of the error, 0.18 um beyond the grid, the bump's signal outside the smooth map
    is below the test's 50 % power and it is indistinguishable instead.)"""
    from core.diagnosis import take_rows
    from core.discover import _path_tries, _smooth_verdict
    t, _ = S.campaign("none", 0)
    bl = baseline.planar(t, grid_step_mm=55.0)
    d = bl.data
    A = bl.A.toarray() if hasattr(bl.A, "toarray") else np.asarray(bl.A)
    Q = orth_of(A)
    rows = np.arange(bl.n)
    u, v = (d.x - d.x.mean()) / 0.1, (d.y - d.y.mean()) / 0.1
    e = 30e-6 * (-d.nx * (u ** 2 + 0.3 * v ** 2) - d.ny * (0.7 * u ** 2 - v ** 2))
    y = e + 0.3e-6 * np.random.default_rng(seed).normal(size=bl.n)
    r = y - Q @ (Q.T @ y)
    st = _State(rows, Q, r, float(r @ r), bl.n - Q.shape[1])
    scans, _ = causes.defect_scans(bl)
    C = np.hstack([take_rows(sc.build(np.arange(sc.size)), rows, 1)[:, :, 0].T for sc in scans])
    P = C - Q @ (Q.T @ C)
    best = int(np.argmax((P.T @ r) ** 2 / np.sum(P * P, axis=0)))
    cause = next(c for c in causes.REGISTRY if c.name == "local_scale_defect")
    settings = Settings()
    tries = 9 * _path_tries(scans, st, settings.alpha_family / 9)
    out = _smooth_verdict(bl, cause, st, C[:, [best]], 0.3e-6, tries, settings)
    assert out["p_smooth_beyond_cause"] < settings.alpha_family
    assert out["refused"] and not out["indistinguishable"]


def test_defect_scores_made_afresh_are_the_kept_table_ones(monkeypatch):
    """A local defect's score table (rows x centres and its square) is kept only while it is small
    (core.diagnosis.TABLE_BYTES: a 1e5-row log's 72 centres were 110 MB); made afresh at each call instead, the
    scores are the same numbers bit for bit (the same products on the same operands), on every row and on a
    subset, twice (the kept denominators)."""
    t, _ = S.campaign("local_scale_defect", 3, 2e-6)
    bl = baseline.planar(t, grid_step_mm=55.0)
    rng = np.random.default_rng(4)
    r = rng.normal(size=bl.n)
    sub = np.sort(rng.choice(bl.n, bl.n - 7, replace=False))
    kept = causes.defect_scans(bl)[0]
    monkeypatch.setattr(causes, "TABLE_BYTES", 0)
    fresh = causes.defect_scans(bl)[0]
    assert len(kept) == len(fresh) > 0
    for a, b in zip(kept, fresh):
        for rows in (np.arange(bl.n), sub, sub):
            assert np.array_equal(a.score(r[rows], rows), b.score(r[rows], rows))


def _gen_b_defect_1047(chips_um: float = 0.0):
    """gen_b local_scale_defect 1047 (a bump 2 mm wide on the X scale, peak 5 um, noise 0.33 um), through its
    interface only; with ``chips_um``, a chip of that height on one touch in each of two set-ups, where the
    defect does not reach (its effect below 0.01 um, 40 mm or more from its centre along X: beyond the widest
    scanned bump, 0.4 grid steps of 25 mm). Returns (report, truth, chip rows)."""
    from core.touches import from_log
    from scenarios.blind import gen_b

    log, truth = gen_b.generate("local_scale_defect", 1047)
    t = from_log(log)
    chips = []
    if chips_um:
        x = np.asarray(log.columns["X_mm"], float)
        setups = np.asarray(log.columns["setup"])
        far = (np.abs(np.asarray(truth.effect_dq_um)) < 0.01) & (np.abs(x - truth.params["centre_mm"]) > 40.0)
        for s in list(dict.fromkeys(setups))[1:3]:
            chips.append(int(np.flatnonzero(far & (setups == s))[5]))
        for r in chips:
            i = np.flatnonzero(t.row == r)[0]
            t.p_R[i] += t.n_R[i] * chips_um * 1e-6
    rep = discovered(log, t).to_report()
    return rep, truth, chips


def test_a_narrow_bump_cut_in_two_set_ups_is_not_read_as_outliers():
    """gen_b local_scale_defect 1047: the bump (2 mm wide) is narrower than the narrowest scanned one (half-width
    0.2 grid steps, 5 mm), so the first outlier screen took its three largest touches (4.6, 4.0 and -4.3 um, in
    two set-ups) and the search on every row, which adopts the defect, left the same three beyond the bound
    beside it: 'fewer outliers left' failed and the report was `outlier`, confident (a3ba8ad). The defect
    adopted on every row cuts their residuals by a quarter or more in two set-ups or more
    (core.discover._explains_set_aside): they are its structure. Named, none left set aside, the three put
    back. Since the scan's half-widths reach the positions' resolution (core.causes.DEFECT_WIDTHS, issue 13,
    session 14) the first screen's model holds a bump of the right width (3.6 mm), which leaves none of its
    touches beyond the bound: nothing set aside, nothing to put back (the rule is tested by hand below)."""
    rep, truth, _ = _gen_b_defect_1047()
    assert rep["cause"] in truth.acceptable_causes, rep["cause"]
    assert rep["findings"][0]["evidence"]["confidence"] == "named", rep["findings"][0]["evidence"]
    assert rep["outlier_rows"] == [], rep["outlier_rows"]
    assert rep["findings"][0]["evidence"].get("outliers_put_back", 0) == 0, rep["findings"][0]["evidence"]




def test_a_narrow_bump_in_three_set_ups_is_not_read_as_outliers():
    """gen_b local_scale_defect 1313 (a tuning seed; `outlier`, confident, on main 69a6324): a bump 1.7 mm wide,
    -7.6 um, on the Y scale; the first screen set aside six of its touches (2.5-8.0 um of the generator's
    effect) in three set-ups, and the search on every row left the same six beyond the bound beside the defect.
    Named, confident, some put back; any touch still set aside is one the defect reaches by more than 1 um (2.2
    sigma of this campaign's 0.46 um noise: the generator's own effect on it, not dust; here row 26, the peak,
    -8.0 um). Fails on main 69a6324 (`outlier`). With the finer half-widths (core.causes.DEFECT_WIDTHS, session
    14) none of the bump's touches is set aside at all, so none is put back."""
    from scenarios.blind import gen_b

    log, truth = gen_b.generate("local_scale_defect", 1313)
    rep = discovered(log).to_report()
    ev = rep["findings"][0]["evidence"]
    assert rep["cause"] in truth.acceptable_causes, rep["cause"]
    assert ev["confidence"] == "named", ev
    effect = np.abs(np.asarray(truth.effect_dq_um))
    assert all(effect[r] > 1.0 for r in rep["outlier_rows"]), (rep["outlier_rows"], effect[rep["outlier_rows"]])


def test_the_narrow_bump_rule_needs_the_same_touches_set_aside_beside_the_cause():
    """Hand-built: 40 touches in two set-ups (rows 0-19, 20-39), noise 0.01, 5 on rows 10 and 30 (set aside
    before); one cause whose column is 1 on rows 9, 10, 29, 30 (a form that follows the two in part: fitted
    on every row it takes about 2.5 of each, a cut of about half, above the quarter). With the same two set
    aside beside the cause, the rule fires (two set-ups); in one set-up only, it does not. With a third touch
    (row 5) set aside beside the cause that was kept before, it does not fire: the touches set aside beside the
    cause must be among those set aside before (the two counted are the same; without that guard it fires)."""
    n = 40
    y = 0.01 * np.random.default_rng(0).standard_normal(n)
    y[[10, 30]] += 5.0
    c = np.zeros((n, 1))
    c[[9, 10, 29, 30], 0] = 1.0
    tm = Term("local_scale_defect", c, ("bump",), {}, "X")
    Qall = np.full((n, 1), 1 / np.sqrt(n))
    all_rows = np.arange(n)
    rows = np.setdiff1d(all_rows, [10, 30])
    setups = np.repeat([0, 1], n // 2)
    assert _explains_set_aside(Qall, y, all_rows, rows, [tm], setups, rows)
    assert not _explains_set_aside(Qall, y, all_rows, rows, [tm], np.zeros(n, int), rows)
    assert not _explains_set_aside(Qall, y, all_rows, rows, [tm], setups, np.setdiff1d(all_rows, [5, 10, 30]))


def test_chips_beside_a_narrow_bump_stay_outliers():
    """The same campaign with a 5 um chip (15 sigma) on one touch in each of two set-ups where the defect does not
    reach: the defect is still named and the two chips, which it does not cut, stay set aside (the touches put
    back are the bump's three only). With the finer half-widths (session 14) the bump's touches are never set
    aside: the chips are the only outliers and nothing is put back."""
    rep, truth, chips = _gen_b_defect_1047(5.0)
    assert len(chips) == 2
    assert rep["cause"] in truth.acceptable_causes, rep["cause"]
    assert rep["outlier_rows"] == sorted(chips), (rep["outlier_rows"], chips)
    assert rep["findings"][0]["evidence"].get("outliers_put_back", 0) == 0, rep["findings"][0]["evidence"]


@pytest.mark.parametrize("gen, seed", [
    # gen_a 1163 failed from session 13 (part_change on every row cut row 128 and, dropped, left it in the fit)
    # to session 16; it passes since a cause's materiality counts the touches its columns reach (s16_partchange,
    # merged in session 17; the same on OpenBLAS's SkylakeX and Haswell kernels): how that change reaches this
    # campaign was not traced
    ("gen_a", 1163),
    # gen_b 1175 failed from session 14 to 26 (a strict xfail): on the defect's finer half-widths
    # (core.causes.DEFECT_WIDTHS) a -87 um bump of 1.5 mm half-width centred 0.8 mm beside the chip of row 116
    # passed the two-positions rule at 2.4 effective positions, named local_scale_defect, ambiguous, on the grid
    # BIC chose with the chips in. It passes since session 27: a bump named beside touches set aside has the grid
    # chosen again on the kept touches (core.discover.GRID_AFTER_OUTLIERS), and there the chips alone are set aside
    ("gen_b", 1175)])
def test_chips_a_cause_on_every_row_reaches_stay_outliers(gen, seed):
    """Chips the search on every row reaches, that the rule for a bump followed in part must not take (both
    `outlier`, confident, on a3ba8ad, the generator's chips set aside). With the cut in two set-ups counted over
    any touch: gen_a outlier 1163 (chips of 5.6-13 um on two walls and the boss, two set-ups): part_change on
    every row cut two, was taken, put them back, was dropped by the rival check on its next pass and left them
    in the fit: `unexplained`, confident, extended workpiece 1.97 um against 0.24. gen_b outlier 1175: a bump
    fitted on one chip took it in whole (it left the bound; another touch went beyond it) and cut a second
    one: `local_scale_defect`. Now a touch counts only while it stays beyond the bound beside the cause, and a
    put-back whose cause is dropped is undone (the touches judged again)."""
    import importlib

    mod = importlib.import_module(f"scenarios.blind.{gen}")
    log, truth = mod.generate("outlier", seed)
    rep = discovered(log).to_report()
    assert rep["cause"] == "outlier", rep["cause"]
    assert rep["findings"][0]["evidence"]["confidence"] == "named", rep["findings"][0]["evidence"]
    assert rep["outlier_rows"] == sorted(int(r) for r in truth.outlier_rows), (rep["outlier_rows"], truth.outlier_rows)


@pytest.mark.parametrize("seed, grid_mm", [(1064, 40.0), (1007, 80.0)])
def test_a_narrow_defect_on_a_coarse_grid_is_named_where_the_generator_put_it(seed, grid_mm):
    """gen_a local_scale_defect 1064 and 1007 (tuning seeds): bumps of the Y scale 2.9 and 3.2 mm half-width
    (4.9 and 2.9 um), on baselines whose BIC chose 40 and 80 mm grids. The scan's narrowest half-width was 0.2
    grid steps (8 and 16 mm): its best trial crossed the bump's few positions with the wrong form and was
    refused (1064: held-out gain below materiality; 1007: the feature-per-set-up smooth explains more), both
    `unexplained`, confidently (this test fails on e61eefc^, before the finer half-widths: both `unexplained`). Scanned down to
    the positions' resolution (core.causes.DEFECT_WIDTHS) the defect is named first, on the generator's axis;
    its centre within a quarter of the true half-width (the scan's step between centres), its half-width and
    peak amplitude within their U95 of the generator's."""
    from scenarios.blind import gen_a

    log, truth = gen_a.generate("local_scale_defect", seed)
    rep = discovered(log).to_report()
    assert rep["baseline"]["grid_step_mm"] == grid_mm
    f = rep["findings"][0]
    assert f["cause"] == "local_scale_defect", (f["cause"], rep["rejected"])
    p, u, true = f["params"], f["params_u95"], truth.params
    assert p["axis"] == true["axis"]
    assert abs(p["centre_mm"] - true["centre_mm"]) < true["half_width_mm"] / 4, (p, true)
    assert abs(p["half_width_mm"] - true["half_width_mm"]) < u["half_width_mm"], (p, u, true)
    assert abs(p["amplitude_um"] - truth.physical["amplitude_um"]) < u["amplitude_um"], (p, u, truth.physical)



def test_defect_widths_stop_at_the_positions_resolution(monkeypatch):
    """Bad input for the scan's half-widths: a campaign whose positions along X are too sparse for the finer
    half-widths gets none below half their mean spacing (core.causes.DEFECT_MIN_WIDTH_GAPS: a bump's full
    width at least one mean spacing; twice the spacing before session 34) nor any whose bump holds fewer than
    four distinct positions, and an axis whose touches sit at one place gets no trial at all. On synthetic
    seed 0 (55 mm grid, mean spacings well below a millimetre) the half-widths below 0.2 grid steps are scanned
    (1.4 to 22 mm); with every x moved onto 40 evenly spaced places (a mean spacing of 5 mm) the four positions
    a bump needs ask for 1.5 spacings (7.5 mm): only 11 and 22 mm are scanned, as under the floor of two
    spacings; with every y at one place, no trial on Y. Gathered in threes 0.8 mm apart, 5 mm between the
    groups (a wall's touches; a mean spacing of 1.8 mm), the 2.75 mm half-width holds four positions between
    two groups and is scanned; the floor of two mean spacings (3.6 mm) dropped it (the set C misses)."""
    assert causes.DEFECT_MIN_WIDTH_GAPS == 0.5
    t, _ = S.campaign("none", 0)
    bl = baseline.planar(t, grid_step_mm=55.0)
    d = bl.data
    ws = {sc.infos[0]["half_width_m"] for sc in causes.defect_scans(bl)[0]}
    assert min(ws) < 0.2 * d.grid_step_m
    for axis in ("x", "y"):
        span, gap = causes._positions_gap(getattr(d, axis))
        assert all(w >= 0.5 * gap for w in ws)
    lo, hi = d.x.min(), d.x.max()
    sparse = dataclasses.replace(d, x=lo + np.round((d.x - lo) / (hi - lo) * 39) * (hi - lo) / 39,
                                 y=np.full(d.y.shape, d.y[0]))
    scans = causes.defect_scans(dataclasses.replace(bl, data=sparse))[0]
    gap = causes._positions_gap(sparse.x)[1]
    assert {sc.infos[0]["axis"] for sc in scans} == {"X"}
    assert {sc.infos[0]["half_width_m"] for sc in scans} == {w for w in ws if w >= 1.5 * gap}
    assert {w for w in ws if w < 1.5 * gap}  # (widths the full layout scans that the sparse one must not)
    # gathered in threes: place k of 120 at 5 mm * (k // 3) + 0.8 mm * (k % 3)
    k = np.round((d.x - lo) / (hi - lo) * 119).astype(int)
    grouped = dataclasses.replace(d, x=lo + 5e-3 * (k // 3) + 0.8e-3 * (k % 3), y=np.full(d.y.shape, d.y[0]))
    gap = causes._positions_gap(grouped.x)[1]
    assert 1.6e-3 < gap < 2.0e-3  # (not every one of the 120 places is occupied: 1.80 mm here)
    w275 = min(w for w in ws if w > 2e-3)
    assert w275 == pytest.approx(2.75e-3)
    got = {sc.infos[0]["half_width_m"] for sc in causes.defect_scans(dataclasses.replace(bl, data=grouped))[0]}
    assert w275 in got and min(ws) not in got  # (1.375 mm: three positions at most under it)
    monkeypatch.setattr(causes, "DEFECT_MIN_WIDTH_GAPS", 2.0)
    got = {sc.infos[0]["half_width_m"] for sc in causes.defect_scans(dataclasses.replace(bl, data=grouped))[0]}
    assert w275 not in got


@functools.cache
def _blind_report_once(gen: str, effect: str, seed: int) -> dict:
    import importlib

    log, _ = importlib.import_module(f"scenarios.blind.{gen}").generate(effect, seed)
    return discovered(log).to_report()


def _blind_report(gen: str, effect: str, seed: int) -> dict:
    """A blind generator's campaign discovered with the default settings, its report (a copy): discovered once
    for the module (gen_a outlier 1083 is read by two tests). For tests that change no setting."""
    return copy.deepcopy(_blind_report_once(gen, effect, int(seed)))


@pytest.mark.parametrize("gen, seed, words", [
    ("gen_a", 1083, "a gross error at that one place (outlier) does as much, and this design cannot tell them apart")])
def test_a_bump_seen_at_one_place_where_it_reaches_is_ambiguous_with_outlier(gen, seed, words):
    """Two tuning campaigns of chips (the generators' outliers) read `local_scale_defect` confidently on the finer
    half-widths (core.causes.DEFECT_WIDTHS): the bump's evidence, counted over every touch, passes the
    two-positions rule (the fitted part spreads over all touches beside the baseline), while where its own column
    reaches one position carries more than half. Counted there it is not refused (real narrow bumps touched at
    their peak and two shoulders fail it too: six gen_a defects of 1000-1099, session 14) but the finding is
    ambiguous with `outlier`, the reason said. Measured on gen_a/gen_b outlier and local_scale_defect 1000-1099
    (400 campaigns): no cause changes, these two and 7 real defects named ambiguous instead of confident. Both
    named confidently on main before (bb56e91). Session 29 (core.discover._beyond_one_place): 1083's bump reaches
    no other touch where it would move it detectably (0.25 sigma expected beyond its place), and the reason says
    the design cannot tell the two apart; 1015's was seen beyond its place (a second chip under it), the words "a
    gross error at that one place (outlier) could do as much"; since session 34 1015 reads `outlier` (below)."""
    rep = _blind_report(gen, "outlier", seed)
    f = next(f for f in rep["findings"] if f["cause"] == "local_scale_defect")
    ev = f["evidence"]
    assert ev["confidence"] == "ambiguous", ev.get("confidence_reason")
    assert "outlier" in ev["ambiguous_with"]
    assert words in ev["confidence_reason"]
    assert ev["support_units_reached"] < MIN_SUPPORT <= ev["support_units"]


def test_two_chips_under_a_bump_half_the_spacing_wide_are_outliers():
    """gen_b outlier 1015 (tuning): two chips under one bump (each seen beyond the other's place) read
    `local_scale_defect?` (ambiguous with `outlier`, then `unexplained` and `outlier`; extended workpiece 1.60 um, U95 2.56) until the
    scan's narrowest half-width came down to half the positions' mean spacing (core.causes.DEFECT_MIN_WIDTH_GAPS,
    session 34): now `outlier`, confidently, the generator's own rows set aside, no bump named, the extended
    workpiece 0.26 um (U95 0.51). (It was the tuning campaign of the words "a gross error at that one place
    (outlier) could do as much", which no campaign of this module reaches now.)"""
    from scenarios.blind import gen_b

    _, truth = gen_b.generate("outlier", 1015)
    rep = _blind_report("gen_b", "outlier", 1015)
    assert rep["cause"] == "outlier", [f["cause"] for f in rep["findings"]]
    assert rep["findings"][0]["evidence"]["confidence"] == "named", rep["findings"][0]["evidence"]
    assert "local_scale_defect" not in [f["cause"] for f in rep["findings"]]
    assert rep["outlier_rows"] == sorted(int(r) for r in truth.outlier_rows), (rep["outlier_rows"], truth.outlier_rows)


def test_a_named_cause_whose_size_is_not_determined_is_ambiguous():
    """A magnitude whose U95 is wider than its whole plausible range is reported as no value; the cause named
    beside it is at most ambiguous, the value, U95 and range said (review of s14_lsd: gen_a outlier 1083's
    refined bump, fitted at +473 um against bounds of -50..50 um, was named with no amplitude and no flag;
    the bounds check had nothing to hold). Fails on main before (no such evidence or reason)."""
    rep = _blind_report("gen_a", "outlier", 1083)
    f = next(f for f in rep["findings"] if f["cause"] == "local_scale_defect")
    ev = f["evidence"]
    assert "amplitude_um not determined" in ev["magnitude_undetermined"] and "-50..50" in ev["magnitude_undetermined"]
    # no number of the undetermined fit is printed (its value and U95 are those of a direction the design leaves
    # open: review30c's MFB Z step printed pretravel_pv = 4.46e+09 +- 7.87e+09 um; session 30)
    assert "+-" not in ev["magnitude_undetermined"] and "=" not in ev["magnitude_undetermined"]
    assert f["params"]["amplitude_um"] is None and f["params_u95"]["amplitude_um"] is None
    assert ev["confidence"] == "ambiguous" and "its size is not determined on this design" in ev["confidence_reason"]


def test_path_count_of_trials_short_of_their_columns():
    """A trial of four columns whose span beside the model has two dimensions is a chi-square process of two
    degrees of freedom, not four (session 24's review: gen_a periodic designs 1025, 1027 have trials of rank 2 and
    3 beside the model): the two orthogonal planes of test_path_count_hand_worked with two zero columns beside them
    count exactly as the planes alone (before the mend 0.73 times, the steps divided by 4 and counted at 4 dof); a
    trial that is not finite has no span and breaks no count (its eigen-decomposition raised before)."""
    from core.discover import _path_tries
    n = 12
    st = _State(np.arange(n), np.zeros((n, 0)), np.zeros(n), 1.0, n)
    planes = np.zeros((2, n, 2))
    planes[0, 0, 0] = planes[0, 1, 1] = planes[1, 2, 0] = planes[1, 3, 1] = 1.0
    padded = np.concatenate([planes, np.zeros((2, n, 2))], axis=2)
    sc2 = causes.Scan(("a", "b"), ({}, {}), "x", lambda idx: planes[np.asarray(idx)], path=True)
    sc4 = causes.Scan(("a", "b", "c", "d"), ({}, {}), "x", lambda idx: padded[np.asarray(idx)], path=True)
    two = _path_tries([sc2], st, 0.01)
    assert two > 1.5
    assert _path_tries([sc4], st, 0.01) == pytest.approx(two, rel=1e-9)
    bad = np.concatenate([planes[:1], np.full((1, n, 2), np.nan), planes[1:]])
    sc_bad = causes.Scan(("a", "b"), ({}, {}, {}), "x", lambda idx: bad[np.asarray(idx)], path=True)
    assert _path_tries([sc_bad], st, 0.01) == pytest.approx(1.0, rel=1e-9)  # no step survives the gap


def test_support_message_never_rounds_a_short_count_up_to_the_bar():
    """The support count's message: 1.986 effective positions printed "2" beside "at least 2" (blind gen_b 8306,
    session 29); it now shows the digits that put it short; other counts keep their two digits."""
    from core.discover import MIN_SUPPORT, _positions_text

    assert MIN_SUPPORT == 2.0
    assert _positions_text(1.986) == "1.99" and _positions_text(1.9996) == "1.9996"
    assert (_positions_text(1.7), _positions_text(2.4), _positions_text(15.3), _positions_text(2.0)) == \
        ("1.7", "2.4", "15", "2")
