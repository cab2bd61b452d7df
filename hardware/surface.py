"""Surface probing: the plan of a rectangular grid probed along Z, and that plan from a file.

The commonest real probing job (bCNC, UGS, Candle "auto-level", LinuxCNC's
``gridprobe.ngc`` / ``smartprobe.ngc``) probes a surface straight down at
the nodes of an XY grid. :func:`grid_plan` writes that job as a
``probe-log/1`` plan; :func:`plan_from_z_touches` rebuilds the plan from
the touches alone, for a controller's file that came without one.

Each touch: nominal stylus-tip centre ``(x, y, z + r)`` over a surface of
nominal height ``z`` (stylus radius ``r``), outward normal ``+Z``, approach
``-Z``. Targets are named ``r<row>c<col>`` (row along Y, column along X,
0-based); rows are probed in a serpentine (X forward on even rows, back on
odd rows), the order the usual senders use.
"""

from __future__ import annotations

import math

import numpy as np

from core.exceptions import ConfigError, counted
from core.probelog import FORMAT, ProbeLog, make_log

#: XY coordinates closer than this (mm) are the same grid line / target.
SAME_MM = 1e-3


#: Most touches a grid plan may hold (a plan is a file a controller runs touch by touch).
MAX_GRID_TOUCHES = 100_000


def axis_nodes(lo_mm: float, hi_mm: float, step_mm: float, name: str) -> np.ndarray:
    """Nodes ``lo, lo + step, ..., hi`` (mm); ``hi - lo`` must be a multiple of ``step``.

    More than :data:`MAX_GRID_TOUCHES` nodes are refused before any array is
    made (``--x-mm 0:1e9:1`` asked numpy for 8 GB and then a copy of it).
    """
    vals = (lo_mm, hi_mm, step_mm)
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in vals):
        raise ConfigError(f"{name} {lo_mm}:{hi_mm}:{step_mm}: not finite numbers")
    if step_mm <= 0 or hi_mm < lo_mm:
        raise ConfigError(f"{name} {lo_mm:g}:{hi_mm:g}:{step_mm:g}: expected lo <= hi and step > 0")
    k = (hi_mm - lo_mm) / step_mm
    if abs(k - round(k)) > 1e-9 * max(1.0, k):
        raise ConfigError(f"{name} {lo_mm:g}:{hi_mm:g}:{step_mm:g}: the span is not a whole number of steps")
    if round(k) + 1 > MAX_GRID_TOUCHES:
        raise ConfigError(f"{name} {lo_mm:g}:{hi_mm:g}:{step_mm:g}: {round(k) + 1:.0f} nodes, "
                          f"more than {MAX_GRID_TOUCHES} touches")
    return lo_mm + step_mm * np.arange(int(round(k)) + 1)


def _plan(xy_mm: np.ndarray, targets: list[str], z_tip_mm: np.ndarray, meta: dict,
          source: str) -> ProbeLog:
    n = len(targets)
    nan = np.full(n, np.nan)
    cols = {"setup": ["grid"] * n, "target": targets, "t_s": nan, "X_mm": nan, "Y_mm": nan,
            "Z_mm": nan, "Xn_mm": xy_mm[:, 0], "Yn_mm": xy_mm[:, 1], "Zn_mm": z_tip_mm,
            "nx": np.zeros(n), "ny": np.zeros(n), "nz": np.ones(n),
            "dx": np.zeros(n), "dy": np.zeros(n), "dz": -np.ones(n), "feature": ["surface"] * n}
    return make_log(cols, {"format": FORMAT, "artefact": "surface", **meta}, source=source)


