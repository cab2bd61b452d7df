"""Exact primitives and artefacts: known distances, normals, form errors, truth."""

import numpy as np
import pytest

from core.exceptions import ConfigError
from sim import artefacts as A
from sim.catalog import CATALOG, make_artefact


def test_plane_finite_face_distance_is_exact_to_the_prism():
    f = A.Plane((0, 0, 0), (0, 0, 1), (1, 0, 0), 0.01, 0.02)
    p = np.array([[0.005, 0.0, 0.003], [0.013, 0.0, 0.004], [0.013, 0.0, -0.004], [0.0, 0.0, -0.002]])
    # inside laterally: height; beside: Euclidean to the rim; below beside: lateral; inside: -depth
    np.testing.assert_allclose(A.Plane.sdf(f, p), [0.003, 0.005, 0.003, -0.002], atol=1e-15)
    np.testing.assert_allclose(f.normal(p)[0], [0, 0, 1])


def test_sphere_rod_hole_distances_and_normals():
    s = A.Sphere((0.1, 0.0, 0.0), 0.0127)
    np.testing.assert_allclose(s.sdf([[0.1, 0.02, 0.0]]), [0.02 - 0.0127], atol=1e-16)
    r = A.Rod((0, 0, 0), (0, 0, 1), 0.006, 0.01)
    np.testing.assert_allclose(r.sdf([[0.009, 0, 0.0], [0.008, 0, 0.014]]),
                               [0.003, np.hypot(0.002, 0.004)], atol=1e-16)
    h = A.Hole((0, 0, 0), (0, 0, 1), 0.008)
    np.testing.assert_allclose(h.sdf([[0.005, 0, 0.3]]), [0.003], atol=1e-16)
    np.testing.assert_allclose(h.normal([[0.005, 0, 0]])[0], [-1, 0, 0])


def test_pocket_prism_concave_corner_is_exact():
    pk = A.Prism(A.cross_outline(), material_inside=False)
    # near the concave corner (100, 18) mm: distance to the nearer of the two walls
    p = np.array([[97e-3, 16e-3, 0.0], [99e-3, 10e-3, 0.0], [0.0, 0.0, 0.0]])
    # the centre: nearest material is the convex corner (18, 18) mm
    np.testing.assert_allclose(pk.sdf(p), [2e-3, 1e-3, 18e-3 * np.sqrt(2)], atol=1e-15)
    # inside the material (beyond the end wall)
    assert pk.sdf([[0.105, 0.0, 0.0]])[0] == pytest.approx(-5e-3, abs=1e-15)


def test_form_error_displaces_the_surface_along_its_normal():
    f = A.Plane((0, 0, 0), (0, 0, 1), form=A.Offset(2e-6))
    assert f.sdf([[0.0, 0.0, 1e-3]])[0] == pytest.approx(1e-3 - 2e-6, abs=1e-18)
    w = A.Waviness(1e-6, 0.04, (1, 0, 0))
    q = np.array([[0.01, 0.0, 0.0]])
    assert w(q)[0] == pytest.approx(1e-6)


def test_mfb_counts_and_truth_displace_the_features():
    mfb = A.multi_feature_bar()
    kinds = [f.kind for f in mfb.features]
    assert kinds.count("hole") == 12 and kinds.count("rod") == 11 and kinds.count("plane") == 22
    E = mfb.info["E_MFB_m"]
    assert E[:, 0].min() == pytest.approx(-42e-6, abs=1e-9)  # positioning up to -42 um (paper Fig. 9)
    assert np.abs(E[:, 1:]).max() < 5e-6  # straightness a few um
    h12 = mfb.feature("hole12")
    assert np.asarray(h12.true.centre)[0] - np.asarray(h12.nominal.centre)[0] == pytest.approx(E[11, 0])
    assert mfb.info["support_spacing_m"] == pytest.approx(0.3211, abs=1e-4)  # eq. 1
    # mistake-proofing: two holes shifted off the x axis
    assert [f.name for f in mfb.features if f.kind == "hole" and f.nominal.centre[1] != 0] == ["hole02", "hole05"]


