"""``vmt iso230-2`` and ``vmt simulate positioning``: contract keys, bad input exits 2."""

import json
import math
import subprocess
import sys

import pytest

from core.positioning import iso230_2, read_positioning_log
from scenarios.cli import main
from scenarios.positioning_sample import SAMPLE

CONTRACT = ("B_um", "B_mean_um", "R_up_um", "R_down_um", "R_um", "E_up_um", "E_down_um", "E_um", "M_um",
            "A_up_um", "A_down_um", "A_um", "per_target")
# 2 targets (0, 10 mm) x 2 cycles; deviations in um: + at 0: 1, 3; - at 0: -1, -1; + at 10: 2, 2; - at 10: 0, 2
ROWS = [(0, 1, "+", 0.001), (10, 1, "+", 10.002), (10, 1, "-", 10.0), (0, 1, "-", -0.001),
        (0, 2, "+", 0.003), (10, 2, "+", 10.002), (10, 2, "-", 10.002), (0, 2, "-", -0.001)]
# 2 targets, 2 cycles in ecmc's layout (FWD = +): B_i = (1.0 - -0.5, 2.0 - 0.0) = (1.5, 2.0) um
ECMC = """UNIT=mm
CYCLES=2
POSITIONS=2
TGT_DATA[1]=0
TGT_DATA[2]=10
REF_DATA_FWD[1,1]=0.0010
REF_DATA_FWD[2,1]=10.0020
REF_DATA_FWD[1,2]=0.0010
REF_DATA_FWD[2,2]=10.0020
REF_DATA_BWD[1,1]=-0.0005
REF_DATA_BWD[2,1]=10.0000
REF_DATA_BWD[1,2]=-0.0005
REF_DATA_BWD[2,2]=10.0000
"""


def log_text(rows=ROWS):
    body = "\n".join(",".join(str(v) for v in r) for r in rows)
    return f"# format: positioning-log/1\ntarget_mm,cycle,direction,measured_mm\n{body}\n"


def test_iso230_2_writes_the_contract(tmp_path, capsys):
    out = tmp_path / "r.json"
    assert main(["iso230-2", str(SAMPLE), "--json", str(out), "--eve-um", "0.6"]) == 0
    rep = json.loads(out.read_text())
    assert rep["format"] == "vmt-iso230-2/1"   # docs/formats.md
    for k in CONTRACT:
        assert k in rep, k
    lib = iso230_2(read_positioning_log(SAMPLE)).to_report()  # the wiring: the library's figures, in um
    for k in CONTRACT[:-1]:
        assert rep[k] == lib[k]
    assert rep["per_target"] == lib["per_target"]
    # E_VE 0.6 um rectangular, and (session 34) the readings' printed step, 1 nm (6 decimals in mm), 4 u_q on R
    assert rep["uncertainty"]["U_R_um"] == pytest.approx(2 * math.hypot(0.6 / 12 ** 0.5, 4 * 1e-3 / 12 ** 0.5),
                                                         rel=1e-12, abs=0)
    assert rep["printed_step"]["step_mm"] == pytest.approx(1e-6, rel=1e-12, abs=0) and not rep["printed_step"]["coarse"]
    cap = capsys.readouterr()
    assert ["E", f"{lib['E_um']:.3f}", "um", "(U"] in [line.split()[:4] for line in cap.out.splitlines()]
    assert cap.err == ""


def test_iso230_2_warns_on_a_short_test(tmp_path, capsys):
    p = tmp_path / "short.csv"
    p.write_text(log_text())
    assert main(["iso230-2", str(p), "--json", str(tmp_path / "r.json")]) == 0
    # by hand: x_up(0) = 2, x_down(0) = -1, x_up(10) = 2, x_down(10) = 1 -> E = 2 - (-1) = 3 um
    assert json.loads((tmp_path / "r.json").read_text())["E_um"] == pytest.approx(3.0, abs=1e-6)
    err = capsys.readouterr().err
    assert "2 valid approaches at some target and direction: ISO 230-2 asks 5" in err


def test_iso230_2_reads_ecmc_and_writes_the_log(tmp_path, capsys):
    dat = tmp_path / "x.dat"
    dat.write_text(ECMC)
    assert main(["iso230-2", str(dat), "--json", str(tmp_path / "r.json"),
                 "--write-log", str(tmp_path / "x.csv")]) == 0
    assert (tmp_path / "x.csv").read_text().startswith("# format: positioning-log/1")
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["B_um"] == pytest.approx(2.0, abs=1e-6) and rep["B_mean_um"] == pytest.approx(1.75, abs=1e-6)


