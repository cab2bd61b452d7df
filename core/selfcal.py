"""2D self-calibration of a workpiece on a rotary table (Ibaraki et al., eqs 1-18).

The same nominal target points ``w_p_i`` of a workpiece are probed at ``N_c``
C-axis indexings. Each normal deviation (eq 3)

    dq_ij = n_ij . (p_reported - p_nominal)

is modelled to first order as (eq 14 = eqs 7 + 12 + 13)

    dq_ij = G_i                                     workpiece, eq 7
          - n_ij . [E_X,total, E_Y,total](p_ij)     X/Y axes, eqs 10-12
          - n_ij . [EXC,total(C_j), EYC,total(C_j)] C-axis displacement, eq 13
          - (R90 p_ij) . n_ij * ECC(C_j)            C-axis angle, eq 13

with the X-axis error motions ``EXX``, ``EYX`` tabulated on the x nodes, the
Y-axis motions ``EXY``, ``EYY``, ``ECY`` on the y nodes, bilinear (per-axis
linear) interpolation at the nominal stylus-tip centre ``pn_R`` (eqs 8-11) and
the squareness ``EC0Y`` (eq 4). ``n . (R90 p)`` is the same for the tip
centre and the contact point because ``n`` is perpendicular to ``R90 n``.

Signs: every value is in the ISO 230-1 convention (CONTRIBUTING.md, "Error
conventions"): the displacement of the tool relative to the workpiece, so
each enters as ``-n . E`` like the linear axes of eq 12. The paper's eq 13
has ``+`` because its ``EXC,total``, ``EYC,total`` and ``ECC`` are the
displacement and rotation of the table (the C axis's moving component); vmt
reports the same quantities with the opposite sign. ``EXC,total(C_j)`` is
the tool's X displacement relative to the part due to the C axis at
``C_j``: on a table-side C, the ISO radial motion ``EXC(C_j)`` minus the
line's position ``EX0C`` (a location error is the position of the axis
average line, whichever side it is on; the part rides on it; on a C carried
by A, plus what A's errors add, :func:`c_centre_note`). ``ECC`` is the
ISO angular positioning error: actual minus commanded C of the tool
relative to the part (with C positive as in eq 1).

Parameter vector (fixed order, names in :attr:`SelfCalDesign.names`)::

    EXX@x (N_x) | EYX@x (N_x) | EXY@y (N_y) | EYY@y (N_y) | ECY@y (N_y) | EC0Y |
    G[target] (N_w) | EXC,total[C] (N_c) | EYC,total[C] (N_c) | ECC[C] (N_c)

Null space and gauge
--------------------
``A`` has exactly eleven null directions for a good design, derived here and
checked numerically in the tests (:func:`null_space`):

- translational (6): tool and table shifted together in X / in Y; the
  constant split EXX/EXY and EYX/EYY; the workpiece shifted in X / in Y in W
  (G changes by ``wn . t``, EXC/EYC,total by ``-R(-C_j) t``);
- rotational (4): the machine frame rotated (EC0Y, EYX slope, all ECC); the
  workpiece rotated in W about the C axis (G by ``n . R90 (p - c)``, all ECC,
  and every set-up's EXC/EYC,total by ``-R90 c``); a constant ECY traded for
  an EYX slope; an EXY slope traded for EC0Y;
- scale (1): EXX and EYY slopes with G by ``n . (p - c)`` and every set-up's
  EXC/EYC,total by ``-c`` (a machine scale error is indistinguishable from a
  workpiece scaled about the C axis).

``c = (cx, cy)`` is where the C axis meets the XY plane in R (nominal). The
workpiece's rotation and scale must be taken about a point of W that every
set-up puts in the same place of R, so that ``G`` (one value per target) is
the same in every set-up: the C axis is that point. Worked by hand: a target
at ``u`` from the axis in W is at ``p_j = c + R(-C_j) u`` in set-up j (eq 1
about the axis). Rotating the part by ``phi`` about the axis moves it by
``phi R90 (p_j - c)`` (R90 commutes with R(-C_j)), so ``G`` changes by
``phi n . R90 (p_j - c) = phi wn . R90 u``, the same in every set-up. The
model's ``ECC`` column is a rotation about R's origin, ``-(R90 p) . n``,
so ``ECC = phi`` removes ``phi n . R90 p``; the rest, ``-phi n . R90 c``,
is the same translation ``-phi R90 c`` in every set-up, which
``EXC,total = phi cy``, ``EYC,total = -phi cx`` (entering as ``-n . (EXC,
EYC)``) give back. Check: ``phi [n . R90 (p - c) - n . R90 p + n . R90 c] = 0``.
Scaling the part by ``s`` about the axis moves a target by ``s (p_j - c)``:
``G`` by ``s n . (p - c)`` (the same in every set-up), the EXX and EYY
slopes ``E = s p`` remove ``s n . p``, and ``EXC,total = -s cx``,
``EYC,total = -s cy`` give back ``s n . c``. Translations need no ``c``: a
shift ``t`` in W is ``R(-C_j) t`` in R wherever the axis is. With ``c = 0``
these are the paper's columns; with the axis elsewhere the paper's (rotation
and scale about R's origin) are not null: with C at (22, 0) mm they left
``|A N|`` at 0.04.

``c`` is read from the touches, not given: a target seen at ``C_f`` and at
``C_k`` satisfies ``p_k - c = R(C_f - C_k) (p_f - c)``, so ``(I - R(D)) c =
p_k - R(D) p_f`` with ``D = C_f - C_k``; every touch against its target's
first touch, least squares (``(I - R)^T (I - R) = 2 (1 - cos D) I``, so the
solution is a weighted sum, linear in the touches). ``c`` is taken as 0
where it is within its own standard error (three times the residual's, or
1e3 eps of the positions, whichever is larger) of 0, or where no target is
seen at two angles: the nominal positions then do not place the axis apart
from R's origin, and the columns are the paper's bit for bit
(:func:`c_axis_xy`).

The eleven gauge conditions (eq 16, printed garbled in the paper, and eq 17)
fix them: ``EXX(x_o) = EYX(x_o) = EXY(y_o) = EYY(y_o) = ECY(y_o) = 0`` at the
origin ``x_o = y_o = 0`` (interpolated; the first node when 0 is outside the
grid), ``EXC,total = EYC,total = ECC = 0`` at the reference set-up (the one
whose C is nearest 0), ``EYX(x_N) = 0``, ``EXY(y_N) = 0`` and
``EXX(x_N) = delta_L``. When ``delta_L`` is not given, the scale is unknown:
it is fixed to 0 and the result says so in ``conventions``.

Solving (:func:`core.lsq.solve`) scales the columns, eliminates the equality
constraints, checks the eq 6 count and the rank (dense eigen-decomposition
for small problems, sparse LU pivots for large ones) and names every
parameter combination the data cannot identify.

Reproducing the paper
---------------------
Section 6 (cross pocket, 92 targets incl. two spheres, C = 0, 75, 130, 210
deg, grid -110..110 mm step 22 mm, probing u = 1.38 um)::

    from core.design import example_cross_pocket
    from core.selfcal import Grid
    from core.uncertainty import linear_uncertainty, monte_carlo
    w, wn, ids = example_cross_pocket()
    grid = Grid.regular(-0.110, 0.110, 0.022)
    lin = linear_uncertainty(w, wn, [0, 75, 130, 210], grid)
    mc = monte_carlo(w, wn, [0, 75, 130, 210], grid, runs=1000,
                     rng=np.random.default_rng(1))
    lin.U95[lin.design.slices["G"]].max()  # 20.5 um: G in the gauge of eqs 16-17
    lin.max_form_U95                         # 2.0 um: its form part

This example (arms 90 mm, 8 touches a sphere) is a quick sketch. The paper's
comparison uses the reconstruction in ``sim.artefacts.cross_pocket``
(``vmt scenario cross-pocket-uncertainty``): 6.5 um there in the declared
reading against the paper's 2.1 um, 2.1 um when the spheres' G is taken as
known (docs/papers-selfcal.md).

Fewer angles (0, 75 and 0, 75, 130) reproduce the trend of Fig 18(a, b);
the U of EXC/EYC,total and ECC per angle is Table 2's. With a measured log:
``vmt identify LOG --json OUT --grid-mm -110:110:22 --mc 1000``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import StrEnum

import numpy as np
import scipy.sparse as sp

from .exceptions import ConfigError, IdentifiabilityError, counted
from .lsq import LinearEstimator, column_norms, normal_inverse, remove_span, solve
from .touches import Touches
from .units import DEG, MM, UM

#: Format of :meth:`SelfCalResult.to_report` (what ``vmt identify --json`` writes).
REPORT_FORMAT = "vmt-identify/1"
#: Tolerance (m) for a touch lying on the grid's edge.
EDGE_TOL = 1e-9
#: Largest |n_z| accepted: the model is planar (XY).
NZ_MAX = 0.01

AXIS_SYMBOLS = ("EXX", "EYX", "EXY", "EYY", "ECY")
GAUGE_NAMES = (
    "X translation (tool and table)", "Y translation (tool and table)",
    "EXX/EXY offset split", "EYX/EYY offset split",
    "workpiece X shift", "workpiece Y shift",
    "machine frame rotation", "workpiece rotation",
    "yaw offset vs straightness slope (ECY/EYX or ECX/EXY)", "EXY slope vs EC0Y",
    "scale",
)


def _r(v, nd=4):
    """``v`` rounded to ``nd`` decimals for a report (None stays None)."""
    return None if v is None else round(float(v), nd)


def _fmt_mm(v_m: float) -> str:
    return f"{v_m / MM + 0.0:g}"  # + 0.0: no "-0"


# ---------------------------------------------------------------------------
# grid
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Grid:
    """Nodes of the X- and Y-axis look-up tables (eqs 8-11).

    Attributes
    ----------
    x_m : (N_x,) float
        Strictly increasing x nodes, machine frame, m.
    y_m : (N_y,) float
        Strictly increasing y nodes, machine frame, m.
    """

    x_m: np.ndarray
    y_m: np.ndarray

    def __post_init__(self):
        for nm in ("x_m", "y_m"):
            v = np.asarray(getattr(self, nm), float).ravel()
            if v.size < 2 or not np.all(np.isfinite(v)) or np.any(np.diff(v) <= 0):
                raise ConfigError(f"grid {nm}: needs >= 2 finite strictly increasing nodes, got {v.tolist()}")
            object.__setattr__(self, nm, v)

    @classmethod
    def regular(cls, lo_m: float, hi_m: float, step_m: float, ylo_m=None, yhi_m=None) -> "Grid":
        """Nodes ``lo, lo + step, ..., hi`` in x and (by default the same) in y."""
        if not step_m > 0:
            raise ConfigError(f"grid step must be > 0, got {step_m}")
        ylo_m = lo_m if ylo_m is None else ylo_m
        yhi_m = hi_m if yhi_m is None else yhi_m

        def nodes(a, b):
            n = int(round((b - a) / step_m))
            if n < 1 or abs(a + n * step_m - b) > 1e-9 * max(1.0, abs(b)):
                raise ConfigError(f"grid {a / MM:g}..{b / MM:g} mm is not a whole number of {step_m / MM:g} mm steps")
            return np.round((a + step_m * np.arange(n + 1)) / 1e-9) * 1e-9  # whole nm: 0 is exactly 0

        return cls(nodes(lo_m, hi_m), nodes(ylo_m, yhi_m))

    @classmethod
    def from_extent(cls, p_R: np.ndarray, step_m: float) -> "Grid":
        """Nodes at multiples of ``step_m`` covering ``p_R[:, :2]`` (so 0 is a node line).

        Parameters
        ----------
        p_R : (n, 2+) float
            Points, machine frame, m (the nominal tip centres).
        step_m : float
            Node spacing, m.
        """
        if not step_m > 0:
            raise ConfigError(f"grid step must be > 0, got {step_m}")
        p = np.asarray(p_R, float)
        out = []
        for c in (0, 1):
            lo = np.floor(p[:, c].min() / step_m - 1e-9) * step_m
            hi = np.ceil(p[:, c].max() / step_m + 1e-9) * step_m
            if hi - lo < step_m * 0.5:
                hi = lo + step_m
            out.append(np.round((lo + step_m * np.arange(int(round((hi - lo) / step_m)) + 1)) / 1e-9) * 1e-9)
        return cls(*out)

    @property
    def origin_m(self) -> tuple[float, float]:
        """(x_o, y_o): 0 when inside ``[node_0, node_N)``, else the first node."""
        def o(v):
            return 0.0 if v[0] <= 0.0 < v[-1] else float(v[0])
        return o(self.x_m), o(self.y_m)


def _interp_weights(nodes: np.ndarray, v: np.ndarray):
    """Left node index and weight of the right node (eqs 8, 9)."""
    k = np.clip(np.searchsorted(nodes, v, side="right") - 1, 0, len(nodes) - 2)
    z = (v - nodes[k]) / (nodes[k + 1] - nodes[k])
    return k, z


def _interp_row(nodes: np.ndarray, v: float) -> np.ndarray:
    k, z = _interp_weights(nodes, np.array([v]))
    r = np.zeros(len(nodes))
    r[k[0]] += 1 - z[0]
    r[k[0] + 1] += z[0]
    return r


class Yaw(StrEnum):
    """The yaw that couples the X and Y error maps (eqs 4-5); :data:`YAW_MESSAGES` says how."""

    ECY = "ECY"
    ECX = "ECX"


#: How each :class:`Yaw` enters the model.
YAW_MESSAGES = {
    Yaw.ECY: "X rides on Y: the yaw of Y turns the X stroke, E_Y += x ECY(y), on the y nodes (eq 5, the paper)",
    Yaw.ECX: "Y rides on X: the yaw of X turns the Y stroke, E_X -= y ECX(x), on the x nodes",
}


def yaw_model(value) -> Yaw:
    """``value`` as a :class:`Yaw`; ConfigError naming the two otherwise."""
    try:
        return Yaw(value)
    except ValueError:
        raise ConfigError(f"yaw must be 'ECY' or 'ECX', got {value!r}") from None


# ---------------------------------------------------------------------------
# design
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class SelfCalDesign:
    """The linear model ``dq = A theta`` of eq 15 plus its gauge.

    Attributes
    ----------
    A : scipy.sparse.csr_matrix, (n_touches, n_params)
        Design matrix; theta in m (translations) and rad (rotations).
    names : tuple of str
        Parameter names in column order.
    slices : dict[str, slice]
        Column range of each block: ``EXX``, ``EYX``, ``EXY``, ``EYY``,
        ``ECY`` (or ``ECX``), ``EC0Y``, ``G``, ``EXC``, ``EYC``, ``ECC``;
        with height terms also ``EBC``, ``EAC`` and ``ABBE``.
    grid : Grid
    target_ids, setup_ids : tuple of str
    c_rad : (N_c,) float
        C angle of each set-up, rad.
    ref_setup : int
        Set-up whose C-axis errors the gauge fixes to 0.
    C, d : (11 + h, n_params), (11 + h,) float
        Gauge conditions ``C theta = d`` (eqs 16-17, then the height terms').
    gauge : tuple of str
        The gauge conditions in words (same order as rows of ``C``).
    scale_known : bool
        True when ``delta_L`` was given.
    N : (n_params, 11 + h) float
        Analytic null-space basis, columns named by :data:`GAUGE_NAMES`
        (then the height terms' own, :attr:`HeightTerms.null_names`).
    heights : HeightTerms or None
        The C-axis tilt and Abbe terms of touches at several heights
        (:func:`height_terms`), appended after the paper's parameters; None
        for a planar design.
    """

    A: sp.csr_matrix
    names: tuple
    slices: dict
    grid: Grid
    target_ids: tuple
    setup_ids: tuple
    c_rad: np.ndarray
    ref_setup: int
    C: np.ndarray
    d: np.ndarray
    gauge: tuple
    scale_known: bool
    N: np.ndarray
    yaw: Yaw = Yaw.ECY
    heights: "HeightTerms | None" = None

    @property
    def n_params(self) -> int:
        return len(self.names)

    def to_gauge(self, theta: np.ndarray, delta_L_m: float | None = None) -> np.ndarray:
        """The parameter vector equivalent to ``theta`` that meets this design's gauge.

        Adds the null-space combination ``N alpha`` with ``C (theta + N alpha) =
        d`` so a truth (e.g. the simulator's) can be compared with an
        identification. ``A theta`` is unchanged (exactly, for a truth in the
        model space). ``delta_L_m`` overrides ``d``'s scale value.

        Parameters
        ----------
        theta : (n_params,) float
            Parameters in m / rad, in ``names`` order.
        """
        theta = np.asarray(theta, float)
        if theta.shape != (self.n_params,):
            raise ConfigError(f"theta: expected shape ({self.n_params},), got {theta.shape}")
        d = self.d.copy()
        if delta_L_m is not None:
            d[10] = delta_L_m
        CN = self.C @ self.N
        alpha = np.linalg.solve(CN, d - self.C @ theta)
        return theta + self.N @ alpha


def _setup_angles(touches: Touches) -> np.ndarray:
    c = np.zeros(len(touches.setup_ids))
    for s, sid in enumerate(touches.setup_ids):
        cs = touches.rot_rad[touches.setup == s, 2]
        if np.ptp(cs) > 1e-9:
            rows = touches.row[touches.setup == s]
            k = int(np.argmax(np.abs(cs - cs[0]) > 1e-9))  # the first log row off the set-up's first C
            raise ConfigError(f"set-up {sid!r}: C varies within the set-up ({np.degrees(cs.min()):g}.."
                              f"{np.degrees(cs.max()):g} deg: row {rows[0]} at {np.degrees(cs[0]):g}, row {rows[k]} at "
                              f"{np.degrees(cs[k]):g}); one indexing per set-up")
        c[s] = cs[0]
    return c


def _c_names(setup_ids, c_rad):
    deg = [f"{np.degrees(c):g}" for c in c_rad]
    dup = len(set(deg)) < len(deg)
    return [f"C={d}deg" + (f"#{s}" if dup else "") for d, s in zip(deg, setup_ids)]


#: A carrying rotary axis's location errors (d: translation, w: rotation), C's own, and its error motions
#: (e, eps), per carrier: the terms :func:`c_centre_note` names
_CARRIER_TERMS = {
    "A": ("(0, EY0A, EZ0A)", "(0, EB0A, EC0A)", "(EXA, EYA, EZA)", "(EAA, EBA, ECA)",
          "EY0A alone puts the centre at (0, -EY0A), EB0A alone at (-EB0A (z - z_A), 0)"),
    "B": ("(EX0B, 0, EZ0B)", "(EA0B, 0, EC0B)", "(EXB, EYB, EZB)", "(EAB, EBB, ECB)",
          "EX0B alone puts the centre at (-EX0B, 0), EA0B alone at (0, EA0B (z - z_B))"),
}


def c_centre_note(chain_text: str | None = None) -> str:
    """The report's note on what puts ``EXC``, ``EYC`` on a circle, and where its centre comes from.

    A rotary axis's location errors are relative to the axis carrying it
    (CONTRIBUTING.md, "Error conventions"): on a C that rides on A or B
    (``chain_text``, the log's ``kinematic_chain``, says which) the line the
    circle shows is ``EX0C``, ``EY0C`` plus what the carrier's location
    errors and error motions add at its position, named here (first order;
    ``tests/sim/test_iso_convention.py`` checks the expression against the
    simulator's chain); ``None`` (no chain) says so in words.
    """
    head = ("EXC, EYC are the tool's displacement relative to the part due to the C axis (eq 13's table "
            "displacement with the opposite sign), 0 at the reference set-up: a C line displaced by (dx, dy) in R "
            "at the touches' height z puts them on a circle centred on -(dx, dy), the line as seen from the tool "
            "at the grid origin")
    carrier = None
    if chain_text:
        from .chain import parse_chain

        ch = parse_chain(chain_text)
        if "C" in ch.axes:
            carrier = ch.parent("C")
            if carrier is None:
                return head + "; C sits on the bed: (dx, dy) = (EX0C + EB0C (z - z_C), EY0C - EA0C (z - z_C))"
    if carrier not in _CARRIER_TERMS:
        return (head + ": (EX0C, EY0C) and, on a C carried by another axis, what that axis's location errors and "
                "error motions add at its position (C's location errors are relative to the axis carrying it, "
                "CONTRIBUTING.md \"Error conventions\")")
    d, w, e, eps, example = _CARRIER_TERMS[carrier]
    k = carrier
    return (head + f"; in this chain ({chain_text}) C rides on {k} and its location errors are relative to {k} "
            f"(CONTRIBUTING.md \"Error conventions\"): (dx, dy) are X and Y of d_C + w_C x (P - c_C) + d_{k} + "
            f"w_{k} x (P - c_{k}) - (e_{k} + eps_{k} x (P - c_{k})), with C's location errors d_C = (EX0C, EY0C, 0), "
            f"w_C = (EA0C, EB0C, 0), {k}'s d_{k} = {d}, w_{k} = {w} and its error motions at its position in the "
            f"log e_{k} = {e}, eps_{k} = {eps}; c_C, c_{k} points on the lines, P C's line at height z: {example}")


def yaw_for_chain(chain_text: str | None) -> Yaw:
    """Which yaw couples X and Y in the rigid-body model of a chain: ``"ECY"`` or ``"ECX"``.

    The paper's eqs 4-5 are written for X riding on Y (``V[w-C-A-b-Y-X-Z-(C)-t]``,
    or a table X on a saddle Y): the yaw of Y, ``ECY(y)``, turns the X
    stroke, ``E_Y += x ECY(y)``. When Y rides on X (``[w C' A' b X Y Z (C1) t]``)
    it is the yaw of X that turns the Y stroke: ``E_X -= y ECX(x)``. The axis
    nearer the bed in the branch that holds both is the carrier; ``None`` or a
    chain with X and Y on different branches gives the paper's ``"ECY"``.
    """
    if not chain_text:
        return Yaw.ECY
    from .chain import parse_chain

    ch = parse_chain(chain_text)
    tool, work = list(ch.tool_axes), list(ch.workpiece_axes)
    if "X" in tool and "Y" in tool:  # listed from the bed up: the first is the carrier
        return Yaw.ECY if tool.index("Y") < tool.index("X") else Yaw.ECX
    if "X" in work and "Y" in work:  # listed from the workpiece down: the last is the carrier
        return Yaw.ECY if work.index("Y") > work.index("X") else Yaw.ECX
    return Yaw.ECY


def build_design(touches: Touches, grid: Grid, delta_L_m: float | None = None, *,
                 yaw: Yaw | str = Yaw.ECY, heights: bool | str = False) -> SelfCalDesign:
    """Design matrix of eq 15 for measured or planned touches, with its gauge (eqs 16-17).

    Parameters
    ----------
    touches : Touches
        Uses ``pn_R`` (nominal tip centre, m, R) for the interpolation,
        ``n_R`` (R) for the projections, ``rot_rad[:, 2]`` (C) per set-up
        and the ``setup``/``target`` indices.
    grid : Grid
        Must cover every ``pn_R`` (no extrapolation).
    delta_L_m : float or None
        X-axis positioning error at the last x node (eq 17), m; None = scale
        unknown (fixed to 0 and reported).
    yaw : {"ECY", "ECX"}
        The yaw that couples the axes (:class:`Yaw`, :func:`yaw_for_chain`):
        ``"ECY"`` on the y nodes (the paper: X rides on Y) or ``"ECX"`` on
        the x nodes (Y rides on X, ``E_X -= y ECX(x)``).
    heights : bool or "auto"
        Append the height terms (:func:`height_terms`) when the touches lie
        at more than one Z level (True and "auto" alike; False: the paper's
        planar model whatever the heights).

    Raises
    ------
    ConfigError
        A touch outside the grid, a non-planar normal, mixed C in a set-up,
        a non-finite ``delta_L_m``, a bad ``heights``.
    """
    yaw = yaw_model(yaw)
    _check_touches(touches, grid)
    if delta_L_m is not None and not np.isfinite(delta_L_m):
        raise ConfigError(f"delta_L must be finite, got {delta_L_m}")
    c_rad = _setup_angles(touches)
    slices, names = _parameters(touches, grid, c_rad, yaw)
    A = _eq14_matrix(touches, grid, slices, yaw)
    C, d, gauge, ref = _gauge_conditions(grid, slices, c_rad, _c_names(touches.setup_ids, c_rad), delta_L_m, yaw)
    N = _null_basis(touches, slices, grid.x_m, grid.y_m, c_rad, len(names), yaw)
    des = SelfCalDesign(A=A, names=tuple(names), slices=slices, grid=grid, target_ids=tuple(touches.target_ids),
                        setup_ids=tuple(touches.setup_ids), c_rad=c_rad, ref_setup=ref, C=C, d=d,
                        gauge=tuple(gauge), scale_known=delta_L_m is not None, N=N, yaw=yaw)
    if not (heights is True or heights is False or heights == "auto"):
        raise ConfigError(f"heights must be True, False or 'auto', got {heights!r}")
    if heights:
        ht = height_terms(touches, des)
        if ht is not None:
            des = with_heights(des, ht)
    return des


def _check_touches(touches: Touches, grid: Grid) -> None:
    """ConfigError for no touches, a normal out of the XY plane, or a touch outside the grid."""
    if touches.n == 0:
        raise ConfigError("no touches")
    bad = np.flatnonzero(np.abs(touches.n_R[:, 2]) > NZ_MAX)
    if bad.size:
        raise ConfigError(f"log row {touches.row[bad[0]]}: normal n_z = {touches.n_R[bad[0], 2]:.3g};"
                          f" the 2D self-calibration model needs normals in the XY plane")
    for v, g, ax in ((touches.pn_R[:, 0], grid.x_m, "X"), (touches.pn_R[:, 1], grid.y_m, "Y")):
        out = np.flatnonzero((v < g[0] - EDGE_TOL) | (v > g[-1] + EDGE_TOL))
        if out.size:
            i = out[0]
            raise ConfigError(f"log row {touches.row[i]}: nominal {ax} = {v[i] / MM:.3f} mm lies outside the grid"
                              f" {g[0] / MM:g}..{g[-1] / MM:g} mm ({out.size} touches outside)")


def _parameters(touches: Touches, grid: Grid, c_rad: np.ndarray, yaw: Yaw) -> tuple[dict, list]:
    """(slices, names) of the parameter vector in its fixed order (module docstring)."""
    gx, gy = grid.x_m, grid.y_m
    Nx, Ny = len(gx), len(gy)
    Nw, Nc = len(touches.target_ids), len(touches.setup_ids)
    sizes = [("EXX", Nx), ("EYX", Nx), ("EXY", Ny), ("EYY", Ny), (yaw, Ny if yaw == Yaw.ECY else Nx), ("EC0Y", 1),
             ("G", Nw), ("EXC", Nc), ("EYC", Nc), ("ECC", Nc)]
    slices, o = {}, 0
    for nm, k in sizes:
        slices[nm] = slice(o, o + k)
        o += k
    cn = _c_names(touches.setup_ids, c_rad)
    names = ([f"EXX@x={_fmt_mm(v)}mm" for v in gx] + [f"EYX@x={_fmt_mm(v)}mm" for v in gx]
             + [f"{s}@y={_fmt_mm(v)}mm" for s in ("EXY", "EYY") for v in gy]
             + ([f"ECY@y={_fmt_mm(v)}mm" for v in gy] if yaw == Yaw.ECY else [f"ECX@x={_fmt_mm(v)}mm" for v in gx])
             + ["EC0Y"]
             + [f"G[{t}]" for t in touches.target_ids]
             + [f"EXC,total[{c}]" for c in cn] + [f"EYC,total[{c}]" for c in cn] + [f"ECC[{c}]" for c in cn])
    return slices, names


def _eq14_matrix(touches: Touches, grid: Grid, s: dict, yaw: Yaw) -> sp.csr_matrix:
    """(n_touches, n_params) sparse A of eq 14: eq 12 with eqs 4-5 and 8-11, eq 7, eq 13."""
    m = touches.n
    x, y = touches.pn_R[:, 0], touches.pn_R[:, 1]
    nx, ny = touches.n_R[:, 0], touches.n_R[:, 1]
    kx, zx = _interp_weights(grid.x_m, x)
    ky, zy = _interp_weights(grid.y_m, y)
    j = touches.setup
    cols, vals = [], []

    def add(c, v):  # one entry per touch (row): the matrix is built row-wise, a fixed count per row
        cols.append(np.broadcast_to(np.asarray(c, np.int64), (m,)))
        vals.append(np.broadcast_to(np.asarray(v, float), (m,)))

    # eq 12 with eqs 10, 11: dq = -nx E_X,total - ny E_Y,total; entries in column order
    # (the blocks' order of _parameters), so every row comes out sorted
    add(s["EXX"].start + kx, -nx * (1 - zx))
    add(s["EXX"].start + kx + 1, -nx * zx)
    add(s["EYX"].start + kx, -ny * (1 - zx))
    add(s["EYX"].start + kx + 1, -ny * zx)
    add(s["EXY"].start + ky, -nx * (1 - zy))
    add(s["EXY"].start + ky + 1, -nx * zy)
    add(s["EYY"].start + ky, -ny * (1 - zy))
    add(s["EYY"].start + ky + 1, -ny * zy)
    if yaw == Yaw.ECY:  # X rides on Y: E_Y += x ECY(y) (eq 5)
        add(s["ECY"].start + ky, -ny * x * (1 - zy))
        add(s["ECY"].start + ky + 1, -ny * x * zy)
    else:  # Y rides on X: E_X -= y ECX(x)
        add(s["ECX"].start + kx, nx * y * (1 - zx))
        add(s["ECX"].start + kx + 1, nx * y * zx)
    add(np.full(m, s["EC0Y"].start), nx * y)
    # eq 7
    add(s["G"].start + touches.target, np.ones(m))
    # eq 13 in the ISO 230-1 sign (tool relative to the part, module doc):
    # the paper's table displacement and rotation with the opposite sign
    rp_n = -nx * y + ny * x  # (R90 p) . n
    add(s["EXC"].start + j, -nx)
    add(s["EYC"].start + j, -ny)
    add(s["ECC"].start + j, -rp_n)
    n_par = max(sl.stop for sl in s.values())
    k = len(cols)
    idx = np.empty((m, k), np.int32 if n_par < 2 ** 31 else np.int64)
    val = np.empty((m, k))
    for c, (ci, vi) in enumerate(zip(cols, vals)):
        idx[:, c] = ci
        val[:, c] = vi
    A = sp.csr_matrix((val.ravel(), idx.ravel(), np.arange(0, k * m + 1, k)), shape=(m, n_par))
    A.has_sorted_indices = True  # built in column order (checked by the tests)
    return A


def _gauge_conditions(grid: Grid, s: dict, c_rad: np.ndarray, cn: list, delta_L_m, yaw: Yaw):
    """(C (11, n), d (11,), words, ref set-up) of the eleven gauge conditions, eqs 16-17."""
    gx, gy = grid.x_m, grid.y_m
    n_par = max(sl.stop for sl in s.values())
    xo, yo = grid.origin_m
    ref = int(np.argmin(np.abs(np.angle(np.exp(1j * c_rad)))))
    C = np.zeros((11, n_par))
    d = np.zeros(11)
    gauge = _gauge_words(grid, yaw, cn[ref], delta_L_m)

    def g(i, blk, row, val=0.0):
        C[i, s[blk]] = row
        d[i] = val

    g(0, "EXX", _interp_row(gx, xo))
    g(1, "EYX", _interp_row(gx, xo))
    g(2, "EXY", _interp_row(gy, yo))
    g(3, "EYY", _interp_row(gy, yo))
    if yaw == Yaw.ECY:
        g(4, "ECY", _interp_row(gy, yo))
    else:
        g(4, "ECX", _interp_row(gx, xo))
    e = np.zeros(len(c_rad))
    e[ref] = 1.0
    g(5, "EXC", e)
    g(6, "EYC", e)
    g(7, "ECC", e)
    last_x = np.zeros(len(gx))
    last_x[-1] = 1
    last_y = np.zeros(len(gy))
    last_y[-1] = 1
    g(8, "EYX", last_x)
    g(9, "EXY", last_y)
    g(10, "EXX", last_x, 0.0 if delta_L_m is None else float(delta_L_m))
    return C, d, gauge, ref


def _gauge_words(grid: Grid, yaw: Yaw, ref_name: str, delta_L_m, J_m=None) -> list:
    """The eleven gauge conditions of eqs 16-17 in words (rows of :func:`_gauge_conditions`).

    Positions at the grid's readings (``J_m`` None: the design, the report's tables), or at the axis
    positions reading + J (``J_m`` (3,) m: a ``vmt-estimate/1`` state whose nodes are axis positions,
    :meth:`SelfCalResult.estimate`)."""
    ox, oy = (0.0, 0.0) if J_m is None else (float(J_m[0]), float(J_m[1]))
    gx, gy = np.asarray(grid.x_m) + ox, np.asarray(grid.y_m) + oy
    xo, yo = grid.origin_m[0] + ox, grid.origin_m[1] + oy
    words = [f"EXX(x={_fmt_mm(xo)}mm)=0", f"EYX(x={_fmt_mm(xo)}mm)=0", f"EXY(y={_fmt_mm(yo)}mm)=0",
             f"EYY(y={_fmt_mm(yo)}mm)=0",
             f"ECY(y={_fmt_mm(yo)}mm)=0" if yaw == Yaw.ECY else f"ECX(x={_fmt_mm(xo)}mm)=0",
             f"EXC,total({ref_name})=0", f"EYC,total({ref_name})=0", f"ECC({ref_name})=0",
             f"EYX(x={_fmt_mm(gx[-1])}mm)=0", f"EXY(y={_fmt_mm(gy[-1])}mm)=0"]
    if delta_L_m is None:
        words.append(f"EXX(x={_fmt_mm(gx[-1])}mm)=0: scale unknown (delta_L not given), "
                     "EXX, EYY and G carry an unknown common scale")
    else:
        words.append(f"EXX(x={_fmt_mm(gx[-1])}mm)=delta_L={delta_L_m / UM:g}um (scale known)")
    return words


def c_axis_xy(touches: Touches, c_rad: np.ndarray) -> tuple[float, float]:
    """(cx, cy), m: where the nominal C axis meets the XY plane in R, read from the touches' nominal positions.

    Every touch against its target's first touch at another angle (module
    docstring, "Null space and gauge"): ``c = sum_i (I - R(D_i))^T b_i /
    sum_i 2 (1 - cos D_i)`` with ``b_i = p_i - R(D_i) p_f``. (0, 0) when no
    target is seen at two angles, or when ``|c|`` is within max(3 standard
    errors of the fit, 1e3 eps max|p|) of 0: the positions do not tell the
    axis from R's origin.

    Parameters
    ----------
    touches : Touches
        Uses ``pn_R[:, :2]`` (m, R), ``target``, ``setup``.
    c_rad : (N_c,) float
        C angle of each set-up, rad.
    """
    Nw = len(touches.target_ids)
    first = np.full(Nw, touches.n)
    np.minimum.at(first, touches.target, np.arange(touches.n))
    f = first[touches.target]
    p = touches.pn_R[:, :2]
    D = c_rad[touches.setup[f]] - c_rad[touches.setup]
    cd, sd = np.cos(D), np.sin(D)
    w = 2.0 * (1.0 - cd)
    use = w > 1e-12
    if not np.any(use):
        return 0.0, 0.0
    pf, pk, cd, sd, w = p[f[use]], p[use], cd[use], sd[use], w[use]
    b = pk - np.column_stack([cd * pf[:, 0] - sd * pf[:, 1], sd * pf[:, 0] + cd * pf[:, 1]])  # p_k - R(D) p_f
    # (I - R(D))^T b, R(D) = [[cd, -sd], [sd, cd]]
    rhs = np.column_stack([(1 - cd) * b[:, 0] - sd * b[:, 1], sd * b[:, 0] + (1 - cd) * b[:, 1]])
    c = rhs.sum(axis=0) / w.sum()
    r = b - np.column_stack([(1 - cd) * c[0] + sd * c[1], -sd * c[0] + (1 - cd) * c[1]])  # b - (I - R(D)) c
    dof = max(2 * len(w) - 2, 1)
    se = np.sqrt(np.sum(r * r) / dof / w.sum())
    tol = max(3.0 * se, 1e3 * np.finfo(float).eps * float(np.max(np.abs(p))))
    if np.hypot(c[0], c[1]) <= tol:
        return 0.0, 0.0
    return float(c[0]), float(c[1])


def _null_basis(touches, s, gx, gy, c_rad, n_par, yaw=Yaw.ECY) -> np.ndarray:
    """The eleven analytic null directions of A (see module docstring; C axis at :func:`c_axis_xy`)."""
    N = np.zeros((n_par, 11))
    cx, cy = c_axis_xy(touches, c_rad)
    Nw = s["G"].stop - s["G"].start
    first = np.full(Nw, touches.n)
    np.minimum.at(first, touches.target, np.arange(touches.n))
    pn = touches.pn_R[first, :2]
    nR = touches.n_R[first, :2]
    cf = c_rad[touches.setup[first]]
    # normal of each target in W: wn = R(+C) n
    cw, sw = np.cos(cf), np.sin(cf)
    wn = np.column_stack([cw * nR[:, 0] - sw * nR[:, 1], sw * nR[:, 0] + cw * nR[:, 1]])
    cc, sc = np.cos(c_rad), np.sin(c_rad)
    # 0, 1: tool and table translated together
    N[s["EXX"], 0] = 1
    N[s["EXC"], 0] = -1
    N[s["EYX"], 1] = 1
    N[s["EYC"], 1] = -1
    # 2, 3: constant splits
    N[s["EXX"], 2] = 1
    N[s["EXY"], 2] = -1
    N[s["EYX"], 3] = 1
    N[s["EYY"], 3] = -1
    # 4, 5: workpiece shifted by t in W; EC_j += R(-C_j) t
    for k, t in ((4, (1.0, 0.0)), (5, (0.0, 1.0))):
        N[s["G"], k] = wn @ np.array(t)
        N[s["EXC"], k] = cc * t[0] + sc * t[1]
        N[s["EYC"], k] = -sc * t[0] + cc * t[1]
    # 6: machine frame rotated
    N[s["EC0Y"], 6] = 1
    N[s["EYX"], 6] = gx
    N[s["ECC"], 6] = -1
    # 7: workpiece rotated in W about the C axis: G by n . R90 (p - c), ECC, EXC/EYC,total by -R90 c
    # (0.0 - cx, not -cx: a C axis at the origin gives +0.0, main's entries bit for bit)
    N[s["G"], 7] = -nR[:, 0] * (pn[:, 1] - cy) + nR[:, 1] * (pn[:, 0] - cx)
    N[s["ECC"], 7] = 1
    N[s["EXC"], 7] = cy
    N[s["EYC"], 7] = 0.0 - cx
    # 8: yaw offset vs a straightness slope (ECY vs EYX; ECX vs EXY); 9: EXY slope vs EC0Y
    if yaw == Yaw.ECY:
        N[s["ECY"], 8] = 1
        N[s["EYX"], 8] = -gx
    else:
        N[s["ECX"], 8] = 1
        N[s["EXY"], 8] = gy
    N[s["EXY"], 9] = gy
    N[s["EC0Y"], 9] = 1
    # 10: scale
    N[s["EXX"], 10] = gx
    N[s["EYY"], 10] = gy
    N[s["G"], 10] = np.einsum("ij,ij->i", nR, pn - (cx, cy))  # about the C axis: EXC/EYC,total by -c
    N[s["EXC"], 10] = 0.0 - cx
    N[s["EYC"], 10] = 0.0 - cy
    return N


# ---------------------------------------------------------------------------
# touches at several heights: C-axis tilt and Abbe terms
# ---------------------------------------------------------------------------
#: Touches whose nominal tip-centre heights differ by less than this share a probing level, m.
LEVEL_TOL_M = 1e-6


@dataclass(frozen=True)
class HeightTerms:
    """Columns for touches above (or below) the reference probing level.

    The paper's model (eqs 1-18) is planar: every touch at one height. A
    touch ``dz`` above the reference level (the level with the most
    touches; the sphere equators of the cross pocket sit 25.7 mm above the
    pocket walls) also sees, to first order,

    - the tilt of the tool relative to the part at its set-up, ``EBC,total``
      about Y and ``EAC,total`` about X, in the ISO 230-1 sign like EXC, EYC
      and ECC (the C axis's tilt motions and location errors, the opposite
      of the table's tilt, plus constant parts of the tool's Z-axis errors:
      all that is the same for every raised touch of one set-up):
      ``dq += -dz (n_x EBC - n_y EAC)`` (the tool displaced by
      ``(EBC dz, -EAC dz)`` relative to the part at height ``dz``);
    - the Abbe offset of the tool's angular error motions over the stroke,
      ``E_X += dz EB(x, y)``, ``E_Y -= dz EA(x, y)`` (eq 12 with the pitch
      ``EB`` and roll ``EA`` of the tool, actual minus nominal, as the
      lever of ``dz``), taken linear: ``EB = dEB/dx x + dEB/dy y`` (the
      slopes of ``EBX(x)`` and ``EBY(y)``), ``EA`` alike; their constant
      parts are in the tilt. Curvature of the angular errors over the
      raised targets is left as model error. Included only when the raised
      touches can tell them apart from the tilt and the raised targets'
      own positions (a local rank test: raised features seen in two set-ups
      or more; two spheres at four angles tell them well, one sphere only
      through its own two-lobe signature, weakly).

    What no set of touches can see (the gauge, :attr:`C`): a tilt of the
    part on the table (every raised target moved by ``dz`` times a vector in
    W): the reference set-up's tilt is set to 0, like its EXC/EYC/ECC by
    eq 16; a twist of the raised targets about the C axis and a growth of their
    radius in proportion to their height: the rotation and scale parts of
    the Abbe terms are set to 0 (only their two shear parts are seen). The
    raised targets' G carry those parts instead, so a comparison of G with
    the truth removes them as well (:func:`workpiece_gauge_basis` with
    ``dz_W``).

    Attributes
    ----------
    A : (n_touches, k) float
        Columns, m per rad.
    names : tuple of str
        ``EBC,total[C=..]``, ``EAC,total[C=..]`` per set-up with raised
        touches, then ``dEB/dx``, ``dEB/dy``, ``dEA/dx``, ``dEA/dy``
        (rad per m) when included.
    blocks : dict[str, slice]
        ``EBC``, ``EAC``, ``ABBE`` within the k columns.
    setups : (q,) int
        The set-ups with raised touches (one EBC and one EAC each).
    own : tuple of (2,) int arrays
        Per set-up of the design, its own columns within the k (empty when
        it has no raised touch): refitted on a held-out set-up in cross
        validation (:mod:`core.discover`).
    C : (h, k) float
        Gauge rows on the k columns (``C theta_h = 0``).
    gauge : tuple of str
        The h gauge conditions in words.
    null_G : (N_w, h) float
        The G part of the h null directions the gauge fixes (per target).
    null_H : (k, h) float
        Their part on the k columns.
    null_names : tuple of str
    z_ref_m : float
        Reference level (nominal tip-centre Z of most touches), machine frame, m.
    levels_m : tuple of float
        All levels, m.
    dz_m : (n_touches,) float
        Each touch's height above the reference level, m.
    dz_target_m : (N_w,) float
        Each target's (from its first touch), m: for :func:`workpiece_form`.
    abbe : bool
        Whether the Abbe terms are included.
    why : str
        Why not, when they are not.
    """

    A: np.ndarray
    names: tuple
    blocks: dict
    setups: np.ndarray
    own: tuple
    C: np.ndarray
    gauge: tuple
    null_G: np.ndarray
    null_H: np.ndarray
    null_names: tuple
    z_ref_m: float
    levels_m: tuple
    dz_m: np.ndarray
    dz_target_m: np.ndarray
    abbe: bool
    why: str = ""


def probing_levels(z_m: np.ndarray) -> tuple[np.ndarray, float]:
    """(levels (L,), reference) of nominal tip-centre heights ``z_m`` (n,): the
    levels within :data:`LEVEL_TOL_M`, the reference the one with most touches."""
    z = np.asarray(z_m, float)
    zr = np.round(z / LEVEL_TOL_M) * LEVEL_TOL_M
    lv, cnt = np.unique(zr, return_counts=True)
    return lv, float(lv[np.argmax(cnt)])


def height_terms(touches: Touches, design: SelfCalDesign, *, abbe: bool | str = "auto") -> HeightTerms | None:
    """The C-axis tilt and Abbe columns of touches at several heights (see :class:`HeightTerms`).

    The physics the discovery engine adds to its baseline too: it can call
    this with its own planar design (same touches, same set-ups).

    Parameters
    ----------
    touches : Touches
        Uses ``pn_R`` (its Z for the levels), ``n_R``, ``setup``, ``target``.
    design : SelfCalDesign
        The planar design of the same touches (set-up names, reference
        set-up, targets).
    abbe : bool or "auto"
        Include the Abbe terms: "auto" when the raised touches identify
        them (:func:`_abbe_identifiable`), True to insist (ConfigError
        naming why not), False never.

    Returns
    -------
    HeightTerms, or None when every touch is at one level.
    """
    z = touches.pn_R[:, 2]
    lv, z_ref = probing_levels(z)
    if lv.size < 2:
        return None
    dz = np.where(np.abs(z - z_ref) <= LEVEL_TOL_M, 0.0, z - z_ref)
    nx, ny = touches.n_R[:, 0], touches.n_R[:, 1]
    x, y = touches.pn_R[:, 0], touches.pn_R[:, 1]
    raised = dz != 0
    setups = np.flatnonzero(np.bincount(touches.setup[raised], minlength=len(design.setup_ids)))
    cn = [nm.split("[", 1)[1].rstrip("]") for nm in design.names[design.slices["EXC"]]]
    q = len(setups)
    cols = [-nx * dz * (touches.setup == j) for j in setups] + [ny * dz * (touches.setup == j) for j in setups]
    names = [f"EBC,total[{cn[j]}]" for j in setups] + [f"EAC,total[{cn[j]}]" for j in setups]
    # the tilt's gauge: the reference set-up's (or the first with raised touches)
    ref = design.ref_setup if design.ref_setup in setups else int(setups[0])
    r = int(np.flatnonzero(setups == ref)[0])
    if not (abbe is True or abbe is False or abbe == "auto"):
        raise ConfigError(f"abbe must be True, False or 'auto', got {abbe!r}")
    use_abbe, why = (False, "not asked for") if abbe is False else _abbe_identifiable(touches, dz, setups)
    if abbe is True and not use_abbe:
        raise ConfigError(f"the Abbe height terms are not identifiable: {why}")
    ab = [-nx * dz * x, -nx * dz * y, ny * dz * x, ny * dz * y] if use_abbe else []
    k = 2 * q + len(ab)
    Ck = np.zeros((2 + 2 * use_abbe, k))
    Ck[0, r] = 1.0
    Ck[1, q + r] = 1.0
    gauge = [f"EBC,total({cn[ref]})=0: a tilt of the part about Y on the table is not seen (height terms)",
             f"EAC,total({cn[ref]})=0: a tilt of the part about X on the table is not seen (height terms)"]
    # null directions: G parts per target (from its first touch) and height parts
    nw = len(design.target_ids)
    first = np.full(nw, touches.n)
    np.minimum.at(first, touches.target, np.arange(touches.n))
    dzt = dz[first]
    nR, pn, cf = touches.n_R[first, :2], touches.pn_R[first, :2], design.c_rad[touches.setup[first]]
    wn = np.column_stack([np.cos(cf) * nR[:, 0] - np.sin(cf) * nR[:, 1], np.sin(cf) * nR[:, 0] + np.cos(cf) * nR[:, 1]])
    h = Ck.shape[0]
    NG = np.zeros((nw, h))
    NH = np.zeros((k, h))
    cs = design.c_rad[setups]
    for c, u in enumerate(((1.0, 0.0), (0.0, 1.0))):  # the part tilted: raised targets moved by dz u (W)
        NG[:, c] = dzt * (wn @ np.array(u))
        Ru = np.column_stack([np.cos(cs) * u[0] + np.sin(cs) * u[1], -np.sin(cs) * u[0] + np.cos(cs) * u[1]])  # R(-C) u
        NH[:q, c] = Ru[:, 0]
        NH[q:2 * q, c] = -Ru[:, 1]
    null_names = ["part tilted about Y on the table (raised targets)", "part tilted about X on the table (raised targets)"]
    blocks = {"EBC": slice(0, q), "EAC": slice(q, 2 * q), "ABBE": slice(2 * q, k)}
    if use_abbe:
        cols += ab
        names += ["dEB/dx", "dEB/dy", "dEA/dx", "dEA/dy"]
        Ck[2, 2 * q + 1] = Ck[2, 2 * q + 2] = 1.0  # rotation part: dEB/dy + dEA/dx = 0
        Ck[3, 2 * q] = 1.0  # scale part: dEB/dx - dEA/dy = 0
        Ck[3, 2 * q + 3] = -1.0
        gauge += ["dEB/dy + dEA/dx = 0: a twist of the raised targets about Z in proportion to their height is not seen",
                  "dEB/dx - dEA/dy = 0: a growth of the raised targets' radius in proportion to their height is not seen"]
        # twist and growth about the C axis (c, module docstring "Null space and gauge"): the Abbe part
        # removes dz n . R90 p (dz n . p), G gives dz n . R90 (p - c) (dz n . (p - c)), and every raised
        # set-up's tilt gives back -dz n . R90 c (-dz n . c): EBC, EAC = cy, cx (-cx, cy); 0 with c = 0
        cx, cy = c_axis_xy(touches, design.c_rad)
        NG[:, 2] = dzt * (-nR[:, 0] * (pn[:, 1] - cy) + nR[:, 1] * (pn[:, 0] - cx))  # twist: n . R90 (p - c)
        NH[2 * q:, 2] = (0.0, -1.0, -1.0, 0.0)
        NH[:q, 2], NH[q:2 * q, 2] = cy, cx
        NG[:, 3] = dzt * np.einsum("ij,ij->i", nR, pn - (cx, cy))  # growth: n . (p - c)
        NH[2 * q:, 3] = (1.0, 0.0, 0.0, -1.0)
        NH[:q, 3], NH[q:2 * q, 3] = 0.0 - cx, cy
        null_names += ["raised targets twisted about Z in proportion to height",
                       "raised targets' radius grown in proportion to height"]
    own = tuple(np.array([np.flatnonzero(setups == j)[0], q + np.flatnonzero(setups == j)[0]])
                if j in setups else np.zeros(0, int) for j in range(len(design.setup_ids)))
    return HeightTerms(A=np.column_stack(cols), names=tuple(names), blocks=blocks, setups=setups, own=own, C=Ck,
                       gauge=tuple(gauge), null_G=NG, null_H=NH, null_names=tuple(null_names), z_ref_m=z_ref,
                       levels_m=tuple(float(v) for v in lv), dz_m=dz, dz_target_m=dzt, abbe=bool(use_abbe),
                       why=why)


def _abbe_identifiable(touches: Touches, dz: np.ndarray, setups: np.ndarray) -> tuple[bool, str]:
    """Whether the raised touches tell the Abbe shear apart from the tilt and their targets' G.

    A local rank test on the raised touches alone: with each raised
    target's own constant (its G) projected out (the columns less their mean
    over the target's touches), the two shear columns must add two to the
    rank of the tilt columns (the twist and growth parts never do: they are
    the gauge). Cost linear in the raised touches.
    """
    raised = np.flatnonzero(dz != 0)
    nx, ny = touches.n_R[raised, 0], touches.n_R[raised, 1]
    x, y, d = touches.pn_R[raised, 0], touches.pn_R[raised, 1], dz[raised]
    st = touches.setup[raised]
    _, tg = np.unique(touches.target[raised], return_inverse=True)
    tilt = np.column_stack([nx * d * (st == j) for j in setups] + [-ny * d * (st == j) for j in setups])
    shear = np.column_stack([-nx * d * x + ny * d * y, -nx * d * y - ny * d * x])  # (1,0,0,1), (0,1,-1,0)
    M = np.hstack([tilt, shear])
    cnt = np.bincount(tg)
    for c in range(M.shape[1]):
        M[:, c] -= (np.bincount(tg, weights=M[:, c]) / cnt)[tg]
    gain = _rank(M) - _rank(M[:, :-2])
    if gain == 2:
        return True, ""
    return False, (f"the raised touches ({len(raised)} at {counted(len(cnt), 'target')} in {len(setups)} set-up(s))"
                   f" do not tell the tool's Abbe terms apart from the part's tilt and the raised targets' own"
                   f" positions (probe raised features in more set-ups); left out")


def _rank(M: np.ndarray, tol: float = 1e-9) -> int:
    """Numerical rank of ``M`` with its columns scaled to unit norm (zero columns count nothing)."""
    nrm = np.linalg.norm(M, axis=0)
    M = M[:, nrm > 0] / nrm[nrm > 0]
    if M.size == 0:
        return 0
    sv = np.linalg.svd(M, compute_uv=False)
    return int(np.sum(sv > tol * sv[0]))


def with_heights(des: SelfCalDesign, ht: HeightTerms) -> SelfCalDesign:
    """``des`` with the height terms ``ht`` appended (columns, names, gauge, null space)."""
    import dataclasses

    p = des.n_params
    k = ht.A.shape[1]
    A = sp.hstack([des.A, sp.csr_matrix(ht.A)], format="csr")
    slices = dict(des.slices)
    for nm, sl in ht.blocks.items():
        slices[nm] = slice(p + sl.start, p + sl.stop)
    C = np.vstack([np.hstack([des.C, np.zeros((des.C.shape[0], k))]),
                   np.hstack([np.zeros((ht.C.shape[0], p)), ht.C])])
    d = np.concatenate([des.d, np.zeros(ht.C.shape[0])])
    Nh = np.zeros((p + k, ht.C.shape[0]))
    Nh[des.slices["G"]] = ht.null_G
    Nh[p:] = ht.null_H
    N = np.hstack([np.vstack([des.N, np.zeros((k, des.N.shape[1]))]), Nh])
    return dataclasses.replace(des, A=A, names=des.names + ht.names, slices=slices, C=C, d=d,
                               gauge=des.gauge + ht.gauge, N=N, heights=ht)



def null_space(design: SelfCalDesign) -> np.ndarray:
    """(n_params, 11 + h) analytic null-space basis of ``design.A`` (named by :data:`GAUGE_NAMES`, then
    ``design.heights.null_names``)."""
    return design.N


# ---------------------------------------------------------------------------
# identification
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class SelfCalResult:
    """Identified workpiece, axis and rotary errors (eqs 15-18).

    Attributes
    ----------
    design : SelfCalDesign
    theta : (n_params,) float
        All parameters, m / rad, in ``design.names`` order.
    std : (n_params,) float or None
        Standard uncertainties (k = 1), m / rad; 0 for gauge-fixed values:
        probing noise and, when budgeted, model error (``budget``).
    cov : (n_params, n_params) float or None
        Their covariance (both parts).
    residuals_m : (n_touches,) float
    rms_m : float
        Residual RMS, m.
    sigma_m : float
        Probing standard deviation used for the covariance, m (with a model
        error budget: the noise component beside it).
    sigma_source : str
    dof : int
    conventions : tuple of str
        The gauge conditions (``design.gauge``), then notes.
    scale_known : bool
    n_touches : int
    budget : ModelErrorBudget or None
        The split of ``std`` into probing noise and model error
        (:func:`core.uncertainty.model_error_budget`); None when not computed.
    blind_lobes : tuple of BlindLobe
        The probe's pre-travel lobe orders this design absorbs into its
        parameters (:func:`blind_lobes`): what the U95 does not cover.
    direction : DirectionStructure or None
        Residuals that follow the approach azimuth (:func:`direction_structure`):
        removed before the model-error budget, not in the U95, its shift of the
        parameters reported in ``not_covered``.
    time : TimeStructure or None
        Residuals that follow time (:func:`time_structure`, with :data:`TIME_STRUCTURE` on): a drift inside
        the campaign, not in the U95, its shift of the parameters reported in ``not_covered``.
    """

    design: SelfCalDesign
    theta: np.ndarray
    std: np.ndarray | None
    cov: np.ndarray | None
    residuals_m: np.ndarray
    rms_m: float
    sigma_m: float
    sigma_source: str
    dof: int
    conventions: tuple
    scale_known: bool
    n_touches: int
    budget: object = None
    blind_lobes: tuple = ()
    direction: object = None
    time: object = None
    serial: object = None
    lobe_limits: tuple = ()

    def _blk(self, k):
        return self.theta[self.design.slices[k]]

    @property
    def EXX(self):
        """(N_x,) m on ``design.grid.x_m``."""
        return self._blk("EXX")

    @property
    def EYX(self):
        """(N_x,) m."""
        return self._blk("EYX")

    @property
    def EXY(self):
        """(N_y,) m on ``design.grid.y_m``."""
        return self._blk("EXY")

    @property
    def EYY(self):
        """(N_y,) m."""
        return self._blk("EYY")

    @property
    def yaw(self) -> Yaw:
        """``ECY`` (on the y nodes) or ``ECX`` (on the x nodes): see :func:`yaw_for_chain`."""
        return self.design.yaw

    @property
    def ECY(self):
        """(N_y,) rad (designs with ``yaw="ECY"``)."""
        return self._blk("ECY")

    @property
    def ECX(self):
        """(N_x,) rad (designs with ``yaw="ECX"``)."""
        return self._blk("ECX")

    @property
    def EC0Y(self) -> float:
        """Squareness, rad."""
        return float(self._blk("EC0Y")[0])

    @property
    def G(self):
        """(N_w,) workpiece normal deviation per target, m (``design.target_ids``)."""
        return self._blk("G")

    @property
    def EXC(self):
        """(N_c,) EXC,total per set-up, m."""
        return self._blk("EXC")

    @property
    def EYC(self):
        """(N_c,) EYC,total per set-up, m."""
        return self._blk("EYC")

    @property
    def ECC(self):
        """(N_c,) rad."""
        return self._blk("ECC")

    @property
    def EBC(self):
        """(q,) rad: the table's tilt about Y per set-up with raised touches (``design.heights.setups``)."""
        return self._blk("EBC")

    @property
    def EAC(self):
        """(q,) rad: the table's tilt about X per set-up with raised touches."""
        return self._blk("EAC")

    def value(self, name: str) -> float:
        """One parameter by name."""
        return float(self.theta[self.design.names.index(name)])

    def estimate(self, J_m=None) -> dict:
        """The estimate with its covariance (``vmt-estimate/1``, :mod:`core.state`): the X/Y tables
        (EXX, EYX, the yaw on their nodes; linear interpolation, eqs 8-11) and EC0Y are machine errors,
        the workpiece, set-up and height terms named only.

        ``J_m`` (3,) m: the probe offsets of the touches; the nodes, on the grid of readings, are then
        written at the axis positions reading + J (X tables + J_X, Y tables + J_Y), as the format
        declares. None (unknown): at the readings, and ``positions`` says so
        (:data:`core.state.POSITIONS_READINGS`)."""
        from .state import POSITIONS, POSITIONS_READINGS, estimate_doc

        J = None if J_m is None else np.asarray(J_m, float)

        des = self.design
        g = des.grid
        n = des.n_params
        symbols, at, units = [None] * n, [None] * n, ["um"] * n
        for k, sl in des.slices.items():
            r = range(sl.start, sl.stop)
            if k in ("EXX", "EYX", "ECX", "EXY", "EYY", "ECY"):
                on_x = k in ("EXX", "EYX", "ECX")
                pos = g.x_m if on_x else g.y_m
                off = 0.0 if J is None else float(J[0 if on_x else 1])
                for i, x in zip(r, pos):
                    symbols[i], at[i] = k, float(x) + off
            elif k == "EC0Y":
                symbols[sl.start] = k
            if k in ("ECX", "ECY", "EC0Y", "ECC", "EBC", "EAC"):
                for i in r:
                    units[i] = "urad"
            elif k == "ABBE":
                for i in r:
                    units[i] = "urad/m"
        conventions = tuple(self.conventions)
        if J is not None:  # the gauge's positions where the nodes are: the axis positions reading + J
            words = _gauge_words(g, des.yaw, _c_names(des.setup_ids, des.c_rad)[des.ref_setup],
                                 float(des.d[10]) if des.scale_known else None, J)
            conventions = tuple(words) + conventions[len(words):]
        return estimate_doc(des.names, symbols, at, units, self.theta, self.cov,
                            method="2D self-calibration, Ibaraki et al. eqs 15-18 (covariance: probing noise"
                                   + (" and model error)" if self.budget is not None else ")"),
                            interpolation="linear", conventions=conventions,
                            positions=POSITIONS if J is not None else POSITIONS_READINGS)

    def to_report(self, mc=None, J_m=None) -> dict:
        """JSON-ready report (um, urad, mm, deg): what ``vmt identify`` writes.

        ``mc`` (a Monte Carlo :func:`core.uncertainty.monte_carlo_touches` of the
        same touches) adds its U95 per target and its summary. ``J_m``: the
        touches' probe offsets, m, or None (:meth:`estimate`).
        """
        res = self
        des = res.design
        s = des.slices
        U = 2 * res.std if res.std is not None else np.full(des.n_params, np.nan)

        def u95(i):
            v = U[i]
            return None if not np.isfinite(v) else v

        out = {
            "format": REPORT_FORMAT,
            "method": "2D self-calibration, Ibaraki et al. eqs 15-18",
            "touches": res.n_touches,
            "n_params": des.n_params,
            "rms_um": _r(res.rms_m * 1e6),
            "sigma_um": _r(res.sigma_m * 1e6),
            "sigma_source": res.sigma_source,
            "dof": res.dof,
            "conventions": {"gauge": list(des.gauge), "scale_known": res.scale_known, "yaw": des.yaw,
                            "notes": list(res.conventions[len(des.gauge):])},
            "workpiece": [],
            "axes": {},
            "rotary": [],
        }
        for k, tid in enumerate(des.target_ids):
            i = s["G"].start + k
            row = {"target": tid, "g_um": _r(res.theta[i] * 1e6), "u95_um": _r(u95(i) * 1e6)}
            if mc is not None:
                row["mc_u95_um"] = _r(mc.U95[i] * 1e6)
            out["workpiece"].append(row)
        for sym in ("EXX", "EYX", "EXY", "EYY", des.yaw):
            on_x = sym in ("EXX", "EYX", "ECX")
            pos = des.grid.x_m if on_x else des.grid.y_m
            idx = np.arange(s[sym].start, s[sym].stop)
            f, unit = (1e6, "urad") if sym in ("ECY", "ECX") else (1e6, "um")
            out["axes"][sym] = {"axis_pos": "x" if on_x else "y",
                                "positions_mm": [_r(v * 1e3) for v in pos],
                                f"values_{unit}": [_r(res.theta[i] * f) for i in idx],
                                f"u95_{unit}": [_r(u95(i) * f) for i in idx]}
        i = s["EC0Y"].start
        out["axes"]["EC0Y"] = {"value_urad": _r(res.theta[i] * 1e6), "u95_urad": _r(u95(i) * 1e6)}
        for j, sid in enumerate(des.setup_ids):
            ix, iy, ic = s["EXC"].start + j, s["EYC"].start + j, s["ECC"].start + j
            out["rotary"].append({"setup": sid, "c_deg": _r(np.degrees(des.c_rad[j]), 6),
                                  "exc_um": _r(res.theta[ix] * 1e6), "exc_u95_um": _r(u95(ix) * 1e6),
                                  "eyc_um": _r(res.theta[iy] * 1e6), "eyc_u95_um": _r(u95(iy) * 1e6),
                                  "ecc_urad": _r(res.theta[ic] * 1e6), "ecc_u95_urad": _r(u95(ic) * 1e6)})
        if des.heights is not None:
            out["heights"] = _heights_report(res, u95)
        if res.budget is not None:
            b = res.budget
            unit = {"ECY": 1e6, "ECX": 1e6}
            out["uncertainty"] = {
                "probe_sigma_um": _r(b.sigma_probe_m * 1e6),
                "model_error": {k: _r(v * unit.get(k, 1e6)) for k, v in b.components.items()},
                "model_error_units": {k: ("urad" if k in unit else "um") for k in b.components},
                "model_error_z": {k: _r(v, 2) for k, v in b.z.items()},
                "model_error_p": (None if b.p is None else {k: float(f"{v:.3g}") for k, v in b.p.items()}),
                "rule": b.rule}
        out["not_covered"] = not_covered(res.blind_lobes)
        if res.direction is not None:
            ds = res.direction
            bias = direction_biases(des, ds, res.std)
            out["not_covered"]["approach_direction"] = {
                "what": direction_text(ds, bias), "lobe_order": ds.k, "amplitude_um": _r(ds.amplitude_m * 1e6),
                "orders_tested": list(ds.orders), "F": _r(ds.F, 2) if np.isfinite(ds.F) else None, "p_value": float(f"{ds.p:.3g}"),
                "p_value_tables": float(f"{ds.p_tables:.3g}"),
                "dof_taken": ds.rank,
                "shift": {b: {"largest": _r(v["signed"]), "ratio_to_u95": None if v["ratio_to_u95"] is None
                              else _r(v["ratio_to_u95"], 2), "unit": v["unit"],
                              **({} if "worst_phase" not in v else {
                                  "worst_phase": _r(v["worst_phase"]),
                                  "worst_phase_ratio_to_u95": None if v["worst_ratio_to_u95"] is None
                                  else _r(v["worst_ratio_to_u95"], 2)})} for b, v in bias.items()},
                "shift_what": "per block, the value's change of largest magnitude (signed: the estimate minus the "
                              "estimate with the direction structure fitted alongside) and its ratio to that "
                              "value's U95: the structure's visible part, what the residuals show; the part of "
                              "the lobe the design absorbs is not seen and adds to it, so the bias can be larger. "
                              "worst_phase: the largest change a lobe of lobe_order and amplitude_um makes at its "
                              "worst phase, the absorbed part included (magnitude), and its ratio to that value's "
                              "U95; a bound only as good as amplitude_um, itself read from the residuals"}
        if res.serial is not None:
            sc = res.serial
            out["not_covered"]["correlated_errors"] = {
                "what": serial_text(sc) + (
                    "; the approach-direction finding beside it may be these correlated errors, not a lobe: consecutive "
                    "touches share a wall, so a slow wander of the errors shows as a per-direction offset in each "
                    "set-up (a lobe, in the machine frame, leaves no serial correlation once its structure is removed)"
                    if sc.significant and res.direction is not None else ""), "clock": sc.clock, "lag1_autocorrelation": _r(sc.r1, 3),
                "lag1_expected_if_independent": _r(sc.r1_null, 3), "z": _r(sc.z, 2), "p_value": float(f"{sc.p:.3g}"),
                "significant": sc.significant, "threshold_p": SERIAL_P,
                **({"ar1_rho": _r(sc.rho, 3), "ar1_sigma_um": _r(sc.sigma_m * 1e6), "u95_widened_up_to": _r(sc.inflation, 3)}
                   if sc.significant else {})}
        if res.lobe_limits:
            out["not_covered"]["undetected_lobes"] = {
                "what": lobe_limits_text(res.lobe_limits),
                "power": LOBE_DETECTION_POWER,
                "limits": [{"k": L.k, "amplitude_named_half_the_time_um": _r(L.amplitude_m * 1e6),
                            "per_um_of_lobe": {b: _r(v, 3) for b, v in L.per_um.items()},
                            "units": {b: _alias_unit(b) + "/um" for b in L.per_um},
                            "bias_at_limit_ratio_to_u95": {b: _r(v, 2) for b, v in L.ratio.items()}}
                           for L in res.lobe_limits]}
        if res.time is not None:
            ts = res.time
            bias = direction_biases(des, ts, res.std)
            out["not_covered"]["time_drift"] = {
                "what": time_text(ts, bias), "clock": ts.clock, "drift_range_um": {"X": _r(ts.drift_um[0]),
                                                                                 "Y": _r(ts.drift_um[1])},
                "F": _r(ts.F, 2) if np.isfinite(ts.F) else None, "p_value": float(f"{ts.p:.3g}"),
                "p_value_tables": float(f"{ts.p_tables:.3g}"), "dof_taken": ts.rank,
                "shift": {b: {"largest": _r(v["signed"]), "ratio_to_u95": None if v["ratio_to_u95"] is None
                              else _r(v["ratio_to_u95"], 2), "unit": v["unit"]} for b, v in bias.items()},
                "shift_what": "per block, the value's change of largest magnitude (signed: the estimate minus the "
                              "estimate with the drift fitted alongside) and its ratio to that value's U95"}
        if res.cov is not None:
            out["estimate"] = res.estimate(J_m)
        if mc is not None:
            out["monte_carlo"] = {"runs": mc.runs, "u_probe_um": _r(mc.u_probe_m * 1e6),
                                  "what": "probing noise only (JCGM 101), beside the linear U95 of the budget",
                                  "max_workpiece_u95_um": _r(mc.max_workpiece_U95 * 1e6),
                                  "max_workpiece_form_u95_um": _r(mc.max_form_U95 * 1e6)}
        return out


def _heights_report(res: SelfCalResult, u95) -> dict:
    """The height terms of a result in report units (mm, urad, urad/m)."""
    des = res.design
    ht = des.heights
    s = des.slices
    out = {"z_ref_mm": _r(ht.z_ref_m / MM, 6), "levels_mm": [_r(v / MM, 6) for v in ht.levels_m],
           "abbe": ht.abbe, "why": ht.why, "tilt": []}
    for q, j in enumerate(ht.setups):
        ib, ia = s["EBC"].start + q, s["EAC"].start + q
        out["tilt"].append({"setup": des.setup_ids[j], "ebc_urad": _r(res.theta[ib] * 1e6),
                            "ebc_u95_urad": _r(u95(ib) * 1e6), "eac_urad": _r(res.theta[ia] * 1e6),
                            "eac_u95_urad": _r(u95(ia) * 1e6)})
    if ht.abbe:
        out["abbe_urad_per_m"] = {nm: {"value": _r(res.theta[i] * 1e6), "u95": _r(u95(i) * 1e6)}
                                  for nm, i in zip(("dEB/dx", "dEB/dy", "dEA/dx", "dEA/dy"), range(s["ABBE"].start,
                                                                                                   s["ABBE"].stop))}
    return out


def count_condition(n_w: int, n_x: int, n_y: int, n_c: int) -> tuple[int, int, int]:
    """Eq 6: (equations, unknowns, least N_c meeting ``N_w N_c > unknowns``)."""
    unknowns = n_w + 2 * n_x + 3 * n_y + 1 + 3 * n_c
    need = None
    if n_w > 3:
        need = int(np.floor((n_w + 2 * n_x + 3 * n_y + 1) / (n_w - 3))) + 1
    return n_w * n_c, unknowns, need


def check_count(touches: Touches, grid: Grid) -> None:
    """Raise :class:`IdentifiabilityError` unless eq 6 holds (and >= 2 C angles)."""
    nw, nc = len(touches.target_ids), len(touches.setup_ids)
    nx, ny = len(grid.x_m), len(grid.y_m)
    unknowns = nw + 2 * nx + 3 * ny + 1 + 3 * nc
    _, _, need = count_condition(nw, nx, ny, nc)
    if nc < 2:
        raise IdentifiabilityError(f"{nc} C angle: self-calibration needs the same targets at >= 2 C angles (eq 6)")
    if touches.n <= unknowns:
        needs = (f"at least {need} C angles with these {nw} targets" if need is not None
                 else f"more than 3 targets (have {nw})")
        raise IdentifiabilityError(
            f"{nc} C angles give {touches.n} equations for {unknowns} unknowns"
            f" (N_w={nw}, N_x={nx}, N_y={ny}); eq 6 needs N_w N_c > N_w + 2N_x + 3N_y + 1 + 3N_c: {needs},"
            f" or a coarser grid")


def _check_nodes(des: SelfCalDesign) -> None:
    """Raise naming every grid node no touch constrains (they would be solved from the gauge alone).

    An ``ECC`` column is no grid value: it is zero when every probed normal passes through the C axis (a
    circle or a bore probed radially about it: a turn about the axis moves no touch along its normal), and
    the refusal says that, and which faces would see the angle (review33b F4: it gave the grid's advice)."""
    colnorm = column_norms(des.A)
    zero = np.flatnonzero(colnorm <= 1e-12 * colnorm.max())
    if not zero.size:
        return
    ecc = [i for i in zero if des.names[i].startswith("ECC[")]
    if ecc:
        at = ", ".join(des.names[i][len("ECC[C="):-1] for i in ecc)
        raise IdentifiabilityError(
            f"the C angle is not seen (ECC at C = {at}): every probed normal passes through the C axis (a circle "
            "or bore probed radially about it), so a turn about the axis moves no touch along its normal; probe "
            "faces whose normals miss the axis as well (a flat side, a slot's or pocket's walls, a circle off the "
            "axis)")
    shown = ", ".join(des.names[i] for i in zero[:10]) + (f" and {zero.size - 10} more" if zero.size > 10 else "")
    raise IdentifiabilityError(f"no touch constrains {shown}: fit the grid to the touches or add targets there")


def self_calibrate(touches: Touches, grid: Grid | None = None, delta_L_m: float | None = None, *,
                   grid_step_m: float = 0.022, sigma_m: float | None = None, covariance: str = "auto",
                   yaw: Yaw | str = Yaw.ECY, heights: bool | str = "auto",
                   model_error: bool | str = "auto", subgrid: dict | None = None) -> SelfCalResult:
    """2D self-calibration, eqs 15-18.

    Parameters
    ----------
    touches : Touches
        From :func:`core.touches.from_log` (or :func:`nominal_touches`).
    grid : Grid or None
        Look-up-table nodes; None = :meth:`Grid.from_extent` of ``pn_R`` with
        ``grid_step_m``.
    delta_L_m : float or None
        ``EXX(x_N)`` measured independently (eq 17), m; None = scale unknown.
    sigma_m : float or None
        Probing standard deviation, m; None = estimated from residuals.
    covariance : str
        See :func:`solve`.
    yaw : {"ECY", "ECX"}
        The yaw coupling X and Y (:func:`yaw_for_chain` of the log's
        ``kinematic_chain``); the paper's ``"ECY"`` by default.
    heights : bool or "auto"
        Touches at more than one Z level get the height terms
        (:func:`height_terms`: C-axis tilt per set-up, the tool's Abbe terms);
        False keeps the planar model (their height effect is then model error).
    model_error : bool or "auto"
        Budget the model error (:func:`core.uncertainty.model_error_budget`):
        ``std`` then holds probing noise and model error, and ``sigma_m``
        the noise component. "auto" and True: when the design is small
        enough (:data:`core.uncertainty.MODEL_ERROR_MAX_CELLS`; a note says
        when not); False: probing noise alone (the residuals' sigma).
        Not computed with ``covariance="none"``. With the budget, residuals
        that follow the approach direction (:func:`direction_structure`,
        confirmed against the budget's tables) are removed before it and
        named in ``direction``; without it they are not looked for.
    subgrid : dict or None
        Declared sub-grid amplitudes, table -> m (rad for the yaw): what a
        table cannot follow between its nodes, from the machine's spec
        (e.g. a screw's pitch ripple); a floor on the budget's components
        (:func:`core.uncertainty.model_error_budget`). None: the residuals
        alone (which do not see a ripple's value at the datum's nodes).

    Raises
    ------
    IdentifiabilityError
        Eq 6 fails, a grid node no touch constrains, or rank deficiency beyond
        the gauge directions (named).
    ConfigError
        Touches outside the grid, inconsistent set-ups, a bad option.
    """
    if not (model_error is True or model_error is False or model_error == "auto"):
        raise ConfigError(f"model_error must be True, False or 'auto', got {model_error!r}")
    if subgrid and (not model_error or covariance == "none"):
        raise ConfigError("subgrid: a declared sub-grid ripple enters the model-error budget: it needs model_error "
                          "True or 'auto' and a covariance")
    if grid is None:
        grid = Grid.from_extent(touches.pn_R, grid_step_m)
    des, sol = _design_and_solve(touches, grid, delta_L_m, touches.dq_m, yaw, heights, sigma=sigma_m,
                                 covariance=covariance)
    std, cov, sigma, src, budget = sol.std, sol.cov, sol.sigma, sol.sigma_source, None
    notes = [("scale known: EXX(x_N) = delta_L" if des.scale_known else "scale unknown: delta_L not given, fixed to 0"),
             "ECC is the C axis's angular positioning error: actual minus commanded C of the tool relative "
             "to the part, positive a right-handed rotation of the tool relative to the part about Z (eq 13's "
             "table rotation with the opposite sign); 0 at the reference set-up",
             c_centre_note(None),
             "G is the workpiece deviation along the outward normal (eq 7)"]
    if des.heights is not None:
        ht = des.heights
        notes.append(f"touches at {len(ht.levels_m)} heights: C-axis tilt per set-up"
                     + (" and the tool's Abbe terms (linear)" if ht.abbe else f"; Abbe terms: {ht.why}")
                     + f" for touches off the reference level Z = {ht.z_ref_m / MM:g} mm")
    blind = blind_lobes(des, sol.estimator, touches)
    # residuals that follow the approach direction (a probe's lobing the design does not absorb): not table misfit
    direction = None
    direction_tested = bool(model_error and covariance != "none")
    if direction_tested:
        direction = direction_structure(des, sol.estimator, touches, sol.residuals, blind)
        from .uncertainty import model_error_budget

        budget = None
        if direction is not None:   # the budget beside the structure; kept when its tables cannot explain it
            budget = model_error_budget(des, sol.estimator, touches, sol.residuals - direction.fitted_m, sigma_m,
                                        full=sol.cov is not None, subgrid=subgrid, extra_free=direction.rank,
                                        probe_cols=(direction.basis, direction.proj))
            if budget.computed and budget.probe_p is not None and budget.probe_p < DIRECTION_P:
                direction = replace(direction, p_tables=budget.probe_p)
            else:
                direction, budget = None, None
        if budget is None:
            budget = model_error_budget(des, sol.estimator, touches, sol.residuals, sigma_m,
                                        full=sol.cov is not None, subgrid=subgrid)
        if budget.computed:
            sigma = budget.sigma_probe_m
            std = budget.u
            if sol.cov is not None:
                cov = sol.estimator.covariance(sigma) + budget.cov_model
            if sigma_m is None:
                src = "residuals (probing noise beside the model error, moment equations)"
                if direction is not None:
                    src += "; their approach-direction structure removed first (a probe lobing, not table misfit)"
            notes.append(budget.rule)
        else:
            notes.append("model error not budgeted (design too large): U95 from the residuals' sigma as probing noise")
            budget = None
    notes.append(f"sigma from {src}")
    time = None
    if TIME_STRUCTURE and budget is not None:   # a drift in time: named (not_covered), the budget unchanged
        from .uncertainty import model_error_budget

        r_t = sol.residuals - (direction.fitted_m if direction is not None else 0.0)
        ts = time_structure(des, sol.estimator, touches, r_t)
        if ts is not None:
            b2 = model_error_budget(des, sol.estimator, touches, r_t - ts.fitted_m, sigma_m, subgrid=subgrid,
                                    extra_free=ts.rank + (direction.rank if direction is not None else 0),
                                    probe_cols=(ts.basis, ts.proj))
            if b2.computed and b2.probe_p is not None and b2.probe_p < TIME_P:
                time = replace(ts, p_tables=b2.probe_p)
    serial = None
    if SERIAL_CORRELATION and budget is not None:   # errors correlated in touch order: tested, the U95 widened
        r_s = (sol.residuals - (direction.fitted_m if direction is not None else 0.0)
               - (time.fitted_m if time is not None else 0.0))
        serial = serial_correlation(des, sol.estimator, touches, r_s, std, budget.u_model, budget.cov_model,
                                    full=cov is not None,
                                    beside=_serial_beside(des, touches, budget, subgrid, direction, time,
                                                          tables=SERIAL_BESIDE_TABLES))

        if serial is not None and serial.significant:
            std = serial.std
            if serial.cov is not None:
                cov = serial.cov
            notes.append(f"probing errors correlated in touch order (lag-1 z = {serial.z:.1f}): the probing part "
                         f"of the U95 propagated as AR(1) rho {serial.rho:.2f}, sigma {serial.sigma_m * 1e6:.3f} um")
    limits = ()
    if LOBE_DETECTION_LIMITS and direction_tested and std is not None:
        limits = lobe_detection_limits(des, sol.estimator, touches, sigma, std, blind)
    return SelfCalResult(design=des, theta=sol.theta, std=std, cov=cov, residuals_m=sol.residuals,
                         rms_m=sol.rms, sigma_m=sigma, sigma_source=src, dof=sol.dof,
                         conventions=des.gauge + tuple(notes), scale_known=des.scale_known, n_touches=touches.n,
                         budget=budget, blind_lobes=blind, direction=direction, time=time, serial=serial,
                         lobe_limits=limits)


def _design_and_solve(touches: Touches, grid: Grid, delta_L_m, dq, yaw, heights, **kw):
    """(design, Solution): eq 6 checked, the design built (with heights), every node checked, solved."""
    check_count(touches, grid)
    des = build_design(touches, grid, delta_L_m, yaw=yaw, heights=heights)
    free = des.n_params - des.C.shape[0]
    if des.heights is not None and touches.n <= free:
        raise IdentifiabilityError(f"{touches.n} touches for {free} free parameters with the height terms"
                                   f" ({len(des.heights.names)} of them): probe more targets or angles")
    _check_nodes(des)
    sol = solve(des.A, dq, des.C, des.d, names=des.names, diagonal=des.slices["G"], **kw)
    return des, sol


def estimator(touches: Touches, grid: Grid, delta_L_m: float | None = None, *,
              yaw: Yaw | str = Yaw.ECY, heights: bool | str = "auto") -> tuple[SelfCalDesign, LinearEstimator]:
    """Build and factor the design once (for Monte Carlo and design studies)."""
    des, sol = _design_and_solve(touches, grid, delta_L_m, np.zeros(touches.n), yaw, heights, sigma=1.0,
                                 covariance="none")
    return des, sol.estimator


# ---------------------------------------------------------------------------
# what the uncertainty statement does not cover: pre-travel lobes the design absorbs
# ---------------------------------------------------------------------------
#: Lobe orders k of the probe's pre-travel (``p(phi) = a cos k phi + b sin k phi`` of the approach azimuth,
#: machine frame) that :func:`blind_lobes` checks against a design: 1..6 (k = 1 is a probe offset, 3 the
#: common three-point kinematic probe's, 6 its second harmonic).
LOBE_ORDERS = (1, 2, 3, 4, 5, 6)
#: A lobe direction is "not determined" when the sine of its smallest principal angle to the design's column
#: space is below this: the fit absorbs at least 1 - 0.1^2 = 99 % of its signal (variance inflation 100, the
#: threshold core.discover refuses a cause as confounded with the model by, ``vif_max``: about 5.7 deg).
LOBE_ALIAS_SIN = 0.1
#: A block of parameters is named as taking an absorbed lobe when its part of the fitted signal is at least
#: this share of the lobe's (the rest spread over blocks that each take less).
LOBE_ALIAS_SHARE = 0.1


@dataclass(frozen=True)
class BlindLobe:
    """A pre-travel lobe order the design cannot see (:func:`blind_lobes`).

    Attributes
    ----------
    k : int
        Lobe order.
    angle_deg : float
        Smallest principal angle between the lobe's columns (cos k phi, sin k phi) and the design's column
        space, deg (0: some phase of the lobe is fitted exactly).
    absorbed : float
        Share of that worst phase's signal the fit takes (``cos^2`` of the angle).
    blocks : tuple of str
        Parameter blocks taking at least :data:`LOBE_ALIAS_SHARE` of the fitted signal, largest first.
    per_um : dict[str, float]
        Per block, the largest change of one of its values a lobe of 1 um amplitude (any phase) makes, um per
        um (urad per um for ``ECC``, ``ECY``, ``ECX``, ``EC0Y``, ``EBC``, ``EAC``).
    """

    k: int
    angle_deg: float
    absorbed: float
    blocks: tuple
    per_um: dict

    def text(self) -> str:
        mags = ", ".join(f"{b} up to {self.per_um[b]:.2f} {_alias_unit(b)}" for b in self.blocks)
        return (f"k = {self.k} (principal angle {self.angle_deg:.1f} deg, {100 * self.absorbed:.0f} % absorbed)"
                f" into {mags} per um of lobe")


_ANGULAR_BLOCKS = ("ECC", "ECY", "ECX", "EC0Y", "EBC", "EAC")


def _alias_unit(block: str) -> str:
    return "urad" if block in _ANGULAR_BLOCKS else "um"


def _lobe_columns(phi: np.ndarray, k: int):
    """A lobe of order ``k``'s columns ``[cos k phi, sin k phi]`` (m per m of lobe amplitude: 1 um of lobe ->
    1 um), those not vanishing at the azimuths ``phi``; None when both do. The one lobe of
    :func:`blind_lobes`, :func:`absorbed_lobes` (through :func:`_lobe_basis`) and :func:`direction_structure`."""
    L = np.column_stack([np.cos(k * phi), np.sin(k * phi)])
    keep = np.linalg.norm(L, axis=0) > 1e-9 * np.sqrt(phi.size)
    return L[:, keep] if keep.any() else None


def _lobe_basis(phi: np.ndarray, k: int):
    """``(Q, R)``, the QR factors of :func:`_lobe_columns` (None when both columns vanish)."""
    L = _lobe_columns(phi, k)
    return None if L is None else np.linalg.qr(L)


def blind_lobes(design: SelfCalDesign, est: LinearEstimator, touches: Touches,
                orders=LOBE_ORDERS) -> tuple:
    """The probe's pre-travel lobe orders ``orders`` this design cannot tell from the errors it identifies.

    A touch-trigger probe's pre-travel varies with the approach azimuth ``phi``
    (machine frame: the probe turns with the spindle, not with C): a lobe of
    order ``k`` adds ``a cos k phi + b sin k phi`` to each normal deviation.
    Ibaraki et al. (section 2) assume it compensated; vmt's uncertainty does
    not include it. Where the lobe's columns lie in the design's column space
    the fit takes the lobe into its parameters exactly (no residual, so no
    model error is seen) and the U95 does not cover it: e.g. a pocket whose
    walls face 0/90/180/270 deg makes an odd ``k`` act with opposite signs on
    opposite walls, a translation per set-up (EXC/EYC). Computed from the
    design (the touches' approach azimuths and the estimator), not the data:
    the smallest principal angle between ``[cos k phi, sin k phi]`` and the
    column space (the fitted part of each column from ``est``), its worst phase
    absorbed when the sine is below :data:`LOBE_ALIAS_SIN`; the parameter
    blocks that take it and by how much per um of lobe.

    Returns a tuple of :class:`BlindLobe`, in the order of ``orders`` (empty:
    every order is seen at least that well).
    """
    d = np.asarray(touches.d_R, float)
    if d.shape[0] != design.A.shape[0]:
        raise ConfigError(f"blind_lobes: {d.shape[0]} touches for a design of {design.A.shape[0]} rows")
    phi = np.arctan2(d[:, 1], d[:, 0])
    A = design.A
    out = []
    for k in orders:
        if (QR := _lobe_basis(phi, k)) is None:
            continue
        Q, R = QR
        T = est.noise_gain(Q)                                        # the parameters the fit gives each column
        _, sv, Vt = np.linalg.svd(Q - A @ T, full_matrices=False)    # sv: sines of the principal angles
        sin_min = float(min(sv.min(), 1.0))
        if sin_min >= LOBE_ALIAS_SIN:
            continue
        V = Vt[sv < LOBE_ALIAS_SIN].T                                # the absorbed phases (in Q's coordinates)
        TV = T @ V
        fit = A @ TV
        tot = float(np.sum(fit * fit))
        share = {b: float(np.sum((A[:, sl] @ TV[sl]) * fit)) / tot if tot > 0 else 0.0
                 for b, sl in design.slices.items() if b != "ABBE"}
        # per unit lobe amplitude: the lobe's (cos, sin) coefficients are M w for phase w of V, M = R^-1 V;
        # a value's largest change over unit amplitudes in that span is sqrt(a (M^T M)^-1 a), a its row of TV.
        # m per m of lobe = um per um; rad per m = urad per um: the numbers as they stand
        M = np.linalg.solve(R, V)
        Gi = normal_inverse(M)  # (M^T M)^-1, its conditioning checked (review31d F6)
        big = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", TV, Gi, TV), 0.0))
        blocks = tuple(b for b, v_ in sorted(share.items(), key=lambda kv: -kv[1]) if v_ >= LOBE_ALIAS_SHARE)
        out.append(BlindLobe(k=int(k), angle_deg=float(np.degrees(np.arcsin(sin_min))),
                             absorbed=float(1 - sin_min ** 2), blocks=blocks,
                             per_um={b: float(np.max(big[design.slices[b]], initial=0.0)) for b in blocks}))
    return tuple(out)



def absorbed_lobes(phi: np.ndarray, project, orders=LOBE_ORDERS) -> tuple:
    """((k, principal angle deg), ...): the pre-travel lobe orders a model's column space absorbs.

    The model-free half of :func:`blind_lobes`, for a model given only as its
    projection: ``project(X)`` (n, r) -> the part of ``X`` in the model's
    column space (``Q (Q^T X)`` with ``Q`` an orthonormal basis, as the
    discovery baseline's). ``phi`` (n,) is the approach azimuth, machine frame,
    rad. An order is absorbed when the sine of its smallest principal angle to
    the span is below :data:`LOBE_ALIAS_SIN`, as in :func:`blind_lobes`.
    """
    phi = np.asarray(phi, float)
    if phi.ndim != 1 or phi.size == 0 or not np.all(np.isfinite(phi)):
        raise ConfigError(f"absorbed_lobes: phi must be a non-empty finite (n,) array, got shape {phi.shape}")
    out = []
    for k in orders:
        if (QR := _lobe_basis(phi, k)) is None:
            continue
        Q = QR[0]
        P = np.column_stack([np.asarray(project(Q[:, j]), float) for j in range(Q.shape[1])])
        sin_min = float(min(np.linalg.svd(Q - P, compute_uv=False).min(), 1.0))
        if sin_min < LOBE_ALIAS_SIN:
            out.append((int(k), float(np.degrees(np.arcsin(sin_min)))))
    return tuple(out)


#: The approach-direction test of :func:`direction_structure`: the residuals follow the approach azimuth
#: (the pre-travel lobe orders the design leaves a residual for, jointly) when the F test's p-value is below
#: this. One test per identification (all orders together: on a pocket's four wall directions the orders
#: 2, 4, 6 are nearly the same columns, so no per-order family to correct for). Session 29 (sclob29): plain
#: campaigns (nmv3000 errors none and realistic, seeds 1000-1019, and the demo) stay below it with a wide
#: margin, a 0.75 um 2-lobe probe reaches p ~ 1e-50.
DIRECTION_P = 1e-4


@dataclass(frozen=True, kw_only=True)
class _ResidualStructure:
    """What identify's residual checks (:func:`direction_structure`, :func:`time_structure`) share: the
    statistics and the structure's part of the residuals and of the parameters (as :class:`DirectionStructure`
    describes them)."""

    F: float
    p: float
    rank: int
    fitted_m: np.ndarray
    shift: np.ndarray
    basis: np.ndarray
    proj: np.ndarray
    p_tables: float | None = None


@dataclass(frozen=True, kw_only=True)
class DirectionStructure(_ResidualStructure):
    """Residuals that follow the probe's approach azimuth (:func:`direction_structure`).

    Attributes
    ----------
    k : int
        The lobe order that alone explains most of it.
    amplitude_m : float
        That order's amplitude ``sqrt(a^2 + b^2)`` fitted alone, m.
    orders : tuple of int
        The orders tested together (those the design leaves a residual for).
    F, p : float
        The joint F statistic and its p-value (against probing noise).
    rank : int
        Degrees of freedom the structure takes from the residuals.
    fitted_m : (n,) float
        Its part of the residuals (removed before the model-error budget).
    shift : (n_params,) float
        What it puts into the parameters: ``theta_hat`` minus the estimate with the structure fitted
        alongside (m / rad).
    basis : (n, rank) float
        Orthonormal basis of the lobe columns' part the fit leaves (``(I - H) L``).
    proj : (rank,) float
        The residuals along it (``basis^T r``).
    p_tables : float or None
        The p-value of ``proj`` against the model-error budget's noise and table model error
        (:func:`core.uncertainty.model_error_budget`'s ``probe_p``): small when the tables cannot explain it;
        None before the budget (or without one).
    order_gain : (n_params, 1 or 2) float or None
        What a lobe of order ``k`` puts into the parameters per unit of its columns' coefficients
        (``cos k phi``, ``sin k phi``; m per m, rad per m): the fit's gain on the whole lobe, the part
        the design absorbs included (review31 F4: ``shift`` holds only what the residuals show).
    """

    k: int
    amplitude_m: float
    orders: tuple
    order_gain: np.ndarray | None = None


def _structure_f(G: np.ndarray, r: np.ndarray, dof: int, p_max: float):
    """The first stage of identify's residual checks (:func:`direction_structure`, :func:`time_structure`): the
    residuals ``r`` (``dof`` degrees of freedom) projected on the columns ``G`` the fit leaves (those of unit size:
    directions the residuals can hold), F against the rest. None when nothing is held or ``p >= p_max``; else
    ``(U, sv, Vt, keep, q, proj, drop, F, p)`` of the SVD of ``G``. Noise-free residuals (the rest at rounding):
    F infinite, p 0."""
    from scipy import stats

    U, sv, Vt = np.linalg.svd(G, full_matrices=False)
    keep = sv > 1e-6 * np.sqrt(r.size)
    q = int(keep.sum())
    if q == 0 or dof - q <= 0:
        return None
    proj = U[:, keep].T @ r
    drop = float(proj @ proj)
    rest = float(r @ r) - drop
    if drop <= 1e-12 * float(r @ r) or drop <= 0.0:
        return None
    if rest <= 1e-12 * float(r @ r):
        F, p = float("inf"), 0.0
    else:
        F = (drop / q) / (rest / (dof - q))
        p = float(stats.f.sf(F, q, dof - q))
    if not p < p_max:
        return None
    return U, sv, Vt, keep, q, proj, drop, F, p


def direction_structure(design: SelfCalDesign, est: LinearEstimator, touches: Touches, residuals_m: np.ndarray,
                        blind: tuple = (), p_max: float = DIRECTION_P):
    """The part of the residuals that follows the approach azimuth, when significant; else None.

    A probe whose pre-travel depends on the approach direction (lobing) is a
    systematic the self-calibration model does not hold. Its orders the
    design absorbs are :func:`blind_lobes` (no residual shows them); the
    others leave a residual that is constant per approach direction, which
    the model-error budget would otherwise book as table misfit (x-normal
    touches on EXX, y-normal on EYY) and the probing noise would collapse.
    Here the columns ``cos k phi, sin k phi`` of every order in
    :data:`LOBE_ORDERS` not in ``blind``, their part the fit leaves
    (``(I - H) L``), are tested jointly against the residuals (F test,
    the residual variance beside them as the noise); significant at
    ``p_max``: their fitted part, the order that alone explains most, its
    amplitude, and the parameters' shift (``T c``: by Frisch-Waugh, the
    estimate with the structure fitted alongside is ``theta_hat - T c``).
    """
    r = np.asarray(residuals_m, float)
    d = np.asarray(touches.d_R, float)
    if d.shape[0] != r.size or r.size != design.A.shape[0]:
        raise ConfigError(f"direction_structure: {r.size} residuals, {d.shape[0]} touches, design of "
                          f"{design.A.shape[0]} rows")
    phi = np.arctan2(d[:, 1], d[:, 0])
    skip = {b.k for b in blind}
    raw, Gs, ks = [], [], []
    for k in LOBE_ORDERS:
        if k in skip:
            continue
        if (L := _lobe_columns(phi, k)) is None:
            continue
        raw.append(L)
        Gs.append(L - design.A @ est.noise_gain(L))
        ks.append(k)
    dof = r.size - est.n_free
    if not ks or dof <= 0:
        return None
    Lall, Gall = np.hstack(raw), np.hstack(Gs)
    first = _structure_f(Gall, r, dof, p_max)
    if first is None:
        return None
    U, sv, Vt, keep, q, proj, drop, F, p = first
    Uq = U[:, keep]
    c = Vt[keep].T @ (proj / sv[keep])           # coefficients on Lall's columns (minimum norm)
    fitted = Gall @ c
    TL = est.noise_gain(Lall)
    shift = TL @ c
    best, amp, best_drop, cols = ks[0], 0.0, -1.0, slice(0, 0)
    j0 = 0
    for k, L, G in zip(ks, raw, Gs):
        ck = np.linalg.lstsq(G, r, rcond=None)[0]
        dk = float(r @ (G @ ck))
        if dk > best_drop:
            best, amp, best_drop = k, float(np.hypot(*ck) if ck.size == 2 else abs(ck[0])), dk
            cols = slice(j0, j0 + L.shape[1])
        j0 += L.shape[1]
    return DirectionStructure(k=int(best), amplitude_m=amp, orders=tuple(int(k) for k in ks), F=float(F), p=p,
                              rank=q, fitted_m=fitted, shift=shift, basis=Uq, proj=proj, order_gain=TL[:, cols])


#: The parameter blocks the approach-direction note reports a bias for (with their report units).
DIRECTION_BLOCKS = ("EC0Y", "ECY", "ECX", "EXX", "EYY", "EXY", "EYX", "G", "EXC", "EYC", "ECC")


def direction_biases(design: SelfCalDesign, ds, std) -> dict:
    """Per parameter block: the largest shift the direction structure ``ds`` makes (``shift`` its magnitude,
    ``signed`` with its sign, um or urad) and its ratio to that value's U95 (k = 2 ``std``; None without one).

    That shift is the structure's VISIBLE part: what the residuals show. The part of a lobe the design absorbs
    leaves no residual and adds to it, so the true bias can be larger (review31 F4: the demo's order-2 lobe,
    re-simulated, moves EC0Y by 62.1 urad where the visible part says 40.0). With ``ds.order_gain`` (a
    :class:`DirectionStructure`) also ``worst_phase``: the largest change of one of the block's values a lobe
    of order ``ds.k`` and amplitude ``ds.amplitude_m`` makes at its worst phase, the absorbed part included
    (``amplitude x |row of order_gain|``), and ``worst_ratio_to_u95`` (that value's). A bound on that order's
    bias only as far as the amplitude found is the probe's: it is read from the residuals too (the demo: 1.24
    um found against 1.5 injected; its ECY 108 urad against the lobe's 130)."""
    out = {}
    gain = getattr(ds, "order_gain", None)
    for b in DIRECTION_BLOCKS:
        if b not in design.slices:
            continue
        sl = design.slices[b]
        sh = ds.shift[sl]
        if sh.size == 0:
            continue
        i = int(np.argmax(np.abs(sh)))
        u = None if std is None else 2.0 * float(np.asarray(std)[sl][i])
        out[b] = {"shift": abs(float(sh[i])) * 1e6, "signed": float(sh[i]) * 1e6,
                  "ratio_to_u95": (abs(float(sh[i])) / u if u else None), "unit": _alias_unit(b)}
        if gain is not None and gain.shape[1]:
            w = ds.amplitude_m * np.linalg.norm(gain[sl], axis=1)
            j = int(np.argmax(w))
            uj = None if std is None else 2.0 * float(np.asarray(std)[sl][j])
            out[b]["worst_phase"] = float(w[j]) * 1e6
            out[b]["worst_ratio_to_u95"] = float(w[j]) / uj if uj else None
    return out


def _big(biases: dict, ratio: str) -> list:
    return sorted(((b, v) for b, v in biases.items() if v.get(ratio) is not None and v[ratio] >= 0.5),
                  key=lambda kv: -kv[1][ratio])


def direction_text(ds, biases: dict) -> str:
    """The note on an approach-direction structure: what it is, its size, what its visible part shifts, and
    what a lobe of the order and amplitude found shifts at its worst phase, the part the design absorbs
    included (:func:`direction_biases`; review31 F4: the visible part is no upper bound)."""
    named = ", ".join(f"{b} by {v['shift']:.2f} {v['unit']} ({v['ratio_to_u95']:.1f} x its U95)"
                      for b, v in _big(biases, "ratio_to_u95"))
    worst = ", ".join(f"{b} by {v['worst_phase']:.2f} {v['unit']} ({v['worst_ratio_to_u95']:.1f} x its U95)"
                      for b, v in _big(biases, "worst_ratio_to_u95"))
    tail = ""
    if any("worst_phase" in v for v in biases.values()):
        tail = ("; the part the design absorbs is not seen and adds to it: a lobe of order "
                f"{ds.k} and ~{ds.amplitude_m * 1e6:.2f} um at its worst phase, absorbed part included, moves "
                + (worst if worst else "every value by under half its U95")
                + " (a bound only as good as that amplitude, itself read from the residuals)")
    return (f"residuals follow the approach direction (lobe orders {', '.join(map(str, ds.orders))} tested"
            f" together: p = {ds.p:.1e} against noise, {ds.p_tables:.1e} against noise and table model error):"
            f" a probe pre-travel lobing, mostly of order {ds.k}, ~{ds.amplitude_m * 1e6:.2f} um;"
            f" not booked as table model error (the probing sigma is the residuals' beside it), and not in the U95: "
            + (f"its visible part (what the residuals show) moves {named}" if named
               else "its visible part (what the residuals show) moves every value by under half its U95")
            + tail + "; vmt discover names and removes it (or compensate the pre-travel)")


# ---------------------------------------------------------------------------
# residuals that follow time (review30b F7): a drift inside the campaign
# ---------------------------------------------------------------------------
#: Name a drift in time in ``not_covered`` (:func:`time_structure`, confirmed against the budget's noise and
#: table model error): :func:`self_calibrate` runs it after the approach-direction test and the report gets
#: ``not_covered["time_drift"]`` (the U95, the budget and every value unchanged). Session 30 (time30), on the
#: review30b generator's cross pocket (368 touches, noise 0.3 um, 20 seeds each): plain 0/20, a 2 um / 15 mm EXX
#: ripple 0/20, the simulator's cross pocket (nmv3000 realistic, seeds 1-20, t_s clock) 0/20; an X drift of 3 um
#: over the campaign named 17/20, 2 um 6/20, 1 um 0/20. docs/discovery-studies.md "Session 30: identify's residuals that
#: follow time".
TIME_STRUCTURE = True
#: The time test's p-value threshold, both stages (as :data:`DIRECTION_P`).
TIME_P = 1e-4
#: Legendre degrees 1..this in the campaign's time (touch order when the log's t_s does not vary), per
#: machine direction X and Y along each touch's normal. Session 30 (time30): degree 1 (2 columns) names the
#: 3 um drift on 17/20 seeds, degree 2 on 15/20, degree 3 with a linear term per set-up (10 columns left)
#: on a few of 3 (p 6e-5, 1e-8, 5e-3): each column more dilutes the F test; a drift that is not linear in
#: time (a thermal approach) is seen by its linear part.
TIME_DEGREE_CAMPAIGN = 1
#: Legendre degrees 1..this in time within each set-up (its mean is the set-up's own EXC/EYC); 0: none
#: (the campaign's degrees hold a smooth drift's within-set-up part).
TIME_DEGREE_SETUP = 0


@dataclass(frozen=True, kw_only=True)
class TimeStructure(_ResidualStructure):
    """Residuals that follow time (:func:`time_structure`): a drift of the tool relative to the part.

    ``clock`` is "t_s" or "touch order"; ``drift_um`` the fitted drift's range over the campaign per machine
    direction (X, Y), um, up to what the set-ups' translations absorb; the rest as :class:`DirectionStructure`."""

    clock: str
    drift_um: tuple


def _time_clock(touches: Touches) -> tuple[np.ndarray, str]:
    t = np.asarray(touches.t_s, float)
    if t.size and np.all(np.isfinite(t)) and np.ptp(t) > 0:
        return t, "t_s"
    return np.argsort(np.argsort(np.asarray(touches.row), kind="stable"), kind="stable").astype(float), "touch order"


def time_columns(touches: Touches, deg_campaign: int | None = None, deg_setup: int | None = None):
    """(n, q) columns of a smooth drift in X and Y along each touch's normal, (n, q/2) the drift's own basis
    (Legendre in the campaign's time, then within each set-up), and the clock's name."""
    from numpy.polynomial import legendre

    deg_campaign = TIME_DEGREE_CAMPAIGN if deg_campaign is None else int(deg_campaign)
    deg_setup = TIME_DEGREE_SETUP if deg_setup is None else int(deg_setup)
    t, clock = _time_clock(touches)
    n = np.asarray(touches.n_R, float)
    if n.shape[0] != t.size:
        raise ConfigError(f"time_columns: {t.size} times for {n.shape[0]} touches")

    def leg(tau, k):
        return legendre.legval(tau, [0.0] * k + [1.0])

    span = np.ptp(t)
    tau = 2 * (t - t.min()) / span - 1 if span > 0 else np.zeros_like(t)
    B = [leg(tau, k) for k in range(1, deg_campaign + 1)]
    for j in np.unique(touches.setup):
        m = touches.setup == j
        tj = t[m]
        if np.ptp(tj) <= 0:
            continue
        tj = 2 * (tj - tj.min()) / np.ptp(tj) - 1
        for k in range(1, deg_setup + 1):
            col = np.zeros_like(t)
            col[m] = leg(tj, k)
            B.append(col)
    B = np.column_stack(B) if B else np.zeros((t.size, 0))
    # dq = -n . E (the tool's displacement relative to the part along the outward normal)
    L = np.hstack([-n[:, [0]] * B, -n[:, [1]] * B])
    return L, B, clock


def time_structure(design: SelfCalDesign, est: LinearEstimator, touches: Touches, residuals_m: np.ndarray,
                   p_max: float = TIME_P):
    """The part of the residuals that follows time (a drift in X, Y), when significant against the noise; else
    None. As :func:`direction_structure` (F test of the columns' part the fit leaves against the residual
    variance beside them), on :func:`time_columns`; the second stage (against the tables' model error) is the
    caller's, through :func:`core.uncertainty.model_error_budget`'s ``probe_cols``."""
    r = np.asarray(residuals_m, float)
    if r.size != touches.n or r.size != design.A.shape[0]:
        raise ConfigError(f"time_structure: {r.size} residuals, {touches.n} touches, design of "
                          f"{design.A.shape[0]} rows")
    L, B, clock = time_columns(touches)
    dof = r.size - est.n_free
    if L.shape[1] == 0 or dof <= 0:
        return None
    G = L - design.A @ est.noise_gain(L)
    first = _structure_f(G, r, dof, p_max)
    if first is None:
        return None
    U, sv, Vt, keep, q, proj, drop, F, p = first
    Uq = U[:, keep]
    c = Vt[keep].T @ (proj / sv[keep])
    h = B.shape[1]
    ex, ey = B @ c[:h], B @ c[h:]
    return TimeStructure(clock=clock, drift_um=(float(np.ptp(ex)) * 1e6, float(np.ptp(ey)) * 1e6), F=float(F), p=p,
                         rank=q, fitted_m=G @ c, shift=est.noise_gain(L) @ c, basis=Uq, proj=proj)


def time_text(ts, biases: dict) -> str:
    """The note on a drift in time: what it is, its size, what it biases."""
    big = sorted(((b, v) for b, v in biases.items() if v["ratio_to_u95"] is not None and v["ratio_to_u95"] >= 0.5),
                 key=lambda kv: -kv[1]["ratio_to_u95"])
    named = ", ".join(f"{b} by {v['shift']:.2f} {v['unit']} ({v['ratio_to_u95']:.1f} x its U95)" for b, v in big)
    return (f"residuals follow time ({ts.clock}; p = {ts.p:.1e} against noise, {ts.p_tables:.1e} against noise and "
            f"table model error): a drift of the tool relative to the part, fitted range X {ts.drift_um[0]:.2f} um, "
            f"Y {ts.drift_um[1]:.2f} um (beside what the set-ups' translations absorb); not in the U95: "
            + (f"its visible part (what the residuals show) moves {named}; the part the set-ups' translations absorb"
               " is not seen and adds to it, so the bias can be larger" if named
               else "its visible part (what the residuals show) moves every value by under half its U95; the part the"
                    " set-ups' translations absorb is not seen")
            + "; let the machine settle, or probe in an order that separates time from position")


# ---------------------------------------------------------------------------
# probing errors correlated in touch order (review32b F3.2): a test and, when it fires, the U95 they need
# ---------------------------------------------------------------------------
#: Test identify's residuals for lag-1 correlation in touch order within each set-up (:func:`serial_correlation`)
#: and, when significant at :data:`SERIAL_P`, widen the U95's probing part to what AR(1) errors of the
#: correlation found give (``not_covered["correlated_errors"]`` says so and by how much). Session 32 (unc32):
#: review32b's Monte Carlo (perfect nmv3000, cross pocket at 4 set-ups, 368 touches, 0.3 um) gave 79 / 89 / 93 %
#: coverage for AR(1) rho 0.8 / 0.5 / 0.3 with nothing said; docs/discovery-studies.md "Session 32: probing errors
#: correlated in touch order" for the coverage with this on. False: neither test nor widening.
SERIAL_CORRELATION = True
#: The serial test's one-sided p-value threshold (positive correlation). 1e-3: on independent noise it fires
#: once in a thousand identifications (then widens by the little a rho near 0 gives); AR(1) rho 0.3 on the
#: 368-touch pocket sits ~5 standard deviations out.
SERIAL_P = 1e-3
#: Take the serial test beside the model-error budget's entered fine tables too (a table misfit is smooth along
#: its axis, so correlated in touch order along a wall). Off: those tables are chosen by the data and take most of
#: an AR(1) wander with them (review32b's rho 0.8, 60 runs: the test then fires on 36 and coverage stays at
#: 89.9 %, against 60 and 93.5 % off). The test is always beside the declared ripples and the named
#: approach-direction and time structures.
SERIAL_BESIDE_TABLES = False
#: The serial test works on dense (touches x free parameters) arrays and its rho costs ~15 products of
#: touches x free^2: above this many cells, or this much work, it is not run (the report then has no
#: ``correlated_errors`` entry and the U95 takes the errors as independent, as before). The review's pocket:
#: 368 x 160 cells, 1e7 work.
SERIAL_MAX_CELLS = 2.0e7
SERIAL_MAX_WORK = 2.0e9


@dataclass(frozen=True)
class SerialCorrelation:
    """Residuals correlated in touch order (:func:`serial_correlation`).

    Attributes
    ----------
    r1 : float
        Lag-1 autocorrelation of the residuals over consecutive touches of one set-up (``r^T P r / r^T r`` times
        ``n / pairs``).
    r1_null : float
        Its expectation under independent errors through this fit (negative: the fit's own correlation).
    z, p : float
        ``(d - E d) / sd d`` of the ratio ``d = r^T P r / r^T r`` under independent normal errors (its exact
        first two moments through ``R = I - H``, Durbin & Watson 1950), and the normal tail beyond ``z``.
    rho : float
        The AR(1) coefficient (per touch, within a set-up) whose residuals' expected ratio equals ``d``
        (moment equation through the fit: the correlation the fit absorbed counted back in); 0 when ``d`` is
        below the independent expectation.
    sigma_m : float
        The errors' marginal standard deviation under that AR(1): ``r^T r / tr(R Sigma_rho)``, m.
    std : (n_params,) float or None
        The parameters' standard uncertainty, probing part AR(1)(rho, sigma) propagated through the estimator,
        the model-error budget's part beside it (at least the budget's own: never narrower); None when not
        computed.
    inflation : float
        The largest ratio of ``std`` to the budget's.
    clock : str
    significant : bool
        ``p`` below the threshold: ``rho``, ``sigma_m``, ``std`` (and ``cov``) are then set; else only the
        test's statistics (``rho`` 0, nothing widened).
    """

    r1: float
    r1_null: float
    z: float
    p: float
    rho: float
    sigma_m: float
    std: object = None
    cov: object = None
    inflation: float = 1.0
    clock: str = "touch order"
    significant: bool = False


def _touch_sequence(touches: Touches) -> tuple[np.ndarray, list, str]:
    """(order, segments, clock): the touches in time order (:func:`_time_clock`), stably by set-up; ``segments``
    the (start, stop) of each set-up's run in that order."""
    t, clock = _time_clock(touches)
    setup = np.asarray(touches.setup)
    order = np.lexsort((np.arange(t.size), t, setup))
    s = setup[order]
    cut = np.flatnonzero(np.diff(s) != 0) + 1
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [s.size]])
    return order, list(zip(starts.tolist(), stops.tolist())), clock


