"""Done-when of the hardware issue: a full cross-pocket campaign through
`vmt probe` against the GRBL emulator of the *simulated* machine gives the
same identification as the direct simulation, within the probing noise."""

import numpy as np

from core.probelog import read_probe_log, write_probe_log
from core.selfcal import Grid, self_calibrate
from core.touches import from_log
from hardware.emulator import GrblEmulator, TcpServer
from scenarios.cli import main
from scenarios.hidden import gauge_free_rms_m
from hardware.virtual import sim_machine
from sim import artefacts as A
from sim.campaign import simulate_campaign
from sim.machine import Machine
from sim.machines import MACHINES, realistic_errors
from sim.probe import ProbeConfig

NOISE_UM = 0.3
LIMITS = "X-250:250,Y-250:250,Z-100:200"


def test_cross_pocket_through_grbl_matches_the_direct_simulation(tmp_path):
    angles = [0, 75, 130, 210]
    machine = Machine(MACHINES["nmv3000"](errors=realistic_errors(
        ("X", "Y", "Z", "C"), rng=np.random.default_rng(1), ripple=False)))
    art = A.cross_pocket()
    plan = simulate_campaign(art, machine, ProbeConfig(), angles, None, plan_only=True)
    plan_path = write_probe_log(tmp_path / "plan.csv", plan)
    direct = simulate_campaign(art, machine, ProbeConfig(repeatability_k2_m=2 * NOISE_UM * 1e-6), angles,
                               np.random.default_rng(5))
    emu = GrblEmulator(sim_machine("cross-pocket", NOISE_UM, seed=9), axes="XYZABC", home_mm=(0, 0, 150),
                       limits_mm=((-250, 250), (-250, 250), (-100, 200)))
    srv = TcpServer(emu).start()
    out = tmp_path / "grbl.csv"
    try:
        assert main(["probe", "--machine", srv.url, "--plan", str(plan_path), "--out", str(out),
                     "--limits", LIMITS, "--safe-z", "80", "--timeout", "10", "--rotary"]) == 0
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert log.n == plan.n and log.ok.all()
    grid = Grid.regular(-0.110, 0.110, 0.022)
    a, b = self_calibrate(from_log(direct), grid), self_calibrate(from_log(log), grid)
    assert a.design.target_ids == b.design.target_ids
    # the workpiece form (shift, rotation, scale removed: what self-calibration
    # sees) agrees within the probing noise: two independent 0.3 um draws plus
    # GRBL's 1 um display rounding give ~0.5 um per touch, averaged over four C angles
    ids = a.design.target_ids
    first = {k: plan.col("target").tolist().index(k) for k in ids}
    w = {k: np.array([plan.col("wx_mm")[i], plan.col("wy_mm")[i]]) * 1e-3 for k, i in first.items()}
    wn = {k: np.array([plan.col("wnx")[i], plan.col("wny")[i]]) for k, i in first.items()}
    diff = gauge_free_rms_m(b.G, ids, dict(zip(ids, a.G)), w, wn)
    print(f"gauge-free workpiece difference {diff * 1e6:.3f} um")
    assert diff < NOISE_UM * 1e-6
    assert abs(a.rms_m - b.rms_m) < 0.3e-6
    dq = (log.dq_mm() - direct.dq_mm()) * 1e3
    assert abs(dq.mean()) < 0.1 and dq.std() < 0.6  # touch by touch: noise, no bias
