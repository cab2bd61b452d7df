"""How much of each identified error to apply: four rules against the exact simulator, over seeds.

The study behind docs/papers-mfb.md, "How much of each error a compensation applies" (the table
of residuals per rule; sessions 26-27 ran it as an unkept script, ``/tmp/rerun27/comp_eval.py``).
Per seed, ``mfb-3axis`` is identified (``--mc 0``: the factors use the linear covariance either
way) on one of three machines and four rules choose the fraction of each error function applied:

- ``every``: every identified value (the rule before session 26);
- ``cut95``: a term whose RMS exceeds its RMS U95, whole; others left out;
- ``cut71``: the same above 0.71 x its RMS U95 (the break-even of applying a term whose error
  equals its standard uncertainty);
- ``rule``: :func:`core.comprule.select_terms`, the shipped rule (the positive-part James-Stein
  factor, ``core.comprule.SHRINKAGE``).

The residual each leaves is the exact simulator's tip deviation before (stylus
:data:`scenarios.mfb.COMP_STYLUS`, over the plan's node box, a rigid motion removed:
:func:`scenarios.mfb._volumetric_deviation`) minus the chain's first-order map of the applied
tables (:func:`core.comprule.tip_map` at the node box's axis positions, the readings the nodes less
T0's J, as :func:`scenarios.mfb._prediction` takes them). For the shipped rule this is what the
closed loop (:func:`scenarios.mfb.closed_loop`, the controller in front of the exact machine)
measures, to first order (the test checks seed 1 against it). Machines: ``none`` (the 3-axis
plan's machine without errors), ``five`` (the review's five injected errors, :data:`FIVE_ERRORS`)
and ``study`` (the realistic ``study`` set, all 21 errors)::

    python -m scenarios.comprule_study --machines none five study --seeds 1 9 --json comp.json

Seeds ``lo`` to ``hi - 1``. Prints per machine and rule the worst axis over the node box, mean
over the seeds (largest), um; ``--json`` writes every seed's figures (JSON). About 4 s of CPU
per seed and machine.
"""

from __future__ import annotations

import json
import sys

import numpy as np

#: The review of session 26's machine: five errors injected on the 3-axis plan's machine.
FIVE_ERRORS = """format = "vmt-machine/1"
base = "vmc-3axis"
[error.EC0Y]
constant_urad = 20.0
[error.EB0Z]
constant_urad = -15.0
[error.EXX]
slope_um_per_m = 20.0
[error.EAY]
slope_urad_per_m = 10.0
[error.EYX]
quadratic_um_per_m2 = 30.0
"""
MACHINES = ("none", "five", "study")
RULES = ("every", "cut95", "cut71", "rule")
#: The break-even cut: a term is applied whole when its RMS exceeds this fraction of its RMS U95.
BREAK_EVEN = 0.7071
FORMAT = "vmt-comprule-study/1"


def machine_spec(which: str):
    """The truth machine ``which`` (:data:`MACHINES`) for ``mfb-3axis``."""
    import pathlib
    import tempfile

    from scenarios import mfb
    from sim.machinefile import truth_machine

    own = mfb.PLANS["mfb-3axis"]().machine
    if which == "none":
        return truth_machine(own, "none", "study")
    if which == "study":
        return truth_machine(own, "study", "study")
    if which == "five":
        with tempfile.TemporaryDirectory(prefix="vmt-comprule-") as d:
            p = pathlib.Path(d) / "five-errors.toml"
            p.write_text(FIVE_ERRORS)
            return truth_machine(str(p), None, "study")
    raise ValueError(f"comprule_study: unknown machine {which!r} (one of {', '.join(MACHINES)})")


def factors(decisions: dict, rule: str) -> dict:
    """Symbol -> fraction applied under ``rule`` (:data:`RULES`) from :func:`core.comprule.select_terms`'s
    decisions. A term with no uncertainty (``ratio`` None, the gauge's fixed values) is applied whole by
    every rule."""
    out = {}
    for s, d in decisions.items():
        r = d["ratio"]
        if rule == "rule":
            out[s] = float(d["factor"])
        elif r is None or rule == "every":
            out[s] = 1.0
        elif rule == "cut95":
            out[s] = float(r > 1.0)
        elif rule == "cut71":
            out[s] = float(r > BREAK_EVEN)
        else:
            raise ValueError(f"comprule_study: unknown rule {rule!r} (one of {', '.join(RULES)})")
    return out


