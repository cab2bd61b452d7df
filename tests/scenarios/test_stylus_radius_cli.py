"""One stylus radius option, one way of speaking (session 26).

``vmt fit`` with a log that says no stylus radius applied 0 with a notice: a ball, a bore or a pin fitted wrong by
the radius, a plane's position too. ``vmt plan grid`` without ``--stylus-r-mm`` wrote a plan for a 0 mm tip: every
nominal, and the approach's clearance above the surface, off by the radius. Both now refuse in one line naming
``--stylus-r-mm`` (exit 2); the fit takes the log's radius when it has one; ``--stylus-r-mm 0`` is a pin or a tool.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from core.probelog import make_log, read_probe_log, write_probe_log
from scenarios.cli import build_parser, main

ASK = "give --stylus-r-mm R, the stylus tip radius in mm (--stylus-r-mm 0 for a pin or a tool as the probe)"


def ball_log(path, meta):
    """A 12.5 mm ball at (10, 20, 30) mm touched by a 1.5 mm tip: tip centres 14 mm from its centre."""
    u = np.random.default_rng(4).normal(size=(24, 3))
    u[:, 2] = np.abs(u[:, 2])
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    p = np.array([10.0, 20.0, 30.0]) + 14.0 * u
    k = len(p)
    cols = {"setup": ["S1"] * k, "target": [f"t{i}" for i in range(k)], "t_s": np.arange(k, dtype=float),
            "X_mm": p[:, 0], "Y_mm": p[:, 1], "Z_mm": p[:, 2], "Xn_mm": p[:, 0], "Yn_mm": p[:, 1],
            "Zn_mm": p[:, 2], "nx": u[:, 0], "ny": u[:, 1], "nz": u[:, 2], "feature": ["ball"] * k}
    return write_probe_log(path, make_log(cols, meta))


def test_fit_without_a_radius_is_refused_in_one_line(tmp_path, capsys):
    log = ball_log(tmp_path / "ball.csv", {})
    js = tmp_path / "fit.json"
    for kind in ("sphere", "plane", "circle"):
        assert main(["fit", kind, str(log), "--json", str(js)]) == 2
        err = capsys.readouterr().err
        assert err == f"vmt fit: error: {log}: says no stylus radius (no stylus_r_mm column or metadata): {ASK}\n"
        assert not js.exists()
    assert main(["fit", "sphere", str(log), "--stylus-r-mm", "1.5", "--json", str(js)]) == 0
    out = capsys.readouterr().out
    assert "stylus radius 1.5 mm applied (--stylus-r-mm; the log says none)" in out
    rep = json.loads(js.read_text())
    assert rep["values"]["radius_mm"] == pytest.approx(12.5, abs=1e-9)
    assert (rep["stylus_r_mm"], rep["stylus_r_source"], rep["log_stylus_r_mm"]) == (1.5, "given", None)
    assert main(["fit", "sphere", str(log), "--stylus-r-mm", "0", "--json", str(js)]) == 0   # a pin: allowed
    assert json.loads(js.read_text())["values"]["radius_mm"] == pytest.approx(14.0, abs=1e-9)


def test_fit_takes_the_logs_radius_and_the_option_wins(tmp_path, capsys):
    log = ball_log(tmp_path / "ball.csv", {"stylus_r_mm": "1.5"})
    js = tmp_path / "fit.json"
    assert main(["fit", "sphere", str(log), "--json", str(js)]) == 0
    assert "stylus radius 1.5 mm applied (the log's stylus_r_mm metadata)" in capsys.readouterr().out
    assert json.loads(js.read_text())["values"]["radius_mm"] == pytest.approx(12.5, abs=1e-9)
    assert main(["fit", "sphere", str(log), "--stylus-r-mm", "1.4987", "--json", str(js)]) == 0
    assert "stylus radius 1.4987 mm applied (--stylus-r-mm; the log says 1.5 mm)" in capsys.readouterr().out
    assert json.loads(js.read_text())["values"]["radius_mm"] == pytest.approx(12.5013, abs=1e-9)
    assert main(["fit", "sphere", str(log), "--stylus-r-mm", "1.5"]) == 0
    assert "(--stylus-r-mm, as the log says)" in capsys.readouterr().out
    for bad in ("-1", "nan", "inf"):
        assert main(["fit", "sphere", str(log), "--stylus-r-mm", bad]) == 2
        err = capsys.readouterr().err
        assert err.startswith("vmt fit: error: --stylus-r-mm must be a finite number >= 0") and err.count("\n") == 1


def test_plan_grid_without_a_radius_is_refused_in_the_same_words(tmp_path, capsys):
    out = tmp_path / "grid.csv"
    assert main(["plan", "grid", "--x-mm", "0:20:10", "--y-mm", "0:10:10", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == ("vmt plan grid: error: no stylus radius (the plan's nominal tip centres stand one radius above "
                   f"the surface): {ASK}\n")
    assert not out.exists()
    assert main(["plan", "grid", "--x-mm", "0:20:10", "--y-mm", "0:10:10", "--z-mm", "5", "--stylus-r-mm", "1.5",
                 "--out", str(out)]) == 0
    plan = read_probe_log(out)
    assert np.allclose(plan.nominals_mm()[:, 2], 6.5) and plan.meta["stylus_r_mm"] == "1.5"
    assert main(["plan", "grid", "--x-mm", "0:20:10", "--y-mm", "0:10:10", "--stylus-r-mm", "0",
                 "--out", str(tmp_path / "pin.csv")]) == 0


def test_one_stylus_radius_option_everywhere():
    """Every command that takes a stylus radius names it --stylus-r-mm, no default, the same help."""
    from test_cli_options import _walk  # (the parser walk of the option-language tests)

    from scenarios.cli.options import STYLUS_R_HELP

    uses = {" ".join(path[1:]): a for path, a in _walk(build_parser())
            if any("stylus" in o or "radius" in o for o in a.option_strings)}
    assert set(uses) == {"plan grid", "fit"}
    for a in uses.values():
        assert a.option_strings == ["--stylus-r-mm"] and a.default is None and a.type is float
        assert a.help.startswith(STYLUS_R_HELP + "; ")
