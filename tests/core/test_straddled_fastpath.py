"""The straddled-groups screen's steps (core.diagnosis._straddled_steps) against the plain loop they replaced, bit
for bit: session 24 formed the groups' keys, sizes and means once and took the groups out of them step by step,
where each step had made its own np.unique and group sums; and pivoted_qr's economic factorisation calls LAPACK's
geqp3 and orgqr itself (scipy's qr without its argument handling). Known answers: the plain computation, written
out here as it stood (session 23, 586aff4), on many layouts of groups, trends and outliers."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
from scipy import special

from core.diagnosis import STRADDLED_MAX_STEPS, _qr_economic_pivoted, _straddled_steps, pivoted_qr, \
    straddled_groups
from core.lsq import _dense, group_sums


def _plain_pivoted_qr(M):
    """pivoted_qr as it stood: scipy's qr of the scaled columns."""
    nrm = np.linalg.norm(M, axis=0)
    keep = nrm > 0
    Q, R, _ = sla.qr(M[:, keep] / nrm[keep], mode="economic", pivoting=True)
    return Q, np.abs(np.diag(R))


def _plain_trend_within(T, inv, g, cnt):
    Tc = T - (group_sums(inv, g, T) / cnt[:, None])[inv]
    nrm = np.linalg.norm(Tc, axis=0)
    big = nrm > 1e-9 * np.maximum(np.linalg.norm(T, axis=0), 1e-300)
    if not big.any():
        return np.zeros((len(T), 0))
    Q, d = _plain_pivoted_qr(Tc[:, big])
    return Q[:, :int(np.sum(d > 1e-9 * d[0]))]


