"""The 5-axis MFB plan's 1,000-run Monte Carlo through the pipeline (issue 16 item 3), stored in
scenarios/data/mfb-5axis-budget-study.npz: made by this code, summarised in docs/papers-mfb.md,
and its budget checked against the truth it was drawn around and against hand values."""

from pathlib import Path

import numpy as np

from scenarios import mfb as S

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "scenarios" / "data" / "mfb-5axis-budget-study.npz"


def test_stored_5axis_study_is_this_pipeline_and_the_doc_table_is_its_summary():
    # run 1 recomputed now (one pipeline run, ~2 s) equals the stored vector to 1e-9 relative (the
    # study ran in separate processes on the same code; the tolerance leaves room for BLAS
    # re-association only)
    with np.load(STUDY) as z:
        err, ok = z["error"], z["attempt_ok"]
        assert len(err) == 1000 and ok.sum() == len(err) and str(z["name"]) == "mfb-5axis"
        first = int(np.flatnonzero(ok)[0]) + 1
        e0 = err[0]
    r = S.budget_run("mfb-5axis", first)
    assert np.abs(r["error"] - e0).max() <= 1e-9 * np.abs(e0).max()
    rep = S.study_report(STUDY)
    doc = (ROOT / "docs" / "papers-mfb.md").read_text()
    assert S.study_table_markdown(rep) in doc
    assert f"## Uncertainty budget of the 5-axis plan: {len(err):,} runs through the pipeline" in doc


def test_5axis_budget_covers_the_injected_errors_and_meets_the_hand_values():
    rep = S.study_report(STUDY)
    # the truth each run was drawn around: a right U95 covers about 95 % of the identified - true
    # values; one twice too large covers ~100 %, one half the size ~68 % (nodes are correlated, so
    # the band is wider than a binomial one)
    a, b = map(int, rep["coverage"]["within_quadrature_U95"].split("/"))
    assert 0.93 <= a / b <= 0.975
    # the sum of one-source shares against the Monte Carlo, per error: 1,000 runs give each U95 to
    # 2.2 % (1 SE); the per-error value is a ratio of maxima over ~6-9 nodes, and the 3-axis study
    # (same sources, same estimator) came to 0.90-1.02: 6 SE either way (set before the 5-axis
    # study ended; a share missing or doubled moves the ratio by far more)
    for s, c in rep["per_error"].items():
        assert 0.87 <= c["mc_over_quadrature"] <= 1.13, (s, c["mc_over_quadrature"])
    # JCGM 101 7.9 by halves: most nodes' halves within 2 standard errors
    assert rep["stability"]["within_2_se"] >= 0.9
    # hand values: 11.5 um/m/K (machine scales) and 1 um/m/K (Invar bar) over the plan's node spans
    # 450 / 350 / 250 mm
    ts = rep["temperature_sensitivity_per_C"]
    for s, span_mm in (("EXX", 450.0), ("EYY", 350.0), ("EZZ", 250.0)):
        assert abs(ts["machine temperature"][s] - 11.5e-3 * span_mm) <= 1e-3
        assert abs(ts["bar temperature"][s] - 1e-3 * span_mm) <= 1e-3
