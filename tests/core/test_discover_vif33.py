"""Session 33 (vif33): a term nearly inside the baseline, and the shift its inflated directions carry.

- :data:`core.discover.INFLATED_SIGNAL_HEDGED`: a named cause whose significance rests on its directions inflated
  beyond ``vif_max`` (its determined directions alone not significant, the inflated ones carrying most of its fitted
  values) is named with doubt (gen_b stylus_bending 9702: ``probe_lobing`` read confidently from a 0.17 um bending
  through four directions inflated up to 2163 times);
- :data:`core.discover.HEDGED_SHIFT_READING` ``"determined"``: the shift carried for such a cause is the one between
  its term fitted on every direction and on its determined ones only, not the whole term's.

Known answers on a synthetic term nearly inside a baseline (:func:`core.discover._inflated_split`), and on the
campaigns that pin the rules. docs/discovery-studies.md, "Session 33: a term nearly inside the baseline".
"""

import numpy as np
import pytest

import core.discover as D
from core.units import UM
from scenarios.blind import gen_a, gen_b
from scenarios.hidden import blind_outcome
from tests.discover_helpers import discovered


@pytest.fixture(autouse=True)
def _extended_workpiece_offered(monkeypatch):
    """These tests examine the extended fit's workpiece (its shift, its U95) on campaigns whose extended U95 grows
    beyond 3 times the baseline's, which core.discover.WORKPIECE_U95_GROWTH_WITHHELD (on since session 35) withholds
    from the report: held off here, so that the estimate beneath it is what they check, as they were written to."""
    import core.discover as D

    monkeypatch.setattr(D, "WORKPIECE_U95_GROWTH_WITHHELD", False)


def _frame(n=200, seed=3):
    """Orthonormal ``q1, q2`` (the model's basis ``Q``), ``u, v, w`` orthonormal and orthogonal to it."""
    rng = np.random.default_rng(seed)
    B = np.linalg.qr(rng.standard_normal((n, 5)))[0]
    return B[:, :2], B[:, 2], B[:, 3], B[:, 4]


def _split_case(eps=0.05, alpha=2.0, beta=0.3, gamma=1.5, scale=(3.0, 0.5)):
    """A cause ``E = [s1 u, s2 (q1 + eps v)]`` beside ``Q``: its second column lies ``atan(eps)`` from the model
    (inflation ``(1 + eps^2) / eps^2``), the residual ``r = alpha u + beta v + gamma w`` (um)."""
    Q, u, v, w = _frame()
    E = np.column_stack([scale[0] * u, scale[1] * (Q[:, 0] + eps * v)])
    r = (alpha * u + beta * v + gamma * w) * UM
    return Q, E, r, (Q, u, v, w)


def test_inflated_split_known_answer():
    """Exact figures: the inflated direction explains ``beta^2``, the determined one ``alpha^2``; the coefficient
    along the inflated one is ``beta sqrt(1 + eps^2) / eps`` on the normalised column, so the term's fitted values
    are ``alpha u + beta (q1 / eps + v)``; the determined direction's F test is ``alpha^2 / (gamma^2 / (dof - 2))``
    (the residual left by both directions is ``gamma w``). Tolerance 1e-9 relative: a few dozen rounded operations
    on unit vectors."""
    eps, alpha, beta, gamma = 0.05, 2.0, 0.3, 1.5
    Q, E, r, (_, u, v, w) = _split_case(eps, alpha, beta, gamma)
    n, dof = len(r), len(r) - 2
    sp = D._inflated_split(Q, E, r, dof, vif_max=100.0)
    assert (sp["k_inflated"], sp["k_determined"]) == (1, 1)
    s2 = (alpha ** 2 + beta ** 2 + gamma ** 2) / dof  # (the chi-square's sigma: the model's residual, r r / dof)
    assert sp["chi2_inflated"] == pytest.approx(beta ** 2 / s2, rel=1e-9)
    assert sp["ss_share_inflated"] == pytest.approx(beta ** 2 / (alpha ** 2 + beta ** 2), rel=1e-9)
    f_inf = beta * np.sqrt(1.0 + eps ** -2)  # |beta (q1 / eps + v)|
    f_all = np.sqrt(alpha ** 2 + f_inf ** 2)  # (u is orthogonal to q1 and v)
    assert sp["magnitude_share_inflated"] == pytest.approx(f_inf / f_all, rel=1e-9)
    assert sp["rms_um"] == pytest.approx(f_all / np.sqrt(n), rel=1e-9)
    assert sp["rms_determined_um"] == pytest.approx(alpha / np.sqrt(n), rel=1e-9)
    F = alpha ** 2 / (gamma ** 2 / (dof - 2))
    assert sp["F_determined"] == pytest.approx(F, rel=1e-9)
    from scipy import stats
    assert sp["p_determined"] == pytest.approx(stats.f.sf(F, 1, dof - 2), rel=1e-6, abs=0)
    # the columns' scale does not matter (normalised), nor their sign
    sp2 = D._inflated_split(Q, E * np.array([-7.0, 0.01]), r, dof, vif_max=100.0)
    for k in ("chi2_inflated", "magnitude_share_inflated", "F_determined", "rms_um"):
        assert sp2[k] == pytest.approx(sp[k], rel=1e-9), k


