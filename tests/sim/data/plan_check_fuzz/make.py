"""Write the plan-check fuzz references: ``sim.mfb_scene.check_measurements``'s answers on random
variants of the MFB 5-axis plan, as the code that writes them gives it.

Run from the repository root with the engine whose answers are the reference (issue 19 item 4,
session 15: the plan check at 69ad683, before its broad phases, work zones and least clearances
were batched over the plan's measurements):

    python tests/sim/data/plan_check_fuzz/make.py

The variants are drawn from a fixed generator (:func:`variants`), so the test rebuilds the same
measurements and compares the code's answers with the stored ones (``results.json.gz``, the format
of ``tests/sim/data/plan_check_variants``). Four families, each over the plan's 17 measurements:

- ``small_moves``: every touch moved by up to 0.3 mm, the table turned by up to 20 deg in C and
  5 deg in A, the measurement's stylus (mostly clean: near misses);
- ``wall_moves``: every touch moved by up to 4 mm (into the holes' walls), any table pose, any stylus
  of the plan (mostly colliding);
- ``bar_sunk``: the bar lowered by 0 to 60 mm (the bar below the table face, its supports and the
  probe in the table);
- ``stylus_walls``: the bar flat on the table, a star stylus through the holes' walls at random
  poses, programs of one to all of a hole set's touches.
"""

from __future__ import annotations

import gzip
import importlib.util
import json
import pathlib
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
SEED = 1915


def _variants_module():
    """tests/sim/data/plan_check_variants/make.py (its plan items and results)."""
    spec = importlib.util.spec_from_file_location("plan_check_variants_make",
                                                  HERE.parent / "plan_check_variants" / "make.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def variants():
    """[(name, measurements)]: each a list of (name, T_W_A, T_R_W, blocks, J_m, plan, finger_m)."""
    import dataclasses

    from scenarios import mfb as S
    from sim import artefacts as A
    from sim.machine import nominal_T_R_W
    from sim.machines import MACHINES

    V = _variants_module()
    cfg = MACHINES["mikron-ucp710"]()
    art = S._nominal_bar()
    base = V._plan_items(V.plan_5axis_s25(), art, S._program(S.U_PLACE))
    rng = np.random.default_rng(SEED)
    names = list(S.STYLI)

    def pose(rot):
        return np.asarray(nominal_T_R_W(cfg, np.asarray([rot], float)), float).reshape(4, 4)

    def moved(pl, d):
        return dataclasses.replace(pl, w_A=pl.w_A + rng.uniform(-d, d, pl.w_A.shape))

    out = []
    small = []
    for n, T, _, b, J, pl, f, st, (a, c) in base:
        rot = (a + rng.uniform(-1, 1) * np.deg2rad(5.0), c + rng.uniform(-1, 1) * np.deg2rad(20.0))
        small.append((f"{n}_s", T, pose(rot), b, J, moved(pl, 0.3e-3), f))
    out.append(("small_moves", small))
    wall = []
    for n, T, _, b, J, pl, f, st, _ in base:
        s = names[int(rng.integers(len(names)))]
        rot = (rng.uniform(-np.pi / 2, np.pi / 6), rng.uniform(-np.pi, np.pi))
        wall.append((f"{n}_w", T, pose(rot), b, S.STYLI[s], moved(pl, 4e-3), S.FINGERS.get(s, 0.0)))
    out.append(("wall_moves", wall))
    sunk = []
    for n, T, TR, b, J, pl, f, st, _ in base:
        sunk.append((f"{n}_z", T @ A.make_T(None, (0.0, 0.0, -rng.uniform(0.0, 0.060))), TR, b, J, pl, f))
    out.append(("bar_sunk", sunk))
    flat = A.make_T(None, (-0.175, 0.080, 0.070))
    sets = [ms.holes for ms in V.plan_5axis_s25().measurements]
    walls = []
    for k in range(17):
        holes = sets[int(rng.integers(len(sets)))]
        pl = S._plan_for(art, holes)
        keep = np.sort(rng.choice(pl.n, size=int(rng.integers(1, pl.n + 1)), replace=False))
        s = names[int(rng.integers(len(names)))]
        rot = (rng.uniform(-np.pi / 2, 0.0), rng.uniform(-np.pi, np.pi))
        walls.append((f"h{'_'.join(map(str, holes))}_{k}", flat, pose(rot), (), S.STYLI[s],
                      pl.select(list(keep)), S.FINGERS.get(s, 0.0)))
    out.append(("stylus_walls", walls))
    return out


def results(vs=None) -> dict:
    """{variant: [{name, touches, samples, collisions, clearance_mm}]} of check_measurements."""
    return _variants_module().results(variants() if vs is None else vs)


if __name__ == "__main__":  # pragma: no cover
    sys.path.insert(0, str(HERE.parents[3]))
    res = results()
    with open(HERE / "results.json.gz", "wb") as f, gzip.GzipFile(fileobj=f, mode="wb", mtime=0) as z:
        z.write((json.dumps(res, indent=0) + "\n").encode())  # (mtime 0: the same bytes each time)
    for k, v in res.items():
        print(k, len(v), "measurements,", sum(bool(x["collisions"]) for x in v), "colliding")
