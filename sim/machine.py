"""The virtual machine: an exact Pinocchio chain with injected ISO 230 errors.

Example (the default 5-axis machine, one squareness error)::

    >>> import numpy as np
    >>> from sim.machines import MACHINES
    >>> from sim.errorfuncs import Constant
    >>> from sim.machine import Machine
    >>> m = Machine(MACHINES["nmv3000"](errors={"EC0Y": Constant(-43.4e-6)}))
    >>> lin = np.array([[0.0, 0.0, 0.0], [0.0, 0.1, 0.0], [0.1, 0.1, -0.05]])  # m
    >>> rot = np.zeros((3, len(m.rotary_axes)))                                # A, C in rad
    >>> dev_um = (m.tip_W(lin, rot) - m.tip_W_nominal(lin, rot)) * 1e6
    >>> print(np.round(dev_um, 2) + 0.0)  # -y * EC0Y in X (self-calibration eq. 4)
    [[0.   0.   0.  ]
     [4.34 0.   0.  ]
     [4.34 0.   0.  ]]

The chain (definition shared with ``core.kinematics``, whose module
docstring states it in full): every axis is a nominal Pinocchio joint
(prismatic / revolute) and a free-flyer joint whose configuration is the
axis's error motion; location errors are fixed joint placements. The actual
pose is therefore the exact product of nominal motions and error
transforms, not a first-order formula. Two branches leave the universe (the
bed, frame R): the workpiece branch ends at frame W, the tool branch at the
stylus-tip frame P.

Error values are ISO 230-1 values (CONTRIBUTING.md, "Error conventions"):
the displacement of the TOOL relative to the WORKPIECE, whichever branch
the axis is on. With ``E = [exp(skew(EA, EB, EC)) | (EX, EY, EZ)]`` at the
axis's reading, a tool-branch linear axis moves its carriage by
``Trans(q e) E`` relative to its carrier (E after the motion, in the
carriage); a workpiece-branch linear axis moves its component by the exact
inverse, ``E^-1 Trans(-q e)`` (the free-flyer before the prismatic joint),
so that the carrier, with the tool, moves relative to the component by
``Trans(q e) E``: the same relative motion in the same frame as on the tool
branch. A rotary axis's error sits in its carrier's non-rotating frame at
the axis line, before the rotation: ``E`` on the tool branch, ``E^-1`` on
the workpiece branch. Location errors (squareness, rotary axis lines) are
the geometry of the lines in R and enter alike on both branches.

Conventions: axis readings ``lin_m`` are the stylus-tip centre as the
machine believes it, in R (the controller adds the probe offsets J, so axis
position ``q = reading + J``); a table-moving linear axis moves the table
by ``-q``. Rotary axes on the workpiece branch turn W by ``-theta``:
``p_R = T_R_W(rot) p_W`` with ``R(-C)`` about the C line (self-calibration
paper eq. 1), likewise A. A linear axis's error functions are evaluated at
its axis position ``q = reading + J`` (CONTRIBUTING.md, "Error
conventions"), not at the reading (the probe-log position); a rotary
axis's at its angle. Units: SI.
"""

from __future__ import annotations

import dataclasses
import functools
import types
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from core import iso
from core.chain import Chain, parse_chain
from core.exceptions import ConfigError
from core.memo import Memo
from sim.errorfuncs import Constant, ErrorFunction, SplineStack, SplineTable, Zero

_E = {"X": 0, "Y": 1, "Z": 2, "A": 0, "B": 1, "C": 2}


