"""A warm-up's time constant on an ISO 230-2 test: its estimate, its interval, and where the test cannot tell it.

Review27 fault 2 (session 27): on a 0.96 h test (truth 1200 s) discover said 962 +- 190 s on three seeds of six,
its U95 missing the truth; on the shipped 525 s sample (recipe 1200 s) 223 +- 190 s. Three causes, each a rule
here: the scan's coarse shortlist never tested the four longest constants (``core.causes.WARM_UP_EXHAUSTIVE``),
the refinement stopped at its +-25 % window's edge (``core.discover.REFINE_OVER_RANGE``), and the U95 was the
delta method's of a sum of squares far from quadratic, given as a value even where no upper end exists
(the warm-up's ``profile`` and ``core.discover.ONE_SIDED_AT_BOUND``). The campaigns are written in
``warmup_iso_synth`` apart from core.causes' columns.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

import core.causes as causes_mod
import core.discover as D
from core.baseline import positioning, positioning_from_log
from core.discover import discover_baseline
from core.positioning import read_positioning_log

from warmup_iso_synth import warm_up_test

SAMPLE = os.path.join(os.path.dirname(__file__), "..", "..", "scenarios", "data", "positioning-sample.csv")


def _warm_up_finding(bl):
    rep = discover_baseline(bl).to_report()
    f = [f for f in rep["findings"] if f["cause"] == "warm_up"]
    assert f, [(f["cause"], f["evidence"].get("text")) for f in rep["findings"]]
    return f[0]


def _ls_optimum(bl) -> float:
    """The least-squares time constant by brute force, written here: a mean per target and direction plus
    ``(a + s x) exp(-(t - t0) / T)`` fitted by ``lstsq`` at every T of a fine grid (0.2 % steps), the best T."""
    d = bl.data
    key = np.round(d.x * 1e7).astype(np.int64) * 2 + (np.asarray(d.direction) > 0)
    G = (key[:, None] == np.unique(key)[None, :]).astype(float)
    x = d.x - 0.5 * (d.x.min() + d.x.max())
    t = d.t_s - d.t_s.min()
    T = np.geomspace(0.05, 2.0, 1850) * np.ptp(d.t_s)
    rss = []
    for v in T:
        e = np.exp(-t / v)
        A = np.column_stack([G, e, x * e])
        c, *_ = np.linalg.lstsq(A, bl.y, rcond=None)
        rss.append(np.sum((bl.y - A @ c) ** 2))
    return float(T[int(np.argmin(rss))])


@pytest.mark.parametrize("seed, frac, amp", [(1101, 0.35, 3.5), (1102, 0.35, 3.5), (1103, 0.35, 3.5),
                                            (1201, 0.9, 10.0), (1203, 0.9, 10.0)])
def test_time_constant_is_the_least_squares_optimum(seed, frac, amp):
    """Known answer: the reported time constant is the least-squares one a brute-force fit finds, to 0.5 % (the
    brute force's grid step 0.2 %, the refinement's tolerance 0.001 %). A warm-up slower than the scan reaches
    (0.9 of the test, 10 um: the optimum 3121 s, 2681 s) was stopped at the +-25 % window's edge, 2222 s, without
    REFINE_OVER_RANGE; the profile's interval holds the value."""
    bl, span = warm_up_test(seed, frac * 3418.35, amp_um=amp)
    f = _warm_up_finding(bl)
    v = f["params"]["time_constant_s"]
    assert v == pytest.approx(_ls_optimum(bl), rel=5e-3)
    lo, hi = f["evidence"]["magnitude_intervals"]["time_constant_s"]
    assert lo < v < hi


@pytest.mark.parametrize("frac", [0.35, 0.5])
def test_profile_interval_covers_the_truth_over_seeds(frac):
    """Truth -> noise -> estimate over 60 seeds: the interval (the profile's, ``magnitude_intervals``) holds the
    true time constant at its stated level. At 95.45 % nominal 60 draws miss 2.7 on average; 53 or more covered
    (7 misses or fewer) fails a true 95.45 % with probability 0.8 %. Before (delta method, window-stopped value)
    the same draws at half the test's duration covered about half (101 of 199 over seeds 1000-1199); measured now
    over those 200 seeds: 190 of 200 at 0.35, 192 of 200 at 0.5."""
    covered, n = 0, 60
    for seed in range(2000, 2000 + n):
        bl, span = warm_up_test(seed, 1.0)
        tau = frac * span
        bl, _ = warm_up_test(seed, tau)
        f = _warm_up_finding(bl)
        ev = f["evidence"]
        one = (ev.get("one_sided") or {}).get("time_constant_s")
        if one is not None:  # (a one-sided statement: true where it holds the truth)
            covered += tau >= one.get("at_least", -np.inf) and tau <= one.get("at_most", np.inf)
            continue
        lo, hi = ev["magnitude_intervals"]["time_constant_s"]
        assert lo <= f["params"]["time_constant_s"] <= hi
        covered += lo <= tau <= hi
    assert covered >= 53, covered


