"""The path checks' broad phase (sim.clearance): its bounds never exceed MuJoCo's distances, it
skips no sample where MuJoCo finds a collision, and the checks with it report exactly what the
sample-by-sample MuJoCo checks report, on randomised paths (issue 19 item 4)."""

import numpy as np
import pytest

from core.exceptions import PlanError
from sim import artefacts as A
from sim.clearance import MARGIN_M, path_samples
from sim.mfb_scene import WorkZone, check_measurement
from sim.probe import ProbeConfig
from sim.scene import Scene, check_touch_paths

pytest.importorskip("mujoco")
R = 3e-3
BAR = A.multi_feature_bar(deviations_m=np.zeros((12, 3)))
FLAT = A.make_T(None, (-0.175, 0.080, 0.070))


def _T_R_W(A_deg, C_deg):
    from sim.machine import Machine
    from sim.machines import MACHINES

    m = Machine(MACHINES["mikron-ucp710"]())
    return np.asarray(m.T_R_W_nominal(np.deg2rad([[A_deg, C_deg]])), float).reshape(4, 4)


def _holes(*h):
    from scenarios.mfb import _plan_for

    return _plan_for(BAR, h)


def _old_samples(pts, step, joints):
    """The sampling of the sample-by-sample checks as they were written (linspace per segment)."""
    out = []
    for a, b in zip(pts[:-1], pts[1:]):
        k = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        f = np.linspace(0.0, 1.0, k + 1)
        out.extend(a + x * (b - a) for x in (f if joints else f[:-1]))
    if not joints:
        out.append(pts[-1])
    return np.array(out)


@pytest.mark.parametrize("joints", [True, False])
def test_path_samples_are_the_old_samples_bit_for_bit(joints):
    rng = np.random.default_rng(5)
    polys = [rng.uniform(-0.2, 0.2, (rng.integers(2, 6), 3)) for _ in range(30)]
    polys.append(np.array([[0.0, 0, 0], [0.0, 0, 0]]))  # a zero-length segment: one step
    steps = rng.uniform(0.2e-3, 5e-3, len(polys))
    got, seg, path = path_samples(polys, steps, joints)
    want = np.concatenate([_old_samples(p, s, joints) for p, s in zip(polys, steps)])
    assert np.array_equal(got, want)
    assert np.array_equal(path, np.repeat(np.arange(len(polys)), [len(_old_samples(p, s, joints))
                                                                 for p, s in zip(polys, steps)]))
    assert np.all(np.diff(seg) >= 0)


def _zone(A_deg, C_deg, J_m, finger=0.0):
    wz = WorkZone(BAR, FLAT, (), J_m, R, finger)
    wz.set_table(_T_R_W(A_deg, C_deg))
    return wz


@pytest.mark.parametrize("A_deg,C_deg,J_m,finger", [(0, 0, (0, 0, 0.150), 0.0),
                                                     (-60, 30, (0.0, -0.100, 0.150), 0.0),
                                                     (-90, 0, (0.030, 0.0, 0.150), 0.020)])
def test_bounds_never_exceed_mujoco_distances(A_deg, C_deg, J_m, finger):
    """Every lower bound the broad phase uses is at most MuJoCo's own signed distance of the pair
    (mj_geomDistance), for random tips near the bar, the table and the supports."""
    import mujoco

    wz = _zone(A_deg, C_deg, J_m, finger)
    clr = wz.clearance()
    rng = np.random.default_rng(abs(A_deg) + 7)
    T_R_A = _T_R_W(A_deg, C_deg) @ FLAT
    tips = A.apply_T(T_R_A, rng.uniform([-0.03, -0.03, -0.03], [0.40, 0.08, 0.06], (300, 3)))
    npair = len(clr.pair_probe)
    cand = np.zeros((len(tips), npair), bool)
    ci, cp = clr.candidates(tips)
    cand[ci, cp] = True
    assert cand.sum() > 100
    # every candidate triple, and as many random others
    k_c = np.flatnonzero(cand.ravel())
    k_o = rng.choice(cand.size, k_c.size, replace=False)
    k_all = np.r_[k_c, k_o]
    i, pair = np.divmod(k_all, npair)
    lb = clr.bound(tips, i, pair)
    worst, n_close = -np.inf, 0
    for k in range(len(k_all)):
        wz.set_tip(tips[i[k]])
        a, b = wz._probe[clr.pair_probe[pair[k]]], wz._table[clr.pair_table[pair[k]]]
        d = mujoco.mj_geomDistance(wz.model, wz.data, a, b, 1.0, None)
        worst = max(worst, lb[k] - d)
        n_close += d < 5e-3
        # a pair whose boxes are apart is farther than the margin
        assert cand[i[k], pair[k]] or d > MARGIN_M - 1e-6, (i[k], pair[k], d)
    # MuJoCo's distance of convex pairs is exact to its CCD tolerance (1e-6 m)
    assert worst <= 1e-6, worst
    assert n_close > 50  # the draw reaches the geoms, not only far space


