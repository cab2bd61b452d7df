"""``vmt regress``: the example studies pass through the command, mutations fail on the right quantity,
the JUnit XML meets the common schema's rules, bad studies exit 2, the comparison by hand."""

import json
import re
from dataclasses import replace
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from scenarios import regress
from scenarios.cli import main
from scenarios.regress import (GAUGE_FLOOR, IDENTIFICATIONS, Causes, Estimate, Mutation, Rule, StudyError, check,
                               junit_xml, load_study, loads_study, run_study, simultaneous_k)
from scenarios.testing import assert_recovers, regress_study  # noqa: F401 (the fixture, as a user imports it)

STUDIES = Path(__file__).resolve().parents[2] / "scenarios" / "data"
EXAMPLES = sorted(STUDIES.glob("regress-*.toml"))
SELFCAL = STUDIES / "regress-selfcal-nmv3000.toml"
MFB3 = STUDIES / "regress-mfb-3axis-vmc.toml"
POSITIONING = STUDIES / "regress-iso230-2-vmc-x.toml"

#: The MFB studies' runs without the two notes no regress check reads (conftest mfb_notes_skipped: the errors, their
#: U95 and the estimate's covariance, all that scenarios.regress._mfb takes, are the same doubles): about half of
#: each run's CPU, five runs here.
pytestmark = pytest.mark.usefixtures("mfb_notes_skipped_module")


# --------------------------------------------------------------------------- JUnit schema rules
# The rules of the common JUnit schema (Windy Road JUnit.xsd, Apache Ant's XMLJUnitResultFormatter format,
# read by Jenkins, GitLab, GitHub actions): written here from the schema's text, not from vmt's writer.
_TOKEN = re.compile(r"^\S+( \S+)*$")          # xs:token, minLength 1: no leading/trailing/double spaces, no tabs
_INT = re.compile(r"^[+-]?[0-9]+$")
_DECIMAL = re.compile(r"^[+-]?([0-9]+(\.[0-9]*)?|\.[0-9]+)$")  # xs:decimal: no exponent
_TIMESTAMP = re.compile(r"^[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:[0-9]{2}:[0-9]{2}$")  # no zone


def _attrs(el, required: dict, optional: dict = {}):
    for k, kind in required.items():
        assert k in el.attrib, f"<{el.tag}> lacks the required attribute {k}"
    for k, v in el.attrib.items():
        kind = required.get(k, optional.get(k))
        assert kind is not None, f"<{el.tag}> has an attribute the schema does not declare: {k}"
        pat = {"token": _TOKEN, "int": _INT, "decimal": _DECIMAL, "timestamp": _TIMESTAMP, "string": None}[kind]
        assert pat is None or pat.match(v), f"<{el.tag} {k}={v!r}> is not an xs:{kind}"


def validate_junit(text: str) -> None:
    """Raise AssertionError where ``text`` breaks the rules of JUnit.xsd (aggregated form)."""
    root = ET.fromstring(text.encode("utf-8"))
    assert root.tag == "testsuites" and not root.attrib, "root must be <testsuites> without attributes"
    for n, suite in enumerate(root):
        assert suite.tag == "testsuite", f"<testsuites> holds only <testsuite>, got <{suite.tag}>"
        _attrs(suite, {"name": "token", "timestamp": "timestamp", "hostname": "token", "tests": "int",
                       "failures": "int", "errors": "int", "time": "decimal", "package": "token", "id": "int"},
               {"skipped": "int"})
        assert int(suite.get("id")) == n, "testsuite ids start at 0 and count up"
        tags = [c.tag for c in suite]
        assert tags and tags[0] == "properties", "<properties> first (required)"
        assert tags[-2:] == ["system-out", "system-err"], "<system-out>, <system-err> last (required)"
        assert all(t == "testcase" for t in tags[1:-2]), f"only <testcase> between, got {tags[1:-2]}"
        for p in suite[0]:
            assert p.tag == "property" and not len(p)
            _attrs(p, {"name": "token", "value": "string"})
        cases = suite.findall("testcase")
        for tc in cases:
            _attrs(tc, {"name": "token", "classname": "token", "time": "decimal"})
            assert len(tc) <= 1, "a testcase holds at most one of skipped, error, failure"
            for r in tc:
                assert r.tag in ("skipped", "error", "failure"), f"<testcase> cannot hold <{r.tag}>"
                if r.tag != "skipped":
                    _attrs(r, {"type": "string"}, {"message": "string"})
                    assert not len(r), f"<{r.tag}> holds text only"
        for t in ("system-out", "system-err"):
            assert not len(suite.find(t)) and not suite.find(t).attrib
        assert int(suite.get("tests")) == len(cases)
        assert int(suite.get("failures")) == sum(tc.find("failure") is not None for tc in cases), "failures count"
        assert int(suite.get("errors")) == sum(tc.find("error") is not None for tc in cases)


GOOD = ('<testsuites><testsuite name="s" timestamp="2026-12-01T22:00:00" hostname="h" tests="1" failures="1" '
        'errors="0" time="0.5" package="p" id="0"><properties><property name="a" value="b"/></properties>'
        '<testcase name="q" classname="c" time="0.1"><failure type="t" message="m">m</failure></testcase>'
        '<system-out>x</system-out><system-err/></testsuite></testsuites>')


@pytest.mark.parametrize("bad, why", [
    (GOOD.replace(' hostname="h"', ""), "hostname"),
    (GOOD.replace("22:00:00", "22:00:00Z"), "timestamp"),
    (GOOD.replace('time="0.5"', 'time="5e-1"'), "decimal"),
    (GOOD.replace('name="q"', 'name=" q"'), "token"),
    (GOOD.replace('<testcase name="q"', '<testcase verdict="x" name="q"'), "does not declare"),
    (GOOD.replace('<system-err/>', ''), "system-err"),
    (GOOD.replace('failures="1"', 'failures="0"'), "failures count"),
    (GOOD.replace('<failure type="t" message="m">', '<failure message="m">'), "type"),
    (GOOD.replace('<testsuites>', '<testsuites tests="1">'), "without attributes"),
    (GOOD.replace('id="0"', 'id="1"'), "ids"),
])
def test_the_schema_rules_reject_what_the_schema_rejects(bad, why):
    validate_junit(GOOD)
    with pytest.raises(AssertionError, match=why):
        validate_junit(bad)


# --------------------------------------------------------------------------- the examples, through the command
@pytest.fixture(scope="session")
def example_runs(tmp_path_factory):
    """Every example study run once through ``vmt regress`` (exit status, JSON, JUnit text)."""
    d = tmp_path_factory.mktemp("regress")
    out = {}
    for p in EXAMPLES:
        j, x = d / f"{p.stem}.json", d / f"{p.stem}.xml"
        rc = main(["regress", str(p), "--json", str(j), "--junit", str(x)])
        out[p.stem] = (rc, json.loads(j.read_text()), x.read_text())
    return out


def test_there_is_an_example_per_identification():
    kinds = {load_study(p).identification for p in EXAMPLES}
    assert kinds >= {"selfcal", "iso230-2", "discover"} and kinds & {"mfb-3axis", "mfb-5axis"}, kinds
    assert set(kinds) <= set(IDENTIFICATIONS)


