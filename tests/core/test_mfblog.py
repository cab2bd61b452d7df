"""core.mfblog's pure parts: the bar pose from nominal columns, the metadata lines, refusals (session 37).
The whole reader against the MFB scenarios' own measurements: tests/scenarios/test_mfb_log_route.py."""

import numpy as np
import pytest

from core.exceptions import ConfigError
from core.mfblog import (BAR_E_KEY, BAR_U_KEY, STYLUS_OFFSETS_KEY, _letters, _named_vectors, bar_pose_W,
                         certificate_lines, certificate_of_log, format_named_vectors, probe_sigma_of_log)
from core.probelog import make_log


def _rot(a, b, c):
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    Rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    Ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    Rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def test_bar_pose_known_answer(rng):
    """A pose drawn, the contact points moved by it: the fit gives it back (to rounding), and a pose that does
    not hold (one point 5 um off) is refused naming the miss."""
    T = np.eye(4)
    T[:3, :3] = _rot(*rng.uniform(-np.pi, np.pi, 3))
    T[:3, 3] = rng.uniform(-0.3, 0.3, 3)
    c_A = rng.uniform(-0.05, 0.6, (40, 3))
    p_W = c_A @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(bar_pose_W(c_A, p_W), T, rtol=0, atol=1e-14)
    p_W[7] += 5e-6
    with pytest.raises(ConfigError, match="do not fit one bar pose"):
        bar_pose_W(c_A, p_W)


def test_bar_pose_keeps_a_designed_pose_exact():
    """A bar along -Y standing on Z (the 3-axis plan's VY pose): entries 0 and +-1 exact, not 1e-16 off."""
    T = np.eye(4)
    T[:3, :3] = np.column_stack([(0, 0, 1.0), (1.0, 0, 0), (0, 1.0, 0)])
    T[:3, 3] = (-0.025, -0.02, 0.06)
    c_A = np.array([[0, 0, 0], [0.55, 0, 0], [0.1, 0.008, 0.005], [0.3, -0.008, 0.005], [0.2, 0, -0.01]])
    p_W = c_A @ T[:3, :3].T + T[:3, 3] + 1e-16
    R = bar_pose_W(c_A, p_W)[:3, :3]
    assert np.array_equal(R, T[:3, :3])


def test_bar_pose_refuses_points_on_a_line():
    c_A = np.column_stack([np.linspace(0, 0.5, 6), np.zeros(6), np.zeros(6)])
    with pytest.raises(ConfigError, match="on a line"):
        bar_pose_W(c_A, c_A)


def test_named_vectors_round_trip():
    v = {"T0": np.array([0.0, 0.0, 150.0]), "TY1": np.array([0.0, -100.0, 150.00000000000003])}
    back = _named_vectors(format_named_vectors(v), STYLUS_OFFSETS_KEY, "f.csv")
    assert list(back) == ["T0", "TY1"] and all(np.array_equal(back[k], v[k]) for k in v)


@pytest.mark.parametrize("text,words", [("T0=0,0", "T0=0,0"), ("T0 0,0,150", "T0 0,0,150"), ("=1,2,3", "=1,2,3"),
                                        ("T0=a,b,c", "T0=a,b,c"), (" ; ", "empty"), ("T0=0,0,nan", "nan")])
def test_named_vectors_refuse_naming_the_entry(text, words):
    with pytest.raises(ConfigError, match=STYLUS_OFFSETS_KEY) as e:
        _named_vectors(text, STYLUS_OFFSETS_KEY, "f.csv")
    assert words in str(e.value)


def _log(meta):
    cols = {"setup": ["a"], "target": ["t"], "t_s": [0.0], "X_mm": [0.0], "Y_mm": [0.0], "Z_mm": [0.0],
            "Xn_mm": [0.0], "Yn_mm": [0.0], "Zn_mm": [0.0], "nx": [1.0], "ny": [0.0], "nz": [0.0]}
    return make_log(cols, {"artefact": "mfb", **meta}, source="f.csv")


def test_certificate_lines_round_trip(rng):
    E, u = rng.normal(0, 1e-6, (12, 3)), rng.uniform(0, 5e-7, (12, 3))
    c = certificate_of_log(_log(certificate_lines(E, u)))
    np.testing.assert_allclose(c.E_m, E, rtol=1e-15, atol=0)
    np.testing.assert_allclose(c.u_m, u, rtol=1e-15, atol=0)
    assert certificate_of_log(_log({})) is None


@pytest.mark.parametrize("meta,words", [
    ({BAR_E_KEY: ",".join(["0"] * 36)}, f"no {BAR_U_KEY} line"),
    ({BAR_E_KEY: ",".join(["0"] * 35), BAR_U_KEY: ",".join(["0"] * 36)}, "36 finite numbers"),
    ({BAR_E_KEY: ",".join(["0"] * 36), BAR_U_KEY: ",".join(["-0.1"] * 36)}, ">= 0"),
])
def test_certificate_refusals(meta, words):
    with pytest.raises(ConfigError, match=words):
        certificate_of_log(_log(meta))


def test_probe_sigma_is_half_the_k2_line():
    assert probe_sigma_of_log(_log({"probe_repeatability_k2_um": "0.25"})) == pytest.approx(0.125e-6, rel=1e-15, abs=0)
    assert probe_sigma_of_log(_log({"plan_probe_repeatability_k2_um": "0.5"})) == pytest.approx(0.25e-6, rel=1e-15, abs=0)
    assert probe_sigma_of_log(_log({})) is None


def test_letters():
    assert [_letters(i) for i in (0, 1, 2, 25, 26)] == ["a", "b", "c", "z", "aa"]
