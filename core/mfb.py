"""Multi-feature bar: points of interest, the bar frame R_MFB, orientation, reversal.

Viprey et al. 2016 (shared/papers/viprey2016-multi-feature-bar.txt):

- section 2.1: from the touches of one placement, ``AXIS_i`` of every hole
  (least-squares cylinder, App. A), ``AXIS_j`` of every rod (cylinder),
  the faces ``PL_Lj``, ``PL_Rj`` (least-squares planes, App. B), the points
  ``P_Lj``, ``P_Rj`` where a rod axis crosses its faces, the plane ``PL_i``
  through the four points of the two rods around hole i and the point of
  interest ``O_i = AXIS_i ∩ PL_i`` (:func:`points_of_interest`);
- the bar frame ``R_MFB``: ``z`` the normal of ``PL_ref`` (through the
  P points of the first and last rods), oriented towards the probed side;
  ``O_1``, ``O_N`` where the first and last hole axes meet ``PL_ref``;
  ``x`` along ``O_1 O_N``; ``y = z ^ x``;
- section 2.2: the mistake-proofing holes (2 and 5, shifted +1.5 mm in y)
  tell whether the bar is reversed (:func:`detect_orientation`);
- section 3, eqs 5-7: reversal calibration of the bar's straightness on a
  CMM and positioning by substitution against a step gauge
  (:func:`reversal_calibration`).

Frames: R machine reference (the points are the reported stylus-tip
centres, i.e. the machine's belief), M the bar frame R_MFB, A the bar's own
design frame (origin on hole 1's axis in the plane of the rod axes; the
nominal ``O_i`` in A are ``((i-1) L, shift_i, 0)``, eq. 3 plus the
mistake-proofing shifts).

The stylus radius needs no correction: hole and rod axes are the axes of
the stylus-centre cylinders, and the face planes (offset by the radius)
only slide ``P_L``/``P_R`` along the rod axes, which leaves ``PL_i`` (the
plane of two rod axes) unchanged. Units: SI (m, rad).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .exceptions import ConfigError, FitError
from .fit import cylinder_point_axis, cylinders_point_axis, plane_point_normal, planes_point_normal
from .units import MM


class OrientationError(ConfigError):
    """The bar's orientation read from its shifted holes is not the declared one."""


@dataclass(frozen=True)
class BarGeometry:
    """Design of a multi-feature bar (section 2.2).

    Attributes
    ----------
    n_holes : int
        N holes (N - 1 rods).
    pitch_m : float
        L, m.
    shifted : tuple of (int, float)
        Mistake-proofing: 1-based hole index -> design shift in y_A, m.
    """

    n_holes: int = 12
    pitch_m: float = 0.050
    shifted: tuple = ((2, 1.5 * MM), (5, 1.5 * MM))

    def __post_init__(self):
        if int(self.n_holes) != self.n_holes or self.n_holes < 3:
            raise ConfigError(f"BarGeometry.n_holes must be an integer >= 3, got {self.n_holes!r}")
        if not (np.isfinite(self.pitch_m) and self.pitch_m > 0):
            raise ConfigError(f"BarGeometry.pitch_m must be > 0, got {self.pitch_m!r}")

    def shift_of(self, i: int) -> float:
        return dict(self.shifted).get(int(i), 0.0)

    def O_A(self, holes=None) -> np.ndarray:
        """(k, 3) nominal points of interest in the design frame A, m (eq. 3 + shifts)."""
        holes = range(1, self.n_holes + 1) if holes is None else holes
        return np.array([[(i - 1) * self.pitch_m, self.shift_of(i), 0.0] for i in holes], float)


MFB = BarGeometry()

#: Orientations of a bar relative to the declared one, and the rotation (in A)
#: that maps the declared pose to it: ``normal``; ``upside-down`` (turned 180
#: deg about x_A: the reversal of eqs 5-6); ``turned`` (180 deg about z_A:
#: end for end); ``turned-upside-down`` (180 deg about y_A).
ORIENTATIONS = ("normal", "upside-down", "turned", "turned-upside-down")


def expected_shifts(geom: BarGeometry, orientation: str) -> dict:
    """Hole label (1-based, as probed) -> expected y_M offset, m, for ``orientation``."""
    N = geom.n_holes
    out = {}
    for i, s in geom.shifted:
        if orientation == "normal":
            out[i] = s
        elif orientation == "upside-down":
            out[i] = -s
        elif orientation == "turned":
            out[N + 1 - i] = -s
        elif orientation == "turned-upside-down":
            out[N + 1 - i] = s
        else:
            raise ConfigError(f"unknown bar orientation {orientation!r}; expected one of {', '.join(ORIENTATIONS)}")
    return out


