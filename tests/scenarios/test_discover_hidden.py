"""Discovery judged on campaigns it has never seen (issue 13 item 7).

Every generator hides effects somewhere discovery cannot look at:

- ``hidden``: the simulator (scenarios/hidden.py): effects in the Pinocchio
  chain, the probe model or the artefact, never added to the log;
- ``gen_a``, ``gen_b``, ``gen_c``: blind generators written apart from sim/ and
  from this engine and from each other (scenarios/blind/). Only their interface is used here
  (``generate(effect, seed) -> (log, Truth)``, ``effects()`` and the Truth's
  acceptable causes, noise, visibility and workpiece), never their code, so
  these tests cannot be tuned to them.

Each runs one campaign per effect here (the whole module stays near a
minute on a busy 2-core machine; gen_c's 15 campaigns at seed 0, one per
effect as the others', add about 8 s of CPU, 0.55 s each); ``vmt bench``
(scenarios/bench/discover_study.py) runs ten per effect and prints the same
matrices. The
confusion matrix (effect x reported cause), the rates with their exact
binomial (Clopper-Pearson) 95 % intervals and the gauge-free workpiece error
of baseline and extended model are printed, and the aims asserted:

- false alarms on effect-free campaigns at most 5 %;
- catalogue causes named (an acceptable cause reported) in at least 95 % of
  the campaigns where the effect keeps at least one noise sigma per touch
  after the baseline has absorbed what it can;
- out-of-catalogue effects ``unexplained`` or acceptably named in at least
  80 %, and never confidently misnamed (a wrong catalogue cause without an
  ambiguity flag);
- the extended workpiece never worse than the baseline's beyond its U95.

"Visible" is measured against this engine's own baseline: the effect's part
outside the baseline's column space (the truth carries the effect per
touch), RMS over the touches it acts on, in noise sigmas. What lies inside
that space the baseline absorbs exactly and no residual test can see (the
study lists such effects apart, with their angle to the space).

Aims not met (stated, not hidden): at these seeds no out-of-catalogue
effect is confidently misnamed any more (gen_a reseat_hysteresis 0 read
`outlier` confidently until its outliers' history was asked: ambiguous now,
:data:`NOW_AMBIGUOUS`); gen_b's
out-of-catalogue effects are all ``unexplained`` or named right (4 of 4:
its fixture slip, named c_drift before the slip rival, now is), so its
floor went. The test asserts the known misnaming as a ceiling
(:data:`KNOWN_MISNAMED`): a new one fails, a fixed one passes and should
be removed from it. The catalogue aim holds at these seeds on the blind
generators and on the simulator (its part change at 1000 read
lobing_per_setup, ambiguous, when its :data:`KNOWN_MISSED` entry was written;
it reads part_change on the engine of session 35, and the entry went), but
not over the bench's ten
seeds per effect (docs/discovery.md gives those figures with their intervals).
"""

import importlib
import importlib.util

import numpy as np
import pytest

from scenarios.hidden import HIDDEN_CAUSES, Outcome, blind_outcome, catalogue_names, format_study, hidden_outcome, summarize
from tests.discover_helpers import discovered

SEEDS = {"hidden": (1000,), "gen_a": (0,), "gen_b": (0,), "gen_c": (0,)}
#: Aim for out-of-catalogue effects (unexplained or acceptably named).
OOC_AIM = 0.80
#: Measured at SEEDS where below the aim: the rate these seeds give (k / n).
OOC_FLOOR: dict = {}
#: Out-of-catalogue effects confidently misnamed at SEEDS (aim: none): (effect, cause).
KNOWN_MISNAMED: dict = {}
#: Visible catalogue effects missed at SEEDS where the rate falls below the aim: (effect, cause). Empty since
#: session 35: the simulator's part change at 1000 (1.09 sigma), which read lobing_per_setup (ambiguous) since the
#: folds decide on the column space, reads part_change on the current engine (audit35 D2: its entry was dead).
KNOWN_MISSED: dict = {}


def _blind(name):
    try:
        if importlib.util.find_spec(f"scenarios.blind.{name}") is None:
            return None
    except ModuleNotFoundError:
        return None
    return importlib.import_module(f"scenarios.blind.{name}")


#: Blind outcomes by (generator, effect, seed), shared by the study and the single-campaign tests of this module
#: (an Outcome is frozen; blind_outcome is deterministic in its arguments): gen_a reseat_hysteresis 0 is both
#: in the study and in NOW_AMBIGUOUS, and was generated and discovered twice.
_BLIND_OUTCOMES: dict = {}


def _blind_outcome_once(mod, gen, effect, seed):
    key = (gen, effect, int(seed))
    if key not in _BLIND_OUTCOMES:
        _BLIND_OUTCOMES[key] = blind_outcome(mod, effect, seed, generator=gen)
    return _BLIND_OUTCOMES[key]


