"""rerun recordings (``.rrd``) of a vmt run: scene, probing, identified errors.

One recording per run, written to a file (never a viewer: open it later with
``vmt view RUN.rrd``). The layout follows the frame tree of CONTRIBUTING.md:

=================================  ==========================================
entity path                        what is logged there (data in that frame)
=================================  ==========================================
``/``                              ``ViewCoordinates.RIGHT_HAND_Z_UP``, once, static
``world/R``                        machine reference frame R (MCS)
``world/R/table``                  rotary table, placement in R per set-up
                                   (timeline ``setup``: T_R_W at its angles)
``world/R/table/W``                workpiece frame W (WCS), placement in table
``world/R/table/W/artefact``       artefact mesh, vertices in A, placed in W
                                   (``T_W_A``)
``world/R/table/W/workpiece/*``    identified workpiece deviation / U95 (W)
``world/R/spindle``                spindle S, placement in R
``world/R/spindle/probe``          probe mesh, vertices in S
``world/R/probe_path``             stylus-tip centre path, in R
``world/R/touches``                touch points in R, coloured by dq (one
                                   set-up per step of timeline ``setup``)
``world/R/error_map/*``            error grid: nominal, identified, true (x1000)
``plots/error_motions/<axis>/<S>``  error motion ``S`` against axis position
``plots/rotary/<axis>/<S>``         rotary-axis error motion against angle
``rotary/<axis>/centre_trajectory``  Figure 13 of the self-calibration paper
``discover/residuals/*``           discovery residuals against time / approach
                                   (an ISO 230-2 test's: against time or the
                                   reading order / the target, per direction)
``reports/*``                      markdown tables (errors, findings)
=================================  ==========================================

Scene geometry is in metres (SI, as sim and core hand it over); deviations,
error values and their uncertainties are in the report units µm / µrad, as
the results' JSON carries them (unit in each argument's name). Timelines:
``<axis>_um`` (sequence: axis position in integer µm) for linear error
motions, ``<axis>_mdeg`` (sequence: millidegrees) for rotary ones,
``campaign_time`` (duration, s) and ``approach_mdeg`` for residuals (an ISO 230-2
test's: ``campaign_time`` or ``reading`` (sequence: the reading order, for a log
without a clock) and ``target_um`` or ``target_mdeg``),
``setup`` (sequence: set-up index) for a campaign's set-ups: the table's
placement and the touches of that set-up, so each set-up's touches are drawn
against the part at that set-up's pose.

viz draws what the results hold and computes nothing: every quantity shown
(errors, U95, centres, residuals) is passed in. The only arithmetic here is
drawing arithmetic: colour maps and the magnification of deviations.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np

from core.exceptions import ConfigError
from viz.checks import check_array, check_directions, outlier_mask, same_len
from core.iso import symbol as iso_symbol

# --- entity paths (mirror the frame tree) -----------------------------------
ROOT = "/"
WORLD = "world"
R = "world/R"
TABLE = "world/R/table"
W = "world/R/table/W"
ARTEFACT = "world/R/table/W/artefact"
WORKPIECE = "world/R/table/W/workpiece"
SPINDLE = "world/R/spindle"
PROBE = "world/R/spindle/probe"
PROBE_PATH = "world/R/probe_path"
TOUCHES = "world/R/touches"
ERROR_MAP = "world/R/error_map"
ERROR_MOTIONS = "plots/error_motions"
ROTARY_PLOTS = "plots/rotary"
ROTARY = "rotary"
RESIDUALS = "discover/residuals"
REPORTS = "reports"

#: Magnifications of the papers' figures (self-calibration paper).
PROFILE_MAGNIFICATION = 2500.0  # Figure 9(a), 9(c)
GRID_MAGNIFICATION = 1000.0  # Figure 12

_BLUE = (31, 119, 180)
_ORANGE = (255, 127, 14)
_GREY = (150, 150, 150)
_RED = (214, 39, 40)
_BLACK = (0, 0, 0)


# --- small checks ----------------------------------------------------------
_arr = check_array
_same_len = same_len


# --- colour maps (drawing only) --------------------------------------------
def diverging_colors(values, limit: float | None = None, cmap: str = "RdBu_r") -> np.ndarray:
    """RGB colours of signed values on a diverging map with symmetric limits.

    Parameters
    ----------
    values : (n,) float
        Signed values (e.g. dq in µm).
    limit : float, optional
        The map spans ``[-limit, +limit]``; default ``max |values|``.

    Returns
    -------
    (n, 3) uint8
    """
    import matplotlib

    v = np.asarray(values, dtype=float).ravel()
    lim = float(limit) if limit is not None else float(np.max(np.abs(v), initial=0.0))
    if lim <= 0.0 or not np.isfinite(lim):
        lim = 1.0
    t = np.clip(0.5 + 0.5 * v / lim, 0.0, 1.0)
    return (matplotlib.colormaps[cmap](t)[:, :3] * 255).round().astype(np.uint8)


def sequential_colors(values, vmax: float | None = None, cmap: str = "viridis") -> np.ndarray:
    """RGB colours of non-negative values (e.g. U95 in µm) on ``[0, vmax]``.

    Returns
    -------
    (n, 3) uint8
    """
    import matplotlib

    v = np.asarray(values, dtype=float).ravel()
    top = float(vmax) if vmax is not None else float(np.max(v, initial=0.0))
    if top <= 0.0 or not np.isfinite(top):
        top = 1.0
    t = np.clip(v / top, 0.0, 1.0)
    return (matplotlib.colormaps[cmap](t)[:, :3] * 255).round().astype(np.uint8)


# --- the recording ---------------------------------------------------------
@contextlib.contextmanager
def recording(path, *, application_id: str = "vmt", recording_id: str | None = None
              ) -> Iterator:
    """Open a rerun recording that appears at ``path`` complete or not at all.

    The stream is saved to a temporary file next to ``path`` and renamed into
    place when the ``with`` block ends without an exception (removed
    otherwise). The right-handed Z-up world is logged once, static, at the
    root ``/``.

    Yields
    ------
    rerun.RecordingStream
        Pass it to the ``log_*`` functions of this module (or log to it
        directly).

    Examples
    --------
    >>> with recording("out/run.rrd") as rec:          # doctest: +SKIP
    ...     log_touches(rec, p_R, dq_um)
    """
    import rerun as rr

    path = Path(path)
    if not path.parent.is_dir():
        raise ConfigError(f"recording path {str(path)!r}: folder does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    rec = rr.RecordingStream(application_id, recording_id=recording_id)
    ok = False
    try:
        rec.save(tmp)
        rec.log(ROOT, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        rec.log(R, rr.Transform3D(translation=[0.0, 0.0, 0.0]), static=True)
        yield rec
        ok = True
    finally:
        rec.flush()
        rec.disconnect()
        if ok:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it 0600
            os.replace(tmp, path)
        else:
            with contextlib.suppress(OSError):
                os.unlink(tmp)


def log_placement(rec, path: str, T_parent_child, *, time_s: float | None = None,
                  setup: int | None = None) -> None:
    """Log the pose of the frame at ``path`` in its parent frame.

    Parameters
    ----------
    T_parent_child : (4, 4) float
        Homogeneous transform, translation in m (e.g. ``T_R_W``).
    time_s : float, optional
        Campaign time of this placement (timeline ``campaign_time``).
    setup : int, optional
        Set-up index of this placement (timeline ``setup``, e.g. the table
        at that set-up's C angle). With neither it is logged static.
    """
    import rerun as rr

    T = _arr("T_parent_child", T_parent_child, (4, 4))
    tf = rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3])
    if time_s is None and setup is None:
        rec.log(path, tf, static=True)
        return
    with _at(rec, time_s, setup):
        rec.log(path, tf)


@contextlib.contextmanager
def _at(rec, time_s: float | None, setup: int | None):
    """Log on ``campaign_time`` and/or ``setup`` inside the block; no timeline set after it."""
    if setup is not None and (int(setup) != setup or setup < 0):
        raise ConfigError(f"setup: expected a set-up index >= 0, got {setup!r}")
    if time_s is not None:
        rec.set_time("campaign_time", duration=float(time_s))
    if setup is not None:
        rec.set_time("setup", sequence=int(setup))
    try:
        yield
    finally:
        rec.reset_time()


def log_mesh(rec, path: str, vertices_m, faces, *, T_parent_child=None,
             color=(180, 180, 190)) -> None:
    """Log a triangle mesh (artefact, probe, fixture) in its own frame.

    Parameters
    ----------
    path : str
        Entity path, e.g. :data:`ARTEFACT` or :data:`PROBE`.
    vertices_m : (n, 3) float
        Vertices in the mesh's own frame (e.g. the artefact frame A), m.
    faces : (k, 3) int
        Vertex indices of each triangle.
    T_parent_child : (4, 4) float, optional
        Placement of the mesh's frame in the parent entity's frame (static,
        e.g. ``T_W_A``); without it the vertices are in the parent's frame.
    """
    import rerun as rr

    v = _arr("vertices_m", vertices_m, (-1, 3))
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
        raise ConfigError(f"faces: expected (k, 3) integer array, got {f.shape} {f.dtype}")
    if f.size and (f.min() < 0 or f.max() >= len(v)):
        raise ConfigError(f"faces: vertex index out of range 0..{len(v) - 1}")
    if T_parent_child is not None:
        log_placement(rec, path, T_parent_child)
    rec.log(path, rr.Mesh3D(vertex_positions=v, triangle_indices=f.astype(np.uint32),
                            albedo_factor=color), static=True)


def log_probe_path(rec, p_R_m, *, path: str = PROBE_PATH) -> None:
    """Log the stylus-tip centre path as one line strip.

    Parameters
    ----------
    p_R_m : (n, 3) float
        Successive tip positions in the machine frame R, m.
    """
    import rerun as rr

    p = _arr("p_R_m", p_R_m, (-1, 3))
    rec.log(path, rr.LineStrips3D([p], colors=[_GREY], radii=[0.0002]), static=True)


def log_touches(rec, p_R_m, dq_um, *, limit_um: float | None = None,
                n_R=None, path: str = TOUCHES, setup: int | None = None) -> None:
    """Log touch points coloured by their deviation ``dq`` (diverging, symmetric).

    Parameters
    ----------
    p_R_m : (n, 3) float
        Touch points (tip centre) in R, m.
    dq_um : (n,) float
        Normal deviation ``dq = n . (p_reported - p_nominal)``, µm.
    limit_um : float, optional
        Colour limits ``±limit_um``; default ``max |dq_um|``. The value is
        logged as a label under ``<path>/colour_scale``.
    n_R : (n, 3) float, optional
        Surface normals in R; drawn as short arrows when given.
    setup : int, optional
        These are one set-up's touches: logged at that step of timeline
        ``setup`` (beside the table's placement there, :func:`log_placement`),
        not static; give ``limit_um`` so every set-up has one colour scale.
    """
    import rerun as rr

    p = _arr("p_R_m", p_R_m, (-1, 3))
    dq = _arr("dq_um", dq_um, (-1,))
    _same_len(p_R_m=p, dq_um=dq)
    n = None
    if n_R is not None:
        n = _arr("n_R", n_R, (-1, 3))
        _same_len(p_R_m=p, n_R=n)
    lim = float(limit_um) if limit_um is not None else float(np.max(np.abs(dq), initial=0.0))
    labels = [f"dq = {d:+.2f} µm" for d in dq]
    static = setup is None
    with _at(rec, None, setup) if setup is not None else contextlib.nullcontext():
        rec.log(path, rr.Points3D(p, colors=diverging_colors(dq, lim), radii=[0.0008],
                                  labels=labels, show_labels=False), static=static)
        if n is not None:
            rec.log(f"{path}/normals", rr.Arrows3D(origins=p, vectors=0.004 * n,
                                                   colors=[_GREY]), static=static)
    rec.log(f"{path}/colour_scale",
            rr.TextDocument(f"dq colour scale: blue -{lim:.2f} µm .. white 0 .. red +{lim:.2f} µm"),
            static=True)


def _grid_strips(x, y, z):
    """Row and column polylines of a (ny, nx) grid of 3D nodes."""
    pts = np.stack([x, y, z], axis=-1)
    return [pts[i] for i in range(pts.shape[0])] + [pts[:, j] for j in range(pts.shape[1])]


def log_error_grid(rec, x_mm, y_mm, ex_um, ey_um, *, true_ex_um=None, true_ey_um=None,
                   u95_um=None, magnification: float = GRID_MAGNIFICATION,
                   z_mm: float = 0.0, path: str = ERROR_MAP, note: str = "") -> None:
    """Log the 2D positioning-error map drawn deformed and magnified (Figure 12).

    Each node ``(x, y)`` is drawn at ``(x, y) + magnification * (Ex, Ey)``:
    the nominal grid (grey), the identified grid (blue) and, when known, the
    true grid (orange). With ``u95_um`` the identified nodes are coloured by
    their expanded uncertainty (Figure 20).

    Parameters
    ----------
    x_mm : (nx,) float
        Grid positions along X, mm (R).
    y_mm : (ny,) float
        Grid positions along Y, mm (R).
    ex_um, ey_um : (ny, nx) float
        Positioning errors ``Ex,total``, ``Ey,total`` at each node, µm
        (self-calibration paper eqs. 4-5, computed by core).
    true_ex_um, true_ey_um : (ny, nx) float, optional
        The injected (true) errors, when known.
    u95_um : (ny, nx) float, optional
        Expanded uncertainty (k = 2) of the node's error, µm.
    magnification : float
        Drawing magnification of the errors (1000 as in the paper).
    note : str
        Added to the legend (e.g. how often the true map lies within the U95).
    """
    import rerun as rr

    x = _arr("x_mm", x_mm, (-1,))
    y = _arr("y_mm", y_mm, (-1,))
    shape = (len(y), len(x))
    ex = _arr("ex_um", ex_um, shape)
    ey = _arr("ey_um", ey_um, shape)
    if magnification <= 0:
        raise ConfigError(f"magnification must be > 0, got {magnification}")
    X, Y = np.meshgrid(x * 1e-3, y * 1e-3)
    Z = np.full_like(X, z_mm * 1e-3)
    k = magnification * 1e-6  # µm -> m, magnified
    rec.log(f"{path}/nominal", rr.LineStrips3D(_grid_strips(X, Y, Z), colors=[_GREY],
                                               radii=[0.0003]), static=True)
    rec.log(f"{path}/identified",
            rr.LineStrips3D(_grid_strips(X + k * ex, Y + k * ey, Z), colors=[_BLUE],
                            radii=[0.0005]), static=True)
    if u95_um is not None:
        u = _arr("u95_um", u95_um, shape)
        nodes = np.stack([X + k * ex, Y + k * ey, Z], axis=-1).reshape(-1, 3)
        rec.log(f"{path}/identified/u95", rr.Points3D(
            nodes, colors=sequential_colors(u.ravel()), radii=[0.002],
            labels=[f"U95 = {v:.2f} µm" for v in u.ravel()], show_labels=False), static=True)
    if (true_ex_um is None) != (true_ey_um is None):
        raise ConfigError("true_ex_um and true_ey_um: give both or neither")
    if true_ex_um is not None:
        tx = _arr("true_ex_um", true_ex_um, shape)
        ty = _arr("true_ey_um", true_ey_um, shape)
        rec.log(f"{path}/true", rr.LineStrips3D(_grid_strips(X + k * tx, Y + k * ty, Z),
                                                colors=[_ORANGE], radii=[0.0005]), static=True)
    rec.log(f"{path}/legend", rr.TextDocument(
        f"Error map, errors magnified x{magnification:g}: grey nominal, blue identified"
        + (", orange true" if true_ex_um is not None else "")
        + (", node colour U95 (k=2)" if u95_um is not None else "") + (f". {note}" if note else "")), static=True)


def _values_key(d: Mapping, name: str) -> tuple[np.ndarray, str]:
    for key, unit in (("values_um", "µm"), ("values_urad", "µrad")):
        if key in d:
            return np.asarray(d[key], dtype=float), unit
    raise ConfigError(f"axes[{name!r}]: needs 'values_um' or 'values_urad'")


def _u95_key(d: Mapping):
    for key in ("u95", "u95_um", "u95_urad"):
        if key in d and d[key] is not None:
            return d[key]
    return None


def _series(rec, path: str, timeline: str, ticks: np.ndarray, values: np.ndarray,
            name: str, color, *, points: bool = False) -> None:
    import rerun as rr

    style = (rr.SeriesPoints(names=[name], colors=[color], marker_sizes=[3.0]) if points
             else rr.SeriesLines(names=[name], colors=[color]))
    rec.log(path, style, static=True)
    rec.send_columns(path, indexes=[rr.TimeColumn(timeline, sequence=ticks)],
                     columns=rr.Scalars.columns(scalars=values))


def log_error_motions(rec, axes: Mapping[str, Mapping], *, truth: Mapping | None = None,
                      path: str = ERROR_MOTIONS) -> None:
    """Log identified error motions with their U95 band as plots over axis position.

    Parameters
    ----------
    axes : dict
        The ``axes`` object of the identify report: ``{symbol: {positions_mm,
        values_um | values_urad, u95}}``; ``symbol`` an ISO 230-1 name
        (``"EXX"``, ``"ECY"``...); ``u95`` (k = 2) in the values' unit,
        optional.
    truth : dict, optional
        ``{symbol: values}`` of the injected errors at the same positions,
        same unit (drawn in orange).

    Notes
    -----
    Each symbol ``S`` of axis ``A`` goes to ``<path>/A/S/{value, u95_upper,
    u95_lower, true}`` on the sequence timeline ``A_um`` (axis position in
    integer µm), the MFB paper's Figures 15-17 as a live plot.
    """
    for name, d in axes.items():
        sym = iso_symbol(name)
        pos = _arr(f"axes[{name!r}].positions_mm", d.get("positions_mm", []), (-1,))
        val, unit = _values_key(d, name)
        val = _arr(f"axes[{name!r}].values", val, (-1,))
        _same_len(positions_mm=pos, values=val)
        timeline = f"{sym.axis}_um"
        ticks = np.round(pos * 1000.0).astype(np.int64)
        base = f"{path}/{sym.axis}/{sym.name}"
        label = f"{sym.name}({sym.axis}) / {unit}"
        _series(rec, f"{base}/value", timeline, ticks, val, label, _BLUE)
        u = _u95_key(d)
        if u is not None:
            u = _arr(f"axes[{name!r}].u95", np.broadcast_to(np.asarray(u, float), val.shape), (-1,))
            _series(rec, f"{base}/u95_upper", timeline, ticks, val + u, "+U95 (k=2)", _GREY)
            _series(rec, f"{base}/u95_lower", timeline, ticks, val - u, "-U95 (k=2)", _GREY)
        if truth is not None and name in truth:
            t = _arr(f"truth[{name!r}]", truth[name], (-1,))
            _same_len(positions_mm=pos, truth=t)
            _series(rec, f"{base}/true", timeline, ticks, t, f"{sym.name} true / {unit}", _ORANGE)


def log_rotary(rec, c_deg, exc_um, eyc_um, *, ecc_urad=None, u95_exc_um=None,
               u95_eyc_um=None, u95_ecc_urad=None, centre_um=None, axis: str = "C", chain=None) -> None:
    """Log the rotary-axis error motions and the trajectory of its centre.

    ``rotary/<axis>/centre_trajectory`` is the self-calibration paper's
    Figure 13: the points ``(EXC, EYC)`` at each indexed angle in µm (2D),
    joined in angle order, with the best-fit circle's centre ``centre_um``
    when given (labelled as :func:`viz.figures.centre_label`: the axis line
    sits at minus the centre, the values being the tool relative to the part). The
    values are also plotted against the angle on timeline ``<axis>_mdeg``
    (Figure 14 for ``ECC``), with their U95 bands.

    Parameters
    ----------
    c_deg : (n,) float
        Indexed angles, degrees.
    exc_um, eyc_um : (n,) float
        Radial error motions ``EXC(C)``, ``EYC(C)``, µm.
    ecc_urad : (n,) float, optional
        Angular positioning error ``ECC(C)``, µrad.
    u95_* : (n,) float, optional
        Expanded uncertainties (k = 2), same units.
    chain : str or Chain, optional
        The machine's kinematic chain: what carries the axis, which the
        centre's label names (:func:`viz.figures.centre_label`).
    """
    import rerun as rr

    c = _arr("c_deg", c_deg, (-1,))
    ex = _arr("exc_um", exc_um, (-1,))
    ey = _arr("eyc_um", eyc_um, (-1,))
    _same_len(c_deg=c, exc_um=ex, eyc_um=ey)
    a = axis.upper()
    order = np.argsort(c, kind="stable")
    xy = np.stack([ex, ey], axis=1)
    base = f"{ROTARY}/{a}/centre_trajectory"
    rec.log(base, rr.Points2D(xy, colors=[_BLUE], radii=[0.3],
                              labels=[f"{a}={v:g}°" for v in c]), static=True)
    rec.log(f"{base}/path", rr.LineStrips2D([xy[order]], colors=[_BLUE]), static=True)
    if centre_um is not None:
        from viz.figures import centre_label

        cx, cy = _arr("centre_um", centre_um, (2,))
        rec.log(f"{base}/centre", rr.Points2D([[float(cx), float(cy)]], colors=[_RED], radii=[0.5],
                                              labels=[centre_label(cx, cy, a, chain).replace("\n", " ")]), static=True)
    timeline = f"{a}_mdeg"
    ticks = np.round(c * 1000.0).astype(np.int64)
    series = [(f"EX{a}", ex, u95_exc_um, "µm"), (f"EY{a}", ey, u95_eyc_um, "µm")]
    if ecc_urad is not None:
        series.append((f"EC{a}", _arr("ecc_urad", ecc_urad, (-1,)), u95_ecc_urad, "µrad"))
    for name, v, u, unit in series:
        _same_len(c_deg=c, **{name: v})
        base_s = f"{ROTARY_PLOTS}/{a}/{name}"
        _series(rec, f"{base_s}/value", timeline, ticks, v, f"{name}({a}) / {unit}", _BLUE,
                points=True)
        if u is not None:
            u = _arr(f"u95 of {name}", u, (-1,))
            _same_len(c_deg=c, **{f"u95 of {name}": u})
            _series(rec, f"{base_s}/u95_upper", timeline, ticks, v + u, "+U95 (k=2)", _GREY,
                    points=True)
            _series(rec, f"{base_s}/u95_lower", timeline, ticks, v - u, "-U95 (k=2)", _GREY,
                    points=True)


def log_workpiece(rec, p_W_m, n_W, g_um, *, u95_um=None,
                  magnification: float = PROFILE_MAGNIFICATION, path: str = WORKPIECE,
                  label: str = "G") -> None:
    """Log the identified workpiece deviation and its uncertainty on the part.

    ``<path>/nominal``: the nominal points (grey); ``<path>/deviation``: each
    point moved ``magnification * g`` along its normal (the self-calibration
    paper's Figure 9 profile) and coloured by ``g`` (diverging, symmetric);
    ``<path>/u95``: the nominal points coloured by U95 (Figures 18-19).

    Parameters
    ----------
    p_W_m : (n, 3) float
        Nominal target points in the workpiece frame W, m.
    n_W : (n, 3) float
        Unit outward normals in W.
    g_um : (n,) float
        Identified normal deviation of the workpiece ``G_normal``, µm, or
        what is drawn of it (the demo draws its form: datum shift, rotation
        and scale removed).
    u95_um : (n,) float, optional
        Its expanded uncertainty (k = 2), µm.
    label : str
        The name in each point's label, ``"<label> = +1.06 µm"``: ``"G"``,
        or ``"form"`` when ``g_um`` is the form.
    """
    import rerun as rr

    p = _arr("p_W_m", p_W_m, (-1, 3))
    n = _arr("n_W", n_W, (-1, 3))
    g = _arr("g_um", g_um, (-1,))
    _same_len(p_W_m=p, n_W=n, g_um=g)
    rec.log(f"{path}/nominal", rr.Points3D(p, colors=[_GREY], radii=[0.0004]), static=True)
    moved = p + (magnification * 1e-6) * g[:, None] * n
    rec.log(f"{path}/deviation", rr.Points3D(
        moved, colors=diverging_colors(g), radii=[0.0007],
        labels=[f"{label} = {v:+.2f} µm" for v in g], show_labels=False), static=True)
    rec.log(f"{path}/deviation/profile", rr.LineStrips3D([moved], colors=[_ORANGE]), static=True)
    if u95_um is not None:
        u = _arr("u95_um", u95_um, (-1,))
        _same_len(p_W_m=p, u95_um=u)
        rec.log(f"{path}/u95", rr.Points3D(
            p, colors=sequential_colors(u), radii=[0.0010],
            labels=[f"U95 = {v:.2f} µm" for v in u], show_labels=False), static=True)


def log_residuals(rec, t_s, approach_deg, residual_um, *, outlier_rows: Sequence[int] = (),
                  path: str = RESIDUALS) -> None:
    """Log discovery residuals against campaign time and approach angle.

    Parameters
    ----------
    t_s : (n,) float
        Time of each touch, s.
    approach_deg : (n,) float
        Approach direction of each touch in the machine XY plane, degrees.
    residual_um : (n,) float
        Residual of the baseline model at each touch, µm.
    outlier_rows : sequence of int
        Rows judged invalid (``outlier_rows`` of the discovery report);
        drawn again, in red, under ``<path>/outliers_*``.
    """
    import rerun as rr

    t = _arr("t_s", t_s, (-1,))
    a = _arr("approach_deg", approach_deg, (-1,))
    r = _arr("residual_um", residual_um, (-1,))
    n = _same_len(t_s=t, approach_deg=a, residual_um=r)
    rows = np.flatnonzero(outlier_mask(outlier_rows, n))
    order_t = np.argsort(t, kind="stable")
    order_a = np.argsort(a, kind="stable")

    def send(sub: str, timeline_col, idx: np.ndarray, color, name: str) -> None:
        p = f"{path}/{sub}"
        rec.log(p, rr.SeriesPoints(names=[name], colors=[color], marker_sizes=[2.0]), static=True)
        rec.send_columns(p, indexes=[timeline_col(idx)],
                         columns=rr.Scalars.columns(scalars=r[idx]))

    def by_time(idx):
        return rr.TimeColumn("campaign_time", duration=t[idx])

    def by_angle(idx):
        return rr.TimeColumn("approach_mdeg", sequence=np.round(a[idx] * 1000).astype(np.int64))

    send("vs_time", by_time, order_t, _BLUE, "residual / µm")
    send("vs_approach", by_angle, order_a, _BLUE, "residual / µm")
    if rows.size:
        send("outliers_vs_time", by_time, rows[np.argsort(t[rows], kind="stable")], _RED,
             "outlier / µm")
        send("outliers_vs_approach", by_angle, rows[np.argsort(a[rows], kind="stable")], _RED,
             "outlier / µm")


def log_positioning_residuals(rec, t, target, direction, residual, *, outlier_rows: Sequence[int] = (),
                              clock: bool = True, target_unit: str = "mm", unit: str = "µm",
                              path: str = RESIDUALS) -> None:
    """Log an ISO 230-2 test's discovery residuals against time and the target, each approach direction apart.

    What the report page's :func:`viz.figures.positioning_residuals_figure` draws, as rerun series:
    ``<path>/vs_time_plus``, ``vs_time_minus``, ``vs_target_plus``, ``vs_target_minus`` (and, with outliers,
    ``outliers_vs_time``, ``outliers_vs_target``).

    Parameters
    ----------
    t : (n,) float
        Time of each reading, s (timeline ``campaign_time``); with ``clock`` False its place in the reading order,
        0, 1, ... (timeline ``reading``, a sequence: no time is made up for a log without a clock).
    target : (n,) float
        Target position of each reading in ``target_unit``: ``"mm"`` (timeline ``target_um``, integer µm) or
        ``"deg"`` (``target_mdeg``, millidegrees).
    direction : (n,) int
        Approach direction of each reading, +1 or -1.
    residual : (n,) float
        Residual of each reading's deviation, in ``unit`` (µm, or ″ for a rotary axis).
    outlier_rows : sequence of int
        The report's outlier rows (0-based), drawn again in red.
    """
    import rerun as rr

    tt = _arr("t", t, (-1,))
    p = _arr("target", target, (-1,))
    s = _arr("direction", direction, (-1,))
    r = _arr("residual", residual, (-1,))
    n = _same_len(t=tt, target=p, direction=s, residual=r)
    check_directions(s)
    if target_unit not in ("mm", "deg"):
        raise ConfigError(f"target_unit: 'mm' or 'deg', got {target_unit!r}")
    if not clock and not np.array_equal(tt, np.round(tt)):
        raise ConfigError("t: without a clock it is the reading order, whole numbers")
    bad = outlier_mask(outlier_rows, n)
    rows = np.flatnonzero(bad)

    def by_time(idx):
        return (rr.TimeColumn("campaign_time", duration=tt[idx]) if clock
                else rr.TimeColumn("reading", sequence=tt[idx].astype(np.int64)))

    def by_target(idx):
        return rr.TimeColumn("target_um" if target_unit == "mm" else "target_mdeg",
                             sequence=np.round(p[idx] * 1000).astype(np.int64))

    def send(sub: str, timeline_col, key: np.ndarray, idx: np.ndarray, color, name: str) -> None:
        idx = idx[np.argsort(key[idx], kind="stable")]
        e = f"{path}/{sub}"
        rec.log(e, rr.SeriesPoints(names=[name], colors=[color], marker_sizes=[2.0]), static=True)
        rec.send_columns(e, indexes=[timeline_col(idx)], columns=rr.Scalars.columns(scalars=r[idx]))

    for d, word, color in ((1, "plus", _BLUE), (-1, "minus", _RED)):
        idx = np.flatnonzero((s == d) & ~bad)
        if idx.size:
            name = f"residual, approach {'+' if d > 0 else '-'} / {unit}"
            send(f"vs_time_{word}", by_time, tt, idx, color, name)
            send(f"vs_target_{word}", by_target, p, idx, color, name)
    if rows.size:
        send("outliers_vs_time", by_time, tt, rows, _BLACK, f"outlier / {unit}")
        send("outliers_vs_target", by_target, p, rows, _BLACK, f"outlier / {unit}")


def log_markdown(rec, name: str, markdown: str) -> None:
    """Log a markdown document (a table of results) under ``reports/<name>``."""
    import rerun as rr

    rec.log(f"{REPORTS}/{name}", rr.TextDocument(markdown, media_type="text/markdown"),
            static=True)


def errors_markdown(errors: Mapping[str, Mapping]) -> str:
    """Markdown table of the MFB scenario's ``errors`` object.

    ``errors``: ``{symbol: {injected, identified, u95}}`` (report units);
    the unit of each row comes from the ISO symbol (µm or µrad).
    """
    lines = ["| symbol | unit | injected | identified | U95 (k=2) |", "|---|---|---|---|---|"]
    for name, d in errors.items():
        sym = iso_symbol(name)
        unit = "µrad" if sym.angular else "µm"
        cells = [_fmt(d.get(k)) for k in ("injected", "identified", "u95")]
        lines.append(f"| {sym.name} | {unit} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def findings_markdown(report: Mapping) -> str:
    """Markdown summary of a discovery report (keys of probe-log.md, 'Discovery report')."""
    base = report.get("baseline", {})
    lines = [f"**cause: {report.get('cause', 'none')}**", "",
             f"baseline `{base.get('model', '?')}`: n = {base.get('n', '?')}, "
             f"rms = {_fmt(base.get('rms_um'))} µm", "",
             "| cause | rms / µm | params | evidence |", "|---|---|---|---|"]
    for f in report.get("findings", []):
        params = ", ".join(f"{k} = {_fmt(v)}" for k, v in (f.get("params") or {}).items())
        ev = ", ".join(f"{k} = {_fmt(v)}" for k, v in (f.get("evidence") or {}).items())
        lines.append(f"| {f.get('cause', '?')} | {_fmt(f.get('rms_um'))} | {params} | {ev} |")
    return "\n".join(lines)


def _fmt(v) -> str:
    if v is None:
        return "–"
    if isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool):
        return f"{float(v):.4g}"
    if isinstance(v, (list, tuple)) and len(v) > 6:
        return f"[{len(v)} values]"
    return str(v)