def test_inflated_split_signal_along_the_sliver():
    """A residual along the sliver alone (``alpha = 0``): the determined direction sees nothing (F 0, p 1), the
    inflated one carries every fitted value, ``1 / eps`` times the signal it was read from."""
    eps, beta = 0.02, 0.5
    Q, E, r, _ = _split_case(eps, 0.0, beta, 1.0)
    sp = D._inflated_split(Q, E, r, len(r) - 2, vif_max=100.0)
    assert sp["F_determined"] == pytest.approx(0.0, abs=1e-12) and sp["p_determined"] == pytest.approx(1.0)
    assert sp["magnitude_share_inflated"] == pytest.approx(1.0, rel=1e-9)
    assert sp["rms_um"] * np.sqrt(len(r)) == pytest.approx(beta * np.sqrt(1 + eps ** -2), rel=1e-9)


def test_inflated_split_none_where_nothing_is_inflated_or_everything_is():
    """None: no direction beyond vif_max (eps large), every kept direction beyond it (the cause confounded), no
    column, or no residual."""
    Q, E, r, (_, u, v, w) = _split_case(eps=0.5)  # inflation 5
    assert D._inflated_split(Q, E, r, len(r) - 2, vif_max=100.0) is None
    Q, E, r, _ = _split_case(eps=0.05)
    assert D._inflated_split(Q, E[:, 1:], r, len(r) - 2, vif_max=100.0) is None  # its one direction at 401
    assert D._inflated_split(Q, E[:, :0], r, len(r) - 2, vif_max=100.0) is None
    assert D._inflated_split(Q, E, 0.0 * r, len(r) - 2, vif_max=100.0) is None
    # vif_max above the sliver's inflation: nothing beyond it
    assert D._inflated_split(Q, E, r, len(r) - 2, vif_max=1e3) is None


def test_determined_drop_leaves_the_sliver_out():
    """``_determined(..., drop=True)`` leaves the direction beyond vif_max out whatever VIF_DROP_BEYOND_MAX says
    (the reading HEDGED_SHIFT_READING "determined" refits); ``drop=False`` keeps it; None follows the constant."""
    Q, E, r, (_, u, v, w) = _split_case(eps=0.05)
    M, vif, worst, ang, weak, beyond = D._determined(Q, E, 100.0, drop=True)
    assert M.shape == (2, 1) and beyond == 1 and weak == 1 and vif == pytest.approx(1.0) and worst == vif
    # the kept combination is the column along u (the first), scaled back to the raw column
    assert np.allclose(np.abs(E @ M)[:, 0], np.abs(u), atol=1e-12)
    M, vif, worst, *_ = D._determined(Q, E, 100.0, drop=False)
    assert M.shape == (2, 2) and worst == pytest.approx((1 + 0.05 ** 2) / 0.05 ** 2, rel=1e-9)
    assert D._determined(Q, E, 100.0)[0].shape[1] == (1 if D.VIF_DROP_BEYOND_MAX else 2)


def _report_8907():
    log, _ = gen_a.generate("thermal_bending", 8907)
    return discovered(log).to_report()


