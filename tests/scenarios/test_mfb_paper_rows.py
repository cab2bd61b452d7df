"""docs/papers-mfb.md's seed-1 figures of the Figs. 15-17 rows, of section 3's Figs. 9-10 rows and of
the reversal / declared table are today's runs (session 31, review31b F2: the rows had been typed by
hand and had gone stale, EAX 6.7 / 8.8 urad where the runs gave 1.64 / 3.01, "within 0.64" where
EXX's error exceeded its U95). scenarios.mfb_paper_rows makes them from the page's commands
(``vmt scenario mfb-reversal``, ``mfb-3axis|mfb-5axis --mc 0`` with and without the reversal's
calibration, seed 1); every cell it prints must be on the page, to its printed digits."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_pages_seed_1_figures_are_the_scripts(mfb_seed1_runs):
    """The runs are the script's own (``mfb_paper_rows._runs()``, computed once for the session by the conftest's
    ``mfb_seed1_runs``, which test_mfb_log_route.py and test_mfb_scenario.py read too)."""
    from scenarios import mfb_paper_rows

    doc = (ROOT / "docs" / "papers-mfb.md").read_text(encoding="utf-8")
    cells = mfb_paper_rows.cells(mfb_seed1_runs)
    assert len(cells) == 16
    # the k = 1 reading is quoted in the page's prose, cut at its line breaks: compare its figures
    k1 = cells.pop("k1").split("seed 1: ", 1)[1]
    assert k1 in " ".join(doc.split()), k1
    missing = {k: v for k, v in cells.items() if v not in doc}
    assert not missing, missing


def test_help_runs_nothing_and_arguments_are_refused(capsys):
    """``--help`` printed nothing and ran the 30 s study (cmds36); now it prints the docstring, and an argument the
    study does not take is refused with exit 2, both before any run."""
    from scenarios import mfb_paper_rows

    assert mfb_paper_rows.main(["--help"]) == 0
    assert "seed-1 figures" in capsys.readouterr().out
    assert mfb_paper_rows.main(["--seed", "2"]) == 2
    err = capsys.readouterr().err
    assert "takes no arguments" in err and err.count("\n") == 1
