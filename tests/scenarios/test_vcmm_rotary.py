"""vmt vcmm over features probed at rotary positions (review30d F1, session 30).

The features are fitted in the machine frame R. Two bores on the part at W (60, 0)
and W (0, 60), 84.853 mm apart (60 sqrt 2), probed at C = 0 and C = 90 on the
mikron-ucp710 both appear at R (60, 0): before the mend `vmt vcmm` reported their
distance as "nominal 0.000000 mm" and b2's x as 60 mm (the part's is 0). Such
measurands are now refused (exit 2, one line naming the measurand, the features and
their positions); the same two bores probed at one rotary position are measured
(the distance does not depend on the frame there).
"""
import numpy as np
import pytest

from core import vcmm as V
from core.probelog import make_log, write_probe_log
from scenarios.cli import main
from scenarios.vcmm import plan_from_rows

TASK = """format = "vmt-task/1"
[features.b1]
kind = "circle"
feature = "b1"
[features.b2]
kind = "circle"
feature = "b2"
[[measurands]]
name = "bore-bore distance"
quantity = "distance"
of = ["b1", "b2"]
[[measurands]]
name = "b1 diameter"
quantity = "diameter"
of = "b1"
[mc]
batch_runs = 20
max_runs = 20
"""
POSITION = """[[measurands]]
name = "b2 x"
quantity = "position"
of = "b2"
axis = "x"
"""


def _plan(tmp_path, c1, c2):
    """The reviewer's plan (/tmp/review30d/vc_rot.py): bores r 10 mm at z 60 on the part, 8 touches each,
    b1 probed at C = c1, b2 at C = c2 (nominal p_R = Rz(-C) p_W: the C line through R's origin)."""
    rows, cdeg = [], []
    for name, cW, C in (("b1", (60.0, 0.0), c1), ("b2", (0.0, 60.0), c2)):
        c, s = np.cos(np.deg2rad(-C)), np.sin(np.deg2rad(-C))
        Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        for k in range(8):
            a = np.deg2rad(22.5 + 45 * k)
            pW = np.array([cW[0] + 10 * np.cos(a), cW[1] + 10 * np.sin(a), 60.0])
            rows.append((name, f"{name}-{k}", Rz @ pW, Rz @ np.array([-np.cos(a), -np.sin(a), 0.0])))
            cdeg.append(C)
    plan = plan_from_rows(rows, 3.0, "two bores")
    cols = {k: plan.col(k) for k in plan.columns}
    cols["C_deg"], cols["A_deg"] = np.array(cdeg, float), np.zeros(len(cdeg))
    cols["setup"] = [f"C{c:g}" for c in cdeg]
    return write_probe_log(tmp_path / "plan.csv", make_log(cols, dict(plan.meta)))


def _run(tmp_path, capsys, c1, c2, extra=""):
    task = tmp_path / "task.toml"
    task.write_text(TASK + extra)
    plan = _plan(tmp_path, c1, c2)
    rc = main(["vcmm", "--machine", "mikron-ucp710", "--task", str(task), "--no-budget", "--seed", "1",
               "--json", str(tmp_path / "out.json"), "--plan", str(plan)])
    return rc, capsys.readouterr()


def test_a_distance_between_features_at_two_c_positions_is_refused(tmp_path, capsys):
    rc, out = _run(tmp_path, capsys, 0.0, 90.0)
    assert rc == 2
    lines = out.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in out.err
    assert ("measurand 'bore-bore distance': features 'b1' (rotary zero) and 'b2' (C=90) were probed at "
            "different rotary positions") in lines[0]
    assert "nominal 0.000000" not in out.out


def test_a_position_away_from_rotary_zero_is_refused(tmp_path, capsys):
    """b2 probed at C = 90 sits at R x = 60 mm; on the part its x is 0."""
    t = V.loads_task(TASK.split("[[measurands]]")[0] + POSITION)
    feature = np.array(["b1"] * 8 + ["b2"] * 8)
    target = np.array([f"t{i}" for i in range(16)])
    rot = np.zeros((16, 3))
    rot[8:, 2] = 90.0
    with pytest.raises(V.TaskFileError, match=r"measurand 'b2 x': feature 'b2' was probed at C=90; a position"):
        V.feature_rows(t, target, feature, np.array(["S"] * 16), rot)
    rot[:] = 0.0
    assert V.feature_rows(t, target, feature, np.array(["S"] * 16), rot)["b2"].tolist() == list(range(8, 16))


def test_a_line_angle_from_x_away_from_rotary_zero_is_refused():
    t = V.loads_task("""format = "vmt-task/1"
[features.e]
kind = "line"
feature = "e"
[[measurands]]
name = "edge angle"
quantity = "angle"
of = "e"
""")
    rot = np.zeros((4, 3))
    rot[:, 0] = -90.0
    with pytest.raises(V.TaskFileError, match=r"'edge angle': feature 'e' was probed at A=-90"):
        V.feature_rows(t, np.array(list("abcd")), np.array(["e"] * 4), np.array(["S"] * 4), rot)


def test_the_same_bores_probed_at_one_c_position_are_measured(tmp_path, capsys):
    """Both at C = 90: in R the part has turned as a whole, the distance is the part's, 60 sqrt 2 mm."""
    rc, out = _run(tmp_path, capsys, 90.0, 90.0)
    assert rc == 0, out.err
    line = next(s for s in out.out.splitlines() if s.strip().startswith("bore-bore distance"))
    assert f"nominal {60 * np.sqrt(2):.6f} mm" in line


def test_a_circle_on_a_tilted_table_is_refused(tmp_path, capsys):
    """Found beside F1: circles are fitted in R's XY plane. The same two bores probed at A = -30 (their
    axes 30 deg from R's Z) read 19.079043 mm in diameter and 79.372539 mm apart, exit 0; now refused."""
    from sim.machine import Machine
    from sim.machinefile import truth_machine

    T = Machine(truth_machine("mikron-ucp710", "none").config).T_R_W_nominal(np.deg2rad([[-30.0, 0.0]]))[0]
    rows = []
    for name, cW in (("b1", (60.0, 0.0)), ("b2", (0.0, 60.0))):
        for k in range(8):
            a = np.deg2rad(22.5 + 45 * k)
            pW = np.array([cW[0] + 10 * np.cos(a), cW[1] + 10 * np.sin(a), 60.0]) * 1e-3
            nW = np.array([-np.cos(a), -np.sin(a), 0.0])
            rows.append((name, f"{name}-{k}", (T[:3, :3] @ pW + T[:3, 3]) * 1e3, T[:3, :3] @ nW))
    plan = plan_from_rows(rows, 3.0, "two bores at A=-30")
    cols = {k: plan.col(k) for k in plan.columns}
    cols["A_deg"], cols["C_deg"] = np.full(16, -30.0), np.zeros(16)
    p = write_probe_log(tmp_path / "plan.csv", make_log(cols, dict(plan.meta)))
    task = tmp_path / "task.toml"
    task.write_text(TASK)
    rc = main(["vcmm", "--machine", "mikron-ucp710", "--task", str(task), "--no-budget",
               "--json", str(tmp_path / "out.json"), "--plan", str(p)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert "features.b1: a circle probed at A=-30 B=0 with normals 0.462 out of the machine's XY plane" in err[0]
    assert not (tmp_path / "out.json").exists()
