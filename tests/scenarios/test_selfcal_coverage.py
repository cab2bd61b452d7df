"""The self-calibration's U95 against the exact simulator's truth, per block (issue 14 item 4).

Campaigns are shared by the module (one simulation each). The bigger study
(20 seeds per machine and noise, Clopper-Pearson intervals) is in
``make bench`` (scenarios.bench.selfcal, ``coverage_*`` figures).
"""

import numpy as np
import pytest

from core.selfcal import workpiece_form
from core.units import UM
from scenarios.selfcal_coverage import BLOCKS, block_truth, identify_and_cover, simulate

MACHINES = ("nmv3000", "mikron-ucp710")  # X on Y (yaw ECY), Y on X (yaw ECX)
SEEDS = range(4)
NOISES_M = (0.0, 0.5e-6)


@pytest.fixture(scope="module")
def campaigns():
    """The realistic machines with every screw ripple at phase 0: the truth these tests were written on
    (sim.machines.realistic_errors before session 27). A phase that flatters the workpiece and C-axis
    blocks; at phases drawn per seed they do not cover (test_drawn_ripple_phases_...)."""
    return {(m, nz): [simulate(m, s, nz, ripple_phase=0.0) for s in SEEDS] for m in MACHINES for nz in NOISES_M}


def pooled(cs, **kw):
    tot = {b: [0, 0] for b in BLOCKS}
    for c in cs:
        for b, (k, n) in identify_and_cover(c, **kw)[1].items():
            tot[b][0] += k
            tot[b][1] += n
    return {b: k / n for b, (k, n) in tot.items()}


def test_truth_extraction_and_identification_agree_in_the_model_space():
    """Errors the extended model represents exactly (straight tables, constant squareness, a
    C axis that wobbles and tilts per set-up, angular errors linear in x and y acting through
    the spheres' height): noise free, the identification equals the simulator's truth in
    its gauge to second order. The discrepancy of each parameter is at most what 20 nm of
    probing noise would give it (|error| / u(1 m of noise) < 2e-8; measured 8.7e-9, from
    second-order cross terms: residual RMS 2.3 nm), the workpiece within 50 nm (21), and
    the first-order split of the exact tip deviation into tables leaves < 1 nm. A sign or
    frame error in the truth or in the height model would show as micrometres."""
    from sim.errorfuncs import Constant, Periodic, Polynomial

    errs = {"EXX": Polynomial((0.0, 1.2e-4)), "EYY": Polynomial((1e-6, -6e-5)), "EYX": Polynomial((0.0, 2e-5)),
            "EXY": Polynomial((0.0, -3e-5)), "EC0Y": Constant(-43.4e-6), "ECY": Polynomial((4e-6, 0.0)),
            "EBX": Polynomial((1e-5, 3e-4)), "EAY": Polynomial((-5e-6, 2e-4)), "EB0Z": Constant(20e-6),
            "EX0C": Constant(15e-6), "EY0C": Constant(6e-6), "ECC": Periodic(12e-6, 2 * np.pi),
            "EXC": Periodic(1.5e-6, 2 * np.pi), "EBC": Periodic(3e-6, 2 * np.pi), "EAC": Periodic(3e-6, 2 * np.pi, 1.0)}
    from core.selfcal import estimator

    c = simulate("nmv3000", 0, 0.0, errors=errs)
    res, _, misfit = identify_and_cover(c, model_error=False)
    raw, _ = block_truth(c, res.design)
    err = np.abs(res.theta - res.design.to_gauge(raw))
    u1 = estimator(c.touches, res.design.grid)[1].std(1.0)
    free = u1 > 0
    assert res.design.heights.abbe and misfit < 1e-9
    assert (err[free] / u1[free]).max() < 2e-8
    assert err[res.design.slices["G"]].max() < 50e-9 and res.rms_m < 5e-9


def test_height_terms_remove_the_spheres_model_error():
    """Issue 14: the sphere equators sit 25.7 mm above the pocket walls; the planar model
    leaves the height effect in the workpiece. Noise free, smooth realistic errors (no
    ripple), nmv3000: the workpiece form error (shift, rotation, scale, offset and the
    height terms' tilt, twist and growth removed) falls from 0.196 um RMS (planar, measured)
    to 0.0042 um, the pocket's alone from 0.204 to 0.0042 um (the pocket without the
    spheres: 0.0024)."""
    from scenarios.hidden import workpiece_truth

    c = simulate("nmv3000", 1, 0.0, ripple=False)
    g = workpiece_truth(c.art, c.plan)
    err = {}
    for name, kw in (("planar", dict(heights=False)), ("heights", {})):
        res, _, _ = identify_and_cover(c, model_error=False, **kw)
        des = res.design
        first = [int(np.flatnonzero(c.touches.target == k)[0]) for k in range(len(des.target_ids))]
        w, wn = c.touches.w_A[first, :2], c.touches.wn_A[first, :2]
        dz = c.touches.pn_R[first, 2] - np.median(c.touches.pn_R[:, 2])
        e = workpiece_form(res.G - np.array([g[k] for k in des.target_ids]), w, wn, dz)
        err[name] = np.sqrt(np.mean(e ** 2))
    assert err["planar"] > 0.1 * UM
    assert err["heights"] < 0.01 * UM


