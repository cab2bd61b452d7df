"""Choice of C angles (core.design)."""

import itertools

import numpy as np
import pytest

from core.design import example_cross_pocket, max_workpiece_U95, optimise_angles
from core.exceptions import ConfigError
from core.selfcal import Grid

GRID = Grid.regular(-0.110, 0.110, 0.022)


@pytest.fixture(scope="module")
def pocket():
    w, wn, _ = example_cross_pocket()
    return w, wn


def test_example_cross_pocket_is_the_papers_size():
    w, wn, ids = example_cross_pocket()
    assert len(w) == 92 and len(ids) == 92  # N_w = 92 (section 4.2)
    np.testing.assert_allclose(np.linalg.norm(wn, axis=1), 1.0)
    # pocket normals point into the pocket (towards the centre line of an arm)
    inside = w + 0.001 * wn
    on_pocket = np.array([i.startswith("pocket") for i in ids])
    x, y = np.abs(inside[on_pocket]).T
    assert np.all(((x < 0.090) & (y < 0.018)) | ((x < 0.018) & (y < 0.090)))


def test_optimiser_known_answer_three_angles(pocket):
    """Known answer: brute force over all 30-deg pairs (C1 = 0); exhaustive when small,
    coordinate search (a local method) within 5 % of it."""
    w, wn = pocket
    brute = min(max_workpiece_U95(w, wn, (0.0, a, b), GRID)
                for a, b in itertools.combinations(np.arange(30, 360, 30.0), 2))
    r = optimise_angles(w, wn, 3, GRID, step_deg=30, reference_deg=[0, 75, 130])
    assert r.c_deg[0] == 0 and len(r.c_deg) == 3
    assert r.max_U95_m == pytest.approx(brute, rel=1e-9)
    assert r.reference_max_U95_m == pytest.approx(max_workpiece_U95(w, wn, [0, 75, 130], GRID))
    assert r.gain == pytest.approx(r.reference_max_U95_m / r.max_U95_m)
    local = optimise_angles(w, wn, 3, GRID, step_deg=30, exhaustive_max=0)
    assert brute <= local.max_U95_m <= 1.05 * brute


def test_optimiser_not_worse_than_reference_on_its_grid(pocket):
    w, wn = pocket
    r = optimise_angles(w, wn, 4, GRID, step_deg=45, reference_deg=[0, 45, 135, 225], exhaustive_max=0)
    assert r.gain >= 1.0
    assert r.max_U95_m < 3e-6


def test_bad_input(pocket):
    w, wn = pocket
    with pytest.raises(ConfigError, match="n_angles must be >= 2"):
        optimise_angles(w, wn, 1, GRID)
    with pytest.raises(ConfigError, match="step_deg must divide 360"):
        optimise_angles(w, wn, 3, GRID, step_deg=7)
    with pytest.raises(ConfigError, match="measure must be"):
        max_workpiece_U95(w, wn, [0, 75, 130], GRID, measure="max")
