"""rank30's leftovers (session 30, rank30b): the outlier screen's refitted bases and the long log's elimination at
the baseline's rank tolerance (the log's printed precision, ``core.baseline.precision_rank_tol``).

review30c's plate logs (tests/core/data/rank30, test_discover_rank30.py) printed to fewer decimals: their two
rounding directions sit at QR pivots ~1-2 ``q / L`` of the largest; the baseline's ``rank_tol`` (10 ``q / L``) drops
them. Every fit of the same rows must drop them too.
"""
import numpy as np
import pytest

from core import baseline as B
from core import discover as D
from core.lsq import BlockDesign, DiagLowRank

from test_discover_rank30 import _decisions, _join, _planar, _rounded, _rows, _text


@pytest.fixture(scope="module")
def plate4():
    """plate_none_300 with Xn, Yn, Zn printed to 4 decimals of a mm: its planar baseline (rank 113 at its
    rank_tol 1.2e-5; 115 at 1e-9: the two rounding directions) and the baseline's basis Qall."""
    _, bl = _planar(_rounded(_text("plate_none_300"), 4))
    A = np.asarray(bl.A)
    Qall = D.orth_of(A, tol=bl.rank_tol, qr=bl.qr)
    assert Qall.shape[1] == 113 and D.orth_of(A).shape[1] == 115
    return bl, A, Qall


@pytest.mark.parametrize("row, m, flagged", [(100, 7.335, True), (10, 8.275, False)])
def test_outlier_screen_factors_the_rows_at_the_baselines_rank_tol(plate4, row, m, flagged):
    """The screen's verdict on a row does not depend on whether the caller hands it the baseline's basis (the
    engine's first screen: Qall, cut at rank_tol) or lets it factor the design itself (the extended designs'
    screens, a long log's rows after a removal, the slip test's fits). Known answers: one row of the 4-decimal
    log moved by ``m`` residual sigmas, halfway between the two thresholds the bisection measured with Qall
    (row 100: 7.279 sigma, row 10: 8.299) and with the screen's old 1e-9 cut (7.391 and 8.250: two more
    parameters made of the file's rounding move the deleted t and the Bonferroni bound's dof), 0.05 sigma from
    each. Fails with OUTLIER_RANK_TOL off (row 100 not flagged, row 10 flagged)."""
    bl, A, Qall = plate4
    y = bl.y.copy()
    y[row] += m * np.std(bl.y - Qall @ (Qall.T @ bl.y))
    given = D.find_outliers(A, y, Q=Qall, rank_tol=bl.rank_tol)
    assert (row in given) is flagged
    assert D.find_outliers(A, y, Q=None, rank_tol=bl.rank_tol) == given
    # no rank_tol (a design without one): orth_of's 1e-9, as before
    assert (row in D.find_outliers(A, y, Q=None)) is not flagged


def _dense_and_block(text, monkeypatch):
    t, dense = _planar(text)
    with monkeypatch.context() as mp:
        mp.setattr(B, "DENSE_DESIGN_BYTES", 0)
        block = B.planar(t)
    assert isinstance(block.A, BlockDesign) and not isinstance(dense.A, BlockDesign)
    assert block.rank_tol == dense.rank_tol and block.info["grid_step_mm"] == dense.info["grid_step_mm"]
    return dense, block


def _same_fit(a, b, tol):
    for u, v in zip(a[:2], b[:2]):
        u, v = (w.toarray() if isinstance(w, DiagLowRank) else w for w in (u, v))
        np.testing.assert_allclose(v, u, rtol=0, atol=tol * np.abs(u).max())
    assert np.array_equal(a[2], b[2])


