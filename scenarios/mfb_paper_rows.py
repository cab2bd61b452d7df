"""The seed-1 figures of docs/papers-mfb.md's "Section 6: results" rows (Figs. 15-17) and of its
reversal / declared table ("What vmt adds"), computed from the runs the page's commands make:

    vmt scenario mfb-reversal --json cal.json
    vmt scenario mfb-3axis --mc 0 [--bar-calibration cal.json]
    vmt scenario mfb-5axis --mc 0 [--bar-calibration cal.json]

``python -m scenarios.mfb_paper_rows`` prints each cell; tests/scenarios/test_mfb_paper_rows.py checks
that the page holds every one of them (session 31, review31b F2: the rows had been typed by hand and
went stale). Also the declared calibration's U95 read as k = 1 (review31b F3: the paper's 0.4 / 0.7 um
"average uncertainty" states no coverage factor; vmt takes them as k = 2).
"""

from __future__ import annotations

import os
import tempfile

#: The page's seed.
SEED = 1


def _runs() -> dict:
    from scenarios.mfb import bar_calibration_doc, read_bar_calibration, reversal_on_cmm, run
    from core.atomic import write_json_atomic

    rev = reversal_on_cmm(seed=SEED)
    with tempfile.TemporaryDirectory() as d:  # through the file, as --bar-calibration reads it
        f = os.path.join(d, "cal.json")
        write_json_atomic(f, bar_calibration_doc(rev), special=True)
        cal, true_m = read_bar_calibration(f)
    out = {"reversal": rev}
    for name in ("mfb-3axis", "mfb-5axis"):
        out[name, "declared"] = run(name, seed=SEED, mc_runs=0)
        out[name, "reversal"] = run(name, seed=SEED, mc_runs=0, bar_calibration=cal, bar_true_m=true_m)
        out[name, "k1"] = run(name, seed=SEED, mc_runs=0, u_cal_um=(0.4, 0.7, 0.7))
    return out


def _e(doc, k):
    e = doc["errors"][k]
    return max(abs(v) for v in e["injected"]), e["max_dev"], max(e["u95"])


