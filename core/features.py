"""One feature of a probe log: fitted, corrected for the stylus, with U95 and form.

:func:`fit_log_feature` takes the valid touches of a log (optionally one
``feature`` or one ``setup``), fits a plane, sphere, circle (in XY) or
cylinder to the reported stylus-tip centres (:mod:`core.fit`) and turns the
tip-centre feature into the surface: a plane moves by the stylus radius
``r`` against its outward normal; a radius shrinks by ``r`` on a ball,
boss or pin (the log's normals point away from the centre) and grows by
``r`` in a bore or hollow (normals point at the centre). Position and
orientation do not depend on ``r``.

The radius is the caller's (``stylus_r_mm``: a qualified, effective radius
wins over the nominal one a log carries), else the log's (its
``stylus_r_mm`` column, else its metadata). A log that says none and no
radius given is refused (:class:`NoStylusRadius`): a fit with a wrong
radius is wrong by that radius, and nothing in the fit would show it.

A fit the touches cannot tell is refused (:class:`core.exceptions.FitError`, naming the feature and the
set-up; review31 F1): a plane whose nominal tip centres lie on one line in the surface, a cylinder whose lie
at one height along the axis (at the log's printing step, :data:`ONE_LINE_QUANTA`), and any fit whose outward
normal at a touch is more than :data:`NORMAL_AGREE_MAX_DEG` from the log's normal of that touch (a boss touched
round one height is not a plane; touches from above are not a circle). The largest angle accepted is
``FeatureReport.normal_angle_deg``.

Each parameter comes with its U95: Student's t on the fit's own covariance
(:func:`core.fit.u95`, the touches' scatter), never below what the log's
printing allows (:func:`core.fit.rounding_u95` of the measured columns'
printed steps, :func:`printing_steps_mm`; session 32, review31e F3: a perfect
wall printed to 3 decimals fitted with zero residual and a U95 of 1e-25 um),
and the feature with its form deviation
(:func:`core.fit.form_deviation`, peak-to-valley about the least-squares
feature). Units: mm, um, urad, as the field names say; frame: the machine
frame R of the log.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from . import fit as F
from .exceptions import ConfigError, FitError
from .probelog import ProbeLog

KINDS = ("plane", "sphere", "circle", "cylinder")


@dataclass(frozen=True)
class FeatureReport:
    """A fitted feature of a log.

    Attributes
    ----------
    kind : str
        ``plane``, ``sphere``, ``circle`` (in the XY plane) or ``cylinder``.
    n : int
        Touches used.
    rows : (n,) int
        Their 0-based rows in the log.
    values : dict[str, float or list]
        The surface feature: ``point_mm`` / ``normal`` (plane), ``centre_mm``,
        ``radius_mm`` (sphere, circle), ``point_mm``, ``axis``, ``radius_mm``
        (cylinder); ``side`` (``outside``: ball, boss, pin; ``inside``: bore).
    u95 : dict[str, float]
        U95 of each fitted parameter, unit in the name (``offset_n_um``,
        ``tilt_u_urad``, ``centre_x_um``, ``radius_um``, ...): the larger of
        ``u95_scatter`` and ``u95_rounding`` (NaN where the scatter's is: an
        exact fit, no degree of freedom).
    form_um : float
        Form deviation (flatness, sphericity, roundness, cylindricity), um.
    rms_um : float
        RMS of the residuals, um.
    residuals_um : (n,) float
        Signed orthogonal residual of each touch (for a plane: its height
        above the least-squares plane along the normal), um.
    stylus_r_mm : float
        Stylus radius applied.
    dof : int
        Degrees of freedom of the fit.
    stylus_r_source : str
        Where the radius came from: ``given``, ``column`` (the log's
        ``stylus_r_mm`` column) or ``metadata`` (its ``stylus_r_mm`` line).
    log_stylus_r_mm : float or None
        The radius the log says (column or metadata), ``None`` when it says none.
    normal_angle_deg : float
        Largest angle, deg, between the fitted surface's outward normal at a touch and the log's normal of
        that touch (at most :data:`NORMAL_AGREE_MAX_DEG`: a larger one is refused).
    u95_scatter : dict[str, float]
        The Student-t U95 of the touches' scatter (:func:`core.fit.u95`), keys as ``u95``.
    u95_rounding : dict[str, float]
        The U95 the printing step allows at best (:func:`core.fit.rounding_u95`), keys as ``u95``; 0 for a log
        printed at full precision.
    printing_step_mm : tuple of float
        The step the fitted coordinates were printed to, mm (``X_mm``, ``Y_mm``, ``Z_mm``; a circle ``X_mm``,
        ``Y_mm``): :func:`printing_steps_mm`.
    """

    kind: str
    n: int
    rows: np.ndarray
    values: dict
    u95: dict
    form_um: float
    rms_um: float
    residuals_um: np.ndarray
    stylus_r_mm: float
    dof: int
    stylus_r_source: str = "given"
    log_stylus_r_mm: float | None = None
    normal_angle_deg: float = math.nan
    u95_scatter: dict | None = None
    u95_rounding: dict | None = None
    printing_step_mm: tuple = ()


class NoStylusRadius(ConfigError):
    """The log says no stylus radius (no ``stylus_r_mm`` column or metadata) and none was given."""


class MixedRows(ConfigError):
    """The valid touches chosen span more than one set-up or feature (review30 F1: a pin's 8 set-ups
    fitted as one circle gave a 197 mm radius for a 6 mm pin, exit 0).

    ``spans`` maps the column (``setup``, ``feature``) to the values found, in :func:`name_order`; the message
    names them and the keyword that picks one (a caller with other names for it, like the CLI's
    ``--setup``, builds its own line from ``spans``).
    """

    def __init__(self, source: str, spans: dict[str, list[str]]):
        self.source, self.spans = source, spans
        super().__init__(f"{source}: {mixed_rows_text(spans)}; pick one with "
                         + " and ".join(f"{c}=NAME" for c in spans))


#: Values named in a refusal of mixed rows before "...": enough to recognise the log's naming.
MIXED_SHOWN = 6

#: Largest angle, deg, between the fitted surface's outward normal at a touch and the log's normal of that touch
#: that a fit accepts (review31 F1: a wall probed along one height was fitted as the horizontal plane through the
#: touches, its normal at 90 deg to every touch's, flatness and U95 0, exit 0; a boss probed round one height the
#: same). The log's normals are the plan's: a part set up off its nominal place turns them by about its offset
#: over the feature's radius (1 mm on a 4 mm pin-and-tip radius: 14 deg), so 30 deg leaves room for a real
#: set-up and still refuses the fits that do not describe the probed surface (90 deg for those two).
NORMAL_AGREE_MAX_DEG = 30.0

#: A plan's nominal tip centres within this many of the log's printing step (the step its text printed ``Xn_mm``,
#: ``Yn_mm``, ``Zn_mm`` to, the coarsest, where it records them: :data:`TEXT_STEPS`; else
#: ``core.probelog.decimal_quantum`` of the rows' nominal and measured coordinates, at most
#: ``ONE_LINE_STEP_MAX_MM``) of one line in the surface
#: (plane) or of one height along the axis (cylinder) probe one line: rounding to the step moves a point by at
#: most ``sqrt(3)/2`` steps, so 2 steps is rounding, not a second direction.
ONE_LINE_QUANTA = 2.0
#: mm: the coarsest printing step the one-line test believes (controllers print 3 to 6 decimals of a mm). A
#: hand-written log whose values are all whole mm reads as printed to 1 mm; without the cap its 2 mm would
#: refuse a wall probed at two heights 1 mm apart.
ONE_LINE_STEP_MAX_MM = 1e-3
#: Relative floor of the one-line test (a log printed at full precision): ``FitTolerances.cond_max``'s 1e-8.
ONE_LINE_REL = 1e-8
#: Session 32 (fitq32, review31e F3): every U95 of ``vmt fit`` is at least what the log's printing step allows
#: (:func:`core.fit.rounding_u95` of the steps :func:`printing_steps_mm` reads): a wall printed to 3 decimals whose
#: touches share one printed X fitted with zero residual and a U95 of 1e-25 um, where its offset is unknown by up to
#: the half step (0.5 um). False: the scatter's Student-t U95 alone (the behaviour before).
ROUNDING_FLOOR = True
#: Session 32 (fitq32): the printing step of a column comes from the log's text where it records one
#: (:attr:`core.probelog.ProbeLog.text_steps`: ``48.000`` is printed to 1 um, where its value alone reads as whole
#: mm); a column whose every cell is written without decimals (a step of 1 mm read from ``48``, hand-written) is an
#: unknown step, read from the values as before. False: the values' step alone (the one-line test before).
TEXT_STEPS = True


def name_order(name: str) -> tuple:
    """Sort key for set-up and feature names, numbers as numbers (session 30: ``vmt fit`` listed
    ``C137`` before ``C31`` and set-up ``10`` before ``2``, sorted as text).

    A name that is a finite number (``2``, ``-30``, ``7.5``) sorts by its value, before every other
    name; any other by its runs of digits as integers and the text between them as text
    (``C2 < C31 < C137``, ``pin2 < pin10``); the name itself breaks ties (``C01``, ``C1``).
    """
    try:
        v = float(name)
    except ValueError:
        v = math.nan
    if math.isfinite(v):
        return (0, v, (), name)
    parts = re.split(r"(\d+)", name)      # text, digits, text, ...: digits at the odd places
    return (1, 0.0, tuple(int(q) if i % 2 else q for i, q in enumerate(parts)), name)


def mixed_rows_text(spans: dict[str, list[str]]) -> str:
    """``the valid touches span 8 set-ups (C0, C45, ...) and 2 features (a, b): a fit takes one feature
    of one set-up``, for :class:`MixedRows`."""
    noun = {"setup": ("set-up", "set-ups"), "feature": ("feature", "features")}
    parts = []
    for col, vals in spans.items():
        shown = ", ".join(repr(v) if v == "" else v for v in vals[:MIXED_SHOWN])
        more = ", ..." if len(vals) > MIXED_SHOWN else ""
        parts.append(f"{len(vals)} {noun[col][1]} ({shown}{more})")
    return ("the valid touches span " + " and ".join(parts)
            + ": a fit takes the touches of one feature in one set-up")


def log_stylus_r_mm(log: ProbeLog, rows: np.ndarray) -> tuple[float | None, str]:
    """The stylus radius the log says for ``rows``, mm, and where (``column``, ``metadata``); ``(None, "")``.

    Raises
    ------
    ConfigError
        The rows' radii differ; metadata that is not a finite number >= 0.
    """
    if log.has("stylus_r_mm"):
        rows = np.arange(log.n)[rows]
        r = log.col("stylus_r_mm")[rows].astype(float)
        known = np.isfinite(r)
        if known.any():  # (an empty cell holds the metadata's radius: core.probelog reads it so)
            first = int(np.argmax(known))
            if not known.all():  # review31 F9: one empty cell, no metadata, dropped the column's radius
                k = int(np.argmin(known))
                raise ConfigError(f"{log.source}: row {rows[k]}: stylus_r_mm is empty and there is no stylus_r_mm "
                                  f"metadata, but row {rows[first]} of this feature has {r[first]:g} mm: give "
                                  "every touch its radius (or the metadata line)")
            if np.ptp(r) > 1e-9:
                k = int(np.argmax(np.abs(r - r[first]) > 1e-9))
                meta = log.meta.get("stylus_r_mm", "")
                raise ConfigError(f"{log.source}: the touches of this feature have different stylus radii "
                                  f"(row {rows[first]}: {r[first]:g} mm, row {rows[k]}: {r[k]:g} mm"
                                  + (f"; an empty stylus_r_mm cell is the metadata's {meta} mm)" if meta else ")"))
            return float(r[first]), "column"
    if "stylus_r_mm" not in log.meta:
        return None, ""
    try:
        v = float(log.meta["stylus_r_mm"])
    except ValueError:
        v = float("nan")
    if not (np.isfinite(v) and v >= 0):
        raise ConfigError(f"{log.source}: metadata stylus_r_mm {log.meta['stylus_r_mm']!r} is not a finite "
                          "number >= 0")
    return v, "metadata"


def _u95_named(u95: dict, units: dict) -> dict:
    """``{name: U95}`` (m, rad) of a fit with each name's unit: ``{offset_n_um: ...}``."""
    out = {}
    for name, v in u95.items():
        scale, unit = units.get(name, (1e6, "um"))
        out[f"{name}_{unit}"] = v * scale
    return out


