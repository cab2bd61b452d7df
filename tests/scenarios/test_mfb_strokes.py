"""The MFB plans within the machine's travel (session 26).

A stroke limits the axis position (the carriage, the spindle's gauge point) stated for the
machine's reference tool (its file's ``[tool] offset_mm``, ``J_ref``): a reading taken with a
stylus of offsets J puts the axis at ``reading + J - J_ref`` (docs/formats.md, "Strokes").
Every position the program commands (touches, approach starts, overshoot ends, link moves) is
checked, on every run (:func:`scenarios.mfb.check_plan`, :func:`scenarios.mfb.check_plan_strokes`).

The independent check here recomputes every commanded position from the bar's touch program
and the link rule as stated (sim.mfb_scene: along a feature's level, else out to 10 mm beyond
the bar's top along z_A, across and back), with its own loops, and compares the axis ranges
with what check_plan reports.
"""

from dataclasses import replace

import numpy as np
import pytest

from core.exceptions import PlanError
from scenarios import mfb as M
from sim.machine import nominal_T_R_W
from sim.machines import MACHINES

R_STYLUS = 3.0e-3
LINK_CLEAR = 10.0e-3  # sim.mfb_scene.LINK_CLEAR_M, restated


def _positions_by_hand(plan):
    """{measurement: {kind: (k,3) axis positions (reading + J - J_ref)}}, computed touch by touch."""
    from sim.scene import artefact_points

    cfg = MACHINES[plan.machine]()
    art = M._nominal_bar()
    prog = M._program(M.U_PLACE)
    top_A = max(p[2] for p in artefact_points(art)) + R_STYLUS + LINK_CLEAR
    out = {}
    for ms in plan.measurements:
        rot = np.array([ms.rot_rad], float) if len(ms.rot_rad) else None
        T = np.asarray(nominal_T_R_W(cfg, rot), float).reshape(-1, 4, 4)[0] @ np.asarray(ms.T_W_A, float)
        pl = M._plan_for(art, ms.holes, **prog)
        dJ = np.array(ms.J_m) - np.array(cfg.J_m)
        to_q = lambda p_A: T[:3, :3] @ p_A + T[:3, 3] + dJ  # noqa: E731
        touch, start, over, link = [], [], [], []
        prev = None
        for i in range(pl.n):
            c = pl.w_A[i] + R_STYLUS * pl.wn_A[i]
            s = c + pl.clearance_m * pl.wn_A[i]
            touch.append(to_q(c))
            start.append(to_q(s))
            over.append(to_q(c - pl.overshoot_m * pl.wn_A[i]))
            if prev is not None:
                a, f_a, l_a = prev
                if not (f_a == pl.feature[i] and l_a == pl.level[i]):
                    z = max(top_A, a[2], s[2])
                    link += [to_q(np.array([a[0], a[1], z])), to_q(np.array([s[0], s[1], z]))]
                link += [to_q(a), to_q(s)]
            prev = (s, pl.feature[i], pl.level[i])
        out[ms.name] = {"touches": np.array(touch), "approach starts": np.array(start),
                        "overshoot ends": np.array(over), "links": np.array(link).reshape(-1, 3)}
    return out, cfg


@pytest.mark.parametrize("name", ["mfb-3axis", "mfb-5axis"])
def test_shipped_plans_lie_within_the_strokes_as_axis_positions(name):
    """Every commanded position of the shipped plans lies within the strokes (by hand, not by
    check_program_strokes), and check_plan's axis ranges are the hand ones (0.1 mm rounding)."""
    plan = M.PLANS[name]()
    by_hand, cfg = _positions_by_hand(plan)
    rep = M.check_plan(plan)  # (refuses a plan outside: it passes)
    for ms in plan.measurements:
        q = np.concatenate(list(by_hand[ms.name].values()))
        for j, ax in enumerate("XYZ"):
            lo, hi = cfg.strokes[ax]
            assert lo <= q[:, j].min() and q[:, j].max() <= hi, (ms.name, ax, q[:, j].min(), q[:, j].max())
            got = rep["measurements"][ms.name]["axis_range_mm"][ax]
            assert got == pytest.approx([q[:, j].min() * 1e3, q[:, j].max() * 1e3], abs=0.051), (ms.name, ax)


