"""`vmt probe` campaigns against the emulator: equal to the backend, resumable, lossless."""

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import LIMITS, LIMITS_MM, plan_log, scene
from core.exceptions import HardwareError, PlanError, ProbeLogError
from core.probelog import read_probe_log, write_probe_log
from hardware.backend import VirtualBackend
from hardware.campaign import ProbeSettings, recover_log, run_campaign
from hardware.emulator import ControllerConfig, Faults, GrblEmulator, TcpServer
from scenarios.cli import main

ROOT = Path(__file__).resolve().parents[2]
#: GRBL reports 3 decimals in mm (0.5 µm) and commands carry 4 (0.05 µm).
QUANT_MM = 0.6e-3
#: The emulator's motion takes the time a machine takes; its clock runs this much faster.
TIME_SCALE = 200.0


def direct_log(tmp_path, plan, noise_um=0.0, name="direct.csv"):
    """The reference: the same plan on the same machine, called in-process."""
    out = tmp_path / name
    run_campaign(VirtualBackend(scene(noise_um), home_m=(0, 0, 0.05)), plan, out,
                 ProbeSettings(limits_mm=LIMITS_MM, safe_z_mm=30.0))
    return read_probe_log(out)


def serve(faults=None, noise_um=0.0, machine=None, homing=False):
    emu = GrblEmulator(machine or scene(noise_um), ControllerConfig(home=(0, 0, 50), homing=homing),
                       faults=faults)
    return emu, TcpServer(emu, time_scale=TIME_SCALE).start()


def probe_args(url, plan, out, *extra):
    return ["probe", "--controller", url, "--plan", str(plan), "--out", str(out),
            "--limits-mm", LIMITS, "--safe-z-mm", "30", "--timeout-s", "5", *extra]


def assert_complete(log, plan, ref=None):
    """Row i is plan row i: nothing lost, nothing twice, time never backwards; with ``ref`` (the log of a run never
    stopped) every touch where that run's is, to the controller's quantisation."""
    assert log.n == plan.n
    assert list(log.columns["target"]) == list(plan.columns["target"])
    assert list(log.columns["setup"]) == list(plan.columns["setup"])
    t = log.columns["t_s"][log.ok]
    assert np.all(np.diff(t) >= 0)
    if ref is not None:
        assert np.abs(log.positions_mm() - ref.positions_mm()).max() < QUANT_MM


def test_campaign_through_vmt_probe_equals_the_backend(tmp_path, plan_path, capsys):
    """Noise 1 µm, same seed: the emulator draws the same noise; difference = GRBL's rounding."""
    plan = read_probe_log(plan_path)
    ref = direct_log(tmp_path, plan, noise_um=1.0)
    emu, srv = serve(noise_um=1.0)
    try:
        out = tmp_path / "log.csv"
        assert main(probe_args(srv.url, plan_path, out)) == 0
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert_complete(log, plan)
    assert np.all(log.ok)
    assert np.abs(log.positions_mm() - ref.positions_mm()).max() < QUANT_MM
    # the known errors show: without noise, sphere touches deviate by > 1 µm
    # (1.16 µm: 40 µm/m over ~60 mm, projected), more than the rounding
    clean = direct_log(tmp_path, plan, noise_um=0.0, name="clean.csv")
    assert np.abs(clean.dq_mm()).max() > 1e-3 > 1.5 * QUANT_MM
    assert "12 of 12 touches (12 new, 0 before" in capsys.readouterr().out
    # the controller under its own key (session 37; before, as the log's machine)
    assert log.meta["controller"] == srv.url and "started_unix" in log.meta


def test_virtual_machine_url_runs_the_same_campaign(tmp_path, plan_path):
    out = tmp_path / "v.csv"
    assert main(probe_args("virtual:", plan_path, out)) == 0
    assert_complete(read_probe_log(out), read_probe_log(plan_path))


def test_lost_connection_then_resume_is_complete_and_duplicate_free(tmp_path, plan_path, capsys):
    plan = read_probe_log(plan_path)
    ref = direct_log(tmp_path, plan)
    # probe 3 is made but its answer lost; probe 8 (the 7th touch) never happens
    emu, srv = serve(Faults(drop_after_probe=(3,), drop_before_probe=(8,)))
    out = tmp_path / "log.csv"
    try:
        assert main(probe_args(srv.url, plan_path, out)) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "connection lost" in err and "--resume" in err
        assert read_probe_log(out).n == 2
        assert main(probe_args(srv.url, plan_path, out, "--resume")) == 2
        assert read_probe_log(out).n == 6
        assert main(probe_args(srv.url, plan_path, out, "--resume")) == 0
        assert "6 before" in capsys.readouterr().out
        assert main(probe_args(srv.url, plan_path, out, "--resume")) == 0    # nothing left: no motion
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert_complete(log, plan, ref)
    assert emu.probes == plan.n + 2          # the two lost probes were made again


