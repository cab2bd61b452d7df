"""Session 28 (v328): a cause's directions inflated beyond ``vif_max`` are left out of it (``VIF_DROP_BEYOND_MAX``).

Session 27's blind check failed gen_a c_drift 7302's workpiece check: a creep common to every set-up fitted to
per-set-up creeps of alternating sign, along a direction inflated 936 times (the best 12.3, below ``vif_max``, so the
form was not refused), carried 12.8 um into the extended workpiece against baseline 1.17 + U95 1.50. Its tuning twin
gen_a c_drift 1998 fails alike (the form "after each indexing", best inflation 29.7, worst 1,370). With the rule the
inflated direction is left out as a numerically unseen one (``WEAK_SV``) is, the creep it carried is not reported, and
the extended workpiece comes within the baseline's figure and its U95.
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest

import core.discover as D
from tests.discover_helpers import discovered


def _report(gen, effect, seed):

    log, _ = importlib.import_module(f"scenarios.blind.{gen}").generate(effect, seed)
    return discovered(log).to_report()


def test_determined_drops_directions_beyond_vif_max(monkeypatch):
    """Known answer: three columns orthogonal to a one-column model, ``a``, ``b`` orthogonal and ``c`` at 0.06 rad
    to ``a`` (the normalised pair's Gram eigenvalues 1 +- cos 0.06: its difference inflated 2 / 0.06^2 ~ 556 times,
    the best 1 / 2): with the rule the map keeps two directions, the worst kept inflation is at most vif_max and one
    direction is counted weak; without it all three are kept, the worst ~556."""
    rng = np.random.default_rng(0)
    n = 200
    Q, _ = np.linalg.qr(rng.normal(size=(n, 4)))
    a, b, d = Q[:, 1], Q[:, 2], Q[:, 3]
    Q = Q[:, :1]
    c = np.cos(0.06) * a + np.sin(0.06) * d
    E = np.column_stack([a, 3.0 * b, c])
    monkeypatch.setattr(D, "VIF_DROP_BEYOND_MAX", True)
    M, best, worst, ang, weak, beyond = D._determined(Q, E, 100.0)
    assert M.shape == (3, 2) and weak == 1 and beyond == 1
    assert best == pytest.approx(1 / (1 + np.cos(0.06))) and worst == pytest.approx(1.0)
    monkeypatch.setattr(D, "VIF_DROP_BEYOND_MAX", False)
    M0, best0, worst0, _, weak0, beyond0 = D._determined(Q, E, 100.0)
    assert M0.shape == (3, 3) and weak0 == 0 and beyond0 == 0 and best0 == best
    assert worst0 == pytest.approx(1 / (1 - np.cos(0.06)))  # (~556: beyond vif_max, within 1 / WEAK_SV^2)
    # a bound of infinity (the other reading's count, _reading_u95) leaves out only WEAK_SV's directions
    monkeypatch.setattr(D, "VIF_DROP_BEYOND_MAX", True)
    assert D._determined(Q, E, np.inf)[0].shape == (3, 3)
    # a confounded cause (best beyond vif_max) is still refused: no directions
    assert D._determined(Q, E, 0.5)[0].shape == (3, 0)


def test_c_drift_1998_workpiece_within_u95_only_with_the_rule(monkeypatch):
    """gen_a c_drift 1998 (session 27's likeness of the blind 7302): with the rule the extended workpiece error is
    1.842 um against baseline 1.084 + U95 0.836 (the check passes) and the creep of the form "after each indexing" is
    not reported (its gradient lies along the dropped direction); without it 11.894 um against 1.084 + 1.551 (fails)
    and the creep reads -994 +- 116 urad (the truth: per-set-up creeps of alternating sign, 37-175 urad)."""
    from scenarios.hidden import blind_outcome

    gen_a = importlib.import_module("scenarios.blind.gen_a")
    monkeypatch.setattr(D, "VIF_DROP_LEAST_INFLATION", False)  # (the drop alone; the form choice is tested below)
    monkeypatch.setattr(D, "VIF_FORM_BY_GAIN", False)  # (nor session 30's choice by gain: on since form30)
    monkeypatch.setattr(D, "FORM_SHIFT_CARRIED", False)  # (v328's figures: the other forms' shift not carried)
    monkeypatch.setattr(D, "HEDGED_SHIFT_CARRIED", None)  # (nor session 32's: an inflated named term's shift)
    monkeypatch.setattr(D, "VIF_DROP_BEYOND_MAX", True)
    on = blind_outcome(gen_a, "c_drift", 1998, generator="gen_a")
    assert on.cause == "c_drift" and on.confident
    # (the figures as measured, to 1e-3 um: a change of the engine that moves them should be looked at)
    assert on.wp_ext_um == pytest.approx(1.842, abs=1e-3) and on.wp_u95_um == pytest.approx(0.836, abs=1e-3)
    assert on.wp_ext_um <= on.wp_base_um + on.wp_u95_um
    f = _report("gen_a", "c_drift", 1998)["findings"][0]
    assert f["cause"] == "c_drift" and f["params"]["form"] == "after each indexing"
    assert f["evidence"]["weak_directions"] == 1 and f["evidence"]["directions_beyond_vif_max"] == 1
    assert f["evidence"]["max_vif"] <= 100.0
    assert f["params"]["ECC_change_in_setup_urad"] is None and f["params_u95"]["ECC_change_in_setup_urad"] is None

    monkeypatch.setattr(D, "VIF_DROP_BEYOND_MAX", False)
    off = blind_outcome(gen_a, "c_drift", 1998, generator="gen_a")
    assert off.cause == "c_drift"
    assert off.wp_ext_um > off.wp_base_um + off.wp_u95_um + 5.0, (off.wp_ext_um, off.wp_base_um, off.wp_u95_um)
    f0 = _report("gen_a", "c_drift", 1998)["findings"][0]
    assert f0["evidence"]["weak_directions"] == 0 and f0["evidence"]["max_vif"] > 1000.0
    assert "directions_beyond_vif_max" not in f0["evidence"]
    assert abs(f0["params"]["ECC_change_in_setup_urad"]) > 500.0


@pytest.mark.parametrize("seed, base_um, on_um, off_um", [
    (1998, 1.084, 0.216, 11.894),  # (the form "after each indexing", worst inflation 1,370, best 29.7)
    (1682, 0.641, 0.366, 1.609),  # (the form "over the campaign", worst 563, best 7.9: VIF_DROP_BEYOND_MAX alone 2.084)
])
def test_c_drift_least_inflated_form_when_a_direction_is_beyond_vif_max(monkeypatch, seed, base_um, on_um, off_um):
    """``VIF_DROP_LEAST_INFLATION`` (session 28, off): gen_a c_drift 1998 and 1682 adopt a creep common to every set-up
    (smallest p) fitted to per-set-up creeps of alternating sign, a direction inflated beyond vif_max; with the rule
    the cause's other passing forms are weighed and the least inflated, the per-set-up rates (inflation ~3), is named,
    and the extended workpiece comes within the baseline and its U95; without it the common creep stands and the
    check fails (the figures as measured, to 1e-3 um)."""
    from scenarios.hidden import blind_outcome

    gen_a = importlib.import_module("scenarios.blind.gen_a")
    # (both off by default since session 28: measured, each moves other campaigns; docs/discovery.md)
    assert D.VIF_DROP_LEAST_INFLATION is False and D.VIF_DROP_BEYOND_MAX is False
    # (the choice by least inflation, as session 28 measured it: session 30's choice by held-out gain, on since
    # form30, would take the same per-set-up form by its gain, with another evidence line, and mend "off" too)
    monkeypatch.setattr(D, "VIF_FORM_BY_GAIN", False)
    monkeypatch.setattr(D, "FORM_SHIFT_CARRIED", False)  # (v328's figures: the other forms' shift not carried)
    monkeypatch.setattr(D, "HEDGED_SHIFT_CARRIED", None)  # (nor session 32's: an inflated named term's shift)
    monkeypatch.setattr(D, "VIF_DROP_LEAST_INFLATION", True)
    on = blind_outcome(gen_a, "c_drift", seed, generator="gen_a")
    assert on.cause == "c_drift" and on.confident
    assert on.wp_base_um == pytest.approx(base_um, abs=1e-3) and on.wp_ext_um == pytest.approx(on_um, abs=1e-3)
    assert on.wp_ext_um <= on.wp_base_um + on.wp_u95_um
    f = _report("gen_a", "c_drift", seed)["findings"][0]
    assert f["cause"] == "c_drift" and f["params"]["form"] == "per set-up"
    assert "least variance inflation" in f["evidence"]["least_inflated_form"]
    assert f["evidence"]["vif"] < 5.0

    monkeypatch.setattr(D, "VIF_DROP_LEAST_INFLATION", False)
    off = blind_outcome(gen_a, "c_drift", seed, generator="gen_a")
    assert off.cause == "c_drift" and off.wp_ext_um == pytest.approx(off_um, abs=1e-3)
    assert off.wp_ext_um > off.wp_base_um + off.wp_u95_um
