"""Write the plan-check references: every measurement's result of ``sim.mfb_scene.check_measurements``
on plan variants, as the code that writes them gives it.

Run from the repository root with the engine whose answers are the reference (issue 19 item 4:
the plan check at c08d3ff, before the broad phase bounded each distinct move once):

    python tests/sim/data/plan_check_variants/make.py

``results.json.gz`` holds, per variant (one ``check_measurements`` call: a plan's measurements checked
together), per measurement: touches, path points, collisions (the messages) and the least clearance
at the approach starts (mm, the float as Python writes it). tests/sim/test_mfb_scene.py
checks the code against them. A change meant to change the check's answers (what is modelled)
rewrites them once it is reviewed; a change of its speed must leave them as they are.

The variants (:func:`variants`): the MFB 5-axis plan of session 25 (:func:`plan_5axis_s25`) as
``scenarios.mfb.check_plan`` checks it; the
same turned 30 deg in C, tilted 30 deg more in A, each measurement with the next stylus (star arms
through walls); the bar sunk 80 mm into the table; a star arm through a hole's wall and a finger
stylus, programs of one and two touches; the riser block raised into the bar; the touches moved at
random by up to 3 mm at random table poses and styli, or by up to 0.2 mm with the measurement's
stylus, turned by up to 10 deg. Clean and colliding measurements both (counted by the test).
"""

from __future__ import annotations

import gzip
import json
import pathlib
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
R_M = 3.0e-3  # the stylus radius check_plan uses


def _plan_items(plan, art, program):
    """The measurements of ``plan`` as scenarios.mfb.check_plan gives them to check_measurements."""
    from scenarios import mfb as S
    from sim.machine import nominal_T_R_W
    from sim.machines import MACHINES

    cfg = MACHINES[plan.machine]()
    out, progs = [], {}
    for ms in plan.measurements:
        T_R_W = np.asarray(nominal_T_R_W(cfg, np.asarray([ms.rot_rad], float)), float).reshape(4, 4)
        pl = progs.get(ms.holes)
        if pl is None:
            pl = progs[ms.holes] = S._plan_for(art, ms.holes, **program)
        out.append([ms.name, np.asarray(ms.T_W_A, float), T_R_W, tuple(plan.fixtures.get(ms.placement, ())),
                    tuple(ms.J_m), pl, S.FINGERS.get(ms.stylus, 0.0), ms.stylus, tuple(ms.rot_rad)])
    return out


def plan_5axis_s25():
    """The 5-axis plan as shipped until session 26 (the references were made on it): today's
    ``scenarios.mfb.plan_5axis`` with X3, DXZ, AXZ on TY1 (100 mm arm, not TYM's 60 mm), VXb on TX2, VY
    (P1 at A -90, C -90 deg, holes 6-11, TY1, TY2, TYL) back, VXc (TXL) out, in the old order; P3
    (Y3, VX, DYZ) at x = -60 mm with its angle plate and DXY's, AXY's holes as then (session 27 moved
    P3 to 90 mm and widened the diagonals' reach: :data:`_S25_DIAG_HOLES`).
    (Session 26 refit the plan within the Y stroke as axis positions; the plan check's engine
    references stay those of this plan: they test the engine, not the plan.)"""
    import dataclasses

    from scenarios import mfb as S
    from sim.mfb_scene import Block

    new = {ms.name: ms for ms in S.plan_5axis().measurements}
    ty = {st: S.STYLI[st] for st in ("TY1", "TY2", "TYL")}

    def old(n):
        ms = new[n]
        if ms.placement == "P3":  # P3 at x = -60 mm until session 27 (then moved to 90 mm for VX's TX3)
            T = np.array(ms.T_W_A, float)
            T[:3, 3] = (-0.060, -0.225, 0.105)
            ms = dataclasses.replace(ms, T_W_A=T)
        if n in _S25_DIAG_HOLES:  # the diagonals' holes as fitted then (session 27 widened their reach)
            ms = dataclasses.replace(ms, holes=_S25_DIAG_HOLES[n])
        if ms.stylus == "TYM":
            return dataclasses.replace(ms, J_m=ty["TY1"], stylus="TY1")
        if ms.stylus == "TX3":  # (VXb: TX2 until session 26)
            return dataclasses.replace(ms, J_m=S.STYLI["TX2"], stylus="TX2")
        return ms

    x1 = new["X1"]
    rot = tuple(float(np.deg2rad(v)) for v in (-90.0, -90.0))
    vy = [S.MeasurementSpec(f"VY{k}", "P1", x1.T_W_A, rot, ty[st], tuple(range(6, 12)),
                            "EZZ, EXZ, EYZ; dJ_Y: ECZ, EAZ; dJ_Z: EBZ, EAZ", st, setup="P1@A-90,C-90")
          for k, st in zip("abc", ("TY1", "TY2", "TYL"))]
    order = ["X1", "X2", "X3", "Y1a", "Y1b", "Y2", "Y3", "VYa", "VYb", "VYc", "VXa", "VXb", "DXY", "AXY",
             "DXZ", "AXZ", "DYZ"]
    by = {**{n: old(n) for n in new if n != "VXc"}, **{m.name: m for m in vy}}
    plan = S.plan_5axis()
    fixtures = {**plan.fixtures, "P3": (Block("angle_plate", (0.010, -0.135, 0.0), (0.030, 0.235, 0.140)),)}
    return S.MfbPlan(plan.machine, tuple(by[n] for n in order), plan.nodes, fixtures)


#: The 5-axis diagonals' holes of sessions 25-26 (DXZ, AXZ, DYZ unchanged since).
_S25_DIAG_HOLES = {"DXY": (1, 2, 3, 4, 5), "AXY": (4, 5, 6, 7, 8, 9, 10)}


