"""A positioning log without a clock, in the engine's own words (session 37, left37).

Without a complete ``t_s`` column core.baseline.positioning takes the reading order, 0, 1, ..., n - 1, for the
time. Session 36 (left36) drew such a log against the reading order on the report page, but the engine's own
report still said "residuals follow time" and named warm_up's time constant ``time_constant_s``: a count of
readings read as seconds. Now the baseline says what its time is (``info["time"]``, the report's
``baseline.time``), the covariates built on it say "the reading order", and a finding's time figure is named in
readings (``time_constant_readings``). A log with a clock reads as before.

Checked against what the engine did not produce: the sample log's own rows with the clock taken out by hand, and a
report written by hand.
"""

from __future__ import annotations

import functools

import numpy as np

from core.baseline import NO_CLOCK_TIME, _no_clock_keys, positioning


def _bl(t_s):
    x = np.tile(np.repeat([0.0, 0.1, 0.2], 2), 3)
    d = np.tile(["+", "-"], 9)
    c = np.repeat([0, 1, 2], 6)
    return positioning(x, d, c, 1e-6 * np.sin(np.arange(18.0)), t_s)


def test_the_baseline_says_its_time_is_the_reading_order():
    no = _bl(None)
    assert no.info["time"] == NO_CLOCK_TIME == "the reading order (the log has no clock)"
    words = {c.name: c.words for c in no.covariates}
    assert words["time"] == "time, here the reading order (the log has no clock)"
    assert words["time_by_direction"].startswith("time, here the reading order (the log has no clock), opposite")
    assert np.array_equal(next(c for c in no.covariates if c.name == "time").values, np.arange(18.0))
    clocked = _bl(np.arange(18.0) * 7.5)
    assert "time" not in clocked.info
    assert {c.name: c.words for c in clocked.covariates}["time"] == "time"


def test_a_findings_time_figure_is_named_in_readings():
    """Known answer on a report written by hand: every place the finding names time_constant_s says
    time_constant_readings, its values unchanged; a key that is not a time figure stays; a rival named by the
    time covariate is said to be the order's; the diagnosis (built from the covariates' words) is left alone."""
    rep = {"findings": [{"cause": "warm_up",
                         "params": {"initial_offset_um": -1.3, "time_constant_s": None, "rms_s_um": 2.0},
                         "params_u95": {"initial_offset_um": 0.4, "time_constant_s": None},
                         "evidence": {"one_sided": {"time_constant_s": {"at_least": 20.4}},
                                      "profile_at_grid_edge": ["time_constant_s"],
                                      "confidence_reason": "indistinguishable from a smooth term in time; "
                                                           "time_constant_s >= 20.4: not determined"}}],
           "diagnosis": [{"covariate": "time", "text": "residuals follow time: 0.3 um"}]}
    out = _no_clock_keys(rep)
    f = out["findings"][0]
    assert f["params"] == {"initial_offset_um": -1.3, "time_constant_readings": None, "rms_s_um": 2.0}
    assert f["params_u95"] == {"initial_offset_um": 0.4, "time_constant_readings": None}
    assert f["evidence"]["one_sided"] == {"time_constant_readings": {"at_least": 20.4}}
    assert f["evidence"]["profile_at_grid_edge"] == ["time_constant_readings"]
    assert f["evidence"]["confidence_reason"] == ("indistinguishable from a smooth term in time (the reading order "
                                                  "here); time_constant_readings >= 20.4: not determined")
    assert out["diagnosis"] == rep["diagnosis"]
    assert rep["findings"][0]["params"]["time_constant_s"] is None   # the input is not changed


@functools.lru_cache(maxsize=None)
def _discovered(holes: bool):
    import tempfile
    from pathlib import Path

    from core.baseline import positioning_from_log
    from core.discover import discover_baseline
    from core.positioning import read_positioning_log
    from tests.scenarios.test_discover_report_left36 import _without_clock

    with tempfile.TemporaryDirectory() as tmp:
        log = read_positioning_log(_without_clock(Path(tmp) / "p.csv", holes))
    return discover_baseline(positioning_from_log(log)).to_report()


def test_the_report_and_summary_of_a_log_without_a_clock_say_readings():
    """The shipped sample without its t_s column (a warm-up, named; fails before: "residuals follow time: ..." and
    ``time_constant_s >= 20.4`` in the summary ``vmt discover`` prints)."""
    import json

    from scenarios.cli.discover import summary_lines

    rep = _discovered(False)
    assert rep["baseline"]["time"] == NO_CLOCK_TIME
    time_d = next(d for d in rep["diagnosis"] if d["covariate"] == "time")
    assert time_d["text"].startswith("residuals follow time, here the reading order (the log has no clock): ")
    assert rep["cause"] == "warm_up"
    assert "time_constant_readings" in rep["findings"][0]["params"]
    text = json.dumps(rep["findings"])
    assert "time_constant_s" not in text and "term in time;" not in text
    lines = "\n".join(summary_lines(rep, "positioning"))
    assert "residuals follow time:" not in lines and "time_constant_s" not in lines
    assert "time_constant_readings" in lines


def test_a_clock_with_a_hole_is_the_reading_order_too():
    rep = _discovered(True)
    assert rep["baseline"]["time"] == NO_CLOCK_TIME
    assert rep["findings"] and not any(k.endswith("_s") for f in rep["findings"] for k in f["params"])
