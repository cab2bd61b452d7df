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


def run_discover(log_path, json_out, report=None, grid_mm=None, progress=None) -> dict:
    """Read, discover, check the result, write the report folder, then the JSON; return the report dict.

    Nothing is written unless the result is complete: the JSON is checked
    first (NaN or infinity in a figure the contract requires is refused),
    the report folder comes next and the JSON last. ``null`` is allowed only
    where the contract says "not available": the per-target workpiece
    figures and the findings' fitted magnitudes.
    """
    from core.atomic import json_safe, json_text, write_text_atomic
    from core.discover import discover
    from core.probelog import read_probe_log
    from core.scope import check_planar_scope
    from core.touches import from_log

    log = read_probe_log(log_path)
    check_planar_scope(log, "discover")
    t = from_log(log)
    kw = {}
    if progress is not None and _takes_progress(discover):
        kw["progress"] = progress
    d = discover(t, grid_step_mm=grid_mm, chain=log.meta.get("kinematic_chain"), **kw)
    rep = dict(d.to_report())
    for k in ("workpiece", "findings"):
        if k in rep:
            rep[k] = json_safe(rep[k])
    rep["log"] = str(log_path)
    text = json_text(rep, json_out)
    if report:
        from scenarios.reports import discovery_report

        discovery_report(report, d, t, rep, title=f"vmt discover: {Path(log_path).name}")
    write_text_atomic(json_out, text, special=True)
    return rep


def _takes_progress(fn) -> bool:
    """True when the discovery engine takes ``progress(done, total)`` (its next version will)."""
    import inspect

    try:
        return "progress" in inspect.signature(fn).parameters
    except (TypeError, ValueError):  # pragma: no cover
        return False


def summary_lines(rep: dict) -> list[str]:
    """The lines ``vmt discover`` prints for a report."""
    out = [f"baseline   {rep['baseline']['model']}: rms {rep['baseline']['rms_um']:.3f} um, "
           f"cv rms {rep['baseline_cv_rms_um']:.3f} um ({rep['baseline']['n']} touches, "
           f"{rep['baseline']['n_params']} parameters)"]
    if not rep["findings"]:
        out.append("cause      none: the baseline explains the data within the probing noise")
    for f in rep["findings"]:
        shown = ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                          for k, v in list(f["params"].items())[:6])
        rms = "n/a" if f.get("rms_um") is None else f"{f['rms_um']:.3f} um"
        out.append(f"finding    {f['cause']}: rms {rms}  {shown}")
    g = rep["gain"]
    out.append(f"extended   {rep['extended']['model']}: rms {rep['extended']['rms_um']:.3f} um "
               f"(x{g['rms_ratio']:.2f}), cv rms {rep['extended']['cv_rms_um']:.3f} um (x{g['cv_rms_ratio']:.2f})")
    return out


def run(args) -> int:
    from scenarios.cli.guard import progress_line

    with progress_line("discover") as bar:
        rep = run_discover(args.log, args.json_out, args.report, args.grid_mm, progress=bar)
    for line in summary_lines(rep):
        print(line)
    from scenarios.cli.guard import said

    print(f"wrote {said(args.json_out)}" + (f" and {args.report}/index.html" if args.report else ""))
    return 0
