"""Probing plans: the nominal touches of each artefact, in the artefact frame A.

A :class:`Plan` lists, in probing order, each target's id, feature, nominal
contact point ``w_A`` and outward normal ``wn_A`` (A frame). The approach is
along ``-n`` from ``clearance_m`` outside the nominal stylus-centre position
and searches ``overshoot_m`` past it. ``level`` groups touches that may be
linked by a direct move (same feature, same level); others are linked via
the safe height.

Counts (asserted in the tests):

- MFB (Viprey 2016, section 2.1): 8 per hole on two levels x 12 holes = 96,
  12 per rod in four sections x 11 rods = 132, 4 per face x 22 faces = 88;
  316 per placement.
- Cross pocket (Ibaraki section 4.2): 3 per end wall x 4 + 9 per side wall
  x 8 = 84 wall points 3 mm below the top, plus 4 equator points per
  sphere x 2 = 92 per C angle.
- Pin circle (section 5.1): 4 per pin x 18 + 8 per sphere x 2 = 88 per C
  angle, the spheres' eight on the equator 45 deg apart, as in case 1
  ("The points on the spheres are on their equator", 4.2), since the
  planar model (eqs 1-3) takes normals in XY (the paper writes "total 84",
  which its own counts do not give: 17 pins x 4 + 16 would).
- Free-form plate: 64 contour points + 4 equator points per sphere x 2 = 72.
"""

from __future__ import annotations

import operator
from dataclasses import dataclass, field, replace

import numpy as np

from core.exceptions import ConfigError
from core.memo import Memo

from . import artefacts as A
from core.units import MM


@dataclass(frozen=True)
class Plan:
    """Nominal touches of one artefact, A frame, SI units.

    Attributes
    ----------
    artefact : str
    target : tuple of str
        Target ids (unique; the same id is the same physical point in every set-up).
    feature : tuple of str
    w_A : (n,3) float
        Nominal contact points, m.
    wn_A : (n,3) float
        Nominal outward unit normals.
    level : (n,) float
        Link key: consecutive touches of one feature at one level move directly.
    clearance_m, overshoot_m : float
        Approach start outside the nominal stylus centre, search past it, m.
    """

    artefact: str
    target: tuple
    feature: tuple
    w_A: np.ndarray = field(compare=False)
    wn_A: np.ndarray = field(compare=False)
    level: np.ndarray = field(compare=False)
    clearance_m: float = 2.0 * MM
    overshoot_m: float = 1.0 * MM

    @property
    def n(self) -> int:
        return len(self.target)

    def select(self, rows) -> "Plan":
        """A plan with only ``rows`` (indices or bool mask), order kept."""
        idx = np.arange(self.n)[rows]
        ids = idx.tolist()  # (Python ints index the tuples faster than numpy's)
        if len(ids) > 1:  # (the tuples' items by one itemgetter: the same items, 156 rows 17 -> 4 us)
            get = operator.itemgetter(*ids)
            target, feature = get(self.target), get(self.feature)
        else:
            target, feature = tuple([self.target[i] for i in ids]), tuple([self.feature[i] for i in ids])
        # (rows gathered by take: the same values as indexing, a few times faster on (k,3) rows)
        return Plan(self.artefact, target, feature, self.w_A.take(idx, axis=0), self.wn_A.take(idx, axis=0),
                    self.level.take(idx, axis=0), self.clearance_m, self.overshoot_m)

    def counts(self) -> dict:
        """Touches per feature kind prefix (``hole``, ``rod``, ``face``, ...)."""
        out: dict = {}
        for f in self.feature:
            k = f.rstrip("0123456789").rstrip("LR") if f.startswith("face") else f.rstrip("0123456789")
            out[k] = out.get(k, 0) + 1
        return out


def _check_margins(clearance_m, overshoot_m) -> None:
    if not (clearance_m > 0 and overshoot_m > 0):
        raise ConfigError("clearance_m and overshoot_m must be positive")


