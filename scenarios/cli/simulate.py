"""``vmt simulate ARTEFACT --out LOG.csv``: simulate a touch-trigger campaign.

The artefact (one of ``sim.catalog.CATALOG``) is probed with its standard
plan on a named virtual machine, with the realistic truth errors or none,
and the result written as ``probe-log/1``. ``--plan-only`` writes the plan
(measured columns empty).
``vmt simulate positioning --axis X`` runs an ISO 230-2 positioning test
of one axis instead and writes ``positioning-log/1``.
"""

from __future__ import annotations

import math


def register(sub) -> None:
    import argparse

    from sim import catalog
    from sim.machines import describe

    p = sub.add_parser(
        "simulate", help="simulate a touch-trigger campaign on an artefact into a probe log",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=__doc__.split("\n\n")[1] if __doc__ else None,
        epilog="artefacts (and their defaults):\n  " + _catalogue_text(catalog.describe()).replace("\n", "\n  ")
        + "\n  positioning   an ISO 230-2 positioning test of one axis\n                default: on vmc-3axis, axis X"
        + "\n  mfb-3axis     the multi-feature bar's 3-axis plan of 'vmt scenario mfb-3axis' (17 measurements, 7"
        + "\n                styli), its campaign for the same seed, as a log vmt identify / discover read"
        + "\n                default: on vmc-3axis, its study errors"
        + "\n  mfb-5axis     the same for the 5-axis plan (mikron-ucp710, A and C)"
        + "\n\nmachines (--machine NAME, or a machine file):\n  " + describe().replace("\n", "\n  "))
    p.add_argument("artefact", choices=tuple(catalog.CATALOG) + ("positioning",) + MFB_PLANS,
                   help="artefact to probe, 'positioning' for an ISO 230-2 test of one axis, or an MFB plan of "
                        "vmt scenario (mfb-3axis, mfb-5axis: every measurement of the plan, its styli and "
                        "certificate in the log)")
    p.add_argument("--out", required=True, help="probe-log/1 CSV to write (positioning-log/1 for positioning)")
    p.add_argument("--seed", type=int, default=None,
                   help="seed of the probing noise (0); only where there is noise (positioning: of the scatter "
                        "and target spacing)")
    from scenarios.cli.options import add_machine_args, add_noise_arg, option

    add_machine_args(p, default=None, what="virtual machine (default: the artefact's, list below; positioning: "
                                            "vmc-3axis)")
    add_noise_arg(p, "default: the machine's probe, 0.125 for the built-ins: the MFB paper's 0.25 um at k=2; "
                     "1.38 for the self-calibration paper; not for positioning, which has no probe: its "
                     "readings' scatter is --scatter-um")
    option(p, "--c-angles-deg", dest="c_angles", default=None, old=("--c-angles",),
           help="comma-separated C angles of the set-ups, deg (not for a placed artefact: mfb)")
    p.add_argument("--plan-only", action="store_true", help="write the plan only (measured columns empty)")
    p.add_argument("--no-collision-check", action="store_true", help="skip the MuJoCo path checks")
    _add_positioning_options(p)
    p.set_defaults(func=run)


def _catalogue_text(text: str) -> str:
    """``sim.catalog.describe()`` with, under the catalogue's ``mfb``, what its log is for
    (:data:`MFB_CATALOGUE_HELP`)."""
    lines = text.split("\n")
    at = next((i for i, ln in enumerate(lines) if ln.startswith("mfb ")), None)
    if at is None:      # pragma: no cover - the catalogue has its bar
        return text
    return "\n".join(lines[:at + 2] + [f"{'':13s} {ln}" for ln in MFB_CATALOGUE_HELP] + lines[at + 2:])


#: ``vmt simulate --help``'s words under the catalogue's ``mfb`` (what its log is for, and which log identify reads).
MFB_CATALOGUE_HELP = ("the bar's paths and touches: a plan for vmt probe (--plan-only), collision checks;",
                      "all its bars lie along X, one stylus, no probe offsets or bar certificate: vmt",
                      "identify / discover refuse its log; for a log they read: mfb-3axis, mfb-5axis")


#: The MFB plans ``vmt simulate`` writes as a log (``scenarios.mfb.PLANS``: the campaign of ``vmt scenario NAME``).
MFB_PLANS = ("mfb-3axis", "mfb-5axis")
#: What ``vmt simulate mfb`` adds to its line: the catalogue's bar (17 placements, all along X, one stylus, no probe
#: offsets J, no certificate) is a path and touch campaign, which no MFB model identifies all 21 errors from
#: (``vmt identify`` / ``vmt discover`` refuse it, naming what it lacks); the plans of ``vmt scenario`` are the logs
#: they read.
MFB_CATALOGUE_NOTE = ("note: this is the catalogue's bar path (all bars along X, one stylus, no probe offsets or bar "
                      "certificate): for plans and collision checks; vmt identify / vmt discover refuse it. For a bar "
                      "log they identify: vmt simulate mfb-3axis (or mfb-5axis) --out LOG.csv")


