"""PART_CHANGE_ONE_TARGET (R1 of session 28's diagnosis, built in session 29, lobe29): a part_change finding whose
signal one target carries PART_CHANGE_ONE_TARGET_SHARE (0.8) or more of is named at most ambiguous
(docs/discovery-studies.md "Session 29: the move-signed reversal must earn its move").

gen_c travel_hysteresis 5409 (session 28's blind seed, spent and opened for this work): a lost motion wound by the
traverse between features changes bore2's first touch after it, in time order by the feature order; approach-signed
reversal only, the engine reads `part_change` confidently, one target carrying 0.91 of it."""
from types import SimpleNamespace

import numpy as np
import pytest

import core.causes as C
import core.discover as D
from scenarios.blind import gen_c
from scenarios.hidden import blind_outcome

SEED = 5409


@pytest.fixture
def approach_only(monkeypatch):
    monkeypatch.setattr(C, "REVERSAL_MOVE_SIGNED", False)


def test_one_target_change_is_hedged(approach_only, monkeypatch):
    monkeypatch.setattr(D, "PART_CHANGE_ONE_TARGET", True)
    o = blind_outcome(gen_c, "travel_hysteresis", SEED, generator="gen_c")
    assert o.cause == "part_change" and not o.confident


def test_without_the_rule_it_is_named_confidently(approach_only, monkeypatch):
    monkeypatch.setattr(D, "PART_CHANGE_ONE_TARGET", False)
    o = blind_outcome(gen_c, "travel_hysteresis", SEED, generator="gen_c")
    assert o.cause == "part_change" and o.confident


def _case(coef, n_per=50, seed=2):
    """Two walls (columns), the first on targets a and b, the second on target c; the model a constant."""
    rng = np.random.default_rng(seed)
    tg = np.array(["a"] * n_per + ["b"] * n_per + ["c"] * n_per, dtype=object)
    E = np.zeros((3 * n_per, 2))
    E[:2 * n_per, 0] = rng.uniform(0.5, 1.5, 2 * n_per)
    E[2 * n_per:, 1] = rng.uniform(0.5, 1.5, n_per)
    Q = np.ones((3 * n_per, 1)) / np.sqrt(3 * n_per)
    y = E @ np.asarray(coef, float)
    r = y - Q @ (Q.T @ y)
    st = D._State(np.arange(3 * n_per), Q, r, float(r @ r), 3 * n_per - 1)
    bl = SimpleNamespace(data=SimpleNamespace(touches=SimpleNamespace(target=tg)))
    return bl, SimpleNamespace(columns=E), st, E, tg


def test_one_target_share_known_answer():
    """Known answer (no noise): the fitted coefficients are the truth, so each target's share is its sum of
    (column x coefficient)^2 over the total; to 1e-12 (a least-squares solve of an exact system)."""
    bl, tm, st, E, tg = _case([1.0, 3.0])
    s2 = (E @ np.array([1.0, 3.0])) ** 2
    want = max(s2[tg == t].sum() for t in ("a", "b", "c")) / s2.sum()
    assert D._one_target_share(bl, tm, st, st.rows) == pytest.approx(want, abs=1e-12)
    assert want > 0.8  # the third target carries it (the check below means something)
    bl, tm, st, E, tg = _case([1.0, 0.0])  # the first wall alone: split between a and b
    assert D._one_target_share(bl, tm, st, st.rows) == pytest.approx(
        max((E[tg == t, 0] ** 2).sum() for t in ("a", "b")) / (E[:, 0] ** 2).sum(), abs=1e-12)


def test_one_target_share_of_nothing_is_none():
    bl, tm, st, *_ = _case([0.0, 0.0])
    assert D._one_target_share(bl, tm, st, st.rows) is None