def _random_paths(rng, T_R_A, n):
    """Polylines in R through and around the bar: random points in a box about it (A frame)."""
    out = []
    for _ in range(n):
        k = rng.integers(2, 5)
        out.append(A.apply_T(T_R_A, rng.uniform([-0.02, -0.02, -0.01], [0.38, 0.06, 0.05], (k, 3))))
    return out


@pytest.mark.parametrize("A_deg,C_deg,J_m", [(0, 0, (0, 0, 0.150)), (-60, 30, (0.0, -0.100, 0.150)),
                                             (-90, 45, (0.030, 0.0, 0.150))])
def test_broad_phase_skips_no_colliding_sample(A_deg, C_deg, J_m):
    """Differential, sample by sample: on random paths MuJoCo runs at every sample; every sample
    where it finds a collision is one the broad phase kept (and most clear ones are skipped)."""
    wz = _zone(A_deg, C_deg, J_m)
    rng = np.random.default_rng(11 + abs(A_deg))
    T_R_A = _T_R_W(A_deg, C_deg) @ FLAT
    pts, seg, path = path_samples(_random_paths(rng, T_R_A, 40), np.full(40, 3e-3), joints=False)
    feats = np.array([f.name for f in BAR.features] + [""], dtype=object)
    allow = feats[rng.integers(0, len(feats), 40)][path]
    near = wz.clearance().near(pts, allow, seg)
    hit = np.array([bool(wz.collisions(p, f)) for p, f in zip(pts, allow)])
    assert hit.sum() > 20 and (~hit).sum() > 20  # both kinds drawn
    assert not np.any(hit & ~near)
    assert (~near).sum() > 0.3 * (~hit).sum()


@pytest.mark.parametrize("A_deg,C_deg,J_m,holes,finger", [
    (0, 0, (0.0, -0.100, 0.150), (3,), 0.0),       # the star arm through the hole wall
    (-60, 30, (0, 0, 0.150), (1, 7), 0.0),
    (-90, 0, (0.030, 0.0, 0.150), (2, 9), 0.020),
    (45, -90, (0, 0, 0.150), (6,), 0.0)])
def test_check_measurement_with_and_without_broad_phase_agree(A_deg, C_deg, J_m, holes, finger):
    """Old (MuJoCo at every sample and pair) against new on real plans, some colliding: the same
    collisions in the same words, the same sample count, the same least clearance."""
    args = ("m", BAR, FLAT, _T_R_W(A_deg, C_deg), (), J_m, R, _holes(*holes), finger)
    new, old = check_measurement(*args), check_measurement(*args, broad_phase=False)
    assert new == old


def test_check_measurement_random_perturbed_plans_agree():
    """Random tips of the bar's plan moved by up to 3 mm and random table poses: old and new agree."""
    import dataclasses

    rng = np.random.default_rng(2)
    base = _holes(4, 10)
    n_bad = 0
    for _ in range(3):
        pl = dataclasses.replace(base, w_A=base.w_A + rng.uniform(-3e-3, 3e-3, base.w_A.shape))
        T = _T_R_W(rng.uniform(-90, 30), rng.uniform(-180, 180))
        J = (rng.uniform(-0.03, 0.03), rng.uniform(-0.1, 0.1), 0.150)
        args = ("m", BAR, FLAT, T, (), J, R, pl)
        new, old = check_measurement(*args), check_measurement(*args, broad_phase=False)
        assert new == old
        n_bad += len(new.collisions)
    assert n_bad > 0


