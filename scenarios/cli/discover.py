"""``vmt discover LOG --json OUT [--report DIR]``: what the model gets wrong, where, why, and what fixing it gains."""

from __future__ import annotations

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("discover", help="find what the baseline model misses, where, name the cause, extend, "
                                        "measure the gain")
    p.add_argument("log", help="probe-log/1 campaign (the same targets at two or more C angles)")
    p.add_argument("--json", dest="json_out", required=True, help="discovery report (JSON) to write")
    p.add_argument("--report", help="folder for a readable report (index.html, PNG figures, rerun .rrd)")
    p.add_argument("--grid-mm", type=float, default=None,
                   help="error-map grid step of the baseline, mm (default: chosen by BIC among 22-80 mm)")
    p.set_defaults(func=run)


def run_discover(log_path, json_out, report=None, grid_mm=None, progress=None):
    """Read, discover, write the JSON (and the report); return (report dict, Discovery)."""
    from core.atomic import json_safe, write_json_atomic
    from core.baseline import extra_columns
    from core.discover import discover
    from core.probelog import read_probe_log
    from core.scope import check_planar_scope
    from core.touches import from_log

    log = read_probe_log(log_path)
    check_planar_scope(log, "discover")
    t = from_log(log)
    d = discover(t, grid_step_mm=grid_mm, chain=log.meta.get("kinematic_chain"), progress=progress,
                 extra=extra_columns(log, t.row))
    rep = json_safe(d.to_report())
    rep["log"] = str(log_path)
    write_json_atomic(json_out, rep)
    if report:
        from scenarios.reports import discovery_report

        discovery_report(report, d, rep, title=f"vmt discover: {Path(log_path).name}")
    return rep, d


def _fmt(v, u=None) -> str:
    if isinstance(v, float):
        return f"{v:.3g}" + (f" +- {u:.2g}" if isinstance(u, float) else "")
    return "n/d" if v is None else str(v)


def run(args) -> int:
    from viz.progress import TerminalProgress

    with TerminalProgress("discover") as bar:
        rep, _ = run_discover(args.log, args.json_out, args.report, args.grid_mm, progress=bar)
    b, nz = rep["baseline"], rep["noise_um"]
    print(f"baseline   {b['model']}: rms {b['rms_um']:.3f} um, cv rms {rep['baseline_cv_rms_um']:.3f} um "
          f"({b['n']} touches, {b['n_params']} parameters)")
    print(f"noise      {nz['sigma_um']:.3f} um (from {nz['method']}); held-out/in-sample ratio "
          f"{nz['cv_gap']['ratio']:.2f} (pure noise: {nz['cv_gap']['expected_ratio']:.2f}, "
          f"p = {nz['cv_gap']['p_value']:.2g})")
    shown = [d for d in rep["diagnosis"] if d["p_value"] < 0.01][:4]
    for d in shown:
        print(f"diagnosis  {d['text']}")
    if not shown:
        print("diagnosis  no covariate carries structure (every smooth term's p >= 0.01)")
    if not rep["findings"]:
        print("cause      none: the baseline explains the data within the probing noise")
    for f in rep["findings"]:
        pu = f.get("params_u95", {})
        params = ", ".join(f"{k} {_fmt(v, pu.get(k))}" for k, v in list(f["params"].items())[:6])
        flag = " (ambiguous: " + ", ".join(f["evidence"]["indistinguishable_from"]) + ")" \
            if f["evidence"].get("confidence") == "ambiguous" else ""
        text = f["evidence"].get("text", "")
        print(f"finding    {f['cause']}{flag}: {params or text}")
    g = rep["gain"]
    print(f"extended   {rep['extended']['model']}: rms {rep['extended']['rms_um']:.3f} um "
          f"(x{g['rms_ratio']:.2f}), cv rms {rep['extended']['cv_rms_um']:.3f} um (x{g['cv_rms_ratio']:.2f})")
    if not rep["workpiece_identifiable"]:
        print("workpiece  not identifiable by this design (reported as null)")
    print(f"wrote {args.json_out}" + (f" and {args.report}/index.html" if args.report else ""))
    return 0
