"""The CLI speaks one language: one meaning per option name, units in the names, old names still working.

The walk reads every command's parser (``vmt`` and its sub-commands), so a new
option that breaks the rule fails here, not in a user's script.
"""

import argparse
import re

import numpy as np
import pytest

from scenarios.cli import build_parser, main
from scenarios.cli.options import UNIT_SUFFIXES, Renamed

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
    (["machine", "program"], "--feed", "50", "--feed-mm-min"),
    (["machine", "program"], "--move-feed", "500", "--move-feed-mm-min"),
    (["machine", "program"], "--max-feed", "900", "--max-feed-mm-min"),
    (["machine", "program"], "--clearance", "1", "--clearance-mm"),
    (["machine", "program"], "--overtravel", "1", "--overtravel-mm"),
    (["machine", "program"], "--safe-z", "80", "--safe-z-mm"),
    (["machine", "serve"], "--home", "0,0,10", "--home-mm"),
    (["machine", "serve"], "--limits", "X0:1,Y0:1,Z0:1", "--limits-mm"),
    (["machine", "serve"], "--idle-timeout", "9", "--idle-timeout-s"),
    (["machine", "serve"], "--max-seconds", "9", "--stop-after-s"),
    (["simulate", "cross-pocket"], "--c-angles", "0,90", "--c-angles-deg"),
    (["simulate", "positioning"], "--move-feed", "900", "--move-feed-mm-min"),
    (["design"], "--angles", "3", "--n-angles"),
    (["design"], "--reference", "0,90", "--reference-deg"),
    (["design"], "--u-probe-um", "1.1", "--noise-um"),
    (["iso230-2", "x.csv"], "--from", "ecmc", "--log-kind"),
    (["identify", "log.csv"], "--u-probe-um", "1.1", "--noise-um"),
    (["discover", "log.csv"], "--grid-step-mm", "30", "--grid-mm"),
    (["import", "grbl", "t.txt"], "--dt", "2", "--dt-s"),
    (["demo"], "--out", "o", "--out-dir"),
    (["bench"], "--out", "o.json", "--json"),
]

#: what each command needs besides the option under test, to parse
REQUIRED = {"probe": ["--controller", "virtual:", "--plan", "p.csv", "--out", "o.csv"],
            "machine program": ["--plan", "p.csv", "--out", "o.ngc"], "machine serve": ["--port", "0"],
            "simulate": ["--out", "o.csv"], "design": ["--plan", "plan.csv", "--n-angles", "3"],
            "identify": ["--json", "o.json"], "iso230-2": ["--json", "o.json"],
            "discover": ["--json", "o.json"], "import": ["--out", "o.csv"]}


def _walk(p, path=("vmt",)):
    for a in p._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sp in a.choices.items():
                yield from _walk(sp, path + (name,))
        else:
            yield path, a


def _options(parser=None, hidden: bool = False):
    """{--name: [(command, action)]} of every long option of every command (``hidden``: the old aliases too)."""
    out = {}
    for path, a in _walk(build_parser() if parser is None else parser):
        if a.help == argparse.SUPPRESS and not (hidden and isinstance(a, Renamed)):
            continue
        for o in a.option_strings:
            if o.startswith("--") and o not in ("--help", "--version"):
                out.setdefault(o, []).append((" ".join(path), a))
    return out


def _unit(help_text: str) -> str | None:
    m = _UNIT.search(help_text or "")
    return m.group(1) if m else None


def _meaning(a, actions) -> tuple:
    """What an option means: flag or value, type, choices, unit and name (an old alias: its new option's)."""
    if isinstance(a, Renamed):
        a = next(n for n in actions if a.new in n.option_strings)
    return (a.nargs == 0, getattr(a.type, "__name__", a.type), tuple(a.choices or ()), _unit(a.help),
            a.option_strings[0])


def meaning_problems(parser=None, hidden: bool = True) -> list:
    """Option names used with two meanings across the commands of ``parser`` (default: vmt's)."""
    parser = build_parser() if parser is None else parser
    acts = {}
    for path, a in _walk(parser):
        acts.setdefault(" ".join(path), []).append(a)
    bad = []
    for name, uses in _options(parser, hidden).items():
        meanings = {_meaning(a, acts[c]) for c, a in uses}
        if len(meanings) > 1:
            bad.append(f"{name}: {sorted((c, *map(str, _meaning(a, acts[c]))) for c, a in uses)}")
    return bad


def unit_problems(parser=None) -> list:
    """Options of ``parser`` (default: vmt's) whose help states a unit their name lacks, or numbers without one."""
    bad = []
    for name, uses in _options(parser).items():
        for command, a in uses:
            unit = _unit(a.help)
            if unit is not None and not name.endswith(UNIT_NAMES[unit]):
                bad.append(f"{command} {name}: help says {unit!r}, the name does not end with {UNIT_NAMES[unit]}")
            if a.type is float and name not in DIMENSIONLESS and not name.endswith(UNIT_SUFFIXES):
                bad.append(f"{command} {name}: a number without a unit suffix {UNIT_SUFFIXES}")
    return bad


#: Old names kept as aliases whose old meaning differs from the same name's meaning elsewhere (they work,
#: print their new name, and go when the aliases go); any other name with two meanings fails the walk.
OLD_MEANINGS = {"--out", "--machine", "--home"}


def test_each_option_name_has_one_meaning_across_commands():
    assert len(_options()) > 80                                  # the walk reached the sub-commands
    visible = meaning_problems(hidden=False)
    assert not visible, "\n".join(visible)
    both = meaning_problems(hidden=True)
    assert {b.split(":")[0] for b in both} == OLD_MEANINGS, "\n".join(both)


def test_a_quantity_carries_its_unit_in_its_name():
    bad = unit_problems()
    assert not bad, "\n".join(bad)


