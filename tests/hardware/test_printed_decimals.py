"""The controller's printing step reaches the probe log (session 33, step33).

GRBL prints every position it reports to 3 decimals in mm (``[PRB:61.328,50.000,5.283:1]``: a step of 1 um);
LinuxCNC's probe file ``%f``, 6. ``vmt import`` and ``vmt probe`` read that step from the controller's own text
and declare the log's X_mm, Y_mm, Z_mm printed to it (``# number_format: shortest round-trip; decimals X_mm=3,
Y_mm=3, Z_mm=3``), every other column exact, so ``vmt fit`` floors each U95 on the readings' rounding. Before, such
a log declared every number exact: the real firmware's table touched at four points fitted a plane with U95 0.
"""

import json
import re

import numpy as np
import pytest

from conftest import plan_log, scene
from core import fit as F
from core.exceptions import HardwareError
from core.probelog import format_probe_log, read_probe_log, write_probe_log
from hardware.backend import VirtualBackend
from hardware.campaign import ProbeSettings, run_campaign
from hardware.emulator import Faults
from hardware.grbl import GrblBackend, GrblClient, parse_prb
from scenarios.cli import main
from test_campaign import probe_args, serve
from test_grbl_transcripts import CAMPAIGN, LIMITS_MM, ReplayLink, settings, transcript

XYZ = ("X_mm", "Y_mm", "Z_mm")
#: k x 1 um / sqrt(12), k = 1.96: a wall's offset U95 from a 1 um printing step alone (core.fit.rounding_u95; every
#: touch of the table shares one printed Z)
FLOOR_1UM = F.ROUNDING_K / np.sqrt(12.0)


def _cells(path, col):
    """The text of column ``col`` in the data rows of a CSV log."""
    lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    j = lines[0].split(",").index(col)
    return [ln.split(",")[j] for ln in lines[1:]]


def _decimals(cells):
    return {len(c.partition(".")[2]) for c in cells if c}


def _fit_table(path, tmp_path, capsys):
    js = tmp_path / f"{path.stem}.json"
    assert main(["fit", "plane", str(path), "--feature", "table", "--json", str(js)]) == 0
    return json.loads(js.read_text()), capsys.readouterr().out


def test_import_of_the_real_firmwares_transcript_declares_its_1_um_and_fit_floors_on_it(tmp_path, capsys):
    """The real GRBL 1.1h campaign (tests/hardware/data/grbl-1.1h): its reports print 3 decimals. The import
    declares them, writes every reading to 3 decimals (the controller's own numbers, exact), keeps the plan's
    nominals exact, and writes again to the same bytes. ``vmt fit plane`` of the table (four touches at z = 0,
    every one printed ``0.000``: the scatter's U95 is 0) gives the offset U95 1.96 x 1 um / sqrt(12) = 0.566 um,
    marked as the printing step's; the same log declared exact (what the import wrote before) gives 0."""
    plan = write_probe_log(tmp_path / "plan.csv", plan_log())
    out = tmp_path / "imported.csv"
    assert main(["import", "grbl", str(CAMPAIGN), "--plan", str(plan), "--out", str(out)]) == 0
    capsys.readouterr()
    text = out.read_text()
    assert "# number_format: shortest round-trip; decimals X_mm=3, Y_mm=3, Z_mm=3\n" in text
    log = read_probe_log(out)
    assert log.text_steps == {**{c: 1e-3 for c in XYZ}, **{c: 0.0 for c in ("Xn_mm", "Yn_mm", "Zn_mm", "nx", "ny",
                                                                             "nz")}}
    prb = [parse_prb(t)[0] for d, t in transcript(CAMPAIGN) if t.startswith("[PRB")]
    assert np.array_equal(log.positions_mm(), np.array(prb))      # the controller's numbers, not a digit moved
    assert all(_decimals(_cells(out, c)) == {3} for c in XYZ)
    assert format_probe_log(log) == text                           # write -> read -> write
    rep, said = _fit_table(out, tmp_path, capsys)
    assert rep["printing_step_mm"] == pytest.approx([1e-3] * 3)
    assert rep["u95"]["offset_n_um"] == pytest.approx(FLOOR_1UM, rel=1e-9) and rep["u95_scatter"]["offset_n_um"] < 1e-9
    assert "never below the rounding of X, Y, Z printed to 0.001 mm): offset_n_um 0.566 (printing step)" in said
    exact = tmp_path / "exact.csv"
    exact.write_text(text.replace("; decimals X_mm=3, Y_mm=3, Z_mm=3", ""))
    rep0, said0 = _fit_table(exact, tmp_path, capsys)
    assert rep0["printing_step_mm"] == [0.0, 0.0, 0.0] and rep0["u95"]["offset_n_um"] < 1e-9
    assert "printing step" not in said0


