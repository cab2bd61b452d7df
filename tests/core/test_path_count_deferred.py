"""Session 26: the path count put off where a bound from the scans' sizes shows the candidate significant.

:func:`core.discover._judge_trial` raises a path scan's Bonferroni count to
:func:`core.discover._path_tries`' (Davies' bound on the trials' path) before
its significance test. Where :func:`core.discover._path_count_below` (every
step at its largest, pi / 2) shows the candidate significant at any count the
path can give, the count is made only once a later test reads it
(:data:`core.discover.PATH_COUNT_DEFERRED`): the same counts, the same
decisions, and the demo's first-round periodic scan, refused by its family,
is never counted.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from core import causes
from core import discover as D

_PATH_TRIES = D._path_tries  # (the count itself, whatever a test patches in its place)


def _orthogonal_scan(n: int, T: int, k: int):
    """A path scan of ``T`` trials of ``k`` columns, each trial's columns unit vectors on rows of their own: every
    step between consecutive trials is pi / 2 beside a model on other rows (the bound's longest path)."""
    def build(idx):
        idx = np.asarray(idx)
        C = np.zeros((len(idx), n, k))
        for a, t in enumerate(idx):
            C[a, k * t + np.arange(k), np.arange(k)] = 1.0
        return C
    return causes.Scan(tuple("abcd"[:k]), tuple({} for _ in range(T)), "x", build, path=True)


def _state(n: int, T: int, k: int, r: int = 5):
    rng = np.random.default_rng(0)
    Q = np.zeros((n, r))
    Q[k * T:] = np.linalg.qr(rng.standard_normal((n - k * T, r)))[0]  # the model on the rows no trial touches
    return D._State(np.arange(n), Q, np.zeros(n), 1.0, n)


def _threshold(scans, rows, level):
    """The least count the bound says the path's count is below (bisection on its log)."""
    lo, hi = 1.0, 1e12  # (a count is at least the scans' number: never below 1)
    assert D._path_count_below(scans, rows, level, hi) and not D._path_count_below(scans, rows, level, lo)
    for _ in range(200):
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if D._path_count_below(scans, rows, level, mid) else (mid, hi)
    return hi


@pytest.mark.parametrize("k", [1, 4])
def test_bound_is_the_count_of_the_longest_path(k):
    """Known answer: trials whose consecutive spans are orthogonal trace steps of pi / 2 each, the bound's path; its
    threshold is the count :func:`_path_tries` makes of them (to brentq's 1e-6 and the bisection's), and never
    below it."""
    n, T = 400, 60
    sc, st = _orthogonal_scan(n, T, k), _state(n, T, k)
    for level in (1e-3, 2.8e-4, 1e-6):
        count = D._path_tries([sc], st, level)
        assert count > 10  # (a path, not the scan's one trial)
        got = _threshold([sc], n, level)
        assert got >= count * (1 - 2e-6)
        assert got == pytest.approx(count, rel=1e-5)


def test_bound_above_the_demos_counts():
    """On the demo's periodic scans beside its baseline the bound's threshold is above the count (1,073 at the level
    the engine asks); beyond PATH_ARC_ROWS rows it bounds nothing, and no count is below the scans' number."""
    from scenarios.bench.discover import demo_campaign
    from core import baseline as bl_mod, selfcal
    from core.discover import Settings
    from core.lsq import orth_of

    t = demo_campaign()
    bl = bl_mod.planar(t, None, Settings().grid_steps_mm, yaw=selfcal.yaw_for_chain(None), extra={})
    scans = next(c for c in causes.for_kind(bl.kind) if c.name == "periodic_axis_error").scans(bl)[0]
    Q = orth_of(bl.A, qr=bl.qr)
    st = D._State(np.arange(bl.n), Q, np.zeros(bl.n), 1.0, bl.n)
    level = 0.01 / 36
    count = D._path_tries(scans, st, level)
    assert 1000 < count < 1200
    got = _threshold(scans, bl.n, level)
    assert count < got < 10 * count  # (3,251 against 1,073: 3.0 times)
    assert not D._path_count_below(scans, D.PATH_ARC_ROWS + 1, level, 1e12)
    assert D._path_count_below(scans, bl.n, level, np.inf)  # (a p-value of zero: no count reaches it)
    assert not D._path_count_below(scans, bl.n, level, 0.0)
    assert not D._path_count_below(scans, bl.n, level, 2.0)  # (two scans: a count is at least 2)


def _demo_report(monkeypatch, deferred):
    from scenarios.bench.discover import demo_campaign

    monkeypatch.setattr(D, "PATH_COUNT_DEFERRED", deferred)
    calls = []
    orig = _PATH_TRIES

    def counted(scans, st, level):
        calls.append(st.Q.shape[1])
        return orig(scans, st, level)

    monkeypatch.setattr(D, "_path_tries", counted)
    D._PATH_CACHE.clear()
    D._PATH_PRODUCTS.clear()
    rep = D.discover(demo_campaign()).to_report()
    return json.dumps(rep, sort_keys=True, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)), calls


