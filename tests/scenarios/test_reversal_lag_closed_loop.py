"""A lag and a lead of known size through the exact simulator, read back with ISO 230-2's sign (session 21, issue 13).

``sim.errorfuncs.Reversal(size, sense="lag")`` is backlash, the axis stopping short of its reading by ``size/2``
against its motion; ``sense="lead"`` (the default) is the mirror. ISO 230-2's signed reversal value
``B_i = x_up - x_down`` is ``-size`` for the lag and ``+size`` for the lead (docs/discovery.md, "Session 20: the sign
of the reported lost motion"; the hand-built known answers without sim/ are tests/core/test_reversal_sign.py). Here
the same truths go through the simulator: discover's ``x_lost_motion_um`` / ``y_lost_motion_um`` on a cross-pocket
campaign (``scenarios.hidden``: ``reversal`` a lead, ``reversal_lag`` the same draw as a lag) and
``core.positioning.iso230_2`` on a simulated ISO 230-2 run (``scenarios.positioning.simulate_test``).
"""

import numpy as np
import pytest

from core.positioning import iso230_2
from scenarios.positioning import simulate_test
from tests.discover_helpers import discovered

SIZE_UM = 6.0


@pytest.mark.parametrize("sense, sign", [("lead", 1.0), ("lag", -1.0)])
def test_iso_230_2_of_a_simulated_positioning_run_reads_the_sense(sense, sign):
    """No machine errors, no scatter: at every target ``B_i`` is exactly ``sign * size`` (2.12), ``B`` the size."""
    log = simulate_test("vmc-3axis", "X", np.random.default_rng(0), errors="none", noise_um=0.0,
                        reversal_um=SIZE_UM, reversal_sense=sense)
    res = iso230_2(log)
    assert np.allclose(np.asarray(res.B_i) * 1e3, sign * SIZE_UM, atol=1e-9)
    assert res.B_mean * 1e3 == pytest.approx(sign * SIZE_UM, abs=1e-9)
    assert res.B * 1e3 == pytest.approx(SIZE_UM, abs=1e-9)  # 2.13: max |B_i|, unsigned
    assert log.meta.get("added_reversal_sense", "lead") == sense


def test_a_lead_positioning_log_is_as_before_the_sense():
    """The default sense writes the log it wrote before (no new meta key, the same readings): the readings are
    those the code before the sense existed wrote (424011c, the same call; stored here, in mm, as that code
    printed them), and the explicit lead writes the same. Session 27: the machine's errors at the axis
    positions reading + J (the vmc's probe 150 mm on Z: its Z errors at the measuring line 150 mm higher)
    moved the readings by ~3.2 um each (sum -260.0334 -> -260.3882 mm over 110); the new values are the
    code at 63c4d4f (the lead's log as 424011c's, checked then) with every linear-axis error function f
    replaced by a wrapper x -> f(x + J) (cross-axis terms' other axes shifted alike; the joint27 report):
    the same floats to the last digit as this code's. Session 28: the realistic tables are laid over the
    axis positions the strokes allow (stroke + J, sim.machines.realistic_errors), so at the reference
    stylus every smooth profile's value at q = reading + J is its value at the reading before session 27,
    and the 10 mm ripple's phase is the same (J_Z = 150 mm is 15 whole periods, J_X = J_Y = 0): the
    readings are again those of 424011c's code, the literals before session 27 to the last digit (sum
    -260.0334 mm)."""
    a = simulate_test("vmc-3axis", "X", np.random.default_rng(3), reversal_um=2.0)
    b = simulate_test("vmc-3axis", "X", np.random.default_rng(3), reversal_um=2.0, reversal_sense="lead")
    assert a.meta == b.meta and "added_reversal_sense" not in a.meta
    assert np.array_equal(a.measured, b.measured)
    m = np.asarray(a.measured, float)
    before_head = [-294.9920533688337, -248.2118070584371, -184.74784056035648, -109.08847762364432]
    before_tail = [-109.09007061913529, -184.75080375820383, -248.21333270240422, -294.99518137693644]
    assert m.shape == (110,)
    np.testing.assert_allclose(m[:4], before_head, rtol=0, atol=1e-9)  # (1e-9 mm: last digits, not a 2 um lead)
    np.testing.assert_allclose(m[-4:], before_tail, rtol=0, atol=1e-9)
    assert float(m.sum()) == pytest.approx(-260.0333820482991, abs=1e-8)


