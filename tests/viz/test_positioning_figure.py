"""viz.figures.positioning_figure: the ISO 230-2 plot draws what the report holds."""

import numpy as np
import pytest

from core.exceptions import ConfigError
from core.positioning import iso230_2, make_positioning_log
from viz import figures as vf


def _report_and_readings():
    rng = np.random.default_rng(5)
    P = np.array([0.0, 52.0, 98.5, 151.0, 200.0])
    T, C, D, M = [], [], [], []
    for j in range(1, 6):
        for d in (1, -1):
            for p in (P if d > 0 else P[::-1]):
                T.append(p), C.append(j), D.append(d)
                M.append(p + 1e-5 * p + d * 1.5e-3 + rng.normal(0, 5e-4))
    log = make_positioning_log(T, C, D, M, meta={"axis": "X", "cycle_kind": "linear"})
    rep = iso230_2(log).to_report()
    return rep, {"target": log.target, "deviation": log.deviation * 1e3, "direction": log.direction}


def test_positioning_figure_draws_the_report(tmp_path):
    import matplotlib.image as mpimg

    rep, rd = _report_and_readings()
    fig = vf.positioning_figure(rep, readings=rd)
    img = mpimg.imread(vf.save_png(fig, tmp_path / "iso230_2.png"))
    assert img.shape[0] > 300 and float(img[..., :3].var()) > 1e-3
    main, rev = fig.axes[0], fig.axes[1]
    assert main.get_ylabel() == "positional deviation x / µm"
    assert rev.get_xlabel() == "X / mm" and rev.get_ylabel() == "B_i / µm"
    # the mean up line is the report's numbers, not recomputed
    up = [l for l in main.get_lines() if l.get_label().startswith("x̄↑ (approach")][0]
    np.testing.assert_allclose(up.get_ydata(), [r["mean_up_um"] for r in rep["per_target"]])
    # the table holds the axis figures as the report has them
    texts = [c.get_text().get_text() for c in fig.axes[2].tables[0].get_celld().values()]
    assert f"{rep['E_um']:.3f}" in texts and f"{rep['R_um']:.3f}" in texts
    assert "5 targets, 5 cycles, linear cycle" in fig._suptitle.get_text()


@pytest.mark.parametrize("mutate,match", [
    (lambda r: r.update(unit="mm"), "unit 'mm' is not"),
    (lambda r: r.update(per_target=[]), "needs per_target"),
    (lambda r: r["per_target"][0].pop("upper_up_um"), "per_target has no 'upper_up_um'"),
    (lambda r: r.pop("A_um"), "needs A_um"),
    (lambda r: r["per_target"][1].update(mean_um=float("nan")), "NaN"),
])
def test_positioning_figure_bad_report(mutate, match):
    rep, _ = _report_and_readings()
    mutate(rep)
    with pytest.raises(ConfigError, match=match):
        vf.positioning_figure(rep)


@pytest.mark.parametrize("axis, unit, label", [("X1", "deg", "X1 / °"), ("C", "deg", "C / °"),
                                               ("", "deg", "target P / °"), ("spindle", "mm", "spindle / mm")])
def test_positioning_figure_x_label_follows_the_unit(axis, unit, label):
    """review30 F6: the reversal plot's x label came from the axis letter ('X / mm' whatever the unit); a log in
    degrees of an axis named otherwise than A B C (refused for X Y Z U V W since) said mm."""
    P = np.array([0.0, 90.0, 180.0, 270.0, 360.0])
    T, C, D, M = [], [], [], []
    for j in range(1, 6):
        for d in (1, -1):
            for p in (P if d > 0 else P[::-1]):
                T.append(p), C.append(j), D.append(d), M.append(p + d * 1e-4 + 1e-5 * j)
    log = make_positioning_log(T, C, D, M, meta={"axis": axis}, unit=unit)
    fig = vf.positioning_figure(iso230_2(log).to_report())
    assert fig.axes[1].get_xlabel() == label
