"""``vmt discover LOG --json OUT [--report DIR]``: what the model gets wrong, where, why, and what fixing it gains."""

from __future__ import annotations

from pathlib import Path

# the library part (read, discover, check, write), shared with the regression studies; names kept here for callers
from scenarios.discover_run import (_discover_positioning, _discover_probe_log, _is_positioning_log,  # noqa: F401
                                    lobes_not_determined, magnitude_said, run_discover, unit_keys_back,
                                    workpiece_form_change)


def register(sub) -> None:
    p = sub.add_parser("discover", help="find what the baseline model misses, where, name the cause, extend, "
                                        "measure the gain")
    p.add_argument("log", help="probe-log/1 campaign (the same targets at two or more C angles), a "
                               "multi-feature bar's placements (its artefact line 'mfb': the volumetric baseline, "
                               "the 21 errors of X, Y, Z; docs/formats.md), or a positioning-log/1 ISO 230-2 test "
                               "(baseline: the standard's mean per target and direction)")
    p.add_argument("--json", dest="json_out", required=True, help="discovery report (JSON) to write")
    p.add_argument("--report", help="folder for a readable report (index.html, PNG figures, rerun .rrd)")
    from scenarios.cli.options import option

    # --grid-mm as in identify and design (the error-map grid, mm); discover takes its STEP form only
    option(p, "--grid-mm", dest="grid_mm", default=None, metavar="STEP", old=("--grid-step-mm",),
           help="error-map grid of the baseline, mm: STEP only, discover places the nodes (default: the step "
                "chosen by BIC among 22-80 mm)")
    from scenarios.cli.options import add_bar_calibration_arg

    add_bar_calibration_arg(p)
    p.set_defaults(func=run)


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


def _said(cause: str, k: str, v, u, side, kind: str) -> str:
    """A finding's parameter as printed: a fixed one with its unit and "(fixed)", an angle whose U95 reaches half
    its circle "n/d (U95 reaches half the circle)" (scenarios.discover_run.magnitude_said), else :func:`_fmt`."""
    m = magnitude_said(cause, k, v, u, kind)
    if m is None:
        return _fmt(v, u, side)
    return f"{m[0]} (fixed)" if m[1] == "fixed" else f"{m[0]} (U95 {m[1]})"


#: baseline kind -> (what its estimand is called, the noun of its rows) in the summary
ESTIMAND_WORDS = {"planar": ("workpiece", "targets"),
                  "positioning": ("deviation", "means per target and direction"),
                  "volumetric": ("tables", "node values")}


#: baseline kind -> the noun of the baseline's rows in the summary (default: touches)
ROW_WORDS = {"positioning": "readings", "volumetric": "point coordinates"}


def report_kind(rep: dict, positioning: bool) -> str:
    """The baseline kind of a discovery report: ``positioning`` (an ISO 230-2 test), ``volumetric`` (a
    multi-feature bar's log: its model's name) or ``planar``."""
    if positioning:
        return "positioning"
    return "volumetric" if str((rep.get("baseline") or {}).get("model", "")).startswith("volumetric") else "planar"


