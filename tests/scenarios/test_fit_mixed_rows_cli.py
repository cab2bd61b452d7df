"""``vmt fit`` on touches of several set-ups or features (review30 F1).

``vmt simulate pin-circle`` logs one 6 mm pin in 8 set-ups; ``vmt fit circle LOG --feature pin01`` without
``--setup`` fitted all 32 touches as one circle (radius 197.1 mm, roundness 18 mm, exit 0). Now refused in one
line naming the set-ups found and ``--setup``; with ``--setup C0`` the pin's 6 mm.
"""

from __future__ import annotations

import pytest

from scenarios.cli import main


@pytest.fixture(scope="module")
def pin_log(tmp_path_factory):
    out = tmp_path_factory.mktemp("pin") / "pin.csv"
    assert main(["simulate", "pin-circle", "--out", str(out), "--seed", "2"]) == 0
    return out


def test_fit_across_setups_is_refused_naming_them_and_the_option(pin_log, capsys):
    capsys.readouterr()
    assert main(["fit", "circle", str(pin_log), "--feature", "pin01"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err
    assert str(pin_log) in err and err.endswith("choose one with --setup NAME")
    # in the order of their angles (session 30: sorted as text, "C0, C137, C191, C227, C257, C31, ...")
    assert "span 8 set-ups (C0, C31, C83, C137, C191, C227, ...)" in err
    assert main(["fit", "circle", str(pin_log), "--feature", "pin01", "--setup", "C0"]) == 0
    assert "radius 5.9998 mm" in capsys.readouterr().out


def test_fit_across_features_names_both_options(tmp_path, capsys):
    """A cross-pocket campaign: walls and two spheres in four set-ups (review30: radius 761.7 mm, exit 0)."""
    log = tmp_path / "xp.csv"
    assert main(["simulate", "cross-pocket", "--out", str(log), "--seed", "1", "--no-collision-check"]) == 0
    capsys.readouterr()
    assert main(["fit", "sphere", str(log)]) == 2
    err = capsys.readouterr().err.strip()
    assert "features (pocket, sphere1, sphere2)" in err and err.endswith("--setup NAME and --feature NAME")
    # one set-up touches a ring of each sphere: a circle
    assert main(["fit", "circle", str(log), "--feature", "sphere1", "--setup", "C0"]) == 0
