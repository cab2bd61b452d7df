"""core.vcmm: task files, measurands from touches, declared draws, JCGM 101 statistics."""

import math

import numpy as np
import pytest

from core import vcmm as V
from core.exceptions import ConfigError

TASK = """
format = "vmt-task/1"
[features.bore]
kind = "circle"
feature = "bore"
[features.f1]
kind = "plane"
targets = ["A", "B", "C"]
[features.f2]
kind = "plane"
feature = "f2"
setup = "S1"
[[measurands]]
name = "d"
quantity = "diameter"
of = "bore"
[[measurands]]
name = "x"
quantity = "position"
of = "bore"
axis = "x"
[[measurands]]
name = "gap"
quantity = "distance"
of = ["f1", "f2"]
[[measurands]]
name = "squareness"
quantity = "angle"
of = ["f1", "f2"]
[[measurands]]
name = "flat"
quantity = "flatness"
of = "f1"
[declared.EXX]
slope_um_per_m = 5
constant_um = 1
[declared.EC0Y]
constant_urad = 20
distribution = "normal"
[mc]
tolerance_um = 0.05
batch_runs = 50
"""


def test_task_reads_every_field():
    t = V.loads_task(TASK, "t.toml")
    assert [f.name for f in t.features] == ["bore", "f1", "f2"]
    assert t.feature("f1").targets == ("A", "B", "C") and t.feature("f2").setup == "S1"
    assert [m.quantity for m in t.measurands] == ["diameter", "position", "distance", "angle", "flatness"]
    assert t.measurands[1].axis == "x" and t.measurands[3].unit == "deg" and t.measurands[4].unit == "um"
    terms = {d.source: d for d in t.declared}
    assert set(terms) == {"EXX slope", "EXX constant", "EC0Y constant"}
    assert terms["EXX slope"].bound == pytest.approx(5e-6) and terms["EXX slope"].power == 1
    assert terms["EC0Y constant"].u == pytest.approx(10e-6)   # normal: bound = U at k = 2
    assert terms["EXX constant"].u == pytest.approx(1e-6 / math.sqrt(3), abs=0)
    assert t.mc.tolerance == pytest.approx(5e-8, abs=0) and t.mc.batch_runs == 50


@pytest.mark.parametrize("edit, match", [
    (("[mc]", "[mx]"), "mx: unknown key"),
    (('axis = "x"', 'axis = "w"'), "measurands.1..axis|measurands\\[1\\].axis"),
    (('of = ["f1", "f2"]\n[[measurands]]\nname = "squareness"', 'of = ["f1"]\n[[measurands]]\nname = "squareness"'),
     "distance takes two features"),
    (('of = "f1"\n[declared', 'of = "bore"\n[declared'), "flatness is the form of a plane"),
    (("slope_um_per_m = 5", "slope_um_per_m = -5"), "must be >= 0"),
    (("batch_runs = 50", "batch_runs = 5"), "mc.batch_runs"),
    (('name = "x"', 'name = "d"'), "names must be unique"),
    (("[mc]", "[temperature]\npart_C = 500\n[mc]"), "temperature.part_C: a workshop temperature"),
    (("[mc]", "[temperature]\nu_part_K = -1\n[mc]"), "temperature.u_part_K: must be >= 0"),
    (("[mc]", "[temperature]\npart_K = 1\n[mc]"), "temperature.part_K: unknown key"),
    (('quantity = "flatness"', 'quantity = "profile"'), "profile needs statistic = one of max, min, rms, zone"),
    (('quantity = "flatness"', 'quantity = "profile"\nstatistic = "p2v"'), "measurands.4..statistic"),
    (('quantity = "flatness"', 'quantity = "flatness"\nstatistic = "max"'), "only for quantity = \"profile\""),
    (('quantity = "flatness"', 'quantity = "straightness"'), "straightness is the form of a line, 'f1' is a plane"),
    (('kind = "plane"\nfeature = "f2"', 'kind = "line"\nfeature = "f2"'),
     "distance: a line with a line, circle or sphere"),
    (('[[measurands]]\nname = "flat"', '[[measurands]]\nname = "a1"\nquantity = "angle"\nof = "f1"\n'
      '[[measurands]]\nname = "flat"'), "angle takes two features"),
])
def test_bad_task_names_the_key(edit, match):
    with pytest.raises(V.TaskFileError, match=match):
        V.loads_task(TASK.replace(*edit), "t.toml")


