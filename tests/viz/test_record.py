"""viz.record: recordings read back with rerun 0.41's own reader (rerun.chunk.RrdReader)."""

from collections import defaultdict

import numpy as np
import pyarrow as pa
import pytest

from core.exceptions import ConfigError, VmtError
from viz import record as vr

rc = pytest.importorskip("rerun.chunk")


def read(path):
    """{entity_path: {column name: list of values}} of every chunk in the file."""
    out = defaultdict(lambda: defaultdict(list))
    for ch in rc.RrdReader(path).stream():
        rb = ch.to_record_batch()
        for i, name in enumerate(rb.schema.names):
            col = rb.column(i)
            if pa.types.is_temporal(col.type):  # ns times: read as integers
                col = col.cast(pa.int64())
            out[str(ch.entity_path)][name] += col.to_pylist()
    return out


def schema_paths(path):
    return set(rc.RrdReader(path).store().schema().entity_paths())


def scalars(data, entity):
    return np.array([v[0] for v in data[entity]["Scalars:scalars"]])


@pytest.fixture
def grid():
    x = np.linspace(-100.0, 100.0, 5)
    y = np.linspace(-50.0, 50.0, 3)
    X, Y = np.meshgrid(x, y)
    return x, y, 0.01 * X, -0.02 * Y  # Ex, Ey in µm


def test_world_is_z_up_once_static_at_root(tmp_path):
    p = tmp_path / "run.rrd"
    with vr.recording(p):
        pass
    assert p.exists() and not list(tmp_path.glob(".*tmp"))
    data = read(p)
    st = rc.RrdReader(p).store()
    assert "/ rows=1 static=True" in st.summary()
    assert len(data["/"]["ViewCoordinates:xyz"]) == 1
    import rerun as rr
    # RIGHT_HAND_Z_UP is X=Right, Y=Forward, Z=Up: the same three codes
    assert data["/"]["ViewCoordinates:xyz"][0][0] == [d.value for d in
                                                          rr.ViewCoordinates.RIGHT_HAND_Z_UP.coordinates]


def test_failure_inside_leaves_no_file(tmp_path):
    p = tmp_path / "run.rrd"
    with pytest.raises(RuntimeError):
        with vr.recording(p):
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_missing_folder_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="folder does not exist"):
        with vr.recording(tmp_path / "no" / "run.rrd"):
            pass


def test_scene_paths_mirror_the_frame_tree(tmp_path, rng):
    p = tmp_path / "scene.rrd"
    T = np.eye(4)
    T[:3, 3] = [0.1, 0.0, 0.0]
    with vr.recording(p) as rec:
        vr.log_placement(rec, vr.TABLE, np.eye(4), time_s=0.0)
        vr.log_placement(rec, vr.W, T)
        vr.log_mesh(rec, vr.ARTEFACT, rng.random((4, 3)), [[0, 1, 2], [0, 2, 3]])
        vr.log_mesh(rec, vr.PROBE, rng.random((3, 3)), [[0, 1, 2]], T_parent_child=np.eye(4))
        vr.log_probe_path(rec, rng.random((20, 3)))
        dq = np.array([-3.0, 0.0, 3.0, 1.0])
        vr.log_touches(rec, rng.random((4, 3)), dq, n_R=np.tile([0.0, 0.0, 1.0], (4, 1)))
    paths = schema_paths(p)
    for e in ["/world/R/table", "/world/R/table/W", "/world/R/table/W/artefact",
              "/world/R/spindle/probe", "/world/R/probe_path", "/world/R/touches"]:
        assert e in paths, e
    data = read(p)
    assert np.allclose(data["/world/R/table/W"]["Transform3D:translation"][0], [0.1, 0, 0])
    # touches: symmetric diverging map, -max -> blue end, 0 -> near white, +max -> red end
    cols = np.array(data["/world/R/touches"]["Points3D:colors"][0], dtype=np.uint32)
    rgb = np.stack([(cols >> 24) & 255, (cols >> 16) & 255, (cols >> 8) & 255], axis=1)
    assert rgb[0, 2] > rgb[0, 0] and rgb[2, 0] > rgb[2, 2]  # blue for -3, red for +3
    assert np.all(rgb[1] > 230)  # white for 0 (RdBu midpoint is (247, 247, 247))


