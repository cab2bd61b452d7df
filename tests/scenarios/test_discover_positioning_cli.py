"""`vmt discover` on an ISO 230-2 positioning test (issue 18 item 4), the project's own sample.

The sample (scenarios/positioning_sample.py, written apart from sim/) hides a
warm-up drift ``3.5 (1 - exp(-t / 1200 s))`` um over a test of about 9
minutes, with scale, pitch and lost motion that the standard's baseline (a
mean per target and direction) absorbs by construction. Over the test the
warm-up rises 1.27 um from its first reading: the finding must be the warm-up,
with its offset against the end of the test within its U95.
"""

import json
import math

import pytest

from scenarios.cli import main
from scenarios.positioning_sample import SAMPLE


def test_discover_names_the_samples_warm_up(tmp_path, capsys):
    out = tmp_path / "d.json"
    assert main(["discover", str(SAMPLE), "--json", str(out)]) == 0
    rep = json.loads(out.read_text())
    assert rep["cause"] == "warm_up", [f["cause"] for f in rep["findings"]]
    f = rep["findings"][0]
    t_end = max(r for r in _times())
    rise = 3.5 * (1 - math.exp(-t_end / 1200.0))            # um, from the first reading to the last
    assert abs(f["params"]["initial_offset_um"] + rise) <= f["params_u95"]["initial_offset_um"], (f, rise)
    assert rep["gain"]["cv_rms_ratio"] < 0.9
    assert "warm_up" in capsys.readouterr().out


def _times():
    for line in SAMPLE.read_text().splitlines():
        if line and not line.startswith("#") and not line.startswith("target"):
            yield float(line.split(",")[4])


@pytest.mark.parametrize("extra, what", [(["--report", "r"], "--report"), (["--grid-mm", "22"], "--grid-mm")])
def test_discover_positioning_refuses_what_it_cannot_do(tmp_path, capsys, extra, what):
    out = tmp_path / "d.json"
    assert main(["discover", str(SAMPLE), "--json", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert what in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
