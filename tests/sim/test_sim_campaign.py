"""Plans and campaigns: counts, probe-log round trip, refusals, no_trigger."""

import numpy as np
import pytest

from core.exceptions import ConfigError, PlanError
from core.probelog import read_probe_log, write_probe_log
from core.touches import from_log
from sim import artefacts as A
from sim.campaign import simulate_campaign
from sim.catalog import make_plan
from sim.plans import mfb_plan
from sim.setups import Setup, mfb_placements
from sim.probe import ProbeConfig
from standins import Translated


class RotaryC(Translated):
    """Stand-in 4-axis machine: perfect, W turned by R(-C) about Z (paper eq. 1)."""

    rotary_axes = ("C",)

    def T_R_W_nominal(self, rot, lin=None):
        rot = np.atleast_2d(rot)
        return np.stack([A.make_T(A.rot_z(-c), (0, 0, 0)) for c in rot[:, 0]])

    def tip_W(self, lin, rot=None, t=None, d=None):
        T = self.T_R_W_nominal(rot)
        return np.einsum("nji,nj->ni", T[:, :3, :3], np.asarray(lin) - T[:, :3, 3])


def test_mfb_plan_has_316_touches():
    p = mfb_plan(A.multi_feature_bar())
    c = p.counts()
    assert c == {"hole": 8 * 12, "rod": 12 * 11, "face": 4 * 22}
    assert 96 + 132 + 88 == 316 == p.n


def test_other_plan_counts():
    assert make_plan(A.cross_pocket()).n == 92  # 84 wall + 8 sphere points per C angle
    assert make_plan(A.pin_circle()).n == 18 * 4 + 2 * 8  # 88 (the paper's "84" does not add up)
    assert make_plan(A.freeform_plate()).n == 72
    assert len(mfb_placements()) == 17


def test_campaign_round_trip_and_truth(tmp_path, rng):
    art = A.cross_pocket()
    log = simulate_campaign(art, RotaryC(), ProbeConfig(), [0, 75, 130, 210], rng)
    assert log.n == 4 * 92 and set(log.col("status")) == {"ok"}
    p = write_probe_log(tmp_path / "c.csv", log)
    back = read_probe_log(p)
    for k in ("machine", "artefact", "stylus_r_mm", "kinematic_chain"):
        assert k in back.meta
    t = from_log(back)
    assert t.n == 368 and len(t.setup_ids) == 4 and len(t.target_ids) == 92
    assert np.all(np.diff(t.t_s) > 0)
    # perfect machine: dq is the wall form error (same at every C) plus noise
    dq = t.dq_m.reshape(4, 92)
    assert np.max(np.abs(dq - dq[0])) < 8 * ProbeConfig().sigma_m * np.sqrt(2)
    # w* identical across set-ups; C column in degrees
    assert sorted(set(back.col("C_deg"))) == [0.0, 75.0, 130.0, 210.0]


def test_plan_only_has_empty_measured_columns(tmp_path):
    log = simulate_campaign("pin-circle", Translated(), ProbeConfig(), [0.0], None, plan_only=True)
    assert log.is_plan and log.n == 88
    back = read_probe_log(write_probe_log(tmp_path / "p.csv", log))
    assert back.is_plan


def test_translation_error_gives_minus_n_dot_E(rng):
    E = np.array([4e-6, -3e-6, 2e-6])
    log = simulate_campaign("freeform", Translated(E), ProbeConfig(repeatability_k2_m=0), [0.0], None,
                            check_collisions=False)
    nolog = simulate_campaign("freeform", Translated(), ProbeConfig(repeatability_k2_m=0), [0.0], None,
                              check_collisions=False)
    dq = (log.dq_mm() - nolog.dq_mm()) * 1e-3
    np.testing.assert_allclose(dq, -log.normals() @ E, atol=1e-9)  # CONTRIBUTING: dq = -n . E


