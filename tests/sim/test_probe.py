"""Touch-trigger model: contact to < 1 nm against analytic geometry, on a
perfect machine and with errors of known answer; no_trigger; pre-travel;
noise; the VirtualMachine for the emulator."""

import numpy as np
import pytest

from core.exceptions import ConfigError
from sim import artefacts as A
from sim.probe import ProbeConfig, VirtualMachine, simulate_touches
from standins import Translated

R = 3e-3
NM = 1e-9


class Rotated(Translated):
    """Stand-in: tip_W = Rz(eps) reading (a small rotation of the whole machine)."""

    def __init__(self, eps):
        self.R = A.rot_z(eps)

    def tip_W(self, lin, rot=None, t=None, d=None):
        return np.asarray(lin, float) @ self.R.T


def touch(machine, prim, start, d, travel=6e-3, probe=None):
    start = np.atleast_2d(np.asarray(start, float))
    n = len(start)
    d = np.broadcast_to(np.asarray(d, float), (n, 3))
    return simulate_touches(machine, probe or ProbeConfig(repeatability_k2_m=0), None, start, d,
                            np.full(n, travel), None, np.zeros(n), np.full(n, 0.004), [prim.sdf],
                            np.zeros(n, int), np.broadcast_to(np.eye(4), (n, 4, 4)))


OFF = np.array([3e-6, -2e-6, 5e-6])


@pytest.mark.parametrize("off", [np.zeros(3), OFF])
def test_plane_contact_exact(off):
    pl = A.Plane((0, 0, 0.01), (0, 0, 1))
    res = touch(Translated(off), pl, [[0.02, 0.03, 0.01 + R + 2e-3]], (0, 0, -1))
    # actual tip = reading + off touches z = 0.01 + R  ->  reading z = 0.01 + R - off_z
    assert abs(res.pos_R[0, 2] - (0.01 + R - off[2])) < NM


@pytest.mark.parametrize("off", [np.zeros(3), OFF])
def test_sphere_contact_exact_off_axis(off):
    c, Rs = np.array([0.05, 0.0, 0.02]), 0.0127
    sp = A.Sphere(tuple(c), Rs)
    y = np.array([0.0, 2e-3, 6e-3])
    start = np.column_stack([c[0] + Rs + R + 2e-3 + 0 * y, c[1] + y, np.full(3, c[2])])
    res = touch(Translated(off), sp, start, (-1, 0, 0))
    # actual path x(s) = x0 - s + off_x, at (y + off_y, off_z) from the centre
    xa = c[0] + np.sqrt((Rs + R) ** 2 - (y + off[1]) ** 2 - off[2] ** 2)
    assert np.max(np.abs(res.pos_R[:, 0] + off[0] - xa)) < NM


@pytest.mark.parametrize("off", [np.zeros(3), OFF])
def test_rod_and_hole_contact_exact(off):
    rod = A.Rod((0.0, 0.0, 0.0), (0, 1, 0), 5e-3, 0.03)
    a = np.deg2rad(45.0)
    n = np.array([np.sin(a), 0, np.cos(a)])
    res = touch(Translated(off), rod, [(5e-3 + R + 2e-3) * n], -n)
    # solve |(s-line + off) radial in xz| = 5 + 3 mm exactly
    p0 = (5e-3 + R + 2e-3) * n + off
    b = p0[[0, 2]] @ (-n[[0, 2]])
    cc = p0[[0, 2]] @ p0[[0, 2]] - (5e-3 + R) ** 2
    s = -b - np.sqrt(b * b - cc)
    assert np.linalg.norm(res.pos_R[0] - ((5e-3 + R + 2e-3) * n - s * n)) < NM
    hole = A.Hole((0.1, 0.0, 0.0), (0, 0, 1), 8e-3)
    res = touch(Translated(off), hole, [[0.1 + 3e-3, 0.0, 0.0]], (1, 0, 0))
    xa = 0.1 + np.sqrt((8e-3 - R) ** 2 - off[1] ** 2)
    assert abs(res.pos_R[0, 0] + off[0] - xa) < NM


