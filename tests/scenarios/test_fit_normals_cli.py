"""``vmt fit`` refuses what the touches cannot tell (review31 F1).

A wall probed along one height: ``vmt fit plane`` returned the horizontal plane through the touches (normal
(0, 0, 1) at 90 deg to every touch's, the 2 mm stylus radius applied vertically, flatness and every U95 0, exit 0).
The simulator's own cross-pocket campaign did the same for its pocket and its spheres' touches. Now one line
naming the log, the feature, the set-up and why, exit 2; at two heights the wall, with the angle said.
"""

from __future__ import annotations

import numpy as np

from scenarios.cli import main


def _wall_log(path, heights, *, noise_um=0.3, seed=5, r=2.0):
    """review31's mklog.py in small: wall x = 50 mm, normal -x, y -40..40 every 10 mm, 6 decimals."""
    rng = np.random.default_rng(seed)
    lines = ["# format: probe-log/1", f"# stylus_r_mm: {r}",
             "setup,target,feature,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz"]
    i = 0
    for z in heights:
        for y in range(-40, 41, 10):
            xn = 50.0 - r
            x = xn + noise_um * 1e-3 * rng.standard_normal()
            lines.append(f"C0,E{i:02d},wallE,{6.0 * i:.3f},{x:.6f},{y:.6f},{z:.6f},{xn:.6f},{y:.6f},{z:.6f},-1,0,0")
            i += 1
    path.write_text("\n".join(lines) + "\n")
    return path


def test_one_height_wall_refused_in_one_line_two_heights_fitted(tmp_path, capsys):
    one = _wall_log(tmp_path / "one.csv", [-5.0])
    assert main(["fit", "plane", str(one), "--setup", "C0", "--feature", "wallE"]) == 2
    cap = capsys.readouterr()
    err = cap.err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err and cap.out == ""
    assert err.startswith(f"vmt fit: error: {one} (--feature wallE --setup C0): plane fit (feature wallE, set-up C0): "
                          "the touches lie on one line: a plane needs two heights / two directions (")
    two = _wall_log(tmp_path / "two.csv", [-5.0, -10.0])
    js = tmp_path / "fit.json"
    assert main(["fit", "plane", str(two), "--json", str(js)]) == 0
    out = capsys.readouterr().out
    assert "  point (50.0000, " in out and "normal (-1.000000, " in out
    assert "  the log's touch normals within 0.0 deg of the fitted plane's (refused beyond 30 deg)\n" in out
    import json

    assert json.loads(js.read_text())["normal_angle_deg"] < 0.05     # 0.3 um noise over 5 mm: ~0.01 deg


def test_cross_pocket_features_at_one_height_are_not_planes(tmp_path, capsys):
    log = tmp_path / "xp.csv"
    assert main(["simulate", "cross-pocket", "--out", str(log), "--seed", "1", "--no-collision-check"]) == 0
    capsys.readouterr()
    for feat, tg, k in (("pocket", "wall00_0", 84), ("sphere1", "sphere1_p0", 4)):
        assert main(["fit", "plane", str(log), "--setup", "C75", "--feature", feat]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and f"plane fit (feature {feat}, set-up C75): the fitted plane's normal is at " \
            f"90.0 deg to the log's normal of touch {tg} ({k} of {k} touches beyond 30 deg)" in err