def test_check_touch_paths_random_paths_agree_with_every_sample_check():
    """Scene (campaign) checks: random links and approaches around the cross pocket, with the
    broad phase and with MuJoCo at every sample: the same verdict and message."""
    art = A.cross_pocket()
    scene = Scene(art, ProbeConfig())
    rng = np.random.default_rng(4)
    lo = art.T_W_A[:3, 3] + [-0.06, -0.06, -0.01]
    hi = art.T_W_A[:3, 3] + [0.06, 0.06, 0.09]
    outcomes = []
    for trial in range(30):
        th = rng.uniform(0, 2 * np.pi)
        c, s_ = np.cos(th), np.sin(th)
        scene.set_table(A.make_T(np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1.0]]), [0, 0, 0]))
        n = 4
        links = [None] + [rng.uniform(lo, hi, (3, 3)) for _ in range(n - 1)]
        approach = rng.uniform(lo, hi, (n, 2, 3))
        approach[:, 1] = approach[:, 0] + rng.uniform(-4e-3, 4e-3, (n, 3))
        feats = [rng.choice(["pocket", "sphere1", "sphere2", ""]) for _ in range(n)]
        msgs = []
        for bp in (True, False):
            from sim import scene as S

            S._PASSED.clear()
            try:
                check_touch_paths(scene, "C0", [f"t{j}" for j in range(n)], feats, links, approach, broad_phase=bp)
                msgs.append(None)
            except PlanError as e:
                msgs.append(str(e))
        assert msgs[0] == msgs[1]
        outcomes.append(msgs[0] is None)
    assert 3 <= sum(outcomes) <= 27  # both verdicts drawn


def test_broad_phase_geoms_are_the_compiled_models():
    """The broad phases read the geoms the MJCF is written from, not the compiled model (which is
    compiled only when a sample reaches MuJoCo): they agree with MuJoCo's poses to rounding."""
    from sim.clearance import model_geoms

    T_R_W = A.make_T(A.rot_z(-0.4) @ A.rot_x(0.2), (0.01, 0.02, -0.03))
    for art in (BAR, A.cross_pocket()):
        sc = Scene(art, ProbeConfig())
        sc.place(A.make_T(A.rot_z(0.7), (0.05, -0.02, 0.11)))
        sc.set_table(T_R_W)
        clr = sc.clearance()
        assert sc._model is None  # nothing compiled yet
        sc.set_tip(np.zeros(3))
        T_A_R = clr.T_F_R
        H = model_geoms(sc.model, sc.data, sc._table_geoms)
        P = model_geoms(sc.model, sc.data, [sc.stylus, sc.stylus + 1, sc.stylus + 2])
        assert np.abs(H.centre @ T_A_R[:3, :3].T + T_A_R[:3, 3] - clr.table.centre).max() < 1e-15
        assert np.abs(T_A_R[:3, :3] @ H.axes - clr.table.axes).max() < 1e-15
        assert np.abs(P.centre @ T_A_R[:3, :3].T - clr.probe.centre).max() < 1e-15
        assert np.abs(T_A_R[:3, :3] @ P.axes - clr.probe.axes).max() < 1e-15
        for G, g in ((H, clr.table), (P, clr.probe)):
            assert np.array_equal(G.kind, g.kind) and np.abs(G.size - g.size).max() < 1e-18
    wz = WorkZone(BAR, FLAT, (), (0.030, 0.0, 0.150), R, 0.020)
    wz.set_table(_T_R_W(-60, 30))
    g = wz.table_geoms()
    assert wz._model is None
    wz.set_tip(np.zeros(3))
    m, d = wz.model, wz.data
    assert np.abs(g.centre - d.geom_xpos[wz._table]).max() < 1e-15
    assert np.abs(g.axes.reshape(-1, 9) - d.geom_xmat[wz._table]).max() < 1e-15
    assert np.array_equal(g.kind, m.geom_type[wz._table]) and np.array_equal(g.size, m.geom_size[wz._table])


