"""``vmt machine show|serve|program``: a machine's definition, the virtual machine behind GRBL, LinuxCNC programs.

    vmt machine show NAME|FILE [--errors realistic|none]
    vmt machine serve --port N [--host 127.0.0.1] [--pty] [--scene ARTEFACT [--machine NAME|FILE] [--errors SET]]
                      [--tool-offset-mm X,Y,Z]
    vmt machine program --plan PLAN.csv --out PROBE.ngc (--limits-mm ... | --machine NAME|FILE)
"""

from __future__ import annotations

import sys
import time

from scenarios.cli.options import parse_floats3


def register(sub) -> None:
    from scenarios.cli.options import ERRORS_HELP, add_machine_args, add_noise_arg, add_settings_args, option

    p = sub.add_parser("machine", help="show a machine; serve the virtual machine over GRBL; write LinuxCNC programs")
    msub = p.add_subparsers(dest="machine_command", metavar="ACTION")
    sh = msub.add_parser("show", help="print a machine's chain, strokes, errors and tip deviations")
    sh.add_argument("machine", metavar="NAME|FILE", help="a built-in machine or a machine file (TOML)")
    from sim.machinefile import ERROR_SETS

    sh.add_argument("--errors", choices=ERROR_SETS, default=None,
                    help="the error set of a built-in machine (default realistic: the papers' magnitudes, the "
                         f"set simulate uses); {ERRORS_HELP}; a machine file states its own")
    sh.set_defaults(func=run_show)
    s = msub.add_parser("serve", help="run a GRBL emulator of the virtual machine on localhost")
    s.add_argument("--port", type=int, required=True, help="TCP port (0: any free port)")
    s.add_argument("--host", default="127.0.0.1", help="address to listen on (127.0.0.1)")
    s.add_argument("--pty", action="store_true", help="also serve on a pseudo-terminal (serial port)")
    s.add_argument("--scene", default="simple",
                   help="simple (table + sphere, linear errors) or a simulated artefact on the virtual machine: "
                        "cross-pocket, pin-circle, freeform, mfb")
    add_machine_args(s, default="nmv3000", what="the virtual machine under a simulated artefact (--scene)",
                     errors_default="drawn", errors_why="the emulator's machine, the same as probe --controller "
                                                        "virtual:SCENE")
    add_noise_arg(s, "default 0 on a built-in machine, as probe --controller virtual:SCENE; a machine file's probe")
    s.add_argument("--seed", type=int, default=None,
                   help="seed of the probing noise (0); only where there is noise: --noise-um, or a machine file's")
    s.add_argument("--scale-ppm", default="0,0,0", help="scale errors of X,Y,Z, µm/m (0,0,0)")
    s.add_argument("--ec0y-urad", type=float, default=0.0, help="squareness EC0Y, µrad (0)")
    option(s, "--limits-mm", dest="limits", old=("--limits",),
           help="soft limits, machine frame, mm: X-10:300,Y0:200,Z-100:0 (ALARM:2 beyond); "
                "GRBL allows them only with homing: the controller powers on in alarm")
    s.add_argument("--homing", action="store_true", help="homing enabled ($22=1): powers on in alarm, $H homes")
    s.add_argument("--axes", help="the controller's axes (default: the machine's, e.g. XYZAC for the nmv3000)")
    option(s, "--home-mm", dest="home", default="0,0,50", metavar="X,Y,Z", old=("--home",),
           help="power-on / $H position, machine frame, mm (0,0,50)")
    s.add_argument("--tool-offset-mm", default=None, metavar="X,Y,Z",
                   help="the probe's offsets J, mm (spindle gauge point minus stylus-tip centre, as a machine file's "
                        "[tool] offset_mm): the machine position is then the spindle's, the tip centre J from it, as "
                        "on a real GRBL machine (probe it with vmt probe --tool-offset-mm J). Default none: the "
                        "machine position is the tip centre's")
    s.add_argument("--time-scale", type=float, default=1.0,
                   help="emulated time per second of wall clock (1: a machine's pace; 10: ten times faster)")
    option(s, "--idle-timeout-s", dest="idle_timeout", type=float, default=300.0, old=("--idle-timeout",),
           help="close a client that sends nothing this long while the machine is idle, s (300)")
    option(s, "--stop-after-s", dest="max_seconds", type=float, old=("--max-seconds",),
           help="stop after this long, s (default: until Ctrl-C)")
    s.add_argument("--on-connect", choices=("greet", "reset", "silent"), default="greet",
                   help="what a new TCP client meets: greet (the banner, the position kept: a network "
                        "controller's welcome), reset (a hardware reset first, the position 0 where the machine "
                        "stands: an Arduino GRBL whose serial port a bridge opens per client, DTR) or silent "
                        "(nothing: a bridge that holds the port open); default greet")
    s.set_defaults(func=run_serve)
    g = msub.add_parser("program", help="write a plan as a LinuxCNC part program (G38.2; each touch a LOG "
                        "line numbered by its plan row)")
    add_settings_args(g, live=False)
    g.add_argument("--out", required=True, help="part program to write (.ngc)")
    g.add_argument("--probe-file", default="vmt-probe.txt",
                   help="file named in (LOGOPEN,...): one line per touch, numbered by its plan row")
    g.add_argument("--wcs", default="G59.3", help="work coordinate system zeroed and used (G59.3)")
    g.add_argument("--from-row", type=int, default=0, metavar="K",
                   help="continue a run that stopped at plan row K (K = the probe file's line count; vmt import "
                        "linuxcnc names it): rows K on, the probe file opened with LOGAPPEND so its lines stay. "
                        "Default 0: the whole plan, LOGOPEN, which empties the file: copy or import it before "
                        "running a program again")
    g.add_argument("--axes", help="the controller's axes, e.g. XYZAC ([TRAJ] COORDINATES): a word for each of its "
                                  "rotary axes and no other (LinuxCNC refuses a letter its machine lacks); default: "
                                  "--machine's, else the machine the plan names (its kinematic_chain)")
    add_machine_args(g, default=None, errors=False,
                     what="take the soft limits from this machine's X, Y, Z strokes (when --limits-mm is not given) "
                          "and the controller's axes from its chain (when --axes is not given)")
    g.set_defaults(func=run_program)
    p.set_defaults(func=lambda a: (p.print_help(), 2)[1])


