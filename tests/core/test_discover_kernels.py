"""discover's shared kernels (issue 19 item 6): known answers, and reuse equal to recomputation.

The reports as a whole are held to main's by test_discover_identity; these
tests pin the pieces that reuse rests on, each against a hand-worked
answer or against computing the thing again.
"""

from __future__ import annotations

import numpy as np
import pytest

from core import diagnosis as D
from core.diagnosis import Covariate, diagnose, orth, pivoted_qr, screen_phasors, spectral_table, term_bases
from core.discover import _constant_within, _constrained, _smooth_gauge, first_per_event
from core.exceptions import ConfigError


def test_one_factorisation_cut_at_two_tolerances():
    """orth with a given pivoted QR equals orth computed afresh; a factorisation of another matrix is ignored."""
    rng = np.random.default_rng(1)
    M = rng.normal(size=(40, 6))
    M[:, 4] = M[:, 0] + 1e-8 * M[:, 4]  # nearly dependent: rank 5 at 1e-9, 4 at 1e-7 (columns scaled first)
    M[:, 5] = 0.0
    f = pivoted_qr(M)
    for tol in (1e-9, 1e-7):
        assert np.array_equal(orth(M, tol, qr=f), orth(M, tol))
    assert orth(M, 1e-9, qr=f).shape[1] == 5 and orth(M, 1e-7, qr=f).shape[1] == 4
    other = rng.normal(size=(40, 6))
    assert np.array_equal(orth(other, qr=f), orth(other))  # not other's factorisation: factored afresh


def test_take_rows_is_the_array_itself_only_for_every_row_of_a_c_contiguous_one():
    """Known answers: every row in order of a C-contiguous array is that array (no copy); anything else is the copy."""
    from core.diagnosis import take_rows

    rng = np.random.default_rng(3)
    M = rng.normal(size=(6, 5, 2))
    every = np.arange(5)
    M0 = M[0]
    assert take_rows(M, every, 1) is M and take_rows(M0, every) is M0
    for rows in (np.array([0, 2, 4]), np.array([1, 0, 2, 3, 4]), np.array([0, 1, 2, 3, 3])):
        got = take_rows(M, rows, 1)
        assert got is not M and np.array_equal(got, M[:, rows, :])
    F = np.asfortranarray(M[0])  # every row, but not C-contiguous: the copy (the layout the callers were given)
    got = take_rows(F, every)
    assert got is not F and got.flags.c_contiguous and np.array_equal(got, F)


def test_nested_f_batch_usual_case_is_the_masked_expressions_bit_for_bit():
    """The usual case (every trial's directions outside the model, F defined) takes fewer passes; the same numbers.

    Without model columns every trial is computed on its own (no product mixes trials), so a trial's
    figures in a batch that holds a degenerate trial (a repeated column: one direction not counted;
    the masked expressions) equal its figures in a batch without it (the usual case), bit for bit;
    and a known answer: a trial's columns exactly in the data's direction remove the whole sum of squares.
    """
    from core.diagnosis import nested_f_batch

    rng = np.random.default_rng(5)
    n, k = 60, 3
    r = rng.normal(size=n)
    C = rng.normal(size=(4, n, k))
    bad = C[:1].copy()
    bad[0, :, 2] = bad[0, :, 1]  # a repeated column: k = 2 for that trial
    Q0 = np.zeros((n, 0))
    plain = nested_f_batch(C, Q0, r, float(r @ r), n - 5)
    mixed = nested_f_batch(np.concatenate([bad, C]), Q0, r, float(r @ r), n - 5)
    assert mixed[1].tolist() == [2, 3, 3, 3, 3]
    two = nested_f_batch(bad[:, :, :2], Q0, r, float(r @ r), n - 5)  # the degenerate trial without its copy
    np.testing.assert_allclose([mixed[0][0], mixed[2][0], mixed[3][0]], [two[0][0], two[2][0], two[3][0]],
                               rtol=1e-10)
    for a, b in zip(plain, mixed):
        assert np.array_equal(a, b[1:])
    # the masked path with every trial usual (dof too small for one: F and p of that trial 0 and 1)
    few = nested_f_batch(C, Q0, r, float(r @ r), 3)
    assert few[2].tolist() == [0.0] * 4 and few[3].tolist() == [1.0] * 4 and np.array_equal(few[0], plain[0])
    # known answer: r itself among a trial's columns, against a model r is orthogonal to
    Q = orth(rng.normal(size=(n, 4)))
    r1 = r - Q @ (Q.T @ r)
    Ct = np.stack([np.column_stack([r1, rng.normal(size=n)])])
    ss, kk, F, p = nested_f_batch(Ct, Q, r1, float(r1 @ r1), n - 4)
    assert kk.tolist() == [2]
    np.testing.assert_allclose(ss, [r1 @ r1], rtol=1e-12)
    # a column inside the model to 1e-9 (a direction not counted) that the residuals follow: left out of
    # the sum of squares (the trial removes what its other column alone removes), not divided by its ~0 eigenvalue
    z = rng.normal(size=n)
    Cn = np.stack([np.column_stack([C[0, :, 0], Q[:, 0] + 1e-9 * (z + 50 * r1)])])
    ss_n, k_n, _, _ = nested_f_batch(Cn, Q, r1, float(r1 @ r1), n - 4)
    ss_1, k_1, _, _ = nested_f_batch(Cn[:, :, :1], Q, r1, float(r1 @ r1), n - 4)
    assert k_n.tolist() == [1] and k_1.tolist() == [1]
    np.testing.assert_allclose(ss_n, ss_1, rtol=1e-6)


def test_new_basis_of_a_zero_column_is_the_basis_without_it():
    """A zero column is left out (the kept columns copied) and a whole basis divided as it is: the same numbers."""
    from core.diagnosis import new_basis

    rng = np.random.default_rng(7)
    Q = orth(rng.normal(size=(50, 6)))
    B = rng.normal(size=(50, 4))
    Bz = np.column_stack([B[:, :2], np.zeros(50), B[:, 2:]])
    assert np.array_equal(new_basis(Q, Bz), new_basis(Q, B))


def test_bound_key_patterns_known_answers():
    """``*`` stands for any text, brackets are literal; a pattern compiled once answers as often as asked."""
    from core.discover import _matches

    for _ in range(2):
        assert _matches("k2_amplitude_um", "k*_amplitude_um") and not _matches("k2_amplitude_umx", "k*_amplitude_um")
        assert _matches("a[1]", "a[1]") and not _matches("a1", "a[1]") and _matches("EXX_bump", "E*_bump")


def test_estimability_with_more_unknowns_than_rows():
    """Known answer: 3 rows see parameters 0, 1 and 0 + 2; 5 unknowns, no gauge.

    Parameters 0, 1, 2 are determined (1, 2, 3 - 1); 3 and 4 are seen by no
    row. A thin SVD has 3 directions, all seen; the two beyond them are
    unseen (they were missed, and 3 and 4 called estimable, before the
    null-space code was shared with the smooth gauge's).
    """
    A = np.array([[1.0, 0, 0, 0, 0], [0, 1.0, 0, 0, 0], [1.0, 0, 1.0, 0, 0]])
    y = np.array([1.0, 2.0, 3.0])
    theta, cov, est = _constrained(A, y, np.zeros((0, 5)), np.zeros(0), np.arange(3), None, 0)
    assert est.tolist() == [True, True, True, False, False]
    np.testing.assert_allclose(theta[:3], [1.0, 2.0, 2.0], atol=1e-12)


def test_smooth_gauge_pins_the_unseen_directions_of_the_penalised_block():
    """Known answer: a smooth block that copies a model column is pinned to it; its free column is left free."""
    x = np.linspace(0, 1, 8)
    A = np.column_stack([np.ones(8), x, np.ones(8), x ** 2])  # model: 1, x; smooth: 1 (a copy), x^2
    pen = np.array([False, False, True, True])
    C, d = _smooth_gauge(A, np.zeros((0, 4)), np.zeros(0), np.arange(8), pen)
    assert C.shape == (1, 4) and d.tolist() == [0.0]
    np.testing.assert_allclose(np.abs(C[0]), [0, 0, 1, 0], atol=1e-12)  # the copy's coefficient fixed at 0


def test_first_per_event_known_answer():
    events = np.array([5, 5, -1, 7, -1, 5, 7])
    assert first_per_event([1, 0, 2, 4, 6, 3], events) == [1, 2, 4, 6]
    assert first_per_event(np.array([4, 2]), events).__len__() == 2  # negative keys: a row each


def test_diagnosis_taken_from_a_diagnosis_of_the_same_model_is_the_same():
    """diagnose(known=...) over more covariates equals diagnosing afresh (tests, Holm, words, fitted values)."""
    rng = np.random.default_rng(3)
    n = 120
    t = np.sort(rng.uniform(0, 100, n))
    covs = (Covariate("time", t, "smooth", 6, (0,), "time", "time"),
            Covariate("x", rng.uniform(-1, 1, n), "smooth", 5, (0,), "x", "position"),
            Covariate("setup", rng.integers(0, 3, n), "categorical", 0, (0,), "set-up", "time"))
    modes = np.ones((n, 1))
    Q = orth(np.column_stack([np.ones(n), rng.normal(size=n)]))
    y = np.sin(t / 15) * 1e-6 + rng.normal(0, 3e-7, n)
    r = y - Q @ (Q.T @ y)
    bases = term_bases(covs, modes)
    kw = dict(sigma_m=3e-7, material_sigma=0.3, rows=np.arange(n), bases=bases)
    part = diagnose(Q, r, n - 2, covs[:2], modes, **kw)
    fresh = diagnose(Q, r, n - 2, covs, modes, **kw)
    taken = diagnose(Q, r, n - 2, covs, modes, known=part, **kw)
    assert [d.to_dict() for d in taken] == [d.to_dict() for d in fresh]
    for a, b in zip(taken, fresh):
        assert a.test == b.test and np.array_equal(a.basis, b.basis) and np.array_equal(a.fitted_um, b.fitted_um)
    assert fresh[0].covariate == "time" and fresh[0].p_value < 1e-6  # not a vacuous comparison


