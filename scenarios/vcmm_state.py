"""Does a virtual CMM fed with an identified machine state cover the truth? Through the exact simulator.

Each seed: a machine (``nmv3000``) with realistic errors drawn from the seed
(:func:`sim.machines.realistic_errors`: smooth tables the 22 mm look-up
tables cannot follow exactly, the 10 mm screw ripple, angular errors, C-
and A-axis errors: a truth outside the model's space); a cross-pocket
self-calibration campaign on it with probing noise, identified as ``vmt
identify`` does (:func:`scenarios.selfcal_coverage.simulate` and
:func:`core.selfcal.self_calibrate`), the scale from a measured length
(eq 17, :func:`scenarios.crosspocket.measure_delta_L`, its standard
uncertainty added to the state's covariance through the estimate's exact
sensitivity to it); the result's ``vmt-estimate/1`` block read back
(:func:`core.state.loads_estimate`) and handed to the virtual CMM
(:func:`scenarios.vcmm.prepare` on the machine's structure with no other
error: the state is all that is known) for a task on a block at the
pocket's height, C = 0.

The truth: the same task's touches on the *true* machine, simulated on the
exact chain with one draw of the probing noise, fitted and evaluated as the
virtual CMM evaluates a run. A measurand is covered when that value lies in
the virtual CMM's 95 % coverage interval of the measured value.

Measurands (:data:`TASK`): the distance between two faces 120 mm apart
along X (scale and EXX), the distance between two bore centres 128 mm apart
diagonally (the tables and EC0Y), one bore's diameter (20 mm: local form of
the tables, where the 10 mm ripple lives).
"""

from __future__ import annotations

import dataclasses

import numpy as np

MACHINE = "nmv3000"
#: Probing noise of the campaign and of the task (k = 1), m: the paper's 0.5 um at k = 2.
NOISE_M = 0.25e-6
#: The task (vmt-task/1) the coverage is counted on (features of :func:`coverage_plan`).
TASK = """
format = "vmt-task/1"
[features.left]
kind = "plane"
feature = "left"
[features.right]
kind = "plane"
feature = "right"
[features.b1]
kind = "circle"
feature = "b1"
[features.b2]
kind = "circle"
feature = "b2"
[[measurands]]
name = "face distance X"
quantity = "distance"
of = ["left", "right"]
[[measurands]]
name = "bore-bore distance"
quantity = "distance"
of = ["b1", "b2"]
[[measurands]]
name = "bore diameter"
quantity = "diameter"
of = "b1"
[mc]
batch_runs = 100
max_runs = 400
"""


#: The screw ripple declared (``[declared]``, appended to :data:`TASK` in :data:`TASK_RIPPLE`): the
#: identification's 22 mm tables cannot follow a 10 mm period, so a truth with the ripple
#: (:func:`sim.machines.realistic_errors`, ``ripple=True``: a 10 mm sine of 1 % of each linear
#: profile's magnitude on EXX, EBX, EYY, ECY, ...) carries an error the state does not hold. Declared
#: from the machine's specification alone (not from any coverage figure): the bound is 1 % of the
#: largest magnitude the machine's class reports (``sim.machines._LINEAR``: EXX 38 um, EBX 98 urad,
#: EYY 20 um, ECY 15 urad), amplitude uniform within it, phase unknown (uniform). EBX acts through the
#: tool's Abbe arm, ECY through the X offset of the tool; EZZ and EBZ do not move between the touches
#: of one height. Only the X and Y axes' terms move this task's features.
RIPPLE_DECLARED = """
[declared.EXX]
periodic_um = 0.38
period_mm = 10.0
distribution = "uniform"
[declared.EBX]
periodic_urad = 0.98
period_mm = 10.0
distribution = "uniform"
[declared.EYY]
periodic_um = 0.20
period_mm = 10.0
distribution = "uniform"
[declared.ECY]
periodic_urad = 0.15
period_mm = 10.0
distribution = "uniform"
"""
#: :data:`TASK` with the ripple declared (:data:`RIPPLE_DECLARED`).
TASK_RIPPLE = TASK.replace("[mc]", RIPPLE_DECLARED.lstrip() + "[mc]")


