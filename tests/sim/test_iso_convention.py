"""ISO 230-1's sign convention, checked where it matters: in the touches.

Every error value is the displacement of the tool relative to the
workpiece, whichever side of the bed the axis is on (CONTRIBUTING.md,
"Error conventions"). The hand-worked case: ``EXX = +1 um`` leaves the tool
1 um further in +X relative to the part than commanded; a touch triggers
when the real tool reaches the surface, which the scale reports 1 um short,
so a touch on an X face (facing +X or -X) reads ``X_mm - Xn_mm = -1 um``,
and in general ``p - pn = -(n . E) n`` (a flat face: exactly; a sphere: up to
(1 um)^2 / (2 R) ~ 1e-10 m). Here through the real touch simulation
(``sim.campaign`` / ``sim.probe`` on the Pinocchio chain), not through core's
formula, on a machine whose X carries the table and on one whose X carries
the tool. Tolerance 1 nm: the touch simulation agrees with the geometry to
< 1e-12 m, the sphere term is 1e-10 m.
"""

import numpy as np
import pytest

from sim import artefacts as A
from sim.campaign import Setup, simulate_campaign
from sim.errorfuncs import Constant
from sim.machine import Machine, MachineConfig
from sim.machines import realistic_errors
from sim.probe import ProbeConfig

STROKES = {"X": (-0.30, 0.30), "Y": (-0.20, 0.20), "Z": (-0.05, 0.40)}
#: X carries the table (vmc-3axis), X carries the tool (the Mikron's linear axes)
CHAINS = {"table": "V[w-X-Y-b-Z-(C)-t]", "tool": "[w-b-X-Y-Z-t]"}


def _machine(chain, errors):
    return Machine(MachineConfig("iso", chain, STROKES, J_m=(0.0, 0.0, 0.150), errors=errors))


@pytest.fixture(scope="module")
def pocket():
    art = A.cross_pocket(form=None)
    return art


@pytest.mark.parametrize("side", ["table", "tool"])
def test_exx_plus_one_um_reads_minus_one_um_on_every_x_face(pocket, side):
    m = _machine(CHAINS[side], {"EXX": Constant(1e-6)})
    assert m.chain.side("X") == ("workpiece" if side == "table" else "tool")
    log = simulate_campaign(pocket, m, ProbeConfig(repeatability_k2_m=0.0), [Setup("s", pocket.T_W_A)],
                            None, check_collisions=False)
    ok = log.ok
    n = log.normals()[ok]
    d_um = (log.positions_mm() - log.nominals_mm())[ok] * 1e3  # X_mm - Xn_mm ..., um
    on_x = np.abs(n[:, 0]) > 1 - 1e-12
    # both facings are present: walls facing +X and facing -X
    assert (n[on_x, 0] > 0).sum() >= 4 and (n[on_x, 0] < 0).sum() >= 4
    # the hand-worked reading: X_mm - Xn_mm = -1 um, Y and Z untouched
    np.testing.assert_allclose(d_um[on_x], np.tile([-1.0, 0.0, 0.0], (on_x.sum(), 1)), rtol=0, atol=1e-3)
    # every touch (Y walls, floor, spheres): p - pn = -(n . E) n with E = (1 um, 0, 0)
    np.testing.assert_allclose(d_um, -n[:, [0]] * n, rtol=0, atol=1e-3)


def test_same_iso_errors_same_tip_table_or_tool_side(rng):
    """X on the table ([w-X-b-Y-Z-t]) or on the tool ([w-b-X-Y-Z-t]), the same 21
    errors: the tool relative to the part is the same, to rounding (1e-12 m),
    exactly, not only to first order (the table moves by the exact inverse)."""
    errs = realistic_errors(("X", "Y", "Z"), strokes=STROKES, J_m=(0.0, 0.0, 0.150), rng=rng)
    a = _machine("[w-X-b-Y-Z-t]", errs)
    b = _machine("[w-b-X-Y-Z-t]", errs)
    lin = np.column_stack([rng.uniform(*STROKES[k], 200) for k in "XYZ"])
    ta, tb = a.tip_W(lin), b.tip_W(lin)
    assert np.abs(ta - lin).max() > 10e-6  # the errors are there
    assert np.abs(ta - tb).max() < 1e-12
    # table on X on Y (vmc-3axis) and the tool on X on Y: the 18 motion errors
    motion = {k: f for k, f in errs.items() if k not in ("EC0Y", "EB0Z", "EA0Z")}
    c = _machine("V[w-X-Y-b-Z-(C)-t]", motion)
    d = _machine("[w-b-X-Y-Z-t]", motion)
    assert np.abs(c.tip_W(lin) - d.tip_W(lin)).max() < 1e-12


