"""The plain ISO 230-2 table's metadata (session 31, warn31): a key given twice with two values is refused, as in a
positioning log (core.probelog.add_meta); '#' lines stay comments anywhere in a table (docs/formats.md, "The
table": a table is not a positioning log, whose '#' lines are before its header only)."""

from __future__ import annotations

import pytest

from core.positioning import PositioningLogError, parse_table

READINGS = ["0 1 + 0.001", "10 1 + 10.002", "0 1 - 0.0", "10 1 - 10.001"]


def test_a_unit_given_twice_with_two_values_is_refused_naming_both_lines():
    """Before: the last '# unit:' won without a word (this table, written in deg, was read in mm)."""
    text = "\n".join(["# unit: deg", *READINGS[:2], "# unit: mm", *READINGS[2:]]) + "\n"
    with pytest.raises(PositioningLogError) as e:
        parse_table(text, "t.txt")
    assert str(e.value) == ("t.txt: line 4: metadata key 'unit' given twice: 'deg' on line 1, 'mm' on line 4: "
                            "keep the one that holds")


def test_the_same_value_twice_and_comments_between_blocks_read_as_before():
    text = "\n".join(["# unit: deg", "# axis: C", *READINGS[:2], "# the return run", "# unit: deg",
                      *READINGS[2:]]) + "\n"
    log = parse_table(text, "t.txt")
    assert log.unit == "deg" and log.meta["axis"] == "C" and log.n == 4
    assert list(log.measured) == [0.001, 10.002, 0.0, 10.001]


def test_a_key_vmt_does_not_read_given_twice_keeps_its_first_with_a_warning():
    """The positioning log's rule (core.probelog.add_meta, review31e F1): the specs keep and ignore unknown keys,
    so a repeated '# note:' is not a refusal; the table says so as the other readers do."""
    text = "\n".join(["# note: first run", *READINGS[:2], "# note: return run", *READINGS[2:]]) + "\n"
    log = parse_table(text, "t.txt")
    assert log.meta["note"] == "first run" and log.n == 4
    assert ("line 4: metadata key 'note' given twice ('first run' on line 1, 'return run' on line 4): the first kept "
            "(vmt does not read it)") in log.warnings