def test_constant_within_groups_known_answers_and_the_loop_it_replaced():
    key = np.array([0, 1, 0, -1, 1, 2])
    E = np.array([[1.0, 5.0], [2.0, 6.0], [1.0, 5.0], [9.0, 9.0], [2.0, 6.0], [3.0, 0.0]])
    assert _constant_within(key, E)  # row 3 belongs to no group: it may differ
    E[4, 1] += 1e-6  # group 1 varies in column 1 (1e-6 > 1e-9 of its largest entry, 9)
    assert not _constant_within(key, E)
    E[4, 1] -= 1e-6 - 1e-12  # within 1e-9 of the column's largest entry: constant
    assert _constant_within(key, E)
    assert _constant_within(np.full(6, -1), E) and _constant_within(key, np.zeros((6, 0)))

    def loop(key, E):  # the per-group loop the vectorised version replaced
        for k in np.unique(key[key >= 0]):
            if np.any(np.ptp(E[key == k], axis=0) > 1e-9 * np.maximum(np.abs(E).max(axis=0), 1e-300)):
                return False
        return True

    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(300):
        n, g = int(rng.integers(2, 40)), int(rng.integers(1, 8))
        key = rng.integers(-1, g, n)
        E = rng.normal(size=(g + 1, 3))[np.maximum(key, 0)]
        if rng.random() < 0.5:
            E[rng.integers(n), rng.integers(3)] += rng.choice([1e-13, 1e-6])
        seen.add(loop(key, E))
        assert _constant_within(key, E) == loop(key, E)
    assert seen == {True, False}


def test_spectral_scan_in_blocks_is_the_kept_table_bit_for_bit(monkeypatch):
    """A scan too big to keep is made a block of frequencies at a time: the same columns, the same diagnosis.

    Known answer first: a sine of period 7 s in the residuals is the scan's finding. Then the table is
    refused (TABLE_BYTES 0) and blocks are the minimum, 32 frequencies (the last one short) by one row (a long
    log's scan, a block of rows at a time): every block equals the kept table's entries bit for bit, each entry
    met once, the screen's products summed over the blocks equal the whole table's to 1e-12 (the order of the
    sums over rows changes), and the diagnosis (test, basis, fitted values) is equal.
    """
    rng = np.random.default_rng(5)
    n = 300
    t = np.sort(rng.uniform(0, 600, n))
    cov = Covariate("time_periodic", t, "spectral", 0, (0,), "time periodically", "time", (3.0, 200.0))
    modes = np.ones((n, 1))
    Q = orth(np.ones((n, 1)))
    y = 1e-6 * np.sin(2 * np.pi * t / 7.0 + 0.3) + rng.normal(0, 2e-7, n)
    r = y - Q @ (Q.T @ y)
    kw = dict(sigma_m=2e-7, material_sigma=0.3, rows=np.arange(n))
    kept = spectral_table(cov)
    assert kept.Z is not None and len(kept.f) % D._BLOCK  # a short last block
    whole = diagnose(Q, r, n - 1, [cov], modes, bases={cov.name: kept}, **kw)
    assert whole[0].p_value < 1e-6 and abs(whole[0].test.period - 7.0) < 0.05  # the sine is found
    monkeypatch.setattr(D, "TABLE_BYTES", 0)
    monkeypatch.setattr(D, "SCAN_BLOCK_BYTES", 1)
    lazy = spectral_table(cov)
    assert lazy.Z is None and np.array_equal(lazy.f, kept.f)
    seen = np.zeros(kept.Z.shape, int)
    for cols, rows, Z, S2, C2 in lazy.blocks():  # (blocks of one row: SCAN_BLOCK_BYTES 1)
        assert Z.shape[1] <= D._BLOCK and Z.shape[0] == 1
        assert np.array_equal(Z, kept.Z[rows, cols]) and np.array_equal(S2, kept.S2[rows, cols])
        assert np.array_equal(C2, kept.C2[rows, cols])
        seen[rows, cols] += 1
    assert np.all(seen == 1)
    # the screen's products summed over the blocks of rows: the whole table's to rounding
    A, W2 = (r[:, None] * modes).T, (modes ** 2).T
    for a, b in zip(lazy.screen(A, W2), kept.screen(A, W2)):
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b))
    blocked = diagnose(Q, r, n - 1, [cov], modes, bases={cov.name: lazy}, **kw)
    assert [d.to_dict() for d in blocked] == [d.to_dict() for d in whole]
    assert blocked[0].test == whole[0].test and np.array_equal(blocked[0].basis, whole[0].basis)
    with pytest.raises(ValueError, match="multiple of 32"):
        screen_phasors(kept.w, kept.f, 5)


def _plane(x, y, rng, grid_step_m=0.04):
    """The planar data periodic_scans reads: positions (m), in-plane normals, the error map's grid step."""
    from types import SimpleNamespace

    b = rng.uniform(0, 2 * np.pi, len(x))
    return SimpleNamespace(data=SimpleNamespace(x=x, y=y, nx=np.cos(b), ny=np.sin(b), grid_step_m=grid_step_m))


def test_ripple_scan_follows_the_distinct_positions_not_the_rows():
    """Repeats add rows, not frequencies; and past MAX_SCAN_FREQUENCIES the grid stops growing.

    200 distinct positions (1 mm apart along x, 0.5 mm along y) give the same trials whether each is
    touched once or ten times (2,000 rows): along x, 3 * span * (1 / p_lo - 1 / p_hi) = 3 * 0.199 m *
    (1 / 2 mm - 1 / 40 mm) = 283.6, so 284 frequencies. Known answer for the cap: 20,001 distinct
    positions 5 um apart over 0.1 m would need 3 * 0.1 * (1 / 10 um - 1 / 40 mm) = 29,993 on the fine grid;
    the scan keeps the cap's count over the same range, and a log twice as long scans no more.
    """
    from core.causes import periodic_scans

    rng = np.random.default_rng(3)
    x, y = np.arange(200) * 1e-3, np.arange(200) * 0.5e-3
    once, _ = periodic_scans(_plane(x, y, rng))
    rep, _ = periodic_scans(_plane(np.repeat(x, 10), np.repeat(y, 10), rng))
    assert [len(s.infos) for s in once] == [len(s.infos) for s in rep] and len(once) == 2
    assert [s.infos for s in once] == [s.infos for s in rep] and len(once[0].infos) == 284
    cap = D.MAX_SCAN_FREQUENCIES
    for n in (20_001, 40_001):
        a = np.linspace(0.0, 0.1, n)
        sc, _ = periodic_scans(_plane(a, a, rng))
        f = 1 / np.array([i["period_m"] for i in sc[0].infos])
        assert cap <= len(f) <= cap + 1  # (arange's last step may round either way)
        assert f[0] == pytest.approx(1 / 0.04) and f[-1] <= 1 / sc[0].infos[0]["nyquist_m"]
        assert sc[0].infos[0]["scan_step_per_m"] == pytest.approx(f[1] - f[0])  # the refinement's reach
    assert "scan_step_per_m" not in once[0].infos[0]  # the fine grid: refined as before


def test_ripple_scan_in_blocks_is_the_kept_table_bit_for_bit(monkeypatch):
    """A ripple scan too big to keep is scored a block of frequencies at a time: the same scores, bit for bit.

    Known answer first: a 7 mm ripple along x in the residuals scores best at the trial nearest 7 mm.
    Then the table is refused (TABLE_BYTES 0, blocks of 32 frequencies): every score is equal, on all
    rows and on a subset (the rows a cross-validation fold keeps).
    """
    from core import causes as C

    rng = np.random.default_rng(11)
    n = 400
    x, y = np.sort(rng.uniform(0, 0.2, n)), rng.uniform(0, 0.2, n)
    bl = _plane(x, y, rng)
    r = -bl.data.nx * 1e-6 * np.sin(2 * np.pi * x / 7e-3 + 0.4) + rng.normal(0, 1e-7, n)
    kept = C.periodic_scans(bl)[0][0]
    rows, sub = np.arange(n), np.sort(rng.choice(n, 300, replace=False))
    s_all, s_sub = kept.score(r, rows), kept.score(r[sub], sub)
    P = np.array([i["period_m"] for i in kept.infos])
    assert abs(P[np.argmax(s_all)] - 7e-3) <= np.min(np.abs(P - 7e-3)) + 1e-12 and len(P) % D._BLOCK
    monkeypatch.setattr(C, "TABLE_BYTES", 0)
    monkeypatch.setattr(D, "SCAN_BLOCK_BYTES", 1)
    lazy = C.periodic_scans(bl)[0][0]
    assert np.array_equal(lazy.score(r, rows), s_all) and np.array_equal(lazy.score(r[sub], sub), s_sub)


