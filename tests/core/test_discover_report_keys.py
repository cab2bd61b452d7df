"""The report's ``params_u95``: the spec's "same keys as ``params``", and no U95 for an angle it cannot place.

The probe-log spec (docs/formats.md, the discovery report) gives each finding's
``params_u95`` the keys of its ``params``, null where the data do not determine a
value. Before session 25's review the report left out the keys of choices (a
periodic error's ``axis``, an outlier finding's ``n_outliers``), and gave a
periodic error's phase beside an amplitude consistent with zero a U95 of
12.96 rad, more than the whole circle: on the README's own campaign
(``vmt simulate cross-pocket --out log.csv --seed 1 --noise-um 0.3 --c-angles-deg
0,75,130,210``, stored here as it came out), whose ``EYX`` amplitude is
0.0060 +- 0.0060 um.
"""

from __future__ import annotations

import gzip
import math
import pathlib

import pytest

from core import causes
from core.discover import Finding, _report_u95
from core.probelog import parse_probe_log
from tests.discover_helpers import discovered

HERE = pathlib.Path(__file__).parent / "data" / "report_keys"


@pytest.fixture(scope="module")
def readme_report():
    name = "readme-cross-pocket-seed1.csv.gz"
    log = parse_probe_log(gzip.decompress((HERE / name).read_bytes()).decode(), name)
    return discovered(log).to_report()


def test_every_param_has_its_u95_key(readme_report):
    assert readme_report["findings"], "the README's campaign names its periodic error"
    for f in readme_report["findings"]:
        assert list(f["params_u95"]) == list(f["params"])
        for k, v in f["params"].items():
            if not isinstance(v, (int, float)) or isinstance(v, bool):
                assert f["params_u95"][k] is None, k


def test_a_phase_beside_an_amplitude_consistent_with_zero_has_no_u95(readme_report):
    f = next(f for f in readme_report["findings"] if f["cause"] == "periodic_axis_error")
    p, u = f["params"], f["params_u95"]
    # EYX's amplitude is within its U95 of zero: its phase is any angle, and the report says so
    assert p["EYX_amplitude_um"] <= u["EYX_amplitude_um"] + 1e-12
    assert u["EYX_phase_rad"] is None
    # EXX's amplitude is five U95s from zero: its phase is placed, its U95 well inside half a turn
    assert p["EXX_amplitude_um"] > 3 * u["EXX_amplitude_um"]
    assert 0 < u["EXX_phase_rad"] < 0.5


@pytest.mark.parametrize("u, kept", [(math.pi * (1 - 1e-12), True), (math.pi, False), (12.96, False)])
def test_half_a_turn_is_the_limit(u, kept):
    """Known answers at the limit: a U95 just under half the circle is reported, half of it or more is not."""
    f = Finding("periodic_axis_error", {}, {"axis": "X", "EXX_phase_rad": 0.3},
                {"EXX_phase_rad": u, "unknown_extra_key": 1.0}, 0.5)
    out = _report_u95(f, "planar")
    assert out == {"axis": None, "EXX_phase_rad": u if kept else None}
    # the same key on a cause that declares no circle keeps any U95
    g = Finding("unexplained", {}, {"EXX_phase_rad": 0.3}, {"EXX_phase_rad": u}, 0.5)
    assert _report_u95(g, "planar") == {"EXX_phase_rad": u}


def test_circular_declarations_name_magnitudes_the_causes_report():
    """Each declared circle's pattern is a key its cause's magnitudes write (a renamed key is not silently lost)."""
    from core.discover import _matches
    seen = {c.name: c.circular for c in causes.REGISTRY if c.circular}
    assert set(seen) == {"periodic_axis_error", "part_change"}
    assert _matches("EXX_phase_rad", "E*_phase_rad") and _matches("EYY_phase_rad", "E*_phase_rad")
    assert "ovalisation_axis_deg" in seen["part_change"]
