"""Session 34 (alt34): step 8's alternatives gate as a two-way test, and an outlier finding's structure doubt
carried back to the named causes.

:func:`core.discover._two_way` (:data:`core.discover.ALTERNATIVES_TWO_WAY`): the named cause's columns beyond model +
a smooth alternative, and the smooth's beyond model + cause, two nested F tests in the union of both models.
Known answers on a made-up design (a cause that is there beside a smooth that reproduces most of it; a smooth's
structure that the cause's columns only follow), the F statistics against explicit least squares, and the gate's
verdicts through :func:`core.discover._alternatives`. :func:`core.discover._rejudged_beside_outlier_structure`
(:data:`core.discover.OUTLIER_STRUCTURE_REJUDGED`) is checked on a made-up model and on a tuning campaign it mends
(docs/discovery-studies.md, "Session 34: the alternatives gate as a two-way test, and an outlier finding's doubt carried
back (alt34)").
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

import core.discover as D
from core.diagnosis import new_basis
from core.discover import Settings

UM = 1e-6
N, SIGMA = 240, 0.3 * UM


def _design(seed):
    """A baseline of 12 group offsets, a cause's column (a ramp within each group, a drift) and a smooth's five
    columns (a cubic B-spline-like basis in a second covariate ``u`` that follows the ramp in part).
    Returns (Q baseline basis, E (N, 1) cause, B (N, 5) smooth, rng)."""
    rng = np.random.default_rng(seed)
    g = np.repeat(np.arange(12), N // 12)
    A = (g[:, None] == np.arange(12)[None, :]).astype(float)
    Q, _ = np.linalg.qr(A)
    ramp = np.tile(np.linspace(-1, 1, N // 12), 12)
    u = ramp + 0.6 * rng.normal(size=N)  # the smooth's covariate follows the cause's in part
    B = np.column_stack([u ** k for k in range(1, 6)])
    return Q, ramp[:, None], B, rng


def _state(Q, y):
    return D._state(Q, y, np.arange(N), [])


def _f_direct(y, X0, X1):
    """Nested F test of X1's columns beyond X0 (explicit least squares): (F, p)."""
    def rss(X):
        c, *_ = np.linalg.lstsq(X, y, rcond=None)
        e = y - X @ c
        return float(e @ e), np.linalg.matrix_rank(X)
    r0, p0 = rss(X0)
    r1, p1 = rss(np.hstack([X0, X1]))
    k, dof = p1 - p0, len(y) - p1
    F = ((r0 - r1) / k) / (r1 / dof)
    return F, float(stats.f.sf(F, k, dof))


@pytest.mark.parametrize("seed", range(4))
def test_a_cause_that_is_there_stands_beyond_the_smooth(seed):
    """y = the drift (2 um at its ends, 6.7 sigma) + noise: the cause stands beyond the smooth of ``u`` (which
    reproduces part of it), and the smooth adds nothing beyond the cause (p_adjusted above 0.01 on these seeds)."""
    Q, E, B, rng = _design(seed)
    y = 2.0 * UM * E[:, 0] + rng.normal(0, SIGMA, N)
    so = _state(Q, y)
    U = new_basis(so.Q, B)
    tw = D._two_way(so, U, B, SimpleNamespace(columns=E, tries=1.0), SIGMA, Settings())["two_way"]
    assert tw["cause_stands"]
    assert tw["p_adjusted_cause_beyond"] < 1e-10  # measured 1e-70 and below: far from the decision
    assert tw["p_alternative_beyond"] > 0.01


@pytest.mark.parametrize("seed", range(4))
def test_the_smooths_structure_followed_by_the_cause_does_not_stand(seed):
    """y = a cubic in ``u`` (the smooth's own structure) + noise: the drift's column follows it (``u`` follows the
    ramp) but explains nothing material and significant beyond the smooth; the smooth stands beyond the cause."""
    Q, E, B, rng = _design(seed)
    y = 1.5 * UM * (B[:, 0] - 0.3 * B[:, 2]) + rng.normal(0, SIGMA, N)
    so = _state(Q, y)
    U = new_basis(so.Q, B)
    tw = D._two_way(so, U, B, SimpleNamespace(columns=E, tries=1.0), SIGMA, Settings())["two_way"]
    assert not tw["cause_stands"]
    assert tw["p_alternative_beyond"] < 1e-10


