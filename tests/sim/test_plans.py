"""sim.plans.mfb_plan: the paper's 316 touches per full bar (Viprey 2016, 2.1), cached per
bar and margins, read-only when cached, and its bad input."""

from dataclasses import replace

import numpy as np
import pytest

from core.exceptions import ConfigError
from core.units import MM
from sim import artefacts as A
from sim import plans as P


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


def test_mfb_plan_has_the_papers_touches_per_bar():
    """316 touches on a 12-hole bar (12 holes x 8 + 11 rods x 12 + 22 faces x 4), 8 x 5 + 20 x 4
    on a 5-hole bar, whatever its deviations, temperature, pose or the margins."""
    n = []
    for art in _bars():
        for cl, ov in ((2.0 * MM, 1.0 * MM), (4.5 * MM, 7.25 * MM)):
            pl = P.mfb_plan(art, clearance_m=cl, overshoot_m=ov)
            assert (pl.clearance_m, pl.overshoot_m) == (cl, ov) and len(set(pl.target)) == pl.n
        n.append(P.mfb_plan(art).n)
    assert n == [316, 316, 316, 316, 8 * 5 + 20 * 4]


def test_mfb_plan_cache_is_per_artefact_and_margins_and_read_only():
    P._MFB_PLANS.clear()
    P._MFB_TOUCHES.clear()
    a, b = A.multi_feature_bar(), A.multi_feature_bar(deviations_m=np.zeros((12, 3)))
    p = P.mfb_plan(a, clearance_m=2e-3, overshoot_m=3e-3)
    assert P.mfb_plan(a, clearance_m=2e-3, overshoot_m=3e-3) is p
    q = P.mfb_plan(a, clearance_m=2e-3, overshoot_m=4e-3)
    assert q is not p and q.overshoot_m == 4e-3
    # the touches are built once per bar and shared by its plans at other margins; they are a
    # fresh build's at those margins bit for bit
    assert q.w_A is p.w_A and q.wn_A is p.wn_A and q.level is p.level and q.target is p.target
    ref = P._build_mfb_plan(a, 2e-3, 4e-3)
    assert (q.target, q.feature, q.clearance_m, q.overshoot_m) == (ref.target, ref.feature, 2e-3, 4e-3)
    assert all(x.tobytes() == y.tobytes() for x, y in ((q.w_A, ref.w_A), (q.wn_A, ref.wn_A), (q.level, ref.level)))
    assert P.mfb_plan(b, clearance_m=2e-3, overshoot_m=3e-3) is not p  # another bar object, its own plan
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
