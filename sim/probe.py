"""Touch-trigger probing: exact contact, pre-travel with lobing, noise.

The stylus centre moves from a start point along a commanded straight line
in axis space (the machine's belief, frame R). Where it really is comes
from the machine's erroneous kinematics, ``machine.tip_W(lin, rot, t, d)``
(frame W). The touch happens where the stylus sphere meets the true,
form-deviated surface: the root of

    g(s) = sdf_A(T_A_W tip_W(start + s d, rot, t0 + s / feed, d)) - r

found for every touch at once (coarse bracketing on a few samples, then a
vectorised Illinois regula falsi to |g| < 1e-14 m or a bracket below
1e-13 m). The probe triggers after its pre-travel (constant, axial term,
low-order Fourier lobing in the approach azimuth in the probe frame P,
feed term); the machine reports its scale positions there plus the
repeatability noise along the approach direction, drawn from the passed
``np.random.Generator``. A path that meets no surface within its travel is
a ``no_trigger`` touch (NaN position), one that starts inside the material
an ``early_trigger`` touch: never an exception in the middle of a campaign.

Frames: R machine reference (axis readings), W table, A artefact, P probe
(the spindle frame: P = R orientation for a machine without a swivel head).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from core.exceptions import ConfigError
from core.touches import ProbeStatus

from .artefacts import Artefact, GroupedSdf, Solid, apply_T, inv_T, make_T, solids_points


#: Root-finding tolerances (m): on |g| and on the bracket width.
G_TOL_M = 1e-14
S_TOL_M = 1e-13


@dataclass(frozen=True)
class ProbeConfig:
    """A touch-trigger probe. SI units.

    Attributes
    ----------
    stylus_r_m : float
        Stylus sphere radius, m (default 3 mm: the papers' 6 mm ball).
    pretravel_m : float
        Constant pre-travel left after the controller's probe calibration, m.
    pretravel_axial_m : float
        Extra pre-travel for an axial approach, weighted by ``d_z^2`` (P frame), m.
    lobing_m : tuple of (k, a, b)
        Fourier lobing in the approach azimuth phi = atan2(d_y, d_x) (P frame):
        ``sum a cos(k phi) + b sin(k phi)``, weighted by ``1 - d_z^2``, m.
    pretravel_per_feed_s : float
        Pre-travel change per unit feed above ``feed_ref_mps``, m per (m/s).
    feed_ref_mps : float
        Probing feed the pre-travel refers to (default 240 mm/min, MFB paper).
    repeatability_k2_m : float
        Expanded (k=2) repeatability; noise sigma = half of it, along the
        approach direction. Default 0.25 um (Viprey 2016 section 5).
    max_travel_m : float
        Longest search past the start point before ``no_trigger``, m.
    shank_r_m, shank_length_m : float
        Stylus shank (for collision checks), m.
    """

    stylus_r_m: float = 3.0e-3
    pretravel_m: float = 0.0
    pretravel_axial_m: float = 0.0
    lobing_m: tuple = ()
    pretravel_per_feed_s: float = 0.0
    feed_ref_mps: float = 0.240 / 60.0
    repeatability_k2_m: float = 0.25e-6
    max_travel_m: float = 10.0e-3
    shank_r_m: float = 1.0e-3
    shank_length_m: float = 50.0e-3

    def __post_init__(self):
        for name in ("stylus_r_m", "feed_ref_mps", "max_travel_m", "shank_length_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ConfigError(f"ProbeConfig.{name} must be a positive length/speed, got {v!r}")
        for name in ("pretravel_m", "pretravel_axial_m", "pretravel_per_feed_s"):
            if not np.isfinite(getattr(self, name)):
                raise ConfigError(f"ProbeConfig.{name} must be finite")
        if not (np.isfinite(self.repeatability_k2_m) and self.repeatability_k2_m >= 0):
            raise ConfigError(f"ProbeConfig.repeatability_k2_m must be >= 0, got {self.repeatability_k2_m!r}")
        if not (0 <= self.shank_r_m < self.stylus_r_m):
            raise ConfigError("ProbeConfig.shank_r_m must be >= 0 and below stylus_r_m")
        for term in self.lobing_m:
            if len(term) != 3 or int(term[0]) != term[0] or term[0] < 1 or not np.all(np.isfinite(term)):
                raise ConfigError(f"ProbeConfig.lobing_m terms are (k >= 1 integer, a_m, b_m), got {term!r}")

    @classmethod
    def viprey2016(cls, **kw) -> "ProbeConfig":
        """The MFB paper's probe: 0.25 um (k=2) at 240 mm/min."""
        return cls(**kw)

    @classmethod
    def ibaraki(cls, **kw) -> "ProbeConfig":
        """The self-calibration paper's probing: 1.38 um standard uncertainty (k=1)."""
        kw.setdefault("repeatability_k2_m", 2 * 1.38e-6)
        return cls(**kw)

    @property
    def sigma_m(self) -> float:
        """Standard deviation of the repeatability noise, m."""
        return self.repeatability_k2_m / 2.0

    def pretravel(self, d_P: np.ndarray, feed_mps: np.ndarray | float) -> np.ndarray:
        """(n,) pre-travel for approach directions ``d_P`` (n,3, P frame) and feeds (m/s)."""
        d = np.atleast_2d(d_P)
        dz2 = d[:, 2] ** 2
        phi = np.arctan2(d[:, 1], d[:, 0])
        lob = np.zeros(len(d))
        for k, a, b in self.lobing_m:
            lob += a * np.cos(k * phi) + b * np.sin(k * phi)
        return (self.pretravel_m + self.pretravel_axial_m * dz2 + (1 - dz2) * lob
                + self.pretravel_per_feed_s * (np.asarray(feed_mps, float) - self.feed_ref_mps))


# ---------------------------------------------------------------------------
# the machine seen through duck typing


def rotary_count(machine) -> int:
    return len(getattr(machine, "rotary_axes", ()) or ())


def tip_W(machine, lin_m, rot_rad, t_s, direction, J_m=None) -> np.ndarray:
    """``machine.tip_W`` with ``rot_rad`` dropped for machines without rotary axes.

    ``direction`` (n,3) is passed as the signs (-1, 0, +1) of the X, Y, Z
    velocities (what reversal errors depend on); ``J_m`` (n, 3), when given,
    each pose's probe offsets (``sim.machine.Machine.tip_W``).
    """
    rot = None if rot_rad is None or rotary_count(machine) == 0 else rot_rad
    d = np.asarray(direction, float)
    sgn = np.sign(np.where(np.abs(d) < 1e-12, 0.0, d))
    if J_m is None:
        return np.asarray(machine.tip_W(lin_m, rot, t_s, sgn), float)
    return np.asarray(machine.tip_W(lin_m, rot, t_s, sgn, J_m=J_m), float)


def T_R_W_nominal(machine, rot_rad: np.ndarray | None, n: int) -> np.ndarray:
    """(n,4,4) nominal pose of W in R; identity when the machine has no such method."""
    f = getattr(machine, "T_R_W_nominal", None)
    if f is None or rotary_count(machine) == 0:
        return np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    T = np.asarray(f(rot_rad), float)
    return np.broadcast_to(T, (n, 4, 4)).copy() if T.ndim == 2 else T


# ---------------------------------------------------------------------------
# vectorised contact search


def find_contacts(g: Callable[[np.ndarray, np.ndarray], np.ndarray], n: int,
                  travel_m: np.ndarray, n_coarse: int = 13, max_iter: int = 100,
                  n_first: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """First root of ``g(idx, s)`` on ``[0, travel]`` for ``n`` paths at once.

    Parameters
    ----------
    g : callable
        ``g(idx (m,), s (m,)) -> (m,)``: signed clearance of path ``idx``
        after ``s`` metres (positive = free).
    travel_m : (n,) float
        Length of each path, m.
    n_coarse : int
        Samples per path to bracket the first crossing (a graze that enters
        and leaves the material between two samples is missed).
    n_first : int, optional
        Evaluate the first ``n_first`` samples of every path, then the others
        only on the paths without a crossing among them (default: all at
        once). The same samples decide, so the result is the same; only the
        number of evaluations changes (fewer when most contacts lie within
        the first samples).

    Returns
    -------
    s : (n,) float
        Path length at contact, m (NaN without a contact).
    status : (n,) object
        ``ok``, ``no_trigger`` or ``early_trigger``.
    """
    travel = np.broadcast_to(np.asarray(travel_m, float), (n,))
    frac = np.linspace(0.0, 1.0, n_coarse)
    G = _coarse_samples(g, n, travel, frac, n_coarse if n_first is None else max(1, min(n_first, n_coarse)))
    status = np.full(n, ProbeStatus.OK, dtype=object)
    early = G[:, 0] <= 0
    neg = G <= 0
    hit = neg.any(axis=1) & ~early
    status[early] = ProbeStatus.EARLY_TRIGGER
    status[~hit & ~early] = ProbeStatus.NO_TRIGGER
    s = np.full(n, np.nan)
    k = np.argmax(neg, axis=1)
    act = np.flatnonzero(hit)
    if act.size == 0:
        return s, status
    kk = k[act]
    a = travel[act] * frac[kk - 1]
    b = travel[act] * frac[kk]
    ga = G[act, kk - 1]
    gb = G[act, kk]
    side = np.zeros(act.size, int)
    x = b.copy()
    # a coarse sample on the root already (|g| within the tolerance: a nominal contact on a
    # perfect machine lies on a sample): that sample. Regula falsi would return the sample
    # itself, which the bracket test rejects, and bisect some 30 times to S_TOL_M.
    at_a = np.abs(ga) < G_TOL_M
    x[at_a] = a[at_a]
    done = at_a | (np.abs(gb) < G_TOL_M)
    for _ in range(max_iter):
        live = np.flatnonzero(~done)
        if live.size == 0:
            break
        al, bl, gal, gbl = a[live], b[live], ga[live], gb[live]
        xl = (al * gbl - bl * gal) / (gbl - gal)
        bad = ~np.isfinite(xl) | (xl <= np.minimum(al, bl)) | (xl >= np.maximum(al, bl))
        xl = np.where(bad, 0.5 * (al + bl), xl)
        gx = g(act[live], xl)
        x[live] = xl
        conv = (np.abs(gx) < G_TOL_M) | (np.abs(bl - al) < S_TOL_M)
        left = gx > 0  # root lies in [x, b]
        # Illinois: halve the function value at the end that stays
        a_new = np.where(left, xl, al)
        ga_new = np.where(left, gx, np.where(side[live] == 1, 0.5 * gal, gal))
        b_new = np.where(left, bl, xl)
        gb_new = np.where(left, np.where(side[live] == -1, 0.5 * gbl, gbl), gx)
        side[live] = np.where(left, -1, 1)
        a[live], b[live], ga[live], gb[live] = a_new, b_new, ga_new, gb_new
        done[live] = conv
    s[act] = x
    return s, status


def _coarse_samples(g, n: int, travel: np.ndarray, frac: np.ndarray, n_first: int) -> np.ndarray:
    """(n, len(frac)) values of ``g`` at ``travel * frac`` on each path: the first ``n_first``
    samples of every path, the rest on the paths where none of those is <= 0 (elsewhere
    +inf: never read, the first crossing lies before them)."""
    k = len(frac)
    G = np.full((n, k), np.inf)
    rows = np.arange(n)
    for cols in (np.arange(n_first), np.arange(n_first, k)):
        if cols.size == 0 or rows.size == 0:
            continue
        idx = np.repeat(rows, cols.size)
        G[np.ix_(rows, cols)] = g(idx, (travel[rows, None] * frac[cols]).ravel()).reshape(rows.size, cols.size)
        rows = rows[~(G[rows, :cols[-1] + 1] <= 0).any(axis=1)]
    return G


def _box_sdf(p: np.ndarray, half: np.ndarray) -> np.ndarray:
    q = np.abs(p) - half
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def solid_sdf(s: Solid) -> Callable[[np.ndarray], np.ndarray]:
    """Signed distance (A frame points, m) of one convex solid (exact except
    outside a mesh's edges, where the plane bound underestimates)."""
    Tinv = inv_T(make_T(s.rot, s.pos))
    if s.kind == "box":
        half = np.asarray(s.size, float)
        return lambda p: _box_sdf(apply_T(Tinv, p), half)
    if s.kind == "sphere":
        c = np.asarray(s.pos, float)
        return lambda p: np.linalg.norm(p - c, axis=1) - s.size[0]
    if s.kind == "cylinder":
        r, h = s.size

        def f(p):
            q = apply_T(Tinv, p)
            dr = np.hypot(q[:, 0], q[:, 1]) - r
            dz = np.abs(q[:, 2]) - h
            return np.hypot(np.maximum(dr, 0), np.maximum(dz, 0)) + np.minimum(np.maximum(dr, dz), 0)
        return f
    from scipy.spatial import ConvexHull

    eq = ConvexHull(np.asarray(s.vertices, float)).equations
    return lambda p: np.max(apply_T(Tinv, p) @ eq[:, :3].T + eq[:, 3], axis=1)


def material_sdf(artefact: Artefact) -> Callable[[np.ndarray], np.ndarray]:
    """Signed distance to the whole true artefact (A frame, m), for free moves.

    Each feature's exact true primitive, intersected with the bounding box
    of its solids (``max`` of the two distances), plus every solid that
    carries no feature; the union is the ``min``. Exact on the features'
    surfaces away from their edges; near edges a lower bound (safe side).
    """
    parts = []
    for f in artefact.features:
        sol = [s for s in artefact.solids if s.feature == f.name]
        prim = f.true
        if sol:
            pts = solids_points(sol)
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            c, half = (lo + hi) / 2, (hi - lo) / 2 + 1e-9
            parts.append(lambda p, prim=prim, c=c, half=half: np.maximum(prim.sdf(p), _box_sdf(p - c, half)))
        else:
            parts.append(prim.sdf)
    for s in artefact.solids:
        if not s.feature:
            parts.append(solid_sdf(s))

    def sdf(p):
        p = np.atleast_2d(p)
        out = np.full(len(p), np.inf)
        for f in parts:
            out = np.minimum(out, f(p))
        return out
    return sdf


# ---------------------------------------------------------------------------
# touches


@dataclass(frozen=True)
class TouchResult:
    """Simulated touches. Frame R for positions, SI units.

    Attributes
    ----------
    pos_R : (n,3) float
        Reported axis positions at the trigger (stylus-tip centre as the
        machine believes it), m; NaN when the status is not ok.
    s_contact_m : (n,) float
        Path length from the start to the first contact, m.
    s_trigger_m : (n,) float
        Path length to the trigger (contact + pre-travel), m.
    t_s : (n,) float
        Time at the trigger, s.
    status : (n,) object
        ``ok``, ``no_trigger`` or ``early_trigger``.
    """

    pos_R: np.ndarray
    s_contact_m: np.ndarray
    s_trigger_m: np.ndarray
    t_s: np.ndarray
    status: np.ndarray


def _feature_by_feature(sdf_A):
    """``(group (m,), p (m,3)) -> (m,)`` calling each distance function on its own points."""
    def dist(gi, p):
        out = np.empty(len(gi))
        for k in np.unique(gi):
            m = gi == k
            out[m] = sdf_A[k](p[m])
        return out
    return dist


def simulate_touches(machine, probe: ProbeConfig, rng: np.random.Generator | None,
                     start_R: np.ndarray, d_R: np.ndarray, travel_m: np.ndarray,
                     rot_rad: np.ndarray | None, t0_s: np.ndarray, feed_mps: np.ndarray,
                     sdf_A: Sequence[Callable[[np.ndarray], np.ndarray]], group: np.ndarray,
                     T_A_W: np.ndarray, d_P: np.ndarray | None = None, n_coarse: int = 7,
                     grouped_sdf: bool = True, J_m: np.ndarray | None = None) -> TouchResult:
    """Simulate ``n`` touch-trigger moves at once.

    Parameters
    ----------
    machine : object with ``tip_W(lin_m, rot_rad, t_s, direction)``
    probe : ProbeConfig
    rng : np.random.Generator or None
        Source of the repeatability noise (None: no noise).
    start_R : (n,3) float
        Commanded axis positions at the start of each approach, R, m.
    d_R : (n,3) float
        Unit commanded approach direction in axis space, R.
    travel_m : (n,) float
        Longest approach before ``no_trigger``, m.
    rot_rad : (n,k) float or None
        Rotary axis positions (held during the touch), rad.
    t0_s : (n,) float
        Time at the start of each approach, s.
    feed_mps : (n,) float
        Probing feed, m/s.
    sdf_A : sequence of callables
        True signed distance functions, A-frame points (m,3) -> (m,), m.
    group : (n,) int
        Which ``sdf_A`` each touch probes.
    T_A_W : (n,4,4) float
        True pose of W in A (inverse of the true placement ``T_W_A``).
    d_P : (n,3) float, optional
        Approach direction in the probe frame (default ``d_R``).
    n_coarse : int
        Samples per path bracketing the first contact (default 7: 0.5 mm
        apart on the default 3 mm travel, far below the stylus radius).
    grouped_sdf : bool
        Evaluate the distances of all touches in one pass per primitive kind
        (:class:`sim.artefacts.GroupedSdf`, default) or feature by feature (the
        path before issue 19, kept as the reference of the bench and tests).
    J_m : (n, 3) float, optional
        Each touch's probe offsets (its stylus on ``machine``: ``Machine.tip_W``'s
        ``J_m``), m; default the machine's own.
    """
    start_R = np.asarray(start_R, float)
    n = len(start_R)
    d_R = np.asarray(d_R, float)
    t0 = np.broadcast_to(np.asarray(t0_s, float), (n,))
    feed = np.broadcast_to(np.asarray(feed_mps, float), (n,))
    group = np.asarray(group, int)
    r = probe.stylus_r_m
    rot = None if rot_rad is None else np.asarray(rot_rad, float)
    dist = GroupedSdf(sdf_A) if grouped_sdf else _feature_by_feature(sdf_A)
    J = None if J_m is None else np.broadcast_to(np.asarray(J_m, float), (n, 3))

    def g(idx, s):
        lin = start_R[idx] + s[:, None] * d_R[idx]
        p_W = tip_W(machine, lin, None if rot is None else rot[idx], t0[idx] + s / feed[idx], d_R[idx],
                    None if J is None else J[idx])
        p_A = apply_T(T_A_W[idx], p_W)
        return dist(group[idx], p_A) - r

    # the last sample only where no crossing is bracketed before it (a campaign's nominal
    # contact lies at two thirds of the travel): the same result, 1/7 fewer evaluations
    s_c, status = find_contacts(g, n, travel_m, n_coarse=n_coarse, n_first=n_coarse - 1)
    ok = status == ProbeStatus.OK
    delta = probe.pretravel(d_R if d_P is None else d_P, feed)
    s_t = np.where(ok, s_c + delta, np.nan)
    pos = start_R + s_t[:, None] * d_R
    if rng is not None and probe.sigma_m > 0:
        pos = pos + (probe.sigma_m * rng.standard_normal(n))[:, None] * d_R
    pos[~ok] = np.nan
    return TouchResult(pos, s_c, s_t, t0 + np.where(ok, s_t, 0.0) / feed, status)


class VirtualMachine:
    """A machine, artefacts and a probe behind ``probe_move`` (for the emulator).

    Parameters
    ----------
    machine : object with ``tip_W``
    artefacts : Artefact or sequence of Artefact or of (Artefact, T_W_A)
        What stands on the table (default placement when none is given).
    probe : ProbeConfig
    rng : np.random.Generator
    feed_mps : float
        Probing feed, m/s (default 240 mm/min).
    """

    def __init__(self, machine, artefacts, probe: ProbeConfig | None = None,
                 rng: np.random.Generator | None = None, feed_mps: float = 0.004):
        if isinstance(artefacts, Artefact) or (isinstance(artefacts, tuple) and len(artefacts) == 2
                                               and isinstance(artefacts[0], Artefact)):
            artefacts = [artefacts]
        self.machine = machine
        self.probe = probe or ProbeConfig()
        self.rng = rng
        if not (np.isfinite(feed_mps) and feed_mps > 0):
            raise ConfigError(f"feed_mps must be positive, got {feed_mps!r}")
        self.feed_mps = float(feed_mps)
        self.t_s = 0.0
        self._sdf, self._T_A_W = [], []
        for a in artefacts:
            art, T = (a, a.T_W_A) if isinstance(a, Artefact) else a
            self._sdf.append(material_sdf(art))
            self._T_A_W.append(inv_T(np.asarray(T, float)))

    def _clearance(self, idx, lin, rot, t, d):
        p_W = tip_W(self.machine, lin, rot, t, d)
        out = np.full(len(lin), np.inf)
        for f, T in zip(self._sdf, self._T_A_W):
            out = np.minimum(out, f(apply_T(T, p_W)))
        return out - self.probe.stylus_r_m

    def probe_move(self, start_m, target_m, rot_rad=None) -> tuple[bool, np.ndarray]:
        """Move linearly in axis space from ``start_m`` towards ``target_m`` (R, m).

        Returns ``(True, scale position at the trigger)`` or
        ``(False, target_m)`` when no surface is met on the way.
        """
        start = np.asarray(start_m, float).reshape(3)
        target = np.asarray(target_m, float).reshape(3)
        L = float(np.linalg.norm(target - start))
        if not np.isfinite(L):
            raise ConfigError("probe_move: start_m and target_m must be finite")
        if L == 0:
            return False, target.copy()
        d = (target - start) / L
        rot = None if rot_rad is None else np.atleast_2d(np.asarray(rot_rad, float))
        t0 = self.t_s

        def g(idx, s):
            lin = start + s[:, None] * d
            rr = None if rot is None else np.repeat(rot, len(s), axis=0)
            return self._clearance(idx, lin, rr, t0 + s / self.feed_mps, np.broadcast_to(d, lin.shape))

        n_coarse = int(min(2001, max(13, np.ceil(L / 0.5e-3) + 1)))
        s, status = find_contacts(g, 1, np.array([L]), n_coarse=n_coarse)
        if status[0] != ProbeStatus.OK:
            self.t_s += L / self.feed_mps
            if status[0] == ProbeStatus.EARLY_TRIGGER:
                return True, start.copy()
            return False, target.copy()
        st = s[0] + float(self.probe.pretravel(d[None], self.feed_mps)[0])
        pos = start + st * d
        if self.rng is not None and self.probe.sigma_m > 0:
            pos = pos + self.probe.sigma_m * self.rng.standard_normal() * d
        self.t_s += st / self.feed_mps
        return True, pos
