"""The discovery engine on first-order synthetic campaigns (tests/core/discover_synth.py).

These check the statistics and the cause registry in isolation: every
catalogue cause named with its magnitudes inside their U95, out-of-catalogue
effects reported as ``unexplained`` with the covariate they follow,
effect-free campaigns left alone, the report's keys, invariance under a
move of the campaign and a new order of its set-ups, and bad input. The
hidden-effect studies (tests/scenarios/test_discover_hidden.py) hide the
effects in the simulator and in generators written apart from this engine.
"""

import dataclasses

import numpy as np
import pytest

from core import causes, selfcal
from core.design import example_cross_pocket
from core.diagnosis import holm, nested_f, new_basis, orth
from core.baseline import touch_history
from core.discover import Settings, concentration_p, discover, find_outliers
from core.exceptions import ConfigError, IdentifiabilityError
from core.touches import from_log
from core.units import UM
import discover_synth as S
from tests.discover_helpers import discovered

CATALOGUE = ["thermal_drift", "c_drift", "temperature_expansion", "periodic_axis_error", "probe_lobing",
             "stylus_bending", "local_scale_defect", "part_change", "reversal", "nonrigid"]


#: Magnitudes (um) where 2 um leaves less than one noise sigma per touch once the
#: baseline has absorbed what it can (the x y^2 coupling is mostly an error map).
MAG_UM = {"nonrigid": 6.0}


@pytest.fixture(scope="module")
def runs():
    """One campaign per effect (2 um over 0.3 um noise), discovered once: {effect: (report, Discovery, effect)}."""
    out = {}
    for name in ["none"] + CATALOGUE + ["feature_offset_per_setup", "pretravel_warmup"]:
        t, e = S.campaign(name, 100, MAG_UM.get(name, 2.0) * 1e-6)
        d = discover(t)
        out[name] = (d.to_report(), d, e)
    return out


@pytest.mark.parametrize("cause", CATALOGUE)
def test_catalogue_cause_named(runs, cause):
    rep, _, _ = runs[cause]
    assert rep["cause"] == cause, [(f["cause"], f["evidence"].get("text")) for f in rep["findings"]]
    f = rep["findings"][0]
    assert f["evidence"]["p_adjusted"] < Settings().alpha_family
    assert rep["gain"]["cv_rms_ratio"] < 1.0
    # every numeric magnitude has a U95 (None only where the data cannot determine it)
    for k, v in f["params"].items():
        if isinstance(v, float):
            assert k in f["params_u95"]
            assert f["params_u95"][k] is None or f["params_u95"][k] >= 0


def test_effect_free_campaign_stays_none(runs):
    rep, _, _ = runs["none"]
    assert rep["cause"] == "none" and rep["findings"] == []
    assert not rep["structure"]["baseline"]["present"]
    assert all(d["p_value"] > 0.01 for d in rep["diagnosis"])


@pytest.mark.parametrize("effect, where", [("feature_offset_per_setup", "feature"),
                                           ("pretravel_warmup", "time_in_setup")])
def test_out_of_catalogue_is_unexplained_and_located(runs, effect, where):
    """The spheres re-seated in every set-up, a pre-travel settling after each
    indexing: no catalogue cause has that form. The report says unexplained,
    and the diagnosis names where the structure lives."""
    rep, _, _ = runs[effect]
    assert rep["cause"] == "unexplained", [f["cause"] for f in rep["findings"]]
    top = rep["diagnosis"][0]
    assert top["covariate"] == where and top["p_value"] < 1e-6, top
    assert "residuals follow" in rep["findings"][0]["evidence"]["text"]


def test_magnitudes_within_u95(runs):
    """Known answers: the hidden magnitudes (discover_synth) against the fitted ones and their U95."""
    rep = {k: runs[k][0]["findings"][0] for k in ("periodic_axis_error", "temperature_expansion", "reversal")}
    p = rep["periodic_axis_error"]
    assert p["params"]["axis"] == "Y"
    for key, true in (("period_mm", 9.3), ("EYY_amplitude_um", 2.0)):
        assert abs(p["params"][key] - true) <= p["params_u95"][key], (key, p["params"][key], p["params_u95"][key])
    te = rep["temperature_expansion"]
    alpha = 2e-6 / (0.1 * 1.5) * 1e6  # um/m/K, discover_synth
    assert abs(te["params"]["alpha_y_um_per_m_K"] - alpha) <= te["params_u95"]["alpha_y_um_per_m_K"]
    rv = rep["reversal"]
    assert abs(rv["params"]["x_lost_motion_um"] - 2.0) <= rv["params_u95"]["x_lost_motion_um"]


def test_report_keys_follow_the_spec(runs):
    rep, _, _ = runs["periodic_axis_error"]
    assert set(rep) >= {"baseline", "findings", "cause", "extended", "baseline_cv_rms_um", "gain", "workpiece",
                        "outlier_rows", "noise_um", "diagnosis"}
    assert set(rep["baseline"]) >= {"model", "n", "n_params", "rms_um"}
    assert set(rep["findings"][0]) >= {"cause", "evidence", "params", "params_u95", "rms_um"}
    assert set(rep["diagnosis"][0]) >= {"covariate", "explained_rms_um", "p_value"}
    assert set(rep["workpiece"][0]) >= {"target", "baseline_um", "extended_um", "baseline_u95_um", "extended_u95_um"}
    assert rep["noise_um"]["method"] in ("repeats", "repeats beyond the model's terms", "short-term repeats", "residuals")
    assert rep["noise_um"]["dof"] > 0
    for w in rep["workpiece"]:
        assert w["extended_u95_um"] > 0


def test_noise_floor_from_repeats(runs):
    """Sixteen repeated touches per set-up: the pure-error sigma after a time
    trend per set-up and mode (64 contrasts less at most 4 x 3 trend
    columns: at least 52 degrees of freedom, relative standard deviation at
    most 9.8 %) against the true 0.3 um."""
    rep, _, _ = runs["none"]
    nz = rep["noise_um"]
    assert nz["method"] == "repeats" and nz["repeats"]["dof_plain"] == 64 and 52 <= nz["repeats"]["dof"] < 64
    assert abs(nz["repeats"]["sigma_um"] - 0.3) < 0.3 * 0.30  # 3 standard deviations
    assert nz["cv_gap"]["p_value"] > 0.01 and nz["lack_of_fit"]["p_value"] > 0.01


def test_extended_workpiece_closer_for_a_periodic_error(runs):
    """Gauge-free error of the workpiece against the synthetic truth: the
    periodic error's extension at least halves it."""
    from core.lsq import remove_span
    from core.selfcal import workpiece_gauge_basis as gauge_basis

    _, d, _ = runs["periodic_axis_error"]
    _, _, truth = S.campaign("periodic_axis_error", 100, with_form=True)
    B = gauge_basis(*d.baseline.geometry)
    eb = np.sqrt(np.mean(remove_span(d.G_baseline_m - truth, B) ** 2))
    ee = np.sqrt(np.mean(remove_span(d.G_extended_m - truth, B) ** 2))
    assert ee < 0.5 * eb, (eb / UM, ee / UM)