def test_resumed_progress_starts_at_the_rows_on_disk(tmp_path, plan_path, monkeypatch):
    """An interrupted run on the emulator (connection lost before probe 5: 4 rows on disk),
    then --resume: its progress line starts at 4/12 (run_campaign's on_start, before any motion)
    and counts on, so the time left is from this run's rate (viz.progress.TerminalProgress.begin);
    on main the first line was 5/12 and the estimate counted the 4 earlier touches as this run's."""
    import io

    import viz.progress

    class Tty(io.StringIO):
        def isatty(self):
            return True

    drawn = []

    class Recorded(viz.progress.TerminalProgress):
        def __init__(self, label, **kw):
            super().__init__(label, stream=Tty(), min_interval_s=0.0)
            drawn.append(self.stream)

    monkeypatch.setattr(viz.progress, "TerminalProgress", Recorded)
    plan = read_probe_log(plan_path)
    starts = []
    emu, srv = serve(Faults(drop_before_probe=(5,)))
    out = tmp_path / "log.csv"
    try:
        assert main(probe_args(srv.url, plan_path, out)) == 2
        assert read_probe_log(out).n == 4
        assert main(probe_args(srv.url, plan_path, out, "--resume")) == 0
        # the library's side: on_start once, with the rows on disk and the plan's, before any touch
        out2 = tmp_path / "again.csv"
        run_campaign(VirtualBackend(scene(), home_m=(0, 0, 0.05)), plan, out2, ProbeSettings(limits_mm=LIMITS_MM),
                     on_start=lambda d, n: starts.append((d, n)), on_touch=lambda row, _r: starts.append(row))
    finally:
        srv.stop()
    assert_complete(read_probe_log(out), plan)
    assert starts == [(0, 12)] + list(range(12))
    lines = [[x.strip() for x in t.getvalue().split("\r") if x.strip()] for t in drawn]
    counts = [[x.split("] ")[1].split(" ")[0] for x in run] for run in lines]
    assert counts == [[f"{k}/12" for k in range(0, 5)], [f"{k}/12" for k in range(4, 13)]]
    assert "left" not in lines[1][0] and "left" in lines[1][1] and "done in" in lines[1][-1]


@pytest.mark.parametrize("homing", [False, True])
def test_hard_limit_alarm_needs_a_reset_then_the_users_word(tmp_path, plan_path, capsys, homing):
    """ALARM:1, as GRBL: nothing answered until a reset, then $X or $H; vmt says so."""
    plan = read_probe_log(plan_path)
    emu, srv = serve(Faults(alarm_at_probe={5: 1}), homing=homing)    # a hard limit on probe 5
    out = tmp_path / "log.csv"
    word = "--home-cycle" if homing else "--unlock"
    try:
        first = ["--home-cycle"] if homing else []
        assert main(probe_args(srv.url, plan_path, out, *first)) == 2
        err = capsys.readouterr().err
        assert "ALARM:1 (hard limit" in err and "--resume --reset --home-cycle" in err
        # --unlock alone cannot help: the firmware answers nothing until a reset
        assert main(probe_args(srv.url, plan_path, out, "--resume", word, "--timeout-s", "1")) == 2
        err = capsys.readouterr().err
        assert "did not answer a status query" in err and "--reset" in err and emu.state == "Alarm"
        assert read_probe_log(out).n == 4
        # a reset alone leaves the alarm lock: nothing is sent without the user's word
        assert main(probe_args(srv.url, plan_path, out, "--resume", "--reset")) == 2
        assert "controller in alarm, nothing sent" in capsys.readouterr().err
        assert main(probe_args(srv.url, plan_path, out, "--resume", "--reset", word)) == 0
    finally:
        srv.stop()
    assert_complete(read_probe_log(out), plan)


