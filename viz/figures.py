"""Static report figures (matplotlib, Agg): the figures the papers print.

Every function takes plain numpy arrays (or the plain dicts of the results'
JSON) and returns a :class:`matplotlib.figure.Figure` that is not attached to
pyplot (no global state, no display); :func:`save_png` writes it. Every axis
is labelled with its quantity's ISO symbol and unit, ``"EXX(X) / µm"``,
``"X / mm"``.

Units are those of the reports: positions in mm, angles in degrees, errors
and deviations in µm / µrad, times in s; the name of each argument says so.
viz computes nothing: errors, uncertainties, centres and residuals are drawn
as given. The only arithmetic is drawing arithmetic (magnification of
deviations along their normals, as the self-calibration paper's figures do).

================================  ===========================================
function                          paper figure
================================  ===========================================
:func:`profile_figure`            self-calibration Fig. 9 (profiles x2500)
:func:`error_grid_figure`         self-calibration Fig. 12 (error map x1000)
:func:`grid_uncertainty_figure`   self-calibration Fig. 20 (U95 of the map)
:func:`error_motions_figure`      MFB Figs. 15-17 (error motions, U95 bars)
:func:`errors_figure`             MFB scenario: injected vs identified ± U95
:func:`rotary_centre_figure`      self-calibration Fig. 13 (C-axis centre)
:func:`rotary_motions_figure`     self-calibration Fig. 14 (ECC(C) ...)
:func:`workpiece_uncertainty_figure`  self-calibration Figs. 18-19 (U95 colour)
:func:`residuals_figure`          discovery: residuals vs time and approach
:func:`findings_figure`           discovery: RMS of baseline and candidates
:func:`diagnosis_figure`          discovery: residuals against each covariate
                                  that carries structure, with its smooth term
:func:`positioning_residuals_figure`  discovery on an ISO 230-2 test: residuals
                                  vs time and target, by approach direction
================================  ===========================================
"""

from __future__ import annotations

import os
import tempfile
import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from core.exceptions import ConfigError
from viz.checks import check_array, check_directions, outlier_mask, same_len
from core.iso import symbol as iso_symbol

PROFILE_MAGNIFICATION = 2500.0  # self-calibration paper, Fig. 9(a), (c)
GRID_MAGNIFICATION = 1000.0  # self-calibration paper, Fig. 12

