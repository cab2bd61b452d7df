"""core.volumetric: 21-error identification, gauge, observability, tables (MFB eqs 8-12)."""

import numpy as np
import pytest

from core import volumetric as vol
from core.exceptions import ConfigError, IdentifiabilityError


@pytest.fixture(scope="module")
def meas3(mfb3_noise_free):
    """Noise-free measurements of the 3-axis plan on the default realistic machine (tests/conftest.py)."""
    return mfb3_noise_free[1]


def test_gauge_is_iso_and_full_plan_observable(meas3):
    meas, chain, nodes, rp = meas3
    rep = vol.observability(meas, chain, nodes, rp)
    assert rep.ok, rep.unidentifiable
    g = " ".join(rep.gauge)
    for s in ("EXX", "EYY", "EZZ"):  # positioning zero at the first node (EX0X = 0 ...)
        assert f"{s} = 0 at the first node" in g
    # end-point lines on all six straightness tables: the slope of EYX, EZX, EZY is a gauge
    # freedom (placements), and with the errors at the axis positions (eq. 8) the slope of EXY,
    # EXZ, EYZ is one combination with a squareness and a constant angular error (below), which
    # ISO's end-point line gives to the squareness (session 27; 9 lines, EXY/EXZ/EYZ at their
    # first node only, while the errors were evaluated at the tip readings)
    assert g.count("end-point reference line") == 12
    for s in ("EXY", "EXZ", "EYZ"):
        assert f"{s} = 0 at the last node (end-point reference line)" in g
    # the constant angular errors of the table-carrying axes (a rotated table is a rotated bar)
    for s in ("EAX", "EBX", "ECX", "EAY", "EBY", "ECY"):
        assert f"{s} = 0 at the first node" in g
    # those of Z (the spindle's) are sensed through the styli's lever arms: not in the gauge
    for s in ("EAZ", "EBZ", "ECZ"):
        assert s not in g
    assert len(rep.gauge) == 21
    assert rep.rank == rep.n_params - len(rep.gauge)
    assert rep.sv_min_rel > 1e-5  # conditioning of the gauge-fixed, column-scaled design


# squareness = straightness slope + constant angular error (signs by core.kinematics' chain; the
# hand derivation: EB0Z tilts the Z motion and the tool it carries, the tip moves EB0Z (Z - J_z)
# along x: an EXZ slope EB0Z * Z and a constant EBZ = EB0Z on the lever arm -J_z). The angular
# term is there when the axis carries the tool (Z on both machines, Y on the Mikron); vmc-3axis's
# Y carries the table, whose constant ECY is a rotated bar (a placement's freedom): EC0Y is the
# EXY slope alone there.
_TRIPLES = (("EB0Z", "EXZ", +1.0, "EBZ", +1.0), ("EA0Z", "EYZ", -1.0, "EAZ", +1.0),
            ("EC0Y", "EXY", -1.0, "ECY", 0.0))
_TOOL_SIDE_ECY = {"vmc-3axis": 0.0, "mikron-ucp710": 1.0}


@pytest.mark.parametrize("sq,st,a,ang,b", _TRIPLES)
def test_squareness_is_a_straightness_slope_and_a_constant_angular_error(meas3, sq, st, a, ang, b):
    """The first-order design (2) of the 3-axis plan (every stylus: T0, TX1/TX2 star arms, TYL
    extension): the squareness's column equals ``a`` x the straightness table's column at slope 1
    (node values = the axis positions of its nodes) plus ``b`` x the angular table's columns at a
    constant 1, to rounding (1e-12 relative; 0.25-0.55 while the errors were evaluated at the
    readings); so the combination is a null direction and the gauge must fix it."""
    meas, chain, nodes, rp = meas3
    d = vol.design(meas, chain, nodes, rp)
    A = d.A
    x = np.asarray(d.nodes[st[-1]], float)
    combo = a * (A[:, d.slices[st]] @ x) + b * A[:, d.slices[ang]].sum(axis=1)
    col = A[:, d.slices[sq]][:, 0]
    assert np.linalg.norm(col) > 0 and np.linalg.norm(col - combo) < 1e-12 * np.linalg.norm(col)


def test_squareness_identity_on_the_chain_by_stylus():
    """The same identity on core's exact chain, stylus by stylus (a star arm along X, one along Y,
    an extension), on both built-in chains: the tip moved by the squareness e equals the tip moved
    by the slope a e (at the axis positions reading + J) and the constant b e, to second order
    (e = 10 urad over 0.4 m: < 1e-10 m of ~4 um)."""
    from core import kinematics as K
    from sim.machines import MACHINES

    rng = np.random.default_rng(5)
    for name in ("vmc-3axis", "mikron-ucp710"):
        cfg = MACHINES[name]()
        for J in ((0.0, 0.0, 0.150), (-0.100, 0.0, 0.150), (0.0, -0.100, 0.250)):
            g = K.ChainGeometry.of(cfg.chain, J, dict(cfg.rotary_points_R_m or {}) or None)
            nr = len(g.chain.rotary_axes)
            r = rng.uniform(-0.2, 0.2, (20, 3))
            rot = None if not nr else np.zeros((20, nr))
            q, e, z = r + np.asarray(J), 1e-5, np.zeros(20)
            base = K.tip_W(g, r, rot, None)
            for sq, st, a, ang, b in _TRIPLES:
                b = _TOOL_SIDE_ECY[name] if ang == "ECY" else b
                ax = "XYZ".index(st[-1])
                d_sq = K.tip_W(g, r, rot, {sq: z + e}) - base
                d_c = K.tip_W(g, r, rot, {st: a * e * q[:, ax], ang: z + b * e}) - base
                assert np.abs(d_sq).max() > 1e-6 and np.abs(d_sq - d_c).max() < 1e-10, (name, J, sq)


