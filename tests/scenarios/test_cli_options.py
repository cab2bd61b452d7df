"""The CLI speaks one language: one meaning per option name, units in the names, old names still working.

The walk reads every command's parser (``vmt`` and its sub-commands), so a new
option that breaks the rule fails here, not in a user's script.
"""

import argparse
import re

import pytest

from scenarios.cli import build_parser, main
from scenarios.cli.options import UNIT_SUFFIXES

#: The unit a help text states (``..., mm (2)``, ``..., µm/h``) -> the suffixes its option name may end with.
UNIT_NAMES = {"mm": ("-mm",), "mm/min": ("-mm-min",), "um": ("-um",), "µm": ("-um",),
              "µm/m": ("-um-per-m", "-ppm"), "µm/h": ("-um-per-h",), "urad": ("-urad",), "µrad": ("-urad",),
              "deg": ("-deg",), "s": ("-s",), "K": ("-k",), "1/K": ("-per-k",), "°C": ("-c",)}
_UNIT = re.compile(r",\s*(mm/min|µm/m|µm/h|mm|um|µm|µrad|urad|deg|1/K|K|°C|s)(?=$|[\s(:;,])")

#: float options that carry no quantity with a unit (a ratio)
DIMENSIONLESS = {"--time-scale"}

#: every old name kept as a hidden alias: (command words, old option, a value or None for a flag, new option)
RENAMED = [
    (["probe"], "--machine", "virtual:", "--controller"),
    (["probe"], "--home", None, "--home-cycle"),
    (["probe"], "--timeout", "5", "--timeout-s"),
    (["probe"], "--limits", "X0:1,Y0:1,Z0:1", "--limits-mm"),
    (["probe"], "--feed", "50", "--feed-mm-min"),
    (["probe"], "--move-feed", "500", "--move-feed-mm-min"),
    (["probe"], "--max-feed", "900", "--max-feed-mm-min"),
    (["probe"], "--clearance", "1", "--clearance-mm"),
    (["probe"], "--overtravel", "1", "--overtravel-mm"),
    (["probe"], "--safe-z", "80", "--safe-z-mm"),
    (["machine", "program"], "--limits", "X0:1,Y0:1,Z0:1", "--limits-mm"),
    (["machine", "serve"], "--home", "0,0,10", "--home-mm"),
    (["machine", "serve"], "--limits", "X0:1,Y0:1,Z0:1", "--limits-mm"),
    (["machine", "serve"], "--idle-timeout", "9", "--idle-timeout-s"),
    (["machine", "serve"], "--max-seconds", "9", "--stop-after-s"),
    (["simulate", "cross-pocket"], "--c-angles", "0,90", "--c-angles-deg"),
    (["simulate", "positioning"], "--move-feed", "900", "--move-feed-mm-min"),
    (["design", "plan.csv"], "--angles", "3", "--n-angles"),
    (["design", "plan.csv"], "--reference", "0,90", "--reference-deg"),
    (["design", "plan.csv"], "--u-probe-um", "1.1", "--noise-um"),
    (["identify", "log.csv"], "--u-probe-um", "1.1", "--noise-um"),
    (["discover", "log.csv"], "--grid-mm", "30", "--grid-step-mm"),
    (["import", "grbl", "t.txt"], "--dt", "2", "--dt-s"),
    (["demo"], "--out", "o", "--out-dir"),
]

#: what each command needs besides the option under test, to parse
REQUIRED = {"probe": ["--controller", "virtual:", "--plan", "p.csv", "--out", "o.csv"],
            "machine program": ["--plan", "p.csv", "--out", "o.ngc"], "machine serve": ["--port", "0"],
            "simulate": ["--out", "o.csv"], "design": ["--n-angles", "3"], "identify": ["--json", "o.json"],
            "discover": ["--json", "o.json"], "import": ["--out", "o.csv"]}


def _walk(p, path=("vmt",)):
    for a in p._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sp in a.choices.items():
                yield from _walk(sp, path + (name,))
        else:
            yield path, a


def _options():
    """{--name: [(command, action)]} of every visible long option of every command."""
    out = {}
    for path, a in _walk(build_parser()):
        if a.help == argparse.SUPPRESS:
            continue
        for o in a.option_strings:
            if o.startswith("--") and o not in ("--help", "--version"):
                out.setdefault(o, []).append((" ".join(path), a))
    return out