_C_NOMINAL = "0.6"
_C_MEAS = "tab:blue"
_C_TRUE = "tab:orange"
_C_BAD = "tab:red"
_CYCLE = ("tab:blue", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:olive")


# --- helpers ---------------------------------------------------------------
_arr = check_array
_same_len = same_len


def _figure(width_in: float, height_in: float):
    """A Figure with its own Agg canvas: no pyplot, no display, no global state."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _unit(sym) -> str:
    return "µrad" if sym.angular else "µm"


def iso_label(name: str) -> str:
    """Axis label of an ISO error symbol with its argument and report unit.

    ``"EXX"`` -> ``"EXX(X) / µm"``, ``"ECY"`` -> ``"ECY(Y) / µrad"``,
    ``"EC0Y"`` -> ``"EC0Y / µrad"`` (a location error has no argument).
    """
    s = iso_symbol(name)
    arg = "" if s.location else f"({s.axis})"
    return f"{s.name}{arg} / {_unit(s)}"


def _axis_label(axis: str) -> str:
    return f"{axis} / °" if axis in ("A", "B", "C") else f"{axis} / mm"


def _scale_bar(ax, length_mm: float, text: str) -> None:
    """Error scale bar in the lower-left corner (data units of the plot, mm)."""
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar as Bar

    ax.add_artist(Bar(ax.transData, length_mm, text, "lower left", pad=0.5,
                      frameon=True, size_vertical=0))


def write_png(fig, target, *, dpi: int = 110) -> None:
    """``fig.savefig(target, dpi=dpi, format="png")``, drawn once instead of twice.

    With a layout engine (our figures are ``constrained``) matplotlib's
    savefig draws a figure twice: an invisible draw that lays it out, then
    the draw that paints (every tick label and text measured again). On its
    own Agg canvas (:func:`_figure`) the figure is drawn once at ``dpi``
    (layout and paint in one draw) and the canvas written as savefig writes
    it (``matplotlib.image.imsave``, same metadata): the same PNG, byte for
    byte. ``target``: a path or a binary file object. The figure keeps its
    dpi; any other figure goes through savefig. Written as drawn: the
    ``savefig.*`` rcParams (facecolor, transparent, bbox) are not consulted
    and animated artists are not drawn (viz sets none of them).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.image import imsave

    if type(fig.canvas) is not FigureCanvasAgg or fig.get_layout_engine() is None:
        fig.savefig(target, dpi=dpi, format="png")
        return
    old_dpi = fig.dpi
    try:
        fig.set_dpi(dpi)
        fig.canvas.draw()
        imsave(target, fig.canvas.buffer_rgba(), format="png", origin="upper", dpi=fig.dpi)
    finally:
        fig.set_dpi(old_dpi)


def save_png(fig, path, *, dpi: int = 110) -> Path:
    """Write ``fig`` as a PNG at ``path``, complete or not at all (temp + rename)."""
    path = Path(path)
    if not path.parent.is_dir():
        raise ConfigError(f"figure path {str(path)!r}: folder does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        write_png(fig, tmp, dpi=dpi)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path


# --- self-calibration figures ------------------------------------------------
def profile_figure(points_mm, normals, profiles: Mapping[str, object], *,
                   reference_um=None, reference_label: str = "reference (CMM)",
                   magnification: float = PROFILE_MAGNIFICATION, scale_um: float = 20.0,
                   title: str = "Workpiece profile"):
    """Profiles drawn as deviations along the surface normal, magnified (Fig. 9).

    Parameters
    ----------
    points_mm : (n, 2) float
        Nominal points ``w p_i*`` in the workpiece frame W (x, y), mm.
    normals : (n, 2) float
        Unit normals at the points, in W.
    profiles : dict
        ``{label: dq_um}``: one (n,) array of normal deviations per profile
        (e.g. ``"C = 0°"``, or ``"identified G_normal"``), µm.
    reference_um : (n,) float, optional
        A reference profile (CMM, or the injected truth), µm.
    magnification : float
        Drawing magnification (2500 as in Fig. 9(a)).
    scale_um : float
        Length of the error scale bar, µm.
    """
    p = _arr("points_mm", points_mm, (-1, 2))
    n = _arr("normals", normals, (-1, 2))
    _same_len(points_mm=p, normals=n)
    if magnification <= 0:
        raise ConfigError(f"magnification must be > 0, got {magnification}")
    if not profiles and reference_um is None:
        raise ConfigError("profiles: give at least one profile")
    k = magnification * 1e-3  # µm -> mm, magnified
    fig = _figure(6.4, 5.4)
    ax = fig.add_subplot()
    ax.plot(p[:, 0], p[:, 1], "o", ms=3, mfc="none", color=_C_NOMINAL, label="nominal")
    for i, (label, dq) in enumerate(profiles.items()):
        d = _arr(f"profiles[{label!r}]", dq, (-1,))
        _same_len(points_mm=p, **{"profile": d})
        q = p + k * d[:, None] * n
        ax.plot(q[:, 0], q[:, 1], "o-", ms=3, lw=0.8, color=_CYCLE[i % len(_CYCLE)], label=label)
    if reference_um is not None:
        d = _arr("reference_um", reference_um, (-1,))
        _same_len(points_mm=p, reference_um=d)
        q = p + k * d[:, None] * n
        ax.plot(q[:, 0], q[:, 1], "D", ms=3, color="tab:green", label=reference_label)
    _scale_bar(ax, k * scale_um, f"error scale: {scale_um:g} µm")
    ax.set_xlabel("x_W / mm")
    ax.set_ylabel("y_W / mm")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{title}: normal deviation dq / µm, magnified ×{magnification:g}")
    ax.legend(fontsize="small", loc="upper right")
    ax.grid(alpha=0.3)
    return fig


def _draw_grid(ax, X, Y, **kw) -> None:
    for i in range(X.shape[0]):
        ax.plot(X[i], Y[i], **kw)
        kw.pop("label", None)
    for j in range(X.shape[1]):
        ax.plot(X[:, j], Y[:, j], **kw)


def error_grid_figure(x_mm, y_mm, ex_um, ey_um, *, true_ex_um=None, true_ey_um=None,
                      magnification: float = GRID_MAGNIFICATION, scale_um: float = 10.0,
                      title: str = "2D positioning error map"):
    """The error map drawn deformed and magnified beside the true one (Fig. 12).

    Parameters
    ----------
    x_mm : (nx,) float, y_mm : (ny,) float
        Grid positions in the machine frame R, mm.
    ex_um, ey_um : (ny, nx) float
        ``Ex,total``, ``Ey,total`` at each node (self-calibration eqs. 4-5,
        from core), µm.
    true_ex_um, true_ey_um : (ny, nx) float, optional
        The true (injected or independently measured) errors.
    """
    x = _arr("x_mm", x_mm, (-1,))
    y = _arr("y_mm", y_mm, (-1,))
    shape = (len(y), len(x))
    ex = _arr("ex_um", ex_um, shape)
    ey = _arr("ey_um", ey_um, shape)
    if (true_ex_um is None) != (true_ey_um is None):
        raise ConfigError("true_ex_um and true_ey_um: give both or neither")
    if magnification <= 0:
        raise ConfigError(f"magnification must be > 0, got {magnification}")
    k = magnification * 1e-3
    X, Y = np.meshgrid(x, y)
    fig = _figure(6.4, 5.4)
    ax = fig.add_subplot()
    _draw_grid(ax, X, Y, color=_C_NOMINAL, ls="--", lw=0.8, label="nominal")
    if true_ex_um is not None:
        tx = _arr("true_ex_um", true_ex_um, shape)
        ty = _arr("true_ey_um", true_ey_um, shape)
        _draw_grid(ax, X + k * tx, Y + k * ty, color=_C_TRUE, lw=3.0, alpha=0.6,
                   label="true")
    _draw_grid(ax, X + k * ex, Y + k * ey, color=_C_MEAS, lw=1.2, marker="o", ms=3,
               label="identified")
    _scale_bar(ax, k * scale_um, f"error scale: {scale_um:g} µm")
    ax.set_xlabel("X / mm")
    ax.set_ylabel("Y / mm")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{title} (Ex,total, Ey,total / µm), magnified ×{magnification:g}")
    ax.legend(fontsize="small", loc="upper right")
    return fig


def grid_uncertainty_figure(x_mm, y_mm, u95_um, *,
                            title: str = "U95 (k=2) of the 2D positioning error"):
    """Expanded uncertainty of the error map as colour (Fig. 20).

    ``u95_um`` : (ny, nx) float, µm, at the nodes of ``x_mm`` (nx,), ``y_mm`` (ny,).
    """
    x = _arr("x_mm", x_mm, (-1,))
    y = _arr("y_mm", y_mm, (-1,))
    u = _arr("u95_um", u95_um, (len(y), len(x)))
    fig = _figure(6.4, 5.0)
    ax = fig.add_subplot()
    m = ax.pcolormesh(x, y, u, shading="nearest", cmap="viridis", vmin=0.0)
    fig.colorbar(m, ax=ax, label="U95 of (Ex,total, Ey,total) / µm")
    ax.set_xlabel("X / mm")
    ax.set_ylabel("Y / mm")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(title)
    return fig


def workpiece_uncertainty_figure(points_mm, u95_um, *, g_um=None, normals=None,
                                 magnification: float = PROFILE_MAGNIFICATION,
                                 title: str = "U95 (k=2) of the identified workpiece"):
    """Uncertainty of the identified workpiece deviation as colour (Figs. 18-19).

    Parameters
    ----------
    points_mm : (n, 2) float
        Nominal target points in W (x, y), mm.
    u95_um : (n,) float
        Expanded uncertainty (k = 2) of ``G_normal`` at each target, µm.
    g_um, normals : (n,) float, (n, 2) float, optional
        When both are given the points are drawn moved along their normals by
        ``magnification * g_um`` (the identified profile, as in Fig. 9(c)).
    """
    p = _arr("points_mm", points_mm, (-1, 2))
    u = _arr("u95_um", u95_um, (-1,))
    _same_len(points_mm=p, u95_um=u)
    q = p
    if (g_um is None) != (normals is None):
        raise ConfigError("g_um and normals: give both or neither")
    if g_um is not None:
        g = _arr("g_um", g_um, (-1,))
        n = _arr("normals", normals, (-1, 2))
        _same_len(points_mm=p, g_um=g, normals=n)
        q = p + magnification * 1e-3 * g[:, None] * n
    fig = _figure(6.4, 5.0)
    ax = fig.add_subplot()
    ax.plot(p[:, 0], p[:, 1], ".", ms=2, color=_C_NOMINAL, label="nominal")
    s = ax.scatter(q[:, 0], q[:, 1], c=u, cmap="viridis", vmin=0.0, s=22,
                   label="identified" if g_um is not None else "targets")
    fig.colorbar(s, ax=ax, label="U95 of G_normal / µm")
    ax.set_xlabel("x_W / mm")
    ax.set_ylabel("y_W / mm")
    ax.set_aspect("equal", adjustable="datalim")
    suffix = f", profile ×{magnification:g}" if g_um is not None else ""
    ax.set_title(title + suffix)
    return fig


def line_from_centre(centre_um) -> np.ndarray:
    """(2,) a table-side rotary axis's line ``(EX0C, EY0C)`` from its fitted trajectory's centre, µm.

    The trajectory is the tool relative to the part (ISO 230-1): a line at
    ``c`` moves it on ``(R(-C) - I) c``, a circle centred on ``-c``. The one
    place this sign is written (``+ 0.0``: no ``-0.0`` in labels and JSON).
    """
    return -np.asarray(centre_um, float) + 0.0


#: What a rotary carrier's errors add to the line of the axis it carries, in words, per carrier (the terms
#: :func:`core.selfcal.c_centre_note` writes out; the line is minus the centre): A's EY0A in Y and EB0A times the
#: height above A's line in X; B's EX0B in X and EA0B times the height in Y.
_CARRIER_WORDS = {"A": "EY0A, EB0A (z - z_A), ...", "B": "EX0B, EA0B (z - z_B), ..."}


def centre_label(cx: float, cy: float, axis: str = "C", chain=None) -> str:
    """Legend of a rotary axis's fitted centre ``(cx, cy)`` µm: the centre and the axis line it places.

    The trajectory is the tool relative to the part, so the line sits at minus
    the centre (:func:`line_from_centre`), in the identification's gauge
    (eqs 16-17): with the linear axes' error folded in, seen from the tool at
    the grid origin when the axis is on it (elsewhere the gauge's rotation
    and scale, fixed at the grid's last nodes, mix in too).

    What the line is depends on what carries the axis (``chain``: the log's
    ``kinematic_chain`` text or a parsed chain): on the bed it is the axis's
    own location ``(EX0C, EY0C)``; on an axis carried by A or B, whose
    location errors are relative to its carrier (CONTRIBUTING.md, "Error
    conventions"), it is those plus what the carrier's location errors and
    error motions add (:func:`core.selfcal.c_centre_note`; the nmv3000's C
    rides on A: EY0A = 10 µm alone puts the line at (0, 10) µm with EX0C =
    EY0C = 0), and the label says so, naming the carrier. Carried by another
    axis, or with no chain (None), it says the line is ``(EX0C, EY0C)`` only
    on a bed axis (session 35: the label claimed ``(EX0C, EY0C)`` whatever
    carried the axis).
    """
    a = axis.upper()
    lx, ly = line_from_centre((cx, cy))
    head = f"centre ({cx:.1f}, {cy:.1f}) µm:\n"
    gauge = "in the gauge of eqs 16-17"
    carrier, known = None, False
    if chain is not None:
        from core.chain import parse_chain

        ch = parse_chain(chain) if isinstance(chain, str) else chain
        if a in ch.axes:
            carrier, known = ch.parent(a), True
    if known and carrier is None:
        return head + f"(EX0{a}, EY0{a}) = ({lx:.1f}, {ly:.1f}) µm\n{gauge}"
    if carrier in _CARRIER_WORDS:
        return (head + f"{a} carried by {carrier}: its line ({lx:.1f}, {ly:.1f}) µm\n= (EX0{a}, EY0{a}) + what "
                f"{carrier} adds\n({_CARRIER_WORDS[carrier]}), {gauge}")
    why = f"{a} carried by {carrier}" if carrier is not None else "chain unknown"
    return (head + f"{a} line ({lx:.1f}, {ly:.1f}) µm: (EX0{a}, EY0{a})\nif {a} sits on the bed ({why}; "
            f"carried,\nplus its carrier's errors), {gauge}")


def rotary_centre_figure(c_deg, exc_um, eyc_um, *, centre_um=None, true_centre_um=None,
                         u95_exc_um=None, u95_eyc_um=None, axis: str = "C", title: str | None = None,
                         chain=None):
    """Trajectory of the rotary axis's centre, ``(EXC(C), EYC(C))`` (Fig. 13).

    Parameters
    ----------
    c_deg : (n,) float
        Indexed angles, degrees.
    exc_um, eyc_um : (n,) float
        The tool's displacement relative to the part due to the axis at each
        angle (``EXC,total``, ``EYC,total``: radial motion and line position), µm.
    centre_um : (2,) float, optional
        Centre of the circle fitted to the trajectory, µm. The values are the
        tool relative to the part (ISO 230-1), so a table's axis line at
        ``(EX0C, EY0C)`` puts the centre at ``-(EX0C, EY0C)``, in the
        identification's gauge (eqs 16-17: the linear axes' error at the
        grid origin and the radial motion mix in;
        :func:`scenarios.reports.c_line_um`). The label gives both.
    true_centre_um : (2,) float, optional
        The truth's centre in the same gauge (a simulation), drawn beside it.
    u95_exc_um, u95_eyc_um : (n,) float, optional
        Expanded uncertainties (k = 2), drawn as error bars.
    chain : str or Chain, optional
        The machine's kinematic chain (the log's ``kinematic_chain``): what
        carries the axis, which the centre's label names (:func:`centre_label`).
    """
    a = axis.upper()
    c = _arr("c_deg", c_deg, (-1,))
    ex = _arr("exc_um", exc_um, (-1,))
    ey = _arr("eyc_um", eyc_um, (-1,))
    _same_len(c_deg=c, exc_um=ex, eyc_um=ey)
    order = np.argsort(c, kind="stable")
    fig = _figure(5.4, 5.0)
    ax = fig.add_subplot()
    ux = None if u95_exc_um is None else _arr("u95_exc_um", u95_exc_um, (len(c),))
    uy = None if u95_eyc_um is None else _arr("u95_eyc_um", u95_eyc_um, (len(c),))
    ax.errorbar(ex[order], ey[order], xerr=None if ux is None else ux[order],
                yerr=None if uy is None else uy[order], fmt="o-", color=_C_MEAS, capsize=3,
                label=f"(EX{a}, EY{a}) at each {a}")
    for ci, xi, yi in zip(c, ex, ey):
        ax.annotate(f"{a}={ci:g}°", (xi, yi), textcoords="offset points", xytext=(4, 4),
                    fontsize="small")
    ax.plot([0], [0], "+", color="k", ms=10, label="no error")
    if centre_um is not None:
        cx, cy = _arr("centre_um", centre_um, (2,))
        ax.plot([cx], [cy], "x", color=_C_BAD, ms=10, mew=2, label=centre_label(cx, cy, a, chain))
    if true_centre_um is not None:
        tx, ty = _arr("true_centre_um", true_centre_um, (2,))
        ax.plot([tx], [ty], "*", color=_C_TRUE, ms=12,
                label=f"the truth's centre, same gauge:\n({tx:.1f}, {ty:.1f}) µm")
    ax.set_xlabel(f"EX{a}({a}) / µm")
    ax.set_ylabel(f"EY{a}({a}) / µm")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(title or f"Trajectory of the {a}-axis centre line")
    ax.legend(fontsize="small")
    ax.grid(alpha=0.3)
    return fig


def rotary_motions_figure(c_deg, values: Mapping[str, object],
                          u95: Mapping[str, object] | None = None, *, axis: str = "C"):
    """Rotary-axis error motions against the angle, with U95 bars (Fig. 14).

    Parameters
    ----------
    c_deg : (n,) float
        Indexed angles, degrees.
    values : dict
        ``{symbol: (n,) values}``, e.g. ``{"ECC": ecc_urad}``, in the
        symbol's report unit (µm or µrad).
    u95 : dict, optional
        ``{symbol: (n,) U95}``, same units.
    """
    c = _arr("c_deg", c_deg, (-1,))
    if not values:
        raise ConfigError("values: give at least one error motion")
    fig = _figure(6.4, 2.2 + 1.8 * len(values))
    axs = fig.subplots(len(values), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (name, v) in zip(axs, values.items()):
        s = iso_symbol(name)
        val = _arr(name, v, (-1,))
        _same_len(c_deg=c, **{name: val})
        err = None
        if u95 is not None and u95.get(name) is not None:
            err = _arr(f"u95[{name!r}]", u95[name], (len(c),))
        ax.errorbar(c, val, yerr=err, fmt="o", color=_C_MEAS, capsize=3, label=f"{s.name} ± U95")
        ax.axhline(0.0, color=_C_NOMINAL, lw=0.8)
        ax.set_ylabel(iso_label(name))
        ax.grid(alpha=0.3)
    axs[-1].set_xlabel(_axis_label(axis.upper()))
    axs[0].set_title(f"Error motions of the {axis.upper()} axis (error bars: U95, k=2)")
    return fig


# --- MFB figures -------------------------------------------------------------
def _u95_of(d: Mapping):
    for key in ("u95", "u95_um", "u95_urad"):
        if d.get(key) is not None:
            return d[key]
    return None


def _values_of(name: str, d: Mapping) -> np.ndarray:
    for key in ("values_um", "values_urad"):
        if key in d:
            return _arr(f"axes[{name!r}].{key}", d[key], (-1,))
    raise ConfigError(f"axes[{name!r}]: needs 'values_um' or 'values_urad'")


def error_motions_figure(axes: Mapping[str, Mapping], *, truth: Mapping | None = None,
                         symbols: Sequence[str] | None = None, ncols: int = 3,
                         title: str = "Error motions (band and bars: U95, k=2)"):
    """Identified error motions against axis position with U95 (MFB Figs. 15-17).

    Parameters
    ----------
    axes : dict
        The identify report's ``axes``: ``{symbol: {positions_mm, values_um |
        values_urad, u95}}`` (``u95``: scalar or (n,), the values' unit).
    truth : dict, optional
        ``{symbol: (n,) injected values}`` at the same positions.
    symbols : sequence of str, optional
        Which symbols to draw, in this order (default: all of ``axes``).
    """
    names = list(symbols) if symbols is not None else list(axes)
    if not names:
        raise ConfigError("axes: no error motion to draw")
    for nm in names:
        if nm not in axes:
            raise ConfigError(f"symbols: {nm!r} is not in axes")
    ncols = max(1, min(ncols, len(names)))
    nrows = -(-len(names) // ncols)
    fig = _figure(4.2 * ncols, 2.9 * nrows)
    axs = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax, name in zip(axs, names):
        s = iso_symbol(name)
        d = axes[name]
        pos = _arr(f"axes[{name!r}].positions_mm", d.get("positions_mm", []), (-1,))
        val = _values_of(name, d)
        _same_len(positions_mm=pos, values=val)
        u = _u95_of(d)
        if u is not None:
            u = _arr(f"axes[{name!r}].u95", np.broadcast_to(np.asarray(u, float), val.shape), (-1,))
            ax.fill_between(pos, val - u, val + u, color=_C_MEAS, alpha=0.2, lw=0, label="U95")
        ax.errorbar(pos, val, yerr=u, fmt="o-", ms=3, color=_C_MEAS, capsize=2,
                    label="identified")
        if truth is not None and name in truth:
            t = _arr(f"truth[{name!r}]", truth[name], (-1,))
            _same_len(positions_mm=pos, truth=t)
            ax.plot(pos, t, "--", color=_C_TRUE, label="injected")
        ax.axhline(0.0, color=_C_NOMINAL, lw=0.8)
        ax.set_xlabel(_axis_label(s.axis))
        ax.set_ylabel(iso_label(name))
        ax.set_title(s.name, fontsize="medium")
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize="x-small")
    for ax in axs[len(names):]:
        ax.set_visible(False)
    fig.suptitle(title)
    return fig


def errors_figure(errors: Mapping[str, Mapping],
                  title: str = "Injected and identified errors (bars: U95, k=2)"):
    """MFB scenario's ``errors`` object: identified ± U95 beside injected.

    ``errors``: ``{symbol: {injected, identified, u95}}`` with scalar values
    in the symbol's report unit. Translations (µm) and rotations (µrad) get
    one panel each.
    """
    if not errors:
        raise ConfigError("errors: nothing to draw")
    groups: dict[str, list] = {"µm": [], "µrad": []}
    for name, d in errors.items():
        s = iso_symbol(name)
        if "identified" not in d:
            raise ConfigError(f"errors[{name!r}]: needs 'identified'")
        groups[_unit(s)].append((s.name, d))
    groups = {k: v for k, v in groups.items() if v}
    fig = _figure(7.0, 1.6 + 0.3 * len(errors) + 0.6 * len(groups))
    axs = fig.subplots(len(groups), 1, squeeze=False,
                       height_ratios=[len(v) + 1 for v in groups.values()])[:, 0]
    for ax, (unit, rows) in zip(axs, groups.items()):
        yy = np.arange(len(rows))
        ident = np.array([float(d["identified"]) for _, d in rows])
        u = np.array([float(_u95_of(d) or 0.0) for _, d in rows])
        ax.errorbar(ident, yy, xerr=u, fmt="o", color=_C_MEAS, capsize=3, label="identified ± U95")
        inj = [(i, float(d["injected"])) for i, (_, d) in enumerate(rows)
               if d.get("injected") is not None]
        if inj:
            ii, vv = zip(*inj)
            ax.plot(vv, ii, "D", mfc="none", color=_C_TRUE, label="injected")
        ax.axvline(0.0, color=_C_NOMINAL, lw=0.8)
        ax.set_yticks(yy, [n for n, _ in rows])
        ax.invert_yaxis()
        ax.set_xlabel(f"error / {unit}")
        ax.set_ylabel("ISO 230-1 symbol")
        ax.grid(alpha=0.3, axis="x")
        ax.legend(fontsize="x-small")
    axs[0].set_title(title)
    return fig


# --- discovery figures ------------------------------------------------------
def residuals_figure(t_s, approach_deg, residual_um, *, outlier_rows: Sequence[int] = (),
                     title: str = "Residuals of the baseline model"):
    """Discovery residuals against campaign time and approach angle.

    Parameters
    ----------
    t_s : (n,) float
        Time of each touch, s.
    approach_deg : (n,) float
        Approach direction in the machine XY plane, degrees.
    residual_um : (n,) float
        Normal residual ``dq - dq_model`` of each touch, µm.
    outlier_rows : sequence of int
        The report's ``outlier_rows`` (0-based), drawn in red.
    """
    t = _arr("t_s", t_s, (-1,))
    a = _arr("approach_deg", approach_deg, (-1,))
    r = _arr("residual_um", residual_um, (-1,))
    n = _same_len(t_s=t, approach_deg=a, residual_um=r)
    bad = outlier_mask(outlier_rows, n)
    fig = _figure(9.0, 3.6)
    ax1, ax2 = fig.subplots(1, 2, sharey=True)
    for ax, xv, xl in ((ax1, t, "t / s"), (ax2, a, "approach angle θ / °")):
        ax.plot(xv[~bad], r[~bad], ".", color=_C_MEAS, ms=4, label="touches")
        if bad.any():
            ax.plot(xv[bad], r[bad], "x", color=_C_BAD, ms=6, label="outlier rows")
        ax.axhline(0.0, color=_C_NOMINAL, lw=0.8)
        ax.set_xlabel(xl)
        ax.grid(alpha=0.3)
    ax1.set_ylabel("residual of dq / µm")
    if a.size and a.min() >= 0.0 and a.max() <= 360.0:
        ax2.set_xlim(-5.0, 365.0)
    ax1.legend(fontsize="x-small")
    fig.suptitle(title)
    return fig


def findings_figure(report: Mapping, title: str = "Discovery: residual RMS by model", *,
                    quantity: str = "dq", unit: str = "µm"):
    """Residual RMS of the baseline and of each candidate extension.

    ``report``: the discovery report (keys ``baseline.rms_um``,
    ``findings[].cause`` / ``rms_um``, ``cause``, ``extended.cv_rms_um``,
    ``baseline_cv_rms_um``; probe-log.md, "Discovery report"). ``quantity`` and
    ``unit`` name what the RMS is of (a probe log's ``dq`` in µm; an ISO 230-2
    test's deviation, in µm or ″ for a rotary axis, its report's keys named
    ``_um`` again).
    """
    base = report.get("baseline") or {}
    if base.get("rms_um") is None:
        raise ConfigError("report: needs baseline.rms_um")
    import textwrap

    labels = ["baseline"]
    rms = [float(base["rms_um"])]
    for f in report.get("findings") or []:
        labels.append(str(f.get("cause", "?")))
        rms.append(float(f.get("rms_um", np.nan)))
    fig = _figure(7.0, 2.2 + 0.35 * len(labels))
    ax = fig.add_subplot()
    colors = [_C_NOMINAL] + [_C_TRUE if lab == report.get("cause") else _C_MEAS
                             for lab in labels[1:]]
    yy = np.arange(len(labels))
    ax.barh(yy, rms, color=colors)
    ax.set_yticks(yy, labels)
    ax.invert_yaxis()
    cv_b, ext = report.get("baseline_cv_rms_um"), report.get("extended") or {}
    if cv_b is not None and ext.get("cv_rms_um") is not None:
        models = textwrap.fill(f"baseline: {base.get('model', '?')}; extended: {ext.get('model', '?')}", 100)
        ax.set_title(f"{title}\ncross-validated RMS: baseline {cv_b:.3g} {unit} -> "
                     f"extended {ext['cv_rms_um']:.3g} {unit}"
                     f"\n{models}", fontsize="small")
    else:
        ax.set_title(title)
    ax.set_xlabel(f"residual RMS of {quantity} / {unit}")
    ax.set_ylabel("model (cause)")
    ax.grid(alpha=0.3, axis="x")
    return fig


def diagnosis_figure(panels: Sequence[Mapping], title: str = "Discovery: where the structure lives",
                     ylabel: str = "residual of dq / µm"):
    """Residuals against each covariate that carries structure, with the fitted smooth term.

    ``ylabel``: the residual's quantity and unit (a probe log's ``dq`` in µm; an ISO 230-2 test's positional
    deviation, in µm or arc seconds).

    Parameters
    ----------
    panels : sequence of mappings, one per covariate (at most 6 drawn)
        ``x`` : (n,) float, the covariate's value per row (a category's index
        for a category); ``residual_um`` : (n,) float, the baseline's
        residuals, µm; ``fitted_um`` : (n,) float, the smooth term the
        diagnosis fitted, µm; ``xlabel`` : str (with its unit); ``text`` : str (the
        diagnosis in words, drawn as the panel's title); ``xticklabels`` :
        optional, a category's names (drawn at x = 0, 1, ...).
    """
    panels = list(panels)[:6]
    if not panels:
        raise ConfigError("panels: needs at least one covariate")
    cols = min(3, len(panels))
    rows = int(np.ceil(len(panels) / cols))
    fig = _figure(4.2 * cols, 3.0 * rows + 0.6)
    axs = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax, p in zip(axs, panels):
        x = _arr("x", p["x"], (-1,))
        r = _arr("residual_um", p["residual_um"], (-1,))
        f = _arr("fitted_um", p["fitted_um"], (-1,))
        _same_len(x=x, residual_um=r, fitted_um=f)
        order = np.argsort(x, kind="stable")
        ax.plot(x, r, ".", color=_C_MEAS, ms=3, alpha=0.6, label="residuals")
        ax.plot(x[order], f[order], ".", color=_C_TRUE, ms=3, label="smooth term")
        ax.axhline(0.0, color=_C_NOMINAL, lw=0.8)
        ax.set_xlabel(str(p.get("xlabel", "")))
        ticks = p.get("xticklabels")
        if ticks is not None:   # a category: drawn at 0, 1, ... and named
            ax.set_xticks(np.arange(len(ticks)), [str(v) for v in ticks], rotation=30 if len(ticks) > 4 else 0,
                          fontsize="x-small")
        ax.set_ylabel(ylabel)
        # wrapped to the panel's width: a single panel's long title was cut ("... p = 0" for p = 0.0012, review30c)
        ax.set_title(textwrap.fill(str(p.get("text", "")), 58), fontsize="x-small")
        ax.grid(alpha=0.3)
    for ax in axs[len(panels):]:
        ax.set_visible(False)
    axs[0].legend(fontsize="x-small")
    fig.suptitle(title)
    return fig


# --- ISO 230-2 positioning test ---------------------------------------------
_C_UP = "tab:blue"
_C_DOWN = "tab:red"


def positioning_residuals_figure(t_s, target, direction, residual, *, unit: str = "µm", target_label: str = "target / mm",
                                 outlier_rows: Sequence[int] = (),
                                 title: str = "Residuals of the baseline model", time_label: str = "t / s"):
    """Discovery residuals of an ISO 230-2 test against time and target position, by approach direction.

    The probe log's :func:`residuals_figure` draws against the approach angle, which a positioning test does not
    have; here the second panel is the target, and the two approach directions are drawn apart (``+`` blue,
    ``-`` red), as :func:`positioning_figure` draws them.

    Parameters
    ----------
    t_s : (n,) float
        Time of each reading, s; or, when the log has no clock, its place in the reading order (0, 1, ...), which
        ``time_label`` then says (the panel said "t / s" over reading indices before session 36).
    target : (n,) float
        Target position of each reading in the target unit (``target_label`` says it: mm, or ° for a rotary axis).
    direction : (n,) int
        Approach direction of each reading, +1 or -1.
    residual : (n,) float
        Residual of each reading's deviation, in ``unit`` (µm, or ″ for a rotary axis).
    outlier_rows : sequence of int
        The report's outlier rows (0-based), drawn as red crosses.
    time_label : str
        The first panel's axis label: what ``t_s`` holds, with its unit.
    """
    t = _arr("t_s", t_s, (-1,))
    p = _arr("target", target, (-1,))
    s = _arr("direction", direction, (-1,))
    r = _arr("residual", residual, (-1,))
    n = _same_len(t_s=t, target=p, direction=s, residual=r)
    check_directions(s)
    bad = outlier_mask(outlier_rows, n)
    fig = _figure(9.0, 3.6)
    ax1, ax2 = fig.subplots(1, 2, sharey=True)
    for ax, xv, xl in ((ax1, t, time_label), (ax2, p, target_label)):
        for d, c, name in ((1, _C_UP, "approach +"), (-1, _C_DOWN, "approach -")):
            k = (s == d) & ~bad
            ax.plot(xv[k], r[k], "." if d > 0 else "+", color=c, ms=4 if d > 0 else 5, label=name)
        if bad.any():
            ax.plot(xv[bad], r[bad], "x", color="k", ms=6, label="outlier rows")
        ax.axhline(0.0, color=_C_NOMINAL, lw=0.8)
        ax.set_xlabel(xl)
        ax.grid(alpha=0.3)
    ax1.set_ylabel(f"residual of the deviation / {unit}")
    ax1.legend(fontsize="x-small")
    fig.suptitle(title)
    return fig


def positioning_figure(report: Mapping, *, readings: Mapping | None = None,
                       title: str = "ISO 230-2 positioning test"):
    """The standard's plot of a positioning test, with its figures in a table.

    Mean unidirectional positional deviations ``x̄_i↑`` and ``x̄_i↓`` per
    target with their ``x̄ ± 2s`` bands, the mean bidirectional deviation
    ``x̄_i``, the individual readings (optional), the reversal values
    ``B_i`` underneath, and the axis figures (``B``, ``R``, ``E``, ``M``,
    ``A``, ...) beside.

    Parameters
    ----------
    report : mapping
        The ``vmt iso230-2`` JSON report (``core.positioning.Iso2302Result.
        to_report``): ``unit`` (``um`` or ``arcsec``), ``axis``, the axis
        figures ``<name>_<unit>`` and ``per_target`` with ``target_mm`` (or
        ``target_deg``), ``mean_up_<u>``, ``mean_down_<u>``, ``mean_<u>``,
        ``B_<u>``, ``lower_up_<u>`` ... ``upper_down_<u>``.
    readings : mapping, optional
        ``target`` (N,) in the target unit, ``deviation`` (N,) in the
        report unit, ``direction`` (N,) +1 / -1: drawn as dots.
    """
    u = report.get("unit")
    if u not in ("um", "arcsec"):
        raise ConfigError(f"report: unit {u!r} is not 'um' or 'arcsec'")
    rows = report.get("per_target") or []
    if not rows:
        raise ConfigError("report: needs per_target")
    tkey = "target_mm" if "target_mm" in rows[0] else "target_deg"
    sym = "µm" if u == "um" else "″"

    def col(key):
        try:
            return _arr(key, [r[key] for r in rows], (-1,))
        except KeyError:
            raise ConfigError(f"report: per_target has no {key!r}") from None

    P = col(tkey)
    fig = _figure(11.0, 6.2)
    gs = fig.add_gridspec(2, 2, width_ratios=(3.2, 1.25), height_ratios=(3.0, 1.1))
    ax = fig.add_subplot(gs[0, 0])
    axb = fig.add_subplot(gs[1, 0], sharex=ax)
    axt = fig.add_subplot(gs[:, 1])
    if readings is not None:
        rt = _arr("readings target", readings.get("target"), (-1,))
        rd = _arr("readings deviation", readings.get("deviation"), (-1,))
        rs = _arr("readings direction", readings.get("direction"), (-1,))
        _same_len(target=rt, deviation=rd, direction=rs)
        for d, c in ((1, _C_UP), (-1, _C_DOWN)):
            k = rs == d
            ax.plot(rt[k], rd[k], ".", color=c, ms=3, alpha=0.45)
    for d, c, arrow in (("up", _C_UP, "↑"), ("down", _C_DOWN, "↓")):
        lo, hi = col(f"lower_{d}_{u}"), col(f"upper_{d}_{u}")
        ax.fill_between(P, lo, hi, color=c, alpha=0.12, lw=0)
        ax.plot(P, lo, "--", color=c, lw=0.8)
        ax.plot(P, hi, "--", color=c, lw=0.8, label=f"x̄{arrow} ± 2s{arrow}")
        ax.plot(P, col(f"mean_{d}_{u}"), "o-", color=c, ms=4, lw=1.5, label=f"x̄{arrow} (approach {'+' if d == 'up' else '-'})")
    ax.plot(P, col(f"mean_{u}"), "k:", lw=1.2, label="x̄ bidirectional")
    ax.axhline(0.0, color=_C_NOMINAL, lw=0.8)
    ax.set_ylabel(f"positional deviation x / {sym}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="x-small", ncol=3, loc="best")
    ax.tick_params(labelbottom=False)
    axb.bar(P, col(f"B_{u}"), width=0.6 * (np.min(np.diff(np.sort(P))) if P.size > 1 else 1.0),
            color=_C_MEAS, alpha=0.7)
    axb.axhline(0.0, color=_C_NOMINAL, lw=0.8)
    axis = report.get("axis") or ""
    # the unit from the report's targets, not from the axis letter (an axis 'X1' in degrees read '/ mm')
    axb.set_xlabel(f"{axis or 'target P'} / {'mm' if tkey == 'target_mm' else '°'}")
    axb.set_ylabel(f"B_i / {sym}")
    axb.grid(alpha=0.3)
    names = (("B", "reversal B"), ("B_mean", "mean reversal B̄"), ("R_up", "repeatability R↑"),
             ("R_down", "repeatability R↓"), ("R", "repeatability R"), ("E_up", "systematic E↑"),
             ("E_down", "systematic E↓"), ("E", "systematic E"), ("M", "mean bidir. M"),
             ("A_up", "accuracy A↑"), ("A_down", "accuracy A↓"), ("A", "accuracy A"))
    cells = []
    for key, label in names:
        v = report.get(f"{key}_{u}")
        if v is None:
            raise ConfigError(f"report: needs {key}_{u}")
        cells.append([label, f"{float(v):.3f}"])
    axt.axis("off")
    tab = axt.table(cellText=cells, colLabels=["ISO 230-2", f"/ {sym}"], loc="upper center",
                    cellLoc="left", colLoc="left")
    tab.auto_set_font_size(False)
    tab.set_fontsize(8.5)
    tab.scale(1.0, 1.35)
    from core.positioning import cycles_said

    sub = f"{report.get('targets', P.size)} targets, {cycles_said(report)}"
    if report.get("cycle_kind"):
        sub += f", {report['cycle_kind']} cycle"
    fig.suptitle(f"{title} ({sub})")
    return fig


# --- virtual CMM -------------------------------------------------------------
def budget_figure(measurands: Sequence[Mapping], title: str = "Uncertainty budget (one source at a time)"):
    """The budget of each measurand as horizontal bars: u of each source alone and the full u.

    ``measurands``: the ``measurands`` of a ``vmt vcmm`` result (keys ``name``,
    ``u``, ``u_unit``, ``budget[].source`` / ``u``). One panel per measurand;
    the full Monte Carlo u is the dark bar on top, so a budget whose sources
    do not add in quadrature to it (interactions, non-linear measurands such
    as a form deviation) shows at a glance.
    """
    ms = list(measurands)
    if not ms:
        raise ConfigError("budget figure: no measurand")
    rows = max(1, max(len(m.get("budget") or []) for m in ms) + 1)
    fig = _figure(7.0, 0.6 + len(ms) * (0.7 + 0.28 * rows))
    axes = fig.subplots(len(ms), 1, squeeze=False)[:, 0]
    for ax, m in zip(axes, ms):
        b = sorted(m.get("budget") or [], key=lambda x: -float(x["u"]))
        labels = ["Monte Carlo u (all sources)"] + [str(x["source"]) for x in b]
        u = [float(m["u"])] + [float(x["u"]) for x in b]
        yy = np.arange(len(labels))
        ax.barh(yy, u, color=[_C_NOMINAL] + [_C_MEAS] * len(b))
        ax.set_yticks(yy, labels, fontsize="small")
        ax.invert_yaxis()
        ax.set_xlabel(f"standard uncertainty u / {m.get('u_unit', 'µm').replace('um', 'µm').replace('urad', 'µrad')}")
        ax.set_title(str(m["name"]), fontsize="small")
        ax.grid(alpha=0.3, axis="x")
    fig.suptitle(title)
    return fig
