"""Session 25: a long log's periodic path length estimated from its speed at a sample of frequencies.

Beyond :data:`core.discover.PATH_ARC_ROWS` rows the periodic scan's path
(:func:`core.discover._path_tries`) is no longer summed trial by trial
(every trial projected out of the model: about 30 min of CPU at 1e6
rows) but estimated by :func:`core.discover._arc_path`: the path's speed
at one frequency drawn in each of :data:`core.discover.PATH_ARC_SAMPLES`
strata, integrated, plus :data:`core.discover.PATH_ARC_Z` standard
errors (docs/discovery.md, "Session 25: the periodic path count on long
logs").
"""

from __future__ import annotations

import numpy as np
import pytest

from core import causes
from core import discover as D
from core.diagnosis import scan_grid
from core.lsq import Basis


def _design(seed: int = 5, targets: int = 60, per: int = 10):
    """A moderate planar design: ``targets`` targets each touched ``per`` times at scattered positions and normals,
    the model their per-target constants and a quadratic map along x and y (both as an array and as a long log's
    block basis); a periodic scan along x as :func:`core.causes.periodic_scans` makes it (three trials per
    independent frequency, the range widened by one step either side)."""
    rng = np.random.default_rng(seed)
    n = targets * per
    tgt = np.repeat(np.arange(targets), per)
    x = rng.uniform(-0.1, 0.1, targets)[tgt] + rng.normal(0, 0.004, n)
    y = rng.uniform(-0.1, 0.1, targets)[tgt] + rng.normal(0, 0.004, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    nx, ny = np.cos(ang), np.sin(ang)
    ind = np.zeros((n, targets))
    ind[np.arange(n), tgt] = 1.0
    smooth = np.column_stack([nx * x, nx * y, ny * x, ny * y, nx * x ** 2, ny * y ** 2, nx, ny])
    Qa = np.linalg.qr(np.column_stack([ind, smooth]))[0]
    # the same span as a block basis: normalised indicators, then the smooth columns centred per target
    cen = smooth - (ind @ (ind.T @ smooth)) / per
    Qb = Basis(tgt, np.full(targets, per), np.linalg.qr(cen)[0])
    span = np.ptp(x)
    f, _ = scan_grid(2 * span / (n - 1), 0.02, span)
    d = type("D", (), {"x": x, "y": y, "nx": nx, "ny": ny})()
    step = f[1] - f[0]
    scan = causes.Scan(("a", "b", "c", "d"), tuple({"period_m": 1 / v} for v in f), "x",
                       lambda idx: causes._periodic_cols(d, 0, 1 / f[np.asarray(idx)]), path=True,
                       path_at=lambda fq: causes._periodic_cols(d, 0, 1 / np.asarray(fq, float)),
                       path_range=(float(f[0] - step), float(f[-1] + step)))
    rows = np.arange(n)
    st = [D._State(rows, Q, np.zeros(n), 1.0, n - 70) for Q in (Qa, Qb)]
    return scan, st, d, f


def _analytic_speed(d, Q, fq):
    """The path's speed at frequency ``fq`` from the columns' derivative in frequency (not a difference):
    ``sqrt(tr(A^-1 (E - B^T A^-1 B)) / k)`` with ``A``, ``B``, ``E`` the Gram blocks of the columns and their
    derivatives beside the model (the motion of an orthonormal basis of the span out of its own span)."""
    ph = 2 * np.pi * d.x * fq
    s, c = np.sin(ph), np.cos(ph)
    w = 2 * np.pi * d.x
    C = np.column_stack([-d.nx * s, -d.nx * c, -d.ny * s, -d.ny * c])
    Dd = np.column_stack([-d.nx * c * w, d.nx * s * w, -d.ny * c * w, d.ny * s * w])
    X = np.column_stack([C, Dd])
    X = X - Q @ (Q.T @ X)
    G = X.T @ X
    A, B, E = G[:4, :4], G[:4, 4:], G[4:, 4:]
    Ai = np.linalg.inv(A)
    return float(np.sqrt(np.trace(Ai @ (E - B.T @ Ai @ B)) / 4))


def test_arc_speed_is_the_derivatives():
    """The speed :func:`core.discover._arc_speeds` takes from a short chord equals the one the columns' derivative
    gives, to 1e-4 relative (the chord over ``h`` is the speed to about ``(speed h)^2 / 24``, 1e-8 here, and the
    angle's rounding is about 1e-8 rad of a chord of about 1e-3 rad), against the array basis and the block one."""
    scan, (sa, sb), d, f = _design()
    Qa = sa.Q
    fq = np.array([f[3], f[len(f) // 2] + 0.3 * (f[1] - f[0]), f[-5]])
    h = D.PATH_ARC_H * (f[1] - f[0])
    want = [_analytic_speed(d, Qa, v) for v in fq]
    for st in (sa, sb):
        sp, m = D._arc_speeds(scan, st, fq, h, 1)
        assert list(m) == [4, 4, 4]
        np.testing.assert_allclose(sp, want, rtol=1e-4)


def test_arc_count_bounds_the_trial_by_trial_count():
    """Known answer on a moderate log: the estimated length is at least the trial-by-trial chord sum (an arc is
    never shorter than its chords, and the estimate adds its margin) and within 12 % of it (the two end steps the
    refinement reaches, 2 of the scan's trials, about 1.3 %; a chord's shortfall of its arc at three trials per
    independent frequency, about 1.5 %; three standard errors of 32 strata, about 3-6 %); the count at every level
    follows; the block basis gives the array's figures to 1e-9 relative."""
    scan, (sa, sb), d, f = _design()
    exact = D._subspace_path(scan.build(np.arange(scan.size)), sa)
    arcs = [D._arc_path(scan, st, 10 ** 6) for st in (sa, sb)]
    assert list(exact) == [4] and list(arcs[0]) == [4]
    assert arcs[1][4] == pytest.approx(arcs[0][4], rel=1e-9)
    assert exact[4] <= arcs[0][4] <= 1.12 * exact[4]
    # the integral itself (no margin) against a chord sum eight times finer over the same range: within 3 %
    # (32 strata of a speed varying by about +-15 %: a standard error about 1 %)
    fine = np.linspace(*scan.path_range, 8 * scan.size)
    arc_fine = D._subspace_path(scan.path_at(fine), sa)[4]
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(D, "PATH_ARC_Z", 0.0)
        bare = D._arc_path(scan, sa, 10 ** 6)[4]
    assert bare == pytest.approx(arc_fine, rel=0.03)
    for level in (0.05, 0.0025, 2.8e-4):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(D, "PATH_ARC_ROWS", 10 ** 12)
            n_exact = D._path_tries([scan], sa, level)
            mp.setattr(D, "PATH_ARC_ROWS", 0)
            n_arc = D._path_tries([scan], sa, level)
        assert n_exact <= n_arc <= 1.12 * n_exact


def test_long_log_path_builds_a_sample_not_every_trial(monkeypatch):
    """Beyond PATH_ARC_ROWS rows the path is built at 2 PATH_ARC_SAMPLES frequencies, not the scan's trials;
    at or below it every trial is built (the rule: without it a long log's count projects every trial)."""
    scan, (sa, _), d, f = _design()
    built, at = [], []
    sc = causes.Scan(scan.labels, scan.infos, "x", lambda idx: (built.append(len(idx)), scan.build(idx))[1],
                     path=True, path_at=lambda fq: (at.append(len(fq)), scan.path_at(fq))[1],
                     path_range=scan.path_range)
    D._PATH_CACHE.clear()
    monkeypatch.setattr(D, "PATH_ARC_ROWS", len(sa.rows) - 1)
    D._path_tries([sc], sa, 0.01)
    assert built == [1] and sum(at) == 2 * D.PATH_ARC_SAMPLES  # (one trial tells the scan's columns)
    monkeypatch.setattr(D, "PATH_ARC_ROWS", len(sa.rows))
    D._path_tries([sc], sa, 0.01)
    assert sum(built) >= scan.size
