"""The virtual machine: exact, general, and equal to core's independent model.

Tolerances: chains of ~10 4x4 products of O(1 m) magnitude round to a few
1e-16 m, so "exact" agreement is asserted at 1e-12 m.
"""

import doctest
import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import sim.machine
from core import iso
from core import kinematics as K
from core.exceptions import ConfigError
from sim.errorfuncs import Constant, Drift, Polynomial, Reversal
from sim.machine import Machine
from sim.machines import MACHINES, describe, realistic_errors

NAMES = list(MACHINES)


def _poses(cfg, rot_axes, n, rng):
    lin = np.column_stack([rng.uniform(*cfg.strokes[a], n) for a in "XYZ"])
    rot = np.column_stack([rng.uniform(*cfg.strokes[a], n) for a in rot_axes]) if rot_axes else None
    return lin, rot


def _realistic(name, rng=None):
    cfg = MACHINES[name]()
    m = Machine(cfg)
    return m.with_errors(realistic_errors(m.chain.axes, strokes=cfg.strokes, J_m=cfg.J_m, rng=rng))


def test_docstring_example_runs():
    assert doctest.testmod(sim.machine).failed == 0


def test_api_axes():
    assert Machine(MACHINES["vmc-3axis"]()).rotary_axes == ()
    m = Machine(MACHINES["nmv3000"]())
    assert m.linear_axes == ("X", "Y", "Z") and m.rotary_axes == ("A", "C")
    assert "mikron-ucp710" in describe()


# (a) all errors zero: nominal to 1e-12 m -----------------------------------
@pytest.mark.parametrize("name", NAMES)
def test_zero_errors_is_nominal(name, rng):
    cfg = MACHINES[name]()
    m = Machine(cfg)
    lin, rot = _poses(cfg, m.rotary_axes, 300, rng)
    assert np.abs(m.tip_W(lin, rot) - m.tip_W_nominal(lin, rot)).max() < 1e-12
    # rotary axes at zero: the tip in W is the reading, whichever side the axes are on
    zero = None if rot is None else np.zeros_like(rot)
    assert np.abs(m.tip_W(lin, zero) - lin).max() < 1e-12
    assert np.abs(m._nominal_fk_tip(lin, rot) - m.tip_W_nominal(lin, rot)).max() < 1e-12


def test_nominal_T_R_W_without_the_machine_is_the_machines():
    """sim.machine.nominal_T_R_W (the configuration alone, no Pinocchio model) gives
    Machine.T_R_W_nominal bit for bit: 5-axis with off-centre rotary points and errors (which a
    nominal pose must ignore), a 3-axis machine, table-side linear axes, and its input check."""
    from sim.machine import nominal_T_R_W

    rng = np.random.default_rng(3)
    cfg = MACHINES["mikron-ucp710"](rotary_points_R_m={"A": (0.0, 0.01, -0.12), "C": (0.003, -0.02, 0.0)})
    cfg = dataclasses.replace(cfg, errors=realistic_errors(("X", "Y", "Z", "A", "C"), strokes=cfg.strokes,
                                                           J_m=cfg.J_m, rng=rng))
    rot = rng.uniform(-1.5, 1.5, (7, 2))
    m = Machine(cfg)
    for args in ((rot,), (rot[:1],), (None,), (rot, rng.uniform(-0.2, 0.2, (7, 3)))):
        assert np.array_equal(nominal_T_R_W(cfg, *args), m.T_R_W_nominal(*args))
    c3 = MACHINES["vmc-3axis"]()
    assert np.array_equal(nominal_T_R_W(c3), Machine(c3).T_R_W_nominal())
    with pytest.raises(ConfigError, match="rot_rad given but"):  # the machine's own input check
        nominal_T_R_W(c3, rot)


def test_W_turns_by_minus_C_about_the_table_centre():
    cfg = MACHINES["nmv3000"](rotary_points_R_m={"C": (0.01, -0.02, 0.0)})
    m = Machine(cfg)
    C = 0.3
    T = m.T_R_W_nominal(np.array([[0.0, C]]))[0]
    c = np.array([0.01, -0.02, 0.0])
    p_W = np.array([0.05, 0.02, 0.01])
    Rz = Rotation.from_rotvec([0, 0, -C]).as_matrix()  # R(-C): C positive clockwise (eq. 1)
    assert np.allclose(T[:3, :3] @ p_W + T[:3, 3], c + Rz @ (p_W - c), atol=1e-15)
    # and the tip: the reading p_R maps to p_W = T_R_W^-1 p_R
    lin = np.array([[0.05, 0.02, 0.01]])
    tip = m.tip_W_nominal(lin, [[0.0, C]])[0]
    assert np.allclose(c + Rz @ (tip - c), lin[0], atol=1e-15)


