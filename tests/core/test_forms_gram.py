"""part_change's time forms chosen from Gram matrices on a long log (``core.discover._forms_gram_choice``).

Session 22: on a long log (the model's basis a ``core.lsq.Basis``) whose feature's columns are more than
``FORMS_DENSE_BYTES``, ``_time_forms_chosen`` tests the step per set-up against the continuous form (and against one
step at one set-up change) from sums accumulated a block of ``FORMS_BLOCK_ROWS`` rows at a time, where it formed the
columns, their projections and the basis stacked with the alternative dense (the bench's 1e6-row discover stopped
there under its 2,048 MB limit). These tests force the block design and blocks of a few rows, and compare the two
paths on campaigns where the step form is tried: every branch (continuous kept, the steps beyond one step at one
set-up change or not), the same p-values to rounding and the same choice, and the same report.
"""
import tracemalloc

import numpy as np
import pytest

import core.baseline as Bm
from core import discover as D
from tests.discover_helpers import discovered

_DENSE = D._forms_dense_choice


def _campaign(which, seed):

    if which == "sim":
        from scenarios.hidden import hidden_campaign

        log, _ = hidden_campaign(("part_change",), seed)
    else:
        from scenarios.blind import gen_b

        log, _ = gen_b.generate(which, seed)
    return lambda: discovered(log).to_report()


def _spy(monkeypatch, calls):
    """Every dense choice made (on a block basis) also made from the Gram matrices, in blocks of 7 rows."""
    def both(cs, cc, level, rows, st, settings):
        out = _DENSE(cs, cc, level, rows, st, settings)
        assert isinstance(st.Q, D.Basis)
        monkeypatch.setattr(D, "FORMS_BLOCK_ROWS", 7)
        calls.append((out, D._forms_gram_choice(cs, cc, level, rows, st, settings), (cs, cc, level, rows, st,
                                                                                          settings)))
        return out

    monkeypatch.setattr(D, "_forms_dense_choice", both)


# (campaign, seed, what the dense path chooses for its part_change feature: the steps or not, one-off p reached)
CASES = [("sim", 4077, True, True),  # the wall grown by a step per set-up: steps beyond one step at a change
         ("stylus_pickup", 1012, False, True),  # gen_b: the steps significant, not beyond one step at one change
         ("part_change", 1010, False, False)]  # gen_b: a continuous change keeps the continuous form


@pytest.mark.parametrize("which,seed,steps,once", CASES)
def test_gram_forms_choose_as_the_dense_forms(monkeypatch, which, seed, steps, once):
    monkeypatch.setattr(Bm, "DENSE_DESIGN_BYTES", 0)
    monkeypatch.setattr(D, "FORMS_DENSE_BYTES", 1 << 60)  # the dense path decides
    calls = []
    _spy(monkeypatch, calls)
    _campaign(which, seed)()
    assert calls
    seen = set()
    for (c_d, p_d), (c_g, p_g), _ in calls:
        assert c_d == c_g, (p_d, p_g)
        assert (p_d[2] is None) == (p_g[2] is None)
        for a, b in zip(p_d, p_g):
            if a is not None:  # equal to rounding: the p-values' logarithms to 1e-9 relative
                assert abs(np.log(max(a, 1e-300)) - np.log(max(b, 1e-300))) <= 1e-9 * max(1.0, abs(np.log(max(a, 1e-300)))), (p_d, p_g)
        seen.add((c_d, p_d[2] is not None))
    assert (steps, once) in seen, seen


def test_gram_forms_report_the_dense_forms_report(monkeypatch):
    """sim part_change 4077 through the block design: the report with the forms from Gram matrices in blocks of 7
    rows is the dense forms' (every decision and text; the numbers to rounding)."""
    monkeypatch.setattr(Bm, "DENSE_DESIGN_BYTES", 0)
    run = _campaign("sim", 4077)
    monkeypatch.setattr(D, "FORMS_DENSE_BYTES", 1 << 60)
    dense = run()
    monkeypatch.setattr(D, "FORMS_DENSE_BYTES", 0)
    monkeypatch.setattr(D, "FORMS_BLOCK_ROWS", 7)
    gram = run()
    assert dense["cause"] == gram["cause"] == "part_change"
    assert [(f["cause"], f["params"].get("time_form"), f["evidence"].get("confidence")) for f in dense["findings"]] \
        == [(f["cause"], f["params"].get("time_form"), f["evidence"].get("confidence")) for f in gram["findings"]]
    _close(dense, gram)