def test_invariance_under_a_move_and_a_new_set_up_order():
    """The same measured deviations with the campaign 350 mm / -220 mm away in
    X / Y (the C axis there), and with its set-ups run in another order: the
    same cause, the same period, the same gauge-free workpiece to numerical
    noise (1e-6 um)."""
    from core.lsq import remove_span
    from core.selfcal import workpiece_gauge_basis as gauge_basis

    t0, _ = S.campaign("periodic_axis_error", 7)
    shift = np.array([0.350, -0.220, 0.0])
    t1 = dataclasses.replace(t0, pn_R=t0.pn_R + shift, p_R=t0.p_R + shift)
    d0, d1 = discover(t0), discover(t1)
    # another order of the set-ups: blocks permuted, times re-assigned by the new position
    order = [2, 0, 3, 1]
    rows = np.concatenate([np.flatnonzero(t0.setup == j) for j in order])
    t2 = t0.subset(rows, reindex=True)
    blocks = [np.flatnonzero(t2.setup == j) for j in range(4)]
    ts = np.concatenate([k * 600.0 + 8.0 * np.arange(b.size) for k, b in enumerate(blocks)])
    t2 = dataclasses.replace(t2, t_s=ts)
    d2 = discover(t2)
    assert d0.cause == d1.cause == d2.cause == "periodic_axis_error"
    P, N = d0.baseline.geometry
    B = gauge_basis(P, N)
    ids = list(d0.baseline.estimand_ids)

    def form(d):
        G = dict(zip(d.baseline.estimand_ids, d.G_extended_m))
        return remove_span(np.array([G[k] for k in ids]), B)

    for d in (d1, d2):
        assert np.max(np.abs(form(d) - form(d0))) < 1e-12, np.max(np.abs(form(d) - form(d0))) / UM
    p0, p1 = (d.findings[0].params["period_mm"] for d in (d0, d1))
    assert abs(p0 - p1) < 1e-6
    # the design is built about the C axis: held-out residuals identical too
    assert abs(d1.extended_cv_rms_um - d0.extended_cv_rms_um) < 1e-9 * d0.extended_cv_rms_um


def test_drift_follows_a_logged_temperature(runs):
    rep, _, _ = runs["temperature_expansion"]
    p = rep["findings"][0]["params"]
    assert p["sensor"] == "temp_scale_y_C" and p["reference_temperature_C"] == 20.0


def test_outliers_found_by_row():
    t, _ = S.campaign("none", 3)
    dq = t.dq_m.copy()
    dq[[7, 150, 300]] += [6e-6, -5e-6, 8e-6]
    t = dataclasses.replace(t, p_R=t.pn_R + dq[:, None] * t.n_R)
    d = discover(t)
    assert d.cause == "outlier" and d.outlier_rows == (7, 150, 300)
    rng = np.random.default_rng(3)
    assert find_outliers(np.ones((200, 1)), rng.normal(0, 1, 200)) == []


def test_outlier_passes_downdate_the_basis_as_a_fresh_factorisation_would():
    """find_outliers takes each pass's basis as the previous one less the removed row (discover's
    _without_row, O(n r) instead of a pivoted QR of the rows left). Against a fresh factorisation of
    the rows left, on the cross pocket's baseline design (432 x 158) less rows of leverage up to 0.97:
    orthonormal and the same projection to 1e-12 (rounding of a few products; a wrong downdate
    factor is off by the row's leverage, 1e-2 or more)."""
    from core.baseline import planar
    from core.discover import _without_row

    t, _ = S.campaign("none", 3)
    bl = planar(t, None, Settings().grid_steps_mm, yaw=selfcal.yaw_for_chain(None), extra={})
    X, y = np.asarray(bl.A), bl.y
    Q = orth(X)
    h = np.sum(Q ** 2, axis=1)
    keep = np.ones(len(X), bool)
    for k in (int(np.argmax(np.where(h < 0.97, h, 0))), 5, 200, 431):  # the highest leverage first
        pos = int(np.sum(keep[:k]))
        keep[k] = False
        Q = _without_row(Q, pos)
        F = orth(X[keep])
        assert Q.shape == F.shape
        assert np.abs(Q.T @ Q - np.eye(Q.shape[1])).max() < 1e-12
        assert np.abs(Q @ (Q.T @ y[keep]) - F @ (F.T @ y[keep])).max() < 1e-12 * np.abs(y).max()


@pytest.mark.parametrize("seed", [2, 8, 9])
def test_outliers_near_the_bound_after_a_high_leverage_one(seed):
    """The passes after the first stand on the downdated basis: a wrong one moves the residuals of
    the rows left and so the answer. 60 rows, 6 columns, N(0, 1) noise; row 0 scaled 6x (leverage
    0.79-0.88) carries an outlier at 25 of its own scale. Each other value is set by hand from a
    plain least-squares fit (numpy's lstsq, no QR basis of find_outliers') of the rows that pass
    would hold without it: row 10 at 1.03 times the bound of the second pass (59 rows, Bonferroni
    0.001, Student's t on 59 - 6 - 1 dof) in its externally studentized residual, row 20 at 0.97
    times the third pass's. So the answer is [0, 10]. Verified to fail with _without_row returning
    the rows left uncorrected, with the factor 1 / (1 - s) for 1 / sqrt(1 - s), with the correction's
    sign flipped and with the wrong row removed (each seed: another answer for each)."""
    from scipy import stats

    n, p = 60, 6
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, p))
    X[0] *= 6.0
    y = X @ rng.normal(size=p) + rng.normal(size=n)

    def fit_without(i, rows):  # the fit of ``rows`` less i: (x_i b, the scale of y_i - x_i b)
        R = [j for j in rows if j != i]
        b, *_ = np.linalg.lstsq(X[R], y[R], rcond=None)
        e = y[R] - X[R] @ b
        g = X[i] @ np.linalg.solve(X[R].T @ X[R], X[i])
        return X[i] @ b, np.sqrt(e @ e / (len(R) - p) * (1 + g))

    def bound(m):  # find_outliers' bound on m rows
        return stats.t.isf(0.001 / (2 * m), m - p - 1)

    rows = list(range(n))
    fit, sc = fit_without(20, [j for j in rows if j not in (0, 10)])
    y[20] = fit + 0.97 * bound(n - 2) * sc
    fit, sc = fit_without(10, rows[1:])
    y[10] = fit + 1.03 * bound(n - 1) * sc
    fit, sc = fit_without(0, rows)
    y[0] = fit + 25.0 * sc
    assert find_outliers(X, y) == [0, 10]


def test_outliers_are_confidently_dust_only_when_their_pattern_could_be_seen():
    """Three chips in three set-ups at random (concentration p 0.74) are dust, ``named``; one alone is
    ``ambiguous`` with its reason: one event cannot tell a chip from an intermittent mechanism (a seat
    that re-seats, a clamp that slips: gen_a reseat_hysteresis 502 and 609, gen_b fixture_slip 600 were
    reported as confident outliers before this rule)."""
    t, _ = S.campaign("none", 3)
    for rows, conf in (([7, 150, 300], "named"), ([150], "ambiguous")):
        dq = t.dq_m.copy()
        dq[rows] += 6e-6
        rep = discover(dataclasses.replace(t, p_R=t.pn_R + dq[:, None] * t.n_R)).to_report()
        f = rep["findings"][0]
        assert f["cause"] == "outlier" and f["evidence"]["events"] == len(rows)
        assert f["evidence"]["confidence"] == conf, f["evidence"]
    assert f["evidence"]["confidence_reason"].startswith("one event")
    from scenarios.cli.discover import summary_lines  # the CLI says why

    assert any(ln.startswith("finding    outlier (ambiguous: one event") for ln in summary_lines(rep))


def test_too_many_outliers_are_structure_not_dust():
    """If the outlier test wants more than 2 % of the rows, nothing is removed."""
    rng = np.random.default_rng(4)
    y = rng.normal(0, 1, 300)
    y[:10] += 12.0  # 3.3 % of the rows, 12 sigma
    assert find_outliers(np.ones((300, 1)), y, max_frac=0.02) == []
    assert find_outliers(np.ones((300, 1)), y, max_frac=0.05) == list(range(10))


