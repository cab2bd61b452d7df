"""The MFB budget's long Monte Carlo (issue 16 item 3): its draws, the resumable study, the stored
1,000-run studies of the 3-axis and 5-axis plans and their tables in docs/papers-mfb.md recomputed
from them, the 5-axis budget checked against the truth and hand values."""

from pathlib import Path

import numpy as np
import pytest

from scenarios import mfb as S

ROOT = Path(__file__).resolve().parents[2]


def test_budget_draws_attempt_alone_equals_the_sequence():
    # attempt j's draw does not depend on how many were drawn (a study resumes or splits anywhere),
    # and it is the draw budget() made in its loop: T then the phase from default_rng(seed + 1000)
    d = S.budget_draws(1, 40)
    assert np.array_equal(S.budget_draws(1, 7), d[:7])
    rng = np.random.default_rng(1001)
    first = [(rng.uniform(19.0, 22.0), rng.uniform(0.0, 2.0 * np.pi)) for _ in range(3)]
    assert np.array_equal(d[:3], np.array(first))
    assert d[:, 0].min() >= 19.0 and d[:, 0].max() <= 22.0 and d[:, 1].min() >= 0 and d[:, 1].max() <= 2 * np.pi
    assert not np.array_equal(S.budget_draws(2, 7), d[:7])


def _fake_pipeline(monkeypatch, n=6, lose=(3,)):
    """budget_shares / budget_run replaced by cheap stand-ins (the driver's logic alone)."""
    calls = []
    sl = {"EXX": (0, 3), "EC0Y": (3, 4)}
    shares = {"U": {s: np.full(n, 1e-6 * (k + 1)) for k, s in enumerate(S.BUDGET_SOURCES)},
              "U_temp": np.full(n, 2e-6), "sens": {"bar temperature": np.full(n, 1e-7),
                                                   "machine temperature": np.full(n, -3e-6)},
              "keep": np.array([False, True, True, True, False, False]), "t_rms": 1.0, "slices": sl,
              "stylus_runs": 2}

    def run(name, j, **kw):
        calls.append(j)
        T, ph = S.budget_draws(kw.get("seed", 1), j)[j - 1]
        if j in lose:
            return {"j": j, "T_C": T, "phase_rad": ph, "lost": f"measurement 'X1': run {j} lost"}
        e = np.random.default_rng(j).normal(0, 1e-6, n)
        return {"j": j, "T_C": T, "phase_rad": ph, "error": e, "U95_lin": np.full(n, 1.5e-6)}

    monkeypatch.setattr(S, "budget_shares", lambda name, **kw: shares)
    monkeypatch.setattr(S, "budget_run", run)
    return calls, shares


def test_budget_study_resumes_without_recomputing_and_keeps_the_order(tmp_path, monkeypatch):
    calls, shares = _fake_pipeline(monkeypatch)
    st = S.budget_study("mfb-3axis", tmp_path, 4, chunk=2)
    assert int(st["ok"].sum()) == 4 and list(st["ok"]) == [True, True, False, True, True]
    assert st["lost"] == [(3, "measurement 'X1': run 3 lost")]
    n_calls = len(calls)
    # interrupted: run 2's file lost (a run in progress is never half written: atomic rename)
    (tmp_path / "run-00002.npz").unlink()
    part = S.study_arrays(tmp_path)
    assert len(part["ok"]) == 1  # the complete prefix only
    st2 = S.budget_study("mfb-3axis", tmp_path, 4, chunk=2)
    assert calls[n_calls:] == [2]  # only the missing run
    assert np.array_equal(st2["error"], st["error"]) and np.array_equal(st2["T_C"], st["T_C"])
    # more runs later: the first four are kept, the next attempts added in order
    st3 = S.budget_study("mfb-3axis", tmp_path, 6, chunk=2)
    assert int(st3["ok"].sum()) >= 6 and np.array_equal(st3["error"][:4], st["error"])
    # the stored study: its report is the budget's summary of the same vectors
    rep = S.assemble_study(tmp_path, tmp_path / "study.npz", 6)
    ref = S.budget_summary("mfb-3axis", shares, st3["error"][:6], st3["U95_lin"][:6].astype(np.float32),
                           runs_lost=[{"seed": 4, "error": "measurement 'X1': run 3 lost"}], runs_drawn=7)
    assert {k: {f: c[f] for f in ref["per_error"][k]} for k, c in rep["per_error"].items()} == ref["per_error"]
    assert rep["coverage"]["within_quadrature_U95"] == ref["coverage"]["within_quadrature_U95"]
    assert rep["runs_drawn"] == 7 and rep["mc_runs"] == 6
    assert 0.0 <= rep["stability"]["within_2_se"] <= 1.0