def _side(p_m: np.ndarray, n: np.ndarray, centre_m: np.ndarray, axis=None) -> str:
    r = p_m - centre_m
    if axis is not None:
        r = r - np.outer(r @ axis, axis)
    s = np.einsum("ij,ij->i", r, n)
    return "outside" if np.sum(s) >= 0 else "inside"


def _which(log: ProbeLog, rows: np.ndarray) -> str:
    """``feature wallE, set-up C0`` of the rows (the names a refusal gives), '' when the log names neither."""
    out = []
    for col, noun in (("feature", "feature"), ("setup", "set-up")):
        if log.has(col):
            v = str(log.col(col)[rows[0]])
            if v:
                out.append(f"{noun} {v}")
    return ", ".join(out)


def _text_step(log: ProbeLog, col: str) -> float | None:
    """The step the log's text printed ``col`` to, mm; None where it records none (a log built in memory) or
    the column holds no decimal at all (``48``: an unknown step, not 1 mm) (:data:`TEXT_STEPS`)."""
    q = log.text_steps.get(col) if TEXT_STEPS else None
    return q if q is not None and q < 1.0 else None


def printing_steps_mm(log: ProbeLog, rows: np.ndarray, cols=("X_mm", "Y_mm", "Z_mm")) -> np.ndarray:
    """The step each column of ``cols`` was printed to over ``rows``, mm (0: exact, full precision).

    The text's step where the log records one (:func:`_text_step`: ``48.000`` printed to 1 um); else the
    values' (:func:`core.probelog.decimal_quantum`, the fewest decimals that write them), at most
    :data:`ONE_LINE_STEP_MAX_MM` (the values alone read ``48.000`` as whole mm).
    """
    from .probelog import decimal_quantum

    out = []
    for c in cols:
        q = _text_step(log, c)
        out.append(q if q is not None else min(decimal_quantum(log.col(c)[rows]), ONE_LINE_STEP_MAX_MM))
    return np.array(out, dtype=float)


