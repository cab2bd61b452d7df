"""Does the self-calibration's U95 hold the truth? Per block, through the exact simulator.

A cross-pocket campaign (the paper's C = 0, 75, 130, 210 deg, spheres
included) is simulated touch by touch on a machine with "realistic" errors
(:func:`sim.machines.realistic_errors`: smooth tables the 22 mm look-up
tables cannot follow exactly, the 10 mm screw ripple, C-axis wobble, the
angular errors that act through the spheres' 25.7 mm height), with or
without probing noise, and identified by :func:`core.selfcal.self_calibrate`
exactly as ``vmt identify`` does. The truth of every parameter is taken
from the simulator, not from the model (:func:`block_truth`):

- the X/Y tables (EXX, EYX, EXY, EYY, the yaw) and EC0Y: the exact tip
  deviation of the machine with its tool-side errors only, at the pocket
  height and C = 0, on every pair of grid nodes, split into the tables of
  eqs 4-5 by least squares (the split is exact to first order; what it
  leaves is reported);
- EXC,total, EYC,total, ECC per set-up: the exact displacement and rotation
  of the table (its errors only) at the C axis, pocket height;
- the height terms: the table's tilt per set-up, plus the tool's deviation
  at the spheres' height less that at the pocket's, fitted by a constant and
  a linear term over the raised touches;
- the workpiece: the part's own form at each target
  (:func:`scenarios.hidden.workpiece_truth`);

then expressed in the identification's gauge (:meth:`SelfCalDesign.to_gauge`).
A block's coverage is the fraction of its free parameters whose
``|estimate - truth| <= U95``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Blocks whose coverage is checked, each a list of design slices.
BLOCKS = {"EXX": ("EXX",), "EYY": ("EYY",), "EYX/EXY/EC0Y": ("EYX", "EXY", "EC0Y"), "yaw": ("ECY", "ECX"),
          "workpiece": ("G",), "C-axis": ("EXC", "EYC", "ECC")}
#: A parameter whose U95 is below this fraction of its block's largest is gauge-fixed (its U95 and its error are
#: rounding: EXX at the scale node carried U95 ~ 1e-22 m beside an error ~ 2e-21 m under a model-error budget and
#: was counted, mostly as a miss, before session 27).
FIXED_REL = 1e-9
#: The paper's C angles (section 4.2), deg.
ANGLES = (0.0, 75.0, 130.0, 210.0)
#: The paper's grid: -110..110 mm, 22 mm step.
GRID_MM = (-110.0, 110.0, 22.0)


@dataclass(frozen=True)
class Campaign:
    """One simulated campaign and what its truth needs."""

    machine: object
    touches: object
    art: object
    plan: object
    seed: int
    noise_m: float


def simulate(machine_name: str, seed: int, noise_m: float = 0.0, *, ripple: bool = True,
             angles=ANGLES, errors: dict | None = None, ripple_phase: float | None = None) -> Campaign:
    """A cross-pocket campaign on ``machine_name`` with realistic errors drawn from ``seed``.

    ``noise_m``: probing standard deviation (k = 1), m, along the approach;
    ``errors``: the machine's errors (symbol -> sim.errorfuncs function)
    instead of the realistic draw; ``ripple_phase``: every screw ripple at this
    phase (rad; :func:`sim.machines.realistic_errors`, default drawn from the
    seed). Only touches with normals in the XY plane are kept (as ``vmt identify``).
    """
    from core.touches import from_log
    from sim import artefacts as A
    from sim.campaign import simulate_campaign
    from sim.catalog import make_plan
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors
    from sim.probe import ProbeConfig

    cfg = MACHINES[machine_name]()
    axes = tuple(a for a in ("X", "Y", "Z", "C", "A") if a in cfg.strokes)
    errs = (realistic_errors(axes, strokes=cfg.strokes, J_m=cfg.J_m, rng=np.random.default_rng(seed), ripple=ripple,
                             ripple_phase=ripple_phase) if errors is None else errors)
    m = Machine(MACHINES[machine_name](errors=errs))
    art = A.cross_pocket()
    plan = make_plan(art)
    rng = np.random.default_rng([seed, 7]) if noise_m > 0 else None
    log = simulate_campaign(art, m, ProbeConfig(repeatability_k2_m=2.0 * noise_m), list(angles), rng,
                            check_collisions=False)
    t = from_log(log.select(np.abs(log.col("nz")) <= 0.01))
    return Campaign(m, t, art, plan, seed, noise_m)


def _split(machine):
    """(tool-side machine, table-side machine): the same geometry, each with its side's errors only."""
    from core import iso

    tool, table = {}, {}
    for k, f in machine.config.errors.items():
        (tool if iso.symbol(k).axis in machine.chain.tool_axes else table)[k] = f
    return machine.with_errors(tool), machine.with_errors(table)