@dataclass(frozen=True)
class BarFeatures:
    """Associated features of one placement (frame of the points, R).

    Attributes
    ----------
    hole_point, hole_axis : dict hole index -> (3,) float
        A point of AXIS_i (m) and its unit direction.
    rod_point, rod_axis : dict rod index -> (3,) float
    face_point, face_normal : dict (side, rod index) -> (3,) float
        side ``"L"`` or ``"R"``.
    probe_side : (3,) float
        Mean outward normal of the rod touches (the probed side of the bar).
    """

    hole_point: dict
    hole_axis: dict
    rod_point: dict
    rod_axis: dict
    face_point: dict
    face_normal: dict
    probe_side: np.ndarray = field(compare=False)


@dataclass(frozen=True)
class PointsOfInterest:
    """Points of interest of one placement (section 2.1).

    Attributes
    ----------
    holes : tuple of int
        1-based hole labels, as probed.
    O_R : (k, 3) float
        O_i in the frame of the touches (machine frame R, readings), m.
    O_M : (k, 3) float
        O_i in the bar frame R_MFB, m.
    T_R_M : (4, 4) float
        Pose of R_MFB in R (origin O_a, the first unshifted hole used).
    frame_holes : (int, int)
        The holes whose axes define the origin and x_M.
    orientation : str
        One of :data:`ORIENTATIONS`, read from the shifted holes.
    shifted_found : dict hole -> float
        Holes whose |y_M| exceeds half the design shift, with their y_M, m.
    """

    holes: tuple
    O_R: np.ndarray
    O_M: np.ndarray
    T_R_M: np.ndarray
    frame_holes: tuple
    orientation: str
    shifted_found: dict


def _num(name: str, prefix: str) -> int | None:
    if not name.startswith(prefix):
        return None
    tail = name[len(prefix):]
    return int(tail) if tail.isdigit() else None


def _axis_hint(normals: np.ndarray) -> np.ndarray:
    """Direction perpendicular to all the touch normals of a cylinder (smallest singular vector)."""
    _, _, Vt = np.linalg.svd(np.asarray(normals, float))
    return Vt[-1]


def _meet(p, d, q, n) -> np.ndarray:
    """Intersection of the line (p, d) with the plane (q, n)."""
    den = float(d @ n)
    if abs(den) < 1e-9:
        raise FitError("MFB: a feature axis is parallel to the plane it must cross")
    return p + (float((q - p) @ n) / den) * d


def _group(feature) -> dict:
    out: dict = {}
    for k, f in enumerate(np.asarray(feature, dtype=object)):
        out.setdefault(str(f), []).append(k)
    return {f: np.asarray(v) for f, v in out.items()}


def fit_bar_features(p_R, feature, n_R, *, fits: dict | None = None) -> BarFeatures:
    """Least-squares features of one placement (cylinders App. A, planes App. B).

    Parameters
    ----------
    p_R : (n, 3) float
        Reported stylus-tip centres, m.
    feature : (n,) str
        Feature id per touch: ``holeNN``, ``rodNN``, ``faceLNN``, ``faceRNN``
        (others ignored).
    n_R : (n, 3) float
        Nominal outward normals (used for the axis hints and the probed side).
    fits : dict, optional
        Kept by the caller across calls: a feature whose touches and hint were
        fitted before is taken from it, and a cylinder's axis hint found before
        for the same normals (the same numbers, bit for bit; ``fits`` of
        :func:`poi_noise_gain`).

    Each feature by the validated single fits (:func:`core.fit.cylinder_point_axis`,
    :func:`core.fit.plane_point_normal`: coincident or collinear points refused by
    name). Touches known good (simulated, each checked to trigger on its target) may
    be fitted in batches instead, :func:`points_of_interest_batched`.
    """
    p_R, n_R = _checked_touches(p_R, feature, n_R)
    feats, side = _sorted_features(feature, n_R, fits)
    out = {"hole": ({}, {}), "rod": ({}, {}), "face": ({}, {})}
    for kind, key, idx, hint, f in feats:
        try:
            out[kind][0][key], out[kind][1][key] = _fit_once(fits, "plane" if kind == "face" else "cylinder",
                                                             p_R[idx], hint)
        except FitError as e:
            raise FitError(f"MFB feature {f!r}: {e}") from None
    return BarFeatures(*out["hole"], *out["rod"], *out["face"], side)


def _classify(feature):
    """The features of one placement's touches, in the order met: ``(kind "hole" | "rod" | "face",
    key: the hole's or rod's number or (side "L" | "R", rod number), touch indices, name)`` for the
    names ``holeNN``, ``rodNN``, ``faceLNN``, ``faceRNN`` (others ignored)."""
    for f, idx in _group(feature).items():
        if (i := _num(f, "hole")) is not None:
            yield "hole", i, idx, f
        elif (j := _num(f, "rod")) is not None:
            yield "rod", j, idx, f
        elif f[:5] in ("faceL", "faceR") and (j := _num(f[5:], "")) is not None:
            yield "face", (f[4], j), idx, f