def test_missed_touch_g38_2_alarm_5_is_logged_once(tmp_path):
    plan = plan_log(miss_rows=(2,))
    plan_path = write_probe_log(tmp_path / "plan.csv", plan)
    emu, srv = serve()
    out = tmp_path / "log.csv"
    try:
        assert main(probe_args(srv.url, plan_path, out)) == 2
        assert read_probe_log(out).n == 3 and emu.alarm == 5
        assert main(probe_args(srv.url, plan_path, out, "--resume", "--unlock")) == 0
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert_complete(log, plan)
    assert list(log.col("status")).count("no_trigger") == 1 and log.col("status")[2] == "no_trigger"
    assert np.isnan(log.columns["X_mm"][2])        # probe-log/1: invalid touch, empty measured cells


def test_allow_miss_g38_3_goes_on(tmp_path):
    plan_path = write_probe_log(tmp_path / "plan.csv", plan_log(miss_rows=(1, 6)))
    emu, srv = serve()
    out = tmp_path / "log.csv"
    try:
        assert main(probe_args(srv.url, plan_path, out, "--allow-miss")) == 0
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert [i for i, s in enumerate(log.col("status")) if s != "ok"] == [1, 6]


def test_garbage_lines_are_reported_and_never_taken(tmp_path, plan_path, capsys):
    plan = read_probe_log(plan_path)
    ref = direct_log(tmp_path, plan)
    emu, srv = serve(Faults(garbage_every=2))
    out = tmp_path / "log.csv"
    try:
        assert main(probe_args(srv.url, plan_path, out)) == 0
    finally:
        srv.stop()
    err = capsys.readouterr().err
    assert "unexpected line from controller" in err
    log = read_probe_log(out)
    assert_complete(log, plan, ref)


class _Slow:
    """A machine that takes 50 ms per probing move, so a kill lands mid-campaign."""

    def __init__(self, machine):
        self.machine = machine

    def probe_move(self, a, b, rot):
        time.sleep(0.05)
        return self.machine.probe_move(a, b, rot)


def _rows(path):
    return [x for x in path.read_text().splitlines() if not x.startswith("#")][1:] if path.exists() else []


def _wait_rows(path, n, seconds):
    """Wait until the log at ``path`` holds ``n`` touch rows (its header and comments aside), or ``seconds`` pass."""
    end = time.monotonic() + seconds
    while len(_rows(path)) < n and time.monotonic() < end:
        time.sleep(0.01)


def test_killed_process_and_torn_line_then_resume(tmp_path, plan_path):
    plan = read_probe_log(plan_path)
    ref = direct_log(tmp_path, plan)
    emu, srv = serve(machine=_Slow(scene()))
    out = tmp_path / "log.csv"
    try:
        proc = subprocess.Popen([sys.executable, "-m", "scenarios.cli",
                                 *probe_args(srv.url, plan_path, out)],
                                cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        _wait_rows(out, 5, 15)
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=10)
        n_before = read_probe_log(out).n
        assert 5 <= n_before < plan.n
        with open(out, "ab") as f:                      # a torn line, as if killed mid-write
            f.write(b"sphere,s9,12.0,61.2")
        assert main(probe_args(srv.url, plan_path, out, "--resume")) == 0
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert_complete(log, plan, ref)


@pytest.mark.parametrize("sig, rc, said", [(signal.SIGINT, 130, "interrupted"),
                                           (signal.SIGTERM, 143, "terminated (SIGTERM)")])
def test_ctrl_c_and_sigterm_say_the_rows_kept_and_resume(tmp_path, plan_path, sig, rc, said):
    """review30 F7: Ctrl-C said only 'vmt probe: interrupted' and SIGTERM nothing (rc 143) where a lost connection
    says '[60 of 368 rows in LOG; continue with --resume]'. Both now say it, the rows it counts are the log's, and
    --resume completes the campaign on the emulator as a run never stopped would have."""
    plan = read_probe_log(plan_path)
    ref = direct_log(tmp_path, plan)
    emu, srv = serve(machine=_Slow(scene()))
    out = tmp_path / "log.csv"
    try:   # SIGINT as the default handler takes it, even when this test runs with it ignored (a background job)
        proc = subprocess.Popen([sys.executable, "-m", "scenarios.cli", *probe_args(srv.url, plan_path, out)],
                                cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.default_int_handler))
        _wait_rows(out, 3, 30)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
        assert proc.returncode == rc, err
        last = err.strip().splitlines()[-1]
        m = re.fullmatch(rf"vmt probe: {re.escape(said)} \[(\d+) of {plan.n} rows in (.+); continue with --resume\]",
                         last)
        assert m and m.group(2) == str(out), err
        n_before = read_probe_log(out).n
        assert 3 <= n_before < plan.n and int(m.group(1)) == n_before
        assert main(probe_args(srv.url, plan_path, out, "--resume")) == 0
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert_complete(log, plan, ref)


