"""Options shared by several ``vmt`` commands: one meaning per option name.

The CLI speaks one language: an option name means one thing in every command
that takes it, and a name that carries a quantity says its unit
(``--feed-mm-min``, ``--timeout-s``, ``--c-angles-deg``; the suffixes are
:data:`UNIT_SUFFIXES`). ``tests/scenarios/test_cli_options.py`` walks every
command's parser and holds the rule.

Shared here: ``--grid-mm`` (``identify``, ``design``), ``--stylus-r-mm`` (``plan grid``, ``fit``), the probing settings
(``probe``, ``machine program``), ``--machine NAME|FILE`` with its truth
errors (:func:`add_machine_args`, :func:`sim.machinefile.truth_machine`: one rule for every
command), ``--noise-um`` and the old names kept as hidden aliases
(:func:`add_renamed`: they work and say on stderr what they are now called).
"""

from __future__ import annotations

import argparse
import math
import sys

#: The unit suffixes an option carrying a quantity ends with (``--travel-mm``, ``--drift-um-per-h``).
UNIT_SUFFIXES = ("-mm", "-um", "-m", "-s", "-deg", "-urad", "-ppm", "-mm-min", "-um-per-h", "-um-per-m",
                 "-per-k", "-k", "-c")

#: The one placeholder an option shows in every command's usage and help (``--report DIR`` in discover, iso230-2,
#: scenario and vcmm alike; it read ``--report REPORT`` in three and ``--report DIR`` in one, ``--json`` OUT,
#: JSON_OUT or JSON). :class:`scenarios.cli.guard.OneLineParser` gives an option of this table its placeholder when
#: the command gives none; ``tests/scenarios/test_cli_options.py`` refuses a name shown with two placeholders, and a
#: folder (``DIR``) where a file goes or a file where a folder goes.
PLACEHOLDERS = {"--json": "OUT", "--out": "OUT", "--junit": "OUT", "--report": "DIR", "--out-dir": "DIR",
                "--comp": "DIR", "--apply-comp": "DIR", "--plan": "PLAN", "--machine": "NAME|FILE",
                "--bar-calibration": "FILE", "--seed": "SEED", "--mc": "N",
                "--clearance-mm": "CLEARANCE_MM", "--overtravel-mm": "OVERTRAVEL_MM"}


class Renamed(argparse.Action):
    """An old option name: still works (same destination), prints one line on stderr naming the new one."""

    def __init__(self, option_strings, dest, new: str = "", **kw):
        self.new = new
        super().__init__(option_strings, dest, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"vmt: {option_string} is renamed to {self.new} (the old name works for now; use the new one)",
              file=sys.stderr, flush=True)
        setattr(namespace, self.dest, self.const if self.nargs == 0 else values)


def add_renamed(p, old: str, new_action: argparse.Action) -> None:
    """Keep ``old`` working on ``p`` as a hidden alias of the option ``new_action`` (same dest, type, choices)."""
    a = new_action
    flag = a.nargs == 0
    p.add_argument(old, dest=a.dest, action=Renamed, new=a.option_strings[0], nargs=0 if flag else a.nargs,
                   const=a.const if flag else None, type=None if flag else a.type,
                   choices=None if flag else a.choices, default=argparse.SUPPRESS, help=argparse.SUPPRESS)


def option(p, name: str, *args, old: tuple[str, ...] = (), **kw) -> argparse.Action:
    """``p.add_argument(name, ...)``, with each of ``old`` kept as a hidden renamed alias.

    A required option with an old name is checked by the parser after parsing
    (:class:`scenarios.cli.guard.OneLineParser`), so that either name satisfies it.
    """
    if kw.get("action") not in ("store_true", "store_false") and "metavar" not in kw:
        kw["metavar"] = PLACEHOLDERS.get(name, name.lstrip("-").upper().replace("-", "_"))
    if old and kw.get("required"):
        kw["help"] = kw.get("help", "") + " (required)"
        kw["required"] = False
        kw.setdefault("default", None)
        a = p.add_argument(name, *args, **kw)
        p.vmt_required = (*getattr(p, "vmt_required", ()), (a.dest, name))
    else:
        a = p.add_argument(name, *args, **kw)
    for o in old:
        add_renamed(p, o, a)
    return a


