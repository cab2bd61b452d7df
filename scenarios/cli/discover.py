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

    warned: list[str] = []   # the reader's warnings (said on stderr by scenarios.cli.reading), for the JSON
    if _is_positioning_log(log_path):
        d = _discover_positioning(log_path, report, grid_mm, warned=warned)
    else:
        d = _discover_probe_log(log_path, grid_mm, progress, warned=warned)
    rep = dict(d.to_report())
    for k in ("workpiece", "findings"):
        if k in rep:
            rep[k] = json_safe(rep[k])
    fc = workpiece_form_change(d)
    if fc is not None:
        rep["workpiece_form_change"] = fc
    nd = lobes_not_determined(d)
    if nd is not None:
        rep["not_determined"] = nd
    rep["log"] = str(log_path)
    rep["input_warnings"] = warned
    text = json_text(rep, json_out)
    if report:
        from scenarios.reports import discovery_report

        discovery_report(report, d, rep, title=f"vmt discover: {Path(log_path).name}")
    write_text_atomic(json_out, text, special=True)
    return rep


def workpiece_form_change(d) -> dict | None:
    """The largest change of the workpiece's FORM from the baseline to the extended model, or None.

    The two models' workpiece estimates are each in a gauge: a shift, a
    rotation and a scale of the part and a common offset (with touches at
    several heights also a tilt, twist and growth of the raised targets) are
    not seen by self-calibration, and an effect the extended model takes (a
    drift, an offset per set-up) can move the estimate along them without
    changing the form at all (review 27: a drift run's per-target change of
    -1.320 um was at most 0.040 um of form). So the change is taken after
    removing that span (:func:`core.selfcal.workpiece_form`, the basis
    :func:`core.selfcal.workpiece_gauge_basis` of each target's nominal point,
    normal and height), over the targets both models report.
    """
    import numpy as np

    from core.selfcal import target_heights, workpiece_form

    bl = d.baseline
    geo = getattr(bl, "geometry", None)
    Gb, Ge = d.G_baseline_m, d.G_extended_m
    if geo is None or Gb is None or Ge is None or not d.workpiece_identifiable:
        return None
    Gb, Ge = np.asarray(Gb, float), np.asarray(Ge, float)
    P, N = np.asarray(geo[0], float), np.asarray(geo[1], float)
    ids = tuple(bl.estimand_ids)
    if not (len(Gb) == len(Ge) == len(P) == len(ids)):
        return None
    fz = target_heights(bl.data.touches, len(ids))   # each target's height above the common level
    dz = None if fz is None or not np.any(fz[1] != 0) else fz[1]
    ok = np.isfinite(Gb) & np.isfinite(Ge)
    if ok.sum() < 2:
        return None
    f = workpiece_form(Ge[ok] - Gb[ok], P[ok], N[ok], None if dz is None else dz[ok])
    raw = (Ge - Gb)[ok]
    j = int(np.argmax(np.abs(f)))
    kept = [ids[i] for i in np.flatnonzero(ok)]
    return {"max_abs_um": float(abs(f[j]) * 1e6), "value_um": float(f[j] * 1e6), "target": kept[j],
            "raw_max_abs_um": float(np.max(np.abs(raw)) * 1e6), "targets": int(ok.sum()), "heights": dz is not None,
            "what": "extended minus baseline workpiece, its shift, rotation, scale and common offset removed"
                    + (" (and the tilt, twist and growth of the raised targets)" if dz is not None else "")
                    + ": the change of the form, the part the gauge does not decide"}


def lobes_not_determined(d) -> dict | None:
    """The probe's pre-travel lobe orders the baseline absorbs (:func:`core.selfcal.absorbed_lobes`), or None.

    What the baseline takes exactly leaves no residual: no diagnosis sees it
    and no cause can be named for it, so a ``none`` says nothing about it
    (review 27: a three-lobe probe on a cross pocket, walls at 0/90/180/270
    deg, read as C-axis errors while discover said ``none``). Empty orders
    when every order of :data:`core.selfcal.LOBE_ORDERS` leaves a residual;
    None for a baseline without approach directions (an ISO 230-2 test).
    """
    import numpy as np

    from core.baseline import RANK_TOL
    from core.lsq import orth_of
    from core.selfcal import LOBE_ALIAS_SIN, LOBE_ORDERS, absorbed_lobes

    bl = d.baseline
    data = getattr(bl, "data", None)
    phi = getattr(data, "azimuth", None)
    if phi is None or getattr(bl, "kind", None) != "planar" or bl.A is None:
        return None
    qr = getattr(bl, "qr", None)
    if qr is not None:   # the baseline's own factorisation (reflectors: formed here, the same Q as ever)
        from core.diagnosis import qr_formed

        qr = qr_formed(qr)
    Q = orth_of(bl.A, getattr(bl, "rank_tol", None) or RANK_TOL, qr=qr)
    got = absorbed_lobes(np.asarray(phi, float), lambda x: Q @ (Q.T @ x))
    ks = [k for k, _ in got]
    lim = float(np.degrees(np.arcsin(LOBE_ALIAS_SIN)))
    what = (f"pre-travel lobes of order k = {', '.join(map(str, ks))} (approach azimuth, machine frame) are not "
            f"determined on this design: the baseline absorbs them (principal angle below {lim:.1f} deg), so no "
            "residual shows them and no cause's magnitude at these orders is measured: a `none` does not "
            "exclude them (vmt identify's not_covered names the parameters they move)" if ks else
            f"every pre-travel lobe order k = {', '.join(map(str, LOBE_ORDERS))} leaves a residual on this design")
    return {"pretravel_lobe_orders": ks, "principal_angle_deg": [round(a, 2) for _, a in got],
            "checked_lobe_orders": list(LOBE_ORDERS), "what": what}


