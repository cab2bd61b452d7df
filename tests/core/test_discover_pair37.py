"""Session 37 (pair37): a pair of causes each refused beside the other (sel36's third gap).

The rival check drops a cause A beside a cause B adopted after it; B, judged again without A, is refused (often for
its plainer counter A). A's drop referred to a model that no longer stands, and A was kept out of every reopened
round: neither stood. :data:`core.discover.PAIR_REFUSED_DECIDED` (built, off) judges A once more in the model that
stands (beside the causes that stay, where B was just refused: the search's tests, then the rival check with A and
without B). A that passes is restored and stands against B (B kept out of every round after); A is restored once per
run. A that fails stays dropped, said in ``rejected``.

Tuning campaigns (gen_a): lobing_per_setup 1153 (probe_lobing restored, named hedged with lobing_per_setup as the
alternative), knock 1002 and probe_heating 1000 (out of the catalogue, read ``unexplained``: A judged again, fails
the rival check without B, stays dropped; the reading unchanged). docs/discovery-studies.md, "Session 37: a pair of causes
each refused beside the other".
"""

from __future__ import annotations

import json

import pytest

import core.discover as D
from scenarios.blind import gen_a
from tests.discover_helpers import discovered

PAIRED = "(adopted after it) was refused without it"  # the words of the rule's refusal in ``rejected``


def _report(log, monkeypatch, on: bool) -> dict:
    monkeypatch.setattr(D, "PAIR_REFUSED_DECIDED", on)
    return discovered(log).to_report()


@pytest.fixture(scope="module")
def log_1153():
    return gen_a.generate("lobing_per_setup", 1153)[0]


def test_off_by_default():
    """The rule is built and off: the lead's blind check of session 37 reads the engine without it."""
    assert D.PAIR_REFUSED_DECIDED is False


def test_1153_probe_lobing_restored_over_lobing_per_setup(log_1153, monkeypatch):
    """gen_a lobing_per_setup 1153 (tuning; true lobes k = 3 turned by 0.17-0.70 rad over 5 set-ups, a common share
    of 0.68 in the truth's own signal where uniform turns give 0.2): probe_lobing wins round 1, lobing_per_setup
    round 2 beside it, the rival check drops probe_lobing (0.57 of a smooth in approach_azimuth, beside the cause
    that nests its columns), lobing_per_setup judged again without it is refused for its plainer counter (common
    lobing, 85 % of its signal, p = 0.008 under random turns). Off: ``unexplained``, probe_lobing's drop "not judged
    again". On: probe_lobing, judged again beside no cause, passes every test and the rival check; it is named,
    hedged (ambiguous with lobing_per_setup, the richer cause significant beyond it), and lobing_per_setup is not
    adopted again. The truth is lobing_per_setup: the reading is not the acceptable name but the nested one, hedged
    with it (the engine's own policy where the fixed lobes explain a share random turns rarely leave: session 28)."""
    off = _report(log_1153, monkeypatch, False)
    assert off["cause"] == "unexplained"
    pl_off = [r for r in off["rejected"] if r["cause"] == "probe_lobing"]
    assert len(pl_off) == 1 and pl_off[0]["reason"].startswith("explains only part of the structure in "
                                                               "approach_azimuth (share 0.57")
    assert pl_off[0]["judged_again_later"] is False

    on = _report(log_1153, monkeypatch, True)
    assert on["cause"] == "probe_lobing"
    f = on["findings"][0]
    assert f["cause"] == "probe_lobing" and f["evidence"]["confidence"] == "ambiguous"
    assert f["evidence"]["pair_restored_over"] == ["lobing_per_setup"]
    assert "lobing_per_setup" in f["evidence"].get("ambiguous_with", [])
    assert f["evidence"]["rival_share"] >= 0.8  # (the rival check passed in the model without lobing_per_setup)
    assert not any(g["cause"] == "lobing_per_setup" for g in on["findings"])
    # the drop beside lobing_per_setup is still listed, and now says probe_lobing was judged again without it
    pl_on = [r for r in on["rejected"] if r["cause"] == "probe_lobing"]
    assert len(pl_on) == 1 and pl_on[0]["judged_again_later"] is True
    assert pl_on[0]["made_beside_dropped"] == ["lobing_per_setup"]
    # lobing_per_setup is not judged in any round after the restoration (kept out: the loop); its refusals are the
    # two the off run has before the drop and at its judgement again (the off run's third, in the reopened round,
    # is gone)
    lps = lambda rep: [r["reason"].split("; made beside")[0] for r in rep["rejected"]
                       if r["cause"] == "lobing_per_setup"]
    assert len(lps(off)) == 3 and lps(on) == lps(off)[:2]
    json.dumps(on)  # (plain JSON)


