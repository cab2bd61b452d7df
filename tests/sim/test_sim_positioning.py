"""An ISO 230-2 test on the virtual machine: schedule, exact readings, closed loops.

Tolerances: the chain is exact (transform products of O(1 m) round to a
few 1e-16 m), so readings are compared with the error functions evaluated
directly, or with core's independent kinematic model, at 1e-12 m
(1e-9 mm). Statistical checks state their bounds in the test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from core import kinematics as K
from core.exceptions import ConfigError
from core.positioning import arrange, baseline, iso230_2
from sim.errorfuncs import Drift, Polynomial, Reversal
from sim.machine import Machine
from sim.machines import MACHINES, realistic_errors
from sim.positioning import (deviations_m, iso_targets, positioning_plan, schedule,
                             simulate_positioning)

MM = 1e-3
EXACT_M = 1e-12


@pytest.fixture(scope="module")
def vmc():
    return Machine(MACHINES["vmc-3axis"]())


def test_linear_cycle_schedule_by_hand(vmc):
    # targets 0, 10, 30 mm; overrun 5 mm; 10 mm/s; dwell 1 s; start at -5 mm.
    # up:   -5->0 0.5 s, +1 -> 1.5 | 0->10 1 s -> 2.5, +1 -> 3.5 | 10->30 2 s -> 5.5, +1 -> 6.5
    # overrun 30->35 0.5 s -> 7.0
    # down: 35->30 0.5 -> 7.5, +1 -> 8.5 | 30->10 2 -> 10.5, +1 -> 11.5 | 10->0 1 -> 12.5, +1 -> 13.5
    # back to -5: 0.5 -> 14.0: the next cycle repeats 14 s later.
    plan = positioning_plan(vmc, "X", targets_m=[0, 0.010, 0.030], cycles=2, overrun_m=5 * MM,
                            feed_mps=10 * MM, dwell_s=1.0)
    s = schedule(plan)
    first = [1.5, 3.5, 6.5, 8.5, 11.5, 13.5]
    np.testing.assert_allclose(s["t_s"], first + [t + 14 for t in first], rtol=0, atol=1e-12)
    assert s["direction"].tolist() == [1, 1, 1, -1, -1, -1] * 2
    assert s["target_index"].tolist() == [0, 1, 2, 2, 1, 0] * 2
    assert s["cycle"].tolist() == [1] * 6 + [2] * 6


def test_pilgrim_cycle_schedule_by_hand(vmc):
    # at 0: -5->0 0.5 +1 -> 1.5 (+, j1) | ->5 0.5 -> 2.0 | ->0 0.5 +1 -> 3.5 (-, j1)
    #       ->-5 0.5 -> 4.0 | ->0 0.5 +1 -> 5.5 (+, j2) | ->5 -> 6.0 | ->0 +1 -> 7.5 (-, j2)
    # at 10: 0->5 0.5 -> 8.0 | ->10 0.5 +1 -> 9.5 (+, j1) ...
    plan = positioning_plan(vmc, "X", targets_m=[0, 0.010], cycles=2, cycle_kind="pilgrim",
                            overrun_m=5 * MM, feed_mps=10 * MM, dwell_s=1.0)
    s = schedule(plan)
    np.testing.assert_allclose(s["t_s"][:5], [1.5, 3.5, 5.5, 7.5, 9.5], rtol=0, atol=1e-12)
    assert s["direction"].tolist() == [1, -1] * 4
    assert s["cycle"].tolist() == [1, 1, 2, 2] * 2
    assert s["target_index"].tolist() == [0, 0, 0, 0, 1, 1, 1, 1]


def test_iso_targets_irregular_inside_the_travel(rng):
    P = iso_targets(-0.25, 0.25, 11, rng)
    p = 0.05
    assert P[0] == -0.25 and P[-1] == 0.25 and np.all(np.diff(P) > 0)
    assert np.all(np.abs(P - (-0.25 + p * np.arange(11))) <= p / 4 + 1e-12)
    assert len(set(np.round(np.diff(P), 9))) > 5  # irregular spacing
    np.testing.assert_array_equal(np.round(P / 1e-6), P / 1e-6)  # commanded to 1 um


@pytest.mark.parametrize("axis,sym,sign", [("X", "EXX", +1.0), ("Z", "EZZ", +1.0)])
def test_scale_error_and_reversal_read_exactly(axis, sym, sign):
    """Only a positioning error and lost motion on the axis: the reading is E exactly.

    Error values are ISO 230-1's, the tool relative to the part, whichever
    side of the bed the axis is on: X of vmc-3axis moves the table, Z the
    spindle, both read +E. Reversal gives +L/2 moving in +, -L/2 in -.
    The targets are readings (the stylus-tip centre the controller commands,
    its probe offset J in effect); the error read there is the one at the
    axis position P + J (session 27: Z's 150 mm probe reads E(P + 150 mm),
    6 um more than E(P) with this 40 um/m slope; X's J_x = 0).
    """
    L = 3e-6
    f = Polynomial((2e-6, 40e-6))  # 2 um + 40 um/m
    m = Machine(MACHINES["vmc-3axis"](errors={sym: f + Reversal(L)}))
    plan = positioning_plan(m, axis, n_targets=6, cycles=3)
    log = simulate_positioning(m, plan, np.random.default_rng(0))
    P = log.target * MM + m.config.J_m["XYZ".index(axis)]  # the axis positions
    assert m.config.J_m == (0.0, 0.0, 0.150)
    expect_mm = sign * (f(P) + 0.5 * L * log.direction) / MM
    np.testing.assert_allclose(log.deviation, expect_mm, rtol=0, atol=EXACT_M / MM)
    r = iso230_2(log)
    assert abs(r.B - L / MM) < 1e-9 and abs(r.B_mean - sign * L / MM) < 1e-9
    assert r.R == pytest.approx(L / MM, abs=1e-9)  # s = 0: R_i = |B_i|
    span = 40e-6 * (P.max() - P.min()) / MM
    assert r.M == pytest.approx(span, abs=1e-9) and r.E == pytest.approx(span + L / MM, abs=1e-9)


def test_drift_follows_the_clock():
    """Thermal drift of 1 um per minute on EXX: every reading is -(EXX(P) + rate t) at its t_s.

    The machine of the old convention (the table's carriage error f + drift on
    the table-side X) given in ISO 230-1 values (the tool relative to the
    part): the injected error negated, the readings unchanged."""
    rate = 1e-6 / 60
    f = Polynomial((0.0, 20e-6))
    m = Machine(MACHINES["vmc-3axis"](errors={"EXX": Polynomial((0.0, -20e-6)) + Drift(offset_rate=-rate)}))
    plan = positioning_plan(m, "X", n_targets=5, cycles=5)
    log = simulate_positioning(m, plan, np.random.default_rng(0))
    expect_mm = -(f(log.target * MM) + rate * log.t_s) / MM
    np.testing.assert_allclose(log.deviation, expect_mm, rtol=0, atol=EXACT_M / MM)
    # the standard's model sees drift as scatter: s grows with the cycle period
    b = baseline(arrange(log))
    assert b.s_up_pooled > 0 and np.all(np.diff(log.t_s) > 0)


def test_realistic_errors_agree_with_core_model(vmc):
    """All 21 realistic errors (Abbe offsets at the measuring line included),
    sim's Pinocchio chain against core's own transform product."""
    cfg = MACHINES["vmc-3axis"]()
    m = vmc.with_errors(realistic_errors(("X", "Y", "Z"), strokes=cfg.strokes, J_m=cfg.J_m))
    for axis in "XYZ":
        plan = positioning_plan(m, axis, n_targets=7, cycles=2, rng=np.random.default_rng(3))
        s = schedule(plan)
        got = deviations_m(m, plan, s["target_m"], s["t_s"], s["direction"])
        k = "XYZ".index(axis)
        lin = np.tile(np.asarray(plan.line_m), (s["target_m"].size, 1))
        lin[:, k] = s["target_m"]
        dirn = np.zeros((lin.shape[0], 3))
        dirn[:, k] = s["direction"]
        vals = m.error_values(lin, None, s["t_s"], dirn)
        geom = m.geometry()
        expect = (K.tip_W(geom, lin, None, vals) - K.tip_W(geom, lin, None, {}))[:, k]
        np.testing.assert_allclose(got, expect, rtol=0, atol=EXACT_M)
        assert np.ptp(got) > 10e-6  # the errors are there (tens of um)


def test_pilgrim_equals_linear_when_nothing_depends_on_time():
    cfg = MACHINES["vmc-3axis"]()
    m = Machine(MACHINES["vmc-3axis"](errors=realistic_errors(("X", "Y", "Z"), strokes=cfg.strokes, J_m=cfg.J_m)))
    kw = dict(n_targets=6, cycles=3)
    a = iso230_2(simulate_positioning(m, positioning_plan(m, "Y", **kw), np.random.default_rng(0)))
    b = iso230_2(simulate_positioning(m, positioning_plan(m, "Y", cycle_kind="pilgrim", **kw),
                                      np.random.default_rng(0)))
    assert a.cycle_kind == "linear" and b.cycle_kind == "pilgrim"
    np.testing.assert_allclose(a.mean_up, b.mean_up, rtol=0, atol=1e-12)
    assert a.E == pytest.approx(b.E, abs=1e-12)


def test_scatter_round_trip():
    """A perfect machine with scatter sigma: pooled s recovers sigma.

    11 targets x (5 - 1) = 44 degrees of freedom per direction, so
    se(s) ~ sigma / sqrt(2 * 44) for each pooled s; bound 4.5 se.
    """
    sigma = 0.8e-6
    m = Machine(MACHINES["vmc-3axis"]())
    plan = positioning_plan(m, "X", rng=np.random.default_rng(1))
    log = simulate_positioning(m, plan, np.random.default_rng(2), noise_m=sigma)
    b = baseline(arrange(log))
    dof = b.dof / 2
    for s in (b.s_up_pooled, b.s_down_pooled):
        assert abs(s * MM - sigma) < 4.5 * sigma / math.sqrt(2 * dof)
    assert log.meta["cycle_kind"] == "linear" and log.meta["machine"] == "vmc-3axis"


@pytest.mark.parametrize("kw,match", [
    (dict(axis="C"), "only the linear axes"),
    (dict(cycles=1), "cycles must be a whole number >= 2"),
    (dict(cycle_kind="spiral"), "cycle kind 'spiral'"),
    (dict(targets_m=[-0.30, 0.0]), "leave the stroke -300..300 mm"),
    (dict(overrun_m=-1.0), "overrun must be >= 0"),
    (dict(feed_mps=0.0), "feed must be > 0"),
    (dict(line_m=(0, 0.5, 0)), "measuring line: Y = 500 mm outside the stroke"),
    (dict(targets_m=[0.1, 0.1]), "targets must be distinct"),
])
def test_bad_plans(vmc, kw, match):
    kw = {"axis": "X", **kw}
    axis = kw.pop("axis")
    with pytest.raises(ConfigError, match=match):
        positioning_plan(vmc, axis, **kw)


def test_negative_noise_refused(vmc):
    with pytest.raises(ConfigError, match="noise must be >= 0"):
        simulate_positioning(vmc, positioning_plan(vmc, "X"), np.random.default_rng(0), noise_m=-1e-6)


def test_targets_are_written_as_their_commanded_decimals_and_read_back_exactly(tmp_path):
    """The metre-to-millimetre conversion left targets such as 84.97099999999999 in the file; the
    commanded values are whole micrometres (interior targets) or the travel's ends: each target cell
    must read as a decimal of at most 3 places in mm, and the file must read back to the same doubles."""
    from decimal import Decimal

    from core.positioning import format_positioning_log, read_positioning_log, write_positioning_log
    from scenarios.positioning import simulate_test

    for axis in "XYZ":
        log = simulate_test("vmc-3axis", axis, np.random.default_rng(3))
        p = write_positioning_log(tmp_path / f"{axis}.csv", log)
        lines = [ln for ln in p.read_text().splitlines() if not ln.startswith("#")]
        col = lines[0].split(",").index("target_mm")
        cells = {ln.split(",")[col] for ln in lines[1:]}
        assert all(Decimal(c).as_tuple().exponent >= -3 for c in cells), sorted(cells)
        back = read_positioning_log(p)
        for k in ("target", "measured", "t_s"):
            np.testing.assert_array_equal(getattr(back, k), getattr(log, k))
        assert format_positioning_log(back) == p.read_text()
