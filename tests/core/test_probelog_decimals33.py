"""The printing step of each column (session 33, step33): ``# number_format: shortest round-trip; decimals X_mm=3,
Y_mm=3, Z_mm=3`` declares the named columns printed to that many decimals and every other number exact.

Before, the line had one word for the whole file: a log of a GRBL controller's readings (printed to 1 um) written by
``vmt import`` or ``vmt probe`` declared them exact, so ``vmt fit`` floored no U95 on their rounding; and a log
written with fixed decimals in some columns dropped the line, so its other columns' shortest round-trip digits were
read as a step (``160.0`` as 0.1 mm).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from core import features as FE
from core import fit as F
from core import probelog as P
from core.exceptions import ProbeLogError
from core.probelog import format_probe_log, make_log, parse_probe_log
from scenarios.cli import main

XYZ = ("X_mm", "Y_mm", "Z_mm")


def _wall(noise_um=0.0, seed=0):
    """A 3x3 wall at x = 48 mm (normal +x), touched from +x: nominals whole mm, readings ``noise_um`` off along x,
    rounded to 1 um as a GRBL controller prints them."""
    rng = np.random.default_rng(seed)
    y, z = np.meshgrid([-5.0, 0.0, 5.0], [-5.0, -4.5, -4.0])
    n = y.size
    x = 48.0 + noise_um * 1e-3 * rng.standard_normal(n)
    cols = {"setup": ["S1"] * n, "target": [f"T{i}" for i in range(n)], "t_s": np.arange(n, dtype=float),
            "X_mm": np.round(x, 3), "Y_mm": y.ravel(), "Z_mm": z.ravel(),
            "Xn_mm": np.full(n, 48.0), "Yn_mm": y.ravel(), "Zn_mm": z.ravel(),
            "nx": np.ones(n), "ny": np.zeros(n), "nz": np.zeros(n), "feature": ["wall"] * n}
    log = make_log(cols, {"stylus_r_mm": "2.0"})
    return replace(log, text_steps={c: 1e-3 for c in XYZ})       # what an import of the controller's text records


def test_a_mixed_log_keeps_exact_nominals_and_3_decimal_readings_through_write_read_write():
    """The writer declares the readings' 3 decimals and prints them so (``48.000``); the nominals stay their
    shortest round-trip (``48.0``) and read back exact (step 0), not as 0.1 mm. Write -> read -> write: the same
    bytes; the values read back are the log's."""
    log = _wall(0.3, seed=1)
    text = format_probe_log(log)
    lines = text.splitlines()
    assert "# number_format: shortest round-trip; decimals X_mm=3, Y_mm=3, Z_mm=3" in lines
    header = lines.index(next(ln for ln in lines if ln.startswith("setup,")))
    row = lines[header + 1].split(",")
    cols = lines[header].split(",")
    assert row[cols.index("Y_mm")] == "-5.000" and row[cols.index("Yn_mm")] == "-5.0"
    back = parse_probe_log(text, "mixed.csv")
    assert back.text_steps == {"X_mm": 1e-3, "Y_mm": 1e-3, "Z_mm": 1e-3, "Xn_mm": 0.0, "Yn_mm": 0.0, "Zn_mm": 0.0,
                               "nx": 0.0, "ny": 0.0, "nz": 0.0}
    for c in log.columns:
        assert back.columns[c].tolist() == log.columns[c].tolist(), c
    assert format_probe_log(back) == text
    assert P.NUMBER_FORMAT_KEY not in back.meta          # the line is the file's, not the log's


def test_the_declared_step_is_the_columns_whatever_its_digits():
    """``10.0`` in a column declared to 3 decimals is 10 printed to 1 um (the digits alone say 0.1 mm); a declared
    column outside the recorded ones (a temperature) is kept and written back to its decimals."""
    text = ("# format: probe-log/1\n# number_format: shortest round-trip; decimals X_mm=3, Y_mm=3, Z_mm=3, "
            "temp_a_C=2\nsetup,target,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz,temp_a_C\n"
            "S,T,0.0,10.0,0.0,0.0,10.0,0.0,0.0,1.0,0.0,0.0,20.5\n")
    log = parse_probe_log(text, "d.csv")
    assert log.text_steps["X_mm"] == 1e-3 and log.text_steps["Xn_mm"] == 0.0 and log.text_steps["temp_a_C"] == 0.01
    out = format_probe_log(log)
    assert out.splitlines()[-1] == "S,T,0.0,10.000,0.000,0.000,10.0,0.0,0.0,1.0,0.0,0.0,20.50"
    assert format_probe_log(parse_probe_log(out, "d2.csv")) == out
    # without the declaration the digits say 0.1 mm (how the same text read before session 33, and still does)
    plain = text.replace("; decimals X_mm=3, Y_mm=3, Z_mm=3, temp_a_C=2", "").replace("# number_format: "
                                                                                      "shortest round-trip\n", "")
    assert parse_probe_log(plain, "p.csv").text_steps["X_mm"] == pytest.approx(0.1)


