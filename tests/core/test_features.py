"""Feature fits of a log (core.features), U95 and form (core.fit), the planar scope check (core.scope)."""

import numpy as np
import pytest

from core.exceptions import ConfigError, FitError, IdentifiabilityError
from core.features import fit_log_feature
from core.fit import coverage_factor, fit_plane, fit_sphere, form_deviation, u95
from core.probelog import make_log
from core.scope import check_planar_scope


def log_of(p_mm, n, *, feature="f", setup=None, stylus_r_mm=0.0, status=None, nominal=None):
    p_mm, n = np.asarray(p_mm, float), np.asarray(n, float)
    pn = p_mm if nominal is None else np.asarray(nominal, float)
    k = len(p_mm)
    cols = {"setup": setup if setup is not None else ["s1"] * k, "target": [f"t{i}" for i in range(k)],
            "t_s": np.arange(k, dtype=float), "X_mm": p_mm[:, 0], "Y_mm": p_mm[:, 1], "Z_mm": p_mm[:, 2],
            "Xn_mm": pn[:, 0], "Yn_mm": pn[:, 1], "Zn_mm": pn[:, 2],
            "nx": n[:, 0], "ny": n[:, 1], "nz": n[:, 2], "feature": [feature] * k}
    if status is not None:
        cols["status"] = status
        bad = np.array(status) != "ok"
        for c in ("t_s", "X_mm", "Y_mm", "Z_mm"):
            cols[c] = np.where(bad, np.nan, cols[c])
    return make_log(cols, {"stylus_r_mm": repr(stylus_r_mm)})


def test_coverage_factor_is_student_t():
    # JCGM 100 Table G.2: t_95.45 ... here the two-sided 95 % points, from any t table
    assert coverage_factor(5) == pytest.approx(2.5706, abs=1e-4)
    assert coverage_factor(30) == pytest.approx(2.0423, abs=1e-4)
    assert np.isnan(coverage_factor(0))


def test_plane_known_answer_form_and_stylus():
    """A cosine bump of known amplitude on a tilted plane, 2 mm stylus on top."""
    x, y = np.meshgrid(np.linspace(0, 100, 11), np.linspace(0, 60, 7))
    x, y = x.ravel(), y.ravel()
    bump = 2e-3 * np.cos(2 * np.pi * x / 100) * np.cos(2 * np.pi * y / 60)   # mm, zero mean on this grid
    z_surf = 5.0 + bump                                   # surface height, mm
    p = np.column_stack([x, y, z_surf + 2.0])             # tip centres, 2 mm radius, probed from above
    rep = fit_log_feature(log_of(p, np.tile([0, 0, 1.0], (len(x), 1)), stylus_r_mm=2.0), "plane")
    assert rep.values["point_mm"][2] == pytest.approx(5.0 + bump.mean(), abs=1e-9)
    assert np.allclose(rep.values["normal"], [0, 0, 1], atol=1e-9)
    # the grid samples each cosine symmetrically: LS removes no tilt, form = ptp of the bump
    assert rep.form_um == pytest.approx(np.ptp(bump) * 1e3, abs=1e-6)
    assert np.allclose(rep.residuals_um, (bump - bump.mean()) * 1e3, atol=1e-6)


def test_sphere_and_circle_stylus_side():
    rng = np.random.default_rng(1)
    u = rng.normal(size=(30, 3))
    u[:, 2] = np.abs(u[:, 2])
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    c = np.array([10.0, 20.0, 30.0])
    ball = fit_log_feature(log_of(c + (12.5 + 1.5) * u, u, stylus_r_mm=1.5), "sphere")
    assert ball.values["side"] == "outside" and ball.values["radius_mm"] == pytest.approx(12.5, abs=1e-9)
    a = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    rad = np.column_stack([np.cos(a), np.sin(a), np.zeros(12)])
    bore = fit_log_feature(log_of(c + (20.0 - 1.5) * rad, -rad, stylus_r_mm=1.5), "circle")
    assert bore.values["side"] == "inside" and bore.values["radius_mm"] == pytest.approx(20.0, abs=1e-9)
    assert np.allclose(bore.values["centre_mm"], c[:2], atol=1e-9)


