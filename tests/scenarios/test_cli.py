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
    assert "turned" not in out
    cols["C_deg"] = [0, 90, 90]                  # set-up a turns: identify would refuse it, check says so
    p = write_probe_log(tmp_path / "turned.csv", make_log(cols))
    assert main(["check", str(p)]) == 0
    assert ("turned   set-up 'a': C varies within it (0..90 deg: row 0 at 0, row 1 at 90): identify and discover "
            "take one indexing per set-up and refuse it") in capsys.readouterr().out


def test_check_shows_progress_with_time_left(tmp_path, capsys, monkeypatch):
    """vmt check draws the shared progress line (viz.progress: time left) while it reads: a
    1e6-row log takes some 20 s. Blocks of 2 rows here (core.probelog.CHUNK_ROWS), so a
    7-row log reports after each block, then once validated, on a terminal."""
    import io

    import core.probelog
    import scenarios.cli.guard as guard
    from viz.progress import TerminalProgress

    class Tty(io.StringIO):
        def isatty(self):
            return True

    tty = Tty()
    monkeypatch.setattr(core.probelog, "CHUNK_ROWS", 2)
    monkeypatch.setattr(guard, "progress_line", lambda label: TerminalProgress(label, stream=tty, min_interval_s=0))
    n = 7
    cols = {"setup": ["a"] * n, "target": [str(i) for i in range(n)], "t_s": list(range(n)),
            "X_mm": list(range(n)), "Y_mm": [0] * n, "Z_mm": [0] * n, "Xn_mm": list(range(n)), "Yn_mm": [0] * n,
            "Zn_mm": [0] * n, "nx": [1] * n, "ny": [0] * n, "nz": [0] * n}
    p = write_probe_log(tmp_path / "ok.csv", make_log(cols))
    lines = p.read_text().splitlines()
    assert main(["check", str(p)]) == 0
    drawn = [s.rstrip() for s in tty.getvalue().split("\r") if s.strip()]
    first_row = len(lines) - n + 1  # the file line of the first row (after metadata and header)
    done = [first_row + 1, first_row + 3, first_row + 5]  # the last line of each full block of 2 rows
    assert [d.split("] ")[1].split(" ")[0] for d in drawn] == [f"{k}/{len(lines)}" for k in done + [len(lines)]]
    assert all(d.startswith("check: lines read: [") for d in drawn)
    assert "left" in drawn[0] and "done in" in drawn[-1]
    assert "touches  7 (7 ok)" in capsys.readouterr().out


def test_check_bad_log_one_line_exit_2_no_traceback(tmp_path, capsys):
    # in this process (a real process of `vmt check` exits 2 in tests/test_fuzz_cli.py)
    p = tmp_path / "bad.csv"
    p.write_text("setup,target\n")
    assert main(["check", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and err.startswith("vmt check: error: "), err
    assert "missing required column 't_s'" in err


def test_missing_log_exit_2(tmp_path, capsys):
    assert main(["check", str(tmp_path / "none.csv")]) == 2
    assert "no such file" in capsys.readouterr().err
