"""Discovery on the volumetric MFB baseline (issue 13 item 8).

One simulated MFB campaign (scenarios.mfb, the 3-axis plan, 0.25 um k=2
probing, bar calibration and placement errors, machine errors the tables
represent: ``on_nodes``, and the bar as calibrated: ``bar_cal_error``
off), shared by the module. (A bar that differs from its calibration by
0.2-0.35 um per hole is real structure along the bar, which discovery
reports as unexplained at 0.08 um.) The
same discovery engine runs on the volumetric model's baseline
(core.baseline.volumetric): nothing there is named on the plain campaign,
and physical effects put into the measured data are found:

- the axes' scales drifting between placements (each measurement's
  axis positions, reading + J, scaled about the axes' zero by the drift
  at its time);
- the bar sagging between its supports (the points read lower, along
  gravity's part perpendicular to the bar, by a quartic of the position
  along it; a standing bar does not sag).

Effects hidden in the simulator itself (a drift of the machine, a lobing per
stylus of the probe) are tested in tests/scenarios/test_mfb_discovered.py and
run by ``vmt bench`` (scenarios/bench/discover_study.py, ``mfb``).
"""

import dataclasses

import numpy as np
import pytest

from core.baseline import volumetric
from core.discover import discover_baseline

MEAS_S = 600.0


@pytest.fixture(scope="module")
def campaign():
    from scenarios.mfb import default_machine, run

    res = run("mfb-3axis", seed=5, mc_runs=0, on_nodes=True, bar_cal_error=False)
    cfg, _ = default_machine(res.plan.machine)
    times = {m.name: i * MEAS_S for i, m in enumerate(res.meas)}
    return res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m), times


def _discover(campaign, meas=None):
    m0, chain, nodes, rp, times = campaign
    return discover_baseline(volumetric(meas if meas is not None else m0, chain, nodes, rp, times))


def test_plain_campaign_is_none(campaign):
    rep = _discover(campaign).to_report()
    assert rep["cause"] == "none", [(f["cause"], f["evidence"].get("text")) for f in rep["findings"]]
    assert rep["baseline"]["model"].startswith("volumetric MFB")
    # the error tables with U95 (zero where an ISO convention fixes a value: EXX = 0 at the first node ...)
    u = [w["baseline_u95_um"] for w in rep["workpiece"]]
    assert rep["workpiece_identifiable"] and all(v >= 0 for v in u) and sum(v > 0 for v in u) > 0.8 * len(u)


def _scale_drifted(meas, s):
    """``meas`` with the axes' scales drifting by ``s`` (3,) from the first measurement to the last: each
    measurement's axis positions q = reading + J (its stylus's J; the scale reads the carriage) dilated
    about the axes' zero by ``1 + s tau``, tau 0..1 in the measurement order, and read back as readings."""
    tau = np.linspace(0.0, 1.0, len(meas))
    out = []
    for m, ti in zip(meas, tau):
        f, J = 1 + np.asarray(s) * ti, np.asarray(m.J_m)
        out.append(dataclasses.replace(m, O_R=(np.asarray(m.O_R) + J) * f - J, q_R=(np.asarray(m.q_R) + J) * f - J))
    return out


def test_scale_drift_between_placements(campaign):
    """Scales drifting by -12, +8, -10 ppm in X, Y, Z over the campaign, and the opposite drift: both
    named thermal_drift, and the response to the drift, half the difference of the two estimates, is
    the drift within 5 % on every axis.

    In the ISO 230-1 sign a reading that grows with the scale means the tool moved less than read: a
    dilation by +12, -8, +10 ppm is the scale errors -12, +8, -10 ppm. The dilation is of the axis
    positions reading + J, where the tables and the drift model E_aa += s tau u live (session 27);
    dilating the readings about zero instead adds s tau J per stylus, which the model has no term for
    (Z read -1.6 ppm for -10). Why the difference, not each estimate: this campaign (seed 5, its
    placement errors drawn: the only input drawn, the bar as calibrated and the styli's J exact)
    reads an apparent drift of its own, half the sum of the two estimates, X +1.8, Y -2.3, Z -0.6 ppm
    (seed 6: -2.0, +0.7, -3.3; seed 7: +1.6, -0.6, -0.3), RMS 1.75 ppm, about three times the
    standard uncertainty the reported U95 (1.0-1.3 ppm, k = 2) implies; without the drawn placements
    (draw_inputs=False) seed 5 reads -0.4, +0.7, -0.1. The single estimate Y +5.7 ppm (29 % off, session 26's strict
    xfail) was that -2.3 ppm; the response itself is -12.01, +8.03, -9.98 ppm (measured, seed 5;
    seed 7 -11.95, +8.00, -10.08), so the bound is 5 %."""
    meas = campaign[0]
    s = np.array([12e-6, -8e-6, 10e-6])
    est = []
    for sign in (1, -1):
        rep = _discover(campaign, _scale_drifted(meas, sign * s)).to_report()
        assert rep["cause"] == "thermal_drift", [(f["cause"], f["evidence"].get("text")) for f in rep["findings"]]
        est.append(np.array([rep["findings"][0]["params"][f"{a}_scale_change_ppm"] for a in "XYZ"]))
    response = (est[0] - est[1]) / 2
    for a, r, true in zip("XYZ", response, (-12.0, 8.0, -10.0)):
        assert abs(r - true) <= 0.05 * abs(true), (a, r, true, est)


