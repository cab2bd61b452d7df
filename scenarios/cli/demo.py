"""``vmt demo``: the main job, end to end on a built-in default.

It grows with the project: it always runs the most complete story vmt can
tell today.
"""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the main job end to end (simulate, identify, discover; the same plan through "
                       "vmt probe's interface; the MFB and its compensation closed loop; an ISO 230-2 test and its "
                       "table's closed loop; the virtual CMM on the identified machine; the bar's campaign as a "
                       "probe log through identify and discover; a report)")
    from scenarios.cli.options import option

    option(p, "--out-dir", dest="out_dir", default="out", old=("--out",),
           help="folder for the logs, JSON, report and recording (out)")
    p.add_argument("--seed", type=int, default=2026, help="seed of the simulated campaign")
    p.set_defaults(func=run)


def run(args) -> int:
    from scenarios.demo import main_job
    from scenarios.cli.guard import progress_line

    with progress_line("demo") as bar:
        return main_job(out=args.out_dir, seed=args.seed, progress=bar)
