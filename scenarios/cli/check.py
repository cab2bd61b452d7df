"""``vmt check LOG``: validate a probe log and print a short summary."""

from __future__ import annotations

import json


def register(sub) -> None:
    p = sub.add_parser("check", help="validate a probe-log/1 file and summarise it")
    p.add_argument("log", help="probe-log/1 CSV file")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    from core.probelog import read_probe_log, summary

    log = read_probe_log(args.log)
    s = summary(log)
    if args.json:
        print(json.dumps(s, indent=2))
        return 0
    kind = "plan" if s["plan"] else "campaign"
    print(f"{args.log}: valid probe-log/1 {kind}")
    print(f"  touches  {s['touches']} ({s['ok']} ok)   set-ups {s['setups']}   targets {s['targets']}")
    print(f"  time     {s['time_span_s']:.1f} s")
    for ax in ("X", "Y", "Z"):
        r = s[f"{ax}_range_mm"]
        if r:
            print(f"  {ax}        {r[0]:.3f} .. {r[1]:.3f} mm")
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
        print(f"  repeated {rep['touches']} touches repeat an earlier (setup, target) ({rep['pairs']} pairs, "
              f"e.g. {ex}): two writers on one log, or a plan that repeats targets?")
    for w in s["warnings"]:
        print(f"  warning  {w}")
    return 0
