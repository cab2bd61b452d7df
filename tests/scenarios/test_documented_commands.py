"""The commands the user's pages show run as written (session 36, cmds36).

A user's first hour is README.md, CONTRIBUTING.md and docs/*.md. Two checks keep their commands true:

- every ``vmt`` line of every command block in those pages (``sh``, ``text`` or untagged fences; a ``$ vmt``
  line of a transcript; ``\\`` continuations joined; ``.venv/bin/vmt`` too) is read by the command line's own
  parser (:func:`scenarios.cli._parser`): a sub-command or option renamed or removed fails here, and so
  does a page still using an old name kept as an alias (it prints "is renamed to" on stderr);
- every ``--option`` of a prose span such as `vmt scenario mfb-3axis --comp DIR` (a fragment, placeholders and
  all) is an option of that command, under its current name;
- a block marked ``<!-- run ... -->`` on the line before its fence runs: a ``sh`` block line by line, as
  written, in a scratch folder (``scenarios/data`` reachable as from the repository's root), each line exit
  0 and every output it names (``--out``, ``--json``, ``--report``, ``--junit``) written; a ``text`` block
  that starts with ``$ vmt ...`` is a transcript, and the command must print the block's remaining lines,
  stdout then stderr, exactly.

Only cheap commands are marked (README's first session and the ISO 230-2 sample: about 15 s of CPU in one
process); the rest, run once by hand in session 36 against the simulator, the GRBL emulator and LinuxCNC
files in LinuxCNC's format, are listed in that session's report.
"""

from __future__ import annotations

import argparse
import re
import shlex
from pathlib import Path

import pytest

from scenarios.cli import _parser, main

ROOT = Path(__file__).resolve().parents[2]
PAGES = ["README.md", "CONTRIBUTING.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^\s*```(\S*)\s*$")
RUN_MARK = re.compile(r"^\s*<!--\s*run\b")
OUTPUT_OPTIONS = ("--out", "--json", "--report", "--junit")


def blocks(text: str):
    """(line number of the fence, its tag, marked to run, [(line number, line)]) of each fenced block."""
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        start, tag = i, m.group(1)
        marked = i > 0 and bool(RUN_MARK.match(lines[i - 1]))
        body = []
        i += 1
        while i < len(lines) and not FENCE.match(lines[i]):
            body.append((i + 1, lines[i]))
            i += 1
        yield start + 1, tag, marked, body
        i += 1


def commands(body):
    """(line number, argv after ``vmt``) of each ``vmt`` command of a block, continuations joined, comments dropped."""
    out = []
    transcript = any(line.strip().startswith("$ ") for _n, line in body)   # then only the $ lines are commands
    it = iter(body)
    for n, line in it:
        s = line.strip()
        if s.startswith("$ "):
            s = s[2:].lstrip()
        elif transcript or re.match(r"vmt [\w-]+:", s):     # output, or a message of vmt's ("vmt iso230-2: warning")
            continue
        for prefix in (".venv/bin/vmt ", "vmt "):
            if s.startswith(prefix) or s == prefix.strip():
                s = "vmt " + s[len(prefix):]
                break
        else:
            continue
        while s.endswith("\\"):
            s = s[:-1] + " " + next(it)[1].strip()
        argv = shlex.split(s, comments=True)
        out.append((n, argv[1:]))
    return out


def documented():
    return list(_documented())


def _documented():
    for page in PAGES:
        for _start, tag, _marked, body in blocks((ROOT / page).read_text(encoding="utf-8")):
            if tag in ("", "sh", "bash", "shell", "console", "text"):
                for n, argv in commands(body):
                    yield pytest.param(argv, id=f"{page}:{n}")


def test_pages_hold_commands():
    """The extraction finds the pages' commands (a changed fence style would otherwise pass vacuously)."""
    found = list(documented())
    assert len(found) >= 40
    readme = [p for p in found if p.id.startswith("README.md:")]
    assert any(p.values[0][:1] == ["identify"] for p in readme)
    assert any(p.values[0][:2] == ["scenario", "mfb-3axis"] for p in readme)


@pytest.mark.parametrize("argv", documented())
def test_documented_command_parses(argv, capsys):
    """Each documented command is one the parser takes, under today's names."""
    try:
        args = _parser().parse_args(argv)
    except SystemExit as e:                     # --help: printed, exit 0; a bad option: one line, exit 2
        assert e.code == 0, capsys.readouterr().err
    else:
        assert getattr(args, "func", None), argv
    err = capsys.readouterr().err
    assert "renamed" not in err, err


def _subcommands(p):
    return next((a.choices for a in p._actions if isinstance(a, argparse._SubParsersAction)), {})


