"""A planar campaign with a part clamped with a bow in its first two set-ups (review32c's generator, session 32).

Trimmed from review32c's own planar generator (written from docs/formats.md and the probe-log spec, not from
scenarios/blind or sim; byte-identical output to its ``clamp_relax`` logs: ``campaign(20000, 6.30895275826131)`` is
its ``ooc_clamp_relax_20000.csv``). Part: a bolt-hole circle of 6 bores (r 8 mm on a 55 mm pitch circle) plus a
rectangular boss 40 x 26 mm off centre, on a rotary table whose axis is at (312.4, 187.9) mm. Set-ups at C
0/37/151/270 deg, unequal (set-up 2 skips two bores, set-up 4 skips the boss's short faces), repeats: each set-up's
first target touched again at its end, plus 2 immediate double touches a set-up. Timings 4-9 s a touch, 60-400 s
between set-ups, a 900 s pause in set-up 3. Noise: Student-t 4 dof scaled to sigma (0.2-0.5 um), plus a slowly
wandering probe offset (OU, 0.08 um RMS). Machine: smooth axis errors (cubic, ~6 um over the stroke), per-set-up C
location/angle errors (the baseline's). The effect: in set-ups 1-2 the part's surface moves along W's y by a bow of
``bow_um`` times 4 ((x / 55 mm)^2 - 1/2), relaxed after re-clamping: discover reads it ``unexplained`` in
``feature`` (the feature, differently in each set-up), whose held-out curve over the ridge penalties is flat.
"""
import numpy as np

UM = 1e-3  # mm
C_CENTRE = np.array([312.4, 187.9])


