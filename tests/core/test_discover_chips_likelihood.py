"""The outlier screen at a target whose touches disagree, decided by the target's face (session 23, issue 13 item 7).

``OUTLIER_CHIPS_LIKELIHOOD``: at a target whose touches disagree beyond the outlier bound, the touch set aside is the
one that disagrees with the target's prediction from its face's other targets (``core.discover._target_z``), not
the one furthest from the target's own mean (which keeps two agreeing chips and sets aside their clean neighbour).
No sign is assumed: a burr's skid (reading less material) beside clean touches is still the one set aside.

gen_a outlier 1505 (a tuning seed): three chips (9.1, 8.4 and 4.4 um) on the four touches of one target of wall1
(log rows 73, 90, 237; the fourth, 254, clean). The deleted-residual screen sets aside 237 and 254 (the smallest chip
and the clean touch); the face predicts the target within 0.15 um of the clean touch (z -0.14) and the chips at
z 8.3, 7.9 and 3.9.
"""

import numpy as np
import pytest

import core.discover as D
from core import selfcal


def _wall(seed=3, n_t=12, chips=(), skids=()):
    """A wall of ``n_t`` targets (normal +y, x 0..0.2 m), three touches each; its true form a smooth bow; one
    parameter per target, noise 0.3 um. ``chips``/``skids``: (row, um) added."""
    rng = np.random.default_rng(seed)
    tg = np.repeat(np.arange(n_t), 3)
    X = (tg[:, None] == np.arange(n_t)[None, :]).astype(float)
    x = np.linspace(0.0, 0.2, n_t)
    form = 2e-6 + 3e-6 * (x / 0.2) + 0.4e-6 * ((x / 0.1 - 1) ** 2 - 1 / 3)
    y = X @ form + rng.normal(0, 0.3e-6, tg.size)
    for r, h in tuple(chips) + tuple(skids):
        y[r] += h * 1e-6
    P = np.column_stack([x, np.full(n_t, 0.05)])
    N = np.tile([0.0, 1.0], (n_t, 1))
    places = D.Places(tg[:, None], ("target",), np.arange(tg.size), None, None, tg, np.arange(n_t),
                      selfcal.workpiece_gauge_basis(P, N), np.zeros(n_t, int), X.shape[1])
    return X, y, places


def test_off_by_default():
    assert D.OUTLIER_CHIPS_LIKELIHOOD is False


def test_two_chips_against_one_clean_touch(monkeypatch):
    # two chips of +3 um (10 sigma) on target 4's first two touches: the target's mean sits between them and the
    # clean third touch, which the screen sets aside; the wall's other targets predict the clean touch
    X, y, places = _wall(chips=((12, 3.0), (13, 3.2)))
    monkeypatch.setattr(D, "OUTLIER_CHIPS_LIKELIHOOD", False)
    assert D.find_outliers(X, y, 0.001, places=places) == [14]
    monkeypatch.setattr(D, "OUTLIER_CHIPS_LIKELIHOOD", True)
    assert D.find_outliers(X, y, 0.001, places=places) == [12, 13]


def test_only_the_baselines_screens(monkeypatch):
    # beside a cause's columns (here one more column, the design wider than the baseline's) the face's prediction is
    # not formed: the screen's own choice stands (gen_b outlier 1916: a later screen's swap let a wrong bump stand)
    X, y, places = _wall(chips=((12, 3.0), (13, 3.2)))
    Xw = np.hstack([X, np.linspace(-1, 1, len(y))[:, None] * 1e-3])
    monkeypatch.setattr(D, "OUTLIER_CHIPS_LIKELIHOOD", True)
    assert D.find_outliers(X, y, 0.001, places=places) == [12, 13]
    assert D.find_outliers(Xw, y, 0.001, places=places) == D.find_outliers(Xw, y, 0.001)


def test_a_skid_beside_clean_touches_is_still_set_aside(monkeypatch):
    # a skid (-4 um: reads less material) on target 7's first touch: the face agrees with the clean touches, so the
    # skid is set aside with the rule as without it (no sign assumed)
    X, y, places = _wall(skids=((21, -4.0),))
    for on in (False, True):
        monkeypatch.setattr(D, "OUTLIER_CHIPS_LIKELIHOOD", on)
        assert D.find_outliers(X, y, 0.001, places=places) == [21]


def test_no_prediction_without_a_degree_of_freedom(monkeypatch):
    # a face of three targets: without the disputed one, two targets span the wall's basis (offset and tilt)
    # exactly, nothing is left to judge the prediction by: the screen's choice stands
    X, y, places = _wall(n_t=3, chips=((3, 3.0), (4, 3.2)))
    keep = np.ones(len(y), bool)
    assert D._target_z(X, y, keep, places, 1, np.array([3, 4, 5])) is None


@pytest.mark.slow
def test_gen_a_outlier_1505_the_three_chips_set_aside(first_outlier_screen):
    out, o = first_outlier_screen("OUTLIER_CHIPS_LIKELIHOOD", True)
    assert sorted(out) == [73, 90, 237], out
    assert o.cause == "outlier", o
    assert o.wp_ext_um < o.wp_base_um, o


@pytest.mark.slow
def test_gen_a_outlier_1505_clean_touch_set_aside_without_the_rule(first_outlier_screen):
    out, o = first_outlier_screen("OUTLIER_CHIPS_LIKELIHOOD", False)
    assert sorted(out) == [237, 254], out
    assert o.wp_ext_um > o.wp_base_um, o