def test_study_report_stability_and_percentiles_known_answer(tmp_path, monkeypatch):
    # errors of a known spread: 2 x RMS -> 2 sigma, the 95th percentile of |e| -> 1.96 sigma, and two
    # halves of one normal population agree within 2 standard errors for about 95 % of the parameters
    _, shares = _fake_pipeline(monkeypatch, n=400, lose=())
    shares["keep"] = np.ones(400, bool)
    shares["slices"] = {"EXX": (0, 400)}
    rng = np.random.default_rng(4)
    err = rng.normal(0, 1e-6, (2000, 400))
    S._npz_atomic(tmp_path / "s.npz", name=np.array("mfb-3axis"), seed=1, attempt_T_C=np.full(2000, 20.5),
                  attempt_phase_rad=np.zeros(2000), attempt_ok=np.ones(2000, bool), attempt_cpu_s=np.ones(2000),
                  error=err, U95_lin=np.full((2000, 400), 2e-6, np.float32), lost_j=np.zeros(0, int),
                  lost_message=np.zeros(0, str), keep=shares["keep"], U_temp=shares["U_temp"],
                  t_rms=1.0, stylus_runs=2, slices=np.array([("EXX", 0, 400)], object),
                  **{f"U:{s}": np.full(400, 1e-7) for s in S.BUDGET_SOURCES},
                  **{f"sens:{s}": v[:1].repeat(400) for s, v in shares["sens"].items()})
    rep = S.study_report(tmp_path / "s.npz")
    mc = 2.0 * np.sqrt(np.mean(err ** 2, axis=0))
    assert rep["per_error"]["EXX"]["mc"] == pytest.approx(mc.max() * 1e6)
    assert 1.9 < rep["per_error"]["EXX"]["mc_percentile"] / 1.0 < 2.15
    assert 0.9 < rep["stability"]["within_2_se"] <= 1.0 and 0.55 < rep["stability"]["within_1_se"] < 0.8
    assert rep["temperature_draws"]["mean_C"] == 20.5


@pytest.mark.parametrize("name, heading", [
    pytest.param("mfb-3axis", "## Uncertainty budget (item 3): {n:,} runs through the pipeline"),
    pytest.param("mfb-5axis", "## Uncertainty budget of the 5-axis plan: {n:,} runs through the pipeline"),
])
def test_stored_study_is_this_pipeline_and_the_doc_table_is_its_summary(name, heading, monkeypatch):
    # run 1 of the stored study recomputed now (one pipeline run) equals the stored vector: the
    # study was made by this code (to 1e-9 relative: runs made before and after the speed-ups
    # agree to 1.1e-12; the dense normal matrix of core.lsq moves the last bits). The stored studies are
    # of model (3)'s linear extraction gain (made before session 32's exact extraction, not made again:
    # 2 x 1,000 pipeline runs; the 200-run study of docs/papers-mfb.md, "The exact extraction in vmt", found
    # bias, spread and coverage unchanged), so run 1 is recomputed with (3); with (3') it moves by 5.5e-7 m.
    from core import volumetric as vol

    # The model-error share (MFB_MODEL_ERROR_SHARE, on since session 34) as the file says its runs were made:
    # both studies made again with it in session 34 (key model_error_share True; the 3-axis study's run 1 is one
    # the share widens, x 1.28 over the nodes' median; the 5-axis study's run 1 is behind a closed gate). A file
    # without the key was made before session 34, with the share off. The errors are the same either way.
    monkeypatch.setattr(vol, "EXACT_EXTRACTION", False)
    study = ROOT / "scenarios" / "data" / f"{name}-budget-study.npz"
    with np.load(study) as z:
        err, ok = z["error"], z["attempt_ok"]
        assert len(err) == 1000 and ok.sum() == len(err) and str(z["name"]) == name
        first = int(np.flatnonzero(ok)[0]) + 1
        e0 = err[0]
        with_share = bool(z["model_error_share"]) if "model_error_share" in z.files else False
    assert with_share
    monkeypatch.setattr(S, "MFB_MODEL_ERROR_SHARE", with_share)
    r = S.budget_run(name, first)
    assert np.abs(r["error"] - e0).max() <= 1e-9 * np.abs(e0).max()
    rep = S.study_report(study)
    doc = (ROOT / "docs" / "papers-mfb.md").read_text()
    assert S.study_table_markdown(rep) in doc
    assert heading.format(n=len(err)) in doc
    # both studies were made whole by this code (session 26, the plans refit within the strokes): the
    # runs' own U95 are today's (no "U_runs:" calibration share kept beside them, as the studies made
    # before the calibration share's correction had), run 1's recomputed above equal to the stored
    # float32 ones (6e-8 relative), and the doc's coverage within them is the file's
    with np.load(study) as z:
        assert not any(k.startswith("U_runs:") for k in z.files)
        own, keep = z["U95_lin"].astype(float), z["keep"]
    assert np.allclose(own[0], r["U95_lin"], rtol=1e-6, atol=1e-15)
    k, n = int(np.sum(np.abs(err[:, keep]) <= own[:, keep])), int(keep.sum()) * len(err)
    assert f"{k:,} ({100 * k / n:.1f} %" in doc


