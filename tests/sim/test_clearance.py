"""The path checks' broad phase (sim.clearance): its bounds never exceed MuJoCo's distances, it
skips no sample where MuJoCo finds a collision, and the checks with it report exactly what the
sample-by-sample MuJoCo checks report, on randomised paths (issue 19 item 4)."""

import numpy as np
import pytest

from core.exceptions import PlanError
from sim import artefacts as A
from sim.clearance import MARGIN_M, path_samples, path_segments
from sim.mfb_scene import WorkZone, check_measurement
from sim.probe import ProbeConfig
from sim.scene import Scene, check_touch_paths

pytest.importorskip("mujoco")
R = 3e-3
BAR = A.multi_feature_bar(deviations_m=np.zeros((12, 3)))
FLAT = A.make_T(None, (-0.175, 0.080, 0.070))


def _same_check(got, want, note=None) -> None:
    """A check's CheckResult (or a list of them) as the reference's (``broad_phase=False``: MuJoCo at
    every sample and every triple): every field bit for bit but the least clearance, which may differ
    by up to 1e-12 mm (1e-15 m: about ten times the largest difference measured): the broad phase's path takes
    the ball's distances from the holder's spheres, cylinders and boxes in numpy
    (sim.mfb_scene._ball_distance, MuJoCo's primitive in another order of operations; measured below
    1e-13 mm on the plan-check variants and fuzz sets), the reference MuJoCo's own."""
    if isinstance(got, list):
        assert len(got) == len(want), note
        for g, w in zip(got, want):
            _same_check(g, w, note)
        return
    a, b = vars(got), vars(want)
    assert a.keys() == b.keys(), note
    for k in a:
        x, y = a[k], b[k]
        if k == "min_table_clearance_mm":
            assert x == y or abs(x - y) <= 1e-12, (note, x, y)
        elif isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            assert type(x) is type(y) and x.dtype == y.dtype and np.array_equal(x, y), (note, k)
        elif isinstance(x, dict) or isinstance(y, dict):  # (positions_R: kind -> array, in order)
            assert type(x) is type(y) and list(x) == list(y), (note, k, list(x), list(y))
            assert all(x[j].dtype == y[j].dtype and np.array_equal(x[j], y[j]) for j in x), (note, k)
        else:
            assert x == y, (note, k, x, y)


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
    lb_box = clr.box_bound(tips, np.arange(npair))[i, pair]  # (the least clearance's first pass)
    worst, n_close, n_inside = -np.inf, 0, 0
    for k in range(len(k_all)):
        wz.set_tip(tips[i[k]])
        a, b = wz._probe[clr.pair_probe[pair[k]]], wz._table[clr.pair_table[pair[k]]]
        d = mujoco.mj_geomDistance(wz.model, wz.data, a, b, 1.0, None)
        worst = max(worst, lb[k] - d, lb_box[k] - d)
        n_close += d < 5e-3
        n_inside += d < -1e-3  # penetrating pairs: the bounds are signed
        # a pair whose boxes are apart is farther than the margin
        assert cand[i[k], pair[k]] or d > MARGIN_M - 1e-6, (i[k], pair[k], d)
    # MuJoCo's distance of convex pairs is exact to its CCD tolerance (1e-6 m)
    assert worst <= 1e-6, worst
    assert n_close > 50 and n_inside > 10  # the draw reaches the geoms, and into them


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
    paths = _random_paths(rng, T_R_A, 40)
    pts, seg, path = path_samples(paths, np.full(40, 3e-3), joints=False)
    feats = np.array([f.name for f in BAR.features] + [""], dtype=object)
    allow_path = feats[rng.integers(0, len(feats), 40)]
    allow = allow_path[path]
    near = wz.clearance().near(pts, allow, seg)
    hit = np.array([bool(wz.collisions(p, f)) for p, f in zip(pts, allow)])
    assert hit.sum() > 20 and (~hit).sum() > 20  # both kinds drawn
    assert not np.any(hit & ~near)
    # the path checks' two broad phases (the ball against the bar, shared by every zone of
    # the bar, and the rest of this zone's), whole segments at once: no colliding sample left out
    kept = np.zeros(len(pts), bool)
    kept[wz.near_segments(path_segments(paths, np.full(40, 3e-3), joints=False), allow_path)] = True
    assert not np.any(hit & ~kept)
    assert (~kept).sum() > 0.3 * (~hit).sum()
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
    _same_check(new, old)


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
        _same_check(new, old)
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
    real = Clearance._block_candidates
    monkeypatch.setattr(Clearance, "_block_candidates", lambda self, a, *r: boxes.__setitem__(0, boxes[0] + len(a))
                        or real(self, a, *r))
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
    """The link moves as sim.mfb_scene wrote them before it batched them (one transform per
    link): a list, None for the first start."""
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
    from sim.mfb_scene import link_points
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
            P, cnt = link_points(T_R_A, st, pl.feature, pl.level, top)
            want = _link_paths_one_by_one(T_R_A, st, pl.feature, pl.level, top)
            assert len(cnt) == len(want) - 1 and len(P) == cnt.sum()
            for g, w in zip(np.split(P, np.cumsum(cnt)[:-1]), want[1:]):
                assert g.shape == w.shape and np.array_equal(g, w)
            n += len(cnt)
    assert n > 500


def _sphere_over_box(pad=0.5e-3):
    """A ball of radius R (the probe, tip at its centre) over a box whose top face is z = 0
    (feature "top"): the distance of the ball at height z is z - R, exactly."""
    from sim.clearance import Clearance, Geoms

    one = lambda *v: np.array([v], float)  # noqa: E731
    ball = Geoms(one(0, 0, 0), np.eye(3)[None], np.array([2]), one(R, 0, 0), np.array([R]))
    box = Geoms(one(0, 0, -0.010), np.eye(3)[None], np.array([6]), one(0.050, 0.050, 0.010),
                np.array([np.sqrt(0.05 ** 2 * 2 + 0.01 ** 2)]))
    return Clearance(ball, box, ["top"], 0, cert_pad_m=pad)


def test_certificates_clear_exactly_their_radius():
    """Known answer: a move 0.3 mm above the box leaves a certificate of 0.3 - 0.1 (margin)
    = 0.2 mm. Moves of the same segment by 0.19 mm down are cleared by it (no new box test);
    by 0.21 mm (0.09 mm from the box: within the margin), by 0.45 mm (0.15 mm deep) and with one
    end only 0.45 mm down (the segment tilted into the box) the samples near the box are
    returned. A radius 0.06 mm too large, or a move measured at its nearer end, clears one of
    them. A certificate left with the ball allowed on the box's feature clears nothing for a
    move that is not."""
    from sim.clearance import Clearance, path_segments

    def seg(za, zb, allow=""):
        sg = path_segments([np.array([[-0.02, 0, za], [0.02, 0, zb]])], [0.5e-3], joints=False)
        return sg, [allow]

    z0 = R + 0.3e-3
    calls = []
    real = Clearance._block_candidates

    def counted(self, lo, *rest):
        calls.append(len(lo))
        return real(self, lo, *rest)

    for dz_a, dz_b, want_near in ((0.19e-3, 0.19e-3, False), (0.21e-3, 0.21e-3, True),
                                  (0.45e-3, 0.45e-3, True), (0.45e-3, 0.0, True), (0.0, 0.45e-3, True)):
        clr = _sphere_over_box()
        Clearance._block_candidates = counted
        try:
            assert clr.near_segments(*seg(z0, z0)).size == 0
            calls.clear()
            near = clr.near_segments(*seg(z0 - dz_a, z0 - dz_b))
        finally:
            Clearance._block_candidates = real
        assert (near.size > 0) == want_near, (dz_a, dz_b)
        assert (len(calls) == 0) == (not want_near)  # cleared by the certificate, not recomputed
    clr = _sphere_over_box()
    assert clr.near_segments(*seg(R - 1e-3, R - 1e-3, "top")).size == 0  # the ball may touch "top"
    assert clr.near_segments(*seg(R - 1e-3, R - 1e-3)).size > 0  # but nothing else may


@pytest.mark.parametrize("axis,sign", [(0, 1), (0, -1), (1, 1), (1, -1), (2, 1)])
def test_a_move_toward_each_face_is_kept_within_the_margin(axis, sign):
    """Known answer on every face the ball can reach (the box's top, x and y sides): a move
    along the face's normal that ends 0.05 mm from the box (within the 0.1 mm margin) is kept,
    one that ends 0.15 mm away is cleared (the swept bound along the box's axis is exact for a
    sphere moving straight at a face). A box test that loses 1 mm of overlap along one axis
    drops the first (checked by mutation, on each of x, y, z in turn)."""
    from sim.clearance import path_segments

    face = np.array([0.050, 0.050, 0.0])  # the faces' distance from the box's axis line (x, y), top z = 0
    centre = np.array([0.0, 0.0, -0.010])
    for gap, want_near in ((0.05e-3, True), (0.15e-3, False)):
        n = np.zeros(3)
        n[axis] = sign
        on_face = centre + 0.0  # the point of the face nearest the approach, then out along n
        on_face[axis] = sign * face[axis] if axis < 2 else 0.0
        end = on_face + n * (R + gap)
        start = end + n * 5e-3
        sg = path_segments([np.array([start, end])], [0.5e-3], joints=False)
        near = _sphere_over_box().near_segments(sg, [""])
        assert (near.size > 0) == want_near, (axis, sign, gap)


