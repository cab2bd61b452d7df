"""Artefacts: exact primitives, their form deviations, and the four test pieces.

Every surface a touch can hit is an *exact* primitive with a vectorised
signed distance (positive outside the material, metres), the closest point
on its nominal surface and the outward normal there (pointing out of the
material, towards the stylus):

- :class:`Plane`    a face: the half-space below a plane, optionally limited
  to a rectangle (then the semi-infinite prism under it, exact too);
- :class:`Sphere`   a precision sphere;
- :class:`Rod`      an outer cylinder (material inside), finite or infinite;
- :class:`Hole`     an inner cylinder (material outside the radius);
- :class:`Prism`    a straight prism over a 2-D polygon, the material inside
  (a boss, the free-form plate) or outside (a pocket, the cross). Its
  distance is exact, concave corners included (min over the edges).

A primitive carries a ``form`` error: a function of the nominal closest
point giving how far the *true* surface is displaced along the outward
normal (m, positive = material added). The true signed distance is
``d_nominal(p) - form(q(p))`` with ``q(p)`` the nominal closest point: the
zero level set is exactly the displaced surface ``q + form(q) n(q)``; the
distance to it away from the surface is exact to second order in the slope
of the form error (``r |grad form|^2 / 2``: below 2 nm for the defaults).

An :class:`Artefact` is a set of :class:`Feature` (nominal and true
primitive of each probed surface), convex :class:`Solid` pieces for the
MuJoCo scene and the display meshes, and a default placement ``T_W_A``
(pose of the artefact frame A in the table frame W).

Chosen geometry (documented choices where the papers leave it open):

MFB (Viprey 2016, section 2): 12 vertical holes of 16 mm diameter at pitch
L = 50 mm along x_A in webs 30 x 40 x 20 mm, 11 horizontal rods of 10 mm
diameter along y_A at x = (j - 1/2) L between two rails whose outer faces
(y_A = +-30 mm) are the flat faces PL_L / PL_R (webs 24 mm long in x_A leave
26 mm windows to reach the rods); bar length 580 mm
(x_A from -15 to 565 mm), supports 0.5537 L_bar = 321.1 mm apart. Holes 2
and 5 are shifted +1.5 mm in y_A (mistake-proofing: a reversed bar reads
differently). A = R_MFB: origin on hole 1's axis in the plane of the rod
axes. The true bar: holes displaced by (Exx, Eyx), rods by Ezx (at their
x), so the points of interest O_i move by eq. 4; Invar 1 um/m/degC.

Cross pocket (Ibaraki, section 4.2): arms 36 mm wide, 10 mm deep, each arm
200 mm long (wall contact points within 102 mm of the centre, so every
probed point stays inside the +-110 mm grid at any C angle when the part is
centred on the C axis); plate 240 x 240 x 30 mm; walls probed 3 mm below the
top; two 25.4 mm spheres on 10 mm stems at (60, 60) and (-70, -55) mm.
True wall form: 2 um waviness of 40 mm wavelength plus a 3 um local bump on
the +x end wall.

Pin circle (section 5): 18 pins of 12 mm diameter, 20 mm tall, on a
400 mm pitch circle every 20 deg, pin 6 shifted -10 mm in X as the paper's
Fig. 15 note says; two 30 mm spheres at (0, 60) and (50, -80) mm; true pin
positions off by a few um.

Free-form plate (the paper's future work): a convex, point-asymmetric boss
r(t) = 90 + 5 cos 2t + 3 sin 3t + cos 5t mm, 15 mm tall, as a 1440-gon
(the polygon *is* the nominal geometry), on a base plate; two 25.4 mm
spheres; true form: 1.5 um seven-lobe waviness plus a 2.5 um bump.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from core.exceptions import ConfigError
from core.units import MM, UM


Form = Callable[[np.ndarray], np.ndarray]


# ---------------------------------------------------------------------------
# small frame helpers


def rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], float)


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]], float)


def rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], float)


def make_T(R: np.ndarray | None = None, p=(0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4 homogeneous transform from a rotation and a translation (m)."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = p
    return T


def apply_T(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Apply one (4,4) or a batch (n,4,4) of transforms to points (n,3)."""
    p = np.asarray(p, float)
    if T.ndim == 2:
        return p @ T[:3, :3].T + T[:3, 3]
    return np.einsum("nij,nj->ni", T[:, :3, :3], p) + T[:, :3, 3]


