"""The module maps (README "Layout", CONTRIBUTING "Map of the code") name every module that exists.

A map that leaves modules out sends a reader looking in the wrong place; this
check makes a new module's author add its line.
"""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "sim", "hardware", "viz", "scenarios")


def _row(doc: str, package: str) -> str:
    """The map table's row of ``package`` in ``doc`` (the line starting ``| `package/` |``)."""
    rows = [ln for ln in (ROOT / doc).read_text(encoding="utf-8").splitlines()
            if ln.startswith(f"| `{package}/` |")]
    assert len(rows) == 1, f"{doc}: expected one map row for {package}/, found {len(rows)}"
    return rows[0]


def _members(package: str) -> set[str]:
    """Top-level modules (without ``__init__``) and sub-folders of a package."""
    d = ROOT / package
    mods = {p.stem for p in d.glob("*.py") if p.stem != "__init__"}
    dirs = {p.name + "/" for p in d.iterdir() if p.is_dir() and not p.name.startswith((".", "__"))}
    return mods | dirs


@pytest.mark.parametrize("doc", ["README.md", "CONTRIBUTING.md"])
@pytest.mark.parametrize("package", PACKAGES)
def test_module_map_names_every_module(doc, package):
    row = _row(doc, package)
    named = set(re.findall(r"`([A-Za-z0-9_./-]+)`", row))
    named |= {n.removesuffix(".py") for n in named} | {n.split("/")[0] for n in named}
    missing = sorted(m for m in _members(package) if m not in named and m.rstrip("/") not in named)
    assert not missing, f"{doc}: the {package}/ row of the module map does not name {', '.join(missing)}"