def test_certificates_across_placements_agree_with_every_sample_check(monkeypatch):
    """A plan checked at one placement leaves certificates; the same paths (fixed in R) at other
    placements of the artefact turned the same way (moved 0 to 1.2 mm: some within a certificate's
    radius, some beyond) give exactly the verdicts and messages of MuJoCo at every sample. The
    links graze the artefact's top (the ball 0.5 mm below to 1 mm above it: some pairs within the
    boxes' 0.5 mm padding, some beyond), so the moves change verdicts: a certificate that clears too
    much is seen (a radius 2 mm too large, or a padding radius 1 mm too large, fails here). A third
    of the placements are also turned about the spindle axis, the paths with them: the probe looks
    the same from every side, so they share the broad phase and its certificates."""
    from sim import scene as S
    from sim.clearance import Clearance

    art = A.cross_pocket()  # the pocket's blocks' tops at z_A = 0, 0.12 m from the centre; spheres at
    probe = ProbeConfig()   # y_A = 0.06 and -0.055, standing higher
    scene = Scene(art, probe)
    rng = np.random.default_rng(9)
    T0 = art.T_W_A
    z_top = T0[2, 3] + probe.stylus_r_m
    boxes = [0]
    real = Clearance._box_pairs
    monkeypatch.setattr(Clearance, "_box_pairs", lambda self, a, b: boxes.__setitem__(0, boxes[0] + len(a))
                        or real(self, a, b))
    changed = reused = 0
    for trial in range(10):
        n = 4
        links = [None]
        for _ in range(n - 1):  # across the blocks' tops from outside, at a grazing height
            z = z_top + rng.uniform(-0.5e-3, 1.0e-3)
            y = T0[1, 3] + rng.choice([-1, 1]) * rng.uniform(0.025, 0.035)
            x = T0[0, 3] + rng.choice([-1, 1]) * 0.14
            links.append(np.array([[x, y, z + 0.02], [x, y, z], [-x, y, z]]))
        approach = np.column_stack([T0[0, 3] + rng.uniform(-0.1, 0.1, n), T0[1, 3] + rng.uniform(-0.03, 0.03, n),
                                    np.full(n, z_top + 0.03)])
        approach = np.stack([approach, approach - [0, 0, 2e-3]], axis=1)
        feats = [""] * n
        outcomes = []
        for j, move in enumerate([0.0] + list(rng.uniform(0, 1.2e-3, 6))):
            u = rng.normal(size=3) if j % 2 else np.array([0.0, 0.0, 1.0])  # half of them straight up
            # a third turned about the spindle axis, the paths with them (the same plan in A)
            T_turn = A.make_T(A.rot_z(rng.uniform(-np.pi, np.pi)) if j % 3 == 2 else np.eye(3), [0.0, 0, 0])
            T_turn = T0 @ T_turn @ A.inv_T(T0)
            T_nom = T_turn @ T0
            scene.place(A.make_T(T_nom[:3, :3], T_nom[:3, 3] + move * u / np.linalg.norm(u)))
            scene.set_table(np.eye(4))
            links_j = [None] + [A.apply_T(T_turn, ln) for ln in links[1:]]
            approach_j = A.apply_T(T_turn, approach.reshape(-1, 3)).reshape(approach.shape)
            msgs = []
            for bp in (True, False):
                S._PASSED.clear()
                before = boxes[0]
                try:
                    check_touch_paths(scene, "C0", [f"t{k}" for k in range(n)], feats, links_j, approach_j,
                                      broad_phase=bp)
                    msgs.append(None)
                except PlanError as e:
                    msgs.append(str(e))
                if bp and j > 0:
                    reused += boxes[0] - before < 5 * n  # most segments cleared by certificates
            assert msgs[0] == msgs[1], (trial, j, move)
            outcomes.append(msgs[1])
        changed += len(set(outcomes)) > 1
    assert changed >= 3 and reused >= 10, (changed, reused)