def _sorted_features(feature, n_R, hints: dict | None = None) -> tuple[list, np.ndarray]:
    """:func:`_classify` with each feature's hint, ``[(kind, key, touch indices, hint, name)]``
    (a cylinder's axis from its normals, :func:`_axis_hint`, a face's mean normal), and the probed
    side (mean outward normal of the rod touches). ``hints``: axis hints already found, by the
    bytes of the normals (placements of one orientation, or the plans of one campaign, share their
    nominal normals: the same numbers), and new ones added."""
    def axis_hint(nrm):
        if hints is None:
            return _axis_hint(nrm)
        key = ("axis hint", nrm.tobytes())
        if key not in hints:
            hints[key] = _axis_hint(nrm)
            hints[key].setflags(write=False)  # shared by every later lookup
        return hints[key]

    out, rod_normals = [], []
    for kind, key, idx, f in _classify(feature):
        if kind == "face":
            out.append((kind, key, idx, n_R[idx].mean(axis=0), f))
        else:
            out.append((kind, key, idx, axis_hint(n_R[idx]), f))
            if kind == "rod":
                rod_normals.append(n_R[idx])
    return out, (np.concatenate(rod_normals).mean(axis=0) if rod_normals else np.zeros(3))


def _checked_touches(p_R, feature, n_R) -> tuple:
    """(p_R, n_R) as float arrays, refused by name unless (n, 3), (n,) and finite."""
    p_R = np.asarray(p_R, float)
    n_R = np.asarray(n_R, float)
    if p_R.ndim != 2 or p_R.shape[1] != 3 or n_R.shape != p_R.shape or len(feature) != len(p_R):
        raise ConfigError(f"MFB features: p_R, n_R must be (n, 3) and feature (n,), got "
                          f"{p_R.shape}, {n_R.shape}, {len(feature)}")
    if not np.all(np.isfinite(p_R)):
        raise ConfigError("MFB features: p_R holds non-finite positions (drop invalid touches first)")
    return p_R, n_R


def _fit_placements_batched(placements) -> list[BarFeatures]:
    """:func:`fit_bar_features` of several placements ``[(p_R, feature, n_R)]`` by the light batched
    fits (:func:`core.fit.cylinders_point_axis`, :func:`core.fit.planes_point_normal`: the same
    iteration per feature, the same answer to rounding, not bit for bit, without the single fits'
    checks: touches known good only). The features of all placements that share a kind, a touch
    count and a hint (the same bits: the placements of one orientation) are fitted in one call.
    Each set's iteration is its own (the batched fits update a set only while it is active), so
    every feature gets the numbers its placement alone gives, bit for bit (tests/core/test_mfb.py).
    A fit error is raised as the first placement alone raises it."""
    placements = [_checked_touches(p, f, n) + (f,) for p, f, n in placements]
    groups: dict = {}  # (kind, touches, hint bytes) -> [(placement, key, idx, hint, feature)]
    sides, hints = [], {}
    for k, (p_R, n_R, feature) in enumerate(placements):
        feats, side = _sorted_features(feature, n_R, hints)
        for kind, key, idx, hint, f in feats:
            groups.setdefault((kind, len(idx), hint.tobytes()), []).append((k, key, idx, hint, f))
        sides.append(side)
    out = [{"hole": ({}, {}), "rod": ({}, {}), "face": ({}, {})} for _ in placements]
    for (kind, _, _), items in groups.items():
        pts = np.stack([placements[k][0][idx] for k, _, idx, _, _ in items])
        hint = items[0][3]
        try:
            if kind == "face":
                pt, ax = planes_point_normal(pts, normal_hint=hint)
            else:
                pt, ax = cylinders_point_axis(pts, axis_hint=hint)
        except FitError as e:
            if len(placements) > 1:  # name the features as the placement's own batch does
                for p_R, n_R, feature in placements:
                    _fit_placements_batched([(p_R, feature, n_R)])
            raise FitError(f"MFB features {', '.join(f for *_, f in items)}: {e}") from None
        for b, (k, key, *_) in enumerate(items):
            out[k][kind][0][key], out[k][kind][1][key] = pt[b], ax[b]
    return [BarFeatures(*o["hole"], *o["rod"], *o["face"], side) for o, side in zip(out, sides)]


def _rod_points(bf: BarFeatures, j: int) -> np.ndarray:
    pts = []
    for s in ("L", "R"):
        if (s, j) not in bf.face_point:
            raise FitError(f"MFB: rod {j} has no face{s}{j:02d} touches (P_{s}{j} undefined)")
        pts.append(_meet(bf.rod_point[j], bf.rod_axis[j], bf.face_point[(s, j)], bf.face_normal[(s, j)]))
    return np.array(pts)


def _rod_pair(i: int, rods: set) -> tuple[int, int]:
    """Rods (j-1, j) around hole i (end holes: the two nearest rods)."""
    cands = [(i - 1, i), (i, i + 1), (i - 2, i - 1)]
    for a, b in cands:
        if a in rods and b in rods:
            return a, b
    raise FitError(f"MFB: hole {i} has no two neighbouring rods measured (PL_{i} undefined)")