def _blind_case(gen, effect, seed):
    """One blind generator's campaign, discovered and scored (skipped when the generator is absent)."""
    mod = _blind(gen)
    if mod is None:
        pytest.skip(f"blind generator {gen} not present")
    return _blind_outcome_once(mod, gen, effect, seed)


GENERATORS = ["hidden"] + [g for g in ("gen_a", "gen_b", "gen_c") if _blind(g) is not None]


def _effect_free_once(hidden_campaign):
    """``hidden_campaign`` simulating each effect-free campaign (seed, options) once.

    Every hidden outcome of a seed compares its campaign with the effect-free
    campaign of that seed (``hidden_effect_um``), so the study of one seed ran
    the same deterministic simulation once per effect (12 times). The log is
    read, never changed, by its users (``from_log``, ``discover``).
    """
    kept = {}

    def once(causes=("none",), seed=0, **kw):
        if tuple(causes) != ("none",):
            return hidden_campaign(causes, seed, **kw)
        key = (int(seed), tuple(sorted(kw.items())))
        if key not in kept:
            kept[key] = hidden_campaign(causes, seed, **kw)
        return kept[key]

    return once


@pytest.fixture(scope="module")
def studies():
    import scenarios.hidden as H

    out = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(H, "hidden_campaign", _effect_free_once(H.hidden_campaign))
        for g in GENERATORS:
            if g == "hidden":
                out[g] = [hidden_outcome(e, s) for e in HIDDEN_CAUSES for s in SEEDS[g]]
            else:
                mod = _blind(g)
                out[g] = [_blind_outcome_once(mod, g, e, s) for e in mod.effects() for s in SEEDS[g]]
    return out


def test_print_the_matrices(studies, capsys):
    with capsys.disabled():
        for g, outs in studies.items():
            print("\n" + format_study(outs, f"discovery on {g}: {len(SEEDS[g])} campaign(s) per effect"))
    assert all(len(o) for o in studies.values())


@pytest.mark.parametrize("gen", GENERATORS)
def test_false_alarms_at_most_5_percent(studies, gen):
    s = summarize(studies[gen])["false_alarm"]
    assert s["n"] == 0 or s["rate"] <= 0.05, s


@pytest.mark.parametrize("gen", GENERATORS)
def test_catalogue_causes_named(studies, gen):
    s = summarize(studies[gen])["catalogue"]
    cat = catalogue_names()
    missed = [(o.effect, o.cause, round(o.visible_sigmas, 2)) for o in studies[gen]
              if o.visible_sigmas >= 1 and o.cause not in o.acceptable and o.effect in cat]
    assert s["rate"] >= 0.95 or {m[:2] for m in missed} <= KNOWN_MISSED.get(gen, set()), (s, missed)


@pytest.mark.parametrize("gen", GENERATORS)
def test_out_of_catalogue_unexplained_or_named(studies, gen):
    """Aim 80 %; where these seeds measure less (OOC_FLOOR) that figure is asserted, with its interval."""
    s = summarize(studies[gen])["out_of_catalogue"]
    if s["n"] == 0:
        assert gen == "hidden"  # the simulator hides no out-of-catalogue effect; the blind generators do
        return
    wrong = [(o.effect, o.cause) for o in studies[gen] if o.effect not in catalogue_names()
             and o.acceptable != ("none",) and o.cause not in o.acceptable + ("unexplained",)]
    assert s["rate"] >= min(OOC_AIM, OOC_FLOOR.get(gen, OOC_AIM)) - 1e-12, (s, wrong)


@pytest.mark.parametrize("gen", GENERATORS)
def test_out_of_catalogue_never_confidently_misnamed_beyond_the_known(studies, gen):
    """Aim: never. The known misnamings at SEEDS are listed; any other one fails."""
    cat = catalogue_names()
    bad = {(o.effect, o.cause) for o in studies[gen] if o.acceptable != ("none",) and o.effect not in cat
           and o.cause in cat and o.cause not in o.acceptable and o.confident}
    assert bad <= KNOWN_MISNAMED.get(gen, set()), bad
    assert summarize(studies[gen])["confident_misnamed"]["k"] == len(bad)


