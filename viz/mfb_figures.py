"""The MFB paper's figures from a scenario's result (Viprey et al. 2016).

================================  ===========================================
function                          paper figure
================================  ===========================================
:func:`error_curves_figure`       Figs. 15-17 for all 18 error motions: the
                                  identified values at the nodes with U95
                                  bars (k = 2), the injected ones beside
:func:`squareness_figure`         the three squarenesses, identified ± U95
                                  beside injected
:func:`bar_calibration_figure`    Figs. 9-10: the bar's calibrated Exx, Eyx,
                                  Ezx at its points of interest, ± U95
================================  ===========================================

Inputs are the plain dicts of the scenario JSON (``errors``:
``{symbol: {nodes_mm, identified, injected, u95, unit}}``) or arrays in
report units (mm, µm, µrad). Nothing is computed here but the drawing.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from core import iso
from core.exceptions import ConfigError

from . import figures


def motion_axes(errors: Mapping) -> tuple[dict, dict]:
    """The 18 motions of ``errors`` as ``(axes, truth)``: ``axes`` ``{symbol: {positions_mm,
    values_um | values_urad[, u95]}}`` (what :func:`viz.figures.error_motions_figure` and
    :func:`viz.record.log_error_motions` take), ``truth`` ``{symbol: injected}``, same units."""
    axes, truth = {}, {}
    for s in iso.LINEAR_MOTION:
        if s not in errors:
            raise ConfigError(f"errors: {s} missing (the 21-error result is needed)")
        e = errors[s]
        key = "values_urad" if iso.symbol(s).angular else "values_um"
        axes[s] = {"positions_mm": e["nodes_mm"], key: e["identified"]}
        if e.get("u95") is not None:
            axes[s]["u95"] = e["u95"]
        if e.get("injected") is not None:
            truth[s] = e["injected"]
    return axes, truth


def error_curves_figure(errors: Mapping, title: str = "MFB: 18 error motions, identified ± U95 (k=2) and injected"):
    """The 18 motion errors against their axis (6 rows x 3: X, Y, Z per column)."""
    axes, truth = motion_axes(errors)
    order = [f"E{k}{a}" for a in "XYZ" for k in "XYZABC"]
    # columns X, Y, Z: the error of each axis in one column
    grid = [order[i + 6 * c] for i in range(6) for c in range(3)]
    return figures.error_motions_figure(axes, truth=truth or None, symbols=grid, ncols=3, title=title)


def squareness_figure(errors: Mapping, title: str = "MFB: squarenesses, identified ± U95 (k=2) and injected"):
    """EC0Y, EB0Z, EA0Z (µrad) identified ± U95 beside injected."""
    sq = {}
    for s in iso.SQUARENESS:
        if s not in errors:
            raise ConfigError(f"errors: {s} missing")
        e = errors[s]
        sq[s] = {"identified": e["identified"][0], "injected": (e.get("injected") or [None])[0],
                 "u95": (e.get("u95") or [None])[0]}
    return figures.errors_figure(sq, title=title)


def bar_calibration_figure(x_mm, E_um, U95_um=None, *, truth_um=None,
                           title: str = "MFB calibration (Figs. 9-10): Exx, Eyx, Ezx of the points of interest"):
    """The bar's calibrated deviations at its points of interest.

    Parameters
    ----------
    x_mm : (n,) float
        Nominal x of each point of interest O_i in R_MFB, mm.
    E_um : (n, 3) float
        Calibrated Exx, Eyx, Ezx (eq. 4), µm.
    U95_um : (n, 3) float, optional
        Their expanded uncertainty (k = 2), µm.
    truth_um : (n, 3) float, optional
        The simulated bar's true deviations, µm.
    """
    x = np.asarray(x_mm, float).ravel()
    E = np.asarray(E_um, float)
    if E.shape != (len(x), 3) or not np.all(np.isfinite(E)):
        raise ConfigError(f"E_um must be a finite ({len(x)}, 3) array, got shape {E.shape}")
    fig = figures._figure(11.0, 3.2)
    axs = fig.subplots(1, 3)
    for j, (ax, name) in enumerate(zip(axs, ("Exx", "Eyx", "Ezx"))):
        u = None if U95_um is None else np.asarray(U95_um, float)[:, j]
        ax.errorbar(x, E[:, j], yerr=u, fmt="o-", ms=3, capsize=2, color=figures._C_MEAS, label="calibrated ± U95")
        if truth_um is not None:
            ax.plot(x, np.asarray(truth_um, float)[:, j], "--", color=figures._C_TRUE, label="true (simulated bar)")
        ax.axhline(0.0, color=figures._C_NOMINAL, lw=0.8)
        ax.set_xlabel("x_MFB / mm")
        ax.set_ylabel(f"{name}_MFB / µm")
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize="x-small")
    fig.suptitle(title)
    return fig


def log_squareness(rec, errors: Mapping, *, path: str = "mfb/squareness") -> None:
    """Log the three squarenesses as points (identified, injected, ±U95) on a sequence
    timeline ``squareness`` (0 EC0Y, 1 EB0Z, 2 EA0Z), µrad: the squareness figure as a plot."""
    from .record import _BLUE, _GREY, _ORANGE, _series

    idx = np.arange(len(iso.SQUARENESS), dtype=np.int64)
    vals = {k: [] for k in ("identified", "injected", "u95")}
    for s in iso.SQUARENESS:
        e = errors[s]
        for k in vals:
            v = e.get(k)
            vals[k].append(np.nan if v is None else float(np.asarray(v, float).ravel()[0]))
    ident, inj, u = (np.asarray(vals[k]) for k in ("identified", "injected", "u95"))
    _series(rec, f"{path}/identified", "squareness", idx, ident, "identified / µrad", _BLUE, points=True)
    if np.all(np.isfinite(inj)):
        _series(rec, f"{path}/injected", "squareness", idx, inj, "injected / µrad", _ORANGE, points=True)
    if np.all(np.isfinite(u)):
        _series(rec, f"{path}/u95_upper", "squareness", idx, ident + u, "+U95 (k=2)", _GREY, points=True)
        _series(rec, f"{path}/u95_lower", "squareness", idx, ident - u, "-U95 (k=2)", _GREY, points=True)


def log_bar_calibration(rec, x_mm, E_um, U95_um=None, *, truth_um=None, path: str = "mfb/bar_calibration") -> None:
    """Log the bar's calibrated Exx, Eyx, Ezx (µm) at its points of interest with ±U95 and,
    for a simulated bar, its true deviations, on the sequence timeline ``x_MFB_um``
    (nominal x in integer µm): Figs. 9-10 as plots (``<path>/<Exx|Eyx|Ezx>/...``)."""
    from .record import _BLUE, _GREY, _ORANGE, _series

    x = np.asarray(x_mm, float).ravel()
    E = np.asarray(E_um, float)
    if E.shape != (len(x), 3) or not np.all(np.isfinite(E)):
        raise ConfigError(f"E_um must be a finite ({len(x)}, 3) array, got shape {E.shape}")
    ticks = np.round(x * 1000.0).astype(np.int64)
    for j, name in enumerate(("Exx", "Eyx", "Ezx")):
        base = f"{path}/{name}"
        _series(rec, f"{base}/calibrated", "x_MFB_um", ticks, E[:, j], f"{name} calibrated / µm", _BLUE)
        if U95_um is not None:
            u = np.asarray(U95_um, float)[:, j]
            _series(rec, f"{base}/u95_upper", "x_MFB_um", ticks, E[:, j] + u, "+U95 (k=2)", _GREY)
            _series(rec, f"{base}/u95_lower", "x_MFB_um", ticks, E[:, j] - u, "-U95 (k=2)", _GREY)
        if truth_um is not None:
            _series(rec, f"{base}/true", "x_MFB_um", ticks, np.asarray(truth_um, float)[:, j],
                    f"{name} true / µm", _ORANGE)


def write_mfb_figures(doc: Mapping, directory, *, bar: Mapping | None = None) -> list:
    """Write the MFB figures of a scenario result (its JSON dict) as PNG; returns the paths.

    ``bar``: ``{x_mm, E_um, U95_um[, truth_um]}`` of the bar's calibration
    (default: none drawn).
    """
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    name = doc.get("scenario", "mfb")
    out = [figures.save_png(error_curves_figure(doc["errors"]), d / f"{name}-error-curves.png"),
           figures.save_png(squareness_figure(doc["errors"]), d / f"{name}-squareness.png")]
    if bar is not None:
        out.append(figures.save_png(bar_calibration_figure(bar["x_mm"], bar["E_um"], bar.get("U95_um"),
                                                           truth_um=bar.get("truth_um")),
                                    d / f"{name}-bar-calibration.png"))
    return out