def test_setups_on_their_timeline(tmp_path, rng):
    """A campaign's set-ups (review30d F2): the table's placement and that set-up's touches at each
    step of timeline ``setup``, one colour scale; nothing logged after them carries that timeline."""
    p = tmp_path / "setups.rrd"
    c = np.deg2rad([0.0, 75.0])
    with vr.recording(p) as rec:
        for k, ck in enumerate(c):
            T = np.eye(4)
            T[:2, :2] = [[np.cos(ck), np.sin(ck)], [-np.sin(ck), np.cos(ck)]]
            vr.log_placement(rec, vr.TABLE, T, setup=k)
            vr.log_touches(rec, rng.random((3 + k, 3)), np.array([1.0, -2.0, 0.5, 0.0][:3 + k]),
                           limit_um=2.0, n_R=np.tile([1.0, 0.0, 0.0], (3 + k, 1)), setup=k)
        vr.log_placement(rec, vr.W, np.eye(4), time_s=1.0)
    data = read(p)
    assert data["/world/R/table"]["setup"] == [0, 1]
    assert data["/world/R/touches"]["setup"] == [0, 1]
    assert [len(x) for x in data["/world/R/touches"]["Points3D:positions"]] == [3, 4]
    assert data["/world/R/touches/normals"]["setup"] == [0, 1]
    M = np.asarray(data["/world/R/table"]["Transform3D:mat3x3"][1][0]).reshape(3, 3).T   # column-major
    assert np.allclose(M[:2, :2], [[np.cos(c[1]), np.sin(c[1])], [-np.sin(c[1]), np.cos(c[1])]], atol=1e-7)
    assert "setup" not in data["/world/R/table/W"]                   # the time is reset after a set-up
    with vr.recording(tmp_path / "bad.rrd") as rec:
        for bad in (-1, 1.5):
            with pytest.raises(ConfigError, match="setup: expected a set-up index"):
                vr.log_placement(rec, vr.TABLE, np.eye(4), setup=bad)


def test_diverging_colors_are_symmetric():
    c = vr.diverging_colors([-2.0, 2.0, 0.0], limit=2.0)
    assert c.dtype == np.uint8 and c.shape == (3, 3)
    assert np.array_equal(c[0], vr.diverging_colors([-5.0], limit=5.0)[0])
    assert not np.array_equal(c[0], c[1])


def test_error_grid_is_magnified_beside_the_truth(tmp_path, grid):
    x, y, ex, ey = grid
    p = tmp_path / "grid.rrd"
    with vr.recording(p) as rec:
        vr.log_error_grid(rec, x, y, ex, ey, true_ex_um=ex * 0.9, true_ey_um=ey * 0.9,
                          u95_um=np.ones_like(ex))
    paths = schema_paths(p)
    for sub in ("nominal", "identified", "true", "identified/u95"):
        assert f"/world/R/error_map/{sub}" in paths
    data = read(p)
    strips = data["/world/R/error_map/identified"]["LineStrips3D:strips"][0]
    first_row = np.array(strips[0])  # y = -50 mm row, nodes along x
    # node (x=100 mm, y=-50 mm): Ex = 1 µm drawn x1000 -> +1 mm; Ey = 1 µm -> +1 mm
    assert np.allclose(first_row[-1], [0.100 + 0.001, -0.050 + 0.001, 0.0])
    assert len(strips) == 3 + 5  # rows + columns


def test_error_grid_bad_shape(grid):
    x, y, ex, ey = grid
    with pytest.raises(ConfigError, match=r"ey_um: expected shape \(3, 5\)"):
        with_rec(lambda rec: vr.log_error_grid(rec, x, y, ex, ey.T))
    with pytest.raises(ConfigError, match="give both or neither"):
        with_rec(lambda rec: vr.log_error_grid(rec, x, y, ex, ey, true_ex_um=ex))


def with_rec(fn):
    import rerun as rr
    rec = rr.RecordingStream("vmt_test")  # no sink: nothing is written anywhere
    try:
        fn(rec)
    finally:
        rec.disconnect()


