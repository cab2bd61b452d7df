"""Fixtures shared by the whole suite, and how the suite is split between workers.

``make test`` runs on two pytest-xdist workers with ``--dist loadfile``, which
this file refines (:func:`pytest_xdist_make_scheduler`): each test file stays
on one worker, so its module and session fixtures are computed once, and the
files that use one of :data:`SHARED_SESSION_FIXTURES` are one unit, so that
fixture too is computed once. The longest units are handed out first
(:data:`LONGEST_FIRST`).

(``--dist loadgroup`` with ``xdist_group`` marks would say the same, but with
pytest 9.2 and xdist 3.8 the marks are silently ignored: xdist rewrites
``item._nodeid``, which pytest no longer reads; pytest-xdist issue 1386.)
"""

import compileall
import fnmatch
import functools
import inspect
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

#: The session fixtures of this conftest that several test files use: every file that names one
#: runs on the same worker, and fixtures named together in one file are one unit (:func:`fixture_units`).
#: Checked on every worker against the fixtures the tests really use.
SHARED_SESSION_FIXTURES = ("mfb3_noise_free", "mfb_seed1_runs")

#: The longest units, longest first: every unit of 5 s or more (62 of 251 units), by its seconds (tests, set-ups
#: included, summed per unit) in session 38's make test on an idle fresh clone (the lead's junit of it: 1,267 s of
#: tests on two workers, 645 s of wall), the files sharing a session fixture as one unit (the mfb3_noise_free unit,
#: with mfb_seed1_runs's files: 229 s); the others follow in collection order and fill the end. Handed out first, so
#: that no long file starts last and leaves one worker running alone. The list of sessions 27-37 had gone stale: it
#: missed test_discover_volumetric (49 s), test_mfb_discovered (27 s), test_discover_form_shift (12 s),
#: test_mfb_study (11 s) and others, which ran where collection put them, and kept test_cli26 second (159 s in
#: session 27, 19 s now).
#: xdist's queue replayed on these durations (a unit at a time to the first free worker), each unit's time scaled by a
#: random factor (lognormal, 30 %, 2,000 draws): the gap between the workers' ends averages 1.7 s (90th percentile
#: 4.8 s) with the old list and 0.4 s (0.8 s) with this one. A file missing here only loses its place.
LONGEST_FIRST = ("fixture:mfb3_noise_free", "tests/core/test_discover_misses.py",
                 "tests/scenarios/test_discover_hidden.py", "tests/core/test_discover_volumetric.py",
                 "tests/scenarios/test_demo.py", "tests/scenarios/test_mfb_discovered.py",
                 "tests/hardware/test_campaign.py", "tests/core/test_discover_norm_u95.py",
                 "tests/core/test_discover_cv.py", "tests/core/test_discover_nonrigid_u95.py",
                 "tests/scenarios/test_cli26.py", "tests/scenarios/test_comp_closed_loop.py",
                 "tests/core/test_discover_engine.py", "tests/scenarios/test_regress.py",
                 "tests/core/test_discover_defect.py", "tests/core/test_discover_form_shift.py",
                 "tests/core/test_discover_gain_interval.py", "tests/scenarios/test_warn31_input_warnings.py",
                 "tests/scenarios/test_mfb_study.py", "tests/core/test_discover_turned_lead.py",
                 "tests/core/test_discover_u95_smooth.py", "tests/core/test_discover_generalisation.py",
                 "tests/core/test_straddled_fastpath.py", "tests/core/test_discover_diag31.py",
                 "tests/scenarios/test_discover_abbe_baseline.py", "tests/core/test_discover_named_beside_turn.py",
                 "tests/scenarios/test_vcmm_route37.py", "tests/core/test_uncertainty.py",
                 "tests/scenarios/test_demo_steps37.py", "tests/core/test_discover_workpiece_named.py",
                 "tests/core/test_discover_warmup_tau.py", "tests/hardware/test_emulator_sim.py",
                 "tests/core/test_fit.py", "tests/sim/test_mfb_scene.py", "tests/scenarios/test_paper_scenarios.py",
                 "tests/scenarios/test_identify_tool_offset.py", "tests/test_architecture.py",
                 "tests/core/test_discover_pair37.py", "tests/sim/test_clearance.py", "tests/viz/test_figures.py",
                 "tests/scenarios/test_hidden_mfb.py", "tests/core/test_forms_gram.py",
                 "tests/core/test_discover_sel36.py", "tests/core/test_selfcal_serial.py",
                 "tests/core/test_long_basis.py", "tests/core/test_part_change_curve.py",
                 "tests/scenarios/test_guard.py", "tests/scenarios/test_parallel.py",
                 "tests/core/test_fit_rounding.py", "tests/scenarios/test_vcmm_true_value.py",
                 "tests/scenarios/test_comprule_study.py", "tests/core/test_discover_vif33.py",
                 "tests/scenarios/test_selfcal_coverage.py", "tests/core/test_path_count_deferred.py",
                 "tests/hardware/test_emulator_robust.py", "tests/hardware/test_grbl_tool_offset.py",
                 "tests/core/test_discover_vif32.py", "tests/scenarios/test_blind_gen_a.py", "tests/test_fuzz_cli.py",
                 "tests/scenarios/test_mfb_between_nodes.py", "tests/core/test_discover_fine_shift.py",
                 "tests/core/test_discover_grid_after_outliers.py")