def test_a_segment_with_no_pair_in_its_padded_box_certifies_exactly_the_padding():
    """Known answer for the other source of certificates: a segment whose box, padded by 0.5 mm,
    meets no pair's box (pairs are inflated by the 0.1 mm margin) is clear by at least the padding,
    so its certificate radius is the padding itself. Ball centre at R + 0.65 mm over the box: the
    padded box misses the pair's box by 0.05 mm. Moved 0.49 mm down (0.16 mm from the box) it is
    cleared by the certificate without a box test; moved 0.56 mm (0.09 mm: within the margin) it
    must be bounded again and found near. A radius 0.07 mm larger than the padding clears the
    second (checked by mutation: this test fails at +0.07, +0.1 and +0.3 mm; at +0.06 mm the radius
    equals the 0.56 mm move and clears nothing). The gap was found by a mutation,
    `r[todo] = pad + 0.3 mm`, that no test caught."""
    from sim.clearance import Clearance, path_segments

    pad = 0.5e-3

    def seg(z):
        return path_segments([np.array([[-0.02, 0, z], [0.02, 0, z]])], [0.5e-3], joints=False), [""]

    z0 = R + pad + 0.15e-3
    calls = []
    real = Clearance._block_candidates

    def counted(self, lo, *rest):
        calls.append(len(lo))
        return real(self, lo, *rest)

    for dz, want_near in ((0.49e-3, False), (0.56e-3, True)):
        clr = _sphere_over_box(pad)
        assert clr.near_segments(*seg(z0)).size == 0
        Clearance._block_candidates = counted
        try:
            calls.clear()
            near = clr.near_segments(*seg(z0 - dz))
        finally:
            Clearance._block_candidates = real
        assert (near.size > 0) == want_near, dz
        assert (len(calls) == 0) == (not want_near)  # cleared by the certificate, not recomputed


def test_a_closing_point_is_cleared_by_its_segment_or_bounded_after_it(monkeypatch):
    """Known answer for the rows near_segments_many leaves to the row before them (a polyline's
    closing point, without joints: the end of its last segment, a sample of its own). One step
    per segment, so a segment's only sample is its start: a move from 5 mm above the box (sample
    0) down to the ball 1 mm into it (sample 1, the closing point) is near at sample 1 only; the
    same move ending 0.3 mm above the box is clear, and its closing point is not bounded (the box
    test sees one row of the two). With the closing point taken as cleared whenever its segment
    is (the second bounding left out) the first case returns nothing: this test fails then."""
    from sim.clearance import Clearance, path_segments

    seen = []
    real = Clearance._block_candidates
    monkeypatch.setattr(Clearance, "_block_candidates", lambda self, lo, *r: seen.append(len(lo)) or real(self, lo, *r))
    for z_end, want in ((R - 1e-3, [1]), (R + 0.3e-3, [])):
        sg = path_segments([np.array([[-0.02, 0, R + 5e-3], [0.02, 0, z_end]])], [1.0], joints=False)
        assert sg.n_samples == 2 and len(sg.a) == 2  # the segment (its start), the closing point
        seen.clear()
        near = _sphere_over_box().near_segments(sg, [""])
        assert near.tolist() == want, (z_end, near)
        assert seen[0] == 1  # the segment alone; (the closing point again only when it may be near)
        assert len(seen) == (2 if want else 1)


def _lookup(st, a, b, allow):
    """(r0, moved) of each segment as near_segments_many looks it up: in order, then by grid cell."""
    r0, moved = st.in_order(a, b, allow)
    rest = np.flatnonzero(~(moved < r0))
    if rest.size and st._n:
        st.by_cell(a, b, allow, rest, r0, moved)
    return r0, moved


