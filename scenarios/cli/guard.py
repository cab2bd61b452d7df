"""What every ``vmt`` command promises, kept in one place.

:func:`run_command` runs a parsed command so that

- bad input (:class:`core.exceptions.VmtError`) and operating-system errors
  (permission denied, no space left, a folder where a file should be, ...)
  end as ONE line on stderr, ``vmt COMMAND: error: WHAT``, exit status 2;
- the inputs are checked before any work (exist, are files, can be read),
  and so are the outputs (not an input of the same run, not a folder, link,
  device or socket where a file goes, in a folder that can be written), so a
  ten-minute run never ends in "cannot write";
- a run that fails leaves no output behind: what it wrote at its outputs
  (files, report folders, hidden temporaries) is removed, and an earlier
  output it replaced is put back (:class:`core.atomic.RunOutputs`); the
  append-only log of ``vmt probe`` is kept, it is what ``--resume`` continues;
- a closed pipe (``vmt check log.csv | head -2``) ends quietly, status 141
  like any program killed by SIGPIPE; Ctrl-C ends with one line, status 130, and SIGTERM (timeout(1), a CI
  cancel, systemd) the same way, status 143: the outputs put back as on any failure (session 32);
- an output named ``/dev/stdout`` is written on standard output itself (never
  replaced) and the command's own messages then go to stderr; an output file
  named ``-`` is the same (:data:`DASH_OWN`: ``check --json -`` prints its JSON
  instead of its text), but where a command appends to a file or rewrites it
  in place (:data:`NO_DASH`: ``probe --out``, ``probe --transcript``, ``bench
  --readme``) and for a folder (``--report -``), which refuse it.

Which argument of which command is an input or an output is the table
:data:`FILES`; a command missing there gets only the error handling.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import os
import re
import signal
import sys
import tempfile
import textwrap
from pathlib import Path

#: command -> (input files, output files, output folders), as ``args`` attribute names.
#: ``vmt probe --out`` is absent on purpose: an append-only log, continued by --resume.
FILES = {
    "check": (("log",), ("json",), ()),
    "identify": (("log",), ("json",), ()),
    "discover": (("log",), ("json_out",), ("report",)),
    "design": (("plan",), ("json",), ()),
    "import": (("file", "plan"), ("out",), ()),
    "simulate": ((), ("out",), ()),
    "scenario": ((), ("json",), ("comp", "report")),
    "demo": ((), (), ("out_dir",)),
    "bench": ((), ("out",), ()),
    "probe": (("plan",), (), ()),
    "machine": (("plan",), ("out",), ()),
    "view": (("rrd",), (), ()),
    "plan": ((), ("out",), ()),
    "fit": (("log",), ("json",), ()),
    "iso230-2": (("log", "add_to"), ("json", "write_log", "comp_file"), ("report",)),
    "regress": (("study",), ("json", "junit"), ()),
    "vcmm": (("plan", "task"), ("json",), ("report",)),
}

#: command -> arguments that name an input file only sometimes (``--machine NAME|FILE``: a built-in
#: name or a machine file), or that the command reads and checks itself (``--bar-calibration``,
#: ``--machine-state``): not checked before the run, but an output on the same existing file is
#: refused like an output on an input of :data:`FILES`.
OTHER_INPUTS = {
    "simulate": ("machine",),
    "scenario": ("machine", "bar_calibration"),
    "machine": ("machine",),
    "vcmm": ("machine", "machine_state"),
}

#: commands that read ``-`` as an output themselves (``check --json -``: the JSON instead of the
#: text); in every other command an output file ``-`` is standard output, as ``/dev/stdout``.
DASH_OWN = ("check",)

#: command -> {option: why it cannot be ``-``}: files a command appends to or rewrites in place, never
#: standard output (a folder option refuses ``-`` in every command: :func:`map_dash`).
NO_DASH = {
    "probe": {"out": "the campaign log is appended to, locked and continued by --resume, so it must be a file",
              "transcript": "the transcript is appended to a file; give a file"},
    "bench": {"readme": "the file is read and its table rewritten in place; give a file"},
}

#: Exit status of a command killed by SIGPIPE (128 + 13), as a shell reports it.
EXIT_PIPE = 141


class _WholeNames:
    """Help text wrapped at spaces only, never inside a word at its hyphens (textwrap's default, which
    argparse keeps): ``write --comp-range-deg=-400:800`` came out as ``--comp-range-`` / ``deg=-400:800``
    on two lines, an option name a reader copying it got wrong (cmds36). A word longer than the line is
    still cut, as before."""

    def _split_lines(self, text, width):
        return textwrap.wrap(self._whitespace_matcher.sub(" ", text).strip(), width, break_on_hyphens=False)

    def _fill_text(self, text, width, indent):
        if isinstance(self, argparse.RawDescriptionHelpFormatter):     # kept as written
            return super()._fill_text(text, width, indent)
        return textwrap.fill(self._whitespace_matcher.sub(" ", text).strip(), width, initial_indent=indent,
                             subsequent_indent=indent, break_on_hyphens=False)


@functools.cache
def _whole_names(formatter_class: type) -> type:
    """``formatter_class`` with :class:`_WholeNames`' wrapping (one class per formatter class)."""
    return type(f"WholeNames{formatter_class.__name__}", (_WholeNames, formatter_class), {})


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line, ``vmt CMD: error: ...``, exit 2.

    Options are never abbreviated (``allow_abbrev=False``, every command's
    parser is this class): an old option name kept as a hidden alias would
    otherwise make a prefix ambiguous, and a prefix could change meaning
    when an option is added. Help text never breaks a line inside an option
    name (:class:`_WholeNames`).
    """

    def __init__(self, *args, **kw):
        kw.setdefault("allow_abbrev", False)
        kw["formatter_class"] = _whole_names(kw.get("formatter_class", argparse.HelpFormatter))
        super().__init__(*args, **kw)

    def add_argument(self, *args, **kw):  # noqa: D102
        # an option of options.PLACEHOLDERS shows its one placeholder in every command (unless given its own:
        # the walk in tests/scenarios/test_cli_options.py refuses a second one)
        from scenarios.cli.options import PLACEHOLDERS

        if args and args[0] in PLACEHOLDERS and "metavar" not in kw and kw.get("action") in (None, "store"):
            kw["metavar"] = PLACEHOLDERS[args[0]]
        return super().add_argument(*args, **kw)

    def error(self, message):  # noqa: D102 - argparse's hook
        m = re.fullmatch(r"argument (--[\w-]+)(?:/[^:]*)?: expected one argument", message)
        if m:   # argparse takes a value such as -110:110 for an option: '--travel-mm -100:100' lands here
            message += f" (a value that starts with '-' is written {m[1]}=VALUE, e.g. {m[1]}=-100:100)"
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    @contextlib.contextmanager
    def _shown_required(self):
        """Options the command requires and refuses itself, in its own words (``vmt_shown_required``:
        ``plan grid --stylus-r-mm``), shown in the usage without brackets as argparse shows a required one."""
        acts = getattr(self, "vmt_shown_required", ())
        for a in acts:
            a.required = True
        try:
            yield
        finally:
            for a in acts:
                a.required = False

    def format_usage(self):  # noqa: D102
        with self._shown_required():
            return super().format_usage()

    def format_help(self):  # noqa: D102
        with self._shown_required():
            return super().format_help()

    def parse_args(self, args=None, namespace=None):  # noqa: D102
        # an unknown option is named by the command that was given it (``vmt probe: error: ...
        # (see vmt probe --help)``), not by ``vmt``, whose help does not list that command's options
        ns, rest = self.parse_known_args(args, namespace)
        if rest:
            self._command_parser(ns).error(f"unrecognized arguments: {' '.join(rest)}")
        return ns

    def _command_parser(self, ns) -> argparse.ArgumentParser:
        """The innermost sub-command's parser that ``ns`` was parsed by (``vmt machine serve``)."""
        parser = self
        while True:
            subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
            chosen = getattr(ns, subs[0].dest, None) if subs else None
            if chosen not in (subs[0].choices if subs else {}):
                return parser
            parser = subs[0].choices[chosen]

    def parse_known_args(self, args=None, namespace=None):  # noqa: D102
        # a required option with an old name (scenarios.cli.options.option) is required here, not by
        # argparse: either name satisfies it
        ns, rest = super().parse_known_args(args, namespace)
        # an old positional spelling of an option (scenarios.cli.options.add_plan_arg): moved over, said once
        for old, dest, shown, new in getattr(self, "vmt_positional_renamed", ()):
            v = getattr(ns, old, None)
            if v is None:
                continue
            if getattr(ns, dest, None) is not None:
                self.error(f"{shown} given twice: as {new} and as an argument (the old spelling); give {new} only")
            print(f"vmt: {shown} as a positional argument is renamed to {new} {shown} (the old spelling works for "
                  "now; use the new one)", file=sys.stderr, flush=True)
            setattr(ns, dest, v)
            setattr(ns, old, None)
        missing = [name for dest, name in getattr(self, "vmt_required", ()) if getattr(ns, dest, None) is None]
        if missing:
            self.error(f"the following arguments are required: {', '.join(missing)}")
        return ns, rest