def served_machine(args):
    """The machine ``vmt machine serve`` puts behind the emulator (``--scene``, ``--machine``, ``--errors``).

    On an artefact scene: the built-in ``--machine`` (nmv3000) with the error
    set ``drawn`` and no probing noise unless ``--errors``/``--noise-um`` say
    otherwise, the machine ``probe --controller virtual:SCENE`` probes; a
    machine file with its errors and its probe.
    """
    from core.exceptions import ConfigError
    from core.units import UM
    from hardware.virtual import builtin_machine, sim_machine
    from sim.machinefile import truth_machine
    from sim.machinefile import builtin_names
    from scenarios.cli.options import refuse_seed_without_noise

    if args.scene == "simple":
        for opt, v in (("--machine", args.machine), ("--errors", args.errors)):
            if v is not None:
                raise ConfigError(f"{opt}: the simple scene has its own errors (--scale-ppm, --ec0y-urad); "
                                  "give --scene ARTEFACT to probe an artefact on a machine")
        refuse_seed_without_noise(args.seed, args.noise_um, 0.0, "the simple scene is served noise-free")
        return builtin_machine(args.noise_um or 0.0, args.seed or 0, parse_floats3(args.scale_ppm, "--scale-ppm"),
                               args.ec0y_urad)
    name = args.machine or "nmv3000"
    spec = truth_machine(name, args.errors, "drawn")
    builtin = name in builtin_names()
    noise = args.noise_um if args.noise_um is not None else (0.0 if builtin else None)
    refuse_seed_without_noise(args.seed, args.noise_um, 0.0 if builtin else spec.probe.sigma_m / UM,
                              "a built-in machine is served noise-free" if builtin
                              else f"the probe of machine file {name} has none")
    return sim_machine(args.scene, noise, args.seed or 0, spec=spec)


