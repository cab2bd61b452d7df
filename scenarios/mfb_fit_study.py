"""The MFB's lack-of-fit note against truths its tables can and cannot follow (session 29, review29b F2).

Truths as the review made them (/tmp/review29b/cov*/gen.py, reproduced here): the Mikron UCP 710
(``mfb-5axis``'s machine) with ``errors = "none"`` and, per error, a polynomial (slope, quadratic,
cubic) plus one sinusoid of period drawn in ``band`` mm, each from ``numpy.random.default_rng(base +
r)`` (base 999000 for the short band, 777000 for the long one, as the review's two sets); run ``r``
identifies its truth at seed ``4000 + r`` (``--mc 0``: the U95 is the linear propagation's). ``realistic`` runs the plan's own study machine at the same seeds. Per run: the
residual RMS, :func:`core.volumetric.lack_of_fit`'s figures, whether the note fires, and the U95's
coverage (nodes whose identified - injected lies within U95, the values the conventions fix left
out)::

    python -m scenarios.mfb_fit_study short 0 20 OUT.jsonl     # periods 100-140 mm
    python -m scenarios.mfb_fit_study long 0 40 OUT.jsonl      # periods 180-500 mm
    python -m scenarios.mfb_fit_study realistic 0 40 OUT.jsonl
    python -m scenarios.mfb_fit_study --tally OUT.jsonl ...

``--share`` turns the model-error share on (:data:`scenarios.mfb.MFB_MODEL_ERROR_SHARE`, on by default since
session 34: the flag then changes nothing; kept so the session 29-30 commands run as written); the tally
reports its entries and the U95's growth.

About 7 s per run.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

#: kind -> (period band mm, the review's generator seed base)
BANDS = {"short": ((100.0, 140.0), 999000), "long": ((180.0, 500.0), 777000)}


def truth_toml(r: int, band: tuple, base: int) -> str:
    """The review's truth ``r`` (its gen.py: the period band and the seed base its two sets used), vmt-machine/1 text."""
    rng = np.random.default_rng(base + r)
    lines = ['format = "vmt-machine/1"', f'name = "own-{r}"', 'base = "mikron-ucp710"', 'errors = "none"', '']

    def s(a):
        return float(rng.uniform(-a, a))

    for a in "XYZ":
        for b in "XYZ":
            sym = f"E{b}{a}"
            if a == b:
                c, amp = (s(30), s(40), s(60)), rng.uniform(0.4, 1.5)
            else:
                c, amp = (0.0, s(15), s(25)), rng.uniform(0.2, 0.8)
            lines += [f'[error.{sym}]', f'slope_um_per_m = {c[0]:.4f}', f'quadratic_um_per_m2 = {c[1]:.4f}',
                      f'cubic_um_per_m3 = {c[2]:.4f}',
                      f'periodic = [{{ amplitude_um = {amp:.4f}, period_mm = {rng.uniform(*band):.2f}, '
                      f'phase_deg = {rng.uniform(0, 360):.1f} }}]', '']
        for b in "ABC":
            sym = f"E{b}{a}"
            lines += [f'[error.{sym}]', f'slope_urad_per_m = {s(40):.4f}', f'quadratic_urad_per_m2 = {s(60):.4f}',
                      f'cubic_urad_per_m3 = {s(80):.4f}',
                      f'periodic = [{{ amplitude_urad = {rng.uniform(1, 4):.4f}, period_mm = '
                      f'{rng.uniform(*band):.2f}, phase_deg = {rng.uniform(0, 360):.1f} }}]', '']
    for sym in ("EC0Y", "EB0Z", "EA0Z"):
        lines += [f'[error.{sym}]', f'constant_urad = {s(25):.4f}', '']
    return "\n".join(lines)


