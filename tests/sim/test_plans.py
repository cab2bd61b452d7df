"""sim.plans.mfb_plan (built in numpy at once, cached) against the builder it replaced.

The oracle below is the former touch-by-touch builder, kept verbatim: the plans must be
equal bit for bit (target ids, features, contact points, normals, levels), on the
default bar, other bars (deviations, temperature, pose) and a bar with fewer holes.
"""

from dataclasses import replace

import numpy as np
import pytest

from core.exceptions import ConfigError
from core.units import MM
from sim import artefacts as A
from sim import plans as P


def _oracle_mfb_plan(art, clearance_m=2.0 * MM, overshoot_m=1.0 * MM):
    b = P._Builder()
    az = np.deg2rad([0.0, 90.0, 180.0, 270.0])
    n_holes = sum(1 for f in art.features if f.kind == "hole")
    for i in range(1, n_holes + 1):
        hole = art.feature(f"hole{i:02d}")
        c = np.asarray(hole.nominal.centre)
        R = hole.nominal.radius
        for lvl, z in (("u", 5.0 * MM), ("l", -5.0 * MM)):
            for k, a in enumerate(az):
                e = np.array([np.cos(a), np.sin(a), 0.0])
                b.add(f"hole{i:02d}_{lvl}{k}", hole.name, c + [0, 0, z] + R * e, -e, level=z)
        if i == n_holes:
            break
        rod = art.feature(f"rod{i:02d}")
        c = np.asarray(rod.nominal.centre)
        R = rod.nominal.radius
        for si, y in enumerate((-15.0 * MM, -7.5 * MM, 7.5 * MM, 15.0 * MM)):
            for k, a in enumerate(np.deg2rad([-45.0, 0.0, 45.0])):
                e = np.array([np.sin(a), 0.0, np.cos(a)])
                b.add(f"rod{i:02d}_s{si}_a{k}", rod.name, c + [0, y, 0] + R * e, e, level=1000 + si * 10 + k)
        for side in ("L", "R"):
            face = art.feature(f"face{side}{i:02d}")
            o = np.asarray(face.nominal.origin)
            nrm = np.asarray(face.nominal.normal_, float)
            for k, (dx, dz) in enumerate(((-8.0, -6.0), (8.0, -6.0), (8.0, 6.0), (-8.0, 6.0))):
                b.add(f"face{side}{i:02d}_p{k}", face.name, o + [dx * MM, 0, dz * MM], nrm, level=0.0)
    return b.plan(art.name, clearance_m, overshoot_m)


def _bars():
    yield A.multi_feature_bar()
    yield A.multi_feature_bar(deviations_m=np.zeros((12, 3)))
    rng = np.random.default_rng(7)
    yield A.multi_feature_bar(deviations_m=rng.normal(0, 20e-6, (12, 3)), temperature_C=23.5)
    T = np.eye(4)
    T[:3, 3] = (0.1, -0.2, 0.05)
    yield A.multi_feature_bar(T_W_A=T)
    full = A.multi_feature_bar()
    keep = {f"hole{i:02d}" for i in range(1, 6)} | {f"rod{i:02d}" for i in range(1, 5)} \
        | {f"face{s}{i:02d}" for s in "LR" for i in range(1, 5)}
    yield replace(full, features=tuple(f for f in full.features if f.name in keep))


def _same(a, b):
    assert (a.artefact, a.target, a.feature, a.clearance_m, a.overshoot_m) == \
        (b.artefact, b.target, b.feature, b.clearance_m, b.overshoot_m)
    for x, y in ((a.w_A, b.w_A), (a.wn_A, b.wn_A), (a.level, b.level)):
        assert x.shape == y.shape and x.dtype == y.dtype
        assert np.array_equal(x, y), np.abs(x - y).max()  # bit for bit (no -0/+0 or NaN here)


def test_mfb_plan_equals_the_touch_by_touch_builder_bit_for_bit():
    n = []
    for art in _bars():
        for cl, ov in ((2.0 * MM, 1.0 * MM), (2.0 * MM, 3.0 * MM), (4.5 * MM, 7.25 * MM)):
            P._MFB_PLANS.clear()
            _same(P.mfb_plan(art, clearance_m=cl, overshoot_m=ov), _oracle_mfb_plan(art, cl, ov))
        n.append(P.mfb_plan(art).n)
    assert n == [316, 316, 316, 316, 8 * 5 + 20 * 4]


def test_mfb_plan_cache_is_per_artefact_and_margins_and_read_only():
    P._MFB_PLANS.clear()
    a, b = A.multi_feature_bar(), A.multi_feature_bar(deviations_m=np.zeros((12, 3)))
    p = P.mfb_plan(a, clearance_m=2e-3, overshoot_m=3e-3)
    assert P.mfb_plan(a, clearance_m=2e-3, overshoot_m=3e-3) is p
    q = P.mfb_plan(a, clearance_m=2e-3, overshoot_m=4e-3)
    assert q is not p and q.overshoot_m == 4e-3
    _same(P.mfb_plan(b, clearance_m=2e-3, overshoot_m=3e-3), _oracle_mfb_plan(b, 2e-3, 3e-3))
    with pytest.raises(ValueError):
        p.w_A[0, 0] = 1.0  # a cached plan cannot be changed under its next user
    # a selection is a fresh, writable plan
    s = p.select([0, 1])
    s.w_A[0, 0] = 1.0
    assert p.w_A[0, 0] != 1.0


def test_mfb_plan_bad_input():
    art = A.multi_feature_bar()
    with pytest.raises(ConfigError, match="positive"):
        P.mfb_plan(art, clearance_m=0.0)
    with pytest.raises(ConfigError, match="positive"):
        P.mfb_plan(art, overshoot_m=-1e-3)
    no_rod = replace(art, features=tuple(f for f in art.features if f.name != "rod03"))
    with pytest.raises(ConfigError, match="no feature 'rod03'"):
        P.mfb_plan(no_rod)