@pytest.mark.slow
def test_8907_determined_reading_is_the_drop_beyond_max_model_known_answer(monkeypatch):
    """Known answer: 8907's extended model is the baseline + part_change on every row, so beside the final model
    the part_change's determined directions are those VIF_DROP_BEYOND_MAX keeps at its adoption (the same basis,
    rows and columns): the reading ``"determined"`` sets beside it is VIF_DROP_BEYOND_MAX's extended workpiece, and
    the shift carried is ``D = extended - extended_drop`` per target: ``U95^2 - U95_none^2 = D^2`` (``D D^T / 4`` at
    k = 2). Tolerance: relative 1e-7 of the U95 squared (two fits of the same model by different routes: the
    eigenvectors' signs and the solver's order of sums), absolute 1e-9 um^2."""
    monkeypatch.setattr(D, "HEDGED_SHIFT_CARRIED", None)
    r0 = _report_8907()  # no shift carried
    monkeypatch.setattr(D, "VIF_DROP_BEYOND_MAX", True)
    rd = _report_8907()  # the term on its determined directions
    monkeypatch.setattr(D, "VIF_DROP_BEYOND_MAX", False)
    monkeypatch.setattr(D, "HEDGED_SHIFT_CARRIED", "inflated_any")
    monkeypatch.setattr(D, "HEDGED_SHIFT_READING", "determined")
    r1 = _report_8907()
    causes = ["unexplained", "part_change"]
    assert [f["cause"] for f in rd["findings"]] == [f["cause"] for f in r1["findings"]] == causes
    assert r0["outlier_rows"] == rd["outlier_rows"] == r1["outlier_rows"] == []
    ev = r1["findings"][1]["evidence"]
    fig = ev["workpiece_shift_determined"]
    assert "workpiece_shift_without" not in ev and "_determined_columns" not in ev
    assert fig["carried_in_u95"] and fig["alternative"] == "part_change on its determined directions", fig
    assert any("its term fitted on its determined directions only moves the workpiece" in c for c in r1["conventions"])
    for w0, wd, w1 in zip(r0["workpiece"], rd["workpiece"], r1["workpiece"]):
        assert w1["extended_um"] == w0["extended_um"] and w1["baseline_um"] == w0["baseline_um"]
        d = w0["extended_um"] - wd["extended_um"]
        lhs = w1["extended_u95_um"] ** 2 - w0["extended_u95_um"] ** 2
        assert lhs == pytest.approx(d ** 2, rel=1e-7, abs=1e-9), w0["target"]


@pytest.mark.slow
@pytest.mark.parametrize("gen, effect, seed", [(gen_a, "thermal_bending", 8907), (gen_b, "signal_latency", 9309)])
def test_determined_reading_holds_8907_and_9309(monkeypatch, gen, effect, seed):
    """The two blind misses HEDGED_SHIFT_CARRIED mended (session 32) stay mended with the sharper reading: name,
    findings and estimate unchanged, the check held by the U95 (8907: 6.909 <= 1.053 + 6.884; 9309: 4.798 <=
    0.221 + 5.052), the U95 below the whole term's (6.937, 5.190)."""
    monkeypatch.setattr(D, "HEDGED_SHIFT_READING", "without")
    o0 = blind_outcome(gen, effect, seed, generator=gen.__name__.rsplit(".", 1)[-1])
    monkeypatch.setattr(D, "HEDGED_SHIFT_READING", "determined")
    o1 = blind_outcome(gen, effect, seed, generator=gen.__name__.rsplit(".", 1)[-1])
    assert (o1.cause, o1.confident, o1.findings) == (o0.cause, o0.confident, o0.findings)
    assert o1.wp_ext_um == o0.wp_ext_um and o1.wp_base_um == o0.wp_base_um
    assert o1.wp_ext_um <= o1.wp_base_um + o1.wp_u95_um, o1
    assert o1.wp_u95_um < o0.wp_u95_um


