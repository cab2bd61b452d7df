"""vmt view: only the error paths and the command construction (never a viewer)."""

import os
import subprocess
import sys

import pytest

from core.exceptions import VmtError
from scenarios.cli import view as cmd_view
from viz import viewer
from scenarios.cli import main


@pytest.fixture
def rrd(tmp_path):
    p = tmp_path / "run.rrd"
    p.write_bytes(b"RRF2")
    return p


@pytest.fixture
def fake_viewer(tmp_path):
    exe = tmp_path / "bin" / "rerun"
    exe.parent.mkdir()
    exe.write_text("#!/bin/sh\nexit 0\n")
    exe.chmod(0o755)
    return exe


def test_command_is_viewer_then_file(rrd, fake_viewer):
    assert viewer.viewer_command(rrd, env={"RERUN_CLI_PATH": str(fake_viewer)}) == \
        [str(fake_viewer), str(rrd)]


def test_default_viewer_is_the_installed_rerun_cli_binary(rrd):
    cmd = viewer.viewer_command(rrd, env={})
    assert os.path.basename(cmd[0]) in ("rerun", "rerun.exe") and cmd[1] == str(rrd)


def test_print_command_runs_nothing(rrd, capsys):
    assert main(["view", str(rrd), "--print-command"]) == 0
    out = capsys.readouterr().out.strip()
    assert out.endswith(str(rrd)) and "rerun" in out


def test_missing_file_one_line_exit_2(tmp_path):
    r = subprocess.run([sys.executable, "-m", "scenarios.cli", "view", str(tmp_path / "x.rrd")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "x.rrd: no such file" in r.stderr


def test_not_an_rrd(tmp_path):
    p = tmp_path / "log.csv"
    p.write_text("x")
    with pytest.raises(VmtError, match="expected a .rrd file"):
        viewer.viewer_command(p)


def test_no_viewer_found(rrd, tmp_path):
    with pytest.raises(VmtError, match="no rerun viewer found"):
        viewer.viewer_command(rrd, env={"RERUN_CLI_PATH": str(tmp_path / "nope")})


def test_no_display_exit_2(rrd, monkeypatch, capsys):
    monkeypatch.setattr(cmd_view, "has_display", lambda: False)
    monkeypatch.setattr(cmd_view.subprocess, "call", lambda *a, **k: pytest.fail("ran viewer"))
    assert main(["view", str(rrd)]) == 2
    assert "no display" in capsys.readouterr().err


def test_viewer_failing_to_start_exit_2(rrd, monkeypatch, capsys):
    monkeypatch.setattr(cmd_view, "has_display", lambda: True)
    monkeypatch.setattr(cmd_view.subprocess, "call", lambda cmd: 1)
    assert main(["view", str(rrd)]) == 2
    assert "viewer exited with status 1" in capsys.readouterr().err

    def boom(cmd):
        raise FileNotFoundError(2, "No such file or directory")
    monkeypatch.setattr(cmd_view.subprocess, "call", boom)
    assert main(["view", str(rrd)]) == 2
    assert "cannot start the rerun viewer" in capsys.readouterr().err


def test_has_display():
    assert not viewer.has_display({}, "linux")
    assert viewer.has_display({"WAYLAND_DISPLAY": "wayland-0"}, "linux")
    assert viewer.has_display({}, "darwin")