#: Examples that FAIL, and the one failure each gives: a finding of the code under test, kept visible (not
#: loosened away) until the code changes. discover-nmv3000 (review29c F3, rf29): since a discover study states
#: the whole set of causes, its realistic ripple-free machine (the 'no hidden effect' set the LUT models
#: represent) reads ``unexplained`` beside the screw on seed 1 (13 of seeds 1-20; without the screw 12 of 20,
#: and ``outlier`` 2 of 20): a 0.1 um structure per feature and set-up that stays at 0.03 um probing noise
#: while identify's tables leave 0.019 um RMS noise-free. When discover stops naming it this test fails: move
#: the study back among those that pass.
KNOWN_FAILING: dict = {}  # empty since session 31: the Abbe columns gated on the raised touches' own evidence
# (core.baseline.PLANAR_ABBE_GATE) take the ripple-free machine's Abbe shear, and discover-nmv3000 names the screw
# alone on seed 1 (20 of seeds 1-20; without the screw nothing 20 of 20)


@pytest.mark.parametrize("stem", [p.stem for p in EXAMPLES])
def test_each_example_passes_through_vmt_regress(example_runs, stem):
    rc, rep, xml = example_runs[stem]
    failed = [c["message"] for c in rep["checks"] if not c["passed"]]
    if stem in KNOWN_FAILING:
        assert (rc, rep["passed"], failed) == (1, False, [KNOWN_FAILING[stem]])
    else:
        assert rc == 0, failed
        assert rep["passed"] and rep["n_failed"] == 0
    assert rep["n_checks"] == len(rep["checks"]) > 0
    for c in rep["checks"]:  # every check is a real comparison, not an empty one
        if c["unit"] != "cause":   # (a cause check compares sets: none named is a comparison when none is expected)
            assert c["elements"] >= 1
            assert c["deviation"] <= c["limit"] and c["margin"] >= 0
    validate_junit(xml)
    assert len(ET.fromstring(xml).findall(".//testcase")) == rep["n_checks"]


# --------------------------------------------------------------------------- mutations
def _mutated(tmp_path, src: Path, mutate: str) -> Path:
    p = tmp_path / src.name
    p.write_text(src.read_text() + "\n[mutate]\n" + mutate + "\n")
    return p


@pytest.mark.parametrize("src, mutate, quantity", [
    (SELFCAL, 'flip_sign = ["EC0Y"]', "EC0Y"),       # a wrong sign in the squareness
    (SELFCAL, 'drop = ["EXC"]', "EXC"),              # the C axis's X location error left out of the model
    (POSITIONING, 'flip_sign = ["reversal"]', "reversal"),
    (POSITIONING, 'drop = ["mean"]', "mean"),
    (POSITIONING, 'scale = { mean = 1.5 }', "mean"),  # a gain error: the means 1.5 x what they are
])
def test_a_mutated_identification_fails_on_that_quantity(tmp_path, capsys, src, mutate, quantity):
    p = _mutated(tmp_path, src, mutate)
    j, x = tmp_path / "r.json", tmp_path / "r.xml"
    assert main(["regress", str(p), "--json", str(j), "--junit", str(x)]) == 1
    rep = json.loads(j.read_text())
    failed = {c["quantity"] for c in rep["checks"] if not c["passed"]}
    assert failed == {quantity}, failed
    for c in rep["checks"]:
        if not c["passed"]:
            assert c["margin"] < 0 and quantity in c["message"] and "margin -" in c["message"]
    xml = x.read_text()
    validate_junit(xml)
    fails = [tc.get("name") for tc in ET.fromstring(xml).iter("testcase") if tc.find("failure") is not None]
    assert fails and all(n.startswith(quantity + " seed") for n in fails)
    out = capsys.readouterr().out
    assert f"FAIL {quantity} (seed" in out and "MUTATED" in out


def test_the_simultaneous_band_still_catches_mutations_of_the_mfb(tmp_path, capsys):
    """The 3-axis MFB study at its shipped within_u95 = "simultaneous" (k_sim ~1.72 over 126 values):
    a flipped squareness, a dropped positioning error and a 1.2 x gain on a pitch each fail, and only they."""
    p = _mutated(tmp_path, MFB3, 'flip_sign = ["EC0Y"]\ndrop = ["EXX"]\nscale = { EBX = 1.2 }')
    j = tmp_path / "r.json"
    assert main(["regress", str(p), "--json", str(j)]) == 1
    rep = json.loads(j.read_text())
    assert {c["quantity"] for c in rep["checks"] if not c["passed"]} == {"EC0Y", "EXX", "EBX"}
    (sim,) = rep["simultaneous"]
    assert sim["values"] == 126 and 1.5 < sim["k_sim"] < 2.0 and rep["mutation"]["scale"] == {"EBX": 1.2}
    assert all("simultaneous, 95% over 126 values" in c["rule"] for c in rep["checks"])
    out = capsys.readouterr().out
    assert "scale EBX x 1.2" in out and "simultaneous band k_sim = " in out


def test_simultaneous_k_known_answers():
    """Independent values: Sidak's k; one value: the normal's 1.96 / 2; values that move together: one
    value's; a U95 estimated from 5 readings (4 degrees of freedom): Student's t_4 97.5 % point / 2;
    the same covariance gives the same k (fixed seed); an estimate without its factor is refused."""
    from scipy import stats

    def est(F, dof=None):
        F = np.asarray(F, float)
        return Estimate(np.zeros(len(F)), np.zeros(len(F)), 2.0 * np.sqrt((F * F).sum(axis=1)), ("v",) * len(F),
                        "um", F, dof)

    n = 40
    k, m = simultaneous_k([est(np.diag(np.linspace(0.1, 3.0, n)))])
    sidak = stats.norm.ppf((1 + 0.95 ** (1 / n)) / 2) / 2
    assert m == n and k == pytest.approx(sidak, abs=0.015)
    assert simultaneous_k([est([[0.7]])])[0] == pytest.approx(stats.norm.ppf(0.975) / 2, abs=0.01)
    together = np.outer(np.linspace(1, 2, n), [1.0, 0.0])  # one source moves all n values
    assert simultaneous_k([est(together)])[0] == pytest.approx(stats.norm.ppf(0.975) / 2, abs=0.01)
    # correlated values lie between the two bounds; two estimates are one family (their rows stacked)
    rho = np.hstack([np.full((n, 1), 0.8), np.diag(np.full(n, 0.6))])
    k2, m2 = simultaneous_k([est(rho[:25]), est(rho[25:])])
    assert m2 == n and stats.norm.ppf(0.975) / 2 + 0.05 < k2 < sidak - 0.05
    regress._SIMULTANEOUS_K.clear()
    assert simultaneous_k([est(rho[:25]), est(rho[25:])]) == (k2, m2)   # drawn again: the fixed seed
    t4 = simultaneous_k([est([[0.5]], np.array([4.0]))])[0]
    assert t4 == pytest.approx(stats.t.ppf(0.975, 4) / 2, abs=0.015)
    # the memo's key holds what the draws read: the same factor without dof, or another factor, is drawn anew
    k1 = simultaneous_k([est([[0.5]])])[0]
    assert k1 == pytest.approx(stats.norm.ppf(0.975) / 2, abs=0.01) and k1 < t4 - 0.1   # (0.98 against 1.39)
    rho2 = rho.copy()
    rho2[0, 0] = 0.0  # the first value now independent of the others
    assert simultaneous_k([est(rho2[:25]), est(rho2[25:])])[0] != k2
    # no seed: another sample of the same band (k within 0.05, five times its sampling error at 1e5 draws)
    assert abs(simultaneous_k([est(rho[:25]), est(rho[25:])], seed=None)[0] - k2) < 0.05
    # a value fixed by a convention (U95 0) is left out of the family
    fixed = est(np.vstack([np.zeros((1, n)), np.diag(np.full(n, 0.3))]))
    assert simultaneous_k([fixed])[1] == n
    with pytest.raises(ValueError, match="without its covariance factor"):
        simultaneous_k([Estimate(np.zeros(2), np.zeros(2), np.ones(2), ("a", "b"), "um")])