def coverage_plan(z_mm: float, stylus_r_mm: float = 3.0):
    """A block at tip-centre height ``z_mm``: faces x = -60 and +60 mm (4 touches each, 4 mm above and
    below), bores of 20 mm at (-50, -40) and (50, 40) mm (8 touches each); a probe-log/1 plan."""
    from scenarios.vcmm import plan_from_rows

    rows = []
    for name, (cx, cy) in (("b1", (-50.0, -40.0)), ("b2", (50.0, 40.0))):
        for k in range(8):
            a = np.deg2rad(22.5 + 45.0 * k)
            rows.append((name, f"{name}-{k}", (cx + 10 * np.cos(a), cy + 10 * np.sin(a), z_mm),
                         (-np.cos(a), -np.sin(a), 0.0)))
    for side, x, nx in (("left", -60.0, -1.0), ("right", 60.0, 1.0)):
        for k, (y, dz) in enumerate(((-45.0, -4.0), (-15.0, 4.0), (15.0, -4.0), (45.0, 4.0))):
            rows.append((side, f"{side}-{k}", (x, y, z_mm + dz), (nx, 0.0, 0.0)))
    return plan_from_rows(rows, stylus_r_mm, "vmt vcmm coverage block")


@dataclasses.dataclass(frozen=True)
class Identified:
    """One campaign's identification: the ``vmt identify`` JSON report, the true machine, the pocket height."""

    report: dict
    machine: object
    z_m: float
    delta_L: tuple
    #: d(estimate)/d(delta_L), SI per m, in the estimate's parameter order: what the covariance's
    #: measured-length term is made of (``g g^T u_dL^2``).
    dtheta_ddL: np.ndarray | None = None


def model_space_errors(seed: int, ripple: bool = True) -> dict:
    """The realistic machine of ``seed`` projected onto the identification's own model: its tool's exact
    X/Y deviation at the probing height on the grid's nodes, split into the tables (EXX, EYX, EXY, EYY,
    the yaw; linear between nodes) and EC0Y (:func:`scenarios.selfcal_coverage._tool_tables`); no
    other error. A truth inside the model space with the realistic machine's node values."""
    from core.selfcal import Grid, estimator, probing_levels, yaw_for_chain
    from scenarios import selfcal_coverage as SC
    from sim.errorfuncs import Constant, LinearTable

    c = SC.simulate(MACHINE, seed, 0.0, ripple=ripple)
    lo, hi, step = (v * 1e-3 for v in SC.GRID_MM)
    des, _ = estimator(c.touches, Grid.regular(lo, hi, step), yaw=yaw_for_chain(c.machine.config.chain))
    _, z_ref = probing_levels(c.touches.pn_R[:, 2])
    th, _ = SC._tool_tables(SC._split(c.machine)[0], des, z_ref)
    s = des.slices
    gx, gy = tuple(des.grid.x_m), tuple(des.grid.y_m)
    errs = {"EXX": LinearTable(gx, tuple(th[s["EXX"]])), "EYX": LinearTable(gx, tuple(th[s["EYX"]])),
            "EXY": LinearTable(gy, tuple(th[s["EXY"]])), "EYY": LinearTable(gy, tuple(th[s["EYY"]])),
            "EC0Y": Constant(float(th[s["EC0Y"]][0]))}
    if "ECY" in s:
        errs["ECY"] = LinearTable(gy, tuple(th[s["ECY"]]))
    else:
        errs["ECX"] = LinearTable(gx, tuple(th[s["ECX"]]))
    return errs


