"""Identical Monte Carlo results on serial, local processes and a real Dask cluster: scenarios.parallel's
study and design sweep, and scenarios.vcmm's study (the virtual CMM's gauge of test_vcmm_study)."""

import numpy as np
import pytest

from core.design import example_cross_pocket, max_workpiece_U95
from core.selfcal import Grid
from scenarios.parallel import design_sweep, mc_study

GRID = Grid.regular(-0.110, 0.110, 0.022)
ANG = [0, 75, 130, 210]


@pytest.fixture(scope="module")
def dask_cluster():
    """The scheduler address of one local Dask cluster (2 worker processes, 1 thread each) for this file's
    tests: started once (about 10 s and 4.5 s of CPU, and its workers import vmt again each time) and shut
    down when the file is done (an idle cluster still costs about 10 s of CPU a minute)."""
    import distributed                      # a dependency (pyproject, requirements.lock): fails, never skips

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        yield cluster.scheduler_address


@pytest.fixture(scope="module")
def pocket():
    w, wn, _ = example_cross_pocket()
    return w, wn


def test_mc_independent_of_grouping_and_agrees_with_linear(pocket):
    w, wn = pocket
    a = mc_study(w, wn, ANG, GRID, 1.38e-6, runs=5000, seed=3, block=500, blocks_per_task=1)
    b = mc_study(w, wn, ANG, GRID, 1.38e-6, runs=5000, seed=3, block=500, blocks_per_task=4)
    for k in ("mean", "u", "lo", "hi"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    free = a.u_linear > 0
    # sampling error of a std from 5000 runs ~1 %: 5 % bound over ~150 parameters
    np.testing.assert_allclose(a.u[free], a.u_linear[free], rtol=0.05)
    np.testing.assert_allclose(a.hi[free], 1.96 * a.u_linear[free], rtol=0.1)


def test_dask_cluster_and_local_processes_give_identical_results(pocket, dask_cluster):
    w, wn = pocket
    serial = mc_study(w, wn, ANG, GRID, 1.38e-6, runs=3000, seed=42, block=500, blocks_per_task=2)
    local = mc_study(w, wn, ANG, GRID, 1.38e-6, runs=3000, seed=42, block=500, blocks_per_task=2, workers=2)
    dk = mc_study(w, wn, ANG, GRID, 1.38e-6, runs=3000, seed=42, block=500, blocks_per_task=2, dask=dask_cluster)
    sweep = design_sweep(w, wn, [ANG, [0, 60, 150, 210]], GRID, 1.38e-6, dask=dask_cluster)
    for k in ("mean", "u", "lo", "hi"):
        assert np.array_equal(getattr(serial, k), getattr(local, k)), k
        assert np.array_equal(getattr(serial, k), getattr(dk, k)), k
    # a design evaluation refactors in the worker: equal up to BLAS rounding (thread counts differ)
    assert sweep == pytest.approx([max_workpiece_U95(w, wn, ANG, GRID),
                                   max_workpiece_U95(w, wn, [0, 60, 150, 210], GRID)], rel=1e-10, abs=0)
    # another seed gives other numbers
    other = mc_study(w, wn, ANG, GRID, 1.38e-6, runs=3000, seed=43, block=500)
    assert not np.array_equal(other.u, serial.u)


def test_vcmm_dask_gives_the_same_result_per_seed(dask_cluster):
    """vmt vcmm's study serially and on the Dask cluster: identical values, run by run."""
    from core.vcmm import loads_task
    from scenarios import vcmm as S
    from sim.machinefile import resolve
    from tests.scenarios.test_vcmm_study import GAUGE, GAUGE_TASK

    task = loads_task(GAUGE_TASK.replace("batch_runs = 50", "batch_runs = 20").replace("noise_um = 0.0",
                                                                                         "noise_um = 0.2"))
    st = S.prepare(GAUGE, task, resolve("vmc-3axis"))
    serial = S.study(st, 5, budget=False)
    remote = S.study(st, 5, budget=False, dask=dask_cluster)
    assert serial["runs"] == remote["runs"]
    assert np.array_equal(serial["values_si"], remote["values_si"])
    assert [t["u_dq_um"] for t in serial["touches_u"]] == [t["u_dq_um"] for t in remote["touches_u"]]


def test_vcmm_dask_true_values_of_a_drawn_form_are_the_serial_ones(dask_cluster):
    """A [form] task's truth runs (one simulation each) go to the cluster too: the same errors about the
    true value, run by run, and the progress line counts them (it ends at the truth's last run)."""
    from core.vcmm import loads_task
    from scenarios import vcmm as S
    from sim.machinefile import resolve
    from tests.scenarios.test_vcmm_line_profile import meas
    from tests.scenarios.test_vcmm_study import BORE

    task = loads_task('[features.bore]\nkind = "circle"\nfeature = "bore"\n[probe]\nnoise_um = 0.2\n'
                      + meas("round", "roundness", "bore") + '[form.bore]\namplitude_um = 1.5\nlobes = 3\n'
                      + "[mc]\nbatch_runs = 20\nmax_runs = 40\n")
    st = S.prepare(BORE, task, resolve("vmc-3axis"))
    seen: list = []
    serial = S.study(st, 5, budget=False, progress=lambda d, t: seen.append((d, t)))
    remote = S.study(st, 5, budget=False, dask=dask_cluster)
    n = len(serial["values_si"])
    assert seen[-1] == (2 * n, 2 * n)          # n measured runs, then n truth runs, counted
    a, b = serial["measurands"][0], remote["measurands"][0]
    for k in ("error_interval", "error_mean", "U95_about_true", "U_covers_true", "biased"):
        assert a[k] == b[k], k
    assert a["error_interval"] != [0.0, 0.0]   # the truth moved: not the nominal's interval
