"""The study commands the pages show (``python -m scenarios.<study> ...``) name options their study takes
(session 38, cli38).

``tests/scenarios/test_documented_commands.py`` reads every ``vmt`` line and prose span with vmt's own parser;
the studies run as ``python -m scenarios.<study>`` (coverage, compensation rules, the fit and range studies)
build their parser inside ``main()`` or read ``sys.argv`` by hand, so here every ``--option`` of such a command
on README.md, CONTRIBUTING.md and docs/*.md must be one the study's module spells (``"--option"`` in its source),
and the module must exist and have a ``main`` (``python -m scenarios.cli ...`` is vmt: its commands' options).
A sentence naming an option apart from its command ("`bench` ... the `--out` file", which README said after
``bench --out`` became ``--json``) is not read: found by hand in session 38, too loose a pattern for a test.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PAGES = ["README.md", "CONTRIBUTING.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))]
STUDY = re.compile(r"python -m scenarios\.([a-z_0-9.]+)((?:[ \t]+(?:\\\n)?[^`\n|;]*)?)")


def study_commands():
    """(page:line, module, [--options]) of each ``python -m scenarios.<study>`` on the pages."""
    out = []
    for page in PAGES:
        text = (ROOT / page).read_text(encoding="utf-8")
        for m in STUDY.finditer(text):
            opts = re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", m.group(2))
            out.append((f"{page}:{text[:m.start()].count(chr(10)) + 1}", m.group(1), opts))
    return out


def test_pages_hold_study_commands():
    found = study_commands()
    assert len(found) >= 8 and sum(len(o) for _w, _m, o in found) >= 8, found


def test_study_commands_name_their_studys_options():
    from scenarios.cli import _parser

    bad = []
    for where, mod, opts in study_commands():
        if mod == "cli":        # vmt itself (``python -m scenarios.cli bench --only ...``): its own parser's words
            known = {o for a in _parser()._actions for sp in getattr(a, "choices", None) or {}
                     for b in getattr((a.choices or {}).get(sp), "_actions", ()) for o in b.option_strings}
            bad += [f"{where}: python -m scenarios.cli {o}: no vmt command takes it" for o in opts if o not in known]
            continue
        src = ROOT / "scenarios" / f"{mod.replace('.', '/')}.py"
        if not src.is_file() and (ROOT / "scenarios" / mod.replace(".", "/") / "__main__.py").is_file():
            src = ROOT / "scenarios" / mod.replace(".", "/") / "__main__.py"
        if not src.is_file():
            bad.append(f"{where}: scenarios.{mod}: no such module")
            continue
        text = src.read_text(encoding="utf-8")
        if "def main(" not in text and not src.name == "__main__.py" and "__main__" not in text:
            bad.append(f"{where}: scenarios.{mod} has no main()")
        bad += [f"{where}: scenarios.{mod} {o}: not an option of the study" for o in opts if f'"{o}"' not in text]
    assert not bad, "\n".join(bad)