@dataclass(frozen=True)
class MachineConfig:
    """A virtual machine: structure, nominal geometry and truth errors.

    Attributes
    ----------
    name : str
    chain : str
        ISO 10791 chain, e.g. ``"V[w-C-A-b-Y-X-Z-(C)-t]"`` (``core.chain``).
    strokes : mapping axis -> (min, max)
        Travel of every axis of the chain: m (linear), rad (rotary). A linear
        stroke bounds the axis position ``q = reading + J``, written in the
        readings of this configuration's own offsets ``J_m`` (the reference
        tool): a reading with a stylus of offsets J is checked as
        ``reading + J - J_m`` (docs/formats.md, "Strokes").
    rotary_points_R_m : mapping axis -> (3,) float
        A point on each rotary axis's nominal line, in R with all axes at
        zero, m (the C entry is the rotary table centre). Default origin.
    J_m : (3,) float
        Probe offsets (J_X, J_Y, J_Z) of MFB eq. 8, m: spindle gauge point
        minus stylus-tip centre (J_Z is the tip's depth below the spindle
        gauge line). The Z ram's angular errors pivot about the gauge point.
    errors : mapping ISO symbol -> ErrorFunction
        Motion errors of every axis (``EXX`` ... ``ECZ``, ISO 230-7 ``EXC``
        ... ``ECC``) in the ISO 230-1 convention (tool relative to the
        workpiece, whichever branch carries the axis), and location errors
        as ``Constant``: ``EC0Y``, ``EB0Z``, ``EA0Z``, and per rotary axis
        ``EX0C``, ``EY0C``, ``EA0C``, ``EB0C`` (``EY0A``, ``EZ0A``, ``EB0A``,
        ``EC0A`` for A). Absent: zero.
    """

    name: str
    chain: str
    strokes: Mapping[str, tuple[float, float]]
    rotary_points_R_m: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)
    J_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    errors: Mapping[str, ErrorFunction] = field(default_factory=dict)

    def __post_init__(self):
        ch = parse_chain(self.chain)
        missing = [a for a in iso.LINEAR_AXES if a not in ch.axes]
        if missing:
            raise ConfigError(f"machine {self.name!r}: chain {self.chain!r} lacks linear axis {missing[0]}")
        strokes = {}
        for a in ch.axes:
            if a not in self.strokes:
                raise ConfigError(f"machine {self.name!r}: no stroke for axis {a}")
            lo, hi = (float(v) for v in self.strokes[a])
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ConfigError(f"machine {self.name!r}: stroke of {a} must be finite min < max, got {self.strokes[a]!r}")
            strokes[a] = (lo, hi)
        for a in self.strokes:
            if a not in ch.axes:
                raise ConfigError(f"machine {self.name!r}: stroke given for axis {a!r} not in the chain")
        pts = {}
        for a in ch.rotary_axes:
            p = tuple(float(v) for v in self.rotary_points_R_m.get(a, (0.0, 0.0, 0.0)))
            if len(p) != 3 or not np.all(np.isfinite(p)):
                raise ConfigError(f"machine {self.name!r}: rotary_points_R_m[{a}] must be 3 finite values")
            pts[a] = p
        for a in self.rotary_points_R_m:
            if a not in ch.rotary_axes:
                raise ConfigError(f"machine {self.name!r}: rotary point given for {a!r}, not a rotary axis of the chain")
        J = tuple(float(v) for v in self.J_m)
        if len(J) != 3 or not np.all(np.isfinite(J)):
            raise ConfigError(f"machine {self.name!r}: J_m must be 3 finite values, got {self.J_m!r}")
        errs = {}
        for k, f in dict(self.errors).items():
            s = iso.symbol(k)
            if s.axis not in ch.axes:
                raise ConfigError(f"machine {self.name!r}: error {s.name} belongs to axis {s.axis}, not in {self.chain}")
            if s.location and s.axis in iso.LINEAR_AXES and s.name not in iso.SQUARENESS:
                raise ConfigError(f"machine {self.name!r}: {s.name} is zero by the ISO 230-1 convention (X primary, Y secondary)")
            if not isinstance(f, ErrorFunction):
                raise ConfigError(f"machine {self.name!r}: error {s.name} is a {type(f).__name__}, not an ErrorFunction")
            if s.location and not isinstance(f, (Constant, Zero)):
                raise ConfigError(f"machine {self.name!r}: location error {s.name} must be Constant")
            if s.name in errs:
                raise ConfigError(f"machine {self.name!r}: error {s.name} given twice")
            errs[s.name] = f
        object.__setattr__(self, "strokes", types.MappingProxyType(strokes))
        object.__setattr__(self, "rotary_points_R_m", types.MappingProxyType(pts))
        object.__setattr__(self, "J_m", J)
        object.__setattr__(self, "errors", types.MappingProxyType(errs))

    @property
    def parsed_chain(self) -> Chain:
        return parse_chain(self.chain)