def identify_campaign(seed: int, noise_m: float = NOISE_M, *, ripple: bool = True, exact_scale: bool = False,
                      errors: dict | None = None) -> Identified:
    """Simulate and identify one cross-pocket campaign (module doc); the report is ``vmt identify``'s JSON.

    ``exact_scale``: delta_L is its true value and adds no uncertainty (a diagnosis, not a measurement);
    ``errors``: the machine's errors instead of the realistic draw (e.g. :func:`model_space_errors`)."""
    from core.selfcal import Grid, probing_levels, self_calibrate, yaw_for_chain
    from scenarios import selfcal_coverage as SC
    from scenarios.crosspocket import measure_delta_L

    c = SC.simulate(MACHINE, seed, noise_m, ripple=ripple, errors=errors)
    lo, hi, step = (v * 1e-3 for v in SC.GRID_MM)
    grid = Grid.regular(lo, hi, step)
    _, z_ref = probing_levels(c.touches.pn_R[:, 2])
    dL, dL_true, u_dL = measure_delta_L(c.machine, hi, z_ref, noise_m, np.random.default_rng([seed, 17]))
    if exact_scale:
        dL, u_dL = dL_true, 0.0
    yaw = yaw_for_chain(c.machine.config.chain)
    res = self_calibrate(c.touches, grid, dL, yaw=yaw)
    # the measured length's own uncertainty: the estimate is linear in delta_L (eq 17 is a gauge row)
    res1 = self_calibrate(c.touches, grid, dL + 1e-6, yaw=yaw, covariance="none", model_error=False)
    res0 = self_calibrate(c.touches, grid, dL, yaw=yaw, covariance="none", model_error=False)
    g = (res1.theta - res0.theta) / 1e-6
    res = dataclasses.replace(res, cov=res.cov + np.outer(g, g) * u_dL ** 2)
    return Identified(res.to_report(), c.machine, float(z_ref), (dL, dL_true, u_dL), g)


def true_values(ident: Identified, st, seed: int) -> np.ndarray:
    """The task's measurands (SI) on the true machine: the exact chain, one draw of the probing noise."""
    from core import vcmm as V
    from scenarios.vcmm import simulate_run

    p = simulate_run(st, {}, np.random.default_rng([seed, 23]), machine=ident.machine)
    return V.evaluate(st.task, st.rows, p, st.n_R, st.probe.stylus_r_m, st.Xn_R)


def one_seed(seed: int, *, noise_m: float = NOISE_M, ripple: bool = True, vcmm_seed: int | None = None,
             ident: Identified | None = None, task: str = TASK) -> dict:
    """Coverage of the task's measurands for one campaign: per measurand the true value, the interval, U95.

    ``task``: the task's text (default :data:`TASK`; :data:`TASK_RIPPLE` declares the ripple); ``ident``
    a campaign already identified (``seed`` still sets the truth's noise draw and the virtual CMM's);
    ``vcmm_seed``: the virtual CMM's Monte Carlo seed, default ``seed`` (each campaign its own draws, so
    the study averages the Monte Carlo's sampling error over the seeds instead of repeating one draw's;
    run k draws from ``SeedSequence([vcmm_seed, k])``'s children, apart from the campaign's
    ``default_rng(seed)``, ``[seed, 7]``, ``[seed, 17]``, ``[seed, 23]``). The truth's screw ripple
    (``ripple``) sits at the phases :func:`sim.machines.realistic_errors` draws from the seed."""
    from core import vcmm as V
    from core.state import loads_estimate
    from scenarios.vcmm import prepare, study
    from sim.machinefile import truth_machine

    if ident is None:
        ident = identify_campaign(seed, noise_m, ripple=ripple)
    # the report's tables are at the readings (vmt identify does not know J): at the axis positions reading + J
    # of the probe the campaign used, as vmt vcmm --machine-state places them (J_X = J_Y = 0 on nmv3000)
    state = loads_estimate(ident.report, source=f"identify seed {seed}").at_axis_positions(ident.machine.config.J_m)
    spec = truth_machine(MACHINE, "none")  # the best estimate before the state: no errors
    task = V.loads_task(task, source="coverage task")
    st = prepare(coverage_plan(ident.z_m * 1e3), task, spec, noise_um=noise_m * 1e6, state=state)
    rep = study(st, seed if vcmm_seed is None else vcmm_seed, budget=False)
    y = true_values(ident, st, seed)
    out = {}
    for j, m in enumerate(rep["measurands"]):   # all in mm, U in um
        lo, hi = m["interval"]
        t = float(y[j] * task.measurands[j].scale)
        out[m["name"]] = {"true_mm": t, "interval_mm": [lo, hi], "U95_um": m["U"], "covered": bool(lo <= t <= hi),
                          "true_minus_mean_um": (t - m["mean"]) * 1e3, "runs": rep["runs"]}
    return out