def _tool_tables(mt, des, z_m: float) -> tuple[np.ndarray, float]:
    """Table node values from the tool's exact tip deviation on the node pairs; and the split's worst misfit, m."""
    from core.selfcal import Yaw

    gx, gy = des.grid.x_m, des.grid.y_m
    X, Y = np.meshgrid(gx, gy, indexing="ij")
    lin = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, z_m)])
    rot = np.zeros((len(lin), len(mt.rotary_axes)))
    E = mt.tip_W(lin, rot) - mt.tip_W_nominal(lin, rot)
    s = des.slices
    kx = np.repeat(np.arange(len(gx)), len(gy))
    ly = np.tile(np.arange(len(gy)), len(gx))
    npt = len(lin)
    M = np.zeros((2 * npt, des.n_params))
    r = np.arange(npt)
    M[r, s["EXX"].start + kx] = 1.0
    M[r, s["EXY"].start + ly] = 1.0
    M[r, s["EC0Y"].start] = -Y.ravel()  # eq 4: -y EC0Y in X
    M[npt + r, s["EYX"].start + kx] = 1.0
    M[npt + r, s["EYY"].start + ly] = 1.0
    if des.yaw == Yaw.ECY:
        M[npt + r, s["ECY"].start + ly] = X.ravel()  # eq 5
    else:
        M[r, s["ECX"].start + kx] = -Y.ravel()
    used = np.flatnonzero(np.any(M != 0, axis=0))
    b = np.concatenate([E[:, 0], E[:, 1]])
    sol, *_ = np.linalg.lstsq(M[:, used], b, rcond=None)
    th = np.zeros(des.n_params)
    th[used] = sol
    return th, float(np.abs(M[:, used] @ sol - b).max())


def machine_truth(machine, des, z_m: float) -> tuple[np.ndarray, float, np.ndarray]:
    """The machine's part of :func:`block_truth`: (theta raw, split misfit m, table tilt (n_c, 2) rad).

    theta holds the X/Y tables, EC0Y and the yaw (the tool side's exact tip
    deviation at height ``z_m``, C = 0, split over the node pairs) and per
    set-up EXC,total, EYC,total, ECC (the table side's exact displacement and
    rotation at the machine's x = y = 0, height ``z_m``: where eq 13's terms
    act); the workpiece and height terms are 0. ``tilt`` is each set-up's
    table rotation about Y and about X.
    """
    mt, mw = _split(machine)
    th, misfit = _tool_tables(mt, des, z_m)
    s = des.slices
    ic = machine.rotary_axes.index("C")
    tilt = np.zeros((len(des.c_rad), 2))
    for j, cj in enumerate(des.c_rad):
        rv = np.zeros((1, len(machine.rotary_axes)))
        rv[0, ic] = cj
        Ta, Tn = mw.T_R_W(np.zeros((1, 3)), rv)[0], mw.T_R_W_nominal(rv)[0]
        q = np.array([0.0, 0.0, z_m, 1.0])
        d = Ta @ np.linalg.solve(Tn, q) - q
        Rr = Ta[:3, :3] @ Tn[:3, :3].T
        # ISO 230-1 sign (core.selfcal): the tool relative to the part, the opposite of the table's motion
        th[s["EXC"].start + j], th[s["EYC"].start + j], th[s["ECC"].start + j] = -d[0], -d[1], -Rr[1, 0]
        tilt[j] = (Rr[0, 2], Rr[2, 1])  # rotation about Y (EBC), about X (EAC)
    return th, misfit, tilt


