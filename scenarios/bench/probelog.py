"""Large probe logs: time and peak memory to read and check a 1e6-row ``probe-log/1`` file.

A campaign of 10,000 targets at 100 C angles (1e6 touches, the 20 columns
``vmt identify`` reads plus ``status``) is written with the library's own
writer, block by block, to a temporary file. Then, each in a fresh
interpreter so that its peak resident memory is its own:

- ``log_1e6_check_peak_mb``: ``vmt check LOG --json``;
- ``log_1e6_touches_peak_mb``: reading it and converting it to SI touches
  (what ``vmt identify`` does before it solves);
- ``python_numpy_baseline_mb``: the same interpreter importing the CLI and
  numpy only (the reference the two above are read against).

Speed: ``log_1e6_check_s`` (the whole ``vmt check``) beside
``log_1e6_csv_split_s`` (the same file split into cells by ``csv.reader``
alone, no number parsing or validation, in this process), and their ratio.

Discovery: ``log_1e5_discover_peak_mb`` and ``log_1e5_discover_s``, ``vmt
discover`` of a 1e5-row campaign (1,000 targets at 100 C angles, the same
generator) in a fresh interpreter limited to :data:`DISCOVER_GUARD_MB` of
address space (the machine is shared) and :data:`DISCOVER_TIMEOUT_S` of
wall time: a run that does not fit or finish reports None and the reason
in ``log_1e5_discover_error``. ``log_1e6_discover_peak_mb`` likewise on the
1e6-row file under the target itself (:data:`DISCOVER_1E6_GUARD_MB`): its
figure, or None and the reason in ``log_1e6_discover_error``.

The long-log path against the dense one, on a 1e4-row campaign (100
targets at 100 C angles: its design, 33 MB, is below
:data:`core.baseline.DENSE_DESIGN_BYTES`, so ``vmt discover`` takes it
dense): ``log_1e4_discover_blocks_peak_mb`` and ``_s``, the same command
forced through the block design (the threshold set to 0 in the child),
read against ``log_1e4_discover_dense_peak_mb`` and ``_s``; both children
must write the same findings (else the figure is refused).

Writing: ``log_1e6_write_s``, the 1e6-row file written by
:func:`core.probelog.write_probe_log` (streamed block by block). On the
1e5-row campaign (written once: the streamed writer's file is the one
discover reads), beside the previous writer (:func:`previous_format`: one
``csv.writer`` row per touch, the whole text in memory, then written):
``log_1e5_write_s`` / ``log_1e5_write_previous_s`` (time) and
``log_1e5_write_peak_mb`` / ``log_1e5_write_previous_peak_mb`` (peak of
Python's allocations while writing, tracemalloc, the log's columns
already in memory): the streamed writer's peak is one block of text
whatever the row count, the previous one's the whole file twice.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

N_TARGETS, N_ANGLES = 10_000, 100


#: figure -> its reference figure measured in the same run (ratio = figure / reference)
REFERENCES = {
    "log_1e6_check_s": "log_1e6_csv_split_s",
    "log_1e6_check_peak_mb": "python_numpy_baseline_mb",
    "log_1e6_touches_peak_mb": "python_numpy_baseline_mb",
    "log_1e5_discover_peak_mb": "python_numpy_baseline_mb",
    "log_1e6_discover_peak_mb": "python_numpy_baseline_mb",
    "log_1e5_write_s": "log_1e5_write_previous_s",
    "log_1e4_discover_blocks_peak_mb": "log_1e4_discover_dense_peak_mb",
    "log_1e4_discover_blocks_s": "log_1e4_discover_dense_s",
    "log_1e5_write_peak_mb": "log_1e5_write_previous_peak_mb",
}
TARGETS = {"log_1e6_check_peak_mb": "< 2048 MB (issue 19 item 2)",
           "log_1e6_touches_peak_mb": "< 2048 MB (issue 19 item 2)",
           "log_1e5_discover_peak_mb": "< 2048 MB (issue 19 item 2)",
           "log_1e6_discover_peak_mb": "< 2048 MB (issue 19 item 2)"}
#: Address-space limit of the discover child (MB): beyond it the run stops with a MemoryError.
DISCOVER_GUARD_MB = 6144
#: The 1e6-row discover child's address-space limit (MB: the target).
DISCOVER_1E6_GUARD_MB = 2048
#: Wall-time limit of either discover child (s): beyond it the run is stopped and reported as not finished.
DISCOVER_TIMEOUT_S = 1800


def large_log(n_targets: int, n_angles: int, rng: np.random.Generator):
    """A self-calibration campaign of ``n_targets * n_angles`` touches as a ProbeLog (file units).

    Targets on random radii 20..95 mm with random in-plane normals, probed at
    ``n_angles`` C angles with 1 um normal noise.
    """
    from core.probelog import make_log
    from core.selfcal import nominal_touches

    r = rng.uniform(0.02, 0.095, n_targets)
    a = rng.uniform(0, 2 * np.pi, n_targets)
    b = rng.uniform(0, 2 * np.pi, n_targets)
    w = np.column_stack([r * np.cos(a), r * np.sin(a)])
    wn = np.column_stack([np.cos(b), np.sin(b)])
    c = np.round(np.linspace(0, 360, n_angles, endpoint=False) + 7.0, 3)
    t = nominal_touches(w, wn, c, stylus_r_m=0.003)
    n = t.n
    p = t.pn_R + rng.normal(0, 1e-6, n)[:, None] * t.n_R
    z = np.zeros(n)
    cols = {"setup": np.array(t.setup_ids, dtype=object)[t.setup],
            "target": np.array(t.target_ids, dtype=object)[t.target],
            "t_s": np.arange(n) * 0.5, "X_mm": p[:, 0] * 1e3, "Y_mm": p[:, 1] * 1e3, "Z_mm": z,
            "Xn_mm": t.pn_R[:, 0] * 1e3, "Yn_mm": t.pn_R[:, 1] * 1e3, "Zn_mm": z,
            "nx": t.n_R[:, 0], "ny": t.n_R[:, 1], "nz": z, "C_deg": np.degrees(t.rot_rad[:, 2]),
            "wx_mm": t.w_A[:, 0] * 1e3, "wy_mm": t.w_A[:, 1] * 1e3, "wz_mm": z,
            "wnx": t.wn_A[:, 0], "wny": t.wn_A[:, 1], "wnz": z, "status": np.full(n, "ok", dtype=object)}
    return make_log(cols, {"artefact": "bench"}, validate=False)


def previous_format(log) -> str:
    """The probe-log text as :func:`core.probelog.format_probe_log` built it before it streamed:
    one ``csv.writer`` row per touch into one in-memory text (the reference of the writer's figures)."""
    import csv
    import io

    from core import probelog as P

    buf = io.StringIO()
    buf.write(next(P.iter_probe_log_text(log)))  # metadata and header, as before
    cols = P._ordered(dict(log.columns))
    w = csv.writer(buf, lineterminator="\n")
    text = {k: P._is_text_column(k, v) for k, v in cols.items()}
    for r in range(log.n):
        w.writerow([v[r] if text[k] else P._fmt(v[r]) for k, v in cols.items()])
    return buf.getvalue()


def _write_figures(log, d) -> dict:
    """Time and traced peak of the streamed writer and of the previous one on the same rows."""
    import tracemalloc

    from core.atomic import write_text_atomic
    from core.probelog import format_probe_log, write_probe_log

    new, old = Path(d) / "new.csv", Path(d) / "old.csv"
    out = {}
    for name, f in (("log_1e5_write", lambda: write_probe_log(new, log)),
                    ("log_1e5_write_previous", lambda: write_text_atomic(old, previous_format(log)))):
        t0 = time.perf_counter()
        f()
        out[f"{name}_s"] = round(time.perf_counter() - t0, 2)
        tracemalloc.start()
        f()
        out[f"{name}_peak_mb"] = round(tracemalloc.get_traced_memory()[1] / 2**20, 1)
        tracemalloc.stop()
    if new.read_text(encoding="utf-8") != old.read_text(encoding="utf-8") or \
            format_probe_log(log) != previous_format(log):  # a faster writer of another text is no figure
        raise RuntimeError("the streamed probe-log writer's text differs from the previous writer's")
    return out


# run in a fresh interpreter: the work, then its wall time (s) and its own peak RSS (kB): VmHWM of
# /proc/self/status, not getrusage's ru_maxrss, which keeps the forking parent's peak across exec
_CHILD = """
import sys, time
import scenarios.cli
t0 = time.perf_counter()
{work}
dt = time.perf_counter() - t0
hwm = [ln.split()[1] for ln in open("/proc/self/status") if ln.startswith("VmHWM:")][0]
print(dt, hwm)
"""
_WORK = {
    "baseline": "import numpy",
    "check": "from scenarios.cli import main\nassert main(['check', sys.argv[1], '--json']) == 0",
    "discover": ("import resource\nlim = int(sys.argv[2]) << 20\nresource.setrlimit(resource.RLIMIT_AS, (lim, lim))\n"
                 "from scenarios.cli import main\nassert main(['discover', sys.argv[1], '--json', sys.argv[1] + '.json']) == 0"),
    # argv: log, json out, the dense design's threshold (bytes; 0 forces the block design)
    "discover_at": ("import core.baseline\ncore.baseline.DENSE_DESIGN_BYTES = int(sys.argv[3])\n"
                    "from scenarios.cli import main\nassert main(['discover', sys.argv[1], '--json', sys.argv[2]]) == 0"),
    "touches": ("from core.probelog import read_probe_log\nfrom core.touches import from_log\n"
                "log = read_probe_log(sys.argv[1])\nt = from_log(log.select(abs(log.col('nz')) <= 0.01))"),
}


def _child(what: str, path, *args, timeout: float | None = None) -> tuple[float, float]:
    """(wall time s, peak resident memory MB) of ``_WORK[what]`` in a fresh interpreter (stopped after ``timeout``
    s)."""
    out = subprocess.run([sys.executable, "-c", _CHILD.format(work=_WORK[what]), str(path), *map(str, args)],
                         capture_output=True, text=True, check=True, timeout=timeout)
    t, kb = out.stdout.split()[-2:]
    return float(t), round(int(kb) / 1024, 1)


def _csv_split(path) -> int:
    """Rows of the file split into cells by ``csv.reader`` alone (the reference of the reading speed)."""
    import csv

    with open(path, newline="", encoding="utf-8") as f:
        return sum(1 for row in csv.reader(ln for ln in f if not ln.startswith("#")))


def run() -> dict:
    out: dict = {}
    with tempfile.TemporaryDirectory(prefix="vmt-bench-log.") as d:
        path = Path(d) / "campaign-1e6.csv"
        from core.probelog import write_probe_log

        log = large_log(N_TARGETS, N_ANGLES, np.random.default_rng(19))
        n = log.n
        t0 = time.perf_counter()
        write_probe_log(path, log)
        out["log_1e6_write_s"] = round(time.perf_counter() - t0, 2)
        del log
        # the 1e5-row campaign, written once (by both writers, timed): discover reads the streamed writer's file
        log5 = large_log(1_000, N_ANGLES, np.random.default_rng(19))
        out.update(_write_figures(log5, d))
        del log5
        out.update(_dense_and_blocks(Path(d)))
        out["log_1e6_rows"] = n
        out["log_1e6_file_mb"] = round(os.path.getsize(path) / 2**20, 1)
        t0 = time.perf_counter()
        assert _csv_split(path) == n + 1  # the header and every row
        t_ref = time.perf_counter() - t0
        _, out["python_numpy_baseline_mb"] = _child("baseline", path)
        t_check, out["log_1e6_check_peak_mb"] = _child("check", path)
        t_touch, out["log_1e6_touches_peak_mb"] = _child("touches", path)
        out["log_1e6_csv_split_s"] = round(t_ref, 2)
        out["log_1e6_check_s"] = round(t_check, 2)
        out["log_1e6_check_over_csv_split"] = round(t_check / t_ref, 2)
        out["log_1e6_touches_s"] = round(t_touch, 2)
        out.update(_discover_figures(Path(d) / "new.csv", "log_1e5", DISCOVER_GUARD_MB, DISCOVER_TIMEOUT_S))
        out.update(_discover_figures(path, "log_1e6", DISCOVER_1E6_GUARD_MB, DISCOVER_TIMEOUT_S))
    return out


def _findings(path) -> list:
    rep = json.loads(Path(path).read_text(encoding="utf-8"))
    return [(f["cause"], f["evidence"].get("confidence")) for f in rep["findings"]] + [rep["structure"]["baseline"]["present"]]


def _dense_and_blocks(d: Path) -> dict:
    """``vmt discover`` of a 1e4-row campaign dense and forced through the block design (module docstring)."""
    from core.baseline import DENSE_DESIGN_BYTES
    from core.probelog import write_probe_log

    path = d / "campaign-1e4.csv"
    write_probe_log(path, large_log(100, N_ANGLES, np.random.default_rng(19)))
    out = {}
    for name, limit in (("dense", DENSE_DESIGN_BYTES), ("blocks", 0)):
        t, out[f"log_1e4_discover_{name}_peak_mb"] = _child("discover_at", path, d / f"{name}.json", limit)
        out[f"log_1e4_discover_{name}_s"] = round(t, 2)
    if _findings(d / "dense.json") != _findings(d / "blocks.json"):
        raise RuntimeError("discover forced through the block design finds otherwise than dense on the 1e4-row log")
    return out


def _discover_figures(path, name: str, guard_mb: int, timeout_s: float | None = None) -> dict:
    """``vmt discover`` of ``path`` in a guarded fresh interpreter: ``{name}_discover_s`` and ``_peak_mb``,
    or None for both and ``{name}_discover_error`` saying why it did not finish (see the module docstring)."""
    try:
        t, mb = _child("discover", path, guard_mb, timeout=timeout_s)
        return {f"{name}_discover_s": round(t, 2), f"{name}_discover_peak_mb": mb}
    except subprocess.CalledProcessError as e:  # did not fit under the guard: no figure, the reason
        last = (e.stderr or e.stdout or "").strip().splitlines()[-1:] or ["no output"]
        why = f"exit {e.returncode} under a {guard_mb} MB limit: {last[0][:200]}"
    except subprocess.TimeoutExpired:
        why = f"not finished in {timeout_s:g} s (stopped)"
    return {f"{name}_discover_s": None, f"{name}_discover_peak_mb": None, f"{name}_discover_error": why}

if __name__ == "__main__":  # pragma: no cover - by hand: python -m scenarios.bench.probelog
    print(json.dumps(run(), indent=2))
