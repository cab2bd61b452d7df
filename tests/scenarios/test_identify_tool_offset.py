"""``vmt identify`` and the probe log's recorded tool offset J (its ``tool_offset_mm`` line, session 36).

A GRBL run made with ``vmt probe`` / ``vmt import grbl --tool-offset-mm J`` records J in its log: the log is
the record of what was done. identify takes that J without the option, refuses (one line, exit 2, no file
written or overwritten) an option that says another J, and says in its output and its JSON (``tool_offset``)
which J it placed the tables with and where it came from. vcmm refuses a plan logged with another J than its
machine's ``[tool] offset_mm``. Every command that takes ``--tool-offset-mm`` refuses the same bad value in the
same words (one parser, ``hardware.campaign.parse_tool_offset``).

The known answer: a cross-pocket campaign simulated on a machine whose probe sits J = (40, 0, 150) mm from the
spindle, with a known EXX (8 um lobes), noise-free. Its log gets the header line the GRBL route writes for that J
(``hardware.campaign.tool_offset_text``: the readings are the simulator's tip centres, which is what that
route's log holds: tests/hardware/test_grbl_tool_offset.py closes that loop through the emulator to 0.6 um).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from hardware.campaign import TOOL_OFFSET_KEY, tool_offset_text
from scenarios.cli import main
from tests.cli_helpers import one_line_error
from tests.scenarios.test_selfcal_joint import MACHINE  # the nmv3000, probe 40 mm off the spindle, 8 um EXX, no noise

J = (40.0, 0.0, 150.0)

#: um: the identified EXX nodes against the truth at their positions, an offset and a slope removed (the gauge
#: EXX(x=0)=0 and the unknown scale), as tests/scenarios/test_selfcal_joint.py: noise-free touches, what is left
#: is the grid's model error (0.055 um measured there with this machine); the nodes placed at the readings, or
#: with another J_X, are over 1 um off (asserted below, so the bound tells the right J from a wrong one).
TOL_UM = 0.15


def _with_line(src, dst, value: str):
    """``src`` with the metadata line ``# tool_offset_mm: value`` after its format line, as the GRBL route writes
    it (its other lines byte for byte)."""
    lines = src.read_text().splitlines(keepends=True)
    assert lines[0] == "# format: probe-log/1\n"
    dst.write_text(lines[0] + f"# {TOOL_OFFSET_KEY}: {value}\n" + "".join(lines[1:]))
    return dst


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """The campaign without the line (a simulation's log), with the line of its J, and the machine's truth."""
    from sim.machinefile import resolve

    d = tmp_path_factory.mktemp("jlog")
    m = d / "m40.toml"
    m.write_text(MACHINE)
    bare = d / "p40.csv"
    assert main(["simulate", "cross-pocket", "--machine", str(m), "--out", str(bare)]) == 0
    assert resolve(str(m)).config.J_m == pytest.approx(tuple(v * 1e-3 for v in J), abs=1e-15)
    with_j = _with_line(bare, d / "p40j.csv", tool_offset_text(J))
    return bare, with_j, resolve(str(m)).config.errors["EXX"]


def _identify(log, out, *extra):
    return main(["identify", str(log), "--json", str(out), *extra])


def _exx(doc):
    e = doc["estimate"]
    nodes = [(p["at_mm"], v) for p, v in zip(e["parameters"], e["values"]) if p["symbol"] == "EXX"]
    return np.array([a for a, _ in nodes]), np.array([v for _, v in nodes])


def _off_truth(x_mm, v_um, truth):
    d = v_um - truth(np.asarray(x_mm) * 1e-3) * 1e6
    A = np.vstack([np.ones_like(d), x_mm]).T
    return float(np.abs(d - A @ np.linalg.lstsq(A, d, rcond=None)[0]).max())


def test_the_logs_J_is_taken_without_the_option_known_answer(logs, tmp_path, capsys):
    bare, with_j, truth = logs
    from_log, given, both = tmp_path / "log.json", tmp_path / "opt.json", tmp_path / "both.json"
    capsys.readouterr()
    assert _identify(with_j, from_log) == 0
    out = capsys.readouterr().out
    assert "probe offsets J = (40, 0, 150) mm, from the log's tool_offset_mm line: the tables at the axis " \
           "positions reading + J\n" in out
    assert _identify(bare, given, "--tool-offset-mm", "40,0,150") == 0           # before session 36's line
    assert "from --tool-offset-mm (the log has no tool_offset_mm line)" in capsys.readouterr().out
    assert _identify(with_j, both, "--tool-offset-mm", "40.000,0,150.0") == 0    # the same J, written otherwise
    assert "from the log's tool_offset_mm line and --tool-offset-mm" in capsys.readouterr().out
    a, b, c = (json.loads(p.read_text()) for p in (from_log, given, both))
    assert a["tool_offset"] == {"J_mm": [40.0, 0.0, 150.0], "from": "log"}
    assert b["tool_offset"] == {"J_mm": [40.0, 0.0, 150.0], "from": "option"}
    assert c["tool_offset"] == {"J_mm": [40.0, 0.0, 150.0], "from": "log and option"}
    assert a["estimate"] == b["estimate"] == c["estimate"]        # the state, its record included: identical
    assert a["estimate"]["identified_on"]["probe_offsets_J_mm"] == [[40.0, 0.0, 150.0]]
    # the injected EXX recovered at the axis positions reading + J (its nodes on the grid of readings + 40 mm)
    x, v = _exx(a)
    assert _off_truth(x, v, truth) < TOL_UM
    assert _off_truth(x - 40.0, v, truth) > 1.0                    # the same values at the readings: wrong


def test_without_the_line_or_the_option_J_is_unknown(logs, tmp_path, capsys):
    bare, _, truth = logs
    out = tmp_path / "none.json"
    capsys.readouterr()
    assert _identify(bare, out) == 0
    assert ("probe offsets J unknown (no tool_offset_mm line in the log, no --tool-offset-mm): the tables at the "
            "readings, the state's probe_offsets_J_mm null\n") in capsys.readouterr().out
    doc = json.loads(out.read_text())
    assert doc["tool_offset"] == {"J_mm": None, "from": "none"}
    assert doc["estimate"]["identified_on"]["probe_offsets_J_mm"] is None
    x, v = _exx(doc)
    assert _off_truth(x, v, lambda q: truth(q + 0.040)) < TOL_UM   # at the readings: the truth at reading + J


@pytest.mark.parametrize("given, said", [
    ("0,0,150", "0.0,0.0,150.0"),            # the tool length right, the probe's X offset forgotten
    ("40,0,150.001", "40.0,0.0,150.001"),    # 1 um: a conflict still, the log's J and the option's are one number
])
def test_a_conflicting_option_is_refused_and_nothing_is_written(logs, tmp_path, capsys, given, said):
    _, with_j, _ = logs
    fresh, kept = tmp_path / "fresh.json", tmp_path / "kept.json"
    kept.write_bytes(b'{"an earlier report": true}\n')
    capsys.readouterr()
    for out in (fresh, kept):
        assert _identify(with_j, out, "--tool-offset-mm", given) == 2
        one_line_error(capsys, f"vmt identify: error: --tool-offset-mm {said}: {with_j}'s tool_offset_mm line says its "
                          "readings were logged with J = 40.0,0.0,150.0 mm; one log holds one J")
    assert not fresh.exists() and kept.read_bytes() == b'{"an earlier report": true}\n'


@pytest.mark.parametrize("value", ["0,150", "0,0,x", "0,0,nan", "0,0,1e6"])
def test_a_bad_line_in_the_log_is_refused_naming_the_file(logs, tmp_path, capsys, value):
    bare, _, _ = logs
    bad = _with_line(bare, tmp_path / "bad.csv", value)
    out = tmp_path / "o.json"
    capsys.readouterr()
    assert _identify(bad, out) == 2
    one_line_error(capsys, f"{bad}: metadata tool_offset_mm {value!r}: ")
    assert not out.exists()


# --------------------------------------------------------------------------- one parser: the same words everywhere

BAD = ["0,150", "0,0,150,0", "0,0,x", "0,0,nan", "0,0,inf", "", "0;0;150", "0,0,1e6"]


@pytest.fixture(scope="module")
def plan(tmp_path_factory):
    p = tmp_path_factory.mktemp("plan") / "plan.csv"
    assert main(["plan", "grid", "--x-mm", "10:90:40", "--y-mm", "10:90:80", "--z-mm=-1.5", "--stylus-r-mm", "1.5",
                 "--out", str(p)]) == 0
    return p


def _commands(tmp_path, plan, value):
    """Every command that takes --tool-offset-mm, with ``value``, given what it needs to reach the option."""
    opt = f"--tool-offset-mm={value}"
    return {
        "identify": ["identify", str(plan), "--json", str(tmp_path / "o.json"), opt],
        "import": ["import", "grbl", str(plan), "--plan", str(plan), "--out",
                   str(tmp_path / "i.csv"), opt],
        "machine": ["machine", "serve", "--port", "0", "--stop-after-s", "1", opt],
        "probe": ["probe", "--controller", "grbl://127.0.0.1:9", "--plan", str(plan), "--out",
                  str(tmp_path / "p.csv"), "--dry-run", opt],
    }


@pytest.mark.parametrize("value", BAD)
def test_every_command_refuses_a_bad_value_in_the_same_words(tmp_path, plan, capsys, value):
    """identify refused these in its own words until session 36 ("expected three numbers a,b,c, each finite"):
    now each command's one line, after its ``vmt CMD: error: `` prefix, is the same, and nothing is written."""
    said = {}
    capsys.readouterr()
    for name, argv in _commands(tmp_path, plan, value).items():
        assert main(argv) == 2, name
        err = one_line_error(capsys, f"--tool-offset-mm {value!r}: ")
        assert err.startswith("vmt ") and ": error: " in err, err
        said[name] = err.split(": error: ", 1)[1]
    assert len(set(said.values())) == 1, said
    assert ("expected X,Y,Z, three finite numbers, mm" in said["identify"]
            or "beyond 100000 mm, no probe's offset" in said["identify"])
    assert not any(tmp_path.iterdir())


# --------------------------------------------------------------------------- vcmm: the plan's J and the machine's

VCMM = ["vcmm", "--task", "scenarios/data/vcmm-block-task.toml", "--no-budget", "--machine", "vmc-3axis"]


def test_vcmm_refuses_a_plan_logged_with_another_J_than_its_machines(tmp_path, capsys):
    from pathlib import Path

    src = Path("scenarios/data/vcmm-block-plan.csv")
    plan = _with_line(src, tmp_path / "plan100.csv", "0.0,0.0,100.0")
    out = tmp_path / "v.json"
    capsys.readouterr()
    assert main(VCMM + ["--plan", str(plan), "--json", str(out)]) == 2
    one_line_error(capsys, f"vmt vcmm: error: {plan}: its tool_offset_mm line says its touches were logged with J = "
                      "0.0,0.0,100.0 mm, the machine vmc-3axis's [tool] offset_mm is 0.0,0.0,150.0 mm")
    assert not out.exists()
    # the record the runs' JSON gets (scenarios.cli.vcmm._tool_offset): the machine's J, and whether the plan
    # said the same one (a full vcmm run is tests/scenarios/test_cli26.py's; the subject here is the record)
    from core.probelog import read_probe_log
    from scenarios.cli.vcmm import _tool_offset
    from sim.machinefile import truth_machine

    spec = truth_machine("vmc-3axis", None, "none")
    same = read_probe_log(_with_line(src, tmp_path / "plan150.csv", "0,0,150"))
    assert _tool_offset(same, spec, "p") == {"J_mm": [0.0, 0.0, 150.0], "from": "machine and log"}
    assert _tool_offset(read_probe_log(src), spec, "p") == {"J_mm": [0.0, 0.0, 150.0], "from": "machine"}


# --------------------------------------------------------------------------- the GRBL route, closed

#: mm: a GRBL log's tip centres against the direct simulation's: reports printed to 3 decimals (0.5 um), commands
#: to 4 (0.05 um); the same bound as tests/hardware/test_emulator_sim.py and test_grbl_tool_offset.py.
QUANT_MM = 0.6e-3


def test_closed_loop_a_grbl_log_made_with_J_is_identified_with_it(logs, tmp_path, capsys):
    """The whole route, no line written by hand: the emulator serves the machine with its probe J = (40, 0, 150)
    mm from the spindle (``vmt machine serve --tool-offset-mm``), ``vmt probe --tool-offset-mm`` runs the
    cross-pocket plan through it (limits and safe Z in the spindle's machine coordinates: the tip's + J) and its
    writer records J; ``vmt identify`` of that log, without the option, places the tables as the direct
    simulation identified with the option does. 6 s CPU (368 touches through the emulator at 1000x)."""
    from argparse import Namespace

    from core.probelog import read_probe_log
    from hardware.emulator import ControllerConfig, GrblEmulator, TcpServer
    from scenarios.cli.machine import served_machine

    bare, _, _ = logs
    m = bare.parent / "m40.toml"
    plan, log, got, direct = (tmp_path / n for n in ("plan.csv", "grbl.csv", "grbl.json", "direct.json"))
    assert main(["simulate", "cross-pocket", "--plan-only", "--machine", str(m), "--out", str(plan)]) == 0
    machine = served_machine(Namespace(scene="cross-pocket", machine=str(m), errors=None, noise_um=None, seed=None))
    emu = GrblEmulator(machine, ControllerConfig(axes="XYZAC", home=(0, 0, 300)), tool_offset_mm=J)
    srv = TcpServer(emu, time_scale=1000).start()
    try:
        assert main(["probe", "--controller", srv.url, "--plan", str(plan), "--out", str(log), "--rotary",
                     "--limits-mm", "X-210:290,Y-250:250,Z50:350", "--safe-z-mm", "230",
                     "--tool-offset-mm", "40,0,150"]) == 0
    finally:
        srv.stop()
    g, s = read_probe_log(log), read_probe_log(bare)
    assert g.meta[TOOL_OFFSET_KEY] == "40.0,0.0,150.0" and list(g.col("target")) == list(s.col("target"))
    assert np.abs(g.positions_mm() - s.positions_mm()).max() < QUANT_MM      # the tip centres, not the spindle's
    capsys.readouterr()
    assert _identify(log, got) == 0
    assert "probe offsets J = (40, 0, 150) mm, from the log's tool_offset_mm line" in capsys.readouterr().out
    assert _identify(bare, direct, "--tool-offset-mm", "40,0,150") == 0
    a, b = json.loads(got.read_text()), json.loads(direct.read_text())
    assert a["tool_offset"] == {"J_mm": [40.0, 0.0, 150.0], "from": "log"}
    assert a["estimate"]["identified_on"]["probe_offsets_J_mm"] == b["estimate"]["identified_on"]["probe_offsets_J_mm"]
    assert a["estimate"]["positions"] == b["estimate"]["positions"]
    (xa, va), (xb, vb) = _exx(a), _exx(b)
    np.testing.assert_allclose(xa, xb, rtol=0, atol=1e-9)          # the EXX nodes at the same axis positions
    # the values differ by the reports' rounding only: within the GRBL run's own U95 at every node (measured:
    # at most 0.55 of it; the U95 is of a probing sigma of 0.28 um, the rounding's, that the residuals show)
    u95 = np.array(a["axes"]["EXX"]["u95_um"])
    assert u95.shape == va.shape == (11,) and np.allclose(np.array(a["axes"]["EXX"]["positions_mm"]) + 40.0, xa)
    assert np.all(np.abs(va - vb) <= u95 + 1e-9), (va - vb, u95)
