"""Real LinuxCNC in the loop (``make test-controllers``; not part of ``make test``).

LinuxCNC 2.9 (Debian's linuxcnc-uspace) runs headless with the config in
hardware/linuxcnc_sim/: the display program homes and runs the part program
written by ``vmt machine program`` in AUTO; the probe input is tripped in
the servo thread at the point where vmt's virtual machine (SimpleScene: a
table at Z = 0 and a 12.5 mm sphere at (50, 50, 0), tip-centre space, with
known scale and squareness errors) meets the part. The probe file is
imported with ``vmt import linuxcnc`` and fitted with ``vmt fit``.

Resolution (stated, and asserted): LinuxCNC latches the first servo sample
past the trigger, so every touch lies on its probing line between the true
trigger and one servo period of travel beyond it:
``0 <= e <= F * T = 30 mm/min * 1 ms = 0.5 um``; the file has 6 decimals
(0.5 nm per axis), and so has the program's path (vmt machine program), hence
the 1 nm slack on each below.

Never skipped: without LinuxCNC every test fails (tests/controllers/conftest.py; the make target installs it).
"""

import json
import os

import numpy as np
import pytest

from core.probelog import make_log, read_probe_log, write_probe_log
from hardware.backend import VirtualBackend
from hardware.campaign import ProbeSettings, run_campaign
from hardware.linuxcnc_sim.loop import linuxcnc_path, resolution_mm, run_program
from hardware.scene import SimpleScene
from scenarios.cli import main

FEED = 30.0                    # probing feed, mm/min
RES_MM = resolution_mm(FEED)   # 0.5 um
ROUND_MM = 1e-6                # the probe file's 6 decimals (+ margin)
LIMITS = "X-20:200,Y-20:200,Z-50:100"
LIMITS_MM = ((-20, 200), (-20, 200), (-50, 100))
SCALE = (40e-6, -25e-6, 10e-6)
EC0Y = 30e-6
COMMON = ["--limits-mm", LIMITS, "--feed-mm-min", str(FEED), "--move-feed-mm-min", "2000", "--clearance-mm", "1",
          "--overtravel-mm", "1", "--safe-z-mm", "20"]
#: the user's frames before the run: G54 selected, G59.3 shifted and rotated 30 deg, G92 on
USER_PARAMS = {5220: 1, 5221: 1.0, 5222: 2.0, 5223: 0.5, 5381: 5.0, 5382: -3.0, 5383: 2.0, 5390: 30.0,
               5210: 1, 5211: 0.5, 5212: 0.25, 5213: 0.1}


def scene():
    return SimpleScene(scale=SCALE, ec0y_rad=EC0Y)


def plan(miss_row=None):
    """12 table touches on a 4 x 3 grid (clear of the sphere), then 12 on the sphere."""
    rows = []
    for j, y in enumerate((10.0, 50.0, 90.0)):
        for i, x in enumerate((100.0, 120.0, 140.0, 160.0)):
            rows.append(("table", f"r{j}c{i}", (x, y, 0.0), (0, 0, 1.0)))
    for k in range(12):
        el, az = np.radians(20 + 25 * (k % 3)), np.radians(30 * k)
        n = (np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el))
        rows.append(("sphere", f"s{k}", tuple(np.array([50, 50, 0.0]) + 12.5 * np.array(n)), n))
    cols = {c: [] for c in ("setup", "target", "feature", "Xn_mm", "Yn_mm", "Zn_mm", "nx", "ny", "nz")}
    for r, (f, t, p, n) in enumerate(rows):
        if r == miss_row:
            p = (p[0], p[1], p[2] + 10.0)            # nothing there: a G38.2 miss
        for c, v in zip(("setup", "target", "feature"), ("s1", t, f)):
            cols[c].append(v)
        for c, v in zip(("Xn_mm", "Yn_mm", "Zn_mm", "nx", "ny", "nz"), (*p, *n)):
            cols[c].append(v)
    n = len(rows)
    for c in ("t_s", "X_mm", "Y_mm", "Z_mm"):
        cols[c] = [np.nan] * n
    return make_log(cols, {"artefact": "table+sphere", "stylus_r_mm": "0"})


def reference(plan_path, tmp_path):
    """The same plan on the same virtual machine, in-process (exact touches)."""
    out = tmp_path / "reference.csv"
    run_campaign(VirtualBackend(scene(), home_m=(0, 0, 0)), read_probe_log(plan_path), out,
                 ProbeSettings(probe_feed_mm_min=FEED, move_feed_mm_min=2000, clearance_mm=1,
                               overtravel_mm=1, safe_z_mm=20, limits_mm=LIMITS_MM))
    return read_probe_log(out)


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    linuxcnc_path()                     # HardwareError (a failure, never a skip) without LinuxCNC
    tmp = tmp_path_factory.mktemp("lcnc")
    plan_path = write_probe_log(tmp / "plan.csv", plan())
    prog = tmp / "probe.ngc"
    assert main(["machine", "program", "--plan", str(plan_path), "--out", str(prog),
                 "--probe-file", "probe.txt", *COMMON]) == 0
    res = run_program(prog, scene(), probe_file="probe.txt", out_dir=tmp, parameters=USER_PARAMS)
    return tmp, plan_path, res


