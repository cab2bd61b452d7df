"""``vmt view RUN.rrd``: open a recording in the rerun viewer.

The viewer is the ``rerun`` executable of the installed rerun-sdk (so its
version matches the recordings vmt writes), or ``$RERUN_CLI_PATH``, or a
``rerun`` on ``PATH``. It runs in the foreground until its window is closed.
A missing file, a missing viewer, no display or a viewer that fails to start
is one error line and exit status 2.
"""

from __future__ import annotations

import subprocess

from viz.viewer import has_display, viewer_command


def register(sub) -> None:
    p = sub.add_parser("view", help="open a .rrd recording in the rerun viewer")
    p.add_argument("rrd", help="rerun recording (.rrd) written by vmt")
    p.add_argument("--print-command", action="store_true",
                   help="print the viewer command instead of running it")
    p.set_defaults(func=run)


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