# the standing bars are the only placements nothing else replaces (the X/Y
# bars at a second height or with a second stylus are backed, weakly, by the
# diagonal pairs: without X2 the weakest relative sv is 3e-5); since session 27 only VY: EB0Z,
# which VX alone gave while the errors were evaluated at the readings, is now the EXZ slope (the
# gauge's) plus a constant EBZ, which VY's extension TYL senses through its lever arm
@pytest.mark.parametrize("drop,names", [("VY", "EAZ")])
def test_plan_without_a_placement_names_what_is_lost(meas3, drop, names):
    meas, chain, nodes, rp = meas3
    full = vol.observability(meas, chain, nodes, rp).gauge  # conventions of the complete plan
    kept = [m for m in meas if m.placement != drop]
    rep = vol.observability(kept, chain, nodes, rp, gauge=full)
    assert not rep.ok and names in " ".join(rep.unidentifiable)
    with pytest.raises(IdentifiabilityError, match="cannot identify"):
        vol.identify_volumetric(kept, chain, nodes, rp, gauge=full)


def test_plan_without_vx_is_still_observable(meas3):
    """VX (TX1 vs TX2 along X) backs up what VY's star arms and extension sense (see above)."""
    meas, chain, nodes, rp = meas3
    full = vol.observability(meas, chain, nodes, rp).gauge
    rep = vol.observability([m for m in meas if m.placement != "VX"], chain, nodes, rp, gauge=full)
    assert rep.ok, rep.unidentifiable


def test_spline_weights_interpolate_nodes_and_cubics():
    x = np.linspace(0, 0.5, 6)
    W = vol.spline_weights(x, x)
    assert np.allclose(W, np.eye(6), atol=1e-12)
    u = np.linspace(0, 0.5, 37)
    f = lambda t: 3 * t ** 3 - t + 0.2  # noqa: E731  a not-a-knot spline reproduces cubics
    assert np.allclose(vol.spline_weights(x, u) @ f(x), f(u), atol=1e-12)


def test_spline_weights_cached_per_node_table():
    """The splines are built once per node table (issue 19): the same table again gives the same
    weights, another table of the same length its own (a cubic reproduced; beyond the ends the
    end tangent), and a caller writing into the weights does not change the cache."""
    f = lambda t: 3 * t ** 3 - t + 0.2  # noqa: E731
    df = lambda t: 9 * t ** 2 - 1  # noqa: E731
    for x in (np.linspace(0, 0.5, 6), np.linspace(-0.2, 0.1, 6), np.linspace(0, 0.5, 6)):
        u = np.array([x[0] - 0.01, x[0], 0.5 * (x[1] + x[2]), x[-1], x[-1] + 0.02])
        W = vol.spline_weights(x, u)
        want = f(u)
        want[0] = f(x[0]) - 0.01 * df(x[0])
        want[-1] = f(x[-1]) + 0.02 * df(x[-1])
        assert np.allclose(W @ f(x), want, atol=1e-12)
        W[:] = 0.0


def test_bad_input(meas3):
    meas, chain, nodes, rp = meas3
    with pytest.raises(ConfigError, match="no measurements"):
        vol.identify_volumetric([], chain, nodes)
    bad = dict(nodes)
    bad["X"] = bad["X"][::-1]
    with pytest.raises(ConfigError, match="strictly increasing"):
        vol.identify_volumetric(meas, chain, bad)
    short = dict(nodes)
    short["Y"] = nodes["Y"][:-1]  # the last Y bar touches 84 mm beyond the last node: refused, not extrapolated
    with pytest.raises(ConfigError, match="outside the Y nodes"):
        vol.identify_volumetric(meas, chain, short)


def test_iso_map_end_point_line(meas3):
    # known answer: a straightness table that is a line plus a bump is reported
    # as the bump minus its own end-point line (zero at both ends); positioning
    # and angular tables pass unchanged
    meas, chain, nodes, rp = meas3
    d = vol.design(meas, chain, nodes, rp)
    L = vol.iso_map(d)
    th = np.zeros(len(d.names))
    x = d.nodes["Y"]
    bump = 1e-6 * np.sin(np.pi * (x - x[0]) / (x[-1] - x[0]))
    th[d.slices["EXY"]] = 3e-6 + 2e-5 * x + bump
    th[d.slices["EYY"]] = 1e-5 * x
    out = L @ th
    assert np.allclose(out[d.slices["EXY"]], bump, atol=1e-18)
    assert np.allclose(out[d.slices["EYY"]], th[d.slices["EYY"]])
    assert vol.end_point_slopes(d, th)["EXY"] == pytest.approx(2e-5)