def test_simultaneous_k_memo_key_holds_what_the_draws_read(monkeypatch):
    """The memo of simultaneous_k serves a band only for the same factor rows, U95, dof, coverage, draws
    and seed: each other input is drawn anew (the private draws counted, on an empty memo), a repeat is
    served from the memo (no draw), and no seed (fresh entropy) is drawn every time and never kept."""
    from core.memo import Memo

    calls = []
    draw = regress._simultaneous_k

    def counted(*a):
        calls.append(a)
        return draw(*a)

    monkeypatch.setattr(regress, "_simultaneous_k", counted)
    monkeypatch.setattr(regress, "_SIMULTANEOUS_K", Memo(64))
    F = np.array([[0.5, 0.2], [0.1, 0.4], [0.3, 0.3]])

    def est(dof=None):
        return Estimate(np.zeros(3), np.zeros(3), 2.0 * np.sqrt((F * F).sum(axis=1)), ("v",) * 3, "um", F, dof)

    def drawn(*a, **kw):  # (k, whether it was drawn now)
        before = len(calls)
        k = simultaneous_k(*a, **kw)[0]
        assert len(calls) - before in (0, 1)
        return k, len(calls) > before

    k0, new = drawn([est()])
    assert new and drawn([est()]) == (k0, False)   # the same inputs: from the memo
    # the same factor with dof 4 and with dof 10: two bands (t_4 wider than t_10), neither the normal one
    k4, new4 = drawn([est(np.array([4.0, 4.0]))])
    k10, new10 = drawn([est(np.array([10.0, 10.0]))])
    assert new4 and new10 and k4 > k10 + 0.05 > k0 + 0.05   # (1.53, 1.27, 1.12: sampling error about 0.01)
    # another coverage, another number of draws, another seed: drawn anew
    k90, new90 = drawn([est()], coverage=0.9)
    assert new90 and k90 < k0 - 0.1   # (0.96 against 1.12)
    assert drawn([est()], draws=20_000)[1] and drawn([est()], seed=2)[1]
    # no seed: drawn each time, not kept (the fixed seed's band is still the one served)
    assert drawn([est()], seed=None)[1] and drawn([est()], seed=None)[1]
    assert drawn([est()]) == (k0, False)
    # a seed that is not a plain int is not keyed by int(seed): a Generator or a SeedSequence is drawn
    # from (not refused), every call, not kept; 1.5 is refused by numpy, not served the band of seed 1
    for s in (np.random.default_rng(1), np.random.SeedSequence(1)):
        assert drawn([est()], seed=s)[1] and drawn([est()], seed=s)[1]
    k1, _ = drawn([est()], seed=1)
    with pytest.raises(TypeError, match="SeedSequence expects int"):
        simultaneous_k([est()], seed=1.5)
    assert drawn([est()], seed=np.int64(1)) == (k1, False)   # a numpy int is a plain int's key
    assert drawn([est()]) == (k0, False)


def test_check_by_hand_simultaneous():
    """A simultaneous rule compares with k_sim x U95 (given), fails without one, and names k_sim and the count."""
    est = Estimate(np.array([1.0, 2.0]), np.array([1.0, 2.5]), np.array([0.3, 0.3]), ("a", "b"), "um",
                   np.eye(2) * 0.15)
    rule = Rule("EXX", None, None, "um", simultaneous=True)
    assert check(rule, est, 1, 1.7, 2).passed and not check(rule, est, 1, 1.6, 2).passed
    c = check(rule, est, 1, 1.6, 2)
    assert c.limit == pytest.approx(1.6 * 0.3 + GAUGE_FLOOR) and "1.600 x U95 (simultaneous, 95% over 2 values)" in c.rule
    assert check(rule, est, 1).note == "no joint covariance from the identification"


def test_a_dropped_model_term_inside_the_estimator_is_caught(tmp_path, capsys):
    """``planar = true``: the self-calibration itself runs without its height terms (a different estimator,
    not a relabelled output). The spheres stand 25.7 mm above the walls, so the C axis's tilt and the
    tool's Abbe terms go unmodelled into the workpiece (and the tables): the study fails there and the
    C axis's location, which the tilt does not move at the pocket's height, still passes.

    The leak is small: 1.25 x U95 at the worst target on seed 1 (1.34 with the ripple at phase 0 undeclared), beyond each value's own U95 but inside
    the shipped study's simultaneous band (k_sim 1.67 over its 149 values), which it passes. So this
    mutation is checked at 1 x U95 per value (a rule a correct identification of this study also fails
    on 50 of 60 seeds): the simultaneous band does not catch it on this study (README)."""
    one = SELFCAL.read_text().replace('within_u95 = "simultaneous"', "within_u95 = 1.0")
    src = tmp_path / "selfcal-1x.toml"
    src.write_text(one)
    p = _mutated(tmp_path, src, "planar = true")
    j = tmp_path / "r.json"
    assert main(["regress", str(p), "--json", str(j)]) == 1
    checks = {c["quantity"]: c for c in json.loads(j.read_text())["checks"]}
    assert not checks["workpiece"]["passed"] and checks["workpiece"]["margin"] < 0
    assert 1.2 < checks["workpiece"]["deviation"] / checks["workpiece"]["u95"] < 1.67
    assert checks["EXC"]["passed"] and checks["EYC"]["passed"]
    assert "planar model" in capsys.readouterr().out


def test_discover_fails_when_the_hidden_cause_is_not_there(tmp_path):
    """The discover example without its hidden screw error (and no ripple): discover names no cause,
    so the study fails on ``cause``; the check is not satisfied by any campaign."""
    src = (STUDIES / "regress-discover-nmv3000.toml").read_text()
    assert "period_mm = 8.01" in src and "ripple = false" in src
    p = tmp_path / "no-hidden.toml"
    p.write_text(src.replace("periodic = [{ amplitude_um = 1.5, period_mm = 8.01 }]", "slope_um_per_m = 0.0"))
    j = tmp_path / "r.json"
    assert main(["regress", str(p), "--json", str(j)]) == 1
    (c,) = json.loads(j.read_text())["checks"]
    assert c["quantity"] == "cause" and not c["passed"] and "periodic_axis_error not named" in c["message"]


DISCOVER_CLEAN = """
identification = "discover"
machine = "nmv3000"
seeds = [1]
noise_um = 0.3
[injected]
errors = "none"
%s
[plan]
c_angles_deg = [0, 75, 130, 210]
[accept.cause]
%s
"""
SCREW = "[injected.error.EYY]\nperiodic = [{ amplitude_um = 1.5, period_mm = 8.01 }]"


