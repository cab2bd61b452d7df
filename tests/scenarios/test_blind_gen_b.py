"""Blind generator B (issue 13, item 7): geometry, signs, effects, truth.

Checks against things the generator does not compute itself: hand-worked
touches, rigid transforms fitted from the log's own columns, point-in-
polygon tests of the normals, rotation-covariant fields that must look like
a workpiece form, and the validating reader and CLI of the core.
"""

from __future__ import annotations

import math
import pickle
import subprocess
import sys

import numpy as np
import pytest

from core.exceptions import ConfigError
from core.probelog import make_log, read_probe_log, write_probe_log
from core.chain import parse_chain
from scenarios.blind import gen_b
from scenarios.cli import main

SEED = 20261201
EFFECTS = tuple(gen_b.effects())


@pytest.fixture(scope="session")
def campaigns():
    """Every effect on and off, one seed (the same campaign for all)."""
    return {(e, on): gen_b.generate(e, SEED, effect_on=on) for e in EFFECTS for on in (True, False)}


def _dq_um(log):
    return log.dq_mm() * 1e3


# ---------------------------------------------------------------------------
# interface


def test_effect_list_names_kinds_and_truth_fields(campaigns):
    fx = gen_b.effects()
    catalogue = {"none", "outlier", "thermal_drift", "periodic_axis_error", "probe_lobing",
                 "reversal", "nonrigid"}
    new = {"c_drift", "temperature_expansion", "stylus_bending", "lobing_per_setup",
           "local_scale_defect", "part_change"}
    assert {k for k, v in fx.items() if v == "catalogue"} == catalogue
    assert {k for k, v in fx.items() if v == "new_named"} == new
    own = [k for k, v in fx.items() if v == "out_of_catalogue"]
    assert len(own) >= 4 and not set(own) & (catalogue | new)
    allowed = {"time", "time_in_setup", "setup", "C", "x", "y", "z", "approach_azimuth",
               "approach_elevation", "feature", "order"}
    for e in EFFECTS:
        log, tr = campaigns[(e, True)]
        assert tr.effect == e and tr.kind == fx[e] and tr.seed == SEED
        assert tr.acceptable_causes == ((e,) if fx[e] != "out_of_catalogue" else ("unexplained",))
        assert all(c in allowed or c.startswith("temp_") for c in tr.covariates)
        assert len(tr.effect_dq_um) == log.n and not tr.effect_dq_um.flags.writeable
        assert len(tr.workpiece_um) == len(tr.targets) == 60
        assert tr.detectable == (tr.visible_sigmas >= 1.0)
        assert tr.visible_sigmas == pytest.approx(tr.visible_um / tr.noise_um, abs=0)
        assert 0.2 <= tr.noise_um <= 0.5
        assert 3 <= len(tr.schedule_deg) <= 8
        assert 200 <= log.n <= 500
        assert log.has("temp_air_C") and log.has("temp_spindle_C")
    _, tr = campaigns[("c_drift", True)]
    back = pickle.loads(pickle.dumps(tr))                  # runs across processes
    assert back.params == tr.params and np.array_equal(back.effect_dq_um, tr.effect_dq_um)
    _, off = campaigns[("c_drift", False)]
    assert off.acceptable_causes == ("none",) and off.magnitude_um == 0 and not off.effect_dq_um.any()


def test_chain_parses_with_x_and_y_on_the_workpiece_side(campaigns):
    log, _ = campaigns[("none", True)]
    ch = parse_chain(log.meta["kinematic_chain"])
    assert ch.side("X") == ch.side("Y") == ch.side("C") == "workpiece"
    assert ch.tool_axes == ("Z",) and ch.parent("X") == "Y"


def test_bad_input_is_refused_with_a_reason():
    with pytest.raises(ConfigError, match="unknown effect 'wobble'"):
        gen_b.generate("wobble", 1)
    with pytest.raises(ConfigError, match="unknown option 'noise'"):
        gen_b.generate("none", 1, noise=0.3)
    with pytest.raises(ConfigError, match="seed must be a non-negative integer"):
        gen_b.generate("none", -1)
    with pytest.raises(ConfigError, match="schedule 'weekly'"):
        gen_b.generate("none", 1, schedule="weekly")
    with pytest.raises(ConfigError, match="noise_um must be > 0"):
        gen_b.generate("none", 1, noise_um=0.0)
    with pytest.raises(ConfigError, match="distinct C angles"):
        gen_b.generate("none", 1, schedule_deg=(0, 360))