def test_placement_errors_are_absorbed_and_bad_u_place(meas3):
    # a placement error moves the bar rigidly; the estimator takes translation,
    # pitch and yaw into the placement's nuisance values (share ~1e-12 per mm /
    # mrad, rounding). The roll is not estimated: it moves only the shifted
    # holes along z_A (not used) and the points by roll x their calibrated
    # offsets from the bar axis (a few um): 1 mrad of roll gives 0.04 um / urad
    # at most (the tilted diagonals), 4 % of what 0.1 um of calibration error
    # gives; bound 10 %.
    meas, chain, nodes, rp = meas3
    res = vol.identify_volumetric(meas, chain, nodes, rp, exact=False)
    d = res.design
    idx = np.array([i for s in vol.MOTION + vol.SQUARENESS for i in range(d.slices[s].start, d.slices[s].stop)])
    uc = vol.uncertainty(res, meas, 0.0, np.full((12, 3), 1e-7), runs=0).u_lin[idx].max()
    for j in range(6):
        u = np.zeros(6)
        u[j] = 1e-3
        up = vol.uncertainty(res, meas, 0.0, np.zeros((12, 3)), runs=0, u_place=u).u_lin[idx].max()
        assert up < (0.1 * uc if j == 3 else 1e-10), (j, up)
    with pytest.raises(ConfigError, match="u_place must be 6"):
        vol.uncertainty(res, meas, 0.0, np.zeros((12, 3)), runs=0, u_place=(1e-4, 1e-4))


def test_identify_shortcuts_give_the_reference_bit_for_bit(meas3, monkeypatch):
    # the plan's nominal design kept between identifications, the theta-independent parts of the
    # rows computed once, the last residual without its Jacobian: against the path without them
    # (every design from scratch, every _rows call recomputing everything with its Jacobian),
    # kept here as the reference by monkeypatching; theta, K and the design identical bit for bit
    meas, chain, nodes, rp = meas3
    # a run off the noise-free one (readings moved 0.3 um) so that the iterations have work to do
    rng = np.random.default_rng(2)
    from dataclasses import replace

    meas = [replace(m, q_R=m.q_R + rng.normal(0, 3e-7, m.q_R.shape)) for m in meas]
    vol._NOMINAL.clear()
    new = vol.identify_volumetric(meas, chain, nodes, rp)
    assert len(vol._NOMINAL) == 1
    again = vol.identify_volumetric(meas, chain, nodes, rp)  # from the kept nominal design
    from scenarios.bench.mfb import NeverKept, rows_whole  # the bench's reference path, the same

    monkeypatch.setattr(vol, "_rows", rows_whole(vol._rows))
    monkeypatch.setattr(vol, "_NOMINAL", NeverKept())
    ref = vol.identify_volumetric(meas, chain, nodes, rp)
    for r in (new, again):
        assert r.iterations == ref.iterations >= 2
        assert np.array_equal(r.theta, ref.theta) and np.array_equal(r.K, ref.K) and r.rms_m == ref.rms_m
        for f in ("A", "y", "C", "null", "unseen", "sv_rel"):
            assert np.array_equal(getattr(r.design, f), getattr(ref.design, f)), f
        assert r.design.gauge == ref.design.gauge


def test_nominal_design_kept_per_plan(meas3):
    # the key holds everything the nominal design reads: another stylus offset, another plan or
    # another node table is another entry; new readings of the same plan are not
    meas, chain, nodes, rp = meas3
    from dataclasses import replace

    k0 = vol._nominal_key(meas, chain, nodes, rp, None, ("a",))
    moved = [replace(meas[0], O_R=meas[0].O_R + 1e-6, q_R=meas[0].q_R + 1e-6)] + list(meas[1:])
    assert vol._nominal_key(moved, chain, nodes, rp, None, ("a",)) == k0
    other_J = [replace(meas[0], J_m=(0.0, 0.0, 0.151))] + list(meas[1:])
    assert vol._nominal_key(other_J, chain, nodes, rp, None, ("a",)) != k0
    assert vol._nominal_key(meas[1:], chain, nodes, rp, None, ("a",)) != k0
    nodes2 = dict(nodes, X=np.asarray(nodes["X"]) + 1e-3)
    assert vol._nominal_key(meas, chain, nodes2, rp, None, ("a",)) != k0
    G2 = np.array(meas[0].G_A, float)
    G2[0, 0] += 1e-9
    assert vol._nominal_key([replace(meas[0], G_A=G2)] + list(meas[1:]), chain, nodes, rp, None, ("a",)) != k0
    # residual alone: the same numbers as with the Jacobian
    names, slices, n, _ = vol._layout(meas, {a: np.asarray(v, float) for a, v in nodes.items()})
    th = np.random.default_rng(1).normal(0, 1e-6, n)
    J, r1, _ = vol._rows(meas, chain, rp, nodes, th, slices, n, True)
    none, r2, _ = vol._rows(meas, chain, rp, nodes, th, slices, n, True, jacobian=False)
    assert none is None and J.shape == (len(r1), n) and np.array_equal(r1, r2)


