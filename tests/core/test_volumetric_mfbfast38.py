"""Session 38 (mfbfast38): the residual tests' chi-square tails without scipy.stats, bit for bit.

core.volumetric's lack-of-fit, model-error share and between-node tests took their chi-square tails from
scipy.stats.chi2, whose import was 0.5 s of the CPU of a ``vmt scenario mfb-*`` process (it used nothing else of
scipy.stats). ``_chi2_sf`` calls the function chi2.sf calls (scipy.special.chdtrc) and keeps its wrapper's rules;
core.mfb's reversal calibration takes Student's quantile from scipy.special.stdtrit (t.ppf's own). Checked against
scipy.stats itself (the reference, not code of ours): equal in every double (tolerance none), edge cases included.
"""

import subprocess
import sys

import numpy as np
import pytest
from scipy import special, stats

from core.volumetric import _chi2_sf, _satterthwaite_sf, _tail_lower_bound


def _grid():
    rng = np.random.default_rng(38)
    x = np.concatenate([rng.exponential(5, 4000), 10 ** rng.uniform(-12, 3, 4000), [0.0, -1.0, -np.inf, np.inf,
                                                                                      np.nan, 1e-300, 1e300]])
    df = np.concatenate([rng.uniform(0.01, 100, 4000), rng.integers(1, 300, 4000).astype(float),
                         [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]])
    return x, df


def test_chi2_sf_is_scipy_stats_bit_for_bit_arrays_and_scalars():
    x, df = _grid()
    assert np.array_equal(_chi2_sf(x, df), stats.chi2.sf(x, df), equal_nan=True)
    for xi, di in zip(x[::40], df[::40]):
        a, b = _chi2_sf(xi, di), float(stats.chi2.sf(xi, di))
        assert isinstance(a, float)
        assert a == b or (np.isnan(a) and np.isnan(b)), (xi, di, a, b)
    lam = np.linspace(0.1, 2.0, 39)  # _tail_lower_bound's call: one x over weights, degrees 1..k
    k = np.arange(1, 40)
    assert np.array_equal(_chi2_sf(7.5 / lam, k), stats.chi2.sf(7.5 / lam, k))


@pytest.mark.parametrize("x,df", [(3.0, 0.0), (3.0, -1.0), (3.0, np.nan), (-1.0, 0.0), (np.nan, 2.0)])
def test_chi2_sf_bad_arguments_are_nan_as_scipy_stats_gives(x, df):
    assert np.isnan(_chi2_sf(x, df)) and np.isnan(stats.chi2.sf(x, df))


def test_chi2_sf_support_ends():
    assert _chi2_sf(0.0, 3.0) == 1.0 == stats.chi2.sf(0.0, 3.0)
    assert _chi2_sf(-2.0, 3.0) == 1.0 == stats.chi2.sf(-2.0, 3.0)
    assert _chi2_sf(np.inf, 3.0) == 0.0 == stats.chi2.sf(np.inf, 3.0)


def test_the_tests_tails_are_the_old_ones():
    """_satterthwaite_sf and _tail_lower_bound as they were written with scipy.stats.chi2 (known answers: the old
    expressions evaluated here)."""
    for q, t1, t2 in ((12.0, 10.0, 14.0), (0.5, 3.0, 9.0), (300.0, 40.0, 80.0)):
        assert _satterthwaite_sf(q, t1, t2) == float(stats.chi2.sf(q / (t2 / t1), t1 * t1 / t2))
    lam = np.array([1.0, 0.3, 0.3, 1e-3])
    want = float(np.max(stats.chi2.sf(30.0 / lam, np.arange(1, 5))))
    assert _tail_lower_bound(lam, 30.0) == want
    assert _tail_lower_bound(lam[::-1], 30.0) == want  # sorted inside


def test_student_quantile_is_t_ppf_bit_for_bit():
    nu = np.concatenate([1 + 10 ** np.random.default_rng(1).uniform(-8, 8, 5000), [1.0, 2.0, 1e300]])
    assert np.array_equal(special.stdtrit(nu, 0.975), stats.t.ppf(0.975, nu))


def test_an_mfb_run_does_not_import_scipy_stats():
    """A fresh process: the 3-axis scenario with noise (lack of fit, share, between-node test: every tail) and the
    reversal calibration leave scipy.stats unimported."""
    code = ("import sys, io, contextlib\n"
            "from scenarios import mfb\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    r = mfb.run('mfb-3axis', seed=2, mc_runs=0)\n"
            "    mfb.reversal_on_cmm(seed=2)\n"
            "assert r.doc['lack_of_fit']['p'] > 0 and 'between_nodes' in r.doc\n"
            "print('scipy.stats' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
