"""A ripple the bar cannot see: the 3-axis MFB identification's U95 coverage with the screw ripple, declared or not.

The study behind docs/papers-mfb.md, "A ripple the bar cannot see: declared, its effect in the U95"
(session 25; its scripts, /tmp/mfbrip/cov.py, covph.py and score.py, were not kept). Per seed,
``mfb-3axis`` is identified (``--mc 0``, linear U95) on the plan's machine with the realistic error
set, the screw ripple of the "lin" tables included (EXX, EYY, EZZ, EBX, EBZ, ECY; 10 mm, 1 % of
each table's magnitude), and every node value is scored against the injected truth, ``|identified
- injected| <= U95``, the values the gauge fixes (U95 0) left out. Conditions:

- ``off``: no ripple (the ``study`` set): the run's own coverage;
- ``none``: the ripple at phase 0 (the nominal set), nothing declared;
- ``lin``: phase 0, EXX, EYY and EZZ declared (what ``--declared-ripple-um-mm`` gives);
- ``all``: phase 0, all six declared;
- ``drawn``: each ripple at a phase drawn per seed (``default_rng(seed + 1000000)``, uniform, one
  per table in the set's order), all six declared.

Declared amplitudes are the truth's own (the nominal set's). ::

    python -m scenarios.mfb_ripple_coverage none lin all drawn --seeds 1000 1200 --json rip.json

Prints per condition the share of all values and of EXX, EBX, EYY, EZZ within U95 with the exact
(Clopper-Pearson) 95 % interval; ``--json`` writes every seed's deviations and U95 (JSON). About
2-3 s of CPU per seed and condition.
"""

from __future__ import annotations

import json
import sys

import numpy as np

CONDITIONS = ("off", "none", "lin", "all", "drawn")
#: Tables the printed summary lists (the document's columns).
SHOWN = ("EXX", "EBX", "EYY", "EZZ")
FORMAT = "vmt-mfb-ripple-coverage/1"


def _ripples(errors: dict) -> dict:
    """Symbol -> (amplitude, period) of every periodic term of a realistic set, in the set's order."""
    from sim.errorfuncs import Periodic, Sum

    out = {}
    for s, f in errors.items():
        if isinstance(f, Sum):
            for t in f.terms:
                if isinstance(t, Periodic):
                    out[s] = (t.amplitude, t.period)
    return out


def machine_and_declared(condition: str, seed: int):
    """(machine spec, declared ripple or None) of one seed under ``condition`` (:data:`CONDITIONS`)."""
    from dataclasses import replace

    from sim.errorfuncs import Periodic, Sum
    from sim.machinefile import truth_machine

    if condition not in CONDITIONS:
        raise ValueError(f"mfb_ripple_coverage: unknown condition {condition!r} (one of {', '.join(CONDITIONS)})")
    if condition == "off":
        return truth_machine("vmc-3axis", "study"), None
    spec = truth_machine("vmc-3axis", "realistic")
    decl = _ripples(spec.config.errors)
    if condition == "none":
        return spec, None
    if condition == "lin":
        return spec, {k: v for k, v in decl.items() if k in ("EXX", "EYY", "EZZ")}
    if condition == "all":
        return spec, decl
    ph = iter(np.random.default_rng(seed + 1_000_000).uniform(0.0, 2.0 * np.pi, len(decl)))
    errs = {}
    for s, f in spec.config.errors.items():
        if s in decl:
            errs[s] = Sum(tuple(Periodic(t.amplitude, t.period, next(ph)) if isinstance(t, Periodic) else t
                                for t in f.terms))
        else:
            errs[s] = f
    return replace(spec, config=replace(spec.config, errors=errs)), decl


def one_seed(condition: str, seed: int) -> dict:
    """Every error's identified - injected and U95 at its nodes (um, urad), the run's ``u95_scope`` note."""
    from scenarios.mfb import run

    spec, decl = machine_and_declared(condition, seed)
    d = run("mfb-3axis", seed=seed, mc_runs=0, machine=spec, declared_ripple=decl).doc
    errs = {k: {"dev": (np.asarray(v["identified"], float) - np.asarray(v["injected"], float)).tolist(),
                "u95": [float(x) for x in v["u95"]]} for k, v in d["errors"].items()}
    return {"condition": condition, "seed": seed, "scope": d.get("u95_scope"), "errors": errs}


def score(records: list) -> dict:
    """Per error and over all: (within, values) over the free nodes (U95 > 1e-6), with Clopper-Pearson 95 %."""
    from scenarios.selfcal_coverage import clopper_pearson

    tot: dict = {}
    for r in records:
        for k, v in r["errors"].items():
            d, U = np.abs(np.asarray(v["dev"], float)), np.asarray(v["u95"], float)
            m = U > 1e-6
            a = tot.setdefault(k, [0, 0])
            a[0] += int(np.sum(d[m] <= U[m]))
            a[1] += int(m.sum())
    tot["all"] = [sum(a for a, _ in tot.values()), sum(b for _, b in tot.values())]
    return {k: {"within": a, "values": b, "share": a / b if b else float("nan"),
                "ci95": list(clopper_pearson(a, b)) if b else None} for k, (a, b) in tot.items()}


def main(argv=None) -> int:
    from scenarios.cli.guard import OneLineParser   # bad input: one line naming it, exit 2 (vmt's parser)

    ap = OneLineParser(prog="python -m scenarios.mfb_ripple_coverage", description=__doc__.split("\n")[0])
    ap.add_argument("conditions", nargs="+", choices=CONDITIONS)
    ap.add_argument("--seeds", nargs=2, type=int, default=(1000, 1200), metavar=("LO", "HI"))
    from scenarios.cli.options import option

    # --out until session 38: vmt's --out is a log, plan or program, its JSON outputs --json (one name per thing)
    option(ap, "--json", dest="out", old=("--out",), help="JSON of every seed's deviations and U95, and the scores")
    a = ap.parse_args(argv)
    if a.seeds[1] <= a.seeds[0]:
        print(f"error: --seeds {a.seeds[0]} {a.seeds[1]}: no seed (HI must exceed LO)", file=sys.stderr)
        return 2
    from viz.progress import TerminalProgress

    recs, scores = [], {}
    bar = TerminalProgress("mfb_ripple_coverage: seeds")     # on a terminal only (stderr): the time left
    seeds = range(*a.seeds)
    total = len(a.conditions) * len(seeds)
    bar(0, total)
    for c in a.conditions:
        rc = []
        for s in seeds:
            rc.append(one_seed(c, s))
            bar(len(recs) + len(rc), total)
        recs += rc
        sc = scores[c] = score(rc)
        bar.clear()
        print(f"{c}: all {sc['all']['within']}/{sc['all']['values']} = {sc['all']['share']:.3f}; " + ", ".join(
            f"{k} {sc[k]['within']}/{sc[k]['values']} = {sc[k]['share']:.3f} [{sc[k]['ci95'][0]:.3f}, "
            f"{sc[k]['ci95'][1]:.3f}]" for k in SHOWN) + f"; runs with a note {sum(1 for r in rc if r['scope'])}",
              flush=True)
        if a.out:
            with open(a.out, "w") as f:
                json.dump({"format": FORMAT, "seeds": list(range(*a.seeds)), "scores": scores, "records": recs}, f)
    bar.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
