"""The rule that carries the design: core never imports sim, hardware, viz,
scenarios, mujoco or rerun."""

import ast
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
FORBIDDEN = {"sim", "hardware", "viz", "scenarios", "mujoco", "rerun", "pinocchio", "trimesh"}


def test_core_source_imports_nothing_forbidden():
    for f in (ROOT / "core").rglob("*.py"):
        tree = ast.parse(f.read_text(), filename=str(f))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module or ""]
            else:
                continue
            for n in names:
                assert n.split(".")[0] not in FORBIDDEN, f"{f.name} imports {n}"


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
