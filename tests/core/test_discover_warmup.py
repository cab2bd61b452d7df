"""A thermal drift that settles within the campaign: named, with the noise it leaves.

Two defects left gen_a's warm-ups (``1 - exp(-t / tau)``, tau 200-900 s over
campaigns of 1,000-3,500 s) ``unexplained`` on main (seeds 1201, 1202, 1204,
1210, 1211, 1225, 1227 of 1200-1229):

- the drift's only forms were polynomials of degree 1-3 over the campaign,
  which cannot follow a warm-up settling in a fifth of it: what they left
  read as a step early on, and a fixture slip explained as much. A
  first-order thermal response, ``exp(-t / T)`` with ``T`` scanned and
  refined, is now one of the drift's layouts (:func:`core.causes.drift_scans`);
- the noise was the repeats' scatter with only a rate per set-up taken out:
  a warm-up's curvature within the first set-up stayed in it (gen_a 1204:
  2.4 um for a probe of 0.3 um), which made every materiality eight times
  too large. The noise is now the short-term pairs' scatter where their
  test fires (main's ``_short_term``: 1204), else the repeats' scatter
  beyond the model's terms where that leaves 10 degrees of freedom
  (``noise_of`` in :func:`core.discover.discover_baseline`).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib

import numpy as np
import pytest

from core.discover import discover
import discover_synth as S
from tests.discover_helpers import discovered

TAU_FRACTION = 0.15  # the warm-up's time constant over the campaign's duration


def _warm_up(seed: int):
    """The synthetic cross pocket with X and Y offsets and scales settling as ``1 - exp(-t / T)``.

    X: 1 um offset and 20 ppm scale at the end, Y: -0.45 um and 15 ppm
    (written here, not with core.causes' columns: the offsets at the
    part's centre, the scale about it), over 0.3 um noise.
    Returns (touches, T s, x offset change um, x scale change ppm).
    """
    rng = np.random.default_rng(seed)
    t = S.plan()
    mf, _ = S.machine_and_form(t, rng)
    x, y = t.pn_R[:, 0] - t.pn_R[:, 0].mean(), t.pn_R[:, 1] - t.pn_R[:, 1].mean()
    span = float(np.ptp(t.t_s))
    w = 1 - np.exp(-(t.t_s - t.t_s.min()) / (TAU_FRACTION * span))
    e = -t.n_R[:, 0] * 2e-6 * (0.5 + x / 0.1) * w - t.n_R[:, 1] * 1.5e-6 * (y / 0.1 - 0.3) * w
    dq = mf + e + rng.normal(0, S.SIG, t.n)
    w_end = 1 - np.exp(-1 / TAU_FRACTION)
    return dataclasses.replace(t, p_R=t.pn_R + dq[:, None] * t.n_R), TAU_FRACTION * span, 1.0 * w_end, 20.0 * w_end


@functools.cache
def _discovered(seed: int):
    """``discover`` of :func:`_warm_up`'s campaign, once per seed for the two tests that read it (the
    naming, the noise; neither changes it): the same touches and default settings give the same report."""
    return discover(_warm_up(seed)[0])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_warm_up_settling_early_is_named_with_its_time_constant(seed):
    """Named thermal_drift in its warm-up form (main: unexplained on seeds 0-5), the time constant and the
    X changes inside their U95 of the truth (the scale's reference point is the pocket's centre, the
    drift's the positions' mid-range: the scale change compares directly, the offset does not, so the
    offset is held only to its sign and a factor 2)."""
    _, tau, dx_um, sx_ppm = _warm_up(seed)
    rep = _discovered(seed).to_report()
    assert rep["cause"] == "thermal_drift", [(r["cause"], r["reason"]) for r in rep["rejected"]]
    f = rep["findings"][0]
    p, u = f["params"], f["params_u95"]
    assert p["form"] == "warm-up"
    assert abs(p["time_constant_s"] - tau) <= u["time_constant_s"], (p["time_constant_s"], u["time_constant_s"], tau)
    assert abs(p["x_scale_change_ppm"] - sx_ppm) <= u["x_scale_change_ppm"]
    assert 0.5 * dx_um < p["x_offset_change_um"] < 2 * dx_um


def test_a_warm_up_campaign_is_named_with_a_noise_near_the_truth():
    """gen_a thermal_drift 1204 (blind generator; 5 repeat groups of 3, the first set-up's holding the
    warm-up): the repeats read 2.39 um of noise for the generator's 0.304 um and left the drift unexplained
    (a fixture slip explained as much once materiality was 64 times too large). Now the short-term pairs
    give the noise (0.35 um, 5 dof: main's mechanism; the 30 % bound, kept from before, is about one
    relative standard error, 1 / sqrt(2 * 5) = 32 %), and the drift is named."""
    gen = importlib.import_module("scenarios.blind.gen_a")
    log, truth = gen.generate("thermal_drift", 1204)
    d = discovered(log)
    assert d.cause == "thermal_drift"
    assert abs(d.noise["sigma_um"] / truth.noise_um - 1) < 0.3, (d.noise["sigma_um"], truth.noise_um)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_noise_is_the_repeats_beyond_the_named_warm_up(seed):
    """The repeats' scatter with only the rates taken out holds the warm-up's curvature (0.35-0.37 um on
    seeds 0-2 for 0.3 um of noise); beside the named drift its columns' variation within the repeat groups
    goes too: the report says that method and the 52 degrees of freedom it leaves (56 less the drift's
    rank 4 within the groups), and the estimate is within 3 standard errors of the truth (sigma's relative
    s.e. with 52 dof: 1 / sqrt(2 * 52) = 9.8 %)."""
    n = _discovered(seed).noise
    assert n["method"] == "repeats beyond the model's terms" and n["dof"] == 52, (n["method"], n["dof"])
    assert abs(n["sigma_um"] / (S.SIG / 1e-6) - 1) < 3 / np.sqrt(2 * 52), n["sigma_um"]
