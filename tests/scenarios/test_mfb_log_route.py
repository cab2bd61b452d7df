"""A multi-feature bar's probe log through `vmt identify` and `vmt discover` (core.mfblog, session 37).

Closed loops: `vmt simulate mfb-3axis` writes the campaign `vmt scenario mfb-3axis` simulates for the same seed
(scenarios.mfb.run); the log read back (core.mfblog.read_mfb_log) gives the same measurements, and `vmt identify`
the same 21 errors and U95 as the scenario, to the rounding of the bar poses fitted from the log's printed
nominal columns. `vmt discover` reads `none` on an effect-free campaign and names a hidden effect
(scenarios.hidden, tuning seeds 0-999), the same reading as the in-memory path. Bad input: one line, exit 2,
nothing written.
"""

import json

import numpy as np
import pytest

from core.probelog import read_probe_log, write_probe_log
from scenarios.cli import main
from tests.cli_helpers import one_line_error, percent_counts, record_progress

#: identified and U95 of the log route against the in-memory run, um or urad. The log holds every number in
#: shortest round trip, so the touches, normals, features and gains come back bit for bit (checked below); the
#: one thing rebuilt is each set-up's nominal bar pose, a rigid fit of the nominal tip centres to the nominal
#: contact points (core.mfblog.bar_pose_W), 1e-15 m off the plan's. Through the identification that moves the
#: errors by 5e-9 um (3-axis seed 1): 1e-6 is 200 times that, and 1e-6 of the smallest U95 (0.66 um).
TOL_UM = 1e-6


@pytest.fixture(scope="module")
def run3(tmp_path_factory, mfb_seed1_runs):
    """The 3-axis scenario's run (seed 1, linear U95: ``run("mfb-3axis", seed=1, mc_runs=0)``, the session's, read
    only: tests/conftest.py mfb_seed1_runs) and its campaign written by `vmt simulate mfb-3axis`."""
    d = tmp_path_factory.mktemp("mfb3")
    path = d / "m3.csv"
    assert main(["simulate", "mfb-3axis", "--seed", "1", "--out", str(path)]) == 0
    return mfb_seed1_runs["mfb-3axis", "declared"], path


def _same_measurements(a_list, b_list):
    assert [m.name for m in a_list] == [m.name for m in b_list]
    for a, b in zip(a_list, b_list):
        assert (a.placement, a.holes, a.rot_rad, a.J_m, a.feature) == (b.placement, b.holes, b.rot_rad, b.J_m,
                                                                       b.feature)
        for k in ("O_R", "q_R", "G_A", "d_A", "n_A"):   # read back exactly: shortest round trip, the same fits
            np.testing.assert_array_equal(getattr(a, k), getattr(b, k), err_msg=f"{a.name} {k}")
        # wx_mm / 1e3 and the bar poses fitted from the nominal columns: to rounding
        np.testing.assert_allclose(b.c_A, a.c_A, rtol=0, atol=1e-15)
        np.testing.assert_allclose(b.O_A, a.O_A, rtol=0, atol=1e-15)
        np.testing.assert_allclose(b.T_W_A, a.T_W_A, rtol=0, atol=1e-13)


def test_simulated_log_reads_back_into_the_scenarios_measurements(run3):
    from core.mfblog import read_mfb_log

    r, path = run3
    ml = read_mfb_log(read_probe_log(path))
    _same_measurements(r.meas, ml.meas)
    assert ml.nodes_from == "log" and ml.touches == r.doc["touches"] == 3888
    for a in "XYZ":
        np.testing.assert_allclose(ml.nodes[a], r.plan.nodes[a], rtol=0, atol=1e-15)
    assert ml.sigma_probe_m == pytest.approx(0.125e-6, rel=1e-12, abs=0)
    np.testing.assert_allclose(ml.certificate.u_m, r.campaign["u_cal_m"], rtol=0, atol=1e-18)