def _arg_paths(args, names) -> dict:
    """``{--option: path}`` of the arguments ``names`` that hold a path (skip flags and unset ones)."""
    out = {}
    for name in names:
        v = getattr(args, name, None)
        if isinstance(v, (str, os.PathLike)) and str(v) not in ("", "-") and not str(v).startswith("\0"):
            out[name] = str(v)
    return out


def _opt(name: str, command: str | None = None) -> str:
    """How the command line names the argument ``name`` (an ``args`` attribute) of ``command``."""
    return {"json_out": "--json", "log": "LOG", "plan": "--plan", "file": "FILE", "rrd": "RRD",
            "c_angles": "--c-angles-deg", "study": "STUDY"}.get(name, "--" + name.replace("_", "-"))


def map_dash(args, outs, dirs) -> None:
    """An output file ``-`` becomes ``/dev/stdout`` (but in :data:`DASH_OWN`); refuse ``-`` where it
    cannot be standard output: a folder option, or an option of :data:`NO_DASH`."""
    from core.exceptions import ConfigError

    for name, why in NO_DASH.get(args.command, {}).items():
        if getattr(args, name, None) == "-":
            raise ConfigError(f"{_opt(name, args.command)} -: '-' (standard output) cannot be it: {why}")
    for name in dirs:
        if getattr(args, name, None) == "-":
            raise ConfigError(f"{_opt(name, args.command)} -: names a folder, and '-' (standard output) is "
                              "for an output file; give a folder")
    if args.command not in DASH_OWN:
        for out in outs:
            if getattr(args, out, None) == "-":
                setattr(args, out, "/dev/stdout")


