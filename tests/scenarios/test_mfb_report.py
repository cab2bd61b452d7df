"""`vmt scenario mfb-3axis --report DIR`: index.html naming all 21 errors, the figures, the recording;
nothing left behind when the run fails after the report was written.

The shared noise-free run (conftest ``mfb3_noise_free``) stands in for the campaign, so the test
exercises the command's wiring and the report, not a second simulation. A report takes ~3.5 s of
CPU (matplotlib's layout of three figures), so it is written twice in this file and drawn once:
by a successful command with ``--budget-runs`` (:func:`budget_report`, shared by three tests: its
page is byte for byte the one ``mfb_report`` writes for the same document, figures included),
and by the failing command, which checks the page without a budget before it is removed, its
figures (the same document's) not drawn (conftest ``figures_not_drawn``).
"""

import contextlib
import copy
import dataclasses
import io
import json
import re
from pathlib import Path
from types import SimpleNamespace

import pytest

from core import iso
from scenarios.cli import main


def _use_shared_run(monkeypatch, mfb3_noise_free):
    import functools

    import scenarios.mfb as S

    # wraps: the report reads run's default bar calibration (u_cal_um) from its signature; a copy of the
    # document, since the command adds to it (its budget) and the run is shared with other files
    res = mfb3_noise_free[0]
    monkeypatch.setattr(S, "run", functools.wraps(S.run)(
        lambda name, **kw: dataclasses.replace(res, doc=copy.deepcopy(res.doc))))


#: The stubbed budget (its numbers are budget()'s, tested apart): one error, a different U95 per source.
def _budget_per_error(sources):
    return {"EXX": {"unit": "um", "U95": {s: 0.1 * (i + 1) for i, s in enumerate(sources)},
                    "temperature_one_T": 0.65, "quadrature": 1.4, "mc": 1.5, "mc_over_quadrature": 1.5 / 1.4}}


@pytest.fixture(scope="module")
def budget_report(tmp_path_factory, mfb3_noise_free):
    """``vmt scenario mfb-3axis --mc 0 --seed 4 --budget-runs 3 --report rep --json r.json`` on the
    shared run, the budget stubbed: ``(code, tmp, rep, js, out, seen)``, ``seen`` holding what the
    command asked the budget for, ``out`` its standard output."""
    import scenarios.mfb as S

    tmp = tmp_path_factory.mktemp("budget_report")
    seen = {}

    def fake(name, **kw):
        seen.update(kw, name=name)
        return {"sources": list(S.BUDGET_SOURCES), "per_error": _budget_per_error(S.BUDGET_SOURCES),
                "mc_runs": kw["mc_runs"], "method": "declared method text", "ratio_range": [1.0, 1.0, 1.0],
                "coverage": {"within_quadrature_U95": "1/1", "within_run_linear_U95": "1/1"}}

    rep, js, buf = tmp / "rep", tmp / "r.json", io.StringIO()
    with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stdout(buf):
        _use_shared_run(mp, mfb3_noise_free)
        mp.setattr(S, "budget", fake)
        from tests.cli_helpers import record_progress

        bars = record_progress(mp)
        code = main(["scenario", "mfb-3axis", "--mc", "0", "--seed", "4", "--budget-runs", "3", "--report", str(rep),
                     "--json", str(js)])
    return SimpleNamespace(code=code, tmp=tmp, rep=rep, js=js, out=buf.getvalue(), seen=seen, bars=bars)


def _page_has_the_21_errors_and_the_figures(page, doc):
    rows = re.findall(r"<tr><td>([A-Z0-9]+)</td>", page)
    assert rows[:21] == [*iso.LINEAR_MOTION, *iso.SQUARENESS]
    for png in ("error-curves.png", "squareness.png", "bar-calibration.png"):
        assert f'src="{png}"' in page
    # the table's max |identified - injected| is the run's own, not recomputed differently
    assert f"<td>EXX</td><td>{doc['errors']['EXX']['unit']}</td>" in page


