"""LinuxCNC part programs and probe files, GRBL transcripts: to probe-log/1, bad input exit 2."""

import re
from pathlib import Path

import numpy as np
import pytest

from conftest import LIMITS, LIMITS_MM, plan_log, scene
from core.exceptions import PlanError, ProbeLogError
from core.probelog import make_log, read_probe_log, write_probe_log
from hardware.backend import VirtualBackend
from hardware.campaign import ProbeSettings, run_campaign
from hardware.emulator import ControllerConfig, GrblEmulator, TcpServer
from hardware.linuxcnc import import_probe_file, part_program, read_probe_file
from hardware.grbl import parse_prb
from hardware.transcript import read_transcript
from scenarios.cli import main


@pytest.fixture
def measured(tmp_path, plan_path):
    """The reference campaign (in-process virtual machine) and its log."""
    out = tmp_path / "direct.csv"
    run_campaign(VirtualBackend(scene(), home_m=(0, 0, 0.05)), read_probe_log(plan_path), out,
                 ProbeSettings(limits_mm=LIMITS_MM, safe_z_mm=30.0))
    return read_probe_log(out)


def test_part_program_probes_every_row_between_logopen_and_logclose(plan_path, tmp_path, capsys):
    prog = tmp_path / "probe.ngc"
    assert main(["machine", "program", "--plan", str(plan_path), "--out", str(prog),
                 "--limits-mm", LIMITS, "--safe-z-mm", "30", "--probe-file", "/tmp/p.txt"]) == 0
    text = prog.read_text()
    lines = text.splitlines()
    i0, i1 = lines.index("(LOGOPEN,/tmp/p.txt)"), lines.index("(LOGCLOSE)")
    probes = [k for k, ln in enumerate(lines) if ln.startswith("G38.2 ")]
    assert len(probes) == 12 and i0 < probes[0] and probes[-1] < i1
    # each probe logged right after it, numbered by its plan row (a PROBEOPEN file has no line for a probe
    # at the previous one's position: LinuxCNC's emccanon.cc), and nothing else logged
    logged = [lines[k + 1] for k in probes]
    assert [ln.split(" G91 ")[0] for ln in logged] == [f"(LOG,N{r} G1 X#5061 Y#5062 Z#5063" for r in range(12)]
    # ... with the probing move that made it, start to end (G91 G38.2): 2 + 2 mm long (session 30)
    moves = [np.array([float(v) for v in re.findall(r"[XYZ](-?\d+\.\d+)", ln.split("G38.2")[1])]) for ln in logged]
    assert all(ln.endswith(")") and " G91 G38.2 X" in ln for ln in logged)
    np.testing.assert_allclose([np.linalg.norm(m) for m in moves], 4.0, atol=2e-4)
    assert sum(ln.startswith("(LOG,") for ln in lines) == 12 and not any("PROBEOPEN" in ln for ln in lines)
    # G59.3 zeroed with no rotation (R0: an existing XY rotation would turn the file), G92 suspended
    assert "G10 L2 P9 X0 Y0 Z0 R0" in lines and "G59.3" in lines and "G92.2" in lines
    assert "G92.1" not in lines                      # the user's G92 values are kept, not erased
    # ... and the user's frame, G92 and modal state come back at the end, before M2
    k0, k_end = lines.index("M70"), lines.index("M2")
    saved = {ln.split(" = ")[0]: ln.split(" = ")[1] for ln in lines[k0 + 1:k0 + 5]}
    assert saved == {"#<_vmt_wcs_x>": "#5381", "#<_vmt_wcs_y>": "#5382", "#<_vmt_wcs_z>": "#5383",
                     "#<_vmt_wcs_r>": "#5390"}
    assert lines[i1 + 1] == "G10 L2 P9 X#<_vmt_wcs_x> Y#<_vmt_wcs_y> Z#<_vmt_wcs_z> R#<_vmt_wcs_r>"
    assert lines[i1 + 2:k_end] == ["o9001 if [#<_vmt_g92_on> EQ 1]", "G92.3", "o9001 endif", "M72"]
    head = "\n".join(lines[:k0])
    assert "restored" in head and "stops early" in head
    # the stroke, so the import can bound each touch by it (session 29)
    assert ("(probing stroke: clearance 2 + overtravel 2 mm; each LOG line carries its G38.2 move as G91 G38.2 "
            "words, start to end:)") in lines[:k0]
    g54 = part_program(read_probe_log(plan_path), ProbeSettings(limits_mm=LIMITS_MM), wcs="G54").splitlines()
    assert "G10 L2 P1 X0 Y0 Z0 R0" in g54 and "#<_vmt_wcs_r> = #5230" in g54
    # each probe is followed (after its LOG line) by its retract to the approach start, which preceded it
    for k in probes:
        assert lines[k + 2] == lines[k - 1]
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
    ("1 2 3\n" * 13, "13 probe lines but the plan"),
    ("G1 X1 Y2 Z3\n1 2 3\n", "line 2: G-code words and bare numbers mixed"),
    ("G1 X1 Y2\n", "line 1: no Z word"),
    ("G1 X1 Y2 Z3 X4\n", "line 1: two X words"),
    ("G1 X1 Y2 Z3\nprobe 1 2 3\n", "line 2: 'probe' is not a G-code word"),
    # a file of another kind: named as not a probe file, with what was expected (it said "line 1:
    # 'probe' is not a G-code word", and of a CSV table "'a,b,c' is not a G-code word")
    ("probe 1 2 3\n", "not a LinuxCNC probe file: line 1 is 'probe 1 2 3'; expected a PROBEOPEN file"),
    ("a,b,c\n1,2,3\n", "not a LinuxCNC probe file: line 1 is 'a,b,c'; expected a PROBEOPEN file (3 or 9 "
                        "numbers a line: X Y Z [A B C U V W]) or a LOGOPEN file (lines like 'G1 X1.0 Y2.0 Z-0.5')"),
    ("1,2,3\n", "not a LinuxCNC probe file: line 1 is '1,2,3'"),
    ("# format: probe-log/1\nsetup,target\n", "a probe-log/1 file (vmt's own log), not a LinuxCNC probe file"),
    ("%\n(PROBEOPEN p.txt)\nG38.2 Z-10 F100\n", "a part program (it probes: G38.2), not the probe file it writes"),
    ("G1 X1 Y2 Z3\ng38.3 z-5\n", "a part program (it probes: g38.3)"),
])
def test_linuxcnc_bad_probe_file_one_line_exit_2(tmp_path, plan_path, capsys, body, msg):
    pf = tmp_path / "probe.txt"
    pf.write_text(body)
    out = tmp_path / "log.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert msg in err and err.count("\n") == 1 and str(pf) in err
    assert not out.exists()


def _probe_then_import(tmp_path, plan_path, probe_rc: int):
    """`vmt probe` of the plan on the emulator with a transcript (exit ``probe_rc``), then `vmt import grbl` of
    that transcript: (the live log, the imported log)."""
    tr, out = tmp_path / "session.txt", tmp_path / "live.csv"
    emu = GrblEmulator(scene(), ControllerConfig(home=(0, 0, 50)))
    with TcpServer(emu, time_scale=200.0) as srv:
        assert main(["probe", "--controller", srv.url, "--plan", str(plan_path), "--out", str(out),
                     "--limits-mm", LIMITS, "--safe-z-mm", "30", "--transcript", str(tr)]) == probe_rc
    imp = tmp_path / "imported.csv"
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(imp)]) == 0
    return read_probe_log(out), read_probe_log(imp)


def test_grbl_transcript_of_a_live_campaign_imports_to_the_same_log(tmp_path, plan_path):
    a, b = _probe_then_import(tmp_path, plan_path, 0)
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
    (["a,b,c", "1,2,3"], "no probe reports ([PRB:...]) in it: not a GRBL session transcript"),  # a CSV table
    (["[PRB:1,2,3:1]"] * 5, "5 probe reports but the plan"),
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


def _probe_file(path, pos, fmt="{:f}"):
    with open(path, "w") as f:
        for p in pos:
            f.write(" ".join(fmt.format(v) for v in list(p) + [0.0] * 6) + "\n")


def test_partial_probe_file_keeps_every_touch_and_marks_the_rest(tmp_path, plan_path, measured, capsys):
    """A G38.2 miss stops LinuxCNC: the file holds the touches before it, in plan order."""
    pos = measured.positions_mm()
    pf = tmp_path / "probe.txt"
    _probe_file(pf, pos[:5])
    out = tmp_path / "log.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan_path), "--out", str(out)]) == 0
    assert "5 of 12" in capsys.readouterr().out
    log = read_probe_log(out)
    assert list(log.col("status")) == ["ok"] * 5 + ["aborted"] * 7
    assert np.allclose(log.positions_mm()[:5], pos[:5], atol=1e-6)
    assert np.all(np.isnan(log.positions_mm()[5:]))
    assert "plan row 5" in log.meta["probe_file_rows"]