class _Builder:
    def __init__(self):
        self.t, self.f, self.w, self.n, self.lv = [], [], [], [], []

    def add(self, target, feature, w, n, level=0.0):
        n = np.asarray(n, float)
        self.t.append(target)
        self.f.append(feature)
        self.w.append(np.asarray(w, float))
        self.n.append(n / np.linalg.norm(n))
        self.lv.append(float(level))

    def plan(self, artefact, clearance_m, overshoot_m) -> Plan:
        _check_margins(clearance_m, overshoot_m)
        if len(set(self.t)) != len(self.t):
            raise ConfigError(f"plan for {artefact!r} has duplicate target ids")
        return Plan(artefact, tuple(self.t), tuple(self.f), np.array(self.w), np.array(self.n),
                    np.array(self.lv), float(clearance_m), float(overshoot_m))


#: :func:`mfb_plan`'s plans by (artefact object, kept in the entry and checked with ``is``,
#: clearance, overshoot); their arrays are read-only. 64 plans (before: cleared at 64).
_MFB_PLANS = Memo(64)
#: :func:`mfb_plan`'s touches (targets, features, points, normals, levels) by artefact object:
#: they do not depend on the margins, so a bar's plans at other margins share them (read-only
#: arrays). 64 bars.
_MFB_TOUCHES = Memo(64)


def mfb_plan(art: A.Artefact, clearance_m=2.0 * MM, overshoot_m=1.0 * MM) -> Plan:
    """The MFB's 316 touches per placement, pattern by pattern (Viprey 2016, 2.1).

    Cached per (artefact object, clearance, overshoot): a collision check asks for the
    same bar's plan once per measurement. The touches are built once per artefact object
    and shared by its plans at every margin (the plans' making's 2 / 3 mm and a check's
    placement margins: 2.7 ms a build). The cached plan's arrays are read-only.
    """
    def touches():
        pl = _build_mfb_plan(art, 1.0, 1.0)  # the margins are set by each plan
        for x in (pl.w_A, pl.wn_A, pl.level):
            x.flags.writeable = False
        return pl

    def build():
        pl = _MFB_TOUCHES.get_or_compute(id(art), touches, owner=art)
        _check_margins(clearance_m, overshoot_m)
        return replace(pl, clearance_m=float(clearance_m), overshoot_m=float(overshoot_m))

    return _MFB_PLANS.get_or_compute((id(art), float(clearance_m), float(overshoot_m)), build, owner=art)


def _build_mfb_plan(art: A.Artefact, clearance_m, overshoot_m) -> Plan:
    b = _Builder()
    az = np.deg2rad([0.0, 90.0, 180.0, 270.0])
    n_holes = sum(1 for f in art.features if f.kind == "hole")
    for i in range(1, n_holes + 1):
        hole = art.feature(f"hole{i:02d}")
        c = np.asarray(hole.nominal.centre)
        R = hole.nominal.radius
        for lvl, z in (("u", 5.0 * MM), ("l", -5.0 * MM)):
            for k, a in enumerate(az):
                e = np.array([np.cos(a), np.sin(a), 0.0])
                b.add(f"hole{i:02d}_{lvl}{k}", hole.name, c + [0, 0, z] + R * e, -e, level=z)
        if i == n_holes:
            break
        rod = art.feature(f"rod{i:02d}")
        c = np.asarray(rod.nominal.centre)
        R = rod.nominal.radius
        for si, y in enumerate((-15.0 * MM, -7.5 * MM, 7.5 * MM, 15.0 * MM)):
            for k, a in enumerate(np.deg2rad([-45.0, 0.0, 45.0])):
                e = np.array([np.sin(a), 0.0, np.cos(a)])
                b.add(f"rod{i:02d}_s{si}_a{k}", rod.name, c + [0, y, 0] + R * e, e, level=1000 + si * 10 + k)
        for side in ("L", "R"):
            face = art.feature(f"face{side}{i:02d}")
            o = np.asarray(face.nominal.origin)
            nrm = np.asarray(face.nominal.normal_, float)
            for k, (dx, dz) in enumerate(((-8.0, -6.0), (8.0, -6.0), (8.0, 6.0), (-8.0, 6.0))):
                b.add(f"face{side}{i:02d}_p{k}", face.name, o + [dx * MM, 0, dz * MM], nrm, level=0.0)
    return b.plan(art.name, clearance_m, overshoot_m)