def variants():
    """[(name, measurements)]: each a list of (name, T_W_A, T_R_W, blocks, J_m, plan, finger_m)."""
    import dataclasses

    from scenarios import mfb as S
    from sim import artefacts as A
    from sim.machine import nominal_T_R_W
    from sim.machines import MACHINES
    from sim.mfb_scene import Block

    cfg = MACHINES["mikron-ucp710"]()
    art = S._nominal_bar()
    base = _plan_items(plan_5axis_s25(), art, S._program(S.U_PLACE))

    def pose(rot):
        return np.asarray(nominal_T_R_W(cfg, np.asarray([rot], float)), float).reshape(4, 4)

    def strip(items):
        return [tuple(it[:7]) for it in items]

    out = [("plan_5axis", strip(base))]
    out.append(("turned_c30", [(f"{n}", T, pose((a, c + np.deg2rad(30.0))), b, J, pl, f)
                               for n, T, _, b, J, pl, f, _, (a, c) in base]))
    out.append(("tilted_a30", [(f"{n}", T, pose((a - np.deg2rad(30.0), c)), b, J, pl, f)
                               for n, T, _, b, J, pl, f, _, (a, c) in base]))
    names = list(S.STYLI)
    out.append(("next_stylus", [(n, T, TR, b, S.STYLI[names[(names.index(st) + 1) % len(names)]], pl,
                                 S.FINGERS.get(names[(names.index(st) + 1) % len(names)], 0.0))
                                for n, T, TR, b, J, pl, f, st, _ in base]))
    sunk = [it for it in base if it[0] in ("X1", "Y1a", "VYa", "DXY")]
    out.append(("bar_in_table", [(n, T @ A.make_T(None, (0.0, 0.0, -0.080)), TR, b, J, pl, f)
                                 for n, T, TR, b, J, pl, f, _, _ in sunk]))
    flat = A.make_T(None, (-0.175, 0.080, 0.070))
    holes = {h: S._plan_for(art, h) for h in ((3,), (1, 7), (2, 9), (6,), (3, 4))}
    out.append(("arm_through_wall", [
        ("arm_h3", flat, pose((0.0, 0.0)), (), (0.0, -0.100, 0.150), holes[(3,)], 0.0),
        ("arm_h34", flat, pose((0.0, 0.0)), (), (0.0, -0.100, 0.150), holes[(3, 4)], 0.0),
        ("tilt_h17", flat, pose((np.deg2rad(-60.0), np.deg2rad(30.0))), (), (0.0, 0.0, 0.150), holes[(1, 7)], 0.0),
        ("finger_h29", flat, pose((np.deg2rad(-90.0), 0.0)), (), (0.030, 0.0, 0.150), holes[(2, 9)], 0.020),
        ("turn_h6", flat, pose((np.deg2rad(45.0), np.deg2rad(-90.0))), (), (0.0, 0.0, 0.150), holes[(6,)], 0.0),
        ("one_touch", flat, pose((0.0, 0.0)), (), (0.0, 0.0, 0.150), holes[(6,)].select([0]), 0.0),
        ("two_touches", flat, pose((0.0, 0.0)), (), (0.0, -0.100, 0.150), holes[(3,)].select([0, 5]), 0.0)]))
    riser = (Block("riser", (-0.095, -0.045, 0.0), (0.295, 0.045, 0.175)),)  # 25 mm into the bar on P2
    out.append(("riser_in_bar", [(n, T, TR, riser if b else b, J, pl, f)
                                 for n, T, TR, b, J, pl, f, _, _ in base if n in ("X2", "Y2", "X1")]))
    rng = np.random.default_rng(19)
    rand = []
    for k, (n, T, _, b, J, pl, f, st, (a, c)) in enumerate(base[:12]):
        d = 3e-3 if k % 2 else 0.2e-3  # (odd: by up to 3 mm, into the holes' walls, any pose and stylus)
        moved = dataclasses.replace(pl, w_A=pl.w_A + rng.uniform(-d, d, pl.w_A.shape))
        if k % 2:
            rot = (rng.uniform(-np.pi / 2, np.pi / 6), rng.uniform(-np.pi, np.pi))
            J = (rng.uniform(-0.03, 0.03), rng.uniform(-0.1, 0.1), 0.150)
        else:  # (even: by up to 0.2 mm, the measurement's stylus, its pose turned by up to 10 deg in C)
            rot = (a, c + rng.uniform(-np.pi / 18, np.pi / 18))
        rand.append((f"{n}_r{k}", T, pose(rot), b, J, moved, f))
    out.append(("random_moved", rand))
    return out


def results(vs=None) -> dict:
    """{variant: [{name, touches, samples, collisions, clearance_mm}]} of check_measurements."""
    from scenarios import mfb as S
    from sim.mfb_scene import check_measurements

    art = S._nominal_bar()
    out = {}
    for name, items in (variants() if vs is None else vs):
        got = check_measurements(art, items, R_M)
        out[name] = [{"name": r.measurement, "touches": r.touches, "samples": r.samples,
                      "collisions": list(r.collisions), "clearance_mm": r.min_table_clearance_mm} for r in got]
    return out


if __name__ == "__main__":  # pragma: no cover
    sys.path.insert(0, str(HERE.parents[3]))
    res = results()
    with open(HERE / "results.json.gz", "wb") as f, gzip.GzipFile(fileobj=f, mode="wb", mtime=0) as z:
        z.write((json.dumps(res, indent=0) + "\n").encode())  # (mtime 0: the same bytes each time)
    for k, v in res.items():
        print(k, len(v), "measurements,", sum(bool(x["collisions"]) for x in v), "colliding")
