import subprocess
import sys

import pytest

from core.probelog import make_log, write_probe_log
from scenarios.cli import main


def test_version_and_help(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.startswith("vmt ")
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "check" in capsys.readouterr().out


def test_check_summarises_a_valid_log(tmp_path, capsys):
    cols = {"setup": ["a", "a", "b"], "target": ["1", "2", "1"], "t_s": [0, 1, 2],
            "X_mm": [1, 2, 3], "Y_mm": [0, 0, 0], "Z_mm": [0, 0, 0],
            "Xn_mm": [1, 2, 3], "Yn_mm": [0, 0, 0], "Zn_mm": [0, 0, 0],
            "nx": [1, 1, 1], "ny": [0, 0, 0], "nz": [0, 0, 0], "C_deg": [0, 0, 90]}
    p = write_probe_log(tmp_path / "ok.csv", make_log(cols))
    assert main(["check", str(p)]) == 0
    out = capsys.readouterr().out
    assert "touches  3 (3 ok)" in out and "set-ups 2" in out and "0, 90 deg" in out


def test_check_bad_log_one_line_exit_2_no_traceback(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("setup,target\n")
    r = subprocess.run([sys.executable, "-m", "scenarios.cli", "check", str(p)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "missing required column 't_s'" in r.stderr


def test_missing_log_exit_2(tmp_path, capsys):
    assert main(["check", str(tmp_path / "none.csv")]) == 2
    assert "no such file" in capsys.readouterr().err