def test_linuxcnc_runs_the_program_to_its_end(loop):
    tmp, plan_path, res = loop
    assert res.ok, f"LinuxCNC: {res.errors}\n{res.output[-3000:]}"
    assert res.probe_file is not None and res.probe_file.is_file()
    assert len(res.answers) == 24 and all(a["q_mm"] is not None for a in res.answers)
    assert not any(r.get("late") for r in res.component_log), res.component_log
    # the ray the component asked about is the programmed probing line: its direction,
    # taken from two of its own position reads 50 um apart, agrees with the plan's
    # approach to the program's rounding (6 decimals over 2 mm: 2.5e-7 rad); a read
    # mixing two servo periods, or a first point off the line, would tilt it by
    # 0.5 um / 50 um = 1e-2 rad and move the trigger by um
    nrm = read_probe_log(plan_path).normals()
    tilt = [float(np.arccos(min(1.0, -np.dot(r["d"], nrm[r["move"]])))) for r in res.component_log]
    assert len(tilt) == 24 and max(tilt) < 1e-6, tilt
    n = len(res.answers)
    figures = {"direction_error_urad_max": round(max(tilt) * 1e6, 4),
               "start_to_homed_s": round(res.homed_s, 2), "run_s": round(res.run_s, 1),
               "touches": n, "touches_per_min": round(n / res.run_s * 60, 1),
               "wall_s": round(res.wall_s, 1), "resolution_um": RES_MM * 1e3}
    (tmp / "figures.json").write_text(json.dumps(figures))
    print(f"\nLinuxCNC in the loop: {json.dumps(figures)}")


def test_touches_agree_with_the_virtual_part_to_the_resolution(loop, tmp_path):
    tmp, plan_path, res = loop
    out = tmp / "log.csv"
    assert main(["import", "linuxcnc", str(res.probe_file), "--plan", str(plan_path),
                 "--out", str(out)]) == 0
    log = read_probe_log(out)
    assert log.n == 24 and np.all(log.ok)
    ref = reference(plan_path, tmp_path)
    d = -log.normals()                                     # approach directions
    diff = log.positions_mm() - ref.positions_mm()
    along = np.einsum("ij,ij->i", diff, d)
    across = np.linalg.norm(diff - along[:, None] * d, axis=1)
    print(f"\ntouch - virtual machine along the approach: {along.min() * 1e3:.4f} .. "
          f"{along.max() * 1e3:.4f} um (bound 0 .. {RES_MM * 1e3:g}); across: max {across.max() * 1e6:.2f} nm")
    table = "\n".join(f"{k:2d} {log.col('target')[k]:6s} along {a * 1e3:+.4f} um across {c * 1e6:.2f} nm"
                      for k, (a, c) in enumerate(zip(along, across)))
    assert np.all(along >= -ROUND_MM) and np.all(along <= RES_MM + ROUND_MM), table
    assert np.all(across <= 2 * ROUND_MM), across
    # and against the geometry, computed here apart from the scene's code: the actual tip
    # (I + E) p of each touch is on the table top / the sphere, or at most F*T past it
    E = np.diag(SCALE)
    E[0, 1] = -EC0Y
    act = log.positions_mm() @ (np.eye(3) + E).T
    table = log.col("feature") == "table"
    assert np.all(act[table, 2] <= ROUND_MM) and np.all(act[table, 2] >= -RES_MM - ROUND_MM)
    dist = np.linalg.norm(act[~table] - [50, 50, 0], axis=1) - 12.5
    assert np.all(dist <= ROUND_MM) and np.all(dist >= -RES_MM - ROUND_MM), dist


