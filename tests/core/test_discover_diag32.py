"""Session 32's second blind check: its four misses (diag32), diagnosed and pinned.

Each campaign has a strict xfail test of the issue's aim (it fails as shipped; it passes, and so fails the suite,
the day a rule mends it: gen_b stylus_bending 9702's, mended in session 33, is a plain test now) and a test pinning the mechanism's figures. Tolerances: row sets and names exactly;
studentized strengths and noise figures to 0.01 (values 0.1-11: far beyond BLAS rounding, well inside any change of
the screen or the floor). docs/discovery-studies.md, "Session 32: the second blind check's misses".

Session 33 (out33) mended 1 and 2 with :data:`core.discover.OUTLIERS_STRUCTURE_HEDGED` (``outlier``, hedged: one
column of structure, the target's time or the reversed approach, explains the rows as well as dust by BIC); their
mechanism tests pin the session-32 reading with it off, their aim tests pass.

1. gen_a part_change 9707 -> ``outlier``, confident: wall6's bow grows with time (its middle target 16 reads
   +1.10, +2.77, +5.95, +6.82 um over the four set-ups); the target's workpiece value takes their mean, and the screen
   sets aside the two early visits (rows 17, 66: strengths 8.87 and 6.25 against the bound 4.80, 1.85 and 1.30 times
   it, both beyond :data:`core.discover.OUTLIER_EVENT_MARGIN` 1.25, two events: one per set-up); what is left of
   the change is not named. :data:`core.discover.OUTLIER_CHIPS_READ_MORE` (off) sets nothing aside here and names
   ``part_change`` (p 8.5e-12, wall change 6.85 um).
2. gen_a reseat_hysteresis 9702 -> ``outlier``, confident: 45 touches read -6.2 to -7.5 um (the first after a turn); 39 are
   13 targets flagged at every visit (absorbed by their workpiece values), the other 6 on 5 targets flagged at some
   visits only: the screen's five rows are exactly those targets' odd touches (159, 167, 173, 214, 274; strengths
   8.9-11.1 against 4.81, two events). No rule built and off mends it.
3. gen_b stylus_bending 9702 -> ``probe_lobing``, confident, at 0.31 sigma: the same campaign without the effect
   reads ``none``; with its 0.17 um visible part a 4-lobe term nearly inside the baseline (best VIF 2.8, worst 2163,
   principal angle 1.2 deg; k4 5.8 +- 2.6 um) passes (p_adj 9.5e-4). :data:`core.discover.VIF_WORST_REFUSED` (off:
   24 right -> wrong on tuning) refuses it: ``stylus_bending``, hedged. Mended since session 33 (vif33) by
   :data:`core.discover.INFLATED_SIGNAL_HEDGED`: ``probe_lobing`` hedged (its aim's test passes).
4. gen_b none 9704 -> ``unexplained``, confident (lack of fit): the repeats' floor is 0.132 um (16 dof, per-set-up
   time trend; 0.152 with 24 dof plain) for a true 0.280 and a residual 0.275: a draw that low has probability
   5e-4 (3e-4 plain) under gen_b's Gaussian noise; on gen_b none 1000-1019 the floor is 0.61-1.30 of the truth.
   No rule built and off mended it; session 33's :data:`core.discover.LOF_ALONE_FLOOR_GUARD` (``"hedged"``) flags a
   lack of fit alone ``ambiguous`` (still ``unexplained``: a false alarm by the issue's count, not a confident one).
"""

import pytest

import core.discover as D
from scenarios.blind import gen_a, gen_b
from tests.discover_helpers import discovered


def _read(log):
    """(cause, confident, discovery): the report's cause, confident as the blind study scores it (the first
    finding not ``ambiguous``)."""
    d = discovered(log)
    rep = d.to_report()
    conf = not any(f["evidence"].get("confidence") == "ambiguous" for f in rep["findings"][:1])
    return rep["cause"], conf, d


def _aim(gen, effect, seed, allowed=None):
    """The issue's aim on one campaign: its cause is one of ``allowed`` (the generator's acceptable causes when
    None), or it is not confident."""
    log, tr = gen.generate(effect, seed)
    cause, conf, _ = _read(log)
    assert cause in (allowed if allowed is not None else tr.acceptable_causes) or not conf, (cause, conf)


def _finding(d, cause):
    return next(f for f in d.findings if f.cause == cause)


# 1. gen_a part_change 9707 ------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_gen_a_part_change_9707_mechanism(monkeypatch):
    """As shipped in session 32 (:data:`core.discover.OUTLIERS_STRUCTURE_HEDGED` off): confident ``outlier``."""
    monkeypatch.setattr(D, "OUTLIERS_STRUCTURE_HEDGED", False)
    log, tr = gen_a.generate("part_change", 9707)
    assert tr.params["feature"] == "wall6" and {17, 66} <= set(tr.affected_rows)
    cause, conf, d = _read(log)
    assert cause == "outlier" and conf and d.outlier_rows == (17, 66)
    se = _finding(d, "outlier").evidence["strong_events"]
    assert se["bound"] == pytest.approx(4.80, abs=0.01) and se["strong_events"] == 2
    assert se["strength"] == pytest.approx([8.87, 6.25], abs=0.01)
    # the second event passes the margin by 4 %: 6.25 against 1.25 x 4.80 = 6.00
    ratio = min(se["strength"]) / se["bound"]
    assert ratio == pytest.approx(1.30, abs=0.01) and ratio > D.OUTLIER_EVENT_MARGIN


