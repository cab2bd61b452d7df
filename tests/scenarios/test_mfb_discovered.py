"""Discovery on MFB campaigns with the effect hidden IN THE SIMULATOR (issue 13 item 8; audit35 F3, session 35).

tests/core/test_discover_volumetric.py puts its effects into the measured data; here the simulator itself runs
the campaign with the effect hidden in the machine or the probe (scenarios.hidden.hidden_mfb: the X, Y, Z scales
drifting between measurements; each stylus of the star with its own 2- and 3-lobe pre-travel), and discovery on
the volumetric baseline must name it, with magnitudes within their U95 of what was hidden or said not determined.

One tuning seed (simulator 4000), the 3-axis plan, the bar as calibrated (``bar_cal_error`` off): discovery's noise
on this plan is the residuals' (no repeats), and on the realistic bar, without its declared calibration in the noise
model (before session 36), it held the bar's 0.2-0.35 um deviation from its calibration, 2.5-4.5 x the 0.125 um
touch noise, so that every effect hidden_mfb draws was 0.2-0.8 sigma of it (docs/discovery-studies.md, "Session 35:
MFB discovery with the effects hidden in the simulator"; the tests at the end of this module). With the bar as
calibrated, discovery's sigma on the effect-free campaign is 0.128 um, and the hidden effects' parts outside the
baseline's column space are 1.29 sigma (lobing per stylus) and 1.86 sigma (the drift): visible, and asserted so,
by scenarios.hidden.mfb_effect_outside_baseline (the campaign less the same seed without the effect: the same
bar, placements and noise draws).

Cost: three simulated campaigns (effect-free, lobing, drift) and four discoveries, about 12 s CPU on an idle
machine (measured: 11.9 s for the module, session 35).

Session 36 (mfb36): the realistic bar judged with its declared calibration uncertainty in the baseline's noise
model (core.baseline.VOLUMETRIC_BAR_CALIBRATION_NOISE): the effect-free campaign above analysed with the bar's
calibration off by 30 draws of that uncertainty (scenarios.hidden.mfb_bar_miscalibrated: no new simulation, the
campaign shared through scenarios.hidden.mfb_campaign) reads `none` with the touch noise's sigma; with the touch
noise alone it does not.
"""

import dataclasses

import numpy as np
import pytest

from scenarios.hidden import mfb_discovered

SEED = 4000  # a tuning seed (simulator 4000-4099)


def _said(rep):
    return [(f["cause"], f["evidence"].get("confidence"), f["evidence"].get("confidence_reason")) for f in
            rep["findings"]]


@pytest.fixture(scope="module")
def free():
    return mfb_discovered("none", SEED, bar_cal_error=False)


@pytest.fixture(scope="module")
def lobing(free):
    return mfb_discovered("lobing_per_stylus", SEED, bar_cal_error=False)


def test_the_effect_free_campaign_reads_none(free):
    """No effect hidden: nothing is named, and the noise is the touch noise's size (0.125 um at k = 1, whitened per
    point; measured 0.128 um): the bar as calibrated leaves no structure of its own. The band 0.10-0.16 um: the
    residuals' sigma on about 300 degrees of freedom scatters by about 4 % (1 s.d.); wider would hide the bar's
    deviation (0.3-0.6 um on the realistic bar)."""
    o, rep, _, _ = free
    assert o.cause == "none" and rep["cause"] == "none", _said(rep)
    assert 0.10 <= o.noise_um <= 0.16, o.noise_um


def test_a_lobing_per_stylus_hidden_in_the_probe_is_named(lobing):
    """Each stylus its own 2- and 3-lobe pre-travel (0.5-1.5 um each; hidden_mfb): 1.29 sigma outside the baseline
    (asserted >= 1), named lobing_per_stylus. Flagged ambiguous, and rightly: on the 3-axis plan the styli are used
    in the plan's order, so a stylus' own pattern is also a smooth function of time, and VYb, VYc and VXb each use a
    stylus no other measurement uses (a bar moved in its fixture shifts them alike; docs/discovery.md, causes of the
    volumetric kind); the reason says so. Its magnitudes: every pre-travel peak-to-valley either within its U95 of
    the hidden one (hidden_mfb's params, the same stylus names) or reported not determined, value and U95 both
    absent together (no number without its U95); measured: not determined on this design, the reason saying which
    styli. The error tables (the estimand) within the baseline's error plus their U95, the study's workpiece check."""
    o, rep, params, _ = lobing
    assert o.visible_sigmas >= 1.0, o.visible_sigmas
    assert rep["cause"] == "lobing_per_stylus", _said(rep)
    f = rep["findings"][0]
    ev = f["evidence"]
    if ev.get("confidence") == "ambiguous":
        reason = ev["confidence_reason"]
        assert "time" in reason or "moved in its fixture" in reason, reason
    for k, v in f["params"].items():
        u = f["params_u95"][k]
        assert (v is None) == (u is None), (k, v, u)
        if v is not None and k.startswith("pretravel_pv_um["):
            assert abs(v - params[k]) <= u, (k, v, u, params[k])
    if any(v is None for v in f["params"].values()):
        assert "not determined" in ev["confidence_reason"], ev.get("confidence_reason")
    _each_missing_value_said(f)
    assert np.isfinite(o.wp_ext_um) and o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