def test_chips_that_fall_at_random_are_dust_up_to_5_percent():
    """Five chips in 140 touches (3.6 %) at random rows are removed when the rows' covariates say they fall
    at random; the same five on consecutive touches (the touches after something moved) are structure."""
    rng = np.random.default_rng(5)
    n = 140
    ranks = np.column_stack([(np.arange(n) + 0.5) / n, (rng.permutation(n) + 0.5) / n])  # time order, a position
    y = rng.normal(0, 1, n)
    chips = [9, 33, 61, 97, 128]
    y[chips] += 15.0
    g = np.random.default_rng
    assert find_outliers(np.ones((n, 1)), y) == []  # nothing says where they fall: more than 2 % is structure
    assert find_outliers(np.ones((n, 1)), y, ranks=ranks, rng=g(0)) == chips
    y2 = rng.normal(0, 1, n)
    y2[70:75] += 15.0
    assert find_outliers(np.ones((n, 1)), y2, ranks=ranks, rng=g(0)) == []
    y3 = rng.normal(0, 1, n)
    y3[:8] += 15.0  # 5.7 %: more than any shop's chips, wherever they fall
    assert find_outliers(np.ones((n, 1)), y3, ranks=ranks[::-1].copy(), rng=g(0)) == []


def test_concentration_known_answers():
    """Rows at one end of a covariate or side by side are concentrated; rows drawn at random are not
    (the test's false rate at a 5 % level over 200 random draws of 4 rows: binomial 99.9 % bound 20)."""
    n = 200
    ranks = ((np.arange(n) + 0.5) / n)[:, None]
    rng = np.random.default_rng(6)
    assert concentration_p(ranks, [196, 197, 198, 199], rng) < 1e-3  # the last four: both statistics
    assert concentration_p(ranks, [100, 101, 102, 103], rng) < 1e-3  # together in the middle: the spread
    hits = sum(concentration_p(ranks, rng.choice(n, 4, replace=False), rng, draws=2000) < 0.05 for _ in range(200))
    assert hits <= 20, hits
    assert concentration_p(ranks, [5], rng) == 1.0  # one row cannot concentrate


def test_a_fixture_slip_is_not_named_a_c_axis_creep():
    """The part turning once by 40 urad about the C axis late in one set-up: the touches after it shift
    by ``rot * 40e-6``. A C-axis creep per set-up fits it (the engine before the slip rival named it
    c_drift), but a one-off step explains as much: the report says unexplained and why."""
    t, _ = S.campaign("none", 11)
    idx = np.flatnonzero(t.setup == np.unique(t.setup)[1])
    after = idx[np.argsort(t.t_s[idx])][int(0.6 * idx.size):]
    dq = t.dq_m.copy()
    p, n = t.pn_R[after], t.n_R[after]
    dq[after] += (-n[:, 0] * p[:, 1] + n[:, 1] * p[:, 0]) * 40e-6  # eq 13 about the C axis at the origin
    rep = discover(dataclasses.replace(t, p_R=t.pn_R + dq[:, None] * t.n_R)).to_report()
    assert rep["cause"] == "unexplained", [f["cause"] for f in rep["findings"]]
    assert any(r["cause"] == "c_drift" and "fixture slip" in r["reason"] for r in rep["rejected"]), rep["rejected"]


def test_touch_history_known_answer():
    """Rest since the previous touch (log10 s; the first gets the others' median) and the approach's turn."""
    t = np.array([10.0, 0.0, 1.0, 3.0])  # log order differs from time order
    d = np.array([[0, 1, 0], [1, 0, 0], [1, 0, 0], [-1, 0, 0]], float)
    since, turn = touch_history(t, d)
    np.testing.assert_allclose(since, [np.log10(7), np.median([0, np.log10(2), np.log10(7)]), 0, np.log10(2)],
                               atol=1e-15)
    np.testing.assert_array_equal(turn, [90, 0, 0, 180])


def test_bad_input():
    t, _ = S.campaign("none", 1)
    with pytest.raises(ConfigError, match="at least 10 valid touches"):
        discover(t.subset(np.arange(5)))
    with pytest.raises(IdentifiabilityError, match="no baseline"):
        discover(t.subset(t.setup == 0, reindex=True))


def test_symmetric_design_workpiece_not_identifiable():
    """A symmetric part at C 90 deg apart: the self-calibration is rank
    deficient beyond the gauge; residuals need no gauge, so discovery runs,
    and the workpiece is reported as not identifiable (null, no U95)."""
    w, wn, _ = example_cross_pocket(spheres=False)
    t = selfcal.nominal_touches(w, wn, [0, 90, 180, 270], stylus_r_m=0.003)
    rng = np.random.default_rng(11)
    dq = rng.normal(0, 0.3e-6, t.n)
    t = dataclasses.replace(t, p_R=t.pn_R + dq[:, None] * t.n_R, t_s=np.arange(t.n) * 10.0)
    rep = discover(t).to_report()
    assert rep["cause"] == "none" and rep["workpiece_identifiable"] is False
    assert all(w["extended_um"] is None and w["extended_u95_um"] is None for w in rep["workpiece"])
    assert "NOT identifiable" in " ".join(rep["conventions"])


def test_out_of_plane_touches_are_left_out_and_said():
    t, _ = S.campaign("none", 5)
    n = t.n_R.copy()
    n[:6] = [0.6, 0.0, 0.8]
    rep = discover(dataclasses.replace(t, n_R=n)).to_report()
    assert rep["baseline"]["n"] == t.n - 6
    assert any("6 touches with normals out of the XY plane" in c for c in rep["conventions"])


def test_progress_reaches_the_total():
    t, _ = S.campaign("none", 2)
    calls = []
    discover(t, progress=lambda done, total: calls.append((done, total)))
    assert calls and calls[-1][0] == calls[-1][1]
    assert all(b[0] >= a[0] for a, b in zip(calls, calls[1:]))


def test_registry_records_are_complete():
    """One frozen record per cause: physics in a docstring, magnitudes, bounds."""
    for c in causes.REGISTRY:
        assert c.doc and len(c.doc) > 80, c.name
        if c.scans is not None:
            assert c.magnitudes is not None and c.books_to in ("machine", "probe", "workpiece", "artefact")
    assert causes.lookup("part_change").books_to == "workpiece"
    assert len({(c.name, k) for c in causes.REGISTRY for k in c.kinds}) == sum(len(c.kinds) for c in causes.REGISTRY)


def test_nested_f_is_calibrated_under_the_null():
    """Known distribution: for pure noise the nested F test's p-values are
    uniform. 400 draws: the share below 0.05 within its binomial band
    (0.05 +- 3 sd = 0.017-0.083)."""
    rng = np.random.default_rng(0)
    A = rng.normal(size=(120, 10))
    B = rng.normal(size=(120, 6))
    Q = orth(A)
    U = new_basis(Q, B)
    p = []
    for _ in range(400):
        y = rng.normal(size=120)
        r = y - Q @ (Q.T @ y)
        p.append(nested_f(U, r, float(r @ r), 120 - Q.shape[1]).p_value)
    frac = np.mean(np.array(p) < 0.05)
    assert 0.017 < frac < 0.083, frac


def test_holm_known_answer():
    """Holm (1979): sorted p (0.01, 0.04, 0.03, 0.005) over 4 tests -> 0.03, 0.06, 0.06, 0.02."""
    np.testing.assert_allclose(holm([0.01, 0.04, 0.03, 0.005]), [0.03, 0.06, 0.06, 0.02])