def _ar1_apply(X: np.ndarray, rho: float, order: np.ndarray, segments) -> np.ndarray:
    """``Sigma_rho X``: AR(1) correlation ``rho^|i - j|`` between touches i, j of one set-up in touch order,
    0 across set-ups (forward and backward first-order filters: O(n) per column)."""
    from scipy.signal import lfilter

    X = np.asarray(X, float)
    Y = np.empty_like(X)
    Xo = X[order]
    Yo = np.empty_like(Xo)
    for a, b in segments:
        seg = Xo[a:b]
        f = lfilter([1.0], [1.0, -rho], seg, axis=0)
        bk = lfilter([1.0], [1.0, -rho], seg[::-1], axis=0)[::-1]
        Yo[a:b] = f + bk - seg
    Y[order] = Yo
    return Y


def serial_correlation(design: SelfCalDesign, est: LinearEstimator, touches: Touches, residuals_m: np.ndarray,
                       u_now=None, u_model=None, cov_model=None, *, full: bool = False, beside=None,
                       p_max: float = SERIAL_P):
    """Lag-1 correlation of the residuals in touch order within each set-up: a :class:`SerialCorrelation`
    (``significant`` at ``p_max``, one-sided, positive; None when there are not two consecutive pairs).

    ``d = r^T P r / r^T r`` (``P`` symmetric, 1/2 on each pair of consecutive touches of one set-up) under
    independent normal errors through the fit (``r = R e``, ``R = I - H``, ``H = B M^-1 B^T``): ``E d = tr(R P) /
    nu``, ``var d = 2 (nu tr((R P)^2) - tr(R P)^2) / (nu^2 (nu + 2))``, ``nu = tr R`` (Durbin & Watson's moments;
    the traces through ``M^-1`` (n_free square), no n x n matrix). When significant: the AR(1) ``rho`` whose
    expected ratio ``tr(R P R S) / tr(R S)`` (``S`` its correlation) equals ``d`` (bisection), the marginal sigma
    ``r^T r / tr(R S)``, and the parameters' probing covariance ``sigma^2 T S T^T`` (``T`` the estimator's gain):
    an AR(1) model of the correlation, the simplest that has one parameter per lag decay; a HAC (Newey-West)
    sandwich from the residuals alone would miss what the fit absorbs (the residual sigma falls from 0.3 to 0.2
    um at rho 0.8)."""
    from scipy import stats

    r = np.asarray(residuals_m, float)
    if r.size != touches.n or r.size != design.A.shape[0]:
        raise ConfigError(f"serial_correlation: {r.size} residuals, {touches.n} touches, design of "
                          f"{design.A.shape[0]} rows")
    n = r.size
    if n * est.n_free > SERIAL_MAX_CELLS or n * float(est.n_free) ** 2 > SERIAL_MAX_WORK:
        return None
    order, segs, clock = _touch_sequence(touches)
    i = np.concatenate([order[a:b - 1] for a, b in segs if b - a > 1] or [np.zeros(0, int)])
    j = np.concatenate([order[a + 1:b] for a, b in segs if b - a > 1] or [np.zeros(0, int)])
    pairs = i.size
    rr = float(r @ r)
    if pairs < 2 or rr <= 0.0:
        return None
    P = sp.coo_matrix((np.full(2 * pairs, 0.5), (np.concatenate([i, j]), np.concatenate([j, i]))),
                      shape=(n, n)).tocsr()
    B = est.B
    Bd0 = B.toarray() if sp.issparse(B) else np.asarray(B)
    K0 = est._solve_M(np.eye(est.n_free))                # M^-1, n_free square: the estimator's own
    if beside is None or np.asarray(beside).shape[1] == 0:
        Bd, K, nu = Bd0, K0, n - est.n_free
    else:   # the test beside the columns given too (model error the budget holds, a structure already named)
        X = np.asarray(beside, float)
        if X.shape[0] != n:
            raise ConfigError(f"serial_correlation: beside has {X.shape[0]} rows for {n} touches")
        Bd = np.hstack([Bd0, X])
        nrm = np.linalg.norm(Bd, axis=0)
        Ub, sb, _ = np.linalg.svd(Bd[:, nrm > 0] / nrm[nrm > 0], full_matrices=False)
        Bd = Ub[:, sb > sb[0] * 1e-8]                     # an orthonormal basis of span(B, X): H = Bd Bd^T
        K = np.eye(Bd.shape[1])
        nu = n - Bd.shape[1]
        r = r - Bd @ (K @ (Bd.T @ r))                     # the residuals beside those columns too
        rr = float(r @ r)
        if rr <= 0.0:
            return None
    PB = P @ Bd
    BPB = Bd.T @ PB
    KBPB = K @ BPB
    tr_RP = -float(np.trace(KBPB))                      # tr P = 0
    tr_PP = float(P.multiply(P).sum())
    tr_RPRP = tr_PP - 2.0 * float(np.trace(K @ (PB.T @ PB))) + float(np.sum(KBPB * KBPB.T))
    if nu <= 2:
        return None
    Ed = tr_RP / nu
    var = 2.0 * (nu * tr_RPRP - tr_RP ** 2) / (nu ** 2 * (nu + 2.0))
    d = float(r @ (P @ r)) / rr
    z = (d - Ed) / np.sqrt(var) if var > 0 else 0.0
    p = float(stats.norm.sf(z))
    r1_scale = n / pairs
    if not p < p_max:
        return SerialCorrelation(r1=d * r1_scale, r1_null=Ed * r1_scale, z=float(z), p=p, rho=0.0, sigma_m=float("nan"),
                                 clock=clock, significant=False)

    def ratio(rho):                                       # E[r^T P r] / E[r^T r] under AR(1) rho
        SB = _ar1_apply(Bd, rho, order, segs)
        KBSB = K @ (Bd.T @ SB)
        tr_S = float(n)
        tr_RS = tr_S - float(np.trace(KBSB))
        # tr(R P R S) = tr(PS) - tr(HPS) - tr(PHS) + tr(HPHS)
        tr_PS = rho * pairs                               # S_ij = rho for each consecutive pair, P 1/2 twice
        tr_HPS = float(np.sum(K * (SB.T @ PB)))           # tr(H P S) = tr(P H S) = tr(K (S B)^T P B)
        tr_HPHS = float(np.sum((KBPB) * (KBSB).T))
        return (tr_PS - 2.0 * tr_HPS + tr_HPHS) / tr_RS, tr_RS, SB

    lo, hi = 0.0, 0.99
    if ratio(lo)[0] >= d:
        rho = 0.0
    else:
        if ratio(hi)[0] <= d:
            lo = hi
        for _ in range(40):
            if hi - lo < 1e-4:
                break
            mid = 0.5 * (lo + hi)
            if ratio(mid)[0] < d:
                lo = mid
            else:
                hi = mid
        rho = 0.5 * (lo + hi)
    _, tr_RS, _ = ratio(rho)
    sigma = float(np.sqrt(rr / tr_RS))
    SB0 = _ar1_apply(Bd0, rho, order, segs)
    G = K0 @ (Bd0.T @ SB0) @ K0                           # M^-1 B^T S B M^-1: the estimator's gain
    DZ = est.DZ
    cov_p = sigma ** 2 * np.asarray(DZ @ np.asarray(DZ @ G).T)
    var_p = np.maximum(np.diag(cov_p), 0.0)
    std = cov = None
    infl = 1.0
    if u_now is not None:
        u_old = np.asarray(u_now, float)
        var_model = 0.0 if u_model is None else np.asarray(u_model, float) ** 2
        std = np.maximum(np.sqrt(var_p + var_model), u_old)
        ok = u_old > 1e-12 * max(float(u_old.max()), 1e-300)
        infl = float(np.max(std[ok] / u_old[ok])) if ok.any() else 1.0
        if full:
            cov = cov_p + (0.0 if cov_model is None else cov_model)
    return SerialCorrelation(r1=d * r1_scale, r1_null=Ed * r1_scale, z=float(z), p=p, rho=float(rho),
                             sigma_m=sigma, std=std, cov=cov, inflation=infl, clock=clock, significant=True)


