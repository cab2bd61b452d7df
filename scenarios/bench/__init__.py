"""The benchmarks behind ``vmt bench`` / ``make bench``: one flat JSON object of figures.

Each benchmark module in ``BENCHES`` (one module of this package per area)
exposes ``run() -> dict[str, float]`` returning named figures (speeds as
rates or ratios measured side by side in the same run, since these machines
are noisy). Figures are merged into one flat object; a module that fails
records ``bench_<name>_error`` instead of silently vanishing. The command
line (``scenarios.cli.bench``) writes it to ``bench/results.json``.
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
    "scenarios.bench.fit",
    "scenarios.bench.machine",
    "scenarios.bench.selfcal",
    "scenarios.bench.touch",
    "scenarios.bench.discover",
    "scenarios.bench.vcmm",
    "scenarios.bench.probelog",
    "scenarios.bench.discover_study",
    "scenarios.bench.simspeed",
]


def short_name(mod: str) -> str:
    """``bench_<module>``: the prefix of a benchmark's figures in the JSON (``bench_fit_wall_s``)."""
    return "bench_" + mod.rsplit(".", 1)[-1]


def run_all(only: list[str] | None = None) -> dict:
    """Run the benchmarks (those whose module or short name contains a text of ``only``)."""
    figures: dict = {"python": platform.python_version(), "cpu_count": os.cpu_count(),
                     # the BLAS thread count asked for (one unless the user chose: scenarios.cli)
                     "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "unset")}
    for mod in BENCHES:
        short = short_name(mod)
        if only and not any(o in mod or o in short for o in only):
            continue
        t0 = time.perf_counter()
        try:
            res = importlib.import_module(mod).run()
        except Exception as e:  # a broken benchmark is a figure too
            figures[f"{short}_error"] = f"{type(e).__name__}: {e}"
            continue
        figures.update(res)
        figures[f"{short}_wall_s"] = round(time.perf_counter() - t0, 3)
    return figures


def write_figures(figures: dict, out) -> Path:
    """Write ``figures`` as sorted, indented JSON to ``out`` atomically; return the path."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=".bench.")
    with os.fdopen(fd, "w") as f:
        json.dump(figures, f, indent=2, sort_keys=True)
    os.replace(tmp, out)
    return out
