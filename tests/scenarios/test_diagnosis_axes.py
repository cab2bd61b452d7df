"""diagnosis.png's axes say their units and name their categories (review 27 fault 4), read from the
matplotlib objects the report draws, not from pixels."""

import numpy as np
import pytest

from core.diagnosis import Covariate
from scenarios.reports import TIME_IN_HOURS_S, _discovery_sections, diagnosis_axis
from tests.discover_helpers import discovered


class _Bl:
    group_ids = ("C0", "C75", "C130", "C210")


def test_each_covariate_kind_gets_its_unit_or_its_names():
    n = 8
    cases = {
        "time": (Covariate("time", np.linspace(0, 600, n), "smooth", 6, (0,), "time", "time"), "time / s"),
        "time_h": (Covariate("time", np.linspace(0, 3 * TIME_IN_HOURS_S, n), "smooth", 6, (0,), "time", "time"),
                   "time / h"),
        "in_setup": (Covariate("time_in_setup", np.linspace(0, 1, n), "smooth", 5, (0,), "time within each set-up",
                               "time"), "time within each set-up (fraction of the longest set-up's span, 0..1)"),
        "az": (Covariate("approach_azimuth", np.linspace(0, np.pi, n), "circular", 4, (0,), "the approach azimuth",
                         "direction"), "the approach azimuth / °"),
        "x": (Covariate("x", np.linspace(0, 0.1, n), "smooth", 8, (0,), "the x position", "position"),
              "the x position / mm"),
        "since": (Covariate("time_since_previous", np.linspace(0, 2, n), "smooth", 4, (0,),
                            "the time since the previous touch", "history"),
                  "log10 of the time since the previous touch / s"),
        "temp": (Covariate("temp_spindle", np.linspace(20, 21, n), "smooth", 5, (0,), "the temperature temp_spindle_C",
                           "time"), "the temperature temp_spindle_C / °C"),
    }
    for key, (cov, want) in cases.items():
        x, label, ticks = diagnosis_axis(cov, np.asarray(cov.values), _Bl())
        assert label == want, key
        assert ticks is None
    assert diagnosis_axis(cases["time_h"][0], np.asarray(cases["time_h"][0].values))[0].max() == \
        pytest.approx(3 * TIME_IN_HOURS_S / 3600)
    setup = Covariate("setup", np.array([0, 0, 1, 3, 3, 2]), "categorical", 0, (0,), "the set-up", "time")
    x, label, ticks = diagnosis_axis(setup, np.asarray(setup.values), _Bl())
    assert ticks == ["C0", "C75", "C130", "C210"] and label == "the set-up (category)"
    assert x.tolist() == [0, 0, 1, 3, 3, 2]
    # drawn: the ticks sit at the categories' indices and carry their names
    from viz.figures import diagnosis_figure

    fig = diagnosis_figure([{"x": x, "residual_um": np.zeros(6), "fitted_um": np.zeros(6), "xlabel": label,
                             "text": "t", "xticklabels": ticks}])
    ax = fig.axes[0]
    assert ax.get_xlabel() == "the set-up (category)"
    assert [tk.get_text() for tk in ax.get_xticklabels()] == ["C0", "C75", "C130", "C210"]
    assert list(ax.get_xticks()) == [0, 1, 2, 3]
    feat = Covariate("feature", np.array(["pocket|0", "sphere1|1", "pocket|1"], dtype=object), "categorical", 0,
                     (0,), "the feature, differently in each set-up", "feature")
    assert diagnosis_axis(feat, np.asarray(feat.values), _Bl())[2] == ["pocket @ C0", "pocket @ C75",
                                                                       "sphere1 @ C75"]


