"""``vmt machine serve|program``: the virtual machine behind GRBL, and LinuxCNC part programs.

    vmt machine serve --port N [--host 127.0.0.1] [--pty]
    vmt machine program --plan PLAN.csv --out PROBE.ngc --limits ...
"""

from __future__ import annotations

import sys
import time


def _floats3(text: str, name: str):
    from core.exceptions import ConfigError

    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3:
        raise ConfigError(f"{name} {text!r}: expected three numbers a,b,c")
    return v


def register(sub) -> None:
    p = sub.add_parser("machine", help="serve the virtual machine over GRBL; write LinuxCNC programs")
    msub = p.add_subparsers(dest="machine_command", metavar="ACTION")
    s = msub.add_parser("serve", help="run a GRBL emulator of the virtual machine on localhost")
    s.add_argument("--port", type=int, required=True, help="TCP port (0: any free port)")
    s.add_argument("--host", default="127.0.0.1", help="address to listen on (127.0.0.1)")
    s.add_argument("--pty", action="store_true", help="also serve on a pseudo-terminal (serial port)")
    s.add_argument("--scene", default="simple",
                   help="simple (table + sphere, linear errors) or a simulated artefact on the nmv3000 with "
                        "realistic errors: cross-pocket, pin-circle, freeform, mfb")
    s.add_argument("--noise-um", type=float, default=0.0, help="probing noise, µm per axis (0)")
    s.add_argument("--seed", type=int, default=0, help="seed of the noise (0)")
    s.add_argument("--scale-ppm", default="0,0,0", help="scale errors of X,Y,Z, µm/m (0,0,0)")
    s.add_argument("--ec0y-urad", type=float, default=0.0, help="squareness EC0Y, µrad (0)")
    s.add_argument("--limits", help="soft limits, mm: X-10:300,Y0:200,Z-100:0 (ALARM:2 beyond); "
                   "GRBL allows them only with homing: the controller powers on in alarm")
    s.add_argument("--homing", action="store_true", help="homing enabled ($22=1): powers on in alarm, $H homes")
    s.add_argument("--axes", help="the controller's axes (default: the machine's, e.g. XYZAC for the nmv3000)")
    s.add_argument("--home", default="0,0,50", help="power-on / $H position, mm (0,0,50)")
    s.add_argument("--time-scale", type=float, default=1.0,
                   help="emulated time per second of wall clock (1: a machine's pace; 10: ten times faster)")
    s.add_argument("--idle-timeout", type=float, default=300.0,
                   help="close a client that sends nothing this long while the machine is idle, s (300)")
    s.add_argument("--max-seconds", type=float, help="stop after this long (default: until Ctrl-C)")
    s.set_defaults(func=run_serve)
    g = msub.add_parser("program", help="write a plan as a LinuxCNC part program (G38.2, PROBEOPEN)")
    from scenarios.cli.options import add_settings_args

    add_settings_args(g, live=False)
    g.add_argument("--out", required=True, help="part program to write (.ngc)")
    g.add_argument("--probe-file", default="vmt-probe.txt", help="file named in (PROBEOPEN ...)")
    g.add_argument("--wcs", default="G59.3", help="work coordinate system zeroed and used (G59.3)")
    g.set_defaults(func=run_program)
    p.set_defaults(func=lambda a: (p.print_help(), 2)[1])


def run_serve(args) -> int:
    from core.exceptions import ConfigError
    from hardware.campaign import parse_limits
    from hardware.emulator import ControllerConfig, EmulatorRunner, GrblEmulator, PtyServer, TcpServer

    if not 0 <= args.port <= 65535:
        raise ConfigError(f"--port {args.port}: not a TCP port")
    from hardware.virtual import builtin_machine, sim_machine

    if args.scene == "simple":
        machine = builtin_machine(args.noise_um, args.seed, _floats3(args.scale_ppm, "--scale-ppm"),
                                  args.ec0y_urad)
    else:
        machine = sim_machine(args.scene, args.noise_um, args.seed)
    axes = args.axes or "XYZ" + "".join(a for a in "ABC" if a in getattr(machine, "rotary_axes", ()))
    config = ControllerConfig(axes=axes, home=_floats3(args.home, "--home"), homing=args.homing,
                              travel=parse_limits(args.limits) if args.limits else None)
    emu = GrblEmulator(machine, config)
    runner = EmulatorRunner(emu, time_scale=args.time_scale)
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"vmt machine: warning: listening on {args.host}, not only this computer",
              file=sys.stderr)
    try:
        tcp = TcpServer(runner, args.host, args.port, idle_timeout_s=args.idle_timeout).start()
    except OSError as e:
        raise ConfigError(f"--host {args.host} --port {args.port}: cannot listen ({e.strerror})") from None
    ptys = PtyServer(runner).start() if args.pty else None
    print(f"vmt machine: GRBL emulator of axes {axes} on {tcp.url}", flush=True)
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
    print(f"vmt machine: stopped after {emu.probes} probing moves", flush=True)
    return 0


def run_program(args) -> int:
    from core.atomic import write_text_atomic
    from core.probelog import read_probe_log
    from hardware.linuxcnc import part_program
    from scenarios.cli.options import settings_from_args

    plan = read_probe_log(args.plan)
    text = part_program(plan, settings_from_args(args), probe_file=args.probe_file, wcs=args.wcs)
    out = write_text_atomic(args.out, text)
    print(f"{out}: LinuxCNC program, {plan.n} touches, probe file {args.probe_file}")
    return 0
