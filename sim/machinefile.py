"""Machine files: a virtual machine described in TOML (format ``vmt-machine/1``).

A machine file names the machine's structure (ISO 10791 chain), strokes,
rotary axis points, probe offsets, the touch-trigger probe, and every ISO
230-1 / ISO 230-7 error, with units in the key names. Error values follow
vmt's one convention (CONTRIBUTING.md, "Error conventions"): the
displacement of the TOOL relative to the WORKPIECE, whichever side the axis
is on. The built-in machines (``vmc-3axis``, ``mikron-ucp710``,
``nmv3000``) are such files, shipped in ``sim/data/machines/``.

Example (a user's machine starting from a built-in one)::

    format = "vmt-machine/1"
    name = "my-vmc"
    base = "vmc-3axis"          # start from a built-in machine (optional)
    errors = "realistic"         # "none" (default) or "realistic": the papers' magnitudes
    seed = 7                     # realistic: scale, signs and phases drawn (absent: the nominal set)

    [strokes]
    X_mm = [-250, 250]           # replaces the base's X stroke

    [error.EXX]                  # replaces the base set's EXX
    constant_um = 1.0
    slope_um_per_m = 20.0
    periodic = [{ amplitude_um = 0.5, period_mm = 10.0 }]

    [error.EC0Y]
    constant_urad = -43.4

Top-level keys
--------------
``format`` ("vmt-machine/1", optional), ``name``, ``description``,
``base`` (a built-in machine), ``chain`` (ISO 10791, e.g.
``"V[w-X-Y-b-Z-(C)-t]"``), ``errors`` ("none" | "realistic"), ``seed``
(integer, with "realistic"), ``ripple`` (bool, realistic: the 10 mm screw
pitch ripple, default true), and the tables:

- ``[strokes]``: ``X_mm = [min, max]`` per linear axis, ``C_deg = [min,
  max]`` per rotary axis: the axis positions the controller's soft limits
  bound, stated for the file's own tool (``[tool] offset_mm``): a reading
  taken with a stylus of offsets J lies at ``reading + J - offset`` in those
  terms (docs/formats.md, "Strokes"); with that tool, its readings;
- ``[rotary_points]``: ``C_mm = [x, y, z]``, a point on each rotary axis's
  nominal line in R with every axis position at zero (default the origin;
  a linear axis's position is reading + ``[tool] offset_mm``, so a pivot
  on the tool side is given where it is at readings = minus the offsets);
- ``[tool]``: ``offset_mm = [J_X, J_Y, J_Z]``, spindle gauge point minus
  stylus-tip centre (MFB paper eq. 8; default [0, 0, 150], said where
  it is assumed: :func:`tool_offset_note`);
- ``[probe]``: ``stylus_radius_mm``, ``pretravel_um``,
  ``pretravel_axial_um``, ``lobing = [{k = 3, cos_um = 0.3, sin_um = 0.0}]``
  (``sum cos_um cos(k phi) + sin_um sin(k phi)`` in the approach azimuth),
  ``noise_um`` (probing repeatability, a standard deviation, k = 1, along
  the approach), ``max_travel_mm``;
- ``[error.SYMBOL]``: one ISO symbol per table, the sum of its terms.

Error terms (``U`` = ``um`` for a translation, ``urad`` for a rotation;
positions in m, mm or deg as the key says; a rotary axis's positions in deg)
--------------------------------------------------------------------------
Every term of a linear axis is a function of its axis position ``q = reading
+ J`` (the probe offsets ``[tool] offset_mm`` added to the stylus-tip reading,
:mod:`sim.machine`; CONTRIBUTING.md, "Error conventions"), not of the reading
the probe log holds: ``EZZ`` ``slope_um_per_m = 10`` with ``offset_mm = [0, 0,
150]`` is 1.5 um at reading Z = 0 (review30b F5). A rotary axis's: its angle.

- ``constant_U``;
- ``slope_U_per_m``, ``quadratic_U_per_m2``, ``cubic_U_per_m3`` (rotary
  axis: ``_per_deg``, ``_per_deg2``, ``_per_deg3``): a polynomial in the
  axis position;
- ``table_mm`` (rotary ``table_deg``) with ``table_U`` and ``interpolation
  = "cubic"`` (C2 spline, not-a-knot, end tangents beyond the ends) or
  ``"linear"`` (end segments continued beyond the ends);
- ``periodic = [{amplitude_U = a, period_mm = p, phase_deg = f}, ...]``
  (rotary ``period_deg``): ``a sin(2 pi pos / p + f)``;
- ``thermal = {offset_U_per_h, scale_ppm_per_h, tau_h, offset_U_per_K,
  scale_ppm_per_K, temperature_h = [...], temperature_K = [...]}``
  (``sim.errorfuncs.Drift``; ``scale_ppm_*`` for translations of a linear
  axis only: um per m of axis position);
- ``reversal_U``: lost motion (>= 0), half of it added moving in +,
  subtracted moving in - (a lead: ISO 230-2's reversal value ``B_i =
  +reversal_U``); with ``reversal_sense = "lag"`` half of it subtracted
  moving in +, added moving in - (backlash, the axis stopping short of its
  reading: ``B_i = -reversal_U``). ``reversal_sense`` is ``"lead"`` by
  default and needs ``reversal_U`` (``sim.errorfuncs.Reversal``).

Location errors (``EC0Y``, ``EB0Z``, ``EA0Z``, ``EX0C`` ...) take
``constant_U`` only. A linear axis's orient its line in R; a rotary axis's
are relative to the axis carrying it (its line in the carrier's frame): on
a C carried by A, C's line in R at A = 0 is ``EX0C``, ``EY0C`` plus what
A's errors add there (``EY0A``; ``EB0A`` times the height above A's line;
CONTRIBUTING.md, "Error conventions").

Bounds: an error the file gives, its terms summed, must stay within
:data:`MAX_ANGULAR_URAD` (a rotation) or :data:`MAX_LINEAR_UM` (a
translation) over its axis's stroke, both directions, at the start and after
:data:`BOUND_AFTER_H` hours (its thermal drift); beyond, the file is refused
naming the error, the value reached and the unit (review30 F3: ``EC0Y =
-20000000 urad``, 20 rad, simulated as "368 touches (29 ok)", exit 0).

A malformed file raises :class:`MachineFileError` with one line naming the
file, the key and what is wrong.
"""

