"""Line features and profile deviation through the exact simulator, run by run against hand-worked answers.

The part: a face with outward normal +Y at y = 30 mm probed at x = -40, -20, 0, 20, 40 mm
(the line ``rail``, nominal direction -X: ``d = z x n``) and a face with outward normal +X at
x = 50 mm probed at y = -20, 0, 20 mm (the line ``side``, direction +Y). The machine (vmc-3axis,
no errors of its own) gets a declared straightness of X in Y, ``EYX(x) = c + s x + q x^2``, and of
Y in X, ``EXY(y) = t y``. A touch on a face of normal n reports the surface displaced by the
error against n (the tool sits at the command plus the error, so it meets the face when the
command is short of it by the error): ``n . (reported - nominal) = -E``, here ``-EYX(x_i)``
for the rail and ``-EXY(y_j)`` for the side, exactly (no noise).

Hand-worked consequences, to the fit's rounding (1e-12):
- rail direction ``(-1, s) / |.|`` (the points stay on a line when q = 0): angle from +X
  ``pi - atan(s)``; side direction ``(-t, 1) / |.|``: ``pi / 2 + atan(t)``; the angle of
  their outward normals ``(s, 1)`` and ``(1, t)``: ``pi / 2 - atan(s) - atan(t)``.
- with q only: x_i symmetric about 0, so the LS line of ``-q x^2`` is the constant
  ``-q mean(x^2)``; straightness ``|q| (max x^2 - min x^2) = |q| 1600 mm^2``.
- profile of the rail: ``d_i = -EYX(x_i)``: max, min, rms ``sqrt(mean d^2)``, zone ``2 max |d|``.
"""

import math

import numpy as np
import pytest

from core import vcmm as V
from scenarios import vcmm as S
from sim.machinefile import resolve
from tests.scenarios.test_vcmm_study import plan_of

XS = np.array([-40.0, -20.0, 0.0, 20.0, 40.0])   # mm
YS = np.array([-20.0, 0.0, 20.0])
PLAN = plan_of([("rail", (x, 30.0, -10.0), (0, 1, 0)) for x in XS] + [("side", (50.0, y, -10.0), (1, 0, 0))
                                                                      for y in YS])
HEAD = """
[features.rail]
kind = "line"
feature = "rail"
[features.side]
kind = "line"
feature = "side"
[probe]
noise_um = 0.0
"""


def meas(name, q, of, stat=None):
    of = f'"{of}"' if isinstance(of, str) else "[" + ", ".join(f'"{x}"' for x in of) + "]"
    return f'[[measurands]]\nname = "{name}"\nquantity = "{q}"\nof = {of}\n' + (f'statistic = "{stat}"\n' if stat else "")


@pytest.fixture(scope="module")
def machine():
    return resolve("vmc-3axis")


def test_line_angles_under_declared_slopes(machine):
    task = (HEAD + meas("rail angle", "angle", "rail") + meas("side angle", "angle", "side")
            + meas("between", "angle", ["rail", "side"]) + meas("gap", "distance", ["side", "rail"])
            + '[declared.EYX]\nslope_um_per_m = 200.0\n[declared.EXY]\nslope_um_per_m = 200.0\n')
    st = S.prepare(PLAN, V.loads_task(task), machine)
    y = S.run_values(st, 3, range(6))
    signs = set()
    for i in range(6):
        c = S.draw(st, 3, i)[0]
        s, t = c[("EYX", 1)], c[("EXY", 1)]
        signs.add(s > 0)
        assert y[i, 0] == pytest.approx(math.pi - math.atan(s), abs=1e-12)
        assert y[i, 1] == pytest.approx(math.pi / 2 + math.atan(t), abs=1e-12)
        assert y[i, 2] == pytest.approx(math.pi / 2 - math.atan(s) - math.atan(t), abs=1e-12)
    assert signs == {True, False}   # the rail's angle crossed the +-180 deg cut without a jump
    # the perfect machine: side's surface line x = 50 mm, rail's centroid y = 30 mm: the gap is the rail
    # centroid's distance from the side's line, 50 - 0 = 50 mm
    y0 = V.evaluate(st.task, st.rows, S.simulate_run(st, {}, None, noise=False), st.n_R, st.probe.stylus_r_m)
    assert y0[3] == pytest.approx(0.05, abs=1e-12)


def test_straightness_and_profile_of_a_bowed_rail(machine):
    task = (HEAD + meas("straight", "straightness", "rail") + "".join(
        meas(f"p {k}", "profile", "rail", k) for k in V.PROFILE_STATISTICS)
        + '[declared.EYX]\nconstant_um = 2.0\nquadratic_um_per_m2 = 500.0\n')
    st = S.prepare(PLAN, V.loads_task(task), machine)
    y = S.run_values(st, 5, range(5))
    x = XS * 1e-3
    for i in range(5):
        c = S.draw(st, 5, i)[0]
        c0, q = c[("EYX", 0)], c[("EYX", 2)]
        assert abs(q) <= 500e-6 and abs(c0) <= 2e-6
        assert y[i, 0] == pytest.approx(abs(q) * 0.04 ** 2, abs=1e-12)
        d = -(c0 + q * x ** 2)
        assert y[i, 1:] == pytest.approx([d.max(), d.min(), math.sqrt(np.mean(d * d)), 2 * np.abs(d).max()],
                                         abs=1e-12)


def test_profile_needs_the_nominal_points():
    task = V.loads_task(HEAD + meas("p", "profile", "rail", "max"))
    with pytest.raises(V.ConfigError, match="profile deviation needs the nominal points"):
        V.evaluate(task, {"rail": np.arange(5), "side": np.arange(5, 8)}, np.c_[np.arange(8.0), np.zeros((8, 2))],
                   np.tile([0, 1.0, 0], (8, 1)), 0.0)
