"""``vmt vcmm``: the virtual CMM against closed-form answers, through the exact simulator.

Truths outside the code: a gauge's length under an X scale error and a
bore's diameter under X and Y scale errors, worked by hand (below), run by
run (each run's drawn scale is known) and in distribution (u and the 95 %
interval of a uniform scale). The simulator's touches are on the exact
Pinocchio chain; the fits are core's.
"""

import json
import math

import numpy as np
import pytest

from core.probelog import make_log, write_probe_log
from core.vcmm import loads_task
from scenarios import vcmm as S
from scenarios.cli import main
from sim.machinefile import resolve

R_ST = 3.0  # stylus radius, mm


def plan_of(rows):
    """A probe-log/1 plan from (feature, surface point mm, outward normal) rows."""
    n = len(rows)
    s = np.array([p for _, p, _ in rows], float)
    nn = np.array([v for _, _, v in rows], float)
    nn /= np.linalg.norm(nn, axis=1)[:, None]
    Xn = s + R_ST * nn
    nan = np.full(n, np.nan)
    return make_log({"setup": ["S1"] * n, "target": [f"P{i:02d}" for i in range(n)], "t_s": nan, "X_mm": nan,
                     "Y_mm": nan, "Z_mm": nan, "Xn_mm": Xn[:, 0], "Yn_mm": Xn[:, 1], "Zn_mm": Xn[:, 2],
                     "nx": nn[:, 0], "ny": nn[:, 1], "nz": nn[:, 2], "feature": [f for f, _, _ in rows],
                     "stylus_r_mm": np.full(n, R_ST)})


L_MM = 100.0
GAUGE = plan_of([("a", (0.0, y, z), (-1, 0, 0)) for y, z in ((-5, -10), (5, -10), (0, -20))]
                + [("b", (L_MM, y, z), (1, 0, 0)) for y, z in ((-5, -10), (5, -10), (0, -20))])
GAUGE_TASK = """
[features.a]
kind = "plane"
feature = "a"
[features.b]
kind = "plane"
feature = "b"
[[measurands]]
name = "length"
quantity = "distance"
of = ["a", "b"]
[declared.EXX]
slope_um_per_m = 10.0
distribution = "uniform"
[probe]
noise_um = 0.0
[mc]
batch_runs = 50
max_runs = 2000
tolerance_um = 0.1
"""
A_SLOPE = 10e-6  # the declared half-width of the X scale error, m/m

R_MM, C_MM = 10.0, (20.0, 10.0)   # the bore
BORE = plan_of([("bore", (C_MM[0] + R_MM * math.cos(a), C_MM[1] + R_MM * math.sin(a), -10.0),
                 (-math.cos(a), -math.sin(a), 0.0)) for a in np.deg2rad(22.5 + 45.0 * np.arange(8))])
BORE_TASK = """
[features.bore]
kind = "circle"
feature = "bore"
[[measurands]]
name = "d"
quantity = "diameter"
of = "bore"
[declared.EXX]
slope_um_per_m = 10.0
[declared.EYY]
slope_um_per_m = 10.0
[probe]
noise_um = 0.0
"""


@pytest.fixture(scope="module")
def machine():
    return resolve("vmc-3axis")   # errors = "none": the declared terms are the only errors


def _slopes(st, seed, runs):
    """The drawn (EXX, EYY) slopes of each run (the draws are public: scenarios.vcmm.draw)."""
    out = np.zeros((len(runs), 2))
    for i, k in enumerate(runs):
        c, _, _ = S.draw(st, seed, k)
        out[i] = c.get(("EXX", 1), 0.0), c.get(("EYY", 1), 0.0)
    return out


