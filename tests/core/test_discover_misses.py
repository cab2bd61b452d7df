"""The rules written for issue 13's named-cause misses (docs/discovery.md, "Three misses by mechanism").

- fixed lobes are named confidently only when the design could have seen
  lobes turned per set-up (an unoriented spindle) and did not
  (:func:`core.causes.turned_lobes`);
- the outliers' concentration test sees places on the part (feature,
  target): outliers that share a feature set-up after set-up are no dust
  (:func:`core.discover.concentration_p` with :class:`core.discover.Places`);
- outliers on a feature whose other touches carry structure are not
  confidently dust (:func:`core.discover._place_carries`);
- the outliers lead the findings when they are material and beside them is
  only unnamed structure that explains less than they carry, with no noise
  excess (:func:`core.discover._ordered`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from core import causes
from core.baseline import planar
from core.discover import Finding, Places, Settings, _State, _ordered, concentration_p, discover, find_outliers
from core.lsq import orth_of
import discover_synth as S
from tests.discover_helpers import discovered

C6 = (0.0, 50.0, 110.0, 170.0, 230.0, 300.0)


def _lobes(t, psi, amp_m=2e-6, k=2):
    phi = np.arctan2(t.d_R[:, 1], t.d_R[:, 0])
    return amp_m * np.cos(k * (phi - np.asarray(psi, float)[t.setup]))


def _fit(t):
    """The planar baseline of ``t``, its orthonormal basis, the fixed lobes' columns and the machine + form part."""
    bl = planar(t, 30.0)
    return bl, orth_of(bl.A), causes.common_lobing(bl)


def test_turned_lobes_known_answers():
    """Six set-ups, 24 approach azimuths: a turn shows. Fixed lobes: the per-set-up phase model's F test is
    not significant and a random turn of the fitted lobes would have shown (p_turned at the floor of the
    draws); lobes turned per set-up: the F test is significant."""
    t = S.plan(c_deg=C6)
    bl, Q, L = _fit(t)
    rng = np.random.default_rng(4)
    mf, _ = S.machine_and_form(t, rng)
    noise = rng.normal(0, S.SIG, t.n)
    fixed = causes.turned_lobes(bl, Q, mf + _lobes(t, [0.7] * 6) + noise, np.arange(t.n), L, S.SIG, 1e-2)
    assert fixed["setups"] == 6 and fixed["dof"] > 4
    assert fixed["p_value"] > 0.01 and fixed["p_turned"] < 1e-3, fixed
    turned = causes.turned_lobes(bl, Q, mf + _lobes(t, [0.0, 0.8, 2.1, 2.9, 1.4, 0.3]) + noise, np.arange(t.n), L,
                                 S.SIG, 1e-2)
    assert turned["p_value"] < 1e-6 and turned["beyond_ss_um2"] > 50, turned
    # the rows of one set-up: nothing turns, no test
    rows = np.flatnonzero(t.setup == 0)
    assert causes.turned_lobes(bl, Q[rows], noise[rows], rows, L[rows], S.SIG, 1e-2) is None


def test_turned_lobes_is_calibrated_where_a_turn_hides():
    """Four set-ups of four wall directions 90 deg apart (the simulator's cross pocket): each set-up sees
    one combination of the lobes, and one direction beyond the part's form and the fixed lobes tells a
    turn. Under lobes turned at random (the hypothesis the test rejects), p_turned falls below 0.05 in
    about 5 % of campaigns, not more: the test does not call a turned probe oriented more often than its
    level."""
    t0 = S.plan()
    t = t0.subset(np.array([f == "pocket" for f in t0.feature]), reindex=True)
    bl, Q, L = _fit(t)
    rng = np.random.default_rng(7)
    mf, _ = S.machine_and_form(t, rng)
    low = []
    for _ in range(40):
        y = mf + _lobes(t, rng.uniform(0, np.pi, 4)) + rng.normal(0, S.SIG, t.n)
        r = causes.turned_lobes(bl, Q, y, np.arange(t.n), L, S.SIG, 1e-2, draws=1000)
        assert r["dof"] >= 1
        low.append(r["p_turned"] < 0.05)
    assert sum(low) <= 6, sum(low)  # 40 x 0.05 = 2 expected; 6 or more has probability 0.016


def test_fixed_lobes_ambiguous_where_a_turn_cannot_be_excluded():
    """The engine: on the four-wall design an oriented probe cannot be told from one turned per set-up
    (p_turned above the overall alpha): probe_lobing is named, ambiguous with lobing_per_setup (it was
    named confidently, and the simulator's turned lobes 3001, 3006, 2801, 2805, 2807 with it). On six
    set-ups of 24 azimuths the same lobes are named confidently, the test reported."""
    t0 = S.plan()
    t = t0.subset(np.array([f == "pocket" for f in t0.feature]), reindex=True)
    tt, _ = S.campaign("probe_lobing", 1, t=t)
    f = discover(tt).to_report()["findings"][0]
    assert f["cause"] == "probe_lobing" and f["evidence"]["confidence"] == "ambiguous"
    assert "lobing_per_setup" in f["evidence"]["ambiguous_with"], f["evidence"]
    assert f["evidence"]["richer"]["p_turned"] >= 0.01
    rng = np.random.default_rng(0)
    t6 = S.plan(c_deg=C6)
    mf, _ = S.machine_and_form(t6, rng)
    dq = mf + _lobes(t6, [0.7] * 6, k=3) + rng.normal(0, S.SIG, t6.n)
    f = discover(dataclasses.replace(t6, p_R=t6.pn_R + dq[:, None] * t6.n_R)).to_report()["findings"][0]
    assert f["cause"] == "probe_lobing" and f["evidence"]["confidence"] == "named", f["evidence"]
    assert f["evidence"]["richer"]["p_turned"] < 0.01 and f["evidence"]["richer"]["p_value"] > 0.01
    assert f["evidence"]["richer"]["log10_odds_fixed"] >= 2, f["evidence"]["richer"]  # odds 1 / alpha reached


def test_fixed_odds_is_the_gaussian_bayes_factor():
    """Known answer: the closed form of :func:`core.causes._fixed_odds` equals the ratio of the two normal
    densities at the data, N(0, sigma^2) over N(0, sigma^2 + lam) per direction (scipy's logpdf; to 1e-12 of
    the log, the rounding of sums of a few terms of order 10), its statistic the weighted sum of squares
    turned_lobes tests; a direction no turn reaches (lam 0) adds nothing; one telling direction caps the odds
    at sqrt(1 + lam / sigma^2); noise-free data (sigma 0) are not limited by noise (None)."""
    from scipy import stats

    rng = np.random.default_rng(3)
    sigma = 0.3e-6
    lam = np.array([0.0, 2.0, 40.0, 900.0]) * sigma ** 2
    for _ in range(5):
        x = rng.normal(0, sigma, lam.size) * rng.uniform(0.2, 3.0)
        obs = float(np.sum(lam / (sigma ** 2 + lam) * x ** 2))
        ref = np.sum(stats.norm.logpdf(x, 0, sigma) - stats.norm.logpdf(x, 0, np.sqrt(sigma ** 2 + lam)))
        got = causes._fixed_odds(lam, sigma, obs)
        assert abs(got["log10_odds_fixed"] * np.log(10) - ref) < 1e-12 * max(1.0, abs(ref)), (got, ref)
        assert got["log10_odds_fixed"] <= got["log10_odds_most"]
    one = causes._fixed_odds(np.array([0.0, 99.0]) * sigma ** 2, sigma, 0.0)
    assert abs(10 ** one["log10_odds_most"] - 10.0) < 1e-12 and one["log10_odds_fixed"] == one["log10_odds_most"]
    assert causes._fixed_odds(lam, 0.0, 0.0) == {"log10_odds_fixed": None, "log10_odds_most": None}


def test_one_telling_direction_caps_the_odds_for_fixed_lobes():
    """Session 27: on the four-wall design one direction tells a turn, so however small p_turned is the data
    favour fixed lobes over turned ones by at most about the turn's amplitude over the noise. Fixed lobes of
    2 um there (the campaign of seed 3: p_turned 0.0017, below alpha 0.01, the per-set-up lobes not
    significant) reach odds near 60, below 1 / alpha = 100, and their ceiling on this design is below it too;
    six set-ups of 24 azimuths (many telling directions) give odds far beyond it."""
    t0 = S.plan()
    t = t0.subset(np.array([f == "pocket" for f in t0.feature]), reindex=True)
    tt, _ = S.campaign("probe_lobing", 3, t=t)
    bl, Q, L = _fit(tt)
    y = np.einsum("ij,ij->i", tt.p_R - tt.pn_R, tt.n_R)  # the readings along the normal (dq)
    r = causes.turned_lobes(bl, Q, y, np.arange(tt.n), L, S.SIG, 1e-2)
    assert r["p_turned"] < 0.01 and r["p_value"] > 0.01, r
    assert r["log10_odds_fixed"] <= r["log10_odds_most"] < 2, r
    t6 = S.plan(c_deg=C6)
    bl, Q, L = _fit(t6)
    rng = np.random.default_rng(4)
    mf, _ = S.machine_and_form(t6, rng)
    r6 = causes.turned_lobes(bl, Q, mf + _lobes(t6, [0.7] * 6) + rng.normal(0, S.SIG, t6.n), np.arange(t6.n), L,
                             S.SIG, 1e-2)
    assert r6["p_turned"] < 0.01 and r6["log10_odds_fixed"] > 5, r6  # 9.3 measured: 1e5 is far beyond 1e2


def _places(n_feat=12, per=5, setups=6):
    """A campaign of ``setups`` set-ups, ``n_feat`` features of ``per`` targets each: one row per target."""
    feat = np.tile(np.repeat(np.arange(n_feat), per), setups)
    target = np.tile(np.arange(n_feat * per), setups)
    setup = np.repeat(np.arange(setups), n_feat * per)
    units = setup * n_feat * per + target
    ranks = ((np.arange(setup.size) + 0.5) / setup.size)[:, None]  # time order
    return Places(np.column_stack([feat, target]), ("feature", "target"), units), ranks, feat, setup


def test_concentration_sees_places():
    """Outliers on one feature in five set-ups are no dust (p well below the family level); as many at
    random places are (the test holds its level: at most a few per cent of random sets below 0.05)."""
    pl, ranks, feat, setup = _places()
    rng = np.random.default_rng(0)
    one_feature = [np.flatnonzero((feat == 3) & (setup == s))[s % 5] for s in range(5)]
    assert concentration_p(ranks, one_feature, rng, places=pl, place_idx=one_feature) < 1e-3
    # without the places the same rows are spread over time: dust
    assert concentration_p(ranks, one_feature, rng) > 0.05
    hits = 0
    for _ in range(100):
        idx = rng.choice(setup.size, 5, replace=False)
        hits += concentration_p(ranks, idx, rng, draws=2000, places=pl, place_idx=idx) < 0.05
    assert hits <= 10, hits


def test_outliers_on_one_feature_are_structure():
    """find_outliers: five gross residuals, one per set-up, all on one feature: not removed (structure on
    that feature); the same five on five features, or on one feature in one set-up: dust, removed."""
    pl, ranks, feat, setup = _places()
    rng = np.random.default_rng(1)
    n = setup.size
    X = np.ones((n, 1))
    y = rng.normal(0, 1, n)
    same = [int(np.flatnonzero((feat == 3) & (setup == s))[s % 5]) for s in range(5)]
    spread = [int(np.flatnonzero((feat == 2 * s) & (setup == s))[1]) for s in range(5)]
    one_setup = [int(i) for i in np.flatnonzero((feat == 3) & (setup == 2))]  # where one set-up's swarf fell
    for rows, expect in ((same, []), (spread, sorted(spread)), (one_setup, sorted(one_setup))):
        yy = y.copy()
        yy[rows] += 9.0
        got = find_outliers(X, yy, ranks=ranks, rng=np.random.default_rng(0), events=setup, places=pl)
        assert got == expect, (rows, got)
        # without the places both are dust
        assert find_outliers(X, yy, ranks=ranks, rng=np.random.default_rng(0), events=setup) == sorted(rows)


def _f(cause, ss, conf=None, **ev):
    ev = {"explained_ss_um2": ss, **ev}
    if conf:
        ev["confidence"] = conf
    return Finding(cause, ev, {}, {}, 0.3, "data" if cause == "outlier" else "machine")


@pytest.mark.parametrize("findings, first", [
    ([_f("unexplained", 0.0), _f("outlier", 75.0, "named")], "outlier"),  # gen_a outlier 902: a held-out gap only
    ([_f("unexplained", 3.8), _f("outlier", 12.4, "ambiguous")], "outlier"),  # 903: one event, 0.13 um beside
    ([_f("unexplained", 0.0, noise_excess=True), _f("outlier", 155.0, "named")], "unexplained"),  # reseat 801
    ([_f("local_scale_defect", 1.8, "named"), _f("outlier", 18.9, "named")], "local_scale_defect"),  # gen_b 905
    ([_f("part_change", 9.0, "ambiguous"), _f("outlier", 40.0, "ambiguous")], "part_change"),  # gen_a 1000
    ([_f("reversal", 907.7, "ambiguous"), _f("outlier", 24.5, "named")], "reversal"),  # a cause that explains more
    ([_f("unexplained", 341.5), _f("outlier", 70.4, "ambiguous")], "unexplained"),  # gen_a knock 900
    ([_f("unexplained", 0.0), _f("outlier", 0.34, "ambiguous")], "unexplained"),  # gen_b stylus_bending 804
])


def test_outliers_lead_when_they_are_the_story(findings, first):
    """The outliers lead only when material, beside unnamed structure that explains less than they carry and
    leaves no noise excess (the development cases of each row: the lead they took, and those where they
    must not; materiality 2 um^2, about (0.3 sigma)^2 over 270 touches at 0.3 um)."""
    out = _ordered(findings, 2.0)
    assert out[0].cause == first
    assert sorted(f.cause for f in out) == sorted(f.cause for f in findings)
    assert ("leads" in out[0].evidence) == (first == "outlier")


def test_outliers_on_a_feature_that_moves_are_not_confidently_dust():
    """_place_carries: two outliers in two set-ups on a feature whose other touches step set-up by set-up
    (a wall relaxing): the feature carries structure beyond them; the same outliers on a still feature, or
    in one set-up only, say nothing."""
    from core.discover import _place_carries
    from core.lsq import orth_of as orth

    pl, _, feat, setup = _places()
    pl = dataclasses.replace(pl, feature=feat.astype(object), columns=lambda f: np.column_stack(
        [(feat == f) & (setup == s) for s in range(6)]).astype(float))
    rng = np.random.default_rng(3)
    n = setup.size
    out = [int(np.flatnonzero((feat == 3) & (setup == s))[0]) for s in (4, 5)]
    noise = rng.normal(0, 1e-6, n)
    for step_m, rows, found in ((0.8e-6, out, True), (0.0, out, False),
                                (0.8e-6, [out[0], out[0] + 1], False)):  # (the last: one set-up)
        y = noise + step_m * (feat == 3) * setup
        k = np.setdiff1d(np.arange(n), rows)
        Qk = orth(np.ones((k.size, 1)))
        r = y[k] - Qk @ (Qk.T @ y[k])
        got = _place_carries(Qk, r, k, rows, setup, pl, 0.0025, 0.3)
        assert (got is not None) == found, (step_m, rows, got)
        if found:
            assert got["feature"] == "3" and got["p_adjusted"] < 1e-6


def test_gen_a_part_change_904_outliers_not_confidently_dust(monkeypatch):
    """The development miss the outliers' place rule was written from: gen_a part_change 904, the relaxing
    boss's three largest residuals (two set-ups) judged dust, `outlier`, confident; its other touches carry
    the structure (the boss's walls per set-up, p < 1e-6), so the outliers were made ambiguous (the rule
    itself: test_outliers_on_a_feature_that_moves_are_not_confidently_dust). The boss (eight targets, one
    per 45 deg sector) had no part_change column; with the ring's ovalisation columns the change is named
    on the changing feature, and no outlier is called dust confidently. With the ring switched off
    (RING_FIT_REL 0: no feature is a ring) the place rule still does its part end to end: the outliers
    are ambiguous, their structure placed on the boss."""
    from core.touches import from_log
    from scenarios.blind import gen_a

    log, tr = gen_a.generate("part_change", 904)
    t = from_log(log)
    rep = discovered(log, t).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "part_change" and f["params"]["feature"] == tr.params["feature"], rep["findings"]
    assert not any(g["cause"] == "outlier" and g["evidence"].get("confidence") != "ambiguous"
                   for g in rep["findings"]), rep["findings"]
    monkeypatch.setattr(causes, "RING_FIT_REL", 0.0)
    rep = discovered(log, t).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "outlier" and f["evidence"]["confidence"] == "ambiguous", f["evidence"]
    assert f["evidence"]["place_structure"]["feature"] == "boss"


def _gen_b_baseline(effect, seed):
    from core.baseline import extra_columns, planar
    from core.touches import from_log
    from scenarios.blind import gen_b

    log, tr = gen_b.generate(effect, seed)
    t = from_log(log)
    return log, tr, t, planar(t, 30.0, extra=extra_columns(log, t.row))


