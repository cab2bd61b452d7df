"""``[drift]``: the machine's drift during the measurement, run by run against the hand-worked gauge.

The gauge of the study tests: face a (x = 0) probed by plan rows 0-2, face b (x = 100 mm) by rows
3-5, each face's three contacts sharing their centroid's y, z (no tilt lever). An X offset
drifting at ``v`` (m/s) makes touch i report ``v (t_i + tau)`` short along X (``tau`` = the
approach, the same for all), so the length reads ``L - v (mean t_b - mean t_a)``:
- ``touches_per_min = 6`` (t_i = 10 s i): ``L - 30 s v``;
- a measured log's own ``t_s`` (a plan's are empty) 0, 10, 20, 600, 610, 620 s: ``L - 600 s v``.
A drifting Z alone does not change the length (the faces' normals are X): it must read L.
Each face tilts by its three touches' different drifts, theta <= 3 um/h x 20 s / 10 mm = 1.7e-6 rad,
which shortens the length by L theta^2 / 2 <= 1.4e-13 m: tolerance 1e-12 m. (With both drifts
at once the Z drift between the faces, 0.5 um in 600 s, times that tilt adds ~1e-12 m: the X
check runs the X drift alone, on the same draws.)
"""

import pytest

from core import vcmm as V
from core.exceptions import ConfigError
from core.probelog import make_log
from scenarios import vcmm as S
from sim.machinefile import resolve
from tests.scenarios.test_vcmm_study import GAUGE, GAUGE_TASK, L_MM

NO_SCALE = ('[declared.EXX]\nslope_um_per_m = 10.0\ndistribution = "uniform"', "")
DRIFT = '[drift]\nx_um_per_h = 3.0\nz_um_per_h = 3.0\n'


@pytest.fixture(scope="module")
def machine():
    return resolve("vmc-3axis")


def timed(plan, t):
    """The plan as a measured log (a probe-log/1 row has all of X, Y, Z, t_s or none): its own times."""
    cols = {k: v for k, v in plan.columns.items()}
    cols["t_s"] = t
    for c in "XYZ":
        cols[f"{c}_mm"] = cols[f"{c}n_mm"]
    return make_log(cols, dict(plan.meta))


@pytest.mark.parametrize("plan, rate, dt", [(GAUGE, "touches_per_min = 6\n", 30.0),
                                            (timed(GAUGE, [0.0, 10, 20, 600, 610, 620]), "", 600.0)])
def test_drift_shortens_the_gauge_by_its_rate_times_the_time_between_faces(machine, plan, rate, dt):
    task = GAUGE_TASK.replace(*NO_SCALE) + DRIFT + rate
    st = S.prepare(plan, V.loads_task(task), machine)
    assert st.sources == ("EXX drift", "EZZ drift")
    y = S.run_values(st, 9, range(5), active=("EXX drift",))[:, 0]
    for i in range(5):
        c = S.draw(st, 9, i)[0]
        v = c[("drift", "EXX")]
        assert abs(v) <= 3e-6 / 3600 and abs(c[("drift", "EZZ")]) <= 3e-6 / 3600
        assert y[i] == pytest.approx(L_MM * 1e-3 - dt * v, abs=1e-12)
    yz = S.run_values(st, 9, range(3), active=("EZZ drift",))[:, 0]
    assert yz == pytest.approx(L_MM * 1e-3, abs=1e-12)


def test_drift_needs_times(machine):
    with pytest.raises(ConfigError, match="needs the plan's t_s on every used row or drift.touches_per_min"):
        S.prepare(GAUGE, V.loads_task(GAUGE_TASK + DRIFT), machine)


#: Bad [drift] tables (checked with the bad [form] tables: tests/scenarios/test_vcmm_form.py).
BAD_DRIFT = [
    ("[drift]\ntouches_per_min = 6\n", "drift: no rate"),
    ("[drift]\nx_um_per_h = -1\n", "drift.x_um_per_h: must be >= 0"),
    ("[drift]\nx_um_per_h = 1\ntouches_per_min = 0\n", "drift.touches_per_min"),
    ("[drift]\nw_um_per_h = 1\n", "drift.w_um_per_h: unknown key"),
]