def test_unoriented_lobing_free_of_the_parts_own_lobes():
    """Known answer: one probe's 3-lobe pattern (1.5 um) turned to seven random
    orientations, plus a lobing fixed in the machine frame (the circle's
    centre) and a 3-lobe form of the part turning with the table (the
    workpiece absorbs it: R(-3 C_j) w per set-up). Noise-free, the amplitude
    and the orientations come back to the fit's precision (1e-6 um: the
    Gauss-Newton's tolerance in a 1 um problem); with the part's lobes left
    in, the plain circle is off by tenths of a micrometre."""
    from types import SimpleNamespace

    rng = np.random.default_rng(5)
    k, A = 3, 1.5 * UM
    c_rad = np.radians(rng.choice(np.arange(0, 360, 7), 7, replace=False).astype(float))
    theta = rng.uniform(-np.pi, np.pi, 7)
    m, w = rng.normal(0, 0.4 * UM, 2), rng.normal(0, 0.6 * UM, 2)
    a = -k * c_rad
    part = np.column_stack([np.cos(a) * w[0] - np.sin(a) * w[1], np.sin(a) * w[0] + np.cos(a) * w[1]])
    coef = (m + part + A * np.column_stack([np.cos(theta), np.sin(theta)])).ravel()
    ids = tuple(f"S{j}" for j in range(7))
    setup = np.repeat(np.arange(7), 3)
    rot = np.zeros((21, 3))
    rot[:, 2] = c_rad[setup]
    bl = SimpleNamespace(data=SimpleNamespace(touches=SimpleNamespace(setup_ids=ids, setup=setup, rot_rad=rot)))
    out = causes.unoriented_magnitudes({"harmonic": k, "setups": ids}, coef, bl)
    assert abs(out["amplitude_um"] - 1.5) < 1e-6, out["amplitude_um"]
    assert out["circle_residual_um"] < 1e-6
    got = np.radians([out[f"orientation_deg[{s}]"] for s in ids]) * k
    assert np.max(np.abs(np.angle(np.exp(1j * (got - theta))))) < 1e-6
    plain = causes._circle(coef.reshape(7, 2))
    assert abs(plain[1] / UM - 1.5) > 0.05 or plain[2] / UM > 0.05  # the part's lobes do bend the plain circle


def test_cv_gap_calibrated_when_one_set_up_dominates():
    """Under pure noise the CV-gap p-value must not call ordinary excursions
    structure, also when one poorly predicted set-up dominates the held-out
    error (its held-out residual amplified 1e4-fold: the ratio is then
    close to a scaled chi-square with one degree of freedom, far from
    normal). Observed and null ratios are drawn from the same exact
    quadratic forms (z_1^2 * 1e4 + sum of 199 z^2) / chi2(200); at the
    engine's level 0.0025 the rate of p < level over 4000 pure-noise
    campaigns stays within its binomial bound (a normal tail gave about
    0.02 here)."""
    from core.diagnosis import cv_gap

    rng = np.random.default_rng(11)

    def draw(m):  # the sums of squared standard normals drawn as the chi-squares they are
        return 1e4 * rng.chisquare(1, m) + rng.chisquare(199, m), rng.chisquare(200, m)

    hits = 0
    for _ in range(4000):
        cv, rss = draw(1)
        ncv, nrss = draw(99)
        hits += cv_gap(float(cv[0]), float(rss[0]), ncv, nrss).p_value < 0.0025
    # binomial(4000, 0.0025): mean 10, P(X > 25) < 1e-4; a too-heavy tail would also be caught by the lower side
    assert hits <= 25, hits


def test_scatter_above_a_probes_noise_is_never_none():
    """A 10 um seat hysteresis on a random third of the touches follows no
    covariate and inflates both the repeats and the residuals (about 4.7 um):
    read as noise it would be 'none'. No touch-trigger probe scatters that
    much (Settings.noise_max_um, 1.5 um): the answer is 'unexplained', saying
    so. The same campaign with 1 um of honest noise stays 'none'."""
    rng = np.random.default_rng(3)
    t, _ = S.campaign("none", 7, sigma_m=1.0e-6)
    rep = discover(t).to_report()
    assert rep["cause"] == "none", rep["cause"]
    dq = 10e-6 * (rng.random(t.n) < 1 / 3)
    rep = discover(dataclasses.replace(t, p_R=t.p_R + dq[:, None] * t.n_R)).to_report()
    f = rep["findings"][0]
    assert rep["cause"] == "unexplained" and f["evidence"]["noise_excess"], rep["findings"]
    assert "above any touch-trigger probe's noise" in f["evidence"]["text"]


def test_a_dirty_set_up_is_dust_but_a_slip_within_it_is_not():
    """Counting one event per set-up: three chips scattered in one set-up are dust; three outliers that one
    step of that set-up's tail explains (a slip moving the part: large where the touch's normal meets the
    motion, small elsewhere) are not, once the slip's trials are given. Without the trials both are dust:
    the trade Settings.outlier_events='setup' makes."""
    rng = np.random.default_rng(12)
    n, per = 120, 30
    setup = np.repeat(np.arange(4), per)
    pos = np.tile(np.arange(per), 4)
    ranks = np.column_stack([(np.arange(n) + 0.5) / n, (rng.permutation(n) + 0.5) / n])
    w = rng.uniform(-0.1, 0.1, n)  # the slip's share on each touch (its normal against the motion)
    w[[62 + 20, 62 + 23, 62 + 27]] = 1.0
    trials = np.array([(w * ((setup == j) & (pos >= s)))[:, None] for j in range(4) for s in range(1, per)])
    X = np.column_stack([np.ones(n), np.linspace(-1, 1, n)])
    g = np.random.default_rng
    slip = rng.normal(0, 1, n)
    slip[(setup == 2) & (pos >= 20)] += 12.0 * w[(setup == 2) & (pos >= 20)]
    chips = rng.normal(0, 1, n)
    chips[[63, 74, 86]] += 12.0
    for y, rows in ((slip, [82, 85, 89]), (chips, [63, 74, 86])):
        assert find_outliers(X, y, ranks=ranks, rng=g(0), events=setup) == rows
    assert find_outliers(X, chips, ranks=ranks, rng=g(0), events=setup, slips=lambda: trials) == [63, 74, 86]
    assert find_outliers(X, slip, ranks=ranks, rng=g(0), events=setup, slips=lambda: trials) == []


def test_a_slip_explains_its_own_set_up_not_another_set_ups_chips(monkeypatch):
    """review32c F3 (cat_outlier_20010): one set-up's step explaining that set-up's outliers kept every outlier
    of the campaign, chips of another set-up too (two chips of set-up S1 kept beside S3's step: a confident
    `unexplained`). The same slip as above in set-up 2 (three outliers it explains, more than its one
    parameter) and two chips of 12 sigma in set-up 0, where no step is given that could take them (set-up 0's
    trials move only its tail from touch 20 on; the chips are touches 5 and 17): the slip's rows stay, the
    chips go (SLIP_VETO_PER_EVENT); off, nothing goes (the rule before)."""
    import core.discover as D

    rng = np.random.default_rng(12)
    n, per = 120, 30
    setup = np.repeat(np.arange(4), per)
    pos = np.tile(np.arange(per), 4)
    ranks = np.column_stack([(np.arange(n) + 0.5) / n, (rng.permutation(n) + 0.5) / n])
    w = rng.uniform(-0.1, 0.1, n)
    w[[62 + 20, 62 + 23, 62 + 27]] = 1.0
    trials = np.array([(w * ((setup == j) & (pos >= s)))[:, None] for j in range(4) for s in range(20, per)])
    X = np.column_stack([np.ones(n), np.linspace(-1, 1, n)])
    y = rng.normal(0, 1, n)
    y[(setup == 2) & (pos >= 20)] += 12.0 * w[(setup == 2) & (pos >= 20)]
    y[[5, 17]] += 12.0
    g = np.random.default_rng
    monkeypatch.setattr(D, "SLIP_VETO_PER_EVENT", True)   # (off by default since session 32's end: its cost on knock)
    assert find_outliers(X, y, ranks=ranks, rng=g(0), events=setup) == [5, 17, 82, 85, 89]
    assert find_outliers(X, y, ranks=ranks, rng=g(0), events=setup, slips=lambda: trials) == [5, 17]
    monkeypatch.setattr(D, "SLIP_VETO_PER_EVENT", False)
    assert find_outliers(X, y, ranks=ranks, rng=g(0), events=setup, slips=lambda: trials) == []


