"""``vmt check LOG``: validate a probe log and print a short summary."""

from __future__ import annotations

import json


#: ``--json`` given without a value: the old flag (print the JSON), now ``--json -``.
_BARE = "\0bare"


def register(sub) -> None:
    # LOG is required (run refuses without it); it is optional to argparse only so that the old
    # `check --json LOG` (argparse gives LOG to --json) still reads: the usage line says what is asked
    p = sub.add_parser("check", help="validate a probe-log/1 file and summarise it",
                       usage="%(prog)s [-h] [--json [OUT]] LOG")
    p.add_argument("log", metavar="LOG", nargs="?", help="probe-log/1 CSV file (required)")
    p.add_argument("--json", metavar="OUT", nargs="?", const=_BARE, default=None,
                   help="also write the summary as JSON to OUT ('-': print it instead of the text)")
    p.set_defaults(func=run)


def run(args) -> int:
    from core.probelog import read_probe_log, summary

    import sys

    from core.exceptions import ConfigError

    if args.log is None and args.json not in (None, "-", _BARE) and args.json.lower().endswith(".json"):
        raise ConfigError(f"give the LOG to check (--json {args.json} is where the summary goes)")
    if args.json == _BARE or (args.log is None and args.json not in (None, "-")):
        # the old flag: `check LOG --json` (or `check --json LOG`, where argparse took LOG as --json's value)
        print("vmt: check --json with no file is renamed to --json - (print the JSON); --json FILE writes it",
              file=sys.stderr, flush=True)
        if args.json != _BARE:
            args.log = args.json
        args.json = "-"
    if args.log is None:
        raise ConfigError("give the LOG to check: vmt check LOG")
    from scenarios.cli.guard import progress_line

    with progress_line("check: lines read") as bar:  # a 1e6-row log takes some 20 s
        s = summary(read_probe_log(args.log, progress=bar))
    if args.json == "-":
        print(json.dumps(s, indent=2))
        return 0
    if args.json is not None:
        from core.atomic import write_json_atomic
        from scenarios.cli.guard import said

        write_json_atomic(args.json, s, special=True)
    kind = "plan" if s["plan"] else "campaign"
    print(f"{args.log}: valid probe-log/1 {kind}")
    from core.exceptions import counted

    if s["plan"]:
        # a plan has no time and no readings (session 37, audit37: it printed `time 0.0 s`, the span of no
        # touches); its X, Y, Z are the nominal tip centres
        print(f"  plan     {counted(s['touches'], 'touch')} in {counted(s['setups'], 'set-up')}, "
              f"{counted(s['targets'], 'target')}: nothing measured yet")
    else:
        print(f"  touches  {s['touches']} ({s['ok']} ok)   set-ups {s['setups']}   targets {s['targets']}")
        print(f"  time     {s['time_span_s']:.1f} s")
    for ax in ("X", "Y", "Z"):
        r = s[f"{ax}_range_mm"]
        if r:
            print(f"  {ax}        {r[0]:.3f} .. {r[1]:.3f} mm" + (" (nominal)" if s["plan"] else ""))
    for ax in ("A", "B", "C"):
        v = s.get(f"{ax}_values_deg")
        if v:
            shown = ", ".join(f"{x:g}" for x in v[:12]) + (" ..." if len(v) > 12 else "")
            print(f"  {ax}        {shown} deg")
    bad = {k: v for k, v in s["status"].items() if k != "ok"}
    if bad:
        print("  invalid  " + ", ".join(f"{k}: {v}" for k, v in bad.items()))
    rep = s["repeated"]
    if rep["touches"]:
        ex = ", ".join(f"{e['setup']}/{e['target']} x{e['times']}" for e in rep["examples"])
        n = rep["touches"]
        print(f"  repeated {counted(n, 'touch')} {'repeats' if n == 1 else 'repeat'} an earlier (setup, target) "
              f"({counted(rep['pairs'], 'pair')}, "
              f"e.g. {ex}): two writers on one log, or a plan that repeats targets?")
    for t in s["turned_within_setup"]:
        print(f"  turned   set-up {t['setup']!r}: {t['axis']} varies within it ({t['min_deg']:g}..{t['max_deg']:g} "
              f"deg: row {t['first_row']} at {t['first_deg']:g}, row {t['row']} at {t['row_deg']:g}): identify and "
              f"discover take one indexing per set-up and refuse it (a 5-axis placement may turn on purpose)")
    for w in s["warnings"]:
        print(f"  warning  {w}")
    if args.json is not None:
        print(f"wrote {said(args.json)}")
    return 0