def rod_height_map(geom: BarGeometry = MFB) -> np.ndarray:
    """(N, N - 1) how the points of interest's heights follow the rods': ``z(O_i) = W @ h``.

    ``h`` the heights (z_A) of rods 1..N-1, rod j's axis at x_A = (j - 1/2) L; ``PL_i`` passes
    through the rods around hole i (:func:`_rod_pair`: (i-1, i), the end holes' two nearest) and
    O_i is read on it at x_A = (i - 1) L (section 2.1): the two rods' mean for an inner hole,
    1.5 / -0.5 for an end hole. N heights from N - 1 rods: one combination of the O_i's heights
    (alternating in sign) is no shape a bar can take, and no calibration of it can err that way.
    """
    N = geom.n_holes
    rods = set(range(1, N))
    W = np.zeros((N, N - 1))
    for i in range(1, N + 1):
        a, b = _rod_pair(i, rods)
        t = ((i - 1) - (a - 0.5)) / (b - a)  # hole i's place between rods a and b (0 at a, 1 at b)
        W[i - 1, a - 1], W[i - 1, b - 1] = 1.0 - t, t
    return W


def calibration_map(geom: BarGeometry = MFB) -> np.ndarray:
    """(3N, 3N) how a bar calibration's errors reach its points of interest
    (``cal_map`` of :func:`core.volumetric.uncertainty`): the points' (x, y, z) deviations, point
    by point, are off by ``calibration_map() @ (u_cal.ravel() * n)``, n independent standard normal.

    x and y as declared, one independent error per point; the heights projected onto the ones
    the rods can give (``P = W W^+``, :func:`rod_height_map`): a calibration that derives O_i from
    the rods (the paper's, and the reversal on a CMM) errs only in the heights a bar can have,
    and the simulated bar is built so (``sim.artefacts.multi_feature_bar``). For N = 12: 0.99
    of the declared variance at holes 1 and 12, 0.94 at 2 and 11, 0.89 at 3-10, neighbours
    correlated, none in the alternating combination; taken as independent, that combination
    (which 9 nodes over 12 holes hardly tell from EZX) made the 3-axis plan's calibration
    share of EZX's first free node 4.01 um U95 where the bar's draws give 3.65 (the plan before
    session 10, its bars in the table; on today's plan the linear share is 3.82 um taken as
    independent against 3.42 projected, seed 1).
    """
    N = geom.n_holes
    W = rod_height_map(geom)
    M = np.eye(3 * N)
    iz = 3 * np.arange(N) + 2
    M[np.ix_(iz, iz)] = W @ np.linalg.pinv(W)
    return M


def poi_from_features(bf: BarFeatures, geom: BarGeometry = MFB, *, batched: bool = False) -> PointsOfInterest:
    """Points of interest and R_MFB from fitted features (section 2.1). ``batched``: the
    planes PL_i of all holes in one call (:func:`core.fit.planes_point_normal`, to rounding;
    without the single fit's checks: for features known good, :func:`points_of_interest_batched`)."""
    rods = set(bf.rod_point)
    holes = sorted(bf.hole_point)
    if len(holes) < 2 or len(rods) < 2:
        raise FitError(f"MFB: need at least 2 holes and 2 rods, got {len(holes)} and {len(rods)}")
    P = {j: _rod_points(bf, j) for j in sorted(rods)}
    pairs = [_rod_pair(i, rods) for i in holes]
    if batched:
        qs, ns = planes_point_normal(np.stack([np.vstack([P[a], P[b]]) for a, b in pairs]),
                                     normal_hint=bf.probe_side)
    else:
        qs, ns = zip(*(plane_point_normal(np.vstack([P[a], P[b]]), normal_hint=bf.probe_side) for a, b in pairs))
    O_R = np.array([_meet(bf.hole_point[i], bf.hole_axis[i], q, n) for i, q, n in zip(holes, qs, ns)])
    # R_MFB: PL_ref through the P points of the first and last rods
    j0, j1 = min(rods), max(rods)
    ref_point, z = plane_point_normal(np.vstack([P[j0], P[j1]]),
                                      normal_hint=bf.probe_side if np.any(bf.probe_side) else None)
    shifted = {i for i, _ in geom.shifted} | {geom.n_holes + 1 - i for i, _ in geom.shifted}
    plain = [i for i in holes if i not in shifted] or holes
    ia, ib = plain[0], plain[-1]
    if ia == ib:
        ia, ib = holes[0], holes[-1]
    Oa = _meet(bf.hole_point[ia], bf.hole_axis[ia], ref_point, z)
    Ob = _meet(bf.hole_point[ib], bf.hole_axis[ib], ref_point, z)
    x = (Ob - Oa) / np.linalg.norm(Ob - Oa)
    y = np.cross(z, x)
    R = np.column_stack([x, y, z])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, Oa
    O_M = (O_R - Oa) @ R
    O_M[:, 0] += (ia - 1) * geom.pitch_m  # x_M counted from hole 1's nominal place
    orient, found = detect_orientation(O_M, holes, geom)
    return PointsOfInterest(tuple(holes), O_R, O_M, T, (ia, ib), orient, found)


