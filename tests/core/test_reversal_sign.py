"""The sign of the reported lost motion (``x_lost_motion_um``), a known answer built by hand (no sim/).

The worked case (docs/discovery.md, "Session 20: the sign of the reported lost motion"): the X carriage,
driven through a screw read by a rotary encoder, lags the reading by ``b/2 = 3 um`` against its motion, so its
tool error (actual minus reported, ISO 230-1's E_XX) is ``E = -(b/2) sign(v_x)``. A block's two x faces are
touched. The trigger fires when the actual tip reaches the face (the nominal tip centre ``Xn``); the machine
reports ``X = Xn - E``:

- face normal +x, the stylus approaching in -x (``d = (-1, 0, 0)``): ``E = +b/2``, ``X = Xn - b/2``,
  ``dq = n.(X - Xn) = -b/2``;
- face normal -x, approaching in +x: ``E = -b/2``, ``X = Xn + b/2``, ``dq = -1 * (+b/2) = -b/2``.

The block reads smaller by ``b`` (each face ``b/2`` in). ISO 230-2 on the same axis (a laser reading the actual
position at commanded targets, ``x = actual - target``): ``x_up = -b/2``, ``x_down = +b/2``, the reversal value
``B_i = x_up - x_down = -b``. The report's ``x_lost_motion_um`` is ISO 230-2's signed reversal value ``B_i``
(2.12) of the axis: ``-b = -6 um`` here; a lead (the simulator's positive ``Reversal``) reads positive.
"""

from __future__ import annotations

import types

import numpy as np

from core import causes
from core.positioning import iso230_2, make_positioning_log
from core.probelog import make_log
from core.touches import from_log
from core.units import UM

LAG_UM = 6.0  # b: the carriage trails the encoder by b/2 against its motion


def _hand_log(lag_um: float):
    """Two set-ups of a 40 mm block: its +x and -x faces at three heights of y, and its +y face (no x motion at
    the touch: no x error, and the y axis is perfect). Reported = nominal - E, E = -(b/2) sign(d_x)."""
    rows = []
    for s in ("s1", "s2"):
        for k, y in enumerate((-10.0, 0.0, 10.0)):
            rows.append((s, f"xp{k}", 20.0 + 3.0, y, (1.0, 0.0), (-1.0, 0.0)))   # face +x, approached moving -x
            rows.append((s, f"xm{k}", -20.0 - 3.0, y, (-1.0, 0.0), (1.0, 0.0)))  # face -x, approached moving +x
        for k, x in enumerate((-10.0, 10.0)):
            rows.append((s, f"yp{k}", x, 20.0 + 3.0, (0.0, 1.0), (0.0, -1.0)))   # face +y, approached moving -y
    X, Xn, n, d = [], [], [], []
    for _, _, xn, yn, nn, dd in rows:
        e_x = -(lag_um / 2) * np.sign(dd[0]) * 1e-3  # mm; 0 when the approach has no x component
        Xn.append((xn, yn, 0.0))
        X.append((xn - e_x, yn, 0.0))
        n.append(nn)
        d.append(dd)
    X, Xn, n, d = (np.asarray(a, float) for a in (X, Xn, n, d))
    m = len(rows)
    cols = {"setup": [r[0] for r in rows], "target": [r[1] for r in rows], "t_s": np.arange(m, dtype=float),
            "X_mm": X[:, 0], "Y_mm": X[:, 1], "Z_mm": X[:, 2], "Xn_mm": Xn[:, 0], "Yn_mm": Xn[:, 1],
            "Zn_mm": Xn[:, 2], "nx": n[:, 0], "ny": n[:, 1], "nz": np.zeros(m),
            "dx": d[:, 0], "dy": d[:, 1], "dz": np.zeros(m)}
    return make_log(cols, {"stylus_r_mm": 3.0})


def test_hand_built_lag_reads_as_iso_230_2_reversal_value():
    log = _hand_log(LAG_UM)
    t = from_log(log)
    # the spec's dq, from the file's columns
    spec_dq_um = 1e3 * (log.col("nx") * (log.col("X_mm") - log.col("Xn_mm"))
                        + log.col("ny") * (log.col("Y_mm") - log.col("Yn_mm")))
    on_x = np.abs(log.col("nx")) > 0.5
    assert np.allclose(spec_dq_um[on_x], -LAG_UM / 2) and np.allclose(spec_dq_um[~on_x], 0.0)
    assert np.allclose(t.dq_m / UM, spec_dq_um)  # the reader's dq is the spec's
    # the reversal's columns on these touches (what reversal_scans reads of a baseline: the touches and normals)
    bl = types.SimpleNamespace(data=types.SimpleNamespace(touches=t, nx=t.n_R[:, 0], ny=t.n_R[:, 1]))
    scans, _ = causes.reversal_scans(bl)
    A = scans[0].build([0])[0]
    coef = np.linalg.lstsq(A, spec_dq_um * UM, rcond=None)[0]
    assert np.allclose(A @ coef, spec_dq_um * UM, atol=1e-15)  # the lag is exactly in the cause's span
    mag = causes.reversal_magnitudes(scans[0].infos[0], coef, bl)
    assert abs(mag["x_lost_motion_um"] - (-LAG_UM)) < 1e-9, mag
    assert abs(mag["y_lost_motion_um"]) < 1e-9, mag


def test_iso_230_2_reversal_value_of_the_same_lag_is_negative():
    """The same carriage on a positioning test: targets 0, 50, 100 mm, two cycles, the laser reading the actual
    position ``target + E``: ``B_i = x_up - x_down = -b`` at every target, the report's sign."""
    tg, cy, di, me = [], [], [], []
    for c in (1, 2):
        for sgn, order in ((1, (0.0, 50.0, 100.0)), (-1, (100.0, 50.0, 0.0))):
            for p in order:
                tg.append(p)
                cy.append(c)
                di.append("+" if sgn > 0 else "-")
                me.append(p - (LAG_UM / 2) * sgn * 1e-3)
    res = iso230_2(make_positioning_log(tg, cy, di, me))
    assert np.allclose(np.asarray(res.B_i) * 1e3, -LAG_UM)  # mm -> um
    assert abs(res.B_mean * 1e3 + LAG_UM) < 1e-9
    assert abs(res.B * 1e3 - LAG_UM) < 1e-9  # 2.13: the axis' reversal value is max |B_i|, unsigned


def test_a_lead_reads_positive():
    """The mirror case (the simulator's ``Reversal``: ``+lost_motion/2`` moving in +, a lead): +b."""
    log = _hand_log(-LAG_UM)
    t = from_log(log)
    dq = (log.col("nx") * (log.col("X_mm") - log.col("Xn_mm"))) * 1e-3
    bl = types.SimpleNamespace(data=types.SimpleNamespace(touches=t, nx=t.n_R[:, 0], ny=t.n_R[:, 1]))
    scans, _ = causes.reversal_scans(bl)
    A = scans[0].build([0])[0]
    coef = np.linalg.lstsq(A, dq, rcond=None)[0]
    assert abs(causes.reversal_magnitudes(scans[0].infos[0], coef, bl)["x_lost_motion_um"] - LAG_UM) < 1e-9