@pytest.mark.slow
def test_gen_a_part_change_9707_not_confidently_misnamed():
    """Mended in session 33 by :data:`core.discover.OUTLIERS_STRUCTURE_HEDGED` (a strict xfail before)."""
    _aim(gen_a, "part_change", 9707, ("part_change",))


@pytest.mark.slow
def test_gen_a_part_change_9707_the_target_time_explains_the_rows(monkeypatch):
    """Session 33: wall6's middle target's time, every row kept, has a lower BIC than two free values for rows 17
    and 66 (delta -0.99 with the 2 log 2 of the two columns tried; -2.38 without): ``outlier``, hedged, the same rows
    set aside. Tolerance 0.01 on a BIC difference of ~1 in values of ~-4700: far beyond BLAS rounding. Held with
    session 36's travel column off (OUTLIER_STRUCTURE_REVERSAL_TRAVEL: a third column tried costs its log 2)."""
    monkeypatch.setattr(D, "OUTLIER_STRUCTURE_REVERSAL_TRAVEL", False)
    log, _ = gen_a.generate("part_change", 9707)
    cause, conf, d = _read(log)
    assert cause == "outlier" and not conf and d.outlier_rows == (17, 66)
    s = _finding(d, "outlier").evidence["structure"]
    assert s["explains"] and s["column"] == "time wall6-d1-p2" and s["tried"] == ["reversed approach",
                                                                                    "time wall6-d1-p2"]
    assert s["delta_bic"] == pytest.approx(-0.99, abs=0.01)


@pytest.mark.slow
def test_gen_a_part_change_9707_chips_read_more_would_name_it(monkeypatch):
    """OUTLIER_CHIPS_READ_MORE (off since session 22: two gen_b workpieces further) sets nothing aside here."""
    monkeypatch.setattr(D, "OUTLIER_CHIPS_READ_MORE", True)
    log, _ = gen_a.generate("part_change", 9707)
    cause, conf, d = _read(log)
    assert cause == "part_change" and conf and d.outlier_rows == ()


# 2. gen_a reseat_hysteresis 9702 ------------------------------------------------------------------------------------

@pytest.mark.slow
def test_gen_a_reseat_hysteresis_9702_mechanism(monkeypatch):
    """The screen's rows are exactly the odd touches of the targets the turn flags at some visits only (as shipped
    in session 32, :data:`core.discover.OUTLIERS_STRUCTURE_HEDGED` off: confident)."""
    monkeypatch.setattr(D, "OUTLIERS_STRUCTURE_HEDGED", False)
    log, tr = gen_a.generate("reseat_hysteresis", 9702)
    cause, conf, d = _read(log)
    assert cause == "outlier" and conf and d.outlier_rows == (159, 167, 173, 214, 274)
    se = _finding(d, "outlier").evidence["strong_events"]
    assert se["bound"] == pytest.approx(4.81, abs=0.01) and se["strong_events"] == 2
    assert min(se["strength"]) == pytest.approx(8.91, abs=0.01) and max(se["strength"]) == pytest.approx(11.10, abs=0.01)


@pytest.mark.slow
def test_gen_a_reseat_hysteresis_9702_not_confidently_named():
    """Mended in session 33 by :data:`core.discover.OUTLIERS_STRUCTURE_HEDGED` (a strict xfail before)."""
    _aim(gen_a, "reseat_hysteresis", 9702)


@pytest.mark.slow
def test_gen_a_reseat_hysteresis_9702_the_reversed_approach_explains_the_rows(monkeypatch):
    """Session 33: one column marking the touches whose approach reversed the move before explains the five rows
    better than five free values (delta BIC -19.1): ``outlier``, hedged, the same rows. Since session 36 the reversal
    as a travel along the approach (OUTLIER_STRUCTURE_REVERSAL_TRAVEL) is tried beside it and explains them better,
    the reading the same."""
    monkeypatch.setattr(D, "OUTLIER_STRUCTURE_REVERSAL_TRAVEL", False)
    log, _ = gen_a.generate("reseat_hysteresis", 9702)
    cause, conf, d = _read(log)
    assert cause == "outlier" and not conf and d.outlier_rows == (159, 167, 173, 214, 274)
    s = _finding(d, "outlier").evidence["structure"]
    assert s["explains"] and s["column"] == "reversed approach" and s["tried"] == ["reversed approach"]
    assert s["delta_bic"] == pytest.approx(-19.09, abs=0.01)
    monkeypatch.setattr(D, "OUTLIER_STRUCTURE_REVERSAL_TRAVEL", True)
    cause, conf, d = _read(log)
    assert cause == "outlier" and not conf and d.outlier_rows == (159, 167, 173, 214, 274)
    s = _finding(d, "outlier").evidence["structure"]
    assert s["explains"] and s["column"] == "reversed approach travel"
    assert s["tried"] == ["reversed approach", "reversed approach travel"] and s["delta_bic"] < -19.09