def points_of_interest(p_R, feature, n_R, geom: BarGeometry = MFB, declared: str | None = None) -> PointsOfInterest:
    """O_i of one placement from its touches (Viprey 2016, section 2.1).

    Parameters
    ----------
    p_R : (n, 3) float
        Reported stylus-tip centres of the touches of ONE placement, m.
    feature : (n,) str
        Feature ids (probe-log ``feature`` column).
    n_R : (n, 3) float
        Nominal outward normals, R.
    geom : BarGeometry
    declared : str, optional
        Declared orientation; if given and the shifted holes say otherwise,
        :class:`OrientationError` names them.

    Returns
    -------
    PointsOfInterest
    """
    poi = poi_from_features(fit_bar_features(p_R, feature, n_R), geom)
    if declared is not None:
        check_orientation(poi.orientation, poi.shifted_found, declared, geom)
    return poi


def points_of_interest_batched(placements, geom: BarGeometry = MFB) -> list[PointsOfInterest]:
    """:func:`points_of_interest` of several placements ``[(p_R, feature, n_R)]`` by the light batched
    fits, their features fitted together (:func:`_fit_placements_batched`: each placement's numbers
    as it alone gives them, bit for bit; the single path's to rounding; touches known good only,
    e.g. a campaign's simulated touches each checked to trigger)."""
    return [poi_from_features(bf, geom, batched=True) for bf in _fit_placements_batched(placements)]


def detect_orientation(O_M, holes, geom: BarGeometry = MFB) -> tuple[str, dict]:
    """Orientation of the bar from the y_M offsets of its holes (section 2.2).

    Returns the orientation in :data:`ORIENTATIONS` whose pattern of shifted
    holes matches, and the holes found shifted (|y_M| above half the
    smallest design shift) with their y_M. ``"unknown"`` when none matches.
    """
    O_M = np.asarray(O_M, float)
    thr = 0.5 * min(abs(s) for _, s in geom.shifted)
    found = {int(i): float(O_M[k, 1]) for k, i in enumerate(holes) if abs(O_M[k, 1]) > thr}
    hs = set(int(h) for h in holes)
    for o in ORIENTATIONS:
        exp = {i: s for i, s in expected_shifts(geom, o).items() if i in hs}
        if set(exp) == set(found) and all(np.sign(exp[i]) == np.sign(found[i]) for i in exp) and exp:
            return o, found
    return "unknown", found


def _fmt_found(found: dict) -> str:
    if not found:
        return "no hole is shifted"
    return ", ".join(f"hole {i} at y_M {v / MM:+.3f} mm" for i, v in sorted(found.items()))


def check_orientation(orientation: str, found: dict, declared: str, geom: BarGeometry = MFB) -> None:
    """Raise :class:`OrientationError` naming the shifted holes when ``orientation != declared``."""
    if declared not in ORIENTATIONS:
        raise ConfigError(f"declared orientation {declared!r} is not one of {', '.join(ORIENTATIONS)}")
    if orientation != declared:
        exp = expected_shifts(geom, declared)
        want = ", ".join(f"hole {i} {s / MM:+.1f} mm" for i, s in sorted(exp.items()))
        raise OrientationError(
            f"bar declared {declared} (expects {want}) but the shifted holes read {orientation}: {_fmt_found(found)}")


# --------------------------------------------------------------------------- noise gain
def _meet_batch(p, d, q, n) -> np.ndarray:
    """:func:`_meet` for (b, 3) lines and planes (either side may be one (3,) line or plane)."""
    den = np.einsum("...j,...j->...", d, n)
    if np.any(np.abs(den) < 1e-9):
        raise FitError("MFB: a feature axis is parallel to the plane it must cross")
    return p + (np.einsum("...j,...j->...", q - p, n) / den)[..., None] * d


#: The fits :func:`_fit_once` may keep: kind -> (function, name of its hint argument).
_FITS = {"cylinder": (cylinder_point_axis, "axis_hint"), "plane": (plane_point_normal, "normal_hint"),
         "cylinders": (cylinders_point_axis, "axis_hint"), "planes": (planes_point_normal, "normal_hint")}


def _fit_once(fits: dict | None, kind: str, pts: np.ndarray, hint: np.ndarray) -> tuple:
    """``fit(pts, hint)`` of :data:`_FITS` ``[kind]``, looked up first in ``fits`` (None: no
    lookup) by the exact bytes of its inputs: the fits are pure functions, so a point set met
    again (the same touches in another plan of a campaign) gives the same numbers, bit for bit."""
    fit, arg = _FITS[kind]
    if fits is None:
        return fit(pts, **{arg: hint})
    hint = np.asarray(hint, float)
    key = (kind, pts.shape, pts.tobytes(), hint.tobytes())
    out = fits.get(key)
    if out is None:
        out = fit(pts, **{arg: hint})
        for a in out:
            a.setflags(write=False)  # shared by every later lookup
        fits[key] = out
    return out


