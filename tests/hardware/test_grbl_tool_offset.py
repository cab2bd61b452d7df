"""The GRBL route's tool offset J (``--tool-offset-mm``, session 36): the sign by hand, the closed loop.

J is the probe's offsets, spindle gauge point minus stylus-tip centre (a machine file's ``[tool]
offset_mm``, ``vmt identify --tool-offset-mm``): on a GRBL machine whose machine coordinates are the
spindle's, the tip centre is ``machine position - J`` (``G43``'s sign: a positive tool length puts the tip
below the gauge line). ``vmt probe --tool-offset-mm J`` sends the plan's tip centres + J and logs each
``[PRB:...]`` less J; ``vmt import grbl --tool-offset-mm J`` takes J off a transcript's reports; ``vmt
machine serve --tool-offset-mm J`` is such a machine (its tip centre J from its machine position).

Tolerances: the emulator prints positions to 3 decimals (GRBL's mm report: 0.5 um rounding) and vmt
commands 4 (0.05 um), so a touch through it lies within 0.6 um of the direct simulation's (QUANT_MM, as
tests/hardware/test_campaign.py); two runs through it that send the same commands report the same numbers,
so what J changes is compared to 1e-9 mm (a float's last bits on numbers of 150 mm).
"""

import re
import shlex
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import plan_log, scene
from core.exceptions import ConfigError, PlanError
from core.probelog import make_log, read_probe_log, write_probe_log
from hardware.backend import VirtualBackend
from hardware.campaign import (ProbeSettings, parse_tool_offset, plan_steps, run_campaign,
                               tool_offset_step_problem)
from hardware.emulator import ControllerConfig, Faults, GrblEmulator, TcpServer
from hardware.grbl import GrblBackend, GrblClient, parse_prb
from scenarios.cli import main
from tests.cli_helpers import one_line_error

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).parent / "data" / "grbl-1.1h"
CAMPAIGN = DATA / "grbl-1.1h-sim-vmt-campaign-transcript.txt"
QUANT_MM = 0.6e-3
TIME_SCALE = 200.0
#: a probe 150.125 mm long, mounted 12.5 mm in X and -7.25 mm in Y from the spindle axis: every axis shifted,
#: each on GRBL's 0.001 mm step
J = (12.5, -7.25, 150.125)
J_TEXT = "12.5,-7.25,150.125"
#: the tip-centre limits of conftest.LIMITS (X-20:200, Y-20:200, Z-50:100) + J, and the safe Z 30 + J_z
LIMITS_J = "X-7.5:212.5,Y-27.25:192.75,Z100.125:250.125"
SAFE_Z_J = "180.125"


def _serve(J_mm=None, faults=None, home=(0, 0, 50)):
    emu = GrblEmulator(scene(), ControllerConfig(home=home), faults=faults, tool_offset_mm=J_mm)
    return emu, TcpServer(emu, time_scale=TIME_SCALE).start()


def _probe(url, plan, out, *extra, limits=LIMITS_J, safe_z=SAFE_Z_J):
    return ["probe", "--controller", url, "--plan", str(plan), "--out", str(out),
            "--limits-mm", limits, "--safe-z-mm", safe_z, "--timeout-s", "5", *extra]


def _direct(tmp_path, plan):
    """The simulator's truth: the same plan on the same machine, in-process, tip centres exact."""
    out = tmp_path / "direct.csv"
    run_campaign(VirtualBackend(scene(), home_m=(0, 0, 0.05)), plan, out,
                 ProbeSettings(limits_mm=((-20, 200), (-20, 200), (-50, 100)), safe_z_mm=30.0))
    return read_probe_log(out)


def _shifted_plan(plan, J_mm):
    """The plan written in the controller's machine coordinates (tip centre + J): what a user wrote before
    session 36 (docs/formats.md's workaround), and what a probe log without the option then holds."""
    cols = {c: v.copy() for c, v in plan.columns.items()}
    for c, v in zip(("Xn_mm", "Yn_mm", "Zn_mm"), J_mm):
        cols[c] = cols[c] + v
    return make_log(cols, dict(plan.meta))