def test_identify_on_the_log_gives_the_scenarios_errors_and_u95(run3, tmp_path, capsys, monkeypatch):
    r, path = run3
    out = tmp_path / "i.json"
    bars = record_progress(monkeypatch)
    assert main(["identify", str(path), "--json", str(out)]) == 0
    # the progress line counts the reading's 17 noise gains (session 38: it sat at 0/4 for them, 40 % of the run)
    from scenarios.cli.identify import MFB_IDENTIFY_SHARES

    done = percent_counts(bars[0].calls)
    fitted, read = MFB_IDENTIFY_SHARES
    assert len({d for d in done if fitted <= d <= read}) >= 15 and done[-1] == 100, done
    said = capsys.readouterr().out
    assert "multi-feature bar, 14 set-ups, 17 measurements, 3888 touches" in said and "selfcal" not in said
    doc = json.loads(out.read_text())
    assert doc["format"] == "vmt-identify-mfb/1" and doc["u95_method"] == r.doc["u95_method"]
    assert doc["estimate"]["format"] == "vmt-estimate/1"
    for s, e in r.doc["errors"].items():
        np.testing.assert_allclose(doc["errors"][s]["identified"], e["identified"], rtol=0, atol=TOL_UM, err_msg=s)
        np.testing.assert_allclose(doc["errors"][s]["u95"], e["u95"], rtol=0, atol=TOL_UM, err_msg=s)
        np.testing.assert_allclose(doc["errors"][s].get("nodes_mm", 0), e.get("nodes_mm", 0), rtol=0, atol=1e-9)
    # the injected errors recovered as the scenario recovers them (its own comparison against the truth)
    dev = max(np.max(np.abs(np.subtract(doc["errors"][s]["identified"], e["injected"])))
              for s, e in r.doc["errors"].items() if e["unit"] == "um")
    assert dev == pytest.approx(r.doc["max_dev_um"], abs=TOL_UM)
    assert doc["rms_residual_um"] == pytest.approx(r.doc["rms_residual_um"], abs=TOL_UM)


def test_identify_with_a_declared_ripple_gives_the_scenarios_u95(run3, tmp_path):
    """--declared-ripple-um-mm on an MFB log: the type B term of vmt scenario mfb-3axis --declared-ripple-um-mm (the
    same U95 to TOL_UM; the identified values do not move)."""
    from scenarios.mfb import run

    r, path = run3
    ripple = {"EXX": (0.38e-6, 0.010), "EYY": (0.2e-6, 0.010)}
    rr = run("mfb-3axis", seed=1, mc_runs=0, declared_ripple=ripple)
    out = tmp_path / "i.json"
    assert main(["identify", str(path), "--json", str(out), "--declared-ripple-um-mm", "EXX=0.38:10,EYY=0.2:10"]) == 0
    doc = json.loads(out.read_text())
    assert "declared ripple" in doc["u95_inputs"] and set(doc["declared_ripple"]) == {"EXX", "EYY"}
    for s, e in rr.doc["errors"].items():
        np.testing.assert_allclose(doc["errors"][s]["u95"], e["u95"], rtol=0, atol=TOL_UM, err_msg=s)
        np.testing.assert_allclose(doc["errors"][s]["identified"], r.doc["errors"][s]["identified"], rtol=0,
                                   atol=TOL_UM, err_msg=s)
    assert max(rr.doc["errors"]["EXX"]["u95"]) > max(r.doc["errors"]["EXX"]["u95"]) + 0.1   # the term is there


def test_the_5axis_plan_round_trip(tmp_path, mfb_seed1_runs):
    """mfb-5axis: rotary set-ups (A, C), the rotary axes' points on their line; the nodes derived from the bars
    when the log has no nodes line are the plan's. (The run is ``run("mfb-5axis", seed=1, mc_runs=0)``, the
    session's: tests/conftest.py mfb_seed1_runs, read only.)"""
    from core.mfblog import NODES_KEY, read_mfb_log
    from scenarios.mfb import campaign_log, identify_log

    r = mfb_seed1_runs["mfb-5axis", "declared"]
    path = tmp_path / "m5.csv"
    log = campaign_log(r)
    write_probe_log(path, log)
    ml = read_mfb_log(read_probe_log(path))
    _same_measurements(r.meas, ml.meas)
    doc = identify_log(ml, sigma_m=ml.sigma_probe_m)
    for s, e in r.doc["errors"].items():
        np.testing.assert_allclose(doc["errors"][s]["identified"], e["identified"], rtol=0, atol=TOL_UM, err_msg=s)
        np.testing.assert_allclose(doc["errors"][s]["u95"], e["u95"], rtol=0, atol=TOL_UM, err_msg=s)
    del log.meta[NODES_KEY]
    derived = read_mfb_log(log)
    assert derived.nodes_from == "derived"
    for a in "XYZ":
        np.testing.assert_allclose(derived.nodes[a], r.plan.nodes[a], rtol=0, atol=1e-12)


