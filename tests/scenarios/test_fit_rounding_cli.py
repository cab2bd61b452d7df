"""``vmt fit`` says the printing step its U95 stands on (session 32, fitq32; review31e F3).

review31e's wall: four touches of a perfect wall at x = 48 mm printed to 3 decimals. Before: ``U95 (Student t, 1
dof): offset_n_um 0, tilt_u_urad 0, tilt_v_urad 0`` (1e-25 um). Now each U95 is at least what the 1 um step allows,
the line says so and marks the figures the step sets; the JSON has both parts and the steps.
"""

from __future__ import annotations

import json

import pytest

from scenarios.cli import main


def _wall(path, decimals=3):
    f = f"{{:.{decimals}f}}".format
    rows = [f"S1,T{i},f,{i + 1}.0," + ",".join(map(f, p + p)) + ",-1.000000000,0.000000000,0.000000000"
            for i, p in enumerate([[48, -5, -5], [48, -5, -4], [48, 5, -5], [48, 5, -4]])]
    path.write_text("# format: probe-log/1\n# stylus_r_mm: 2.0\n"
                    "setup,target,feature,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz\n" + "\n".join(rows) + "\n")
    return path


def test_the_u95_line_names_the_printing_step_and_the_json_keeps_both_parts(tmp_path, capsys):
    log, js = _wall(tmp_path / "wall.csv"), tmp_path / "wall.json"
    assert main(["fit", "plane", str(log), "--json", str(js)]) == 0
    out = capsys.readouterr().out
    assert ("  U95 (Student t, 1 dof; never below the rounding of X, Y, Z printed to 0.001 mm): offset_n_um 0.566 "
            "(printing step), tilt_u_urad 113 (printing step), tilt_v_urad 1.13e+03 (printing step)\n") in out
    rep = json.loads(js.read_text())
    assert rep["printing_step_mm"] == pytest.approx([1e-3] * 3)
    assert rep["u95"]["offset_n_um"] == pytest.approx(0.5658, abs=1e-4) == rep["u95_rounding"]["offset_n_um"]
    assert rep["u95_scatter"]["offset_n_um"] < 1e-12


def test_a_log_printed_at_full_precision_prints_the_line_as_before(tmp_path, capsys):
    """A step of 1e-12 mm (12 decimals: the most the reader counts) floors at its own size (5.66e-10 um, marked:
    the perfect wall's scatter is still 1e-25); vmt's own logs (shortest round-trip) are exact: the old line."""
    log = _wall(tmp_path / "w12.csv", decimals=12)
    assert main(["fit", "plane", str(log)]) == 0
    out = capsys.readouterr().out
    assert "never below the rounding of X, Y, Z printed to 1e-12 mm): offset_n_um 5.66e-10 (printing step)" in out
    text = log.read_text().replace("# stylus_r_mm", "# number_format: shortest round-trip\n# stylus_r_mm")
    (tmp_path / "exact.csv").write_text(text)
    assert main(["fit", "plane", str(tmp_path / "exact.csv")]) == 0
    out = capsys.readouterr().out
    assert "  U95 (Student t, 1 dof): offset_n_um " in out and "printing" not in out