def test_touches_of_all_measurements_in_one_call_are_the_per_measurement_calls(meas3):
    # the rows' kinematics batched over the measurements (7 styli in one call, per-pose J) against
    # a call per measurement with its own stylus geometry, the path before: bit for bit, at a
    # theta off zero (Gauss-Newton) and at zero (the design), tips at the touches and at the points
    meas, chain, nodes, rp = meas3
    nodes = {a: np.asarray(v, float) for a, v in nodes.items()}
    names, slices, n, _ = vol._layout(meas, nodes)
    assert len({m.J_m for m in meas}) >= 5  # several styli mixed in the batch
    prep = vol._prepare_all(meas, chain, rp, nodes)
    for theta in (np.zeros(n), np.random.default_rng(3).normal(0, 1e-5, n)):
        S, tip, at = vol._touch_kinematics(prep, theta, slices, True, True)
        for i, (m, pm) in enumerate(zip(meas, prep)):
            g = vol._geom(chain, m.J_m, rp)
            t = len(pm["qt"])
            v = vol._values(theta, slices, pm["W"], t)
            rows = slice(at[i], at[i] + t)
            assert np.array_equal(S[rows], vol.sensitivity(g, pm["qt"], pm["rott"], v, symbols=vol.MOTION + vol.SQUARENESS))
            assert np.array_equal(tip[rows], vol.tip_W(g, pm["qt"], pm["rott"], v))
            assert np.array_equal(pm["tip0_t"], vol.tip_W(g, pm["qt"], pm["rott"], None))
            assert np.array_equal(pm["pred0"], vol.tip_W(g, pm["q"], pm["rot"], None))
    assert vol._touch_kinematics(prep, theta, slices, False, False) == (None, None, {})
    # the rows' Jacobian: the touches' rows projected and spread over the nodes for all measurements
    # at once, against each measurement's own product (the path before), at the last theta
    J, _, _ = vol._rows(meas, chain, rp, nodes, theta, slices, n, True, prep=prep)
    r0 = 0
    for i, (m, pm) in enumerate(zip(meas, prep)):
        k, t = pm["k"], len(pm["qt"])
        Jt = vol._projected_error_jacobian(S[at[i]:at[i] + t], pm["d_W"], pm["W"], slices, n)
        own = (pm["GW"].reshape(3 * k, t) @ Jt).reshape(k, 3, n)
        rows = J[r0:r0 + 3 * k].reshape(k, 3, n)
        off = ~pm["off"]  # the placement's columns and the roll projection come after: compare the rest
        mask = np.ones(n, bool)
        sl = slices[m.placement]
        mask[sl] = False
        assert np.array_equal(rows[off][:, :, mask], own[off][:, :, mask]), m.name
        r0 += 3 * k


def test_lack_of_fit_known_answers_and_bad_input(meas3):
    # review29b F2. Noise-free measurements of the realistic 3-axis machine: the residuals are the
    # model's own truncation (the tables' splines against the truth's 9-knot profiles, nm). Declared
    # against the probe's 0.125 um they fit (ratio << 1); declared against a 1 pm probe the same
    # residuals are far beyond its noise (p ~ 0); with no input at all there is nothing to test (None).
    # The residual RMS is the identification's own (res.rms_m: the same rows at the same solution).
    meas, chain, nodes, rp = meas3
    res = vol.identify_volumetric(meas, chain, nodes, rp)
    u0 = np.zeros((12, 3))
    ok = vol.lack_of_fit(res, meas, 0.125e-6, u0)
    assert ok.fits and ok.p > 0.5 and ok.ratio < 0.5 and ok.dof > 1
    assert ok.rms_m == pytest.approx(res.rms_m, rel=1e-9, abs=0)
    bad = vol.lack_of_fit(res, meas, 1e-12, u0)
    assert not bad.fits and bad.p < 1e-12 and bad.ratio > 10
    assert set(bad.as_dict()) >= {"rms_um", "expected_rms_um", "tested_ratio", "dof", "p", "fits"}
    assert vol.lack_of_fit(res, meas, 0.0, u0) is None
    for args, match in (((-1e-7, u0), "sigma_probe_m"), ((float("nan"), u0), "sigma_probe_m"),
                        ((1e-7, np.zeros((12, 2))), "u_cal_m"), ((1e-7, u0, (1e-4,)), "u_place")):
        with pytest.raises(ConfigError, match=match):
            vol.lack_of_fit(res, meas, *args)


