"""part_change's continuous form curving in time (core.causes.PART_CHANGE_CURVE, session 23; docs/discovery.md,
"Session 23: the last blind check's part changes ...").

gen_a's and gen_b's parts change as ``1 - exp(-t / tau)`` with tau about the campaign's span; the catalogue's
continuous form is the line in ``t`` (0 at the first touch, 1 at the last). The settling change is that line plus
a bulge ``t (1 - t)`` (zero at both ends) and a small rest: the richest layout again with each wall's shift (a
ring's ovalisation) also times ``t (1 - t)``, grown like the turns and bows (core.discover._grow_layout: taken only
where its new columns are significant beyond the layout taken so far and it lowers the held-out mean square).
Built, measured and left off (a settling thermal bending is fitted as well: gen_a thermal_bending 1138 and knock 1001
right -> wrong; session 24's core.discover.PART_CHANGE_CURVE_CONFINED takes those back, tested below); these tests
turn it on.
"""
import numpy as np
import pytest

import core.causes as C
from core.baseline import extra_columns, planar
from core.lsq import orth_of
from core.touches import from_log
from tests.discover_helpers import discovered


def _campaign(gen, effect, seed):
    from scenarios.blind import gen_a, gen_b

    log, tr = {"gen_a": gen_a, "gen_b": gen_b}[gen].generate(effect, seed)
    return log, tr, from_log(log)


def test_curve_scan_holds_a_settling_change(monkeypatch):
    """Each feature's curve scan extends its richest continuous layout (its columns are in the curve scan's span)
    and holds a wall's settling change ``(1 - exp(-t / tau)) / (1 - exp(-1 / tau))`` (tau a third of the span)
    to less than a fifth of what the line alone leaves (0.105 against 0.657: the rest is the settling's third
    order and beyond); the step-per-set-up form has no curve scan."""
    monkeypatch.setattr(C, "PART_CHANGE_CURVE", True)
    log, tr, t = _campaign("gen_b", "none", 1010)
    bl = planar(t, 30.0, extra=extra_columns(log, t.row))
    scans, count = C.part_change_scans(bl)
    assert count == len(scans)
    monkeypatch.setattr(C, "PART_CHANGE_CURVE", False)  # off (the default): the scans before, none curving
    off = C.part_change_scans(bl)[0]
    assert not any(s.infos[0].get("curve") for s in off) and len(scans) == len(off) + len(
        {s.infos[0]["feature"] for s in scans if s.infos[0].get("curve")})
    assert not any(s.infos[0].get("curve") for s in scans if s.infos[0].get("time_form") == "per_setup")
    cont = [s for s in scans if s.infos[0].get("time_form", "continuous") == "continuous"
            and s.infos[0]["feature"] == "slot"]
    assert [bool(s.infos[0].get("curve")) for s in cont] == [False, False, False, True], [s.labels for s in cont]
    Q_rich, Q_curve = (orth_of(s.build([0])[0]) for s in cont[2:])
    assert np.linalg.norm(Q_rich - Q_curve @ (Q_curve.T @ Q_rich)) < 1e-9 * np.sqrt(Q_rich.shape[1])
    tau = (t.t_s - t.t_s.min()) / np.ptp(t.t_s)
    settle = (1 - np.exp(-tau * 3)) / (1 - np.exp(-3))
    wall = np.flatnonzero(np.abs(cont[0].build([0])[0][:, 0]) > 0)
    y = np.zeros(t.n)
    y[wall] = settle[wall]
    left = {name: np.linalg.norm(y - Q @ (Q.T @ y)) for name, Q in (("line", Q_rich), ("curve", Q_curve))}
    assert left["curve"] < 0.2 * left["line"] and left["line"] > 0.05 * np.linalg.norm(y), left


@pytest.mark.parametrize("curve", [True, False])
def test_gen_a_part_change_1080_named_with_its_curve(monkeypatch, curve):
    """The tuning miss: gen_a part_change 1080 (2.97 sigma visible; bore3 relaxing with tau a fraction of the span)
    read `outlier` (ambiguous), part_change refused for a held-out loss of 0.054 um^2 (the line in time leaves the
    settling bulge). With the curve scan it is named, confident, on the generator's feature, the walls' curves
    beside their changes; without it (the flag off: the engine before) it is not."""
    monkeypatch.setattr(C, "PART_CHANGE_CURVE", curve)
    log, tr, t = _campaign("gen_a", "part_change", 1080)
    rep = discovered(log, t).to_report()
    f = rep["findings"][0]
    if not curve:
        assert f["cause"] != "part_change", f
        return
    assert f["cause"] == "part_change" and f["params"]["feature"] == tr.params["feature"], rep["rejected"]
    assert f["evidence"].get("confidence") != "ambiguous", f["evidence"].get("confidence_reason")
    curves = [k for k in f["params"] if k.endswith("_curve_um")]
    assert curves and all(k.replace("_curve_um", "_change_um") in f["params"] for k in curves), f["params"]
    # a settling change bulges the way it changes: each wall's curve has its change's sign
    assert all(np.sign(f["params"][k]) == np.sign(f["params"][k.replace("_curve_um", "_change_um")])
               for k in curves), f["params"]


