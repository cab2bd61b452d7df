"""`vmt machine serve` as a process: a campaign against it over TCP and over its pty."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import LIMITS
from core.probelog import read_probe_log
from scenarios.cli import main

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def server():
    proc = subprocess.Popen([sys.executable, "-m", "scenarios.cli", "machine", "serve", "--port", "0",
                             "--pty", "--stop-after-s", "30", "--time-scale", "200"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    urls = []
    try:
        for _ in range(2):
            line = proc.stdout.readline()
            urls.append(line.split()[-1].strip("()"))
        assert urls[0].startswith("grbl://127.0.0.1:") and urls[1].startswith("serial:///dev/")
        yield urls
    finally:
        proc.terminate()
        proc.communicate(timeout=10)


def test_campaign_over_tcp_and_pty_of_a_served_machine(tmp_path, plan_path, server):
    logs = []
    for k, url in enumerate(server):
        out = tmp_path / f"log{k}.csv"
        assert main(["probe", "--controller", url, "--plan", str(plan_path), "--out", str(out),
                     "--limits-mm", LIMITS, "--safe-z-mm", "30", "--timeout-s", "5"]) == 0
        logs.append(read_probe_log(out))
    assert logs[0].n == logs[1].n == 12
    # the built-in machine has no errors and no noise: both give the nominal points to 0.5 µm
    for log in logs:
        assert np.abs(log.dq_mm()).max() < 0.6e-3


def test_serve_bad_arguments_exit_2(capsys, plan_path, tmp_path):
    assert main(["machine", "serve", "--port", "70000"]) == 2
    assert "not a TCP port" in capsys.readouterr().err
    assert main(["machine", "serve", "--port", "0", "--scale-ppm", "1,2"]) == 2
    assert "three numbers" in capsys.readouterr().err
    assert main(["probe", "--controller", "http://x", "--plan", str(plan_path), "--out",
                 str(tmp_path / "o.csv"), "--limits-mm", LIMITS]) == 2
    assert "expected grbl://HOST:PORT" in capsys.readouterr().err
