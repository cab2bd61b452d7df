"""part_change's continuous form curving in time (core.causes.PART_CHANGE_CURVE, session 23; docs/discovery.md,
"Session 23: the last blind check's part changes ...").

gen_a's and gen_b's parts change as ``1 - exp(-t / tau)`` with tau about the campaign's span; the catalogue's
continuous form is the line in ``t`` (0 at the first touch, 1 at the last). The settling change is that line plus
a bulge ``t (1 - t)`` (zero at both ends) and a small rest: the richest layout again with each wall's shift (a
ring's ovalisation) also times ``t (1 - t)``, grown like the turns and bows (core.discover._grow_layout: taken only
where its new columns are significant beyond the layout taken so far and it lowers the held-out mean square).
Built, measured and left off (a settling thermal bending is fitted as well: gen_a thermal_bending 1138 and knock 1001
right -> wrong); these tests turn it on.
"""
import numpy as np
import pytest

import core.causes as C
from core.baseline import extra_columns, planar
from core.discover import discover
from core.lsq import orth_of
from core.touches import from_log


def _campaign(gen, effect, seed):
    from scenarios.blind import gen_a, gen_b

    log, tr = {"gen_a": gen_a, "gen_b": gen_b}[gen].generate(effect, seed)
    return log, tr, from_log(log)


def test_curve_scan_holds_a_settling_change(monkeypatch):
    """Each feature's curve scan extends its richest continuous layout (its columns are in the curve scan's span)
    and holds a wall's settling change ``(1 - exp(-t / tau)) / (1 - exp(-1 / tau))`` (tau a third of the span)
    to less than a fifth of what the line alone leaves (0.105 against 0.657: the rest is the settling's third
    order and beyond); the step-per-set-up form has no curve scan."""
    monkeypatch.setattr(C, "PART_CHANGE_CURVE", True)
    log, tr, t = _campaign("gen_b", "none", 1010)
    bl = planar(t, 30.0, extra=extra_columns(log, t.row))
    scans, count = C.part_change_scans(bl)
    assert count == len(scans)
    monkeypatch.setattr(C, "PART_CHANGE_CURVE", False)  # off (the default): the scans before, none curving
    off = C.part_change_scans(bl)[0]
    assert not any(s.infos[0].get("curve") for s in off) and len(scans) == len(off) + len(
        {s.infos[0]["feature"] for s in scans if s.infos[0].get("curve")})
    assert not any(s.infos[0].get("curve") for s in scans if s.infos[0].get("time_form") == "per_setup")
    cont = [s for s in scans if s.infos[0].get("time_form", "continuous") == "continuous"
            and s.infos[0]["feature"] == "slot"]
    assert [bool(s.infos[0].get("curve")) for s in cont] == [False, False, False, True], [s.labels for s in cont]
    Q_rich, Q_curve = (orth_of(s.build([0])[0]) for s in cont[2:])
    assert np.linalg.norm(Q_rich - Q_curve @ (Q_curve.T @ Q_rich)) < 1e-9 * np.sqrt(Q_rich.shape[1])
    tau = (t.t_s - t.t_s.min()) / np.ptp(t.t_s)
    settle = (1 - np.exp(-tau * 3)) / (1 - np.exp(-3))
    wall = np.flatnonzero(np.abs(cont[0].build([0])[0][:, 0]) > 0)
    y = np.zeros(t.n)
    y[wall] = settle[wall]
    left = {name: np.linalg.norm(y - Q @ (Q.T @ y)) for name, Q in (("line", Q_rich), ("curve", Q_curve))}
    assert left["curve"] < 0.2 * left["line"] and left["line"] > 0.05 * np.linalg.norm(y), left


@pytest.mark.parametrize("curve", [True, False])
def test_gen_a_part_change_1080_named_with_its_curve(monkeypatch, curve):
    """The tuning miss: gen_a part_change 1080 (2.97 sigma visible; bore3 relaxing with tau a fraction of the span)
    read `outlier` (ambiguous), part_change refused for a held-out loss of 0.054 um^2 (the line in time leaves the
    settling bulge). With the curve scan it is named, confident, on the generator's feature, the walls' curves
    beside their changes; without it (the flag off: the engine before) it is not."""
    monkeypatch.setattr(C, "PART_CHANGE_CURVE", curve)
    log, tr, t = _campaign("gen_a", "part_change", 1080)
    rep = discover(t, chain=log.meta.get("kinematic_chain"), extra=extra_columns(log, t.row)).to_report()
    f = rep["findings"][0]
    if not curve:
        assert f["cause"] != "part_change", f
        return
    assert f["cause"] == "part_change" and f["params"]["feature"] == tr.params["feature"], rep["rejected"]
    assert f["evidence"].get("confidence") != "ambiguous", f["evidence"].get("confidence_reason")
    curves = [k for k in f["params"] if k.endswith("_curve_um")]
    assert curves and all(k.replace("_curve_um", "_change_um") in f["params"] for k in curves), f["params"]
    # a settling change bulges the way it changes: each wall's curve has its change's sign
    assert all(np.sign(f["params"][k]) == np.sign(f["params"][k.replace("_curve_um", "_change_um")])
               for k in curves), f["params"]
