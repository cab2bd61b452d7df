"""Where residual structure lives: covariate tests and the noise floor, without a catalogue.

Discovery (:mod:`core.discover`) names causes from a catalogue
(:mod:`core.causes`); this module answers the questions that must not
depend on it:

1. **How large is the noise?** From repeated touches (pure replicate
   scatter, :func:`replicate_scatter`) and from the gap between in-sample
   and cross-validated residuals (:func:`cv_gap`).
2. **Where does the structure live?** For every covariate the log holds
   (time, time within the set-up, set-up, C, x, y, z, approach azimuth and
   elevation, feature, each ``temp_*_C``, touch order) a smooth function of
   it is added to the model and its explained variance tested
   (:func:`diagnose`).

The test (:func:`nested_f`) is the classical F test of a nested linear
model: the smooth term's columns ``B`` are projected out of the current
model's column space, and under Gaussian noise of one variance the statistic
``F = (SS_B / k) / ((RSS - SS_B) / (dof - k))`` follows ``F(k, dof - k)``
exactly, whatever the model. Over the covariates the p-values are adjusted
by Holm's step-down method (:func:`holm`), which holds the family-wise
error rate under any dependence between the tests (covariates such as time
and touch order are strongly correlated). The explained RMS is debiased:
``sqrt(max(SS_B - k s^2, 0) / n)``, zero on average for pure noise.

A smooth function of a covariate ``v`` acts on a touch through *response
modes*: for the planar baseline a scalar (pre-travel, the part's surface)
and the six components of an affine displacement field of the tip in the
machine frame (x and y translation, x and y scale, the two shears, whose
difference is a rotation), all on centred, scaled coordinates
(:func:`core.baseline.planar_modes`). The basis of the term is every mode
times every basis function of ``v`` (B-splines with knots at quantiles of
``v``, a Fourier series for an angle, indicators for a category), so a
machine error that follows ``v`` with any direction is seen, not only a
scalar trend. Quantile knots and centred coordinates make the tests
invariant to translating the campaign or renumbering its set-ups.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy import special, stats
from scipy.interpolate import BSpline

from .exceptions import ConfigError
from .lsq import Basis, _dense, group_sums, row_blocks
from .memo import Memo
from .units import UM

#: Relative column norm (after projection out of the model) below which a
#: basis column counts as already inside the model.
IN_SPAN = 1e-6


# ---------------------------------------------------------------------------
# linear algebra
# ---------------------------------------------------------------------------
#: Above this many bytes a C-ordered float64 matrix of two or more columns has its column norms (:func:`col_norms`)
#: summed :data:`LONG_ROWS` rows at a time, and :func:`new_basis` projects and rotates it a block of rows at a time
#: in its own memory: at 1e6 rows a sine's eight columns (61 MiB) had a squared copy, the model's product and the
#: rotated basis beside them, each as large.
LONG_BYTES = 16 << 20
#: Rows of one such block.
LONG_ROWS = 8192
#: Columns at most of a matrix those blocks take (a sine's eight, a drift's twelve: narrow; wider ones as before).
LONG_COLS = 16


def col_norms(M: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(M, axis=0)`` bit for bit: for a float64 ``M`` its own expression without the copy
    ``M.conj()`` makes of a real array (``sqrt(add.reduce(M * M, axis=0))``, the same product in the same layout and
    the same reduction; 33 -> 20 us for 432 x 6, session 23), any other array by numpy's.

    A long C-ordered ``M`` (over :data:`LONG_BYTES`, two or more columns) is squared :data:`LONG_ROWS` rows at a
    time, each block's reduction started from the sums so far (a block's first row): numpy reduces the leading
    axis of such an array row after row, so the sums are the whole reduction's bit for bit
    (tests/core/test_long_basis.py); one column alone is summed pairwise and is left whole."""
    if isinstance(M, np.ndarray) and M.dtype == np.float64 and M.ndim == 2:
        n, k = M.shape
        if 2 <= k <= LONG_COLS and M.nbytes > LONG_BYTES and M.flags.c_contiguous:
            buf = np.empty((min(LONG_ROWS, n) + 1, k))
            np.multiply(M[:LONG_ROWS], M[:LONG_ROWS], out=buf[:min(LONG_ROWS, n)])
            acc = np.add.reduce(buf[:min(LONG_ROWS, n)], axis=0)
            for a in range(LONG_ROWS, n, LONG_ROWS):
                b = min(a + LONG_ROWS, n)
                buf[0] = acc
                np.multiply(M[a:b], M[a:b], out=buf[1:b - a + 1])
                acc = np.add.reduce(buf[:b - a + 1], axis=0)
            return np.sqrt(acc)
        return np.sqrt(np.add.reduce(M * M, axis=0))
    return np.linalg.norm(M, axis=0)


def pivoted_qr(M: np.ndarray, q: bool = True):
    """The factorisation :func:`orth` cuts: ``(Q, d, M)``, pivoted QR of ``M`` with columns scaled.

    ``Q`` (n, p') its orthonormal factor over the non-zero columns, ``d``
    (p',) the magnitudes of R's diagonal (decreasing), ``M`` the matrix
    factored (so that a holder can tell which matrix it belongs to).

    ``q=False``: ``Q`` not formed yet (a :class:`HouseholderQ`, LAPACK's
    reflectors): :func:`qr_formed` forms it, bit for bit the ``Q`` of
    ``pivoted_qr(M)`` (the same factorisation, then the same ``orgqr``
    call as scipy's economic mode), and :func:`qr_rss` gives a vector's
    residual sum of squares from the reflectors without it (what the planar
    baseline's grid choice needs of the grids it does not choose).
    """
    if M.ndim != 2 or M.shape[1] == 0:
        return np.zeros((M.shape[0], 0)), np.zeros(0), M
    nrm = col_norms(M)
    keep = nrm > 0
    if not keep.any():
        return np.zeros((M.shape[0], 0)), np.zeros(0), M
    Ms = M[:, keep] / nrm[keep]
    if not q:
        (H, tau), R, _ = sla.qr(Ms, mode="raw", pivoting=True)
        return HouseholderQ(H, tau), np.abs(np.diag(R)), M
    if Ms.shape[0] >= Ms.shape[1] and np.isfinite(Ms).all():
        return _qr_economic_pivoted(Ms) + (M,)
    Q, R, _ = sla.qr(Ms, mode="economic", pivoting=True)  # (more columns than rows; or not finite: scipy's error)
    return Q, np.abs(np.diag(R)), M


def _qr_economic_pivoted(A: np.ndarray):
    """``(Q, |diag R|)`` of ``sla.qr(A, mode="economic", pivoting=True)`` for a finite ``A`` of at least as many rows
    as columns, bit for bit: the same two LAPACK calls (``geqp3`` on a copy, then ``orgqr`` in place on its
    reflectors, each with the workspace LAPACK asks for, asked once per shape), without scipy's argument handling
    and its ``triu`` (33 -> 20 us at 128 x 12; ``R``'s diagonal is the reflectors' diagonal). Session 24."""
    geqp3, orgqr = sla.get_lapack_funcs(("geqp3", "orgqr"), (A,))
    shape = A.shape + (geqp3.typecode,)
    if shape not in _QR_LWORK:  # the workspaces LAPACK asks for depend on the shape alone (ilaenv's block sizes)
        _QR_LWORK[shape] = (int(geqp3(A, lwork=-1)[-2][0].real), None)
    lw, lw_q = _QR_LWORK[shape]
    qr, _jpvt, tau, _work, info = geqp3(A, lwork=lw, overwrite_a=False)
    if info < 0:
        raise ValueError(f"illegal value in {-info}th argument of internal geqp3")
    d = np.abs(np.diag(qr))  # (before orgqr overwrites it)
    if lw_q is None:
        lw_q = int(orgqr(qr, tau, lwork=-1)[-2][0].real)
        _QR_LWORK[shape] = (lw, lw_q)
    Q, _work, info = orgqr(qr, tau, lwork=lw_q, overwrite_a=1)
    if info < 0:
        raise ValueError(f"illegal value in {-info}th argument of internal gorgqr/gungqr")
    return Q, d


#: (rows, columns, LAPACK's type) -> the workspaces geqp3 and orgqr ask for (:func:`_qr_economic_pivoted`)
_QR_LWORK: dict = {}


@dataclass(frozen=True)
class HouseholderQ:
    """The orthonormal factor of a :func:`pivoted_qr` not yet formed: LAPACK's reflectors ``H`` (n, p') and ``tau``."""

    H: np.ndarray
    tau: np.ndarray


def _lapack(name: str, f, *args, **kw):
    """``f(*args, lwork=..., **kw)`` with the workspace LAPACK asks for, as scipy's own QR calls it."""
    ret = f(*args, lwork=-1, **kw)
    ret = f(*args, lwork=ret[-2][0].real.astype(np.int_), **kw)
    if ret[-1] < 0:
        raise ValueError(f"illegal value in {-ret[-1]}th argument of internal {name}")
    return ret[:-2]


def qr_formed(qr):
    """:func:`pivoted_qr` ``(Q, d, M)`` with ``Q`` formed: bit for bit ``pivoted_qr(M)`` (one made with ``q=False``)."""
    Q, d, M = qr
    if not isinstance(Q, HouseholderQ):
        return qr
    orgqr, = sla.get_lapack_funcs(("orgqr",), (Q.H,))
    H = Q.H[:, :Q.H.shape[0]] if Q.H.shape[0] < Q.H.shape[1] else Q.H  # (fewer rows than columns: scipy's first M)
    return _lapack("orgqr", orgqr, H.copy(), Q.tau, overwrite_a=1)[0], d, M


def qr_rss(qr, y: np.ndarray, r: int) -> float:
    """``|y - Q_r Q_r^T y|^2`` for the first ``r`` columns of a :func:`pivoted_qr`'s ``Q``, formed or not.

    From the reflectors: ``c = Q_full^T y`` (an orthogonal transformation),
    the sum of ``c[r:] ** 2``; the same number to rounding as from the
    formed ``Q``, not bit for bit.
    """
    Q = qr[0]
    if not isinstance(Q, HouseholderQ):
        e = y - Q[:, :r] @ (Q[:, :r].T @ y)
        return float(e @ e)
    ormqr, = sla.get_lapack_funcs(("ormqr",), (Q.H,))
    c = _lapack("ormqr", ormqr, "L", "T", Q.H[:, :len(Q.tau)], Q.tau, np.asarray(y, float)[:, None].copy())[0][:, 0]
    return float(c[r:] @ c[r:])


def orth(M: np.ndarray, tol: float = 1e-9, qr=None) -> np.ndarray:
    """(n, r) orthonormal basis of the column space of ``M`` (columns scaled first).

    Pivoted QR; the rank is the number of ``|R_ii| > tol |R_00|``.
    ``qr``: :func:`pivoted_qr` of this very ``M``, when already computed
    (one factorisation cut at two tolerances); ignored for another matrix.
    """
    Q, d, of = qr if qr is not None and qr[2] is M else pivoted_qr(M)
    return Q[:, :qr_rank(d, tol)]


def qr_rank(d: np.ndarray, tol: float) -> int:
    """The rank :func:`orth` cuts a :func:`pivoted_qr`'s ``|R_ii|`` (``d``) at: the number above ``tol |R_00|``."""
    return int(np.sum(d > tol * d[0])) if d.size else 0


