"""discover on logs from another generator: not the simulator's quirks.

A first-order generator unlike the simulator: a random star-shaped part of
72 points (no spheres, no drift-check repeats), five random C angles, a
stylus of 2 mm, smooth machine errors and a workpiece form, 0.3 um noise,
each cause at a random 1-4 um, six seeds per cause. Drift and reversal are
mostly inside what the self-calibration model explains here (no repeated
touches, five random angles): most keep less than a noise sigma per touch
after the baseline, the physical limit, so the aim is asked of the visible
ones.
"""

import dataclasses

import numpy as np
import pytest

from core import selfcal
from core.discover import discover

N = 6


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


def _visible_sigmas(d) -> float:
    """What the baseline leaves of the effect, in noise sigmas (true noise 0.3 um)."""
    rep = d.to_report()
    n, p = d.baseline.n, rep["baseline"]["n_params"]
    return float(np.sqrt(max(rep["baseline"]["rms_um"] ** 2 - 0.3 ** 2 * (n - p) / n, 0.0)) / 0.3)


@pytest.fixture(scope="module")
def results():
    out = {}
    for cause in ("none", "periodic_axis_error", "nonrigid", "probe_lobing", "thermal_drift", "reversal"):
        out[cause] = []
        for s in range(N):
            d = discover(_log(cause, np.random.default_rng([77, s])))
            out[cause].append((d.cause, _visible_sigmas(d)))
    return out


def test_effect_free_campaigns_get_no_catalogue_name(results):
    """The generator's effect-free campaigns carry smooth errors the error
    map's grid does not follow exactly: 'unexplained' structure may be
    reported (it is real), a catalogue cause never."""
    named = [c for c, _ in results["none"]]
    assert all(c in ("none", "unexplained") for c in named), named
    assert named.count("none") >= N - 2, named


def test_visible_catalogue_effects_named(results):
    """Every effect that keeps at least one noise sigma per touch after the
    baseline is named (aim: 95 %); the smaller ones are at the physical
    limit of this design (no repeated touches, five random angles)."""
    vis = [(cause, c, v) for cause in results if cause != "none" for c, v in results[cause] if v >= 1.0]
    hits = sum(c == cause for cause, c, _ in vis)
    assert len(vis) >= 9 and hits >= 0.95 * len(vis), [(a, b, round(v, 2)) for a, b, v in vis if a != b]
