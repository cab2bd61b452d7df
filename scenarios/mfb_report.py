"""The MFB scenario's report folder: the paper's figures, the table of the 21 errors, a recording.

viz draws (:mod:`viz.mfb_figures`, :mod:`viz.record`, :mod:`viz.report`);
this module only picks what to draw from a finished run's JSON document
(:attr:`scenarios.mfb.ScenarioResult.doc`) and from the bar calibration the
run used.
"""

from __future__ import annotations

import inspect
import shutil
from pathlib import Path

import numpy as np

from core import iso
from core.units import MM, UM


def bar_calibration(u_cal_um=None) -> dict:
    """The bar calibration every MFB run identifies with, in report units (Figs. 9-10).

    ``{x_mm, E_um, U95_um}``: the nominal x of the 12 points of interest
    (mm), their calibrated Exx, Eyx, Ezx (:func:`sim.artefacts.mfb_default_deviations`,
    eq. 4, µm) and the expanded uncertainty 2 ``u_cal_um`` (k = 2, µm);
    ``u_cal_um`` defaults to the one :func:`scenarios.mfb.run` uses.
    """
    from sim import artefacts as A

    from scenarios.mfb import run

    if u_cal_um is None:
        u_cal_um = inspect.signature(run).parameters["u_cal_um"].default
    E = A.mfb_default_deviations()
    x = np.arange(len(E)) * A.MFB_PITCH_M
    return {"x_mm": x / MM, "E_um": E / UM, "U95_um": np.tile(2.0 * np.asarray(u_cal_um, float), (len(E), 1))}


def error_rows(errors: dict) -> list:
    """One row per error, in ISO order: symbol, unit, max |injected|, max |identified - injected|, max U95."""
    rows = []
    for s in (*iso.LINEAR_MOTION, *iso.SQUARENESS):
        e = errors[s]
        u = e.get("u95")
        rows.append([s, e["unit"], float(np.max(np.abs(e["injected"]))), float(e["max_dev"]),
                     None if u is None else float(np.max(u))])
    return rows


def budget_table(budget: dict) -> tuple[list, list]:
    """(header, rows) of the budget's contributions: one row per error, one column per
    source (max over the nodes of its U95 share, k = 2), then the sum in quadrature,
    the Monte Carlo U95 through the pipeline and their ratio."""
    srcs = list(budget["sources"])
    head = ["error", "unit", *srcs, "temperature, bar and machine at one T", "quadrature sum",
            "MC (all sources)", "MC / sum"]
    rows = []
    for s, c in budget["per_error"].items():
        rows.append([s, c["unit"], *[c["U95"].get(k) for k in srcs], c.get("temperature_one_T"),
                     c.get("quadrature"), c.get("mc"),
                     c.get("mc_over_quadrature")])
    return head, rows


#: Percent of :func:`mfb_report`'s work done when its figures are drawn and when its recording is written; the
#: page and its PNGs are the rest. Measured on ``vmt scenario mfb-3axis --report`` (session 38: the line ended
#: with the identification, and 4.7 s of CPU, 15 s at load 14, followed uncounted): CPU, imports and figures 2.1 s
#: (the error curves 0.8), the recording 0.3 s, the page 2.3 s; wall at load 14, 3, 2 and 11 s.
REPORT_SHARES = (30, 40)


def mfb_report(folder, doc: dict, progress=None) -> Path:
    """Write ``folder``: index.html, the MFB figures (PNG) and ``recording.rrd``; returns the folder.

    Complete or absent: the recording and the page are built beside
    ``folder`` and renamed into place (:func:`viz.report.write_report`).

    Parameters
    ----------
    doc : dict
        The scenario's result document (``errors``: ``{symbol: {nodes_mm,
        identified, injected, u95, unit, max_dev}}`` for all 21 errors).
    """
    if progress is not None:
        progress(0, 100)
    from scenarios.reports import _recording_path
    from viz import mfb_figures as F, record
    from viz.report import Section, Table, write_report

    folder = Path(folder)
    errors = doc["errors"]
    rows = error_rows(errors)
    b = doc.get("bar")
    if b is not None:  # the calibration the run used, and the simulated bar's truth (one gauge)
        bar = {"x_mm": np.asarray(b["x_mm"], float), "E_um": np.asarray(b["calibrated_um"], float),
               "U95_um": np.asarray(b["U95_um"], float), "truth_um": np.asarray(b["true_um"], float)}
        bar_text = (f"The bar's calibration the identification used ({b['source']}) ± its U95, beside the "
                    f"simulated bar's true deviations (max difference {b['calibrated_minus_true_max_um']:.3f} µm); "
                    f"both in one gauge: {b['gauge']}.")
    else:  # a document written before the bar block
        bar = bar_calibration()
        bar_text = ("The calibrated deviations of the bar's points of interest the identification used, "
                    "± U95 (k = 2) of the calibration.")
    axes, truth = F.motion_axes(errors)
    secs = [
        Section("Run", text=f"{doc['scenario']}: {doc['placements']} placements, {doc['measurements']} "
                f"measurements, {doc['touches']} touches on {doc['machine']}, seed {doc['seed']}, probing "
                f"noise {doc['noise_um']:g} µm (k = 1); {doc['model']}. Straightnesses against their end-point "
                "line; the injected values are the truth at the nodes in the same ISO 230-1 conventions."
                + ("" if rows[0][4] is not None else " No uncertainty was propagated (no U95 bars).")),
        Section("Error motions (Figs. 15-17)", figures={"error-curves": F.error_curves_figure(errors)}),
        Section("Squarenesses", figures={"squareness": F.squareness_figure(errors)}),
        Section("Bar calibration (Figs. 9-10)",
                text=bar_text,
                figures={"bar-calibration": F.bar_calibration_figure(bar["x_mm"], bar["E_um"], bar["U95_um"],
                                                                     truth_um=bar.get("truth_um"))}),
        Section("The 21 errors", tables=[Table(
            ["error", "unit", "max |injected|", "max |identified - injected|", "max U95 (k=2)"], rows)]),
    ]
    if doc.get("budget"):
        bt = budget_table(doc["budget"])
        secs.append(Section("Uncertainty budget: contributions per error", text=doc["budget"]["method"],
                            tables=[Table(bt[0], bt[1])]))
    if progress is not None:
        progress(REPORT_SHARES[0], 100)
    rrd = _recording_path(folder)
    try:
        with record.recording(rrd) as rec:
            record.log_error_motions(rec, axes, truth=truth)
            F.log_squareness(rec, errors)
            F.log_bar_calibration(rec, bar["x_mm"], bar["E_um"], bar["U95_um"], truth_um=bar.get("truth_um"))
            record.log_markdown(rec, doc["scenario"], record.errors_markdown(
                {s: {k: errors[s].get(k) for k in ("injected", "identified", "u95")} for s in errors}))
        if progress is not None:
            progress(REPORT_SHARES[1], 100)
        out = write_report(folder, f"MFB ({doc['scenario']}): 21 errors identified, injected, U95", secs,
                           recording=rrd)
        if progress is not None:
            progress(100, 100)
        return out
    finally:
        shutil.rmtree(rrd.parent, ignore_errors=True)
