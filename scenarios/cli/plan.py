"""``vmt plan grid``: the plan of a rectangular grid probed along Z (surface probing)."""

from __future__ import annotations


def _range(text: str, name: str) -> tuple:
    from core.exceptions import ConfigError

    try:
        lo, hi, step = (float(v) for v in text.split(":"))
    except ValueError:
        raise ConfigError(f"{name} {text!r}: expected lo:hi:step in mm (write {name}=-10:10:5 "
                          "when lo < 0)") from None
    return lo, hi, step


def register(sub) -> None:
    p = sub.add_parser("plan", help="write a probing plan (probe-log/1) for a common job")
    psub = p.add_subparsers(dest="plan_command", metavar="KIND")
    g = psub.add_parser("grid", help="a rectangular XY grid probed straight down (surface / height map)")
    g.add_argument("--x-mm", required=True, metavar="lo:hi:step", help="grid lines along X, machine frame, mm")
    g.add_argument("--y-mm", required=True, metavar="lo:hi:step", help="grid lines along Y, machine frame, mm")
    g.add_argument("--z-mm", type=float, default=0.0, help="nominal surface height, machine frame, mm (0)")
    from scenarios.cli.options import add_stylus_r_arg

    add_stylus_r_arg(g, "required: the plan's nominal tip centres stand one radius above the surface",
                     required=True)
    g.add_argument("--no-serpentine", action="store_true",
                   help="probe every row in +X (default: serpentine, X reversed on odd rows)")
    g.add_argument("--out", required=True, help="plan to write (probe-log/1, measured columns empty)")
    g.set_defaults(func=run_grid)
    p.set_defaults(func=lambda a: (p.print_help(), 2)[1])


def run_grid(args) -> int:
    from core.probelog import write_probe_log
    from hardware.surface import grid_plan
    from scenarios.cli.options import no_stylus_r

    x_mm, y_mm = _range(args.x_mm, "--x-mm"), _range(args.y_mm, "--y-mm")
    if args.stylus_r_mm is None:      # never 0 by default: every nominal and the approach clearance would be off by it
        raise no_stylus_r("no stylus radius (the plan's nominal tip centres stand one radius above the surface)")
    plan = grid_plan(x_mm, y_mm, args.z_mm,
                     stylus_r_mm=args.stylus_r_mm, serpentine=not args.no_serpentine)
    write_probe_log(args.out, plan, special=True)
    from core.exceptions import counted

    print(f"{args.out}: {plan.meta['plan']} ({counted(plan.n, 'touch')})")
    return 0