def check_input(path: str) -> None:
    """A readable file (or pipe) at ``path``, else :class:`~core.exceptions.VmtError` naming it."""
    from core.atomic import input_problem
    from core.exceptions import VmtError

    problem = input_problem(path)
    if problem:
        raise VmtError(f"{path}: {problem}")


def _writable_folder(path: Path, *, folder: bool = False) -> None:
    """The nearest existing folder on the way to ``path`` (a file, or a ``folder``) must take a new file."""
    from core.exceptions import OutputError

    q = path if folder else path.parent
    while not q.exists() and q != q.parent:
        q = q.parent
    if not q.is_dir():
        raise OutputError(f"{path}: cannot write there: {q} is not a folder")
    try:
        with tempfile.TemporaryFile(dir=q, prefix=f".{path.name}.probe."):
            pass
    except OSError as e:
        raise OutputError(f"{path}: cannot write in {q}: {e.strerror}") from None


def check_outputs(inputs: dict, files: dict, folders: dict, command: str | None = None) -> None:
    """Refuse outputs that would overwrite an input, or that cannot be written as files/folders
    (``command`` names a positional argument as its usage does)."""
    from core.atomic import check_output, output_kind, same_file
    from core.exceptions import OutputError

    for oname, out in {**files, **folders}.items():
        for iname, inp in inputs.items():
            if os.path.exists(out) and same_file(out, inp):
                raise OutputError(f"{_opt(oname, command)} {out} is the input {_opt(iname, command)} {inp}: "
                                  "refusing to overwrite an input; choose another output")
    for other, out in files.items():
        for oname2, out2 in {**files, **folders}.items():
            if oname2 != other and os.path.abspath(out) == os.path.abspath(out2):
                raise OutputError(f"{_opt(other, command)} and {_opt(oname2, command)} are the same path {out}")
    for name, out in files.items():
        if check_output(out, special=True) == "replace":
            _writable_folder(Path(out))
    for name, out in folders.items():
        kind = output_kind(out)
        if kind not in ("missing", "directory", "symbolic link"):
            raise OutputError(f"{_opt(name, command)} {out}: is a {kind}, not a folder")
        if kind != "missing" and not os.path.isdir(out):
            raise OutputError(f"{_opt(name, command)} {out}: is not a folder")
        _writable_folder(Path(out), folder=True)


