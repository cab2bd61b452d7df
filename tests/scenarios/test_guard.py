"""The promises every command keeps (scenarios.cli.guard): one line and exit 2, nothing left behind."""

import io
import json
import os

import numpy as np
import pytest

from core.exceptions import VmtError
from core.probelog import make_log, write_probe_log
from scenarios.cli import main


@pytest.fixture(autouse=True)
def _figures_not_drawn(figures_not_drawn):
    """Every test here checks which files a command writes, keeps, puts back or refuses, and the
    messages, never a figure's pixels: the report figures are not drawn (conftest ``figures_not_drawn``;
    each written as a 1 x 1 PNG through the same atomic path, 0.2 s of CPU saved a figure, 2.3 s in all).
    The ISO 230-2 figure these reports carry is drawn and its pixels checked by
    tests/viz/test_positioning_figure.py, and drawn into a real report by
    tests/scenarios/test_iso230_2_cli.py; pin-circle's fig17 by tests/scenarios/test_paper_scenarios.py."""


@pytest.fixture
def files(tmp_path):
    cols = {"setup": ["a", "a", "b"], "target": ["1", "2", "1"], "t_s": [0, 1, 2],
            "X_mm": [1, 2, 3], "Y_mm": [0, 0, 0], "Z_mm": [0, 0, 0],
            "Xn_mm": [1, 2, 3], "Yn_mm": [0, 0, 0], "Zn_mm": [0, 0, 0],
            "nx": [1, 1, 1], "ny": [0, 0, 0], "nz": [0, 0, 0]}
    log = write_probe_log(tmp_path / "log.csv", make_log(cols))
    plan = make_log({**cols, **{c: [np.nan] * 3 for c in ("t_s", "X_mm", "Y_mm", "Z_mm")}})
    plan_p = write_probe_log(tmp_path / "plan.csv", plan)
    probe = tmp_path / "probe.txt"
    probe.write_text("1 0 0\n2 0 0\n3 0 0\n")
    return {"log": log, "plan": plan_p, "probe": probe, "dir": tmp_path}


def one_line(capsys, start):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(start), err
    return err


def test_unreadable_input_is_one_line(files, capsys, monkeypatch):
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, m: False if str(p) == str(files["log"]) else real(p, m))
    assert main(["check", str(files["log"])]) == 2
    one_line(capsys, f"vmt check: error: {files['log']}: cannot read: Permission denied")


def test_folder_given_as_input_or_output(files, capsys):
    d = files["dir"] / "sub"
    d.mkdir()
    assert main(["import", "linuxcnc", str(d), "--plan", str(files["plan"]), "--out", str(d / "x.csv")]) == 2
    one_line(capsys, f"vmt import: error: {d}: is a directory, not a file")
    assert main(["import", "linuxcnc", str(files["probe"]), "--plan", str(files["plan"]), "--out", str(d)]) == 2
    one_line(capsys, f"vmt import: error: {d}: is a directory, not a file")
    assert list(d.iterdir()) == []


def test_output_folder_that_cannot_be_written(files, capsys, monkeypatch):
    import tempfile

    def denied(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "TemporaryFile", denied)
    out = files["dir"] / "ro" / "x.csv"
    assert main(["import", "linuxcnc", str(files["probe"]), "--plan", str(files["plan"]), "--out", str(out)]) == 2
    one_line(capsys, f"vmt import: error: {out}: cannot write in {files['dir']}: Permission denied")
    assert not (files["dir"] / "ro").exists()


def test_devices_and_links_as_outputs(files, capsys):
    args = ["import", "linuxcnc", str(files["probe"]), "--plan", str(files["plan"]), "--out"]
    assert main(args + ["/dev/full"]) == 2
    one_line(capsys, "vmt import: error: cannot write /dev/full: No space left on device")
    assert not os.path.isfile("/dev/full")
    assert main(args + ["/dev/null"]) == 0
    assert "/dev/null (a character device: written through, not replaced)" in capsys.readouterr().out
    link = files["dir"] / "link.csv"
    link.symlink_to(files["dir"] / "target.csv")
    assert main(args + [str(link)]) == 2
    one_line(capsys, f"vmt import: error: {link}: is a symbolic link")
    assert link.is_symlink() and not (files["dir"] / "target.csv").exists()


def test_output_that_is_an_input_is_refused(files, capsys):
    before = files["plan"].read_bytes()
    assert main(["import", "linuxcnc", str(files["probe"]), "--plan", str(files["plan"]),
                 "--out", str(files["dir"] / "." / "plan.csv")]) == 2
    one_line(capsys, "vmt import: error: --out ")
    assert files["plan"].read_bytes() == before