def _one_line_tol(printed_mm: np.ndarray, spread_mm: float, q_text: float | None = None) -> tuple[float, str]:
    """The one-line tolerance, mm, of coordinates printed to the step of ``printed_mm`` (the rows' nominal and
    measured coordinates; ``q_text``, where given, the step the text printed the nominal columns to), and how it
    reads; ``spread_mm`` the nominal centres' RMS spread (``ONE_LINE_REL``)."""
    from .probelog import decimal_quantum

    q = q_text if q_text is not None else min(decimal_quantum(printed_mm), ONE_LINE_STEP_MAX_MM)
    rel = ONE_LINE_REL * spread_mm
    if q > 0 and ONE_LINE_QUANTA * q >= rel:
        return ONE_LINE_QUANTA * q, f"{ONE_LINE_QUANTA:g} x the log's printing step {q:g} mm"
    return rel, f"{ONE_LINE_REL:g} of their spread"


def _check_spans(kind: str, pn_mm: np.ndarray, p_mm: np.ndarray, n: np.ndarray, who: str,
                 q_text: float | None = None) -> None:
    """Refuse a plane whose touches' nominal tip centres lie on one line in the surface, or a cylinder whose
    lie at one height along the axis the normals leave (review31 F1). The plan's nominals are free of the
    probing noise that hides the line in the measured points (the wall's 0.3 um along x against 80 mm: condition
    number 3e5, under ``FitTolerances.cond_max``)."""
    X = pn_mm - pn_mm.mean(axis=0)
    spread = float(np.sqrt(np.mean(np.einsum("ij,ij->i", X, X))))
    if not spread > 0:
        return                                   # one point repeated: the fit's own refusal says it
    tol, how = _one_line_tol(np.concatenate([pn_mm, p_mm]), spread, q_text)
    if kind == "plane":
        nm = n.mean(axis=0)
        if np.linalg.norm(nm) > 0.5:             # the touches agree on a normal: the surface's directions
            nm = nm / np.linalg.norm(nm)
            Y = X - np.outer(X @ nm, nm)
        else:                                    # they do not: the normal check below refuses it
            return
        sv = np.linalg.svd(Y, compute_uv=False)
        width = float(sv[1] / np.sqrt(len(Y)))   # RMS distance from their best line within the surface
        if width <= tol:
            raise FitError(f"plane fit ({who}): the touches lie on one line: a plane needs two heights / two "
                           f"directions (the nominal tip centres within {width:.3g} mm RMS of one line in the "
                           f"surface, at most {how})")
    elif kind == "cylinder":
        _, sv, Vt = np.linalg.svd(n, full_matrices=False)
        a = Vt[-1]                               # the direction the normals are most nearly perpendicular to
        if float(np.sqrt(np.mean((n @ a) ** 2))) > math.sin(math.radians(NORMAL_AGREE_MAX_DEG)):
            return                               # no common axis: the normal check below says so
        h = X @ a
        rms_h = float(np.sqrt(np.mean(h**2)))
        if rms_h <= tol:
            raise FitError(f"cylinder fit ({who}): the touches lie at one height along the axis: a cylinder needs "
                           f"touches round it at two heights or more (the nominal tip centres' heights along "
                           f"({a[0]:.3f}, {a[1]:.3f}, {a[2]:.3f}) within {rms_h:.3g} mm RMS, at most {how}); "
                           "one height is a circle: vmt fit circle")


