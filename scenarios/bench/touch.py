"""Touch-trigger simulation speed: a full MFB campaign (17 x 316 = 5,372 touches).

Figures: ``touches_per_s`` and ``mfb_campaign_s`` (simulation with the
root finding batched over each set-up's touches, plan validation included,
MuJoCo path checks excluded) and ``mfb_collision_check_s`` (the MuJoCo
checks of every link, approach and retract path of the same campaign).
"""

from __future__ import annotations

import time


def run() -> dict:
    import numpy as np

    from sim.campaign import simulate_campaign
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors
    from sim.probe import ProbeConfig

    cfg = MACHINES["mikron-ucp710"]()
    m = Machine(MACHINES["mikron-ucp710"](errors=realistic_errors(("X", "Y", "Z", "A", "C"), strokes=cfg.strokes,
                                                                  J_m=cfg.J_m)))
    rng = np.random.default_rng(1)
    simulate_campaign("cross-pocket", m, ProbeConfig(), [0.0], rng, check_collisions=False)  # warm-up
    t0 = time.perf_counter()
    log = simulate_campaign("mfb", m, ProbeConfig(), None, rng, check_collisions=False)
    t_sim = time.perf_counter() - t0
    t0 = time.perf_counter()
    simulate_campaign("mfb", m, ProbeConfig(), None, rng, check_collisions=True)
    t_all = time.perf_counter() - t0
    return {
        "touches_per_s": round(log.n / t_sim, 1),
        "mfb_campaign_s": round(t_sim, 3),
        "mfb_touches": int(log.n),
        "mfb_collision_check_s": round(max(t_all - t_sim, 0.0), 3),
    }