def test_an_effect_outside_the_catalogue_with_a_catalogue_reading_is_scored_outside():
    """gen_a's thermal_bending (a wall bending with the heat) may be read ``thermal_drift`` or ``unexplained``.
    Until session 18 the study scored it as a catalogue effect because a catalogue name was among its
    readings, so a confident ``c_drift`` on it was a catalogue miss and never a confident misnaming. It is
    scored outside the catalogue: named right or ``unexplained`` counts, a confident wrong name counts in
    ``confident_misnamed``, an ambiguous one does not; a catalogue effect confidently read as another cause
    counts in ``confident_misnamed_catalogue``."""
    acc = ("unexplained", "thermal_drift")
    outs = [Outcome("g", "thermal_bending", 0, acc, "c_drift", ("c_drift",), True, 2.0, 0.3, 0.3, 0.3, 0.3, 0.1),
            Outcome("g", "thermal_bending", 1, acc, "c_drift", ("c_drift",), False, 2.0, 0.3, 0.3, 0.3, 0.3, 0.1),
            Outcome("g", "thermal_bending", 2, acc, "thermal_drift", ("thermal_drift",), True, 2.0, 0.3, 0.3, 0.3,
                    0.3, 0.1),
            Outcome("g", "c_drift", 3, ("c_drift",), "part_change", ("part_change",), True, 2.0, 0.3, 0.3, 0.3,
                    0.3, 0.1)]
    s = summarize(outs)
    assert (s["catalogue"]["k"], s["catalogue"]["n"]) == (0, 1)
    assert (s["out_of_catalogue"]["k"], s["out_of_catalogue"]["n"]) == (1, 3)
    assert (s["confident_misnamed"]["k"], s["confident_misnamed"]["n"]) == (1, 3)
    assert (s["confident_misnamed_catalogue"]["k"], s["confident_misnamed_catalogue"]["n"]) == (1, 1)


#: The largest factor by which the extended workpiece's U95 may exceed the baseline's (``Outcome.wp_u95_um`` over
#: ``wp_u95_base_um``, both RMS over the targets outside the part's gauge) in the check below: without a bound a U95
#: that grows with the damage always passes "never worse than the baseline beyond its U95". Session 35 (earn35): of
#: 256 tuning campaigns (gen_a, gen_b, gen_c) with an extension and both workpieces reported, one exceeds 3 (gen_a
#: feed_latency 1009, x4.75, its workpiece 13.6 um from the truth against the baseline's 4.96); the next are x2.85
#: (gen_c speed_pretravel 11, whose extension mends the workpiece 1.04 -> 0.65 um) and x2.25 (gen_a feed_latency
#: 1003, 3.49 -> 0.47 um); 5 exceed x2, 28 x1.5. The same factor as core.discover.WORKPIECE_U95_GROWTH_MAX
#: (docs/discovery-studies.md, "Session 35: an extended workpiece offered only when earned").
U95_GROWTH_MAX = 3.0
#: Campaigns at SEEDS whose extended U95 grows beyond :data:`U95_GROWTH_MAX` (a ceiling, as :data:`KNOWN_MISNAMED`: a
#: new one fails, a mended one passes and should be removed): gen_a knock 0, an unnamed smooth in ``feature`` adopted
#: at a held-out RMS ratio of x0.92 (95 %: 0.33-2.58), its workpiece 1.90 um from the truth against the baseline's
#: 0.99, its U95 5.5 times the baseline's; it goes with core.discover.WORKPIECE_U95_GROWTH_WITHHELD or
#: SMOOTH_WORKPIECE_EARNED on (the extended workpiece is then not offered:
#: :func:`test_an_extension_that_has_not_earned_it_does_not_move_the_workpiece`). Empty since session 35 switched
#: WORKPIECE_U95_GROWTH_WITHHELD on (knock 0's extended workpiece is withheld, so it has no extended U95 here).
KNOWN_U95_GROWN: dict = {}


@pytest.mark.parametrize("gen", GENERATORS)
def test_extended_workpiece_never_worse_beyond_its_u95(studies, gen):
    s = summarize(studies[gen])["workpiece_ok"]
    bad = [(o.effect, round(o.wp_base_um, 3), round(o.wp_ext_um, 3), round(o.wp_u95_um, 3)) for o in studies[gen]
           if np.isfinite(o.wp_ext_um) and not o.wp_ext_um <= o.wp_base_um + o.wp_u95_um]
    assert s["k"] == s["n"], bad
    # ... and its U95 not grown beyond U95_GROWTH_MAX times the baseline's (a U95 that grows with the damage passes
    # the first check whatever the damage)
    grown = {o.effect: round(o.wp_u95_um / o.wp_u95_base_um, 2) for o in studies[gen]
             if np.isfinite(o.wp_ext_um) and o.wp_u95_base_um > 0 and o.wp_u95_um > U95_GROWTH_MAX * o.wp_u95_base_um}
    assert set(grown) <= KNOWN_U95_GROWN.get(gen, set()), grown


@pytest.mark.parametrize("rule", [pytest.param(None, marks=pytest.mark.xfail(
    strict=True, reason="both rules off: the smooth's extended workpiece is offered")),
    "SMOOTH_WORKPIECE_EARNED", "WORKPIECE_U95_GROWTH_WITHHELD"])