def _sphere_points(b, feat, elevations_deg=(0.0,), azimuths=((0, 90, 180, 270),), level=2000.0):
    c = np.asarray(feat.nominal.centre)
    R = feat.nominal.radius
    k = 0
    for el, azs in zip(elevations_deg, azimuths):
        for a in np.deg2rad(azs):
            e = np.array([np.cos(np.deg2rad(el)) * np.cos(a), np.cos(np.deg2rad(el)) * np.sin(a),
                          np.sin(np.deg2rad(el))])
            b.add(f"{feat.name}_p{k}", feat.name, c + R * e, e, level=level + k)
            k += 1


def cross_pocket_plan(art: A.Artefact, clearance_m=2.0 * MM, overshoot_m=1.0 * MM) -> Plan:
    """92 points per C angle: 84 on the pocket walls 3 mm below the top, 8 on the spheres."""
    b = _Builder()
    poly = A.cross_outline()
    z = A.CROSS_PROBE_Z_M
    m = len(poly)
    for k in range(m):
        a, c = poly[k], poly[(k + 1) % m]
        e = c - a
        L = np.linalg.norm(e)
        fr = (0.25, 0.5, 0.75) if L < 50 * MM else tuple((np.arange(9) + 0.5) / 9)
        nrm = np.array([-e[1], e[0], 0.0]) / L  # into the pocket (CCW outline, material outside)
        for j, f in enumerate(fr):
            p = a + f * e
            b.add(f"wall{k:02d}_{j}", "pocket", (p[0], p[1], z), nrm, level=k)
    for f in art.features:
        if f.kind == "sphere":
            _sphere_points(b, f)
    return b.plan(art.name, clearance_m, overshoot_m)


def pin_circle_plan(art: A.Artefact, clearance_m=2.0 * MM, overshoot_m=1.0 * MM) -> Plan:
    """4 points per pin at mid-height, 8 per sphere on its equator, 45 deg apart from +x (section 5.1)."""
    b = _Builder()
    for f in art.features:
        if f.kind == "rod":
            c = np.asarray(f.nominal.centre)
            for k, a in enumerate(np.deg2rad([0.0, 90.0, 180.0, 270.0])):
                e = np.array([np.cos(a), np.sin(a), 0.0])
                b.add(f"{f.name}_p{k}", f.name, (c[0], c[1], A.PIN_PROBE_Z_M) + f.nominal.radius * e, e,
                      level=k)  # around a pin: via the safe height
    for f in art.features:
        if f.kind == "sphere":
            _sphere_points(b, f, (0.0,), (tuple(range(0, 360, 45)),))
    return b.plan(art.name, clearance_m, overshoot_m)


def freeform_plan(art: A.Artefact, clearance_m=2.0 * MM, overshoot_m=1.0 * MM, n_contour: int = 64) -> Plan:
    """64 contour points (edge midpoints, 5 mm below the top) and 4 per sphere."""
    b = _Builder()
    poly = A.freeform_outline()
    m = len(poly)
    z = A.FREEFORM_PROBE_Z_M
    for j in range(n_contour):
        k = (int(round(j * m / n_contour)) + 7) % m
        a, c = poly[k], poly[(k + 1) % m]
        e = c - a
        nrm = np.array([e[1], -e[0], 0.0]) / np.linalg.norm(e)  # out of the boss
        p = 0.5 * (a + c)
        b.add(f"contour{j:02d}", "contour", (p[0], p[1], z), nrm, level=z)
    for f in art.features:
        if f.kind == "sphere":
            _sphere_points(b, f)
    return b.plan(art.name, clearance_m, overshoot_m)