def poi_noise_gain(p_R, feature, n_R, d_R, geom: BarGeometry = MFB, h_m: float = 1e-7, *,
                   fits: dict | None = None) -> np.ndarray:
    """d O_R / d e: change of the points of interest per touch displacement along d, (3k, n).

    Central differences (step ``h_m`` along each touch's approach direction
    ``d_R``), refitting only the feature the touch belongs to and
    recomputing only the O_i it enters (its hole's, or those whose plane
    PL_i uses its rod; the others' differences are exactly zero): exact to
    ~(h/R)^2 and the fits' convergence (1e-9 relative), so that a rigid
    motion of all touches moves the points rigidly (``G`` keeps the exact
    gauge freedoms of :mod:`core.volumetric`). Used for the touch model of
    the identification and for the propagation of the probing noise.

    The 2 n perturbed fits of a feature run as one batch (the light fits of
    :mod:`core.fit`: :func:`~core.fit.cylinders_point_axis`,
    :func:`~core.fit.planes_point_normal`, no covariance); the features of
    the unperturbed touches are checked once, by the full fits
    (:func:`fit_bar_features`, :func:`poi_from_features`).

    ``fits``: a dict the caller keeps across calls (e.g. the plans of one
    campaign, whose hole sets share their features' touches): each batch of
    perturbed sets already fitted is taken from it (same inputs bit for bit,
    same numbers) and each new one added.
    """
    p_R = np.asarray(p_R, float)
    d_R = np.asarray(d_R, float)
    n_R = np.asarray(n_R, float)
    feature = np.asarray(feature, dtype=object)
    if d_R.shape != p_R.shape or not np.all(np.isfinite(d_R)):
        raise ConfigError(f"MFB noise gain: d_R must be finite and shaped as p_R {p_R.shape}, got {d_R.shape}")
    bf = fit_bar_features(p_R, feature, n_R, fits=fits)
    holes = poi_from_features(bf, geom).holes  # validates the set (holes, rods, faces)
    rods = set(bf.rod_point)
    pair = {i: _rod_pair(i, rods) for i in holes}
    row = {i: k for k, i in enumerate(holes)}
    P = {j: _rod_points(bf, j) for j in sorted({j for i in holes for j in pair[i]})}
    PL = {i: plane_point_normal(np.vstack([P[pair[i][0]], P[pair[i][1]]]), normal_hint=bf.probe_side,
                                validate=False) for i in holes}
    base = {i: _meet(bf.hole_point[i], bf.hole_axis[i], *PL[i]) for i in holes}
    G = np.zeros((3 * len(holes), len(p_R)))
    planes = []  # (touches, hole h, perturbed point sets of PL_h) of the rods and faces
    for kind, key, idx, _ in _classify(feature):
        if kind == "hole":
            i = key
            hs = [i] if i in row else []
        else:
            sd, j = key if kind == "face" else (None, key)  # a face's key: (side, rod number)
            hs = [h for h in holes if j in pair[h]]
        if not hs:
            continue
        # the 2 n perturbed point sets of this feature: touch k moved by +h, then -h, along d
        nk = len(idx)
        Q = np.broadcast_to(p_R[idx], (2 * nk, nk, 3)).copy()
        step = h_m * d_R[idx]
        Q[2 * np.arange(nk), np.arange(nk)] += step
        Q[2 * np.arange(nk) + 1, np.arange(nk)] -= step
        if kind == "hole":
            q, a = _fit_once(fits, "cylinders", Q, bf.hole_axis[i])
            _gain_rows(G, 3 * row[i], idx, _meet_batch(q, a, *PL[i]) - base[i], h_m)
        else:
            Pj = np.broadcast_to(P[j], (2 * nk, 2, 3)).copy()
            if kind == "rod":
                q, a = _fit_once(fits, "cylinders", Q, bf.rod_axis[j])
                for k, side in enumerate("LR"):
                    Pj[:, k] = _meet_batch(q, a, bf.face_point[(side, j)], bf.face_normal[(side, j)])
            else:
                q, nrm = _fit_once(fits, "planes", Q, bf.face_normal[key])
                Pj[:, "LR".index(sd)] = _meet_batch(bf.rod_point[j], bf.rod_axis[j], q, nrm)
            for h in hs:
                a, c = pair[h]
                planes.append((idx, h, np.concatenate([Pj if a == j else np.broadcast_to(P[a], Pj.shape),
                                                       Pj if c == j else np.broadcast_to(P[c], Pj.shape)], axis=1)))
    if planes:  # every perturbed plane PL_h in one batch (they share the hint)
        q, nrm = planes_point_normal(np.concatenate([pts for *_, pts in planes]), normal_hint=bf.probe_side)
        at = 0
        for idx, h, pts in planes:
            b = slice(at, at + len(pts))
            at += len(pts)
            _gain_rows(G, 3 * row[h], idx, _meet_batch(bf.hole_point[h], bf.hole_axis[h], q[b], nrm[b]) - base[h], h_m)
    return G


def _gain_rows(G, r0: int, idx, dO, h_m: float) -> None:
    """G[r0:r0 + 3, idx] from the shifts dO (2 n, 3) of a point of interest, +h then -h of each touch."""
    dO = dO / (2.0 * h_m)
    G[r0:r0 + 3, idx] = (dO[0::2] - dO[1::2]).T