def test_logopen_file_smartprobe_style(tmp_path, plan_path, measured):
    """smartprobe.ngc logs (LOG,G1 X#5061 Y#5062 Z#5063): 6 decimals, in the program's units."""
    pos = measured.positions_mm()
    pf = tmp_path / "probe-results.ngc"
    lines = [f"G1 X{p[0] / 25.4:f} Y{p[1] / 25.4:f} Z{p[2] / 25.4:f}" for p in pos]
    lines[1] = lines[1].replace(" ", "")                    # words need no spaces
    lines[2] += " (comment)"
    pf.write_text("\n".join(lines) + "\n")
    out = tmp_path / "log.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan_path), "--out", str(out),
                 "--units", "inch"]) == 0
    log = read_probe_log(out)
    assert np.all(log.ok) and np.allclose(log.positions_mm(), pos, atol=25.4e-6)


def test_plan_grid_and_a_planless_import_give_the_same_plan(tmp_path, capsys):
    plan_p = tmp_path / "grid.csv"
    assert main(["plan", "grid", "--x-mm", "0:30:10", "--y-mm=-10:10:10", "--z-mm", "2",
                 "--stylus-r-mm", "1", "--out", str(plan_p)]) == 0
    plan = read_probe_log(plan_p)
    assert plan.n == 12 and plan.is_plan
    assert list(plan.col("target")[:8]) == ["r0c0", "r0c1", "r0c2", "r0c3", "r1c3", "r1c2", "r1c1", "r1c0"]
    assert np.allclose(plan.nominals_mm()[4], [30, 0, 3])              # serpentine; Z = surface + r
    assert np.allclose(plan.normals(), [0, 0, 1]) and np.allclose(plan.col("dz"), -1)
    # a surface 1 um/mm tilted in X, probed: the file alone rebuilds the same targets
    pos = plan.nominals_mm() + np.column_stack([np.zeros((12, 2)), 1e-3 * plan.nominals_mm()[:, 0]])
    pf = tmp_path / "probe.txt"
    _probe_file(pf, pos)
    out = tmp_path / "log.csv"
    assert main(["import", "linuxcnc", str(pf), "--out", str(out)]) == 0
    assert "no plan" in capsys.readouterr().out
    log = read_probe_log(out)
    assert list(log.col("target")) == list(plan.col("target")) and np.all(log.ok)
    assert np.allclose(log.dq_mm(), pos[:, 2] - np.median(pos[:, 2]), atol=1e-9)
    # and vmt fit plane finds the tilt and a flat surface; the file does not say the stylus radius (the plan
    # did): the fit asks for it rather than apply 0 (session 26), and puts the surface one radius below the tips
    js = tmp_path / "plane.json"
    capsys.readouterr()
    assert main(["fit", "plane", str(out), "--json", str(js)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(out) in err and "give --stylus-r-mm R" in err and not js.exists()
    assert main(["fit", "plane", str(out), "--json", str(js), "--stylus-r-mm", "1"]) == 0
    assert "stylus radius 1 mm applied (--stylus-r-mm; the log says none)" in capsys.readouterr().out
    import json
    rep = json.loads(js.read_text())
    n = np.array(rep["values"]["normal"])
    assert abs(n[0] / n[2] + 1e-3) < 1e-6 and rep["form_um"] < 0.01
    # the tip centres' plane (z = 3 + 1e-3 x) moved 1 mm against its normal: the surface
    p0 = np.array(rep["values"]["point_mm"])
    assert abs((p0 - [0, 0, 3]) @ n + 1.0) < 1e-9 and rep["stylus_r_source"] == "given"
    assert len(rep["touches"]) == 12


def test_planless_import_of_scattered_points_and_bad_grids(tmp_path, capsys):
    """review30 F2: without --plan the file was read as a Z grid whatever its points (a pocket's wall touches
    became 83 'points, not a full grid' whose plane fit said 26 mm flatness, exit 0). Points that are not a
    grid's nodes are refused naming --plan; a grid's nodes (a line of them too, repeats too) are read."""
    pf = tmp_path / "probe.txt"
    out = tmp_path / "log.csv"
    _probe_file(pf, [[0, 0, 1], [5, 1, 1.1], [0, 0, 1.05]])            # scattered: 2 of a 2 x 2 grid's nodes
    assert main(["import", "linuxcnc", str(pf), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(pf) in err and "3 touches at 2 XY points on 2 X and 2 Y lines" in err
    assert err.rstrip().endswith("give the plan that was run: --plan PLAN.csv") and not out.exists()
    # a 3 x 2 grid run that stopped after 4 nodes: its last nodes are not known without the plan
    grid = [[0, 0, 1], [10, 0, 1], [20, 0, 1], [20, 5, 1], [10, 5, 1], [0, 5, 1]]
    _probe_file(pf, grid[:4])
    assert main(["import", "linuxcnc", str(pf), "--out", str(out)]) == 2
    assert "are not the 6 nodes of a surface grid" in capsys.readouterr().err
    # the whole grid, with a repeat: read, the repeat sharing its node's target
    _probe_file(pf, grid + [[0, 0, 1.001]])
    assert main(["import", "linuxcnc", str(pf), "--out", str(out)]) == 0
    assert list(read_probe_log(out).col("target")) == ["r0c0", "r0c1", "r0c2", "r1c2", "r1c1", "r1c0", "r0c0"]
    # the note says how the plan was built (it said 'built from the file': the plan's 'plan' key is plan_plan)
    assert "note: no plan: built from 7 touches probed along -Z (grid 3 x 2)" in capsys.readouterr().out
    # one line of nodes is a grid too (vmt plan grid --y-mm 0:0:1)
    _probe_file(pf, grid[:3])
    assert main(["import", "linuxcnc", str(pf), "--out", str(out)]) == 0
    assert list(read_probe_log(out).col("target")) == ["r0c0", "r0c1", "r0c2"]
    for bad, msg in (("0:10:3", "not a whole number of steps"), ("10:0:1", "lo <= hi"),
                     ("0:10", "expected lo:hi:step")):
        assert main(["plan", "grid", "--x-mm", bad, "--y-mm", "0:1:1", "--stylus-r-mm", "0",
                     "--out", str(tmp_path / "g.csv")]) == 2
        assert msg in capsys.readouterr().err
    assert main(["import", "grbl", str(pf), "--out", str(out)]) == 2
    assert "--plan is required" in capsys.readouterr().err


def test_identify_and_discover_name_the_real_reason(tmp_path, capsys):
    plan_p = tmp_path / "grid.csv"
    assert main(["plan", "grid", "--x-mm", "0:30:10", "--y-mm", "0:20:10", "--stylus-r-mm", "0",
                 "--out", str(plan_p)]) == 0
    pf = tmp_path / "probe.txt"
    _probe_file(pf, read_probe_log(plan_p).nominals_mm())
    out = tmp_path / "log.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan_p), "--out", str(out)]) == 0
    capsys.readouterr()
    for cmd in (["identify", str(out), "--json", str(tmp_path / "i.json")],
                ["discover", str(out), "--json", str(tmp_path / "d.json")]):
        assert main(cmd) == 2
        err = capsys.readouterr().err
        assert "no touch has a normal in the XY plane" in err and "vmt fit plane" in err
        assert f"{cmd[0]} needs touches on vertical walls" in err and err.count("\n") == 1


def test_contact_server_answers_like_the_virtual_machine(monkeypatch):
    """The socket vmt_probe.py talks to (hardware/linuxcnc_sim/loop.py), without LinuxCNC."""
    import socket

    from core.exceptions import HardwareError
    from hardware.linuxcnc_sim import loop

    sc = scene()
    srv = loop.ContactServer(sc).start()
    try:
        host, port = srv.address.rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=5) as c:
            f = c.makefile("r")
            c.sendall(b"probe 130 50 1 0 0 -1\nprobe 50 50 40 0 0 1\nhello\n")
            hit, miss, bad = f.readline().split(), f.readline().split(), f.readline().split()
    finally:
        srv.stop()
    ok, q = sc.probe_move(np.array([0.130, 0.050, 0.001]), np.array([0.130, 0.050, 0.001 - loop.RAY_MM * 1e-3]))
    assert hit[0] == "hit" and ok and np.allclose([float(v) for v in hit[1:]], q * 1e3, atol=1e-9)
    assert miss == ["miss"] and bad == ["miss"] and "hello" in srv.error
    assert len(srv.answers) == 2 and srv.answers[1]["q_mm"] is None
    assert loop.resolution_mm(30.0) == pytest.approx(0.5e-3)          # 30 mm/min x 1 ms
    monkeypatch.setattr(loop.shutil, "which", lambda name: None)
    with pytest.raises(HardwareError, match="apt-get install -y linuxcnc-uspace"):
        loop.linuxcnc_path()


def test_grbl_import_refuses_units_it_would_ignore(tmp_path, capsys):
    """'vmt import grbl T --units inch' read the transcript's reports as mm regardless (main: exit 0,
    every touch 25.4 times too small were the reports in inches); --units is LinuxCNC's."""
    plan_path = write_probe_log(tmp_path / "plan.csv", plan_log(n_sphere=0))
    tr = tmp_path / "t.txt"
    tr.write_text("\n".join(["[PRB:10.000,10.000,0.001:1]", "[PRB:90.000,10.000,-0.002:1]",
                             "[PRB:90.000,90.000,0.000:1]", "[PRB:10.000,90.000,0.000:1]"]) + "\n")
    out = tmp_path / "o.csv"
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(out), "--units", "inch"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--units is for LinuxCNC probe files" in err and not out.exists()
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(out)]) == 0   # without: as before


# ---------------------------------------------------------------- a GRBL run that stopped (session 26)
REF = Path(__file__).parent / "data" / "grbl-1.1h"


def _cut(lines, upto, tail=()):
    """The first ``upto`` lines of a recorded transcript, then ``tail`` (text lines, timestamped after it)."""
    head = lines[:upto]
    t = float(head[-1].split(" ", 1)[0])
    return head + [f"{t + 0.05 * (i + 1):.3f} {x}" for i, x in enumerate(tail)]


def _import(tmp_path, lines, plan, capsys):
    tr, plan_path, out = tmp_path / "t.txt", tmp_path / "plan.csv", tmp_path / "log.csv"
    tr.write_text("\n".join(lines) + "\n")
    write_probe_log(plan_path, plan)
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(out)]) == 0
    return read_probe_log(out), capsys.readouterr().out