def test_5axis_budget_covers_the_injected_errors_and_meets_the_hand_values():
    rep = S.study_report(ROOT / "scenarios" / "data" / "mfb-5axis-budget-study.npz")
    # the truth each run was drawn around: a right U95 covers about 95 % of the identified - true
    # values; one twice too large covers ~100 %, one half the size ~68 % (nodes are correlated, so
    # the band is wider than a binomial one)
    a, b = map(int, rep["coverage"]["within_quadrature_U95"].split("/"))
    assert 0.93 <= a / b <= 0.975
    # the sum of one-source shares against the Monte Carlo, per error: 1,000 runs give each U95 to
    # 2.2 % (1 SE); the per-error value is a ratio of maxima over ~6-9 nodes, and the 3-axis study
    # (same sources, same estimator; its first study, of the plan before session 10) came to
    # 0.90-1.02: 6 SE either way (set before the 5-axis study ended; a share missing or doubled
    # moves the ratio by far more)
    for s, c in rep["per_error"].items():
        assert 0.87 <= c["mc_over_quadrature"] <= 1.13, (s, c["mc_over_quadrature"])
    # JCGM 101 7.9 by halves: most nodes' halves within 2 standard errors
    assert rep["stability"]["within_2_se"] >= 0.9
    # hand values: 11.5 um/m/K (machine scales) over the plan's node spans 450 / 350 / 250 mm, to
    # 1e-3 um. The Invar bar's 1 um/m/K is that hand value only while the errors were evaluated at
    # the tip readings (0.4500 / 0.3500 / 0.2500 then): the scales act at the carriage (reading + J),
    # the bar expands about the tips, so styli of different J see it offset by s x dJ at one carriage
    # position, which no machine error reproduces (session 27: 0.4521 / 0.3194 / 0.2403); each axis's
    # departure within s x the plan's largest dJ along it (X: TX3's 250 mm, Y: TYM's 60, Z: TXL's
    # 100 mm over the others' 150), a bound from that geometry, not from the figures
    ts = rep["temperature_sensitivity_per_C"]
    for s, span_mm, dJ_mm in (("EXX", 450.0, 250.0), ("EYY", 350.0, 60.0), ("EZZ", 250.0, 100.0)):
        assert abs(ts["machine temperature"][s] - 11.5e-3 * span_mm) <= 1e-3
        assert abs(ts["bar temperature"][s] - 1e-3 * span_mm) <= 1e-3 * dJ_mm