# --------------------------------------------------------------------------- reversal (eqs 5-7)
def align_on_cmm(O_R, z_R, *, roll: bool = True) -> np.ndarray:
    """The points of interest of one placement as the CMM's alignment on the bar gives them
    to the reversal (:func:`reversal_calibration`): O_1 at the origin; the roll about the
    CMM's X taken out so that the bar's own z (``z_R``: the normal of PL_ref, R_MFB's z_M in
    the CMM frame, :attr:`PointsOfInterest.T_R_M` ``[:3, 2]``; +Z or -Z as the bar lies
    normal or upside-down) has no Y component; then y and z against the line O_1 O_N.

    Why the roll: holes 2 and 5 are shifted 1.5 mm in y (mistake-proofing); a roll phi of
    the bar about its axis moves them 1.5 mm x phi in z. A roll common to both orientations
    does not cancel in eq. 6 (it stays as bar form: 0.75 um at holes 2 and 5 for 0.5 mrad,
    review31b F1) and the line O_1 O_N does not see it (the unshifted holes lie on the axis).
    The rods' axes do: PL_ref passes through two of them, across the bar. A CMM roll (its
    X carriage's EAX) is taken out with it as far as it is common to the two end rods.
    ``roll=False``: the line alone (the alignment before session 31).

    Parameters
    ----------
    O_R : (N, 3) float
        O_i in the CMM frame, m.
    z_R : (3,) float
        The bar's z_M in the CMM frame (unit or not; its Y, Z components give the roll).

    Returns
    -------
    (N, 3) float, m.
    """
    O = np.asarray(O_R, float)
    z = np.asarray(z_R, float)
    if O.ndim != 2 or O.shape[1] != 3 or len(O) < 2 or not np.all(np.isfinite(O)):
        raise ConfigError(f"align_on_cmm: O_R must be finite (N >= 2, 3), got {O.shape}")
    if z.shape != (3,) or not np.all(np.isfinite(z)) or abs(z[2]) <= abs(z[1]):
        raise ConfigError(f"align_on_cmm: z_R must be the bar's z within 45 deg of the CMM's +-Z, got {z_R!r}")
    O = O - O[0]
    if roll:
        s = np.sign(z[2])
        phi = np.arctan2(-s * z[1], s * z[2])  # z_M = Rx(phi) (0, 0, s)
        c, q = np.cos(phi), np.sin(phi)
        O = O @ np.array([[1.0, 0.0, 0.0], [0.0, c, q], [0.0, -q, c]]).T  # Rx(-phi)
    if O[-1, 0] == 0.0:
        raise ConfigError("align_on_cmm: O_1 and O_N at the same x")
    O[:, 1:] -= np.outer(O[:, 0] / O[-1, 0], O[-1, 1:])
    return O


def step_gauge_u_m(L_m) -> np.ndarray:
    """Standard uncertainty of the step gauge's calibrated distance L from its reference face, m: the
    paper's step gauge, U(k=2) = 0.3 um + 1.5e-6 L (Viprey 2016), halved, for every face L > 0. The
    distance's, not a face's: the reference face itself (L = 0, at O_1) is at distance 0 from itself by
    definition and gets u = 0 (session 32, refface32; until then 0.15 um, the constant taken at L = 0:
    an independent error stated at the one point defined as error-free, which the identification added
    to every difference from O_1, the MFB's EXX U95 up to 25 % wider at a node). The 0.3 um constant
    is a per-distance term (the probing of both faces, the gauge's set-up): it stays at every other
    face. The one formula of :func:`reversal_calibration`'s default and of the simulated step gauge
    (scenarios.mfb.reversal_on_cmm)."""
    L = np.asarray(L_m, float)
    return np.where(L == 0.0, 0.0, 0.5 * (0.3e-6 + 1.5e-6 * L))


@dataclass(frozen=True)
class BarCalibration:
    """Calibrated deviations of the points of interest (eq. 4) with uncertainty.

    Attributes
    ----------
    E_m : (N, 3) float
        (Exx, Eyx, Ezx)_MFB of O_i in R_MFB, m.
    u_m : (N, 3) float
        Standard uncertainties, m.
    U95_m : (N, 3) float
        Expanded uncertainties (95 %: Student t of the effective degrees of
        freedom of the repeats, k = 2 for type B only), m.
    n_repeats : int
    """

    E_m: np.ndarray
    u_m: np.ndarray
    U95_m: np.ndarray
    n_repeats: int


