"""Session 24: a long log's narrow matrices normed, projected out of a block basis and rotated a block of rows at a
time (core.diagnosis.col_norms, project_out, new_basis; core.lsq.Basis.subtract_matmul), and group_sums of a large
dense block by the indicators' CSR product: the same numbers bit for bit as the whole arrays' operations."""
import json

import numpy as np
import pytest
import scipy.sparse as sp

import core.baseline as Bm
import core.diagnosis as Dg
import core.lsq as L
from tests.discover_helpers import discovered


def _whole_norms(M):
    return np.sqrt(np.add.reduce(M * M, axis=0))


def test_col_norms_in_blocks_are_the_whole_reduction(monkeypatch):
    rng = np.random.default_rng(24)
    monkeypatch.setattr(Dg, "LONG_BYTES", 0)
    for _ in range(200):
        n, k = int(rng.integers(1, 30000)), int(rng.integers(2, 13))
        monkeypatch.setattr(Dg, "LONG_ROWS", int(rng.integers(1, 9000)))
        M = rng.standard_normal((n, k)) * 10.0 ** rng.uniform(-8, 8, size=(n, 1))
        assert Dg.col_norms(M).tobytes() == _whole_norms(M).tobytes()
    # one column is reduced pairwise: left whole (blocks would differ), as are wide and non-C-ordered matrices
    M = rng.standard_normal((20000, 1)) * 10.0 ** rng.uniform(-8, 8, size=(20000, 1))
    assert Dg.col_norms(M).tobytes() == _whole_norms(M).tobytes()


def test_rotation_in_place_is_the_product(monkeypatch):
    rng = np.random.default_rng(7)
    for _ in range(30):
        n, k = int(rng.integers(50, 20000)), int(rng.integers(2, 10))
        Q = np.linalg.qr(rng.standard_normal((n, 5)))[0]
        B = rng.standard_normal((n, k)) * 10.0 ** rng.uniform(-3, 3, size=(1, k))
        if k > 3:
            B[:, -1] = B[:, 0] + 1e-9 * B[:, 1]  # a direction new_basis drops: fewer columns out than in
        monkeypatch.setattr(Dg, "LONG_BYTES", 1 << 60)
        ref = Dg.new_basis(Q, B.copy())
        monkeypatch.setattr(Dg, "LONG_BYTES", 0)
        monkeypatch.setattr(Dg, "LONG_ROWS", int(rng.integers(1, 3000)))
        got = Dg.new_basis(Q, B.copy(), inplace=True)
        assert got.shape == ref.shape and got.tobytes() == ref.tobytes()


def test_group_sums_of_many_cells_by_the_csr_product(monkeypatch):
    rng = np.random.default_rng(3)
    ids = rng.integers(0, 40, 5000)
    X = rng.standard_normal((5000, 6)) * 10.0 ** rng.uniform(-8, 8, size=(5000, 1))
    a = L.group_sums(ids, 40, X)
    monkeypatch.setattr(L, "GROUP_CELLS_MAX", 10)
    b = L.group_sums(ids, 40, X)
    G = sp.csr_matrix((np.ones(5000), (ids, np.arange(5000))), shape=(40, 5000))
    assert a.tobytes() == b.tobytes() == np.asarray(G @ X).tobytes()


def _block_state():
    """A campaign's baseline forced through the block design (a long log's path): its model basis a Basis."""
    from core.touches import from_log
    from scenarios.hidden import hidden_campaign

    log, _ = hidden_campaign(("part_change",), 4077)
    t = from_log(log)
    return log, t


def test_subtract_matmul_is_the_basis_product(monkeypatch):
    monkeypatch.setattr(Bm, "DENSE_DESIGN_BYTES", 0)
    log, t = _block_state()
    bl = Bm.planar(t, None, extra=Bm.extra_columns(log, t.row))
    assert isinstance(bl.A, L.BlockDesign)
    Q0 = bl.A.basis()
    rng = np.random.default_rng(5)
    for Q in (Q0, Q0.hstack(np.linalg.qr(rng.standard_normal((bl.n, 3)))[0])):  # with dense columns as well
        for rows in (7, 100, 8192):
            B = rng.standard_normal((bl.n, 6))
            c = Q.T @ B
            ref = B - Q @ c
            got = Q.subtract_matmul(c, B.copy(), rows)
            assert got.tobytes() == ref.tobytes()


