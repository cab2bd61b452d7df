"""``vmt scenario NAME``: run a named study end to end.

``SCENARIOS`` maps a name to a function ``f(args) -> int``; add a study by
adding one entry (the lead adds the cross-pocket scenarios here).
"""

from __future__ import annotations


def _mfb(args) -> int:
    import json
    import os

    from scenarios.mfb import run

    r = run(args.name, seed=args.seed, noise_um=args.noise_um, mc_runs=args.mc)
    d = r.doc
    print(f"vmt scenario {args.name}: {d['placements']} placements, {d['measurements']} measurements, "
          f"{d['touches']} touches, {r.seconds:.1f} s; {d['model']}")
    print(f"{'error':6s} {'unit':5s} {'max|injected|':>14s} {'max|ident-inj|':>15s} {'max U95':>9s}")
    for s, e in d["errors"].items():
        inj = max(abs(v) for v in e["injected"])
        u = max(e.get("u95", [float("nan")]))
        print(f"{s:6s} {e['unit']:5s} {inj:14.3f} {e['max_dev']:15.4f} {u:9.3f}")
    print(f"max_dev_um {d['max_dev_um']:.4f}  max_dev_urad {d['max_dev_urad']:.4f}")
    if args.json:
        tmp = args.json + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(d, fh, indent=1)
        os.replace(tmp, args.json)
    return 0


#: name -> runner(args) -> exit code
SCENARIOS = {
    "mfb-3axis": _mfb,
}


def register(sub) -> None:
    p = sub.add_parser("scenario", help="run a named study: simulate, identify, compare with the truth")
    p.add_argument("name", choices=sorted(SCENARIOS), help="scenario name")
    p.add_argument("--json", default=None, help="write the result JSON here")
    p.add_argument("--seed", type=int, default=1, help="seed of the simulated campaign")
    p.add_argument("--noise-um", type=float, default=None, dest="noise_um",
                   help="probe repeatability k=2, um (default 0.25; 0 = noise-free)")
    p.add_argument("--mc", type=int, default=500, help="Monte Carlo trials (0: linear propagation only)")
    p.set_defaults(func=lambda a: SCENARIOS[a.name](a))