def test_an_extension_that_has_not_earned_it_does_not_move_the_workpiece(monkeypatch, rule):
    """gen_a knock 0 (audit35 F4): an unnamed smooth in ``feature`` adopted on the point estimate of its held-out
    gain (1.19 um^2 against materiality 0.015), whose interval reaches "no gain": held-out RMS x0.92, 95 %
    0.33-2.58. Its extended workpiece is 1.90 um from the truth against the baseline's 0.99, its U95 (RMS outside
    the part's gauge) 10.35 um against 1.87 (5.5 times; U95 max 55.3 um against 5.6 in the gauge). With either rule of
    core.discover (SMOOTH_WORKPIECE_EARNED: the smooth's own held-out gain interval reaches 1;
    WORKPIECE_U95_GROWTH_WITHHELD: the U95 beyond WORKPIECE_U95_GROWTH_MAX = 3 times the baseline's) the finding, the
    smooth and the diagnosis stay; the extended workpiece is not offered (null per target, the fit's own under
    ``extended_fit_um``), the baseline's is the estimate, the reason is in the JSON and the summary. With both off
    the first assertion on the workpiece fails (strict xfail)."""
    import core.discover as D
    from scenarios.cli.discover import summary_lines

    mod = _blind("gen_a")
    if mod is None:
        pytest.skip("blind generator gen_a not present")
    # what the rules withhold, against the truth: the extended estimate is the worse one, its U95 grown, with both
    # off (the study's outcome while both are off, as they ship: kept for the module, so fetched before a constant
    # is set; made apart with both set off where one ships on)
    rules = ("SMOOTH_WORKPIECE_EARNED", "WORKPIECE_U95_GROWTH_WITHHELD")
    if any(getattr(D, r) for r in rules):
        for r in rules:
            monkeypatch.setattr(D, r, False)
        off = blind_outcome(mod, "knock", 0, generator="gen_a")
    else:
        off = _blind_case("gen_a", "knock", 0)
    assert off.wp_ext_um > 1.5 * off.wp_base_um, (off.wp_base_um, off.wp_ext_um)
    assert off.wp_u95_um > 5 * off.wp_u95_base_um, (off.wp_u95_base_um, off.wp_u95_um)
    for r in rules:
        monkeypatch.setattr(D, r, r == rule)
    log, _ = mod.generate("knock", 0)
    rep = discovered(log).to_report()
    assert rep["cause"] == "unexplained" and rep["extended"]["model"].endswith("unnamed smooth in feature")
    iv = rep["gain"]["cv_rms_ratio_95"]
    assert iv is not None and iv[1] >= 1.0, iv  # the extension's held-out gain may be none
    wp = rep["workpiece"]
    assert all(w["extended_um"] is None and w["extended_u95_um"] is None for w in wp)
    assert all(w["baseline_um"] is not None and w["extended_fit_um"] is not None for w in wp)
    no = rep["workpiece_not_offered"]
    assert no["smooth"]["covariate"] == "feature"
    # the smooth is the whole extension here: its own interval (beside no named cause, on the final rows) is the
    # report's gain interval (the baseline's held-out sums, computed apart), to rounding
    assert no["smooth"]["cv_rms_ratio_95"] == pytest.approx(iv, rel=1e-9)
    line = next(x for x in summary_lines(rep) if x.startswith("workpiece"))
    assert "extended estimate not offered" in line, line
    if rule == "SMOOTH_WORKPIECE_EARNED":
        assert no["rule"] == "smooth_gain_interval" and "95 %: 0.33-2.58" in line, (no, line)
    else:
        # the engine's gauge-free U95 is the harness's (computed apart, from the truth's targets), to rounding
        g = no["u95_rms_gauge_free_um"]
        assert no["rule"] == "u95_growth" and "beyond 3" in line, (no, line)
        assert (g["extended"], g["baseline"]) == pytest.approx((off.wp_u95_um, off.wp_u95_base_um), rel=1e-6)


def _outcome(base, ext, u95, identifiable=True):
    return Outcome("g", "e", 0, ("unexplained",), "unexplained", ("unexplained",), True, 2.0, 0.3,
                   base, ext, u95, 0.1, identifiable=identifiable)


def test_workpiece_check_counts_every_reported_extension():
    """Known answers: an extended workpiece reported without a U95 fails the check.

    The case of gen_b fixture_slip 301 before the smooth's gauge: baseline
    0.26 um, extended 0.79 um, no U95 (design the generator calls
    unidentifiable); it used to be left out of the check.
    """
    nan = float("nan")
    outs = [_outcome(0.26, 0.79, nan, identifiable=False),  # reported, no U95: fails
            _outcome(0.26, 0.79, 0.40),  # 0.79 > 0.66: fails
            _outcome(0.26, 0.79, 0.96, identifiable=False),  # within: passes
            _outcome(0.26, 0.20, 0.05),  # better than the baseline: passes
            _outcome(0.26, nan, nan)]  # withheld (not an estimate): not checked, counted apart
    s = summarize(outs)
    assert (s["workpiece_ok"]["k"], s["workpiece_ok"]["n"]) == (2, 4)
    assert (s["workpiece_ok_identifiable"]["k"], s["workpiece_ok_identifiable"]["n"]) == (1, 2)
    assert (s["workpiece_withheld"]["k"], s["workpiece_withheld"]["n"]) == (1, 5)


