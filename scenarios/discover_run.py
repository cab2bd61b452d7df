"""``vmt discover``'s library part: read a campaign (a probe log or an ISO 230-2 positioning log), discover,
check the result and write its JSON (and report folder). The command (:mod:`scenarios.cli.discover`) parses and
prints around it; regression studies (:mod:`scenarios.regress`, ``identification = "discover"``) run the very
same path. Here, not in the command module, because commands are leaves: nothing imports a command module but
the entry point (CONTRIBUTING.md, "Where new things go"; review31d F12).
"""

from __future__ import annotations

from pathlib import Path


def run_discover(log_path, json_out, report=None, grid_mm=None, progress=None, bar_calibration=None) -> dict:
    """Read, discover, check the result, write the report folder, then the JSON; return the report dict.

    Nothing is written unless the result is complete: the JSON is checked
    first (NaN or infinity in a figure the contract requires is refused),
    the report folder comes next and the JSON last. ``null`` is allowed only
    where the contract says "not available": the per-target workpiece
    figures, the findings' fitted magnitudes and their U95.

    A multi-feature bar's log (its ``artefact`` line ``mfb``) is discovered on the volumetric baseline
    (:func:`_discover_mfb_log`), never the planar one; ``bar_calibration`` (a ``vmt-bar-calibration/1`` path) is
    its certificate instead of the log's own lines, refused for any other log.
    """
    from core.atomic import json_text, write_text_atomic

    warned: list[str] = []   # the reader's warnings (said on stderr by scenarios.cli.reading), for the JSON
    if _is_positioning_log(log_path):
        if bar_calibration is not None:
            from core.exceptions import ConfigError

            raise ConfigError(f"--bar-calibration: {log_path} is a positioning test, not a multi-feature bar's log")
        d = _discover_positioning(log_path, report, grid_mm, warned=warned)
    else:
        d = _discover_probe_log(log_path, grid_mm, progress, warned=warned, bar_calibration=bar_calibration)
    rep = discover_json(d, log_path, warned)
    text = json_text(rep, json_out)
    if report:
        from scenarios.reports import discovery_report

        discovery_report(report, d, rep, title=f"vmt discover: {Path(log_path).name}")
    write_text_atomic(json_out, text, special=True)
    return rep


def discover_json(d, log_path, warned=()) -> dict:
    """The JSON document of a discovery ``d`` on the campaign ``log_path``: the engine's report
    (``d.to_report()``) with the figures ``vmt discover`` adds beside it (the workpiece's form change and its U95
    outside the part's gauge, the pre-travel lobes the baseline absorbs), the log and the reader's warnings
    ``warned``. The one writer of ``vmt discover``'s JSON and the demo's discover.json (session 37: the demo wrote
    the engine's report alone, without ``workpiece_u95_gauge_free``, so its file and the command's on the same
    campaign differed)."""
    from core.atomic import json_safe

    rep = dict(d.to_report())
    for k in ("workpiece", "findings"):
        if k in rep:
            rep[k] = json_safe(rep[k])
    if getattr(d.baseline, "kind", None) == "volumetric":
        # the MFB plan has no redundancy to hold points out (core.baseline.volumetric: Mallows' Cp), so there is
        # no held-out noise to compare: the cv_gap's figures are not available (null), not a failed result
        nz = dict(rep["noise_um"])
        nz["cv_gap"] = json_safe(nz.get("cv_gap"))
        rep["noise_um"] = nz
    fc = workpiece_form_change(d)
    if fc is not None:
        rep["workpiece_form_change"] = fc
    gf = workpiece_u95_gauge_free(d)
    if gf is not None:
        rep["workpiece_u95_gauge_free"] = gf
    nd = lobes_not_determined(d)
    if nd is not None:
        rep["not_determined"] = nd
    rep["log"] = str(log_path)
    rep["input_warnings"] = list(warned)
    return rep


#: A finding's parameters that are context, not fitted: printed with their unit and "(fixed)", never "+- U95"
#: (audit35 N2: a drift's ``over_h``, the campaign's duration, printed "0.924 +- 0" as if it were measured; the
#: JSON keeps its value and its params_u95 of 0.0). Name -> unit.
FIXED_PARAMS = {"over_h": "h"}