def block_truth(c: Campaign, des) -> tuple[np.ndarray, float]:
    """(theta (n_params,), split misfit m): every parameter's truth from the simulator (module docstring), raw
    (not yet in the design's gauge: :meth:`core.selfcal.SelfCalDesign.to_gauge` does that)."""
    from core.selfcal import probing_levels
    from scenarios.hidden import workpiece_truth

    mt, _ = _split(c.machine)
    t = c.touches
    _, z_ref = probing_levels(t.pn_R[:, 2])
    th, misfit, tilt = machine_truth(c.machine, des, z_ref)
    s = des.slices
    g = workpiece_truth(c.art, c.plan)
    th[s["G"]] = [g[k] for k in des.target_ids]
    ht = des.heights
    if ht is not None:
        raised = ht.dz_m != 0
        dz = float(np.median(ht.dz_m[raised]))
        p = t.pn_R[raised]
        rot = np.zeros((len(p), len(mt.rotary_axes)))
        lo = p.copy()
        lo[:, 2] = z_ref
        dE = (mt.tip_W(p, rot) - p) - (mt.tip_W(lo, rot) - lo)
        F = np.column_stack([np.ones(len(p)), p[:, 0], p[:, 1]])
        cx, *_ = np.linalg.lstsq(F, dE[:, 0], rcond=None)
        cy, *_ = np.linalg.lstsq(F, dE[:, 1], rcond=None)
        for q, j in enumerate(ht.setups):
            # dq = -n . c (tool) = -dz (n_x EBC - n_y EAC): EBC = c_x / dz, EAC = -c_y / dz; minus the table's tilt
            th[s["EBC"].start + q] = -tilt[j, 0] + cx[0] / dz
            th[s["EAC"].start + q] = -tilt[j, 1] - cy[0] / dz
        if ht.abbe:  # E_X += dz (b_x x + b_y y), E_Y -= dz (a_x x + a_y y)
            th[s["ABBE"]] = (cx[1] / dz, cx[2] / dz, -cy[1] / dz, -cy[2] / dz)
    return th, misfit


def coverage(res, truth: np.ndarray) -> dict:
    """Per block of :data:`BLOCKS`: (covered, free parameters) with ``|theta - truth| <= 2 std``; a parameter
    is free when its U95 is above :data:`FIXED_REL` of the block's largest (gauge-fixed ones carry rounding)."""
    des = res.design
    U = 2.0 * res.std
    out = {}
    for b, ks in BLOCKS.items():
        idx = np.concatenate([np.arange(des.n_params)[des.slices[k]] for k in ks if k in des.slices])
        idx = idx[U[idx] > FIXED_REL * U[idx].max()] if idx.size and U[idx].max() > 0 else idx[:0]
        out[b] = (int(np.sum(np.abs(res.theta[idx] - truth[idx]) <= U[idx])), int(idx.size))
    return out


def identify_and_cover(c: Campaign, **kw) -> tuple[object, dict, float]:
    """(result, coverage per block, split misfit m) of one campaign, identified as ``vmt identify`` does."""
    from core.selfcal import Grid, self_calibrate, yaw_for_chain

    lo, hi, st = (v * 1e-3 for v in GRID_MM)
    res = self_calibrate(c.touches, Grid.regular(lo, hi, st), yaw=yaw_for_chain(c.machine.config.chain), **kw)
    raw, misfit = block_truth(c, res.design)
    return res, coverage(res, res.design.to_gauge(raw)), misfit


