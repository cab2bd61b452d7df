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
