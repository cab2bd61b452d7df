"""Progress with time left inside each seed of ``vmt regress`` (session 38, cli38).

A shipped study has one or two seeds of 4-11 s each; the line counted seeds only, so it sat at ``0/1`` with no
time left until the run ended. ``run_study`` now reports the percent of the study done, each seed's own stages
inside its share.
"""

from pathlib import Path

import scenarios.regress as regress

ROOT = Path(__file__).resolve().parents[2]


def test_run_study_counts_each_seeds_stages_in_percent(monkeypatch):
    """Known answer: two seeds, a runner that says 1 of 4 then 4 of 4 of its work: 0, 12, 50 (seed 1 done),
    50 (seed 2 starts), 62, 100, 100 (the study done)."""
    study = regress.load_study(ROOT / "scenarios" / "data" / "regress-discover-none-nmv3000.toml")
    assert len(study.seeds) == 2

    def runner(st, seed, progress=None):
        progress(1, 4)
        progress(4, 4)
        return {"cause": regress.Causes(())}

    monkeypatch.setitem(regress.RUNNERS, study.identification, runner)
    calls = []
    regress.run_study(study, progress=lambda d, t: calls.append((d, t)))
    assert calls == [(0, 100), (12, 100), (50, 100), (50, 100), (62, 100), (100, 100), (100, 100)]


def test_a_runner_without_a_count_still_runs_without_progress(monkeypatch):
    """Runners are called as before (two arguments) when nobody asks for progress (the studies' own callers)."""
    study = regress.load_study(ROOT / "scenarios" / "data" / "regress-discover-none-nmv3000.toml")
    monkeypatch.setitem(regress.RUNNERS, study.identification, lambda st, sd: {"cause": regress.Causes(())})
    res = regress.run_study(study)
    assert len(res.seconds) == 2


def test_the_selfcal_runner_reports_its_stages(monkeypatch):
    """The self-calibration runner's stages at their measured shares (SEED_SHARES), in order (run_study says the
    seed's end)."""
    study = regress.load_study(ROOT / "scenarios" / "data" / "regress-selfcal-nmv3000.toml")
    calls = []
    regress.RUNNERS["selfcal"](study, study.seeds[0], progress=lambda d, t: calls.append((d, t)))
    assert [d for d, _ in calls][:3] == [0, *regress.SEED_SHARES["selfcal"][:2]]
    assert all(t == 100 for _, t in calls)


class _Terminal:
    """A stderr that says it is a terminal (the progress line draws only on one) and keeps what is drawn."""

    def __init__(self):
        self.text = ""

    def isatty(self):
        return True

    def write(self, s):
        self.text += s

    def flush(self):
        pass


def test_a_coverage_study_draws_its_progress_on_a_terminal_apart_from_its_lines(monkeypatch, capsys):
    """python -m scenarios.selfcal_coverage counted nothing for its minutes; now a line with the time left on stderr
    (a terminal only), erased before each printed result line, which stays on stdout alone."""
    import sys

    from scenarios import selfcal_coverage as sc

    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    assert sc.main(["--machines", "nmv3000", "--seeds", "20", "21", "--noise-um", "0", "--budget", "residuals"]) == 0
    out = capsys.readouterr().out
    assert "selfcal_coverage: campaigns: [" in term.text and "1/1 (100 %)  done in" in term.text, term.text
    assert "\r\033[K" in term.text                                  # erased before the result line
    assert out.startswith("nmv3000, 0 um, phase drawn, residuals: ") and "campaigns:" not in out, out


def test_a_studys_json_is_json_and_its_old_out_still_works(tmp_path, capsys):
    """The studies' JSON output is --json, as in every vmt command (it was --out, which is vmt's log, plan or
    program); --out still works, hidden, and says its new name in one line. Refused before any seed is run."""
    from scenarios import comprule_study as cs

    for old in (False, True):
        assert cs.main(["--machines", "none", "--seeds", "3", "3", "--out" if old else "--json", "x.json"]) == 2
        err = capsys.readouterr().err
        assert ("--out is renamed to --json" in err) == old and "HI must exceed LO" in err, err


def test_a_studys_bad_input_is_one_line(capsys):
    """The studies parse with vmt's own parser: a bad option is one line naming it, exit 2 (argparse's default
    printed the usage, three lines, above it)."""
    import pytest

    from scenarios import comprule_study, mfb_coverage, mfb_ripple_coverage, selfcal_coverage

    for mod, argv, says in ((comprule_study, ["--seeds", "x"], "argument --seeds: expected 2 arguments"),
                            (mfb_coverage, [], "required: study"),
                            (selfcal_coverage, ["--bogus"], "unrecognized arguments: --bogus"),
                            (mfb_ripple_coverage, ["nonsense"], "invalid choice: 'nonsense'")):
        with pytest.raises(SystemExit) as e:
            mod.main(argv)
        err = capsys.readouterr().err
        assert e.value.code == 2 and err.count("\n") == 1 and says in err and "Traceback" not in err, err