def test_linear_calibration_share_is_the_simulated_bars_own():
    # The budget's "bar cal" column and every run's U95 propagate the bar calibration's u through
    # the estimator. The simulated bar (sim.artefacts, written apart) takes a draw of the 12 points'
    # heights and keeps what its 11 rods can give: its heights' errors are correlated and one
    # combination (alternating in sign) never occurs. Exact reference, no Monte Carlo error: the
    # simulator's response to each of the 36 drawn components (its construction is linear in them),
    # pushed through the same estimator. Both budget studies measured it through the whole pipeline:
    # EZX's first free node MC / sum 0.90 (3-axis, its first study: the plan before session 10, bars
    # in the table) and 0.89 (5-axis), the other nodes 0.93-1.01.
    from core import mfb, volumetric as vol
    from sim import artefacts as A

    r = S.run("mfb-3axis", noise_um=0.0, draw_inputs=False, mc_runs=10)  # its U95: the calibration's alone (lin)
    u_cal = np.tile(np.array(S.inspect_default("u_cal_um"), float) * 1e-6, (12, 1))
    E0 = A.mfb_default_deviations()
    base = A.multi_feature_bar(deviations_m=E0).info["E_MFB_m"]
    R = np.column_stack([(A.multi_feature_bar(deviations_m=E0 + np.eye(36)[k].reshape(12, 3)).info["E_MFB_m"]
                          - base).ravel() for k in range(36)])
    sim_bar = 2.0 * np.sqrt(np.diag(vol.covariance(r.result, r.meas, 0.0, u_cal, cal_map=R)))
    d = r.result.design
    for s in (*vol.MOTION, *vol.SQUARENESS):
        sl = d.slices[s]
        assert np.allclose(r.unc.U95_lin[sl], sim_bar[sl], rtol=1e-9, atol=1e-15), \
            (s, np.max(r.unc.U95_lin[sl] / np.where(sim_bar[sl] > 0, sim_bar[sl], 1.0)))
    # the comparison sees the difference: the points taken as independent (main before this test)
    # put 6.2 % more in EZX's first free node (2.23 um against the simulated bar's 2.10; session 27,
    # the errors at the axis positions and EXY/EXZ/EYZ's end-point conventions: 11.7 %, 3.82 against
    # 3.42 um, before; 9.7 %, 4.01 against 3.65 um, on the plan before its bars were lifted onto the
    # table face). The band as before: 0.03 on the ratio, 3 % on the value (this pipeline's figures)
    ezx = d.slices["EZX"].start + 1
    indep = 2.0 * np.sqrt(vol.covariance(r.result, r.meas, 0.0, u_cal)[ezx, ezx])
    assert 1.05 < indep / sim_bar[ezx] < 1.08 and 2.07e-6 < sim_bar[ezx] < 2.14e-6
    # and the bar's own map is the rods' (core.mfb's reading of section 2.1, sim's built apart)
    assert np.allclose(mfb.calibration_map(), R, atol=1e-12)
    # the run's bar block, U95 of calibrated - true in the gauge it is shown in (Exx from O_1; Eyx,
    # Ezx against the line O_1 O_12). Hand-worked answers on the document itself: x and y are
    # declared one independent error per point (u 0.2, 0.35 um), so Exx_i - Exx_1 has u 0.2 sqrt(2)
    # from hole 2 on, and Eyx_i minus the line (weights 1 - t, t at t = i / 11) has
    # u 0.35 sqrt(1 + (1 - t)^2 + t^2); the ends are 0 in y and z (they define the line); an inner
    # height's u is 0.41-0.46 um (not the 0.35 sqrt(...) of independent heights, 0.43-0.47)
    Ud = np.asarray(r.doc["bar"]["U95_um"], float)
    t = np.arange(12) / 11.0
    assert Ud.shape == (12, 3) and Ud[0, 0] == 0.0 and np.allclose(Ud[1:, 0], 0.4 * np.sqrt(2.0), rtol=1e-12)
    assert np.allclose(Ud[1:11, 1], 0.7 * np.sqrt(1.0 + (1.0 - t[1:11]) ** 2 + t[1:11] ** 2), rtol=1e-12)
    assert np.all(Ud[[0, 11], 1:] < 1e-12)
    assert 0.82 < Ud[1:11, 2].min() and Ud[1:11, 2].max() < 0.93
    # and against the simulated bar's own response, the gauge written here (not S.bar_gauge): each
    # drawn calibration component (one of the 36, at its u) moves the simulated bar's points by a
    # response (R's column, linear: one joint random draw through the simulator agrees with the sum
    # of the responses to 1e-18 m), and the components are independent, so each gauge value's
    # variance is the sum of its responses' squares
    def gauge(E):
        return np.column_stack([E[:, 0] - E[0, 0], *(E[:, c] - E[0, c] - t * (E[-1, c] - E[0, c]) for c in (1, 2))])

    n = np.random.default_rng(7).standard_normal(36)
    joint = A.multi_feature_bar(deviations_m=E0 + (u_cal.ravel() * n).reshape(12, 3)).info["E_MFB_m"] - base
    assert np.allclose(joint.ravel(), R @ (u_cal.ravel() * n), rtol=0, atol=1e-18)
    resp = [gauge((R[:, k] * u_cal.ravel()[k]).reshape(12, 3)) for k in range(36)]
    U_sim = 2e6 * np.sqrt(sum(g ** 2 for g in resp))
    assert np.allclose(Ud, U_sim, rtol=1e-9, atol=1e-12), np.max(np.abs(Ud - U_sim))