def test_error_motions_as_series_with_u95_band(tmp_path):
    pos = np.array([-100.0, 0.0, 100.0])
    axes = {"EXX": {"positions_mm": pos, "values_um": [1.0, 2.0, 3.0], "u95": [0.5, 0.5, 0.5]},
            "ECY": {"positions_mm": pos, "values_urad": [4.0, 5.0, 6.0], "u95": 1.0}}
    p = tmp_path / "em.rrd"
    with vr.recording(p) as rec:
        vr.log_error_motions(rec, axes, truth={"EXX": [1.1, 2.1, 3.1]})
    data = read(p)
    base = "/plots/error_motions/X/EXX"
    assert np.allclose(scalars(data, f"{base}/value"), [1, 2, 3])
    assert np.allclose(scalars(data, f"{base}/u95_upper"), [1.5, 2.5, 3.5])
    assert np.allclose(scalars(data, f"{base}/u95_lower"), [0.5, 1.5, 2.5])
    assert np.allclose(scalars(data, f"{base}/true"), [1.1, 2.1, 3.1])
    assert data[f"{base}/value"]["X_um"] == [-100000, 0, 100000]
    assert np.allclose(scalars(data, "/plots/error_motions/Y/ECY/u95_upper"), [5, 6, 7])
    assert data["/plots/error_motions/Y/ECY/value"]["SeriesLines:names"][0] == ["ECY(Y) / µrad"]


def test_error_motions_bad_input():
    with pytest.raises(ConfigError, match="unknown ISO error symbol 'EQX'"):
        with_rec(lambda rec: vr.log_error_motions(
            rec, {"EQX": {"positions_mm": [0], "values_um": [0]}}))
    with pytest.raises(ConfigError, match="needs 'values_um' or 'values_urad'"):
        with_rec(lambda rec: vr.log_error_motions(rec, {"EXX": {"positions_mm": [0]}}))
    with pytest.raises(ConfigError, match="length mismatch"):
        with_rec(lambda rec: vr.log_error_motions(
            rec, {"EXX": {"positions_mm": [0, 1], "values_um": [0]}}))


def test_rotary_centre_trajectory_and_workpiece(tmp_path, rng):
    p = tmp_path / "rot.rrd"
    c = [0.0, 75.0, 130.0, 210.0]
    with vr.recording(p) as rec:
        vr.log_rotary(rec, c, [16, 14, 15, 13], [6, 7, 5, 6], ecc_urad=[0, 2, 1, 3],
                      u95_exc_um=[1, 1, 1, 1], centre_um=(15.0, 6.0), chain="V[w-C-A-b-Y-X-Z-(C)-t]")
        n = 12
        vr.log_workpiece(rec, rng.random((n, 3)), np.tile([1.0, 0, 0], (n, 1)),
                         rng.normal(size=n), u95_um=rng.random(n))
        vr.log_workpiece(rec, rng.random((2, 3)), np.tile([1.0, 0, 0], (2, 1)), np.array([1.06, -1.1]),
                         label="form", path=f"{vr.WORKPIECE}/form")
    data = read(p)
    assert data["/world/R/table/W/workpiece/deviation"]["Points3D:labels"][0][0].startswith("G = ")
    assert data["/world/R/table/W/workpiece/form/deviation"]["Points3D:labels"][0] == [
        "form = +1.06 µm", "form = -1.10 µm"]
    traj = np.array(data["/rotary/C/centre_trajectory"]["Points2D:positions"][0])
    assert np.allclose(traj, [[16, 6], [14, 7], [15, 5], [13, 6]])
    assert data["/rotary/C/centre_trajectory/centre"]["Points2D:positions"][0] == [[15.0, 6.0]]
    lab = data["/rotary/C/centre_trajectory/centre"]["Points2D:labels"][0][0]   # the label names C's carrier
    assert "C carried by A: its line (-15.0, -6.0) µm = (EX0C, EY0C) + what A adds" in lab and "\n" not in lab
    assert data["/plots/rotary/C/ECC/value"]["C_mdeg"] == [0, 75000, 130000, 210000]
    paths = schema_paths(p)
    for e in ("nominal", "deviation", "u95"):
        assert f"/world/R/table/W/workpiece/{e}" in paths
    assert "/plots/rotary/C/EXC/u95_upper" in paths


