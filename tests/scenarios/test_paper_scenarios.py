"""The self-calibration paper's studies, reproduced (scenarios.crosspocket)."""

import json

import pytest

from scenarios.cli import main


def test_cross_pocket_uncertainty(tmp_path, capsys):
    out = tmp_path / "cpu.json"
    assert main(["scenario", "cross-pocket-uncertainty", "--json", str(out), "--mc", "400"]) == 0
    r = json.loads(out.read_text())
    cases = {(tuple(c["c_angles_deg"]), c["spheres"]): c for c in r["cases"]}
    g = [cases[(c, True)]["g_u95_max_um"] for c in ((0, 75), (0, 75, 130), (0, 75, 130, 210))]
    assert g[0] > g[1] > g[2]  # more C angles, smaller uncertainty (Fig. 18)
    # the paper's 3.0 and 2.1 um within 30 % (our pocket is reconstructed, see notes)
    assert g[1] == pytest.approx(3.0, rel=0.3) and g[2] == pytest.approx(2.1, rel=0.3)
    for c in r["cases"]:
        # Monte Carlo (400 runs: ~4 % sampling error on a standard deviation) agrees with linear propagation
        assert c["g_u95_max_um"] == pytest.approx(c["g_u95_max_linear_um"], rel=0.12)
    # spheres help (Fig. 19 vs 18(c))
    assert cases[((0, 75, 130, 210), False)]["g_u95_max_um"] > g[2]
    t2 = {t["c_deg"]: t for t in r["table2"]}
    assert t2[0.0]["u_xc_um"] == 0 and t2[0.0]["u_cc_urad"] == 0
    for c in (75.0, 130.0, 210.0):
        assert t2[c]["u_cc_urad"] == pytest.approx(t2[c]["paper_u_cc_urad"], rel=0.15)


def test_pin_circle(tmp_path):
    out = tmp_path / "pc.json"
    assert main(["scenario", "pin-circle", "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["pins"] == 18
    assert r["selfcal_pin_error_max_um"] < 2.0 < r["raw_c0_pin_error_max_um"]  # paper: ~8 um -> < 2 um


def test_scenario_mc_too_small(capsys):
    assert main(["scenario", "cross-pocket-uncertainty", "--mc", "3"]) == 2
    assert "--mc must be >= 10" in capsys.readouterr().err