# (c) sim (Pinocchio) == core (numpy HTM) == a short HTM product here --------
@pytest.mark.parametrize("name", NAMES)
def test_sim_agrees_with_core(name, rng):
    m = _realistic(name, rng)
    lin, rot = _poses(m.config, m.rotary_axes, 200, rng)
    t = rng.uniform(0, 3600, 200)
    d = rng.choice([-1, 0, 1], size=(200, 3))
    vals = m.error_values(lin, rot, t, d)
    assert np.abs(m.tip_W(lin, rot, t, d) - K.tip_W(m.geometry(), lin, rot, vals)).max() < 1e-12
    assert np.abs(m.T_R_W(lin, rot, t, d) - K.T_R_W(m.geometry(), lin, rot, vals)).max() < 1e-12
    # Pinocchio's own forwardKinematics, one pose at a time, is the oracle of both fast paths
    # (sim's batched evaluation of the Pinocchio model, core's direct (R, t) product)
    pin_tip = m.tip_W_pinocchio(lin, rot, t, d)
    assert np.abs(m.tip_W(lin, rot, t, d) - pin_tip).max() < 1e-12
    assert np.abs(K.tip_W(m.geometry(), lin, rot, vals) - pin_tip).max() < 1e-12
    for want in ("W", "P"):
        oracle = m._poses_pinocchio(lin, rot, t, d, want)[0 if want == "W" else 1]
        fast = m.T_R_W(lin, rot, t, d) if want == "W" else m.T_R_P(lin, rot, t, d)
        assert np.abs(fast - oracle).max() < 1e-12
    assert np.abs(K.T_R_P(m.geometry(), lin, rot, vals) - m.T_R_P(lin, rot, t, d)).max() < 1e-12


@pytest.mark.parametrize("name", NAMES)
def test_batched_kinematics_is_pinocchio_with_large_errors(name, rng):
    """Errors of 1 mm and 0.05 rad (far beyond any machine's, so no product can hide behind
    a small-angle shortcut): the batched evaluation still equals Pinocchio's loop."""
    big = {s.name: Constant(rng.uniform(-1, 1) * (0.05 if s.angular else 1e-3))
           for s in iso.SYMBOLS if s.axis in Machine(MACHINES[name]()).chain.axes
           and not (s.location and s.axis in iso.LINEAR_AXES and s.name not in iso.SQUARENESS)}
    m = Machine(MACHINES[name]()).with_errors(big)
    lin, rot = _poses(m.config, m.rotary_axes, 100, rng)
    pin_tip = m.tip_W_pinocchio(lin, rot)
    assert np.abs(pin_tip - m.tip_W_nominal(lin, rot)).max() > 1e-4  # the errors matter
    assert np.abs(m.tip_W(lin, rot) - pin_tip).max() < 1e-12
    assert np.abs(K.tip_W(m.geometry(), lin, rot, m.error_values(lin, rot)) - pin_tip).max() < 1e-12


def _H(R=np.eye(3), t=(0, 0, 0)):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _E(v, axis):  # [exp(skew(EA, EB, EC)) | (EX, EY, EZ)] of one axis from the values dict
    s = [f"E{d}{axis}" for d in "XYZABC"]
    g = [float(v.get(k, 0.0)) for k in s]
    return _H(Rotation.from_rotvec(g[3:]).as_matrix(), g[:3])


def _rz(a):
    return Rotation.from_rotvec([0, 0, a]).as_matrix()


def _rx(a):
    return Rotation.from_rotvec([a, 0, 0]).as_matrix()


def _by_hand(name, cfg, lin, rot, v):
    """The chain written out for one pose (MFB eq. 8 for the Mikron)."""
    J = np.array(cfg.J_m)
    q = lin + J
    g = lambda k: float(v.get(k, 0.0))  # noqa: E731
    c0y, b0z, a0z = g("EC0Y"), g("EB0Z"), g("EA0Z")
    SZ = Rotation.from_rotvec([a0z, b0z, 0]).as_matrix()
    Tx, Ty, Tz = (_H(t=q[i] * np.eye(3)[i]) for i in range(3))
    if name == "mikron-ucp710":  # b-X-Y-Z: squareness carried downstream (eq. 8)
        tool = Tx @ _E(v, "X") @ _H(_rz(c0y)) @ Ty @ _E(v, "Y") @ _H(SZ) @ Tz @ _E(v, "Z")
    elif name == "nmv3000":  # b-Y-X-Z: X kept along the machine X axis
        tool = _H(_rz(c0y)) @ Ty @ _E(v, "Y") @ _H(_rz(-c0y)) @ Tx @ _E(v, "X") @ _H(SZ) @ Tz @ _E(v, "Z")
    else:  # vmc: b-Y-X-w on the table (moving by -q), b-Z-t
        tool = _H(SZ) @ Tz @ _E(v, "Z")
    tip_R = tool @ np.r_[-J, 1.0]
    # workpiece branch (ISO 230-1: errors are the tool relative to the part): the
    # component moves by the exact inverse E^-1, in its carrier, before its motion
    inv = np.linalg.inv
    if name == "vmc-3axis":
        TW = _H(_rz(c0y)) @ inv(_E(v, "Y")) @ _H(t=-q[1] * np.eye(3)[1]) @ _H(_rz(-c0y)) \
            @ inv(_E(v, "X")) @ _H(t=-q[0] * np.eye(3)[0])
    else:
        cA, cC = (np.array(cfg.rotary_points_R_m[a]) for a in "AC")
        A, C = rot
        TW = (_H(Rotation.from_rotvec([0, g("EB0A"), g("EC0A")]).as_matrix(), cA + [0, g("EY0A"), g("EZ0A")])
              @ inv(_E(v, "A")) @ _H(_rx(-A)) @ _H(t=-cA)
              @ _H(Rotation.from_rotvec([g("EA0C"), g("EB0C"), 0]).as_matrix(), cC + [g("EX0C"), g("EY0C"), 0])
              @ inv(_E(v, "C")) @ _H(_rz(-C)) @ _H(t=-cC))
    return (np.linalg.inv(TW) @ tip_R)[:3]