from __future__ import annotations

import hashlib
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from core import iso
from core.chain import parse_chain
from core.exceptions import ConfigError, counted
from core.keyreader import KeyReader, read_text_file
from core.units import DEG, MM, UM

from .errorfuncs import (Constant, Drift, ErrorFunction, LinearTable, Periodic, Polynomial, Reversal,
                         SplineTable, Sum)

FORMAT = "vmt-machine/1"
#: Probe offsets when a file gives none: a 150 mm probe below the gauge line.
DEFAULT_OFFSET_MM = (0.0, 0.0, 150.0)
_TOP = ("format", "name", "description", "base", "chain", "errors", "seed", "ripple",
        "strokes", "rotary_points", "tool", "probe", "error")
_PROBE = ("stylus_radius_mm", "pretravel_um", "pretravel_axial_um", "lobing", "noise_um", "max_travel_mm")


# The bounds on an error's size live in core.iso (one place: the vmt-comp/1 reader, core.volumetric.comp_tables,
# applies them too); re-exported here, where they were first set (review30 F3).
MAX_ANGULAR_URAD = iso.MAX_ANGULAR_URAD
MAX_LINEAR_UM = iso.MAX_LINEAR_UM
#: The bounds hold at the start and after this many hours of the error's thermal drift (a working shift).
BOUND_AFTER_H = 8.0
#: Positions along the stroke where an error is checked against its bound, beside the peaks and troughs of
#: each periodic term (:func:`stroke_positions`).
BOUND_SAMPLES = 2001


def _periodic_terms(f: ErrorFunction):
    if isinstance(f, Periodic):
        yield f
    elif isinstance(f, Sum):
        for t in f.terms:
            yield from _periodic_terms(t)


def stroke_positions(f: ErrorFunction, stroke, n: int = BOUND_SAMPLES) -> np.ndarray:
    """Sorted positions over ``stroke`` (SI) where ``f`` is evaluated for its range: ``n`` evenly spaced
    and, for each of its periodic terms ``a sin(2 pi pos / p + phi)``, the peak and the trough nearest to
    each of them (inside the stroke). Even samples alone alias a period near a multiple of their step
    (audit37: a 1500 um ripple of period 0.6 mm on a 600 mm stroke sampled every 0.3 mm read as 0 and
    passed the +-1000 um bound; `vmt machine show` printed a 5 um ripple of period 6 mm as [-0.000 ..
    +0.000]); at its peaks a ripple of any period is seen at its amplitude beside the rest of ``f``."""
    lo, hi = float(stroke[0]), float(stroke[1])
    pos = np.linspace(lo, hi, n)
    parts = [pos]
    for t in _periodic_terms(f):
        k = 2 * np.pi / t.period
        for top in (0.5 * np.pi, -0.5 * np.pi):           # sin's peak, its trough
            with np.errstate(over="ignore", invalid="ignore"):
                m = np.round((k * pos + t.phase - top) / (2 * np.pi))
                x = (top - t.phase + 2 * np.pi * m) / k
            parts.append(x[np.isfinite(x) & (x >= lo) & (x <= hi)])
    return np.unique(np.concatenate(parts))


