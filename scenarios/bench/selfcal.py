"""Benchmark of the 2D self-calibration: MC speed and identification time vs touches and grid size."""

from __future__ import annotations

import time

import numpy as np


def _campaign(n_targets: int, n_angles: int, grid_n: int, rng):
    """Random free-form targets (radius 20..95 mm) at n_angles C angles; in-model truth + 1 um noise."""
    from dataclasses import replace

    from core.selfcal import Grid, build_design, nominal_touches

    r = rng.uniform(0.02, 0.095, n_targets)
    a = rng.uniform(0, 2 * np.pi, n_targets)
    w = np.column_stack([r * np.cos(a), r * np.sin(a)])
    b = rng.uniform(0, 2 * np.pi, n_targets)
    wn = np.column_stack([np.cos(b), np.sin(b)])
    c = np.round(np.linspace(0, 360, n_angles, endpoint=False) + 7.0, 3)
    t = nominal_touches(w, wn, c)
    lo, hi = t.pn_R[:, :2].min(axis=0), t.pn_R[:, :2].max(axis=0)
    g = Grid(np.linspace(lo[0], hi[0], grid_n), np.linspace(lo[1], hi[1], grid_n))
    des = build_design(t, g)
    th = des.to_gauge(rng.normal(0, 3e-6, des.n_params))
    dq = des.A @ th + rng.normal(0, 1e-6, t.n)
    return replace(t, p_R=t.pn_R + dq[:, None] * t.n_R), g


def _time_identify(n_targets, n_angles, grid_n, rng):
    from core.selfcal import self_calibrate

    t, g = _campaign(n_targets, n_angles, grid_n, rng)
    t0 = time.perf_counter()
    self_calibrate(t, g, covariance="none")
    return round(time.perf_counter() - t0, 4)


def run() -> dict:
    from core.design import example_cross_pocket
    from core.selfcal import Grid
    from core.uncertainty import monte_carlo

    out = {}
    w, wn, _ = example_cross_pocket()
    grid = Grid.regular(-0.110, 0.110, 0.022)
    monte_carlo(w, wn, [0, 75, 130, 210], grid, runs=100, rng=np.random.default_rng(0))  # warm-up
    t0 = time.perf_counter()
    monte_carlo(w, wn, [0, 75, 130, 210], grid, runs=1000, rng=np.random.default_rng(1))
    dt = time.perf_counter() - t0
    out["selfcal_mc_1000_cross_pocket_s"] = round(dt, 4)
    out["mc_runs_per_s"] = round(1000 / dt, 1)
    rng = np.random.default_rng(2026)
    # growth with touches (grid 20 x 20) and with grid size (1e4 touches)
    for n_t, n_c in ((100, 10), (1000, 10), (10000, 10)):
        out[f"selfcal_s_{n_t * n_c:.0e}_touches_grid20".replace("+0", "")] = _time_identify(n_t, n_c, 20, rng)
    for gn in (10, 40, 100):
        out[f"selfcal_s_1e4_touches_grid{gn}"] = _time_identify(1000, 10, gn, rng)
    out["grid100_1e5_touches_s"] = _time_identify(10000, 10, 100, rng)
    return out
