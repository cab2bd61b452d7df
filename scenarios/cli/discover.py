"""``vmt discover LOG --json OUT [--report DIR]``: what the model gets wrong, where, why, and what fixing it gains."""

from __future__ import annotations

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("discover", help="find what the baseline model misses, where, name the cause, extend, "
                                        "measure the gain")
    p.add_argument("log", help="probe-log/1 campaign (the same targets at two or more C angles), or a "
                               "positioning-log/1 ISO 230-2 test (baseline: the standard's mean per target "
                               "and direction)")
    p.add_argument("--json", dest="json_out", required=True, help="discovery report (JSON) to write")
    p.add_argument("--report", help="folder for a readable report (index.html, PNG figures, rerun .rrd)")
    from scenarios.cli.options import option

    # --grid-mm as in identify and design (the error-map grid, mm); discover takes its STEP form only
    option(p, "--grid-mm", dest="grid_mm", default=None, metavar="STEP", old=("--grid-step-mm",),
           help="error-map grid of the baseline, mm: STEP only, discover places the nodes (default: the step "
                "chosen by BIC among 22-80 mm)")
    p.set_defaults(func=run)


def run_discover(log_path, json_out, report=None, grid_mm=None, progress=None) -> dict:
    """Read, discover, check the result, write the report folder, then the JSON; return the report dict.

    Nothing is written unless the result is complete: the JSON is checked
    first (NaN or infinity in a figure the contract requires is refused),
    the report folder comes next and the JSON last. ``null`` is allowed only
    where the contract says "not available": the per-target workpiece
    figures, the findings' fitted magnitudes and their U95.
    """
    from core.atomic import json_safe, json_text, write_text_atomic

    if _is_positioning_log(log_path):
        d = _discover_positioning(log_path, report, grid_mm)
    else:
        d = _discover_probe_log(log_path, grid_mm, progress)
    rep = dict(d.to_report())
    for k in ("workpiece", "findings"):
        if k in rep:
            rep[k] = json_safe(rep[k])
    rep["log"] = str(log_path)
    text = json_text(rep, json_out)
    if report:
        from scenarios.reports import discovery_report

        discovery_report(report, d, rep, title=f"vmt discover: {Path(log_path).name}")
    write_text_atomic(json_out, text, special=True)
    return rep


def _discover_probe_log(log_path, grid_mm, progress):
    """The planar self-calibration baseline of a probe-log/1 campaign, then the search."""
    from core.baseline import extra_columns
    from core.discover import discover
    from core.probelog import read_probe_log
    from core.scope import check_planar_scope
    from core.touches import from_log

    log = read_probe_log(log_path)
    check_planar_scope(log, "discover")
    t = from_log(log)
    chain, extra = log.meta.get("kinematic_chain"), extra_columns(log, t.row)
    del log  # the file's columns are not the search's: 152 MiB held through it at the bench's 1e6 rows
    # the touches handed over, not held here: the search keeps only what it reads (core.baseline.planar_data)
    held = [t]
    del t
    return discover(held.pop(), grid_step_mm=grid_mm, chain=chain, progress=progress, extra=extra)


def _is_positioning_log(path) -> bool:
    """Whether the file's first line declares ``positioning-log/1`` (an unreadable file is left to the reader)."""
    from core.positioning import FORMAT

    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            first = f.readline()
    except (OSError, ValueError):
        return False
    return first.strip().replace(" ", "") == f"#format:{FORMAT}"


def _discover_positioning(log_path, report, grid_mm):
    """Discovery on an ISO 230-2 test: the standard's model (a mean per target and direction,
    the replicates' repeatability) as the baseline, then drift, warm-up, outliers (core.baseline)."""
    from core.baseline import positioning_from_log
    from core.discover import discover_baseline
    from core.exceptions import ConfigError
    from core.positioning import read_positioning_log

    if grid_mm is not None:
        raise ConfigError("--grid-mm: a positioning test has no error-map grid (its baseline is a mean per target "
                          "and direction)")
    if report:
        raise ConfigError("--report: not available for positioning tests yet (the JSON and the summary are; "
                          "vmt iso230-2 --report draws the test)")
    return discover_baseline(positioning_from_log(read_positioning_log(log_path)))


def _fmt(v, u=None, side=None) -> str:
    if v is None and isinstance(side, dict):  # a one-sided statement (core.discover._one_sided): no value +- U95
        if "at_least" in side:
            return f">= {side['at_least']:.3g} (not determined)"
        if "at_most" in side:
            return f"<= {side['at_most']:.3g} (not determined)"
        return "not determined"
    if isinstance(v, float):
        return f"{v:.3g}" + (f" +- {u:.2g}" if isinstance(u, float) else "")
    return "n/d" if v is None else str(v)


