"""What ``vmt discover`` prints: a finding's +- is said to be its U95, and the workpiece's U95 before
and after the extension is printed beside the gain (the report's figures, read by hand here)."""

import pytest

from scenarios.cli.discover import summary_lines


def _report(workpiece, identifiable=True, u95=0.25):
    return {
        "baseline": {"model": "m", "rms_um": 1.0, "n": 10, "n_params": 3},
        "baseline_cv_rms_um": 1.5,
        "noise_um": {"sigma_um": 0.3, "method": "repeats",
                     "cv_gap": {"ratio": 2.0, "expected_ratio": 2.0, "p_value": 0.5}},
        "diagnosis": [],
        "findings": [{"cause": "periodic_axis_error", "params": {"axis": "X", "period_mm": 8.0},
                      "params_u95": {"period_mm": u95}, "evidence": {"confidence": "named"}}],
        "gain": {"rms_ratio": 0.5, "cv_rms_ratio": 0.4},
        "extended": {"model": "m + periodic_axis_error", "rms_um": 0.5, "cv_rms_um": 0.6},
        "workpiece": workpiece, "workpiece_identifiable": identifiable,
    }


WP = [{"target": "a", "baseline_um": 1.0, "extended_um": 1.5, "baseline_u95_um": 2.0, "extended_u95_um": 0.75},
      {"target": "b", "baseline_um": -1.0, "extended_um": -3.0, "baseline_u95_um": 1.0, "extended_u95_um": 1.25}]


def test_finding_says_its_plus_minus_is_u95():
    lines = summary_lines(_report(WP))
    f = next(ln for ln in lines if ln.startswith("finding"))
    assert f == "finding    periodic_axis_error: axis X, period_mm 8 +- 0.25 (value +- U95, k = 2)"


def test_no_u95_label_without_an_uncertainty():
    f = next(ln for ln in summary_lines(_report(WP, u95=None)) if ln.startswith("finding"))
    assert f == "finding    periodic_axis_error: axis X, period_mm 8"


def test_workpiece_u95_before_and_after():
    # U95 max: baseline max(2.0, 1.0) = 2.0, extended max(0.75, 1.25) = 1.25; the largest change is b's
    # -3.0 - (-1.0) = -2.0 (a's is +0.5)
    w = [ln for ln in summary_lines(_report(WP)) if ln.startswith("workpiece")]
    # (without the U95 of the form in the report, the largest per-target U95, said to be in the map's gauge: session 36)
    assert w == ["workpiece  U95 max 2.000 -> 1.250 um (baseline -> extended, 2 targets, in the map's gauge); "
                 "largest change -2.000 um at b (in the gauge: shift, rotation and scale included)"]
    # with the form's change in the report (vmt discover writes it), that is what is printed
    rep = _report(WP)
    rep["workpiece_form_change"] = {"max_abs_um": 0.04, "value_um": -0.04, "target": "a", "raw_max_abs_um": 2.0,
                                    "targets": 2, "heights": False, "what": "..."}
    w = [ln for ln in summary_lines(rep) if ln.startswith("workpiece")]
    assert w == ["workpiece  U95 max 2.000 -> 1.250 um (baseline -> extended, 2 targets, in the map's gauge); "
                 "largest change of the form"
                 " -0.040 um at a (the part's shift, rotation, scale, offset removed; 2.000 um at most per target in"
                 " the gauge)"]


def test_workpiece_line_when_not_identifiable_or_nothing_found():
    nulls = [{k: (v if k == "target" else None) for k, v in r.items()} for r in WP]
    assert [ln for ln in summary_lines(_report(nulls, identifiable=False)) if ln.startswith("workpiece")] == \
        ["workpiece  not identifiable by this design (reported as null)"]
    rep = _report(WP)
    rep["findings"] = []
    assert not [ln for ln in summary_lines(rep) if ln.startswith("workpiece")]


