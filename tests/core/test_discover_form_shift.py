"""Session 28 (form28): gen_a c_drift's wrong form, where the adopted form has a direction inflated beyond ``vif_max``.

Session 27's blind check failed gen_a c_drift 7302's workpiece check: a creep common to every set-up adopted (named)
for per-set-up creeps of alternating sign, along a direction inflated hundreds to thousands of times while the best,
which ``vif_max`` judges, stayed below it. Its tuning twin 1998 fails alike (the form "after each indexing", best
inflation 29.7, worst 1,370: the extended workpiece 11.894 um against the baseline 1.084 + U95 1.551). Two remedies,
each behind its constant (docs/discovery-studies.md, "Session 28: the workpiece not determined between a cause's forms"):

- ``FORM_SHIFT_CARRIED`` ("v8"): the cause's other passing forms fitted in the adopted one's place and the largest real
  workpiece shift carried in the extended U95 (the name and the estimate unchanged);
- ``VIF_FORM_BY_GAIN`` with ``VIF_DROP_BEYOND_MAX`` ("v7"): of the cause's passing forms the one of largest held-out
  gain taken, the inflated directions left out.
"""

from __future__ import annotations

import importlib

import pytest

import core.discover as D
from tests.discover_helpers import discovered


@pytest.fixture(autouse=True)
def _extended_workpiece_offered(monkeypatch):
    """These tests examine the extended fit's workpiece (its shift, its U95) on campaigns whose extended U95 grows
    beyond 3 times the baseline's, which core.discover.WORKPIECE_U95_GROWTH_WITHHELD (on since session 35) withholds
    from the report: held off here, so that the estimate beneath it is what they check, as they were written to."""
    import core.discover as D

    monkeypatch.setattr(D, "WORKPIECE_U95_GROWTH_WITHHELD", False)


def _report(gen, effect, seed):

    log, _ = importlib.import_module(f"scenarios.blind.{gen}").generate(effect, seed)
    return discovered(log).to_report()


def _off(monkeypatch):
    for name in ("VIF_DROP_BEYOND_MAX", "VIF_DROP_LEAST_INFLATION", "VIF_FORM_BY_GAIN", "FORM_SHIFT_CARRIED",
                 "FORM_BY_GAIN_DETERMINED_ONLY", "FORM_BY_GAIN_MATERIAL"):
        monkeypatch.setattr(D, name, False)
    # (session 32's carried shift of an inflated named term, on since: it widens these campaigns' U95s too; the
    # figures below are the session 28-30 rules' own)
    monkeypatch.setattr(D, "HEDGED_SHIFT_CARRIED", None)
    # (session 34's count of the held-out fallback as a second selection, on since: with these old rules gen_a c_drift
    # 7302's common creep comes through the fallback and reads hedged; the figures are the same either way)
    monkeypatch.setattr(D, "FALLBACK_SELECTION_COUNTED", False)


def test_defaults():
    """v8 on (its readings the determined forms), v7 off (session 28, form28's measurement); v9b on (the choice by
    held-out gain among determined forms, without the drop: session 30, form30), v9c off (session 29, form29)."""
    assert D.FORM_SHIFT_CARRIED is True and D.FORM_SHIFT_DETERMINED_ONLY is True
    assert D.VIF_DROP_BEYOND_MAX is False and D.VIF_DROP_LEAST_INFLATION is False
    assert D.VIF_FORM_BY_GAIN is True and D.FORM_BY_GAIN_DETERMINED_ONLY is True
    assert D.FORM_BY_GAIN_MATERIAL is False


def test_v9b_by_default_mends_c_drift_1998_and_keeps_thermal_drift_1086():
    """The engine's defaults (no constant set here: session 30, form30, turned v9b on). gen_a c_drift 1998, a creep
    common to the set-ups adopted along a direction inflated 1,370 times for per-set-up creeps of alternating sign:
    the per-set-up creep (inflation ~3, the truth's form) is taken by its larger held-out gain and the extended
    workpiece is mended, 0.216 um against the baseline's 1.084, U95 0.483 (session 29's figures for v9, to 1e-3 um);
    without the rule (both constants off) it is 11.894 um off, covered only by v8's U95 of 12.486. gen_a thermal_drift
    1086 (1.03 sigma) keeps its hedged ``thermal_drift``: the form of larger gain there is itself inflated beyond
    ``vif_max``, no candidate among determined forms (v9 alone: ``unexplained``)."""
    from scenarios.hidden import blind_outcome

    gen_a = importlib.import_module("scenarios.blind.gen_a")
    on = blind_outcome(gen_a, "c_drift", 1998, generator="gen_a")
    assert on.cause == "c_drift" and on.confident
    assert on.wp_ext_um == pytest.approx(0.216, abs=1e-3) and on.wp_u95_um == pytest.approx(0.483, abs=1e-3)
    assert on.wp_ext_um < on.wp_base_um  # mended by the estimate, not covered by the width
    f = _report("gen_a", "c_drift", 1998)["findings"][0]
    assert f["params"]["form"] == "per set-up" and "largest held-out gain" in f["evidence"]["least_inflated_form"]
    th = blind_outcome(gen_a, "thermal_drift", 1086, generator="gen_a")
    assert th.cause == "thermal_drift" and not th.confident