def test_gauge_length_under_an_x_scale_error_matches_the_closed_form(machine):
    """Touches at tip centres x1 - r and x2 + r; the tool sits at X (1 + s), so the machine reads
    X = (surface +- r) / (1 + s) and the length is (L + 2 r) / (1 + s) - 2 r, exactly (run by run,
    to 1 nm: the contact search's resolution). In distribution u = (L + 2 r) a / sqrt(3)."""
    st = S.prepare(GAUGE, loads_task(GAUGE_TASK), machine)
    runs = np.arange(300)
    y = S.run_values(st, 7, runs)[:, 0]
    s = _slopes(st, 7, runs)[:, 0]
    Lr = (L_MM + 2 * R_ST) * 1e-3
    want = Lr / (1 + s) - 2 * R_ST * 1e-3
    assert np.max(np.abs(y - want)) < 1e-9
    u_closed = Lr * A_SLOPE / math.sqrt(3)           # 0.612 um
    # sampling: u of a uniform from N runs has a relative standard error 0.447 / sqrt(N) (2.6 % at 300):
    # 4 of them
    assert abs(y.std(ddof=1) / u_closed - 1) < 4 * 0.447 / math.sqrt(len(y))


def test_bore_diameter_under_scale_errors_matches_the_closed_form(machine):
    """Reported tip centres are the true ones divided by (1 + s_x), (1 + s_y): an ellipse; the
    least-squares circle of 8 evenly spaced points has the mean radius, rho (1 - (s_x + s_y) / 2)
    to first order (rho = R - r: a bore's tip circle), and the stylus radius is added back
    unscaled: D = 2 R - rho (s_x + s_y) + O(rho s^2) (~1e-12 m). u = rho sqrt(2) a / sqrt(3)."""
    st = S.prepare(BORE, loads_task(BORE_TASK), machine)
    runs = np.arange(300)
    y = S.run_values(st, 3, runs)[:, 0]
    s = _slopes(st, 3, runs)
    rho = (R_MM - R_ST) * 1e-3
    want = 2 * R_MM * 1e-3 - rho * (s[:, 0] + s[:, 1])
    assert np.max(np.abs(y - want)) < 1e-9
    u_closed = rho * math.sqrt(2) * A_SLOPE / math.sqrt(3)
    # the sum of two uniforms (triangular, kurtosis 2.4): relative standard error of u sqrt(1.4 / 4N)
    assert abs(y.std(ddof=1) / u_closed - 1) < 4 * math.sqrt(1.4 / (4 * len(y)))


def test_gauge_length_at_a_part_and_scale_temperature_matches_the_closed_form(machine):
    """Part at T_p (best estimate 22 C, u 1 K), alpha_p = 11.5e-6 /K, scales at T_s (21 C, u 0.5 K),
    alpha_s = 8e-6 /K; results corrected to 20 C with the best estimates e0. By hand: the faces are
    L (1 + e_p) apart, the tip centres read (L (1 + e_p) + 2 r) / (1 + e_s); corrected,
    L_20 = [(L (1 + e_p) + 2 r) (1 + e_s0) / (1 + e_s) - 2 r] / (1 + e_p0), run by run to 1 nm;
    u = sqrt((L alpha_p u_Tp)^2 + ((L + 2 r) alpha_s u_Ts)^2) to first order (1.19 um)."""
    task = loads_task(GAUGE_TASK.replace("[declared.EXX]\nslope_um_per_m = 10.0\ndistribution = \"uniform\"\n", "")
                      + "[temperature]\npart_C = 22.0\nu_part_K = 1.0\npart_alpha_per_K = 11.5e-6\n"
                        "scales_C = 21.0\nu_scales_K = 0.5\nscales_alpha_per_K = 8e-6\n")
    st = S.prepare(GAUGE, task, machine)
    assert st.sources == ("part temperature", "scale temperature")
    runs = np.arange(200)
    y = S.run_values(st, 11, runs)[:, 0]
    T = np.array([[S.draw(st, 11, k)[2][n] for n in st.sources] for k in runs])
    L, r = L_MM * 1e-3, R_ST * 1e-3
    e_p, e_s = 11.5e-6 * (T[:, 0] - 20), 8e-6 * (T[:, 1] - 20)
    e_p0, e_s0 = 11.5e-6 * 2, 8e-6 * 1
    want = ((L * (1 + e_p) + 2 * r) * (1 + e_s0) / (1 + e_s) - 2 * r) / (1 + e_p0)
    assert np.max(np.abs(y - want)) < 1e-9
    u_closed = math.hypot(L * 11.5e-6 * 1.0, (L + 2 * r) * 8e-6 * 0.5)
    # normal inputs: relative standard error of u 1 / sqrt(2N) (5 % at 200); 4 of them
    assert abs(y.std(ddof=1) / u_closed - 1) < 4 / math.sqrt(2 * len(y))
    assert abs(y.mean() - L) < 4 * u_closed / math.sqrt(len(y))        # corrected to 20 C: no bias


