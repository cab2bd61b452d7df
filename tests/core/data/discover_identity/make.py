"""Write the discovery identity references: campaigns and the reports main's engine gave on them.

Run from the repository root with the engine whose reports are the
reference (issue 19 item 6: main at 2a7a508, before discover's numerical
kernels were rewritten):

    python tests/core/data/discover_identity/make.py          # the reports, from the stored logs
    python tests/core/data/discover_identity/make.py --logs   # the logs too (simulated, generated)

Each campaign's probe log is kept (gzip CSV, the data contract's text), so
the test reads the same touches whatever the simulator or the generators
become; ``reports.json.gz`` holds ``discover(...).to_report()`` of each.
A change meant to change discover's answers (a decision rule) rewrites
the reports with the first command once it is reviewed; a change of its
numerical kernels must leave them as they are.
"""

from __future__ import annotations

import gzip
import json
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent

#: (name, generator, effect, seed): the demo's campaign, the hidden simulator's
#: effects (catalogue, not nameable), the blind generators' (catalogue, new
#: named, out of catalogue), none made for this test.
CAMPAIGNS = (
    ("demo", "demo", "", 0),
    ("hidden-none-1000", "hidden", "none", 1000),
    ("hidden-periodic_axis_error-1000", "hidden", "periodic_axis_error", 1000),
    ("hidden-lobing_per_setup-1000", "hidden", "lobing_per_setup", 1000),
    ("hidden-thermal_drift-1001", "hidden", "thermal_drift", 1001),
    ("hidden-outlier-1002", "hidden", "outlier", 1002),
    ("hidden-c_drift-1003", "hidden", "c_drift", 1003),
    ("gen_a-probe_lobing-302", "gen_a", "probe_lobing", 302),
    ("gen_a-reseat_hysteresis-502", "gen_a", "reseat_hysteresis", 502),
    ("gen_a-thermal_bending-604", "gen_a", "thermal_bending", 604),
    ("gen_a-knock-1", "gen_a", "knock", 1),
    ("gen_a-nonrigid-2", "gen_a", "nonrigid", 2),
    ("gen_b-fixture_slip-500", "gen_b", "fixture_slip", 500),
    ("gen_b-fixture_slip-301", "gen_b", "fixture_slip", 301),
    ("gen_b-stylus_pickup-501", "gen_b", "stylus_pickup", 501),
    ("gen_b-head_tram-3", "gen_b", "head_tram", 3),
)


def campaign_log(gen: str, effect: str, seed: int):
    """The probe log of one campaign (simulated or generated)."""
    if gen == "demo":
        from scenarios.bench.discover import demo_campaign_log
        return demo_campaign_log()
    if gen == "hidden":
        from scenarios.hidden import hidden_campaign
        return hidden_campaign((effect,), seed)[0]
    from scenarios.blind import gen_a, gen_b
    return {"gen_a": gen_a, "gen_b": gen_b}[gen].generate(effect, seed)[0]


def report_of(log) -> dict:
    """discover's report on a log, as plain JSON values (what the CLI writes)."""
    from core.baseline import extra_columns
    from core.discover import discover
    from core.touches import from_log

    t = from_log(log)
    rep = discover(t, chain=log.meta.get("kinematic_chain"), extra=extra_columns(log, t.row)).to_report()
    return json.loads(json.dumps(rep, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))


def main() -> None:
    sys.path.insert(0, str(HERE.parents[3]))
    from core.probelog import format_probe_log

    reports = {}
    for name, gen, effect, seed in CAMPAIGNS:
        if "--logs" in sys.argv[1:]:
            log = campaign_log(gen, effect, seed)
            (HERE / f"{name}.csv.gz").write_bytes(gzip.compress(format_probe_log(log).encode(), mtime=0))
        reports[name] = report_of(read_log(name))  # from the stored text: what the test reads
        print(name, [f["cause"] for f in reports[name]["findings"]])
    (HERE / "reports.json.gz").write_bytes(gzip.compress(json.dumps(reports, sort_keys=True).encode(), mtime=0))


def read_log(name: str):
    from core.probelog import parse_probe_log
    return parse_probe_log(gzip.decompress((HERE / f"{name}.csv.gz").read_bytes()).decode(), name)


if __name__ == "__main__":
    main()
