"""REVERSAL_MOVE_EARNS (session 29, lobe29): reversal's move-signed layout (core.causes.REVERSAL_MOVE_SIGNED) is taken
only where its move-signed pair is significant beside the model and the approach-signed pair, under the cause's own
Bonferroni count (docs/discovery-studies.md "Session 29: the move-signed reversal must earn its move").

gen_b probe_lobing 1007 (tuning): gen_b hides no lost motion there. The approach-signed pair is refused beside the
lobes (confounded, inflation 518); unguarded, the four columns come in as its fallback, passing the confounding
check on the move pair's well determined directions (best inflation 2) while their signal is the approach-signed
pair's (7.3 um, worst inflation 1,460) and the move pair fits 0.24 +- 0.23 um: a spurious secondary `reversal`."""
import numpy as np
import pytest

import core.causes as C
import core.discover as D
from scenarios.blind import gen_b
from scenarios.hidden import blind_outcome

SEED = 1007  # gen_b tuning seed: probe_lobing, a secondary reversal without the guard, none with it


@pytest.fixture
def move_signed(monkeypatch):
    monkeypatch.setattr(C, "REVERSAL_MOVE_SIGNED", True)


def test_lobes_gain_no_reversal_with_the_guard(move_signed, monkeypatch):
    monkeypatch.setattr(D, "REVERSAL_MOVE_EARNS", True)
    o = blind_outcome(gen_b, "probe_lobing", SEED, generator="gen_b")
    assert o.cause == "probe_lobing"
    assert "reversal" not in o.findings


def test_without_the_guard_the_lobes_gain_a_reversal(move_signed, monkeypatch):
    monkeypatch.setattr(D, "REVERSAL_MOVE_EARNS", False)
    o = blind_outcome(gen_b, "probe_lobing", SEED, generator="gen_b")
    assert o.cause == "probe_lobing"
    assert "reversal" in o.findings


def _model(n=400, seed=3):
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(n, 3))  # the model's own columns
    Q, _ = np.linalg.qr(B)
    Cm = rng.choice([-0.5, 0.5], size=(n, 4)) * rng.uniform(0.2, 1.0, size=(n, 4))  # four lost-motion-like columns
    return rng, Q, Cm


def _state(Q, y):
    r = y - Q @ (Q.T @ y)
    return D._State(np.arange(len(y)), Q, r, float(r @ r), len(y) - Q.shape[1])


def test_move_pair_p_known_answers():
    """Truth -> noise -> test. A move pair of 5 noise sigmas per column's RMS is found (p < 1e-12); a signal
    of the approach pair alone leaves the move pair's test at its null (this draw's p 0.1-1: the test is exact
    for Gaussian noise, any draw above 0.01 at 99 %, the seed fixed); a move pair in the approach pair's span adds
    no direction (p = 1)."""
    rng, Q, Cm = _model()
    e = rng.normal(size=Q.shape[0])
    y_move = e + Cm[:, 2:] @ (np.array([5.0, -5.0]) / np.sqrt(np.mean(Cm[:, 2:] ** 2, axis=0)))
    assert D._move_pair_p(Cm, _state(Q, y_move)) < 1e-12
    y_appr = e + Cm[:, :2] @ np.array([8.0, 3.0])
    p = D._move_pair_p(Cm, _state(Q, y_appr))
    assert 0.01 < p <= 1.0
    same = np.hstack([Cm[:, :2], Cm[:, :2] @ np.array([[1.0, 2.0], [0.5, -1.0]])])
    assert D._move_pair_p(same, _state(Q, y_appr)) == 1.0


def test_move_pair_p_null_is_uniform():
    """Under the null (noise, the approach pair's signal) the p-value is uniform: over 400 draws the share below
    0.05 is 0.05 within 4 binomial sigmas (0.011)."""
    rng, Q, Cm = _model(n=200, seed=5)
    ps = [D._move_pair_p(Cm, _state(Q, rng.normal(size=200) + Cm[:, :2] @ np.array([2.0, -1.0])))
          for _ in range(400)]
    assert abs(np.mean(np.array(ps) < 0.05) - 0.05) < 4 * np.sqrt(0.05 * 0.95 / 400)


def test_move_pair_p_bad_input():
    rng, Q, Cm = _model()
    st = _state(Q, rng.normal(size=Q.shape[0]))
    with pytest.raises(ValueError, match="four columns"):
        D._move_pair_p(Cm[:, :3], st)
    with pytest.raises(ValueError, match="four columns"):
        D._move_pair_p(Cm[:10], st)


def test_engine_defaults_read_the_wound_lost_motion_and_leave_the_lobes_alone():
    """The defaults (session 29): the move-signed layout on, guarded. gen_c travel_hysteresis 213 (a lost motion
    wound by the traverse) reads reversal confidently; gen_b probe_lobing 1007 reads probe_lobing with no reversal."""
    assert C.REVERSAL_MOVE_SIGNED and D.REVERSAL_MOVE_EARNS
    from scenarios.blind import gen_c
    o = blind_outcome(gen_c, "travel_hysteresis", 213, generator="gen_c")
    assert o.cause == "reversal" and o.confident
    o = blind_outcome(gen_b, "probe_lobing", SEED, generator="gen_b")
    assert o.cause == "probe_lobing" and "reversal" not in o.findings
