"""The CLI's leftovers of session 25: errors that name their file, progress with the time left, the
folders a run makes said, counts in the right number.

In-process through ``scenarios.cli.main`` (exit status 2 and one line on stderr for bad input; the
process path of the same promise is tests/test_fuzz_cli.py's).
"""

from __future__ import annotations

import io

import numpy as np
import pytest

from core.probelog import make_log, write_probe_log
from scenarios.cli import main


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


# --------------------------------------------------------------------------- identify names its log

def campaign(path, angles, rng):
    """The cross-pocket's 92 targets at ``angles`` (deg), read off a machine with a squareness (the fuzz tests'
    campaign, every target)."""
    from test_fuzz_cli import campaign_log

    return write_probe_log(path, campaign_log(rng, c_deg=tuple(float(c) for c in angles), every=1))


@pytest.mark.parametrize("angles, grid, said", [
    # C = 0 and 180 deg: a half turn maps the pocket onto itself, the design is rank deficient
    ((0, 180), "20", "rank deficient by"),
    # a 2 mm grid: more unknowns than equations (eq 6 of Ibaraki et al.)
    ((0, 75, 130, 210), "2", "eq 6 needs"),
])
def test_identify_design_errors_name_the_log(tmp_path, rng, capsys, angles, grid, said):
    """They said 'vmt identify: error: rank deficient by 31 ...' with no file (session 25)."""
    log = campaign(tmp_path / "camp.csv", angles, rng)
    out = tmp_path / "id.json"
    assert main(["identify", str(log), "--json", str(out), "--grid-mm", grid]) == 2
    err = one_error_line(capsys)
    assert err.startswith(f"vmt identify: error: {log}: ") and said in err, err
    assert not out.exists()


# --------------------------------------------------------------------------- fit names its log

def ring_log(path, z_mm=(0.0,), r_mm=10.0, n=12, feature="ring"):
    """Touches around a circle of radius ``r_mm`` in XY at each height of ``z_mm`` (outside, radial normals)."""
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    rows = [(r_mm * np.cos(t), r_mm * np.sin(t), z, np.cos(t), np.sin(t)) for z in z_mm for t in a]
    x, y, z, nx, ny = (np.array(v) for v in zip(*rows))
    k = len(x)
    cols = {"setup": ["S1"] * k, "target": [f"t{i}" for i in range(k)], "t_s": np.arange(k, dtype=float),
            "X_mm": x, "Y_mm": y, "Z_mm": z, "Xn_mm": x, "Yn_mm": y, "Zn_mm": z, "nx": nx, "ny": ny,
            "nz": np.zeros(k), "feature": [feature] * k}
    return write_probe_log(path, make_log(cols, {"stylus_r_mm": "0"}))


def test_fit_error_names_the_log_and_the_rows(tmp_path, capsys):
    """'sphere fit: points are coplanar' said which data only as 'sphere fit' (session 25)."""
    log = ring_log(tmp_path / "ring.csv")
    assert main(["fit", "sphere", str(log)]) == 2
    err = one_error_line(capsys)
    assert err.startswith(f"vmt fit: error: {log}: sphere fit: ") and "coplanar" in err, err
    assert main(["fit", "sphere", str(log), "--feature", "ring", "--setup", "S1"]) == 2
    err = one_error_line(capsys)
    assert err.startswith(f"vmt fit: error: {log} (--feature ring --setup S1): sphere fit: "), err


def square_log(path):
    """A square section, 20 mm a side, touched on its four faces at two heights: it lies about
    equally well on cylinders about X, Y and Z."""
    s = np.linspace(-10, 10, 5)
    rows = [p for z in (0.0, 20.0) for v in s
            for p in ((10, v, z, 1, 0), (-10, v, z, -1, 0), (v, 10, z, 0, 1), (v, -10, z, 0, -1))]
    x, y, z, nx, ny = (np.array(v, float) for v in zip(*rows))
    k = len(x)
    cols = {"setup": ["S1"] * k, "target": [f"t{i}" for i in range(k)], "t_s": np.arange(k, dtype=float),
            "X_mm": x, "Y_mm": y, "Z_mm": z, "Xn_mm": x, "Yn_mm": y, "Zn_mm": z, "nx": nx, "ny": ny,
            "nz": np.zeros(k), "feature": ["block"] * k}
    return write_probe_log(path, make_log(cols, {"stylus_r_mm": "0"}))


