"""An identified machine state: the estimate and its covariance, self-described (``vmt-estimate/1``).

``vmt identify`` (2D self-calibration, :mod:`core.selfcal`) and the MFB
scenarios (:mod:`core.volumetric`) write, under the key ``estimate`` of
their JSON, the whole estimated parameter vector with its covariance in
a form a reader can turn back into error functions without the code that
produced it (README, "Identification results: the estimate and its
covariance")::

    {"format": "vmt-estimate/1",
     "method": "...",
     "sign_convention": "ISO 230-1: the tool's displacement relative to the workpiece",
     "positions": "axis (joint) positions: the reading (stylus-tip centre) + the probe offsets J, in the machine frame R, mm",
     "interpolation": "linear" | "cubic-spline",
     "conventions": ["EXX(x=0mm)=0", ...],       # the gauge: what the data cannot fix
     "parameters": [{"name": "EXX@x=-110mm", "symbol": "EXX", "at_mm": -110.0, "unit": "um"},
                    {"name": "EC0Y", "symbol": "EC0Y", "unit": "urad"},
                    {"name": "G[P01]", "symbol": null, "unit": "um"}, ...],
     "values": [...],                            # one per parameter, in its unit
     "covariance": [[...], ...],                 # n x n, entry (i, j) in unit_i * unit_j
     "identified_on": {"machine": "nmv3000", "chain": "V[w-C-A-b-Y-X-Z-(C)-t]",
                       "probe_offsets_J_mm": [[0, 0, 150]] | null, "z_mm": [27.0, 27.0] | null,
                       "t_s": [0.0, 4210.5],                             # optional (session 34)
                       "temperature_C": {"temp_spindle_C": [20.1, 20.4, 20.9]},  # optional: min, mean, max
                       "controller": "grbl://192.168.1.20:23"}}         # optional (session 37)

``positions`` is :data:`POSITIONS` (the nodes at the axis positions reading + J); a ``vmt identify``
without ``--tool-offset-mm`` (J unknown) writes :data:`POSITIONS_READINGS`, its nodes at the readings, and a
reader places them with the J of the probe it assumes (:meth:`MachineState.at_axis_positions`, as vmt vcmm
does with a notice): the nodes, the positions its ``conventions`` name and a note of that J move together, and
the placed state saves (:func:`state_doc`) with ``positions`` :data:`POSITIONS`. A state written before session 27's fix (review27b F2) has its ``vmt identify`` nodes at
the readings under either wording.

``identified_on`` (since session 26; optional, a file without it reads with a notice) says what the
state was identified on: the machine's name (the kinematic model: the machine the probe log's plan was made
for, :func:`log_machine`, not the controller that moved it) and ISO 10791 chain, the probe offsets J of the touches
(mm, tool side; null: the log did not state them) and the range of the touches' Z axis readings (mm; null
for a 3D identification whose tables run along Z). A state is refused on another machine or chain
(:func:`identified_on_mismatch`). Since session 34 (review33a F8) it may also say when and at what
temperature: ``t_s`` the first and last touch's time (s from the campaign's start, the log's ``t_s``:
probe-log/1 holds no clock date) and ``temperature_C`` per ``temp_<name>_C`` sensor of the log its min,
mean and max over the touches used. Both keys are left out when the log does not give them (a record
written before session 34 has neither and reads as before); :func:`temperature_notice` compares them
with the temperatures of the touches a state is applied to. Since session 37 it may name the ``controller``
that moved the machine (the log's ``controller`` line), a record only; a state identified before from a
``vmt probe`` or ``vmt import`` log has the controller's name as its ``machine`` (``grbl://...``,
``virtual:...``, ``grbl``, ``linuxcnc``), and only its chain is compared (:func:`controller_named`).

A parameter with a ``symbol`` and ``at_mm`` is one node of that ISO 230-1
motion error's table along its axis (the symbol names the axis); with a
``symbol`` and no ``at_mm`` it is a constant (a squareness); with no
``symbol`` it belongs to the identification alone (the workpiece, a
set-up, a placement) and is named only. Between nodes the tables follow
``interpolation`` (``linear``: straight segments, ``cubic-spline``: the C2
not-a-knot spline); beyond the end nodes the end segment (tangent)
continues.

This module writes the block (:func:`estimate_doc`; a state's, :func:`state_doc`) and reads it back
(:func:`read_estimate`) into a :class:`MachineState` that can draw machine
states from the multivariate normal of the estimate (JCGM 101 6.4.8).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, replace

import numpy as np

from . import iso
from .exceptions import ConfigError, counted

FORMAT = "vmt-estimate/1"
INTERPOLATIONS = ("linear", "cubic-spline")
SIGN_CONVENTION = "ISO 230-1: the tool's displacement relative to the workpiece (actual minus commanded)"
POSITIONS = "axis (joint) positions: the reading (stylus-tip centre) + the probe offsets J, in the machine frame R, mm"
#: ``positions`` of a state whose probe offsets J were not known to its writer (``vmt identify`` without
#: ``--tool-offset-mm``: ``identified_on.probe_offsets_J_mm`` null): its nodes are at the readings, not
#: shifted by an unknown J (a reader adds the J of the probe it assumes, :meth:`MachineState.at_axis_positions`).
POSITIONS_READINGS = ("readings (stylus-tip centre) in the machine frame R, mm: the probe offsets J unknown "
                      "(identified_on.probe_offsets_J_mm null), so not the axis positions reading + J")
#: Relative asymmetry of a covariance tolerated (rounding in JSON), and the relative size of a negative
#: eigenvalue taken as rounding (clipped to 0) rather than refused.
SYM_TOL = 1e-6
NEG_EIG_TOL = 1e-9


class StateFileError(ConfigError):
    """An estimate (``vmt-estimate/1``) that cannot be used: the file, the key, what is wrong."""


def estimate_doc(names, symbols, at_m, units, theta, cov, *, method: str, interpolation: str,
                 conventions, positions: str = POSITIONS) -> dict:
    """The ``vmt-estimate/1`` block (module doc), JSON-ready (``positions``: :data:`POSITIONS`, or
    :data:`POSITIONS_READINGS` when the writer does not know J).

    Parameters
    ----------
    names : (n,) str
    symbols : (n,) str or None
        The ISO 230-1 symbol of a table node or constant; None for a
        parameter of the identification alone.
    at_m : (n,) float or None
        The node's position along the symbol's axis, m; None for a constant.
    units : (n,) str
        Each parameter's unit in the file: ``um`` (SI m), ``urad`` (rad),
        ``urad/m`` (rad/m): every one is the SI value times 1e6.
    theta : (n,) float
        SI (m, rad).
    cov : (n, n) float
        SI.
    """
    if interpolation not in INTERPOLATIONS:
        raise ConfigError(f"interpolation: expected one of {INTERPOLATIONS}, got {interpolation!r}")
    theta = np.asarray(theta, float)
    cov = np.asarray(cov, float)
    n = len(theta)
    if cov.shape != (n, n):
        raise ConfigError(f"covariance must be ({n}, {n}), got {cov.shape}")
    params = []
    for nm, s, a, un in zip(names, symbols, at_m, units):
        p = {"name": str(nm), "symbol": s, "unit": str(un)}
        if a is not None:
            p["at_mm"] = round(float(a) * 1e3, 9)
        params.append(p)
    return {"format": FORMAT, "method": method, "sign_convention": SIGN_CONVENTION, "positions": positions,
            "interpolation": interpolation, "conventions": [str(c) for c in conventions],
            "parameters": params, "values": (theta * 1e6).tolist(), "covariance": (cov * 1e12).tolist()}


def identified_on(machine, chain, probe_offsets_J_mm=None, z_mm=None, t_s=None, temperature_C=None,
                  controller=None) -> dict:
    """The ``identified_on`` record of an estimate (module doc): ``machine`` name, ``chain`` (ISO 10791),
    ``probe_offsets_J_mm`` (k, 3) mm or None (unknown), ``z_mm`` (lo, hi) of the touches' Z readings or None;
    optional (keys left out when None): ``t_s`` (first, last) touch time, s from the campaign's start,
    ``temperature_C`` {sensor column: (min, mean, max)} degC (:func:`log_conditions` makes both from a log),
    and ``controller``, what moved the machine and reported the touches (a log's ``controller``,
    :func:`log_machine`; a record, never compared)."""
    J = None if probe_offsets_J_mm is None else [[round(float(v), 9) for v in j] for j in probe_offsets_J_mm]
    z = None if z_mm is None else [round(float(v), 9) for v in z_mm]
    rec = {"machine": None if machine is None else str(machine), "chain": None if chain is None else str(chain),
           "probe_offsets_J_mm": J, "z_mm": z}
    if t_s is not None:
        rec["t_s"] = [round(float(v), 6) for v in t_s]
    if temperature_C is not None:
        rec["temperature_C"] = {str(k): [round(float(v), 6) for v in vals] for k, vals in temperature_C.items()}
    if controller is not None:
        rec["controller"] = str(controller)
    return rec


#: The ``source`` of a probe log a controller measured (``vmt probe``, ``vmt import linuxcnc|grbl``): before
#: session 37 its ``machine`` line named the controller and ``plan_machine`` the plan's machine.
_MEASURED_SOURCES = ("vmt probe", "vmt import ")


def log_machine(meta: dict) -> tuple[str | None, str | None]:
    """``(machine, controller)`` a probe log's metadata names: the machine whose structure its plan was made
    for (the kinematic model a state identified from it holds) and what moved it and reported the touches
    (``grbl://HOST:PORT``, ``virtual:SCENE``, ``linuxcnc``, ``grbl``; None for a simulator's log).

    Since session 37 a measured log writes both (``machine``: the plan's, ``controller``); a log measured
    before (no ``controller`` line, its ``source`` ``vmt probe`` or ``vmt import ...``) named the controller
    as its ``machine`` and the plan's machine as ``plan_machine``: read so, so an old log identifies on the
    plan's machine too. None: the log does not say."""
    if "controller" in meta:
        return meta.get("machine"), meta["controller"]
    if str(meta.get("source", "")).startswith(_MEASURED_SOURCES):
        return meta.get("plan_machine"), meta.get("machine")
    return meta.get("machine"), None


def controller_named(name) -> bool:
    """Whether a state's ``identified_on.machine`` is a controller's name, not a machine's (a state identified
    before session 37 from a ``vmt probe`` or ``vmt import`` log, :func:`log_machine`): it says nothing of the
    kinematic model, so only the chain is compared (:func:`identified_on_mismatch`)."""
    return isinstance(name, str) and (name.startswith(("grbl://", "virtual:")) or name in ("grbl", "linuxcnc"))


def log_conditions(log, used=None) -> dict:
    """The keyword arguments ``t_s`` and ``temperature_C`` of :func:`identified_on` from a probe log's touches
    ``used`` (bool mask, default ``log.ok``): the first and last finite ``t_s``, and per ``temp_<name>_C``
    column with a finite value its min, mean and max; None where the log gives none."""
    used = np.asarray(log.ok if used is None else used, bool)
    t = np.asarray(log.col("t_s"), float)[used] if "t_s" in log.columns else np.zeros(0)
    t = t[np.isfinite(t)]
    temps = {}
    for name in log.temperature_columns():
        v = np.asarray(log.col(name), float)[used]
        v = v[np.isfinite(v)]
        if v.size:
            temps[name] = (float(v.min()), float(v.mean()), float(v.max()))
    return {"t_s": (float(t.min()), float(t.max())) if t.size else None, "temperature_C": temps or None}


#: A state applied to touches whose sensor reads this much off (degC) from the mean it was identified at
#: (the same ``temp_<name>_C`` column) gets a notice (:func:`temperature_notice`): a steel machine's scales
#: move by 11.5 um/m per degC (scenarios.mfb.MACHINE_CTE_PER_C), 3.5 um over 300 mm at 1 degC, several
#: times an MFB node's U95 (0.4-0.7 um).
TEMPERATURE_NOTICE_C = 1.0


def temperature_notice(state: "MachineState", temperature_C: dict | None) -> str | None:
    """A notice when a sensor the state's record names (``identified_on.temperature_C``) reads, in the touches
    the state is applied to (``temperature_C`` {column: (min, mean, max)}, :func:`log_conditions`), a mean
    more than :data:`TEMPERATURE_NOTICE_C` from the one it was identified at; None when they agree, when either
    side has no temperatures, or when they share no sensor (nothing to compare: the caller may say what the
    record holds, :func:`describe_conditions`)."""
    rec = state.identified_on or {}
    then = rec.get("temperature_C") or {}
    now = temperature_C or {}
    off = [(k, float(then[k][1]), float(now[k][1])) for k in then if k in now
           and abs(float(now[k][1]) - float(then[k][1])) > TEMPERATURE_NOTICE_C]
    if not off:
        return None
    return (f"{state.source}: identified at " + ", ".join(f"{k} {a:.1f} C" for k, a, _ in off) + ", applied to "
            "touches at " + ", ".join(f"{b:.1f} C" for _, _, b in off) + f" (more than {TEMPERATURE_NOTICE_C:g} C "
            "apart): the machine's thermal state differs, its errors may too, and its U95 does not hold that")


def describe_conditions(state: "MachineState") -> str | None:
    """One line of what the record says of when and at what temperature the state was identified (None: it
    says neither, a record written before session 34 or a log without them)."""
    rec = state.identified_on or {}
    parts = []
    if rec.get("temperature_C"):
        parts.append("at " + ", ".join(f"{k} {v[1]:.1f} C ({v[0]:.1f}..{v[2]:.1f})"
                                       for k, v in rec["temperature_C"].items()))
    if rec.get("t_s"):
        a, b = rec["t_s"]
        parts.append(f"touches over {b - a:.0f} s of its campaign (t_s {a:g}..{b:g} s)")
    return f"{state.source}: identified " + "; ".join(parts) if parts else None


def _same_chain(a: str, b: str) -> bool:
    from .chain import parse_chain

    try:
        pa, pb = parse_chain(a), parse_chain(b)
    except ConfigError:
        return a.strip() == b.strip()
    return (pa.workpiece_axes, pa.tool_axes) == (pb.workpiece_axes, pb.tool_axes)


def identified_on_mismatch(state: "MachineState", machine: str, chain: str) -> str | None:
    """Why ``state`` may not be applied to machine ``machine`` with chain ``chain`` (None: it may; also None
    when the state carries no record: the caller says so, :attr:`MachineState.identified_on`)."""
    rec = state.identified_on
    if rec is None:
        return None
    got_m, got_c = rec.get("machine"), rec.get("chain")
    if controller_named(got_m):   # a controller's name (a state identified before session 37): the chain alone
        got_m = None
    where = ", ".join(w for w in (
        None if got_m is None else f"machine {got_m!r}", None if got_c is None else f"chain {got_c}",
        None if not rec.get("z_mm") else f"Z {rec['z_mm'][0]:g}..{rec['z_mm'][1]:g} mm") if w)
    if got_c is not None and not _same_chain(got_c, chain):
        return f"identified on {where}, not on machine {machine!r} (chain {chain}): another structure"
    if got_m is not None and got_m != machine:
        return (f"identified on {where}, not on machine {machine!r}: identify this machine, or name the one "
                "it was identified on")
    return None


#: The symbols whose common slope (the axes' scale) a state with :attr:`MachineState.scale_unknown` does not hold.
SCALE_SYMBOLS = ("EXX", "EYY")


#: Probe offsets closer than this on every axis are the same probe, mm (a file rounds them to 1e-9 mm).
J_SAME_MM = 1e-3


def probe_offsets_check(state: "MachineState", J_mm) -> tuple[str | None, str | None]:
    """``(refusal, notice)`` of applying ``state`` with a tool of offsets ``J_mm`` (3,) mm; both None: fine.

    Only a state of the tool's deviation at one height (``z_mm`` recorded: ``vmt identify``'s 2D
    self-calibration) depends on the probe: its tables are the tool tip's X/Y deviation with the probe
    it was identified with, the machine's angular errors acting through that probe's arm, so with other
    offsets the tip deviates otherwise. Refused when the record names other offsets; a notice when it
    does not name them (``identify`` without ``--tool-offset-mm``: null). An MFB state (``z_mm`` null)
    holds the axes' own errors, angular ones included, and applies with any tool."""
    rec = state.identified_on
    if rec is None or rec.get("z_mm") is None:
        return None, None
    here = "(" + ", ".join(f"{float(v):g}" for v in J_mm) + ") mm"
    J = rec.get("probe_offsets_J_mm")
    if J is None:
        return None, (f"{state.source}: the probe offsets J it was identified with are not recorded (vmt identify "
                      f"--tool-offset-mm): its tables, the tool's X/Y deviation with that probe, applied with the "
                      f"tool offsets {here} unchecked"
                      + (" (its nodes, at the readings, placed at reading + these offsets)" if state.at_readings
                         else ""))
    if any(max(abs(float(a) - float(b)) for a, b in zip(j, J_mm)) <= J_SAME_MM for j in J):
        return None, None
    there = " or ".join("(" + ", ".join(f"{float(v):g}" for v in j) + ")" for j in J)
    return (f"identified with probe offsets J {there} mm, not with this machine's tool offsets {here}: its tables "
            "are the tool's X/Y deviation with that probe (the angular errors through its arm); identify with "
            "this probe, or give the machine file that probe's [tool] offset_mm"), None


#: A position named in a convention's words, ``(x=-110mm)``: the axis letter and the position, mm.
_POSITION_WORDS = re.compile(r"\(([xyz])=(-?\d+(?:\.\d*)?(?:e[+-]?\d+)?)mm\)")


def _at_position(words: str, J_mm) -> str:
    """``words`` with each position it names along X, Y or Z moved by that axis's J (mm), written as the
    writer writes them (``:g``, no ``-0``)."""
    return _POSITION_WORDS.sub(lambda m: f"({m[1]}={float(m[2]) + J_mm['xyz'.index(m[1])] + 0.0:g}mm)", words)


@dataclass(frozen=True)
class MachineState:
    """The machine part of an estimate: tables and constants with their joint normal distribution (SI).

    Attributes
    ----------
    tables : dict symbol -> ((k,) nodes m, (k,) int indices into ``mean``)
    constants : dict symbol -> int index into ``mean``
    mean : (p,) float
        The estimate of the machine parameters, m / rad.
    factor : (p, r) float
        ``cov = factor factor^T`` (its non-negative eigen-decomposition).
    interpolation : str
    conventions : tuple of str
    source : str
    identified_on : dict or None
        What it was identified on (:func:`identified_on`); None: a file without the record.
    at_readings : bool
        The tables' nodes are readings (``positions`` :data:`POSITIONS_READINGS`: the writer did not
        know J), not axis positions; :meth:`at_axis_positions` places them with a probe's J.
    method : str
        The estimate's ``method`` as read ("": none).
    """

    tables: dict
    constants: dict
    mean: np.ndarray
    factor: np.ndarray
    interpolation: str
    conventions: tuple
    source: str
    identified_on: dict | None = None
    at_readings: bool = False
    method: str = ""

    @property
    def scale_unknown(self) -> str | None:
        """The convention that says the state's scale is its gauge (None: the scale is known): a 2D
        self-calibration without a length reference (``vmt identify`` without ``--delta-l-um``) pins EXX at
        its last node to 0 as well, so EXX and EYY carry an unknown common slope (:data:`SCALE_SYMBOLS`) and
        a length measured with the state carries that unknown (``core.selfcal`` writes the word ``scale
        unknown`` into the convention)."""
        return next((c for c in self.conventions if "scale unknown" in c), None)

    def at_axis_positions(self, J_m) -> "MachineState":
        """The state with its tables at the axis positions: a state at the readings (:attr:`at_readings`)
        has each table's nodes moved by the probe offset ``J_m`` (3,) m along the table's axis (reading
        + J, the probe taken as the one it was identified with); any other state is returned as is.

        Its labels move with the nodes: every position the ``conventions`` name (``EXX(x=0mm)=0``: the
        gauge where a table is pinned) is moved by the same J, as the writer does when it knows J
        (:meth:`core.selfcal.SelfCalResult.estimate`), and a note saying which J placed them is appended,
        so the state saved (:func:`state_doc`, ``positions`` :data:`POSITIONS`) and read back is this
        state. ``identified_on`` is left as read (J null: the writer did not know it)."""
        if not self.at_readings:
            return self
        J = np.asarray(J_m, float)
        tables = {s: (x + J["XYZ".index(iso.symbol(s).axis)], idx) for s, (x, idx) in self.tables.items()}
        J_mm = [float(v) * 1e3 for v in J]
        conventions = tuple(_at_position(c, J_mm) for c in self.conventions) + (
            "nodes placed at the axis positions reading + J with the reader's probe offsets J = ("
            + ", ".join(f"{v + 0.0:g}" for v in J_mm) + ") mm (the writer did not know J)",)
        return replace(self, tables=tables, conventions=conventions, at_readings=False)

    @property
    def symbols(self) -> tuple:
        return tuple(self.tables) + tuple(self.constants)

    @property
    def u(self) -> np.ndarray:
        """(p,) standard uncertainties, SI."""
        return np.sqrt(np.einsum("ij,ij->i", self.factor, self.factor))

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """One draw of the machine parameters from N(mean, cov), (p,) SI."""
        return self.mean + self.factor @ rng.standard_normal(self.factor.shape[1])

    def functions(self, values: np.ndarray | None = None) -> dict:
        """``{symbol: sim-free description}``: ``(kind, nodes m, values)`` with kind ``linear``,
        ``cubic-spline`` or ``constant`` (nodes None), for ``values`` (default the mean)."""
        v = self.mean if values is None else np.asarray(values, float)
        out = {s: (self.interpolation, x, v[i]) for s, (x, i) in self.tables.items()}
        out.update({s: ("constant", None, float(v[i])) for s, i in self.constants.items()})
        return out


def read_estimate(path) -> MachineState:
    """Read the ``estimate`` of an identification result (``vmt identify``'s or an MFB scenario's JSON),
    or a bare ``vmt-estimate/1`` document; :class:`StateFileError` names the key at fault."""
    from .keyreader import read_text_file

    text = read_text_file(path, StateFileError, "machine state")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise StateFileError(f"{path}: not JSON: {e}") from None
    return loads_estimate(doc, source=str(path))


def loads_estimate(doc, source: str = "<estimate>") -> MachineState:
    """:func:`read_estimate` of a parsed document."""
    def fail(key, msg):
        raise StateFileError(f"{source}: {key}: {msg}")

    if not isinstance(doc, dict):
        fail("(top)", "expected a JSON object")
    if doc.get("format") != FORMAT:
        if "estimate" not in doc:
            fail("estimate", f"missing: no {FORMAT} estimate in this file (write it with vmt identify or "
                             "vmt scenario mfb-3axis --json)")
        doc = doc["estimate"]
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            fail("estimate.format", f"expected {FORMAT!r}")
    interp = doc.get("interpolation")
    if interp not in INTERPOLATIONS:
        fail("interpolation", f"expected one of {', '.join(INTERPOLATIONS)}, got {interp!r}")
    params, vals, cov = doc.get("parameters"), doc.get("values"), doc.get("covariance")
    if not isinstance(params, list) or not params or not all(isinstance(p, dict) for p in params):
        fail("parameters", "expected a non-empty list of objects")
    n = len(params)
    try:
        v = np.asarray(vals, float)
        C = np.asarray(cov, float)
    except (TypeError, ValueError):
        fail("values/covariance", "expected numbers")
    if v.shape != (n,):
        fail("values", f"expected {counted(n, 'number')} (one per parameter), got shape {v.shape}")
    if C.shape != (n, n):
        fail("covariance", f"expected {n} x {n}, got shape {C.shape}")
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(C))):
        fail("values/covariance", "not finite")
    scale = max(float(np.abs(np.diag(C)).max()), 1e-300)
    if np.abs(C - C.T).max() > SYM_TOL * scale:
        fail("covariance", "not symmetric")
    tables: dict = {}
    constants: dict = {}
    for i, p in enumerate(params):
        s = p.get("symbol")
        if s is None:
            continue
        key = f"parameters[{i}]"
        try:
            sy = iso.symbol(s)
        except ConfigError:
            fail(f"{key}.symbol", f"unknown ISO 230-1 / 230-7 error symbol {s!r}")
        unit = "urad" if sy.angular else "um"
        if p.get("unit") != unit:
            fail(f"{key}.unit", f"{sy.name} is in {unit}, got {p.get('unit')!r}")
        if "at_mm" in p:
            a = p["at_mm"]
            if not isinstance(a, int | float) or isinstance(a, bool) or not math.isfinite(a):
                fail(f"{key}.at_mm", f"expected a number, got {a!r}")
            if sy.axis not in iso.LINEAR_AXES:
                fail(f"{key}.at_mm", f"{sy.name}: tables along a rotary axis are not supported")
            tables.setdefault(sy.name, []).append((float(a) * 1e-3, i))
        else:
            if sy.name in constants:
                fail(f"{key}.symbol", f"{sy.name} given twice as a constant")
            constants[sy.name] = i
    if not tables and not constants:
        fail("parameters", "no machine error (no parameter has a symbol)")
    both = set(tables) & set(constants)
    if both:
        fail("parameters", f"{sorted(both)[0]} is both a table and a constant")
    keep: list = []
    out_t = {}
    for s, rows in tables.items():
        rows.sort()
        x = np.array([r[0] for r in rows])
        if len(x) < 2 or np.any(np.diff(x) <= 0):
            fail("parameters", f"{s}: a table needs >= 2 nodes at distinct positions")
        out_t[s] = (x, np.arange(len(keep), len(keep) + len(rows)))
        keep += [r[1] for r in rows]
    out_c = {}
    for s, i in constants.items():
        out_c[s] = len(keep)
        keep.append(i)
    keep = np.array(keep)
    Cs = 0.5 * (C + C.T)[np.ix_(keep, keep)] * 1e-12
    w, V = np.linalg.eigh(Cs)
    if w.size and w.min() < -NEG_EIG_TOL * max(w.max(), 1e-300):
        fail("covariance", f"not positive semi-definite (eigenvalue {w.min() * 1e12:.3g})")
    F = V * np.sqrt(np.clip(w, 0.0, None))[None, :]
    return MachineState(out_t, out_c, v[keep] * 1e-6, F, interp, tuple(str(c) for c in doc.get("conventions", [])),
                        source, _read_identified_on(doc.get("identified_on"), fail),
                        at_readings=doc.get("positions") == POSITIONS_READINGS, method=str(doc.get("method", "")))