def test_u95_covers_the_truth_in_a_noise_round_trip():
    """truth -> seeded noise -> plane and sphere: the error is within U95 in about 95 % of trials."""
    rng = np.random.default_rng(20261201)
    x, y = np.meshgrid(np.linspace(-50, 50, 5), np.linspace(-30, 30, 4))
    P0 = np.column_stack([x.ravel(), y.ravel(), 1e-3 * x.ravel()]) * 1e-3      # m, tilt 1 mrad about Y
    n_true = np.array([-1e-3, 0, 1]) / np.linalg.norm([-1e-3, 0, 1])
    hits, trials = 0, 400
    for _ in range(trials):
        P = P0 + 1e-6 * rng.standard_normal(len(P0))[:, None] * n_true
        f = fit_plane(P, normal_hint=[0, 0, 1])
        tilt = (f.normal - n_true) @ f.basis[0]
        hits += abs(tilt) <= u95(f)["tilt_u"]
    assert 0.92 * trials <= hits <= 0.98 * trials            # binomial 95 %: 380 +- 9 at 2 sigma
    u = np.random.default_rng(3).normal(size=(40, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    hits = 0
    for _ in range(trials):
        P = (0.0125 + 1e-6 * rng.standard_normal(40))[:, None] * u
        f = fit_sphere(P)
        hits += abs(f.radius - 0.0125) <= u95(f)["radius"]
    assert 0.92 * trials <= hits <= 0.98 * trials
    assert form_deviation(f) == pytest.approx(np.ptp(f.residuals))


@pytest.mark.parametrize("kind, kw, exc, msg", [
    ("cone", {}, ConfigError, "feature kind 'cone'"),
    ("plane", {"feature": "nope"}, ConfigError, "no feature 'nope'"),
    ("sphere", {}, FitError, "sphere fit"),
])
def test_fit_log_feature_bad_input(kind, kw, exc, msg):
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    with pytest.raises(exc, match=msg):
        fit_log_feature(log_of(p, np.tile([0, 0, 1.0], (3, 1))), kind, **kw)


def test_scope_names_the_real_reason():
    zgrid = log_of(np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0.0], [10, 10, 0]]), np.tile([0, 0, 1.0], (4, 1)))
    with pytest.raises(IdentifiabilityError, match=r"no touch has a normal in the XY plane.*vmt fit plane"):
        check_planar_scope(zgrid)
    u = np.random.default_rng(0).normal(size=(8, 3))
    u[:, 2] = np.abs(u[:, 2]) + 0.5
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    with pytest.raises(IdentifiabilityError, match="vmt fit sphere"):
        check_planar_scope(log_of(12.5 * u, u), "discover")
    dead = log_of(zgrid.positions_mm(), zgrid.normals(), status=["no_trigger", "aborted", "aborted", "aborted"])
    with pytest.raises(IdentifiabilityError, match="no valid touch.*3 aborted, 1 no_trigger"):
        check_planar_scope(dead)
    a = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    rad = np.column_stack([np.cos(a), np.sin(a), np.zeros(6)])
    with pytest.raises(IdentifiabilityError, match="one set-up"):
        check_planar_scope(log_of(20 * rad, rad))
    check_planar_scope(log_of(20 * rad, rad, setup=["C0"] * 3 + ["C90"] * 3))      # in scope: no error


def test_stylus_radius_given_from_the_log_or_refused():
    """Session 26: a log that says no stylus radius was fitted with 0, a sphere's radius then wrong by the stylus
    radius with only a notice. Now: the log's radius (column, else metadata) by default, a given one wins (a
    qualified, effective radius), none at all is refused; 0 given is a pin or a tool used as the probe."""
    from core.features import NoStylusRadius

    rng = np.random.default_rng(1)
    u = rng.normal(size=(30, 3))
    u[:, 2] = np.abs(u[:, 2])
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    c = np.array([10.0, 20.0, 30.0])
    tips = c + (12.5 + 1.5) * u                                   # a 12.5 mm ball probed with a 1.5 mm tip
    said = log_of(tips, u, stylus_r_mm=1.5)
    r = fit_log_feature(said, "sphere")
    assert r.values["radius_mm"] == pytest.approx(12.5, abs=1e-9)
    assert (r.stylus_r_source, r.log_stylus_r_mm) == ("metadata", 1.5)
    r = fit_log_feature(said, "sphere", stylus_r_mm=1.4987)     # the qualified radius wins: 12.5 + 0.0013
    assert r.values["radius_mm"] == pytest.approx(12.5013, abs=1e-9)
    assert (r.stylus_r_source, r.log_stylus_r_mm) == ("given", 1.5)
    cols = dict(said.columns)
    cols["stylus_r_mm"] = np.full(said.n, 1.5)
    from core.probelog import make_log as mk

    assert fit_log_feature(mk(cols, {}), "sphere").stylus_r_source == "column"
    silent = mk(dict(said.columns), {})                          # no column, no metadata
    with pytest.raises(NoStylusRadius, match="says no stylus radius"):
        fit_log_feature(silent, "sphere")
    assert issubclass(NoStylusRadius, ConfigError)
    r = fit_log_feature(silent, "sphere", stylus_r_mm=0.0)       # explicit 0: the tip-centre sphere itself
    assert r.values["radius_mm"] == pytest.approx(14.0, abs=1e-9) and r.log_stylus_r_mm is None
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ConfigError, match="need a finite number >= 0"):
            fit_log_feature(said, "sphere", stylus_r_mm=bad)


