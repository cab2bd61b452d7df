"""LinuxCNC part programs and probe files, GRBL transcripts: to probe-log/1, bad input exit 2."""

import re

import numpy as np
import pytest

from conftest import LIMITS, LIMITS_MM, plan_log, scene
from core.exceptions import PlanError, ProbeLogError
from core.probelog import read_probe_log, write_probe_log
from hardware.backend import VirtualBackend
from hardware.campaign import ProbeSettings, run_campaign
from hardware.emulator import ControllerConfig, GrblEmulator, TcpServer
from hardware.linuxcnc import part_program, read_probe_file
from hardware.transcript import read_transcript
from scenarios.cli import main


@pytest.fixture
def measured(tmp_path, plan_path):
    """The reference campaign (in-process virtual machine) and its log."""
    out = tmp_path / "direct.csv"
    run_campaign(VirtualBackend(scene(), home_m=(0, 0, 0.05)), read_probe_log(plan_path), out,
                 ProbeSettings(limits_mm=LIMITS_MM, safe_z_mm=30.0))
    return read_probe_log(out)


def test_part_program_probes_every_row_between_probeopen_and_probeclose(plan_path, tmp_path, capsys):
    prog = tmp_path / "probe.ngc"
    assert main(["machine", "program", "--plan", str(plan_path), "--out", str(prog),
                 "--limits", LIMITS, "--safe-z", "30", "--probe-file", "/tmp/p.txt"]) == 0
    text = prog.read_text()
    lines = text.splitlines()
    i0, i1 = lines.index("(PROBEOPEN /tmp/p.txt)"), lines.index("(PROBECLOSE)")
    probes = [k for k, ln in enumerate(lines) if ln.startswith("G38.2 ")]
    assert len(probes) == 12 and i0 < probes[0] and probes[-1] < i1
    assert "G10 L2 P9 X0 Y0 Z0" in text and "G59.3" in lines and "G92.1" in lines
    # each probe is followed by its retract to the approach start, which preceded it
    for k in probes:
        assert lines[k + 1] == lines[k - 1]
    plan = read_probe_log(plan_path)
    first = [float(v) for v in re.findall(r"[XYZ](-?\d+\.\d+)", lines[probes[0]])]
    assert np.allclose(first, plan.nominals_mm()[0] - 2.0 * plan.normals()[0], atol=1e-4)
    with pytest.raises(PlanError, match="wcs"):
        part_program(plan, ProbeSettings(limits_mm=LIMITS_MM), wcs="G60")
    assert main(["machine", "program", "--plan", str(plan_path), "--out", str(prog)]) == 2
    assert "without them" in capsys.readouterr().err


@pytest.mark.parametrize("width", [3, 9])
def test_linuxcnc_probe_file_both_widths(tmp_path, plan_path, measured, width, capsys):
    pos = measured.positions_mm()
    pf = tmp_path / "probe.txt"
    with open(pf, "w") as f:
        for p in pos:                         # LinuxCNC writes "%f" (6 decimals), space separated
            vals = list(p) + [0.0] * (width - 3)
            f.write(" ".join(f"{v:f}" for v in vals) + "\n")
    out = tmp_path / "log.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan_path), "--out", str(out)]) == 0
    log = read_probe_log(out)
    assert log.n == 12 and np.all(log.ok)
    assert np.allclose(log.positions_mm(), pos, atol=1e-6)       # 6 decimals in the file
    assert np.allclose(log.nominals_mm(), measured.nominals_mm())
    assert list(log.columns["feature"]) == list(measured.columns["feature"])
    assert np.all(np.diff(log.columns["t_s"]) > 0) and "plan order" in log.meta["t_s_source"]


@pytest.mark.parametrize("body, msg", [
    ("1 2 3\n1 2 3 4\n", "line 2: 4 numbers, expected 3"),
    ("1 2 3\n1 2 x\n", "line 2: 'x' is not a number"),
    ("1 2 3\n\n1 2 3 0 0 0 0 0 0\n", "line 3: 9 numbers but earlier lines have 3"),
    ("1 2 nan\n", "line 1: not finite"),
    ("\n\n", "empty probe file"),
    ("1 2 3\n" * 5, "5 probe lines but the plan"),
])
def test_linuxcnc_bad_probe_file_one_line_exit_2(tmp_path, plan_path, capsys, body, msg):
    pf = tmp_path / "probe.txt"
    pf.write_text(body)
    out = tmp_path / "log.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert msg in err and err.count("\n") == 1 and str(pf) in err
    assert not out.exists()


