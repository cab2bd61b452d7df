"""Blind generator C (scenarios/blind/gen_c.py): its own correctness, not discovery's.

- every effect's log is a legal ``probe-log/1`` (written and read back through
  the spec's validation) with the design the module docstring describes;
- the effect switched on changes the readings by exactly the Truth's
  ``effect_dq_um`` and nothing else (same schedule, nominals and noise), and
  only on the rows the effect reaches;
- the truth round trip: a noise-free effect-free campaign whose machine has
  only affine axis errors gives the workpiece back through the baseline to
  numerical precision; with the smooth machine, within the grid's
  interpolation error;
- the lost-motion path model against hand-computed answers;
- bad input refused.
"""

import functools
import types

import numpy as np
import pytest

from core.probelog import format_probe_log, parse_probe_log
from scenarios.blind import gen_c


def _dq_um(log):
    return log.dq_mm() * 1e3


@pytest.mark.parametrize("effect", gen_c.effects())
def test_every_log_is_legal_and_as_described(effect):
    log, tr = gen_c.generate(effect, 3)
    back = parse_probe_log(format_probe_log(log))          # the reader's full validation
    assert back.n == log.n
    ok = log.ok
    assert np.all(np.diff(log.columns["t_s"]) > 0)          # touches in the order made, time running
    assert set(log.col("status")) <= {"ok", "no_trigger"}
    assert np.all(np.isnan(log.columns["X_mm"][~ok]))
    # one C angle per set-up, 4-6 set-ups, each target in every set-up
    setups = list(dict.fromkeys(log.columns["setup"]))
    assert 4 <= len(setups) <= 6 and len(setups) == len(tr.c_angles_deg)
    for s, c in zip(setups, tr.c_angles_deg):
        m = log.columns["setup"] == s
        assert set(log.columns["C_deg"][m]) == {c}
        assert set(log.columns["target"][m & ok]) == set(tr.targets)
    # normals horizontal, approach against the normal, the tip centre r off the contact point
    assert np.all(log.columns["nz"] == 0)
    # the nominal at C: the artefact point turned by -C plus the stylus radius along the normal
    c = np.radians(log.columns["C_deg"])
    wx, wy = log.columns["wx_mm"], log.columns["wy_mm"]
    xm = np.cos(c) * wx + np.sin(c) * wy + gen_c.STYLUS_R_MM * log.columns["nx"]
    ym = -np.sin(c) * wx + np.cos(c) * wy + gen_c.STYLUS_R_MM * log.columns["ny"]
    np.testing.assert_allclose(log.columns["Xn_mm"], xm, atol=1e-9)
    np.testing.assert_allclose(log.columns["Yn_mm"], ym, atol=1e-9)
    assert 0.2 <= tr.noise_um <= 0.5
    assert len(tr.workpiece_um) == len(tr.targets) == 74
    assert tr.acceptable_causes == gen_c.ACCEPTABLE[effect]
    # the boss re-probed at the end of every set-up: repeats
    assert np.sum(log.columns["feature"] == "boss") == 16 * len(setups) + np.sum(
        (log.columns["feature"] == "boss") & ~ok)


def test_catalogue_names_are_catalogue_causes():
    from core import causes

    names = causes.names()
    for e in gen_c.CATALOGUE:
        assert e in names and e in gen_c.ACCEPTABLE[e]
    for e in gen_c.OUTSIDE:                                  # outside: not itself a cause, unexplained accepted
        assert e not in names and "unexplained" in gen_c.ACCEPTABLE[e]


def _rows_reached(effect, tr, log):
    """Rows the effect must change (and no other)."""
    p = tr.params
    if effect == "outlier":
        m = np.zeros(log.n, bool)
        m[p["rows"]] = True
        return m
    if effect == "part_change":
        return (log.columns["feature"] == p["feature"]) & log.ok
    return None


