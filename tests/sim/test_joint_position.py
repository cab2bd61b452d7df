"""Motion errors are functions of the axis (joint) position q = reading + J, not of the tip reading.

Viprey et al. 2016 (MFB) eq. 8 writes the tip of the b-X-Y-Z chain as the product of each axis's
nominal motion and its motion errors E_XX(X), E_YX(X)... evaluated at the JOINT parameters X, Y, Z,
with the probe offset J applied last: ``tip = T_X(X) E_X(X) T_Y(Y) E_Y(Y) T_Z(Z) E_Z(Z) (-J)``.
The homogeneous transforms below are this test's own (not the code's); the machine is the built-in
mikron-ucp710 (tool-side X, Y, Z, eq. 8's chain) with its rotary axes at zero and no rotary or
location error, so W coincides with R and the tip is exactly that product.

Known answers (hand-worked):
- a pure translation error (EXX = a X, EZZ = b Z) moves the tip by (a X, 0, b Z) at the carriage
  position (X, Y, Z), whatever the stylus: at a fixed carriage every stylus sees the same deviation;
- an angular error EAZ(Z) = c Z rotates what Z carries about x: the tip moves by (R_x(c Z) - I)(-J),
  its lever arm the stylus offset J.
Tolerances: 1e-15 m (products of 4x4 transforms of O(0.5 m), rounding only).
"""

import numpy as np
import pytest

from core import kinematics as K
from sim.errorfuncs import Polynomial
from sim.machine import Machine
from sim.machines import MACHINES

A_EXX = 100e-6  # 100 um/m
B_EZZ = 100e-6
C_EAZ = 50e-6  # 50 urad/m

STYLI = {"T0": (0.0, 0.0, 0.150), "TX1": (-0.100, 0.0, 0.150), "TYL": (0.0, -0.100, 0.250)}


def _trans(v):
    T = np.eye(4)
    T[:3, 3] = v
    return T


def _rot_x(a):
    T = np.eye(4)
    c, s = np.cos(a), np.sin(a)
    T[1:3, 1:3] = [[c, -s], [s, c]]
    return T


def _eq8_tip(q, J, exx=0.0, ezz=0.0, eaz=0.0):
    """Eq. 8 by hand: T_X(X) E_X T_Y(Y) T_Z(Z) E_Z (-J), errors at the joint q."""
    X, Y, Z = q
    E_X = _trans((exx * X, 0.0, 0.0))
    E_Z = _trans((0.0, 0.0, ezz * Z)) @ _rot_x(eaz * Z)
    T = _trans((X, 0, 0)) @ E_X @ _trans((0, Y, 0)) @ _trans((0, 0, Z)) @ E_Z
    return (T @ np.append(-np.asarray(J, float), 1.0))[:3]


def _machine(J, **errs):
    return Machine(MACHINES["mikron-ucp710"](errors={k: Polynomial((0.0, v)) for k, v in errs.items()}, J_m=J))


CARRIAGES = [np.array([0.0, 0.0, 0.200]), np.array([0.150, -0.080, 0.320]), np.array([-0.250, 0.100, 0.050])]


@pytest.mark.parametrize("q", CARRIAGES)
def test_translation_errors_give_every_stylus_the_same_deviation(q):
    devs = []
    for name, J in STYLI.items():
        m = _machine(J, EXX=A_EXX, EZZ=B_EZZ)
        r = (q - np.asarray(J))[None]  # the reading at that carriage position
        rot = np.zeros((1, 2))
        tip = m.tip_W(r, rot)[0]
        want = _eq8_tip(q, J, exx=A_EXX, ezz=B_EZZ)
        np.testing.assert_allclose(tip, want, rtol=0, atol=1e-15)
        # the same through core's chain, the values evaluated at q = reading + J by the simulator
        vals = m.error_values(r, rot)
        np.testing.assert_allclose(K.tip_W(m.geometry(), r, rot, vals)[0], want, rtol=0, atol=1e-15)
        devs.append(tip - r[0])
    # hand-worked: (a X, 0, b Z) at the carriage, identical for every stylus
    for d in devs:
        np.testing.assert_allclose(d, [A_EXX * q[0], 0.0, B_EZZ * q[2]], rtol=0, atol=1e-15)


@pytest.mark.parametrize("q", CARRIAGES)
def test_angular_error_lever_arm_is_the_stylus_offset(q):
    for name, J in STYLI.items():
        m = _machine(J, EAZ=C_EAZ)
        r = (q - np.asarray(J))[None]
        tip = m.tip_W(r, np.zeros((1, 2)))[0]
        np.testing.assert_allclose(tip, _eq8_tip(q, J, eaz=C_EAZ), rtol=0, atol=1e-15)
        # the deviation: the rotation R_x(c Z) at the joint Z applied to the lever arm -J
        a = C_EAZ * q[2]
        lever = -np.asarray(J)
        want = np.array([0.0, np.cos(a) * lever[1] - np.sin(a) * lever[2] - lever[1],
                         np.sin(a) * lever[1] + np.cos(a) * lever[2] - lever[2]])
        np.testing.assert_allclose(tip - r[0], want, rtol=0, atol=1e-15)
    # two styli differing only in J_Z by 100 mm at one carriage: the y deviations differ by c Z * 0.1 m
    d = [(_machine(J, EAZ=C_EAZ).tip_W((q - np.asarray(J))[None], np.zeros((1, 2)))[0] - (q - np.asarray(J)))
         for J in ((0.0, -0.100, 0.150), (0.0, -0.100, 0.250))]
    assert abs((d[1][1] - d[0][1]) - C_EAZ * q[2] * 0.100) < 1e-15 + 1e-6 * abs(C_EAZ * q[2] * 0.1)


def test_per_pose_offsets_evaluate_at_each_poses_joint():
    """``tip_W(J_m=...)`` (several styli in one call) evaluates each pose's errors at its own
    reading + J, bit for bit as a machine per stylus."""
    base = _machine(STYLI["T0"], EXX=A_EXX, EZZ=B_EZZ, EAZ=C_EAZ)
    Js = np.array(list(STYLI.values()))
    q = CARRIAGES[1]
    r = q - Js
    got = base.tip_W(r, np.zeros((3, 2)), J_m=Js)
    each = np.array([_machine(tuple(J), EXX=A_EXX, EZZ=B_EZZ, EAZ=C_EAZ).tip_W(r[i:i + 1], np.zeros((1, 2)))[0]
                     for i, J in enumerate(Js)])
    assert np.array_equal(got, each)
    vals = base.error_values(r, np.zeros((3, 2)), J_m=Js)
    np.testing.assert_allclose(vals["EZZ"], B_EZZ * q[2], rtol=0, atol=1e-18)
    np.testing.assert_allclose(vals["EXX"], A_EXX * q[0], rtol=0, atol=1e-18)