def test_missed_surface_is_a_no_trigger_row(tmp_path):
    art = A.pin_circle()
    # the true pin 3 is 10 mm (more than pin + stylus radius) off in Y: the -X approach misses it
    D = A.pin_default_deviations().copy()
    D[2] = (0.0, 10.0e-3)
    art_off = A.pin_circle(deviations_m=D)
    log = simulate_campaign(art_off, Translated(), ProbeConfig(), [0.0], None, check_collisions=False)
    st = log.col("status")
    assert st[8] == "no_trigger" and np.isnan(log.columns["X_mm"][8])
    assert st[9] == "early_trigger"  # the +Y start is inside the moved pin
    assert (st == "ok").sum() == 88 - 4
    back = read_probe_log(write_probe_log(tmp_path / "m.csv", log))
    assert from_log(back).n == (st == "ok").sum()
    assert art.name == art_off.name


def test_crashing_placement_is_refused():
    art = A.multi_feature_bar()
    # the bar sunk 12 mm into the table plane of the scene: the rod approach from
    # above still works, but a placement that puts the bar through the probe body is refused
    bad = Setup("P99", A.make_T(A.rot_x(np.pi / 2), (-0.275, 0.0, 0.07)))
    with pytest.raises(PlanError, match="set-up 'P99' target"):
        simulate_campaign(art, Translated(), ProbeConfig(), [bad], None)


def test_a_crash_is_raised_before_a_later_set_ups_stroke_error():
    """The path checks of a campaign's set-ups run at once after their moves (sim.campaign._PathChecker):
    a set-up's crash is still raised before a later set-up's stroke error, and a set-up's stroke
    error before a later set-up's crash, as when each set-up was checked in turn."""
    from types import SimpleNamespace

    class Stroked(Translated):
        config = SimpleNamespace(strokes={"X": (-1.0, 1.0), "Y": (-1.0, 1.0), "Z": (-1.0, 1.0)})

    art = A.multi_feature_bar()
    bad = Setup("P99", A.make_T(A.rot_x(np.pi / 2), (-0.275, 0.0, 0.07)))  # (as above: a crash)
    far = Setup("FAR", A.make_T(A.rot_x(np.pi / 2), (3.0, 0.0, 0.07)))  # (outside the X stroke)
    with pytest.raises(PlanError, match="set-up 'P99' target 'hole01_u0': link move crashes") as e:
        simulate_campaign(art, Stroked(), ProbeConfig(), [bad, far], None)
    assert e.value.__context__ is None  # (raised on its own, not while the stroke error is handled)
    with pytest.raises(PlanError, match="set-up 'FAR' target .*: X = .* is outside the stroke"):
        simulate_campaign(art, Stroked(), ProbeConfig(), [far, bad], None)


def test_target_too_close_to_a_corner_is_refused():
    art = A.cross_pocket()
    p = make_plan(art)
    w = p.w_A.copy()
    w[0] = (0.1, 0.0175, -3e-3)  # on the end wall, 0.5 mm from the concave corner
    bad = type(p)(p.artefact, p.target, p.feature, w, p.wn_A, p.level)
    with pytest.raises(PlanError, match="target 'wall00_0'"):
        simulate_campaign(art, Translated(), ProbeConfig(), [0.0], None, plan=bad)


def test_bad_setups():
    with pytest.raises(ConfigError, match="has no C axis"):
        simulate_campaign("cross-pocket", Translated(), ProbeConfig(), [0, 90], None)
    with pytest.raises(ConfigError, match="unknown artefact"):
        simulate_campaign("nope", Translated(), ProbeConfig(), [0], None)


def test_real_machine_campaign(tmp_path, rng):
    pytest.importorskip("pinocchio")
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors

    cfg = MACHINES["nmv3000"]()
    m = Machine(MACHINES["nmv3000"](errors=realistic_errors(("X", "Y", "Z", "A", "C"), strokes=cfg.strokes,
                                                            J_m=cfg.J_m)))
    log = simulate_campaign("cross-pocket", m, ProbeConfig.ibaraki(), [0, 75, 130, 210], rng)
    assert log.meta["kinematic_chain"] == cfg.chain and log.meta["machine"] == "nmv3000"
    t = from_log(read_probe_log(write_probe_log(tmp_path / "r.csv", log)))
    assert t.n == 368
    # errors of tens of um show: dq differs between C angles far beyond the noise
    dq = t.dq_m.reshape(4, 92)
    assert np.std(dq[1] - dq[0]) > 3e-6