def test_a_smooth_that_moves_the_workpiece_is_checked():
    """gen_b reseat_settling 108: the unnamed smooth moves the workpiece (2.99 -> 1.76 um).

    Its design is one the generator calls unidentifiable; the extension is
    reported as an estimate, so it must carry a U95 and be counted: finite,
    and the extended error within baseline + U95 (2.35 um at the time of
    writing). Written on gen_b fixture_slip 301 (0.26 -> 0.79 um, U95 0.96;
    before the smooth's gauge the engine's per-target U95 were about 3,000 um
    and the study gave none), whose smooth no longer earns a material
    held-out gain since the folds decide on the column space (its held-out
    RMS was the truncation's: 1.51 um, now 0.45 um with or without it).
    """
    o = _blind_case("gen_b", "reseat_settling", 108)
    assert not o.identifiable and np.isfinite(o.wp_ext_um)
    assert abs(o.wp_ext_um - o.wp_base_um) > 0.3, (o.wp_base_um, o.wp_ext_um)  # the smooth did move it
    # a U95 of millimetres would pass any check: bound it (3 um, over ten noise sigmas: 0.26 um here)
    assert np.isfinite(o.wp_u95_um) and o.wp_u95_um < 3.0, o.wp_u95_um
    s = summarize([o])["workpiece_ok"]
    assert (s["k"], s["n"]) == (1, 1), (o.wp_base_um, o.wp_ext_um, o.wp_u95_um)


def test_a_real_shift_by_an_unnamed_smooth_is_in_the_u95():
    """gen_a thermal_bending 100: an unnamed smooth moves the workpiece 3.09 -> 2.47 um (truth outside its model).

    The shift is real against its own scatter, and an unnamed term's split of
    the effect between machine and part is its assumption, not a
    measurement: the extended U95 must carry it; the U95 is bounded too
    (3 um: a U95 of millimetres would pass any check). Written on
    thermal_bending 604 (0.82 -> 1.98 um; before the rule its U95 was 0.78
    um and the check failed), whose smooth now moves it 0.82 -> 0.78 um
    only (the column-space folds: its baseline's held-out RMS 7.5 -> 0.93 um).
    """
    o = _blind_case("gen_a", "thermal_bending", 100)
    assert o.cause == "unexplained" and abs(o.wp_ext_um - o.wp_base_um) > 0.5, (o.cause, o.wp_base_um, o.wp_ext_um)
    assert np.isfinite(o.wp_u95_um) and o.wp_u95_um < 3.0, o.wp_u95_um
    s = summarize([o])["workpiece_ok"]
    assert (s["k"], s["n"]) == (1, 1), (o.wp_base_um, o.wp_ext_um, o.wp_u95_um)


#: Out-of-catalogue campaigns once named with full confidence by a wrong catalogue cause, now reported with
#: the name flagged ``ambiguous`` (the confidence rules of core.discover's step 8, not a threshold):
#: - gen_a reseat_hysteresis 502: one outlier of 5 um (one event cannot tell a chip from a seat);
#: - gen_a reseat_hysteresis 0 (session 10): six outliers in four set-ups, at one end of the touches'
#:   history counted one per place (concentration p 0.0078 with it, one family) (core.discover._outlier_finding's
#:   history check: a probe that re-seats after a turn); since session 24 ``unexplained``, the right reading: its
#:   outliers' centred turn (p 1.0e-5) hands the lead to ``unexplained`` (core.discover.OUTLIERS_TURNED_UNEXPLAINED);
#: - gen_b stylus_pickup 501, 605 (thermal_drift) and gen_a probe_heating 707 (part_change): the probe's
#:   size changing with time (and, for 707, a one-off event) explains as much and the cause nothing
#:   material beyond it (a gradual cause's time alternatives);
#: - gen_a reseat_hysteresis 409 (c_drift): a smooth term in the turn from the previous touch explains
#:   1.8 times as much and reproduces 60 % of the cause's signal (the structure lives there).
#: Since the folds decide on the column space and the repeats' noise is taken after a time trend, the last four
#: are no longer named at all: ``unexplained`` (stylus_pickup 501: noise 1.01 -> 0.30 um once the drift between
#: its repeats is a trend), the honest answer for an effect outside the catalogue.
#: Issue 13 item 7 (development seeds): a drift and a temperature that follows the clock, one explanation under
#: two names (core.discover._cause_alternatives, every fixed layout of a cause): gen_a thermal_drift 1109, gen_b
#: thermal_drift 1001 and 1008 read temperature_expansion (the drift's columns reproduce 98-99.5 % of its signal
#: and explain 1.01-1.2 times as much), gen_a reseat_hysteresis 1006 reads c_drift (the drift's columns 80 %,
#: 1.06 times as much); main named all four confidently. Session 9: gen_a thermal_drift 1109 (a warm-up,
#: 1 - exp(-t / tau)) is named thermal_drift, confidently, since the drift has a warm-up layout
#: (core.causes.drift_scans): NOW_RIGHT. Session 17: gen_b thermal_drift 1001 (0.43 sigma) is named thermal_drift,
#: still ambiguous with temperature_expansion: the drift's layout of smallest p (degree 1, p 1.0e-12) predicts
#: worse than the model (held-out gain -1.23 um^2) and refused the drift; its other layouts are now judged too
#: (core.discover.HELD_OUT_FALLBACK) and degree 2 (p 2.0e-11, gain 4.05 um^2) is named.
#: Session 19: gen_b thermal_drift 1001 and 1008 are named thermal_drift, confidently (NOW_RIGHT): their
#: spindle sensor is a clock (core.causes.clock_sensors: a smooth function of time to its own scatter), whose
#: course is now a layout of the drift and no temperature_expansion layout, so nothing else reads the same.
NOW_AMBIGUOUS = [("gen_a", "reseat_hysteresis", 502, "outlier", None),
                 ("gen_a", "reseat_hysteresis", 0, "unexplained", None),
                 ("gen_b", "stylus_pickup", 501, "unexplained", None),
                 ("gen_b", "stylus_pickup", 605, "unexplained", None),
                 ("gen_a", "probe_heating", 707, "unexplained", None),
                 ("gen_a", "reseat_hysteresis", 409, "unexplained", None),
                 ("gen_a", "reseat_hysteresis", 1006, "c_drift", "thermal_drift")]


