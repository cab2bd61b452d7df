"""The discovery study of ``vmt bench`` refuses seeds the blind checks spent or hold (session 36, left36).

``scenarios.bench.discover_study.run(blind_seed0=...)`` ran gen_a, gen_b and gen_c at ``blind_seed0 + s``: with a
value in 7000-7990 it would have read gen_c on seeds the lead holds for a blind check (and gen_a/gen_b on spent
ones). The ranges are one declared table (``BLIND_CHECK_SEEDS``); a range reaching into it is refused in one line
before any campaign runs.
"""

import pytest

from core.exceptions import ConfigError
from scenarios.bench import discover_study as S


@pytest.fixture
def no_campaign(monkeypatch):
    """Any campaign the study would run fails the test: the refusal comes first."""
    import scenarios.hidden as H

    def ran(*a, **k):
        raise AssertionError("a campaign ran")

    for name in ("blind_outcome", "hidden_outcome", "mfb_outcome"):
        monkeypatch.setattr(H, name, ran)


@pytest.mark.parametrize("blind, hidden, said", [
    (7000, 2000, "blind_seed0 7000 (seeds 7000-7009) reaches the seeds the blind checks spent or hold: gen_a 2510-, "
                 "gen_b 2510-, gen_c 5000-7999"),
    (2501, 2000, "blind_seed0 2501 (seeds 2501-2510) reaches"),       # the first spent seed, at the range's end
    (100, 4091, "hidden_seed0 4091 (seeds 4091-4100) reaches the seeds the blind checks spent or hold: "
                "the simulator 4100-"),
    (11400, 8400, "blind_seed0 11400"),
])
def test_a_study_on_blind_seeds_is_refused_in_one_line(no_campaign, blind, hidden, said):
    with pytest.raises(ConfigError) as e:
        S.run(blind_seed0=blind, hidden_seed0=hidden)
    msg = str(e.value)
    assert said in msg and "\n" not in msg and "BLIND_CHECK_SEEDS" in msg
    if hidden >= 4091:
        assert "hidden_seed0" in msg
    with pytest.raises(ConfigError, match=said.split(" (")[0]):
        S.outlier_trade(blind, hidden)


@pytest.mark.parametrize("blind, hidden", [(100, 2000), (400, 2300), (2500, 4090), (0, 0), (1990, 4000)])
def test_tuning_and_bench_seeds_pass(blind, hidden):
    """The bench's defaults, docs/discovery.md's other pair (400/2300), the ranges' last free seeds and the tuning
    seeds: no refusal."""
    S.check_seeds(blind, hidden)


def test_the_table_holds_the_blind_ranges():
    """Known answers from the blind checks' record (docs/discovery-studies.md, "The blind check of session 35":
    set E gen_a/gen_b 10900-11109, gen_c 7000-7109, the simulator 8100-8209; set N gen_a/gen_b 11300-11379, gen_c
    7300-7379, the simulator 8300-8379): each of its seeds is inside the table; the tuning seeds are outside."""
    def inside(g, s):
        lo, hi = S.BLIND_CHECK_SEEDS[g]
        return s >= lo and (hi is None or s <= hi)

    for g, seeds in (("gen_a", (10900, 11109, 11300, 11379)), ("gen_b", (10900, 11379)),
                     ("gen_c", (7000, 7109, 7300, 7379, 7400, 7999)), ("hidden", (8100, 8209, 8300, 8379, 8400))):
        assert all(inside(g, s) for s in seeds), g
    for g, seeds in (("gen_a", (1000, 1999)), ("gen_b", (1000, 1999)), ("gen_c", (0, 999)), ("hidden", (4000, 4099))):
        assert not any(inside(g, s) for s in seeds), g