def _each_missing_value_said(f):
    """Every magnitude without a value is named where the finding says why (session 37: mfb-3axis seed 1's
    lobing_per_stylus had 8 keys null and a reason naming 2; the weak-direction rule's nulls were said nowhere,
    now in ``magnitude_not_seen``)."""
    import re

    ev = f["evidence"]
    said = " ".join(str(ev.get(k) or "") for k in ("magnitude_not_seen", "magnitude_undetermined"))
    for k, v in f["params"].items():
        if v is None:
            assert re.search(rf"(^|[\s;(]){re.escape(k)}[\s:,]", said) or k in (ev.get("one_sided") or {}), (k, said)


def test_mended_lobing_columns_drop_the_rounding_directions(lobing, monkeypatch):
    """core.causes.STYLUS_LOBING_MENDED and core.discover.MAGNITUDE_ZERO_COLUMN_UNSEEN (off in the engine; on
    here): the axial touches carry no lobes and the
    columns of rounding (sin 2 phi at multiples of 90 deg) are zero, so the term the engine fits has no direction of
    pure rounding. Known figures of this campaign (as of mfb-3axis seed 1, the same plan): without the mend the term
    is fitted on 12 directions of its 49, beside 12 columns of norm below 1e-6 of the largest (rounding, normalised
    to unit length by the engine), and two pre-travel U95s read wider than 0..50 um; with it on 5, no such column
    (6 exactly zero), no "wider" note; the cause is still named, and each magnitude without a value is said. (The
    per-stylus patterns stay not determined: the 5 directions are combinations across styli; core.causes, the
    constant's comment.)"""
    from core import causes
    from core import discover as D

    def kept(on):
        monkeypatch.setattr(causes, "STYLUS_LOBING_MENDED", on)
        monkeypatch.setattr(D, "MAGNITUDE_ZERO_COLUMN_UNSEEN", on)   # (the mend's zero columns need it)
        seen = []
        orig = D._magnitudes

        def spy(cause, bl, tm, *a, **k):
            if cause.name == "lobing_per_stylus":
                seen.append(tm)
            return orig(cause, bl, tm, *a, **k)

        monkeypatch.setattr(D, "_magnitudes", spy)
        rep = D.discover_baseline(lobing[3]).to_report()
        monkeypatch.setattr(D, "_magnitudes", orig)
        cols = seen[-1].cols_all if seen[-1].cols_all is not None else seen[-1].columns
        nrm = np.linalg.norm(cols, axis=0)
        tiny = int(np.sum((nrm > 0) & (nrm < 1e-6 * nrm.max())))
        return rep, seen[-1].map.shape[1], tiny

    import warnings

    rep_off, k_off, tiny_off = kept(False)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        rep_on, k_on, tiny_on = kept(True)
    # a magnitude that needs an exactly-zero column is unseen, said without g / 1e-300 (whose norm overflows: one
    # "overflow encountered in dot" per discovery with MAGNITUDE_ZERO_COLUMN_UNSEEN off)
    assert not [x for x in w if "overflow" in str(x.message)], [str(x.message) for x in w]
    assert tiny_off == 12 and tiny_on == 0, (tiny_off, tiny_on)
    assert (k_off, k_on) == (12, 5), (k_off, k_on)
    assert "wider than" in rep_off["findings"][0]["evidence"].get("magnitude_undetermined", "")
    assert rep_on["cause"] == "lobing_per_stylus", _said(rep_on)
    assert not rep_on["findings"][0]["evidence"].get("magnitude_undetermined")
    _each_missing_value_said(rep_on["findings"][0])


def test_without_the_lobing_columns_it_is_not_named(lobing, monkeypatch):
    """The check above can fail: the same campaign discovered with the volumetric baseline's lobing-per-stylus
    columns removed (its scans give none) is not read lobing_per_stylus."""
    from core import causes
    from core.discover import discover_baseline

    reg = tuple(dataclasses.replace(c, scans=lambda bl: ([], 1.0)) if c.name == "lobing_per_stylus" else c
                for c in causes.REGISTRY)
    monkeypatch.setattr(causes, "REGISTRY", reg)
    rep = discover_baseline(lobing[3]).to_report()
    assert rep["cause"] != "lobing_per_stylus", _said(rep)


