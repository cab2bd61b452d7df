"""`vmt discover` on an ISO 230-2 positioning test (issue 18 item 4), the project's own sample.

The sample (scenarios/positioning_sample.py, written apart from sim/) hides a
warm-up drift ``3.5 (1 - exp(-t / 1200 s))`` um over a test of about 9
minutes, with scale, pitch and lost motion that the standard's baseline (a
mean per target and direction) absorbs by construction. Over the test the
warm-up rises 1.27 um from its first reading: the finding must be the warm-up,
with its offset against the end of the test within its U95.
"""

import json
import math
from pathlib import Path

import pytest

from scenarios.cli import main
from scenarios.positioning_sample import SAMPLE


def test_discover_names_the_samples_warm_up(tmp_path, capsys):
    out = tmp_path / "d.json"
    assert main(["discover", str(SAMPLE), "--json", str(out)]) == 0
    rep = json.loads(out.read_text())
    assert rep["cause"] == "warm_up", [f["cause"] for f in rep["findings"]]
    f = rep["findings"][0]
    t_end = max(r for r in _times())
    rise = 3.5 * (1 - math.exp(-t_end / 1200.0))            # um, from the first reading to the last
    assert abs(f["params"]["initial_offset_um"] + rise) <= f["params_u95"]["initial_offset_um"], (f, rise)
    assert rep["gain"]["cv_rms_ratio"] < 0.9
    assert "warm_up" in capsys.readouterr().out


def _times():
    for line in SAMPLE.read_text().splitlines():
        if line and not line.startswith("#") and not line.startswith("target"):
            yield float(line.split(",")[4])