def test_kept_denominators_give_the_scores_computed_afresh(monkeypatch):
    """The pre-screens keep their denominators per set of rows: every later score equals a fresh scorer's.

    The ripple scorer (kept table and blocks) and a spectral covariate's table are used in turn with
    other residuals, a subset of the rows, other modes and the first residuals again; each answer is
    bit for bit what a scorer or table made for that call alone gives. A table keeps a key's
    denominators only for the modes array it was given with them (another array under the same key is
    computed afresh); under the same key and array the kept ones are used, whatever the weights passed.
    """
    from core import causes as C

    rng = np.random.default_rng(12)
    n = 400
    x, y = np.sort(rng.uniform(0, 0.2, n)), rng.uniform(0, 0.2, n)
    bl = _plane(x, y, rng)
    r1 = -bl.data.nx * 1e-6 * np.sin(2 * np.pi * x / 7e-3 + 0.4) + rng.normal(0, 1e-7, n)
    r2 = rng.normal(0, 1e-7, n)
    rows, sub = np.arange(n), np.sort(rng.choice(n, 300, replace=False))
    calls = [(r1, rows), (r2, rows), (r2[sub], sub), (r1, rows), (r1[sub], sub)]
    for big in (False, True):
        if big:
            monkeypatch.setattr(C, "TABLE_BYTES", 0)
            monkeypatch.setattr(D, "SCAN_BLOCK_BYTES", 1)
        sc = C.periodic_scans(bl)[0][0]
        for r, rw in calls:
            assert np.array_equal(sc.score(r, rw), C.periodic_scans(bl)[0][0].score(r, rw))
    monkeypatch.undo()
    t = np.sort(rng.uniform(0, 600, n))
    cov = Covariate("time_periodic", t, "spectral", 0, (0, 1), "time periodically", "time", (3.0, 200.0))
    modes = np.column_stack([np.ones(n), rng.uniform(0.5, 1.5, n)])
    Q = orth(np.ones((n, 1)))
    ys = [1e-6 * np.sin(2 * np.pi * t / 7.0 + 0.3) + rng.normal(0, 2e-7, n), rng.normal(0, 2e-7, n)]
    tab = spectral_table(cov)

    def diag(table, y, rw, m):
        Qr = Q if rw is None else orth(np.ones((len(rw), 1)))
        yr = y if rw is None else y[rw]
        return diagnose(Qr, yr - Qr @ (Qr.T @ yr), len(yr) - 1, [cov], m, bases={cov.name: table}, sigma_m=2e-7,
                        material_sigma=0.3, rows=rw)

    other = np.column_stack([np.ones(n), rng.uniform(0.5, 1.5, n)])
    for y, rw, m in [(ys[0], None, modes), (ys[1], None, modes), (ys[1], sub, modes), (ys[0], None, modes),
                     (ys[0], None, other)]:
        kept, fresh = diag(tab, y, rw, m), diag(spectral_table(cov), y, rw, m)
        assert [d.to_dict() for d in kept] == [d.to_dict() for d in fresh]
        assert kept[0].test == fresh[0].test and np.array_equal(kept[0].basis, fresh[0].basis)
    # the subset's own denominators were made (rows outside it weighted by zero), not the first rows' taken
    Mw = np.where(np.isin(np.arange(n), sub)[:, None], modes, 0.0)
    assert any(np.array_equal(dS, (Mw ** 2).T @ tab.S2) for _, dS, _ in tab._dens.values())
    A, W2 = rng.normal(size=(2, n)), rng.uniform(0.5, 1.5, (2, n))
    first = tab.screen(A, W2, "key", modes)
    moved = tab.screen(A, 2 * W2, "key", other)  # the same key, another modes array: made afresh
    assert np.array_equal(moved[1], spectral_table(cov).screen(A, 2 * W2)[1]) and not np.array_equal(moved[1], first[1])
    again = tab.screen(A, 0 * W2, "key", other)  # the same key and array: the kept denominators
    assert np.array_equal(again[1], moved[1]) and np.array_equal(again[0], first[0])


def test_folds_keep_the_held_out_rows_only():
    """Cross-validation keeps, per held-out group, the eigenvectors of the hat matrix's held-out block only
    (n_te x min(n_te, p) numbers: a long log's folds total at most rows x parameters), not a table over the
    training rows nor a (p x p) eigenbasis per group (1,346^2 numbers x 100 set-ups at 1e5 rows: 1.4 GB). A
    design of 8 groups with a column only one group sees: that group's fold has one own direction, and the
    held-out residuals of several observation vectors at once are those of each alone (linear, 1e-12)."""
    from core import discover as X

    rng = np.random.default_rng(21)
    n, p = 240, 12
    groups = np.repeat(np.arange(8), n // 8)
    A = rng.normal(size=(n, p))
    A[:, -1] = (groups == 3) * rng.normal(size=n)  # seen by one group only: that fold's own column
    folds = X.Folds(A, groups, X.Settings().cv_seen)
    assert all(f.U.shape == (f.te.size, min(f.te.size, p)) for f in folds.items)
    assert [f.Qo.shape[1] for f in folds.items] == [0, 0, 0, 1, 0, 0, 0, 0]
    Y = rng.normal(size=(n, 5))
    E = np.column_stack([np.sin(np.arange(n) / 7.0), rng.normal(size=n), A[:, 0] + 1e-3 * rng.normal(size=n)])
    pen = np.diag([0.0, 2.0, 5.0])
    for extra in ((), (E,), (E, pen)):
        a = folds.residuals(Y, *extra)
        b = np.column_stack([folds.residuals(Y[:, j], *extra) for j in range(Y.shape[1])])
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())


def _block_design(rng, n=600, g=30, m=6, groups=5):
    """A block design with a target seen by one group only and a dense column seen by another only."""
    from core.lsq import BlockDesign

    ids = rng.integers(0, g - 1, n)
    grp = rng.integers(0, groups, n)
    D = rng.normal(size=(n, m))
    D[:, -1] = (grp == 2) * rng.normal(size=n)  # group 2's own column
    ids[(grp == 3) & (rng.random(n) < 0.2)] = g - 1  # target g-1: group 3's own
    return BlockDesign(ids, D, np.arange(3, 3 + g), np.r_[0:3, 3 + g:3 + g + m - 3]), grp


def test_folds_block_path_is_the_dense_one_on_a_well_posed_design():
    """A long log's folds eliminate the targets (Schur complement): on a design whose training fits are unique
    (no truncated direction), the held-out residuals and dof are the dense path's to rounding (1e-12 relative),
    own target and own column included, with an extension, a penalty and one observation vector."""
    from core import discover as X

    rng = np.random.default_rng(5)
    A, grp = _block_design(rng)
    Y = rng.normal(size=(len(grp), 3))
    E = np.column_stack([np.sin(np.arange(len(grp)) / 9.0), rng.normal(size=len(grp)), (grp == 1) * 1.0])
    seen = X.Settings().cv_seen
    dense, blocks = X.Folds(A.toarray(), grp, seen), X.Folds(A, grp, seen)
    assert all(f.U.shape[0] == f.te.size for f in blocks.items)
    assert [f.Qo.shape[1] for f in blocks.items] == [0, 0, 1, 1, 0]  # group 2's own column, group 3's own target
    for args in ((Y,), (Y, E), (Y, E, np.diag([1.0, 0.0, 3.0])), (Y[:, 0], E[:, :1])):
        a, b = dense.residuals(*args), blocks.residuals(*args)
        assert dense.last_dof == blocks.last_dof
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())


def _bench_log_dense_and_block(monkeypatch, cut=lambda log: log):
    """The benchmark generator's 150 x 8 log (``cut`` of it) as touches, its planar baseline with a dense design
    and forced through the block design (DENSE_DESIGN_BYTES 0)."""
    from core import baseline as Bm
    from core.touches import from_log
    from scenarios.bench.probelog import large_log

    t = from_log(cut(large_log(150, 8, np.random.default_rng(19))))
    dense = Bm.planar(t)
    monkeypatch.setattr(Bm, "DENSE_DESIGN_BYTES", 0)
    return t, dense, Bm.planar(t)


def _quick_folds_made(monkeypatch) -> list:
    """The list to which every later call of Folds._fold_one_touch_per_target appends its answer (a fold or None)."""
    from core import discover as X

    made = []
    quick = X.Folds._fold_one_touch_per_target
    monkeypatch.setattr(X.Folds, "_fold_one_touch_per_target",
                        lambda self, te: made.append(quick(self, te)) or made[-1])
    return made


def test_folds_of_a_log_probed_once_per_target_and_setup_by_the_svd_of_the_dense_rows(monkeypatch):
    """A long log probed once per target and set-up (the benchmark's generator: 150 targets at 8 C angles, forced
    through the block design): every fold is made from the SVD of the basis's dense rows (the hat block's
    indicator part is a multiple of the identity), not the eigh of the hat block, and gives the same held-out
    residuals and dof as the dense design's folds (a different algorithm: orth of the formed matrix, each
    fold's eigh) and as the block path's general fold, to 1e-12 relative, with and without an extension."""
    from core import discover as X

    t, dense, block = _bench_log_dense_and_block(monkeypatch)
    seen = X.Settings().cv_seen
    made = _quick_folds_made(monkeypatch)
    fast = X.Folds(block.A, block.groups, seen)
    assert len(made) == 8 and all(f is not None and f.m > 0 for f in made)  # every fold, a cluster kept implicit
    monkeypatch.setattr(X.Folds, "_fold_one_touch_per_target", lambda self, te: None)
    general, ref = X.Folds(block.A, block.groups, seen), X.Folds(dense.A, dense.groups, seen)
    rng = np.random.default_rng(3)
    Y, E = rng.normal(size=(t.n, 2)), rng.normal(size=(t.n, 2))
    for args in ((Y,), (Y, E), (block.y,)):
        a = ref.residuals(*args)
        for folds in (fast, general):
            b = folds.residuals(*args)
            assert folds.last_dof == ref.last_dof
            np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())


