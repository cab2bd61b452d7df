"""The tool offset J a command runs with, said (session 37, left37).

``vmt vcmm`` says on the terminal which J its runs probe with and where it came from, in the words of ``vmt
identify``'s line (``scenarios.cli.options.tool_offset_said``); a machine file without ``[tool]`` gets J = (0, 0,
150) mm (``sim.machinefile.DEFAULT_OFFSET_MM``), which changes the result (the Abbe arms through the machine's
angular errors, the axis positions reading + J), so that J is said as assumed in the output and in the JSON
(``tool_offset``: ``from`` ``assumed``, ``note``), as the CLI says its other assumptions rather than refusing
them (identify's "probe offsets J unknown", the self-calibration's "scale unknown: delta_L not given").
"""

from __future__ import annotations

import json

import pytest

from scenarios.cli import main

#: A machine file without [tool]: the built-in vmc-3axis's own lines but the tool's (its strokes stated for the
#: 150 mm probe, as the built-in's are).
NO_TOOL = """format = "vmt-machine/1"
name = "my-vmc"
chain = "V[w-X-Y-b-Z-(C)-t]"
errors = "none"

[strokes]
X_mm = [-300, 300]
Y_mm = [-200, 200]
Z_mm = [-50, 400]

[probe]
stylus_radius_mm = 3.0
noise_um = 0.125
"""

#: ``--tol-um 1``: the subject is the line and the record, made before any run (as tests/scenarios/test_cli26.py's
#: state-check runs: 1.5 s CPU each at 1 um against 14 s at the default).
VCMM = ["vcmm", "--plan", "scenarios/data/vcmm-block-plan.csv", "--task", "scenarios/data/vcmm-block-task.toml",
        "--no-budget", "--tol-um", "1"]


def test_identify_and_vcmm_say_J_in_one_sentence():
    """Known answers of the shared sentence: identify's words for its sources (as its line said them before
    session 37, byte for byte), vcmm's for the machine's, and the assumed J's."""
    from scenarios.cli.options import tool_offset_said

    J = (40.0, 0.0, 150.0)
    assert tool_offset_said(J, "log", "the tables") == (
        "probe offsets J = (40, 0, 150) mm, from the log's tool_offset_mm line: the tables at the axis positions "
        "reading + J")
    assert tool_offset_said(J, "option", "the tables") == (
        "probe offsets J = (40, 0, 150) mm, from --tool-offset-mm (the log has no tool_offset_mm line): the tables "
        "at the axis positions reading + J")
    assert tool_offset_said(None, "none", "the tables") == (
        "probe offsets J unknown (no tool_offset_mm line in the log, no --tool-offset-mm): the tables at the "
        "readings, the state's probe_offsets_J_mm null")
    assert tool_offset_said((0, 0, 150), "machine", "the runs") == (
        "probe offsets J = (0, 0, 150) mm, from the machine's [tool] offset_mm: the runs at the axis positions "
        "reading + J")
    assert tool_offset_said((0, 0, 150), "assumed", "the runs") == (
        "probe offsets J = (0, 0, 150) mm, tool offset not given: J = (0, 0, 150) mm assumed: the runs at the axis "
        "positions reading + J")
    with pytest.raises(ValueError, match="'nowhere' is not one of"):
        tool_offset_said(J, "nowhere", "the runs")


def test_identify_says_J_in_the_shared_words():
    """identify's own line (scenarios/cli/identify.py, left to its owner this session) is the shared sentence
    word for word, for every source it has: the two commands say J alike."""
    from scenarios.cli.identify import _tool_offset_said
    from scenarios.cli.options import tool_offset_said

    for J, src in (((40.0, 0.0, 150.0), "log"), ((40.0, 0.0, 150.0), "log and option"),
                   ((1.5, -2.0, 90.0), "option"), (None, "none")):
        assert _tool_offset_said(J, src) == tool_offset_said(J, src, "the tables")


def test_a_machine_file_without_tool_says_J_is_assumed(tmp_path):
    from sim.machinefile import DEFAULT_OFFSET_MM, loads, tool_offset_note, truth_machine

    spec = loads(NO_TOOL, "my-vmc.toml")
    assert not spec.tool_offset_given
    assert tuple(v * 1e3 for v in spec.config.J_m) == pytest.approx(DEFAULT_OFFSET_MM, abs=1e-12)
    assert tool_offset_note(spec) == "tool offset not given: J = (0, 0, 150) mm assumed"
    # a file that gives it, a built-in (its shipped file gives it), a file based on a built-in: nothing assumed
    given = loads(NO_TOOL + "\n[tool]\noffset_mm = [0, 0, 150]\n", "g.toml")
    assert given.tool_offset_given and tool_offset_note(given) is None
    assert tool_offset_note(truth_machine("vmc-3axis", "none")) is None
    assert tool_offset_note(loads('base = "vmc-3axis"\nname = "b"\n', "b.toml")) is None


def test_vcmm_says_J_and_whether_it_was_assumed(tmp_path, capsys):
    """One line naming J and whence on the terminal (before session 37 none: identify said it, vcmm did not); the
    JSON's ``tool_offset`` the same J; a machine file without [tool] says "tool offset not given: J = (0, 0, 150) mm
    assumed" in both (before, nothing: J silently the default)."""
    out = tmp_path / "v.json"
    capsys.readouterr()
    assert main(VCMM + ["--machine", "vmc-3axis", "--json", str(out)]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if "probe offsets J" in ln]
    assert lines == ["probe offsets J = (0, 0, 150) mm, from the machine's [tool] offset_mm: the runs at the axis "
                     "positions reading + J"]
    assert json.loads(out.read_text())["tool_offset"] == {"J_mm": [0.0, 0.0, 150.0], "from": "machine"}

    m = tmp_path / "my-vmc.toml"
    m.write_text(NO_TOOL)
    out2 = tmp_path / "v2.json"
    assert main(VCMM + ["--machine", str(m), "--json", str(out2)]) == 0
    said = capsys.readouterr().out
    lines = [ln for ln in said.splitlines() if "probe offsets J" in ln]
    assert lines == ["probe offsets J = (0, 0, 150) mm, tool offset not given: J = (0, 0, 150) mm assumed: the runs "
                     "at the axis positions reading + J"], said
    assert json.loads(out2.read_text())["tool_offset"] == {
        "J_mm": [0.0, 0.0, 150.0], "from": "assumed", "note": "tool offset not given: J = (0, 0, 150) mm assumed"}


def test_simulate_and_machine_say_the_assumed_J(tmp_path, capsys):
    """``vmt simulate`` (the touches it writes are simulated with J) and ``vmt machine`` (what the file holds) say
    the assumed J on a file without [tool]; on a built-in they say nothing of it."""
    m = tmp_path / "my-vmc.toml"
    m.write_text(NO_TOOL)
    capsys.readouterr()
    assert main(["machine", "show", str(m)]) == 0
    out = capsys.readouterr().out
    assert ("tool offset J (gauge point - tip centre): (0, 0, 150) mm (tool offset not given: J = (0, 0, 150) mm "
            "assumed)") in out, out
    assert main(["simulate", "freeform", "--machine", str(m), "--out", str(tmp_path / "s.csv"), "--seed", "1"]) == 0
    assert "tool offset not given: J = (0, 0, 150) mm assumed\n" in capsys.readouterr().out
    assert main(["simulate", "freeform", "--machine", "vmc-3axis", "--out", str(tmp_path / "b.csv"), "--seed", "1"]) == 0
    assert "tool offset not given" not in capsys.readouterr().out