def _serial_beside(des: SelfCalDesign, touches: Touches, budget, subgrid, direction, time,
                   tables: bool = True) -> np.ndarray | None:
    """The columns the serial test is taken beside: the fine tables the model-error budget entered (their
    residual is model error it already holds: a table misfit is smooth along the axis, so correlated in touch
    order along a wall), the declared sub-grid ripples', and the approach-direction and time structures named."""
    from .uncertainty import MODEL_ERROR_CORR_M, MODEL_ERROR_STEP_M, _check_subgrid, _fine_table, _ripple_table

    cols = []
    ell = MODEL_ERROR_CORR_M if not isinstance(MODEL_ERROR_CORR_M, tuple) else MODEL_ERROR_CORR_M[0]
    for k, v in (budget.components.items() if tables else ()):
        if v > 0 and k in des.slices:
            cols.append(_fine_table(des, touches, k, MODEL_ERROR_STEP_M, ell)[0].toarray())
    for k, v in (subgrid or {}).items():
        if k in des.slices and _check_subgrid(k, v)[0] > 0:
            cols.append(_ripple_table(des, touches, k, _check_subgrid(k, v)[1])[0])
    for s in (direction, time):
        if s is not None:
            cols.append(np.asarray(s.basis, float))
    return np.hstack(cols) if cols else None