def test_demo_counts_once_and_reports_the_same(monkeypatch):
    """The demo's discover: the count put off is the first round's (the periodic scan refused by its family), the
    second round's is made; the report is the same bytes as with every count made before the test."""
    on, calls_on = _demo_report(monkeypatch, True)
    off, calls_off = _demo_report(monkeypatch, False)
    assert calls_off == [145, 149]  # beside the baseline, then beside it and the lobing's four directions
    assert calls_on == [149]  # (fails with the counts made before the test: [145, 149])
    assert on == off
    tries = [f["evidence"]["tries"] for f in json.loads(on)["findings"] if f["cause"] == "periodic_axis_error"]
    assert tries and tries[0] > 1000  # the count made is read


def test_floor_recheck_takes_step_fives_tests(monkeypatch):
    """A report that would read ``none`` at an inflated repeats' floor is judged again at the residuals' floor
    (:func:`core.discover._none_at_the_residual_floor`) with step 5's tests of the same model taken (only their
    materiality judged again): gen_a reseat_hysteresis 1000 (session 25: ``none`` -> ``unexplained``) reads the same
    finding, number for number, as with every covariate tested again."""
    from core.touches import from_log
    from scenarios.blind import gen_a

    orig = D._none_at_the_residual_floor
    calls = []

    def both(bl, st, rep, rows, settings, bases=None, known=()):
        a = orig(bl, st, rep, rows, settings, bases, known=known)
        b = orig(bl, st, rep, rows, settings, bases)
        calls.append((len(known), a, b))
        return a

    monkeypatch.setattr(D, "_none_at_the_residual_floor", both)
    # one search: the finer-map check (session 27) would search this unexplained reading again on the 22 mm map
    # (its reading not none there, the first one kept), a second call that is not this report's
    monkeypatch.setattr(D, "FINER_MAP_CHECK", False)
    log = gen_a.generate("reseat_hysteresis", 1000)[0]
    rep = D.discover(from_log(log), chain=log.meta.get("kinematic_chain")).to_report()
    assert [f["cause"] for f in rep["findings"]] == ["unexplained"]
    assert len(calls) == 1
    n_known, a, b = calls[0]
    assert n_known > 5  # (fails with nothing taken: 0)
    dump = lambda f: json.dumps(dataclasses.asdict(f), sort_keys=True, default=str)
    assert a is not None and dump(a) == dump(b)


@pytest.mark.parametrize("gen,effect,seed", [("demo", "", 0), ("gen_a", "part_change", 1000),
                                             ("gen_b", "part_change", 1001)])
def test_not_significant_at_once_is_the_judges_answer(monkeypatch, gen, effect, seed):
    """:data:`core.discover.NOT_SIGNIFICANT_AT_ONCE`: where every trial's p times the count is 1 or more,
    :func:`core.discover._evaluate` answers at once; each such answer equals the one it gives with the time forms
    chosen and the best trial judged (the rule off), and it answers so on these campaigns (the demo's part_change
    in each of its rounds; fails with the rule out: no answer without a trial judged)."""
    import sys
    sys.path.insert(0, "tests/core/data/discover_identity")
    import make

    orig, judge = D._evaluate, D._judge_trial
    shortcut, judged = [], []

    def counted(*a, **k):
        judged.append(1)
        return judge(*a, **k)

    monkeypatch.setattr(D, "_judge_trial", counted)

    def both(*a, **k):
        judged.clear()
        on = orig(*a, **k)
        if not judged and "no columns" not in on.get("reason", ""):  # answered at once (no trial judged)
            monkeypatch.setattr(D, "NOT_SIGNIFICANT_AT_ONCE", False)
            try:
                off = orig(*a, **k)
            finally:
                monkeypatch.setattr(D, "NOT_SIGNIFICANT_AT_ONCE", True)
            assert off == on
            shortcut.append(a[0].name)
        return on

    monkeypatch.setattr(D, "_evaluate", both)
    make.report_of(make.campaign_log(gen, effect, seed))
    assert shortcut
    if gen == "demo":
        assert shortcut.count("part_change") == 3


def test_not_significant_at_once_skips_the_time_forms(monkeypatch):
    """The demo's part_change is refused without its time forms chosen (fails with the rule out: three choices, one a
    round) and the report is the same bytes either way."""
    calls = []
    orig = D._time_forms_chosen

    def counted(owns, *a, **k):
        calls.append(len(owns))
        return orig(owns, *a, **k)

    monkeypatch.setattr(D, "_time_forms_chosen", counted)
    on, _ = _demo_report(monkeypatch, True)
    n_on = len(calls)
    monkeypatch.setattr(D, "NOT_SIGNIFICANT_AT_ONCE", False)
    off, _ = _demo_report(monkeypatch, True)
    assert len(calls) - n_on - n_on >= 3  # the rule off: at least part_change's three choices more
    assert on == off
