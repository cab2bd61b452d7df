"""The README's hardware commands, as written, against the GRBL emulator of the simulated machine.

``vmt simulate cross-pocket --plan-only``, then ``vmt machine serve ...
--scene cross-pocket`` (a process, as a user starts it) and ``vmt probe
--controller grbl://... --rotary``: the README's lines, except the port, which
the test picks free (5000 may be taken on a shared machine). The campaign
through GRBL must give, touch by touch, the direct simulation's touches
within GRBL's rounding: reports carry 3 decimals in mm (0.5 µm), commands 4
(0.05 µm), the trigger moves by at most about as much: 0.6 µm per coordinate.
"""

import re
import shlex
import signal
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np

from core.probelog import read_probe_log
from core.selfcal import Grid, self_calibrate
from core.touches import from_log
from scenarios.cli import main
from scenarios.hidden import gauge_free_rms_m
from sim import artefacts as A
from sim.campaign import simulate_campaign
from sim.machine import Machine
from sim.machines import MACHINES, realistic_errors
from sim.probe import ProbeConfig

ROOT = Path(__file__).resolve().parents[2]
QUANT_MM = 0.6e-3


def readme_hardware_commands():
    """The plan, serve and probe lines of the README's command block (comments cut)."""
    return (readme_command("vmt simulate cross-pocket --plan-only"), readme_command("vmt machine serve"),
            readme_command("vmt probe --controller grbl://"))


def readme_command(prefix):
    """The line of the README's "Command line" blocks that starts with ``prefix`` (comment cut)."""
    section = (ROOT / "README.md").read_text().split("## Command line", 1)[1].split("\n## ", 1)[0]
    lines = [ln for block in section.split("```")[1::2] for ln in block.splitlines()]
    return next(re.split(r"\s+#", ln)[0].strip() for ln in lines if ln.startswith(prefix))


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_readme_hardware_commands_as_written(tmp_path, monkeypatch, capsys):
    plan_cmd, serve_cmd, probe_cmd = readme_hardware_commands()
    assert "--safe-z-mm" in probe_cmd and "--rotary" in probe_cmd and "--scene cross-pocket" in serve_cmd
    port = str(_free_port())
    serve = [port if a == "5000" else a for a in shlex.split(serve_cmd)[1:]]
    probe = [a.replace(":5000", f":{port}") for a in shlex.split(probe_cmd)[1:]]
    monkeypatch.chdir(tmp_path)
    assert main(shlex.split(plan_cmd)[1:]) == 0
    plan = read_probe_log(tmp_path / "plan.csv")
    # the dry run: every row is approached from the safe Z, never straight across the part
    capsys.readouterr()
    assert main(probe + ["--dry-run"]) == 0
    cap = capsys.readouterr()
    lines = cap.out.splitlines()
    firsts = [lines[i + 1] for i, ln in enumerate(lines) if ln.startswith("(row ")]
    assert len(firsts) == plan.n and all(" Z80.0000 " in ln for ln in firsts)
    # without a controller the dry run cannot know its axes: it says so, and --axes names them
    assert "no --axes" in cap.err and re.search(r" B-?\d", cap.out)
    assert main(probe + ["--dry-run", "--axes", "XYZAC"]) == 0
    out = capsys.readouterr().out
    assert not re.search(r" B-?\d", out) and re.search(r" C-?\d", out)
    assert main(probe + ["--dry-run", "--axes", "XYQ"]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    # the README's LinuxCNC part program, as written, on the same plan
    assert main(shlex.split(readme_command("vmt machine program"))[1:]) == 0, capsys.readouterr().err
    assert sum(ln.startswith("G38.2 ") for ln in (tmp_path / "probe.ngc").read_text().splitlines()) == plan.n
    # Ctrl-C must reach it even when this run was started with SIGINT ignored (a background job of a
    # non-interactive shell): an ignored SIGINT is inherited through exec, and the server then never stops
    proc = subprocess.Popen([sys.executable, "-m", "scenarios.cli", *serve], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        first = proc.stdout.readline()
        assert f"of axes XYZAC on grbl://127.0.0.1:{port}" in first, first + proc.stderr.read()
        assert main(probe) == 0
    finally:
        proc.send_signal(signal.SIGINT)          # Ctrl-C, as a user stops it
        try:
            out, err = proc.communicate(timeout=120)   # a busy machine: stopping waits for the last move
        except subprocess.TimeoutExpired:
            proc.kill()                          # never leave a server behind a failed test
            out, err = proc.communicate()
            raise AssertionError(f"machine serve did not stop within 120 s of Ctrl-C: {err[-500:]}") from None
    assert f"stopped after {plan.n} probing moves" in out, err
    log = read_probe_log(tmp_path / probe[probe.index("--out") + 1])   # the log the README's line names
    assert log.n == plan.n == 368 and log.ok.all()

    # the same campaign simulated directly on the same machine (serve --scene cross-pocket:
    # nmv3000, realistic errors of seed 1 without the ripple, no probing noise), built here
    # as it was before --errors named it "drawn"
    machine = Machine(MACHINES["nmv3000"](errors=realistic_errors(
        ("X", "Y", "Z", "C"), rng=np.random.default_rng(1), ripple=False)))
    angles = sorted(set(plan.col("C_deg")))
    direct = simulate_campaign(A.cross_pocket(), machine, ProbeConfig(repeatability_k2_m=0.0), angles,
                               np.random.default_rng(0))
    assert list(direct.col("target")) == list(log.col("target"))
    d = log.positions_mm() - direct.positions_mm()
    print(f"GRBL - direct: max |d| {np.abs(d).max() * 1e3:.3f} um, rms {np.sqrt(np.mean(d ** 2)) * 1e3:.3f} um")
    assert np.abs(d).max() < QUANT_MM
    grid = Grid.regular(-0.110, 0.110, 0.022)
    a, b = self_calibrate(from_log(direct), grid), self_calibrate(from_log(log), grid)
    ids = a.design.target_ids
    first_row = {k: list(plan.col("target")).index(k) for k in ids}
    w = {k: np.array([plan.col("wx_mm")[i], plan.col("wy_mm")[i]]) * 1e-3 for k, i in first_row.items()}
    wn = {k: np.array([plan.col("wnx")[i], plan.col("wny")[i]]) for k, i in first_row.items()}
    diff = gauge_free_rms_m(b.G, ids, dict(zip(ids, a.G)), w, wn)
    print(f"gauge-free workpiece difference {diff * 1e6:.3f} um")
    assert diff < 0.3e-6          # rounding of <= 0.5 um per touch, averaged over 4 C angles