def state_doc(state: MachineState) -> dict:
    """The ``vmt-estimate/1`` block of ``state``'s machine part (what :func:`loads_estimate` reads back
    as the same state: nodes, values, covariance, ``conventions``, ``positions``, ``identified_on``): a
    state placed at the axis positions (:meth:`MachineState.at_axis_positions`) is written with
    ``positions`` :data:`POSITIONS`, one still at the readings with :data:`POSITIONS_READINGS`."""
    names, symbols, at, units, idx = [], [], [], [], []
    for s, (x, ii) in state.tables.items():
        sy = iso.symbol(s)
        for xv, i in zip(x, ii):
            names.append(f"{s}@{sy.axis.lower()}={float(xv) * 1e3 + 0.0:g}mm")
            symbols.append(s)
            at.append(float(xv))
            units.append("urad" if sy.angular else "um")
            idx.append(int(i))
    for s, i in state.constants.items():
        names.append(s)
        symbols.append(s)
        at.append(None)
        units.append("urad" if iso.symbol(s).angular else "um")
        idx.append(int(i))
    idx = np.asarray(idx, int)
    cov = state.factor @ state.factor.T
    doc = estimate_doc(names, symbols, at, units, state.mean[idx], cov[np.ix_(idx, idx)],
                       method=state.method or f"the machine part of {state.source}",
                       interpolation=state.interpolation, conventions=state.conventions,
                       positions=POSITIONS_READINGS if state.at_readings else POSITIONS)
    if state.identified_on is not None:
        doc["identified_on"] = json.loads(json.dumps(state.identified_on))
    return doc