def folders_to_make(files: dict, folders: dict, command: str | None = None) -> list[tuple[Path, str]]:
    """(the folder an output goes in, the option and output) for each output whose folder does not
    exist yet: :func:`make_folders` makes it before the run, with the folders above it that are
    missing too. An output folder itself (``--report DIR``) is not counted: the command names it
    when it says what it wrote; the folder it goes in is."""
    made = []
    for name, out in {**files, **folders}.items():
        q = Path(out).parent
        if str(q) not in ("", ".") and not os.path.lexists(q) and all(q != f for f, _ in made):
            made.append((q, f"{_opt(name, command)} {out}"))
    return made


def make_folders(made: list[tuple[Path, str]]) -> None:
    """Make the folders of :func:`folders_to_make`, before the run: the one place a command's output
    folders are made, so every writer finds its folder (a report writer that made its own parent and
    one that did not: ``scenario pin-circle --report new/rep`` failed after its work, session 26).
    :class:`core.atomic.RunOutputs`, made before, takes them back if the run fails."""
    for q, _ in made:
        q.mkdir(parents=True, exist_ok=True)


def say_made(made: list[tuple[Path, str]]) -> None:
    """One line naming the folders a run made on the way to its outputs (:func:`folders_to_make`)
    that exist now: the user learns where the outputs went, not only that they were written."""
    now = [(f, why) for f, why in made if f.is_dir()]
    if now:
        s = "s" if len(now) > 1 else ""
        print(f"made the folder{s} " + "; ".join(f"{f} (for {why})" for f, why in now))


def _inside(path: str, folder: str) -> bool:
    """``path`` (links resolved) is ``folder`` or lies in it."""
    p, f = os.path.realpath(path), os.path.realpath(folder)
    return p == f or p.startswith(f.rstrip(os.sep) + os.sep)


def check_report_folder(report: str, inputs: dict, outputs: dict, command: str | None = None) -> None:
    """A report replaces its folder whole (:func:`viz.report.write_report`): refuse, before the run,
    a folder that is no earlier report of vmt or holds anything else (:func:`viz.report.replace_problem`),
    and an input or another output lying in it (it would be lost with the folder, or written and then
    swept away)."""
    from core.exceptions import OutputError
    from viz.report import replace_problem

    for kind, paths in (("the input", inputs), ("the output", outputs)):
        for name, path in paths.items():
            if name != "report" and _inside(path, report):
                raise OutputError(f"{_opt(name, command)} {path} lies in --report {report}, a folder the report "
                                  f"replaces whole: {kind} would be lost; put it elsewhere")
    problem = replace_problem(report)
    if problem:
        raise OutputError(f"--report {report}: {problem}")


