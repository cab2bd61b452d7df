"""The reader's warnings reach the user of every command that reads a log (session 31, warn31; input31 noticed).

The probe-log and positioning-log readers warn without refusing (an empty angle cell read as 0 beside written
ones, a file that ends without an end of line); before warn31 only ``vmt check`` printed them, and ``discover``,
``identify``, ``fit``, ``design``, ``vcmm``, ``machine program``, ``import``, ``probe`` read the same file silently.
Every command now reads through :mod:`scenarios.cli.reading`: each warning once on stderr as
``vmt COMMAND: warning: ...``, and in the command's JSON (where it writes one) as ``input_warnings``.

The files: review31's square-pocket campaign (tests/core/data/input31/mylog.csv) with its one C_deg cell of set-up
C0 emptied (read as 0, the set-up's own angle, so every command goes on to its result; review31's own
mylog_emptyC.csv empties one in C75, which identify and discover then refuse, warning first), the README's vcmm plan
and the project's ISO 230-2 sample each cut at their last end of line (the last field a number: read whole, warned).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from core.positioning import read_positioning_log
from core.probelog import read_probe_log
from scenarios.cli import main
from scenarios.positioning_sample import SAMPLE

sys.path.insert(0, str(Path(__file__).parents[1] / "core"))
sys.path.insert(0, str(Path(__file__).parent))
from test_input31 import MYLOG, blanked  # noqa: E402  (the reviewer's files, made as input31 makes them)

PLAN = Path("scenarios/data/vcmm-block-plan.csv")
TASK = "scenarios/data/vcmm-block-task.toml"


@pytest.fixture
def empty_c0(tmp_path) -> tuple[Path, str]:
    p = blanked(MYLOG, tmp_path / "emptyC0.csv", {"C_deg": [0]})
    w = read_probe_log(p).warnings
    assert len(w) == 1 and "column 'C_deg' is empty: read as 0" in w[0]   # the reader warns (input31)
    return p, w[0]


def _said_once(err: str, command: str, warning: str) -> None:
    lines = [s for s in err.splitlines() if "warning:" in s]
    assert lines == [f"vmt {command}: warning: {warning}"], err


@pytest.mark.parametrize("command, argv", [
    ("discover", ["discover", "{log}", "--json", "{out}"]),
    ("identify", ["identify", "{log}", "--json", "{out}"]),
    ("design", ["design", "--plan", "{log}", "--n-angles", "4", "--step-deg", "45", "--json", "{out}"]),
])
def test_probe_log_analyses_say_the_readers_warning_and_carry_it(tmp_path, capsys, empty_c0, command, argv):
    log, warning = empty_c0
    out = tmp_path / "out.json"
    assert main([a.format(log=log, out=out) for a in argv]) == 0
    cap = capsys.readouterr()
    _said_once(cap.err, command, warning)
    assert warning not in cap.out                       # stderr, not the command's output
    assert json.loads(out.read_text())["input_warnings"] == [warning]


def test_the_reviewers_empty_c75_cell_is_said_before_the_refusal(tmp_path, capsys):
    """review31's mylog_emptyC.csv (C75's row 36 empty): identify refuses the set-up whose C varies; the reader's
    warning, which says why (the empty cell read as 0), comes first."""
    p = blanked(MYLOG, tmp_path / "emptyC.csv", {"C_deg": [36]})
    for command in ("discover", "identify"):
        assert main([command, str(p), "--json", str(tmp_path / "o.json")]) == 2
        err = capsys.readouterr().err.splitlines()
        assert err[0] == f"vmt {command}: warning: {p}: row 36 (line 44): column 'C_deg' is empty: read as 0, " \
                         "the format's default (1 empty cell of 144)", err
        assert err[1].startswith(f"vmt {command}: error: ")


def test_fit_says_the_readers_warning_and_carries_it(tmp_path, capsys):
    """A wall at two heights (test_fit_normals_cli's) cut at its last end of line (the last field nz, a number)."""
    from test_fit_normals_cli import _wall_log

    p = _wall_log(tmp_path / "wall.csv", [-5.0, -10.0])
    p.write_text(p.read_text().rstrip("\n"))
    (warning,) = read_probe_log(p).warnings
    assert "ends without an end of line" in warning
    out = tmp_path / "f.json"
    assert main(["fit", "plane", str(p), "--setup", "C0", "--feature", "wallE", "--json", str(out)]) == 0
    cap = capsys.readouterr()
    _said_once(cap.err, "fit", warning)
    assert warning not in cap.out
    assert json.loads(out.read_text())["input_warnings"] == [warning]


@pytest.fixture
def cut_plan(tmp_path) -> tuple[Path, str]:
    p = tmp_path / "plan.csv"
    p.write_text(PLAN.read_text().rstrip("\n"))
    w = read_probe_log(p).warnings
    assert len(w) == 1 and "ends without an end of line" in w[0]
    return p, w[0]


def test_vcmm_says_the_plans_warning_and_carries_it(tmp_path, capsys, cut_plan):
    """``--tol-um 1``: the subject is the plan reader's warning, said before any run and carried into the JSON, not
    the Monte Carlo (as tests/scenarios/test_cli26.py's and test_tool_offset_said.py's vcmm runs; session 38: 1,600
    runs at the task's own tolerance, 12.4 s CPU, against 200 runs, 2.4 s)."""
    plan, warning = cut_plan
    out = tmp_path / "v.json"
    assert main(["vcmm", "--plan", str(plan), "--machine", "vmc-3axis", "--task", TASK, "--no-budget",
                 "--tol-um", "1", "--json", str(out)]) == 0
    _said_once(capsys.readouterr().err, "vcmm", warning)
    assert json.loads(out.read_text())["input_warnings"] == [warning]


def test_the_plan_readers_say_the_plans_warning(tmp_path, capsys, cut_plan):
    """``machine program`` (and ``import``, ``probe``: the same helper) read a plan: its warning is said."""
    plan, warning = cut_plan
    assert main(["machine", "program", "--plan", str(plan), "--out", str(tmp_path / "p.ngc"),
                 "--limits-mm", "X-300:300,Y-300:300,Z-300:300"]) == 0
    _said_once(capsys.readouterr().err, "machine program", warning)
    # import reads the plan before the probe file: the plan's warning is said, then the file's refusal
    (tmp_path / "probe.txt").write_text("")
    main(["import", "linuxcnc", str(tmp_path / "probe.txt"), "--plan", str(plan), "--out", str(tmp_path / "o.csv")])
    assert f"vmt import: warning: {warning}" in capsys.readouterr().err


@pytest.fixture
def cut_positioning(tmp_path) -> tuple[Path, str]:
    """The ISO 230-2 sample's valid readings without the status column (optional) and the last end of line: the
    last field a temperature, read whole, warned."""
    lines = SAMPLE.read_text().splitlines()
    kept = [s for s in lines if s.startswith("#") or s.endswith(",status") or s.endswith(",ok")]
    cut = [s if s.startswith("#") else s.rsplit(",", 1)[0] for s in kept]
    p = tmp_path / "pos.csv"
    p.write_text("\n".join(cut))
    w = read_positioning_log(p).warnings
    assert len(w) == 1 and "ends without an end of line" in w[0]
    return p, w[0]


@pytest.mark.parametrize("command", ["discover", "iso230-2"])
def test_positioning_commands_say_the_readers_warning_and_carry_it(tmp_path, capsys, cut_positioning, command):
    log, warning = cut_positioning
    out = tmp_path / "out.json"
    assert main([command, str(log), "--json", str(out)]) == 0
    _said_once(capsys.readouterr().err, command, warning)
    assert json.loads(out.read_text())["input_warnings"] == [warning]
