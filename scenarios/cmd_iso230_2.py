"""``vmt iso230-2 LOG --json OUT [--report DIR]``: evaluate a positioning test by ISO 230-2.

LOG is a positioning-log/1 file, an ecmc ``.dat`` (EPICS motion control)
or a table of target, cycle, direction, measured value. Every figure of
ISO 230-2 goes to the JSON in µm; ``--report`` adds a folder with the
standard's plot. This module also holds ``vmt simulate positioning``
(:func:`add_simulate_options`, :func:`run_simulate`).
"""

from __future__ import annotations

import sys


def register(sub) -> None:
    p = sub.add_parser("iso230-2", help="evaluate a positioning test (ISO 230-2): every figure, in µm",
                       description=__doc__.split("\n\n")[1])
    p.add_argument("log", help="positioning-log/1 CSV, ecmc .dat, or a table of target, cycle, direction, measured")
    p.add_argument("--json", required=True, metavar="OUT", help="JSON report to write (atomically)")
    p.add_argument("--report", help="folder for a readable report (index.html, the standard's plot)")
    p.add_argument("--from", dest="kind", choices=("auto", "log", "ecmc", "table"), default="auto",
                   help="what LOG is (auto: '# format:' line -> log, TGT_DATA[ -> ecmc, else table)")
    p.add_argument("--write-log", metavar="LOG", help="also write the readings as positioning-log/1")
    g = p.add_argument_group("uncertainty of the test (ISO/TR 230-9 style; any of these adds U (k=2) per figure)")
    g.add_argument("--u-instrument-um", type=float, help="instrument, length-independent, standard uncertainty, µm")
    g.add_argument("--u-instrument-um-per-m", type=float, help="instrument, per m of travel, standard uncertainty, µm/m")
    g.add_argument("--misalignment-urad", type=float, help="largest beam-to-axis angle (cosine error), µrad")
    g.add_argument("--temp-c", type=float, help="mean temperature of the machine scale during the test, °C (20)")
    g.add_argument("--u-temp-k", type=float, help="standard uncertainty of that temperature, K")
    g.add_argument("--alpha-per-k", type=float, help="expansion coefficient of the scale, 1/K (11.5e-6)")
    g.add_argument("--u-alpha-per-k", type=float, help="its standard uncertainty, 1/K")
    g.add_argument("--eve-um", type=float, help="environmental variation error E_VE (drift check range), µm")
    p.set_defaults(func=run)


_UNC = {"u_instrument_um": "u_instrument_um", "u_instrument_um_per_m": "u_instrument_um_per_m",
        "misalignment_urad": "misalignment_urad", "temp_c": "temperature_C", "u_temp_k": "u_temperature_K",
        "alpha_per_k": "alpha_per_K", "u_alpha_per_k": "u_alpha_per_K", "eve_um": "eve_um"}


def run(args) -> int:
    from core.positioning import UncertaintyInputs
    from scenarios.positioning import FIGURE_ROWS, evaluate_file

    given = {v: getattr(args, k) for k, v in _UNC.items() if getattr(args, k) is not None}
    unc = UncertaintyInputs(**given) if given else None
    rep, warnings = evaluate_file(args.log, args.json, args.report, kind=args.kind, uncertainty=unc,
                                  write_log=args.write_log)
    for w in warnings:
        print(f"vmt iso230-2: warning: {w}", file=sys.stderr)
    u = rep["unit"]
    sym = "um" if u == "um" else "arcsec"
    print(f"{args.log}: axis {rep['axis'] or '?'}, {rep['targets']} targets x {rep['cycles']} cycles"
          + (f", {rep['cycle_kind']} cycle" if rep.get("cycle_kind") else ""))
    U = rep.get("uncertainty") or {}
    for name, symbol, clause, meaning in FIGURE_ROWS:
        extra = f"  (U {U[f'U_{name}_um']:.3f})" if U else ""
        pad = " " * (4 - len(symbol.replace("\u0304", "")))  # B̄ carries a combining macron
        print(f"  {symbol}{pad}{rep[f'{name}_{u}']:10.3f} {sym}{extra}   {meaning} [{clause}]")
    print(f"wrote {args.json}" + (f" and {args.report}/index.html" if args.report else "")
          + (f" and {args.write_log}" if args.write_log else ""))
    return 0