def test_chips_a_step_could_absorb_are_dust_when_nothing_else_moved():
    """A slip moves every touch after it; a chip only the touch it sits under. gen_a outlier 1108 (two chips
    in set-up 0, 12 and 14 sigma, and one in set-up 3) and 1109 (two in set-up 0, two elsewhere): the best
    step of set-up 0 (its first 17 touches against the other 36, three free parameters) fitted on every row
    absorbed both chips, so the set was called a slip and nothing was removed; the answer was 'none',
    confident, beside 8-30 sigma chips. With the chips set aside the step explains nothing of the set-up's
    other touches: they are dust, the rows the generator put them on (its truth, not this engine's)."""
    from scenarios.blind import gen_a

    for seed in (1108, 1109):
        log, truth = gen_a.generate("outlier", seed)
        rep = discovered(log).to_report()
        assert rep["cause"] == "outlier", (seed, rep["cause"])
        assert sorted(rep["outlier_rows"]) == sorted(truth.outlier_rows), (seed, rep["outlier_rows"])


def test_outlier_events_must_be_known():
    t, _ = S.campaign("none", 3)
    with pytest.raises(ConfigError, match="outlier_events"):
        discover(t, settings=Settings(outlier_events="chip"))


def _lobed_campaign(seed: int, psi_rad) -> tuple:
    """Six set-ups of the synthetic cross pocket with a 2 um lobing of the approach azimuth (0.3 um noise).

    ``psi_rad`` per set-up: the lobes' orientation (all equal: an oriented probe).
    Harmonic 3 for a fixed pattern, 2 for a turning one.
    """
    rng = np.random.default_rng(seed)
    t = S.plan(c_deg=(0.0, 50.0, 110.0, 170.0, 230.0, 300.0))
    phi = np.arctan2(t.d_R[:, 1], t.d_R[:, 0])
    psi = np.asarray(psi_rad, float)
    k = 3 if np.ptp(psi) == 0 else 2
    e = 2e-6 * np.cos(k * (phi - psi[t.setup]))
    mf, _ = S.machine_and_form(t, rng)
    dq = mf + e + rng.normal(0, S.SIG, t.n)
    return dataclasses.replace(t, p_R=t.pn_R + dq[:, None] * t.n_R)


def test_fixed_lobes_are_the_plainer_explanation_of_lobes_per_set_up():
    """Lobes turned per set-up nest the probe's fixed lobes; the richer cause is
    refused before adoption when the fixed lobes explain as much, so the plainer
    named cause wins the round (not `unexplained`); a real turn is still named,
    its amplitude to 0.1 um (noise 0.3 um over 6 x 4 orientations' fits)."""
    rep = discover(_lobed_campaign(0, [0.7] * 6)).to_report()
    assert rep["cause"] == "probe_lobing", [f["cause"] for f in rep["findings"]]
    why = [r["reason"] for r in rep["rejected"] if r["cause"] == "lobing_per_setup"]
    assert why and why[0].startswith("a plainer explanation (common lobing) explains as much"), rep["rejected"]
    rep = discover(_lobed_campaign(1, [0.0, 0.8, 2.1, 2.9, 1.4, 0.3])).to_report()
    assert rep["cause"] == "lobing_per_setup", [f["cause"] for f in rep["findings"]]
    assert abs(rep["findings"][0]["params"]["amplitude_um"] - 2.0) < 0.1


def test_smooth_term_workpiece_u95_is_the_datas_not_the_penaltys():
    """Known answer: a smooth basis that copies a workpiece column exactly.

    Three targets measured in two set-ups, four times each; the baseline is
    ``y = g[target] + o[set-up]`` with ``o[0] = 0`` (the gauge). The smooth
    term's basis is (target 0's indicator, time): its first column is the
    workpiece's own, so the data cannot split that signal and only the
    penalty would. The extended workpiece must then be the ordinary least
    squares of (targets, set-up 1, time), computed here by the textbook
    formula ``s^2 (X^T X)^-1`` apart from the engine: estimate and U95 to
    1e-7 um. Why that bound: the ridge (lambda = 1e-10 on the smooth's
    coefficients) biases the time coefficient by about
    lambda / |t outside the model|^2, 2e-9 um here; float64 rounding on a
    24-row problem is far below. The engine before this rule let the ridge
    decide the shared direction: target 0's U95 was 45,668 um (about
    2 s / sqrt(lambda)) and its estimate 1.07e-6 um off.
    """
    from types import SimpleNamespace

    from core.discover import Term, _workpiece

    rng = np.random.default_rng(7)
    tgt = np.tile(np.repeat(np.arange(3), 4), 2)
    su = np.repeat([0, 1], 12)
    n = tgt.size
    time = np.arange(n, dtype=float) / n
    A0 = np.hstack([np.eye(3)[tgt], np.eye(2)[su]])
    C = np.array([[0.0, 0, 0, 1, 0]])
    y = A0 @ np.array([3.0, -2.0, 1.0, 0.0, 5.0]) * UM + 0.8 * UM * time + 0.3 * UM * rng.standard_normal(n)
    bl = SimpleNamespace(estimand=np.arange(3), A=A0, C=C, d=np.zeros(1), n=n, estimand_ids=("a", "b", "c"))
    lam = 1e-10
    sm = Term(causes.UNEXPLAINED, np.column_stack([A0[:, 0], time]), ("smooth[0]", "smooth[1]"), {}, "time",
              penalty=lam * np.eye(2), unnamed=True)
    rows = np.arange(n)
    wp, ident, _, Ge, _, cGe, shift = _workpiece(bl, [sm], y, rows, None, None)
    X = np.column_stack([np.eye(3)[tgt], (su == 1).astype(float), time])
    beta, rss = np.linalg.lstsq(X, y, rcond=None)[:2]
    cov = float(rss[0]) / (n - X.shape[1]) * np.linalg.inv(X.T @ X)
    assert ident
    assert np.allclose(Ge / UM, beta[:3] / UM, atol=1e-7, rtol=0)
    u95 = np.array([w["extended_u95_um"] for w in wp])
    assert not shift["carried_in_u95"], shift  # the U95 above is the data's alone only when the shift is noise
    assert np.allclose(u95, 2 * np.sqrt(np.diag(cov)[:3]) / UM, atol=1e-7, rtol=0)
    assert np.allclose(2 * np.sqrt(np.diag(cGe)) / UM, u95, atol=1e-12, rtol=0)


