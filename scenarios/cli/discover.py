"""``vmt discover LOG --json OUT [--report DIR]``: what the model gets wrong, and why."""

from __future__ import annotations

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("discover", help="find what the baseline model misses, name the cause, extend, measure the gain")
    p.add_argument("log", help="probe-log/1 campaign (the same targets at two or more C angles)")
    p.add_argument("--json", dest="json_out", required=True, help="discovery report (JSON) to write")
    p.add_argument("--report", help="folder for a readable report (index.html, PNG figures, rerun .rrd)")
    p.add_argument("--grid-mm", type=float, default=None, help="error-map grid step of the baseline (default: finest identifiable)")
    p.set_defaults(func=run)


def run_discover(log_path, json_out, report=None, grid_mm=None) -> dict:
    """Read, discover, write the JSON (and the report); return the report dict."""
    from core.atomic import json_safe, write_json_atomic
    from core.discover import discover
    from core.probelog import read_probe_log
    from core.touches import from_log

    log = read_probe_log(log_path)
    t = from_log(log)
    d = discover(t, grid_step_mm=grid_mm, chain=log.meta.get("kinematic_chain"))
    rep = json_safe(d.to_report())
    rep["log"] = str(log_path)
    write_json_atomic(json_out, rep)
    if report:
        from scenarios.reports import discovery_report

        discovery_report(report, d, t, rep, title=f"vmt discover: {Path(log_path).name}")
    return rep


def run(args) -> int:
    rep = run_discover(args.log, args.json_out, args.report, args.grid_mm)
    print(f"baseline   {rep['baseline']['model']}: rms {rep['baseline']['rms_um']:.3f} um, "
          f"cv rms {rep['baseline_cv_rms_um']:.3f} um ({rep['baseline']['n']} touches, "
          f"{rep['baseline']['n_params']} parameters)")
    if not rep["findings"]:
        print("cause      none: the baseline explains the data within the probing noise")
    for f in rep["findings"]:
        shown = ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                          for k, v in list(f["params"].items())[:6])
        print(f"finding    {f['cause']}: rms {f['rms_um']:.3f} um  {shown}")
    g = rep["gain"]
    print(f"extended   {rep['extended']['model']}: rms {rep['extended']['rms_um']:.3f} um "
          f"(x{g['rms_ratio']:.2f}), cv rms {rep['extended']['cv_rms_um']:.3f} um (x{g['cv_rms_ratio']:.2f})")
    print(f"wrote {args.json_out}" + (f" and {args.report}/index.html" if args.report else ""))
    return 0
