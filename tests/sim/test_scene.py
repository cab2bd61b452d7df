"""MuJoCo scene: analytic distances agree with the exact primitives; crashing paths refused."""

import numpy as np
import pytest

from core.exceptions import PlanError
from sim import artefacts as A
from sim.probe import ProbeConfig
from sim.scene import Scene, check_touch_paths

pytest.importorskip("mujoco")
R = 3e-3


def _stylus_distance(scene, p_R, geom):
    scene.set_tip(p_R)
    return scene.geom_distance("stylus", geom)


def test_mujoco_distances_match_exact_primitives_to_1nm():
    rng = np.random.default_rng(3)
    art = A.pin_circle()
    scene = Scene(art, ProbeConfig())
    T = art.T_W_A
    checks = 0
    for f in art.features:
        k = next(i for i, s in enumerate(art.solids) if s.feature == f.name and s.exact)
        geom = f"{f.name}__{k}"
        for _ in range(5):
            # points 0.5..4 mm outside the surface near the probed height
            if f.kind == "sphere":
                e = rng.normal(size=3)
                e /= np.linalg.norm(e)
                p_A = np.asarray(f.nominal.centre) + (f.nominal.radius + R + rng.uniform(0.5e-3, 4e-3)) * e
            else:
                a = rng.uniform(0, 2 * np.pi)
                c = np.asarray(f.nominal.centre)
                p_A = c + [(f.nominal.radius + R + rng.uniform(0.5e-3, 4e-3)) * np.cos(a),
                           (f.nominal.radius + R + rng.uniform(0.5e-3, 4e-3)) * np.sin(a), rng.uniform(-5e-3, 5e-3)]
            exact = f.nominal.sdf(p_A[None])[0] - R
            got = _stylus_distance(scene, A.apply_T(T, p_A[None])[0], geom)
            assert abs(got - exact) < 1e-9, (f.name, got, exact)
            checks += 1
    assert checks == 100


def test_box_face_distance_matches_plane_primitive():
    art = A.multi_feature_bar()
    scene = Scene(art, ProbeConfig())
    f = art.feature("faceR03")
    k = next(i for i, s in enumerate(art.solids) if s.feature == f.name)
    for dx, dz, h in ((0.0, 0.0, 1e-3), (8e-3, 6e-3, 2.5e-3), (-10e-3, -4e-3, 0.7e-3)):
        p_A = np.asarray(f.nominal.origin) + [dx, h + R, dz]
        got = _stylus_distance(scene, A.apply_T(art.T_W_A, p_A[None])[0], f"{f.name}__{k}")
        assert abs(got - (f.nominal.sdf(p_A[None])[0] - R)) < 1e-9


def test_hole_surroundings_are_conservative():
    """The 16-gon of boxes contains all the material: inscribed in the hole."""
    art = A.multi_feature_bar()
    scene = Scene(art, ProbeConfig())
    c = np.asarray(art.feature("hole04").nominal.centre)
    # stylus touching the true hole wall collides with the polygon (never misses material)
    p_A = c + [A.HOLE_R_M - R, 0.0, 0.0]
    hits = scene.collisions(A.apply_T(art.T_W_A, p_A[None])[0])
    assert any(h[1].startswith("hole04") for h in hits)
    # ...and is allowed when hole04 is the touch's own feature
    assert scene.collisions(A.apply_T(art.T_W_A, p_A[None])[0], allow_feature="hole04") == []


def test_crashing_path_is_refused_naming_setup_and_target():
    art = A.cross_pocket()
    scene = Scene(art, ProbeConfig())
    scene.set_table(np.eye(4))
    z = art.T_W_A[2, 3] - 3e-3
    # a straight link across the convex corner (18, 18) mm of the cross: crashes
    link = np.array([[0.0225, 0.013, z], [0.013, 0.0225, z]])
    approach = np.array([[[0.013, 0.0225, z], [0.013, 0.020, z]]])
    with pytest.raises(PlanError, match=r"set-up 'C0' target 'wall02_0': link move crashes"):
        check_touch_paths(scene, "C0", ["wall02_0"], ["pocket"], [link], approach)
    # the approach itself into another feature: refused too
    approach = np.array([[[0.0, 0.0, 0.06], [0.06, 0.06, 0.06]]])
    with pytest.raises(PlanError, match=r"target 'x': approach/retract path crashes: stylus hits sphere1"):
        check_touch_paths(scene, "C0", ["x"], ["pocket"], [None], approach)