def test_part_change_wall_turns():
    """A wall of a feature may turn as it moves (a slot's wall relaxing more at its open end): each wall's
    change linear along the wall times the time is in part_change's span, the wall shifting alone is too.
    The wall's direction here is the principal axis of its own nominal contact points (not the sector the
    scan uses), the time the log's. Before the turn columns the turn was not in the span (its residual
    outside it 1.17 of 1.17: the turn is all but orthogonal to the shifts); a pin (one target per 45 deg
    sector) gets no turn column, nor does a curved surface's sector (the blade's: a turn there is the
    feature's smooth form, and with it gen_b local_scale_defect 1077 was named part_change, confident)."""
    _, _, t, bl = _gen_b_baseline("none", 1010)
    sc = {s.infos[0]["feature"]: s for s in causes.part_change_scans(bl)[0] if s.infos[0].get("time_form", "continuous") == "continuous"}
    C = sc["slot"].build([0])[0]
    Qc = orth_of(C)
    tau = (t.t_s - t.t_s.min()) / np.ptp(t.t_s)
    slot = np.asarray(t.feature) == "slot"
    az = np.arctan2(t.wn_A[:, 1], t.wn_A[:, 0])
    walls = [slot & (np.abs(np.angle(np.exp(1j * (az - a0)))) < 0.1) for a0 in np.unique(np.round(az[slot], 3))]
    assert len(walls) == 2 and all(w.sum() >= 10 for w in walls)
    for w in walls:
        p = t.w_A[w, :2] - t.w_A[w, :2].mean(0)
        along = p @ np.linalg.svd(p, full_matrices=False)[2][0]
        for form in (np.ones(w.sum()), along / np.ptp(along)):
            y = np.zeros(t.n)
            y[w] = tau[w] * form
            assert np.linalg.norm(y - Qc @ (Qc.T @ y)) < 1e-9 * np.linalg.norm(y)
    assert not any("turn" in lb for f, s in sc.items() if f.startswith("pin") for lb in s.labels)
    # a curved surface's sector is no wall: the blade's sectors whose normals spread (by the log's own normals)
    # get no turn; its flat ones (one normal, two places or more) would
    feat = np.asarray(t.feature)
    blade = feat == "blade"
    sector = np.mod(np.round(az / (np.pi / 4)).astype(int), 8)
    curved = [45 * k for k in np.unique(sector[blade]) if np.ptp(np.degrees(az[blade & (sector == k)])) > 1.0]
    assert len(curved) >= 2
    assert not set(curved) & set(sc["blade"].infos[0]["turns_deg"]), sc["blade"].labels


def test_part_change_turn_needs_a_wall_of_some_length():
    """WALL_TURN_MIN: gen_b none 1010's slot walls (two targets and more, one normal each) pressed along the
    wall to 1e-6 of their length (spread 1e-6 of the feature's extent, non-zero, below WALL_TURN_MIN = 1e-3)
    get no turn column: the column, scaled to -1..1 along the wall, would be the same full-size pattern from a
    wall that has no length. At 1e-2 of their length (above the constant) they keep it. The scan's count is
    one trial per layout (each feature's shift, shift and turn, ...: core.discover._grow_layout picks a
    feature's layout by its p-value); that assertion restates part_change_scans' count and guards it only."""
    from core.baseline import extra_columns
    from core.touches import from_log
    from scenarios.blind import gen_b

    log, _ = gen_b.generate("none", 1010)
    t0 = from_log(log)
    slot = np.asarray(t0.feature) == "slot"
    az = np.arctan2(t0.wn_A[:, 1], t0.wn_A[:, 0])
    turns = {}
    for squeeze in (1e-6, 1e-2):
        w = np.array(t0.w_A, float)
        for a0 in np.unique(np.round(az[slot], 3)):
            wall = slot & (np.abs(np.angle(np.exp(1j * (az - a0)))) < 0.1)
            c = w[wall, :2].mean(0)
            w[wall, :2] = c + squeeze * (w[wall, :2] - c)
        t = dataclasses.replace(t0, w_A=w)
        scans, count = causes.part_change_scans(planar(t, 30.0, extra=extra_columns(log, t.row)))
        assert count == len(scans)
        turns[squeeze] = {a for s in scans if s.infos[0]["feature"] == "slot" for a in s.infos[0]["turns_deg"]}
    assert turns[1e-6] == set() and turns[1e-2] == {135, 315}, turns


def test_part_change_wall_bows():
    """A flat wall may bow as it relaxes (held at its ends, most in its middle): each wall's change of second
    order along the wall times the time is in the span of part_change's richest scan, not in the shifts' and
    turns' (gen_b none 1010's slot: two walls of ten touches and more). The wall's direction and place along
    it are the principal axis of its own nominal contact points (not the scan's sector), the time the log's.
    A wall whose targets sit at two places only (here pressed onto its two ends) has no bow column
    (WALL_BOW_PLACES = 3: on two places a parabola is a shift and a turn), but keeps its turn."""
    log, _, t, bl = _gen_b_baseline("none", 1010)
    scans = [s for s in causes.part_change_scans(bl)[0]
             if s.infos[0]["feature"] == "slot" and s.infos[0].get("time_form", "continuous") == "continuous"]
    assert [len(s.infos[0]["bows_deg"]) for s in scans] == [0, 0, 2], [s.labels for s in scans]
    Q_turn, Q_bow = (orth_of(s.build([0])[0]) for s in scans[1:])
    tau = (t.t_s - t.t_s.min()) / np.ptp(t.t_s)
    slot = np.asarray(t.feature) == "slot"
    az = np.arctan2(t.wn_A[:, 1], t.wn_A[:, 0])
    walls = [slot & (np.abs(np.angle(np.exp(1j * (az - a0)))) < 0.1) for a0 in np.unique(np.round(az[slot], 3))]
    assert len(walls) == 2 and all(w.sum() >= 10 for w in walls)
    w_two = np.array(t.w_A, float)
    for w in walls:
        p = t.w_A[w, :2] - t.w_A[w, :2].mean(0)
        ax = np.linalg.svd(p, full_matrices=False)[2][0]
        along = p @ ax
        u = 2 * (along - along.min()) / np.ptp(along) - 1
        y = np.zeros(t.n)
        y[w] = tau[w] * (1 - u ** 2)
        assert np.linalg.norm(y - Q_bow @ (Q_bow.T @ y)) < 1e-9 * np.linalg.norm(y)
        # (outside the shifts and turns: a bow the turns cannot take; before the bow columns it was not in the
        # span at all)
        assert np.linalg.norm(y - Q_turn @ (Q_turn.T @ y)) > 0.1 * np.linalg.norm(y)
        ends = np.where(along > np.median(along), along.max(), along.min())
        w_two[w, :2] = t.w_A[w, :2] + (ends - along)[:, None] * ax[None, :]
    from core.baseline import extra_columns
    t2 = dataclasses.replace(t, w_A=w_two)
    sc2 = [s for s in causes.part_change_scans(planar(t2, 30.0, extra=extra_columns(log, t2.row)))[0]
           if s.infos[0]["feature"] == "slot" and s.infos[0].get("time_form", "continuous") == "continuous"]
    assert len(sc2) == 2 and set(sc2[1].infos[0]["turns_deg"]) == {135, 315}, [s.labels for s in sc2]
    assert not any(s.infos[0]["bows_deg"] for s in sc2)


@pytest.mark.parametrize("seed", [1049, 1064, 1503])
def test_gen_a_part_change_named_with_the_bow(seed):
    """The tuning miss this was written from: gen_a part_change 1049 (3.1 sigma visible), one wall of the
    part bowing into the pocket, most in its middle (a parabola along the wall growing with time), read
    `outlier` (part_change never significant): noise-free, the wall's shift explained 57 % of the change
    outside the baseline, with its turn 58 %, with its bow 98 %. With the bow (nested beyond the turn) the
    change is named on the right wall, and the wall's change at its middle and its bow agree with the
    generator's (a parabola through its change at the wall's targets at the campaign's end, fitted here by
    hand from the truth's workpiece at the start and the end) within their U95. At 1049 the wall has three
    targets: shift, turn and bow are three numbers for three places (core.causes.WALL_BOW_PLACES), so the
    bow is a change of form there, not a shape tested; gen_a part_change 1064 (a tuning gain of the bow,
    `outlier` second finding dropped) has six targets on its wall, where the parabola is over-determined
    and fitted here by least squares. gen_a part_change 1503 (4.6 sigma visible, a fresh seed of session 11,
    opened to diagnose it) read `none`: its wall's shift alone (p = 0.068) lost to another wall's (0.0029)
    before any wall's bow was tried, so the bow (p = 1e-22) never was (core.discover._grow_layout: every feature's
    layout is grown before the features are compared); it fails on a3ba8ad."""
    from scenarios.blind import gen_a

    log, tr = gen_a.generate("part_change", seed)
    rep = discovered(log).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "part_change" and f["params"]["feature"] == tr.params["feature"], rep["rejected"]
    bow = [k for k in f["params"] if k.endswith("_bow_um")]
    assert len(bow) == 1, f["params"]
    change = bow[0].replace("_bow_um", "_change_um")
    # the truth: the end-of-campaign change per target of the wall, a parabola in the place along the wall
    d = dict(zip(map(str, tr.targets), np.asarray(tr.workpiece_end_um) - np.asarray(tr.workpiece_um)))
    names = np.asarray(log.col("target")).astype(str)
    ids = np.unique(names[np.asarray(log.col("feature")).astype(str) == tr.params["feature"]])
    assert len(ids) == {1049: 3, 1064: 6, 1503: 4}[seed]
    first = np.array([np.flatnonzero(names == k)[0] for k in ids])
    p = np.column_stack([np.asarray(log.col("wx_mm"), float)[first], np.asarray(log.col("wy_mm"), float)[first]])
    p = p - p.mean(0)
    along = p @ np.linalg.svd(p, full_matrices=False)[2][0]
    u = 2 * (along - along.min()) / np.ptp(along) - 1
    v_true, _, b_true = np.linalg.lstsq(np.column_stack([np.ones_like(u), u, -u ** 2]),
                                        np.array([d[k] for k in ids]), rcond=None)[0]
    assert abs(f["params"][change] - v_true) <= f["params_u95"][change], (f["params"], v_true)
    assert abs(f["params"][bow[0]] - b_true) <= f["params_u95"][bow[0]], (f["params"], b_true)


def test_sim_part_change_3106_the_turn_kept_only_where_it_holds_out():
    """The simulator's part change (a bump over a wall's middle, no taper): sim part_change 3106 (four walls of
    the pocket). The walls' turns are significant beyond their shifts in-sample (p ~7e-8) but lower the
    held-out error of none: with the turns taken unconditionally part_change's held-out gain fell to
    -0.0135 um^2 and lobing_per_setup was named. The turn is kept only where it is significant beyond the
    shifts AND lowers the held-out mean square: the walls' shifts are named, without turns."""
    from scenarios.hidden import hidden_campaign

    log, _ = hidden_campaign(("part_change",), 3106)
    rep = discovered(log).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "part_change" and f["params"]["feature"] == "pocket", rep["rejected"]
    assert not any(k.endswith("_turn_um") for k in f["params"]), f["params"]


def test_gen_b_part_change_1010_named_beside_the_slip():
    """The development miss this was written from: gen_b part_change 1010 (3.05 sigma visible), the slot
    closing 0.1 to 1 times its closure from its closed end to its open one, read `unexplained`: the walls
    shifting alone explained less of it than a one-off slip of the part in the first set-up (the plainer
    explanation). With the walls' turns the change is named, and its turns are reported."""

    log, tr, t, _ = _gen_b_baseline("part_change", 1010)
    assert "part_change" in tr.acceptable_causes
    rep = discovered(log, t).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "part_change" and f["params"]["feature"] == "slot", rep["rejected"]
    assert {"wall135deg_turn_um", "wall315deg_turn_um"} <= set(f["params"])


def test_a_cause_confounded_in_a_later_round_names_the_model(monkeypatch):
    """gen_a reversal 1208: the reversal's columns (``-n_x sign(d_x) / 2``: about ``|n_x| / 2`` when the
    approach is along the normal, even harmonics of the azimuth) are determined beside the baseline alone
    (best variance inflation about 9) but not beside the baseline and the probe's lobes (harmonics 1-4,
    adopted first on a lower held-out mean square), where the best inflation is about 151 > 100. The
    refusal said "confounded with the baseline"; it names the model it is confounded with, and the
    inflation that decides it (the engine before this change fails the test).

    Since session 19 the reversal leads here (the plainer of one explanation under two names,
    ``_plainer_one_explanation``; test_plainer_of_one_explanation_leads below): the round's choice before
    that rule is restored so that the stage this test is about, the lobes adopted first, is kept."""
    import core.discover as D
    from scenarios.blind import gen_a

    monkeypatch.setattr(D, "_plainer_one_explanation", lambda best, *a: best)
    log, _ = gen_a.generate("reversal", 1208)
    rep = discovered(log).to_report()
    why = [r["reason"] for r in rep["rejected"] if r["cause"] == "reversal"]
    assert why and why[0].startswith("confounded with the baseline + probe_lobing (best variance inflation "), why
    assert rep["findings"][0]["cause"] == "probe_lobing" and "reversal" in rep["findings"][0]["evidence"][
        "ambiguous_with"]


def test_history_shift_holds_its_level_and_sees_one_end():
    """concentration_p's ``history_ranks`` (the shift alone, per row given): 200 random sets of 6 rows, p
    below 0.05 at most 20 times (the binomial 99.9 % bound for a 5 % test); six rows in the top 2 %:
    p < 1e-3; six in the bottom 2 % too (the shift is two-sided)."""
    n = 300
    rng = np.random.default_rng(8)
    hist = ((np.arange(n) + 0.5) / n)[:, None]
    none = np.zeros((n, 0))
    hits = sum(concentration_p(none, [], rng, draws=2000, history_ranks=hist,
                               place_rows=rng.choice(n, 6, replace=False)) < 0.05 for _ in range(200))
    assert hits <= 20, hits
    assert concentration_p(none, [], rng, history_ranks=hist, place_rows=list(range(n - 6, n))) < 1e-3
    assert concentration_p(none, [], rng, history_ranks=hist, place_rows=list(range(6))) < 1e-3


def test_history_shift_level_on_the_generators_true_chips():
    """The history statistic's level on real dust: gen_a outlier seeds 0-119, the generator's TRUE chip rows
    (no discovery), one per target and set-up, campaigns whose chips fall in two or more set-ups; the ranks
    of the engine's history covariates (time since the previous touch, turn of the approach) with the ties
    of real data (the first touch's median rest, repeated turns). Two statistics, Bonferroni: p < 0.05 in
    at most the binomial 99.9 % bound of a 5 % test over the eligible campaigns (a null that ignored the
    ties or the one-per-place counting would not be checked by the uniform ranks of the test above)."""
    from scipy import stats

    from core.baseline import touch_history
    from core.touches import from_log
    from scenarios.blind import gen_a

    ps = []
    for seed in range(120):
        log, truth = gen_a.generate("outlier", seed)
        t = from_log(log)
        row_of = {int(r): i for i, r in enumerate(t.row)}
        chips = [row_of[r] for r in truth.outlier_rows if r in row_of]
        setup, target = np.asarray(t.setup), np.asarray(t.target)
        if len(set(setup[chips].tolist())) < 2:
            continue
        places = list({(setup[c], target[c]): c for c in reversed(chips)}.values())
        hist = np.column_stack([(stats.rankdata(v) - 0.5) / len(v) for v in touch_history(t.t_s, t.d_R)])
        ps.append(concentration_p(np.zeros((len(hist), 0)), [], np.random.default_rng(seed), draws=2000,
                                  history_ranks=hist, place_rows=places))
    ps = np.array(ps)
    assert ps.size >= 40, ps.size  # enough campaigns to say something
    assert np.sum(ps < 0.05) <= stats.binom.ppf(0.999, ps.size, 0.05), (np.sum(ps < 0.05), ps.size)


def test_gen_a_reseat_hysteresis_876_outliers_not_confidently_dust():
    """The development miss the history check was written from: gen_a reseat_hysteresis 876, eleven
    outliers in three set-ups, ten of them touches after a turn of the approach of 86 deg or more (a probe
    re-seating, out of the catalogue), read `outlier` confidently (one event per set-up: concentration
    p = 0.069). Counted one per place in the touch's history covariates they gather at one end: the finding
    is ambiguous, its concentration p (one family: covariates per event, places, history per place, 0.0024)
    below the overall rate 0.01 (main fails: confident, p = 0.069). Since session 24 the outliers, whose centred
    turn is below alpha_family too, hand the report's lead to ``unexplained`` (OUTLIERS_TURNED_UNEXPLAINED,
    tests/core/test_discover_turned_lead.py); the outlier finding follows it, as tested here."""
    from scenarios.blind import gen_a

    log, _ = gen_a.generate("reseat_hysteresis", 876)
    rep = discovered(log).to_report()
    assert rep["cause"] == "unexplained", rep["cause"]
    f = next(f for f in rep["findings"] if f["cause"] == "outlier")
    assert f["evidence"]["confidence"] == "ambiguous", f["evidence"]
    assert f["evidence"]["concentration_p"] < 0.01 and f["evidence"]["events"] == 3


@pytest.mark.parametrize("seed", [1012, 1088, 1262])
def test_gen_a_reseat_hysteresis_outliers_a_baseline_half_absorbs_not_confidently_dust(seed):
    """The target issue 13 sets, on three of the 17 tuning campaigns of gen_a reseat_hysteresis (out of
    catalogue) read `outlier` confidently on main a3ba8ad/69a6324, one of each mechanism measured in
    session 12: 1012 only long residuals (clean touches of a target re-seated in its other set-ups, which
    the target's parameter half absorbed), 1088 both signs (two re-seats at a target re-seated in 2 of 4
    set-ups read short, a clean touch at a target re-seated in 3 of 4 reads long), 1262 only short residuals
    (re-seats at targets re-seated in 1 of 3 set-ups). The outcome must not be a confident wrong name.
    Main d9fc3d0 fails all three (each `outlier`, confident); the centred-turn test of the outlier finding
    (:func:`core.discover.centred_turn_p`: p 1.2e-4, 1.0e-5, 1.5e-4 against alpha_family 0.0025) makes the
    finding ambiguous."""
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    o = blind_outcome(gen_a, "reseat_hysteresis", seed, generator="gen_a")
    assert not (o.confident and o.cause not in o.acceptable), (o.cause, o.confident, o.acceptable)


@pytest.mark.parametrize("gen, effect, seed, p, confidence", [
    ("gen_a", "reseat_hysteresis", 1262, 0.0001799982000179998, "ambiguous"),
    ("gen_b", "outlier", 1134, 0.00911990880091199, "named")])