def _unit(help_text: str) -> str | None:
    m = _UNIT.search(help_text or "")
    return m.group(1) if m else None


def test_each_option_name_has_one_meaning_across_commands():
    opts = _options()
    assert len(opts) > 80                                  # the walk reached the sub-commands
    bad = []
    for name, uses in opts.items():
        kinds = {(type(a).__name__, getattr(a.type, "__name__", a.type)) for _c, a in uses}
        units = {_unit(a.help) for _c, a in uses}
        if len(kinds) > 1 or len(units) > 1:
            bad.append(f"{name}: {[(c, type(a).__name__, _unit(a.help)) for c, a in uses]}")
    assert not bad, "\n".join(bad)


def test_a_quantity_carries_its_unit_in_its_name():
    bad = []
    for name, uses in _options().items():
        for command, a in uses:
            unit = _unit(a.help)
            if unit is not None and not name.endswith(UNIT_NAMES[unit]):
                bad.append(f"{command} {name}: help says {unit!r}, the name does not end with {UNIT_NAMES[unit]}")
            if a.type is float and name not in DIMENSIONLESS and not name.endswith(UNIT_SUFFIXES):
                bad.append(f"{command} {name}: a number without a unit suffix {UNIT_SUFFIXES}")
    assert not bad, "\n".join(bad)


def test_the_rule_catches_a_unitless_quantity():
    """The checks above can fail: an option like the old ``--feed`` is caught."""
    p = argparse.ArgumentParser()
    a = p.add_argument("--feed", type=float, help="probing feed, mm/min (100)")
    assert _unit(a.help) == "mm/min" and not "--feed".endswith(UNIT_NAMES["mm/min"] + UNIT_SUFFIXES)
    assert _unit("longest wait, s (60)") == "s" and _unit("seed of the draws (0); same seed") is None


@pytest.mark.parametrize("words, old, value, new", RENAMED, ids=[f"{' '.join(r[0][:1])}{r[1]}" for r in RENAMED])
def test_an_old_option_name_still_works_and_says_its_new_name(words, old, value, new, capsys):
    parser = build_parser()
    cmd = " ".join(w for w in words if not w.endswith((".csv", ".txt")) and w not in ("cross-pocket", "positioning",
                                                                                      "grbl"))
    base = [*words, *REQUIRED.get(cmd, [])]
    if old == "--machine":
        base = [w for w in base if w not in ("--controller", "virtual:")]
    if new == "--n-angles":
        base = [w for w in base if w not in ("--n-angles", "3")]
    given = [old] if value is None else [old, value]
    now = [new] if value is None else [new, value]
    a_old = parser.parse_args(base + given)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{old} is renamed to {new}" in err
    a_new = parser.parse_args(base + now)
    assert capsys.readouterr().err == ""
    assert vars(a_old) == vars(a_new)