#: baseline kind -> (what its estimand is called, the noun of its rows) in the summary
ESTIMAND_WORDS = {"planar": ("workpiece", "targets"),
                  "positioning": ("deviation", "means per target and direction")}


def summary_lines(rep: dict, kind: str = "planar") -> list[str]:
    """The lines ``vmt discover`` prints for a report: baseline, noise, diagnosis, cause, gain.

    ``kind`` is the baseline's (``planar``: a probe-log campaign, its estimand the workpiece;
    ``positioning``: an ISO 230-2 test, its estimand the mean deviation per target and direction).
    """
    from core.discover import cv_ratio_text

    label, rows = ESTIMAND_WORDS[kind]
    b, nz = rep["baseline"], rep["noise_um"]
    out = [f"baseline   {b['model']}: rms {b['rms_um']:.3f} um, cv rms {rep['baseline_cv_rms_um']:.3f} um "
           f"({b['n']} touches, {b['n_params']} parameters)",
           f"noise      {nz['sigma_um']:.3f} um (from {nz['method']}); held-out/in-sample ratio "
           f"{nz['cv_gap']['ratio']:.2f} (pure noise: {nz['cv_gap']['expected_ratio']:.2f}, "
           f"p = {nz['cv_gap']['p_value']:.2g})"]
    shown = [d for d in rep["diagnosis"] if d["p_value"] < 0.01][:4]
    out += [f"diagnosis  {d['text']}" for d in shown]
    if not shown:
        out.append("diagnosis  no covariate carries structure (every smooth term's p >= 0.01)")
    if not rep["findings"]:
        out.append("cause      none: the baseline explains the data within the probing noise")
    for f in rep["findings"]:
        pu = f.get("params_u95", {})
        shown_params = list(f["params"].items())[:6]
        sides = f["evidence"].get("one_sided") or {}
        params = ", ".join(f"{k} {_fmt(v, pu.get(k), sides.get(k))}" for k, v in shown_params)
        flag = f" (ambiguous: {f['evidence'].get('confidence_reason', '')})" \
            if f["evidence"].get("confidence") == "ambiguous" else ""
        said_u95 = " (value +- U95, k = 2)" if any(isinstance(pu.get(k), float) for k, _ in shown_params) else ""
        out.append(f"finding    {f['cause']}{flag}: {params or f['evidence'].get('text', '')}{said_u95}")
    g = rep["gain"]
    out.append(f"extended   {rep['extended']['model']}: rms {rep['extended']['rms_um']:.3f} um "
               f"(x{g['rms_ratio']:.2f}), cv rms {rep['extended']['cv_rms_um']:.3f} um ({cv_ratio_text(g)})")
    if not rep["workpiece_identifiable"] and rep.get("workpiece") is not None:
        out.append(f"{label:10s} not identifiable by this design (reported as null)")
    elif rep.get("workpiece") and rep["findings"]:
        w = [r for r in rep["workpiece"] if isinstance(r.get("extended_u95_um"), float)
             and isinstance(r.get("baseline_u95_um"), float)]
        if w:
            moved = max(w, key=lambda r: abs(r["extended_um"] - r["baseline_um"]))
            out.append(f"{label:10s} U95 max {max(r['baseline_u95_um'] for r in w):.3f} -> "
                       f"{max(r['extended_u95_um'] for r in w):.3f} um (baseline -> extended, {len(w)} {rows}); "
                       f"largest change {moved['extended_um'] - moved['baseline_um']:+.3f} um at {moved['target']}")
    return out


def run(args) -> int:
    import math

    from core.exceptions import ConfigError
    from scenarios.cli.guard import progress_line, said

    if args.grid_mm is not None:
        try:
            step = float(args.grid_mm)
        except ValueError:
            step = None
        if step is None or not (math.isfinite(step) and step > 0):
            # 0 was taken for "choose by BIC" and a negative step failed on the grid's nodes in metres
            raise ConfigError(f"--grid-mm must be a finite number > 0 (mm; discover takes a STEP, not x0:x1:step), "
                              f"got {args.grid_mm}; leave it out to choose the step by BIC")
        args.grid_mm = step

    with progress_line("discover") as bar:
        rep = run_discover(args.log, args.json_out, args.report, args.grid_mm, progress=bar)
    for line in summary_lines(rep, "positioning" if _is_positioning_log(args.log) else "planar"):
        print(line)
    print(f"wrote {said(args.json_out)}" + (f" and {Path(args.report) / 'index.html'}" if args.report else ""))
    return 0