@pytest.mark.parametrize("drift_um", [0.0, 2.0])
def test_an_unnamed_smooths_workpiece_shift_is_tested_and_carried(drift_um):
    """Known answer: the shift of the workpiece an unnamed term makes, tested as Hausman's and carried in the U95.

    Three targets in two set-ups, four times each, target 0 always first in
    a set-up (so a drift with the time within each set-up moves it). The unnamed term is one column
    (time, ridge 1e-10: least squares to 1e-8 um, the ridge's bias being
    about 1e-10 x 2 um / |time outside the baseline|^2 = 2e-9 um). Textbook identity
    (Hausman 1978, one added column): the chi-square of the shift
    ``D = G_e - G_b`` against ``s^2 (L_e - L_b)(L_e - L_b)^T`` equals the
    squared t statistic of the added column's coefficient, ``(c / se(c))^2``
    with the extended fit's ``s``; computed here by ordinary least squares
    apart from the engine, to 1e-6 relative. With a 2 um drift the shift is
    real (t = 3.7, p = 2e-4 against
    the engine's 0.0025): the extended U95 must reach the baseline's answer at
    every target, ``U95_e^2 = U95_ols^2 + D^2`` to 1e-7 um (the engine
    before this rule gave ``U95_ols`` alone: an unnamed term's split of the
    effect between machine and part entered no uncertainty). Without the
    drift the shift is noise and the U95 stays the data's.
    """
    from types import SimpleNamespace

    from core.discover import Term, _workpiece

    rng = np.random.default_rng(11)
    tgt = np.tile(np.repeat(np.arange(3), 4), 2)
    su = np.repeat([0, 1], 12)
    n = tgt.size
    time = np.tile(np.arange(12), 2) / 12.0  # within each set-up
    A0 = np.hstack([np.eye(3)[tgt], np.eye(2)[su]])
    C = np.array([[0.0, 0, 0, 1, 0]])
    y = A0 @ np.array([3.0, -2.0, 1.0, 0.0, 5.0]) * UM + drift_um * UM * time \
        + 0.3 * UM * rng.standard_normal(n)
    bl = SimpleNamespace(estimand=np.arange(3), A=A0, C=C, d=np.zeros(1), n=n, estimand_ids=("a", "b", "c"))
    sm = Term(causes.UNEXPLAINED, time[:, None], ("smooth[0]",), {}, "time", penalty=1e-10 * np.eye(1),
              unnamed=True)
    wp, ident, Gb, Ge, _, cGe, shift = _workpiece(bl, [sm], y, np.arange(n), None, None)
    X0 = np.column_stack([np.eye(3)[tgt], (su == 1).astype(float)])
    X1 = np.column_stack([X0, time])
    b0 = np.linalg.lstsq(X0, y, rcond=None)[0]
    b1, rss = np.linalg.lstsq(X1, y, rcond=None)[:2]
    s2 = float(rss[0]) / (n - X1.shape[1])
    cov1 = s2 * np.linalg.inv(X1.T @ X1)
    t2 = b1[-1] ** 2 / cov1[-1, -1]
    assert shift["dof"] == 1
    assert abs(shift["chi2"] / t2 - 1) < 1e-6, (shift["chi2"], t2)
    D = (b1[:3] - b0[:3]) / UM
    assert np.allclose((Ge - Gb) / UM, D, atol=1e-8, rtol=0), ((Ge - Gb) / UM - D)
    u95 = np.array([w["extended_u95_um"] for w in wp])
    u95_ols = 2 * np.sqrt(np.diag(cov1)[:3]) / UM
    assert shift["carried_in_u95"] == (drift_um > 0), shift
    want = np.sqrt(u95_ols ** 2 + D ** 2) if drift_um > 0 else u95_ols
    assert np.allclose(u95, want, atol=1e-7, rtol=0), (u95, want)
    if drift_um > 0:
        assert np.all(u95 >= np.abs(D))  # the U95 reaches the baseline's answer at every target


def test_a_knock_whose_every_later_touch_is_an_outlier_is_not_dust():
    """gen_a knock 811: the part knocked in set-up C198 with a quarter of its touches (12 of 48) left; all 12
    touches after the knock are beyond the outlier bound, so none is left for the set-up's other touches to
    show the step. Twelve outliers that one rigid step (three parameters) leaves all within the bound agree
    with it beyond what chips would: structure, kept, 'unexplained' (the generator's truth: out of the
    catalogue). Requiring the other touches to see the step in every case called them dust ('outlier')."""
    from scenarios.blind import gen_a

    log, truth = gen_a.generate("knock", 811)
    rep = discovered(log).to_report()
    assert rep["cause"] in truth.acceptable_causes, rep["cause"]
    assert rep["outlier_rows"] == [], rep["outlier_rows"]


def test_a_cause_rejected_without_its_largest_touches_is_judged_with_them():
    """gen_b local_scale_defect 829 and 1003: the bump's largest touches (6 at 829, residuals 1-4.6 um at
    0.21 um noise) are set aside as outliers, the local scale defect adopted on the rest, then refused by
    the rival check (a fixture slip 'explains as much' of what is left). Judged again with the touches put
    back (those whose residual it cuts by a quarter or more) it stands: they were its structure, and the
    report says how many came back.
    The generator's truth names the defect. Without the re-judging (commit a206ffa) both read 'outlier',
    confidently. Since the defect's half-widths reach the positions' resolution (core.causes.DEFECT_WIDTHS,
    issue 13, session 14) the first screen's model holds the bump at its width and sets none of its touches
    aside: nothing is put back (the rule's own test: tests/core/test_discover_defect.py, by hand)."""
    from scenarios.blind import gen_b

    for seed in (829, 1003):
        log, truth = gen_b.generate("local_scale_defect", seed)
        rep = discovered(log).to_report()
        assert rep["cause"] in truth.acceptable_causes, (seed, rep["cause"])
        # put back: the touches the defect reaches; any left set aside is one it does not reach (1003: row
        # 151, residual 1.9 um, the defect's true effect there 0.0 um, cut 15 %: not its structure)
        e = np.abs(truth.effect_dq_um)
        assert all(e[r] < 0.05 * e.max() for r in rep["outlier_rows"]), (seed, rep["outlier_rows"])
        assert rep["findings"][0]["evidence"].get("outliers_put_back", 0) == 0, rep["findings"][0]["evidence"]
        # the baseline judged on the rows the report keeps: the touches put back are structure
        assert rep["structure"]["baseline"]["present"], (seed, rep["structure"]["baseline"])


def test_a_chip_beside_a_cause_put_back_stays_an_outlier():
    """gen_b local_scale_defect 829 with a 5 um chip on row 87, where the defect is nil (the reviewer's
    chip.py): the put-back was all or nothing, so the chip came back with the bump's touches and was
    reported as the defect's structure (outlier_rows []). Only the set-aside touches whose residual the
    defect cuts by a quarter or more come back (the bump's 6: cut 47-82 %; the chip's: 5 %): the defect
    is named, the chip stays an outlier, the 6 are put back. Since the defect's half-widths reach the
    positions' resolution (core.causes.DEFECT_WIDTHS, session 14) the bump's touches are never set aside:
    the chip is the only outlier and nothing is put back."""
    from scenarios.blind import gen_b

    log, truth = gen_b.generate("local_scale_defect", 829)
    assert abs(truth.effect_dq_um[87]) < 0.01  # the defect does not reach the chip's touch
    t = from_log(log)
    i = np.flatnonzero(t.row == 87)[0]
    t.p_R[i] += t.n_R[i] * 5e-6
    rep = discovered(log, t).to_report()
    assert rep["cause"] in truth.acceptable_causes, rep["cause"]
    assert rep["outlier_rows"] == [87], rep["outlier_rows"]
    assert rep["findings"][0]["evidence"].get("outliers_put_back", 0) == 0, rep["findings"][0]["evidence"]
    assert rep["structure"]["baseline"]["present"], rep["structure"]["baseline"]


def test_the_baseline_is_judged_on_the_rows_the_report_keeps(monkeypatch):
    """gen_b outlier 945: the report keeps other rows than the first screen's (15, 25, 31 set aside in
    the end) and the baseline's structure was reported from the first screen's rows: 'present': False
    beside a named cause. Judged again on the final rows, it is present. (The cause named here, with
    INSIDE_SMOOTH_REFUSED off, is not the generator's 'outlier': a wrong answer this test does not pin; it pins
    the report's consistency. With the rule on, as shipped since session 36, the bump is refused and the
    campaign reads `outlier`, right.)"""
    from core import discover as D
    from scenarios.blind import gen_b

    log, truth = gen_b.generate("outlier", 945)
    monkeypatch.setattr(D, "INSIDE_SMOOTH_REFUSED", False)
    rep = discovered(log).to_report()
    assert rep["cause"] not in ("outlier", "unexplained", None), rep["cause"]
    assert rep["structure"]["baseline"]["present"], rep["structure"]["baseline"]
    monkeypatch.setattr(D, "INSIDE_SMOOTH_REFUSED", True)
    assert discovered(log).to_report()["cause"] == "outlier"


