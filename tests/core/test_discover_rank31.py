"""The planar rank tolerance on a log whose nominal positions are round by design (session 31, rank31).

``core.baseline.precision_rank_tol`` took the nominals' step from their values alone: a part whose every nominal
tip centre lies on a whole mm (a plate's walls probed every 10 mm, C at 0/90/180/270, no spheres) read as printed
to 1 mm (q / L ~ 1e-2, a tolerance of 0.13), and its workpiece was reported not identifiable, while the same
campaign moved off-round by 0.0123457 mm reported it. Values round by design are exact, not rounded; only the text
says how many digits were printed: the reader records the step each nominal and normal column was printed to (the
most decimals written, ``ProbeLog.text_steps``) and the tolerance takes the smaller of it and the values' step.
"""
import numpy as np
import pytest

from core import baseline as B
from core import probelog as P
from core import selfcal
from core.probelog import make_log, parse_probe_log
from core.touches import from_log

from test_discover_rank30 import _decisions, _rounded, _text


def _plate(shift_mm: float = 0.0, r_mm: float = 1.0, decimals: int = 7, nominal_decimals: int | None = None,
           seed: int = 1) -> str:
    """A 120 x 80 mm plate's outer walls probed every 10 mm by a tip of radius ``r_mm`` at C 0/90/180/270 about a
    C axis at (200, 150) mm (+ ``shift_mm`` in X and Y), the plate's corner at (-50, -30) from it: with r 1 every
    nominal tip centre lies on a whole mm (r 1.5: on a half mm). Measured = nominal + the normal times (0.5 um
    noise + a 3 ppm X scale and a 2 ppm squareness), every number printed to ``decimals`` (the nominals to
    ``nominal_decimals`` where given)."""
    rng = np.random.default_rng(seed)
    cx, cy = 200.0 + shift_mm, 150.0 + shift_mm
    x0, y0, W, H = -50.0, -30.0, 120.0, 80.0
    pts = []
    for i, x in enumerate(np.arange(x0 + 10, x0 + W, 10.0)):
        pts += [(f"S{i}", (x, y0 - r_mm), (0, -1)), (f"N{i}", (x, y0 + H + r_mm), (0, 1))]
    for i, y in enumerate(np.arange(y0 + 10, y0 + H, 10.0)):
        pts += [(f"W{i}", (x0 - r_mm, y), (-1, 0)), (f"E{i}", (x0 + W + r_mm, y), (1, 0))]
    f = f"{{:.{decimals}f}}".format
    fn = f"{{:.{decimals if nominal_decimals is None else nominal_decimals}f}}".format
    lines = ["# format: probe-log/1", "setup,target,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz,C_deg"]
    t = 0.0
    for C in (0, 90, 180, 270):
        c, s = np.cos(np.radians(C)), np.sin(np.radians(C))
        R = np.array([[c, -s], [s, c]]).round(12)
        for tg, w, n in pts:
            rel = R @ np.array(w)
            pn, nn = rel + (cx, cy), R @ np.array(n, float) + 0.0
            p = pn + np.array([3e-6 * rel[0], 2e-6 * rel[0]]) + nn * rng.normal(0, 0.5e-3)
            lines.append(",".join([f"C{C}", tg, f"{t:.1f}", f(p[0]), f(p[1]), f(-5), fn(pn[0]), fn(pn[1]), fn(-5),
                                   f(nn[0]), f(nn[1]), f(0), f"{C:.4f}"]))
            t += 2.0
    return "\n".join(lines) + "\n"


def _planar(text: str):
    t = from_log(parse_probe_log(text, "plate"))
    t = t.subset(np.abs(t.n_R[:, 2]) <= selfcal.NZ_MAX, reindex=True)
    return t, B.planar(t)


# ---- the printed step, as the reader counts it ----

@pytest.mark.parametrize("cells, k", [
    (["10.0000000", "20.0000000"], 7), (["10", "-20"], 0), (["10.", "3"], 0), ([".5", "10"], 1),
    (["10", "3.25", "7.1"], 2), ([" 2.50 ", "1"], 2), (["1.5e-3"], 4), (["1E-7", "2"], 7), (["1.25e3"], 0),
    (["", "4.000", ""], 3), (["", " "], None), (["71.70328770000001", "1.5"], 12), (["6.1e-17"], 12),
])
def test_most_decimals_known_answers(cells, k):
    """The most decimals written in a column's cells: trailing zeros count (``10.0000000`` is printed to 1e-7),
    an exponent moves the point (``1.5e-3`` is 0.0015: 4 decimals), empty cells count nothing; counted up to
    TEXT_DECIMALS_MAX (12: a repr's 14 read as 12)."""
    assert P.most_decimals(cells) == k