# ---------------------------------------------------------------------------
# exact geometry and hand-worked touches


def test_perfect_machine_and_part_give_zero_dq():
    log, tr = gen_b.generate("none", 5, perfect=True, noisy=False)
    assert np.max(np.abs(log.dq_mm())) <= 1e-12
    assert np.max(np.abs(log.positions_mm() - log.nominals_mm())) <= 1e-12


def _fit_rigid_2d(a, b):
    """Rotation angle (rad) and translation with b = R a + t (Kabsch)."""
    ca, cb = a.mean(0), b.mean(0)
    h = (a - ca).T @ (b - cb)
    ang = math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
    r = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
    return ang, cb - r @ ca, r


@pytest.mark.parametrize("seed", [2, 9])
def test_nominals_are_one_rigid_part_turned_by_minus_c_about_the_centre(seed):
    """From the log's own columns: per set-up, the artefact-frame tip centres
    (w + r wn) map onto Xn by a rigid motion to 1e-12 mm; its angle follows
    -C (paper eq. 1, C positive clockwise seen from +Z); the fixed point of
    the motion between two set-ups is the C-axis centre."""
    log, tr = gen_b.generate("none", seed)
    c = log.columns
    r = float(log.meta["stylus_r_mm"])
    w = np.column_stack([c["wx_mm"], c["wy_mm"]]) + r * np.column_stack([c["wnx"], c["wny"]])
    xn = np.column_stack([c["Xn_mm"], c["Yn_mm"]])
    fits = {}
    for s in dict.fromkeys(c["setup"]):
        k = c["setup"] == s
        ang, t, rot = _fit_rigid_2d(w[k], xn[k])
        assert np.max(np.abs(w[k] @ rot.T + t - xn[k])) < 1e-12
        assert np.max(np.abs(np.column_stack([c["wnx"], c["wny"]])[k] @ rot.T
                             - np.column_stack([c["nx"], c["ny"]])[k])) < 1e-12
        fits[s] = (ang, t, rot, float(c["C_deg"][k][0]))
    (a0, t0, r0, c0), *rest = fits.values()
    for a1, t1, r1, c1 in rest:
        turn = (a1 - a0) + math.radians(c1 - c0)
        assert abs((turn + math.pi) % (2 * math.pi) - math.pi) < 1e-12
        # fixed point p of x -> R1 R0^-1 (x - t0) + t1
        m = r1 @ r0.T
        p = np.linalg.solve(np.eye(2) - m, t1 - m @ t0)
        assert np.allclose(p, tr.centre_mm, atol=1e-9)


def _inside(poly, pts):
    """Ray casting point-in-polygon (independent of the spline code)."""
    x, y = poly[:, 0], poly[:, 1]
    x2, y2 = np.roll(x, -1), np.roll(y, -1)
    out = []
    for px, py in pts:
        cross = ((y > py) != (y2 > py)) & (px < x + (py - y) * (x2 - x) / (y2 - y + 1e-300))
        out.append(bool(cross.sum() % 2))
    return np.array(out)


def test_part_normals_point_out_of_the_material_and_features_are_exact():
    P = gen_b.part()
    s = np.linspace(0, P.blade.x[-1], 4000, endpoint=False)
    contour = P.blade(s)
    pw, nw = P.p_W[:30, :2], P.n_W[:30]
    assert not _inside(contour, pw + 0.2 * nw).any() and _inside(contour, pw - 0.2 * nw).all()
    # the stylus ball fits every concave stretch of the blade where it touches
    k = gen_b.blade_curvature_per_mm(P.s_blade)
    assert np.all(k > -1 / gen_b.STYLUS_R_MM)
    # pins: on a 5 mm circle, normal radial
    for j, c in enumerate(P.pins_mm):
        rows = slice(30 + 4 * j, 34 + 4 * j)
        d = P.p_W[rows, :2] - c
        assert np.allclose(np.linalg.norm(d, axis=1), 5.0, atol=1e-12)
        assert np.allclose(d / 5.0, P.n_W[rows], atol=1e-12)
    # slot walls at +-8 mm from the centre line, normals into the slot
    d = P.p_W[50:, :2] - P.slot_centre_mm
    across = d @ gen_b._perp(P.slot_dir)
    assert np.allclose(np.abs(across), 8.0, atol=1e-12)
    assert np.all((-d * P.n_W[50:]).sum(1) > 0)