# ---------------------------------------------------------------------------------------------------------
# the sign, by hand


def test_the_sign_of_J_by_hand_g43s_a_positive_length_puts_the_tip_below_the_gauge_line():
    """docs/formats.md's worked case: a face at z = 20 mm, stylus r 1.5 mm (tip centre at contact Zn = 21.5),
    clearance 10 mm, a 150 mm probe (J = (0, 0, 150)). The tip must start 10 mm above the contact, at
    z = 31.5: the spindle's machine Z is 31.5 + 150 = 181.5, and the probing move goes 12 mm down (10 + the
    2 mm overtravel) to machine Z 169.5, the tip to 19.5. Without J the spindle went to 31.5 and the tip to
    31.5 - 150 = -118.5, 138.5 mm below the face."""
    plan = make_log({"setup": ["s"], "target": ["t"], "t_s": [np.nan], "X_mm": [np.nan], "Y_mm": [np.nan],
                     "Z_mm": [np.nan], "Xn_mm": [0.0], "Yn_mm": [0.0], "Zn_mm": [21.5], "nx": [0.0], "ny": [0.0],
                     "nz": [1.0]}, {"stylus_r_mm": "1.5"})
    st = plan_steps(plan, ProbeSettings(clearance_mm=10.0, tool_offset_mm=(0.0, 0.0, 150.0)))[0]
    assert st.start_mm.tolist() == [0.0, 0.0, 181.5] and st.end_mm.tolist() == [0.0, 0.0, 169.5]
    bare = plan_steps(plan, ProbeSettings(clearance_mm=10.0))[0]
    assert bare.start_mm.tolist() == [0.0, 0.0, 31.5] and (bare.start_mm - 150.0)[2] == -118.5


