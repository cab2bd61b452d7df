#!/usr/bin/python3
"""HAL userspace component ``vmtprobe``: where the current probing move meets the part.

Runs under LinuxCNC's own Python (it needs LinuxCNC's ``hal`` module), as
the unprivileged user running LinuxCNC. It imports nothing of vmt: vmt's
virtual machine runs in the vmt process that started LinuxCNC
(``hardware/linuxcnc_sim/loop.py``) and answers over a local TCP socket
(``$VMT_CONTACT``, ``host:port``), one line per question::

    probe x y z dx dy dz      ->  hit qx qy qz   |   miss

(machine coordinates, mm: a ray from the point ``x y z`` along the unit
direction ``d``; ``q`` is the axis position at which the virtual machine's
probe triggers).

Polling at about 1 kHz, the component watches ``motion-type``. When a
probing move starts (type 5) it takes the first position ``p1`` it sees and,
once the machine is 50 um further, the direction ``d`` of the move (a
LinuxCNC probing move is a straight line, so two points fix it to rounding).
It asks where the ray ``p1 + s d`` triggers and publishes, for the axis ``i``
with the largest ``|d_i|``, ``sel`` (that axis), ``sign = sign(d_i)`` and
``threshold = sign * q_i``, then sets ``armed``. The comparison itself runs
in the servo thread (vmt_sim.hal), so the trigger does not depend on this
loop's timing; the loop only has to answer before the machine gets there
(it logs ``late`` otherwise). Every question and answer is appended to
``$VMT_PROBE_LOG`` as one JSON line.
"""

import json
import math
import os
import socket
import sys
import time

import hal

PROBING = 5          # motion.motion-type of a G38.x move (EMC_MOTION_TYPE_PROBING)
MIN_TRAVEL_MM = 0.05


def position(h):
    """The machine position (x, y, z) of one servo period.

    The three pins are read one by one from userspace while the servo thread
    updates them: a read that straddles an update mixes two periods (up to
    feed x period, 0.5 um at 30 mm/min, on one axis), which tilts the
    direction taken from two such reads by 0.5 um / travel and moves the
    trigger point along the ray by that tilt times the ray's length (several
    um on a loaded machine). Reading until two successive triplets agree
    gives a triplet of one period (a moving axis changes every period).
    """
    p = (h["x"], h["y"], h["z"])
    while True:
        q = (h["x"], h["y"], h["z"])
        if q == p:
            return p
        p = q


def main():
    host, port = os.environ["VMT_CONTACT"].rsplit(":", 1)
    log = open(os.environ["VMT_PROBE_LOG"], "a", buffering=1)
    conn = socket.create_connection((host, int(port)), timeout=30)
    rfile = conn.makefile("r")

    h = hal.component("vmtprobe")
    for n in ("x", "y", "z"):
        h.newpin(n, hal.HAL_FLOAT, hal.HAL_IN)
    h.newpin("motion-type", hal.HAL_S32, hal.HAL_IN)
    h.newpin("probe-in", hal.HAL_BIT, hal.HAL_IN)
    h.newpin("sel0", hal.HAL_BIT, hal.HAL_OUT)
    h.newpin("sel1", hal.HAL_BIT, hal.HAL_OUT)
    h.newpin("sign", hal.HAL_FLOAT, hal.HAL_OUT)
    h.newpin("threshold", hal.HAL_FLOAT, hal.HAL_OUT)
    h.newpin("armed", hal.HAL_BIT, hal.HAL_OUT)
    h["sign"] = 1.0
    h["threshold"] = 1e9
    h.ready()

    p1 = None          # first position seen in the current probing move
    asked = False
    n_move = 0
    try:
        while True:
            mt = h["motion-type"]
            p = position(h)
            if mt != PROBING:
                if h["armed"]:
                    h["armed"] = False
                p1, asked = None, False
            elif p1 is None:
                p1 = p
            elif not asked:
                v = [b - a for a, b in zip(p1, p)]
                L = math.sqrt(sum(c * c for c in v))
                if L >= MIN_TRAVEL_MM:
                    d = [c / L for c in v]
                    conn.sendall(("probe %.17g %.17g %.17g %.17g %.17g %.17g\n"
                                  % (*p1, *d)).encode())
                    ans = rfile.readline().split()
                    rec = {"move": n_move, "p1_mm": p1, "d": d}
                    if ans and ans[0] == "hit":
                        q = [float(c) for c in ans[1:4]]
                        i = max(range(3), key=lambda k: abs(d[k]))
                        sign = 1.0 if d[i] > 0 else -1.0
                        h["armed"] = False
                        h["sel0"] = bool(i & 1)
                        h["sel1"] = bool(i & 2)
                        h["sign"] = sign
                        h["threshold"] = sign * q[i]
                        now = position(h)
                        rec.update(q_mm=q, axis=i, late=bool(sign * now[i] >= sign * q[i]))
                        h["armed"] = True
                    else:
                        rec.update(q_mm=None)
                    log.write(json.dumps(rec) + "\n")
                    asked = True
                    n_move += 1
            time.sleep(0.001)
    except KeyboardInterrupt:
        pass
    finally:
        conn.close()
        log.close()


if __name__ == "__main__":
    sys.exit(main())