def _read_identified_on(rec, fail) -> dict | None:
    """The ``identified_on`` record as read (None: absent), or ``fail(key, msg)``."""
    if rec is None:
        return None
    if not isinstance(rec, dict):
        fail("identified_on", "expected an object")
    for k in ("machine", "chain", "controller"):
        if rec.get(k) is not None and not isinstance(rec[k], str):
            fail(f"identified_on.{k}", f"expected a string or null, got {rec[k]!r}")

    def numbers(v, n):
        return (isinstance(v, list) and len(v) == n and all(isinstance(x, int | float) and not isinstance(x, bool)
                                                             and math.isfinite(x) for x in v))

    J = rec.get("probe_offsets_J_mm")
    if J is not None and not (isinstance(J, list) and all(numbers(j, 3) for j in J)):
        fail("identified_on.probe_offsets_J_mm", "expected a list of [x, y, z] mm or null")
    z = rec.get("z_mm")
    if z is not None and not (numbers(z, 2) and z[0] <= z[1]):
        fail("identified_on.z_mm", "expected [lo, hi] mm (lo <= hi) or null")
    t = rec.get("t_s")
    if t is not None and not (numbers(t, 2) and t[0] <= t[1]):
        fail("identified_on.t_s", "expected [first, last] s (first <= last) or null")
    temps = rec.get("temperature_C")
    if temps is not None and not (isinstance(temps, dict) and all(
            isinstance(k, str) and numbers(v, 3) and v[0] <= v[1] <= v[2] for k, v in temps.items())):
        fail("identified_on.temperature_C", "expected {sensor: [min, mean, max] C} (min <= mean <= max) or null")
    return identified_on(rec.get("machine"), rec.get("chain"), J, z, t, temps, rec.get("controller"))
