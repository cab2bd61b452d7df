"""``vmt bench``: run every benchmark and write one flat JSON object of figures.

Each benchmark module in ``BENCHES`` exposes ``run() -> dict[str, float]``
returning named figures (speeds as rates or ratios measured side by side in
the same run, since these machines are noisy). Figures are merged into one
flat object; a module that fails records ``<module>_error`` instead of
silently vanishing.
"""

from __future__ import annotations

import importlib
import json
import os
import platform
import tempfile
import time
from pathlib import Path

#: Benchmark modules, each with ``run() -> dict``.
BENCHES: list[str] = [
    "scenarios.bench_fit",
    "scenarios.bench_machine",
    "scenarios.bench_selfcal",
    "scenarios.bench_touch",
    "scenarios.bench_discover",
]


def register(sub) -> None:
    p = sub.add_parser("bench", help="run the benchmarks, write one flat JSON of figures")
    p.add_argument("--out", default="bench/results.json", help="JSON file to write")
    p.add_argument("--only", action="append", default=[], help="run only modules containing this text")
    p.set_defaults(func=run_cli)


def run_all(only: list[str] | None = None) -> dict:
    figures: dict = {"python": platform.python_version(), "cpu_count": os.cpu_count()}
    for mod in BENCHES:
        if only and not any(o in mod for o in only):
            continue
        short = mod.rsplit(".", 1)[-1]
        t0 = time.perf_counter()
        try:
            res = importlib.import_module(mod).run()
        except Exception as e:  # a broken benchmark is a figure too
            figures[f"{short}_error"] = f"{type(e).__name__}: {e}"
            continue
        figures.update(res)
        figures[f"{short}_wall_s"] = round(time.perf_counter() - t0, 3)
    return figures


def run_cli(args) -> int:
    figures = run_all(args.only)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=".bench.")
    with os.fdopen(fd, "w") as f:
        json.dump(figures, f, indent=2, sort_keys=True)
    os.replace(tmp, out)
    for k in sorted(figures):
        print(f"{k:40s} {figures[k]}")
    print(f"wrote {out}")
    return 0