def study_coverage(seeds=range(10), **kw) -> dict:
    """Coverage over campaigns: per measurand and in all, covered / trials with Clopper-Pearson 95 % intervals."""
    from scenarios.selfcal_coverage import clopper_pearson

    per: dict = {}
    rows = []
    for sd in seeds:
        r = one_seed(int(sd), **kw)
        rows.append({"seed": int(sd), **r})
        for k, v in r.items():
            a = per.setdefault(k, [0, 0, []])
            a[0] += v["covered"]
            a[1] += 1
            a[2].append(v["U95_um"])
    out = {k: {"covered": a, "n": n, "ci95": list(clopper_pearson(a, n)), "U95_um_median": float(np.median(u))}
           for k, (a, n, u) in per.items()}
    ka, na = sum(v["covered"] for v in out.values()), sum(v["n"] for v in out.values())
    out["all"] = {"covered": ka, "n": na, "ci95": list(clopper_pearson(ka, na))}
    return {"summary": out, "seeds": rows}


#: Grid nodes (x, y) mm where the cross-pocket comparison reads the error map.
COMPARE_NODES_MM = ((88.0, 88.0), (110.0, 0.0), (-110.0, 110.0))


def _node_task(nodes_mm) -> str:
    t = ['format = "vmt-task/1"']
    for k, _ in enumerate(nodes_mm):
        t += [f"[features.n{k}]", 'kind = "circle"', f'feature = "n{k}"']
    for k, (x, y) in enumerate(nodes_mm):
        for a in "xy":
            t += ["[[measurands]]", f'name = "n{k} {a}"', 'quantity = "position"', f'of = "n{k}"', f'axis = "{a}"']
    t += ["[mc]", "batch_runs = 100", "max_runs = 600"]
    return "\n".join(t) + "\n"


def _node_plan(nodes_mm, z_mm: float, r_mm: float = 3.0, ring_mm: float = 4.0):
    """An 8-touch bore of radius ``ring_mm`` centred on each node (tip centres at height ``z_mm``)."""
    from scenarios.vcmm import plan_from_rows

    rows = []
    for k, (cx, cy) in enumerate(nodes_mm):
        for j in range(8):
            a = np.deg2rad(22.5 + 45.0 * j)
            rows.append((f"n{k}", f"n{k}-{j}", (cx + ring_mm * np.cos(a), cy + ring_mm * np.sin(a), z_mm),
                         (-np.cos(a), -np.sin(a), 0.0)))
    return plan_from_rows(rows, r_mm, "vcmm: bores on the cross-pocket grid nodes")


