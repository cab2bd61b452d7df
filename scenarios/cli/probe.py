"""``vmt probe``: run a probing plan on a machine, append-only and resumable.

    vmt probe --controller grbl://HOST:PORT|serial:///dev/ttyX|virtual: --plan PLAN.csv
              --out LOG.csv --limits-mm X0:300,Y0:200,Z-100:0 [--tool-offset-mm X,Y,Z] [--dry-run] [--resume]

Before any motion the program is checked against the soft limits and the
maximum feed; ``--dry-run`` only prints it. Every touch is on disk (fsync)
before the next move; after a lost connection, an alarm or a killed
process, the same command with ``--resume`` continues where the log stops.
"""

from __future__ import annotations

import sys

from scenarios.cli.options import add_settings_args, option, settings_from_args


def register(sub) -> None:
    p = sub.add_parser("probe", help="run a probing plan on a machine (GRBL live or virtual)")
    option(p, "--controller", metavar="URL", required=True, old=("--machine",),
                   help="grbl://HOST:PORT, serial:///dev/ttyX[?baud=115200], virtual: (built-in scene) "
                        "or virtual:cross-pocket (the simulator's nmv3000 and part). GRBL: the plan goes out as G53 "
                        "targets and the log holds the [PRB] machine positions, each + and - the --tool-offset-mm J "
                        "when given (a real machine's machine coordinates are the spindle's, J from the tip; the "
                        "emulator's are the tip's unless served with --tool-offset-mm: docs/formats.md, 'GRBL "
                        "transcript')")
    p.add_argument("--out", required=True, help="campaign log (probe-log/1), append-only")
    add_settings_args(p)
    p.add_argument("--tool-offset-mm", default=None, metavar="X,Y,Z",
                   help="the probe's offsets J, mm (spindle gauge point minus stylus-tip centre, as a machine file's "
                        "[tool] offset_mm and vmt identify --tool-offset-mm), for a GRBL controller whose machine "
                        "coordinates are the spindle's: the plan's tip centres go out as tip + J (--limits-mm and "
                        "--safe-z-mm are then the controller's machine coordinates, the spindle's), each [PRB] report "
                        "is logged less J, and the log records J (tool_offset_mm); a --resume must give the same J. "
                        "Not for virtual: (its positions are the tip centre's)")
    p.add_argument("--dry-run", action="store_true", help="print the program, move nothing")
    p.add_argument("--resume", action="store_true",
                   help="continue the log --out where it stops (refused, nothing moved, when the controller lost the "
                        "log's machine position: then add --home-cycle)")
    p.add_argument("--unlock", action="store_true", help="send $X if the controller is in alarm")
    option(p, "--home-cycle", dest="home", action="store_true", old=("--home",),
           help="send $H (the homing cycle) before probing")
    p.add_argument("--rotary", action="store_true",
                   help="send the controller's rotary axes (plan's A_deg, B_deg, C_deg; only those it has)")
    p.add_argument("--axes", help="the controller's axes, e.g. XYZAC (default: from its reports)")
    p.add_argument("--reset", action="store_true",
                   help="soft-reset the controller (Ctrl-X) first: needed after a hard/soft limit alarm")
    option(p, "--timeout-s", dest="timeout", type=float, default=60.0, old=("--timeout",),
           help="longest wait for one answer, s (60)")
    p.add_argument("--transcript", help="append the raw controller exchange to this file")
    p.set_defaults(func=run)


def _warn(msg: str) -> None:
    print(f"vmt probe: warning: {msg}", file=sys.stderr, flush=True)


def run(args) -> int:
    from scenarios.cli.reading import read_probe
    from hardware.campaign import check_program, plan_steps, plan_turns

    plan = read_probe(args.plan, "probe")
    settings = _with_tool_offset(settings_from_args(args), args)
    _check_resumed_offset(settings, args)
    steps = plan_steps(plan, settings)
    if args.dry_run:
        return _dry_run(steps, settings, args)
    # before connecting, before any motion; the rotary axes as the run will command them (a controller's with
    # --rotary, the in-process virtual machine's wherever the plan turns: hardware.campaign.run_campaign)
    rotary = args.rotary or (args.controller.startswith("virtual") and plan_turns(steps))
    check_program(steps, settings, rotary=rotary)
    _check_before_connecting(steps, args)
    res = _probe(plan, settings, args)
    new = res.rows_done - res.rows_before
    from core.exceptions import counted

    extra = f", cut a torn last line ({counted(res.torn_bytes, 'byte')})" if res.torn_bytes else ""
    st = ", ".join(f"{k}: {v}" for k, v in sorted(res.statuses.items())) or "none"
    print(f"{args.out}: {res.rows_done} of {counted(res.rows_total, 'touch')} "
          f"({new} new, {res.rows_before} before{extra}; the new ones: {st})")
    return 0