def test_fit_cylinder_advice_is_an_option_of_the_command(tmp_path, capsys):
    """Touches that lie about equally well on cylinders of different axes: the library says 'pass
    axis_hint', an argument of a function no user of the command can give; the command says what
    it can do."""
    log = square_log(tmp_path / "square.csv")
    assert main(["fit", "cylinder", str(log)]) == 2
    err = one_error_line(capsys)
    assert "axis_hint" not in err and "cylinders with different axes" in err and str(log) in err, err
    assert err.rstrip().endswith("fit one cylinder's touches: --feature NAME"), err
    assert main(["fit", "cylinder", str(log), "--feature", "block"]) == 2
    err = one_error_line(capsys)
    assert "axis_hint" not in err and "touches around it at two or more heights)" in err, err
    # two rings fix it: a known answer, radius 10 mm about Z
    two = ring_log(tmp_path / "two.csv", z_mm=(0.0, 20.0))
    assert main(["fit", "cylinder", str(two)]) == 0
    out = capsys.readouterr().out
    assert "radius 10.0000 mm (outside)" in out and "axis (0.000000, 0.000000, 1.000000)" in out.replace("-0.0", "0.0")


class Tty(io.StringIO):
    def isatty(self):
        return True


def drawn_lines(tty) -> list[str]:
    return [s.rstrip() for s in tty.getvalue().split("\r") if s.strip()]


def terminal(monkeypatch) -> Tty:
    """Draw the commands' progress lines (scenarios.cli.guard.progress_line) on a fake terminal."""
    import scenarios.cli.guard as guard
    from viz.progress import TerminalProgress

    tty = Tty()
    monkeypatch.setattr(guard, "progress_line", lambda label: TerminalProgress(label, stream=tty, min_interval_s=0))
    return tty


def test_fit_shows_progress_with_time_left(tmp_path, capsys, monkeypatch):
    """vmt fit took 1-6 s on 2 busy cores on a 5,000-row log while its Student t imported scipy.stats, and a large
    log's read still takes seconds (16 us a line): the line shows the share of the work done while the log is read,
    then the time left, then done."""
    import core.probelog
    import scenarios.cli.fit as fit

    monkeypatch.setattr(core.probelog, "CHUNK_ROWS", 8)
    # the fit weighed as much as reading these 24 rows (0.12 s, 7,500 lines' worth, really): the read's
    # share is then seen in whole percent
    monkeypatch.setattr(fit, "FIT_S", 24 * fit.READ_S_PER_LINE)
    tty = terminal(monkeypatch)
    log = ring_log(tmp_path / "two.csv", z_mm=(0.0, 20.0))
    assert main(["fit", "cylinder", str(log)]) == 0
    drawn = drawn_lines(tty)
    assert all(d.startswith("fit: % of the work: [") for d in drawn), drawn
    shares = [int(d.split("] ")[1].split("/")[0]) for d in drawn]
    assert shares == sorted(shares) and shares[-1] == 100 and len(shares) >= 3, drawn
    assert any("left" in d for d in drawn[:-1]) and "done in" in drawn[-1], drawn
    assert tty.getvalue().endswith("\n")      # the line is ended before the result is printed
    assert "cylinder: 24 touches" in capsys.readouterr().out


def shares_of(drawn, label) -> list[int]:
    assert drawn and all(d.startswith(f"{label}: [") for d in drawn), drawn
    return [int(d.split("] ")[1].split("/")[0]) for d in drawn]