def test_temperature_reads_and_strains():
    t = V.loads_task(TASK.replace("[mc]", "[temperature]\npart_C = 23\nu_part_K = 0.5\npart_alpha_per_K = 1e-5\n"
                                          "scales_C = 21\nscales_alpha_per_K = 8e-6\n[mc]"))
    assert t.temperature.sources == ("part temperature",)              # only sources with a u
    assert t.temperature.strains() == pytest.approx((3e-5, 8e-6))
    assert t.temperature.strains({"part temperature": 20.0}) == pytest.approx((0.0, 8e-6))


def test_feature_rows_select_and_refuse():
    t = V.loads_task(TASK)
    target = np.array(["A", "B", "C", "D", "E", "F", "G", "H", "I"])
    feature = np.array(["", "", "", "bore", "bore", "bore", "f2", "f2", "f2"])
    setup = np.array(["S1"] * 8 + ["S2"])
    rows = V.feature_rows(t, target, feature, setup)
    assert rows["f1"].tolist() == [0, 1, 2] and rows["bore"].tolist() == [3, 4, 5] and rows["f2"].tolist() == [6, 7]
    with pytest.raises(V.TaskFileError, match="targets: not in the plan: C"):
        V.feature_rows(t, np.where(target == "C", "Z", target), feature, setup)
    rot = np.zeros((9, 3))
    rot[4, 2] = 90.0
    with pytest.raises(V.TaskFileError, match="different rotary positions"):
        V.feature_rows(t, target, feature, setup, rot)


def _ring(c, rho, z, k=8):
    a = 2 * np.pi * (np.arange(k) + 0.25) / k
    return np.c_[c[0] + rho * np.cos(a), c[1] + rho * np.sin(a), np.full(k, z)], np.c_[np.cos(a), np.sin(a), 0 * a]


def test_measurands_known_answers():
    """Exact points: a bore and a boss of radius 10 mm probed by a 3 mm ball, two faces 50 mm
    apart and one perpendicular to them, a sphere; values to 1e-12 m / 1e-12 rad."""
    r = 3e-3
    p_bore, u = _ring((0.02, 0.01), 7e-3, -0.01)
    p_boss, u2 = _ring((-0.05, 0.0), 13e-3, -0.01)
    fb = V.fit_feature("circle", p_bore, -u, r)        # a bore: normals point at the centre
    fo = V.fit_feature("circle", p_boss, u2, r)        # a boss: outward
    assert fb.radius == pytest.approx(10e-3, abs=1e-12) and fo.radius == pytest.approx(10e-3, abs=1e-12)
    yz = np.array([[0, 0.0, 0], [0, 0.02, 0], [0, 0, -0.02], [0, 0.02, -0.02]])
    left = V.fit_feature("plane", yz + [-r, 0, 0], np.tile([-1.0, 0, 0], (4, 1)), r)
    right = V.fit_feature("plane", yz + [0.05 + r, 0, 0], np.tile([1.0, 0, 0], (4, 1)), r)
    top = V.fit_feature("plane", np.array([[0, 0, r], [0.01, 0, r], [0, 0.01, r], [0.01, 0.02, r]]),
                        np.tile([0, 0, 1.0], (4, 1)), r)
    sph = V.fit_feature("sphere", np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1],
                                            [0.6, 0.8, 0]]) * 0.015, np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0],
                                                                             [0, -1, 0], [0, 0, 1], [0.6, 0.8, 0]]), r)
    feats = {"bore": fb, "boss": fo, "l": left, "r": right, "t": top, "s": sph}

    def val(q, of, axis=None):
        return V.measurand_value(V.Measurand("m", q, of, axis), feats)

    assert val("diameter", ("bore",)) == pytest.approx(0.02, abs=1e-12)
    assert val("position", ("bore",), "y") == pytest.approx(0.01, abs=1e-12)
    assert val("distance", ("l", "r")) == pytest.approx(0.05, abs=1e-12)
    assert val("distance", ("bore", "boss")) == pytest.approx(math.hypot(0.07, 0.01), abs=1e-12)
    assert val("distance", ("t", "bore")) == pytest.approx(0.01, abs=1e-12)   # centre height -10 mm
    assert val("angle", ("l", "t")) == pytest.approx(math.pi / 2, abs=1e-12)
    assert val("angle", ("l", "r")) == pytest.approx(math.pi, abs=1e-12)      # outward normals: opposite
    assert val("diameter", ("s",)) == pytest.approx(0.024, abs=1e-12)         # 15 mm tip sphere - 3 mm
    assert val("flatness", ("l",)) == pytest.approx(0.0, abs=1e-15)