def test_the_declaration_holds_with_the_text_steps_switched_off(monkeypatch):
    """TEXT_STEP_COLUMNS None stops the counting of digits, not a declaration the file makes."""
    monkeypatch.setattr(P, "TEXT_STEP_COLUMNS", None)
    log = parse_probe_log(format_probe_log(_wall()), "w.csv")
    assert log.text_steps == {c: 1e-3 for c in XYZ}


def test_other_words_before_the_list_are_not_taken():
    """Only vmt's own words declare: another value of the key leaves the digits to say the step (as before
    session 33). Since session 37 (small37) vmt's list after other words is refused, not read as other words: the
    line names vmt's list, so it is meant as vmt's, written in a form vmt does not read (a malformed
    kinematic_chain, tool_offset_mm or stylus_r_mm is refused too); tests/scenarios/test_small37.py."""
    other = format_probe_log(_wall()).replace("shortest round-trip; decimals X_mm=3, Y_mm=3, Z_mm=3",
                                              "six decimals")
    log = parse_probe_log(other, "o.csv")
    assert log.text_steps["X_mm"] == 1e-3 and log.text_steps["Xn_mm"] == pytest.approx(0.1)
    listed = format_probe_log(_wall()).replace("shortest round-trip; decimals", "six decimals; decimals")
    with pytest.raises(ProbeLogError, match="a 'decimals' list goes after vmt's words"):
        parse_probe_log(listed, "o.csv")


_HEAD = "setup,target,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz\n"
_ROW = "S,T,0.0,10.123,0.0,0.0,10.0,0.0,0.0,1.0,0.0,0.0\n"