def test_scan_tests_every_time_constant(monkeypatch):
    """The scan's chosen trial (before refinement) is the grid's exact best. The coarse shortlist scored 1125 s
    (the best) below the eight shorter constants: its column is mostly a constant the per-target means hold."""
    seen = []
    real = D._refine

    def spy(cause, bl, info, st, rows):
        if cause.name == "warm_up":
            seen.append(info["tau_s"])
        return real(cause, bl, info, st, rows)

    monkeypatch.setattr(D, "_refine", spy)
    bl, span = warm_up_test(13, 1200.0)
    _warm_up_finding(bl)
    grid = np.geomspace(span / 20, span / 2, 12)
    d = bl.data
    t = d.t_s - d.t_s.min()
    key = np.round(d.x * 1e7).astype(np.int64) * 2 + (np.asarray(d.direction) > 0)
    G = (key[:, None] == np.unique(key)[None, :]).astype(float)
    x = d.x - 0.5 * (d.x.min() + d.x.max())
    rss = [np.sum((bl.y - (A := np.column_stack([G, np.exp(-t / v), x * np.exp(-t / v)]))
                   @ np.linalg.lstsq(A, bl.y, rcond=None)[0]) ** 2) for v in grid]
    assert seen and seen[0] == pytest.approx(grid[int(np.argmin(rss))], rel=1e-12), (seen, grid)


def test_short_test_gives_a_lower_bound_not_a_value():
    """The shipped 525 s sample (its recipe: warm-up 1200 s, scenarios/positioning_sample.py): the profile's set
    reaches the longest time constant the range holds (twice the test): ``time_constant_s >= X``, no value, no
    U95, the bound below the truth; the CLI prints the bound."""
    from scenarios.cli.discover import summary_lines

    log = read_positioning_log(SAMPLE)
    rep = discover_baseline(positioning_from_log(log)).to_report()
    f = [f for f in rep["findings"] if f["cause"] == "warm_up"][0]
    assert f["params"]["time_constant_s"] is None and f["params_u95"]["time_constant_s"] is None
    lo = f["evidence"]["one_sided"]["time_constant_s"]["at_least"]
    assert 0 < lo <= 1200.0
    assert f["evidence"]["confidence"] != "confident"
    line = [s for s in summary_lines(rep, "positioning") if s.startswith("finding")][0]
    assert f"time_constant_s >= {lo:.3g} (not determined)" in line


def test_warm_up_range_profile_and_bad_input(monkeypatch):
    """The range and the profile's grid span a twentieth to twice the test; a test without a time span has no
    warm-up scan, and a range that is not positive and increasing leaves the scan's trial as it is."""
    bl, _ = warm_up_test(1, 600.0)
    lo, hi = causes_mod.warm_up_range(bl)["tau_s"]
    assert lo == pytest.approx(np.ptp(bl.data.t_s) * causes_mod.WARM_UP_TAU_MIN_SPANS)
    assert hi == pytest.approx(np.ptp(bl.data.t_s) * causes_mod.WARM_UP_TAU_MAX_SPANS)
    g = causes_mod.warm_up_profile({"tau_s": 500.0}, bl)["tau_s"][0]
    assert g[0] == pytest.approx(lo) and g[-1] == pytest.approx(hi) and g.size == causes_mod.WARM_UP_PROFILE_POINTS
    d = bl.data
    flat = positioning(d.x, d.direction, d.cycle + 1, bl.y, np.zeros_like(d.t_s))
    assert causes_mod.warm_up_scans(flat) == ([], 1.0)
    cause = [c for c in causes_mod.REGISTRY if c.name == "warm_up"][0]
    for rng in ((0.0, 100.0), (500.0, 400.0), (np.nan, 100.0)):
        assert D._refine_bounded(cause, bl, {"tau_s": 321.0}, "tau_s", rng, None, None) == 321.0