def bound_problem(s, f: ErrorFunction, stroke, what: str = "a machine file's") -> str | None:
    """What is wrong with error ``f`` of symbol ``s`` (core.iso.Symbol) over ``stroke`` (its axis's, SI), or
    None: not finite, or beyond :data:`MAX_ANGULAR_URAD` / :data:`MAX_LINEAR_UM` at the start or after
    :data:`BOUND_AFTER_H` hours, either direction. The one check of a machine file's errors and of a vcmm
    task's declared limits (``what`` names whose: review32d F4, a task's 1e12 um/m slope was refused only
    later, naming neither file nor key)."""
    U, bound = ("urad", MAX_ANGULAR_URAD) if s.angular else ("um", MAX_LINEAR_UM)
    pos = stroke_positions(f, stroke)
    peak = 0.0
    at = when = 0.0
    for t_s in (0.0, BOUND_AFTER_H * 3600.0):
        for d in (1.0, -1.0):
            with np.errstate(over="ignore", invalid="ignore"):
                v = np.asarray(f(pos, np.full(pos.shape, t_s), np.full(pos.shape, d)), float) / 1e-6
            i = int(np.argmax(np.abs(v)))
            if not np.isfinite(v[i]):
                return f"not finite on the {s.axis} stroke"
            if abs(v[i]) > abs(peak):
                peak, at, when = v[i], pos[i], t_s
    if abs(peak) <= bound * (1 + 1e-9):     # the bound itself loads (units scaled to SI and back)
        return None
    rot = s.axis in iso.ROTARY_AXES
    where = f"{at / DEG:g} deg" if rot else f"{at / MM:g} mm"
    why = ("vmt's models take angular errors to first order: the neglected e^2/2 is 0.5 um a metre "
           "from the axis at 1000 urad" if s.angular else
           "half the plans' 2 mm approach clearance; a real machine's are tens of um")
    at_ = [] if s.location else [f"at {s.axis} {where}"]
    at_ += [f"after {BOUND_AFTER_H:g} h"] if when else []
    return (f"reaches {peak:.6g} {U}" + (f" ({', '.join(at_)})" if at_ else "")
            + f": beyond the +-{bound:g} {U} {what} " + ("rotation" if s.angular else "translation")
            + f" error may have ({why})")


class MachineFileError(ConfigError):
    """A machine file that cannot be read: the file, the key, what is wrong."""


@dataclass(frozen=True)
class MachineSpec:
    """A machine read from a file.

    Attributes
    ----------
    config : sim.machine.MachineConfig
        Structure, geometry and truth errors (SI).
    probe : sim.probe.ProbeConfig
    source : str
        The file (or built-in name) it was read from.
    description : str
    errors : str
        The base error set: ``"none"`` or ``"realistic"``.
    seed : int or None
        Seed of the realistic set (None: the nominal set).
    overrides : tuple of str
        Symbols set by ``[error.SYMBOL]`` tables.
    tool_offset_given : bool
        Whether the file (or the built-in it is based on) gives ``[tool] offset_mm``; False: J is
        :data:`DEFAULT_OFFSET_MM`, assumed (:func:`tool_offset_note` says so).
    """

    config: object
    probe: object
    source: str
    description: str = ""
    errors: str = "none"
    seed: int | None = None
    overrides: tuple = field(default=())
    tool_offset_given: bool = True

    @property
    def name(self) -> str:
        return self.config.name


def builtin_names() -> tuple[str, ...]:
    """Names of the machine files shipped in the package."""
    d = resources.files("sim") / "data" / "machines"
    return tuple(sorted(p.name[:-5] for p in d.iterdir() if p.name.endswith(".toml")))


def builtin_text(name: str) -> str:
    """The TOML text of a built-in machine."""
    if name not in builtin_names():
        raise MachineFileError(f"unknown built-in machine {name!r}; known: {', '.join(builtin_names())}")
    return (resources.files("sim") / "data" / "machines" / f"{name}.toml").read_text(encoding="utf-8")


def resolve(name_or_path: str) -> MachineSpec:
    """A built-in machine by name, or a machine file by path (``--machine``)."""
    if name_or_path in builtin_names():
        return loads(builtin_text(name_or_path), source=name_or_path)
    p = Path(name_or_path)
    if p.suffix.lower() == ".toml" or p.exists():
        return load(p)
    raise MachineFileError(f"--machine {name_or_path!r}: no such file, and not a built-in machine "
                           f"({', '.join(builtin_names())})")


#: The error sets ``--errors`` names for a built-in machine (:func:`truth_machine`).
ERROR_SETS = ("realistic", "study", "drawn", "none")