@pytest.mark.parametrize("seed", [4077, 4001])
def test_discover_with_every_block_path_forced(monkeypatch, seed):
    """The whole discovery of a block-design campaign with the blocks forced on every narrow matrix (of 7 rows) gives
    the report of the whole arrays' operations, byte for byte."""
    from core.touches import from_log
    from scenarios.hidden import hidden_campaign

    monkeypatch.setattr(Bm, "DENSE_DESIGN_BYTES", 0)
    log, _ = hidden_campaign(("part_change",), seed)
    t = from_log(log)
    run = lambda: json.dumps(discovered(log, t).to_report(), sort_keys=True, default=str)  # noqa: E731
    monkeypatch.setattr(Dg, "LONG_BYTES", 1 << 60)
    monkeypatch.setattr(L, "GROUP_CELLS_MAX", 1 << 60)
    ref = run()
    monkeypatch.setattr(Dg, "LONG_BYTES", 0)
    monkeypatch.setattr(Dg, "LONG_ROWS", 7)
    monkeypatch.setattr(L, "GROUP_CELLS_MAX", 0)
    assert run() == ref


def test_drift_polynomial_layout_a_mode_at_a_time():
    """core.causes.drift_rebuild's polynomial layout written a mode at a time: the modes' outer product with the
    Legendre columns byte for byte, without the (n, 4) modes held beside it."""
    import tracemalloc

    import core.causes as C
    from core.touches import from_log
    from scenarios.hidden import hidden_campaign

    log, _ = hidden_campaign(("thermal_drift",), 4001)
    t = from_log(log)
    bl = Bm.planar(t, None, extra=Bm.extra_columns(log, t.row))
    d = bl.data
    modes = np.column_stack([-d.nx, -d.ny, -d.nx * d.xs, -d.ny * d.ys])
    for deg in (1, 2, 3):
        ref = C._outer(modes, C._legendre(2 * d.tau - 1, deg))[None]
        tracemalloc.start()
        got = C.drift_rebuild(bl, {"degree": deg})
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert got.shape == ref.shape and got.flags.c_contiguous and got.tobytes() == ref.tobytes()
        # above the layout: the Legendre recurrence's and a mode's temporaries (measured 3.35, 7.7, 10.7 columns of
        # n for degrees 1-3 on these 432 rows; 9.5, 22.5, 31.5 before, with the modes and the broadcast product)
        assert peak < got.nbytes + 8 * bl.n * (4 * deg + 2), (deg, peak, got.nbytes)


def test_row_blocks_cover_the_rows_aligned_and_their_products_are_the_whole():
    """row_blocks: every row once, in order, each block starting at a multiple of ROW_ALIGN, none shorter than it
    unless the whole is; and the products a block at a time equal the whole product bit for bit on random shapes
    whose plain blocks would leave a one-row tail (a matrix-vector product: 586 of 3,000 such products differed on
    an AMD EPYC's kernels)."""
    for n in (0, 1, 63, 64, 65, 127, 128, 129, 8193, 20001):
        for rows in (1, 7, 63, 64, 65, 100, 8192):
            bl = L.row_blocks(n, rows)
            assert [i for s in bl for i in range(s.start, s.stop)] == list(range(n))
            assert all(s.start % L.ROW_ALIGN == 0 for s in bl)
            assert all(s.stop - s.start >= L.ROW_ALIGN for s in bl) or len(bl) == 1
    rng = np.random.default_rng(25)
    for _ in range(400):
        rows = int(rng.integers(1, 3000))
        step = L.row_blocks(10 ** 6, rows)[0].stop
        n = step * int(rng.integers(1, 6)) + int(rng.choice([1, 2, 3, L.ROW_ALIGN - 1, L.ROW_ALIGN, L.ROW_ALIGN + 1]))
        k = int(rng.integers(1, 17))
        P = rng.standard_normal((n, k)) * 10.0 ** rng.uniform(-3, 3, size=(1, k))
        V = rng.standard_normal((k, int(rng.integers(1, k + 1))))
        got = np.vstack([P[s] @ V for s in L.row_blocks(n, rows)])
        assert got.tobytes() == (P @ V).tobytes()