@pytest.mark.parametrize("cut", [lambda log: log, lambda log: _log_with_unequal_counts(log)])
def test_folds_of_a_long_log_keep_the_held_out_rows_sparse(monkeypatch, cut):
    """A held-out set-up's rows of a block basis kept sparse (:meth:`Folds._q_rows` above
    FOLD_ROWS_DENSE_BYTES, here 0: every set-up; the 1e6-row log's 10,000 x 10,000 indicator block, 800 MB
    formed): one entry a row in the indicator part, and the held-out residuals and dof of the dense design's
    folds to 1e-12 relative (the same products summed in another order) with and without an extension and a
    penalty on it (the direct route), by the quick fold (the bench log) and the general one (unequal counts)."""
    import scipy.sparse as sp

    from core import discover as X

    t, dense, block = _bench_log_dense_and_block(monkeypatch, cut)
    monkeypatch.setattr(X, "FOLD_ROWS_DENSE_BYTES", 0)
    seen = X.Settings().cv_seen
    folds, ref = X.Folds(block.A, block.groups, seen), X.Folds(dense.A, dense.groups, seen)
    te = folds.items[0].te
    Qte, cols = folds._q_rows(te)
    k = np.unique(block.A.ids[te]).size
    assert sp.issparse(Qte) and Qte.shape == (te.size, cols.size)
    assert np.array_equal(np.diff(Qte[:, :k].tocsr().indptr), np.ones(te.size))
    rng = np.random.default_rng(3)
    Y, E = rng.normal(size=(t.n, 2)), rng.normal(size=(t.n, 2))
    for args in ((Y,), (Y, E), (Y, E, np.diag([1.0, 3.0])), (block.y,)):
        a, b = ref.residuals(*args), folds.residuals(*args)
        assert folds.last_dof == ref.last_dof
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())


def test_turned_lobes_trials_kept_sparse_test_as_the_dense_ones(monkeypatch):
    """lobing_per_setup's trials (cos k phi, sin k phi per set-up) kept sparse for a long log hold the dense
    trials' values exactly, and their nested F test against the block basis (from their Gram matrices) is the
    dense trials' to 1e-12 relative (the same sums in another order), on all rows and on some; engine's
    choice: sparse for a block basis, dense otherwise. Dense, they were n x 2 set-ups (1.6 GB at 1e6 rows)."""
    import scipy.sparse as sp

    from core import causes as K
    from core import discover as X
    from core.diagnosis import SparseTrials, nested_f_batch, take_rows

    t, dense, block = _bench_log_dense_and_block(monkeypatch)
    scans, _ = K.unoriented_scans(block)
    assert len(scans) == 3 and all(sc.build_sparse is not None for sc in scans)
    Q = block.A.basis()
    r = np.random.default_rng(4).normal(size=t.n)
    r -= Q @ (Q.T @ r)
    for sc in scans:
        S, D = sc.build_sparse([0]), sc.build([0])
        assert isinstance(S, SparseTrials) and sp.issparse(S[0]) and S.shape == D.shape
        assert np.array_equal(S[0].toarray(), D[0]) and S[0].nnz == 2 * t.n
        assert sc.build_sparse([0, -1]).shape == sc.build([0, -1]).shape  # (as the dense scan indexes)
        for bad in ([1], [0.0], 0, [[0]]):  # the scan has one trial: another index is refused, not copied
            with pytest.raises(ConfigError):
                sc.build_sparse(bad)
        for rows in (np.arange(t.n), np.arange(0, t.n, 3)):
            Qr = Q if len(rows) == t.n else block.A[rows].basis()
            rr = r[rows] - Qr @ (Qr.T @ r[rows])
            a = nested_f_batch(take_rows(D, rows, 1), Qr, rr, float(rr @ rr), len(rows) - Qr.shape[1])
            b = nested_f_batch(take_rows(S, rows, 1), Qr, rr, float(rr @ rr), len(rows) - Qr.shape[1])
            assert np.array_equal(a[1], b[1])
            for u, v in zip(a, b):
                np.testing.assert_allclose(v, u, rtol=1e-12, atol=0)
    st = X._State(rows=np.arange(t.n), Q=Q, r=r, rss=float(r @ r), dof=10)
    assert isinstance(X._trials(scans[0], [0], st), SparseTrials)
    st = X._State(rows=np.arange(t.n), Q=orth(dense.A), r=r, rss=float(r @ r), dof=10)
    assert isinstance(X._trials(scans[0], [0], st), np.ndarray)


def test_c_drift_per_setup_trial_kept_sparse_tests_as_the_dense_one(monkeypatch):
    """c_drift's rate per set-up (the table's angle creeping within each set-up: rows x set-ups, held for the run
    they were 800 MB at the bench's 1e6 rows) is built when its trial is: kept sparse for a long log it holds the
    dense columns' values exactly, one a row, and its nested F test against the block basis is the dense one's to
    1e-12 relative (the same sums in another order), on all rows and on some; another trial index is refused;
    the engine takes it sparse for a block basis, dense otherwise."""
    import scipy.sparse as sp

    from core import causes as K
    from core import discover as X
    from core.diagnosis import SparseTrials, nested_f_batch, take_rows

    t, dense, block = _bench_log_dense_and_block(monkeypatch)
    scans, _ = K.c_drift_scans(block)
    sc, = [sc for sc in scans if sc.infos[0]["form"] == "per set-up"]
    assert all(o.build_sparse is None for o in scans if o is not sc)
    S, D = sc.build_sparse([0]), sc.build([0])
    assert isinstance(S, SparseTrials) and sp.issparse(S[0]) and S.shape == D.shape == (1, t.n, 8)
    assert np.array_equal(S[0].toarray(), D[0]) and S[0].nnz == t.n
    assert np.array_equal(D[0], K.c_drift_scans(dense)[0][2].build([0])[0])  # the dense baseline's scan
    assert sc.build_sparse([0, -1]).shape == sc.build([0, -1]).shape  # (as the dense scan indexes)
    for bad in ([1], [0.0], 0, [[0]]):
        with pytest.raises(ConfigError):
            sc.build_sparse(bad)
    Q = block.A.basis()
    r = np.random.default_rng(4).normal(size=t.n)
    r -= Q @ (Q.T @ r)
    for rows in (np.arange(t.n), np.arange(0, t.n, 3)):
        Qr = Q if len(rows) == t.n else block.A[rows].basis()
        rr = r[rows] - Qr @ (Qr.T @ r[rows])
        a = nested_f_batch(take_rows(D, rows, 1), Qr, rr, float(rr @ rr), len(rows) - Qr.shape[1])
        b = nested_f_batch(take_rows(S, rows, 1), Qr, rr, float(rr @ rr), len(rows) - Qr.shape[1])
        assert np.array_equal(a[1], b[1]) and a[1][0] > 0
        for u, v in zip(a, b):
            np.testing.assert_allclose(v, u, rtol=1e-12, atol=0)
    st = X._State(rows=np.arange(t.n), Q=Q, r=r, rss=float(r @ r), dof=10)
    assert isinstance(X._trials(sc, [0], st), SparseTrials)
    st = X._State(rows=np.arange(t.n), Q=orth(dense.A), r=r, rss=float(r @ r), dof=10)
    assert isinstance(X._trials(sc, [0], st), np.ndarray)


def test_drift_trend_kept_sparse_is_the_dense_one(monkeypatch):
    """The noise's per-set-up time trend (discover_baseline's first screen) kept sparse holds the dense columns'
    values exactly, and the repeats' scatter with it is the dense one's (only the repeated rows are formed: the
    same numbers, dof equal, the sum of squares to 1e-12 relative: the BLAS kernels may round otherwise on
    another copy's alignment). Dense it was rows x 3 modes x set-ups: 2.4 GB at the bench's 1e6 rows and 100 set-ups, where the
    1e6-row discover stopped after the workpiece fit, folds and lobing trials were made to fit. The bench log
    with 10 % of its touches repeated (a copy 1 um noise off, 1000 s later): repeats in every set-up."""
    import scipy.sparse as sp

    from core import baseline as Bm
    from core import discover as X
    from core.diagnosis import replicate_scatter
    from core.touches import from_log
    from scenarios.bench.probelog import large_log

    log = large_log(40, 12, np.random.default_rng(19))
    pick = np.flatnonzero(np.random.default_rng(2).random(log.n) < 0.1)
    cols = {k: np.concatenate([v, v[pick]]) for k, v in log.columns.items()}
    cols["t_s"][log.n:] += 1000.0
    e = np.random.default_rng(6).normal(0, 1e-3, pick.size)
    cols["X_mm"][log.n:] += e * cols["nx"][log.n:]
    cols["Y_mm"][log.n:] += e * cols["ny"][log.n:]
    order = np.argsort(cols["t_s"], kind="stable")
    from core.probelog import make_log

    bl = Bm.planar(from_log(make_log({k: v[order] for k, v in cols.items()}, dict(log.meta), validate=False)))
    assert (bl.replicate >= 0).sum() > 0
    for rows in (np.arange(bl.n), np.arange(5, bl.n)):
        a, b = X.drift_trend(bl, rows), X.drift_trend(bl, rows, sparse=True)
        assert sp.issparse(b) and np.array_equal(b.toarray(), a) and b.nnz <= 3 * len(rows)
        ra = replicate_scatter(bl.replicate[rows], bl.y[rows], a)
        rb = replicate_scatter(bl.replicate[rows], bl.y[rows], b)
        assert ra.dof > 0 and (ra.dof, ra.groups) == (rb.dof, rb.groups) and ra.ss > 0
        assert rb.ss == pytest.approx(ra.ss, rel=1e-12, abs=0)


def _log_with_unequal_counts(log):
    """The benchmark log with 10 % of its touches dropped at random: targets touched 6 to 8 times."""
    return log.select(np.random.default_rng(5).random(len(log.columns["target"])) > 0.1)


def _log_with_targets_probed_once(log):
    """The benchmark log with its first 40 targets probed in one set-up only (one touch each, a different set-up
    target by target): their set-ups hold targets touched once beside targets touched 8 times."""
    tg = log.columns["target"]
    ut = np.unique(tg)
    keep = ~np.isin(tg, ut[:40])
    for i, target in enumerate(ut[:40]):
        idx = np.flatnonzero(tg == target)
        keep[idx[i % len(idx)]] = True
    return log.select(keep)