def _normal_angles(kind: str, f, p: np.ndarray, n: np.ndarray, side: str | None) -> np.ndarray:
    """Angle, deg, between the fitted surface's outward normal at each touch and the log's normal of it."""
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    if kind == "plane":
        s = np.broadcast_to(f.normal, n.shape)
    else:
        if kind == "sphere":
            r = p - f.centre
        elif kind == "circle":
            r = np.column_stack([p[:, :2] - f.centre, np.zeros(len(p))])
        else:
            r = p - f.point
            r = r - np.outer(r @ f.axis, f.axis)
        with np.errstate(invalid="ignore", divide="ignore"):   # a touch on the centre or axis: nan, refused
            s = r / np.linalg.norm(r, axis=1, keepdims=True) * (1.0 if side == "outside" else -1.0)
    # atan2 of sine and cosine: arccos near 1 keeps only sqrt(eps), 1e-6 deg
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(s, n), axis=1), np.einsum("ij,ij->i", s, n)))


def _check_normals(kind: str, ang: np.ndarray, who: str, log: ProbeLog, rows: np.ndarray) -> None:
    """Refuse a fit whose surface normal is more than ``NORMAL_AGREE_MAX_DEG`` from a touch's normal in the log."""
    i = int(np.argmax(ang))
    if not ang[i] <= NORMAL_AGREE_MAX_DEG:
        tg = str(log.col("target")[rows[i]]) if log.has("target") else f"row {rows[i]}"
        why = {"plane": "the touches do not face one way (a wall probed along one height, or a boss or bore round "
                        "one height, is not a plane of them)",
               "sphere": "the touches do not face away from (or towards) one centre",
               "circle": "the touches do not face away from (or towards) one centre in XY",
               "cylinder": "the touches do not face away from (or towards) one axis"}[kind]
        raise FitError(f"{kind} fit ({who}): the fitted {kind}'s normal is at {ang[i]:.1f} deg to the log's normal "
                       f"of touch {tg} ({int(np.sum(ang > NORMAL_AGREE_MAX_DEG))} of {len(ang)} touches beyond "
                       f"{NORMAL_AGREE_MAX_DEG:g} deg): {why}")