def test_a_discover_naming_every_cause_fails_the_study():
    """review29c's hook (/tmp/review29c/disc_hook.py): a discover that names all 15 catalogue causes passed
    a study expecting one of them. The study now states the whole set: on an error-free machine with only the
    hidden screw, discover names just it (the study passes), and the hook fails it naming the 14 others."""
    from core.causes import names

    study = loads_study(DISCOVER_CLEAN % (SCREW, 'expected = ["periodic_axis_error"]'), "s.toml")
    assert run_study(study).passed
    every = tuple(sorted(names()))
    res = run_study(study, hook=lambda ident, est: {"cause": Causes(every)})
    (c,) = res.checks
    others = [n for n in every if n != "periodic_axis_error"]
    assert not res.passed and len(others) == 14 and c.note.endswith("; not expected: " + ", ".join(others))
    # allowed on purpose (others = "allowed"), it passes, and says so
    loose = loads_study(DISCOVER_CLEAN % (SCREW, 'expected = ["periodic_axis_error"]\nothers = "allowed"'), "s.toml")
    res = run_study(loose, hook=lambda ident, est: {"cause": Causes(every)})
    assert res.passed and res.checks[0].rule == "names periodic_axis_error (others allowed)"


@pytest.mark.parametrize("expected", ["expected = []", 'expected = "none"'])
def test_an_effect_free_study_fails_on_any_finding(expected):
    """No hidden effect (errors none, probing noise 0.3 um): discover names nothing (seeds 1-20 all, rf29), the
    study expecting no cause passes; a finding injected into the same run fails it, named."""
    study = loads_study(DISCOVER_CLEAN % ("", expected), "s.toml")
    res = run_study(study)
    assert res.passed and res.checks[0].note == "named no cause" and res.checks[0].rule == "names no cause"
    res = run_study(study, hook=lambda ident, est: {"cause": Causes(est["cause"].named + ("outlier",))})
    assert not res.passed and res.checks[0].note == "named outlier; not expected: outlier"


def test_the_flip_is_exactly_a_negation(tmp_path):
    """The hook sees the identification's values: a sign flip negates the identified quantity, nothing else."""
    study = load_study(POSITIONING)
    study = replace(study, seeds=(1,))
    base = run_study(study)
    flipped = run_study(study, hook=Mutation(flip_sign=("mean",)))
    b, f = base.estimates[1], flipped.estimates[1]
    assert np.array_equal(f["mean"].identified, -b["mean"].identified)
    assert np.array_equal(f["mean"].injected, b["mean"].injected)
    assert np.array_equal(f["reversal"].identified, b["reversal"].identified)


def test_a_missing_simultaneous_quantity_is_named_in_the_others_verdicts():
    """No joint band when one simultaneous quantity is missing: the others fail naming it (they were told they
    had no joint covariance, which was not so)."""
    study = replace(load_study(POSITIONING), seeds=(1,))
    res = run_study(study, hook=lambda ident, est: {q: e for q, e in est.items() if q != "reversal"})
    (mean,) = [c for c in res.checks if c.quantity == "mean"]
    assert not mean.passed and mean.note == "no joint band: reversal has no joint covariance"


# --------------------------------------------------------------------------- pytest face
def test_assert_recovers_names_the_quantity_and_margin():
    study = replace(load_study(POSITIONING), seeds=(2,))
    res = assert_recovers(study)
    assert res.passed
    with pytest.raises(AssertionError, match=r"reversal \(seed 2\) at P=.*exceeds <= 1.9\d\d x U95 \(simultaneous, 95% over 12 values\) = .*margin -"):
        assert_recovers(study, hook=Mutation(flip_sign=("reversal",)))


@pytest.mark.parametrize("regress_study", [str(POSITIONING)], indirect=True)
def test_the_fixture_gives_the_result(regress_study):
    assert regress_study.passed and regress_study.study.identification == "iso230-2"


# --------------------------------------------------------------------------- known answers
def test_check_by_hand():
    est = Estimate(np.array([1.0, 2.0, 0.0]), np.zeros(3), np.array([4.0, 1.0, 0.0]), ("a", "b", "c"), "um")
    c = check(Rule("EXX", 1.0, None, "um"), est, 7)
    # deviations 1, 2, 0 against limits 4, 1, 0 (+ floor): b is the worst, failed by 1 um
    assert not c.passed and c.where == "b" and c.margin == pytest.approx(-1.0 + GAUGE_FLOOR)
    assert c.message().startswith("EXX (seed 7) at b: |identified - injected| = |2 - 0| = 2 um exceeds")
    c = check(Rule("EXX", None, 2.5, "um"), est, 7)
    assert c.passed and c.where == "b" and c.margin == pytest.approx(0.5)
    # an element fixed by the ISO convention (U95 0) must match to the rounding of the gauge transform
    fixed = Estimate(np.array([0.0]), np.array([1e-14]), np.array([0.0]), ("EXX@0",), "um")
    assert check(Rule("EXX", 1.0, None, "um"), fixed, 1).passed
    off = Estimate(np.array([0.0]), np.array([1e-3]), np.array([0.0]), ("EXX@0",), "um")
    assert not check(Rule("EXX", 1.0, None, "um"), off, 1).passed
    assert check(Rule("EXX", 1.0, None, "um"), None, 1).note == "not identified"
    rule = Rule("cause", None, None, "cause", ("periodic_axis_error",))
    assert check(rule, Causes(("periodic_axis_error",)), 1).passed
    c = check(rule, Mutation(drop=("cause",))("discover", {"cause": Causes(("periodic_axis_error",))})["cause"], 1)
    assert not c.passed and c.message() == "cause (seed 1): named no cause; expected periodic_axis_error not named"
    # the expected set is the whole set: a cause beyond it fails, named (once however often it is named)
    c = check(rule, Causes(("probe_lobing", "periodic_axis_error", "probe_lobing")), 1)
    assert not c.passed and c.note == ("named probe_lobing, periodic_axis_error, probe_lobing; not expected: "
                                       "probe_lobing")
    c = check(rule, Causes(("outlier",)), 1)
    assert c.note == "named outlier; expected periodic_axis_error not named; not expected: outlier"
    assert check(replace(rule, others_allowed=True), Causes(("probe_lobing", "periodic_axis_error")), 1).passed
    none = Rule("cause", None, None, "cause", ())
    assert check(none, Causes(()), 1).passed and none.text() == "names no cause"
    assert not check(none, Causes(("unexplained",)), 1).passed


def test_positioning_truth_by_hand():
    """Noise free, only EXX = 40 um/m and 3 um of lost motion: the mean deviation at P is 0.04 um/mm * P
    and every reversal value 3 um, by hand; identified and injected both equal it."""
    s = loads_study("""
        identification = "iso230-2"
        machine = "vmc-3axis"
        seeds = [0]
        noise_um = 0
        [injected.error.EXX]
        slope_um_per_m = 40.0
        reversal_um = 3.0
        [plan]
        targets = 5
        [accept.mean]
        tolerance_um = 1e-6
        [accept.reversal]
        tolerance_um = 1e-6
        [accept.B]
        tolerance_um = 1e-6
        [accept.M]
        tolerance_um = 1e-6
    """, "by-hand")
    res = run_study(s)
    assert res.passed, [c.message() for c in res.failures]
    e = res.estimates[0]
    P_mm = np.array([float(x[2:-2]) for x in e["mean"].labels])
    assert np.allclose(e["mean"].injected, 0.04 * P_mm, atol=1e-9)
    assert np.allclose(e["reversal"].injected, 3.0, atol=1e-9)
    assert e["M"].injected[0] == pytest.approx(0.04 * np.ptp(P_mm), abs=1e-9)