def test_a_scale_drift_hidden_in_the_machine_is_named_within_its_u95(free):
    """The X, Y, Z scales drifting linearly from the first measurement to the last (hidden_mfb: 5-15 ppm each,
    the machine as it is at each measurement's time): 1.86 sigma outside the baseline, named thermal_drift
    without a flag, each scale change within its U95 of the drawn one (measured -10.72 +- 1.05 of -10.35 ppm,
    12.82 +- 1.22 of 12.64, 6.92 +- 1.23 of 6.24). The error tables are scored against the machine at the
    campaign's middle time, the state the extended model's tables describe
    (scenarios.hidden.MFB_DRIFT_TRUTH_MID_CAMPAIGN): 0.74 -> 0.15 um (U95 0.32); against the first measurement's
    machine, as mfb_outcome scored them before session 35, 0.34 -> 0.75 um, and this check fails."""
    o, rep, params, _ = mfb_discovered("thermal_drift", SEED, bar_cal_error=False)
    assert o.visible_sigmas >= 1.0, o.visible_sigmas
    assert rep["cause"] == "thermal_drift" and o.confident, _said(rep)
    p, u = rep["findings"][0]["params"], rep["findings"][0]["params_u95"]
    for a in "XYZ":
        k = f"{a}_scale_change_ppm"
        assert abs(p[k] - params[k]) <= u[k], (k, p[k], u[k], params[k])
    assert np.isfinite(o.wp_ext_um) and o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


# --- the realistic bar: its deviation from its calibration judged with the declared uncertainty (session 36) ---
#: Draws of the bar's calibration error on the effect-free campaign (below). 30: each costs its discovery alone
#: (0.3-0.4 s CPU), and 30 is enough for the noise check (every draw, deterministic) and a false-alarm count
#: that the 5 % aim bounds (below); more would cost the test's budget for a rate the study measures
#: (docs/discovery-studies.md, "Session 36: MFB discovery judged with the bar's declared calibration").
DRAWS = 30


#: The keywords scenarios.hidden.mfb_baseline passes to mfb_campaign (the `free` fixture's path), in its order: an
#: lru_cache keys on the call as written (``f(a, b=1)`` and ``f(a, name=n, b=1)`` are two entries), so a call
#: written otherwise simulated the same campaign a second time (session 38: 1.8 s of CPU).
FREE_KEY = {"name": "mfb-3axis", "bar_cal_error": False}


def _miscalibrated(k: int):
    """The effect-free campaign of SEED (the `free` fixture's simulation, shared: scenarios.hidden.mfb_campaign),
    analysed with the bar's calibration off by draw ``k`` of its declared uncertainty
    (scenarios.hidden.mfb_bar_miscalibrated: 0.2, 0.35, 0.35 um per hole, its heights through the rods, the same
    in every placement, as scenarios.mfb.run draws the realistic bar), the baseline's noise model given the
    declared certificate and repeatability (scenarios.hidden.mfb_declared_noise)."""
    from core.baseline import volumetric
    from scenarios.hidden import mfb_bar_miscalibrated, mfb_campaign, mfb_declared_noise
    from scenarios.mfb import default_machine

    res, times, _ = mfb_campaign("none", SEED, **FREE_KEY)
    cfg, _ = default_machine(res.plan.machine)
    meas = mfb_bar_miscalibrated(res.meas, np.random.default_rng([SEED, 36, k]))
    return volumetric(meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m), times,
                      **mfb_declared_noise(res, True))


@pytest.fixture(scope="module")
def miscalibrated(free):
    from core.discover import discover_baseline

    out = []
    for k in range(DRAWS):
        rep = discover_baseline(_miscalibrated(k)).to_report()
        out.append((rep["cause"], rep["noise_um"]["sigma_um"], _said(rep)))
    return out