def test_1153_restored_once_loop_guard(log_1153, monkeypatch):
    """The loop guard: a restored cause dropped again by the rival check stays dropped (it is restored once per
    run), and the cause it was restored over stays out. Forced: the rival check drops probe_lobing whenever it
    carries ``pair_restored_over`` (after its restoration); the run ends, probe_lobing is dropped twice and named
    nowhere, lobing_per_setup is not adopted again. (Two guards stop the loop on 1153: lobing_per_setup kept out of
    the rounds after the restoration, and the restoration once per cause. Checked on scratch edits, session 37:
    either alone ends the run, 1153 then reading ``unexplained`` with the keep-out removed; with both removed the
    run does not end, probe_lobing and lobing_per_setup each dropping the other. This forced case ends with either.)"""
    real = D._rival_share

    def forced(bl, tm, *a, **k):
        share = real(bl, tm, *a, **k)
        if "pair_restored_over" in tm.evidence:
            share = {**share, "kept": False}
        return share

    monkeypatch.setattr(D, "_rival_share", forced)
    on = _report(log_1153, monkeypatch, True)
    names = [f["cause"] for f in on["findings"]]
    assert "probe_lobing" not in names and "lobing_per_setup" not in names
    drops = [r for r in on["rejected"] if r["cause"] == "probe_lobing"
             and r["reason"].startswith("explains only part of the structure in approach_azimuth")]
    assert len(drops) == 2
    assert not any(PAIRED in r["reason"] for r in on["rejected"])  # (never judged a second time)


@pytest.mark.parametrize("effect, seed, a, b, share", [
    ("knock", 1002, "c_drift", "part_change", "0.53"),
    ("probe_heating", 1000, "thermal_drift", "part_change", "0.43"),
])
def test_out_of_catalogue_pair_judged_again_stays_dropped(effect, seed, a, b, share, monkeypatch):
    """gen_a knock 1002 and probe_heating 1000 (out of the catalogue; ``unexplained`` is the acceptable reading):
    A (c_drift, thermal_drift) dropped beside B (part_change), B refused without A. On, A is judged again in the
    model without B and fails the rival check there too (a smaller share of its covariate's smooth than beside B):
    it stays dropped, the refusal says so, and the report is otherwise the off run's (its cause, findings, workpiece
    and every other refusal)."""
    log = gen_a.generate(effect, seed)[0]
    off = _report(log, monkeypatch, False)
    on = _report(log, monkeypatch, True)
    assert off["cause"] == on["cause"] == "unexplained"
    again = [r for r in on["rejected"] if PAIRED in r["reason"]]
    assert len(again) == 1 and again[0]["cause"] == a
    assert again[0]["reason"].startswith(f"judged again once {b} (adopted after it) was refused without it: explains "
                                         f"only part of the structure in ")
    assert f"(share {share} of a smooth term's)" in again[0]["reason"]
    assert not any(PAIRED in r["reason"] for r in off["rejected"])
    # nothing else moved: the report without ``rejected`` byte-identical, ``rejected`` the off run's plus the one
    # entry (and A's drop now judged again later)
    strip = lambda rs: [{k: v for k, v in r.items() if k != "judged_again_later"} | {
        "reason": r["reason"].split("; made beside")[0]} for r in rs]
    rej_on, rej_off = on.pop("rejected"), off.pop("rejected")
    assert json.dumps(on, sort_keys=True, default=str) == json.dumps(off, sort_keys=True, default=str)
    assert strip([r for r in rej_on if r is not again[0]]) == strip(rej_off)