def test_within_u95_counts_and_what_the_model_expects_of_correlated_nodes():
    # known answers: an error whose 4 nodes move together (one draw for all) is within everywhere or
    # nowhere, 95 % of the time within: the count of values is 4 or 0 (expected 3.8, 2.5 % point 0);
    # 4 independent nodes: binomial(4, 0.95), P(count <= 2) = 1.4 %, so the 2.5 % point is 3 (SE of
    # the expected counts from 20,000 draws: 0.006 and 0.003)
    z = 1.959964  # U95 / sigma of a normal value
    errors = {"EXX": {"u95": [0.0, z, z, z, z], "identified": [0.0, 0.1, 2.5, 0.0, -3.0], "injected": [0.0] * 5},
              "EYX": {"u95": [z] * 4, "identified": [0.2, 0.2, 0.2, 0.2], "injected": [0.0] * 4},
              "EC0Y": {"u95": [0.0], "identified": [5.0], "injected": [0.0]}}  # fixed by a convention: not counted
    w = S.within_u95(errors)
    assert (w["inside"], w["total"], w["errors_inside"], w["errors_total"]) == (6, 8, 1, 2)
    sl = {"EXX": slice(0, 5), "EYX": slice(5, 9), "EC0Y": slice(9, 10)}
    cov = np.zeros((10, 10))
    cov[:5, :5] = 1e-12  # sigma 1 um, the same draw at every node
    cov[5:9, 5:9] = 1e-12 * np.eye(4)
    for corr, ind in ((True, False), (False, True)):
        e = {k: v for k, v in errors.items() if (k == "EXX" and corr) or (k == "EYX" and ind)}
        m = S.within_u95(e, cov, sl, np.random.default_rng(5), draws=20000)
        # the error within at every node: 0.95 when its nodes move together, 0.95^4 = 0.81 when not
        assert abs(m["expected"] - 3.8) < 0.03 and abs(m["errors_expected"] - (0.95 if corr else 0.95 ** 4)) < 0.01
        assert m["range95"] == ([0, 4] if corr else [3, 4])


def test_remaking_a_stored_study_with_the_share_gives_its_errors_and_widens_a_gated_run(tmp_path, monkeypatch):
    # review33a F4, session 34: the stored studies made again with the model-error share on (the 3-axis study
    # is: scenarios/data/mfb-3axis-budget-study.npz). The share moves no estimate, so each run's identified - true
    # comes back as stored (to 1e-9 relative, as the stored-study test above) and so does its own U95 (the file's
    # float32, 6e-8 relative). Attempt 1 is one whose residuals reject the noise model (lack-of-fit p 7.4e-4,
    # below its 1e-3): against the same run with the share off its U95 grows (x 1.28 over the nodes' median on
    # this machine, session 34); attempt 3 (made in the same chunk, p 0.055) is behind a closed gate: the same U95.
    from core import volumetric as vol

    was = S.MFB_MODEL_ERROR_SHARE
    st = S.remake_study_with_share("mfb-3axis", tmp_path, runs=1)
    # all three put back (the between-node test, a note that moves neither error nor U95, is off while it runs)
    assert S.MFB_MODEL_ERROR_SHARE is was and vol.EXACT_EXTRACTION is True and S.MFB_BETWEEN_NODES is True
    with np.load(ROOT / "scenarios" / "data" / "mfb-3axis-budget-study.npz") as z:
        err, own, keep = z["error"][:3], z["U95_lin"][:3].astype(float), z["keep"]
        assert bool(z["model_error_share"])
    assert st["ok"][0] and len(st["error"]) == 1
    assert np.abs(st["error"][0] - err[0]).max() <= 1e-9 * np.abs(err[0]).max()
    np.testing.assert_allclose(st["U95_lin"][0][keep], own[0][keep], rtol=1e-6)
    with np.load(tmp_path / "run-00003.npz") as r:
        assert np.abs(r["error"] - err[2]).max() <= 1e-9 * np.abs(err[2]).max()
        np.testing.assert_allclose(r["U95_lin"][keep], own[2][keep], rtol=1e-6)
    # the same attempts with the share off (model (3), as the remake): attempt 1 narrower, attempt 3 the same
    monkeypatch.setattr(vol, "EXACT_EXTRACTION", False)
    monkeypatch.setattr(S, "MFB_MODEL_ERROR_SHARE", False)
    off1, off3 = S.budget_run("mfb-3axis", 1), S.budget_run("mfb-3axis", 3)
    assert np.array_equal(off1["error"], st["error"][0])
    g = own[0][keep] / off1["U95_lin"][keep]
    assert np.all(g >= 1 - 1e-6) and 1.1 < np.median(g) < 1.6, np.median(g)
    np.testing.assert_allclose(off3["U95_lin"][keep], own[2][keep], rtol=1e-6)