def _exp3(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of one rotation vector (3,)."""
    import pinocchio as pin

    return pin.exp3(np.asarray(w, float))


def _quat_xyzw_rows(w) -> np.ndarray:
    """Unit quaternions (x, y, z, w) (4, n) of rotation vectors (3 rows of n)."""
    wx, wy, wz = (np.asarray(v, float) for v in w)
    th = np.sqrt(wx * wx + wy * wy + wz * wz)
    small = th < 1e-6
    half = np.where(small, 0.5 - th**2 / 48.0, np.sin(0.5 * th) / np.where(small, 1.0, th))
    return np.stack([wx * half, wy * half, wz * half, np.cos(0.5 * th)])


def _quat_rotate_rows(q: np.ndarray, v) -> list:
    """Vectors (3 rows of n) rotated by unit quaternions (4, n) (x, y, z, w): 3 rows."""
    ux, uy, uz, w = q
    vx, vy, vz = v
    cx, cy, cz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    return [vx + 2.0 * w * cx + 2.0 * (uy * cz - uz * cy),
            vy + 2.0 * w * cy + 2.0 * (uz * cx - ux * cz),
            vz + 2.0 * w * cz + 2.0 * (ux * cy - uy * cx)]


class Machine:
    """The exact virtual machine built from a :class:`MachineConfig`.

    Attributes
    ----------
    config : MachineConfig
    chain : core.chain.Chain
    linear_axes : ("X", "Y", "Z")
    rotary_axes : tuple of str, A B C order (``()`` for a 3-axis machine)
    """

    def __init__(self, config: MachineConfig):
        self.config = config
        self.chain = config.parsed_chain
        self._motion = {a: tuple(s.name for s in iso.symbols_of_axis(a, location=False)) for a in self.chain.axes}
        self._error_plan, self._spline_stacks = self._compile_errors()
        # the Pinocchio models read the geometry and the location errors only (motion errors enter
        # the configurations, :meth:`_configurations_T`): built once per such key (_MODELS)
        (self._model, self._layout, self._fW, self._fP, self._tip_pending, self._fk, self._fk_W,
         self._fk_P) = _MODELS.get_or_compute(self._models_key(), self._build_models)
        self._layout_W = tuple(e for e in self._layout if e[3] < 0)  # the workpiece branch's joints
        self._layout_P = tuple(e for e in self._layout if e[3] > 0)  # the tool branch's
        # W's pose depends on the rotary angles alone when its branch holds only rotary axes
        # whose errors depend on the angle only: then it is evaluated once per distinct angles
        self._W_by_angles = bool(self.rotary_axes) and all(a in self.rotary_axes for a in self.chain.workpiece_from_bed) \
            and all(f.static for k, f in self.config.errors.items() if iso.symbol(k).axis in self.chain.workpiece_from_bed)

    # ------------------------------------------------------------------ API
    @property
    def linear_axes(self) -> tuple[str, ...]:
        return iso.LINEAR_AXES

    @property
    def rotary_axes(self) -> tuple[str, ...]:
        return self.chain.rotary_axes

    def with_errors(self, errors: Mapping[str, ErrorFunction]) -> "Machine":
        """A new machine, same geometry, these truth errors."""
        return Machine(dataclasses.replace(self.config, errors=dict(errors)))

    def error_values(self, lin_m, rot_rad=None, t_s=None, direction=None, J_m=None) -> dict[str, np.ndarray]:
        """Every configured error evaluated at the poses: symbol -> (n,) m or rad.

        Motion errors of a linear axis are evaluated at its axis (joint)
        position ``q = reading + J`` (the carriage, what its scale reads;
        Viprey et al. eq. 8: the errors are functions of the joint
        parameters, the tool offset J applied after them) and
        ``direction[:, i]``, every axis's ``q`` passed as ``axes``; those of a
        rotary axis at its angle (direction 0). ``J_m`` (n, 3): each pose's
        probe offsets (default the configuration's ``J_m``).
        Spline tables of one linear axis on the same knots are evaluated in one
        call (:class:`sim.errorfuncs.SplineStack`, the same values), and the
        position-only errors of a rotary axis once per distinct angle (a
        rotary axis is held during a touch: a campaign has one angle per set-up).
        """
        lin, rot, n = self._inputs(lin_m, rot_rad)
        t, d = self._td(t_s, direction, n)
        lin = lin + (np.asarray(self.config.J_m, float) if J_m is None else np.broadcast_to(np.asarray(J_m, float), (n, 3)))
        axes = {a: lin[:, k] for k, a in enumerate(iso.LINEAR_AXES)}
        stacked = {}
        for i, names, stack in self._spline_stacks:
            stacked.update(zip(names, stack(lin[:, i])))
        angles = {}  # rotary axis index -> (distinct angles, index of each pose's angle)
        out = {}
        for name, kind, i, f in self._error_plan:
            if kind == "loc":
                out[name] = np.full(n, f)
            elif kind == "spline":
                out[name] = stacked[name]
            elif kind == "lin":
                out[name] = np.asarray(f.evaluate(lin[:, i], t, d[:, i], axes), float).reshape(n)
            elif kind == "rot_static":
                if i not in angles:
                    angles[i] = _runs(rot[:, i])
                first, inv = angles[i]
                out[name] = np.asarray(f(rot[first, i], None, None), float).reshape(len(first))[inv]
            else:
                out[name] = np.asarray(f(rot[:, i], t, None), float).reshape(n)
        return out

    def _compile_errors(self):
        """How :meth:`error_values` evaluates each error: ``[(name, kind, axis index, f or value)]``
        in the configuration's order, and the spline stacks ``[(axis index, names, SplineStack)]``."""
        plan, tables = [], {}
        for name, f in self.config.errors.items():
            s = iso.symbol(name)
            if s.location:
                plan.append((name, "loc", -1, float(f(np.zeros(1))[0])))
            elif s.axis in iso.LINEAR_AXES:
                i = iso.LINEAR_AXES.index(s.axis)
                if type(f) is SplineTable:
                    tables.setdefault((i, f.pos), []).append((name, f))
                    plan.append((name, "spline", i, f))
                else:
                    plan.append((name, "lin", i, f))
            else:
                plan.append((name, "rot_static" if f.static else "rot", self.rotary_axes.index(s.axis), f))
        stacks = [(i, tuple(k for k, _ in fs), SplineStack([f for _, f in fs])) for (i, _), fs in tables.items()]
        return tuple(plan), tuple(stacks)

    def tip_W(self, lin_m, rot_rad=None, t_s=None, direction=None, J_m=None) -> np.ndarray:
        """ACTUAL stylus-tip centre in the workpiece frame W, (n, 3) m.

        Parameters
        ----------
        lin_m : (n, 3) float
            Axis readings X, Y, Z, m (tip centre as the machine believes it, R).
        rot_rad : (n, len(rotary_axes)) float, optional
            Rotary positions, rad (default 0).
        t_s : (n,) float or float, optional
            Seconds since campaign start (time-dependent errors).
        direction : (n, 3) float, optional
            Signs (-1, 0, +1) of the X, Y, Z velocities (reversal errors).
        J_m : (n, 3) float, optional
            Probe offsets of each pose's stylus, m (default the configuration's
            ``J_m`` at every pose): the tips of several styli on this machine in
            one call, each as ``Machine(replace(config, J_m=J))`` gives it, bit
            for bit (the offsets enter the axis positions q = reading + J, at
            which the motion errors are evaluated, and the tip frame, nothing
            else).
        """
        return self._poses(lin_m, rot_rad, t_s, direction, want="tip", J=J_m)[1]

    def T_R_W(self, lin_m, rot_rad=None, t_s=None, direction=None) -> np.ndarray:
        """ACTUAL pose of W in R, (n, 4, 4)."""
        oMW, _ = self._poses(lin_m, rot_rad, t_s, direction, want="W")
        return oMW

    def T_R_P(self, lin_m, rot_rad=None, t_s=None, direction=None) -> np.ndarray:
        """ACTUAL pose of the stylus-tip frame P in R, (n, 4, 4)."""
        _, oMP = self._poses(lin_m, rot_rad, t_s, direction, want="P")
        return oMP

    def T_R_W_nominal(self, rot_rad=None, lin_m=None) -> np.ndarray:
        """Nominal pose of W in R, (n, 4, 4) (table-side linear axes at ``lin_m``,
        default zero readings, i.e. positions q = J)."""
        nr = len(self.rotary_axes)
        if lin_m is not None:
            n = len(np.atleast_2d(lin_m))
        elif rot_rad is not None and nr:
            n = np.asarray(rot_rad, float).reshape(-1, nr).shape[0]
        else:
            n = np.shape(rot_rad)[0] if rot_rad is not None and np.ndim(rot_rad) == 2 else 1
        lin = np.zeros((n, 3)) if lin_m is None else lin_m
        lin, rot, n = self._inputs(lin, rot_rad)
        return self._nominal_product("workpiece", lin, rot, n)

    def tip_W_nominal(self, lin_m, rot_rad=None) -> np.ndarray:
        """Nominal stylus-tip centre in W, (n, 3) m (equals lin_m at rotary zero)."""
        lin, rot, n = self._inputs(lin_m, rot_rad)
        TW = self._nominal_product("workpiece", lin, rot, n)
        TP = self._nominal_product("tool", lin, rot, n)
        p = TP[:, :3, 3] - np.asarray(self.config.J_m) @ TP[:, :3, :3].transpose(0, 2, 1)
        return np.einsum("nji,nj->ni", TW[:, :3, :3], p - TW[:, :3, 3])

    def geometry(self):
        """The nominal geometry as ``core.kinematics.ChainGeometry`` (for core)."""
        from core.kinematics import ChainGeometry

        return ChainGeometry.of(self.chain, self.config.J_m, self.config.rotary_points_R_m)

    # ------------------------------------------------------------------ internals
    def _inputs(self, lin_m, rot_rad):
        lin = np.atleast_2d(np.asarray(lin_m, float))
        if lin.ndim != 2 or lin.shape[1] != 3:
            raise ConfigError(f"lin_m must be (n, 3), got shape {np.shape(lin_m)}")
        n = lin.shape[0]
        nr = len(self.rotary_axes)
        if rot_rad is None or nr == 0:
            if rot_rad is not None and np.size(rot_rad) != 0:
                raise ConfigError(f"rot_rad given but machine {self.config.name!r} has no rotary axis")
            return lin, np.zeros((n, nr)), n
        rot = np.asarray(rot_rad, float)
        rot = rot.reshape(n, nr) if rot.size == n * nr else rot
        if rot.shape != (n, nr):
            raise ConfigError(f"rot_rad must be (n, {nr}) for axes {self.rotary_axes}, got {np.shape(rot_rad)}")
        return lin, rot, n

    @staticmethod
    def _td(t_s, direction, n):
        t = None if t_s is None else np.broadcast_to(np.asarray(t_s, float), (n,))
        if direction is None:
            d = np.zeros((n, 3))
        else:
            d = np.asarray(direction, float)
            if d.shape not in ((n, 3), (3,)):
                raise ConfigError(f"direction must be (n, 3) signs, got shape {d.shape}")
            d = np.sign(np.broadcast_to(d, (n, 3)))
        return t, d

    def _axes(self, side):
        return self.chain.tool_axes if side == "tool" else self.chain.workpiece_from_bed

    def _loc(self, name):
        f = self.config.errors.get(name)
        return 0.0 if f is None else float(f(np.zeros(1))[0])

    def _models_key(self) -> tuple:
        """Everything :meth:`_build` reads: the chain, the probe offsets, the rotary axes' points and
        the location errors' values (as ``float.hex``, so -0.0 and 0.0 stay apart), in chain order."""
        cfg = self.config
        locs = tuple((sy.name, self._loc(sy.name).hex()) for a in self.chain.axes
                     for sy in iso.symbols_of_axis(a, location=True)
                     if a not in iso.LINEAR_AXES or sy.name in iso.SQUARENESS)
        pts = tuple((a, tuple(v.hex() for v in cfg.rotary_points_R_m[a])) for a in self.chain.rotary_axes)
        return cfg.chain, tuple(v.hex() for v in cfg.J_m), pts, locs

    def _build_models(self) -> tuple:
        """The model with errors (its layout, W and P frames, the tip's pending placement) and its
        batched kinematics. Read-only once built (several machines share them through :data:`_MODELS`)."""
        model, layout, fW, fP = self._build(with_errors=True)
        return (model, layout, fW, fP, self._tip_pending,
                _BatchFK(model, (fW, fP)), _BatchFK(model, (fW,)), _BatchFK(model, (fP,)))

    @functools.cached_property
    def _data(self):
        """Scratch of :meth:`tip_W_pinocchio` (the oracle): one per machine, made at its first use
        (0.3 ms; a Monte Carlo run's machine never calls the oracle)."""
        return self._model.createData()

    @functools.cached_property
    def _nominal_model(self) -> tuple:
        """``(model, layout, fW, fP, data)``: the error-free Pinocchio model of :meth:`_nominal_fk_tip`
        (a benchmark's reference), built at its first use; it reads the geometry only, not the errors."""
        nmodel, nlayout, nfW, nfP = self._build(with_errors=False)
        return nmodel, nlayout, nfW, nfP, nmodel.createData()

    def _build(self, with_errors: bool):
        import pinocchio as pin

        model = pin.Model()
        layout = []  # (kind, axis, idx_q, sign): kind 'lin' | 'rot' | 'err'
        J = np.asarray(self.config.J_m)
        frames = {}
        for side in ("workpiece", "tool"):
            s = 1.0 if side == "tool" else -1.0
            parent = 0
            pending = pin.SE3.Identity()
            cum = np.zeros(3)
            for a in self._axes(side):
                e = np.zeros(3)
                e[_E[a]] = 1.0
                w_loc = np.zeros(3)
                d_loc = np.zeros(3)
                if with_errors:
                    for sy in iso.symbols_of_axis(a, location=True):
                        if a in iso.LINEAR_AXES and sy.name not in iso.SQUARENESS:
                            continue
                        (w_loc if sy.angular else d_loc)[_E[sy.direction]] += self._loc(sy.name)
                if a in iso.LINEAR_AXES:
                    rel = w_loc - (cum - e * (e @ cum))  # undo the carrier's tilt across the axis
                    cum = cum + rel
                    place = pending * pin.SE3(_exp3(rel), np.zeros(3))
                    jm = (pin.JointModelPX, pin.JointModelPY, pin.JointModelPZ)[_E[a]]()
                    if with_errors and side == "workpiece":  # E^-1 in the carrier, before the motion
                        parent = model.addJoint(parent, pin.JointModelFreeFlyer(), place, f"E_{a}")
                        layout.append(("err", a, model.joints[parent].idx_q, s))
                        place = pin.SE3.Identity()
                    parent = model.addJoint(parent, jm, place, f"{a}")
                    layout.append(("lin", a, model.joints[parent].idx_q, s))
                    pending = pin.SE3.Identity()
                    if with_errors and side == "tool":  # E in the moving carriage, after the motion
                        parent = model.addJoint(parent, pin.JointModelFreeFlyer(), pin.SE3.Identity(), f"E_{a}")
                        layout.append(("err", a, model.joints[parent].idx_q, s))
                else:
                    c = np.asarray(self.config.rotary_points_R_m[a], float)
                    rel = w_loc
                    cum = cum + rel
                    place = pending * pin.SE3(_exp3(rel), c + d_loc)
                    if with_errors:
                        parent = model.addJoint(parent, pin.JointModelFreeFlyer(), place, f"E_{a}")
                        layout.append(("err", a, model.joints[parent].idx_q, s))
                        place = pin.SE3.Identity()
                    jm = (pin.JointModelRX, pin.JointModelRY, pin.JointModelRZ)[_E[a]]()
                    parent = model.addJoint(parent, jm, place, f"{a}")
                    layout.append(("rot", a, model.joints[parent].idx_q, s))
                    pending = pin.SE3(np.eye(3), -c)
            if side == "workpiece":
                frames["W"] = model.addFrame(pin.Frame("W", parent, 0, pending, pin.FrameType.OP_FRAME))
            else:
                tip = pending * pin.SE3(np.eye(3), -J)
                if with_errors:  # what J is appended to (per-pose offsets: :meth:`_tip_rows`)
                    self._tip_pending = tuple(_read_only(np.array(v, float)) for v in (pending.rotation, pending.translation))
                frames["P"] = model.addFrame(pin.Frame("P", parent, 0, tip, pin.FrameType.OP_FRAME))
        return model, tuple(layout), frames["W"], frames["P"]

    def _configurations(self, model, layout, lin, rot, vals, n):
        """Pinocchio configurations (n, nq) of the poses: axis positions and error free-flyers."""
        return self._configurations_T(model, layout, lin, rot, vals, n).T

    def _configurations_T(self, model, layout, lin, rot, vals, n, J=None):
        """:meth:`_configurations` transposed, (nq, n), each coordinate a contiguous row
        (``J`` (n, 3): each pose's probe offsets, default the configuration's)."""
        import pinocchio as pin

        QT = np.repeat(np.asarray(pin.neutral(model), float)[:, None], n, axis=1)
        J = self.config.J_m if J is None else J.T
        zero = np.zeros(n)
        for kind, a, iq, s in layout:
            if kind == "lin":
                QT[iq] = s * (lin[:, iso.LINEAR_AXES.index(a)] + J[_E[a]])
            elif kind == "rot":
                QT[iq] = s * rot[:, self.rotary_axes.index(a)]
            else:
                names = self._motion[a]
                t = [vals.get(k, zero) for k in names[:3]]
                quat = _quat_xyzw_rows([vals.get(k, zero) for k in names[3:]])
                if s < 0:  # workpiece branch: the component moves by the exact inverse of E
                    quat[:3] = -quat[:3]
                    t = [-v for v in _quat_rotate_rows(quat, t)]
                QT[iq:iq + 3] = t
                QT[iq + 3:iq + 7] = quat
        return QT

    def _poses(self, lin_m, rot_rad, t_s, direction, want, J=None):
        """Poses of W, P or the tip by :class:`_BatchFK` (the Pinocchio model, all poses at once);
        ``J`` (n, 3): each pose's probe offsets (tip only; default the configuration's)."""
        lin, rot, n = self._inputs(lin_m, rot_rad)
        tip_t = None
        if J is not None:
            J = np.broadcast_to(np.asarray(J, float), (n, 3))
            if want != "tip" or not np.all(np.isfinite(J)):
                raise ConfigError(f"per-pose probe offsets J_m: finite (n, 3), for the tip only, got {J.shape}")
            tip_t = self._tip_rows(J)
        vals = self.error_values(lin, rot, t_s, direction, J)
        if want == "tip" and self._W_by_angles and n > 1:
            # the workpiece branch once per run of equal rotary positions (a campaign: one per
            # set-up), the tool branch at every pose
            first, inv = _runs(rot)
            vals_W = {k: v[first] for k, v in vals.items()}
            QT_W = self._configurations_T(self._model, self._layout_W, lin[first], rot[first], vals_W, len(first),
                                          None if J is None else J[first])
            (R_W, t_W), = self._fk_W.frames(QT_W)
            (R_P, t_P), = self._fk_P.frames(self._configurations_T(self._model, self._layout_P, lin, rot, vals, n, J),
                                            None if tip_t is None else [tip_t])
            return None, np.einsum("nji,nj->ni", R_W[inv], t_P - t_W[inv])
        QT = self._configurations_T(self._model, self._layout, lin, rot, vals, n, J)
        (R_W, t_W), (R_P, t_P) = self._fk.frames(QT, None if tip_t is None else [None, tip_t])
        if want == "tip":
            return None, np.einsum("nji,nj->ni", R_W, t_P - t_W)
        R, t = (R_W, t_W) if want == "W" else (R_P, t_P)
        out = np.zeros((n, 4, 4))
        out[:, :3, :3], out[:, :3, 3], out[:, 3, 3] = R, t, 1.0
        return (out, None) if want == "W" else (None, out)

    def _tip_rows(self, J: np.ndarray) -> np.ndarray:
        """(3, n) translation of the tip frame P in its joint for each pose's offsets J (n, 3): the
        model's ``pending * SE3(I, -J)``, -J itself when nothing is pending (no tool-side rotary axis)."""
        R, t = self._tip_pending
        if np.array_equal(R, np.eye(3)) and not np.any(t):
            return -J.T
        return t[:, None] + R @ -J.T

    def tip_W_pinocchio(self, lin_m, rot_rad=None, t_s=None, direction=None) -> np.ndarray:
        """:meth:`tip_W` by Pinocchio's own ``forwardKinematics``, one pose at a time, (n, 3) m.

        The independent oracle of the batched evaluation (tests) and the reference
        of its speed (``vmt bench``); same arguments as :meth:`tip_W`.
        """
        return self._poses_pinocchio(lin_m, rot_rad, t_s, direction, want="tip")[1]

    def _poses_pinocchio(self, lin_m, rot_rad, t_s, direction, want):
        import pinocchio as pin

        lin, rot, n = self._inputs(lin_m, rot_rad)
        vals = self.error_values(lin, rot, t_s, direction)
        model, data, fW, fP = self._model, self._data, self._fW, self._fP
        Q = self._configurations(model, self._layout, lin, rot, vals, n)
        fk, ufp = pin.forwardKinematics, pin.updateFramePlacement
        if want == "tip":
            out = np.empty((n, 3))
            for i in range(n):
                fk(model, data, Q[i])
                out[i] = ufp(model, data, fW).actInv(ufp(model, data, fP).translation)
            return None, out
        out = np.empty((n, 4, 4))
        fid = fW if want == "W" else fP
        for i in range(n):
            fk(model, data, Q[i])
            out[i] = ufp(model, data, fid).homogeneous
        return (out, None) if want == "W" else (None, out)

    def _nominal_fk_tip(self, lin_m, rot_rad=None) -> np.ndarray:
        """Nominal tip in W by Pinocchio's own FK on the error-free model
        (benchmark reference; same result as :meth:`tip_W_nominal`)."""
        import pinocchio as pin

        lin, rot, n = self._inputs(lin_m, rot_rad)
        model, nlayout, nfW, nfP, data = self._nominal_model
        Q = self._configurations(model, nlayout, lin, rot, {}, n)
        fk, ufp = pin.forwardKinematics, pin.updateFramePlacement
        out = np.empty((n, 3))
        for i in range(n):
            fk(model, data, Q[i])
            out[i] = ufp(model, data, nfW).actInv(ufp(model, data, nfP).translation)
        return out

    def _nominal_product(self, side, lin, rot, n):
        """Nominal pose of the branch end (W, or the Z ram gauge point), numpy."""
        T = np.tile(np.eye(4), (n, 1, 1))
        s = 1.0 if side == "tool" else -1.0
        J = self.config.J_m
        for a in self._axes(side):
            e = np.zeros(3)
            e[_E[a]] = 1.0
            M = np.tile(np.eye(4), (n, 1, 1))
            if a in iso.LINEAR_AXES:
                M[:, :3, 3] = (s * (lin[:, iso.LINEAR_AXES.index(a)] + J[_E[a]]))[:, None] * e
            else:
                c = np.asarray(self.config.rotary_points_R_m[a], float)
                th = s * rot[:, self.rotary_axes.index(a)]
                K = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
                R = np.eye(3) + np.sin(th)[:, None, None] * K + (1 - np.cos(th))[:, None, None] * (K @ K)
                M[:, :3, :3] = R
                M[:, :3, 3] = c - R @ c
            T = T @ M
        return T


#: The Pinocchio models of machines, by :meth:`Machine._models_key` (geometry and location errors):
#: a Monte Carlo study builds a machine per run with new motion errors on the same geometry
#: (scenarios.vcmm.simulate_run). Safe: the key holds everything the models are built from, and
#: the models and batched kinematics are never written after their build (each machine has its
#: own Pinocchio ``Data``).
_MODELS = Memo(32)


class _Nominal:
    """What :meth:`Machine.T_R_W_nominal` reads of a machine: its configuration, chain and rotary
    axes (no Pinocchio model: those carry the truth errors, the nominal product does not)."""

    def __init__(self, config: MachineConfig):
        self.config = config
        self.chain = config.parsed_chain

    rotary_axes = Machine.rotary_axes
    _inputs, _axes, _nominal_product = Machine._inputs, Machine._axes, Machine._nominal_product


def nominal_T_R_W(config: MachineConfig, rot_rad=None, lin_m=None) -> np.ndarray:
    """``Machine(config).T_R_W_nominal(rot_rad, lin_m)`` without building the machine, (n, 4, 4).

    The same method on the configuration alone (bit for bit, tests/sim/test_machine.py): a
    Machine builds two Pinocchio models (1.4 ms) that a nominal pose never reads. For callers
    that need only nominal table poses (:func:`scenarios.mfb.check_plan`, one per set-up).
    """
    return Machine.T_R_W_nominal(_Nominal(config), rot_rad, lin_m)


class _BatchFK:
    """Forward kinematics of a Pinocchio model for a batch of configurations, in numpy.

    Walks ``model``'s joints in order (each after its parent) and composes
    ``oMi = oMparent . jointPlacement . M_joint(q)`` for every configuration
    at once, then the frames' ``oMf = oMi[parent] . placement``: the product
    ``pinocchio.forwardKinematics`` forms one configuration at a time, read
    from the same model (joint types, placements, configuration indices),
    without derivatives. Joint types: prismatic and revolute about X, Y, Z,
    free-flyer (translation, unit quaternion x y z w); others raise.
    Pinocchio's own loop stays the oracle (``tests/sim/test_machine.py``:
    agreement < 1e-12 m).

    Parameters
    ----------
    model : pinocchio.Model
    frame_ids : sequence of int
        Frames returned by :meth:`frames` (only the joints they hang from and
        those joints' ancestors are walked).
    """

    _KINDS = {"JointModelPX": ("P", 0), "JointModelPY": ("P", 1), "JointModelPZ": ("P", 2),
              "JointModelRX": ("R", 0), "JointModelRY": ("R", 1), "JointModelRZ": ("R", 2),
              "JointModelFreeFlyer": ("F", 0)}

    def __init__(self, model, frame_ids):
        self.joints = []
        needed = set()  # the joints the frames hang from and their ancestors: the only ones walked
        for f in frame_ids:
            fr = model.frames[f]
            j = int(fr.parentJoint if hasattr(fr, "parentJoint") else fr.parent)
            while j > 0:
                needed.add(j)
                j = int(model.parents[j])
        for j in range(1, model.njoints):
            if j not in needed:
                self.joints.append(None)
                continue
            name = model.joints[j].shortname()
            if name not in self._KINDS:
                raise ConfigError(f"batched kinematics: joint type {name} is not supported")
            M = model.jointPlacements[j]
            R = _read_only(np.array(M.rotation, float))  # shared between machines through _MODELS
            self.joints.append((*self._KINDS[name], int(model.parents[j]), int(model.joints[j].idx_q), R,
                                None if not np.any(M.translation) else _read_only(np.array(M.translation, float)),
                                bool(np.array_equal(R, np.eye(3)))))  # None: no translation
        self.frames_ = []
        for f in frame_ids:
            fr = model.frames[f]
            parent = fr.parentJoint if hasattr(fr, "parentJoint") else fr.parent
            Rf = _read_only(np.array(fr.placement.rotation, float))
            self.frames_.append((int(parent), None if np.array_equal(Rf, np.eye(3)) else Rf,
                                 _read_only(np.array(fr.placement.translation, float))))

    def frames(self, QT: np.ndarray, frame_t: list | None = None) -> list:
        """[(R (n,3,3), t (n,3))] of the frames in the universe, for configurations QT (nq, n)
        (transposed: each coordinate a row); ``frame_t``: per frame, None or (3, n) translations
        of the frame in its joint, one per configuration, instead of the model's placement's."""
        QT = np.asarray(QT, float)
        n = QT.shape[1]
        # rotations as (3, 3, n) and translations as (3, n): every product is 9 or 3 rows of n
        oM = [(None, np.zeros((3, n)))]  # joint 0, the universe (None: identity)
        for joint in self.joints:
            if joint is None:  # not an ancestor of the frames asked for
                oM.append(None)
                continue
            kind, ax, parent, iq, Rp, tp, Rp_is_I = joint
            Ra, ta = oM[parent]
            t = ta if tp is None else ta + (tp[:, None] if Ra is None else _mv_const(Ra, tp))
            Rb = Ra if Rp_is_I else (np.broadcast_to(Rp[:, :, None], (3, 3, n)) if Ra is None else _mm_const(Ra, Rp))
            if kind == "P":
                R = Rb
                col = np.eye(3)[:, ax, None] if Rb is None else Rb[:, ax]
                t = t + col * QT[iq]
            elif kind == "R":
                c, s = np.cos(QT[iq]), np.sin(QT[iq])
                i, k = (ax + 1) % 3, (ax + 2) % 3  # Rot about e_ax: e_i -> c e_i + s e_k, e_k -> -s e_i + c e_k
                Rb = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, n)) if Rb is None else Rb
                R = np.empty((3, 3, n))
                R[:, ax] = Rb[:, ax]
                R[:, i] = c * Rb[:, i] + s * Rb[:, k]
                R[:, k] = c * Rb[:, k] - s * Rb[:, i]
            else:
                Rq = _quat_matrix(QT[iq + 3:iq + 7])
                if Rb is None:
                    R, t = Rq, t + QT[iq:iq + 3]
                else:
                    R, t = _mm(Rb, Rq), t + _mv(Rb, QT[iq:iq + 3])
            oM.append((R, t))
        out = []
        for k, (parent, Rf, tf) in enumerate(self.frames_):
            Ra, ta = oM[parent]
            rows = None if frame_t is None else frame_t[k]
            if Ra is None:
                R = np.broadcast_to((np.eye(3) if Rf is None else Rf)[:, :, None], (3, 3, n))
                t = ta + (tf[:, None] if rows is None else rows)
            else:
                R = Ra if Rf is None else _mm_const(Ra, Rf)
                t = ta + (_mv_const(Ra, tf) if rows is None else _mv(Ra, rows))
            out.append((np.moveaxis(R, 2, 0), t.T))
        return out