@pytest.mark.parametrize("text,kind,match", [
    (None, "auto", "no such file"),
    (log_text([r for r in ROWS if r[2] == "+"]), "auto", "no valid readings approached in the '-' direction"),
    (ECMC.replace("REF_DATA_BWD[2,2]=10.0000\n", ""), "auto", "REF_DATA_BWD[2,2] missing"),
    (log_text(), "ecmc", "not KEY=VALUE or KEY[i,j]=VALUE"),
])
def test_iso230_2_bad_input_exit_2(tmp_path, capsys, text, kind, match):
    p = tmp_path / "in.txt"
    if text is not None:
        p.write_text(text)
    out = tmp_path / "r.json"
    assert main(["iso230-2", str(p), "--json", str(out), "--log-kind", kind]) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1
    assert not out.exists()  # nothing half-written


def test_iso230_2_subprocess_no_traceback(tmp_path):
    p = tmp_path / "dup.csv"
    p.write_text(log_text(ROWS + [ROWS[0]]))
    r = subprocess.run([sys.executable, "-m", "scenarios.cli", "iso230-2", str(p), "--json",
                        str(tmp_path / "r.json")], capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr and r.stderr.count("\n") == 1
    assert "already measured in row 0" in r.stderr


def test_simulate_positioning_then_evaluate_with_report(tmp_path, capsys):
    log = tmp_path / "y.csv"
    assert main(["simulate", "positioning", "--machine", "vmc-3axis", "--axis", "Y", "--out", str(log),
                 "--targets", "6", "--cycles", "5", "--cycle-kind", "pilgrim", "--reversal-um", "2",
                 "--scatter-um", "0", "--errors", "none"]) == 0
    assert main(["iso230-2", str(log), "--json", str(tmp_path / "r.json"), "--report", str(tmp_path / "rep")]) == 0
    rep = json.loads((tmp_path / "r.json").read_text())
    # lost motion 2 um on Y (ISO 230-1 values: the tool relative to the part, also on this table-side
    # Y) reads as B_i = +2 um at every target, nothing else
    assert rep["B_mean_um"] == pytest.approx(2.0, abs=1e-6) and rep["E_um"] == pytest.approx(2.0, abs=1e-6)
    assert rep["M_um"] == pytest.approx(0.0, abs=1e-6) and rep["cycle_kind"] == "pilgrim"
    html = (tmp_path / "rep" / "index.html").read_text()
    assert "iso230_2.png" in html and "Baseline for model discovery" in html
    # a pilgrim cycle is ISO 230-2's Annex B step cycle: its figures are said not to be ISO 230-2 results
    # (for acceptance) in the JSON, on the CLI (one line) and in the report; a linear test says nothing
    note = "a pilgrim (step) cycle, ISO 230-2:2014 Annex B: not ISO 230-2 results to quote or to accept a machine by"
    assert rep["cycle_note"].startswith(note) and "agree so in writing" in rep["cycle_note"]
    out = capsys.readouterr().out
    assert sum(note in ln for ln in out.splitlines()) == 1 and note in html
    lin = tmp_path / "lin.csv"
    assert main(["simulate", "positioning", "--machine", "vmc-3axis", "--axis", "Y", "--out", str(lin),
                 "--targets", "6", "--cycles", "5", "--scatter-um", "0", "--errors", "none"]) == 0
    assert main(["iso230-2", str(lin), "--json", str(tmp_path / "l.json")]) == 0
    assert "Annex B" not in capsys.readouterr().out
    assert "cycle_note" not in json.loads((tmp_path / "l.json").read_text())


@pytest.mark.parametrize("argv,match", [
    (["simulate", "mfb", "--out", "x.csv", "--axis", "X"], "--axis applies to 'vmt simulate positioning' only"),
    (["simulate", "positioning", "--out", "x.csv", "--c-angles-deg", "0"], "--c-angles-deg does not apply"),
    (["simulate", "positioning", "--out", "x.csv", "--machine", "nope"], "--machine 'nope': no such file, and not a built-in machine"),
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


# session 25 review (brief pos5): refusals reach the user as one line and exit 2
_HDR = "target_mm,cycle,direction,measured_mm"


@pytest.mark.parametrize("text,match", [
    ("# axis: X\n" + _HDR + ",status\n" + "\n".join(f"{p},{c},{d},{m},ok" for p, c, d, m in ROWS) + "\n",
     "line 2: column 'status' is not a table column"),
    ("# unit: deg\ntarget,cycle,direction,deviation_um\n" + "\n".join(f"{p},{c},{d},1" for p, c, d, _ in ROWS),
     "column 'deviation_um' is a length (um) but the table is in deg"),
    (log_text(ROWS + [(10.0000004, 1, "+", 10.1)]), "target 10.0000004 mm, cycle 1, direction '+' already measured"),
    (log_text([("1_0", 1, "+", 10.002)] + ROWS[1:]), "column 'target_mm': '1_0' is not a number"),
    (log_text([r + (-5 + k,) for k, r in enumerate(ROWS)]).replace(_HDR, _HDR + ",t_s"),
     "column 't_s': -5 is out of range (must be >= 0"),
    (log_text([r + (-500,) for r in ROWS]).replace(_HDR, _HDR + ",temp_air_C"),
     "column 'temp_air_C': -500 is out of range (must be >= -273.15"),
    (log_text([(1e300 if p else p, c, d, 1e300 if p else m) for p, c, d, m in ROWS]),
     "column 'target_mm': 1e+300 is out of range"),
])
def test_iso230_2_review_refusals_exit_2(tmp_path, capsys, text, match):
    p = tmp_path / "in.csv"
    p.write_text(text)
    out = tmp_path / "r.json"
    assert main(["iso230-2", str(p), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1 and str(p) in err
    assert not out.exists()


def test_iso230_2_deg_table_is_evaluated_and_saved_in_degrees(tmp_path, capsys):
    """A table with target_deg/measured_deg columns and no '# unit:' line: degrees (main: mm)."""
    rows = [(p / 10, c, d, p / 10 + (m - p) / 10) for p, c, d, m in ROWS]
    p = tmp_path / "t.csv"
    p.write_text("target_deg,cycle,direction,measured_deg\n" + "\n".join(",".join(map(str, r)) for r in rows) + "\n")
    out, log = tmp_path / "r.json", tmp_path / "w.csv"
    assert main(["iso230-2", str(p), "--json", str(out), "--write-log", str(log)]) == 0
    rep = json.loads(out.read_text())
    assert rep["unit"] == "arcsec" and "B_arcsec" in rep
    back = read_positioning_log(log)
    assert back.unit == "deg" and "target_deg,cycle,direction,measured_deg" in log.read_text()


def test_simulated_z_test_records_j_and_the_comp_file_sits_at_the_axis_positions(tmp_path, capsys):
    """vmc-3axis's probe is 150 mm long (J_Z): the simulated Z log records it, and
    ``vmt iso230-2 --comp-file`` writes the table at target + 150 mm; its forward / reverse columns
    are nominal + the JSON's mean deviations (6 decimals in mm: 0.5 nm)."""
    log = tmp_path / "z.csv"
    assert main(["simulate", "positioning", "--axis", "Z", "--out", str(log), "--targets", "6"]) == 0
    assert "# tool_offset_mm: 0.0,0.0,150.0\n" in log.read_text()
    comp = tmp_path / "z.comp"
    assert main(["iso230-2", str(log), "--json", str(tmp_path / "r.json"), "--comp-file", str(comp)]) == 0
    assert f"and {comp}" in capsys.readouterr().out
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["tool_offset_mm"] == [0.0, 0.0, 150.0] and rep["axis_position_offset_mm"] == 150.0
    rows = [[float(v) for v in line.split()] for line in comp.read_text().splitlines()]
    targets = sorted(set(read_positioning_log(log).target.tolist()))
    assert len(rows) == 6
    for (nom, fwd, rev), p, t in zip(rows, targets, rep["per_target"]):
        assert nom == pytest.approx(p + 150.0, abs=5e-7)
        assert fwd - nom == pytest.approx(t["mean_up_um"] * 1e-3, abs=1e-6)
        assert rev - nom == pytest.approx(t["mean_down_um"] * 1e-3, abs=1e-6)


def test_iso230_2_bad_tool_offset_exit_2(tmp_path, capsys):
    p = tmp_path / "j.csv"
    p.write_text(log_text().replace("\ntarget_mm", "\n# axis: Z\n# tool_offset_mm: 0,150\ntarget_mm"))
    assert main(["iso230-2", str(p), "--json", str(tmp_path / "r.json"), "--comp-file", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert "metadata tool_offset_mm '0,150': expected 3 numbers" in err and err.count("\n") == 1
    assert not (tmp_path / "c").exists() and not (tmp_path / "r.json").exists()


def test_iso230_2_comp_file_on_the_input_refused(tmp_path, capsys):
    p = tmp_path / "in.csv"
    p.write_text(log_text())
    assert main(["iso230-2", str(p), "--json", str(tmp_path / "r.json"), "--comp-file", str(p)]) == 2
    err = capsys.readouterr().err
    assert "--comp-file" in err and "refusing to overwrite an input" in err and err.count("\n") == 1
    assert p.read_text() == log_text()


def test_iso230_2_names_e_as_the_standard_does(tmp_path, capsys):
    """review30 F9: ISO 230-2:2014 calls E the systematic positioning error of an axis (2.20, 2.21)."""
    from scenarios.positioning import FIGURE_ROWS

    said = {name: meaning for name, _s, _c, meaning in FIGURE_ROWS}
    assert said["E"] == "bidirectional systematic positioning error"
    assert said["E_up"].startswith("unidirectional systematic positioning error")
    assert not any("positional deviation" in m for n, m in said.items() if n.startswith("E"))