@pytest.mark.parametrize("cut", [_log_with_unequal_counts, _log_with_targets_probed_once])
def test_folds_of_a_log_off_the_one_touch_per_target_form_take_the_general_fold(monkeypatch, cut):
    """The quick fold (:meth:`Folds._fold_one_touch_per_target`) declines (None) where the held-out set-up's
    targets have unequal counts (its equal-count guard: 10 % of touches dropped; 40 targets probed once), and the
    folds' held-out residuals and dof are the dense design's. Without that guard the quick fold is taken there and
    is wrong (measured: residuals 0.16 of their largest off with 10 % dropped; dof 915 against 880 with 40
    targets probed once). 1e-12
    relative: the same algebra by other routes, worst measured 9.6e-15 on these logs."""
    from core import discover as X

    t, dense, block = _bench_log_dense_and_block(monkeypatch, cut)
    seen = X.Settings().cv_seen
    made = _quick_folds_made(monkeypatch)
    folds = X.Folds(block.A, block.groups, seen)
    assert len(made) == 8 and all(f is None for f in made)
    ref = X.Folds(dense.A, dense.groups, seen)
    rng = np.random.default_rng(3)
    Y, E = rng.normal(size=(t.n, 2)), rng.normal(size=(t.n, 2))
    for args in ((Y,), (Y, E), (block.y,)):
        a, b = ref.residuals(*args), folds.residuals(*args)
        assert folds.last_dof == ref.last_dof
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())


def test_folds_where_the_largest_cluster_is_not_the_indicators_take_the_general_fold(monkeypatch):
    """Hand-made: 5 targets, each probed once in each of 3 set-ups (equal counts, one touch per target: the quick
    fold's form), and 4 machine columns, column j touching target (j - g) mod 5 in set-up g (a cyclic design).
    A held-out set-up's dense rows W (5 x 4) leave one direction (n0 = 1, share delta = 1/3), and the cyclic
    symmetry pairs W's singular values: in one fold the largest cluster of equal shares is such a pair, not the
    indicators' delta, and the quick fold (which drops the cluster as if it were delta's) declines there (its
    cluster guard); the held-out residuals and dof are the dense design's. Without that guard the quick fold is
    taken and the residuals are 0.41 of their largest off (measured). 1e-12 relative: the same algebra by other
    routes, worst measured 6.1e-15."""
    from core import discover as X
    from core.lsq import BlockDesign

    S, T, r = 3, 5, 4
    rows = [(t, g) for g in range(S) for t in range(T)]
    A = np.zeros((len(rows), T + r))
    for i, (t, g) in enumerate(rows):
        A[i, t] = 1.0
        if (t + g) % T < r:
            A[i, T + (t + g) % T] = 1.0
    groups = np.array([g for _, g in rows])
    assert np.linalg.matrix_rank(A) == T + r
    seen = X.Settings().cv_seen
    made = _quick_folds_made(monkeypatch)
    folds = X.Folds(BlockDesign.from_sparse(A, np.arange(T)), groups, seen)
    assert len(made) == S and any(f is None for f in made)
    ref = X.Folds(A, groups, seen)
    Y = np.random.default_rng(1).normal(size=(len(rows), 2))
    for args in ((Y,), (Y[:, 0], Y[:, 1:])):
        a, b = ref.residuals(*args), folds.residuals(*args)
        assert folds.last_dof == ref.last_dof
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())


def test_planar_block_design_and_its_constrained_fit_are_the_dense_ones(monkeypatch):
    """A long planar log's baseline (forced here on 480 touches) keeps the same design as a BlockDesign (the
    targets' block), chooses the same grid with the same rank, and its gauge-constrained workpiece fit (solved
    from the normal matrix) gives the dense SVD's estimates, covariance, estimability and linear map to 1e-9
    relative (the normal matrix squares the conditioning: about 1e-13 here)."""
    from core import baseline as Bm
    from core import discover as X
    from core.diagnosis import orth
    from core.lsq import BlockDesign
    from core.touches import from_log
    from scenarios.bench.probelog import large_log

    t = from_log(large_log(40, 12, np.random.default_rng(19)))
    dense = Bm.planar(t)
    monkeypatch.setattr(Bm, "DENSE_DESIGN_BYTES", 0)
    block = Bm.planar(t)
    assert isinstance(block.A, BlockDesign) and not isinstance(dense.A, BlockDesign)
    assert block.info["grid_step_mm"] == dense.info["grid_step_mm"] and block.qr is None
    assert np.array_equal(block.A.toarray(), dense.A) and block.names == dense.names
    assert block.A.basis().shape == orth(dense.A).shape
    rows = np.arange(3, dense.n)
    for a, b in zip(X._constrained(dense.A, dense.y, dense.C, dense.d, rows, None, 0, True),
                    X._constrained(block.A, block.y, block.C, block.d, rows, None, 0, True)):
        a, b = np.asarray(a, float), np.asarray(b, float)
        assert np.array_equal(np.isfinite(a), np.isfinite(b))
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-9 * np.abs(a).max())


def _planar_dense_and_block(monkeypatch, n_targets=40, n_angles=12):
    """The bench generator's log (``n_targets`` at ``n_angles`` C angles): its planar baseline dense and forced
    through the block design."""
    from core import baseline as Bm
    from core.touches import from_log
    from scenarios.bench.probelog import large_log

    t = from_log(large_log(n_targets, n_angles, np.random.default_rng(19)))
    dense = Bm.planar(t)
    monkeypatch.setattr(Bm, "DENSE_DESIGN_BYTES", 0)
    return dense, Bm.planar(t)


def _same_fit(a, b, tol):
    """Two (theta, cov, est) of _constrained equal: theta and cov to ``tol`` of their largest, est exactly."""
    from core.lsq import DiagLowRank

    for u, v in zip(a[:2], b[:2]):
        u, v = (w.toarray() if isinstance(w, DiagLowRank) else w for w in (u, v))
        np.testing.assert_allclose(v, u, rtol=0, atol=tol * np.abs(u).max())
    assert np.array_equal(a[2], b[2])


def test_workpiece_fit_of_a_long_log_eliminates_the_targets(monkeypatch):
    """The block design's gauge-constrained fit without the linear map (the workpiece's baseline and extended
    fits) eliminates the targets (a Schur complement over the machine's columns and the gauge rows): its
    covariance is kept factored (diag + low rank, never p x p) and equals the dense SVD's, with the estimate,
    to 1e-12 of their largest (measured 1.9e-15 and 2.7e-15 here; the normal equations square a condition
    number of about 700, and one step of refinement on the rows' residuals brings the estimate back), every
    parameter estimable; also on rows leaving some out and with an extension's penalty (its ridge rows)."""
    from core import discover as X
    from core.lsq import DiagLowRank

    dense, block = _planar_dense_and_block(monkeypatch)
    n = dense.n
    for rows in (np.arange(n), np.arange(3, n)):
        a = X._constrained(dense.A, dense.y, dense.C, dense.d, rows, None, 0)
        b = X._constrained(block.A, block.y, block.C, block.d, rows, None, 0)
        assert isinstance(b[1], DiagLowRank) and b[2].all()
        _same_fit(a, b, 1e-12)
        q = block.estimand
        np.testing.assert_allclose(b[1].take(q)[np.ix_(np.arange(7), np.arange(3, 9))], a[1][np.ix_(q, q)][:7, 3:9], rtol=0,
                                   atol=1e-12 * np.abs(a[1]).max())
        np.testing.assert_allclose(b[1].diagonal(), np.diag(a[1]), rtol=0, atol=1e-12 * np.abs(a[1]).max())
        assert b[1][5, 7] == pytest.approx(a[1][5, 7], rel=0, abs=1e-12 * np.abs(a[1]).max())
        with pytest.raises(ConfigError):  # a repeated index: its diagonal term belongs off the diagonal too
            b[1].take(np.array([3, 4, 3]))
    # an extension with a penalty: two columns, a ridge on them
    E = np.random.default_rng(3).normal(size=(n, 2))
    P = np.array([[2.0, 0.5], [0.5, 1.0]])
    C1 = np.hstack([dense.C, np.zeros((dense.C.shape[0], 2))])
    a = X._constrained(np.hstack([dense.A, E]), dense.y, C1, dense.d, np.arange(n), P, 2)
    b = X._constrained(np.hstack([block.A, E]), block.y, C1, block.d, np.arange(n), P, 2)
    assert isinstance(b[1], DiagLowRank)
    _same_fit(a, b, 1e-12)
    # a near-collinear extension (its second column the first plus 1e-3 of another): the equilibrated Schur
    # complement's condition number is 1.0e7 (below SCHUR_COND_MAX, so eliminated), the normal equations lose
    # about that factor, and the refinement step carries the estimate back: 6.0e-13 of its largest with it,
    # 1.0e-9 without it (range(1) in _constrained_schur), so 1e-11 here fails without the step
    e = np.random.default_rng(3).normal(size=n)
    E = np.column_stack([e, e + 1e-3 * np.random.default_rng(4).normal(size=n)])
    a = X._constrained(np.hstack([dense.A, E]), dense.y, C1, dense.d, np.arange(n), None, 0)
    b = X._constrained(np.hstack([block.A, E]), block.y, C1, block.d, np.arange(n), None, 0)
    assert isinstance(b[1], DiagLowRank)
    np.testing.assert_allclose(b[0], a[0], rtol=0, atol=1e-11 * np.abs(a[0]).max())


