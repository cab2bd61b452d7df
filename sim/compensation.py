"""A controller's compensation on the virtual machine (the truth stays untouched).

Two compensators wrap a :class:`sim.machine.Machine` (or anything with
``tip_W``) and change only the commands it receives: the exact chain, its
error functions and the scene are the same machine, so re-running a
campaign on the wrapper and identifying again closes the loop through the
exact simulator.

:class:`AxisCompensation` is LinuxCNC's per-joint screw compensation as
LinuxCNC implements it (``src/emc/motion/control.c``,
``compute_screw_comp()``; tables loaded by ``usrmotLoadComp()`` in
``src/emc/motion/usrmotintf.cc`` and ``EMCMOT_SET_JOINT_COMP`` in
``src/emc/motion/command.c``): the joint is commanded to ``pos_cmd + trim``
(``motor_pos_cmd = pos_cmd + backlash_filt + motor_offset``, ``output_to_hal``)
while the reported position stays ``pos_cmd`` (``pos_fb = motor_pos_fb -
backlash_filt - motor_offset``), so the scale reading in a probe log is the
uncompensated command. ``trim`` is the forward trim when the joint moves in
+, the reverse trim in -; a file of TYPE 0 holds ``nominal forward
reverse`` (the positions where the joint really is when commanded to
``nominal``) and the loader stores ``trim = nominal - forward`` (resp.
reverse). Between entries the trim is linear in ``pos_cmd``; below the
first entry it is the first trim, from the last entry on the last trim
(the table's sentinels at -DBL_MAX and +DBL_MAX, ``motion.c``). A joint
that does not move keeps the trim of its last motion: the simulated
touches carry no history, so the wrapper uses one stated direction
(``idle_direction``) for joints at rest; a table with equal forward and
reverse columns gives the same trim either way. The ramp of the
correction (``backlash_filt`` limited by the joint's velocity and
acceleration) has settled at the slow probing feeds and is not modelled.

:class:`VolumetricCompensation` is a controller with volumetric
compensation: it corrects each commanded tip position by the 21-error model
at that position (core's exact chain with the error tables), solving
``tip_model(q') = tip_nominal(q)`` for the command ``q'`` by fixed-point
iteration.

Positions: the wrapped machine's readings (stylus-tip centre in R, m).
LinuxCNC indexes its tables by joint position, which is the reading plus
the tool offset in effect, and vmt's error functions are functions of the
joint positions too (``sim.machine``, ``core.kinematics``: ``q = reading +
J``), so both controllers look their tables up at ``reading + J`` with the
probe offsets J of the stylus mounted (the wrapped machine's ``J_m``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from core import iso
from core.exceptions import ConfigError

#: LinuxCNC's largest table (``EMCMOT_COMP_SIZE``, src/emc/motion/motion.h).
LINUXCNC_COMP_SIZE = 256


@dataclass(frozen=True)
class JointTable:
    """One joint's compensation table as LinuxCNC holds it after loading.

    Attributes
    ----------
    nominal_m : (k,) float
        Strictly increasing joint positions, m.
    fwd_trim_m, rev_trim_m : (k,) float
        ``nominal - forward`` and ``nominal - reverse`` (TYPE 0 files), m:
        what is added to the command when moving in + / in -.
    """

    nominal_m: tuple
    fwd_trim_m: tuple
    rev_trim_m: tuple

    def __post_init__(self):
        cols = []
        for name in ("nominal_m", "fwd_trim_m", "rev_trim_m"):
            v = np.asarray(getattr(self, name), float).ravel()
            if not np.all(np.isfinite(v)):
                raise ConfigError(f"JointTable.{name} must be finite")
            cols.append(v)
        nom, fwd, rev = cols
        if not (len(nom) == len(fwd) == len(rev) >= 1):
            raise ConfigError(f"JointTable: columns of {len(nom)}, {len(fwd)}, {len(rev)} entries, "
                              "expected equal and at least one")
        if len(nom) > LINUXCNC_COMP_SIZE:
            raise ConfigError(f"JointTable: {len(nom)} entries, LinuxCNC holds at most {LINUXCNC_COMP_SIZE}")
        if np.any(np.diff(nom) <= 0):
            raise ConfigError("JointTable: compensation values must increase (nominal strictly increasing)")
        for name, v in zip(("nominal_m", "fwd_trim_m", "rev_trim_m"), cols):
            object.__setattr__(self, name, tuple(v.tolist()))

    @classmethod
    def from_type0(cls, rows_m) -> "JointTable":
        """From TYPE 0 rows ``(nominal, forward, reverse)`` (k, 3), m."""
        r = np.asarray(rows_m, float)
        if r.ndim != 2 or r.shape[1] != 3:
            raise ConfigError(f"TYPE 0 rows must be (k, 3), got shape {r.shape}")
        return cls(tuple(r[:, 0]), tuple(r[:, 0] - r[:, 1]), tuple(r[:, 0] - r[:, 2]))

    def trim(self, pos_m, direction) -> np.ndarray:
        """(n,) trim at joint positions ``pos_m`` (n,), moving in ``direction`` (n,) signs, m.

        ``compute_screw_comp()``: linear between entries, the end trims held
        beyond them; forward trim for direction > 0, reverse for < 0.
        """
        p = np.asarray(pos_m, float)
        d = np.broadcast_to(np.asarray(direction, float), p.shape)
        fwd = np.interp(p, self.nominal_m, self.fwd_trim_m)
        rev = np.interp(p, self.nominal_m, self.rev_trim_m)
        return np.where(d < 0, rev, fwd)


class _Wrapper:
    """Proxy of a machine whose commands are changed before they reach it."""

    def __init__(self, machine):
        self.machine = machine

    def __getattr__(self, k):
        return getattr(self.machine, k)

    @property
    def rotary_axes(self):
        return tuple(getattr(self.machine, "rotary_axes", ()) or ())

    def commanded(self, lin_m, rot_rad=None, direction=None) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def tip_W(self, lin_m, rot_rad=None, t_s=None, direction=None) -> np.ndarray:
        """ACTUAL stylus-tip centre in W (n, 3) for the readings ``lin_m``: the
        wrapped machine at the compensated command."""
        return self.machine.tip_W(self.commanded(lin_m, rot_rad, direction), rot_rad, t_s, direction)

    def T_R_W(self, lin_m, rot_rad=None, t_s=None, direction=None) -> np.ndarray:
        return self.machine.T_R_W(self.commanded(lin_m, rot_rad, direction), rot_rad, t_s, direction)

    def T_R_P(self, lin_m, rot_rad=None, t_s=None, direction=None) -> np.ndarray:
        return self.machine.T_R_P(self.commanded(lin_m, rot_rad, direction), rot_rad, t_s, direction)


class AxisCompensation(_Wrapper):
    """LinuxCNC per-joint compensation (module doc) in front of a machine.

    Parameters
    ----------
    machine : object with ``tip_W`` (``sim.machine.Machine``)
    tables : mapping axis ("X", "Y", "Z") -> JointTable
        Joints without a table are not compensated.
    joint_offset_m : (3,) float, optional
        Joint position minus reading per axis, m: default the wrapped
        machine's probe offsets ``config.J_m`` (the stylus mounted: the joint
        really is at reading + J, whatever stylus the files were measured with).
    idle_direction : {+1, -1}
        The trim of a joint at rest during a touch: forward (+1) or reverse.
    """

    def __init__(self, machine, tables: Mapping[str, JointTable], joint_offset_m=None,
                 idle_direction: int = 1):
        super().__init__(machine)
        t = {}
        for a, tab in dict(tables).items():
            if a not in iso.LINEAR_AXES:
                raise ConfigError(f"AxisCompensation: tables for linear axes X, Y, Z, got {a!r}")
            if not isinstance(tab, JointTable):
                raise ConfigError(f"AxisCompensation: table of {a} is a {type(tab).__name__}, not a JointTable")
            t[a] = tab
        off = np.asarray(machine.config.J_m if joint_offset_m is None else joint_offset_m, float)
        if off.shape != (3,) or not np.all(np.isfinite(off)):
            raise ConfigError(f"joint_offset_m must be 3 finite values, got {joint_offset_m!r}")
        if idle_direction not in (1, -1):
            raise ConfigError(f"idle_direction must be +1 or -1, got {idle_direction!r}")
        self.tables = t
        self.joint_offset_m = off
        self.idle_direction = int(idle_direction)

    def commanded(self, lin_m, rot_rad=None, direction=None) -> np.ndarray:
        """(n, 3) readings the joints really go to: ``reading + trim(reading + offset)``."""
        lin = np.atleast_2d(np.asarray(lin_m, float))
        d = np.zeros_like(lin) if direction is None else np.broadcast_to(np.sign(np.asarray(direction, float)),
                                                                         lin.shape)
        out = lin.copy()
        for a, tab in self.tables.items():
            i = iso.LINEAR_AXES.index(a)
            di = np.where(d[:, i] == 0, self.idle_direction, d[:, i])
            out[:, i] = lin[:, i] + tab.trim(lin[:, i] + self.joint_offset_m[i], di)
        return out


def _table_function(x, v):
    """The error table as a function of the axis position, interpolated as
    :func:`core.volumetric.spline_weights` does (C2 not-a-knot for 4 nodes or
    more, natural for 2-3, as SplineTable; continued along the end tangents)."""
    from scipy.interpolate import CubicSpline

    x, v = np.asarray(x, float), np.asarray(v, float)
    if len(x) == 1:
        return lambda u: np.full(np.shape(u), v[0])
    cs = CubicSpline(x, v, bc_type="not-a-knot" if len(x) >= 4 else "natural")
    d0, d1 = cs(x[0], 1), cs(x[-1], 1)

    def f(u):
        u = np.asarray(u, float)
        out = cs(np.clip(u, x[0], x[-1]))
        return np.where(u < x[0], v[0] + d0 * (u - x[0]), np.where(u > x[-1], v[-1] + d1 * (u - x[-1]), out))
    return f


@dataclass(frozen=True)
class ErrorModel:
    """The 21 linear-axis errors as a controller holds them (tables, SI).

    Attributes
    ----------
    chain : str
        ISO 10791 chain the model is for.
    tables : mapping symbol -> ((k,) nodes m, (k,) values m or rad)
        Motion errors, interpolated as :func:`core.volumetric.spline_weights`
        does (C2 not-a-knot, natural below 4 nodes, end tangents beyond the end nodes).
    constants : mapping symbol -> float
        Squarenesses (rad).
    rotary_points_R_m : mapping axis -> (3,) float
    """

    chain: str
    tables: Mapping
    constants: Mapping
    rotary_points_R_m: Mapping

    def __post_init__(self):
        fns = {}
        for s, (x, v) in dict(self.tables).items():
            sy = iso.symbol(s)
            if sy.location or sy.axis not in iso.LINEAR_AXES:
                raise ConfigError(f"ErrorModel: {s} is not a motion error of a linear axis")
            x, v = np.asarray(x, float), np.asarray(v, float)
            if x.ndim != 1 or x.shape != v.shape or len(x) < 1 or np.any(np.diff(x) <= 0):
                raise ConfigError(f"ErrorModel: table of {s} must be increasing nodes and equal-length values")
            fns[s] = (iso.LINEAR_AXES.index(sy.axis), _table_function(x, v))
        for s in self.constants:
            if iso.symbol(s).name not in iso.SQUARENESS:
                raise ConfigError(f"ErrorModel: constant {s} is not a squareness")
        object.__setattr__(self, "_fns", fns)

    def values(self, lin_m) -> dict:
        """symbol -> (n,) error values at the axis (joint) positions (n, 3), reading + J."""
        lin = np.atleast_2d(np.asarray(lin_m, float))
        out = {s: f(lin[:, i]) for s, (i, f) in self._fns.items()}
        for s, v in self.constants.items():
            out[s] = np.full(len(lin), float(v))
        return out


class VolumetricCompensation(_Wrapper):
    """A controller correcting each command by the 21-error model (module doc).

    The command ``q'`` for a wanted reading ``q`` solves
    ``tip_model_W(q') = tip_nominal_W(q)`` with core's exact chain
    (``core.kinematics.tip_W``) at the machine's probe offsets J and rotary
    positions, the model's tables at the axis positions ``q' + J``:
    ``q' <- q' - R_RW (tip_model_W(q') - tip_nominal_W(q))``,
    ``iterations`` times (the model's gradient is < 1e-3, each step gains
    three digits: 3 steps leave < 1e-15 m of a 100 um correction).
    """

    def __init__(self, machine, model: ErrorModel, iterations: int = 3):
        super().__init__(machine)
        from core.kinematics import ChainGeometry

        if not isinstance(model, ErrorModel):
            raise ConfigError(f"VolumetricCompensation needs an ErrorModel, got {type(model).__name__}")
        self.model = model
        self.iterations = int(iterations)
        self._geom = ChainGeometry.of(model.chain, machine.config.J_m, model.rotary_points_R_m)
        self._J = np.asarray(self._geom.J_m, float)

    def commanded(self, lin_m, rot_rad=None, direction=None) -> np.ndarray:
        from core.kinematics import T_R_W, tip_W

        lin = np.atleast_2d(np.asarray(lin_m, float))
        nr = len(self._geom.chain.rotary_axes)
        rot = None if not nr else (np.zeros((len(lin), nr)) if rot_rad is None else rot_rad)
        target_W = tip_W(self._geom, lin, rot, None)  # where a perfect machine puts the tip
        R_RW = T_R_W(self._geom, lin, rot, None)[:, :3, :3]  # d reading / d tip_W of a perfect machine
        q = lin.copy()
        for _ in range(self.iterations):
            err_W = tip_W(self._geom, q, rot, self.model.values(q + self._J)) - target_W
            q = q - np.einsum("nij,nj->ni", R_RW, err_W)
        return q