def test_u95_label_only_when_a_printed_parameter_has_one():
    """Only the first 6 parameters are printed; main said '(value +- U95, k = 2)' when only a 7th,
    unprinted one had a U95 (no printed value carried a +-)."""
    rep = _report(WP)
    rep["findings"][0]["params"] = {f"p{i}": float(i) for i in range(7)}
    rep["findings"][0]["params_u95"] = {"p6": 0.5}
    f = next(ln for ln in summary_lines(rep) if ln.startswith("finding"))
    assert f == "finding    periodic_axis_error: p0 0, p1 1, p2 2, p3 3, p4 4, p5 5"
    rep["findings"][0]["params_u95"] = {"p5": 0.5}
    f = next(ln for ln in summary_lines(rep) if ln.startswith("finding"))
    assert f.endswith("p5 5 +- 0.5 (value +- U95, k = 2)")


def test_a_fixed_parameter_and_an_undetermined_phase_are_said_so():
    """audit35 N1, N2: a drift's ``over_h`` (the campaign's duration, context: its params_u95 0.0) was printed
    "over_h 0.924 +- 0" as if fitted; a phase whose U95 the report withholds (it reaches half the circle, beside an
    amplitude consistent with zero) was printed bare, "EYX_phase_rad -1.96", read as a measurement. A phase with
    its U95 keeps it. The report page's magnitudes table says the same (scenarios.reports._magnitude_rows)."""
    from scenarios.reports import _magnitude_rows

    rep = _report(WP)
    rep["findings"] = [
        {"cause": "thermal_drift", "params": {"x_offset_change_um": 2.34, "over_h": 0.924},
         "params_u95": {"x_offset_change_um": 0.5, "over_h": 0.0}, "evidence": {"confidence": "named"}},
        {"cause": "periodic_axis_error", "params": {"axis": "X", "EXX_phase_rad": 0.0463, "EYX_phase_rad": -1.96},
         "params_u95": {"axis": None, "EXX_phase_rad": 0.19, "EYX_phase_rad": None}, "evidence": {}}]
    f = [ln for ln in summary_lines(rep) if ln.startswith("finding")]
    assert f == ["finding    thermal_drift: x_offset_change_um 2.34 +- 0.5, over_h 0.924 h (fixed) (value +- U95, k = 2)",
                 "finding    periodic_axis_error: axis X, EXX_phase_rad 0.0463 +- 0.19, EYX_phase_rad n/d (U95 reaches "
                 "half the circle) (value +- U95, k = 2)"]
    assert _magnitude_rows(rep, "planar") == [r + [""] for r in [   # (the fifth column: a note, none here)
        ["thermal_drift", "x_offset_change_um", 2.34, 0.5], ["thermal_drift", "over_h", "0.924 h", "fixed"],
        ["periodic_axis_error", "axis", "X", None], ["periodic_axis_error", "EXX_phase_rad", 0.0463, 0.19],
        ["periodic_axis_error", "EYX_phase_rad", "n/d", "reaches half the circle"]]]


def test_an_iso230_2_test_says_deviation_not_workpiece():
    """On an ISO 230-2 log the estimand is the mean deviation per target and direction (ids such as
    'P=-295mm-'), not a workpiece: main printed 'workpiece  U95 max ... 22 targets'."""
    w = [ln for ln in summary_lines(_report(WP), "positioning") if ln.startswith(("workpiece", "deviation"))]
    assert w == ["deviation  U95 max 2.000 -> 1.250 um (baseline -> extended, 2 means per target and direction); "
                 "largest change -2.000 um at b"]
    nulls = [{k: (v if k == "target" else None) for k, v in r.items()} for r in WP]
    assert [ln for ln in summary_lines(_report(nulls, identifiable=False), "positioning")
            if ln.startswith(("workpiece", "deviation"))] == \
        ["deviation  not identifiable by this design (reported as null)"]


def test_vmt_discover_on_a_positioning_log_words_its_estimand(tmp_path, capsys):
    """The command itself: a simulated ISO 230-2 test with a drift (seed 2801, a development seed)."""
    from scenarios.cli import main

    log = tmp_path / "p.csv"
    assert main(["simulate", "positioning", "--out", str(log), "--seed", "2801", "--drift-um-per-h", "20"]) == 0
    capsys.readouterr()
    assert main(["discover", str(log), "--json", str(tmp_path / "d.json")]) == 0
    out = capsys.readouterr().out
    assert "finding    thermal_drift" in out, out
    assert "\ndeviation  U95 max " in out and "means per target and direction" in out and "workpiece" not in out


