"""Known answers for the pieces of the self-calibration paper's studies (scenarios.crosspocket, core.uncertainty)."""

from types import SimpleNamespace

import numpy as np
import pytest

from core.exceptions import ConfigError
from core.selfcal import Grid, error_map, estimator, nominal_touches
from core.uncertainty import error_map_operator, workpiece_components
from scenarios import crosspocket as cp
from sim import artefacts as A


def test_align_on_pins_removes_a_rigid_motion_not_a_scale():
    p = A.pin_positions_nominal()
    t, phi = np.array([3e-6, -2e-6]), 4e-6  # shift and small rotation (rad) of the whole circle
    rigid = t + phi * np.column_stack([-p[:, 1], p[:, 0]])
    assert np.abs(cp.align_on_pins(rigid, p)).max() < 1e-18
    s = 5e-6  # a scale error of 5 ppm survives: pin 10 (opposite pin 1 within 20 deg) moves ~2 um
    e = cp.align_on_pins(s * p, p)
    assert np.all(e[0] == 0) and abs(e[10, 1]) < 1e-18
    # hand-worked: the scale's errors relative to pin 1, rotated about pin 1 so that pin 11's y error is 0
    r = p - p[0]
    hand = s * r + (-s * r[10, 1] / r[10, 0]) * np.column_stack([-r[:, 1], r[:, 0]])
    np.testing.assert_allclose(e, hand, atol=1e-18)
    assert np.hypot(*e.T).max() > 1.5e-6
    with pytest.raises(ConfigError, match="cannot set the X direction"):
        cp.align_on_pins(rigid, np.array([[0.0, 0.0]] * 11))


def test_pin_centres_round_trip():
    from sim.catalog import make_plan

    art = A.pin_circle()
    plan = make_plan(art)
    rng = np.random.default_rng(3)
    d = rng.normal(0, 2e-6, (18, 2))
    g = {}
    for k, wn in zip(plan.target, plan.wn_A):
        if k.startswith("pin"):
            g[k] = float(wn[:2] @ d[int(k[3:5]) - 1]) + 1.5e-6  # + a radius change no centre carries
    names, nominal, got = cp.pin_centres(g, plan)
    assert names[0] == "pin01" and len(names) == 18
    np.testing.assert_allclose(got, d, atol=1e-15)
    np.testing.assert_array_equal(nominal, A.pin_positions_nominal())


def test_pin_circle_plan_has_the_papers_eight_equator_touches_a_sphere():
    art = A.pin_circle()
    plan = cp.pin_circle_paper_plan(art)
    assert plan.n == 18 * 4 + 2 * 8 == 88  # section 5.1's counts (its "Total 84" is not what they give)
    spheres = {f.name: f.nominal for f in art.features if f.kind == "sphere"}
    for name, s in spheres.items():
        rows = [i for i, f in enumerate(plan.feature) if f == name]
        assert len(rows) == 8
        w, n = plan.w_A[rows], plan.wn_A[rows]
        c = np.asarray(s.centre)
        np.testing.assert_allclose(np.linalg.norm(w - c, axis=1), s.radius, rtol=0, atol=1e-15)  # on the sphere
        np.testing.assert_allclose(w[:, 2], c[2], atol=1e-15)  # on its equator
        np.testing.assert_allclose(n[:, 2], 0.0, atol=1e-15)  # eq 3's normal in XY
        np.testing.assert_allclose(np.degrees(np.arctan2(n[:, 1], n[:, 0])) % 360, np.arange(0, 360, 45),
                                   atol=1e-12)
    pins = [i for i, f in enumerate(plan.feature) if f.startswith("pin")]
    from sim.plans import pin_circle_plan

    ref = pin_circle_plan(art)
    keep = [i for i, f in enumerate(ref.feature) if f.startswith("pin")]
    np.testing.assert_array_equal(plan.w_A[pins], ref.w_A[keep])  # the pins' touches are the standard plan's
    # and so are the spheres' (`vmt simulate pin-circle` then `vmt identify` keeps all 88: none leaves XY);
    # built apart (deg2rad(45 k) there, 2 pi k / 8 here), bit for bit the same
    assert (ref.target, ref.feature) == (plan.target, plan.feature)
    for a, b in ((ref.level, plan.level), (ref.w_A, plan.w_A), (ref.wn_A, plan.wn_A)):
        np.testing.assert_array_equal(a, b)
    assert cp.pin_circle_paper_plan(art, 4).n == 80
    for bad in (2, 4.5, -1):
        with pytest.raises(ConfigError, match="sphere_touches must be an integer >= 3"):
            cp.pin_circle_paper_plan(art, bad)