def add_plan_arg(p, help: str) -> None:
    """``--plan PLAN``: the probing plan, one spelling in every command that reads one (``probe``, ``import``,
    ``machine program``, ``design``, ``vcmm``), required here. ``design`` and ``vcmm`` took it as a positional
    argument until session 33 (review32d F9): that spelling still works, hidden, and says on stderr in one
    line that it is now ``--plan`` (:class:`scenarios.cli.guard.OneLineParser` moves it over after parsing)."""
    p.add_argument("--plan", default=None, metavar="PLAN", help=help + " (required)")
    p.add_argument("plan_positional", nargs="?", default=None, help=argparse.SUPPRESS)
    p.vmt_required = (*getattr(p, "vmt_required", ()), ("plan", "--plan"))
    p.vmt_positional_renamed = (*getattr(p, "vmt_positional_renamed", ()),
                                ("plan_positional", "plan", "PLAN", "--plan"))


def parse_grid(text: str, p_R):
    """``--grid-mm STEP`` (nodes at multiples of STEP covering ``p_R``) or ``x0:x1:step`` (both axes).

    ``p_R`` : (n, 2+) float, the nominal tip centres in R, m (used for STEP only).
    """
    from core.exceptions import ConfigError
    from core.selfcal import Grid
    from core.units import MM

    try:
        mm = [float(v) for v in text.split(":")]
    except ValueError:
        raise ConfigError(f"--grid-mm: expected STEP or x0:x1:step in mm, got {text!r}") from None
    if len(mm) not in (1, 3):
        raise ConfigError(f"--grid-mm: expected STEP or x0:x1:step in mm, got {text!r}")
    # judged here, in the option's mm: the grid's own checks speak in metres ('got -0.005' for -5)
    if not all(math.isfinite(v) for v in mm):
        raise ConfigError(f"--grid-mm {text}: expected finite numbers of mm")
    if not mm[-1] > 0:
        raise ConfigError(f"--grid-mm {text}: the step must be > 0 mm, got {mm[-1]:g} mm")
    if len(mm) == 3 and not mm[0] < mm[1]:
        raise ConfigError(f"--grid-mm {text}: expected x0 < x1, got {mm[0]:g} and {mm[1]:g} mm")
    parts = [v * MM for v in mm]
    try:   # the grid's own refusals (not a whole number of steps, ...) are of this option: it is named
        if len(parts) == 1:
            return Grid.from_extent(p_R, parts[0])
        return Grid.regular(parts[0], parts[1], parts[2])
    except ConfigError as e:
        raise ConfigError(f"--grid-mm {text}: {e}") from None


def parse_floats3(text: str, name: str) -> tuple[float, float, float]:
    """``a,b,c``: three finite numbers (an option's value), else a ConfigError naming the option ``name``."""
    from core.exceptions import ConfigError

    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise ConfigError(f"{name} {text!r}: expected three numbers a,b,c, each finite")
    return v


#: Two statements of a probe's offsets J (a log's ``tool_offset_mm`` line, ``--tool-offset-mm``, a machine file's
#: ``[tool] offset_mm``) are the same J when they agree to this on every axis, mm: the float noise of J's trip
#: through metres (a machine file states J in mm, the simulator holds it in m; 12.345 / 1e3 * 1e3 need not give
#: 12.345 back), far below any step a J is written to (a GRBL log's 0.001 mm). Not :data:`core.state.J_SAME_MM`
#: (1 um: whether a state identified with one probe may be applied with another): here both are statements of
#: the one J the readings were logged with, and two values of it are a conflict, refused, never chosen between.
J_EQUAL_MM = 1e-9


def parse_tool_offset(text: str) -> tuple[float, float, float]:
    """``--tool-offset-mm X,Y,Z``: the probe's offsets J, mm (:func:`hardware.campaign.parse_tool_offset`, the one
    parser of the option and of a log's ``tool_offset_mm`` line: every command that takes the option refuses the
    same bad value in the same words)."""
    from hardware.campaign import parse_tool_offset as parse

    return parse(text, "--tool-offset-mm")


def log_tool_offset(log) -> tuple[float, float, float] | None:
    """The J a probe log says its readings were logged with (its ``tool_offset_mm`` line: ``vmt probe`` / ``vmt
    import grbl --tool-offset-mm``), mm; None without the line (the log does not say: a LinuxCNC run, whose
    controller applied J itself, and a simulation have none, so absent is not J = 0 here). A line that is not
    three finite numbers within the length bound: ProbeLogError naming the file."""
    from hardware.campaign import TOOL_OFFSET_KEY, log_tool_offset as said

    return said(log.meta, log.source) if TOOL_OFFSET_KEY in log.meta else None


