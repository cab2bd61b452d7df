"""``vmt bench``: run every benchmark (:mod:`scenarios.bench`) and write one flat JSON of figures."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("bench", help="run the benchmarks, write one flat JSON of figures")
    p.add_argument("--out", default="bench/results.json", help="JSON file to write")
    p.add_argument("--only", action="append", default=[], help="run only modules containing this text")
    p.set_defaults(func=run)


def run(args) -> int:
    from scenarios.bench import run_all, write_figures

    figures = run_all(args.only)
    out = write_figures(figures, args.out)
    for k in sorted(figures):
        print(f"{k:40s} {figures[k]}")
    print(f"wrote {out}")
    return 0
