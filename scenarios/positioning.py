"""ISO 230-2 positioning tests: evaluate a file, report it, run one on a virtual machine.

The commands ``vmt iso230-2`` and ``vmt simulate positioning`` are thin
wrappers of :func:`evaluate_file` and :func:`simulate_test`.
"""

from __future__ import annotations

import dataclasses

from pathlib import Path

import numpy as np

#: Figures in the order the standard defines them: (name, symbol, clause, meaning).
FIGURE_ROWS = (
    ("B", "B", "2.13", "reversal value of the axis, max |B_i|"),
    ("B_mean", "B̄", "2.14", "mean reversal value"),
    ("R_up", "R↑", "2.18", "unidirectional repeatability, approach +"),
    ("R_down", "R↓", "2.18", "unidirectional repeatability, approach -"),
    ("R", "R", "2.19", "bidirectional repeatability (with the reversal term)"),
    ("E_up", "E↑", "2.20", "unidirectional systematic positioning error, +"),
    ("E_down", "E↓", "2.20", "unidirectional systematic positioning error, -"),
    ("E", "E", "2.21", "bidirectional systematic positioning error"),
    ("M", "M", "2.22", "range of the mean bidirectional positional deviation"),
    ("A_up", "A↑", "2.23", "unidirectional accuracy, +"),
    ("A_down", "A↓", "2.23", "unidirectional accuracy, -"),
    ("A", "A", "2.24", "bidirectional accuracy"),
)


#: What a pilgrim-cycle test's figures are, in the JSON (``cycle_note``), the CLI and the report. vmt's
#: ``pilgrim`` cycle (:mod:`sim.positioning`: each target approached ``n`` times from each side before the
#: axis steps on) is a step cycle, the optional cycle of ISO 230-2:2014 Annex B, whose scope says its
#: results are not to be quoted with reference to ISO 230-2 nor used for acceptance except under a written
#: agreement between manufacturer/supplier and user: acceptance to ISO 230-2 means the standard (linear)
#: test cycle.
PILGRIM_NOTE = ("a pilgrim (step) cycle, ISO 230-2:2014 Annex B: not ISO 230-2 results to quote or to accept a "
                "machine by, unless manufacturer/supplier and user agree so in writing (acceptance: the "
                "standard, linear cycle)")


#: Share of :func:`evaluate_file`'s work with a report done (percent) once the test is evaluated and
#: its JSON written, once the report's figure is drawn and once the report is written: CPU seconds
#: measured on a simulated test of 110 readings and one of 8,000 (0.03-0.09, 0.31-0.36 and 0.20 s;
#: matplotlib's import is in the figure's), for the progress line's time left.
REPORT_SHARES = (8, 66, 100)