def _sagged(meas, sag_m, plan):
    """``meas`` with the bar sagging by ``sag_m`` at mid-span between its supports, as on the machine: its points move
    by ``sag (1 - s^2)^2`` along gravity's part perpendicular to the bar, s the position along the WHOLE bar (holes
    1..12 at -1..1, whatever holes a measurement probed: the supports are symmetric about the bar's middle), gravity
    the machine's -z_R turned into W by the set-up's nominal table pose (the simulator's own: sim.machine), and the
    points' displacement in W read in machine coordinates (O_R moves by R_RW v: the linear axes are R's)."""
    from scenarios.mfb import PLANS, default_machine
    from sim.machine import nominal_T_R_W

    cfg, _ = default_machine(PLANS[plan]().machine)
    out = []
    for m in meas:
        rot = np.asarray(m.rot_rad, float)[None, :] if len(m.rot_rad) else None
        R_RW = np.asarray(nominal_T_R_W(cfg, rot), float).reshape(-1, 4, 4)[0, :3, :3]
        x_A = np.asarray(m.T_W_A)[:3, 0]
        g = R_RW.T @ np.array([0.0, 0.0, -1.0])
        g_perp = g - (g @ x_A) * x_A
        s = (np.asarray(m.holes, float) - 6.5) / 5.5
        w = sag_m * (1 - s ** 2) ** 2
        out.append(dataclasses.replace(m, O_R=np.asarray(m.O_R) + w[:, None] * (R_RW @ g_perp)[None, :]))
    return out


def test_bar_sagging_between_its_supports(campaign):
    """3 um of sag at mid-span, about the bar's middle, on every placement of the 3-axis plan (17 measurements, 14 of
    them probing holes 1-8 or fewer): named bar_bending, the sag within its U95.

    Measured (seed 5, the bar as calibrated): 3.00 um. Without core.baseline.BAR_BENDING_ABOUT_BAR_MIDDLE (the quartic
    about the probed holes' middle, sessions 13-30) the columns are not the sag's shape: see
    test_bending_columns_about_the_bars_middle."""
    rep = _discover(campaign, _sagged(campaign[0], 3e-6, "mfb-3axis")).to_report()
    assert rep["cause"] == "bar_bending", [(f["cause"], f["evidence"].get("text")) for f in rep["findings"]]
    p, u = rep["findings"][0]["params"], rep["findings"][0]["params_u95"]
    assert abs(p["midspan_sag_um"] - 3.0) <= u["midspan_sag_um"], (p, u)
    assert rep["findings"][0]["books_to"] == "artefact"


def _bending_fit(bl):
    """The sag (m) the bar_bending columns (core.causes.bending_bar_scans) take beside the volumetric baseline's
    gauge-fixed least squares, unweighted (the round trips below are noise-free)."""
    from core.causes import bending_bar_magnitudes, bending_bar_scans

    d = bl.data.design
    A, y = d.A[bl.rows], d.y[bl.rows]
    scan = bending_bar_scans(bl)[0][0]
    E = np.asarray(scan.build([0]))[0]  # (n, 2): the columns in the rows' own units (discover whitens them)
    _, sv, Vt = np.linalg.svd(bl.C)
    N = Vt[int(np.sum(sv > 1e-12 * sv.max())):].T
    c = np.linalg.lstsq(np.hstack([A @ N, E]), y, rcond=None)[0]
    return bending_bar_magnitudes({}, c[-2:], bl)["midspan_sag_um"] * 1e-6


@pytest.fixture(scope="module")
def campaign5():
    """The 5-axis plan (Mikron UCP710: table C on A), noise-free, the bar as calibrated, no placement draws."""
    from scenarios.mfb import default_machine, run

    res = run("mfb-5axis", seed=5, mc_runs=0, on_nodes=True, bar_cal_error=False, noise_um=0.0, draw_inputs=False)
    cfg, _ = default_machine(res.plan.machine)
    times = {m.name: i * MEAS_S for i, m in enumerate(res.meas)}
    return res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m), times


def test_gravity_in_W_follows_the_table_pose(campaign5):
    """Gravity is the machine's -z_R carried into W by the set-up's nominal table pose (review31c F4).

    By hand for the UCP710 (chain ``w C' A' b X Y Z``: T_R_W = Rot_x(-A) Rot_z(-C), the table's rotaries on the
    workpiece branch): A = -90 deg turns W by +90 deg about x, y_W points up, so g_W = -y_W; A = -90, C = -45:
    Rot_z(45)^T (0, -1, 0) = (-1, -1, 0) / sqrt 2; A = -45, C = 0: (0, -1, -1) / sqrt 2; A = 0: -z_W whatever C.
    On the plan: X3 (along x_W, A -90) sags along -y_W; the standing bars VXa/b/c (along y_W, A -90: vertical) not
    at all; DXZ, AXZ (A -90, C -+45) and DYZ (A -45) at |g_perp| = 1/sqrt 2; X1 (A 0) along -z_W. Tolerance 1e-12:
    rounding of the rotation (cos 90 deg is 6e-17). Without rotary axes gravity is GRAVITY_R itself, bit for bit."""
    import core.baseline as B

    meas, chain, nodes, rp, times = campaign5
    d2 = np.radians
    r2 = 1 / np.sqrt(2)
    for rot, want in [((0, 0), (0, 0, -1)), ((0, d2(73)), (0, 0, -1)), ((d2(-90), 0), (0, -1, 0)),
                      ((d2(-90), d2(-45)), (-r2, -r2, 0)), ((d2(-90), d2(45)), (r2, -r2, 0)),
                      ((d2(-45), 0), (0, -r2, -r2))]:
        assert np.allclose(B.gravity_W(chain, rot, rp), want, atol=1e-12, rtol=0), (rot, B.gravity_W(chain, rot, rp))
    g3 = B.gravity_W("[w b X Y Z (C1) t]")
    assert g3.tobytes() == np.array([0.0, 0.0, -1.0]).tobytes()
    bl = volumetric(meas, chain, nodes, rp, times)
    d = bl.data
    want = {"X1": (0, 0, -1), "X3": (0, -1, 0), "VXa": (0, 0, 0), "VXb": (0, 0, 0), "VXc": (0, 0, 0)}
    for k, name in enumerate(d.meas_names):
        rows = d.meas == k
        gp = np.zeros(3)
        for c in range(3):  # the row's component c of g_perp
            v = d.g_perp[rows & (d.comp == c)]
            if v.size:
                assert np.ptp(v) == 0.0  # one value per measurement and component
                gp[c] = v[0]
        if name in want:
            assert np.allclose(gp, want[name], atol=1e-12, rtol=0), (name, gp)
        if name in ("DXZ", "AXZ", "DYZ"):
            assert abs(np.linalg.norm(gp) - r2) < 1e-12, (name, gp)