#: Share of ``vmt simulate ARTEFACT``'s work done (percent) when its machine is built (the imports and
#: the truth machine), when the campaign is simulated (paths checked, touches) and when the log is
#: written: CPU seconds measured on each artefact with its default machine (0.45, 0.06-0.24 and
#: 0.00-0.04 s), for the progress line's time left; the run takes 2-3 s wall on 2 busy cores.
SIMULATE_SHARES = (70, 96, 100)


#: Old option names refused in one line, with the name that took their meaning (dest -> message): one meaning
#: per option name (review30 F9: '--cycle', the kind, sat beside '--cycles', the count).
REFUSED = {"old_cycle": "--cycle is now --cycle-kind (the test cycle, linear or pilgrim; --cycles is the number "
                        "of approaches)"}


def run(args) -> int:
    from core.exceptions import ConfigError

    for dest, why in REFUSED.items():
        if getattr(args, dest, None) is not None:
            raise ConfigError(why)
    if args.artefact == "positioning":
        return _run_positioning(args)
    if args.artefact in MFB_PLANS:
        return _run_mfb_plan(args)
    from scenarios.cli.guard import progress_line

    with progress_line(f"simulate {args.artefact}: % of the work") as bar:
        log, cfg, errors, note = _campaign(args, bar)
    from scenarios.cli.guard import said

    from core.exceptions import counted

    setups = counted(len(dict.fromkeys(log.col('setup'))), "set-up")
    if args.plan_only:      # a plan measures nothing and has no truth errors: neither is described
        print(f"{said(args.out)}: plan of {log.n} touches (nothing measured) on {args.artefact}, "
              f"machine {cfg.name}, {setups}")
    else:
        print(f"{said(args.out)}: campaign of {log.n} touches ({int(log.ok.sum())} ok) on {args.artefact}, "
              f"machine {cfg.name}, errors {errors}, {setups}")
    if note and not args.plan_only:   # the J the touches were simulated with changes them: said where assumed
        print(note)
    if args.artefact == "mfb":      # (a user following this command's help must not reach a refusal unwarned)
        print(MFB_CATALOGUE_NOTE)
    return 0


def _campaign(args, bar):
    """Simulate the campaign of ``args`` and write its log; return (log, machine config, errors label, the
    assumed tool offset's line or None: :func:`sim.machinefile.tool_offset_note`)."""
    from core.exceptions import ConfigError

    for name in POSITIONING_ONLY:
        if getattr(args, name, None) is not None:
            flag = "--move-feed-mm-min" if name == "move_feed" else f"--{name.replace('_', '-')}"
            raise ConfigError(f"{flag} applies to 'vmt simulate positioning' only")
    import numpy as np

    from dataclasses import replace

    from core.probelog import write_probe_log
    from core.units import UM
    from sim.campaign import simulate_campaign
    from sim.catalog import CATALOG
    from sim.machine import Machine
    from sim.machinefile import errors_label, tool_offset_note, truth_machine

    rec = CATALOG[args.artefact]
    name = args.machine or rec.default_machine
    spec = truth_machine(name, args.errors)
    cfg = spec.config
    errors = errors_label(name, spec)
    machine = Machine(cfg)
    probe = spec.probe
    if args.noise_um is not None:
        if not (np.isfinite(args.noise_um) and args.noise_um >= 0):
            raise ConfigError(f"--noise-um must be >= 0, got {args.noise_um!r}")
        probe = replace(probe, repeatability_k2_m=2 * args.noise_um * UM)
    from scenarios.cli.options import refuse_seed_without_noise

    if args.plan_only:      # a plan touches nothing, so nothing is drawn: an option that draws would be ignored
        for given, opt in ((args.seed, "--seed"), (args.noise_um, "--noise-um")):
            if given is not None:
                raise ConfigError(f"{opt} {given:g}: --plan-only measures nothing, so there is no probing noise "
                                  f"to draw; leave {opt} out")
        if args.errors is not None:
            raise ConfigError(f"--errors {args.errors}: --plan-only measures nothing, so the machine's errors "
                              "change nothing in it; leave --errors out")
    refuse_seed_without_noise(args.seed, args.noise_um, spec.probe.sigma_m / UM,
                              f"the probe of machine {name} has none")
    if rec.placements is not None:
        if args.c_angles:
            raise ConfigError(f"--c-angles-deg: the {rec.name} campaign uses its {rec.setups_text()}, not C angles")
        setups = None
    else:
        text = args.c_angles or (",".join(f"{c:g}" for c in rec.default_c_deg) if machine.rotary_axes else "0")
        try:
            setups = [float(v) for v in text.split(",") if v.strip()]
        except ValueError:
            raise ConfigError(f"--c-angles-deg {text!r} is not a comma-separated list of degrees") from None
        if not all(math.isfinite(c) for c in setups):   # (the set-ups said 'C angle nan is not finite')
            raise ConfigError(f"--c-angles-deg {text!r}: expected finite angles, deg")
    seed = args.seed or 0
    bar(SIMULATE_SHARES[0], 100)    # (drawn once the options are judged: a refused one is the only line)
    log = simulate_campaign(args.artefact, machine, probe, setups, np.random.default_rng(seed),
                            plan_only=args.plan_only, check_collisions=not args.no_collision_check,
                            meta={} if args.plan_only else {"errors": errors, "seed": str(seed)})
    bar(SIMULATE_SHARES[1], 100)
    write_probe_log(args.out, log, special=True)
    bar(SIMULATE_SHARES[2], 100)
    return log, cfg, errors, tool_offset_note(spec)