def test_grbl_miss_transcript_of_the_real_firmware_imports_with_the_whole_plan(tmp_path, capsys):
    """GRBL 1.1h's own G38.2 miss (the plan's third row 10 mm up): ALARM:5, the stale [PRB:...:0], error:9.

    Before session 26 the import refused it ("3 probe reports but the plan has 12 rows"): a stopped run could not
    be imported. Now it is what the LinuxCNC import makes of a short probe file: the two touches and the miss as
    the transcript has them, the nine rows never probed kept as ``aborted`` with empty measured cells, and the
    alarm that stopped the run named in the metadata and on screen."""
    lines = (REF / "grbl-1.1h-sim-g38.2-miss-transcript.txt").read_text().splitlines()
    log, out = _import(tmp_path, lines, plan_log(miss_rows=(2,)), capsys)
    assert list(log.col("status")) == ["ok", "ok", "no_trigger"] + ["aborted"] * 9
    assert log.positions_mm()[:2].tolist() == [[10.0, 10.0, 0.0], [90.0, 10.0, 0.0]]   # the PRB digits
    assert np.all(np.isnan(log.positions_mm()[2:])) and np.all(np.isnan(log.columns["t_s"][2:]))
    alarm_line = 1 + next(i for i, x in enumerate(lines) if x.endswith("< ALARM:5"))
    assert alarm_line == 38
    assert log.meta["stop_reason"].startswith("ALARM:5 (probe did not contact")
    assert log.meta["stop_reason"].endswith(f"at line {alarm_line}")
    assert log.meta["transcript_reports"].startswith("3 of 12: the run stopped at plan row 2 (target 'p2'")
    assert "rows 3..11 not measured (aborted)" in log.meta["transcript_reports"]
    assert "note: what stopped it: ALARM:5" in out and "3 of 12" in out
    assert log.meta["artefact"] == "table+sphere" and log.meta["stylus_r_mm"] == "1.5"   # the plan's kept


# the campaign transcript (12 touches, all triggered) cut after the G38.2 of plan row 5 (its line 70), then what
# GRBL 1.1h answered in the same state in tests/hardware/data/grbl-1.1h/recorded-*.txt
@pytest.mark.parametrize("tail, first, reason", [
    ([], "aborted", "the transcript ends at line 70 without an alarm, during the probing move sent at line 70"),
    (["< ALARM:4", "< ok"], "early_trigger", "ALARM:4 (probe not in the expected state"),     # probe_closed
    (["< ALARM:5"], "no_trigger", "ALARM:5 (probe did not contact"),           # cut in the 0.5 s alarm delay
    (["> \x18", "< ALARM:3", "< ok", "< Grbl 1.1h ['$' for help]", "< [MSG:'$H'|'$X' to unlock]"],   # motion
     "alarm", "ALARM:3 (reset while in motion"),
    (["> ^X", "< ALARM:3", "< ok", "< Grbl 1.1h ['$' for help]"], "alarm", "ALARM:3 (reset while in motion"),
])
def test_grbl_run_stopped_during_a_touch(tmp_path, capsys, tail, first, reason):
    lines = (REF / "grbl-1.1h-sim-vmt-campaign-transcript.txt").read_text().splitlines()
    assert "G38.2" in lines[69] and "[PRB" in lines[59]
    log, out = _import(tmp_path, _cut(lines, 70, tail), plan_log(), capsys)
    assert list(log.col("status")) == ["ok"] * 5 + [first] + ["aborted"] * 6
    prb = [parse_prb(x.split(" ", 2)[2])[0] for x in lines[:70] if "[PRB" in x]
    assert np.array_equal(log.positions_mm()[:5], np.array(prb))
    assert log.meta["stop_reason"].startswith(reason)
    assert log.meta["transcript_reports"].startswith("5 of 12: the run stopped "
                                                     + ("after plan row 4" if first == "aborted"
                                                        else f"at plan row 5 (target 's1', {first})"))
    assert "note: what stopped it" in out


def test_grbl_run_stopped_between_touches(tmp_path, capsys):
    """A soft-limit alarm on a positioning move (no probing command sent since the last report): the touch was
    not under way, so row 5 is ``aborted``, not ``alarm``; an error and an idle reset name themselves."""
    lines = (REF / "grbl-1.1h-sim-vmt-campaign-transcript.txt").read_text().splitlines()
    assert "G53 G90 G1" in lines[67]
    log, _ = _import(tmp_path, _cut(lines, 68, ["< ALARM:2", "< [MSG:Reset to continue]"]), plan_log(), capsys)
    assert list(log.col("status")) == ["ok"] * 5 + ["aborted"] * 7
    assert log.meta["stop_reason"].startswith("ALARM:2 (soft limit")
    log, _ = _import(tmp_path, _cut(lines, 68, ["> G90", "< error:9"]), plan_log(), capsys)
    assert log.meta["stop_reason"].startswith("error:9 (") and "after plan row 4" in log.meta["transcript_reports"]
    log, _ = _import(tmp_path, _cut(lines, 68, ["> ^X", "< Grbl 1.1h ['$' for help]"]), plan_log(), capsys)
    assert log.meta["stop_reason"] == "the controller was reset at line 69"
    log, _ = _import(tmp_path, lines[:68], plan_log(), capsys)
    assert log.meta["stop_reason"] == "the transcript ends at line 68 without an alarm (a lost connection, " \
                                      "or the sender stopped)"


def test_grbl_resumed_session_in_one_transcript_is_whole(tmp_path, capsys):
    """`vmt probe --transcript` appends: a run stopped by the miss, then resumed, is one transcript with one
    report per row; the alarm in its middle does not stop the import."""
    miss = (REF / "grbl-1.1h-sim-g38.2-miss-transcript.txt").read_text().splitlines()
    camp = (REF / "grbl-1.1h-sim-vmt-campaign-transcript.txt").read_text().splitlines()
    k = 1 + max(i for i, x in enumerate(camp) if "[PRB" in x and i < 40)      # the campaign's 3 first touches
    shift = float(miss[-1].split(" ", 1)[0]) + 60.0 - float(camp[k].split(" ", 1)[0])   # resumed a minute later
    rest = [f"{float(x.split(' ', 1)[0]) + shift:.3f} {x.split(' ', 1)[1]}" for x in camp[k:]]
    log, out = _import(tmp_path, miss + rest, plan_log(miss_rows=(2,)), capsys)
    assert list(log.col("status")) == ["ok", "ok", "no_trigger"] + ["ok"] * 9
    assert "stop_reason" not in log.meta and "note:" not in out