def test_gravity_through_the_table_is_what_names_the_5axis_sag(campaign5, monkeypatch):
    """3 um of physical sag on the 5-axis plan (gravity through each set-up's table pose, about the bar's middle):
    the bar_bending columns take 2.996 um of it noise-free (tolerance 0.05 um: the first-order model's remainder on
    a noise-free campaign, measured 4.5 nm here), and with gravity as -z_W at every pose (BAR_GRAVITY_THROUGH_TABLE
    off) they do not (measured 0.03 um); about the probed holes' middle (BAR_BENDING_ABOUT_BAR_MIDDLE off) neither
    (0.54 um); with both off (sessions 13-30) 0.15 um. The bound for "do not": 1 um off the 3 um."""
    import core.baseline as B

    meas, chain, nodes, rp, times = campaign5
    sag = _sagged(meas, 3e-6, "mfb-5axis")
    got = _bending_fit(volumetric(sag, chain, nodes, rp, times))
    assert abs(got - 3e-6) <= 0.05e-6, got
    for flag in ("BAR_GRAVITY_THROUGH_TABLE", "BAR_BENDING_ABOUT_BAR_MIDDLE"):
        with monkeypatch.context() as mp:
            mp.setattr(B, flag, False)
            off = _bending_fit(volumetric(sag, chain, nodes, rp, times))
        assert abs(off - 3e-6) > 1e-6, (flag, off)


def test_single_drift_estimate_within_its_u95(campaign):
    """Each single estimate of the drift (+s and -s), not only the response, within its U95 of the truth.

    Session 28 left this campaign's apparent drift (half the sum of the two estimates) at X +1.8, Y -2.3,
    Z -0.6 ppm against a U95 of 1.0-1.3 ppm: the first-order problem (2) at the nominal placements reads
    a bar turned by w in pitch and yaw as one whose length changed by -(w_y^2 + w_z^2) / 2, a scale per
    placement the drift took. With the observations reduced to first order at the exact solution
    (core.baseline.VOLUMETRIC_REDUCED_AT_SOLUTION, session 29) the errors are X +0.39, Y -0.92, Z +0.34
    ppm (+s) and +0.41, -0.95, +0.28 (-s) against U95 1.06, 1.23, 1.24. Over 20 campaigns (seeds 5-24) the
    +s magnitudes lie within their U95 39 -> 56 of 60, on 20 fresh ones (300-319) 40 -> 55 of 60."""
    meas = campaign[0]
    s = np.array([12e-6, -8e-6, 10e-6])
    for sign in (1, -1):
        f = _discover(campaign, _scale_drifted(meas, sign * s)).to_report()["findings"][0]
        assert f["cause"] == "thermal_drift", f["cause"]
        for a, true in zip("XYZ", -sign * s * 1e6):
            est, u95 = f["params"][f"{a}_scale_change_ppm"], f["params_u95"][f"{a}_scale_change_ppm"]
            assert abs(est - true) <= u95, (a, sign, est, true, u95)


def _drift_fit(bl):
    """The volumetric baseline's gauge-fixed least squares with the three drift columns of
    core.causes.vol_drift_scans beside it (unweighted: the round trip below is noise-free), and the
    scale changes in ppm (ISO sign)."""
    d = bl.data.design
    A, y = d.A[bl.rows], d.y[bl.rows]
    tau = 2 * (bl.data.t_s - bl.data.t_s.min()) / np.ptp(bl.data.t_s) - 1
    D = np.column_stack([(A[:, d.slices[f"E{a}{a}"]] @ d.nodes[a]) * tau for a in "XYZ"])
    _, sv, Vt = np.linalg.svd(bl.C)
    N = Vt[int(np.sum(sv > 1e-12 * sv.max())):].T  # theta = N z satisfies the ISO gauge C theta = 0
    c = np.linalg.lstsq(np.hstack([A @ N, D]), y, rcond=None)[0]
    return 2e6 * c[-3:]