def evaluate_file(path, json_out, report=None, *, kind: str = "auto", uncertainty=None,
                  write_log=None, comp_file=None, add_to=None, comp_range_deg=None,
                  progress=None) -> tuple[dict, list[str]]:
    """Read a positioning test, evaluate ISO 230-2, write the JSON (and report).

    Parameters
    ----------
    path : path
        ``positioning-log/1``, an ecmc ``.dat`` or a table (``kind``).
    json_out : path
        JSON report to write (atomically).
    report : path, optional
        Report folder (index.html, figure).
    kind : str
        ``auto``, ``log``, ``ecmc`` or ``table``.
    uncertainty : core.positioning.UncertaintyInputs, optional
        Measuring conditions: adds the expanded uncertainty of each figure.
    write_log : path, optional
        Also write the readings as ``positioning-log/1`` (an import).
    comp_file : path, optional
        Also write a LinuxCNC TYPE 0 compensation table of the axis
        (:func:`hardware.linuxcnc.positioning_comp_file`: at the axis positions,
        target + the log's ``tool_offset_mm``).
    comp_range_deg : (lo, hi), optional
        A rotary test: the joint positions ``comp_file`` must cover, deg
        (:func:`hardware.linuxcnc.rotary_wrap_rows`); refused on a linear test.
    add_to : path, optional
        The TYPE 0 file the joint had loaded during the test: the test measured
        its residual, and ``comp_file`` gets their sum
        (:func:`hardware.linuxcnc.add_comp`), not the residual alone, which
        LinuxCNC would load in the old table's place.
    progress : callable, optional
        ``progress(done, 100)``: the share of the work done (:data:`REPORT_SHARES`), after each step.

    Returns
    -------
    (dict, list of str)
        The JSON report and its warnings.
    """
    from core.atomic import write_json_atomic
    from core.exceptions import ConfigError
    from core.positioning import (arrange, baseline, figure_uncertainty, iso230_2, load_positioning, printed_step,
                                  skipped_readings, write_positioning_log)

    if add_to and not comp_file:
        raise ConfigError("--add-to: give --comp-file too (the file to write: the old table plus this test's residual)")
    old_table = None
    if add_to:
        from hardware.linuxcnc import read_comp_file

        old_table = read_comp_file(add_to)          # a bad file is refused before anything is written
    log = load_positioning(path, kind=kind)
    test = arrange(log)
    result = iso230_2(test)
    rep = result.to_report()
    rep["log"] = str(path)
    rep["machine"] = log.meta.get("machine", "")
    rep["instrument"] = log.meta.get("instrument", "")
    rep["input_warnings"] = list(log.warnings)   # the reader's own (also among "warnings", with the test's)
    rep["readings"] = skipped_readings(log)      # read, valid, left out for their status (review34)
    if rep.get("cycle_kind") == "pilgrim":
        rep["cycle_note"] = PILGRIM_NOTE
    rep["printed_step"], w = printed_step(log, result)   # the readings' rounding (review34), beside the figures
    if w:
        result = dataclasses.replace(result, warnings=tuple(result.warnings) + (w,))
        rep["warnings"] = list(result.warnings)
    budget = None
    if uncertainty is not None:
        budget = figure_uncertainty(result, uncertainty, step=log.text_steps.get("measured"))
        rep["uncertainty"] = budget.to_report()
        w = (budget.temperature or {}).get("warning")
        if w:   # (the readings are not corrected to 20 C here: said where the figures are, review31 F10)
            result = dataclasses.replace(result, warnings=tuple(result.warnings) + (w,))
            rep["warnings"] = list(result.warnings)
    base = baseline(test)
    k = 1e3 if test.unit == "mm" else 3600.0
    ru = rep["unit"]
    rep["baseline"] = {"model": "ISO 230-2: one mean per target and direction",
                       "n_params": base.n_params, "dof": base.dof, f"rms_{ru}": base.rms * k,
                       f"s_up_pooled_{ru}": base.s_up_pooled * k, f"s_down_pooled_{ru}": base.s_down_pooled * k}
    if J := log.tool_offset_mm:
        rep["tool_offset_mm"] = list(J)
        rep["axis_position_offset_mm"] = log.joint_offset
    comp_text = None
    if comp_file:
        from hardware.linuxcnc import positioning_comp_file

        if comp_range_deg is not None and test.unit != "deg":
            raise ConfigError(f"--comp-range-deg: {path} is a test in {test.unit}; the range in degrees is for a "
                              "rotary axis (a log in degrees)")
        try:
            comp_text = positioning_comp_file(test, comp_range_deg)
        except ConfigError as e:
            if comp_range_deg is None:
                raise
            raise ConfigError(f"--comp-range-deg {comp_range_deg[0]:g}:{comp_range_deg[1]:g}: {e}") from None
        if old_table is not None:
            from hardware.linuxcnc import add_comp, comp_text as _text

            residual = np.array([[float(v) for v in ln.split()] for ln in comp_text.splitlines()])
            try:
                comp_text = _text(add_comp(old_table, residual))
            except ConfigError as e:
                raise ConfigError(f"--add-to {add_to}: {e}") from None
            rep["comp_file_added_to"] = str(add_to)
    if write_log:
        write_positioning_log(write_log, log, special=True)
    if comp_text is not None:
        from core.atomic import write_text_atomic

        write_text_atomic(comp_file, comp_text, special=True)
    write_json_atomic(json_out, rep, special=True)
    if report:
        if progress is not None:
            progress(REPORT_SHARES[0], 100)
        positioning_report(report, rep, log, budget=budget, title=f"ISO 230-2: {Path(path).name}",
                           progress=progress)
    if progress is not None:
        progress(100, 100)
    return rep, list(result.warnings)


