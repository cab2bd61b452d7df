"""Coverage of an MFB identification's U95 against the exact simulator, at a fixed truth.

One study file (``vmt regress``'s, an ``mfb-3axis`` or ``mfb-5axis`` identification) fixes the
machine and its injected errors; each seed is one run of :func:`scenarios.mfb.run` with the study's
probing noise and, as every noisy run, a fresh draw of the bar's calibration error and of the
placements. Every value identified is compared with the injected truth (same conventions) against
the run's own linear U95 (probing noise, bar calibration, placement), and the figures say whether
that U95 is right (about 95 % of the values inside, each node's mean squared z near 1) and how
often a whole run has every value inside k x U95 (what a regression study checks at once), beside
what the linear model's joint normal distribution predicts for the same count, and how many runs
pass ``within_u95 = "simultaneous"`` (every value within the run's k_sim x U95, the very check ``vmt
regress`` makes; about 95 % when the covariance is right) with its exact binomial interval::

    python -m scenarios.mfb_coverage scenarios/data/regress-mfb-5axis-mikron.toml --seeds 1 121 --workers 2

Seeds ``lo`` to ``hi - 1``; ``--out`` keeps the per-run arrays (npz). Minutes per hundred runs on
two free cores (a 5-axis run is about 2.5 s of CPU).
"""

from __future__ import annotations

import sys

import numpy as np

K_LEVELS = (1.0, 1.25, 1.5, 1.75, 2.0)


def one_run(study, seed: int) -> tuple:
    """(dev, U95, names, k_sim, passed): identified - injected and the run's U95 of every value (um,
    urad), in the report's order, values the conventions fix included (U95 0); the run's simultaneous
    band over all 21 errors (:func:`scenarios.regress.simultaneous_k`) and whether every value lies
    within it, exactly as ``within_u95 = "simultaneous"`` checks it (:func:`scenarios.regress.check`)."""
    from dataclasses import replace

    from scenarios.regress import RUNNERS, Rule, check, simultaneous_k

    est = RUNNERS[study.identification](replace(study, plan=(("mc_runs", 0),)), seed)
    dev = np.concatenate([e.identified - e.injected for e in est.values()])
    U = np.concatenate([e.u95 for e in est.values()])
    names = np.concatenate([[s] * len(e.identified) for s, e in est.items()])
    k_sim, n = simultaneous_k(list(est.values()))
    passed = all(check(Rule(s, None, None, e.unit, simultaneous=True), e, seed, k_sim, n).passed
                 for s, e in est.items())
    return dev, U, names, k_sim, passed


def _task(args):
    from scenarios.regress import load_study

    path, seed = args
    return one_run(load_study(path), seed)


def _model_cov(study, seed: int) -> tuple:
    """(C, names): the linear propagation's joint covariance of run ``seed``'s free values (m^2, rad^2;
    the values the conventions fix, variance 0, left out) and the error each belongs to, report order."""
    from core import mfb as cmfb, volumetric as vol
    from scenarios import mfb

    r = mfb.run(study.identification, seed=seed, noise_um=study.noise_um, mc_runs=0, machine=study.machine)
    u_cal = np.tile(np.asarray(mfb.U_CAL_UM) * 1e-6, (12, 1))  # run's default declared calibration
    cov = vol.covariance(r.result, r.meas, study.noise_um * 1e-6, u_cal, np.asarray(mfb.U_PLACE, float),
                         cal_map=cmfb.calibration_map())
    d = r.result.design
    idx = [(i, q) for q in vol.MOTION + vol.SQUARENESS for i in range(d.slices[q].start, d.slices[q].stop)
           if cov[i, i] > 1e-24]
    return cov[np.ix_([i for i, _ in idx], [i for i, _ in idx])], np.array([q for _, q in idx])


def model_all_within(study, seed: int = 1, draws: int = 200_000, cov=None) -> dict:
    """What the linear model predicts: the share of runs with every value within k x U95 (k of
    :data:`K_LEVELS`), from joint normal draws with the covariance of run ``seed`` (``cov``: that
    covariance, :func:`_model_cov`'s first item, when already at hand)."""
    C = _model_cov(study, seed)[0] if cov is None else cov
    u = np.sqrt(np.diag(C))
    w, V = np.linalg.eigh(0.5 * (C + C.T))
    x = np.random.default_rng(0).standard_normal((int(draws), len(u))) @ (V * np.sqrt(np.clip(w, 0, None))).T
    mx = (np.abs(x) / (2.0 * u)).max(axis=1)
    return {f"{k:g}": float(np.mean(mx <= k)) for k in K_LEVELS} | {"values": len(u)}