def fit_log_feature(log: ProbeLog, kind: str, *, feature: str | None = None,
                    setup: str | None = None, stylus_r_mm: float | None = None) -> FeatureReport:
    """Fit a feature to the valid touches of ``log``.

    Parameters
    ----------
    log : ProbeLog
        A campaign log (reported positions, nominal normals).
    kind : {"plane", "sphere", "circle", "cylinder"}
    feature, setup : str or None
        Use only the rows of this ``feature`` / ``setup``.
    stylus_r_mm : float or None
        Stylus tip radius, mm (0: a pin or a tool as the probe); ``None``: the log's.

    Raises
    ------
    NoStylusRadius
        ``stylus_r_mm`` is ``None`` and the log says no radius.
    MixedRows
        The valid touches chosen span more than one set-up or feature
        (a ``ConfigError``: choose one with ``setup`` / ``feature``).
    ConfigError
        Unknown kind, an unknown feature or set-up, a plan instead of a log,
        a radius that is not a finite number >= 0.
    FitError
        Too few or degenerate points (from :mod:`core.fit`).
    """
    if kind not in KINDS:
        raise ConfigError(f"feature kind {kind!r}: expected one of {', '.join(KINDS)}")
    if log.n and log.is_plan:
        raise ConfigError(f"{log.source}: is a plan (measured columns empty), not a campaign")
    mask = log.ok.copy()
    for col, want in (("feature", feature), ("setup", setup)):
        if want is not None:
            have = log.col(col).astype(str)
            if want not in set(have):
                known = ", ".join(sorted(set(have[log.ok]), key=name_order))[:200]
                raise ConfigError(f"{log.source}: no {col} {want!r} (valid touches have: {known})")
            mask &= have == want
    spans = {}
    for col in ("setup", "feature"):
        if log.has(col):
            vals = sorted(set(log.col(col).astype(str)[mask]), key=name_order)
            if len(vals) > 1:
                spans[col] = vals
    if spans:
        raise MixedRows(str(log.source), spans)
    rows = np.flatnonzero(mask)
    if rows.size == 0:
        raise FitError(f"{log.source}: no valid touch to fit")
    p = log.positions_mm()[rows] * 1e-3
    n = log.normals()[rows]
    said, where = log_stylus_r_mm(log, rows)
    if stylus_r_mm is not None:
        r_st = float(stylus_r_mm)
        if not (np.isfinite(r_st) and r_st >= 0):
            raise ConfigError(f"stylus radius {stylus_r_mm!r} mm: need a finite number >= 0")
        where = "given"
    elif said is None:
        raise NoStylusRadius(f"{log.source}: says no stylus radius (no stylus_r_mm column or metadata); "
                             "a fit without the right one is wrong by it")
    else:
        r_st = said
    who = _which(log, rows) or "the touches"
    if kind in ("plane", "cylinder"):
        qn = [_text_step(log, c) for c in ("Xn_mm", "Yn_mm", "Zn_mm")]   # the nominals' rounding, where the text says
        _check_spans(kind, log.nominals_mm()[rows], p * 1e3, n, who, None if None in qn else max(qn))
    n_mean = n.mean(axis=0)
    if kind == "plane":
        f = F.fit_plane(p, normal_hint=n_mean if np.linalg.norm(n_mean) > 0.5 else None)
        pt = f.point - r_st * 1e-3 * f.normal
        vals = {"point_mm": (pt * 1e3).tolist(), "normal": f.normal.tolist()}
        units = {"tilt_u": (1e6, "urad"), "tilt_v": (1e6, "urad")}
        res = f.residuals
    elif kind == "sphere":
        f = F.fit_sphere(p)
        side = _side(p, n, f.centre)
        R = f.radius * 1e3 + (-r_st if side == "outside" else r_st)
        vals = {"centre_mm": (f.centre * 1e3).tolist(), "radius_mm": R, "side": side}
        units = {}
        res = f.residuals
    elif kind == "circle":
        f = F.fit_circle_2d(p[:, :2])
        side = _side(p[:, :2], n[:, :2], f.centre)
        R = f.radius * 1e3 + (-r_st if side == "outside" else r_st)
        vals = {"centre_mm": (f.centre * 1e3).tolist(), "radius_mm": R, "side": side,
                "z_mm": float(np.mean(p[:, 2]) * 1e3)}
        units = {}
        res = f.residuals
    else:
        f = F.fit_cylinder(p)
        side = _side(p, n, f.point, f.axis)
        R = f.radius * 1e3 + (-r_st if side == "outside" else r_st)
        vals = {"point_mm": (f.point * 1e3).tolist(), "axis": f.axis.tolist(), "radius_mm": R,
                "side": side}
        units = {"tilt_u": (1e6, "urad"), "tilt_v": (1e6, "urad")}
        res = f.residuals
    ang = _normal_angles(kind, f, p, n, vals.get("side"))
    _check_normals(kind, ang, who, log, rows)
    u_s = _u95_named(F.u95(f), units)
    planar = kind == "circle"
    q = printing_steps_mm(log, rows, ("X_mm", "Y_mm") if planar else ("X_mm", "Y_mm", "Z_mm"))
    u_r = _u95_named(F.rounding_u95(f, p[:, :2] if planar else p, q * 1e-3 if ROUNDING_FLOOR else 0.0), units)
    u = {k: v if np.isnan(v) else max(v, u_r[k]) for k, v in u_s.items()}
    return FeatureReport(kind=kind, n=int(rows.size), rows=rows, values=vals, u95=u, u95_scatter=u_s,
                         u95_rounding=u_r, printing_step_mm=tuple(q.tolist()),
                         form_um=F.form_deviation(f) * 1e6, rms_um=f.rms * 1e6,
                         residuals_um=np.asarray(res) * 1e6, stylus_r_mm=r_st, dof=int(f.dof),
                         stylus_r_source=where, log_stylus_r_mm=said, normal_angle_deg=float(np.max(ang)))