def test_the_review_s_excesses_are_gone():
    """The review's cases (session 26): Mikron X3, VY*, DXZ, AXZ put the spindle at Y -298 / -348 mm
    (TY1, TY2) against -275 mm; vmc-3axis VYc (TYL) reached Z 493 mm as an axis position against
    400 mm. Now the -Y facing bars of the 5-axis plan use TYM (60 mm arm): the least Y axis
    position 2 mm inside the stroke; 3-axis VYc over holes 1-5."""
    five, cfg5 = _positions_by_hand(M.PLANS["mfb-5axis"]())
    for n in ("X3", "DXZ", "AXZ"):
        y = np.concatenate(list(five[n].values()))[:, 1].min()
        assert -0.275 <= y <= -0.270, (n, y)
    three, cfg3 = _positions_by_hand(M.PLANS["mfb-3axis"]())
    z = np.concatenate(list(three["VYc"].values()))[:, 2].max()
    assert 0.390 <= z <= 0.400, z


def _narrowed(cfg, ax, side, to):
    st = dict(cfg.strokes)
    lo, hi = st[ax]
    st[ax] = (to, hi) if side == "lo" else (lo, to)
    return replace(cfg, strokes=st)


@pytest.mark.parametrize("kind, ax", [("touches", "Y"), ("approach starts", "Y"), ("overshoot ends", "X"),
                                      ("links", "Y")])
def test_a_plan_1_mm_beyond_a_stroke_is_refused_naming_measurement_axis_and_excess(kind, ax):
    """The Mikron's stroke of ``ax`` moved (its lower end) so that X3's ``kind`` (by hand) reaches
    1 mm beyond it: refused in one line naming X3, the axis, the kind and 1.0 mm. The kinds are
    checked in the order touches, approach starts, overshoot ends, links; the limit is met first
    by ``kind`` (the kinds before it stay inside: asserted, so the case tests what it names). The
    whole plan is refused too (by X3 or a measurement before it), and X3 passes at its
    least position of all kinds."""
    plan = M.PLANS["mfb-5axis"]()
    by_hand, cfg = _positions_by_hand(plan)
    j = "XYZ".index(ax)
    least = {k: v[:, j].min() for k, v in by_hand["X3"].items()}
    order = ["touches", "approach starts", "overshoot ends", "links"]
    limit = least[kind] + 1.0e-3
    assert all(least[k] >= limit + 1e-6 for k in order[:order.index(kind)]), least
    x3 = M.MfbPlan(plan.machine, tuple(ms for ms in plan.measurements if ms.name == "X3"), plan.nodes, plan.fixtures)
    with pytest.raises(PlanError) as e:
        M.check_plan_strokes(x3, _narrowed(cfg, ax, "lo", limit))
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(f"measurement 'X3': axis {ax} at ") and f"at its {kind} " in msg, msg
    assert msg.endswith(f"1.0 mm beyond its stroke's {limit * 1e3:g} mm"), msg
    with pytest.raises(PlanError, match=f"axis {ax} at "):
        M.check_plan_strokes(plan, _narrowed(cfg, ax, "lo", limit))
    M.check_plan_strokes(x3, _narrowed(cfg, ax, "lo", min(least.values())))  # (at the least of all: inside)


def test_kinds_the_1_mm_cases_reach():
    """The 1 mm cases above reach touches, approach starts and links on X3 (the brief's three), not
    skipped: their least Y positions are ordered links < starts < touches by more than 1 mm."""
    by_hand, _ = _positions_by_hand(M.PLANS["mfb-5axis"]())
    y = {k: v[:, 1].min() for k, v in by_hand["X3"].items()}
    assert y["links"] < y["approach starts"] - 1e-3 < y["touches"] - 2e-3
    assert y["overshoot ends"] >= y["touches"]  # (the overshoot goes into the bar: +Y here)


