"""An ISO 230-2 positioning test with a warm-up, written here apart from core.causes' columns (session 27).

One 400 mm axis, 11 irregular targets, 5 linear cycles (each target approached from both directions, a 5 mm
overrun at each end), moves at 2000 mm/min with a dwell at each target, 0.3 um repeatability. The warm-up: the
axis' zero settles as ``A (1 - exp(-t / tau))`` and its scale as ``S (1 - exp(-t / tau))`` about the axis'
middle, on top of a systematic deviation the same in every cycle (a pitch error and a reversal).
"""

from __future__ import annotations

import numpy as np

from core.baseline import positioning

TARGETS_MM = np.array([-200.0, -158.4, -119.0, -81.7, -38.2, 4.6, 41.3, 79.9, 122.4, 160.8, 200.0])
SIG_UM = 0.3


def warm_up_test(seed: int, tau_s: float, amp_um: float = 3.5, scale_ppm: float = 2.0, dwell_s: float = 30.0):
    """(baseline, test duration s): the readings of one test, the warm-up's truth ``tau_s``, ``amp_um`` (zero)
    and ``scale_ppm`` (scale) at its end."""
    rng = np.random.default_rng(seed)
    rows, t, pos = [], 0.0, -205.0
    for c in range(1, 6):
        for d, seq in (("+", TARGETS_MM), ("-", TARGETS_MM[::-1])):
            for p in seq:
                t += abs(p - pos) / (2000 / 60) + dwell_s
                pos = p
                rows.append((p, d, c, t))
            pos += 5 if d == "+" else -5  # the overrun before the reversal
            t += 3.0
    p, d, c, ts = (np.array(v) for v in zip(*rows))
    settle = 1 - np.exp(-ts / tau_s)
    dev_um = (2.0 * np.sin(np.pi * p / 400) + np.where(d == "+", 0.6, -0.6)
              + amp_um * settle + scale_ppm * (p / 1000) * settle + rng.normal(0, SIG_UM, p.size))
    return positioning(p * 1e-3, d, c, dev_um * 1e-6, ts), float(np.ptp(ts))
