"""vmt's writer declares its numbers exact (session 31, the lead; after rank31): ``repr`` prints the shortest text
that reads back as the same double, so ``160.0`` is exactly 160, not a value printed to a tenth of a mm. Without
the declaration a log vmt wrote of a plate whose nominals lie on whole mm read as printed to 0.1 mm, and its rank
tolerance was ``RANK_QUANTUM_FACTOR x 0.1 mm / L`` instead of ``RANK_TOL``."""
import numpy as np
import pytest

from core import baseline as B
from core import probelog as P
from core.probelog import format_probe_log, parse_probe_log
from core.touches import from_log

from test_discover_rank31 import _plate, _planar, _decisions


def _rewritten(text: str) -> str:
    """``text`` read and written again by vmt (numbers as repr)."""
    return format_probe_log(parse_probe_log(text, "in.csv"))


def _in_memory(text: str) -> str:
    """``text``'s log as if built in memory (the simulator's, an import's: no printed step) and written by vmt."""
    log = parse_probe_log(text, "in.csv")
    return format_probe_log(P.ProbeLog(meta=log.meta, columns=log.columns, source="memory"))


def test_the_writer_declares_its_numbers_exact_and_the_reader_takes_them_so():
    """The whole-mm plate built in memory and written by vmt: the nominals print as ``160.0`` (1 decimal); the
    declaration makes their step 0, so the tolerance is RANK_TOL and the decisions are those of the file printed
    to 7 decimals (grid, rank, estimable workpiece; workpiece equal to 1e-9 um). The declaration is the file's,
    not the log's: read back, the metadata equal the original's (a lossless round trip)."""
    src = _plate(0.0)
    text = _in_memory(src)
    assert f"# {P.NUMBER_FORMAT_KEY}: {P.NUMBER_FORMAT_EXACT}" in text.splitlines()[:5]
    assert ",160.0," in text or ",-160.0," in text or ".0," in text  # (whole mm printed with one decimal)
    log = parse_probe_log(text, "vmt.csv")
    assert P.NUMBER_FORMAT_KEY not in log.meta and log.meta == parse_probe_log(src, "in.csv").meta
    assert set(log.text_steps.values()) == {0.0}
    t, bl = _planar(text)
    t7, bl7 = _planar(src)
    assert bl.rank_tol == bl7.rank_tol == B.RANK_TOL
    assert _decisions(bl)[:3] == _decisions(bl7)[:3]
    assert np.sqrt(np.mean((_decisions(bl)[3] - _decisions(bl7)[3]) ** 2)) < 1e-9


def test_without_the_declaration_the_digits_are_the_precision():
    """The same text with the line deleted: ``160.0`` is a value printed to 0.1 mm, and the tolerance the one such
    a file needs (rank30's 10 q / L): what the declaration is for (this test fails if the reader ignores the
    digits, the other if it ignores the declaration)."""
    text = "\n".join(l for l in _in_memory(_plate(0.0)).splitlines() if not l.startswith(f"# {P.NUMBER_FORMAT_KEY}"))
    t = from_log(parse_probe_log(text + "\n", "edited.csv"))
    assert t.text_steps["Xn_mm"] == pytest.approx(0.1)
    L = np.abs(t.pn_R[:, :2] - B.c_axis_centre(t)[:2]).max()
    assert B.precision_rank_tol(t, B.c_axis_centre(t)) == pytest.approx(B.RANK_QUANTUM_FACTOR * 0.1e-3 / L, rel=1e-12, abs=0)


@pytest.mark.parametrize("k", [7, 4, 3])
def test_a_log_read_from_a_file_and_written_again_keeps_its_printed_precision(k):
    """A plate printed to ``k`` decimals, read and written again by vmt: the recorded columns are written to the
    same ``k`` decimals (``160.0000000`` stays so, not ``160.0``), declared so column by column (session 33: before,
    the line was dropped, and the columns written as repr, ``t_s``, ``C_deg``, read as printed to their digits), and
    the tolerance read back is the file's own: 7 decimals keep RANK_TOL on the whole-mm plate, 4 and 3 rank30's
    protection."""
    src = _plate(0.0 if k == 7 else 0.0123457, decimals=k)
    text = _rewritten(src)
    cols = ("X_mm", "Y_mm", "Z_mm", "Xn_mm", "Yn_mm", "Zn_mm", "nx", "ny", "nz")
    assert (f"# {P.NUMBER_FORMAT_KEY}: {P.NUMBER_FORMAT_EXACT}; decimals "
            + ", ".join(f"{c}={k}" for c in cols)) in text.splitlines()
    assert _rewritten(text) == text    # write -> read -> write: the same bytes
    assert parse_probe_log(text, "re.csv").columns["Xn_mm"].tolist() == parse_probe_log(src, "in.csv").columns["Xn_mm"].tolist()
    t, t0 = from_log(parse_probe_log(text, "re.csv")), from_log(parse_probe_log(src, "in.csv"))
    assert t.text_steps["Xn_mm"] == pytest.approx(10.0 ** -k, abs=0) == t0.text_steps["Xn_mm"]
    c = B.c_axis_centre(t)
    assert B.precision_rank_tol(t, c) == B.precision_rank_tol(t0, c)
    assert (B.precision_rank_tol(t, c) == B.RANK_TOL) is (k == 7)


def test_a_declaration_in_other_words_is_not_taken():
    """Only vmt's own words declare exact numbers: another value of the key leaves the digits to say it."""
    text = _in_memory(_plate(0.0)).replace(P.NUMBER_FORMAT_EXACT, "six decimals")
    log = parse_probe_log(text, "other.csv")
    assert log.text_steps["Xn_mm"] == pytest.approx(0.1)