#: Once misnamed, now named right (the cause, confident).
NOW_RIGHT = [("gen_a", "thermal_drift", 1109), ("gen_b", "thermal_drift", 1001), ("gen_b", "thermal_drift", 1008)]


@pytest.mark.parametrize("gen, effect, seed", NOW_RIGHT)
def test_once_misnamed_now_named(gen, effect, seed, monkeypatch):
    """Session 33 (vif33): gen_b thermal_drift 1001's warm-up is read through directions inflated up to 1352 times
    (its determined four alone not significant): :data:`core.discover.INFLATED_SIGNAL_HEDGED` names it with doubt,
    the name right; confident with that hedge off (its measured price: 8 of gen_b thermal_drift 1000-1039)."""
    import core.discover as D

    o = _blind_case(gen, effect, seed)
    if (gen, seed) == ("gen_b", 1001):
        assert o.cause == effect and not o.confident, (o.cause, o.confident)
        monkeypatch.setattr(D, "INFLATED_SIGNAL_HEDGED", False)
        o = blind_outcome(_blind(gen), effect, seed, generator=gen)  # (not the cached outcome: the hedge off)
    assert o.cause == effect and o.confident, (o.cause, o.confident)


@pytest.mark.parametrize("seed", [1, 5, 14])
def test_a_simulated_local_scale_defect_is_not_refused_where_confinement_cannot_be_tested(seed):
    """The simulator's local scale defects, seeds 1, 5, 14: named on main, refused as 'not confined' by the
    first confinement rule (a fitted signal beyond the smooth error map of one noise variance per column was
    taken as power). The rule now refuses only where the bump's signal outside the smooth map reaches the
    noncentrality of 50 % power at the adoption's level (core.discover._half_power_nc); here it does not,
    and the defect is named (ambiguous: the design cannot tell it from a smooth error map)."""
    o = hidden_outcome("local_scale_defect", seed)
    assert o.cause == "local_scale_defect", o.cause


@pytest.mark.parametrize("seed", [45, 57])
def test_a_simulated_local_scale_defect_is_not_refused_for_what_the_smooth_map_explains_of_it(seed):
    """The simulator's Gaussian defects 45 and 57 (EYY 3.5 um and EXX 2.4 um, sigma 4 mm): refused as 'not
    confined' by main (ac5a07d), `unexplained`: the smooth error map's 36 and 28 columns explained as much as
    the one bump column (29.8 against 31.9, 11.4 against 11.6 um^2) because they hold most of the bump itself
    (93 % and 80 % of its fitted signal), and the bump beside them was not significant after Bonferroni
    (p = 0.049, 0.035 against alpha_family 0.0025). The smooth map explains nothing significant beyond the bump (p = 0.96,
    0.12): it is refused only when it does (core.discover._smooth_verdict), else the two are indistinguishable
    and the defect is named, ambiguous."""
    o = hidden_outcome("local_scale_defect", seed)
    assert o.cause == "local_scale_defect", o.cause


@pytest.mark.parametrize("gen, effect, seed, cause, alternative", NOW_AMBIGUOUS)
def test_once_confident_misnamings_are_flagged(gen, effect, seed, cause, alternative):
    o = _blind_case(gen, effect, seed)
    assert o.cause == cause and (cause == "unexplained" or not o.confident), (o.cause, o.confident)
    # the other catalogue cause that reads the same (issue 13 item 7: the drift) is listed
    assert alternative is None or alternative in o.alternatives, o.alternatives


