#!/usr/bin/python3
"""vmt's headless LinuxCNC display: home, run one part program in AUTO, exit.

LinuxCNC starts it as ``./vmt_display.py -ini FILE`` (``[DISPLAY]DISPLAY``);
when it exits, LinuxCNC shuts down. It uses LinuxCNC's Python interface
(``linuxcnc.stat``, ``linuxcnc.command``, ``linuxcnc.error_channel``):
E-stop reset, machine on, home all joints, AUTO mode, open and run
``$VMT_PROGRAM``, wait for the interpreter to go idle. It writes
``$VMT_RESULT`` (JSON): the times from start to homed and of the run,
every message of the error channel, and whether the program ran to its end.
Exit status 0 when it did, 1 otherwise.
"""

import json
import os
import sys
import time

import linuxcnc

T0 = time.monotonic()


def main():
    out = {"ok": False, "errors": [], "messages": []}
    s, c, e = linuxcnc.stat(), linuxcnc.command(), linuxcnc.error_channel()
    timeout_s = float(os.environ.get("VMT_TIMEOUT_S", "600"))

    def drain():
        while True:
            m = e.poll()
            if not m:
                return
            kind, text = m
            (out["errors"] if kind in (linuxcnc.NML_ERROR, linuxcnc.OPERATOR_ERROR)
             else out["messages"]).append(text)

    def wait(cond, what, limit_s):
        end = time.monotonic() + limit_s
        while time.monotonic() < end:
            s.poll()
            drain()
            if cond():
                return
            time.sleep(0.002)
        raise TimeoutError(f"{what}: not done after {limit_s:g} s (task_state {s.task_state}, "
                           f"estop {s.estop}, enabled {s.enabled}, homed {s.homed[:s.joints]}, "
                           f"interp_state {s.interp_state}, exec_state {s.exec_state})")

    try:
        # task may not listen yet when the display starts: repeat each state change until it shows
        for state, what in ((linuxcnc.STATE_ESTOP_RESET, "E-stop reset"), (linuxcnc.STATE_ON, "machine on")):
            for attempt in range(40):
                c.state(state)
                c.wait_complete(1.0)
                try:
                    wait(lambda: s.task_state == state, what, 0.5)
                    break
                except TimeoutError:
                    if attempt == 39:
                        raise
        c.mode(linuxcnc.MODE_MANUAL)
        c.wait_complete()
        c.teleop_enable(0)
        c.wait_complete()
        c.home(-1)
        c.wait_complete()
        wait(lambda: all(s.homed[j] for j in range(s.joints)), "homing", 30)
        out["homed_s"] = time.monotonic() - T0
        c.mode(linuxcnc.MODE_AUTO)
        c.wait_complete()
        c.program_open(os.environ["VMT_PROGRAM"])
        c.wait_complete()
        t_run = time.monotonic()
        c.auto(linuxcnc.AUTO_RUN, 0)
        c.wait_complete()
        try:
            wait(lambda: s.interp_state != linuxcnc.INTERP_IDLE, "program start", 2)
        except TimeoutError:   # a program without motion may be over before the first poll
            out["messages"].append("vmt_display: the interpreter was never seen running")
        wait(lambda: s.interp_state == linuxcnc.INTERP_IDLE, "program", timeout_s)
        out["run_s"] = time.monotonic() - t_run
        drain()
        out["ok"] = not out["errors"]
    except Exception as ex:  # report every failure in the result file, then exit non-zero
        out["errors"].append(f"{type(ex).__name__}: {ex}")
    out["total_s"] = time.monotonic() - T0
    with open(os.environ["VMT_RESULT"], "w") as f:
        json.dump(out, f)
    return 0 if out["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
