"""``vmt identify LOG --json OUT``: 2D self-calibration of a probe log (core.selfcal)."""

from __future__ import annotations



def register(sub) -> None:
    p = sub.add_parser("identify", help="2D self-calibration on a rotary table (workpiece, X/Y and C errors)")
    p.add_argument("log", help="probe-log/1 campaign: the same targets at several C angles")
    p.add_argument("--json", required=True, metavar="OUT", help="JSON report to write (atomically)")
    p.add_argument("--grid-mm", default="22", metavar="STEP|x0:x1:step",
                   help="grid step (nodes at multiples of it covering the touches) or x0:x1:step (both axes; write --grid-mm=-110:110:22 when x0 < 0)")
    p.add_argument("--delta-l-um", type=float, default=None,
                   help="X positioning error at the last x node, measured (eq 17); omitted = scale unknown")
    p.add_argument("--mc", type=int, default=0, metavar="N", help="also run N Monte Carlo runs (JCGM 101)")
    p.add_argument("--seed", type=int, default=0, help="seed of the Monte Carlo runs")
    p.add_argument("--u-probe-um", type=float, default=None,
                   help="probing standard uncertainty for U95 (default: sigma from the residuals)")
    p.set_defaults(func=run)


def parse_grid(text: str, p_R):
    from core.exceptions import ConfigError
    from core.selfcal import Grid

    try:
        parts = [float(v) * 1e-3 for v in text.split(":")]
    except ValueError:
        raise ConfigError(f"--grid-mm: expected STEP or x0:x1:step in mm, got {text!r}") from None
    if len(parts) == 1:
        return Grid.from_extent(p_R, parts[0])
    if len(parts) == 3:
        return Grid.regular(parts[0], parts[1], parts[2])
    raise ConfigError(f"--grid-mm: expected STEP or x0:x1:step in mm, got {text!r}")


def _r(v, nd=4):
    return None if v is None else round(float(v), nd)


def report(res, mc=None) -> dict:
    """JSON-ready report (um, urad, mm, deg) of a :class:`core.selfcal.SelfCalResult`."""
    import numpy as np

    des = res.design
    s = des.slices
    U = 2 * res.std if res.std is not None else np.full(des.n_params, np.nan)

    def u95(i):
        v = U[i]
        return None if not np.isfinite(v) else v

    out = {
        "method": "2D self-calibration, Ibaraki et al. eqs 15-18",
        "touches": res.n_touches,
        "n_params": des.n_params,
        "rms_um": _r(res.rms_m * 1e6),
        "sigma_um": _r(res.sigma_m * 1e6),
        "sigma_source": res.sigma_source,
        "dof": res.dof,
        "conventions": {"gauge": list(des.gauge), "scale_known": res.scale_known, "yaw": des.yaw,
                        "notes": list(res.conventions[11:])},
        "workpiece": [],
        "axes": {},
        "rotary": [],
    }
    for k, tid in enumerate(des.target_ids):
        i = s["G"].start + k
        row = {"target": tid, "g_um": _r(res.theta[i] * 1e6), "u95_um": _r(u95(i) * 1e6)}
        if mc is not None:
            row["mc_u95_um"] = _r(mc.U95[i] * 1e6)
        out["workpiece"].append(row)
    for sym in ("EXX", "EYX", "EXY", "EYY", des.yaw):
        on_x = sym in ("EXX", "EYX", "ECX")
        pos = des.grid.x_m if on_x else des.grid.y_m
        idx = np.arange(s[sym].start, s[sym].stop)
        f, unit = (1e6, "urad") if sym in ("ECY", "ECX") else (1e6, "um")
        out["axes"][sym] = {"axis_pos": "x" if on_x else "y",
                            "positions_mm": [_r(v * 1e3) for v in pos],
                            f"values_{unit}": [_r(res.theta[i] * f) for i in idx],
                            f"u95_{unit}": [_r(u95(i) * f) for i in idx]}
    i = s["EC0Y"].start
    out["axes"]["EC0Y"] = {"value_urad": _r(res.theta[i] * 1e6), "u95_urad": _r(u95(i) * 1e6)}
    for j, sid in enumerate(des.setup_ids):
        ix, iy, ic = s["EXC"].start + j, s["EYC"].start + j, s["ECC"].start + j
        out["rotary"].append({"setup": sid, "c_deg": _r(np.degrees(des.c_rad[j]), 6),
                              "exc_um": _r(res.theta[ix] * 1e6), "exc_u95_um": _r(u95(ix) * 1e6),
                              "eyc_um": _r(res.theta[iy] * 1e6), "eyc_u95_um": _r(u95(iy) * 1e6),
                              "ecc_urad": _r(res.theta[ic] * 1e6), "ecc_u95_urad": _r(u95(ic) * 1e6)})
    if mc is not None:
        out["monte_carlo"] = {"runs": mc.runs, "u_probe_um": _r(mc.u_probe_m * 1e6),
                              "max_workpiece_u95_um": _r(mc.max_workpiece_U95 * 1e6),
                              "max_workpiece_form_u95_um": _r(mc.max_form_U95 * 1e6)}
    return out


def run(args) -> int:
    import numpy as np

    from core.exceptions import ConfigError
    from core.probelog import read_probe_log
    from core.scope import check_planar_scope
    from core.selfcal import identify, yaw_for_chain
    from core.touches import from_log
    from core.uncertainty import monte_carlo_touches

    log = read_probe_log(args.log)
    check_planar_scope(log, "identify")
    yaw = yaw_for_chain(log.meta.get("kinematic_chain"))
    # the planar model takes touches with normals in XY (sphere points off the
    # equator are for 3D fits); say how many were left out
    planar = abs(log.col("nz")) <= 0.01
    t = from_log(log.select(planar))
    if not planar.all():
        print(f"{args.log}: {int((~planar & log.ok).sum())} touches with normals out of the XY plane left out")
    grid = parse_grid(args.grid_mm, t.pn_R)
    dL = None if args.delta_l_um is None else args.delta_l_um * 1e-6
    sigma = None
    if args.u_probe_um is not None:
        if not args.u_probe_um > 0:
            raise ConfigError(f"--u-probe-um must be > 0, got {args.u_probe_um}")
        sigma = args.u_probe_um * 1e-6
    if args.mc < 0:
        raise ConfigError(f"--mc must be >= 0, got {args.mc}")
    res = identify(t, grid, dL, sigma_m=sigma, yaw=yaw)
    mc = None
    if args.mc:
        mc = monte_carlo_touches(t, grid, res.sigma_m, runs=args.mc, rng=np.random.default_rng(args.seed),
                                 delta_L_m=dL, yaw=yaw)
    from core.atomic import write_json_atomic

    out = write_json_atomic(args.json, report(res, mc))
    G = res.G
    print(f"{args.log}: {res.n_touches} touches, {len(G)} targets, {len(res.design.setup_ids)} C angles;"
          f" residual RMS {res.rms_m * 1e6:.3f} um; workpiece {G.min() * 1e6:+.2f}..{G.max() * 1e6:+.2f} um;"
          f" scale {'known' if res.scale_known else 'unknown'}")
    print(f"wrote {out}")
    return 0