def test_touches_of_several_setups_or_features_are_refused_not_fitted_as_one():
    """review30 F1: a pin's 8 set-ups fitted as one circle gave a 197 mm radius for a 6 mm pin, exit 0.
    Two 6 mm pins (two set-ups, or two features) 200 mm apart: one at a time fits exactly; together refused."""
    from core.features import MixedRows

    a = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    rad = np.column_stack([np.cos(a), np.sin(a), np.zeros(8)])
    p = np.vstack([[0.0, 0, 5] + 6.0 * rad, [200.0, 0, 5] + 6.0 * rad])
    n = np.vstack([rad, rad])
    two_setups = log_of(p, n, setup=["C0"] * 8 + ["C90"] * 8)
    assert fit_log_feature(two_setups, "circle", setup="C90").values["radius_mm"] == pytest.approx(6.0, abs=1e-9)
    with pytest.raises(MixedRows, match=r"span 2 set-ups \(C0, C90\).*pick one with setup=NAME$") as e:
        fit_log_feature(two_setups, "circle")
    assert e.value.spans == {"setup": ["C0", "C90"]} and isinstance(e.value, ConfigError)
    lg = log_of(p, n)
    lg.columns["feature"] = np.array(["pinA"] * 8 + ["pinB"] * 8, dtype=object)
    with pytest.raises(MixedRows, match=r"span 2 features \(pinA, pinB\).*pick one with feature=NAME$"):
        fit_log_feature(lg, "sphere")
    assert fit_log_feature(lg, "circle", feature="pinA").values["radius_mm"] == pytest.approx(6.0, abs=1e-9)
    # rows already excluded (status not ok) do not count: one valid set-up is one set-up
    st = ["ok"] * 8 + ["miss"] * 8
    one_ok = log_of(p, n, setup=["C0"] * 8 + ["C90"] * 8, status=st)
    assert fit_log_feature(one_ok, "circle").values["radius_mm"] == pytest.approx(6.0, abs=1e-9)


def test_setup_names_listed_as_numbers_where_they_are_numbers():
    """Session 30: vmt fit's refusal listed the set-ups sorted as text (set-up 10 before 2, C137 before C31).
    Numbers sort by value, digit runs inside a name as integers; the unknown-name line lists them alike."""
    from core.features import MixedRows, name_order

    assert sorted(["10", "2", "-30", "7.5", "1e3"], key=name_order) == ["-30", "2", "7.5", "10", "1e3"]
    assert sorted(["C137", "C31", "C2", "pin10", "pin2", "C01", "C1", "", "nan"], key=name_order) == [
        "", "C01", "C1", "C2", "C31", "C137", "nan", "pin2", "pin10"]
    assert sorted(["C31", "2", "C137", "10"], key=name_order) == ["2", "10", "C31", "C137"]   # numbers first
    a = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    rad = np.column_stack([np.cos(a), np.sin(a), np.zeros(8)])
    names = ["10", "2", "C137", "C31"]
    p = np.vstack([[200.0 * k, 0, 5] + 6.0 * rad for k in range(4)])
    lg = log_of(p, np.vstack([rad] * 4), setup=[s for s in names for _ in range(8)])
    with pytest.raises(MixedRows, match=r"span 4 set-ups \(2, 10, C31, C137\)") as e:
        fit_log_feature(lg, "circle")
    assert e.value.spans == {"setup": ["2", "10", "C31", "C137"]}
    with pytest.raises(ConfigError, match=r"no setup 'C3' \(valid touches have: 2, 10, C31, C137\)"):
        fit_log_feature(lg, "circle", setup="C3")