def test_recover_cuts_a_torn_line_and_refuses_another_plan(tmp_path, plan_path):
    plan = read_probe_log(plan_path)
    ref_path = tmp_path / "direct.csv"
    direct_log(tmp_path, plan)
    text = ref_path.read_text()
    cut = text[: text.index("sphere,s3")] + "sphere,s3,0.1"
    ref_path.write_text(cut)
    rec = recover_log(ref_path, plan)
    assert rec.rows_done == 7 and rec.torn_bytes == len("sphere,s3,0.1")
    assert ref_path.read_text().endswith("\n")
    other = plan_log(n_sphere=6)
    with pytest.raises(PlanError, match="not plan row 5"):
        recover_log(ref_path, other)


def test_recover_leaves_a_file_that_is_not_a_log_of_the_plan_whole(tmp_path, plan_path, capsys):
    """recover_log cut the last line without its newline before it looked at the file: a gzip
    log lost the bytes after its last newline byte, a log of another plan lost its last
    line, and only then were they refused. Now each is refused and its bytes are as they were;
    a torn line that ends inside a UTF-8 character is still cut (and its rows recovered)."""
    import gzip

    plan = read_probe_log(plan_path)
    direct_log(tmp_path, plan)
    text = (tmp_path / "direct.csv").read_text()
    torn = text[: text.index("sphere,s3")] + "sphere,s3,0.1"
    packed = tmp_path / "packed.csv"
    body = gzip.compress(torn.encode(), mtime=0)
    assert not body.endswith(b"\n")  # the bytes after its last newline byte were cut as a "torn line"
    packed.write_bytes(body)
    with pytest.raises(ProbeLogError, match="gzip-compressed, not text"):
        recover_log(packed, plan)
    assert packed.read_bytes() == body
    other = tmp_path / "other.csv"
    other.write_text(torn)
    with pytest.raises(PlanError, match="not plan row 5"):
        recover_log(other, plan_log(n_sphere=6))
    assert other.read_text() == torn
    cut = torn.encode() + "\u00b5".encode()[:1]  # the first byte of a 2-byte character
    other.write_bytes(cut)
    rec = recover_log(other, plan)
    assert rec.rows_done == 7 and rec.torn_bytes == len("sphere,s3,0.1") + 1
    assert other.read_text() == text[: text.index("sphere,s3")]
    emu, srv = serve()  # the CLI: vmt probe --resume on it, one line, exit 2, the file whole
    try:
        assert main(probe_args(srv.url, plan_path, packed, "--resume")) == 2
    finally:
        srv.stop()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "gzip-compressed, not text" in err and emu.probes == 0
    assert packed.read_bytes() == body


def test_no_nan_height_passes_the_soft_limits(tmp_path, plan_path, capsys):
    """--safe-z-mm nan passed every soft-limit comparison (NaN compares false): 'vmt machine program'
    wrote 'G1 X0 Y0 Znan' and 'vmt probe' sent it to the controller. Refused before any connection or
    file, named by its option; check_program counts a NaN point outside the limits on its own; the
    settings' other refusals name their options too (not 'probe_feed_mm_min 0.0 ...')."""
    from hardware.campaign import Step, check_program

    emu, srv = serve()
    out = tmp_path / "log.csv"
    try:
        for extra, said in ((["--safe-z-mm", "nan"], "vmt probe: error: --safe-z-mm nan must be a finite number"),
                            (["--feed-mm-min", "0"], "vmt probe: error: --feed-mm-min 0.0 must be a positive number"),
                            (["--clearance-mm", "-1"], "vmt probe: error: --clearance-mm -1.0 must be a positive "
                                                       "number")):
            assert main(probe_args(srv.url, plan_path, out, *extra)) == 2
            assert capsys.readouterr().err == said + "\n"
        assert srv.connections == 0 and not out.exists()
    finally:
        srv.stop()
    ngc = tmp_path / "p.ngc"
    assert main(["machine", "program", "--plan", str(plan_path), "--out", str(ngc), "--probe-file", "p.txt",
                 "--limits-mm", LIMITS, "--safe-z-mm", "nan"]) == 2
    assert capsys.readouterr().err == "vmt machine program: error: --safe-z-mm nan must be a finite number\n"
    assert not ngc.exists()
    settings = ProbeSettings(limits_mm=((0, 10), (0, 10), (0, 10)))
    nan_step = Step(0, "S1", "t0", np.array([1.0, 1.0, np.nan]), np.array([1.0, 1.0, 1.0]), np.zeros(3))
    with pytest.raises(PlanError, match="outside the soft limits of Z"):
        check_program([nan_step], settings)


