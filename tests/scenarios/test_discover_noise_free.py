"""Discovery on noise-free campaigns (session 26): the data's own rounding is the floor.

A user simulating without noise (a regression test against injected errors)
gets exact repeats (their scatter is 0) and, where the baseline represents the
machine exactly, residuals of rounding alone. Discovery must then raise no
warning (pyproject turns a core RuntimeWarning into an error), read ``none``
where every residual is rounding, and still name an effect the data carry.
gen_c's affine machine is one the baseline represents exactly (its noise-free
effect-free round trip gives the workpiece back to 2e-12 um).
"""

import numpy as np
import pytest

from core import discover as disc
from core.touches import from_log
from scenarios.blind import gen_c
from tests.discover_helpers import discovered


def _report(effect, seed, machine="affine"):
    log, _ = gen_c.generate(effect, seed, noise=False, machine=machine)
    d = discovered(log)
    return d, d.to_report()


def test_roundoff_floor_known_answer():
    # 64 eps times the largest coordinate: gen_c's plate reaches about 0.1 m from the table's axis
    log, _ = gen_c.generate("none", 0, noise=False, machine="affine")
    from core.baseline import planar
    bl = planar(from_log(log))
    mag = max(np.max(np.abs(bl.data.x)), np.max(np.abs(bl.data.y)), np.max(np.abs(bl.y)))
    assert disc.roundoff_floor_m(bl) == disc.ROUNDOFF_ULPS * np.finfo(float).eps * mag
    assert 1e-16 < disc.roundoff_floor_m(bl) < 1e-14


@pytest.mark.parametrize("seed", [0, 1])
def test_noise_free_exact_machine_reads_none(seed):
    # every residual is rounding (3e-18 m RMS against a floor of 1.4e-15 m): nothing to find, no warning (before
    # session 26: `unexplained` and a divide-by-zero RuntimeWarning in the held-out gap's noise figure)
    d, rep = _report("none", seed)
    assert rep["baseline"]["rms_um"] < 1e-9
    assert rep["cause"] == "none" and rep["findings"] == []
    assert not rep["structure"]["baseline"]["present"] and not rep["outlier_rows"]
    assert any("within the data's rounding" in c for c in rep["conventions"])


@pytest.mark.parametrize("effect", ["probe_lobing", "reversal"])
def test_noise_free_effect_named_alone(effect):
    # a catalogue form the generator draws exactly: named, and the extended model's residuals are rounding
    # (2.5e-12 um on the workpiece): no `unexplained` beside it (before: the held-out gap of the rounding, judged
    # against the fit's own rounding scatter, called structure)
    d, rep = _report(effect, 0)
    assert rep["cause"] == effect
    assert [f["cause"] for f in rep["findings"]] == [effect]
    assert not rep["structure"]["extended"]["present"]


def test_noise_free_outliers_named_alone():
    # chips on a noise-free campaign: outliers, and nothing else once they are set aside
    d, rep = _report("outlier", 0)
    assert [f["cause"] for f in rep["findings"]] == ["outlier"]


def test_noise_free_smooth_machine_still_finds_its_misfit():
    # the smooth machine's cubic axis errors between the map's nodes leave 5e-9 m RMS (not rounding: 3.5e6
    # times the floor): the floor does not hide a structure the data hold
    d, rep = _report("none", 1, machine="smooth")
    assert rep["baseline"]["rms_um"] > 1e-3
    assert rep["cause"] == "unexplained"


def test_noisy_campaign_untouched_by_the_floor():
    # with the probe's noise the floor is seven orders below every scatter: the same report as with no floor
    log, _ = gen_c.generate("probe_lobing", 3)
    t = from_log(log)
    a = discovered(log, t).to_report()
    import unittest.mock as um
    with um.patch.object(disc, "ROUNDOFF_ULPS", 0.0):
        b = discovered(log, t).to_report()
    import json
    assert json.dumps(a, sort_keys=True, default=str) == json.dumps(b, sort_keys=True, default=str)
