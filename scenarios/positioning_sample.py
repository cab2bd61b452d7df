"""Make ``scenarios/data/positioning-sample.csv``: a laser test of a 800 mm Y axis, as a shop would log it.

Written apart from ``sim/`` (no machine model): the deviations follow a
stated recipe, so the sample has known causes a reader (or a discovery
engine) can look for. Rewrite it with

    python -m scenarios.positioning_sample

Recipe (deviation of the reading from the target, µm; P in mm, t in s):

- scale error 15 µm/m: ``0.015 P``
- screw pitch error, period 10 mm, 1.8 µm: ``1.8 sin(2 pi P / 10 + 0.7)``
- lost motion 3 µm, the axis lags: ``-1.5`` approaching in +, ``+1.5`` in -
- warm-up drift 3.5 µm, time constant 20 min: ``3.5 (1 - exp(-t / 1200))``
- scatter 0.35 µm (k = 1), seeded
- cycle 3, target 4, approach +: the beam was interrupted (status), the
  reading was retaken after the last cycle.

Targets: 9 over 0..800 mm, ISO 230-2 ``P_i = (i - 1) p + r`` with r fixed
below; linear cycle, 5 cycles, 2000 mm/min, 3 s dwell, 5 mm overrun.
"""

import math
from pathlib import Path

import numpy as np

TARGETS = [0.0, 96.357, 203.118, 297.904, 405.771, 502.643, 598.21, 704.486, 800.0]
FEED = 2000 / 60.0  # mm/s
DWELL, OVERRUN = 3.0, 5.0
#: The sample file (packaged with scenarios).
SAMPLE = Path(__file__).with_name("data") / "positioning-sample.csv"


def deviation_um(p, d, t, rng):
    return (0.015 * p + 1.8 * math.sin(2 * math.pi * p / 10 + 0.7) - 1.5 * d
            + 3.5 * (1 - math.exp(-t / 1200)) + rng.normal(0, 0.35))


def main(path=SAMPLE):
    """Write the sample to ``path`` (default: the packaged file)."""
    rng = np.random.default_rng(230_2)
    rows, pos, t = [], TARGETS[0] - OVERRUN, 0.0

    def go(x):
        nonlocal pos, t
        t += abs(x - pos) / FEED
        pos = x

    def read(i, j, d, status="ok"):
        nonlocal t
        go(TARGETS[i])
        t += DWELL
        p = TARGETS[i]
        meas = "" if status != "ok" else repr(round(p + deviation_um(p, d, t, rng) / 1000, 6))
        scale = 20.4 + 0.6 * (1 - math.exp(-t / 1200)) + rng.normal(0, 0.01)
        air = 20.9 + 0.3 * (1 - math.exp(-t / 2400)) + rng.normal(0, 0.02)
        rows.append(f"{p},{j},{'+' if d > 0 else '-'},{meas},{t:.1f},{scale:.2f},{air:.2f},{status}")

    for j in range(1, 6):
        for i in range(len(TARGETS)):
            read(i, j, +1, "beam interrupted" if (j, i) == (3, 3) else "ok")
        go(TARGETS[-1] + OVERRUN)
        for i in reversed(range(len(TARGETS))):
            read(i, j, -1)
        go(TARGETS[0] - OVERRUN)
    go(TARGETS[3] - OVERRUN)
    read(3, 3, +1)  # the retake
    head = ["# format: positioning-log/1", "# axis: Y", "# unit: mm",
            "# machine: sample vertical machining centre (synthetic, scenarios/positioning_sample.py)",
            "# instrument: laser interferometer, material compensation on temp_scale_C",
            "# cycle_kind: linear", "# note: synthetic data with a stated recipe (see the generator)",
            "target_mm,cycle,direction,measured_mm,t_s,temp_scale_C,temp_air_C,status"]
    Path(path).write_text("\n".join(head + rows) + "\n")


if __name__ == "__main__":
    main()