def test_f_tests_against_explicit_least_squares():
    """Both p-values against explicit nested fits: baseline + smooth against baseline + smooth + cause (times the
    cause's tries, 3 here), and baseline + cause against baseline + cause + smooth. The noise's sigma enters only
    the materiality, not the F test (its denominator is the larger model's residual mean square)."""
    Q, E, B, rng = _design(7)
    y = 0.4 * UM * E[:, 0] + 0.5 * UM * B[:, 1] + rng.normal(0, SIGMA, N)
    so = _state(Q, y)
    U = new_basis(so.Q, B)
    tw = D._two_way(so, U, B, SimpleNamespace(columns=E, tries=3.0), SIGMA, Settings())["two_way"]
    _, p_c = _f_direct(y, np.hstack([Q, B]), E)
    _, p_a = _f_direct(y, np.hstack([Q, E]), B)
    assert tw["p_adjusted_cause_beyond"] == pytest.approx(min(1.0, 3 * p_c), rel=1e-6, abs=0)
    assert tw["p_alternative_beyond"] == pytest.approx(p_a, rel=1e-6, abs=0)


def _alternatives_of(y, Q, E, B, mode, monkeypatch, sigma=SIGMA):
    """:func:`core.discover._alternatives` on the made-up design with one covariate ``u`` of family ``other`` (the
    cause's family ``time``), :data:`ALTERNATIVES_TWO_WAY` at ``mode``."""
    monkeypatch.setattr(D, "ALTERNATIVES_TWO_WAY", mode)
    so = _state(Q, y)
    tm = SimpleNamespace(columns=E, tries=1.0, covariate="t")
    covs = {"t": SimpleNamespace(name="t", family="time"), "u": SimpleNamespace(name="u", family="other")}
    bl = SimpleNamespace(covariate=covs.get, covariates=list(covs.values()))
    sig = D._signal(tm, so, sigma)
    return D._alternatives(bl, tm, so, sigma, Settings(), {"u": B, "t": E}, sig)


