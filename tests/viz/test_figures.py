"""viz.figures: non-blank PNGs; every axis labelled with its ISO symbol and unit."""

import numpy as np
import pytest

from core.exceptions import ConfigError
from viz import figures as vf

TH = np.linspace(0.0, 2.0 * np.pi, 36, endpoint=False)
P = np.c_[50.0 * np.cos(TH), 50.0 * np.sin(TH)]
N = np.c_[np.cos(TH), np.sin(TH)]
X_MM = np.linspace(-100.0, 100.0, 5)
Y_MM = np.linspace(-110.0, 110.0, 4)
GX, GY = np.meshgrid(X_MM, Y_MM)
AXES = {"EXX": {"positions_mm": X_MM, "values_um": 0.1 * X_MM, "u95": 1.0},
        "ECY": {"positions_mm": Y_MM, "values_urad": 0.05 * Y_MM, "u95": np.full(4, 2.0)}}


def png_variance(fig, tmp_path, name):
    """Pixel variance of the saved PNG: a blank (one-colour) image has 0."""
    import matplotlib.image as mpimg

    path = vf.save_png(fig, tmp_path / f"{name}.png")
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100
    return float(img[..., :3].var())


def labels(fig):
    return [(ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes if ax.get_visible()]


# (name, builder, [(x-label fragments), (y-label fragments)] of the first axes)
CASES = [
    ("profile", lambda: vf.profile_figure(P, N, {"C = 0°": 3 * np.sin(3 * TH)},
                                          reference_um=np.sin(3 * TH)),
     (["x_W", "mm"], ["y_W", "mm"])),
    ("grid", lambda: vf.error_grid_figure(X_MM, Y_MM, 0.02 * GY, 0.01 * GX,
                                          true_ex_um=0.018 * GY, true_ey_um=0.011 * GX),
     (["X", "mm"], ["Y", "mm"])),
    ("grid_u95", lambda: vf.grid_uncertainty_figure(X_MM, Y_MM, np.abs(GY) / 10 + 1),
     (["X", "mm"], ["Y", "mm"])),
    ("motions", lambda: vf.error_motions_figure(AXES, truth={"EXX": 0.09 * X_MM}),
     (["X", "mm"], ["EXX(X)", "µm"])),
    ("errors", lambda: vf.errors_figure({"EXX": {"injected": 1, "identified": 1.2, "u95": 0.3},
                                         "EC0Y": {"injected": 10, "identified": 11, "u95": 2}}),
     (["error", "µm"], ["ISO 230-1"])),
    ("centre", lambda: vf.rotary_centre_figure([0, 75, 130, 210], [16, 14, 15, 13], [6, 7, 5, 6],
                                               centre_um=(15.0, 6.0)),
     (["EXC(C)", "µm"], ["EYC(C)", "µm"])),
    ("rotary", lambda: vf.rotary_motions_figure([0, 75, 130, 210], {"ECC": [0, 2, 1, 3]},
                                                {"ECC": [1, 1, 1, 1]}),
     (["C", "°"], ["ECC(C)", "µrad"])),
    ("workpiece", lambda: vf.workpiece_uncertainty_figure(P, np.abs(np.sin(TH)) + 1,
                                                          g_um=np.sin(3 * TH), normals=N),
     (["x_W", "mm"], ["y_W", "mm"])),
    ("residuals", lambda: vf.residuals_figure(np.arange(36.0), np.degrees(TH), np.cos(TH),
                                              outlier_rows=[3]),
     (["t", "s"], ["residual", "µm"])),
    ("findings", lambda: vf.findings_figure(
        {"baseline": {"model": "rigid", "rms_um": 2.0}, "cause": "thermal_drift",
         "findings": [{"cause": "thermal_drift", "rms_um": 1.0}]}),
     (["RMS", "µm"], ["cause"])),
]


@pytest.mark.parametrize("name,build,want", CASES, ids=[c[0] for c in CASES])
def test_figure_is_labelled_and_not_blank(tmp_path, name, build, want):
    fig = build()
    xl, yl = labels(fig)[0]
    for frag in want[0]:
        assert frag in xl, (name, xl)
    for frag in want[1]:
        assert frag in yl, (name, yl)
    # a blank figure has variance 0; any drawn content gives > 1e-3 on [0, 1] pixels
    assert png_variance(fig, tmp_path, name) > 1e-3
    assert not list(tmp_path.glob(".*"))  # no temp file left behind


def test_every_error_motion_panel_names_its_symbol_and_unit():
    fig = vf.error_motions_figure(AXES)
    got = labels(fig)
    assert got == [("X / mm", "EXX(X) / µm"), ("Y / mm", "ECY(Y) / µrad")]


def test_rotary_panels_and_residual_axes():
    fig = vf.rotary_motions_figure([0, 90], {"EXC": [1, 2], "ECC": [3, 4]})
    assert [ax.get_ylabel() for ax in fig.axes] == ["EXC(C) / µm", "ECC(C) / µrad"]
    fig = vf.residuals_figure([0, 1], [0, 90], [0.1, -0.1])
    assert fig.axes[1].get_xlabel() == "approach angle θ / °"


def test_iso_label():
    assert vf.iso_label("EXX") == "EXX(X) / µm"
    assert vf.iso_label("EC0Y") == "EC0Y / µrad"
    assert vf.iso_label("EC(0X)Y") == "EC0Y / µrad"


def test_profile_magnification_is_drawn(tmp_path):
    # one point at (50, 0), normal +x, dq = 2 µm: drawn at 50 + 2500 * 2e-3 = 55 mm
    fig = vf.profile_figure([[50.0, 0.0]], [[1.0, 0.0]], {"p": [2.0]})
    line = [ln for ln in fig.axes[0].lines if ln.get_label() == "p"][0]
    assert np.allclose(line.get_xydata(), [[55.0, 0.0]])
    assert "×2500" in fig.axes[0].get_title()


@pytest.mark.parametrize("call,match", [
    (lambda: vf.error_grid_figure(X_MM, Y_MM, GX, GY.T), r"ey_um: expected shape \(4, 5\)"),
    (lambda: vf.error_grid_figure(X_MM, Y_MM, GX, GY, true_ex_um=GX), "give both or neither"),
    (lambda: vf.profile_figure(P, N[:3], {"a": TH}), "length mismatch"),
    (lambda: vf.profile_figure(P, N, {}), "at least one profile"),
    (lambda: vf.error_motions_figure({"EQX": {"positions_mm": [0], "values_um": [0]}}),
     "unknown ISO error symbol"),
    (lambda: vf.error_motions_figure(AXES, symbols=["EYX"]), "'EYX' is not in axes"),
    (lambda: vf.residuals_figure([0, 1], [0, 1], [0, np.nan]), "residual_um: contains NaN"),
    (lambda: vf.residuals_figure([0, 1], [0, 1], [0, 1], outlier_rows=[2]), "out of range"),
    (lambda: vf.findings_figure({"findings": []}), "needs baseline.rms_um"),
    (lambda: vf.errors_figure({"EXX": {"injected": 1.0}}), "needs 'identified'"),
])
def test_bad_input(call, match):
    with pytest.raises(ConfigError, match=match):
        call()


def test_save_png_missing_folder(tmp_path):
    with pytest.raises(ConfigError, match="folder does not exist"):
        vf.save_png(vf.findings_figure({"baseline": {"rms_um": 1.0}}), tmp_path / "no" / "f.png")


@pytest.mark.parametrize("build", [
    lambda: vf.rotary_centre_figure([0, 75, 130, 210], [16, 14, 15, 13], [6, 7, 5, 6], centre_um=(15.0, 6.0)),
    lambda: vf.grid_uncertainty_figure(X_MM, Y_MM, np.abs(GY) / 10 + 1),  # a colorbar
    lambda: vf.error_motions_figure(AXES, truth={"EXX": 0.09 * X_MM}),  # panels, a hidden one
], ids=["centre", "colorbar", "panels"])
def test_written_png_is_what_savefig_writes(build):
    # write_png draws once where savefig draws twice; matplotlib's own savefig is the reference:
    # the same bytes, the first save and the second, and the figure keeps its dpi and its engine
    import io

    fig_a, fig_b = build(), build()
    for _ in range(2):
        a, b = io.BytesIO(), io.BytesIO()
        fig_a.savefig(a, dpi=110, format="png")
        vf.write_png(fig_b, b, dpi=110)
        assert a.getvalue() == b.getvalue()
    assert fig_b.dpi == 100 and type(fig_b.get_layout_engine()).__name__ == "ConstrainedLayoutEngine"


def test_written_png_of_a_figure_without_agg_canvas_goes_through_savefig(tmp_path):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(2, 2), layout="constrained")  # its canvas is FigureCanvasBase
    fig.add_subplot().plot([0, 1], [1, 0])
    vf.write_png(fig, tmp_path / "f.png", dpi=50)
    assert (tmp_path / "f.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