def crosspocket_comparison(seed: int = 1, nodes_mm=COMPARE_NODES_MM, vcmm_seed: int = 0) -> dict:
    """The cross-pocket study's error-map U95 (its Fig. 20) against the virtual CMM's, node by node.

    The same measurand: the tool's 2D position error at a grid node, in the gauge of eqs 16-17, scale
    unknown, C = {0, 75, 130, 210} deg with the spheres, probing u 1.38 um (the cross-pocket study's
    U_PROBE_M). The study: linear propagation through the nominal design, evaluated where identify
    evaluates (the tip centres, with the height terms: :func:`scenarios.crosspocket.study_touches`; exact for this linear
    estimator; its Monte Carlo agrees to sampling). The virtual CMM: a simulated campaign on a
    realistic nmv3000 at that noise, identified as ``vmt identify`` does (scale unknown), its
    estimate and covariance as ``--machine-state``, a noise-free probe (the state alone), an 8-touch
    bore of 4 mm radius on each node; U95 = sqrt(U95_x^2 + U95_y^2). Beside both: the same map by
    linear propagation of the identification's covariance, split into its probing part at the study's
    1.38 um, at the residuals' sigma, and with the model-error budget (what the difference is made of).
    """
    from core.selfcal import Grid, estimator, probing_levels, self_calibrate, yaw_for_chain
    from core.state import loads_estimate
    from core.uncertainty import K, error_map_operator
    from scenarios import crosspocket as CP
    from scenarios import selfcal_coverage as SC
    from scenarios.vcmm import prepare, study
    from core import vcmm as V
    from sim.machinefile import truth_machine

    grid = Grid.regular(-0.110, 0.110, 0.022)
    w, wn, ids, z = CP._plan_points(True, heights=True)
    des0, est0 = estimator(CP.study_touches(w, wn, SC.ANGLES, ids, z), grid)
    map0 = CP._map_u95_linear(des0, est0)
    c = SC.simulate(MACHINE, seed, CP.U_PROBE_M)
    _, z_ref = probing_levels(c.touches.pn_R[:, 2])
    res = self_calibrate(c.touches, grid, None, yaw=yaw_for_chain(c.machine.config.chain))
    _, est1 = estimator(c.touches, grid, yaw=yaw_for_chain(c.machine.config.chain))
    M = error_map_operator(res.design)
    nxy = len(grid.x_m) * len(grid.y_m)

    def u95_map(cov):
        v = np.einsum("ij,jk,ik->i", M, cov, M)
        return K * np.sqrt(np.maximum(v[:nxy] + v[nxy:], 0)).reshape(len(grid.x_m), len(grid.y_m))

    maps = {"campaign design, probing 1.38 um": u95_map(est1.covariance(CP.U_PROBE_M)),
            f"campaign design, residual sigma {res.sigma_m * 1e6:.3f} um": u95_map(est1.covariance(res.sigma_m)),
            "identification's covariance (sigma + model error)": u95_map(res.cov)}
    spec = truth_machine(MACHINE, "none")  # the best estimate before the state: no errors
    st = prepare(_node_plan(nodes_mm, z_ref * 1e3), V.loads_task(_node_task(nodes_mm)), spec, noise_um=0.0,
                 state=loads_estimate(res.to_report(), source=f"identify seed {seed}").at_axis_positions(
                     c.machine.config.J_m))   # at reading + J, as vmt vcmm places a state at the readings
    rep = study(st, vcmm_seed, budget=False)
    ms = {m["name"]: m for m in rep["measurands"]}
    rows = []
    for k, (x, y) in enumerate(nodes_mm):
        i, j = int(np.argmin(np.abs(grid.x_m - x * 1e-3))), int(np.argmin(np.abs(grid.y_m - y * 1e-3)))
        row = {"node_mm": [x, y], "crosspocket_study_U95_um": float(map0[i, j] * 1e6),
               "vcmm_U95_um": float(np.hypot(ms[f"n{k} x"]["U"], ms[f"n{k} y"]["U"])),
               "vcmm_runs": rep["runs"]}
        row.update({f"linear: {kk}": float(v[i, j] * 1e6) for kk, v in maps.items()})
        rows.append(row)
    return {"seed": seed, "residual_sigma_um": res.sigma_m * 1e6, "rms_um": res.rms_m * 1e6,
            "model_error_um": ({k: float(v * 1e6) for k, v in res.budget.components.items()}
                               if res.budget is not None else None), "nodes": rows}