def test_safety_checks_before_any_connection(tmp_path, plan_path, capsys):
    emu, srv = serve()
    out = tmp_path / "log.csv"
    try:
        bad = [(["--limits-mm", "X-20:200,Y-20:200,Z-1:100"], "outside the soft limits"),
               (["--max-feed-mm-min", "500"], "exceeds the maximum feed"),
               (["--limits-mm", "X1:0,Y0:1,Z0:1"], "min < max"),
               (["--limits-mm", "X0:1,Y0:1"], "give X, Y and Z")]
        for extra, msg in bad:
            assert main(probe_args(srv.url, plan_path, out, *extra)) == 2
            err = capsys.readouterr().err
            assert msg in err and err.count("\n") == 1
        args = probe_args(srv.url, plan_path, out)
        i = args.index("--limits-mm")
        assert main(args[:i] + args[i + 2:]) == 2
        assert "without them" in capsys.readouterr().err
        assert srv.connections == 0 and not out.exists()
        # a log that exists is never overwritten
        out.write_text("precious\n")
        assert main(probe_args(srv.url, plan_path, out)) == 2
        assert "use --resume" in capsys.readouterr().err and out.read_text() == "precious\n"
        # a campaign log is not a plan
        assert main(probe_args(srv.url, plan_path, tmp_path / "x.csv")) == 0
        assert main(probe_args(srv.url, tmp_path / "x.csv", tmp_path / "y.csv")) == 2
        assert "measured columns must be empty" in capsys.readouterr().err
    finally:
        srv.stop()


def test_dry_run_prints_the_program_and_moves_nothing(tmp_path, plan_path, capsys):
    emu, srv = serve()
    try:
        assert main(probe_args(srv.url, plan_path, tmp_path / "log.csv", "--dry-run")) == 0
    finally:
        srv.stop()
    out = capsys.readouterr().out
    assert out.count("G38.2") == 12 and "G53 G90 G1" in out
    assert srv.connections == 0 and not (tmp_path / "log.csv").exists()


class _Warm:
    """A machine with a temperature sensor that warms by 0.1 degC per touch."""

    def __init__(self, machine):
        self.machine, self.k = machine, 0

    def probe_move(self, a, b, rot):
        self.k += 1
        return self.machine.probe_move(a, b, rot)

    def temperatures_C(self):
        return {"spindle": 20.0 + 0.1 * self.k}


def test_temperatures_are_logged_and_kept_on_resume(tmp_path, plan_path):
    plan = read_probe_log(plan_path)
    out = tmp_path / "log.csv"
    machine = _Warm(scene())
    settings = ProbeSettings(limits_mm=LIMITS_MM, safe_z_mm=30.0)

    class Flaky(VirtualBackend):
        fail_at = 5

        def probe(self, *a, **k):
            if self.machine.k + 1 == self.fail_at:
                self.fail_at = None
                raise HardwareError("connection lost (test)")
            return super().probe(*a, **k)

    with pytest.raises(HardwareError, match=r"4 of 12 rows .* --resume"):
        run_campaign(Flaky(machine), plan, out, settings)
    run_campaign(VirtualBackend(machine), plan, out, settings, resume=True)
    log = read_probe_log(out)
    assert_complete(log, plan)
    assert np.allclose(log.columns["temp_spindle_C"], 20.0 + 0.1 * np.arange(1, 13))


def test_rotary_plan_needs_rotary_controller(tmp_path, capsys):
    plan = plan_log()
    cols = dict(plan.columns)
    cols["C_deg"] = np.where(np.arange(plan.n) < 6, 0.0, 90.0)
    from core.probelog import make_log

    p = write_probe_log(tmp_path / "plan.csv", make_log(cols, plan.meta))
    assert main(probe_args("grbl://127.0.0.1:1", p, tmp_path / "o.csv")) == 2
    assert "row 6 needs rotary axes" in capsys.readouterr().err