@pytest.mark.parametrize("effect", [e for e in gen_c.effects() if e != "none"])
def test_effect_on_changes_only_its_rows_by_its_truth(effect):
    seed = 7
    log0, tr0 = gen_c.generate("none", seed)
    log1, tr1 = gen_c.generate(effect, seed)
    # the same campaign: schedule, nominals, part, noise
    for k in ("setup", "target", "t_s", "Xn_mm", "Yn_mm", "Zn_mm", "nx", "ny", "C_deg", "status", "temp_bed_C"):
        assert np.array_equal(log0.columns[k], log1.columns[k]), k
    np.testing.assert_array_equal(tr0.workpiece_um, tr1.workpiece_um)
    assert tr0.noise_um == tr1.noise_um
    ok = log0.ok
    d = _dq_um(log1)[ok] - _dq_um(log0)[ok]
    # the readings differ by the effect alone: 1e-6 um is a few ulps of a 100 mm reading
    np.testing.assert_allclose(d, tr1.effect_dq_um[ok], atol=1e-6)
    assert np.all(tr1.effect_dq_um[~ok] == 0)
    assert np.max(np.abs(tr1.effect_dq_um)) > 0.1
    reached = _rows_reached(effect, tr1, log1)
    if reached is not None:
        assert np.all(tr1.effect_dq_um[~reached] == 0)
        assert np.all(tr1.effect_dq_um[reached & ok] != 0)
    # the generator's visibility is its own figure: RMS over the rows at >= 10 % of the peak / noise
    e = tr1.effect_dq_um
    on = np.abs(e) >= 0.1 * np.max(np.abs(e))
    assert tr1.visible_sigmas == pytest.approx(np.sqrt(np.mean(e[on] ** 2)) / tr1.noise_um, rel=1e-12)


def test_none_has_no_effect_and_is_deterministic():
    a, ta = gen_c.generate("none", 11)
    b, tb = gen_c.generate("none", 11)
    assert format_probe_log(a) == format_probe_log(b)
    assert not np.any(ta.effect_dq_um) and ta.visible_sigmas == 0.0
    c, _ = gen_c.generate("none", 12)
    assert format_probe_log(a) != format_probe_log(c)


def _baseline_workpiece_error(seed, machine):
    from scenarios.hidden import blind_outcome

    mod = types.SimpleNamespace(generate=functools.partial(gen_c.generate, noise=False, machine=machine))
    return blind_outcome(mod, "none", seed, generator="gen_c").wp_base_um


# (no warning filter: on noise-free data the noise is never taken below the
# data's rounding, core.discover.ROUNDOFF_ULPS; session 26)
def test_truth_round_trip_noise_free_affine_machine():
    # affine axis errors are in any error map's span and the part's pose per
    # set-up in the set-ups' terms: the baseline must give the form back exactly
    # (gauge-free RMS, um); measured 2e-12 to 3e-12 on seeds 0-2
    assert _baseline_workpiece_error(0, "affine") < 1e-8


def test_truth_round_trip_noise_free_smooth_machine():
    # quadratic and cubic axis errors between grid nodes: a linear map's
    # interpolation error h^2 f''/8 is a few hundredths of a um (measured
    # 0.003 and 0.047 um on seeds 0 and 2); 0.1 um bounds it, a third of the
    # least noise this generator draws
    assert _baseline_workpiece_error(2, "smooth") < 0.1


def test_lost_motion_known_answers():
    # X moves +10 then the approach goes -1 (a reversal): plain lost motion
    # takes -b/2 at once; Dahl's wind-up over s0 reaches -b/2 + b exp(-1/s0)
    rows = [{"path": [np.array([0.0, 0.0]), np.array([10.0, 0.0])], "xn": np.array([9.0, 0.0, 0.0])}]
    b = np.array([4.0, 0.0])
    np.testing.assert_allclose(gen_c._lost_motion(rows, b, np.zeros(2))[0], [-2.0, 0.0])
    s0 = 2.0
    w_after_10 = 2.0 * (1 - np.exp(-10 / s0))          # from 0 towards +2 over 10 mm
    w_after_rev = -2.0 + (w_after_10 + 2.0) * np.exp(-1 / s0)   # towards -2 over 1 mm
    np.testing.assert_allclose(gen_c._lost_motion(rows, b, np.array([s0, 1.0]))[0], [w_after_rev, 0.0])
    # Y never moves: no error on Y whatever its lost motion
    np.testing.assert_allclose(gen_c._lost_motion(rows, np.array([0.0, 3.0]), np.zeros(2))[0], [0.0, 0.0])


def test_bad_input_refused():
    with pytest.raises(ValueError, match="unknown effect 'drift'"):
        gen_c.generate("drift", 0)
    with pytest.raises(ValueError, match="machine must be"):
        gen_c.generate("none", 0, machine="rigid")