def test_derived_nodes_of_the_3axis_plan(run3):
    """Without a nodes line: per axis from the lowest to the highest nominal point of interest of the bars along
    it (reading + J), as many nodes as holes up to 9: the 3-axis plan's own (9 along X over 12 holes, 8 along Y,
    7 along Z with TYL's 100 mm longer J reaching the same top)."""
    from core.mfblog import NODES_KEY, read_mfb_log

    r, path = run3
    log = read_probe_log(path)
    del log.meta[NODES_KEY]
    ml = read_mfb_log(log)
    for a in "XYZ":
        np.testing.assert_allclose(ml.nodes[a], r.plan.nodes[a], rtol=0, atol=1e-12)


def test_discover_reads_none_on_an_effect_free_campaign(run3, tmp_path, capsys, monkeypatch):
    _, path = run3
    out = tmp_path / "d.json"
    bars = record_progress(monkeypatch)
    assert main(["discover", str(path), "--json", str(out)]) == 0
    # the progress line counts the reading's noise gains, the baseline and the search (session 38: no count at all)
    from scenarios.discover_run import MFB_DISCOVER_SHARES

    done = percent_counts(bars[0].calls)
    fitted, read, built = MFB_DISCOVER_SHARES
    assert done[0] == fitted and len({d for d in done if fitted <= d <= read}) >= 15 and done[-1] == 100, done
    assert built in done and any(built < d < 100 for d in done), done
    said = capsys.readouterr().out
    rep = json.loads(out.read_text())
    assert rep["cause"] == "none" and not rep["findings"], rep["cause"]
    assert rep["baseline"]["model"].startswith("volumetric") and "selfcal" not in said
    assert "normals out of the XY plane" not in said          # never the planar baseline on an MFB log
    assert rep["noise_um"]["cv_gap"]["ratio"] is None        # no held-out points on this plan: null, not NaN
    assert "cause      none" in said


@pytest.mark.parametrize("cause,seed", [("bar_bending", 0), ("thermal_drift", 1)])
def test_a_hidden_effect_written_out_and_read_back_reads_as_in_memory(cause, seed, tmp_path):
    """scenarios.hidden's campaign (tuning seeds) written as a log and discovered: the same baseline and reading
    as the in-memory measurements with the same times (each measurement at its touches' mean t_s), and the same
    cause as the MFB study's own path (its times i * 600 s: a drift's ppm differ by a few %, the cause not)."""
    from core.baseline import volumetric
    from core.discover import discover_baseline
    from scenarios.discover_run import mfb_log_baseline
    from scenarios.hidden import mfb_baseline, mfb_campaign, mfb_declared_noise
    from scenarios.mfb import campaign_log, default_machine

    # written as mfb_baseline calls it (below): lru_cache keys on the call as written, so ``mfb_campaign(cause,
    # seed)`` was a second entry and simulated the campaign again (session 38: about 2 s of CPU a case)
    res, _, _ = mfb_campaign(cause, seed, name="mfb-3axis", bar_cal_error=True)
    path = tmp_path / "h.csv"
    write_probe_log(path, campaign_log(res))
    bl, ml = mfb_log_baseline(read_probe_log(path))
    _same_measurements(res.meas, ml.meas)
    cfg, _ = default_machine(res.plan.machine)
    bl_m = volumetric(res.meas, cfg.chain, res.plan.nodes, dict(cfg.rotary_points_R_m), ml.times_s,
                      **mfb_declared_noise(res, True))
    assert np.array_equal(bl.rows, bl_m.rows)
    np.testing.assert_allclose(bl.y, bl_m.y, rtol=0, atol=1e-12)   # whitened rows: unit noise
    rep, rep_m = discover_baseline(bl).to_report(), discover_baseline(bl_m).to_report()
    assert rep["cause"] == rep_m["cause"] == cause
    f, f_m = rep["findings"][0], rep_m["findings"][0]
    assert f["evidence"].get("confidence") == f_m["evidence"].get("confidence") == "named"
    for k, v in f_m["params"].items():
        if isinstance(v, float):
            assert f["params"][k] == pytest.approx(v, rel=1e-6, abs=1e-9), k
    bl_h, _, _ = mfb_baseline(cause, seed)
    assert discover_baseline(bl_h).to_report()["cause"] == cause