def test_the_real_firmwares_campaign_on_a_spindle_frame_is_sent_plus_J_and_logged_less_J(tmp_path):
    """The real GRBL 1.1h campaign (tests/hardware/data/grbl-1.1h, 12 touches; its host simulator's machine
    coordinates were the tip centre's), rewritten as the same firmware on a machine whose coordinates are the
    spindle's, J = (12.5, -7.25, 150.125) mm from the tip: every G53 target, MPos and [PRB:...] + J, the
    G91 G38.2 increments as they were. vmt's client, replaying it with --tool-offset-mm J, must send exactly
    those lines (the plan's tip centres + J), and log exactly the original reports: the sphere touch
    ``[PRB:61.328,50.000,5.283:1]`` arrives as ``[PRB:73.828,42.750,155.408:1]`` and is logged
    X 73.828 - 12.5 = 61.328, Y 42.750 + 7.25 = 50.000, Z 155.408 - 150.125 = 5.283."""
    from test_grbl_transcripts import ReplayLink, transcript

    def plus_j(text, dec):
        vals = [float(v) + j for v, j in zip(text.split(","), J)]
        return ",".join(f"{v:.{dec}f}" for v in vals)

    lines = []
    for d, t in transcript(CAMPAIGN):
        if t.startswith("G53 G90 G1 "):
            t = re.sub(r"([XYZ])(-?[\d.]+)", lambda m: f"{m[1]}{float(m[2]) + J['XYZ'.index(m[1])]:.4f}", t)
        t = re.sub(r"MPos:([-\d.]+,[-\d.]+,[-\d.]+)", lambda m: "MPos:" + plus_j(m[1], 3), t)
        t = re.sub(r"^\[PRB:([-\d.]+,[-\d.]+,[-\d.]+):", lambda m: "[PRB:" + plus_j(m[1], 3) + ":", t)
        lines.append((d, t))
    assert ("<", "[PRB:73.828,42.750,155.408:1]") in lines and ("<", "[PRB:61.328,50.000,5.283:1]") in transcript(
        CAMPAIGN)
    link = ReplayLink(lines)
    be = GrblBackend(GrblClient(link, timeout_s=0.5))
    lim = tuple((lo + j, hi + j) for (lo, hi), j in zip(((-20, 200), (-20, 200), (-50, 100)), J))
    s = ProbeSettings(probe_feed_mm_min=200.0, move_feed_mm_min=2000.0, max_feed_mm_min=2000.0, limits_mm=lim,
                      tool_offset_mm=J)
    res = run_campaign(be, plan_log(), tmp_path / "log.csv", s)
    assert not link.lines and not link.pending and link.sent == 66   # every line sent as the shifted transcript
    assert res.rows_done == 12 and res.statuses == {"ok": 12}
    log = read_probe_log(tmp_path / "log.csv")
    tip = [parse_prb(t)[0] for d, t in transcript(CAMPAIGN) if t.startswith("[PRB")]
    assert np.array_equal(log.positions_mm(), np.array(tip))          # the tip centres, to the last digit
    assert log.positions_mm()[4].tolist() == [61.328, 50.0, 5.283]
    assert log.meta["tool_offset_mm"] == "12.5,-7.25,150.125"
    text = (tmp_path / "log.csv").read_text()
    assert "# tool_offset_mm: 12.5,-7.25,150.125\n" in text and "61.328,50.000,5.283" in text
    # the same rewritten transcript imported: the same tip centres; without J its reports are not the plan's
    sent = tmp_path / "spindle-frame.txt"
    sent.write_text("".join(f"1796146761.0 {d} {t}\n" for d, t in lines))
    plan = write_probe_log(tmp_path / "plan.csv", plan_log())
    imp = tmp_path / "imp.csv"
    assert main(["import", "grbl", str(sent), "--plan", str(plan), "--out", str(imp), "--tool-offset-mm",
                 J_TEXT]) == 0
    got = read_probe_log(imp)
    assert np.array_equal(got.positions_mm(), np.array(tip)) and got.meta["tool_offset_mm"] == J_TEXT


def test_parse_and_step_checks():
    assert parse_tool_offset("0,0,150") == (0.0, 0.0, 150.0)
    for bad in ("0,0,nan", "0,0,inf", "0,150", "0,0,150,1", "a,b,c", "", "0,0,1e6"):
        with pytest.raises(ConfigError, match="--tool-offset-mm"):
            parse_tool_offset(bad)
    with pytest.raises(ConfigError, match="tool_offset_mm"):
        ProbeSettings(tool_offset_mm=(0.0, 0.0, float("nan")))
    assert tool_offset_step_problem((0.0, -7.25, 150.125), 3) is None
    assert tool_offset_step_problem((0.0, 0.0, 150.0000), 3) is None           # 150.0000 is on the step
    said = tool_offset_step_problem((0.0, 0.0, 150.0005), 3)
    assert said.startswith("its Z 150.0005 mm is not a multiple of the controller's printing step 0.001 mm")
    assert tool_offset_step_problem((0.0, 0.0, 150.0005), None) is None        # a backend measuring in metres
    assert tool_offset_step_problem((0.0, 0.0, 150.0005), {"X_mm": 3}) is None  # Z printed exact


# ---------------------------------------------------------------------------------------------------------
# the closed loop through the emulator