@pytest.mark.parametrize("k", [None, 4, 3])
def test_long_log_elimination_agrees_with_the_dense_fit_on_a_rounded_log(monkeypatch, k):
    """The long log's fit eliminates the targets (_constrained_schur) on the rounded plate logs (their gauge's
    smallest direction 0.036 of the largest, condition 2.2e3: far from any cut) and equals the dense SVD's at the
    baseline's rank_tol: estimate and covariance to 1e-12 of their largest (measured at most 5e-14 on both
    logs, full precision and 5, 4, 3 decimals, every grid), the same parameters estimable."""
    text = _text("plate_none_300") if k is None else _rounded(_text("plate_none_300"), k)
    dense, block = _dense_and_block(text, monkeypatch)
    for rows in (np.arange(dense.n), np.arange(3, dense.n)):
        a = D._constrained(dense.A, dense.y, dense.C, dense.d, rows, None, 0, tol=dense.rank_tol)
        b = D._constrained(block.A, block.y, block.C, block.d, rows, None, 0, tol=block.rank_tol)
        assert isinstance(b[1], DiagLowRank) and b[2].all()
        _same_fit(a, b, 1e-12)


@pytest.mark.parametrize("eps", [3e-3, 1e-3])
def test_long_log_elimination_leaves_a_direction_near_the_cut_to_the_whole_matrix(monkeypatch, eps):
    """A log printed to 2 decimals of a mm (rank_tol 1.2e-3) with a near-collinear extension (its second column
    the first plus ``eps`` of another): the gauge's direction along their difference is at 9.2e-4 (eps 3e-3) or
    3.1e-4 (1e-3) of the largest, below the cut, so the dense fit leaves 9 parameters estimable; the equilibrated
    Schur complement's condition number is 1.3e6 or 1.2e7, below SCHUR_COND_MAX (1e8). Without
    SCHUR_TOL_MARGIN the elimination kept that direction (all 128 estimable, the estimate 17% and 53% of its
    largest from the dense one's); with it (the condition above 1 / (10 x 1.2e-3)^2 = 6.9e3) the whole normal
    matrix decides, as the dense fit."""
    dense, block = _dense_and_block(_rounded(_text("plate_none_300"), 2), monkeypatch)
    n = dense.n
    assert dense.rank_tol == pytest.approx(1.2e-3, rel=0.01)
    e = np.random.default_rng(3).normal(size=n)
    E = np.column_stack([e, e + eps * np.random.default_rng(4).normal(size=n)])
    C1 = np.hstack([dense.C, np.zeros((dense.C.shape[0], 2))])
    a = D._constrained(np.hstack([dense.A, E]), dense.y, C1, dense.d, np.arange(n), None, 0, tol=dense.rank_tol)
    b = D._constrained(np.hstack([block.A, E]), block.y, C1, block.d, np.arange(n), None, 0, tol=block.rank_tol)
    assert not a[2].all() and not isinstance(b[1], DiagLowRank)
    _same_fit(a, b, 1e-9)


# ---- normals printed to 4 decimals (rank30's "not done"): read, normalised, their step in the rank tolerance ----

_HDR = "setup,target,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz"


def test_normals_printed_to_4_decimals_are_read_normalised_with_their_step():
    """Known answers: ``0.7071,0.7071,0`` has length 0.99999040 (1e-6 refused it before); printed to 4 decimals a
    unit vector misses 1 by at most sqrt(3) x 0.5e-4 = 8.7e-5, so it is read, stored normalised (length 1 to
    1e-15, direction kept) and the step 1e-4 kept for the rank tolerance. A log whose normals pass 1e-6 is stored
    as written (no step)."""
    from core.probelog import parse_probe_log
    from core.touches import from_log

    text = _HDR + "\ns1,p1,0,1,1,0,1,1,0,0.7071,0.7071,0\ns1,p2,1,2,0,0,2,0,0,1.0000,0.0000,0.0000\n"
    log = parse_probe_log(text, "n4.csv")
    n = log.normals()
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(n[0], [np.sqrt(0.5), np.sqrt(0.5), 0.0], rtol=0, atol=1e-15)
    assert np.array_equal(n[1], [1.0, 0.0, 0.0])
    assert log.unit_steps == {"nx": pytest.approx(1e-4)}
    assert from_log(log).n_step == pytest.approx(1e-4)
    full = parse_probe_log(_HDR + "\ns1,p1,0,1,1,0,1,1,0,0.707106781,0.707106781,0\n", "n9.csv")
    assert full.unit_steps == {} and full.normals()[0, 0] == 0.707106781 and from_log(full).n_step == 0.0


