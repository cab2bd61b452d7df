"""A local scale defect narrower than the mean spacing of the positions along its axis is scanned and named.

The bump scan's narrowest half-width was twice the mean spacing of the distinct positions along the axis
(core.causes.DEFECT_MIN_WIDTH_GAPS = 2.0 before session 34). A symmetric part measured in set-ups turned by 180 deg
has few distinct positions (gen_a's hexagon-pocket-sym and octagon-pocket-sym: 52-54 over 130-150 mm, a mean
spacing of 2.4-2.8 mm), so the narrowest bump on the 22 mm grid was 8.8 mm, three times gen_a's narrow defects
(2.5-3.7 mm), whose touches sit 1-2 mm apart on one wall. The 8.8 mm bump reached touches the true one does not
move and was refused (carried by one place, confounded) or its held-out gain fell short, and a short period took
the defect's touches (blind set C: gen_a local_scale_defect 10108, 10300, 10306 read `periodic_axis_error?`). Now
the floor is half the mean spacing (a bump's full width at least one spacing), the trial's own count of four
distinct positions under it being the resolution where it sits.

Tuning seeds (gen_a 1000-1299, the local_scale_defect campaigns whose true half-width is below twice the mean
spacing along its axis): 1121, 1246 and 1299 read `periodic_axis_error?` and 1293 `unexplained` (confident) at
2.0; all four `local_scale_defect` (ambiguous) at 0.5. Each test below fails with the floor at 2.0 (checked by
hand: ``core.causes.DEFECT_MIN_WIDTH_GAPS = 2.0``).
"""

from __future__ import annotations

import pytest

from core import causes
from tests.discover_helpers import discovered


def _report(seed: int):
    from scenarios.blind import gen_a

    log, truth = gen_a.generate("local_scale_defect", seed)
    return discovered(log).to_report(), truth


def test_the_floor_is_half_the_mean_spacing():
    assert causes.DEFECT_MIN_WIDTH_GAPS == 0.5


def test_a_narrow_defect_read_as_a_period_is_named_on_its_axis():
    """gen_a local_scale_defect 1121 (hexagon-pocket-sym, 22 mm grid): a 9.9 um bump of 3.7 mm half-width on Y,
    its positions along Y 2.5 mm apart on average. At the floor of two spacings: `periodic_axis_error?` (the
    bump's narrowest trial 8.8 mm). Now `local_scale_defect` first, on Y, its half-width within twice the
    truth's (the refined width 3.6 mm) and its peak within a fifth of the generator's (9.6 against 9.9 um).
    (Its centre is compared by its size only: this symmetric part, measured at C 0 and 180 deg only, cannot tell
    the bump from its image about the C axis, and the report gives +52.6 mm with the image -52.6 listed, the
    generator -52.8: tests/core/test_discover_cat35.py, session 35.) Still ambiguous, with `outlier` among
    the alternatives: the bump's touches are one wall's."""
    rep, truth = _report(1121)
    f = rep["findings"][0]
    assert rep["cause"] == "local_scale_defect", (rep["cause"], rep["rejected"])
    assert f["params"]["axis"] == truth.params["axis"] == "Y"
    assert abs(f["params"]["centre_mm"]) == pytest.approx(abs(truth.params["centre_mm"]),
                                                          abs=truth.params["half_width_mm"] / 4)
    assert 0.5 < f["params"]["half_width_mm"] / truth.params["half_width_mm"] < 2.0
    assert abs(f["params"]["amplitude_um"] - truth.physical["amplitude_um"]) < 0.2 * truth.physical["amplitude_um"]
    assert "periodic_axis_error" not in [g["cause"] for g in rep["findings"]]


def test_a_narrow_defect_left_unexplained_is_named_where_the_generator_put_it():
    """gen_a local_scale_defect 1293 (octagon-pocket, no symmetry: its centre determined, the generator's frame): a
    6.2 um bump of 3.0 mm half-width on X. At the floor of two spacings: `unexplained`, confident. Now
    `local_scale_defect` first, on X, its centre within a quarter of the true half-width (the scan's step between
    centres), its half-width and peak amplitude within their U95 of the generator's (the known answer:
    55.4 mm, 2.75 mm, 6.45 um against 55.7, 3.02, 6.22)."""
    rep, truth = _report(1293)
    f = rep["findings"][0]
    assert rep["cause"] == "local_scale_defect", (rep["cause"], rep["rejected"])
    p, u, true = f["params"], f["params_u95"], truth.params
    assert p["axis"] == true["axis"] == "X"
    assert abs(p["centre_mm"] - true["centre_mm"]) < true["half_width_mm"] / 4, (p, true)
    assert abs(p["half_width_mm"] - true["half_width_mm"]) < u["half_width_mm"], (p, u, true)
    assert abs(p["amplitude_um"] - truth.physical["amplitude_um"]) < u["amplitude_um"], (p, u, truth.physical)