#: The largest ``--delta-l-um`` taken, um: the X positioning error at the last node of a grid of a few hundred
#: mm is microns to tens of microns; 1 mm (thousands of ppm) is no machine's, and the linear model of the
#: self-calibration (small errors) would not hold (review26: 1e30 was taken and identified).
DELTA_L_MAX_UM = 1000.0


#: Options that mean the same in every command that has them (``args`` name: test, rule).
COMMON = {
    "seed": (lambda v: v >= 0, "must be >= 0"),
    # --mc: not here; its one refusal is scenarios.cli.options.check_mc (what 0 means is the command's)
    "noise_um": (lambda v: v >= 0 and v < float("inf"), "must be a finite number >= 0"),
    "dt": (lambda v: 0 < v < float("inf"), "must be a positive number of seconds"),
    "step_deg": (lambda v: 0 < v <= 360, "must be > 0 and divide 360"),
    "angles": (lambda v: v >= 2, "must be >= 2"),
    "workers": (lambda v: v >= 1, "must be >= 1"),
    "delta_l_um": (lambda v: abs(v) <= DELTA_L_MAX_UM,
                   f"must be within +-{DELTA_L_MAX_UM:g} um (the X positioning error at the last x node)"),
    "ec0y_urad": (lambda v: abs(v) < float("inf"), "must be a finite number"),  # (an infinite squareness was served)
    "z_mm": (lambda v: abs(v) < float("inf"), "must be a finite number"),
    "stylus_r_mm": (lambda v: 0 <= v < float("inf"), "must be a finite number >= 0"),
    "drift_tau_s": (lambda v: 0 < v < float("inf"), "must be a finite number > 0"),
    "time_scale": (lambda v: 0 < v < float("inf"), "must be a finite number > 0"),  # ('time scale nan: ...')
    "timeout": (lambda v: 0 < v < float("inf"), "must be a finite number > 0"),  # (was checked after the plan's)
}


#: The option names of :data:`COMMON`'s entries whose ``args`` name is not the option's.
FLAGS = {"dt": "--dt-s", "angles": "--n-angles", "timeout": "--timeout-s"}


#: ``--noise-um`` where it is the sigma a U95 is computed from (``identify``, ``design``): 0 has no meaning
#: there, and -1 and 0 are refused in the same words (``p.set_defaults(vmt_rules=NOISE_POSITIVE)``).
NOISE_POSITIVE = {"noise_um": (lambda v: 0 < v < float("inf"), "must be a finite number > 0")}


#: Options that name something and where an empty value (``--out ""``, ``--machine ""``) would fall back to a
#: default or say "'.': is a directory": refused naming the empty value (review26). ``args`` name -> what to give.
NONEMPTY = {"machine": "a built-in machine name or a machine file (or leave --machine out)",
            "c_angles": "comma-separated C angles in degrees (or leave --c-angles-deg out)",
            "machine_state": "an identification result (JSON)", "bar_calibration": "a bar calibration (JSON)",
            "transcript": "a file name", "readme": "a file name"}


def check_empty_values(args) -> None:
    """Refuse an empty value of an option that names a file, a folder, a machine or a list (one line)."""
    from core.exceptions import ConfigError

    ins, outs, dirs = FILES.get(args.command, ((), (), ()))
    what = {**{n: "a file" for n in ins}, **{n: "a file name" for n in outs}, **{n: "a folder name" for n in dirs},
            **NONEMPTY}
    for name, give in what.items():
        v = getattr(args, name, None)
        if isinstance(v, str) and not v.strip():
            raise ConfigError(f"{_opt(name, args.command)} {v!r}: empty; give {give}")