def test_table_axis_error_sign_by_hand():
    """X on the workpiece side: at X = 400 mm the table really sits 1 um
    further in -X than commanded, so the tool relative to the workpiece is
    1 um further in +X (EXX = +1 um). A wall facing +X (n = +X, approached
    in -X) is then 1 um farther away along -X; the machine drives 1 um
    deeper before the trigger: dq = -1 um."""
    mc = gen_b.Machine(table_x_um=(-1.0, 0.0, 0.0))
    e = gen_b.linear_error_mm(mc, np.array([[400.0, 0.0]]))
    assert e[0] == pytest.approx([1e-3, 0.0], abs=1e-15)
    dq = gen_b.touch_dq_mm(np.array([[1.0, 0.0]]), e, np.zeros(1), np.zeros(1))
    assert dq[0] == pytest.approx(-1e-3, abs=1e-15)
    # the same error seen by a wall facing -X triggers 1 um "outside": dq = +1 um
    dq = gen_b.touch_dq_mm(np.array([[-1.0, 0.0]]), e, np.zeros(1), np.zeros(1))
    assert dq[0] == pytest.approx(1e-3, abs=1e-15)


def test_c_axis_error_sign_by_hand():
    """ECC = +10 urad (tool turned +10 urad about Z relative to the part, so
    the part turned -10 urad): a point 100 mm along +X from the C centre moves
    1 um in -Y; a wall there facing +Y recedes 1 um: dq = -1 um."""
    zeros = (0.0,)
    mc = gen_b.Machine(exc_um=zeros, eyc_um=zeros, ecc_urad=(10.0,))
    centre = np.array([350.0, -220.0])
    e = gen_b.c_axis_error_mm(mc, np.array([0]), centre + [[100.0, 0.0]], centre)
    dq = gen_b.touch_dq_mm(np.array([[0.0, 1.0]]), e, np.zeros(1), np.zeros(1))
    assert dq[0] == pytest.approx(-1e-3, abs=1e-15)


def test_reading_moves_along_an_inclined_approach_by_hand():
    """Approach 30 deg downward onto a wall facing +X, dq = -2 um: the reading
    is 2 um deeper along X and 2 tan 30 = 1.1547 um lower in Z."""
    el = math.radians(30.0)
    d = np.array([[-math.cos(el), 0.0, -math.sin(el)]])
    x = gen_b.reading_mm(np.zeros((1, 3)), np.array([[1.0, 0.0]]), d, np.array([-2e-3]))
    assert x[0] == pytest.approx([-2e-3, 0.0, -2e-3 * math.tan(el)], abs=1e-15)


def test_effects_by_hand_from_the_log_columns():
    """Two effects recomputed from what the log holds plus the stated params."""
    log, tr = gen_b.generate("head_tram", 4, perfect=True, noisy=False)
    c, p = log.columns, tr.params
    z, a, tilt = c["wz_mm"], p["tilt_azimuth_rad"], p["tilt_urad"]
    hand = -(c["nx"] * math.cos(a) + c["ny"] * math.sin(a)) * z * tilt * 1e-3   # um
    assert np.max(np.abs(hand - tr.effect_dq_um)) < 1e-9
    assert np.max(np.abs(_dq_um(log) - hand)) < 1e-9
    log, tr = gen_b.generate("temperature_expansion", 4, perfect=True, noisy=False)
    c, p = log.columns, tr.params
    dT = c["temp_air_C"] - p["t_ref_C"]
    ex = p["alpha_x_um_per_m_K"] * dT * (c["Xn_mm"] - p["x_fix_mm"]) * 1e-3
    ey = p["alpha_y_um_per_m_K"] * dT * (c["Yn_mm"] - p["y_fix_mm"]) * 1e-3
    assert np.max(np.abs(-(c["nx"] * ex + c["ny"] * ey) - _dq_um(log))) < 1e-9


