"""Self-calibration with touches at several heights (core.selfcal.height_terms): null space, round trips, refusals."""

from dataclasses import replace

import numpy as np
import pytest

from core.design import example_cross_pocket
from core.exceptions import ConfigError
from core.selfcal import (Grid, build_design, height_terms, nominal_touches, self_calibrate, workpiece_form,
                          workpiece_gauge_basis)
from core.units import MM, UM

GRID = Grid.regular(-0.110, 0.110, 0.022)
ANGLES = [0, 75, 130, 210]
DZ = 25.7 * MM  # the cross pocket's sphere equators above its walls


def raised(ids_prefix=("sphere1", "sphere2")):
    """The paper's cross pocket (nominal), its sphere targets raised by DZ."""
    w, wn, ids = example_cross_pocket()
    t = nominal_touches(w, wn, ANGLES, stylus_r_m=0.003, target_ids=ids)
    up = np.array([ids[k].startswith(ids_prefix) for k in t.target])
    pn = t.pn_R.copy()
    pn[up, 2] += DZ
    return replace(t, pn_R=pn, p_R=pn.copy()), up


def test_sphere_ids():
    _, up = raised()
    assert up.sum() == 16 * len(ANGLES)  # 8 equator points on each of two spheres per set-up


def test_null_space_is_the_gauge_plus_four():
    """The height design has exactly 11 + 4 null directions, the analytic ones, and the
    gauge fixes them: a part tilt (2), a twist and a growth of the raised targets."""
    t, _ = raised()
    des = build_design(t, GRID, heights="auto")
    ht = des.heights
    assert ht.abbe and ht.names[-4:] == ("dEB/dx", "dEB/dy", "dEA/dx", "dEA/dy")
    assert len(ht.setups) == 4 and ht.z_ref_m == 0.0 and ht.levels_m == pytest.approx((0.0, DZ), abs=1e-12)
    A = des.A.toarray()
    assert np.abs(A @ des.N).max() < 1e-15
    sv = np.linalg.svd(A / np.linalg.norm(A, axis=0), compute_uv=False)
    assert (sv > 1e-9 * sv[0]).sum() == des.n_params - 15
    assert np.linalg.matrix_rank(des.C @ des.N) == 15 and len(des.gauge) == 15


def test_known_answer_in_the_model_space():
    """A truth with table tilts, Abbe slopes and the paper's parameters, noise free:
    recovered to rounding in the gauge, residuals zero."""
    t, _ = raised()
    des = build_design(t, GRID, heights="auto")
    rng = np.random.default_rng(4)
    th = rng.normal(0, 3 * UM, des.n_params)
    for k in ("ECY", "EC0Y", "ECC", "EBC", "EAC"):
        th[des.slices[k]] = rng.normal(0, 20e-6, des.slices[k].stop - des.slices[k].start)
    th[des.slices["ABBE"]] = rng.normal(0, 3e-4, 4)  # 300 urad/m: 98 urad over a 320 mm stroke
    truth = des.to_gauge(th)
    res = self_calibrate(replace(t, p_R=t.pn_R + (des.A @ th)[:, None] * t.n_R), GRID, sigma_m=UM)
    np.testing.assert_allclose(res.theta, truth, atol=1e-12)
    assert res.rms_m < 1e-15 and res.design.heights is not None


def test_planar_model_on_raised_touches_carries_the_height_as_error():
    """The same truth seen by the paper's planar model: its residuals show the height terms
    (what issue 14 measured as 1.2 um on the spheres), the height model's do not."""
    t, up = raised()
    des = build_design(t, GRID, heights="auto")
    th = np.zeros(des.n_params)
    th[des.slices["ABBE"]] = (3e-4, 0.0, 0.0, 0.0)  # EBX 98 urad over 320 mm
    th[des.slices["EBC"]] = (0.0, 5e-6, -4e-6, 2e-6)
    tt = replace(t, p_R=t.pn_R + (des.A @ th)[:, None] * t.n_R)
    flat = self_calibrate(tt, GRID, heights=False, model_error=False)
    assert flat.design.heights is None and np.abs(flat.residuals_m[up]).max() > 0.1 * UM
    assert self_calibrate(tt, GRID).rms_m < 1e-15


def test_raised_targets_in_one_setup_leave_the_abbe_terms_out():
    """Spheres probed at one C angle only: their G take everything the height does there (the
    tilt of that set-up is the gauge's), so the Abbe terms are left out and the result says
    why; asked for, they are refused by name."""
    w, wn, ids = example_cross_pocket()
    t = nominal_touches(w, wn, ANGLES, stylus_r_m=0.003, target_ids=ids)
    up = np.array([ids[k].startswith("sphere") for k in t.target]) & (t.setup == 1)
    pn = t.pn_R.copy()
    pn[up, 2] += DZ
    t = replace(t, pn_R=pn, p_R=pn.copy())
    des = build_design(t, GRID, heights="auto")
    assert not des.heights.abbe and "16 at 16 targets in 1 set-up(s)" in des.heights.why
    assert des.slices["ABBE"].stop == des.slices["ABBE"].start and len(des.heights.setups) == 1
    res = self_calibrate(t, GRID, sigma_m=UM)
    assert any("Abbe terms: the raised touches" in c for c in res.conventions)
    with pytest.raises(ConfigError, match="the Abbe height terms are not identifiable: the raised touches"):
        height_terms(t, build_design(t, GRID), abbe=True)


def test_one_sphere_tells_the_abbe_terms_by_its_two_lobe_signature():
    """One sphere at four angles: the Abbe shear deforms its equator into two lobes fixed in
    the machine while the sphere turns with the table, so they are identifiable (rank test)."""
    t, _ = raised(("sphere1",))
    assert build_design(t, GRID, heights="auto").heights.abbe


def test_single_level_has_no_height_terms_and_bad_options():
    w, wn, ids = example_cross_pocket()
    t = nominal_touches(w, wn, ANGLES, target_ids=ids)
    assert height_terms(t, build_design(t, GRID)) is None
    assert build_design(t, GRID, heights=True).heights is None
    with pytest.raises(ConfigError, match="heights must be True, False or 'auto', got 'yes'"):
        build_design(t, GRID, heights="yes")
    with pytest.raises(ConfigError, match="abbe must be True, False or 'auto'"):
        height_terms(raised()[0], build_design(raised()[0], GRID), abbe=1)
    with pytest.raises(ConfigError, match="model_error must be True, False or 'auto'"):
        self_calibrate(t, GRID, model_error="sometimes")


def test_workpiece_form_with_heights_removes_tilt_twist_growth():
    """G of raised targets moved by a part tilt, twist and growth in proportion to their
    height has no form once those are removed; a lobe on them survives."""
    w, wn, _ = example_cross_pocket()
    dz = np.where(np.arange(len(w)) >= len(w) - 16, DZ, 0.0)
    tilt = dz * (wn @ np.array([4e-5, -3e-5]))
    twist = dz * 2e-4 * (-wn[:, 0] * w[:, 1] + wn[:, 1] * w[:, 0])
    grow = dz * 1e-4 * np.einsum("ij,ij->i", wn, w)
    np.testing.assert_allclose(workpiece_form(tilt + twist + grow, w, wn, dz), 0.0, atol=1e-18)
    assert np.abs(workpiece_form(tilt + twist + grow, w, wn)).max() > 0.1 * UM  # the planar gauge keeps them
    assert workpiece_gauge_basis(w, wn, np.zeros(len(w))).shape == (len(w), 5)