def test_model_error_share_enters_only_when_residuals_show_it_and_bad_input(meas3, monkeypatch):
    # review29b F2b. The same noise-free measurements as the lack-of-fit test: against the probe's
    # 0.125 um the model's own truncation (nm) is far inside the noise, so no table enters (z <= 3)
    # and the U95 is unchanged to the last bit; against a 1 pm probe the same residuals are far beyond
    # it, so shares enter and the U95 grows by exactly their columns (u^2 adds: rel 1e-12, rounding).
    meas, chain, nodes, rp = meas3
    res = vol.identify_volumetric(meas, chain, nodes, rp)
    u0 = np.zeros((12, 3))
    quiet = vol.model_error_share(res, meas, 0.125e-6, u0)
    assert quiet.entered == () and quiet.columns.shape == (len(res.theta), 0)
    assert max(quiet.z.values()) <= vol.MFB_MODEL_ERROR_Z and set(quiet.z) == set(quiet.p) == set(vol.MOTION)
    assert min(quiet.p.values()) > vol.MFB_MODEL_ERROR_P   # the exact tail agrees here
    # against the 1 pm probe the tails are Satterthwaite's (session 35): p ~ 0 either way, and Imhof's quadrature
    # this far out took 27 of the test's 29 s CPU (its known answers: the tail tests below)
    monkeypatch.setattr(vol, "_tail", lambda lam, x, p_sat, level, exact=False: (float(p_sat), True))
    loud = vol.model_error_share(res, meas, 1e-12, u0)
    assert loud.entered and all(loud.z[s] > vol.MFB_MODEL_ERROR_Z and loud.u[s] > 0 for s in loud.entered)
    assert all(0.0 <= v <= 1.0 for v in loud.p.values()) and min(loud.p.values()) < vol.MFB_MODEL_ERROR_P
    assert all(loud.u[s] == 0 for s in vol.MOTION if s not in loud.entered)
    base = vol.uncertainty(res, meas, 1e-12, u0, runs=0)
    same = vol.uncertainty(res, meas, 1e-12, u0, runs=0, model_error=quiet.columns)
    assert np.array_equal(base.u_lin, same.u_lin)
    wide = vol.uncertainty(res, meas, 1e-12, u0, runs=0, model_error=loud.columns)
    add = np.einsum("ij,ij->i", loud.columns, loud.columns)
    np.testing.assert_allclose(wide.u_lin ** 2, base.u_lin ** 2 + add, rtol=1e-12, atol=1e-40)
    assert np.any(add > 0)
    cov = vol.covariance(res, meas, 1e-12, u0, model_error=loud.columns)
    np.testing.assert_allclose(np.diag(cov), wide.u_lin ** 2, rtol=1e-9, atol=1e-40)
    assert vol.model_error_share(res, meas, 0.0, u0) is None
    d = loud.as_dict()
    assert d["entered"] == list(loud.entered) and set(d["u"]) == set(loud.entered)
    # without the exact tails (session 34: the budget study's runs keep the columns only) the shares are the
    # same numbers, p None; the JSON says p null
    fast = vol.model_error_share(res, meas, 1e-12, u0, exact_p=False)
    assert fast.p is None and fast.entered == loud.entered and fast.z == loud.z and fast.u == loud.u
    assert np.array_equal(fast.columns, loud.columns) and fast.as_dict()["p"] is None
    # the fine rows' kinematics computed once for the 18 tables (session 34) give each table's rows as a
    # call of its own does (the same numbers: the first table checked bit for bit)
    prep = vol._prepare_all(meas, res.chain, res.rotary_points_R_m, res.design.nodes)
    kin = vol._fine_kinematics(res, prep)
    for s in ("EXX", "EBZ"):
        a, b = vol._fine_rows(res, meas, prep, s, 1e-3, kin), vol._fine_rows(res, meas, prep, s, 1e-3)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
        # the node values, put in the design's gauge all columns at once: each column is in the gauge
        # (Design.to_gauge leaves it where it is, to rounding) and the hat functions' values sum to 1 per node
        S = a[1]
        np.testing.assert_allclose(np.column_stack([res.design.to_gauge(c) for c in S.T]), S, rtol=0,
                                   atol=1e-12)
        assert S.shape[1] > 50 and np.abs(S).max() > 0.5
    for args, kw, match in (((-1e-7, u0), {}, "sigma_probe_m"), ((float("nan"), u0), {}, "sigma_probe_m"),
                            ((1e-7, np.zeros((12, 2))), {}, "u_cal_m"), ((1e-7, u0, (1e-4,)), {}, "u_place"),
                            ((1e-7, u0), {"step_m": 0.0}, "step_m"), ((1e-7, u0), {"z_min": float("nan")}, "z_min")):
        with pytest.raises(ConfigError, match=match):
            vol.model_error_share(res, meas, *args, **kw)
    with pytest.raises(ConfigError, match="model_error"):
        vol.uncertainty(res, meas, 1e-7, u0, runs=0, model_error=np.zeros((3, 1)))


def test_exact_extraction_predicts_the_points_fitted_from_the_moved_touches(meas3):
    """(3') of the module doc, known answers: at theta = 0 the prediction is model (3)'s exactly (the fit of the
    error-free tips against itself: the residuals the same doubles); at a theta of errors it is the points of
    interest fitted (core.mfb.points_of_interest, the single fits) from each touch moved to its actual tip
    tip_W(q; E), to the fits' convergence (the batched fits of the identification against the single ones: 1e-12 m
    allowed, measured below 1e-14 m); and it differs from (3)'s linear gain by the extraction's nonlinearity, well
    above that (nm at these micrometre errors, the gain taken at the nominal bar)."""
    from core import mfb
    from core.kinematics import tip_W

    meas, chain, nodes, rp = meas3
    assert all(vol._has_features(m) for m in meas)  # every source of the scenario carries them
    d = vol.design(meas, chain, nodes, rp)
    n = len(d.names)
    prep = vol._prepare_all(meas, chain, rp, d.nodes)
    z = np.zeros(n)
    _, r3, _ = vol._rows(meas, chain, rp, d.nodes, z, d.slices, n, exact=True, jacobian=False, prep=prep)
    _, r3x, _ = vol._rows(meas, chain, rp, d.nodes, z, d.slices, n, exact=True, jacobian=False, prep=prep,
                          extraction=True)
    assert np.array_equal(r3, r3x)
    theta = np.zeros(n)
    rng = np.random.default_rng(5)
    for s in vol.MOTION:  # errors of a few um / 10 urad at every node
        theta[d.slices[s]] = rng.standard_normal(d.slices[s].stop - d.slices[s].start) * 5e-6
    _, r3, _ = vol._rows(meas, chain, rp, d.nodes, theta, d.slices, n, exact=True, jacobian=False, prep=prep)
    _, r3x, _ = vol._rows(meas, chain, rp, d.nodes, theta, d.slices, n, exact=True, jacobian=False, prep=prep,
                          extraction=True)
    worst, r0 = 0.0, 0
    for i, m in enumerate(meas):
        pm = prep[i]
        W = vol._axis_weights(d.nodes, pm["qt"] + np.asarray(pm["g"].J_m, float))
        vals = vol._values(theta, d.slices, W, len(pm["qt"]))
        J = np.broadcast_to(pm["g"].J_m, pm["qt"].shape)
        a = tip_W(pm["g"], pm["qt"], pm["rott"], vals, J_m=J)
        b = tip_W(pm["g"], pm["qt"], pm["rott"], None, J_m=J)
        want = pm["pred0"] + mfb.points_of_interest(a, m.feature, pm["n_W"]).O_R \
            - mfb.points_of_interest(b, m.feature, pm["n_W"]).O_R
        P, k = pm["P"], pm["k"]
        r = P - want  # placements 0
        r[pm["off"]] = r[pm["off"]] @ pm["Pz"].T
        worst = max(worst, np.abs(r.ravel() - r3x[r0:r0 + 3 * k]).max())
        r0 += 3 * k
    assert worst < 1e-12, worst
    diff = np.sqrt(np.mean((r3 - r3x) ** 2))
    assert diff > 1e-10, diff  # (3) and (3') are not the same model at these errors


