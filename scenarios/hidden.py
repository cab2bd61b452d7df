"""Campaigns with an effect hidden in the virtual machine or probe.

Model discovery is only worth something if it finds what is really there.
:func:`hidden_campaign` simulates a cross-pocket self-calibration campaign
on the 5-axis machine of the self-calibration paper (nmv3000, realistic
smooth errors) with one or more effects hidden *in the simulator* (never
added to the log):

===================== ========================================================
cause                 where it is hidden
===================== ========================================================
thermal_drift         ``Drift`` of an X/Y offset or scale in the machine
periodic_axis_error   ``Periodic`` term (5-15 mm period) on one X/Y error
probe_lobing          the probe's pre-travel lobing (k = 2, 3 Fourier terms)
reversal              ``Reversal`` (lost motion) of the X or Y axis
nonrigid              ``CrossAxis``: the X error grows with x * y
outlier               a chip on the pocket wall during one set-up (1-3 touches)
===================== ========================================================

Each set-up ends by re-probing sixteen pocket targets (four per wall
direction), the drift check a careful metrologist adds: without repeated
touches, drift along the probing path is mostly indistinguishable from the
machine's error map (the path order ties time to position).

The truth returned with the log holds the workpiece's true normal
deviation per target (from a perfect machine, noise-free), so a study can
check that the extended model's workpiece is closer to it than the
baseline's (after removing what no self-calibration can see: the
workpiece's position, rotation and scale in W).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.exceptions import ConfigError
from core.units import MM, UM

HIDDEN_CAUSES = ("none", "outlier", "thermal_drift", "periodic_axis_error", "probe_lobing", "reversal",
                 "nonrigid")


@dataclass(frozen=True)
class HiddenTruth:
    """What was hidden, and the workpiece truth per target."""

    causes: tuple
    params: dict
    g_true_m: dict = field(repr=False)  # target -> true normal deviation, m
    w_A: dict = field(repr=False)  # target -> (2,) nominal contact point, artefact frame A, m
    wn_A: dict = field(repr=False)  # target -> (2,) normal, A
    outlier_rows: tuple = ()


def _mag(rng, lo_um=1.0, hi_um=4.0) -> float:
    return float(rng.uniform(lo_um, hi_um)) * UM * float(rng.choice((-1.0, 1.0)))


def _effects(causes, rng, duration_s: float):
    """Extra machine errors, probe settings and chips for the causes (one builder per cause)."""
    errs: dict = {}
    probe_kw: dict = {}
    chips = []
    params: dict = {}
    for c in causes:
        if c == "none":
            continue
        if c not in _EFFECTS:
            raise ConfigError(f"unknown hidden cause {c!r}; expected one of {', '.join(HIDDEN_CAUSES)}")
        e_errs, e_probe, e_chips, params[c] = _EFFECTS[c](rng, duration_s)
        for sym, f in e_errs.items():
            errs[sym] = errs[sym] + f if sym in errs else f
        probe_kw.update(e_probe)
        chips = e_chips or chips
    return errs, probe_kw, chips, params


def _thermal_drift(rng, duration_s):
    """An X or Y offset or scale drifting linearly over the campaign."""
    from sim.errorfuncs import Drift

    kind = rng.choice(["x_offset", "y_offset", "x_scale", "y_scale"])
    m = _mag(rng)
    sym = "EXX" if kind[0] == "x" else "EYY"
    if kind.endswith("offset"):
        f = Drift(offset_rate=m / duration_s)
    else:  # m at 100 mm from the centre by the end of the campaign
        f = Drift(scale_rate=m / 0.1 / duration_s)
    return {sym: f}, {}, [], {"kind": str(kind), "symbol": sym, "total_um": m / UM}


def _periodic_axis_error(rng, duration_s):
    """A 5-15 mm periodic term on one X/Y error (a ball screw's pitch)."""
    from sim.errorfuncs import Periodic

    sym = str(rng.choice(["EXX", "EYY", "EYX", "EXY"]))
    P = float(rng.uniform(5, 15)) * MM
    m = abs(_mag(rng))
    f = Periodic(m, P, float(rng.uniform(0, 2 * np.pi)))
    return {sym: f}, {}, [], {"symbol": sym, "period_mm": P / MM, "amplitude_um": m / UM}


def _probe_lobing(rng, duration_s):
    """Pre-travel lobing of the probe: 3 and 2 lobes."""
    m = abs(_mag(rng))
    ph3, ph2 = rng.uniform(0, 2 * np.pi, 2)
    r2 = float(rng.uniform(0.2, 0.6))
    lobing = ((3, m * np.cos(ph3), m * np.sin(ph3)), (2, r2 * m * np.cos(ph2), r2 * m * np.sin(ph2)))
    return {}, {"lobing_m": lobing}, [], {"k3_amplitude_um": m / UM, "k2_amplitude_um": r2 * m / UM}


def _reversal(rng, duration_s):
    """Lost motion of the X or Y axis."""
    from sim.errorfuncs import Reversal

    sym = str(rng.choice(["EXX", "EYY"]))
    m = abs(_mag(rng))
    return {sym: Reversal(m)}, {}, [], {"symbol": sym, "lost_motion_um": m / UM}


def _nonrigid(rng, duration_s):
    """An X error growing with x * y (or the X straightness with y * x)."""
    from sim.errorfuncs import CrossAxis

    sym, other = (("EXX", "Y") if rng.random() < 0.5 else ("EXY", "X"))
    m = _mag(rng)
    return {sym: CrossAxis(m / 0.1 ** 2, other)}, {}, [], {"symbol": sym, "other": other, "at_100mm_um": m / UM}


def _outlier(rng, duration_s):
    """1-3 chips of 3-10 um on the pocket wall (placed by :func:`_with_chips`)."""
    n = int(rng.integers(1, 4))
    chips = [abs(_mag(rng, 3.0, 10.0)) for _ in range(n)]
    return {}, {}, chips, {"chips_um": [h / UM for h in chips]}


#: cause -> builder ``(rng, duration_s) -> (errors, probe settings, chips, params)``.
_EFFECTS = {"thermal_drift": _thermal_drift, "periodic_axis_error": _periodic_axis_error,
            "probe_lobing": _probe_lobing, "reversal": _reversal, "nonrigid": _nonrigid, "outlier": _outlier}


def hidden_campaign(causes=("none",), seed: int = 0, *, noise_sigma_m: float = 0.3e-6,
                    c_angles_deg=(0.0, 75.0, 130.0, 210.0), machine_seed: int | None = None):
    """Simulate a cross-pocket campaign with ``causes`` hidden in the simulator.

    Parameters
    ----------
    causes : sequence of str
        From :data:`HIDDEN_CAUSES` (several at once are allowed).
    seed : int
        Seeds the effect parameters and the probing noise.
    noise_sigma_m : float
        Probing repeatability, standard deviation, m (0.3 um by default).
    machine_seed : int or None
        Seeds the realistic machine errors (default: ``seed``).

    Returns
    -------
    (ProbeLog, HiddenTruth)
    """
    from sim import artefacts as A
    from sim.campaign import simulate_campaign
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors
    from sim.probe import ProbeConfig

    causes = tuple(causes)
    rng = np.random.default_rng(seed)
    base = realistic_errors(("X", "Y", "Z", "C"), rng=np.random.default_rng(
        seed if machine_seed is None else machine_seed), ripple=False)
    art = A.cross_pocket()
    plan = drift_check_plan(art)
    # the campaign's length (drift totals refer to it): a dry, noise-free run
    dry = simulate_campaign(art, Machine(MACHINES["nmv3000"](errors=base)), ProbeConfig(), list(c_angles_deg),
                            None, plan=plan, check_collisions=False)
    duration = float(np.nanmax(dry.col("t_s")))
    extra, probe_kw, chips, params = _effects(causes, rng, duration)
    errs = dict(base)
    for k, f in extra.items():
        errs[k] = errs[k] + f if k in errs else f
    machine = Machine(MACHINES["nmv3000"](errors=errs))
    probe = ProbeConfig(repeatability_k2_m=2 * noise_sigma_m, **probe_kw)
    noise = np.random.default_rng([seed, 1])
    meta = {"hidden": "yes (see the test that made it)"}
    if not chips:
        log = simulate_campaign(art, machine, probe, list(c_angles_deg), noise, plan=plan, meta=meta)
        out_rows = ()
    else:
        log, out_rows = _with_chips(art, plan, machine, probe, list(c_angles_deg), seed, chips, rng, meta)
    g_true = workpiece_truth(art, plan)
    tg = list(dict.fromkeys(plan.target))
    first = {k: plan.target.index(k) for k in tg}
    truth = HiddenTruth(causes=causes, params=params, g_true_m=g_true,
                        w_A={k: plan.w_A[first[k], :2] for k in tg}, wn_A={k: plan.wn_A[first[k], :2] for k in tg},
                        outlier_rows=tuple(out_rows))
    return log, truth


def drift_check_plan(art, per_direction: int = 4):
    """The artefact's plan plus repeated pocket touches at the end.

    The repeats are the first ``per_direction`` pocket targets (earliest in
    the path, so farthest in time from the repeat) whose normals point
    along +x, -x, +y and -y (A frame).
    """
    from sim.catalog import make_plan

    plan = make_plan(art)
    pocket = np.flatnonzero(np.asarray(plan.feature) == "pocket")
    picks = []
    for d in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        score = plan.wn_A[pocket, :2] @ np.array(d, float)
        best = pocket[score > score.max() - 1e-9]
        picks += [int(i) for i in best[:per_direction]]  # the earliest in the path
    return plan.select(np.concatenate([np.arange(plan.n), picks]))


def _with_chips(art, plan, machine, probe, c_angles, seed, chips, rng, meta):
    """The campaign with chips on the pocket wall during one set-up.

    Two full campaigns with identically seeded noise, one on the clean and
    one on the dirty part (same moves, same times, same noise draws); the
    dirty set-up's rows come from the second. Time-dependent effects stay
    continuous across set-ups.
    """
    from core.probelog import make_log
    from sim import artefacts as A
    from sim.campaign import simulate_campaign

    pocket = np.flatnonzero(np.asarray(plan.feature) == "pocket")
    pocket = pocket[pocket < len(set(plan.target))]  # not a repeat
    dirty_setup = int(rng.integers(len(c_angles)))
    hit = rng.choice(pocket, size=len(chips), replace=False)
    bumps = [A.Bump(h, tuple(plan.w_A[i]), 0.4 * MM) for h, i in zip(chips, hit)]
    feat = art.feature("pocket")
    base_form = [feat.true.form] if feat.true.form is not None else []
    dirty = _replace_pocket_form(art, A.FormSum(tuple(base_form + bumps)))
    clean = simulate_campaign(art, machine, probe, c_angles, np.random.default_rng([seed, 1]), plan=plan, meta=meta)
    dirt = simulate_campaign(dirty, machine, probe, c_angles, np.random.default_rng([seed, 1]), plan=plan, meta=meta)
    n_per = plan.n
    take = np.zeros(clean.n, bool)
    take[dirty_setup * n_per:(dirty_setup + 1) * n_per] = True
    cols = {k: np.where(take, dirt.columns[k], v) if v.dtype != object else
            np.array([b if tk else a for a, b, tk in zip(v, dirt.columns[k], take)], dtype=object)
            for k, v in clean.columns.items()}
    # every touch of a chipped target in that set-up (drift-check repeats included)
    chipped = {plan.target[i] for i in hit}
    rows = tuple(int(dirty_setup * n_per + i) for i in range(n_per) if plan.target[i] in chipped)
    return make_log(cols, clean.meta), rows


def _replace_pocket_form(art, form):
    import dataclasses

    feats = []
    for f in art.features:
        if f.name == "pocket":
            f = dataclasses.replace(f, true=dataclasses.replace(f.true, form=form))
        feats.append(f)
    return dataclasses.replace(art, features=tuple(feats))


def workpiece_truth(art, plan) -> dict:
    """True normal deviation of the part at each target (its form error), m.

    At a nominal contact point ``w`` the true signed distance is
    ``-form(w)`` (sim.artefacts), so the outward deviation is ``-sdf(w)``.
    """
    out = {}
    for tid, f, w in zip(plan.target, plan.feature, plan.w_A):
        out[tid] = -float(art.feature(f).true.sdf(np.asarray(w, float)[None, :])[0])
    return out


def gauge_free_rms_m(g_m, ids, g_true: dict, w_A: dict, wn_A: dict) -> float:
    """RMS of (estimate - truth) per target after removing what self-calibration cannot see.

    The workpiece's shift (2), rotation and scale in W and a common offset
    (the gauge of eqs 16-17 and the stylus radius) are projected out of the
    difference first (:func:`core.selfcal.workpiece_form`).
    """
    from core.selfcal import workpiece_form

    P = np.array([w_A[k] for k in ids])
    N = np.array([wn_A[k] for k in ids])
    e = workpiece_form(np.asarray(g_m, float) - np.array([g_true[k] for k in ids]), P, N)
    return float(np.sqrt(np.mean(e ** 2)))


def workpiece_errors_um(report: dict, truth: HiddenTruth) -> tuple[float, float]:
    """Gauge-free RMS error of the baseline and extended workpiece of a discovery report, um."""
    rows = [w for w in report["workpiece"] if w["target"] in truth.g_true_m]
    if not rows:
        raise ConfigError("no target of the report is in the truth")
    ids = [w["target"] for w in rows]
    return tuple(gauge_free_rms_m(np.array([w[k] for w in rows]) * UM, ids, truth.g_true_m, truth.w_A,
                                  truth.wn_A) / UM for k in ("baseline_um", "extended_um"))
