"""Discovery's CPU, exactly (session 38, fast38): the same numbers, computed once.

- core.baseline.planar's ``designs`` cache and PLANAR_STOP_AT_FIRST (core.discover.FINER_DESIGN_REUSE): the
  finer-map check's planar call takes the first identifiable grid's design BIC's comparison built, and builds no
  grid after the one it takes;
- core.discover.ROBUST_OUTLIERS_MEMO: the outlier screen's robust start (a linear program) once for each design,
  observations and set;
- core.discover._chi2_max_mean integrates special.chdtr, what stats.chi2.cdf computes for x > 0.

Each is checked against the path it replaces (the same values to the bit, the same report byte for byte) and
against something it did not produce (a closed form, a count of designs built). Campaign: gen_a knock 1002 (BIC
takes a grid coarser than the first identifiable one, 30 mm, and the finer-map check searches that map to its end;
the robust start runs on the same design and set more than once).
"""

import dataclasses
import json

import numpy as np
import pytest
from scipy import integrate, stats

import core.baseline as B
import core.discover as D
from core import selfcal
from core.touches import from_log
from scenarios.blind import gen_a
from tests.discover_helpers import discovered


@pytest.fixture(scope="module")
def knock():
    log, _ = gen_a.generate("knock", 1002)
    return log


def _report(d) -> str:
    return json.dumps(d.to_report(), sort_keys=True, default=str)


@pytest.mark.parametrize("m,k", [(2, 1), (3, 2), (7, 4), (17, 1), (19, 12), (25, 30), (40, 7)])
def test_chi2_max_mean_is_the_chi2_cdf_integral_to_the_bit(m, k):
    old = float(integrate.quad(lambda x: 1.0 - stats.chi2.cdf(x, k) ** m, 0.0, np.inf, limit=200)[0])
    assert D._chi2_max_mean.__wrapped__(m, k) == old


@pytest.mark.parametrize("m", [1, 2, 5, 19])
def test_chi2_max_mean_known_answer_two_dof(m):
    # chi-square on 2 dof is 2 x Exp(1); the largest of m exponentials has mean H_m (harmonic number). quad's
    # default tolerances (1.5e-8 absolute and relative) bound the error: 1e-7 relative is a margin above them.
    h = sum(1.0 / i for i in range(1, m + 1))
    assert D._chi2_max_mean.__wrapped__(m, 2) == pytest.approx(2.0 * h, rel=1e-7)


def _count_designs(monkeypatch):
    n = [0]
    build = selfcal.build_design

    def counted(*a, **kw):
        n[0] += 1
        return build(*a, **kw)

    monkeypatch.setattr(selfcal, "build_design", counted)
    return n


def _same_baseline(a, b):
    assert a.info["grid_step_mm"] == b.info["grid_step_mm"]
    assert np.array_equal(a.A, b.A) and np.array_equal(a.C, b.C) and np.array_equal(a.d, b.d)
    assert a.names == b.names and np.array_equal(a.estimand, b.estimand) and a.conventions == b.conventions
    assert all(np.array_equal(x, y) for x, y in zip(a.qr[:2], b.qr[:2]))  # (the formed Q and |diag R|, to the bit)
    assert a.qr[2] is a.A and b.qr[2] is b.A  # (each factorisation names its own holder's design: orth's check)
    assert a.A is not b.A  # (no two baselines share the cached arrays)


def test_the_finer_call_takes_the_design_bic_built_and_builds_none(monkeypatch, knock):
    t = from_log(knock)
    steps = D.Settings().grid_steps_mm
    n = _count_designs(monkeypatch)
    designs = {}
    first = B.planar(t, None, steps, select_grid=True, designs=designs)
    assert n[0] == len(steps)  # (BIC compared every grid)
    # the first identifiable grid kept: 30 mm here (22 mm leaves a combination unseen), finer than BIC's choice
    assert designs["first"][2][0] == 30.0 < first.info["grid_step_mm"]
    n[0] = 0
    again = dataclasses.replace(t)  # (another holder of the same values, as discover's copy of the touches)
    reused = B.planar(again, None, steps, select_grid=False, designs=designs)
    assert n[0] == 0
    fresh = B.planar(again, None, steps, select_grid=False)
    assert n[0] == 2  # (22 and 30 mm; PLANAR_STOP_AT_FIRST: the grids after the first identifiable one not built)
    _same_baseline(reused, fresh)
    monkeypatch.setattr(B, "PLANAR_STOP_AT_FIRST", False)
    n[0] = 0
    _same_baseline(B.planar(again, None, steps, select_grid=False), fresh)
    assert n[0] == len(steps)


def test_other_touches_do_not_take_the_cache(monkeypatch, knock):
    t = from_log(knock)
    steps = D.Settings().grid_steps_mm
    designs = {}
    B.planar(t, None, steps, designs=designs)
    p = t.p_R.copy()
    p[5, 0] += 1e-6  # (one touch's measurement 1 um off: another observation, the same nominal geometry)
    other = dataclasses.replace(t, p_R=p)
    assert not B._same_touches(t, other) and B._same_touches(t, dataclasses.replace(t, p_R=t.p_R.copy()))
    n = _count_designs(monkeypatch)
    B.planar(other, None, steps, select_grid=False, designs=designs)
    assert n[0] == 2  # (22 and 30 mm built again, not taken from the cache)
    n[0] = 0
    B.planar(t, None, (30.0, 40.0), select_grid=False, designs=designs)  # (other grids: another key)
    assert n[0] == 1
    # each call keeps its own first identifiable design in the cache (the last one made): asked again, it is taken
    assert designs["first"][1] is t and designs["first"][0][0] == ((30.0, None), (40.0, None))
    n[0] = 0
    B.planar(other, None, steps, select_grid=False, designs=designs)
    B.planar(other, None, steps, select_grid=False, designs=designs)
    assert n[0] == 2


def test_the_report_is_the_same_with_the_reuse_and_the_memo_off(monkeypatch, knock):
    calls = []
    run = D._robust_outliers_of

    def counted(*a, **kw):
        calls.append(1)
        return run(*a, **kw)

    monkeypatch.setattr(D, "_robust_outliers_of", counted)
    checked = []
    check = D._finer_map_check
    monkeypatch.setattr(D, "_finer_map_check", lambda *a, **kw: checked.append(1) or check(*a, **kw))
    D._ROBUST.clear()
    on = discovered(knock)
    n_on = len(calls)
    monkeypatch.setattr(D, "FINER_DESIGN_REUSE", False)
    monkeypatch.setattr(B, "PLANAR_STOP_AT_FIRST", False)
    monkeypatch.setattr(D, "ROBUST_OUTLIERS_MEMO", False)
    calls.clear()
    off = discovered(knock)
    assert checked == [1, 1]  # (the finer-map check ran in both)
    assert 0 < n_on < len(calls)  # (the memo answered some screens, and the robust start ran)
    assert _report(on) == _report(off)
