"""``vmt regress STUDY.toml [--junit OUT.xml] [--json OUT.json]``: are the injected errors still recovered?

Runs a study file (format ``vmt-study/1``, :mod:`scenarios.regress`): one
simulated campaign and one identification per seed, every identified
quantity compared with the injected truth in the identification's gauge
and ISO 230-1 sign convention, each against its acceptance rule. Prints a
table (quantity, seed, where, injected, identified, U95, limit, verdict).
Exit status 0 when every quantity passes, 1 when one fails, 2 for bad
input (a malformed study, an unknown machine or quantity).
"""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("regress", help="run a regression study: inject known errors, identify, check recovery",
                       description=__doc__.split("\n\n")[1])
    p.add_argument("study", help="study file (TOML, format vmt-study/1; README 'Regression studies')")
    p.add_argument("--junit", metavar="OUT", help="JUnit XML to write (one test case per quantity and seed)")
    p.add_argument("--json", metavar="OUT", help="JSON report to write (every check, with its margin)")
    p.set_defaults(func=run)


def run(args) -> int:
    from core.atomic import write_json_atomic, write_text_atomic
    from scenarios.cli.guard import progress_line, said
    from scenarios.regress import junit_xml, load_study, run_study

    study = load_study(args.study)
    seeds = f"{len(study.seeds)} seed{'s' if len(study.seeds) != 1 else ''}"
    with progress_line(f"regress ({seeds}): % of the work") as bar:
        res = run_study(study, progress=bar)
    print(f"{args.study}: {study.name} ({study.identification} on {study.machine.config.name}, "
          f"seeds {', '.join(map(str, study.seeds))}, noise {study.noise_um:g} um k=1"
          + (", MUTATED: " + ", ".join([f"flip_sign {q}" for q in study.mutation.flip_sign]
                                       + [f"scale {q} x {c:g}" for q, c in study.mutation.scale]
                                       + [f"drop {q}" for q in study.mutation.drop]
                                       + (["planar model"] if study.mutation.planar else [])) if study.mutation else "")
          + ")")
    print(res.table())
    for line in res.sign_untestable() + res.gain_power():
        print(line)
    written = []
    if args.json:
        written.append(write_json_atomic(args.json, res.to_json(), special=True))
    if args.junit:
        written.append(write_text_atomic(args.junit, junit_xml(res), special=True))
    for c in res.failures:
        print(f"FAIL {c.message()}")
    n, f = len(res.checks), len(res.failures)
    print(f"{n - f} of {n} checks passed" + (f"; {f} failed" if f else "")
          + (f"; wrote {', '.join(said(p) for p in written)}" if written else ""))
    return 0 if res.passed else 1
