"""The compensation closed through the exact simulator: a good machine is not made worse beyond the
stated residual U95, a machine with real errors still improves (review of session 26: applying every
identified value took mfb-3axis --errors none from 0 to X/Y/Z 2.75/1.43/2.27 um)."""

import json

import numpy as np
import pytest

from scenarios import mfb
from scenarios.comprule_study import FIVE_ERRORS as MIX  # session 26's review machine: five errors
from sim.machinefile import truth_machine


def _loop(tmp_path, spec, seed, force_whole=False):
    """The volumetric controller alone (its JSON; the .comp files removed), noise as the probe's. Each caller takes
    conftest's ``mfb_notes_skipped``: what these tests read (the JSON's errors, U95 and applied factors, the loop's
    checks) is the same doubles without the runs' two notes, at about 40 % of a noisy run's CPU."""
    kw = dict(machine=spec, mc_runs=0)
    r = mfb.run("mfb-3axis", seed=seed, **kw)
    d = tmp_path / f"c{seed}"
    for p in r.write_comp(d):
        if p.suffix == ".comp":
            p.unlink()
    if force_whole:  # the rule before session 26: every identified value applied
        pj = d / "mfb-3axis-comp.json"
        doc = json.loads(pj.read_text())
        for e in doc["errors"].values():
            e["applied_factor"] = 1.0
        pj.write_text(json.dumps(doc))
    return r, mfb.closed_loop("mfb-3axis", d, before=r, seed=seed, **kw)


def _own(errors):
    return truth_machine(mfb.PLANS["mfb-3axis"]().machine, errors, "study")


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_perfect_machine_is_not_made_worse_beyond_the_stated_u95(tmp_path, mfb_notes_skipped, seed):
    """--errors none, three seeds: the exact tip deviation after the volumetric table stays within the
    U95 the compensation file states for what is left (not_worse on every axis), every point's
    residual within the prediction's U95 at >= 90 % of the 504 points (a 95 % interval; the points of
    one axis move together), and no axis above 1 um at these seeds (seeds 1-8, first-order study in
    docs/papers-mfb.md: worst axis 0.40-2.29 um after this rule, seed 4's Z the largest; 1.13-3.63 um
    after every value)."""
    r, loop = _loop(tmp_path, _own("none"), seed)
    v = loop["volumetric"]["volumetric_check"]
    stated = json.loads((tmp_path / f"c{seed}" / "mfb-3axis-comp.json").read_text())["predicted_residual"]
    for a in "XYZ":
        assert v[a]["before_max_um"] < 1e-6
        assert v[a]["not_worse"] and v[a]["after_max_um"] <= stated["volumetric"][a]["u95_max_um"], (a, v[a])
        k, n = (int(t) for t in v[a]["within_u95"].split("/"))
        assert n == 504 and k >= 0.9 * n, (a, v[a])
        assert v[a]["after_max_um"] < 1.0, (a, v[a])


def test_applying_every_value_would_fail_the_check_on_the_perfect_machine(tmp_path, mfb_notes_skipped):
    """The check can fail: the old rule (every factor 1) leaves seed 1's perfect machine 2.74 um off in
    X, beyond its residual U95 (the reviewer's figure was 2.75 um against 2.53 on the plan before session 26's
    refit within the strokes; 2.728 until session 27, whose estimate of the same campaign moved with the
    tables at the axis positions and the EXY/EXZ/EYZ end-point conventions: the truth, no error, did not)."""
    _, loop = _loop(tmp_path, _own("none"), 1, force_whole=True)
    v = loop["volumetric"]["volumetric_check"]["X"]
    assert not v["not_worse"] and v["after_max_um"] == pytest.approx(2.738, abs=0.01)


