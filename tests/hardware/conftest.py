"""Shared plans and stand-in machines for the hardware tests.

The stand-in machine is :class:`hardware.scene.SimpleScene`: a table top at
z = 0 and a sphere of radius 12.5 mm at (50, 50, 0) mm, with known linear
errors, so a touch's expected position is computable.
"""

import numpy as np
import pytest

from core.probelog import make_log, write_probe_log
from hardware.scene import SimpleScene

LIMITS = "X-20:200,Y-20:200,Z-50:100"
LIMITS_MM = ((-20, 200), (-20, 200), (-50, 100))
SCALE = (40e-6, -25e-6, 10e-6)
EC0Y = 30e-6


def plan_log(n_sphere: int = 8, miss_rows=()):
    """Table touches, then sphere touches; rows in ``miss_rows`` are moved 10 mm up (no contact)."""
    rows = []
    for i, (x, y) in enumerate([(10, 10), (90, 10), (90, 90), (10, 90)]):
        rows.append(("table", f"p{i}", np.array([x, y, 0.0]), np.array([0, 0, 1.0])))
    for k in range(n_sphere):
        el, az = np.radians(25 + 15 * (k % 3)), np.radians(360 / n_sphere * k)
        n = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        rows.append(("sphere", f"s{k}", np.array([50, 50, 0.0]) + 12.5 * n, n))
    cols = {c: [] for c in ("setup", "target", "t_s", "X_mm", "Y_mm", "Z_mm",
                            "Xn_mm", "Yn_mm", "Zn_mm", "nx", "ny", "nz", "feature")}
    for r, (s, t, p, n) in enumerate(rows):
        if r in miss_rows:
            p = p + np.array([0, 0, 10.0])
        cols["setup"].append(s)
        cols["target"].append(t)
        cols["feature"].append(s)
        for c in ("t_s", "X_mm", "Y_mm", "Z_mm"):
            cols[c].append(np.nan)
        for c, v in zip(("Xn_mm", "Yn_mm", "Zn_mm"), p):
            cols[c].append(v)
        for c, v in zip(("nx", "ny", "nz"), n):
            cols[c].append(v)
    return make_log(cols, {"artefact": "table+sphere", "stylus_r_mm": "1.5"})


def scene(noise_um: float = 0.0, seed: int = 7):
    return SimpleScene(scale=SCALE, ec0y_rad=EC0Y, noise_m=noise_um * 1e-6,
                       rng=np.random.default_rng(seed))


@pytest.fixture
def plan_path(tmp_path):
    return write_probe_log(tmp_path / "plan.csv", plan_log())