def project_out(Q: np.ndarray, B: np.ndarray, inplace: bool = False) -> np.ndarray:
    """``B`` less its projection on the orthonormal columns ``Q``.

    ``inplace``: ``B`` (a temporary of the caller's) is overwritten with
    the result (the same numbers, one array fewer).

    A model basis declared by :func:`extends` (``Q = [Qb, U]``, the
    engine's states: the baseline's basis and the terms' directions beyond
    it) projects in two steps, ``Pb = B - Qb Qb^T B`` then ``Pb - U U^T Pb``,
    and keeps ``Pb`` (:data:`_OUTSIDE_BASE`): the same columns projected
    again against the same baseline (every round tests the catalogue's
    trials and the covariates' terms again beside a few more directions)
    pay for ``U`` only. Against ``Qb`` itself the numbers are the one-step
    product's bit for bit; beside ``U`` the same to rounding (``U`` is
    orthogonal to ``Qb``).
    """
    if not Q.shape[1]:
        return B if inplace else B.copy()
    ext = _extension_of(Q, B)
    if ext is not None:
        return _project_out_extended(Q, ext, B, inplace)
    if isinstance(Q, np.ndarray) and isinstance(B, np.ndarray) and B.ndim == 2 and B.nbytes > 2 * PROJECT_BLOCK_BYTES:
        return _project_blocks(Q, B if inplace else B.copy())
    if inplace and isinstance(Q, Basis) and isinstance(B, np.ndarray) and B.ndim == 2 and B.nbytes > LONG_BYTES:
        # a long log's block basis: Q Q^T B subtracted a block of rows at a time (the same numbers, no n x m product)
        return Q.subtract_matmul(Q.T @ B, B, LONG_ROWS)
    QB = Q @ (Q.T @ B)
    return np.subtract(B, QB, out=B) if inplace else B - QB