@pytest.mark.parametrize("name", NAMES)
def test_sim_agrees_with_hand_written_htm(name, rng):
    m = _realistic(name, rng)
    lin, rot = _poses(m.config, m.rotary_axes, 20, rng)
    got = m.tip_W(lin, rot)
    vals = m.error_values(lin, rot)
    for i in range(len(lin)):
        v = {k: a[i] for k, a in vals.items()}
        want = _by_hand(name, m.config, lin[i], None if rot is None else rot[i], v)
        assert np.abs(got[i] - want).max() < 1e-12


# (b) small errors: first order = MFB eqs. 10-12 ------------------------------
def test_first_order_agrees_with_mfb_eqs_10_12(rng):
    """Mikron (b-X-Y-Z, eq. 8): tip error = -(dX, dY, dZ) of eqs. 10-12 up to
    second order. Bound: the exact chain differs from its linearisation by at
    most (sum|angles|)^2 * L + (sum|angles|) * (sum|translations|), L the
    largest arm from a pivot to the tip (< 1 m here)."""
    cfg = MACHINES["mikron-ucp710"](J_m=(0.02, -0.015, 0.15))
    m = Machine(cfg).with_errors(realistic_errors(("X", "Y", "Z"), strokes=cfg.strokes, J_m=cfg.J_m, rng=rng))
    lin, rot = _poses(cfg, ("A", "C"), 200, rng)
    geom = m.geometry()
    T = m.T_R_W_nominal(rot)
    p_w = m.tip_W_nominal(lin, rot)
    resid = []
    for scale in (1.0, 0.1):
        vals = {k: scale * v for k, v in m.error_values(lin, rot).items()}
        # eqs. 10-12 are in the machine frame R: rotate the tip error out of W
        exact = np.einsum("nij,nj->ni", T[:, :3, :3], K.tip_W(geom, lin, rot, vals) - p_w)
        delta = K.mfb_deviation(vals, p_w, T[:, :3, :3], T[:, :3, 3], cfg.J_m)
        ang = sum(np.abs(vals[s]) for s in iso.TWENTY_ONE if iso.symbol(s).angular)
        tra = sum(np.abs(vals[s]) for s in iso.TWENTY_ONE if not iso.symbol(s).angular)
        bound = ang**2 * 1.0 + ang * tra
        r = np.linalg.norm(exact + delta, axis=1)
        assert np.all(r <= bound), (r / bound).max()
        assert np.linalg.norm(exact, axis=1).max() > 100 * r.max()  # the first order is the bulk
        resid.append(r.max())
    assert resid[1] < resid[0] / 50  # quadratic: errors /10 -> remainder /100


# (d) Jacobians against finite differences of the truth ------------------------
def test_sensitivity_matches_finite_differences_of_sim(rng):
    cfg = MACHINES["nmv3000"]()
    errs = realistic_errors(("X", "Y", "Z", "A", "C"), strokes=cfg.strokes, J_m=cfg.J_m)
    m = Machine(cfg).with_errors(errs)
    lin, rot = _poses(cfg, m.rotary_axes, 5, rng)
    syms = ("EXX", "EBX", "ECY", "EC0Y", "EB0Z", "EAZ", "EX0C", "EA0C", "ECC", "EYA", "EB0A")
    S = K.sensitivity(m.geometry(), lin, rot, m.error_values(lin, rot), syms)
    h = 1e-6  # central differences; exact for the translations, O(h^2 L) for angles
    for j, s in enumerate(syms):
        plus = m.with_errors({**errs, s: errs.get(s, Constant(0.0)) + Constant(h)}).tip_W(lin, rot)
        minus = m.with_errors({**errs, s: errs.get(s, Constant(0.0)) + Constant(-h)}).tip_W(lin, rot)
        assert np.allclose(S[:, :, j], (plus - minus) / (2 * h), rtol=0, atol=1e-8), s