def test_fit_and_scope_on_the_imported_file(loop, capsys):
    tmp, plan_path, res = loop
    out = tmp / "log.csv"
    if not out.exists():
        assert main(["import", "linuxcnc", str(res.probe_file), "--plan", str(plan_path),
                     "--out", str(out)]) == 0
    capsys.readouterr()
    js = tmp / "plane.json"
    assert main(["fit", "plane", str(out), "--feature", "table", "--json", str(js)]) == 0
    rep = json.loads(js.read_text())
    assert rep["form_um"] <= (RES_MM + 2 * ROUND_MM) * 1e3           # flat table, one period at most
    assert abs(rep["values"]["point_mm"][2]) <= RES_MM + ROUND_MM
    js = tmp / "sphere.json"
    assert main(["fit", "sphere", str(out), "--feature", "sphere", "--json", str(js)]) == 0
    rep = json.loads(js.read_text())
    assert np.allclose(rep["values"]["centre_mm"], [50, 50, 0], atol=2e-3)
    assert abs(rep["values"]["radius_mm"] - 12.5) <= 2e-3             # scale errors: < 1 um on 12.5 mm
    capsys.readouterr()
    assert main(["identify", str(out), "--json", str(tmp / "id.json")]) == 2
    err = capsys.readouterr().err
    assert "no touch has a normal in the XY plane" in err and err.count("\n") == 1


def test_user_frames_are_restored(loop):
    tmp, plan_path, res = loop
    after = res.parameters
    for k, v in USER_PARAMS.items():
        assert after.get(k) == pytest.approx(v, abs=1e-9), (k, after.get(k))


def test_a_miss_stops_linuxcnc_and_the_partial_file_keeps_every_touch(tmp_path, loop):
    plan_path = write_probe_log(tmp_path / "plan.csv", plan(miss_row=3))
    plan_path = write_probe_log(tmp_path / "plan5.csv", read_probe_log(plan_path).select(np.arange(6)))
    prog = tmp_path / "probe.ngc"
    assert main(["machine", "program", "--plan", str(plan_path), "--out", str(prog),
                 "--probe-file", "probe.txt", *COMMON]) == 0
    res = run_program(prog, scene(), probe_file="probe.txt", out_dir=tmp_path)
    assert not res.ok and any("G38.2" in e for e in res.errors), res.errors
    out = tmp_path / "log.csv"
    assert main(["import", "linuxcnc", str(res.probe_file), "--plan", str(plan_path),
                 "--out", str(out)]) == 0
    log = read_probe_log(out)
    assert list(log.col("status")) == ["ok"] * 3 + ["aborted"] * 3
    assert "3 of 6" in log.meta["probe_file_rows"]
    assert np.all(np.abs(log.positions_mm()[:3, 2]) <= RES_MM + ROUND_MM)
    assert os.path.getsize(res.probe_file) > 0


def test_a_touch_repeated_at_the_same_position_keeps_its_row(tmp_path, capsys):
    """Two probes tripping at the same position (the first table touch made twice, then the second): the
    program's numbered LOG lines keep all three. The same program with PROBEOPEN instead (vmt's programs
    before session 28) gets two lines from LinuxCNC, which writes no line for a probe at the previous one's
    position (emccanon.cc, GET_EXTERNAL_PROBE_POSITION); its import is refused, naming the line and row
    (before session 28: imported with the second touch on the wrong target and the last row 'aborted')."""
    linuxcnc_path()                     # HardwareError (a failure, never a skip) without LinuxCNC
    plan_path = write_probe_log(tmp_path / "plan.csv", plan().select(np.array([0, 0, 1])))
    prog = tmp_path / "probe.ngc"
    assert main(["machine", "program", "--plan", str(plan_path), "--out", str(prog),
                 "--probe-file", "probe.txt", *COMMON]) == 0
    res = run_program(prog, scene(), probe_file="probe.txt", out_dir=tmp_path / "log")
    assert res.ok, res.errors
    lines = res.probe_file.read_text().splitlines()
    assert [ln.split()[0] for ln in lines] == ["N0", "N1", "N2"] and lines[0][3:] == lines[1][3:], lines
    out = tmp_path / "log.csv"
    assert main(["import", "linuxcnc", str(res.probe_file), "--plan", str(plan_path), "--out", str(out)]) == 0
    log = read_probe_log(out)
    assert np.all(log.ok) and np.array_equal(log.positions_mm()[0], log.positions_mm()[1])
    old = prog.read_text().replace("(LOGOPEN,probe.txt)", "(PROBEOPEN probe.txt)").replace("(LOGCLOSE)",
                                                                                           "(PROBECLOSE)")
    old_prog = tmp_path / "old.ngc"
    old_prog.write_text("".join(ln + "\n" for ln in old.splitlines() if not ln.startswith("(LOG,")))
    res = run_program(old_prog, scene(), probe_file="probe.txt", out_dir=tmp_path / "old")
    assert res.ok, res.errors
    assert len(res.probe_file.read_text().splitlines()) == 2          # three probes, two lines
    capsys.readouterr()
    assert main(["import", "linuxcnc", str(res.probe_file), "--plan", str(plan_path),
                 "--out", str(tmp_path / "old.csv")]) == 2
    err = capsys.readouterr().err
    assert "line 2: [120, 10, " in err and "not a touch of plan row 1 (target 'r0c0'" in err, err
    assert "one row early" in err and err.count("\n") == 1
