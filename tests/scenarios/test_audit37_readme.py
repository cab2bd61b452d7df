"""README figures quoted as a command's output, re-run (audit37). The marked blocks are run by
test_documented_commands.py; these are figures in the prose that no test compared."""

import json
import re
from pathlib import Path

import pytest

from scenarios.cli import main

ROOT = Path(__file__).resolve().parents[2]


def _readme():
    return re.sub(r"\s+", " ", (ROOT / "README.md").read_text(encoding="utf-8"))


def test_identify_on_a_2_lobe_probe_prints_the_readmes_figures(tmp_path, capsys):
    """README, "`vmt identify` on a simulated cross-pocket log": the nmv3000 with errors none and a probe of
    `lobing = [{ k = 2, cos_um = 0.75, sin_um = 0.0 }]`, noise 0.3 um, `vmt simulate cross-pocket --seed 1`.
    Every figure the README quotes from that run's line is the run's, and so is the probing sigma beside
    them: 0.276 um (the README said 0.286 until audit37, the figure of the test's seed 1001,
    tests/scenarios/test_identify_cli.py)."""
    src = (ROOT / "sim" / "data" / "machines" / "nmv3000.toml").read_text()
    assert 'errors = "none"' in src and "noise_um = 0.125" in src
    toml = tmp_path / "lob.toml"
    toml.write_text(src.replace("noise_um = 0.125",
                                "noise_um = 0.3\nlobing = [{ k = 2, cos_um = 0.75, sin_um = 0.0 }]"))
    log, out = tmp_path / "lob.csv", tmp_path / "lob.json"
    assert main(["simulate", "cross-pocket", "--machine", str(toml), "--seed", "1", "--out", str(log)]) == 0
    capsys.readouterr()
    assert main(["identify", str(log), "--json", str(out), "--mc", "0"]) == 0
    said = re.sub(r"\s+", " ", capsys.readouterr().out)
    readme = _readme()
    for quoted in ("moves G by 4.52 um (3.3 x its U95), EC0Y by 45.06 urad (3.1 x its U95)",
                   "a lobe of order 2 and ~0.75 um at its worst phase, absorbed part included, moves G by 4.78 "
                   "um (3.5 x its U95), EC0Y by 47.12 urad (3.3 x its U95)"):
        assert quoted in readme, quoted
        assert quoted in said, said
    sigma = json.loads(out.read_text())["uncertainty"]["probe_sigma_um"]
    assert f"{sigma:.3f}" == "0.276", sigma
    assert "sigma 0.276 µm on the campaign above, seed 1" in readme


@pytest.mark.parametrize("axis, figures", [("X", {"E_um": 54.8, "M_um": 54.4, "A_um": 56.7, "R_um": 3.3, "B_um": 0.6})])
def test_positioning_on_vmc_3axis_prints_the_readmes_figures(tmp_path, capsys, axis, figures):
    """README, "ISO 230-2 positioning tests": `vmt simulate positioning --machine vmc-3axis --axis X` (seed 0)
    scores E = 54.8 um, M = 54.4 um, A = 56.7 um, R = 3.3 um, B = 0.6 um: the README's words and the run's
    figures rounded as the README rounds them (0.1 um)."""
    readme = _readme()
    assert "axis X scores E = 54.8 µm, M = 54.4 µm, A = 56.7 µm, R = 3.3 µm, B = 0.6 µm (seed 0)" in readme
    log, js = tmp_path / "x.csv", tmp_path / "x.json"
    assert main(["simulate", "positioning", "--machine", "vmc-3axis", "--axis", axis, "--seed", "0",
                 "--out", str(log)]) == 0
    assert main(["iso230-2", str(log), "--json", str(js)]) == 0
    r = json.loads(js.read_text())
    for k, v in figures.items():
        assert round(r[k], 1) == v, (k, r[k])