def _close(a, b, path="report"):
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            _close(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _close(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-7, abs=1e-300), path
    else:
        assert a == b, path


def _long_state(n=24_000, g=600, k=6, seed=3):
    """A long log's model state (a block basis: ``g`` targets' indicators and three smooth columns) and a feature's
    columns in both time forms: its pattern times each of six set-ups' levels (a part changing at every set-up, as
    the simulator's grown wall) and times the time; the residuals carry the steps."""
    rng = np.random.default_rng(seed)
    ids = rng.integers(0, g, n)
    counts = np.bincount(ids, minlength=g).astype(float)
    x = rng.uniform(-1, 1, n)
    F = np.column_stack([x, x ** 2, np.sin(3 * x)])
    F -= (np.stack([np.bincount(ids, F[:, j], g) for j in range(3)], 1) / counts[:, None])[ids]
    U = np.linalg.qr(F)[0]
    Q = D.Basis(ids, counts, U)
    t = np.arange(n) / n
    setup = np.minimum((t * 6).astype(int), 5)
    level = np.array([0.0, 0.15, 0.45, 0.55, 0.8, 1.0])[setup]
    pat = np.column_stack([np.cos((j + 1) * np.pi * x + j) for j in range(k)])
    cs, cc = pat * level[:, None], pat * t[:, None]
    y = rng.normal(0, 1e-6, n) + cs @ rng.normal(0, 2e-7, k)
    r = y - Q @ (Q.T @ y)
    rows = np.arange(n)
    st = D._State(rows, Q, r, float(r @ r), n - Q.shape[1])
    return cs, cc, level, rows, st, D.Settings()


def test_gram_forms_in_bounded_memory(monkeypatch):
    """On a long log's state (24,000 rows, a feature of 6 columns whose steps are chosen beyond one step at one set-up
    change, every test made) the block path chooses as the dense path, the same p-values to rounding, and its peak
    (traced) stays under one rows x columns array with blocks of 512 rows, where the dense path forms several (the
    columns, their projections, the basis stacked with the alternative's, the one-off trials)."""
    args = _long_state()
    monkeypatch.setattr(D, "FORMS_BLOCK_ROWS", 512)
    peaks, outs = {}, {}
    for name, f in (("dense", _DENSE), ("blocks", D._forms_gram_choice)):
        tracemalloc.start()
        outs[name] = f(*args)
        peaks[name] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    (c_d, p_d), (c_b, p_b) = outs["dense"], outs["blocks"]
    assert c_d and c_b and p_d[2] is not None and p_b[2] is not None, (p_d, p_b)
    assert np.allclose(np.log(p_d), np.log(p_b), rtol=1e-9, atol=0), (p_d, p_b)
    one = 8 * args[0].size  # bytes of one rows x columns array
    assert peaks["dense"] > 4 * one, peaks
    assert peaks["blocks"] < one, peaks
    # the path is taken on a block basis where a form's columns exceed FORMS_DENSE_BYTES, not on an array basis
    cs, cc, _, rows, st, _ = args
    monkeypatch.setattr(D, "FORMS_DENSE_BYTES", one - 1)
    assert D._forms_by_gram(st, rows, cs, cc)
    monkeypatch.setattr(D, "FORMS_DENSE_BYTES", one)
    assert not D._forms_by_gram(st, rows, cs, cc)
    monkeypatch.setattr(D, "FORMS_DENSE_BYTES", 0)
    assert not D._forms_by_gram(D._State(rows, st.Q.toarray()[:, :5], st.r, st.rss, st.dof), rows, cs, cc)