def test_probe_needs_a_controller_by_either_name(capsys):
    with pytest.raises(SystemExit) as e:
        main(["probe", "--plan", "p.csv", "--out", "o.csv"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "required: --controller" in err


def test_check_json_file_stdout_and_the_old_flag(tmp_path, capsys):
    import json

    from core.probelog import make_log, write_probe_log

    cols = {"setup": ["a", "b"], "target": ["1", "1"], "t_s": [0, 1], "X_mm": [1, 2], "Y_mm": [0, 0],
            "Z_mm": [0, 0], "Xn_mm": [1, 2], "Yn_mm": [0, 0], "Zn_mm": [0, 0], "nx": [1, 1], "ny": [0, 0],
            "nz": [0, 0], "C_deg": [0, 90]}
    log = str(write_probe_log(tmp_path / "ok.csv", make_log(cols)))
    out = tmp_path / "s.json"
    assert main(["check", log, "--json", str(out)]) == 0          # a file, as everywhere else
    cap = capsys.readouterr()
    assert json.loads(out.read_text())["touches"] == 2 and "touches  2 (2 ok)" in cap.out and cap.err == ""
    assert main(["check", log, "--json", "-"]) == 0                # '-': the JSON on stdout
    cap = capsys.readouterr()
    assert json.loads(cap.out)["touches"] == 2 and cap.err == ""
    for argv in (["check", log, "--json"], ["check", "--json", log]):   # the old flag, either order
        assert main(argv) == 0
        cap = capsys.readouterr()
        assert json.loads(cap.out)["touches"] == 2 and cap.err.count("\n") == 1 and "--json -" in cap.err


def test_simulate_positioning_noise_is_now_scatter(tmp_path, capsys):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["simulate", "positioning", "--targets", "5", "--cycles", "2", "--out", str(a),
                 "--noise-um", "0.3"]) == 0
    assert "renamed to --scatter-um" in capsys.readouterr().err
    assert main(["simulate", "positioning", "--targets", "5", "--cycles", "2", "--out", str(b),
                 "--scatter-um", "0.3"]) == 0
    assert capsys.readouterr().err == ""
    assert a.read_bytes() == b.read_bytes()
    assert main(["simulate", "positioning", "--out", str(b), "--noise-um", "0.3", "--scatter-um", "0.3"]) == 2


def test_naming_the_default_machine_is_omitting_it():
    """One rule: a built-in name carries realistic errors unless --errors none, whichever command reads it."""
    from scenarios.cli.options import machine_spec
    from sim.machinefile import resolve

    real, none = machine_spec("nmv3000"), machine_spec("nmv3000", "none")
    assert real.errors == "realistic" and real.config.errors and not none.config.errors
    assert machine_spec("nmv3000", "realistic").config.errors.keys() == real.config.errors.keys()
    assert none.config.chain == real.config.chain == resolve("nmv3000").config.chain


def test_machine_show_and_simulate_agree_on_a_built_in(tmp_path, capsys):
    assert main(["machine", "show", "vmc-3axis"]) == 0
    shown = capsys.readouterr().out
    assert "base set realistic" in shown and "\n  none\n" not in shown
    assert main(["machine", "show", "vmc-3axis", "--errors", "none"]) == 0
    assert "\n  none\n" in capsys.readouterr().out


def test_errors_is_refused_for_a_machine_file(tmp_path, capsys):
    f = tmp_path / "m.toml"
    f.write_text('format = "vmt-machine/1"\nbase = "vmc-3axis"\n')
    rc = main(["machine", "show", str(f), "--errors", "none"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "states its errors" in err, err


def test_bench_merge_without_a_results_file_refuses_and_keeps_the_readme(tmp_path, monkeypatch, capsys):
    import scenarios.bench as B

    readme = tmp_path / "README.md"
    readme.write_text("x\n<!-- bench-table -->\nrow\n<!-- /bench-table -->\n")
    before = readme.read_bytes()
    ran = []
    monkeypatch.setattr(B, "run_all", lambda *a, **k: ran.append(1))
    rc = main(["bench", "--out", str(tmp_path / "none.json"), "--merge", "--readme", str(readme)])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "--merge" in err and "does not exist" in err
    assert readme.read_bytes() == before and not ran and not (tmp_path / "none.json").exists()


def test_simulate_plan_only_says_nothing_was_measured(tmp_path, capsys):
    plan = tmp_path / "plan.csv"
    assert main(["simulate", "cross-pocket", "--plan-only", "--no-collision-check", "--out", str(plan)]) == 0
    out = capsys.readouterr().out
    assert "plan of 368 touches (nothing measured)" in out and " ok)" not in out and "errors" not in out
    assert main(["check", str(plan)]) == 0
    out = capsys.readouterr().out
    assert "touches  368 planned (nothing measured)" in out and "ok)" not in out


def test_errors_name_things_in_english(tmp_path, capsys):
    """A one-set-up log names its set-up as text (no numpy repr); a dangling link 'does not exist'."""
    import os

    log = tmp_path / "one.csv"
    assert main(["simulate", "cross-pocket", "--c-angles-deg", "0", "--no-collision-check", "--out", str(log)]) == 0
    capsys.readouterr()
    assert main(["identify", str(log), "--json", str(tmp_path / "id.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "one set-up ('C0')" in err and "np." not in err, err
    link = tmp_path / "out.json"
    os.symlink(tmp_path / "gone" / "target.json", link)
    assert main(["identify", str(log), "--json", str(link)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "target.json, which does not exist)" in err and "a missing" not in err, err


def test_report_paths_have_no_double_slash(tmp_path, capsys):
    from scenarios.cli import main as vmt

    assert vmt(["iso230-2", "scenarios/data/positioning-sample.csv", "--json", str(tmp_path / "s.json"),
                "--report", str(tmp_path / "s-report") + "/"]) == 0
    out = capsys.readouterr().out
    assert "s-report/index.html" in out and "//" not in out
