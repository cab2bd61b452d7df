"""The benchmarks behind ``vmt bench`` / ``make bench``: every figure with its same-run reference.

Each benchmark module in ``BENCHES`` (one module of this package per area)
exposes ``run() -> dict[str, float]`` returning named figures (speeds as
rates or times measured side by side with a reference in the same run,
since these machines are noisy), and may declare beside it

- ``REFERENCES = {figure: reference_figure}``: the figure of the same run
  it is to be read against (ratio = figure / reference);
- ``TARGETS = {figure: "text"}``: the target it answers (an issue's).

So adding a figure with its reference is one module: a key in ``run()``'s
dict (and the reference's, if new) and one line in ``REFERENCES``.

:func:`run_all` returns one document, ``{"meta": {...}, "figures": {name:
record}}``; every record has ``value`` and ``bench`` (the module), and
``reference``, ``reference_value``, ``ratio`` and ``target`` when declared.
A module that fails records ``bench_<name>_error`` instead of silently
vanishing; each module's wall time is ``bench_<name>_wall_s``. The command
line (``scenarios.cli.bench``) writes it to ``bench/results.json`` and
regenerates the README's performance table from it
(:mod:`scenarios.bench.table`).
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
    "scenarios.bench.mfb",
]


def short_name(mod: str) -> str:
    """``bench_<module>``: the prefix of a benchmark's figures in the JSON (``bench_fit_wall_s``)."""
    return "bench_" + mod.rsplit(".", 1)[-1]


def run_all(only: list[str] | None = None) -> dict:
    """Run the benchmarks (those whose module or short name contains a text of ``only``); the document."""
    meta: dict = {"python": platform.python_version(), "cpu_count": os.cpu_count(),
                  # the BLAS thread count asked for (one unless the user chose: scenarios.cli)
                  "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "unset"),
                  "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
                  "load_average_1min_at_start": round(os.getloadavg()[0], 2)}
    values: dict = {}
    origin: dict = {}
    refs: dict = {}
    targets: dict = {}
    for mod in BENCHES:
        short = short_name(mod)
        if only and not any(o in mod or o in short for o in only):
            continue
        t0 = time.perf_counter()
        try:
            m = importlib.import_module(mod)
            res = m.run()
        except Exception as e:  # a broken benchmark is a figure too
            values[f"{short}_error"] = f"{type(e).__name__}: {e}"
            origin[f"{short}_error"] = short
            continue
        res[f"{short}_wall_s"] = round(time.perf_counter() - t0, 3)
        values.update(res)
        origin.update(dict.fromkeys(res, short))
        refs.update(getattr(m, "REFERENCES", {}))
        targets.update(getattr(m, "TARGETS", {}))
    meta["load_average_1min_at_end"] = round(os.getloadavg()[0], 2)
    return document(meta, values, refs, targets, origin)


def document(meta: dict, values: dict, refs: dict, targets: dict, origin: dict | None = None) -> dict:
    """``{"meta": meta, "figures": {name: record}}`` from flat figure values and their declarations.

    A record is ``{"value", "bench"}`` plus, for a figure in ``refs``,
    ``reference`` (the reference figure's name), ``reference_value`` and
    ``ratio`` = value / reference value (None when either is missing, not a
    number, or the reference is 0), and ``target`` for a figure in ``targets``.
    """
    origin = origin or {}
    figures: dict = {}
    for name, v in values.items():
        rec: dict = {"value": v, "bench": origin.get(name)}
        if name in refs:
            rv = values.get(refs[name])
            num = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (v, rv))
            rec.update(reference=refs[name], reference_value=rv,
                       ratio=round(v / rv, 4) if num and rv else None)
        if name in targets:
            rec["target"] = targets[name]
        figures[name] = rec
    return {"meta": meta, "figures": figures}


def write_figures(figures: dict, out) -> Path:
    """Write the document ``figures`` as sorted, indented JSON to ``out`` atomically; return the path."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=".bench.")
    with os.fdopen(fd, "w") as f:
        json.dump(figures, f, indent=2, sort_keys=True)
    os.replace(tmp, out)
    return out