def test_a_bar_off_its_calibration_by_its_declared_uncertainty_reads_none(miscalibrated):
    """The bar's deviation from its calibration is the same in every placement, so on a baseline whitened by the
    touch noise alone it is structure along the bar (session 35: 3 of 28 effect-free realistic-bar campaigns read
    `unexplained`/`outlier?`, discovery's sigma 0.32-0.57 um). Judged with the declared calibration uncertainty in
    the noise model (core.baseline.VOLUMETRIC_BAR_CALIBRATION_NOISE) it is noise of known covariance:

    - every draw's sigma is the touch noise's (0.125 um; the band 0.10-0.16 um of the bar as calibrated, above):
      the whitened residuals hold nothing of the bar beyond its declared covariance (measured 0.123-0.132 um;
      with the touch noise alone 0.245-0.595 um on the same draws: the check fails on every one of them);
    - at most 1 of the 30 reads anything but `none`: the issue's aim is at most 5 % false alarms, 1.5 of 30
      expected at that rate; measured 0 of 30 (Wilson 95 % 0-11 %); the touch noise alone read 1 (`unexplained`,
      along the bar, p = 8e-10) and the study's simulated realistic bars 3 of 28 (session 35) -- the rate alone
      on 30 could not tell 5 % from 11 %, the noise check does, on every draw."""
    bad = [(k, c, said) for k, (c, _, said) in enumerate(miscalibrated) if c != "none"]
    assert len(bad) <= 1, bad
    sig = [s for _, s, _ in miscalibrated]
    assert all(0.10 <= s <= 0.16 for s in sig), sig


def test_without_the_declared_calibration_the_bar_inflates_the_noise(monkeypatch, free):
    """The check above can fail: the same draws with the bar's calibration left out of the noise model
    (VOLUMETRIC_BAR_CALIBRATION_NOISE off: the touch noise alone, as before session 36) judge with a sigma
    that holds the bar's deviation, outside the touch noise's band (measured 0.444, 0.463, 0.509 um)."""
    from core import baseline
    from core.discover import discover_baseline

    monkeypatch.setattr(baseline, "VOLUMETRIC_BAR_CALIBRATION_NOISE", False)
    for k in range(3):
        rep = discover_baseline(_miscalibrated(k)).to_report()
        assert rep["noise_um"]["sigma_um"] > 0.2, (k, rep["noise_um"]["sigma_um"])


def test_the_noise_whitening_is_the_inverse_square_root_of_the_declared_covariance():
    """Known answer: core.baseline._noise_whitening of points with touch gains G and bar columns L gives
    ``W (blockdiag(G G^T) + L L^T) W^T = c^2 I`` (c the points' mean gain, :func:`_point_whitening`'s scale), and
    without L the per-point whitening (a zero L changes nothing: the bar adds nothing where declared 0). Sizes
    are a toy's: 4 points of 3 rows, 5 touches each, 6 bar columns; tolerance 1e-9 relative (double rounding
    of a 12 x 12 eigen-decomposition)."""
    from core.baseline import _noise_whitening, _point_whitening

    rng = np.random.default_rng(36)
    n, point = 12, np.repeat(np.arange(4), 3)
    GW = rng.standard_normal((n, 5))
    touch = [(np.arange(n), GW, None)]
    L = rng.standard_normal((n, 6)) * 2.0
    W = _noise_whitening(touch, n, point, L)
    S = np.zeros((n, n))
    for p in range(4):
        r = np.flatnonzero(point == p)
        S[np.ix_(r, r)] = GW[r] @ GW[r].T
    c2 = np.mean([np.mean(np.diag(S[np.ix_(r, r)])) for r in (np.flatnonzero(point == p) for p in range(4))])
    assert np.allclose(W @ (S + L @ L.T) @ W.T, c2 * np.eye(n), rtol=0, atol=1e-9 * c2)
    assert np.allclose(_noise_whitening(touch, n, point, np.zeros((n, 6))), _point_whitening(touch, n, point),
                       rtol=0, atol=1e-12)


def test_the_declared_calibration_is_refused_when_incomplete(free):
    """Bad input: the bar's uncertainty without the probe's repeatability (their ratio is the model), a
    repeatability of 0, a u of the wrong shape or negative, a cal_map of the wrong size: one ConfigError each,
    naming the argument."""
    from core.baseline import volumetric
    from core.exceptions import ConfigError
    from scenarios.hidden import mfb_campaign
    from scenarios.mfb import default_machine

    res, times, _ = mfb_campaign("none", SEED, **FREE_KEY)
    cfg, _ = default_machine(res.plan.machine)
    args = (res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m), times)
    u = np.full((12, 3), 0.3e-6)
    for kw, word in (({"u_cal_m": u}, "sigma_probe_m"), ({"u_cal_m": u, "sigma_probe_m": 0.0}, "sigma_probe_m"),
                     ({"u_cal_m": u[:11], "sigma_probe_m": 1e-7}, "u_cal_m"),
                     ({"u_cal_m": -u, "sigma_probe_m": 1e-7}, "u_cal_m"),
                     ({"u_cal_m": u, "sigma_probe_m": 1e-7, "cal_map": np.eye(35)}, "cal_map")):
        with pytest.raises(ConfigError, match=word):
            volumetric(*args, **kw)
