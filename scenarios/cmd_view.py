"""``vmt view RUN.rrd``: open a recording in the rerun viewer.

The viewer is the ``rerun`` executable of the installed rerun-sdk (so its
version matches the recordings vmt writes), or ``$RERUN_CLI_PATH``, or a
``rerun`` on ``PATH``. It runs in the foreground until its window is closed.
A missing file, a missing viewer, no display or a viewer that fails to start
is one error line and exit status 2.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("view", help="open a .rrd recording in the rerun viewer")
    p.add_argument("rrd", help="rerun recording (.rrd) written by vmt")
    p.add_argument("--print-command", action="store_true",
                   help="print the viewer command instead of running it")
    p.set_defaults(func=run)


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


def run(args) -> int:
    from core.exceptions import VmtError

    cmd = viewer_command(args.rrd)
    if args.print_command:
        print(" ".join(cmd))
        return 0
    if not has_display():
        raise VmtError(f"no display to open the viewer on (DISPLAY unset); copy {args.rrd} "
                       "to a machine with a display and run `rerun` on it")
    try:
        rc = subprocess.call(cmd)
    except OSError as e:
        raise VmtError(f"cannot start the rerun viewer {cmd[0]}: {e.strerror}") from None
    if rc != 0:
        raise VmtError(f"the rerun viewer exited with status {rc}")
    return 0