# ---------------------------------------------------------------------------
# logs, determinism


def test_every_effect_log_reads_back_and_passes_check(campaigns, tmp_path, capsys):
    for (e, on), (log, _) in campaigns.items():
        if not on:
            continue
        make_log(log.columns, log.meta)                    # the validating constructor
        p = write_probe_log(tmp_path / f"{e}.csv", log)
        back = read_probe_log(p)
        assert back.n == log.n and back.meta["kinematic_chain"] == gen_b.CHAIN
        for k, v in log.columns.items():
            assert np.array_equal(back.columns[k], v), (e, k)
        assert main(["check", str(p)]) == 0
    assert "valid probe-log/1 campaign" in capsys.readouterr().out
    r = subprocess.run([sys.executable, "-m", "scenarios.cli", "check", str(tmp_path / "none.csv")],
                       capture_output=True, text=True)
    assert r.returncode == 0 and "touches" in r.stdout


def test_same_seed_same_campaign_and_effect_does_not_change_the_campaign(campaigns):
    log, tr = campaigns[("stylus_pickup", True)]
    again, tr2 = gen_b.generate("stylus_pickup", SEED)
    for k in log.columns:
        assert np.array_equal(log.columns[k], again.columns[k]), k
    assert np.array_equal(tr.effect_dq_um, tr2.effect_dq_um) and tr.visible_um == tr2.visible_um
    other, _ = gen_b.generate("stylus_pickup", SEED + 1)
    assert other.n != log.n or not np.array_equal(other.columns["X_mm"], log.columns["X_mm"])
    base, _ = campaigns[("none", True)]
    for k in ("t_s", "Xn_mm", "Yn_mm", "temp_air_C", "setup", "target"):
        assert np.array_equal(base.columns[k], log.columns[k]), k


# ---------------------------------------------------------------------------
# effects: stated magnitudes, visibility, scaling


def test_each_effect_changes_dq_by_exactly_its_stated_dq(campaigns):
    for e in EFFECTS:
        on, tr = campaigns[(e, True)]
        off, _ = campaigns[(e, False)]
        diff = _dq_um(on) - _dq_um(off)
        assert np.max(np.abs(diff - tr.effect_dq_um)) < 1e-9, e      # mm -> um round-off
        assert np.sqrt(np.mean(diff**2)) == pytest.approx(tr.magnitude_um, abs=1e-9), e
        assert tr.visible_um <= tr.magnitude_um + 1e-12
        if e != "none":
            assert tr.magnitude_um > 0.05, e
    _, tr = campaigns[("outlier", True)]
    assert set(np.flatnonzero(tr.effect_dq_um)) == set(tr.outlier_rows) and len(tr.outlier_rows) >= 2


def test_visible_part_matches_the_full_eq15_least_squares(campaigns):
    """The fast projector (G eliminated by target means) against the plain SVD
    of the full eq. 15 matrix, on the effect dq of several effects."""
    for e in ("thermal_drift", "nonrigid", "fixture_slip", "reseat_settling"):
        log, tr = campaigns[(e, True)]
        c = log.columns
        setup = np.unique(c["setup"], return_inverse=True)[1]
        target = np.unique(c["target"], return_inverse=True)[1]
        xy, n = np.column_stack([c["Xn_mm"], c["Yn_mm"]]), np.column_stack([c["nx"], c["ny"]])
        A, _ = gen_b.paper_design(xy, n, setup, target, np.array(tr.centre_mm),
                                  nodes=(tr.grid_x_mm, tr.grid_y_mm))
        full = gen_b.visible_part(A, tr.effect_dq_um)
        assert np.sqrt(np.mean(full**2)) == pytest.approx(tr.visible_um, rel=1e-9, abs=1e-12), e