def test_centred_turn_p_pinned_on_a_campaign(gen, effect, seed, p, confidence):
    """The centred turn's p on two tuning campaigns, exactly (review of s13_rhturn, finding 1: nothing pinned
    the seeding, the residuals' signs in the wiring or the threshold): gen_a reseat_hysteresis 1262 below
    alpha_family (0.0025: ambiguous), gen_b outlier 1134, the generator's chips, between it and 0.05 (named:
    a threshold of 0.05 would make it ambiguous). The review's mutations that survived the other tests (an
    unseeded generator, |r| passed for r, p < 0.05 as the rule) each fail here. 1262's p moved 1.5e-4 ->
    3.8e-4 in session 14 (still below alpha_family) with the local defect's finer half-widths
    (core.causes.DEFECT_WIDTHS): a 1-2 mm bump takes its re-seat at row 2 before the fixture slip drops it,
    and the row stays in the fit (outliers rows 2, 5, 95 -> 5, 95, an `unexplained` second finding), the
    put-back left as gen_a outlier 1163's (tests/core/test_discover_defect.py). 3.8e-4 -> 4.1e-4 in session 24
    (:data:`core.discover.TURN_THROUGH_NO_TRIGGER`: 1262's log holds a no-trigger row, and the touch after it
    turns from that row's approach), still below alpha_family. 4.1e-4 -> 1.8e-4 in session 36
    (:data:`core.discover.DROPPED_ROUND_REOPENED` on: the bump that took row 2's re-seat is dropped by the rival
    check and its round decided again without it, so row 2 is an outlier again, rows 2, 5, 95), still below
    alpha_family."""
    import importlib

    log, _ = importlib.import_module(f"scenarios.blind.{gen}").generate(effect, seed)
    rep = discovered(log).to_report()
    f = next(f for f in rep["findings"] if f["cause"] == "outlier")
    assert f["evidence"]["centred_turn_p"] == p, f["evidence"]
    assert f["evidence"]["confidence"] == confidence, f["evidence"]


def test_gen_a_knock_1609_slip_veto_judges_what_the_step_does_not_fit_exactly():
    """gen_a knock 1609 (fresh seed, examined in session 11): the part moves 15.9 um and turns 264 urad at
    log row 49 of set-up C355.5 (rows 36-71); the set-up's pose takes the 23 moved touches, so the outliers
    are the 13 unmoved ones' largest: rows 36 (the set-up's first drift-check touch on wall6) and 43-48
    (bore1). The best step of the set-up (rows 49-71 moved) leaves bore1's six within the bound (|t| <= 1.85
    against 4.76), but before the step only the wall touch sees a turn (a bore's radial normals are blind
    to a turn about its axis): row 36 has leverage 1 under the step, no deleted residual, and main refused
    the step for it, set the seven aside as one event of dust and moved the extended workpiece from 1.08
    to 2.37 um (U95 0.35). Judged on the six it can judge (more than the step's three parameters) the
    step explains them: they are kept, and the workpiece is the baseline's (main fails all three)."""
    from scenarios import hidden
    from scenarios.blind import gen_a

    o = hidden.blind_outcome(gen_a, "knock", 1609, generator="gen_a")
    assert "outlier" not in o.findings, o
    assert o.cause in o.acceptable, o  # unexplained: the knock is out of the catalogue
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o  # the issue's check: never worse beyond U95


@pytest.mark.parametrize("sigmas", [None, 1.0])
def test_gen_a_reseat_hysteresis_1609_repeats_above_the_model_is_not_confident(sigmas):
    """gen_a reseat_hysteresis 1609 (fresh seed, examined in session 11; out of catalogue): 46 of 216
    touches, each the first after the approach turned by more than 90 deg, read 2.72 um short (noise
    0.363 um). 9 of the 18 drift-check repeats follow a turn, so the repeats scatter 1.57 um (11 degrees
    of freedom beyond the model's terms) and every check of c_drift's adoption was judged with that; main
    named c_drift confidently. The extended model's residuals scatter 1.53 um within the six repeat groups
    (12 dof) and 0.73 um overall (148 dof) (F = 4.4, p = 5e-6 by the rule's conservative statistic), and
    that surplus over the campaign's rows (394 um^2) is more than c_drift explains (30 um^2), so c_drift
    is at most ambiguous, for that reason only. The rule was designed on this campaign. At the
    generator's ``sigmas`` 1.0 the same campaign was c_drift confident on main as well (the withdrawn
    noise-excess rule of session 11 kept it confident: its repeats, 1.02 um, are under its 1.5 um
    ceiling). Main fails both."""
    from scenarios.blind import gen_a

    log, _ = gen_a.generate("reseat_hysteresis", 1609, **({} if sigmas is None else {"sigmas": sigmas}))
    d = discovered(log)
    f = d.findings[0]
    assert f.cause != "unexplained" and f.evidence["confidence"] == "ambiguous", f.evidence
    x = f.evidence["repeats_beyond_residual"]
    assert x["p_value"] < Settings().alpha_family and x["repeats_sigma_um"] > x["model_sigma_um"], x
    # this rule's reason is appended last; before it stands only the two-way test's (session 34,
    # ALTERNATIVES_TWO_WAY: beside the feature's smooth, reproducing 87 % of its signal, c_drift explains nothing
    # material: 0.29 and 0 um^2 against 10.3 and 5.7), which puts it in doubt on its own: no other check did
    before, _, _ = f.evidence["confidence_reason"].partition("the model's residuals scatter more within repeats")
    assert before.startswith("beyond a smooth term in feature (reproducing 87% of its signal)"), f.evidence
    assert before.endswith("nothing material and significant: the data do not prefer the name; "), f.evidence


def test_gen_b_thermal_drift_1072_repeats_beyond_residual_below_explained_leaves_the_name():
    """gen_b thermal_drift 1072 (a tuning seed): the drift moves repeats 200 s apart by 3-7 um and the
    catalogue's drift form follows it but for 0.73 um within the 24 repeat pairs against 0.48 um overall
    (F = 2.3, p = 6.5e-4, below the lack-of-fit family's 0.0025): an excess of 117 um^2 over the campaign
    beside the 314 um^2 the drift explains. The drift is no part of a bigger structure: thermal_drift stays
    named (with the repeats' test alone, no comparison with what the cause explains, it was ambiguous)."""
    from scenarios.blind import gen_b

    log, _ = gen_b.generate("thermal_drift", 1072)
    d = discovered(log)
    f = d.findings[0]
    assert f.cause == "thermal_drift" and f.evidence["confidence"] == "named", f.evidence
    assert "repeats_beyond_residual" not in f.evidence


def _repeats_design():
    """A design of 160 rows and 12 columns (148 residual dof) with six repeat groups of three touches (one
    design row each, touched early, mid and late: 12 dof within), a time column and a column oscillating
    over the campaign (both varying within the groups: the residuals' leverage within groups,
    tr(W H), is 0.21 of the 12 dof): its orthonormal basis, the repeat key and the groups' first touches."""
    n = 160
    X = np.random.default_rng(0).normal(size=(n, 10))
    X[:, 0] = 1.0
    key = np.full(n, -1)
    for g in range(6):
        i = np.arange(3) * 50 + 3 * g
        X[i] = X[i[0]]
        key[i] = g
    t = np.linspace(0.0, 1.0, n)
    Q = np.linalg.qr(np.column_stack([X, t, np.sin(9 * np.pi * t)]))[0]
    first = np.zeros(n)
    first[[np.flatnonzero(key == g)[0] for g in range(6)]] = 1.0
    return Q, key, first, t


def _beyond(Q, key, e):
    from core.discover import _repeats_beyond_residual
    from core.units import UM

    r = (e - Q @ (Q.T @ e)) * UM  # the residuals (I - H) e of a least-squares fit on the design
    st = _State(rows=np.arange(len(r)), Q=Q, r=r, rss=float(r @ r), dof=len(r) - Q.shape[1])
    return _repeats_beyond_residual(key, st, Settings())


def test_repeats_beyond_residual_null_calibration():
    """:func:`core.discover._repeats_beyond_residual` under the null (the residuals (I - H) e of pure
    Gaussian noise on a design with repeat groups and columns varying within them, :func:`_repeats_design`)
    fires in at most ``Settings.alpha_family`` of 8,000 seeded draws. The tolerance is the level the rule
    claims (0.25 %, 20 draws): a statistic firing at twice it (40 expected) would exceed 20 with
    probability above 0.99. The statistic is a conservative hybrid (the within-repeats mean square against
    the whole residual's, which contains it): it fired in 3 of these 8,000 draws (0.04 %). A version that
    forgot the groups' means (the residuals' sum of squares at the repeats on sum(size - 1) dof) fired in
    35 and fails here."""
    Q, key, _, _ = _repeats_design()
    rng = np.random.default_rng(1)
    n_draws = 8000
    fired = sum(_beyond(Q, key, rng.normal(size=len(key))) is not None for _ in range(n_draws))
    assert fired <= Settings().alpha_family * n_draws, fired


def test_repeats_beyond_residual_power():
    """:func:`core.discover._repeats_beyond_residual` fires when the groups' first touches read 7.5 sigma
    short (gen_a reseat_hysteresis 1609's 2.72 um against its noise 0.363 um), an effect within the
    repeats the design does not hold: the within-repeats scatter is then well above the whole residual's.
    An effect as large varying within the groups that the design holds (the time column, 7.5 sigma over
    the campaign) leaves the residuals and does not fire; nor does the null draw itself, nor a campaign
    without repeat groups."""
    Q, key, first, t = _repeats_design()
    e = np.random.default_rng(2).normal(size=len(key))
    x = _beyond(Q, key, e - 7.5 * first)
    assert x is not None and x["p_value"] < Settings().alpha_family, x
    assert x["repeats_sigma_um"] > x["model_sigma_um"] and x["repeats_dof"] == 12 and x["model_dof"] == 148, x
    assert _beyond(Q, key, e + 7.5 * t) is None
    assert _beyond(Q, key, e) is None
    assert _beyond(Q, np.full(len(key), -1), e - 7.5 * first) is None


def test_part_change_ring_columns():
    """A ring (a boss or a bore) whose 45 deg sectors do not each hold two targets has no wall column; its
    ovalisation changing with time is its columns instead (``tau cos 2 theta``, ``tau sin 2 theta`` on its
    touches, theta its normal's azimuth in the part's frame) and its size (``tau`` on its touches,
    ``causes.RING_SIZE``, session 28; without it a size change mostly not in the span). gen_a none 1017's boss
    (eight targets, one per sector): one scan, an ovalisation of any axis in its span (to 1e-9 of its norm:
    rounding), a size change too.
    Hand-made rings: eight points on a circle are one; the same points moved along one normal by 1 % of the
    radius are not (a flat wall's places, a blade's curve); four points 90 deg apart are a ring whose
    ovalisation's axis cannot be seen (``cos 2 theta`` and ``sin 2 theta`` one column up to sign), no ring
    columns. gen_b none 1000: its blade (a curve of changing radius) is no ring, its pins (four targets, each
    sector a wall) keep their walls: no ring columns there."""
    from core.baseline import extra_columns
    from core.touches import from_log
    from scenarios.blind import gen_a

    log, _ = gen_a.generate("none", 1017)
    t = from_log(log)
    bl = planar(t, 30.0, extra=extra_columns(log, t.row))
    scans = [s for s in causes.part_change_scans(bl)[0]
             if s.infos[0]["feature"] == "boss" and s.infos[0].get("time_form", "continuous") == "continuous"]
    assert len(scans) == 1 and scans[0].infos[0].get("ring"), [s.labels for s in scans]
    boss = np.asarray(t.feature) == "boss"
    tau = (t.t_s - t.t_s.min()) / np.ptp(t.t_s)
    th = np.arctan2(t.wn_A[:, 1], t.wn_A[:, 0])
    Q = orth_of(scans[0].build([0])[0])
    y = boss * tau * np.cos(2 * th - 0.4)
    assert np.linalg.norm(y - Q @ (Q.T @ y)) < 1e-9 * np.linalg.norm(y)
    y = boss * tau
    assert np.linalg.norm(y - Q @ (Q.T @ y)) < 1e-9 * np.linalg.norm(y)
    assert scans[0].infos[0].get("ring_size") and scans[0].labels[-1] == "boss size", scans[0].labels
    with pytest.MonkeyPatch.context() as mp:  # without the size (the rule before session 28): mostly outside
        mp.setattr(causes, "RING_SIZE", False)
        sc0 = [s for s in causes.part_change_scans(bl)[0] if s.infos[0]["feature"] == "boss"][0]
        assert not sc0.infos[0].get("ring_size") and len(sc0.labels) == 2
        Q0 = orth_of(sc0.build([0])[0])
        assert np.linalg.norm(y - Q0 @ (Q0.T @ y)) > 0.9 * np.linalg.norm(y)
    a = np.linspace(0, 2 * np.pi, 8, endpoint=False) + 0.3
    n = np.column_stack([np.cos(a), np.sin(a)])
    w = np.array([3.0, -2.0]) + 12.0 * n
    assert causes._ring(w, n) and causes._ring(w, -n)  # a boss, and a bore (normals to the centre)
    w2 = w.copy()
    w2[2] += 0.12 * n[2]
    assert not causes._ring(w2, n)
    from types import SimpleNamespace
    for k, sees in ((4, False), (5, True)):  # four azimuths 90 deg apart: the ovalisation's axis unseen
        az = np.linspace(0, 2 * np.pi, k, endpoint=False) + 0.3
        p = np.column_stack([12.0 * np.cos(az), 12.0 * np.sin(az), np.zeros(k)])
        d = SimpleNamespace(touches=SimpleNamespace(target=np.arange(k), w_A=p), wn_az=az, tau=np.linspace(0, 1, k))
        assert causes._ring(p[:, :2], p[:, :2] / 12.0)
        assert (causes._ring_columns(d, np.ones(k, bool)) is not None) == sees, k
    # a bore by hand: nine targets (uneven azimuths) on a 12 mm circle, normals to the centre, changing by
    # 5 um cos 2(theta - phi) at the end (theta the normal's azimuth), phi 250 deg: the axis is phi mod 180
    a = np.radians([3.0, 41.0, 77.0, 128.0, 160.0, 199.0, 236.0, 281.0, 322.0])
    p = np.column_stack([3.0 + 12.0 * np.cos(a), -2.0 + 12.0 * np.sin(a), np.zeros(a.size)])
    az = a + np.pi
    tau = np.linspace(0.0, 1.0, a.size)
    d = SimpleNamespace(touches=SimpleNamespace(target=np.arange(a.size), w_A=p), wn_az=az, tau=tau)
    cols = causes._ring_columns(d, np.ones(a.size, bool))
    y = 5.0 * causes.UM * tau * np.cos(2 * (az - np.radians(250.0)))
    # with a size change of -2 um (the bore opening: material receding from the stylus) beside it
    y = y - 2.0 * causes.UM * tau
    got = causes.part_change_magnitudes({"feature": "bore", "ring": True, "ring_size": True},
                                        np.linalg.lstsq(cols, y, rcond=None)[0], None)
    assert abs(got["ovalisation_axis_deg"] - 70.0) < 1e-9 and abs(got["ovalisation_um"] - 5.0) < 1e-9, got
    assert abs(got["size_um"] + 2.0) < 1e-9, got
    _, _, tb, blb = _gen_b_baseline("none", 1000)
    assert not any(s.infos[0].get("ring") for s in causes.part_change_scans(blb)[0])
    assert causes._ring_columns(blb.data, np.asarray(tb.feature) == "blade") is None


@pytest.mark.parametrize("seed", [1017, 1026, 1059, 1090, 1086])
def test_gen_a_part_change_a_boss_ovalising_named(seed):
    """The tuning misses this was written from: gen_a part_change 1017 (5.6 sigma visible), the boss (eight
    targets, one per 45 deg sector) ovalising, read `outlier` (1059, 1090 too; 1086 `unexplained`): part_change had no column on it (two targets per sector were needed on a
    feature of eight or more). Noise-free, 1017's ovalisation growing with time explains 97 % of the change
    outside the baseline, the best one-off slip 6 %. With the ring's columns the change is named on the
    changing feature, and its axis agrees with the generator's (the second harmonic of its change at the
    boss's targets at the campaign's end, from the truth's workpiece at the start and the end, fitted here
    beside a size) within 3 deg: the columns' linear-in-time form scales the ovalisation's two parts alike,
    so the axis (their ratio) is not biased by it, only by noise (its U95 2.3-3.1 deg on these seeds; the
    largest miss measured 2.0 deg, 1017). The magnitude is biased low by that form (the generator grows as
    1 - exp(-t/tau)) and its U95 covers noise only: found/truth 0.68-0.98 on these seeds (1059, tau 718 s
    against a 2188 s campaign, 0.68; core/causes.py part_change_scans); within 25 % is checked on 1017
    (0.955), the form's bias bound met where tau is not short against the campaign."""
    from scenarios.blind import gen_a

    log, tr = gen_a.generate("part_change", seed)
    rep = discovered(log).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "part_change" and f["params"]["feature"] == tr.params["feature"], rep["rejected"]
    d = dict(zip(map(str, tr.targets), np.asarray(tr.workpiece_end_um) - np.asarray(tr.workpiece_um)))
    names = np.asarray(log.col("target")).astype(str)
    ids = np.unique(names[np.asarray(log.col("feature")).astype(str) == tr.params["feature"]])
    first = np.array([np.flatnonzero(names == k)[0] for k in ids])
    th = np.arctan2(np.asarray(log.col("wny"), float)[first], np.asarray(log.col("wnx"), float)[first])
    c = np.linalg.lstsq(np.column_stack([np.ones_like(th), np.cos(2 * th), np.sin(2 * th)]),
                        np.array([d[k] for k in ids]), rcond=None)[0]
    p = f["params"]
    axis = np.degrees(0.5 * np.arctan2(c[2], c[1])) % 180.0
    assert abs((p["ovalisation_axis_deg"] - axis + 90.0) % 180.0 - 90.0) <= 3.0, (p, axis)
    if seed == 1017:
        assert abs(p["ovalisation_um"] / np.hypot(c[1], c[2]) - 1.0) <= 0.25, (p, c)