def run_serve(args) -> int:
    from core.exceptions import ConfigError
    from hardware.campaign import parse_limits
    from hardware.emulator import ControllerConfig, EmulatorRunner, GrblEmulator, PtyServer, TcpServer

    if not 0 <= args.port <= 65535:
        raise ConfigError(f"--port {args.port}: not a TCP port")
    for opt, v in (("--idle-timeout-s", args.idle_timeout), ("--stop-after-s", args.max_seconds)):
        if v is not None and not v > 0:
            raise ConfigError(f"{opt} must be > 0, got {v:g}")
    from hardware.campaign import parse_tool_offset

    J = None if args.tool_offset_mm is None else parse_tool_offset(args.tool_offset_mm)   # before any work
    machine = served_machine(args)
    axes = args.axes or "XYZ" + "".join(a for a in "ABC" if a in getattr(machine, "rotary_axes", ()))
    config = ControllerConfig(axes=axes, home=parse_floats3(args.home, "--home-mm"), homing=args.homing,
                              travel=parse_limits(args.limits) if args.limits else None)
    emu = GrblEmulator(machine, config, tool_offset_mm=J)
    runner = EmulatorRunner(emu, time_scale=args.time_scale)
    try:
        tcp = TcpServer(runner, args.host, args.port, idle_timeout_s=args.idle_timeout,
                        on_connect=args.on_connect).start()
    except OSError as e:
        raise ConfigError(f"--host {args.host} --port {args.port}: cannot listen ({e.strerror})") from None
    # said once it listens (session 37, audit37: said before, it preceded the error of a host it cannot listen on)
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"vmt machine: warning: listening on {args.host}, not only this computer",
              file=sys.stderr)
    ptys = PtyServer(runner).start() if args.pty else None
    print(f"vmt machine: GRBL emulator of axes {axes} on {tcp.url}"
          + ("" if J is None else f", the probe's tip centre J = ({', '.join(f'{v:g}' for v in J)}) mm from the "
                                  "machine position"), flush=True)
    if ptys is not None:
        print(f"vmt machine: serial port {ptys.path} ({ptys.url})", flush=True)
    end = None if args.max_seconds is None else time.monotonic() + args.max_seconds
    try:
        while end is None or time.monotonic() < end:
            time.sleep(0.1)
    except KeyboardInterrupt:
        pass
    finally:
        tcp.stop()
        if ptys is not None:
            ptys.stop()
    from core.exceptions import counted

    print(f"vmt machine: stopped after {counted(emu.probes, 'probing move')}", flush=True)
    return 0


def run_program(args) -> int:
    from core.atomic import write_text_atomic
    from scenarios.cli.reading import read_probe
    from hardware.linuxcnc import part_program
    from scenarios.cli.options import settings_from_args

    from hardware.linuxcnc import check_axes, program_axes

    plan = read_probe(args.plan, "machine program")
    settings = settings_from_args(args)
    axes = None if args.axes is None else check_axes(args.axes)
    if args.machine is not None:
        from dataclasses import replace

        from core.exceptions import ConfigError
        from sim.machinefile import truth_machine

        if args.limits:
            raise ConfigError("--machine and --limits-mm: give one (the machine's strokes are its limits)")
        cfg = truth_machine(args.machine).config
        st = cfg.strokes
        settings = replace(settings, limits_mm=tuple((lo * 1e3, hi * 1e3) for lo, hi in (st[a] for a in "XYZ")))
        if axes is None:
            axes, source = "XYZ" + "".join(cfg.parsed_chain.rotary_axes), f"machine {args.machine}"
    from scenarios.cli.guard import about_file

    name = plan.meta.get("machine")
    if axes is None and not plan.meta.get("kinematic_chain") and name:
        from sim.machinefile import builtin_names, truth_machine

        if name in builtin_names():     # a plan that names a built-in machine but carries no chain
            axes = "XYZ" + "".join(truth_machine(name, "none").config.parsed_chain.rotary_axes)
            source = f"the plan's machine {name}"
    with about_file(args.plan):     # 'row 23 (target ...): approach ... is outside the soft limits': of this plan
        if axes is None:
            axes, source = program_axes(plan)
        elif args.axes is not None:
            source = "--axes"
        text = part_program(plan, settings, probe_file=args.probe_file, wcs=args.wcs, axes=axes,
                            from_row=args.from_row)
    out = write_text_atomic(args.out, text, special=True)
    from core.exceptions import counted

    if args.from_row:
        print(f"{out}: LinuxCNC program, rows {args.from_row}..{plan.n - 1} ({plan.n - args.from_row} of "
              f"{counted(plan.n, 'touch')}), axes {axes} ({source}), appending to probe file {args.probe_file} "
              f"(LOGAPPEND: it must hold rows 0..{args.from_row - 1})")
    else:
        print(f"{out}: LinuxCNC program, {counted(plan.n, 'touch')}, axes {axes} ({source}), "
              f"probe file {args.probe_file} (LOGOPEN empties it: after a stop, copy it and continue with --from-row)")
    return 0