def test_certificates_by_place_and_by_segment_and_feature():
    """The certificate store finds a remembered segment within its radius for the same segments
    in the same order moved by less than their radii (another placement), and for the same
    segments in another order and number, moved by rounding (another measurement's moves);
    never across allowed features, never for a segment moved by its radius or more."""
    from sim.clearance import _Certificates

    rng = np.random.default_rng(4)
    a = rng.uniform(-0.2, 0.2, (500, 3))
    b = a + rng.normal(0, 0.01, (500, 3))
    allow = np.array(["", "hole01", "rod02"], dtype=object)[rng.integers(0, 3, 500)]
    r = rng.uniform(0.1e-3, 0.5e-3, 500)
    st = _Certificates()
    st.add(a, b, allow, r)
    st.add(a + 0.05, b + 0.05, np.roll(allow, 1), r)  # others, elsewhere
    u = rng.normal(size=(500, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    f = rng.uniform(0, 1.5, 500)
    r0, moved = _lookup(st, a + (f * r)[:, None] * u, b, allow)  # in order, moved 0 to 1.5 radii
    assert np.array_equal(moved < r0, f < 1) and np.allclose(moved, f * r, rtol=0, atol=1e-15)
    p = rng.permutation(500)[:300]
    r0, moved = _lookup(st, a[p] + rng.normal(0, 1e-15, (300, 3)), b[p], allow[p])  # shuffled, 300
    assert np.all(moved < r0) and np.all(moved < 1e-14) and np.array_equal(r0, r[p])
    other = np.where(allow[p] == "", "rod02", "").astype(object)
    r0, moved = _lookup(st, a[p], b[p], other)  # the same segments with another allowed feature
    assert not np.any(moved < r0)
    # within one grid cell (1 um) but beyond a 0.2 um radius: the distance is still measured
    c = np.array([[0.012, -0.034, 0.056]])
    st.add(c, c + [0.01, 0, 0], np.array([""], dtype=object), np.array([0.2e-6]))
    r0, moved = _lookup(st, np.r_[a[:3], c + [0.4e-6, 0, 0]], np.r_[b[:3], c + [0.01, 0, 0]],
                          np.r_[allow[:3], np.array([""], dtype=object)])
    assert r0[3] == 0.2e-6 and abs(moved[3] - 0.4e-6) < 1e-15 and not moved[3] < r0[3]


def test_certificate_cell_hash_known_answer():
    """The certificates' cell hash (:meth:`sim.clearance._Certificates._key`) is its definition,
    computed here with Python's integers: each end's cells (1 um, half to even) and the feature number weighted
    by the odd constants, summed modulo 2^64 (negative cells as their two's complement), then
    splitmix64's finalizer; the features as numbers in order of first appearance."""
    from sim.clearance import _CELLS, _HASH, _Certificates

    M = 2 ** 64
    w = [int(x) for x in _HASH]
    rng = np.random.default_rng(11)
    a = rng.uniform(-0.4, 0.4, (40, 3))
    b = a + rng.normal(0, 0.02, (40, 3))
    a[0], b[0] = 0.0, -0.0  # (a zero cell, either sign)
    allow = np.array(["", "hole01", "rod02"], dtype=object)[rng.integers(0, 3, 40)]
    h, f = _Certificates()._key(a, b, allow)
    first = {x: n for n, x in enumerate(dict.fromkeys(allow))}
    assert f.tolist() == [first[x] for x in allow]
    for j in range(40):
        cells = [round(float(v) * float(s)) for v, s in zip((*a[j], *b[j]), _CELLS)] + [first[allow[j]]]
        x = sum(c * wk for c, wk in zip(cells, w[2:])) % M
        x = ((x ^ (x >> 30)) * w[0]) % M
        x = ((x ^ (x >> 27)) * w[1]) % M
        assert int(h[j]) == x ^ (x >> 31), j
    h2, f2 = _Certificates()._key(a, b, f)  # features already numbers: the same keys
    assert np.array_equal(h2, h) and np.array_equal(f2, f)


def test_least_holder_clearance_refines_to_the_every_triple_minimum():
    """Tips scattered 0-20 mm around the bar's supports and the table, a star stylus at a tilted
    table (its arm's and finger's bounds loose by millimetres): the branch and bound gives
    MuJoCo's least distance over every (tip, probe geom, holder geom), as the reference does, to
    1e-12 m (MuJoCo's distances, the same calls). A refinement stopped 5 mm (or 1 mm) early
    returns a larger value on some of these sets."""
    rng = np.random.default_rng(11)
    n_diff = 0
    for A_deg, C_deg, J in ((-60, 30, (0.0, -0.100, 0.150)), (-30, 120, (0.030, 0.0, 0.150)),
                            (0, 45, (0.0, 0.0, 0.150))):
        wz = _zone(A_deg, C_deg, J, 0.020 if J[0] else 0.0)
        T_R_A = _T_R_W(A_deg, C_deg) @ FLAT
        pts = A.apply_T(T_R_A, artefact_points_low())
        for _ in range(3):
            tips = pts[rng.integers(0, len(pts), 40)] + rng.normal(0, 0.012, (40, 3))
            new = wz.least_holder_clearance(tips)
            old = wz.least_holder_clearance(tips, broad_phase=False)
            assert abs(new - old) <= 1e-12, (A_deg, C_deg, new, old)
            n_diff += new < 0.05
    assert n_diff >= 6


def artefact_points_low():
    """Points of the bar within 15 mm of its underside (A frame, m): near the supports and the table."""
    from sim.scene import artefact_points

    p = artefact_points(BAR)
    return p[p[:, 2] <= p[:, 2].min() + 0.015]


def test_least_holder_clearance_looks_past_loose_bounds():
    """Known answer: 108 tips 12 mm outside the table disc's rim, at half its thickness (the ball
    9 mm from the rim; at oblique azimuths they lie within the disc's bounding box, so the first
    bounds of those pairs are at most 0 and they come first) and one tip with the ball 8 mm above the disc's face (its bound exact,
    8 mm, ranked after more than 64 loose rows). The least clearance is 8 mm, with the broad
    phase as without; a refinement that stops 5 mm short of the best distance found (9 mm) never
    reaches the 8 mm tip."""
    from sim.mfb_scene import TABLE_R_M, TABLE_T_M

    wz = _zone(0, 0, (0.0, 0.0, 0.150))
    T_R_W = _T_R_W(0, 0)
    az = np.deg2rad(np.linspace(20, 70, 15))[:, None] + np.deg2rad([0, 90, 180, 270])[None, :]
    # and 48 nearly on the axes (7-10 deg: the ball's bounds 4.3-6.7 mm, its distance 9 mm), so
    # more than 64 rows lie between the best distance less 5 mm and the 8 mm tip's bound
    az = np.r_[az.ravel(), (np.deg2rad(np.linspace(7, 10, 12))[:, None] + np.deg2rad([0, 90, 180, 270])).ravel()]
    rho = TABLE_R_M + 12e-3
    rim = np.column_stack([rho * np.cos(az), rho * np.sin(az), np.full(az.size, -TABLE_T_M / 2)])
    top = np.array([[0.05, -0.02, R + 8e-3]])  # above the disc, far from the bar's supports
    tips = A.apply_T(T_R_W, np.vstack([rim, top]))
    new = wz.least_holder_clearance(tips)
    assert abs(new - 8e-3) < 1e-9, new  # MuJoCo's sphere-cylinder distance, to rounding
    assert abs(new - wz.least_holder_clearance(tips, broad_phase=False)) <= 1e-12
    assert abs(wz.least_holder_clearance(tips[:-1]) - 9e-3) < 1e-6  # the rim alone: the ball 9 mm away


@pytest.mark.parametrize("J_m,finger", [((0.0, 0.0, 0.150), 0.0), ((0.0, -0.060, 0.150), 0.020)])
def test_one_work_zone_at_many_table_poses_agrees_with_every_sample_check(J_m, finger):
    """One work zone (one stylus, one placement) checked at table poses in turn, as a plan's
    measurements are: turns about the spindle axis (sharing the broad phase in W and its
    certificates when the probe is a straight stylus) and tilts (each its own), some crashing.
    Every result equals MuJoCo at every sample. A broad phase shared across spindle axes, or a
    star stylus's shared across turns about the axis, misses a crash here."""
    from sim import mfb_scene

    mfb_scene._ZONES.clear()
    pl = _holes(3, 4, 5)
    n_bad = 0
    for A_deg, C_deg in ((0, 0), (0, 90), (0, -45), (-90, 0), (-90, 90), (-45, 0), (0, 180), (-90, -90)):
        args = ("m", BAR, FLAT, _T_R_W(A_deg, C_deg), (), J_m, R, pl, finger)
        new, old = check_measurement(*args), check_measurement(*args, broad_phase=False)
        _same_check(new, old, (A_deg, C_deg))
        n_bad += bool(new.collisions)
    assert n_bad >= 2


def _same_segments(got, want):
    for f in ("a", "b", "k", "m", "first", "path"):
        assert np.array_equal(getattr(got, f), getattr(want, f)), f


def _touch_paths(T_R_A, start, Xn, plan, top, link_step_m, approach_step_m):
    """(Segments, touch of each polyline, allowed feature of each) of one measurement's polylines,
    sim.mfb_scene._paths_of of that measurement alone."""
    from sim.mfb_scene import _paths_of, link_points

    if plan.n > 1:
        L, cnt = link_points(T_R_A, start, plan.feature, plan.level, top)
    else:
        L, cnt = np.zeros((0, 3)), np.zeros(0, int)
    sg, touch, allow, _ = _paths_of([(start, Xn, L, cnt, plan)], link_step_m, approach_step_m)[0]
    return sg, touch, allow


def test_measurement_paths_are_the_polylines_checked_one_by_one():
    """check_measurement's polylines built in one array (sim.mfb_scene._paths_of) are the ones
    the list-of-polylines version built: per touch the link into its start (none for the first,
    allowed feature none), then its approach (the touched feature allowed); the same segments,
    bit for bit, the same touch and allowed feature per polyline."""
    from sim.clearance import path_segments

    for holes, (A_deg, C_deg) in (((3, 4, 5), (0, 0)), ((1,), (-90, 45)), ((10, 11), (-45, 120))):
        pl = _holes(*holes)
        T_R_A = _T_R_W(A_deg, C_deg) @ FLAT
        Xn = A.apply_T(T_R_A, pl.w_A + R * pl.wn_A)
        start = Xn + pl.clearance_m * A.apply_R(T_R_A, pl.wn_A)
        top = 0.021
        for n in (pl.n, 1, 2):
            sub = pl.select(np.arange(n))
            links = _link_paths_one_by_one(T_R_A, start[:n], sub.feature, sub.level, top)
            paths = []
            for i in range(n):
                if links[i] is not None:
                    paths.append((i, links[i], 3e-3, ""))
                paths.append((i, np.array([start[i], Xn[i]]), 0.5e-3, sub.feature[i]))
            want = path_segments([p[1] for p in paths], [p[2] for p in paths], joints=False)
            sg, touch, allow = _touch_paths(T_R_A, start[:n], Xn[:n], sub, top, 3e-3, 0.5e-3)
            _same_segments(sg, want)
            assert touch.tolist() == [p[0] for p in paths] and allow.tolist() == [p[3] for p in paths]


def test_campaign_paths_are_the_polylines_checked_one_by_one(monkeypatch):
    """check_touch_paths' polylines in one array are those of the list-of-polylines version: per
    touch its link (when it has one of two points or more; none allowed), then its approach (its
    feature allowed); the same segments bit for bit, as sim.clearance receives them, and the
    allowed features as the broad phase's numbers of those names (given numbered, session 23)."""
    from sim import scene as S
    from sim.clearance import Clearance, path_segments

    seen = []
    monkeypatch.setattr(Clearance, "near_segments", lambda self, sg, allow_feature=None, feature_ids=None:
                        seen.append((sg, list(self.feature_ids(allow_feature)) if feature_ids is None
                                     else list(feature_ids), self)) or np.zeros(0, int))
    art = A.cross_pocket()
    scene = Scene(art, ProbeConfig())
    rng = np.random.default_rng(9)
    for links in ([None, np.zeros((1, 3)), rng.normal(0, 0.05, (3, 3)), rng.normal(0, 0.05, (2, 3))],
                  [rng.normal(0, 0.05, (k, 3)) for k in (2, 4, 4, 3)]):
        approach = rng.normal(0, 0.05, (4, 2, 3))
        feats = ["pocket", "sphere1", "", "pocket"]
        S._PASSED.clear()
        seen.clear()
        check_touch_paths(scene, "C0", ["a", "b", "c", "d"], feats, links, approach)
        paths = []
        for i in range(4):
            if links[i] is not None and len(links[i]) > 1:
                paths.append((links[i], 2e-3, ""))
            paths.append((approach[i], 0.25e-3, feats[i]))
        _same_segments(seen[0][0], path_segments([p[0] for p in paths], [p[1] for p in paths], joints=True))
        assert seen[0][1] == list(seen[0][2].feature_ids([p[2] for p in paths]))
        assert seen[0][1].count(-2) == sum(p[2] == "" for p in paths)  # (the names known: "" alone unnumbered)


@pytest.mark.parametrize("weigh_feature", [True, False])
def test_a_certificate_serves_only_segments_with_its_allowed_feature(monkeypatch, weigh_feature):
    """An approach into a hole, checked with the hole allowed (the ball's pairs with it left out:
    a certificate), then as a link (nothing allowed): the ball at the contact is on the hole's
    geoms, so it must be kept. Without the feature in the cell hash (weigh_feature False) the
    two segments share a key: the lookup's feature check alone keeps the certificate out."""
    from sim import clearance as C
    from sim import mfb_scene

    if not weigh_feature:
        monkeypatch.setattr(C, "_HASH", np.r_[C._HASH[:-1], np.uint64(0)])
    mfb_scene._BALLS.clear()
    wz = _zone(0, 0, (0, 0, 0.150))
    pl = _holes(3)
    T_R_A = _T_R_W(0, 0) @ FLAT
    i = int(np.flatnonzero(np.char.startswith(np.asarray(pl.feature, str), "hole"))[0])
    Xn = A.apply_T(T_R_A, pl.w_A[i] + R * pl.wn_A[i])
    start = Xn + pl.clearance_m * A.apply_R(T_R_A, pl.wn_A[i])
    sg = path_segments([np.array([start, Xn])], [0.5e-3], joints=False)
    clr = wz.ball_clearance()
    assert clr.near_segments(sg, [pl.feature[i]]).size == 0  # cleared, certificates left
    assert clr.near_segments(sg, [""]).size > 0  # the contact itself: on the hole's geoms
    mfb_scene._BALLS.clear()


def test_swept_bound_known_answer():
    """Known answer: the ball (radius R) moved 20 mm along a box's top face with its lowest point
    5 mm above it: the swept bound is that distance, 5 mm (the closest-point axis, the face's
    normal, is exact for a sphere and a box). The same move ending with the ball 1 mm into the
    box: the least signed distance over the move, -1 mm at its end (the offset along the normal
    is linear along the move: its least value is an end's)."""
    clr = _sphere_over_box()
    a, b = np.array([[-0.01, 0.0, R + 5e-3]]), np.array([[0.01, 0.0, R + 5e-3]])
    assert clr.swept_bound(a, b, np.array([0]))[0] == pytest.approx(5e-3, abs=1e-15)
    lb = clr.swept_bound(a, np.array([[0.01, 0.0, R - 1e-3]]), np.array([0]))[0]
    assert lb == pytest.approx(-1e-3, abs=1e-15)


@pytest.mark.parametrize("A_deg,C_deg,J_m,finger", [(0, 0, (0, 0, 0.150), 0.0),
                                                     (-60, 30, (0.0, -0.100, 0.150), 0.0)])
def test_swept_bounds_never_exceed_mujoco_distances_along_the_segment(A_deg, C_deg, J_m, finger):
    """The swept bound of a pair for a straight move (what clears a whole segment at once) is at
    most MuJoCo's distance of the pair at every point of the move (21 points each), for random
    short moves near the bar, the table and the supports, the pairs their boxes let through."""
    import mujoco

    wz = _zone(A_deg, C_deg, J_m, finger)
    clr = wz.clearance()
    rng = np.random.default_rng(abs(A_deg) + 11)
    T_R_A = _T_R_W(A_deg, C_deg) @ FLAT
    a = A.apply_T(T_R_A, rng.uniform([-0.03, -0.03, -0.03], [0.40, 0.08, 0.06], (200, 3)))
    b = a + rng.normal(0, 4e-3, a.shape)
    i, pair = clr.candidates(np.r_[a, b], np.r_[np.arange(len(a)), np.arange(len(a))])
    i = i % len(a)
    key = np.unique(i * len(clr.pair_probe) + pair)
    i, pair = np.divmod(key, len(clr.pair_probe))
    lb = clr.swept_bound(a[i], b[i], pair)
    worst, n_close = -np.inf, 0
    for k in range(len(i)):
        ga, gb = wz._probe[clr.pair_probe[pair[k]]], wz._table[clr.pair_table[pair[k]]]
        d = np.inf
        for f in np.linspace(0.0, 1.0, 21):
            wz.set_tip(a[i[k]] + f * (b[i[k]] - a[i[k]]))
            d = min(d, mujoco.mj_geomDistance(wz.model, wz.data, ga, gb, 1.0, None))
        worst = max(worst, lb[k] - d)
        n_close += d < 5e-3
    assert worst <= 1e-6, worst  # (MuJoCo's distances: to its CCD tolerance, 1e-6 m)
    assert len(i) > 100 and n_close > 30


def test_near_segments_of_several_broad_phases_at_once_are_each_alone():
    """near_segments_many on parts of several broad phases (the ball's in A and two work zones'
    in W, moved copies sharing one) gives each part the samples its own near_segments gives it
    (all fresh: no certificates), and leaves each broad phase the certificates it would."""
    from sim import mfb_scene
    from sim.clearance import Segments, near_segments_many

    rng = np.random.default_rng(21)
    made = []
    for A_deg, C_deg, J_m in ((0, 0, (0, 0, 0.150)), (-90, 0, (0.0, -0.100, 0.150)), (0, 90, (0, 0, 0.150))):
        T_R_A = _T_R_W(A_deg, C_deg) @ FLAT
        sg = path_segments(_random_paths(rng, T_R_A, 40), np.full(40, 3e-3), joints=False)
        feats = np.array([f.name for f in BAR.features] + [""], dtype=object)
        made.append((A_deg, C_deg, J_m, sg, feats[rng.integers(0, len(feats), 40)]))

    def parts():
        mfb_scene._BALLS.clear()
        mfb_scene._ZONES.clear()
        out = []
        for A_deg, C_deg, J_m, sg, allow in made:
            wz = mfb_scene._work_zone(BAR, FLAT, (), J_m, R, 0.0)
            wz.set_table(_T_R_W(A_deg, C_deg))
            for clr in (wz.ball_clearance(), wz.clearance(part="rest")):
                sgF = Segments(clr.to_frame(sg.a), clr.to_frame(sg.b), sg.k, sg.m, sg.first, sg.path)
                out.append((clr, sgF, clr.feature_ids(allow)[sg.path]))
        return out

    alone = []
    for p in parts():  # each on fresh broad phases
        alone.append(near_segments_many([p])[0])
        p[0]._certs.__init__()
    many = parts()
    got = near_segments_many(many)
    assert all(np.array_equal(x, y) for x, y in zip(got, alone))
    assert sum(len(x) for x in got) > 20 and sum(len(x) > 0 for x in got) >= 4
    assert all(p[0]._certs._n > 0 for p in many)


def test_a_plans_measurements_checked_at_once_are_each_alone_and_every_sample():
    """check_measurements of several measurements (placements, tables turned and tilted, straight
    and star styli, some crashing, one hole set measured twice so its certificates clear the
    other's ball moves) gives each the result of check_measurement alone and of MuJoCo at every
    sample: collisions, path points, least clearance."""
    from sim import mfb_scene
    from sim.mfb_scene import Block, check_measurements

    riser = (Block("riser", (-0.095, -0.045, 0.0), (0.295, 0.045, 0.150)),)
    P2 = A.make_T(None, (-0.175, 0.000, 0.220))
    items = [("a", FLAT, _T_R_W(0, 0), (), (0, 0, 0.150), _holes(3, 4), 0.0),
             ("b", FLAT, _T_R_W(0, 90), (), (0, 0, 0.150), _holes(3, 4), 0.0),
             ("c", FLAT, _T_R_W(-90, 0), (), (0.0, -0.100, 0.150), _holes(6), 0.0),
             ("d", P2, _T_R_W(0, 0), riser, (0, 0, 0.150), _holes(1, 2), 0.0),
             ("e", FLAT, _T_R_W(0, 0), (), (0.0, -0.100, 0.150), _holes(3), 0.0),  # the arm across the bar
             ("f", FLAT, _T_R_W(-45, 0), (), (-0.100, 0.0, 0.190), _holes(10), 0.040)]
    mfb_scene._ZONES.clear()
    mfb_scene._BALLS.clear()
    got = check_measurements(BAR, items, R)
    ref = [check_measurement(it[0], BAR, *it[1:5], R, *it[5:], broad_phase=False) for it in items]
    mfb_scene._ZONES.clear()
    mfb_scene._BALLS.clear()
    one = [check_measurement(it[0], BAR, *it[1:5], R, *it[5:]) for it in items]
    assert got == one
    _same_check(got, ref)
    assert sum(bool(r.collisions) for r in got) >= 1 and sum(r.ok for r in got) >= 3


def test_measurements_paths_sampled_at_once_are_each_alone():
    """The polylines of several measurements sampled in one pass (sim.mfb_scene._paths_of, as
    check_measurements does) are each measurement's alone (_touch_paths), bit for bit."""
    from sim.mfb_scene import _paths_of, link_points

    items, want = [], []
    for holes, (A_deg, C_deg) in (((3, 4, 5), (0, 0)), ((1,), (-90, 45)), ((10, 11), (-45, 120)), ((7,), (0, 0))):
        pl = _holes(*holes)
        for n in (pl.n, 1):
            sub = pl.select(np.arange(n))
            T_R_A = _T_R_W(A_deg, C_deg) @ FLAT
            Xn = A.apply_T(T_R_A, sub.w_A + R * sub.wn_A)
            start = Xn + sub.clearance_m * A.apply_R(T_R_A, sub.wn_A)
            L, cnt = link_points(T_R_A, start, sub.feature, sub.level, 0.021) if n > 1 else (np.zeros((0, 3)),
                                                                                              np.zeros(0, int))
            items.append((start, Xn, L, cnt, sub))
            want.append(_touch_paths(T_R_A, start, Xn, sub, 0.021, 3e-3, 0.5e-3))
    for (sg, touch, allow, app), (sg1, touch1, allow1) in zip(_paths_of(items, 3e-3, 0.5e-3), want):
        _same_segments(sg, sg1)
        assert np.array_equal(touch, touch1) and allow.tolist() == allow1.tolist()
        assert np.array_equal(app[:-1], touch[1:] != touch[:-1]) and app[-1]  # (each touch's last polyline)


def test_an_artefact_without_solids_has_an_empty_pose_stack():
    """Edge path (review): no solids gives empty pose arrays, as before the stacked form, not a broadcast error."""
    import dataclasses

    from sim import artefacts as A
    from sim.mfb_scene import _solid_pose_stack

    art = dataclasses.replace(A.multi_feature_bar(deviations_m=np.zeros((12, 3))), solids=())
    assert _solid_pose_stack(art).shape == (0, 4, 4)


def _skipped_colliding(items, passes=2):
    """(samples skipped, skipped samples MuJoCo finds colliding, near samples) of measurements
    ``items`` (T_W_A, T_R_W, blocks, J, plan, finger) checked by the one-pass broad phase
    (sim.mfb_scene._near_samples) ``passes`` times (later passes from certificates), fresh caches. MuJoCo
    is asked once per skipped sample: a later pass keeps an earlier pass's verdict (the same sample of the
    same measurement), and checks every sample it newly skips."""
    from sim import mfb_scene
    from sim.mfb_scene import _near_samples, _paths_of, _work_zone, link_points

    mfb_scene._ZONES.clear()
    mfb_scene._BALLS.clear()
    ms = [(f"m{i}", np.asarray(a, float), np.asarray(b, float), tuple(c), d, p, float(f))
          for i, (a, b, c, d, p, f) in enumerate(items)]
    mfb_scene.share_ball_model(BAR, [(m[1], m[3], m[4], m[6]) for m in ms], R)
    top = float(mfb_scene.artefact_points(BAR)[:, 2].max()) + R
    zones, paths = [], []
    for _, T_W_A, T_R_W, blocks, J, plan, fin in ms:
        T_R_A = T_R_W @ T_W_A
        zones.append(_work_zone(BAR, T_W_A, blocks, J, R, fin))
        Xn = A.apply_T(T_R_A, plan.w_A + R * plan.wn_A)
        start = Xn + plan.clearance_m * A.apply_R(T_R_A, plan.wn_A)
        L, cnt = link_points(T_R_A, start, plan.feature, plan.level, top)
        paths.append((start, Xn, L, cnt, plan))
    live = list(range(len(ms)))
    sgs = _paths_of(paths, 3e-3, 0.5e-3)
    skipped, bad, n_near = 0, [], 0
    asked = [set() for _ in ms]  # samples MuJoCo judged in an earlier pass: the same sample, the same answer
    for _ in range(passes):
        near = _near_samples(ms, zones, live, sgs)
        for i in live:
            wz = zones[i]
            wz.set_table(ms[i][2])
            sg, _, allow, _ = sgs[i]
            n_near += near[i].size
            skip = np.setdiff1d(np.arange(sg.n_samples), near[i])
            skipped += skip.size
            new = np.array([s for s in skip.tolist() if s not in asked[i]], dtype=int)
            pts, which = sg.points(new), sg.path[sg.segment_of(new)]
            bad += [(i, pts[k]) for k in range(new.size) if wz.collisions(pts[k], allow[which[k]])]
            asked[i].update(new.tolist())
    return skipped, bad, n_near


def test_no_sample_the_one_pass_check_skips_collides():
    """Soundness of the one-pass broad phase (certificates reused between measurements): every sample it skips
    is clear in MuJoCo. Seven measurements in four orientations, each beside a subset of its holes (so the
    second's moves are cleared from the first's certificates), a finger on two; checked twice (the second
    pass from certificates only). The check can fail: MuJoCo sees a tip sunk in the bar."""
    from sim import mfb_scene

    rng = np.random.default_rng(11)
    items = []
    for k, (a_deg, c_deg) in enumerate([(0, 0), (0, 90), (-90, 0), (-60, 30)]):
        holes = tuple(sorted(rng.choice(np.arange(1, 13), size=3, replace=False).tolist()))
        fin = 0.040 if k % 2 else 0.0
        items.append((FLAT, _T_R_W(a_deg, c_deg), (), (0, 0, 0.150), _holes(*holes), fin))
        items.append((FLAT, items[-1][1], (), (0, 0, 0.150), _holes(*holes[:1]), fin))
    skipped, bad, _ = _skipped_colliding(items[:7])
    assert not bad, f"skipped samples collide: {bad[:3]}"
    assert skipped > 1000  # the broad phase skipped most samples: the check above tested something
    wz = mfb_scene._work_zone(BAR, FLAT, (), (0, 0, 0.150), R, 0.0)
    wz.set_table(items[0][1])
    inside = A.apply_T(items[0][1] @ FLAT, mfb_scene.artefact_points(BAR)[:1] - np.array([0.0, 0.0, 0.01]))
    assert wz.collisions(inside[0])  # a tip 10 mm inside the bar's material collides


def test_no_sample_a_shared_part_skips_collides():
    """Soundness of the parts measurements share (sim.mfb_scene._near_samples): one program (plan object)
    at three table poses shares its ball part (frame A), and at a turn about the spindle axis with the
    straight stylus its work zone's part too (frame W); a copy of the program moved 4 mm along x_A (the
    same steps, the same features: only the program object differs) at the same pose collides in MuJoCo
    and must get its own parts. No skipped sample collides; the moved copy's collisions are found
    (check_measurements reports them, as MuJoCo at every sample does). Keyed without the program, the
    moved copy would take the first's near samples and this test fails (tried)."""
    import dataclasses

    from sim.mfb_scene import check_measurement, check_measurements

    pl = _holes(3, 4)
    moved = dataclasses.replace(pl, w_A=pl.w_A + np.array([4e-3, 0.0, 0.0]))
    J0 = (0, 0, 0.150)
    items = [(FLAT, _T_R_W(0, 0), (), J0, pl, 0.0), (FLAT, _T_R_W(0, 45), (), J0, pl, 0.0),
             (FLAT, _T_R_W(-90, 0), (), (0.0, -0.100, 0.150), pl, 0.0), (FLAT, _T_R_W(0, 0), (), J0, moved, 0.0)]
    skipped, bad, n_near = _skipped_colliding(items, passes=1)
    assert not bad, f"skipped samples collide: {bad[:3]}"
    assert skipped > 1000 and n_near > 0
    got = check_measurements(BAR, [(f"m{i}", *it[:2], it[2], it[3], it[4], it[5]) for i, it in enumerate(items)], R)
    ref = check_measurement("m3", BAR, FLAT, items[3][1], (), J0, R, moved, broad_phase=False)
    assert got[3].collisions and all(r.ok for r in got[:3])
    _same_check(got[3], ref)


def _longest_link_move(T_R_W, pl):
    """(the measurement's segments (R), the longest level segment of its link moves (the move across
    the bar at the clearance plane), that segment's middle sample (3,) R) of program ``pl`` on the
    bar at FLAT with the table at ``T_R_W``, as sim.mfb_scene.check_measurements samples its paths."""
    from sim import mfb_scene
    from sim.mfb_scene import _paths_of, link_points

    T_R_A = T_R_W @ FLAT
    Xn = A.apply_T(T_R_A, pl.w_A + R * pl.wn_A)
    start = Xn + pl.clearance_m * A.apply_R(T_R_A, pl.wn_A)
    top = float(mfb_scene.artefact_points(BAR)[:, 2].max()) + R
    L, cnt = link_points(T_R_A, start, pl.feature, pl.level, top)
    sg, _, _, is_app = _paths_of([(start, Xn, L, cnt, pl)], 3e-3, 0.5e-3)[0]
    link_seg = ~is_app[sg.path] & (sg.a[:, 2] == sg.b[:, 2]) & (sg.m > 2)
    j = np.flatnonzero(link_seg)[np.argmax(np.linalg.norm((sg.b - sg.a)[link_seg], axis=1))]
    return sg, j, sg.points(np.array([sg.first[j] + sg.m[j] // 2]))[0]


@pytest.mark.parametrize("gap_um", [3.0, -3.0, 150.0])
def test_a_near_miss_block_under_a_link_move_is_judged_as_mujoco_at_every_sample(gap_um):
    """Exactness of the plan check (sim.mfb_scene.check_measurements, what scenarios.mfb.check_plan
    calls) at a near miss: a workholder pillar 1 mm square whose top lies ``gap_um`` below the stylus
    ball's lowest point at one sample of a link move across the bar (the ball straight above it: the
    distance is the gap, a hand-worked answer). 3 um: inside the broad phase's margin (100 um), so
    MuJoCo judges it: no collision (the least clearance, reported at the approach starts, stays above 1 mm); -3 um: the ball
    sinks 3 um into it (far beyond MuJoCo's 1e-9 m tolerance): a collision with the pillar; 150 um:
    cleared by the broad phase. Each time beside two other measurements (a clear one and one whose
    arm crosses the bar) checked in the same pass, and each result equal to MuJoCo at every sample
    and every pair (broad_phase=False): collisions, path points, least clearance."""
    from sim import mfb_scene
    from sim.mfb_scene import Block, check_measurements

    T_R_W, J0, pl = _T_R_W(0, 0), (0, 0, 0.150), _holes(3, 4)
    _, _, p_R = _longest_link_move(T_R_W, pl)
    p_W = A.apply_T(A.inv_T(T_R_W), p_R[None])[0]
    top_W = p_W[2] - R - gap_um * 1e-6
    pillar = (Block("pillar", (p_W[0] - 0.5e-3, p_W[1] - 0.5e-3, 0.0), (p_W[0] + 0.5e-3, p_W[1] + 0.5e-3, top_W)),)
    items = [("near", FLAT, T_R_W, pillar, J0, pl, 0.0),
             ("clear", FLAT, _T_R_W(0, 90), (), J0, _holes(6), 0.0),
             ("arm", FLAT, T_R_W, (), (0.0, -0.100, 0.150), _holes(3), 0.0)]  # the arm across the bar
    mfb_scene._ZONES.clear()
    mfb_scene._BALLS.clear()
    got = check_measurements(BAR, items, R)
    ref = [check_measurement(it[0], BAR, *it[1:5], R, *it[5:], broad_phase=False) for it in items]
    _same_check(got, ref)
    near, clear, arm = got
    assert clear.ok and not arm.ok
    # the construction: MuJoCo's distance of the ball from the pillar at that sample is the gap (1e-12 m)
    import mujoco

    wz = mfb_scene._work_zone(BAR, FLAT, pillar, J0, R, 0.0)
    wz.set_table(T_R_W)
    wz.set_tip(p_R)
    d = mujoco.mj_geomDistance(wz.model, wz.data, wz._names.index("ball"), wz._names.index("fix_pillar"), 0.01, None)
    assert abs(d - gap_um * 1e-6) <= 1e-12
    assert near.ok == (gap_um > 0)
    if gap_um > 0:  # the least clearance is measured at the approach starts, not under the link move
        assert near.min_table_clearance_mm > 1.0
    if gap_um < 0:
        assert any("ball hits fix_pillar" in c for c in near.collisions), near.collisions


@pytest.mark.parametrize("gap_um", [3.0, -3.0, 150.0])
def test_a_pillar_touched_only_inside_a_link_move_by_the_extension_is_judged_as_mujoco_at_every_sample(gap_um):
    """Exactness of the plan check for a geom of the probe other than the ball (the rest broad phase,
    sim.mfb_scene.WorkZone.clearance(part="rest")) where only the inside of a swept segment comes near:
    a workholder pillar 1 mm square beside the longest level link move across the bar (along x_W or
    y_W), its near face
    ``gap_um`` from the side of the probe's vertical extension (a capsule of EXTENSION_R_M about the
    tip's vertical, 50-110 mm above the tip) at the move's middle sample, the pillar's top 80 mm above
    the tip (below the probe body, beside the stem and ball). Hand-worked: at that sample MuJoCo's
    distance extension-pillar is the gap (capsule against box: exact primitives); at the samples 3 mm
    either side it is about 0.6 mm, and at the segment's two ends (the link move's corners) more than
    10 mm, so a broad phase that bounded a segment by its ends, or skipped it because its ends are
    clear, misses it. -3 um: a collision of the extension with the pillar, reported; 3 um: no
    collision (MuJoCo judges it: inside the margin); 150 um: clear. Each time the result is MuJoCo's at
    every sample and every pair (broad_phase=False): collisions, path points, least clearance."""
    import mujoco

    from sim import mfb_scene
    from sim.mfb_scene import EXTENSION_R_M, Block, check_measurements

    T_R_W, J0, pl = _T_R_W(0, 0), (0, 0, 0.150), _holes(3, 4)
    sg, j, p_R = _longest_link_move(T_R_W, pl)
    W_R = A.inv_T(T_R_W)
    p_W, a_W, b_W = A.apply_T(W_R, np.array([p_R, sg.a[j], sg.b[j]]))
    u = (b_W - a_W) / np.linalg.norm(b_W - a_W)
    ax = int(np.argmax(np.abs(u[:2])))  # the move runs along x_W or y_W (the construction), the pillar beside it
    assert abs(u[ax]) == pytest.approx(1.0, abs=1e-12)
    # (standing on the bar's top face, W z = 80 mm on FLAT: from the table it would run through the bar,
    # which the check refuses, sim.mfb_scene.block_overlaps)
    lo, hi = np.array([0.0, 0.0, 0.080]), np.array([0.0, 0.0, p_W[2] + 0.080])
    lo[ax], hi[ax] = p_W[ax] - 0.5e-3, p_W[ax] + 0.5e-3
    hi[1 - ax] = p_W[1 - ax] - EXTENSION_R_M - gap_um * 1e-6  # the near face, beside the extension's side
    lo[1 - ax] = hi[1 - ax] - 1e-3
    pillar = (Block("pillar", tuple(lo), tuple(hi)),)
    items = [("near", FLAT, T_R_W, pillar, J0, pl, 0.0),
             ("clear", FLAT, _T_R_W(0, 90), (), J0, _holes(6), 0.0)]
    mfb_scene._ZONES.clear()
    mfb_scene._BALLS.clear()
    got = check_measurements(BAR, items, R)
    ref = [check_measurement(it[0], BAR, *it[1:5], R, *it[5:], broad_phase=False) for it in items]
    _same_check(got, ref)
    near, clear = got
    assert clear.ok
    wz = mfb_scene._work_zone(BAR, FLAT, pillar, J0, R, 0.0)
    wz.set_table(T_R_W)

    def dist(q_R):
        wz.set_tip(q_R)
        return mujoco.mj_geomDistance(wz.model, wz.data, wz._names.index("extension"), wz._names.index("fix_pillar"),
                                      0.05, None)

    assert abs(dist(p_R) - gap_um * 1e-6) <= 1e-12
    step = (sg.b[j] - sg.a[j]) / sg.k[j]
    assert min(dist(p_R - step), dist(p_R + step)) > 0.5e-3
    assert min(dist(sg.a[j]), dist(sg.b[j])) > 10e-3  # only the segment's inside comes near
    assert near.ok == (gap_um > 0)
    if gap_um < 0:
        assert near.collisions == ref[0].collisions and "extension hits fix_pillar" in near.collisions[0]


@pytest.mark.parametrize("collide", [False, True])
def test_unique_segments_are_numpys_unique_rows(monkeypatch, collide):
    """Known answer: the distinct rows (a, b, allowed feature) of segments, bit for bit, are those
    np.unique finds (first occurrences, in their order), -0.0 apart from 0.0 (another row), rows
    of round numbers (whose words end in zeros) and of random ones. With every hash equal
    (collide: the weights zeroed) the rows are told apart by comparison alone, with the same
    answer: a hash match is never taken for equality."""
    from sim import clearance
    from sim.clearance import unique_segments

    if collide:
        monkeypatch.setattr(clearance, "_HASH", np.zeros_like(clearance._HASH))
    rng = np.random.default_rng(3)
    a = rng.integers(0, 3, (3000, 3)).astype(float)
    b = np.where(rng.random((3000, 3)) < 0.5, rng.normal(size=(3000, 3)).round(1), 0.0)
    f = rng.integers(-2, 2, 3000)
    a[::7, 0] = -0.0  # (-0.0 == 0.0, other bits: another row)
    first, inv = unique_segments(a, b, f)
    rows = np.column_stack([a, b, f])
    bits = np.ascontiguousarray(rows).view(np.uint64)
    _, i0 = np.unique(bits, axis=0, return_index=True)
    assert np.array_equal(first, np.sort(i0))
    assert np.array_equal(bits[first][inv], bits)
    assert 100 < len(first) < 3000
    assert np.array_equal(unique_segments(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, int))[0], [])


def test_open_rows_are_the_segments_that_may_come_near():
    """Known answer of near_segments_many(samples=False): the ball moving 0.3 mm above the box (clear:
    0.2 mm beyond the margin) is not open, moving 0.05 mm above (within the 0.1 mm margin) and sinking
    1 mm into it are, and so is the closing point after the sinking move (left to its segment, which
    is open) but not the one after the clear move; the samples of the open rows are the near samples
    near_segments_many(samples=True) gives. Fails if open rows are taken from the samples (a clear
    sampling of an open segment) or the closing points are left clear."""
    from sim.clearance import near_segments_many, path_segments

    polys = [np.array([[-0.02, 0, R + z0], [0.02, 0, R + z1]]) for z0, z1 in
             ((0.3e-3, 0.3e-3), (0.05e-3, 0.05e-3), (5e-3, -1e-3))]
    sg = path_segments(polys, [1e-3] * 3, joints=False)
    clr = _sphere_over_box(0.0)
    parts = [(clr, sg, np.full(len(sg.a), -2))]
    got = near_segments_many(parts, samples=False)[0]
    assert got.tolist() == [False, False, True, True, True, True]  # (segment, closing point) x 3
    near = near_segments_many(parts)[0]
    assert np.array_equal(np.unique(sg.segment_of(near)), np.flatnonzero(got))


def _many_bases_rows(seed: int = 11):
    """Rows of three rest broad phases and the ball's for the box levels' tests: (bases, groups,
    cl0, lo, hi, allow) (test_broad_phases_at_once_are_each_broad_phase_alone says what)."""
    rng = np.random.default_rng(seed)
    zones = [WorkZone(BAR, FLAT, (), J, R) for J in ((0.0, 0.0, 0.08), (0.03, 0.0, 0.08))]
    bases = []
    for wz, (a_deg, c_deg) in ((zones[0], (0, 0)), (zones[0], (-30, 45)), (zones[1], (0, 90))):
        wz.set_table(_T_R_W(a_deg, c_deg))
        bases.append(wz.clearance(part="rest", moved=False))
    bases.append(zones[0]._ball_base())
    A_, B_, F_, P_, groups, pair0, cl0 = [], [], [], [], [], [0], [0]
    for k, c in enumerate(bases):
        n = int(rng.integers(40, 300)) | 1  # (odd: the last block of 16 not full)
        p = rng.integers(0, len(c.pair_probe), n)
        # a tip where the pair's probe geom sits on its table geom, give or take 2 mm, or anywhere near
        a = c.table.centre[c.pair_table[p]] - c.probe.centre[c.pair_probe[p]] + rng.normal(0, 2e-3, (n, 3))
        far = rng.random(n) < 0.5
        a[far] += rng.normal(0, 0.03, (int(far.sum()), 3))
        b = a + rng.normal(0, 3e-3, (n, 3))
        A_.append(a), B_.append(b), P_.append(p + pair0[-1])
        F_.append(rng.integers(-2, max(len(c._fid), 1), n))
        groups.append((k, sum(len(x) for x in A_[:-1]), sum(len(x) for x in A_)))
        pair0.append(pair0[-1] + len(c.pair_probe))
        cl0.append(cl0[-1] + len(c._cstart))
    a, b, allow, pair = map(np.concatenate, (A_, B_, F_, P_))
    pb = np.repeat(np.arange(len(bases)), [len(x) for x in A_])
    pad = np.array([bases[k].cert_pad_m for k in pb])[:, None]
    lo, hi = np.minimum(a, b) - pad, np.maximum(a, b) + pad
    return bases, groups, cl0, lo, hi, allow


def test_broad_phases_at_once_are_each_broad_phase_alone():
    """Known answer: near_segments_many's first box level for the rows of several broad phases at
    once (_block_candidates_many) is that of one broad phase at a time (Clearance._block_candidates),
    bit for bit and in the same order: three rest broad phases (two probes, three table poses,
    frame W) and the ball's (frame A), random rows around the bar, half of them through a pair's
    two geoms, allowed features at random, groups of rows that do not fill their last block."""
    from sim.clearance import _block_candidates_many

    bases, groups, cl0, lo, hi, allow = _many_bases_rows()
    # the first box level
    seg, cp = _block_candidates_many(groups, np.array(cl0), lo, hi, allow,
                                     np.concatenate([c._cloT for c in bases], axis=1),
                                     np.concatenate([c._chiT for c in bases], axis=1),
                                     np.concatenate([c._cballf for c in bases]))
    want = [c._block_candidates(lo[r0:r1], hi[r0:r1], allow[r0:r1]) for c, (_, r0, r1) in zip(bases, groups)]
    assert np.array_equal(seg, np.concatenate([s + r0 for (s, _), (_, r0, _) in zip(want, groups)]))
    assert np.array_equal(cp, np.concatenate([x + cl0[k] for k, (_, x) in enumerate(want)]))
    assert len(seg) > 1000


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_block_rows_are_the_first_two_box_levels(seed):
    """Known answer: the second box level done block by block (_block_candidates_many(rows=True),
    sim.clearance._block_rows; session 26) gives the (row, cluster) candidates of the first level
    (rows=False) that the second keeps (_overlap_rows, each row's box against its cluster's, as
    _pair_candidates did them): the same rows and clusters in the same order, on the rows of three
    rest broad phases and the ball's (_many_bases_rows: groups whose last block is not full,
    allowed features at random). Fails on a block's padding rows let through, a comparison
    changed (> for >=) or another order; tried: the valid-row mask left out fails here."""
    from sim.clearance import _block_candidates_many, _overlap_rows

    bases, groups, cl0, lo, hi, allow = _many_bases_rows(seed)
    cloT = np.concatenate([c._cloT for c in bases], axis=1)
    chiT = np.concatenate([c._chiT for c in bases], axis=1)
    cballf = np.concatenate([c._cballf for c in bases])
    seg, cp = _block_candidates_many(groups, np.array(cl0), lo, hi, allow, cloT, chiT, cballf)
    ok = _overlap_rows(lo.T.copy(), hi.T.copy(), seg, cloT, chiT, cp)
    got = _block_candidates_many(groups, np.array(cl0), lo, hi, allow, cloT, chiT, cballf, rows=True)
    assert np.array_equal(got[0], seg[ok]) and np.array_equal(got[1], cp[ok])
    assert 0 < len(got[0]) < len(seg)  # (the second level drops some candidates and keeps some)


def _old_block_rows(cut, end, blk, cp, lo, hi, allow, cloT, chiT, cballf):
    """sim.clearance._block_rows as it stood at 72703a3 (session 26): each hit's 16 rows gathered as
    (hits, 16, 3) boxes, six strided comparisons and the feature's, np.nonzero."""
    from sim.clearance import _BLOCK

    slot = cut[:, None] + np.arange(_BLOCK)
    valid = slot < end[:, None]
    slot = np.where(valid, slot, cut[:, None]).ravel()
    LB = lo.take(slot, axis=0).reshape(len(cut), _BLOCK, 3).take(blk, axis=0)
    HB = hi.take(slot, axis=0).reshape(len(cut), _BLOCK, 3).take(blk, axis=0)
    cl, ch = cloT.take(cp, axis=1), chiT.take(cp, axis=1)
    ok = valid.take(blk, axis=0)
    for ax in range(3):
        ok &= HB[:, :, ax] >= cl[ax][:, None]
        ok &= LB[:, :, ax] <= ch[ax][:, None]
    ok &= allow.take(slot).reshape(len(cut), _BLOCK).take(blk, axis=0) != cballf.take(cp)[:, None]
    h, j = np.nonzero(ok)
    return cut.take(blk.take(h)) + j, cp.take(h)


def _old_block_candidates_many(groups, cl0, lo, hi, allow, cloT, chiT, cballf, rows=False):
    """sim.clearance._block_candidates_many as it stood at 72703a3: the (block, near cluster) pairs
    by _expand's run numbers, both boxes gathered by them (_overlap_rows), then _old_block_rows."""
    from sim.clearance import _BLOCK, _expand, _overlap_rows

    g_b = np.array([g[0] for g in groups])
    g_r0 = np.array([g[1] for g in groups])
    g_r1 = np.array([g[2] for g in groups])
    nblk = (g_r1 - g_r0 + _BLOCK - 1) // _BLOCK
    gb = np.repeat(np.arange(len(groups)), nblk)
    b0 = np.cumsum(nblk) - nblk
    cut = g_r0[gb] + (np.arange(len(gb)) - b0[gb]) * _BLOCK
    b_lo, b_hi = np.minimum.reduceat(lo, cut, axis=0), np.maximum.reduceat(hi, cut, axis=0)
    a_lo, a_hi = np.minimum.reduceat(b_lo, b0, axis=0).T, np.maximum.reduceat(b_hi, b0, axis=0).T
    g_of = np.full(len(cl0) - 1, -1)
    g_of[g_b] = np.arange(len(groups))
    gc = np.repeat(g_of, np.diff(cl0))
    cl = np.flatnonzero(gc >= 0)
    gcl = gc[cl]
    near = (a_hi[0][gcl] >= cloT[0][cl]) & (a_lo[0][gcl] <= chiT[0][cl]) & (a_hi[1][gcl] >= cloT[1][cl]) \
        & (a_lo[1][gcl] <= chiT[1][cl]) & (a_hi[2][gcl] >= cloT[2][cl]) & (a_lo[2][gcl] <= chiT[2][cl])
    cl, gcl = cl[near], gcl[near]
    ncl = np.bincount(gcl, minlength=len(groups))
    blk, at = _expand((np.cumsum(ncl) - ncl)[gb], ncl[gb])
    cp = cl[at]
    hit = _overlap_rows(b_lo.T.copy(), b_hi.T.copy(), blk, cloT, chiT, cp)
    blk, cp = blk.take(hit), cp.take(hit)
    if rows:
        return _old_block_rows(cut, g_r1.take(gb), blk, cp, lo, hi, allow, cloT, chiT, cballf)
    seg = (cut.take(blk)[:, None] + np.arange(_BLOCK)).ravel()
    cp = np.repeat(cp, _BLOCK)
    ok = seg < np.repeat(g_r1[gb[blk]], _BLOCK)
    seg, cp = seg.compress(ok), cp.compress(ok)
    ok = cballf.take(cp) != allow.take(seg)
    return seg.compress(ok), cp.compress(ok)


@pytest.mark.parametrize("seed", [11, 12, 13, 14, 15])
def test_box_levels_are_the_old_code_paths(seed):
    """Known answer (session 27, perf27b): the box levels of near_segments_many as rewritten for
    speed (_block_candidates_many's (block, cluster) test on x then y and z, _block_rows on 1-D
    coordinate rows, _pair_candidates' segments by np.repeat) give what the code of 72703a3 gave
    (copied above): the same (row, cluster) and (row, pair) candidates, element for element and in
    the same order, with and without the row level, with and without the caller's transposed boxes,
    on the rows of three rest broad phases and the ball's (_many_bases_rows: groups whose last block
    is not full, allowed features at random, half the rows through a pair's geoms). Exact: integer
    answers of the same float comparisons. A third of the rows have a side exactly on a side of a
    cluster's or pair's box (ties): fails on a comparison changed (>= for >; tried: _block_rows' y
    fails on all five seeds, the first level's x on two) or another order (tried: _pair_candidates'
    segments reversed)."""
    from sim.clearance import _block_candidates_many, _expand, _overlap_rows, _pair_candidates

    bases, groups, cl0, lo, hi, allow = _many_bases_rows(seed)
    cloT = np.concatenate([c._cloT for c in bases], axis=1)
    chiT = np.concatenate([c._chiT for c in bases], axis=1)
    cballf = np.concatenate([c._cballf for c in bases])
    # ties: a third of the rows given a side exactly on a side of one of its base's cluster or pair
    # boxes (a row touching a box by a closed comparison: >= and <= tell it from > and <)
    rng = np.random.default_rng(seed + 100)
    for b, r0, r1 in groups:
        c = bases[b]
        for r in range(r0, r1):
            if rng.random() < 1 / 3:
                ax, j = int(rng.integers(3)), int(rng.integers(len(c._cstart)))
                if rng.random() < 0.5:
                    box = (c._cloT, c._chiT)
                else:  # (a pair of the cluster)
                    box, j = (c._loT, c._hiT), int(c._cstart[j] + rng.integers(c._ccount[j]))
                if rng.random() < 0.5:
                    hi[r, ax] = box[0][ax, j]
                    lo[r, ax] = min(lo[r, ax], hi[r, ax])
                else:
                    lo[r, ax] = box[1][ax, j]
                    hi[r, ax] = max(hi[r, ax], lo[r, ax])
    args = (groups, np.array(cl0), lo, hi, allow, cloT, chiT, cballf)
    for rows in (False, True):
        want = _old_block_candidates_many(*args, rows=rows)
        got = _block_candidates_many(*args, rows=rows)
        assert all(np.array_equal(x, y) for x, y in zip(got, want))
        assert len(want[0]) > 100
    got = _block_candidates_many(*args, rows=True, loT=lo.T.copy(), hiT=hi.T.copy())
    assert all(np.array_equal(x, y) for x, y in zip(got, want))
    # the pair level on the row level's candidates: _expand's run numbers and a gather (the old way)
    pair0 = np.cumsum([0] + [len(c.pair_probe) for c in bases])
    cstart = np.concatenate([c._cstart + pair0[b] for b, c in enumerate(bases)])
    ccount = np.concatenate([c._ccount for c in bases])
    loT = np.concatenate([c._loT for c in bases], axis=1)
    hiT = np.concatenate([c._hiT for c in bases], axis=1)
    seg, cp = want
    k, pair = _expand(cstart.take(cp), ccount.take(cp))
    s_old = seg.take(k)
    ok = _overlap_rows(lo.T.copy(), hi.T.copy(), s_old, loT, hiT, pair)
    got = _pair_candidates(lo.T.copy(), hi.T.copy(), seg, cp, cloT, chiT, cstart, ccount, loT, hiT, rows_done=True)
    assert np.array_equal(got[0], s_old.take(ok)) and np.array_equal(got[1], pair.take(ok))
    assert 0 < len(got[0]) < len(s_old)


@pytest.mark.parametrize("seed", [11, 12])
def test_swept_bounds_at_once_are_each_broad_phase_alone(seed):
    """Known answer (session 27, perf27b): sim.clearance._swept_many (the swept bounds of rows of
    several broad phases in one pass, as near_segments_many now asks them) is Clearance._swept of
    each broad phase's rows alone, as near_segments_many asked them at 72703a3 (one call per broad
    phase), bit for bit: three rest broad phases and the ball's, random (row, pair) rows in mixed
    order (a tip where the pair's geoms meet, give or take 2 mm, half of them moved up to ~3 cm), so
    that some rows are cleared by the first axis and others go on to the pairs' fixed axes. Fresh
    broad phases for each side (the fixed axes computed on demand by each), compared as uint64."""
    from sim.clearance import _swept_many

    def rows(bases, rng):
        n = 400
        pb = rng.integers(0, len(bases), n)
        pair = np.array([rng.integers(0, len(bases[k].pair_probe)) for k in pb])
        a = np.array([bases[k].table.centre[bases[k].pair_table[p]] - bases[k].probe.centre[bases[k].pair_probe[p]]
                      for k, p in zip(pb, pair)]) + rng.normal(0, 2e-3, (n, 3))
        far = rng.random(n) < 0.5
        a[far] += rng.normal(0, 0.03, (int(far.sum()), 3))
        return pb, pair, a, a + rng.normal(0, 3e-3, (n, 3))

    old_bases = _many_bases_rows(seed)[0]
    new_bases = _many_bases_rows(seed)[0]
    pb, pair, a, b = rows(old_bases, np.random.default_rng(seed))
    want = np.empty(len(pb))
    for k, clr in enumerate(old_bases):
        r = np.flatnonzero(pb == k)
        want[r] = clr._swept(a.take(r, axis=0), b.take(r, axis=0), pair[r])
    got = _swept_many(new_bases, pb, pair, a, b)
    assert np.array_equal(got.view(np.uint64), want.view(np.uint64))
    # (both kinds of rows: some pairs' fixed axes computed, fewer than the rows)
    assert 0 < sum(int(c._have.sum()) for c in new_bases) < len(pb)
    assert len(_swept_many(new_bases, pb[:0], pair[:0], a[:0], b[:0])) == 0


def test_pieces_are_np_split():
    """Known answer: sim.clearance._pieces gives np.split's views (the same rows, shapes and base)
    for cuts at the ends, repeated, as a list or an array, and no cut."""
    from sim.clearance import _pieces

    x = np.arange(36.0).reshape(12, 3)
    for cut in ([], [5], [0, 4, 4, 12], np.array([2, 7])):
        want, got = np.split(x, cut), _pieces(x, cut)
        assert len(got) == len(want)
        for g, w in zip(got, want):
            assert g.shape == w.shape and np.array_equal(g, w) and g.base is w.base is not None


def test_row_norm_is_numpys_norm_bit_for_bit():
    """Known answer and property: sim.clearance._row_norm (the paths' segment lengths, the unit
    axes of the swept bounds, the geoms' bounding radii; session 26) is np.linalg.norm(d, axis=-1)
    bit for bit: the squares summed as (x^2 + y^2) + z^2, numpy's order. Known answer: a row whose
    two orders of summation differ (1 and two squares of 0.6 ulp: 1 + 2 ulp against 1 + 1 ulp
    before the root) gives numpy's; property: random rows of magnitudes 1e-17 .. 1e17, shapes
    (n,3) and (n,7,3), C, Fortran and reversed strides, zeros. Fails with the sum in the other
    order (x^2 + (y^2 + z^2)) on the known row."""
    from sim.clearance import _row_norm

    u = np.finfo(float).eps  # (1 ulp of 1.0)
    y = np.sqrt(0.6 * u)
    row = np.array([[1.0, y, y]])
    numpy_order = np.sqrt((1.0 + y * y) + y * y)
    assert numpy_order != np.sqrt(1.0 + (y * y + y * y))  # (the row tells the two orders apart)
    assert _row_norm(row)[0] == numpy_order == np.linalg.norm(row, axis=-1)[0]
    rng = np.random.default_rng(3)
    for shape in ((1, 3), (644, 3), (2000, 3), (400, 7, 3), (0, 3)):
        x = rng.standard_normal(shape) * np.exp(rng.uniform(-40, 40, shape))
        x[rng.random(shape) < 0.1] = 0.0
        for v in (x, np.asfortranarray(x), x[::-1]):
            assert np.array_equal(_row_norm(v).view(np.uint64), np.linalg.norm(v, axis=-1).view(np.uint64))