def test_cli_simulate_writes_a_readable_log(tmp_path, capsys):
    from scenarios.cli import main

    out = tmp_path / "cp.csv"
    assert main(["simulate", "cross-pocket", "--out", str(out), "--seed", "4", "--c-angles-deg", "0,75"]) == 0
    log = read_probe_log(out)
    assert log.n == 184 and log.meta["artefact"] == "cross-pocket" and log.meta["seed"] == "4"
    assert main(["simulate", "cross-pocket", "--out", str(out), "--plan-only"]) == 0
    assert read_probe_log(out).is_plan
    assert main(["simulate", "mfb", "--out", str(out), "--c-angles-deg", "0"]) == 2
    assert "placements" in capsys.readouterr().err


@pytest.fixture(scope="module")
def drifting_mikron():
    """The MFB machine with realistic errors plus a thermal drift and a reversal error
    (the touches' times and directions matter), Pinocchio chain."""
    pytest.importorskip("pinocchio")
    from sim.errorfuncs import Drift, Reversal
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors

    cfg = MACHINES["mikron-ucp710"]()
    err = dict(realistic_errors(("X", "Y", "Z", "A", "C"), strokes=cfg.strokes, J_m=cfg.J_m))
    err["EXX"] = err["EXX"] + Drift(offset_rate=2e-9, scale_rate=1e-10)
    err["EYY"] = err["EYY"] + Reversal(3e-6)
    return Machine(MACHINES["mikron-ucp710"](errors=err))


@pytest.mark.parametrize("art", ["mfb", "cross-pocket", "pin-circle", "freeform"])
def test_all_setups_at_once_is_the_setup_by_setup_path(art, drifting_mikron, monkeypatch):
    # issue 19 item 5: one simulate_touches call for every set-up against the path before
    # (one call per set-up, kept as _simulate_each_setup), with noise, drift and reversal.
    # Each touch's root finding does the same arithmetic either way, so the positions agree
    # to 1e-12 m (the "same touch" bound of the issue; observed 0 m) and the noise, drawn in
    # the same order, is the same draw.
    from sim import campaign

    setups = None if art == "mfb" else [0.0, 75.0, 210.0]
    logs = []
    for f in (campaign._simulate_setups, campaign._simulate_each_setup):
        monkeypatch.setattr(campaign, "_simulate_setups", f)
        logs.append(simulate_campaign(art, drifting_mikron, ProbeConfig(), setups, np.random.default_rng(7),
                                      check_collisions=False))
    new, old = logs
    assert new.n == old.n and list(new.col("status")) == list(old.col("status"))
    assert list(new.col("setup")) == list(old.col("setup"))
    pn, po = new.positions_mm(), old.positions_mm()
    assert np.array_equal(np.isnan(pn), np.isnan(po))
    assert np.nanmax(np.abs(pn - po)) * 1e-3 < 1e-12
    tn, to = np.asarray(new.col("t_s"), float), np.asarray(old.col("t_s"), float)
    assert np.array_equal(np.isnan(tn), np.isnan(to)) and np.nanmax(np.abs(tn - to)) < 1e-9


