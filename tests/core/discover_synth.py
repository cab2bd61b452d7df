"""A first-order synthetic campaign for the discovery engine's unit tests.

Not the simulator: the cross pocket's nominal touches (core.design) at four
C angles, each set-up ending with sixteen repeated touches of early targets,
every other one approached 30 deg from above (drift check and
stylus-bending check), times
with a pause between set-ups, smooth machine errors and a workpiece form
written here, one effect added on top in closed form, Gaussian noise. Each
effect is written independently of core.causes' columns (other shapes:
exponential drifts, a Gaussian bump, per-set-up steps).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from core import selfcal
from core.design import example_cross_pocket

SIG = 0.3e-6


def plan(c_deg=(0.0, 75.0, 130.0, 210.0), repeats: int = 16, shift_m=(0.0, 0.0)):
    """Nominal touches: every target at every angle, repeats at the end of each set-up."""
    w, wn, ids = example_cross_pocket()
    base = selfcal.nominal_touches(w, wn, list(c_deg), stylus_r_m=0.003, target_ids=ids)
    nw = len(ids)
    order, el = [], []
    for j in range(len(c_deg)):
        rows = np.arange(j * nw, (j + 1) * nw)
        order += list(rows) + list(rows[:repeats])
        el += [0.0] * nw + [np.radians(30.0) * (i % 2) for i in range(repeats)]
    feat = np.array([i.split("_")[0] if i.startswith("sphere") else "pocket" for i in ids], dtype=object)
    base = dataclasses.replace(base, feature=feat[base.target])
    t = base.subset(np.array(order))
    el = np.array(el)
    d = -t.n_R.copy()
    d[:, :2] *= np.cos(el)[:, None]
    d[:, 2] = -np.sin(el)
    ts = np.zeros(t.n)
    k = 0
    for j in range(len(c_deg)):
        m = np.flatnonzero(t.setup == j)
        ts[m] = k * 600.0 + 8.0 * np.arange(m.size)
        k += 1
    sh = np.array([shift_m[0], shift_m[1], 0.0])
    return dataclasses.replace(t, d_R=d, t_s=ts, pn_R=t.pn_R + sh, p_R=t.pn_R + sh, row=np.arange(t.n))


def machine_and_form(t, rng):
    """Smooth machine errors (within the baseline's model) and a workpiece form: (dq per touch, form per target), m."""
    x, y = t.pn_R[:, 0] - t.pn_R[:, 0].mean(), t.pn_R[:, 1] - t.pn_R[:, 1].mean()
    nx, ny = t.n_R[:, 0], t.n_R[:, 1]
    a = rng.normal(0, 1, 6)
    ex = 1e-6 * (3 * a[0] * x / 0.1 + a[1] * np.sin(x / 0.05) + 2 * a[2] * (y / 0.1) ** 2)
    ey = 1e-6 * (2 * a[3] * y / 0.1 + a[4] * np.cos(y / 0.04) + 2 * a[5] * (x / 0.1) ** 2)
    form = 1e-6 * rng.normal(0, 1, len(t.target_ids))
    return -nx * ex - ny * ey + form[t.target], form


def effect(name: str, t, rng, mag_m: float, c0=(0.0, 0.0)) -> tuple[np.ndarray, dict]:
    """One effect's normal deviations (m) and extra fields for the touches."""
    x, y = t.pn_R[:, 0] - t.pn_R[:, 0].mean(), t.pn_R[:, 1] - t.pn_R[:, 1].mean()
    nx, ny = t.n_R[:, 0], t.n_R[:, 1]
    phi = np.arctan2(t.d_R[:, 1], t.d_R[:, 0])
    el = np.arcsin(-t.d_R[:, 2])
    tau = (t.t_s - t.t_s.min()) / np.ptp(t.t_s)
    tin = np.zeros(t.n)
    for j in np.unique(t.setup):
        m = t.setup == j
        tin[m] = (t.t_s[m] - t.t_s[m].min()) / np.ptp(t.t_s[m])
    kw: dict = {}
    if name == "none":
        e = 0 * x
    elif name == "thermal_drift":  # an x scale growing to a steady state
        e = -nx * mag_m * (x / 0.1) * (1 - np.exp(-3 * tau))
    elif name == "c_drift":  # the table creeping after each indexing (saturating)
        rot = -nx * (t.pn_R[:, 1] - c0[1]) + ny * (t.pn_R[:, 0] - c0[0])
        e = rot * (mag_m / 0.08) * (1 - np.exp(-4 * tin))
    elif name == "temperature_expansion":
        T = 20 + 1.5 * np.sin(2 * np.pi * 1.3 * tau) + 0.3 * tau
        alpha = mag_m / (0.1 * 1.5)
        e = -ny * alpha * y * (T - T.mean())
        kw["temps_C"] = {"temp_scale_y_C": T}
    elif name == "periodic_axis_error":
        e = -ny * mag_m * np.sin(2 * np.pi * t.pn_R[:, 1] / 0.0093 + 0.4)
    elif name == "probe_lobing":
        e = mag_m * (np.cos(2 * phi + 0.3) + 0.6 * np.sin(3 * phi))
    elif name == "lobing_per_setup":
        psi = np.array([0.0, 0.8, 2.1, 2.9])[t.setup]
        e = mag_m * np.cos(2 * (phi - psi))
    elif name == "stylus_bending":
        e = -mag_m * np.sin(el) ** 2 / np.sin(np.radians(30)) ** 2
    elif name == "local_scale_defect":
        e = -nx * mag_m * np.exp(-0.5 * ((t.pn_R[:, 0] - 0.035) / 0.003) ** 2)
    elif name == "part_change":  # one pocket wall (normal +x in the part) relaxing
        wall = (np.abs(np.angle(np.exp(1j * np.arctan2(t.wn_A[:, 1], t.wn_A[:, 0])))) < 0.3)
        e = mag_m * wall * tau
    elif name == "reversal":
        e = -nx * np.sign(t.d_R[:, 0]) * mag_m / 2
    elif name == "nonrigid":
        e = -nx * mag_m * (x / 0.09) * (y / 0.09) ** 2
    elif name == "nonrigid_field":  # the non-rigid field in its own form: P2(xs) P2(ys) in the error of X
        xs, ys = nonrigid_scaled(t)
        e = -nx * mag_m * (3 * xs ** 2 - 1) / 2 * (3 * ys ** 2 - 1) / 2
    elif name == "feature_offset_per_setup":  # out of catalogue: the spheres re-seated per set-up
        jump = rng.normal(0, 1, len(np.unique(t.setup)))
        sph = np.array([str(f).startswith("sphere") for f in t.feature])
        e = mag_m * sph * jump[t.setup]
    elif name == "pretravel_warmup":  # out of catalogue: pre-travel settling after each indexing, scalar
        e = mag_m * np.exp(-5 * tin)
    else:
        raise ValueError(name)
    return e, kw


def nonrigid_scaled(t):
    """The positions centred on their extent and scaled by its larger half (the planar baseline's xs, ys)."""
    x, y = t.pn_R[:, 0], t.pn_R[:, 1]
    L = max(np.ptp(x), np.ptp(y)) / 2
    return (x - (x.max() + x.min()) / 2) / L, (y - (y.max() + y.min()) / 2) / L


def campaign(name: str, seed: int, mag_m: float = 2e-6, sigma_m: float = SIG, shift_m=(0.0, 0.0), t=None,
             with_form: bool = False):
    """Touches with the effect ``name`` at ``mag_m`` over ``sigma_m`` noise (seeded).

    Returns (touches, effect per touch m) or, with ``with_form``, also the
    true workpiece form per target (m, ``t.target_ids`` order).
    """
    rng = np.random.default_rng(seed)
    t = plan(shift_m=shift_m) if t is None else t
    e, kw = effect(name, t, rng, mag_m, c0=shift_m)
    mf, form = machine_and_form(t, rng)
    dq = mf + e + rng.normal(0, sigma_m, t.n)
    out = dataclasses.replace(t, p_R=t.pn_R + dq[:, None] * t.n_R, **kw)
    return (out, e, form) if with_form else (out, e)
