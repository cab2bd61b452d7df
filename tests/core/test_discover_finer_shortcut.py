"""The finer-map check's shortcut (core.discover.FINER_MAP_SHORTCUT): the search on the finest identifiable map is
not run, or stopped after its first step, where the check is known beforehand to keep the coarse map's reading;
the report is the same, byte for byte, as with the search run to its end (session 37, fast37).

Each "fires" test sees the shortcut decide and the same report with it off; the "does not fire" tests see the
search run to its end where its answer is taken, or asked to. Campaigns: gen_c periodic_axis_error 200 (a 5-14 mm
ripple on BIC's 80 mm grid: the 22 mm map shows structure on every row, so it cannot read none), gen_b c_drift
1000 (the 22 mm map reads none only at 5.7 times the coarse map's workpiece U95, FINER_MAP_U95_RATIO 2: known
from the baseline alone), gen_c none 220 (the 22 mm map reads none and is taken: nothing may stop it).
"""

import json

import core.discover as D
from scenarios.blind import gen_b, gen_c
from tests.discover_helpers import discovered


def _searches(monkeypatch):
    """Each discover_baseline call as (grid mm, 'stopped' or its discovery)."""
    seen = []
    run = D.discover_baseline

    def counted(bl, **kw):
        try:
            d = run(bl, **kw)
        except D._NoneImpossible:
            seen.append((bl.info["grid_step_mm"], "stopped"))
            raise
        seen.append((bl.info["grid_step_mm"], d))
        return d

    monkeypatch.setattr(D, "discover_baseline", counted)
    return seen


def _read(seen):
    return [(g, d if isinstance(d, str) else d.cause) for g, d in seen]


def _report(d) -> str:
    return json.dumps(d.to_report(), sort_keys=True, default=str)


def test_structure_on_every_row_stops_the_finer_search_and_changes_nothing(monkeypatch):
    log, _ = gen_c.generate("periodic_axis_error", 200)
    seen = _searches(monkeypatch)
    on = discovered(log)
    assert _read(seen) == [(80.0, "periodic_axis_error"), (22.0, "stopped")]
    assert on.cause == "periodic_axis_error" and not on.outlier_rows
    monkeypatch.setattr(D, "FINER_MAP_SHORTCUT", False)
    seen.clear()
    off = discovered(log)
    # run to its end, the 22 mm search reads something (structure present on every row: never none)
    assert [g for g, _ in seen] == [80.0, 22.0] and seen[1][1].cause != "none"
    assert seen[1][1].structure["baseline"]["present"] and not seen[1][1].outlier_rows
    assert _report(on) == _report(off)


def test_a_finer_u95_beyond_the_ratio_is_known_before_the_search(monkeypatch):
    log, _ = gen_b.generate("c_drift", 1000)
    seen = _searches(monkeypatch)
    on = discovered(log)
    assert _read(seen) == [(55.0, "unexplained")]  # the 22 mm map not searched at all
    monkeypatch.setattr(D, "FINER_MAP_SHORTCUT", False)
    seen.clear()
    off = discovered(log)
    assert _read(seen) == [(55.0, "unexplained"), (22.0, "none")]
    df = seen[1][1]
    # the U95 the shortcut computes from the baseline alone is the one the finer report carries, to the bit, and it
    # fails the ratio (5.7 times the coarse map's)
    assert D._baseline_u95_rms(df.baseline) == D._u95_rms(df)
    assert D._u95_rms(df) > 5 * D._u95_rms(off)
    assert _report(on) == _report(off)


def test_a_finer_map_that_reads_none_is_searched_to_its_end(monkeypatch):
    log, _ = gen_c.generate("none", 220)
    seen = _searches(monkeypatch)
    d = discovered(log)
    assert _read(seen) == [(80.0, "unexplained"), (22.0, "none")] and d is seen[1][1]


def test_no_stop_asked_where_the_coarse_map_set_touches_aside(monkeypatch):
    # a finer map reading only the coarse map's outliers is taken too (FINER_MAP_OUTLIERS_AGREE): structure on every
    # row does not exclude that reading, so the search is not asked to stop; with the agreement off it is
    asked = []
    monkeypatch.setattr(D, "discover_baseline", lambda bl, **kw: asked.append(kw["stop_unless_none_possible"]))

    class Stub:
        A = None  # (not a dense design: the U95 precondition is not computed)

    for rows, agree in (((3,), True), ((), True), ((3,), False)):
        monkeypatch.setattr(D, "FINER_MAP_OUTLIERS_AGREE", agree)
        D._finer_map_search(Stub(), type("d", (), {"outlier_rows": rows})(), D.Settings(), None, 1.0)
    assert asked == [False, True, True]
    monkeypatch.setattr(D, "FINER_MAP_SHORTCUT", False)
    D._finer_map_search(Stub(), type("d", (), {"outlier_rows": ()})(), D.Settings(), None, 1.0)
    assert asked[-1] is False


def test_a_coarse_map_without_a_finite_u95_skips_the_check():
    # no finer discovery passes `u95 <= ratio * nan`: the check returns d before making the finer baseline
    d = type("d", (), {"cov_G_baseline": None, "baseline": None})()
    assert D._finer_map_check(d, None, D.Settings(), "", None, None) is d