def test_c_drift_1998_the_other_forms_shift_carried_in_the_u95(monkeypatch):
    """``FORM_SHIFT_CARRIED`` on gen_a c_drift 1998: the name, the form and the extended workpiece (11.894 um) do not
    change; the cause's other passing forms are refitted in its place, the cubic over the campaign moves the workpiece
    by 12.4 um RMS (p ~ 1e-123 against its own scatter: real) and is carried in quadrature, so the U95 goes 1.551 ->
    12.486 um and the check passes (11.894 <= 1.084 + 12.486); off, it fails (11.894 > 1.084 + 1.551). Figures as
    measured, to 1e-3 um (an engine change that moves them should be looked at)."""
    from scenarios.hidden import blind_outcome

    gen_a = importlib.import_module("scenarios.blind.gen_a")
    _off(monkeypatch)
    off = blind_outcome(gen_a, "c_drift", 1998, generator="gen_a")
    assert off.cause == "c_drift" and off.confident
    assert off.wp_ext_um == pytest.approx(11.894, abs=1e-3) and off.wp_u95_um == pytest.approx(1.551, abs=1e-3)
    assert off.wp_ext_um > off.wp_base_um + off.wp_u95_um
    f0 = _report("gen_a", "c_drift", 1998)["findings"][0]
    assert "workpiece_shift_form" not in f0["evidence"] and f0["evidence"]["max_vif"] > 100.0

    monkeypatch.setattr(D, "FORM_SHIFT_CARRIED", True)
    monkeypatch.setattr(D, "FORM_SHIFT_DETERMINED_ONLY", True)
    on = blind_outcome(gen_a, "c_drift", 1998, generator="gen_a")
    assert on.cause == "c_drift" and on.confident
    assert on.wp_ext_um == pytest.approx(off.wp_ext_um, abs=1e-9)  # (the estimate is the adopted form's)
    assert on.wp_u95_um == pytest.approx(12.486, abs=1e-3)
    assert on.wp_ext_um <= on.wp_base_um + on.wp_u95_um
    r = _report("gen_a", "c_drift", 1998)
    f = r["findings"][0]
    assert f["params"]["form"] == "after each indexing"
    sh = f["evidence"]["workpiece_shift_form"]
    assert sh["carried_in_u95"] and sh["p"] < 1e-6 and sh["shift_rms_um"] == pytest.approx(12.39, abs=0.01)
    assert sh["alternative"].startswith("c_drift as ")
    assert any("inflated beyond vif_max" in c for c in r["conventions"])


def test_no_other_form_carried_where_the_adopted_form_is_within_vif_max(monkeypatch):
    """The rule acts only where the adopted form has a direction inflated beyond ``vif_max``: gen_a c_drift 1005's
    per-set-up creep (worst inflation 22.3) reads the same with the constant on and off, field for field."""
    from scenarios.hidden import blind_outcome

    gen_a = importlib.import_module("scenarios.blind.gen_a")
    _off(monkeypatch)
    f0 = _report("gen_a", "c_drift", 1005)["findings"][0]
    assert f0["evidence"]["max_vif"] <= 100.0
    off = blind_outcome(gen_a, "c_drift", 1005, generator="gen_a")
    monkeypatch.setattr(D, "FORM_SHIFT_CARRIED", True)
    on = blind_outcome(gen_a, "c_drift", 1005, generator="gen_a")
    assert (on.cause, on.confident, on.wp_ext_um, on.wp_u95_um) == (off.cause, off.confident, off.wp_ext_um,
                                                                     off.wp_u95_um)
    assert "workpiece_shift_form" not in _report("gen_a", "c_drift", 1005)["findings"][0]["evidence"]