@pytest.mark.parametrize("cells, match", [
    ("0.7071,0.7075,0", r"n5\.csv: row 0 \(line 2\): vector \(nx,ny,nz\) has length 1.00027\d*, not 1 "
                        r"\(tolerance 1e-06; 8\.8e-05 for components printed to 0\.0001\)"),
    ("0.707,0.707,0", r"has length 0.999848989, not 1 \(tolerance 1e-06; components printed to 0\.001, coarser "
                      r"than 0\.0001\)"),
])
def test_normals_off_their_printed_step_are_refused(cells, match):
    """Bad input: 4-decimal components whose length misses 1 by more than their rounding allows (2.8e-4 against
    8.8e-5), and 3-decimal normals (0.5 mrad of direction: refused as before), each one line naming the file,
    the row, the length and the tolerance."""
    from core.exceptions import ProbeLogError
    from core.probelog import parse_probe_log

    with pytest.raises(ProbeLogError, match=match):
        parse_probe_log(_HDR + f"\ns1,p1,0,1,1,0,1,1,0,{cells}\n", "n5.csv")


def _unit_rounded(text: str, k: int) -> str:
    """The log with every unit-vector column (nx.., wnx..) printed to ``k`` decimals as well."""
    meta, hdr, rows = _rows(text)
    h = hdr.split(",")
    ix = [h.index(c) for c in ("nx", "ny", "nz", "dx", "dy", "dz", "wnx", "wny", "wnz") if c in h]
    for r in rows:
        for i in ix:
            if r[i]:
                r[i] = f"{float(r[i]):.{k}f}"
    return _join(meta, hdr, rows)


def test_normals_rounded_to_4_decimals_keep_the_design_decisions(monkeypatch):
    """review30c's plate_none_300 with its nominals and its normals printed to 4 decimals: the normals' rounding
    (up to 5e-5 rad) makes directions far above the coordinates' tolerance (1.2e-5); with the printed step in the
    rank tolerance (10 x 1e-4 = 1e-3) the log keeps the full-precision log's grid (55 mm), rank (113) and
    estimable workpiece, within 0.1 um RMS of it (the nominals' rounding alone moves it 0.032 um; measured 0.032
    with the normals too). Without the step (rank30's trial, Touches.n_step 0): another grid or rank."""
    import dataclasses

    full = _text("plate_none_300")
    g0, r0, e0, w0 = _decisions(_planar(full)[1])
    t, bl = _planar(_unit_rounded(_rounded(full, 4), 4))
    assert t.n_step == pytest.approx(1e-4) and bl.rank_tol == pytest.approx(1e-3)
    g, r, e, w = _decisions(bl)
    assert (g, r, e) == (g0, r0, e0) == (55.0, 113, True)
    assert np.sqrt(np.mean((w - w0) ** 2)) < 0.1
    bl_old = B.planar(dataclasses.replace(t, n_step=0.0))
    assert _decisions(bl_old)[:2] != (g0, r0)


def test_axis_aligned_normals_are_exact_at_any_step():
    """A log whose normals all lie along the axes (``1,0,0``: a prismatic part probed at C = 0, 90, 180, 270) has
    no printed step in its normals: before, decimal_quantum read them as printed to whole units and the planar
    rank tolerance became 10 (every direction unseen). Known answer: the 41 axis-aligned touches of
    plate_none_300 (its first set-up's walls and top) take the coordinates' tolerance (7 decimals: RANK_TOL), as
    the whole log does."""
    t, bl = _planar(_text("plate_none_300"))
    ax = np.all(np.isin(t.n_R, (0.0, 1.0, -1.0)), axis=1)
    assert ax.sum() == 41
    assert B.precision_rank_tol(t.subset(ax), B.c_axis_centre(t)) == bl.rank_tol == B.RANK_TOL