def serial_text(sc: SerialCorrelation) -> str:
    """The note on residuals correlated in touch order: the test, the AR(1) it reads, what the U95 now holds."""
    if not sc.significant:
        return (f"the U95 takes the probing errors as independent; tested ({sc.clock}, consecutive touches of one "
                f"set-up): lag-1 autocorrelation {sc.r1:.2f} against {sc.r1_null:.2f} expected of independent errors,"
                f" z = {sc.z:.1f}, p = {sc.p:.1e}, not significant at {SERIAL_P:g}; a correlation the test does not"
                f" see (on a 368-touch pocket at 0.3 um: AR(1) rho below ~0.15) or one across set-ups is not covered")
    return (f"residuals are correlated in touch order within the set-ups ({sc.clock}; lag-1 autocorrelation "
            f"{sc.r1:.2f} against {sc.r1_null:.2f} expected of independent errors through this fit, z = {sc.z:.1f},"
            f" p = {sc.p:.1e}): probing errors that are not independent (vibration, thermal wander of the probe, a "
            f"drift faster than the set-up), read as AR(1) per touch rho = {sc.rho:.2f}, marginal sigma "
            f"{sc.sigma_m * 1e6:.3f} um; the U95 above holds them as such (widened up to {sc.inflation:.2f} x the "
            f"independent-error U95); an error correlated another way (not AR(1), across set-ups) is not covered")