def _near_miss(seed):
    """A near miss of the two ratios (set C's gen_c clamp_creep 6704: the feature's smooth reproducing 0.787 of the
    signal and explaining 1.05 times as much): ``u`` the ramp plus scatter 0.4, the data 0.3 of the ramp and 0.7 of
    ``u`` (1 um), noise 0.5 um. The drift's column holds the ramp; the smooth of ``u`` holds nearly everything."""
    rng = np.random.default_rng(seed)
    g = np.repeat(np.arange(12), N // 12)
    Q, _ = np.linalg.qr((g[:, None] == np.arange(12)[None, :]).astype(float))
    ramp = np.tile(np.linspace(-1, 1, N // 12), 12)
    u = ramp + 0.4 * rng.normal(size=N)
    y = UM * (0.3 * ramp + 0.7 * u) + rng.normal(0, 0.5 * UM, N)
    return Q, ramp[:, None], np.column_stack([u ** k for k in range(1, 6)]), y


@pytest.mark.parametrize("seed", range(6))
def test_the_gate_hedges_by_the_test_where_the_ratios_miss(seed, monkeypatch):
    """The near miss: the ratios do not hedge (overlap 0.70-0.73 < 0.8, measured on these seeds) and the smooth does
    not explain materially more (ratio 1.13-1.25 < 1 / 0.8): ``"off"`` leaves the name confident. The cause explains
    beyond the smooth 0.9-3.6 um^2 against a materiality of 5.6 (p 1e-4 to 0.02): it does not stand, and ``"add"``
    and ``"replace"`` hedge it; the figures say which test did."""
    Q, E, B, y = _near_miss(seed)
    off = _alternatives_of(y, Q, E, B, "off", monkeypatch, sigma=0.5 * UM)
    assert len(off) == 1 and "two_way" not in off[0]
    assert not off[0]["indistinguishable"] and not off[0]["explains_more"]
    add = _alternatives_of(y, Q, E, B, "add", monkeypatch, sigma=0.5 * UM)
    tw = add[0]["two_way"]
    assert add[0]["indistinguishable"] and not tw["cause_stands"] and tw["alternatives_tried"] == 1
    assert not tw["by_ratios"]
    assert _alternatives_of(y, Q, E, B, "replace", monkeypatch, sigma=0.5 * UM)[0]["indistinguishable"]


def test_replace_keeps_a_cause_that_stands_beside_a_smooth_reproducing_it(monkeypatch):
    """A smooth that holds the cause's whole column (``u`` is the ramp itself here, no scatter) reproduces its signal
    and explains as much: the ratios hedge it, and so do ``"add"`` and ``"replace"`` (the cause explains nothing
    beyond a smooth that spans it: nested, not stronger)."""
    Q, E, B, rng = _design(2)
    B = np.column_stack([E[:, 0] ** k for k in range(1, 6)])
    y = 2.0 * UM * E[:, 0] + rng.normal(0, SIGMA, N)
    for mode in ("off", "add", "replace"):
        a = _alternatives_of(y, Q, E, B, mode, monkeypatch)
        assert a[0]["indistinguishable"], mode


def test_rejudged_beside_outlier_structure_hedges_a_cause_the_column_holds(monkeypatch):
    """A made-up model: every row's reading steps by -4 um after a reversed approach (the column), the screen set
    aside its four largest rows, and a 'cause' whose column follows the reversals in part was named confident on
    the rest. With the rows back and the column beside it the cause explains nothing: hedged, with the column's
    reading returned for the workpiece; a cause of its own (a drift, present) stands."""
    Q, E, B, rng = _design(3)
    rev = (rng.random(N) < 0.25).astype(float)
    cause_col = (rev + 0.5 * rng.normal(size=N))[:, None]
    drift = E
    y = -4.0 * UM * rev + 2.0 * UM * drift[:, 0] + rng.normal(0, SIGMA, N)
    outliers = np.argsort(np.abs(y - Q @ (Q.T @ y)))[-4:]
    tm_c = SimpleNamespace(cause="c_drift", columns=cause_col, tries=1.0, unnamed=False, penalty=None)
    tm_d = SimpleNamespace(cause="thermal_drift", columns=drift, tries=1.0, unnamed=False, penalty=None)
    fo = D.Finding("outlier", {"structure": {"column": "reversed approach", "explains": True}}, {}, {}, 0.3, "data")
    findings = [D.Finding(t.cause, {"confidence": "named"}, {}, {}, 0.3, "data") for t in (tm_c, tm_d)] + [fo]
    monkeypatch.setattr(D, "outlier_structure_columns", lambda bl, out: {"reversed approach": rev})
    got = D._rejudged_beside_outlier_structure(None, findings, [tm_c, tm_d], Q, y, np.arange(N), outliers, SIGMA,
                                               Settings())
    assert list(got) == ["c_drift"] and got["c_drift"][0] == "reversed approach in its place"
    assert findings[0].evidence["confidence"] == "ambiguous"
    assert "reversed approach" in findings[0].evidence["confidence_reason"]
    assert findings[1].evidence["confidence"] == "named"
    assert findings[1].evidence["outlier_structure_rejudged"]["stands"]


# set C's two misses the rules were built for (spent blind seeds, read as the brief names them; the rules were judged
# on tuning seeds: docs/discovery-studies.md, "Session 34: the alternatives gate as a two-way test, and an outlier finding's
# doubt carried back (alt34)"). Each read with the rule off (the reading before) and on: the second shows that the
# rule, not something else, makes the difference.

def _outcome(gen, effect, seed):
    from scenarios import hidden
    from scenarios.blind import gen_a, gen_c
    return hidden.blind_outcome({"gen_a": gen_a, "gen_c": gen_c}[gen], effect, seed, generator=gen)


def test_gen_a_reseat_hysteresis_10100_c_drift_hedged_and_its_workpiece_held(monkeypatch):
    """Four touches after a reversed approach set aside, `c_drift` adopted on the rest: with the rows back and the
    reversed approach beside it, c_drift explains 1.48 um^2 (p_adj 1): hedged, and the workpiece read with the column
    in its place carries the shift (extended 5.254 um against baseline 2.96, U95 0.744 -> 5.25)."""
    monkeypatch.setattr(D, "OUTLIER_STRUCTURE_REJUDGED", False)
    before = _outcome("gen_a", "reseat_hysteresis", 10100)
    assert before.cause == "c_drift" and before.confident
    assert before.wp_ext_um > before.wp_base_um + before.wp_u95_um  # the blind check's failure
    monkeypatch.setattr(D, "OUTLIER_STRUCTURE_REJUDGED", True)
    after = _outcome("gen_a", "reseat_hysteresis", 10100)
    assert after.cause == "c_drift" and not after.confident
    assert after.wp_ext_um <= after.wp_base_um + after.wp_u95_um
    assert after.wp_ext_um == pytest.approx(before.wp_ext_um, rel=1e-9)  # the estimate stays; its U95 says the doubt


def test_gen_c_clamp_creep_6704_thermal_drift_hedged_by_the_two_way_test(monkeypatch):
    """thermal_drift beside a feature smooth reproducing 0.787 of its signal and explaining 1.05 times as much (both
    ratios missed): beyond the smooth it explains 8.0 um^2 against a materiality of 10.4 (p_adj 1.5e-5): hedged."""
    monkeypatch.setattr(D, "ALTERNATIVES_TWO_WAY", "off")
    before = _outcome("gen_c", "clamp_creep", 6704)
    assert before.cause == "thermal_drift" and before.confident
    monkeypatch.setattr(D, "ALTERNATIVES_TWO_WAY", "add")
    after = _outcome("gen_c", "clamp_creep", 6704)
    assert after.cause == "thermal_drift" and not after.confident
    assert after.wp_ext_um == pytest.approx(before.wp_ext_um, rel=1e-9)