@pytest.mark.parametrize("machine", MACHINES)
def test_u95_covers_per_block(campaigns, machine):
    """Realistic errors (10 mm screw ripple at phase 0, smooth tables, C-axis wobble, height), noise 0
    and 0.5 um, four seeds each: at least 90 % of every block's U95 bands hold the truth.
    Measured on these campaigns: 0.94-0.99 for every block of both machines; 20 seeds per
    machine and noise in the bench."""
    cov = pooled(campaigns[(machine, 0.0)] + campaigns[(machine, 0.5e-6)])
    assert min(cov.values()) >= 0.90, cov


def test_without_heights_and_budget_the_bands_do_not_cover(campaigns):
    """The same campaigns identified the old way (planar model, sigma from the residuals as
    probing noise): noise free on the mikron, EXX, EYY, the C axis and the workpiece cover
    67, 68, 72 and 79 % (issue 14: "EXX 67 %"): the check has teeth."""
    cov = pooled(campaigns[("mikron-ucp710", 0.0)], heights=False, model_error=False)
    assert cov["EXX"] < 0.8 and cov["C-axis"] < 0.85 and cov["workpiece"] < 0.85, cov


@pytest.mark.xfail(strict=True, reason="session 27: the screw ripple at drawn phases leaves the workpiece and "
                                       "C-axis blocks outside their U95 from the residuals alone (noise free "
                                       "0.75-0.86 over 20 seeds); declared (spec_subgrid) it is covered, below")
@pytest.mark.parametrize("machine", MACHINES)
def test_drawn_ripple_phases_are_covered_per_block(machine):
    """The same check with each screw's ripple at the phase sim.machines.realistic_errors draws from the
    seed (session 27), noise free, four seeds: measured workpiece 0.75 and C axis 0.72 (nmv3000), 0.72 and
    0.64 (mikron; its EXX 0.75) against >= 0.90 (seeds 20-39: workpiece 0.80 and 0.76, C axis 0.86 and
    0.75, every block 0.92-1.00 at phase 0; docs/discovery-studies.md, "Session 27: the screw ripple's phase").
    The model-error budget from the residuals alone does not hold a ripple at an arbitrary phase in these
    blocks: the misses are the workpiece's shift, rotation and scale (its form error stays within 0.2 U95),
    the datum eqs 16-17 set on the nodes, where the truth holds the ripple's value and no touch sees it."""
    cov = pooled([simulate(machine, s, 0.0) for s in SEEDS])
    assert min(cov.values()) >= 0.90, cov


@pytest.fixture(scope="module")
def drawn():
    """The realistic machines with each screw's ripple at the phase its seed draws."""
    return {(m, nz): [simulate(m, s, nz) for s in SEEDS] for m in MACHINES for nz in NOISES_M}


@pytest.mark.parametrize("machine", MACHINES)
def test_declared_ripple_covers_drawn_phases(drawn, machine):
    """The same drawn-phase campaigns (noise 0 and 0.5 um, four seeds) with the screw ripple declared as
    the spec gives it (spec_subgrid: 1 % of each 'lin' table's nominal magnitude, 10 mm, phase unknown):
    every block's U95 holds the truth in >= 90 % (measured on these 8 campaigns: 0.967-1.000 per block, without
    the declaration 0.750-0.975, workpiece 0.85 and 0.83, C axis 0.79 and 0.75; on
    the held-out seeds 200-239: noise free 1.000 in every block, both machines, 0.5 um 0.958-0.986;
    docs/discovery-studies.md, "Session 27: a declared sub-grid ripple"). Without the declaration the same
    campaigns miss (the xfail above)."""
    from scenarios.selfcal_coverage import spec_subgrid

    cov = pooled(drawn[(machine, 0.0)] + drawn[(machine, 0.5e-6)], subgrid=spec_subgrid())
    assert min(cov.values()) >= 0.90, cov


def test_spec_subgrid_is_the_generators_bound():
    """spec_subgrid declares what sim.machines.realistic_errors can put there: the ripple's amplitude is
    1 % of a magnitude drawn in [0.5, 1] x nominal, so every seed's amplitude lies in [0.5, 1] x the
    declared one (checked on the drawn functions of seeds 0-19), period 10 mm."""
    from scenarios.selfcal_coverage import spec_subgrid
    from sim.machines import MACHINES as M, realistic_errors

    spec = spec_subgrid()
    assert set(spec) == {"EXX", "EYY", "ECY"}
    cfg = M["nmv3000"]()
    for sd in range(20):
        errs = realistic_errors(("X", "Y", "Z", "C"), strokes=cfg.strokes, J_m=cfg.J_m, rng=np.random.default_rng(sd))
        for t, (a, p) in spec.items():
            rip = errs[t].terms[1]
            assert rip.period == p and 0.5 * a - 1e-18 <= rip.amplitude <= a + 1e-18