def _first_and_rejected(gen, effect, seed):
    log, tr, t = _campaign(gen, effect, seed)
    rep = discovered(log, t).to_report()
    return rep["findings"][0], [r["reason"] for r in rep["rejected"] if r["cause"] == "part_change"]


@pytest.mark.parametrize("confined", [True, False])
def test_curved_change_refused_where_the_others_move(monkeypatch, confined):
    """Session 24 (core.discover.PART_CHANGE_CURVE_CONFINED): gen_a thermal_bending 1138 (a guideway bowing as it
    warms, out of the catalogue) with the curve on. Its bore1's curved change is one of form beyond the bore's
    rigid motion (p < 1e-6: the warm-up field's gradient over the bore), so the rule before, which refuses only a
    feature moving as a whole, named it part_change (session 23's wrong turn, pinned with the rule off). Held to
    one feature's settling, the curved change is refused because the other features move in its time forms
    (43.7 um^2 in 28 directions, p < 1e-6), and the campaign reads `unexplained` again. The rule off is the engine
    of session 24 (``SLIP_UNJUDGED_BY_OTHERS`` off too: with session 25's slip rule and the confinement off, 1138's
    outliers are a slip's structure, kept in the fit, and `unexplained` leads with part_change second, ambiguous
    `part_change?` before; docs/discovery.md, "Session 25: hedged outliers of effects that are not dust")."""
    import core.discover as D

    monkeypatch.setattr(C, "PART_CHANGE_CURVE", True)
    monkeypatch.setattr(D, "PART_CHANGE_CURVE_CONFINED", confined)
    # (the wrong turn pinned below is of the named cause's adoption: session 25's
    # NAMED_BESIDE_TURNED_OUTLIERS_UNEXPLAINED, off here, would put `unexplained` ahead of it, the outliers beside
    # it turned and carrying more than it explains)
    monkeypatch.setattr(D, "NAMED_BESIDE_TURNED_OUTLIERS_UNEXPLAINED", False)
    # (session 25's single-outlier slip rule, SLIP_ONE_OUTLIER_BY_OTHERS, keeps 1138's single outliers as a slip's
    # structure: then part_change is refused before the confinement is asked, the structure following time more
    # than its form, and the campaign reads `unexplained` with the confinement on or off; off here, the rule pinned
    # is the confinement's)
    monkeypatch.setattr(D, "SLIP_ONE_OUTLIER_BY_OTHERS", False)
    if not confined:
        monkeypatch.setattr(D, "SLIP_UNJUDGED_BY_OTHERS", False)
    f, rejected = _first_and_rejected("gen_a", "thermal_bending", 1138)
    if not confined:
        assert f["cause"] == "part_change" and f["params"]["feature"] == "bore1", f["cause"]
        oth = f["evidence"]["other_features"]
        assert oth["form_beyond_rigid_p"] < 1e-6 and oth["others_move_p"] < 1e-6 and not oth["refused"], oth
        return
    assert f["cause"] == "unexplained", f["cause"]
    assert any("bore1's change curves in time as a warm-up does" in r for r in rejected), rejected


@pytest.mark.parametrize("confined", [True, False])
def test_curved_change_not_saved_by_a_slip_on_its_feature(monkeypatch, confined):
    """Session 24: gen_a knock 1001 (the part bumped once inside a set-up, 1.15 sigma visible, out of the catalogue)
    with the curve on. A fixture slip explains more than bore1's curved change (4.78 against 4.06 um^2, the cause
    nothing beyond it) but is not seen off the bore (p = 0.011 >= alpha), so the rule before named part_change,
    ambiguous with the slip (session 23's wrong turn, pinned with the rule off). A curved change is not saved that
    way (the curve's bulge is what lets a change in time follow a step): refused, `unexplained` as with the curve
    off."""
    import core.discover as D

    monkeypatch.setattr(C, "PART_CHANGE_CURVE", True)
    monkeypatch.setattr(D, "PART_CHANGE_CURVE_CONFINED", confined)
    f, rejected = _first_and_rejected("gen_a", "knock", 1001)
    if not confined:
        assert f["cause"] == "part_change" and f["evidence"]["indistinguishable_counter"] == "fixture slip", f
        assert f["evidence"]["p_slip_off_feature"] >= 0.01, f["evidence"]["p_slip_off_feature"]
        return
    assert f["cause"] == "unexplained", f["cause"]
    assert "a plainer explanation (fixture slip) explains as much" in rejected, rejected