def test_the_log_names_what_the_options_added_not_the_machines_reversal(tmp_path):
    """review31 F2: on a machine file whose EXX has ``reversal_um = 2`` the log said ``reversal_um: 0`` (the
    option's added value) beside a measured B of 2 um. The keys now say ``added_``; the machine's own lost motion
    is in ``errors`` (its file) and in the readings: B = 2 um (no scatter, no other error: exact to 1e-9 mm)."""
    m = tmp_path / "m.toml"
    m.write_text('format = "vmt-machine/1"\nname = "m"\nbase = "vmc-3axis"\nerrors = "none"\n'
                 '[error.EXX]\nreversal_um = 2.0\n')
    log = simulate_test(str(m), "X", np.random.default_rng(0), noise_um=0.0)
    assert "reversal_um" not in log.meta and "drift_um_per_h" not in log.meta
    assert log.meta["added_reversal_um"] == "0" and log.meta["added_drift_um_per_h"] == "0"
    assert iso230_2(log).B * 1e3 == pytest.approx(2.0, abs=1e-9)
    both = simulate_test(str(m), "X", np.random.default_rng(0), noise_um=0.0, reversal_um=3.0,
                         reversal_sense="lag", drift_um_per_h=1.0, drift_tau_s=60.0)
    assert (both.meta["added_reversal_um"], both.meta["added_reversal_sense"], both.meta["added_drift_um_per_h"],
            both.meta["added_drift_tau_s"]) == ("3", "lag", "1", "60")


def test_a_sense_without_a_lost_motion_is_refused():
    """A lag of nothing is no lag: the log would say ``reversal_sense: lag`` of a run without one (the machine file
    refuses the same: its sense needs ``reversal_um``; the session 21 review)."""
    from core.exceptions import ConfigError

    with pytest.raises(ConfigError, match="reversal-sense lag needs --reversal-um"):
        simulate_test("vmc-3axis", "X", np.random.default_rng(0), reversal_um=0.0, reversal_sense="lag")


def _discovered(effect, seed):
    from scenarios.hidden import hidden_campaign

    log, truth = hidden_campaign((effect,), seed)
    rep = discovered(log).to_report()
    return truth, rep


def test_discover_reads_a_simulated_lag_negative_and_a_lead_positive():
    """Simulator seed 4000 (a tuning seed): 3.72 um of lost motion on Y, drawn once, simulated as a lead
    (``reversal``) and as a lag (``reversal_lag``; same machine, moves and noise). Both are named ``reversal``; the
    lead reads +4.09 +- 0.52 um, the lag -3.36 +- 0.52: each truth (+3.72, -3.72) within U95. The two readings
    differ by twice the size (the fit is linear in the truth and both campaigns share everything else): what the
    two have in common (+0.37 um here) is the effect-free campaign's own reading, not the sign."""
    out = {}
    for effect in ("reversal", "reversal_lag"):
        truth, rep = _discovered(effect, 4000)
        p = truth.params[effect]
        key = p["symbol"][1].lower() + "_lost_motion_um"
        f = next(f for f in rep["findings"] if f["cause"] == "reversal")
        assert rep["cause"] == "reversal"
        assert abs(f["params"][key] - p["lost_motion_um"]) <= f["params_u95"][key], (effect, f["params"], p)
        out[effect] = (p["lost_motion_um"], f["params"][key])
    (b_lead, r_lead), (b_lag, r_lag) = out["reversal"], out["reversal_lag"]
    assert b_lead > 0 and b_lag == -b_lead  # the truth: ISO's signed B_i, +size lead, -size lag
    assert r_lead > 0 > r_lag
    assert (r_lead - r_lag) / 2 == pytest.approx(b_lead, abs=0.01)