def test_the_3_axis_z_stroke_1_mm_beyond_at_vyc_is_refused():
    """Z on the 3-axis machine: VYc (TYL, J_Z 250 mm: axis = reading + 100 mm) alone, the Z stroke
    1 mm below its highest axis position (by hand): refused by 1.0 mm; its readings lie 100 mm
    lower, so a check of readings (the check before session 26) would pass it."""
    plan = M.PLANS["mfb-3axis"]()
    by_hand, cfg = _positions_by_hand(plan)
    vyc = M.MfbPlan(plan.machine, tuple(ms for ms in plan.measurements if ms.name == "VYc"), plan.nodes, plan.fixtures)
    z = np.concatenate(list(by_hand["VYc"].values()))[:, 2].max()
    limit = z - 1.0e-3
    with pytest.raises(PlanError, match=r"^measurement 'VYc': axis Z at .* 1\.0 mm beyond its stroke's"):
        M.check_plan_strokes(vyc, _narrowed(cfg, "Z", "hi", limit))
    assert z - 0.100 < limit - 0.090  # (as readings: 99 mm inside)
    M.check_plan_strokes(vyc, _narrowed(cfg, "Z", "hi", z))


def test_check_program_strokes_bad_and_good_input():
    """Known answers of the check itself: a point 1 mm beyond, the offsets' difference counted."""
    st = {"X": (-0.1, 0.1), "Y": (-0.1, 0.1), "Z": (0.0, 0.4)}
    pts = {"links": np.array([[0.0, 0.0, 0.35]])}
    lo, hi = M.check_program_strokes("m", pts, (0, 0, 0.150), (0, 0, 0.150), st)
    assert hi[2] == pytest.approx(0.35)
    # a 250 mm stylus on a machine whose reference tool is 150 mm: the axis 100 mm higher
    with pytest.raises(PlanError, match=r"measurement 'm': axis Z at 450\.0 mm at its links .* 50\.0 mm beyond"):
        M.check_program_strokes("m", pts, (0, 0, 0.250), (0, 0, 0.150), st)
    with pytest.raises(PlanError, match=r"axis X at -101\.0 mm at its touches .* 1\.0 mm beyond its stroke's -100 mm"):
        M.check_program_strokes("m", {"touches": np.array([[-0.101, 0.0, 0.1]])}, (0, 0, 0.15), (0, 0, 0.15), st)


def test_run_on_a_machine_file_with_a_shorter_stroke_is_refused():
    """run(machine=...) checks the program on that machine's strokes too (its own offsets the
    reference): the Mikron with Y from -272 mm refuses the 5-axis plan (X3 reaches -273 mm)."""
    from sim.machinefile import loads, builtin_text

    text = builtin_text("mikron-ucp710").replace("Y_mm = [-275, 275]", "Y_mm = [-272, 275]")
    assert "Y_mm = [-272, 275]" in text
    spec = loads(text, source="short.toml")
    with pytest.raises(PlanError, match=r"^measurement 'X3': axis Y at -273\.0 mm .* 1\.0 mm beyond its stroke's -272 mm"):
        M.run("mfb-5axis", seed=1, mc_runs=0, machine=spec)


def _strokes_loop(positions, J_m, J_ref_m, strokes):
    """check_program_strokes as written before session 27 (kind by kind, axis by axis): the reference
    its one pass must equal, (lo, hi) or the error's text."""
    dJ = np.asarray(J_m, float) - np.asarray(J_ref_m, float)
    lo_all, hi_all = [np.inf] * 3, [-np.inf] * 3
    for kind, P in positions.items():
        if not len(P):
            continue
        q = np.asarray(P, float) + dJ
        for j, ax in enumerate("XYZ"):
            lo, hi = strokes[ax]
            qmin, qmax = float(q[:, j].min()), float(q[:, j].max())
            lo_all[j], hi_all[j] = min(lo_all[j], qmin), max(hi_all[j], qmax)
            for v, lim, over in ((qmax, hi, qmax - hi), (qmin, lo, lo - qmin)):
                if over > 1e-9:
                    return f"{kind} {ax} {v!r} {over!r}"
    return lo_all, hi_all


