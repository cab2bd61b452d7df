"""The covariates' tests beside a long log's block basis (core.lsq.Basis): the dense tests' answers.

diagnose and nested_f_batch take a :class:`core.lsq.Basis` through Gram
matrices formed a block of rows at a time (per-set-up columns sparse),
never the term's basis outside the model; these compare them with the
dense path on the same design (the basis as an array).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from core import diagnosis as Dg
from core.lsq import BlockDesign


def _case(seed=5, n=900, g=30, m=6, setups=6):
    r = np.random.default_rng(seed)
    ids = r.integers(0, g, n)
    setup = r.integers(0, setups, n)
    D = r.normal(size=(n, m))
    D[:, 0] = (setup == 1)  # a per-set-up offset: the set-up term's direction partly inside the model
    A = BlockDesign(ids, D, np.arange(g), np.arange(g, g + m))
    az = r.uniform(0, 2 * np.pi, n)
    F = np.column_stack([np.cos(2 * az), np.sin(2 * az)])
    per = np.hstack([F * (setup == j)[:, None] for j in range(setups)])
    modes = np.column_stack([np.ones(n), r.normal(size=n)])
    y = r.normal(size=n) + 0.3 * np.cos(2 * az) * (setup == 2) + 0.2 * np.sin(3 * r.uniform(size=n))
    covs = [Dg.Covariate("setup", setup, "categorical", 0, (0, 1), "the set-up", "time"),
            Dg.Covariate("az_setup", sp.csr_matrix(per), "basis", per.shape[1], (0,), "azimuth per set-up"),
            Dg.Covariate("az_setup_dense", per, "basis", per.shape[1], (0,), "azimuth per set-up"),
            Dg.Covariate("t", np.arange(n, dtype=float), "smooth", 6, (0, 1), "time", "time")]
    return A, y, covs, modes, r


@pytest.mark.parametrize("rows_every", [1, 3])
def test_diagnose_beside_a_block_basis_is_the_dense_diagnosis(monkeypatch, rows_every):
    """Every covariate's k, p-value, explained RMS and fitted term equal the dense diagnosis's (1e-9 relative),
    over every row and over a subset, with the blocks of rows a few rows long; no basis is kept."""
    A, y, covs, modes, r = _case()
    rows = np.arange(0, len(y), rows_every)
    Ar = A[rows]
    Q = Ar.basis()
    Qd = Q.toarray()
    res = y[rows] - Qd @ (Qd.T @ y[rows])
    dof = len(rows) - Qd.shape[1]
    monkeypatch.setattr(Dg, "GRAM_CHUNK_ROWS", 64)
    monkeypatch.setattr(Dg, "FIGURE_P", 2.0)  # every fitted term kept, to compare (test_long_log_keeps_...)
    lean = Dg.diagnose(Q, res, dof, covs, modes, sigma_m=1.0, material_sigma=0.1, rows=rows)
    dense = Dg.diagnose(Qd, res, dof, covs, modes, sigma_m=1.0, material_sigma=0.1, rows=rows)
    assert sorted(d.covariate for d in lean) == sorted(d.covariate for d in dense) and len(lean) == 4
    by = {d.covariate: d for d in dense}  # (the sparse and dense azimuth terms tie: their order is rounding's)
    for a in lean:
        b = by[a.covariate]
        assert a.k == b.k and a.basis is None and b.basis is not None
        np.testing.assert_allclose([a.p_value, a.explained_rms_um], [b.p_value, b.explained_rms_um], rtol=1e-9)
        np.testing.assert_allclose(a.fitted_um, b.fitted_um, rtol=0, atol=1e-9 * np.abs(b.fitted_um).max())
    # a diagnosis taken as known (the same model) keeps its fitted term without a basis
    again = Dg.diagnose(Q, res, dof, covs, modes, sigma_m=1.0, material_sigma=0.1, rows=rows, known=lean)
    by = {d.covariate: d for d in lean}
    for a in again:
        b = by[a.covariate]
        assert a.test is b.test and np.array_equal(a.fitted_um, b.fitted_um)


@pytest.mark.parametrize("rows_every", [1, 3])
def test_long_log_keeps_only_the_fitted_terms_a_figure_draws(monkeypatch, rows_every):
    """Beside a block basis a diagnosis keeps its fitted term only when ``p_value < FIGURE_P`` (the report's
    panels draw no other; each is a rows-long array held for the run): those kept bit for bit the terms kept
    when every one is (FIGURE_P 2), the others None; the tests and figures are the same. The case has both
    (every 1: two azimuth terms at p 0.004 kept, two dropped; every 3: none kept). The dense path keeps all."""
    A, y, covs, modes, r = _case()
    rows = np.arange(0, len(y), rows_every)
    Q = A[rows].basis()
    Qd = Q.toarray()
    res = y[rows] - Qd @ (Qd.T @ y[rows])
    dof = len(rows) - Qd.shape[1]
    kw = dict(sigma_m=1.0, material_sigma=0.1, rows=rows)
    lean = Dg.diagnose(Q, res, dof, covs, modes, **kw)
    with monkeypatch.context() as m:
        m.setattr(Dg, "FIGURE_P", 2.0)
        every = Dg.diagnose(Q, res, dof, covs, modes, **kw)
    assert Dg.FIGURE_P == 0.01 and [d.covariate for d in lean] == [d.covariate for d in every]
    kept = 0
    for a, b in zip(lean, every):
        assert (a.p_value, a.p_raw, a.k, a.words, a.explained_rms_um) == (b.p_value, b.p_raw, b.k, b.words,
                                                                           b.explained_rms_um)
        assert b.fitted_um is not None
        if a.p_value < 0.01:
            kept += 1
            assert np.array_equal(a.fitted_um, b.fitted_um)
        else:
            assert a.fitted_um is None
    assert kept == (2 if rows_every == 1 else 0)
    # taken as known, a dropped term stays dropped, a kept one is the same array
    again = Dg.diagnose(Q, res, dof, covs, modes, known=lean, **kw)
    for a, b in zip(again, lean):
        assert a.covariate == b.covariate and (a.fitted_um is b.fitted_um or np.array_equal(a.fitted_um, b.fitted_um))
    assert all(d.fitted_um is not None for d in Dg.diagnose(Qd, res, dof, covs, modes, **kw))


def test_nested_f_batch_beside_a_block_basis_is_the_dense_one():
    """The trials' sums of squares, dimensions and p-values from Gram matrices equal the projected ones (1e-10)."""
    A, y, covs, modes, r = _case(seed=8)
    Q = A.basis()
    Qd = Q.toarray()
    res = y - Qd @ (Qd.T @ y)
    C = r.normal(size=(3, len(y), 4))
    C[1, :, 0] = A.D[:, 1]  # a column inside the model
    C[2, :, 3] = C[2, :, 2] * 2.0  # a dependent one
    C = np.concatenate([C, C[:1]])
    C[3, :, 1] = 0.0  # a column that is zero on these rows (a set-up's own column, its rows out)
    a = Dg.nested_f_batch(C, Q, res, float(res @ res), len(y) - Qd.shape[1])
    b = Dg.nested_f_batch(C, Qd, res, float(res @ res), len(y) - Qd.shape[1])
    assert np.array_equal(a[1], b[1]) and list(a[1]) == [4, 3, 3, 3] and np.all(np.isfinite(a[0]))
    for x, z in zip(a, b):
        np.testing.assert_allclose(x, z, rtol=1e-10)


