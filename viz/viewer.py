"""Find and start the rerun viewer for a ``.rrd`` recording (``vmt view``).

The viewer is the ``rerun`` executable of the installed rerun-sdk (so its
version matches the recordings vmt writes), or ``$RERUN_CLI_PATH``, or a
``rerun`` on ``PATH``. :func:`viewer_command` names the problem (missing
file, not a recording, no viewer) as a :class:`core.exceptions.VmtError`.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path


def find_viewer(env: dict | None = None) -> str | None:
    """Path of the rerun viewer executable, or None.

    Order: ``$RERUN_CLI_PATH``; the binary bundled with the installed
    ``rerun_cli`` package; ``rerun`` on ``PATH``.
    """
    env = os.environ if env is None else env
    if env.get("RERUN_CLI_PATH"):
        p = env["RERUN_CLI_PATH"]
        return p if os.path.isfile(p) and os.access(p, os.X_OK) else None
    try:
        import rerun_cli  # only locates the binary; imports nothing heavy

        exe = "rerun.exe" if sys.platform.startswith("win") else "rerun"
        bundled = Path(rerun_cli.__file__).parent / exe
        if bundled.is_file() and os.access(bundled, os.X_OK):
            return str(bundled)
    except ImportError:
        pass
    return shutil.which("rerun", path=env.get("PATH"))


def viewer_command(rrd, *, env: dict | None = None) -> list[str]:
    """The command that opens ``rrd`` in the viewer: ``[rerun, PATH.rrd]``.

    Raises
    ------
    VmtError
        If the file does not exist or no viewer executable is found.
    """
    from core.exceptions import VmtError

    path = Path(rrd)
    if not path.is_file():
        raise VmtError(f"{rrd}: no such file")
    if path.suffix.lower() != ".rrd":
        raise VmtError(f"{rrd}: not a rerun recording (expected a .rrd file)")
    exe = find_viewer(env)
    if exe is None:
        raise VmtError("no rerun viewer found (install rerun-sdk, or set RERUN_CLI_PATH)")
    return [exe, str(path)]


def has_display(env: dict | None = None, platform: str = sys.platform) -> bool:
    """False on Linux/BSD without ``$DISPLAY`` or ``$WAYLAND_DISPLAY``."""
    env = os.environ if env is None else env
    if platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return bool(env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"))
    return True