def test_grbl_live_run_stopped_by_a_miss_imports_to_the_same_rows(tmp_path):
    """End to end through the emulator: `vmt probe` stops at the miss (exit 2, the rows before it and the miss on
    disk); its transcript imports to the same rows, digit for digit, and the plan's rest as aborted."""
    plan_path = write_probe_log(tmp_path / "plan.csv", plan_log(miss_rows=(6,)))
    a, b = _probe_then_import(tmp_path, plan_path, 2)
    assert a.n == 7 and b.n == 12
    assert list(b.col("status")) == list(a.col("status")) + ["aborted"] * 5 == ["ok"] * 6 + ["no_trigger"] + \
        ["aborted"] * 5
    assert np.array_equal(a.positions_mm(), b.positions_mm()[:7], equal_nan=True)
    assert b.meta["stop_reason"].startswith("ALARM:5")


def test_live_log_keeps_the_controllers_digits(tmp_path):
    """A GRBL report of -3.937 mm was logged -3.9369999999999994 by `vmt probe` (the backend's metres divided
    back into mm; about 1.5 % of 3-decimal values move by a unit in the last place so), while `vmt import grbl`
    of the same session's transcript wrote -3.937: the live log and the import disagreed in 10 of 368 touches of
    the README's cross-pocket run (session 26). The log now writes the report's own numbers."""
    plan = plan_log(n_sphere=0)
    xy = np.array([[10.0, -3.937], [-15.996, 10.0], [43.271, 7.852], [87.275, 43.264]])
    assert all((v * 1e-3) / 1e-3 != v for v in (-3.937, -15.996))       # values the metre trip moves
    plan.columns["Xn_mm"][:], plan.columns["Yn_mm"][:] = xy[:, 0], xy[:, 1]
    plan_path = write_probe_log(tmp_path / "plan.csv", plan)
    tr, out = tmp_path / "session.txt", tmp_path / "live.csv"
    emu = GrblEmulator(scene(), ControllerConfig(home=(0, 0, 50)))
    with TcpServer(emu, time_scale=200.0) as srv:
        assert main(["probe", "--controller", srv.url, "--plan", str(plan_path), "--out", str(out),
                     "--limits-mm", LIMITS, "--safe-z-mm", "30", "--transcript", str(tr)]) == 0
    prb = np.array([parse_prb(x.split(" ", 2)[2])[0][:3] for x in tr.read_text().splitlines() if "[PRB" in x])
    live = read_probe_log(out).positions_mm()
    assert np.array_equal(live, prb) and np.array_equal(live[:, :2], xy)
    imp = tmp_path / "imported.csv"
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(imp)]) == 0
    assert np.array_equal(read_probe_log(imp).positions_mm(), live)


def test_grbl_run_stopped_at_its_first_touch_is_named(tmp_path, capsys):
    """No report at all: nothing measured (a log of it would read as a plan, as LinuxCNC's empty probe file is
    refused); the refusal names the alarm that stopped the first touch instead of 'not a GRBL transcript'."""
    lines = (REF / "grbl-1.1h-sim-vmt-campaign-transcript.txt").read_text().splitlines()
    assert "G38.2" in lines[14] and not any("[PRB" in x for x in lines[:15])
    tr, plan_path = tmp_path / "t.txt", write_probe_log(tmp_path / "plan.csv", plan_log())
    tr.write_text("\n".join(_cut(lines, 15, ["< ALARM:4", "< ok"])) + "\n")
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the run stopped at its first touch, ALARM:4 (probe not in the expected" in err
    assert "at line 16; nothing measured to import" in err and not (tmp_path / "o.csv").exists()


# ---------------------------------------------------------------- reports on their rows' approach lines (session 26)

def _prb_rows(lines):
    return [i for i, x in enumerate(lines) if "[PRB" in x]


def test_grbl_repeated_touch_after_a_resume_is_dropped_not_shifted(tmp_path, capsys):
    """`vmt probe` killed after row 3's report reached the transcript but before the log's fsync: --resume probes
    row 3 again, so the transcript holds one report too many; the run then stops after row 7. Main mapped every
    report after the repeat one row off (row 4 got row 3's touch, ..., exit 0, no word). Now the repeat lies on row
    3's approach line, not row 4's: the first is dropped with a note and every row keeps its own touch."""
    lines = (REF / "grbl-1.1h-sim-vmt-campaign-transcript.txt").read_text().splitlines()
    prb = _prb_rows(lines)
    assert len(prb) == 12
    rep = lines[:prb[3] + 1] + [lines[prb[3]]] + lines[prb[3] + 1:prb[7] + 1]    # row 3 twice, then stops at 7
    log, out = _import(tmp_path, rep, plan_log(), capsys)
    want = [parse_prb(lines[i].split(" ", 2)[2])[0] for i in prb[:8]]
    assert list(log.col("status")) == ["ok"] * 8 + ["aborted"] * 4
    assert np.array_equal(log.positions_mm()[:8], np.array(want))
    said = f"lines {prb[3] + 1} and {prb[3] + 2} both report plan row 3 (target "
    assert log.meta["transcript_repeats"].startswith(said) and f"note: {said}" in out
    assert "the first dropped" in log.meta["transcript_repeats"]


def test_grbl_report_off_its_row_is_refused_naming_the_line(tmp_path, capsys):
    """A report lost (row 2's line removed): every later report would fill the row before its own. Refused at the
    first report that is not its row's touch, with its distance from the row's approach line."""
    lines = (REF / "grbl-1.1h-sim-vmt-campaign-transcript.txt").read_text().splitlines()
    prb = _prb_rows(lines)
    cut = lines[:prb[2]] + lines[prb[2] + 1:]
    tr, plan_path, out = tmp_path / "t.txt", tmp_path / "plan.csv", tmp_path / "log.csv"
    tr.write_text("\n".join(cut) + "\n")
    write_probe_log(plan_path, plan_log())
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert re.search(rf"line {prb[3]}: report 3 \[[-\d., ]+\] mm is not a touch of plan row 2 \(target 'p2', "
                     r"nominal \[[-\d., ]+\] mm\): [\d.]+ mm off its approach line", err), err
    # the bound along the line: the transcript's own G91 G38.2 move (Z-4: clearance + overtravel), session 29
    assert "within 0.5 mm of the line and 4 mm of the nominal: the stroke of the G38 move sent at line " in err
    assert not out.exists()


def test_row_offset_known_answers():
    """Lateral and along distances of a report from a row, by hand: nominal (10, 0, 0), approach -z."""
    from hardware.transcript import ALIGN_LATERAL_MM, _on_row, _row_offset

    pn, d = np.array([10.0, 0.0, 0.0]), np.array([0.0, 0.0, -2.0])      # (not unit: normalised)
    assert np.allclose(_row_offset([10.0, 0.0, -1.5], pn, d), (0.0, 1.5))
    assert np.allclose(_row_offset([13.0, 4.0, 1.0], pn, d), (5.0, -1.0))
    assert _on_row([10.0 + ALIGN_LATERAL_MM, 0.0, -2.0], pn, d)
    assert not _on_row([10.0 + ALIGN_LATERAL_MM + 1e-6, 0.0, -2.0], pn, d)
    assert not _on_row([10.0, 0.0, -10.5], pn, d) and _on_row([10.0, 0.0, -10.0], pn, d)
    assert np.allclose(_row_offset([13.0, 4.0, 0.0], pn, np.full(3, np.nan)), (0.0, 5.0))   # no direction


def test_a_huge_grid_is_refused_before_any_array_is_made(tmp_path, capsys):
    """``plan grid --x-mm 0:1e9:1`` took 49 s and 15.6 GB before its count was refused (the fuzz test's case 113,
    session 26): the count is checked from the range itself. A range of 1e12 nodes would ask numpy for 8 TB and
    fail with MemoryError, not this refusal, without the check."""
    from core.exceptions import ConfigError
    from hardware.surface import MAX_GRID_TOUCHES, axis_nodes, grid_plan

    with pytest.raises(ConfigError, match=r"--x-mm 0:1e\+12:1: 1000000000001 nodes, more than 100000 touches"):
        axis_nodes(0.0, 1e12, 1.0, "--x-mm")
    assert axis_nodes(0.0, MAX_GRID_TOUCHES - 1.0, 1.0, "--x-mm").size == MAX_GRID_TOUCHES
    with pytest.raises(ConfigError, match="more than 100000 touches"):
        grid_plan((0.0, 1e12, 1.0), (0.0, 20.0, 10.0), stylus_r_mm=1.0)
    rc = main(["plan", "grid", "--x-mm", "0:1e12:1", "--y-mm", "0:20:10", "--out", str(tmp_path / "p.csv"),
               "--stylus-r-mm", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "more than 100000 touches" in err[0], err
    assert not (tmp_path / "p.csv").exists()


# ----------------------------------------------------------------- probe-file lines checked on their rows
# review28's repro (/tmp/review28/bad): two touches planned at the same point, then three more along X
DUP_PLAN = """# format: probe-log/1
# artefact: surface
# stylus_r_mm: 1.5
setup,target,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz,feature,dx,dy,dz
grid,r0c0,,,,,0.0,0.0,1.5,0.0,0.0,1.0,surface,0.0,0.0,-1.0
grid,r0c0b,,,,,0.0,0.0,1.5,0.0,0.0,1.0,surface,0.0,0.0,-1.0
grid,r0c1,,,,,10.0,0.0,1.5,0.0,0.0,1.0,surface,0.0,0.0,-1.0
grid,r0c2,,,,,20.0,0.0,1.5,0.0,0.0,1.0,surface,0.0,0.0,-1.0
grid,r0c3,,,,,30.0,0.0,1.5,0.0,0.0,1.0,surface,0.0,0.0,-1.0
"""
#: the two touches at r0c0 tripped at the same position: LinuxCNC's PROBEOPEN file has one line for both
DUP_TXT = "0.000000 0.000000 1.500200\n10.000000 0.000000 1.500400\n20.000000 0.000000 1.500600\n" \
          "30.000000 0.000000 1.500800\n"
#: a first line nowhere near its row (123, -77, 9) for a touch planned at (0, 0, 1.5) along -Z
WRONG_TXT = "123.000000 -77.000000 9.000000\n10.000000 0.000000 1.500400\n20.000000 0.000000 1.500600\n" \
            "30.000000 0.000000 1.500800\n0 0 1.5\n"


@pytest.mark.parametrize("body, msg", [
    # before session 28: exit 0, r0c0b booked (10, 0) and so on, r0c3 'aborted' blaming a stopped program
    (DUP_TXT, "line 2: [10, 0, 1.5004] mm is not a touch of plan row 1 (target 'r0c0b', nominal [0, 0, 1.5] mm): "
              "10.000 mm off its approach line"),
    # before: exit 0, every row ok, r0c0 at (123, -77, 9) and r0c3 at (0, 0, 1.5)
    (WRONG_TXT, "line 1: [123, -77, 9] mm is not a touch of plan row 0 (target 'r0c0', nominal [0, 0, 1.5] mm): "
                "145.114 mm off its approach line, -7.500 mm along it"),
])
def test_probe_file_line_off_its_row_is_refused_naming_line_and_row(tmp_path, capsys, body, msg):
    plan = tmp_path / "dup.csv"
    plan.write_text(DUP_PLAN)
    pf = tmp_path / "dup.txt"
    pf.write_text(body)
    out = tmp_path / "imp.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert msg in err and err.count("\n") == 1 and str(pf) in err, err
    assert not out.exists()
    if body == DUP_TXT:    # the likely cause named: LinuxCNC's PROBEOPEN skips a repeated position
        assert "it lies on row 2's line: the lines are one row early" in err and "PROBEOPEN line" in err


def _log_lines(pos, rows):
    """A vmt machine program's LOGOPEN file: ``N<row> G1 X.. Y.. Z..`` as LinuxCNC expands its LOG lines
    (``%lf``: 6 decimals)."""
    return "".join(f"N{r} G1 X{p[0]:f} Y{p[1]:f} Z{p[2]:f}\n" for r, p in zip(rows, pos))


def test_numbered_log_file_keeps_a_repeated_touch_on_its_own_row(tmp_path, capsys):
    """The same run as DUP_TXT, logged by the session-28 program: a line per probe, the repeat included."""
    plan = tmp_path / "dup.csv"
    plan.write_text(DUP_PLAN)
    pos = np.array([[0, 0, 1.5002], [0, 0, 1.5002], [10, 0, 1.5004], [20, 0, 1.5006], [30, 0, 1.5008]])
    pf = tmp_path / "dup.log"
    pf.write_text(_log_lines(pos, range(5)))
    out = tmp_path / "imp.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan), "--out", str(out)]) == 0
    log = read_probe_log(out)
    assert list(log.col("status")) == ["ok"] * 5 and np.array_equal(log.positions_mm(), pos)
    assert "probe_file_rows" not in log.meta
    # a run stopped at row 3 (a miss): three numbered lines, the rest aborted; no word of PROBEOPEN's skips
    pf.write_text(_log_lines(pos[:3], range(3)))
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan), "--out", str(out)]) == 0
    log = read_probe_log(out)
    assert list(log.col("status")) == ["ok"] * 3 + ["aborted"] * 2
    assert "3 of 5" in log.meta["probe_file_rows"] and "PROBEOPEN" not in log.meta["probe_file_rows"]
    assert log.meta["probe_file_rows"] == ("lines for 3 of 5 plan rows: the program stopped at plan row 3 (a G38.2 "
                                           "miss or an abort; its LOG lines numbered 0..2, one per probe); rows "
                                           "3..4 marked aborted; to continue: vmt machine program --from-row 3 "
                                           "(appends to this file: keep it)")