def run_show(args) -> int:
    import numpy as np

    from core import iso
    from core.units import DEG, MM
    from sim.machine import Machine
    from sim.machinefile import truth_machine
    from sim.machinefile import describe_error, stroke_positions

    spec = truth_machine(args.machine, args.errors)
    cfg = spec.config
    ch = cfg.parsed_chain
    print(f"machine {cfg.name} ({spec.source})" + (f": {spec.description}" if spec.description else ""))
    print(f"chain {cfg.chain}: workpiece side {', '.join(ch.workpiece_from_bed) or '-'} (from the bed), "
          f"tool side {', '.join(ch.tool_axes) or '-'}")

    def stroke(a, lo, hi):
        return f"{a} {lo / DEG:g}..{hi / DEG:g} deg" if a in iso.ROTARY_AXES else f"{a} {lo / MM:g}..{hi / MM:g} mm"

    print("strokes: " + ", ".join(stroke(a, *cfg.strokes[a]) for a in "XYZABC" if a in cfg.strokes))
    if cfg.rotary_points_R_m:
        print("rotary axis points: " + ", ".join(f"{a} ({', '.join(f'{v * 1e3:g}' for v in p)}) mm"
                                                 for a, p in cfg.rotary_points_R_m.items()))
    from sim.machinefile import tool_offset_note

    note = tool_offset_note(spec)   # the file gives no [tool]: said where its default stands in (session 37)
    print(f"tool offset J (gauge point - tip centre): ({', '.join(f'{v * 1e3:g}' for v in cfg.J_m)}) mm"
          + (f" ({note})" if note else ""))
    pr = spec.probe
    lob = ", ".join(f"k={int(k)}: {a * 1e6:g}/{b * 1e6:g} um" for k, a, b in pr.lobing_m) or "none"
    print(f"probe: stylus radius {pr.stylus_r_m * 1e3:g} mm, noise {pr.sigma_m * 1e6:g} um (k=1), "
          f"pre-travel {pr.pretravel_m * 1e6:g} um, lobing {lob}")
    base = spec.errors + (f", seed {spec.seed}" if spec.seed is not None else "")
    print(f"errors (ISO 230-1: the tool relative to the workpiece; base set {base}"
          + (f"; set in the file: {', '.join(spec.overrides)}" if spec.overrides else "") + "):")
    if not cfg.errors:
        print("  none")
    for name, f in sorted(cfg.errors.items(), key=lambda kv: [s.name for s in iso.SYMBOLS].index(kv[0])):
        sy = iso.symbol(name)
        if sy.location:
            rng_txt = ""
        else:
            lo, hi = cfg.strokes[sy.axis]
            where = "over the stroke"
            if sy.axis in iso.LINEAR_AXES:   # evaluated at the axis position reading + J (the reference tool)
                j = cfg.J_m[iso.LINEAR_AXES.index(sy.axis)]
                lo, hi = lo + j, hi + j
                where = f"over the stroke + J ({sy.axis} {lo / MM:g}..{hi / MM:g} mm, axis positions)"
            v = np.asarray(f(stroke_positions(f, (lo, hi))), float) * 1e6
            rng_txt = f"  [{v.min():+.3f} .. {v.max():+.3f}] {where}"
        print(f"  {name:5s} {sy.report_unit:4s} {describe_error(f, sy)}{rng_txt}")
    m = Machine(cfg)
    lin = []
    for x in (0, 1):
        for y in (0, 1):
            for z in (0, 1):
                lin.append([cfg.strokes[a][k] for a, k in zip("XYZ", (x, y, z))])
    lin.append([0.5 * sum(cfg.strokes[a]) for a in "XYZ"])
    lin = np.array(lin)
    rot = None if not m.rotary_axes else np.zeros((len(lin), len(m.rotary_axes)))
    dev = (m.tip_W(lin, rot) - m.tip_W_nominal(lin, rot)) * 1e6
    print("tip deviation, tool relative to the workpiece (exact chain; rotary axes at 0; corners and centre "
          "of the strokes):")
    print(f"  {'X_mm':>9s} {'Y_mm':>9s} {'Z_mm':>9s}   {'dX_um':>9s} {'dY_um':>9s} {'dZ_um':>9s}")
    for p, d in zip(lin * 1e3, dev):
        print(f"  {p[0]:9.1f} {p[1]:9.1f} {p[2]:9.1f}   {d[0]:9.3f} {d[1]:9.3f} {d[2]:9.3f}")
    return 0