# --------------------------------------------------------------------------- bad input
BASE = 'identification = "iso230-2"\nmachine = "vmc-3axis"\nseeds = [1]\n[accept.mean]\nwithin_u95 = 1.0\n'
DISC = BASE.replace('"iso230-2"', '"discover"').replace("[accept.mean]\nwithin_u95 = 1.0", "[accept.cause]\nexpected = []")
SC = (BASE.replace('"iso230-2"', '"selfcal"').replace("[accept.mean]", "[accept.EXX]")
      .replace('"vmc-3axis"', '"nmv3000"').replace("within_u95 = 1.0", 'within_u95 = "simultaneous"'))


@pytest.mark.parametrize("text, match", [
    ("x = ", "not TOML"),
    ("colour = 1\n" + BASE, "colour: unknown key"),
    (BASE.replace('"iso230-2"', '"dicsover"'), "identification: expected one of"),
    (BASE.replace('"iso230-2"', '"discover"'), "accept.mean: unknown quantity for discover"),
    (DISC.replace("expected = []", "expected = [1]"), "accept.cause.expected: expected a cause name"),
    (DISC.replace("expected = []", 'expected = ["none"]'), "accept.cause.expected: expected a cause name"),
    (DISC.replace("expected = []", 'expected = ""'), "accept.cause.expected: expected a cause name"),
    (DISC.replace("expected = []", 'expected = ["x"]\nothers = "some"'), 'accept.cause.others: expected "allowed"'),
    (DISC.replace("expected = []", 'expected = []\nothers = "allowed"'), "accept.cause: expected = .* nothing can fail"),
    (DISC.replace("expected = []", 'expected = ["x"]\nallowed = ["y"]'), "accept.cause.allowed: unknown key"),
    (DISC.replace("expected = []", 'others = "allowed"'), "accept.cause: missing: expected"),
    (DISC + '[mutate]\ndrop = ["cause"]\n', "mutate.drop: the study expects no cause"),
    (BASE.replace("seeds = [1]", "seeds = []"), "seeds: missing"),
    (BASE.replace("seeds = [1]", "seeds = [1, 1]"), "seeds: a seed given twice"),
    (BASE.replace("seeds = [1]", 'seeds = ["a"]'), r"seeds\[0\]: expected an integer"),
    (BASE.replace('"vmc-3axis"', '"nope.toml"'), "machine: 'nope.toml': no such machine file"),
    (BASE + "[accept.EXX]\ntolerance_um = 1\n", "accept.EXX: unknown quantity for iso230-2"),
    (BASE + "[accept.E]\nwithin_u95 = 1\n", "accept.E.within_u95: E has no U95"),
    (BASE + "[accept.M]\ntolerance_urad = 1\n", "accept.M.tolerance_urad: unknown key"),
    (BASE + "[accept.B]\ntolerance_um = -1\n", "accept.B.tolerance_um: must be > 0"),
    ("noise_um = 0\n" + BASE, "within_u95: needs probing noise"),
    (BASE + "[plan]\naxis = \"A\"\n", "plan.axis: expected X, Y or Z"),
    (BASE + "[plan]\nc_angles_deg = [0, 90]\n", "plan.c_angles_deg: unknown key for iso230-2"),
    (BASE + "[mutate]\nflip_sign = [\"EXX\"]\n", "mutate.flip_sign: unknown quantity 'EXX'"),
    (BASE + "[plan]\ndeclared_ripple = { EXX = [0.4, 10] }\n", "plan.declared_ripple: unknown key for iso230-2"),
    (SC + "[plan]\ndeclared_ripple = { EZZ = [0.4, 10] }\n", "plan.declared_ripple.EZZ: not a table"),
    (SC + "[plan]\ndeclared_ripple = { EXX = [0.4] }\n", r"plan.declared_ripple.EXX: expected \[amplitude"),
    (SC + "[plan]\ndeclared_ripple = { EXX = [0.4, 0] }\n", "plan.declared_ripple.EXX: expected amplitude >= 0 and"),
    (SC + "[plan]\ndeclared_ripple = { EXX = [\"a\", 10] }\n", r"plan.declared_ripple.EXX\[0\]"),
    (SC + "[plan]\ndeclared_ripple = 3\n", "plan.declared_ripple: expected a table"),
    (SC + "[plan]\ndeclared_ripple = { EXX = [0.38, 10], ECY = [0.15, 10] }\n", None),
    (BASE + "[mutate]\nplanar = true\n", "mutate.planar: only for the self-calibration"),
    (BASE + "[injected.error.EXX]\nslope_um = 1\n", "error.EXX"),
    (BASE.replace("[accept.mean]\nwithin_u95 = 1.0\n", ""), "accept: missing"),
    (BASE.replace("within_u95 = 1.0", 'within_u95 = "joint"'), 'accept.mean.within_u95: expected a number or "simultaneous"'),
    (BASE.replace("within_u95 = 1.0", 'within_u95 = "simultaneous"').replace('"iso230-2"', '"selfcal"').replace(
        "[accept.mean]", "[accept.EXX]").replace('"vmc-3axis"', '"nmv3000"'), None),
    (BASE + "[mutate]\nscale = { mean = \"x\" }\n", "mutate.scale.mean: expected a finite number"),
    (BASE + "[mutate]\nscale = { EXX = 2 }\n", "mutate.scale: unknown quantity 'EXX'"),
    # main: "identification: expected one of selfcal, ..., got None" of an empty file or a missing key
    ("", "s.toml: empty study"),
    ("# nothing but a comment\n", "s.toml: empty study"),
    (BASE.replace('identification = "iso230-2"\n', ""), "identification: missing"),
])
def test_bad_studies_are_refused_with_the_key(text, match):
    if match is None:  # the good twin of a refused study: read without complaint
        assert loads_study(text, "s.toml").rules[0].simultaneous
        return
    with pytest.raises(StudyError, match=match) as e:
        loads_study(text, "s.toml")
    assert "\n" not in str(e.value)


