"""``vmt iso230-2`` on review34's findings (session 34): the readings' printed step in the output and JSON, the
readings skipped for their status counted, an evaluation refusal naming the file line, B̄ of a zero."""

import csv
import json

import pytest

from scenarios.cli import main
from scenarios.positioning_sample import SAMPLE


def _sample_rows():
    lines = open(SAMPLE).read().splitlines()
    k = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    return lines[:k], list(csv.reader(lines[k:]))


def test_skipped_readings_are_counted_by_status(tmp_path, capsys):
    meta, rows = _sample_rows()
    status = [r[rows[0].index("status")] for r in rows[1:]]   # counted here with the csv module, not by vmt
    bad = [s for s in status if s.strip().lower() != "ok"]
    assert len(status) == 91 and bad == ["beam interrupted"]
    out = tmp_path / "s.json"
    assert main(["iso230-2", str(SAMPLE), "--json", str(out)]) == 0
    rep = json.loads(out.read_text())
    assert rep["readings"] == {"readings": 91, "valid": 90, "skipped": 1,
                               "skipped_by_status": {"beam interrupted": 1}}
    first = capsys.readouterr().out.splitlines()[0]
    assert first.endswith("linear cycle; 91 readings, 1 skipped for its status ('beam interrupted')"), first


def test_no_skip_no_words(tmp_path, capsys):
    meta, rows = _sample_rows()
    j = rows[0].index("status")
    kept = [rows[0]] + [r for r in rows[1:] if r[j] == "ok"]
    p = tmp_path / "ok.csv"
    p.write_text("\n".join(meta + [",".join(r) for r in kept]) + "\n")
    assert main(["iso230-2", str(p), "--json", str(tmp_path / "o.json")]) == 0
    assert "skipped" not in capsys.readouterr().out.splitlines()[0]
    assert json.loads((tmp_path / "o.json").read_text())["readings"]["skipped"] == 0


def test_coarse_printed_step_is_said_in_output_and_json(tmp_path, capsys):
    meta, rows = _sample_rows()
    m = rows[0].index("measured_mm")
    for r in rows[1:]:
        r[m] = f"{float(r[m]):.2f}" if r[m] else r[m]
    p = tmp_path / "r2.csv"
    p.write_text("\n".join(meta + [",".join(r) for r in rows]) + "\n")
    out = tmp_path / "o.json"
    assert main(["iso230-2", str(p), "--json", str(out), "--eve-um", "0.4"]) == 0
    cap = capsys.readouterr()
    rep = json.loads(out.read_text())
    assert rep["printed_step"]["step_mm"] == pytest.approx(0.01) and rep["printed_step"]["coarse"] is True
    assert rep["R_um"] == pytest.approx(17.889, abs=5e-4)   # the standard's figure from the readings as printed
    # U cond of R: E_VE 0.4 um rectangular and 4 x 10 um / sqrt 12 (STEP_SENSITIVITY)
    assert rep["uncertainty"]["U_R_um"] == pytest.approx(2 * ((0.4 / 12 ** 0.5) ** 2 + (40 / 12 ** 0.5) ** 2) ** 0.5)
    assert [w for w in rep["warnings"] if "measured_mm is printed to 0.01 mm (10 um)" in w]
    assert cap.err.count("measured_mm is printed to 0.01 mm") == 1
    assert "  readings printed to 0.01 mm: rounding u 2.887 um a reading" in cap.out


def test_an_evaluation_refusal_names_the_file_line(tmp_path, capsys):
    meta, rows = _sample_rows()
    m = rows[0].index("measured_mm")
    assert rows[5][m] == "405.774005"        # data row 4, file line len(meta) + 1 + 5
    rows[5][m] = "502.653779"                # the next target's reading typed in its place
    p = tmp_path / "slip.csv"
    p.write_text("\n".join(meta + [",".join(r) for r in rows]) + "\n")
    assert main(["iso230-2", str(p), "--json", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err
    assert f"{p}: row 4 (line {len(meta) + 1 + 5}): measured 502.653779 mm at target 405.771 mm" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "o.json").exists()


HAND = """# format: positioning-log/1
# axis: X
target_mm,cycle,direction,measured_mm
""" + "".join(f"{t},{c},{d},{m}\n" for c, rows in enumerate((
    ((0, "+", "0.001"), (100, "+", "100.000"), (200, "+", "200.005"), (200, "-", "200.006"), (100, "-", "99.998"),
     (0, "-", "0.004")),
    ((0, "+", "0.002"), (100, "+", "100.000"), (200, "+", "200.007"), (200, "-", "200.006"), (100, "-", "99.998"),
     (0, "-", "0.004")),
    ((0, "+", "0.003"), (100, "+", "100.000"), (200, "+", "200.009"), (200, "-", "200.006"), (100, "-", "99.998"),
     (0, "-", "0.007"))), start=1) for t, d, m in rows)


def test_a_zero_mean_reversal_prints_as_zero(tmp_path, capsys):
    """review34's hand case: B_i = -3, +2, +1 um, so B̄ = 0 by hand; in floats -3.1e-12 um, printed -0.000 before."""
    p = tmp_path / "hand.csv"
    p.write_text(HAND)
    assert main(["iso230-2", str(p), "--json", str(tmp_path / "h.json")]) == 0
    rep = json.loads((tmp_path / "h.json").read_text())
    assert rep["B_mean_um"] == pytest.approx(0.0, abs=1e-9) and rep["B_um"] == pytest.approx(3.0, abs=1e-9)
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("  B\u0304"))
    assert line.split()[1] == "0.000", line


def test_a_capitalised_format_key_is_named(tmp_path, capsys):
    """review34: '# Format:' made the file a table and the message asked to add the line it had in another case.
    The spec's keys are written in lower case and the reader takes them as written: refused, naming the line."""
    meta, rows = _sample_rows()
    assert meta[0] == "# format: positioning-log/1"
    p = tmp_path / "upper.csv"
    p.write_text("\n".join(["# Format: positioning-log/1"] + meta[1:] + [",".join(r) for r in rows]) + "\n")
    assert main(["iso230-2", str(p), "--json", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("write line 1's key in lower case, '# format: positioning-log/1' (metadata keys are "
                        "case-sensitive: '# Format:' is another key)"), err
    assert len(err.splitlines()) == 1
