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
import time
from pathlib import Path

#: Format of a bench document (``bench/results.json``: :func:`document`, :func:`merge_documents`).
FORMAT = "vmt-bench/1"
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


def _selects(o: str, mod: str, short: str) -> bool:
    """Whether ``--only o`` selects a module: a module's exact name (``bench_discover``,
    ``scenarios.bench.discover``) selects it alone; any other text, every module containing it."""
    exact = {m for b in BENCHES for m in (b, short_name(b))}
    return o in (mod, short) if o in exact else (o in mod or o in short)


def expected_walls(doc: dict | None) -> dict[str, float]:
    """Each benchmark's wall time in an earlier document (``bench_<module>_wall_s``), by short name."""
    figs = (doc or {}).get("figures", {}) if isinstance(doc, dict) else {}
    walls = {}
    for mod in BENCHES:
        rec = figs.get(f"{short_name(mod)}_wall_s")
        v = rec.get("value") if isinstance(rec, dict) else None
        if isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0:
            walls[short_name(mod)] = float(v)
    return walls


def progress_weights(mods: list[str], expected: dict[str, float] | None) -> list[int]:
    """Whole seconds each benchmark is expected to take (its earlier run's wall time; the median of
    the known ones where it has none), at least 1: so the time left is not a mean over benchmarks
    that last from seconds (fit) to half an hour (the discovery study); all 1 without an earlier run."""
    known = sorted(v for v in (expected or {}).values())
    if not known:
        return [1] * len(mods)
    fill = known[len(known) // 2]
    return [max(1, round((expected or {}).get(short_name(m), fill))) for m in mods]


def run_all(only: list[str] | None = None, progress=None, expected: dict[str, float] | None = None) -> dict:
    """Run the benchmarks (those whose module or short name contains a text of ``only``); the document.

    ``progress(done, total)`` (optional, :mod:`viz.progress`) is called before the first and after
    each benchmark, in expected seconds (:func:`progress_weights` of ``expected``, from
    :func:`expected_walls` of an earlier document) or, without them, in benchmarks.
    """
    meta: dict = {"python": platform.python_version(), "cpu_count": os.cpu_count(),
                  # the BLAS thread count asked for (one unless the user chose: scenarios.cli)
                  "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "unset"),
                  "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
                  "load_average_1min_at_start": round(os.getloadavg()[0], 2)}
    values: dict = {}
    origin: dict = {}
    refs: dict = {}
    targets: dict = {}
    chosen = [mod for mod in BENCHES if not only or any(_selects(o, mod, short_name(mod)) for o in only)]
    weights = progress_weights(chosen, expected)
    done, total = 0, sum(weights)
    if progress is not None:
        progress(done, total)
    for mod, weight in zip(chosen, weights):
        short = short_name(mod)
        t0 = time.perf_counter()
        run = {"date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "invocation_utc": meta["date_utc"],
               "load_average_1min_at_start": round(os.getloadavg()[0], 2)}
        meta.setdefault("runs", {})[short] = run
        try:
            m = importlib.import_module(mod)
            res = m.run()
        except Exception as e:  # a broken benchmark is a figure too
            values[f"{short}_error"] = f"{type(e).__name__}: {e}"
            origin[f"{short}_error"] = short
            run["load_average_1min_at_end"] = round(os.getloadavg()[0], 2)
            done += weight
            if progress is not None:
                progress(done, total)
            continue
        run["load_average_1min_at_end"] = round(os.getloadavg()[0], 2)
        res[f"{short}_wall_s"] = round(time.perf_counter() - t0, 3)
        values.update(res)
        origin.update(dict.fromkeys(res, short))
        refs.update(getattr(m, "REFERENCES", {}))
        targets.update(getattr(m, "TARGETS", {}))
        done += weight
        if progress is not None:
            progress(done, total)
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
    return {"format": FORMAT, "meta": meta, "figures": figures}


def merge_documents(old: dict, new: dict) -> dict:
    """``old`` with the benchmarks of ``new`` replaced: every figure of a benchmark run in
    ``new`` comes from ``new`` (old figures of that benchmark go, even those it no longer
    writes); the others stay as ``old`` measured them, with their run's date and load in
    ``meta["runs"]``. Ratios are never formed across documents: each figure's reference
    belongs to its own benchmark, so to its own run.
    """
    ran = set(new.get("meta", {}).get("runs", {}))
    figures = {k: r for k, r in old.get("figures", {}).items()
               if not (isinstance(r, dict) and r.get("bench") in ran)}
    figures.update(new["figures"])
    runs = {k: v for k, v in old.get("meta", {}).get("runs", {}).items() if k not in ran}
    if not runs and old.get("figures"):  # a document written before meta["runs"] existed
        om = old.get("meta", {})
        for b in {r.get("bench") for r in figures.values() if isinstance(r, dict)} - ran - {None}:
            runs[b] = {k: om.get(k) for k in ("date_utc", "load_average_1min_at_start",
                                              "load_average_1min_at_end")}
    runs.update(new.get("meta", {}).get("runs", {}))
    meta = dict(new.get("meta", {}), runs=dict(sorted(runs.items())))
    return {"format": FORMAT, "meta": meta, "figures": figures}


def write_figures(figures: dict, out) -> Path:
    """Write the document ``figures`` as sorted, indented JSON to ``out`` atomically; return the path.

    Through :func:`core.atomic.write_text_atomic`: only a regular file is replaced, a device or pipe
    (``/dev/stdout``, ``/dev/null``) is written through and a link to anything else refused.
    """
    from core.atomic import write_text_atomic

    return write_text_atomic(Path(out), json.dumps(figures, indent=2, sort_keys=True), special=True)