@pytest.mark.parametrize("extra, msg", [
    (["--dt-s", "nan"], "--dt-s must be a positive number of seconds, got nan"),
    (["--dt-s", "-1"], "--dt-s must be a positive number of seconds, got -1"),
    (["--dt-s", "0"], "--dt-s must be a positive number of seconds, got 0"),
])
def test_import_dt_messages(files, capsys, extra, msg):
    out = files["dir"] / "o.csv"
    assert main(["import", "linuxcnc", str(files["probe"]), "--plan", str(files["plan"]),
                 "--out", str(out)] + extra) == 2
    one_line(capsys, f"vmt import: error: {msg}")
    assert not out.exists()


def test_design_step_zero_and_usage_errors_are_one_line(files, capsys):
    assert main(["design", "--plan", str(files["plan"]), "--n-angles", "4", "--step-deg", "0"]) == 2
    one_line(capsys, "vmt design: error: --step-deg must be > 0 and divide 360, got 0")
    with pytest.raises(SystemExit) as e:
        main(["design", "--plan", str(files["plan"]), "--n-angles", "four"])
    assert e.value.code == 2
    one_line(capsys, "vmt design: error: argument --n-angles: invalid int value: 'four' (see vmt design --help)")


def test_failed_run_leaves_no_output(files, capsys, monkeypatch):
    """A command that wrote its JSON and half a report, then failed: both removed, a file of
    the user's in the report's parent kept; Ctrl-C the same, exit 130."""
    import scenarios.cli.discover as cd

    keep = files["dir"] / "notes.txt"
    keep.write_text("mine")

    def half(log_path, json_out, report=None, grid_mm=None, progress=None, bar_calibration=None):
        from core.atomic import write_json_atomic

        write_json_atomic(json_out, {"baseline": {}})
        os.makedirs(report)
        (files["dir"] / ".rep.tmp123").mkdir()
        raise error

    monkeypatch.setattr(cd, "run_discover", half)
    for error, rc, start in ((VmtError("report: needs baseline.rms_um"), 2, "vmt discover: error: report"),
                             (KeyboardInterrupt(), 130, "vmt discover: interrupted")):
        assert main(["discover", str(files["log"]), "--json", str(files["dir"] / "d.json"),
                     "--report", str(files["dir"] / "rep")]) == rc
        one_line(capsys, start)
        assert sorted(p.name for p in files["dir"].iterdir()) == ["log.csv", "notes.txt", "plan.csv", "probe.txt"]


def test_os_error_inside_a_command_is_one_line(files, capsys, monkeypatch):
    import scenarios.cli.check as cc

    def boom(args):
        raise IsADirectoryError(21, "Is a directory", "/some/where")

    monkeypatch.setattr(cc, "run", boom)
    monkeypatch.setattr("scenarios.cli.check.run", boom)
    from scenarios.cli import build_parser
    from scenarios.cli.guard import run_command

    args = build_parser().parse_args(["check", str(files["log"])])
    args.func = boom
    assert run_command(args) == 2
    one_line(capsys, "vmt check: error: /some/where: Is a directory")