def test_the_report_figure_of_a_drifting_campaign_reads_its_units(tmp_path):
    """A drift written into a simulated cross pocket (as review 27's drift run): time, time within a set-up
    and the touch order carry structure; every panel's x label names its unit or scale, categories their
    names."""
    from core.probelog import read_probe_log
    from core.touches import from_log
    from tests.scenarios.test_discover_cli_summary import drift_log

    log = drift_log(tmp_path)
    lg = read_probe_log(log)
    t = from_log(lg)
    d = discovered(lg, t)
    rep = d.to_report()
    secs = _discovery_sections(d, t, rep)
    fig = next(s.figures["diagnosis"] for s in secs if "diagnosis" in s.figures)
    axs = [ax for ax in fig.axes if ax.get_visible()]
    labels = [ax.get_xlabel() for ax in axs]   # seed 1001: time in set-up, time periodically, order, time, C, set-up
    assert any(lb == "time / s" or lb == "time / h" for lb in labels), labels
    units = (" / s", " / h", " / °", " / mm", " / °C", "(category)", "(index)", "0..1)")
    for ax, lb in zip(axs, labels):
        assert lb.endswith(units), lb
        if lb == "the set-up (category)":
            assert [tk.get_text() for tk in ax.get_xticklabels()] == list(d.baseline.group_ids)
    if any(lb.startswith("time within each set-up") for lb in labels):
        assert "time within each set-up (fraction of the longest set-up's span, 0..1)" in labels


def test_a_periodic_diagnosis_is_drawn_against_its_phase():
    """A periodic (spectral) diagnosis is drawn against the covariate modulo the period found, so a 12.4 mm screw
    profile over 150 mm of x reads as one profile (review30c finding 7: drawn against x it looked like noise); a
    smooth covariate, and a periodic one without a period, as given. Known answers: 30.0 mm mod 12.4 = 5.2 mm."""
    from types import SimpleNamespace

    from scenarios.reports import periodic_phase

    cov = Covariate("x_periodic", np.array([0.0, 0.03, 0.0124]), "spectral", 0, (1, 2), "the x position periodically",
                    "position", (0.005, 0.05))
    x, label, _ = diagnosis_axis(cov, np.asarray(cov.values))
    xp, lp = periodic_phase(cov, SimpleNamespace(test=SimpleNamespace(period=0.0124)), x, label)
    np.testing.assert_allclose(xp, [0.0, 30.0 - 2 * 12.4, 0.0], atol=1e-12)
    assert lp == "the x position periodically, modulo 12.4 / mm"
    tcov = Covariate("time_periodic", np.linspace(0, 3 * TIME_IN_HOURS_S, 4), "spectral", 0, (0,), "time periodically",
                     "time", (60.0, 3600.0))
    x, label, _ = diagnosis_axis(tcov, np.asarray(tcov.values))
    xp, lp = periodic_phase(tcov, SimpleNamespace(test=SimpleNamespace(period=1800.0)), x, label)
    assert lp == "time periodically, modulo 0.5 / h" and np.all(xp < 0.5)
    smooth = Covariate("x", np.array([0.0, 0.03]), "smooth", 8, (0,), "the x position", "position")
    x, label, _ = diagnosis_axis(smooth, np.asarray(smooth.values))
    assert periodic_phase(smooth, SimpleNamespace(test=SimpleNamespace(period=0.0124)), x, label) == (x, label)
    assert periodic_phase(cov, SimpleNamespace(test=None), x, label) == (x, label)


def test_a_long_panel_title_is_wrapped_not_cut():
    """A single panel's title (the diagnosis in words) is wrapped to the panel, so its p-value is drawn whole
    (review30c: "... p = 0" for p = 0.0012 on screw_saw-312's one panel)."""
    from viz.figures import diagnosis_figure

    words = ("residuals follow the x position periodically (period 12.4 mm): 0.16 µm, p = 0.0012")
    fig = diagnosis_figure([{"x": np.arange(5.0), "residual_um": np.zeros(5), "fitted_um": np.zeros(5),
                             "xlabel": "x / mm", "text": words}])
    title = fig.axes[0].get_title()
    assert "\n" in title and title.replace("\n", " ") == words
    fig.canvas.draw()
    bb, fb = fig.axes[0].title.get_window_extent(), fig.bbox
    assert bb.x0 >= fb.x0 - 1 and bb.x1 <= fb.x1 + 1  # inside the figure: nothing cut