def test_line_known_answers():
    """Tip centres of a face with outward normal (-sin a, cos a), a = 30 deg, probed by a 2 mm ball at
    5 points 10 mm apart, the middle one 3 um proud: the LS line moves 3/5 um out (the offset's mean),
    the residuals are -0.6 (x4) and +2.4 um, so the straightness is 3 um; the direction z x n is
    (-cos a, -sin a): 210 deg, reported -150; the surface is 2 mm back along the normal."""
    a, r, h = math.radians(30.0), 2e-3, 3e-6
    n = np.array([-math.sin(a), math.cos(a), 0.0])
    t = np.array([math.cos(a), math.sin(a), 0.0])
    s = np.arange(5)[:, None] * 0.01 * t + [0.1, 0.2, -0.01]
    p = s + r * n
    p[2] += h * n
    f = V.fit_feature("line", p, np.tile(n, (5, 1)), r)
    assert f.form == pytest.approx(h, abs=1e-15)
    assert f.direction == pytest.approx(-t, abs=1e-12)
    assert f.point == pytest.approx(s.mean(axis=0) + h / 5 * n, abs=1e-12)
    ang = V.measurand_value(V.Measurand("a", "angle", ("l",)), {"l": f})
    assert ang == pytest.approx(math.radians(-150.0), abs=1e-12)
    g = V.fit_feature("line", s + 0.05 * n + r * n, np.tile(n, (5, 1)), r)   # a parallel face 50 mm further out
    assert V.measurand_value(V.Measurand("d", "distance", ("l", "g")), {"l": f, "g": g}) == pytest.approx(
        0.05 - h / 5, abs=1e-12)
    assert V.measurand_value(V.Measurand("b", "angle", ("l", "g")), {"l": f, "g": g}) == pytest.approx(0, abs=1e-6)


def test_profile_statistics_hand_worked():
    """Deviations +1, -3, +2 um (reported minus nominal along the outward normal; the normals differ,
    the offsets along the surface do not count): max 2, min -3, rms sqrt(14/3), zone 6 um."""
    n = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    Xn = np.array([[0.1, 0, 0], [0, 0.2, 0], [0, 0, 0.3]])
    p = Xn + n * np.array([[1e-6], [-3e-6], [2e-6]]) + [[0, 5e-6, 0], [7e-6, 0, 0], [0, 0, 0]]
    d = V.profile_deviations(p, Xn, n)
    assert d == pytest.approx([1e-6, -3e-6, 2e-6], abs=1e-16)   # rounding of 0.3 m + 2 um: ~6e-17
    got = [V.profile_value(k, d) for k in V.PROFILE_STATISTICS]
    assert got == pytest.approx([2e-6, -3e-6, math.sqrt(14 / 3) * 1e-6, 6e-6], abs=1e-16)


def test_saltelli_first_order_on_the_ishigami_function():
    """Ishigami (a = 7, b = 0.1, X uniform on [-pi, pi]^3) has closed-form first-order indices
    S1 = V1 / V = 0.3139, S2 = 0.4424, S3 = 0 (V1 = (1 + b pi^4 / 5)^2 / 2, V2 = a^2 / 8,
    V13 = b^2 pi^8 (1/18 - 1/50)). Shifted by 1000 so that an estimator without centring fails
    (its standard error grows ~270-fold). The stated standard error is right: over 200 seeds at
    n = 4000, (S - S_true) / se had standard deviations 0.97, 1.00, 1.01 and 3-4 % beyond 2; here
    each index within 4 se, and se < 0.02."""
    a, b, n = 7.0, 0.1, 4000
    V1, V2, V13 = 0.5 * (1 + b * math.pi ** 4 / 5) ** 2, a * a / 8, b * b * math.pi ** 8 * (1 / 18 - 1 / 50)
    truth = np.array([V1, V2, 0.0]) / (V1 + V2 + V13)

    def f(X):
        return (1000 + np.sin(X[:, 0]) + a * np.sin(X[:, 1]) ** 2 + b * X[:, 2] ** 4 * np.sin(X[:, 0]))[:, None]

    rng = np.random.default_rng(11)
    A, B = rng.uniform(-np.pi, np.pi, (n, 3)), rng.uniform(-np.pi, np.pi, (n, 3))
    fAB = {}
    for i in range(3):
        M = A.copy()
        M[:, i] = B[:, i]
        fAB[i] = f(M)
    s, se = V.saltelli_first_order(f(A), f(B), fAB)
    for i in range(3):
        assert se[i][0] < 0.02 and abs(s[i][0] - truth[i]) < 4 * se[i][0], (i, s[i], se[i], truth[i])
    flat = V.saltelli_first_order(np.ones((5, 1)), np.ones((5, 1)), {"x": np.ones((5, 1))})
    assert np.isnan(flat[0]["x"][0]) and np.isnan(flat[1]["x"][0])   # no variance: NaN, not 0 / 0 noise
    with pytest.raises(ConfigError, match="same shape"):
        V.saltelli_first_order(np.ones((5, 1)), np.ones((4, 1)), {})