def test_report_folder_has_the_page_figures_and_recording(budget_report, mfb3_noise_free):
    b = budget_report
    assert b.code == 0
    rep = b.rep
    for f in ("index.html", "recording.rrd", "error-curves.png", "squareness.png", "bar-calibration.png"):
        assert (rep / f).is_file() and (rep / f).stat().st_size > 0, f
    assert (rep / "recording.rrd").read_bytes()[:4] == b"RRF2"  # a rerun stream, not an empty placeholder
    page = (rep / "index.html").read_text(encoding="utf-8")
    _page_has_the_21_errors_and_the_figures(page, mfb3_noise_free[0].doc)
    # the 21 errors' table, then the budget's one row (EXX): no other table row
    assert len(re.findall(r"<tr><td>([A-Z0-9]+)</td>", page)) == 22
    assert not [p for p in b.tmp.iterdir() if p.name.startswith(".")]  # no temporaries left beside it


def test_a_failing_run_leaves_no_report(tmp_path, monkeypatch, mfb3_noise_free, capsys, figures_not_drawn):
    """The JSON is written after the report: failing there removes the report. When the JSON is written
    the report is complete, and without --budget-runs it has no budget section. Its three figures are
    not drawn (``figures_not_drawn``, about 1.4 s of CPU): they are those of the same shared run's
    document, which :func:`budget_report` draws (the PNGs were the same bytes in both tests)."""
    import core.atomic

    _use_shared_run(monkeypatch, mfb3_noise_free)
    rep = tmp_path / "rep"
    pages = []

    def fail(*a, **k):
        pages.append((rep / "index.html").read_text(encoding="utf-8"))
        raise OSError(28, "No space left on device", str(tmp_path / "r.json"))

    monkeypatch.setattr(core.atomic, "write_json_atomic", fail)
    assert main(["scenario", "mfb-3axis", "--mc", "0", "--noise-um", "0", "--report", str(rep), "--json",
                 str(tmp_path / "r.json")]) == 2
    assert "No space left" in capsys.readouterr().err
    assert not rep.exists() and list(tmp_path.iterdir()) == []
    assert len(pages) == 1
    _page_has_the_21_errors_and_the_figures(pages[0], mfb3_noise_free[0].doc)
    assert [Path(t).name.split(".")[1] for _, t in figures_not_drawn] == ["error-curves", "squareness",
                                                                          "bar-calibration"]
    assert len(re.findall(r"<tr><td>([A-Z0-9]+)</td>", pages[0])) == 21 and "budget" not in pages[0].lower()


def test_the_report_draws_its_own_progress_line(budget_report):
    """The report (4.7 s of CPU, 15 s at load 14) counted nothing after the identification's line (session 38):
    its own line, the figures, the recording and the page at their measured shares (REPORT_SHARES)."""
    from scenarios.mfb_report import REPORT_SHARES
    from tests.cli_helpers import percent_counts

    report = [b for b in budget_report.bars if "report" in b.label]
    assert len(report) == 1 and percent_counts(report[0].calls) == [0, *REPORT_SHARES, 100], report[0].calls


def test_report_draws_the_true_bar_and_the_budget_table(budget_report):
    """The bar section names the calibration and the simulated bar's truth; a budget in the
    document becomes the contributions table (one row per error, one column per source)."""
    page = (budget_report.rep / "index.html").read_text(encoding="utf-8")
    assert "true deviations" in page and "declared" in page
    assert "declared method text" in page and "machine temperature" in page
    assert re.search(r"<tr><td>EXX</td><td>um</td><td>0\.1(0*)?</td>", page), page[page.find("budget"):][:800]


def test_cli_budget_runs_reaches_json_terminal_and_report(budget_report):
    """--budget-runs N: the budget (stubbed: its numbers are budget()'s, tested apart) is
    asked for N runs with the run's seed, printed, and lands in the JSON and the report."""
    b = budget_report
    assert b.code == 0
    assert b.seen["name"] == "mfb-3axis" and b.seen["mc_runs"] == 3 and b.seen["seed"] == 4
    assert "uncertainty budget" in b.out
    assert json.loads(b.js.read_text())["budget"]["per_error"]["EXX"]["mc"] == 1.5
    assert "Uncertainty budget" in (b.rep / "index.html").read_text(encoding="utf-8")