def test_workpiece_fit_of_a_long_log_not_well_posed_takes_the_whole_normal_matrix(monkeypatch):
    """Where the targets' elimination does not apply, the block design's fit is the dense one's as before
    (a formed p x p covariance, the unseen parameters not estimable): rows that leave a target unseen (its
    count zero: the elimination would divide by it), and a gauge short of one row (the saddle system is
    singular: the elimination would invert a matrix of condition number 1e17 or more)."""
    from core import discover as X

    dense, block = _planar_dense_and_block(monkeypatch)
    rows = np.flatnonzero(block.A.ids != 5)  # target 5 left out
    a = X._constrained(dense.A, dense.y, dense.C, dense.d, rows, None, 0)
    b = X._constrained(block.A, block.y, block.C, block.d, rows, None, 0)
    assert isinstance(b[1], np.ndarray) and not b[2].all()
    _same_fit(a, b, 1e-9)
    C, d = dense.C[1:], dense.d[1:]
    a = X._constrained(dense.A, dense.y, C, d, np.arange(dense.n), None, 0)
    b = X._constrained(block.A, block.y, C, d, np.arange(dense.n), None, 0)
    assert isinstance(b[1], np.ndarray) and not b[2].all()
    _same_fit(a, b, 1e-9)


def test_pivoted_qr_formed_later_is_the_one_formed_at_once():
    """Known answers: Q formed from the reflectors is pivoted_qr's bit for bit (more rows or more columns than the
    other, a zero column); the residual sum of squares from the reflectors is the formed Q's to rounding."""
    from core.diagnosis import qr_formed, qr_rss

    rng = np.random.default_rng(11)
    for shape in ((120, 30), (20, 26), (40, 40)):
        M = rng.normal(size=shape)
        M[:, 3] = M[:, 1] + 2 * M[:, 2]
        M[:, 5] = 0.0
        a, raw = pivoted_qr(M), pivoted_qr(M, q=False)
        b = qr_formed(raw)
        assert all(np.array_equal(x, y) for x, y in zip(a[:2], b[:2])) and b[2] is M
        assert np.array_equal(orth(M, 1e-9, qr=b), orth(M, 1e-9))
        y = rng.normal(size=shape[0])
        for r in (0, 4, a[0].shape[1]):
            e = y - a[0][:, :r] @ (a[0][:, :r].T @ y)
            np.testing.assert_allclose(qr_rss(raw, y, r), e @ e, rtol=1e-12, atol=1e-12 * (y @ y))
            assert qr_rss(a, y, r) == float(e @ e)  # a formed Q: its own sum


def _grid_by_formed_bic(Bm, t):
    """The grid the planar baseline chose before the reflectors' BIC: every grid's Q formed, BIC from it."""
    best = None
    for st in (22.0, 30.0, 40.0, 55.0, 80.0):
        bl = Bm.planar(t, st)
        Q = orth(bl.A, tol=Bm.RANK_TOL, qr=bl.qr)
        if bl.A.shape[1] - Q.shape[1] > np.linalg.matrix_rank(bl.C):
            continue
        r = t.dq_m - Q @ (Q.T @ t.dq_m)
        score = Bm._bic(float(r @ r), t.n, Q.shape[1])
        if best is None or score < best[0]:
            best = (score, st)
    return best[1]


def test_planar_grid_choice_forms_one_q_and_chooses_as_the_formed_bic(monkeypatch):
    """The planar baseline forms the Q of the grid it chooses only, and chooses the grid the formed BICs choose.

    On a noisy campaign the reflectors' BIC decides (one Q formed); on one whose readings a 40 mm map
    reproduces to rounding (its residual sum of squares is rounding, so its BIC is not known to better than
    its bound) the grids are compared by their formed BICs, as before; the kept factorisation is pivoted_qr's
    of the design, bit for bit.
    """
    import dataclasses

    from core import baseline as Bm
    from core.touches import from_log
    from scenarios.bench.probelog import large_log

    formed = []
    real = Bm.qr_formed
    monkeypatch.setattr(Bm, "qr_formed", lambda qr: formed.append(1) or real(qr))
    t = from_log(large_log(40, 12, np.random.default_rng(19)))
    exact = Bm.planar(t, 40.0)
    theta = np.random.default_rng(2).normal(size=exact.A.shape[1]) * 1e-6
    dq = exact.A @ theta  # what a 40 mm map reproduces exactly
    t0 = dataclasses.replace(t, p_R=t.p_R + t.n_R * (dq - t.dq_m)[:, None])  # readings n . (p - pn) = dq
    for tt, n_formed in ((t, 1), (t0, None)):
        formed.clear()
        bl = Bm.planar(tt)
        if n_formed is not None:
            assert len(formed) == n_formed
        else:
            assert len(formed) > 1  # near ties by the bounds: the formed BICs decided
        assert bl.info["grid_step_mm"] == _grid_by_formed_bic(Bm, tt)
        ref = pivoted_qr(bl.A)
        assert all(np.array_equal(x, y) for x, y in zip(bl.qr[:2], ref[:2]))


def test_folds_block_path_sees_a_large_own_column_as_unseen_by_training():
    """A held-out group's own column that is large: its training norm is exactly zero, and the folds must find
    it so (computed from the training rows, not as the total minus the held-out part, whose rounding remainder
    made such a column look trained and extrapolated a fitted rounding error onto the held-out rows; a review
    found it on a stored campaign's C-axis column). Held-out residuals and dof are the dense path's (1e-12)."""
    from core import discover as X

    rng = np.random.default_rng(7)
    A, grp = _block_design(rng)
    A.D[:, -1] *= 1e3  # group 2's own column, 1e3 larger than the others
    Y = rng.normal(size=(len(grp), 2))
    seen = X.Settings().cv_seen
    dense, blocks = X.Folds(A.toarray(), grp, seen), X.Folds(A, grp, seen)
    assert [f.Qo.shape[1] for f in blocks.items] == [f.Qo.shape[1] for f in dense.items]
    a, b = dense.residuals(Y), blocks.residuals(Y)
    assert dense.last_dof == blocks.last_dof
    np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())