def test_contact_in_the_concave_pocket_corner_exact():
    pk = A.Prism(A.cross_outline(), material_inside=False)
    # along the bisector into the corner (100, 18) mm: the ball touches both walls at once
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    start = np.array([[0.09, 0.008, 0.0]])
    res = touch(Translated(), pk, start, d, travel=0.02)
    np.testing.assert_allclose(res.pos_R[0, :2], [0.1 - R, 0.018 - R], atol=NM)
    # oblique approach towards the corner, with a translation error: the end wall comes first
    d = np.array([np.cos(np.pi / 6), np.sin(np.pi / 6), 0.0])
    res = touch(Translated(OFF), pk, [[0.09, 0.0, 0.0]], d, travel=0.02)
    s = (0.1 - R - 0.09 - OFF[0]) / d[0]
    assert np.linalg.norm(res.pos_R[0] - (np.array([0.09, 0.0, 0.0]) + s * d)) < NM
    # a start closer than the stylus radius to the other wall: early trigger, not a crash
    res = touch(Translated(), pk, [[0.098, 0.013, 0.0]], (0, 1, 0))
    assert res.status[0] == "early_trigger"


def test_rotation_error_has_analytic_answer():
    eps = 50e-6  # rad
    pl = A.Plane((0.0, 0.0, 0.0), (1, 0, 0))  # face x = 0, material below
    y0 = 0.2
    res = touch(Rotated(eps), pl, [[R + 2e-3, y0, 0.0]], (-1, 0, 0))
    # actual x = cos(eps) X - sin(eps) y0 = R  ->  X = (R + sin(eps) y0) / cos(eps)
    assert abs(res.pos_R[0, 0] - (R + np.sin(eps) * y0) / np.cos(eps)) < NM


def test_form_error_shows_in_the_touch():
    pl = A.Plane((0, 0, 0), (0, 0, 1), form=A.Bump(3e-6, (0, 0, 0), 0.005))
    res = touch(Translated(), pl, [[0.0, 0.0, R + 2e-3], [0.05, 0.0, R + 2e-3]], (0, 0, -1))
    np.testing.assert_allclose(res.pos_R[:, 2] - R, [3e-6, 0.0], atol=NM)


def test_missed_surface_is_no_trigger_not_an_exception():
    sp = A.Sphere((0.0, 0.0, 0.0), 0.0127)
    res = touch(Translated(), sp, [[0.03, 0.02, 0.0], [0.03, 0.0, 0.0]], (-1, 0, 0), travel=0.005)
    assert list(res.status) == ["no_trigger", "no_trigger"]
    assert np.isnan(res.pos_R).all()
    res = touch(Translated(), sp, [[0.01, 0.0, 0.0]], (-1, 0, 0))
    assert res.status[0] == "early_trigger"


def test_pretravel_lobing_and_noise():
    pl = A.Plane((0, 0, 0), (1, 0, 0))
    pr = ProbeConfig(pretravel_m=1e-6, lobing_m=((3, 0.5e-6, 0.0),), repeatability_k2_m=0)
    res = touch(Translated(), pl, [[R + 2e-3, 0.0, 0.0]], (-1, 0, 0), probe=pr)
    # azimuth pi: cos(3 pi) = -1 -> pre-travel 0.5 um, reported farther along -x
    assert res.pos_R[0, 0] == pytest.approx(R - 0.5e-6, abs=NM)
    rng = np.random.default_rng(7)
    n = 4000
    start = np.tile([R + 2e-3, 0.0, 0.0], (n, 1))
    res = simulate_touches(Translated(), ProbeConfig(), rng, start, np.tile([-1.0, 0, 0], (n, 1)),
                           np.full(n, 6e-3), None, np.zeros(n), np.full(n, 0.004), [pl.sdf],
                           np.zeros(n, int), np.broadcast_to(np.eye(4), (n, 4, 4)))
    # sigma = 0.125 um; the sample std of 4000 draws is within 5 %: the relative SD of a sample SD is
    # 1 / sqrt(2 (n - 1)) = 1.12 %, so 5 % is 4.5 SD of its spread (a false failure ~7e-6)
    assert np.std(res.pos_R[:, 0]) == pytest.approx(0.125e-6, rel=0.05)


def _pretravel_by_hand(d, pre, axial, lobes, per_feed=0.0, feed=0.004, feed_ref=0.004):
    """The docstring's pre-travel written out apart from sim (ProbeConfig's attributes, one approach direction):
    pre + axial d_z^2 + (1 - d_z^2) sum_k (a cos k phi + b sin k phi) + per_feed (feed - feed_ref),
    phi = atan2(d_y, d_x)."""
    import math

    phi = math.atan2(d[1], d[0])
    lob = sum(a * math.cos(k * phi) + b * math.sin(k * phi) for k, a, b in lobes)
    return pre + axial * d[2] ** 2 + (1 - d[2] ** 2) * lob + per_feed * (feed - feed_ref)