#: Campaigns once named wrongly, each fixed by a rule of the engine (not by a
#: threshold): (generator, effect, seed, what the rule made of it).
#: - gen_a probe_lobing 302: a probe's fixed 3 lobes named lobing_per_setup
#:   (the per-set-up form won the round on cross-validation); the plainer
#:   cause is now tested before adoption;
#: - gen_b fixture_slip 500: a slip (5.0 sigma visible) named
#:   temperature_expansion with nothing significant beyond the slip; a cause
#:   must now stay significant beside it.
#: - gen_a nonrigid 702: the coupling (2.8 sigma visible) left unexplained because a finer rigid error
#:   map explains as much (on this part's geometry it represents the effect exactly); a plainer
#:   explanation without a name now leaves the cause named, flagged ambiguous.
#: - gen_a periodic_axis_error 703 and nonrigid 703 (1.8 and 2.9 sigma visible): left unexplained because
#:   the per-feature-per-set-up term explained 2 % more (245 against 241 um^2); that term nests any machine
#:   error smooth over a feature (each feature of each set-up is one place of the machine), so for a
#:   position cause it is judged as the cause's own covariate's smooth (core.discover.NESTING_FAMILIES).
#: - gen_b outlier 908 (issue 13 item 7, a development seed): local_scale_defect named confidently ahead of
#:   1,436 um^2 of chips, explaining 1.40 um^2 of the 1.90 um^2 a smooth in y explains (share 0.73), kept
#:   because the shortfall was below materiality (2.29 um^2) though the structure in y was too: a shortfall
#:   is now forgiven only of material structure (core.discover._rival_share).
REGRESSIONS = [("gen_a", "probe_lobing", 302, ("probe_lobing",)),
               ("gen_b", "fixture_slip", 500, ("unexplained",)),
               ("gen_a", "nonrigid", 702, ("nonrigid",)),
               ("gen_a", "periodic_axis_error", 703, ("periodic_axis_error",)),
               ("gen_a", "nonrigid", 703, ("nonrigid",)),
               ("gen_b", "outlier", 908, ("outlier",))]


@pytest.mark.parametrize("gen, effect, seed, expected", REGRESSIONS)
def test_once_misnamed_campaigns_stay_fixed(gen, effect, seed, expected):
    o = _blind_case(gen, effect, seed)
    assert o.cause in expected, (o.cause, o.findings)


def test_two_causes_this_design_cannot_tell_apart_are_both_named():
    """Lost motion on touches that approach along the normal is a function of the approach direction.

    ``-n_x sign(d_x) / 2 = |n_x| / 2``: its Fourier series in the azimuth has
    harmonics 0, 2, 4, 6, ... with weights 1/(4k^2 - 1), so harmonics 2 and
    4 (both in the probe's lobing columns) hold (1/9 + 1/225) / ((pi^2 - 8)
    / 16) = 98.8 % of its variance: the simulator's reversal is named, and
    flagged ambiguous with probe_lobing (and, since a cause of several fixed
    layouts is an alternative too, with lobing_per_setup, whose lobes turned
    per set-up nest the probe's fixed ones). And the study counts a wrong name
    whose alternatives hold the right one apart (``catalogue_alternative``),
    never in ``catalogue``.
    """
    assert (1 / 9 + 1 / 225) / ((np.pi ** 2 - 8) / 16) > 0.98
    o = hidden_outcome("reversal", 2700)
    assert o.cause == "reversal" and not o.confident and o.alternatives == ("probe_lobing", "lobing_per_setup"), o
    a = Outcome("g", "reversal", 0, ("reversal",), "probe_lobing", ("probe_lobing",), False, 2.0, 0.3,
                0.3, 0.3, 0.3, 0.1, alternatives=("reversal",))
    b = Outcome("g", "reversal", 1, ("reversal",), "reversal", ("reversal",), False, 2.0, 0.3, 0.3, 0.3, 0.3, 0.1,
                alternatives=("probe_lobing",))
    s = summarize([a, b])
    assert (s["catalogue"]["k"], s["catalogue"]["n"]) == (1, 2)
    assert (s["catalogue_ambiguous"]["k"], s["catalogue_ambiguous"]["n"]) == (1, 1)
    assert (s["catalogue_alternative"]["k"], s["catalogue_alternative"]["n"]) == (1, 2)


def test_lobes_turned_per_set_up_named_ambiguous_when_their_magnitudes_are_not_determined():
    """The cross pocket's own 2-lobe form turns with the table and absorbs two directions of lobes turned per set-up.

    The simulator's turned lobes (seed 2706) were named probe_lobing (their
    common part) because lobing_per_setup's amplitude and orientations are
    not determined on this design and its plausibility check refused it.
    Not determined is not implausible: the cause is named, flagged
    ambiguous, and the shift of the workpiece it makes is tested and, when
    real, carried in the extended U95 (seed 2703: 0.49 -> 0.83 um against
    the truth; the U95 without the shift was 0.30 um, with it 0.76 um).
    Visibility comes from the truth (the campaign less its effect-free twin).
    """
    o = hidden_outcome("lobing_per_setup", 2706)
    assert o.cause == "lobing_per_setup" and not o.confident, o
    assert o.visible_sigmas >= 1.0 and np.isfinite(o.angle_to_baseline_deg)
    o = hidden_outcome("lobing_per_setup", 2703)
    assert o.cause == "lobing_per_setup" and o.shift_carried, o
    assert o.wp_ext_um > o.wp_base_um + 0.3 and o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


