"""MFB figures: all 21 errors drawn (18 curves with U95 bars, 3 squarenesses), the bar's calibration; bad input refused."""

import numpy as np
import pytest

from core import iso
from core.exceptions import ConfigError
from viz import mfb_figures as M


def _errors():
    out = {}
    x = np.linspace(-175.0, 275.0, 9)
    for k, s in enumerate(iso.LINEAR_MOTION):
        v = np.sin(x / 100.0 + k)
        out[s] = {"nodes_mm": x.tolist(), "identified": v.tolist(), "injected": (v + 0.1).tolist(),
                  "u95": np.full(9, 0.3).tolist()}
    for s in iso.SQUARENESS:
        out[s] = {"identified": [2.0], "injected": [2.5], "u95": [1.0]}
    return out


def test_every_error_has_its_panel_with_bars_and_the_injected_curve(tmp_path):
    fig = M.error_curves_figure(_errors())
    axs = [a for a in fig.axes if a.get_visible()]
    assert len(axs) == 18
    # columns are the axes X, Y, Z; rows EX., EY., EZ., EA., EB., EC.
    assert [a.get_title() for a in axs[:3]] == ["EXX", "EXY", "EXZ"]
    assert axs[-1].get_title() == "ECZ"
    for a in axs:
        assert a.collections and len(a.lines) >= 2  # U95 band/bars, identified and injected
    paths = M.write_mfb_figures({"scenario": "mfb-5axis", "errors": _errors()}, tmp_path,
                                bar={"x_mm": np.arange(12) * 50.0, "E_um": np.zeros((12, 3)),
                                     "U95_um": np.full((12, 3), 0.4)})
    assert [p.name for p in paths] == ["mfb-5axis-error-curves.png", "mfb-5axis-squareness.png",
                                       "mfb-5axis-bar-calibration.png"]
    assert all(p.stat().st_size > 10_000 for p in paths)


def test_bad_input_is_refused_by_name():
    e = _errors()
    del e["EBY"]
    with pytest.raises(ConfigError, match="EBY"):
        M.error_curves_figure(e)
    with pytest.raises(ConfigError, match="E_um"):
        M.bar_calibration_figure(np.arange(12.0), np.zeros((11, 3)))


def test_recording_holds_the_squareness_and_bar_calibration_plots(tmp_path):
    """The figures themselves in the recording (read back with rerun's own reader): the three
    squarenesses as points with ±U95 and the injected ones; the bar's calibrated Exx, Eyx, Ezx
    ±U95 and its true deviations, on x_MFB in µm."""
    from viz import record as vr

    rc = pytest.importorskip("rerun.chunk")
    from tests.viz.test_record import read, scalars

    x = np.arange(12) * 50.0
    E = np.column_stack([-x / 10.0, np.sin(x / 100.0), np.cos(x / 100.0)])
    p = tmp_path / "r.rrd"
    with vr.recording(p) as rec:
        M.log_squareness(rec, _errors())
        M.log_bar_calibration(rec, x, E, np.full((12, 3), 0.4), truth_um=E + 0.05)
    assert rc is not None
    d = read(p)
    assert np.allclose(scalars(d, "/mfb/squareness/identified"), [2.0] * 3)
    assert np.allclose(scalars(d, "/mfb/squareness/injected"), [2.5] * 3)
    assert np.allclose(scalars(d, "/mfb/squareness/u95_upper"), [3.0] * 3)
    assert np.allclose(scalars(d, "/mfb/bar_calibration/Eyx/calibrated"), E[:, 1])
    assert np.allclose(scalars(d, "/mfb/bar_calibration/Exx/u95_lower"), E[:, 0] - 0.4)
    assert np.allclose(scalars(d, "/mfb/bar_calibration/Ezx/true"), E[:, 2] + 0.05)
    with pytest.raises(ConfigError, match="E_um"):
        with vr.recording(tmp_path / "bad.rrd") as rec:
            M.log_bar_calibration(rec, x, E[:11])