def test_pretravel_lobing_against_the_docstrings_formula():
    """review31d F4: the lobing model, the truth every lobing study is scored against, at azimuths all round, at
    elevations d_z = 0, +-0.6, -0.8, 1 (the lobing's weight 1 - d_z^2: 1, 0.64, 0.36, 0) and with sine
    coefficients, two lobe orders at once; against the docstring's formula written apart (_pretravel_by_hand).
    A hand value first: k = 2, a = 0.4, b = 0.3 um, azimuth 30 deg in the plane: 0.4 cos 60 + 0.3 sin 60 =
    0.2 + 0.25981 = 0.45981 um (a mirrored phase, -b sin, gives -0.0598; no weight changes nothing here). The
    same at d_z = -0.6 (the in-plane part 0.8): 0.64 x 0.45981 + the axial 0.36 x 0.7 um = 0.54628 um.
    Tolerance 1e-18 m: the same double operations in another order (the values are ~1e-6 m)."""
    import math

    pr = ProbeConfig(pretravel_m=0.0, pretravel_axial_m=0.7e-6, lobing_m=((2, 0.4e-6, 0.3e-6),))
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    assert pr.pretravel(np.array([[c, s, 0.0]]), 0.004)[0] == pytest.approx(0.45981e-6, abs=1e-11)
    assert pr.pretravel(np.array([[0.8 * c, 0.8 * s, -0.6]]), 0.004)[0] == pytest.approx(0.54628e-6, abs=1e-11)
    lobes = ((2, 0.4e-6, 0.3e-6), (3, -0.2e-6, 0.25e-6))
    pr = ProbeConfig(pretravel_m=1.0e-6, pretravel_axial_m=0.7e-6, lobing_m=lobes, pretravel_per_feed_s=0.01)
    d = []
    for az in np.radians([0.0, 17.0, 30.0, 75.0, 135.0, 200.0, 290.0, 333.0]):
        for dz in (0.0, 0.6, -0.6, -0.8, 1.0):
            h = math.sqrt(1 - dz * dz)
            d.append([h * math.cos(az), h * math.sin(az), dz])
    d = np.array(d)
    got = pr.pretravel(d, 0.005)
    want = [_pretravel_by_hand(v, 1.0e-6, 0.7e-6, lobes, 0.01, 0.005) for v in d]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-18)
    assert np.ptp(got[::5]) > 0.5e-6  # the lobes do show in the plane (the check is not of a constant)


def test_touch_pretravel_of_a_two_lobe_probe_at_30_deg_by_hand():
    """A physical touch (review31d F4): a plane through the origin whose normal n is at azimuth 30 deg, touched along
    d = -n (azimuth 210 deg) by a probe of pre-travel 1 um and two lobes a = 0.4, b = 0.3 um. The sphere meets the
    plane with its centre R along n; it triggers delta later along d, so the reported centre is (R - delta) n.
    By hand: 2 x 210 deg = 420 deg = 60 deg: delta = 1 + 0.4 x 0.5 + 0.3 x 0.86603 = 1.45981 um. Tilted, n with
    n_z = 0.6 (d_z = -0.6, the in-plane part 0.8 at the same azimuth): delta = 1 + 0.36 x 0.7 (axial) + 0.64 x 0.45981
    = 1.54628 um. Tolerance 1 nm, the contact's (the file's other contact checks)."""
    import math

    pr = ProbeConfig(pretravel_m=1.0e-6, pretravel_axial_m=0.7e-6, lobing_m=((2, 0.4e-6, 0.3e-6),),
                     repeatability_k2_m=0)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    for n, delta in ((np.array([c, s, 0.0]), 1.45981e-6), (np.array([0.8 * c, 0.8 * s, 0.6]), 1.54628e-6)):
        res = touch(Translated(), A.Plane((0, 0, 0), tuple(n)), [(R + 2e-3) * n], -n, probe=pr)
        assert res.status[0] == "ok"
        assert float(res.pos_R[0] @ n) == pytest.approx(R - delta, abs=NM)
        np.testing.assert_allclose(res.pos_R[0], (R - delta) * n, atol=NM)


