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