def test_a_slips_turn_explains_its_outliers_and_dust_alone_does_not():
    """``_slip_explains``' second condition (no more outliers than the step's parameters), hand-built: four set-ups
    of 50 touches in time order, one offset per set-up; a trial step (every fifth touch a start) moves every touch
    of its set-up from its start on by a translation and a turn, ``a + b L`` (L the touch's lever arm about the
    turn's centre). Two outliers on set-up 0's touches 48 and 49 (levers +3 and -3).

    Dust: chips of +20 and -20 sigma, touches 45-47 near the turn's centre and unmoved: not explained. A real turn
    from touch 45 (levers 1.5, -1.5, 1.2 for 45-47, moved with 48-49): explained, at +-20 sigma on the outliers
    (10, -10, 8 sigma on 45-47) and at a moderate +-8 (4.0, -4.0, 3.2 sigma on 45-47)."""
    from core import discover as D

    rng = np.random.default_rng(11)
    G, m = 4, 50
    n = G * m
    events = np.repeat(np.arange(G), m)
    k = np.arange(n) % m
    X = (events[:, None] == np.arange(G)).astype(float)
    L = rng.normal(size=n)
    L[[45, 46, 47, 48, 49]] = [0.1, -0.1, 0.05, 3.0, -3.0]
    starts = [(g, t) for g in range(G) for t in range(5, m, 5)]

    def slips():
        C = np.zeros((len(starts), n, 2))
        for i, (g, t) in enumerate(starts):
            on = ((events == g) & (k >= t)).astype(float)
            C[i, :, 0], C[i, :, 1] = on, on * L
        return C

    noise = rng.normal(size=n)
    chips = np.zeros(n)
    chips[[48, 49]] = [20.0, -20.0]
    out = [48, 49]
    assert not D._slip_explains(X, noise + chips, out, events, slips, 0.001, 0.0025)
    L[[45, 46, 47]] = [1.5, -1.5, 1.2]  # the turn's centre elsewhere: touches 45-47 move with 48-49
    for b in (20.0 / 3.0, 8.0 / 3.0):
        turn = np.where((events == 0) & (k >= 45), b * L, 0.0)
        assert D._slip_explains(X, noise + turn, out, events, slips, 0.001, 0.0025), b


def test_slip_explains_judges_only_what_the_step_does_not_fit_exactly():
    """core.discover._slip_explains, condition 1 (hand-built, noise 1): outliers a step's columns fit
    exactly (leverage 1: an indicator column each) have no deleted residual and are not judged; with every
    outlier so, the step explains nothing (the old code refused it for any such row). One such row (a 50
    sigma chip) beside four outliers that a real step moves (20 sigma, rows 11-19) is explained along with
    them, without evidence of its own (s11_diag; the old code refused the whole step for the one row)."""
    from core.discover import _slip_explains

    rng = np.random.default_rng(0)
    n = 60
    X, y = np.ones((n, 1)), rng.normal(0, 1, n)
    events = np.repeat([0, 1, 2], 20)
    ind = lambda i: (np.arange(n) == i).astype(float)  # noqa: E731

    def slips(*cols):
        C = np.zeros((1, n, 3))
        for j, c in enumerate(cols):
            C[0, :, j] = c
        return lambda: C

    y1 = y.copy()
    y1[[10, 11]] += [30, -25]
    assert not _slip_explains(X, y1, [10, 11], events, slips(ind(10), ind(11), 0 * y), 0.05, 0.05)
    step = ((np.arange(n) >= 11) & (np.arange(n) < 20)).astype(float)
    y2 = y + 20 * step
    y2[10] += 50
    assert _slip_explains(X, y2, [10, 11, 12, 13, 14], events, slips(ind(10), step, step * np.arange(n)), 0.05, 0.05)


def test_slip_veto_places_the_step_at_its_own_first_touch():
    """core.discover._slip_explains with trials kept as quantile splits (core.diagnosis.StepTrials, 40 per set-up
    of 100 touches: a split every 2-3 touches): three set-ups in time order, one offset each; set-up 1's part
    turns from its touch 38 on (not a split: the trials start at 36 and 39), ``2 L`` with L the touch's lever,
    noise 0.3. Its eight touches of lever 2.5-3 are the outliers, 138 (the step's first) among them. The best
    trial starts at 39 (36 would also move 136-137, unmoved levers of 2.5) and leaves 138 at the step's full
    6 (20 sigma): before session 22 the step was refused and the eight read as dust. Refined to the touch
    (core.discover._exact_step), the step from 38 explains them. The same eight rows as chips of +-6 whose
    signs do not follow the lever are not explained."""
    from core import discover as D
    from core.diagnosis import StepTrials

    rng = np.random.default_rng(5)
    G, m = 3, 100
    n = G * m
    events = np.repeat(np.arange(G), m)
    k = np.arange(n) % m
    X = (events[:, None] == np.arange(G)).astype(float)
    phi = rng.uniform(0, 2 * np.pi, n)
    L = rng.normal(0, 0.2, n)
    L[[136, 137]] = [2.5, -2.5]
    rows = [138, 141, 150, 157, 163, 170, 181, 192]
    L[rows] = [3.0, -3.0, 2.5, -2.8, 3.0, -2.6, 2.7, -3.0]
    M = np.column_stack([np.cos(phi), np.sin(phi), L])
    grid = np.unique(np.round(np.linspace(1, m - 1, 40)).astype(int))
    assert 38 not in grid and {36, 39} <= set(grid.tolist())
    slips = lambda: StepTrials(M, [(np.flatnonzero(events == g), grid) for g in range(G)])  # noqa: E731
    noise = 0.3 * rng.normal(size=n)
    y = noise + np.where((events == 1) & (k >= 38), 2.0 * L, 0.0)
    out = D.find_outliers(X, y, 0.001, 0.05)
    assert out == rows, out
    assert D._slip_explains(X, y, out, events, slips, 0.001, 0.0025)
    chips = np.zeros(n)
    chips[rows] = 6.0 * np.array([1, 1, -1, 1, -1, -1, 1, 1])
    out = D.find_outliers(X, noise + chips, 0.001, 0.05)
    assert out == rows, out
    assert not D._slip_explains(X, noise + chips, out, events, slips, 0.001, 0.0025)