def test_flatness_is_the_peak_to_valley_of_a_known_bump():
    p = np.array([[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0], [0.01, 0.01, 0], [0.005, 0.005, 2e-6]])
    f = V.fit_feature("plane", p, np.tile([0, 0, 1.0], (5, 1)), 0.0)
    # LS plane of 4 corners at 0 and a centre at h: offset h/5; residuals -h/5 (corners), 4h/5: p-v = h
    assert f.form == pytest.approx(2e-6, abs=1e-15)


@pytest.mark.parametrize("dist", V.DISTRIBUTIONS)
def test_draws_have_the_declared_standard_uncertainty(dist):
    t = V.DeclaredTerm("EXX", "slope", 2.0, dist)
    rng = np.random.default_rng(5)
    x = np.array([V.draw_term(t, rng) for _ in range(20000)])
    # relative standard error of a standard deviation from 20000 draws: < 1 %; 3 of them
    assert x.std() == pytest.approx(t.u, rel=0.03)
    if dist != "normal":
        assert np.abs(x).max() <= 2.0


def test_mc_stats_jcgm101_interval_indices():
    """JCGM 101 7.7.2: M = 1000, p = 0.95: q = 950, r = 25: [y_(25), y_(975)]; M = 101: q = 96, M - q
    odd: r = 3: [y_(3), y_(99)]."""
    s = V.mc_stats(np.arange(1000, 0, -1.0))
    assert (s.low, s.high, s.runs) == (25.0, 975.0, 1000) and s.mean == 500.5
    s = V.mc_stats(np.arange(1, 102.0))
    assert (s.low, s.high) == (3.0, 99.0)
    with pytest.raises(ConfigError, match="2 finite"):
        V.mc_stats(np.array([1.0, np.nan]))


def test_numerical_tolerance_jcgm101_7_9_2():
    """u = 0.35 with 2 significant digits: 35 x 10^-2, delta = 0.005; one digit: delta = 0.05."""
    assert V.numerical_tolerance(0.35, 2) == pytest.approx(0.005)
    assert V.numerical_tolerance(0.35, 1) == pytest.approx(0.05)
    assert V.numerical_tolerance(2.7e-7, 1) == pytest.approx(5e-8, abs=0)
    assert V.numerical_tolerance(0.0, 1) == 0.0


def test_adaptive_check_on_normal_batches():
    """Batches of N(0, 1), u = 1.0 held to two digits (10 x 10^-1: delta = 0.05): s of the batch means
    is 1 / sqrt(h M), of the 2.5 % quantile 2.7 / sqrt(h M), so 2 s <= 0.05 needs h M >~ 12000."""
    rng = np.random.default_rng(1)

    def batches(h, M):
        b = []
        for _ in range(h):
            s = V.mc_stats(rng.standard_normal(M))
            b.append([s.mean, s.u, s.low, s.high])
        return np.array(b)

    assert not V.adaptive_check(batches(1, 100), 1.0, 2).stable          # one batch: never
    assert not V.adaptive_check(batches(4, 100), 1.0, 2).stable          # 400 runs: not yet
    a = V.adaptive_check(batches(40, 1000), 1.0, 2)
    assert a.stable and a.delta == pytest.approx(0.05)
    b = batches(30, 100)   # 3000 runs: s of u ~ 0.71 / sqrt(3000) = 0.013, of the ends ~ 0.05
    assert V.adaptive_check(b, 1.0, 2, which="u").stable and not V.adaptive_check(b, 1.0, 2).stable
    zero = V.adaptive_check(np.zeros((2, 4)), 0.0, 1, which="u")          # a source without effect
    assert zero.stable