_ROOT = Path(__file__).resolve().parents[1]


def _named(text: str) -> list:
    """The shared session fixtures (:data:`SHARED_SESSION_FIXTURES`, in its order) that a test file's source names."""
    return [n for n in SHARED_SESSION_FIXTURES if n in text]


@functools.cache
def fixture_units() -> dict:
    """Shared session fixture -> the fixture naming its unit: fixtures named together in one test file are one
    unit (transitively), named by the first of them in :data:`SHARED_SESSION_FIXTURES`; else each its own. A
    file naming two fixtures of two units would otherwise leave one of them computed on both workers."""
    root = {n: n for n in SHARED_SESSION_FIXTURES}

    def find(n):
        while root[n] != n:
            n = root[n]
        return n

    order = {n: i for i, n in enumerate(SHARED_SESSION_FIXTURES)}
    for fn in sorted((_ROOT / "tests").rglob("*.py")):
        if fn.name == "conftest.py":
            continue
        try:
            names = _named(fn.read_text(encoding="utf-8"))
        except OSError:
            continue
        for n in names[1:]:
            a, b = sorted((find(names[0]), find(n)), key=order.get)
            root[b] = a
    return {n: find(n) for n in SHARED_SESSION_FIXTURES}


@functools.cache
def unit_of(path: str) -> str:
    """The work unit of a test file (rootdir-relative ``path``): ``fixture:NAME`` for a file whose
    source names a shared session fixture (NAME: the fixture naming that fixture's unit, :func:`fixture_units`),
    else the file."""
    try:
        text = (_ROOT / path).read_text(encoding="utf-8")
    except OSError:
        return path
    names = _named(text)
    return f"fixture:{fixture_units()[names[0]]}" if names else path