def _plain_steps(key, y, trend=None):
    """The screen's loop as it stood: each step its own np.unique, group sums and trend basis."""
    key = np.asarray(key)
    ok = np.flatnonzero(key >= 0)
    if ok.size == 0:
        return [], 1
    yy = np.asarray(y, float)[ok]
    T = None
    if trend is not None and np.shape(trend)[1]:
        T = _dense(trend[ok])
    kept = np.ones(ok.size, bool)
    steps = []
    max_out = min(max(int(np.sum(np.unique(key[ok], return_counts=True)[1] > 1)) // 2, 1), STRADDLED_MAX_STEPS)
    while True:
        k, inv, cnt = np.unique(key[ok][kept], return_inverse=True, return_counts=True)
        multi = cnt > 1
        if multi.sum() < 3:
            break
        yk = yy[kept]
        mean = group_sums(inv, len(k), yk) / cnt
        res = yk - mean[inv]
        dof = int(np.sum(cnt - 1))
        B = np.zeros((len(yk), 0))
        if T is not None and dof:
            B = _plain_trend_within(T[kept], inv, len(k), cnt)
            if B.shape[1]:
                res = res - B @ (B.T @ res)
                dof -= B.shape[1]
        ss = float(res @ res)
        if dof < 2 or not ss > 0:
            break
        order = np.argsort(inv, kind="stable")
        starts = np.concatenate([[0], np.cumsum(cnt)])
        p_g = np.ones(len(k))
        for n_g in np.unique(cnt[multi]):
            gs = np.flatnonzero(cnt == n_g)
            idx = order[starts[gs][:, None] + np.arange(n_g)]
            M = np.eye(n_g) - 1.0 / n_g - np.einsum("gik,gjk->gij", B[idx], B[idx])
            w, V = np.linalg.eigh(M)
            pos = w > 1e-9
            z = np.einsum("gij,gi->gj", V, res[idx])
            dss = np.sum(np.where(pos, z ** 2 / np.where(pos, w, 1.0), 0.0), axis=1)
            ddof = pos.sum(axis=1)
            rest = ss - dss
            good = (ddof > 0) & (ddof < dof)
            F = np.where(good & (rest > 0), (dss / np.maximum(ddof, 1)) / np.maximum(rest, 1e-300)
                         * (dof - ddof), np.inf)
            p_g[gs] = np.where(good, special.fdtrc(np.maximum(ddof, 1), np.maximum(dof - ddof, 1), F), 1.0)
        g = int(np.argmin(p_g))
        if not p_g[g] < 1.0:
            break
        steps.append((float(p_g[g]) * int(multi.sum()), k[g]))
        if len(steps) >= max_out:
            break
        kept &= key[ok] != k[g]
    return steps, max_out


def _layout(rng, i):
    """A log of repeat groups: sizes 1-5 (or all pairs, as the demo's), keys shuffled with rows of no group, a trend
    of 0-12 columns (dense C or F order, sparse, per set-up rates, constant within groups, repeated), steps."""
    G = int(rng.integers(2, 70))
    sizes = np.full(G, 2) if i % 3 == 0 else rng.integers(1, 6, G)
    keys = rng.permutation(np.repeat(rng.choice(10 * G + 5, G, replace=False), sizes))
    n_none = int(rng.integers(0, 20))
    key = rng.permutation(np.concatenate([keys, np.full(n_none, -1)]))
    n = key.size
    y = rng.normal(0, 10.0 ** rng.uniform(-8, -5), n)
    for kk in rng.choice(np.unique(keys), min(int(rng.integers(0, 4)), G), replace=False):  # groups holding a step
        rows = np.flatnonzero(key == kk)
        y[rows[len(rows) // 2:]] += rng.normal(0, 20) * np.std(y)
    q = int(rng.integers(0, 13))
    t = np.cumsum(rng.uniform(0, 1, n))
    if i % 4 == 1:  # per set-up rates (the engine's drift_trend: one column per set-up, zero elsewhere)
        setup = rng.integers(0, max(q, 1), n)
        T = np.zeros((n, max(q, 1)))
        T[np.arange(n), setup] = t
    else:
        T = rng.normal(size=(n, q)) * t[:, None] ** rng.uniform(0, 1, q)
        if q >= 2 and i % 5 == 0:
            T[:, 1] = T[:, 0] * 2.0  # a repeated column (the basis' rank below the columns)
        if q >= 3 and i % 7 == 0:
            T[:, 2] = key.astype(float)  # constant within every group: vanishes within them
    kind = i % 4
    trend = None if (kind == 2 and i % 8 == 2) else (np.asfortranarray(T) if kind == 3 else
                                                    sp.csr_matrix(T) if kind == 1 else T)
    return key, y, trend


def _steps_given(key, y, trend, got):
    """:func:`core.diagnosis._straddled_steps` for :func:`straddled_groups`' call on this layout: ``got``, its answer
    on the same arrays just checked against the plain loop; a call with any other arguments (not the same objects,
    or ``eligible``) goes to the real function, so an argument passed wrong still shows."""
    def steps(k, yy, tr, eligible=None):
        if k is key and yy is y and tr is trend and eligible is None:
            return got
        return _straddled_steps(k, yy, tr, eligible)
    return steps


@pytest.mark.parametrize("block", range(6))
def test_straddled_steps_are_the_plain_loops_bit_for_bit(block, monkeypatch):
    """Known answers: the plain loop's steps (each p-value times the groups still in, each key) and its most steps,
    equal as numbers and as bytes, on 60 layouts per block; and the groups set aside at three levels.

    straddled_groups is its steps (the fast ones) cut at ``alpha``: at each level it runs on the steps just checked
    (:func:`_steps_given`): four calls per layout, each computing those steps again, were 60 % of the test's CPU
    (session 36: a block 4.3 -> 1.6 s; the thresholding, the sort, the dtype and the arguments handed on are
    straddled_groups' own, as before: an off-by-one in the cut, the trend not handed on or the Bonferroni factor
    dropped each fails this test, as it failed the test before)."""
    import core.diagnosis as diag

    rng = np.random.default_rng(24_000 + block)
    fired = 0
    for i in range(60):
        key, y, trend = _layout(rng, i + 60 * block)
        want = _plain_steps(key, y, trend)
        got = _straddled_steps(key, y, trend)
        assert got[1] == want[1]
        assert len(got[0]) == len(want[0]), (block, i)
        for (p1, k1), (p0, k0) in zip(got[0], want[0]):
            assert k1 == k0 and np.float64(p1).tobytes() == np.float64(p0).tobytes(), (block, i)
        monkeypatch.setattr(diag, "_straddled_steps", _steps_given(key, y, trend, got))
        for alpha in (0.01, 0.05, 1.0):
            sig = [j for j, (pb, _) in enumerate(want[0]) if pb * want[1] < alpha]
            out = np.sort(np.asarray([kk for _, kk in want[0][:sig[-1] + 1]] if sig else [], dtype=key.dtype))
            groups = straddled_groups(key, y, trend, alpha=alpha)
            assert groups.tolist() == out.tolist() and groups.dtype == key.dtype
            if alpha == 0.01:
                fired += groups.size > 0
        monkeypatch.undo()
    assert 0 < fired < 60  # layouts with and without groups set aside


def test_straddled_steps_on_the_demo_campaigns_repeats(monkeypatch):
    """Known answer: on the screen's call in the demo's discover (64 repeat pairs, the per set-up drift trend as a
    sparse matrix), the plain loop's 32 steps, none below the level."""
    import core.discover as D
    from scenarios.bench.discover import demo_campaign

    seen = []
    monkeypatch.setattr(D, "straddled_groups", lambda *a, **kw: seen.append(a) or straddled_groups(*a, **kw))
    D.discover(demo_campaign())
    assert len(seen) == 1
    key, y, trend = seen[0][:3]
    want, got = _plain_steps(key, y, trend), _straddled_steps(key, y, trend)
    assert sp.issparse(trend) and len(want[0]) == 32 and want[1] == 32
    assert [(np.float64(p).tobytes(), k) for p, k in got[0]] == [(np.float64(p).tobytes(), k) for p, k in want[0]]


def test_pivoted_qr_calls_lapack_as_scipy_does():
    """Known answers: scipy's economic pivoted QR (Q and |diag R|) bit for bit on 400 finite matrices of 1-300 rows,
    1-60 columns, column scales 1e-8-1e8, repeated columns, C and F order; pivoted_qr the same as before; a matrix
    with a NaN or more columns than rows goes to scipy (its error, its answer)."""
    rng = np.random.default_rng(24)
    for trial in range(400):
        m = int(rng.integers(1, 300))
        k = int(rng.integers(1, min(m, 60) + 1))
        A = rng.normal(size=(m, k)) * 10.0 ** rng.uniform(-8, 8, size=k)
        if trial % 5 == 0 and k > 1:
            A[:, -1] = A[:, 0] * 3
        if trial % 7 == 0:
            A = np.asfortranarray(A)
        Q, R, _ = sla.qr(A, mode="economic", pivoting=True)
        Q2, d2 = _qr_economic_pivoted(A)
        assert Q.tobytes() == Q2.tobytes() and np.abs(np.diag(R)).tobytes() == d2.tobytes(), trial
        Qp, dp, Mp = pivoted_qr(A)
        Q0, d0 = _plain_pivoted_qr(A)
        assert Qp.tobytes() == Q0.tobytes() and dp.tobytes() == d0.tobytes() and Mp is A
    wide = rng.normal(size=(3, 7))
    assert pivoted_qr(wide)[0].tobytes() == _plain_pivoted_qr(wide)[0].tobytes()
    bad = rng.normal(size=(9, 3))
    bad[2, 1] = np.inf  # (a column of NaN has no norm > 0: left out, before as now)
    for f in (pivoted_qr, _plain_pivoted_qr):
        with pytest.raises(ValueError, match="infs or NaNs"), np.errstate(invalid="ignore"):
            f(bad)


def _plain_face_groups(f_t, nrm):
    """_target_faces' groups as it stood: each target's feature's normals made unique again for every target."""
    key = []
    for j in range(len(f_t)):
        mine = f_t == f_t[j]
        planar_faces = len(np.unique(nrm[mine], axis=0)) <= 3
        key.append((f_t[j], tuple(nrm[j])) if planar_faces else (f_t[j],))
    return np.unique(np.array([repr(k) for k in key]), return_inverse=True)[1]


@pytest.mark.parametrize("campaign", ["demo", "gen_a", "gen_b"])
def test_target_faces_once_a_feature_is_the_plain_loops(campaign, monkeypatch):
    """Known answers: _target_faces (session 24: a feature's normals made unique once, not once per target: 4.8 ->
    0.5 ms of the demo's discover) gives the plain loop's groups on the demo's campaign and a blind campaign of
    each generator (tuning seed 1000), its other outputs unchanged in kind."""
    import core.discover as D
    from core.touches import from_log

    if campaign == "demo":
        from scenarios.bench.discover import demo_campaign
        t = demo_campaign()
    else:
        import importlib
        mod = importlib.import_module(f"scenarios.blind.{campaign}")
        t = from_log(mod.generate(next(iter(mod.effects())), 1000)[0])
    seen = []
    orig = D._target_faces
    monkeypatch.setattr(D, "_target_faces", lambda *a: seen.append((a, orig(*a))) or seen[-1][1])
    D.discover(t)
    checked = []
    for (bl, tt, feats), got in seen:
        if got[0] is None:
            continue
        tid = np.asarray(tt.target, int)
        first = np.unique(tid, return_index=True)[1]
        want = _plain_face_groups(feats[first].astype(str), np.round(np.asarray(bl.geometry[1], float), 3))
        assert got[3].tolist() == want.tolist()
        checked.append(int(want.max()) + 1)
    assert checked and min(checked) > 1, checked  # (faces to tell apart)