def test_measurements_of_several_styli_at_once_are_each_campaign(drifting_mikron):
    # issue 19 item 3: the 5-axis MFB plan's 17 measurements (7 styli, 9 table indexes, 3 hole
    # sets) simulated in one call, each touch with its stylus's offsets, against one campaign per
    # measurement on a machine built with those offsets: the same logs bit for bit (each touch's
    # arithmetic is the same; the noise, drift and reversal draws the same), NaNs included.
    from dataclasses import replace

    from scenarios.mfb import PLANS, U_PLACE, _plan_for, _program
    from sim import campaign
    from sim.campaign import simulate_measurements
    from sim.machine import Machine

    plan, art, probe = PLANS["mfb-5axis"](), A.multi_feature_bar(), ProbeConfig()
    program, machines, items = _program(U_PLACE), {}, []
    for ms in plan.measurements:
        m = machines.setdefault(ms.stylus, Machine(replace(drifting_mikron.config, J_m=tuple(ms.J_m))))
        items.append((art, m, probe, Setup(ms.name, ms.T_W_A, tuple(ms.rot_rad)), _plan_for(art, ms.holes, **program)))
    assert len({id(m) for _, m, *_ in items}) == 6  # T0, TYM, TXF, TX1, TX2, TXL (session 26: TY1, TY2, TYL out)
    new = simulate_measurements(items, np.random.default_rng(3), stroke_check=False)
    # one clock (review30b F2): each campaign starts 300 s (the bar's set-up change) after the one before
    # ended (its last retract and dwell), so the drift goes on across the measurements
    old = _campaigns_on_one_clock(items, np.random.default_rng(3))
    ts = [np.asarray(g.col("t_s"), float) for g in new]
    assert np.nanmin(ts[0]) < 300.0 and all(np.nanmin(b) > np.nanmax(a) + 300.0 for a, b in zip(ts, ts[1:]))
    assert all(a.positions_mm().tobytes() == b.positions_mm().tobytes() for a, b in zip(
        old, campaign._simulate_each_measurement(items, np.random.default_rng(3), stroke_check=False)))
    assert len(new) == len(old) == 15
    for a, b in zip(new, old):
        assert a.meta == b.meta and a.n == b.n
        for c in ("setup", "target", "feature", "status"):
            assert list(a.col(c)) == list(b.col(c))
        for c in ("X_mm", "Y_mm", "Z_mm", "t_s", "Xn_mm", "nx", "C_deg", "A_deg"):
            assert np.asarray(a.col(c), float).tobytes() == np.asarray(b.col(c), float).tobytes(), c
    # a machine that differs in more than its offsets (here a compensated-like copy with other
    # errors) is simulated campaign by campaign: still the same logs
    other = Machine(replace(drifting_mikron.config, errors={}))
    mixed = [items[0], (art, other) + items[1][2:]]
    got = simulate_measurements(mixed, np.random.default_rng(5), stroke_check=False)
    ref = _campaigns_on_one_clock(mixed, np.random.default_rng(5))
    for a, b in zip(got, ref):
        assert a.positions_mm().tobytes() == b.positions_mm().tobytes()
        assert np.asarray(a.col("t_s"), float).tobytes() == np.asarray(b.col("t_s"), float).tobytes()


def _campaigns_on_one_clock(items, rng):
    """The oracle of sim.campaign.simulate_measurements: one simulate_campaign per measurement, each started
    300 s (the bar's set-up change, sim.catalog) after the one before ended (its last retract and dwell)."""
    from sim import campaign

    out, t = [], 0.0
    for a, m, p, st, pl in items:
        out.append(simulate_campaign(a, m, p, [st], rng, plan=pl, check_collisions=False, stroke_check=False,
                                     t_start_s=t))
        _, end = campaign._touch_start_times(campaign.setup_moves(m, a, pl, st, p), np.full(
            pl.n, pl.clearance_m + pl.overshoot_m), t, campaign.PROBING_FEED_MPS, campaign.RAPID_FEED_MPS)
        t = end + 300.0
    return out


def test_first_outside_stroke_is_the_first_position_reached_then_x_y_z():
    """sim.campaign.first_outside_stroke, the one stroke rule of sim.campaign.check_strokes and
    scenarios.mfb.check_program_strokes. Known answers: row 1 (Y 2 mm beyond, Z 5 mm beyond) is named
    before row 2 (X 50 mm beyond: larger, but reached later), and Y before Z within it; 1 nm beyond is
    within (STROKE_TOL_M, rounding), 2 nm is not; an axis without a stroke is not checked."""
    from sim.campaign import STROKE_TOL_M, first_outside_stroke

    st = {"X": (-0.1, 0.1), "Y": (-0.1, 0.1), "Z": (0.0, 0.4), "C": (-3.2, 3.2)}
    q = np.array([[0.0, 0.0, 0.2], [0.0, -0.102, 0.405], [0.15, 0.0, 0.2]])
    i, j, v, lim, over = first_outside_stroke(q, st)
    assert (i, j, v, lim) == (1, 1, -0.102, -0.1) and over == pytest.approx(0.002, abs=1e-15)
    assert first_outside_stroke(q[[0, 2]], st)[:4] == (1, 0, 0.15, 0.1)
    assert STROKE_TOL_M == 1e-9
    assert first_outside_stroke([[0.1 + 1e-9, 0.0, 0.0]], st) is None
    assert first_outside_stroke([[0.1 + 2e-9, 0.0, 0.0]], st)[:2] == (0, 0)
    assert first_outside_stroke([[5.0, 0.0, 0.2]], {"Y": (-0.1, 0.1), "Z": (0.0, 0.4)}) is None
    assert first_outside_stroke(np.empty((0, 3)), st) is None


