"""core.chain and core.kinematics: parsing, analytic derivatives, eqs 10-12."""

import numpy as np
import pytest

from core import iso, kinematics as K
from core.chain import parse_chain
from core.exceptions import ConfigError


def test_parse_the_papers_chains():
    c = parse_chain("V[w-C-A-b-Y-X-Z-(C)-t]")
    assert (c.workpiece_axes, c.tool_axes, c.spindle) == (("C", "A"), ("Y", "X", "Z"), "C")
    assert c.workpiece_from_bed == ("A", "C") and c.parent("X") == "Y" and c.parent("A") is None
    c = parse_chain("[w C' A' b X Y Z (C1) t]")
    assert (c.workpiece_axes, c.tool_axes, c.spindle) == (("C", "A"), ("X", "Y", "Z"), "C1")
    c = parse_chain("V[w-X-Y-b-Z-(C)-t]")
    assert c.workpiece_axes == ("X", "Y") and c.tool_axes == ("Z",) and c.rotary_axes == ()
    assert c.sign("X") == -1 and c.sign("Z") == 1 and c.side("Y") == "workpiece"


@pytest.mark.parametrize("text, match", [
    ("w-X-b-Z-t", "expected"), ("[X-b-Z-t]", "start with 'w'"), ("[w-X-b-Z]", "end with 't'"),
    ("[w-X-Z-t]", "exactly one 'b'"), ("[w-X-b-X-t]", "appears twice"), ("[w-Q-b-Z-t]", "unknown token"),
    ("[w-(C)-b-Z-t]", "workpiece side"), ("[w-b-Z-(C)-(C1)-t]", "more than one spindle"),
])
def test_bad_chain(text, match):
    with pytest.raises(ConfigError, match=match):
        parse_chain(text)


GEOMS = [
    K.ChainGeometry.of("V[w-C-A-b-Y-X-Z-(C)-t]", (0.01, -0.02, 0.15), {"A": (0, 0, -0.1), "C": (0.01, 0.02, 0)}),
    K.ChainGeometry.of("[w C' A' b X Y Z (C1) t]", (0.0, 0.0, 0.12), {"A": (0, 0.05, -0.12)}),
    K.ChainGeometry.of("V[w-X-Y-b-Z-(C)-t]", (0.0, 0.0, 0.15)),
    K.ChainGeometry.of("H[w-B-Z-b-X-Y-t]", (0.0, 0.15, 0.0), {"B": (0.0, 0.0, 0.2)}),
]


def _random(geom, rng, n=6, scale=1e-4):
    lin = rng.uniform(-0.3, 0.3, (n, 3))
    rot = rng.uniform(-1.5, 1.5, (n, len(geom.chain.rotary_axes)))
    vals = {s: rng.normal(0, scale, n) for s in K.error_symbols(geom.chain)}
    return lin, rot, vals


@pytest.mark.parametrize("geom", GEOMS, ids=lambda g: g.chain.text)
def test_nominal_is_identity_at_rotary_zero(geom, rng):
    lin, rot, _ = _random(geom, rng)
    assert np.abs(K.tip_W(geom, lin, np.zeros_like(rot)) - lin).max() < 1e-15


@pytest.mark.parametrize("geom", GEOMS, ids=lambda g: g.chain.text)
def test_sensitivity_and_axis_jacobian_match_finite_differences(geom, rng):
    """Analytic at non-zero errors (large ones, 0.01 rad, so J_l matters).
    Central differences, h = 1e-6: truncation ~h^2 * 1 m, round-off ~1e-16/h."""
    lin, rot, vals = _random(geom, rng, scale=1e-2)
    syms = K.error_symbols(geom.chain)
    S = K.sensitivity(geom, lin, rot, vals)
    h = 1e-6
    for j, s in enumerate(syms):
        up, dn = dict(vals), dict(vals)
        up[s], dn[s] = vals[s] + h, vals[s] - h
        fd = (K.tip_W(geom, lin, rot, up) - K.tip_W(geom, lin, rot, dn)) / (2 * h)
        assert np.allclose(S[:, :, j], fd, rtol=0, atol=1e-9), s
    Ja = K.jacobian_axes(geom, lin, rot, vals)
    for j in range(Ja.shape[2]):
        dl, dr = np.zeros_like(lin), np.zeros_like(rot)
        (dl if j < 3 else dr)[:, j if j < 3 else j - 3] = h
        fd = (K.tip_W(geom, lin + dl, rot + dr, vals) - K.tip_W(geom, lin - dl, rot - dr, vals)) / (2 * h)
        assert np.allclose(Ja[:, :, j], fd, rtol=0, atol=1e-9), j


