"""``vmt iso230-2`` and ``vmt simulate positioning``: contract keys, bad input exits 2."""

import json
import subprocess
import sys

import pytest

from scenarios.cli import main
from tests.core.test_positioning import ECMC_OWN, HAND_FIGURES_UM, hand_rows, hand_text

CONTRACT = ("B_um", "B_mean_um", "R_up_um", "R_down_um", "R_um", "E_up_um", "E_down_um", "E_um", "M_um",
            "A_up_um", "A_down_um", "A_um", "per_target")


def test_iso230_2_writes_the_contract(tmp_path, capsys):
    log = tmp_path / "hand.csv"
    log.write_text(hand_text())
    out = tmp_path / "r.json"
    assert main(["iso230-2", str(log), "--json", str(out), "--eve-um", "0.6"]) == 0
    rep = json.loads(out.read_text())
    for k in CONTRACT:
        assert k in rep, k
    for name, um in HAND_FIGURES_UM.items():
        assert rep[f"{name}_um"] == pytest.approx(um, abs=1e-6)
    assert rep["uncertainty"]["U_R_um"] == pytest.approx(2 * 0.6 / 12 ** 0.5)
    cap = capsys.readouterr()
    assert ["E", "12.000", "um", "(U"] in [line.split()[:4] for line in cap.out.splitlines()]
    assert "3 targets: ISO 230-2 asks at least 5" in cap.err


def test_iso230_2_reads_ecmc_and_writes_the_log(tmp_path, capsys):
    dat = tmp_path / "x.dat"
    dat.write_text(ECMC_OWN)
    assert main(["iso230-2", str(dat), "--json", str(tmp_path / "r.json"),
                 "--write-log", str(tmp_path / "x.csv")]) == 0
    assert (tmp_path / "x.csv").read_text().startswith("# format: positioning-log/1")
    # B = max |B_i|: at 0 mm FWD 2.0, 2.2 um -> 2.1; BWD 0.0, -0.2 -> -0.1; B_i = 2.2 (at -10: 1.8, at 10: 1.8)
    assert json.loads((tmp_path / "r.json").read_text())["B_um"] == pytest.approx(2.2, abs=1e-6)


@pytest.mark.parametrize("text,kind,match", [
    (None, "auto", "no such file"),
    ("\n".join(hand_text().splitlines()[:4]), "auto", "no valid readings approached in the '-' direction"),
    (ECMC_OWN.replace("REF_DATA_BWD[3,2]=10.0010\n", ""), "auto", r"REF_DATA_BWD[3,2] missing"),
    (hand_text(), "ecmc", "not KEY=VALUE or KEY[i,j]=VALUE"),
])
def test_iso230_2_bad_input_exit_2(tmp_path, capsys, text, kind, match):
    p = tmp_path / "in.txt"
    if text is not None:
        p.write_text(text)
    out = tmp_path / "r.json"
    assert main(["iso230-2", str(p), "--json", str(out), "--from", kind]) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1
    assert not out.exists()  # nothing half-written


def test_iso230_2_subprocess_no_traceback(tmp_path):
    p = tmp_path / "dup.csv"
    rows = hand_rows()
    p.write_text(hand_text(rows + [rows[0]]))
    r = subprocess.run([sys.executable, "-m", "scenarios.cli", "iso230-2", str(p), "--json",
                        str(tmp_path / "r.json")], capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr and r.stderr.count("\n") == 1
    assert "already measured in row 0" in r.stderr


def test_simulate_positioning_then_evaluate_with_report(tmp_path, capsys):
    log = tmp_path / "y.csv"
    assert main(["simulate", "positioning", "--machine", "vmc-3axis", "--axis", "Y", "--out", str(log),
                 "--targets", "6", "--cycles", "5", "--cycle", "pilgrim", "--reversal-um", "2",
                 "--noise-um", "0", "--errors", "none"]) == 0
    assert main(["iso230-2", str(log), "--json", str(tmp_path / "r.json"), "--report", str(tmp_path / "rep")]) == 0
    rep = json.loads((tmp_path / "r.json").read_text())
    # Y of vmc-3axis moves the table: lost motion 2 um reads as B_i = -2 um at every target, nothing else
    assert rep["B_mean_um"] == pytest.approx(-2.0, abs=1e-6) and rep["E_um"] == pytest.approx(2.0, abs=1e-6)
    assert rep["M_um"] == pytest.approx(0.0, abs=1e-6) and rep["cycle_kind"] == "pilgrim"
    html = (tmp_path / "rep" / "index.html").read_text()
    assert "iso230_2.png" in html and "Baseline for model discovery" in html


@pytest.mark.parametrize("argv,match", [
    (["simulate", "mfb", "--out", "x.csv", "--axis", "X"], "--axis applies to 'vmt simulate positioning' only"),
    (["simulate", "positioning", "--out", "x.csv", "--c-angles", "0"], "--c-angles does not apply"),
    (["simulate", "positioning", "--out", "x.csv", "--machine", "nope"], "--machine 'nope' is not one of"),
    (["simulate", "positioning", "--out", "x.csv", "--travel-mm", "0-100"], "--travel-mm '0-100': expected 2"),
    (["simulate", "positioning", "--out", "x.csv", "--cycles", "1"], "cycles must be a whole number >= 2"),
    (["simulate", "positioning", "--out", "x.csv", "--travel-mm", "0:400"], "leave the stroke"),
])
def test_simulate_positioning_bad_options_exit_2(tmp_path, capsys, monkeypatch, argv, match):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1
    assert not (tmp_path / "x.csv").exists()