def test_axis_jacobian_with_error_slopes_matches_sim(rng):
    cfg = MACHINES["mikron-ucp710"]()
    errs = realistic_errors(("X", "Y", "Z", "A", "C"), strokes=cfg.strokes, J_m=cfg.J_m)
    m = Machine(cfg).with_errors(errs)
    lin, rot = _poses(cfg, m.rotary_axes, 5, rng)
    geom = m.geometry()
    vals = m.error_values(lin, rot)
    syms = tuple(vals)
    Ja = K.jacobian_axes(geom, lin, rot, vals)
    S = K.sensitivity(geom, lin, rot, vals, syms)
    cols = ("X", "Y", "Z") + m.rotary_axes
    for j, a in enumerate(cols):
        pos = lin[:, j] + geom.J_m[j] if j < 3 else rot[:, j - 3]  # the errors at the axis position reading + J
        dv = np.array([errs[s].derivative(pos) if iso.symbol(s).axis == a and not iso.symbol(s).location
                       else np.zeros(len(pos)) for s in syms]).T
        total = Ja[:, :, j] + np.einsum("nkm,nm->nk", S, dv)
        h = 1e-6
        dl, dr = np.zeros_like(lin), np.zeros_like(rot)
        (dl if j < 3 else dr)[:, j if j < 3 else j - 3] = h
        fd = (m.tip_W(lin + dl, rot + dr) - m.tip_W(lin - dl, rot - dr)) / (2 * h)
        assert np.allclose(total, fd, rtol=0, atol=1e-8), a


# (e) time and direction really move the tip -----------------------------------
def test_drift_and_reversal_move_the_tip():
    cfg = MACHINES["vmc-3axis"]()
    m = Machine(cfg).with_errors({"EXX": Reversal(4e-6), "EYY": Drift(offset_rate=1e-9)})
    lin = np.array([[0.1, 0.1, 0.1]] * 3)
    d = np.array([[1, 0, 0], [-1, 0, 0], [0, 0, 0]])
    tip = m.tip_W(lin, None, t_s=np.array([0.0, 0.0, 1000.0]), direction=d)
    # ISO 230-1 values: the tool relative to the part moves by +EXX, +EYY, also
    # on this machine's table-side X and Y
    assert np.allclose(tip - lin, [[2e-6, 0, 0], [-2e-6, 0, 0], [0, 1e-6, 0]], rtol=0, atol=1e-15)


def test_squareness_sign_convention():
    """CONTRIBUTING.md: the tip error from EC0Y is -y * EC0Y in X, on every machine."""
    lin = np.array([[0.0, 0.1, 0.0]])
    for name in NAMES:
        m = Machine(MACHINES[name](errors={"EC0Y": Constant(50e-6)}, J_m=(0, 0, 0.15)))
        rot = None if not m.rotary_axes else np.zeros((1, 2))
        # second order: y * EC0Y^2 / 2 ~ 1e-10 m in Y
        assert np.allclose(m.tip_W(lin, rot) - lin, [[-5e-6, 0, 0]], rtol=0, atol=1e-9), name


def test_c_axis_offset_moves_the_part():
    m = Machine(MACHINES["nmv3000"](errors={"EX0C": Constant(15e-6), "EY0C": Constant(6e-6)}))
    lin = np.array([[0.05, 0.0, 0.0]])
    assert np.allclose(m.tip_W(lin, [[0.0, 0.0]]) - lin, [[-15e-6, -6e-6, 0]], atol=1e-15)


def test_realistic_errors_magnitudes():
    cfg = MACHINES["mikron-ucp710"]()
    e = realistic_errors(("X", "Y", "Z", "A", "C"), strokes=cfg.strokes, J_m=cfg.J_m)
    x = np.linspace(*cfg.strokes["X"], 201)
    assert 35e-6 < np.ptp(e["EXX"](x)) < 40e-6
    assert np.abs(e["EYX"](x)).max() <= 3e-6 and np.abs(e["EBX"](x)).max() <= 100e-6
    assert np.abs(e["EAX"](x)).max() < 10e-6 and np.abs(e["ECX"](x)).max() < 40e-6
    assert e["EX0C"].value == 15e-6 and e["EY0C"].value == 6e-6
    r = realistic_errors(("X",), rng=np.random.default_rng(3))
    assert 19e-6 <= np.ptp(r["EXX"](np.linspace(-0.355, 0.355, 11))) <= 40e-6


#: The paper magnitude's peak-to-peak of each profile shape (sim.machines._LINEAR): "lin" ramps 0..mag, "bow" rises
#: 0..mag..0, "s" is mag sin(2 pi u), -mag..mag.
_PP = {"lin": 1.0, "bow": 1.0, "s": 2.0}


def _smooth(f):
    from sim.machinefile import strip_ripple

    return strip_ripple(f)