def _project_blocks(Q: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``B - Q Q^T B`` written over ``B``, a block of :data:`PROJECT_BLOCK_BYTES` of columns at a time (at least 16):
    a block and its product stay in the core's cache (the rival check's 480 slip columns on the demo: 4.9 -> 3.3 ms
    a call in one step; the same products column by column, bit for bit at the demo's 432 rows)."""
    w = max(16, PROJECT_BLOCK_BYTES // (8 * max(B.shape[0], 1)))
    for a in range(0, B.shape[1], w):
        blk = B[:, a:a + w]
        blk -= Q @ (Q.T @ blk)
    return B


#: :func:`project_out` projects columns more than twice this many bytes a block of about this many at a time (at
#: least 16 columns).
PROJECT_BLOCK_BYTES = 256 << 10


#: :func:`extends`' declarations, ``id(Q) -> (Q, Qb)`` (Q held: its id is not reused while declared).
_EXTENDS = Memo(64)
#: ``B - Qb Qb^T B`` per baseline basis ``Qb`` and columns ``B`` (:func:`project_out`): ``(id(Qb), shape, a
#: fingerprint of B) -> (Qb, B, Pb)``, ``B`` kept to check a hit is these very numbers (both read-only). Columns of
#: at most :data:`OUTSIDE_BASE_BYTES` only (256 of them: 128 MiB with their copies); larger ones up to
#: :data:`OUTSIDE_BASE_BIG_BYTES` in :data:`_OUTSIDE_BASE_BIG`. (Session 16 measured keeping the rival check's 480
#: slip columns as costing what taking them saved, 6.0 + 1.5 ms kept and taken against 3.8 + 3.0 in one step, from
#: their fresh arrays' page faults; under vmt's allocator settings, projected a block at a time, two such tests
#: are 8.4-9.5 ms kept and taken against 11.4-12.5 ms in blocks, session 17.)
_OUTSIDE_BASE = Memo(256)
OUTSIDE_BASE_BYTES = 256 << 10
#: :data:`_OUTSIDE_BASE` for columns of more than :data:`OUTSIDE_BASE_BYTES` up to :data:`OUTSIDE_BASE_BIG_BYTES`,
#: the last two (64 MiB with their copies), projected on ``Qb`` a block at a time (:data:`PROJECT_BLOCK_BYTES`):
#: the rival check's 480 slip columns (1.66 MB on the demo) are tested beside each named cause against the same
#: baseline, and the second test pays for the causes' few directions only.
_OUTSIDE_BASE_BIG = Memo(2)
OUTSIDE_BASE_BIG_BYTES = 16 << 20


def extends(Q: np.ndarray, Qb: np.ndarray) -> np.ndarray:
    """Declare ``Q[:, :Qb.shape[1]]`` to be ``Qb`` bit for bit and ``Q``'s other columns orthogonal to it (an
    engine state's model basis: the baseline's, then the terms' directions beyond it); ``Q`` may be ``Qb``.
    :func:`project_out` then keeps the columns' part outside ``Qb`` for the next basis extending it. Returns ``Q``.
    Neither array may be written to afterwards (the caller's promise)."""
    if isinstance(Q, np.ndarray) and isinstance(Qb, np.ndarray) and Q.ndim == 2 and Qb.ndim == 2:
        _EXTENDS.put(id(Q), (Q, Qb))
    return Q


def release_projections() -> None:
    """Forget :func:`extends`' declarations and the parts outside their bases kept (the end of an engine run: a
    later run's bases are other arrays, so nothing kept would be taken again; up to 128 MiB freed)."""
    for m in (_EXTENDS, _OUTSIDE_BASE, _OUTSIDE_BASE_BIG):
        m.clear()


def _extension_of(Q, B):
    """The declared ``Qb`` of ``Q`` (:func:`extends`) where ``B`` is small enough to keep its part outside, else
    None."""
    if not isinstance(Q, np.ndarray) or not isinstance(B, np.ndarray) or B.ndim != 2 or \
            B.nbytes > OUTSIDE_BASE_BIG_BYTES:
        return None
    ent = _EXTENDS.get(id(Q))
    return ent[1] if ent is not None and ent[0] is Q else None


def _project_out_extended(Q: np.ndarray, Qb: np.ndarray, B: np.ndarray, inplace: bool) -> np.ndarray:
    """:func:`project_out` against a declared ``Q = [Qb, U]``: ``B``'s part outside ``Qb`` kept or taken."""
    key = (id(Qb), B.shape, B[0].tobytes(), np.einsum("ij->j", B).tobytes())  # (a fingerprint: a hit is checked)
    memo = _OUTSIDE_BASE if B.nbytes <= OUTSIDE_BASE_BYTES else _OUTSIDE_BASE_BIG
    hit = memo.get(key)
    if hit is not None and hit[0] is Qb and np.array_equal(hit[1], B):
        Pb = hit[2]
    else:
        Bk = np.array(B)  # (kept: the caller's B may be a temporary written over)
        if memo is _OUTSIDE_BASE_BIG:
            Pb = _project_blocks(Qb, Bk.copy())
        else:
            Pb = Qb @ (Qb.T @ Bk)
            np.subtract(Bk, Pb, out=Pb)  # (Bk - Qb Qb^T Bk written over the product: one rows x columns array fewer)
        Bk.flags.writeable = Pb.flags.writeable = False
        memo.put(key, (Qb, Bk, Pb))
    kb = Qb.shape[1]
    if Q.shape[1] == kb:  # the baseline's basis itself: the one-step product, bit for bit
        if not inplace:
            return Pb.copy()
        np.copyto(B, Pb)
        return B
    U = Q[:, kb:]
    UP = U @ (U.T @ Pb)
    return np.subtract(Pb, UP, out=B if inplace else UP)


class SparseTrials:
    """Trials ``(T, n, k)`` kept as ``T`` sparse (n, k) CSR matrices (a long log's per-set-up columns: each lives
    on one set-up's rows; dense they were 1.6 GB for the turned lobes' 200 columns at 1e6 rows).

    ``C[t]`` is trial ``t``'s matrix, :meth:`rows` the trials on some rows; :func:`nested_f_batch` tests them
    against a :class:`core.lsq.Basis` from their Gram matrices (:func:`take_rows` takes their rows).
    """

    def __init__(self, mats):
        self.mats = [sp.csr_matrix(m) for m in mats]

    @property
    def shape(self) -> tuple:
        return (len(self.mats),) + (self.mats[0].shape if self.mats else (0, 0))

    def __getitem__(self, t):
        return self.mats[t]

    def rows(self, rows) -> "SparseTrials":
        return SparseTrials([m[np.asarray(rows)] for m in self.mats])


class StepTrials:
    """Trials ``(T, n, k)`` of one-off steps kept as their splits, not formed at once (:func:`core.causes.fixture_slip`:
    every set-up's up to 40 splits were 0.96 GB dense on a 1e4-row log of 100 set-ups, about 96 GB at 1e6 rows).

    Trial ``t`` is ``M`` (n, k) on one group's rows from its split on (the group's rows ``idx`` in time order,
    ``idx[split:]``) and zero elsewhere: :meth:`take` builds any of them, on any rows, with the values the dense
    array ``M[None] * mask[:, :, None]`` holds there (the same product, so a masked negative entry is ``-0.0`` as
    there); :func:`nested_f_trials` tests them a block at a time; :meth:`moved_event` says which one event each moves.
    """

    def __init__(self, M: np.ndarray, groups):
        self.M = np.asarray(M, float)
        self.groups = [(np.asarray(idx, int), np.asarray(splits, int)) for idx, splits in groups]
        self.offsets = np.concatenate([[0], np.cumsum([s.size for _, s in self.groups], dtype=int)]).astype(int)
        self.shape = (int(self.offsets[-1]),) + self.M.shape

    def masks(self, ts) -> np.ndarray:
        """(len(ts), n) 1 on the rows trial ``ts[i]`` moves (``M``'s zero rows included), 0 elsewhere."""
        ts = np.asarray(ts, int)
        m = np.zeros((ts.size, self.shape[1]))
        g = np.searchsorted(self.offsets, ts, side="right") - 1
        for i, (t, j) in enumerate(zip(ts, g)):
            idx, splits = self.groups[j]
            m[i, idx[splits[t - self.offsets[j]]:]] = 1.0
        return m

    def take(self, ts, rows=None) -> np.ndarray:
        """(len(ts), n or len(rows), k) trials ``ts`` on ``rows`` (all if None): the dense array's ``[ts]`` (C-contiguous)
        and its rows taken as :func:`take_rows` takes them (the same layout), bit for bit."""
        full = self.M[None, :, :] * self.masks(ts)[:, :, None]
        return full if rows is None else take_rows(full, rows, 1)

    def dense(self) -> np.ndarray:
        """Every trial at once (small cases and tests only)."""
        return self.take(np.arange(self.shape[0]))

    def moved_event(self, events: np.ndarray) -> np.ndarray:
        """(T,) the one event of ``events`` (n,) holding every row trial ``t`` moves (a nonzero row of it), or
        ``STEP_MIXED`` where it moves rows of two or more events or none: the dense trials' ``on = any(C != 0,
        axis=2)`` asked ``all(~on[:, events != e]) & any(on[:, events == e])`` (``M`` finite)."""
        events = np.asarray(events)
        nz = np.any(self.M != 0, axis=1)
        out = np.full(self.shape[0], STEP_MIXED, dtype=np.int64)
        for j, (idx, splits) in enumerate(self.groups):
            ev = events[idx].astype(np.int64)
            on = nz[idx]
            big, small = np.iinfo(np.int64).max, np.iinfo(np.int64).min
            lo = np.minimum.accumulate(np.where(on, ev, big)[::-1])[::-1]  # over each suffix's moved rows
            hi = np.maximum.accumulate(np.where(on, ev, small)[::-1])[::-1]
            lo, hi = lo[splits], hi[splits]
            single = on[::-1].cumsum()[::-1][splits] > 0
            single &= lo == hi
            out[self.offsets[j]:self.offsets[j + 1]] = np.where(single, lo, STEP_MIXED)
        return out


#: :meth:`StepTrials.moved_event` of a trial moving rows of more than one event, or none.
STEP_MIXED = np.iinfo(np.int64).min

#: :func:`nested_f_trials` tests step trials forming more than this many bytes (on the rows tested) a block at a
#: time; each block is more than :data:`OUTSIDE_BASE_BIG_BYTES` and a whole number of :func:`_project_blocks`'
#: column groups, so every column is projected by the same products as in one batch (bit for bit).
TRIAL_BLOCK_BYTES = 32 << 20


def trial_blocks(T: int, n: int, k: int, Q) -> list:
    """:func:`nested_f_trials`' blocks ``(a, b)`` of ``T`` trials of ``n`` rows by ``k`` columns against ``Q``.

    One block (the one batch) up to :data:`TRIAL_BLOCK_BYTES`. Beyond it: against a block basis (a long log's
    :class:`core.lsq.Basis`, each trial tested on its own) or no basis, blocks of about that many bytes; against
    an array basis, blocks each more than :data:`OUTSIDE_BASE_BIG_BYTES` (so :func:`project_out` takes the
    one-step path the whole batch takes, not the kept part outside a declared baseline, :func:`extends`) and a
    whole number of :func:`_project_blocks`' groups of ``w`` columns (the same matrix products column for column;
    the last block takes the rest). Column norms (``einsum`` over the rows of each contiguous trial) and the
    per-trial products after the projection do not depend on the batch.
    """
    nb = 8 * max(n, 1) * max(k, 1)
    if T <= 1 or T * nb <= TRIAL_BLOCK_BYTES:
        return [(0, T)]
    if isinstance(Q, Basis) or (isinstance(Q, np.ndarray) and Q.ndim == 2 and not Q.shape[1]):
        tb = max(1, TRIAL_BLOCK_BYTES // nb)
    elif isinstance(Q, np.ndarray) and Q.ndim == 2 and TRIAL_BLOCK_BYTES > OUTSIDE_BASE_BIG_BYTES >= 2 * PROJECT_BLOCK_BYTES:
        w = max(16, PROJECT_BLOCK_BYTES // (8 * max(n, 1)))
        g = w // int(np.gcd(w, k))  # trials per whole number of column groups
        tb = g * (OUTSIDE_BASE_BIG_BYTES // (nb * g) + 1)
    else:
        return [(0, T)]
    m = T // tb
    if m <= 1:
        return [(0, T)]
    return [(i * tb, (i + 1) * tb) for i in range(m - 1)] + [((m - 1) * tb, T)]


def trials_take(C, ts, rows=None) -> np.ndarray:
    """Trials ``ts`` of ``C`` (a dense (T, n, k) array or :class:`StepTrials`) on ``rows`` (all if None)."""
    if isinstance(C, StepTrials):
        return C.take(ts, rows)
    out = C[np.asarray(ts, int)]
    return out if rows is None else take_rows(out, rows, 1)


def nested_f_trials(C, rows, Q, r: np.ndarray, rss: float, dof: int, ts=None):
    """:func:`nested_f_batch` of the trials ``ts`` of ``C`` (all if None) on ``rows`` (all if None): a dense
    (T, n, k) array as one batch (``C[ts]``, its rows taken by :func:`take_rows`), :class:`StepTrials` built and
    tested a block at a time (:func:`trial_blocks`), the same four arrays bit for bit."""
    if not isinstance(C, StepTrials):
        Ct = C if ts is None else C[np.asarray(ts, int)]
        return nested_f_batch(Ct if rows is None else take_rows(Ct, rows, 1), Q, r, rss, dof)
    n, k = C.shape[1], C.shape[2]
    ts = np.arange(C.shape[0]) if ts is None else np.asarray(ts, int)
    if rows is not None:
        rows = np.asarray(rows)
        if rows.size == n and np.array_equal(rows, np.arange(n)):
            rows = None  # (take_rows gives a contiguous batch itself: the block as built)
    outs = [nested_f_batch(C.take(ts[a:b], rows), Q, r, rss, dof)
            for a, b in trial_blocks(ts.size, n if rows is None else rows.size, k, Q)]
    if len(outs) == 1:
        return outs[0]
    return tuple(np.concatenate([o[i] for o in outs]) for i in range(4))


def take_rows(M: np.ndarray, rows, axis: int = 0) -> np.ndarray:
    """``M``'s rows ``rows`` along ``axis`` (``M[rows]``, ``M[:, rows]`` ...), for reading only.

    Every row in order (``rows`` is ``arange(len)``) of a C-contiguous
    ``M``: ``M`` itself, not a copy (the same values in the same layout a
    copy would have); otherwise the indexed copy. Trials kept sparse
    (:class:`SparseTrials`, ``axis`` 1): theirs on those rows.
    """
    if isinstance(M, SparseTrials):
        if axis != 1:
            raise ConfigError("take_rows: a SparseTrials' rows are its axis 1")
        return M.rows(rows)
    n = M.shape[axis]
    if M.flags.c_contiguous and len(rows) == n and np.array_equal(rows, np.arange(n)):
        return M
    return M[(slice(None),) * axis + (np.asarray(rows),)]


def new_basis(Q: np.ndarray, B: np.ndarray, tol: float = IN_SPAN, inplace: bool = False) -> np.ndarray:
    """Orthonormal basis of the part of span(B) outside span(Q).

    Columns normalised, projected out of Q; the eigen-decomposition of
    their Gram matrix keeps directions whose singular value exceeds
    ``max(tol, 1e-5)`` (a direction retaining less of a unit column is
    inside the model, for every purpose here).

    ``inplace``: ``B`` (a temporary of the caller's, C-contiguous) is
    normalised and projected in its own memory (the same numbers; one
    rows x columns array fewer: 46 MiB for a sine's six columns at 1e6
    rows). The result is divided in place as well (bit for bit the
    quotient a new array would hold).
    """
    if B.shape[1] == 0:
        return np.zeros((B.shape[0], 0))
    nrm = col_norms(B)
    keep = nrm > 0
    if not keep.any():
        return np.zeros((B.shape[0], 0))
    whole = keep.all() and B.flags.c_contiguous  # (B itself divided: the layout B[:, keep] would have)
    if whole and inplace and B.flags.writeable:
        P = np.divide(B, nrm, out=B)
    else:
        P = B / nrm if whole else B[:, keep] / nrm[keep]
    P = project_out(Q, P, inplace=True)
    w, V = np.linalg.eigh(P.T @ P)
    good = w > max(tol, 1e-5) ** 2
    Vg = V[:, good]
    if P.nbytes > LONG_BYTES and P.flags.c_contiguous and 2 <= P.shape[1] <= LONG_COLS:
        # a long log: the rotation a block of rows at a time into P's own memory (P is this function's or the
        # caller's temporary; row blocks laid out by row_blocks are the whole product's rows bit for bit), no
        # second array
        n, g = P.shape[0], Vg.shape[1]
        flat = P.reshape(-1)
        for ch in row_blocks(n, LONG_ROWS):
            block = P[ch] @ Vg  # (read before its rows' memory is written: rows of U start at or before P's)
            flat[ch.start * g:ch.stop * g] = block.reshape(-1)
        U = flat[:n * g].reshape(n, g)
    else:
        U = P @ Vg
    del P  # (the caller's B, or this function's normalised copy: freed before the result is scaled)
    U /= np.sqrt(w[good])
    return U


# ---------------------------------------------------------------------------
# tests
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class NestedTest:
    """F test of columns added to a linear model.

    Attributes
    ----------
    k : int
        Added dimensions (outside the model).
    ss : float
        Residual sum of squares they remove, m^2.
    F, p_value : float
    explained_rms_m : float
        Debiased RMS of the added term over the rows, m.
    """

    k: int
    ss: float
    F: float
    p_value: float
    explained_rms_m: float


def nested_f(U: np.ndarray, r: np.ndarray, rss: float, dof: int) -> NestedTest:
    """Nested F test of the orthonormal directions ``U`` (already outside the model).

    Parameters
    ----------
    U : (n, k) float
        Orthonormal, orthogonal to the model's column space.
    r : (n,) float
        Residuals of the model, m.
    rss : float
        ``r @ r``.
    dof : int
        Residual degrees of freedom of the model.
    """
    k = U.shape[1]
    if k == 0 or dof - k < 1:
        return NestedTest(0, 0.0, 0.0, 1.0, 0.0)
    return _nested_f_ss(k, float(np.sum((U.T @ r) ** 2)), len(r), rss, dof)


def _nested_f_ss(k: int, ss: float, n: int, rss: float, dof: int) -> NestedTest:
    """:func:`nested_f` from the sum of squares ``ss`` that ``k`` directions (``dof - k >= 1``) remove."""
    s2 = max(rss - ss, 1e-300) / (dof - k)
    F = (ss / k) / s2
    p = float(special.fdtrc(k, dof - k, F))
    return NestedTest(k, ss, F, p, float(np.sqrt(max(ss - k * s2, 0.0) / n)))


def nested_f_batch(C: np.ndarray, Q: np.ndarray, r: np.ndarray, rss: float, dof: int):
    """Nested F tests of many candidate column sets at once.

    Parameters
    ----------
    C : (T, n, k) float
        Candidate columns (any scaling).
    Q : (n, q) float
        Orthonormal basis of the model.
    r : (n,) float
        Model residuals (orthogonal to Q); ``rss = r @ r``.

    Returns
    -------
    ss, k, F, p : (T,) arrays
        Sum of squares each set removes, its dimension outside the model
        (eigenvalues of the projected, column-normalised Gram above
        ``IN_SPAN^2``), the F statistic and its p-value.
    """
    T, n, k = C.shape
    if isinstance(C, SparseTrials):  # kept sparse: from their Gram matrices against a long log's basis
        if not isinstance(Q, Basis):
            raise ConfigError("nested_f_batch: sparse trials are tested against a block basis (a long log's)")
        return _sparse_batch(C, Q, r, rss, dof)
    nrm = np.maximum(np.sqrt(np.einsum("tnk,tnk->tk", C, C)), 1e-300)
    if isinstance(Q, Basis):  # a long log: P^T P and P^T r from the Gram matrices (no (n, T k) projection formed)
        inv = np.where(nrm > 1e-300, 1.0 / nrm, 0.0)  # (a zero column stays zero, as C / nrm leaves it)
        G = np.empty((T, k, k))
        b = np.empty((T, k))
        Qr = Q.T @ r
        for t in range(T):
            QC = (Q.T @ C[t]) * inv[t]
            G[t] = (C[t].T @ C[t]) * np.outer(inv[t], inv[t]) - QC.T @ QC
            b[t] = (C[t].T @ r) * inv[t] - QC.T @ Qr
        return _batch_tests(G, b, rss, dof)
    if Q.shape[1]:  # one matrix product for every trial: (n, T k), normalised in that layout
        if T == 1:
            C2 = C[0] / nrm[0]
        else:  # (a copy into the layout, then divided in place: a strided divide is slower)
            C2 = np.empty((n, T, k))
            C2[...] = C.transpose(1, 0, 2)  # (np.moveaxis(C, 0, 1): the same view, without its checks)
            C2 /= nrm[None, :, :]
            C2 = C2.reshape(n, T * k)
        P = project_out(Q, C2, inplace=True).reshape(n, T, k).transpose(1, 0, 2)
    else:
        P = C / nrm[:, None, :]
    Pt = P.transpose(0, 2, 1)
    return _batch_tests(Pt @ P, Pt @ r, rss, dof)


def _sparse_batch(C: SparseTrials, Q: Basis, r: np.ndarray, rss: float, dof: int):
    """:func:`nested_f_batch`'s block-basis branch for sparse trials: ``C^T C``, ``C^T r`` sparse products, ``Q^T C``
    a block of rows at a time (:data:`GRAM_CHUNK_ROWS`), nothing rows x columns formed dense."""
    T, _, k = C.shape
    G = np.empty((T, k, k))
    b = np.empty((T, k))
    Qr = Q.T @ r
    for t in range(T):
        Ct = C[t]
        CC = _dense(Ct.T @ Ct)
        nrm = np.maximum(np.sqrt(np.maximum(np.diag(CC), 0.0)), 1e-300)
        inv = np.where(nrm > 1e-300, 1.0 / nrm, 0.0)
        QC = basis_rmatmul(Q, Ct)
        QC *= inv
        G[t] = CC * np.outer(inv, inv) - QC.T @ QC
        b[t] = np.asarray(Ct.T @ r).ravel() * inv - QC.T @ Qr
    return _batch_tests(G, b, rss, dof)


def _batch_tests(G: np.ndarray, b: np.ndarray, rss: float, dof: int):
    """:func:`nested_f_batch` from each trial's projected Gram matrix ``G`` (T, k, k) and ``P^T r`` (T, k)."""
    w, V = np.linalg.eigh(G)
    good = w > IN_SPAN ** 2
    proj = (V.transpose(0, 2, 1) @ b[..., None])[..., 0]
    T, kk = w.shape
    if kk and dof - kk >= 1 and good.all():
        # (the usual case: every direction kept, so every trial's k is the columns' count and every test is made;
        # the same values as the masked expressions below, fewer passes over the small arrays)
        k = np.full(T, kk, dtype=np.intp)
        d2 = dof - k
        ss = np.sum(proj ** 2 / w, axis=1)
        F = (ss / k) / (np.maximum(rss - ss, 1e-300) / d2)
        return ss, k, F, special.fdtrc(k, d2, F)
    return _masked_tests(w, good, proj, rss, dof)


def _masked_tests(w: np.ndarray, good: np.ndarray, proj: np.ndarray, rss: float, dof: int):
    """:func:`_batch_tests`' general case: each trial's test on its kept directions ``good`` (T, k) of
    eigenvalues ``w`` and projections ``proj``; a trial with none kept, or no degree of freedom left, p 1."""
    k = good.sum(axis=1)
    d2 = dof - k
    ok = (k > 0) & (d2 >= 1)
    ss = np.sum(np.where(good, proj ** 2 / np.where(good, w, 1.0), 0.0), axis=1)
    F = np.where(ok, (ss / np.maximum(k, 1)) / (np.maximum(rss - ss, 1e-300) / np.maximum(d2, 1)), 0.0)
    p = np.where(ok, special.fdtrc(np.maximum(k, 1), np.maximum(d2, 1), F), 1.0)
    return ss, k, F, p


#: Two tests of terms against the same model tie when they add the same number
#: of dimensions and their sums of squares differ by at most ``TIE_RTOL`` of
#: the model's residual sum of squares: equal in exact arithmetic (the same
#: span outside the model, e.g. the set-up's term and the C angle's when each
#: set-up has its own C; a campaign-long drift and one within each set-up
#: beside per-set-up constants), so the order the floating-point kernels give
#: them is rounding, and a tie is broken by a fixed order instead (the
#: caller's: the covariate registry's, the catalogue's scans and trials). Why
#: 1e-8: a term's sum of squares ``sum (V^T P^T r)^2 / w`` carries a rounding
#: error of about ``eps sqrt(ss rss / w)`` (times a small constant), at most
#: ``eps rss / IN_SPAN`` = 2e-10 rss for the weakest direction a test keeps;
#: a difference that means anything is of the order of the noise's variance,
#: ``rss / dof``, 1e-5 rss or more for any log up to 1e5 rows (1e-6 at 1e6).
TIE_RTOL = 1e-8


def tied(ss_a: float, k_a: int, ss_b: float, k_b: int, rss: float) -> bool:
    """Whether two tests against one model (residual sum of squares ``rss``) tie (:data:`TIE_RTOL`)."""
    return int(k_a) == int(k_b) and abs(float(ss_a) - float(ss_b)) <= TIE_RTOL * float(rss)


#: Relative width within which two statistics are taken as tied (:func:`_first_largest`): rounding
#: differences between BLAS kernels measured 1e-14 relative on the same campaign; distinct statistics
#: closer than 1e-9 are not met in practice.
ARGMAX_TIE_RTOL = 1e-9


def _first_largest(v: np.ndarray) -> int:
    """The index of the largest value of ``v``, the lowest index among values tied with it (within
    :data:`ARGMAX_TIE_RTOL` relative).

    Two touches can carry the same statistic in exact arithmetic (the outlier screen's two
    readings of one target whose residuals the fit splits evenly: gen_a reseat_hysteresis 1087,
    rows 83 and 85, t 8.667225540449 both to 1e-14); ``np.argmax`` then picks whichever the
    rounding of the machine's BLAS kernel favours (OpenBLAS's SkylakeX kernels row 85, its
    Haswell and Zen kernels row 83), and the rest of the screen follows that pick. The lowest
    index, the earlier touch, makes the choice the data's, not the machine's.
    """
    top = float(np.max(v))
    if not np.isfinite(top):  # (a NaN or an infinity: np.argmax's pick, as before the rule)
        return int(np.argmax(v))
    return int(np.flatnonzero(v >= top - ARGMAX_TIE_RTOL * abs(top))[0])


def rank_with_ties(items, key, ss_k, rss: float) -> list:
    """``items`` sorted by ``key``, each set of tied items (:func:`tied`) in its input order.

    ``ss_k(item)`` gives ``(ss, k)``. A tie set takes the place of its
    member that sorts first and is judged against it: members sorted apart
    only by rounding come out in the same order whatever the rounding.
    """
    items = list(items)
    order = sorted(range(len(items)), key=lambda i: key(items[i]))
    sk = [ss_k(it) for it in items]
    done = [False] * len(items)
    out = []
    for i in order:
        if done[i]:
            continue
        group = [j for j in range(len(items)) if not done[j] and (j == i or tied(*sk[i], *sk[j], rss))]
        for j in group:  # (input order)
            done[j] = True
            out.append(items[j])
    return out


def holm(p) -> np.ndarray:
    """Holm step-down adjusted p-values (family-wise error rate, any dependence)."""
    p = np.asarray(p, float)
    m = len(p)
    if m == 0:
        return p
    order = np.argsort(p)
    adj = np.empty(m)
    run = 0.0
    for i, j in enumerate(order):
        run = max(run, min(1.0, (m - i) * p[j]))
        adj[j] = run
    return adj


def fmt_p(p: float) -> str:
    """``p < 1e-6``, ``p = 0.0031``."""
    if p < 1e-6:
        return "p < 1e-6"
    if p < 1e-3:
        return f"p = {p:.1e}"
    return f"p = {p:.2g}"


# ---------------------------------------------------------------------------
# covariates and their bases
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Covariate:
    """One variable the rows carry, and how a smooth function of it is built.

    Attributes
    ----------
    name : str
        Report name (``time``, ``time_in_setup``, ``x``, ``temp_spindle_C`` ...).
    values : (n,) float
        The variable (any unit; bases use quantiles and ranges only).
    kind : {"smooth", "circular", "categorical", "basis"}
        B-splines, a Fourier series (values in rad), indicators, or given
        functions (``values`` is then (n, m)).
    size : int
        Basis functions (smooth), harmonics (circular); ignored for categories.
    modes : tuple of int
        Which response modes of the baseline the function acts through.
    words : str
        How the report says it (``"time within each set-up"``).
    family : str
        Covariates of one family are confounded by the way campaigns are
        run (time, touch order and a temperature that follows the clock):
        ``time``, ``position``, ``direction``, ``feature``.
    period_range : (float, float)
        For ``kind="spectral"``: the shortest and longest period scanned, in
        the covariate's unit. A spectral covariate is tested by the best
        sine of its values (each mode times sin, cos), the p-value
        Bonferroni-adjusted over the independent frequencies scanned:
        structure too fine for a smooth basis (a screw ripple) is located.
    """

    name: str
    values: np.ndarray = field(repr=False)
    kind: str
    size: int
    modes: tuple
    words: str
    family: str = ""
    period_range: tuple = ()


#: Width, relative to the values' magnitude (the largest of their span and their absolute values), within
#: which two values of a covariate are one value (:func:`distinct_values`): repeat touches of one nominal
#: position differ by 6e-17 m by the BLAS kernel that computed them; distinct positions are micrometres apart.
DISTINCT_RTOL = 1e-9


def distinct_values(v: np.ndarray) -> np.ndarray:
    """The distinct values of ``v`` (sorted), a value within :data:`DISTINCT_RTOL` of the values' magnitude
    of the next smaller one taken as the same (the smallest of such a run stands for it).

    ``np.unique`` counts values equal in exact arithmetic apart when rounding
    parts them: gen_a nonrigid 1039's x positions hold 78 distinct values under
    OpenBLAS's SkylakeX kernels and 79 under its Haswell kernels (22 and 23 of
    them 6e-17 m from another), and the spline's quantile knots followed.
    """
    s = np.sort(np.asarray(v, float).ravel())
    if s.size < 2:
        return s
    scale = max(s[-1] - s[0], abs(s[0]), abs(s[-1]))
    return s[np.r_[True, np.diff(s) > DISTINCT_RTOL * scale]]


def spline_basis(v: np.ndarray, size: int) -> np.ndarray:
    """(n, m) B-spline basis of ``v`` with interior knots at quantiles of its distinct values.

    Cubic when there are enough distinct values; the degree drops with
    fewer. ``m <= size``; partition of unity (the constant is in the span).
    """
    v = np.asarray(v, float)
    u = distinct_values(v)
    if u.size < 2:
        return np.ones((len(v), 1))
    m = int(min(size, u.size))
    deg = int(min(3, m - 1))
    n_int = m - deg - 1
    lo, hi = u[0], u[-1]
    inner = np.quantile(u, np.linspace(0, 1, n_int + 2)[1:-1]) if n_int > 0 else np.zeros(0)
    t = np.concatenate([np.full(deg + 1, lo), inner, np.full(deg + 1, hi)])
    x = np.clip(v, lo, hi)
    B = BSpline.design_matrix(x, t, deg, extrapolate=False).toarray()
    B[x >= hi, -1] = 1.0  # the right end belongs to the last function
    B[x >= hi, :-1] = 0.0
    return B


def fourier_basis(phi: np.ndarray, harmonics: int) -> np.ndarray:
    """(n, 1 + 2h) ``1, cos k phi, sin k phi`` for k = 1..h."""
    cols = [np.ones(len(phi))]
    for k in range(1, harmonics + 1):
        cols += [np.cos(k * phi), np.sin(k * phi)]
    return np.column_stack(cols)


def category_basis(v: np.ndarray) -> np.ndarray:
    """(n, L) indicators of the distinct values of ``v``."""
    _, inv = np.unique(np.asarray(v), return_inverse=True)
    B = np.zeros((len(inv), inv.max() + 1))
    B[np.arange(len(inv)), inv] = 1.0
    return B


def function_basis(cov: Covariate) -> np.ndarray:
    """(n, m) basis functions of the covariate alone (before the modes)."""
    if cov.kind == "basis" and sp.issparse(cov.values):  # a long log's per-set-up functions (kept sparse)
        return cov.values.toarray()
    if cov.kind == "smooth":
        return spline_basis(cov.values, cov.size)
    if cov.kind == "circular":
        return fourier_basis(np.asarray(cov.values, float), cov.size)
    if cov.kind == "categorical":
        return category_basis(cov.values)
    if cov.kind == "basis":  # the functions themselves, (n, m)
        return np.asarray(cov.values, float)
    if cov.kind == "spectral":
        raise ValueError(f"covariate {cov.name!r}: a spectral covariate has no fixed basis")
    raise ValueError(f"covariate {cov.name!r}: unknown kind {cov.kind!r}")


def term_bases(covariates, modes: np.ndarray, lazy: bool = False) -> dict:
    """Every covariate's term basis over all rows, once (name -> (n, m)).

    A spectral covariate has no basis: its entry is its :class:`SpectralTable`
    (the scan's frequencies and the pre-screen's tables), kept for every
    diagnosis of a run. ``lazy`` (a long log, :class:`LazyBases`): the other
    covariates' bases are built when asked for and not kept (the set-up by
    every response mode is rows x 700 numbers); :func:`diagnose` then tests
    from the covariates themselves (:func:`gram_test`).
    """
    out = LazyBases(covariates, modes) if lazy else {}
    for c in covariates:
        if c.kind == "spectral":
            tab = spectral_table(c)
            if tab is not None:
                dict.__setitem__(out, c.name, tab)
        elif not lazy:
            out[c.name] = term_basis(c, modes)
    return out


class LazyBases(dict):
    """:func:`term_bases` of a long log: spectral tables held, every other covariate's basis built on each access."""

    def __init__(self, covariates, modes: np.ndarray):
        super().__init__()
        self.covs = {c.name: c for c in covariates if c.kind != "spectral"}
        self.modes = modes

    def __missing__(self, name):
        if name not in self.covs:
            raise KeyError(name)
        return term_basis(self.covs[name], self.modes)

    def __contains__(self, name) -> bool:
        return dict.__contains__(self, name) or name in self.covs

    def get(self, name, default=None):
        return self[name] if name in self else default


def _frequencies(cov: Covariate):
    """Frequencies a spectral covariate scans (three per independent one), or None."""
    span = float(np.ptp(np.asarray(cov.values, float)))
    p_lo, p_hi = cov.period_range
    if span <= 0 or p_hi <= 1.2 * p_lo:
        return None
    return scan_grid(p_lo, p_hi, span)[0]


#: Most frequencies one spectral scan tests (a ripple along x or y, an
#: oscillation in time). The fine grid has three frequencies per independent
#: one, ``1 / (3 span)`` apart: about 1.5 per distinct position (or per touch
#: interval in time), so its size would grow with a long log's rows. Up to
#: this many the fine grid is scanned whole (every stored campaign and the
#: demo: at most 2,143, gen_b's head_tram 3 in time); beyond it the same
#: range is scanned on an evenly spaced grid of this many frequencies (a
#: coarser resolution, ``(1/p_lo - 1/p_hi) / MAX_SCAN_FREQUENCIES``) and
#: the cause scans refine the best trials around it (discover's ``_refine``
#: over one coarse step either side). A sine's peak is about ``0.9 / span``
#: wide at half power (2.7 fine steps): a coarse step up to that (fine grids
#: up to about 11,000 frequencies) samples every peak near its top; beyond
#: it a peak can fall between two frequencies and be missed.
MAX_SCAN_FREQUENCIES = 4096


def scan_grid(p_lo: float, p_hi: float, span: float) -> tuple[np.ndarray, bool]:
    """((F,) frequencies (1/unit) scanned for periods ``p_lo..p_hi`` over values spanning ``span``, coarse).

    ``1 / (3 span)`` apart from ``1 / p_hi`` (three per independent
    frequency), or, when that is more than :data:`MAX_SCAN_FREQUENCIES`,
    that many evenly spaced over the same range (see its note): then
    ``coarse`` is True.
    """
    step = 1 / (3 * span)
    coarse = (1 / p_lo - 1 / p_hi) / step > MAX_SCAN_FREQUENCIES
    if coarse:
        step = (1 / p_lo - 1 / p_hi) / MAX_SCAN_FREQUENCIES
    return np.arange(1 / p_hi, 1 / p_lo, step), coarse


#: Frequencies per block of the pre-screen's tables: each block starts from an
#: exact sine and cosine, the others are rotations of it (error ~ BLOCK eps).
_BLOCK = 32

#: Largest pre-screen table kept for a whole run (``Z``, ``S2``, ``C2``: 32
#: bytes per row and frequency; the demo's is 23 MB). A larger scan (a long
#: log: 1e5 rows scanning 1,659 frequencies would keep 5.3 GB) is computed
#: afresh at each use, a block of frequencies at a time, in about
#: :data:`SCAN_BLOCK_BYTES` (at least ``_BLOCK`` frequencies a block).
TABLE_BYTES = 64 << 20
SCAN_BLOCK_BYTES = 16 << 20


class SpectralTable(tuple):
    """A spectral covariate's scan over all rows: ``(Z, S2, C2, f, w)``.

    ``f`` (F,) the frequencies; ``w`` (n,) ``2 pi v``, so that a frequency's
    exact columns are ``sin(w f_i)``, ``cos(w f_i)`` (:meth:`columns`, the
    same floating-point operations as ``2 pi v f`` evaluated whole). ``Z``
    (n, F) ``exp(i w f)`` for the periodogram-like pre-screen only, built by
    rotation from an exact value every ``_BLOCK`` frequencies (within about
    1e-14 of the exact one: it ranks frequencies, it enters no test);
    ``S2``, ``C2`` its squared sine and cosine (the pre-screen's
    denominators). ``Z``, ``S2``, ``C2`` are None when the table would
    exceed :data:`TABLE_BYTES`: :meth:`blocks` then makes them a block of
    frequencies at a time.
    """

    def __new__(cls, Z, S2, C2, f, w):
        self = super().__new__(cls, (Z, S2, C2, f, w))
        self._dens = {}  # the pre-screen's denominators per (rows, modes): see screen()
        return self

    Z = property(lambda self: self[0])
    S2 = property(lambda self: self[1])
    C2 = property(lambda self: self[2])
    f = property(lambda self: self[3])
    w = property(lambda self: self[4])

    def columns(self, i: int):
        """Exact ``sin``, ``cos`` of frequency ``i`` over all rows, (n,) each."""
        ph = self.w * self.f[i]
        return np.sin(ph), np.cos(ph)

    def blocks(self, squares: bool = True):
        """``(cols, rows, Z, S2, C2)`` over the frequencies: the kept table whole, or blocks of it.

        A block's entries are bit for bit those of the whole table (each
        block starts at a multiple of ``_BLOCK``, so from the same exact
        phasors and the same rotations: :func:`screen_phasors`; a row's
        phasors are its own). ``rows``: a slice, every row (``slice(None)``)
        but where ``_BLOCK`` frequencies over every row exceed
        :data:`SCAN_BLOCK_BYTES` (:func:`phasor_blocks`).
        ``squares=False``: ``S2``, ``C2`` not made for the blocks (None).
        """
        if self.Z is not None:
            yield slice(None), slice(None), self.Z, self.S2, self.C2
            return
        for cols, rows, Z in phasor_blocks(self.w, self.f):
            yield (cols, rows, Z, Z.imag ** 2, Z.real ** 2) if squares else (cols, rows, Z, None, None)

    def screen(self, A: np.ndarray, W2: np.ndarray, key=None, owner=None):
        """The pre-screen's products ``(A @ Z, W2 @ S2, W2 @ C2)``, (m, F) each.

        ``A`` (m, n) the weighted residuals, ``W2`` (m, n) the squared
        weights. The denominators ``W2 @ S2``, ``W2 @ C2`` do not depend on
        the residuals: with a ``key`` (what ``W2`` was made from: the rows
        and the modes' columns) and its ``owner`` (the modes array itself,
        held with them so that the key names it) they are kept for the next
        diagnosis on the same rows (the last few keys): the same products
        on the same operands, so the same numbers bit for bit. A table made
        a block of rows at a time (a long log) sums the blocks' products:
        the same to rounding (the order of the sums over rows changes).
        """
        F = len(self.f)
        NZ = np.zeros((A.shape[0], F), complex)
        have = self._dens.pop(key, None) if key is not None else None
        if have is not None and have[0] is not owner:
            have = None
        if have is None:
            dS, dC = np.zeros((2, W2.shape[0], F))
        else:
            _, dS, dC = have
        for cols, rows, Z, S2, C2 in self.blocks(squares=have is None):
            # (zeros plus the whole table's product: that product, bit for bit, as the blocks' products are). ``A``
            # is real: the product is one real product on the phasors' real and imaginary parts side by side
            # (_real_times_complex), half the multiplications of the complex one numpy makes of a real matrix
            NZ[:, cols] += _real_times_complex(A[:, rows], Z)
            if have is None:
                dS[:, cols] += W2[:, rows] @ S2
                dC[:, cols] += W2[:, rows] @ C2
        if key is not None:
            self._dens[key] = (owner, dS, dC)
            while len(self._dens) > 4:
                self._dens.pop(next(iter(self._dens)))
        return NZ, dS, dC


def _real_times_complex(A: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """``A @ Z`` for a real ``A`` (m, n) and a complex ``Z`` (n, F) by one real product: ``A @ Z.view(float)``,
    whose columns are the real and imaginary parts interleaved, read back as complex (m, F); ``Z``'s last axis
    contiguous (a phasor table and its blocks are), else the complex product. numpy's ``A @ Z`` casts ``A`` to
    complex and multiplies its zero imaginary parts too: twice the work. The same sums of the same products, to
    rounding (the order the kernels add them may differ): the pre-screen only ranks frequencies with it, and the
    16 identity campaigns' reports (tests/core/test_discover_identity.py) come out bit for bit as before."""
    if A.dtype != np.float64 or Z.dtype != np.complex128 or Z.ndim != 2 or Z.strides[1] != Z.itemsize:
        return A @ Z
    return np.ascontiguousarray(A @ Z.view(np.float64)).view(np.complex128)


def phasor_blocks(w: np.ndarray, f: np.ndarray):
    """``(cols, rows, Z)``: :func:`screen_phasors` of ``w`` over ``f`` a block of frequencies at a time.

    Blocks of about :data:`SCAN_BLOCK_BYTES` (a table row and frequency
    costs 32 bytes with its squares), at least ``_BLOCK`` frequencies,
    each starting at a multiple of ``_BLOCK``: bit for bit the columns of
    the whole table. Where ``_BLOCK`` frequencies over every row exceed
    that (more than 16,384 rows: 1 GiB with its squares at the bench's 1e6
    rows), a block of rows at a time too (``rows`` a slice, else
    ``slice(None)``; every row's phasors are its own, so bit for bit the
    whole table's rows).
    """
    n, F = len(w), len(f)
    step = max(1, SCAN_BLOCK_BYTES // (32 * max(n, 1) * _BLOCK)) * _BLOCK
    rb = max(1, SCAN_BLOCK_BYTES // (32 * step))
    for a in range(0, F, step):
        for r0 in range(0, max(n, 1), rb):
            rows = slice(None) if rb >= n else slice(r0, r0 + rb)
            yield slice(a, a + step), rows, screen_phasors(w[rows], f, a, min(F, a + step))


def spectral_table(cov: Covariate):
    """The :class:`SpectralTable` of a spectral covariate, or None (nothing to scan)."""
    f = _frequencies(cov)
    if f is None:
        return None
    w = 2 * np.pi * np.asarray(cov.values, float)
    if 32 * len(w) * len(f) > TABLE_BYTES:
        return SpectralTable(None, None, None, f, w)
    Z = screen_phasors(w, f)
    return SpectralTable(Z, Z.imag ** 2, Z.real ** 2, f, w)


def screen_phasors(w: np.ndarray, f: np.ndarray, start: int = 0, stop: int | None = None) -> np.ndarray:
    """(n, stop - start) complex ``exp(i w f)`` on an evenly spaced ``f``, for ranking frequencies only.

    Exact (``np.exp``) at every ``_BLOCK``-th frequency, rotations of it
    by ``exp(i w df)`` between: within about ``_BLOCK * eps * |w f|`` of
    the exact phasor (3e-13 on the campaigns seen), at a few complex
    products per entry instead of a sine and a cosine. A pre-screen ranks
    with it; every test uses exact columns. ``start:stop`` (``start`` a
    multiple of ``_BLOCK``): those frequencies' columns only, bit for bit
    the same as the whole table's.
    """
    stop = len(f) if stop is None else min(stop, len(f))
    if start % _BLOCK:
        raise ValueError(f"screen_phasors: start {start} is not a multiple of {_BLOCK}")
    heads = np.arange(start, stop, _BLOCK)
    E = np.exp(1j * (w[:, None] * f[heads][None, :]))  # (n, nb) exact at each block's first frequency
    step = f[1] - f[0] if len(f) > 1 else 0.0
    R = np.ones((len(w), _BLOCK), complex)  # exp(i w k step), k = 0 .. _BLOCK - 1
    R[:, 1:] = np.exp(1j * w * step)[:, None]
    R = np.cumprod(R, axis=1)
    return (E[:, :, None] * R[:, None, :]).reshape(len(w), -1)[:, :stop - start]  # a view: products take its stride


@dataclass(frozen=True)
class _SpectralTest(NestedTest):
    period: float = 0.0


def _spectral(cov: Covariate, Q, r, rss, dof, modes, rows, table=None, shortlist: int = 4):
    """The best sine of a covariate against the residuals (see :attr:`Covariate.period_range`).

    Returns None or ``(cov, test, (U, fitted))``: the sine's basis outside the model ``U``, or for a long log
    (``Q`` a :class:`core.lsq.Basis`) its fitted term ``U U^T r`` (m) in its place (``U`` None).
    """
    lean = isinstance(Q, Basis)
    tab = spectral_table(cov) if table is None else table
    if tab is None:
        return None
    v = np.asarray(cov.values, float)
    Mf = modes[:, list(cov.modes)]
    f = tab.f
    # periodogram-like pre-screen (r is orthogonal to the model): per mode w and
    # frequency, (r w . sin)^2 / (w^2 . sin^2) + the same with cos, the rows left
    # out weighted by zero
    rf = np.zeros(len(v))
    rf[slice(None) if rows is None else rows] = r
    if rows is None:
        Mw = Mf
    else:
        keep = np.zeros(len(v), bool)
        keep[rows] = True
        Mw = np.where(keep[:, None], Mf, 0.0)
    A, W2 = (rf[:, None] * Mw).T, (Mw ** 2).T
    # the denominators kept on the table per rows and modes (a table of this run's bases)
    key = (None if rows is None else np.asarray(rows).tobytes(), id(modes), tuple(cov.modes)) if table is not None \
        else None
    NZ, dS, dC = tab.screen(A, W2, key, modes)
    del A, W2, Mw, rf  # (rows x modes each: not read again; freed before the shortlist's columns are formed)
    num = np.zeros(len(f))
    for m in range(Mf.shape[1]):
        num += NZ[m].imag ** 2 / np.maximum(dS[m], 1e-300)
        num += NZ[m].real ** 2 / np.maximum(dC[m], 1e-300)
    if rows is not None:
        v, M = v[rows], Mf[rows]
    else:
        M = Mf
    span = float(np.ptp(v))
    p_lo, p_hi = cov.period_range
    best = None
    m = M.shape[1]
    for i in np.argsort(-num)[:shortlist]:
        s, c = tab.columns(i)
        if rows is not None:
            s, c = s[rows], c[rows]
        B = np.empty((len(s), 2 * m))  # [M s, M c], each product written in place (what hstack copied)
        np.multiply(M, s[:, None], out=B[:, :m])
        np.multiply(M, c[:, None], out=B[:, m:])
        del s, c
        U = new_basis(Q, B, inplace=True)
        del B
        if U.shape[1] == 0 or dof - U.shape[1] < 5:
            continue
        t = nested_f(U, r, rss, dof)
        if best is None or t.p_value < best[0].p_value:
            # a long log (Q a block basis) keeps the fitted term U U^T r, not U (rows x 2 to 6, 15-46 MiB at 1e6
            # rows, which diagnose kept for the run): the product diagnose forms from U, bit for bit
            best = (t, (None, U @ (U.T @ r)) if lean else (U, None), 1 / f[i])
        del U
    if best is None:
        return None
    t, U, P = best
    tries = max(span * (1 / p_lo - 1 / p_hi), 1.0)  # independent frequencies
    return cov, _SpectralTest(t.k, t.ss, t.F, min(1.0, t.p_value * tries), t.explained_rms_m, float(P)), U


def sparse_function_basis(cov: Covariate):
    """:func:`function_basis` with the indicators of a category, and a long log's sparse given functions, as a
    sparse (CSR) matrix: a column that is non-zero on one set-up's rows only is stored on those rows only."""
    if cov.kind == "categorical":
        _, inv = np.unique(np.asarray(cov.values), return_inverse=True)
        inv = inv.ravel()
        return sp.csr_matrix((np.ones(len(inv)), (np.arange(len(inv)), inv)), shape=(len(inv), inv.max() + 1))
    if cov.kind == "basis" and sp.issparse(cov.values):
        return sp.csr_matrix(cov.values)
    return function_basis(cov)


#: Rows of a covariate's term basis formed at once by :func:`gram_test` (dense chunks; sparse ones are cheap).
GRAM_CHUNK_ROWS = 8192


def basis_rmatmul(Q: Basis, X) -> np.ndarray:
    """``Q^T X`` (q, m) dense for a block basis ``Q`` (n rows) and ``X`` (n, m) dense or sparse: each block of
    :data:`GRAM_CHUNK_ROWS` rows' share added into the sum in place (:meth:`core.lsq.Basis.rows_rmatmul`),
    nothing rows x columns formed."""
    n = Q.shape[0]
    out = np.zeros((Q.shape[1], X.shape[1]))
    for a in range(0, n, GRAM_CHUNK_ROWS):
        pos = np.arange(a, min(a + GRAM_CHUNK_ROWS, n))
        Q.rows_rmatmul(pos, X[pos], out=out)
    return out


def _term_chunks(cov: Covariate, F, modes: np.ndarray, rows: np.ndarray):
    """``term_basis(cov, modes)[rows]`` a block of rows at a time: (positions, block), sparse for sparse functions
    (``F``: :func:`sparse_function_basis` of ``cov``, made once by the caller)."""
    M = modes[:, list(cov.modes)]
    for a in range(0, len(rows), GRAM_CHUNK_ROWS):
        pos = np.arange(a, min(a + GRAM_CHUNK_ROWS, len(rows)))
        idx = rows[pos]
        if sp.issparse(F):
            Fc = F[idx]
            yield pos, sp.hstack([Fc.multiply(M[idx, j][:, None]) for j in range(M.shape[1])], format="csr")
        else:
            Fc, Mc = F[idx], M[idx]
            yield pos, (Mc[:, :, None] * Fc[:, None, :]).reshape(len(idx), -1)


def gram_test(cov: Covariate, Q, r: np.ndarray, rss: float, dof: int, modes: np.ndarray, rows=None,
              tol: float = IN_SPAN):
    """:func:`new_basis` and :func:`nested_f` of a covariate's term without forming its basis outside ``Q``.

    For a long log (``Q`` a :class:`core.lsq.Basis`): the term's columns
    ``B`` (normalised) are met a block of rows at a time (sparse where they
    are: a per-set-up column lives on one set-up's rows) and only ``B^T B``,
    ``Q^T B`` and ``B^T r`` kept; the part outside ``Q`` is ``P = B - Q Q^T B``
    with ``P^T P = B^T B - (Q^T B)^T Q^T B``, whose eigen-decomposition keeps
    the directions :func:`new_basis` keeps (singular value above
    ``max(tol, 1e-5)``: the difference of the Gram matrices loses about
    1e-16 of a unit column's square, 1e-6 of the cut). Returns (test, fitted
    (n,) m, k) or None when the term has no direction outside the model (or
    too few degrees of freedom are left), as :func:`diagnose` skips it.
    """
    n = len(r)
    rows = np.arange(n) if rows is None else np.asarray(rows)
    F = sparse_function_basis(cov)
    if F.shape[1] * len(cov.modes) >= n:  # more columns than rows: B^T B is the larger
        U = new_basis(Q, term_basis(cov, modes, rows), tol)
        if U.shape[1] == 0 or dof - U.shape[1] < 5:
            return None
        return nested_f(U, r, rss, dof), U @ (U.T @ r), U.shape[1]
    BB = QB = Br = None
    for pos, Bc in _term_chunks(cov, F, modes, rows):
        bb = _dense(Bc.T @ Bc)
        br = np.asarray(Bc.T @ r[pos]).ravel()
        if BB is None:  # (zeros plus the first block's share: that share, bit for bit)
            BB, QB, Br = bb, np.zeros((Q.shape[1], bb.shape[1])), br
        else:
            BB, Br = BB + bb, Br + br
        Q.rows_rmatmul(pos, Bc, out=QB)  # in place: (q, columns), 55 MiB for the 700 per-set-up ones at 1e6 rows
    if BB is None:
        return None
    nrm = np.sqrt(np.maximum(np.diag(BB), 0.0))
    keep = nrm > 0
    if not keep.any():
        return None
    nk = nrm[keep]
    # the normalised products in place of the sums when every column is kept (a copy was another 55 MiB at 1e6
    # rows): the same numbers; the fitted term below is then Q^T B's part as QBn (W z), the same to rounding
    QBn = QB if keep.all() else QB[:, keep]
    QBn /= nk
    del QB
    G = BB[np.ix_(keep, keep)] / np.outer(nk, nk) - QBn.T @ QBn
    w, V = np.linalg.eigh(G)
    good = w > max(tol, 1e-5) ** 2
    k = int(good.sum())
    if k == 0 or dof - k < 5:
        return None
    W = V[:, good] / np.sqrt(w[good])
    z = W.T @ (Br[keep] / nk - QBn.T @ (Q.T @ r))  # U^T r, U = P W orthonormal
    test = _nested_f_ss(k, float(np.sum(z ** 2)), n, rss, dof)
    cw = W @ z
    c = np.zeros(len(nrm))
    c[keep] = cw / nk  # U U^T r = B c - Q (Q^T B c), Q^T B c = QBn cw
    fitted = -(Q @ (QBn @ cw))
    for pos, Bc in _term_chunks(cov, F, modes, rows):
        fitted[pos] += np.asarray(Bc @ c).ravel()
    return test, fitted, k


def term_basis(cov: Covariate, modes: np.ndarray, rows=None) -> np.ndarray:
    """(n, len(cov.modes) * m) columns of a smooth term: each mode times each basis function."""
    F = function_basis(cov)
    M = modes[:, list(cov.modes)]
    if rows is not None:
        F, M = F[rows], M[rows]
    return (M[:, :, None] * F[:, None, :]).reshape(len(F), -1)


#: A figure draws a diagnosis's fitted term only below this adjusted p-value (the report's diagnosis panels). On a
#: long log (:func:`diagnose` given a :class:`core.lsq.Basis`) a term at or above it is not kept: each is a rows-long
#: array held for the run (the bench's 1e6-row log: 14 covariates, 8 MB each).
FIGURE_P = 0.01


@dataclass(frozen=True)
class Diagnosis:
    """Residual structure along one covariate.

    Attributes
    ----------
    covariate : str
    explained_rms_um : float
        Debiased RMS of the fitted smooth term, um.
    p_value : float
        Holm-adjusted p-value of its F test.
    p_raw : float
    k : int
        Dimensions of the term outside the model.
    words : str
        The finding in words (``"residuals follow time within each set-up:
        0.61 um, p < 1e-6"``).
    material : bool
        Explained RMS at least the materiality threshold (a fraction of the noise).
    fitted_um : (n,) float or None
        The fitted smooth term at the rows tested, um (what a figure draws);
        None on a long log when ``p_value >= FIGURE_P`` (no figure draws it).
    test : NestedTest or None
        The unadjusted test behind the figures.
    basis : (n, k) float or None
        The term's orthonormal directions outside the model (rows tested),
        ``new_basis(Q, B)``: what another test against the same model
        (:func:`diagnose`'s ``known``) can take instead of projecting again.
    """

    covariate: str
    explained_rms_um: float
    p_value: float
    p_raw: float
    k: int
    words: str
    material: bool
    fitted_um: np.ndarray | None = field(default=None, repr=False, compare=False)
    test: NestedTest | None = field(default=None, repr=False, compare=False)
    basis: np.ndarray | None = field(default=None, repr=False, compare=False)

    def significant(self, alpha: float) -> bool:
        return self.p_value < alpha and self.material

    def to_dict(self) -> dict:
        return {"covariate": self.covariate, "explained_rms_um": self.explained_rms_um,
                "p_value": self.p_value, "k": self.k, "text": self.words}


def diagnose(Q: np.ndarray, r: np.ndarray, dof: int, covariates, modes: np.ndarray, *,
             sigma_m: float, material_sigma: float, rows=None, bases: dict | None = None, known=()) -> list:
    """Test every covariate's smooth term against the model, strongest first.

    Parameters
    ----------
    Q : (n, r) float
        Orthonormal basis of the model's column space (rows used).
    r : (n,) float
        The model's residuals, m.
    dof : int
    covariates : sequence of Covariate
        Full-length covariates (``rows`` selects).
    modes : (N, m) float
        The baseline's response modes (full length).
    sigma_m : float
        Noise (1 sigma) for the materiality threshold, m.
    material_sigma : float
        A term explaining less than ``material_sigma * sigma_m`` RMS is
        immaterial (reported, never a reason to call structure).
    rows : index array or None
    bases : dict or None
        :func:`term_bases` of the covariates (computed when None).
    known : sequence of Diagnosis
        Diagnoses already made against this very model (the same ``Q``,
        ``r``, ``dof`` and ``rows``, bit for bit: the caller's promise):
        their covariates' tests are taken as they are, not made again (the
        Holm adjustment is made over ``covariates``, as always).

    Returns
    -------
    list of Diagnosis
        Sorted by adjusted p-value, then explained RMS (descending); tests
        that tie (:func:`tied`: the same span outside the model, so equal
        but for rounding) in the order of ``covariates``.
    """
    rss = float(r @ r)
    have = {d.covariate: d for d in known if d.test is not None}
    lean = isinstance(Q, Basis)  # a long log: no term basis formed or kept (gram_test)
    raw, fits = [], {}
    for cov in covariates:
        if cov.name in have:
            raw.append((cov, have[cov.name].test, have[cov.name].basis))
            if have[cov.name].basis is None:
                fits[cov.name] = have[cov.name].fitted_um
            continue
        if cov.kind == "spectral":
            res = _spectral(cov, Q, r, rss, dof, modes, rows, (bases or {}).get(cov.name))
            if res is not None:
                U, fitted = res[2]
                raw.append((cov, res[1], U))
                if U is None:  # a long log: the fitted term kept, not the sine's basis (_spectral)
                    fits[cov.name] = fitted / UM
            continue
        if lean:
            res = gram_test(cov, Q, r, rss, dof, modes, rows)
            if res is not None:
                raw.append((cov, res[0], None))
                fits[cov.name] = res[1] / UM
            continue
        B = bases[cov.name] if bases is not None else term_basis(cov, modes)
        U = new_basis(Q, B if rows is None else take_rows(B, rows))
        if U.shape[1] == 0 or dof - U.shape[1] < 5:
            continue
        raw.append((cov, nested_f(U, r, rss, dof), U))
    if not raw:
        return []
    adj = holm([t.p_value for _, t, _ in raw])
    out = []
    for (cov, t, U), pa in zip(raw, adj):
        rms_um = t.explained_rms_m / UM
        if cov.kind == "spectral":
            P = getattr(t, "period", 0.0)
            words = (f"{cov.words} (period {P / 1e-3:.3g} mm)" if cov.family == "position" else
                     f"{cov.words} (period {P:.3g} s)" if cov.family == "time" else f"{cov.words} (period {P:.3g})")
        else:
            words = cov.words
        out.append(Diagnosis(cov.name, rms_um, float(pa), t.p_value, t.k,
                             f"residuals follow {words}: {rms_um:.2g} µm, {fmt_p(float(pa))}",
                             t.explained_rms_m >= material_sigma * sigma_m,
                             (fits[cov.name] if pa < FIGURE_P else None) if U is None else (U @ (U.T @ r)) / UM,
                             t, U))
    # ties (the same span outside the model) in the covariates' order, not the kernels' rounding
    return rank_with_ties(out, lambda d: (d.p_value, -d.explained_rms_um), lambda d: (d.test.ss, d.test.k), rss)


# ---------------------------------------------------------------------------
# noise floor
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Replicates:
    """Scatter of repeated touches (same set-up, same target: the same design row).

    Attributes
    ----------
    ss : float
        Pure-error sum of squares, m^2.
    dof : int
        Sum over groups of (size - 1).
    groups : int
        Groups with two or more touches.
    """

    ss: float
    dof: int
    groups: int

    @property
    def sigma_m(self) -> float:
        return float(np.sqrt(self.ss / self.dof)) if self.dof else float("nan")


def replicate_scatter(key: np.ndarray, y: np.ndarray, trend: np.ndarray | None = None) -> Replicates:
    """Pure replicate scatter of ``y`` within groups of equal ``key`` (``key < 0``: no group).

    ``trend`` (n, q), optional: columns whose variation within the groups is
    removed first. Repeats of one target minutes apart differ by whatever
    drifts in between (a thermal drift, a probe warming); with ``trend`` the
    within-group deviations of ``y`` (``y`` less its group mean, the
    contrasts of the group) are regressed on the same deviations of these
    columns, and ``ss`` is what is left, ``dof`` the contrasts less the rank
    of that regression. Under pure Gaussian noise ``ss / sigma^2`` is then
    exactly chi-square with ``dof`` degrees of freedom (unbiased, like the
    plain estimate); a drift the columns represent (discovery: a rate per
    set-up and response mode, :func:`core.discover.drift_trend`) adds
    nothing, a drift's curvature over a group's time span still does.
    """
    key = np.asarray(key)
    if key.shape != np.shape(y):
        raise ConfigError(f"replicate_scatter: key {key.shape} and y {np.shape(y)} must have one entry per row")
    if trend is not None and (len(np.shape(trend)) != 2 or np.shape(trend)[0] != len(key)):
        raise ConfigError(f"replicate_scatter: trend must be ({len(key)}, q), got {np.shape(trend)}")
    ok = key >= 0
    if not ok.any():
        return Replicates(0.0, 0, 0)
    k, inv, cnt = np.unique(key[ok], return_inverse=True, return_counts=True)
    yy = y[ok]
    s = group_sums(inv, len(k), yy)
    mean = s / cnt
    res = yy - mean[inv]
    dof = int(np.sum(cnt - 1))
    if trend is not None and trend.shape[1] and dof:
        # (a sparse trend: its repeated rows formed, the same values)
        B = _trend_within(_dense(trend[ok]), inv, len(k), cnt)
        if B.shape[1]:
            res = res - B @ (B.T @ res)
            dof -= B.shape[1]
    return Replicates(float(res @ res), max(dof, 0), int(np.sum(cnt > 1)))


#: The most groups :func:`straddled_groups` sets aside (its steps, each a refit of the rest): half the groups up to
#: this many (a log of up to 101 groups is tested to half its groups; a longer one's cost stays bounded).
STRADDLED_MAX_STEPS = 50


def _trend_within(T: np.ndarray, inv: np.ndarray, g: int, cnt: np.ndarray) -> np.ndarray:
    """(n, r) orthonormal basis of a time trend's variation within the repeat groups: ``T``'s columns less their
    group means (``inv`` each row's group of ``g``, ``cnt`` their sizes), those that vanish within the groups
    dropped; (n, 0) where none is left. What :func:`replicate_scatter` and :func:`straddled_groups` take out of
    the repeats' residuals beside their means."""
    return _basis_within(T, T - (group_sums(inv, g, T) / cnt[:, None])[inv])


def _basis_within(T: np.ndarray, Tc: np.ndarray) -> np.ndarray:
    """:func:`_trend_within` from ``T`` and its deviations from the group means ``Tc`` (the same operations; the
    columns' norms by :func:`col_norms`, ``np.linalg.norm``'s bit for bit)."""
    nrm = col_norms(Tc)
    big = nrm > 1e-9 * np.maximum(col_norms(T), 1e-300)
    return orth(Tc[:, big]) if big.any() else np.zeros((len(T), 0))


def separated_groups(key: np.ndarray, t_s: np.ndarray, setup: np.ndarray,
                     fraction: float | None = None) -> np.ndarray:
    """The keys (sorted) of the repeat groups (``key >= 0``) whose touches something separates: some two of its
    touches consecutive in time (within one ``setup``) have another touch of that set-up between them, or are more
    than ``fraction`` (default :data:`CLOSE_PAIR_FRACTION`) of the set-up's time span apart (the short-term scale of
    :func:`close_pair_scatter`), or lie
    in different set-ups. Only such a group can straddle a step (a slip, a knock) within its set-up: two touches one
    right after the other, with nothing between them and seconds apart, hold no event between them that is not
    noise (review32c F1: a pair 7 s apart, one touch a heavy-tailed noise tail, was set aside as straddling)."""
    key, t_s, setup = (np.asarray(a) for a in (key, t_s, setup))
    if not (key.shape == t_s.shape == setup.shape):
        raise ConfigError("separated_groups: key, t_s and setup must have one entry per row, got "
                          f"{key.shape}, {t_s.shape}, {setup.shape}")
    fraction = CLOSE_PAIR_FRACTION if fraction is None else fraction
    t_s = t_s.astype(float)
    su, sinv = np.unique(setup, return_inverse=True)
    sinv = sinv.ravel()
    lo = np.full(su.size, np.inf)
    hi = np.full(su.size, -np.inf)
    np.minimum.at(lo, sinv, t_s)
    np.maximum.at(hi, sinv, t_s)
    span = hi - lo
    ok = np.flatnonzero(key >= 0)
    order = ok[np.lexsort((t_s[ok], key[ok]))]  # by target, then time
    a, b = order[:-1], order[1:]
    same = key[a] == key[b]
    a, b = a[same], b[same]
    # touches of the set-up strictly between the two (in time): the set-up's times sorted, counted by bisection
    between = np.zeros(a.size, dtype=int)
    for j in range(su.size):
        m = (sinv[a] == j) & (sinv[b] == j)
        if m.any():
            ts = np.sort(t_s[sinv == j])
            between[m] = (np.searchsorted(ts, t_s[b[m]], side="left")
                          - np.searchsorted(ts, t_s[a[m]], side="right"))
    sep = ((sinv[a] != sinv[b]) | (between > 0)
           | (t_s[b] - t_s[a] > fraction * span[sinv[a]]))
    return np.unique(key[a[sep]])


def straddled_groups(key: np.ndarray, y: np.ndarray, trend: np.ndarray | None = None,
                     alpha: float = 0.01, eligible: np.ndarray | None = None) -> np.ndarray:
    """Replicate groups whose scatter is no probe's: the keys (sorted) of groups that scatter beyond the others.

    Repeats of one target touched before and after a step within their
    set-up (a fixture slip, a knock) differ by the step; the other groups'
    scatter is the probe's. Pure error is one variance shared by every
    group, so a group that holds a step is an outlying variance among them
    (Cochran's problem), told by an exact test: leaving one group ``g`` out
    of :func:`replicate_scatter` (with the same ``trend``) is the nested
    model with one free parameter per touch of ``g``; what its contrasts
    add, ``dss_g`` over ``ddof_g`` degrees of freedom, against the other
    groups' ``ss - dss_g`` over ``dof - ddof_g`` is ``F(ddof_g, dof -
    ddof_g)`` under pure Gaussian noise, independent of them. The group of
    the smallest p-value is taken out and the test made again on the rest,
    ``m`` steps in all (half the groups, at most
    :data:`STRADDLED_MAX_STEPS`); each step's p-value is multiplied by the
    groups still in and by ``m`` (Bonferroni over both), and the groups set
    aside are those up to the last step below ``alpha`` (generalised-ESD
    fashion: the largest step's pairs mask the next one's, which the test
    on the rest then sees). Under pure noise it set one aside in at most
    ``alpha`` of logs (the unit test's draws: 0.1-0.9 %). A drift or a re-seat that moves every group's
    repeats alike is no outlying variance: it is not seen (nor meant to be).

    ``dss_g`` is the deleted-group formula: ``e_g' (I - J/n_g - B_g
    B_g')^+ e_g`` with ``e`` the scatter's residuals and ``B`` the basis of
    the trend's within-group deviations, ``ddof_g`` that matrix's rank.

    ``eligible`` (keys), optional: only these groups may be set aside (the
    others stay in the pool as pure error, and the Bonferroni factor counts
    the eligible groups still in): :func:`separated_groups`, the groups
    whose touches something separates (session 32, review32c F1).
    """
    key = np.asarray(key)
    steps, max_out = _straddled_steps(key, y, trend, eligible)
    sig = [i for i, (pb, _) in enumerate(steps) if pb * max_out < alpha]
    out = [kk for _, kk in steps[:sig[-1] + 1]] if sig else []
    return np.sort(np.asarray(out, dtype=key.dtype))


def _straddled_steps(key: np.ndarray, y: np.ndarray, trend: np.ndarray | None, eligible=None):
    """:func:`straddled_groups`' steps, ``[(p * groups still in, key), ...]``, and ``m`` (the most steps)."""
    ok = np.flatnonzero(key >= 0)
    if ok.size == 0:
        return [], 1
    yy = np.asarray(y, float)[ok]
    T = None
    if trend is not None and np.shape(trend)[1]:
        T = _dense(trend[ok])
    # Each step's groups are the first's less whole groups, the rows kept in their order: the groups' keys, sizes
    # and each row's group (np.unique's of the rows kept) are the first step's less the groups taken out, and a
    # group's mean (of y, of the trend's columns) sums the same rows in the same order (group_sums: bincount) at
    # every step, so the rows' means are formed once and taken at the rows kept. Bit for bit the step's own
    # np.unique and group_sums (tests/core/test_straddled_fastpath.py against the plain loop); session 24.
    k, inv, cnt = np.unique(key[ok], return_inverse=True, return_counts=True)
    inv = inv.ravel()
    y_dev = yy - (group_sums(inv, len(k), yy) / cnt)[inv]  # (each row less its group's mean: the same subtraction)
    T_dev = T - (group_sums(inv, len(k), T) / cnt[:, None])[inv] if T is not None else None
    rows = np.arange(ok.size)  # the rows kept (of ok's)
    steps: list = []  # (Bonferroni p, key) of the most outlying group, then of the rest's, ...
    max_out = min(max(int(np.sum(cnt > 1)) // 2, 1), STRADDLED_MAX_STEPS)
    elig = np.ones(len(k), dtype=bool) if eligible is None else np.isin(k, np.asarray(eligible))
    while True:
        multi = cnt > 1
        if multi.sum() < 3:
            break
        res = y_dev[rows]
        dof = int(np.sum(cnt - 1))
        B = np.zeros((len(res), 0))
        if T is not None and dof:
            B = _basis_within(T[rows], T_dev[rows])
            if B.shape[1]:
                res = res - B @ (B.T @ res)
                dof -= B.shape[1]
        ss = float(res @ res)
        if dof < 2 or not ss > 0:
            break
        order = np.argsort(inv, kind="stable")
        starts = np.concatenate([[0], np.cumsum(cnt)])
        p_g = np.ones(len(k))
        for n_g in np.unique(cnt[multi]):  # the groups of one size at once
            gs = np.flatnonzero(cnt == n_g)
            idx = order[starts[gs][:, None] + np.arange(n_g)]  # (groups, n_g) rows
            Bi = B[idx]
            M = np.eye(n_g) - 1.0 / n_g - np.einsum("gik,gjk->gij", Bi, Bi)
            w, V = np.linalg.eigh(M)
            pos = w > 1e-9
            z = np.einsum("gij,gi->gj", V, res[idx])
            dss = np.sum(np.where(pos, z ** 2 / np.where(pos, w, 1.0), 0.0), axis=1)
            ddof = pos.sum(axis=1)
            rest = ss - dss
            good = (ddof > 0) & (ddof < dof)
            F = np.where(good & (rest > 0), (dss / np.maximum(ddof, 1)) / np.maximum(rest, 1e-300)
                         * (dof - ddof), np.inf)
            # (special.fdtrc: stats.f.sf's own function without its argument handling, 40 -> 1.2 us a call;
            # F = inf -> 0 and F = 0 -> 1 as there)
            p_g[gs] = np.where(good, special.fdtrc(np.maximum(ddof, 1), np.maximum(dof - ddof, 1), F), 1.0)
        if eligible is not None:
            p_g[~elig] = 1.0  # (a group nothing separates stays pure error)
        g = int(np.argmin(p_g))
        if not p_g[g] < 1.0:
            break
        steps.append((float(p_g[g]) * int((multi if eligible is None else multi & elig).sum()), k[g]))
        if len(steps) >= max_out:
            break
        # group g out: np.unique of the rows left gives the same keys less k[g], the later groups' index one less
        stay = inv != g
        rows, inv = rows[stay], inv[stay]
        inv[inv > g] -= 1
        k, cnt, elig = np.delete(k, g), np.delete(cnt, g), np.delete(elig, g)
    return steps, max_out


#: Repeats no further apart in time than this share of their set-up's time
#: span are a short-term pair (:func:`close_pair_scatter`).
CLOSE_PAIR_FRACTION = 0.05


def close_pair_scatter(key: np.ndarray, y: np.ndarray, t_s: np.ndarray, setup: np.ndarray,
                       fraction: float = CLOSE_PAIR_FRACTION) -> Replicates:
    """Short-term repeatability: the scatter of repeats touched one right after the other.

    Repeats of one target (equal ``key >= 0``) are taken in time order; each
    two consecutive ones whose gap is at most ``fraction`` of their
    set-up's time span (the span of every row of that ``setup`` given) form
    a pair, and ``ss = sum(d^2) / 2`` over the pairs' differences ``d``,
    ``dof`` the number of pairs. ``E[d^2] = 2 sigma^2`` for every pair under
    pure noise, so ``ss / dof`` is unbiased (pairs sharing a touch are
    correlated: ``ss / sigma^2`` is then only near chi-square with ``dof``
    degrees of freedom). A drift moves such a pair by its rate times a gap
    a twentieth of the set-up at most; repeats minutes apart (a drift check)
    measure the drift as well, which is what they are for: their scatter is
    not the probing noise when the drift is not linear in time
    (:func:`replicate_scatter` with a trend removes only a linear one).
    ``groups`` counts the targets with at least one pair.
    """
    key, y, t_s, setup = (np.asarray(a) for a in (key, y, t_s, setup))
    if not (key.shape == y.shape == t_s.shape == setup.shape):
        raise ConfigError("close_pair_scatter: key, y, t_s and setup must have one entry per row, got "
                          f"{key.shape}, {y.shape}, {t_s.shape}, {setup.shape}")
    su, sinv = np.unique(setup, return_inverse=True)
    lo = np.full(su.size, np.inf)
    hi = np.full(su.size, -np.inf)
    np.minimum.at(lo, sinv, t_s)
    np.maximum.at(hi, sinv, t_s)
    span = (hi - lo)[sinv]
    ok = np.flatnonzero(key >= 0)
    order = ok[np.lexsort((t_s[ok], key[ok]))]  # by target, then time
    a, b = order[:-1], order[1:]
    pair = (key[a] == key[b]) & (setup[a] == setup[b]) & (t_s[b] - t_s[a] <= fraction * span[a])
    d = y[b[pair]] - y[a[pair]]
    return Replicates(float(d @ d) / 2.0, int(pair.sum()), int(np.unique(key[a[pair]]).size))


@dataclass(frozen=True)
class LackOfFit:
    """Classical lack-of-fit F test: residual scatter beyond the replicates' scatter."""

    F: float
    p_value: float
    sigma_lof_m: float  # sqrt of the lack-of-fit variance component (0 when below the replicates)
    dof: int
    dof_pe: int = 0  # the pure error's degrees of freedom (the F's second)


def lack_of_fit(rss: float, dof: int, rep: Replicates) -> LackOfFit | None:
    """F = ((RSS - SS_PE) / (dof - dof_PE)) / (SS_PE / dof_PE), or None without replicates.

    Valid when the model's design rows are equal within each replicate
    group (the baseline's are: same set-up, same target).
    """
    if rep.dof < 5 or dof - rep.dof < 1:
        return None
    d1 = dof - rep.dof
    ms_lof = max(rss - rep.ss, 0.0) / d1
    ms_pe = rep.ss / rep.dof
    F = ms_lof / max(ms_pe, 1e-300)
    return LackOfFit(F, float(stats.f.sf(F, d1, rep.dof)), float(np.sqrt(max(ms_lof - ms_pe, 0.0))), d1, rep.dof)


@dataclass(frozen=True)
class CvGap:
    """Cross-validated against in-sample residuals, and what pure noise would give.

    Attributes
    ----------
    ratio : float
        ``cv_ss / rss`` observed.
    expected : float
        Its mean under the null (same model, same folds).
    p_value : float
        Upper tail of the observed ratio under a chi-square scaled to the
        draws' mean and variance (Satterthwaite).
    sigma_cv_m : float
        Noise level that would explain the cross-validated residuals:
        ``sqrt(cv_ss / E||M z||^2)`` (M the linear CV map, z standard normal).
    draws : int
    """

    ratio: float
    expected: float
    p_value: float
    sigma_cv_m: float
    draws: int


#: Relative spread (standard deviation over mean) of the CV-gap draws' ratios below which the draws are alike:
#: the ratio does not vary with the noise (every held-out residual a fixed multiple of an in-sample one, as
#: in a positioning test's leave-one-cycle-out: 1.5625 = (5/4)^2 for every draw) and what spread there is
#: is rounding (about 1e-15 relative). A gamma tail fitted to that spread (shape about 1e30) turns the
#: observed ratio's own rounding into any p-value between 0 and 1 (0.09 on an effect-free positioning
#: run, where the answer is 1). 1e-9: six orders above rounding, far below a noise-driven spread
#: (3.6e-3 relative with one gross reading in that positioning test).
NULL_ALIKE = 1e-9


def cv_gap(cv_ss: float, rss: float, null_cv_ss: np.ndarray, null_rss: np.ndarray, scale: float = 1.0) -> CvGap:
    """The CV-gap test from the observed sums and their null draws.

    The draws are observations through the same linear fit and folds:
    standard normal noise (``scale`` 1), or a parametric bootstrap (the
    fitted model plus noise of standard deviation ``scale``,
    :func:`core.discover._cv_gap`). Under Gaussian noise, and when the folds
    predict the model's own fitted field exactly, the ratio ``cv_ss / rss``
    does not depend on the noise level, and the draws give its distribution
    up to Monte Carlo error.
    """
    null = null_cv_ss / np.maximum(null_rss, 1e-300)
    ratio = cv_ss / max(rss, 1e-300)
    # the held-out sum of squares is a quadratic form in the noise: a scaled
    # chi-square with matched mean and variance (Satterthwaite) gives its
    # tail from the draws' mean and spread, so a p-value below 1 / draws is
    # still resolved. When many directions share the held-out error the
    # shape is large and the tail is the normal's; when one poorly
    # predicted set-up dominates it the shape falls towards 1/2 and the
    # tail is a chi-square's with one degree of freedom (a normal tail
    # would call its ordinary excursions structure).
    mu = float(np.mean(null)) if len(null) else float("nan")
    var = float(np.var(null, ddof=1)) if len(null) > 1 else float("nan")
    if mu > 0 and var <= (NULL_ALIKE * mu) ** 2:  # every draw alike: the ratio does not vary with the noise
        p = 1.0 if ratio <= mu * (1 + NULL_ALIKE) else 0.0
    elif var > 0 and mu > 0:
        p = float(stats.gamma.sf(ratio, mu * mu / var, scale=var / mu))
    else:  # fewer than two draws: no test
        p = 1.0
    return CvGap(float(ratio), float(np.mean(null)), p,
                 float(np.sqrt(cv_ss / max(np.mean(null_cv_ss) / scale ** 2, 1e-300))), int(len(null)))