# ---------------------------------------------------------------------------
# a lobe too small to be named (review32b F3.3): the detection limit per order and the bias it leaves
# ---------------------------------------------------------------------------
#: Name in ``not_covered["undetected_lobes"]``, per lobe order the design leaves a residual for, the amplitude the
#: approach-direction test (:func:`direction_structure`) names half the time on this design at this sigma, and
#: the bias a lobe of that amplitude puts into the parameters (:func:`lobe_detection_limits`). Session 32 (unc32):
#: review32b's 0.1-0.15 um 2-lobe, unnamed, left EC0Y inside its U95 in 87-88 % of runs with nothing said.
LOBE_DETECTION_LIMITS = True
#: The detection probability the limit is quoted at.
LOBE_DETECTION_POWER = 0.5


@dataclass(frozen=True)
class LobeLimit:
    """A lobe order's detection limit (:func:`lobe_detection_limits`).

    ``amplitude_m``: the lobe amplitude the approach-direction test names with probability
    :data:`LOBE_DETECTION_POWER` (phase-averaged noncentrality, first stage against the noise: the second stage
    against the tables can only name fewer); ``per_um``: per block, the largest change of one value a 1 um lobe
    of this order makes at its worst phase, absorbed part included (um/um, urad/um); ``ratio``: per block, the
    largest ratio of that change at ``amplitude_m`` to the value's U95."""

    k: int
    amplitude_m: float
    per_um: dict
    ratio: dict

    def text(self) -> str:
        big = sorted(((b, v) for b, v in self.ratio.items() if v >= 0.5), key=lambda kv: -kv[1])
        what = ", ".join(f"{b} {self.per_um[b] * self.amplitude_m * 1e6:.2f} {_alias_unit(b)} ({v:.1f} x U95)"
                         for b, v in big[:4])
        return (f"k = {self.k}: ~{self.amplitude_m * 1e6:.2f} um is named half the time; a lobe that size, unnamed, "
                f"moves " + (what if what else "every value by under half its U95"))