def same_tool_offset(a, b) -> bool:
    """Whether two J (mm) are the same J (:data:`J_EQUAL_MM`)."""
    return max(abs(float(x) - float(y)) for x, y in zip(a, b)) <= J_EQUAL_MM


#: Where the J a command used came from (its JSON's ``tool_offset.from``): ``vmt identify``: the log's
#: ``tool_offset_mm`` line, that line with ``--tool-offset-mm`` giving the same J, the option alone (the log has no
#: line), neither (J unknown); ``vmt vcmm``: the machine's ``[tool] offset_mm`` (a machine file's, a built-in's
#: shipped file's), with the plan's ``tool_offset_mm`` line saying the same J, or ``assumed``: the machine file
#: gives no ``[tool] offset_mm`` and the plan no line, J is :data:`sim.machinefile.DEFAULT_OFFSET_MM` (the record's
#: ``note`` says so, :func:`sim.machinefile.tool_offset_note`); ``vmt demo``'s identify.json: ``machine`` (the
#: virtual machine's tool).
TOOL_OFFSET_FROM = ("log", "log and option", "option", "none", "machine", "machine and log", "assumed")

#: How a command says where its J came from, one of :data:`TOOL_OFFSET_FROM` (``none`` and ``assumed`` have their
#: own sentences in :func:`tool_offset_said`).
TOOL_OFFSET_FROM_WORDS = {"log": "the log's tool_offset_mm line",
                          "log and option": "the log's tool_offset_mm line and --tool-offset-mm",
                          "option": "--tool-offset-mm (the log has no tool_offset_mm line)",
                          "machine": "the machine's [tool] offset_mm",
                          "machine and log": "the machine's [tool] offset_mm and the plan's tool_offset_mm line"}


def tool_offset_said(J_mm, J_from: str, placed: str, note: str | None = None) -> str:
    """The one line that says which probe offsets J a command used and where they came from, in the words of
    ``vmt identify``'s (``probe offsets J = (x, y, z) mm, from ...: <placed> at the axis positions reading + J``).

    ``J_mm`` (3,) mm or None (unknown: ``J_from`` ``"none"``); ``J_from`` one of :data:`TOOL_OFFSET_FROM`;
    ``placed`` what sits at the axis positions (``"the tables"``, ``"the runs"``); ``note`` for ``"assumed"``:
    :func:`sim.machinefile.tool_offset_note`'s line."""
    if J_from not in TOOL_OFFSET_FROM:
        raise ValueError(f"tool_offset_said: J_from {J_from!r} is not one of {', '.join(TOOL_OFFSET_FROM)}")
    if J_mm is None:
        return (f"probe offsets J unknown (no tool_offset_mm line in the log, no --tool-offset-mm): {placed} at the "
                "readings, the state's probe_offsets_J_mm null")
    J = f"({', '.join(f'{v:g}' for v in J_mm)}) mm"
    if J_from == "assumed":
        return f"probe offsets J = {J}, {note or 'tool offset not given: J = ' + J + ' assumed'}: {placed} at the " \
               "axis positions reading + J"
    return f"probe offsets J = {J}, from {TOOL_OFFSET_FROM_WORDS[J_from]}: {placed} at the axis positions reading + J"


def tool_offset_of_log(log, given: str | None) -> tuple[tuple[float, float, float] | None, str]:
    """``(J mm or None, where from)`` for a command that reads the probe log ``log`` with ``--tool-offset-mm``
    ``given`` (text or None; parse it first, :func:`parse_tool_offset`, to refuse a bad value before any work).

    The log is the record of what was done: its ``tool_offset_mm`` line is the J its readings were logged with,
    taken without the option; the option may repeat it (the same J, :data:`J_EQUAL_MM`) and is refused, one line
    naming both values, when it says another (ConfigError). Without the line the option's J is taken; without
    either J is unknown (None, ``"none"``). ``where from``: one of :data:`TOOL_OFFSET_FROM`."""
    from core.exceptions import ConfigError
    from hardware.campaign import tool_offset_text

    J_opt = None if given is None else parse_tool_offset(given)
    J_log = log_tool_offset(log)
    if J_log is None:
        return (J_opt, "none") if J_opt is None else (J_opt, "option")
    if J_opt is None:
        return J_log, "log"
    if not same_tool_offset(J_log, J_opt):
        raise ConfigError(f"--tool-offset-mm {tool_offset_text(J_opt)}: {log.source}'s tool_offset_mm line says "
                          f"its readings were logged with J = {tool_offset_text(J_log)} mm; one log holds one J: "
                          "give the log's, or leave the option out (the log's is taken)")
    return J_log, "log and option"


