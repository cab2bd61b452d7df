import numpy as np
import pytest


@pytest.fixture
def rng():
    """A seeded generator: every random test is reproducible."""
    return np.random.default_rng(20261122)


@pytest.fixture(scope="session")
def mfb3_noise_free():
    """One noise-free ``mfb-3axis`` run on the default realistic machine, shared by the test files
    that need it (a full run is the suite's costliest step): ``(ScenarioResult, (meas, chain,
    nodes, rotary_points))``, the second being what the run handed to the identification."""
    import core.volumetric as V
    import scenarios.mfb as S

    cap = {}
    orig = V.identify_volumetric

    def spy(meas, chain, nodes, rp=None, **kw):
        cap["m"] = (meas, chain, nodes, rp)
        return orig(meas, chain, nodes, rp, **kw)

    V.identify_volumetric = spy
    try:
        res = S.run("mfb-3axis", noise_um=0.0, mc_runs=0)
    finally:
        V.identify_volumetric = orig
    return res, cap["m"]
