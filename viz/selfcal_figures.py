"""The self-calibration paper's figures that :mod:`viz.figures` does not draw.

================================  ===========================================
function                          paper figure
================================  ===========================================
:func:`outline_uncertainty_figure`  Figs. 18-19: U95 of G_normal as colour,
                                  drawn ON the part's outline (no deviation
                                  moves a point off it)
:func:`pin_positions_figure`      Fig. 17: pin positions, raw and
                                  self-calibrated, errors ×2500
================================  ===========================================

Figs. 9(a-c) and 10 are :func:`viz.figures.profile_figure` (×2500, ×1000),
Fig. 12 :func:`viz.figures.error_grid_figure`, Fig. 13
:func:`viz.figures.rotary_centre_figure`, Fig. 14
:func:`viz.figures.rotary_motions_figure`, Fig. 20
:func:`viz.figures.grid_uncertainty_figure`; :mod:`scenarios.crosspocket`
assembles them. :func:`log_figures` puts the rendered figures themselves in a
rerun recording. Same conventions as :mod:`viz.figures`: plain arrays in, a
Figure not attached to pyplot out; positions mm, errors µm; viz computes
nothing but drawing arithmetic.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from core.exceptions import ConfigError
from viz.checks import check_array, same_len
from viz.figures import PROFILE_MAGNIFICATION, _figure, _scale_bar

_C_OUTLINE = "0.45"


def outline_uncertainty_figure(points_mm, u95_um, *, outlines_mm: Sequence = (), circles_mm: Sequence = (),
                               title: str = "U95 (k=2) of the identified workpiece G_normal",
                               vmax_um: float | None = None):
    """Expanded uncertainty of ``G_normal`` as colour at the targets, on the part's outline (Figs. 18-19).

    Parameters
    ----------
    points_mm : (n, 2) float
        Nominal contact points ``w p_i*`` in W (x, y), mm: drawn where they
        are, on the outline (the uncertainty is a colour, not a displacement).
    u95_um : (n,) float
        Expanded uncertainty (k = 2) at each target, µm.
    outlines_mm : sequence of (m, 2) float
        Closed polygons of the part's walls in W, mm (drawn closed).
    circles_mm : sequence of (x, y, r)
        Circles (the spheres' equators), mm.
    vmax_um : float, optional
        Top of the colour scale (to compare figures on one scale).
    """
    p = check_array("points_mm", points_mm, (-1, 2))
    u = np.asarray(u95_um, float)
    if u.ndim != 1 or np.any(np.isinf(u)) or np.all(np.isnan(u)):
        raise ConfigError(f"u95_um: expected (n,) finite values (NaN = not computed), got shape {u.shape}")
    same_len(points_mm=p, u95_um=u)
    fig = _figure(6.4, 5.4)
    ax = fig.add_subplot()
    for k, poly in enumerate(outlines_mm):
        q = check_array(f"outlines_mm[{k}]", poly, (-1, 2))
        q = np.vstack([q, q[:1]])
        ax.plot(q[:, 0], q[:, 1], "-", lw=0.8, color=_C_OUTLINE, label="outline" if k == 0 else None)
    th = np.linspace(0.0, 2 * np.pi, 121)
    for k, c in enumerate(circles_mm):
        x, y, r = (float(v) for v in c)
        if not r > 0:
            raise ConfigError(f"circles_mm[{k}]: radius must be > 0, got {r}")
        ax.plot(x + r * np.cos(th), y + r * np.sin(th), "-", lw=0.8, color=_C_OUTLINE)
    bad = np.isnan(u)
    if bad.any():
        ax.plot(p[bad, 0], p[bad, 1], "x", ms=4, color="0.5", label="U95 not computed")
    s = ax.scatter(p[~bad, 0], p[~bad, 1], c=u[~bad], cmap="jet", vmin=0.0, vmax=vmax_um, s=26, zorder=3)
    fig.colorbar(s, ax=ax, label="U95 (k=2) of G_normal / µm")
    ax.set_xlabel("x_W / mm")
    ax.set_ylabel("y_W / mm")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{title}\nmax {np.nanmax(u):.2f} µm", fontsize="medium")
    if bad.any():
        ax.legend(fontsize="small", loc="upper right")
    ax.grid(alpha=0.3)
    return fig


def pin_positions_figure(nominal_mm, raw_err_um, cal_err_um, *, magnification: float = PROFILE_MAGNIFICATION,
                         scale_um: float = 40.0, labels=("raw, C = 0°", "self-calibrated"),
                         title: str = "Pin positions against the reference (Fig. 17)"):
    """Pin positions drawn as errors from the reference, magnified (Fig. 17).

    Parameters
    ----------
    nominal_mm : (P, 2) float
        Pin centres in W, mm (the reference positions drawn at the nominal).
    raw_err_um, cal_err_um : (P, 2) float
        Position errors (measured minus reference) in the paper's frame
        (0 at pin 1, no Y error at pin 11), µm.
    magnification : float
        2500 as the paper (40 µm drawn as 100 mm).
    """
    p = check_array("nominal_mm", nominal_mm, (-1, 2))
    raw = check_array("raw_err_um", raw_err_um, (-1, 2))
    cal = check_array("cal_err_um", cal_err_um, (-1, 2))
    same_len(nominal_mm=p, raw_err_um=raw, cal_err_um=cal)
    if magnification <= 0:
        raise ConfigError(f"magnification must be > 0, got {magnification}")
    k = magnification * 1e-3
    fig = _figure(6.4, 6.0)
    ax = fig.add_subplot()
    loop = np.vstack([p, p[:1]])
    ax.plot(loop[:, 0], loop[:, 1], "o-", ms=7, mfc="none", lw=0.8, color="k", label="reference (CMM's role)")
    for e, lab, col in ((raw, labels[0], "tab:blue"), (cal, labels[1], "tab:red")):
        q = p + k * e
        q = np.vstack([q, q[:1]])
        ax.plot(q[:, 0], q[:, 1], "o-", ms=5, lw=1.0, color=col,
                label=f"{lab} (max {np.hypot(e[:, 0], e[:, 1]).max():.2f} µm)")
    for i, (x, y) in enumerate(p):
        ax.annotate(str(i + 1), (x, y), textcoords="offset points", xytext=(6, 6), fontsize="x-small")
    _scale_bar(ax, k * scale_um, f"error scale: {scale_um:g} µm")
    ax.set_xlabel("x_W / mm")
    ax.set_ylabel("y_W / mm")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{title}, errors ×{magnification:g}", fontsize="medium")
    ax.legend(fontsize="small", loc="upper right")
    ax.grid(alpha=0.3)
    return fig


def figure_png_bytes(fig, *, dpi: int = 110) -> bytes:
    """The figure rendered as PNG bytes (what :func:`log_figures` records)."""
    import io

    from viz.figures import write_png

    buf = io.BytesIO()
    write_png(fig, buf, dpi=dpi)
    return buf.getvalue()


def log_figures(rec, figures: dict, *, path: str = "reports/figures") -> None:
    """Log each ``{name: Figure or PNG bytes}`` as a PNG image at ``path/name`` (static) in a rerun recording."""
    import rerun as rr

    for name, fig in figures.items():
        png = fig if isinstance(fig, bytes) else figure_png_bytes(fig)
        rec.log(f"{path}/{name}", rr.EncodedImage(contents=png, media_type="image/png"), static=True)
