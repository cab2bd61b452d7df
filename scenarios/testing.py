"""The regression check in your own pytest suite: ``assert_recovers`` and a fixture.

The same check as ``vmt regress`` (:mod:`scenarios.regress`), as a plain
assertion::

    # tests/test_my_machine.py
    from scenarios.testing import assert_recovers

    def test_my_compensation_keeps_the_errors_recovered():
        assert_recovers("studies/my-machine-selfcal.toml")

On failure the :class:`AssertionError` names every failing quantity, the
seed, where, the deviation, the limit and the margin (one line each).

The fixture runs a study once per test session and hands you its
:class:`scenarios.regress.StudyResult` to assert on::

    # conftest.py
    from scenarios.testing import regress_study  # noqa: F401  (makes the fixture available)

    # test_x.py
    import pytest

    @pytest.mark.parametrize("regress_study", ["studies/nightly.toml"], indirect=True)
    def test_nightly(regress_study):
        assert regress_study.passed, regress_study.failures

``assert_recovers`` takes a path, a :class:`~scenarios.regress.Study` or
an already run :class:`~scenarios.regress.StudyResult`, and ``hook=``
(the documented place to change the identification,
:func:`scenarios.regress.run_study`).
"""

from __future__ import annotations

import pytest

from scenarios.regress import Study, StudyResult, load_study, run_study

_RESULTS: dict = {}


def recovered(study, *, hook=None) -> StudyResult:
    """Run ``study`` (a path or a :class:`Study`); an already run result is returned as is."""
    if isinstance(study, StudyResult):
        return study
    if not isinstance(study, Study):
        study = load_study(study)
    return run_study(study, hook=hook)


def failure_message(result: StudyResult) -> str:
    """What failed, one line per (quantity, seed): where, deviation, limit, margin."""
    f = result.failures
    head = (f"{result.study.name}: {len(f)} of {len(result.checks)} checks failed "
            f"({result.study.identification} on {result.study.machine.config.name})")
    return "\n".join([head] + [c.message() for c in f])


def assert_recovers(study, *, hook=None) -> StudyResult:
    """Assert that every quantity of ``study`` is recovered by its rule; return the result.

    Raises
    ------
    AssertionError
        Naming each failing quantity with its seed, the element, the
        deviation, the limit and the (negative) margin.
    scenarios.regress.StudyError
        A malformed study (bad input, not a failed check).
    """
    res = recovered(study, hook=hook)
    if not res.passed:
        raise AssertionError(failure_message(res))
    return res


@pytest.fixture(scope="session")
def regress_study(request) -> StudyResult:
    """The result of the study given as the fixture's parameter (a path), run once per session and path."""
    path = getattr(request, "param", None)
    if path is None:
        raise pytest.UsageError("regress_study: give the study file with "
                                "@pytest.mark.parametrize('regress_study', ['study.toml'], indirect=True)")
    key = str(path)
    if key not in _RESULTS:
        _RESULTS[key] = recovered(path)
    return _RESULTS[key]