def _wall(heights, *, noise_um=0.0, seed=5, r=2.0):
    """review31 F1's wall: x = 50 mm, normal (-1, 0, 0), touched every 10 mm of y at ``heights`` with a ``r`` mm tip;
    the noise along the normal (x) only, nominals the plan's (printed to 6 decimals, as vmt writes)."""
    y, z = np.meshgrid(np.arange(-40.0, 41.0, 10.0), np.asarray(heights, float))
    k = y.size
    pn = np.column_stack([np.full(k, 50.0 - r), y.ravel(), z.ravel()])
    p = pn.copy()
    p[:, 0] += np.round(noise_um * 1e-3 * np.random.default_rng(seed).standard_normal(k), 6)
    return p, pn, np.tile([-1.0, 0, 0], (k, 1))


def test_wall_at_two_heights_known_answer_and_one_height_refused():
    """review31 F1: a wall probed along one height was fitted as the horizontal plane z = -7 (the radius applied
    vertically), flatness and every U95 0, exit 0. At two heights the fit is the wall (x = 50, normal -x); at one
    the touches lie on one line: refused, naming the feature and the set-up."""
    from core.features import NORMAL_AGREE_MAX_DEG

    p, pn, n = _wall([-5.0, -10.0])
    r = fit_log_feature(log_of(p, n, nominal=pn, feature="wallE", setup=["C0"] * len(p), stylus_r_mm=2.0), "plane")
    assert r.values["point_mm"][0] == pytest.approx(50.0, abs=1e-9)      # exact points: rounding only
    assert np.allclose(r.values["normal"], [-1, 0, 0], atol=1e-12) and r.normal_angle_deg < 1e-4
    p, pn, n = _wall([-5.0, -10.0], noise_um=0.3)                          # noise: the truth within U95
    r = fit_log_feature(log_of(p, n, nominal=pn, stylus_r_mm=2.0), "plane")
    assert abs(r.values["point_mm"][0] - 50.0) * 1e3 <= r.u95["offset_n_um"]
    assert r.normal_angle_deg < 0.01 < NORMAL_AGREE_MAX_DEG
    p, pn, n = _wall([-5.0], noise_um=0.3)
    with pytest.raises(FitError, match=r"plane fit \(feature wallE, set-up C0\): the touches lie on one line: a plane "
                                       r"needs two heights / two directions \(.*printing step"):
        fit_log_feature(log_of(p, n, nominal=pn, feature="wallE", setup=["C0"] * len(p), stylus_r_mm=2.0), "plane")


def test_one_line_test_reads_a_whole_mm_log_as_printed_to_at_most_1_um(monkeypatch):
    """A hand-written log of whole millimetres reads as printed to 1 mm (decimal_quantum): without the cap
    (ONE_LINE_STEP_MAX_MM, 1 um) its 2 mm tolerance refused a wall probed at heights 1 mm apart. Heights 0.5 um
    apart (0.25 um RMS from one line, under 2 x 1 um) are one line."""
    import core.features as cf

    assert cf.ONE_LINE_STEP_MAX_MM == 1e-3 and cf.ONE_LINE_QUANTA == 2.0
    p, pn, n = _wall([-5.0, -6.0])
    lg = log_of(p, n, nominal=pn, stylus_r_mm=2.0)
    r = fit_log_feature(lg, "plane")
    assert r.values["point_mm"][0] == pytest.approx(50.0, abs=1e-9)
    p, pn, n = _wall([-5.0, -5.0005])
    with pytest.raises(FitError, match=r"one line.*0.00025 mm RMS"):
        fit_log_feature(log_of(p, n, nominal=pn, stylus_r_mm=2.0), "plane")
    monkeypatch.setattr(cf, "ONE_LINE_STEP_MAX_MM", 1.0)         # no cap: the 1 mm apart wall refused
    with pytest.raises(FitError, match=r"one line.*0.5 mm RMS.*printing step 1 mm"):
        fit_log_feature(lg, "plane")


def _boss(z_levels, *, R=10.0, r=1.0, k=8):
    a = np.linspace(0, 2 * np.pi, k, endpoint=False)
    rad = np.column_stack([np.cos(a), np.sin(a), np.zeros(k)])
    p = np.vstack([(R + r) * rad + [0, 0, z] for z in z_levels])
    return p, np.vstack([rad] * len(z_levels))