def test_grbl_transcript_of_a_live_campaign_imports_to_the_same_log(tmp_path, plan_path):
    tr, out = tmp_path / "session.txt", tmp_path / "live.csv"
    emu = GrblEmulator(scene(), ControllerConfig(home=(0, 0, 50)))
    with TcpServer(emu, time_scale=200.0) as srv:
        assert main(["probe", "--machine", srv.url, "--plan", str(plan_path), "--out", str(out),
                     "--limits", LIMITS, "--safe-z", "30", "--transcript", str(tr)]) == 0
    imp = tmp_path / "imported.csv"
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(imp)]) == 0
    a, b = read_probe_log(out), read_probe_log(imp)
    assert np.array_equal(a.positions_mm(), b.positions_mm())      # same PRB lines, same digits
    assert b.meta["t_s_source"] == "transcript timestamps"
    assert np.all(np.diff(b.columns["t_s"]) >= 0)


def test_transcript_formats_misses_and_status_queries(tmp_path):
    plan = plan_log(n_sphere=0)           # 4 table touches
    plan_path = write_probe_log(tmp_path / "plan.csv", plan)
    tr = tmp_path / "t.txt"
    tr.write_text("\n".join([
        "[23:59:58.5] > G38.2 Z-4 F100",
        "[23:59:59.0] < [PRB:10.000,10.000,0.001:1]",
        "[23:59:59.1] < ok",
        "[23:59:59.5] > $#",
        "[23:59:59.6] < [G54:0.000,0.000,0.000]",
        "[23:59:59.6] < [G92:0.000,0.000,0.000]",
        "[23:59:59.6] < [TLO:0.000]",
        "[23:59:59.6] < [PRB:10.000,10.000,0.001:1]",       # $# repeats the last probe
        "[00:00:01.0] < [PRB:90.000,10.000,-0.002,0.000:1]",   # midnight, 4 axes
        "[00:00:02.0] < ALARM:5",
        "[00:00:02.0] < [PRB:90.000,90.000,-2.000:0]",
        "[00:00:03.0] < [PRB:10.000,90.000,0.000:1]",
    ]) + "\n")
    out = tmp_path / "log.csv"
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(out)]) == 0
    log = read_probe_log(out)
    assert list(log.col("status")) == ["ok", "ok", "no_trigger", "ok"]
    assert np.allclose(log.columns["t_s"][log.ok], [0.5, 2.5, 4.5])
    assert np.isclose(log.columns["Z_mm"][1], -0.002)


@pytest.mark.parametrize("lines, msg", [
    (["[PRB:1.0,zz,3:1]"], "line 1: malformed probe report"),
    (["5.0 < [PRB:1,2,3:1]", "[PRB:1,2,3:1]"], "line 2: probe report without a timestamp"),
    (["5.0 < [PRB:1,2,3:1]", "4.0 < [PRB:1,2,3:1]"], "line 2: time goes backwards"),
    (["ok", "<Idle|MPos:0,0,0>"], "no probe reports"),
    (["[PRB:1,2,3:1]"] * 3, "3 probe reports but the plan"),
])
def test_bad_transcript_one_line_exit_2(tmp_path, capsys, lines, msg):
    plan_path = write_probe_log(tmp_path / "plan.csv", plan_log(n_sphere=0))
    tr = tmp_path / "t.txt"
    tr.write_text("\n".join(lines) + "\n")
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out",
                 str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert msg in err and err.count("\n") == 1


def test_missing_files(tmp_path, plan_path, capsys):
    for kind in ("linuxcnc", "grbl"):
        assert main(["import", kind, str(tmp_path / "none.txt"), "--plan", str(plan_path),
                     "--out", str(tmp_path / "o.csv")]) == 2
        assert "no such file" in capsys.readouterr().err
    with pytest.raises(ProbeLogError, match="no such file"):
        read_probe_file(tmp_path / "none.txt")
    with pytest.raises(ProbeLogError, match="no such file"):
        read_transcript(tmp_path / "none.txt")
