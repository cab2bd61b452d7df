#!/usr/bin/python3
"""HAL userspace component ``vmtjoints``: each joint's command and motor command at every stop.

Runs under LinuxCNC's own Python (it needs LinuxCNC's ``hal`` module), as the
unprivileged user running LinuxCNC; it imports nothing of vmt. Started as
``vmt_joints.py N`` (``loadusr -Wn vmtjoints``), it has, for joints
``0 .. N-1``, the input pins ``<j>.pos-cmd`` (what the trajectory commands,
``joint.<j>.pos-cmd``), ``<j>.motor-pos-cmd`` (what LinuxCNC sends the motor:
pos-cmd plus the joint's compensation, ``output_to_hal()`` in control.c) and
``<j>.motor-offset``.

Polling at about 1 kHz, it reads all pins as one servo period's set (until two
successive reads agree: the servo thread updates them while a userspace read
goes on). When that set has not changed for ``SETTLE_S`` and differs from the
last one written, it appends it to ``$VMT_JOINT_LOG`` as one JSON line
(``pos_cmd``, ``motor_pos_cmd``, ``motor_offset``: lists of N floats; JSON writes
each double's shortest round-trip form, so they come back exactly). A part program
that dwells at each stop longer than ``SETTLE_S`` (``G4``) gets one line per
stop; the start-up and homing states come first.
"""

import json
import os
import sys
import time

import hal

SETTLE_S = 0.1


def snapshot(h, names):
    """All pins of one servo period (read until two successive reads agree)."""
    p = tuple(h[n] for n in names)
    while True:
        q = tuple(h[n] for n in names)
        if q == p:
            return p
        p = q


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    h = hal.component("vmtjoints")
    kinds = ("pos-cmd", "motor-pos-cmd", "motor-offset")
    names = [f"{j}.{k}" for k in kinds for j in range(n)]
    for name in names:
        h.newpin(name, hal.HAL_FLOAT, hal.HAL_IN)
    h.ready()
    log = open(os.environ["VMT_JOINT_LOG"], "a", buffering=1)
    last_written, current, since = None, None, time.monotonic()
    try:
        while True:
            s = snapshot(h, names)
            now = time.monotonic()
            if s != current:
                current, since = s, now
            elif s != last_written and now - since >= SETTLE_S:
                rec = {k.replace("-", "_"): [float(v) for v in s[i * n:(i + 1) * n]] for i, k in enumerate(kinds)}
                log.write(json.dumps(rec) + "\n")
                last_written = s
            time.sleep(0.001)
    except KeyboardInterrupt:
        pass
    finally:
        log.close()


if __name__ == "__main__":
    sys.exit(main())
