"""Report folders for the scenarios: figures and recordings from results.

viz draws; this module only picks what to draw from results that already
exist (discover, identify) and passes plain arrays.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def discovery_report(folder, d, t, rep: dict, title: str) -> Path:
    """Write ``folder`` with index.html, residual plots and a rerun recording.

    Parameters
    ----------
    d : core.discover.Discovery
    t : core.touches.Touches
        The touches ``d`` was computed from (times, approach directions).
    rep : dict
        ``d.to_report()`` as written to JSON.
    """
    from viz import figures, record
    from viz.report import Section, Table, write_report

    folder = Path(folder)
    approach_deg = np.degrees(np.arctan2(t.d_R[:, 1], t.d_R[:, 0]))
    out_idx = [int(np.flatnonzero(t.row == r)[0]) for r in rep["outlier_rows"]]
    rrd = folder.parent / f".{folder.name}.rrd"
    with record.recording(rrd) as rec:
        record.log_touches(rec, t.pn_R, d.residuals_baseline_um, n_R=t.n_R)
        record.log_residuals(rec, t.t_s, approach_deg, d.residuals_baseline_um, outlier_rows=out_idx,
                             path=record.RESIDUALS + "/baseline")
        res_e = np.where(np.isfinite(d.residuals_extended_um), d.residuals_extended_um, 0.0)
        record.log_residuals(rec, t.t_s, approach_deg, res_e, path=record.RESIDUALS + "/extended")
        record.log_markdown(rec, "discovery", record.findings_markdown(rep))
    secs = [
        Section("Verdict", text=_verdict(rep),
                figures={"findings": figures.findings_figure(rep)},
                tables=[Table(["model", "RMS / µm", "cross-validated RMS / µm"],
                              [[rep["baseline"]["model"], rep["baseline"]["rms_um"], rep["baseline_cv_rms_um"]],
                               [rep["extended"]["model"], rep["extended"]["rms_um"], rep["extended"]["cv_rms_um"]]])]),
        Section("Baseline residuals: what the model gets wrong",
                text="Residuals of the 2D self-calibration against time and approach direction "
                     "(machine frame). Structure here is what the findings explain.",
                figures={"residuals_baseline": figures.residuals_figure(
                    t.t_s, approach_deg, d.residuals_baseline_um, outlier_rows=out_idx)}),
    ]
    fin = np.isfinite(d.residuals_extended_um)
    secs.append(Section("Extended model residuals",
                        figures={"residuals_extended": figures.residuals_figure(
                            t.t_s[fin], approach_deg[fin], d.residuals_extended_um[fin])}))
    rows = []
    for f in rep["findings"]:
        for k, v in f["params"].items():
            rows.append([f["cause"], k, v])
    if rows:
        secs.append(Section("Fitted magnitudes", tables=[Table(["cause", "parameter", "value"], rows)]))
    secs.append(Section("Workpiece per target", tables=[Table(
        ["target", "baseline / µm", "extended / µm"],
        [[w["target"], w["baseline_um"], w["extended_um"]] for w in rep["workpiece"]])]))
    try:
        return write_report(folder, title, secs, recording=rrd)
    finally:
        if rrd.exists():
            rrd.unlink()


def _verdict(rep: dict) -> str:
    if rep["cause"] == "none":
        return ("No candidate cause beats the baseline out of sample and the residuals show no "
                "structure: the baseline explains the data within the probing noise.")
    names = ", ".join(f["cause"] for f in rep["findings"])
    g = rep["gain"]
    return (f"Cause: {rep['cause']} (findings: {names}). The extended model cuts the residual RMS by "
            f"a factor {1 / max(g['rms_ratio'], 1e-9):.2f} and the cross-validated RMS by "
            f"{1 / max(g['cv_rms_ratio'], 1e-9):.2f}.")
