"""``vmt import linuxcnc|grbl FILE [--plan PLAN.csv] --out LOG.csv [--tool-offset-mm X,Y,Z]``: a controller's log to
probe-log/1 (``--tool-offset-mm``: grbl only, the probe's J taken off every report)."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("import", help="merge a controller's probe file or transcript with its plan")
    p.add_argument("kind", choices=("linuxcnc", "grbl"),
                   help="linuxcnc: the LOGOPEN file of a vmt machine program run (N<row> G1 X.. Y.. Z.. lines), "
                        "a PROBEOPEN file (3 or 9 numbers a line) or another LOGOPEN file "
                        "(G1 X.. Y.. Z.. lines); grbl: a session transcript (its [PRB] machine positions are "
                        "logged less --tool-offset-mm, as they are without it: the stylus-tip centre's only if the "
                        "controller's machine coordinates are; docs/formats.md, 'GRBL transcript')")
    p.add_argument("file", help="the probe file or transcript")
    p.add_argument("--plan", help="the probe-log/1 plan that was run; without it (linuxcnc) the file "
                   "is a surface probed along Z and the plan is built from it (points that are not a grid's "
                   "nodes are refused)")
    p.add_argument("--out", required=True, help="probe-log/1 file to write")
    from scenarios.cli.options import option

    option(p, "--dt-s", dest="dt", type=float, default=1.0, old=("--dt",),
           help="time between touches when the file has no clock, s (1)")
    p.add_argument("--units", choices=("mm", "inch"), default=None,
                   help="units of a LinuxCNC probe file (mm); not for grbl, whose reports are read as mm "
                        "(a transcript showing $13=1, report inches, is refused)")
    p.add_argument("--tool-offset-mm", default=None, metavar="X,Y,Z",
                   help="grbl: the probe's offsets J the transcript's run was made with, mm (spindle gauge point minus "
                        "stylus-tip centre, as vmt probe --tool-offset-mm and a machine file's [tool] offset_mm): "
                        "every [PRB] report is logged less J, the tip centre the plan means, and the log records J "
                        "(tool_offset_mm). Not for linuxcnc, which applies its tool table's offset itself (G43)")
    p.add_argument("--clearance-mm", dest="clearance", type=float, default=None,
                   help="the program's approach start before contact (vmt machine program / vmt probe "
                        "--clearance-mm), mm (2 when only --overtravel-mm is given): each touch within clearance + "
                        "overtravel of its nominal along its approach line; neither given, 10 mm (a GRBL "
                        "transcript's own G91 G38.2 moves say it, and so do the LOG lines of a vmt machine "
                        "program since session 30: their own stroke is used)")
    p.add_argument("--overtravel-mm", dest="overtravel", type=float, default=None,
                   help="the program's probing end beyond contact, mm (2 when only --clearance-mm is given)")
    p.set_defaults(func=run)


def run(args) -> int:
    from core.probelog import write_probe_log
    from scenarios.cli.reading import read_probe

    from core.exceptions import ConfigError

    from hardware.transcript import program_stroke

    stroke = program_stroke(args.clearance, args.overtravel)
    J = None
    if args.tool_offset_mm is not None:     # before reading anything
        if args.kind != "grbl":
            raise ConfigError("import linuxcnc: --tool-offset-mm is for grbl transcripts; LinuxCNC applies the "
                              "probe's tool length offset itself (its tool table, G43), so its probe file already "
                              "holds the tip centres")
        from hardware.campaign import parse_tool_offset

        J = parse_tool_offset(args.tool_offset_mm)
    plan = read_probe(args.plan, "import") if args.plan else None
    if args.kind == "linuxcnc":
        from hardware.linuxcnc import import_probe_file

        from hardware.surface import NotAGrid

        try:
            log = import_probe_file(args.file, plan, dt_s=args.dt, units=args.units or "mm", stroke=stroke)
        except NotAGrid as e:   # read without --plan as a Z grid, and it is none
            raise ConfigError(f"{e}; give the plan that was run: --plan PLAN.csv") from None
    else:
        from hardware.transcript import import_transcript

        if plan is None:
            raise ConfigError("import grbl: --plan is required (a transcript does not say what was probed)")
        if args.units is not None:
            raise ConfigError("import grbl: --units is for LinuxCNC probe files; a GRBL transcript's reports are "
                              "read as mm (GRBL's $13=0): inch reports are not converted")

        log = import_transcript(args.file, plan, dt_s=args.dt, stroke=stroke, tool_offset_mm=J)
    write_probe_log(args.out, log, special=True)
    ok = int(log.ok.sum())
    from scenarios.cli.guard import said

    from core.exceptions import counted

    print(f"{said(args.out)}: {counted(log.n, 'touch')} ({ok} ok) from {args.kind} {args.file}"
          + ("" if J is None else f", each report less the tool offset J = ({', '.join(f'{v:g}' for v in J)}) mm"))
    if "probe_file_rows" in log.meta:
        print(f"note: the probe file has {log.meta['probe_file_rows']}")
    if "transcript_repeats" in log.meta:
        print(f"note: {log.meta['transcript_repeats']}")
    if "transcript_reports" in log.meta:
        print(f"note: the transcript has {log.meta['transcript_reports']}")
        print(f"note: what stopped it: {log.meta['stop_reason']}")
    if plan is None:
        # the plan's 'plan', kept as plan_plan
        print(f"note: no plan: {log.meta.get('plan_plan', 'built from the file')}")
    return 0