def one(kind: str, r: int, directory) -> dict:
    """Run ``r`` of ``kind`` (``short``, ``long`` or ``realistic``): its figures."""
    from scenarios.mfb import run
    from sim.machinefile import truth_machine

    spec = None
    if kind != "realistic":
        p = Path(directory) / f"{kind}{r}.toml"
        p.write_text(truth_toml(r, *BANDS[kind]))
        spec = truth_machine(str(p), None, "study")
    d = run("mfb-5axis", seed=4000 + r, mc_runs=0, machine=spec).doc
    ins = tot = 0
    per = {}
    for s, e in d["errors"].items():
        idf, inj, u = (np.atleast_1d(np.asarray(e[k], float)) for k in ("identified", "injected", "u95"))
        m = u > 0
        k = int(np.sum(np.abs(idf - inj)[m] <= u[m]))
        per[s] = [k, int(m.sum())]
        ins, tot = ins + k, tot + int(m.sum())
    return {"kind": kind, "r": r, "seed": 4000 + r, "rms_residual_um": d["rms_residual_um"],
            "lack_of_fit": d.get("lack_of_fit"), "note": d.get("model_fit_note"), "within": [ins, tot],
            "model_error": d.get("model_error"),
            "per_error": per}


def tally(paths) -> str:
    rows = [json.loads(x) for p in paths for x in Path(p).read_text().splitlines() if x.strip()]
    out = []
    for kind in ("realistic", "long", "short"):
        rs = [x for x in rows if x["kind"] == kind]
        if not rs:
            continue
        ins, tot = sum(x["within"][0] for x in rs), sum(x["within"][1] for x in rs)
        fired = sum(bool(x["note"]) for x in rs)
        ratio = sorted(x["lack_of_fit"]["tested_ratio"] for x in rs)
        p = sorted(x["lack_of_fit"]["p"] for x in rs)
        out.append(f"{kind}: {len(rs)} runs, note fired on {fired}; within U95 {ins}/{tot} = {ins / tot:.3f}; "
                   f"tested ratio {ratio[0]:.2f}-{ratio[-1]:.2f} (median {ratio[len(ratio) // 2]:.2f}); "
                   f"p from {p[0]:.1e} (median {p[len(p) // 2]:.1e})")
        me = [x.get("model_error") for x in rs]
        if any(m is not None for m in me):  # the model-error share (session 29, F2b)
            ent = [m for m in me if m and m["entered"]]
            grow = sorted(m["u95_growth"]["median"] for m in ent if "u95_growth" in m)
            allg = sorted(grow + [0.0] * (len(rs) - len(grow)))
            tabs = sorted({s for m in ent for s in m["entered"]})
            out.append(f"  model-error share entered on {len(ent)}/{len(rs)} runs ({', '.join(tabs) or 'none'}); "
                       f"median U95 growth per run: median over runs {allg[len(allg) // 2]:.3f}"
                       + (f", over the runs it entered {grow[0]:.3f}-{grow[-1]:.3f}" if grow else ""))
        if fired and fired < len(rs):
            a = [x for x in rs if x["note"]]
            b = [x for x in rs if not x["note"]]
            for lab, g in (("fired", a), ("silent", b)):
                i, t = sum(x["within"][0] for x in g), sum(x["within"][1] for x in g)
                out.append(f"  {lab}: {len(g)} runs, within U95 {i}/{t} = {i / t:.3f}")
    return "\n".join(out)


def main(argv=None) -> int:
    a = list(sys.argv[1:] if argv is None else argv)
    if "--share" in a:  # the model-error share in the U95 (scenarios.mfb.MFB_MODEL_ERROR_SHARE, on since session 34)
        import scenarios.mfb

        a.remove("--share")
        scenarios.mfb.MFB_MODEL_ERROR_SHARE = True
    if a and a[0] == "--tally":
        print(tally(a[1:]))
        return 0
    if len(a) != 4 or a[0] not in ("short", "long", "realistic"):
        print("usage: python -m scenarios.mfb_fit_study [--share] short|long|realistic R_LO R_HI OUT.jsonl "
              "| --tally OUT.jsonl ...", file=sys.stderr)
        return 2
    kind, lo, hi, out = a[0], int(a[1]), int(a[2]), Path(a[3])
    out.parent.mkdir(parents=True, exist_ok=True)
    from viz.progress import TerminalProgress

    with TerminalProgress("mfb_fit_study: truths") as bar:     # on a terminal only (stderr): the time left
        bar(0, max(hi - lo, 0))
        for r in range(lo, hi):
            rec = one(kind, r, out.parent)
            with out.open("a") as f:
                f.write(json.dumps(rec) + "\n")
            bar.clear()
            print(kind, r, rec["rms_residual_um"], rec["lack_of_fit"]["p"], rec["within"], flush=True)
            bar(r - lo + 1, hi - lo)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