def test_closed_loop_emulator_with_a_known_tool_length(tmp_path, capsys):
    """The emulator with J: ``vmt probe --tool-offset-mm J`` logs the simulator's truth (the same plan, the
    same machine, in-process) to the emulator's resolution (0.6 um: 3-decimal reports, 4-decimal commands);
    the same touches without the option (the plan written in the controller's coordinates, tip + J, the only
    way before) are off by exactly J; the run's transcript imported with J gives the first log's readings
    digit for digit, and without J is refused in one line (its reports lie 150 mm from the plan's lines)."""
    plan = plan_log()
    plan_path = write_probe_log(tmp_path / "plan.csv", plan)
    shifted_path = write_probe_log(tmp_path / "plan-j.csv", _shifted_plan(plan, J))
    truth = _direct(tmp_path, plan)
    with_j, without, tr = tmp_path / "with-j.csv", tmp_path / "without.csv", tmp_path / "session.txt"
    emu, srv = _serve(J, home=(0, 0, 250))
    try:
        assert main(_probe(srv.url, plan_path, with_j, "--tool-offset-mm", J_TEXT, "--transcript", str(tr))) == 0
        assert main(_probe(srv.url, shifted_path, without)) == 0
    finally:
        srv.stop()
    capsys.readouterr()
    a, b = read_probe_log(with_j), read_probe_log(without)
    assert a.n == b.n == truth.n == 12 and a.ok.all() and b.ok.all()
    d = a.positions_mm() - truth.positions_mm()
    assert np.abs(d).max() < QUANT_MM, np.abs(d).max()
    # the truth's touches are not trivially equal to the nominals: the machine's known errors show (1.16 um)
    assert np.abs(truth.dq_mm()).max() > 1e-3
    off = b.positions_mm() - a.positions_mm()
    assert np.allclose(off, np.tile(J, (12, 1)), rtol=0, atol=1e-9)       # off by exactly J
    assert a.meta["tool_offset_mm"] == J_TEXT and "tool_offset_mm" not in b.meta
    # the dq of both is the same (the deviations are right either way; the positions are not)
    assert np.allclose(a.dq_mm(), b.dq_mm(), rtol=0, atol=1e-9)
    # the transcript of the run with J, imported with J: the same readings, digit for digit
    imp = tmp_path / "imported.csv"
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(imp),
                 "--tool-offset-mm", J_TEXT]) == 0
    assert "each report less the tool offset J = (12.5, -7.25, 150.125) mm" in capsys.readouterr().out
    got = read_probe_log(imp)
    assert np.array_equal(got.positions_mm(), a.positions_mm()) and got.meta["tool_offset_mm"] == J_TEXT
    # imported without J against the tip-centre plan: refused, naming a line, nothing written
    bad = tmp_path / "bad.csv"
    assert main(["import", "grbl", str(tr), "--plan", str(plan_path), "--out", str(bad)]) == 2
    one_line_error(capsys, "is not a touch of plan row 0", "14.450 mm off its approach line, -150.125 mm along it",
                      "or its controller's machine coordinates are the spindle's (give the probe's --tool-offset-mm)")
    assert not bad.exists()
    # and against the plan in the controller's coordinates: the log without the option, off by J
    imp2 = tmp_path / "imported-j.csv"
    assert main(["import", "grbl", str(tr), "--plan", str(shifted_path), "--out", str(imp2)]) == 0
    assert np.array_equal(read_probe_log(imp2).positions_mm(), b.positions_mm())


def test_emulator_without_J_is_unchanged_and_a_plan_of_tip_centres_crashes_on_a_spindle_frame(tmp_path, capsys):
    """J = 0 (the default) is the emulator as before: its machine position is the tip centre. With J = (0, 0,
    150) and no --tool-offset-mm, a tip-centre plan puts the stylus 150 mm into the table: the first probing
    move finds the probe already triggered (ALARM:4), logged early_trigger, nothing else probed."""
    plan = plan_log()
    plan_path = write_probe_log(tmp_path / "plan.csv", plan)
    truth = _direct(tmp_path, plan)
    out0, crash = tmp_path / "j0.csv", tmp_path / "crash.csv"
    emu, srv = _serve(None)
    try:
        assert main(_probe(srv.url, plan_path, out0, limits="X-20:200,Y-20:200,Z-50:100", safe_z="30")) == 0
    finally:
        srv.stop()
    assert np.abs(read_probe_log(out0).positions_mm() - truth.positions_mm()).max() < QUANT_MM
    emu, srv = _serve((0.0, 0.0, 150.0), home=(0, 0, 250))
    try:
        assert main(_probe(srv.url, plan_path, crash, limits="X-20:200,Y-20:200,Z-50:100", safe_z="30")) == 2
    finally:
        srv.stop()
    assert "ALARM:4 (probe not in the expected state" in capsys.readouterr().err
    log = read_probe_log(crash)
    assert log.n == 1 and log.col("status")[0] == "early_trigger" and emu.probes == 1


