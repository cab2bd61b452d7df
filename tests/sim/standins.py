"""Stand-in machines with analytic answers, shared by the sim tests."""

import numpy as np


class Translated:
    """Stand-in machine: tip_W = reading + constant offset (a pure translation error)."""

    linear_axes = ("X", "Y", "Z")
    rotary_axes = ()

    def __init__(self, off=(0.0, 0.0, 0.0)):
        self.off = np.asarray(off, float)

    def tip_W(self, lin, rot=None, t=None, d=None):
        return np.asarray(lin, float) + self.off