def test_drift_round_trip_with_placements_turned_noise_free():
    """Truth -> noise-free MFB campaign with the placement errors drawn (U_PLACE: 0.5 mrad pitch, 1 mrad
    yaw) -> the drift beside the volumetric baseline: the scale changes within 0.3 ppm on every axis.

    Measured (seed 5): with the observations reduced at the exact solution 0.14, 0.22, 0.06 ppm off (+s);
    with (2)'s own left side (the constant off) 1.24, 1.49, 0.77 ppm off, which the bound fails. Without
    placement draws both read within 0.04 ppm; with the translations and roll alone within 0.08 ppm:
    what is left (0.15 ppm) follows the pitch and yaw still (a first-order remainder not chased). 0.3 ppm
    is half the drift's standard uncertainty on the noisy campaign (0.53-0.62 ppm). The reduced
    observations minus the first-order model at the identification's solution are the exact model's
    residual (2.7 nm RMS here; rel 1e-9: the same numbers by another sum); (2)'s own left side differs
    from them by 0.105 um RMS, 39 times that (the bound 20: the turns' second order is what is removed)."""
    import core.baseline as B
    from scenarios.mfb import default_machine, run

    res = run("mfb-3axis", seed=5, mc_runs=0, on_nodes=True, bar_cal_error=False, noise_um=0.0, draw_inputs=True)
    cfg, _ = default_machine(res.plan.machine)
    times = {m.name: i * MEAS_S for i, m in enumerate(res.meas)}
    s = np.array([12e-6, -8e-6, 10e-6])
    bl = B.volumetric(_scale_drifted(res.meas, s), cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m), times)
    err = _drift_fit(bl) - (-s * 1e6)
    assert np.all(np.abs(err) <= 0.3), err
    assert any("reduced to first order" in c for c in bl.conventions)
    # the identification's own solution fits the reduced observations: its residual is the exact model's
    from core import volumetric as vol

    d, theta = vol.reduced_design(res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m))
    # (reduced_design keeps model (3) by default, discovery's baseline; the identification its own model, the
    # exact extraction (3') since session 32: each reduction is that of the identification with the same model)
    for ext in (False, True):
        d_x, theta_x = vol.reduced_design(res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m),
                                          extraction=ext)
        r_exact = vol.identify_volumetric(res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m),
                                          extraction=ext).rms_m
        assert np.sqrt(np.mean((d_x.y - d_x.A @ theta_x) ** 2)) == pytest.approx(r_exact, rel=1e-9, abs=0)
    assert np.array_equal(d_x.A, d.A) and np.array_equal(d.y, vol.reduced_design(
        res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m), extraction=False)[0].y)
    r_exact = vol.identify_volumetric(res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m),
                                      extraction=False).rms_m
    d1 = vol.design(res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m))
    assert np.array_equal(d.A, d1.A) and np.sqrt(np.mean((d1.y - d.y) ** 2)) > 20 * r_exact


def test_reduced_design_where_the_plan_leaves_combinations_unseen(campaign):
    """A plan that cannot identify every table (five of the fourteen placements): no solution to reduce
    at; reduced_design returns design() itself and None, and the baseline says it is not identifiable
    (no convention line of the reduction)."""
    from core import volumetric as vol

    meas, chain, nodes, rp, times = campaign
    part = [m for m in meas if m.placement in ("X1", "X2", "X3", "Y1", "VY")]
    d, theta = vol.reduced_design(part, chain, nodes, rp)
    assert theta is None and d.unseen.shape[1] > 0
    assert np.array_equal(d.y, vol.design(part, chain, nodes, rp).y)
    bl = volumetric(part, chain, nodes, rp, times)
    assert not bl.identifiable and not any("reduced to first order" in c for c in bl.conventions)