def share_ranges(cov, names, runs: int, sets: int = 2000, rng=None, lowest: int = 3) -> dict:
    """What the linear model expects of each error's share of values within U95 over ``runs`` runs, and of
    the lowest shares among the errors: the chance against which a study's worst errors are judged.

    ``cov`` (m, m) the joint covariance of the free values (one run's: the U95 barely moves between
    seeds), ``names`` (m,) the error of each value. Each of ``sets`` simulated studies draws ``runs``
    joint normal vectors (nodes and errors correlated as ``cov`` says: the bar's calibration moves a
    straightness everywhere at once) and counts |value| <= 2 sqrt(cov_ii) (the U95, k = 2) per error.
    The share of one error over ``runs`` runs spreads more than a binomial over its values (its nodes
    miss together), and the lowest of 21 such shares lies below 0.95 in most studies even when every U95
    is right. Returns ``{"errors": {name: [mean, lo, hi]}, "lowest": [[median, lo, hi], ...]}`` (lo, hi:
    the 2.5 and 97.5 % points over the sets; ``lowest[j]`` the (j + 1)-th lowest share of a study).
    """
    from core.exceptions import ConfigError

    C = np.asarray(cov, float)
    names = np.atleast_1d(np.asarray(names))
    m = len(names)
    if C.shape != (m, m) or m == 0 or not np.all(np.isfinite(C)) or np.any(np.diag(C) <= 0):
        raise ConfigError(f"share_ranges: cov must be a finite ({m}, {m}) covariance with a positive diagonal, "
                          f"got {C.shape}")
    if int(runs) < 1 or int(sets) < 2 or int(lowest) < 1:
        raise ConfigError(f"share_ranges: runs >= 1, sets >= 2, lowest >= 1, got {runs}, {sets}, {lowest}")
    rng = np.random.default_rng(0) if rng is None else rng
    groups, g = np.unique(names, return_inverse=True)
    count = np.bincount(g) * int(runs)
    U = 2.0 * np.sqrt(np.diag(C))
    w, V = np.linalg.eigh(0.5 * (C + C.T))
    A = V * np.sqrt(np.clip(w, 0.0, None))
    sh = np.empty((int(sets), len(groups)))
    step = max(1, 2_000_000 // (int(runs) * m))  # studies per block of draws (about 16 MB)
    onehot = np.eye(len(groups))[g]  # (m, errors)
    for j in range(0, int(sets), step):
        b = min(step, int(sets) - j)
        x = rng.standard_normal((b, int(runs), m)) @ A.T
        sh[j:j + b] = ((np.abs(x) <= U).sum(axis=1) @ onehot) / count
    low = np.sort(sh, axis=1)[:, :min(int(lowest), len(groups))]
    q = (2.5, 97.5)
    return {"runs": int(runs), "sets": int(sets),
            "errors": {str(k): [float(sh[:, i].mean()), *map(float, np.percentile(sh[:, i], q))]
                       for i, k in enumerate(groups)},
            "lowest": [[float(np.median(c)), *map(float, np.percentile(c, q))] for c in low.T]}


def summarize(dev: np.ndarray, U: np.ndarray, names: np.ndarray, rng=None) -> dict:
    """Coverage figures of runs (rows) x values (columns): the share within U95 with a 95 %
    interval by resampling whole runs (a run's values are correlated: a binomial interval over
    values would be too narrow), per error the share, the runs with every node inside and the
    range over its nodes of the mean squared z = dev / (U95 / 2) (1 when U95 is right; over n runs
    its 95 % band is chi2(n) / n), and the runs with every value within k x U95."""
    from scipy import stats

    rng = np.random.default_rng(0) if rng is None else rng
    dev, U, names = np.asarray(dev, float), np.asarray(U, float), np.asarray(names)
    k = np.all(U > 1e-9, axis=0)  # the values the conventions fix (U95 0) are left out
    r = np.abs(dev[:, k]) / U[:, k]
    n = len(r)

    def share(cols):
        ins = (r[:, cols] <= 1.0).mean(axis=1)
        boot = ins[rng.integers(0, n, (2000, n))].mean(axis=1)
        return float(ins.mean()), [float(v) for v in np.quantile(boot, (0.025, 0.975))]

    out = {"runs": n, "values": int(k.sum()), "within": share(np.ones(k.sum(), bool)),
           "chi2_band": [float(stats.chi2.ppf(q, n) / n) for q in (0.025, 0.975)], "errors": {}}
    nk = names[k]
    for s in dict.fromkeys(nk):
        c = nk == s
        z2 = (2.0 * r[:, c]) ** 2
        out["errors"][s] = {"nodes": int(c.sum()), "within": share(c),
                            "runs_all_within": int(np.all(r[:, c] <= 1.0, axis=1).sum()),
                            "mean_z2": [float(z2.mean(axis=0).min()), float(z2.mean(axis=0).max())],
                            "max_ratio": float(r[:, c].max())}
    mx = r.max(axis=1)
    out["runs_all_within"] = {f"{q:g}": int(np.sum(mx <= q)) for q in K_LEVELS}
    return out


def simultaneous_summary(k_sim, passed) -> dict:
    """The runs a ``within_u95 = "simultaneous"`` study passes, with the exact (Clopper-Pearson) 95 %
    interval of that rate, and the range of the runs' k_sim."""
    from scipy import stats

    passed = np.asarray(passed, bool)
    n, x = len(passed), int(passed.sum())
    lo = float(stats.beta.ppf(0.025, x, n - x + 1)) if x > 0 else 0.0
    hi = float(stats.beta.ppf(0.975, x + 1, n - x)) if x < n else 1.0
    return {"runs": n, "passed": x, "rate": x / n, "interval": [lo, hi],
            "k_sim": [float(np.min(k_sim)), float(np.median(k_sim)), float(np.max(k_sim))]}


def describe(s: dict, model: dict | None = None) -> str:
    w, (lo, hi) = s["within"]
    lines = [f"{s['runs']} runs x {s['values']} values: {w:.3f} within U95 (95 % interval over runs {lo:.3f}-{hi:.3f})",
             f"error  nodes  within [interval]      runs all nodes in  mean z^2 over nodes (band "
             f"{s['chi2_band'][0]:.2f}-{s['chi2_band'][1]:.2f})  max |dev|/U95"]
    for q, e in s["errors"].items():
        (v, (a, b)) = e["within"]
        lines.append(f"{q:5s} {e['nodes']:4d}   {v:.3f} [{a:.3f}-{b:.3f}]  {e['runs_all_within']:4d}/{s['runs']}"
                     f"           {e['mean_z2'][0]:.2f}-{e['mean_z2'][1]:.2f}"
                     f"                          {e['max_ratio']:.2f}")
    for q, c in s["runs_all_within"].items():
        m = f"; model {model[q]:.3f}" if model else ""
        lines.append(f"every value within {q} x U95: {c}/{s['runs']} runs{m}")
    return "\n".join(lines)


def describe_lowest(s: dict, model: dict) -> str:
    """The study's lowest error shares (:func:`summarize`) beside the range the linear model gives the
    same ranks over as many runs (:func:`share_ranges`)."""
    low = sorted((e["within"][0], q) for q, e in s["errors"].items())
    return "\n".join(f"{j + 1}. lowest error share: {low[j][1]} {low[j][0]:.3f}; the model over {model['runs']} runs: "
                     f"median {m:.3f}, 95 % {lo:.3f}-{hi:.3f}" for j, (m, lo, hi) in enumerate(model["lowest"])
                     if j < len(low))


def main(argv=None) -> int:
    from concurrent.futures import ProcessPoolExecutor

    from scenarios.regress import load_study

    from scenarios.cli.guard import OneLineParser   # bad input: one line naming it, exit 2 (vmt's parser)

    ap = OneLineParser(prog="python -m scenarios.mfb_coverage", description=__doc__.split("\n")[0])
    ap.add_argument("study")
    ap.add_argument("--seeds", nargs=2, type=int, default=(1, 61), metavar=("LO", "HI"))
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", help="npz of the per-run arrays")
    a = ap.parse_args(argv)
    study = load_study(a.study)
    if not study.identification.startswith("mfb"):
        print(f"error: {a.study}: an mfb-3axis or mfb-5axis study is needed, got {study.identification}",
              file=sys.stderr)
        return 2
    from viz.progress import TerminalProgress

    tasks = [(a.study, s) for s in range(*a.seeds)]
    runs = []
    # on a terminal only (stderr): the time left; the last step is the model's covariance (one more run)
    with TerminalProgress("mfb_coverage: runs (each seed's, then the covariance's)") as bar:
        bar(0, len(tasks) + 1)
        if a.workers > 1:
            with ProcessPoolExecutor(a.workers) as ex:
                for r in ex.map(_task, tasks):
                    runs.append(r)
                    bar(len(runs), len(tasks) + 1)
        else:
            for t in tasks:
                runs.append(_task(t))
                bar(len(runs), len(tasks) + 1)
        dev, U = np.array([x[0] for x in runs]), np.array([x[1] for x in runs])
        names = runs[0][2]
        k_sim, passed = np.array([x[3] for x in runs]), np.array([x[4] for x in runs])
        if a.out:
            np.savez(a.out, dev=dev, U=U, names=names, seeds=np.arange(*a.seeds), k_sim=k_sim, passed=passed)
        C, cnames = _model_cov(study, 1)
        bar(len(tasks) + 1, len(tasks) + 1)
    s = summarize(dev, U, names)
    print(describe(s, model_all_within(study, cov=C)))
    print(describe_lowest(s, share_ranges(C, cnames, len(runs))))
    sm = simultaneous_summary(k_sim, passed)
    print(f"within_u95 = \"simultaneous\" (k_sim x U95, {sm['k_sim'][0]:.3f}-{sm['k_sim'][2]:.3f} over the runs, "
          f"median {sm['k_sim'][1]:.3f}): {sm['passed']}/{sm['runs']} runs pass = {sm['rate']:.3f} "
          f"(95 % interval {sm['interval'][0]:.3f}-{sm['interval'][1]:.3f}; the aim 0.95)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