def tool_offset_record(J, source: str, note: str | None = None) -> dict:
    """The JSON record of the J a command used: ``{"J_mm": [x, y, z] or null, "from": source}``, and ``"note"``
    where ``note`` is given (``from`` ``assumed``: :func:`sim.machinefile.tool_offset_note`'s line)."""
    rec = {"J_mm": None if J is None else [float(v) + 0.0 for v in J], "from": source}
    if note is not None:
        rec["note"] = note
    return rec


GRID_HELP = ("error-map grid, mm: STEP (nodes at multiples of it covering the touches) or x0:x1:step (both axes; "
             "write --grid-mm=-110:110:22 when x0 < 0)")


def add_noise_arg(p, default_text: str, *, old: tuple[str, ...] = (), default=None) -> None:
    """``--noise-um``: the probing noise, a standard deviation (k=1) along the approach, um (every command)."""
    option(p, "--noise-um", type=float, default=default, dest="noise_um", old=old,
           help=f"probing noise, a standard deviation (k=1) along the approach, um ({default_text})")


def add_mc_arg(p, default_text: str) -> None:
    """``--mc N``: the number of Monte Carlo runs (JCGM 101), one meaning in every command that takes it.

    ``default_text`` says the command's default and what 0 does there (``"500; 0: linear propagation only"``).
    """
    from core.uncertainty import MC_MIN_RUNS

    p.add_argument("--mc", type=int, default=None, metavar="N",
                   help=f"Monte Carlo runs (JCGM 101: each run draws every input once and identifies again; the "
                        f"U95 in identify and scenario cross-pocket-uncertainty: 2 x the runs' std (Gaussian errors: "
                        f"probing noise through a linear estimator); in scenario mfb-*: the half-width of the runs' "
                        f"2.5-97.5 %% interval), at "
                        f"least {MC_MIN_RUNS} ({default_text})")


def check_mc(n: int, *, zero: str | None = None) -> int:
    """The one refusal of ``--mc``: ``n`` below :data:`core.uncertainty.MC_MIN_RUNS` (0 only where the command
    gives it a meaning, ``zero``: what 0 does there) -> a ConfigError naming ``--mc``, in one line."""
    from core.exceptions import ConfigError
    from core.uncertainty import MC_MIN_RUNS

    if n >= MC_MIN_RUNS or (zero is not None and n == 0):
        return n
    alt = f", or --mc 0 ({zero})" if zero is not None else ""
    raise ConfigError(f"--mc {n}: a Monte Carlo needs at least {MC_MIN_RUNS} runs (its U95 is read from the "
                      f"runs' spread: their 2.5 % and 97.5 % percentiles, or 2 std in identify){alt}")


#: What ``--stylus-r-mm`` is, in every command that takes it (the same words as probe-log/1's ``stylus_r_mm``).
STYLUS_R_HELP = "stylus tip radius, mm (0: a pin or a tool as the probe)"


def add_stylus_r_arg(p, when: str, *, required: bool = False) -> None:
    """``--stylus-r-mm``: the stylus tip radius, mm, in every command that needs one.

    It has no default: a radius left out is never taken for 0 (a fit is then wrong by the radius, a plan's
    nominals and its approach clearance too); ``when`` says when the command needs it, and
    :func:`no_stylus_r` is the one refusal when it is needed and not known.
    """
    a = p.add_argument("--stylus-r-mm", type=float, default=None, help=f"{STYLUS_R_HELP}; {when}")
    if required:    # refused by the command in its own words (no_stylus_r); the usage shows it required
        p.vmt_shown_required = (*getattr(p, "vmt_shown_required", ()), a)


def no_stylus_r(what: str):
    """The one refusal of every command that needs a stylus radius and has none: a ConfigError naming the option."""
    from core.exceptions import ConfigError

    return ConfigError(f"{what}: give --stylus-r-mm R, the stylus tip radius in mm "
                       "(--stylus-r-mm 0 for a pin or a tool as the probe)")


