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