def _fabricated():
    from scenarios.cli.guard import OneLineParser
    from scenarios.cli.options import option

    p = OneLineParser(prog="x")
    sub = p.add_subparsers()
    a, b = sub.add_parser("a"), sub.add_parser("b")
    a.add_argument("--depth-mm", type=float, help="depth, mm (1)")
    b.add_argument("--depth-mm", type=float, help="depth, mm (1)")
    option(b, "--wait-s", dest="wait", type=float, old=("--wait",), help="wait, s (1)")
    return p, a, b


def test_the_walk_fails_on_a_unitless_quantity():
    """The unit check itself, on a made-up parser: clean, then with an option like the old ``--feed``."""
    p, a, _b = _fabricated()
    assert unit_problems(p) == []
    a.add_argument("--feed", type=float, help="probing feed, mm/min (100)")
    bad = unit_problems(p)
    assert len(bad) == 2 and all("--feed" in x for x in bad), bad       # unit in the help, and a bare number
    q, a2, _ = _fabricated()
    a2.add_argument("--ratio", type=float, help="a ratio (1)")          # a number, no unit named
    assert unit_problems(q) == ["vmt a --ratio: a number without a unit suffix " + str(UNIT_SUFFIXES)]


def test_the_walk_fails_on_a_name_with_two_meanings():
    """The meaning check itself, on a made-up parser: two visible meanings, then a hidden alias's."""
    p, a, b = _fabricated()
    assert meaning_problems(p) == []
    a.add_argument("--mode", choices=("x", "y"))
    b.add_argument("--mode", choices=("x", "z"))
    assert [x.split(":")[0] for x in meaning_problems(p)] == ["--mode"]
    q, a, b = _fabricated()
    a.add_argument("--wait", action="store_true", help="wait for the machine")   # b's old --wait is a number
    assert meaning_problems(q, hidden=False) == []
    assert [x.split(":")[0] for x in meaning_problems(q)] == ["--wait"]


#: Names shown with another placeholder on purpose, and why (each one a narrower value, said in the help).
PLACEHOLDER_EXCEPTIONS = {"--grid-mm": "discover takes the STEP form only (its search places the nodes; "
                                       "core.discover's grid_step_mm), identify and design STEP or x0:x1:step"}

#: Other spellings of a concept vmt already names, and vmt's name for it (session 38, cli38: the same thing is
#: not spelled two ways in two commands; a new option under one of these names fails the walk).
SYNONYMS = {"--output": "--out", "-o": "--out", "--out-file": "--out", "--output-file": "--out",
            "--outdir": "--out-dir", "--output-dir": "--out-dir", "--dir": "--out-dir",
            "--json-out": "--json", "--out-json": "--json", "--json-file": "--json",
            "--report-dir": "--report", "--html": "--report",
            "--seeds": "--seed", "--random-seed": "--seed", "--rng-seed": "--seed",
            "--runs": "--mc", "--mc-runs": "--mc", "--n-mc": "--mc", "--monte-carlo": "--mc",
            "--sigma-um": "--noise-um", "--u-probe-um": "--noise-um", "--probe-noise-um": "--noise-um",
            "--jobs": "--workers", "-j": "--workers", "--processes": "--workers", "--n-workers": "--workers",
            "--threads": "--workers", "--cluster": "--dask", "--scheduler": "--dask",
            "--grid-step-mm": "--grid-mm", "--step-mm": "--grid-mm",
            "--stylus-radius-mm": "--stylus-r-mm", "--tip-r-mm": "--stylus-r-mm",
            "--tool-offsets-mm": "--tool-offset-mm", "--j-mm": "--tool-offset-mm",
            "--error-set": "--errors", "--truth": "--errors", "--machine-file": "--machine",
            "--log": "LOG (a positional argument)", "--input": "the command's positional argument"}


def placeholder_problems(parser=None) -> list:
    """Option names shown with two placeholders across the commands (``--report REPORT`` beside ``--report DIR``)."""
    shown = {}
    for name, uses in _options(parser).items():
        for command, a in uses:
            if a.nargs != 0:
                shown.setdefault(name, {}).setdefault(str(a.metavar or a.dest.upper()), []).append(command)
    said = lambda ms: ", ".join(f"{m} ({', '.join(c)})" for m, c in sorted(ms.items()))  # noqa: E731
    return [f"{n}: shown as {said(ms)}" for n, ms in sorted(shown.items())
            if len(ms) > 1 and n not in PLACEHOLDER_EXCEPTIONS]


def folder_problems(parser=None, files=None) -> list:
    """Outputs shown as what they are: a folder of ``scenarios.cli.guard.FILES`` shows ``DIR``, a file never does,
    and a JSON file written is ``--json`` (not ``--out``, ``--json-out``: one name for one thing)."""
    from scenarios.cli.guard import FILES

    files = FILES if files is None else files
    bad = []
    for name, uses in _options(parser).items():
        for command, a in uses:
            _ins, outs, dirs = files.get(command.split()[1] if " " in command else command, ((), (), ()))
            shown = str(a.metavar or a.dest.upper())
            if a.dest in dirs and shown != "DIR":
                bad.append(f"{command} {name}: a folder, shown as {shown} (DIR)")
            if a.dest in outs and shown == "DIR":
                bad.append(f"{command} {name}: a file, shown as DIR")
            if a.dest in outs and name != "--json" and "JSON" in (a.help or "").split(",")[0].upper().split():
                bad.append(f"{command} {name}: writes JSON, and a JSON output is --json")
    return bad


def synonym_problems(parser=None) -> list:
    """Visible options spelling a concept another way than vmt names it (:data:`SYNONYMS`)."""
    return [f"{c} {n}: vmt says {SYNONYMS[n]}" for n, uses in sorted(_options(parser).items()) for c, _a in uses
            if n in SYNONYMS]