def test_a_pose_off_its_exact_entries_by_rounding_keeps_the_baselines_rows(run3):
    """Session 38 (dup38): core.baseline.volumetric left out the mistake-proofing holes' roll rows (the model drops
    each one's component along the bar's z_A) only where they were exactly zero, which they are only when the
    pose's other entries are exactly 0 and +-1: a pose 1e-16 off them (mfbcli37: the log reader's fitted pose,
    423 rows for the in-memory 389; snapped in the reader since) kept 34 empty rows. Now found by the pose's
    structure (core.volumetric.roll_rows): every measurement's pose turned by a rounding-level rotation gives the
    same rows. Every bar of the 3-axis plan has its z_A along a W axis, so each mistake-proofing hole (1.5 mm
    off the bar's axis along y_A) loses one row: 3 x holes - mistake-proofing holes, counted here from O_A."""
    from dataclasses import replace

    from core.baseline import volumetric
    from core.kinematics import exp_so3
    from scenarios.mfb import default_machine

    r, _ = run3
    cfg, _ = default_machine(r.plan.machine)
    args = (cfg.chain, r.plan.nodes, dict(cfg.rotary_points_R_m))
    turned = []
    for i, m in enumerate(r.meas):
        T = np.array(m.T_W_A, float)
        T[:3, :3] = T[:3, :3] @ exp_so3(np.array([3e-16, -2e-16, 1e-16]) * (i + 1))  # 3.7e-16 (i + 1) rad
        assert not np.array_equal(T, m.T_W_A)
        turned.append(replace(m, T_W_A=T))
    want = sum(3 * len(m.holes) - int(np.sum(np.abs(np.asarray(m.O_A)[:, 1]) > 1e-3)) for m in r.meas)
    bl, bl_t = volumetric(r.meas, *args), volumetric(turned, *args)
    assert len(bl.rows) == len(bl_t.rows) == want == 389, (len(bl.rows), len(bl_t.rows), want)
    assert np.array_equal(bl.rows, bl_t.rows)
    # the turns, 6.3e-15 rad at most, move a point 1 m out by 6.3e-15 m: the rows (m, up to 1.5e-3) by 1.0e-15
    # (measured); 1e-12 is a thousand times that
    np.testing.assert_allclose(bl_t.y, bl.y, rtol=0, atol=1e-12)

# --------------------------------------------------------------------------- bad input: one line, exit 2
def _edited(path, tmp_path, *, drop_meta=(), drop_cols=(), rows=None, name="bad.csv"):
    from dataclasses import replace

    log = read_probe_log(path)
    meta = {k: v for k, v in log.meta.items() if k not in drop_meta}
    cols = {k: (v if rows is None else v[rows]) for k, v in log.columns.items() if k not in drop_cols}
    out = tmp_path / name
    write_probe_log(out, replace(log, meta=meta, columns=cols))
    return out


def _refused(capsys, tmp_path, argv, *words):
    out = tmp_path / "out.json"
    assert main(argv + ["--json", str(out)]) == 2
    one_line_error(capsys, *words)
    assert not out.exists()


@pytest.mark.parametrize("command", ["identify", "discover"])
def test_a_log_without_its_certificate_or_offsets_is_refused_naming_both(run3, tmp_path, capsys, command):
    from core.mfblog import BAR_E_KEY, BAR_U_KEY, STYLUS_OFFSETS_KEY

    _, path = run3
    bad = _edited(path, tmp_path, drop_meta=(BAR_E_KEY, BAR_U_KEY, STYLUS_OFFSETS_KEY))
    _refused(capsys, tmp_path, [command, str(bad)], "the bar's calibration", "--bar-calibration", STYLUS_OFFSETS_KEY)


