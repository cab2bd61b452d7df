"""Session 31's two blind misses (diag31), diagnosed and pinned.

gen_c outlier 6106 (``periodic_axis_error``, confident): three gross touches (+14.0, +7.1, -18.7 um) make BIC choose
the 80 mm error map (117 parameters; on the same log without them it also chooses 80 mm, so
:data:`core.discover.GRID_AFTER_OUTLIERS` finds no other grid); the screen sets the three aside (all three, no
other), and the 80 mm map's misfit of gen_c's smooth machine is read as a ripple at the grid step (X, 81.4 mm,
0.12 um, explained 0.063 um RMS). :data:`core.discover.FINER_MAP_CHECK` runs the 22 mm map, which reads the same three
outliers and nothing else, but it asked for ``none`` and so kept the ripple. :data:`FINER_MAP_OUTLIERS_AGREE` (on)
takes the finer map there too (tuning twins gen_c outlier 134, confident ripple, and 162 hedged nonrigid, both
``outlier`` with it; no right -> wrong on the tuning sets measured) (docs/discovery-studies.md, "Session 31: a coarse map's ripple beside outliers, and a part change
inflated 181 times").

gen_a thermal_bending 8907 (extended workpiece 6.909 um against baseline 1.053 + U95 2.114): a hedged
``part_change`` of bore1 (continuous form, walls changing by -40 to +46 um over the campaign) fitted to the
warming guideway's bow along a direction inflated 181 times (best 4.7, vif_max 100; principal angle 4.3 deg):
bore1's three visits, one per set-up and C angle, cannot tell a wall changing in time from the walls' values; the
extended workpiece of bore1's walls moves 7-37 um with an extended U95 of 4-8 um. No rule was switched on for it in
session 31; since session 32 (vif32) :data:`core.discover.HEDGED_SHIFT_CARRIED` carries the hedged part_change's own
shift in the extended U95 (tests/core/test_discover_vif32.py).
"""

from types import SimpleNamespace

import pytest

import core.discover as D
from scenarios.blind import gen_a, gen_c
from scenarios.hidden import blind_outcome
from tests.discover_helpers import discovered


@pytest.fixture(autouse=True)
def _extended_workpiece_offered(monkeypatch):
    """These tests examine the extended fit's workpiece (its shift, its U95) on campaigns whose extended U95 grows
    beyond 3 times the baseline's, which core.discover.WORKPIECE_U95_GROWTH_WITHHELD (on since session 35) withholds
    from the report: held off here, so that the estimate beneath it is what they check, as they were written to."""
    import core.discover as D

    monkeypatch.setattr(D, "WORKPIECE_U95_GROWTH_WITHHELD", False)


def _finding(cause):
    return SimpleNamespace(cause=cause)


def _disc(causes, outliers):
    return SimpleNamespace(findings=[_finding(c) for c in causes], outlier_rows=tuple(outliers))


@pytest.mark.parametrize("finer, coarse, agree", [
    ((("outlier",), (3, 7)), (("periodic_axis_error", "outlier"), (3, 7, 9)), True),   # the same outliers (fewer)
    ((("outlier",), (3, 8)), (("periodic_axis_error", "outlier"), (3, 7, 9)), False),  # an outlier the coarse missed
    ((("outlier", "periodic_axis_error"), (3,)), (("periodic_axis_error", "outlier"), (3,)), False),  # more than them
    (((), ()), (("periodic_axis_error", "outlier"), (3,)), False),  # none: the check's old branch, not this one
    ((("outlier",), (3,)), (("periodic_axis_error",), ()), False),  # the coarse map set nothing aside
])
def test_finer_reads_the_same_outliers_known_answers(monkeypatch, finer, coarse, agree):
    monkeypatch.setattr(D, "FINER_MAP_OUTLIERS_AGREE", True)
    assert D._finer_reads_the_same_outliers(_disc(*finer), _disc(*coarse)) is agree
    monkeypatch.setattr(D, "FINER_MAP_OUTLIERS_AGREE", False)
    assert D._finer_reads_the_same_outliers(_disc(*finer), _disc(*coarse)) is False


