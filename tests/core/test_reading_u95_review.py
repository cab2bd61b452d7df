"""The session 23 review's mends of the reading-choice U95 (:func:`core.discover._reading_u95`).

(1) The other reading's directions the data cannot see are looked for within the chosen reading's combinations,
where it is fitted (before, over all its labels: gen_b probe_lobing 1294's other-reading k3 and k4 went to their
lower bounds though that reading measures them). (2) A magnitude the other reading leaves free gets no U95 where that
reading's weight is above ``READING_FREE_WEIGHT`` (before: the chosen U95 stood as if the other reading agreed).
(3) A chosen reading whose best direction is inflated beyond ``vif_max`` is still counted (before: k_c = 0, w_o = 1).
Each test fails on the code before the mend (9e70f75). docs/discovery.md, "Session 23: three latent faults of the
reading-choice U95", "Review mends".
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

import core.discover as D
from scenarios.blind import gen_a, gen_b

sys.path.insert(0, str(Path(__file__).parent))
from test_reading_u95_latent import _call  # noqa: E402

UM = 1e-6


def _finding(rep):
    return [f for f in rep["findings"] if f["cause"] == "probe_lobing"][0]


def _direct(args, cols):
    """Least squares of the residuals beside ``so`` on ``cols`` (rows used) projected out of it: label coefficients
    ``tm.map @ c`` and the sum of squares the columns explain (numpy's lstsq, not _magnitudes)."""
    cause, bl, tm, so, rows = args[:5]
    E = cols[rows] @ tm.map
    Ep = E - so.Q @ (so.Q.T @ E)
    c = np.linalg.lstsq(Ep, so.r, rcond=None)[0]
    return tm.map @ c, float(np.sum((Ep @ c) ** 2))


def test_1_the_other_reading_measures_what_its_fitted_combinations_see():
    """(1) gen_b probe_lobing 1294, read along the normal (6 combinations of 8 labels, the first harmonic held): the
    other (approach) reading's third and fourth harmonics are fitted in those combinations and determined there. Its
    amplitudes are the direct least squares' |(cos_k, sin_k)| (1.997 and 0.024 um); before, the weak-direction test
    ran over all 8 labels and reported them as lower bounds only."""
    args, r, rep = _call(gen_b, 1294)
    tm = args[2]
    assert _finding(rep)["params"]["pretravel_along"] == "normal" and tm.map.shape == (8, 6)
    C = D._other_reading(args[1], tm)[1]
    coef, _ = _direct(args, C)
    for k, want in ((3, 1.997), (4, 0.024)):
        key = f"k{k}_amplitude_um"
        amp = float(np.hypot(coef[2 * k - 2], coef[2 * k - 1])) / UM
        assert amp == pytest.approx(want, abs=1e-3)
        assert r["other_values"][key] == pytest.approx(amp, rel=1e-9)
        assert r["other_u95"][key] is not None and key not in r.get("other_lower_bounds", {})
    assert r["other_values"]["k1_amplitude_um"] is None  # (the held first harmonic is still no estimate)


def _weight(args):
    """Akaike's weight of the other reading from the direct fits (each reading's combinations its determined ones
    here: cut by their count of columns, 8 chosen, 6 other on gen_b read along the approach)."""
    cause, bl, tm, so, rows, vals, u95, sig = args[:8]
    C = D._other_reading(bl, tm)[1]
    _, ss_c = _direct(args, tm.columns)
    Eo = C[rows] @ tm.map
    Eo = Eo - so.Q @ (so.Q.T @ Eo)
    s = np.linalg.svd(Eo / np.linalg.norm(Eo, axis=0), compute_uv=False)
    k_o = int(np.sum(s > 1e-2))
    U = np.linalg.svd(Eo, full_matrices=False)[0][:, :k_o]
    ss_o = float(np.sum((U.T @ so.r) ** 2))
    return 1.0 / (1.0 + np.exp((ss_c - ss_o) / (2 * sig ** 2) - (tm.map.shape[1] - k_o)))


@pytest.mark.parametrize("seed, free", [(1276, True), (1253, False)])
def test_2_a_magnitude_the_other_reading_leaves_free_has_no_u95_at_a_material_weight(seed, free):
    """(2) gen_b probe_lobing 1276 and 1253, read along the approach: k1 is the chosen reading's (3.53 and 2.22 um),
    the normal reading leaves it in the baseline. At weight 0.081 (1276, above READING_FREE_WEIGHT = 0.05) the
    mixture's 95 % interval cannot be bounded: no U95, said in ``magnitude_undetermined`` (before: 3.527 +- 3.527 um
    reported as if the other reading agreed). At 0.048 (1253) the chosen U95 stands."""
    args, r, rep = _call(gen_b, seed)
    f = _finding(rep)
    key = "k1_amplitude_um"
    assert f["params"]["pretravel_along"] == "approach" and r["other_values"][key] is None
    w = _weight(args)
    assert r["weight_other"] == pytest.approx(w, rel=1e-6)
    assert (w > D.READING_FREE_WEIGHT) == free
    assert f["params"][key] == pytest.approx(args[5][key])
    if free:
        assert f["params_u95"][key] is None and r["free_in_other"] == [key]
        assert f"{key} = " in f["evidence"]["magnitude_undetermined"]
        assert f["evidence"]["confidence"] == "ambiguous"
    else:
        assert f["params_u95"][key] == pytest.approx(args[6][key], rel=1e-12) and "free_in_other" not in r


def test_3_a_chosen_reading_inflated_beyond_vif_max_is_still_counted():
    """(3) gen_a probe_lobing 1023 with ``vif_max`` between the two readings' best inflations (1.32305 chosen,
    1.32270 other): _determined refused the chosen reading and counted k_c = 0 against 8, giving w_o = 1.0. The
    count is of the determined directions (8 labels, every one determined: 8 and 8), and the weight that of the
    direct fits."""
    args, r0, _ = _call(gen_a, 1023)
    cause, bl, tm, so, rows, vals, u95, sig, settings, folds, others = args
    C = D._other_reading(bl, tm)[1]
    vc = D._determined(so.Q, tm.columns[rows] @ tm.map, np.inf)[1]
    vo = D._determined(so.Q, C[rows] @ tm.map, np.inf)[1]
    assert vc > vo
    s2 = dataclasses.replace(settings, vif_max=float(np.sqrt(vc * vo)))
    r = D._reading_u95(cause, bl, tm, so, rows, vals, u95, sig, s2, None, others)
    assert r["columns"] == [8, 8]
    _, ss_c = _direct(args, tm.columns)
    _, ss_o = _direct(args, C)
    assert r["weight_other"] == pytest.approx(1.0 / (1.0 + np.exp((ss_c - ss_o) / (2 * sig ** 2))), rel=1e-6)
    assert 0.3 < r["weight_other"] < 0.5