# --------------------------------------------------------------------------- vmt simulate positioning
#: Options only ``vmt simulate positioning`` takes (dest names).
POSITIONING_ONLY = ("axis", "targets", "travel_mm", "cycles", "cycle_kind", "overrun_mm", "move_feed", "dwell_s",
                    "scatter_um", "line_mm", "reversal_um", "reversal_sense", "drift_um_per_h", "drift_tau_s")


def _add_positioning_options(p) -> None:
    """The options of ``vmt simulate positioning`` (on the ``simulate`` parser)."""
    g = p.add_argument_group("positioning (vmt simulate positioning: an ISO 230-2 test, writes positioning-log/1)")
    g.add_argument("--axis", choices=("X", "Y", "Z"), help="linear axis under test (X)")
    g.add_argument("--targets", type=int, help="number of target positions, irregularly spaced (11)")
    g.add_argument("--travel-mm", metavar="LO:HI", help="measurement travel, mm (the stroke less the overrun; "
                   "write --travel-mm=-100:100 when LO < 0)")
    g.add_argument("--cycles", type=int, help="approaches per target and direction (5, as ISO 230-2 asks)")
    g.add_argument("--cycle-kind", choices=("linear", "pilgrim"), help="test cycle: linear (ISO 230-2's "
                   "standard test, the default) or pilgrim (a step cycle, its Annex B: not for acceptance); "
                   "the log's cycle_kind")
    import argparse

    g.add_argument("--cycle", dest="old_cycle", default=None, help=argparse.SUPPRESS)   # refused: REFUSED
    g.add_argument("--overrun-mm", type=float, help="overrun before each reversal, mm (5)")
    from scenarios.cli.options import option

    option(g, "--move-feed-mm-min", dest="move_feed", type=float, old=("--move-feed",),
           help="positioning feed, mm/min (2000)")
    g.add_argument("--scatter-um", type=float, help="scatter of each reading, a standard deviation (k=1), um (0.5)")
    g.add_argument("--dwell-s", type=float, help="stop at each target before the reading, s (2)")
    g.add_argument("--line-mm", metavar="X,Y,Z", help="measuring line: readings of the other axes, mm "
                   "(the tested axis's entry is ignored; default mid-stroke)")
    g.add_argument("--reversal-um", type=float, help="lost motion added to the axis's positioning error, µm (0)")
    g.add_argument("--reversal-sense", choices=("lead", "lag"),
                   help="the lost motion leads the reading (ISO 230-2 B_i = +size, the default) or lags it "
                        "(backlash, the axis stopping short: B_i = -size)")
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


