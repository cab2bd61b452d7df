"""Benchmark: Monte Carlo runs per second of a 100-touch virtual-CMM task (``vmt vcmm``).

The task: a block with a bore, as the README's example but with 100
touches (bore 32, two faces 16 each, top face 36), the README's declared
limits (four terms) and probing noise; every run draws a machine, builds
it, simulates the 100 touches on the exact chain, fits the four features
and evaluates four measurands.

Figures: ``vcmm_runs_per_s`` (full runs), and side by side in the same
run ``vcmm_simulate_share`` (the share of a run spent simulating the
touches on an already-built machine: the rest is the machine's build,
the draws, the fits and the measurands).
"""

from __future__ import annotations

import math
import time

import numpy as np

RUNS = 40
SEED = 20261201


def plan_100():
    """A 100-touch plan of the README's block (see :func:`scenarios.vcmm.block_plan`)."""
    from core.probelog import make_log

    r = 3.0
    rows = []
    for k in range(32):
        a = 2 * math.pi * (k + 0.5) / 32
        rows.append(("bore", (10 + 10 * math.cos(a), 10 * math.sin(a), -10.0 - 5 * (k % 2)),
                     (-math.cos(a), -math.sin(a), 0.0)))
    for side, x, nx in (("left", -40.0, -1.0), ("right", 40.0, 1.0)):
        for y in np.linspace(-24, 24, 8):
            for z in (-20.0, -8.0):
                rows.append((side, (x, y, z), (nx, 0.0, 0.0)))
    for x in np.linspace(-35, 35, 8):
        for y in np.linspace(-25, 25, 6):
            if len([q for q in rows if q[0] == "top"]) < 36 and not (-2 <= x <= 22 and abs(y) <= 12):
                rows.append(("top", (x, y, 0.0), (0.0, 0.0, 1.0)))
    n = len(rows)
    s = np.array([p for _, p, _ in rows])
    nn = np.array([v for _, _, v in rows])
    Xn = s + r * nn
    nan = np.full(n, np.nan)
    return make_log({"setup": ["S1"] * n, "target": [f"P{i:03d}" for i in range(n)], "t_s": nan,
                     "X_mm": nan, "Y_mm": nan, "Z_mm": nan, "Xn_mm": Xn[:, 0], "Yn_mm": Xn[:, 1],
                     "Zn_mm": Xn[:, 2], "nx": nn[:, 0], "ny": nn[:, 1], "nz": nn[:, 2],
                     "feature": [f for f, _, _ in rows], "stylus_r_mm": np.full(n, r)})


def run() -> dict:
    from importlib import resources

    from core.vcmm import loads_task
    from scenarios import vcmm as S
    from sim.machine import Machine
    from sim.machinefile import resolve

    plan = plan_100()
    text = (resources.files("scenarios") / "data" / "vcmm-block-task.toml").read_text(encoding="utf-8")
    st = S.prepare(plan, loads_task(text), resolve("vmc-3axis"))
    assert len(st.Xn_R) == 100, len(st.Xn_R)
    S.run_values(st, SEED, range(2))                         # warm-up (imports, first builds)
    t0 = time.perf_counter()
    S.run_values(st, SEED, range(RUNS))
    t_full = time.perf_counter() - t0
    m = Machine(st.config)
    rng = np.random.default_rng(SEED)
    t0 = time.perf_counter()
    for _ in range(RUNS):
        S.simulate_run(st, {}, rng, machine=m)
    t_sim = time.perf_counter() - t0
    return {"vcmm_touches": 100, "vcmm_runs": RUNS, "vcmm_runs_per_s": round(RUNS / t_full, 2),
            "vcmm_simulate_share": round(t_sim / t_full, 3)}
