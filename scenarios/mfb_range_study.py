"""Beyond the node box: the MFB compensation's two extrapolation rules compared (session 29, review29b F1).

Each run identifies ``NAME`` at ``seed`` (``--mc 0``: the tables do not depend on the Monte Carlo),
writes the compensation and closes the loop on the exact simulator (:func:`scenarios.mfb.closed_loop`),
whose ``strokes`` block measures the exact errors beyond the node box out to the strokes. ``tangent``
is vmt's rule (the tables along their end tangents, the ``.comp`` files with a line at each stroke
end); ``held`` is LinuxCNC's own rule made the rule of both controllers (the files stop at the end
nodes, LinuxCNC holds their end trims; the volumetric controller's tables clamped at their end nodes
in this process)::

    python -m scenarios.mfb_range_study mfb-5axis 1 4 OUTDIR

prints one line per rule, seed and controller (um): the true positioning error at the stroke points
outside the nodes, and the tip deviation over the stroke box and over the node box (a rigid motion
removed). Seeds ``lo`` to ``hi - 1``. About 10 s per run.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path


def one(name: str, seed: int, rule: str, directory) -> dict:
    """The closed loop's ``before``, ``per_axis_files`` and ``volumetric`` blocks with the rule
    ``"tangent"`` (vmt's) or ``"held"`` (the ends held by both controllers)."""
    import numpy as np

    import sim.compensation as sc
    from scenarios.mfb import closed_loop, run

    if rule not in ("tangent", "held"):
        raise ValueError(f"rule must be tangent or held, got {rule!r}")
    orig = sc._table_function
    try:
        if rule == "held":
            def held(x, v):
                f, x = orig(x, v), np.asarray(x, float)
                return lambda u: f(np.clip(np.asarray(u, float), x[0], x[-1]))
            sc._table_function = held
        r = run(name, seed=seed, mc_runs=0)
        (replace(r, strokes_m=None) if rule == "held" else r).write_comp(directory)
        return closed_loop(name, directory, before=r, seed=seed, mc_runs=0)
    finally:
        sc._table_function = orig


def main(argv=None) -> int:
    a = sys.argv[1:] if argv is None else argv
    if len(a) != 4:
        print("usage: python -m scenarios.mfb_range_study NAME SEED_LO SEED_HI OUTDIR", file=sys.stderr)
        return 2
    name, lo, hi, out = a[0], int(a[1]), int(a[2]), Path(a[3])
    from viz.progress import TerminalProgress

    bar = TerminalProgress("mfb_range_study: closed loops")     # on a terminal only (stderr): the time left
    total, done = 2 * max(hi - lo, 0), 0
    bar(0, total)
    for rule in ("tangent", "held"):
        for seed in range(lo, hi):
            loop = one(name, seed, rule, out / f"{rule}-{seed}")
            done += 1
            bar.clear()
            for k in ("before", "per_axis_files", "volumetric"):
                st = loop[k]["strokes"]
                f = lambda d: " / ".join(f"{d[x]:.3f}" for x in "XYZ")  # noqa: E731
                print(f"{rule:7s} {name} seed {seed} {k:14s} positioning outside the nodes "
                      f"{f(st['positioning_outside_max_um'])}; stroke box {f(st['volumetric_residual_um'])}; "
                      f"node box {f(loop[k]['volumetric_residual_um'])}", flush=True)
            bar(done, total)
    bar.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
