"""Discovery on ISO 230-2 positioning runs (issue 13 item 8), first-order synthetic tests.

A test of one 600 mm axis: 11 targets at irregular spacing, five linear
cycles approaching each target from both directions, 0.5 um repeatability,
a systematic deviation with a pitch error, a reversal varying along the
axis and a 10 mm ripple (all the same in every cycle: the baseline's
means hold them). Effects that change between cycles are hidden on top,
written here in closed form apart from core.causes' columns: a scale drift
that keeps growing through the test, a warm-up decaying with its time
constant, a gross reading, and (out of catalogue) a deviation that
alternates between odd and even cycles. (A drift that settles is a
warm-up: the two are then one physics, and either name is right.)
"""

import dataclasses

import numpy as np
import pytest

from core.baseline import positioning
from core.discover import discover_baseline
from core.exceptions import ConfigError

SIG = 0.5e-6


def _run(effect: str, seed: int):
    rng = np.random.default_rng(seed)
    P = np.array([0, 57, 121, 178, 243, 300, 361, 419, 482, 537, 600], float) * 1e-3
    rows = []
    t = 0.0
    for j in range(1, 6):
        for d, seq in ((+1, P), (-1, P[::-1])):
            for p in seq:
                rows.append((p, d, j, t))
                t += 12.0
    x, d, c, ts = (np.array(v) for v in zip(*rows))
    sysdev = 4e-6 * np.sin(np.pi * x / 0.6) + 1.5e-6 * (x / 0.6) * d + 0.8e-6 * np.sin(2 * np.pi * x / 0.010)
    tau = ts / ts.max()
    eff = {
        "none": 0 * x,
        "thermal_drift": 10e-6 * (x / 0.6) * (tau + 0.3 * tau ** 2),
        "warm_up": (3e-6 + 4e-6 * x / 0.6) * np.exp(-ts / 300.0),
        "outlier": np.where(np.arange(len(x)) == 57, 9e-6, 0.0),
        "cycle_parity": 2e-6 * np.where(c % 2 == 0, 1.0, -1.0),
        # (out of catalogue) a reversal that grows through the test: + readings drift up, - readings down
        "reversal_grow": 0.5 * 5e-6 * d * tau,
        # (out of catalogue) a reversal that changes with the feed, run fast in alternate cycles (review31c rev_feed)
        "reversal_feed": 0.5 * 3e-6 * d * (c % 2 == 0),
    }[effect]
    dev = sysdev + eff + rng.normal(0, SIG, len(x))
    return positioning(x, np.where(d > 0, "+", "-"), c, dev, ts)


@pytest.mark.parametrize("effect, cause", [("none", "none"), ("thermal_drift", "thermal_drift"),
                                           ("warm_up", "warm_up"), ("outlier", "outlier"),
                                           ("cycle_parity", "unexplained")])
def test_positioning_effects(effect, cause):
    rep = discover_baseline(_run(effect, 3)).to_report()
    assert rep["cause"] == cause, [(f["cause"], f["evidence"].get("text")) for f in rep["findings"]]
    assert rep["baseline"]["model"].startswith("ISO 230-2")
    if cause == "none":
        # the repeatability from the replicates (20 groups of 5 readings: 80 degrees of freedom)
        assert abs(rep["noise_um"]["repeats"]["sigma_um"] - 0.5) < 0.5 * 0.25
    if cause == "warm_up":
        p, u = rep["findings"][0]["params"], rep["findings"][0]["params_u95"]
        assert abs(p["time_constant_s"] - 300.0) <= max(u["time_constant_s"], 60.0), (p, u)


def test_positioning_bad_input():
    with pytest.raises(ConfigError, match="direction must be"):
        positioning([0.0, 0.1], ["+", "x"], [1, 2], [0.0, 0.0])
    with pytest.raises(ConfigError, match="two cycles"):
        positioning([0.0, 0.1], ["+", "-"], [1, 1], [0.0, 0.0])


def test_positioning_log_through_core_positioning():
    """The same engine from a positioning-log/1 test (core.positioning's arrangement), a drift named."""
    from core.baseline import positioning_from_log
    from core.positioning import make_positioning_log

    bl = _run("thermal_drift", 5)
    d = bl.data
    log = make_positioning_log(d.x / 1e-3, d.cycle + 1, d.direction, (d.x + bl.y) / 1e-3, t_s=d.t_s)
    rep = discover_baseline(positioning_from_log(log)).to_report()
    assert rep["cause"] == "thermal_drift", [f["cause"] for f in rep["findings"]]
    assert rep["baseline"]["n"] == log.n


