"""Large Monte Carlo studies and design sweeps on a Dask cluster or local processes.

Results depend only on the seed, never on the executor or the number of
workers: the runs are cut into fixed blocks of ``block`` runs, block ``b``
draws from ``np.random.SeedSequence(seed).spawn(n_blocks)[b]``, each block
returns sums, sums of squares and histogram counts, and the parent reduces
them in block order. Serial, local processes (``workers=N``) and Dask
(``dask="tcp://HOST:PORT"``) give bit-identical results.

The design is factored once, in the parent, into the dense gain ``K``
(:func:`gain_matrix`); workers only draw noise and multiply.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Histogram bins per parameter for the coverage interval (range +-8 u_linear).
BINS = 1600
HIST_HALF_WIDTH = 8.0

def gain_matrix(w, wn, c_deg, grid) -> np.ndarray:
    """(n_params, n_touches) dense gain K of the factored estimator: error = K noise.

    Computed once by the parent and shipped to the workers, so every worker
    applies the very same numbers (a factorisation redone in a worker with
    another BLAS thread count can differ in the last bits).
    """
    from core.selfcal import estimator, nominal_touches

    t = nominal_touches(w, wn, c_deg)
    _des, est = estimator(t, grid)
    return np.ascontiguousarray(est.noise_gain(np.eye(t.n)))


def _mc_block(task):
    """One block of runs: (sum, sum of squares, histogram counts) of the estimation errors."""
    K, u, n_runs, seedseq, half = task
    e = np.random.default_rng(seedseq).standard_normal((K.shape[1], n_runs)) * u
    # numpy's own loop, not BLAS: a BLAS gemm's rounding depends on its thread count,
    # which differs between the parent, local processes and Dask workers
    err = np.einsum("ij,jk->ki", K, e, optimize=False)
    s1 = err.sum(axis=0)
    s2 = (err ** 2).sum(axis=0)
    # fixed bins per parameter: [-half, half] in BINS cells, outside -> end cells
    scale = np.where(half > 0, half, 1.0)
    k = np.clip(((err / scale + 1.0) * 0.5 * BINS).astype(np.int64), 0, BINS - 1)
    counts = np.zeros((err.shape[1], BINS), np.int64)
    np.add.at(counts, (np.broadcast_to(np.arange(err.shape[1]), k.shape), k), 1)
    return s1, s2, counts


def _design_eval(task):
    w, wn, c_deg, gx, gy, u, measure = task
    from core.design import max_workpiece_U95
    from core.selfcal import Grid

    return max_workpiece_U95(w, wn, c_deg, Grid(gx, gy), u, measure)


def pmap(func, tasks, *, dask: str | None = None, workers: int | None = None) -> list:
    """``[func(t) for t in tasks]`` in order, on Dask, local processes or serially."""
    tasks = list(tasks)
    if dask:
        from distributed import Client

        with Client(dask, timeout="20s") as client:
            futs = client.map(func, tasks, pure=False)
            return client.gather(futs)
    if workers and workers > 1 and len(tasks) > 1:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        ex = ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"))
        try:
            out = list(ex.map(func, tasks))
        except BaseException:
            # interrupted (Ctrl-C, or SIGTERM sent to this process alone: scenarios.cli.guard): the workers stop
            # now, the tasks not begun are dropped, rather than the exit waiting for every task (session 32)
            # (the workers listed before the shutdown, which forgets them; each ended and waited for, so none is
            # left running after the command's last line. A worker whose start the signal interrupted is not listed:
            # it ends by itself, reading a closed pipe)
            procs = list((getattr(ex, "_processes", None) or {}).values())
            ex.shutdown(wait=False, cancel_futures=True)
            for proc in procs:
                proc.terminate()
            for proc in procs:
                proc.join(timeout=10)
            raise
        ex.shutdown(wait=True)
        return out
    return [func(t) for t in tasks]


@dataclass(frozen=True)
class MCStudy:
    """Monte Carlo study of a nominal self-calibration design.

    Attributes
    ----------
    names : tuple of str
    runs : int
    mean : (n,) float
        Mean estimation error (should be ~0), m / rad.
    u : (n,) float
        Standard uncertainty, m / rad.
    lo, hi : (n,) float
        95 % coverage interval of the error (from the histogram, resolution
        ``2 * 8 u_lin / BINS``).
    u_linear : (n,) float
        Linear propagation, for comparison.
    seed : int
    block : int
    """

    names: tuple
    runs: int
    mean: np.ndarray
    u: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    u_linear: np.ndarray
    seed: int
    block: int


def _quantile(counts, half, q):
    cdf = np.cumsum(counts, axis=1) / counts.sum(axis=1, keepdims=True)
    i = np.array([np.searchsorted(c, q) for c in cdf])
    prev = np.where(i > 0, cdf[np.arange(len(i)), np.maximum(i - 1, 0)], 0.0)
    cur = cdf[np.arange(len(i)), i]
    frac = np.where(cur > prev, (q - prev) / np.where(cur > prev, cur - prev, 1), 0.5)
    x = (i + frac) / BINS * 2.0 - 1.0
    return x * half


def mc_study(w_W, wn_W, c_deg, grid, u_probe_m: float, runs: int, seed: int, *, block: int = 1000,
             dask: str | None = None, workers: int | None = None, blocks_per_task: int = 8) -> MCStudy:
    """Monte Carlo of ``runs`` runs (10^5-10^6 fine), identical for a seed on any executor.

    Parameters
    ----------
    w_W, wn_W : (N_w, 2) float
        Targets (m) and outward normals, W.
    c_deg : sequence of float
    grid : core.selfcal.Grid
    u_probe_m : float
        Probing standard uncertainty, m.
    runs, seed, block : int
        ``block`` fixes the random streams (part of the seed's meaning).
    dask : str, optional
        Scheduler address ``tcp://HOST:PORT``.
    workers : int, optional
        Local processes when no ``dask``.
    """
    from core.exceptions import ConfigError
    from core.uncertainty import check_mc_runs, linear_uncertainty

    runs, block = check_mc_runs(runs), int(block)
    if block < 1:
        raise ConfigError(f"block must be >= 1, got {block}")
    w = np.ascontiguousarray(w_W, float)
    wn = np.ascontiguousarray(wn_W, float)
    c = tuple(float(v) for v in c_deg)
    lin = linear_uncertainty(w, wn, c, grid, u_probe_m)
    half = HIST_HALF_WIDTH * lin.u
    nb = -(-runs // block)
    seqs = np.random.SeedSequence(seed).spawn(nb)
    sizes = [min(block, runs - b * block) for b in range(nb)]
    K = gain_matrix(w, wn, c, grid)
    tasks = [(K, float(u_probe_m), sizes[b], seqs[b], half) for b in range(nb)]
    # group blocks into tasks only to cut overhead; grouping does not change any stream
    groups = [tasks[i:i + blocks_per_task] for i in range(0, nb, blocks_per_task)]
    parts = pmap(_mc_group, groups, dask=dask, workers=workers)
    n = lin.u.size
    s1, s2, counts = np.zeros(n), np.zeros(n), np.zeros((n, BINS), np.int64)
    for grp in parts:  # fixed order: block 0, 1, 2, ...
        for a, b, h in grp:
            s1 += a
            s2 += b
            counts += h
    mean = s1 / runs
    u = np.sqrt(np.maximum((s2 - runs * mean ** 2) / (runs - 1), 0))
    lo = _quantile(counts, half, 0.025)
    hi = _quantile(counts, half, 0.975)
    return MCStudy(names=lin.design.names, runs=runs, mean=mean, u=u, lo=lo, hi=hi, u_linear=lin.u,
                   seed=int(seed), block=block)


def _mc_group(group):
    return [_mc_block(t) for t in group]


def design_sweep(w_W, wn_W, angle_sets, grid, u_probe_m: float, measure: str = "gauge", *,
                 dask: str | None = None, workers: int | None = None) -> list:
    """Max workpiece U95 (m) of every angle set, in order, on any executor."""
    w = np.ascontiguousarray(w_W, float)
    wn = np.ascontiguousarray(wn_W, float)
    tasks = [(w, wn, tuple(float(v) for v in s), grid.x_m, grid.y_m, float(u_probe_m), measure)
             for s in angle_sets]
    return [float(v) for v in pmap(_design_eval, tasks, dask=dask, workers=workers)]


def design_evaluator(w_W, wn_W, grid, u_probe_m, measure="gauge", *, dask=None, workers=None):
    """An ``evaluate`` callable for :func:`core.design.optimise_angles` (None = serial default)."""
    if not dask and not (workers and workers > 1):
        return None

    def evaluate(sets):
        return design_sweep(w_W, wn_W, sets, grid, u_probe_m, measure, dask=dask, workers=workers)

    return evaluate
