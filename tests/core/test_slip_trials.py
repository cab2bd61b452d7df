"""The fixture slip's trials kept as their splits (core.diagnosis.StepTrials) and tested a block at a time.

``core.causes.fixture_slip`` formed every split's trial at once, a dense (T, n, 3) array (0.96 GB on a 1e4-row
log of 100 set-ups); it now returns the splits, and its consumers (the rival check's counter scan, the outlier
screen's ``setup_slip``) build the trials they test a block at a time. These tests hold the blocked trials and
every number computed from them to the dense ones bit for bit, with blocks small enough to be several on a
small campaign (the byte budgets lowered, the same in both runs compared).
"""

import dataclasses

import numpy as np
import pytest

import discover_synth as S
from core import baseline as B
from core import causes as C
from core import diagnosis as G
from core.discover import discover
from core.lsq import _dense


def _dense_slips(bl):
    """The trials as fixture_slip formed them before (its code, verbatim): the reference."""
    d = bl.data
    t = d.touches
    M = np.column_stack([d.nx, d.ny, d.rot_m / max(d.L_m, 1e-9)])
    masks = []
    for j in np.unique(t.setup):
        idx = np.flatnonzero(t.setup == j)
        idx = idx[np.argsort(t.t_s[idx], kind="stable")]
        if idx.size < 3:
            continue
        splits = np.arange(1, idx.size)
        if splits.size > C.SLIP_SPLITS:
            splits = np.unique(np.round(np.linspace(1, idx.size - 1, C.SLIP_SPLITS)).astype(int))
        m = np.zeros((splits.size, t.n))
        after = np.arange(idx.size)[None, :] >= splits[:, None]
        m[:, idx] = after
        masks.append(m)
    return M[None, :, :] * np.concatenate(masks)[:, :, None]


def _same_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a.view(np.uint8), b.view(np.uint8))


@pytest.fixture(scope="module")
def slip_case():
    """A synthetic campaign with several set-ups: its planar baseline, the slip's trials dense and kept."""
    t, _ = S.campaign("none", 11)
    bl = B.planar(t)
    return bl, _dense_slips(bl), C.fixture_slip(bl)


@pytest.fixture
def small_blocks(monkeypatch):
    """Byte budgets low enough for several blocks and column groups on the small campaign (both runs compared)."""
    monkeypatch.setattr(G, "PROJECT_BLOCK_BYTES", 16 << 10)
    monkeypatch.setattr(G, "OUTSIDE_BASE_BIG_BYTES", 64 << 10)
    monkeypatch.setattr(G, "TRIAL_BLOCK_BYTES", 128 << 10)


def test_step_trials_are_the_dense_trials_element_for_element(slip_case):
    bl, dense, st = slip_case
    assert len(np.unique(bl.data.touches.setup)) >= 3
    assert st.shape == dense.shape and dense.shape[0] > 40
    assert _same_bits(st.dense(), dense)  # (the masked negative entries' -0.0 included)
    rng = np.random.default_rng(0)
    ts = rng.choice(dense.shape[0], 25, replace=False)
    rows = np.sort(rng.choice(dense.shape[1], dense.shape[1] - 7, replace=False))
    assert _same_bits(st.take(ts), dense[ts])
    assert _same_bits(st.take(ts, rows), G.take_rows(dense[ts], rows, 1))
    assert st.take(ts).flags.c_contiguous and st.take(ts, rows).strides == G.take_rows(dense[ts], rows, 1).strides


def test_moved_event_selects_the_trials_the_dense_rows_did(slip_case):
    bl, dense, st = slip_case
    on = np.any(dense != 0, axis=2)
    n = bl.groups.size
    halves = (np.arange(n) % 2).astype(int)  # across set-ups: only a trial moving one touch stays in one
    found = 0
    for events in (bl.groups, np.where(np.arange(n) % 17 == 0, -1, bl.groups), halves):
        moved = st.moved_event(events)
        for e in np.unique(events[events >= 0]):
            ref = np.flatnonzero(np.all(~on[:, events != e], axis=1) & np.any(on[:, events == e], axis=1))
            assert np.array_equal(np.flatnonzero(moved == e), ref), e
            found += ref.size
        assert np.all((moved == G.STEP_MIXED) | (moved >= 0) | (moved == -1))
    assert found > dense.shape[0]