def test_a_machine_with_five_errors_improves_and_z_is_not_made_worse(tmp_path, mfb_notes_skipped):
    """The reviewer's five injected errors: X 9.68 -> 0.73, Y 3.58 -> 0.69 um (improved beyond U95); Z,
    1.0 um before, 0.10 after (it was 2.28 after every value: made worse). Session 27 (errors at the
    axis positions); at 63c4d4f 0.60 / 0.63 / 0.09 (the 0.86 / 0.87 / 0.45 this doc quoted were older)."""
    p = tmp_path / "mix.toml"
    p.write_text(MIX)
    r, loop = _loop(tmp_path, truth_machine(str(p), None, "study"), 1)
    v = loop["volumetric"]["volumetric_check"]
    assert v["X"]["improved"] and v["Y"]["improved"]
    assert v["Z"]["not_worse"] and v["Z"]["after_max_um"] < v["Z"]["before_max_um"], v["Z"]
    f = loop["volumetric"]["applied_factor"]
    assert f["EXX"] > 0.99 and f["EC0Y"] > 0.95 and f["EB0Z"] > 0.9  # the injected errors applied
    assert f["EZX"] == 0.0  # absent, left out
    # absent EBY: its estimate (RMS 3.9 urad, up to 6.9 at the last node, all within U95) leaves
    # 1 - (U95/2)^2 / RMS^2 = 0.056 > 0 since session 27 (the plan's U95 of EBY 13.2 -> 12.4 urad
    # at the last node with the errors at the axis positions; 0 before): the rule by hand from the
    # report, and the part applied within the U95 at every node
    e = r.doc["errors"]["EBY"]
    ident, u = np.asarray(e["identified"], float), np.asarray(e["u95_lin"], float)
    assert f["EBY"] == pytest.approx(max(0.0, 1.0 - np.mean((u / 2) ** 2) / np.mean(ident ** 2)), rel=1e-9)
    assert 0.0 < f["EBY"] < 1.0 and np.all(np.abs(f["EBY"] * ident) <= u)


def test_the_realistic_machine_still_improves_on_every_axis(tmp_path, mfb_notes_skipped):
    """The study machine (all 21 errors present): 44.7/19.0/11.6 um -> 2.15/2.15/1.69 um, each beyond
    its U95 (session 28's truth, the tables over the axis positions; session 27's, the tables over the
    strokes as readings: 47.8/21.1/14.8 -> 2.45/1.88/1.69 um; 44.7/19.0/11.6 -> 2.67/2.42/2.30 um at
    63c4d4f; several real errors sit near their U95 and are applied in part)."""
    _, loop = _loop(tmp_path, None, 1)
    v = loop["volumetric"]["volumetric_check"]
    for a in "XYZ":
        assert v[a]["improved"] and v[a]["after_max_um"] < v[a]["before_max_um"] / 4, (a, v[a])


def test_volumetric_check_known_answer():
    """Two points, one axis moving: before 3 / after 1 um against U95 1.5: improved; after 2 against
    U95 1.5 from 0: worse; residuals within the predicted U95 counted point by point."""
    Rb = np.array([[3e-6, 0, 0], [1e-6, 0, 0]])
    Ra = np.array([[1e-6, 0, 0], [0.2e-6, 0, 0]])
    pred = {"residual": np.array([[0.5e-6, 0, 0], [-1.5e-6, 0, 0]]), "U95": np.full((2, 3), 1.5e-6),
            "U95_added": np.full((2, 3), 0.5e-6)}
    v = mfb.volumetric_check(Rb, Ra, pred)
    assert v["X"]["improved"] and v["X"]["not_worse"] and v["X"]["within_u95"] == "1/2"
    assert v["X"]["before_max_um"] == pytest.approx(3.0) and v["X"]["after_max_um"] == pytest.approx(1.0)
    assert v["X"]["predicted_max_um"] == pytest.approx(1.5) and v["X"]["u95_added_max_um"] == pytest.approx(0.5)
    assert not v["Y"]["improved"] and v["Y"]["not_worse"]
    w = mfb.volumetric_check(np.zeros((2, 3)), Ra * 2, pred)
    assert not w["X"]["not_worse"] and not w["X"]["improved"]