def test_short_probeopen_file_says_a_repeated_position_leaves_no_line(tmp_path, plan_path, measured, capsys):
    """A PROBEOPEN file one line short whose lines all fit their rows: a stopped run, or the last touch at the
    previous one's position (nothing in the file tells them apart); the note says both, neither as the fact
    (session 28's opened with "the program stopped at plan row k"), and that a numbered LOGOPEN file tells."""
    pf = tmp_path / "probe.txt"
    _probe_file(pf, measured.positions_mm()[:11])
    note = import_probe_file(pf, read_probe_log(plan_path)).meta["probe_file_rows"]
    assert note.startswith("lines for 11 of 12 plan rows: the program stopped at plan row 11 (a G38.2 miss or an "
                           "abort), or touches at a repeated position left no line (LinuxCNC writes no PROBEOPEN "
                           "line for a probe at exactly the position of the last line it wrote: the previous "
                           "probe's"), note
    assert "a PROBEOPEN file does not tell which (a LOGOPEN file of vmt machine program's, a line per probe " \
        "numbered by its row, does)" in note and note.endswith("row 11 marked aborted")
    # the case itself: the plan's last two rows at one point, touched at exactly one position (DUP_PLAN's
    # rows 0-1 moved to its end): LinuxCNC wrote 4 lines for 5 rows, nothing stopped
    plan = tmp_path / "end.csv"
    head, rows = DUP_PLAN.split("feature,dx,dy,dz\n")
    rows = rows.splitlines()
    plan.write_text(head + "feature,dx,dy,dz\n" + "\n".join(rows[2:] + rows[:2]) + "\n")
    pf.write_text("10.000000 0.000000 1.500400\n20.000000 0.000000 1.500600\n30.000000 0.000000 1.500800\n"
                  "0.000000 0.000000 1.500200\n")
    out = tmp_path / "end-log.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan), "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "note: the probe file has lines for 4 of 5 plan rows: the program stopped at plan row 4 (a G38.2 " \
        "miss or an abort), or touches at a repeated position left no line" in said, said
    assert list(read_probe_log(out).col("status")) == ["ok"] * 4 + ["aborted"]


@pytest.mark.parametrize("rows, change, msg", [
    ([0, 2, 3], None, "line 2: N2, but it is probe line 2, plan row 1's: a line is missing or repeated"),
    ([0, 1, 1], None, "line 3: N1, but it is probe line 3, plan row 2's: a line is missing or repeated"),
    ([1, 2, 3], None, "line 1: N1, but it is probe line 1, plan row 0's"),
    ([0, 1, 12], None, "line 3: N12, but it is probe line 3, plan row 2's: row 12 is beyond the plan's 12 rows"),
    ([0, 1, 2], ("N1 ", "N1.5 "), "line 2: N1.5: the plan row must be a whole number >= 0"),
    ([0, 1, 2], ("N1 ", "N-1 "), "line 2: N-1: the plan row must be a whole number >= 0"),
    ([0, 1, 2], ("N1 ", ""), "line 2: an N word (the plan row) on some lines and not on others"),
    # X given a leading 1 (90 -> 190 mm): numbered right, but off its row's line
    ([0, 1, 2], ("N1 G1 X", "N1 G1 X1"), "is not a touch of plan row 1 (target 'p1'"),
])
def test_numbered_log_file_bad_rows_one_line_exit_2(tmp_path, plan_path, measured, capsys, rows, change, msg):
    pf = tmp_path / "probe.log"
    text = _log_lines(measured.positions_mm()[:3], rows)
    if change:
        text = text.replace(*change, 1)
    pf.write_text(text)
    out = tmp_path / "log.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert msg in err and err.count("\n") == 1 and str(pf) in err, err
    assert not out.exists()