def test_pin_circle_paper_plan_runs_without_collision():
    """Every approach, touch, retract and link of the paper's plan at the eq 20 angles, checked in the MuJoCo
    scene (the scenario itself runs without the check)."""
    from sim.campaign import simulate_campaign
    from sim.machine import Machine
    from sim.machines import MACHINES
    from sim.probe import ProbeConfig

    art = A.pin_circle()
    log = simulate_campaign(art, Machine(MACHINES["mikron-ucp710"]()), ProbeConfig(), list(cp.PIN_ANGLES_DEG),
                            None, plan=cp.pin_circle_paper_plan(art), check_collisions=True)
    assert len(log.col("status")) == 8 * 88 and set(log.col("status")) == {"ok"}


def test_measure_delta_L_known_answer():
    from sim.machine import Machine
    from sim.machines import MACHINES

    m = Machine(MACHINES["mikron-ucp710"]())  # no errors: the true delta_L is 0
    rng = np.random.default_rng(7)
    z = np.random.default_rng(7).standard_normal()
    meas, true, u = cp.measure_delta_L(m, 0.240, 0.01, 0.9e-6, rng)
    assert abs(true) < 1e-12
    # by hand: 5 touches per end, sigma 0.9 um; artefact U95 = 0.6 + 240/600 = 1.0 um -> u = 0.5 um
    assert u == pytest.approx(np.sqrt(2 * 0.81 / 5 + 0.25) * 1e-6, rel=1e-12, abs=0)
    assert meas == pytest.approx(true + u * z, abs=1e-15)


@pytest.fixture(scope="module")
def design():
    w, wn, ids = cp._plan_points(True)
    t = nominal_touches(w, wn, (0, 75, 130, 210), target_ids=ids)
    return estimator(t, Grid.regular(-0.110, 0.110, 0.022))


def test_error_map_operator_matches_error_map(design):
    des, _ = design
    theta = np.random.default_rng(2).normal(0, 1e-6, des.n_params)
    res = SimpleNamespace(design=des, yaw=des.yaw, EC0Y=float(theta[des.slices["EC0Y"]][0]),
                          **{k: theta[des.slices[k]] for k in ("EXX", "EYX", "EXY", "EYY", "ECY")})
    _, _, ex, ey = error_map(res)
    v = error_map_operator(des) @ theta
    n = ex.size
    np.testing.assert_allclose(v[:n], ex.ravel(), atol=1e-18)
    np.testing.assert_allclose(v[n:], ey.ravel(), atol=1e-18)


def test_workpiece_components_known_answer(design):
    des, _ = design
    rng = np.random.default_rng(5)
    a = rng.normal(0, 1e-6, (50, 1))
    err = a * des.N[:, 10]  # a pure scale (a null direction): no form, all scale
    parts = workpiece_components(des, err)
    np.testing.assert_allclose(parts["scale"], parts["total"], rtol=1e-9, atol=1e-20)
    assert parts["form"].max() < 1e-9 * parts["total"].max()
    assert parts["shift"].max() < 1e-9 * parts["total"].max()


def test_fig20_json_is_in_the_figures_layout_on_a_non_square_grid():
    """The JSON map is (N_y, N_x) as drawn (row = y, column = x); a square grid would hide a transposition."""
    g = Grid(np.array([-0.04, 0.0, 0.04]), np.array([-0.02, 0.0, 0.02, 0.04, 0.06]))  # 3 x-nodes, 5 y-nodes
    X, Y = np.meshgrid(g.x_m, g.y_m, indexing="ij")
    umap = (1.0 + 100.0 * X + 10.0 * Y) * 1e-6  # (N_x, N_y) as error_map_u95 gives it; largest at (40, 60) mm
    js, at = cp.map_u95_json(g, umap)
    assert np.shape(js) == (5, 3) and at == [40.0, 60.0]
    assert js[4][0] == pytest.approx(1.0 - 4.0 + 0.6)  # row y = 60 mm, column x = -40 mm, by hand
    assert js[0][2] == pytest.approx(1.0 + 4.0 - 0.2)  # row y = -20 mm, column x = 40 mm
    figs = cp.fig20_figures({"grid_x_mm": [-40, 0, 40], "grid_y_mm": [-20, 0, 20, 40, 60],
                             "map_u95_um_with_spheres_C0_75_130_210": js})
    quad = figs["fig20a"].axes[0].collections[0]
    np.testing.assert_allclose(np.asarray(quad.get_array()).reshape(5, 3), js)  # drawn as written
    with pytest.raises(ConfigError, match="shape"):
        cp.map_u95_json(g, umap.T)