def test_simulate_shows_progress_with_time_left(tmp_path, capsys, monkeypatch):
    """vmt simulate ARTEFACT took 2-3 s wall on 2 busy cores with no line (session 25): the shares of
    scenarios.cli.simulate.SIMULATE_SHARES, the time left once the machine is built."""
    from scenarios.cli.simulate import SIMULATE_SHARES

    tty = terminal(monkeypatch)
    out = tmp_path / "cp.csv"
    assert main(["simulate", "cross-pocket", "--out", str(out), "--c-angles-deg", "0,90"]) == 0
    drawn = drawn_lines(tty)
    assert shares_of(drawn, "simulate cross-pocket: % of the work") == list(SIMULATE_SHARES)
    assert all("left" in d for d in drawn[:-1]) and "done in" in drawn[-1], drawn
    assert "campaign of 184 touches" in capsys.readouterr().out and out.exists()


def test_simulate_refused_option_draws_no_progress(tmp_path, capsys, monkeypatch):
    """An option refused before the work is the only line on the terminal (no half-drawn progress)."""
    tty = terminal(monkeypatch)
    assert main(["simulate", "cross-pocket", "--out", str(tmp_path / "p.csv"), "--plan-only",
                 "--errors", "none"]) == 2
    assert "--plan-only measures nothing" in one_error_line(capsys) and tty.getvalue() == ""


def test_iso230_2_report_shows_progress_with_time_left(tmp_path, capsys, monkeypatch):
    """vmt iso230-2 --report took 2-3 s wall on 2 busy cores (the plot) with no line."""
    from scenarios.positioning import REPORT_SHARES

    log = tmp_path / "pos.csv"
    assert main(["simulate", "positioning", "--out", str(log)]) == 0
    tty = terminal(monkeypatch)
    assert main(["iso230-2", str(log), "--json", str(tmp_path / "r.json"), "--report", str(tmp_path / "rep")]) == 0
    drawn = drawn_lines(tty)
    assert shares_of(drawn, "iso230-2: % of the work") == list(REPORT_SHARES)
    assert all("left" in d for d in drawn[:-1]) and "done in" in drawn[-1], drawn
    assert (tmp_path / "rep" / "index.html").exists()


# --------------------------------------------------------------------------- the folders a run makes

