"""The package rules of CONTRIBUTING.md ("Map of the code"), checked on the source.

core never imports sim, hardware, viz, scenarios, mujoco or rerun; sim may
import core (and mujoco, trimesh, pinocchio); hardware may import core, and
sim only in the emulator and the virtual-machine module; viz may import core
(and rerun); scenarios may import everything.
"""

import ast
import functools
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
FORBIDDEN = {"sim", "hardware", "viz", "scenarios", "mujoco", "rerun", "pinocchio", "trimesh"}
#: The project's packages and the heavy libraries whose use the rules restrict.
RULED = {"core", "sim", "hardware", "viz", "scenarios", "mujoco", "rerun", "rerun_cli", "pinocchio", "trimesh"}
#: What each package may import of RULED (its own modules always).
ALLOWED = {
    "core": {"core"},
    "sim": {"sim", "core", "mujoco", "trimesh", "pinocchio"},
    "hardware": {"hardware", "core"},
    "viz": {"viz", "core", "rerun", "rerun_cli"},
}
#: The only hardware modules that may import sim: the GRBL emulator and the virtual machine.
HARDWARE_SIM = {"emulator.py", "virtual.py"}


@functools.cache
def _imports(f: pathlib.Path) -> tuple:
    """Top-level names of every absolute import in ``f`` (also those inside functions); each file
    parsed once for the two core checks."""
    out = []
    for node in ast.walk(ast.parse(f.read_text(), filename=str(f))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            names = [node.module or ""]
        else:
            continue
        out += [n.split(".")[0] for n in names]
    return tuple(out)


def test_core_source_imports_nothing_forbidden():
    for f in (ROOT / "core").rglob("*.py"):
        for n in _imports(f):
            assert n not in FORBIDDEN, f"{f.name} imports {n}"


@pytest.mark.parametrize("pkg", sorted(ALLOWED))
def test_package_imports_only_what_the_architecture_allows(pkg):
    bad = []
    for f in sorted((ROOT / pkg).rglob("*.py")):
        allowed = ALLOWED[pkg] | ({"sim"} if pkg == "hardware" and f.name in HARDWARE_SIM else set())
        bad += [f"{f.relative_to(ROOT)} imports {n}" for n in _imports(f) if n in RULED and n not in allowed]
    assert not bad, "; ".join(bad)


def test_the_rule_checker_sees_a_violation(tmp_path):
    """The checker is not vacuous: an import inside a function, and one of a submodule, are found."""
    f = tmp_path / "campaign.py"
    f.write_text("def f():\n    from sim.machine import Machine\n    import viz.record\n")
    assert sorted(_imports(f)) == ["sim", "viz"]


def _command_modules() -> set[str]:
    """The command modules, ``scenarios.cli.NAME``, as ``COMMANDS`` of ``scenarios/cli/__init__.py`` lists them
    (read from the source, not imported)."""
    tree = ast.parse((ROOT / "scenarios" / "cli" / "__init__.py").read_text())
    for node in ast.walk(tree):
        targets = getattr(node, "targets", None) or [getattr(node, "target", None)]
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and any(getattr(t, "id", "") == "COMMANDS" for t in targets):
            return {elt.elts[1].value for elt in node.value.elts}
    raise AssertionError("scenarios/cli/__init__.py: no COMMANDS list")


def _dotted_imports(f: pathlib.Path) -> list[str]:
    """Every absolute import of ``f`` as the dotted module it names (``from a.b import c`` gives ``a.b`` and
    ``a.b.c``: ``c`` may be a module), inside functions too."""
    out = []
    for node in ast.walk(ast.parse(f.read_text(), filename=str(f))):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out += [node.module] + [f"{node.module}.{a.name}" for a in node.names]
    return out


def _command_importers(files, commands, root=ROOT) -> list[str]:
    return [f"{f.relative_to(root)} imports {n}" for f in files for n in _dotted_imports(f)
            if any(n == c or n.startswith(c + ".") for c in commands)]


def test_nothing_imports_a_command_module_but_the_entry_point():
    """CONTRIBUTING.md ("Where new things go"): a command module is a leaf. Nothing imports it but the entry
    point (scenarios/cli/__init__.py, through COMMANDS): what two commands share goes to scenarios/cli/options.py,
    what anything else needs to its owner package (review31d F12: scenarios/regress.py imported
    scenarios.cli.discover for run_discover, now scenarios.discover_run; scenarios/cli/identify.py imported
    scenarios.cli.scenario for the declared-ripple options, now in options.py)."""
    commands = _command_modules()
    assert "scenarios.cli.discover" in commands and "scenarios.cli.regress" in commands
    files = [f for pkg in ("core", "sim", "hardware", "viz", "scenarios") for f in sorted((ROOT / pkg).rglob("*.py"))
             if f != ROOT / "scenarios" / "cli" / "__init__.py"]
    bad = _command_importers(files, commands)
    assert not bad, "; ".join(bad)


def test_the_command_rule_sees_a_violation(tmp_path):
    """The command rule's checker is not vacuous: each way of naming a command module inside a function is found,
    the entry point, the shared options and a module merely named like a command are not."""
    f = tmp_path / "study.py"
    f.write_text("def f():\n    from scenarios.cli.discover import run_discover\n    import scenarios.cli.regress as r\n"
                 "    from scenarios.cli import identify\n    from scenarios.cli import main\n"
                 "    from scenarios.cli.options import option\n    import scenarios.discover_run\n")
    got = [b.split(" imports ")[1] for b in _command_importers([f], _command_modules(), root=tmp_path)]
    assert got == ["scenarios.cli.discover", "scenarios.cli.discover.run_discover", "scenarios.cli.regress",
                   "scenarios.cli.identify"]


def test_importing_core_loads_no_mujoco_or_rerun():
    code = (
        "import sys, pkgutil, importlib, core\n"
        "for m in pkgutil.iter_modules(core.__path__):\n"
        "    importlib.import_module('core.' + m.name)\n"
        "bad = sorted(k for k in sys.modules if k.split('.')[0] in "
        "{'mujoco','rerun','sim','hardware','viz','pinocchio','trimesh'})\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, check=True)
    assert out.stdout.strip() == ""


def test_shipped_docs_stand_alone():
    """A user's clone has only the repository: its docs may not send readers outside it."""
    docs = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").glob("*.md"))]
    leaks = [f"{p.name}:{i}" for p in docs for i, ln in enumerate(p.read_text().splitlines(), 1)
             if "../shared" in ln or "shared/spec" in ln or "shared/papers" in ln]
    assert leaks == []
    assert "probe-log/1" in (ROOT / "docs" / "formats.md").read_text()
