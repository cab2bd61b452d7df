"""Truth error functions injected into the virtual machine.

Each is a small frozen dataclass, vectorised::

    f(pos, t_s=None, direction=None) -> (n,) float

``pos`` is the axis position (m for a linear axis: the machine passes its
reading plus the probe offset, ``q = reading + J``, :mod:`sim.machine`; rad
for a rotary axis),
``t_s`` seconds since the campaign start (None: 0), ``direction`` the sign
of the axis velocity at that moment (-1, 0, +1; None: 0). The value is in
m for a translational error, rad for an angular one (``core.iso``).
``f.derivative(pos, t_s, direction)`` is d f / d pos (direction held).

Kinds: :class:`Zero`, :class:`Constant`, :class:`Polynomial`,
:class:`SplineTable`, :class:`LinearTable`, :class:`Periodic`, :class:`Drift`, :class:`Reversal`,
:class:`Sum` (also ``f + g``), and :class:`CrossAxis`, the one kind that
also depends on another axis's reading (a non-rigid machine: the machine
passes every reading through ``f.evaluate(pos, t_s, direction, axes)``).
Bad parameters raise ``ConfigError``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from core.exceptions import ConfigError


def _finite(name: str, v) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a number, got {v!r}") from None
    if not math.isfinite(x):
        raise ConfigError(f"{name} must be finite, got {v!r}")
    return x


def _tuple(name: str, vs) -> tuple[float, ...]:
    try:
        seq = tuple(vs)
    except TypeError:
        raise ConfigError(f"{name} must be a sequence of numbers, got {vs!r}") from None
    return tuple(_finite(f"{name}[{i}]", v) for i, v in enumerate(seq))


class ErrorFunction:
    """Base of the truth error functions (see module docstring)."""

    def __call__(self, pos, t_s=None, direction=None) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def derivative(self, pos, t_s=None, direction=None) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    @property
    def static(self) -> bool:
        """True when the value depends on the position only."""
        return True

    def evaluate(self, pos, t_s=None, direction=None, axes=None) -> np.ndarray:
        """Value with every axis reading at hand (``axes``: axis -> (n,));
        only :class:`CrossAxis` (and sums holding one) uses ``axes``."""
        return self(pos, t_s, direction)

    def __add__(self, other: "ErrorFunction") -> "Sum":
        if not isinstance(other, ErrorFunction):
            return NotImplemented
        if isinstance(self, Constant) and isinstance(other, Constant):
            return Constant(self.value + other.value)  # stays a valid location error
        return Sum((self, other))


@dataclass(frozen=True)
class Zero(ErrorFunction):
    """No error."""

    def __call__(self, pos, t_s=None, direction=None):
        return np.zeros(np.atleast_1d(np.asarray(pos, float)).shape)

    derivative = __call__


@dataclass(frozen=True)
class Constant(ErrorFunction):
    """A constant value (m or rad); the only kind allowed for location errors."""

    value: float

    def __post_init__(self):
        object.__setattr__(self, "value", _finite("Constant.value", self.value))

    def __call__(self, pos, t_s=None, direction=None):
        return np.full(np.atleast_1d(np.asarray(pos, float)).shape, self.value)

    def derivative(self, pos, t_s=None, direction=None):
        return np.zeros(np.atleast_1d(np.asarray(pos, float)).shape)


@dataclass(frozen=True)
class Polynomial(ErrorFunction):
    """``sum_i coeffs[i] * pos**i`` (ascending powers; SI units per power)."""

    coeffs: tuple[float, ...]

    def __post_init__(self):
        c = _tuple("Polynomial.coeffs", self.coeffs)
        if not c:
            raise ConfigError("Polynomial.coeffs must have at least one coefficient")
        object.__setattr__(self, "coeffs", c)

    def __call__(self, pos, t_s=None, direction=None):
        return np.polynomial.polynomial.polyval(np.atleast_1d(np.asarray(pos, float)), self.coeffs)

    def derivative(self, pos, t_s=None, direction=None):
        d = np.polynomial.polynomial.polyder(self.coeffs) if len(self.coeffs) > 1 else [0.0]
        return np.polynomial.polynomial.polyval(np.atleast_1d(np.asarray(pos, float)), d)


@dataclass(frozen=True)
class SplineTable(ErrorFunction):
    """Cubic C2 spline through a table (``pos`` strictly increasing).

    Not-a-knot end conditions (natural for 3 points or fewer); outside the
    table the end tangent lines continue (C1), never a runaway cubic.
    """

    pos: tuple[float, ...]
    values: tuple[float, ...]
    _spline: object = field(init=False, repr=False, compare=False, default=None)
    _ends: tuple = field(init=False, repr=False, compare=False, default=())

    def __post_init__(self):
        from scipy.interpolate import CubicSpline

        x = _tuple("SplineTable.pos", self.pos)
        y = _tuple("SplineTable.values", self.values)
        if len(x) < 2:
            raise ConfigError(f"SplineTable needs at least 2 points, got {len(x)}")
        if len(x) != len(y):
            raise ConfigError(f"SplineTable.pos has {len(x)} points but values has {len(y)}")
        if np.any(np.diff(x) <= 0):
            raise ConfigError("SplineTable.pos must be strictly increasing")
        object.__setattr__(self, "pos", x)
        object.__setattr__(self, "values", y)
        bc = "not-a-knot" if len(x) > 3 else "natural"
        s = CubicSpline(np.array(x), np.array(y), bc_type=bc)
        object.__setattr__(self, "_spline", s)
        # value and slope at both ends, for the tangent lines outside the table
        object.__setattr__(self, "_ends", (s(x[0]), s(x[0], 1), s(x[-1]), s(x[-1], 1)))

    def __call__(self, pos, t_s=None, direction=None):
        p = np.atleast_1d(np.asarray(pos, float))
        x0, x1 = self.pos[0], self.pos[-1]
        y0, dy0, y1, dy1 = self._ends
        out = self._spline(np.clip(p, x0, x1))
        lo, hi = p < x0, p > x1
        out = np.where(lo, y0 + dy0 * (p - x0), out)
        return np.where(hi, y1 + dy1 * (p - x1), out)

    def derivative(self, pos, t_s=None, direction=None):
        p = np.atleast_1d(np.asarray(pos, float))
        return self._spline(np.clip(p, self.pos[0], self.pos[-1]), 1)


class SplineStack:
    """Several :class:`SplineTable` on the same knots, evaluated in one call.

    The tables' own piecewise-polynomial coefficients side by side (one
    ``scipy.interpolate.PPoly`` with a trailing axis of tables) and their end
    tangent lines as arrays: row ``k`` of ``stack(pos)`` is
    ``tables[k](pos)`` by the same coefficients and the same compiled
    evaluation, in one pass over the positions instead of one per table.

    Parameters
    ----------
    tables : sequence of SplineTable
        At least one; all with the same ``pos``.
    """

    def __init__(self, tables):
        from scipy.interpolate import PPoly

        tables = tuple(tables)
        if not tables or any(not isinstance(t, SplineTable) or t.pos != tables[0].pos for t in tables):
            raise ConfigError("SplineStack needs SplineTables on the same knots")
        self.tables = tables
        self.x0, self.x1 = tables[0].pos[0], tables[0].pos[-1]
        c = np.stack([np.asarray(t._spline.c, float) for t in tables], axis=-1)  # (4, knots - 1, m)
        self._pp = PPoly.construct_fast(c, np.asarray(tables[0]._spline.x, float))
        self._ends = np.array([[float(v) for v in t._ends] for t in tables]).T  # (4, m): y0, dy0, y1, dy1

    def __call__(self, pos) -> np.ndarray:
        """(m, n) values of the m tables at the positions (n,)."""
        p = np.atleast_1d(np.asarray(pos, float))
        y0, dy0, y1, dy1 = self._ends
        out = np.ascontiguousarray(self._pp(np.clip(p, self.x0, self.x1)).T)
        lo, hi = p < self.x0, p > self.x1
        if lo.any():
            out = np.where(lo, y0[:, None] + dy0[:, None] * (p - self.x0), out)
        if hi.any():
            out = np.where(hi, y1[:, None] + dy1[:, None] * (p - self.x1), out)
        return out


@dataclass(frozen=True)
class LinearTable(ErrorFunction):
    """Linear interpolation in a table (``pos`` strictly increasing).

    Outside the table the end segments continue (a straight line through the
    last two points), like :class:`SplineTable`'s end tangents.
    """

    pos: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self):
        x = _tuple("LinearTable.pos", self.pos)
        y = _tuple("LinearTable.values", self.values)
        if len(x) < 2:
            raise ConfigError(f"LinearTable needs at least 2 points, got {len(x)}")
        if len(x) != len(y):
            raise ConfigError(f"LinearTable.pos has {len(x)} points but values has {len(y)}")
        if np.any(np.diff(x) <= 0):
            raise ConfigError("LinearTable.pos must be strictly increasing")
        object.__setattr__(self, "pos", x)
        object.__setattr__(self, "values", y)

    def _segment(self, p):
        x = np.asarray(self.pos)
        k = np.clip(np.searchsorted(x, p, side="right") - 1, 0, len(x) - 2)
        return k, (np.asarray(self.values)[k + 1] - np.asarray(self.values)[k]) / (x[k + 1] - x[k])

    def __call__(self, pos, t_s=None, direction=None):
        p = np.atleast_1d(np.asarray(pos, float))
        k, slope = self._segment(p)
        return np.asarray(self.values)[k] + slope * (p - np.asarray(self.pos)[k])

    def derivative(self, pos, t_s=None, direction=None):
        return self._segment(np.atleast_1d(np.asarray(pos, float)))[1]


@dataclass(frozen=True)
class Periodic(ErrorFunction):
    """``amplitude * sin(2 pi pos / period + phase)``: e.g. screw pitch error.

    amplitude in m or rad, period in m or rad (> 0), phase in rad.
    """

    amplitude: float
    period: float
    phase: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "amplitude", _finite("Periodic.amplitude", self.amplitude))
        object.__setattr__(self, "period", _finite("Periodic.period", self.period))
        object.__setattr__(self, "phase", _finite("Periodic.phase", self.phase))
        if self.period <= 0:
            raise ConfigError(f"Periodic.period must be > 0, got {self.period}")

    def __call__(self, pos, t_s=None, direction=None):
        p = np.atleast_1d(np.asarray(pos, float))
        return self.amplitude * np.sin(2 * np.pi * p / self.period + self.phase)

    def derivative(self, pos, t_s=None, direction=None):
        p = np.atleast_1d(np.asarray(pos, float))
        k = 2 * np.pi / self.period
        return self.amplitude * k * np.cos(k * p + self.phase)


@dataclass(frozen=True)
class Drift(ErrorFunction):
    """Offset and scale change growing with time (thermal drift).

    ``value = (offset_rate + scale_rate * pos) * h(t)
    + (offset_per_K + scale_per_K * pos) * dT(t)``

    with ``h(t) = t`` or, given ``tau_s``, ``tau (1 - exp(-t / tau))``
    (first-order approach to a steady state), and ``dT(t)`` the temperature
    history ``temperature_K`` at ``temperature_t_s`` (linear interpolation,
    held at the ends) minus its first value.

    Attributes
    ----------
    offset_rate : float  (m/s or rad/s)
    scale_rate : float   (1/s)
    tau_s : float or None
    offset_per_K : float (m/K or rad/K)
    scale_per_K : float  (1/K; e.g. 11.5e-6 for a steel scale)
    temperature_t_s, temperature_K : tuples of float
    """

    offset_rate: float = 0.0
    scale_rate: float = 0.0
    tau_s: float | None = None
    offset_per_K: float = 0.0
    scale_per_K: float = 0.0
    temperature_t_s: tuple[float, ...] = ()
    temperature_K: tuple[float, ...] = ()

    def __post_init__(self):
        for k in ("offset_rate", "scale_rate", "offset_per_K", "scale_per_K"):
            object.__setattr__(self, k, _finite(f"Drift.{k}", getattr(self, k)))
        if self.tau_s is not None:
            tau = _finite("Drift.tau_s", self.tau_s)
            if tau <= 0:
                raise ConfigError(f"Drift.tau_s must be > 0, got {tau}")
            object.__setattr__(self, "tau_s", tau)
        ts = _tuple("Drift.temperature_t_s", self.temperature_t_s)
        Ks = _tuple("Drift.temperature_K", self.temperature_K)
        if len(ts) != len(Ks):
            raise ConfigError(f"Drift.temperature_t_s has {len(ts)} samples but temperature_K has {len(Ks)}")
        if len(ts) and np.any(np.diff(ts) <= 0):
            raise ConfigError("Drift.temperature_t_s must be strictly increasing")
        if (self.offset_per_K or self.scale_per_K) and not ts:
            raise ConfigError("Drift.offset_per_K/scale_per_K need a temperature history")
        object.__setattr__(self, "temperature_t_s", ts)
        object.__setattr__(self, "temperature_K", Ks)

    @property
    def static(self) -> bool:
        return False

    def _time(self, p, t_s):
        t = np.zeros(p.shape) if t_s is None else np.broadcast_to(np.asarray(t_s, float), p.shape)
        h = t if self.tau_s is None else self.tau_s * -np.expm1(-t / self.tau_s)
        if self.temperature_t_s:
            dT = np.interp(t, self.temperature_t_s, self.temperature_K) - self.temperature_K[0]
        else:
            dT = np.zeros(p.shape)
        return h, dT

    def __call__(self, pos, t_s=None, direction=None):
        p = np.atleast_1d(np.asarray(pos, float))
        h, dT = self._time(p, t_s)
        return (self.offset_rate + self.scale_rate * p) * h + (self.offset_per_K + self.scale_per_K * p) * dT

    def derivative(self, pos, t_s=None, direction=None):
        p = np.atleast_1d(np.asarray(pos, float))
        h, dT = self._time(p, t_s)
        return self.scale_rate * h + self.scale_per_K * dT


@dataclass(frozen=True)
class Reversal(ErrorFunction):
    """Direction-dependent error (lost motion): ``lost_motion/2`` added to the
    axis in the direction it moves (``sense="lead"``, the default) or against
    it (``sense="lag"``); 0 when ``direction`` is 0 or None.

    The error is added to the actual position (``Machine.tip_W``: actual =
    reading + error). A LEAD (``+lost_motion/2`` moving in +, ``-lost_motion/2``
    moving in -) puts the axis ahead of its reading in the direction it moves;
    a LAG (``-lost_motion/2`` moving in +, ``+lost_motion/2`` moving in -) is
    the usual backlash, the carriage stopping short of its reading. ISO 230-2's
    signed reversal value (2.12, ``B_i = x_up - x_down``, deviation = actual
    minus target) is :attr:`reversal_value`: ``+lost_motion`` for a lead,
    ``-lost_motion`` for a lag, and discover reports it with that sign as
    ``x_lost_motion_um`` / ``y_lost_motion_um`` (core.causes.reversal_scans).
    ``lost_motion >= 0`` is the size (2.13's unsigned ``B`` of the axis).
    """

    lost_motion: float
    sense: str = "lead"

    def __post_init__(self):
        v = _finite("Reversal.lost_motion", self.lost_motion)
        if v < 0:
            raise ConfigError(f"Reversal.lost_motion must be >= 0 (its sign is sense, \"lead\" or \"lag\"), "
                              f"got {v}")
        if self.sense not in ("lead", "lag"):
            raise ConfigError(f"Reversal.sense must be \"lead\" or \"lag\", got {self.sense!r}")
        object.__setattr__(self, "lost_motion", v)

    @property
    def reversal_value(self) -> float:
        """ISO 230-2's signed reversal value ``B_i = x_up - x_down`` of this error (m): +size lead, -size lag."""
        return self.lost_motion if self.sense == "lead" else -self.lost_motion

    @property
    def static(self) -> bool:
        return False

    def __call__(self, pos, t_s=None, direction=None):
        p = np.atleast_1d(np.asarray(pos, float))
        if direction is None:
            return np.zeros(p.shape)
        half = 0.5 * self.lost_motion if self.sense == "lead" else -0.5 * self.lost_motion
        return half * np.sign(np.broadcast_to(np.asarray(direction, float), p.shape))

    def derivative(self, pos, t_s=None, direction=None):
        return np.zeros(np.atleast_1d(np.asarray(pos, float)).shape)


@dataclass(frozen=True)
class Sum(ErrorFunction):
    """Sum of error functions."""

    terms: tuple[ErrorFunction, ...]

    def __post_init__(self):
        terms = tuple(self.terms) if isinstance(self.terms, (list, tuple)) else None
        if not terms:
            raise ConfigError("Sum.terms must be a non-empty sequence of error functions")
        for i, t in enumerate(terms):
            if not isinstance(t, ErrorFunction):
                raise ConfigError(f"Sum.terms[{i}] is {type(t).__name__}, not an error function")
        object.__setattr__(self, "terms", terms)

    @property
    def static(self) -> bool:
        return all(t.static for t in self.terms)

    def __call__(self, pos, t_s=None, direction=None):
        return sum(t(pos, t_s, direction) for t in self.terms)

    def evaluate(self, pos, t_s=None, direction=None, axes=None):
        return sum(t.evaluate(pos, t_s, direction, axes) for t in self.terms)

    def derivative(self, pos, t_s=None, direction=None):
        return sum(t.derivative(pos, t_s, direction) for t in self.terms)


@dataclass(frozen=True)
class CrossAxis(ErrorFunction):
    """A non-rigid coupling: ``k (pos - pos0) (other - other0)``.

    The error of one axis depends on the reading of ``other`` (a linear
    axis), which no rigid-body model of independent axes can produce
    (a guideway bent by the load of another axis). ``k`` in m/m^2 for a
    translational error, rad/m^2 for an angular one.
    """

    k: float
    other: str
    pos0: float = 0.0
    other0: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "k", _finite("CrossAxis.k", self.k))
        object.__setattr__(self, "pos0", _finite("CrossAxis.pos0", self.pos0))
        object.__setattr__(self, "other0", _finite("CrossAxis.other0", self.other0))
        if self.other not in ("X", "Y", "Z"):
            raise ConfigError(f"CrossAxis.other must be a linear axis X, Y or Z, got {self.other!r}")

    def __call__(self, pos, t_s=None, direction=None):
        raise ConfigError(f"CrossAxis needs the reading of axis {self.other}: call evaluate(..., axes=...)")

    def evaluate(self, pos, t_s=None, direction=None, axes=None):
        if axes is None or self.other not in axes:
            raise ConfigError(f"CrossAxis needs the reading of axis {self.other}")
        p = np.atleast_1d(np.asarray(pos, float))
        return self.k * (p - self.pos0) * (np.asarray(axes[self.other], float) - self.other0)

    def derivative(self, pos, t_s=None, direction=None):
        raise ConfigError("CrossAxis has no derivative along its own axis alone; it couples two axes")