def _z_step(meas):
    """review30c's spindle Z growth: +2.5 um on every reading from the middle measurement on, plus a 1 um ramp."""
    n = len(meas)
    out = []
    for i, m in enumerate(meas):
        O = np.asarray(m.O_R, float).copy()
        O[:, 2] += (2.5e-6 if i >= n // 2 else 0.0) + 1.0e-6 * i / max(n - 1, 1)
        out.append(dataclasses.replace(m, O_R=O))
    return out


def test_an_undetermined_magnitude_prints_no_number(campaign):
    """A Z step read as a lobing per stylus whose pre-travel the plan does not determine: the finding says which
    magnitudes are not determined and their range, never the value and U95 of the unidentifiable fit (review30c,
    seed 11: ``pretravel_pv = 4.46e+09 +- 7.87e+09`` um in the reason). Fails before (the numbers printed)."""
    rep = _discover(campaign, _z_step(campaign[0])).to_report()
    texts = [" ".join(str(f["evidence"].get(k, "")) for k in ("confidence_reason", "magnitude_undetermined"))
             for f in rep["findings"]]
    said = [t for t in texts if "not determined" in t]
    assert said, [(f["cause"], f["evidence"].get("confidence_reason")) for f in rep["findings"]]
    assert not any("+-" in t for t in said), said


def _hvac_x_scale(meas, amp=8e-6):
    """review30c's X scale following an HVAC cycle: +-``amp`` about 1, two periods over the campaign (not monotone:
    no drift), each measurement's axis positions (reading + J) dilated in X."""
    n = len(meas)
    out = []
    for i, m in enumerate(meas):
        f, J = np.array([1 + amp * np.sin(2 * np.pi * 2 * i / n), 1.0, 1.0]), np.asarray(m.J_m)
        out.append(dataclasses.replace(m, O_R=(np.asarray(m.O_R) + J) * f - J, q_R=(np.asarray(m.q_R) + J) * f - J))
    return out


def test_a_scale_that_oscillates_between_measurements_is_structure(campaign, monkeypatch):
    """An X scale of +-8 ppm following two HVAC cycles (points moved by up to about 2 um): structure in the position
    along the bar with its own slope per measurement (core.baseline.VOLUMETRIC_ALONG_BAR_BY_MEASUREMENT), read
    `unexplained` (no catalogue cause oscillates; thermal_drift's monotone form explains too little). Before,
    review30c's seed 11 read `none`: the one along_bar smooth at p = 1.6e-6 explained 0.077 um, below the materiality
    of a residual noise the effect itself inflated (0.242 um against 0.141 without it). Fails with the constant off
    (`outlier` here). The constant is off in the engine (docs/discovery-studies.md, "Session 30: MFB"): set on here."""
    import core.baseline as B

    monkeypatch.setattr(B, "VOLUMETRIC_ALONG_BAR_BY_MEASUREMENT", True)
    rep = _discover(campaign, _hvac_x_scale(campaign[0])).to_report()
    assert rep["cause"] == "unexplained", [(f["cause"], f["evidence"].get("text")) for f in rep["findings"]]
    assert rep["diagnosis"][0]["covariate"] == "along_bar_by_measurement"


# Session 31 (review31c F1, F2, F3, F5): effects out of the catalogue that the MFB discovery must not confidently
# misname. The effects are review31c's generator's (its mfb_disc.py), applied to this module's campaign.
def _bar_axis_s(m):
    """(the bar's frame in W, its axis the first column; the position along the bar scaled -1..1) of measurement
    ``m``, as core.baseline.volumetric."""
    sA = np.asarray(m.O_A)[:, 0]
    return np.asarray(m.T_W_A)[:3, :3], (sA - (sA.max() + sA.min()) / 2) / (np.ptp(sA) / 2)


def _bar_turned_after_first(meas, um):
    """The bar turned in its fixture (yaw about its middle, ``um`` at its ends) after the first measurement of each
    placement measured more than once: the later measurements read it turned."""
    seen, out = {}, []
    for m in meas:
        k = seen.get(m.placement, 0)
        seen[m.placement] = k + 1
        R, s = _bar_axis_s(m)
        u = um * 1e-6 * k * s
        out.append(dataclasses.replace(m, O_R=np.asarray(m.O_R) + u[:, None] * R[:, 1][None, :]) if k else m)
    return out


def _bar_gradient(meas, um, seed):
    """A temperature gradient along the bar changing per measurement: its expansion along the bar a quadratic in the
    position, ``um`` at the ends relative to the middle times a factor 0.5-1 of either sign per measurement."""
    rng, out = np.random.default_rng([seed, 31]), []
    for m in meas:
        R, s = _bar_axis_s(m)
        g = rng.uniform(0.5, 1.0) * rng.choice([-1, 1])
        u = um * 1e-6 * g * (s ** 2 - np.mean(s ** 2))
        out.append(dataclasses.replace(m, O_R=np.asarray(m.O_R) + u[:, None] * R[:, 0][None, :]))
    return out


def _bar_bent(meas, um):
    """Every bar bent by ``um`` at mid-span along gravity's part across it (positive: a sag; negative: upward)."""
    out = []
    for m in meas:
        R, s = _bar_axis_s(m)
        g = np.array([0.0, 0.0, -1.0])
        gp = g - (g @ R[:, 0]) * R[:, 0]
        w = um * 1e-6 * (1 - s ** 2) ** 2
        out.append(dataclasses.replace(m, O_R=np.asarray(m.O_R) + w[:, None] * gp[None, :]))
    return out


def _bar_slipped_after_first(meas, um, seed):
    """The bar translated by ``um`` (a random direction) in its fixture after the first measurement of each placement
    measured more than once."""
    rng, seen, out = np.random.default_rng([seed, 31]), {}, []
    for m in meas:
        k = seen.get(m.placement, 0)
        seen[m.placement] = k + 1
        if k:
            v = rng.normal(size=3)
            v *= um * 1e-6 * k / np.linalg.norm(v)
            m = dataclasses.replace(m, O_R=np.asarray(m.O_R) + v[None, :])
        out.append(m)
    return out


def _said(rep):
    return [(f["cause"], f["evidence"].get("confidence"), f["evidence"].get("confidence_reason"))
            for f in rep["findings"]]


def test_a_bar_turned_in_its_fixture_is_no_confident_dust(campaign, monkeypatch):
    """review31c F1: a bar turned 1 um at its ends after a placement's first measurement put three residuals beyond
    the outlier bound, all in one placement (VY's measurements): each row was its own event, three events, and the
    concentration test (p 0.04 on review31c's seed 342) passed them as dust, `outlier` confident (14 of 20 of its
    campaigns; here too). Counted per placement (core.discover.VOLUMETRIC_OUTLIER_EVENTS) they are one event, which
    cannot tell dust from the bar moving: ambiguous, the moved bar named. Fails with the constant None and
    VOLUMETRIC_HEDGE_SIGNIFICANT_LEFT off (named, 3 events: the concentration test's count, which stays per row).
    Session 32's test of the outliers' measurements (VOLUMETRIC_OUTLIER_MEASUREMENT_STRUCTURE) hedges them too (the
    turned bar moves every point of its later measurements): off here, to see these constants alone."""
    import core.discover as D

    monkeypatch.setattr(D, "VOLUMETRIC_OUTLIER_MEASUREMENT_STRUCTURE", False)
    rep = _discover(campaign, _bar_turned_after_first(campaign[0], 1.0)).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "outlier" and f["evidence"]["confidence"] == "ambiguous", _said(rep)
    assert f["evidence"]["placements"] == 1 and f["evidence"]["moved_bar"].startswith("VY"), f["evidence"]
    assert "moved in its fixture" in f["evidence"]["confidence_reason"]
    # (here the structure left beside them, z at p = 3.8e-5, hedges them too: VOLUMETRIC_HEDGE_SIGNIFICANT_LEFT)
    monkeypatch.setattr(D, "VOLUMETRIC_HEDGE_SIGNIFICANT_LEFT", False)
    f1 = _discover(campaign, _bar_turned_after_first(campaign[0], 1.0)).to_report()["findings"][0]
    assert f1["evidence"]["confidence"] == "ambiguous" and "moved in its fixture" in f1["evidence"]["confidence_reason"]
    monkeypatch.setattr(D, "VOLUMETRIC_OUTLIER_EVENTS", None)
    f0 = _discover(campaign, _bar_turned_after_first(campaign[0], 1.0)).to_report()["findings"][0]
    assert f0["cause"] == "outlier" and f0["evidence"]["confidence"] == "named" and f0["evidence"]["events"] == 3


def test_a_bar_gradient_beside_outliers_is_no_confident_dust(campaign, monkeypatch):
    """review31c F2: a temperature gradient along the bar (1.5 um at the ends, changing per measurement) leaves
    four outliers in four placements and ``along_bar`` significant (p 5.6e-4) though below materiality (0.095 um):
    `outlier` was confident. Beside structure left significant the outliers may be its largest residuals:
    ambiguous (core.discover.VOLUMETRIC_HEDGE_SIGNIFICANT_LEFT). Fails with the constant off (named). Session 32's
    test of the outliers' measurements (VOLUMETRIC_OUTLIER_MEASUREMENT_STRUCTURE: VXa carries the gradient in its
    other points) hedges them first: off here, to see this constant alone."""
    import core.discover as D

    monkeypatch.setattr(D, "VOLUMETRIC_OUTLIER_MEASUREMENT_STRUCTURE", False)
    rep = _discover(campaign, _bar_gradient(campaign[0], 1.5, 5)).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "outlier" and f["evidence"]["confidence"] == "ambiguous", _said(rep)
    assert "along_bar" in f["evidence"]["confidence_reason"] and f["evidence"]["events"] >= 2
    monkeypatch.setattr(D, "VOLUMETRIC_HEDGE_SIGNIFICANT_LEFT", False)
    f0 = _discover(campaign, _bar_gradient(campaign[0], 1.5, 5)).to_report()["findings"][0]
    assert f0["cause"] == "outlier" and f0["evidence"]["confidence"] == "named", f0["evidence"]


def test_bar_sag_plausible_known_answers(monkeypatch):
    """core.causes.bar_sag_plausible: a sag below zero by more than its U95 is refused; within its U95 of zero, or
    positive, or not determined, it stands; with BAR_SAG_GRAVITY_SIGN off nothing is refused."""
    import core.causes as C

    assert C.bar_sag_plausible({"midspan_sag_um": -1.4}, {"midspan_sag_um": 0.33})
    assert C.bar_sag_plausible({"midspan_sag_um": -0.3}, {"midspan_sag_um": 0.33}) is None
    assert C.bar_sag_plausible({"midspan_sag_um": 2.0}, {"midspan_sag_um": 0.1}) is None
    assert C.bar_sag_plausible({"midspan_sag_um": -1.0}, {"midspan_sag_um": None})  # (no U95: the value decides)
    assert C.bar_sag_plausible({}, {}) is None
    monkeypatch.setattr(C, "BAR_SAG_GRAVITY_SIGN", False)
    assert C.bar_sag_plausible({"midspan_sag_um": -1.4}, {"midspan_sag_um": 0.33}) is None


def test_a_bar_bending_upward_is_no_sag(campaign, monkeypatch):
    """review31c F2: seed 347's bar gradient read `bar_bending` confident with a sag of -1.40 +- 0.33 um, the bar
    bending upward. A bar sags along gravity (core.causes.BAR_SAG_GRAVITY_SIGN): 2 um upward here is refused as
    implausible, and the structure it fitted reads `unexplained` (core.discover.VOLUMETRIC_IMPLAUSIBLE_UNEXPLAINED;
    without it `none`). Fails with the sign rule off (bar_bending named, sag -1.9 um) and with the unexplained rule
    off (none)."""
    import core.causes as C
    import core.discover as D

    bent = _bar_bent(campaign[0], -2.0)
    rep = _discover(campaign, bent).to_report()
    assert rep["cause"] == "unexplained", _said(rep)
    assert any(r["cause"] == "bar_bending" and r["reason"].startswith("implausible") for r in rep["rejected"])
    assert "bar_bending" in rep["findings"][0]["evidence"]["text"]
    monkeypatch.setattr(D, "VOLUMETRIC_IMPLAUSIBLE_UNEXPLAINED", False)
    assert _discover(campaign, bent).to_report()["cause"] == "none"
    monkeypatch.setattr(C, "BAR_SAG_GRAVITY_SIGN", False)
    rep0 = _discover(campaign, bent).to_report()
    assert rep0["cause"] == "bar_bending" and rep0["findings"][0]["params"]["midspan_sag_um"] < 0, _said(rep0)


def test_a_per_stylus_shift_names_the_moved_bar_as_its_rival(campaign, monkeypatch):
    """review31c F5: on the 3-axis plan the later measurements of VY and VX each use a stylus no other measurement
    uses, so a bar that slipped after a placement's first measurement is exactly a shift per stylus:
    `lobing_per_stylus` ambiguous with no rival named. The finding names the measurements a moved bar would
    shift (``moved_bar``, core.discover.VOLUMETRIC_MOVED_BAR_RIVAL). Fails with the constant off."""
    import core.discover as D

    slipped = _bar_slipped_after_first(campaign[0], 1.5, 1)
    rep = _discover(campaign, slipped).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "lobing_per_stylus" and f["evidence"]["confidence"] == "ambiguous", _said(rep)
    assert "VY (VYa, VYb, VYc)" in f["evidence"]["moved_bar"] and "VX (VXa, VXb)" in f["evidence"]["moved_bar"]
    assert "moved in its fixture" in f["evidence"]["confidence_reason"]
    monkeypatch.setattr(D, "VOLUMETRIC_MOVED_BAR_RIVAL", False)
    f0 = _discover(campaign, slipped).to_report()["findings"][0]
    assert "moved_bar" not in f0["evidence"] and "moved in its fixture" not in f0["evidence"]["confidence_reason"]


def test_a_warming_drift_with_immaterial_structure_beside_it_stays_named(campaign, monkeypatch):
    """The significant-left hedge spares a catalogue cause that explains as much as a plain smooth of its own
    covariate (core.discover.VOLUMETRIC_HEDGE_LEFT_RIVAL_SHARE, 0.75): a drift of 8 ppm (random signs, a warming
    course tau (2 - tau)) reads `thermal_drift` confidently (rival share 0.97) beside structure left significant
    though immaterial; with every named cause hedged (the share None) it reads ambiguous (review31c's grid: 8 right
    names hedged so)."""
    import core.discover as D

    meas = campaign[0]
    rng = np.random.default_rng([2, 31])
    s = 8e-6 * rng.choice([-1.0, 1.0], 3) * rng.uniform(0.7, 1.0, 3)
    drifted = []
    for i, m in enumerate(meas):
        tau = i / (len(meas) - 1)
        f, J = 1 + s * tau * (2 - tau), np.asarray(m.J_m)
        drifted.append(dataclasses.replace(m, O_R=(np.asarray(m.O_R) + J) * f - J, q_R=(np.asarray(m.q_R) + J) * f - J))
    rep = _discover(campaign, drifted).to_report()
    f = rep["findings"][0]
    assert f["cause"] == "thermal_drift" and f["evidence"]["confidence"] == "named", _said(rep)
    assert f["evidence"]["rival_share"] >= 0.75
    monkeypatch.setattr(D, "VOLUMETRIC_HEDGE_LEFT_RIVAL_SHARE", None)
    f0 = _discover(campaign, drifted).to_report()["findings"][0]
    assert f0["cause"] == "thermal_drift" and f0["evidence"]["confidence"] == "ambiguous"
    assert "significant though below materiality" in f0["evidence"]["confidence_reason"]
def test_a_sag_on_the_realistic_bar_at_one_sigma_of_its_noise():
    """The realistic bar (bar_cal_error on: the bar differs from its calibration by 0.2-0.35 um per hole, drawn):
    MFB has no repeats, so vmt's noise is the residuals' and holds that deviation (review31c F6: 0.34-0.50 um, 2.7-4
    times the 0.125 um touch noise; here 0.44 um). A 12 um sag at mid-span (about the bar's middle, gravity through
    the table: _sagged) leaves 0.47 um RMS outside the baseline's column space (the whitened rows' part no error
    table, placement or gauge takes), 1.07 sigma of that noise (asserted >= 1 sigma: the test is about an effect of
    one sigma of vmt's own noise, not of the touch noise): named bar_bending, 11.71 um, U95 1.28 um. On this bar
    3 um (0.27 sigma) is not named (rejected: its cross-validated gain 0.0116 um^2 below the materiality (0.3 x
    0.44 um)^2), 6 um (0.53 sigma) is: 5.71 um.

    Session 31 (bend31), the same injection on review31c's realistic 3-axis campaigns (seeds 311-322): 3 um (0.19-0.35
    sigma outside the baseline) named 3 of 12, 6 um (0.39-0.70 sigma) 12 of 12, 10 um (0.64-1.16 sigma) 12 of 12, its
    estimate 8.7-11.3 um (the bar's own deviation from its calibration has a part of the bending's shape, up to
    1.3 um, the same at every sag on one bar)."""
    from scenarios.mfb import default_machine, run

    res = run("mfb-3axis", seed=5, mc_runs=0, on_nodes=True)  # bar_cal_error on: the default
    cfg, _ = default_machine(res.plan.machine)
    times = {m.name: i * MEAS_S for i, m in enumerate(res.meas)}
    c = (res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m), times)
    bl0 = volumetric(*c)
    rep0 = discover_baseline(bl0).to_report()
    sigma = rep0["noise_um"]["sigma_um"]
    assert sigma > 2.5 * 0.125, sigma  # the bar's deviation dominates the residuals
    sag = 12e-6
    bl = volumetric(_sagged(res.meas, sag, "mfb-3axis"), *c[1:])
    dy = bl.y - bl0.y
    outside = dy - bl0.A @ np.linalg.lstsq(bl0.A, dy, rcond=None)[0]
    vis = np.sqrt(np.mean(outside ** 2)) * 1e6
    assert vis >= sigma, (vis, sigma)
    rep = discover_baseline(bl).to_report()
    assert rep["cause"] == "bar_bending", [(f["cause"], f["evidence"].get("text")) for f in rep["findings"]]
    p, u = rep["findings"][0]["params"], rep["findings"][0]["params_u95"]
    assert abs(p["midspan_sag_um"] - sag * 1e6) <= u["midspan_sag_um"], (p, u)


