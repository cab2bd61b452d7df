"""The self-calibration's analytic null space and gauge with the C axis off x = y = 0 (exact simulator).

``core.selfcal``'s null directions "workpiece rotation" and "scale" are taken
about the C axis (module docstring, "Null space and gauge"): with the axis at
(cx, cy) they move every set-up's EXC/EYC,total by -phi R90 c and -s c. The
paper's columns (about R's origin) left |A N| at 0.04 with C at (22, 0) mm,
so ``to_gauge(truth)`` was not the identification's gauge there.

Tolerances. |A N|: 1e-14 (the entries of A and N are O(1) per unit
parameter, |A||N| <= 2.2 here; each product sums <= 12 terms, so rounding
leaves a few 1e-16; main's 0.04 is 13 orders above). Closed loop: the
identification is first order, the simulator exact; the terms it leaves out
are of order e^2 / L (errors of ~10 um and 20 urad over the pocket's 0.1 m
lever: ~1 nm), so 0.01 um on lengths and G, 0.05 urad on EC0Y and ECC (0.01
um over the 0.2 m between the grid's end nodes; measured <= 0.004 um, 0.007
urad). ECY is not compared: its end nodes are seen by few touches (0.10 urad
off at (22, 0) mm, 0.04 at (-35, 15) mm, main and branch alike). Main's gauge
puts EXC,total 2.05 um and EYC,total 1.06 um away at (22, 0) mm (3.45, 2.28
at (-35, 15) mm) and leaves |A N| at 0.041 (0.073).
"""

from __future__ import annotations

import numpy as np
import pytest

from core.units import UM, URAD

C_POSITIONS_M = [(0.022, 0.0, 0.0), (-0.035, 0.015, 0.0)]


def _campaign(c_point):
    from core.touches import from_log
    from scenarios.crosspocket import CROSS_ANGLES_DEG
    from sim import artefacts as A
    from sim.campaign import simulate_campaign
    from sim.catalog import make_plan
    from sim.errorfuncs import Constant, Polynomial
    from sim.machine import Machine
    from sim.machines import MACHINES
    from sim.probe import ProbeConfig

    errs = {"EXX": Polynomial((3 * UM, 50e-6)), "EYY": Polynomial((0.0, -30e-6)), "EC0Y": Constant(20 * URAD),
            "EX0C": Constant(5 * UM), "EY0C": Constant(-4 * UM)}
    machine = Machine(MACHINES["nmv3000"](errors=errs, rotary_points_R_m={"C": c_point}))
    art = A.cross_pocket()
    plan = make_plan(art)
    log = simulate_campaign(art, machine, ProbeConfig(repeatability_k2_m=0.0), list(CROSS_ANGLES_DEG),
                            np.random.default_rng(0), plan=plan, check_collisions=False)
    return from_log(log.select(np.abs(log.col("nz")) < 0.01)), machine, art, plan


def _grid(t):
    """11 x 11 nodes over the touches' extent: every node seen by touches both ways (a grid of multiples of
    22 or 44 mm leaves an ECY end node unseen with C at (-35, 15) mm: a 12th null direction, whatever the gauge)."""
    from core.selfcal import Grid

    p = t.pn_R
    return Grid(np.linspace(p[:, 0].min(), p[:, 0].max(), 11), np.linspace(p[:, 1].min(), p[:, 1].max(), 11))


@pytest.fixture(scope="module", params=C_POSITIONS_M, ids=lambda c: f"C({c[0] * 1e3:g},{c[1] * 1e3:g})mm")
def case(request):
    return (request.param, *_campaign(request.param))


@pytest.mark.parametrize("heights", [False, True])
def test_null_space_is_exact_and_complete_off_axis(case, heights):
    from scipy.linalg import null_space

    from core.selfcal import build_design

    _, t, *_ = case
    des = build_design(t, _grid(t), heights=heights)
    A = des.A.toarray()
    assert np.max(np.abs(A @ des.N)) < 1e-14
    sc = np.linalg.norm(A, axis=0)
    sc[sc == 0] = 1.0
    assert null_space(A / sc).shape[1] == des.N.shape[1]       # no null direction missed, none extra
    assert np.linalg.matrix_rank(des.N) == des.N.shape[1]
    assert np.linalg.matrix_rank(des.C @ des.N) == des.N.shape[1]  # the gauge fixes every one


def test_c_axis_read_from_the_touches(case):
    """The axis's position from the nominal positions alone (to rounding: 1e-12 m against 0.1 m positions)."""
    from core.selfcal import c_axis_xy

    c_point, t, *_ = case
    c_rad = np.array([t.rot_rad[t.setup == j, 2][0] for j in range(len(t.setup_ids))])
    np.testing.assert_allclose(c_axis_xy(t, c_rad), c_point[:2], rtol=0, atol=1e-12)
    one = t.setup == 0  # one angle: nothing places the axis
    assert c_axis_xy(_subset(t, one), c_rad[:1]) == (0.0, 0.0)


def _subset(t, keep):
    import dataclasses

    fields = {f.name: getattr(t, f.name) for f in dataclasses.fields(t)}
    out = {k: (v[keep] if isinstance(v, np.ndarray) and v.shape[:1] == keep.shape else v) for k, v in fields.items()}
    out["temps_C"] = {k: v[keep] for k, v in t.temps_C.items()}
    out["setup_ids"] = t.setup_ids[:1]
    return type(t)(**out)


def test_noise_free_identification_is_the_truth_in_the_gauge_off_axis(case):
    from core.selfcal import self_calibrate
    from scenarios.hidden import workpiece_truth
    from scenarios.selfcal_coverage import machine_truth

    _, t, machine, art, plan = case
    res = self_calibrate(t, _grid(t), model_error=False, heights=False)
    des = res.design
    raw = machine_truth(machine, des, float(np.median(t.pn_R[:, 2])))[0]
    g = workpiece_truth(art, plan)
    raw[des.slices["G"]] = [g[k] for k in des.target_ids]
    truth = des.to_gauge(raw)
    np.testing.assert_allclose(des.A @ truth, des.A @ raw, rtol=0, atol=1e-15)  # the gauge moves nothing seen
    d = res.theta - truth
    s = des.slices
    for blk in ("EXX", "EYX", "EXY", "EYY", "G", "EXC", "EYC"):
        assert np.max(np.abs(d[s[blk]])) < 0.01 * UM, blk
    for blk in ("EC0Y", "ECC"):
        assert np.max(np.abs(d[s[blk]])) < 0.05 * URAD, blk