def lobe_limits_text(limits: tuple) -> str:
    """The note on lobes too small to be named: per order, the amplitude named half the time and its bias."""
    return ("a pre-travel lobe smaller than the approach-direction test names is neither named nor in the U95 "
            "(its absorbed part biases the values): " + "; ".join(L.text() for L in limits))


def lobe_detection_limits(design: SelfCalDesign, est: LinearEstimator, touches: Touches, sigma_m: float,
                          std, blind: tuple = (), p_max: float = DIRECTION_P,
                          power: float = LOBE_DETECTION_POWER) -> tuple:
    """Per lobe order of :data:`LOBE_ORDERS` not in ``blind``: the amplitude :func:`direction_structure`'s F test
    names with probability ``power`` (noncentral F, ``q`` and ``dof - q`` degrees of freedom as the test's, the
    noncentrality ``a^2 (|G c|^2 + |G s|^2) / (2 sigma^2)`` with ``G`` the order's columns the fit leaves: phase
    averaged) and the bias a lobe of that amplitude leaves in the parameters (the fit's gain on the whole lobe,
    worst phase), against the U95 (``2 std``). Computed from the design and sigma, not from the data's lobe."""
    from scipy import optimize, stats

    if not (sigma_m > 0) or std is None:
        return ()
    d = np.asarray(touches.d_R, float)
    phi = np.arctan2(d[:, 1], d[:, 0])
    skip = {b.k for b in blind}
    cols, gains, ks = [], [], []
    for k in LOBE_ORDERS:
        if k in skip or (L := _lobe_columns(phi, k)) is None:
            continue
        T = est.noise_gain(L)
        cols.append(L - design.A @ T)
        gains.append(T)
        ks.append(k)
    if not ks:
        return ()
    sv = np.linalg.svd(np.hstack(cols), compute_uv=False)
    q = int(np.sum(sv > 1e-6 * np.sqrt(phi.size)))
    dof = phi.size - est.n_free
    if q == 0 or dof - q <= 0:
        return ()
    Fc = stats.f.isf(p_max, q, dof - q)
    U = 2.0 * np.asarray(std, float)
    out = []
    for k, G, T in zip(ks, cols, gains):
        lam1 = float(np.sum(G * G)) / G.shape[1]   # noncentrality per (amplitude / sigma)^2, phase averaged
        if lam1 <= 0:
            continue

        def pw(a):   # a: amplitude in sigmas
            return float(stats.ncf.sf(Fc, q, dof - q, a * a * lam1)) - power

        hi = 1.0
        while pw(hi) < 0 and hi < 1e6:
            hi *= 4.0
        a50 = (float(optimize.brentq(pw, 0.0, hi, xtol=1e-9)) * sigma_m if pw(0.0) < 0 < pw(hi)
               else float("nan"))
        per, ratio = {}, {}
        rows = np.linalg.norm(T, axis=1)
        for b in DIRECTION_BLOCKS:
            if b not in design.slices:
                continue
            sl = design.slices[b]
            if rows[sl].size == 0:
                continue
            per[b] = float(rows[sl].max())
            u = U[sl]
            ok = u > 0
            ratio[b] = float(np.max(a50 * rows[sl][ok] / u[ok])) if ok.any() else float("nan")
        out.append(LobeLimit(k=int(k), amplitude_m=a50, per_um=per, ratio=ratio))
    return tuple(out)