def reversal_calibration(M_norm, M_rev, E_XX_cmm_m=None, *, pitch_m: float = MFB.pitch_m,
                         u_step_gauge_m=None, geom: BarGeometry = MFB,
                         declared_norm: str = "normal", declared_rev: str = "upside-down") -> BarCalibration:
    """Reversal calibration of the bar on a CMM (Viprey 2016 eqs 5-7).

    Parameters
    ----------
    M_norm, M_rev : (r, N, 3) float
        Repeated CMM measurements of O_1..O_N, normal (no reversal, the
        paper's NR) and reversed (``_rev``, the paper's R: bar turned 180 deg
        about its x axis), in the CMM frame
        with the bar along the CMM's X axis, each as the CMM reports it, m
        (O_1 at the origin; the mistake-proofing shifts included).
    E_XX_cmm_m : (N,) float, optional
        CMM positioning error at the O_i (eq. 7), from the substitution
        against a step gauge; default 0.
    u_step_gauge_m : (N,) float, optional
        Standard uncertainty of ``E_XX_cmm_m`` (default: the paper's step
        gauge at L = (i-1) x pitch from O_1, :func:`step_gauge_u_m`: 0 at O_1, its reference face).
    declared_norm, declared_rev : str
        Declared orientations of the two set-ups; :class:`OrientationError`
        names the shifted holes when a set-up is not what it is declared.

    Returns
    -------
    BarCalibration
        ``Eyx = (M_Y^NR - M_Y^R) / 2``, ``Ezx = (M_Z^NR - M_Z^R) / 2``
        (eq. 6: the CMM straightness cancels), ``Exx = (M_X^NR + M_X^R) / 2
        - (i-1) L + E_XXcmm`` (eq. 7), averaged over the repeats; u from the
        scatter of the repeats (type A) and the step gauge (type B).
    """
    M_norm = np.asarray(M_norm, float)
    M_rev = np.asarray(M_rev, float)
    N = geom.n_holes
    if M_norm.ndim == 2:
        M_norm = M_norm[None]
    if M_rev.ndim == 2:
        M_rev = M_rev[None]
    for nm, M in (("M_norm", M_norm), ("M_rev", M_rev)):
        if M.ndim != 3 or M.shape[1:] != (N, 3) or not np.all(np.isfinite(M)):
            raise ConfigError(f"reversal_calibration: {nm} must be finite (repeats, {N}, 3), got {M.shape}")
    r = min(len(M_norm), len(M_rev))
    holes = list(range(1, N + 1))
    shifts = np.array([geom.shift_of(i) for i in holes])
    for nm, M, decl in (("normal set-up", M_norm, declared_norm), ("reversed set-up", M_rev, declared_rev)):
        mean = M.mean(axis=0)
        o, found = detect_orientation(mean, holes, geom)
        try:
            check_orientation(o, found, decl, geom)
        except OrientationError as e:
            raise OrientationError(f"reversal calibration, {nm}: {e}") from None
    # remove the known design shifts (sign per set-up) before separating
    sgn_norm = 1.0 if declared_norm == "normal" else -1.0
    sgn_rev = 1.0 if declared_rev == "normal" else -1.0
    Mn = M_norm[:r].copy()
    Mr = M_rev[:r].copy()
    Mn[:, :, 1] -= sgn_norm * shifts
    Mr[:, :, 1] -= sgn_rev * shifts
    x_nom = (np.arange(N)) * pitch_m
    Exx_cmm = np.zeros(N) if E_XX_cmm_m is None else np.asarray(E_XX_cmm_m, float)
    if Exx_cmm.shape != (N,):
        raise ConfigError(f"reversal_calibration: E_XX_cmm_m must be ({N},), got {Exx_cmm.shape}")
    u_sg = (step_gauge_u_m(x_nom) if u_step_gauge_m is None
            else np.broadcast_to(np.asarray(u_step_gauge_m, float), (N,)))
    per = np.empty((r, N, 3))
    per[:, :, 0] = 0.5 * (Mn[:, :, 0] + Mr[:, :, 0]) - x_nom + Exx_cmm
    per[:, :, 1] = 0.5 * (Mn[:, :, 1] - Mr[:, :, 1])
    per[:, :, 2] = 0.5 * (Mn[:, :, 2] - Mr[:, :, 2])
    E = per.mean(axis=0)
    if r > 1:
        uA = per.std(axis=0, ddof=1) / np.sqrt(r)
    else:
        uA = np.zeros((N, 3))
    u = uA.copy()
    u[:, 0] = np.sqrt(uA[:, 0] ** 2 + u_sg ** 2)
    # coverage factor: Student t for the r - 1 degrees of freedom of the
    # repeats (type A; Welch-Satterthwaite with an infinite-dof step gauge)
    # (scipy.special's stdtrit(nu, 0.975) is scipy.stats.t.ppf(0.975, nu) bit for bit, its _ppf, for the nu >= 1
    # taken here; without importing scipy.stats: session 38, as core.fit.coverage_factor)
    from scipy.special import stdtrit

    if r > 1:
        with np.errstate(divide="ignore", invalid="ignore"):
            nu = np.where(uA > 0, (r - 1) * u ** 4 / np.where(uA > 0, uA, 1) ** 4, np.inf)
        k = np.where(np.isfinite(nu), stdtrit(np.maximum(nu, 1), 0.975), 2.0)
    else:
        k = np.full_like(u, 2.0)
    return BarCalibration(E, u, k * u, r)