def test_exact_extraction_bad_input(meas3):
    """What (3') needs is checked by name: feature and n_A together, one per touch, finite, the touches' features
    giving the measurement's own holes, and ``extraction`` a bool (or None, the module's default)."""
    from dataclasses import replace

    meas, chain, nodes, rp = meas3
    m0 = meas[0]
    t = len(m0.q_R)
    cases = [
        (replace(m0, n_A=None), "feature and n_A go together"),
        (replace(m0, feature=m0.feature[:-1]), "one per touch"),
        (replace(m0, n_A=np.vstack([m0.n_A[:-1], [np.nan, 0.0, 1.0]])), "one per touch"),
        (replace(m0, q_R=None, feature=m0.feature), "need the touches"),
    ]
    for bad, msg in cases:
        with pytest.raises(ConfigError, match=msg):
            vol.identify_volumetric([bad] + list(meas[1:]), chain, nodes, rp, extraction=True)
    # the first hole's touches renamed to a feature the extraction ignores: its points are another hole set
    h = f"hole{m0.holes[0]:02d}"
    other = tuple("other" if f == h else f for f in m0.feature)
    assert other != m0.feature and len(other) == t
    with pytest.raises(ConfigError, match=f"{m0.name}.*points of holes"):
        vol.identify_volumetric([replace(m0, feature=other)] + list(meas[1:]), chain, nodes, rp, extraction=True)
    with pytest.raises(ConfigError, match="extraction must be True, False or None"):
        vol.identify_volumetric(meas, chain, nodes, rp, extraction="yes")


def test_residual_noise_shared_gives_each_test_its_own_figures_and_is_refused_for_other_inputs(meas3, monkeypatch):
    # session 34 (bn34): the MFB run computes the residuals' noise model once (residual_noise) and passes it to
    # lack_of_fit, model_error_share and between_nodes_fit, which computed it each. The same figures, bit for
    # bit (the same numbers, only not computed twice): checked against each test's own computation, against a
    # 1 pm probe (the residuals far beyond it: every test says something: p ~ 0, shares enter, a note).
    # The tails are Satterthwaite's here (session 35): the subject is what is shared, not the tail, and Imhof's
    # quadrature this far out took 50 of the test's 55 s CPU (its known answers: the tail tests below).
    monkeypatch.setattr(vol, "_tail", lambda lam, x, p_sat, level, exact=False: (float(p_sat), True))
    meas, chain, nodes, rp = meas3
    res = vol.identify_volumetric(meas, chain, nodes, rp)
    u0, up = np.zeros((12, 3)), np.full(6, 1e-6)
    nm = vol.residual_noise(res, meas, 1e-12, u0, up)
    lof, lof_own = vol.lack_of_fit(res, meas, 1e-12, u0, up, noise=nm), vol.lack_of_fit(res, meas, 1e-12, u0, up)
    assert lof == lof_own and not lof.fits
    sh, sh_own = (vol.model_error_share(res, meas, 1e-12, u0, up, noise=nm),
                  vol.model_error_share(res, meas, 1e-12, u0, up))
    assert sh.entered and sh.entered == sh_own.entered and sh.z == sh_own.z and sh.p == sh_own.p
    assert np.array_equal(sh.columns, sh_own.columns)
    bn, bn_own = (vol.between_nodes_fit(res, meas, 1e-12, u0, up, noise=nm),
                  vol.between_nodes_fit(res, meas, 1e-12, u0, up))
    assert bn == bn_own and not bn.fits
    assert "kin" in nm.cache   # the fine kinematics computed once, for the share and the between-node test
    # the fine rows without the node values (what the between-node test uses): the same rows and centres
    for s in ("EXX", "EBZ"):
        a = vol._fine_rows(res, meas, nm.prep, s, 1e-3, nm.cache["kin"], centres=True)
        b = vol._fine_rows(res, meas, nm.prep, s, 1e-3, nm.cache["kin"], centres=True, values=False)
        assert b[1] is None and np.array_equal(a[0], b[0]) and np.array_equal(a[2], b[2])
    # a noise model of other inputs is refused by the test's name, whichever input differs
    for who, f in (("lack_of_fit", vol.lack_of_fit), ("model_error_share", vol.model_error_share),
                   ("between_nodes_fit", vol.between_nodes_fit)):
        for args, kw in (((meas, 2e-12, u0, up), {}), ((meas, 1e-12, u0 + 1e-7, up), {}),
                         ((meas, 1e-12, u0, None), {}), ((meas[:-1], 1e-12, u0, up), {}),
                         ((meas, 1e-12, u0, up), {"cal_map": np.eye(36)})):
            with pytest.raises(ConfigError, match=f"{who}: noise was computed for other inputs"):
                f(res, *args, noise=nm, **kw)
    with pytest.raises(ConfigError, match="residual_noise: sigma_probe_m"):
        vol.residual_noise(res, meas, -1e-7, u0)