def test_held_out_gap_of_alike_draws_is_one():
    """A positioning test's baseline (the mean per target and direction over five cycles) has every held-out
    residual a fixed multiple of an in-sample one (leave one cycle out: (5/4)^2 = 1.5625 for every draw), so its
    CV-gap draws are alike up to rounding (about 1e-15 relative) and the observed ratio is the same number: the
    p-value is 1, not a gamma tail fitted to the rounding (which gave 0.28 here, 0.09 on the cycle-parity run:
    the observed ratio's last bit against a spread of 5e-16). The same from the figures alone, and a ratio
    beyond the alike draws is 0."""
    from core.diagnosis import NULL_ALIKE, cv_gap

    for effect in ("none", "cycle_parity"):
        gap = discover_baseline(_run(effect, 3)).to_report()["noise_um"]["cv_gap"]
        assert gap["p_value"] == 1.0 and abs(gap["ratio"] - 1.5625) < 1e-12, (effect, gap)
    rng = np.random.default_rng(0)
    rss = rng.uniform(1.0, 2.0, 99)
    cv = 1.5625 * rss * (1 + 2e-16 * rng.normal(size=99))
    assert cv_gap(1.5625 * (1 + 4e-16), 1.0, cv, rss).p_value == 1.0
    assert cv_gap(1.5625 * (1 + 10 * NULL_ALIKE), 1.0, cv, rss).p_value == 0.0


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_a_reversal_growing_through_the_test_is_structure_in_time_by_direction(seed):
    """A reversal growing by 5 um through the test (0.72 um RMS beside the per-target-and-direction means against
    a 0.5 um repeatability) reads `unexplained` with the diagnosis first in time by direction. A + trend up and a -
    trend down cancel in a plain time smooth, and the repeats of one target in one direction across the cycles
    pool it as noise: before (no time_by_direction covariate) review30c's backlash_grow3 401 read `none` at 1.53 um
    left against a true 0.62 um (docs/discovery-studies.md, "Session 30: positioning"). Fails without
    core.baseline.POSITIONING_TIME_BY_DIRECTION (none or another covariate first at each of these seeds)."""
    rep = discover_baseline(_run("reversal_grow", seed)).to_report()
    assert rep["cause"] == "unexplained", [(f["cause"], f["evidence"].get("text")) for f in rep["findings"]]
    assert rep["diagnosis"][0]["covariate"] == "time_by_direction"
    assert rep["findings"][0]["params"]["covariate"] == "time_by_direction"


def test_time_by_direction_basis_is_signed_legendre():
    """The covariate's columns: the direction times P_1..P_k of the normalised time (known values), so that
    readings alike in time and opposite in direction have opposite columns."""
    import core.baseline as B
    bl = _run("none", 3)
    cov = bl.covariate("time_by_direction")
    assert cov is not None and cov.kind == "basis" and cov.values.shape == (len(bl.y), B.POSITIONING_TIME_BY_DIRECTION)
    u = 2 * bl.data.tau - 1
    np.testing.assert_allclose(cov.values[:, 0], bl.data.direction * u, atol=1e-15)
    np.testing.assert_allclose(cov.values[:, 1], bl.data.direction * (3 * u ** 2 - 1) / 2, atol=1e-15)


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_the_noise_of_a_reversal_growing_through_the_test_is_the_repeatability(seed):
    """A reversal growing by 12 um through the test (review30c's backlash_grow3 rate): the repeats of one target in
    one direction sit in different cycles, so their plain scatter holds the growth. Beyond the per-cycle rates and
    the baseline's time_by_direction columns (core.discover.POSITIONING_NOISE_BEYOND_TIME_BY_DIRECTION) the noise
    is the 0.5 um repeatability: within 25 % (22 groups of 5 readings: 88 contrasts, about 81 beyond the
    columns, 1 s.d. of sigma about 8 %, so 3 s.d.). Fails without the constant (the rates alone leave 1.02-1.22 um
    at seeds 3-5)."""
    bl = _run("reversal_grow", seed)
    bl = dataclasses.replace(bl, y=bl.y + 0.5 * 7e-6 * bl.data.direction * bl.data.tau)  # 5 + 7 = 12 um
    nz = discover_baseline(bl).to_report()["noise_um"]
    assert nz["method"] == "repeats" and nz["repeats"]["beyond"] == ["time_by_direction"], nz
    assert abs(nz["sigma_um"] - 0.5) < 0.5 * 0.25, nz
    # (88 contrasts less the 8 columns' rank within the groups: 7 here, 81; the rates alone take 5)
    assert nz["repeats"]["dof_plain"] - 8 <= nz["dof"] < nz["repeats"]["dof_plain"] - 5, nz


