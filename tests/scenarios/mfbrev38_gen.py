"""An independent multi-feature-bar log generator (session 38, mfbrev38): numpy only, no vmt import.

Written from three texts, not from vmt's code:

- docs/formats.md, "A multi-feature bar's log" (the columns and lines the log must hold) and
  "Columns every file has" (a reading is where the machine believes the stylus-tip centre is; the nominal
  columns are a perfect machine's tip centre; the normal points out of the material towards the stylus);
- CONTRIBUTING.md, "Error conventions" (ISO 230-1: every error is the tool's displacement relative to the
  workpiece; the exact transform of an error motion is ``[exp(skew(EA, EB, EC)) | (EX, EY, EZ)]``; a linear
  axis's errors are functions of its axis position ``q = reading + J``);
- Viprey et al. 2016 (the MFB paper): the bar (12 holes and 11 rods at L = 50 mm, section 2.2 / eq. 3; holes
  2 and 5 shifted for mistake-proofing; 8 touches per hole on two levels, 12 per rod on four sections, 4 per
  face: 316 touches a placement, section 2.1 / 7), the point of interest ``O_i = AXIS_i ∩ PL_i`` with
  ``PL_i`` through ``P_L``, ``P_R`` of the rods around hole i, and eq. 8: the tool-relative-to-workpiece chain
  of a machine ``[w b X Y Z t]`` (X carries Y carries Z carries the probe)::

      T = Trans(X) E_X(X) . R0Y . Trans(Y) E_Y(Y) . R0Z . Trans(Z) E_Z(Z) . Trans(-J)

  with ``R0Y = exp(skew(0, 0, EC0Y))`` and ``R0Z = exp(skew(EA0Z, EB0Z, 0))`` (eq. 8's squareness matrices,
  before the axis's motion), X, Y, Z the joint parameters (reading + J).

Where the texts leave a choice, it is made here and said: the bar's own dimensions (hole radius, rod radius,
face positions, levels) are this generator's, only the pitch (50 mm), the shifted holes (2 and 5, +1.5 mm in
y) and the frame (origin on hole 1's axis in the plane of the rod axes, x along the bar, holes along z) are
the paper's; the end holes' plane ``PL_1``, ``PL_12`` goes through their two nearest rods (the paper's
``PL_i`` needs rods i-1 and i, which hole 1 and hole 12 do not both have).

The truth is in the ISO 230-1 gauge the docs state (README "the 21 errors per node, straightness against its
end-point line"; ``conventions`` in vmt's JSON): positioning zero at the first node, straightness zero at both
end nodes, angular errors zero at the first node; the three squarenesses are free constants. So the truth at
the nodes is what an identification must return, whichever of those conventions it fixes.
"""

from __future__ import annotations

import json

import numpy as np

MM = 1e-3
UM = 1e-6
URAD = 1e-6

# --- the bar (paper section 2.2, eq. 3; dimensions below are this generator's own) -------------------------
N_HOLES = 12
PITCH_MM = 50.0
SHIFTED = {2: 1.5, 5: 1.5}      # mistake-proofing: hole -> y shift, mm
HOLE_R_MM = 7.0                  # hole radius
HOLE_LEVELS_MM = (-3.0, -11.0)   # z of the two probed sections of a hole
ROD_R_MM = 4.0                   # rod radius (rod axes along y, in the plane z = 0)
ROD_SECTIONS_MM = (-13.0, -5.0, 5.0, 13.0)
ROD_ANGLES_DEG = (-50.0, 0.0, 50.0)   # from +z in the x-z plane
FACE_Y_MM = 18.0                 # faceL at y = -18 (normal -y), faceR at y = +18 (normal +y)
FACE_PTS_MM = ((-9.0, -7.0), (9.0, -7.0), (-9.0, 7.0), (9.0, 7.0))   # (dx from the rod, z)
STYLUS_R_MM = 2.0

ERRORS = ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX",
          "EXY", "EYY", "EZY", "EAY", "EBY", "ECY",
          "EXZ", "EYZ", "EZZ", "EAZ", "EBZ", "ECZ")
SQUARENESS = ("EC0Y", "EA0Z", "EB0Z")
#: ISO 230-1 kinds: the first letter after E is the direction, the last the axis.
KIND = {e: ("positioning" if e[1] == e[2] else "straightness" if e[1] in "XYZ" else "angular") for e in ERRORS}