def not_covered(blind: tuple) -> dict:
    """The report's statement of what the U95 leaves out (:func:`blind_lobes` of the design), JSON-ready."""
    orders = ", ".join(str(k) for k in LOBE_ORDERS)
    if blind:
        what = ("the probe's pre-travel lobes of order k = " + ", ".join(str(b.k) for b in blind)
                + " (approach azimuth, machine frame) are absorbed by this design into the parameters named:"
                  " no residual shows them, no model error is budgeted for them, and the U95 does not cover them;"
                  " compensate the pre-travel or change the design (approach azimuths that separate them)")
    else:
        what = (f"every pre-travel lobe order k = {orders} leaves a residual on this design (none absorbed at a"
                f" principal angle below {np.degrees(np.arcsin(LOBE_ALIAS_SIN)):.1f} deg); their effect is in the"
                " residuals and the model-error budget, not hidden in the parameters")
    return {"checked_lobe_orders": list(LOBE_ORDERS), "what": what,
            "pretravel_lobes": [{"k": b.k, "principal_angle_deg": _r(b.angle_deg, 2),
                                 "absorbed_share": _r(b.absorbed, 4), "into": list(b.blocks),
                                 "per_um_of_lobe": {k: _r(v, 3) for k, v in b.per_um.items()},
                                 "units": {k: _alias_unit(k) + "/um" for k in b.blocks}}
                                for b in blind]}


