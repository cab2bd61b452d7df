"""The self-calibration paper's studies, reproduced on vmt's reconstructed parts.

``cross-pocket-uncertainty`` (paper section 6): the maximum expanded
uncertainty (k = 2) of the identified workpiece ``G_normal`` for C = {0, 75},
{0, 75, 130} and {0, 75, 130, 210} deg, with and without the two spheres,
by Monte Carlo (JCGM 101, 1,000 runs, probing standard uncertainty 1.38 um)
beside linear propagation, and the C-axis uncertainties of Table 2.

``pin-circle`` (paper section 5): 18 pins on a 400 mm pitch circle and two
spheres at C = 0, 31, 83, 137, 191, 227, 257, 313 deg, grid step 80 mm over
the touched extent (the paper's -400..400 mm has nodes no pin reaches); the raw error at C = 0 against the self-calibrated one.

The part geometry is vmt's reconstruction (sim.artefacts); the paper's Fig. 8
is not fully dimensioned, so the figures differ: see ``notes`` in the JSON.
"""

from __future__ import annotations

import time

import numpy as np

PAPER_G_U95_UM = {(0.0, 75.0): 6.5, (0.0, 75.0, 130.0): 3.0, (0.0, 75.0, 130.0, 210.0): 2.1}
PAPER_TABLE2 = {75.0: (1.0, 0.9, 8.9), 130.0: (1.2, 1.1, 9.3), 210.0: (1.2, 1.2, 8.2)}
U_PROBE_M = 1.38e-6


def _plan_points(spheres: bool):
    """Nominal contact points and normals (W, 2D) of the cross-pocket plan."""
    from sim import artefacts as A
    from sim.catalog import make_plan

    plan = make_plan(A.cross_pocket())
    keep = np.array([spheres or not f.startswith("sphere") for f in plan.feature])
    ids = [t for t, k in zip(plan.target, keep) if k]
    return plan.w_A[keep, :2], plan.wn_A[keep, :2], ids


def cross_pocket_uncertainty(runs: int = 1000, seed: int = 1, progress=None) -> dict:
    """The paper's Fig. 18/19 and Table 2 study (see module docstring).

    ``progress(done, total)``: one step per case (C angles x spheres).
    """
    from core.selfcal import Grid
    from core.uncertainty import linear_uncertainty, monte_carlo

    grid = Grid.regular(-0.110, 0.110, 0.022)
    cases = []
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    table2 = []
    total = 2 * len(PAPER_G_U95_UM)
    for spheres in (True, False):
        w, wn, _ = _plan_points(spheres)
        for c in PAPER_G_U95_UM:
            if progress is not None:
                progress(len(cases), total)
            case = {"c_angles_deg": list(c), "spheres": spheres, "n_targets": len(w),
                    "paper_g_u95_max_um": PAPER_G_U95_UM[c] if spheres else None}
            try:
                mc = monte_carlo(w, wn, c, grid, U_PROBE_M, runs=runs, rng=rng)
                lin = linear_uncertainty(w, wn, c, grid, U_PROBE_M)
            except Exception as e:  # an unidentifiable design is a result, not a crash
                case.update(identifiable=False, reason=str(e), g_u95_max_um=None)
                cases.append(case)
                continue
            case.update(identifiable=True,
                        g_u95_max_um=round(mc.max_form_U95 * 1e6, 3),
                        g_u95_max_linear_um=round(lin.max_form_U95 * 1e6, 3),
                        g_u95_max_with_datum_um=round(mc.max_workpiece_U95 * 1e6, 3))
            cases.append(case)
            if spheres and len(c) == 4:
                des = mc.design
                for j, cj in enumerate(np.degrees(des.c_rad)):
                    xc = mc.U95[des.slices["EXC"]][j] * 1e6
                    yc = mc.U95[des.slices["EYC"]][j] * 1e6
                    cc = mc.U95[des.slices["ECC"]][j] * 1e6
                    p = PAPER_TABLE2.get(round(float(cj), 6), (0.0, 0.0, 0.0))
                    table2.append({"c_deg": round(float(cj), 6), "u_xc_um": round(float(xc), 3),
                                   "u_yc_um": round(float(yc), 3), "u_cc_urad": round(float(cc), 3), "paper_u_xc_um": p[0], "paper_u_yc_um": p[1],
                                   "paper_u_cc_urad": p[2]})
    if progress is not None:
        progress(total, total)
    return {
        "scenario": "cross-pocket-uncertainty",
        "method": f"Monte Carlo (JCGM 101), {runs} runs per case, linear propagation beside it",
        "u_probe_um": U_PROBE_M * 1e6,
        "grid_mm": "-110..110 step 22 (10 x 10 intervals), as the paper",
        "cases": cases,
        "table2": table2,
        "notes": [
            "g_u95_max_um: U95 (k=2) of the workpiece form, i.e. G with the part's shift, rotation and scale "
            "(the gauge of eqs 16-17) removed, the quantity of the paper's Figs 18-19; "
            "g_u95_max_with_datum_um adds the datum (eq 16-17 nodes at the grid edge).",
            "table2 values are U95 (k=2) like the paper's Table 2; C = 0 is the reference set-up (0 by eq 16). "
            "U_CC agrees with the paper within 10 %; U_XC and U_YC come out 2.5-3.5 times the paper's, a "
            "difference not yet explained (the reconstructed sphere positions and point layout are the first "
            "suspects: the C-axis shift is separated from the workpiece shift by few, sphere, points).",
            "The pocket is reconstructed (arms 200 mm, 36 mm wide, spheres at (60, 60) and (-70, -55) mm); "
            "the paper's point layout and sphere positions are not fully given, which moves the figures, most "
            "of all for two angles, where the design is at the edge of eq 6.",
        ],
        "seconds": round(time.perf_counter() - t0, 2),
    }