#: the joint (reading + J) box the error tables span, mm, and the nodes (6 a side, 110 mm apart)
BOX_MM = (0.0, 550.0)
N_NODES = 6
NODES_MM = np.linspace(*BOX_MM, N_NODES)

STYLI_MM = {"T0": (0.0, 0.0, 150.0), "TX": (80.0, 0.0, 150.0), "TY": (0.0, 80.0, 150.0),
            "TL": (0.0, 0.0, 250.0)}


def skew(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def exp_so3(w):
    w = np.asarray(w, float)
    th = float(np.linalg.norm(w))
    K = skew(w)
    if th < 1e-12:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + np.sin(th) / th * K + (1.0 - np.cos(th)) / th ** 2 * K @ K


def exp_so3_batch(w):
    """Rodrigues for (n, 3) rotation vectors -> (n, 3, 3)."""
    th = np.linalg.norm(w, axis=1)
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
    small = th < 1e-6
    a = np.where(small, 1.0 - th ** 2 / 6.0, np.sin(th) / np.where(small, 1.0, th))
    b = np.where(small, 0.5 - th ** 2 / 24.0, (1.0 - np.cos(th)) / np.where(small, 1.0, th) ** 2)
    return np.eye(3) + a[:, None, None] * K + b[:, None, None] * (K @ K)


# --- the bar's nominal touches in its frame A ---------------------------------------------------------------
def hole_x_mm(i):
    return (i - 1) * PITCH_MM


def rod_x_mm(j):
    return (j - 0.5) * PITCH_MM


def bar_touches():
    """[(feature, target, w_A mm (3,), wn_A (3,))] of one placement: 12 x 8 + 11 x 12 + 22 x 4 = 316."""
    out = []
    for i in range(1, N_HOLES + 1):
        cx, cy = hole_x_mm(i), SHIFTED.get(i, 0.0)
        for lv, z in zip("ul", HOLE_LEVELS_MM):
            for k, th in enumerate(np.deg2rad([45.0, 135.0, 225.0, 315.0])):
                c, s = np.cos(th), np.sin(th)
                out.append((f"hole{i:02d}", f"hole{i:02d}_{lv}{k}", np.array([cx + HOLE_R_MM * c, cy + HOLE_R_MM * s, z]),
                            np.array([-c, -s, 0.0])))
    for j in range(1, N_HOLES):
        x = rod_x_mm(j)
        for a, y in enumerate(ROD_SECTIONS_MM):
            for k, ph in enumerate(np.deg2rad(ROD_ANGLES_DEG)):
                n = np.array([np.sin(ph), 0.0, np.cos(ph)])
                out.append((f"rod{j:02d}", f"rod{j:02d}_{a}{k}", np.array([x, y, 0.0]) + ROD_R_MM * n, n))
        for side, sy in (("L", -1.0), ("R", 1.0)):
            for k, (dx, z) in enumerate(FACE_PTS_MM):
                out.append((f"face{side}{j:02d}", f"face{side}{j:02d}_{k}", np.array([x + dx, sy * FACE_Y_MM, z]),
                            np.array([0.0, sy, 0.0])))
    return out


class TrueBar:
    """The real bar: hole axes moved in x, y; rods raised in z (all in A, mm). Its points of interest follow
    the paper's extraction: AXIS_i met with the plane through the rods around hole i."""

    def __init__(self, rng, sd_xy_um=3.0, sd_rod_um=1.5):
        self.dxy = rng.normal(0.0, sd_xy_um, (N_HOLES, 2)) * 1e-3   # mm
        self.h = rng.normal(0.0, sd_rod_um, N_HOLES - 1) * 1e-3      # mm

    @staticmethod
    def rod_pair(i):
        if 2 <= i <= N_HOLES - 1:
            return i - 1, i
        return (1, 2) if i == 1 else (N_HOLES - 2, N_HOLES - 1)

    def poi_mm(self):
        """(12, 3) true O_i in A, mm. The rods are parallel to y, so PL_i is z = the line through the two rod
        heights over x."""
        out = np.zeros((N_HOLES, 3))
        for i in range(1, N_HOLES + 1):
            a, b = self.rod_pair(i)
            xa, xb = rod_x_mm(a), rod_x_mm(b)
            x = hole_x_mm(i) + self.dxy[i - 1, 0]
            y = SHIFTED.get(i, 0.0) + self.dxy[i - 1, 1]
            z = self.h[a - 1] + (self.h[b - 1] - self.h[a - 1]) * (x - xa) / (xb - xa)
            out[i - 1] = (x, y, z)
        return out

    def certificate_um(self):
        """(12, 3) Exx, Eyx, Ezx, um: the true points less their nominal places, in the frame of O_1 and O_12
        (a rigid move of the whole bar changes nothing a placement does not absorb)."""
        O = self.poi_mm()
        nom = np.array([[hole_x_mm(i), SHIFTED.get(i, 0.0), 0.0] for i in range(1, N_HOLES + 1)])
        E = O - nom
        E = E - E[0]
        L = hole_x_mm(N_HOLES)
        ty, tz = E[-1, 1] / L, E[-1, 2] / L
        E[:, 1] -= ty * nom[:, 0]
        E[:, 2] -= tz * nom[:, 0]
        E[:, 0] += ty * nom[:, 1]   # the same small rotation acting on the shifted holes' y
        return E * 1e3

    def gap_mm(self, feature, a):
        """Signed distance (mm) of stylus centres ``a`` (n, 3, in A) from contact with ``feature``: > 0 off."""
        r = STYLUS_R_MM
        if feature.startswith("hole"):
            i = int(feature[4:])
            c = np.array([hole_x_mm(i), SHIFTED.get(i, 0.0)]) + self.dxy[i - 1]
            rho = np.hypot(a[:, 0] - c[0], a[:, 1] - c[1])
            return (HOLE_R_MM - r) - rho
        if feature.startswith("rod"):
            j = int(feature[3:])
            rho = np.hypot(a[:, 0] - rod_x_mm(j), a[:, 2] - self.h[j - 1])
            return rho - (ROD_R_MM + r)
        sy = -1.0 if feature[4] == "L" else 1.0
        return sy * a[:, 1] - FACE_Y_MM - r


# --- the machine (eq. 8, exact) ------------------------------------------------------------------------------
class Truth:
    """The 18 motion errors as functions of the joint position (mm -> m or rad) and 3 squarenesses (rad)."""

    def __init__(self, rng, shape="poly", scale=1.0):
        self.shape = shape
        self.c = {}
        for e in ERRORS:
            k = KIND[e]
            amp = {"positioning": 12.0, "straightness": 4.0, "angular": 25.0}[k] * scale
            self.c[e] = rng.uniform(-1.0, 1.0, 4) * amp
        self.sq = {s: v * scale for s, v in zip(SQUARENESS, rng.uniform(-40.0, 40.0, 3))}

    @classmethod
    def given(cls, funcs=None, sq=None):
        """A truth of given functions ``{error: f(q_mm) -> um or urad}`` (others 0) and squarenesses (urad)."""
        t = cls.__new__(cls)
        t.shape, t.c = "given", {}
        t.funcs = dict(funcs or {})
        t.sq = {s: float((sq or {}).get(s, 0.0)) for s in SQUARENESS}
        return t

    def value(self, e, q_mm):
        """e at joint positions q_mm: um (translations) or urad (angles)."""
        if self.shape == "given":
            f = self.funcs.get(e)
            return np.zeros(np.shape(q_mm)) if f is None else np.broadcast_to(f(np.asarray(q_mm, float)),
                                                                              np.shape(q_mm)).astype(float)
        u = (np.asarray(q_mm, float) - BOX_MM[0]) / (BOX_MM[1] - BOX_MM[0])
        c = self.c[e]
        k = KIND[e]
        if self.shape == "poly":
            if k == "straightness":
                return u * (1.0 - u) * (c[0] + c[1] * u) * 4.0
            return c[0] * u + c[1] * u ** 2 + c[2] * u ** 3
        # non-polynomial, smooth at the node spacing (wavelengths 1.4 to 2 spans) and in the same gauge
        if k == "straightness":
            return c[0] * np.sin(np.pi * u) + c[1] * np.sin(2.0 * np.pi * u) * 0.5 \
                + c[2] * (np.exp(u) - 1.0 - u * (np.e - 1.0))
        return c[0] * np.sin(2.0 * np.pi * u / 1.6) + c[1] * (1.0 - np.cos(2.0 * np.pi * u / 2.0)) * 0.5 \
            + c[2] * (np.exp(0.8 * u) - 1.0)

    def node_table(self):
        return {e: [float(v) for v in self.value(e, NODES_MM)] for e in ERRORS}

    def tip_mm(self, q_mm, J_mm):
        """Actual stylus-tip centres (n, 3), mm, at joint positions q_mm (n, 3) with offsets J (3,)."""
        q = np.asarray(q_mm, float)
        J = np.asarray(J_mm, float)
        R0Y = exp_so3([0.0, 0.0, self.sq["EC0Y"] * URAD])
        R0Z = exp_so3([self.sq["EA0Z"] * URAD, self.sq["EB0Z"] * URAD, 0.0])
        p = np.tile(-J, (len(q), 1))
        for ax, j, R0 in (("Z", 2, R0Z), ("Y", 1, R0Y), ("X", 0, None)):
            t = np.column_stack([self.value(f"E{d}{ax}", q[:, j]) for d in "XYZ"]) * 1e-3     # um -> mm
            w = np.column_stack([self.value(f"E{d}{ax}", q[:, j]) for d in "ABC"]) * URAD
            p = np.einsum("nij,nj->ni", exp_so3_batch(w), p) + t     # E = [exp(skew(EA, EB, EC)) | t]
            p[:, j] += q[:, j]                                       # Trans(q e) . E
            if R0 is not None:
                p = p @ R0.T                                         # the squareness, before the motion
        out = p
        return out


# --- placements ----------------------------------------------------------------------------------------------
def _R(xA, zA):
    xA, zA = np.asarray(xA, float), np.asarray(zA, float)
    xA, zA = xA / np.linalg.norm(xA), zA / np.linalg.norm(zA)
    return np.column_stack([xA, np.cross(zA, xA), zA])


def plan():
    """[(setup, R_WA, O_1's joint position with T0 (mm), styli)]: 4 bars along each axis at the corners of
    the box's cross-section, three face diagonals (squareness, paper fig. 14d), styli of several J."""
    X, Y, Z = np.eye(3)
    out = []
    for k, (a, b) in enumerate([(100, 100), (450, 100), (100, 450), (450, 450)]):
        out.append((f"X{k + 1}", _R(X, Z), (0.0, a, b), ("T0", "TY") + (("TL",) if k < 2 else ())))
        out.append((f"Y{k + 1}", _R(Y, Z), (a, 0.0, b), ("T0", "TX")))
        out.append((f"Z{k + 1}", _R(Z, X), (a, b, 0.0), ("T0", "TX", "TY")))
    d = 550.0 / np.sqrt(2.0)
    out.append(("DXY", _R(X + Y, Z), (80.0, 80.0, 275.0), ("T0",)))
    out.append(("DXZ", _R(X + Z, Z - X), (80.0, 275.0, 80.0), ("T0",)))
    out.append(("DYZ", _R(Y + Z, Z - Y), (275.0, 80.0, 80.0), ("T0",)))
    assert d < 400
    return out


def generate(seed, *, shape="poly", noise_um=0.0, cert_noise=False, place_um=40.0, place_urad=40.0,
             scale=1.0, cert_u_um=(0.2, 0.35, 0.35), effect=None, effect_size=1.0, truth=None,
             bar_sd_um=(3.0, 1.5), only=None, noise_seed=None,
             cert_seed=None):
    """One campaign: (rows, meta, truth dict). ``noise_um``: the probe's standard deviation (k = 1) along the
    approach; ``cert_noise``: the certificate differs from the real bar by a draw of its stated u.
    ``effect`` (discovery): None; ``"drift"`` (the X scale grows with time, a thermal drift between and within
    placements: ``effect_size * 10 ppm`` at the campaign's end, 0 at its start); ``"bending"`` (the bar sags
    between its supports along gravity's part across it (gravity the machine's -Z; a standing bar does not):
    ``effect_size * 3 um`` at mid length relative to the end holes, ``(1 - s^2)^2`` of s from -1 to 1 over the
    holes); ``"lobing"`` (stylus TX triggers late by ``effect_size * 1.0 um * cos(3 phi)``, TY by
    ``effect_size * 0.8 um * cos(2 phi)``, phi the approach's azimuth in the machine's XY plane).
    ``only``: the set-ups to write (names of :func:`plan`), default all; ``truth``: a :class:`Truth` (default
    drawn); ``noise_seed``: the probe noise's own generator (default the seed's): the same machine, bar and
    placements, other touches; ``cert_seed``: the certificate's draw's own generator (default the seed's)."""
    rng = np.random.default_rng(seed)
    rng_noise = rng if noise_seed is None else np.random.default_rng([noise_seed, 38])
    truth = truth if truth is not None else Truth(rng, shape, scale)
    bar = TrueBar(rng, *bar_sd_um)
    t_s, rows = 0.0, []
    touches = bar_touches()
    feats = [t[0] for t in touches]
    w_A = np.array([t[2] for t in touches])
    wn_A = np.array([t[3] for t in touches])
    c_A = w_A + STYLUS_R_MM * wn_A
    half = hole_x_mm(N_HOLES) / 2.0
    sag = effect_size * 3e-3 * (1.0 - ((w_A[:, 0] - half) / half) ** 2) ** 2 if effect == "bending" \
        else np.zeros(len(w_A))                         # mm, 0 at the end holes
    setups = [s for s in plan() if only is None or s[0] in only]
    n_meas = sum(len(s[3]) for s in setups)
    t_end = n_meas * len(touches) * 2.0
    for name, R, o_joint, styli in setups:
        J0 = np.array(STYLI_MM["T0"])
        p_nom = np.asarray(o_joint, float) - J0        # O_1's reading with T0: the pose's translation, mm
        v = rng.normal(0.0, place_um, 3) * 1e-3
        w = rng.normal(0.0, place_urad, 3) * URAD
        dR = exp_so3(w)                                 # placement error in A: A_true = A_nom . [dR | v]
        R_true, p_true = R @ dR, p_nom + R @ v
        g_A = R.T @ np.array([0.0, 0.0, -1.0])
        g_A = g_A - g_A[0] * np.eye(3)[0]               # gravity across the bar, in A (0 for a standing bar)
        sag_A = sag[:, None] * g_A[None, :]             # the surface moved down by the sag
        for st in styli:
            J = np.array(STYLI_MM[st])
            c_W = c_A @ R.T + p_nom                     # nominal tip centres (the log's Xn_mm..)
            n_W = wn_A @ R.T
            d_W = -n_W                                  # approach: against the normal
            s = np.zeros(len(c_W))
            for it in range(6):                         # secant/Newton on the trigger along the approach
                g = _gap(bar, truth, feats, c_W + s[:, None] * d_W, J, R_true, p_true, sag_A)
                g2 = _gap(bar, truth, feats, c_W + (s + 1e-4)[:, None] * d_W, J, R_true, p_true, sag_A)
                s = s - g * 1e-4 / (g2 - g)
            reading = c_W + s[:, None] * d_W
            if effect == "lobing" and st in ("TX", "TY"):
                phi = np.arctan2(d_W[:, 1], d_W[:, 0])
                lobe = 1.0e-3 * np.cos(3.0 * phi) if st == "TX" else 0.8e-3 * np.cos(2.0 * phi)
                reading = reading + (effect_size * lobe)[:, None] * d_W
            times = t_s + 2.0 * np.arange(1, len(c_W) + 1)
            if effect == "drift":
                reading[:, 0] -= effect_size * 10e-6 * (times / t_end) * (reading[:, 0] + J[0])
            if noise_um > 0:
                reading = reading + (rng_noise.normal(0.0, noise_um, len(c_W)) * 1e-3)[:, None] * d_W
            for k in range(len(c_W)):
                rows.append(dict(setup=name, target=touches[k][1], t_s=times[k], X_mm=reading[k, 0],
                                 Y_mm=reading[k, 1], Z_mm=reading[k, 2], Xn_mm=c_W[k, 0], Yn_mm=c_W[k, 1],
                                 Zn_mm=c_W[k, 2], nx=n_W[k, 0], ny=n_W[k, 1], nz=n_W[k, 2], feature=feats[k],
                                 wx_mm=w_A[k, 0], wy_mm=w_A[k, 1], wz_mm=w_A[k, 2], wnx=wn_A[k, 0],
                                 wny=wn_A[k, 1], wnz=wn_A[k, 2], stylus=st))
            t_s = times[-1]
    E_um = bar.certificate_um()
    u_um = np.tile(np.asarray(cert_u_um, float), (N_HOLES, 1))
    u_um[0] = 0.0                                       # O_1 is the frame's origin: 0 by definition
    if cert_noise:
        rng_cert = rng if cert_seed is None else np.random.default_rng([cert_seed, 3838])
        E_um = E_um + rng_cert.normal(0.0, 1.0, E_um.shape) * u_um
    meta = {"format": "probe-log/1", "artefact": "mfb", "machine": f"mfbrev38 generator seed {seed}",
            "kinematic_chain": "[w b X Y Z t]", "stylus_r_mm": repr(STYLUS_R_MM),
            "stylus_offsets_mm": "; ".join(f"{k}=" + ",".join(repr(x) for x in v) for k, v in STYLI_MM.items()),
            "error_table_nodes_mm": "; ".join(f"{a}=" + ",".join(repr(float(x)) for x in NODES_MM) for a in "XYZ"),
            "bar_calibration_E_um": ",".join(repr(float(x)) for x in E_um.ravel()),
            "bar_calibration_u_um": ",".join(repr(float(x)) for x in u_um.ravel()),
            "probe_repeatability_k2_um": repr(2.0 * noise_um) if noise_um > 0 else "0.25",
            "number_format": "shortest round-trip"}
    tr = {"errors_um_urad": truth.node_table(), "squareness_urad": dict(truth.sq),
          "nodes_mm": [float(x) for x in NODES_MM], "shape": shape, "noise_um": noise_um, "seed": seed,
          "effect": effect, "E_um": E_um.tolist(), "u_um": u_um.tolist()}
    return rows, meta, tr


def _gap(bar, truth, feats, reading, J, R_true, p_true, sag_A):
    tip = truth.tip_mm(reading + J, J)                 # where the stylus really is, W, mm
    a = (tip - p_true) @ R_true - sag_A                 # in the real bar's frame; a sagging bar's surface moved
    g = np.empty(len(a))
    for f in dict.fromkeys(feats):
        idx = [k for k, x in enumerate(feats) if x == f]
        g[idx] = bar.gap_mm(f, a[idx])
    return g


COLUMNS = ("setup", "target", "t_s", "X_mm", "Y_mm", "Z_mm", "Xn_mm", "Yn_mm", "Zn_mm", "nx", "ny", "nz",
           "feature", "wx_mm", "wy_mm", "wz_mm", "wnx", "wny", "wnz", "stylus")


def write_log(path, rows, meta, columns=COLUMNS):
    with open(path, "w", encoding="utf-8") as f:
        for k, v in meta.items():
            f.write(f"# {k}: {v}\n")
        f.write(",".join(columns) + "\n")
        for r in rows:
            f.write(",".join(repr(float(r[c])) if isinstance(r[c], (float, np.floating)) else str(r[c])
                             for c in columns) + "\n")


def write_certificate(path, tr):
    """``vmt-bar-calibration/1`` as README "Bar calibration file" describes it."""
    E = np.asarray(tr["E_um"], float)
    u = np.asarray(tr["u_um"], float)
    doc = {"format": "vmt-bar-calibration/1", "x_mm": [hole_x_mm(i) for i in range(1, N_HOLES + 1)],
           "E_um": E.tolist(), "u_um": u.tolist(), "U95_um": (2.0 * u).tolist(), "n_repeats": 5}
    with open(path, "w", encoding="utf-8") as f:
        json.dump(doc, f)


if __name__ == "__main__":   # pragma: no cover - a manual run
    import sys
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    rows, meta, tr = generate(seed, shape=sys.argv[3] if len(sys.argv) > 3 else "poly",
                              noise_um=float(sys.argv[4]) if len(sys.argv) > 4 else 0.0,
                              cert_noise=len(sys.argv) > 4 and float(sys.argv[4]) > 0)
    write_log(sys.argv[1], rows, meta)
    with open(sys.argv[1] + ".truth.json", "w") as f:
        json.dump(tr, f)