def test_most_decimals_agrees_with_counting_cell_by_cell():
    """The block scan (a run of digits after a point longer than the longest so far) against each cell's
    decimals counted one by one, on 200 blocks of 1-300 cells printed to 0-10 decimals each, with exponents
    (``1.2e+03``: 0, ``-4.5e-05``: 6) and as repr, ``6.123233995736766e-17`` among them."""
    rng = np.random.default_rng(31)
    for _ in range(200):
        n = int(rng.integers(1, 300))
        ks = rng.integers(0, 13, n)
        v = rng.normal(0, 10.0 ** rng.integers(-2, 4), n)
        cells = [repr(float(x)) if k == 12 else f"{x:.{k}e}" if k == 11 else f"{x:.{k}f}" for x, k in zip(v, ks)]
        if rng.random() < 0.3:
            cells[0] = repr(float(rng.normal() * 1e-17))  # (a component next to 0: 6.123233995736766e-17)

        def one(c):
            m, _, e = c.partition("e")
            return max((len(m) - m.index(".") - 1 if "." in m else 0) - (int(e) if e else 0), 0)
        assert P.most_decimals(cells) == min(max(map(one, cells)), P.TEXT_DECIMALS_MAX)


_HDR = "setup,target,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz"


def test_the_reader_records_the_printed_step_of_the_nominal_and_normal_columns(monkeypatch):
    """Known answers: ``10.0000000`` declares 1e-7 whatever its value, ``10`` declares 1; the most decimals over
    every block of rows (the 7-decimal cell in the last of three blocks); a log built in memory declares nothing
    (its values say it); with TEXT_STEP_COLUMNS None nothing is recorded."""
    text = (_HDR + "\ns1,p1,0,1,1,0,10,20.5,0,1,0,0\ns1,p2,1,2,0,0,10.0000000,-20.5,0,0.6000000,0.8,0\n"
            "s1,p3,2,2,0,0,10,-20.5,0.000,0,1,0\n")
    monkeypatch.setattr(P, "CHUNK_ROWS", 1)
    log = parse_probe_log(text, "steps.csv")
    assert log.text_steps == {"Xn_mm": pytest.approx(1e-7, abs=0), "Yn_mm": pytest.approx(0.1), "Zn_mm": pytest.approx(1e-3),
                              "nx": pytest.approx(1e-7, abs=0), "ny": pytest.approx(0.1), "nz": 1.0,
                              # (session 32, fitq32: the measured columns too, for vmt fit's rounding floor)
                              "X_mm": 1.0, "Y_mm": 1.0, "Z_mm": 1.0}
    assert from_log(log).text_steps == log.text_steps
    assert log.select(np.array([0])).text_steps == log.text_steps
    assert make_log({k: log.columns[k] for k in log.columns}).text_steps == {}
    assert from_log(make_log({k: log.columns[k] for k in log.columns})).text_steps is None
    monkeypatch.setattr(P, "TEXT_STEP_COLUMNS", None)
    assert parse_probe_log(text, "steps.csv").text_steps == {}


# ---- the round-by-design campaign ----

