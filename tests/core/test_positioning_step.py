"""The printed step of a positioning log's readings (session 34, review34's medium finding): recorded on reading,
its rounding's uncertainty stated per figure and counted in U cond, a warning when it is coarse beside the
repeatability; the figures themselves stay the standard's, from the readings as printed."""

import math

import numpy as np
import pytest

from core.positioning import (STEP_SENSITIVITY, Iso2302Result, PositioningLogError, UncertaintyInputs, arrange,
                              figure_uncertainty, iso230_2, parse_positioning_log, parse_table, printed_step,
                              read_positioning_log)

SAMPLE = "scenarios/data/positioning-sample.csv"


def _rounded(decimals: int, meta: str = "") -> str:
    """The shipped sample with measured_mm printed to ``decimals`` (what a spreadsheet export holds)."""
    out = []
    for ln in open(SAMPLE).read().splitlines():
        if ln.startswith("#") or ln.startswith("target"):
            out.append(ln)
            if ln.startswith("# format") and meta:
                out.append(meta)
            continue
        c = ln.split(",")
        c[3] = f"{float(c[3]):.{decimals}f}" if c[3] else c[3]
        out.append(",".join(c))
    return "\n".join(out) + "\n"


def test_steps_recorded_from_the_digits():
    log = read_positioning_log(SAMPLE)
    assert log.text_steps == {"target": pytest.approx(1e-3, rel=1e-12, abs=0), "measured": pytest.approx(1e-6, rel=1e-12, abs=0)}
    assert parse_positioning_log(_rounded(2)).text_steps["measured"] == pytest.approx(0.01, rel=1e-12, abs=0)
    assert log.lines is not None and log.lines[0] == 9   # 7 metadata lines, the header on line 8


def test_number_format_line_is_honoured():
    """The probe log's ``number_format`` words: exact -> step 0; a column declared to K decimals -> 10^-K."""
    exact = parse_positioning_log(_rounded(2, "# number_format: shortest round-trip"))
    assert exact.text_steps == {"target": 0.0, "measured": 0.0}
    fixed = parse_positioning_log(_rounded(3, "# number_format: shortest round-trip; decimals measured_mm=3"))
    assert fixed.text_steps["measured"] == pytest.approx(1e-3, rel=1e-12, abs=0) and fixed.text_steps["target"] == 0.0
    with pytest.raises(PositioningLogError, match="names column 'X_mm', which the header does not have"):
        parse_positioning_log(_rounded(3, "# number_format: shortest round-trip; decimals X_mm=3"))



@pytest.mark.parametrize("line", [
    "# number_format: shortest round-trip; decimals X_mm=3",         # a column the header does not have
    "# number_format: shortest round-trip; decimals measured_mm=x",  # K not a whole number
    "# number_format: shortest round-trip; six decimals",            # not 'decimals COLUMN=K' after the words
    "# number_format: decimals measured_mm=3",                      # vmt's list without vmt's words (session 37)
])
def test_a_malformed_number_format_line_is_named_by_its_file_line(line):
    """Session 38 (dup38): a malformed ``number_format`` line in a positioning log was refused naming the file
    alone (``d.csv: metadata number_format ...``), where the probe log's reader names the line too and every
    other error of this reader names the line or row. Now the probe log's words to the letter, with the line
    the test itself put the metadata on (counted from the text, not from the reader)."""
    from core.exceptions import ProbeLogError
    from core.probelog import parse_number_format

    text = _rounded(3, line)
    n = text.splitlines().index(line) + 1
    with pytest.raises(PositioningLogError) as e:
        parse_positioning_log(text, source="nf.csv")
    msg = str(e.value)
    assert msg.startswith(f"nf.csv: line {n}: metadata number_format") and "\n" not in msg, msg
    header = next(r for r in text.splitlines() if r.startswith("target")).split(",")
    with pytest.raises(ProbeLogError) as p:   # the probe log reader's message for the same line
        parse_number_format(line.split(":", 1)[1].strip(), header, "nf.csv", n)
    assert msg == str(p.value)