def test_the_step_is_read_from_the_reports_text_not_assumed(tmp_path, capsys):
    """The same transcript with every report printed to 4 decimals (a firmware built to print mm so; its '$$'
    answer, $13=0, kept in the transcript says mm: 4 decimals without it is GRBL's inch print, refused): the log
    declares 4 and the fit floors on 0.1 um."""
    plan = write_probe_log(tmp_path / "plan.csv", plan_log())
    tr = tmp_path / "four.txt"
    four = re.sub(r"\[PRB:([^:\]]*):", lambda m: "[PRB:" + ",".join(v + "0" for v in m.group(1).split(","))
                  + ":", CAMPAIGN.read_text())
    tr.write_text(four)
    assert "[PRB:10.0000,10.0000,0.0000:1]" in tr.read_text()
    out = tmp_path / "four.csv"
    assert main(["import", "grbl", str(tr), "--plan", str(plan), "--out", str(out)]) == 2
    assert "prints 4 decimals, as GRBL prints inches" in capsys.readouterr().err and not out.exists()
    first, rest = four.split("\n", 1)
    tr.write_text(f"{first}\n{first.split()[0]} < $13=0\n{rest}")
    assert main(["import", "grbl", str(tr), "--plan", str(plan), "--out", str(out)]) == 0
    assert "decimals X_mm=4, Y_mm=4, Z_mm=4" in out.read_text()
    rep, _ = _fit_table(out, tmp_path, capsys)
    assert rep["u95"]["offset_n_um"] == pytest.approx(FLOOR_1UM / 10, rel=1e-9)


def test_vmt_probe_on_the_grbl_emulator_declares_the_controllers_3_decimals(tmp_path, plan_path, capsys):
    """``vmt probe`` against the project's GRBL emulator: the log's line declares X, Y, Z printed to the 3
    decimals of the controller's status report, every reading is written so (as its [PRB:...] printed it), a
    resumed run appends to the same decimals, and vmt's writer gives the same bytes back. The in-process virtual
    machine measures in metres: its log is exact (no decimals declared)."""
    out = tmp_path / "log.csv"
    emu, srv = serve(Faults(drop_before_probe=(6,)))                  # the link lost before the 6th probe
    try:
        assert main(probe_args(srv.url, plan_path, out)) == 2
        assert read_probe_log(out).n == 5
        assert main(probe_args(srv.url, plan_path, out, "--resume")) == 0
    finally:
        srv.stop()
    capsys.readouterr()
    text = out.read_text()
    assert "# number_format: shortest round-trip; decimals X_mm=3, Y_mm=3, Z_mm=3\n" in text
    assert all(_decimals(_cells(out, c)) == {3} for c in XYZ)
    log = read_probe_log(out)
    assert log.n == 12 and np.all(log.ok) and {log.text_steps[c] for c in XYZ} == {1e-3}
    assert format_probe_log(log) == text
    rep, _ = _fit_table(out, tmp_path, capsys)
    assert rep["printing_step_mm"] == pytest.approx([1e-3] * 3)
    v = tmp_path / "virtual.csv"
    assert main(probe_args("virtual:", plan_path, v)) == 0
    assert "# number_format: shortest round-trip\n" in v.read_text()
    assert {read_probe_log(v).text_steps[c] for c in XYZ} == {0.0}


def test_a_report_printed_finer_than_the_log_declares_is_not_logged(tmp_path):
    """The real firmware's campaign replayed with its first report printed to 4 decimals while its status reports
    print 3: writing it to the declared 3 would cut the controller's number, so the touch is refused, one line
    naming the row and both steps, and nothing is written (the log holds its header only)."""
    lines = transcript(CAMPAIGN)
    k = next(i for i, (d, t) in enumerate(lines) if t.startswith("[PRB"))
    lines[k] = ("<", "[PRB:10.0004,10.000,0.000:1]")
    be = GrblBackend(GrblClient(ReplayLink(lines), timeout_s=0.5))
    out = tmp_path / "log.csv"
    with pytest.raises(HardwareError, match=r"row 0 \(target 'p0'\) to 4 decimals, but the log declares X_mm, "
                                            r"Y_mm, Z_mm printed to 3"):
        run_campaign(be, plan_log(), out, settings(200.0))
    assert read_probe_log(out).n == 0