def test_an_effect_free_simulated_campaign_is_not_a_local_defect_by_an_undercounted_scan():
    """The simulator's effect-free campaign 3301: main (ac5a07d) named local_scale_defect, confidently (a
    0.54 um bump at Y -29 mm, p = 3.7e-6 per trial, adjusted 0.0013 over 38 counted bumps times 9 causes,
    below alpha_family 0.0025). Beside the baseline the scan's 150 trials trace a path of length 86; Davies'
    bound (core.discover._path_tries) at the adoption's level (0.0025 / 9) counts 176 bumps: adjusted
    0.0058, not significant, and the campaign is `none`."""
    o = hidden_outcome("none", 3301)
    assert o.cause == "none", o.cause


def test_the_noise_beyond_a_drift_model_is_taken_where_shown():
    """gen_a thermal_drift 1201: 5 repeat groups give 10 degrees of freedom and no rate can be taken out of
    them (a rate per set-up or a shared one leaves fewer than 10), so their scatter holds the drift: 0.84 um
    for a true 0.347 um, kept on main (ac5a07d) even after thermal_drift was adopted, because the scatter
    beyond the model's terms leaves 8 degrees of freedom, below the floor of 10. What the drift's columns take
    out of the repeats is far more than noise (F = 30, p = 2e-4, against SHORT_TERM_ALPHA 0.01), so the
    scatter beyond them is the noise now: 0.32 um. Bounds: the 99 % interval of an 8-dof estimate,
    sigma * sqrt(chi2(8) quantiles 0.005, 0.995 / 8) = [0.41, 1.66] sigma."""
    mod = _blind("gen_a")
    if mod is None:
        pytest.skip("gen_a generator absent")
    log, tr = mod.generate("thermal_drift", 1201)
    rep = discovered(log).to_report()
    noise = rep["noise_um"]
    assert noise["method"] == "repeats beyond the model's terms", noise["method"]
    assert 0.41 * tr.noise_um < noise["sigma_um"] < 1.66 * tr.noise_um, (noise["sigma_um"], tr.noise_um)


def test_turned_lobes_hidden_in_the_one_telling_direction_are_not_confidently_fixed(monkeypatch):
    """Session 27 (issue 13; the blind check's lobing_per_setup 6101, tuning twin 4038): the cross pocket leaves
    one direction that tells lobes turned per set-up from fixed ones, and 4038's turn angles hide the turn
    there (p_turned 0.0005 < alpha: main named probe_lobing confidently). The data favour fixed lobes by odds
    of only 57 (at most 58 on this design), below 1 / alpha: probe_lobing stays ambiguous with
    lobing_per_setup. Without the rule (RICHER_NEEDS_ODDS False) the misnaming is confident again."""
    import core.discover as D

    o = hidden_outcome("lobing_per_setup", 4038)
    assert o.cause == "probe_lobing" and not o.confident, o
    monkeypatch.setattr(D, "RICHER_NEEDS_ODDS", False)
    o = hidden_outcome("lobing_per_setup", 4038)
    assert o.cause == "probe_lobing" and o.confident, o


def test_the_richer_readings_workpiece_shift_is_carried_where_the_name_is_hedged_beside_it(monkeypatch):
    """Session 28 (issue 13; the blind check's lobing_per_setup 6403, spent): the truth turns a 2-lobe pre-travel
    per set-up, the report names probe_lobing (fixed lobes) hedged beside lobing_per_setup. The extended workpiece
    (0.611 um from the truth) misses the baseline's 0.300 + its U95 0.296 (the fixed-lobe model's variance alone).
    The richer reading (lobes turned per set-up, their determined combinations in the fixed lobes' place) moves
    the workpiece far beyond its scatter: carried (u = |shift| / 2 per target), the U95 is 0.397 and covers.
    Without the rule (RICHER_SHIFT_CARRIED False) the check fails again. The campaign: shift28 showed the rule on
    the tuning twin 4086, which on session 28's truth (the tables over stroke + J) no longer fails without it
    (0.947 against 0.645 + 0.310), nor does any of the simulator's 820 lobing_per_setup / probe_lobing campaigns
    4000-4409 (the rule changes 385 of their U95, none across its check); 6403 still does (the lead's run,
    /tmp/lead28/rs)."""
    import core.discover as D

    o = hidden_outcome("lobing_per_setup", 6403)
    assert o.cause == "probe_lobing" and not o.confident, o
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o
    monkeypatch.setattr(D, "RICHER_SHIFT_CARRIED", False)
    o = hidden_outcome("lobing_per_setup", 6403)
    assert o.cause == "probe_lobing" and not o.confident, o
    assert o.wp_ext_um > o.wp_base_um + o.wp_u95_um, o