def test_gram_test_refuses_a_covariate_without_a_fixed_basis():
    """A spectral covariate (no fixed basis) or an unknown kind: a one-line error naming the covariate."""
    A, y, covs, modes, r = _case()
    Q = A.basis()
    for kind in ("spectral", "wavelet"):
        bad = Dg.Covariate("odd", np.arange(len(y), dtype=float), kind, 3, (0,), "odd")
        with pytest.raises(ValueError, match="covariate 'odd'"):
            Dg.gram_test(bad, Q, y, float(y @ y), len(y) - 40, modes)


def test_sparse_per_setup_azimuth_is_the_dense_one():
    """A long log's azimuth_by_setup covariate (sparse) holds the dense one's numbers, column for column."""
    from core import baseline as Bm
    from core.touches import from_log
    from scenarios.bench.probelog import large_log

    t = from_log(large_log(12, 8, np.random.default_rng(3)))
    d = Bm.planar_data(t, 0.04)
    dense = {c.name: c for c in Bm.planar_covariates(d)}["azimuth_by_setup"].values
    lean = {c.name: c for c in Bm.planar_covariates(d, sparse=True)}["azimuth_by_setup"].values
    assert sp.issparse(lean) and np.array_equal(lean.toarray(), dense)


def test_sparse_covariates_leave_the_others_as_they_are():
    """Every other covariate of a long log (sparse=True) is the dense build's: name, kind, size, modes and values
    (a local name of the sparse build once replaced the position modes of the feature covariate)."""
    from core import baseline as Bm
    from core.touches import from_log
    from scenarios.bench.probelog import large_log

    t = from_log(large_log(12, 8, np.random.default_rng(3)))
    t = t.__class__(**{**t.__dict__, "feature": np.array([f"f{i % 3}" for i in range(t.n)], dtype=object)})
    d = Bm.planar_data(t, 0.04)
    dense, lean = Bm.planar_covariates(d), Bm.planar_covariates(d, sparse=True)
    assert [c.name for c in dense] == [c.name for c in lean] and "feature" in [c.name for c in lean]
    for a, b in zip(dense, lean):
        assert (a.kind, a.size, tuple(a.modes), a.words, a.family) == (b.kind, b.size, tuple(b.modes), b.words,
                                                                       b.family)
        if a.name != "azimuth_by_setup":
            assert np.array_equal(np.asarray(a.values), np.asarray(b.values))