class _Slower(_Slow):
    """0.4 s per probing move: a 12-touch campaign lasts about 5 s."""

    def probe_move(self, a, b, rot):
        time.sleep(0.4)
        return self.machine.probe_move(a, b, rot)


def test_second_writer_is_refused_while_the_first_writes(tmp_path, plan_path, capsys):
    """Two processes, one log: `vmt probe --resume` in a subprocess holds the lock; a second
    `vmt probe --resume` (this process) is refused with one line naming the log, and changes nothing."""
    plan = read_probe_log(plan_path)
    ref = direct_log(tmp_path, plan)
    out = tmp_path / "log.csv"
    emu, srv = serve(machine=_Slower(scene()), homing=True)
    try:
        assert main(probe_args("virtual:", plan_path, out)) == 0       # a finished log, cut back to 3 rows
        text = out.read_text()
        head = [x for x in text.splitlines(True) if x.startswith("#") or x.startswith("setup")]
        out.write_text("".join(head + [x for x in text.splitlines(True)
                                       if not (x.startswith("#") or x.startswith("setup"))][:3]))
        # the log's rows were made on another machine (virtual:): the controller's position is not
        # where the log left it, so the resume homes it (hardware.campaign.resume_frame_problem)
        first = subprocess.Popen([sys.executable, "-m", "scenarios.cli",
                                  *probe_args(srv.url, plan_path, out, "--resume", "--home-cycle")],
                                 cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        _wait_rows(out, 4, 30)                                          # the first writer is at work
        assert len(_rows(out)) >= 4 and first.poll() is None
        before = out.read_bytes()
        capsys.readouterr()
        assert main(probe_args("virtual:", plan_path, out, "--resume")) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err
        assert f"{out}: another process is writing this log right now" in err
        assert out.read_bytes()[:len(before)] == before                # nothing cut, nothing added by us
        o, e = first.communicate(timeout=60)
        assert first.returncode == 0, e
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert_complete(log, plan, ref)                                    # 12 rows, none twice
    # the lock dies with its holder: after the first writer, resuming is allowed (nothing left)
    assert main(probe_args("virtual:", plan_path, out, "--resume")) == 0


def test_lock_is_kept_from_creation_and_recovery_respects_it(tmp_path, plan_path):
    """A log created by AppendLog is locked from the moment it exists; recover_log will not cut
    a line under a live writer; a killed holder releases the lock."""
    plan = read_probe_log(plan_path)
    out = tmp_path / "log.csv"
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys; from hardware.campaign import AppendLog; "
         f"AppendLog.create({str(out)!r}, ['setup', 'target'], {{'format': 'probe-log/1'}}); "
         "print('locked', flush=True); sys.stdin.read()"],
        cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(PlanError, match=r"log.csv: another process is writing this log"):
            recover_log(out, plan)
        with pytest.raises(PlanError, match=r"another process is writing this log"):
            run_campaign(VirtualBackend(scene()), plan, out, ProbeSettings(limits_mm=LIMITS_MM), resume=True)
    finally:
        holder.kill()
        holder.wait(10)
    with pytest.raises(ProbeLogError, match=r"missing required column 't_s'"):  # lock gone; the content speaks
        recover_log(out, plan)


def test_measured_log_does_not_claim_the_simulators_provenance(tmp_path, capsys):
    """A plan written by the simulator carries its generator and settings; the measured log keeps
    them as the plan's (``plan_<key>``), never as its own (review F7: a `vmt probe` log said
    ``generator: vmt sim.campaign`` and ``feed_mm_per_min: 240`` beside the real probing feed).
    What the analysis reads about the part and the machine stays under its name. The LinuxCNC
    import (hardware.campaign.log_from_plan) follows the same rule."""
    from core.probelog import make_log
    from hardware.campaign import PLAN_META_KEPT

    base = plan_log()
    sim_meta = {"machine": "nmv3000", "artefact": "table+sphere", "stylus_r_mm": "1.5",
                "kinematic_chain": "V[w-C-A-b-Y-X-Z-(C)-t]", "probe_repeatability_k2_um": "0.25",
                "feed_mm_per_min": "240.0", "generator": "vmt sim.campaign", "planner": "by hand",
                "plan_origin": "a plan's own plan_ key"}
    plan_p = write_probe_log(tmp_path / "plan.csv", make_log(dict(base.columns), sim_meta))
    out = tmp_path / "log.csv"
    assert main(probe_args("virtual:", plan_p, out)) == 0
    pf = tmp_path / "probe.txt"
    pf.write_text("".join(f"{x:f} {y:f} {z:f}\n" for x, y, z in read_probe_log(out).positions_mm()))
    imp = tmp_path / "imported.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan_p), "--out", str(imp)]) == 0
    for path in (out, imp):
        meta = read_probe_log(path).meta
        for k in ("generator", "probe_repeatability_k2_um", "feed_mm_per_min", "planner"):  # ('planner' too)
            assert k not in meta and meta[f"plan_{k}"] == sim_meta[k], (path.name, k)
        # the plan's machine is the log's (its kinematic model: what a state identified from it holds), the
        # controller under its own key (session 37; before, machine named the controller, plan_machine the plan's)
        assert meta["machine"] == "nmv3000" and "plan_machine" not in meta
        assert meta["controller"] == ("virtual:builtin" if path == out else "linuxcnc")
        assert meta["plan_origin"] == sim_meta["plan_origin"] and "plan_plan_origin" not in meta
        assert all(meta[k] == sim_meta[k] for k in PLAN_META_KEPT)
    assert float(read_probe_log(out).meta["probe_feed_mm_min"]) == 100.0     # the feed it probed at