def _in_model_dq(log, centre, rng):
    """dq of a random field inside the paper's model: smooth axis errors,
    squareness, yaw x*ECY(y), C errors per set-up and a workpiece form."""
    c = log.columns
    x, y = c["Xn_mm"] - centre[0], c["Yn_mm"] - centre[1]
    u, v = x / 150, y / 150
    a = rng.normal(size=12)
    ex = a[0] * u + a[1] * u**2 + a[2] * v**3 - a[3] * v
    ey = a[4] * u**3 + a[5] * v**2 + u * (a[6] + a[7] * v)
    setup = np.unique(c["setup"], return_inverse=True)[1]
    tgt = np.unique(c["target"], return_inverse=True)[1]
    sc = rng.normal(size=(setup.max() + 1, 3))
    ex = ex + sc[setup, 0]
    ey = ey + sc[setup, 1] + sc[setup, 2] * 1e-2 * x
    ex = ex - sc[setup, 2] * 1e-2 * y
    return -(c["nx"] * ex + c["ny"] * ey) + rng.normal(size=tgt.max() + 1)[tgt]


def test_in_model_fields_are_absorbed_and_a_nonrigid_one_is_not(campaigns):
    log, tr = campaigns[("none", True)]
    c = log.columns
    setup = np.unique(c["setup"], return_inverse=True)[1]
    target = np.unique(c["target"], return_inverse=True)[1]
    xy, n = np.column_stack([c["Xn_mm"], c["Yn_mm"]]), np.column_stack([c["nx"], c["ny"]])
    proj = gen_b.Projector(xy, n, setup, target, tr.centre_mm, model="poly")
    dq = _in_model_dq(log, tr.centre_mm, np.random.default_rng(3))
    assert np.max(np.abs(proj.residual(dq))) < 1e-9 * np.max(np.abs(dq))
    u = (c["Xn_mm"] - tr.centre_mm[0]) / 150
    v = (c["Yn_mm"] - tr.centre_mm[1]) / 150
    assert np.sqrt(np.mean(proj.residual(c["ny"] * u**2 * v**2) ** 2)) > 1e-3
    # the base machine of every campaign is inside the model (grid interpolation only)
    assert max(t.base_visible_um for (_, on), (_, t) in campaigns.items()) < 0.02


@pytest.mark.parametrize("effect", [e for e in EFFECTS if e != "none"])
def test_sigmas_sets_the_visible_strength(effect):
    _, tr = gen_b.generate(effect, 31, sigmas=2.0, schedule="irregular5")
    assert tr.visible_sigmas == pytest.approx(2.0, rel=1e-9)
    assert tr.detectable


def test_temperature_is_decorrelated_from_time():
    corr = [abs(gen_b.generate("temperature_expansion", s)[1].params["corr_temp_time"])
            for s in range(12)]
    assert np.median(corr) < 0.5


# ---------------------------------------------------------------------------
# identifiability


@pytest.mark.parametrize("name", list(gen_b.SCHEDULES))
def test_schedules_are_flagged_identifiable_or_not(name):
    for seed in (1, 2):
        _, tr = gen_b.generate("none", seed, schedule=name)
        assert tr.workpiece_identifiable == (name not in gen_b.NOT_IDENTIFIABLE), (name, seed)


def _per_target_spread(log, centre, field):
    c = log.columns
    e = field(c["Xn_mm"] - centre[0], c["Yn_mm"] - centre[1])
    nE = c["nx"] * e[0] + c["ny"] * e[1]
    return max(np.ptp(nE[c["target"] == t]) for t in np.unique(c["target"])), np.std(nE)


def test_rotation_covariant_fields_look_like_a_workpiece_form():
    """Why quarters and thirds are not identifiable, without the null-space
    code: (f(x), f(y)) with f odd is covariant under 90 deg, (x^2 - y^2, -2xy)
    under 120 deg; both fit the rigid-body model, and n . E is the same at a
    target in every set-up, i.e. exactly a workpiece form. On an irregular
    schedule the same fields change between set-ups."""
    cubic = lambda x, y: ((x / 100) ** 3, (y / 100) ** 3)               # noqa: E731
    quad = lambda x, y: (((x / 100) ** 2 - (y / 100) ** 2), -2 * (x / 100) * (y / 100))  # noqa: E731
    for sched, field in (("quarters", cubic), ("thirds", quad)):
        log, tr = gen_b.generate("none", 8, schedule=sched)
        spread, size = _per_target_spread(log, tr.centre_mm, field)
        assert size > 0.1 and spread < 1e-12 * max(size, 1.0), sched
        log, tr = gen_b.generate("none", 8, schedule="irregular5")
        spread, size = _per_target_spread(log, tr.centre_mm, field)
        assert spread > 0.1 * size