@pytest.mark.parametrize("kind, line, units, declared", [
    ("probeopen", "{:f} {:f} {:f}", "mm", "decimals X_mm=6, Y_mm=6, Z_mm=6"),
    ("log", "G1 X{:.4f} Y{:.4f} Z{:.4f}", "mm", "decimals X_mm=4, Y_mm=4, Z_mm=4"),
    ("inch", "{:f} {:f} {:f}", "inch", None),
])
def test_linuxcnc_import_declares_the_files_decimals(tmp_path, plan_path, kind, line, units, declared, capsys):
    """LinuxCNC's PROBEOPEN file (``%f``: 6 decimals) and a LOGOPEN file printed to 4: each import declares the
    decimals its file wrote X, Y, Z with. A file in inches is converted (x 25.4): a step of 25.4 x 10^-6 mm is
    no decimal step, and the converted numbers are written exact, as before (left out: said in docs/formats.md)."""
    run_campaign(VirtualBackend(scene(), home_m=(0, 0, 0.05)), read_probe_log(plan_path), tmp_path / "d.csv",
                 ProbeSettings(limits_mm=LIMITS_MM, safe_z_mm=30.0))
    pos = read_probe_log(tmp_path / "d.csv").positions_mm() / (25.4 if units == "inch" else 1.0)
    pf = tmp_path / "probe.txt"
    pf.write_text("".join(line.format(*p) + "\n" for p in pos))
    out = tmp_path / "log.csv"
    assert main(["import", "linuxcnc", str(pf), "--plan", str(plan_path), "--out", str(out), "--units", units]) == 0
    nf = next(x for x in out.read_text().splitlines() if x.startswith("# number_format:"))
    log = read_probe_log(out)
    if declared is None:
        assert nf == "# number_format: shortest round-trip" and {log.text_steps[c] for c in XYZ} == {0.0}
    else:
        assert nf == f"# number_format: shortest round-trip; {declared}"
        assert {log.text_steps[c] for c in XYZ} == {10.0 ** -int(declared[-1])}


def test_a_log_vmt_probe_began_before_session_33_is_resumed_as_it_was(tmp_path, plan_path, capsys):
    """A campaign log without the line (``vmt probe`` wrote none before session 33; its readings their shortest
    round-trip, ``10.0``) is resumed in its own format: the rows appended as they were, no line added, and the
    file read from its digits as before."""
    out = tmp_path / "old.csv"
    emu, srv = serve(Faults(drop_before_probe=(6,)))
    try:
        assert main(probe_args(srv.url, plan_path, out)) == 2
        lines = out.read_text().splitlines(True)
        old = [x for x in lines if not x.startswith("# number_format:")]
        k = old.index(next(x for x in old if x.startswith("setup,")))
        cols = old[k].strip().split(",")
        for i in range(k + 1, len(old)):                              # the rows as the old writer wrote them
            cells = old[i].rstrip("\n").split(",")
            for c in XYZ:
                j = cols.index(c)
                cells[j] = repr(float(cells[j]))
            old[i] = ",".join(cells) + "\n"
        out.write_text("".join(old))
        assert main(probe_args(srv.url, plan_path, out, "--resume")) == 0
    finally:
        srv.stop()
    text = out.read_text()
    assert "number_format" not in text and text.startswith("".join(old))
    new_rows = text[len("".join(old)):].splitlines()
    assert len(new_rows) == 7
    for c in XYZ:          # the appended readings in the old form: the shortest round-trip repr, not 3 fixed decimals
        j = cols.index(c)
        assert all(r.split(",")[j] == repr(float(r.split(",")[j])) for r in new_rows)
    assert any(r.split(",")[cols.index("X_mm")] in ("10.0", "90.0") for r in old[k + 1:])   # repr, as before
    assert read_probe_log(out).n == 12