@pytest.mark.parametrize("rows_kept", ["all", "some"])
def test_blocked_f_tests_are_the_one_batch_bit_for_bit(slip_case, small_blocks, rows_kept):
    """nested_f_trials over blocks against nested_f_batch of the dense trials: ss, k, F, p the same bits, against
    a model basis declared to extend the baseline's (as the engine's states are) and against none."""
    bl, dense, st = slip_case
    n = dense.shape[1]
    rows = np.arange(n) if rows_kept == "all" else np.setdiff1d(np.arange(n), [3, 50, 51, 200])
    A = _dense(bl.A)[rows]
    y = bl.y[rows]
    Qb = G.orth(A)
    rng = np.random.default_rng(1)
    U = G.new_basis(Qb, rng.normal(size=(rows.size, 2)))
    Q = G.extends(np.hstack([Qb, U]), Qb)
    try:
        for Qm in (Q, Qb, np.zeros((rows.size, 0))):
            r = y - Qm @ (Qm.T @ y)
            dof = rows.size - Qm.shape[1]
            blocks = G.trial_blocks(dense.shape[0], rows.size, 3, Qm)
            assert len(blocks) >= 3, blocks  # several blocks: the test can tell
            ref = G.nested_f_batch(G.take_rows(dense, rows, 1), Qm, r, float(r @ r), dof)
            got = G.nested_f_trials(st, rows, Qm, r, float(r @ r), dof)
            for a, b in zip(ref, got):
                assert _same_bits(a, b)
            sub = np.arange(5, dense.shape[0], 2)  # some trials (the outlier screen's: one event's)
            assert len(G.trial_blocks(sub.size, rows.size, 3, Qm)) >= 2
            ref = G.nested_f_batch(G.take_rows(dense[sub], rows, 1), Qm, r, float(r @ r), dof)
            got = G.nested_f_trials(st, rows, Qm, r, float(r @ r), dof, ts=sub)
            for a, b in zip(ref, got):
                assert _same_bits(a, b)
    finally:
        G.release_projections()


def test_the_engine_decides_the_same_with_blocks_of_trials(small_blocks, monkeypatch):
    """A c_drift mimicked by a one-off turn (test_a_fixture_slip_is_not_named_a_c_axis_creep's campaign): the rival
    check's counter scan meets the slip, blocked (several blocks) and in one batch; the reports are the same."""
    t, _ = S.campaign("none", 11)
    idx = np.flatnonzero(t.setup == np.unique(t.setup)[1])
    after = idx[np.argsort(t.t_s[idx])][int(0.6 * idx.size):]
    dq = t.dq_m.copy()
    p, nn = t.pn_R[after], t.n_R[after]
    dq[after] += (-nn[:, 0] * p[:, 1] + nn[:, 1] * p[:, 0]) * 40e-6
    tt = dataclasses.replace(t, p_R=t.pn_R + dq[:, None] * t.n_R)
    calls = []
    real = G.trial_blocks

    def spy(*a):
        calls.append(len(real(*a)))
        return real(*a)

    monkeypatch.setattr(G, "trial_blocks", spy)
    blocked = discover(tt).to_report()
    assert calls and max(calls) >= 3, calls
    monkeypatch.setattr(G, "TRIAL_BLOCK_BYTES", 1 << 40)
    calls.clear()
    one = discover(tt).to_report()
    assert calls and max(calls) == 1, calls
    assert blocked == one
    assert any(r["cause"] == "c_drift" and "fixture slip" in r["reason"] for r in blocked["rejected"])
