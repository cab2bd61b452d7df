"""Truth error functions: known answers, derivatives, bad parameters."""

import numpy as np
import pytest

from core.exceptions import ConfigError
from sim.errorfuncs import (Constant, Drift, LinearTable, Periodic, Polynomial, Reversal, SplineTable,
                            Sum, Zero)

POS = np.linspace(-0.3, 0.3, 7)


def test_zero_and_constant():
    assert np.all(Zero()(POS) == 0)
    assert np.allclose(Constant(5e-6)(POS), 5e-6)
    assert Constant(1e-6)(0.0).shape == (1,)


def test_polynomial_known_answer():
    f = Polynomial((1e-6, 2e-5, -3e-4))  # 1 um + 20 um/m x - 300 um/m^2 x^2
    assert np.allclose(f(POS), 1e-6 + 2e-5 * POS - 3e-4 * POS**2, rtol=0, atol=1e-18)
    assert np.allclose(f.derivative(POS), 2e-5 - 6e-4 * POS, rtol=0, atol=1e-18)


def test_spline_passes_through_table_and_is_c2():
    x = (-0.3, -0.1, 0.0, 0.2, 0.3)
    y = (0.0, 2e-6, 1e-6, -1e-6, 0.5e-6)
    f = SplineTable(x, y)
    assert np.allclose(f(x), y, rtol=0, atol=1e-18)
    # a cubic is reproduced exactly by a not-a-knot spline
    g = SplineTable(x, tuple(1e-5 * np.array(x) ** 3))
    assert np.allclose(g(POS), 1e-5 * POS**3, rtol=0, atol=1e-18)
    # outside the table: continued along the end tangent
    assert np.isclose(g(0.4)[0], g(0.3)[0] + g.derivative(0.3)[0] * 0.1, rtol=0, atol=1e-18)


def test_linear_table_known_answer():
    f = LinearTable((-0.1, 0.0, 0.2), (1e-6, 3e-6, -1e-6))
    # between points: linear; beyond the ends: the end segments continued
    np.testing.assert_allclose(f([-0.2, -0.05, 0.0, 0.1, 0.3]), [-1e-6, 2e-6, 3e-6, 1e-6, -3e-6], rtol=0, atol=1e-18)
    np.testing.assert_allclose(f.derivative([-0.05, 0.1]), [2e-5, -2e-5], rtol=0, atol=1e-18)


def test_periodic_known_answer():
    f = Periodic(1e-6, 0.01, np.pi / 2)  # cosine of 10 mm pitch
    assert np.allclose(f([0.0, 0.005, 0.01]), [1e-6, -1e-6, 1e-6], rtol=0, atol=1e-18)


def test_drift_grows_with_time_and_follows_temperature():
    f = Drift(offset_rate=1e-9, scale_rate=1e-8)  # 1 nm/s + 10 nm/(m s)
    assert np.allclose(f([0.1], t_s=100.0), (1e-9 + 1e-9) * 100, rtol=0, atol=1e-18)
    assert np.all(f(POS) == 0)  # t = 0
    g = Drift(offset_rate=1e-9, tau_s=600.0)
    assert np.isclose(g([0.0], t_s=1e6)[0], 600e-9)  # saturates at rate * tau
    h = Drift(scale_per_K=11.5e-6, temperature_t_s=(0, 3600), temperature_K=(293.15, 295.15))
    assert np.isclose(h([0.2], t_s=1800.0)[0], 11.5e-6 * 0.2 * 1.0)  # 1 K halfway
    assert not h.static


def test_reversal_depends_on_direction():
    f = Reversal(4e-6)
    assert np.allclose(f(POS[:3], direction=[1, -1, 0]), [2e-6, -2e-6, 0])
    assert np.all(f(POS) == 0)


def test_reversal_lag_is_the_lead_mirrored():
    """A lag (backlash, the axis stopping short) subtracts half the lost motion moving in + and adds it moving in -:
    ISO 230-2's reversal value ``x_up - x_down`` is -size, a lead's +size; the default is the lead, as before."""
    lead, lag = Reversal(4e-6), Reversal(4e-6, sense="lag")
    d = np.array([1.0, -1.0, 0.0])
    assert lead.sense == "lead" and lead == Reversal(4e-6, "lead")
    assert np.array_equal(lag(POS[:3], direction=d), -lead(POS[:3], direction=d))
    assert np.array_equal(lag(POS[:3], direction=d), [-2e-6, 2e-6, 0.0])
    assert lead.reversal_value == 4e-6 and lag.reversal_value == -4e-6
    assert np.all(lag(POS) == 0) and lag.static is False


def test_sum_and_add():
    f = Constant(1e-6) + Periodic(1e-6, 0.01)
    assert isinstance(f, Sum)
    assert np.allclose(f([0.0025]), 2e-6)
    assert Sum((Reversal(1e-6), Constant(0.0))).static is False


