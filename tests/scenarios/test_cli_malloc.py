"""The ``vmt`` command lets glibc keep freed memory for reuse, unless the user chose (issue 19)."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

import pytest

from scenarios.cli import MALLOC_VARS, MALLOPT, keep_freed_memory

# Fresh interpreter: import the CLI package as the console script does, then
# free a 3 MB array and make another: the minor page faults of the second
# say whether the freed memory was kept (none) or the pages were given back
# and faulted in afresh (768 pages of 4 kB; under 4 MB, so numpy asks for
# no huge pages).
_PROBE = """
import resource, sys
import scenarios.cli
import numpy as np
a = np.ones(3 << 17); del a
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
b = np.ones(3 << 17)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


def _faults(extra: dict[str, str]) -> int:
    env = {k: v for k, v in os.environ.items() if k not in MALLOC_VARS and k != "GLIBC_TUNABLES"}
    env.update(extra)
    out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True)
    return int(out.stdout)


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="the setting is glibc's; elsewhere a no-op")
def test_freed_arrays_are_reused_unless_the_user_chose():
    assert _faults({}) < 50  # kept, reused without faults (measured 0)
    # a user's malloc tunable (one with no effect): glibc left at its defaults, which give the
    # freed array back and fault the next one in (measured 755)
    assert _faults({"GLIBC_TUNABLES": "glibc.malloc.perturb=0"}) > 500
    assert _faults({"MALLOC_MMAP_THRESHOLD_": str(128 << 10)}) > 500  # mapped afresh (measured 769)


class _Libc:
    def __init__(self, ok=1):
        self.calls, self.ok = [], ok

    def mallopt(self, p, v):
        self.calls.append((p, v))
        return self.ok


def test_settings_and_overrides():
    libc = _Libc()
    assert keep_freed_memory({}, libc) is True
    assert libc.calls == list(MALLOPT) == [(-3, 64 << 20), (-1, 256 << 20), (-2, 64 << 20)]
    for env in ({"MALLOC_TOP_PAD_": "0"}, {"MALLOC_TRIM_THRESHOLD_": "1"},
                {"GLIBC_TUNABLES": "glibc.malloc.trim_threshold=1"}):
        libc = _Libc()
        assert keep_freed_memory(env, libc) is False and libc.calls == []
    libc = _Libc()  # blank counts as unset; another tunable is not a malloc choice
    assert keep_freed_memory({"MALLOC_TOP_PAD_": " ", "GLIBC_TUNABLES": "glibc.rtld.nns=2"}, libc) is True
    assert len(libc.calls) == 3
    assert keep_freed_memory({}, _Libc(ok=0)) is False  # glibc refused a value: reported, nothing raised