def spec_subgrid() -> dict:
    """The realistic machines' sub-grid ripple as their spec would declare it (``self_calibrate(subgrid=)``).

    Every "lin" positioning table of :func:`sim.machines.realistic_errors`
    the self-calibration holds (EXX, EYY, the yaw ECY) carries a screw
    ripple of period :data:`sim.machines.RIPPLE_PERIOD_M` and amplitude 1 %
    of its magnitude, the magnitude drawn up to the nominal one: the
    declared amplitude is that bound (1 % of the nominal magnitude), not a
    seed's value (which lies between half of it and all of it), and the
    phase is not declared. Returns table -> (amplitude m or rad, period m).
    """
    from sim.machines import _LINEAR, RIPPLE_PERIOD_M

    out = {}
    for rows in _LINEAR.values():
        for sym, shape, m in rows:
            if shape == "lin" and sym in ("EXX", "EYX", "EXY", "EYY", "ECY", "ECX"):
                out[sym] = (0.01 * abs(m), RIPPLE_PERIOD_M)
    return out


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval for k successes in n trials (Clopper and Pearson, 1934)."""
    from scipy.stats import beta

    a = (1.0 - level) / 2.0
    lo = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1.0 - a, k + 1, n - k))
    return lo, hi


def study(machines=("nmv3000", "mikron-ucp710"), seeds=range(20), noises_m=(0.0, 0.5e-6), **kw) -> dict:
    """Coverage per machine, noise and block over ``seeds`` campaigns, with Clopper-Pearson intervals.

    ``kw`` goes to :func:`core.selfcal.self_calibrate` (``heights``,
    ``model_error``: the before/after comparison). The intervals treat the
    parameters as independent trials; within one campaign they are not
    (one truth, one gauge), so the intervals are narrower than the truth's.
    """
    out = {}
    for mn in machines:
        for nz in noises_m:
            tot: dict = {}
            worst = 0.0
            for sd in seeds:
                _, cv, mis = identify_and_cover(simulate(mn, int(sd), nz), **kw)
                worst = max(worst, mis)
                for b, (k, n) in cv.items():
                    a = tot.setdefault(b, [0, 0])
                    a[0] += k
                    a[1] += n
            out[f"{mn}/noise_{nz * 1e6:g}um"] = {
                b: {"covered": k, "n": n, "fraction": round(k / n, 4),
                    "ci95": [round(v, 4) for v in clopper_pearson(k, n)]} for b, (k, n) in tot.items()}
            out[f"{mn}/noise_{nz * 1e6:g}um"]["split_misfit_nm"] = round(worst * 1e9, 3)
    return out


#: Version of the JSON :func:`main` writes.
FORMAT = "vmt-selfcal-coverage/1"


def record(c: Campaign, declared: bool = False) -> dict:
    """One campaign's figures: coverage per block (covered, free), the median workpiece U95 and the largest
    C-axis displacement U95 (EXC, EYC), um, and the split's misfit, nm; the budget from the residuals alone,
    or with the spec's sub-grid ripple declared (:func:`spec_subgrid`)."""
    res, cv, mis = identify_and_cover(c, **({"subgrid": spec_subgrid()} if declared else {}))
    s, U = res.design.slices, 2.0 * res.std
    uc = np.concatenate([U[s["EXC"]], U[s["EYC"]]])
    return {"coverage": {b: list(v) for b, v in cv.items()}, "workpiece_u95_median_um": float(np.median(U[s["G"]]) * 1e6),
            "c_axis_u95_max_um": float(uc.max() * 1e6), "split_misfit_nm": float(mis * 1e9)}


def pool(records: list) -> dict:
    """Per block: covered, n, fraction and Clopper-Pearson 95 % over ``records`` (:func:`record`'s); the median
    over campaigns of the median workpiece U95, and of the largest C-axis U95, um."""
    tot: dict = {}
    for r in records:
        for b, (k, n) in r["coverage"].items():
            a = tot.setdefault(b, [0, 0])
            a[0] += k
            a[1] += n
    out = {b: {"covered": k, "n": n, "fraction": round(k / n, 4), "ci95": [round(v, 4) for v in clopper_pearson(k, n)]}
           for b, (k, n) in tot.items()}
    out["workpiece_u95_median_um"] = float(np.median([r["workpiece_u95_median_um"] for r in records]))
    out["c_axis_u95_max_um"] = float(np.median([r["c_axis_u95_max_um"] for r in records]))
    out["campaigns"] = len(records)
    return out