def check_common_options(args) -> None:
    """Refuse a value of a shared option outside its meaning (NaN fails every test); a command's
    ``vmt_rules`` default (same shape as :data:`COMMON`) narrows an entry for it, in the same phrasing."""
    from core.exceptions import ConfigError

    own = getattr(args, "vmt_rules", None) or {}
    for name, (ok, rule) in {**COMMON, **own}.items():
        v = getattr(args, name, None)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and not ok(v):
            raise ConfigError(f"{FLAGS.get(name, '--' + name.replace('_', '-'))} {rule}, got {v:g}")


@contextlib.contextmanager
def about_file(path, detail: str = ""):
    """Errors of the work done on the input ``path`` inside this block name the file.

    The library's estimators speak of their data (``sphere fit: points are coplanar``, ``rank
    deficient by 31``), not of the file it came from; a :class:`~core.exceptions.VmtError` whose
    message does not already name ``path`` is raised again, the same class, as ``PATH: message``
    (``PATH (detail): message`` when ``detail`` says which part of it, e.g. ``--feature sphere1``).
    A message that starts with an option (``--wcs 'G99': expected ...``) is of that option, not of
    the file: it is left as it is.
    """
    from core.exceptions import VmtError

    try:
        yield
    except VmtError as e:
        msg = str(e)
        if str(path) in msg or msg.startswith("--"):
            raise
        head = f"{path} ({detail})" if detail else str(path)
        try:
            again = type(e)(f"{head}: {msg}")
        except TypeError:       # a subclass with another constructor: the root class says it as well
            again = VmtError(f"{head}: {msg}")
        raise again from None


def os_error_line(e: OSError) -> str:
    """WHICH PATH: WHY (one line) for an operating-system error."""
    why = e.strerror or str(e) or type(e).__name__
    if e.filename is not None and e.filename2 is not None:
        return f"{e.filename} -> {e.filename2}: {why}"
    if e.filename is not None:
        return f"{e.filename}: {why}"
    return why