def test_coarse_step_warns_and_its_u_is_step_over_sqrt12():
    log = parse_positioning_log(_rounded(2), source="r2.csv")
    res = iso230_2(arrange(log))
    rep, w = printed_step(log, res)
    uq = 10.0 / math.sqrt(12.0)   # um: a 0.01 mm step, uniform
    assert rep["step_mm"] == pytest.approx(0.01) and rep["u_reading_um"] == pytest.approx(uq, rel=1e-12)
    assert rep["u_R_um"] == pytest.approx(4 * uq) and rep["u_A_um"] == pytest.approx(math.sqrt(10) * uq)
    assert rep["u_E_um"] == pytest.approx(math.sqrt(2) * uq) and rep["coarse"] is True
    assert w is not None and "measured_mm is printed to 0.01 mm (10 um)" in w and w.startswith("r2.csv: ")
    # the full-precision sample: a 1 nm step, far below its s (0.19-0.85 um): no warning
    full = read_positioning_log(SAMPLE)
    rep, w = printed_step(full, iso230_2(arrange(full)))
    assert w is None and rep["coarse"] is False and rep["u_reading_um"] == pytest.approx(1e-3 / math.sqrt(12))


@pytest.mark.parametrize("decimals", [2, 3, 4])
def test_rounded_figures_lie_within_the_steps_U_of_the_full_precision_ones(decimals):
    """Known answer from outside the rounded file: the same readings at full precision. Each figure of the
    rounded log is within k = 2 x the step's u of the full-precision figure (2 decimals: R 17.889 for 5.402,
    |diff| 12.5 um = 4.3 u_q, U 23.1 um; A 34.889 for 18.583, 5.65 u_q against 2 sqrt 10 = 6.3). The figures are
    NOT changed: they are the standard's from the readings as printed (R 17.889 stays)."""
    full = iso230_2(arrange(read_positioning_log(SAMPLE)))
    log = parse_positioning_log(_rounded(decimals))
    res = iso230_2(arrange(log))
    rep, _ = printed_step(log, res)
    for f in Iso2302Result.FIGURES:
        assert abs(getattr(res, f) - getattr(full, f)) * 1e3 <= 2 * rep[f"u_{f}_um"], f
    if decimals == 2:
        assert res.R * 1e3 == pytest.approx(17.889, abs=5e-4) and res.A * 1e3 == pytest.approx(34.889, abs=5e-4)


def test_budget_counts_the_step_per_figure():
    log = parse_positioning_log(_rounded(2))
    res = iso230_2(arrange(log))
    inp = UncertaintyInputs(u_instrument_um=0.1, eve_um=0.4)
    b0 = figure_uncertainty(res, inp)
    b1 = figure_uncertainty(res, inp, step=0.01)
    assert b0.step_u is None and len(b0.to_report()["contributions"]) == 5
    uq = 10.0 / math.sqrt(12.0)
    for f, c in STEP_SENSITIVITY.items():
        assert b1.U[f] == pytest.approx(2 * math.hypot(b0.U[f] / 2, c * uq), rel=1e-12)
    rows = b1.to_report()["contributions"]
    assert rows[-1]["source"] == "printed step (rounding)" and rows[-1]["u_R_um"] == pytest.approx(4 * uq)


def test_table_deviation_um_step_in_mm():
    text = "target,cycle,direction,deviation_um\n" + "".join(
        f"{t},{c},{d},{0.1 * c + (1.0 if d == '-' else 0.0):.1f}\n"
        for c in (1, 2, 3) for t in (0, 100, 200) for d in "+-")
    log = parse_table(text)
    assert log.text_steps["measured"] == pytest.approx(1e-4, rel=1e-12, abs=0)   # 0.1 um printed in um -> 1e-4 mm
    assert log.text_steps["target"] == 1.0
    assert np.all(log.lines == np.arange(2, 20))


