"""discover on logs from another generator: not the simulator's quirks.

A first-order generator unlike the simulator: a random star-shaped part of
72 points (no spheres, no drift-check repeats), five random C angles, a
stylus of 2 mm, smooth machine errors and a workpiece form, 0.3 um noise,
each cause at a random 1-4 um. Required over 10 seeds per cause: none
stays none 9/10; periodic, non-rigid and lobing named 9/10. Drift and
reversal are the hard ones here: without repeated touches, and with five
random angles and a 22 mm error map, about 90 % of their signature lies
inside what the self-calibration model already explains (measured: 10-14 %
of the candidate columns lie outside the baseline's column space), so the
smallest are invisible (measured rates 60-85 % over 25 seeds). For them
the test asks what must hold: half named, and never a wrong cause in 9/10
(missed means 'none', not a guess).
"""

import dataclasses

import numpy as np
import pytest

from core import selfcal
from core.discover import discover

N = 10


def _part(rng, n=72):
    th = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = 0.07 + 0.02 * np.cos(3 * th + 0.5) + 0.01 * np.sin(5 * th)
    dr = -0.06 * np.sin(3 * th + 0.5) + 0.05 * np.cos(5 * th)
    p = np.column_stack([r * np.cos(th), r * np.sin(th)])
    tang = np.column_stack([dr * np.cos(th) - r * np.sin(th), dr * np.sin(th) + r * np.cos(th)])
    tang /= np.linalg.norm(tang, axis=1)[:, None]
    return p, np.column_stack([tang[:, 1], -tang[:, 0]])


def _log(cause, rng):
    p, n = _part(rng)
    c = np.sort(rng.choice(np.arange(0, 360, 5), size=5, replace=False)).astype(float)
    t = selfcal.nominal_touches(p, n, c - c[0], stylus_r_m=0.002)
    x, y = t.pn_R[:, 0], t.pn_R[:, 1]
    nx, ny = t.n_R[:, 0], t.n_R[:, 1]
    phi = np.arctan2(t.d_R[:, 1], t.d_R[:, 0])
    tt = np.arange(t.n) / t.n
    m = rng.uniform(1, 4) * 1e-6 * rng.choice([-1, 1])
    dq = (-nx * (5e-6 * x / 0.1 + 2e-6 * (y / 0.1) ** 2) - ny * 3e-6 * np.sin(x / 0.05)
          + 1e-6 * np.sin(7 * np.arctan2(p[:, 1], p[:, 0]))[t.target])
    effect = {
        "none": 0 * x,
        "thermal_drift": [-nx * m * tt, -ny * m * tt, -nx * (x / 0.1) * m * tt][rng.integers(3)],
        "probe_lobing": abs(m) * np.cos(2 * phi + rng.uniform(0, 6)) + 0.5 * abs(m) * np.cos(3 * phi + rng.uniform(0, 6)),
        "reversal": (-nx * np.sign(t.d_R[:, 0]) if rng.random() < 0.5 else -ny * np.sign(t.d_R[:, 1])) * abs(m) / 2,
        "nonrigid": -nx * (x / 0.08) * (y / 0.08) * m,
        "periodic_axis_error": -[nx, ny][rng.integers(2)] * abs(m)
        * np.sin(2 * np.pi * [x, y][rng.integers(2)] / rng.uniform(0.005, 0.015)),
    }[cause]
    dq = dq + effect + rng.normal(0, 0.3e-6, t.n)
    return dataclasses.replace(t, p_R=t.pn_R + dq[:, None] * t.n_R, t_s=np.arange(t.n) * 8.0)


@pytest.mark.parametrize("cause", ["none", "periodic_axis_error", "nonrigid", "probe_lobing"])
def test_another_generator(cause):
    named = [discover(_log(cause, np.random.default_rng([77, s]))).cause for s in range(N)]
    assert sum(c == cause for c in named) >= 9, named


@pytest.mark.parametrize("cause", ["thermal_drift", "reversal"])
def test_another_generator_hard_causes_are_missed_not_misnamed(cause):
    named = [discover(_log(cause, np.random.default_rng([77, s]))).cause for s in range(N)]
    assert sum(c == cause for c in named) >= N // 2, named
    assert sum(c in (cause, "none") for c in named) >= 9, named