def test_an_option_shows_one_placeholder_everywhere():
    bad = placeholder_problems()
    assert not bad, "\n".join(bad)
    assert _options()["--report"] and all(a.metavar == "DIR" for _c, a in _options()["--report"])


def test_folders_say_dir_and_json_is_json():
    bad = folder_problems()
    assert not bad, "\n".join(bad)


def test_a_concept_is_not_spelled_two_ways():
    bad = synonym_problems()
    assert not bad, "\n".join(bad)


def test_the_walk_fails_on_a_second_placeholder_a_folder_shown_as_a_file_and_a_synonym():
    """The three checks themselves, on made-up parsers: clean, then each with one planted violation."""
    p, a, b = _fabricated()
    files = {"a": ((), ("json",), ("report",)), "b": ((), ("json",), ("report",))}
    assert placeholder_problems(p) == folder_problems(p, files) == synonym_problems(p) == []
    a.add_argument("--report", metavar="DIR", help="folder for a readable report")
    b.add_argument("--report", metavar="REPORT", help="folder for a readable report")
    assert placeholder_problems(p) == ["--report: shown as DIR (vmt a), REPORT (vmt b)"]
    assert folder_problems(p, files) == ["vmt b --report: a folder, shown as REPORT (DIR)"]
    q, a, b = _fabricated()
    a.add_argument("--json-out", dest="json", metavar="OUT", help="JSON report to write")
    b.add_argument("--seeds", type=int, help="seeds of the runs")
    assert folder_problems(q, files) == ["vmt a --json-out: writes JSON, and a JSON output is --json"]
    assert synonym_problems(q) == ["vmt a --json-out: vmt says --json", "vmt b --seeds: vmt says --seed"]


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