def test_folders_made_for_outputs_are_said_in_one_line(tmp_path, capsys):
    """Outputs in folders that did not exist: they were made silently (session 25); one line names
    each (the folder the output went in) with its option. An existing folder is not named."""
    log = ring_log(tmp_path / "two.csv", z_mm=(0.0, 20.0))
    out = tmp_path / "new" / "deeper" / "fit.json"
    assert main(["fit", "cylinder", str(log), "--json", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-2:] == [f"wrote {out}", f"made the folder {out.parent} (for --json {out})"]
    assert main(["fit", "cylinder", str(log), "--json", str(out)]) == 0     # the folder is there now
    assert "made the folder" not in capsys.readouterr().out


def test_folders_made_for_a_report_and_files_are_one_line(tmp_path, capsys):
    """iso230-2 with --json, --write-log and --report in three new folders: one line names the
    three; the report's folder is made as discover's is (it was refused after the work: 'report
    folder ...: parent folder does not exist', the JSON written and taken back)."""
    log = tmp_path / "pos.csv"
    assert main(["simulate", "positioning", "--out", str(log)]) == 0
    capsys.readouterr()
    j, w, r = tmp_path / "j" / "iso.json", tmp_path / "w" / "pos.csv", tmp_path / "r" / "sub" / "rep"
    assert main(["iso230-2", str(log), "--json", str(j), "--write-log", str(w), "--report", str(r)]) == 0
    last = capsys.readouterr().out.splitlines()[-1]
    assert last == (f"made the folders {j.parent} (for --json {j}); {w.parent} (for --write-log {w}); "
                    f"{r.parent} (for --report {r})"), last
    assert (r / "index.html").exists()


def test_failed_run_takes_back_the_folders_it_made(tmp_path, capsys):
    """The line is said of a run that succeeded; a failed one leaves no folder (guard's promise)."""
    log = ring_log(tmp_path / "ring.csv")
    out = tmp_path / "new" / "fit.json"
    assert main(["fit", "sphere", str(log), "--json", str(out)]) == 2
    assert "made the folder" not in capsys.readouterr().out and not (tmp_path / "new").exists()


def test_output_where_a_file_is_is_refused_before_the_work(tmp_path, capsys):
    """A file where the output's folder should be, or given as a report folder: exit 2, one line
    naming it, before any work (the shared checks of scenarios.cli.guard)."""
    log = ring_log(tmp_path / "two.csv", z_mm=(0.0, 20.0))
    f = tmp_path / "afile"
    f.write_text("mine\n")
    assert main(["fit", "cylinder", str(log), "--json", str(f / "x.json")]) == 2
    assert f"{f / 'x.json'}: cannot write there: {f} is a file, not a folder" in one_error_line(capsys)
    pos = tmp_path / "pos.csv"
    assert main(["simulate", "positioning", "--out", str(pos)]) == 0
    capsys.readouterr()
    assert main(["iso230-2", str(pos), "--json", str(tmp_path / "i.json"), "--report", str(f)]) == 2
    assert f"--report {f}: is a file, not a folder" in one_error_line(capsys)
    assert f.read_text() == "mine\n" and not (tmp_path / "i.json").exists()


@pytest.mark.parametrize("argv", [
    ["design", "--plan", "{plan}", "--n-angles", "3", "--step-deg", "30", "--json", "{out}"],
    ["scenario", "pin-circle", "--json", "{out}"],
])
def test_json_outputs_are_said(tmp_path, capsys, argv):
    """design --json and scenario pin-circle --json wrote their JSON without a word (session 25)."""
    out = tmp_path / "r.json"
    plan = cross_pocket_plan(tmp_path / "plan.csv") if "{plan}" in argv else None
    assert main([a.format(plan=plan, out=out) for a in argv]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == f"wrote {out}" and out.exists()


def cross_pocket_plan(path):
    from sim.campaign import simulate_campaign
    from sim.catalog import CATALOG
    from sim.machine import Machine
    from sim.machinefile import truth_machine

    spec = truth_machine(CATALOG["cross-pocket"].default_machine, "none")
    return write_probe_log(path, simulate_campaign("cross-pocket", Machine(spec.config), spec.probe, [0.0],
                                                   plan_only=True, check_collisions=False))


def test_design_error_names_the_plan(tmp_path, capsys):
    """'no choice of 2 C angles on a 90 deg grid identifies the workpiece' named no plan (session 25)."""
    plan = cross_pocket_plan(tmp_path / "plan.csv")
    assert main(["design", "--plan", str(plan), "--n-angles", "2", "--step-deg", "90"]) == 2
    err = one_error_line(capsys)
    assert err.startswith(f"vmt design: error: {plan}: no choice of 2 C angles"), err


# --------------------------------------------------------------------------- counts in the right number

def test_counted_known_answers():
    from core.exceptions import counted

    assert [counted(1, "entry"), counted(2, "entry"), counted(0, "entry")] == ["1 entry", "2 entries", "0 entries"]
    assert [counted(1, "touch"), counted(7, "touch"), counted(2, "field"), counted(3, "key")] == \
        ["1 touch", "7 touches", "2 fields", "3 keys"]
    assert [counted(1, "rotary axis", "rotary axes"), counted(2, "rotary axis", "rotary axes")] == \
        ["1 rotary axis", "2 rotary axes"]


def test_one_of_a_count_is_singular_in_messages(tmp_path, capsys):
    """'holds 1 entries', '1 numbers, expected 3', '1 fields, header has 20': the counts that can be
    one say it in the singular (session 25)."""
    pf = tmp_path / "probe.txt"
    pf.write_text("1 2 3\n5\n")
    assert main(["import", "linuxcnc", str(pf), "--out", str(tmp_path / "o.csv")]) == 2
    assert "line 2: 1 number, expected 3 (X Y Z)" in one_error_line(capsys)
    log = ring_log(tmp_path / "ring.csv")
    text = log.read_text().splitlines()
    (tmp_path / "short.csv").write_text("\n".join(text + ["S1"]) + "\n")
    assert main(["check", str(tmp_path / "short.csv")]) == 2
    assert "1 field, header has" in one_error_line(capsys)


# --------------------------------------------------------------------------- the sweep's findings

@pytest.mark.parametrize("argv, said", [
    # was: "measuring line must be 3 finite readings X, Y, Z, got array([nan, 0., 0.])" (a numpy repr)
    (["simulate", "positioning", "--out", "{tmp}/p.csv", "--line-mm", "nan,0,0"],
     "vmt simulate: error: --line-mm nan,0,0: expected three finite numbers X,Y,Z in mm"),
    # was: "C angle nan is not finite" (no option)
    (["simulate", "cross-pocket", "--out", "{tmp}/c.csv", "--c-angles-deg", "0,nan"],
     "vmt simulate: error: --c-angles-deg '0,nan': expected finite angles, deg"),
    # was: "time scale nan: expected a positive number" (no option)
    (["machine", "serve", "--port", "0", "--time-scale", "nan"],
     "vmt machine serve: error: --time-scale must be a finite number > 0, got nan"),
    (["machine", "serve", "--port", "0", "--time-scale", "inf"],
     "vmt machine serve: error: --time-scale must be a finite number > 0, got inf"),
    # was: "limits_mm ((nan, 300.0), (-300.0, 300.0), (-300.0, 300.0)): expected ((xmin, xmax), ..." (a field)
    (["machine", "program", "--plan", "{plan}", "--out", "{tmp}/p.ngc", "--limits-mm", "Xnan:300,Y-300:300,Z-300:300"],
     "vmt machine program: error: --limits-mm 'Xnan:300,Y-300:300,Z-300:300': 'Xnan:300': expected finite min < max"),
    (["machine", "program", "--plan", "{plan}", "--out", "{tmp}/p.ngc", "--limits-mm", "X300:0,Y-300:300,Z-300:300"],
     "vmt machine program: error: --limits-mm 'X300:0,Y-300:300,Z-300:300': 'X300:0': expected finite min < max"),
    # was: "row 23 (target 'wall03_2'): approach ... is outside the soft limits" (no plan named)
    (["machine", "program", "--plan", "{plan}", "--out", "{tmp}/p.ngc", "--limits-mm", "X0:300,Y-300:300,Z-300:300"],
     "vmt machine program: error: {plan}: row "),
])
def test_sweep_messages_name_the_option_or_file(tmp_path, capsys, argv, said):
    plan = cross_pocket_plan(tmp_path / "plan.csv") if any("{plan}" in a for a in argv) else None
    assert main([a.format(tmp=tmp_path, plan=plan) for a in argv]) == 2
    err = one_error_line(capsys)
    assert err.startswith(said.format(plan=plan)), err
    assert not list(tmp_path.glob("p.*")) and not (tmp_path / "c.csv").exists()


def test_every_report_finds_its_folder_made_by_one_place(tmp_path, capsys):
    """Session 26: a report's parent folder was made by some report writers (discover's, iso230-2's, vcmm's, each
    its own mkdir) and not by others: `vmt scenario pin-circle --report new/sub/rep` did its work, then failed
    'report folder ...: parent folder does not exist' (exit 2). The CLI now makes every output's missing folders
    before the run (scenarios.cli.guard.make_folders) and says them after it; the writers make none."""
    rep = tmp_path / "new" / "sub" / "rep"
    assert main(["scenario", "pin-circle", "--report", str(rep)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1] == f"made the folder {rep.parent} (for --report {rep})", out[-3:]
    assert (rep / "index.html").is_file()
    import inspect

    import scenarios.positioning
    import scenarios.reports
    import scenarios.vcmm

    for m in (scenarios.reports, scenarios.vcmm, scenarios.positioning):
        assert ".parent.mkdir(" not in inspect.getsource(m), m.__name__


def test_a_report_writer_without_its_folder_says_so(tmp_path):
    """Called as a library, a report writer whose parent folder is missing refuses it in write_report's words."""
    from core.exceptions import ConfigError
    from scenarios.reports import _recording_path

    with pytest.raises(ConfigError, match="parent folder does not exist"):
        _recording_path(tmp_path / "none" / "rep")