def summary_lines(rep: dict, kind: str = "planar") -> list[str]:
    """The lines ``vmt discover`` prints for a report: baseline, noise, diagnosis, cause, gain.

    ``kind`` is the baseline's (``planar``: a probe-log campaign, its estimand the workpiece;
    ``positioning``: an ISO 230-2 test, its estimand the mean deviation per target and direction).
    """
    from core.discover import DEFECT_CENTRE_FRAME, LEFT_OUT_NOTE, cv_ratio_text, not_counted_words

    unit = (rep.get("baseline") or {}).get("unit", "um")
    if unit != "um":   # a rotary positioning test's report: arc seconds (core.baseline.positioning_report_units)
        from core.baseline import positioning_report_units

        back = unit_keys_back(rep, unit)
        return [positioning_report_units(ln, unit) for ln in summary_lines(back, kind)]
    label, rows = ESTIMAND_WORDS[kind]
    b, nz = rep["baseline"], rep["noise_um"]
    # (what the repeats were taken beyond, besides the rates: a positioning run's time_by_direction)
    beyond = (" beyond " + ", ".join(nz["repeats"]["beyond"])
              if nz["method"] == "repeats" and (nz.get("repeats") or {}).get("beyond") else "")
    # (a positioning run's held-out/in-sample ratio is not printed: leaving a cycle out of means per target and
    # direction scales each residual by n/(n-1), so on balanced cycles the ratio is (n/(n-1))^2 whatever the data,
    # 1.56 of 1.56 at p = 1 on every run (review31c); the JSON keeps noise_um.cv_gap)
    gap = ("" if kind != "planar" else
           f"; held-out/in-sample ratio {nz['cv_gap']['ratio']:.2f} (pure noise: {nz['cv_gap']['expected_ratio']:.2f}, "
           f"p = {nz['cv_gap']['p_value']:.2g})")
    out = [f"baseline   {b['model']}: rms {b['rms_um']:.3f} um, cv rms {rep['baseline_cv_rms_um']:.3f} um "
           f"({b['n']} {ROW_WORDS.get(kind, 'touches')}, {b['n_params']} parameters)",
           f"noise      {nz['sigma_um']:.3f} um (from {nz['method']}{beyond}){gap}"]
    left = next((c for c in rep.get("conventions") or () if c.endswith(LEFT_OUT_NOTE)), None)
    if left is not None:  # said in the summary, not only in the JSON (review30c)
        out.append(f"left out   {left.split(' with ')[0]} with normals out of the XY plane (top faces, inclined "
                   "walls): the planar baseline reads X and Y only, so an error along Z (a spindle's Z growth) "
                   "cannot be seen here")
    shown = [d for d in rep["diagnosis"] if d["p_value"] < 0.01][:4]
    why = not_counted_words(rep)
    for d in shown:
        out.append(f"diagnosis  {d['text']}")
        if d["covariate"] in why:  # printed, yet no structure: say why (review30c: the verdict contradicted it)
            out.append(f"           ({why[d['covariate']]})")
    if not shown:
        out.append("diagnosis  no covariate carries structure (every smooth term's p >= 0.01)")
    if not rep["findings"]:
        out.append("cause      none: the baseline explains the data within the "
                   + ("repeatability" if kind == "positioning" else "probing noise"))
    for f in rep["findings"]:
        pu = f.get("params_u95", {})
        shown_params = list(f["params"].items())[:6]
        sides = f["evidence"].get("one_sided") or {}
        params = ", ".join(f"{k} {_said(f['cause'], k, v, pu.get(k), sides.get(k), kind)}" for k, v in shown_params)
        flag = f" (ambiguous: {f['evidence'].get('confidence_reason', '')})" \
            if f["evidence"].get("confidence") == "ambiguous" else ""
        said_u95 = " (value +- U95, k = 2)" if any(isinstance(pu.get(k), float) for k, _ in shown_params) else ""
        out.append(f"finding    {f['cause']}{flag}: {params or f['evidence'].get('text', '')}{said_u95}")
        if f["cause"] == "local_scale_defect" and isinstance(f["params"].get("axis"), str):
            # a bump's centre: of what (session 35), and the images of it the design cannot tell from it
            out.append("           centre_mm: " + "; ".join(
                [DEFECT_CENTRE_FRAME.format(axis=f["params"]["axis"])]
                + [im["text"] for im in f["evidence"].get("centre_images") or ()]))
    nd = rep.get("not_determined")
    if nd and nd.get("pretravel_lobe_orders"):
        out.append(f"not seen   pre-travel lobes k = {', '.join(map(str, nd['pretravel_lobe_orders']))}: absorbed by"
                   " the baseline on this design (not determined: no residual shows them, no cause measures them)")
    g = rep["gain"]
    out.append(f"extended   {rep['extended']['model']}: rms {rep['extended']['rms_um']:.3f} um "
               f"(x{g['rms_ratio']:.2f}), cv rms {rep['extended']['cv_rms_um']:.3f} um ({cv_ratio_text(g)})")
    if not rep["workpiece_identifiable"] and rep.get("workpiece") is not None:
        out.append(f"{label:10s} not identifiable by this design (reported as null)")
    elif rep.get("workpiece_not_offered"):  # (core.discover.SMOOTH_WORKPIECE_EARNED, WORKPIECE_U95_GROWTH_WITHHELD)
        no = rep["workpiece_not_offered"]
        u = no.get("u95_max_um") or {}
        gf = rep.get("workpiece_u95_gauge_free")
        # (the u95_growth rule's reason says the U95 of the form already; the smooth rule's does not)
        form = (f"; U95 of the form {gf['baseline_um']:.3f} um, the extended fit's {gf['extended_um']:.3f} um (RMS "
                f"over {gf['targets']} {rows}, the part's shift, rotation, scale and offset removed)"
                if gf and "u95_growth" not in str(no.get("rule", "")) else "")
        gauge = " in the map's gauge" if kind == "planar" else ""
        out.append(f"{label:10s} extended estimate not offered: {no['reason']}{form}; the baseline's is the estimate"
                   + (f" (U95 max{gauge} {u['baseline']:.3f} um; the extended fit's {u['extended']:.3f} um)"
                      if u else ""))
    elif rep.get("workpiece") and rep["findings"]:
        w = [r for r in rep["workpiece"] if isinstance(r.get("extended_u95_um"), float)
             and isinstance(r.get("baseline_u95_um"), float)]
        gf = rep.get("workpiece_u95_gauge_free")
        if w:
            bmax, emax = max(r["baseline_u95_um"] for r in w), max(r["extended_u95_um"] for r in w)
            if gf and not gf.get("extended_withheld"):
                # the figure WORKPIECE_U95_GROWTH_WITHHELD judges, with its meaning (session 36: "U95 max" was the
                # map's gauge's, read as the part's uncertainty; scenarios.discover_run.workpiece_u95_gauge_free)
                line = (f"{label:10s} U95 of the form {gf['baseline_um']:.3f} -> {gf['extended_um']:.3f} um (baseline "
                        f"-> extended: RMS over {gf['targets']} {rows} of each one's U95, k = 2, with the part's "
                        f"shift, rotation, scale and offset removed, what the data decide of the part; per target in "
                        f"the map's gauge at most {bmax:.3f} -> {emax:.3f} um)")
            else:   # (no gauge-free figure: an ISO 230-2 test's means have no gauge; a long log's factored covariance)
                line = (f"{label:10s} U95 max {bmax:.3f} -> {emax:.3f} um (baseline -> extended, {len(w)} {rows}"
                        + (", in the map's gauge" if kind == "planar" else "") + ")")
            fc = rep.get("workpiece_form_change")
            if fc is not None:
                # the form's change, the gauge removed: a shift/rotation/scale/offset of the part is no change of it
                gauge = "shift, rotation, scale, offset" + (", tilt, twist and growth" if fc.get("heights") else "")
                line += (f"; largest change of the form {fc['value_um']:+.3f} um at {fc['target']} (the part's {gauge}"
                         f" removed; {fc['raw_max_abs_um']:.3f} um at most per target in the gauge)")
            else:   # no geometry to remove a gauge with (a planar one said so; ISO 230-2's means have none)
                moved = max(w, key=lambda r: abs(r["extended_um"] - r["baseline_um"]))
                line += (f"; largest change {moved['extended_um'] - moved['baseline_um']:+.3f} um at "
                         f"{moved['target']}" + (" (in the gauge: shift, rotation and scale included)"
                                                 if kind == "planar" else ""))
            out.append(line)
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
        rep = run_discover(args.log, args.json_out, args.report, args.grid_mm, progress=bar,
                           bar_calibration=args.bar_calibration)
    for line in summary_lines(rep, report_kind(rep, _is_positioning_log(args.log))):
        print(line)
    print(f"wrote {said(args.json_out)}" + (f" and {Path(args.report) / 'index.html'}" if args.report else ""))
    return 0
