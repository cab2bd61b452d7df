"""Blind generator C: a bored plate on a rotary table, written from the physics alone.

Issue 13 item 7 asks for generators "written independently of sim/'s code
path and of each other". This one was written in session 26 without reading
``sim/``, ``scenarios/blind/gen_a.py``, ``gen_b.py``, their tests or the
internals of ``core/discover.py`` and ``core/causes.py``: only the probe-log
format (``shared/spec/probe-log.md``, ``docs/formats.md``), the catalogue's
causes in words (``docs/discovery.md``, "Causes") and the scoring harness's
interface (``scenarios.hidden.blind_outcome``) were read. Its interface:
``generate(effect, seed) -> (log, Truth)`` and ``effects()``.

The part (artefact frame: origin at the centre of the plate's top face, mm)
---------------------------------------------------------------------------
A 220 x 160 x 15 mm plate, clamped on a rotary table (C), its top 40 mm above
the table's reference plane; every normal is horizontal (a planar campaign):

- ``edge``: the four outer faces, 18 touches 6 mm below the top;
- ``bore1`` .. ``bore6``: six 18 mm bores on a 124 mm pitch circle round the
  centre, six touches each (azimuths 15 deg + k 60 deg), 7 mm below the top;
- ``slot``: a 12 mm slot along y at x = 90 mm, its two walls (five touches
  each) and its two end arcs (one touch each), 5 mm below the top;
- ``boss``: a 36 mm boss standing 12 mm on the plate's centre, eight
  touches 6 mm above the top (the second probing height), probed first and
  again last in every set-up (the re-check gives repeats).

Its form (the truth ``workpiece_um``, per target, along the normal, um): the
edges' straightness (a quadratic and a half-wave along each face), each
bore's size error and roundness (2, 3 and 4 lobes), the slot's walls tapered
and bowed, the boss's three-lobed roundness: 0.5-2 um each.

The machine (the baseline's world)
----------------------------------
A three-axis mill, table on Y, rotary table C at the machine origin. Smooth
axis errors (X, Y scale, their quadratic and cubic terms, both
straightnesses, the squareness), a constant probe pre-travel, and a pose
error of the part in every set-up (translation of a few um, rotation of a
few urad: the table's indexing and clamping). The reading at the trigger is
``X = Xn + (g + n.d_part - p) n + e(X)``: the part's form ``g``, the part's
pose error ``d_part``, the pre-travel ``p`` and the scales' reading error
``e`` (reading minus true position), so ``dq = n . (X - Xn)``.

Timing: the probing approach at 120-400 mm/min (per feature), a 0.3 s dwell,
positioning at 2000 mm/min between touches, a lift to 15 mm above the top
between features, 2-7 minutes for each index of the table and its check.
Noise: 0.2-0.5 um (1 sigma) per campaign. Set-ups: four to six, at C angles
drawn as uneven gaps (25-110 deg) from a random start (not symmetric
patterns: self-calibration separates the part from the machine best with
uneven angles, Ibaraki et al.). A missed touch (``no_trigger``, logged without
a reading and tried again) happens in about a third of the campaigns.

Logged beside the spec's columns: ``temp_bed_C`` (a machine-bed sensor
following the shop's air, an HVAC cycle of 20-60 minutes, 0.3-1 K: not a clock) and
``feed_mm_per_min`` (the approach's feed, the feature's programmed feed
times the set-up's feed override).

Effects (every magnitude drawn per seed; the forms are this generator's own)
----------------------------------------------------------------------------
Catalogue:

- ``thermal_drift``: X and Y offsets and scales moving exponentially towards
  a plateau, ``1 - exp(-t / tau)``, tau 0.15-1.0 of the campaign, offsets 3-8 um,
  scales 2-8 um per 100 mm;
- ``c_drift``: the table's angle settling after every index,
  ``a (1 - exp(-(t - t_index) / tau))``, 30-90 urad, tau 40-250 s (a set-up lasts 3-4 minutes);
- ``temperature_expansion``: the X (or Y) scale and zero following the bed
  sensor (10-40 um/m/K, 1-4 um/K about 20 C);
- ``periodic_axis_error``: a ripple of X or Y with its second harmonic,
  period 5-14 mm;
- ``local_scale_defect``: a raised-cosine bump of X or Y, half-width
  4-10 mm, 1.5-5 um;
- ``probe_lobing``: pre-travel with 3 and 4 lobes of the approach azimuth
  (machine frame);
- ``reversal``: lost motion of X and/or Y, signed by the axis' last
  direction of motion (the path between touches is followed);
- ``nonrigid``: X's error depending on Y (x y and x^2 y) and Y's on X;
- ``part_change``: one feature (a bore shrinking and going oval as it cools,
  or the slot closing, or the boss growing) changing exponentially in time;
- ``outlier``: one to three touches on a chip or triggered early.

Outside the catalogue:

- ``clamp_creep``: three clamps denting the plate's rim, each index's
  re-tightening adding to the dent (growing with the set-up's number);
- ``speed_pretravel``: pre-travel proportional to the approach speed, with
  the feed override changed at every set-up (the same feature probed at
  another speed reads another size);
- ``travel_hysteresis``: an axis whose lost motion winds up with the
  distance travelled since its last reversal (a friction-loaded drive,
  Dahl's model): short approaches after a reversal show part of it;
- ``coolant_gradient``: the part warmed by coolant from one side: a uniform
  rise and a linear temperature gradient across it, both growing in time;
  the free plate's in-plane bending (``u = alpha a (x^2 - y^2, 2 x y) / 2``
  along the gradient).

Truth: ``acceptable_causes`` (what a metrologist accepts), ``noise_um``,
``targets`` and ``workpiece_um`` (the form at the campaign's first touch),
``workpiece_identifiable``, ``visible_sigmas`` (the generator's own figure:
the effect's RMS per affected touch over the noise, before any baseline),
``effect_dq_um`` (the effect alone, per log row: the harness takes its part
outside the baseline, ``scenarios.hidden.effect_outside_baseline``) and
``params`` (the drawn magnitudes).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.probelog import make_log

#: Catalogue effects (the name is the catalogue cause), then the ones outside it.
CATALOGUE = ("thermal_drift", "c_drift", "temperature_expansion", "periodic_axis_error", "local_scale_defect",
             "probe_lobing", "reversal", "nonrigid", "part_change", "outlier")
OUTSIDE = ("clamp_creep", "speed_pretravel", "travel_hysteresis", "coolant_gradient")
EFFECTS = ("none",) + CATALOGUE + OUTSIDE

#: What a metrologist would accept as the report's cause, per effect.
ACCEPTABLE = {
    "none": ("none",),
    "thermal_drift": ("thermal_drift",),
    "c_drift": ("c_drift",),
    # a machine scale following a temperature is a thermal drift of the machine too
    "temperature_expansion": ("temperature_expansion", "thermal_drift"),
    "periodic_axis_error": ("periodic_axis_error",),
    "local_scale_defect": ("local_scale_defect",),
    "probe_lobing": ("probe_lobing",),
    "reversal": ("reversal",),
    "nonrigid": ("nonrigid",),
    "part_change": ("part_change",),
    "outlier": ("outlier",),
    # the rim's form changes with the set-up: a change of the part
    "clamp_creep": ("unexplained", "part_change"),
    "speed_pretravel": ("unexplained",),
    # a lost motion, whatever its wind-up
    "travel_hysteresis": ("unexplained", "reversal"),
    # the part's uniform warming is a scale drift in any frame (isotropic
    # growth about the table's centre commutes with the table's turn); the
    # gradient's bending is a change of the part
    "coolant_gradient": ("unexplained", "part_change", "thermal_drift"),
}

STYLUS_R_MM = 2.0
TOP_Z_MM = 40.0            # the plate's top face above the machine's Z origin (table)
PLATE = (220.0, 160.0)     # x, y size, mm
BORE_R_MM, BORE_PITCH_R_MM = 9.0, 62.0
SLOT_X_MM, SLOT_HALF_W_MM, SLOT_HALF_L_MM = 90.0, 6.0, 45.0
BOSS_R_MM = 18.0
#: programmed approach feed (mm/min) and approach length (mm) per feature kind
FEED = {"edge": 400.0, "bore": 120.0, "slot": 200.0, "boss": 250.0}
APPROACH_MM = {"edge": 5.0, "bore": 1.5, "slot": 2.0, "boss": 4.0}
POSITIONING_MM_MIN = 2000.0
DWELL_S = 0.3
CLEAR_Z_MM = 15.0
ALPHA_PART = 11.5e-6        # steel, 1/K
UM = 1e-3                   # mm per um


def effects() -> tuple:
    """Every effect this generator hides (``none`` first)."""
    return EFFECTS


@dataclass
class Truth:
    """What was hidden in one campaign (see the module docstring)."""

    effect: str
    seed: int
    acceptable_causes: tuple
    noise_um: float
    targets: list
    workpiece_um: np.ndarray
    workpiece_identifiable: bool
    visible_sigmas: float
    effect_dq_um: np.ndarray
    c_angles_deg: tuple
    params: dict = field(default_factory=dict)


# ---------------------------------------------------------------------------
# the part
# ---------------------------------------------------------------------------
def _targets():
    """(name, feature, kind, w (3,), wn (3,)) of every target, artefact frame."""
    out = []
    hx, hy = PLATE[0] / 2, PLATE[1] / 2
    k = 0
    for y in (-55.0, -20.0, 20.0, 55.0):
        out.append((f"edgeXp{k}", "edge", "edge", (hx, y, -6.0), (1.0, 0.0, 0.0))); k += 1
    for x in (80.0, 40.0, 0.0, -40.0, -80.0):
        out.append((f"edgeYp{k}", "edge", "edge", (x, hy, -6.0), (0.0, 1.0, 0.0))); k += 1
    for y in (55.0, 20.0, -20.0, -55.0):
        out.append((f"edgeXm{k}", "edge", "edge", (-hx, y, -6.0), (-1.0, 0.0, 0.0))); k += 1
    for x in (-80.0, -40.0, 0.0, 40.0, 80.0):
        out.append((f"edgeYm{k}", "edge", "edge", (x, -hy, -6.0), (0.0, -1.0, 0.0))); k += 1
    for b in range(6):
        a = np.radians(60.0 * b)
        cx, cy = BORE_PITCH_R_MM * np.cos(a), BORE_PITCH_R_MM * np.sin(a)
        for j in range(6):
            t = np.radians(15.0 + 60.0 * j)
            out.append((f"bore{b + 1}_{j}", f"bore{b + 1}", "bore",
                        (cx + BORE_R_MM * np.cos(t), cy + BORE_R_MM * np.sin(t), -7.0),
                        (-np.cos(t), -np.sin(t), 0.0)))
    xs = SLOT_X_MM
    for j, y in enumerate((-30.0, -15.0, 0.0, 15.0, 30.0)):
        out.append((f"slotL{j}", "slot", "slot", (xs - SLOT_HALF_W_MM, y, -5.0), (1.0, 0.0, 0.0)))
    out.append(("slotN", "slot", "slot", (xs, SLOT_HALF_L_MM, -5.0), (0.0, -1.0, 0.0)))
    for j, y in enumerate((30.0, 15.0, 0.0, -15.0, -30.0)):
        out.append((f"slotR{j}", "slot", "slot", (xs + SLOT_HALF_W_MM, y, -5.0), (-1.0, 0.0, 0.0)))
    out.append(("slotS", "slot", "slot", (xs, -SLOT_HALF_L_MM, -5.0), (0.0, 1.0, 0.0)))
    boss = []
    for j in range(8):
        t = np.radians(22.5 + 45.0 * j)
        boss.append((f"boss{j}", "boss", "boss", (BOSS_R_MM * np.cos(t), BOSS_R_MM * np.sin(t), 6.0),
                     (np.cos(t), np.sin(t), 0.0)))
    return boss, out


def _form_um(rng, tg) -> dict:
    """The part's own form along each target's normal, um."""
    g = {}
    face = {}
    for name, feat, kind, w, wn in tg:
        if kind == "edge":
            key = name[:6]
            if key not in face:
                face[key] = rng.uniform(-1.0, 1.0, 3)
            q, h, ph = face[key]
            s = (w[1] if abs(wn[0]) > 0.5 else w[0]) / 100.0
            g[name] = 1.2 * q * (s ** 2 - 0.3) + 0.6 * h * np.sin(np.pi * s + 3 * ph)
    for b in range(6):
        size, a2, a3, a4 = rng.uniform(-1.5, 1.5), rng.uniform(0, 1.0), rng.uniform(0, 0.7), rng.uniform(0, 0.5)
        p2, p3, p4 = rng.uniform(0, 2 * np.pi, 3)
        for j in range(6):
            t = np.radians(15.0 + 60.0 * j)
            g[f"bore{b + 1}_{j}"] = size + a2 * np.cos(2 * t + p2) + a3 * np.cos(3 * t + p3) + a4 * np.cos(4 * t + p4)
    taper, bow = rng.uniform(-1.5, 1.5), rng.uniform(-1.0, 1.0)
    for name, feat, kind, w, wn in tg:
        if feat == "slot":
            s = w[1] / SLOT_HALF_L_MM
            g[name] = (taper * s + bow * (1 - 2 * s ** 2)) if name[4] in "LR" else rng.uniform(-0.8, 0.8)
    a3, p3, size = rng.uniform(0.3, 1.2), rng.uniform(0, 2 * np.pi), rng.uniform(-1.0, 1.0)
    for j in range(8):
        t = np.radians(22.5 + 45.0 * j)
        g[f"boss{j}"] = size + a3 * np.cos(3 * t + p3)
    return g


# ---------------------------------------------------------------------------
# the schedule: set-ups, touch order, path and time
# ---------------------------------------------------------------------------
def _rot(c_deg):
    """Machine position of an artefact point: the table turned by C (R(-C), the part turning with the table)."""
    c = np.radians(c_deg)
    return np.array([[np.cos(c), np.sin(c), 0.0], [-np.sin(c), np.cos(c), 0.0], [0.0, 0.0, 1.0]])


def _c_angles(rng) -> tuple:
    n = int(rng.integers(4, 7))
    while True:
        gaps = rng.uniform(25.0, 110.0, n - 1)
        if gaps.sum() <= 330.0:
            break
    start = float(rng.choice([0.0, rng.uniform(0.0, 90.0)]))
    return tuple(float(round(start + v, 1)) for v in np.concatenate([[0.0], np.cumsum(gaps)]))


def _schedule(rng, boss, tg, angles):
    """Rows in touch order with their nominal geometry, path and time."""
    rows = []
    t = 0.0
    # feature order per set-up: boss, then the features in an order that varies per set-up
    groups = {}
    for item in tg:
        groups.setdefault(item[1], []).append(item)
    names = list(groups)
    override = rng.uniform(0.6, 1.4, len(angles))
    pos = np.array([0.0, 0.0, TOP_Z_MM + CLEAR_Z_MM + 20.0])
    path_xy = [pos[:2]]
    for s, c in enumerate(angles):
        if s > 0:
            t += rng.uniform(120.0, 420.0)      # index the table, check, restart
        R = _rot(c)
        order = list(rng.permutation(names))
        seq = [("boss", boss)] + [(f, groups[f]) for f in order] + [("boss", boss)]
        miss = rng.random() < 0.35 / len(angles)
        for fi, (feat, items) in enumerate(seq):
            kind = items[0][2]
            # lift, move over the feature's first start point, plunge
            first = items[0]
            n0 = R @ np.array(first[4])
            p0 = R @ np.array(first[3]) + np.array([0, 0, TOP_Z_MM]) + STYLUS_R_MM * n0 + APPROACH_MM[kind] * n0
            lift = np.array([pos[0], pos[1], TOP_Z_MM + CLEAR_Z_MM])
            over = np.array([p0[0], p0[1], TOP_Z_MM + CLEAR_Z_MM])
            dist = abs(lift[2] - pos[2]) + np.linalg.norm(over - lift) + abs(p0[2] - over[2])
            t += dist / POSITIONING_MM_MIN * 60.0 + 0.5
            path_xy += [lift[:2], over[:2]]
            pos = p0
            for name, _, _, w, wn in items:
                n_m = R @ np.array(wn)
                xc = R @ np.array(w) + np.array([0, 0, TOP_Z_MM]) + STYLUS_R_MM * n_m   # tip centre at contact
                start = xc + APPROACH_MM[kind] * n_m
                # move to the approach start (along the part, inside the feature)
                t += np.linalg.norm(start - pos) / POSITIONING_MM_MIN * 60.0
                path_xy.append(start[:2])
                feed = FEED[kind] * override[s]
                tries = 2 if (miss and rng.random() < 0.08) else 1
                for k in range(tries):
                    t += APPROACH_MM[kind] / feed * 60.0
                    rows.append(dict(setup=f"S{s + 1}", target=name, feature=feat, kind=kind, s=s, C=c,
                                     t=t, w=np.array(w), wn=np.array(wn), xn=xc, n=n_m, path=list(path_xy),
                                     feed=feed, status="no_trigger" if k < tries - 1 else "ok"))
                    path_xy = [xc[:2]]
                    t += DWELL_S + APPROACH_MM[kind] / POSITIONING_MM_MIN * 60.0
                    if k < tries - 1:
                        miss = False
                        path_xy = [start[:2]]
                        t += 1.0
                pos = start
                path_xy.append(start[:2])
    return rows, override


def _lost_motion(rows, b_um, s0_mm):
    """Per row the X and Y reading error (um) of drives with lost motion ``b`` winding up over ``s0`` mm.

    Each axis' state follows Dahl's first-order law in the distance it
    travels: ``w -> sign(v) b / 2`` with ``dw/ds = (sign(v) b / 2 - w) / s0``;
    ``s0 = 0`` is a plain lost motion (the state jumps at every reversal).
    The path is the positioning moves between touches and each approach.
    """
    out = np.zeros((len(rows), 2))
    for ax in range(2):
        if b_um[ax] == 0:
            continue
        w = 0.0
        for i, r in enumerate(rows):
            pts = [np.asarray(p, float) for p in r["path"]] + [r["xn"][:2]]
            for a, b in zip(pts[:-1], pts[1:]):
                d = b[ax] - a[ax]
                if abs(d) < 1e-9:
                    continue
                goal = np.sign(d) * b_um[ax] / 2
                w = goal if s0_mm[ax] == 0 else goal + (w - goal) * np.exp(-abs(d) / s0_mm[ax])
            out[i, ax] = w
    return out


# ---------------------------------------------------------------------------
# the campaign
# ---------------------------------------------------------------------------
def generate(effect: str, seed: int, *, noise: bool = True, machine: str = "smooth"):
    """One campaign with ``effect`` hidden: ``(probe log, Truth)``.

    ``noise=False`` leaves the probing noise out; ``machine="affine"`` keeps
    only the axes' offsets, scales and squareness (errors any error map
    represents exactly), for a noise-free round trip.
    """
    if effect not in EFFECTS:
        raise ValueError(f"gen_c: unknown effect {effect!r} (one of {', '.join(EFFECTS)})")
    if machine not in ("smooth", "affine"):
        raise ValueError(f"gen_c: machine must be 'smooth' or 'affine', not {machine!r}")
    seed = int(seed)
    rng = np.random.default_rng([seed, 26, 3])            # part, schedule, machine, noise: shared by every effect
    erng = np.random.default_rng([seed, 26, 4, EFFECTS.index(effect)])   # the effect's own draws
    boss, tg = _targets()
    g = _form_um(rng, boss + tg)
    angles = _c_angles(rng)
    rows, override = _schedule(rng, boss, tg, angles)
    n = len(rows)
    T = np.array([r["t"] for r in rows])
    dur = float(T[-1])
    S = np.array([r["s"] for r in rows])
    X = np.array([r["xn"] for r in rows])             # nominal tip centre, machine frame, mm
    N = np.array([r["n"] for r in rows])
    W = np.array([r["w"] for r in rows])
    WN = np.array([r["wn"] for r in rows])
    x, y = X[:, 0], X[:, 1]
    sigma = float(rng.uniform(0.2, 0.5))
    # machine: reading error e (um) of the scales, smooth in each axis
    L = 100.0
    ex = rng.uniform(-4, 4) + rng.uniform(-6, 6) * x / L
    ey = rng.uniform(-4, 4) + rng.uniform(-6, 6) * y / L + rng.uniform(-5, 5) * x / L   # squareness
    if machine == "smooth":
        ex = ex + rng.uniform(-2, 2) * (x / L) ** 2 + rng.uniform(-1, 1) * (x / L) ** 3 + rng.uniform(-2, 2) * (y / L) ** 2
        ey = ey + rng.uniform(-2, 2) * (y / L) ** 2 + rng.uniform(-1, 1) * (y / L) ** 3 + rng.uniform(-2, 2) * (x / L) ** 2
    else:
        rng.uniform(size=6)                           # same draws after this point either way
    pre = rng.uniform(0.5, 2.0)                       # probe pre-travel, um
    pose = np.column_stack([rng.uniform(-3, 3, len(angles)), rng.uniform(-3, 3, len(angles)),
                            rng.uniform(-8e-6, 8e-6, len(angles))])       # dx, dy um, rotation rad
    # bed temperature: the shop's air through the machine's mass (HVAC cycle)
    per = rng.uniform(1200.0, 3600.0)
    temp = 20.4 + rng.uniform(0.3, 1.0) * np.sin(2 * np.pi * T / per + rng.uniform(0, 2 * np.pi)) \
        + rng.uniform(-0.3, 0.3) * T / max(dur, 1.0) + rng.normal(0, 0.01, n)
    eps = rng.normal(0.0, sigma, n) if noise else np.zeros(n)
    gv = np.array([g[r["target"]] for r in rows])
    d_pose = pose[S, 0] * N[:, 0] + pose[S, 1] * N[:, 1] + pose[S, 2] * 1e3 * (x * N[:, 1] - y * N[:, 0])
    base = gv + d_pose - pre + ex * N[:, 0] + ey * N[:, 1]
    e_vec = np.zeros((n, 2))                           # the effect's reading error (um), machine frame
    e_n = np.zeros(n)                                  # the effect along the normal (um), part or probe
    params: dict = {}
    u = erng.uniform
    ts = np.array([T[S == s].min() for s in range(len(angles))])[S]   # each row's set-up start
    if effect == "thermal_drift":
        tau = u(0.15, 1.0) * dur
        h = 1.0 - np.exp(-T / tau)
        o = u(3.0, 8.0, 2) * erng.choice([-1, 1], 2)
        sc = u(2.0, 8.0, 2) * erng.choice([-1, 1], 2)
        e_vec[:, 0] = (o[0] + sc[0] * x / L) * h
        e_vec[:, 1] = (o[1] + sc[1] * y / L) * h
        params = {"tau_s": tau, "offset_um": o.tolist(), "scale_um_per_100mm": sc.tolist()}
    elif effect == "c_drift":
        a, tau = u(30e-6, 90e-6) * erng.choice([-1, 1]), u(40.0, 250.0)
        th = a * (1 - np.exp(-(T - ts) / tau))
        e_n = th * 1e3 * (x * N[:, 1] - y * N[:, 0])
        params = {"urad": a * 1e6, "tau_s": tau}
    elif effect == "temperature_expansion":
        ax = int(erng.integers(0, 2))
        k, z0 = u(10.0, 40.0) * erng.choice([-1, 1]), u(1.0, 4.0) * erng.choice([-1, 1])
        e_vec[:, ax] = (k * X[:, ax] * 1e-3 + z0) * (temp - 20.0)
        params = {"axis": "XY"[ax], "um_per_m_K": k, "um_per_K": z0}
    elif effect == "periodic_axis_error":
        ax = int(erng.integers(0, 2))
        P, a1 = u(5.0, 14.0), u(0.5, 1.6)
        a2 = a1 * u(0.2, 0.5)
        p1, p2 = u(0, 2 * np.pi, 2)
        e_vec[:, ax] = a1 * np.sin(2 * np.pi * X[:, ax] / P + p1) + a2 * np.sin(4 * np.pi * X[:, ax] / P + p2)
        params = {"axis": "XY"[ax], "period_mm": P, "amplitudes_um": [a1, a2]}
    elif effect == "local_scale_defect":
        ax = int(erng.integers(0, 2))
        hw, A = u(4.0, 10.0), u(1.5, 5.0) * erng.choice([-1, 1])
        v = X[:, ax]
        c = u(np.quantile(v, 0.1), np.quantile(v, 0.9))
        z = np.abs(v - c) / hw
        e_vec[:, ax] = np.where(z < 1, A * np.cos(np.pi * z / 2) ** 2, 0.0)
        params = {"axis": "XY"[ax], "centre_mm": c, "half_width_mm": hw, "amplitude_um": A}
    elif effect == "probe_lobing":
        a3, a4 = u(0.4, 1.5, 2)
        p3, p4 = u(0, 2 * np.pi, 2)
        phi = np.arctan2(-N[:, 1], -N[:, 0])            # azimuth of the approach (against the normal)
        e_n = -(a3 * np.cos(3 * phi + p3) + a4 * np.cos(4 * phi + p4))
        params = {"k3_um": a3, "k4_um": a4}
    elif effect in ("reversal", "travel_hysteresis"):
        which = int(erng.integers(0, 3))                # X, Y or both
        b = u(2.0, 6.0, 2) * erng.choice([-1, 1], 2) * np.array([which != 1, which != 0])
        s0 = np.zeros(2) if effect == "reversal" else u(2.0, 8.0, 2)
        e_vec = _lost_motion(rows, b, s0)
        params = {"lost_motion_um": b.tolist(), "windup_mm": s0.tolist()}
    elif effect == "nonrigid":
        a, bb, c = u(1.5, 5.0, 3) * erng.choice([-1, 1], 3)
        e_vec[:, 0] = a * (x / L) * (y / L) + bb * (x / L) ** 2 * (y / L)
        e_vec[:, 1] = c * (x / L) * (y / L)
        params = {"xy_um": a, "x2y_um": bb, "yx_um": c}
    elif effect == "part_change":
        feat = str(erng.choice(["bore1", "bore2", "bore3", "bore4", "bore5", "bore6", "slot", "boss"]))
        A, ov, tau = u(1.5, 4.0), u(0.0, 2.0), u(0.2, 1.0) * dur
        psi = u(0, np.pi)
        on = np.array([r["feature"] == feat for r in rows])
        h = 1 - np.exp(-T / tau)
        az = np.arctan2(-WN[:, 1], -WN[:, 0])          # the bore's azimuth of the touch (normal points inwards)
        if feat.startswith("bore"):
            e_n = on * h * (A + ov * np.cos(2 * (az - psi)))     # shrinking towards its centre: along n
        elif feat == "slot":
            e_n = on * h * A                              # both walls and ends closing in
        else:
            e_n = on * h * (A + ov * np.cos(2 * (az - psi)))     # the boss growing outwards: along n
        params = {"feature": feat, "um": A, "oval_um": ov, "tau_s": tau}
    elif effect == "outlier":
        k = int(erng.integers(1, 4))
        ok = np.flatnonzero([r["status"] == "ok" for r in rows])
        idx = erng.choice(ok, k, replace=False)
        mag = u(4.0, 20.0, k) * np.where(erng.random(k) < 0.7, 1.0, -1.0)
        e_n[idx] = mag
        params = {"rows": idx.tolist(), "um": mag.tolist()}
    elif effect == "clamp_creep":
        hx, hy = PLATE[0] / 2, PLATE[1] / 2
        clamps = [((-hx, 0.0), (1.0, 0.0)), ((hx * 0.3, hy), (0.0, -1.0)), ((hx * 0.3, -hy), (0.0, 1.0))]
        sp = u(25.0, 45.0)
        A = u(0.5, 1.5, 3)
        uu = np.zeros((n, 2))
        for (cw, push), a in zip(clamps, A):
            d2 = (W[:, 0] - cw[0]) ** 2 + (W[:, 1] - cw[1]) ** 2
            uu += a * S[:, None] * np.exp(-d2 / (2 * sp ** 2))[:, None] * np.array(push)
        e_n = uu[:, 0] * WN[:, 0] + uu[:, 1] * WN[:, 1]
        params = {"um_per_setup": A.tolist(), "spread_mm": sp}
    elif effect == "speed_pretravel":
        k = u(0.006, 0.02)                             # um of pre-travel per mm/min
        f = np.array([r["feed"] for r in rows])
        e_n = -k * (f - f.mean())
        params = {"um_per_mm_min": k, "override": override.tolist()}
    elif effect == "coolant_gradient":
        tau, dT, grad = u(0.2, 1.0) * dur, u(1.0, 4.0), u(0.02, 0.06)    # K, K/mm across the part
        psi = u(0, 2 * np.pi)
        h = 1 - np.exp(-T / tau)
        c, s_ = np.cos(psi), np.sin(psi)
        xp, yp = c * W[:, 0] + s_ * W[:, 1], -s_ * W[:, 0] + c * W[:, 1]
        ux = ALPHA_PART * (dT * xp + grad * (xp ** 2 - yp ** 2) / 2) * 1e3      # mm -> um
        uy = ALPHA_PART * (dT * yp + grad * xp * yp) * 1e3
        uxw, uyw = c * ux - s_ * uy, s_ * ux + c * uy
        e_n = h * (uxw * WN[:, 0] + uyw * WN[:, 1])       # material moving out along n: read farther out
        params = {"uniform_K": dT, "gradient_K_per_mm": grad, "direction_deg": np.degrees(psi), "tau_s": tau}
    eff = e_n + e_vec[:, 0] * N[:, 0] + e_vec[:, 1] * N[:, 1]
    okr = np.array([r["status"] == "ok" for r in rows])
    eff = np.where(okr, eff, 0.0)
    dq = base + eff + eps
    # the reading: along the normal as dq says, the scales' tangential error beside it
    tang = np.column_stack([ex + e_vec[:, 0], ey + e_vec[:, 1], np.zeros(n)])
    tang -= np.einsum("ij,ij->i", tang, N)[:, None] * N
    read = X + (dq[:, None] * N + tang) * UM
    cols = {
        "setup": [r["setup"] for r in rows], "target": [r["target"] for r in rows],
        "t_s": T, "X_mm": np.where(okr, read[:, 0], np.nan), "Y_mm": np.where(okr, read[:, 1], np.nan),
        "Z_mm": np.where(okr, read[:, 2], np.nan),
        "Xn_mm": X[:, 0], "Yn_mm": X[:, 1], "Zn_mm": X[:, 2], "nx": N[:, 0], "ny": N[:, 1], "nz": N[:, 2],
        "feature": [r["feature"] for r in rows], "C_deg": [r["C"] for r in rows],
        "dx": -N[:, 0], "dy": -N[:, 1], "dz": -N[:, 2],
        "wx_mm": W[:, 0], "wy_mm": W[:, 1], "wz_mm": W[:, 2], "wnx": WN[:, 0], "wny": WN[:, 1], "wnz": WN[:, 2],
        "temp_bed_C": np.round(temp, 3), "feed_mm_per_min": [round(r["feed"], 1) for r in rows],
        "status": [r["status"] for r in rows],
    }
    meta = {"machine": "gen_c: three-axis mill, rotary table C at the origin", "artefact": "bored plate",
            "stylus_r_mm": STYLUS_R_MM, "kinematic_chain": "V[w-C-A-b-Y-X-Z-(C)-t]"}
    log = make_log(cols, meta)
    targets = [t[0] for t in boss + tg]
    on = np.abs(eff) >= 0.1 * np.max(np.abs(eff)) if np.any(eff) else np.zeros(n, bool)
    vis = float(np.sqrt(np.mean(eff[on] ** 2)) / sigma) if on.any() else 0.0
    truth = Truth(effect, seed, ACCEPTABLE[effect], sigma, targets, np.array([g[k] for k in targets]),
                  len(angles) >= 4, vis, eff, angles, params)
    return log, truth