def magnitude_said(cause: str, key: str, v, u, kind: str = "planar") -> tuple[str, str | None] | None:
    """How the summary and the report page say a parameter the JSON gives without a measured U95, or None.

    ``(value text, U95 text)`` for a context parameter (:data:`FIXED_PARAMS`: ``("0.924 h", "fixed")``) and for
    an angle whose U95 the report withholds because it reaches half its circle (a cause's
    :attr:`core.causes.Cause.circular`: a periodic error's phase beside an amplitude consistent with zero;
    audit35 N1: ``EYX_phase_rad -1.96`` was printed bare, read as a measurement): ``("n/d", "reaches half the
    circle")``. None for every other parameter (said as before: value +- U95, or n/d).
    """
    from fnmatch import fnmatchcase

    if key in FIXED_PARAMS and isinstance(v, float):
        return f"{v:.3g} {FIXED_PARAMS[key]}", "fixed"
    if isinstance(v, float) and u is None:
        from core import causes

        c = causes.lookup(cause, kind)
        if c is not None and any(fnmatchcase(key, pat) for pat in (c.circular or {})):
            return "n/d", "reaches half the circle"
    return None


def unit_keys_back(rep, unit: str):
    """A positioning report with its ``_<unit>`` keys named ``_um`` again (what the summary and the report page
    read), ``unit`` gone from the baseline block; the values as they are (:func:`core.baseline.positioning_report_units`
    renamed them; a linear axis's report, ``unit`` "um", comes back unchanged)."""
    if isinstance(rep, dict):
        return {(k.replace(f"_{unit}", "_um") if isinstance(k, str) else k): unit_keys_back(v, unit)
                for k, v in rep.items() if not (k == "unit" and v == unit)}
    if isinstance(rep, list):
        return [unit_keys_back(v, unit) for v in rep]
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


#: What ``workpiece_u95_gauge_free`` measures, in words (the JSON's ``what``; the summary says it shorter).
GAUGE_FREE_U95_WHAT = ("the RMS over the targets of each target's U95 (k = 2) once the part's shift, rotation, "
                       "scale and common offset are removed (what self-calibration cannot see, so what the data "
                       "decide of the part's form); the per-target U95 of the workpiece table is in the map's gauge "
                       "and its largest value mostly measures that gauge")


def workpiece_u95_gauge_free(d) -> dict | None:
    """The workpiece's U95 outside the part's gauge, baseline and extended, or None.

    The figure :data:`core.discover.WORKPIECE_U95_GROWTH_WITHHELD` judges, by the engine's own function
    (``core.discover._u95_gauge_free``: imported, not copied, so the summary prints what the rule reads): the RMS
    over the targets both models determine of each target's U95 (k = 2) once the span of
    :func:`core.selfcal.workpiece_gauge_basis` (the part's shift, rotation, scale and common offset) is removed.
    The per-target U95 of the report (``baseline_u95_um``, ``extended_u95_um``) is in the map's gauge; its largest
    value mostly measures that gauge (docs/discovery.md, "U95 max" of the summary before session 36). Where the
    extended estimate is withheld, the extended figure is the extended fit's (the one the rule judged). None
    without geometry, with a factored covariance (a long log's) or fewer than six targets, and for an ISO 230-2
    test (its means per target have no gauge).
    """
    from core.discover import _u95_gauge_free

    bl = d.baseline
    if getattr(bl, "kind", None) != "planar" or not d.workpiece_identifiable or not d.findings:
        return None
    withheld = d.workpiece_not_offered is not None
    Ge = d.G_extended_fit_m if withheld else d.G_extended_m
    cGe = d.cov_G_extended_fit if withheld else d.cov_G_extended
    if d.G_baseline_m is None or Ge is None:
        return None
    g = _u95_gauge_free(bl, d.G_baseline_m, Ge, d.cov_G_baseline, cGe)
    if g is None:
        return None
    import numpy as np

    e, b = g
    n = int(np.sum(np.isfinite(np.asarray(d.G_baseline_m, float)) & np.isfinite(np.asarray(Ge, float))))
    return {"baseline_um": b, "extended_um": e, "ratio": e / b if b > 0 else None, "targets": n,
            "extended_withheld": withheld, "what": GAUGE_FREE_U95_WHAT}


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


def _discover_probe_log(log_path, grid_mm, progress, warned: list | None = None, bar_calibration=None):
    """The planar self-calibration baseline of a probe-log/1 campaign, then the search
    (the reader's warnings said on stderr and added to ``warned``); a multi-feature bar's log: the volumetric
    baseline (:func:`_discover_mfb_log`)."""
    from core.baseline import extra_columns
    from core.discover import discover
    from core.exceptions import ConfigError
    from core.mfblog import is_mfb_log
    from core.scope import check_planar_scope
    from core.touches import from_log

    from scenarios.cli.reading import read_probe

    log = read_probe(log_path, "discover", bar=progress)
    if warned is not None:
        warned.extend(log.warnings)
    if is_mfb_log(log):
        return _discover_mfb_log(log, grid_mm, bar_calibration, progress)
    if bar_calibration is not None:
        raise ConfigError(f"--bar-calibration: {log_path} is not a multi-feature bar's log (its artefact line is "
                          "not 'mfb'): the option is for MFB logs")
    check_planar_scope(log, "discover")
    t = from_log(log)
    chain, extra = log.meta.get("kinematic_chain"), extra_columns(log, t.row)
    del log  # the file's columns are not the search's: 152 MiB held through it at the bench's 1e6 rows
    # the touches handed over, not held here: the search keeps only what it reads (core.baseline.planar_data)
    held = [t]
    del t
    return discover(held.pop(), grid_step_mm=grid_mm, chain=chain, progress=progress, extra=extra)