@pytest.mark.parametrize("seed", [1508, 1701])
def test_dropped_cause_still_significant_is_no_none(seed, monkeypatch):
    """gen_b part_change 1508 and 1701 (fresh seeds of session 11, opened to diagnose them) read `none`:
    part_change was adopted (p = 1.6e-5 and 8e-16 after its Bonferroni, material held-out gains) and the
    rival check dropped it for a one-off slip of the part explaining as much; the catalogue-free tests then
    saw nothing (no covariate at alpha_family, no held-out gap, no lack of fit) and the report said `none`.
    A dropped cause whose columns still explain a material, significant sum of squares beyond the model
    kept is structure (core.discover._dropped_still_significant): `unexplained`, saying so and naming the rival
    that dropped it. Fails on a3ba8ad.

    Session 21: the slip that dropped it is seen on the slot alone (core.discover._slip_off_feature), so by
    default both are now named part_change, ambiguous with the slip; the dropped-cause mechanism is tested with
    that rule off."""
    from core import discover as D
    from core.touches import from_log
    from scenarios.blind import gen_b

    log, _ = gen_b.generate("part_change", seed)
    t = from_log(log)
    rep = discovered(log, t).to_report()
    f = rep["findings"][0]
    assert rep["cause"] == "part_change" and f["evidence"]["indistinguishable_counter"] == "fixture slip", rep["cause"]
    monkeypatch.setattr(D, "SLIP_OFF_FEATURE", False)
    rep = discovered(log, t).to_report()
    assert rep["cause"] == "unexplained", (rep["cause"], rep["rejected"])
    left = rep["structure"]["extended"]["dropped_still_significant"]
    assert [d["cause"] for d in left] == ["part_change"] and left[0]["p_adjusted"] < Settings().alpha_family, left
    assert "part_change" in rep["findings"][0]["evidence"]["text"]
    # the text names what dropped it (the rival check's own reason), not a generic "plainer explanation"
    assert "fixture slip" in left[0]["dropped_because"], left
    assert left[0]["dropped_because"] in rep["findings"][0]["evidence"]["text"], rep["findings"][0]["evidence"]


def _turn_designs(gen: str, seeds):
    """gen_a/gen_b ``outlier`` campaigns' touches, centred turns, turns, dust units (target in set-up) and the
    generator's true chips (touch index, true size in um)."""
    import importlib

    from core.baseline import touch_history
    from core.discover import centred_turn_of
    from core.touches import from_log

    mod = importlib.import_module(f"scenarios.blind.{gen}")
    out = []
    for seed in seeds:
        log, truth = mod.generate("outlier", seed)
        t = from_log(log)
        row_of = {int(r): i for i, r in enumerate(t.row)}
        chips = np.array([row_of[r] for r in truth.outlier_rows if r in row_of], int)
        e = np.asarray(truth.effect_dq_um, float)[np.asarray(t.row)]
        unit = np.unique(np.asarray(t.setup) * (int(np.max(t.target)) + 1) + np.asarray(t.target),
                         return_inverse=True)[1].ravel()
        out.append((seed, centred_turn_of(t.t_s, t.d_R, t.target), touch_history(t.t_s, t.d_R)[1],
                    np.asarray(t.target), unit, chips, e[chips]))
    return out


def test_centred_turn_known_answers():
    """centred_turn_of on a written-out plan, centred_turn_p where the null is a binomial: c = +-1 at
    alternate touches, k rows at c = +1 with equal residuals: |S*| = k only when all k draws share a sign,
    P = 2 * 2^-k (k = 10: 0.00195; k = 2: 0.5), p within 4 Monte Carlo SE; p does not depend on the units of
    r or c (same seed); rows at both ends with residuals of opposite sign score as one sign at one end
    (the same binomial)."""
    from core.discover import TURN_DRAWS, centred_turn_of, centred_turn_p

    # five touches in time order: target 0 along +x, target 1 along +y, target 0 along -x, target 0 along
    # +x, target 2 along +y; turns 0 (first), 90, 90, 180, 90; target 0: 0, 90, 180 (mean 90)
    d = np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    c = centred_turn_of(np.arange(5.0), d, np.array([0, 1, 0, 0, 2]))
    assert np.allclose(c, [-90, 0, 0, 90, 0]), c  # targets 1 and 2 touched once: 0
    # the time order counts, not the log order
    c2 = centred_turn_of(np.arange(5.0)[::-1], d[::-1], np.array([0, 1, 0, 0, 2])[::-1])
    assert np.allclose(c2, c[::-1]), c2
    n = 1000
    cc = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    up = np.flatnonzero(cc > 0)
    se = np.sqrt(0.00195 * (1 - 0.00195) / TURN_DRAWS)
    p10 = centred_turn_p(cc, up[:10], np.ones(10), np.random.default_rng(1))
    assert abs(p10 - 2 * 0.5 ** 10) < 4 * se, p10
    assert abs(centred_turn_p(cc, up[:2], np.ones(2), np.random.default_rng(1)) - 0.5) < 0.01
    p_scaled = centred_turn_p(7 * cc, up[:10], 1e3 * np.ones(10), np.random.default_rng(1))
    assert p_scaled == p10
    both = np.r_[up[:5], np.flatnonzero(cc < 0)[:5]]
    p_both = centred_turn_p(cc, both, np.r_[-np.ones(5), np.ones(5)], np.random.default_rng(1))
    assert abs(p_both - 2 * 0.5 ** 10) < 4 * se, p_both  # |S| = 10, the same null distribution


def test_centred_turn_bad_input():
    """A target touched once has centred turn 0; the first touch (no previous one) takes the covariate's
    turn 0 and enters its target's mean; fewer than two rows, residuals or turns not finite, rows outside
    the campaign, shapes that do not match: ConfigError; a campaign whose targets are each touched once
    (every centred turn 0) has nothing to test: centred_turn is None (the outlier finding then carries no
    centred_turn_p and keeps its confidence)."""
    from core.baseline import planar
    from core.discover import centred_turn, centred_turn_of, centred_turn_p
    from core.exceptions import ConfigError

    d = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0]], float)
    assert np.allclose(centred_turn_of([0.0, 1.0, 2.0], d, [0, 0, 1]), [-90, 90, 0])
    assert centred_turn_of([], np.zeros((0, 3)), []).shape == (0,)
    with pytest.raises(ConfigError):
        centred_turn_of([0.0, 1.0], d, [0, 0, 1])
    with pytest.raises(ConfigError):
        centred_turn_of([0.0, np.nan, 2.0], d, [0, 0, 1])
    c = np.array([-1.0, 1.0, 0.0, 2.0])
    rng = np.random.default_rng(0)
    for idx, r in (([1], [1.0]), ([0, 1], [1.0, np.nan]), ([0, 4], [1.0, 1.0]), ([0, -1], [1.0, 1.0]),
                   ([0, 1], [1.0]), ([[0, 1]], [[1.0, 1.0]])):
        with pytest.raises(ConfigError):
            centred_turn_p(c, idx, np.asarray(r), rng, draws=10)
    with pytest.raises(ConfigError):
        centred_turn_p(np.array([0.0, np.inf, 1.0]), [0, 1], np.ones(2), rng, draws=10)
    t = S.plan()
    assert centred_turn(planar(t, 30.0)) is not None
    same = dataclasses.replace(t, d_R=np.tile(t.d_R[:1], (t.n, 1)))  # one approach: no touch turns
    assert centred_turn(planar(same, 30.0)) is None


def test_centred_turn_holds_its_level_on_the_generators_dust():
    """The null: dust at the generators' designs. gen_a and gen_b ``outlier`` seeds 0-9: the generator's TRUE
    chips with their true sizes (no discovery; gen_b's chips and skids of both signs), and on each design 60
    made-up dust sets of one sign (the caution case: 2-6 dust units, a target in a set-up, every touch of a
    unit reading one size, uniform 2-8 um), 1,000 draws each. p < 0.05 and p < 0.01 in at most the binomial
    99.9 % bound of a 5 % and a 1 % test. Measured (session 13): 1,216 p-values, 54 below 0.05, 16 below
    0.01, 5 below 0.0025 (bounds 86 and 24; 3.0 expected below 0.0025); on 3,000 made-up sets per
    generator (seeds 0-29, 2,000 draws) 3.8 % and 5.3 % below 0.05, 0.20 % and 0.30 % below 0.0025; the true
    chips of seeds 0-199 (4,000 draws): gen_a 148 campaigns, 5 below 0.05, none below 0.01; gen_b 200, 11
    and 1. Checked to fail: a null drawn without the absolute value (one-sided draws against a two-sided
    S) gives 106 below 0.05."""
    from scipy import stats

    from core.discover import centred_turn_p

    ps = []
    for gen in ("gen_a", "gen_b"):
        for seed, c, _, _, unit, chips, size in _turn_designs(gen, range(10)):
            rng = np.random.default_rng(seed)
            if chips.size >= 2:
                ps.append(centred_turn_p(c, chips, size, rng, draws=1000))
            for _ in range(60):
                u = rng.choice(unit.max() + 1, rng.integers(2, 7), replace=False)
                rows = np.flatnonzero(np.isin(unit, u))
                sz = dict(zip(u.tolist(), rng.uniform(2, 8, u.size)))
                ps.append(centred_turn_p(c, rows, np.array([sz[int(unit[i])] for i in rows]), rng, draws=1000))
    ps = np.array(ps)
    assert ps.size >= 1200, ps.size
    assert np.sum(ps < 0.05) <= stats.binom.ppf(0.999, ps.size, 0.05), (np.sum(ps < 0.05), ps.size)
    assert np.sum(ps < 0.01) <= stats.binom.ppf(0.999, ps.size, 0.01), (np.sum(ps < 0.01), ps.size)


def test_centred_turn_sees_a_reseat_the_targets_half_absorb():
    """The power: on gen_a ``outlier`` seeds 0-9's designs, a re-seat written here (every touch after a turn
    of more than 90 deg reads 5 um short, noise 0.5 um), less its target's mean (what the baseline's target
    parameter absorbs), the six largest residuals taken as the outliers: p < alpha_family (0.0025) in at
    least 5 of 10 (measured: 7 of 10; 14 of 20 on seeds 0-19; with the two largest 1 of 10 and 6 of 20, the
    four largest 6 of 10 and 11 of 20: the power grows with the outliers the finding holds). The same
    residuals at six random touches of the design: p < 0.0025 in none. Checked to fail: the raw turn in
    place of the centred one reaches 3 of 10."""
    from core.discover import centred_turn_p

    hits = hits_random = 0
    for seed, c, turn, target, _, _, _ in _turn_designs("gen_a", range(10)):
        rng = np.random.default_rng(seed)
        eff = -5.0 * (turn > 90) + rng.normal(0, 0.5, turn.size)
        tg = np.unique(target, return_inverse=True)[1].ravel()
        r = eff - (np.bincount(tg, eff) / np.bincount(tg))[tg]
        rows = np.argsort(-np.abs(r), kind="stable")[:6]
        hits += centred_turn_p(c, rows, r[rows], rng, draws=20000) < 0.0025
        hits_random += centred_turn_p(c, rng.choice(turn.size, 6, replace=False), r[rows], rng,
                                      draws=20000) < 0.0025
    assert hits >= 5, hits
    assert hits_random == 0, hits_random


@pytest.mark.parametrize("seed, cause", [(1047, "stylus_bending"), (1060, "c_drift")])
def test_a_named_cause_beside_turned_outliers_is_in_doubt(seed, cause, monkeypatch):
    """gen_a reseat_hysteresis (out of catalogue) 1047 and 1060 name a catalogue cause confidently, with an
    outlier finding beside it whose residuals follow the centred turn (p 8e-5, 0.0023 < alpha_family): the
    re-seat's minority readings; its other readings are in the fit, where the named cause may be taking their
    share. The named cause must not stay confident (both confident on main e880365: the test fails there), and
    the reason names the turn. (Since session 33, vif33, 1060's c_drift is hedged before the turn is asked: its
    one direction inflated 3370 times carries all of its 43 um RMS of fitted values, 0.12 um on the determined
    one, :data:`core.discover.INFLATED_SIGNAL_HEDGED`; the turn's reason is read with that hedge off, and the
    cause stays ambiguous with it on.)"""
    import importlib

    import core.discover as D

    log, _ = importlib.import_module("scenarios.blind.gen_a").generate("reseat_hysteresis", seed)
    on = next(f for f in discovered(log).to_report()["findings"] if f["cause"] != "unexplained")
    assert on["cause"] == cause and on["evidence"]["confidence"] == "ambiguous", on["evidence"]
    monkeypatch.setattr(D, "INFLATED_SIGNAL_HEDGED", False)
    rep = discovered(log).to_report()
    # (1047's stylus_bending explains less than the turned outliers carry: session 25's
    # NAMED_BESIDE_TURNED_OUTLIERS_UNEXPLAINED puts `unexplained` ahead of it, the cause second)
    first = next(f for f in rep["findings"] if f["cause"] != "unexplained")
    assert first["cause"] == cause, first["cause"]
    assert first["evidence"]["confidence"] == "ambiguous", first["evidence"]
    assert "centred turn" in first["evidence"]["confidence_reason"], first["evidence"]["confidence_reason"]
    out = next(f for f in rep["findings"] if f["cause"] == "outlier")
    assert out["evidence"]["centred_turn_p"] < 0.0025, out["evidence"]


def test_doubt_beside_turned_outliers_unit():
    """_doubt_beside_turned_outliers on made-up findings (review finding 11): no outlier finding below
    alpha_family leaves every named cause named; one below it makes every named cause ambiguous, the first
    and a secondary one alike, with the turn in the reason; an already ambiguous cause keeps its own reason;
    outlier and unexplained findings are not touched."""
    from core.discover import Finding, Settings, _doubt_beside_turned_outliers

    def f(cause, **ev):
        return Finding(cause, dict(ev), {}, {}, 0.1)

    st = Settings()
    fs = [f("stylus_bending", confidence="named"), f("outlier", confidence="named", centred_turn_p=0.01)]
    _doubt_beside_turned_outliers(fs, st)
    assert fs[0].evidence["confidence"] == "named" and "confidence_reason" not in fs[0].evidence
    fs = [f("stylus_bending", confidence="named"), f("c_drift", confidence="ambiguous", confidence_reason="own"),
          f("unexplained", confidence="named"), f("thermal_drift", confidence="named"),
          f("outlier", confidence="ambiguous", centred_turn_p=1e-4)]
    _doubt_beside_turned_outliers(fs, st)
    assert [x.evidence["confidence"] for x in fs] == ["ambiguous", "ambiguous", "named", "ambiguous", "ambiguous"]
    assert "centred turn" in fs[0].evidence["confidence_reason"] and "centred turn" in fs[3].evidence["confidence_reason"]
    assert fs[1].evidence["confidence_reason"] == "own"
    assert "confidence_reason" not in fs[2].evidence


def test_a_categorical_term_spans_what_is_constant_in_its_categories():
    """core.discover._spans_exactly on gen_b's design (none 1010): every feature of a set-up is probed at one
    approach elevation, so the feature-per-set-up term (indicators through the scalar mode) holds the stylus
    bending's columns (sin e, sin^2 e) exactly, and the reversal's (|n_x| / 2, varying around a pin) not.
    Known answers by construction; bad inputs (no such covariate, a covariate that is not categorical, no
    columns) say no."""
    from core.discover import _spans_exactly

    _, _, t, bl = _gen_b_baseline("none", 1010)
    rows = np.arange(bl.n)
    bend = causes.bending_scans(bl)[0][0].build([0])[0]
    rev = causes.reversal_scans(bl)[0][0].build([0])[0]
    assert _spans_exactly(bl, "feature", bend, rows)
    # the same by least squares: the columns' residual beyond the indicators is zero
    key = np.unique(np.asarray(bl.covariate("feature").values), return_inverse=True)[1]
    ind = np.eye(key.max() + 1)[key]
    res = bend - ind @ np.linalg.lstsq(ind, bend, rcond=None)[0]
    assert np.abs(res).max() < 1e-12 * np.abs(bend).max()
    assert not _spans_exactly(bl, "feature", rev, rows)
    assert not _spans_exactly(bl, "no_such_covariate", bend, rows)
    assert not _spans_exactly(bl, "approach_elevation", bend, rows)  # a smooth term, not categories
    assert not _spans_exactly(bl, "feature", bend[:, :0], rows)
    # one touch's elevation changed: its feature no longer holds one value, and the term no longer spans it
    bend2 = bend.copy()
    bend2[5] += 0.1
    assert not _spans_exactly(bl, "feature", bend2, rows)
    # a NaN column is constant within nothing (it compared equal to itself before the review's guard), and no rows
    bend3 = bend.copy()
    bend3[:, 0] = np.nan
    assert not _spans_exactly(bl, "feature", bend3, rows)
    assert not _spans_exactly(bl, "feature", bend[:0], rows[:0])


def test_gen_b_stylus_bending_1041_named_where_the_feature_term_nests_it():
    """The tuning miss this was written from: gen_b stylus_bending 1041 (2.04 sigma visible) read `unexplained`:
    step 4e refused the bending because the feature per set-up explained 124 against its 121 um^2. On gen_b
    each feature of a set-up is probed at one elevation, so that term is any function of the elevation: it
    nests the bending (and its form error: the generator's 1 / (1 + k sin e) against the catalogue's
    quadratic in sin e), as it nests a position cause, and refuses it only below rival_share of it. Named,
    ambiguous (indistinguishable from a smooth in the feature on this design); the engine before this change
    reads `unexplained` (fails)."""

    log, tr, t, _ = _gen_b_baseline("stylus_bending", 1041)
    assert "stylus_bending" in tr.acceptable_causes
    rep = discovered(log, t).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "stylus_bending", rep["rejected"]
    assert f["evidence"]["confidence"] == "ambiguous"
    assert any(a["covariate"] == "feature" for a in f["evidence"]["alternatives"])