@pytest.mark.parametrize("name", sorted(MACHINES))
def test_realistic_profiles_lie_over_the_axis_positions_the_strokes_allow(name):
    """Each linear axis's realistic profile (sim.machinefile.truth_machine's set, the CLI's) is laid over the
    axis positions its stroke allows, stroke + the reference tool's J (docs/formats.md, "Strokes"; errors are
    functions of q = reading + J): over them its peak-to-peak is the paper's magnitude (to 1e-4 relative:
    the 9-node spline through a sine peaks 9e-6 above its nodes, measured) and every spline's table spans
    exactly them, so no reachable position runs on an end-tangent extension. Before session 28 the tables
    were laid over the strokes as readings: on the Mikron EAZ's bow read 46.7 urad p-p over the Z axis
    positions (paper 20), 150 mm beyond its table."""
    from sim.errorfuncs import SplineTable
    from sim.machinefile import truth_machine
    from sim.machines import _LINEAR

    cfg = truth_machine(name, "realistic").config
    for j, a in enumerate("XYZ"):
        lo, hi = cfg.strokes[a][0] + cfg.J_m[j], cfg.strokes[a][1] + cfg.J_m[j]
        q = np.linspace(lo, hi, 2001)
        for sym, shape, mag in _LINEAR[a]:
            f = _smooth(cfg.errors[sym])
            assert np.ptp(f(q)) == pytest.approx(_PP[shape] * mag, rel=1e-4), (name, sym)
            if isinstance(f, SplineTable):
                assert f.pos[0] == pytest.approx(lo, abs=1e-15) and f.pos[-1] == pytest.approx(hi, abs=1e-15)
            else:  # "lin": 0 at the stroke's low end as an axis position
                assert f(np.array([lo]))[0] == pytest.approx(0.0, abs=1e-18), (name, sym)


@pytest.mark.parametrize("plan_name", ["plan_3axis", "plan_5axis"])
def test_realistic_profiles_cover_the_positions_an_mfb_campaign_reaches(plan_name):
    """Over every axis position the MFB plans command (touches, approach starts, overshoot ends, links; q =
    reading + the measurement's stylus J, scenarios.mfb.program_positions) each linear-axis profile of the
    scenario's truth (scenarios.mfb.default_machine) stays within its table's nodes and within the paper's
    peak-to-peak (1e-4 relative: the spline's overshoot above its nodes, as above). Before session 28 the
    3-axis plan put Z at 543.8 mm, 143.8 mm past the vmc's Z tables' 400 mm (EAZ 20 -> 45.4 urad p-p, EYZ 3
    -> 6.8 um over the positions it reaches); the 5-axis plan (refitted to its node box in session 27)
    stayed within them (Z 72-393 mm)."""
    from sim.errorfuncs import SplineTable
    from sim.machines import _LINEAR
    from scenarios import mfb

    plan = getattr(mfb, plan_name)()
    _, errs = mfb.default_machine(plan.machine)
    cfg = MACHINES[plan.machine]()
    qs = []
    for ms, T_R_W, pl, art in mfb.measurement_programs(plan, cfg):
        pos = mfb.program_positions(T_R_W @ ms.T_W_A, pl, 3.0e-3, art)
        qs.append(np.concatenate([np.asarray(P, float).reshape(-1, 3) for P in pos.values()]) + np.asarray(ms.J_m))
    q = np.concatenate(qs)
    for j, a in enumerate("XYZ"):
        for sym, shape, mag in _LINEAR[a]:
            f = errs[sym]
            if isinstance(f, SplineTable):
                assert f.pos[0] <= q[:, j].min() and q[:, j].max() <= f.pos[-1], (plan_name, sym)
            assert np.ptp(f(q[:, j])) <= _PP[shape] * mag * (1 + 1e-4), (plan_name, sym)


def test_realistic_errors_refuse_strokes_without_their_reference_tool():
    """Strokes are written in the reference tool's readings: without its J the axis positions they allow are
    unknown (a silent default would lay a custom machine's tables 150 mm off); a bad J is named."""
    cfg = MACHINES["vmc-3axis"]()
    with pytest.raises(ConfigError, match="strokes given without J_m"):
        realistic_errors(("X",), strokes=cfg.strokes)
    for bad in ((0.0, 0.0), (0.0, 0.0, float("nan"))):
        with pytest.raises(ConfigError, match="J_m must be 3 finite values"):
            realistic_errors(("X",), strokes=cfg.strokes, J_m=bad)
    # J_m = 0: strokes already in axis positions; the Z tables then lie over the strokes as they are
    e = realistic_errors(("Z",), strokes=cfg.strokes, J_m=(0.0, 0.0, 0.0))
    assert e["EAZ"].pos[0] == cfg.strokes["Z"][0] and e["EAZ"].pos[-1] == cfg.strokes["Z"][1]
    e = realistic_errors(("Z",), strokes=cfg.strokes, J_m=cfg.J_m)
    assert e["EAZ"].pos[0] == cfg.strokes["Z"][0] + 0.150 and e["EAZ"].pos[-1] == cfg.strokes["Z"][1] + 0.150


