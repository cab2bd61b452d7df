"""``vmt design``'s default grid is ``vmt identify``'s (review31 F7).

The default was the paper's fixed -110:110:22; on a user's 100 mm square pocket (targets within 64 mm of the C
axis) design refused "no choice of 4 C angles ... identifies the workpiece" while identify's default grid (a
22 mm step covering the targets: -66:66:22 once turned through a full turn) designs it. A refusal now names the
grid's reach and ``--grid-mm``. The paper's cross pocket (targets within 100.4 mm) gets -110:110:22 either way.
"""

from __future__ import annotations

import json

from scenarios.cli import main
from scenarios.cli.design import GRID_DEFAULT


def _square_pocket_plan(path, r=2.0):
    """review31's myplan.csv: a 100 mm square pocket's four walls at z -5, a target every 10 mm, set-up C0."""
    lines = ["# format: probe-log/1", f"# stylus_r_mm: {r}",
             "setup,target,feature,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz,C_deg,wx_mm,wy_mm,wz_mm,wnx,wny,wnz"]
    for i, s in enumerate(range(-40, 41, 10)):
        for tg, (wx, wy), (nx, ny) in ((f"E{i:02d}", (50, s), (-1, 0)), (f"W{i:02d}", (-50, s), (1, 0)),
                                       (f"N{i:02d}", (s, 50), (0, -1)), (f"S{i:02d}", (s, -50), (0, 1))):
            xn, yn = wx + r * nx, wy + r * ny
            lines.append(f"C0,{tg},wall,,,,,{xn},{yn},-5,{nx},{ny},0,0,{wx},{wy},-5,{nx},{ny},0")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_design_of_a_small_part_on_identifys_grid_and_the_refusal_names_the_grid(tmp_path, capsys):
    plan = _square_pocket_plan(tmp_path / "plan.csv")
    js = tmp_path / "d.json"
    assert GRID_DEFAULT == "22"
    args = ["design", "--plan", str(plan), "--n-angles", "4", "--step-deg", "15", "--reference-deg", "0,75,130,210"]
    assert main([*args, "--json", str(js)]) == 0
    r = json.loads(js.read_text())
    assert len(r["c_deg"]) == 4 and r["max_u95_um"] <= r["reference_max_u95_um"]
    capsys.readouterr()
    assert main([*args, "--grid-mm=-110:110:22"]) == 2          # the old default: nodes no target reaches
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err
    assert err.endswith("identifies the workpiece (eq 6: more angles or a coarser grid); the grid x -110:110 mm, "
                        "y -110:110 mm, 22 mm step (--grid-mm -110:110:22) against targets within 64.0 mm of the C "
                        "axis: a coarser or smaller one is --grid-mm STEP or x0:x1:step")