@pytest.mark.parametrize("command", ["identify", "discover"])
def test_a_log_without_features_is_refused(run3, tmp_path, capsys, command):
    _, path = run3
    bad = _edited(path, tmp_path, drop_cols=("feature", "wnx", "wny", "wnz"))
    _refused(capsys, tmp_path, [command, str(bad)], "lacks the columns feature, wnx, wny, wnz")


def test_a_measurement_missing_its_rods_is_refused(run3, tmp_path, capsys):
    """Measurement X2 without its rods: no plane PL_i for any hole (a rod or two missing is not bad input: the
    planes take the rods there are, core.mfb._rod_pair)."""
    _, path = run3
    log = read_probe_log(path)
    rods = np.array([str(f).startswith("rod") for f in log.col("feature")])
    keep = ~((log.col("measurement") == "X2") & rods)
    bad = _edited(path, tmp_path, rows=np.flatnonzero(keep))
    _refused(capsys, tmp_path, ["identify", str(bad)], "points of interest cannot be fitted")


def test_a_truncated_log_is_refused(run3, tmp_path, capsys):
    _, path = run3
    text = path.read_text()
    cut = tmp_path / "cut.csv"
    cut.write_text(text[: len(text) // 2].rsplit(",", 3)[0])    # torn inside a row
    _refused(capsys, tmp_path, ["discover", str(cut)], "cut.csv")


def test_a_stylus_without_offsets_is_refused(run3, tmp_path, capsys):
    from core.mfblog import STYLUS_OFFSETS_KEY

    _, path = run3
    log = read_probe_log(path)
    meta = dict(log.meta)
    meta[STYLUS_OFFSETS_KEY] = "; ".join(p for p in meta[STYLUS_OFFSETS_KEY].split("; ") if not p.startswith("TXF="))
    from dataclasses import replace

    bad = tmp_path / "nostylus.csv"
    write_probe_log(bad, replace(log, meta=meta))
    _refused(capsys, tmp_path, ["identify", str(bad)], "stylus 'TXF' has no offsets")


@pytest.mark.parametrize("argv,words", [
    (["identify", "{log}", "--grid-mm", "30"], ("--grid-mm", "multi-feature bar")),
    (["identify", "{log}", "--delta-l-um", "2"], ("--delta-l-um", "multi-feature bar")),
    (["discover", "{log}", "--grid-mm", "30"], ("--grid-mm", "multi-feature bar")),
    (["identify", "{log}", "--tool-offset-mm", "0,0,150"], ("--tool-offset-mm", "stylus")),
])
def test_planar_options_on_an_mfb_log_are_refused(run3, tmp_path, capsys, argv, words):
    _, path = run3
    _refused(capsys, tmp_path, [a.format(log=path) for a in argv], *words)


def test_bar_calibration_on_a_planar_log_is_refused(tmp_path, capsys):
    log = tmp_path / "cp.csv"
    assert main(["simulate", "cross-pocket", "--out", str(log), "--seed", "1"]) == 0
    capsys.readouterr()
    cal = tmp_path / "cal.json"
    cal.write_text("{}")
    for command in ("identify", "discover"):
        _refused(capsys, tmp_path, [command, str(log), "--bar-calibration", str(cal)], "--bar-calibration",
                 "not a multi-feature bar's log")


def test_the_catalogs_mfb_log_is_refused_never_read_as_planar(tmp_path, capsys):
    """`vmt simulate mfb` (the catalogue's 17 flat placements, one stylus) writes no probe offsets and no
    certificate: refused naming both; given them, its bars all lie along X (no Y or Z table): refused so."""
    log = tmp_path / "m.csv"
    assert main(["simulate", "mfb", "--out", str(log)]) == 0
    capsys.readouterr()
    _refused(capsys, tmp_path, ["discover", str(log)], "probe offsets J", "the bar's calibration")
    from core.mfb import MFB
    from core.mfblog import TOOL_OFFSET_KEY, certificate_lines

    src = read_probe_log(log)
    from dataclasses import replace

    given = tmp_path / "m2.csv"
    write_probe_log(given, replace(src, meta={**src.meta, TOOL_OFFSET_KEY: "0,0,150",
                                              **certificate_lines(np.zeros((MFB.n_holes, 3)),
                                                                  np.full((MFB.n_holes, 3), 0.2e-6))}))
    _refused(capsys, tmp_path, ["identify", str(given)], "no bar lies along Y")