@pytest.mark.parametrize("findings, first, confidence", [
    ([_f("unexplained", 13.0, text="residuals follow time"), _f("outlier", 50.0, "named")], "outlier", "ambiguous"),
    ([_f("unexplained", 0.0), _f("outlier", 75.0, "named")], "outlier", "ambiguous"),  # a held-out gap beside
    ([_f("outlier", 75.0, "named")], "outlier", "named"),  # dust alone: nothing beside it says the model is wrong
    ([_f("unexplained", 3.8), _f("outlier", 12.4, "ambiguous", confidence_reason="own")], "outlier", "ambiguous"),
    ([_f("local_scale_defect", 1.8, "named"), _f("outlier", 18.9, "named")], "local_scale_defect", "named"),
    ([_f("unexplained", 341.5), _f("outlier", 70.4, "named")], "unexplained", "named"),  # the structure leads
])


def test_outliers_leading_beside_unnamed_structure_are_not_confidently_dust(findings, first, confidence):
    """_ordered: outliers that lead beside an `unexplained` finding were judged against a model the finding
    says is wrong, and may be its largest residuals: the outlier finding is ambiguous, with a reason naming
    the structure; outliers alone, or outliers that do not lead, keep their confidence, and a reason already
    given is kept. Known answers by construction (main f3c9460 fails the first two: the outliers stay named)."""
    out = _ordered(findings, 2.0)
    assert out[0].cause == first
    dust = next(f for f in out if f.cause == "outlier")
    assert dust.evidence["confidence"] == confidence, dust.evidence
    if len(findings) > 1 and first == "outlier" and findings[-1].evidence.get("confidence_reason") != "own":
        assert "structure the model does not name" in dust.evidence["confidence_reason"]
        assert "residuals follow time" in dust.evidence["confidence_reason"] or findings[0].evidence.get(
            "text") is None
    if findings[-1].evidence.get("confidence_reason") == "own":
        assert dust.evidence["confidence_reason"] == "own"


@pytest.mark.parametrize("effect, seed", [("knock", 1085), ("reseat_hysteresis", 1036)])
def test_gen_a_outliers_beside_unnamed_structure_not_confidently_misnamed(effect, seed):
    """Two tuning campaigns of gen_a (out of catalogue) read `outlier` confidently on main f3c9460, each
    with an `unexplained` finding beside the outliers (session 16, docs/discovery.md): knock 1085 (five of
    the six outliers are touches of set-up B after the knock, the step its set-up's parameters half absorb;
    structure left in time, 0.24 um, p 2.6e-8) and reseat_hysteresis 1036 (two minority readings of the
    re-seats, -5.5 and +5.1 um, beside a lack of fit F = 24.5 against the repeats). The outcome must not be
    a confident wrong name, and the outlier finding says why (main f3c9460 fails both). Since session 22 the
    slip veto's step starts at the knock's own first touch (core.discover._exact_step; the best trial started
    it one touch late and left that touch beyond the bound): knock 1085's outliers are the knock's, kept in
    the fit, and the report reads `unexplained` with no outlier finding, the right reading."""
    from scenarios.blind import gen_a

    log, _ = gen_a.generate(effect, seed)
    rep = discovered(log).to_report()
    if effect == "knock":
        assert rep["cause"] == "unexplained", rep["cause"]
        assert all(g["cause"] != "outlier" for g in rep["findings"]), [g["cause"] for g in rep["findings"]]
        return
    # since session 24 the `unexplained` finding, whose strongest covariate is the turn from the previous touch,
    # leads (core.discover.OUTLIERS_BESIDE_TURN_UNEXPLAINED): the right reading; the outlier finding follows it
    assert rep["cause"] == "unexplained", rep["cause"]
    f = next(g for g in rep["findings"] if g["cause"] == "outlier")
    assert f["evidence"]["confidence"] == "ambiguous", f["evidence"]
    # since session 33 the structure hedge (core.discover.OUTLIERS_STRUCTURE_HEDGED: the reversed approach explains
    # the two rows better than dust, delta BIC -137) hedges the finding first and gives its reason; the session-16
    # rule writes its own only over a confident finding
    why = f["evidence"]["confidence_reason"]
    assert "structure the model does not name" in why or "reversed approach, explains them" in why, why
    assert [g["cause"] for g in rep["findings"]] == ["unexplained", "outlier"], rep["findings"]


def test_doubt_beside_gathered_outliers_unit():
    """_doubt_beside_gathered_outliers on made-up findings: outliers that are no dust (concentration p below
    alpha, or structure on their feature) and carry more than a named cause explains make it ambiguous, with
    the sizes in the reason; outliers that are dust (p at or above alpha, or no test: p None), or carry less
    than the cause explains, leave it named; an ambiguous cause keeps its own reason; outlier and unexplained
    findings are not touched. Known answers by construction (main f3c9460 has no such rule: the first case
    stays named there)."""
    from core.discover import Finding, Settings, _doubt_beside_gathered_outliers

    def f(cause, **ev):
        return Finding(cause, dict(ev), {}, {}, 0.1)

    st = Settings()
    fs = [f("stylus_bending", confidence="named", explained_ss_um2=2.77), f("c_drift", confidence="ambiguous",
          confidence_reason="own", explained_ss_um2=1.0), f("unexplained", confidence="named", explained_ss_um2=1.0),
          f("outlier", confidence="ambiguous", concentration_p=0.0098, explained_ss_um2=59.3)]
    _doubt_beside_gathered_outliers(fs, st)
    assert [x.evidence["confidence"] for x in fs] == ["ambiguous", "ambiguous", "named", "ambiguous"]
    assert "59.3 um^2" in fs[0].evidence["confidence_reason"] and "2.77" in fs[0].evidence["confidence_reason"]
    assert fs[1].evidence["confidence_reason"] == "own" and "confidence_reason" not in fs[2].evidence
    for out in (f("outlier", confidence="named", concentration_p=0.01, explained_ss_um2=59.3),  # at alpha: dust
                f("outlier", confidence="ambiguous", concentration_p=None, explained_ss_um2=59.3),  # one event
                f("outlier", confidence="ambiguous", concentration_p=0.001, explained_ss_um2=2.0),  # smaller
                f("outlier", confidence="ambiguous", concentration_p=0.001)):  # no sum of squares: carries nothing
        fs = [f("local_scale_defect", confidence="named", explained_ss_um2=2.77), out]
        _doubt_beside_gathered_outliers(fs, st)
        assert fs[0].evidence["confidence"] == "named", out.evidence
    fs = [f("local_scale_defect", confidence="named", explained_ss_um2=2.77),
          f("outlier", confidence="ambiguous", concentration_p=0.5, explained_ss_um2=18.9,
            place_structure={"feature": "wall1"})]
    _doubt_beside_gathered_outliers(fs, st)
    assert fs[0].evidence["confidence"] == "ambiguous"


def test_gen_a_reseat_hysteresis_1087_named_cause_beside_gathered_outliers_in_doubt():
    """gen_a reseat_hysteresis 1087 (out of catalogue) read `stylus_bending` confidently on main f3c9460
    (session 16): the cause explains 2.77 um^2 beside six outliers carrying 59.3 um^2 whose concentration
    p 0.0098 (below alpha 0.01) says they are a mechanism, not dust (their centred turn p 0.023 is not below
    0.0025, so the turn's rule does not fire). The cause must not stay confident (main fails)."""
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    o = blind_outcome(gen_a, "reseat_hysteresis", 1087, generator="gen_a")
    assert o.cause == "stylus_bending" and not o.confident, (o.cause, o.confident)


def test_doubt_beside_noise_excess_unit():
    """_doubt_beside_noise_excess on made-up findings: an unexplained noise excess makes every named cause
    whose rival was debiased to nothing ambiguous (the first and a secondary alike), with the reason; a cause
    whose rival still explains something (gen_a probe_lobing 1933's figures), or with no rival, stays named;
    an unexplained finding without the excess leaves them all named; an ambiguous cause keeps its own reason;
    outlier and unexplained findings are not touched. Known answers by construction (main f3c9460 has no
    such rule)."""
    from core.discover import Finding, _doubt_beside_noise_excess

    def f(cause, **ev):
        return Finding(cause, dict(ev), {}, {}, 0.1)

    blind = {"rival": "time_in_setup", "rival_explained_ss_um2": 0.0}
    fs = [f("c_drift", confidence="named", **blind), f("unexplained", noise_excess=False),
          f("outlier", confidence="named")]
    _doubt_beside_noise_excess(fs)
    assert [x.evidence.get("confidence") for x in fs] == ["named", None, "named"]
    fs = [f("c_drift", confidence="named", **blind), f("thermal_drift", confidence="ambiguous",
          confidence_reason="own", **blind), f("stylus_bending", confidence="named", **blind),
          f("probe_lobing", confidence="named", rival="approach_azimuth", rival_explained_ss_um2=73.4),
          f("part_change", confidence="named", rival=None), f("unexplained", noise_excess=True),
          f("outlier", confidence="named")]
    _doubt_beside_noise_excess(fs)
    assert [x.evidence.get("confidence") for x in fs] == ["ambiguous", "ambiguous", "ambiguous", "named", "named",
                                                          None, "named"]
    assert "noise excess" in fs[0].evidence["confidence_reason"] and "time_in_setup" in fs[2].evidence[
        "confidence_reason"]
    assert fs[1].evidence["confidence_reason"] == "own"
    _doubt_beside_noise_excess([])  # nothing to judge: no error


def test_gen_a_reseat_hysteresis_1130_named_cause_beside_a_noise_excess_in_doubt():
    """gen_a reseat_hysteresis 1130 (out of catalogue) read `c_drift` confidently on main f3c9460 (session 16)
    beside an unexplained noise excess: the repeats scatter 3.0 um (above the 1.5 um of any touch-trigger
    probe), the floor its rival and materiality checks were judged with. The cause must not stay confident
    (main fails)."""
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    o = blind_outcome(gen_a, "reseat_hysteresis", 1130, generator="gen_a")
    assert o.cause == "c_drift" and not o.confident, (o.cause, o.confident)


@pytest.mark.parametrize("gen, seed, refused", [
    ("gen_a", 1135, "cross-validated gain"),  # the quadratic over the campaign: smallest p, no held-out gain
    ("gen_b", 1187, "confounded"),  # the quadratic over the campaign: confounded with the set-ups' own angles
])


def test_c_drift_judged_on_a_form_that_predicts(monkeypatch, gen, seed, refused):
    """The tuning misses this was written from (issue 13, session 17): gen_a c_drift 1135 (3.7 sigma) read
    `unexplained`, gen_b c_drift 1187 (1.5 sigma) `none`. c_drift's trial of smallest p was a polynomial over
    the campaign, which with the set-ups' own angles fits within the set-ups but does not predict a held-out
    set-up (1135: held-out gain -0.028 um^2) or is not determined beside them (1187: inflation 208); the
    per-set-up rates, next by p (held-out gain 2.52 and 0.30 um^2), were never judged. With
    ``HELD_OUT_FALLBACK`` the cause's other significant forms are judged in turn and it is named; without it
    the same campaign refuses c_drift for that form's reason."""
    import importlib

    import core.discover as D
    from core.touches import from_log

    log, tr = importlib.import_module(f"scenarios.blind.{gen}").generate("c_drift", seed)
    assert "c_drift" in tr.acceptable_causes
    t = from_log(log)
    # (the held-out step on by default since session 18, the confounded one by p off: core.discover.HELD_OUT_FALLBACK
    # and CONFOUNDED_FALLBACK, their measured figures; since session 26 the confounded step takes the least inflated
    # passing form, CONFOUNDED_FALLBACK_LEAST_INFLATION, on)
    assert D.HELD_OUT_FALLBACK is True and D.CONFOUNDED_FALLBACK is False
    monkeypatch.setattr(D, "HELD_OUT_FALLBACK", True)
    if refused == "confounded":
        monkeypatch.setattr(D, "CONFOUNDED_FALLBACK", True)

    def run():
        return discovered(log, t).to_report()

    rep = run()
    f = rep["findings"][0]
    assert f["cause"] == "c_drift", rep["rejected"]
    assert refused in f["evidence"]["held_out_fallback"]
    assert f["params"].get("form") != "over the campaign"
    monkeypatch.setattr(D, "HELD_OUT_FALLBACK", False)
    off = run()
    assert off["cause"] != "c_drift"
    assert any(r["cause"] == "c_drift" and r["reason"].startswith(refused) for r in off["rejected"]), off["rejected"]


def test_confounded_fallback_by_held_out_gain(monkeypatch):
    """Session 25 (conf25): the confounded step's variant that takes, of the cause's other forms that pass every
    test, the one of largest held-out gain (``CONFOUNDED_FALLBACK_BY_GAIN``, off: measured, it lost gen_a c_drift
    1267's workpiece check). gen_b c_drift 1187: the quadratic over the campaign is confounded (inflation 208);
    with the variant every passing form is judged and the one named has the largest held-out gain of them (its
    evidence says so); with the first-by-p step it is the first that passes, whose gain is not above it."""
    import core.discover as D
    from core.touches import from_log
    from scenarios.blind import gen_b

    assert D.CONFOUNDED_FALLBACK is False and D.CONFOUNDED_FALLBACK_BY_GAIN is False
    assert D.CONFOUNDED_FALLBACK_SAME_COVARIATE is False
    # (the least-inflation choice, on since session 26, comes before the gain's: off here, this test is the gain's)
    monkeypatch.setattr(D, "CONFOUNDED_FALLBACK_LEAST_INFLATION", False)
    log, _ = gen_b.generate("c_drift", 1187)
    t = from_log(log)

    def run():
        return discovered(log, t).to_report()

    monkeypatch.setattr(D, "CONFOUNDED_FALLBACK", True)
    first = run()["findings"][0]
    assert first["cause"] == "c_drift"
    assert "largest held-out gain" not in first["evidence"]["held_out_fallback"]
    monkeypatch.setattr(D, "CONFOUNDED_FALLBACK_BY_GAIN", True)
    best = run()["findings"][0]
    assert best["cause"] == "c_drift"
    assert "confounded" in best["evidence"]["held_out_fallback"]
    assert "largest held-out gain" in best["evidence"]["held_out_fallback"]
    assert best["evidence"]["cv_gain_um2"] >= first["evidence"]["cv_gain_um2"]


def test_confounded_fallback_least_inflation(monkeypatch):
    """Session 25 (conf25): the confounded step's variant that takes, of the cause's passing forms, the one of least
    variance inflation (``CONFOUNDED_FALLBACK_LEAST_INFLATION``, on since session 26: measured on every effect).
    gen_a c_drift 1267 (1.31 sigma): the creep after each indexing is confounded (inflation 1.08e3); the step by
    gain takes its degree 2, a near-confounded neighbour (extended workpiece 9.48 um off against 0.56 + U95 1.92);
    the least inflated passing form keeps the workpiece inside the baseline's U95 (0.19 um measured; asserted
    against the check itself, ``ext <= base + U95``, the study's workpiece aim)."""
    import core.discover as D
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    monkeypatch.setattr(D, "CONFOUNDED_FALLBACK_LEAST_INFLATION", False)
    monkeypatch.setattr(D, "CONFOUNDED_FALLBACK", True)
    monkeypatch.setattr(D, "CONFOUNDED_FALLBACK_BY_GAIN", True)
    # (session 32: HEDGED_SHIFT_CARRIED, on, covers the by-gain reading's error in its U95, 9.48 against 0.56 +
    # 9.69; switched off here to see the form's own failure, which the least inflated form mends by the estimate)
    monkeypatch.setattr(D, "HEDGED_SHIFT_CARRIED", None)
    # (session 35: WORKPIECE_U95_GROWTH_WITHHELD, on, withholds that reading's extended workpiece; off here too, to
    # see the form's own estimate)
    monkeypatch.setattr(D, "WORKPIECE_U95_GROWTH_WITHHELD", False)
    gain = blind_outcome(gen_a, "c_drift", 1267, generator="gen_a")
    assert gain.cause == "c_drift" and gain.wp_ext_um > gain.wp_base_um + gain.wp_u95_um
    monkeypatch.setattr(D, "CONFOUNDED_FALLBACK_LEAST_INFLATION", True)
    o = blind_outcome(gen_a, "c_drift", 1267, generator="gen_a")
    assert o.cause == "c_drift", o.cause
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, (o.wp_ext_um, o.wp_base_um, o.wp_u95_um)


def test_confounded_step_by_least_inflation_names_c_drift_1125(monkeypatch):
    """Session 26 (conf26): the confounded step on by default, taking the least inflated of the cause's passing forms
    (``CONFOUNDED_FALLBACK_LEAST_INFLATION``; measured on every effect of gen_a/gen_b 1000-1099 and the simulator
    4000-4049). gen_a c_drift 1125 (1.25 sigma): c_drift's form of smallest p, the quadratic over the campaign, is
    confounded with the baseline (inflation 370); of its three other forms that pass every test, the least
    inflated (10.8) is named, and the extended workpiece stays inside the check (0.44 um against the baseline's 0.71
    + U95 0.50: the study's aim ``ext <= base + U95``). With the switch off the step is never taken and the campaign
    reads `unexplained`, confidently: a miss."""
    import core.discover as D
    from core.touches import from_log
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    assert D.CONFOUNDED_FALLBACK is False and D.CONFOUNDED_FALLBACK_BY_GAIN is False
    log, _ = gen_a.generate("c_drift", 1125)
    t = from_log(log)

    def run():
        return discovered(log, t).to_report()

    rep = run()
    assert rep["cause"] == "c_drift", rep["rejected"]
    step = rep["findings"][0]["evidence"]["held_out_fallback"]
    assert "confounded" in step and "least variance inflation" in step, step
    o = blind_outcome(gen_a, "c_drift", 1125, generator="gen_a")
    assert o.cause == "c_drift" and o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, (o.wp_ext_um, o.wp_base_um,
                                                                                  o.wp_u95_um)
    monkeypatch.setattr(D, "CONFOUNDED_FALLBACK_LEAST_INFLATION", False)
    assert run()["cause"] == "unexplained"