def refuse_seed_without_noise(seed: int | None, noise_um: float | None, default_um: float, default_why: str) -> None:
    """``--seed`` where it seeds the probing noise only (``simulate ARTEFACT``, ``machine serve``):
    given where there is no noise it would change nothing, so it is refused in one line, not ignored.

    ``noise_um`` is the ``--noise-um`` given (None: not given), ``default_um`` the noise without it
    and ``default_why`` why that one is zero (``"a built-in machine is served noise-free"``).
    """
    from core.exceptions import ConfigError

    noise = default_um if noise_um is None else noise_um
    if seed is not None and not noise > 0:
        why = default_why if noise_um is None else f"--noise-um {noise_um:g}"
        raise ConfigError(f"--seed {seed}: it seeds the probing noise, and there is none ({why}); "
                          "give --noise-um above 0, or leave --seed out")


#: What each error set ``--errors`` names is (:func:`sim.machinefile.truth_machine`), for the help texts.
ERRORS_HELP = ("realistic: the papers' magnitudes with the screw ripple; study: the same without the ripple; "
               "drawn: a ripple-free set drawn with seed 1; none: the file as shipped")


def add_machine_args(p, *, default: str | None, what: str, errors: bool = True, required: bool = False,
                     errors_default: str = "realistic", errors_why: str = "") -> None:
    """``--machine NAME|FILE`` (and ``--errors``): the same machine and error set in every command.

    ``default``: the built-in name used when ``--machine`` is omitted (None: the command needs none).
    ``errors_default``: the error set of a built-in machine when ``--errors`` is omitted; ``--errors``
    means the same in every command (the error set of the machine the command runs on), only its
    default follows the command's meaning, said in words by ``errors_why``.
    """
    from sim.machinefile import ERROR_SETS

    d = f" (default {default})" if default else ""
    p.add_argument("--machine", default=None, metavar="NAME|FILE", required=required,
                   help=f"{what}: a built-in machine name or a machine file (TOML, README 'Your own machine'){d}")
    if errors:
        why = f": {errors_why}" if errors_why else ""
        p.add_argument("--errors", choices=ERROR_SETS, default=None,
                       help=f"the error set of a built-in machine (default {errors_default}{why}); "
                            f"{ERRORS_HELP}; a machine file states its own")
        p.set_defaults(errors_default=errors_default)


def add_settings_args(p, *, live: bool = True) -> None:
    """The probing settings shared by ``vmt probe`` and ``vmt machine program``."""
    p.add_argument("--plan", required=True, help="probe-log/1 plan (measured columns empty)")
    option(p, "--limits-mm", dest="limits", old=("--limits",),
           help="soft limits, machine frame, mm: X-10:300,Y0:200,Z-100:0 (required before any motion)")
    option(p, "--feed-mm-min", dest="feed", type=float, default=100.0, old=("--feed",),
           help="probing feed, mm/min (100)")
    option(p, "--move-feed-mm-min", dest="move_feed", type=float, default=1000.0, old=("--move-feed",),
           help="positioning feed, mm/min (1000)")
    option(p, "--max-feed-mm-min", dest="max_feed", type=float, default=2000.0, old=("--max-feed",),
           help="no feed above this, mm/min (2000)")
    option(p, "--clearance-mm", dest="clearance", type=float, default=2.0, old=("--clearance",),
           help="approach start before contact, mm (2)")
    option(p, "--overtravel-mm", dest="overtravel", type=float, default=2.0, old=("--overtravel",),
           help="probing end beyond contact, mm (2)")
    option(p, "--safe-z-mm", dest="safe_z", type=float, old=("--safe-z",),
           help="travel between touches at this machine Z, mm")
    if live:
        p.add_argument("--allow-miss", action="store_true",
                       help="probe with G38.3: a miss is logged no_trigger and the campaign goes on")


def settings_from_args(args):
    """The :class:`hardware.campaign.ProbeSettings` of the options :func:`add_settings_args` added."""
    from core.exceptions import ConfigError
    from hardware.campaign import ProbeSettings, parse_limits

    limits = parse_limits(args.limits) if args.limits else None
    try:
        return ProbeSettings(
            probe_feed_mm_min=args.feed, move_feed_mm_min=args.move_feed,
            max_feed_mm_min=args.max_feed, clearance_mm=args.clearance,
            overtravel_mm=args.overtravel, safe_z_mm=args.safe_z,
            allow_miss=bool(getattr(args, "allow_miss", False)), limits_mm=limits)
    except ConfigError as e:     # named by the option ('--feed-mm-min 0 ...', not 'probe_feed_mm_min 0.0 ...')
        said = str(e)
        for field, flag in SETTINGS_OPTIONS.items():
            if said.startswith(f"{field} "):
                said = f"{flag} {said[len(field) + 1:]}"
        raise ConfigError(said) from None


