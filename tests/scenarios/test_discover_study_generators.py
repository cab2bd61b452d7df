"""``make bench``'s discovery study runs every blind generator the README counts (audit35 F2: gen_c was in
neither the printing test nor the bench). The campaigns are replaced by fixed outcomes here: what is tested is
which generators and seeds the study asks for and that each gets its rates and matrix, not discovery itself
(tests/scenarios/test_discover_hidden.py runs that)."""

import scenarios.bench.discover_study as S
import scenarios.hidden as H


def _fake(generator, effect, seed):
    acc = ("none",) if effect == "none" else (effect,)
    return H.Outcome(generator, effect, seed, acc, acc[0], (acc[0],), True, 2.0, 0.3, 0.3, 0.3, 0.3, 0.1)


def test_the_bench_study_runs_gen_c_at_the_blind_seeds(monkeypatch):
    asked = []

    def blind(mod, effect, seed, generator=None, **kw):
        asked.append((generator, effect, seed))
        return _fake(generator, effect, seed)

    monkeypatch.setattr(H, "blind_outcome", blind)
    monkeypatch.setattr(H, "hidden_outcome", lambda e, s, **kw: _fake("hidden", e, s))
    monkeypatch.setattr(H, "mfb_outcome", lambda e, s, **kw: _fake("mfb", e, s))
    monkeypatch.setattr(S, "SEEDS", 2)
    out = S.run(blind_seed0=100, hidden_seed0=2000)
    from scenarios.blind import gen_c

    got = {(e, s) for g, e, s in asked if g == "gen_c"}
    assert got == {(e, 100 + s) for e in gen_c.effects() for s in range(2)}   # tuning seeds 0-999 at the default
    for g in ("gen_a", "gen_b", "gen_c"):
        assert out[f"discover_{g}_catalogue_rate"] == 1.0 and f"{g}: 2 campaigns per effect" in out[f"discover_{g}_matrix"]


def test_the_bench_study_runs_the_mfb_campaigns_on_both_bars(monkeypatch):
    """Two MFB rows (session 36, mfb36): the realistic bar (``mfb``, bar_cal_error on) and the bar as calibrated
    (``mfb_calibrated``), every hidden MFB effect at the seeds 300-301 each, each row with its rates and a matrix
    titled with its own campaigns per effect (MFB_SEEDS, not the blind generators' SEEDS)."""
    asked = []

    def mfb(effect, seed, bar_cal_error=True, **kw):
        asked.append((effect, seed, bar_cal_error))
        return _fake("mfb", effect, seed)

    monkeypatch.setattr(H, "blind_outcome", lambda mod, e, s, generator=None, **kw: _fake(generator, e, s))
    monkeypatch.setattr(H, "hidden_outcome", lambda e, s, **kw: _fake("hidden", e, s))
    monkeypatch.setattr(H, "mfb_outcome", mfb)
    monkeypatch.setattr(S, "SEEDS", 1)
    out = S.run(blind_seed0=100, hidden_seed0=2000)
    want = {(e, 300 + s, bar) for e in H.MFB_HIDDEN for s in range(S.MFB_SEEDS) for bar in (True, False)}
    assert set(asked) == want and len(asked) == len(want)
    for g in ("mfb", "mfb_calibrated"):
        assert out[f"discover_{g}_catalogue_rate"] == 1.0
        assert f"{g}: {S.MFB_SEEDS} campaigns per effect" in out[f"discover_{g}_matrix"]