# ------------------------------------------------ the along-the-line bound: the program's own stroke (session 29)
def _long_stroke_transcript(z_report: str, g38: str = "G91 G38.2 X0.0000 Y0.0000 Z-24.0000"):
    """The real GRBL 1.1h campaign, its first probe sent with a 24 mm stroke (start Z2, end Z-22: clearance 2 +
    overtravel 22) and its report at ``z_report`` (the plan's nominal: Z 0)."""
    lines = (REF / "grbl-1.1h-sim-vmt-campaign-transcript.txt").read_text().splitlines()
    i = next(k for k, x in enumerate(lines) if "G38.2" in x)
    j = _prb_rows(lines)[0]
    assert lines[i].endswith("> G91 G38.2 X0.0000 Y0.0000 Z-4.0000 F200.0") and j == i + 1
    assert lines[j].endswith("< [PRB:10.000,10.000,0.000:1]")
    lines[i] = lines[i].replace("G91 G38.2 X0.0000 Y0.0000 Z-4.0000", g38)
    lines[j] = lines[j].replace("10.000,10.000,0.000", f"10.000,10.000,{z_report}")
    return lines


def _grbl_import(tmp_path, lines, *opts):
    tr, plan_path, out = tmp_path / "t.txt", tmp_path / "plan.csv", tmp_path / "log.csv"
    tr.write_text("\n".join(lines) + "\n")
    write_probe_log(plan_path, plan_log())
    return main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(out), *opts]), out


def test_grbl_long_stroke_touch_is_its_rows_by_the_transcripts_own_stroke(tmp_path, capsys):
    """A touch 11 mm beyond its nominal, probed with a 24 mm stroke the transcript itself sent (G91 G38.2
    Z-24): refused before session 29 (the bound was 10 mm whatever the stroke), its row's now. Off its line, or
    beyond the stroke, still refused, the message naming the bound and where it is from."""
    rc, out = _grbl_import(tmp_path, _long_stroke_transcript("-11.000"))
    assert rc == 0 and read_probe_log(out).positions_mm()[0, 2] == -11.0
    capsys.readouterr()
    out.unlink()
    for z, x, what in (("-11.000", "15.000", "5.000 mm off its approach line, +11.000 mm along it"),
                       ("-30.000", "10.000", "0.000 mm off its approach line, +30.000 mm along it")):
        lines = [ln.replace("[PRB:10.000,10.000,", f"[PRB:{x},10.000,") for ln in _long_stroke_transcript(z)]
        rc, out = _grbl_import(tmp_path, lines)
        err = capsys.readouterr().err
        assert rc == 2 and err.count("\n") == 1 and what in err, err
        assert "within 0.5 mm of the line and 24 mm of the nominal: the stroke of the G38 move sent at line 15" \
            in err and not out.exists()


def test_grbl_probe_move_sent_without_spaces_is_a_probing_move(tmp_path):
    """GRBL strips spaces, so a sender may write ``G91G38.2Z-24``: it is a probing move (its stroke read as with
    spaces; a word boundary before G38 missed it: no stroke, the 10 mm fallback refused the 11 mm touch)."""
    lines = _long_stroke_transcript("-11.000", g38="G91G38.2X0.0000Y0.0000Z-24.0000")
    rc, out = _grbl_import(tmp_path, lines)
    assert rc == 0 and read_probe_log(out).positions_mm()[0, 2] == -11.0


def test_grbl_absolute_probe_moves_take_the_programs_stroke_from_the_options(tmp_path, capsys):
    """A sender's absolute G38.2 (no G91: where it started is not on its line) does not say its stroke: the
    10 mm fallback refuses the long stroke's touch and says how to give the stroke; --clearance-mm 2
    --overtravel-mm 22 (the program's) accept it."""
    lines = _long_stroke_transcript("-11.000", g38="G90 G38.2 X10.0000 Y10.0000 Z-22.0000")
    rc, out = _grbl_import(tmp_path, lines)
    err = capsys.readouterr().err
    assert rc == 2 and "+11.000 mm along it (a touch lies within 0.5 mm of the line and 10 mm of the nominal: " \
        "the program's stroke not known, its G38 move is not relative (G91) in the transcript: give vmt import " \
        "the program's --clearance-mm and --overtravel-mm)" in err, err
    rc, out = _grbl_import(tmp_path, lines, "--clearance-mm", "2", "--overtravel-mm", "22")
    assert rc == 0 and read_probe_log(out).positions_mm()[0, 2] == -11.0


#: Rows on one approach line (a step probed down Z at one XY): row 1's nominal 3 mm below row 0's
STEP_PLAN = """# format: probe-log/1
# artefact: surface
# stylus_r_mm: 1.5
setup,target,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz,feature,dx,dy,dz
grid,upper,,,,,0.0,0.0,4.5,0.0,0.0,1.0,surface,0.0,0.0,-1.0
grid,lower,,,,,0.0,0.0,1.5,0.0,0.0,1.0,surface,0.0,0.0,-1.0
grid,far,,,,,40.0,0.0,1.5,0.0,0.0,1.0,surface,0.0,0.0,-1.0
"""


def test_linuxcnc_bound_along_the_line_is_the_programs_stroke(tmp_path, capsys):
    """LinuxCNC's probe file does not say the stroke: vmt import takes the program's --clearance-mm and
    --overtravel-mm. A long stroke (12 + 12 mm): a touch 11 mm beyond its nominal refused by the 10 mm
    fallback (before session 29, always), its row's with the stroke; 30 mm beyond still refused. A short
    stroke (0.5 + 0.5 mm): a PROBEOPEN file of one line, the lower step's touch (3 mm along row 0's line, where
    a 1 mm stroke cannot reach: another run's file), passed the 10 mm bound as row 0's, wrong row; refused
    with the stroke."""
    plan = tmp_path / "step.csv"
    plan.write_text(STEP_PLAN)
    pf, out = tmp_path / "probe.log", tmp_path / "imp.csv"
    args = ["import", "linuxcnc", str(pf), "--plan", str(plan), "--out", str(out)]
    pos = np.array([[0.0, 0.0, 4.5002], [0.0, 0.0, -9.5], [40.0, 0.0, 1.5001]])   # lower: 11 mm beyond
    pf.write_text(_log_lines(pos, range(3)))
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "line 2: [0, 0, -9.5] mm is not a touch of plan row 1 (target 'lower'" in err and \
        "+11.000 mm along it (a touch lies within 0.5 mm of the line and 10 mm of the nominal: the program's " \
        "stroke not known, give vmt import the program's --clearance-mm and --overtravel-mm)" in err, err
    assert main(args + ["--clearance-mm", "12", "--overtravel-mm", "12"]) == 0
    assert np.array_equal(read_probe_log(out).positions_mm(), pos)
    pos[1, 2] = 1.5 - 30.0
    pf.write_text(_log_lines(pos, range(3)))
    out.unlink()
    assert main(args + ["--clearance-mm", "12", "--overtravel-mm", "12"]) == 2
    err = capsys.readouterr().err
    assert "+30.000 mm along it (a touch lies within 0.5 mm of the line and 24 mm of the nominal: the program's " \
        "stroke, clearance 12 + overtravel 12 mm)" in err and not out.exists(), err
    # the short stroke: the lower step's touch read as row 0's (the upper step's)
    pf = tmp_path / "probe.txt"
    pf.write_text("0.000000 0.000000 1.500200\n")
    args = ["import", "linuxcnc", str(pf), "--plan", str(plan), "--out", str(out)]
    assert main(args) == 0 and read_probe_log(out).positions_mm()[0, 2] == 1.5002     # wrong row, no word
    capsys.readouterr()
    out.unlink()
    assert main(args + ["--clearance-mm", "0.5", "--overtravel-mm", "0.5"]) == 2
    err = capsys.readouterr().err
    assert "line 1: [0, 0, 1.5002] mm is not a touch of plan row 0 (target 'upper'" in err and \
        "+2.9998 mm along it" not in err and "+3.000 mm along it (a touch lies within 0.5 mm of the line and " \
        "1 mm of the nominal: the program's stroke, clearance 0.5 + overtravel 0.5 mm)" in err, err
    assert not out.exists()


