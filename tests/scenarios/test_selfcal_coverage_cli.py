"""python -m scenarios.selfcal_coverage: the study's runner (one seed, against the functions it wraps), its pooling
by hand, bad input."""

import json

import numpy as np
import pytest

from scenarios import selfcal_coverage as sc


def test_one_seed_through_the_runner_is_the_studys_campaign(tmp_path, capsys):
    """nmv3000, seed 20, noise free, the ripple at its drawn phase: the JSON's record and pooled figures are
    identify_and_cover's on the same campaign (residuals only), and the declared budget covers every block
    (docs/discovery-studies.md, "Session 27: a declared sub-grid ripple": 1.000 noise free on seeds 20-39);
    the residuals alone miss part of the workpiece there (60 of 92 on this seed, measured; 58 before session 30's
    probing sigma beside the entered tables' fine span, core.uncertainty.SIGMA_BESIDE_TABLES)."""
    out = tmp_path / "c.json"
    assert sc.main(["--machines", "nmv3000", "--seeds", "20", "21", "--noise-um", "0", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["format"] == sc.FORMAT and doc["seeds"] == [20]
    res, cv, mis = sc.identify_and_cover(sc.simulate("nmv3000", 20, 0.0))
    rec = {r["budget"]: r for r in doc["records"]}
    assert rec["residuals"]["coverage"] == {b: list(v) for b, v in cv.items()}
    assert rec["residuals"]["split_misfit_nm"] == pytest.approx(mis * 1e9, rel=1e-12, abs=0)
    s = res.design.slices
    assert rec["residuals"]["workpiece_u95_median_um"] == pytest.approx(np.median(2 * res.std[s["G"]]) * 1e6, rel=1e-12, abs=0)
    assert rec["residuals"]["coverage"]["workpiece"] == [60, 92]
    assert all(k == n for k, n in rec["declared"]["coverage"].values())
    pooled = {p["budget"]: p for p in doc["pooled"]}
    assert pooled["residuals"]["workpiece"]["covered"] == 60 and pooled["residuals"]["campaigns"] == 1
    assert "nmv3000, 0 um, phase drawn, residuals: " in capsys.readouterr().out


def test_pool_known_answer():
    """Two campaigns: counts add, the fraction and Clopper-Pearson interval are of the sums, the U95 figures
    are medians over the campaigns."""
    recs = [{"coverage": {"EXX": [9, 10]}, "workpiece_u95_median_um": 1.0, "c_axis_u95_max_um": 2.0},
            {"coverage": {"EXX": [10, 10]}, "workpiece_u95_median_um": 3.0, "c_axis_u95_max_um": 4.0}]
    p = sc.pool(recs)
    assert p["EXX"]["covered"] == 19 and p["EXX"]["n"] == 20 and p["EXX"]["fraction"] == 0.95
    assert p["EXX"]["ci95"] == [round(v, 4) for v in sc.clopper_pearson(19, 20)]
    assert p["workpiece_u95_median_um"] == 2.0 and p["c_axis_u95_max_um"] == 3.0 and p["campaigns"] == 2


@pytest.mark.parametrize("argv, word", [(["--machines", "vmc-3axis"], "--machines vmc-3axis"),
                                        (["--machines", "nope"], "--machines nope"),
                                        (["--seeds", "5", "5"], "--seeds 5 5"),
                                        (["--noise-um", "-1"], "negative noise")])
def test_bad_input_one_line_exit_2(argv, word, capsys):
    assert sc.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and word in err and err.startswith("error: ")
