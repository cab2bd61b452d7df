"""Hidden-effect tests: an effect hidden in the simulated machine or probe
(never added to the log) must be found and named by ``discover``.

Magnitudes are drawn at random in 1-4 um (chips 3-10 um: a chip is gross by
definition), over 0.3 um probing noise (standard deviation), with random
parameters, on a realistic machine whose smooth errors the baseline model
represents. Each case runs the full path: simulate -> probe-log/1 ->
core.touches -> discover.
"""

import numpy as np
import pytest

from core.discover import discover
from core.touches import from_log
from scenarios.hidden import hidden_campaign, workpiece_errors_um

N_SEEDS = 20


def _run(causes, seed, **kw):
    log, truth = hidden_campaign(causes, seed, **kw)
    rep = discover(from_log(log)).to_report()
    return rep, truth


@pytest.fixture(scope="module")
def results():
    """Every case once: {cause: [(report, truth), ...]}."""
    out = {}
    for cause in ("none", "outlier", "thermal_drift", "periodic_axis_error", "probe_lobing", "reversal",
                  "nonrigid"):
        out[cause] = [_run((cause,), 1000 + s) for s in range(N_SEEDS)]
    return out


def test_none_stays_none(results):
    named = [r["cause"] for r, _ in results["none"]]
    assert named.count("none") >= 0.95 * N_SEEDS, named


@pytest.mark.parametrize("cause", ["outlier", "periodic_axis_error", "probe_lobing", "reversal", "nonrigid"])
def test_cause_named(results, cause):
    named = [r["cause"] for r, _ in results[cause]]
    hits = sum(n == cause for n in named)
    assert hits >= 0.95 * N_SEEDS, named


def test_thermal_drift_named(results):
    """Drift over the campaign of 1-4 um: the detection limit is physical.

    Within one set-up the probe's path ties time to position, so most of a
    drift is indistinguishable from the machine's error map; only the
    drift-check repeats see it cleanly. An offset drift of 1.2 um over four
    set-ups is 0.3 um per set-up, the noise level. Required: every drift of
    2 um or more named, and 85 % of all (measured on 30 other seeds: 28/30,
    both misses below 1.7 um).
    """
    cases = results["thermal_drift"]
    named = [r["cause"] for r, _ in cases]
    big = [r["cause"] for r, t in cases if abs(t.params["thermal_drift"]["total_um"]) >= 2.0]
    assert all(n == "thermal_drift" for n in big), big
    assert sum(n == "thermal_drift" for n in named) >= 0.85 * N_SEEDS, named


def test_outlier_rows_are_the_chipped_touches(results):
    exact = 0
    for rep, truth in results["outlier"]:
        if rep["cause"] == "outlier":
            exact += set(rep["outlier_rows"]) == set(truth.outlier_rows)
    assert exact >= 0.9 * N_SEEDS


@pytest.mark.parametrize("cause", ["outlier", "thermal_drift", "periodic_axis_error", "probe_lobing",
                                   "reversal", "nonrigid"])
def test_extended_workpiece_closer_to_truth(results, cause):
    """Averaged over the cases where the cause was named, the extended
    model's workpiece is closer to the truth than the baseline's."""
    errs = [workpiece_errors_um(r, t) for r, t in results[cause] if r["cause"] == cause]
    base, ext = np.mean(errs, axis=0)
    assert ext < base, (base, ext)


def test_gain_is_measured(results):
    for cause in ("periodic_axis_error", "probe_lobing", "reversal", "nonrigid"):
        for rep, _ in results[cause]:
            if rep["cause"] == cause:
                assert rep["gain"]["rms_ratio"] < 1 and rep["gain"]["cv_rms_ratio"] < 1


@pytest.mark.parametrize("causes", [("thermal_drift", "periodic_axis_error"), ("probe_lobing", "nonrigid"),
                                    ("outlier", "probe_lobing"), ("reversal", "nonrigid"),
                                    ("outlier", "thermal_drift")])
def test_two_effects_both_found(causes):
    found = 0
    for s in range(6):
        rep, truth = _run(causes, 2000 + s)
        if all(a in {f["cause"] for f in rep["findings"]} for a in causes):
            # drift below 2 um may hide under the other effect (see above)
            found += 1
        elif "thermal_drift" in causes and abs(truth.params["thermal_drift"]["total_um"]) < 2.0:
            found += 1
    assert found >= 5


def test_generalises_to_another_part_angles_and_noise():
    """Not the cross pocket's quirks: the free-form plate at five other C
    angles, 0.2 um noise; a lobing probe is found, a clean one is not."""
    import numpy as np

    from sim.campaign import simulate_campaign
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors
    from sim.probe import ProbeConfig

    m = Machine(MACHINES["nmv3000"](errors=realistic_errors(("X", "Y", "Z", "C"), rng=np.random.default_rng(4),
                                                             ripple=False)))
    angles = [0, 60, 150, 240, 300]
    clean = simulate_campaign("freeform", m, ProbeConfig(repeatability_k2_m=0.4e-6), angles,
                              np.random.default_rng(1))
    assert discover(from_log(clean)).cause == "none"
    lob = ProbeConfig(repeatability_k2_m=0.4e-6, lobing_m=((3, 2.0e-6, -1.0e-6),))
    dirty = simulate_campaign("freeform", m, lob, angles, np.random.default_rng(1))
    assert discover(from_log(dirty)).cause == "probe_lobing"


def test_generalises_to_a_machine_whose_y_rides_on_x():
    """The Mikron's Y rides on X: the rigid model's yaw is ECX(x), read from the
    log's kinematic_chain. A clean pin-circle campaign stays 'none' (with the
    paper's ECY model it would look non-rigid); a lobing probe is found."""
    from sim.campaign import simulate_campaign
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors
    from sim.probe import ProbeConfig

    cfg = MACHINES["mikron-ucp710"]()
    errs = realistic_errors(("X", "Y", "Z", "C"), strokes=cfg.strokes, rng=np.random.default_rng(2), ripple=False)
    m = Machine(MACHINES["mikron-ucp710"](errors=errs))
    angles = [0, 31, 83, 137, 191, 227, 257, 313]
    for lobing, cause in (((), "none"), (((2, 1.5e-6, 0.8e-6),), "probe_lobing")):
        log = simulate_campaign("pin-circle", m, ProbeConfig(repeatability_k2_m=0.6e-6, lobing_m=lobing), angles,
                                np.random.default_rng(3), check_collisions=False)
        assert discover(from_log(log), chain=log.meta["kinematic_chain"]).cause == cause
