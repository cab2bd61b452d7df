"""Real controllers in the loop: ``make test-controllers`` runs this folder; ``make test`` never collects it
(pyproject.toml's ``norecursedirs`` holds ``controllers``; ``tests/hardware/test_controllers_gate.py`` checks it).

Every test here needs LinuxCNC and fails, never skips, when it is missing (the Makefile's promise: the make target
installs it, so a missing LinuxCNC is a broken set-up, and a skipped run reads as a passed one). Session 35: the
probing loop failed while the rotary loop (session 34) skipped; both now fail through this one gate.
"""

import pytest

from core.exceptions import HardwareError
from hardware.linuxcnc_sim.loop import linuxcnc_path


@pytest.fixture(scope="session", autouse=True)
def linuxcnc_required():
    """Fail (one line: what is missing and how to install it) before any LinuxCNC test when the ``linuxcnc``
    launcher is not on PATH. Session-scoped, so it runs before the modules' own LinuxCNC runs (module fixtures)."""
    try:
        linuxcnc_path()
        return
    except HardwareError as e:
        why = str(e)
    pytest.fail(f"{why} (tests/controllers fail, never skip, without LinuxCNC)", pytrace=False)
