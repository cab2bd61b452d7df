"""The demo report's views: array layouts the figures and the recording expect."""

import numpy as np

from core.selfcal import Grid, error_map, self_calibrate
from core.touches import from_log
from scenarios.reports import _DemoView
from sim import artefacts as A
from sim.campaign import simulate_campaign
from sim.machine import Machine
from sim.machines import MACHINES, realistic_errors
from sim.probe import ProbeConfig


def test_demo_view_maps_are_rows_y_columns_x_on_a_non_square_grid():
    """error_map gives (N_x, N_y); the figures and the recording draw (ny, nx).

    A square grid hides a transposition (the demo's is square): here X has
    11 nodes and Y 6, and the view's node (iy, ix) must be error_map's (ix, iy).
    """
    machine = Machine(MACHINES["nmv3000"](errors=realistic_errors(
        ("X", "Y", "Z", "C"), rng=np.random.default_rng(1), ripple=False)))
    log = simulate_campaign(A.cross_pocket(), machine, ProbeConfig(repeatability_k2_m=0.0),
                            [0.0, 75.0, 130.0, 210.0], np.random.default_rng(0))
    t = from_log(log)
    res = self_calibrate(t, Grid(np.linspace(-0.110, 0.110, 11), np.linspace(-0.110, 0.110, 6)))
    ident = {"workpiece": [{"u95_um": None}] * len(res.design.target_ids)}
    v = _DemoView.of(t, res, ident, machine=machine)
    _, _, ex, ey = error_map(res)
    assert ex.shape == (11, 6)
    assert v.ex_um.shape == v.ey_um.shape == v.tex.shape == v.tey.shape == (6, 11)
    np.testing.assert_allclose(v.ex_um[2, 7], ex[7, 2] * 1e6, rtol=0, atol=1e-9)
    np.testing.assert_allclose(v.ey_um[5, 10], ey[10, 5] * 1e6, rtol=0, atol=1e-9)
    assert v.chain is None                  # an ident without identified_on: chain unknown, the label hedges
    ident["estimate"] = {"identified_on": {"chain": log.meta["kinematic_chain"]}}
    assert _DemoView.of(t, res, ident, machine=machine).chain == "V[w-C-A-b-Y-X-Z-(C)-t]"   # the C label's carrier