def one_seed(which: str, seed: int, spec=None) -> dict:
    """Seed ``seed`` on machine ``which``: the worst |deviation| per axis X/Y/Z over the node box before and
    after each rule (um), and the shipped rule's factors."""
    from dataclasses import replace

    from core.comprule import select_terms, tip_map
    from core.state import loads_estimate
    from scenarios import mfb
    from sim.machine import Machine

    spec = machine_spec(which) if spec is None else spec
    r = mfb.run("mfb-3axis", seed=seed, mc_runs=0, machine=spec)
    J = np.asarray(mfb.STYLI[mfb.COMP_STYLUS], float)
    Rb = mfb._volumetric_deviation(Machine(replace(spec.config, J_m=tuple(J))), r.plan.nodes)
    st = loads_estimate(r.doc["estimate"])
    G = tip_map(st, r.result.chain, mfb._node_box(r.plan.nodes) - J, J, r.result.rotary_points_R_m)
    dec = select_terms(st)
    idx = {s: i for s, (_, i) in st.tables.items()} | dict(st.constants)
    out = {"machine": which, "seed": seed, "before_um": (np.abs(Rb).max(0) * 1e6).tolist()}
    for rule in RULES:
        lam = np.zeros(len(st.mean))
        for s, f in factors(dec, rule).items():
            lam[idx[s]] = f
        after = Rb - (G @ (lam * st.mean)).reshape(-1, 3)
        out[rule + "_um"] = (np.abs(after).max(0) * 1e6).tolist()
    out["rule_factor"] = {s: float(d["factor"]) for s, d in dec.items()}
    return out


def summarize(records: list) -> dict:
    """Per machine and rule (and ``before``): worst axis, mean over the seeds and largest, um."""
    out = {}
    for m in dict.fromkeys(x["machine"] for x in records):
        rows = [x for x in records if x["machine"] == m]
        out[m] = {k: {"mean_um": float(np.mean([max(x[k + "_um"]) for x in rows])),
                      "max_um": float(np.max([max(x[k + "_um"]) for x in rows])), "seeds": len(rows)}
                  for k in ("before",) + RULES}
    return out


def main(argv=None) -> int:
    from scenarios.cli.guard import OneLineParser   # bad input: one line naming it, exit 2 (vmt's parser)

    ap = OneLineParser(prog="python -m scenarios.comprule_study", description=__doc__.split("\n")[0])
    ap.add_argument("--machines", nargs="+", default=list(MACHINES), choices=MACHINES)
    ap.add_argument("--seeds", nargs=2, type=int, default=(1, 9), metavar=("LO", "HI"))
    from scenarios.cli.options import option

    # --out until session 38: vmt's --out is a log, plan or program, its JSON outputs --json (one name per thing)
    option(ap, "--json", dest="out", old=("--out",), help="JSON of every seed's figures and the summary")
    a = ap.parse_args(argv)
    if a.seeds[1] <= a.seeds[0]:
        print(f"error: --seeds {a.seeds[0]} {a.seeds[1]}: no seed (HI must exceed LO)", file=sys.stderr)
        return 2
    from viz.progress import TerminalProgress

    recs = []
    bar = TerminalProgress("comprule_study: seeds")     # on a terminal only (stderr): the time left
    total = len(a.machines) * (a.seeds[1] - a.seeds[0])
    bar(0, total)
    for m in a.machines:
        spec = machine_spec(m)
        for s in range(*a.seeds):
            x = one_seed(m, s, spec)
            recs.append(x)
            bar.clear()
            print(m, s, "before " + "/".join(f"{v:.2f}" for v in x["before_um"]), " | ".join(
                f"{k}: " + "/".join(f"{v:.2f}" for v in x[k + "_um"]) for k in RULES), flush=True)
            bar(len(recs), total)
    bar.close()
    summ = summarize(recs)
    print("worst axis, mean over the seeds (largest), um:")
    for m, d in summ.items():
        print(f"  {m}: " + " | ".join(f"{k} {v['mean_um']:.2f} ({v['max_um']:.2f})" for k, v in d.items()))
    if a.out:
        with open(a.out, "w") as f:
            json.dump({"format": FORMAT, "plan": "mfb-3axis", "mc_runs": 0, "seeds": list(range(*a.seeds)),
                       "records": recs, "summary": summ}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