def positioning_report(folder, rep: dict, log, *, budget=None, title: str = "ISO 230-2 positioning test",
                       progress=None):
    """Write the report folder of one evaluated test (viz.report helpers); ``progress(done, 100)``
    once its figure is drawn (:data:`REPORT_SHARES`)."""
    from viz.figures import positioning_figure
    from viz.report import Section, Table, write_report

    u = rep["unit"]
    sym = "µm" if u == "um" else "arcsec"
    from core.positioning import cycles_said

    test_text = (f"Axis {rep.get('axis') or '?'}; {rep['targets']} targets, {cycles_said(rep)}"
                 f"{', ' + rep['cycle_kind'] + ' cycle' if rep.get('cycle_kind') else ''}; "
                 f"machine {rep.get('machine') or '?'}; instrument {rep.get('instrument') or '?'}. "
                 "Definitions of ISO 230-2 (clause numbers of the 2006 edition, unchanged in 2014): "
                 "x_ij = P_ij - P_i, means and s (n - 1) per target and direction, R_i = max(2 s↑ + 2 s↓ "
                 "+ |B_i|, 4 s↑, 4 s↓).")
    if rep.get("cycle_note"):
        test_text += f"\n\nNote: {rep['cycle_note']}."
    if rep.get("warnings"):
        test_text += "\n\nWarnings: " + "; ".join(rep["warnings"]) + "."
    rows = []
    unc = rep.get("uncertainty") or {}
    for name, symbol, clause, meaning in FIGURE_ROWS:
        row = [symbol, clause, meaning, rep[f"{name}_{u}"]]
        if unc:
            row.append(unc.get(f"U_{name}_um"))
        rows.append(row)
    cols = ["figure", "clause", "meaning", f"value / {sym}"] + (["U (k=2) / µm"] if unc else [])
    tkey = "target_mm" if "target_mm" in rep["per_target"][0] else "target_deg"
    per = Table([f"P_i / {tkey[-2:] if tkey.endswith('mm') else 'deg'}", "n↑", "n↓", f"x̄↑ / {sym}",
                 f"x̄↓ / {sym}", f"x̄ / {sym}", f"B_i / {sym}", f"s↑ / {sym}", f"s↓ / {sym}", f"R_i / {sym}"],
                [[p[tkey], p["n_up"], p["n_down"], p[f"mean_up_{u}"], p[f"mean_down_{u}"], p[f"mean_{u}"],
                  p[f"B_{u}"], p[f"s_up_{u}"], p[f"s_down_{u}"], p[f"R_{u}"]] for p in rep["per_target"]])
    k = 1e3 if log.unit == "mm" else 3600.0
    ok = log.ok
    readings = {"target": log.target[ok], "deviation": log.deviation[ok] * k, "direction": log.direction[ok]}
    figure = positioning_figure(rep, readings=readings)
    if progress is not None:
        progress(REPORT_SHARES[1], 100)
    sections = [
        Section("Figures", text=test_text, tables=[Table(cols, rows)]),
        Section("The standard's plot", text="Mean positional deviations per direction with their x̄ ± 2s "
                "bands (the edges that make A), the bidirectional mean, every reading, and the reversal "
                "value B_i at each target.", figures={"iso230_2": figure}),
        Section("Per target", tables=[per]),
    ]
    if budget is not None:
        sections.append(Section(
            "Uncertainty of the test",
            text=(f"ISO/TR 230-9 style budget over the measurement travel L = {budget.travel_mm:g} mm: "
                  "scale-like contributions (instrument, cosine misalignment, temperature, expansion "
                  "coefficient) act on the range figures E, M, A and cancel at one target; the "
                  "environmental variation acts on all. Standard uncertainties (k = 1) below, "
                  "expanded (k = 2) in the figures table. "
                  + "".join(w[:1].upper() + w[1:] for w in [(budget.temperature or {}).get("what", "")])
                  + (f" (uncorrected, the expansion over the travel would be "
                     f"{budget.temperature['expansion_if_uncorrected_um']:+.3f} µm)."
                     if budget.temperature else "")
                  + (f" The readings' printed step (rounding, u = step / sqrt 12 a reading) is a contribution of "
                     f"its own, by figure: E, M, B {budget.step_u['E']:.4g}, A {budget.step_u['A']:.4g}, "
                     f"R {budget.step_u['R']:.4g} µm (JSON printed_step)." if budget.step_u else "")),
            tables=[Table(["source", "u on E, M, A / µm", "u on B, R / µm"],
                          [[s, a, b] for s, (a, b) in budget.contributions.items()])]))
    b = rep["baseline"]
    sections.append(Section(
        "Baseline for model discovery",
        text=(f"The standard's own model (one systematic deviation per target and direction, "
              f"{b['n_params']} parameters, {b['dof']} degrees of freedom) leaves a residual RMS of "
              f"{b[f'rms_{u}']:.3g} {sym}; pooled s {b[f's_up_pooled_{u}']:.3g} {sym} (+), "
              f"{b[f's_down_pooled_{u}']:.3g} {sym} (-). Drift across cycles, warm-up, outliers, "
              "pitch errors between targets stay in these residuals.")))
    return write_report(folder, title, sections)


