"""``vmt simulate ARTEFACT --out LOG.csv``: simulate a touch-trigger campaign.

The artefact (``mfb``, ``cross-pocket``, ``pin-circle``, ``freeform``) is
probed with its standard plan on a named virtual machine, with the
realistic truth errors or none, and the result written as ``probe-log/1``.
``--plan-only`` writes the plan (measured columns empty).
"""

from __future__ import annotations

ARTEFACT_NAMES = ("mfb", "cross-pocket", "pin-circle", "freeform")
#: Default machine and C angles (deg) per artefact (papers' values).
DEFAULT_MACHINE = {"mfb": "mikron-ucp710", "cross-pocket": "nmv3000",
                   "pin-circle": "mikron-ucp710", "freeform": "nmv3000"}
DEFAULT_C_DEG = {"cross-pocket": "0,75,130,210", "pin-circle": "0,31,83,137,191,227,257,313",
                 "freeform": "0,75,130,210"}


def register(sub) -> None:
    import argparse

    from sim.machines import describe

    p = sub.add_parser(
        "simulate", help="simulate a touch-trigger campaign on an artefact into a probe log",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=__doc__.split("\n\n")[1] if __doc__ else None,
        epilog="machines (--machine):\n  " + describe().replace("\n", "\n  ")
        + "\n\ndefaults: mfb on mikron-ucp710 (17 placements); cross-pocket and freeform on nmv3000 "
          "at C = 0,75,130,210; pin-circle on mikron-ucp710 at C = 0,31,83,137,191,227,257,313")
    p.add_argument("artefact", choices=ARTEFACT_NAMES, help="artefact to probe")
    p.add_argument("--out", required=True, help="probe-log/1 CSV to write")
    p.add_argument("--seed", type=int, default=0, help="seed of the probing noise")
    p.add_argument("--machine", default=None, help="virtual machine (see the list below)")
    p.add_argument("--errors", choices=("realistic", "none"), default="realistic",
                   help="truth errors of the machine (default realistic: the papers' magnitudes)")
    p.add_argument("--noise-um", type=float, default=None,
                   help="probing repeatability as a standard deviation (k=1), um "
                        "(default 0.125: the MFB paper's 0.25 um at k=2; 1.38 for the self-calibration paper)")
    p.add_argument("--c-angles", default=None, help="comma-separated C angles, deg (not for mfb)")
    p.add_argument("--plan-only", action="store_true", help="write the plan only (measured columns empty)")
    p.add_argument("--no-collision-check", action="store_true", help="skip the MuJoCo path checks")
    p.set_defaults(func=run)


def run(args) -> int:
    import numpy as np

    from core.exceptions import ConfigError
    from core.probelog import write_probe_log
    from sim.campaign import simulate_campaign
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors
    from sim.probe import ProbeConfig

    name = args.machine or DEFAULT_MACHINE[args.artefact]
    if name not in MACHINES:
        raise ConfigError(f"--machine {name!r} is not one of {', '.join(MACHINES)}")
    cfg = MACHINES[name]()
    axes = tuple(a for a in "XYZABC" if a in cfg.strokes)
    if args.errors == "realistic":
        cfg = MACHINES[name](errors=realistic_errors(axes, strokes=cfg.strokes))
    machine = Machine(cfg)
    kw = {}
    if args.noise_um is not None:
        if not (np.isfinite(args.noise_um) and args.noise_um >= 0):
            raise ConfigError(f"--noise-um must be >= 0, got {args.noise_um!r}")
        kw["repeatability_k2_m"] = 2 * args.noise_um * 1e-6
    probe = ProbeConfig(**kw)
    if args.artefact == "mfb":
        if args.c_angles:
            raise ConfigError("--c-angles: the mfb campaign uses its 17 placements, not C angles")
        setups = None
    else:
        text = args.c_angles or (DEFAULT_C_DEG[args.artefact] if machine.rotary_axes else "0")
        try:
            setups = [float(v) for v in text.split(",") if v.strip()]
        except ValueError:
            raise ConfigError(f"--c-angles {text!r} is not a comma-separated list of degrees") from None
    log = simulate_campaign(args.artefact, machine, probe, setups, np.random.default_rng(args.seed),
                            plan_only=args.plan_only, check_collisions=not args.no_collision_check,
                            meta={"errors": args.errors, "seed": str(args.seed)})
    write_probe_log(args.out, log)
    ok = int(log.ok.sum())
    kind = "plan" if args.plan_only else "campaign"
    print(f"{args.out}: {kind} of {log.n} touches ({ok} ok) on {args.artefact}, machine {name}, "
          f"errors {args.errors}, {len(dict.fromkeys(log.col('setup')))} set-ups")
    return 0