def apply_R(T: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors (n,3) by the rotation part of (4,4) or (n,4,4)."""
    v = np.asarray(v, float)
    if T.ndim == 2:
        return v @ T[:3, :3].T
    return np.einsum("nij,nj->ni", T[:, :3, :3], v)


def inv_T(T: np.ndarray) -> np.ndarray:
    """Inverse of one (4,4) or a batch (n,4,4) of rigid transforms."""
    Ti = np.zeros_like(T)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    Ti[..., :3, :3] = Rt
    Ti[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3])
    Ti[..., 3, 3] = 1.0
    return Ti


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n == 0:
        raise ConfigError(f"direction {v.tolist()} has no length")
    return v / n


def _perp(a: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to unit ``a``."""
    e = np.array([1.0, 0, 0]) if abs(a[0]) < 0.9 else np.array([0, 1.0, 0])
    u = e - a * (e @ a)
    return u / np.linalg.norm(u)


# ---------------------------------------------------------------------------
# form errors (functions of the nominal closest point, A frame, m -> m)


@dataclass(frozen=True)
class Waviness:
    """``amplitude * sin(2 pi (k . q) / wavelength + phase)``: a smooth waviness.

    ``direction`` (A frame) is the direction along which it waves.
    """

    amplitude_m: float
    wavelength_m: float
    direction: tuple = (1.0, 1.0, 0.0)
    phase_rad: float = 0.0

    def __call__(self, q: np.ndarray) -> np.ndarray:
        k = _unit(self.direction)
        return self.amplitude_m * np.sin(2 * np.pi * (q @ k) / self.wavelength_m + self.phase_rad)


@dataclass(frozen=True)
class AngularWaviness:
    """``amplitude * sin(lobes * atan2(y, x) + phase)`` about the A-frame z axis."""

    amplitude_m: float
    lobes: int
    phase_rad: float = 0.0

    def __call__(self, q: np.ndarray) -> np.ndarray:
        return self.amplitude_m * np.sin(self.lobes * np.arctan2(q[:, 1], q[:, 0]) + self.phase_rad)


@dataclass(frozen=True)
class Bump:
    """A local Gaussian bump ``amplitude * exp(-|q - centre|^2 / (2 sigma^2))``."""

    amplitude_m: float
    centre_m: tuple
    sigma_m: float

    def __call__(self, q: np.ndarray) -> np.ndarray:
        d2 = np.sum((q - np.asarray(self.centre_m, float)) ** 2, axis=1)
        return self.amplitude_m * np.exp(-0.5 * d2 / self.sigma_m ** 2)


@dataclass(frozen=True)
class Offset:
    """A uniform displacement of the whole surface along its normal (m)."""

    offset_m: float

    def __call__(self, q: np.ndarray) -> np.ndarray:
        return np.full(len(q), float(self.offset_m))


@dataclass(frozen=True)
class FormSum:
    """The sum of several form errors."""

    parts: tuple

    def __call__(self, q: np.ndarray) -> np.ndarray:
        out = np.zeros(len(q))
        for f in self.parts:
            out = out + f(q)
        return out


# ---------------------------------------------------------------------------
# primitives (A frame, metres)


class _Primitive:
    """Common part: ``sdf`` (with the form error), ``normal``, ``closest``."""

    form: Form | None

    def _nominal(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(signed distance (n,), closest point (n,3), outward normal (n,3))."""
        raise NotImplementedError

    def sdf(self, p: np.ndarray) -> np.ndarray:
        """(n,) signed distance of points ``p`` (n,3, A frame, m) to the true surface."""
        p = np.atleast_2d(np.asarray(p, float))
        d, q, _ = self._nominal(p)
        if self.form is not None:
            d = d - self.form(q)
        return d

    def closest(self, p: np.ndarray) -> np.ndarray:
        """(n,3) closest point on the nominal surface, A frame, m."""
        return self._nominal(np.atleast_2d(np.asarray(p, float)))[1]

    def normal(self, p: np.ndarray) -> np.ndarray:
        """(n,3) outward unit normal of the nominal surface at the closest point."""
        return self._nominal(np.atleast_2d(np.asarray(p, float)))[2]

    def moved(self, dp) -> "_Primitive":
        """The same primitive translated by ``dp`` (3,), m."""
        raise NotImplementedError

    def scaled(self, s: float) -> "_Primitive":
        """Positions scaled by ``s`` about the A origin (thermal expansion)."""
        raise NotImplementedError


@dataclass(frozen=True)
class Plane(_Primitive):
    """A face: material below the plane through ``origin`` with outward ``normal``.

    With finite half-extents ``half_u`` (along ``u``) and ``half_v`` (along
    ``n x u``), the material is the semi-infinite prism under that rectangle;
    the distance is then exact to the prism (edges and corners included).
    """

    origin: tuple
    normal_: tuple
    u: tuple = (1.0, 0.0, 0.0)
    half_u: float = np.inf
    half_v: float = np.inf
    form: Form | None = None

    def _nominal(self, p):
        o = np.asarray(self.origin, float)
        n = _unit(self.normal_)
        u = np.asarray(self.u, float)
        u = u - n * (u @ n)
        u = _unit(u) if np.linalg.norm(u) > 1e-9 else _perp(n)
        v = np.cross(n, u)
        r = p - o
        h = r @ n
        a, b = r @ u, r @ v
        ca = np.clip(a, -self.half_u, self.half_u)
        cb = np.clip(b, -self.half_v, self.half_v)
        ea, eb = a - ca, b - cb
        lateral = np.hypot(ea, eb)
        d = np.where(lateral > 0, np.hypot(lateral, np.maximum(h, 0.0)), h)
        q = o + ca[:, None] * u + cb[:, None] * v
        nn = np.broadcast_to(n, p.shape).copy()
        return d, q, nn

    def moved(self, dp):
        return replace(self, origin=tuple(np.asarray(self.origin) + dp))

    def scaled(self, s):
        return replace(self, origin=tuple(np.asarray(self.origin) * s))


@dataclass(frozen=True)
class Sphere(_Primitive):
    """A sphere of centre ``centre`` (m) and radius ``radius`` (m), material inside."""

    centre: tuple
    radius: float
    form: Form | None = None

    def _nominal(self, p):
        r = p - np.asarray(self.centre, float)
        rho = np.linalg.norm(r, axis=1)
        safe = np.where(rho > 0, rho, 1.0)
        n = np.where(rho[:, None] > 0, r / safe[:, None], np.array([0, 0, 1.0]))
        return rho - self.radius, np.asarray(self.centre) + self.radius * n, n

    def moved(self, dp):
        return replace(self, centre=tuple(np.asarray(self.centre) + dp))

    def scaled(self, s):
        return replace(self, centre=tuple(np.asarray(self.centre) * s))


@dataclass(frozen=True)
class Rod(_Primitive):
    """An outer cylinder: axis through ``centre`` along ``axis``, radius ``radius``.

    ``half_length`` (m) limits it (flat end caps, exact distance), ``inf``
    for an infinite rod.
    """

    centre: tuple
    axis: tuple
    radius: float
    half_length: float = np.inf
    form: Form | None = None

    def _nominal(self, p):
        c = np.asarray(self.centre, float)
        a = _unit(self.axis)
        r = p - c
        t = r @ a
        radial = r - t[:, None] * a
        rho = np.linalg.norm(radial, axis=1)
        e = np.where(rho[:, None] > 0, radial / np.where(rho > 0, rho, 1.0)[:, None], _perp(a))
        dr = rho - self.radius
        dz = np.abs(t) - self.half_length
        outside = np.hypot(np.maximum(dr, 0), np.maximum(dz, 0))
        d = np.where((dr > 0) | (dz > 0), outside, np.maximum(dr, dz))
        tc = np.clip(t, -self.half_length, self.half_length)
        on_side = (dr >= dz) | ~np.isfinite(self.half_length)
        q_side = c + tc[:, None] * a + self.radius * e
        rc = np.minimum(rho, self.radius)
        q_cap = c + (np.sign(t) * self.half_length)[:, None] * a + rc[:, None] * e \
            if np.isfinite(self.half_length) else q_side
        q = np.where(on_side[:, None], q_side, q_cap)
        n_cap = np.sign(t)[:, None] * a
        n = np.where(on_side[:, None], e, n_cap)
        return d, q, n

    def moved(self, dp):
        return replace(self, centre=tuple(np.asarray(self.centre) + dp))

    def scaled(self, s):
        return replace(self, centre=tuple(np.asarray(self.centre) * s))


@dataclass(frozen=True)
class Hole(_Primitive):
    """An inner cylinder: material outside ``radius`` of the axis (infinite along it)."""

    centre: tuple
    axis: tuple
    radius: float
    form: Form | None = None

    def _nominal(self, p):
        c = np.asarray(self.centre, float)
        a = _unit(self.axis)
        r = p - c
        t = r @ a
        radial = r - t[:, None] * a
        rho = np.linalg.norm(radial, axis=1)
        e = np.where(rho[:, None] > 0, radial / np.where(rho > 0, rho, 1.0)[:, None], _perp(a))
        q = c + t[:, None] * a + self.radius * e
        return self.radius - rho, q, -e

    def moved(self, dp):
        return replace(self, centre=tuple(np.asarray(self.centre) + dp))

    def scaled(self, s):
        return replace(self, centre=tuple(np.asarray(self.centre) * s))


@dataclass(frozen=True)
class Prism(_Primitive):
    """Walls of a straight prism over a polygon in the A-frame xy plane.

    ``vertices`` (m,2) counter-clockwise, m. ``material_inside``: a boss
    (True) or a pocket (False). Only the walls count (the prism is infinite
    along z): the probed points are on the walls. The distance is exact:
    the minimum over the edges, signed by the even-odd inside test, so
    concave corners are exact. ``window`` > 0 restricts the edges looked at
    to those within ``window`` edges of the polar angle of the point (for
    fine star-shaped polygons around the origin, e.g. the free-form plate).
    """

    vertices: np.ndarray = field(compare=False)
    material_inside: bool = True
    window: int = 0
    form: Form | None = None

    def _edges(self, p):
        v = np.asarray(self.vertices, float)
        m = len(v)
        if self.window and m > 2 * self.window + 1:
            th = np.arctan2(v[:, 1], v[:, 0])
            # vertices are sampled uniformly in polar angle from theta_0
            t0 = th[0]
            k = np.floor(((np.arctan2(p[:, 1], p[:, 0]) - t0) % (2 * np.pi)) / (2 * np.pi) * m)
            idx = (k[:, None].astype(int) + np.arange(-self.window, self.window + 1)) % m
        else:
            idx = np.broadcast_to(np.arange(m), (len(p), m))
        a = v[idx]
        b = v[(idx + 1) % m]
        return a, b

    def _nominal(self, p):
        xy = p[:, :2]
        a, b = self._edges(p)
        ab = b - a
        ap = xy[:, None, :] - a
        L2 = np.sum(ab * ab, axis=2)
        t = np.clip(np.sum(ap * ab, axis=2) / L2, 0.0, 1.0)
        c = a + t[..., None] * ab
        dist = np.linalg.norm(xy[:, None, :] - c, axis=2)
        j = np.argmin(dist, axis=1)
        rows = np.arange(len(p))
        dmin = dist[rows, j]
        cq = c[rows, j]
        if self.window and len(self.vertices) > 2 * self.window + 1:
            # star-shaped: inside iff the point is on the inner side of the edge
            # crossed by its polar ray (the middle edge of the window)
            mid = self.window
            e0, e1 = a[:, mid], b[:, mid]
            cr = (e1[:, 0] - e0[:, 0]) * (xy[:, 1] - e0[:, 1]) - (e1[:, 1] - e0[:, 1]) * (xy[:, 0] - e0[:, 0])
            inside = cr > 0
        else:
            y0, y1 = a[..., 1], b[..., 1]
            x0, x1 = a[..., 0], b[..., 0]
            py = xy[:, 1:2]
            px = xy[:, 0:1]
            cond = (y0 > py) != (y1 > py)
            xint = x0 + (py - y0) * (x1 - x0) / np.where(y1 != y0, y1 - y0, 1.0)
            inside = (np.sum(cond & (px < xint), axis=1) % 2) == 1
        in_material = inside if self.material_inside else ~inside
        d = np.where(in_material, -dmin, dmin)
        q = np.column_stack([cq, p[:, 2]])
        # outward normal: from the surface towards free space
        r = xy - cq
        rn = np.linalg.norm(r, axis=1)
        ed = (b - a)[rows, j]
        en = np.column_stack([ed[:, 1], -ed[:, 0]]) / np.linalg.norm(ed, axis=1)[:, None]
        if not self.material_inside:
            en = -en
        good = rn > 1e-15
        n2 = np.where(good[:, None], r / np.where(good, rn, 1.0)[:, None] * np.where(in_material, -1.0, 1.0)[:, None], en)
        n = np.column_stack([n2, np.zeros(len(p))])
        return d, q, n

    def moved(self, dp):
        return replace(self, vertices=np.asarray(self.vertices) + np.asarray(dp)[:2])

    def scaled(self, s):
        return replace(self, vertices=np.asarray(self.vertices) * s)


# ---------------------------------------------------------------------------
# artefacts


@dataclass(frozen=True)
class Feature:
    """One probed surface: its id, kind, nominal and true primitives (A frame)."""

    name: str
    kind: str  # plane, sphere, rod, hole, prism
    nominal: _Primitive
    true: _Primitive


@dataclass(frozen=True)
class Solid:
    """A convex piece of material for the MuJoCo scene and display meshes (A frame).

    ``kind``: ``box`` (``size`` = half sizes), ``cylinder`` (radius,
    half-length along local z), ``sphere`` (radius,), ``mesh`` (``vertices``
    of a convex polytope). ``feature``: the feature whose exact primitive
    this solid carries or approximates (its collisions with the stylus are
    judged by the exact primitive when that feature is the touch's target);
    ``exact``: the solid's surface is the feature's nominal surface.
    """

    kind: str
    pos: tuple
    rot: np.ndarray = field(default_factory=lambda: np.eye(3), compare=False)
    size: tuple = ()
    vertices: np.ndarray | None = field(default=None, compare=False)
    feature: str = ""
    exact: bool = False


@dataclass(frozen=True)
class Artefact:
    """A test piece: features (exact), solids (scene/meshes), default placement.

    Attributes
    ----------
    name : str
        ``mfb``, ``cross-pocket``, ``pin-circle``, ``freeform``.
    features : tuple of Feature
    solids : tuple of Solid
    T_W_A : (4,4) float
        Default placement: pose of the artefact frame A in the table frame W, m.
    top_A_m : float
        Highest z of the material in A, m (for safe heights).
    info : dict
        Chosen dimensions and truth (e.g. ``E_MFB_m``), for reports.
    """

    name: str
    features: tuple
    solids: tuple
    T_W_A: np.ndarray = field(compare=False)
    top_A_m: float = 0.0
    info: dict = field(default_factory=dict, compare=False)

    def feature(self, name: str) -> Feature:
        """The feature called ``name`` (ConfigError if there is none)."""
        for f in self.features:
            if f.name == name:
                return f
        raise ConfigError(f"artefact {self.name!r} has no feature {name!r}")

    def meshes(self):
        """trimesh meshes of the solids in the A frame (display, export)."""
        import trimesh

        out = []
        for s in self.solids:
            T = make_T(s.rot, s.pos)
            if s.kind == "box":
                m = trimesh.creation.box(extents=2 * np.asarray(s.size), transform=T)
            elif s.kind == "cylinder":
                m = trimesh.creation.cylinder(radius=s.size[0], height=2 * s.size[1],
                                              sections=48, transform=T)
            elif s.kind == "sphere":
                m = trimesh.creation.icosphere(subdivisions=3, radius=s.size[0])
                m.apply_transform(T)
            else:
                m = trimesh.convex.convex_hull(apply_T(T, s.vertices))
            out.append(m)
        return out

    def mesh(self):
        """One concatenated trimesh of the artefact in the A frame."""
        import trimesh

        return trimesh.util.concatenate(self.meshes())


def solid_points(s: Solid) -> np.ndarray:
    """(k,3) points whose convex hull contains the solid (A frame, m)."""
    if s.kind == "mesh":
        return apply_T(make_T(s.rot, s.pos), np.asarray(s.vertices, float))
    ext = np.asarray(s.size if s.kind == "box" else (s.size[0], s.size[0], s.size[-1]), float)
    corners = _CORNERS * ext
    return corners @ np.asarray(s.rot).T + np.asarray(s.pos, float)


#: A box's 8 corners in half-extents (the order :func:`solid_points` lists them in).
_CORNERS = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)


def solids_points(solids) -> np.ndarray:
    """:func:`solid_points` of every solid, concatenated in order ((k,3), A frame, m).

    The boxes, cylinders and spheres as one stacked product (the same numbers bit for bit as
    one solid at a time, tests/sim/test_artefacts.py: each is its own 8x3 by 3x3 product), a
    mesh by :func:`solid_points`: the bar's 255 solids in 0.26 ms instead of 2.6 ms.
    """
    solids = list(solids)
    cut = [k for k, s in enumerate(solids) if s.kind != "mesh"]
    if not cut:
        return np.concatenate([solid_points(s) for s in solids])
    sol = [solids[k] for k in cut]
    ext = np.array([s.size if s.kind == "box" else (s.size[0], s.size[0], s.size[-1]) for s in sol], float)
    rot = np.array([s.rot for s in sol], float)
    pos = np.array([s.pos for s in sol], float)
    boxes = (_CORNERS[None] * ext[:, None, :]) @ rot.transpose(0, 2, 1) + pos[:, None, :]
    if len(cut) == len(solids):
        return boxes.reshape(-1, 3)
    at = dict(zip(cut, boxes))
    return np.concatenate([at[k] if k in at else solid_points(s) for k, s in enumerate(solids)])


def _box(lo, hi, feature="", exact=False) -> Solid:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return Solid("box", tuple((lo + hi) / 2), np.eye(3), tuple((hi - lo) / 2), feature=feature, exact=exact)


def _hole_ring(name, centre, radius, z0, z1, outer, nseg=16) -> list[Solid]:
    """Convex boxes around a vertical hole: a conservative (material-containing)
    approximation of its surroundings; their inner faces form the regular
    ``nseg``-gon inscribed in the hole circle (apothem ``r cos(pi/nseg)``)."""
    out = []
    ap = radius * np.cos(np.pi / nseg)
    chord = 2 * radius * np.sin(np.pi / nseg)
    thick = outer - ap
    for k in range(nseg):
        th = 2 * np.pi * (k + 0.5) / nseg
        R = rot_z(th)
        mid = ap + thick / 2
        pos = np.asarray(centre, float) + np.array([mid * np.cos(th), mid * np.sin(th), (z0 + z1) / 2])
        # the box widens outwards so adjacent boxes overlap (no gaps)
        half_t = chord / 2 * (outer / ap)
        out.append(Solid("box", tuple(pos), R, (thick / 2, half_t, (z1 - z0) / 2), feature=name))
    return out


# ---- the multi-feature bar --------------------------------------------------

MFB_PITCH_M = 0.050
MFB_N_HOLES = 12
MFB_LENGTH_M = 0.580
MFB_SUPPORT_RATIO = 0.5537
INVAR_CTE_PER_C = 1.0e-6
HOLE_R_M = 8.0 * MM
HOLE_RING_M = 11.5 * MM  # outer radius of the boxes standing for a hole's surroundings
ROD_R_M = 5.0 * MM
RAIL_Y_M = (20.0 * MM, 30.0 * MM)
BAR_HALF_Z_M = 10.0 * MM
WEB_HALF_X_M = 12.0 * MM
SHIFTED_HOLES = {2: 1.5 * MM, 5: 1.5 * MM}  # 1-based hole index -> y shift (mistake-proofing)


def mfb_default_deviations() -> np.ndarray:
    """(12, 3) default calibrated deviations (Exx, Eyx, Ezx)_MFB of O_i, m (eq. 4).

    Of the paper's size (Figs. 9, 10): positioning reaching -42 um at the
    last hole, straightnesses of a few um.
    """
    x = np.arange(MFB_N_HOLES) * MFB_PITCH_M
    u = x / x[-1]
    exx = -42.0 * UM * u + 1.0 * UM * np.sin(4 * np.pi * u)
    eyx = 2.5 * UM * np.sin(np.pi * u) + 0.8 * UM * np.sin(3 * np.pi * u)
    ezx = 1.5 * UM * np.sin(2 * np.pi * u + 0.3) - 0.5 * UM * np.cos(5 * np.pi * u)
    return np.column_stack([exx, eyx, ezx])


def multi_feature_bar(deviations_m: np.ndarray | None = None, temperature_C: float = 20.0,
                      T_W_A: np.ndarray | None = None) -> Artefact:
    """The multi-feature bar (Viprey et al. 2016, section 2).

    Parameters
    ----------
    deviations_m : (12, 3) float, optional
        True deviations (Exx, Eyx, Ezx)_MFB of the points of interest O_i in
        R_MFB = A, m (eq. 4). Holes move by (Exx, Eyx); the rod heights are
        set so the plane through the neighbouring rod axes passes through
        Ezx at each hole (see ``info['rod_dz_m']``). Default:
        :func:`mfb_default_deviations`.
    temperature_C : float
        Bar temperature; the true geometry expands by 1 um/m/degC (Invar)
        about the A origin from 20 degC.
    T_W_A : (4,4), optional
        Default placement in W (default: along X, centred, on 60 mm supports).
    """
    E = mfb_default_deviations() if deviations_m is None else np.asarray(deviations_m, float)
    if E.shape != (MFB_N_HOLES, 3) or not np.all(np.isfinite(E)):
        raise ConfigError(f"deviations_m must be a finite (12, 3) array, got shape {E.shape}")
    if not np.isfinite(temperature_C):
        raise ConfigError("temperature_C must be finite")
    s = 1.0 + INVAR_CTE_PER_C * (temperature_C - 20.0)
    L = MFB_PITCH_M
    x_hole = np.arange(MFB_N_HOLES) * L
    x_rod = (np.arange(MFB_N_HOLES - 1) + 0.5) * L
    # rod heights h_j so that the plane PL_i through rods i-1, i (their mean at
    # x_i) gives z(O_i) = Ezx_i: solve the (12 x 11) system in least squares
    # (end holes extrapolate from the two nearest rods).
    A = np.zeros((MFB_N_HOLES, MFB_N_HOLES - 1))
    for i in range(MFB_N_HOLES):
        if i == 0:
            A[i, 0], A[i, 1] = 1.5, -0.5
        elif i == MFB_N_HOLES - 1:
            A[i, -1], A[i, -2] = 1.5, -0.5
        else:
            A[i, i - 1] = A[i, i] = 0.5
    rod_dz = np.linalg.lstsq(A, E[:, 2], rcond=None)[0]
    ezx_true = A @ rod_dz
    feats: list[Feature] = []
    solids: list[Solid] = []
    y_in, y_out = RAIL_Y_M
    hz = BAR_HALF_Z_M
    for i in range(MFB_N_HOLES):
        name = f"hole{i + 1:02d}"
        c = np.array([x_hole[i], SHIFTED_HOLES.get(i + 1, 0.0), 0.0])
        nom = Hole(tuple(c), (0, 0, 1), HOLE_R_M)
        tru = Hole(tuple(c + [E[i, 0], E[i, 1], 0.0]), (0, 0, 1), HOLE_R_M).scaled(s)
        feats.append(Feature(name, "hole", nom, tru))
        solids += _hole_ring(name, c, HOLE_R_M, -hz, hz, outer=HOLE_RING_M)
        # web outside the ring, between the rails
        solids.append(_box([x_hole[i] - WEB_HALF_X_M, c[1] + HOLE_RING_M, -hz], [x_hole[i] + WEB_HALF_X_M, y_in, hz]))
        solids.append(_box([x_hole[i] - WEB_HALF_X_M, -y_in, -hz], [x_hole[i] + WEB_HALF_X_M, c[1] - HOLE_RING_M, hz]))
    for j in range(MFB_N_HOLES - 1):
        name = f"rod{j + 1:02d}"
        c = np.array([x_rod[j], 0.0, 0.0])
        nom = Rod(tuple(c), (0, 1, 0), ROD_R_M, y_out)
        tru = Rod(tuple(c + [0, 0, rod_dz[j]]), (0, 1, 0), ROD_R_M, y_out).scaled(s)
        feats.append(Feature(name, "rod", nom, tru))
        solids.append(Solid("cylinder", tuple(c), rot_x(-np.pi / 2), (ROD_R_M, y_out), feature=name, exact=True))
        for side, sg in (("L", -1.0), ("R", 1.0)):
            fname = f"face{side}{j + 1:02d}"
            o = np.array([x_rod[j], sg * y_out, 0.0])
            half_u = L / 2
            nomf = Plane(tuple(o), (0, sg, 0), (1, 0, 0), half_u, hz)
            truf = Plane(tuple(o + [0, 0, rod_dz[j]]), (0, sg, 0), (1, 0, 0), half_u, hz).scaled(s)
            feats.append(Feature(fname, "plane", nomf, truf))
            lo = [x_rod[j] - half_u, y_in if sg > 0 else -y_out, -hz]
            hi = [x_rod[j] + half_u, y_out if sg > 0 else -y_in, hz]
            solids.append(_box(lo, hi, feature=fname, exact=True))
    # rail ends beyond the first / last rod (bar from -15 to 565 mm)
    x0 = x_hole[-1] / 2 - MFB_LENGTH_M / 2
    x1 = x_hole[-1] / 2 + MFB_LENGTH_M / 2
    for sg in (-1.0, 1.0):
        ylo, yhi = (y_in, y_out) if sg > 0 else (-y_out, -y_in)
        solids.append(_box([x0, ylo, -hz], [x_rod[0] - L / 2, yhi, hz]))
        solids.append(_box([x_rod[-1] + L / 2, ylo, -hz], [x1, yhi, hz]))
    sup = MFB_SUPPORT_RATIO * MFB_LENGTH_M
    xs = (x_hole[-1] / 2 - sup / 2, x_hole[-1] / 2 + sup / 2)
    support_h = 60.0 * MM
    for xsup in xs:
        solids.append(Solid("cylinder", (xsup, 0.0, -hz - support_h / 2), np.eye(3), (8.0 * MM, support_h / 2)))
    if T_W_A is None:
        T_W_A = make_T(None, (-x_hole[-1] / 2, 0.0, support_h + hz))
    poi_true = np.column_stack([x_hole + E[:, 0], [SHIFTED_HOLES.get(i + 1, 0.0) + E[i, 1] for i in range(12)], ezx_true]) * s
    info = {
        "pitch_m": L, "length_m": MFB_LENGTH_M, "support_spacing_m": sup, "support_x_m": xs,
        "hole_r_m": HOLE_R_M, "rod_r_m": ROD_R_M, "rail_y_m": RAIL_Y_M,
        "shifted_holes": dict(SHIFTED_HOLES), "E_MFB_m": np.column_stack([E[:, :2], ezx_true]),
        "rod_dz_m": rod_dz, "temperature_C": temperature_C, "cte_per_C": INVAR_CTE_PER_C,
        "poi_nominal_m": np.column_stack([x_hole, [SHIFTED_HOLES.get(i + 1, 0.0) for i in range(12)], np.zeros(12)]),
        "poi_true_m": poi_true,
    }
    return Artefact("mfb", tuple(feats), tuple(solids), T_W_A, top_A_m=hz, info=info)


# ---- the cross-shaped pocket ------------------------------------------------

CROSS_HALF_WIDTH_M = 18.0 * MM
CROSS_HALF_LENGTH_M = 100.0 * MM
CROSS_DEPTH_M = 10.0 * MM
CROSS_PLATE_HALF_M = 120.0 * MM
CROSS_PLATE_T_M = 30.0 * MM
CROSS_PROBE_Z_M = -3.0 * MM
CROSS_SPHERE_R_M = 12.7 * MM
CROSS_SPHERES_M = ((60.0 * MM, 60.0 * MM), (-70.0 * MM, -55.0 * MM))
SPHERE_STEM_M = 10.0 * MM


def cross_outline() -> np.ndarray:
    """(12, 2) counter-clockwise vertices of the cross pocket, A frame, m."""
    w, l = CROSS_HALF_WIDTH_M, CROSS_HALF_LENGTH_M
    return np.array([(l, -w), (l, w), (w, w), (w, l), (-w, l), (-w, w), (-l, w), (-l, -w),
                     (-w, -w), (-w, -l), (w, -l), (w, -w)], float)


def cross_default_form() -> Form:
    """The chosen true wall form: 2 um waviness (40 mm) + 3 um bump on the +x end wall."""
    return FormSum((Waviness(2.0 * UM, 40.0 * MM, (1.0, 1.0, 0.0), 0.4),
                    Bump(3.0 * UM, (CROSS_HALF_LENGTH_M, 5.0 * MM, CROSS_PROBE_Z_M), 6.0 * MM)))


def _sphere_feature(name, centre, radius, stem_from_z, form=None, offset=(0, 0, 0)):
    c = np.asarray(centre, float)
    nom = Sphere(tuple(c), radius)
    tru = Sphere(tuple(c + offset), radius, form)
    stem_h = c[2] - radius * 0.8 - stem_from_z
    solids = [Solid("sphere", tuple(c), np.eye(3), (radius,), feature=name, exact=True),
              Solid("cylinder", (c[0], c[1], stem_from_z + stem_h / 2), np.eye(3), (radius * 0.3, stem_h / 2))]
    return Feature(name, "sphere", nom, tru), solids


def cross_pocket(form: Form | None = "default", T_W_A: np.ndarray | None = None) -> Artefact:
    """The cross-shaped pocket with two precision spheres (Ibaraki, section 4.2).

    Parameters
    ----------
    form : callable or None
        True form error of the pocket walls (m along the outward normal as a
        function of the nominal wall point, A frame). ``"default"``:
        :func:`cross_default_form`; ``None``: perfect walls.
    T_W_A : (4,4), optional
        Placement in W; default: centred on the C axis, plate on the table.
    """
    if isinstance(form, str):
        form = cross_default_form()
    poly = cross_outline()
    nom = Prism(poly, material_inside=False)
    tru = Prism(poly, material_inside=False, form=form)
    feats = [Feature("pocket", "prism", nom, tru)]
    w, l, P, t = CROSS_HALF_WIDTH_M, CROSS_HALF_LENGTH_M, CROSS_PLATE_HALF_M, CROSS_PLATE_T_M
    solids = [_box([-P, -P, -t], [P, P, -CROSS_DEPTH_M])]
    for sx in (-1, 1):
        for sy in (-1, 1):  # corner blocks between the arms
            lo = [min(sx * w, sx * P), min(sy * w, sy * P), -CROSS_DEPTH_M]
            hi = [max(sx * w, sx * P), max(sy * w, sy * P), 0.0]
            solids.append(_box(lo, hi, feature="pocket", exact=True))
    for sg in (-1, 1):  # end blocks beyond the arms
        solids.append(_box([min(sg * l, sg * P), -w, -CROSS_DEPTH_M], [max(sg * l, sg * P), w, 0.0], "pocket", True))
        solids.append(_box([-w, min(sg * l, sg * P), -CROSS_DEPTH_M], [w, max(sg * l, sg * P), 0.0], "pocket", True))
    zc = SPHERE_STEM_M + CROSS_SPHERE_R_M
    for k, (x, y) in enumerate(CROSS_SPHERES_M):
        f, s = _sphere_feature(f"sphere{k + 1}", (x, y, zc), CROSS_SPHERE_R_M, 0.0)
        feats.append(f)
        solids += s
    if T_W_A is None:
        T_W_A = make_T(None, (0.0, 0.0, t))
    info = {"arm_width_m": 2 * w, "arm_length_m": 2 * l, "depth_m": CROSS_DEPTH_M,
            "probe_z_m": CROSS_PROBE_Z_M, "sphere_d_m": 2 * CROSS_SPHERE_R_M,
            "sphere_xy_m": CROSS_SPHERES_M, "grid_m": (-0.110, 0.110)}
    return Artefact("cross-pocket", tuple(feats), tuple(solids), T_W_A, top_A_m=zc + CROSS_SPHERE_R_M, info=info)


# ---- the pin circle ----------------------------------------------------------

PIN_R_M = 6.0 * MM
PIN_PCD_M = 400.0 * MM
PIN_N = 18
PIN_H_M = 20.0 * MM
PIN_PROBE_Z_M = 10.0 * MM
PIN_SPHERE_R_M = 15.0 * MM
PIN_SPHERES_M = ((0.0, 60.0 * MM), (50.0 * MM, -80.0 * MM))


def pin_positions_nominal() -> np.ndarray:
    """(18, 2) nominal pin centres, A frame, m (pin 6 shifted -10 mm in X)."""
    a = np.deg2rad(20.0 * np.arange(PIN_N))
    xy = PIN_PCD_M / 2 * np.column_stack([np.cos(a), np.sin(a)])
    xy[5, 0] -= 10.0 * MM
    return xy


def pin_default_deviations() -> np.ndarray:
    """(18, 2) default true pin-position deviations, m (a few um)."""
    k = np.arange(PIN_N)
    return np.column_stack([3.0 * UM * np.sin(2.0 * k + 0.5), 2.0 * UM * np.cos(3.0 * k)])


def pin_circle(deviations_m: np.ndarray | None = None, T_W_A: np.ndarray | None = None) -> Artefact:
    """Pin circle with two 30 mm spheres (Ibaraki, section 5)."""
    D = pin_default_deviations() if deviations_m is None else np.asarray(deviations_m, float)
    if D.shape != (PIN_N, 2) or not np.all(np.isfinite(D)):
        raise ConfigError(f"deviations_m must be a finite (18, 2) array, got shape {D.shape}")
    xy = pin_positions_nominal()
    feats, solids = [], [_box([-0.24, -0.24, -0.03], [0.24, 0.24, 0.0])]
    for k in range(PIN_N):
        name = f"pin{k + 1:02d}"
        c = np.array([xy[k, 0], xy[k, 1], PIN_H_M / 2])
        nom = Rod(tuple(c), (0, 0, 1), PIN_R_M, PIN_H_M / 2)
        tru = Rod(tuple(c + [D[k, 0], D[k, 1], 0]), (0, 0, 1), PIN_R_M, PIN_H_M / 2)
        feats.append(Feature(name, "rod", nom, tru))
        solids.append(Solid("cylinder", tuple(c), np.eye(3), (PIN_R_M, PIN_H_M / 2), feature=name, exact=True))
    zc = 25.0 * MM + PIN_SPHERE_R_M
    for k, (x, y) in enumerate(PIN_SPHERES_M):
        f, s = _sphere_feature(f"sphere{k + 1}", (x, y, zc), PIN_SPHERE_R_M, 0.0)
        feats.append(f)
        solids += s
    if T_W_A is None:
        T_W_A = make_T(None, (0.0, 0.0, 0.03))
    info = {"pin_d_m": 2 * PIN_R_M, "pcd_m": PIN_PCD_M, "pin_xy_m": xy, "pin_dev_m": D,
            "sphere_d_m": 2 * PIN_SPHERE_R_M, "probe_z_m": PIN_PROBE_Z_M}
    return Artefact("pin-circle", tuple(feats), tuple(solids), T_W_A, top_A_m=zc + PIN_SPHERE_R_M, info=info)


# ---- the free-form plate -------------------------------------------------------

FREEFORM_N = 1440
FREEFORM_H_M = 15.0 * MM
FREEFORM_PROBE_Z_M = -5.0 * MM


def freeform_radius(theta: np.ndarray) -> np.ndarray:
    """Outline radius r(theta) of the free-form boss, m (convex, point-asymmetric)."""
    return MM * (90.0 + 5.0 * np.cos(2 * theta) + 3.0 * np.sin(3 * theta) + 1.0 * np.cos(5 * theta))


def freeform_outline() -> np.ndarray:
    """(1440, 2) counter-clockwise vertices of the free-form boss, m."""
    th = 2 * np.pi * np.arange(FREEFORM_N) / FREEFORM_N
    r = freeform_radius(th)
    return np.column_stack([r * np.cos(th), r * np.sin(th)])


def freeform_plate(form: Form | None = "default", T_W_A: np.ndarray | None = None) -> Artefact:
    """A point-asymmetric free-form boss with two 25.4 mm spheres."""
    if isinstance(form, str):
        form = FormSum((AngularWaviness(1.5 * UM, 7, 0.2),
                        Bump(2.5 * UM, (float(freeform_radius(np.array(2.0))) * np.cos(2.0),
                                        float(freeform_radius(np.array(2.0))) * np.sin(2.0),
                                        FREEFORM_PROBE_Z_M), 8.0 * MM)))
    poly = freeform_outline()
    nom = Prism(poly, material_inside=True, window=16)
    tru = Prism(poly, material_inside=True, window=16, form=form)
    feats = [Feature("contour", "prism", nom, tru)]
    prism_v = np.vstack([np.column_stack([poly, np.full(len(poly), z)]) for z in (-FREEFORM_H_M, 0.0)])
    solids = [_box([-0.16, -0.16, -FREEFORM_H_M - 0.02], [0.16, 0.16, -FREEFORM_H_M]),
              Solid("mesh", (0.0, 0.0, 0.0), np.eye(3), (), prism_v, feature="contour", exact=False)]
    spheres = ((0.125 * np.cos(0.3), 0.125 * np.sin(0.3)), (0.125 * np.cos(4.2), 0.125 * np.sin(4.2)))
    zc = -FREEFORM_H_M + SPHERE_STEM_M + CROSS_SPHERE_R_M
    for k, (x, y) in enumerate(spheres):
        f, s = _sphere_feature(f"sphere{k + 1}", (x, y, zc), CROSS_SPHERE_R_M, -FREEFORM_H_M)
        feats.append(f)
        solids += s
    if T_W_A is None:
        T_W_A = make_T(None, (0.0, 0.0, FREEFORM_H_M + 0.02))
    info = {"n_vertices": FREEFORM_N, "height_m": FREEFORM_H_M, "probe_z_m": FREEFORM_PROBE_Z_M,
            "sphere_xy_m": spheres}
    return Artefact("freeform", tuple(feats), tuple(solids), T_W_A, top_A_m=zc + CROSS_SPHERE_R_M, info=info)


# ---------------------------------------------------------------------------
# several primitives at once (issue 19: one pass per kind instead of per feature)


def _rows_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (n,3) arrays."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def _plane_rows(P: Plane) -> np.ndarray:
    """(14,) origin, unit normal, u, v, half_u, half_v as ``Plane._nominal`` derives them."""
    n = _unit(P.normal_)
    u = np.asarray(P.u, float)
    u = u - n * (u @ n)
    u = _unit(u) if np.linalg.norm(u) > 1e-9 else _perp(n)
    return np.concatenate([np.asarray(P.origin, float), n, u, np.cross(n, u), [P.half_u, P.half_v]])


def _axis_rows(P) -> np.ndarray:
    """(12,) centre, unit axis, fallback radial direction, radius, half-length of a Rod/Hole/Sphere."""
    if isinstance(P, Sphere):
        return np.concatenate([np.asarray(P.centre, float), np.zeros(6), [P.radius, 0.0, 0.0]])
    a = _unit(P.axis)
    return np.concatenate([np.asarray(P.centre, float), a, _perp(a),
                           [P.radius, getattr(P, "half_length", np.inf), 0.0]])


def _plane_d_q(R: np.ndarray, p: np.ndarray):
    o, n, u, v = R[:, 0:3], R[:, 3:6], R[:, 6:9], R[:, 9:12]
    hu, hv = R[:, 12], R[:, 13]
    r = p - o
    h = _rows_dot(r, n)
    a, b = _rows_dot(r, u), _rows_dot(r, v)
    ca = np.clip(a, -hu, hu)
    cb = np.clip(b, -hv, hv)
    lateral = np.hypot(a - ca, b - cb)
    d = np.where(lateral > 0, np.hypot(lateral, np.maximum(h, 0.0)), h)
    return d, o + ca[:, None] * u + cb[:, None] * v


def _sphere_d_q(R: np.ndarray, p: np.ndarray):
    c, rad = R[:, 0:3], R[:, 9]
    r = p - c
    rho = np.sqrt(_rows_dot(r, r))
    n = np.where(rho[:, None] > 0, r / np.where(rho > 0, rho, 1.0)[:, None], np.array([0, 0, 1.0]))
    return rho - rad, c + rad[:, None] * n


def _cylinder_d_q(R: np.ndarray, p: np.ndarray, hole: bool):
    c, a, e0, rad, hl = R[:, 0:3], R[:, 3:6], R[:, 6:9], R[:, 9], R[:, 10]
    r = p - c
    t = _rows_dot(r, a)
    radial = r - t[:, None] * a
    rho = np.sqrt(_rows_dot(radial, radial))
    e = np.where(rho[:, None] > 0, radial / np.where(rho > 0, rho, 1.0)[:, None], e0)
    if hole:
        return rad - rho, c + t[:, None] * a + rad[:, None] * e
    dr = rho - rad
    dz = np.abs(t) - hl
    outside = np.hypot(np.maximum(dr, 0), np.maximum(dz, 0))
    d = np.where((dr > 0) | (dz > 0), outside, np.maximum(dr, dz))
    finite = np.isfinite(hl)
    q_side = c + np.clip(t, -hl, hl)[:, None] * a + rad[:, None] * e
    hlf = np.where(finite, hl, 0.0)
    q_cap = c + (np.sign(t) * hlf)[:, None] * a + np.minimum(rho, rad)[:, None] * e
    on_side = (dr >= dz) | ~finite
    return d, np.where(on_side[:, None], q_side, q_cap)


def _cached_rows(P: _Primitive, rows_of) -> np.ndarray:
    """``rows_of(P)`` computed once per primitive (kept on the frozen instance, not compared)."""
    r = P.__dict__.get("_batch_rows")
    if r is None:
        r = rows_of(P)
        object.__setattr__(P, "_batch_rows", r)
    return r


_BATCHED = {Plane: (_plane_rows, _plane_d_q), Sphere: (_axis_rows, _sphere_d_q),
            Rod: (_axis_rows, lambda R, p: _cylinder_d_q(R, p, False)),
            Hole: (_axis_rows, lambda R, p: _cylinder_d_q(R, p, True))}


class GroupedSdf:
    """Signed distances of points to several surfaces, one numpy pass per primitive kind.

    The batched form of calling ``funcs[group[i]](p[i])`` point by point: the
    planes, spheres, rods and holes among ``funcs`` (bound ``_Primitive.sdf``
    methods) are evaluated together, their parameters gathered per point; the
    form errors once per distinct form; any other callable (a prism, a
    composite distance) on its own points. Same formulas as each primitive's
    ``_nominal``; results agree with the one-by-one path to rounding (tested).

    Parameters
    ----------
    funcs : sequence of callables
        Signed distance functions, A-frame points (m,3) -> (m,), m.
    """

    def __init__(self, funcs):
        self._funcs = list(funcs)
        k = len(self._funcs)
        prims = [getattr(f, "__self__", None) if getattr(f, "__func__", None) is _Primitive.sdf else None
                 for f in self._funcs]
        self._kind = np.full(k, -1)
        self._kinds = []  # (d_q function, (k, m) parameter rows)
        for j, cls in enumerate(_BATCHED):
            members = [i for i, P in enumerate(prims) if type(P) is cls]
            if not members:
                continue
            rows_of, d_q = _BATCHED[cls]
            rows = np.zeros((k, len(_cached_rows(prims[members[0]], rows_of))))
            for i in members:
                rows[i] = _cached_rows(prims[i], rows_of)
                self._kind[i] = len(self._kinds)
            self._kinds.append((d_q, rows))
        forms: dict = {}
        for i, P in enumerate(prims):
            if P is not None and self._kind[i] >= 0 and P.form is not None:
                forms.setdefault(id(P.form), (P.form, []))[1].append(i)
        self._forms = [(f, np.array(ii)) for f, ii in forms.values()]
        self._alone = [i for i in range(k) if self._kind[i] < 0]

    def __call__(self, group: np.ndarray, p: np.ndarray) -> np.ndarray:
        """(n,) signed distance of ``p`` (n,3, A frame, m) to surface ``group`` (n,) each."""
        group = np.asarray(group, int)
        p = np.asarray(p, float)
        out = np.empty(len(group))
        kind = self._kind[group]
        q = np.empty_like(p) if self._forms else None
        for j, (d_q, rows) in enumerate(self._kinds):
            m = kind == j
            if m.all():
                d, qq = d_q(rows[group], p)
                out[:] = d
            elif m.any():
                d, qq = d_q(rows[group[m]], p[m])
                out[m] = d
            else:
                continue
            if q is not None:
                q[m] = qq
        for f, members in self._forms:
            m = np.isin(group, members)
            if m.any():
                out[m] -= f(q[m])
        for i in self._alone:
            m = group == i
            if m.any():
                out[m] = self._funcs[i](p[m])
        return out
