"""``vmt vcmm``: the uncertainty about a measurand's TRUE value (review33a F6).

A form measurand (a max - min of residuals) is biased upward by probing noise: on a perfect flat top
the measured flatness is never below 0, so the measured value's own 95 % interval (``interval``,
``U95``) is about where the measured value falls, not about the true 0. The known answer: the block's
8 top touches (README's example) on a perfect machine with noise sigma = 0.25 um along the normal,
true flatness 0. vcmm's Monte Carlo gives ``error_interval`` [lo, hi] of measured - true; the truth is
then in [measured - hi, measured - lo]. Independent repeats of the measurement from the test's own
seeded generator (not vmt's simulator, not its fit: an SVD plane and the peak-to-valley of its
residuals) check that this interval covers 0 in ~95 % of them and the old measured +- U95 does not.
"""

import dataclasses

import numpy as np
import pytest

from core import vcmm as V
from scenarios import vcmm as S
from sim.machine import Machine
from sim.machinefile import resolve
from tests.scenarios.test_vcmm_line_profile import meas
from tests.scenarios.test_vcmm_study import BORE, C_MM, plan_of

TOP = [(-30, -20), (-30, 0), (-30, 20), (-15, -20), (-15, 20), (30, -20), (30, 20), (10, -22)]   # block_plan's top
PLAN = plan_of([("top", (x, y, 0.0), (0.0, 0.0, 1.0)) for x, y in TOP])
SIGMA_UM = 0.25
TASK = ('[features.top]\nkind = "plane"\nfeature = "top"\n' + meas("flat", "flatness", "top")
        + f"[probe]\nnoise_um = {SIGMA_UM}\n[mc]\nbatch_runs = 500\nmax_runs = 1000\ntolerance_um = 0.05\n")


@pytest.fixture(scope="module")
def machine():
    return resolve("vmc-3axis")   # no error in its file: the touches' only error is the noise


def own_flatness_um(rng, n_repeats):
    """Flatness (um) of the perfect top measured ``n_repeats`` times: noise N(0, sigma) along +Z
    (the simulator's noise is along the approach, -n: the same law), LS plane by SVD, max - min."""
    xy = np.array(TOP, float) * 1e-3
    out = np.empty(n_repeats)
    for i in range(n_repeats):
        p = np.c_[xy, SIGMA_UM * 1e-6 * rng.standard_normal(len(xy))]
        c = p - p.mean(axis=0)
        n = np.linalg.svd(c)[2][2]
        r = c @ n
        out[i] = (r.max() - r.min()) * 1e6
    return out


@pytest.fixture(scope="module")
def flat(machine):
    st = S.prepare(PLAN, V.loads_task(TASK), machine)
    assert st.sources == ("probe repeatability",)
    return S.study(st, 3, budget=False)["measurands"][0]


def test_the_interval_about_the_true_flatness_covers_it_and_the_measured_values_does_not(flat):
    assert flat["nominal"] == pytest.approx(0.0, abs=1e-6)     # um: a perfect top reads flat
    lo, hi = flat["error_interval"]
    assert 0.0 < lo < hi     # the error of a max - min is never negative: the truth is below the measured
    assert flat["biased"] and flat["error_mean"] > V.BIAS_OF_U * flat["U95"]
    y = own_flatness_um(np.random.default_rng(20261205), 4000)
    # the truth is 0: the new interval [y - hi, y - lo] holds it when lo <= y <= hi. Tolerance 0.025:
    # the repeats' binomial SE sqrt(0.95 0.05 / 4000) = 0.0034 and the MC's 2.5 % quantiles from
    # 1000 runs (SE of each tail's share sqrt(0.025 0.975 / 1000) = 0.005): 0.008 together, 3 SE
    new = np.mean((y - hi <= 0.0) & (0.0 <= y - lo))
    assert abs(new - 0.95) < 0.025, new
    sym = np.mean(np.abs(y) <= flat["U95_about_true"])
    assert abs(sym - 0.95) < 0.025, sym
    old = np.mean(np.abs(y) <= flat["U95"])   # measured +- U95 (the measured value's half-width)
    assert old < 0.5, old                     # review33a's own MC: 0.15
    # vmt's figure of the old coverage is the repeats' (same law): binomial SEs at 0.15 of 1000 runs
    # (0.011) and 4000 repeats (0.006) make 0.013 together; 0.04 is 3 of it
    assert flat["U_covers_true"] == pytest.approx(old, abs=0.04)
    # the mean error is the repeats' mean flatness (truth 0): SEs 0.2 / sqrt(1000) and 0.2 / sqrt(4000) um,
    # 0.007 together: 0.03 um is 4 of them
    assert flat["error_mean"] == pytest.approx(y.mean(), abs=0.03)