def test_realistic_errors_draw_each_screws_ripple_phase_from_the_seed():
    """A drawn machine's 10 mm screw ripple sits at a phase drawn from its generator, one per screw (every
    "lin" profile of X shares X's phase: EXX, EBX), drawn after every other value: the same seed with and
    without the ripple gives the same magnitudes, signs and rotary phases to the bit. Before session 27 every
    ripple sat at phase 0 in every seed. The nominal set (no generator) keeps phase 0, and
    ripple_phase=0.0 pins a seeded set's ripples there (the set before)."""
    from sim.errorfuncs import Periodic, Sum

    cfg = MACHINES["nmv3000"]()
    axes = ("X", "Y", "Z", "A", "C")
    phases = []
    for seed in (3, 4):
        e = realistic_errors(axes, strokes=cfg.strokes, J_m=cfg.J_m, rng=np.random.default_rng(seed))
        smooth = realistic_errors(axes, strokes=cfg.strokes, J_m=cfg.J_m, rng=np.random.default_rng(seed), ripple=False)
        ph = {}
        for k, f in e.items():
            if k[2] in "XYZ" and isinstance(f, Sum):
                poly, rip = f.terms
                assert isinstance(rip, Periodic) and rip.period == 0.010
                assert repr(poly) == repr(smooth[k]), k       # the profile itself: the same draw
                ph[k] = rip.phase
            else:
                assert repr(f) == repr(smooth[k]), k          # every other error: the same draw
        assert set(ph) == {"EXX", "EBX", "EYY", "ECY", "EZZ", "EBZ"}
        assert ph["EXX"] == ph["EBX"] and ph["EYY"] == ph["ECY"] and ph["EZZ"] == ph["EBZ"]
        assert len({ph["EXX"], ph["EYY"], ph["EZZ"]}) == 3 and all(0.0 < v < 2 * np.pi for v in ph.values())
        phases.append(ph["EXX"])
    assert phases[0] != phases[1]
    again = realistic_errors(axes, strokes=cfg.strokes, J_m=cfg.J_m, rng=np.random.default_rng(3))
    assert again["EXX"].terms[1].phase == phases[0]        # deterministic per seed
    nominal = realistic_errors(axes, strokes=cfg.strokes, J_m=cfg.J_m)
    assert nominal["EXX"].terms[1].phase == 0.0
    pinned = realistic_errors(axes, strokes=cfg.strokes, J_m=cfg.J_m, rng=np.random.default_rng(3), ripple_phase=0.0)
    assert {pinned[k].terms[1].phase for k in ("EXX", "EBX", "EYY", "ECY", "EZZ", "EBZ")} == {0.0}
    assert pinned["EXX"].terms[1].amplitude == again["EXX"].terms[1].amplitude


@pytest.mark.parametrize("kw, match", [
    (dict(errors={"EQQ": Constant(0.0)}), "unknown ISO error symbol"),
    (dict(errors={"EB0X": Constant(1e-6)}), "zero by the ISO 230-1 convention"),
    (dict(errors={"EX0C": Polynomial((0, 1e-6))}), "must be Constant"),
    (dict(errors={"EXB": Constant(0.0)}), "belongs to axis B"),
    (dict(errors={"EXX": 1e-6}), "not an ErrorFunction"),
    (dict(strokes={"X": (0.3, -0.3)}), "stroke of X"),
    (dict(J_m=(0.0, 0.0)), "J_m must be 3"),
])
def test_bad_config(kw, match):
    with pytest.raises(ConfigError, match=match):
        MACHINES["nmv3000"](**kw)


def test_bad_inputs():
    m = Machine(MACHINES["nmv3000"]())
    with pytest.raises(ConfigError, match="lin_m must be"):
        m.tip_W(np.zeros((4, 2)))
    with pytest.raises(ConfigError, match="rot_rad must be"):
        m.tip_W(np.zeros((4, 3)), np.zeros((4, 3)))
    with pytest.raises(ConfigError, match="no rotary axis"):
        Machine(MACHINES["vmc-3axis"]()).tip_W(np.zeros((2, 3)), np.zeros((2, 1)))
    with pytest.raises(ConfigError, match="lacks linear axis Z"):
        sim.machine.MachineConfig("x", "[w-X-Y-b-t]", {"X": (0, 1), "Y": (0, 1)})