def test_a_passed_path_check_is_not_run_twice_and_a_crash_always_is(monkeypatch):
    """Checks are memoised on the scene's MJCF, the table pose and the paths (issue 19): the same
    check again samples nothing; a moved table or path samples again; a crash is never stored."""
    from sim.clearance import Clearance

    art = A.cross_pocket()
    scene = Scene(art, ProbeConfig())
    calls = []
    real = Clearance.near_segments
    monkeypatch.setattr(Clearance, "near_segments",
                        lambda self, sg, *a, **k: calls.append(sg.n_samples) or real(self, sg, *a, **k))
    z = art.T_W_A[2, 3] + 0.02  # 20 mm above the artefact's base: clear of the pocket's floor
    top = art.T_W_A[2, 3] + 0.08
    links = [np.array([[0.0, 0.0, top], [0.0, 0.0, z]])]
    approach = np.array([[[0.0, 0.0, z], [0.0, 0.001, z]]])
    scene.set_table(A.make_T(np.eye(3), [0.3, 0.0, 0.0]))
    check_touch_paths(scene, "C0", ["t"], ["pocket"], links, approach)
    n_first = len(calls)
    assert n_first == 1 and calls[0] > 10  # one broad phase over every sample
    check_touch_paths(scene, "C1", ["other name"], ["pocket"], links, approach)  # names do not matter
    assert len(calls) == n_first
    scene.set_table(A.make_T(np.eye(3), [0.3, 1e-6, 0.0]))  # table moved by 1 um: checked again
    check_touch_paths(scene, "C0", ["t"], ["pocket"], links, approach)
    assert len(calls) == 2 * n_first
    check_touch_paths(scene, "C0", ["t"], ["pocket"], links, approach + [0, 0, 1e-9])  # path moved
    assert len(calls) == 3 * n_first
    scene.set_table(np.eye(4))
    crash = np.array([[[0.0, 0.0, 0.0], [0.06, 0.06, 0.06]]])
    for _ in range(2):
        with pytest.raises(PlanError, match="approach/retract path crashes"):
            check_touch_paths(scene, "C0", ["x"], ["pocket"], [None], crash)


def test_a_scene_moved_to_a_placement_is_the_scene_compiled_there():
    """Scene.place (no recompilation) against a scene compiled at that placement: the same geom
    poses to rounding and the same collisions at random tips around the bar (issue 19)."""
    art = A.multi_feature_bar()
    rng = np.random.default_rng(8)
    T_B = A.make_T(A.rot_z(0.7) @ A.rot_x(0.3), (0.05, -0.02, 0.11))
    moved = Scene(art, ProbeConfig())
    moved.place(T_B)
    fresh = Scene(art, ProbeConfig(), T_B)
    T_R_W = A.make_T(A.rot_z(-0.4), (0.01, 0.02, 0.0))
    for sc in (moved, fresh):
        sc.set_table(T_R_W)
        sc.set_tip(np.zeros(3))
    assert np.abs(moved.data.geom_xpos - fresh.data.geom_xpos).max() < 1e-15
    assert np.abs(moved.data.geom_xmat - fresh.data.geom_xmat).max() < 1e-15
    tips = A.apply_T(T_R_W @ T_B, rng.uniform([-0.02, -0.02, -0.01], [0.38, 0.06, 0.05], (300, 3)))
    got = [moved.collisions(p) for p in tips]
    want = [fresh.collisions(p) for p in tips]
    # the same contacts in the same order; depths to rounding (quaternions normalised apart)
    assert [[c[:2] for c in g] for g in got] == [[c[:2] for c in w] for w in want]
    assert max(abs(a[2] - b[2]) for g, w in zip(got, want) for a, b in zip(g, w)) < 1e-15
    assert sum(bool(g) for g in got) > 20