def test_thermal_drift_1004_an_inflated_reading_not_carried(monkeypatch):
    """``FORM_SHIFT_DETERMINED_ONLY``: gen_a thermal_drift 1004 names the warm-up (the truth's form) with a direction
    inflated beyond vif_max; its other passing forms that are inflated too shift the workpiece by their own
    amplification: read in every form, the U95 goes 0.570 -> 1.147 um against an error of 0.372 (three times wider
    than the error); read only in the determined forms, nothing real is carried and the U95 stays 0.570. Figures as
    measured, to 1e-3 um."""
    from scenarios.hidden import blind_outcome

    gen_a = importlib.import_module("scenarios.blind.gen_a")
    _off(monkeypatch)
    off = blind_outcome(gen_a, "thermal_drift", 1004, generator="gen_a")
    assert off.cause == "thermal_drift" and off.wp_u95_um == pytest.approx(0.570, abs=1e-3)
    monkeypatch.setattr(D, "FORM_SHIFT_CARRIED", True)
    monkeypatch.setattr(D, "FORM_SHIFT_DETERMINED_ONLY", False)
    every = blind_outcome(gen_a, "thermal_drift", 1004, generator="gen_a")
    assert every.wp_ext_um == off.wp_ext_um and every.wp_u95_um == pytest.approx(1.147, abs=1e-3)
    assert every.wp_ext_um < every.wp_u95_um / 3
    monkeypatch.setattr(D, "FORM_SHIFT_DETERMINED_ONLY", True)
    det = blind_outcome(gen_a, "thermal_drift", 1004, generator="gen_a")
    assert det.wp_ext_um == off.wp_ext_um and det.wp_u95_um == off.wp_u95_um


@pytest.mark.parametrize("seed, on_um, off_um, least_inflated_um", [
    (1998, 0.216, 11.894, 0.216),  # (the form "after each indexing" given up for the per-set-up creep)
    (1791, 0.795, 0.584, 1.960),  # (the per-set-up creep kept; by least inflation it is given up and fails)
])
def test_c_drift_form_of_largest_held_out_gain(monkeypatch, seed, on_um, off_um, least_inflated_um):
    """``VIF_FORM_BY_GAIN`` with ``VIF_DROP_BEYOND_MAX`` on gen_a c_drift 1998 and 1791: the per-set-up creep (the
    truth's form) is named in both, each check passes; without the rule 1998 fails (the common creep), and with the
    choice by least inflation instead (``VIF_DROP_LEAST_INFLATION``, v328's v5) 1791 fails (1.960 against 0.644 + U95
    0.659): the key of the choice is what mends both. Figures as measured, to 1e-3 um."""
    from scenarios.hidden import blind_outcome

    gen_a = importlib.import_module("scenarios.blind.gen_a")
    _off(monkeypatch)
    off = blind_outcome(gen_a, "c_drift", seed, generator="gen_a")
    assert off.wp_ext_um == pytest.approx(off_um, abs=1e-3)
    monkeypatch.setattr(D, "VIF_DROP_LEAST_INFLATION", True)
    li = blind_outcome(gen_a, "c_drift", seed, generator="gen_a")
    assert li.wp_ext_um == pytest.approx(least_inflated_um, abs=1e-3)
    monkeypatch.setattr(D, "VIF_DROP_LEAST_INFLATION", False)
    monkeypatch.setattr(D, "VIF_DROP_BEYOND_MAX", True)
    monkeypatch.setattr(D, "VIF_FORM_BY_GAIN", True)
    on = blind_outcome(gen_a, "c_drift", seed, generator="gen_a")
    assert on.cause == "c_drift" and on.wp_ext_um == pytest.approx(on_um, abs=1e-3)
    assert on.wp_ext_um <= on.wp_base_um + on.wp_u95_um
    assert _report("gen_a", "c_drift", seed)["findings"][0]["params"]["form"] == "per set-up"
    if seed == 1998:
        assert off.wp_ext_um > off.wp_base_um + off.wp_u95_um
    else:
        assert li.wp_ext_um > li.wp_base_um + li.wp_u95_um