def test_the_noise_beyond_time_by_direction_is_unbiased_under_no_effect():
    """Under no effect the time_by_direction columns are fixed regressors: the repeats' scatter beyond them is
    chi-square on fewer degrees of freedom (the columns' rank within the groups beyond the rates'), and its mean
    over 200 noise draws is the true variance within 5 % (1 s.d. of the mean of 200 chi-square/81 is 1.1 %:
    4.5 s.d.)."""
    import core.discover as D
    from core.diagnosis import replicate_scatter
    bl = _run("none", 3)
    rows = np.arange(bl.n)
    T = D.drift_trend(bl, rows)
    assert T.shape[1] == 5 + 3  # rates per cycle, then the covariate's columns
    np.testing.assert_array_equal(T[:, 5:], bl.covariate("time_by_direction").values)
    rng = np.random.default_rng(11)
    v = [replicate_scatter(bl.replicate, rng.normal(0, 1.0, bl.n), T) for _ in range(200)]
    # the degrees of freedom: the contrasts less the rank of the columns' variation within the groups (7 of 8 on
    # this evenly clocked design), counted here apart
    Tc = T - np.array([T[bl.replicate == g].mean(0) for g in bl.replicate])
    assert v[0].dof == replicate_scatter(bl.replicate, bl.y).dof - np.linalg.matrix_rank(Tc) < 88 - 5
    assert abs(np.mean([r.ss / r.dof for r in v]) - 1.0) < 0.05


# --- a rotary axis: figures in arc seconds, targets in degrees (session 31, review31 F11) ---------------------------
def _rotary_log():
    """review31's pos_rot.csv in memory: axis C, 6 targets 0..270 deg x 5 linear cycles, readings to 1e-6 deg."""
    from core.positioning import make_positioning_log

    rng = np.random.default_rng(31)
    P = np.array([0, 45, 90, 135, 180, 270], float)
    rows, t = [], 3.0
    for j in range(1, 6):
        for d, seq in (("+", P), ("-", P[::-1])):
            for p in seq:
                dev = 2e-5 + 2e-5 * p / 270 + (-1.5e-5 if d == "-" else 0.0) + rng.normal(0, 5e-6)
                rows.append((p, j, d, round(p + dev, 6), t))
                t += 3.0
    tg, c, d, m, ts = zip(*rows)
    return make_positioning_log(tg, c, d, m, t_s=ts, unit="deg", meta={"axis": "C"})


def test_a_rotary_positioning_log_is_reported_in_arcsec_with_targets_in_degrees():
    """Known answer by hand: the baseline's rms and the mean of each target and direction from the readings in
    arc seconds (3600 per degree), the same figures ``vmt iso230-2`` gives; no key or text says um or mm
    (before: 'P=785.398mm+' for 45 deg and radians x 1e6 under '_um')."""
    import json

    from core.baseline import positioning_from_log

    log = _rotary_log()
    rep = discover_baseline(positioning_from_log(log)).to_report()
    dev = (log.measured - log.target) * 3600.0
    dirs = np.asarray(log.direction)
    res, means = dev.copy(), {}
    for p in np.unique(log.target):
        for s in (1, -1):
            k = (log.target == p) & (dirs == s)
            means[f"P={p:g}deg{'+' if s > 0 else '-'}"] = dev[k].mean()
            res[k] -= dev[k].mean()
    assert rep["baseline"]["unit"] == "arcsec" and rep["baseline"]["target_unit"] == "deg"
    # (1e-9 relative: the readings go deg -> rad -> arcsec x 1e-6 and through a least-squares fit)
    assert rep["baseline"]["rms_arcsec"] == pytest.approx(np.sqrt(np.mean(res ** 2)), rel=1e-9)
    assert rep["noise_arcsec"]["in_sample"]["sigma_arcsec"] == pytest.approx(
        np.sqrt(np.sum(res ** 2) / (len(res) - len(means))), rel=1e-9)
    got = {w["target"]: w["baseline_arcsec"] for w in rep["workpiece"]}
    assert got.keys() == means.keys()
    for k, v in means.items():
        assert got[k] == pytest.approx(v, rel=1e-9, abs=1e-12)
    text = json.dumps(rep, ensure_ascii=False)
    assert "_um" not in text and "µm" not in text and "mm+" not in text and "mm-" not in text