@pytest.mark.parametrize("opts, msg", [
    (["--clearance-mm", "-1"], "--clearance-mm must be a finite number >= 0 (the program's, mm), got -1.0"),
    (["--overtravel-mm", "nan"], "--overtravel-mm must be a finite number >= 0"),
    (["--clearance-mm", "0", "--overtravel-mm", "0"], "--clearance-mm and --overtravel-mm are both 0"),
])
def test_import_stroke_options_bad_values_one_line_exit_2(tmp_path, capsys, opts, msg):
    plan = tmp_path / "step.csv"
    plan.write_text(STEP_PLAN)
    pf = tmp_path / "probe.txt"
    pf.write_text("0.000000 0.000000 4.500200\n")
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan), "--out", str(tmp_path / "o.csv"), *opts]) == 2
    err = capsys.readouterr().err
    assert msg in err and err.count("\n") == 1, err


def test_program_stroke_and_transcript_strokes_known_answers(tmp_path):
    """program_stroke: the one option not given takes the program's default 2 mm; the transcript's stroke:
    a relative probing move's length (mm; G20: inches converted), none for an absolute one."""
    from hardware.transcript import ALIGN_ALONG_SLACK_MM, along_bound, program_stroke, read_session

    assert program_stroke(None, None) is None and along_bound(None) == 10.0
    assert program_stroke(None, 8.0).mm == 10.0 and program_stroke(3.0, None).mm == 5.0
    assert along_bound(program_stroke(0.5, 0.5)) == 1.0 + ALIGN_ALONG_SLACK_MM
    tr = tmp_path / "t.txt"
    tr.write_text("> G91 G38.2 X3 Y-4 F100\n< [PRB:1.000,2.000,3.000:1]\n> G90 G38.2 X1 Y2 Z3\n"
                  "< [PRB:1.000,2.000,3.000:1]\n> G20\n> G91 G38.2 Z-0.5\n< [PRB:1.000,2.000,3.000:1]\n")
    s = read_session(tr)
    assert s.probing == [1, 3, 6] and s.strokes[0] == 5.0 and s.strokes[1] is None
    assert s.strokes[2] == pytest.approx(12.7, abs=1e-12)
INCH_TRANSCRIPT = """1000.000 > $$
1000.010 < $13=1
1000.011 < ok
1000.100 > G91 G38.2 X0.0000 Y0.0000 Z-4.0000 F300.0
1003.000 < [PRB:0.0000,0.0000,0.0669:1]
1003.001 < ok
1004.100 > G91 G38.2 X0.0000 Y0.0000 Z-4.0000 F300.0
1007.000 < [PRB:0.0000,0.0079,0.0669:1]
1007.001 < ok
"""
INCH_PLAN = make_log({"setup": ["s1", "s1"], "target": ["p0", "p1"], "t_s": [np.nan] * 2,
                      "X_mm": [np.nan] * 2, "Y_mm": [np.nan] * 2, "Z_mm": [np.nan] * 2,
                      "Xn_mm": [0.0, 0.0], "Yn_mm": [0.0, 0.2], "Zn_mm": [1.5, 1.5],
                      "nx": [0.0, 0.0], "ny": [0.0, 0.0], "nz": [1.0, 1.0]}, meta={"stylus_r_mm": "1.5"})


@pytest.mark.parametrize("edit, msg", [
    (lambda t: t, "line 5: the probe report is in inches (the controller's $13=1, report inches, line 2)"),
    (lambda t: t.replace("< $13=1", "$13=1 (report inches, bool)"), "(the controller's $13=1, report inches, line 2)"),
    (lambda t: t.replace("< $13=1", "> $13=1"), "line 5: the probe report is in inches"),       # the setting sent
    (lambda t: t.replace("< $13=1", "< $13=x"), "line 5: the controller's $13 (report inches, line 2) is 'x', not a"),
])
def test_grbl_transcript_with_inch_reports_is_refused_naming_the_setting(tmp_path, capsys, edit, msg):
    """The review's transcript: $$ shows $13=1, so GRBL printed [PRB:...] in inches
    (report_probe_parameters -> printFloat_CoordValue); the import read 0.0669 in as 0.0669 mm
    (exit 0). vmt probe refuses a controller with $13=1 (GrblBackend._check_units), so the import
    refuses such a transcript in one line naming the setting's line and the report's."""
    plan_path = write_probe_log(tmp_path / "plan.csv", INCH_PLAN)
    tr, out = tmp_path / "t.txt", tmp_path / "o.csv"
    tr.write_text(edit(INCH_TRANSCRIPT))
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert msg in err and err.count("\n") == 1 and not out.exists()
    assert "set $13=0" in err or "not a number" in err


def _mm3(t):
    """INCH_TRANSCRIPT's reports as GRBL prints mm, to 3 decimals (printFloat_CoordValue)."""
    return t.replace("0.0000", "0.000").replace("0.0669", "0.067").replace("0.0079", "0.008")


@pytest.mark.parametrize("edit, z, y", [
    (lambda t: t.replace("$13=1", "$13=0"), 0.0669, 0.0079),                   # a mm controller's dump
    (lambda t: t.replace("1000.011 < ok", "1000.011 < ok\n1000.050 > $13=0\n1000.051 < ok"), 0.0669, 0.0079),  # set back
    (lambda t: _mm3(t.replace("1000.010 < $13=1\n", "")) + "1008.000 > $13=1\n1008.001 < ok\n", 0.067, 0.008),  # inches after
    (lambda t: _mm3(t.replace("1000.010 < $13=1\n", "")), 0.067, 0.008),      # no dump, GRBL's mm print: read as mm
])
def test_grbl_transcript_in_mm_reads_whatever_13_says_elsewhere(tmp_path, capsys, edit, z, y):
    """Reports read as mm: a $13=0 before them says so whatever they print (a firmware built to print mm to 4
    decimals keeps its '$$' answer in the transcript); without any $13 before them, GRBL's mm print (3 decimals)."""
    plan_path = write_probe_log(tmp_path / "plan.csv", INCH_PLAN)
    tr, out = tmp_path / "t.txt", tmp_path / "o.csv"
    tr.write_text(edit(INCH_TRANSCRIPT))
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(out)]) == 0
    log = read_probe_log(out)
    np.testing.assert_array_equal(log.columns["Z_mm"], [z, z])
    np.testing.assert_array_equal(log.columns["Y_mm"], [0.0, y])


def test_grbl_transcript_printed_as_inches_without_13_is_refused(tmp_path, capsys):
    """review34 (low): a transcript without '$$' (most senders log none) whose reports GRBL printed in inches
    ($13=1: 4 decimals, printFloat_CoordValue; mm 3) was read as mm: near the origin the plan's alignment check
    passed and the import wrote 0.0669 in as 0.0669 mm (exit 0; farther out it was refused as 'not a touch of
    plan row 0', naming no units). Now refused in one line naming the report's line, its 4 decimals and $13."""
    plan_path = write_probe_log(tmp_path / "plan.csv", INCH_PLAN)
    tr, out = tmp_path / "t.txt", tmp_path / "o.csv"
    tr.write_text(INCH_TRANSCRIPT.replace("1000.010 < $13=1\n", ""))
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and not out.exists()
    assert "line 4: the probe report prints 4 decimals, as GRBL prints inches ($13=1" in err
    assert "set $13=0" in err


