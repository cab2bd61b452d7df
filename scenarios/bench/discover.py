"""Benchmark of model discovery: one cross-pocket campaign (432 touches)."""

from __future__ import annotations

import time


def run() -> dict:
    from core.discover import discover
    from core.touches import from_log
    from scenarios.hidden import hidden_campaign

    log, _ = hidden_campaign(("probe_lobing",), 3)
    t = from_log(log)
    t0 = time.perf_counter()
    for _ in range(3):
        d = discover(t)
    dt = (time.perf_counter() - t0) / 3
    if d.cause != "probe_lobing":  # a benchmark of a wrong answer is no figure
        raise RuntimeError(f"discover named {d.cause!r} for a hidden probe_lobing")
    return {"discover_cross_pocket_s": round(dt, 3), "discover_touches": t.n}