@pytest.mark.parametrize("seed, on_um, on_u95, off_um, off_u95, form", [
    (1998, 0.216, 0.483, 11.894, 12.486, "per set-up"),  # (the form "after each indexing" given up)
    (7302, 0.612, 0.671, 12.815, 12.483, "per set-up"),  # (session 27's blind failure, spent; the common creep given up)
    (1791, 0.584, 3.720, 0.584, 3.720, "per set-up"),  # (the per-set-up creep, the truth's form, kept: largest gain)
])
def test_c_drift_form_of_largest_held_out_gain_without_the_drop(monkeypatch, seed, on_um, on_u95, off_um, off_u95,
                                                                 form):
    """``VIF_FORM_BY_GAIN`` alone (session 29, form29, "v9": ``VIF_DROP_BEYOND_MAX`` off, ``FORM_SHIFT_CARRIED`` on):
    at the step a passing form with a direction beyond ``vif_max`` opens, the cause's passing form of largest held-out
    gain is taken, every direction kept. gen_a c_drift 1998 and 7302 then name the per-set-up creep (the truth's form)
    and the extended workpiece is mended (0.216 and 0.612 um, below the baseline 1.084 and 1.170), with a U95 that
    shrinks to 0.483 and 0.671 (no other determined form moves it far); without the rule the common creep's estimate is
    11.894 and 12.815 um off, covered only by v8's U95 of 12.5 um. 1791, whose adopted per-set-up creep predicts
    held-out data best, is left as it was (least inflation would give it up and fail, the test above). The name and
    the confidence are the same both ways. Figures as measured, to 1e-3 um."""
    from scenarios.hidden import blind_outcome

    gen_a = importlib.import_module("scenarios.blind.gen_a")
    _off(monkeypatch)
    monkeypatch.setattr(D, "FORM_SHIFT_CARRIED", True)
    monkeypatch.setattr(D, "FORM_SHIFT_DETERMINED_ONLY", True)
    off = blind_outcome(gen_a, "c_drift", seed, generator="gen_a")
    assert off.wp_ext_um == pytest.approx(off_um, abs=1e-3) and off.wp_u95_um == pytest.approx(off_u95, abs=1e-3)
    monkeypatch.setattr(D, "VIF_FORM_BY_GAIN", True)
    on = blind_outcome(gen_a, "c_drift", seed, generator="gen_a")
    assert (on.cause, on.confident) == (off.cause, off.confident) and on.cause == "c_drift"
    assert on.wp_ext_um == pytest.approx(on_um, abs=1e-3) and on.wp_u95_um == pytest.approx(on_u95, abs=1e-3)
    assert on.wp_ext_um <= on.wp_base_um + on.wp_u95_um
    f = _report("gen_a", "c_drift", seed)["findings"][0]
    assert f["params"]["form"] == form
    if seed != 1791:
        # the estimate mended, not only covered: below the baseline, and a U95 a tenth of the one v8 alone needs
        assert on.wp_ext_um < on.wp_base_um and on.wp_u95_um < off.wp_u95_um / 10
        assert off.wp_ext_um > 5 * off.wp_base_um
        assert "largest held-out gain" in f["evidence"]["least_inflated_form"]
    else:
        assert "least_inflated_form" not in f["evidence"]


def test_thermal_drift_1086_the_form_by_gain_only_among_determined_forms(monkeypatch):
    """v9's cost and v9b's remedy (session 29, form29): gen_a thermal_drift 1086 (1.03 sigma) reads ``thermal_drift``
    hedged; with ``VIF_FORM_BY_GAIN`` alone its warm-up is given up for a form of larger held-out gain that is itself
    inflated beyond ``vif_max``, and the campaign ends ``unexplained``. With ``FORM_BY_GAIN_DETERMINED_ONLY`` that
    form is no candidate and the reading is the defaults' (name, confidence, workpiece and U95 exactly)."""
    from scenarios.hidden import blind_outcome

    gen_a = importlib.import_module("scenarios.blind.gen_a")
    _off(monkeypatch)
    monkeypatch.setattr(D, "FORM_SHIFT_CARRIED", True)
    monkeypatch.setattr(D, "FORM_SHIFT_DETERMINED_ONLY", True)
    off = blind_outcome(gen_a, "thermal_drift", 1086, generator="gen_a")
    assert off.cause == "thermal_drift" and not off.confident
    monkeypatch.setattr(D, "VIF_FORM_BY_GAIN", True)
    v9 = blind_outcome(gen_a, "thermal_drift", 1086, generator="gen_a")
    assert v9.cause == "unexplained"
    monkeypatch.setattr(D, "FORM_BY_GAIN_DETERMINED_ONLY", True)
    v9b = blind_outcome(gen_a, "thermal_drift", 1086, generator="gen_a")
    assert (v9b.cause, v9b.confident, v9b.wp_ext_um, v9b.wp_u95_um) == (off.cause, off.confident, off.wp_ext_um,
                                                                         off.wp_u95_um)
