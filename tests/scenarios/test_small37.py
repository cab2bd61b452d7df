"""Four small things audit37 left (session 37, small37): each a test that failed before its mend.

The probe logs here are written by hand (text), not by vmt's writer."""

from __future__ import annotations

import pytest

from core.exceptions import ProbeLogError
from core.probelog import parse_probe_log
from scenarios.cli import main
from tests.cli_helpers import one_line_error

HEADER = "setup,target,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz"


def _log(number_format: str | None, x_cell: str = "48.001") -> str:
    """Three touches of a wall at x = 48 mm, the measured X printed as ``x_cell`` in the first row."""
    meta = "# format: probe-log/1\n# stylus_r_mm: 2.0\n"
    if number_format is not None:
        meta += f"# number_format: {number_format}\n"
    rows = [f"S1,T0,0.0,{x_cell},-5.000,-5.000,48.0,-5.0,-5.0,1.0,0.0,0.0",
            "S1,T1,1.0,48.002,0.000,-5.000,48.0,0.0,-5.0,1.0,0.0,0.0",
            "S1,T2,2.0,47.999,5.000,-5.000,48.0,5.0,-5.0,1.0,0.0,0.0"]
    return meta + HEADER + "\n" + "\n".join(rows) + "\n"


# --- 1. number_format: vmt's decimals list without vmt's words before it ------------------------------------

@pytest.mark.parametrize("value", ["decimals X_mm=3", "Decimals X_mm=3, Y_mm=3",
                                   "shortest round-trip decimals X_mm=3",        # the ';' forgotten
                                   "exact; decimals X_mm=3"])
def test_a_decimals_list_without_vmts_words_is_refused_naming_the_line(value):
    """Before, ``decimals X_mm=3`` was "other words" and ignored without a word: every column read from its
    digits (Xn_mm ``48.0`` as printed to 0.1 mm, not exact) and a cell with 6 decimals in X_mm passed, which the
    same list after ``shortest round-trip;`` refuses. Refused now, as a malformed kinematic_chain,
    tool_offset_mm or stylus_r_mm is, the message giving the one form vmt reads."""
    with pytest.raises(ProbeLogError) as e:
        parse_probe_log(_log(value), "hand.csv")
    msg = str(e.value)
    assert msg.startswith("hand.csv: line 3: metadata number_format"), msg
    assert "'shortest round-trip; decimals COLUMN=K, ...'" in msg, msg


def test_the_same_list_after_vmts_words_reads_and_other_words_still_read_from_the_digits():
    """What is not refused: vmt's form (its step taken), and other words that name no decimals list (a line
    some other tool wrote: not vmt's, the digits say the precision, as before)."""
    log = parse_probe_log(_log("shortest round-trip; decimals X_mm=3, Y_mm=3, Z_mm=3"), "ok.csv")
    assert log.text_steps["X_mm"] == pytest.approx(1e-3) and log.text_steps["Xn_mm"] == 0.0
    prose = parse_probe_log(_log("six decimals"), "prose.csv")                # words, no list: not vmt's
    assert prose.text_steps["Xn_mm"] == pytest.approx(0.1)
    other = parse_probe_log(_log("printf %.3f"), "other.csv")
    assert other.text_steps["X_mm"] == pytest.approx(1e-3)      # from the digits (3 decimals)
    assert other.text_steps["Xn_mm"] == pytest.approx(0.1)      # '48.0': one decimal, no declaration
    # vmt's form holds the cell to it; the refusal above is what keeps the hand form from passing it
    with pytest.raises(ProbeLogError, match="more decimals"):
        parse_probe_log(_log("shortest round-trip; decimals X_mm=3", x_cell="48.001234"), "six.csv")


def test_check_refuses_the_hand_form_in_one_line(tmp_path, capsys):
    p = tmp_path / "hand.csv"
    p.write_text(_log("decimals X_mm=3", x_cell="48.001234"))
    capsys.readouterr()
    assert main(["check", str(p)]) == 2
    one_line_error(capsys, "vmt check: error:", "line 3: metadata number_format", "decimals X_mm=3",
                   "shortest round-trip; decimals COLUMN=K")


# --- 2. the machine file's thermal history: the message names the file's key --------------------------------

THERMAL = """format = "vmt-machine/1"
base = "vmc-3axis"
errors = "none"
[error.EXX]
thermal = {{ {body} }}
"""