def test_rule_is_on():
    assert D.FINER_MAP_OUTLIERS_AGREE is True


def _c6106():
    return blind_outcome(gen_c, "outlier", 6106, generator="gen_c")


@pytest.mark.slow
def test_gen_c_outlier_6106_named_outlier():
    """As shipped (FINER_MAP_OUTLIERS_AGREE on) the 22 mm map's reading (the three outliers) is reported: outlier,
    confident, the extended workpiece within the baseline's plus its U95."""
    o = _c6106()
    assert o.cause == "outlier" and o.confident and o.findings == ("outlier",), o
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


@pytest.mark.slow
def test_gen_c_outlier_6106_ripple_is_the_coarse_maps_without_the_rule(monkeypatch):
    """Without the rule (the session's blind miss): the 80 mm map's ripple, confident, beside the three outliers."""
    monkeypatch.setattr(D, "FINER_MAP_OUTLIERS_AGREE", False)
    # (session 34's ALTERNATIVES_TWO_WAY hedges this reading on its own: off, to pin the reading without this rule)
    monkeypatch.setattr(D, "ALTERNATIVES_TWO_WAY", "off")
    o = _c6106()
    assert o.cause == "periodic_axis_error" and o.confident and "outlier" in o.findings, o


def _a8907():
    return blind_outcome(gen_a, "thermal_bending", 8907, generator="gen_a")


@pytest.mark.slow
def test_gen_a_thermal_bending_8907_extended_workpiece_held():
    """Session 31's strict xfail, passing since session 32 (vif32): the hedged part_change's own shift of the
    workpiece (6.61 um RMS, real) is carried in the extended U95 (:data:`core.discover.HEDGED_SHIFT_CARRIED`,
    ``inflated``): 6.909 against 1.053 + 6.937; the name, the findings and the estimate are session 31's."""
    o = _a8907()
    assert o.cause == "unexplained" and o.findings == ("unexplained", "part_change"), o
    assert o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


@pytest.mark.slow
def test_gen_a_thermal_bending_8907_fails_without_the_hedged_shift(monkeypatch):
    """Without :data:`core.discover.HEDGED_SHIFT_CARRIED` the session 31 miss (6.909 against 1.053 + 2.114)."""
    monkeypatch.setattr(D, "HEDGED_SHIFT_CARRIED", None)
    o = _a8907()
    assert o.wp_ext_um > o.wp_base_um + o.wp_u95_um, o


@pytest.mark.slow
def test_gen_a_thermal_bending_8907_the_inflated_direction_carries_it(monkeypatch):
    """The mechanism: left out (VIF_DROP_BEYOND_MAX, off for its costs, session 28) the inflated direction takes the
    error with it (6.909 -> 1.485 um, within 1.053 + 1.951); the name does not move."""
    monkeypatch.setattr(D, "VIF_DROP_BEYOND_MAX", True)
    monkeypatch.setattr(D, "HEDGED_SHIFT_CARRIED", None)  # (the drop alone, as session 31 measured it)
    o = _a8907()
    assert o.cause == "unexplained" and o.wp_ext_um <= o.wp_base_um + o.wp_u95_um, o


@pytest.mark.slow
def test_gen_c_outlier_6106_report_says_which_map():
    """The report says the 22 mm map was taken and why: the coarse map's reading, and the same outliers alone here."""

    log, _ = gen_c.generate("outlier", 6106)
    rep = discovered(log).to_report()
    assert rep["baseline"]["grid_step_mm"] == 22.0 and rep["outlier_rows"] == [78, 103, 132], rep["baseline"]
    note = [c for c in rep["conventions"] if "the finest identifiable" in c]
    assert len(note) == 1 and "read periodic_axis_error" in note[0], rep["conventions"]
    assert "only the outliers the screen set aside on that one too" in note[0] and "nothing on this one" not in note[0]