#: Percent of ``vmt discover``'s work on a multi-feature bar's log done when the bars' points of interest are fitted
#: (after the search's imports and the log's reading), when every measurement's noise gain is computed
#: (:func:`core.mfblog.read_mfb_log` counts them) and when the volumetric baseline is built; the search is the
#: rest. Measured on ``vmt simulate mfb-3axis``'s log (3,888 touches, 17 measurements; session 38: the progress
#: line had no count at all for the 10-20 s): idle, imports 2-3 s, reading and fits 0.8 s, gains 3 s, baseline
#: 1.3 s, search 0.13 s; at load 3, 8-9 s, 7 s, 2.3 s and 0.3 s.
MFB_DISCOVER_SHARES = (40, 80, 97)


def mfb_log_baseline(log, bar_calibration=None, progress=None):
    """(volumetric baseline, :class:`core.mfblog.MfbLog`) of a multi-feature bar's probe log ``log``: its
    measurements (:func:`core.mfblog.read_mfb_log`, the certificate ``bar_calibration`` (a path) or the log's own
    lines), each at the mean time of its touches, and the noise model a metrologist declares with them: the
    probe's repeatability (the log's probe_repeatability_k2_um line) and the bar's certificate through its rods
    (:func:`core.mfb.calibration_map`), as ``scenarios.hidden.mfb_declared_noise`` declares them for the
    simulated campaigns; without a repeatability line, the touch noise alone (said in the baseline's conventions).
    ``progress(done, 100)``: the percent done (:data:`MFB_DISCOVER_SHARES`)."""
    from core.baseline import volumetric
    from core.mfb import calibration_map
    from core.mfblog import BarCertificate, read_mfb_log

    cert = None
    if bar_calibration is not None:
        from scenarios.mfb import read_bar_calibration

        cal, _ = read_bar_calibration(bar_calibration)
        cert = BarCertificate(cal.E_m, cal.u_m, f"--bar-calibration {bar_calibration}")
    fitted, read, built = MFB_DISCOVER_SHARES
    ml = read_mfb_log(log, cert, progress=None if progress is None else (
        lambda k, n: progress(fitted + (read - fitted) * k // max(n, 1), 100)))
    declared = ({"sigma_probe_m": ml.sigma_probe_m, "u_cal_m": ml.certificate.u_m, "cal_map": calibration_map()}
                if ml.sigma_probe_m else {})
    from scenarios.cli.guard import about_file

    with about_file(log.source):
        bl = volumetric(ml.meas, ml.chain, ml.nodes, ml.rotary_points_R_m, ml.times_s, **declared)
    if progress is not None:
        progress(built, 100)
    return bl, ml


def _discover_mfb_log(log, grid_mm, bar_calibration=None, progress=None):
    """Discovery on a multi-feature bar's log: the volumetric baseline (:func:`mfb_log_baseline`), then the search
    (``core.discover.discover_baseline``, as the MFB studies run it: ``scenarios.hidden.mfb_outcome``)."""
    from core.discover import discover_baseline
    from core.exceptions import ConfigError

    if grid_mm is not None:
        raise ConfigError(f"--grid-mm: {log.source} is a multi-feature bar's log: its error tables' nodes are its "
                          "bars' points of interest (its error_table_nodes_mm line, else derived from the bars)")
    bl, _ = mfb_log_baseline(log, bar_calibration, progress)
    del log
    built = MFB_DISCOVER_SHARES[-1]
    return discover_baseline(bl, progress=None if progress is None else (
        lambda k, n: progress(built + (100 - built) * k // max(n, 1), 100)))


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
    the replicates' repeatability) as the baseline, then drift, warm-up, outliers (core.baseline)."""
    from core.baseline import positioning_from_log
    from core.discover import discover_baseline
    from core.exceptions import ConfigError

    if grid_mm is not None:
        raise ConfigError("--grid-mm: a positioning test has no error-map grid (its baseline is a mean per target "
                          "and direction)")
    from scenarios.cli.reading import read_positioning

    log = read_positioning(log_path, "discover")
    if warned is not None:
        warned.extend(log.warnings)
    return discover_baseline(positioning_from_log(log))