@pytest.mark.parametrize("f", [
    Polynomial((1e-6, 2e-5, -3e-4, 1e-3)), SplineTable((-0.3, 0, 0.1, 0.3), (0, 1e-6, 3e-6, 0)),
    Periodic(1e-6, 0.05, 0.3), Drift(offset_rate=1e-9, scale_rate=2e-8, tau_s=100.0),
    Constant(1e-6) + Periodic(2e-6, 0.1)])
def test_derivative_matches_finite_differences(f):
    h = 1e-6
    p = 0.9 * POS  # inside the spline table: its ends are only C1
    fd = (f(p + h, t_s=50.0) - f(p - h, t_s=50.0)) / (2 * h)
    # central difference: truncation h^2 f''' ~ 1e-12 * 1e-3; round-off 1e-16*1e-5/1e-6
    assert np.allclose(f.derivative(p, t_s=50.0), fd, rtol=1e-6, atol=1e-12)


@pytest.mark.parametrize("make, match", [
    (lambda: Constant(float("nan")), "Constant.value must be finite"),
    (lambda: Constant("a"), "Constant.value must be a number"),
    (lambda: Polynomial(()), "at least one coefficient"),
    (lambda: SplineTable((0.0,), (1.0,)), "at least 2 points"),
    (lambda: SplineTable((0.0, 1.0), (1.0,)), "values has 1"),
    (lambda: SplineTable((0.0, 0.0, 1.0), (1.0, 2, 3)), "strictly increasing"),
    (lambda: LinearTable((0.0,), (1.0,)), "at least 2 points"),
    (lambda: LinearTable((1.0, 0.0), (1.0, 2.0)), "strictly increasing"),
    (lambda: Periodic(1e-6, 0.0), "period must be > 0"),
    (lambda: Drift(tau_s=-1.0), "tau_s must be > 0"),
    (lambda: Drift(scale_per_K=1e-5), "need a temperature history"),
    (lambda: Drift(temperature_t_s=(0, 1), temperature_K=(293,)), "temperature_K has 1"),
    (lambda: Reversal(-1e-6), "lost_motion must be >= 0"),
    (lambda: Reversal(1e-6, sense="behind"), "sense must be"),
    (lambda: Sum(()), "non-empty"),
    (lambda: Sum((Constant(0.0), 3.0)), "not an error function"),
])
def test_bad_parameters(make, match):
    with pytest.raises(ConfigError, match=match):
        make()


def test_cross_axis_couples_two_axes_in_the_machine():
    import numpy as np
    from core.exceptions import ConfigError
    from sim.errorfuncs import CrossAxis
    from sim.machine import Machine
    from sim.machines import MACHINES

    k = 2e-6 / 0.1 ** 2  # 2 um at (0.1, 0.1) m
    m = Machine(MACHINES["nmv3000"](errors={"EXX": CrossAxis(k, "Y")}))
    lin = np.array([[0.1, 0.1, 0.0], [0.1, -0.1, 0.0], [0.0, 0.1, 0.0]])
    dev = m.tip_W(lin, np.zeros((3, len(m.rotary_axes)))) - lin
    np.testing.assert_allclose(dev[:, 0], [2e-6, -2e-6, 0.0], atol=1e-15)
    with pytest.raises(ConfigError, match="needs the reading of axis Y"):
        CrossAxis(k, "Y")(np.zeros(2))
    with pytest.raises(ConfigError, match="linear axis"):
        CrossAxis(k, "C")


def test_spline_stack_is_each_table():
    # issue 19 item 5: tables on the same knots in one call; each row is the table's own
    # value, bit for bit (the same coefficients and compiled evaluation), inside the
    # table, on its ends and on the tangent lines outside it
    from sim.errorfuncs import SplineStack

    rng = np.random.default_rng(4)
    x = (-0.3, -0.2, -0.05, 0.1, 0.2, 0.3)
    tables = [SplineTable(x, tuple(rng.normal(scale=5e-6, size=6))) for _ in range(4)]
    tables.append(SplineTable(x[:3], (1e-6, -1e-6, 2e-6)))  # natural ends: not on these knots
    p = np.concatenate([rng.uniform(-0.5, 0.5, 500), x, [-0.3000001, 0.3000001]])
    got = SplineStack(tables[:4])(p)
    assert got.shape == (4, len(p))
    for k in range(4):
        assert np.array_equal(got[k], tables[k](p))
    assert np.array_equal(SplineStack(tables[:1])(0.25)[0], tables[0](0.25))
    with pytest.raises(ConfigError, match="same knots"):
        SplineStack(tables[3:])
    with pytest.raises(ConfigError, match="same knots"):
        SplineStack([])
