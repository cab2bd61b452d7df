"""Reference data sets with known least-squares answers (ISO 10360-6 style).

Each set is built backwards from its answer: choose the exact feature,
place points on it, then add residuals that are orthogonal to the column
space of the fit's Jacobian at that feature (random residuals projected
onto the null space of ``J^T``). The first-order optimality condition
``J^T r = 0`` then holds at the chosen feature, and with residuals of a few
µm on features of mm to dm size it is the (unique, nearby) least-squares
solution. Residuals are applied along the feature's own normal directions
(plane normal; radial; for a line the two directions across it; for a
circle in space height and radial), so each point's orthogonal residual is
exactly the component that was added.

For the circle in space the Jacobian depends on the residuals themselves,
but the residual-dependent terms cancel in ``J^T r`` (the height-tilt term
``h (rho e.u)`` and the radial-tilt term ``-h drho (e.u)`` sum to
``R h (e.u)``), so projecting with the Jacobian at the on-feature points is
still exact.

Orientations are random (uniform on the sphere), with a share of exactly
and nearly axis-aligned directions; positions are offset up to 1 m per
coordinate; arcs are full or partial (90-120 degrees by default); residual
RMS is 1-5 µm. Everything is in metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .exceptions import ConfigError
from .fit import _perp_basis, _rj_ball, _rj_circle3, _rj_cylinder, _rj_line, _rj_plane, orient

__all__ = ["KINDS", "RefSet", "make_refset", "make_refsets", "null_space_residuals"]

#: Feature kinds, in the order of :mod:`core.fit`.
KINDS: tuple[str, ...] = ("plane", "line", "circle2d", "circle3d", "sphere", "cylinder")

_N_RANGE = {"plane": (4, 40), "line": (3, 40), "circle2d": (5, 40), "circle3d": (5, 40),
            "sphere": (6, 40), "cylinder": (8, 60)}


@dataclass(frozen=True)
class RefSet:
    """One reference data set and the exact least-squares answer.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    points : (n, 3) float, or (n, 2) for ``circle2d``
        m.
    position : (3,) or (2,) float
        What the fit reports as position: plane - centroid projected onto
        it; line / cylinder - axis point nearest the centroid; circle /
        sphere - centre. m.
    direction : (3,) float or None
        Unit normal / direction / axis with :func:`core.fit.orient` sign;
        None for ``circle2d`` and ``sphere``.
    radius : float
        m; NaN for plane and line.
    residuals : (n,) float
        The orthogonal residuals the fit must report, m.
    arc_rad : float
        Angular span of the points around the axis (circle, cylinder) or the
        cap half-angle (sphere), rad; NaN for plane and line.
    """

    kind: str
    points: np.ndarray
    position: np.ndarray
    direction: np.ndarray | None
    radius: float
    residuals: np.ndarray
    arc_rad: float


def null_space_residuals(J, e):
    """Project ``e`` onto the null space of ``J^T`` (orthogonal to range(J)).

    Parameters
    ----------
    J : (m, k) float
        Jacobian of the residuals at the solution.
    e : (m,) float
        Raw residuals.

    Returns
    -------
    (m,) float
        ``e - U U^T e`` with ``U`` an orthonormal basis of range(J).
    """
    U, sv, _ = np.linalg.svd(J, full_matrices=False)
    U = U[:, sv > sv[0] * 1e-12]
    e = e - U @ (U.T @ e)
    return e - U @ (U.T @ e)  # second pass: orthogonal to rounding


def _direction(rng):
    """Random unit vector; 25 % of the time (nearly) along an axis or diagonal."""
    u = rng.random()
    if u < 0.25:
        base = [np.eye(3)[rng.integers(3)], np.array([1.0, -1.0, 0.0]), np.array([1.0, 1.0, -1.0])]
        d = base[rng.integers(len(base))] * rng.choice([-1.0, 1.0])
        d = d / np.linalg.norm(d)
        if u < 0.15:  # nearly aligned: tilted by 1e-9 .. 1e-4 rad
            B = _perp_basis(d)
            d = d + 10 ** rng.uniform(-9, -4) * B[0]
    else:
        d = rng.normal(size=3)
    return d / np.linalg.norm(d)


def _angles(rng, n, arc):
    start = rng.uniform(0, 2 * np.pi)
    if arc >= 2 * np.pi:
        th = start + np.sort(rng.uniform(0, 2 * np.pi, n))
    else:  # both ends of the arc included
        th = start + np.concatenate([[0.0, arc], rng.uniform(0, arc, n - 2)])
    return th


def _scaled(e, rng, residual_rms, n):
    """Scale ``e`` so that the RMS orthogonal distance over the n points is drawn
    from ``residual_rms`` (line and circle in space: 2 components per point)."""
    lo, hi = residual_rms
    rms = np.sqrt(np.sum(e**2) / n)
    return e * (rng.uniform(lo, hi) / rms) if rms > 0 else e


def make_refset(kind: str, rng: np.random.Generator, *, n: int | None = None,
                offset_max: float = 1.0, residual_rms: tuple[float, float] = (1e-6, 5e-6),
                partial_arc: tuple[float, float] = (np.pi / 2, 2 * np.pi / 3),
                p_partial: float = 0.6) -> RefSet:
    """Build one reference set of ``kind`` with a known least-squares answer.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    rng : np.random.Generator
    n : int, optional
        Number of points; default drawn from a per-kind range.
    offset_max : float
        Feature position uniform in ``[-offset_max, offset_max]`` per
        coordinate, m.
    residual_rms : (2,) float
        RMS of the orthogonal residuals (distances), drawn uniformly in this
        range, m.
    partial_arc : (2,) float
        Span of partial arcs (circle, cylinder), rad; default 90-120 deg.
    p_partial : float
        Probability of a partial arc (else a full circle / sphere).

    Returns
    -------
    RefSet
    """
    if kind not in KINDS:
        raise ConfigError(f"kind must be one of {KINDS}, got {kind!r}")
    if n is None:
        n = int(rng.integers(*_N_RANGE[kind], endpoint=True))
    if n < _N_RANGE[kind][0]:
        raise ConfigError(f"n for {kind} must be >= {_N_RANGE[kind][0]}, got {n}")
    dim = 2 if kind == "circle2d" else 3
    off = rng.uniform(-offset_max, offset_max, dim)
    size = 10 ** rng.uniform(np.log10(3e-3), np.log10(0.15))  # radius / half-extent, m
    partial = rng.random() < p_partial
    arc = rng.uniform(*partial_arc) if partial else 2 * np.pi

    return _BUILDERS[kind](rng, n, off, size, partial, arc, residual_rms)


def _plane_set(rng, n, off, size, partial, arc, residual_rms) -> RefSet:
    """Points about a plane through ``off``; position: the centroid projected onto it."""
    d = orient(_direction(rng))
    B = _perp_basis(d)
    ab = rng.uniform(-size, size, (n, 2)) * [1.0, rng.uniform(0.2, 1.0)]
    Q = off + ab @ B[:2]
    r0, J = _rj_plane(off, B, Q)
    e = _scaled(null_space_residuals(J, rng.normal(size=n)), rng, residual_rms, n)
    P = Q + e[:, None] * d
    c = P.mean(axis=0)
    pos = c - ((c - off) @ d) * d  # centroid projected onto the plane
    return RefSet("plane", P, pos, d, np.nan, e, np.nan)


def _line_set(rng, n, off, size, partial, arc, residual_rms) -> RefSet:
    """Points about a 3D line; position: the foot of the centroid on it."""
    d = orient(_direction(rng))
    B = _perp_basis(d)
    t = rng.uniform(-size, size, n)
    Q = off + t[:, None] * d
    _, J = _rj_line(off, B, Q)
    e = _scaled(null_space_residuals(J, rng.normal(size=2 * n)), rng, residual_rms, n)
    P = Q + e[:n, None] * B[0] + e[n:, None] * B[1]
    c = P.mean(axis=0)
    pos = off + ((c - off) @ d) * d
    return RefSet("line", P, pos, d, np.nan, np.hypot(e[:n], e[n:]), np.nan)


def _circle2d_set(rng, n, off, R, partial, arc, residual_rms) -> RefSet:
    """Points about a circle in the plane (full or an arc)."""
    th = _angles(rng, n, arc)
    er = np.column_stack([np.cos(th), np.sin(th)])
    Q = off + R * er
    _, J = _rj_ball(off, R, Q)
    e = _scaled(null_space_residuals(J, rng.normal(size=n)), rng, residual_rms, n)
    return RefSet("circle2d", Q + e[:, None] * er, off, None, R, e, arc)


def _sphere_set(rng, n, off, R, partial, arc, residual_rms) -> RefSet:
    """Points about a sphere, uniform on a cap (partial) or the whole sphere."""
    cap = rng.uniform(np.pi / 3, np.pi / 2) if partial else np.pi
    pole = _direction(rng)
    B = _perp_basis(pole)
    # uniform on the cap: cos(polar) uniform in [cos cap, 1]
    cp = rng.uniform(np.cos(cap), 1.0, n)
    az = rng.uniform(0, 2 * np.pi, n)
    sp = np.sqrt(1 - cp**2)
    er = (sp * np.cos(az))[:, None] * B[0] + (sp * np.sin(az))[:, None] * B[1] + cp[:, None] * B[2]
    Q = off + R * er
    _, J = _rj_ball(off, R, Q)
    e = _scaled(null_space_residuals(J, rng.normal(size=n)), rng, residual_rms, n)
    return RefSet("sphere", Q + e[:, None] * er, off, None, R, e, cap)


def _axis_frame(rng, n, arc):
    """(d, B, er): a random axis, its basis and radial unit vectors at ``n`` angles over ``arc``."""
    d = orient(_direction(rng))
    B = _perp_basis(d)
    th = _angles(rng, n, arc)
    return d, B, np.cos(th)[:, None] * B[0] + np.sin(th)[:, None] * B[1]


def _circle3d_set(rng, n, off, R, partial, arc, residual_rms) -> RefSet:
    """Points about a circle in 3D (out of its plane and radially)."""
    d, B, er = _axis_frame(rng, n, arc)
    Q = off + R * er
    _, J = _rj_circle3(off, B, R, Q)
    e = _scaled(null_space_residuals(J, rng.normal(size=2 * n)), rng, residual_rms, n)
    P = Q + e[:n, None] * d + e[n:, None] * er
    return RefSet("circle3d", P, off, d, R, np.hypot(e[:n], e[n:]), arc)


def _cylinder_set(rng, n, off, R, partial, arc, residual_rms) -> RefSet:
    """Points about a cylinder of length 1-4 radii, heights uniform; position: the centroid's foot on the axis."""
    d, B, er = _axis_frame(rng, n, arc)
    L = R * rng.uniform(1.0, 4.0)
    t = rng.uniform(-L / 2, L / 2, n)
    Q = off + R * er + t[:, None] * d
    _, J = _rj_cylinder(off, B, R, Q)
    e = _scaled(null_space_residuals(J, rng.normal(size=n)), rng, residual_rms, n)
    P = Q + e[:, None] * er
    c = P.mean(axis=0)
    pos = off + ((c - off) @ d) * d
    return RefSet("cylinder", P, pos, d, R, e, arc)


#: The builder of each kind: ``(rng, n, offset, size, partial, arc, residual_rms) -> RefSet``.
_BUILDERS = {"plane": _plane_set, "line": _line_set, "circle2d": _circle2d_set, "sphere": _sphere_set,
             "circle3d": _circle3d_set, "cylinder": _cylinder_set}


def make_refsets(kind: str, count: int, rng: np.random.Generator, **kw) -> list[RefSet]:
    """``count`` independent reference sets of ``kind`` (see :func:`make_refset`).

    Parameters
    ----------
    kind : str
    count : int
    rng : np.random.Generator
    **kw
        Passed to :func:`make_refset`.

    Returns
    -------
    list of RefSet
    """
    return [make_refset(kind, rng, **kw) for _ in range(count)]