def main(argv=None) -> int:
    """``python -m scenarios.selfcal_coverage``: coverage per block over seeds, machines, noises, the ripple's
    phase (drawn per seed, or every screw at phase 0) and the budget (residuals only and/or declared); prints a
    line per case, ``--json`` writes every campaign's figures and the pooled ones (JSON)."""
    import json
    import sys

    from sim.machines import MACHINES

    from scenarios.cli.guard import OneLineParser   # bad input: one line naming it, exit 2 (vmt's parser)

    ap = OneLineParser(prog="python -m scenarios.selfcal_coverage",
                                 description="the self-calibration's U95 coverage per block against the exact simulator")
    ap.add_argument("--machines", nargs="+", default=["nmv3000", "mikron-ucp710"])
    ap.add_argument("--seeds", nargs=2, type=int, default=(20, 40), metavar=("LO", "HI"))
    ap.add_argument("--noise-um", nargs="+", type=float, default=[0.0, 0.5], help="probing sigma (k = 1), um")
    ap.add_argument("--phase", nargs="+", choices=("drawn", "0"), default=["drawn"],
                    help="the screw ripple's phase: drawn per seed (the truth since session 27) or 0 for every screw")
    ap.add_argument("--budget", nargs="+", choices=("residuals", "declared"), default=["residuals", "declared"],
                    help="model-error budget: from the residuals alone, or with spec_subgrid() declared")
    from scenarios.cli.options import option

    # --out until session 38: vmt's --out is a log, plan or program, its JSON outputs --json (one name per thing)
    option(ap, "--json", dest="out", old=("--out",), help="JSON of every campaign's figures and the pooled ones")
    a = ap.parse_args(argv)
    bad = [m for m in a.machines if m not in MACHINES or "C" not in MACHINES[m]().strokes]
    if bad:
        print(f"error: --machines {bad[0]}: not a built-in machine with a C axis", file=sys.stderr)
        return 2
    if a.seeds[1] <= a.seeds[0] or any(not np.isfinite(n) or n < 0 for n in a.noise_um):
        print(f"error: --seeds {a.seeds[0]} {a.seeds[1]} / --noise-um {a.noise_um}: an empty seed range or a "
              f"negative noise", file=sys.stderr)
        return 2
    from viz.progress import TerminalProgress

    recs = []
    bar = TerminalProgress("selfcal_coverage: campaigns")     # on a terminal only (stderr): the time left
    total, done = len(a.machines) * len(a.noise_um) * len(a.phase) * (a.seeds[1] - a.seeds[0]), 0
    bar(0, total)
    for mn in a.machines:
        for nz in a.noise_um:
            for ph in a.phase:
                for sd in range(*a.seeds):
                    c = simulate(mn, sd, nz * 1e-6, ripple_phase=None if ph == "drawn" else 0.0)
                    for bu in a.budget:
                        recs.append({"machine": mn, "noise_um": nz, "phase": ph, "budget": bu, "seed": sd}
                                    | record(c, declared=bu == "declared"))
                    done += 1
                    bar(done, total)
                bar.clear()
                for bu in a.budget:
                    p = pool([r for r in recs if (r["machine"], r["noise_um"], r["phase"], r["budget"]) == (mn, nz, ph, bu)])
                    print(f"{mn}, {nz:g} um, phase {ph}, {bu}: " + ", ".join(
                        f"{b} {p[b]['fraction']:.3f}" for b in BLOCKS) + f"; workpiece U95 median "
                        f"{p['workpiece_u95_median_um']:.2f} um, C-axis U95 largest {p['c_axis_u95_max_um']:.2f} um "
                        f"(median over {p['campaigns']})", flush=True)
    if a.out:
        cases = dict.fromkeys((r["machine"], r["noise_um"], r["phase"], r["budget"]) for r in recs)
        with open(a.out, "w") as f:
            json.dump({"format": FORMAT, "seeds": list(range(*a.seeds)), "records": recs,
                       "pooled": [{"machine": m, "noise_um": n, "phase": ph, "budget": b} | pool(
                           [r for r in recs if (r["machine"], r["noise_um"], r["phase"], r["budget"]) == (m, n, ph, b)])
                                  for m, n, ph, b in cases]}, f, indent=1)
    bar.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