def test_a_tilted_spindle_axis_gets_its_own_broad_phase():
    """The same plan in the artefact's frame, first with the spindle along z_A (clear: the shank
    stands in the pocket's channel), then with the table tilted 60 deg (the shank, along R's z,
    leans onto the channel's wall): the second check crashes, with and without the broad phase
    alike (a broad phase or certificate shared across spindle axes would clear it)."""
    from sim import scene as S

    art = A.cross_pocket()
    probe = ProbeConfig()
    scene = Scene(art, probe)
    T0 = art.T_W_A
    z = -0.010 + probe.stylus_r_m  # the ball's centre on the floor of the channel along x_A
    p_A = np.array([[[0.05, -0.010, z + 5e-3], [0.05, -0.010, z + 1e-3]]])  # 8 mm from its wall
    outcomes = []
    for th in (0.0, np.deg2rad(60.0)):
        T_R_W = A.make_T(A.rot_x(-th), [0.0, 0, 0])
        scene.set_table(T_R_W)
        approach = A.apply_T(T_R_W @ T0, p_A.reshape(-1, 3)).reshape(p_A.shape)
        msgs = []
        for bp in (True, False):
            S._PASSED.clear()
            try:
                check_touch_paths(scene, "C0", ["t"], ["pocket"], [None], approach, broad_phase=bp)
                msgs.append(None)
            except PlanError as e:
                msgs.append(str(e))
        assert msgs[0] == msgs[1]
        outcomes.append(msgs[1])
    assert outcomes[0] is None and "shank hits pocket" in outcomes[1], outcomes


def _link_paths_one_by_one(T_R_A, starts_R, features, levels, top_A_m):
    """The link moves as sim.mfb_scene.link_paths wrote them before it batched them (one
    transform per link)."""
    from sim.mfb_scene import LINK_CLEAR_M

    T_A_R = A.inv_T(T_R_A)
    s_A = A.apply_T(T_A_R, np.asarray(starts_R, float))
    out = [None]
    for i in range(1, len(s_A)):
        a, b = s_A[i - 1], s_A[i]
        if features[i] == features[i - 1] and levels[i] == levels[i - 1]:
            pts = np.array([a, b])
        else:
            zc = max(top_A_m + LINK_CLEAR_M, a[2], b[2])
            pts = np.array([a, [a[0], a[1], zc], [b[0], b[1], zc], b])
        out.append(A.apply_T(T_R_A, pts))
    return out


def test_link_paths_are_the_one_by_one_links_bit_for_bit():
    """The batched link moves of every measurement of the MFB 5-axis plan (and of its starts
    scattered by 10 mm) are the links computed one by one, to the last bit."""
    from scenarios import mfb as S
    from sim.machine import Machine
    from sim.machines import MACHINES
    from sim.mfb_scene import link_paths
    from sim.scene import artefact_points

    plan = S.plan_5axis()
    mach = Machine(MACHINES[plan.machine]())
    rng = np.random.default_rng(3)
    top = float(artefact_points(BAR)[:, 2].max()) + R
    n = 0
    for ms in plan.measurements[::3]:
        T_R_A = np.asarray(mach.T_R_W_nominal(np.asarray(ms.rot_rad, float)[None, :]), float).reshape(4, 4) @ ms.T_W_A
        pl = _holes(*ms.holes)
        start = A.apply_T(T_R_A, pl.w_A + (R + pl.clearance_m) * pl.wn_A)
        for st in (start, start + rng.normal(0, 0.01, start.shape)):
            got, want = link_paths(T_R_A, st, pl.feature, pl.level, top), _link_paths_one_by_one(T_R_A, st, pl.feature, pl.level, top)
            assert got[0] is None and len(got) == len(want)
            for g, w in zip(got[1:], want[1:]):
                assert g.shape == w.shape and np.array_equal(g, w)
            n += len(got) - 1
    assert n > 500
    assert link_paths(np.eye(4), np.zeros((1, 3)), ["a"], [0], 0.0) == [None]


def test_fixed_bound_grid_is_the_rows_bound_on_fixed_axes():
    """Clearance.fixed_bound_grid (the least clearance's first pass) equals bound() on every
    (tip, pair) row with the closest-point axis left out, bit for bit, and never exceeds bound()."""
    wz = _zone(-60, 30, (0.0, -0.100, 0.150))
    tips = np.random.default_rng(0).uniform(-0.3, 0.3, (40, 3))
    for holder_only in (True, False):
        clr = wz.clearance(holder_only=holder_only)
        npair = len(clr.pair_probe)
        i, pair = np.repeat(np.arange(len(tips)), npair), np.tile(np.arange(npair), len(tips))
        grid = clr.fixed_bound_grid(tips).ravel()
        assert np.array_equal(grid, clr.bound(tips, i, pair, enough=-np.inf))
        assert np.all(grid <= clr.bound(tips, i, pair))
