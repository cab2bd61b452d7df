"""The CLI's language, session 26 (review26): one meaning per option, honest Monte Carlo sizes.

In-process through ``scenarios.cli.main`` (exit status 2 and one line on stderr for bad input).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from scenarios.cli import main


def one_error_line(capsys, start: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(start), err
    return err


def campaign(path, angles, rng):
    """The cross-pocket's 92 targets at ``angles`` (deg) (the fuzz tests' campaign, every target)."""
    from core.probelog import write_probe_log
    from test_fuzz_cli import campaign_log

    return write_probe_log(path, campaign_log(rng, c_deg=tuple(float(c) for c in angles), every=1))


# --------------------------------------------------------------------------- 1. --mc: one minimum everywhere

MC_SAID = ("a Monte Carlo needs at least 10 runs (its U95 is read from the runs' spread: their 2.5 % and 97.5 % "
           "percentiles, or 2 std in identify)")


@pytest.mark.parametrize("cmd, n, zero", [
    # main ran these: --mc 1 gave U95 = 0 for every error (percentiles of one run), 9 a width of 9 runs
    (["scenario", "mfb-3axis"], 1, ", or --mc 0 (the linear propagation's U95 alone)"),
    (["scenario", "mfb-5axis"], 9, ", or --mc 0 (the linear propagation's U95 alone)"),
    # main: '--mc must be >= 10 for this study, got 3' (its own phrasing); 0 has no meaning there
    (["scenario", "cross-pocket-uncertainty"], 3, ""),
    (["scenario", "cross-pocket-uncertainty"], 0, ""),
    (["scenario", "mfb-3axis"], -1, ", or --mc 0 (the linear propagation's U95 alone)"),
])
def test_mc_below_the_minimum_is_refused_in_one_phrasing(tmp_path, capsys, cmd, n, zero):
    out = tmp_path / "r.json"
    assert main(cmd + ["--mc", str(n), "--json", str(out)]) == 2
    one_error_line(capsys, f"vmt scenario: error: --mc {n}: {MC_SAID}{zero}\n")
    assert not out.exists()


def test_identify_mc_below_the_minimum_names_the_option_not_the_log(tmp_path, rng, capsys):
    """main: 'vmt identify: error: LOG: runs must be >= 10, got 3' (after the identification, under the log's
    name); and --mc -1 said '--mc must be >= 0'. Now the one refusal of --mc, before any work."""
    log = campaign(tmp_path / "camp.csv", (0, 75, 130, 210), rng)
    out = tmp_path / "id.json"
    for n in (3, -1):
        assert main(["identify", str(log), "--json", str(out), "--mc", str(n)]) == 2
        one_error_line(capsys, f"vmt identify: error: --mc {n}: {MC_SAID}, or --mc 0 (none)\n")
        assert not out.exists()
    assert main(["identify", str(log), "--json", str(out), "--mc", "10", "--grid-mm", "22"]) == 0
    assert json.loads(out.read_text())["monte_carlo"]["runs"] == 10


def test_volumetric_uncertainty_refuses_a_monte_carlo_of_one_run():
    """core.volumetric.uncertainty(runs=1): U95_mc = 0 everywhere (2.5 and 97.5 percentiles of one value);
    now refused, 0 (linear only) and 10 taken."""
    from core.exceptions import ConfigError
    from scenarios import mfb as S

    r = S.run("mfb-3axis", noise_um=0.0, draw_inputs=False, mc_runs=0, declared_ripple=None)
    from core import volumetric as vol

    u_cal = np.full((12, 3), 1e-6)
    for runs in (1, 2, 9):
        with pytest.raises(ConfigError, match=f"runs {runs}: a Monte Carlo needs at least 10 runs"):
            vol.uncertainty(r.result, r.meas, 1e-7, u_cal, runs=runs, rng=np.random.default_rng(1))
    u10 = vol.uncertainty(r.result, r.meas, 1e-7, u_cal, runs=10, rng=np.random.default_rng(1))
    assert u10.runs == 10 and np.max(u10.U95_mc) > 0
    with pytest.raises(ConfigError, match="mc_runs 1: a Monte Carlo needs at least 10 runs"):
        S.run("mfb-3axis", mc_runs=1)


def test_mc_help_says_what_it_counts():
    """--mc, --budget-runs and --sobol-runs count different runs: the help says what each is."""
    import argparse

    from scenarios.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices
    helps = {(c, a.option_strings[0]): a.help for c in ("identify", "scenario", "vcmm")
             for a in sub[c]._actions if a.option_strings}
    for c in ("identify", "scenario"):
        assert "at least 10" in helps[(c, "--mc")] and "2.5-97.5" in helps[(c, "--mc")]  # (and 2 std: review30b F3)
        assert "in identify and scenario cross-pocket-uncertainty: 2 x the runs' std" in helps[(c, "--mc")]
    assert "simulates the campaign again" in helps[("scenario", "--budget-runs")]
    assert "runs per matrix" in helps[("vcmm", "--sobol-runs")]


# --------------------------------------------------------------------------- 3. the small ones

@pytest.mark.parametrize("cmd, said", [
    # main: --machine "" and --c-angles-deg "" fell back to the defaults (exit 0); --out "" said "'.': is a directory"
    (["simulate", "cross-pocket", "--out", "{d}/x.csv", "--machine", ""],
     "--machine '': empty; give a built-in machine name or a machine file (or leave --machine out)"),
    (["simulate", "cross-pocket", "--out", "{d}/x.csv", "--c-angles-deg", ""],
     "--c-angles-deg '': empty; give comma-separated C angles in degrees (or leave --c-angles-deg out)"),
    (["simulate", "cross-pocket", "--out", ""], "--out '': empty; give a file name"),
    (["scenario", "mfb-3axis", "--json", ""], "--json '': empty; give a file name"),
    (["scenario", "mfb-3axis", "--report", " "], "--report ' ': empty; give a folder name"),
])
def test_an_empty_value_is_refused_naming_it(tmp_path, capsys, cmd, said):
    assert main([a.format(d=tmp_path) for a in cmd]) == 2
    one_error_line(capsys, f"vmt {cmd[0]}: error: {said}\n")
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.parametrize("angles, said", [
    ("0,360", "C angles 0 and 360 deg are the same set-up (equal modulo 360): give each angle once"),
    ("0,90,-270", "C angles 90 and -270 deg are the same set-up (equal modulo 360)"),
    ("10,10", "C angles 10 and 10 deg are the same set-up"),
])
def test_c_angles_equal_modulo_360_are_refused(tmp_path, capsys, angles, said):
    """main took 0,360 as two set-ups (C0 and C360), and identify then reported a rank deficiency."""
    out = tmp_path / "x.csv"
    assert main(["simulate", "cross-pocket", "--out", str(out), "--c-angles-deg", angles]) == 2
    one_error_line(capsys, f"vmt simulate: error: {said}")
    assert not out.exists()


def test_no_c_axis_names_the_angle_not_the_argument(tmp_path, capsys):
    """main: 'c_angles_deg: machine 'vmc-3axis' has no C axis ...' (the function's argument)."""
    assert main(["simulate", "cross-pocket", "--machine", "vmc-3axis", "--out", str(tmp_path / "x.csv"),
                 "--c-angles-deg", "0,90"]) == 2
    one_error_line(capsys, "vmt simulate: error: C angle 90 deg: machine 'vmc-3axis' has no C axis "
                           "(rotary axes none); only 0 is possible\n")


def test_noise_of_identify_and_design_is_refused_in_one_phrasing(tmp_path, rng, capsys):
    """main: --noise-um -1 said 'must be a finite number >= 0', 0 said 'must be > 0' (identify.py, design.py)."""
    log = campaign(tmp_path / "camp.csv", (0, 75, 130, 210), rng)
    for cmd in (["identify", str(log), "--json", str(tmp_path / "i.json")],
                ["design", "--plan", str(log), "--n-angles", "3"]):
        for v in ("-1", "0"):
            assert main(cmd + ["--noise-um", v]) == 2
            one_error_line(capsys, f"vmt {cmd[0]}: error: --noise-um must be a finite number > 0, got {v}\n")


def test_delta_l_is_bounded(tmp_path, rng, capsys):
    """main identified with --delta-l-um 1e30 (exit 0)."""
    log = campaign(tmp_path / "camp.csv", (0, 75, 130, 210), rng)
    out = tmp_path / "i.json"
    for v in ("1e30", "-1001"):
        assert main(["identify", str(log), "--json", str(out), "--delta-l-um", v]) == 2
        one_error_line(capsys, "vmt identify: error: --delta-l-um must be within +-1000 um (the X positioning "
                               f"error at the last x node), got {float(v):g}\n")
    assert not out.exists()
    assert main(["identify", str(log), "--json", str(out), "--delta-l-um", "1000"]) == 0


def test_wrong_chain_machine_file_is_named_by_its_path(tmp_path, capsys):
    """main: '--machine 'nmv3000': chain ...' for /some/dir/mine.toml (the file's machine name)."""
    from pathlib import Path

    mine = tmp_path / "mine.toml"
    mine.write_text((Path(__file__).resolve().parents[2] / "sim" / "data" / "machines" / "nmv3000.toml").read_text())
    assert main(["scenario", "mfb-3axis", "--machine", str(mine)]) == 2
    one_error_line(capsys, f"vmt scenario: error: --machine {mine}: chain 'V[w-C-A-b-Y-X-Z-(C)-t]' is not the "
                           "mfb-3axis plan's")


def test_closed_loop_reports_progress(tmp_path, mfb_notes_skipped):
    """main's --apply-comp loop (about 5 s) drew no progress line: closed_loop now reports over its campaigns."""
    from scenarios import mfb as S

    r = S.run("mfb-3axis", mc_runs=0)
    r.write_comp(tmp_path / "comp")
    seen = []
    loop = S.closed_loop("mfb-3axis", tmp_path / "comp", before=r, mc_runs=0,
                         progress=lambda k, n: seen.append((k, n)))
    assert "volumetric" in loop and seen
    total = {n for _, n in seen}
    assert len(total) == 1 and seen[-1][0] == seen[-1][1]               # one total, reached at the end
    assert all(b[0] >= a[0] for a, b in zip(seen, seen[1:]))            # never backwards
    # each run counts in percent of its CPU (session 38): the touches simulated and fitted at 12, identified at
    # 43 (a count per measurement read 17 of 19 at 13 % of the run)
    runs = sum(1 for k, _ in seen if k % 100 == S.PROGRESS_SIMULATED)
    assert runs >= 1 and total == {100 * runs}
    assert {12, 43} == {S.PROGRESS_SIMULATED, S.PROGRESS_IDENTIFIED} <= {k % 100 for k, _ in seen}


# --------------------------------------------------------------------------- 2. what a state was identified on

@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    """A cross-pocket campaign simulated on nmv3000 (no errors) and identified by the CLI, its scale from a length
    measured along X (``--delta-l-um 0``: the X positioning error at the last node of a machine without errors):
    a state whose scale is unknown is refused for the block's lengths (session 37, test_vcmm_route37.py)."""
    d = tmp_path_factory.mktemp("ident")
    log, out = d / "cp.csv", d / "id.json"
    assert main(["simulate", "cross-pocket", "--out", str(log), "--errors", "none"]) == 0
    assert main(["identify", str(log), "--json", str(out), "--delta-l-um", "0"]) == 0
    return log, out


VCMM = ["vcmm", "--plan", "scenarios/data/vcmm-block-plan.csv", "--task", "scenarios/data/vcmm-block-task.toml",
        "--no-budget"]


def vcmm_state_task(tmp_path) -> list:
    """VCMM with the shipped block task less its "bore x": a position in the machine frame, which a state's
    gauge moves and vcmm refuses with --machine-state (session 38); the tests with a state are about its record."""
    from pathlib import Path

    text = Path(VCMM[4]).read_text()
    bore_x = '[[measurands]]\nname = "bore x"\nquantity = "position"\nof = "bore"\naxis = "x"\n\n'
    assert bore_x in text
    task = tmp_path / "task-no-position.toml"
    task.write_text(text.replace(bore_x, ""))
    return VCMM[:4] + [str(task)] + VCMM[5:]


def test_identify_records_the_machine_chain_and_height(identified):
    from core.probelog import read_probe_log
    from core.state import read_estimate

    log, out = identified
    rec = json.loads(out.read_text())["estimate"]["identified_on"]
    lg = read_probe_log(log)
    used = lg.ok & (np.abs(lg.col("nz")) <= 0.01)
    z, t = lg.col("Z_mm")[used], lg.col("t_s")[used]
    # the campaign's time span too (session 34, review33a F8); the simulated log has no temp_*_C sensor
    assert not lg.temperature_columns() and t.max() > t.min() > -1
    assert rec == {"machine": "nmv3000", "chain": "V[w-C-A-b-Y-X-Z-(C)-t]", "probe_offsets_J_mm": None,
                   "z_mm": [round(float(z.min()), 9), round(float(z.max()), 9)],   # (rounded to 1e-9 mm)
                   "t_s": [round(float(t.min()), 6), round(float(t.max()), 6)]}
    assert read_estimate(out).identified_on == rec                  # read back as written


def test_a_state_on_another_machine_or_chain_is_refused(identified, tmp_path, capsys):
    """main: 'vmt vcmm --machine vmc-3axis --machine-state id.json' took a state identified on nmv3000 (exit 0)."""
    _, ident = identified
    out = tmp_path / "v.json"
    capsys.readouterr()
    assert main(VCMM + ["--machine", "vmc-3axis", "--json", str(out), "--machine-state", str(ident)]) == 2
    err = one_error_line(capsys, f"vmt vcmm: error: --machine-state {ident}: identified on machine 'nmv3000', "
                                 "chain V[w-C-A-b-Y-X-Z-(C)-t], Z ")
    assert "not on machine 'vmc-3axis' (chain V[w-X-Y-b-Z-(C)-t]): another structure" in err
    # the same chain, another machine's name: refused too
    doc = json.loads(ident.read_text())
    doc["estimate"]["identified_on"]["machine"] = "my-nmv"
    other = tmp_path / "other.json"
    other.write_text(json.dumps(doc))
    assert main(VCMM + ["--machine", "nmv3000", "--json", str(out), "--machine-state", str(other)]) == 2
    err = one_error_line(capsys, f"vmt vcmm: error: --machine-state {other}: identified on machine 'my-nmv'")
    assert "not on machine 'nmv3000': identify this machine, or name the one it was identified on" in err
    assert not out.exists()


def test_a_state_without_the_record_reads_with_a_notice(identified, tmp_path, capsys):
    """A state file written before session 26 (no ``identified_on``) is applied with a notice, and the run
    completes. At a loose Monte Carlo tolerance (--tol-um 1: 0.9 s of CPU against 5.9 s at the default,
    session 27): the subject is the notice and the state read; the full run with a state at the default
    tolerance is tests/scenarios/test_vcmm_state.py's."""
    _, ident = identified
    doc = json.loads(ident.read_text())
    del doc["estimate"]["identified_on"]
    old = tmp_path / "old.json"
    old.write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(vcmm_state_task(tmp_path) + ["--machine", "vmc-3axis", "--json", str(tmp_path / "v.json"),
                                             "--machine-state", str(old), "--tol-um", "1"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{old}: no record of the machine it was identified on (a file written before session "
                          "26): applied to vmc-3axis unchecked\n"), out


@pytest.mark.parametrize("rec, key", [
    ("x", "identified_on: expected an object"),
    ({"machine": 3}, "identified_on.machine: expected a string or null"),
    ({"probe_offsets_J_mm": [[0, 0]]}, "identified_on.probe_offsets_J_mm"),
    ({"z_mm": [5, 1]}, "identified_on.z_mm"),
])
def test_a_bad_record_is_refused_by_key(identified, rec, key):
    from core.state import StateFileError, loads_estimate

    doc = json.loads(identified[1].read_text())
    doc["estimate"]["identified_on"] = rec
    with pytest.raises(StateFileError, match=key):
        loads_estimate(doc)


def test_identify_records_the_tool_offsets_given_and_vcmm_checks_them(identified, tmp_path, capsys):
    """A self-calibrated state's tables are the tool's X/Y deviation with the probe it was identified with
    (the angular errors through its arm), so its offsets J matter where it is applied. vmt identify
    --tool-offset-mm records them (a log without a tool_offset_mm line says no J); vmt vcmm applies the state
    with the same tool quietly, refuses another tool in one line (exit 2), and says so when the record has none
    (null).

    The runs that go through take --tol-um 1 (session 35; the subject is the check and the notice, made before
    any run: 14 -> 1.5 s CPU each at 1 um), as the record-less test above."""
    log, ident = identified
    out = tmp_path / "id.json"
    assert main(["identify", str(log), "--json", str(out), "--tool-offset-mm", "0,0,150", "--delta-l-um", "0"]) == 0
    assert json.loads(out.read_text())["estimate"]["identified_on"]["probe_offsets_J_mm"] == [[0.0, 0.0, 150.0]]
    capsys.readouterr()
    v = tmp_path / "v.json"
    assert main(vcmm_state_task(tmp_path) + ["--machine", "nmv3000", "--json", str(v), "--machine-state", str(out),
                                             "--tol-um", "1"]) == 0
    said = capsys.readouterr().out                                           # nmv3000's tool: [0, 0, 150] mm
    # no notice of the state's check: the one line naming probe offsets is the J the runs used (session 37)
    assert [ln for ln in said.splitlines() if "probe offsets" in ln] == [
        "probe offsets J = (0, 0, 150) mm, from the machine's [tool] offset_mm: the runs at the axis positions "
        "reading + J"], said
    assert main(["identify", str(log), "--json", str(out), "--tool-offset-mm", "0,0,100", "--delta-l-um", "0"]) == 0
    capsys.readouterr()
    v.unlink()
    assert main(VCMM + ["--machine", "nmv3000", "--json", str(v), "--machine-state", str(out)]) == 2
    err = one_error_line(capsys, f"vmt vcmm: error: --machine-state {out}: identified with probe offsets J "
                                 "(0, 0, 100) mm, not with this machine's tool offsets (0, 0, 150) mm")
    assert "identify with this probe" in err and not v.exists()
    # without the option (the fixture's state): null, applied with a notice naming what is unchecked
    assert main(vcmm_state_task(tmp_path) + ["--machine", "nmv3000", "--json", str(v), "--machine-state", str(ident),
                                             "--tol-um", "1"]) == 0
    assert (f"{ident}: the probe offsets J it was identified with are not recorded (vmt identify "
            "--tool-offset-mm): its tables, the tool's X/Y deviation with that probe, applied with the tool "
            "offsets (0, 0, 150) mm unchecked (its nodes, at the readings, placed at reading + these offsets)\n"
            ) in capsys.readouterr().out


@pytest.mark.parametrize("value, why", [
    ("0,150", "expected X,Y,Z, three finite numbers, mm"),      # the words of every command that takes it
    ("0,0,nan", "expected X,Y,Z, three finite numbers, mm"),
    ("0,0,x", "expected X,Y,Z, three finite numbers, mm"),
    ("0,0,1e6", "beyond 100000 mm, no probe's offset"),
])
def test_identify_refuses_a_bad_tool_offset_in_one_line(identified, tmp_path, capsys, value, why):
    log, _ = identified
    out = tmp_path / "id.json"
    capsys.readouterr()
    assert main(["identify", str(log), "--json", str(out), f"--tool-offset-mm={value}"]) == 2
    err = one_error_line(capsys, f"vmt identify: error: --tool-offset-mm {value!r}: ")
    assert why in err and not out.exists()


def test_an_mfb_state_applies_with_any_tool():
    """An MFB state (z_mm null) holds the axes' own errors, angular ones included: no probe check."""
    from types import SimpleNamespace

    from core.state import probe_offsets_check

    mfb = SimpleNamespace(source="m.json", identified_on={"machine": "vmc-3axis", "chain": "V[w-X-Y-b-Z-(C)-t]",
                                                          "probe_offsets_J_mm": [[0, 0, 150]], "z_mm": None})
    assert probe_offsets_check(mfb, (0.0, 0.0, 90.0)) == (None, None)
    planar = SimpleNamespace(source="s.json", identified_on={**mfb.identified_on, "z_mm": [27.0, 27.0]})
    assert probe_offsets_check(planar, (0.0, 0.0, 150.0005)) == (None, None)        # within J_SAME_MM
    assert probe_offsets_check(planar, (0.0, 0.0, 150.002))[0].startswith("identified with probe offsets J (0, 0, 150)")
    assert probe_offsets_check(SimpleNamespace(source="o.json", identified_on=None), (0, 0, 1)) == (None, None)


def test_the_mfb_records_its_machine_and_styli(mfb_notes_skipped):
    from core.state import loads_estimate
    from scenarios import mfb as S

    r = S.run("mfb-3axis", mc_runs=0)
    rec = r.doc["estimate"]["identified_on"]
    assert rec["machine"] == "vmc-3axis" and rec["chain"] == "V[w-X-Y-b-Z-(C)-t]" and rec["z_mm"] is None
    J = {tuple(j) for j in rec["probe_offsets_J_mm"]}
    assert J == {tuple(round(v * 1e3, 9) for v in m.J_m) for m in r.plan.measurements} and (0.0, 0.0, 150.0) in J
    assert loads_estimate(json.loads(json.dumps(r.doc))).identified_on == rec


# --------------------------------------------------------------------------- 4. plan grid's usage line

def test_plan_grid_usage_shows_the_stylus_radius_required(capsys):
    """main: 'usage: vmt plan grid ... [--stylus-r-mm STYLUS_R_MM] ...' (optional brackets) though it is refused
    without it; the refusal stays the command's own words (the usage shows it like --x-mm)."""
    import re

    with pytest.raises(SystemExit):
        main(["plan", "grid", "--help"])
    usage = capsys.readouterr().out.split("\n\n")[0]
    assert re.search(r"(?<!\[)--stylus-r-mm STYLUS_R_MM(?!\])", usage) and "[--stylus-r-mm" not in usage, usage
    assert "[--z-mm Z_MM]" in usage                                          # an optional one keeps its brackets
    assert main(["plan", "grid", "--x-mm", "0:10:5", "--y-mm", "0:10:5", "--out", "/nonexistent/p.csv"]) == 2
    one_error_line(capsys, "vmt plan grid: error: no stylus radius (the plan's nominal tip centres stand one "
                           "radius above the surface): give --stylus-r-mm R")
    with pytest.raises(SystemExit):
        main(["plan", "grid", "--help"])
    assert "[--stylus-r-mm" not in capsys.readouterr().out                  # (restored after each formatting)


def test_noise_free_mfb_run_says_no_u95_instead_of_nan(capsys, tmp_path, mfb_notes_skipped):
    """'vmt scenario mfb-3axis --noise-um 0 --mc 0' with a bar calibration of u 0 computes no uncertainty: the
    max U95 column printed nan (review28); now 'n/a' in every row and one line saying why. Noise-free with the
    default calibration u (session 29): the calibration's U95, linear, and a line saying so. With noise,
    numbers and no such line."""
    import json as _json

    from scenarios.mfb import BAR_CALIBRATION_FORMAT
    from sim.artefacts import mfb_default_deviations

    cal = tmp_path / "cal-u0.json"
    cal.write_text(_json.dumps({"format": BAR_CALIBRATION_FORMAT, "E_um": (mfb_default_deviations() * 1e6).tolist(),
                                "u_um": [[0.0, 0.0, 0.0]] * 12, "x_mm": [50.0 * i for i in range(12)]}))
    assert main(["scenario", "mfb-3axis", "--noise-um", "0", "--mc", "0", "--bar-calibration", str(cal)]) == 0
    out = capsys.readouterr().out
    assert "nan" not in out
    lines = out.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("error ") and "max U95" in ln)
    rows = lines[head + 1:head + 22]
    assert len(rows) == 21 and all(ln.split()[-1] == "n/a" for ln in rows), rows
    assert sum(ln.startswith("max U95 n/a: no uncertainty computed") for ln in lines) == 1
    assert main(["scenario", "mfb-3axis", "--noise-um", "0", "--mc", "0"]) == 0   # the calibration's u: its U95
    out = capsys.readouterr().out
    lines = out.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("error ") and "max U95" in ln)
    assert all(float(ln.split()[-1]) > 0 for ln in lines[head + 1:head + 22])
    assert "n/a" not in out and "nan" not in out
    assert sum(ln.startswith("U95 (linear propagation (JCGM 100 eq. 13), k = 2) of bar calibration alone: a "
                             "noise-free run") for ln in lines) == 1
    assert main(["scenario", "mfb-3axis", "--mc", "0"]) == 0             # the default noise: linear U95
    out = capsys.readouterr().out
    lines = out.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("error ") and "max U95" in ln)
    assert all(float(ln.split()[-1]) > 0 for ln in lines[head + 1:head + 22])
    assert "n/a" not in out and "nan" not in out and "noise-free run" not in out