# ---------------------------------------------------------------------------------------------------------
# bad input: one line, exit 2, nothing lost


def test_resume_with_another_J_is_refused_and_the_partial_log_is_untouched(tmp_path, capsys):
    plan = plan_log()
    plan_path = write_probe_log(tmp_path / "plan.csv", plan)
    out = tmp_path / "log.csv"
    emu, srv = _serve(J, faults=Faults(drop_before_probe=(5,)), home=(0, 0, 250))
    try:
        assert main(_probe(srv.url, plan_path, out, "--tool-offset-mm", J_TEXT)) == 2
        capsys.readouterr()
        before = out.read_bytes()
        assert read_probe_log(out).n == 4
        probes = emu.probes
        for other, said in ((["--tool-offset-mm", "12.5,-7.25,150"], "the resume gives --tool-offset-mm "
                                                                     "12.5,-7.25,150.0"),
                            ([], "the resume gives no --tool-offset-mm (J = 0)")):
            assert main(_probe(srv.url, plan_path, out, "--resume", *other)) == 2
            one_line_error(capsys, "not resumed, nothing moved, the log kept",
                              "its tool_offset_mm line says J = 12.5,-7.25,150.125 mm", said)
            assert out.read_bytes() == before and emu.probes == probes      # nothing probed, not a byte changed
        assert main(_probe(srv.url, plan_path, out, "--resume", "--tool-offset-mm", "12.500,-7.25,150.125")) == 0
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert log.n == 12 and log.ok.all() and log.meta["tool_offset_mm"] == J_TEXT
    assert np.abs(log.positions_mm() - _direct(tmp_path, plan).positions_mm()).max() < QUANT_MM


def test_a_log_begun_without_J_refuses_a_resume_with_one(tmp_path, capsys):
    plan_path = write_probe_log(tmp_path / "plan.csv", plan_log())
    out = tmp_path / "log.csv"
    emu, srv = _serve(None, faults=Faults(drop_before_probe=(3,)))
    try:
        args = _probe(srv.url, plan_path, out, limits="X-20:200,Y-20:200,Z-50:300", safe_z="180")
        assert main(args) == 2
        capsys.readouterr()
        before = out.read_bytes()
        assert main(args + ["--resume", "--tool-offset-mm", "0,0,150"]) == 2
        one_line_error(capsys, "it has no tool_offset_mm line: begun with none applied (J = 0)",
                          "--tool-offset-mm 0.0,0.0,150.0")
        assert out.read_bytes() == before
        assert main(args + ["--resume", "--tool-offset-mm", "0,0,0"]) == 0    # J = 0 is what it was begun with
    finally:
        srv.stop()


@pytest.mark.parametrize("value", ["0,0,nan", "0,0,inf", "0,-inf,0", "0,150", "x,y,z"])
def test_a_tool_offset_that_is_not_three_finite_numbers_is_refused_everywhere(tmp_path, capsys, value):
    plan_path = write_probe_log(tmp_path / "plan.csv", plan_log())
    out = tmp_path / "log.csv"
    cmds = [
        _probe("grbl://127.0.0.1:9", plan_path, out, f"--tool-offset-mm={value}"),     # refused before connecting
        _probe("grbl://127.0.0.1:9", plan_path, out, f"--tool-offset-mm={value}", "--dry-run"),
        ["import", "grbl", str(CAMPAIGN), "--plan", str(plan_path), "--out", str(out), f"--tool-offset-mm={value}"],
        ["machine", "serve", "--port", "0", f"--tool-offset-mm={value}", "--stop-after-s", "0.1"],
    ]
    for cmd in cmds:
        assert main(cmd) == 2, cmd
        one_line_error(capsys, f"--tool-offset-mm {value!r}: expected X,Y,Z, three finite numbers, mm")
        assert not out.exists()