def rot(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def part():
    """targets: list of dict(id, feature, w (2,), wn (2,), z)."""
    T = []
    for k in range(6):
        a = np.radians(15 + 60 * k)
        h = 55.0 * np.array([np.cos(a), np.sin(a)])
        for j, phi in enumerate((0, 90, 180, 270)):
            ph = np.radians(phi + 10 * k)
            d = np.array([np.cos(ph), np.sin(ph)])
            T.append(dict(id=f"h{k}_{j}", feature=f"hole{k}", w=h + 8.0 * d, wn=-d, z=-6.0, centre=h, rad=8.0))
    bc = np.array([-12.0, 8.0])  # boss centre
    for face, (nrm, half, along, pts) in {"E": ((1, 0), 20, (0, 1), (-8, 8)), "W": ((-1, 0), 20, (0, 1), (-8, 8)),
                                          "N": ((0, 1), 13, (1, 0), (-12, 0, 12)),
                                          "S": ((0, -1), 13, (1, 0), (-12, 0, 12))}.items():
        nrm, along = np.array(nrm, float), np.array(along, float)
        for j, s in enumerate(pts):
            T.append(dict(id=f"b{face}{j}", feature=f"boss{face}", w=bc + half * nrm + s * along, wn=nrm, z=-3.0,
                          centre=bc, rad=None))
    return T


def campaign(seed: int, bow_um: float, C=(0.0, 37.0, 151.0, 270.0), wander=0.08):
    """(probe-log/1 text, the true workpiece form per target in um) of one campaign at ``seed``."""
    rng = np.random.default_rng(seed)
    sigma = rng.uniform(0.2, 0.5)
    T = part()
    # true workpiece form (um, along the outward normal)
    g = {}
    hole_d = {f"hole{k}": (rng.normal(0, 2.0, 2), rng.normal(0, 1.5)) for k in range(6)}
    face_e = {f"boss{f}": rng.normal(0, 2.0) for f in "EWNS"}
    for t in T:
        if t["feature"].startswith("hole"):
            dlt, dr = hole_d[t["feature"]]
            g[t["id"]] = float(t["wn"] @ dlt - dr + rng.normal(0, 0.4))
        else:
            g[t["id"]] = float(face_e[t["feature"]] + rng.normal(0, 0.4))
    # machine smooth errors (um), cubic in the normalised position
    mc = rng.normal(0, 2.0, (4, 3))
    def E_lin(x, y):
        xs, ys = (x - 312.0) / 100.0, (y - 188.0) / 100.0
        ex = mc[0] @ [xs, xs**2, xs**3] + mc[2] @ [ys, ys**2, ys**3] * 0.5 + 3.0 * ys  # EXX + EXY (+ squareness)
        ey = mc[1] @ [xs, xs**2, xs**3] * 0.5 + mc[3] @ [ys, ys**2, ys**3]
        return np.array([ex, ey])
    # schedule: rows of (setup idx, target index)
    ns = len(C)
    plan = []
    for s in range(ns):
        sel = list(range(len(T)))
        if s == 1:
            sel = [i for i in sel if not T[i]["feature"] in ("hole2", "hole4")]
        if s == 3:
            sel = [i for i in sel if T[i]["feature"] not in ("bossE", "bossW")]
        order = sel[:]
        if s % 2 == 1:  # the shop probes the boss first in odd set-ups
            order = [i for i in sel if T[i]["feature"].startswith("boss")] + [i for i in sel if T[i]["feature"].startswith("hole")]
        rows = []
        dbl = set(rng.choice(order, 2, replace=False).tolist())
        for i in order:
            rows.append(i)
            if i in dbl:
                rows.append(i)
        rows.append(order[0])  # drift check
        plan.append(rows)
    # times
    t, times, srow, trow = 0.0, [], [], []
    setup_start = []
    for s, rows in enumerate(plan):
        t += rng.uniform(60, 400) if s else rng.uniform(5, 20)
        setup_start.append(t)
        for r, i in enumerate(rows):
            t += rng.uniform(4, 9)
            if s == 2 and r == len(rows) // 2:
                t += 900.0
            times.append(t); srow.append(s); trow.append(i)
    times, srow, trow = np.array(times), np.array(srow), np.array(trow)
    n = len(times)
    EXC = rng.normal(0, 3.0, (ns, 2)); ECC = rng.normal(0, 15e-6, ns)  # um, rad
    # geometry per row
    Cdeg = np.array([C[s] for s in srow])
    w = np.array([T[i]["w"] for i in trow]); wn = np.array([T[i]["wn"] for i in trow])
    cen = C_CENTRE
    R = np.array([rot(-c) for c in Cdeg])
    pc = np.einsum("kab,kb->ka", R, w) + cen  # contact, machine
    nn = np.einsum("kab,kb->ka", R, wn)
    z = np.array([T[i]["z"] for i in trow])
    rsty = 1.5
    pn = pc + rsty * nn
    # baseline-absorbable machine part
    El = np.array([E_lin(x, y) for x, y in pn])
    r90 = lambda v: np.column_stack([-v[:, 1], v[:, 0]])
    dq = np.array([g[T[i]["id"]] for i in trow]) - np.einsum("ka,ka->k", nn, El) - np.einsum("ka,ka->k", nn, EXC[srow]) \
        - ECC[srow] * 1e3 * np.einsum("ka,ka->k", r90(pn - cen), nn)  # ECC rad * mm -> um via 1e3
    # the one effect: the part clamped with a bow in set-ups 1-2 (its surface moves along W's y with the square of
    # x), relaxed when re-clamped: the feature's offset differs between set-ups
    before = srow <= 1
    dq_eff = before * (wn[:, 1] * bow_um * 4.0 * ((w[:, 0] / 55.0) ** 2 - 0.5))
    # noise: Student-t 4 dof (variance 2 at unit scale) + wandering offset (OU, 0.08 um RMS, 600 s)
    noise = rng.standard_t(4, n) * sigma / np.sqrt(2.0)
    ou = np.zeros(n); x = 0.0; last = 0.0
    for k2 in range(n):
        dt = times[k2] - last; last = times[k2]; a = np.exp(-dt / 600.0)
        x = a * x + np.sqrt(1 - a * a) * rng.normal(0, wander); ou[k2] = x
    dq_tot = dq + dq_eff + noise - ou
    meas = pn + (dq_tot * UM)[:, None] * nn + rng.normal(0, 0.5 * UM, (n, 1)) * r90(nn)
    cols = ["setup", "target", "feature", "t_s", "X_mm", "Y_mm", "Z_mm", "Xn_mm", "Yn_mm", "Zn_mm", "nx", "ny", "nz",
            "C_deg", "wx_mm", "wy_mm", "wz_mm", "wnx", "wny", "wnz"]
    lines = ["# format: probe-log/1", "# machine: review32c shop mill", "# artefact: boltcircle+boss",
             "# stylus_r_mm: 1.5", ",".join(cols)]
    for k2 in range(n):
        i = trow[k2]
        zz = z[k2]
        v = [f"S{srow[k2]+1}", T[i]["id"], T[i]["feature"], f"{times[k2]:.3f}", f"{meas[k2,0]:.5f}", f"{meas[k2,1]:.5f}",
             f"{zz + rng.normal(0, 0.0003):.5f}", f"{pn[k2,0]:.7f}", f"{pn[k2,1]:.7f}", f"{zz:.7f}", f"{nn[k2,0]:.7f}",
             f"{nn[k2,1]:.7f}", "0.0000000", f"{Cdeg[k2]:.3f}", f"{w[k2,0]:.7f}", f"{w[k2,1]:.7f}", f"{zz:.7f}",
             f"{wn[k2,0]:.7f}", f"{wn[k2,1]:.7f}", "0.0000000"]
        lines.append(",".join(v))
    return "\n".join(lines) + "\n", g