def test_simulate_positioning_refuses_noise_and_the_old_cycle(tmp_path, capsys):
    """review30 F9: --noise-um is the probing noise in every command; in simulate positioning it was an alias
    of --scatter-um. --cycle (the kind) sat beside --cycles (the count): renamed --cycle-kind. Both old
    names are refused in one line naming the option to use; nothing written."""
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    for argv, said in ((["--noise-um", "0.3"], "the scatter of each reading is --scatter-um"),
                       (["--noise-um", "0.3", "--scatter-um", "0.3"], "is --scatter-um"),
                       (["--cycle", "pilgrim"], "--cycle is now --cycle-kind"),
                       (["--cycle", "linear"], "--cycle is now --cycle-kind")):
        assert main(["simulate", "positioning", "--targets", "5", "--cycles", "2", "--out", str(a), *argv]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and said in err and not a.exists(), err
    assert main(["simulate", "positioning", "--targets", "5", "--cycles", "2", "--out", str(a),
                 "--cycle-kind", "pilgrim", "--scatter-um", "0.3"]) == 0
    assert capsys.readouterr().err == "" and "# cycle_kind: pilgrim" in a.read_text()
    assert main(["simulate", "cross-pocket", "--out", str(b), "--cycle-kind", "pilgrim"]) == 2
    assert "--cycle-kind applies to 'vmt simulate positioning' only" in capsys.readouterr().err


def test_naming_the_default_machine_is_omitting_it(tmp_path, capsys):
    """A command run with and without its default --machine (and default --errors) writes the same bytes."""
    outs = {}
    for tag, extra in (("omitted", []), ("named", ["--machine", "vmc-3axis"]),
                       ("both", ["--machine", "vmc-3axis", "--errors", "realistic"]),
                       ("other", ["--machine", "vmc-3axis", "--errors", "none"])):
        out = tmp_path / f"{tag}.csv"
        assert main(["simulate", "positioning", "--targets", "5", "--cycles", "2", "--out", str(out), *extra]) == 0
        outs[tag] = out.read_bytes()
    capsys.readouterr()
    assert outs["omitted"] == outs["named"] == outs["both"] != outs["other"]


def test_simulate_an_artefact_on_its_named_default_machine_is_the_same(tmp_path, capsys):
    from sim.catalog import CATALOG

    base = ["simulate", "cross-pocket", "--c-angles-deg", "0", "--no-collision-check"]
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main([*base, "--out", str(a)]) == 0
    assert main([*base, "--out", str(b), "--machine", CATALOG["cross-pocket"].default_machine]) == 0
    capsys.readouterr()
    assert a.read_bytes() == b.read_bytes()


def _serve_args(*extra):
    from scenarios.cli import build_parser

    return build_parser().parse_args(["machine", "serve", "--port", "0", "--scene", "cross-pocket", *extra])


def _touches(machine):
    """Touches of a few probing moves on the pocket (rotary C at 0 and 75 deg), m."""
    rot = [None, np.array([0.0, 0.0, np.deg2rad(75.0)])]
    out = []
    for y in (-0.009, 0.0, 0.009):
        for r in rot:
            hit, p = machine.probe_move(np.array([0.08, y, 0.027]), np.array([0.11, y, 0.027]), r)
            assert hit
            out.append(p)
    return np.array(out)


def test_serve_seed_only_where_there_is_noise(tmp_path):
    """machine serve --seed seeds the probing noise only: on a noise-free machine (a built-in one
    by default, --noise-um 0, the simple scene) it is refused, not ignored; with noise (--noise-um,
    a machine file's probe) it is taken, and another seed draws other touches."""
    from core.exceptions import ConfigError
    from scenarios.cli.machine import served_machine

    zero = tmp_path / "z.toml"  # a machine file whose probe has no noise
    zero.write_text('format = "vmt-machine/1"\nname = "z"\nbase = "nmv3000"\nerrors = "none"\n'
                    '[probe]\nnoise_um = 0\n')
    for extra, why in (((), "a built-in machine is served noise-free"), (("--noise-um", "0"), "--noise-um 0"),
                       (("--machine", "nmv3000"), "a built-in machine is served noise-free"),
                       (("--machine", str(zero)), f"the probe of machine file {zero} has none")):
        with pytest.raises(ConfigError) as e:
            served_machine(_serve_args("--seed", "3", *extra))
        assert str(e.value) == (f"--seed 3: it seeds the probing noise, and there is none ({why}); "
                                "give --noise-um above 0, or leave --seed out")
    from scenarios.cli import build_parser

    simple = build_parser().parse_args(["machine", "serve", "--port", "0", "--scene", "simple", "--seed", "3"])
    with pytest.raises(ConfigError, match=r"--seed 3: .* \(the simple scene is served noise-free\)"):
        served_machine(simple)
    a = _touches(served_machine(_serve_args("--noise-um", "0.5", "--seed", "3")))
    b = _touches(served_machine(_serve_args("--noise-um", "0.5", "--seed", "4")))
    assert not np.array_equal(a, b)
    assert np.array_equal(_touches(served_machine(_serve_args("--noise-um", "0.5"))),
                          _touches(served_machine(_serve_args("--noise-um", "0.5", "--seed", "0"))))
    f = tmp_path / "m.toml"  # a machine file whose probe has noise: the seed is taken
    f.write_text('format = "vmt-machine/1"\nname = "m"\nbase = "nmv3000"\nerrors = "none"\n'
                 '[probe]\nnoise_um = 0.3\n')
    served_machine(_serve_args("--machine", str(f), "--seed", "3"))


def test_simulate_seed_only_where_there_is_noise(tmp_path, capsys):
    """simulate ARTEFACT --seed seeds the probing noise only, as machine serve --seed (one meaning per
    option name, the same helper): with --noise-um 0, or a machine file whose probe has none, it is
    refused (one line, exit 2), not ignored; without --seed the same run goes through, and with noise
    another seed draws another log."""
    base = ["simulate", "cross-pocket", "--c-angles-deg", "0", "--no-collision-check"]
    zero = tmp_path / "z.toml"
    zero.write_text('format = "vmt-machine/1"\nname = "z"\nbase = "nmv3000"\nerrors = "none"\n'
                    '[probe]\nnoise_um = 0\n')
    for extra, why in ((("--noise-um", "0"), "--noise-um 0"),
                       (("--machine", str(zero)), f"the probe of machine {zero} has none")):
        capsys.readouterr()
        out = tmp_path / f"x{len(why)}.csv"
        assert main([*base, "--out", str(out), "--seed", "5", *extra]) == 2
        err = capsys.readouterr().err
        assert err.splitlines() == [f"vmt simulate: error: --seed 5: it seeds the probing noise, and there is none ({why}); "
                                    "give --noise-um above 0, or leave --seed out"]
        assert not out.exists()
        assert main([*base, "--out", str(out), *extra]) == 0
    # a plan draws nothing: --seed and --noise-um with --plan-only would be ignored, so they are refused
    for opt, val, why in (("--seed", "5", "there is no probing noise to draw"),
                          ("--noise-um", "0.3", "there is no probing noise to draw"),
                          ("--errors", "none", "the machine's errors change nothing in it")):
        capsys.readouterr()
        out = tmp_path / "plan.csv"
        assert main([*base, "--out", str(out), "--plan-only", opt, val]) == 2
        shown = val if opt == "--errors" else f"{float(val):g}"
        assert capsys.readouterr().err.splitlines() == [
            f"vmt simulate: error: {opt} {shown}: --plan-only measures nothing, so {why}; leave {opt} out"]
        assert not out.exists()
    plan = tmp_path / "plan.csv"  # nor does the plan claim an error set or a seed it did not use
    assert main([*base, "--out", str(plan), "--plan-only"]) == 0
    head = [ln for ln in plan.read_text().splitlines() if ln.startswith("#")]
    assert not any(ln.startswith(("# errors:", "# seed:")) for ln in head), head
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main([*base, "--out", str(a), "--seed", "5"]) == 0
    assert main([*base, "--out", str(b), "--seed", "6"]) == 0
    assert a.read_bytes() != b.read_bytes()


def test_serve_and_virtual_scene_are_one_machine_with_the_old_truth():
    """machine serve --scene X and probe --controller virtual:X: one machine, no noise, the old 'drawn' truth."""
    from hardware.virtual import open_backend
    from scenarios.cli.machine import served_machine
    from sim.machinefile import truth_machine
    from sim.machines import MACHINES, realistic_errors

    virt = _touches(open_backend("virtual:cross-pocket").machine)
    for extra in ((), ("--machine", "nmv3000"), ("--errors", "drawn"), ("--noise-um", "0")):
        assert np.array_equal(_touches(served_machine(_serve_args(*extra))), virt), extra
    noisy = _touches(served_machine(_serve_args("--noise-um", "0.5")))
    assert not np.array_equal(noisy, virt)
    realistic = _touches(served_machine(_serve_args("--errors", "realistic")))
    assert np.abs(realistic - virt).max() > 1e-6                        # another truth, micrometres away
    old = MACHINES["nmv3000"](errors=realistic_errors(("X", "Y", "Z", "C"), rng=np.random.default_rng(1),
                                                      ripple=False))
    drawn = truth_machine("nmv3000", "drawn").config
    assert drawn.errors.keys() == old.errors.keys()
    for k in old.errors:
        for x in (-0.1, 0.0, 0.07, 1.0):
            assert drawn.errors[k](x) == old.errors[k](x), k


def test_scenario_names_its_default_machine_and_errors_as_omitting_them(monkeypatch, capsys):
    """scenario mfb-3axis: --machine vmc-3axis (the plan's) and --errors study are the study's own truth."""
    import scenarios.mfb as M

    seen = []

    class Stop(Exception):
        pass

    def fake_run(name, **kw):
        seen.append(kw["machine"])
        raise Stop

    monkeypatch.setattr(M, "run", fake_run)
    assert M.PLANS["mfb-3axis"]().machine == "vmc-3axis"
    for extra in ([], ["--machine", "vmc-3axis"], ["--errors", "study"], ["--machine", "vmc-3axis", "--errors", "study"],
                  ["--errors", "none"], ["--errors", "realistic"]):
        with pytest.raises(Stop):
            main(["scenario", "mfb-3axis", *extra])
    assert seen[:4] == [None] * 4                                      # the study's own truth machine
    assert seen[4].errors == "none" and not seen[4].config.errors       # the file as shipped (before the merge)
    assert seen[5].errors == "realistic" and seen[5].config.errors


def test_errors_means_one_set_everywhere():
    """study is the realistic set without its ripple, the MFB studies' truth; none is the shipped file."""
    from scenarios.mfb import default_machine
    from sim.machinefile import resolve, truth_machine

    study, real = truth_machine("vmc-3axis", "study").config, truth_machine("vmc-3axis", "realistic").config
    _cfg, own = default_machine("vmc-3axis")
    assert study.errors.keys() == own.keys() == real.errors.keys()
    for k in own:
        for x in (-0.2, 0.013, 0.3):
            assert study.errors[k](x) == own[k](x), k
    assert any(study.errors[k](0.013) != real.errors[k](0.013) for k in own)   # the ripple
    assert truth_machine("vmc-3axis", "none") == resolve("vmc-3axis")
    with pytest.raises(Exception, match="expected realistic, study, drawn, none"):
        truth_machine("vmc-3axis", "nominal")


def test_vcmm_errors_default_is_the_shipped_file(tmp_path, capsys):
    """vcmm: a built-in machine's best-estimate errors are its file's (none), as --errors none names them."""
    from sim.machinefile import truth_machine

    assert truth_machine("vmc-3axis", None, "none") == truth_machine("vmc-3axis", "none")
    p = build_parser()
    args = p.parse_args(["vcmm", "--plan", "plan.csv", "--machine", "vmc-3axis", "--task", "t.toml",
                         "--json", "o.json"])
    assert args.errors is None and args.errors_default == "none"
    assert "best-estimate errors" in " ".join(a.help for a in p._subparsers._group_actions[0].choices["vcmm"]._actions
                                              if a.dest == "errors")


def test_no_option_is_abbreviated(capsys):
    """A prefix of an option is refused (allow_abbrev=False on every parser): no ambiguity with old aliases."""
    base = ["probe", "--controller", "virtual:", "--plan", "p.csv", "--out", "o.csv"]
    p = build_parser()
    assert p.parse_args([*base, "--safe-z-mm", "80"]).safe_z == 80.0           # the full new name
    assert p.parse_args([*base, "--safe-z", "80"]).safe_z == 80.0              # the full old name
    capsys.readouterr()
    for prefix in ("--safe", "--safe-z-m", "--contr"):
        with pytest.raises(SystemExit) as e:
            p.parse_args([*base, prefix, "80"])
        assert e.value.code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "unrecognized arguments" in err and "ambiguous" not in err, err
    every = list(_parsers(p))
    assert len(every) > 20 and not any(sp.allow_abbrev for sp in every)


def test_unknown_option_is_named_by_its_command(capsys):
    """An unrecognized option's error names the command given it and that command's help, not vmt's."""
    p = build_parser()
    cases = [(["probe", "--controller", "virtual:", "--plan", "p.csv", "--out", "o.csv", "--safe", "80"],
              "vmt probe", "--safe 80"),
             (["machine", "serve", "--port", "0", "--speed", "2"], "vmt machine serve", "--speed 2"),
             (["plan", "grid", "--x-mm", "0:10:1", "--y-mm", "0:10:1", "--out", "g.csv", "--z", "0"],
              "vmt plan grid", "--z 0"),
             (["check", "log.csv", "extra.csv"], "vmt check", "extra.csv")]
    for argv, prog, rest in cases:
        with pytest.raises(SystemExit) as e:
            p.parse_args(argv)
        assert e.value.code == 2
        err = capsys.readouterr().err
        assert err == f"{prog}: error: unrecognized arguments: {rest} (see {prog} --help)\n", err
    with pytest.raises(SystemExit):                   # no command given: vmt's own
        p.parse_args(["--frobnicate"])
    assert capsys.readouterr().err.startswith("vmt: error: unrecognized arguments: --frobnicate (see vmt --help)")


def _parsers(p):
    yield p
    for a in p._actions:
        if isinstance(a, argparse._SubParsersAction):
            for sp in a.choices.values():
                yield from _parsers(sp)


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
    rc = main(["bench", "--json", str(tmp_path / "none.json"), "--merge", "--readme", str(readme)])
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
    assert "plan     368 touches in 4 set-ups, 92 targets: nothing measured yet" in out and "ok)" not in out
    assert "time " not in out                                  # a plan has no time (small37)


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


def test_check_without_a_log_says_so_once(tmp_path, capsys):
    """No LOG: one line, 'check' not doubled; a JSON file given to --json is not read as the log."""
    out = tmp_path / "s.json"
    out.write_text("{}")
    for argv in (["check"], ["check", "--json", str(out)]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "give the LOG to check" in err and "check: check" not in err \
            and "error: check:" not in err, err
    assert out.read_text() == "{}"


def test_negative_waits_are_refused(tmp_path, capsys):
    plan = tmp_path / "plan.csv"
    assert main(["simulate", "cross-pocket", "--plan-only", "--no-collision-check", "--out", str(plan)]) == 0
    # (--timeout-s is a rule of guard.COMMON, checked before the plan's own checks: the cross-pocket plan turns C and
    # gives no safe Z, which is refused too, after)
    for argv, said in ((["machine", "serve", "--port", "0", "--idle-timeout-s", "-1"], "--idle-timeout-s must be > 0"),
                       (["machine", "serve", "--port", "0", "--stop-after-s", "0"], "--stop-after-s must be > 0"),
                       (["probe", "--controller", "virtual:cross-pocket", "--plan", str(plan), "--out",
                         str(tmp_path / "log.csv"), "--limits-mm", "X-250:250,Y-250:250,Z-100:200",
                         "--timeout-s", "-5"], "--timeout-s must be a finite number > 0, got -5")):
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and said in err, err
    assert not (tmp_path / "log.csv").exists()


@pytest.mark.parametrize("argv, says", [
    (["--from-json", "r.json", "--readme", "R.md", "--merge"], "--merge has no meaning"),
    (["--from-json", "r.json", "--readme", "R.md", "--only", "x"], "--only has no meaning"),
    (["--only", "bench_discover", "--readme", "R.md"], "add --merge"),
])
def test_bench_refuses_a_table_from_part_of_the_benchmarks(tmp_path, monkeypatch, capsys, argv, says):
    import scenarios.bench as B

    ran = []
    monkeypatch.setattr(B, "run_all", lambda *a, **k: ran.append(1))
    monkeypatch.chdir(tmp_path)
    (tmp_path / "R.md").write_text("x\n<!-- bench-table -->\nrow\n<!-- /bench-table -->\n")
    assert main(["bench", "--json", str(tmp_path / "o.json"), *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and says in err, err
    assert not ran and "row" in (tmp_path / "R.md").read_text()


def test_every_old_alias_is_exercised():
    """RENAMED (the aliases the test above runs) lists every hidden old name of every command."""
    listed = {(r[0][0] if r[0][0] != "machine" else "machine " + r[0][1], r[1]) for r in RENAMED}
    found = {(" ".join(path[1:]), o) for path, a in _walk(build_parser()) if isinstance(a, Renamed)
             for o in a.option_strings}
    assert found - listed == set(), sorted(found - listed)
    assert listed - found == set(), sorted(listed - found)


def test_check_usage_says_log_is_required_and_noise_help_says_what_it_does_in_positioning(capsys):
    # `vmt check` refuses to run without LOG: its usage line may not show it optional (it showed [LOG]);
    # `--noise-um` of `vmt simulate positioning` is refused naming --scatter-um (test above): the help says so
    with pytest.raises(SystemExit):
        main(["check", "--help"])
    usage = capsys.readouterr().out.splitlines()[0]
    assert usage.endswith(" LOG") and "[LOG]" not in usage
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "not for positioning, which has no probe: its readings' scatter is --scatter-um" in text
    assert main(["check"]) == 2 and "give the LOG to check" in capsys.readouterr().err


def test_grid_steps_are_judged_in_mm(tmp_path, capsys):
    """--grid-mm (identify, design, discover) is refused in its own unit: a step
    of -5 mm said 'grid step must be > 0, got -0.005' (metres), discover took a step of 0 for 'choose by
    BIC' and a negative one failed on the grid's nodes in metres; nan passed to the grid."""
    from core.exceptions import ConfigError
    from scenarios.cli.options import parse_grid

    p_R = np.array([[0.0, 0.0], [0.1, 0.1]])
    for text, said in (("-5", "the step must be > 0 mm, got -5 mm"), ("0", "the step must be > 0 mm, got 0 mm"),
                       ("nan", "expected finite numbers of mm"), ("-110:110:0", "the step must be > 0 mm"),
                       ("110:-110:22", "expected x0 < x1, got 110 and -110 mm"), ("0:inf:22", "finite")):
        with pytest.raises(ConfigError, match=re.escape(said)):
            parse_grid(text, p_R)
    assert np.allclose(np.diff(parse_grid("50", p_R).x_m), 0.05)
    assert parse_grid("-110:110:110", p_R).y_m.tolist() == [-0.11, 0.0, 0.11]
    log = tmp_path / "log.csv"
    log.write_text("any\n")                 # the step is judged before the log is read
    for step in ("0", "-5", "nan", "10:100:22"):
        assert main(["discover", str(log), "--json", str(tmp_path / "d.json"), "--grid-mm", step]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"vmt discover: error: --grid-mm must be a finite number > 0 (mm; discover takes a "
                              f"STEP, not x0:x1:step), got {step}"), err
        assert err.count("\n") == 1


def test_option_errors_name_the_option_in_its_unit(tmp_path, capsys):
    """Refusals name the option the user wrote, in its unit: 'vmt simulate positioning --travel-mm 10:-10'
    said 'measurement travel must be finite with min < max, got 0.01, -0.01' (metres), --cycles 0
    'cycles must ...', --drift-tau-s 0 'Drift.tau_s must be > 0'; iso230-2's 'uncertainty input
    u_temperature_K ...'; plan grid's 'z_mm 0.0 / stylus_r_mm -1.0'. A negative value given as a
    separate word ('--travel-mm -100:100') said only 'expected one argument'."""
    sample = "scenarios/data/positioning-sample.csv"
    out = str(tmp_path / "o.csv")
    cases = [
        (["simulate", "positioning", "--out", out, "--travel-mm", "10:-10"],
         "vmt simulate: error: --travel-mm 10:-10: expected finite LO < HI in mm"),
        (["simulate", "positioning", "--out", out, "--travel-mm=nan:10"],
         "vmt simulate: error: --travel-mm nan:10: expected finite LO < HI in mm"),
        # the default travel emptied by the overrun: said 'measurement travel must be finite with min < max,
        # got 0.10000000000000003, -0.10000000000000003' (metres, no option; review28)
        (["simulate", "positioning", "--out", out, "--axis", "X", "--overrun-mm", "400"],
         "vmt simulate: error: --overrun-mm 400: axis X's stroke -300..300 mm less 400 mm at each end leaves no "
         "travel to test (the default --travel-mm); give a smaller --overrun-mm"),
        (["simulate", "positioning", "--out", out, "--axis", "X", "--overrun-mm", "300"],
         "vmt simulate: error: --overrun-mm 300: axis X's stroke -300..300 mm less 300 mm at each end leaves no "
         "travel to test (the default --travel-mm); give a smaller --overrun-mm"),
        (["simulate", "positioning", "--out", out, "--cycles", "0"],
         "vmt simulate: error: --cycles must be a whole number >= 2, got 0"),
        (["simulate", "positioning", "--out", out, "--targets", "1"],
         "vmt simulate: error: --targets must be a whole number >= 2, got 1"),
        (["simulate", "positioning", "--out", out, "--drift-tau-s", "0", "--drift-um-per-h", "1"],
         "vmt simulate: error: --drift-tau-s must be a finite number > 0, got 0"),
        (["iso230-2", sample, "--json", str(tmp_path / "i.json"), "--u-temp-k", "-1"],
         "vmt iso230-2: error: --u-temp-k must be a finite number >= 0, got -1.0"),
        (["iso230-2", sample, "--json", str(tmp_path / "i.json"), "--u-instrument-um-per-m", "-1"],
         "vmt iso230-2: error: --u-instrument-um-per-m must be a finite number >= 0, got -1.0"),
        (["iso230-2", sample, "--json", str(tmp_path / "i.json"), "--temp-c", "nan"],
         "vmt iso230-2: error: --temp-c must be a workshop temperature, got nan"),
        (["plan", "grid", "--x-mm", "0:10:5", "--y-mm", "0:10:5", "--out", out, "--stylus-r-mm", "-1"],
         "vmt plan grid: error: --stylus-r-mm must be a finite number >= 0, got -1"),
        (["plan", "grid", "--x-mm", "0:10:5", "--y-mm", "0:10:5", "--out", out, "--z-mm", "inf"],
         "vmt plan grid: error: --z-mm must be a finite number, got inf"),
    ]
    for argv, said in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err == said + "\n", err
    assert not (tmp_path / "o.csv").exists() and not (tmp_path / "i.json").exists()
    with pytest.raises(SystemExit) as e:
        main(["simulate", "positioning", "--out", out, "--travel-mm", "-100:100"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("vmt simulate: error: argument --travel-mm: expected one argument (a value that starts "
                          "with '-' is written --travel-mm=VALUE, e.g. --travel-mm=-100:100)"), err


def test_machine_serve_refuses_non_finite_settings(capsys):
    """'vmt machine serve --ec0y-urad inf' served a machine with an infinite squareness, and
    '--home-mm nan,0,0' said 'controller home (nan, 0.0, 0.0): ...' instead of naming the option."""
    base = ["machine", "serve", "--port", "0", "--stop-after-s", "0.5"]
    three = "expected three numbers a,b,c, each finite"
    for extra, said in ((["--ec0y-urad", "inf"], "--ec0y-urad must be a finite number, got inf"),
                        (["--home-mm", "nan,0,0"], f"--home-mm 'nan,0,0': {three}"),
                        (["--scale-ppm", "0,inf,0"], f"--scale-ppm '0,inf,0': {three}")):
        assert main(base + extra) == 2
        assert capsys.readouterr().err == f"vmt machine serve: error: {said}\n"


def test_wcs_and_one_setup_are_said_plainly(tmp_path, capsys):
    """'vmt machine program --wcs G99' named the field ('wcs ...'), not the option; 'vmt simulate' said
    '1 set-ups' of a one-angle campaign."""
    plan = tmp_path / "plan.csv"
    assert main(["plan", "grid", "--x-mm", "0:10:10", "--y-mm", "0:10:10", "--stylus-r-mm", "0", "--out", str(plan)]) == 0
    capsys.readouterr()
    assert main(["machine", "program", "--plan", str(plan), "--out", str(tmp_path / "p.ngc"), "--probe-file", "p.txt",
                 "--limits-mm", "X-50:50,Y-50:50,Z-50:50", "--wcs", "G99"]) == 2
    assert capsys.readouterr().err.startswith("vmt machine program: error: --wcs 'G99': expected one of G54, ")
    out = tmp_path / "one.csv"
    assert main(["simulate", "pin-circle", "--plan-only", "--out", str(out), "--c-angles-deg", "0",
                 "--no-collision-check"]) == 0
    said = capsys.readouterr().out
    assert said.endswith(", 1 set-up\n"), said


def test_declared_ripple_options_are_defined_once_for_identify_and_scenario(monkeypatch):
    """``--declared-ripple-um-mm`` / ``-urad-mm`` are one definition (name, dest, metavar, default) that
    ``vmt identify`` and ``vmt scenario`` share with their own help: building the parser goes through
    ``scenarios.cli.options.add_declared_ripple_args`` for both, and nothing else defines them."""
    import pathlib

    import scenarios.cli.options as S

    calls = []
    real = S.add_declared_ripple_args
    monkeypatch.setattr(S, "add_declared_ripple_args", lambda p, *h: (calls.append(p.prog), real(p, *h))[1])
    parser = build_parser()
    assert sorted(c.split()[-1] for c in calls) == ["identify", "scenario"]
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    for cmd in ("identify", "scenario"):
        acts = {o: a for a in subs[cmd]._actions for o in a.option_strings}
        assert acts["--declared-ripple-um-mm"].dest == "declared_ripple"
        assert acts["--declared-ripple-urad-mm"].dest == "declared_ripple_urad"
    src = "".join(p.read_text() for p in pathlib.Path(S.__file__).parent.glob("*.py"))
    assert src.count('add_argument("--declared-ripple-um-mm"') == 1
    assert src.count('add_argument("--declared-ripple-urad-mm"') == 1


def test_bench_writes_its_json_with_json_and_out_still_reads(tmp_path, monkeypatch, capsys):
    """review32d F9: `bench --out` where every other command says `--json`: --json now, --out a renamed alias
    (one line naming the new option), the same destination."""
    from scenarios.cli import build_parser

    p = build_parser()
    assert p.parse_args(["bench", "--json", "a.json"]).out == "a.json"
    capsys.readouterr()
    assert p.parse_args(["bench", "--out", "b.json"]).out == "b.json"
    assert "vmt: --out is renamed to --json" in capsys.readouterr().err
    assert p.parse_args(["bench"]).out == "bench/results.json"


@pytest.mark.parametrize("text, says", [("", "empty file"), ("\n  \n", "empty file"),
                                        ("# only a comment\n", "empty file (comments only)")])
def test_an_empty_machine_or_task_file_is_said_to_be_empty(tmp_path, text, says):
    """review32d F11: an empty machine file said "chain: missing: the ISO 10791 chain", a task "features: missing"."""
    from core.exceptions import VmtError
    from core.vcmm import loads_task
    from sim.machinefile import loads

    for read in (loads, loads_task):
        with pytest.raises(VmtError) as e:
            read(text, source="f.toml")
        assert str(e.value) == f"f.toml: {says}", str(e.value)


#: Positional arguments whose name is another command's option, on purpose: ``vmt machine show MACHINE``
#: shows the machine every other command names with ``--machine NAME|FILE`` (the thing the command is about).
POSITIONAL_AS_OPTION = {("machine show", "machine")}


def spelling_problems(parser=None) -> list:
    """Inputs named as a positional argument in one command and as an option in another (review32d F9:
    ``vmt design PLAN`` beside ``vmt probe --plan PLAN``), from the parsers' own actions; an old spelling
    kept hidden (``help=SUPPRESS``) does not count."""
    parser = build_parser() if parser is None else parser
    options = _options(parser)
    bad = []
    for path, a in _walk(parser):
        if a.option_strings or a.help == argparse.SUPPRESS:
            continue
        name = "--" + a.dest.replace("_", "-")
        command = " ".join(path[1:])
        if name in options and (command, a.dest) not in POSITIONAL_AS_OPTION:
            bad.append(f"{command} takes {a.dest.upper()} as an argument, "
                       f"{', '.join(c for c, _ in options[name])} as {name}")
    return bad


def test_an_input_is_spelled_one_way_across_commands():
    assert spelling_problems() == []


def test_the_spelling_walk_fails_on_a_positional_beside_an_option():
    """The check itself, on a made-up parser: a plan taken positionally by one command and as --plan by
    another (vmt design and vmt probe before session 33); the old positional hidden, as add_plan_arg keeps it."""
    p = argparse.ArgumentParser()
    sub = p.add_subparsers()
    sub.add_parser("probe").add_argument("--plan")
    sub.add_parser("design").add_argument("plan")
    assert [b.split(" takes")[0] for b in spelling_problems(p)] == ["design"]
    q = argparse.ArgumentParser()
    sub = q.add_subparsers()
    sub.add_parser("probe").add_argument("--plan")
    d = sub.add_parser("design")
    d.add_argument("--plan")
    d.add_argument("plan_positional", nargs="?", help=argparse.SUPPRESS)
    assert spelling_problems(q) == []


@pytest.mark.parametrize("command", [["design", "--n-angles", "3"],
                                     ["vcmm", "--machine", "vmc-3axis", "--task", "t.toml", "--json", "o.json"]])
def test_a_plan_given_as_an_argument_still_works_and_says_plan(command, capsys):
    """The old spelling (vmt design PLAN, vmt vcmm PLAN): the same arguments as --plan PLAN, one line on stderr;
    both at once, or neither, refused in one line."""
    parser = build_parser()
    old = parser.parse_args([*command, "p.csv"])
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "PLAN as a positional argument is renamed to --plan PLAN" in err, err
    new = parser.parse_args([*command, "--plan", "p.csv"])
    assert capsys.readouterr().err == ""
    assert vars(old) == vars(new) and new.plan == "p.csv"
    for argv, says in (([*command, "a.csv", "--plan", "p.csv"], "PLAN given twice"),
                       (command, "the following arguments are required: --plan")):
        with pytest.raises(SystemExit) as e:
            parser.parse_args(argv)
        err = capsys.readouterr().err
        assert e.value.code == 2 and err.count("\n") == 1 and says in err, err


def test_the_option_table_in_the_docs_is_the_parsers():
    """docs/cli-options.md lists every visible option of every command, each with the commands the parsers
    give it, and nothing else: the table of meanings cannot go stale."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "cli-options.md").read_text()
    rows = {m.group(1): {c.strip() for c in m.group(2).split(",")}
            for m in re.finditer(r"^\| `(--[a-z0-9-]+)` \| ([^|]+) \| [^|]+ \|$", text, re.M)}
    parsed = {n: {c.removeprefix("vmt ") for c, _ in uses} for n, uses in _options().items()}
    assert sorted(set(parsed) - set(rows)) == [], "options missing from docs/cli-options.md"
    assert sorted(set(rows) - set(parsed)) == [], "docs/cli-options.md lists options no command has"
    assert {n: c for n, c in rows.items() if c != parsed[n]} == {}, "commands differ from the parsers'"


def test_command_modules_keep_lines_within_120_characters():
    """The code base's line length (a handful of lines elsewhere pass it); the command modules held to it since
    session 38, when 24 lines of 121-176 characters were wrapped."""
    from pathlib import Path

    folder = Path(__file__).resolve().parents[2] / "scenarios" / "cli"
    long = [f"{p.name}:{i}: {len(line)}" for p in sorted(folder.glob("*.py"))
            for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if len(line) > 120]
    assert len(list(folder.glob("*.py"))) > 15 and not long, long
