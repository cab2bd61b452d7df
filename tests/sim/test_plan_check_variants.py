"""The plan check (sim.mfb_scene.check_measurements, what scenarios.mfb.check_plan calls) against its
answers before issue 19 item 4's last speed-up: every measurement of plan variants, clean and colliding
(the bar sunk into the table, star arms through hole walls, the riser block in the bar, tilted and
turned tables, moved touches), gives the stored touches, path points, collision messages and least
clearance (tests/sim/data/plan_check_variants/make.py wrote them with the code at c08d3ff).

Tolerance: none. The collision messages (what hits what, depth to 0.01 mm, where to 0.1 mm) and the path
points come from MuJoCo at the samples the broad phase cannot clear, in path order: a sound broad phase
gives the same first collision per touch whichever clear samples it skips. The least clearance is
MuJoCo's distance of the same (tip, geom pair) found by the same branch and bound: the same float.
"""

import gzip
import json
import pathlib

import pytest

pytest.importorskip("mujoco")

DATA = pathlib.Path(__file__).resolve().parent / "data" / "plan_check_variants"


def _fresh():
    from sim import clearance, mfb_scene, scene

    for memo in (scene._POINTS, mfb_scene._SOLID_POSES, mfb_scene._ZONES, mfb_scene._BALLS, mfb_scene._PROBES,
                 clearance._TABLE_PREP, clearance._PAIRS):
        memo.clear()


def _load():
    import importlib.util

    spec = importlib.util.spec_from_file_location("plan_check_variants_make", DATA / "make.py")
    make = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make)
    with gzip.open(DATA / "results.json.gz", "rt") as f:
        return make, json.load(f)


def test_plan_variants_give_the_stored_answers_fresh_and_again():
    """Fresh caches, then again with the first pass's broad phases and certificates kept: each time
    every variant's every measurement as stored. Fails on a broad phase that skips a colliding sample
    (a collision lost or another first collision) or on a changed clearance; tried: dropping the open
    segments' sample-by-sample bounds (sim.mfb_scene._near_samples) loses collisions here."""
    make, want = _load()
    vs = make.variants()
    assert [v[0] for v in vs] == list(want)
    _fresh()
    first = make.results(vs)
    again = make.results(vs)
    for got in (first, again):
        for name, rows in want.items():
            assert got[name] == rows, name
    n = [r for rows in want.values() for r in rows]
    # the variants hold both kinds, and colliding ones of every family
    assert sum(not r["collisions"] for r in n) >= 40 and sum(bool(r["collisions"]) for r in n) >= 40
    assert all(any(r["collisions"] for r in want[k]) for k in want if k != "plan_5axis")
    assert not any(r["collisions"] for r in want["plan_5axis"])
