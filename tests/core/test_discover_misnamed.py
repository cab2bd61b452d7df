"""Issue 13 item 7, "never confidently misnamed": the rules written for the confident misnamings left.

- The rival check forgives a cause that falls short of the smooth term in
  its covariate by less than materiality only where that structure is
  itself material (:func:`core.discover._rival_share`): where it is not,
  every shortfall is, and the share decides.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from core.diagnosis import orth
from core.discover import Settings, Term, _rival_share
from core.units import UM


class _Bl:
    """The least of a baseline :func:`_rival_share` asks for: covariates by name, no whitening."""

    whiten = None

    def covariate(self, name):
        return SimpleNamespace(name=name, family="")


@pytest.mark.parametrize("a2, c2, kept", [
    (3.0, 2.0, False),    # d_n 2, d_r 3 (immaterial, 9): share 0.67, the shortfall no longer forgiven (main: kept)
    (20.0, 6.0, True),    # d_n 19, d_r 24 (material): share 0.79, a shortfall of 5 < 9 forgiven
    (20.0, 1.5, True),    # share 19 / 19.5 >= 0.8
    (3.0, 0.5, True),     # immaterial but share 2 / 1.5 >= 0.8: the share decides, and keeps it
])
def test_rival_check_forgives_a_shortfall_only_of_material_structure(a2, c2, kept):
    """Known answers, noise-free, sigma 1, 100 rows (materiality (0.3 sigma)^2 x 100 = 9): the cause's one
    column ``b1``, the smooth of its covariate ``b1, b2`` (orthonormal, outside an intercept), the data
    ``a b1 + c b2``: the cause explains ``a^2 - 1`` (debiased), the smooth ``a^2 + c^2 - 2``. Main kept a
    cause whose share fell short of rival_share (0.8) whenever the shortfall was below materiality, also
    where the covariate's whole structure was immaterial, so that every shortfall was (the check could
    not fail: gen_b outlier 908, local_scale_defect explaining 1.40 um^2 of 1.90 in y, materiality 2.29,
    named confidently beside 1,436 um^2 of chips). Main kept all four."""
    n = 100
    rng = np.random.default_rng(0)
    Qb = orth(np.ones((n, 1)))
    B = orth(np.column_stack([np.ones(n), rng.normal(size=(n, 2))]))[:, 1:]  # orthonormal, outside Qb
    y = np.sqrt(a2) * B[:, 0] + np.sqrt(c2) * B[:, 1]
    tm = Term("probe_lobing", B[:, :1], ("b1",), {}, "c")
    out = _rival_share(_Bl(), tm, [tm], Qb, y, np.arange(n), 1.0, Settings(), {"c": B}, None)
    assert out["explained_ss_um2"] * UM ** 2 == pytest.approx(a2 - 1)
    assert out["rival_explained_ss_um2"] * UM ** 2 == pytest.approx(a2 + c2 - 2)
    assert out["kept"] is kept, out