def test_check_reports_repeated_touches_and_a_possibly_torn_end(files, capsys):
    text = files["log"].read_text()
    dup = files["dir"] / "dup.csv"
    dup.write_text(text + text.splitlines()[-1].replace(",2,3,", ",3,3,", 1))   # no end of line
    assert main(["check", str(dup)]) == 0
    out = capsys.readouterr().out
    assert "repeated 1 touch repeats an earlier (setup, target) (1 pair, e.g. b/1 x2)" in out
    assert "warning  " in out and "may be cut short" in out
    assert main(["check", str(dup), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["repeated"]["touches"] == 1 and len(s["warnings"]) == 1


def test_progress_line_is_quiet_off_a_terminal_and_clears_on_one():
    from scenarios.cli.guard import progress_line

    bar = progress_line("x")
    assert not bar.enabled            # pytest's stderr is no terminal
    bar(1, 2)
    bar.clear()

    class Tty(io.StringIO):
        def isatty(self):
            return True

    bar.stream, bar.enabled = Tty(), True
    bar(1, 4)
    bar.clear()
    bar(2, 4)
    text = bar.stream.getvalue()
    assert text.count("\r\033[K") == 1 and text.endswith("2/4 ( 50 %)  ~" + text.split("~")[-1])
    assert "left" in text


MACHINE_TOML = 'format = "vmt-machine/1"\nname = "mine"\nbase = "vmc-3axis"\nerrors = "none"\n'


@pytest.mark.parametrize("cmd", [
    ["simulate", "cross-pocket", "--machine", "{f}", "--out", "{f}"],
    ["machine", "program", "--plan", "{plan}", "--machine", "{f}", "--safe-z-mm", "80", "--out", "{f}"],
    ["vcmm", "--plan", "scenarios/data/vcmm-block-plan.csv", "--task", "scenarios/data/vcmm-block-task.toml",
     "--machine", "{f}", "--json", "{f}"],
])
def test_machine_file_given_as_the_output_is_refused(files, capsys, cmd):
    """``--machine FILE`` is an input like any other: an output on the same path would replace the
    user's machine file with a probe log, a part program or a JSON report (main: all three ran and
    overwrote it, exit 0)."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    machine = files["dir"] / "mine.toml"
    machine.write_text(MACHINE_TOML)
    argv = [a.format(f=machine, plan=files["plan"]) for a in cmd]
    argv = [str(root / a) if a.startswith("scenarios/data/") else a for a in argv]
    assert main(argv) == 2
    err = one_line(capsys, f"vmt {' '.join(cmd[:2]) if cmd[0] == 'machine' else cmd[0]}: error: ")
    assert f"is the input --machine {machine}: refusing to overwrite an input" in err
    assert machine.read_text() == MACHINE_TOML


def test_bar_calibration_given_as_the_output_is_refused(files, capsys):
    """``scenario mfb-3axis --bar-calibration CAL --json CAL`` would replace the calibration it reads
    with the run's report (main: ran and overwrote it, exit 0)."""
    cal = files["dir"] / "cal.json"
    assert main(["scenario", "mfb-reversal", "--json", str(cal)]) == 0
    capsys.readouterr()
    before = cal.read_bytes()
    assert main(["scenario", "mfb-3axis", "--bar-calibration", str(cal), "--json", str(cal)]) == 2
    err = one_line(capsys, "vmt scenario: error: --json ")
    assert f"is the input --bar-calibration {cal}: refusing to overwrite an input" in err
    assert cal.read_bytes() == before


def test_a_built_in_machine_name_is_no_file_to_guard(files, capsys, monkeypatch):
    """The guard compares ``--machine`` with the outputs only when it names an existing file: a
    built-in name (no such file here) runs as before."""
    monkeypatch.chdir(files["dir"])
    assert main(["simulate", "cross-pocket", "--plan-only", "--machine", "nmv3000", "--out", "p.csv"]) == 0
    assert (files["dir"] / "p.csv").is_file()


@pytest.mark.parametrize("cmd", [["machine", "show", "{d}"], ["simulate", "cross-pocket", "--machine", "{d}",
                                                             "--out", "{o}"]])
def test_a_folder_given_as_the_machine_file_is_named_a_folder(files, capsys, cmd):
    """main said 'DIR: no such machine file' of a folder that exists; now what is wrong with it."""
    d = files["dir"] / "machines"
    d.mkdir()
    assert main([a.format(d=d, o=files["dir"] / "o.csv") for a in cmd]) == 2
    one_line(capsys, f"vmt {' '.join(cmd[:2]) if cmd[0] == 'machine' else cmd[0]}: error: "
                     f"{d}: is a directory, not a machine file")
    assert not (files["dir"] / "o.csv").exists()


@pytest.mark.parametrize("cmd, named", [
    (["regress", "{s}", "--junit", "{s}"], "STUDY"),
    (["design", "--plan", "{p}", "--n-angles", "3", "--json", "{p}"], "--plan"),
    (["vcmm", "--plan", "{p}", "--machine", "vmc-3axis", "--task", "t.toml", "--json", "{p}"], "--plan"),
])
def test_a_positional_input_is_named_as_the_usage_names_it(files, capsys, cmd, named):
    """main named these inputs '--study', '--plan': options the commands do not have."""
    study = files["dir"] / "s.toml"
    study.write_text('format = "vmt-study/1"\n')
    (files["dir"] / "t.toml").write_text('format = "vmt-task/1"\n')
    argv = [a.format(s=study, p=files["plan"]) for a in cmd]
    argv = [str(files["dir"] / a) if a == "t.toml" else a for a in argv]
    assert main(argv) == 2
    path = study if named == "STUDY" else files["plan"]
    err = one_line(capsys, f"vmt {cmd[0]}: error: ")
    assert f"is the input {named} {path}: refusing to overwrite an input" in err, err


def _heights(files):
    heights = files["dir"] / "h.csv"
    cols = {"setup": ["s"] * 4, "target": list("abcd"), "t_s": [0, 1, 2, 3],
            "X_mm": [0, 1, 0, 1], "Y_mm": [0, 0, 1, 1], "Z_mm": [0, 0.001, 0, 0.001],
            "Xn_mm": [0, 1, 0, 1], "Yn_mm": [0, 0, 1, 1], "Zn_mm": [0, 0, 0, 0],
            "nx": [0] * 4, "ny": [0] * 4, "nz": [1] * 4}
    return write_probe_log(heights, make_log(cols))


@pytest.mark.parametrize("cmd, starts", [
    (["plan", "grid", "--x-mm", "0:10:5", "--y-mm", "0:10:5", "--stylus-r-mm", "0", "--out", "-"],
     "# format: probe-log/1"),
    (["fit", "plane", "{heights}", "--stylus-r-mm", "0", "--json", "-"], "{"),
    (["import", "linuxcnc", "{probe}", "--plan", "{plan}", "--out", "-"], "# format: probe-log/1"),
])
def test_dash_is_standard_output_in_every_command(files, capfd, monkeypatch, cmd, starts):
    """'--json -' printed the JSON in 'vmt check' but made a file named '-' in every other command
    (main: exit 0, a file '-' in the working folder, nothing on stdout); now it is standard
    output everywhere, the messages on stderr."""
    monkeypatch.chdir(files["dir"])
    argv = [a.format(heights=_heights(files), probe=files["probe"], plan=files["plan"]) for a in cmd]
    capfd.readouterr()
    rc = main(argv)
    out, err = capfd.readouterr()
    assert rc == 0, err
    assert not (files["dir"] / "-").exists()
    assert out.startswith(starts), out[:200]
    if starts == "{":
        assert json.loads(out)["format"] == "vmt-fit/1"
    assert "/dev/stdout" in err          # the command's own message, on stderr

STDOUT_CASES = [
    (["fit", "plane", "{heights}", "--stylus-r-mm", "0", "--json", "/dev/stdout"], "{"),
    (["plan", "grid", "--x-mm", "0:10:5", "--y-mm", "0:10:5", "--stylus-r-mm", "0", "--out", "/dev/stdout"],
     "# format: probe-log/1"),
    (["simulate", "positioning", "--out", "/dev/stdout"], "# format: positioning-log/1"),
    (["iso230-2", "{sample}", "--json", "/dev/stdout"], "{"),
    (["iso230-2", "{sample}", "--json", "{dir}/s.json", "--write-log", "/dev/stdout"], "# format: positioning-log/1"),
    (["machine", "program", "--plan", "{plan}", "--out", "/dev/stdout", "--limits-mm", "X-9:9,Y-9:9,Z-9:99",
      "--safe-z-mm", "50"], "%"),
    (["vcmm", "--plan", "{vplan}", "--machine", "vmc-3axis", "--task", "{vtask}", "--no-budget", "--tol-um", "2",
      "--json", "/dev/stdout"], "{"),
]


@pytest.mark.parametrize("cmd, starts", STDOUT_CASES)
def test_dev_stdout_redirected_to_a_file_is_written_through(files, capfd, cmd, starts):
    """README: '--out /dev/stdout writes on standard output'. With standard output a file (here
    pytest's capture; 'vmt ... > f' alike) main refused these after the run: '/dev/stdout: is a
    symbolic link (to /proc/self/fd/1, a file): refusing to replace a link' (exit 2; vcmm after its
    whole Monte Carlo). identify, discover, simulate cross-pocket, import already wrote through."""
    from pathlib import Path

    data = Path(__file__).resolve().parents[2] / "scenarios" / "data"
    argv = [a.format(heights=_heights(files), plan=files["plan"], dir=files["dir"],
                     sample=data / "positioning-sample.csv", vplan=data / "vcmm-block-plan.csv",
                     vtask=data / "vcmm-block-task.toml") for a in cmd]
    capfd.readouterr()
    rc = main(argv)
    out, err = capfd.readouterr()
    assert rc == 0, err
    assert out.startswith(starts), out[:200]
    assert "Traceback" not in err


def test_bench_never_replaces_a_link_or_device(files, capfd, monkeypatch):
    """'vmt bench --out LINK' where LINK points to /dev/null: the guard lets a link to a device
    through (written through, README), but main's writer then renamed a temporary file over the
    link (as it would over /dev/null itself, run as root). Now written through, the link kept."""
    import scenarios.bench as sb

    monkeypatch.setattr(sb, "run_all", lambda only=None, **kw: {"format": sb.FORMAT, "meta": {}, "figures": {
        "x_s": {"value": 1.0}}})
    link = files["dir"] / "null-link"
    link.symlink_to("/dev/null")
    assert main(["bench", "--json", str(link)]) == 0, capfd.readouterr().err
    assert link.is_symlink() and os.readlink(link) == "/dev/null"
    out = files["dir"] / "r.json"
    assert main(["bench", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["figures"] == {"x_s": {"value": 1.0}}
    assert out.read_text() == json.dumps(json.loads(out.read_text()), indent=2, sort_keys=True)   # as before


@pytest.mark.parametrize("cmd, msg", [
    (["cross-pocket-uncertainty", "--noise-um", "0.5", "--mc", "10"],
     "--noise-um: cross-pocket-uncertainty does not take it (its probing u is the paper's 1.38 um)"),
    (["pin-circle", "--mc", "5"], "--mc: pin-circle does not take it"),
    (["mfb-reversal", "--mc", "5"], "--mc: mfb-reversal does not take it"),
    (["mfb-reversal", "--report", "{dir}/rr"], "--report: mfb-reversal does not take it"),
    # the mfb-only options in the same phrasing (main: '--comp: only the mfb scenarios take it (not pin-circle)')
    (["pin-circle", "--comp", "{dir}/rr"], "--comp: pin-circle does not take it; it is for mfb-3axis, mfb-5axis"),
    (["mfb-reversal", "--budget-runs", "3"],
     "--budget-runs: mfb-reversal does not take it; it is for mfb-3axis, mfb-5axis"),
])
def test_scenario_refuses_an_option_it_would_ignore(files, capsys, cmd, msg):
    """main ran these and ignored the option (cross-pocket-uncertainty printed 'u_probe 1.38 um'
    under --noise-um 0.5; mfb-reversal wrote no report; exit 0 each)."""
    assert main(["scenario"] + [a.format(dir=files["dir"]) for a in cmd]) == 2
    one_line(capsys, f"vmt scenario: error: {msg}")
    assert not (files["dir"] / "rr").exists()


def test_report_into_a_folder_of_the_users_files_is_refused_before_the_run(files, capsys, monkeypatch):
    """'vmt iso230-2 LOG --json J --report results/' where results/ holds the user's files: main ran,
    then replaced the folder whole (the files gone, exit 0). Now refused before the work, exit 2."""
    from pathlib import Path

    sample = Path(__file__).resolve().parents[2] / "scenarios" / "data" / "positioning-sample.csv"
    mine = files["dir"] / "results"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    j = files["dir"] / "s.json"
    assert main(["iso230-2", str(sample), "--json", str(j), "--report", str(mine)]) == 2
    one_line(capsys, f"vmt iso230-2: error: --report {mine}: exists and holds 1 entry but no report of vmt")
    assert (mine / "notes.txt").read_text() == "mine" and not j.exists()
    assert main(["iso230-2", str(sample), "--json", str(j), "--report", str(files["dir"] / "new")]) == 0
    assert main(["iso230-2", str(sample), "--json", str(j), "--report", str(files["dir"] / "new")]) == 0  # replaced


def _sample():
    from pathlib import Path

    return Path(__file__).resolve().parents[2] / "scenarios" / "data" / "positioning-sample.csv"


def test_a_folder_with_an_index_html_of_its_own_is_no_report(files, capsys):
    """Reviewer's case a): site/ holds index.html, thesis.tex and img/; main (b7ce9a1) took any folder
    with an index.html for an earlier report and replaced it whole (thesis.tex and img/ gone, exit 0)."""
    site = files["dir"] / "site"
    (site / "img").mkdir(parents=True)
    (site / "index.html").write_text("x\n")
    (site / "thesis.tex").write_text("precious\n")
    j = files["dir"] / "a.json"
    assert main(["iso230-2", str(_sample()), "--json", str(j), "--report", str(site)]) == 2
    one_line(capsys, f"vmt iso230-2: error: --report {site}: exists and holds 3 entries but no report of vmt")
    assert (site / "thesis.tex").read_text() == "precious\n" and (site / "img").is_dir() and not j.exists()


def test_a_users_file_in_an_earlier_report_is_never_swept_away(files, capsys):
    """Reviewer's case b): rep/ an earlier report plus the user's mylog.csv, given as the input: main
    replaced rep/ whole after reading it (the input log gone, exit 0). Refused before the run, as
    is an earlier report to which the user added a file."""
    import shutil

    rep, j = files["dir"] / "rep", files["dir"] / "c.json"
    assert main(["iso230-2", str(_sample()), "--json", str(j), "--report", str(rep)]) == 0
    capsys.readouterr()
    shutil.copy(_sample(), rep / "mylog.csv")
    j.unlink()
    assert main(["iso230-2", str(rep / "mylog.csv"), "--json", str(j), "--report", str(rep)]) == 2
    one_line(capsys, f"vmt iso230-2: error: LOG {rep / 'mylog.csv'} lies in --report {rep}, a folder the "
                     "report replaces whole: the input would be lost")
    assert (rep / "mylog.csv").read_bytes() == _sample().read_bytes() and not j.exists()
    assert main(["iso230-2", str(_sample()), "--json", str(j), "--report", str(rep)]) == 2
    one_line(capsys, f"vmt iso230-2: error: --report {rep}: is an earlier report but also holds mylog.csv, "
                     "which the report did not write")
    assert (rep / "mylog.csv").exists() and not j.exists()
    (rep / "mylog.csv").unlink()
    assert main(["iso230-2", str(_sample()), "--json", str(j), "--report", str(rep)]) == 0   # replaced


@pytest.mark.parametrize("opt, name", [("--json", "inner.json"), ("--write-log", "log2.csv")])
@pytest.mark.parametrize("earlier", [True, False])
def test_an_output_inside_the_report_folder_is_refused_before_the_run(files, capsys, opt, name, earlier):
    """Reviewer's cases c) and d): '--json rep/inner.json --report rep' said 'wrote rep/inner.json'
    (exit 0) but the report then replaced rep/ whole, the file gone; with rep/ new, the run went to
    its end and then said 'holds 1 entries' (sic) 'but no index.html' (exit 2). Now refused before any work."""
    rep, j = files["dir"] / "rep", files["dir"] / "j.json"
    if earlier:
        assert main(["iso230-2", str(_sample()), "--json", str(j), "--report", str(rep)]) == 0
        j.unlink()
        before = sorted(p.name for p in rep.iterdir())
    capsys.readouterr()
    argv = ["iso230-2", str(_sample())] + ([] if opt == "--json" else ["--json", str(j)]) + [
        opt, str(rep / name), "--report", str(rep)]
    assert main(argv) == 2
    one_line(capsys, f"vmt iso230-2: error: {opt} {rep / name} lies in --report {rep}, a folder the report "
                     "replaces whole: the output would be lost")
    assert not (rep / name).exists() and not j.exists()
    if earlier:
        assert sorted(p.name for p in rep.iterdir()) == before
    else:
        assert not rep.exists()


def test_a_link_given_as_the_report_folder_is_refused_before_the_run(files, capsys):
    """README: a link given as an output is refused. main replaced '--report lnk' (a link to an earlier
    report) by a real folder after the run and left a stale '.lnk.XXXX.old' link (exit 0)."""
    rep, j = files["dir"] / "rep", files["dir"] / "j.json"
    assert main(["iso230-2", str(_sample()), "--json", str(j), "--report", str(rep)]) == 0
    j.unlink()
    capsys.readouterr()
    (files["dir"] / "lnk").symlink_to("rep")
    assert main(["iso230-2", str(_sample()), "--json", str(j), "--report", str(files["dir"] / "lnk")]) == 2
    one_line(capsys, f"vmt iso230-2: error: --report {files['dir'] / 'lnk'}: is a symbolic link (to rep)")
    assert (files["dir"] / "lnk").is_symlink() and not j.exists()
    assert not [p for p in files["dir"].iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("cmd, msg", [
    (["probe", "--controller", "virtual:", "--plan", "{plan}", "--out", "-", "--limits-mm", "X-9:9,Y-9:9,Z-9:9"],
     "vmt probe: error: --out -: '-' (standard output) cannot be it: the campaign log is appended to"),
    (["probe", "--controller", "virtual:", "--plan", "{plan}", "--out", "{dir}/p.csv", "--limits-mm",
      "X-9:9,Y-9:9,Z-9:9", "--transcript", "-"],
     "vmt probe: error: --transcript -: '-' (standard output) cannot be it: the transcript is appended"),
    (["iso230-2", "{sample}", "--json", "{dir}/j.json", "--report", "-"],
     "vmt iso230-2: error: --report -: names a folder, and '-' (standard output) is for an output file"),
    (["demo", "--out-dir", "-"], "vmt demo: error: --out-dir -: names a folder"),
    (["scenario", "mfb-3axis", "--comp", "-"], "vmt scenario: error: --comp -: names a folder"),
    (["bench", "--from-json", "{dir}/x.json", "--readme", "-"], "vmt bench: error: --readme -: '-' (standard "
                                                                   "output) cannot be it"),
])
def test_dash_where_it_cannot_be_standard_output_is_refused(files, capsys, monkeypatch, cmd, msg):
    """main (f8658e3) made '-' standard output for the guarded files only: 'probe --out -' made a log
    file named '-' (and --transcript - a transcript '-'), '--report -' and the other folder options
    made a folder named '-' (the guard skipped '-', so nothing was checked before the run)."""
    monkeypatch.chdir(files["dir"])
    argv = [a.format(plan=files["plan"], dir=files["dir"], sample=_sample()) for a in cmd]
    assert main(argv) == 2
    one_line(capsys, msg)
    assert not (files["dir"] / "-").exists() and not (files["dir"] / "p.csv").exists()


def test_bench_merge_refuses_an_output_it_cannot_read_back(files, capsys, monkeypatch):
    """'vmt bench --merge --out - | cat' hung on main: --merge read the figures to keep from --out (--json
    since session 32),
    here /dev/stdout, the pipe's writing end. Refused before any benchmark runs: --merge needs a
    regular file to read back."""
    import subprocess
    import sys
    from pathlib import Path

    import scenarios.bench as sb

    monkeypatch.setattr(sb, "run_all", lambda only=None, **kw: pytest.fail("a benchmark ran"))
    for out, kind in (("-", "symbolic link (standard output)"), ("/dev/null", "character device")):
        assert main(["bench", "--merge", "--json", out]) == 2
        one_line(capsys, f"vmt bench: error: --merge reads the figures to keep from --json, so --json must be a "
                         f"regular file; {'/dev/stdout' if out == '-' else out} is a {kind}")
    root = Path(__file__).resolve().parents[2]
    p = subprocess.run(f"{sys.executable} -m scenarios.cli bench --merge --json - | cat", shell=True, cwd=root,
                       capture_output=True, text=True, timeout=120,
                       env={**os.environ, "PYTHONPATH": str(root)})
    assert "--merge reads the figures to keep from --json" in p.stderr, p.stderr


def test_a_failed_run_puts_back_the_users_earlier_outputs(files, capsys, monkeypatch):
    """The reviewer's case: an existing j.json, 'iso230-2 S --json j.json --report rep' failing in its
    report: main exit 2 and j.json gone (RunOutputs removed a file the run had replaced: 'its old
    content was gone'). Now the earlier JSON and the earlier report are back as they were, also when
    the run fails after replacing the report, or on Ctrl-C; nothing hidden is left behind."""
    import scenarios.positioning as sp
    from core.exceptions import OutputError

    j, rep = files["dir"] / "j.json", files["dir"] / "rep"
    argv = ["iso230-2", str(_sample()), "--json", str(j), "--report", str(rep)]
    assert main(argv) == 0
    j.write_text('{"mine": 1}\n')                   # the user's earlier output, told apart from a new one
    page = (rep / "index.html").read_bytes()
    listing = sorted(p.name for p in files["dir"].iterdir())
    real = sp.positioning_report

    def fail_before(*a, **k):
        raise OutputError("report: disk full")

    def fail_after(*a, **k):
        real(*a, **k)
        raise error

    for fake, error, rc in ((fail_before, None, 2), (fail_after, OutputError("later: disk full"), 2),
                            (fail_after, KeyboardInterrupt(), 130)):
        monkeypatch.setattr(sp, "positioning_report", fake)
        capsys.readouterr()
        assert main(argv) == rc
        capsys.readouterr()
        assert j.read_text() == '{"mine": 1}\n'
        assert (rep / "index.html").read_bytes() == page
        assert sorted(p.name for p in files["dir"].iterdir()) == listing


def test_pin_circle_report_is_a_report_folder_like_every_other(files, capsys):
    """--report had two meanings: a report folder replaced whole, except in pin-circle, which added
    fig17.png into any folder (the guard exempted it by name: main ran 'pin-circle --report mine/'
    into a folder of the user's files, exit 0). Now pin-circle writes a report folder (index.html,
    fig17.png) and the guard's rule holds for it: a folder of the user's files is refused before the run."""
    mine = files["dir"] / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    assert main(["scenario", "pin-circle", "--report", str(mine)]) == 2
    one_line(capsys, f"vmt scenario: error: --report {mine}: exists and holds 1 entry but no report of vmt")
    assert sorted(p.name for p in mine.iterdir()) == ["notes.txt"]


@pytest.mark.parametrize("workers", [None, "2"])
def test_sigterm_puts_the_outputs_back_and_says_so_as_ctrl_c_does(tmp_path, workers):
    """review32d F6: SIGTERM to `vmt design` (timeout(1), a CI cancel, systemd) ended it with status -15, no
    word, and its pre-existing --json kept aside in a `.vmt-kept.keep.json.*` folder left behind. Every command
    now takes SIGTERM as Ctrl-C: the output put back, one line, status 143; with --workers the workers stop too."""
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    plan = tmp_path / "plan.csv"
    assert main(["simulate", "cross-pocket", "--plan-only", "--out", str(plan)]) == 0
    keep = tmp_path / "keep.json"
    keep.write_text("PRE-EXISTING\n")
    cmd = [sys.executable, "-m", "scenarios.cli", "design", "--plan", str(plan), "--n-angles", "4", "--json", str(keep)]
    proc = subprocess.Popen(cmd + (["--workers", workers] if workers else []), cwd=root, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": str(root)})
    try:
        t0 = time.monotonic()
        while not list(tmp_path.glob(".vmt-kept.keep.json.*")):   # the run has begun: its output is kept aside
            assert proc.poll() is None and time.monotonic() - t0 < 120, proc.communicate()
            time.sleep(0.05)
        # with --workers, the workers have started (a SIGTERM while one is being spawned leaves that child to end
        # by itself on a closed pipe, with a traceback of its own: the fresh clone's run under load met it once)
        children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children")
        while workers and children.exists() and len(children.read_text().split()) < int(workers) + 1:
            assert proc.poll() is None and time.monotonic() - t0 < 120, proc.communicate()
            time.sleep(0.05)
        time.sleep(0.5)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, err
    assert err.strip().splitlines()[-1] == "vmt design: terminated (SIGTERM)", err
    assert "Traceback" not in err
    assert keep.read_text() == "PRE-EXISTING\n" and not list(tmp_path.glob(".vmt-kept*"))


#: A command run through run_command whose work replaces its --out, then waits inside a nested
#: terminating_as_interrupt block (as vmt probe's around its campaign) and, when stopped, takes 10 ms to say
#: what it kept (vmt probe counts the rows on disk); after the command, 50 ms more before the process exits.
_TWO_SIGTERMS = """
import argparse, sys, time
from scenarios.cli.guard import run_command, terminating_as_interrupt

def work(args):
    with open(args.out, "w") as f:
        f.write("half-written")
    with terminating_as_interrupt():
        try:
            print("ready", flush=True)
            time.sleep(60)
        except KeyboardInterrupt as e:
            time.sleep(0.010)
            e.args = ("[7 of 9 rows in log.csv; continue with --resume]",)
            raise

rc = run_command(argparse.Namespace(command="simulate", func=work, out=sys.argv[1]))
time.sleep(0.050)
sys.exit(rc)
"""


def test_a_second_sigterm_neither_loses_the_line_nor_kills_the_process(tmp_path):
    """review35 F1: GNU timeout(1) sends SIGTERM to the command and then to its process group, so the command
    can get it twice. terminating_as_interrupt raised on every SIGTERM and put the default action back when its
    block ended: a second SIGTERM 1-20 ms after the first raised a fresh interrupt inside the first one's
    cleanup (vmt probe's '[N of M rows in LOG; continue with --resume]' lost) or killed the process (-15).
    Now the first one is the interrupt and later ones are ignored: over ten runs, a second SIGTERM 1 to 19 ms
    after the first (in the 10 ms cleanup for the first five, after the command's block for the others), the
    line with its note every time, exit 143, the replaced output put back. About 0.5 s a run (Python's start)."""
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    out = tmp_path / "out.txt"
    for gap_ms in range(1, 20, 2):
        out.write_text("PRE-EXISTING\n")
        proc = subprocess.Popen([sys.executable, "-c", _TWO_SIGTERMS, str(out)], cwd=root, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": str(root)})
        try:
            assert proc.stdout.readline() == "ready\n", proc.communicate()
            proc.send_signal(signal.SIGTERM)
            time.sleep(gap_ms / 1000)
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
        said = (gap_ms, proc.returncode, err)
        assert proc.returncode == 143, said
        assert err == "vmt simulate: terminated (SIGTERM) [7 of 9 rows in log.csv; continue with --resume]\n", said
        assert out.read_text() == "PRE-EXISTING\n" and not list(tmp_path.glob(".vmt-kept*")), said
