"""Every entry point runs on one BLAS thread, the studies' ``python -m scenarios.<study>`` too (review31d F14).

Each study is started as documented (README, docs/formats.md), ``python -m scenarios.<study> --help``, in a fresh
interpreter; a ``sitecustomize`` on the path (loaded at start-up, before the study, importing nothing but os,
sys and atexit) asks numpy's own OpenBLAS at exit (loading numpy then where the study had not) how many threads it runs (threadpoolctl when installed, else
the library's ``openblas_get_num_threads``) and prints it with the environment's ``OPENBLAS_NUM_THREADS``.
Before the pin moved into ``scenarios/__init__.py`` only ``scenarios.cli`` set it: the studies ran 2 threads
on this 2-core machine.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from scenarios import THREAD_VARS

ROOT = Path(__file__).resolve().parents[2]

#: The studies run as ``python -m`` (each has a ``__main__`` with argparse), and the CLI for contrast.
STUDIES = ("mfb_coverage", "selfcal_coverage", "comprule_study", "mfb_ripple_coverage", "mfb_range_study",
           "mfb_fit_study", "cli")  # (positioning_sample has no --help: it rewrites its packaged file)

_SITE = '''
import atexit, os, sys

def _report():
    n = -1
    try:
        import threadpoolctl
        n = sum(p["num_threads"] for p in threadpoolctl.threadpool_info() if p["internal_api"] == "openblas")
    except ImportError:
        import ctypes, glob
        import numpy  # (a usage message or --help may not have loaded it: the environment decides as it loads)
        libs = glob.glob(os.path.join(os.path.dirname(numpy.__file__), "..", "numpy.libs", "libscipy_openblas*.so"))
        for name in ("scipy_openblas_get_num_threads64_", "scipy_openblas_get_num_threads",
                     "openblas_get_num_threads"):
            f = next((getattr(ctypes.CDLL(lib), name) for lib in libs if hasattr(ctypes.CDLL(lib), name)), None)
            if f is not None:
                n = f()
                break
    print("THREADS", n, os.environ.get("OPENBLAS_NUM_THREADS"), flush=True)

atexit.register(_report)
'''


def _threads(tmp_path, study: str, extra: dict[str, str]) -> tuple[str, str]:
    (tmp_path / "sitecustomize.py").write_text(_SITE)
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    env.update(extra)
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), str(ROOT)])
    out = subprocess.run([sys.executable, "-m", f"scenarios.{study}", "--help"], env=env, cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode in (0, 2), out.stderr[-2000:]  # 2: a study's own usage line (no argparse --help)
    line = [s for s in out.stdout.splitlines() if s.startswith("THREADS")]
    assert line, out.stdout[-2000:]
    _, n, opb = line[-1].split()
    return n, opb


@pytest.mark.parametrize("study", STUDIES)
def test_python_m_study_runs_one_blas_thread(tmp_path, study):
    n, opb = _threads(tmp_path, study, {})
    assert opb == "1"
    if n == "-1":
        pytest.fail("cannot find numpy's OpenBLAS to ask its thread count")
    assert n == "1"


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: OpenBLAS takes one thread anyway")
def test_a_users_thread_count_is_kept(tmp_path):
    assert _threads(tmp_path, "mfb_coverage", {"OPENBLAS_NUM_THREADS": "2"}) == ("2", "2")