def _inline_options():
    """(page:line, the span, an option) of each ``--option`` in a prose span such as `vmt scenario mfb-3axis
    --comp DIR` (outside the command blocks): fragments with placeholders, so only their option names are read."""
    for page in PAGES:
        lines = (ROOT / page).read_text(encoding="utf-8").splitlines()
        fenced = set()
        for start, _tag, _marked, body in blocks("\n".join(lines)):
            fenced.update(range(start, (body[-1][0] if body else start) + 2))
        prose = "\n".join("" if i + 1 in fenced else ln for i, ln in enumerate(lines))
        for m in re.finditer(r"`(vmt [^`]*)`", prose):
            toks = m.group(1).split()[1:]
            p, i = _parser(), 0
            while i < len(toks) and toks[i] in _subcommands(p):
                p, i = _subcommands(p)[toks[i]], i + 1
            if i == 0:
                continue
            for tok in toks[i:]:
                if tok.startswith("--"):
                    yield f"{page}:{prose[:m.start()].count(chr(10)) + 1}", " ".join(toks), p, tok.split("=")[0]


def test_prose_commands_name_real_options():
    """Every option a prose `vmt ...` span names is its command's, under today's name (not a renamed alias)."""
    from scenarios.cli.options import Renamed

    seen, bad = 0, []
    for where, span, p, opt in _inline_options():
        actions = {o: a for a in p._actions for o in a.option_strings}
        seen += 1
        if opt not in actions or isinstance(actions[opt], Renamed):
            bad.append(f"{where}: `vmt {span}`: {opt} " + ("is renamed" if opt in actions else "is not an option"))
    assert seen >= 50 and not bad, bad


def _marked(page: str, tag: str):
    return [body for _s, t, marked, body in blocks((ROOT / page).read_text(encoding="utf-8")) if marked and t == tag]


@pytest.fixture
def scratch(tmp_path, monkeypatch):
    """A folder where ``scenarios/data/...`` reads the repository's data, as from its root."""
    (tmp_path / "scenarios").mkdir()
    (tmp_path / "scenarios" / "data").symlink_to(ROOT / "scenarios" / "data")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _outputs(argv):
    out = []
    for i, a in enumerate(argv):
        name, eq, value = a.partition("=")
        if name in OUTPUT_OPTIONS:
            out.append(value if eq else argv[i + 1])
    return out


def test_readme_first_session_runs_as_written(scratch, capsys):
    """README's marked block: every line exits 0 and writes what it names; the plan is the 368 touches it says."""
    bodies = _marked("README.md", "sh")
    assert len(bodies) == 1, "README marks one sh block to run"
    cmds = commands(bodies[0])
    assert len(cmds) >= 8
    for n, argv in cmds:
        try:
            rc = main(argv)
        except SystemExit as e:                 # vmt --help
            rc = e.code
        err = capsys.readouterr().err
        assert rc == 0, f"README.md:{n}: vmt {' '.join(argv)}: exit {rc}: {err}"
        for o in _outputs(argv):
            p = scratch / o
            assert p.is_file() and p.stat().st_size > 0 or (p / "index.html").is_file(), \
                f"README.md:{n}: {o} not written"
    from core.probelog import read_probe_log

    if (scratch / "plan.csv").exists():         # the block's comment: 368 touches at C = 0, 75, 130, 210
        plan = read_probe_log(scratch / "plan.csv")
        assert len(plan) == 368


def test_readme_transcripts_print_as_documented(scratch, capsys):
    """README's marked transcripts (``$ vmt ...`` and its output) print exactly their output, stdout then stderr."""
    bodies = _marked("README.md", "text")
    assert bodies, "README marks its ISO 230-2 sample's transcript to run"
    for body in bodies:
        (n, argv), = commands(body)
        first = next(i for i, (m, _l) in enumerate(body) if m == n)
        rest = body[first:]
        while rest[0][1].rstrip().endswith("\\"):
            rest = rest[1:]
        expected = [line for _m, line in rest[1:]]
        assert main(argv) == 0
        got = capsys.readouterr()
        assert got.out.splitlines() + got.err.splitlines() == expected, f"README.md:{n}"


def _all_parsers(p, path=("vmt",)):
    yield " ".join(path), p
    for name, sub in _subcommands(p).items():
        yield from _all_parsers(sub, (*path, name))


@pytest.mark.parametrize("columns", ["80", "60"])
def test_help_text_names_whole_options(columns, monkeypatch):
    """Every ``--option`` a command's --help mentions is a real option of vmt, at any terminal width: argparse
    wrapped at hyphens, so iso230-2's advice "write --comp-range-deg=-400:800 when LO < 0" read
    ``--comp-range-`` / ``deg=-400:800`` at 80 columns (scenarios.cli.guard._WholeNames)."""
    monkeypatch.setenv("COLUMNS", columns)
    parsers = list(_all_parsers(_parser()))
    known = {o for _n, p in parsers for a in p._actions for o in a.option_strings}
    bad, seen = [], 0
    for name, p in parsers:
        for m in re.finditer(r"(?<![\w-])--[a-z][a-z0-9-]*", p.format_help()):
            seen += 1
            if m.group(0) not in known:
                bad.append(f"{name} --help: {m.group(0)!r}")
    assert seen >= 300 and not bad, bad
