"""part_change's wall columns made again at each build on a long log (core.causes._part_change_feature): the same
numbers as the held ones, and not held."""
import tracemalloc

import numpy as np

import core.baseline as bl_mod
import core.causes as C
from core.touches import from_log
from scenarios.hidden import hidden_campaign


def _scans(monkeypatch, keep_bytes):
    monkeypatch.setattr(C, "ONE_SCAN_KEEP_BYTES", keep_bytes)
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    scans, _ = next(c for c in C.for_kind("planar") if c.name == "part_change").scans(_scans.bl)
    held = tracemalloc.get_traced_memory()[0] - before
    tracemalloc.stop()
    return scans, held


def test_part_change_lazy_columns_equal_held(monkeypatch):
    log, _ = hidden_campaign(("part_change",), 4077)
    t = from_log(log)
    _scans.bl = bl_mod.planar(t, None, extra=bl_mod.extra_columns(log, t.row))
    held_scans, held_bytes = _scans(monkeypatch, 1 << 40)
    lazy_scans, lazy_bytes = _scans(monkeypatch, 0)
    assert len(held_scans) == len(lazy_scans) > 0
    n_cols = 0
    for a, b in zip(held_scans, lazy_scans):
        assert a.labels == b.labels and a.infos == b.infos
        for idx in ([0], np.arange(a.size)):
            A, B = a.build(idx), b.build(idx)
            assert A.shape == B.shape and np.array_equal(A, B)  # bit for bit
            assert A.dtype == B.dtype and A.tobytes() == B.tobytes()  # (zeros' signs included)
        n_cols += a.build([0]).shape[-1]
    n = _scans.bl.n
    assert held_bytes >= 8 * n * n_cols  # the held path holds every layout's columns
    assert lazy_bytes < 8 * n * n_cols // 4  # the lazy path holds not the layouts' columns (its scans' own ~23 kB)


def test_part_change_lazy_build_makes_only_its_columns(monkeypatch):
    """A layout made again (a long log's build) computes its kept columns into its own array: its traced peak is
    about that array, not the feature's every column, their stack and the kept copy (three times its size or more
    before session 24)."""
    for seed in (4077, 4001):  # 4001's walls turn and bow: layouts of 4, 8 and 12 of its 12 columns
        log, _ = hidden_campaign(("part_change",), seed)
        t = from_log(log)
        _scans.bl = bl_mod.planar(t, None, extra=bl_mod.extra_columns(log, t.row))
        lazy_scans, _ = _scans(monkeypatch, 0)
        n = _scans.bl.n
        for sc in lazy_scans:
            tracemalloc.start()
            A = sc.build([0])
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            assert A.shape[0] == 1 and A.flags.c_contiguous
            # the array and its walls' masks and indexing temporaries (measured 1.75-3.24 columns of n doubles on
            # these 432 rows; 5.1-21.0 before: every column, their stack, the kept copy)
            assert peak < A.nbytes + 4 * 8 * n, (seed, sc.labels, peak, A.nbytes)