def _unit_rank(path: str) -> int:
    u = unit_of(path)
    return LONGEST_FIRST.index(u) if u in LONGEST_FIRST else len(LONGEST_FIRST)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile`` with the files of one shared session fixture as one unit (other modes: xdist's own)."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class SharedFixtureScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return unit_of(nodeid.split("::", 1)[0])

    return SharedFixtureScheduling(config, log)


#: The project's packages, compiled once by :func:`pytest_sessionstart` (the workers and the ``vmt`` processes import them).
PACKAGES = ("core", "sim", "hardware", "scenarios", "viz")


@pytest.hookimpl(tryfirst=True)
def pytest_sessionstart(session):
    """On the xdist controller, before the workers start (xdist's own hook is ``trylast``): the caches
    the workers would otherwise both fill on a fresh clone, filled once. Each worker collects every
    test file, and a test file's import rewrites its asserts (``_pytest.assertion.rewrite``, about
    4 s of CPU for the suite, cached in ``__pycache__`` by the source's hash): without this, both
    workers rewrite every file at once. The same for the packages' byte code (``compileall``, the
    timestamp pyc an import writes). Nothing to do on a second run (about 0.1 s to check); nothing
    done without workers, under ``PYTHONDONTWRITEBYTECODE`` or ``--assert=plain``."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None) or sys.dont_write_bytecode:
        return
    for pkg in PACKAGES:
        compileall.compile_dir(_ROOT / pkg, quiet=2)
    try:  # pytest's own rewriting, as its import hook does it (a private API: skipped, with a warning, if it moved)
        from _pytest.assertion.rewrite import (PYC_TAIL, _read_pyc, _rewrite_test, _write_pyc, assertstate_key,
                                               get_cache_dir, try_makedirs)
    except ImportError as e:
        warnings.warn(pytest.PytestWarning(f"test files' asserts not rewritten before the workers start: {e}"))
        return
    state = config.stash.get(assertstate_key, None)
    if state is None:  # --assert=plain
        return
    patterns, skip = config.getini("python_files"), config.getini("norecursedirs")
    try:  # a speed-up only: a private function whose signature changed must not stop the run
        for fn in sorted((_ROOT / "tests").rglob("*.py")):
            if any(fnmatch.fnmatch(part, pat) for part in fn.relative_to(_ROOT / "tests").parts[:-1] for pat in skip):
                continue
            if fn.name != "conftest.py" and not any(fnmatch.fnmatch(fn.name, pat) for pat in patterns):
                continue
            cache = get_cache_dir(fn)
            pyc = cache / (fn.name[:-3] + PYC_TAIL)
            if try_makedirs(cache) and _read_pyc(fn, pyc) is None:
                source_hash, co = _rewrite_test(fn, config)
                _write_pyc(state, co, source_hash, pyc)
    except (TypeError, AttributeError, ValueError) as e:
        warnings.warn(pytest.PytestWarning(f"test files' asserts not rewritten before the workers start: {e!r}"))


def _conftest_session_fixtures(item) -> set:
    """Names of the session fixtures defined in a conftest that ``item`` uses."""
    info = getattr(item, "_fixtureinfo", None)      # absent on non-function items (doctests)
    if info is None:
        return set()
    return {name for name, defs in info.name2fixturedefs.items()
            if defs[-1].scope == "session" and (inspect.getsourcefile(defs[-1].func) or "").endswith("conftest.py")}


def pytest_collection_modifyitems(config, items):
    """On an xdist worker: the longest units first (``make test`` passes ``--no-loadscope-reorder``, so
    the queue keeps this order), and a warning for a conftest session fixture used by several files
    but not in :data:`SHARED_SESSION_FIXTURES` (it would be computed on both workers). A plain
    ``pytest`` run keeps the collection order."""
    if not hasattr(config, "workerinput"):
        return
    users = {}
    for item in items:
        for name in _conftest_session_fixtures(item):
            users.setdefault(name, set()).add(item.nodeid.split("::", 1)[0])
    for name, files in sorted(users.items()):
        units = {unit_of(f) for f in files}
        if len(units) > 1:
            warnings.warn(pytest.PytestWarning(
                f"session fixture {name} is used by {len(files)} test files on {len(units)} xdist units: "
                f"add it to SHARED_SESSION_FIXTURES in tests/conftest.py (else each worker computes it)"))
    items.sort(key=lambda it: _unit_rank(it.nodeid.split("::", 1)[0]))   # stable: files stay whole, in order


@pytest.fixture
def rng():
    """A seeded generator: every random test is reproducible."""
    return np.random.default_rng(20261122)


@pytest.fixture
def first_outlier_screen(monkeypatch):
    """``run(flag, on, generator="gen_a", seed=1505)``: a blind generator's outlier campaign discovered with
    ``core.discover``'s ``flag`` set to ``on``; ``(the first outlier screen's rows, the outcome)``."""
    import importlib

    import core.discover as D
    from scenarios import hidden

    def run(flag: str, on: bool, generator: str = "gen_a", seed: int = 1505):
        monkeypatch.setattr(D, flag, on)
        seen = []
        orig = D.find_outliers

        def spy(*a, **k):
            r = orig(*a, **k)
            seen.append(r)
            return r

        monkeypatch.setattr(D, "find_outliers", spy)
        o = hidden.blind_outcome(importlib.import_module(f"scenarios.blind.{generator}"), "outlier", seed,
                                 generator=generator)
        return seen[0], o

    return run


@pytest.fixture
def figures_not_drawn(monkeypatch):
    """viz's PNG writer (:func:`viz.figures.write_png`, behind every report figure and recording image)
    replaced, for one test, by one that does not draw: each figure is recorded and a fixed 1 x 1 PNG
    written in its place, through the same atomic path (``save_png``'s temporary and rename). Drawing
    is about 90 % of a figure's cost (constrained layout and text; encoding the PNG the rest; the
    three MFB report figures take 1.4 s of CPU). For a test that checks a report's data, page and files but not its
    pixels, whose figures another test renders from the same data (the test says which). Returns the
    list of ``(figure, target)`` given to the writer, in order."""
    import matplotlib.image

    import viz.figures

    seen = []

    def not_drawn(fig, target, *, dpi: int = 110) -> None:
        assert hasattr(fig, "savefig"), f"not a matplotlib figure: {fig!r}"
        seen.append((fig, target))
        matplotlib.image.imsave(target, np.ones((1, 1, 4)), format="png")

    monkeypatch.setattr(viz.figures, "write_png", not_drawn)
    return seen


@pytest.fixture
def mfb_notes_skipped(monkeypatch):
    """For one test, every noisy MFB run (:func:`scenarios.mfb.run`, and so ``closed_loop``'s and ``vmt
    scenario``'s runs) without the two notes that move nothing else of it: the between-node test
    (:data:`scenarios.mfb.MFB_BETWEEN_NODES` off: no JSON ``between_nodes``) and the model-error statistics
    where the lack-of-fit gate holds them out of the U95 (``model_error_held=False`` by default: no JSON
    ``model_error`` then; where the gate opens the share is still computed and widens the U95 as before, only
    its exact tails ``p`` are left out). Neither draws from the run's generator: theta, the U95, the
    covariance, the estimate, ``within_u95`` and every other key of the run's JSON are the same doubles (session
    36, notes on against off: 3-axis seeds 1, 2, 4, 11, 5-axis seed 1, a closed loop from seed 1, and test_mfb_fit's
    short-wave truth, where the gate opens: the same nine tables entered, the same ``u``, ``z`` and U95 growth, the
    tables' ``p`` null). About 60 % of a noisy run's CPU (3-axis seed 1: 0.7-0.9 against 1.5-2.2 s). For a
    test that reads neither note (their own tests: tests/scenarios/test_mfb_between_nodes.py, test_mfb_fit.py,
    tests/core/test_volumetric.py); a test that binds ``run`` at import keeps the original (import it inside
    the test, or call ``mfb.run``)."""
    _skip_mfb_notes(monkeypatch)


@pytest.fixture(scope="module")
def mfb_notes_skipped_module():
    """:func:`mfb_notes_skipped` for a whole test module (``pytestmark = pytest.mark.usefixtures(...)``): its module
    fixtures' runs too, from its first test to its last."""
    with pytest.MonkeyPatch.context() as mp:
        _skip_mfb_notes(mp)
        yield


def _skip_mfb_notes(mp) -> None:
    import functools

    import scenarios.mfb as S

    mp.setattr(S, "MFB_BETWEEN_NODES", False)
    orig = S.run

    @functools.wraps(orig)
    def run(*args, model_error_held: bool = False, **kw):
        return orig(*args, model_error_held=model_error_held, **kw)

    mp.setattr(S, "run", run)


@pytest.fixture(scope="session")
def mfb3_noise_free():
    """One noise-free ``mfb-3axis`` run on the default realistic machine, shared by the test files
    that need it (a full run is the suite's costliest step): ``(ScenarioResult, (meas, chain,
    nodes, rotary_points))``, the second being what the run handed to the identification."""
    import core.volumetric as V
    import scenarios.mfb as S

    cap = {}
    orig = V.identify_volumetric

    def spy(meas, chain, nodes, rp=None, **kw):
        cap["m"] = (meas, chain, nodes, rp)
        return orig(meas, chain, nodes, rp, **kw)

    V.identify_volumetric = spy
    try:
        res = S.run("mfb-3axis", noise_um=0.0, mc_runs=0)
    finally:
        V.identify_volumetric = orig
    return res, cap["m"]


@pytest.fixture(scope="session")
def mfb_seed1_runs():
    """The seed-1 MFB runs of docs/papers-mfb.md's rows (:func:`scenarios.mfb_paper_rows._runs`, the page's commands
    with ``--mc 0``), shared by the test files that read one of them (read only): ``"reversal"`` (the reversal on
    the simulated CMM, seed 1) and ``(name, kind)`` for ``name`` mfb-3axis and mfb-5axis, ``kind`` ``"declared"``
    (``run(name, seed=1, mc_runs=0)``), ``"reversal"`` (with the reversal's calibration, through its file) and
    ``"k1"`` (``u_cal_um=(0.4, 0.7, 0.7)``). Seven simulations of about 2 s of CPU each, two of which
    tests/scenarios/test_mfb_log_route.py and test_mfb_scenario.py ran again (session 38)."""
    from scenarios import mfb_paper_rows

    return mfb_paper_rows._runs()