def pin_circle(seed: int = 1, noise_um: float = 1.8 / 2) -> dict:
    """The paper's case 2: raw error at C = 0 against the self-calibrated pin positions."""
    from core.selfcal import Grid, self_calibrate
    from core.touches import from_log
    from scenarios.hidden import gauge_free_rms_m, workpiece_truth
    from sim import artefacts as A
    from sim.campaign import simulate_campaign
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors
    from sim.catalog import make_plan
    from sim.probe import ProbeConfig

    t0 = time.perf_counter()
    angles = [0.0, 31.0, 83.0, 137.0, 191.0, 227.0, 257.0, 313.0]
    cfg = MACHINES["mikron-ucp710"]()
    errs = realistic_errors(tuple(a for a in ("X", "Y", "Z", "C") if a in cfg.strokes), strokes=cfg.strokes,
                            rng=np.random.default_rng(seed), ripple=False)
    machine = Machine(MACHINES["mikron-ucp710"](errors=errs))
    art = A.pin_circle()
    plan = make_plan(art)
    log = simulate_campaign(art, machine, ProbeConfig(repeatability_k2_m=2 * noise_um * 1e-6), angles,
                            np.random.default_rng(seed + 1), check_collisions=False)
    # the planar model takes the touches whose normals lie in XY (sphere points
    # off the equator are for 3D sphere fits, not for eqs 1-18)
    t = from_log(log.select(np.abs(log.col("nz")) < 0.01))
    # the paper's 80 mm step; nodes only where touches are (the paper's -400..400
    # mm grid has nodes no pin reaches, which nothing can identify)
    grid = Grid.from_extent(t.pn_R, 0.080)
    res = self_calibrate(t, grid)
    g_true = workpiece_truth(art, plan)
    first = {k: plan.target.index(k) for k in dict.fromkeys(plan.target)}
    w_A = {k: plan.w_A[i, :2] for k, i in first.items()}
    wn_A = {k: plan.wn_A[i, :2] for k, i in first.items()}
    raw0 = t.dq_m[t.setup == 0]
    ids0 = [t.target_ids[k] for k in t.target[t.setup == 0]]
    raw = gauge_free_rms_m(raw0, ids0, g_true, w_A, wn_A)
    cal = gauge_free_rms_m(res.G, res.design.target_ids, g_true, w_A, wn_A)
    pins = [k for k in res.design.target_ids if k.startswith("pin")]
    raw_max = _pin_position_error_max(t, res, g_true, plan, raw=True)
    cal_max = _pin_position_error_max(t, res, g_true, plan, raw=False)
    return {"scenario": "pin-circle", "machine": "mikron-ucp710 (realistic errors)", "c_angles_deg": angles,
            "grid_mm": f"{grid.x_m[0] * 1e3:g}..{grid.x_m[-1] * 1e3:g} step 80", "touches": t.n, "pins": len({p.rsplit('_', 1)[0] for p in pins}),
            "probing_sigma_um": noise_um,
            "raw_c0_rms_um": round(raw * 1e6, 3), "selfcal_rms_um": round(cal * 1e6, 3),
            "raw_c0_pin_error_max_um": round(raw_max, 3), "selfcal_pin_error_max_um": round(cal_max, 3),
            "paper": "raw about 8 um at C = 0, self-calibrated within 2 um",
            "notes": ["errors compared after removing the part's shift, rotation and scale (no self-calibration "
                      "sees them; the paper aligns to pin 1 and pin 11 likewise)",
                      "pin position = least-squares centre shift from the four normal deviations of each pin"],
            "seconds": round(time.perf_counter() - t0, 2)}


def _pin_position_error_max(t, res, g_true, plan, raw: bool) -> float:
    """Largest pin-centre position error (um) from the per-target normal deviations."""
    from core.selfcal import workpiece_form

    first = {k: plan.target.index(k) for k in dict.fromkeys(plan.target)}
    ids = [k for k in res.design.target_ids if k.startswith("pin")]
    if raw:
        sel = t.setup == 0
        g = {t.target_ids[k]: v for k, v in zip(t.target[sel], t.dq_m[sel])}
    else:
        g = dict(zip(res.design.target_ids, res.G))
    P, N, E = [], [], []
    for k in ids:
        i = first[k]
        P.append(plan.w_A[i, :2])
        N.append(plan.wn_A[i, :2])
        E.append(g[k] - g_true[k])
    P, N, E = np.array(P), np.array(N), np.array(E)
    # remove the part's rigid shift/rotation/scale first (as the paper aligns to pins)
    E = workpiece_form(E, P, N)
    worst = 0.0
    groups: dict = {}
    for k, n, e in zip(ids, N, E):
        groups.setdefault(k.rsplit("_", 1)[0], []).append((n, e))
    for rows in groups.values():
        Nn = np.array([r[0] for r in rows])
        ee = np.array([r[1] for r in rows])
        shift, *_ = np.linalg.lstsq(Nn, ee, rcond=None)
        worst = max(worst, float(np.hypot(*shift)))
    return worst * 1e6