def _run_positioning(args) -> int:
    """``vmt simulate positioning``: write the simulated test as positioning-log/1."""
    import numpy as np

    from core.exceptions import ConfigError
    from core.positioning import write_positioning_log
    from scenarios.positioning import simulate_test

    if args.noise_um is not None:    # one meaning per name: --noise-um is the probing noise everywhere else
        raise ConfigError("--noise-um is the probing noise; a positioning test has no probe: the scatter of "
                          "each reading is --scatter-um")
    for name in ("c_angles", "plan_only", "no_collision_check"):
        if getattr(args, name, None):
            flag = "--c-angles-deg" if name == "c_angles" else f"--{name.replace('_', '-')}"
            raise ConfigError(f"{flag} does not apply to a positioning test")

    def opt(name, default):
        v = getattr(args, name, None)
        return default if v is None else v

    travel = _numbers(args.travel_mm, "--travel-mm", ":", 2) if args.travel_mm else None
    # judged here in the options' names and units (the simulator's own checks say 'cycles', 'targets'
    # and the travel in metres)
    for flag, n in (("--targets", args.targets), ("--cycles", args.cycles)):
        if n is not None and n < 2:
            raise ConfigError(f"{flag} must be a whole number >= 2, got {n}")
    if travel is not None and not (np.all(np.isfinite(travel)) and travel[0] < travel[1]):
        raise ConfigError(f"--travel-mm {args.travel_mm}: expected finite LO < HI in mm")
    line = _numbers(args.line_mm, "--line-mm", ",", 3) if args.line_mm else None
    if line is not None and not all(math.isfinite(v) for v in line):
        # (it reached the simulator: 'measuring line must be 3 finite readings X, Y, Z, got array([nan, 0., 0.])')
        raise ConfigError(f"--line-mm {args.line_mm}: expected three finite numbers X,Y,Z in mm")
    name = args.machine or "vmc-3axis"
    log = simulate_test(
        name, opt("axis", "X"), np.random.default_rng(args.seed or 0), errors=args.errors,
        noise_um=opt("scatter_um", 0.5), n_targets=opt("targets", 11), travel_mm=travel, cycles=opt("cycles", 5),
        cycle_kind=opt("cycle_kind", "linear"), overrun_mm=opt("overrun_mm", 5.0), feed_mm_min=opt("move_feed", 2000.0),
        dwell_s=opt("dwell_s", 2.0), line_mm=line, reversal_um=opt("reversal_um", 0.0),
        reversal_sense=opt("reversal_sense", "lead"),
        drift_um_per_h=opt("drift_um_per_h", 0.0), drift_tau_s=args.drift_tau_s)
    write_positioning_log(args.out, log, special=True)
    m = len(set(log.target.tolist()))
    print(f"{args.out}: ISO 230-2 test of {log.axis} on {name}, {m} targets x {int(log.cycle.max())} cycles, "
          f"{log.meta['cycle_kind']} cycle, {log.n} readings over {log.t_s[-1]:.0f} s, errors {log.meta['errors']}")
    return 0



def _run_mfb_plan(args) -> int:
    """``vmt simulate mfb-3axis|mfb-5axis --out LOG``: the campaign :func:`scenarios.mfb.run` simulates for this
    seed (``vmt scenario NAME --seed S``'s, touch for touch), written by :func:`scenarios.mfb.campaign_log`."""
    from core.exceptions import ConfigError

    for name in POSITIONING_ONLY:
        if getattr(args, name, None) is not None:
            flag = "--move-feed-mm-min" if name == "move_feed" else f"--{name.replace('_', '-')}"
            raise ConfigError(f"{flag} applies to 'vmt simulate positioning' only")
    for flag, given in (("--c-angles-deg", args.c_angles), ("--plan-only", args.plan_only),
                        ("--no-collision-check", args.no_collision_check)):
        if given:
            raise ConfigError(f"{flag}: the {args.artefact} plan places its bars itself and is always checked for "
                              "collisions (vmt scenario's plan); leave it out")
    from scenarios.mfb import campaign_log, plan_truth_spec, run

    spec = plan_truth_spec(args.artefact, args.machine, args.errors)
    seed = 0 if args.seed is None else args.seed
    from scenarios.cli.guard import progress_line

    with progress_line(f"simulate {args.artefact}: steps") as bar:
        # the campaign alone (``simulate_only``: the log is a full run's, touch for touch; nothing identified)
        r = run(args.artefact, seed=seed, noise_um=args.noise_um, mc_runs=0, machine=spec, progress=bar,
                simulate_only=True)
        log = campaign_log(r, {"errors": "study" if spec is None else (args.errors or "study"), "seed": str(seed),
                               "scenario": args.artefact})
        from core.probelog import write_probe_log

        write_probe_log(args.out, log, special=True)
    from scenarios.cli.guard import said

    print(f"{said(args.out)}: campaign of {log.n} touches on {args.artefact} ({len(r.plan.measurements)} "
          f"measurements, {len(r.plan.setups)} set-ups), machine {r.doc['machine']}, seed {seed}; "
          f"vmt identify / vmt discover read it")
    return 0
