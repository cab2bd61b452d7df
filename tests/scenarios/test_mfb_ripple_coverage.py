"""scenarios.mfb_ripple_coverage: one seed through each condition, the scoring by hand, bad input."""

import numpy as np
import pytest

from scenarios import mfb_ripple_coverage as rc


def test_declaring_moves_only_the_u95_and_the_phase_only_the_ripple():
    """Seed 1000: the declared ripple is a type B term (it draws nothing), so 'all' has 'none''s deviations
    to the bit and a U95 no smaller at any node (larger where the ripple reaches: EXX's free nodes); the
    drawn phases change the truth's ripple only (same amplitudes and periods, phases from
    default_rng(seed + 1000000), not 0), and 'off' has no periodic term at all."""
    none, every = rc.one_seed("none", 1000), rc.one_seed("all", 1000)
    for k in none["errors"]:
        assert none["errors"][k]["dev"] == every["errors"][k]["dev"], k
        assert np.all(np.asarray(every["errors"][k]["u95"]) >= np.asarray(none["errors"][k]["u95"]) - 1e-12), k
    free = np.asarray(none["errors"]["EXX"]["u95"]) > 1e-6
    assert np.all(np.asarray(every["errors"]["EXX"]["u95"])[free] > np.asarray(none["errors"]["EXX"]["u95"])[free])
    assert none["scope"] and not every["scope"]  # the run names the ripple it leaves out, and only then

    spec0, decl = rc.machine_and_declared("all", 1000)
    spec1, decl1 = rc.machine_and_declared("drawn", 1000)
    assert decl == decl1 and set(decl) == {"EXX", "EYY", "EZZ", "EBX", "EBZ", "ECY"}
    ph = np.random.default_rng(1_001_000).uniform(0.0, 2.0 * np.pi, 6)
    x = np.linspace(-0.3, 0.5, 7)
    for i, s in enumerate(decl):
        a, p = decl[s]
        d = np.asarray(spec1.config.errors[s](x)) - np.asarray(spec0.config.errors[s](x))
        np.testing.assert_allclose(d, a * (np.sin(2 * np.pi * x / p + ph[i]) - np.sin(2 * np.pi * x / p)),
                                   atol=1e-15)
    off, _ = rc.machine_and_declared("off", 1000)
    assert not rc._ripples(off.config.errors)


def test_score_known_answer():
    """Two seeds: a gauge-fixed node (U95 0) left out, a node exactly at its U95 counted inside."""
    recs = [{"errors": {"EXX": {"dev": [0.0, 1.0, -2.0], "u95": [0.0, 1.0, 1.0]}}},
            {"errors": {"EXX": {"dev": [0.0, 0.5, 0.5], "u95": [0.0, 1.0, 1.0]}, "EYY": {"dev": [3.0], "u95": [1.0]}}}]
    s = rc.score(recs)
    assert (s["EXX"]["within"], s["EXX"]["values"]) == (3, 4)
    assert (s["EYY"]["within"], s["EYY"]["values"]) == (0, 1)
    assert (s["all"]["within"], s["all"]["values"]) == (3, 5) and s["all"]["share"] == 0.6


def test_bad_input(capsys):
    with pytest.raises(ValueError, match="unknown condition 'half'"):
        rc.machine_and_declared("half", 1)
    assert rc.main(["none", "--seeds", "4", "2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--seeds 4 2: no seed" in err
