"""core.volumetric: 21-error identification, gauge, observability, tables (MFB eqs 8-12)."""

import numpy as np
import pytest

from core import volumetric as vol
from core.exceptions import ConfigError, IdentifiabilityError


@pytest.fixture(scope="module")
def meas3():
    """Noise-free measurements of the 3-axis plan on a perfect machine (sim, ~3 s)."""
    import scenarios.mfb as S
    import core.volumetric as V

    cap = {}
    orig = V.identify_volumetric

    def spy(meas, chain, nodes, rp=None, **kw):
        cap["m"] = (meas, chain, nodes, rp)
        return orig(meas, chain, nodes, rp, **kw)

    V.identify_volumetric = spy
    try:
        S.run("mfb-3axis", noise_um=0.0, mc_runs=0)
    finally:
        V.identify_volumetric = orig
    return cap["m"]


def test_gauge_is_iso_and_full_plan_observable(meas3):
    meas, chain, nodes, rp = meas3
    rep = vol.observability(meas, chain, nodes, rp)
    assert rep.ok, rep.unidentifiable
    g = " ".join(rep.gauge)
    for s in ("EXX", "EYY", "EZZ"):  # positioning zero at the first node (EX0X = 0 ...)
        assert f"{s} = 0 at the first node" in g
    # end-point lines where the slope is a gauge freedom; the slopes of EXY,
    # EXZ, EYZ are tied to the squarenesses, whose own freedom is the
    # constant angular error of the table-carrying axes (X, Y first nodes)
    assert g.count("end-point reference line") == 9
    for s in ("EAX", "EBX", "ECX", "EAY", "EBY", "ECY"):
        assert f"{s} = 0 at the first node" in g
    assert rep.rank == rep.n_params - len(rep.gauge)
    assert rep.sv_min_rel > 1e-5  # conditioning of the gauge-fixed, column-scaled design


# the standing bars are the only placements nothing else replaces (the X/Y
# bars at a second height or with a second stylus are backed, weakly, by the
# diagonal pairs: without X2 the weakest relative sv is 3e-5)
@pytest.mark.parametrize("drop,names", [("VX", "EB0Z"), ("VY", "EA0Z")])
def test_plan_without_a_placement_names_what_is_lost(meas3, drop, names):
    meas, chain, nodes, rp = meas3
    full = vol.observability(meas, chain, nodes, rp).gauge  # conventions of the complete plan
    kept = [m for m in meas if m.placement != drop]
    rep = vol.observability(kept, chain, nodes, rp, gauge=full)
    assert not rep.ok and names in " ".join(rep.unidentifiable)
    with pytest.raises(IdentifiabilityError, match="cannot identify"):
        vol.identify_volumetric(kept, chain, nodes, rp, gauge=full)


def test_spline_weights_interpolate_nodes_and_cubics():
    x = np.linspace(0, 0.5, 6)
    W = vol.spline_weights(x, x)
    assert np.allclose(W, np.eye(6), atol=1e-12)
    u = np.linspace(0, 0.5, 37)
    f = lambda t: 3 * t ** 3 - t + 0.2  # noqa: E731  a not-a-knot spline reproduces cubics
    assert np.allclose(vol.spline_weights(x, u) @ f(x), f(u), atol=1e-12)


def test_bad_input(meas3):
    meas, chain, nodes, rp = meas3
    with pytest.raises(ConfigError, match="no measurements"):
        vol.identify_volumetric([], chain, nodes)
    bad = dict(nodes)
    bad["X"] = bad["X"][::-1]
    with pytest.raises(ConfigError, match="strictly increasing"):
        vol.identify_volumetric(meas, chain, bad)
    short = dict(nodes)
    short["Y"] = nodes["Y"][:-1]  # the last Y bar touches 84 mm beyond the last node: refused, not extrapolated
    with pytest.raises(ConfigError, match="outside the Y nodes"):
        vol.identify_volumetric(meas, chain, short)


def test_iso_map_end_point_line(meas3):
    # known answer: a straightness table that is a line plus a bump is reported
    # as the bump minus its own end-point line (zero at both ends); positioning
    # and angular tables pass unchanged
    meas, chain, nodes, rp = meas3
    d = vol.design(meas, chain, nodes, rp)
    L = vol.iso_map(d)
    th = np.zeros(len(d.names))
    x = d.nodes["Y"]
    bump = 1e-6 * np.sin(np.pi * (x - x[0]) / (x[-1] - x[0]))
    th[d.slices["EXY"]] = 3e-6 + 2e-5 * x + bump
    th[d.slices["EYY"]] = 1e-5 * x
    out = L @ th
    assert np.allclose(out[d.slices["EXY"]], bump, atol=1e-18)
    assert np.allclose(out[d.slices["EYY"]], th[d.slices["EYY"]])
    assert vol.end_point_slopes(d, th)["EXY"] == pytest.approx(2e-5)


def test_placement_errors_are_absorbed_and_bad_u_place(meas3):
    # a placement error moves the bar rigidly; the estimator takes translation,
    # pitch and yaw into the placement's nuisance values (share ~1e-12 per mm /
    # mrad, rounding). The roll is not estimated: it moves only the shifted
    # holes along z_A (not used) and the points by roll x their calibrated
    # offsets from the bar axis (a few um): 1 mrad of roll gives 0.04 um / urad
    # at most (the tilted diagonals), 4 % of what 0.1 um of calibration error
    # gives; bound 10 %.
    meas, chain, nodes, rp = meas3
    res = vol.identify_volumetric(meas, chain, nodes, rp, exact=False)
    d = res.design
    idx = np.array([i for s in vol.MOTION + vol.SQUARENESS for i in range(d.slices[s].start, d.slices[s].stop)])
    uc = vol.uncertainty(res, meas, 0.0, np.full((12, 3), 1e-7), runs=0).u_lin[idx].max()
    for j in range(6):
        u = np.zeros(6)
        u[j] = 1e-3
        up = vol.uncertainty(res, meas, 0.0, np.zeros((12, 3)), runs=0, u_place=u).u_lin[idx].max()
        assert up < (0.1 * uc if j == 3 else 1e-10), (j, up)
    with pytest.raises(ConfigError, match="u_place must be 6"):
        vol.uncertainty(res, meas, 0.0, np.zeros((12, 3)), runs=0, u_place=(1e-4, 1e-4))