@pytest.mark.parametrize("body, key, words", [
    ("offset_um_per_K = 1.0, temperature_h = [1.0, 0.0], temperature_K = [0.0, 1.0]",
     "error.EXX.thermal.temperature_h", "times must be strictly increasing"),
    ("offset_um_per_K = 1.0, temperature_h = [0.0, 2.0, 2.0], temperature_K = [0.0, 1.0, 2.0]",
     "error.EXX.thermal.temperature_h", "times must be strictly increasing"),
    ("offset_um_per_K = 1.0", "error.EXX.thermal.offset_um_per_K", "needs a temperature history"),
    ("scale_ppm_per_K = 11.5", "error.EXX.thermal.scale_ppm_per_K", "needs a temperature history"),
])
def test_a_thermal_history_error_names_the_files_key_and_section(tmp_path, capsys, body, key, words):
    """Before, `error.EXX.thermal: Drift.temperature_t_s must be strictly increasing` (and `Drift.offset_per_K/
    scale_per_K need a temperature history`): the simulator's field names, which the file does not have."""
    p = tmp_path / "m.toml"
    p.write_text(THERMAL.format(body=body))
    capsys.readouterr()
    assert main(["machine", "show", str(p)]) == 2
    err = one_line_error(capsys, "vmt machine show: error:", f"{p}: {key}: {words}")
    assert "Drift" not in err and "temperature_t_s" not in err


def test_an_increasing_history_still_reads(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text(THERMAL.format(body="offset_um_per_K = 1.0, temperature_h = [0.0, 1.0], temperature_K = [0.0, 2.0]"))
    assert main(["machine", "show", str(p)]) == 0


# --- 3. `vmt machine serve --host` it cannot listen on: the error alone ------------------------------------

def test_serve_on_a_host_it_cannot_listen_on_says_only_the_error(capsys):
    """Before, `warning: listening on 999.1.1.1, not only this computer` came first, then the error that it
    cannot listen: two lines, the first untrue."""
    capsys.readouterr()
    assert main(["machine", "serve", "--host", "999.1.1.1", "--port", "0", "--stop-after-s", "0.2"]) == 2
    err = one_line_error(capsys, "vmt machine serve: error: --host 999.1.1.1 --port 0: cannot listen")
    assert "warning" not in err


def _can_listen_on(host: str) -> bool:
    import socket

    try:
        with socket.socket() as s:
            s.bind((host, 0))
        return True
    except OSError:
        return False


@pytest.mark.skipif(not _can_listen_on("127.0.0.2"), reason="127.0.0.2 is no loopback here (Linux has 127/8)")
def test_serve_on_another_address_still_warns_once_it_listens(capsys):
    """127.0.0.2 is this computer's loopback on Linux, but not one of the names serve takes as local: the
    warning is still said (after the listen succeeded), then the emulator's line."""
    capsys.readouterr()
    assert main(["machine", "serve", "--host", "127.0.0.2", "--port", "0", "--stop-after-s", "0.2"]) == 0
    cap = capsys.readouterr()
    assert cap.err == "vmt machine: warning: listening on 127.0.0.2, not only this computer\n", cap.err
    assert "GRBL emulator of axes XYZ on grbl://127.0.0.2:" in cap.out, cap.out


# --- 4. `vmt check` of a plan: no time, what the plan is ---------------------------------------------------

def _plan() -> str:
    """Three touches planned in two set-ups (two targets; T0 in both), every measured cell empty."""
    rows = ["S1,T0,,,,,48.0,-5.0,-5.0,1.0,0.0,0.0",
            "S1,T1,,,,,48.0,5.0,-5.0,1.0,0.0,0.0",
            "S2,T0,,,,,48.0,-5.0,-5.0,1.0,0.0,0.0"]
    return "# format: probe-log/1\n# stylus_r_mm: 2.0\n" + HEADER + "\n" + "\n".join(rows) + "\n"


def test_check_of_a_plan_says_what_it_plans_and_no_time(tmp_path, capsys):
    """Before: `touches 3 planned (nothing measured)   set-ups 2   targets 2` and `time 0.0 s`, the span of no
    touches. A plan has no time: its summary says how many touches in how many set-ups, and that its X, Y, Z are
    the nominals."""
    p = tmp_path / "plan.csv"
    p.write_text(_plan())
    capsys.readouterr()
    assert main(["check", str(p)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == [f"{p}: valid probe-log/1 plan",
                   "  plan     3 touches in 2 set-ups, 2 targets: nothing measured yet",
                   "  X        48.000 .. 48.000 mm (nominal)",
                   "  Y        -5.000 .. 5.000 mm (nominal)",
                   "  Z        -5.000 .. -5.000 mm (nominal)"], out


def test_check_of_a_campaign_still_says_its_time(tmp_path, capsys):
    p = tmp_path / "log.csv"
    p.write_text(_log(None))
    capsys.readouterr()
    assert main(["check", str(p)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1] == "  touches  3 (3 ok)   set-ups 1   targets 3" and out[2] == "  time     2.0 s", out
    assert out[3] == "  X        47.999 .. 48.002 mm", out                   # measured, not nominal