def cells(runs: dict | None = None) -> dict:
    """Every figure cell of the rows, as the page writes it: name -> text."""
    r = _runs() if runs is None else runs
    m5, m3 = r["mfb-5axis", "declared"].doc, r["mfb-3axis", "declared"].doc
    c = {}
    (i5, d5, u5), (i3, d3, u3) = _e(m5, "EXX"), _e(m3, "EXX")
    c["Fig. 15"] = (f"injected {i5:.1f} µm (mikron) / {i3:.1f} µm (vmc-3axis); error {d5:.2f} / {d3:.2f} µm "
                    f"against U95 max {u5:.2f} / {u3:.2f} µm (declared calibration)")
    (iy5, dy5, uy5), (iz5, dz5, uz5) = _e(m5, "EYX"), _e(m5, "EZX")
    (iy3, dy3, uy3), (iz3, dz3, uz3) = _e(m3, "EYX"), _e(m3, "EZX")
    c["Fig. 16"] = (f"injected {iy5:.1f} / {iz5:.1f} µm (mikron), {iy3:.1f} / {iz3:.1f} µm (vmc-3axis); errors "
                    f"{dy5:.2f} / {dz5:.2f} µm (U95 {uy5:.2f} / {uz5:.2f}) and {dy3:.2f} / {dz3:.2f} µm "
                    f"(U95 {uy3:.2f} / {uz3:.2f})")
    for k in ("EBX", "EAX", "ECX"):
        (a5, b5, v5), (a3, b3, v3) = _e(m5, k), _e(m3, k)
        c[f"Fig. 17 {k}"] = (f"injected {a5:.1f} (mikron) / {a3:.1f} µrad (vmc-3axis); errors {b5:.2f} / "
                             f"{b3:.2f} µrad, U95 {v5:.1f} / {v3:.1f}")
    # the reversal / declared table
    cols = [("mfb-3axis", "reversal"), ("mfb-3axis", "declared"), ("mfb-5axis", "reversal"),
            ("mfb-5axis", "declared")]
    docs = [r[k].doc for k in cols]

    def row(name, f):
        return f"| {name} | " + " | ".join(f(d) for d in docs) + " |"

    c["bar"] = row("bar: calibrated - true, max", lambda d: f"{d['bar']['calibrated_minus_true_max_um']:.2f} µm")
    c["max"] = row("max \\|identified - injected\\|", lambda d: f"{d['max_dev_um']:.2f} µm / {d['max_dev_urad']:.2f} µrad")
    w = "within_u95"
    c["values"] = row("values within U95 (gauge nodes left out; the model's 95 % range)",
                      lambda d: f"{d[w]['inside']}/{d[w]['total']} ({d[w]['range95'][0]}-{d[w]['range95'][1]})")
    c["errors"] = row("errors within U95 at every node (the model's 95 % range)",
                      lambda d: f"{d[w]['errors_inside']}/{d[w]['errors_total']} "
                                f"({d[w]['errors_range95'][0]}-{d[w]['errors_range95'][1]})")
    for k in ("EXX", "EYX", "EZX", "EZY"):
        c[k] = row(f"{k} error / U95 max", lambda d, k=k: f"{_e(d, k)[1]:.2f} / {_e(d, k)[2]:.2f} µm")
    # k = 1: the declared calibration's u the paper's figures themselves
    k1 = [r[n, "k1"].doc for n in ("mfb-3axis", "mfb-5axis")]
    c["k1"] = ("read as k = 1 (u 0.4 / 0.7 / 0.7 µm, twice vmt's), seed 1: EXX U95 max "
               f"{_e(m3, 'EXX')[2]:.2f} -> {_e(k1[0], 'EXX')[2]:.2f} µm (3-axis), "
               f"{_e(m5, 'EXX')[2]:.2f} -> {_e(k1[1], 'EXX')[2]:.2f} µm (5-axis); EZX "
               f"{_e(m3, 'EZX')[2]:.2f} -> {_e(k1[0], 'EZX')[2]:.2f} and "
               f"{_e(m5, 'EZX')[2]:.2f} -> {_e(k1[1], 'EZX')[2]:.2f} µm")
    # section 3 (vmt scenario mfb-reversal): Fig. 9's and Fig. 10's cells
    rc, U = r["reversal"]["compared_um"], r["reversal"]["calibration"].U95_m * 1e6
    n_in = rc["Exx"]["within_U95"].split("/")[0]
    c["Fig. 9"] = (f"U95 mean {U[:, 0].mean():.2f} µm, max {U[:, 0].max():.2f} µm; estimate - truth max "
                   f"{rc['Exx']['max_abs_um']:.2f} µm, {n_in} of 12 within U95 (O_1 is the origin)")
    c["Fig. 10"] = (f"U95 mean {U[:, 1].mean():.3f} / {U[:, 2].mean():.3f} µm, max {U[:, 1].max():.3f} / "
                    f"{U[:, 2].max():.2f} µm (Eyx / Ezx); estimate - truth max {rc['Eyx']['max_abs_um']:.3f} / "
                    f"{rc['Ezx']['max_abs_um']:.3f} µm, {rc['Eyx']['within_U95']} and {rc['Ezx']['within_U95']} "
                    "within U95")
    return c


def main(argv=None) -> int:
    """``python -m scenarios.mfb_paper_rows``: print each cell (about 30 s CPU). ``-h``/``--help`` prints the
    module's docstring and runs nothing; any other argument is refused (exit 2), since the study takes none."""
    import sys

    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in ("-h", "--help"):
        print(__doc__.strip())
        return 0
    if argv:
        print(f"python -m scenarios.mfb_paper_rows: error: takes no arguments, got {' '.join(argv)!r} (-h for help)",
              file=sys.stderr)
        return 2
    for k, v in cells().items():
        print(f"{k}: {v}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