def grid_plan(x_mm: tuple, y_mm: tuple, z_mm: float = 0.0, *, stylus_r_mm: float = 0.0,
              serpentine: bool = True) -> ProbeLog:
    """The plan of a rectangular grid probed along Z.

    Parameters
    ----------
    x_mm, y_mm : (lo, hi, step) mm
        Grid lines along X and Y, machine frame.
    z_mm : float
        Nominal height of the surface, machine frame, mm.
    stylus_r_mm : float
        Stylus tip radius (0 for a pin or a tool used as the probe), mm.
    serpentine : bool
        Reverse X on odd rows (shortest travel); False: every row forward.

    Returns
    -------
    ProbeLog
        A plan (measured columns empty), one row per node.

    Raises
    ------
    ConfigError
        Bad ranges, a negative radius, more than 100 000 nodes.
    """
    xs, ys = axis_nodes(*x_mm, "--x-mm"), axis_nodes(*y_mm, "--y-mm")
    if not (math.isfinite(z_mm) and math.isfinite(stylus_r_mm) and stylus_r_mm >= 0):
        raise ConfigError(f"z_mm {z_mm!r} / stylus_r_mm {stylus_r_mm!r}: need finite numbers, radius >= 0")
    if xs.size * ys.size > MAX_GRID_TOUCHES:
        raise ConfigError(f"grid of {xs.size} x {ys.size} nodes: more than {MAX_GRID_TOUCHES} touches")
    xy, names = [], []
    for j, y in enumerate(ys):
        cols = range(xs.size)
        if serpentine and j % 2:
            cols = reversed(cols)
        for i in cols:
            xy.append((xs[i], y))
            names.append(f"r{j}c{i}")
    xy = np.array(xy, dtype=float)
    meta = {"stylus_r_mm": repr(float(stylus_r_mm)),
            "plan": f"surface grid {xs.size} x {ys.size}: X {xs[0]:g}..{xs[-1]:g} mm, "
                    f"Y {ys[0]:g}..{ys[-1]:g} mm, surface Z {z_mm:g} mm, probed along -Z"}
    return _plan(xy, names, np.full(len(names), z_mm + stylus_r_mm), meta, "<vmt plan grid>")


def _grid_index(v: np.ndarray) -> tuple[np.ndarray, int]:
    """Index of each value among the distinct values (within SAME_MM), and their count."""
    order = np.argsort(v, kind="stable")
    idx = np.empty(v.size, dtype=int)
    k, last = -1, None
    for o in order:
        if last is None or v[o] - last > SAME_MM:
            k += 1
            last = v[o]
        idx[o] = k
    return idx, k + 1


class NotAGrid(ConfigError):
    """Touches that are not the nodes of a surface grid (review30 F2: a pocket's wall touches, read without
    their plan, became a "Z grid" of 83 points whose plane fit said a flatness of 26 mm, exit 0)."""


def plan_from_z_touches(pos_mm, *, z_mm: float | None = None, source: str = "<probe file>") -> ProbeLog:
    """The plan of a surface (Z) probing job, rebuilt from its touches.

    Parameters
    ----------
    pos_mm : (n, 3) float
        Reported X, Y, Z of each touch, machine frame, mm, in probing order.
    z_mm : float or None
        Nominal tip-centre height; ``None``: the median of the touches' Z (then
        ``dq`` is each touch's height above the median).

    Returns
    -------
    ProbeLog
        A plan: nominal ``(X, Y, z)`` per touch, normal ``+Z``, approach ``-Z``,
        targets ``r<row>c<col>``; touches at the same XY (repeats) share a target.

    Raises
    ------
    ConfigError
        Not an (n, 3) array of finite numbers.
    NotAGrid
        The XY points are not a rectangular grid's nodes (every combination of
        the distinct X and Y lines, within :data:`SAME_MM`, each once or more):
        no :func:`grid_plan` makes them, so the touches' nominals, normals and
        approach are not known from the file (a grid run that stopped short is
        one of these: its missing nodes are not known either).
    """
    p = np.asarray(pos_mm, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0 or not np.all(np.isfinite(p)):
        raise ConfigError(f"{source}: touches must be a non-empty (n, 3) array of finite numbers")
    ix, nx = _grid_index(p[:, 0])
    iy, ny = _grid_index(p[:, 1])
    cells = set(zip(iy.tolist(), ix.tolist()))
    if len(cells) != nx * ny:
        raise NotAGrid(f"{source}: {counted(len(p), 'touch')} at {counted(len(cells), 'XY point')} on "
                       f"{nx} X and {ny} Y lines are not the {nx * ny} nodes of a surface grid (each X line "
                       "with each Y line), the one job whose plan the file alone says")
    names = [f"r{j}c{i}" for j, i in zip(iy, ix)]
    zt = float(np.median(p[:, 2])) if z_mm is None else float(z_mm)
    meta = {"plan": f"built from {len(p)} touches probed along -Z (grid {nx} x {ny}); nominal tip-centre Z "
                    f"{zt:.6f} mm ({'median of the touches' if z_mm is None else 'given'})"}
    return _plan(p[:, :2].copy(), names, np.full(len(p), zt), meta, source)