#: ProbeSettings' fields and the options that set them (:func:`add_settings_args`).
SETTINGS_OPTIONS = {"probe_feed_mm_min": "--feed-mm-min", "move_feed_mm_min": "--move-feed-mm-min",
                    "max_feed_mm_min": "--max-feed-mm-min", "clearance_mm": "--clearance-mm",
                    "overtravel_mm": "--overtravel-mm", "safe_z_mm": "--safe-z-mm"}


def _ripple_symbols(angular: bool) -> tuple:
    """The motion errors ``--declared-ripple-um-mm`` (length: positioning, straightness) or
    ``--declared-ripple-urad-mm`` (angular) takes."""
    from core import iso, volumetric as vol

    return tuple(s for s in vol.MOTION if iso.symbol(s).angular == angular)


def add_declared_ripple_args(p, um_help: str, urad_help: str) -> None:
    """The two options ``--declared-ripple-um-mm`` (dest ``declared_ripple``) and
    ``--declared-ripple-urad-mm`` (``declared_ripple_urad``) on parser ``p``, with each command's help;
    :func:`declared_ripples` reads them. ``vmt scenario`` and ``vmt identify`` define them here, once (shared
    options live here: a command module is a leaf, CONTRIBUTING.md)."""
    p.add_argument("--declared-ripple-um-mm", default=None, metavar="SYM=UM:MM,...", dest="declared_ripple",
                   help=um_help)
    p.add_argument("--declared-ripple-urad-mm", default=None, metavar="SYM=URAD:MM,...", dest="declared_ripple_urad",
                   help=urad_help)


def declared_ripples(args) -> dict:
    """``--declared-ripple-um-mm`` and ``--declared-ripple-urad-mm`` (either may be absent) read together ->
    ``{symbol: (m or rad, m)}`` (:func:`parse_declared_ripple`: a ConfigError names the option and the bad item,
    an empty value included). ``vmt scenario`` and ``vmt identify`` read them through this one function."""
    out = {}
    for text, unit in ((args.declared_ripple, "um"), (args.declared_ripple_urad, "urad")):
        if text is not None:
            out.update(parse_declared_ripple(text, unit))
    return out


def parse_declared_ripple(text: str, unit: str = "um") -> dict:
    """``EXX=0.4:10,EYY=0.2:10`` (amplitude in ``unit``, um or urad : period mm per motion error of that unit)
    -> ``{symbol: (m or rad, m)}``, or ConfigError naming the bad item."""
    import math

    from core.exceptions import ConfigError

    opt = f"--declared-ripple-{unit}-mm"
    known = _ripple_symbols(unit == "urad")
    out = {}
    for item in (t.strip() for t in text.split(",")):
        sym, _, val = item.partition("=")
        sym = sym.strip().upper()
        amp, _, per = val.partition(":")
        try:
            a, p = float(amp), float(per)
        except ValueError:
            a = p = math.nan
        if sym not in known or not (math.isfinite(a) and math.isfinite(p) and a >= 0 and p > 0):
            raise ConfigError(f"{opt}: {item!r} is not SYMBOL=AMPLITUDE_{unit.upper()}:PERIOD_MM with SYMBOL one of "
                              f"{', '.join(known)}, amplitude >= 0, period > 0 (e.g. "
                              f"{'EXX=0.4:10,EYY=0.2:10' if unit == 'um' else 'EBX=1:10'})")
        if sym in out:
            raise ConfigError(f"{opt}: {sym} declared twice")
        out[sym] = (a * 1e-6, p * 1e-3)
    return out


def add_bar_calibration_arg(p) -> None:
    """``--bar-calibration FILE`` on ``vmt identify`` and ``vmt discover``: a multi-feature bar's certificate
    (``vmt-bar-calibration/1``) for an MFB log (one meaning in every command: the bar's calibration to identify
    with; ``vmt scenario mfb-*`` defines its own, the same file)."""
    p.add_argument("--bar-calibration", default=None, metavar="FILE", dest="bar_calibration",
                   help="an MFB log (artefact: mfb): the bar's calibration to identify with (vmt-bar-calibration/1 "
                        "JSON, as 'vmt scenario mfb-reversal --json FILE' writes it) instead of the log's own "
                        "bar_calibration_E_um / bar_calibration_u_um lines; not for other logs")