def test_bad_study_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys):
    p = tmp_path / "s.toml"
    p.write_text("colour = 1\n" + BASE)
    j = tmp_path / "r.json"
    assert main(["regress", str(p), "--json", str(j)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "colour: unknown key" in err and "Traceback" not in err
    assert not j.exists()
    assert main(["regress", str(tmp_path / "none.toml")]) == 2


def test_junit_of_a_failed_run_names_the_failure():
    s = replace(load_study(POSITIONING), seeds=(1,))
    xml = junit_xml(run_study(s, hook=Mutation(drop=("mean",))), timestamp="2026-01-02T03:04:05", hostname="ci x")
    validate_junit(xml)
    suite = ET.fromstring(xml).find("testsuite")
    assert suite.get("hostname") == "ci x" and suite.get("failures") == "1" and suite.get("tests") == "5"
    f = suite.find("testcase[@name='mean seed 1']/failure")
    assert f is not None and "mean (seed 1)" in f.get("message") and "margin -" in f.text


# --------------------------------------------------------------------------- power (review31b F4)
def test_power_by_hand():
    """The detection limit per value: (k + POWER_Z / 2) x U95 + GAUGE_FLOOR for a U95 rule (k_sim for a
    simultaneous one), t + POWER_Z / 2 x U95 for a tolerance with a U95, 2 t without one; the flip ratio is
    max 2 |injected| / limit, at the value where it is largest; a cause, a simultaneous rule without its band
    and a non-finite truth state nothing."""
    from scenarios.regress import POWER_Z, power

    U = np.array([1.0, 0.0, 5.0])
    est = Estimate(np.array([1.0, 0.0, -1.5]), np.array([0.5, 0.0, -2.0]), U, ("a", "b", "c"), "um", np.eye(3))
    z2 = POWER_Z / 2
    p = power(Rule("EXX", None, None, "um", simultaneous=True), est, 7, k_sim=1.7)
    lim = (1.7 + z2) * U + GAUGE_FLOOR
    assert np.allclose(p.limits, lim, rtol=0, atol=1e-15) and p.seed == 7 and p.quantity == "EXX"
    assert p.flip_ratio == pytest.approx(2 * 0.5 / lim[0]) and p.where == "a" and not p.sign_testable
    assert p.smallest == (pytest.approx(GAUGE_FLOOR), "b")      # a value the convention fixes: caught above the floor
    big = est.replaced(injected=np.array([0.5, 0.0, -7.0]))
    p = power(Rule("EXX", None, None, "um", simultaneous=True), big, 7, k_sim=1.7)
    assert p.flip_ratio == pytest.approx(14.0 / lim[2]) and p.where == "c" and p.sign_testable
    j = p.to_json()
    assert j["detection_limit"] == pytest.approx(list(lim)) and j["sign_testable"] is True and j["power"] == 0.95
    assert j["detection_limit_min_where"] == "b" and j["injected_max_abs"] == 7.0
    p = power(Rule("EXX", 1.0, None, "um"), est, 1)
    assert np.allclose(p.limits, (1.0 + z2) * U + GAUGE_FLOOR, rtol=0, atol=1e-15)
    p = power(Rule("EXX", None, 0.5, "um"), est, 1)
    assert np.allclose(p.limits, 0.5 + z2 * U, rtol=0, atol=1e-15)
    p = power(Rule("E", None, 0.5, "um"), est.replaced(u95=None), 1)
    assert np.allclose(p.limits, 1.0) and "every run that passed" in p.method
    assert power(Rule("EXX", None, None, "um", simultaneous=True), est, 1) is None   # no band: check fails it
    assert power(Rule("cause", None, None, "cause", ("x",)), Causes(("x",)), 1) is None
    assert power(Rule("EXX", 1.0, None, "um"), None, 1) is None
    assert power(Rule("EXX", 1.0, None, "um"), est.replaced(injected=np.array([np.nan, 0, 0])), 1) is None


def test_the_detection_limit_is_caught_with_the_stated_probability():
    """Truth -> noise -> check: a value whose error is normal with standard deviation U95 / 2, moved by its
    detection limit (k + POWER_Z / 2) x U95, fails |e + d| <= k x U95 on 95 % of draws (200,000 draws:
    binomial standard error 0.05 %, checked to 0.3 %); moved by k x U95 only (the band) on about half."""
    from scenarios.regress import DETECTION_POWER, POWER_Z

    rng = np.random.default_rng(31)
    U, k = 2.0, 1.718
    e = rng.normal(0.0, U / 2, 200_000)
    d = (k + POWER_Z / 2) * U
    assert np.mean(np.abs(e + d) > k * U) == pytest.approx(DETECTION_POWER, abs=3e-3)
    assert np.mean(np.abs(e - d) > k * U) == pytest.approx(DETECTION_POWER, abs=3e-3)
    assert np.mean(np.abs(e + k * U) > k * U) == pytest.approx(0.5, abs=3e-3)


#: The quantities whose sign each shipped study cannot test on seed 1 (its power, review31b F4): a flipped sign
#: moves no value by its detection limit. Session 31 raised the injected errors where the machine allows
#: (the study files say which and why); before, 3-axis EAX EXY EXZ EYZ ECZ EA0Z, 5-axis EYX EAX EXY EBY ECY
#: EYZ EAZ ECZ EC0Y, self-calibration EXX EYX EXY ECY.
SIGN_UNTESTABLE = {"regress-mfb-3axis-vmc": set(), "regress-mfb-5axis-mikron": {"EAX", "EYZ"},
                   "regress-selfcal-nmv3000": {"ECY"}, "regress-iso230-2-vmc-x": set()}


@pytest.mark.parametrize("stem", sorted(SIGN_UNTESTABLE))
def test_each_example_states_its_power(example_runs, stem):
    """The JSON carries each checked quantity's detection limits (one per value, in its unit) and whether its sign
    is testable; the shipped studies can test every sign but the ones named in README's regression section."""
    rc, rep, _ = example_runs[stem]
    seeds = rep["seeds"]
    power = rep["power"]
    assert len(power) == len(seeds) * len([c for c in rep["checks"] if c["seed"] == seeds[0]])
    for p in power:
        assert len(p["detection_limit"]) == len(p["labels"]) >= 1 and p["power"] == 0.95
        assert min(p["detection_limit"]) == p["detection_limit_min"] > 0
        assert p["sign_testable"] == (p["flip_ratio"] >= 1.0)
    for sd in seeds:
        assert {p["quantity"] for p in power if p["seed"] == sd and not p["sign_testable"]} == SIGN_UNTESTABLE[stem]


@pytest.mark.parametrize("src, flips, caught", [
    # review31b's mut3.toml: these three flips passed the band (exit 0) with seed 3's drawn errors
    (MFB3, ["EXZ", "EYZ", "ECZ"], {"EXZ", "EYZ", "ECZ"}),
    # review31b's mutsc.toml: EXX now caught; ECY's sign stays untestable, named as such, and its flip passes
    (SELFCAL, ["EXX", "ECY"], {"EXX"}),
    (STUDIES / "regress-mfb-5axis-mikron.toml", ["EAX", "EBY", "EYZ", "ECZ", "EC0Y"], {"EBY", "ECZ", "EC0Y"}),
])
def test_a_flip_is_caught_where_the_power_says_the_sign_is_testable(tmp_path, capsys, src, flips, caught):
    """Known answer by the mutation itself: each flipped quantity fails the study exactly when the study's power
    calls its sign testable, and the untestable ones are named in one printed line."""
    p = _mutated(tmp_path, src, "flip_sign = " + json.dumps(flips))
    j = tmp_path / "r.json"
    assert main(["regress", str(p), "--json", str(j)]) == 1
    rep = json.loads(j.read_text())
    assert {c["quantity"] for c in rep["checks"] if not c["passed"]} == caught
    testable = {q["quantity"] for q in rep["power"] if q["sign_testable"]}
    assert set(flips) & testable == caught
    out = capsys.readouterr().out
    (line,) = [ln for ln in out.splitlines() if "sign " in ln and "testable" in ln]
    missed = sorted(set(flips) - caught)
    if missed:
        assert line.startswith("seed 1: sign not testable on ") and all(f"{q} (" in line for q in missed)
    else:
        assert line.startswith("seed 1: sign testable on all 21 quantities")


@pytest.fixture(scope="module")
def shipped_runs():
    """run_study of the 3-axis MFB and the self-calibration studies as shipped (seed 1), once for the module."""
    return {"mfb3": run_study(load_study(MFB3)), "selfcal": run_study(load_study(SELFCAL))}


def test_every_flip_of_the_3axis_study_agrees_with_its_power(shipped_runs):
    """The 3-axis MFB study, each of its 21 quantities flipped on its own (the study's own check and band): every
    flip fails the study, and the power calls every sign testable (with seed 3's drawn errors EXZ, EYZ and ECZ
    passed flipped: review31b F4)."""
    res = shipped_runs["mfb3"]
    (seed, k_sim, n), = res.simultaneous
    est = res.estimates[seed]
    for r in res.study.rules:
        flipped = Mutation(flip_sign=(r.quantity,))(res.study.identification, est)[r.quantity]
        assert not check(r, flipped, seed, k_sim, n).passed, r.quantity
    assert all(p.sign_testable for p in res.power) and len(res.power) == 21


# --------------------------------------------------------------------------- gain power (review33a F10)
def test_smallest_gain_by_hand():
    """The smallest gain caught with 95 % power is min_i limit_i / |injected_i| = 2 / flip_ratio; a quantity whose
    injected values are all 0 has none (inf, JSON null); the printed line sorts by it and counts the quantities
    a 10 % and a 20 % gain can pass."""
    from scenarios.regress import POWER_Z, StudyResult, power

    U = np.array([1.0, 2.0, 0.5])
    inj = np.array([10.0, -40.0, 1.0])
    est = Estimate(inj + 0.1, inj, U, ("a", "b", "c"), "um", np.eye(3))
    p = power(Rule("EXX", None, None, "um", simultaneous=True), est, 1, k_sim=1.7)
    lim = (1.7 + POWER_Z / 2) * U + GAUGE_FLOOR
    assert p.smallest_gain == pytest.approx(min(lim / np.abs(inj))) == pytest.approx(2 / p.flip_ratio)
    assert p.smallest_gain == pytest.approx(lim[1] / 40.0) and p.to_json()["smallest_gain_error"] == p.smallest_gain
    z = power(Rule("EYY", None, None, "um", simultaneous=True), est.replaced(injected=np.zeros(3)), 1, k_sim=1.7)
    assert z.smallest_gain == np.inf and z.to_json()["smallest_gain_error"] is None
    big = power(Rule("EBX", None, None, "um", simultaneous=True), est.replaced(injected=inj * p.smallest_gain / 0.8),
                1, k_sim=1.7)  # caught at 80 %: between 20 % and 100 %
    res = StudyResult(None, (), (), power=(z, p, big))
    (line,) = res.gain_power()
    assert line.startswith("seed 1: smallest gain error caught with 95% power")
    assert line.index("EXX") < line.index("EBX") < line.index("EYY") and "EYY none (injected 0)" in line
    assert big.smallest_gain == pytest.approx(0.8) and "EXX 13 %" in line and "EBX 80 %" in line
    assert line.endswith("a gain error of 10% can pass on 3 of 3; a gain error of 20% can pass on 2 of 3"), line


#: review33a's plants (F10): (study, quantity, gain factor, failed as seen by the reviewer). The 3-axis ones scaled
#: the identified error in scenarios/mfb.py (the reported values: what [mutate] scale does), EXY x 0 is a drop.
REVIEW33A_PLANTS = [
    ("mfb3", "EXX", 1.01, False), ("mfb3", "EBX", 1.01, False), ("mfb3", "EXX", 1.05, True),
    ("mfb3", "EXX", 1.10, True), ("mfb3", "EYY", 1.10, True), ("mfb3", "EC0Y", 1.4, True),
    ("mfb3", "EXY", 0.0, True), ("mfb3", "EAZ", 0.5, False), ("mfb3", "EYZ", 0.5, False),
    ("selfcal", "EXX", 1.05, False), ("selfcal", "EXX", 1.2, False), ("selfcal", "EYY", 1.05, False),
    ("selfcal", "EYY", 1.2, True), ("selfcal", "EC0Y", 1.2, False), ("selfcal", "workpiece", 1.05, True),
]


@pytest.mark.parametrize("which, q, factor, failed", REVIEW33A_PLANTS)
def test_the_stated_gain_power_agrees_with_review33as_plants(shipped_runs, which, q, factor, failed):
    """Known answers from outside the code (review33a's 15 plants through the tool's own check): each plant fails
    or passes as the reviewer saw, and never against the stated power: a gain at or above the stated smallest
    gain fails (the statement is a 95 % lower bound on the power, so a smaller gain may fail too: EYY x 1.2
    on the self-calibration, 20 % against a stated 39 %)."""
    res = shipped_runs[which]
    (seed, k_sim, n), = res.simultaneous
    (rule,) = [r for r in res.study.rules if r.quantity == q]
    (pw,) = [p for p in res.power if p.quantity == q]
    est = Mutation(scale=((q, factor),))(res.study.identification, res.estimates[seed])[q]
    c = check(rule, est, seed, k_sim, n)
    assert (not c.passed) == failed, c.message()
    if abs(factor - 1.0) >= pw.smallest_gain:
        assert not c.passed, (q, factor, pw.smallest_gain)


def test_the_printed_gain_power_of_the_3axis_study(shipped_runs, capsys, tmp_path):
    """vmt regress prints the gain line and the JSON holds each quantity's smallest gain; on the 3-axis study seed 1
    a 20 % gain is caught with 95 % power on EXX, EBX, EYY and ECX only (review33a F10: 6, 7, 11, 17 %)."""
    res = shipped_runs["mfb3"]
    g = {p.quantity: p.smallest_gain for p in res.power}
    assert {q for q, v in g.items() if v <= 0.2} == {"EXX", "EBX", "EYY", "ECX"}
    assert g["EXX"] == pytest.approx(0.06, abs=0.01) and g["EBX"] == pytest.approx(0.07, abs=0.01)
    (line,) = res.gain_power()
    assert "a gain error of 20% can pass on 17 of 21" in line and line.index("EXX") < line.index("EYZ")


# --------------------------------------------------------------------------- pinned U95 (review33a F1)
def test_max_u95_by_hand():
    """max_u95: a deviation inside its band still fails when the largest U95 exceeds the pin, the note naming the
    U95, where, the pin and the deviation; at the pin it passes; without a U95 it cannot be held, so it fails."""
    est = Estimate(np.array([1.0, 2.0]), np.array([1.1, 2.0]), np.array([0.3, 0.5]), ("a", "b"), "um", np.eye(2))
    rule = Rule("EXX", None, None, "um", simultaneous=True, max_u95=0.4)
    c = check(rule, est, 1, 1.7, 2)
    assert not c.passed and c.margin > 0
    assert c.note.startswith("U95 at b = 0.5 um exceeds the study's max_u95_um 0.4 (x 1.25)") and "0.1 um at a" in c.note
    assert c.message().startswith("EXX (seed 1): U95 at b") and "max_u95" not in c.rule
    assert check(replace(rule, max_u95=0.5), est, 1, 1.7, 2).passed
    assert not check(Rule("EXX", 1.0, None, "um", max_u95=0.4), est, 1).passed
    c = check(Rule("EXX", None, 1.0, "um", max_u95=0.4), est.replaced(u95=None), 1)
    assert not c.passed and c.note.startswith("no U95 from the identification")
    # a deviation beyond the band is reported as such (its figures), whatever the U95
    c = check(rule, est.replaced(identified=np.array([3.0, 2.0])), 1, 1.7, 2)
    assert not c.passed and c.note == "" and c.margin < 0


@pytest.mark.parametrize("text, match", [
    (BASE.replace("within_u95 = 1.0", "within_u95 = 1.0\nmax_u95_um = 0"), "accept.mean.max_u95_um: must be > 0"),
    (BASE.replace("within_u95 = 1.0", "within_u95 = 1.0\nmax_u95_urad = 1"), "accept.mean.max_u95_urad: unknown key"),
    (BASE.replace("within_u95 = 1.0", "max_u95_um = 1"), "accept.mean: expected exactly one of within_u95"),
    (BASE + "[accept.E]\ntolerance_um = 1\nmax_u95_um = 1\n", "accept.E.max_u95_um: E has no U95"),
])
def test_bad_max_u95_is_refused_with_the_key(text, match):
    with pytest.raises(StudyError, match=match):
        loads_study(text, "s.toml")
    good = loads_study(BASE.replace("within_u95 = 1.0", "within_u95 = 1.0\nmax_u95_um = 0.7"), "s.toml")
    assert good.rules[0].max_u95 == 0.7 and good.rules[0].k == 1.0


def _planted(est: dict, gain: dict, u_scale: float = 1.0, factor_scale: float | None = None) -> dict:
    """review33a's plants on a run's estimates: a gain per quantity, every U95 times ``u_scale`` and the covariance
    factor times ``factor_scale`` (default: the same, a consistent inflation)."""
    fs = u_scale if factor_scale is None else factor_scale
    return {q: e.replaced(identified=gain.get(q, 1.0) * e.identified, u95=u_scale * e.u95, factor=fs * e.factor)
            for q, e in est.items()}


def test_an_inflated_u95_hiding_a_gain_error_fails_the_shipped_study(shipped_runs, monkeypatch):
    """review33a F1 as a unit test (monkeypatched run): EXX x 1.10 with every U95 and the covariance x 3 passed the
    3-axis study (its band k_sim x U95 comes from the run under test); with the shipped max_u95 pins it fails,
    every quantity on its U95 note, and without them (the pins taken out) it still passes, which is the hole."""
    res = shipped_runs["mfb3"]
    (seed, k_sim, _), = res.simultaneous
    base = res.estimates[seed]
    study = res.study
    assert all(r.max_u95 is not None for r in study.rules)
    monkeypatch.setitem(regress.RUNNERS, "mfb-3axis", lambda st, sd: _planted(base, {"EXX": 1.10}, 3.0))
    bad = run_study(study)
    assert not bad.passed and {c.quantity for c in bad.failures} == {r.quantity for r in study.rules}
    (exx,) = [c for c in bad.checks if c.quantity == "EXX"]
    assert "exceeds the study's max_u95_um" in exx.note and exx.margin > 0   # inside the inflated band
    assert bad.simultaneous[0][1] == pytest.approx(k_sim, abs=1e-9)        # a consistent inflation: the same k_sim
    unpinned = replace(study, rules=tuple(replace(r, max_u95=None) for r in study.rules))
    assert run_study(unpinned).passed
    # the same gain error at the run's own U95 fails on EXX alone, on its deviation
    monkeypatch.setitem(regress.RUNNERS, "mfb-3axis", lambda st, sd: _planted(base, {"EXX": 1.10}))
    r = run_study(study)
    assert {c.quantity for c in r.failures} == {"EXX"} and r.failures[0].margin < 0


def test_the_shipped_pins_hold_every_u95_quantity():
    """Every quantity with a U95 in the MFB, self-calibration and ISO 230-2 studies is pinned (review33a F1)."""
    for p in (MFB3, STUDIES / "regress-mfb-5axis-mikron.toml", SELFCAL, POSITIONING):
        s = load_study(p)
        pinned = {r.quantity for r in s.rules if r.max_u95 is not None}
        assert pinned == {r.quantity for r in s.rules if r.quantity not in ("E", "M", "B")}, p.name


# --------------------------------------------------------------------------- a band not drawn from its U95 (F2)
def test_sidak_k_known_answers():
    """One value: Phi^-1(0.975) / 2 = 0.98; 126 independent values: 1.768 (README, review33a)."""
    from scenarios.regress import sidak_k

    assert sidak_k(1) == pytest.approx(1.959964 / 2, abs=1e-6)
    assert sidak_k(126) == pytest.approx(1.768, abs=1e-3)


def test_band_consistency_by_hand():
    """A U95 = 2 sqrt(diag F F^T) band is trusted; a U95 computed apart (x 10) is named with its ratio; a k_sim
    below one value's or above Sidak's is named; with estimated scales (dof) only the U95 is checked."""
    from scenarios.regress import band_consistency, sidak_k

    F = np.array([[0.3, 0.1], [0.0, 0.2]])
    U = 2 * np.sqrt((F ** 2).sum(axis=1))
    est = {"EXX": Estimate(np.zeros(2), np.zeros(2), U, ("a", "b"), "um", F)}
    assert band_consistency(est, 1.05, 2) == ""
    ten = {"EXX": est["EXX"].replaced(u95=U * np.array([1.0, 10.0]))}
    assert band_consistency(ten, 1.05, 2).startswith("U95 is not 2 sqrt(diag) of the joint covariance") and \
        "EXX (10 x at b)" in band_consistency(ten, 1.05, 2)
    assert "k_sim 0.571 lies outside [0.980, " in band_consistency(est, 0.571, 2)
    assert "lies outside" in band_consistency(est, sidak_k(2) + 0.05, 2)
    assert band_consistency(est, sidak_k(2) + 0.01, 2) == ""          # inside the slack (Monte Carlo error)
    dof = {"mean": est["EXX"].replaced(dof=np.array([4.0, 4.0]))}
    assert band_consistency(dof, 2.1, 2) == ""                        # studentized: wider than Sidak's, allowed


def test_a_u95_not_drawn_from_the_covariance_fails_the_run(shipped_runs, monkeypatch):
    """review33a F2: the U95 x 10 and the covariance not (a noise model changed in one place): k_sim fell to 0.571
    and nothing said so. Now every simultaneous check fails, naming the band's fault, and the exit is 1."""
    res = shipped_runs["mfb3"]
    (seed, _, _), = res.simultaneous
    base = res.estimates[seed]
    study = replace(res.study, rules=tuple(replace(r, max_u95=None) for r in res.study.rules))
    monkeypatch.setitem(regress.RUNNERS, "mfb-3axis", lambda st, sd: _planted(base, {}, 10.0, 1.0))
    bad = run_study(study)
    assert len(bad.failures) == 21 and bad.simultaneous[0][1] < 0.98
    assert all(c.note.startswith("simultaneous band not trusted: U95 is not 2 sqrt(diag)") for c in bad.failures)
    assert "k_sim 0." in bad.failures[0].note and "lies outside [0.980, 1.768]" in bad.failures[0].note
    assert "EXX (10 x at EXX@" in bad.failures[0].note and ", 18 more quantities; k_sim" in bad.failures[0].note