def test_error_values_are_each_function_at_its_axis():
    # issue 19 item 5: error_values evaluates spline tables of an axis together and the
    # position-only errors of a rotary axis once per distinct angle; every value must be
    # the function's own at that pose (bit for bit), whatever the mix: tables on shared
    # and on other knots, sums, a time-dependent rotary error, reversal, a cross-axis term
    from sim.errorfuncs import CrossAxis, Periodic, SplineTable

    rng = np.random.default_rng(11)
    xs = tuple(np.linspace(-0.4, 0.4, 9))

    def table(x=xs):
        return SplineTable(x, tuple(rng.normal(scale=4e-6, size=len(x))))

    errors = {"EXX": table() + Polynomial((1e-6, 2e-6)), "EYX": table(), "EZX": table(), "EAX": table(),
              "EBX": table((-0.1, 0.0, 0.2, 0.3)), "EXY": table(), "EYY": Reversal(3e-6) + table(),
              "EZZ": CrossAxis(1e-4, "X"), "EC0Y": Constant(2e-5),
              "EXC": Periodic(3e-6, np.pi / 2), "EYC": Drift(offset_rate=1e-9) + Periodic(1e-6, np.pi),
              "ECC": Periodic(2e-6, np.pi, 0.3), "EAA": Periodic(1e-5, np.pi / 3), "EY0A": Constant(1e-5)}
    m = Machine(MACHINES["nmv3000"](errors=errors))
    n = 600
    lin = rng.uniform(-0.5, 0.5, (n, 3))
    rot = np.column_stack([rng.choice(rng.uniform(-1, 1, 5), n) for _ in m.rotary_axes])  # few angles
    t, d = rng.uniform(0, 1e3, n), rng.choice([-1.0, 0.0, 1.0], (n, 3))
    got = m.error_values(lin, rot, t, d)
    assert list(got) == list(errors)
    q = lin + np.asarray(m.config.J_m, float)  # a linear axis's errors are functions of its axis position reading + J
    axes = {a: q[:, k] for k, a in enumerate("XYZ")}
    for name, f in errors.items():
        s = iso.symbol(name)
        if s.location:
            want = np.full(n, f.value)
        elif s.axis in "XYZ":
            i = "XYZ".index(s.axis)
            want = f.evaluate(q[:, i], t, d[:, i], axes)
        else:
            want = f(rot[:, m.rotary_axes.index(s.axis)], t, None)
        assert got[name].shape == (n,) and np.array_equal(got[name], want), name


@pytest.mark.parametrize("drift", [False, True])
def test_workpiece_branch_once_per_angle_is_pinocchio(drift, rng):
    # issue 19 item 5: on a machine whose workpiece branch holds only rotary axes with
    # position-only errors, tip_W evaluates W once per distinct rotary position; against
    # Pinocchio's own loop (1e-12 m, module docstring) and against the full batched walk
    # (the same products on the same numbers: 1e-15 m, rounding of the libm only); a drift
    # on C makes W time-dependent, where the full walk must be taken
    m = _realistic("mikron-ucp710", rng)
    if drift:
        err = dict(m.config.errors)
        err["EXC"] = err["EXC"] + Drift(offset_rate=1e-8)
        m = m.with_errors(err)
    assert m._W_by_angles is not drift
    n = 400
    lin, _ = _poses(m.config, (), n, rng)
    angles = np.column_stack([rng.uniform(*m.config.strokes[a], 6) for a in m.rotary_axes])
    rot = angles[rng.integers(0, 6, n)]
    t, d = rng.uniform(0, 3e3, n), rng.choice([-1.0, 0.0, 1.0], (n, 3))
    got = m.tip_W(lin, rot, t, d)
    assert np.max(np.abs(got - m.tip_W_pinocchio(lin, rot, t, d))) < 1e-12
    m._W_by_angles = False
    assert np.max(np.abs(got - m.tip_W(lin, rot, t, d))) < 1e-15


def test_runs_of_equal_rows():
    # the dedupe behind the once-per-angle evaluations: consecutive equal rows share a run,
    # a value met again later and every NaN row get runs of their own
    from sim.machine import _runs

    a = np.array([[1.0, 2.0], [1.0, 2.0], [1.0, 3.0], [1.0, 2.0], [np.nan, 0.0], [np.nan, 0.0], [4.0, 0.0]])
    first, inv = _runs(a)
    assert first.tolist() == [0, 2, 3, 4, 5, 6] and inv.tolist() == [0, 0, 1, 2, 3, 4, 5]
    np.testing.assert_array_equal(a[first][inv], a)
    first, inv = _runs(np.array([0.5, 0.5, 0.5]))
    assert first.tolist() == [0] and inv.tolist() == [0, 0, 0]
    assert _runs(np.zeros((0, 2)))[0].size == 0 and _runs(np.zeros((1, 2)))[1].tolist() == [0]


@pytest.mark.parametrize("name", NAMES)
def test_per_pose_probe_offsets_are_each_stylus_machine(name, rng):
    # issue 19 item 3: tip_W with each pose's offsets J_m (several styli in one call) against
    # a machine built with each stylus's offsets (bit for bit: the same products on the same
    # numbers) and against Pinocchio's own loop on it (1e-12 m, module docstring); on the
    # Mikron both walks (W once per angle, and the full one)
    m = _realistic(name, rng)
    n = 120
    lin, rot = _poses(m.config, m.rotary_axes, n, rng)
    t, d = rng.uniform(0, 3e3, n), rng.choice([-1.0, 0.0, 1.0], (n, 3))
    styli = rng.uniform(-0.06, 0.06, (4, 3)) + [0.0, 0.0, 0.15]
    which = rng.integers(0, 4, n)
    for by_angles in {m._W_by_angles, False}:
        m._W_by_angles = by_angles
        got = m.tip_W(lin, rot, t, d, J_m=styli[which])
        # the offsets matter (they cancel nominally: through the angular errors, um here)
        assert np.abs(got - m.tip_W(lin, rot, t, d)).max() > 1e-7
        for k, J in enumerate(styli):
            mk = Machine(dataclasses.replace(m.config, J_m=tuple(J)))
            mk._W_by_angles = by_angles
            sel = which == k
            r = None if rot is None else rot[sel]
            assert got[sel].tobytes() == mk.tip_W(lin[sel], r, t[sel], d[sel]).tobytes()
            assert np.abs(got[sel] - mk.tip_W_pinocchio(lin[sel], r, t[sel], d[sel])).max() < 1e-12
    with pytest.raises(ConfigError, match="per-pose probe offsets"):
        m.tip_W(lin, rot, t, d, J_m=np.full((n, 3), np.nan))