@pytest.mark.parametrize("vals, u95, oriented", [
    # gen_a lobing_per_setup 1040 (rounded): orientations 60 +- 80 deg, the vectors 1.95 +- 0.28 um apart
    ({"amplitude_um": 1.30, "circle_residual_um": 0.007, "spread_um": 1.95, "orientation_spread_deg": 59.7},
     {"amplitude_um": 0.11, "circle_residual_um": 0.21, "spread_um": 0.28, "orientation_spread_deg": 79.6}, False),
    # the same orientations, the vectors apart by less than their U95: an oriented probe
    ({"amplitude_um": 0.50, "circle_residual_um": 0.007, "spread_um": 0.25, "orientation_spread_deg": 59.7},
     {"amplitude_um": 0.11, "circle_residual_um": 0.21, "spread_um": 0.28, "orientation_spread_deg": 79.6}, True),
    # no U95 of the vectors' spread: the orientations decide, as before
    ({"amplitude_um": 1.30, "circle_residual_um": 0.007, "spread_um": 1.95, "orientation_spread_deg": 59.7},
     {"amplitude_um": 0.11, "circle_residual_um": 0.21, "orientation_spread_deg": 79.6}, True),
    # a U95 that is not a number is no U95 (session 18 review: NaN compared false and let the lobes turn)
    ({"amplitude_um": 1.30, "circle_residual_um": 0.007, "spread_um": 1.95, "orientation_spread_deg": 59.7},
     {"amplitude_um": 0.11, "circle_residual_um": 0.21, "spread_um": float("nan"),
      "orientation_spread_deg": 79.6}, True),
    # orientations apart beyond their U95: turned, whatever the vectors
    ({"amplitude_um": 0.50, "circle_residual_um": 0.007, "spread_um": 0.25, "orientation_spread_deg": 40.0},
     {"amplitude_um": 0.11, "circle_residual_um": 0.21, "spread_um": 0.28, "orientation_spread_deg": 10.0}, False),
])


def test_lobes_per_setup_oriented_only_where_the_vectors_agree(vals, u95, oriented):
    """unoriented_plausible: the probe is called oriented (the lobes per set-up implausible) only when the set-ups'
    lobing vectors agree within their U95 as well as the orientations: orientations are angles about the circle's
    centre, which three or four set-ups barely determine."""
    r = causes.unoriented_plausible(vals, u95)
    assert (r is not None and "oriented" in r) is oriented, r


@pytest.mark.parametrize("seed", [1004, 1036, 1040])
def test_gen_a_lobing_per_setup_not_called_oriented_on_its_orientations_alone(seed):
    """The tuning misses this was written from: gen_a lobing_per_setup 1004, 1036, 1040 (3.3, 1.2, 2.0 sigma
    visible; three or four set-ups) read `unexplained`: both trials of the lobes per set-up refused as an
    oriented probe, the orientations' spread (15-60 deg) within its U95 (43-80 deg), while the set-ups' lobing
    vectors lay apart by 3-7 times their U95 and the fixed lobes were refused (held-out loss, or a share 0.50
    of the azimuth's structure). Named `lobing_per_setup` now; the engine before reads `unexplained` (fails)."""
    from scenarios.blind import gen_a

    log, tr = gen_a.generate("lobing_per_setup", seed)
    rep = discovered(log).to_report()
    assert rep["findings"][0]["cause"] == "lobing_per_setup", rep["rejected"]
    assert not any("oriented" in r["reason"] for r in rep["rejected"] if r["cause"] == "lobing_per_setup")


@pytest.mark.parametrize("seed", [1322, 1340])
def test_gen_a_thermal_bending_part_change_beside_a_smooth_of_its_own_covariate_in_doubt(monkeypatch, seed):
    """gen_a thermal_bending 1322 and 1340 (tuning seeds; out of catalogue, acceptable `unexplained` or
    `thermal_drift`) read `part_change` confidently on main d95fcb3 (session 18): the bending, growing in time
    and quadratic in x, moves every feature, and the cause takes one (bore4, bore1); an unnamed smooth in
    `feature`, the cause's own covariate, then earned a material held-out gain beside it (2.44 and
    0.132 um^2 per touch) and step 5 kept the cause as the smooth's refinement. That gain says the
    structure on the features has a form the cause lacks: the name must not stay confident (main fails).
    Session 22's confinement rule refuses the cause on both before this rule is reached (the test below);
    it is switched off here so that this rule is still the one tested."""
    import core.discover as D
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    monkeypatch.setattr(D, "PART_CHANGE_CONFINED", False)
    o = blind_outcome(gen_a, "thermal_bending", seed, generator="gen_a")
    assert o.cause == "part_change" and not o.confident, (o.cause, o.confident)


@pytest.mark.parametrize("effect, seed, fallback, gone, after", [
    # periodic_axis_error adopted in round one, part_change (wall10) beside it in round two; the rival check then
    # drops periodic_axis_error (share 0.60) and part_change stayed, adopted on its residuals
    ("thermal_bending", 1016, False, "periodic_axis_error", "part_change"),
    # with the held-out fallback: c_drift adopted on its second form, part_change beside it, c_drift dropped (share
    # 0.64 of a smooth term in the time within the set-up)
    ("part_change", 1008, True, "c_drift", "part_change"),
])


def test_cause_adopted_beside_a_dropped_cause_is_judged_again(monkeypatch, effect, seed, fallback, gone, after):
    """Issue 13 (session 18): a cause adopted after a cause the rival check later drops was searched with the
    dropped cause in the model. It is judged again by the search's tests beside the causes before it that stay,
    so every cause the report names was adopted beside the final model's earlier causes and no other (its
    adoption basis: the baseline's and theirs). Both campaigns kept the dependant adopted beside the dropped
    cause's columns before the change (session 17's blind gen_a thermal_bending 2400: part_change named,
    confidently, on a search c_drift opened). Session 22's confinement rule refuses thermal_bending 1016's
    part_change after it is judged again (wall10 moves as a whole while the other features move:
    `unexplained`); it is off here so that the judged-again dependant this test examines is still named. So is
    session 25's ENTRANT_FORM_HELD_OUT: on thermal_bending 1016 another wall's change (part_change's other form)
    takes round one from periodic_axis_error on held-out data, and the path this test examines (a cause dropped
    after a dependant was adopted beside it) is not taken (the outcome is the same, `unexplained`). So is session
    34's floor of the bump's half-width (core.causes.DEFECT_MIN_WIDTH_GAPS, 2.0 here as before): with the narrower
    bumps thermal_bending 1016 no longer takes that path either."""
    import core.causes as C
    import core.discover as D
    from core.touches import from_log
    from scenarios.blind import gen_a

    monkeypatch.setattr(D, "HELD_OUT_FALLBACK", fallback)
    monkeypatch.setattr(D, "PART_CHANGE_CONFINED", False)
    monkeypatch.setattr(D, "ENTRANT_FORM_HELD_OUT", False)
    monkeypatch.setattr(C, "DEFECT_MIN_WIDTH_GAPS", 2.0)
    log, _ = gen_a.generate(effect, seed)
    t = from_log(log)
    seen = {}
    findings = D._findings

    def keep(bl, terms, Qb, *a, **k):
        seen["terms"], seen["Qb"] = list(terms), Qb
        return findings(bl, terms, Qb, *a, **k)

    monkeypatch.setattr(D, "_findings", keep)
    rep = discovered(log, t).to_report()
    assert gone not in [f["cause"] for f in rep["findings"]]
    assert any(r["cause"] == gone and r["reason"].startswith(("explains only part", "a plainer explanation"))
               for r in rep["rejected"]), rep["rejected"]  # the rival check's words (_demotion_reason)
    k = seen["Qb"].shape[1]
    for tm in seen["terms"]:
        if tm.unnamed:
            continue
        assert tm.at_adoption[0].shape[1] == k, (tm.cause, tm.at_adoption[0].shape[1], k)
        k += tm.columns.shape[1] if tm.penalty is None else 0
    named = [f for f in rep["findings"] if f["cause"] == after]
    assert named and named[0]["evidence"].get("judged_again_without") == gone, rep["rejected"]


@pytest.mark.parametrize("effect, seed", [("probe_lobing", 1016), ("lobing_per_setup", 1050)])
def test_gen_b_lobes_not_refused_by_the_feature_term_that_nests_them(effect, seed):
    """Issue 13, session 18: gen_b probe_lobing 1016 (1.54 sigma) and lobing_per_setup 1050 (1.81) read
    `unexplained`: step 4e refused the lobes because the feature per set-up explained more (32.2 against 28.3,
    67.1 against 64.2 um^2). gen_b probes its slot walls and blade over narrow arcs, where a feature's offset in
    a set-up takes any function of the azimuth, the lobes' form error (the generator's six-lobe part) included;
    scaled to 10 sigmas (same campaign and noise) both still read `unexplained`: a refusal of form, not power.
    With the direction family nested by the feature term (``NESTING_FAMILIES``, as a position cause is) the
    lobes pass where they explain ``rival_share`` of that term; named, ambiguous."""

    log, tr, t, _ = _gen_b_baseline(effect, seed)
    rep = discovered(log, t).to_report()
    assert rep["cause"] in tr.acceptable_causes, rep["rejected"]


@pytest.mark.parametrize("gen, seed", [("gen_b", 1001), ("gen_b", 1059), ("gen_a", 1208)])
def test_plainer_of_one_explanation_leads(gen, seed):
    """Issue 13, session 19: gen_b reversal 1001 and 1059 (1.16, 1.41 sigma) and gen_a reversal 1208 read
    ``probe_lobing``, ambiguous with ``reversal``: every approach along the normal, the lost motion's two columns
    (``|n_x| / 2``, ``|n_y| / 2``: even harmonics of the azimuth) are one explanation with the fixed lobes'
    eight (harmonics 1-4) on these designs (they reproduce 0.98-0.99 of the lobes' signal and explain as much,
    the lobes nothing material beyond them), and round one took the lobes on their lower held-out mean square
    (gen_b 1001: 5.21 against 6.21 um^2, the baseline's 33.2 against an in-sample residual of 0.09: the
    set-ups' extrapolation, not the mechanism). The plainer of one explanation now leads the round
    (``_plainer_one_explanation``): reversal, still ambiguous with the lobes (the report says the data cannot
    tell them apart), and the lobes it was preferred to in its evidence."""
    import importlib

    mod = importlib.import_module(f"scenarios.blind.{gen}")
    log, _ = mod.generate("reversal", seed)
    rep = discovered(log).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "reversal", (f["cause"], rep["rejected"])
    assert f["evidence"]["plainer_than"]["cause"] == "probe_lobing", f["evidence"].get("plainer_than")
    assert f["evidence"]["confidence"] == "ambiguous"


# --- session 19 (issue 13): position and direction causes and the feature term that nests them ---------------------

def _gen_a_report(effect, seed):
    from scenarios.blind import gen_a

    log, tr = gen_a.generate(effect, seed)
    return tr, discovered(log).to_report()


def test_fine_position_smooth_holds_the_diagnosis_xy_term():
    """The position family's fine smooth (step 4e's own figure against a nesting term) spans the diagnosis'
    ``xy`` term (its products of total degree 4 are among its own), in each axis' error."""
    from core.baseline import _xy_basis
    from core.discover import FINE_POSITION_DEGREE, _fine_position

    bl = planar(S.plan(), 30.0)
    F = _fine_position(bl)
    k = sum(1 for i in range(1, FINE_POSITION_DEGREE) for j in range(1, FINE_POSITION_DEGREE)
            if i + j <= FINE_POSITION_DEGREE)
    assert F.shape == (bl.data.xs.size, 2 * k)
    B = _xy_basis(bl.data.xs, bl.data.ys)
    Q = orth_of(F)
    for n in (bl.data.nx, bl.data.ny):
        E = -n[:, None] * B
        assert np.linalg.norm(E - Q @ (Q.T @ E)) <= 1e-9 * np.linalg.norm(E)


def test_gen_a_nonrigid_1048_not_refused_by_the_feature_term_at_the_xy_terms_resolution():
    """Issue 13, session 19: gen_a nonrigid 1048 (6.23 sigma; the coupling's half-waves 100 and 107 mm over a
    260 mm extent, two to three sign changes along each stroke) read `unexplained`: step 4e refused `nonrigid`
    because the feature per set-up explained more (1,000 against 644 um^2), the family's own figure being the
    diagnosis' degree-4 ``xy`` term, coarser than the field. The feature term nests a position cause; measured
    against the position family's fine smooth it is the same structure, and the cause is named (ambiguous)."""
    tr, rep = _gen_a_report("nonrigid", 1048)
    assert rep["cause"] in tr.acceptable_causes, rep["rejected"]
    assert not any(r["cause"] == "nonrigid" and r["reason"].startswith("the structure follows feature")
                   for r in rep["rejected"]), rep["rejected"]


def test_gen_a_reversal_1054_not_dropped_for_the_feature_smooth_that_nests_it():
    """Issue 13, session 19: gen_a reversal 1054 (5.88 sigma) read `unexplained`: the reversal was adopted, then
    step 5 dropped it as redundant beside the unnamed smooth in `feature`, a term that nests a direction cause on
    the design (a bore's lost motion is its size per set-up: ``NESTING_FAMILIES``). Step 4e already judges such a
    term as the cause's own covariate's; step 5 now does too, and the reversal stays, named."""
    tr, rep = _gen_a_report("reversal", 1054)
    assert rep["cause"] in tr.acceptable_causes, rep["rejected"]
    assert not any(r["cause"] == "reversal" and r["reason"].startswith("no material gain once the unnamed")
                   for r in rep["rejected"]), rep["rejected"]


def test_clock_sensors_known_answers():
    """A reading that is an exponential settling of time plus its rounding is a clock; a thermostat's cycle
    (a triangle of a few minutes' period) is not; a constant sensor gives nothing (no expansion either)."""
    from types import SimpleNamespace

    rng = np.random.default_rng(3)
    setup = np.repeat(np.arange(5), 60)
    t_s = np.sort(rng.uniform(0, 1, setup.size)) * 60.0 + setup * 900.0   # five set-ups of a minute, 15 min apart
    tau = (t_s - t_s[0]) / np.ptp(t_s)
    spindle = np.round(22.0 + 3.0 * np.exp(-t_s / 1800.0) + rng.normal(0, 0.004, t_s.size), 2)
    tri = 2.0 * np.abs(2.0 * ((t_s / 400.0) % 1.0) - 1.0) - 1.0
    air = np.round(20.0 + 0.5 * tri + rng.normal(0, 0.004, t_s.size), 2)
    d = SimpleNamespace(tau=tau, span_s=float(np.ptp(t_s)), touches=SimpleNamespace(setup=setup),
                        temps={"temp_spindle_C": spindle, "temp_air_C": air, "temp_bed_C": np.full(t_s.size, 20.0)})
    clocks = causes.clock_sensors(d)
    assert list(clocks) == ["temp_spindle_C"], clocks
    c = clocks["temp_spindle_C"]
    assert c["time_fit_rms_K"] <= causes.CLOCK_RATIO * c["scatter_rms_K"]
    assert 0.002 < c["scatter_rms_K"] < 0.008, c   # rounding (2.9 mK) and noise (4 mK)


def test_clock_sensors_made_once_for_the_drift_and_the_expansion_scans(monkeypatch):
    """Session 20: the drift's scans and the expansion's take one campaign's clock sensors from one
    computation (kept on its data), with the same layouts as each computing its own."""
    from types import SimpleNamespace

    rng = np.random.default_rng(3)
    setup = np.repeat(np.arange(5), 60)
    t_s = np.sort(rng.uniform(0, 1, setup.size)) * 60.0 + setup * 900.0
    tau = (t_s - t_s[0]) / np.ptp(t_s)
    spindle = np.round(22.0 + 3.0 * np.exp(-t_s / 1800.0) + rng.normal(0, 0.004, t_s.size), 2)
    air = np.round(20.0 + 0.5 * np.sin(t_s / 300.0) + rng.normal(0, 0.004, t_s.size), 2)
    a = rng.uniform(0, 2 * np.pi, t_s.size)

    def campaign():
        return SimpleNamespace(data=SimpleNamespace(
            tau=tau, span_s=float(np.ptp(t_s)), touches=SimpleNamespace(setup=setup),
            temps={"temp_spindle_C": spindle, "temp_air_C": air}, x=rng.uniform(0, 0.1, t_s.size),
            y=rng.uniform(0, 0.1, t_s.size), xs=np.cos(a), ys=np.sin(a), nx=np.cos(a), ny=np.sin(a)))

    bl = campaign()
    alone = (causes.drift_scans(bl), causes.expansion_scans(bl))
    calls = []
    real = causes.clock_sensors
    monkeypatch.setattr(causes, "clock_sensors", lambda d: calls.append(d) or real(d))
    bl = campaign()
    shared = (causes.drift_scans(bl), causes.expansion_scans(bl))
    assert len(calls) == 1 and calls[0] is bl.data
    for (s_a, n_a), (s_s, n_s) in zip(alone, shared):
        assert n_a == n_s and [(s.labels, s.infos) for s in s_a] == [(s.labels, s.infos) for s in s_s]
    assert [s.infos[0].get("sensor") for s in shared[0][0] if "sensor" in s.infos[0]] == ["temp_spindle_C"]
    assert [s.infos[0]["sensor"] for s in shared[1][0]] == ["temp_air_C"]