def test_check_program_strokes_one_pass_equals_the_loop():
    """The one pass over every kind (session 27) gives the loop's ranges bit for bit, and the loop's
    error (the first kind, axis and side in its order) whenever a position is beyond: random programs
    inside, one position moved past a side of an axis in one kind by 1e-9 m (at the tolerance: refused or
    not as rounding makes the excess, as in the loop), 2e-9 m or 1 mm, and positions with a signed zero; a
    NaN position, which the loop let through, is refused."""
    rng = np.random.default_rng(27)
    st = {"X": (-0.3, 0.3), "Y": (-0.2, 0.25), "Z": (0.0, 0.4)}
    kinds = ("touches", "approach starts", "overshoot ends", "links")
    cases = []
    for _ in range(200):
        pos = {k: rng.uniform([-0.29, -0.19, 0.01], [0.29, 0.24, 0.39], (int(rng.integers(0, 6)), 3)) for k in kinds}
        cases.append(pos)
        k, j, side = kinds[rng.integers(4)], int(rng.integers(3)), int(rng.integers(2))
        if len(pos[k]):
            beyond = {kk: v.copy() for kk, v in pos.items()}
            lim = st["XYZ"[j]][side]
            beyond[k][0, j] = lim + (1.0 if side else -1.0) * rng.choice([1e-9, 2e-9, 1e-3])
            cases.append(beyond)
    z = {"touches": np.array([[0.0, -0.0, 0.1], [0.1, 0.0, 0.2]]), "links": np.array([[-0.0, 0.1, 0.0]])}
    cases.append(z)
    # a NaN position (the loop let it through: Python's min keeps inf beside a NaN) is refused by name
    with pytest.raises(PlanError, match=r"measurement 'm': a position at its touches is not a finite number"):
        M.check_program_strokes("m", {"touches": np.array([[np.nan, 0.0, 0.1]]), "links": np.array([[0.1, 0.1, 0.1]])},
                                (0, 0, 0.1), (0, 0, 0.1), st)
    refused = 0
    for pos in cases:
        want = _strokes_loop(pos, (0, 0, 0.1), (0, 0, 0.1), st)
        try:
            got = M.check_program_strokes("m", pos, (0, 0, 0.1), (0, 0, 0.1), st)
        except PlanError as e:
            refused += 1
            assert isinstance(want, str), (pos, str(e))
            k = next(kk for kk in kinds if want.startswith(kk))
            assert f"at its {k} " in str(e) and f"axis {want[len(k) + 1]} " in str(e), (want, str(e))
            continue
        assert not isinstance(want, str), want
        assert [repr(v) for v in got[0] + got[1]] == [repr(v) for v in want[0] + want[1]], (got, want)
    assert 100 <= refused < len(cases) - 150, refused  # (both answers met many times)


@pytest.mark.parametrize("name", ["mfb-3axis", "mfb-5axis"])
def test_check_results_carry_program_positions_bit_for_bit(name):
    """check_plan's stroke check reads the program's positions from the collision check
    (CheckResult.positions_R, session 27): for every measurement they are program_positions' arrays
    bit for bit (the same kinds in the same order; links only for programs of two touches or more),
    also for a program of one touch."""
    from sim.mfb_scene import check_measurements

    plan = M.PLANS[name]()
    cfg = MACHINES[plan.machine]()
    items = []
    for ms, T_R_W, pl, art in M.measurement_programs(plan, cfg):
        items.append((ms.name, ms.T_W_A, T_R_W, plan.fixtures.get(ms.placement, ()), ms.J_m, pl,
                      M.FINGERS.get(ms.stylus, 0.0)))
    one = items[0][5].select(np.array([0]))
    items.append(("one", *items[0][1:5], one, items[0][6]))
    kinds = ["touches", "approach starts", "overshoot ends", "links"]
    for it, r in zip(items, check_measurements(art, items, R_STYLUS)):
        want = M.program_positions(it[2] @ it[1], it[5], R_STYLUS, art)
        assert list(r.positions_R) == list(want) == kinds[:3 + (it[5].n > 1)], it[0]
        for k, v in want.items():
            assert v.shape == r.positions_R[k].shape and v.tobytes() == r.positions_R[k].tobytes(), (it[0], k)