def test_boss_round_one_height_is_a_circle_not_a_plane_nor_a_cylinder():
    """review31 F1's boss: touched round one height, vmt fit plane gave the plane z = -6, U95 0, and fit cylinder an
    axis with a 1.8e6 urad tilt U95. Now the plane is refused by the normals (90 deg to every touch's), the
    cylinder as one height; the circle is the answer (known radius), and two heights make the cylinder."""
    p, n = _boss([-5.0])
    lg = log_of(p, n, feature="boss", setup=["S1"] * len(p), stylus_r_mm=1.0)
    with pytest.raises(FitError, match=r"plane fit \(feature boss, set-up S1\): the fitted plane's normal is at 90.0 "
                                       r"deg to the log's normal of touch t0 \(8 of 8 touches beyond 30 deg\)"):
        fit_log_feature(lg, "plane")
    with pytest.raises(FitError, match=r"cylinder fit \(feature boss, set-up S1\): the touches lie at one height "
                                       r"along the axis.*vmt fit circle$"):
        fit_log_feature(lg, "cylinder")
    c = fit_log_feature(lg, "circle")
    assert c.values["radius_mm"] == pytest.approx(10.0, abs=1e-9) and c.normal_angle_deg < 1e-9
    p, n = _boss([-5.0, -15.0])
    cyl = fit_log_feature(log_of(p, n, stylus_r_mm=1.0), "cylinder")
    assert cyl.values["radius_mm"] == pytest.approx(10.0, abs=1e-9)
    assert abs(cyl.values["axis"][2]) == pytest.approx(1.0, abs=1e-12) and cyl.normal_angle_deg < 1e-9


@pytest.mark.parametrize("tilt_deg, refused", [(0.0, False), (20.0, False), (29.0, False), (31.0, True),
                                                (60.0, True), (180.0, False)])
def test_plane_normals_of_the_log_checked_at_the_stated_angle(tilt_deg, refused):
    """A flat face z = 5 probed on a 2D grid whose log normals are turned by ``tilt_deg`` about Y: up to
    NORMAL_AGREE_MAX_DEG (30) the fit stands and says the angle; beyond, refused. 180: the face probed from below
    (the normal is the log's, the angle 0). At 90 the log's normals make the touches one line of the surface they
    say (x = const): refused as one line."""
    from core.features import NORMAL_AGREE_MAX_DEG

    assert NORMAL_AGREE_MAX_DEG == 30.0
    x, y = np.meshgrid(np.linspace(0, 100, 6), np.linspace(0, 60, 4))
    p = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 5.0)])
    t = np.radians(tilt_deg)
    n = np.tile([np.sin(t), 0.0, np.cos(t)], (len(p), 1))
    lg = log_of(p, n)
    if refused:
        with pytest.raises(FitError, match=rf"the fitted plane's normal is at {tilt_deg:.1f} deg .*24 of 24"):
            fit_log_feature(lg, "plane")
    else:
        assert fit_log_feature(lg, "plane").normal_angle_deg == pytest.approx(tilt_deg % 180, abs=1e-9)
    if tilt_deg == 0:
        with pytest.raises(FitError, match=r"lie on one line"):
            fit_log_feature(log_of(p, np.tile([1.0, 0, 0], (len(p), 1))), "plane")


def test_circle_and_sphere_whose_normals_are_not_radial_are_refused():
    """A face probed round a circle from above (normals +z): fit circle gave the pattern's circle less the tip
    radius, a radius of nothing on the part. A sphere's cap whose log normals all say +z (not radial) likewise."""
    a = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    p = np.column_stack([20 * np.cos(a), 20 * np.sin(a), np.full(12, 3.0)])
    with pytest.raises(FitError, match=r"circle fit \(feature f, set-up s1\): the fitted circle's normal is at 90.0 "
                                       r"deg.*one centre in XY"):
        fit_log_feature(log_of(p, np.tile([0, 0, 1.0], (12, 1))), "circle")
    u = np.random.default_rng(2).normal(size=(30, 3))
    u[:, 2] = np.abs(u[:, 2]) + 0.2
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    ball = 14.0 * u
    assert fit_log_feature(log_of(ball, u), "sphere").normal_angle_deg < 1e-9        # radial: accepted
    with pytest.raises(FitError, match=r"sphere fit .*the fitted sphere's normal is at .* deg.*one centre"):
        fit_log_feature(log_of(ball, np.tile([0, 0, 1.0], (30, 1))), "sphere")
