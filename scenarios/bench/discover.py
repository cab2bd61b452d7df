"""Benchmark of model discovery: the demo's campaign (432 touches), timed beside a reference.

Issue 19 item 6: discover on the demo campaign under 0.2 s. These machines
are shared and noisy, so the time is given as CPU seconds (the median of
five runs) and as a ratio to a reference measured in the same run: a fixed
dense linear-algebra workload of the same shape as discovery's (twenty
pivoted QR factorisations of a 432 x 160 design), whose own time says how
fast the machine was at that moment. ``discover_demo_baseline_cpu_s`` is the
planar baseline's build alone (the grids tried, each designed and factored),
timed in the same loop: its ratio to ``discover_demo_cpu_s`` is the share of
a discover that the engine does not spend.
"""

from __future__ import annotations

import time

import numpy as np


#: figure -> its reference figure measured in the same run (ratio = figure / reference); the
#: baseline's share: the planar builder (core.baseline.planar: the error-map grids tried, each
#: designed and factored) inside one discover, the rest is the engine
REFERENCES = {"discover_demo_cpu_s": "discover_demo_reference_cpu_s",
              "discover_demo_baseline_cpu_s": "discover_demo_cpu_s"}
#: the target on the CPU time, the figure read against its same-run reference (the wall time of a shared,
#: loaded machine counts other processes' turns: 1.16 s wall for 0.18 s of CPU at load 11)
TARGETS = {"discover_demo_cpu_s": "< 0.2 s (issue 19 item 6)"}


def demo_campaign():
    """The touches of ``vmt demo`` (same machine, probe, hidden effects and seed)."""
    from core.touches import from_log

    return from_log(demo_campaign_log())


def demo_campaign_log():
    """The probe log of ``vmt demo``'s campaign (:func:`demo_campaign`'s touches)."""
    from scenarios.demo import LOBING_M, SCREW_MM, SCREW_UM
    from scenarios.hidden import drift_check_plan
    from sim import artefacts as A
    from sim.campaign import simulate_campaign
    from sim.errorfuncs import Periodic
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors
    from sim.probe import ProbeConfig

    seed = 2026
    errs = realistic_errors(("X", "Y", "Z", "C"), rng=np.random.default_rng(seed), ripple=False)
    errs["EYY"] = errs["EYY"] + Periodic(SCREW_UM * 1e-6, SCREW_MM * 1e-3, 0.7)
    machine = Machine(MACHINES["nmv3000"](errors=errs))
    probe = ProbeConfig(repeatability_k2_m=0.6e-6, lobing_m=LOBING_M)
    art = A.cross_pocket()
    log = simulate_campaign(art, machine, probe, [0.0, 75.0, 130.0, 210.0], np.random.default_rng(seed + 1),
                            plan=drift_check_plan(art), check_collisions=False)
    return log


def _reference_s() -> float:
    """CPU seconds of the reference workload (twenty pivoted QR of a 432 x 160 matrix)."""
    import scipy.linalg as sla

    A = np.random.default_rng(0).normal(size=(432, 160))
    t0 = time.process_time()
    for _ in range(20):
        sla.qr(A, mode="economic", pivoting=True)
    return time.process_time() - t0


def run() -> dict:
    from core import baseline, selfcal
    from core.discover import Settings, discover

    t = demo_campaign()
    d = discover(t)  # warm caches and imports
    named = {f.cause for f in d.findings}
    if not {"periodic_axis_error", "probe_lobing"} <= named:  # a benchmark of a wrong answer is no figure
        raise RuntimeError(f"discover named {sorted(named)} on the demo campaign")
    cpu, wall, ref, base = [], [], [], []
    for _ in range(5):
        ref.append(_reference_s())
        c0 = time.process_time()
        baseline.planar(t, None, Settings().grid_steps_mm, yaw=selfcal.yaw_for_chain(None), extra={})  # as discover
        base.append(time.process_time() - c0)
        c0, w0 = time.process_time(), time.perf_counter()
        discover(t)
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    c, r = float(np.median(cpu)), float(np.median(ref))
    return {"discover_demo_cpu_s": round(c, 4), "discover_demo_wall_s": round(float(np.median(wall)), 4),
            "discover_demo_reference_cpu_s": round(r, 4), "discover_demo_ratio_to_reference": round(c / r, 3),
            "discover_demo_baseline_cpu_s": round(float(np.median(base)), 4), "discover_touches": int(t.n)}