def test_a_J_off_the_controllers_step_virtual_and_linuxcnc_are_refused(tmp_path, capsys):
    plan_path = write_probe_log(tmp_path / "plan.csv", plan_log())
    out = tmp_path / "log.csv"
    emu, srv = _serve((0.0, 0.0, 150.0), home=(0, 0, 250))
    try:
        assert main(_probe(srv.url, plan_path, out, "--tool-offset-mm", "0,0,150.0005",
                           limits="X-20:200,Y-20:200,Z100:250", safe_z="180")) == 2
    finally:
        srv.stop()
    one_line_error(capsys, "its Z 150.0005 mm is not a multiple of the controller's printing step 0.001 mm",
                      "nothing probed, no log written")
    assert not out.exists() and emu.probes == 0
    assert main(["import", "grbl", str(CAMPAIGN), "--plan", str(plan_path), "--out", str(out),
                 "--tool-offset-mm", "0,0,0.0005"]) == 2
    one_line_error(capsys, "its Z 0.0005 mm is not a multiple", "nothing written")
    assert main(_probe("virtual:", plan_path, out, "--tool-offset-mm", "0,0,150")) == 2
    one_line_error(capsys, "the in-process virtual machine (virtual:)")
    pf = tmp_path / "probe.txt"
    pf.write_text("10 10 0\n")
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan_path), "--out", str(out),
                 "--tool-offset-mm", "0,0,150"]) == 2
    one_line_error(capsys, "--tool-offset-mm is for grbl transcripts", "G43")
    assert not out.exists()


def test_dry_run_prints_the_spindles_coordinates(tmp_path, capsys):
    plan_path = write_probe_log(tmp_path / "plan.csv", plan_log())
    assert main(_probe("grbl://127.0.0.1:9", plan_path, tmp_path / "o.csv", "--tool-offset-mm", J_TEXT,
                       "--dry-run")) == 0
    lines = capsys.readouterr().out.splitlines()
    # row 0: the table at (10, 10), tip centre at contact z = 0 (conftest's plan), approach start 2 mm above it
    k = lines.index("(row 0 setup table target p0)")
    assert lines[k + 1:k + 5] == ["G53 G90 G1 Z180.1250 F1000.0", "G53 G90 G1 X22.5000 Y2.7500 Z180.1250 F1000.0",
                                  "G53 G90 G1 X22.5000 Y2.7500 Z152.1250 F1000.0",
                                  "G91 G38.2 X0.0000 Y0.0000 Z-4.0000 F100.0"]


def test_run_campaign_itself_refuses_a_resume_with_another_J(tmp_path):
    """The library's own check (the CLI checks first, from the log's head): on the log it has locked, before the
    backend is started; the log's bytes unchanged."""
    plan = plan_log()
    out = tmp_path / "log.csv"
    lim = ((-50, 250), (-50, 250), (-50, 300))
    run_campaign(VirtualBackend(scene(), home_m=(0, 0, 0.25)), plan.select(np.arange(plan.n) < 3), out,
                 ProbeSettings(limits_mm=lim, tool_offset_mm=(0, 0, 0.5)))    # 3 of the plan's 12 rows
    before = out.read_bytes()

    class Untouchable:
        def start(self, **kw):
            raise AssertionError("started")

    with pytest.raises(PlanError, match=r"its tool_offset_mm line says J = 0.0,0.0,0.5 mm, the resume gives "
                                        r"--tool-offset-mm 0.0,0.0,0.25"):
        run_campaign(Untouchable(), plan, out, ProbeSettings(limits_mm=lim, tool_offset_mm=(0, 0, 0.25)), resume=True)
    assert out.read_bytes() == before