def truth_machine(name_or_path: str, errors: str | None = None, default: str = "realistic") -> MachineSpec:
    """The machine ``--machine NAME|FILE [--errors SET]`` names, in every command.

    One rule: a machine file is the machine it describes, with the errors it
    states (``errors`` is refused for it). A built-in NAME is its shipped file
    with the error set ``errors`` names, ``default`` when not given (each
    command states its default in its help):

    - ``"realistic"``: :func:`sim.machines.realistic_errors` over the axis
      positions its strokes allow (strokes + its tool's J), the papers'
      magnitudes, nominal set, with the 10 mm screw ripple;
    - ``"study"``: the same set without the screw ripple (the MFB studies'
      truth, errors their smooth models represent);
    - ``"drawn"``: a ripple-free set with magnitudes and phases drawn with
      seed 1 over the machine's X, Y, Z and C axes and the default
      (Mikron-like) strokes (``realistic_errors(rng=default_rng(1),
      ripple=False)``): the virtual machine behind the GRBL emulator
      (``machine serve --scene``) and ``probe --controller virtual:SCENE``
      since they were written;
    - ``"none"``: the file as shipped (no errors).

    A command's default machine is a built-in name, so omitting ``--machine``
    is naming it.
    """
    from dataclasses import replace

    import numpy as np

    from .machines import realistic_errors

    spec = resolve(name_or_path)
    if name_or_path not in builtin_names():
        if errors is not None:
            raise ConfigError(f"--errors: the machine file {name_or_path} states its errors "
                              "(errors = ..., [error.*])")
        return spec
    errors = default if errors is None else errors
    if errors not in ERROR_SETS:
        raise ConfigError(f"--errors {errors!r}: expected {', '.join(ERROR_SETS)}")
    if errors == "none":
        return replace(spec, errors="none", seed=None, overrides=())
    cfg = spec.config
    axes = tuple(a for a in "XYZABC" if a in cfg.strokes)
    if errors == "drawn":
        errs = realistic_errors(tuple(a for a in "XYZC" if a in cfg.strokes), rng=np.random.default_rng(1),
                                ripple=False)
        return replace(spec, config=replace(cfg, errors=errs), errors="drawn", seed=1, overrides=())
    errs = realistic_errors(axes, strokes=cfg.strokes, J_m=cfg.J_m)
    if errors == "study":
        errs = {k: strip_ripple(v) for k, v in errs.items()}
    return replace(spec, config=replace(cfg, errors=errs), errors=errors, seed=None, overrides=())


def tool_offset_note(spec: MachineSpec) -> str | None:
    """The line a command prints, and writes in its JSON, where ``spec``'s J was assumed (its file gives no
    ``[tool] offset_mm``: :data:`DEFAULT_OFFSET_MM` stands in), else None.

    J changes results (the Abbe arms through the machine's angular errors, the axis positions reading + J the
    errors are evaluated at), so a default standing in for it is said, as the CLI says its other assumptions
    (identify's "probe offsets J unknown", the self-calibration's "scale unknown: delta_L not given"), rather than
    refused: a file written before [tool] existed, or for the 150 mm probe, still runs, and says what it ran with."""
    if spec.tool_offset_given:
        return None
    J = ", ".join(f"{v * 1e3:g}" for v in spec.config.J_m)
    return f"tool offset not given: J = ({J}) mm assumed"


def errors_label(name_or_path: str, spec: MachineSpec) -> str:
    """How a command names the truth errors of ``--machine name_or_path`` (:func:`truth_machine`'s ``spec``).

    A built-in machine's error set (``realistic``, ...), or for a machine
    file what errors its machine has: ``machine file m.toml (sha256
    1a2b3c4d5e6f): EXX, ECC set on base none`` (the ``[error.*]`` tables on
    the base set, seed when drawn), ``machine file m.toml (sha256 ...): base
    realistic, seed 3`` without tables. The file's name only (a log should
    not carry the writer's directories) and the first 12 hex digits of the
    SHA-256 of its bytes, so which file made the log is still exact. Logs
    carry it as free text (metadata ``errors``); nothing parses it, so logs
    written with earlier labels read as before.
    """
    if name_or_path in builtin_names():
        return spec.errors
    p = Path(name_or_path)
    file = f"machine file {p.name} (sha256 {hashlib.sha256(p.read_bytes()).hexdigest()[:12]})"
    base = f"base {spec.errors}" + (f", seed {spec.seed}" if spec.seed is not None else "")
    if spec.overrides:
        return f"{file}: {', '.join(spec.overrides)} set on {base}"
    return f"{file}: {base}"


def strip_ripple(f):
    """``f`` without its screw-pitch ripple (the ``Periodic`` terms of a sum; a purely periodic error stays)."""
    from .errorfuncs import Periodic, Sum

    if isinstance(f, Sum):
        terms = tuple(t for t in f.terms if not isinstance(t, Periodic))
        if not terms:  # a rotary axis' periodic motion, not a screw ripple
            return f
        return terms[0] if len(terms) == 1 else Sum(terms)
    return f


