"""review31e (session 31's fixes reviewed): the reader's rules against the specs' words.

Spec (probe-log.md, positioning-log.md): lines before the header that begin with ``#`` are metadata, one
``# key: value`` per line; "Unknown keys are kept and ignored". input31 refused every key given twice with two
values; a shop macro's repeated ``# Note:`` then stopped every command (F1). A key vmt reads (its value changes
the reading) is still refused; any other keeps its first value and the reader warns naming both lines.
A whole data row commented out with ``#`` was read as a one-touch set-up named ``#C0`` without a word (F2): it is
still read (a set-up may be named so, and vmt's own writer writes such a name unquoted), now with a warning."""
from __future__ import annotations

import pytest

from core.exceptions import ProbeLogError
from core.positioning import PositioningLogError, parse_positioning_log
from core.probelog import READ_META_KEYS, parse_probe_log
from scenarios.cli import main

from test_input31 import HEAD, positioning_text

ROWS = "S1,T1,1.0,10.0,0.0,0.0,10.0,0.0,0.0,1,0,0\nS1,T2,2.0,0.0,10.0,0.0,0.0,10.0,0.0,0,1,0\n"


def test_an_unknown_key_given_twice_is_kept_first_with_a_warning(tmp_path, capsys):
    text = f"# format: probe-log/1\n# Note: probe requalified\n# Note: coolant off\n{HEAD}\n{ROWS}"
    log = parse_probe_log(text, "n.csv")
    assert log.meta["Note"] == "probe requalified"
    assert ("line 3: metadata key 'Note' given twice ('probe requalified' on line 2, 'coolant off' on line 3): "
            "the first kept (vmt does not read it)") in log.warnings
    f = tmp_path / "n.csv"
    f.write_text(text)
    assert main(["check", str(f)]) == 0
    out = capsys.readouterr()
    assert "given twice" in out.out + out.err  # (vmt check prints the reader's warnings)
    pos = parse_positioning_log(positioning_text("ok", "# operator: A\n# operator: B\n"), "p.csv")
    assert pos.meta["operator"] == "A" and any("'operator' given twice" in w for w in pos.warnings)


@pytest.mark.parametrize("key, a, b", [("stylus_r_mm", "2", "3"), ("kinematic_chain", "V[w-C-Y-X-Z-t]", "V[w-Y-X-Z-t]")])
def test_a_key_vmt_reads_given_twice_is_still_refused(key, a, b):
    assert key in READ_META_KEYS
    with pytest.raises(ProbeLogError, match=f"metadata key '{key}' given twice"):
        parse_probe_log(f"# format: probe-log/1\n# {key}: {a}\n# {key}: {b}\n{HEAD}\n{ROWS}", "k.csv")
    with pytest.raises(PositioningLogError, match="metadata key 'unit' given twice"):
        parse_positioning_log(positioning_text("ok", "# unit: mm\n# unit: deg\n"), "p.csv")


def test_a_commented_out_row_is_read_with_a_warning():
    text = f"# format: probe-log/1\n{HEAD}\n{ROWS}#S1,T3,3.0,5.0,5.0,0.0,5.0,5.0,0.0,1,0,0\n"
    log = parse_probe_log(text, "c.csv")
    assert log.n == 3 and list(log.columns["setup"]) == ["S1", "S1", "#S1"]
    assert any(w.startswith("line 5: a whole row after the header starts with '#' (set-up '#S1')")
               for w in log.warnings)
    clean = parse_probe_log(f"# format: probe-log/1\n{HEAD}\n{ROWS}", "c.csv")
    assert not any("starts with '#'" in w for w in clean.warnings)