@pytest.mark.parametrize("r_mm", [1.0, 1.5])
def test_round_nominals_keep_the_decisions_of_the_same_campaign_off_round(monkeypatch, r_mm):
    """The plate with every nominal on a whole mm (r 1) or half mm (r 1.5), printed to 7 decimals, against the
    same campaign moved by 0.0123457 mm (its nominals then need every decimal): the same tolerance (RANK_TOL),
    grid, rank and estimable workpiece, the workpiece within 1e-9 um RMS (the shift is exact at 7 decimals, so
    every dq is the same number: measured 3.5e-11 and 4.8e-11 um, the design's floating-point rounding). Fails with TEXT_STEPS off: the round log's nominals
    read as printed to 1 mm (0.1 mm), a tolerance of 0.13 (0.013) against the off-round log's 1e-7; at 0.13 the
    workpiece is not estimable (at 0.013 it still is on this design: grid 80 mm and rank 53 in all four)."""
    t0, bl0 = _planar(_plate(0.0123457, r_mm))
    t, bl = _planar(_plate(0.0, r_mm))
    q = 1.0 if r_mm == 1.0 else 0.1  # (0.5 mm: 1 decimal)
    assert B.decimal_quantum(t.pn_R[:, :2] / 1e-3) == q
    assert t.text_steps["Xn_mm"] == pytest.approx(1e-7, abs=0)
    assert bl.rank_tol == bl0.rank_tol == B.RANK_TOL
    g0, r0, e0, w0 = _decisions(bl0)
    g, r, e, w = _decisions(bl)
    assert (g, r, e) == (g0, r0, e0) and e0
    assert np.sqrt(np.mean((w - w0) ** 2)) < 1e-9
    monkeypatch.setattr(B, "TEXT_STEPS", False)
    bl_old = B.planar(t)
    L = np.abs(t.pn_R[:, :2] - B.c_axis_centre(t)[:2]).max()
    assert bl_old.rank_tol == pytest.approx(B.RANK_QUANTUM_FACTOR * q * 1e-3 / L, rel=1e-12, abs=0)
    assert _decisions(bl_old)[2] is (r_mm != 1.0)  # (the half-mm plate's workpiece survives 0.013 here)
    assert B.planar(t0).rank_tol == B.RANK_TOL  # (off-round: the values' own step, as before)


def test_nominals_printed_to_whole_mm_declare_whole_mm():
    """The same plate with its nominals printed ``160`` (0 decimals): the file declares whole mm, and the
    tolerance is the one a log printed to that step needs, as before (10 x 1 mm / L; L = 91 mm, the farthest
    nominal from the C axis)."""
    t, _ = _planar(_plate(0.0, nominal_decimals=0))
    assert t.text_steps["Xn_mm"] == 1.0
    L = np.abs(t.pn_R[:, :2] - B.c_axis_centre(t)[:2]).max()
    assert B.precision_rank_tol(t, B.c_axis_centre(t)) == pytest.approx(B.RANK_QUANTUM_FACTOR * 1e-3 / L, rel=1e-12, abs=0)


def test_normals_round_by_design_are_exact(monkeypatch):
    """A wall at 3-4-5 (normal 0.6, 0.8), printed ``0.6000000``: exact to its 7 printed decimals, not printed to
    0.1 (before: q_n = 0.1, a tolerance of 1, every direction unseen). Known answers: 10 x 1e-7 with the text's
    step (the normals' step is unit-free, rank30b: as any normal printed to 7 decimals); 10 x 0.1 without it
    (TEXT_STEPS off)."""
    text = (_HDR + "\ns1,p1,0,1,1,0,71.7032877,-37.2419668,0,0.6000000,0.8000000,0.0000000\n"
            "s1,p2,1,2,0,0,12.5000001,40.1234567,0,1.0000000,0.0000000,0.0000000\n")
    t = from_log(parse_probe_log(text, "n.csv"))
    assert B.precision_rank_tol(t, np.zeros(3)) == pytest.approx(B.RANK_QUANTUM_FACTOR * 1e-7, rel=1e-9, abs=0)
    monkeypatch.setattr(B, "TEXT_STEPS", False)
    assert B.precision_rank_tol(t, np.zeros(3)) == pytest.approx(B.RANK_QUANTUM_FACTOR * 0.1)


@pytest.mark.parametrize("k", [4, 3])
def test_a_log_printed_to_few_decimals_keeps_rank30s_protection(k):
    """review30c's plate printed to 4 and 3 decimals: the text's step is the values' (1e-4, 1e-3), so the
    tolerance is rank30's 10 q / L and the decisions the full log's (grid 55 mm, rank 113, workpiece estimable)."""
    t, bl = _planar(_rounded(_text("plate_none_300"), k))
    assert t.text_steps["Xn_mm"] == pytest.approx(10.0 ** -k)
    L = np.abs(t.pn_R[:, :2] - B.c_axis_centre(t)[:2]).max()
    assert bl.rank_tol == pytest.approx(B.RANK_QUANTUM_FACTOR * 10.0 ** -k * 1e-3 / L, rel=1e-9, abs=0)
    assert _decisions(bl)[:3] == (55.0, 113, True)