# 3. gen_b stylus_bending 9702 ---------------------------------------------------------------------------------------

@pytest.mark.slow
def test_gen_b_stylus_bending_9702_mechanism(monkeypatch):
    monkeypatch.setattr(D, "INFLATED_SIGNAL_HEDGED", False)  # (the reading before session 33's hedge: vif33)
    monkeypatch.setattr(D, "ALTERNATIVES_TWO_WAY", "off")  # (and before session 34's, which hedges it too: alt34)
    log, _ = gen_b.generate("stylus_bending", 9702, effect_on=False)
    assert _read(log)[0] == "none"  # the same campaign without the effect
    log, _ = gen_b.generate("stylus_bending", 9702)
    cause, conf, d = _read(log)
    assert cause == "probe_lobing" and conf
    ev = _finding(d, "probe_lobing").evidence
    assert ev["vif"] == pytest.approx(2.81, abs=0.01) and ev["max_vif"] == pytest.approx(2163, rel=0.01)
    assert ev["max_vif"] > D.Settings().vif_max > ev["vif"]
    assert ev["principal_angle_deg"] == pytest.approx(1.20, abs=0.01)


@pytest.mark.slow
def test_gen_b_stylus_bending_9702_not_confidently_misnamed():
    """Mended since session 33 (vif33, :data:`core.discover.INFLATED_SIGNAL_HEDGED`): the 4-lobe term's
    significance rests on its 4 directions beyond vif_max (its determined 4 alone F 2.3, not significant after 22
    tries; the inflated ones carry 99 % of its fitted values): ``probe_lobing`` named with doubt. Was a strict xfail
    (a confident probe_lobing); fails with the rule off."""
    _aim(gen_b, "stylus_bending", 9702, ("stylus_bending", "none"))


@pytest.mark.slow
def test_gen_b_stylus_bending_9702_worst_vif_refusal_would_hedge_it(monkeypatch):
    """VIF_WORST_REFUSED (off: 24 right -> wrong on tuning, session 32 vif32) refuses the lobing term here."""
    monkeypatch.setattr(D, "VIF_WORST_REFUSED", True)
    log, _ = gen_b.generate("stylus_bending", 9702)
    cause, conf, _ = _read(log)
    assert cause == "stylus_bending" and not conf


# 4. gen_b none 9704 -------------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_gen_b_none_9704_mechanism(monkeypatch):
    """Without the guard (:data:`core.discover.LOF_ALONE_FLOOR_GUARD` None, the reading diag32 pinned) a confident
    ``unexplained`` on the lack of fit alone; the figures are the guard's (``lack_of_fit_alone``)."""
    monkeypatch.setattr(D, "LOF_ALONE_FLOOR_GUARD", None)
    log, tr = gen_b.generate("none", 9704)
    cause, conf, d = _read(log)
    ev = _finding(d, "unexplained").evidence
    assert cause == "unexplained" and conf and ev["lack_of_fit"] and not ev["cv_gap"] and not ev["diagnosis"]
    alone = ev["lack_of_fit_alone"]
    assert not alone["softened"] and alone["dof_pe"] == 24 and alone["residual_dof"] == 116
    # the floor's odds against the fit's scatter (0.152 against 0.275 um on 24 dof): the F's own figure, 4.1e-4
    assert alone["p_floor"] == pytest.approx(4.10e-4, abs=0.01e-4) and alone["p_gap"] == pytest.approx(0.44, abs=0.01)
    n = d.noise
    assert n["method"] == "repeats" and n["repeats"]["dof"] == 16 and n["repeats"]["dof_plain"] == 24
    assert n["sigma_um"] == pytest.approx(0.132, abs=0.01) and n["repeats"]["sigma_plain_um"] == pytest.approx(0.152, abs=0.01)
    assert n["in_sample"]["sigma_um"] == pytest.approx(0.275, abs=0.01) and tr.noise_um == pytest.approx(0.280, abs=0.01)
    assert n["lack_of_fit"]["F"] == pytest.approx(3.89, abs=0.01) and n["lack_of_fit"]["p_value"] < 2e-4


@pytest.mark.slow
def test_gen_b_none_9704_no_false_alarm():
    """The aim as diag32 wrote it (``none``, or not confident): session 33's guard
    (:data:`core.discover.LOF_ALONE_FLOOR_GUARD` ``"hedged"``) flags the lack of fit alone ``ambiguous``. The report's
    cause is still ``unexplained``: issue 13's false-alarm count (cause not ``none``) still counts it."""
    _aim(gen_b, "none", 9704, ("none",))
    log, _ = gen_b.generate("none", 9704)
    cause, conf, d = _read(log)
    ev = _finding(d, "unexplained").evidence
    assert cause == "unexplained" and not conf and ev["lack_of_fit_alone"]["softened"]
    assert ev["confidence_reason"].startswith("the only evidence is the lack of fit against the repeats")