def _quiet_stdout() -> None:
    """After a closed pipe: point stdout at /dev/null so the exit flush stays silent."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):  # pragma: no cover - stdout without a descriptor
        pass


def run_command(args) -> int:
    """Run ``args.func(args)`` keeping the promises of this module; return the exit status."""
    name = " ".join([args.command] + [str(v) for k, v in sorted(vars(args).items())
                                      if k.endswith("_command") and isinstance(v, str)])
    ins, outs, dirs = FILES.get(args.command, ((), (), ()))
    with terminating_as_interrupt():  # SIGTERM as Ctrl-C in every command (review32d F6), not in vmt probe alone
        return _run_command(args, name, ins, outs, dirs)


def _run_command(args, name, ins, outs, dirs) -> int:
    from core.atomic import RunOutputs, own_descriptor
    from core.exceptions import VmtError

    outputs = None
    try:
        try:
            check_common_options(args)
            check_empty_values(args)
            map_dash(args, outs, dirs)
            inputs = _arg_paths(args, ins)
            for path in inputs.values():
                check_input(path)
            files, folders = _arg_paths(args, outs), _arg_paths(args, dirs)
            others = {k: v for k, v in _arg_paths(args, OTHER_INPUTS.get(args.command, ())).items()
                      if os.path.isfile(v)}
            check_outputs({**inputs, **others}, files, folders, args.command)
            report = folders.get("report")
            if report:
                check_report_folder(report, {**inputs, **others}, {**files, **folders}, args.command)
            made = folders_to_make(files, folders, args.command)
            outputs = RunOutputs(list(files.values()) + list(folders.values()))
            make_folders(made)
            # an output on our own stdout (--out /dev/stdout): the command's messages go to stderr
            said_to = sys.stderr if any(own_descriptor(p) == 1 for p in files.values()) else None
            with contextlib.redirect_stdout(said_to) if said_to else contextlib.nullcontext():
                rc = int(args.func(args) or 0)
                say_made(made)
            sys.stdout.flush()
            outputs.commit()
            return rc
        except BrokenPipeError:
            if outputs is not None:
                outputs.commit()
            raise           # the reader went away: what was written is complete, keep it
        except BaseException:
            if outputs is not None:
                outputs.remove_written()
            raise
    except BrokenPipeError:
        _quiet_stdout()
        return EXIT_PIPE
    except VmtError as e:
        print(f"vmt {name}: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"vmt {name}: error: {os_error_line(e)}", file=sys.stderr)
        return 2
    except MemoryError as e:    # numpy's own words (audit37: `vmt identify --mc 1000000000` was a traceback, exit 1)
        said = str(e).strip() or "an allocation failed"
        print(f"vmt {name}: error: out of memory ({said}); nothing written: a smaller input or option (--mc, "
              f"--grid-mm, the log) needs less", file=sys.stderr)
        return 2
    except KeyboardInterrupt as e:   # its text, when a command gave it one, says what is kept (vmt probe's rows)
        sig = getattr(e, "signum", signal.SIGINT)
        what = "interrupted" if sig == signal.SIGINT else f"terminated ({signal.Signals(sig).name})"
        print(f"vmt {name}: {what}" + (f" {e}" if str(e) else ""), file=sys.stderr)
        return 128 + int(sig)


class Terminated(KeyboardInterrupt):
    """A termination signal (SIGTERM) turned into an interruption by a command that has something to say
    on it (vmt probe: the rows on disk and --resume); :func:`terminating_as_interrupt` raises it."""

    def __init__(self, signum: int, *args):
        super().__init__(*args)
        self.signum = signum


#: True once a SIGTERM has been turned into :class:`Terminated` in this process (:func:`terminating_as_interrupt`).
_TERM_TAKEN = False


@contextlib.contextmanager
def terminating_as_interrupt():
    """Inside the block SIGTERM raises :class:`Terminated`, handled as Ctrl-C is (cleanup, one line, exit
    128 + 15 = 143) instead of ending the process without a word (review30 F7). Outside the main thread
    (where no handler can be set) the block runs unchanged.

    The first SIGTERM only: from then on SIGTERM is ignored, in this block, in the blocks around it and after
    them, until the process exits. GNU timeout(1) sends SIGTERM to the command and then to its process group,
    so one "stop" can arrive twice; a second one raised a fresh :class:`Terminated` (no text) inside the first
    one's cleanup, or, once the block had put the default action back, killed the process before or after its
    line: ``vmt probe`` lost its ``[60 of 368 rows in log.csv; continue with --resume]`` (review35 F1). The
    process has been told to end and is ending; Ctrl-C (SIGINT) and SIGKILL (``timeout -k``) still stop a
    cleanup that hangs. A caller that runs a command in its own process (tests) gets SIGTERM ignored after a
    SIGTERM it received during the command, never otherwise."""
    def raise_it(signum, _frame):
        global _TERM_TAKEN
        if _TERM_TAKEN:                 # a second SIGTERM pending before the first was ignored: drop it
            return
        _TERM_TAKEN = True
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        raise Terminated(signum)

    try:
        before = signal.signal(signal.SIGTERM, signal.SIG_IGN if _TERM_TAKEN else raise_it)
    except ValueError:      # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_IGN if _TERM_TAKEN else before)


def progress_line(label: str, **kw):
    """A :class:`viz.progress.TerminalProgress` (drawn on a terminal only; ``clear()`` before
    the command prints a line, so its line never mixes with the output); ``kw`` its options
    (``counts_seconds``)."""
    from viz.progress import TerminalProgress

    return TerminalProgress(label, **kw)


def said(path) -> str:
    """``path`` as a command names an output it wrote: a device or FIFO says it was written through."""
    try:
        kind = _kind(os.stat(path).st_mode)
    except OSError:
        return str(path)
    return f"{path} (a {kind}: written through, not replaced)" if kind != "file" else str(path)


def _kind(mode: int) -> str:
    from core.atomic import _kind_of_mode

    return _kind_of_mode(mode)
