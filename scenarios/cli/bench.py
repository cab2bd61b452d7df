"""``vmt bench``: run the benchmarks (:mod:`scenarios.bench`), write their figures as JSON, and
regenerate the README's performance table from them."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("bench", help="run the benchmarks, write their figures (with same-run references) as JSON")
    from scenarios.cli.options import option

    # --json as in every other command (review32d F9: bench alone wrote its JSON with --out); --out still reads,
    # with a line naming the new option
    option(p, "--json", dest="out", metavar="OUT", default="bench/results.json", old=("--out",),
           help="JSON file to write (bench/results.json)")
    p.add_argument("--only", action="append", default=[],
                   help="run only the benchmarks containing this text (a benchmark's exact name, e.g. "
                        "bench_discover, selects it alone)")
    p.add_argument("--readme", metavar="FILE", default=None,
                   help="also rewrite FILE's performance table (between its bench-table markers) from the JSON")
    p.add_argument("--merge", action="store_true",
                   help="keep the --json file's figures of the benchmarks not run now (each keeps its own run's "
                        "date and load); replace those run now. The --json file must exist: with nothing to "
                        "keep, --merge is refused before any benchmark runs (a table from this run alone would "
                        "drop every other row of --readme)")
    p.add_argument("--from-json", metavar="FILE", default=None,
                   help="run nothing: take the figures of this earlier JSON (with --readme)")
    p.set_defaults(func=run)


def run(args) -> int:
    from pathlib import Path

    from scenarios.bench import BENCHES, _selects, expected_walls, merge_documents, run_all, short_name, write_figures
    from scenarios.bench.table import failed_benchmarks, read_results, update_readme

    from core.exceptions import ConfigError

    if args.from_json is not None:
        if args.readme is None:
            raise ConfigError("--from-json only feeds --readme: give --readme FILE")
        if args.merge or args.only:
            raise ConfigError(f"--from-json runs nothing: {'--merge' if args.merge else '--only'} has no meaning "
                              "with it")
        print(f"wrote {update_readme(args.readme, args.from_json)}")
        return 0
    for o in args.only:     # a text that selects nothing ran nothing and wrote an empty --json (audit37)
        if not any(_selects(o, m, short_name(m)) for m in BENCHES):
            raise ConfigError(f"--only {o!r}: no benchmark's name contains it (the benchmarks: "
                              f"{', '.join(short_name(m) for m in BENCHES)})")
    if args.only and args.readme is not None and not args.merge:
        raise ConfigError("--only with --readme: the table would hold only the benchmarks run now; add --merge "
                          "to keep the others' figures from --json")
    old = None
    if args.merge:
        from core.atomic import output_kind

        kind = output_kind(args.out)
        if kind not in ("missing", "file"):
            # /dev/stdout, a pipe or a device: reading the figures to keep from it would hang or read nothing
            raise ConfigError(f"--merge reads the figures to keep from --json, so --json must be a regular file; "
                              f"{args.out} is a {kind}{' (standard output)' if args.out == '/dev/stdout' else ''}")
        if not Path(args.out).exists():
            raise ConfigError(f"--merge: {args.out} does not exist, so there are no figures to keep (a "
                              "fresh clone has none): run `vmt bench` without --merge (all benchmarks), or "
                              "--json the results file to merge into")
        old = read_results(args.out)
    from scenarios.cli.guard import progress_line

    # the time left from the last run's wall time per benchmark (--json, when it is a readable bench
    # document), else from the benchmarks' count
    earlier = old
    if earlier is None:
        try:
            earlier = read_results(args.out) if Path(args.out).is_file() else None
        except ConfigError:
            earlier = None      # not a bench document: it is replaced, as before
    expected = expected_walls(earlier)
    label = "bench (seconds the last run took)" if expected else "bench (benchmarks)"
    with progress_line(label, counts_seconds=bool(expected)) as bar:
        doc = run_all(args.only, progress=bar, expected=expected)
    out = write_figures(doc if old is None else merge_documents(old, doc), args.out)
    for k, r in sorted(doc["figures"].items()):
        ref = f"   [{r['ratio']} x {r['reference']}]" if r.get("reference") else ""
        print(f"{k:40s} {r['value']}{ref}")
    print(f"wrote {out}")
    if args.readme is not None:
        print(f"wrote {update_readme(args.readme, out)}")
    failed = failed_benchmarks(doc["figures"])
    if failed:  # the figures and table are written (its rows say which failed); the run itself did not succeed
        import sys

        print(f"error: {len(failed)} benchmark(s) failed, their figures missing (see each `NAME_error` above): "
              f"{', '.join(failed)}", file=sys.stderr)
        return 1
    return 0