def load(path) -> MachineSpec:
    """Read a machine file.

    Raises
    ------
    MachineFileError
        No such file, not TOML, or a key that is wrong (named).
    """
    return loads(read_text_file(path, MachineFileError, "machine file"), source=str(path))


def describe_error(f: ErrorFunction, s) -> str:
    """One line of what an error function is, in the report unit of symbol ``s`` (``core.iso.Symbol``)."""
    rot = s.axis in iso.ROTARY_AXES
    pos, pf = ("deg", DEG) if rot else ("mm", MM)
    u = s.report_unit
    if isinstance(f, Sum):
        return " + ".join(describe_error(t, s) for t in f.terms)
    if isinstance(f, Constant):
        return f"constant {f.value / UM:g} {u}"
    if isinstance(f, Polynomial):
        per = "deg" if rot else "m"
        parts = []
        for k, v in enumerate(f.coeffs):
            c = v / UM * (DEG ** k if rot else 1.0)
            if c == 0.0 and len(f.coeffs) > 1:
                continue
            unit = u if k == 0 else f"{u}/{per}" + (f"^{k}" if k > 1 else "")
            var = "" if k == 0 else f" * {s.axis}" + (f"^{k}" if k > 1 else "")
            parts.append(f"{c:g} {unit}{var}")
        return "polynomial " + " + ".join(parts).replace("+ -", "- ")
    if isinstance(f, (SplineTable, LinearTable)):
        how = "cubic" if isinstance(f, SplineTable) else "linear"
        return (f"table of {len(f.pos)} points, {how}, {f.pos[0] / pf:g}..{f.pos[-1] / pf:g} {pos}, "
                f"{min(f.values) / UM:g}..{max(f.values) / UM:g} {u}")
    if isinstance(f, Periodic):
        return f"periodic {f.amplitude / UM:g} {u}, period {f.period / pf:g} {pos}, phase {f.phase / DEG:g} deg"
    if isinstance(f, Reversal):
        return f"reversal {f.lost_motion / UM:g} {u}" + (", lag" if f.sense == "lag" else "")
    if isinstance(f, Drift):
        return "thermal drift"
    return type(f).__name__