SPHERE_Z_TASK = """
[features.top]
kind = "sphere"
feature = "top"
[[measurands]]
name = "z"
quantity = "position"
axis = "z"
of = "top"
[probe]
noise_um = 0.0
[temperature]
scales_C = 25.0
scales_alpha_per_K = 8e-6
[mc]
batch_runs = 50
max_runs = 100
"""


@pytest.mark.parametrize("Jz_m", [0.0, 0.150])
def test_scale_temperature_correction_of_a_position_is_exact_with_a_probe_offset(machine, Jz_m):
    """Scales at 25 C (alpha 8e-6, e_s = 4e-5, no uncertainty), no machine errors, a sphere of
    centre z = -20 mm: the scales read the axis position q = reading + J over 1 + e_s, and the
    correction takes them back exactly (the position measurand is the nominal to 1 nm, float
    rounding only). Review27b F1: correcting the reading instead of q left -e_s J = -6.000 um at
    J_Z = 150 mm (the J = 0 case passed either way)."""
    import dataclasses
    dirs = [(0, 0, 1)] + [(math.cos(a) * math.cos(e), math.sin(a) * math.cos(e), math.sin(e))
                          for e in (0.3, 0.9) for a in np.linspace(0, 2 * math.pi, 6, endpoint=False)]
    plan = plan_of([("top", tuple(np.array((0, 0, -20.0)) + 10 * np.array(d)), d) for d in dirs])
    spec = dataclasses.replace(machine, config=dataclasses.replace(machine.config, errors={}, J_m=(0.0, 0.0, Jz_m)))
    st = S.prepare(plan, loads_task(SPHERE_Z_TASK), spec)
    y = S.run_values(st, 1, np.arange(3))[:, 0]
    assert np.max(np.abs(y - (-0.020))) < 1e-9


def test_cli_end_to_end_gauge(tmp_path, machine, capsys):
    """vmt vcmm: adaptive MC (converged), the budget (one source: all of u), the nominal on a
    perfect machine to 1 nm, the 95 % interval of a uniform: +-0.95 (L + 2 r) a."""
    plan, task, out = tmp_path / "plan.csv", tmp_path / "task.toml", tmp_path / "out.json"
    write_probe_log(plan, GAUGE)
    task.write_text(GAUGE_TASK)
    assert main(["vcmm", "--plan", str(plan), "--machine", "vmc-3axis", "--task", str(task), "--json", str(out),
                 "--seed", "1", "--report", str(tmp_path / "rep")]) == 0
    assert (tmp_path / "rep" / "index.html").is_file() and (tmp_path / "rep" / "budget.png").is_file()
    rep = json.loads(out.read_text())
    m = rep["measurands"][0]
    assert m["converged"] and rep["runs"] >= 100
    assert abs(m["nominal"] - L_MM) < 1e-6           # mm: 1 nm
    Lr_um = (L_MM + 2 * R_ST) * 1e3
    u_closed = Lr_um * A_SLOPE / math.sqrt(3)
    # JCGM 101 7.9: the adaptive rule holds u and the interval ends to the tolerance (0.1 um) with
    # 95 % confidence each; the test allows twice that
    assert abs(m["u"] - u_closed) < 0.2
    half = 0.5 * (m["interval"][1] - m["interval"][0]) * 1e3
    assert abs(half - 0.95 * Lr_um * A_SLOPE) < 0.2
    (b,) = m["budget"]
    # the budget's runs share the full runs' draws but stop on their own (u stable): within the tolerance
    assert b["source"] == "EXX slope" and b["share"] == 1.0 and abs(b["u"] - m["u"]) < 0.1
    assert "length" in capsys.readouterr().out
    # the worst touches: every touch moves by s x along X, so u(dq) grows with |x| (face b at 103 mm)
    tu = {t["target"]: t["u_dq_um"] for t in rep["touches_u"]}
    assert abs(tu["P03"] - 0.103e6 * A_SLOPE / math.sqrt(3)) < 0.1 and tu["P00"] < 0.03