def test_tail_choice_known_answers_and_the_exact_tail_where_a_decision_could_flip(monkeypatch):
    """Session 35 (mfb35): with EXACT_TAIL_NEAR_LEVEL the residual tests take Imhof's exact tail only where it
    could change a decision. Known answers of the rigorous lower bound: equal weights are a scaled chi-square,
    the bound is then the exact tail (chi2_3 at x = 7.8147: 0.05); one weight: chi2_1; uneven weights: below the
    exact tail, at or above each single term. The choice: far from the level Satterthwaite's p stands in,
    labelled; near it (Satterthwaite within EXACT_TAIL_FACTOR of the level, or the bound below the level) the
    exact tail, the same doubles as core.lsq.quadratic_form_sf; a case where Satterthwaite's p says "reject" and
    the exact tail "fits" (weights 1 and 30 x 0.1 at x = 15: 8.2e-6 against 5.9e-4, level 1e-4) takes the exact
    one; ``exact`` and the constant off take it everywhere."""
    from scipy.stats import chi2

    from core.lsq import quadratic_form_sf

    assert vol._tail_lower_bound(np.full(3, 2.0), 2 * 7.814727903251178) == pytest.approx(0.05, rel=1e-12, abs=0)
    assert vol._tail_lower_bound(np.array([2.0]), 3.0) == chi2.sf(1.5, 1)
    assert vol._tail_lower_bound(np.zeros(2), 1.0) == 0.0 and vol._tail_lower_bound(np.zeros(2), -1.0) == 1.0
    for lam, x in ((np.array([3.0, 1.0]), 5.0), (np.array([1.0] + [0.1] * 30), 10.0),
                   (np.geomspace(1e-3, 1.0, 60), 16.0), (np.array([1.0, 0.5] + [0.02] * 200), 15.0)):
        low, ex = vol._tail_lower_bound(lam, x), quadratic_form_sf(lam, x)
        assert chi2.sf(x / lam.max(), 1) <= low <= ex, (low, ex)

    def sat(lam, x):
        t1, t2 = lam.sum(), lam @ lam
        return float(chi2.sf(x / (t2 / t1), t1 * t1 / t2))

    monkeypatch.setattr(vol, "EXACT_TAIL_NEAR_LEVEL", True)
    far = np.array([1.0, 1.0] + [0.2] * 20)   # Satterthwaite 0.624, bound 0.297, exact 0.616 at x = 5
    assert vol._tail(far, 5.0, sat(far, 5.0), 1e-3) == (sat(far, 5.0), True)
    assert vol._tail(far, 5.0, sat(far, 5.0), 1e-3, exact=True) == (quadratic_form_sf(far, 5.0), False)
    # Satterthwaite within the factor of the level: the exact tail (0.00212 against 1e-3 x 10)
    assert vol._tail(far, 15.0, sat(far, 15.0), 1e-3) == (quadratic_form_sf(far, 15.0), False)
    # Satterthwaite far above the level but the bound below it (100 weights 0.01-1, Satterthwaite 0.05, bound
    # 7e-8): the exact tail, though here it agrees (0.0508)
    many = np.linspace(0.01, 1.0, 100)
    x = chi2.isf(0.05, many.sum() ** 2 / (many @ many)) * (many @ many) / many.sum()
    assert sat(many, x) >= vol.EXACT_TAIL_FACTOR * 1e-3 > 1e-3 > vol._tail_lower_bound(many, x)
    assert vol._tail(many, x, sat(many, x), 1e-3) == (quadratic_form_sf(many, x), False)
    # the decision that would flip on Satterthwaite's p: it rejects at 1e-4, the exact tail does not
    flip = np.array([1.0] + [0.1] * 30)
    p, approx = vol._tail(flip, 15.0, sat(flip, 15.0), 1e-4)
    assert sat(flip, 15.0) < 1e-5 and not approx and p == quadratic_form_sf(flip, 15.0) and 4e-4 < p < 8e-4
    monkeypatch.setattr(vol, "EXACT_TAIL_NEAR_LEVEL", False)
    assert vol._tail(far, 5.0, sat(far, 5.0), 1e-3) == (quadratic_form_sf(far, 5.0), False)