def _parse(text: str, source: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise MachineFileError(f"{source}: not TOML: {e}") from None


def loads(text: str, source: str = "<machine file>") -> MachineSpec:
    """Read a machine file's text (see the module doc)."""
    doc = _parse(text, source)
    if not doc:  # said as the logs say it (review32d F11: was "chain: missing: the ISO 10791 chain")
        raise MachineFileError(f"{source}: empty file" + (" (comments only)" if text.strip() else ""))
    return _Reader(source).spec(doc)


class _Reader(KeyReader):
    error_class = MachineFileError

    # ------------------------------------------------------------ helpers
    def numbers(self, key, v, n=None, *, min_len=1) -> tuple[float, ...]:
        if not isinstance(v, list):
            self.fail(key, f"expected a list of numbers, got {v!r}")
        if n is not None and len(v) != n:
            self.fail(key, f"expected {n} numbers, got {len(v)}")
        if len(v) < min_len:
            self.fail(key, f"expected at least {min_len} numbers, got {len(v)}")
        return tuple(self.number(f"{key}[{i}]", x) for i, x in enumerate(v))

    # ------------------------------------------------------------ document
    def merged(self, doc: dict) -> dict:
        for k in doc:
            if k not in _TOP:
                self.fail(k, f"unknown key (expected one of {', '.join(_TOP)})")
        if "format" in doc and doc["format"] != FORMAT:
            self.fail("format", f"expected {FORMAT!r}, got {doc['format']!r}")
        if "base" not in doc:
            return doc
        base = self.string("base", doc["base"])
        if base not in builtin_names():
            self.fail("base", f"unknown built-in machine {base!r} (known: {', '.join(builtin_names())})")
        out = _parse(builtin_text(base), base)
        out.pop("format", None)
        out["name"] = base
        for k, v in doc.items():
            if k == "base":
                continue
            if k in ("strokes", "rotary_points", "tool", "probe", "error"):
                merged = dict(self.table(k, out.get(k, {})))
                merged.update(self.table(k, v))
                out[k] = merged
            else:
                out[k] = v
        if "chain" in doc and "strokes" in out:  # a chain without an axis drops its stroke and point
            axes = set(self.chain(doc["chain"]).axes)
            out["strokes"] = {k: v for k, v in out["strokes"].items()
                              if k.split("_")[0] in axes or k in doc.get("strokes", {})}
            out["rotary_points"] = {k: v for k, v in out.get("rotary_points", {}).items()
                                    if k.split("_")[0] in axes or k in doc.get("rotary_points", {})}
        return out

    def chain(self, v):
        try:
            return parse_chain(self.string("chain", v))
        except ConfigError as e:
            self.fail("chain", str(e))

    def spec(self, doc: dict) -> MachineSpec:
        from .machine import MachineConfig
        from .machines import realistic_errors

        doc = self.merged(doc)
        name = self.string("name", doc.get("name", Path(self.source).stem))
        if "chain" not in doc:
            self.fail("chain", "missing: the ISO 10791 chain, e.g. \"V[w-X-Y-b-Z-(C)-t]\"")
        ch = self.chain(doc["chain"])
        strokes = self.strokes(self.table("strokes", doc.get("strokes", {})), ch)
        points = self.points(self.table("rotary_points", doc.get("rotary_points", {})), ch)
        tool = self.table("tool", doc.get("tool", {}))
        for k in tool:
            if k != "offset_mm":
                self.fail(f"tool.{k}", "unknown key (expected offset_mm)")
        J = tuple(v / 1e3 for v in self.numbers("tool.offset_mm", tool.get("offset_mm", list(DEFAULT_OFFSET_MM)), 3))
        kind = self.string("errors", doc.get("errors", "none"))
        if kind not in ("none", "realistic"):
            self.fail("errors", f"expected \"none\" or \"realistic\", got {kind!r}")
        seed = doc.get("seed")
        if seed is not None:
            if isinstance(seed, bool) or not isinstance(seed, int):
                self.fail("seed", f"expected an integer, got {seed!r}")
            if kind != "realistic":
                self.fail("seed", "only with errors = \"realistic\"")
        ripple = doc.get("ripple", True)
        if not isinstance(ripple, bool):
            self.fail("ripple", f"expected true or false, got {ripple!r}")
        errs: dict[str, ErrorFunction] = {}
        if kind == "realistic":
            rng = None if seed is None else np.random.default_rng(seed)
            errs = realistic_errors(ch.axes, strokes=strokes, J_m=J, rng=rng, ripple=ripple)
        overrides = []
        for sym, body in self.table("error", doc.get("error", {})).items():
            key = f"error.{sym}"
            try:
                s = iso.symbol(sym)
            except ConfigError:
                self.fail(key, "unknown ISO 230-1 / 230-7 error symbol")
            if s.axis not in ch.axes:
                self.fail(key, f"{s.name} belongs to axis {s.axis}, not in the chain {ch.text}")
            if s.location and s.axis in iso.LINEAR_AXES and s.name not in iso.SQUARENESS:
                self.fail(key, f"{s.name} is zero by the ISO 230-1 convention (X primary, Y secondary)")
            errs[s.name] = self.error(key, s, self.table(key, body))
            self.bounded(key, s, errs[s.name], strokes[s.axis])
            overrides.append(s.name)
        try:
            cfg = MachineConfig(name=name, chain=ch.text, strokes=strokes, rotary_points_R_m=points,
                                J_m=J, errors=errs)
        except ConfigError as e:
            self.fail("machine", str(e))
        probe = self.probe(self.table("probe", doc.get("probe", {})))
        return MachineSpec(cfg, probe, self.source, str(doc.get("description", "")), kind, seed, tuple(overrides),
                           tool_offset_given="offset_mm" in tool)

    def axis_of(self, key, k, axes, text, unit) -> str:
        """The axis of a key ``<axis>_<unit>`` among ``axes`` (named in ``text``)."""
        axis, _, got = k.partition("_")
        if axis not in axes:
            self.fail(key, f"{axis!r} is not {text}")
        want = unit(axis)
        if got != want:
            self.fail(key, f"expected {axis}_{want}")
        return axis

    def strokes(self, t, ch) -> dict:
        def unit(a):
            return "deg" if a in iso.ROTARY_AXES else "mm"

        out = {}
        for k, v in t.items():
            key = f"strokes.{k}"
            axis = self.axis_of(key, k, ch.axes, f"an axis of the chain {ch.text}", unit)
            lo, hi = self.numbers(key, v, 2)
            if not lo < hi:
                self.fail(key, f"expected [min, max] with min < max, got {v!r}")
            out[axis] = (lo * DEG, hi * DEG) if unit(axis) == "deg" else (lo / 1e3, hi / 1e3)
        for a in ch.axes:
            if a not in out:
                self.fail(f"strokes.{a}_{unit(a)}", "missing")
        return out

    def points(self, t, ch) -> dict:
        return {self.axis_of(f"rotary_points.{k}", k, ch.rotary_axes, f"a rotary axis of the chain {ch.text}",
                             lambda a: "mm"): tuple(x / 1e3 for x in self.numbers(f"rotary_points.{k}", v, 3))
                for k, v in t.items()}

    def probe(self, t):
        from .probe import ProbeConfig

        kw = {}
        for k, v in t.items():
            key = f"probe.{k}"
            if k not in _PROBE:
                self.fail(key, f"unknown key (expected one of {', '.join(_PROBE)})")
            if k == "lobing":
                terms = v if isinstance(v, list) else self.fail(key, "expected a list of {k, cos_um, sin_um}")
                lob = []
                for i, term in enumerate(terms):
                    tk = f"{key}[{i}]"
                    term = self.table(tk, term)
                    for kk in term:
                        if kk not in ("k", "cos_um", "sin_um"):
                            self.fail(f"{tk}.{kk}", "unknown key (expected k, cos_um, sin_um)")
                    order = term.get("k")
                    if isinstance(order, bool) or not isinstance(order, int) or order < 1:
                        self.fail(f"{tk}.k", f"expected an integer >= 1, got {order!r}")
                    lob.append((order, self.number(f"{tk}.cos_um", term.get("cos_um", 0.0)) / 1e6,
                                self.number(f"{tk}.sin_um", term.get("sin_um", 0.0)) / 1e6))
                kw["lobing_m"] = tuple(lob)
            elif k == "stylus_radius_mm":
                kw["stylus_r_m"] = self.number(key, v, positive=True) / 1e3
            elif k == "pretravel_um":
                kw["pretravel_m"] = self.number(key, v) / 1e6
            elif k == "pretravel_axial_um":
                kw["pretravel_axial_m"] = self.number(key, v) / 1e6
            elif k == "noise_um":
                kw["repeatability_k2_m"] = 2.0 * self.number(key, v, nonneg=True) / 1e6
            elif k == "max_travel_mm":
                kw["max_travel_m"] = self.number(key, v, positive=True) / 1e3
        try:
            return ProbeConfig(**kw)
        except ConfigError as e:
            self.fail("probe", str(e))

    # ------------------------------------------------------------ one error
    def error(self, key, s, t) -> ErrorFunction:
        U = "urad" if s.angular else "um"
        rot = s.axis in iso.ROTARY_AXES
        P, Pt = ("deg", "deg") if rot else ("m", "mm")  # slope unit, table/period unit

        def Pf(v):  # a position in the table/period unit -> SI
            return v * DEG if rot else v / 1e3
        allowed = {f"constant_{U}"}
        if not s.location:
            allowed |= {f"slope_{U}_per_{P}", f"quadratic_{U}_per_{P}2", f"cubic_{U}_per_{P}3",
                        f"table_{Pt}", f"table_{U}", "interpolation", "periodic", "thermal", f"reversal_{U}",
                    "reversal_sense"}
        if not t:
            self.fail(key, f"no terms (expected {', '.join(sorted(allowed))})")
        for k in t:
            if k not in allowed:
                other = "um" if U == "urad" else "urad"
                if other in k:
                    self.fail(f"{key}.{k}", f"{s.name} is {'a rotation' if s.angular else 'a translation'}; "
                                            f"use {k.replace(other, U)}")
                if s.location:
                    self.fail(f"{key}.{k}", f"{s.name} is a location error: constant_{U} only")
                self.fail(f"{key}.{k}", f"unknown key (expected {', '.join(sorted(allowed))})")
        terms: list[ErrorFunction] = []
        pos_to_unit = 1.0 / DEG if rot else 1.0  # reading (m | rad) -> slope position unit (m | deg)
        coeffs = [self.number(f"{key}.constant_{U}", t.get(f"constant_{U}", 0.0)) / 1e6]
        for pw, name in ((1, "slope"), (2, "quadratic"), (3, "cubic")):
            k = f"{name}_{U}_per_{P}{pw if pw > 1 else ''}"
            c = self.number(f"{key}.{k}", t.get(k, 0.0)) / 1e6
            coeffs.append(c * pos_to_unit ** pw)
        while len(coeffs) > 1 and coeffs[-1] == 0.0:
            coeffs.pop()
        if s.location:
            return Constant(coeffs[0])
        if any(coeffs):
            terms.append(Constant(coeffs[0]) if len(coeffs) == 1 else Polynomial(tuple(coeffs)))
        if f"table_{Pt}" in t or f"table_{U}" in t or "interpolation" in t:
            for k in (f"table_{Pt}", f"table_{U}", "interpolation"):
                if k not in t:
                    self.fail(f"{key}.{k}", "missing: a table needs table_{0}, table_{1} and interpolation"
                              .format(Pt, U))
            x = self.numbers(f"{key}.table_{Pt}", t[f"table_{Pt}"], min_len=2)
            y = self.numbers(f"{key}.table_{U}", t[f"table_{U}"])
            if len(y) != len(x):
                self.fail(f"{key}.table_{U}", f"{counted(len(y), 'value')} for {counted(len(x), 'position')}")
            if any(b <= a for a, b in zip(x, x[1:])):
                self.fail(f"{key}.table_{Pt}", "positions must be strictly increasing")
            how = t["interpolation"]
            kind = {"cubic": SplineTable, "linear": LinearTable}.get(how)
            if kind is None:
                self.fail(f"{key}.interpolation", f"expected \"cubic\" or \"linear\", got {how!r}")
            terms.append(kind(tuple(Pf(v) for v in x), tuple(v / 1e6 for v in y)))
        if "periodic" in t:
            items = t["periodic"] if isinstance(t["periodic"], list) else [t["periodic"]]
            for i, item in enumerate(items):
                pk = f"{key}.periodic[{i}]"
                item = self.table(pk, item)
                for k in item:
                    if k not in (f"amplitude_{U}", f"period_{Pt}", "phase_deg"):
                        self.fail(f"{pk}.{k}", f"unknown key (expected amplitude_{U}, period_{Pt}, phase_deg)")
                for k in (f"amplitude_{U}", f"period_{Pt}"):
                    if k not in item:
                        self.fail(f"{pk}.{k}", "missing")
                terms.append(Periodic(self.number(f"{pk}.amplitude_{U}", item[f"amplitude_{U}"]) / 1e6,
                                      Pf(self.number(f"{pk}.period_{Pt}", item[f"period_{Pt}"], positive=True)),
                                      self.number(f"{pk}.phase_deg", item.get("phase_deg", 0.0)) * DEG))
        if "thermal" in t:
            terms.append(self.thermal(f"{key}.thermal", s, U, self.table(f"{key}.thermal", t["thermal"])))
        if "reversal_sense" in t and f"reversal_{U}" not in t:
            self.fail(f"{key}.reversal_sense", f"needs reversal_{U} (the lost motion's size)")
        if f"reversal_{U}" in t:
            sense = t.get("reversal_sense", "lead")
            if sense not in ("lead", "lag"):
                self.fail(f"{key}.reversal_sense", f"expected \"lead\" or \"lag\", got {sense!r}")
            terms.append(Reversal(self.number(f"{key}.reversal_{U}", t[f"reversal_{U}"], nonneg=True) / 1e6,
                                  sense))
        if not terms:
            return Constant(0.0)
        return terms[0] if len(terms) == 1 else Sum(tuple(terms))

    def bounded(self, key, s, f: ErrorFunction, stroke) -> None:
        """Refuse an error that leaves :data:`MAX_ANGULAR_URAD` / :data:`MAX_LINEAR_UM` over the stroke."""
        said = bound_problem(s, f, stroke)
        if said is not None:
            self.fail(key, said)

    def thermal(self, key, s, U, t) -> Drift:
        allowed = [f"offset_{U}_per_h", "tau_h", f"offset_{U}_per_K", "temperature_h", "temperature_K"]
        if not s.angular and s.axis in iso.LINEAR_AXES:
            allowed += ["scale_ppm_per_h", "scale_ppm_per_K"]
        for k in t:
            if k not in allowed:
                self.fail(f"{key}.{k}", f"unknown key (expected {', '.join(allowed)})")
        H = 3600.0
        kw = dict(offset_rate=self.number(f"{key}.offset_{U}_per_h", t.get(f"offset_{U}_per_h", 0.0)) / 1e6 / H,
                  scale_rate=self.number(f"{key}.scale_ppm_per_h", t.get("scale_ppm_per_h", 0.0)) * 1e-6 / H,
                  offset_per_K=self.number(f"{key}.offset_{U}_per_K", t.get(f"offset_{U}_per_K", 0.0)) / 1e6,
                  scale_per_K=self.number(f"{key}.scale_ppm_per_K", t.get("scale_ppm_per_K", 0.0)) * 1e-6)
        if "tau_h" in t:
            kw["tau_s"] = self.number(f"{key}.tau_h", t["tau_h"], positive=True) * H
        if "temperature_h" in t or "temperature_K" in t:
            th = self.numbers(f"{key}.temperature_h", t.get("temperature_h", []))
            tk = self.numbers(f"{key}.temperature_K", t.get("temperature_K", []))
            if len(th) != len(tk):
                self.fail(f"{key}.temperature_K", f"{counted(len(tk), 'temperature')} for {counted(len(th), 'time')}")
            # the file's keys, not Drift's fields (session 37, audit37: the error named Drift.temperature_t_s)
            if any(b <= a for a, b in zip(th, th[1:])):
                self.fail(f"{key}.temperature_h", "times must be strictly increasing (h)")
            kw["temperature_t_s"] = tuple(v * H for v in th)
            kw["temperature_K"] = tk
        else:
            for k in (f"offset_{U}_per_K", "scale_ppm_per_K"):
                if t.get(k):
                    self.fail(f"{key}.{k}", "needs a temperature history (temperature_h and temperature_K)")
        try:
            return Drift(**kw)
        except ConfigError as e:
            self.fail(key, str(e))