# ---------------------------------------------------------------------------------------------------------
# the documented commands, as written, against our emulator


def _doc_block():
    """The three command lines of docs/formats.md's worked case (plan, serve, probe; comments cut)."""
    text = (ROOT / "docs" / "formats.md").read_text()
    block = text.split("Worked case, against vmt's own emulator", 1)[1].split("```bash\n", 1)[1].split("```")[0]
    return [re.split(r"\s+#", ln)[0].strip() for ln in block.splitlines() if ln.startswith("vmt ")]


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_documented_worked_case_runs_against_our_emulator(tmp_path, monkeypatch, capsys):
    """docs/formats.md, "GRBL transcript": the plan, ``vmt machine serve`` (a process, as a user starts it) and
    ``vmt probe`` lines as written (the port picked free), then what the text says of them: the first touch sent
    to machine Z 160 and answered [PRB:10.000,10.000,150.000:1], every reading the tip centre z = 0.000 under the
    log's tool_offset_mm line, and the probe line without --tool-offset-mm refused by the limits, nothing moved."""
    plan_cmd, serve_cmd, probe_cmd = _doc_block()
    assert "--tool-offset-mm 0,0,150" in serve_cmd and "--tool-offset-mm 0,0,150" in probe_cmd
    port = str(_free_port())
    serve = [port if a == "5000" else a for a in shlex.split(serve_cmd)[1:]]
    probe = [a.replace(":5000", f":{port}") for a in shlex.split(probe_cmd)[1:]] + ["--transcript", "session.txt"]
    monkeypatch.chdir(tmp_path)
    assert main(shlex.split(plan_cmd)[1:]) == 0
    proc = subprocess.Popen([sys.executable, "-m", "scenarios.cli", *serve, "--stop-after-s", "120"], cwd=tmp_path,
                            env={**__import__("os").environ, "PYTHONPATH": str(ROOT)},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        first = proc.stdout.readline()
        assert f"on grbl://127.0.0.1:{port}, the probe's tip centre J = (0, 0, 150) mm" in first, \
            first + proc.stderr.read()
        assert main(probe) == 0
        capsys.readouterr()
        bare = [a for a in probe if a not in ("--tool-offset-mm", "0,0,150")]
        bare[bare.index("--out") + 1] = "bare.csv"
        assert main(bare) == 2
        one_line_error(capsys, "row 0 (target 'r0c0'): approach [10.0, 10.0, 10.0] mm is outside the soft "
                                  "limits of Z [140.0, 260.0] mm")
        assert not (tmp_path / "bare.csv").exists()
    finally:
        proc.terminate()
        try:
            proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
    text = (tmp_path / "log.csv").read_text()
    assert "# tool_offset_mm: 0.0,0.0,150.0\n" in text
    log = read_probe_log(tmp_path / "log.csv")
    assert log.n == 6 and log.ok.all() and np.all(log.col("Z_mm") == 0.0)
    rows = [ln for ln in text.splitlines() if not ln.startswith("#")]
    assert rows[1].startswith("grid,r0c0,") and rows[1].split(",")[3:9] == ["10.000", "10.000", "0.000", "10.0",
                                                                            "10.0", "0.0"]
    session = (tmp_path / "session.txt").read_text().splitlines()
    sent = [ln.split(" ", 2)[2] for ln in session]
    k = sent.index("G53 G90 G1 X10.0000 Y10.0000 Z160.0000 F1000.0")
    assert sent[k + 2] == "G91 G38.2 X0.0000 Y0.0000 Z-12.0000 F100.0"
    assert "[PRB:10.000,10.000,150.000:1]" in sent[k + 3:k + 5]
