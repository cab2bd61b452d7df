"""Session 18's small shortcuts in core.diagnosis give the numbers of the paths they stand for."""

from __future__ import annotations

import numpy as np

from core import diagnosis as D


def _masked(G, b, rss, dof):
    """``_batch_tests``' general (masked) expressions (``_masked_tests``), for every case."""
    w, V = np.linalg.eigh(G)
    proj = (V.transpose(0, 2, 1) @ b[..., None])[..., 0]
    return D._masked_tests(w, w > D.IN_SPAN ** 2, proj, rss, dof)


def test_batch_tests_fast_path_is_the_masked_one_bit_for_bit():
    rng = np.random.default_rng(3)
    for T, k in ((1, 4), (7, 3), (160, 3), (2, 12)):
        P = rng.normal(size=(T, 50, k))
        r = rng.normal(size=50)
        G, b = P.transpose(0, 2, 1) @ P, P.transpose(0, 2, 1) @ r
        got, ref = D._batch_tests(G, b, float(r @ r), 40), _masked(G, b, float(r @ r), 40)
        for x, y in zip(got, ref):
            assert x.dtype == y.dtype and np.array_equal(x, y)
    # a direction inside the model (a zero eigenvalue), and too few degrees of freedom: the masked path still
    P = rng.normal(size=(2, 50, 3))
    P[:, :, 2] = P[:, :, 0]
    G, b = P.transpose(0, 2, 1) @ P, P.transpose(0, 2, 1) @ r
    for dof in (40, 3, 2):
        got, ref = D._batch_tests(G, b, float(r @ r), dof), _masked(G, b, float(r @ r), dof)
        for x, y in zip(got, ref):
            assert np.array_equal(x, y)
    assert list(D._batch_tests(G, b, float(r @ r), 40)[1]) == [2, 2]
    # full rank at the shortcut's bounds (session 18 review): dof = k + 1 is the last case it takes, dof = k
    # (no degree of freedom left: p 1, F 0) and no columns at all go the masked way
    P = rng.normal(size=(3, 50, 3))
    G, b = P.transpose(0, 2, 1) @ P, P.transpose(0, 2, 1) @ r
    for dof in (4, 3):
        got, ref = D._batch_tests(G, b, float(r @ r), dof), _masked(G, b, float(r @ r), dof)
        for x, y in zip(got, ref):
            assert x.dtype == y.dtype and np.array_equal(x, y), (dof, got, ref)
    assert list(D._batch_tests(G, b, float(r @ r), 3)[3]) == [1.0, 1.0, 1.0]
    G0, b0 = np.zeros((2, 0, 0)), np.zeros((2, 0))
    got, ref = D._batch_tests(G0, b0, float(r @ r), 40), _masked(G0, b0, float(r @ r), 40)
    for x, y in zip(got, ref):
        assert x.dtype == y.dtype and np.array_equal(x, y)
    assert list(got[3]) == [1.0, 1.0]


def test_real_times_complex_is_the_complex_product():
    rng = np.random.default_rng(4)
    A = rng.normal(size=(3, 40))
    Z = np.exp(1j * rng.uniform(0, 10, size=(40, 64)))[:, :50]  # (a view: rows strided, last axis contiguous)
    got, ref = D._real_times_complex(A, Z), A @ Z
    assert got.shape == ref.shape and got.dtype == ref.dtype
    assert np.allclose(got, ref, rtol=1e-13, atol=1e-13 * np.abs(ref).max())
    Zs = np.exp(1j * rng.uniform(0, 10, size=(40, 100)))[:, ::2]  # last axis strided: the complex product itself
    assert np.array_equal(D._real_times_complex(A, Zs), A @ Zs)


def test_col_norms_is_numpys_column_norm_bit_for_bit():
    """Session 23's :func:`core.diagnosis.col_norms` (no ``M.conj()`` copy): numpy's ``norm(M, axis=0)`` byte for
    byte on the layouts the engine passes (C- and F-ordered, strided views, zero and huge columns) and others."""
    rng = np.random.default_rng(23)
    A = rng.normal(size=(432, 60)) * np.logspace(-9, 3, 60)
    A[:, 5] = 0.0
    cases = [A, np.asfortranarray(A), A[:, ::3], A[::2], A[:7], rng.normal(size=(60, 432)).T, A[:, :0],
             np.arange(12).reshape(3, 4), A.astype(np.float32), A[:, 0]]
    for M in cases:
        got, ref = D.col_norms(M), np.linalg.norm(M, axis=0)
        assert got.dtype == ref.dtype and got.shape == ref.shape and got.tobytes() == ref.tobytes()