def _dust(meas, um, seed):
    """Dust in two holes: two points of interest, in two measurements drawn at random, each moved by ``um`` in a
    random direction (the touch on the chip moved its hole's point); nothing else."""
    rng = np.random.default_rng([seed, 32])
    out = list(meas)
    for i in rng.choice(len(meas), 2, replace=False):
        O = np.array(meas[i].O_R, float)
        h = rng.integers(len(O))
        v = rng.normal(size=3)
        O[h] += v * um * 1e-6 / np.linalg.norm(v)
        out[i] = dataclasses.replace(meas[i], O_R=O)
    return out


def test_outliers_in_a_measurement_that_deforms_are_no_confident_dust(campaign, monkeypatch):
    """Session 32 (mfbre32; review31c's realistic bar_gradient 3 um seed 315 read `outlier` named): a temperature
    gradient along the bar (1.5 um, seed 7 of _bar_gradient) leaves four outliers in three placements beside an
    `unexplained`; nothing significant is left beside them and they span events enough, so the session-31 hedges
    let them stand as confident dust. The measurement VYc holding one of them carries a line and parabola along the
    bar in its other points (F 5.6, p 7.5e-5 after Bonferroni, 1.35 um^2): they are that deformation's largest
    residuals (core.discover.VOLUMETRIC_OUTLIER_MEASUREMENT_STRUCTURE): ambiguous. Fails with the constant off
    (named). Dust in two holes (1.5 um, _dust seed 1) stays confident: the other points of its measurements are
    clean."""
    import core.discover as D

    def outlier(meas):
        rep = _discover(campaign, meas).to_report()
        return next(f for f in rep["findings"] if f["cause"] == "outlier"), rep

    f, rep = outlier(_bar_gradient(campaign[0], 1.5, 7))
    assert f["evidence"]["confidence"] == "ambiguous", _said(rep)
    assert f["evidence"]["measurement_structure"]["measurement"] == "VYc", f["evidence"]
    assert "carries structure along the bar" in f["evidence"]["confidence_reason"]
    f, rep = outlier(_dust(campaign[0], 1.5, 1))
    assert f["evidence"]["confidence"] == "named" and "measurement_structure" not in f["evidence"], _said(rep)
    monkeypatch.setattr(D, "VOLUMETRIC_OUTLIER_MEASUREMENT_STRUCTURE", False)
    f, rep = outlier(_bar_gradient(campaign[0], 1.5, 7))
    assert f["evidence"]["confidence"] == "named", _said(rep)


