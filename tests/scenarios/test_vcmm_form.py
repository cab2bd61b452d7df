"""``[form.FEATURE]``: the part's own form, drawn per run, against hand-worked answers through the simulator.

A bore of 8 touches equally spaced (azimuths theta_i = 22.5 + 45 i deg about its centre) with a
3-lobe form ``f = a cos(3 theta + phi)``: harmonics 3 and 3 +- 1 are not multiples of 8, so the
LS circle's centre and radius do not move (the diameter stays 20 mm to the fit's rounding) and the
roundness is ``ptp(f_i)``; the profile deviation of touch i is ``+f_i`` (the surface lies ``f``
out of the material along the outward normal, into the hole: excess material reads +). The
rail of the line test (a face of normal +Y, x_i = -40 .. 40 mm) with a wave ``a cos(2 pi s /
120 mm + phi)``, ``s = -x`` (along the line's direction z x n = -X from the rail's centroid): the
profile is ``f_i``, the straightness the peak-to-valley of ``f_i`` about its LS line in x
(``np.polyfit``, not the fit of core.fit). The machine has no error (vmc-3axis) and no noise:
the tolerance 1e-12 m is the fits' rounding.
"""

import math

import numpy as np
import pytest

from core import vcmm as V
from scenarios import vcmm as S
from sim.machinefile import resolve
from tests.scenarios.test_vcmm_drift import BAD_DRIFT
from tests.scenarios.test_vcmm_line_profile import HEAD, PLAN, XS, meas
from tests.scenarios.test_vcmm_study import BORE, C_MM, R_MM


@pytest.fixture(scope="module")
def machine():
    return resolve("vmc-3axis")


def test_three_lobe_form_of_a_bore(machine):
    task = ('[features.bore]\nkind = "circle"\nfeature = "bore"\n[probe]\nnoise_um = 0.0\n'
            + meas("d", "diameter", "bore") + meas("round", "roundness", "bore") + meas("pmax", "profile", "bore", "max")
            + meas("pmin", "profile", "bore", "min") + '[form.bore]\namplitude_um = 1.5\nlobes = 3\n')
    st = S.prepare(BORE, V.loads_task(task), machine)
    assert st.sources == ("form of bore",)
    dq: list = []
    y = S.run_values(st, 7, range(5), dq=dq)
    th = np.arctan2(st.Xn_R[:, 1] - C_MM[1] * 1e-3, st.Xn_R[:, 0] - C_MM[0] * 1e-3)
    for i in range(5):
        a, phi = S.draw(st, 7, i)[0][("form", "bore")]
        assert abs(a) <= 1.5e-6
        f = a * np.cos(3 * th + phi)
        assert y[i, 0] == pytest.approx(2 * R_MM * 1e-3, abs=1e-12)
        assert y[i, 1:] == pytest.approx([np.ptp(f), f.max(), f.min()], abs=1e-12)
        # touch by touch (8 azimuths 45 deg apart make {f_i} and {-f_i} the same set: only this sees the sign)
        assert dq[i] == pytest.approx(f, abs=1e-12)


def test_three_lobe_form_of_a_cylinder_bore(machine):
    """The bore as a cylinder (two rings of 8 at z = -5 and -15 mm): f_i = a cos(3 theta_i + phi),
    theta anticlockwise about +Z from +X; the cylinder does not move, the cylindricity is ptp(f_i)."""
    from tests.scenarios.test_vcmm_study import plan_of

    az = np.deg2rad(22.5 + 45.0 * np.arange(8))
    plan = plan_of([("bore", (C_MM[0] + R_MM * math.cos(a), C_MM[1] + R_MM * math.sin(a), z),
                     (-math.cos(a), -math.sin(a), 0.0)) for z in (-5.0, -15.0) for a in az])
    task = ('[features.bore]\nkind = "cylinder"\nfeature = "bore"\n[probe]\nnoise_um = 0.0\n'
            + meas("d", "diameter", "bore") + meas("cyl", "cylindricity", "bore")
            + '[form.bore]\namplitude_um = 1.5\nlobes = 3\ndistribution = "triangular"\n')
    st = S.prepare(plan, V.loads_task(task), machine)
    dq: list = []
    y = S.run_values(st, 6, range(4), dq=dq)
    th = np.tile(az, 2)
    for i in range(4):
        a, phi = S.draw(st, 6, i)[0][("form", "bore")]
        f = a * np.cos(3 * th + phi)
        assert dq[i] == pytest.approx(f, abs=1e-12)
        assert y[i] == pytest.approx([2 * R_MM * 1e-3, np.ptp(f)], abs=1e-12)


def test_wave_form_of_a_line(machine):
    task = (HEAD + meas("straight", "straightness", "rail") + meas("pmax", "profile", "rail", "max")
            + meas("prms", "profile", "rail", "rms") + meas("side pmax", "profile", "side", "max")
            + '[form.rail]\namplitude_um = 2.0\nwavelength_mm = 120.0\ndistribution = "arcsine"\n')
    st = S.prepare(PLAN, V.loads_task(task), machine)
    dq: list = []
    y = S.run_values(st, 8, range(5), dq=dq)
    x = XS * 1e-3
    for i in range(5):
        a, phi = S.draw(st, 8, i)[0][("form", "rail")]
        f = a * np.cos(2 * math.pi * (-x) / 0.12 + phi)
        res = f - np.polyval(np.polyfit(x, f, 1), x)
        assert y[i] == pytest.approx([np.ptp(res), f.max(), math.sqrt(np.mean(f * f)), 0.0], abs=1e-12)
        assert dq[i][:5] == pytest.approx(f, abs=1e-12) and dq[i][5:] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("body, match", [
    ('[form.nope]\namplitude_um = 1\nwavelength_mm = 5\n', "form.nope: no feature 'nope'"),
    ('[form.rail]\namplitude_um = 1\nlobes = 3\n', "form.rail.lobes: unknown key"),
    ('[form.rail]\namplitude_um = 1\n', "form.rail.wavelength_mm: missing"),
    ('[form.rail]\nwavelength_mm = 5\n', "form.rail.amplitude_um: missing"),
    ('[form.rail]\namplitude_um = -1\nwavelength_mm = 5\n', "form.rail.amplitude_um: must be >= 0"),
    ('[form.rail]\namplitude_um = 1\nwavelength_mm = 0\n', "form.rail.wavelength_mm"),
    ('[form.rail]\namplitude_um = 1\nwavelength_mm = 5\ndistribution = "cauchy"\n', "form.rail.distribution"),
] + BAD_DRIFT)
def test_bad_form_or_drift_names_the_key(body, match):
    with pytest.raises(V.TaskFileError, match=match):
        V.loads_task(HEAD + meas("s", "straightness", "rail") + body)


def test_plane_form_along_its_normal_is_refused(machine):
    from core.exceptions import ConfigError
    from tests.scenarios.test_vcmm_study import GAUGE, GAUGE_TASK

    task = GAUGE_TASK + '[form.a]\namplitude_um = 1\nwavelength_mm = 10\nalong = "x"\n'
    with pytest.raises(ConfigError, match="form.a.along: the plane's normal"):
        S.prepare(GAUGE, V.loads_task(task), machine)