@pytest.mark.parametrize("extra, what", [(["--grid-mm", "22"], "--grid-mm")])
def test_discover_positioning_refuses_what_it_cannot_do(tmp_path, capsys, extra, what):
    out = tmp_path / "d.json"
    assert main(["discover", str(SAMPLE), "--json", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert what in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


# --- the report page of a positioning test (issue 13 "Done when"; audit35 F1: --report exited 2 on every ISO 230-2
# log before session 35) -------------------------------------------------------------------------------------------
_POSITIONING_LOGS = [SAMPLE, Path(__file__).resolve().parents[1] / "core" / "data" / "csv_lines" / "pos_ff.csv"]


def _tables(index_html: str) -> dict:
    """{section title: [rows of cell texts]} of a report page (the page's own html, parsed with the stdlib)."""
    import html
    import re

    out = {}
    for title, body in re.findall(r'<h2 id="s\d+">(.*?)</h2>(.*?)(?=<h2 |</body>)', index_html, flags=re.S):
        rows = [[html.unescape(c) for c in re.findall(r"<td>(.*?)</td>", tr, flags=re.S)]
                for tr in re.findall(r"<tr>(.*?)</tr>", body, flags=re.S)]
        out[html.unescape(title)] = [r for r in rows if r]
    return out


@pytest.mark.parametrize("log", _POSITIONING_LOGS, ids=lambda p: p.name)
def test_discover_report_page_of_a_positioning_log(tmp_path, log):
    """Both positioning logs of the repository give rc 0 and a page whose figures exist and whose text is the
    JSON's: the verdict names the JSON's cause, the diagnosis table holds every diagnosis of the JSON (covariate,
    words, p as written), the fitted magnitudes and the mean deviation per target and direction are the JSON's;
    diagnosis.png is drawn exactly when a covariate has p < FIGURE_P (the sample's warm-up: time, order, cycle,
    temperatures; pos_ff: none)."""
    from core.diagnosis import FIGURE_P
    from viz.report import _cell

    out, page = tmp_path / "d.json", tmp_path / "r"
    assert main(["discover", str(log), "--json", str(out), "--report", str(page)]) == 0
    rep = json.loads(out.read_text())
    for png in ("findings.png", "residuals_baseline.png", "residuals_extended.png"):
        assert (page / png).stat().st_size > 1000, png
    structured = [g for g in rep["diagnosis"] if g["p_value"] < FIGURE_P]
    assert (page / "diagnosis.png").exists() == bool(structured)
    if log == SAMPLE:   # the sample's warm-up leaves structure against time: the figure must be there
        assert {g["covariate"] for g in structured} >= {"time", "order", "cycle"}
    text = (page / "index.html").read_text(encoding="utf-8")
    assert f"Cause: {rep['cause']}" in text if rep["cause"] != "none" else "No candidate cause" in text
    tabs = _tables(text)
    want = [[g["covariate"], _cell(g["explained_rms_um"]), _cell(g["p_value"]), g["text"]] for g in rep["diagnosis"]]
    import html

    assert tabs["Diagnosis: where the structure lives"] == [[html.unescape(c) for c in r] for r in want]
    assert "dq" not in text and "approach angle" not in text and "touches" not in text   # a probe log's words
    # (a magnitude bounded on one side, its value null: ">= x", "not determined", as the summary says it; session 36)
    sides = {(f["cause"], k): s for f in rep["findings"] for k, s in (f["evidence"].get("one_sided") or {}).items()}
    mags = [[f["cause"], k, html.unescape(_cell(v)), html.unescape(_cell(f["params_u95"].get(k))), ""]
            if (f["cause"], k) not in sides or v is not None else
            [f["cause"], k, f">= {sides[f['cause'], k]['at_least']:.4g}", "not determined", ""]
            for f in rep["findings"] for k, v in f["params"].items()]
    assert tabs.get("Fitted magnitudes", []) == mags
    assert bool(mags) == (rep["cause"] != "none")
    means = [[w["target"]] + [html.unescape(_cell(w[k])) for k in ("baseline_um", "baseline_u95_um", "extended_um",
                                                                    "extended_u95_um")] for w in rep["workpiece"]]
    assert tabs["Mean deviation per target and direction (discovery)"] == means


def test_positioning_diagnosis_panels_are_the_jsons(tmp_path):
    """The sample's diagnosis figure, read from the matplotlib objects: one panel per covariate with p < FIGURE_P in
    the JSON's order, titled with the JSON's words, its residual axis the deviation in µm, the cycles named by the
    log's numbers (1..5, not indices 0..4), each x axis with its unit."""
    from core.baseline import positioning_from_log
    from core.diagnosis import FIGURE_P
    from core.discover import discover_baseline
    from core.positioning import read_positioning_log
    from scenarios.reports import _positioning_sections

    d = discover_baseline(positioning_from_log(read_positioning_log(SAMPLE)))
    rep = d.to_report()
    secs = _positioning_sections(d, rep)
    fig = next(s.figures["diagnosis"] for s in secs if "diagnosis" in s.figures)
    axs = [ax for ax in fig.axes if ax.get_visible()]
    want = [g for g in rep["diagnosis"] if g["p_value"] < FIGURE_P][:6]
    assert len(want) >= 3 and [ax.get_title().replace("\n", " ") for ax in axs] == [g["text"] for g in want]
    for ax, g in zip(axs, want):
        assert ax.get_ylabel() == "residual of the deviation / µm"
        assert ax.get_xlabel().endswith((" / s", " / °C", " / mm", "(index)", "(category)")), ax.get_xlabel()
        if g["covariate"] == "cycle":
            assert [t.get_text() for t in ax.get_xticklabels()] == ["1", "2", "3", "4", "5"]
    res = next(s.figures["residuals_baseline"] for s in secs if "residuals_baseline" in s.figures)
    assert [ax.get_xlabel() for ax in res.axes] == ["t / s", "the target position / mm"]


def test_a_rotary_positioning_page_is_in_arc_seconds(tmp_path):
    """A rotary axis's page: its figures and columns in arc seconds and targets in degrees, never µm or mm
    (the JSON's _arcsec keys read back; review31 F11's log, tests/core/test_discover_positioning.py)."""
    from core.positioning import write_positioning_log
    from tests.core.test_discover_positioning import _rotary_log

    log = write_positioning_log(tmp_path / "rot.csv", _rotary_log())
    out, page = tmp_path / "d.json", tmp_path / "r"
    assert main(["discover", str(log), "--json", str(out), "--report", str(page)]) == 0
    rep = json.loads(out.read_text())
    text = (page / "index.html").read_text(encoding="utf-8")
    assert "µm" not in text and "mm+" not in text and "RMS / ″" in text
    tabs = _tables(text)
    from viz.report import _cell

    assert tabs["Discovery: verdict"][0][1] == _cell(rep["baseline"]["rms_arcsec"])
