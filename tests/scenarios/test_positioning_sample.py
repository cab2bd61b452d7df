"""The packaged sample positioning test: it reads cleanly, regenerates identically,
and its figures show the causes its recipe (scenarios/positioning_sample.py) put in."""

import math

import numpy as np

from core.positioning import arrange, iso230_2, read_positioning_log
from scenarios import positioning_sample as ps


def test_sample_is_packaged_and_regenerates(tmp_path):
    assert ps.SAMPLE.is_file()
    ps.main(tmp_path / "again.csv")
    assert (tmp_path / "again.csv").read_text() == ps.SAMPLE.read_text()


def test_sample_figures_show_the_recipe():
    log = read_positioning_log(ps.SAMPLE)
    assert int((~log.ok).sum()) == 1 and log.status[~log.ok][0] == "beam interrupted"
    test = arrange(log)
    assert test.warnings == () and test.m == 9 and set(test.n_up) == {5} and set(test.n_down) == {5}
    r = iso230_2(test)
    # lost motion 3 um, lagging: B_mean = -3 um. Scatter 0.35 um gives se(B_mean) = 0.35 sqrt(2/45)
    # = 0.074 um; the warm-up drift reaches the - approaches later in each cycle, < 0.2 um here.
    assert abs(r.B_mean * 1e3 + 3.0) < 4.5 * 0.35 * math.sqrt(2 / 45) + 0.2
    # scale 15 um/m over 800 mm = 12 um, pitch +-1.8 um aliased at the targets, drift 3.5 um at most
    assert 12.0 - 3.6 < r.M * 1e3 < 12.0 + 3.6 + 3.5
    # the time order is kept: the retake is the last row
    assert log.t_s[-1] == np.nanmax(log.t_s) and log.cycle[-1] == 3