def blind_lobes_line(blind: tuple) -> str | None:
    """One line for the CLI: the lobe orders the U95 does not cover and where they go, or None."""
    if not blind:
        return None
    return ("not covered by U95: probe pre-travel lobes this design absorbs (compensate them): "
            + "; ".join(b.text() for b in blind))


# ---------------------------------------------------------------------------
# error map and workpiece form: what an identification is compared with
# ---------------------------------------------------------------------------
def error_map(res: SelfCalResult) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """E_X,total and E_Y,total (eqs 4-5) on the grid nodes from the identified tables.

    Returns
    -------
    x_m : (N_x,) float
    y_m : (N_y,) float
        The grid nodes, machine frame R, m.
    ex_m, ey_m : (N_x, N_y) float
        Tip position error in X and Y at each node (C = 0), m, in the
        identification's gauge (eqs 16-17).
    """
    g = res.design.grid
    X, Y = np.meshgrid(g.x_m, g.y_m, indexing="ij")
    ex = res.EXX[:, None] + res.EXY[None, :] - Y * res.EC0Y
    ey = res.EYX[:, None] + res.EYY[None, :]
    if res.yaw == Yaw.ECY:  # X rides on Y (eq 5)
        ey = ey + X * res.ECY[None, :]
    else:  # Y rides on X
        ex = ex - Y * res.ECX[:, None]
    return g.x_m, g.y_m, ex, ey


def map_gauge_basis(x_m, y_m) -> np.ndarray:
    """(2 N, 4) directions of an (E_X, E_Y) map on nodes (x, y) that self-calibration cannot see.

    A translation in X and in Y, a rotation about Z and a scale (the map's
    part of the gauge of eqs 16-17), stacked as ``[E_X; E_Y]`` over the
    ``N`` points (``x_m``, ``y_m`` flattened alike).
    """
    x, y = np.ravel(x_m), np.ravel(y_m)
    one, zero = np.ones_like(x), np.zeros_like(x)
    return np.vstack([np.column_stack([one, zero, -y, x]), np.column_stack([zero, one, x, y])])


def map_in_gauge(x_m, y_m, ex_true, ey_true, ex_m, ey_m) -> tuple[np.ndarray, np.ndarray]:
    """The true error map expressed in the gauge of an identified one.

    Self-calibration determines the map only up to a translation, a rotation
    and (without delta_L) a scale (:func:`map_gauge_basis`): the part of
    ``identified - true`` those explain is added to the truth, so the two
    can be compared. All maps of one shape, m; ``x_m``, ``y_m`` the node
    coordinates of each entry (e.g. ``np.meshgrid(..., indexing="ij")``).

    Returns
    -------
    (ex, ey) : the truth in the identification's gauge, shapes of ``ex_true``.
    """
    shape = np.shape(ex_true)
    E = np.concatenate([np.ravel(ex_true), np.ravel(ey_true)])
    r = np.concatenate([np.ravel(ex_m), np.ravel(ey_m)]) - E
    Ea = E + (r - remove_span(r, map_gauge_basis(x_m, y_m)))
    n = Ea.size // 2
    return Ea[:n].reshape(shape), Ea[n:].reshape(shape)


def target_heights(t: Touches, n_targets: int):
    """``(first, dz)``: each target's first touch (row index, targets ``0 .. n_targets - 1`` in order) and its
    nominal height above the most common targets' level, m (heights rounded to 1e-6 m), the ``dz_m`` of
    :func:`workpiece_gauge_basis` and :func:`workpiece_form`; None where a target has no touch."""
    seen, first = np.unique(np.asarray(t.target, int), return_index=True)
    if seen.size != n_targets:
        return None
    z = np.round(t.pn_R[first, 2], 6)
    lv, cnt = np.unique(z, return_counts=True)
    return first, z - lv[np.argmax(cnt)]


def workpiece_gauge_basis(w_W, wn_W, dz_m=None) -> np.ndarray:
    """(N_w, 5 or 9) workpiece deviations G that self-calibration cannot see (eqs 16-17).

    A shift of the part in X and in Y (``wn . t``), a rotation in W
    (``wn . R90 w``), a scale (``wn . w``) and a common offset (the stylus
    radius), for targets at contact points ``w_W`` (N_w, 2), m, with outward
    unit normals ``wn_W`` (N_w, 2), both in W. With ``dz_m`` (N_w,), each
    target's height above the reference probing level (m; 0 on it), also
    what the height terms cannot see (:class:`HeightTerms`): a tilt of the
    part (``dz wn . u``, two), a twist and a growth of the raised targets in
    proportion to their height (``dz wn . R90 w``, ``dz wn . w``).
    """
    P, N = np.asarray(w_W, float), np.asarray(wn_W, float)
    rot, scl = -N[:, 0] * P[:, 1] + N[:, 1] * P[:, 0], np.einsum("ij,ij->i", N, P)
    B = np.column_stack([N[:, 0], N[:, 1], rot, scl, np.ones(len(P))])
    if dz_m is None or not np.any(np.asarray(dz_m) != 0):
        return B
    dz = np.asarray(dz_m, float)
    return np.hstack([B, dz[:, None] * np.column_stack([N[:, 0], N[:, 1], rot, scl])])


def workpiece_form(g, w_W, wn_W, dz_m=None) -> np.ndarray:
    """``g`` (N_w,) per target less what a shift, rotation and scale of the part and a
    common offset would give (and, with ``dz_m``, what the height terms cannot see:
    :func:`workpiece_gauge_basis`): the workpiece form that self-calibration sees, in
    the unit of ``g``."""
    return remove_span(np.asarray(g, float), workpiece_gauge_basis(w_W, wn_W, dz_m))


# ---------------------------------------------------------------------------
# nominal touches (plans, studies without simulation)
# ---------------------------------------------------------------------------
def rot2(a_rad) -> np.ndarray:
    """(..., 2, 2) rotation by ``a_rad`` counter-clockwise (eq 2 uses R(-C))."""
    a = np.asarray(a_rad, float)
    c, s = np.cos(a), np.sin(a)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def nominal_touches(w_W: np.ndarray, wn_W: np.ndarray, c_deg, *, stylus_r_m: float = 0.0,
                    target_ids=None, dq_m: np.ndarray | None = None) -> Touches:
    """Touches of a plan: every target at every C angle (eq 1).

    Parameters
    ----------
    w_W : (N_w, 2) float
        Nominal contact points, workpiece frame W, m.
    wn_W : (N_w, 2) float
        Outward unit normals, W.
    c_deg : sequence of float
        C angles, degrees (one set-up each, named ``C=<deg>``).
    stylus_r_m : float
        Stylus radius: nominal tip centre = contact + r n.
    dq_m : (N_c * N_w,) float or None
        Normal deviations to report (set-up major order); None = 0.
    """
    w = np.asarray(w_W, float)
    wn = np.asarray(wn_W, float)
    if w.ndim != 2 or w.shape[1] != 2 or wn.shape != w.shape:
        raise ConfigError(f"w_W and wn_W must both be (N_w, 2), got {w.shape} and {wn.shape}")
    c = np.asarray(c_deg, float).ravel()
    if len(set(c.tolist())) != c.size:
        raise ConfigError(f"C angles repeat: {c.tolist()}")
    nw, nc = len(w), len(c)
    R = rot2(-c * DEG)  # (N_c, 2, 2), eq 1
    tip = w + stylus_r_m * wn
    pn = np.einsum("jab,ib->jia", R, tip).reshape(-1, 2)
    nR = np.einsum("jab,ib->jia", R, wn).reshape(-1, 2)
    m = nw * nc
    z = np.zeros((m, 1))
    pn3 = np.hstack([pn, z])
    n3 = np.hstack([nR, z])
    dq = np.zeros(m) if dq_m is None else np.asarray(dq_m, float).ravel()
    if dq.shape != (m,):
        raise ConfigError(f"dq_m: expected ({m},), got {dq.shape}")
    ids = tuple(target_ids) if target_ids is not None else tuple(f"p{i + 1}" for i in range(nw))
    sids = tuple(f"C={v:g}" for v in c)
    return Touches(row=np.arange(m), p_R=pn3 + dq[:, None] * n3, pn_R=pn3, n_R=n3, d_R=-n3,
                   rot_rad=np.column_stack([np.zeros(m), np.zeros(m), np.repeat(c * DEG, nw)]),
                   t_s=np.arange(m, dtype=float), setup=np.repeat(np.arange(nc), nw),
                   target=np.tile(np.arange(nw), nc), setup_ids=sids, target_ids=ids,
                   feature=np.array([""] * m, dtype=object),
                   w_A=np.hstack([np.tile(w, (nc, 1)), z]), wn_A=np.hstack([np.tile(wn, (nc, 1)), z]),
                   temps_C={})


#: A touch whose residual is more than this many times the RMS of the residuals below it dominates the
#: identification (:func:`dominant_rows`; review32d F3: one reading typed 10 mm off gave a residual RMS of 364 um
#: that identify blamed on the error tables, naming no row). Probing noise alone never does it: the largest of
#: 10^6 normal residuals is 5 sigma; a model error the tables miss spreads over many touches (each under a few
#: times the RMS); 10 is a gross error, a reading to check.
DOMINANT_Z = 10.0
#: At most this many dominant touches are named (the first ones by size; the rest counted).
DOMINANT_MOST = 3


def dominant_rows(residuals) -> np.ndarray:
    """Indices of the touches whose residual dominates (:data:`DOMINANT_Z`), largest first: sorted by size,
    each taken while it exceeds DOMINANT_Z times the RMS of the residuals smaller than it (so a second gross
    error does not hide the first). Empty for a fit without one (or fewer than 3 residuals)."""
    r = np.abs(np.asarray(residuals, float))
    if r.size < 3 or not np.all(np.isfinite(r)):
        return np.zeros(0, np.int64)
    order = np.argsort(-r, kind="stable")
    sq = r[order] ** 2
    below = np.sqrt((np.cumsum(sq[::-1])[::-1] - sq) / np.arange(r.size - 1, -1, -1).clip(1))  # RMS of the rest
    out = []
    for k in range(r.size - 2):
        if not r[order[k]] > DOMINANT_Z * below[k]:
            break
        out.append(order[k])
    return np.asarray(out, np.int64)