def test_error_stats_known_answer():
    """Errors b + N(0, 1) in a fixed sample: the interval is the sample's 2.5 / 97.5 % points, the
    |e| quantile the 95 % one, ``covers`` the share within U; biased past BIAS_OF_U * U only."""
    e = 0.3 + np.random.default_rng(1).standard_normal(20000)
    s = V.error_stats(e, 1.96, 0.95)
    assert s.mean == pytest.approx(e.mean(), abs=1e-15)
    srt = np.sort(e)
    assert (s.low, s.high) == (srt[499], srt[19499])          # JCGM 101 7.7.2: r = 500, q = 19000 (1-based)
    assert s.U_about_true == np.sort(np.abs(e))[18999]
    assert s.covers == np.mean(np.abs(e) <= 1.96)
    # N(0.3, 1): P(|e| <= 1.96) = Phi(1.66) + Phi(2.26) - 1 = 0.9396; 3 binomial SEs 0.005
    assert s.covers == pytest.approx(0.9396, abs=0.005)
    assert s.biased                                            # 0.3 > 0.1 * 1.96
    assert not V.error_stats(e - 0.3 + 0.15, 1.96).biased      # 0.15 < 0.196
    assert not V.error_stats(np.full(5, 1e-18), 0.0).biased    # noise-free rounding is not a bias


def test_the_truth_of_a_drawn_form_is_the_runs_own_part(machine):
    """With a [form] drawn per run, the true roundness is that run's ptp(f_i) (test_vcmm_form's
    hand-worked 3-lobe bore): no noise and a perfect machine make measured == true, error 0."""
    task = ('[features.bore]\nkind = "circle"\nfeature = "bore"\n[probe]\nnoise_um = 0.0\n'
            + meas("round", "roundness", "bore") + '[form.bore]\namplitude_um = 1.5\nlobes = 3\n')
    st = S.prepare(BORE, V.loads_task(task), machine)
    perfect = Machine(dataclasses.replace(st.config, errors={}))
    t = S.true_values(st, 7, range(4), np.zeros(1), perfect)
    th = np.arctan2(st.Xn_R[:, 1] - C_MM[1] * 1e-3, st.Xn_R[:, 0] - C_MM[0] * 1e-3)
    for i in range(4):
        a, phi = S.draw(st, 7, i)[0][("form", "bore")]
        assert t[i, 0] == pytest.approx(np.ptp(a * np.cos(3 * th + phi)), abs=1e-12)   # m: the fits' rounding
    assert np.ptp(t[:, 0]) > 1e-7     # the truth moves run to run (the nominal would be 0 throughout)
    m = S.study(st, 7, budget=False)["measurands"][0]
    assert m["error_interval"] == pytest.approx([0.0, 0.0], abs=1e-6)   # um
    assert m["U95_about_true"] == pytest.approx(0.0, abs=1e-6) and not m["biased"]
    assert m["bias"] > 0.1     # about the nominal 0 the drawn form looks like a bias; about the truth it is none


def test_no_form_the_truth_is_the_nominal_and_no_run_is_simulated(machine):
    st = S.prepare(PLAN, V.loads_task(TASK), machine)
    y = np.array([1.5])
    t = S.true_values(st, 0, range(3), y, perfect=None)   # no machine needed: none is built
    assert t.shape == (3, 1) and np.all(t == 1.5)
