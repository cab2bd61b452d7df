"""``vmt import grbl`` on review34's findings (session 34): an ``error:N`` a sender went on after is named at its
line (not blamed on a mismatched plan), and ``t_s`` is the stamps' difference to their own decimals."""

from decimal import Decimal
from pathlib import Path

import pytest

from conftest import plan_log
from core.exceptions import ProbeLogError
from core.probelog import write_probe_log
from hardware.transcript import import_transcript, read_transcript
from scenarios.cli import main

DATA = Path(__file__).parent / "data" / "grbl-1.1h"
CAMPAIGN = DATA / "grbl-1.1h-sim-vmt-campaign-transcript.txt"


def _with_error(tmp_path) -> tuple[Path, int, int]:
    """The reference campaign with plan row 4's report (s0, the 5th probing move's) answered ``error:2``, the
    sender going on to row 5: review34's tr_error.txt. Returns the file, the error's line and its G38's."""
    lines = CAMPAIGN.read_text().splitlines()
    g38 = [i for i, ln in enumerate(lines) if " > " in ln and "G38.2" in ln]
    k = g38[4] + 1
    assert "[PRB:" in lines[k]
    stamp = lines[k].split(" ", 1)[0]
    lines[k] = f"{stamp} < error:2"
    p = tmp_path / "tr_error.txt"
    p.write_text("\n".join(lines) + "\n")
    return p, k + 1, g38[4] + 1


def test_an_error_the_sender_went_on_after_is_named(tmp_path):
    p, err_line, sent_line = _with_error(tmp_path)
    with pytest.raises(ProbeLogError) as e:
        import_transcript(p, plan_log())
    msg = str(e.value)
    assert msg.startswith(f"{p}: line {err_line}: error:2 answered the probing command of line {sent_line} "
                          "(plan row 4, target 's0') and the sender went on"), msg
    assert "one off" not in msg.split("would be one row off")[0] and "not this plan's" not in msg


def test_the_cli_refuses_it_in_one_line(tmp_path, capsys):
    p, err_line, _ = _with_error(tmp_path)
    plan = write_probe_log(tmp_path / "plan.csv", plan_log())
    out = tmp_path / "log.csv"
    assert main(["import", "grbl", str(p), "--plan", str(plan), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"line {err_line}: error:2 answered" in err and not out.exists()


def test_t_s_is_the_stamps_difference_to_their_decimals():
    """Known answer by decimal arithmetic on the transcript's own text: each report's stamp minus the first
    line's stamp, exact in Decimal, is t_s to the last bit (4.366, not 4.365999937057495)."""
    lines = CAMPAIGN.read_text().splitlines()
    first = Decimal(lines[0].split(" ", 1)[0])
    want = [float(Decimal(ln.split(" ", 1)[0]) - first) for ln in lines if "[PRB:" in ln]
    _, _, t, _ = read_transcript(CAMPAIGN)
    assert len(want) == len(t) == 12
    assert [float(x) for x in t] == want
    assert repr(float(t[0])) == "4.366"