def test_discover_command_lets_the_probe_log_go_before_the_search(monkeypatch, tmp_path):
    """``vmt discover`` of a probe log hands the search the touches, the chain and the extra columns, and holds
    the log itself no longer (its columns were 152 MiB through the search at the bench's 1e6 rows): the log
    read is collected by the time discover runs, and discover gets what it got from it."""
    import gc
    import weakref

    import numpy as np

    import core.discover as X
    import core.probelog as P
    from core.baseline import extra_columns
    from core.touches import from_log
    from scenarios.bench.probelog import large_log
    from scenarios.cli import discover as C

    base = large_log(20, 4, np.random.default_rng(1))
    cols = dict(base.columns)
    cols["spindle_load"] = np.linspace(0.0, 1.0, base.n)  # an extra numeric column: a covariate of its own
    path = tmp_path / "log.csv"
    chain = "V[w-X-Y-b-Z-(C)-t]"    # a chain, passed on (the reader refuses one that is not, audit37)
    P.write_probe_log(path, P.make_log(cols, {**base.meta, "kinematic_chain": chain}, validate=False))
    read, refs, seen = P.read_probe_log, [], []

    def reading(p, **kw):   # (the CLI's reader, scenarios.cli.reading, passes its progress)
        log = read(p, **kw)
        refs.append(weakref.ref(log))
        return log

    def search(t, **kw):
        gc.collect()
        seen.append((refs[0]() is None, t, kw))
        return "found"

    monkeypatch.setattr(P, "read_probe_log", reading)
    monkeypatch.setattr(X, "discover", search)
    assert C._discover_probe_log(path, 5.0, None) == "found"
    (gone, t, kw), = seen
    assert gone, "the probe log is still held while discover runs"
    log = read(path)
    ref = extra_columns(log, from_log(log).row)
    assert t.n == log.n and kw["chain"] == chain and kw["grid_step_mm"] == 5.0 and list(kw["extra"]) == ["spindle_load"]
    assert all(np.array_equal(kw["extra"][k], ref[k]) for k in ref)


def test_discover_command_lets_the_touches_go_before_the_search(monkeypatch, tmp_path):
    """``vmt discover`` of a probe log: once the planar baseline is built, the search runs with no touches alive
    but the baseline's own, which hold neither the measured tip centres nor the part-frame normals
    (core.baseline.PLANAR_TOUCHES_DROPPED: read only while the baseline is built; 46 MiB at the bench's 1e6 rows,
    held through the search by the command's and discover's frames before). Known answer: the baseline is the
    one built from the whole touches (the same observations, design columns and workpiece geometry)."""
    import gc

    import numpy as np

    import core.baseline as Bm
    import core.discover as X
    import core.probelog as P
    from core.touches import Touches, from_log
    from scenarios.bench.probelog import large_log
    from scenarios.cli import discover as C

    path = tmp_path / "log.csv"
    P.write_probe_log(path, large_log(20, 4, np.random.default_rng(1)))
    seen = []

    # touches other tests of this worker keep (module caches) are not this command's: held here so their ids stay
    # theirs, and left out of the count
    gc.collect()
    earlier = [o for o in gc.get_objects() if isinstance(o, Touches)]
    earlier_ids = {id(o) for o in earlier}

    def search(bl, **kw):
        gc.collect()
        alive = [o for o in gc.get_objects() if isinstance(o, Touches) and id(o) not in earlier_ids]
        seen.append((bl, alive))
        return "found"

    monkeypatch.setattr(X, "discover_baseline", search)
    assert C._discover_probe_log(path, 30.0, None) == "found"
    (bl, alive), = seen
    assert len(alive) == 1 and alive[0] is bl.data.touches, f"{len(alive)} touches of this log alive while the search runs"
    del earlier
    with pytest.raises(ValueError, match="no measured tip centres"):
        bl.data.touches.dq_m
    assert all(getattr(bl.data.touches, k) is None for k in Bm.PLANAR_TOUCHES_DROPPED)
    t = from_log(P.read_probe_log(path))
    ref = Bm.planar(t, 30.0)
    assert np.array_equal(bl.y, ref.y) and np.array_equal(bl.y, t.dq_m)
    assert all(np.array_equal(a, b) for a, b in zip(bl.geometry, ref.geometry))
    assert np.array_equal(bl.A.toarray() if hasattr(bl.A, "toarray") else bl.A,
                          ref.A.toarray() if hasattr(ref.A, "toarray") else ref.A)
    assert np.array_equal(bl.data.touches.pn_R, t.pn_R) and np.array_equal(bl.data.touches.d_R, t.d_R)


