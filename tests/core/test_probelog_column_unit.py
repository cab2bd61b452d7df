"""A probe-log column in another unit or case than the spec's (session 34, review34's medium-low finding):
``C_rad`` beside no ``C_deg`` was carried along as an unknown column and C read as 0 without a word. The spec
allows other columns ("other columns are allowed and carried along", docs/formats.md), so the reader keeps the
file and warns in one line naming the column and the spec's name and unit; a missing required column names the
column in another unit it found."""

from pathlib import Path

import pytest

from core.probelog import ProbeLogError, parse_probe_log

MYLOG = Path(__file__).parent / "data" / "input31" / "mylog.csv"


def _renamed(old: str, new: str) -> str:
    lines = MYLOG.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    cols = lines[k].rstrip("\n").split(",")
    assert old in cols
    lines[k] = ",".join(new if c == old else c for c in cols) + "\n"
    return "".join(lines)


def _column_warnings(log):
    return [w for w in log.warnings if "is not a probe-log column" in w]


def test_the_shipped_log_has_no_such_warning():
    assert _column_warnings(parse_probe_log(MYLOG.read_text())) == []


@pytest.mark.parametrize("name, meant", [("C_rad", "C_deg"), ("c_deg", "C_deg"), ("C", "C_deg"),
                                         ("C_arcsec", "C_deg")])
def test_an_angle_in_another_unit_is_named(name, meant):
    log = parse_probe_log(_renamed("C_deg", name), source="x.csv")
    w = _column_warnings(log)
    assert len(w) == 1 and f"column {name!r}" in w[0] and f"the spec's is {meant!r} (degrees)" in w[0]
    assert "C is read as 0" in w[0]
    assert name in log.columns and "C_deg" not in log.columns   # carried along, not read: the spec's rule


def test_an_extra_column_beside_the_spec_one_is_not_warned():
    text = _renamed("C_deg", "C_deg")
    lines = text.splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    lines = lines[:k] + [lines[k].rstrip("\n") + ",C_rad,operator\n"] + [
        ln.rstrip("\n") + ",0.0,ab\n" for ln in lines[k + 1:]]
    assert _column_warnings(parse_probe_log("".join(lines))) == []


def test_a_required_column_in_another_unit_is_named_in_the_refusal():
    with pytest.raises(ProbeLogError, match=r"missing required column 'X_mm'; column 'X_in' is there: the spec's "
                                            r"name carries its unit \('X_mm': millimetres\)"):
        parse_probe_log(_renamed("X_mm", "X_in"))
