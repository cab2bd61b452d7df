"""2D self-calibration (core.selfcal): null space, round trips, exact truth, bad input."""

import numpy as np
import pytest

from core import lsq
from core.design import example_cross_pocket
from core.exceptions import ConfigError, IdentifiabilityError
from core.lsq import solve
from core.selfcal import Grid, build_design, nominal_touches, rot2, self_calibrate
from core.units import UM

GRID = Grid.regular(-0.110, 0.110, 0.022)
ANGLES = [0, 75, 130, 210]


def freeform(n=60, rng=None):
    """Targets on a wavy closed curve (a free-form part), outward normals, W, m."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 0.082 + 0.012 * np.sin(3 * t) + 0.005 * np.cos(5 * t)
    dr = 0.036 * np.cos(3 * t) - 0.025 * np.sin(5 * t)
    p = np.column_stack([r * np.cos(t), r * np.sin(t)])
    tang = np.column_stack([dr * np.cos(t) - r * np.sin(t), dr * np.sin(t) + r * np.cos(t)])
    nrm = np.column_stack([tang[:, 1], -tang[:, 0]])
    return p, nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


def random_truth(des, rng, scale_um=5.0):
    """A truth in the model space: node values, C-axis errors, G (m / rad)."""
    th = rng.normal(0, scale_um * UM, des.n_params)
    for k in ("ECY", "EC0Y", "ECC"):
        th[des.slices[k]] = rng.normal(0, 20 * UM, des.slices[k].stop - des.slices[k].start)  # 20 urad
    return th


def with_dq(t, dq):
    return nominal_touches_like(t, dq)


def nominal_touches_like(t, dq):
    from dataclasses import replace
    return replace(t, p_R=t.pn_R + dq[:, None] * t.n_R)


def test_null_space_is_eleven_dimensional_and_fixed_by_the_gauge():
    w, wn, ids = example_cross_pocket()
    t = nominal_touches(w, wn, ANGLES, stylus_r_m=0.003, target_ids=ids)
    des = build_design(t, GRID)
    A = des.A.toarray()
    # the analytic directions are exact null vectors (rounding only)
    assert np.abs(A @ des.N).max() < 1e-14
    # ... and they are all of the null space: rank = n - 11 (column-scaled SVD)
    sv = np.linalg.svd(A / np.linalg.norm(A, axis=0), compute_uv=False)
    assert (sv > 1e-8 * sv[0]).sum() == des.n_params - 11
    assert np.linalg.matrix_rank(des.N) == 11
    # the eleven gauge conditions fix exactly these directions
    assert np.linalg.matrix_rank(des.C @ des.N) == 11
    assert len(des.gauge) == 11 and "scale unknown" in des.gauge[10]


def _off_axis(t, c_xy):
    """``t`` with the C axis at ``c_xy`` (m) in R: each set-up's tip centres p -> c + R(-C) (w - c), i.e.
    p + (I - R(-C_j)) c (eq 1 about the axis); normals unchanged."""
    from dataclasses import replace
    c = np.asarray(c_xy, float)
    sh = c - np.einsum("jab,b->ja", rot2(-t.rot_rad[:, 2]), c)  # (I - R(-C_j)) c per touch
    pn = t.pn_R.copy()
    pn[:, :2] += sh
    return replace(t, pn_R=pn, p_R=pn + (t.p_R - t.pn_R))


@pytest.mark.parametrize("c_mm", [(22.0, 0.0), (-35.0, 15.0)])
def test_null_space_and_gauge_with_the_c_axis_off_the_origin(c_mm):
    """Known answer and round trip with C at (cx, cy): the rotation and scale directions about the axis.

    The axis is read back from the nominal positions (1e-12 m: rounding of 0.1 m positions); |A N| at
    rounding (1e-14: O(1) entries, a dozen terms a row; the paper's columns about R's origin leave 0.041
    at (22, 0) mm); the null space is all of A's (eleven); a truth in the model space, identified
    noise-free, is ``to_gauge(truth)`` to 1e-6 um (the solve's rounding on um-size values)."""
    from core.selfcal import c_axis_xy
    w, wn, ids = example_cross_pocket()
    t = _off_axis(nominal_touches(w, wn, ANGLES, stylus_r_m=0.003, target_ids=ids), np.array(c_mm) * 1e-3)
    p = t.pn_R  # 11 x 11 nodes over the touches' extent: every node seen by touches both ways
    grid = Grid(np.linspace(p[:, 0].min(), p[:, 0].max(), 11), np.linspace(p[:, 1].min(), p[:, 1].max(), 11))
    des = build_design(t, grid)
    np.testing.assert_allclose(c_axis_xy(t, des.c_rad), np.array(c_mm) * 1e-3, rtol=0, atol=1e-12)
    A = des.A.toarray()
    assert np.abs(A @ des.N).max() < 1e-14
    sc = np.linalg.norm(A, axis=0)
    sc[sc == 0] = 1.0
    sv = np.linalg.svd(A / sc, compute_uv=False)
    assert (sv > 1e-8 * sv[0]).sum() == des.n_params - 11
    assert np.linalg.matrix_rank(des.C @ des.N) == 11
    truth = random_truth(des, np.random.default_rng(3))
    tg = des.to_gauge(truth)
    np.testing.assert_allclose(A @ tg, A @ truth, rtol=0, atol=1e-15)   # the gauge moves nothing the touches see
    np.testing.assert_allclose(des.C @ tg, des.d, rtol=0, atol=1e-18)
    res = self_calibrate(with_dq(t, A @ truth), grid, model_error=False)
    np.testing.assert_allclose(res.theta, tg, rtol=0, atol=1e-6 * UM)


def test_c_axis_at_the_origin_or_unplaced_reads_as_zero():
    """Bit-identity's condition: C at the origin gives exactly (0, 0) (so the paper's columns, bit for bit);
    one angle places no axis."""
    from core.selfcal import c_axis_xy
    w, wn, ids = example_cross_pocket()
    t = nominal_touches(w, wn, ANGLES, stylus_r_m=0.003, target_ids=ids)
    assert c_axis_xy(t, np.radians(ANGLES)) == (0.0, 0.0)
    t1 = _off_axis(nominal_touches(w, wn, [75], target_ids=ids), (0.022, 0.0))
    assert c_axis_xy(t1, np.radians([75.0])) == (0.0, 0.0)


def test_names_and_order():
    w, wn = freeform(40)
    t = nominal_touches(w, wn, ANGLES)
    des = build_design(t, GRID)
    assert des.names[0] == "EXX@x=-110mm" and des.names[11] == "EYX@x=-110mm"
    assert des.names[des.slices["EC0Y"]][0] == "EC0Y"
    assert des.names[des.slices["G"]][0] == "G[p1]"
    assert des.names[des.slices["ECC"]][1] == "ECC[C=75deg]"
    assert des.names[des.slices["EXC"]][3] == "EXC,total[C=210deg]"


def test_design_matches_eq14_for_one_touch():
    """Known answer: eq 14 written out by hand for one touch at a grid-cell interior.

    The C-axis terms in the ISO 230-1 sign (tool relative to the part): the
    paper's eq 13 coefficients negated, like eq 12's for the linear axes."""
    w = np.array([[0.030, 0.050]])
    wn = np.array([[0.6, 0.8]])
    t = nominal_touches(np.repeat(w, 1, 0), wn, [0])
    g = Grid(np.array([0.0, 0.04]), np.array([0.0, 0.1]))
    des = build_design(t, g)
    row = des.A.toarray()[0]
    zx, zy = 0.030 / 0.04, 0.5
    nx, ny, x, y = 0.6, 0.8, 0.030, 0.050
    exp = {"EXX@x=0mm": -nx * (1 - zx), "EXX@x=40mm": -nx * zx, "EYX@x=40mm": -ny * zx,
           "EXY@y=100mm": -nx * zy, "EYY@y=0mm": -ny * (1 - zy), "ECY@y=100mm": -ny * x * zy,
           "EC0Y": nx * y, "G[p1]": 1.0, "EXC,total[C=0deg]": -nx, "EYC,total[C=0deg]": -ny,
           "ECC[C=0deg]": -(-nx * y + ny * x)}
    for k, v in exp.items():
        assert row[des.names.index(k)] == pytest.approx(v, abs=1e-15), k


@pytest.mark.parametrize("delta_L_um", [None, 3.0])
def test_round_trip_in_model_space(rng, delta_L_um):
    """Truth in the model space -> noise 0.5 um -> identify -> gauge-equivalent truth within 4.5 sigma."""
    w, wn = freeform(60)
    t = nominal_touches(w, wn, ANGLES, stylus_r_m=0.002)
    des = build_design(t, GRID)
    dL = None if delta_L_um is None else delta_L_um * UM
    truth = des.to_gauge(random_truth(des, rng), 0.0 if dL is None else dL)
    noise = 0.5 * UM
    dq = des.A @ truth + rng.normal(0, noise, t.n)
    res = self_calibrate(nominal_touches_like(t, dq), GRID, dL, sigma_m=noise)
    assert res.scale_known is (dL is not None)
    assert any("scale unknown" in c for c in res.conventions) is (dL is None)
    z = (res.theta - truth) / np.where(res.std > 0, res.std, 1)
    # 4.5 sigma over ~250 parameters: a false alarm has probability ~1e-3
    assert np.abs(z).max() < 4.5
    # rms^2 = RSS / n, RSS ~ sigma^2 chi^2(dof): the rms's relative SD is 1 / sqrt(2 dof) = 6.4 % at dof 123
    # (240 touches): rel 0.25 is 3.9 SD (a false failure ~1e-4; measured 0.3-6.1 % over seeds 0-4)
    assert res.dof == 123
    assert res.rms_m == pytest.approx(noise * np.sqrt(res.dof / t.n), rel=0.25)
    # gauge-fixed values are exact and have zero uncertainty
    assert res.value("ECC[C=0deg]") == 0 and res.std[des.names.index("EXC,total[C=0deg]")] < 1e-20
    assert res.EXX[-1] == pytest.approx(0.0 if dL is None else dL, abs=1e-15)


def test_noise_free_exact_and_residuals_zero():
    w, wn, ids = example_cross_pocket()
    t = nominal_touches(w, wn, ANGLES, target_ids=ids)
    des = build_design(t, GRID)
    truth = des.to_gauge(random_truth(des, np.random.default_rng(3)))
    res = self_calibrate(nominal_touches_like(t, des.A @ truth), GRID)
    # rounding only: the estimator's gain is < 1e4 (cond of the scaled design)
    assert np.abs(res.theta - truth).max() < 1e-12
    assert res.rms_m < 1e-15


def exact_campaign(w, wn, c_deg, truth, r_m):
    """Reported positions of an exact rigid-body machine (outside the model space).

    Actual table pose: R(-ECC) R(-C) - (EXC, EYC) (exact rotation): the
    truth's EXC,total, EYC,total, ECC are ISO 230-1 values (the tool relative
    to the part), so the table moves by their inverse; actual tip = believed
    tip + E(believed tip) with smooth E; workpiece contact point moved by G
    along its normal. The trigger is solved exactly along the nominal normal.
    """
    t = nominal_touches(w, wn, c_deg, stylus_r_m=r_m)
    nw = len(w)
    dq = np.empty(t.n)
    for j, c in enumerate(c_deg):
        Rj = rot2(-truth["ECC"][j]) @ rot2(-np.radians(c))
        for i in range(nw):
            k = j * nw + i
            a = Rj @ (w[i] + truth["G"][i] * wn[i]) - np.array([truth["EXC"][j], truth["EYC"][j]])
            m = Rj @ wn[i]
            n = t.n_R[k, :2]
            pn = t.pn_R[k, :2]
            s = 0.0
            for _ in range(8):
                p = pn + s * n
                f = m @ (p + truth["E"](p) - a) - r_m
                s -= f / (m @ n)
            dq[k] = s
    return t, dq


def smooth_truth(nw, nc, rng):
    def E(p):
        x, y = p
        exx = 4e-5 * x + 2e-4 * x ** 2
        eyx = 3e-6 * np.sin(x / 0.07)
        exy = 2e-6 * np.cos(y / 0.09) + 1e-5 * y
        eyy = -3e-5 * y + 1.5e-4 * y ** 2
        ecy = 15e-6 * np.sin(y / 0.1)
        return np.array([exx + exy - y * 40e-6, eyx + eyy + x * ecy])

    tr = {"E": E, "G": rng.normal(0, 3 * UM, nw), "EXC": rng.normal(10 * UM, 3 * UM, nc),
          "EYC": rng.normal(5 * UM, 3 * UM, nc), "ECC": rng.normal(0, 30e-6, nc)}
    return tr


def sample_truth(des, tr, gx, gy):
    th = np.zeros(des.n_params)
    s = des.slices
    th[s["EXX"]] = 4e-5 * gx + 2e-4 * gx ** 2
    th[s["EYX"]] = 3e-6 * np.sin(gx / 0.07)
    th[s["EXY"]] = 2e-6 * np.cos(gy / 0.09) + 1e-5 * gy
    th[s["EYY"]] = -3e-5 * gy + 1.5e-4 * gy ** 2
    th[s["ECY"]] = 15e-6 * np.sin(gy / 0.1)
    th[s["EC0Y"]] = 40e-6
    th[s["G"]] = tr["G"]
    th[s["EXC"]], th[s["EYC"]], th[s["ECC"]] = tr["EXC"], tr["EYC"], tr["ECC"]
    return th


def test_exact_truth_outside_model_space_recovered_to_first_order(rng):
    """Smooth error functions, exact table rotation, stylus radius 3 mm, no noise.

    The model is first order with piecewise-linear tables, so the estimate
    differs from the gauge-equivalent truth by (a) the bilinear
    interpolation error, O(h^2) (max |f''| h^2 / 8 ~ 0.03 um per function at
    h = 22 mm) and (b) second-order kinematic terms (ECC x E ~ 30 urad x
    10 um = 3e-4 um), both amplified by the estimator. Checks: the error is
    < 0.2 um (2 % of the raw machine error of ~10 um at h = 22 mm) and
    falls like h^2 when the grid is halved (ratio < 0.35; 0.25 ideal).
    """
    w, wn = freeform(72)
    tr = smooth_truth(len(w), len(ANGLES), rng)
    t, dq = exact_campaign(w, wn, ANGLES, tr, 0.003)
    raw = dq[: len(w)] - tr["G"]  # what probing at C = 0 alone would get wrong
    assert np.abs(raw).max() > 5 * UM
    err = {}
    for step in (0.022, 0.011):
        g = Grid.from_extent(t.pn_R, step)
        res = self_calibrate(nominal_touches_like(t, dq), g)
        truth = res.design.to_gauge(sample_truth(res.design, tr, g.x_m, g.y_m))
        s = res.design.slices
        err[step] = {k: np.abs(res.theta[s[k]] - truth[s[k]]).max() for k in ("G", "EXC", "EYC", "ECC")}
    assert err[0.022]["G"] < 0.2 * UM
    assert max(err[0.022]["EXC"], err[0.022]["EYC"]) < 0.2 * UM
    assert err[0.022]["ECC"] < 0.5e-6  # 0.5 urad against 30 urad of truth
    for k in ("G", "EXC", "EYC", "ECC"):
        assert err[0.011][k] < 0.35 * err[0.022][k], k


def test_sparse_path_matches_dense(monkeypatch, rng):
    """Above DENSE_MAX the solver eliminates the workpiece block (Schur complement); same answer and std."""
    w, wn = freeform(50)
    t = nominal_touches(w, wn, ANGLES)
    des = build_design(t, GRID)
    truth = des.to_gauge(random_truth(des, rng))
    tt = nominal_touches_like(t, des.A @ truth + rng.normal(0, 1 * UM, t.n))
    dense = self_calibrate(tt, GRID)
    monkeypatch.setattr(lsq, "DENSE_MAX", 10)
    sparse = self_calibrate(tt, GRID)
    assert sparse.cov is None
    np.testing.assert_allclose(sparse.theta, dense.theta, atol=1e-13)
    np.testing.assert_allclose(sparse.std, dense.std, rtol=1e-8, atol=1e-15)


def test_symmetric_part_at_symmetric_angles_is_reported_by_name():
    """A cross at 0/90/180/270 looks the same in R every time: rank deficient, named."""
    w, wn, ids = example_cross_pocket(spheres=False)
    t = nominal_touches(w, wn, [0, 90, 180, 270], target_ids=ids)
    with pytest.raises(IdentifiabilityError,
                       match=r"rank deficient by 5 beyond the constraints; unidentifiable: .*\*ECY@y=-55mm"):
        self_calibrate(t, Grid.regular(-0.110, 0.110, 0.055))


def test_too_few_angles_eq6_message():
    w, wn = freeform(30)
    t = nominal_touches(w, wn, [0, 75])
    with pytest.raises(IdentifiabilityError, match=r"2 C angles give 60 equations for 92 unknowns.*eq 6.*at least 4 C angles"):
        self_calibrate(t, GRID)
    with pytest.raises(IdentifiabilityError, match="1 C angle"):
        self_calibrate(nominal_touches(w, wn, [0]), GRID)


def test_unconstrained_nodes_named():
    w, wn = freeform(60)
    t = nominal_touches(w, wn, ANGLES)
    wide = Grid.regular(-0.110, 0.154, 0.022)
    with pytest.raises(IdentifiabilityError, match=r"no touch constrains EXX@x=132mm, EXX@x=154mm, EYX@x=132mm"):
        self_calibrate(t, wide)


def test_bad_input():
    w, wn = freeform(30)
    t = nominal_touches(w, wn, ANGLES)
    with pytest.raises(ConfigError, match=r"nominal X = .* mm lies outside the grid -50..50 mm"):
        self_calibrate(t, Grid.regular(-0.05, 0.05, 0.01))
    with pytest.raises(ConfigError, match="strictly increasing"):
        Grid(np.array([0.0, 0.0]), np.array([0.0, 1.0]))
    with pytest.raises(ConfigError, match="whole number"):
        Grid.regular(-0.1, 0.1, 0.03)
    with pytest.raises(ConfigError, match="sigma must be > 0"):
        self_calibrate(t, GRID, sigma_m=-1.0)
    with pytest.raises(ConfigError, match="C angles repeat"):
        nominal_touches(w, wn, [0, 0, 75])
    with pytest.raises(IdentifiabilityError, match="3 observations for 4 free parameters"):
        solve(np.eye(4)[:3], np.zeros(3))


def test_auto_grid_from_extent():
    w, wn = freeform(40)
    t = nominal_touches(w, wn, ANGLES)
    g = Grid.from_extent(t.pn_R, 0.02)
    assert g.x_m[0] <= t.pn_R[:, 0].min() and g.x_m[-1] >= t.pn_R[:, 0].max()
    assert np.any(np.isclose(g.x_m, 0.0, atol=1e-12))
    res = self_calibrate(t, grid_step_m=0.02)
    assert np.array_equal(res.design.grid.x_m, g.x_m)


def test_error_map_of_a_linear_machine_known_answer():
    """Scales s_x, s_y and squareness a (tip error -y a in X, CONTRIBUTING) give, by hand,
    E_X = s_x x - a y and E_Y = s_y y (eqs 4-5); the truth is already in the gauge
    (zero at the origin, EXX(x_N) = delta_L, no straightness), so the noise-free
    identification's map is that to rounding."""
    from core.selfcal import error_map

    sx, sy, a = 8 * UM / 0.1, -5 * UM / 0.1, 12 * UM  # 8 and -5 um per 100 mm, 12 urad
    w, wn = freeform(60)
    t = nominal_touches(w, wn, ANGLES)
    des = build_design(t, GRID)
    th = np.zeros(des.n_params)
    th[des.slices["EXX"]] = sx * GRID.x_m
    th[des.slices["EYY"]] = sy * GRID.y_m
    th[des.slices["EC0Y"]] = a
    res = self_calibrate(nominal_touches_like(t, des.A @ th), GRID, sx * GRID.x_m[-1], sigma_m=UM)
    x, y, ex, ey = error_map(res)
    X, Y = np.meshgrid(GRID.x_m, GRID.y_m, indexing="ij")
    np.testing.assert_allclose(ex, sx * X - a * Y, atol=1e-15)
    np.testing.assert_allclose(ey, sy * Y, atol=1e-15)


def test_map_in_gauge_adds_exactly_the_unseen_part():
    """A map differing from the truth by a shift, a rotation and a scale is the truth in
    its gauge; a further bump (orthogonal to those by construction) stays a difference."""
    from core.selfcal import map_gauge_basis, map_in_gauge

    X, Y = np.meshgrid(np.linspace(-0.1, 0.1, 6), np.linspace(-0.08, 0.08, 5), indexing="ij")
    ex_t, ey_t = 2 * UM * np.sin(20 * X) * Y / 0.1, 1 * UM * np.cos(15 * Y)
    t1, t2, rot, scale = 3 * UM, -2 * UM, 15 * UM, 40 * UM
    ex_id = ex_t + t1 - rot * Y + scale * X
    ey_id = ey_t + t2 + rot * X + scale * Y
    gx, gy = map_in_gauge(X, Y, ex_t, ey_t, ex_id, ey_id)
    np.testing.assert_allclose(gx, ex_id, atol=1e-18)
    np.testing.assert_allclose(gy, ey_id, atol=1e-18)
    bump = np.concatenate([np.ravel(X ** 2 * Y), np.ravel(Y ** 3)]) * 1e-3
    B = map_gauge_basis(X, Y)
    bump -= B @ np.linalg.lstsq(B, bump, rcond=None)[0]
    n = X.size
    gx, gy = map_in_gauge(X, Y, ex_t, ey_t, ex_id + bump[:n].reshape(X.shape), ey_id + bump[n:].reshape(X.shape))
    np.testing.assert_allclose(gx, ex_id, atol=1e-18)
    np.testing.assert_allclose(gy, ey_id, atol=1e-18)


def test_workpiece_form_removes_shift_rotation_scale_and_offset():
    """G of the same part shifted, rotated, scaled and with another stylus radius has the
    same form; a lobed form error survives it."""
    from core.selfcal import workpiece_form

    w, wn = freeform(40)
    t, rot, scale, r = np.array([4.0, -3.0]) * UM, 20 * UM, 30 * UM, 1.5 * UM
    g_rigid = wn @ t + rot * (-wn[:, 0] * w[:, 1] + wn[:, 1] * w[:, 0]) + scale * np.einsum("ij,ij->i", wn, w) + r
    np.testing.assert_allclose(workpiece_form(g_rigid, w, wn), 0.0, atol=1e-18)
    ang = np.arctan2(w[:, 1], w[:, 0])
    lobes = 2 * UM * np.cos(7 * ang)
    np.testing.assert_allclose(workpiece_form(lobes + g_rigid, w, wn), workpiece_form(lobes, w, wn), atol=1e-18)
    assert np.sqrt(np.mean(workpiece_form(lobes, w, wn) ** 2)) > 1.2 * UM  # most of 2/sqrt(2) um survives


def test_block_elimination_matches_the_sparse_lu_at_scale(rng):
    """10,000 touches, 1,000 free-form targets, grid 30 x 30: the workpiece eliminated first
    (what self_calibrate does above DENSE_MAX) gives the sparse LU's estimate and standard
    uncertainties to rounding (relative 1e-9: both are direct factorisations of the same
    well-conditioned normal matrix, column-scaled, cond ~1e5)."""
    r = rng.uniform(0.02, 0.095, 1000)
    a = rng.uniform(0, 2 * np.pi, 1000)
    b = rng.uniform(0, 2 * np.pi, 1000)
    t = nominal_touches(np.column_stack([r * np.cos(a), r * np.sin(a)]), np.column_stack([np.cos(b), np.sin(b)]),
                        np.arange(10) * 36.0 + 7.0)
    lo, hi = t.pn_R[:, :2].min(axis=0), t.pn_R[:, :2].max(axis=0)
    g = Grid(np.linspace(lo[0], hi[0], 31), np.linspace(lo[1], hi[1], 31))
    des = build_design(t, g)
    dq = des.A @ des.to_gauge(rng.normal(0, 3 * UM, des.n_params)) + rng.normal(0, UM, t.n)
    res = self_calibrate(nominal_touches_like(t, dq), g, covariance="std")
    lu = solve(des.A, dq, des.C, des.d, covariance="std")
    assert lu.estimator._quad is None and res.theta.size > lsq.DENSE_MAX
    np.testing.assert_allclose(res.theta, lu.theta, rtol=1e-9, atol=1e-9 * np.abs(lu.theta).max())
    np.testing.assert_allclose(res.std, lu.std, rtol=1e-9, atol=1e-20)
    np.testing.assert_allclose(res.residuals_m, lu.residuals, atol=1e-9 * UM)


def test_design_rows_are_sorted():
    """The design is built row-wise in column order, without a sort: every row's column
    indices increase strictly (what ``has_sorted_indices`` promises scipy), both yaws."""
    w, wn = freeform(30)
    for yaw in ("ECY", "ECX"):
        A = build_design(nominal_touches(w, wn, ANGLES), GRID, yaw=yaw).A
        assert A.has_sorted_indices
        assert all(np.all(np.diff(A.indices[A.indptr[i]:A.indptr[i + 1]]) > 0) for i in range(A.shape[0]))


@pytest.mark.parametrize("c_deg", [(0, 90, 180, 270), (0, 45, 90, 135)])
def test_normals_through_the_c_axis_refused_naming_the_c_angle(c_deg):
    """review33b F4 (its selfcal_degen.py "4-fold part" cases): 16 targets on a 60 mm circle about the C axis,
    probed radially: every normal passes through the axis, so no touch sees a turn about it and the ECC
    columns are zero. The refusal said "no touch constrains ECC[C=0deg], ...: fit the grid to the touches",
    a grid's advice for a value that is no grid node; it now says the C angle is not seen and why. The same
    circle with one flat-faced target whose normal misses the axis is not refused for it."""
    from core.exceptions import IdentifiabilityError
    from core.selfcal import Grid, nominal_touches, self_calibrate

    ang = np.radians(np.arange(0, 360, 22.5))
    w, wn = np.c_[0.06 * np.cos(ang), 0.06 * np.sin(ang)], np.c_[np.cos(ang), np.sin(ang)]
    grid = Grid(np.array([-0.1, 0.0, 0.1]), np.array([-0.1, 0.0, 0.1]))
    t = nominal_touches(w, wn, c_deg, stylus_r_m=0.003)
    with pytest.raises(IdentifiabilityError) as e:
        self_calibrate(t, grid, 0.0, yaw="ECY", heights=False, model_error=False)
    msg = str(e.value)
    assert msg.startswith("the C angle is not seen (ECC at C = " + ", ".join(f"{c}deg" for c in c_deg) + ")")
    assert "every probed normal passes through the C axis" in msg and "normals miss the axis" in msg
    assert "fit the grid" not in msg
    w2, wn2 = np.r_[w, [[0.07, 0.03]]], np.r_[wn, [[1.0, 0.0]]]    # a flat side at x = 70 mm, 30 mm off the axis
    try:
        self_calibrate(nominal_touches(w2, wn2, c_deg, stylus_r_m=0.003), grid, 0.0, yaw="ECY", heights=False,
                       model_error=False)
    except IdentifiabilityError as e2:      # (the symmetric angles may still be rank deficient: not this refusal)
        assert "C angle is not seen" not in str(e2)