def _through_models_cache(monkeypatch, configs, fresh: bool):
    """tip_W, T_R_W, T_R_P and Pinocchio's own tip of each config's machine, built one after the
    other through one models cache (``fresh``: the cache emptied before each build), and the machines."""
    from core.memo import Memo

    monkeypatch.setattr(sim.machine, "_MODELS", Memo(32))
    rng = np.random.default_rng(11)
    lin, rot = _poses(configs[0], Machine(configs[0]).rotary_axes, 40, rng)
    out, machines = [], []
    for cfg in configs:
        if fresh:
            sim.machine._MODELS.clear()
        m = Machine(cfg)
        out.append((m.tip_W(lin, rot), m.T_R_W(lin, rot), m.T_R_P(lin, rot), m.tip_W_pinocchio(lin[:5], rot[:5])))
        machines.append(m)
    return out, machines


def _cache_configs():
    """nmv3000 with two sets of location errors (squareness, the C line) and motion errors, then the
    first's location errors with other motion errors (the Monte Carlo's case: same models)."""
    cfg = MACHINES["nmv3000"]()
    a = {"EC0Y": Constant(-43e-6), "EX0C": Constant(5e-6), "EA0C": Constant(20e-6), "EXX": Polynomial((1e-6, 2e-5))}
    b = {"EC0Y": Constant(31e-6), "EX0C": Constant(-7e-6), "EA0C": Constant(-9e-6), "EXX": Polynomial((-2e-6, 1e-5))}
    c = {**a, "EXX": Polynomial((3e-6, -4e-5)), "ECC": Constant(15e-6)}
    return [dataclasses.replace(cfg, errors=e) for e in (a, b, c)]


def test_models_cache_gives_what_fresh_builds_give_bit_for_bit(monkeypatch):
    """Machines with different errors built one after the other through the models cache (one per
    geometry and location errors, issue 19 item 5) give what fresh builds give, bit for bit: the
    location errors are in the key, the motion errors in each machine's own configurations."""
    configs = _cache_configs()
    cached, ms = _through_models_cache(monkeypatch, configs, fresh=False)
    fresh, _ = _through_models_cache(monkeypatch, configs, fresh=True)
    for got, want in zip(cached, fresh):
        for g, w in zip(got, want):
            assert np.array_equal(g, w)
    assert ms[2]._model is ms[0]._model and ms[1]._model is not ms[0]._model   # the cache is used
    assert ms[2]._data is not ms[0]._data                                       # scratch not shared
    assert not np.array_equal(cached[0][0], cached[1][0]) and not np.array_equal(cached[0][0], cached[2][0])


def test_models_cache_key_without_the_location_errors_would_be_caught(monkeypatch):
    """The test above fails if the key omits the errors: with a key of the geometry alone the
    second machine reuses the first's location errors and its tips differ from a fresh build's."""
    key = Machine._models_key
    monkeypatch.setattr(Machine, "_models_key", lambda self: key(self)[:3])
    configs = _cache_configs()
    cached, _ = _through_models_cache(monkeypatch, configs, fresh=False)
    fresh, _ = _through_models_cache(monkeypatch, configs, fresh=True)
    assert not np.array_equal(cached[1][0], fresh[1][0])


def test_shared_batched_kinematics_arrays_are_read_only():
    """The batched kinematics' joint and frame placements are shared by every Machine with the same
    model key (sim.machine._MODELS): writing one must fail, not change another machine's tips."""
    mm = sim.machine
    m = Machine(MACHINES["nmv3000"]())
    fks = [v for v in vars(m).values() if isinstance(v, mm._BatchFK)]
    assert fks, "no batched kinematics found on the machine"
    n = 0
    for fk in fks:
        for jt in fk.joints:
            if jt is None:
                continue
            for a in jt:
                if isinstance(a, np.ndarray):
                    with pytest.raises(ValueError):
                        a[...] = 0.0
                    n += 1
        for _, Rf, tf in fk.frames_:
            for a in (Rf, tf):
                if a is not None:
                    with pytest.raises(ValueError):
                        a[...] = 0.0
                    n += 1
    assert n > 0