@pytest.mark.parametrize("value, said", [
    ("shortest round-trip; decimals Q_mm=3", "names column 'Q_mm', which the header does not have"),
    ("shortest round-trip; decimals X_mm=-1", "X_mm='-1': the decimals must be a whole number from 0 to 12"),
    ("shortest round-trip; decimals X_mm=3.5", "X_mm='3.5': the decimals must be a whole number from 0 to 12"),
    ("shortest round-trip; decimals X_mm=13", "X_mm='13': the decimals must be a whole number from 0 to 12"),
    ("shortest round-trip; decimals X_mm=three", "X_mm='three': the decimals must be a whole number"),
    ("shortest round-trip; decimals X_mm", "'X_mm' is not COLUMN=K"),
    ("shortest round-trip; decimals X_mm=3, X_mm=3", "names column 'X_mm' twice"),
    ("shortest round-trip; decimals setup=3", "names column 'setup', which holds text, not numbers"),
    ("shortest round-trip; X_mm=3", "expected 'decimals COLUMN=K, ...'"),
    ("shortest round-trip; decimals", "expected 'decimals COLUMN=K, ...'"),
    ("shortest round-trip; decimals X_mm=2", "row 0 (line 4): column 'X_mm': '10.123' has more decimals than the 2"),
])
def test_a_bad_declaration_is_one_line_and_exit_2(tmp_path, capsys, value, said):
    """Bad input: a column the header lacks or holding text, an impossible decimals count, a list that is not
    ``decimals COLUMN=K, ...``, a cell with more decimals than its column declares. ``vmt check`` (every command
    reads through the same reader): one line naming the file (and the line, or the row), exit 2, the file as it
    was."""
    f = tmp_path / "bad.csv"
    body = f"# format: probe-log/1\n# number_format: {value}\n" + _HEAD + _ROW
    f.write_text(body)
    with pytest.raises(ProbeLogError, match=None) as e:
        parse_probe_log(body, str(f))
    assert said in str(e.value)
    assert main(["check", str(f)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and said in err and str(f) in err and "Traceback" not in err
    assert f.read_text() == body


def test_an_unknown_column_declared_that_holds_text_is_refused():
    text = ("# format: probe-log/1\n# number_format: shortest round-trip; decimals note=1\n" + _HEAD[:-1] + ",note\n"
            + _ROW[:-1] + ",abc\n")
    with pytest.raises(ProbeLogError, match="names column 'note', which holds text, not numbers"):
        parse_probe_log(text, "n.csv")


def test_a_full_precision_column_is_written_whole_not_cut_to_12_decimals():
    """A column read without the declaration whose digits reach the most the reader counts (a shortest round-trip
    repr, ``0.30000000000000004``, ``0.1 + 0.2``: step 1e-12) is written as its repr, every digit, and declared exact
    (before session 33 it was cut to 12 decimals, ``0.300000000000``, another double)."""
    text = ("# format: probe-log/1\n" + _HEAD + "S,T,0.0,0.30000000000000004,0.0,0.0,0.3,0.0,0.0,1.0,0.0,0.0\n")
    log = parse_probe_log(text, "r.csv")
    assert log.text_steps["X_mm"] == pytest.approx(1e-12, abs=0)
    out = format_probe_log(log)
    assert ",0.30000000000000004," in out and "decimals" in out and "X_mm=" not in out
    assert parse_probe_log(out, "r2.csv").columns["X_mm"][0] == 0.1 + 0.2 != 0.3
    assert format_probe_log(parse_probe_log(out, "r2.csv")) == out


def test_fit_floors_on_the_declared_1_um_and_not_on_the_same_log_declared_exact():
    """Known answer (fitq32's rule, tests/core/test_fit_rounding.py): a wall on the x axis whose readings are
    rounded to 1 um (0.1 um of probing noise: every reading prints 48.000, so the scatter is 0) has a rounding U95
    of exactly 1.96 x 1 um / sqrt(12) = 0.566 um on its offset (every touch shares one printed X), and ``vmt fit``
    gives at least that. The same text whose line declares every number exact (what ``vmt import`` wrote before
    session 33) gives the scatter's U95 alone, below 1e-6 um: the declaration is what moves it."""
    text = format_probe_log(_wall(0.1, seed=2))
    log = parse_probe_log(text, "wall.csv")
    assert set(log.columns["X_mm"].tolist()) == {48.0}
    r = FE.fit_log_feature(log, "plane")
    k = F.ROUNDING_K / np.sqrt(12.0)
    assert r.printing_step_mm == pytest.approx((1e-3,) * 3, rel=1e-12, abs=0)
    assert r.u95_rounding["offset_n_um"] == pytest.approx(k, rel=1e-9)
    assert r.u95["offset_n_um"] >= r.u95_rounding["offset_n_um"] and r.u95_scatter["offset_n_um"] < 1e-6
    exact = text.replace("; decimals X_mm=3, Y_mm=3, Z_mm=3", "")
    r0 = FE.fit_log_feature(parse_probe_log(exact, "wall-exact.csv"), "plane")
    assert r0.printing_step_mm == (0.0, 0.0, 0.0) and r0.u95 == r0.u95_scatter and r0.u95["offset_n_um"] < 1e-6


def test_a_column_changed_after_reading_is_written_exact_not_rounded_to_its_old_step():
    """A log read from 3-decimal readings whose X_mm code then moved by 0.4 um (a correction): the writer must not
    print it back to 3 decimals (0.4 um lost, silently). It writes that column exact and declares the rest as
    before; the values read back are the changed ones, to the last bit."""
    log = _wall(0.3, seed=1)
    moved = replace(log, columns={**log.columns, "X_mm": log.columns["X_mm"] + 0.0004})
    text = format_probe_log(moved)
    assert "# number_format: shortest round-trip; decimals Y_mm=3, Z_mm=3" in text.splitlines()
    back = parse_probe_log(text, "moved.csv")
    assert back.columns["X_mm"].tolist() == moved.columns["X_mm"].tolist()
    assert back.text_steps["X_mm"] == 0.0 and back.text_steps["Y_mm"] == 1e-3
    # the unchanged log still prints its step (the check does not fire on values read from the step)
    assert "decimals X_mm=3, Y_mm=3, Z_mm=3" in format_probe_log(log)