@pytest.mark.parametrize("seed", [1038, 1091])
def test_gen_b_thermal_drift_not_read_on_the_clock_sensor(seed):
    """Issue 13, session 19: gen_b thermal_drift 1016, 1023, 1035, 1038, 1073, 1080, 1091, 1098 read
    `temperature_expansion` on ``temp_spindle_C``, ambiguous with `thermal_drift`: that sensor settles
    exponentially (a cubic in time leaves its 0.01 K rounding), a time shape the drift's in-sample-chosen
    polynomial lacks, and its four columns won round one. A clock carries no evidence of itself
    (:func:`core.causes.clock_sensors`): its expansion is the drift's, tried as the drift's layout, with the
    sensor named in the finding's parameters. 1038 (2.0 sigma) and 1091 (1.08) are named `thermal_drift`,
    confidently, on the sensor's course."""

    log, tr, t, bl = _gen_b_baseline("thermal_drift", seed)
    assert set(causes.clock_sensors(bl.data)) == {"temp_spindle_C"}
    rep = discovered(log, t).to_report()
    assert rep["cause"] == "thermal_drift", rep["rejected"]
    f = rep["findings"][0]
    assert f["evidence"]["confidence"] == "named", f["evidence"]
    assert f["params"].get("sensor") == "temp_spindle_C", f["params"]


def test_part_change_time_forms_step_per_setup(monkeypatch):
    """part_change's two time forms (:func:`core.causes.part_change_times`): the continuous one is the campaign's
    normalised time; the step per set-up is constant within each set-up, 0 on the first and 1 on the last, the
    set-ups between at their mean time's place. Every feature's layouts come in both forms, the count of trials
    (the Bonferroni factor) covering both (gen_b none 1010). Both forms are on by default (session 20); with the
    continuous form alone (``PART_CHANGE_FORMS``, the behaviour before) there is no step form."""
    assert causes.PART_CHANGE_FORMS == ("continuous", "per_setup")
    monkeypatch.setattr(causes, "PART_CHANGE_FORMS", ("continuous",))
    assert [f for f, _ in causes.part_change_times(_gen_b_baseline("none", 1010)[3])] == ["continuous"]
    monkeypatch.setattr(causes, "PART_CHANGE_FORMS", ("continuous", "per_setup"))
    _, _, t, bl = _gen_b_baseline("none", 1010)
    forms = dict(causes.part_change_times(bl))
    assert list(forms) == ["continuous", "per_setup"]
    assert np.array_equal(forms["continuous"], bl.data.tau)
    step = forms["per_setup"]
    setups = np.asarray(t.setup)
    order = sorted(set(setups.tolist()), key=lambda s: t.t_s[setups == s].min())
    means = []
    for s in order:
        v = step[setups == s]
        assert np.ptp(v) == 0.0, s
        means.append(float(np.mean(bl.data.tau[setups == s])))
    assert step[setups == order[0]][0] == 0.0 and abs(step[setups == order[-1]][0] - 1.0) < 1e-12
    expect = (np.array(means) - means[0]) / (means[-1] - means[0])
    assert np.allclose([step[setups == s][0] for s in order], expect, rtol=0, atol=1e-12)
    scans, count = causes.part_change_scans(bl)
    by_form = {f: [(s.infos[0]["feature"], s.labels) for s in scans if s.infos[0]["time_form"] == f]
               for f in forms}
    assert by_form["continuous"] == by_form["per_setup"] and count == len(scans) == 2 * len(by_form["per_setup"])


@pytest.mark.parametrize("seed", [4077, 4079])
def test_sim_part_change_named_in_its_step_per_setup_form(seed):
    """Issue 13 (session 19): the simulator grows its pocket's wall by a step per set-up
    (``scenarios.hidden._grown_wall``), where part_change's columns grew continuously with the time; at sim
    part_change 4077 (1.23 sigma) and 4079 (1.47) the lobes per set-up won round one on the held-out gain and
    the campaigns read lobing_per_setup (ambiguous). With the step per set-up a second time form of every layout
    (both counted in the Bonferroni factor; the step kept where it is significant beyond the continuous form and
    not the reverse, ``core.discover._time_forms_chosen``) part_change is named (ambiguous) in the step form, its
    form in the parameters. (gen_b part_change 1010's test guards the other side: a continuous change keeps the
    continuous form; chosen by p alone the step took it there and the slip check refused it.) The step form was
    withheld in session 19 (gen_b stylus_pickup 1012's workpiece) and is on by default since session 20, where the
    steps must also be significant beyond one step at one set-up change (here p 1.6e-26 and 9.0e-37 on four
    set-ups): the test runs the default."""
    from scenarios.hidden import hidden_campaign

    log, _ = hidden_campaign(("part_change",), seed)
    rep = discovered(log).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "part_change" and f["params"]["feature"] == "pocket", (rep["cause"], rep["rejected"])
    assert f["params"]["time_form"] == "per_setup", f["params"]


def test_plainer_rule_judges_the_winner_beyond_it_at_the_plainer_models_sigma():
    """Issue 13, session 19 (lead): gen_a probe_lobing 4100 (4.3 sigma; found on the lead's blind seeds, kept
    here as a regression case). In round one the lost motion's two columns reproduce the lobes' signal, and the
    lobes' 128 um^2 beyond it (p 9e-60) fell below a materiality set by the round's sigma, 2.43 um, which still
    carries the lobes (the generator's noise is 0.2 um): the plainer name led, the lobes were refused next round
    and the azimuth kept 0.73 um. Judged at the sigma of the model with the lost motion in it the lobes stand."""
    from scenarios.blind import gen_a

    log, tr = gen_a.generate("probe_lobing", 4100)
    rep = discovered(log).to_report()
    assert rep["cause"] == "probe_lobing", rep["rejected"]
    assert "plainer_than" not in rep["findings"][0]["evidence"]


def test_centred_sign_known_answers():
    """centred_sign_of on written-out touches: the lost-motion column ``n_ax sign(d_ax)`` less its target's mean;
    a target approached with one sign along an axis has 0 there (its parameter absorbs the lost motion), one
    approached with both (an approach nearly across the axis) keeps +- half the step; an approach with no
    component along the axis takes sign 0, as the catalogue's column does."""
    from core.discover import centred_sign_of

    n = np.array([[1.0, 0, 0], [1.0, 0, 0], [0.1, 0.995, 0], [-0.1, 0.995, 0], [0.0, -1.0, 0]])
    d = np.array([[-1.0, 0, 0], [-0.9, 0.1, 0], [0.05, -0.99, 0], [-0.05, -0.99, 0], [0.0, 1.0, 0]])
    tg = np.array([0, 0, 1, 1, 2])
    c = centred_sign_of(n, d, tg)
    assert c.shape == (5, 2)
    assert np.allclose(c[:2], 0.0) and np.allclose(c[4], 0.0)
    # target 1: n_x sign(d_x) = +0.1 and +0.1 (both normals' x and approaches' x of one sign each: 0.1*1, -0.1*-1)
    assert np.allclose(c[2:4, 0], 0.0)
    d2 = d.copy()
    d2[3, 0] = 0.05  # the second touch of target 1 now approaches with +x: -0.1 * +1 = -0.1 against +0.1
    c2 = centred_sign_of(n, d2, tg)
    assert np.allclose(c2[2:4, 0], [0.1, -0.1]) and np.allclose(c2[:, 1], 0.0)
    d3 = d2.copy()
    d3[3, 0] = 0.0  # no component along x: sign 0, the column 0, the mean 0.05
    assert np.allclose(centred_sign_of(n, d3, tg)[2:4, 0], [0.05, -0.05])
    with pytest.raises(Exception):
        centred_sign_of(n[:, :2], d, tg)


def test_near_across_known_answers():
    """near_across_p where the null is exact: the two touches with the smallest |d_ax| of 100 distinct
    values, drawn with replacement, are matched or beaten by about 3 draws in 10,000 (S <= log(1/100) +
    log(2/100): both draws in the lowest two, or one at the lowest and the other within the lowest two,
    P = 3 / 10,000); rows at the largest values give p 1; ties take the largest rank (100 equal values: p 1
    whatever the rows); bad input raises."""
    from core.discover import near_across_p

    a = np.linspace(0.0, 1.0, 100)
    p = near_across_p(a, np.array([0, 1]), np.random.default_rng(3), draws=400_000)
    assert abs(p - 3e-4) < 6e-5, p
    assert near_across_p(a, np.array([98, 99]), np.random.default_rng(3), draws=2000) == 1.0
    assert near_across_p(np.ones(100), np.array([0, 1]), np.random.default_rng(3), draws=2000) == 1.0
    with pytest.raises(Exception):
        near_across_p(a, np.array([100]), np.random.default_rng(3))


def test_outliers_on_a_lost_motions_visible_part_are_not_confidently_dust(monkeypatch):
    """gen_a reversal 1033 (tuning seed; Y lost motion 30 um, 1.06 sigma beyond the baseline by the study's
    count): the catalogue's reversal column is the generator's exactly here (correlation 1 over all 256
    touches), but it lies almost inside the baseline's span (refused as confounded, variance inflation
    1.7e3): every target is approached with one sign along Y except those whose normal is nearly across
    it, and there the target's parameter leaves +- half the step. Two such touches (rows 34 and 178, n_y
    +-0.118, residuals +2.04 and +2.30 um at 0.24 um noise) are all the data show of it, and the outlier
    screen sets them aside: `outlier`, confident, before session 20 (a confident misnaming). Their residuals
    follow the centred sign of approach along Y (:func:`core.discover.centred_sign_of`) and they sit on the
    touches whose approach moves Y least (:func:`core.discover.near_across_p`); the family's p
    (:func:`core.discover.approach_sign_p`, Bonferroni over its four tests) is below alpha_family, so the
    finding is ambiguous, with reversal as its alternative.

    Session 21: with the lobes' second reading (a pre-travel along the approach, times -(n . d):
    :data:`core.causes.PRETRAVEL_ALONG`) probe_lobing explains those touches first (p 4e-10), named ambiguous
    with reversal: still not confident. The outlier rule is checked with the lobes read as before (one reading:
    :data:`core.causes.ALONG_NORMAL_TOL` infinite)."""
    from core import causes
    from core.touches import from_log
    from scenarios.blind import gen_a

    log, tr = gen_a.generate("reversal", 1033)
    t = from_log(log)
    rep = discovered(log, t).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "probe_lobing" and f["params"]["pretravel_along"] == "approach", f["params"]
    assert f["evidence"]["confidence"] == "ambiguous" and f["evidence"]["ambiguous_with"] == ["reversal"]
    monkeypatch.setattr(causes, "ALONG_NORMAL_TOL", np.inf)
    rep = discovered(log, t).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "outlier" and sorted(f["evidence"]["rows"]) == [34, 178], f["evidence"]
    assert f["evidence"]["approach_sign_p"] < 0.0025, f["evidence"]
    assert f["evidence"]["confidence"] == "ambiguous", f["evidence"]
    assert f["evidence"]["ambiguous_with"] == ["reversal"], f["evidence"]


def test_outliers_a_lost_motion_cannot_reach_are_not_evidence_for_reversal():
    """The review of csign's nearly-across test: it ranked touches by |d_ax| only, though a lost motion moves a
    touch by at most |n_ax| |B|. gen_a outlier 1000 (tuning seed; its own outliers rows 48, 171, 315 named,
    confident) with 3 um put along the normal on the three touches nearest across X (rows 79, 85, 88: |d_x|
    0.033, 0.034, 0.002, |n_x| 0.034, 0.034, 0.002): row 88 needs |B| >= 1,200 um along X to read 2.3 um, beyond
    the reversal cause's plausible 100 um, so no lost motion made it. Before the fix the family's p was 1.3e-3
    (nearly across along X) and the finding ambiguous with reversal; counting only the outliers whose |n_ax|
    times the bound reaches their residual, it stays a confident `outlier` (p 0.058)."""
    import dataclasses

    from core.touches import from_log
    from scenarios.blind import gen_a

    log, tr = gen_a.generate("outlier", 1000)
    t = from_log(log)
    rows = [79, 85, 88]
    assert np.all(np.abs(t.d_R[rows, 0]) < 0.05) and np.all(np.abs(t.n_R[rows, 0]) < 0.05)
    p = t.p_R.copy()
    p[rows] += 3e-6 * t.n_R[rows]
    t = dataclasses.replace(t, p_R=p)
    rep = discovered(log, t).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "outlier" and set(rows) <= set(f["evidence"]["rows"]), f["evidence"]
    assert f["evidence"]["approach_sign_p"] >= 0.0025, f["evidence"]
    assert f["evidence"]["confidence"] == "named", f["evidence"]
    assert "ambiguous_with" not in f["evidence"], f["evidence"]


# --- session 20 (issue 13): a penalised named cause's ridge chosen again in the model the report gives --------------

@pytest.mark.parametrize("seed", [1001, 1092])
def test_gen_a_nonrigid_penalty_chosen_again_in_the_final_model(monkeypatch, seed):
    """Issue 13, session 20: gen_a nonrigid 1001 (6.75 sigma) and 1092 read `unexplained`, `nonrigid` second. The
    field's ridge was chosen in the round that adopted it (1001: 10 times the scale) and kept when the model was
    final (rows, terms beside it); beside it the unnamed smooth in ``xy`` (the same twelve columns) was adopted at
    a ridge of 1 and, explaining more than the over-shrunk field, named first (1092: the structure left beside the
    field at 1 outweighed it, where 0.1 predicts the held-out set-ups best). Chosen again over the same grid in the
    final model, the field is named first; switched off, the miss comes back (the test can fail)."""
    import core.discover as D

    tr, rep = _gen_a_report("nonrigid", seed)
    assert rep["cause"] == "nonrigid", [f["cause"] for f in rep["findings"]]
    ev = rep["findings"][0]["evidence"]
    assert ev["penalty"] != ev["penalty_at_adoption"]
    monkeypatch.setattr(D, "PENALTY_RECHOSEN", False)
    tr, rep = _gen_a_report("nonrigid", seed)
    assert rep["cause"] == "unexplained"


def test_a_step_at_one_setup_change_is_not_a_part_changing_at_every_setup(monkeypatch):
    """Issue 13 (session 20): gen_b stylus_pickup 1012 (out of the catalogue: the stylus picks up material and is
    wiped before some set-ups, a radius that steps at a set-up change). With part_change's step per set-up on, its
    slot's steps were significant beyond the continuous form (and not the reverse) and chosen; part_change in the
    step form was then named beside a thermal drift (both ambiguous), the extended workpiece 7.71 um off against
    the baseline's 1.72 (U95 2.80). Its set-ups' levels (0, 0.445, 1) are one jump: the slot stepping once, at the
    second set-up change, explains 17.1 of the steps' 18.5 um^2 and the steps are not significant beyond it
    (p 0.0068), so the continuous form is the slot's trial (``core.discover._steps_beyond_one_off``) and the
    campaign reads `unexplained`, as with the continuous form alone. The simulator's wall grown at every set-up
    (4077, 4079: the steps beyond the best one-off step at p 1e-26, 1e-36) keeps its step form (their test)."""
    from core import discover as D

    monkeypatch.setattr(causes, "PART_CHANGE_FORMS", ("continuous", "per_setup"))
    assert D.STEP_BEYOND_ONE_OFF
    log, tr, t, _ = _gen_b_baseline("stylus_pickup", 1012)
    rep = discovered(log, t).to_report()
    assert rep["cause"] == "unexplained", [(f["cause"], f["params"].get("time_form")) for f in rep["findings"]]
    assert not any(f["cause"] == "part_change" for f in rep["findings"])


def test_gen_b_part_change_1004_a_slip_seen_on_the_slot_alone_is_ambiguous_not_a_refusal(monkeypatch):
    """Issue 13 (session 21): gen_b part_change 1004 (1.23 sigma visible, the slot closing like 1 - exp(-t/tau))
    read `unexplained`: the best fixture slip, a step after the slot's first wall in the first set-up, explains
    12.4 of part_change's 16.5 um^2 and part_change is not significant beyond it (p 0.79), so the slip check
    refused it. That slip moves the slot's second wall and the blade's drift-check re-touches; a slip of the part
    would move the re-touches too, and they did not (the slip's columns off the slot, p 0.76): the step is seen
    through the slot alone, which the data cannot tell from the slot changing. Named, ambiguous with the slip
    (``core.discover._slip_off_feature``); with the rule off, `unexplained` as before."""
    from core import discover as D

    log, tr, t, _ = _gen_b_baseline("part_change", 1004)
    assert "part_change" in tr.acceptable_causes

    def run():
        return discovered(log, t).to_report()

    rep = run()
    f = rep["findings"][0]
    assert f["cause"] == "part_change" and f["params"]["feature"] == "slot", rep["cause"]
    ev = f["evidence"]
    assert ev["confidence"] == "ambiguous" and ev["indistinguishable_counter"] == "fixture slip"
    assert ev["p_slip_off_feature"] > 0.5 and ev["p_adjusted_beyond_slip"] > 0.5
    monkeypatch.setattr(D, "SLIP_OFF_FEATURE", False)
    assert run()["cause"] == "unexplained"


def test_gen_b_fixture_slip_1195_a_slip_seen_off_the_slot_still_refuses_part_change(monkeypatch):
    """The counterpart (session 21): gen_b fixture_slip 1195 (out of the catalogue) reaches the slip check with
    part_change on the slot; the slip moves the other features probed after it as well (its columns off the
    slot, p 4e-66), so it is a slip of the part and part_change stays refused. Session 23: with the repeat pairs
    that straddle the slip set aside from the noise floor (``REPEATS_STRADDLED``) part_change no longer reaches the
    slip check here (the report is `unexplained` as before, no part_change): the check is exercised with that rule
    off, and the default's report is asserted too."""
    from core import discover as D

    log, tr, t, _ = _gen_b_baseline("fixture_slip", 1195)
    rep = discovered(log, t).to_report()
    assert not any(f["cause"] == "part_change" for f in rep["findings"]), rep["cause"]
    seen = []
    off = D._slip_off_feature
    monkeypatch.setattr(D, "_slip_off_feature", lambda *a: seen.append(off(*a)) or seen[-1])
    monkeypatch.setattr(D, "REPEATS_STRADDLED", False)
    rep = discovered(log, t).to_report()
    assert not any(f["cause"] == "part_change" for f in rep["findings"]), rep["cause"]
    assert seen and max(seen) < 1e-10, seen