def _with_tool_offset(settings, args):
    """``settings`` with ``--tool-offset-mm`` J (checked: three finite numbers, mm; refused on ``virtual:``)."""
    if args.tool_offset_mm is None:
        return settings
    from dataclasses import replace

    from core.exceptions import ConfigError
    from hardware.campaign import parse_tool_offset

    J = parse_tool_offset(args.tool_offset_mm)
    if args.controller.startswith("virtual"):
        raise ConfigError(f"--tool-offset-mm {args.tool_offset_mm}: the in-process virtual machine "
                          f"({args.controller}) moves its stylus-tip centre, it has no spindle J from it; a GRBL "
                          "controller whose machine coordinates are the spindle's takes it (the emulator: vmt "
                          "machine serve --tool-offset-mm)")
    return replace(settings, tool_offset_mm=J)


def _check_resumed_offset(settings, args) -> None:
    """PlanError for a ``--resume`` whose J is not the one its log was begun with (its ``tool_offset_mm`` line),
    before the program is checked: with another J every point moves, and the limits would refuse it first
    without saying why (``run_campaign`` checks it again on the log it locks)."""
    from pathlib import Path

    from core.exceptions import PlanError
    from hardware.campaign import head_meta, resume_offset_problem

    if not (args.resume and not args.dry_run and Path(args.out).is_file()):
        return
    try:
        meta = head_meta(args.out)
    except OSError:
        return            # run_campaign says what is wrong with the file
    problem = resume_offset_problem(args.out, meta, settings.tool_offset_mm)
    if problem:
        raise PlanError(problem)


def _dry_run(steps, settings, args) -> int:
    """``--dry-run``: check the program (limits optional) and print it."""
    from hardware.campaign import check_program, program_lines

    check_program(steps, settings, require_limits=False, rotary=args.rotary)
    if settings.limits_mm is None:
        _warn("no --limits-mm: a live run will refuse to start")
    rotary_axes = "ABC"
    if args.axes is not None:
        from hardware.grbl import check_axes
        rotary_axes = check_axes(args.axes)[3:]
    elif args.rotary:
        _warn("no --axes: the dry run writes A, B and C words; a live run sends only the "
              "controller's rotary axes (name them with --axes, e.g. XYZAC)")
    for line in program_lines(steps, settings, rotary=args.rotary, rotary_axes=rotary_axes):
        print(line)
    return 0


def _check_before_connecting(steps, args) -> None:
    """PlanError for rotary moves without ``--rotary`` (on a controller) or an existing log without ``--resume``."""
    from pathlib import Path

    import numpy as np

    from core.exceptions import PlanError

    if not args.rotary and not args.controller.startswith("virtual"):
        moving = [s for s in steps if np.any(s.rot_deg != 0)]
        if moving:
            raise PlanError(f"{args.plan}: row {moving[0].row} needs rotary axes at "
                            f"{moving[0].rot_deg.tolist()} deg: pass --rotary for a controller with A, B, C")
    if Path(args.out).exists() and not args.resume:
        raise PlanError(f"{args.out}: exists; use --resume to continue it, or choose another --out")


def _probe(plan, settings, args):
    """Open the backend (and the transcript), run the campaign with progress, close both."""
    from hardware.campaign import run_campaign
    from hardware.virtual import open_backend
    from scenarios.cli.guard import terminating_as_interrupt
    from viz.progress import TerminalProgress

    tr = open(args.transcript, "a", encoding="utf-8") if args.transcript else None
    try:
        backend = open_backend(args.controller, timeout_s=args.timeout, rotary=args.rotary, on_event=_warn,
                               transcript=tr, axes=args.axes, reset=args.reset)
        try:
            # SIGTERM as Ctrl-C: the run stops between two statements, the log's rows are on disk, and one line
            # says how many and --resume (it ended the process without a word: review30 F7)
            with TerminalProgress("campaign") as progress, terminating_as_interrupt():
                return run_campaign(backend, plan, args.out, settings, resume=args.resume,
                                    unlock=args.unlock, home=args.home, plan_path=args.plan,
                                    on_touch=lambda row, _r: progress(row + 1, plan.n),
                                    on_start=progress.begin)  # resumed: time left at this run's rate
        finally:
            backend.close()
    finally:
        if tr is not None:
            tr.close()