def test_the_writer_keeps_the_step_and_declares_memory_logs_exact():
    """A log read with a 0.01 mm step written and read back keeps it (repr would print 405.770 as 405.77, and a
    column whose values all end in 0 would come back coarser); a log built in memory is declared exact (its
    shortest round-trip digits are not a print step)."""
    from core.positioning import format_positioning_log, make_positioning_log

    log = parse_positioning_log(_rounded(2))
    text = format_positioning_log(log)
    assert "# number_format: shortest round-trip; decimals target_mm=3, measured_mm=2\n" in text
    back = parse_positioning_log(text)
    assert back.text_steps == log.text_steps and format_positioning_log(back) == text
    ok = log.ok
    assert np.array_equal(back.measured[ok], log.measured[ok]) and np.array_equal(back.target, log.target)
    # every measured value a whole 0.1 mm: the digits alone would read a 0.1 mm step; the declaration keeps 0.01
    t = [0.0, 100.0] * 4
    mem = make_positioning_log(t, [1, 1, 1, 1, 2, 2, 2, 2], "++--++--", [0.1, 100.2, 0.3, 100.1] * 2)
    assert mem.text_steps == {}
    back = parse_positioning_log(format_positioning_log(mem))
    assert back.text_steps == {"target": 0.0, "measured": 0.0}
    stepped = parse_positioning_log(format_positioning_log(
        parse_positioning_log(format_positioning_log(mem).replace(
            "# number_format: shortest round-trip", "# number_format: shortest round-trip; decimals measured_mm=2"))))
    assert stepped.text_steps["measured"] == pytest.approx(0.01, rel=1e-12, abs=0)


def test_an_ecmc_file_records_its_step():
    from core.positioning import parse_ecmc_dat

    text = ("UNIT=mm\nTGT_DATA[1]=0\nTGT_DATA[2]=10\nREF_DATA_FWD[1,1]=0.0010\nREF_DATA_FWD[2,1]=10.0020\n"
            "REF_DATA_FWD[1,2]=0.0010\nREF_DATA_FWD[2,2]=10.0020\nREF_DATA_BWD[1,1]=-0.0005\n"
            "REF_DATA_BWD[2,1]=10.0000\nREF_DATA_BWD[1,2]=-0.0005\nREF_DATA_BWD[2,2]=10.0000\n")
    log = parse_ecmc_dat(text, "e.dat")
    assert log.text_steps["measured"] == pytest.approx(1e-4, rel=1e-12, abs=0) and log.text_steps["target"] == 1.0
    assert list(log.lines[:2]) == [4, 5]   # cycle 1 FWD at targets 0, 10: REF_DATA_FWD[1,1], [2,1]


# ---- session 35: the declared decimals held per cell; one on-step question for both writers ----------------

def _declared(measured_decimals: int, declared: int, row_text=None) -> str:
    text = _rounded(measured_decimals, f"# number_format: shortest round-trip; decimals measured_mm={declared}")
    if row_text is not None:
        lines = text.splitlines()
        k = next(i for i, ln in enumerate(lines) if ln[:1].isdigit())
        c = lines[k + 3].split(",")
        c[3] = row_text
        lines[k + 3] = ",".join(c)
        text = "\n".join(lines) + "\n"
    return text


def test_a_cell_with_more_decimals_than_declared_is_refused_naming_its_row():
    """iso34's leftover: a positioning log's ``decimals measured_mm=3`` was taken as the step and a cell with
    more decimals read silently (the probe log refuses it). Now the same refusal in the same words, naming the
    row and the file line; fewer decimals than declared read (``405.77`` is 405.770 to 1 um)."""
    good = parse_positioning_log(_declared(2, 3), source="d.csv")
    assert good.text_steps["measured"] == pytest.approx(1e-3, rel=1e-12, abs=0)
    with pytest.raises(PositioningLogError) as e:
        parse_positioning_log(_declared(3, 3, "297.9055"), source="d.csv")
    msg = str(e.value)
    assert msg.startswith("d.csv: row 3 (line 13): column 'measured_mm': '297.9055' has more decimals than the 3 "
                          "the metadata number_format declares") and "\n" not in msg
    with pytest.raises(PositioningLogError, match=r"row 0 \(line 10\): column 'measured_mm': '-0.000163' has more "):
        parse_positioning_log(_declared(6, 3), source="d.csv")        # the whole column finer than declared
    tgt = _rounded(3, "# number_format: shortest round-trip; decimals target_mm=2")
    with pytest.raises(PositioningLogError, match=r"row 1 \(line 11\): column 'target_mm': '96.357' has more "):
        parse_positioning_log(tgt, source="d.csv")


