"""The self-calibration paper's extra figures: points on the outline (Fig. 18), pins (Fig. 17), bad input."""

import numpy as np
import pytest

from core.exceptions import ConfigError
from viz import selfcal_figures as S


def _dist_to_polygon(p, poly):
    q = np.vstack([poly, poly[:1]])
    best = np.full(len(p), np.inf)
    for a, b in zip(q[:-1], q[1:]):
        t = np.clip(((p - a) @ (b - a)) / ((b - a) @ (b - a)), 0, 1)
        best = np.minimum(best, np.hypot(*(p - (a + t[:, None] * (b - a))).T))
    return best


def test_fig18_points_lie_on_the_outline():
    """The demo report's Fig. 18 map: every coloured point on the part's outline (it was nominal + 2500 x G)."""
    from scenarios.crosspocket import part_outline_mm
    from scenarios.reports import _u95_outline_figure
    from sim import artefacts as A
    from sim.catalog import make_plan

    art = A.cross_pocket()
    plan = make_plan(art)
    w_mm = plan.w_A[:, :2] * 1e3
    # a G of 30 um (a stylus/offset datum) would have moved points 75 mm off at x2500
    v = type("V", (), {"w_mm": w_mm, "u95_um": np.linspace(1, 6, len(w_mm)), "g_um": np.full(len(w_mm), 30.0),
                       "wn": plan.wn_A[:, :2]})()
    fig = _u95_outline_figure(v, art)
    pts = fig.axes[0].collections[0].get_offsets()
    polys, circles = part_outline_mm(art)
    d = _dist_to_polygon(np.asarray(pts), polys[0])
    for x, y, r in circles:
        d = np.minimum(d, np.abs(np.hypot(pts[:, 0] - x, pts[:, 1] - y) - r))
    assert len(pts) == len(w_mm) and d.max() < 1e-9  # mm


def test_outline_figure_nan_and_bad_input():
    p = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    fig = S.outline_uncertainty_figure(p, [1.0, np.nan, 2.0], outlines_mm=[p])
    assert len(fig.axes[0].collections[0].get_offsets()) == 2
    with pytest.raises(ConfigError, match="length mismatch"):
        S.outline_uncertainty_figure(p, [1.0, 2.0])
    with pytest.raises(ConfigError, match="radius must be > 0"):
        S.outline_uncertainty_figure(p, [1.0, 2.0, 3.0], circles_mm=[(0, 0, 0)])


def test_pin_figure_draws_magnified_errors_and_rejects_bad_input():
    a = np.deg2rad(20 * np.arange(18))
    p = 200 * np.column_stack([np.cos(a), np.sin(a)])
    e = np.zeros((18, 2))
    e[3] = (4.0, 0.0)
    fig = S.pin_positions_figure(p, e, e / 2)
    line = fig.axes[0].lines[1]  # raw, closed loop
    np.testing.assert_allclose(line.get_xydata()[3], p[3] + 2.5 * e[3])  # x2500: 4 um -> 10 mm
    with pytest.raises(ConfigError, match="length mismatch"):
        S.pin_positions_figure(p, e[:5], e)
    with pytest.raises(ConfigError, match="magnification"):
        S.pin_positions_figure(p, e, e, magnification=0)


def test_log_figures_puts_the_png_itself_in_the_recording(tmp_path):
    """The bytes read back with rerun's own reader are the PNG the figure renders to."""
    rc = pytest.importorskip("rerun.chunk")
    from viz import record
    from viz.selfcal_figures import figure_png_bytes, log_figures, pin_positions_figure

    nominal = [[200.0, 0.0], [0.0, 200.0], [-200.0, 0.0]]
    fig = pin_positions_figure(nominal, [[0, 0], [1, 2], [-1, 0.5]], [[0, 0], [0.2, 0.1], [0.1, 0]])
    rrd = tmp_path / "r.rrd"
    with record.recording(rrd) as rec:
        log_figures(rec, {"fig17": fig})
    got = {}
    for ch in rc.RrdReader(rrd).stream():
        rb = ch.to_record_batch()
        if "EncodedImage:blob" in rb.schema.names:
            got[str(ch.entity_path)] = bytes(rb.column(rb.schema.names.index("EncodedImage:blob")).to_pylist()[0][0])
    assert list(got) == ["/reports/figures/fig17"]
    assert got["/reports/figures/fig17"] == figure_png_bytes(fig)