def test_check_strokes_on_axis_positions_with_a_reference_tool_and_the_excess_named():
    """sim.campaign.check_strokes: a stroke bounds the axis position (reading + J - J_ref,
    docs/formats.md "Strokes"). Known answers: a link point at Z reading 0.300 m inside Z's 0.400 m
    on the machine's own offsets (J_ref default: its readings) and with J_ref equal to J; a stylus
    0.101 m longer than the reference tool puts the axis 1 mm beyond: refused naming the excess."""
    from types import SimpleNamespace

    from sim.campaign import check_strokes

    def machine(J):
        return SimpleNamespace(config=SimpleNamespace(strokes={"X": (-1.0, 1.0), "Y": (-1.0, 1.0), "Z": (-0.1, 0.4)},
                                                      J_m=J), rotary_axes=())

    plan = SimpleNamespace(n=1, overshoot_m=0.003, target=["t0"])
    mv = SimpleNamespace(links=[np.array([[0.0, 0.0, 0.300], [0.0, 0.0, 0.100]])],
                         Xn_R=np.array([[0.0, 0.0, 0.090]]), n_R=np.array([[0.0, 0.0, 1.0]]))
    st = Setup("S", np.eye(4), ())
    check_strokes(machine((0.0, 0.0, 0.251)), st, plan, mv)  # its own offsets: readings
    check_strokes(machine((0.0, 0.0, 0.150)), st, plan, mv, J_ref_m=(0.0, 0.0, 0.150))
    with pytest.raises(PlanError, match=r"set-up 'S' target 't0': Z = 401\.000 mm is outside the stroke "
                                        r"-100\.\.400 mm by 1\.000 mm \(axis position"):
        check_strokes(machine((0.0, 0.0, 0.251)), st, plan, mv, J_ref_m=(0.0, 0.0, 0.150))
    # the overshoot end (0.087 m) counts too: Z's lower end at 0.088 m refuses it by 1 mm
    m = machine((0.0, 0.0, 0.150))
    m.config.strokes["Z"] = (0.088, 0.4)
    with pytest.raises(PlanError, match=r"Z = 87\.000 mm is outside the stroke 88\.\.400 mm by 1\.000 mm$"):
        check_strokes(m, st, plan, mv)


def test_the_bars_links_are_its_part_programs_moves():
    """The bar's link moves (which set each touch's simulated t_s through their length at rapid feed)
    are the ones its part program moves and scenarios.mfb checks (program_positions' "links",
    sim.mfb_scene.link_points: out along z_A above the bar, across, back), not a climb along the
    machine's z over the bar's top (before session 27: +181 s over the 17 default placements' 5,372
    touches). The first touch comes down z_A from the clearance plane. A lying artefact keeps R z."""
    from scenarios import mfb as S
    from sim.campaign import setup_moves
    from sim.catalog import CATALOG
    from sim.machine import Machine
    from sim.machines import MACHINES
    from sim.mfb_scene import LINK_CLEAR_M
    from sim.scene import artefact_points

    art = S._nominal_bar()
    plan = make_plan(art)
    probe = ProbeConfig()
    m = Machine(MACHINES["mikron-ucp710"]())
    assert CATALOG["mfb"].links_along_z_A and not CATALOG["cross-pocket"].links_along_z_A
    for st in CATALOG["mfb"].default_setups(m, art)[:4]:
        mv = setup_moves(m, art, plan, st, probe)
        T_R_A = mv.T_R_W @ np.asarray(st.T_W_A, float)
        want = S.program_positions(T_R_A, plan, probe.stylus_r_m, art)["links"]
        np.testing.assert_array_equal(np.concatenate(mv.links[1:]), want)
        first = A.apply_T(A.inv_T(T_R_A), mv.links[0])
        top = artefact_points(art)[:, 2].max() + probe.stylus_r_m + LINK_CLEAR_M
        np.testing.assert_allclose(first[0], [*first[1, :2], top], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(mv.links[0][1], mv.start_R[0])
        seg = [np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in mv.links]
        np.testing.assert_allclose(mv.link_len_m, seg, rtol=1e-12)