def _runs(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first row of each run of equal rows, the run of each row) of ``a`` (n,) or (n, k).

    The distinct held rotary positions of a campaign's poses in one pass (its
    touches come set-up by set-up); a value met again later gets a run of its
    own, a NaN a run alone: never two different values in one run.
    """
    n = len(a)
    new = np.ones(n, bool)
    if n > 1:
        a2 = np.asarray(a).reshape(n, -1)
        np.any(a2[1:] != a2[:-1], axis=1, out=new[1:])
    return np.flatnonzero(new), np.cumsum(new) - 1


def _mm(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Products of stacked 3x3 matrices, (3,3,n) x (3,3,n) -> (3,3,n)."""
    return A[:, 0, None] * B[None, 0] + A[:, 1, None] * B[None, 1] + A[:, 2, None] * B[None, 2]


def _mm_const(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """(3,3,n) x (3,3) -> (3,3,n)."""
    return A[:, 0, None] * B[None, 0, :, None] + A[:, 1, None] * B[None, 1, :, None] + A[:, 2, None] * B[None, 2, :, None]


def _mv(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(3,3,n) x (3,n) -> (3,n)."""
    return A[:, 0] * v[0] + A[:, 1] * v[1] + A[:, 2] * v[2]


def _mv_const(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(3,3,n) x (3,) -> (3,n)."""
    return A[:, 0] * v[0] + A[:, 1] * v[1] + A[:, 2] * v[2]


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (3,3,n) of unit quaternions (4,n) (x, y, z, w)."""
    x, y, z, w = q
    R = np.empty((3, 3, q.shape[1]))
    R[0, 0] = 1 - 2 * (y * y + z * z)
    R[0, 1] = 2 * (x * y - z * w)
    R[0, 2] = 2 * (x * z + y * w)
    R[1, 0] = 2 * (x * y + z * w)
    R[1, 1] = 1 - 2 * (x * x + z * z)
    R[1, 2] = 2 * (y * z - x * w)
    R[2, 0] = 2 * (x * z - y * w)
    R[2, 1] = 2 * (y * z + x * w)
    R[2, 2] = 1 - 2 * (x * x + y * y)
    return R


def _read_only(a: np.ndarray) -> np.ndarray:
    """``a`` made read-only (shared between machines through :data:`_MODELS`)."""
    a.flags.writeable = False
    return a