def test_early_trigger_alarm_4_is_logged_like_import_reads_it(tmp_path, plan_path, capsys):
    """Review 27 (a): ALARM:4 (the probe already triggered before the move) stopped `vmt probe` without a row,
    while `vmt import grbl` reads the same alarm as an `early_trigger` touch and ALARM:5 is logged
    `no_trigger`. Now the touch is logged `early_trigger` (empty measured cells), the run stops on the alarm
    with what to do, and --resume --unlock goes on from the next row to a complete log."""
    plan = read_probe_log(plan_path)
    emu, srv = serve(Faults(alarm_at_probe={5: 4}))     # probe 5 = plan row 4 finds the probe triggered
    out = tmp_path / "log.csv"
    try:
        assert main(probe_args(srv.url, plan_path, out)) == 2
        err = capsys.readouterr().err
        assert "ALARM:4" in err and "logged as early_trigger" in err and "--resume --unlock" in err
        log = read_probe_log(out)
        assert log.n == 5 and log.col("status")[4] == "early_trigger" and emu.alarm == 4
        assert main(probe_args(srv.url, plan_path, out, "--resume", "--unlock")) == 0
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert_complete(log, plan)
    st = list(log.col("status"))
    assert st.count("early_trigger") == 1 and st[4] == "early_trigger" and st.count("ok") == plan.n - 1
    assert np.isnan(log.columns["X_mm"][4])        # probe-log/1: an invalid touch, empty measured cells


# ---------------------------------------------------------------- a controller reset between sessions (review29 F1)

def test_resume_after_a_controller_reset_is_refused_until_homed(tmp_path, plan_path, capsys):
    """Opening an Arduino GRBL's serial port resets it (DTR): GRBL's main() sets the machine position to 0
    where the machine stands, in alarm when homing is enabled. On main a resume after such a reset went on
    in the new frame (--unlock sent $X): every later row off by the machine's former position. The
    emulator behind a bridge that opens the port per client (on_connect="reset") refuses the resume in
    one line, nothing moved and the log kept, with --unlock too; --home-cycle ($H) resumes it, whole."""
    plan = read_probe_log(plan_path)
    ref = direct_log(tmp_path, plan)
    emu, srv = serve(Faults(drop_before_probe=(6,)), homing=True)
    out = tmp_path / "log.csv"
    try:
        assert main(probe_args(srv.url, plan_path, out, "--home-cycle")) == 2     # the link drops: 5 rows
        assert read_probe_log(out).n == 5
        capsys.readouterr()
        before, probes = out.read_bytes(), emu.probes
        srv.on_connect = "reset"
        for extra in ((), ("--unlock",)):
            assert main(probe_args(srv.url, plan_path, out, "--resume", *extra)) == 2
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and "Traceback" not in err
            assert f"{out}: not resumed, nothing moved, the log kept (5 of 12 rows)" in err
            assert "X0.000 Y0.000 Z0.000 mm" in err and "the controller was reset" in err
            assert "re-run with --resume --home-cycle" in err
            assert out.read_bytes() == before and emu.probes == probes and np.allclose(emu.pos_mm, 0)
        assert main(probe_args(srv.url, plan_path, out, "--resume", "--home-cycle")) == 0
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert_complete(log, plan, ref)