def test_planar_grid_choice_compares_a_kept_block_design_with_a_dense_tie(monkeypatch):
    """A block design kept sparse as the best grid so far, then a dense grid whose BIC is within the margin of it
    (an exact fit: every grid's span holds a translation of the whole campaign, the margin is then huge): the tie
    is settled by both grids' formed BICs (main: AttributeError, the kept grid's basis None), and the grid chosen
    is the one chosen when both are dense."""
    from core import baseline as Bm
    from scenarios.bench.probelog import large_log
    from core.touches import from_log
    import dataclasses

    t = from_log(large_log(40, 12, np.random.default_rng(19)))
    t = dataclasses.replace(t, p_R=t.pn_R + np.array([1e-6, -0.5e-6, 0.0]))  # every touch moved as one: exact fit
    steps = (30.0, 55.0)  # (both identifiable on this log; 22 mm is not)
    one = [Bm.planar(t, s) for s in steps]
    p = [b.A.shape[1] for b in one]
    assert p[0] > p[1] and all(b.identifiable for b in one)
    dense = Bm.planar(t, grid_steps_mm=steps)
    monkeypatch.setattr(Bm, "DENSE_DESIGN_BYTES", 8 * t.n * (p[0] + p[1]) // 2)  # 30 mm blocks, 55 dense
    mixed = Bm.planar(t, grid_steps_mm=steps)
    assert mixed.info["grid_step_mm"] == dense.info["grid_step_mm"]


def test_scores_made_a_block_of_rows_at_a_time_are_the_whole_table_s_to_rounding(monkeypatch):
    """A ripple or bump table too big to keep is made afresh a block of rows at a time (SCORE_ROWS_BYTES): with
    blocks forced to one row, every score on all rows and on a subset equals the kept table's to 1e-12 relative
    of the largest score, the best trial is the same (known answers: a 7 mm ripple, a bump at 60 mm), and the
    denominators kept for a set of rows give the same scores again, bit for bit. One block of rows: bit for bit."""
    from core import causes as C

    rng = np.random.default_rng(21)
    n = 500
    x, y = np.sort(rng.uniform(0, 0.2, n)), rng.uniform(0, 0.2, n)
    bl = _plane(x, y, rng)
    ripple = -bl.data.nx * 1e-6 * np.sin(2 * np.pi * x / 7e-3 + 0.4)
    bump = -bl.data.nx * 2e-6 * C._hann((x - 0.06) / 0.004)
    rows, sub = np.arange(n), np.sort(rng.choice(n, 350, replace=False))
    for make, sig, pick in ((lambda: C.periodic_scans(bl)[0][0], ripple, "period_m"),
                            (lambda: C.defect_scans(bl)[0][0], bump, "centre_m")):
        r = sig + rng.normal(0, 1e-7, n)
        kept = make()
        s_all, s_sub = kept.score(r, rows), kept.score(r[sub], sub)
        monkeypatch.setattr(C, "TABLE_BYTES", 0)
        one = make()  # one block of rows (SCORE_ROWS_BYTES whole): the whole products
        assert np.array_equal(one.score(r, rows), s_all) and np.array_equal(one.score(r[sub], sub), s_sub)
        monkeypatch.setattr(C, "SCORE_ROWS_BYTES", 1)
        lazy = make()
        a_all, a_sub = lazy.score(r, rows), lazy.score(r[sub], sub)
        assert np.max(np.abs(a_all - s_all)) <= 1e-12 * np.max(s_all) and not np.array_equal(a_all, s_all)
        assert np.max(np.abs(a_sub - s_sub)) <= 1e-12 * np.max(s_sub)
        assert np.argmax(a_all) == np.argmax(s_all) and np.argmax(a_sub) == np.argmax(s_sub)
        assert np.array_equal(lazy.score(r, rows), a_all)  # (its kept denominators: the same numbers)
        best = kept.infos[int(np.argmax(s_all))][pick]
        assert abs(best - (7e-3 if pick == "period_m" else 0.06)) < (2e-4 if pick == "period_m" else 2e-3)
        monkeypatch.undo()


def test_long_log_trials_tested_in_groups_are_the_whole_batch_bit_for_bit(monkeypatch):
    """A long log's shortlisted dense trials (the basis a core.lsq.Basis) are built and tested a group at a time
    (TRIALS_BLOCK_BYTES): forced to one trial a group, every sum of squares, dimension, F and p-value equals the
    one batch's bit for bit, on every row and on a subset; known answer: the 7 mm ripple's trial is the best; an
    array basis (a short log) takes the one batch whatever the groups' size."""
    from types import SimpleNamespace

    from core import causes as C
    from core import discover as Dc
    from core.lsq import BlockDesign

    rng = np.random.default_rng(23)
    n, g = 600, 40
    x, y = np.sort(rng.uniform(0, 0.2, n)), rng.uniform(0, 0.2, n)
    bl = _plane(x, y, rng)
    sc = C.periodic_scans(bl)[0][0]
    ids = rng.integers(0, g, n)
    A = BlockDesign(ids, rng.normal(size=(n, 3)), np.arange(g), np.arange(g, g + 3))
    obs = -bl.data.nx * 1e-6 * np.sin(2 * np.pi * x / 7e-3 + 0.4) + rng.normal(0, 1e-7, n)
    P = np.array([i["period_m"] for i in sc.infos])
    idx = np.concatenate([[int(np.argmin(np.abs(P - 7e-3)))], rng.choice(len(P), 7, replace=False)])
    for rows in (np.arange(n), np.sort(rng.choice(n, 450, replace=False))):
        Q = A[rows].basis()
        Qd = Q.toarray()
        r = obs[rows] - Qd @ (Qd.T @ obs[rows])
        for basis in (Q, Qd):
            st = SimpleNamespace(Q=basis, rows=rows, r=r, rss=float(r @ r), dof=len(rows) - Qd.shape[1])
            whole = Dc._test_trials(sc, idx, st)
            monkeypatch.setattr(Dc, "TRIALS_BLOCK_BYTES", 1)
            parts = Dc._test_trials(sc, idx, st)
            monkeypatch.undo()
            assert all(np.array_equal(a, b) for a, b in zip(whole, parts)) and len(whole[0]) == 8
            assert np.argmax(whole[0]) == 0 and whole[3][0] < 1e-6


def test_long_log_refinement_built_in_groups_is_the_whole_grid_bit_for_bit(monkeypatch):
    """A long log's refinement (core.discover._refine against a core.lsq.Basis) builds each grid's trials a group at
    a time (REFINE_BLOCK_BYTES, forced to one trial a group): no rebuild makes more than one trial, every grid's
    sums of squares equal the one-shot grid's bit for bit (on every row and on a subset), so the refined
    parameters are the same; known answers: the local defect's centre and half-width refined to within 0.2 mm of
    a 60 mm, 4 mm bump's, the ripple's period to 7 mm. An array basis (a short log) takes the whole grid at once
    whatever the budget. (On the code before the groups a rebuild made the grid's 11 trials at once.)"""
    import dataclasses
    from types import SimpleNamespace

    from core import causes as C
    from core import discover as Dc
    from core.lsq import BlockDesign

    rng = np.random.default_rng(29)
    n, g = 12_000, 40  # (over numpy's 8,192-element buffer: a one-batch einsum splits its sums by the grid's size)
    x, y = np.sort(rng.uniform(0, 0.2, n)), rng.uniform(0, 0.2, n)
    bl = _plane(x, y, rng)
    ids = rng.integers(0, g, n)
    A = BlockDesign(ids, rng.normal(size=(n, 3)), np.arange(g), np.arange(g, g + 3))
    bump = -bl.data.nx * 2e-6 * C._hann((x - 0.06) / 0.004)
    ripple = -bl.data.nx * 1e-6 * np.sin(2 * np.pi * x / 7e-3 + 0.4)
    cases = (("local_scale_defect", bump, {"axis": "X", "centre_m": 0.0612, "half_width_m": 0.0045},
              {"centre_m": 0.06, "half_width_m": 0.004}),
             ("periodic_axis_error", ripple, {"axis": "X", "period_m": 7.1e-3}, {"period_m": 7e-3}))
    for cname, sig, info, truth in cases:
        cause = next(c for c in C.REGISTRY if c.name == cname and "planar" in c.kinds)
        made = []

        def rebuild(b, inf, cause=cause, made=made):
            out = cause.rebuild(b, inf)
            made.append(out.shape[0])
            return out

        cz = dataclasses.replace(cause, rebuild=rebuild)
        obs = sig + rng.normal(0, 1e-7, n)
        for rows in (np.arange(n), np.sort(rng.choice(n, 9_000, replace=False))):
            Q = A[rows].basis()
            Qd = Q.toarray()
            r = obs[rows] - Qd @ (Qd.T @ obs[rows])
            for basis in (Q, Qd):
                st = SimpleNamespace(Q=basis, rows=rows, r=r, rss=float(r @ r), dof=len(rows) - Qd.shape[1])
                whole = Dc._refine(cause, bl, info, st, rows)
                for name in cause.nonlinear:
                    grid = np.linspace(info[name] * 0.9, info[name] * 1.1, 11)
                    batch = Dc._refine_ss(cause, bl, info, name, grid, st, rows, None)  # one nested_f_batch
                    if basis is Qd:
                        assert Dc._refine_group(st, len(rows), 1) is None
                        continue
                    one = Dc._refine_ss(cause, bl, info, name, grid, st, rows, 11)  # the grid built at once
                    for size in (1, 2, 3, 5):
                        assert np.array_equal(Dc._refine_ss(cause, bl, info, name, grid, st, rows, size), one)
                    # (the one batch sums its columns' norms over the grid at once: to rounding only)
                    np.testing.assert_allclose(one, batch, rtol=1e-12, atol=0)
                    assert np.argmax(one) == np.argmax(batch)
                monkeypatch.setattr(Dc, "REFINE_BLOCK_BYTES", 1)
                made.clear()
                grouped = Dc._refine(cz, bl, info, st, rows)
                monkeypatch.undo()
                assert grouped == whole
                assert max(made) == (1 if basis is Q else 11) and len(made) > 1
                for k, v in truth.items():
                    assert abs(whole[k] - v) < 2e-4, (cname, k, whole[k])


def test_one_trial_scans_made_again_at_each_build_are_the_held_ones_bit_for_bit(monkeypatch):
    """Every planar cause's scans of one trial hold their columns while small; above ONE_SCAN_KEEP_BYTES (forced
    to 0) they hold no rows-long array and each build makes the same columns again, bit for bit (the thermal
    drift's polynomials and warm-ups, c_drift's, the lobes', the reversal's, the non-rigid terms)."""
    from core import baseline as Bm
    from core import causes as C
    from core.touches import from_log
    from scenarios.bench.probelog import large_log

    bl = Bm.planar(from_log(large_log(40, 12, np.random.default_rng(4))))
    held = {c.name: c.scans(bl)[0] for c in C.for_kind(bl.kind)}
    monkeypatch.setattr(C, "ONE_SCAN_KEEP_BYTES", 0)
    again = {c.name: c.scans(bl)[0] for c in C.for_kind(bl.kind)}
    made = set()
    for name, scans in held.items():
        assert [s.infos for s in scans] == [s.infos for s in again[name]]
        for a, b in zip(scans, again[name]):
            x, y = a.build([0]), b.build([0])
            assert np.array_equal(x, y) and x.shape[:2] == (1, bl.n)
            cells = [c.cell_contents for c in (b.build.__closure__ or ())]
            if not any(isinstance(v, np.ndarray) and v.ndim >= 2 for v in cells) and len(a.infos) == 1 and \
                    any(isinstance(v, np.ndarray) and v.ndim == 3 for v in (c.cell_contents for c in a.build.__closure__)):
                made.add(name)
    assert {"thermal_drift", "c_drift", "probe_lobing", "reversal", "nonrigid"} <= made


def test_a_one_trial_scan_made_again_is_not_copied_at_its_build(monkeypatch):
    """A one-trial scan made again at each build (above ONE_SCAN_KEEP_BYTES, forced to 0) gives its one trial
    (index [0] or [-1]) as a view of the columns just made, not a copy of them (at 1e6 rows the thermal drift's
    degree-2 layout was a second 61 MiB there): bit for bit the held scan's build; other indices as before
    ([0, 0] two copies, [1] an IndexError). Fails on cd76bae: the build copied (its own data)."""
    from core import baseline as Bm
    from core import causes as C
    from core.touches import from_log
    from scenarios.bench.probelog import large_log

    bl = Bm.planar(from_log(large_log(40, 12, np.random.default_rng(4))))
    cause = next(c for c in C.for_kind(bl.kind) if c.name == "thermal_drift")
    held = cause.scans(bl)[0]
    monkeypatch.setattr(C, "ONE_SCAN_KEEP_BYTES", 0)
    again = cause.scans(bl)[0]
    ones = [(a, b) for a, b in zip(held, again) if len(a.infos) == 1]
    assert len(ones) >= 3
    for a, b in ones:
        ref = a.build([0])
        for idx in ([0], [-1], np.array([0]), (0,)):
            x = b.build(idx)
            assert not x.flags.owndata and x.flags.c_contiguous
            assert np.array_equal(x, ref) and x.dtype == ref.dtype and x.shape == ref.shape
        two = b.build([0, 0])
        assert two.flags.owndata or two.base.shape == two.shape  # indexed: its own array
        assert two.shape == (2,) + ref.shape[1:] and np.array_equal(two[1], ref[0])
        assert b.build(np.array([], int)).shape == (0,) + ref.shape[1:]
        with pytest.raises(IndexError):
            b.build([1])


def test_planar_baseline_info_holds_the_grid_not_the_design(monkeypatch):
    """A planar baseline's ``info`` holds its error map's grid, not the self-calibration design: the design's
    sparse A (one row per touch, 177 MiB at 1e6 rows, a copy beside the baseline's own A) was held for the run
    and read only for its grid. No array reachable from ``info`` has a row per touch (a long log's and a short
    one's); the grid is the design's, node for node, and the smooth error map built from it. Fails on cd76bae
    (``info["design"]``)."""
    import dataclasses

    import scipy.sparse as sp

    from core import baseline as Bm
    from core import causes as C
    from core import selfcal
    from core.touches import from_log
    from scenarios.bench.probelog import large_log

    t = from_log(large_log(40, 12, np.random.default_rng(19)))

    def arrays(o, depth=0):
        if isinstance(o, np.ndarray) or sp.issparse(o):
            yield o
        elif depth < 4 and isinstance(o, dict):
            for v in o.values():
                yield from arrays(v, depth + 1)
        elif depth < 4 and isinstance(o, (list, tuple)):
            for v in o:
                yield from arrays(v, depth + 1)
        elif depth < 4 and dataclasses.is_dataclass(o) and not isinstance(o, type):
            for f in dataclasses.fields(o):
                yield from arrays(getattr(o, f.name), depth + 1)

    short = Bm.planar(t)
    monkeypatch.setattr(Bm, "DENSE_DESIGN_BYTES", 0)
    long_ = Bm.planar(t)
    for bl in (short, long_):
        assert "design" not in bl.info and isinstance(bl.info["grid"], selfcal.Grid)
        assert all(a.shape[0] != bl.n for a in arrays(bl.info) if a.ndim)
    st = short.info["grid_step_mm"]
    assert long_.info["grid_step_mm"] == st
    g = short.info["grid"]
    assert np.array_equal(g.x_m, long_.info["grid"].x_m) and np.array_equal(g.y_m, long_.info["grid"].y_m)
    assert np.all(np.diff(g.x_m) > 0) and np.allclose(np.diff(g.x_m), st * 1e-3)
    E = C.smooth_error_map(short)
    assert E.shape[0] == short.n and np.array_equal(E, C.smooth_error_map(long_))


def test_projection_beside_a_declared_baseline_basis_is_the_one_step_projection():
    """project_out against a basis declared by extends (``[Qb, U]``): the part outside ``Qb`` kept and taken again.

    Known answers: against ``Qb`` itself the one-step product bit for bit; beside ``U`` (orthogonal to ``Qb``) the
    one-step product to rounding, and again the same numbers whether the kept part is taken (a hit) or made (the
    memo emptied); the result orthogonal to ``Q``. Bad inputs: columns with the same fingerprint (first row and
    column sums) but other numbers are not taken for the kept ones; a result written to (a caller's in-place
    temporary) does not change what is kept; an undeclared basis projects in one step.
    """
    rng = np.random.default_rng(7)
    n = 60
    Qb = np.linalg.qr(rng.normal(size=(n, 12)))[0]
    U = D.new_basis(Qb, rng.normal(size=(n, 3)))
    Q = np.hstack([Qb, U])
    B = np.round(rng.normal(size=(n, 5)) * 8) / 8  # (eighths: the column sums below are exact)

    def one_step(Qm, X):
        return X - Qm @ (Qm.T @ X)

    undeclared = np.array(Q)
    assert np.array_equal(D.project_out(undeclared, B), one_step(undeclared, B))
    D.extends(Qb, Qb)
    D.extends(Q, Qb)
    base = D.project_out(Qb, B)
    assert np.array_equal(base, one_step(Qb, B))  # made: bit for bit the one-step product
    base[:] = 0.0  # a caller writes over its result: the kept part is not touched
    assert np.array_equal(D.project_out(Qb, B), one_step(Qb, B))  # taken: the same numbers
    tmp = np.array(B)
    assert D.project_out(Qb, tmp, inplace=True) is tmp and np.array_equal(tmp, one_step(Qb, B))
    ext = D.project_out(Q, B)  # taken beside U
    assert np.allclose(ext, one_step(Q, B), rtol=0, atol=1e-13)
    assert np.abs(Q.T @ ext).max() < 1e-13
    D._OUTSIDE_BASE._d.clear()
    assert np.array_equal(D.project_out(Q, B), ext)  # made afresh: the same numbers as taken
    # the same first row and column sums, other numbers: a fingerprint's collision is not a hit
    B2 = np.array(B)
    B2[1:3, 0] += np.array([1.0, -1.0])
    assert np.array_equal(B2[0], B[0]) and np.array_equal(np.einsum("ij->j", B2), np.einsum("ij->j", B))
    assert np.allclose(D.project_out(Q, B2), one_step(Q, B2), rtol=0, atol=1e-13)
    assert not np.allclose(D.project_out(Q, B2), ext)
    # new_basis and nested_f_batch through it: as through the one-step projection
    assert np.allclose(D.new_basis(Q, B), D.new_basis(undeclared, B), rtol=0, atol=1e-12)
    r = one_step(Q, rng.normal(size=n))
    C = rng.normal(size=(4, n, 2))
    for a, b in zip(D.nested_f_batch(C, Q, r, float(r @ r), n - 15), D.nested_f_batch(C, undeclared, r, float(r @ r),
                                                                                        n - 15)):
        assert np.allclose(a, b, rtol=1e-10, atol=0)
    D.release_projections()  # (the declarations and parts this test kept: the module's memos as it found them)


def test_folds_given_the_basis_they_would_make_are_the_folds_made_afresh():
    """Known answer: Folds (and CpEstimate) given ``orth(A)`` (the engine's model basis of the rows) hold that very
    array and give the held-out residuals of the folds that factor ``A`` themselves, bit for bit. Bad input: a
    basis of other rows is refused."""
    import core.discover as X

    rng = np.random.default_rng(11)
    n = 48
    groups = np.repeat(np.arange(4), n // 4)
    A = np.hstack([np.eye(4)[groups], rng.normal(size=(n, 5))])
    y, E = rng.normal(size=n), rng.normal(size=(n, 2))
    seen = X.Settings().cv_seen
    Qa = orth(A)
    given, made = X.Folds(A, groups, seen, basis=Qa), X.Folds(A, groups, seen)
    assert given.Q is Qa
    assert np.array_equal(given.residuals(y), made.residuals(y))
    assert np.array_equal(given.residuals(y, E), made.residuals(y, E))
    assert X.CpEstimate(A, groups, seen, basis=Qa).Q is Qa
    with pytest.raises(ConfigError, match="basis of 47 rows"):
        X.Folds(A, groups, seen, basis=Qa[:-1])


def test_a_discover_run_leaves_no_projection_kept(monkeypatch):
    """The parts outside a run's bases are forgotten when the run ends (later runs' bases are other arrays): after
    discover nothing is declared or kept; during it the rounds did keep some (the memo is used at all)."""
    import gzip
    import pathlib

    from core.discover import discover
    from core.probelog import parse_probe_log
    from core.touches import from_log

    path = pathlib.Path(__file__).parent / "data" / "discover_identity" / "demo.csv.gz"
    t = from_log(parse_probe_log(gzip.decompress(path.read_bytes()).decode(), "demo"))
    kept = []
    real = D._project_out_extended

    def spy(*a):
        kept.append(len(D._OUTSIDE_BASE))
        return real(*a)

    monkeypatch.setattr(D, "_project_out_extended", spy)
    discover(t)
    assert max(kept) > 0
    assert len(D._EXTENDS) == len(D._OUTSIDE_BASE) == 0


def test_first_largest_takes_the_earliest_of_tied_statistics():
    """The outlier screen's pick among statistics tied in exact arithmetic is the earliest row, whatever the
    rounding (gen_a reseat_hysteresis 1087: rows 83 and 85 at t 8.667225540449, 1e-14 apart, picked by the BLAS
    kernel's rounding before); a real difference, even of 1e-8 relative, still picks the largest."""
    from core.diagnosis import ARGMAX_TIE_RTOL, _first_largest

    t = np.array([3.0, 8.667225540449035, 1.0, 8.667225540448928, 2.0])
    assert _first_largest(t) == 1
    assert _first_largest(t[::-1]) == 1  # (reversed: the tied pair is at 1 and 3; the earliest wins)
    u = t.copy()
    u[3] *= 1 + 1e-8
    assert _first_largest(u) == 3 and 1e-8 > ARGMAX_TIE_RTOL
    assert _first_largest(np.array([0.0, 0.0])) == 0 and _first_largest(np.array([-2.0, -1.0])) == 1
    assert _first_largest(np.array([1.0, np.nan, 2.0])) == int(np.argmax([1.0, np.nan, 2.0]))  # (no IndexError)


def test_a_discover_run_that_raises_leaves_no_projection_kept(monkeypatch):
    """The same when the run raises part way (session 17's review: the release was a plain call before the
    report, so an error after the rounds left up to 128 MiB held until the next run ended)."""
    import gzip
    import pathlib

    import core.discover as X
    from core.probelog import parse_probe_log
    from core.touches import from_log

    path = pathlib.Path(__file__).parent / "data" / "discover_identity" / "demo.csv.gz"
    t = from_log(parse_probe_log(gzip.decompress(path.read_bytes()).decode(), "demo"))

    def fails(*a, **k):
        assert len(D._OUTSIDE_BASE) > 0  # (the rounds kept some: the release matters)
        raise RuntimeError("stop after the rounds")

    monkeypatch.setattr(X, "_noise_report", fails)
    with pytest.raises(RuntimeError, match="stop after the rounds"):
        X.discover(t)
    assert len(D._EXTENDS) == len(D._OUTSIDE_BASE) == 0