def _error_fn_with(errors: dict, sym: str, extra):
    """``errors`` with ``extra`` added to ``sym`` (a new dict)."""
    out = dict(errors)
    out[sym] = extra if sym not in out else out[sym] + extra
    return out


def simulate_test(machine_name: str, axis: str, rng: np.random.Generator, *, errors: str | None = None,
                  noise_um: float = 0.5, n_targets: int = 11, travel_mm=None, cycles: int = 5,
                  cycle_kind: str = "linear", overrun_mm: float = 5.0, feed_mm_min: float = 2000.0,
                  dwell_s: float = 2.0, line_mm=None, reversal_um: float = 0.0,
                  reversal_sense: str = "lead",
                  drift_um_per_h: float = 0.0, drift_tau_s: float | None = None):
    """An ISO 230-2 test of ``axis`` on a named virtual machine: a positioning log.

    ``machine_name``: a built-in machine or a machine file
    (:mod:`sim.machinefile`, whose errors are its own). ``errors`` for a
    built-in: an error set of :func:`sim.machinefile.truth_machine`
    (``realistic``, the default, ``study``, ``drawn`` or ``none``). ``reversal_um`` adds lost motion
    (``Reversal``: +L/2 moving in +, -L/2 in -, a lead, ISO 230-2's ``B_i = +L``; with ``reversal_sense="lag"``
    -L/2 moving in +, +L/2 in -, backlash stopping short, ``B_i = -L``) and ``drift_um_per_h`` an
    offset drift (``Drift``, linear, or approaching its steady state with
    time constant ``drift_tau_s``) to the axis's positioning error
    (``EXX`` for X, ...). Error values are ISO 230-1's (the tool relative
    to the workpiece), so the readings see them with their sign on a
    table-side axis as on a tool-side one. The log's metadata says what the
    options added: ``added_reversal_um``, ``added_drift_um_per_h`` (and
    ``added_reversal_sense``, ``added_drift_tau_s`` when given), on top of
    the machine's own errors (``errors``).
    """
    from core.exceptions import ConfigError
    from sim.errorfuncs import Drift, Reversal
    from dataclasses import replace

    from sim.machine import Machine
    from sim.machinefile import errors_label, truth_machine
    from sim.positioning import positioning_plan, simulate_positioning

    spec = truth_machine(machine_name, errors)  # the one machine rule of every command
    if axis not in ("X", "Y", "Z"):
        raise ConfigError(f"--axis {axis!r}: expected X, Y or Z")
    cfg = spec.config
    errs = dict(cfg.errors)
    errors = errors_label(machine_name, spec)
    for name, v in (("--scatter-um", noise_um), ("--reversal-um", reversal_um), ("--overrun-mm", overrun_mm),
                    ("--dwell-s", dwell_s)):
        if not (np.isfinite(v) and v >= 0):
            raise ConfigError(f"{name} must be >= 0, got {v!r}")
    if not np.isfinite(drift_um_per_h):
        raise ConfigError(f"--drift-um-per-h must be finite, got {drift_um_per_h!r}")
    if not (np.isfinite(feed_mm_min) and feed_mm_min > 0):
        raise ConfigError(f"--move-feed-mm-min must be > 0, got {feed_mm_min!r}")
    if reversal_sense not in ("lead", "lag"):
        raise ConfigError(f"--reversal-sense {reversal_sense!r}: expected lead or lag")
    if reversal_sense != "lead" and not reversal_um:  # (as the machine file: a sense names a lost motion's sign)
        raise ConfigError(f"--reversal-sense {reversal_sense} needs --reversal-um > 0 (the lost motion it signs)")
    if travel_mm is None:          # the default travel: the stroke less the overrun at each end
        lo, hi = cfg.strokes[axis]
        ov = overrun_mm * 1e-3
        if not lo + ov < hi - ov:      # (the simulator said 'measurement travel must be ... got 0.1, -0.1', m)
            raise ConfigError(f"--overrun-mm {overrun_mm:g}: axis {axis}'s stroke {lo * 1e3:g}..{hi * 1e3:g} mm "
                              f"less {overrun_mm:g} mm at each end leaves no travel to test (the default "
                              "--travel-mm); give a smaller --overrun-mm")
    sym = f"E{axis}{axis}"
    if reversal_um:
        errs = _error_fn_with(errs, sym, Reversal(reversal_um * 1e-6, reversal_sense))
    if drift_um_per_h:
        errs = _error_fn_with(errs, sym, Drift(offset_rate=drift_um_per_h * 1e-6 / 3600.0, tau_s=drift_tau_s))
    machine = Machine(replace(cfg, errors=errs))
    plan = positioning_plan(
        machine, axis, n_targets=n_targets, cycles=cycles, cycle_kind=cycle_kind,
        travel_m=None if travel_mm is None else (travel_mm[0] * 1e-3, travel_mm[1] * 1e-3),
        overrun_m=overrun_mm * 1e-3, feed_mps=feed_mm_min * 1e-3 / 60.0, dwell_s=dwell_s,
        line_m=None if line_mm is None else np.asarray(line_mm, float) * 1e-3, rng=rng)
    # what the options ADD to the machine's own errors (named so: '# reversal_um: 0' read as the machine's reversal
    # on a machine file whose EXX has reversal_um = 2, review31 F2); the machine's own are in 'errors'
    meta = {"errors": errors, "added_reversal_um": f"{reversal_um:g}", "added_drift_um_per_h": f"{drift_um_per_h:g}"}
    if reversal_sense != "lead":  # a lead's log as before the sense existed
        meta["added_reversal_sense"] = reversal_sense
    if drift_tau_s:
        meta["added_drift_tau_s"] = f"{drift_tau_s:g}"
    return simulate_positioning(machine, plan, rng, noise_m=noise_um * 1e-6, meta=meta)
