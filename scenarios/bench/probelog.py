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


def write_large_log(path, n_targets: int, n_angles: int, rng: np.random.Generator, block: int = 50_000) -> int:
    """Write a self-calibration campaign of ``n_targets * n_angles`` touches; return the row count.

    Targets on random radii 20..95 mm with random in-plane normals, probed at
    ``n_angles`` C angles with 1 um normal noise; rows are written in blocks
    of ``block`` with :func:`core.probelog.format_probe_log` (metadata and
    header once), so the text never sits in memory whole.
    """
    from core.probelog import format_probe_log, make_log
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
    with open(path, "w", encoding="utf-8") as f:
        for i in range(0, n, block):
            text = format_probe_log(make_log({k: v[i:i + block] for k, v in cols.items()},
                                             {"artefact": "bench"}, validate=False))
            if i:  # metadata and header only once
                text = text[text.index("\n", text.index("\nsetup,") + 1) + 1:]
            f.write(text)
    return n


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
    "touches": ("from core.probelog import read_probe_log\nfrom core.touches import from_log\n"
                "log = read_probe_log(sys.argv[1])\nt = from_log(log.select(abs(log.col('nz')) <= 0.01))"),
}


def _child(what: str, path) -> tuple[float, float]:
    """(wall time s, peak resident memory MB) of ``_WORK[what]`` in a fresh interpreter."""
    out = subprocess.run([sys.executable, "-c", _CHILD.format(work=_WORK[what]), str(path)],
                         capture_output=True, text=True, check=True)
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
        t0 = time.perf_counter()
        n = write_large_log(path, N_TARGETS, N_ANGLES, np.random.default_rng(19))
        out["log_1e6_write_s"] = round(time.perf_counter() - t0, 2)
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
    return out


if __name__ == "__main__":  # pragma: no cover - by hand: python -m scenarios.bench.probelog
    print(json.dumps(run(), indent=2))