def test_the_refusal_is_one_line_exit_2_from_the_cli(tmp_path, capsys):
    from scenarios.cli import main

    f = tmp_path / "d.csv"
    f.write_text(_declared(3, 3, "297.9055"))
    assert main(["iso230-2", str(f), "--json", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and "row 3 (line 13)" in err
    assert not (tmp_path / "o.json").exists()


def test_on_step_known_answers_and_each_writers_tolerance():
    """``core.probelog.on_step``: the one question both writers ask. Values read from K-decimal text lie on the
    step exactly (K = 0..11); one ulp off is off at rtol 0 (the probe log's writer: a change code made is written
    whole) and on at 1e-6 (the positioning writer's); a thousandth of a step is off at both. A table's computed
    measured column (target + deviation) is off the exact step in about a quarter of sums and on within 1e-6."""
    from core.probelog import WRITE_ON_STEP_RTOL_POSITIONING as RP, WRITE_ON_STEP_RTOL_PROBE as R0, on_step

    rng = np.random.default_rng(35)
    for k in range(12):
        v = [float(f"{x:.{k}f}") for x in rng.uniform(-1000, 1000, 300)]
        assert on_step(v, k, R0) and on_step(v, k, RP), k
    x = 405.771
    assert not on_step([np.nextafter(x, 1e9)], 3, R0) and on_step([np.nextafter(x, 1e9)], 3, RP)
    assert not on_step([x + 1e-6], 3, R0) and not on_step([x + 1e-6], 3, RP)
    assert on_step([np.nan, np.inf, 1.5], 1) and on_step([], 3) and on_step([np.nan], 3)
    t = np.round(rng.uniform(-1000, 1000, 2000), 3)
    d = np.round(rng.uniform(-50, 50, 2000), 1)
    sums = t + d * 1e-3
    off = [not on_step([s], 4, R0) for s in sums]
    assert 0.1 < np.mean(off) < 0.5 and on_step(sums, 4, RP)


def test_the_writers_decisions_unchanged_by_the_shared_helper():
    """Both writers' behaviour as before the helper: the probe log writes a column read to 3 decimals to 3 and a
    column moved by 1e-9 mm after reading whole; the positioning writer keeps a table's computed column to its
    step and drops the line for a column moved off it."""
    from dataclasses import replace

    from core.positioning import _written_decimals
    from core.probelog import fixed_decimals, make_log

    cols = {"setup": ["s"] * 2, "target": ["a", "b"], "t_s": [0.0, 1.0], "X_mm": [1.234, 2.5], "Y_mm": [0.0, 0.0],
            "Z_mm": [0.0, 0.0], "Xn_mm": [1.0, 2.0], "Yn_mm": [0.0, 0.0], "Zn_mm": [0.0, 0.0], "nx": [1.0, 1.0],
            "ny": [0.0, 0.0], "nz": [0.0, 0.0]}
    log = replace(make_log(cols), text_steps={"X_mm": 1e-3})
    assert fixed_decimals(log) == {"X_mm": 3}
    log.columns["X_mm"] = np.array([1.234 + 1e-9, 2.5])
    assert fixed_decimals(log) == {}
    log.columns["X_mm"] = np.array([np.nextafter(1.234, 9.0), 2.5])     # one ulp: written whole (rtol 0)
    assert fixed_decimals(log) == {}
    text = "target,cycle,direction,deviation_um\n" + "".join(
        f"{t},{c},{dd},{0.1 * c + (1.3 if dd == '-' else 0.0):.1f}\n"
        for c in (1, 2, 3) for t in (0.001, 100.017, 200.123) for dd in "+-")
    tab = parse_table(text)
    assert _written_decimals(tab) == {"target_mm": 3, "measured_mm": 4}
    assert _written_decimals(replace(tab, measured=tab.measured + 1e-9)) is None