def test_the_slip_off_the_feature_leaves_out_all_the_features_touches(monkeypatch):
    """The session 21 review: in part_change's step-per-set-up form the cause's columns are 0 on the first
    set-up, so "off the feature" taken from the columns' support counted the slot's first-set-up touches as
    off it, exactly where gen_b's refusing slip sits: with the form forced, gen_b part_change 1001's slip was
    "seen elsewhere" at p 1e-17 through the slot's own touches. The feature's rows are its touches."""
    from core import causes as C
    from core import discover as D

    seen = []
    off = D._slip_off_feature
    monkeypatch.setattr(D, "_slip_off_feature", lambda *a: seen.append((off(*a), off(*a[:3]))) or seen[-1][0])
    monkeypatch.setattr(C, "PART_CHANGE_FORMS", ("per_setup",))
    log, tr, t, _ = _gen_b_baseline("part_change", 1001)
    discovered(log, t)
    assert seen, "the slip check never reached the test"
    # with the feature's touches: the slip is not seen off the slot; from the columns' support alone it was
    assert min(p for p, _ in seen) > 0.01 and min(q for _, q in seen) < 1e-10, seen


# --- session 21 (issue 13): a re-chosen ridge passes the adoption gates again ----------------------------------------

def test_a_field_whose_rechosen_ridge_leaves_no_held_out_gain_is_refused(monkeypatch):
    """Issue 13, session 21: gen_b nonrigid 1003 (0.68 sigma). `nonrigid` was adopted at a ridge of 1 (times its
    scale); chosen again in the final model (session 20) its ridge is the grid's largest, 100, and there the field
    predicts the held-out set-ups no better than the model without it (gain -0.0004 um^2 against a materiality of
    0.0037): the held-out set-ups ask for no field. The gates of its adoption that depend on the ridge are run
    again at the ridge chosen (``core.discover._rechosen_gate``) and it is refused, said so in ``rejected``; with
    the gate off it is the report's second finding (the test can fail)."""
    import core.discover as D
    from scenarios.blind import gen_b

    def report():
        log, tr = gen_b.generate("nonrigid", 1003)
        return discovered(log).to_report()

    rep = report()
    assert not any(f["cause"] == "nonrigid" for f in rep["findings"]), [f["cause"] for f in rep["findings"]]
    why = [r["reason"] for r in rep["rejected"] if r["cause"] == "nonrigid"]
    assert any("ridge chosen again in the final model" in w and "the grid's largest" in w and "below materiality" in w
               for w in why), why
    monkeypatch.setattr(D, "PENALTY_RECHOSEN_GATED", False)
    rep = report()
    assert [f["cause"] for f in rep["findings"]][:2] == ["unexplained", "nonrigid"]


@pytest.mark.parametrize("seed", [1139, 1322])
def test_gen_a_thermal_bending_part_change_refused_where_every_feature_moves(seed):
    """gen_a thermal_bending 1139 (tuning seed; out of the catalogue, acceptable `unexplained` or
    `thermal_drift`) read `part_change` confidently before session 22: the X guideway's bending (``EYX`` quadratic
    in x, growing as it warms) moves every feature by the error at its place, nearly a translation over one
    feature; the cause took slot1 (walls 135 and 315 deg moving +23.6 and -22.5 um: the slot moving as a whole,
    its width unchanged). A change of the part changes the feature's form and leaves the other features still:
    here the change is nothing beyond the slot's rigid motion (p 0.48) and the other features' translations in
    the same time form explain 86 um^2 beside it (p < 1e-6), so the cause is refused and the structure left
    `unexplained` (fails before: `part_change`, named). 1322 read `part_change` ambiguous (session 18's rule)."""
    from scenarios.blind import gen_a

    log, _ = gen_a.generate("thermal_bending", seed)
    rep = discovered(log).to_report()
    assert "part_change" not in [f["cause"] for f in rep["findings"]], rep["findings"][0]["cause"]
    assert rep["cause"] == "unexplained"
    assert any(r["cause"] == "part_change" and r["reason"].startswith("not the feature's own change")
               for r in rep["rejected"]), rep["rejected"]


def test_gen_a_part_change_kept_where_its_form_changes_though_others_move():
    """gen_a part_change 1016 (tuning seed): a boss ovalising. The other features' translations are significant
    and material beside it (an unexplained rest: p 1.7e-19, 15.7 um^2), but the boss' change is a change of its
    form (its ovalisation beyond its rigid motion, p 1e-82): the confinement rule refuses only a feature that
    moves as a whole, and part_change stays named."""
    from scenarios.blind import gen_a

    log, _ = gen_a.generate("part_change", 1016)
    rep = discovered(log).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "part_change"
    o = f["evidence"]["other_features"]
    assert o["others_move_p"] < 1e-6 and o["form_beyond_rigid_p"] < 1e-6 and not o["refused"], o


@pytest.mark.parametrize("effect, seed, refused", [("part_change", 1293, False), ("part_change", 1156, False),
                                                   ("thermal_bending", 1015, True)])
def test_the_confinement_rule_at_its_margins_where_the_feature_has_no_form_direction(effect, seed, refused):
    """Session 23 (docs/discovery.md, "Session 23: the margins of the confinement rule and of the chip gate"): on
    gen_a 1000-1399 the true part changes seen only as a place (a wall's shift: the change has no direction
    beyond the feature's rigid motion) nearest a refusal are 1293 and 1156: the other features' translations at
    p 0.011 (against alpha_family 0.0025) and immaterial (0.72 against 1.13 um^2, 3.24 against 5.63); the
    thermal bending refused nearest keeping part_change is 1015 (slot2: p 0.0019, 2.69 against 2.48 um^2). The
    rule keeps the two changes and refuses the bending. A rule made stricter on the bending's side (1015 is
    1.3x inside in p, 1.09x in materiality) fails on 1015; one that refuses on p alone at 0.05 fails on 1293 and
    1156. With the rule off (PART_CHANGE_CONFINED = False) 1015 reads part_change."""
    from scenarios.blind import gen_a

    log, _ = gen_a.generate(effect, seed)
    rep = discovered(log).to_report()
    if refused:
        assert rep["cause"] == "unexplained" and "part_change" not in [f["cause"] for f in rep["findings"]]
        assert any(r["cause"] == "part_change" and r["reason"].startswith("not the feature's own change")
                   for r in rep["rejected"]), rep["rejected"]
    else:
        f = rep["findings"][0]
        assert f["cause"] == "part_change"
        o = f["evidence"]["other_features"]
        # the feature moves as a whole: only the others' test stands between this change and a refusal
        assert o["form_beyond_rigid_k"] == 0 and not o["refused"], o
        assert o["others_move_p"] < 0.05, o  # (the nearest cases: if this moves, the margin figures moved)


@pytest.mark.parametrize("gen, effect, seed", [("gen_a", "knock", 1040), ("gen_b", "fixture_slip", 1030)])
def test_a_slip_between_two_trials_splits_is_no_dust(gen, effect, seed):
    """Session 22 (docs/discovery.md, "Session 22: a slip's first touch between two trials' splits"): the
    part steps at one touch of a set-up of 70-80 touches, whose slip trials split every second touch
    (40 per set-up at quantiles). gen_a knock 1040: the knock moves set-up C from row 202 (9.2 um peak,
    noise 0.35 um), the seven largest of its touches are outliers (rows 202-211); the best trial starts at
    row 203 and leaves row 202 at 3.4 um (t 11.8 against the bound 4.79), so the slip veto refused the step
    and the seven read as one event of dust: `outlier`, ambiguous (a miss of the out-of-catalogue aim).
    gen_b fixture_slip 1030: the slip from row 350, 17 outliers, the best trial leaves row 350 at 3.6 um
    (t 12.9 against 4.83). With the step refined to its own first touch (core.discover._exact_step) the
    outliers are the step's: no outlier finding, `unexplained` (the effect is out of the catalogue)."""
    import importlib

    from scenarios import hidden

    o = hidden.blind_outcome(importlib.import_module(f"scenarios.blind.{gen}"), effect, seed, generator=gen)
    assert "outlier" not in o.findings, o
    assert o.cause in o.acceptable, o
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


def test_gen_a_knock_1292_the_rival_slip_refined_to_the_touch_is_tried_and_off(monkeypatch):
    """Session 22: gen_a knock 1292, a 15 um knock at t = 110 s (row 16 of set-up C128.5). With the slip veto's step
    refined to the touch the knock's touches are no longer set aside as dust, and thermal_drift is named beside the
    knock, ambiguous (the one-off change explains as much): the rival slip of its adoption check is still the best
    quantile trial, whose split misses the knock's first touch, so the drift keeps 14.9 um^2 beyond it (p 4.7e-9).
    With the rival's split refined too (``SLIP_RIVAL_EXACT``, off: not measured across the catalogue) the drift is
    refused and the knock reads `unexplained`, as it did before the veto's refinement."""
    from core import discover as D
    from scenarios import hidden
    from scenarios.blind import gen_a

    # (the default engine reads thermal_drift, ambiguous, here: a hedged miss, not asserted, so a later mend does not
    # fail this test; the second review)
    monkeypatch.setattr(D, "SLIP_RIVAL_EXACT", True)
    o = hidden.blind_outcome(gen_a, "knock", 1292, generator="gen_a")
    assert o.cause in o.acceptable, o


def test_gen_b_fixture_slip_1096_repeats_beyond_the_fit_tried_and_off(monkeypatch):
    """Session 22: gen_b fixture_slip 1096, the slip from row 349 (3.7 um, 17 urad): the drift-check repeats
    straddle it and scatter 1.00 um (21 dof) against a true noise of 0.30 um and the baseline's in-sample 0.44 um
    (lack-of-fit F 0.094, deep in its lower tail); at that floor the slip was 0.25 sigma and the report `none`.
    ``REPEATS_BEYOND_FIT`` (off: three reversals on gen_a reseat_hysteresis 1000-1299, the other gen_b effects not
    measured) sets such repeats aside and reads it `unexplained`. The default engine now reads it `unexplained`
    too, confidently (abbe30, session 30, at b72ab75; which later rule mended it was not traced): this test holds
    the off rule's own reading."""
    from core import discover as D
    from scenarios import hidden
    from scenarios.blind import gen_b

    # (the default engine's reading is not asserted here, so a later change of the default does not fail this test;
    # the second review)
    monkeypatch.setattr(D, "REPEATS_BEYOND_FIT", True)
    o = hidden.blind_outcome(gen_b, "fixture_slip", 1096, generator="gen_b")
    assert o.cause in o.acceptable, o


@pytest.mark.parametrize("seed", [1018, 1077])
def test_gen_b_fixture_slip_repeats_straddling_the_slip_are_no_noise_floor(seed):
    """Session 23 (docs/discovery.md, "Session 23: repeats that straddle a step set aside from the noise floor"):
    gen_b fixture_slip 1018 and 1077, their drift-check pairs' scatter 0.82 and 1.27 um against a true noise of
    0.24 and 0.39 um: one pair (1018: 2.9 um against the other pairs' 0.1-0.9) and two (1077: 3.9 and 3.4 um)
    differ by the slip between their touches. Taken as the noise floor they left the slip below every test:
    `none` (a miss of the out-of-catalogue aim). Set aside as an outlying variance among the pairs'
    (``REPEATS_STRADDLED``, :func:`core.diagnosis.straddled_groups`) the rest is the floor and the slip is
    `unexplained`."""
    from scenarios import hidden
    from scenarios.blind import gen_b

    o = hidden.blind_outcome(gen_b, "fixture_slip", seed, generator="gen_b")
    assert o.cause in o.acceptable, o
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


@pytest.mark.parametrize("seed", [1305, 1648])
def test_effect_free_repeats_keep_their_floor_where_few_groups_would_be_left(seed):
    """Session 23's second review (docs/discovery.md, "Session 23: repeats that straddle a step set aside from the
    noise floor", review mend): on gen_a effect-free campaigns 1305 and 1648 the straddled-groups screen fired and
    the rest (8 and 6 dof) gave floors of 0.052 and 0.145 um for true noises of 0.217 and 0.432 um: both read
    `unexplained`, false alarms. With few groups a firing under pure noise selects a rest that scatters little, so
    groups are set aside only where the rest keep the 10 degrees of freedom a repeats' floor needs: both read
    `none` (fails on the rule as first merged, 0ded631)."""
    from scenarios import hidden
    from scenarios.blind import gen_a

    o = hidden.blind_outcome(gen_a, "none", seed, generator="gen_a")
    assert o.cause == "none", o


def test_gen_a_knock_6109_a_step_that_fits_its_outliers_exactly_is_asked_of_the_other_touches(monkeypatch):
    """Session 25 (docs/discovery.md, "Session 25: hedged outliers of effects that are not dust"): gen_a knock 6109
    (session 24's blind check, spent; out of the catalogue, 1.8 sigma visible, acceptable `unexplained` alone). The
    part is knocked in set-up C300 at t 434.6 s, between rows 98 and 99; the set-up's first touches are bore1 and
    the boss, blind to a turn about their axis, so its last two touches before the knock (97 wall4, 98 slot4) are
    the only ones that see the part's turn: the set-up's placement takes the step's mean and leaves them at -2.2
    and -5.4 um (noise 0.31 um), the outliers. The slip veto's step (from row 99) fits both exactly (leverage
    0.9994, 0.995): none judged, and before the rule the veto stopped there, before asking the set-up's other
    touches (which see the step at p 3e-36): one event of dust, `outlier?` leading `unexplained`. With
    ``SLIP_UNJUDGED_BY_OTHERS`` the other touches decide: no outlier, `unexplained`. (No tuning campaign of the
    session's measurement shows the mechanism: the hand-built case is
    tests/core/test_discover_engine.py::test_slip_veto_asks_the_other_touches_where_the_step_fits_every_outlier_exactly.)"""
    from core import discover as D
    from scenarios.blind import gen_a
    from scenarios.hidden import blind_outcome

    on = blind_outcome(gen_a, "knock", 6109, generator="gen_a")
    assert "outlier" not in on.findings and on.cause in on.acceptable, on
    assert on.wp_ext_um <= on.wp_base_um + on.wp_u95_um, on
    monkeypatch.setattr(D, "SLIP_UNJUDGED_BY_OTHERS", False)
    off = blind_outcome(gen_a, "knock", 6109, generator="gen_a")
    assert off.cause == "outlier" and not off.confident, off  # the rule before: the blind check's miss


def test_gen_a_periodic_axis_error_6706_round_rival_is_an_alternative(monkeypatch):
    """gen_a periodic_axis_error 6706 (session 25's blind check, spent): round one's held-out gains put the periodic
    error within 0.004 um^2 of the one-column local scale defect (materiality 0.075), which leads on fewer columns;
    both explain about 61 um^2. Step 8 tested only the catalogue's fixed layouts (a periodic error's scan
    is a search over periods), so the report listed ``nonrigid`` alone and the study counted a plain miss. With
    ``CAUSE_ALTERNATIVES_OF_THE_ROUND`` the round's other passing candidates are tested too, in the form each
    passed with: the periodic error reproduces the bump's signal (overlap >= rival_share) and explains as much.
    Without it the periodic error is not among the alternatives."""
    import core.discover as D

    assert D.CAUSE_ALTERNATIVES_OF_THE_ROUND is True
    _, rep = _gen_a_report("periodic_axis_error", 6706)
    f = rep["findings"][0]
    assert f["cause"] == "local_scale_defect" and f["evidence"]["confidence"] == "ambiguous", f["evidence"]
    alt = {a["cause"]: a for a in f["evidence"]["cause_alternatives"]}
    assert "periodic_axis_error" in f["evidence"]["ambiguous_with"], f["evidence"]["ambiguous_with"]
    pa = alt["periodic_axis_error"]
    assert pa.get("of_the_round") is True and pa["layout"] == {"axis": "X"}
    assert pa["overlap"] >= Settings().rival_share and pa["explained_ratio"] >= Settings().rival_share, pa
    assert "of_the_round" not in alt["nonrigid"]  # a fixed layout, tested as before
    monkeypatch.setattr(D, "CAUSE_ALTERNATIVES_OF_THE_ROUND", False)
    _, off = _gen_a_report("periodic_axis_error", 6706)
    g = off["findings"][0]
    assert g["cause"] == "local_scale_defect"
    assert "periodic_axis_error" not in g["evidence"]["ambiguous_with"], g["evidence"]["ambiguous_with"]
    assert g["evidence"]["confidence"] == f["evidence"]["confidence"]


def test_gen_a_knock_6701_single_outlier_judged_by_the_slip_veto(monkeypatch):
    """gen_a knock 6701 (session 25's blind check, spent): the knock follows row 9 (bore2-p1, -7.25 um), set-up
    C183's last touch before it; bore2's later touches carry the step and the set-up's pose absorbs most of it, so
    row 9 is the one outlier and the report read ``outlier?``. The slip veto (``_slip_explains``) judged only events
    of two or more outliers and returned False for [9] before any test. With ``SLIP_ONE_OUTLIER_BY_OTHERS`` a single
    outlier is judged by the veto's second condition (the step leaves it within the bound and the set-up's other
    touches see the step): no outlier is set aside and the knock, out of the catalogue, reads ``unexplained``."""
    import core.discover as D
    from scenarios import hidden
    from scenarios.blind import gen_a

    assert D.SLIP_ONE_OUTLIER_BY_OTHERS is True
    o = hidden.blind_outcome(gen_a, "knock", 6701, generator="gen_a")
    assert "outlier" not in o.findings, o
    assert o.cause in o.acceptable, o
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o
    monkeypatch.setattr(D, "SLIP_ONE_OUTLIER_BY_OTHERS", False)
    off = hidden.blind_outcome(gen_a, "knock", 6701, generator="gen_a")
    assert off.cause == "outlier" and not off.confident, off