def test_mfb_invar_expansion():
    cold, warm = A.multi_feature_bar(temperature_C=20.0), A.multi_feature_bar(temperature_C=30.0)
    dx = warm.feature("hole12").true.centre[0] - cold.feature("hole12").true.centre[0]
    assert dx == pytest.approx(0.55 * 1e-6 * 10, rel=1e-3)  # 1 um/m/degC


def test_artefacts_build_and_mesh():
    for name in CATALOG:
        a = make_artefact(name)
        assert a.name == name  # the record's name is the artefact's (logs, plans)
        m = a.mesh()
        assert len(m.vertices) > 0 and np.all(np.isfinite(m.bounds))


def test_solids_points_are_each_solids_points_in_order():
    # issue 19: the stacked corners (one product for every box/cylinder) are the one-solid-at-a-time
    # ones bit for bit and in the same order, meshes (the freeform plate) kept in their place; an
    # axis-aligned box's corners are its centre +- its half sizes (written apart from solid_points)
    for name in CATALOG:
        sol = make_artefact(name).solids
        mixed = sol[::-1] + sol[:3]  # another order, meshes between boxes
        for s in (sol, mixed):
            assert A.solids_points(s).tobytes() == np.concatenate([A.solid_points(x) for x in s]).tobytes()
    b = A._box((0.125, -0.25, 0.0), (0.5, 0.375, 0.0625))  # binary fractions: centre +- half exact
    p = A.solids_points([b, b])
    assert p.shape == (16, 3)
    assert np.array_equal(p.min(axis=0), [0.125, -0.25, 0.0]) and np.array_equal(p.max(axis=0), [0.5, 0.375, 0.0625])


@pytest.mark.parametrize("bad", [np.zeros((11, 3)), np.full((12, 3), np.nan)])
def test_mfb_bad_deviations(bad):
    with pytest.raises(ConfigError, match="deviations_m"):
        A.multi_feature_bar(deviations_m=bad)


def test_unknown_artefact():
    with pytest.raises(ConfigError, match="unknown artefact 'ballplate'"):
        make_artefact("ballplate")


def test_grouped_sdf_matches_each_feature_alone():
    # issue 19: the batched distances (one pass per primitive kind) against each
    # feature's own sdf, over every catalogue artefact (planes, spheres, rods,
    # holes, prisms, form errors), points near and far, a finite rod's caps and
    # points on the axis (the fallback radial direction) included
    rng = np.random.default_rng(3)
    formed = [A.Rod((0.01, 0, 0), (0, 0.3, 1), 0.004, 0.005, A.Bump(2e-6, (0.01, 0.004, 0.005), 0.002)),
              A.Hole((0, 0.01, 0), (1, 0, 0), 0.006, A.AngularWaviness(1e-6, 3)),
              A.Plane((0, 0, 0.01), (0, 0.2, 1), (1, 0, 0), 0.003, 0.002, A.Waviness(1e-6, 0.004)),
              A.Sphere((0.02, 0.02, 0), 0.005, A.Offset(3e-6))]
    for name in list(CATALOG) + ["formed"]:
        if name == "formed":  # forms on every batched kind (the closest point matters)
            prims = formed
        else:
            art = make_artefact(name)
            prims = [f.true for f in art.features] + [f.nominal for f in art.features]
        funcs = [P.sdf for P in prims]
        group = rng.integers(0, len(funcs), 4000)
        anchor = np.array([prims[k].closest(np.zeros((1, 3)))[0] for k in range(len(prims))])
        p = anchor[group] + rng.normal(scale=rng.choice([1e-4, 3e-3, 3e-2], 4000)[:, None], size=(4000, 3))
        for k, P in enumerate(prims[:4]):
            if hasattr(P, "axis"):  # on the axis: the radial direction is undefined
                p[np.flatnonzero(group == k)[:2]] = np.asarray(P.centre)
        got = A.GroupedSdf(funcs)(group, p)
        want = np.empty(len(p))
        for k in range(len(funcs)):  # the path before: each feature on its own points
            want[group == k] = funcs[k](p[group == k])
        assert np.max(np.abs(got - want)) < 1e-15, name  # same formulas: rounding only (1e-15 m)