def test_slip_veto_asks_the_other_touches_where_the_step_fits_every_outlier_exactly(monkeypatch):
    """core.discover._slip_explains where the step fixes its turn on the outliers themselves (session 25,
    ``SLIP_UNJUDGED_BY_OTHERS``; gen_a knock 6109): three set-ups of 100 touches, each its own rigid placement
    (two translations and a turn); set-up 1's touches 0-37 are turn-blind and along X only (like the bores and
    bosses before 6109's knock), 38 and 39 generic, and the part steps from touch 40 by (0.5, 3, 2) along
    (cos, sin, lever), noise 0.3. The set-up's placement takes the step's mean, so 138 and 139, the only touches
    before it that see Y and the turn, are the outliers; beside the step they fit exactly (leverage 1): none is
    judged, and before session 25 the step was refused unasked (dust). With the rule the set-up's other touches
    decide: with 138 and 139 set aside they see the step's X part (F test at 0.0025 over the set-up's trials).
    Chips of +-6 on the same two touches, no step: the other touches see nothing, dust either way."""
    from core import discover as D
    from core.diagnosis import StepTrials

    rng = np.random.default_rng(7)
    G, m = 3, 100
    n = G * m
    events = np.repeat(np.arange(G), m)
    k = np.arange(n) % m
    phi = rng.uniform(0, 2 * np.pi, n)
    L = rng.normal(0, 1.0, n)
    pre = (events == 1) & (k < 38)
    phi[pre], L[pre] = 0.0, 0.0
    M = np.column_stack([np.cos(phi), np.sin(phi), L])
    X = np.hstack([M * (events == g)[:, None] for g in range(G)])
    grid = np.unique(np.round(np.linspace(1, m - 1, 40)).astype(int))
    slips = lambda: StepTrials(M, [(np.flatnonzero(events == g), grid) for g in range(G)])  # noqa: E731
    noise = 0.3 * rng.normal(size=n)
    moved = (events == 1) & (k >= 40)
    y = noise + np.where(moved, M @ np.array([0.5, 3.0, 2.0]), 0.0)
    out = D.find_outliers(X, y, 0.001, 0.05)
    assert out == [138, 139], out
    Q = np.linalg.qr(np.hstack([X, np.where(moved[:, None], M, 0.0)]))[0]
    assert np.all(D.leverage(Q)[out] > 0.99)  # the step fits them exactly: the first condition judges none
    assert D._slip_explains(X, y, out, events, slips, 0.001, 0.0025)
    monkeypatch.setattr(D, "SLIP_UNJUDGED_BY_OTHERS", False)
    assert not D._slip_explains(X, y, out, events, slips, 0.001, 0.0025)  # the rule before: dust
    chips = np.zeros(n)
    chips[[138, 139]] = [6.0, -6.0]
    out = D.find_outliers(X, noise + chips, 0.001, 0.05)
    assert out == [138, 139], out
    for on in (False, True):
        monkeypatch.setattr(D, "SLIP_UNJUDGED_BY_OTHERS", on)
        assert not D._slip_explains(X, noise + chips, out, events, slips, 0.001, 0.0025)


def test_exact_step_refines_a_long_setups_split_to_the_touch():
    """core.discover._exact_step on a set-up of 3,000 touches (40 quantile splits, one every 77 touches, then
    40 between the best's neighbours, then every touch): a noiseless step from touch 1,237 of random columns is
    found at 1,237, its columns the trial's on exactly those rows."""
    from core import discover as D
    from core.diagnosis import StepTrials

    rng = np.random.default_rng(2)
    n = 3000
    M = rng.normal(size=(n, 3))
    grid = np.unique(np.round(np.linspace(1, n - 1, 40)).astype(int))
    assert 1237 not in grid
    Cs = StepTrials(M, [(np.arange(n), grid)])
    y = np.where(np.arange(n) >= 1237, M @ np.array([1.0, -2.0, 0.5]), 0.0)
    Q0 = np.ones((n, 1)) / np.sqrt(n)
    r0 = y - Q0 @ (Q0.T @ y)
    ss, _, _, _ = D.nested_f_trials(Cs, None, Q0, r0, float(r0 @ r0), n - 1)
    C = D._exact_step(Cs, int(np.argmax(ss)), Q0, r0)
    np.testing.assert_array_equal(C, np.where((np.arange(n) >= 1237)[:, None], M, 0.0))


def test_nonrigid_field_known_answer():
    """A non-rigid field in the form the penalised named term fits (P2(xs) P2(ys) in E_X, 6 um at the corner,
    0.3 um noise): named nonrigid, its field's RMS and peak over the probed extent within their U95 of the truth
    (the same magnitudes of the true coefficients), the other axis' field within its U95 of zero.

    One seed, a known answer, not a coverage claim (that is tests/core/test_discover_nonrigid_u95.py's, over 40
    seeds, with the bootstrap's U95 of session 16; the ridge's Bayesian U95 before it missed on seeds 102, 105 and
    113 of this campaign, docs/discovery.md, session 15). The last assertion (U95 of the peak under half of it)
    says the magnitude is determined at all, not how well."""
    from core import causes

    t, _ = S.campaign("nonrigid_field", 100, 6e-6)
    d = discover(t)
    rep = d.to_report()
    assert rep["cause"] == "nonrigid", [(f["cause"], f["evidence"].get("reason")) for f in rep["findings"]]
    f = rep["findings"][0]
    axes = f["params"]["axes"]
    coef = np.zeros(6 * len(axes))
    coef[6 * axes.index("X") + 4] = 6e-6  # the P2 P2 product of X (labels P1P1, P1P2, P1P3, P2P1, P2P2, P3P1)
    truth = causes.nonrigid_magnitudes({"axes": axes}, coef, d.baseline)
    assert abs(truth["EX_field_peak_um"]) > 4.0  # (the probed extent reaches near a corner)
    for k, v in truth.items():
        u = f["params_u95"][k]
        assert u is not None and abs(f["params"][k] - v) <= u, (k, f["params"][k], v, u)
    assert f["params_u95"]["EX_field_peak_um"] < 0.5 * abs(truth["EX_field_peak_um"])  # a determined magnitude
    # its workpiece shift is tested and carried, said to be the penalty's split (it read "a cause whose magnitudes
    # this design does not determine" until the review; the finding carried no workpiece_shift)
    moved = [c for c in rep["conventions"] if "moves the workpiece" in c]
    assert len(moved) == 1 and moved[0].startswith("the penalised nonrigid moves") and "the penalty's" in moved[0]
    assert "workpiece_shift" in f["evidence"]


def test_penalised_fit_bad_input():
    from core.discover import _penalised_fit

    E = np.random.default_rng(0).normal(size=(20, 3))
    r = E @ np.array([1.0, -2.0, 0.5])
    c, cov, s2, edf = _penalised_fit(E, r, 1e-9 * np.eye(3), 20)
    assert np.allclose(c, [1.0, -2.0, 0.5], atol=1e-6) and 2.99 < edf <= 3.0  # (a known answer: no noise)
    # with noise and a real ridge, against the formulas written out here: c = (G + P)^-1 E^T r, edf the trace
    # of (G + P)^-1 G, s^2 the residual sum of squares over dof0 - edf, covariance s^2 (G + P)^-1
    rn = r + np.random.default_rng(1).normal(size=20)
    P = np.diag([0.0, 2.0, 5.0])
    c, cov, s2, edf = _penalised_fit(E, rn, P, 17)
    Mi = np.linalg.inv(E.T @ E + P)
    c_ref = Mi @ E.T @ rn
    edf_ref = np.trace(Mi @ E.T @ E)
    s2_ref = np.sum((rn - E @ c_ref) ** 2) / (17 - edf_ref)
    assert np.allclose(c, c_ref, rtol=1e-12) and abs(edf - edf_ref) < 1e-12 and 2.0 < edf < 3.0
    assert np.isclose(s2, s2_ref, rtol=1e-12) and np.allclose(cov, s2_ref * Mi, rtol=1e-10)
    with pytest.raises(ValueError, match="do not match"):
        _penalised_fit(E, r[:-1], np.eye(3), 20)
    with pytest.raises(ValueError, match="do not match"):
        _penalised_fit(E, r, np.eye(2), 20)
    with pytest.raises(ValueError, match="non-finite"):
        _penalised_fit(E, np.where(np.arange(20) == 3, np.nan, r), np.eye(3), 20)
    with pytest.raises(ValueError, match="non-negative"):
        _penalised_fit(E, r, -np.eye(3), 20)
    with pytest.raises(ValueError, match="non-negative"):  # negative beyond its own size (no absolute floor)
        _penalised_fit(E, r, -1e-13 * np.eye(3), 20)
