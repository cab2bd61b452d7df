"""`vmt scenario mfb-3axis --report DIR`: index.html naming all 21 errors, the figures, the recording;
nothing left behind when the run fails after the report was written.

The shared noise-free run (conftest ``mfb3_noise_free``) stands in for the campaign, so the test
exercises the command's wiring and the report, not a second simulation.
"""

import re

from core import iso
from scenarios.cli import main


def _use_shared_run(monkeypatch, mfb3_noise_free):
    import functools

    import scenarios.mfb as S

    # wraps: the report reads run's default bar calibration (u_cal_um) from its signature
    monkeypatch.setattr(S, "run", functools.wraps(S.run)(lambda name, **kw: mfb3_noise_free[0]))


def test_report_folder_has_the_page_figures_and_recording(tmp_path, monkeypatch, mfb3_noise_free, capsys):
    _use_shared_run(monkeypatch, mfb3_noise_free)
    rep = tmp_path / "rep"
    assert main(["scenario", "mfb-3axis", "--mc", "0", "--noise-um", "0", "--report", str(rep)]) == 0
    for f in ("index.html", "recording.rrd", "error-curves.png", "squareness.png", "bar-calibration.png"):
        assert (rep / f).is_file() and (rep / f).stat().st_size > 0, f
    assert (rep / "recording.rrd").read_bytes()[:4] == b"RRF2"  # a rerun stream, not an empty placeholder
    page = (rep / "index.html").read_text(encoding="utf-8")
    rows = re.findall(r"<tr><td>([A-Z0-9]+)</td>", page)
    assert rows == [*iso.LINEAR_MOTION, *iso.SQUARENESS] and len(rows) == 21
    for png in ("error-curves.png", "squareness.png", "bar-calibration.png"):
        assert f'src="{png}"' in page
    # the table's max |identified - injected| is the run's own, not recomputed differently
    d = mfb3_noise_free[0].doc
    assert f"<td>EXX</td><td>{d['errors']['EXX']['unit']}</td>" in page
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporaries left beside it


def test_a_failing_run_leaves_no_report(tmp_path, monkeypatch, mfb3_noise_free, capsys):
    import core.atomic

    _use_shared_run(monkeypatch, mfb3_noise_free)

    def fail(*a, **k):
        raise OSError(28, "No space left on device", str(tmp_path / "r.json"))

    monkeypatch.setattr(core.atomic, "write_json_atomic", fail)  # the JSON is written after the report
    rep = tmp_path / "rep"
    assert main(["scenario", "mfb-3axis", "--mc", "0", "--report", str(rep), "--json", str(tmp_path / "r.json")]) == 2
    assert "No space left" in capsys.readouterr().err
    assert not rep.exists() and list(tmp_path.iterdir()) == []


def test_report_draws_the_true_bar_and_the_budget_table(tmp_path, mfb3_noise_free):
    """The bar section names the calibration and the simulated bar's truth; a budget in the
    document becomes the contributions table (one row per error, one column per source)."""
    import copy

    from scenarios.mfb import BUDGET_SOURCES
    from scenarios.mfb_report import mfb_report

    doc = copy.deepcopy(mfb3_noise_free[0].doc)
    per = {"EXX": {"unit": "um", "U95": {s: 0.1 * (i + 1) for i, s in enumerate(BUDGET_SOURCES)},
                   "temperature_one_T": 0.65, "quadrature": 1.4, "mc": 1.5, "mc_over_quadrature": 1.5 / 1.4}}
    doc["budget"] = {"sources": list(BUDGET_SOURCES), "per_error": per, "method": "declared method text"}
    page = (mfb_report(tmp_path / "rep", doc) / "index.html").read_text(encoding="utf-8")
    assert "true deviations" in page and "declared" in page
    assert "declared method text" in page and "machine temperature" in page
    assert re.search(r"<tr><td>EXX</td><td>um</td><td>0\.1(0*)?</td>", page), page[page.find("budget"):][:800]


def test_cli_budget_runs_reaches_json_terminal_and_report(tmp_path, monkeypatch, mfb3_noise_free, capsys):
    """--budget-runs N: the budget (stubbed here: its numbers are budget()'s, tested apart) is
    asked for N runs with the run's seed, printed, and lands in the JSON and the report."""
    import json

    import scenarios.mfb as S

    _use_shared_run(monkeypatch, mfb3_noise_free)
    seen = {}
    per = {"EXX": {"unit": "um", "U95": {s: 0.1 for s in S.BUDGET_SOURCES}, "temperature_one_T": 0.1,
                   "quadrature": 0.3, "mc": 0.3, "mc_over_quadrature": 1.0}}

    def fake(name, **kw):
        seen.update(kw, name=name)
        return {"sources": list(S.BUDGET_SOURCES), "per_error": per, "mc_runs": kw["mc_runs"], "method": "m",
                "ratio_range": [1.0, 1.0, 1.0], "coverage": {"within_quadrature_U95": "1/1",
                                                             "within_run_linear_U95": "1/1"}}

    monkeypatch.setattr(S, "budget", fake)
    rep, js = tmp_path / "rep", tmp_path / "r.json"
    assert main(["scenario", "mfb-3axis", "--mc", "0", "--seed", "4", "--budget-runs", "3", "--report", str(rep),
                 "--json", str(js)]) == 0
    assert seen["name"] == "mfb-3axis" and seen["mc_runs"] == 3 and seen["seed"] == 4
    assert "uncertainty budget" in capsys.readouterr().out
    assert json.loads(js.read_text())["budget"]["per_error"]["EXX"]["mc"] == 0.3
    assert "Uncertainty budget" in (rep / "index.html").read_text(encoding="utf-8")
