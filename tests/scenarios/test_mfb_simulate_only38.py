"""Session 38 (mfbfast38): ``scenarios.mfb.run(simulate_only=True)``, the campaign without its identification.

scenarios.hidden's MFB campaigns are read by discovery through their measurements only; run() identified them,
tested the residuals and propagated the U95 besides (1.2 of the 3.0 s CPU of a hidden campaign with its discovery).
With ``simulate_only`` it returns after the measurements. Checked against the full run of the same arguments (a path
that identifies, the reference): every measurement field and the campaign equal bit for bit (tolerance none: the
same draws, in the same order, nothing after the measurements draws before them), with a hook (hidden_mfb's way) and
with noise.
"""

import dataclasses

import numpy as np
import pytest

from scenarios import mfb
from scenarios.mfb import run


def _same(a, b):
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(_same(u, v) for u, v in zip(a, b))
    return a == b


@pytest.mark.parametrize("name,seed", [("mfb-3axis", 5), ("mfb-5axis", 6)])
def test_simulate_only_gives_the_full_runs_campaign_bit_for_bit(name, seed):
    def hook(i, spec, art, probe, machine):  # a hook as hidden_mfb's: the machine of measurement i scaled
        from sim.errorfuncs import Polynomial
        errs = dict(machine.config.errors)
        errs["EXX"] = errs["EXX"] + Polynomial((0.0, 2e-6 * i)) if "EXX" in errs else Polynomial((0.0, 2e-6 * i))
        return art, probe, machine.with_errors(errs)

    kw = dict(seed=seed, mc_runs=0, hook=hook, extraction=False)
    full = run(name, **kw)
    only = run(name, **kw, simulate_only=True)
    assert only.result is None and only.unc is None and only.truth is None
    assert only.doc == {"format": mfb.MFB_FORMAT, "scenario": name, "machine": full.plan.machine, "seed": seed,
                        "noise_um": full.doc["noise_um"], "touches": full.doc["touches"], "simulated_only": True}
    assert only.n_touches == full.n_touches and only.plan == full.plan
    assert only.strokes_m == full.strokes_m and only.J_m == full.J_m
    assert len(only.meas) == len(full.meas) > 0
    for m, f in zip(only.meas, full.meas):
        for fld in dataclasses.fields(f):
            assert _same(getattr(m, fld.name), getattr(f, fld.name)), (m.name, fld.name)
    c, cf = only.campaign, full.campaign
    assert c.keys() == cf.keys()
    for k in c:
        if k == "logs":
            for a, b in zip(c[k], cf[k]):
                assert _same(dict(a.columns), dict(b.columns)) and a.meta == b.meta
        else:
            assert _same(c[k], cf[k]), k


def test_a_campaign_of_simulate_only_writes_the_same_log():
    """campaign_log (vmt simulate's writer) of the campaign alone is the full run's log."""
    from scenarios.mfb import campaign_log

    kw = dict(seed=7, mc_runs=0)
    a, b = campaign_log(run("mfb-3axis", **kw, simulate_only=True)), campaign_log(run("mfb-3axis", **kw))
    assert a.meta == b.meta and _same(dict(a.columns), dict(b.columns))


def test_the_hidden_bending_with_one_bar_per_shape_is_the_bar_built_per_measurement():
    """hidden_mfb's bar_bending keeps one bent bar object per shape (session 38: 4 shapes over the 3-axis plan's 17
    measurements; the bar's build and its touch plans made once). Reference: the hook as written before, a bar built
    for every measurement (its rule copied here: the sag drawn from the seed's stream [seed, 7] as hidden_mfb draws
    it, gravity through bar_gravity_A), run on the same seed: the measurements bit for bit (tolerance none)."""
    from scenarios.hidden import UM, bar_gravity_A, hidden_mfb
    from sim import artefacts as A

    seed = 7
    rng = np.random.default_rng([seed, 7])
    rng.uniform(5, 15, 3), rng.choice([-1.0, 1.0], 3)  # the drift's draws, made first whatever the cause
    sag = float(rng.uniform(1.0, 4.0)) * UM
    built = []

    def hook(i, spec, art, probe, machine):
        rot = np.asarray(spec.rot_rad, float).reshape(1, -1) if len(spec.rot_rad) else None
        g_A = bar_gravity_A(spec.T_W_A, machine.T_R_W_nominal(rot)[0])
        E = np.asarray(art.info["E_MFB_m"], float)
        s = np.linspace(-1, 1, len(E))
        bend = sag * ((1 - s ** 2) ** 2 - np.mean((1 - s ** 2) ** 2))
        built.append(A.multi_feature_bar(deviations_m=E + bend[:, None] * g_A[None, :]))
        return built[-1], probe, machine

    ref = run("mfb-3axis", seed=seed, mc_runs=0, hook=hook, extraction=False, simulate_only=True)
    res, _, params = hidden_mfb("bar_bending", seed)
    assert params["midspan_sag_um"] == sag / UM
    assert len(built) == len(res.meas) == 17
    for m, f in zip(res.meas, ref.meas):
        for fld in dataclasses.fields(f):
            assert _same(getattr(m, fld.name), getattr(f, fld.name)), (m.name, fld.name)