def test_a_bar_gradient_read_as_a_sag_is_hedged_by_its_move_along_the_bar(campaign, monkeypatch):
    """Session 32 (mfbre32): review31c's campaign 349 (mfb-3axis, the bar as calibrated) with its temperature gradient
    along the bar (1.5 um at the ends, a factor 0.5-1 of either sign per measurement: _bar_gradient draws the same as
    review31c's generator) reads `bar_bending` named, a 3.88 um sag, since session 31's bending columns about the
    bar's middle (rival share 0.82, above the 0.75 that hedges a cause beside structure left). Gravity moves no point
    along its bar; the gradient does, differently in each measurement: a parabola per measurement along the bar's
    axis is significant beside the extended model (F 23.9, p 6e-36, 7.6 um^2), so the sag is ambiguous
    (core.discover.VOLUMETRIC_BENDING_ALONG_BAR_RIVAL). Fails with the constant off (named). A sag (2 um about the
    bar's middle, gravity through the table: _sagged) on the module's campaign stays named (2.11 um)."""
    import core.discover as D
    from scenarios.mfb import default_machine, run

    res = run("mfb-3axis", seed=349, mc_runs=0, bar_cal_error=False)
    cfg, _ = default_machine(res.plan.machine)
    times = {m.name: i * MEAS_S for i, m in enumerate(res.meas)}
    c = (res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m), times)

    def first(camp, meas):
        rep = _discover(camp, meas).to_report()
        return rep["findings"][0], rep

    f, rep = first(c, _bar_gradient(res.meas, 1.5, 349))
    assert f["cause"] == "bar_bending" and f["evidence"]["confidence"] == "ambiguous", _said(rep)
    assert f["evidence"]["along_bar_structure"]["p_value"] < 1e-6 and "along their bar" in f["evidence"][
        "confidence_reason"]
    f, rep = first(campaign, _sagged(campaign[0], 2e-6, "mfb-3axis"))
    assert f["cause"] == "bar_bending" and f["evidence"]["confidence"] == "named", _said(rep)
    assert "along_bar_structure" not in f["evidence"]
    monkeypatch.setattr(D, "VOLUMETRIC_BENDING_ALONG_BAR_RIVAL", False)
    f, rep = first(c, _bar_gradient(res.meas, 1.5, 349))
    assert f["cause"] == "bar_bending" and f["evidence"]["confidence"] == "named", _said(rep)