def test_mfb_deviation_known_answers():
    p = np.array([[0.1, 0.2, 0.3]])
    J = (0.01, 0.02, 0.15)
    assert np.allclose(K.mfb_deviation({"EXX": 5e-6}, p, J_m=J), [[-5e-6, 0, 0]])
    # squareness: + EC0Y * F in X (F = y), + EC0Y * J_X in Y (eq. 11)
    assert np.allclose(K.mfb_deviation({"EC0Y": 1e-5}, p, J_m=J), [[1e-5 * 0.2, 1e-5 * 0.01, 0]])
    # EBZ: + EBZ J_Z in X, - EBZ J_X in Z
    assert np.allclose(K.mfb_deviation({"EBZ": 1e-5}, p, J_m=J), [[1e-5 * 0.15, 0, -1e-5 * 0.01]])
    with pytest.raises(ConfigError, match="21 linear-axis errors only"):
        K.mfb_deviation({"EX0C": 1e-6}, p)


def test_bad_values_shape():
    g = GEOMS[2]
    with pytest.raises(ConfigError, match="has shape"):
        K.tip_W(g, np.zeros((3, 3)), None, {"EXX": np.zeros(4)})
    with pytest.raises(ConfigError, match="unknown ISO error symbol"):
        K.sensitivity(g, np.zeros((3, 3)), None, None, ["EQQ"])


@pytest.mark.parametrize("name", ["vmc-3axis", "mikron-ucp710", "nmv3000"])
def test_per_pose_probe_offsets(name, rng):
    """Several styli in one call (``J_m`` per pose, as the volumetric identification batches its
    measurements): each pose is bit for bit the per-stylus call, and equals Pinocchio's chain
    (sim, independent of core) built with that stylus, to 1e-12 m (rounding of ~10 products),
    with errors of 1 mm / 0.05 rad so that no offset can hide behind a small angle."""
    from dataclasses import replace

    from sim.errorfuncs import Constant
    from sim.machine import Machine
    from sim.machines import MACHINES

    cfg = MACHINES[name]()
    chain_axes = Machine(cfg).chain.axes
    big = {s.name: Constant(rng.uniform(-1, 1) * (0.05 if s.angular else 1e-3)) for s in iso.SYMBOLS
           if s.axis in chain_axes and not (s.location and s.axis in iso.LINEAR_AXES
                                            and s.name not in iso.SQUARENESS)}
    styli = [(0.0, 0.0, 0.0), (0.0, -0.1, 0.25), (-0.1, 0.0, 0.19)]  # no offset, a star arm, a finger
    machines = [Machine(replace(cfg, J_m=J)).with_errors(big) for J in styli]
    n = 30
    lin = np.column_stack([rng.uniform(*cfg.strokes[a], n) for a in "XYZ"])
    rot = np.column_stack([rng.uniform(*cfg.strokes[a], n) for a in machines[0].rotary_axes]) \
        if machines[0].rotary_axes else None
    which = rng.integers(0, 3, n)
    which[:3] = (0, 1, 2)
    J = np.asarray(styli)[which]
    vals = machines[0].error_values(lin, rot)
    geom = machines[0].geometry()
    tip = K.tip_W(geom, lin, rot, vals, J_m=J)
    S = K.sensitivity(geom, lin, rot, vals, J_m=J)
    for k, m in enumerate(machines):
        rows = which == k
        r = None if rot is None else rot[rows]
        v = {s: a[rows] for s, a in vals.items()}
        assert np.array_equal(tip[rows], K.tip_W(m.geometry(), lin[rows], r, v))
        assert np.array_equal(S[rows], K.sensitivity(m.geometry(), lin[rows], r, v))
        assert np.abs(tip[rows] - m.tip_W_pinocchio(lin[rows], r)).max() < 1e-12
    with pytest.raises(ConfigError, match=r"J_m must be finite \(n, 3\)"):
        K.tip_W(geom, lin, rot, vals, J_m=J[:-1])
    with pytest.raises(ConfigError, match=r"J_m must be finite \(n, 3\)"):
        K.sensitivity(geom, lin, rot, vals, J_m=np.full((n, 3), np.nan))
