"""The ``vmt`` command asks for one BLAS thread before numpy loads, unless the user chose (issue 19)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from scenarios.cli import THREAD_VARS, one_blas_thread

# Runs in a fresh interpreter: import the CLI package as the console script does,
# then numpy, and ask numpy's own OpenBLAS how many threads it will use.
_PROBE = """
import ctypes, glob, os, sys
import scenarios.cli
assert "numpy" not in sys.modules, "numpy loaded before the thread default was set"
import numpy
libs = glob.glob(os.path.join(os.path.dirname(numpy.__file__), "..", "numpy.libs", "libscipy_openblas*.so"))
n = -1
for name in ("scipy_openblas_get_num_threads64_", "scipy_openblas_get_num_threads", "openblas_get_num_threads"):
    for lib in libs:
        f = getattr(ctypes.CDLL(lib), name, None)
        if f is not None:
            n = f()
            break
    if n != -1:
        break
print(os.environ.get("OPENBLAS_NUM_THREADS"), os.environ.get("OMP_NUM_THREADS"), n)
"""


def _run(extra: dict[str, str]) -> list[str]:
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    env.update(extra)
    out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True)
    return out.stdout.split()


def test_default_is_one_thread_before_numpy_loads():
    opb, omp, n = _run({})
    assert (opb, omp) == ("1", "1")
    if n == "-1":
        pytest.fail("cannot find numpy's OpenBLAS to ask its thread count")
    assert n == "1"  # the machine has 2 cores: unset, OpenBLAS would take 2


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: OpenBLAS takes one thread anyway")
def test_user_choice_overrides():
    opb, omp, n = _run({"OPENBLAS_NUM_THREADS": "2"})
    assert (opb, omp, n) == ("2", "None", "2")


def test_any_thread_variable_leaves_all_alone():
    env = {"OMP_NUM_THREADS": "3"}
    assert one_blas_thread(env) is False
    assert env == {"OMP_NUM_THREADS": "3"}
    env = {"OMP_NUM_THREADS": "  "}  # blank counts as unset
    assert one_blas_thread(env) is True
    assert all(env[v] == "1" for v in THREAD_VARS)