# --------------------------------------------------------------------------- vmt simulate positioning
#: Options only ``vmt simulate positioning`` takes (dest names).
POSITIONING_ONLY = ("axis", "targets", "travel_mm", "cycles", "cycle", "overrun_mm", "move_feed", "dwell_s",
                    "line_mm", "reversal_um", "drift_um_per_h", "drift_tau_s")


def add_simulate_options(p) -> None:
    """The options of ``vmt simulate positioning`` (on the ``simulate`` parser)."""
    g = p.add_argument_group("positioning (vmt simulate positioning: an ISO 230-2 test, writes positioning-log/1)")
    g.add_argument("--axis", choices=("X", "Y", "Z"), help="linear axis under test (X)")
    g.add_argument("--targets", type=int, help="number of target positions, irregularly spaced (11)")
    g.add_argument("--travel-mm", metavar="LO:HI", help="measurement travel, mm (the stroke less the overrun)")
    g.add_argument("--cycles", type=int, help="approaches per target and direction (5, as ISO 230-2 asks)")
    g.add_argument("--cycle", choices=("linear", "pilgrim"), help="ISO 230-2 test cycle (linear)")
    g.add_argument("--overrun-mm", type=float, help="overrun before each reversal, mm (5)")
    g.add_argument("--move-feed", type=float, help="positioning feed, mm/min (2000)")
    g.add_argument("--dwell-s", type=float, help="stop at each target before the reading, s (2)")
    g.add_argument("--line-mm", metavar="X,Y,Z", help="measuring line: readings of the other axes, mm "
                   "(the tested axis's entry is ignored; default mid-stroke)")
    g.add_argument("--reversal-um", type=float, help="lost motion added to the axis's positioning error, µm (0)")
    g.add_argument("--drift-um-per-h", type=float, help="offset drift added to the axis's positioning error, µm/h (0)")
    g.add_argument("--drift-tau-s", type=float, help="the drift approaches its steady state with this time constant, s")


def _numbers(text: str, name: str, sep: str, count: int):
    from core.exceptions import ConfigError

    try:
        v = [float(x) for x in text.split(sep)]
    except ValueError:
        v = []
    if len(v) != count:
        raise ConfigError(f"{name} {text!r}: expected {count} numbers separated by {sep!r}")
    return v


def run_simulate(args) -> int:
    """``vmt simulate positioning``: write the simulated test as positioning-log/1."""
    import numpy as np

    from core.exceptions import ConfigError
    from core.positioning import write_positioning_log
    from scenarios.positioning import simulate_test

    for name in ("c_angles", "plan_only", "no_collision_check"):
        if getattr(args, name, None):
            raise ConfigError(f"--{name.replace('_', '-')} does not apply to a positioning test")

    def opt(name, default):
        v = getattr(args, name, None)
        return default if v is None else v

    travel = _numbers(args.travel_mm, "--travel-mm", ":", 2) if args.travel_mm else None
    line = _numbers(args.line_mm, "--line-mm", ",", 3) if args.line_mm else None
    name = args.machine or "vmc-3axis"
    log = simulate_test(
        name, opt("axis", "X"), np.random.default_rng(args.seed), errors=args.errors,
        noise_um=opt("noise_um", 0.5), n_targets=opt("targets", 11), travel_mm=travel, cycles=opt("cycles", 5),
        cycle_kind=opt("cycle", "linear"), overrun_mm=opt("overrun_mm", 5.0), feed_mm_min=opt("move_feed", 2000.0),
        dwell_s=opt("dwell_s", 2.0), line_mm=line, reversal_um=opt("reversal_um", 0.0),
        drift_um_per_h=opt("drift_um_per_h", 0.0), drift_tau_s=args.drift_tau_s)
    write_positioning_log(args.out, log)
    m = len(set(log.target.tolist()))
    print(f"{args.out}: ISO 230-2 test of {log.axis} on {name}, {m} targets x {int(log.cycle.max())} cycles, "
          f"{log.meta['cycle_kind']} cycle, {log.n} readings over {log.t_s[-1]:.0f} s, errors {args.errors}")
    return 0


def reject_positioning_options(args) -> None:
    """For the artefact campaigns of ``vmt simulate``: the positioning options do not apply."""
    from core.exceptions import ConfigError

    for name in POSITIONING_ONLY:
        if getattr(args, name, None) is not None:
            raise ConfigError(f"--{name.replace('_', '-')} applies to 'vmt simulate positioning' only")
