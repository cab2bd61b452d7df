"""Benchmark of the virtual machine's forward kinematics (5-axis nmv3000,
realistic errors): Pinocchio with every error joint, Pinocchio's own nominal
FK on the error-free model and core's vectorised numpy product, same run."""

from __future__ import annotations

import time

import numpy as np


def _rate(f, n, repeat=3):
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t)
    return n / best


def run(n: int = 20000) -> dict:
    from core import kinematics as K
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors

    cfg = MACHINES["nmv3000"]()
    m = Machine(cfg)
    m = m.with_errors(realistic_errors(m.chain.axes, strokes=cfg.strokes, J_m=cfg.J_m, rng=np.random.default_rng(0)))
    rng = np.random.default_rng(1)
    lin = np.column_stack([rng.uniform(*cfg.strokes[a], n) for a in "XYZ"])
    rot = np.column_stack([rng.uniform(*cfg.strokes[a], n) for a in m.rotary_axes])
    geom = m.geometry()
    err = _rate(lambda: m.tip_W(lin, rot), n)
    nom = _rate(lambda: m._nominal_fk_tip(lin, rot), n)
    core = _rate(lambda: K.tip_W(geom, lin, rot, m.error_values(lin, rot)), n)
    return {
        "fk_error_poses_per_s": round(err),
        "fk_nominal_poses_per_s": round(nom),
        "fk_error_cost_ratio": round(nom / err, 3),
        "fk_core_numpy_error_poses_per_s": round(core),
    }


if __name__ == "__main__":  # pragma: no cover
    print(run())