def test_residuals_against_time_and_angle(tmp_path, rng):
    p = tmp_path / "res.rrd"
    n = 30
    t = np.linspace(0.0, 600.0, n)
    a = rng.uniform(0.0, 360.0, n)
    r = rng.normal(size=n)
    with vr.recording(p) as rec:
        vr.log_residuals(rec, t, a, r, outlier_rows=[4, 7])
        vr.log_markdown(rec, "findings", vr.findings_markdown(
            {"baseline": {"model": "rigid", "n": n, "rms_um": 1.2}, "cause": "outlier",
             "findings": [{"cause": "outlier", "evidence": {"max_abs_um": 9.0},
                           "params": {}, "rms_um": 0.8}]}))
        vr.log_markdown(rec, "errors", vr.errors_markdown(
            {"EXX": {"injected": 1.0, "identified": 1.1, "u95": 0.2}}))
    data = read(p)
    assert len(scalars(data, "/discover/residuals/vs_time")) == n
    assert np.allclose(sorted(scalars(data, "/discover/residuals/vs_approach")), sorted(r))
    assert np.allclose(scalars(data, "/discover/residuals/outliers_vs_time"), r[[4, 7]])
    assert "outlier" in data["/reports/findings"]["TextDocument:text"][0][0]
    assert "| EXX | µm |" in data["/reports/errors"]["TextDocument:text"][0][0]
    with pytest.raises(VmtError, match="outlier_rows: index out of range"):
        with_rec(lambda rec: vr.log_residuals(rec, t, a, r, outlier_rows=[n]))


def test_bad_mesh_faces():
    with pytest.raises(ConfigError, match="faces: vertex index out of range"):
        with_rec(lambda rec: vr.log_mesh(rec, vr.ARTEFACT, np.eye(3), [[0, 1, 3]]))
    with pytest.raises(ConfigError, match="vertices_m: expected shape"):
        with_rec(lambda rec: vr.log_mesh(rec, vr.ARTEFACT, np.eye(2), [[0, 1, 1]]))


def test_positioning_residuals_per_direction_against_time_and_target(tmp_path, rng):
    """An ISO 230-2 test's residuals (session 36: its recording held only the findings' text): each approach
    direction apart, against time and the target (integer µm), the outliers again; without a clock against the
    reading order, a sequence (no time made up)."""
    n = 20
    t = np.arange(n) * 6.0
    target = np.tile([0.0, 100.0, 200.0, 300.5, 400.0], 4)
    d = np.repeat([1, -1, 1, -1], 5)
    r = rng.normal(size=n)
    p = tmp_path / "pos.rrd"
    with vr.recording(p) as rec:
        vr.log_positioning_residuals(rec, t, target, d, r, outlier_rows=[3])
    data = read(p)
    up = np.flatnonzero((d > 0) & (np.arange(n) != 3))
    assert np.allclose(scalars(data, "/discover/residuals/vs_time_plus"), r[up])
    assert np.allclose(sorted(scalars(data, "/discover/residuals/vs_target_minus")), sorted(r[d < 0]))
    assert sorted(data["/discover/residuals/vs_target_minus"]["target_um"]) == sorted((target[d < 0] * 1000).astype(int))
    assert np.allclose(scalars(data, "/discover/residuals/outliers_vs_target"), r[[3]])
    assert data["/discover/residuals/vs_time_plus"]["campaign_time"] == [int(v * 1e9) for v in t[up]]
    q = tmp_path / "order.rrd"
    with vr.recording(q) as rec:
        vr.log_positioning_residuals(rec, np.arange(n, dtype=float), target, d, r, clock=False, target_unit="deg")
    data = read(q)
    assert data["/discover/residuals/vs_time_minus"]["reading"] == list(np.flatnonzero(d < 0))
    assert "campaign_time" not in data["/discover/residuals/vs_time_minus"]
    assert "target_mdeg" in data["/discover/residuals/vs_target_plus"]
    for kw, match in [({"direction": np.zeros(n)}, "direction"), ({"outlier_rows": [n]}, "out of range"),
                      ({"target_unit": "in"}, "target_unit"), ({"t": t + 0.5, "clock": False}, "whole numbers")]:
        args = {"t": t, "target": target, "direction": d, "residual": r, **kw}
        with pytest.raises(VmtError, match=match):
            with_rec(lambda rec: vr.log_positioning_residuals(rec, args.pop("t"), args.pop("target"),
                                                              args.pop("direction"), args.pop("residual"), **args))