def test_exact_tail_never_below_its_rigorous_bound_when_one_weight_dominates(monkeypatch):
    """Session 35 (mfb35's finding): with one weight dominant Imhof's quadrature is inaccurate (the integrand decays
    as for one degree of freedom); at weights (1, 1e-3, 1e-3) and x = 30 it returns 0, where the tail is at least
    chi2_1's sf(30) = 4.32e-8 (the two small terms only add) and at most chi2_1's sf(29.7) = 6.5e-8 plus the
    chance that the small terms together exceed 0.3 (1e-3 chi2_2 > 0.3: exp(-150)). The residual tests' tail is
    then the bound, not 0: a test at any level would otherwise reject. Since session 36 (imhof36) the exact tail
    is the saddlepoint contour's, inside those bounds by itself; the bound still guards Imhof's quadrature (the
    contour off, or its fallback). Known answers from scipy's chi-square, not from the code under test."""
    from scipy.stats import chi2

    import core.lsq as lsq

    lam = np.array([1.0, 1e-3, 1e-3])
    assert lsq._qf_sf_imhof(lam, np.ones(3), 30.0) < chi2.sf(30.0, 1)   # the quadrature's failure this guards against
    assert chi2.sf(30.0, 1) <= lsq.quadratic_form_sf(lam, 30.0) <= chi2.sf(29.7, 1)   # the contour's tail
    for contour in (True, False):
        monkeypatch.setattr(lsq, "QF_SADDLE_CONTOUR", contour)
        for exact in (False, True):
            p, approx = vol._tail(lam, 30.0, 1e-9, 1e-5, exact=exact)
            assert not approx and chi2.sf(30.0, 1) <= p <= chi2.sf(29.7, 1), p


def test_between_node_test_takes_the_exact_tail_near_its_level_and_labels_the_approximate_one(meas3, monkeypatch):
    """Session 35 (mfb35), EXACT_TAIL_NEAR_LEVEL on against off on the same noise model. The noise-free 3-axis
    measurements' residuals (the model's own truncation) against a probing sigma chosen near the between-node
    test's level (measured: 4.0e-9 m gives p_family 4.1e-4, a rejection; 4.3e-9 m 2.0e-3, a pass): there the
    test takes the exact tail, the same doubles as with the constant off, and says so (p_approx False). Far
    from it (3e-8 m: exact p 0.79) the p is Satterthwaite's of the same interval, labelled, the decision the
    same (the exact tail is at or above the level, as the bound proves). The model-error share likewise: the
    tables far from MFB_MODEL_ERROR_P carry Satterthwaite's p, named in p_approx; ``all_exact`` takes every one."""
    meas, chain, nodes, rp = meas3
    res = vol.identify_volumetric(meas, chain, nodes, rp)
    u0 = np.zeros((12, 3))
    for sig, fits in ((4.0e-9, False), (4.3e-9, True), (3e-8, True)):
        nm = vol.residual_noise(res, meas, sig, u0)
        monkeypatch.setattr(vol, "EXACT_TAIL_NEAR_LEVEL", False)
        ex = vol.between_nodes_fit(res, meas, sig, u0, noise=nm)
        monkeypatch.setattr(vol, "EXACT_TAIL_NEAR_LEVEL", True)
        on = vol.between_nodes_fit(res, meas, sig, u0, noise=nm)
        assert ex.fits is on.fits is fits and not ex.p_approx, (sig, ex, on)
        assert (on.symbol, on.interval_m, on.intervals, on.ratio) == (ex.symbol, ex.interval_m, ex.intervals, ex.ratio)
        near = ex.p_family < vol.EXACT_TAIL_FACTOR * vol.BETWEEN_NODES_P
        assert on.p_approx is not near and on.as_dict()["p_approx"] is on.p_approx
        if near:   # the case near the level: the exact tail, bit for bit
            assert on == ex
        else:      # Satterthwaite's p of that interval; the exact one (with the constant off) past the level
            assert ex.p * ex.intervals >= vol.BETWEEN_NODES_P and on.p != ex.p
            assert on.p * on.intervals >= vol.EXACT_TAIL_FACTOR * vol.BETWEEN_NODES_P
    # the share (at 3e-8 m every table far from its level): Satterthwaite's p, labelled; all_exact: the exact tails
    monkeypatch.setattr(vol, "EXACT_TAIL_NEAR_LEVEL", True)   # off by default since session 37: the rule itself
    sh = vol.model_error_share(res, meas, 3e-8, u0, noise=nm)
    assert set(sh.p_approx) == set(vol.MOTION) and sh.as_dict()["p_approx"] == list(vol.MOTION)
    monkeypatch.setattr(vol, "EXACT_TAIL_NEAR_LEVEL", False)
    off = vol.model_error_share(res, meas, 3e-8, u0, noise=nm)
    monkeypatch.setattr(vol, "EXACT_TAIL_NEAR_LEVEL", True)
    every = vol.model_error_share(res, meas, 3e-8, u0, noise=nm, all_exact=True)
    assert off.p_approx == every.p_approx == () and every.p == off.p and every.z == sh.z == off.z
    assert all(off.p[s] >= vol.MFB_MODEL_ERROR_P for s in vol.MOTION) and sh.entered == off.entered
    assert all(sh.p[s] != off.p[s] for s in vol.MOTION)
