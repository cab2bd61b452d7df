"""The gate of tests/controllers (real LinuxCNC), checked without LinuxCNC (session 35).

``make test-controllers`` promises (Makefile) that its tests fail, never skip, when they cannot run: a skipped
run would read as a passed one. Session 34 left the probing loop failing and the rotary loop skipping without
LinuxCNC; one autouse fixture (tests/controllers/conftest.py) now fails both. ``make test`` must never reach
them (it must stay green on a machine without LinuxCNC): pyproject's ``norecursedirs`` keeps pytest out of the
folder when it recurses from ``testpaths``, while a path given on the command line (the make target's
``tests/controllers``) is collected.

Neither check starts LinuxCNC: the gate's run has a PATH without the ``linuxcnc`` launcher (the gate fails every
test before its body), and the collection check runs a throw-away project with the real ini options.
"""

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _pytest(args, cwd, env=None):
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:randomly",
                           *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=600)


def _counts(out: str) -> dict:
    """pytest's last summary line as {outcome: count} (``3 failed, 9 errors in 4.2s``)."""
    last = [ln for ln in out.splitlines() if re.search(r"\bin [0-9.]+s", ln)][-1]
    return {k: int(n) for n, k in re.findall(r"(\d+) (passed|failed|errors?|skipped|xfailed|xpassed|deselected)",
                                             last)}


def test_without_linuxcnc_every_controller_test_fails_and_none_skips(tmp_path):
    """tests/controllers run with no ``linuxcnc`` on PATH (the interpreter's folder only): every test fails at the
    gate, one line naming the missing launcher and how to install it; none skips, none passes, LinuxCNC never
    starts (it is not on PATH). Before the gate the rotary module's 6 tests skipped."""
    path = str(Path(sys.executable).parent)
    assert not (Path(path) / "linuxcnc").exists()
    env = {**os.environ, "PATH": path, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "TMPDIR": str(tmp_path), "COLUMNS": "1000"}    # pytest cuts summary lines to the terminal's width
    r = _pytest(["-p", "no:xdist", "-rfEs", "tests/controllers"], ROOT, env)
    out = r.stdout + r.stderr
    n = _counts(out)
    assert r.returncode == 1, out[-3000:]
    assert n.get("skipped", 0) == 0 and n.get("passed", 0) == 0, out[-3000:]
    collected = n.get("failed", 0) + n.get("errors", n.get("error", 0))
    assert collected >= 12, out[-3000:]       # the probing loop's 6 tests and the rotary loop's 6
    said = ("linuxcnc not found: install Debian's linuxcnc-uspace (apt-get install -y linuxcnc-uspace; make "
            "test-controllers does) (tests/controllers fail, never skip, without LinuxCNC)")
    # the gate's line closes one short-summary line per test (the error sections repeat it above them)
    summary = [ln for ln in out.splitlines()
               if ln.startswith(("ERROR ", "FAILED ")) and ln.endswith(" - Failed: " + said)]
    assert len(summary) == collected and len({ln.split(" - ")[0] for ln in summary}) == collected, out[-3000:]
    assert "During handling" not in out and "raise HardwareError" not in out    # the line alone, no traceback
    assert "test_linuxcnc_rotary.py" in out and "test_linuxcnc_loop.py" in out


def test_make_test_does_not_collect_the_controller_tests(tmp_path):
    """The repository's pytest options (pyproject.toml) on a throw-away tree: a plain run (testpaths, as ``make
    test`` runs it: no path given) collects tests/ but not tests/controllers; the make target's explicit path
    collects it. And the Makefile's ``test`` recipe names no path, its ``test-controllers`` recipe that one."""
    opts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert opts["testpaths"] == ["tests"] and "controllers" in opts["norecursedirs"]
    ini = "[tool.pytest.ini_options]\n" + "".join(
        f"{k} = {v!r}\n".replace("'", '"') for k, v in opts.items() if k in ("testpaths", "norecursedirs"))
    (tmp_path / "pyproject.toml").write_text(ini)
    (tmp_path / "tests" / "controllers").mkdir(parents=True)
    (tmp_path / "tests" / "test_plain.py").write_text("def test_plain():\n    pass\n")
    (tmp_path / "tests" / "controllers" / "test_real.py").write_text("def test_real():\n    assert False\n")
    r = _pytest(["-p", "no:xdist", "--rootdir", str(tmp_path)], tmp_path)
    assert r.returncode == 0 and _counts(r.stdout) == {"passed": 1}, r.stdout
    r = _pytest(["-p", "no:xdist", "--rootdir", str(tmp_path), "tests/controllers"], tmp_path)
    assert r.returncode == 1 and _counts(r.stdout) == {"failed": 1}, r.stdout
    make = (ROOT / "Makefile").read_text()
    test_recipe = make.split("\ntest: ", 1)[1].split("\n\n", 1)[0]
    assert "tests/" not in test_recipe and "pytest" in test_recipe
    ctl = make.split("\ntest-controllers: ", 1)[1].split("\n\n", 1)[0]
    assert "pytest" in ctl and ctl.rstrip().endswith("tests/controllers")
