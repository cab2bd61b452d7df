"""Session 30 (form30): :func:`core.discover._two_lobe_signature`, the signature of a two-lobe probe in reversal's
move-signed layout (:data:`core.discover.REVERSAL_TWO_LOBE_YIELDS`, on since session 30). Known answers on a synthetic design (lost
motions put in, noise 1e-3 of them: the fitted ratios within 0.02 of the true ones, so the thresholds' sides are
read without doubt), the thresholds' edges, and bad input."""

from __future__ import annotations

import numpy as np
import pytest

import core.discover as D


def _design(beta, n=400, seed=0, noise=1e-3):
    rng = np.random.default_rng(seed)
    phi = rng.uniform(0, 2 * np.pi, n)
    nx, ny = np.cos(phi), np.sin(phi)
    sa = -np.sign(np.column_stack([nx, ny]))  # approach along the normal (d_R against n)
    sm = rng.choice([-1.0, 1.0], (n, 2))  # net move of each axis from the previous touch
    C = np.column_stack([-nx * sa[:, 0] / 2, -ny * sa[:, 1] / 2, -nx * sm[:, 0] / 2, -ny * sm[:, 1] / 2])
    B = np.column_stack([np.ones(n), nx, ny])  # a model: offset and a shift of the centre
    Q = np.linalg.qr(B)[0]
    y = C @ np.asarray(beta, float) + B @ np.array([0.3, -0.2, 0.1]) + noise * rng.standard_normal(n)
    r = y - Q @ (Q.T @ y)
    st = D._State(rows=np.arange(n), Q=Q, r=r, rss=float(r @ r), dof=n - 3)
    return C, st


def test_two_lobe_signature_known_answers():
    # equal and opposite approach lost motions, a small move pair: the two-lobe probe's signature
    C, st = _design([1.0, -0.8, 0.1, 0.05])
    bal, share = D._two_lobe_signature(C, st)
    assert bal == pytest.approx(0.8, abs=0.02) and share == pytest.approx(np.hypot(0.1, 0.05) / np.hypot(1, 0.8),
                                                                          abs=0.02)
    # same signs (harmonics 0, 4, 8: not two lobes)
    assert D._two_lobe_signature(*_design([1.0, 0.8, 0.1, 0.05])) is None
    # opposite but one axis dominant (the simulator's lost motions: the smaller at most 0.30 of the larger)
    assert D._two_lobe_signature(*_design([1.0, -0.3, 0.0, 0.0])) is None
    # opposite and balanced, but the move pair carries a lost motion of its own (gen_c's wound lost motion)
    assert D._two_lobe_signature(*_design([1.0, -0.9, 0.6, -0.4])) is None


def test_two_lobe_signature_thresholds(monkeypatch):
    C, st = _design([1.0, -0.8, 0.1, 0.05])
    monkeypatch.setattr(D, "TWO_LOBE_BALANCE", 0.9)
    assert D._two_lobe_signature(C, st) is None
    monkeypatch.setattr(D, "TWO_LOBE_BALANCE", 0.5)
    monkeypatch.setattr(D, "TWO_LOBE_MOVE_SHARE", 0.05)
    assert D._two_lobe_signature(C, st) is None


def test_two_lobe_signature_bad_input():
    C, st = _design([1.0, -0.8, 0.1, 0.05])
    with pytest.raises(ValueError, match="four columns"):
        D._two_lobe_signature(C[:, :2], st)
    with pytest.raises(ValueError, match="four columns"):
        D._two_lobe_signature(C[:-1], st)
    C2 = C.copy(); C2[0, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        D._two_lobe_signature(C2, st)


def test_rule_on_by_default():
    """On since session 30 (docs/discovery-studies.md, "Session 30: the move-signed reversal on two-lobe probes")."""
    assert D.REVERSAL_TWO_LOBE_YIELDS is True and D.TWO_LOBE_BALANCE == 0.5 and D.TWO_LOBE_MOVE_SHARE == 0.3


def test_simulator_4003_by_default():
    """The engine's defaults (nothing set): the simulator's probe_lobing 4003 reads ``probe_lobing?``."""
    from scenarios.hidden import hidden_outcome

    o = hidden_outcome("probe_lobing", 4003)
    assert (o.cause, o.confident) == ("probe_lobing", False)


def test_simulator_two_lobe_probe_4003_reads_probe_lobing_with_the_rule(monkeypatch):
    """The simulator's probe_lobing 4003 (0.99 sigma, a two-lobe probe): without the rule the move-signed reversal
    reads its lobes as lost motions of opposite signs (x +1.43, y -0.96 um, the move pair 0.13 of them) and the report
    is ``reversal?``; with it the four columns give way, the approach-signed layout alone loses to the lobes, and the
    report is ``probe_lobing?`` (``reversal`` its alternative), the workpiece check held (session 30, form30)."""
    from scenarios.hidden import hidden_outcome

    monkeypatch.setattr(D, "REVERSAL_TWO_LOBE_YIELDS", False)
    off = hidden_outcome("probe_lobing", 4003)
    assert (off.cause, off.confident) == ("reversal", False) and "probe_lobing" in off.alternatives
    monkeypatch.setattr(D, "REVERSAL_TWO_LOBE_YIELDS", True)
    on = hidden_outcome("probe_lobing", 4003)
    assert (on.cause, on.confident) == ("probe_lobing", False) and "reversal" in on.alternatives
    assert on.wp_ext_um <= on.wp_base_um + on.wp_u95_um