@pytest.mark.parametrize("kw,match", [({"stylus_r_m": -1.0}, "stylus_r_m"),
                                      ({"repeatability_k2_m": -1e-6}, "repeatability"),
                                      ({"lobing_m": ((0.5, 1e-6, 0),)}, "lobing")])
def test_probe_config_bad_input(kw, match):
    with pytest.raises(ConfigError, match=match):
        ProbeConfig(**kw)


def test_ibaraki_probe_noise():
    assert ProbeConfig.ibaraki().sigma_m == pytest.approx(1.38e-6)


def test_virtual_machine_probe_move():
    art = A.cross_pocket(form=None)
    vm = VirtualMachine(Translated(OFF), art, ProbeConfig(repeatability_k2_m=0), np.random.default_rng(1))
    z = art.T_W_A[2, 3] - 3e-3
    hit, pos = vm.probe_move([0.09, 0.0, z], [0.11, 0.0, z])
    assert hit and abs(pos[0] + OFF[0] - (0.1 - R)) < NM
    hit, pos = vm.probe_move([0.0, 0.0, z], [0.0, 0.0, z + 0.01])  # up into free air
    assert not hit and np.allclose(pos, [0.0, 0.0, z + 0.01])


def test_real_machine_translation_error_has_analytic_answer():
    pytest.importorskip("pinocchio")
    from sim.errorfuncs import Constant
    from sim.machine import Machine
    from sim.machines import MACHINES

    m = Machine(MACHINES["vmc-3axis"](errors={"EC0Y": Constant(-43.4e-6)}))
    pl = A.Plane((0.0, 0.0, 0.0), (1, 0, 0))
    y0 = 0.1
    res = touch(m, pl, [[R + 2e-3, y0, 0.05]], (-1, 0, 0))
    # tip error -y EC0Y in X (CONTRIBUTING): actual x = X - y0 EC0Y = R
    assert abs(res.pos_R[0, 0] - (R + y0 * -43.4e-6)) < NM


@pytest.mark.parametrize("n_first", [1, 3, 6, 7, 20])
def test_find_contacts_in_two_passes_is_all_samples_at_once(n_first):
    # issue 19 item 5: the later coarse samples only where no crossing is bracketed before
    # them; the same samples decide, so the roots and statuses are bit-identical to all
    # samples at once, on paths crossing early, late, twice (the first crossing counts),
    # never, or starting inside the material; and the late samples are evaluated only on
    # the paths that need them
    from sim.probe import find_contacts

    rng = np.random.default_rng(8)
    n = 400
    a = rng.uniform(-0.5e-3, 3.5e-3, n)  # first surface at s = a (before 0: early; past 3 mm: none)
    b = a + rng.uniform(0.2e-3, 2e-3, n)  # material ends at b (a second crossing beyond it)
    curv = rng.uniform(-50, 50, n)
    calls = []

    def g(idx, s):
        calls.append(len(s))
        return np.where(s < b[idx], a[idx] - s, s - b[idx] - 1e-4) + curv[idx] * (s - a[idx]) ** 2

    travel = np.full(n, 3e-3)
    s_all, st_all = find_contacts(g, n, travel, n_coarse=7)
    n_all = calls[0]
    calls.clear()
    s_two, st_two = find_contacts(g, n, travel, n_coarse=7, n_first=n_first)
    assert np.array_equal(s_all, s_two, equal_nan=True) and list(st_all) == list(st_two)
    assert {"ok", "no_trigger", "early_trigger"} <= set(st_all)
    if n_first < 7:
        assert calls[0] == n * n_first and calls[0] + calls[1] < n_all


def test_root_on_a_coarse_sample_is_that_sample_without_bisection():
    # a nominal contact on a perfect machine falls on a coarse sample (2 mm clearance, 3 mm
    # travel, 13 samples): regula falsi returns the sample itself, which the bracket test
    # rejected, and the search bisected ~30 times; now the sample is the root, at once, on
    # either side of the bracket (g just above 0 before it, or exactly 0 at it)
    from sim.probe import G_TOL_M, find_contacts

    n = 50
    root = np.full(n, 2e-3)
    eps = np.where(np.arange(n) % 2 == 0, 0.0, 0.3 * G_TOL_M)  # g = +eps at the sample
    calls = []

    def g(idx, s):
        calls.append(len(s))
        return root[idx] - s + eps[idx]

    s, st = find_contacts(g, n, np.full(n, 3e-3), n_coarse=13)
    assert set(st) == {"ok"} and np.array_equal(s, root)
    assert len(calls) == 1