@pytest.mark.parametrize("carrier", ["A", "B"])
def test_rotary_location_errors_are_relative_to_the_carrying_axis(carrier):
    """review33b F1: a C carried by A (or B) has its line placed in the carrier's frame, not in R
    (CONTRIBUTING.md, "Error conventions"; core.selfcal.c_centre_note states it): with the carrier at 0,
    C's line at height z in R, relative to its nominal point, is the first-order
    d_C + w_C x (P - c_C) + d_K + w_K x (P - c_K) - (e_K + eps_K x (P - c_K)) (location errors d, w;
    the carrier's error motions e, eps at its angle; P the line's point at z). The line is found from the
    simulator's part poses over a half turn of C (the fixed line of the rigid motion), not from the formula.
    Errors drawn within +-10 um / urad, rotary points off the origin; tolerance 1 nm: the formula's
    neglected second order is (10 urad)(10 um) and (10 urad)^2 x 0.11 m, ~1e-10 m (seen 0.2 nm)."""
    rng = np.random.default_rng(7)
    chain = f"[w-C-{carrier}-b-X-Y-Z-t]"
    cK, cC = np.array([0.01, -0.02, -0.11]), np.array([0.03, 0.015, 0.0])
    loc = {"A": ("EY0A", "EZ0A", "EB0A", "EC0A"), "B": ("EX0B", "EZ0B", "EA0B", "EC0B")}[carrier]
    syms = [*loc, *(f"E{d}{carrier}" for d in "XYZABC"), "EX0C", "EY0C", "EA0C", "EB0C"]
    errs = {s: float(rng.uniform(-10, 10)) * 1e-6 for s in syms}
    strokes = {**STROKES, carrier: (-2.0, 2.0), "C": (-7.0, 7.0)}
    m = Machine(MachineConfig("carried", chain, strokes, J_m=(0.0, 0.0, 0.150),
                              rotary_points_R_m={carrier: tuple(cK), "C": tuple(cC)},
                              errors={k: Constant(v) for k, v in errs.items()}))

    def v(*names):
        return np.array([errs.get(n, 0.0) for n in names])

    k = carrier
    for z in (0.0, 0.05):
        rot = np.zeros((2, 2))
        rot[:, list(m.rotary_axes).index("C")] = [0.0, np.pi]
        T = m.T_R_W(np.zeros((2, 3)), rot)
        M = T[1] @ np.linalg.inv(T[0])                 # the table's half turn about C's line, in R
        R, t = M[:3, :3], M[:3, 3]
        w, V = np.linalg.eig(R)
        u = np.real(V[:, np.argmin(abs(w - 1))])
        u = u * np.sign(u[2])                          # the line's direction
        p = np.linalg.lstsq(np.eye(3) - R, t, rcond=None)[0]
        seen = (p + u * ((z - p[2]) / u[2]))[:2] - cC[:2]
        P = np.array([cC[0], cC[1], z])
        hand = (v("EX0C", "EY0C", "EZ0C") + np.cross(v("EA0C", "EB0C", "EC0C"), P - cC)
                + v(f"EX0{k}", f"EY0{k}", f"EZ0{k}") + np.cross(v(f"EA0{k}", f"EB0{k}", f"EC0{k}"), P - cK)
                - v(f"EX{k}", f"EY{k}", f"EZ{k}") - np.cross(v(f"EA{k}", f"EB{k}", f"EC{k}"), P - cK))
        np.testing.assert_allclose(seen, hand[:2], atol=1e-9)
        # the carrier's part is there: the line is not at (EX0C, EY0C) + C's own tilt alone
        own = (v("EX0C", "EY0C", "EZ0C") + np.cross(v("EA0C", "EB0C", "EC0C"), P - cC))[:2]
        assert np.hypot(*(seen - own)) > 1e-6