def _discover_probe_log(log_path, grid_mm, progress, warned: list | None = None):
    """The planar self-calibration baseline of a probe-log/1 campaign, then the search
    (the reader's warnings said on stderr and added to ``warned``)."""
    from core.baseline import extra_columns
    from core.discover import discover
    from core.scope import check_planar_scope
    from core.touches import from_log
    from scenarios.cli.reading import read_probe

    log = read_probe(log_path, "discover", bar=progress)
    if warned is not None:
        warned.extend(log.warnings)
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


def _discover_positioning(log_path, report, grid_mm, warned: list | None = None):
    """Discovery on an ISO 230-2 test: the standard's model (a mean per target and direction,
    the replicates' repeatability) as the baseline, then drift, warm-up, outliers (core.baseline);
    the reader's warnings said on stderr and added to ``warned``."""
    from core.baseline import positioning_from_log
    from core.discover import discover_baseline
    from core.exceptions import ConfigError
    from scenarios.cli.reading import read_positioning

    if grid_mm is not None:
        raise ConfigError("--grid-mm: a positioning test has no error-map grid (its baseline is a mean per target "
                          "and direction)")
    if report:
        raise ConfigError("--report: not available for positioning tests yet (the JSON and the summary are; "
                          "vmt iso230-2 --report draws the test)")
    log = read_positioning(log_path, "discover")
    if warned is not None:
        warned.extend(log.warnings)
    return discover_baseline(positioning_from_log(log))


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
    from core.discover import LEFT_OUT_NOTE, cv_ratio_text, not_counted_words

    label, rows = ESTIMAND_WORDS[kind]
    b, nz = rep["baseline"], rep["noise_um"]
    # (what the repeats were taken beyond, besides the rates: a positioning run's time_by_direction)
    beyond = (" beyond " + ", ".join(nz["repeats"]["beyond"])
              if nz["method"] == "repeats" and (nz.get("repeats") or {}).get("beyond") else "")
    out = [f"baseline   {b['model']}: rms {b['rms_um']:.3f} um, cv rms {rep['baseline_cv_rms_um']:.3f} um "
           f"({b['n']} touches, {b['n_params']} parameters)",
           f"noise      {nz['sigma_um']:.3f} um (from {nz['method']}{beyond}); held-out/in-sample ratio "
           f"{nz['cv_gap']['ratio']:.2f} (pure noise: {nz['cv_gap']['expected_ratio']:.2f}, "
           f"p = {nz['cv_gap']['p_value']:.2g})"]
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
    nd = rep.get("not_determined")
    if nd and nd.get("pretravel_lobe_orders"):
        out.append(f"not seen   pre-travel lobes k = {', '.join(map(str, nd['pretravel_lobe_orders']))}: absorbed by"
                   " the baseline on this design (not determined: no residual shows them, no cause measures them)")
    g = rep["gain"]
    out.append(f"extended   {rep['extended']['model']}: rms {rep['extended']['rms_um']:.3f} um "
               f"(x{g['rms_ratio']:.2f}), cv rms {rep['extended']['cv_rms_um']:.3f} um ({cv_ratio_text(g)})")
    if not rep["workpiece_identifiable"] and rep.get("workpiece") is not None:
        out.append(f"{label:10s} not identifiable by this design (reported as null)")
    elif rep.get("workpiece") and rep["findings"]:
        w = [r for r in rep["workpiece"] if isinstance(r.get("extended_u95_um"), float)
             and isinstance(r.get("baseline_u95_um"), float)]
        if w:
            line = (f"{label:10s} U95 max {max(r['baseline_u95_um'] for r in w):.3f} -> "
                    f"{max(r['extended_u95_um'] for r in w):.3f} um (baseline -> extended, {len(w)} {rows})")
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
        rep = run_discover(args.log, args.json_out, args.report, args.grid_mm, progress=bar)
    for line in summary_lines(rep, "positioning" if _is_positioning_log(args.log) else "planar"):
        print(line)
    print(f"wrote {said(args.json_out)}" + (f" and {Path(args.report) / 'index.html'}" if args.report else ""))
    return 0