def test_the_form_change_is_of_the_form_not_the_gauge(tmp_path, capsys):
    """Review 27 fault 3: a drift run's 'largest change' was a shift/scale of the part (the gauge), not form.
    Known answer: a simulated cross pocket with a drift that discover names; the form change the CLI prints is
    the extended-minus-baseline workpiece with core.selfcal.workpiece_form's span removed, recomputed here from
    the log's own wx/wy/wnx/wny/wz columns (an independent route to the geometry), and it is much smaller than
    the change per target in the gauge."""
    import json

    import numpy as np

    from core.probelog import read_probe_log
    from core.selfcal import workpiece_form
    from scenarios.cli import main

    log, out = drift_log(tmp_path), tmp_path / "d.json"
    capsys.readouterr()
    assert main(["discover", str(log), "--json", str(out)]) == 0
    said = capsys.readouterr().out
    rep = json.loads(out.read_text())
    fc = rep["workpiece_form_change"]
    lg = read_probe_log(log)
    first = {}
    for i, tg in enumerate(lg.col("target")):
        first.setdefault(tg, i)
    ids = [w["target"] for w in rep["workpiece"]]
    ix = np.array([first[k] for k in ids])
    P = np.column_stack([lg.col("wx_mm")[ix], lg.col("wy_mm")[ix]]) * 1e-3
    N = np.column_stack([lg.col("wnx")[ix], lg.col("wny")[ix]])
    z = lg.col("Z_mm")[ix]   # the probing height (R), as the baseline's levels
    zr = np.round(z * 1e-3, 6)
    lv, cnt = np.unique(zr, return_counts=True)
    dz = zr - lv[np.argmax(cnt)]
    g = np.array([w["extended_um"] - w["baseline_um"] for w in rep["workpiece"]])
    f = workpiece_form(g, P, N, dz if np.any(dz != 0) else None)
    j = int(np.argmax(np.abs(f)))
    # 1e-9 um: the JSON's and the engine's doubles differ only by the report's rounding (none for these keys)
    assert fc["target"] == ids[j] and abs(fc["value_um"] - f[j]) < 1e-9
    assert abs(fc["raw_max_abs_um"] - np.abs(g).max()) < 1e-9
    assert fc["max_abs_um"] < 0.5 * fc["raw_max_abs_um"]     # the drift moved the gauge, not (much) the form
    line = next(ln for ln in said.splitlines() if ln.startswith("workpiece"))
    assert f"largest change of the form {fc['value_um']:+.3f} um at {fc['target']}" in line
    # the drift's campaign duration is context, printed with its unit and "(fixed)", not "+- 0" (audit35 N2)
    drift = next(f for f in rep["findings"] if f["cause"] == "thermal_drift")
    finding = next(ln for ln in said.splitlines() if ln.startswith("finding    thermal_drift"))
    assert f"over_h {drift['params']['over_h']:.3g} h (fixed)" in finding and "+- 0," not in finding + ","


def drift_log(tmp_path):
    """A perfect nmv3000's cross-pocket log (seed 1001) with a thermal drift of X written into it (review 27's
    drift_probe.py): time stretched x10, X reading 3 um/h x t more; ``tmp_path / "drift.csv"``, beside the
    clean log ``clean.csv``."""
    from scenarios.cli import main

    clean, log = tmp_path / "clean.csv", tmp_path / "drift.csv"
    assert main(["simulate", "cross-pocket", "--machine", "nmv3000", "--errors", "none", "--out", str(clean),
                 "--seed", "1001"]) == 0
    lines = clean.read_text().splitlines()
    h = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    cols = lines[h].split(",")
    it, ix = cols.index("t_s"), cols.index("X_mm")
    body = []
    for ln in lines[h + 1:]:
        f = ln.split(",")
        t = float(f[it]) * 10
        f[it], f[ix] = repr(t), repr(float(f[ix]) + 3.0 * t / 3600 / 1000)
        body.append(",".join(f))
    log.write_text("\n".join(lines[:h + 1] + body) + "\n")
    return log