@pytest.mark.slow
def test_gen_b_stylus_bending_9702_inflated_signal_hedged(monkeypatch):
    """Set B's miss (diag32): ``probe_lobing`` read confidently from a 0.17 um bending. With INFLATED_SIGNAL_HEDGED
    its significance is found to rest on its 4 directions beyond vif_max (of 8): the determined four alone are not
    significant after its 22 tries, and the inflated ones carry 99 % of its 4.65 um RMS of fitted values (0.18 um on
    the determined ones); named with doubt (the aim: no confident wrong name), name and estimate unchanged."""
    log, _ = gen_b.generate("stylus_bending", 9702)
    monkeypatch.setattr(D, "ALTERNATIVES_TWO_WAY", "off")  # (session 34's test hedges it too: this pins vif33's own)
    monkeypatch.setattr(D, "INFLATED_SIGNAL_HEDGED", False)
    r0 = discovered(log).to_report()
    monkeypatch.setattr(D, "INFLATED_SIGNAL_HEDGED", True)
    r1 = discovered(log).to_report()
    f0, f1 = r0["findings"][0], r1["findings"][0]
    assert f0["cause"] == f1["cause"] == "probe_lobing"
    assert f0["evidence"]["confidence"] == "named" and "inflated_signal" not in f0["evidence"]
    assert f1["evidence"]["confidence"] == "ambiguous"
    assert f1["params"] == f0["params"] and f1["params_u95"] == f0["params_u95"] and r1["workpiece"] == r0["workpiece"]
    sp = f1["evidence"]["inflated_signal"]
    assert (sp["k_inflated"], sp["k_determined"]) == (4, 4)
    assert sp["p_determined_adjusted"] >= D.Settings().alpha_family > f1["evidence"]["p_adjusted"]
    assert sp["magnitude_share_inflated"] > 0.99
    assert sp["rms_um"] == pytest.approx(4.65, abs=0.01) and sp["rms_determined_um"] == pytest.approx(0.18, abs=0.01)
    assert "its significance rests on 4 of its directions inflated beyond vif_max" in \
        f1["evidence"]["confidence_reason"]


def test_inflated_signal_hedge_needs_both_conditions(monkeypatch):
    """The hedge's two conditions on the synthetic sliver: a determined direction that is significant by itself, or
    an inflated part that carries under INFLATED_MAGNITUDE_SHARE of the fitted values, leaves the cause alone
    (the figures the rule reads, :func:`core.discover._inflated_split`)."""
    Q, E, r, _ = _split_case(eps=0.05, alpha=2.0, beta=0.3, gamma=1.5)
    sp = D._inflated_split(Q, E, r, len(r) - 2, vif_max=100.0)
    assert sp["p_determined"] < 1e-6  # alpha = 2 um along u against 1.5 um of noise: seen where determined
    Q, E, r, _ = _split_case(eps=0.05, alpha=0.1, beta=0.3, gamma=1.5)
    sp = D._inflated_split(Q, E, r, len(r) - 2, vif_max=100.0)
    assert sp["p_determined"] > 0.1 and sp["magnitude_share_inflated"] > D.INFLATED_MAGNITUDE_SHARE
    Q, E, r, _ = _split_case(eps=0.2, alpha=0.1, beta=0.001, gamma=1.5)  # inflation 26: nothing beyond vif_max
    assert D._inflated_split(Q, E, r, len(r) - 2, vif_max=100.0) is None


def test_rules_as_shipped():
    """Both on since session 33 (vif33: measured on the tuning seeds, docs/discovery-studies.md "Session 33: a term nearly
    inside the baseline"); HEDGED_SHIFT_CARRIED as session 32 left it."""
    assert D.INFLATED_SIGNAL_HEDGED is True and D.INFLATED_MAGNITUDE_SHARE == 0.5
    assert D.HEDGED_SHIFT_READING == "determined" and D.HEDGED_SHIFT_CARRIED == "inflated_any"


@pytest.mark.slow
def test_gen_b_stylus_bending_9702_aim_fails_without_the_hedge(monkeypatch):
    """The aim's test (diag32's, a strict xfail until session 33) fails with INFLATED_SIGNAL_HEDGED off (and session
    34's ALTERNATIVES_TWO_WAY off, which hedges it on its own: both readings below)."""
    monkeypatch.setattr(D, "INFLATED_SIGNAL_HEDGED", False)
    monkeypatch.setattr(D, "ALTERNATIVES_TWO_WAY", "off")
    log, _ = gen_b.generate("stylus_bending", 9702)
    rep = discovered(log).to_report()
    assert rep["cause"] == "probe_lobing" and rep["findings"][0]["evidence"]["confidence"] == "named"
    monkeypatch.setattr(D, "ALTERNATIVES_TWO_WAY", "add")
    rep = discovered(log).to_report()
    assert rep["cause"] == "probe_lobing" and rep["findings"][0]["evidence"]["confidence"] == "ambiguous"
    assert "beyond a smooth term in" in rep["findings"][0]["evidence"]["confidence_reason"]