@pytest.mark.parametrize("dump", [None, "0", "1"])
def test_grbl_emulator_with_13_set_imports_as_its_units_say(tmp_path, capsys, dump):
    """The project's GRBL emulator (GRBL 1.1h's report.c: every position through printFloat_CoordValue) with
    $13=1 prints [PRB:...] in inches to 4 decimals: its transcript, with no '$$' in it or with its '$$' answer
    ($13=1), is refused naming $13, nothing written; the same session with $13=0 imports the touch it reports,
    the plan's (10, 10, 0) mm. The inch report is checked against the mm one: x 25.4 within the inch print's
    half step (0.00005 in = 1.27 um)."""
    from core.probelog import make_log as _mk
    plan = _mk({"setup": ["table"], "target": ["p0"], "t_s": [np.nan], "X_mm": [np.nan], "Y_mm": [np.nan],
                "Z_mm": [np.nan], "Xn_mm": [10.0], "Yn_mm": [10.0], "Zn_mm": [0.0], "nx": [0.0], "ny": [0.0],
                "nz": [1.0]}, meta={"stylus_r_mm": "1.5"})
    plan_path = write_probe_log(tmp_path / "plan.csv", plan)

    def session(report_inches):
        emu = GrblEmulator(scene(), ControllerConfig(home=(0, 0, 50)))
        lines = []
        for cmd in (["$X", f"$13={report_inches}"] + (["$$"] if dump is not None else [])
                    + ["G53 G90 G1 X10 Y10 Z2 F2000", "G91 G38.2 X0 Y0 Z-4 F200", "G90"]):
            got = [x for x in emu.feed_bytes((cmd + "\n").encode())[0] if x]
            if cmd.startswith("$13="):
                continue            # the setting made off the record (another sender, or an earlier session)
            lines += [f"> {cmd}"] + [f"< {x}" for x in got]
        return "\n".join(lines) + "\n"

    mm_text = session(0)
    prb_mm = parse_prb(next(ln[2:] for ln in mm_text.splitlines() if ln.startswith("< [PRB")))[0]
    text = session(1 if dump != "0" else 0)
    tr, out = tmp_path / "t.txt", tmp_path / "o.csv"
    tr.write_text(text)
    rc = main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(out)])
    err = capsys.readouterr().err
    if dump == "0":
        assert rc == 0, err
        np.testing.assert_array_equal(read_probe_log(out).positions_mm()[0], prb_mm)
        assert np.allclose(prb_mm, [10, 10, 0], atol=0.05)
        return
    prb_in = parse_prb(next(ln[2:] for ln in text.splitlines() if ln.startswith("< [PRB")))[0]
    assert np.all(np.abs(prb_in * 25.4 - prb_mm) <= 0.5e-4 * 25.4 + 0.5e-3 + 1e-9)   # both prints' half steps
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err and not out.exists()
    assert ("the probe report prints 4 decimals, as GRBL prints inches" if dump is None
            else "the probe report is in inches (the controller's $13=1") in err


def test_probeopen_rotary_positions_are_checked_against_the_plan(tmp_path, plan_path, measured, capsys):
    """review30 F8: a 9-number PROBEOPEN file's A B C were ignored: C = 0 on every line of a cross-pocket plan's
    C = 75/130/210 rows was booked at the plan's angles (276 rows), exit 0. Now each line's A B C must be its
    row's within ROTARY_TOL_DEG (modulo 360), else refused naming the line and the row."""
    plan = read_probe_log(plan_path)
    plan.columns["C_deg"] = np.where(np.arange(plan.n) < 6, 0.0, 75.0)    # two set-ups: C 0, then C 75
    turned = write_probe_log(tmp_path / "plan-c.csv", plan)
    pos = measured.positions_mm()
    pf, out = tmp_path / "probe.txt", tmp_path / "log.csv"

    def file_with(c_deg):
        with open(pf, "w") as f:
            for p, c in zip(pos, c_deg):
                f.write(" ".join(f"{v:f}" for v in list(p) + [0.0, 0.0, c, 0.0, 0.0, 0.0]) + "\n")

    file_with([0.0] * plan.n)                                  # the table never turned
    assert main(["import", "linuxcnc", str(pf), "--plan", str(turned), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not out.exists()
    assert f"{pf}: line 7: C 0 deg, but plan row 6 (target {plan.col('target')[6]}) has C 75 deg (within 0.01 deg" in err
    file_with([0.0] * 6 + [75.0] * 5 + [75.02])                # the last 0.02 deg off
    assert main(["import", "linuxcnc", str(pf), "--plan", str(turned), "--out", str(out)]) == 2
    assert "line 12: C 75.02 deg, but plan row 11" in capsys.readouterr().err
    file_with([360.0] * 6 + [435.0] * 5 + [75.009])            # a continuous axis: the same angles
    assert main(["import", "linuxcnc", str(pf), "--plan", str(turned), "--out", str(out)]) == 0
    log = read_probe_log(out)
    assert log.n == plan.n and np.all(log.ok) and list(log.col("C_deg")) == [0.0] * 6 + [75.0] * 6


def _linuxcnc_writes(program: str, pos) -> str:
    """The LOGOPEN file LinuxCNC writes running ``program``: each (LOG,...) line's text, its #5061-#5063 (the
    probed X Y Z) expanded as %lf (6 decimals), one per probe, with the touches ``pos`` (mm)."""
    logs = re.findall(r"^\(LOG,(.*)\)$", program, re.M)
    assert len(logs) == len(pos)
    return "".join(t.replace("#5061", f"{p[0]:f}").replace("#5062", f"{p[1]:f}").replace("#5063", f"{p[2]:f}") + "\n"
                   for t, p in zip(logs, pos))


def test_linuxcnc_program_carries_its_stroke_to_the_import(tmp_path, capsys):
    """Session 30 (small30): vmt's LinuxCNC program logs each touch with the G38.2 move that made it (G91 G38.2,
    start to end: clearance + overtravel), so vmt import linuxcnc reads the stroke from the file, as it reads
    GRBL's from the transcript's G91 G38.2, without --clearance-mm/--overtravel-mm. A 12 + 12 mm stroke: a
    touch 11 mm beyond its nominal, refused by the 10 mm fallback before (the file said nothing), is its row's;
    30 mm beyond is refused naming the line's own 24 mm stroke. A 0.5 + 0.5 mm stroke: a touch 3 mm along
    (the 10 mm fallback took it) is refused."""
    plan = tmp_path / "step.csv"
    plan.write_text(STEP_PLAN)
    pf, out = tmp_path / "probe.log", tmp_path / "imp.csv"
    args = ["import", "linuxcnc", str(pf), "--plan", str(plan), "--out", str(out)]
    lim = ((-50.0, 100.0), (-50.0, 50.0), (-50.0, 50.0))
    prog = part_program(read_probe_log(plan), ProbeSettings(clearance_mm=12.0, overtravel_mm=12.0, limits_mm=lim))
    assert "(LOG,N1 G1 X#5061 Y#5062 Z#5063 G91 G38.2 X0.0000 Y0.0000 Z-24.0000)" in prog
    pos = np.array([[0.0, 0.0, 4.5002], [0.0, 0.0, -9.5], [40.0, 0.0, 1.5001]])   # lower: 11 mm beyond
    pf.write_text(_linuxcnc_writes(prog, pos))
    assert main(args) == 0, capsys.readouterr().err
    assert np.array_equal(read_probe_log(out).positions_mm(), pos)
    pos[1, 2] = 1.5 - 30.0
    pf.write_text(_linuxcnc_writes(prog, pos))
    out.unlink()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "line 2: [0, 0, -28.5] mm is not a touch of plan row 1 (target 'lower'" in err and \
        "+30.000 mm along it (a touch lies within 0.5 mm of the line and 24 mm of the nominal: the program's " \
        "stroke, its G91 G38.2 move on this LOG line (24 mm))" in err and not out.exists(), err
    short = part_program(read_probe_log(plan), ProbeSettings(clearance_mm=0.5, overtravel_mm=0.5, limits_mm=lim))
    lines = _linuxcnc_writes(short, np.array([[0.0, 0.0, 1.5002], [0.0, 0.0, 1.5], [40.0, 0.0, 1.5]]))
    pf.write_text(lines.splitlines(keepends=True)[0])       # one line: the lower step's touch as row 0's (upper)
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "line 1: [0, 0, 1.5002] mm is not a touch of plan row 0 (target 'upper'" in err and \
        "1 mm of the nominal: the program's stroke, its G91 G38.2 move on this LOG line (1 mm)" in err, err


@pytest.mark.parametrize("tail, msg", [
    ("G91 G38.2 X0 Y0 Z0", "its G91 G38.2 move 'X0 Y0 Z0' is not X, Y, Z words of a move of non-zero length"),
    ("G91 G38.2 X0 Q4", "its G91 G38.2 move 'X0 Q4' is not X, Y, Z words"),
    ("G91 G38.2 Z-4\nN1 G1 X0.000000 Y0.000000 Z1.500000",
     "line 2: a G91 G38.2 move (the probing stroke) on some lines and not on others"),
])
def test_linuxcnc_log_line_bad_move_exit_2(tmp_path, capsys, tail, msg):
    plan = tmp_path / "step.csv"
    plan.write_text(STEP_PLAN)
    pf = tmp_path / "probe.log"
    pf.write_text(f"N0 G1 X0.000000 Y0.000000 Z4.500200 {tail}\n")
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan), "--out", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert msg in err and "line " in err and err.count("\n") == 1, err
