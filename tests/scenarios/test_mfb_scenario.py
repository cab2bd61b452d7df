"""vmt scenario mfb-3axis: simulate -> points of interest -> 21 errors -> JSON."""

import json

import pytest


def test_cli_json_keys(tmp_path):
    from scenarios.cli import main

    out = tmp_path / "mfb.json"
    assert main(["scenario", "mfb-3axis", "--json", str(out), "--seed", "2", "--mc", "200"]) == 0
    d = json.loads(out.read_text())
    for k in ("placements", "measurements", "touches", "errors", "max_dev_um", "max_dev_urad"):
        assert k in d
    assert d["placements"] == 11 and d["measurements"] == 14 and d["touches"] > 3000
    assert len(d["errors"]) == 21
    for e in d["errors"].values():
        assert {"injected", "identified", "u95"} <= set(e)


def test_unknown_scenario_exit_2(capsys):
    from scenarios.cli import main

    with pytest.raises(SystemExit) as e:
        main(["scenario", "nope"])
    assert e.value.code == 2