def test_a_rotary_baseline_is_its_linear_twin_in_arcsec():
    """The same numbers as a linear axis (targets x 3.6 mm per degree, deviations 1 um per arc second) give the
    same report, figure for figure, with a finding's parameters (a drift's offset in arcsec, its scale in ppm):
    the engine sees the same arrays, only the names differ (1e-9 relative: rad -> arcsec rounding)."""
    from core.baseline import ROTARY_ENGINE_PER_RAD

    lin = _run("thermal_drift", 3)
    x, dev = lin.data.x, lin.y
    d = np.where(lin.data.direction > 0, "+", "-")
    rot = positioning(x / ROTARY_ENGINE_PER_RAD, d, lin.groups, dev / ROTARY_ENGINE_PER_RAD, lin.data.t_s,
                      rotary=True)
    a, b = discover_baseline(lin).to_report(), discover_baseline(rot).to_report()
    assert a["cause"] == b["cause"] == "thermal_drift"
    fa, fb = a["findings"][0]["params"], b["findings"][0]["params"]
    assert set(fb) == {"offset_change_arcsec", "scale_change_ppm"}
    assert fb["offset_change_arcsec"] == pytest.approx(fa["offset_change_um"], rel=1e-9)
    assert fb["scale_change_ppm"] == pytest.approx(fa["scale_change_ppm"], rel=1e-9)
    assert b["baseline"]["rms_arcsec"] == pytest.approx(a["baseline"]["rms_um"], rel=1e-9)
    assert b["noise_arcsec"]["sigma_arcsec"] == pytest.approx(a["noise_um"]["sigma_um"], rel=1e-9)
    # targets: x m = x / 3.6e-3 deg
    assert [w["target"] for w in b["workpiece"]][:2] == [
        f"P={x0 / 3.6e-3:.10g}deg+" for x0 in np.unique(np.round(x, 9))[:2]]


def test_the_rotary_summary_says_arcsec():
    from core.baseline import positioning_from_log
    from scenarios.cli.discover import summary_lines

    lines = summary_lines(discover_baseline(positioning_from_log(_rotary_log())).to_report(), "positioning")
    assert lines[0].count("arcsec") == 2 and lines[1].startswith("noise") and "arcsec" in lines[1]
    assert not any(" um" in ln or "µm" in ln for ln in lines), lines


def test_the_positioning_report_says_cycles_and_readings_and_no_fixed_ratio():
    """review31c: a positioning report used a planar campaign's words (``time_trend: 'per set-up'``, "one event (a
    touch, or one set-up's touches)") and printed a held-out/in-sample ratio that leaving a cycle out of means per
    target and direction fixes at (n/(n-1))^2 whatever the data (5 balanced cycles: 1.5625, here to 1e-12). Now
    cycles and readings, and no ratio line; the JSON keeps the ratio (the same figure)."""
    import json

    from scenarios.cli.discover import summary_lines

    rep = discover_baseline(_run("outlier", 3)).to_report()
    gap = discover_baseline(_run("none", 3)).to_report()["noise_um"]["cv_gap"]
    assert gap["ratio"] == pytest.approx(1.5625, abs=1e-12) and gap["expected_ratio"] == pytest.approx(1.5625, abs=1e-12)
    assert rep["noise_um"]["repeats"]["time_trend"] in ("per cycle", "shared", "none")
    text = json.dumps(rep)
    assert "set-up" not in text and "touch" not in text, [c for c in rep["conventions"] if "set-up" in c]
    assert "leave one group (cycle) out" in text
    lines = summary_lines(rep, "positioning")
    assert not any("held-out" in ln for ln in lines) and "readings," in lines[0]
    none = summary_lines(discover_baseline(_run("none", 3)).to_report(), "positioning")
    assert any(ln.endswith("within the repeatability") for ln in none), none


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_a_reversal_that_changes_from_cycle_to_cycle_is_located_in_direction_by_cycle(seed):
    """review31c rev_feed: a lost motion 3 um larger in alternate cycles read `unexplained` with the diagnosis at
    order and time; the direction x cycle covariate (core.baseline.POSITIONING_DIRECTION_BY_CYCLE) is where it
    lives: the first diagnosis line, p < 1e-6 (0.73 um RMS beside the means against 0.5 um of noise)."""
    rep = discover_baseline(_run("reversal_feed", seed)).to_report()
    assert rep["cause"] == "unexplained"
    top = rep["diagnosis"][0]
    assert top["covariate"] == "direction_by_cycle" and top["p_value"] < 1e-6, rep["diagnosis"][:3]


def test_direction_by_cycle_raises_no_alarm_on_effect_free_runs():
    """No effect: the new covariate's p-value is above the diagnosis level (0.01) on each of 10 runs, the cause
    none (a false alarm per run at most the family rate: 10 runs cannot show more than that nothing fires)."""
    for seed in range(10, 20):
        rep = discover_baseline(_run("none", seed)).to_report()
        d = {x["covariate"]: x["p_value"] for x in rep["diagnosis"]}
        assert d["direction_by_cycle"] >= 0.01 and rep["cause"] == "none", (seed, d)
