"""REVERSAL_MOVE_SIGNED (R2b, session 28 r2b28): reversal's second layout, each axis' lost motion signed both by the
approach and by the net move from the previous touch (docs/discovery-studies.md "Session 28: the blind check's two gen_c
faults, diagnosed").

gen_c travel_hysteresis 213 (tuning): a lost motion wound up over the distance travelled (Dahl's law, windup of a
few mm), so the traverse between features, not only the probing stroke, sets its sign at a touch. Approach-signed
only, the engine reads it as lobing_per_setup (hedged, a wrong name); with the move-signed layout it reads reversal,
confidently (diag28's list of the 59 campaigns of 200-599 R2b mends)."""
import numpy as np
import pytest

import core.causes as C
from core.baseline import extra_columns, planar
from core.touches import from_log
from scenarios.blind import gen_c
from scenarios.hidden import blind_outcome

SEED = 213  # gen_c tuning seed (0-999), travel_hysteresis: wrong without the rule, reversal (confident) with it


@pytest.fixture
def move_signed(monkeypatch):
    monkeypatch.setattr(C, "REVERSAL_MOVE_SIGNED", True)


@pytest.fixture
def approach_only(monkeypatch):
    monkeypatch.setattr(C, "REVERSAL_MOVE_SIGNED", False)


def test_wound_lost_motion_reads_reversal(move_signed):
    o = blind_outcome(gen_c, "travel_hysteresis", SEED, generator="gen_c")
    assert o.cause == "reversal" and o.confident
    assert o.cause in o.acceptable


def test_without_the_rule_it_is_misnamed(approach_only):
    o = blind_outcome(gen_c, "travel_hysteresis", SEED, generator="gen_c")
    assert o.cause not in o.acceptable


def _baseline(effect, seed):
    log, tr = gen_c.generate(effect, seed, noise=False)
    t = from_log(log)
    return planar(t, 80.0, select_grid=False, extra=extra_columns(log, t.row)), tr


def test_move_signed_layout_columns_and_magnitudes_round_trip(move_signed):
    """Known answer: a residual made of the four columns with chosen lost motions is fitted back exactly, and the
    magnitudes name all four (um, ISO 230-2's sign). Tolerance 1e-9 um: a least-squares solve of an exact system."""
    bl, _ = _baseline("none", 200)
    scans, bonf = C.reversal_scans(bl)
    assert bonf == 2.0 and len(scans) == 2
    sc = scans[1]
    assert sc.infos[0]["signed_by"] == "approach+move"
    E = np.asarray(sc.build(np.array([0]))[0], float)
    assert E.shape == (bl.data.nx.shape[0], 4)
    truth_um = np.array([3.0, -2.0, 4.5, -1.5])
    y = E @ (truth_um * C.UM)
    coef, *_ = np.linalg.lstsq(E, y, rcond=None)
    mag = C.reversal_magnitudes(sc.infos[0], coef, bl)
    got = [mag[k] for k in ("x_lost_motion_um", "y_lost_motion_um", "x_move_lost_motion_um", "y_move_lost_motion_um")]
    assert np.allclose(got, truth_um, atol=1e-9)


def test_approach_only_layout_reports_two_magnitudes(approach_only):
    bl, _ = _baseline("none", 200)
    scans, bonf = C.reversal_scans(bl)
    assert bonf == 1.0 and len(scans) == 1
    mag = C.reversal_magnitudes(scans[0].infos[0], np.array([1.0, 2.0]) * C.UM, bl)
    assert set(mag) == {"x_lost_motion_um", "y_lost_motion_um"}


def test_move_signs_first_touch_zero():
    class T:
        pn_R = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, -2.0, 0.0], [0.5, -2.0, 0.0]])

    class Dd:
        touches = T()
    s = C._move_signs(Dd())
    assert np.array_equal(s, [[0, 0], [1, 0], [0, -1], [-1, 0]])