def test_a_printed_diagnosis_not_counted_as_structure_says_why(tmp_path):
    """review30c's screw_saw-312 (its generator's 12.38 mm sawtooth on X, under 1 sigma visible): the CLI printed
    "residuals follow the x position periodically (period 12.4 mm): 0.16 um, p = 0.0012" and then "none: the baseline
    explains the data within the probing noise", the page "the residuals show no structure". The line is
    significant at its family's level (0.0025) but its explained RMS, 0.152 um, is below the materiality 0.3 x the
    0.533 um noise: said under the line and on the page, the verdict unchanged. Fails before (no such words).
    (0.158 and 0.546 um before rank30's PRECISION_RANK, session 30: the baseline's numerically empty directions,
    made of the file's rounding, are no longer counted as parameters, so the noise's degrees of freedom grow.)"""
    import gzip
    import json
    from pathlib import Path

    from scenarios.cli.discover import run_discover
    from scenarios.reports import _not_counted_note, _verdict

    log = tmp_path / "screw_saw-312.csv"
    log.write_bytes(gzip.decompress((Path(__file__).parents[1] / "core/data/review30c/screw_saw-312.csv.gz")
                                    .read_bytes()))
    rep = run_discover(str(log), str(tmp_path / "r.json"), None, None)
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["cause"] == "none"
    nc = rep["structure"]["baseline"]["not_counted"]
    assert [w["covariate"] for w in nc] == ["x_periodic"] and nc[0]["reason"] == "below_materiality"
    assert nc[0]["explained_rms_um"] < nc[0]["materiality_um"] == pytest.approx(0.3 * rep["noise_um"]["sigma_um"])
    lines = summary_lines(rep)
    i = next(i for i, ln in enumerate(lines) if ln.startswith("diagnosis") and "periodically" in ln)
    assert lines[i + 1].strip().startswith("(significant but below materiality (0.152 um < 0.3 x 0.533 um noise")
    assert "no structure" not in _verdict(rep) and "below materiality" in _verdict(rep)
    assert "x_periodic: significant but below materiality" in _not_counted_note(rep)


def test_not_counted_words_of_a_report_without_them():
    """A report from before (no ``not_counted``) prints as it did."""
    from core.discover import not_counted_words

    assert not_counted_words({}) == {} and not_counted_words({"structure": {"baseline": {}}}) == {}



def test_touches_left_out_of_the_planar_baseline_are_said():
    """The planar baseline leaves out touches with normals out of the XY plane (review30c: 36 of 456 rows, a
    spindle Z growth undetectable by design); before, only the JSON's conventions said so. Fails before (no line)."""
    from core.discover import LEFT_OUT_NOTE

    rep = _report(WP)
    assert not any(ln.startswith("left out") for ln in summary_lines(rep))
    rep["conventions"] = ["EXX(x=0mm)=0", f"36 touches {LEFT_OUT_NOTE}"]
    line = next(ln for ln in summary_lines(rep) if ln.startswith("left out"))
    assert line.startswith("left out   36 touches with normals out of the XY plane") and "Z growth" in line


def test_why_not_counted_names_each_reason():
    """core.discover._why_not_counted on made-up diagnoses (known answers): p not below alpha_family (0.0025), and
    below the materiality by its own columns (0.1 um < 0.3 x 0.5 um = 0.15 um)."""
    from core.diagnosis import Diagnosis
    from core.discover import Settings, _why_not_counted
    from core.units import UM

    s = Settings()
    d = Diagnosis("time", 0.3, 0.004, 0.001, 3, "residuals follow time: 0.3 µm, p = 0.004", True)
    w = _why_not_counted(d, 5, 100, 0.5 * UM, s)
    assert w["reason"] == "not_significant" and w["alpha_family"] == pytest.approx(0.0025)
    assert w["text"].startswith("p not below 0.0025")
    d = Diagnosis("x", 0.1, 1e-4, 1e-5, 3, "residuals follow x: 0.1 µm, p = 1e-4", False)
    w = _why_not_counted(d, 5, 100, 0.5 * UM, s)
    assert w["reason"] == "below_materiality" and w["materiality_um"] == pytest.approx(0.15)
    assert w["text"] == ("significant but below materiality (0.1 um < 0.3 x 0.5 um noise = 0.15 um): not counted as "
                         "structure")