def test_resume_without_a_reset_goes_on_whatever_the_greeting(tmp_path, plan_path, capsys):
    """A reconnect without a reset keeps the machine position: GRBL behind a bridge that holds its port
    prints nothing (on_connect="silent"), a network controller greets (the default): both resume."""
    plan = read_probe_log(plan_path)
    ref = direct_log(tmp_path, plan)
    emu, srv = serve(Faults(drop_before_probe=(4, 9)))
    out = tmp_path / "log.csv"
    try:
        assert main(probe_args(srv.url, plan_path, out)) == 2
        assert read_probe_log(out).n == 3
        srv.on_connect = "silent"
        assert main(probe_args(srv.url, plan_path, out, "--resume")) == 2         # the second drop
        assert read_probe_log(out).n == 7
        srv.on_connect = "greet"
        assert main(probe_args(srv.url, plan_path, out, "--resume")) == 0
    finally:
        srv.stop()
    log = read_probe_log(out)
    assert_complete(log, plan, ref)
    assert np.allclose(emu.frame_mm, 0)


def test_a_banner_when_a_serial_port_opens_is_a_reset(tmp_path, plan_path, capsys):
    """Over a serial link GRBL prints its banner only on a reset, and opening the port resets an Arduino:
    the resume is refused naming the banner and the port (before the position is even read); without
    homing ($22=0) the log cannot be tied to the new frame and the message says so."""
    from hardware.emulator import PtyServer

    plan = read_probe_log(plan_path)
    emu, srv = serve(Faults(drop_before_probe=(6,)))
    out = tmp_path / "log.csv"
    pty = None
    try:
        assert main(probe_args(srv.url, plan_path, out)) == 2
        before = out.read_bytes()
        pty = PtyServer(srv.runner).start()
        pty.power_cycle()                       # the board resets as the host opens its port (DTR)
        capsys.readouterr()
        assert main(probe_args(pty.url, plan_path, out, "--resume")) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and out.read_bytes() == before
        assert "printed its start-up banner (\"Grbl 1.1h ['$' for help]\")" in err
        assert f"when {pty.url} was opened" in err and "start a new log" in err
    finally:
        if pty is not None:
            pty.stop()
        srv.stop()
    assert read_probe_log(out).n == 5 and plan.n == 12


class _Stands:
    """A backend that stands where it is told and keeps its position across connections."""

    keeps_position = True

    def __init__(self, at_mm, banner=None):
        self.at, self.banner = np.asarray(at_mm, float), banner

    def position_m(self):
        return self.at * 1e-3

    def reset_at_connect(self):
        return self.banner


def test_resume_position_tolerance_is_5_mm_from_the_path():
    """RESUME_POSITION_TOL_MM: anywhere on the path the last logged row left the machine on (its probing
    segment, its retract, the moves to the next row and that row's probing segment) resumes; a jog of
    4.9 mm off it too (clearing a probe found in contact); 5.1 mm off, or machine zero, does not."""
    from hardware.campaign import RESUME_POSITION_TOL_MM, plan_steps, resume_frame_problem

    assert RESUME_POSITION_TOL_MM == 5.0
    st = ProbeSettings(limits_mm=LIMITS_MM, safe_z_mm=30.0)
    steps = plan_steps(plan_log(), st)                  # row 2: table (90, 90, 0) -> row 3: (10, 90, 0)
    a, b = steps[2], steps[3]
    on_path = [a.end_mm, a.start_mm, (90, 90, 30), (50, 90, 30), (10, 90, 30), (10, 90, 10), b.start_mm, b.end_mm]
    for p in on_path:
        assert resume_frame_problem(_Stands(p), steps, 3, st) is None
    assert resume_frame_problem(_Stands((50, 94.9, 30)), steps, 3, st) is None
    why = resume_frame_problem(_Stands((50, 95.1, 30)), steps, 3, st)
    assert "5.1 mm from the path the log's last row (row 2)" in why and "X90.000 Y90.000 Z2.000" in why
    assert "90.6 mm from" in resume_frame_problem(_Stands((0, 0, 0)), steps, 3, st)   # a reset: 0 where it stood
    assert resume_frame_problem(_Stands((0, 0, 0)), steps, 0, st) is None          # no row logged: no frame yet
    assert resume_frame_problem(_Stands(a.start_mm, banner="reset"), steps, 3, st) == "reset"
    assert resume_frame_problem(VirtualBackend(scene(), home_m=(0, 0, 0.05)), steps, 3, st) is None