@pytest.mark.parametrize("body, match", [
    ("[features.a]\nkind = \"cone\"\nfeature = \"a\"", "features.a.kind"),
    ("[features.a]\nkind = \"plane\"\n[[measurands]]\nname = \"x\"\nquantity = \"flatness\"\nof = \"a\"",
     "features.a: give feature"),
    ("[features.a]\nkind = \"plane\"\nfeature = \"a\"\n[[measurands]]\nname = \"x\"\nquantity = \"diameter\""
     "\nof = \"a\"", "a plane has no diameter"),
    ("[features.a]\nkind = \"plane\"\nfeature = \"zz\"\n[[measurands]]\nname = \"x\"\nquantity = \"flatness\""
     "\nof = \"a\"", "selects no plan row"),
    ("[features.a]\nkind = \"plane\"\nfeature = \"a\"\n[[measurands]]\nname = \"x\"\nquantity = \"flatness\""
     "\nof = \"a\"\n[declared.EXQ]\nconstant_um = 1", "unknown ISO"),
    ("[features.a]\nkind = \"plane\"\nfeature = \"a\"\n[[measurands]]\nname = \"x\"\nquantity = \"flatness\""
     "\nof = \"a\"\n[declared.EC0Y]\nslope_urad_per_m = 1", "declared.EC0Y.slope_urad_per_m"),
    ("[features.a]\nkind = \"plane\"\nfeature = \"a\"\n[[measurands]]\nname = \"x\"\nquantity = \"flatness\""
     "\nof = \"a\"\n[declared.EXX]\nconstant_um = 1\ndistribution = \"cauchy\"", "distribution"),
    ("not toml [", "not TOML"),
])
def test_bad_task_exits_2_with_one_line(tmp_path, capsys, body, match):
    plan, task, out = tmp_path / "plan.csv", tmp_path / "task.toml", tmp_path / "out.json"
    write_probe_log(plan, GAUGE)
    task.write_text(body)
    assert main(["vcmm", "--plan", str(plan), "--machine", "vmc-3axis", "--task", str(task), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()


def test_points_not_on_one_feature_exit_2(tmp_path, capsys):
    """A plan whose 'plane' points are not coplanar (by 50 um) is refused, naming the feature."""
    rows = [("a", (0.0, y, z), (-1, 0, 0)) for y, z in ((-5, -10), (5, -10), (0, -20))]
    rows.append(("a", (0.05, 0.0, -15.0), (-1, 0, 0)))
    plan, task, out = tmp_path / "plan.csv", tmp_path / "task.toml", tmp_path / "out.json"
    write_probe_log(plan, plan_of(rows))
    task.write_text("[features.a]\nkind = \"plane\"\nfeature = \"a\"\n[[measurands]]\nname = \"f\"\n"
                    "quantity = \"flatness\"\nof = \"a\"\n")
    assert main(["vcmm", "--plan", str(plan), "--machine", "vmc-3axis", "--task", str(task), "--json", str(out)]) == 2
    assert "not on one plane" in capsys.readouterr().err


def test_cli_best_estimate_errors_default_to_the_shipped_file(tmp_path, capsys):
    """vcmm --machine NAME: its errors are the best estimate, a built-in's as its file states them (none):
    the same JSON as --errors none, another with --errors realistic (the merge that made it the default)."""
    plan, task = tmp_path / "plan.csv", tmp_path / "task.toml"
    write_probe_log(plan, GAUGE)
    task.write_text(GAUGE_TASK.replace("max_runs = 2000", "max_runs = 100"))    # two batches: bytes, not u
    docs = {}
    for tag, extra in (("omitted", []), ("none", ["--errors", "none"]), ("realistic", ["--errors", "realistic"])):
        out = tmp_path / f"{tag}.json"
        assert main(["vcmm", "--plan", str(plan), "--machine", "vmc-3axis", "--task", str(task), "--json", str(out),
                     "--seed", "1", "--no-budget", *extra]) == 0
        docs[tag] = {k: v for k, v in json.loads(out.read_text()).items() if k not in ("elapsed_s", "runs_per_s")}
    capsys.readouterr()
    assert docs["omitted"] == docs["none"]
    assert docs["omitted"] != docs["realistic"]


def test_a_declared_polynomial_is_of_the_axis_position_reading_plus_J(machine):
    """core.vcmm's words (review29 F6): a declared slope or quadratic term is a polynomial of the axis
    position q = reading + J, where the simulator evaluates every machine error, not of the reading.
    vmc-3axis has J_Z = 150 mm; touches on a face read Z = -17 mm (q = 133 mm). An EZZ bow c q^2 moves
    each reading by -EZZ at the trigger: c (0.133)^2 = 17.7 um, where c (-0.017)^2 would be 0.29 um."""
    J_z = machine.config.J_m[2]
    assert J_z == 0.150
    plan = plan_of([("top", (x, y, -20.0), (0, 0, 1)) for x, y in ((0, 0), (50, 0), (0, 50), (-40, -30))])
    task = ('[features.top]\nkind = "plane"\nfeature = "top"\n[[measurands]]\nname = "flat"\n'
            'quantity = "flatness"\nof = "top"\n[declared.EZZ]\nquadratic_um_per_m2 = 1000.0\n'
            '[probe]\nnoise_um = 0.0\n')
    st = S.prepare(plan, loads_task(task), machine)
    c = 1e-3                                        # m/m^2 (1000 um/m^2)
    p0 = S.simulate_run(st, {}, None, noise=False)
    p1 = S.simulate_run(st, {("EZZ", 2): c}, None, noise=False)
    np.testing.assert_allclose(p0[:, 2], -0.017, atol=1e-12)
    # exact but for rounding (measured 3e-17 m): the bow at the axis position where the trigger happened
    np.testing.assert_allclose(p1[:, 2] - p0[:, 2], -c * (p1[:, 2] + J_z) ** 2, rtol=0, atol=1e-12)
    assert np.all(np.abs(p1[:, 2] - p0[:, 2]) > 50 * c * p0[:, 2] ** 2)   # not the reading's c z^2
    # a slope (scale) likewise: EZZ = s q
    s = 1e-5
    p2 = S.simulate_run(st, {("EZZ", 1): s}, None, noise=False)
    np.testing.assert_allclose(p2[:, 2] - p0[:, 2], -s * (p2[:, 2] + J_z), rtol=0, atol=1e-12)


def test_u_is_printed_to_the_place_its_tolerance_makes_reliable():
    """review32b F1.2: the terminal printed u to 4 decimals where significant_digits = 1 made one reliable.
    JCGM 101 7.9.2: delta = 1/2 10^l, u stable to the digit of 10^l: delta 0.05 um -> 1 decimal, 0.005 -> 2,
    0.5 -> 0; a user's --tol-um 0.1 (not of that form) -> 1 (the place of 2 delta, rounded down); none -> 4."""
    from scenarios.cli.vcmm import _u_decimals

    assert [_u_decimals(d) for d in (0.05, 0.005, 0.5, 0.1, 0.09999999999999999, None, 0.0, float("nan"))] == \
        [1, 2, 0, 1, 1, 4, 4, 4]