def _old_new_basis(Q, B):
    """new_basis as it was before it worked in place (session 13): the reference of the bit-for-bit tests."""
    nrm = np.linalg.norm(B, axis=0)
    P = B / nrm
    P -= Q @ (Q.T @ P)
    w, V = np.linalg.eigh(P.T @ P)
    good = w > max(Dg.IN_SPAN, 1e-5) ** 2
    return (P @ V[:, good]) / np.sqrt(w[good])


def test_new_basis_in_place_is_the_copying_one_bit_for_bit():
    """new_basis(inplace=True) writes the normalised, projected columns into the caller's B and returns the
    copying path's basis bit for bit (an array Q and a block basis); a B it may not write (read-only, or with a
    zero column) is left as it was, and a zero column is dropped as before."""
    A, y, covs, modes, r = _case(seed=11)
    Qb = A.basis()
    for Q in (Qb, Qb.toarray()):
        B = r.normal(size=(len(y), 5))
        ref = _old_new_basis(Q, B)
        kept = B.copy()
        assert np.array_equal(Dg.new_basis(Q, B), ref) and np.array_equal(B, kept)  # the copying path
        U = Dg.new_basis(Q, B, inplace=True)
        assert np.array_equal(U, ref) and not np.array_equal(B, kept)  # the same basis, B overwritten
        ro = kept.copy()
        ro.flags.writeable = False
        assert np.array_equal(Dg.new_basis(Q, ro, inplace=True), ref) and np.array_equal(ro, kept)
        z = np.column_stack([kept, np.zeros(len(y))])
        z0 = z.copy()
        assert np.array_equal(Dg.new_basis(Q, z, inplace=True), ref) and np.array_equal(z, z0)


def test_spectral_diagnosis_beside_a_block_basis_keeps_the_fitted_term_not_the_basis(monkeypatch):
    """A long log's spectral diagnosis (Q a block basis) keeps its fitted term, not the sine's basis outside the
    model (rows x 2 to 6, up to 46 MiB at 1e6 rows, held for the run): the term is U U^T r of the basis the
    copying new_basis gives for the found sine's columns [M sin, M cos], bit for bit, and the test the same as
    with that basis kept (an array Q: the basis is still kept there). Known answer: a sine of period 9 s."""
    A, y, covs, modes, r = _case(seed=12)
    n = len(y)
    t = np.sort(r.uniform(0, 600, n))
    y = y + 2.0 * np.sin(2 * np.pi * t / 9.0 + 0.4)
    cov = Dg.Covariate("time_periodic", t, "spectral", 0, (0, 1), "time periodically", "time", (3.0, 200.0))
    for rows in (np.arange(n), np.arange(0, n, 2)):
        Q = A[rows].basis()
        Qd = Q.toarray()
        res = y[rows] - Qd @ (Qd.T @ y[rows])
        dof = len(rows) - Qd.shape[1]
        kw = dict(sigma_m=1.0, material_sigma=0.1, rows=rows, bases={cov.name: Dg.spectral_table(cov)})
        lean, = Dg.diagnose(Q, res, dof, [cov], modes, **kw)
        dense, = Dg.diagnose(Qd, res, dof, [cov], modes, **kw)
        assert lean.basis is None and dense.basis is not None and abs(lean.test.period - 9.0) < 0.05
        assert lean.p_value < 1e-6 and lean.test.period == dense.test.period and lean.k == dense.k == 4
        f = Dg.spectral_table(cov).f
        i = int(np.flatnonzero(1 / f == lean.test.period)[0])
        s, c = np.sin(2 * np.pi * t * f[i])[rows], np.cos(2 * np.pi * t * f[i])[rows]
        M = modes[:, [0, 1]][rows]  # (as _spectral takes them: C-contiguous, whose products round as its own)
        U = _old_new_basis(Q, np.hstack([M * s[:, None], M * c[:, None]]))
        assert np.array_equal(lean.fitted_um, (U @ (U.T @ res)) / Dg.UM)
        ref = Dg.nested_f(U, res, float(res @ res), dof)
        assert (lean.test.ss, lean.test.F, lean.test.k) == (ref.ss, ref.F, ref.k)
