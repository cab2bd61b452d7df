"""The MFB's work zone in MuJoCo: rotary table, workholder, bar, star styli, spindle.

:mod:`sim.scene` holds the artefact and a straight probe; a 5-axis MFB plan
also needs what the bar sits on and what the tool carries, because the
table tilts (A) and turns (C) under the probe. This scene has two moving
bodies, posed from the nominal kinematics (no dynamics; MuJoCo is the
collision engine):

- ``table`` (pose ``T_R_W``): the rotary table, a disc of
  :data:`TABLE_R_M` radius and :data:`TABLE_T_M` thickness whose top face is
  W's xy plane; the workholder's blocks (:class:`Block`, W frame); the
  bar's solids (its two supports included) at ``T_W_A``.
- ``spindle`` (origin at the stylus-tip centre, axes parallel to R): the
  stylus ball; the stylus from the tip along the probing direction to the
  probe offsets' horizontal point ``(J_X, J_Y, 0)`` (a star stylus arm, or
  nothing for a straight stylus); the vertical extension from there up to
  the probe body; the probe body (:data:`sim.scene.PROBE_BODY_R_M`) below
  the gauge line ``J``; the spindle nose (:data:`SPINDLE_R_M`) above it.

What is checked (:func:`check_measurement`): every touch's approach and
retract (start point -> nominal contact), every link move between touches
(retract along the bar's ``z_A`` to a clearance plane above the bar, move
across, plunge: a part program for a bar in any orientation), that the
bar and the workholder lie on the table's side of its face, and that no
workholder block runs into the bar or its supports (:func:`block_overlaps`). The tip ball
may touch the geoms of the feature it probes (the exact primitives of
:mod:`sim.probe` judge that contact); everything else is a collision.
Not modelled: the A-axis cradle below the table, the machine's guards.

MuJoCo judges every path sample the broad phase (:mod:`sim.clearance`) cannot
prove clear; the broad phase has two parts (:meth:`WorkZone.near_segments`): the
stylus ball against the bar, in the bar's frame and shared by every probe and
placement of that bar (a sphere looks the same from every direction), and the rest
of the probe and the holder, per work zone and orientation. A plan's measurements
are checked together (:func:`check_measurements`): their paths sampled at once,
each broad phase's distinct moves (in its frame, computed from the programs in A)
bounded in one pass, the samples of the moves it leaves open bounded one by one,
then MuJoCo measurement by measurement, in path order; the least clearances at the
approach starts of every measurement are bounded in one pass too
(:func:`least_holder_clearances`), the distances per measurement (the stylus ball's from a
holder's sphere, cylinder or box in numpy, :func:`_ball_distance`; the others MuJoCo's).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import math

import numpy as np

from core.memo import Memo

from .artefacts import apply_R, apply_T, inv_T, make_T
from .clearance import GEOM_TYPE, flat_path_segments, rbound, touch_polylines
from .scene import COLLISION_TOL_M, PROBE_BODY_H_M, PROBE_BODY_R_M, _f, _free_joint_T, _quat, artefact_points

#: Rotary table of the Mikron UCP710 (assumed: a disc of 600 mm, 60 mm thick).
TABLE_R_M = 0.300
TABLE_T_M = 0.060
#: Spindle nose above the gauge line: radius, length (m).
SPINDLE_R_M = 0.060
SPINDLE_H_M = 0.250
#: Stylus stem and star arm radius, extension radius (m).
STEM_R_M = 1.5e-3
EXTENSION_R_M = 5.0e-3
#: Length of the thin stem above the ball (or of the star arm's thin part), m.
STEM_L_M = 0.050
#: Clearance of the link moves above the bar's top (along z_A), m.
LINK_CLEAR_M = 10.0e-3


@dataclass(frozen=True)
class Block:
    """A workholder block on the table: axis-aligned box in W, corners ``lo``, ``hi`` (m)."""

    name: str
    lo: tuple
    hi: tuple

    def __post_init__(self):
        # corners kept as tuples of floats whatever they were given as (numpy arrays too): the block
        # is hashed as a key of the plan-check and work-zone caches
        object.__setattr__(self, "lo", tuple(map(float, self.lo)))
        object.__setattr__(self, "hi", tuple(map(float, self.hi)))


@dataclass(frozen=True)
class CheckResult:
    """Outcome of a measurement's collision and reach check.

    Attributes
    ----------
    measurement : str
    touches, samples : int
        Touches and path points checked.
    collisions : tuple of str
        First collision of each colliding touch, in words (empty: passed).
    min_table_clearance_mm : float
        Least distance of the probe (ball, stylus, body, spindle) from the
        table, the workholder and the bar's supports at the touches' approach
        starts (where the probe waits before each touch). The paths between are
        checked for collision at every sample, not measured for clearance: a
        path may pass closer than this (plan_5axis: 3.68 mm at the starts, 2.2 mm
        along the paths) without touching.
    """

    measurement: str
    touches: int
    samples: int
    collisions: tuple = ()
    min_table_clearance_mm: float = field(default=float("nan"))
    #: (touches, 3) m, R: each touch's stylus-centre contact as checked (``apply_T(T_R_W @ T_W_A,
    #: w_A + r wn_A)``; None when not given), for a caller's stroke check (scenarios.mfb.check_plan)
    contacts_R: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: kind -> (k, 3) m, R: every position the measurement's program commands, as checked, in the
    #: form and order of ``scenarios.mfb.program_positions`` ("touches" the contacts above, "approach
    #: starts", "overshoot ends", "links" when the program has two touches or more), the same
    #: expressions row by row (None when not given), for a caller's stroke check (scenarios.mfb.check_plan)
    positions_R: dict | None = field(default=None, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        return not self.collisions


def _probe_parts(J_m, r_m: float, finger_m: float = 0.0) -> list:
    """The probe's geoms (spindle body frame: tip centre, axes of R) for offsets J: (name, type,
    ends (2,3) of a capsule's axis or None, centre (3,) of a sphere or cylinder or None,
    size tuple) each, in the model's order. :func:`probe_geoms_mjcf` writes them,
    :func:`probe_geoms` gives them to the broad phase."""
    J = np.asarray(J_m, float)
    r = float(r_m)
    out = [("ball", "sphere", None, np.zeros(3), (r,))]
    h = np.hypot(J[0], J[1])
    z_body = J[2] - PROBE_BODY_H_M
    if h > 1e-9:  # star arm (on its finger), then the vertical extension
        u = np.array([J[0], J[1], 0.0]) / h
        z0 = float(finger_m)
        if z0 > 0:
            out.append(("finger", "capsule", np.array([[0.0, 0, r], [0.0, 0, z0]]), None, (STEM_R_M,)))
        out.append(("arm", "capsule", np.array([(0.0 if z0 > 0 else r) * u + [0, 0, z0], [J[0], J[1], z0]]), None,
                    (STEM_R_M,)))
    else:
        out.append(("stem", "capsule", np.array([[0.0, 0, r], [0.0, 0, STEM_L_M]]), None, (STEM_R_M,)))
        z0 = STEM_L_M
    if z_body - z0 > 1e-6:
        out.append(("extension", "capsule", np.array([[J[0], J[1], z0], [J[0], J[1], z_body]]), None,
                    (EXTENSION_R_M,)))
    out.append(("probe_body", "cylinder", None, np.array([J[0], J[1], z_body + PROBE_BODY_H_M / 2]),
                (PROBE_BODY_R_M, PROBE_BODY_H_M / 2)))
    out.append(("spindle", "cylinder", None, np.array([J[0], J[1], J[2] + SPINDLE_H_M / 2]),
                (SPINDLE_R_M, SPINDLE_H_M / 2)))
    return out


def probe_geoms_mjcf(J_m, r_m: float, finger_m: float = 0.0, only=None) -> str:
    """MJCF geoms of the probe (spindle body frame: tip centre, axes of R) for offsets J.

    ``finger_m``: a star stylus whose ball hangs on a vertical finger of this
    length below its arm (0: the arm at the ball's height). ``only``: the names of
    the geoms to write (default: all).
    """
    g = []
    for name, kind, ends, c, size in _probe_parts(J_m, r_m, finger_m):
        if only is not None and name not in only:
            continue
        where = f'fromto="{_f(ends)}"' if ends is not None else ("" if kind == "sphere" else f'pos="{_f(c)}"')
        g.append(f'<geom name="{name}" type="{kind}" {where + " " if where else ""}size="{_f(size)}" '
                 f'contype="0" conaffinity="1"/>')
    return "".join(g)


def probe_geoms(J_m, r_m: float, finger_m: float = 0.0):
    """(names, :class:`sim.clearance.Geoms`) of the probe's geoms (:func:`probe_geoms_mjcf`) from
    their definitions: about the tip centre, axes of R, in the model's order. A capsule's
    frame has its axis as z (MuJoCo's own x, y about it differ: a capsule looks the same
    from them); poses agree with the compiled model's to rounding (1e-16 m)."""
    return _probe_geoms_many([(J_m, r_m, finger_m)])[0]


def _probe_geoms_many(keys) -> list:
    """:func:`probe_geoms` of several probes ((J_m, r_m, finger_m) each), their geoms' arrays computed
    in one pass (every value row by row: the same numbers as one probe at a time); each probe's
    Geoms holds views of the common arrays."""
    from core.kinematics import _cross_rows as _cross

    from .clearance import Geoms

    each = [_probe_parts(*k) for k in keys]
    parts = [p for ps in each for p in ps]
    k = len(parts)
    kind = np.array([GEOM_TYPE[p[1]] for p in parts])
    size = np.array([tuple(p[4]) + (0.0,) * (3 - len(p[4])) for p in parts])
    cap = kind == GEOM_TYPE["capsule"]
    centre = np.array([p[3] if p[2] is None else np.zeros(3) for p in parts])
    axes = np.tile(np.eye(3), (k, 1, 1))
    ends = np.array([p[2] for p in parts if p[2] is not None]).reshape(-1, 2, 3)  # the capsules'
    d = ends[:, 1] - ends[:, 0]
    L = np.sqrt(np.sum(d * d, axis=1))
    centre[cap], size[cap, 1] = (ends[:, 0] + ends[:, 1]) / 2, L / 2
    z = d / L[:, None]  # each capsule's frame: z its axis, x normal to it and to y (or z) of R
    e = np.where((np.abs(z[:, 2]) > 0.9)[:, None], (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    x = _cross(e, z)
    x /= np.sqrt(np.sum(x * x, axis=1))[:, None]
    axes[cap] = np.stack([x, _cross(z, x), z], axis=2)
    rb = rbound(kind, size)
    out, j = [], 0
    for ps in each:
        sl = slice(j, j + len(ps))
        j += len(ps)
        out.append(([p[0] for p in ps], Geoms(centre[sl], axes[sl], kind[sl], size[sl], rb[sl])))
    return out


#: Each probe's (key, geom names, Geoms) by (J_m, stylus radius, finger): a plan's work zones share
#: a handful of probes (the 5-axis plan: 9 zones, 7 probes). Safe: the key is every input (floats);
#: the Geoms' arrays are read only. 32 probes.
_PROBES = Memo(32)


def _probe_key(J_m, r_m: float, finger_m: float = 0.0) -> tuple:
    """A probe's key: (J_m, r_m, finger_m) as floats (:func:`probe_geoms_mjcf`'s arguments)."""
    return (tuple(float(v) for v in J_m), float(r_m), float(finger_m))


def _probe(J_m, r_m: float, finger_m: float = 0.0) -> tuple:
    """(the probe's key (:func:`_probe_key`: its MJCF written when a model is compiled), then
    :func:`probe_geoms`'s names and Geoms) of a probe, kept (:data:`_PROBES`)."""
    key = _probe_key(J_m, r_m, finger_m)
    return _PROBES.get_or_compute(key, lambda: _kept_probe(key, probe_geoms(*key)))


def _kept_probe(key, built) -> tuple:
    """(key, names, Geoms) of a probe as :data:`_PROBES` keeps it (its arrays read only)."""
    names, g = built
    for a in (g.centre, g.axes, g.kind, g.size, g.rbound):
        a.flags.writeable = False
    return key, names, g


def _probes_ahead(keys) -> None:
    """The probes of ``keys`` (:func:`_probe_key`) not kept yet built in one :func:`_probe_geoms_many`
    and kept (:data:`_PROBES`): a plan's work zones ask for several."""
    todo = list(dict.fromkeys(k for k in keys if _PROBES.get(k) is None))
    for key, built in zip(todo, _probe_geoms_many(todo) if todo else ()):
        _PROBES.get_or_compute(key, lambda key=key, built=built: _kept_probe(key, built))


#: Each solid's pose on the artefact (make_T(rot, pos)) of the artefacts seen last, by object,
#: and beside them (keys ("table", id), ("stack", id)) the artefact's :class:`_Solids` and the
#: poses stacked, and (keys ("side", id, blocks)) its work zones' table sides per workholder
#: (:func:`_table_side`), and (keys ("shapes", id, blocks)) the table side's kinds, sizes and bounding
#: radii per workholder. Safe: the artefact is kept in each entry and checked with ``is``; the
#: blocks are in the key (frozen, compared by value); the values are only read. 64 entries,
#: three per artefact and two per workholder it sits on (before: cleared when the poses
#: of a new artefact found more than 16 entries; the other two kinds were stored unchecked).
_SOLID_POSES = Memo(64)


def _solid_poses(art) -> list:
    """Each solid's pose on the artefact, ``make_T(rot, pos)`` (4,4) of every solid (views of one
    (k,4,4) array, :func:`_solid_pose_stack`)."""
    return _SOLID_POSES.get_or_compute(id(art), lambda: list(_solid_pose_stack(art)), owner=art)


@dataclass(frozen=True)
class _Solids:
    """A bar's solids as table-side geoms of a work zone: MuJoCo type names, sizes (tuples
    as the MJCF writes them, and (k,3) zero-padded), geom names, feature names, and the
    solids that belong to the workholder (the bar's supports: ``holder``, indices)."""

    kinds: list
    sizes: list
    names: list
    features: list
    size3: np.ndarray
    holder: list


def _solid_table(art) -> _Solids:
    """:class:`_Solids` of ``art``, built once per artefact object (kept beside its poses):
    every work zone of a plan holds the same bar."""
    return _SOLID_POSES.get_or_compute(("table", id(art)), lambda: _build_solid_table(art), owner=art)


def _build_solid_table(art) -> _Solids:
    """:func:`_solid_table`'s answer, computed."""
    sol = art.solids
    kinds = [s.kind for s in sol]
    if not set(kinds) <= {"box", "cylinder", "sphere"}:
        raise ValueError("WorkZone: mesh solids are not supported (the MFB has none)")
    # (a flat tuple of numbers as it is, else flattened: the same numbers)
    sizes = [sz if type(sz) is tuple and _NUMBER.issuperset(map(type, sz)) else tuple(np.ravel(sz))
             for sz in (s.size for s in sol)]
    feats = [s.feature for s in sol]
    names = [f"{f or ('support' if kd == 'cylinder' else 'body')}__{k}" for k, (f, kd) in enumerate(zip(feats, kinds))]
    size3 = np.zeros((len(sizes), 3))
    lens = np.fromiter(map(len, sizes), int, len(sizes))
    for n in np.unique(lens):  # (one assignment per size length, not one per solid: the same floats)
        j = np.flatnonzero(lens == n)
        if n:
            size3[j, :n] = [sizes[k] for k in j]
    holder = [k for k, n in enumerate(names) if n.startswith(("fix_", "support__"))]
    return _Solids(kinds, sizes, names, feats, size3, holder)


#: The number types a solid's size tuple is kept as it is with (_build_solid_table).
_NUMBER = frozenset((float, np.float64, int))


def _solid_pose_stack(art) -> np.ndarray:
    """(k,4,4): each solid's pose on the artefact, as ``make_T(rot, pos)`` writes it, in one array
    (read only; kept beside :func:`_solid_poses`)."""
    def build():
        sol = art.solids
        T = np.zeros((len(sol), 4, 4))
        if sol:  # (an empty list does not broadcast into (0, 3, 3))
            T[:, :3, :3] = [np.eye(3) if x.rot is None else x.rot for x in sol]
            T[:, :3, 3] = [x.pos for x in sol]
        T[:, 3, 3] = 1.0
        T.flags.writeable = False
        return T

    return _SOLID_POSES.get_or_compute(("stack", id(art)), build, owner=art)


#: The stylus ball's broad phase against a bar's own solids (frame A, :meth:`WorkZone.ball_clearance`)
#: by (bar object, ball radius); the bar is kept in the entry (its id stays its own). Safe: a
#: Clearance's geoms are fixed, its certificates hold segments in A (valid for any placement).
#: 8 bars.
_BALLS = Memo(8)


def _ball_clearance(art, r: float):
    """The broad phase of a ball of radius ``r`` (m) at A's origin against ``art``'s own solids (its
    supports aside), frame A (:meth:`WorkZone.ball_clearance` moves it)."""
    from .clearance import Clearance, Geoms

    sol = _solid_table(art)
    bar = np.setdiff1d(np.arange(len(sol.kinds)), sol.holder)  # the bar's own solids
    T = _solid_pose_stack(art)[bar]
    kind = np.array([GEOM_TYPE[sol.kinds[k]] for k in bar])
    size = sol.size3[bar]
    H = Geoms(T[:, :3, 3].copy(), T[:, :3, :3].copy(), kind, size, rbound(kind, size))
    P = Geoms(np.zeros((1, 3)), np.eye(3)[None], np.array([GEOM_TYPE["sphere"]]), np.array([[r, 0.0, 0.0]]),
              np.array([r]))
    return Clearance(P, H, [sol.features[k] for k in bar], 0)


#: Per table pose (T_R_W's bytes, :meth:`WorkZone.set_table`): [the table's free-joint qpos (7,), its
#: T_W_R as MuJoCo's pose gives it (:meth:`WorkZone._W_R`, None until asked)], shared by every work
#: zone set to that pose (a plan's zones share a handful of table poses). Safe: each value is a
#: function of the key alone; only read. 64 poses.
_TABLE_POSES = Memo(64)


def _table_side(art, blocks: tuple) -> tuple:
    """(kinds, sizes, poses of the disc and the blocks, names, features, the holder's geoms, table
    geom -> feature) of a work zone's table side for the bar ``art`` on the workholder ``blocks``:
    the table disc, the blocks, the bar's solids, in the model's order. Built once per bar and
    workholder (kept beside the bar's solids, :data:`_SOLID_POSES`) and shared, read only, by the
    zones of every placement and probe (the bar's pose enters through ``T_W_A`` alone)."""
    def build():
        kinds, sizes, poses, names, feats = ["cylinder"], [(TABLE_R_M, TABLE_T_M / 2, 0.0)], \
            [make_T(None, (0.0, 0.0, -TABLE_T_M / 2))], ["table_disc"], [""]
        for b in blocks:
            lo, hi = np.asarray(b.lo, float), np.asarray(b.hi, float)
            kinds.append("box"), sizes.append(tuple((hi - lo) / 2)), poses.append(make_T(None, (lo + hi) / 2))
            names.append(f"fix_{b.name}"), feats.append("")
        sol = _solid_table(art)  # the bar's solids: the same for every placement
        kinds += sol.kinds
        sizes += sol.sizes
        names += sol.names
        feats += sol.features
        n0 = 1 + len(blocks)  # the disc, the blocks (all the holder's), then the bar's solids
        holder = list(range(n0)) + [n0 + k for k in sol.holder]
        return kinds, sizes, poses, names, feats, holder, dict(enumerate(feats))

    return _SOLID_POSES.get_or_compute(("side", id(art), blocks), build, owner=art)


class WorkZone:
    """One bar placement on the table with its workholder, one probe (offsets J).

    Parameters
    ----------
    artefact : sim.artefacts.Artefact
    T_W_A : (4,4) float
        Bar pose on the table (W), m.
    blocks : sequence of Block
    J_m : (3,) float
        Probe offsets (gauge point minus tip centre, R axes), m.
    stylus_r_m : float
    """

    def __init__(self, artefact, T_W_A, blocks, J_m, stylus_r_m: float, finger_m: float = 0.0):
        import mujoco

        self._mj = mujoco
        T_W_A = np.asarray(T_W_A, float)
        self._args = (artefact, T_W_A, tuple(blocks))
        # the table side in W, as numpy geoms (kind, size, pose) in the model's order: the
        # disc, the blocks, the bar's solids (the MJCF of self.mjcf is written from these); the
        # same lists for every zone of this bar and workholder (_table_side; read only)
        kinds, sizes, poses, names, feats, holder, feature = _table_side(artefact, self._args[2])
        self._tkind, self._tsize, self._tpose0 = kinds, sizes, poses  # (the solids' poses: _pose)
        self._T_W_A = T_W_A
        nt = len(names)
        # the probe's geoms from their definitions (the broad phase's), once per probe (_PROBES); its
        # MJCF (written from the same parts, _probe_parts) when a model of the zone is compiled
        self._probe_key, pnames, self._probe_geoms = _probe(J_m, stylus_r_m, finger_m)
        npg = len(pnames)
        # geom ids of the full model (compiled when MuJoCo first needs it, self.model): the table
        # body's geoms in order, then the spindle's; of the holder's model (self._holder_model):
        # the holder's geoms, then the spindle's
        self._names = names + pnames  # + the probe's
        self._table = list(range(nt))
        self._probe = list(range(nt, nt + npg))
        self._holder = holder
        self._feature = feature  # (table geom -> its feature)
        self._feats = feats  # (the same, as a list)
        self._pball = pnames.index("ball")  # the ball among the probe's geoms
        self._ball = nt + self._pball
        self._tq, self._sq = 0, 7  # the table's and the spindle's free joints in qpos (checked on compiling, _check_layout)
        self._hprobe = list(range(len(holder), len(holder) + npg))
        self._hmodel = self._hdata = None
        self._model = self._data = None
        self._tqpos = np.array([0.0, 0, 0, 1, 0, 0, 0])
        self._clr, self._hclr = {}, {}  # (clearance: by part, holder only by table pose)
        self._T_W_R = None  # (clearance)
        self._tpose = [self._tqpos, None]  # (set_table: the pose's entry in _TABLE_POSES)
        self._tkey = None  # (set_table: the pose last set, bytes)
        self._at = {}  # the broad phases at the pose last set (ball_clearance, clearance), by part
        self._hpairs = {}  # the holder's pairs of the rest broad phases (least_holder_clearance), by their pair table
        self._r = float(stylus_r_m)
        self._A_W = None  # (T_A_W: computed when ball_clearance first needs it)
        #: what the work zones of this placement share (_work_zone): the table side's geoms in W
        self._shared = {}

    def _pose(self, j: int) -> np.ndarray:
        """(4,4) pose in W of table-side geom j (a solid's: T_W_A times its pose on the bar)."""
        n0 = len(self._tpose0)
        return self._tpose0[j] if j < n0 else self._T_W_A @ _solid_pose_stack(self._args[0])[j - n0]

    def _geom_mjcf(self, j: int, prefix: str = "") -> str:
        """Table-side geom j's MJCF (its name after ``prefix``): :meth:`_geom_spec`'s values, each float
        as its repr (which MJCF reads back as the same float)."""
        name, kind, size, pos, quat = self._geom_spec(j, prefix)
        q = "" if quat is None else f' quat="{_f(quat)}"'
        return f'<geom name="{name}" type="{kind}" size="{_f(size)}" pos="{_f(pos)}"{q} contype="1" conaffinity="0"/>'

    def _geom_spec(self, j: int, prefix: str = "") -> tuple:
        """Table-side geom j as (name, type, size, pos, quat or None; its name after ``prefix``): what
        :meth:`_geom_mjcf` writes and :func:`_ball_model_spec` builds (the table disc and the fixture
        blocks unrotated)."""
        kind, size, T = self._tkind[j], self._tsize[j], self._pose(j)
        name = self._names[j]
        if j == 0:
            return f"{prefix}table_disc", "cylinder", (TABLE_R_M, TABLE_T_M / 2), (0.0, 0.0, -TABLE_T_M / 2), None
        if name.startswith("fix_") and j <= len(self._args[2]):
            return f"{prefix}{name}", "box", size, T[:3, 3], None
        return f"{prefix}{name}", kind, size, T[:3, 3], _quat(T[:3, :3])

    def _xml(self, table_geoms, probe_mjcf: str | None = None) -> str:
        return _zone_xml("".join(self._geom_mjcf(j) for j in table_geoms),
                         probe_geoms_mjcf(*self._probe_key) if probe_mjcf is None else probe_mjcf)

    @property
    def mjcf(self) -> str:
        """The work zone's MJCF (table side, probe)."""
        return self._xml(self._table)

    def _compile(self, xml: str, names: list):
        """(model, data) of ``xml``, its geoms ``names`` and free joints where this zone expects them."""
        m = self._mj.MjModel.from_xml_string(xml)
        _check_layout(m, self, len(names), names)
        return m, self._mj.MjData(m)

    @property
    def model(self):
        """The compiled MuJoCo model of the whole work zone (compiled on first use: the broad
        phase and the least clearance do not need it)."""
        if self._model is None:
            self._model, self._data = self._compile(self.mjcf, self._names)
        return self._model

    def _holder_model(self):
        """(model, data): the holder's geoms (table disc, blocks, bar supports) and the probe's,
        MuJoCo's distances for the least clearance (compiled on first use)."""
        if self._hmodel is None:
            self._hmodel, self._hdata = self._compile(self._xml(self._holder),
                                                      [self._names[j] for j in self._holder + self._probe])
        return self._hmodel, self._hdata

    def _ball_model(self):
        """(model, data, id of this placement's first holder geom, id of the ball) of the
        placement's ball model: the holder's geoms and the probe's stylus ball alone, one model
        for every probe of this placement with that ball (its distances are :meth:`_holder_model`'s,
        bit for bit: the same geoms at the same poses, the ball at the spindle body's origin), or
        of every placement declared with this one (:func:`share_ball_model`). The holder's geoms
        follow the first in the order of ``self._holder``."""
        key = ("ball_model", self._r)
        if key not in self._shared:
            xml = self._xml(self._holder, probe_geoms_mjcf((0.0, 0.0, 1.0), self._r, only=("ball",)))
            names = [self._names[j] for j in self._holder] + ["ball"]
            self._shared[key] = self._compile(xml, names) + (0, len(self._holder))
        return self._shared[key]

    @property
    def data(self):
        self.model  # noqa: B018  (compiles on first use)
        return self._data

    def set_table(self, T_R_W) -> None:
        T = np.asarray(T_R_W, float)
        key = T.tobytes()
        if key == self._tkey:  # (the same pose again: a plan's check sets it twice per measurement)
            return
        self._tkey = key
        # (per pose, whatever the zone: its free joint's qpos, and T_W_R once a zone asks, _W_R)
        self._tpose = _TABLE_POSES.get_or_compute(key, lambda: [np.concatenate([T[:3, 3], _quat(T[:3, :3])]), None])
        self._tqpos = self._tpose[0]
        self._T_W_R = None
        self._at = {}

    def set_tip(self, p_R) -> None:
        """Place the stylus-tip centre at ``p_R`` (3,) m, R (spindle axes parallel to R)."""
        self._place(self.model, self.data, p_R)

    def _place(self, m, d, p_R) -> None:
        """In ``(m, d)`` (the zone's model, its holder's or its ball's): the table at its pose, the
        stylus-tip centre at ``p_R`` (3,) m, R."""
        d.qpos[self._tq:self._tq + 7] = self._tqpos
        d.qpos[self._sq:self._sq + 3] = p_R
        d.qpos[self._sq + 3:self._sq + 7] = (1.0, 0.0, 0.0, 0.0)
        self._mj.mj_kinematics(m, d)

    def _T_R_W(self) -> np.ndarray:
        """(4,4) the table's pose as MuJoCo computes it from its free joint (set_table's)."""
        return _free_joint_T(self._tqpos)

    def table_geoms(self, in_W: bool = False):
        """The table side's geoms (:class:`sim.clearance.Geoms`, R; W if ``in_W``) at the current
        table pose, in the model's order, from their definitions (MuJoCo's poses agree to
        rounding, 1e-16 m)."""
        from .clearance import Geoms

        T = np.concatenate([np.array(self._tpose0), _solid_pose_stack(self._args[0])])
        T[len(self._tpose0):] = self._T_W_A @ T[len(self._tpose0):]
        if not in_W:
            T = self._T_R_W() @ T
        kind, size, rb = self._side_shapes()
        return Geoms(T[:, :3, 3].copy(), T[:, :3, :3].copy(), kind, size, rb)

    def _side_shapes(self) -> tuple:
        """(kind (k,) int, size (k,3), rbound (k,)) of the table side's geoms (:meth:`table_geoms`),
        the same at every pose and placement: built once per bar and workholder (kept beside the
        bar's solids, :data:`_SOLID_POSES`), read only."""
        art, blocks = self._args[0], self._args[2]

        def build():
            n0 = len(self._tpose0)
            size = np.zeros((len(self._tkind), 3))
            for j, sz in enumerate(self._tsize[:n0]):  # the disc and the blocks; the bar's solids kept
                size[j, :len(sz)] = sz
            size[n0:] = _solid_table(art).size3
            kind = np.array([GEOM_TYPE[k] for k in self._tkind])
            out = (kind, size, rbound(kind, size))
            for x in out:
                x.flags.writeable = False
            return out

        return _SOLID_POSES.get_or_compute(("shapes", id(art), blocks), build, owner=art)

    def clearance(self, holder_only: bool = False, part: str = "all", moved: bool = True):
        """The broad phase (:class:`sim.clearance.Clearance`) at the current table pose.

        ``part``: "all", the probe against every table-side geom (indices of
        ``self._table``); "rest", the same without the stylus ball's pairs with the bar
        (supports aside), which :meth:`ball_clearance` bounds for every probe at once.
        ``holder_only``: the probe against the holder's geoms only (indices of
        ``self._holder``; the reference of :meth:`least_holder_clearance`).

        Built in the table's frame W and kept per orientation of the spindle to W (per
        spindle axis for a probe of spheres, capsules and cylinders on its axis:
        :class:`sim.clearance.ByOrientation`): the measurements of one work zone at table
        poses that differ by a turn about the spindle axis (a C turn on a vertical
        spindle) share it, its pair data and the certificates of their moves (the same
        touches in W: :meth:`sim.clearance.Clearance.near_segments`). ``moved=False``: that
        orientation's broad phase wherever it was last placed (for segments already in W: its
        ``T_F_R`` may be another pose's).
        """
        if holder_only:
            from .clearance import Clearance, model_geoms

            key = self._tqpos.tobytes()
            if key not in self._hclr:
                hm, hd = self._holder_model()
                self._place(hm, hd, np.zeros(3))
                table = model_geoms(hm, hd, range(len(self._holder)))
                self._hclr[key] = Clearance(self._probe_geoms, table, [self._feature.get(i, "") for i in self._holder],
                                            self._pball, cert_pad_m=0.0)
            return self._hclr[key]
        hit = self._at.get(part) if moved else None  # (asked twice per measurement at one pose)
        if hit is not None:
            return hit
        if not moved:
            return self._by_orientation(part).get(self._W_R(), move=False)
        hit = self._at[part] = self._by_orientation(part).get(self._W_R())
        return hit

    def _by_orientation(self, part: str):
        """:meth:`clearance`'s broad phases of ``part`` ("all" or "rest") by orientation
        (:class:`sim.clearance.ByOrientation`), made on first use."""
        if part not in self._clr:  # (the import only when made: 51 asks a fresh 5-axis check, one make a zone and part)
            from .clearance import ByOrientation, Clearance

            probe = self._probe_geoms  # about the tip, axes of R (whatever the table's pose)
            ball = self._pball
            pairs = None
            if part == "rest":  # the ball against the table disc, the blocks and the supports only
                pairs = np.ones((len(self._probe), len(self._table)), bool)
                pairs[ball] = False
                pairs[ball, self._holder] = True
            if "table_W" not in self._shared:  # (the same for every probe at this placement)
                self._shared["table_W"], self._shared["features"] = self.table_geoms(in_W=True), self._feats

            def build(P, T_F_R, pairs=pairs, probe_box=None):
                return Clearance(P, self._shared["table_W"], self._shared["features"], ball, T_F_R=T_F_R,
                                 pairs=pairs, probe_box=probe_box)

            self._clr[part] = ByOrientation(probe, build, table=(self._shared["table_W"], self._shared["features"]))
        return self._clr[part]

    def _W_R(self) -> np.ndarray:
        """(4,4) T_W_R: R in the table's frame, from the table's pose as MuJoCo has it (once per set_table)."""
        if self._T_W_R is None:
            if self._tpose[1] is None:  # (the same for every zone at this pose)
                self._tpose[1] = inv_T(self._T_R_W())
            self._T_W_R = self._tpose[1]
        return self._T_W_R

    def ball_clearance(self):
        """The broad phase of the stylus ball against the bar's solids (its supports aside), in
        the bar's frame A at the current table pose: one per bar and ball radius, shared by
        every probe, work zone and placement of that bar (a sphere has no orientation), with
        its pair data and certificates (:data:`_BALLS`)."""
        hit = self._at.get("ball")
        if hit is None:
            if self._A_W is None:
                self._A_W = inv_T(self._T_W_A)
            hit = self._at["ball"] = self._ball_base().moved(self._A_W @ self._W_R())
        return hit

    def _ball_base(self):
        """:meth:`ball_clearance` in A, unplaced (``T_F_R`` None: for segments already in A)."""
        art, r = self._args[0], self._r
        return _BALLS.get_or_compute((id(art), r), lambda: _ball_clearance(art, r), owner=art)

    def near_segments(self, sg, allow_feature=None) -> np.ndarray:
        """Sorted sample numbers of the segments ``sg`` (R) that may come closer than
        :data:`sim.clearance.MARGIN_M` to a table-side geom (:meth:`sim.clearance.Clearance.near_segments`):
        those of the ball against the bar (:meth:`ball_clearance`) and of the rest
        (:meth:`clearance`, ``part="rest"``)."""
        a = self.ball_clearance().near_segments(sg, allow_feature)
        b = self.clearance(part="rest").near_segments(sg, allow_feature)
        return np.union1d(a, b) if a.size and b.size else (a if a.size else b)

    def collisions(self, p_R, allow_feature: str = "") -> list:
        """(probe geom, table-side geom, depth m) with the tip centre at ``p_R``."""
        d = self.data
        self.set_tip(p_R)
        self._mj.mj_collision(self.model, d)
        out = []
        for c in range(d.ncon):
            dist = d.contact.dist[c]
            if dist > -COLLISION_TOL_M:
                continue
            g1, g2 = (int(g) for g in d.contact.geom[c])
            pg, ag = (g1, g2) if g1 in self._probe else (g2, g1)
            if pg == self._ball and allow_feature and self._feature.get(ag, "") == allow_feature:
                continue
            out.append((self._names[pg], self._names[ag], float(dist)))
        return out

    def least_holder_clearance(self, tips_R, distmax: float = 0.05, broad_phase: bool = True) -> float:
        """Least :meth:`holder_clearance` over the tip positions ``tips_R`` (n,3) m, R.

        Branch and bound: each (tip, probe geom, holder geom) triple has a lower
        bound from :mod:`sim.clearance`; the triple's distance (MuJoCo's ``mj_geomDistance``,
        or for the ball against a sphere, cylinder or box :func:`_ball_distance`, the same to
        1e-17 m) is computed in increasing order of bound while the bound is below the least
        distance found (plus :data:`sim.clearance.MARGIN_M`, MuJoCo's tolerance being far smaller).
        ``broad_phase=False``: MuJoCo at every triple (the reference).
        """

        tips = np.asarray(tips_R, float).reshape(-1, 3)
        best = distmax
        if not broad_phase:  # the reference: every triple in the whole work zone's model
            clr = self.clearance(holder_only=True)
            for k in range(len(tips) * len(clr.pair_probe)):
                i, p = divmod(k, len(clr.pair_probe))
                self.set_tip(tips[i])
                a, b = self._probe[clr.pair_probe[p]], self._holder[clr.pair_table[p]]
                best = min(best, float(self._mj.mj_geomDistance(self.model, self.data, a, b, distmax, None)))
            return best
        return float(least_holder_clearances([(self, None, tips)], distmax)[0])

    def _holder_pairs(self, clr) -> tuple:
        """(the pairs of the rest broad phase ``clr`` with a holder geom (indices of its pairs),
        each table geom's index in the holder's model (-1: not the holder's)): shared by the moved
        copies of a broad phase and by its orientations with the same pairs (kept by their pair
        table, the pair structure's: :func:`sim.clearance._pair_structure`)."""
        hp = self._hpairs.get(id(clr.pair_table))
        if hp is None:
            hpos = np.full(len(self._table), -1)
            hpos[self._holder] = np.arange(len(self._holder))  # table geom -> its holder model's geom
            hp = self._hpairs[id(clr.pair_table)] = (np.flatnonzero(hpos.take(clr.pair_table) >= 0), hpos,
                                                     clr.pair_table)
        return hp[0], hp[1]

    def _holder_distance(self, clr, hpos, tip, pair: int, distmax: float, tip_F=None) -> float:
        """The distance of pair ``pair`` of the rest broad phase ``clr`` with the tip centre at
        ``tip`` (R) at the current table pose: the ball's against a box, cylinder or sphere
        computed here from ``tip_F`` (the tip in clr's frame W, as ``clr.to_frame`` gives it:
        :func:`_ball_distance`, MuJoCo's primitive distance to 1e-17 m), else MuJoCo's: the
        ball's in the placement's ball model, the other probe geoms' in the holder's model (the
        same distance as in the whole zone's)."""
        g = clr.pair_probe[pair]
        if g == self._pball and tip_F is not None:
            h = clr.pair_table[pair]
            if int(clr.table.kind[h]) in _BALL_KINDS:
                P, T = clr.probe, clr.table
                return _ball_distance(int(T.kind[h]), T.size[h], T.centre[h], T.axes[h], tip_F + P.centre[g],
                                      float(P.size[g, 0]), distmax)
        b = int(hpos[clr.pair_table[pair]])
        if g == self._pball:
            m, d, h0, a = self._ball_model()
            b = h0 + b
        else:
            m, d = self._holder_model()
            a = self._hprobe[g]
        self._place(m, d, tip)
        return float(self._mj.mj_geomDistance(m, d, a, b, distmax, None))

    def holder_clearance(self, distmax: float = 0.05) -> float:
        """Least distance (m) of the probe's geoms from the table, the workholder and the
        bar's supports at the current pose (``distmax`` if farther)."""
        m, d = self.model, self.data
        best = distmax
        for a in self._probe:
            for b in self._holder:
                best = min(best, float(self._mj.mj_geomDistance(m, d, a, b, distmax, None)))
        return best


#: The holder geom types whose distance from the stylus ball :func:`_ball_distance` computes
#: (sphere, cylinder, box; MuJoCo's type codes): MuJoCo's own for the others.
_BALL_KINDS = frozenset((GEOM_TYPE["sphere"], GEOM_TYPE["cylinder"], GEOM_TYPE["box"]))


def _ball_distance(kind: int, size, centre, axes, c, r: float, distmax: float) -> float:
    """Signed distance (m) of a ball of radius ``r`` centred at ``c`` (3,) from a sphere, cylinder
    or box (MuJoCo type ``kind``, ``size`` as MuJoCo's, centre (3,), axes (3,3) columns), all in
    one frame; ``distmax`` if farther. MuJoCo's ``mj_geomDistance`` computes these pairs by its
    analytic primitives (sphere-sphere, sphere-cylinder, sphere-box): the centre's distance from
    the geom (its depth inside, negative, from the nearest face or side), minus ``r``. This is the
    same distance in numpy's arithmetic: it agreed with MuJoCo 4.0's to 2e-17 m at 3,000 random
    poses (penetrating ones included), 1.2e-16 m at points aimed at cylinder rims (the session 21 review) and on every least clearance of the plan-check variants
    and fuzz sets (below 1e-12 mm; simspeed's docstring, session 21), not bit for bit.
    Saves a fresh plan check its ball model (an MjSpec compile and MjData, ~1.5-2 ms)."""
    d = np.asarray(c, float) - centre
    if kind == _SPHERE_T:
        out = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) - size[0] - r
    else:
        q0, q1, q2 = (axes[0, j] * d[0] + axes[1, j] * d[1] + axes[2, j] * d[2] for j in range(3))  # in the geom's axes
        if kind == _BOX_T:
            e = (abs(q0) - size[0], abs(q1) - size[1], abs(q2) - size[2])
            if max(e) > 0:
                out = math.sqrt(sum(x * x for x in e if x > 0)) - r
            else:
                out = max(e) - r  # (inside: minus the depth from the nearest face)
        else:  # cylinder: radius size[0], half length size[1] along its z
            dx, dz = math.hypot(q0, q1) - size[0], abs(q2) - size[1]
            if dx > 0 or dz > 0:
                out = math.hypot(max(dx, 0.0), max(dz, 0.0)) - r
            else:
                out = max(dx, dz) - r
    return min(float(out), float(distmax))


_SPHERE_T, _BOX_T = GEOM_TYPE["sphere"], GEOM_TYPE["box"]


#: Triples of the least holder clearance given to MuJoCo in the order of their box bound
#: before the full bound (:meth:`sim.clearance.Clearance.bound`) orders the rest.
_DIRECT = 8


def least_holder_clearances(items, distmax: float = 0.05) -> np.ndarray:
    """:meth:`WorkZone.least_holder_clearance` of several measurements at once: ``items`` (work zone,
    table pose T_R_W (4,4) or None for the zone's current one, tips (n,3) R, n >= 1) each; returns
    (len(items),) m.

    Branch and bound, as :meth:`WorkZone.least_holder_clearance` says: each (tip, probe geom, holder
    geom) triple has a lower bound from :mod:`sim.clearance`; MuJoCo's ``mj_geomDistance`` runs in
    increasing order of bound while the bound is below the least distance found (plus
    :data:`sim.clearance.MARGIN_M`). The vector part is done for every measurement in one pass: the
    holder pairs whose box lies farther than ``distmax`` from the box of every tip of the
    measurement dropped, then the box bound of every remaining (tip, pair) row of every measurement
    in one vectorised expression, sorted by (measurement, bound). MuJoCo's distances and the full
    bound of the rows the box bound leaves close stay per measurement. Each answer is min(distmax,
    every triple's distance) as in the reference (every triple): a triple is left out only when a
    lower bound of its distance exceeds a distance already found by more than the margin, so the
    triple of the least distance is always given a distance: the same float whatever the order.
    The stylus ball's distance from a holder's sphere, cylinder or box is :func:`_ball_distance`'s
    (numpy; MuJoCo's primitive to 1e-17 m, not bit for bit: the reference's MuJoCo distance may
    differ in its last bits), the other triples' MuJoCo's (:meth:`WorkZone._holder_distance`).
    """
    from .clearance import MARGIN_M

    n = len(items)
    out = np.full(n, float(distmax))
    if not n:
        return out
    pre = []  # per item: (zone, its pose, broad phase, holder pairs, hpos, tips R, tips F)
    for wz, T_R_W, tips in items:
        if T_R_W is not None:
            wz.set_table(T_R_W)
        clr = wz.clearance(part="rest")  # (every pair with a holder geom; frame W)
        hp, hpos = wz._holder_pairs(clr)
        tips = np.asarray(tips, float).reshape(-1, 3)
        pre.append((wz, wz._tkey, clr, hp, hpos, tips, clr.to_frame(tips)))
    # the holder pairs of every item, with the box of its tips: those farther than distmax dropped
    # (the distance between two boxes bounds that of any point of one from the other)
    npair = np.array([len(x[3]) for x in pre])
    loT = np.concatenate([x[2]._loT.take(x[3], axis=1) for x in pre], axis=1)
    hiT = np.concatenate([x[2]._hiT.take(x[3], axis=1) for x in pre], axis=1)
    pF = np.concatenate([x[6] for x in pre])  # every item's tips (F), one after another
    nt = np.array([len(x[6]) for x in pre])
    t0 = np.cumsum(nt) - nt
    # (each item's box of tips: one reduceat over all of them, the same least and largest values)
    t_lo = np.repeat(np.minimum.reduceat(pF, t0, axis=0).T, npair, axis=1)
    t_hi = np.repeat(np.maximum.reduceat(pF, t0, axis=0).T, npair, axis=1)
    gap = np.maximum(np.maximum(loT + MARGIN_M - t_hi, t_lo - (hiT - MARGIN_M)), 0.0)
    gap *= gap
    keep = np.sqrt(gap[0] + gap[1] + gap[2]) <= distmax + MARGIN_M
    item_of = np.repeat(np.arange(n), npair)[keep]  # per kept pair: its item
    pair_of = np.concatenate([x[3] for x in pre])[keep]  # its pair in its item's broad phase
    loT, hiT = loT.compress(keep, axis=1) + MARGIN_M, hiT.compress(keep, axis=1) - MARGIN_M  # (the tip's box of contact)
    q = np.bincount(item_of, minlength=n)  # kept pairs per item
    q0 = np.cumsum(q) - q
    # every (tip, kept pair) row of every item, tip-major within an item
    cnt = nt * q
    tot = int(cnt.sum())
    if not tot:
        return out
    item = np.repeat(np.arange(n), cnt)
    local = np.arange(tot) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    qk = q[item]
    tip, prow = np.divmod(local, qk)  # (local // qk, local % qk in one pass)
    tip, prow = tip + t0[item], prow + q0[item]
    pT = np.ascontiguousarray(pF.T).take(tip, axis=1)
    g = np.maximum(loT.take(prow, axis=1) - pT, pT - hiT.take(prow, axis=1))  # the boxes' gap along x, y, z
    worst = np.maximum(np.maximum(g[0], g[1]), g[2])
    m = np.maximum(g, 0.0)
    m *= m
    lb0 = np.where(worst > 0, np.sqrt(m[0] + m[1] + m[2]), worst)
    near = np.flatnonzero(lb0 <= distmax + MARGIN_M)
    # by item, then bound (stable: tip-major on ties): the rows are item-major already, so each
    # item's rows sorted by bound alone, stably (np.lexsort((lb0, item))'s order, item by item)
    lbn = lb0.take(near)
    cut = np.searchsorted(item.take(near), np.arange(n + 1))
    for k in range(n):
        if cut[k + 1] == cut[k]:
            continue
        rows_k = near[cut[k]:cut[k + 1]].take(np.argsort(lbn[cut[k]:cut[k + 1]], kind="stable"))
        wz, tkey, clr, _, hpos, tips, tips_F = pre[k]
        if wz._tkey != tkey:  # (another item of this zone set another pose since)
            wz.set_table(np.frombuffer(tkey).reshape(4, 4))
        i, pair, lb = tip[rows_k] - t0[k], pair_of[prow[rows_k]], lb0[rows_k]
        best = float(distmax)
        pos = 0
        # the first few straight to MuJoCo in the box bound's order (a distance costs less than
        # the full bound of a chunk: in the MFB plans one or two triples are ever within reach)
        while pos < min(len(lb), _DIRECT) and lb[pos] <= best + MARGIN_M:
            best = min(best, wz._holder_distance(clr, hpos, tips[i[pos]], pair[pos], distmax, tips_F[i[pos]]))
            pos += 1
        while pos < len(lb) and lb[pos] <= best + MARGIN_M:
            rows = np.arange(pos, min(pos + 64, len(lb)))
            pos += 64
            rows = rows[lb[rows] <= best + MARGIN_M]
            full = clr.bound(tips, i[rows], pair[rows])
            for j in np.argsort(full, kind="stable"):
                if full[j] > best + MARGIN_M:
                    break
                best = min(best, wz._holder_distance(clr, hpos, tips[i[rows[j]]], pair[rows[j]], distmax,
                                                     tips_F[i[rows[j]]]))
        out[k] = best
    return out


def _zone_xml(table_mjcf: str, probe_mjcf: str) -> str:
    """A work zone's MJCF: the table body (free joint) with ``table_mjcf``'s geoms, then the
    spindle body (free joint) with ``probe_mjcf``'s."""
    return (f'<mujoco model="vmt-mfb-workzone"><compiler angle="radian"/><option gravity="0 0 0"/><worldbody>'
            f'<body name="table"><freejoint name="table"/>{table_mjcf}</body>'
            f'<body name="spindle"><freejoint name="spindle"/>{probe_mjcf}</body>'
            f'</worldbody></mujoco>')


def _ball_model_spec(wz, geoms) -> tuple:
    """(model, data) of :func:`share_ball_model`'s ball model built as an ``MjSpec``: the model
    ``_zone_xml`` of the holders' geoms ``geoms`` (:meth:`WorkZone._geom_spec` each) and the probe's
    stylus ball of radius ``wz._r`` at the spindle's origin (``probe_geoms_mjcf((0, 0, 1), r,
    only=("ball",))``) compiles to, every array equal (tests/sim/test_mfb_scene.py), without writing
    and parsing its MJCF (timeit: 1.9 -> 1.2 ms a compile at load ~9)."""
    mj = wz._mj
    kinds = {"sphere": mj.mjtGeom.mjGEOM_SPHERE, "capsule": mj.mjtGeom.mjGEOM_CAPSULE,
             "cylinder": mj.mjtGeom.mjGEOM_CYLINDER, "box": mj.mjtGeom.mjGEOM_BOX}
    spec = mj.MjSpec()
    spec.modelname = "vmt-mfb-workzone"
    spec.compiler.degree = False  # (<compiler angle="radian"/>)
    spec.option.gravity = [0.0, 0.0, 0.0]
    table = spec.worldbody.add_body(name="table")
    table.add_freejoint(name="table")
    for name, kind, size, pos, quat in geoms:
        sz = [float(v) for v in np.ravel(np.asarray(size, float))]
        if kind not in kinds or not 1 <= len(sz) <= 3 or len(pos) != 3 or (quat is not None and len(quat) != 4):
            raise ValueError(f"ball model: geom {name!r} must be a sphere, capsule, cylinder or box with 1-3 sizes, "
                             f"a position (3) and a quaternion (4) or None; got {kind!r}, size {sz}, pos "
                             f"{list(pos)}, quat {None if quat is None else list(quat)}")
        g = table.add_geom(name=name, type=kinds[kind], size=sz + [0.0] * (3 - len(sz)),
                           pos=[float(v) for v in pos], contype=1, conaffinity=0)
        if quat is not None:
            g.quat = [float(v) for v in quat]
    spindle = spec.worldbody.add_body(name="spindle")
    spindle.add_freejoint(name="spindle")
    spindle.add_geom(name="ball", type=kinds["sphere"], size=[float(wz._r), 0.0, 0.0], contype=0, conaffinity=1)
    m = spec.compile()
    _check_layout(m, wz, len(geoms) + 1)
    return m, mj.MjData(m)


def _check_layout(m, wz, ngeom: int, names=None) -> None:
    """Raise RuntimeError unless the compiled model ``m`` has ``ngeom`` geoms (named ``names`` in
    order, when given) and its table and spindle free joints where the work zone ``wz`` sets them
    (``wz._tq``, ``wz._sq``): the zone's poses and geom numbers would otherwise be another geom's.
    (Checks that hold under ``python -O``, unlike ``assert``.)"""
    if m.ngeom != ngeom:
        raise RuntimeError(f"work zone model: {m.ngeom} geoms compiled, {ngeom} expected")
    if names is not None:
        got = [m.geom(i).name for i in range(m.ngeom)]
        if got != list(names):
            raise RuntimeError(f"work zone model: geoms {got} compiled, {list(names)} expected")
    tq, sq = int(m.jnt_qposadr[m.joint("table").id]), int(m.jnt_qposadr[m.joint("spindle").id])
    if (tq, sq) != (wz._tq, wz._sq):
        raise RuntimeError(f"work zone model: table and spindle joints at qpos {tq}, {sq}; expected {wz._tq}, {wz._sq}")


def share_ball_model(artefact, measurements, stylus_r_m: float, primitives_aside: bool = False) -> list:
    """One MuJoCo model of the stylus ball and the holders of every placement of ``measurements``
    for the least holder clearances of their work zones (instead of one per placement: a compile
    costs about 0.6 ms whatever its few geoms; the 5-axis plan's four placements in one, 0.7 ms).

    ``measurements``: (T_W_A, blocks, J_m, finger_m) of each measurement to be checked with
    :func:`check_measurement` on ``artefact`` with ``stylus_r_m``. Placements that already have
    their ball model keep it. The distances are the same bit for bit: each holder geom is written
    as in its placement's own model (its name prefixed), at the same pose in the table body.
    Returns each measurement's work zone (:func:`_work_zone`), in order.

    ``primitives_aside``: no model when every holder geom is a sphere, cylinder or box (the least
    holder clearances then take the ball's distances from :func:`_ball_distance`, and a
    placement's own ball model is compiled only if MuJoCo is ever asked: :meth:`WorkZone._ball_model`).
    """
    zones, each = {}, []
    _probes_ahead([_probe_key(J_m, stylus_r_m, finger_m) for _, _, J_m, finger_m in measurements])
    for T_W_A, blocks, J_m, finger_m in measurements:
        wz = _work_zone(artefact, T_W_A, blocks, J_m, stylus_r_m, finger_m)
        each.append(wz)
        if ("ball_model", wz._r) not in wz._shared:
            zones.setdefault(id(wz._shared), wz)  # one zone per placement
    if len(zones) < 2:
        return each
    if primitives_aside and all(GEOM_TYPE.get(wz._tkind[j]) in _BALL_KINDS for wz in zones.values() for j in wz._holder):
        return each
    geoms, first = [], []
    for k, wz in enumerate(zones.values()):
        first.append(len(geoms))
        geoms += [wz._geom_spec(j, prefix=f"p{k}_") for j in wz._holder]
    wz = next(iter(zones.values()))
    m, d = _ball_model_spec(wz, geoms)
    names = [g[0] for g in geoms]
    for h0, wz in zip(first, zones.values()):
        wz._shared[("ball_model", wz._r)] = (m, d, h0, len(names))
    return each


#: Compiled work zones by everything their model is made of (the artefact object kept, so
#: its id stays its own): a plan's measurements that share a placement and a stylus share one.
#: Beside them, per placement (key ("placement", artefact id, pose, blocks)) the dict its zones
#: share (their table geoms in W). Safe: the keys hold every input of the model; a zone that
#: outlives its placement's entry keeps its dict. 64 entries (before: cleared at 64).
_ZONES = Memo(64)


def _work_zone(artefact, T_W_A, blocks, J_m, stylus_r_m, finger_m) -> WorkZone:
    key = (id(artefact), np.ascontiguousarray(T_W_A, float).tobytes(), tuple(blocks),  # (Block: frozen, hashable)
           tuple(float(v) for v in J_m), float(stylus_r_m), float(finger_m))

    def build():
        wz = WorkZone(artefact, T_W_A, blocks, J_m, stylus_r_m, finger_m)
        # the dict the placement's zones share: the artefact, its pose, the blocks
        wz._shared = _ZONES.get_or_compute(("placement",) + key[:3], dict, owner=artefact)
        return wz

    return _ZONES.get_or_compute(key, build, owner=artefact)


def block_overlaps(artefact, T_W_A, blocks) -> list:
    """The workholder blocks that run into the bar or its supports at the pose ``T_W_A`` (W, m):
    [(block name, solid name, depth m)], the deepest solid of each overlapping block.

    Separating axes (exact for two boxes: the 3 face normals of each and their 9 cross products):
    a block overlaps a solid when along every axis their projections overlap by more than
    :data:`sim.scene.COLLISION_TOL_M`; the depth is the least of those overlaps. A foot standing
    on a block's face touches it (0 m): not an overlap. A cylinder (a support, a rod) is taken as
    its square prism (side 2 r, on its axis), a sphere as its cube (side 2 r): never cleared when
    it overlaps; a block may be refused when an edge of it passes obliquely within r (sqrt 2 - 1)
    of a cylinder's round side (3.3 mm for the MFB's 8 mm supports), within r (sqrt 3 - 1) of a
    sphere. First the solids' bounding boxes in W (``|R| H`` about the centre) against each block:
    the W axes are the block's face normals, three of the 15, so a solid whose box is clear of the
    block there is clear by the same test; the 15 axes are built only for the solids left."""
    if not blocks:
        return []
    sol = _solid_table(artefact)
    T = np.asarray(T_W_A, float) @ _solid_pose_stack(artefact)  # each solid in W
    C, Rs = T[:, :3, 3], T[:, :3, :3]
    H = _half_sizes(sol)
    e = np.einsum("sjk,sk->sj", np.abs(Rs), H)  # each solid's half extents along the W axes
    out = []
    for b in blocks:
        lo, hi = np.asarray(b.lo, float), np.asarray(b.hi, float)
        hb, cb = (hi - lo) / 2, (lo + hi) / 2
        near = np.flatnonzero((np.abs(C - cb) - hb - e).max(axis=1) < -COLLISION_TOL_M)
        if not near.size:
            continue
        sep = _box_separations(Rs[near], C[near] - cb, H[near], hb)
        j = int(np.argmin(sep))
        if sep[j] < -COLLISION_TOL_M:
            out.append((b.name, sol.names[near[j]], float(-sep[j])))
    return out


def _half_sizes(sol) -> np.ndarray:
    """(k,3) half sizes of the boxes :func:`block_overlaps` tests for the solids: a box's own, a
    cylinder's square prism (r, r, h/2), a sphere's cube (r, r, r)."""
    kinds = np.array(sol.kinds)
    H = sol.size3.copy()
    H[kinds == "cylinder"] = sol.size3[kinds == "cylinder"][:, [0, 0, 1]]
    H[kinds == "sphere"] = sol.size3[kinds == "sphere"][:, [0, 0, 0]]
    return H


def _box_separations(Rs, d, H, hb) -> np.ndarray:
    """The largest separation of each box (rotation Rs (s,3,3), centre ``d`` (s,3) from the block's
    centre, half sizes H (s,3)) from an axis-aligned block of half sizes ``hb`` over the 15 axes:
    the block's normals (W axes), the box's, their cross products (negative: they overlap)."""
    I = np.broadcast_to(np.eye(3), Rs.shape)
    Rt = np.swapaxes(Rs, 1, 2)
    L = np.concatenate([I, Rt, np.cross(np.eye(3)[None, :, None, :], Rt[:, None, :, :]).reshape(-1, 9, 3)], 1)
    n = np.linalg.norm(L, axis=2)
    ok = n > 1e-9  # (a cross product of parallel edges: that axis is a face normal already)
    L = L / np.where(ok, n, 1.0)[..., None]
    r_s = np.einsum("saj,sj->sa", np.abs(np.einsum("sak,skj->saj", L, Rs)), H)  # each box's half extent on each axis
    sep = np.abs(np.einsum("sak,sk->sa", L, d)) - np.abs(L) @ hb - r_s
    return np.where(ok, sep, -np.inf).max(axis=1)


def link_points(T_R_A, starts_R, features, levels, top_A_m, direct=None) -> tuple[np.ndarray, np.ndarray]:
    """The link moves (R, m) between consecutive approach starts: direct within one feature
    and level, else retract along ``z_A`` to ``top_A_m`` + clearance, across, plunge.

    Returns (P (sum cnt, 3), cnt (n - 1,) int): the points of the link into start 1, then
    into start 2, ... (2 or 4 each); n >= 2 starts. All the links' points go through one
    transform back to R (the same values, bit for bit, as transforming each link's points
    alone: tests/sim/test_clearance.py). ``direct``: :func:`_direct_links` of ``features``,
    ``levels`` when already known (then neither is read)."""
    T_A_R = inv_T(T_R_A)
    P, cnt = _link_points_A(apply_T(T_A_R, np.asarray(starts_R, float)), features, levels, top_A_m, direct)
    return apply_T(T_R_A, P), cnt


def _direct_links(features, levels) -> np.ndarray:
    """(n - 1,) bool: which links between consecutive touches are direct (the same feature and level)."""
    f, lv = np.asarray(features, dtype=object), np.asarray(levels)
    return (f[1:] == f[:-1]) & (lv[1:] == lv[:-1])


def _link_points_A(s_A, features, levels, top_A_m, direct=None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`link_points` in A: the links between the starts ``s_A`` (n,3), A, n >= 2 (``direct``:
    :func:`_direct_links` of ``features``, ``levels`` if already known)."""
    a, b = s_A[:-1], s_A[1:]
    if direct is None:
        direct = _direct_links(features, levels)
    zc = np.maximum(np.maximum(top_A_m + LINK_CLEAR_M, a[:, 2]), b[:, 2])
    up_a, up_b = np.column_stack([a[:, :2], zc]), np.column_stack([b[:, :2], zc])
    cnt = np.where(direct, 2, 4)
    st = np.cumsum(cnt) - cnt
    # each point a row of (a, b, up_a, up_b), m rows each, taken in one np.take (the same rows as
    # assigning them in place, a few times faster): a, then b (direct) or up_a, up_b, b
    m = len(a)
    j = np.arange(m)
    src = np.empty(int(cnt.sum()), int)
    src[st] = j
    src[st + 1] = np.where(direct, m + j, 2 * m + j)
    nd = np.flatnonzero(~direct)
    src[st[nd] + 2], src[st[nd] + 3] = 3 * m + nd, m + nd
    return np.concatenate([a, b, up_a, up_b]).take(src, axis=0), cnt


def _segments_A(plans, r: float, top_A_m: float) -> list:
    """Per touch program of ``plans`` (n >= 1 touches each), (a, b) (s,3): the ends, in A, of the
    segments :func:`_paths_of` gives a measurement of that program (rows in the same order), and
    (s,) int: the row of ``a`` that is each row's ``b`` (``b = a.take(nxt, axis=0)``),
    computed in A from the program (the stylus-centre contacts ``w_A + r wn_A``, the starts
    ``clearance_m`` out along ``wn_A``, the links of :func:`_link_points_A`) rather than brought
    back from R: every measurement of a program has the same rows bit for bit, and a touch's
    approach, or a link between the same two touches, the same row in every program (every value
    is computed row by row). They differ from the R rows moved to A by rounding (1e-16 m, far
    below :data:`sim.clearance.MARGIN_M`)."""
    from .clearance import touch_polylines

    n_t = np.array([pl.n for pl in plans])
    t0 = np.cumsum(n_t) - n_t
    Xn = np.concatenate([pl.w_A + r * pl.wn_A for pl in plans])
    start = Xn + np.concatenate([pl.clearance_m * pl.wn_A for pl in plans])
    has = np.ones(len(Xn), bool)
    has[t0] = False  # (a program's first touch has no link)
    feats = np.concatenate([np.asarray(pl.feature, dtype=object) for pl in plans])
    levels = np.concatenate([np.asarray(pl.level) for pl in plans])
    if len(Xn) > 1:  # the links of consecutive starts, those across two programs dropped
        L, cnt = _link_points_A(start, feats, levels, top_A_m)
        keep = has[1:]
        L, cnt = L[np.repeat(keep, cnt)], cnt[keep]
    else:
        L, cnt = np.zeros((0, 3)), np.zeros(0, int)
    P, n_pt, touch, _ = touch_polylines(start, Xn, has, L, cnt)
    nxt = np.arange(1, len(P) + 1)
    nxt[np.cumsum(n_pt) - 1] -= 1  # (a polyline's last point: its closing segment, to itself)
    b = P.take(nxt, axis=0)
    # each program's polylines (its first touch's approach first) and their points
    cut = np.r_[0, np.cumsum(n_pt)][np.r_[np.searchsorted(touch, t0), len(n_pt)]]
    return [(P[cut[j]:cut[j + 1]], b[cut[j]:cut[j + 1]], nxt[cut[j]:cut[j + 1]] - cut[j]) for j in range(len(plans))]


def _paths_of(items, link_step_m, approach_step_m) -> list:
    """The polylines of several measurements in the order checked, sampled at once: per touch i
    the link into ``start[i]`` (from touch i - 1's; none for the first) and the approach
    ``start[i] -> Xn[i]``.

    ``items``: per measurement (start (n,3), Xn (n,3), link points, link counts, plan) as
    :func:`link_points` gives the links, n >= 1 touches. Returns per measurement (Segments,
    touch of each polyline, allowed feature of each (object; one array for the measurements of one
    program, read only), whether each is an approach),
    its segments and sample numbers its own; the same numbers bit for bit as one at a time
    (one :func:`sim.clearance.touch_polylines` and :func:`sim.clearance.flat_path_segments`
    for all: every value is computed row by row)."""
    from .clearance import Segments

    n_t = np.array([it[4].n for it in items])
    t0 = np.cumsum(n_t) - n_t
    has = np.ones(int(n_t.sum()), bool)
    has[t0] = False  # (a measurement's first touch has no link)
    P, n_pt, touch, is_link = touch_polylines(np.concatenate([it[0] for it in items]),
                                              np.concatenate([it[1] for it in items]), has,
                                              np.concatenate([it[2] for it in items]),
                                              np.concatenate([it[3] for it in items]))
    steps = np.where(is_link, float(link_step_m), float(approach_step_m))
    sg = flat_path_segments(P, n_pt, steps, joints=False)
    # each measurement's polylines (its first touch's approach first), their segments (n_pt
    # each: joints=False)
    poly = np.r_[np.searchsorted(touch, t0), len(n_pt)]
    seg0 = np.r_[0, np.cumsum(n_pt)][poly]
    out = []
    allows = {}  # per program (plan object): each polyline's allowed feature (the same for its measurements)
    for j, it in enumerate(items):
        p0, p1, s0, s1 = poly[j], poly[j + 1], seg0[j], seg0[j + 1]
        app = ~is_link[p0:p1]
        allow = allows.get(id(it[4]))
        if allow is None:
            allow = allows[id(it[4])] = np.full(p1 - p0, "", dtype=object)
            allow[app] = np.asarray(it[4].feature, dtype=object)
        out.append((Segments(sg.a[s0:s1], sg.b[s0:s1], sg.k[s0:s1], sg.m[s0:s1], sg.first[s0:s1] - sg.first[s0],
                             sg.path[s0:s1] - p0), touch[p0:p1] - t0[j], allow, app))
    return out


def check_measurement(name, artefact, T_W_A, T_R_W, blocks, J_m, stylus_r_m, plan, finger_m: float = 0.0,
                      link_step_m: float = 3.0e-3, approach_step_m: float = 0.5e-3,
                      broad_phase: bool = True) -> CheckResult:
    """Collision check of one measurement: every approach/retract and link move, the bar on the table, the workholder clear of the bar.

    Parameters
    ----------
    name : str
    artefact : Artefact
    T_W_A : (4,4) float
        Nominal bar pose on the table, m.
    T_R_W : (4,4) float
        Nominal table pose at the measurement's rotary positions, m.
    blocks : sequence of Block
        The workholder (W frame).
    J_m : (3,) float
    stylus_r_m : float
    plan : sim.plans.Plan
        The measurement's touches (A frame).
    finger_m : float
        Finger of a star stylus (:func:`probe_geoms_mjcf`).
    broad_phase : bool
        Skip the samples :mod:`sim.clearance` proves clear (default); False:
        MuJoCo at every sample and every pair (the reference the tests and the
        benchmark compare with).
    """
    return check_measurements(artefact, [(name, T_W_A, T_R_W, blocks, J_m, plan, finger_m)], stylus_r_m,
                              link_step_m, approach_step_m, broad_phase=broad_phase)[0]


def check_measurements(artefact, measurements, stylus_r_m, link_step_m: float = 3.0e-3,
                       approach_step_m: float = 0.5e-3, broad_phase: bool = True) -> list:
    """:func:`check_measurement` of several measurements of one bar: a plan's, in one pass.

    ``measurements``: (name, T_W_A, T_R_W, blocks, J_m, plan, finger_m) each, as the
    arguments of :func:`check_measurement`. Returns their :class:`CheckResult` in order, each
    the one :func:`check_measurement` gives for it alone (MuJoCo at every sample the broad
    phase cannot prove clear, in path order: the same first collision per touch; the same
    least clearance).

    The paths of every measurement are sampled in one :func:`sim.clearance.flat_path_segments`
    and go through the broad phase together (:func:`sim.clearance.near_segments_many`): the
    ball against the bar in A (one broad phase for every measurement, each distinct move bounded
    once: :func:`_near_samples`), the rest of each work zone in W. The work zones' ball models
    are shared (:func:`share_ball_model`). The links of every measurement are computed in A at
    once (:func:`_link_points_A`, each measurement's back in R through its own transform, as
    :func:`link_points` does), and the least clearances of every measurement go through one
    :func:`least_holder_clearances` (its vector part in one pass, MuJoCo per measurement).
    """
    r = float(stylus_r_m)
    ms = [(name, np.asarray(T_W_A, float), np.asarray(T_R_W, float), tuple(blocks), J_m, plan, float(finger_m))
          for name, T_W_A, T_R_W, blocks, J_m, plan, finger_m in measurements]
    each = share_ball_model(artefact, [(m[1], m[3], m[4], m[6]) for m in ms], r, primitives_aside=True)  # (every work zone)
    pts_A = artefact_points(artefact)
    top = float(pts_A[:, 2].max()) + r
    z_bars = {}  # the bar's lowest point in W by placement
    overlaps = {}  # block_overlaps by placement and workholder
    direct = {}  # per program (plan object): its direct links (_direct_links)
    bad, zones, T_R_As, paths = [], [], [], []
    linked = []  # (measurement, starts in A, direct links) of the measurements with links
    ends = {}  # the overshoot ends in R by measurement (CheckResult.positions_R)
    for i, ((name, T_W_A, T_R_W, blocks, J_m, plan, finger_m), wz) in enumerate(zip(ms, each)):
        T_R_A = T_R_W @ T_W_A
        b = []
        # the bar and the workholder on the table's side of its face (W z >= 0)
        key = T_W_A.tobytes()
        if key not in z_bars:
            z_bars[key] = float(apply_T(T_W_A, pts_A)[:, 2].min())
        if z_bars[key] < -1e-9:
            b.append(f"the bar reaches {-z_bars[key] * 1e3:.1f} mm below the table face")
        for blk in blocks:
            if min(blk.lo[2], blk.hi[2]) < -1e-9:
                b.append(f"workholder block {blk.name} below the table face")
        # the workholder clear of the bar and its supports (a foot on a block's face touches it)
        okey = (key, blocks)
        if okey not in overlaps:
            overlaps[okey] = block_overlaps(artefact, T_W_A, blocks)
        b += [f"workholder block {o} runs into the bar's {g} ({dep * 1e3:.2f} mm deep)" for o, g, dep in overlaps[okey]]
        bad.append(b), zones.append(wz), T_R_As.append(T_R_A)
        if plan.n:
            Xn = apply_T(T_R_A, plan.w_A + r * plan.wn_A)
            n_R = apply_R(T_R_A, plan.wn_A)
            start = Xn + plan.clearance_m * n_R
            ends[i] = Xn - plan.overshoot_m * n_R  # (the overshoot ends, as scenarios.mfb.program_positions)
            if plan.n > 1:
                dl = direct.get(id(plan))  # (per program: its features compared once)
                if dl is None:
                    dl = direct[id(plan)] = _direct_links(plan.feature, plan.level)
                # (link_points' starts in A; the links of every measurement computed together below)
                linked.append((i, apply_T(inv_T(T_R_A), start), dl))
            paths.append((start, Xn, np.zeros((0, 3)), np.zeros(0, int)))
        else:
            paths.append(None)
    # the links of every measurement as link_points gives them (the same operations row by row):
    # the starts in A, _link_points_A on all of them at once (the links across two measurements
    # computed and dropped), each measurement's points back to R through its own transform
    if linked:
        n_s = np.array([len(x[1]) for x in linked])
        s0 = np.cumsum(n_s) - n_s
        dl_all = np.ones(int(n_s.sum()) - 1, bool)  # (a dropped link: direct, two points)
        for (_, _, dl), k in zip(linked, s0):
            dl_all[k:k + len(dl)] = dl
        P, cnt = _link_points_A(np.concatenate([x[1] for x in linked]), None, None, top, dl_all)
        p0 = np.r_[0, np.cumsum(cnt)]
        for (i, _, _), k, n in zip(linked, s0, n_s):
            start, Xn = paths[i][:2]
            paths[i] = (start, Xn, apply_T(T_R_As[i], P[p0[k]:p0[k + n - 1]]), cnt[k:k + n - 1])
    # every measurement's polylines in the order checked (per touch i the link into its start,
    # none for the first, then its approach/retract start -> contact), sampled at once
    live = [i for i in range(len(ms)) if paths[i] is not None]
    sgs = [None] * len(ms)
    for i, p in zip(live, _paths_of([paths[i] + (ms[i][5],) for i in live], link_step_m, approach_step_m)
                    if live else ()):
        sgs[i] = p
    near = {}
    if broad_phase and live:
        near = _near_samples(ms, zones, live, sgs)
    out = []
    for i, (name, T_W_A, T_R_W, blocks, J_m, plan, finger_m) in enumerate(ms):
        wz, b = zones[i], bad[i]
        wz.set_table(T_R_W)
        n_samp = 0
        if plan.n:
            sg, path_touch, allow, _ = sgs[i]
            n_samp = sg.n_samples
            idx = near[i] if broad_phase else np.arange(n_samp)
            if idx.size:
                # one past the last sample of each touch (a touch's paths are consecutive)
                touch_end = np.zeros(plan.n, int)
                np.maximum.at(touch_end, path_touch[sg.path], sg.first + sg.m)
                pts, which = sg.points(idx), sg.path[sg.segment_of(idx)]
            bad_touch = set()
            for k in range(len(idx)):  # in path order
                t = int(path_touch[which[k]])
                if t in bad_touch:
                    continue
                hit = wz.collisions(pts[k], allow[which[k]])
                if hit:  # the first collision of touch t: the rest of its samples are not checked
                    g, o, dep = hit[0]
                    b.append(f"{plan.target[t]}: {g} hits {o} ({-dep * 1e3:.2f} mm deep) at "
                             f"{np.round(pts[k] * 1e3, 1).tolist()} mm")
                    bad_touch.add(t)
                    n_samp -= int(touch_end[t] - idx[k] - 1)
        out.append([name, int(plan.n), n_samp, tuple(b)])
    # the least clearance at the approach starts: along every sampled path point it would be
    # exact too, but cost 2.3x this check (bench col_mfb5_measurement_checks_s 0.029 -> 0.069 s
    # against a 0.097 s simulation); the paths between are checked for collision at every sample.
    # Every measurement's in one least_holder_clearances (its vector part in one pass)
    clear = np.full(len(ms), np.inf)
    if broad_phase and live:
        clear[live] = least_holder_clearances([(zones[i], ms[i][2], paths[i][0]) for i in live])
    else:
        for i in live:
            zones[i].set_table(ms[i][2])
            clear[i] = zones[i].least_holder_clearance(paths[i][0], broad_phase=broad_phase)
    return [CheckResult(*r, float(c * 1e3), None if p is None else p[1], _positions(p, ends.get(i), ms[i][5]))
            for i, (r, c, p) in enumerate(zip(out, clear, paths))]


def _positions(path, ends, plan) -> dict | None:
    """:attr:`CheckResult.positions_R` of a measurement from its checked path (start, contacts, links,
    link counts) and overshoot ends: the arrays ``scenarios.mfb.program_positions`` computes, by the same
    expressions on the same operands (the links: :func:`link_points`' rows, as the check computes them)."""
    if path is None:
        return None
    out = {"touches": path[1], "approach starts": path[0], "overshoot ends": ends}
    if plan.n > 1:
        out["links"] = path[2]
    return out


def _near_samples(ms, zones, live, sgs) -> dict:
    """Per measurement (index in ``ms``), the sorted sample numbers of its paths (``sgs``, R) the
    broad phase cannot prove clear (:meth:`WorkZone.near_segments`, every measurement at once).

    Each measurement has two parts, the ball against the bar (its broad phase in A, one per bar
    and ball) and the rest of its work zone (in W, one per zone and orientation). A part's
    segments are computed in its broad phase's frame from the program in A (:func:`_segments_A`;
    in W through the placement ``T_W_A``), so the measurements of a program, and the touches and
    links programs share, have equal rows there bit for bit. Each broad phase bounds each distinct
    row once (:func:`sim.clearance.unique_segments`; the 5-axis plan's ball: 18,364 rows, 1,616
    distinct), every broad phase in one :func:`sim.clearance.near_segments_many` pass that says
    which rows stay open (no certificate of an earlier call, no swept bound proves them clear).
    Only those are then bounded sample by sample, measurement by measurement, with the
    measurement's own samples (its segments' steps, in R, moved to the frame: the points MuJoCo
    would judge), in a second pass over those rows alone. A sample is skipped only when its row's
    segment, or the sample itself, is proven farther than :data:`sim.clearance.MARGIN_M` from every
    pair: the rows in A or W and the R samples moved there differ by rounding (1e-16 m)."""
    from .clearance import Segments, _pieces, near_segments_many, orientations_ahead, unique_segments

    # (a, b) in A per program (plan object; one bar and ball radius for all: check_measurements')
    plans = list({id(ms[i][5]): ms[i][5] for i in live}.values())
    r = zones[live[0]]._r
    segs_A = dict(zip(map(id, plans), _segments_A(plans, r, float(artefact_points(zones[live[0]]._args[0])[:, 2].max())
                                                    + r)))
    rows_F = {}  # per (broad phase, program, placement): (a, b, allowed feature ids) in its frame
    fids = {}  # per (feature numbering, program): each row's allowed feature
    numbering = {}  # per broad phase's feature numbering (its dict's id): its features in order
    in_W = {}  # per (program, placement): its rows in W
    ptag = {}  # per part key in W: (program, placement's bytes, T_W_A)
    fid_of = {}  # per part key: each row's allowed feature as its broad phase's number

    def rows_W(key):  # a part's (a, b, allowed feature) in its frame (in W: moved when first asked)
        got = rows_F[key]
        if got is None:
            pid, pb, place = ptag[key]
            if (pid, pb) not in in_W:
                # (the ends b are rows of a: moved with them, the product being row by row, as
                # link_points' one transform of every link is: the same numbers as b @ R + t)
                a, _, nxt = segs_A[pid]
                aW = a @ place[:3, :3].T + place[:3, 3]
                in_W[pid, pb] = (aW, aW.take(nxt, axis=0))
            got = rows_F[key] = in_W[pid, pb] + (fid_of[key],)
        return got

    bases = {}  # per broad phase (its certificates): [a Clearance, [its part keys]]
    keys = []  # per live measurement: its two part keys (ball, rest)
    # the rest broad phases not kept yet, built first, their probes' boxes in one pass (as the loop
    # below would build each at its measurement)
    asks = []
    for i in live:
        zones[i].set_table(ms[i][2])
        asks.append((zones[i]._by_orientation("rest"), zones[i]._W_R()))
    orientations_ahead(asks)
    ball = zones[live[0]]._ball_base()  # (one per bar and ball radius: every zone's here, check_measurements')
    for i, (bo, W_R) in zip(live, asks):
        sg, _, allow, is_app = sgs[i]
        plan, T_W_A = ms[i][5], ms[i][1]
        if len(segs_A[id(plan)][0]) != len(sg.a):  # (the same polylines, row for row)
            raise RuntimeError(f"_near_samples: {len(sg.a)} path segments, its program's rows in A {len(segs_A[id(plan)][0])}")
        own = []
        # (the two broad phases as kept, not moved to this pose: the rows are given in their frames)
        # (the rest: wz.clearance(part="rest", moved=False) at this measurement's pose, the ask's)
        for clr, place in ((ball, None), (bo.get(W_R, move=False), T_W_A)):
            key = (id(clr._certs), id(plan), b"" if place is None else place.tobytes())
            own.append(key)
            if key in rows_F:
                continue
            if place is not None:  # (in W: its rows moved when asked, _rows_W)
                ptag.setdefault(key, (id(plan), key[2], place))
            # (the program's features as the broad phase's numbers: once per numbering, by its features
            # in order (a plan's table sides number the bar's features alike), and program)
            nk = numbering.get(id(clr._fid))
            if nk is None:
                nk = numbering[id(clr._fid)] = tuple(clr._fid)
            fk = (nk, id(plan))
            if fk not in fids:
                ids = np.full(len(allow), -2)
                ids[is_app] = clr.feature_ids(plan.feature)
                fids[fk] = ids.take(sg.path)
            rows_F[key] = segs_A[id(plan)][:2] + (fids[fk],) if place is None else None
            fid_of[key] = fids[fk]
            bases.setdefault(key[0], [clr, []])[1].append(key)
        keys.append(own)
    # each broad phase's distinct rows, all bounded in one pass: which stay open
    parts, inv = [], {}
    ball_g = None  # per program: its rows' numbers among the ball's distinct rows (A)
    for clr, ks in bases.values():
        n_k = [len(fid_of[k]) for k in ks]
        if len(ks) > 1 and ks[0][2] == b"":  # (the ball, in A: every program's rows)
            a, b, f = (np.concatenate([rows_F[k][j] for k in ks]) for j in range(3))
            first, back = unique_segments(a, b, f)
            a, b, f = a.take(first, axis=0), b.take(first, axis=0), f.take(first)
            ball_g = dict(zip((k[1] for k in ks), _pieces(back, np.cumsum(n_k)[:-1])))
        elif len(ks) > 1 and ball_g is not None:
            first, back = _rest_groups(ks, ball_g, fid_of)
            a, b, f = _rest_rows(ks, n_k, first, segs_A, ptag, fid_of)
        elif len(ks) > 1:  # (no ball groups: the rows in W compared)
            a, b, f = (np.concatenate([rows_W(k)[j] for k in ks]) for j in range(3))
            first, back = unique_segments(a, b, f)
            a, b, f = a.take(first, axis=0), b.take(first, axis=0), f.take(first)
        else:  # (one program's rows, as they are: few repeat)
            a, b, f = rows_W(ks[0])
            back = np.arange(len(f))
        n = len(f)
        parts.append((clr, Segments(a, b, np.ones(n, int), np.ones(n, int), np.arange(n), np.zeros(n, int)), f))
        off = np.cumsum([0] + n_k)
        for j, k in enumerate(ks):
            inv[k] = (len(parts) - 1, back[off[j]:off[j + 1]])
    is_open = near_segments_many(parts, samples=False)
    # the open rows of each measurement, sample by sample (its own samples), in one pass (none
    # when no distinct row of any broad phase is open: the 5-axis plan's case)
    sub, who = [], []
    for n, i in enumerate(live if any(o.any() for o in is_open) else ()):
        sg = sgs[i][0]
        for key in keys[n]:
            p, back = inv[key]
            rows = np.flatnonzero(is_open[p][back])
            if rows.size:
                a, b, f = rows_W(key)
                sub.append((parts[p][0], Segments(a.take(rows, axis=0), b.take(rows, axis=0), sg.k[rows], sg.m[rows], sg.first[rows],
                                                  sg.path[rows]), f[rows]))
                who.append(i)
    out = {i: np.zeros(0, int) for i in live}
    for i, x in zip(who, near_segments_many(sub) if sub else ()):
        if x.size:
            out[i] = np.union1d(out[i], x) if out[i].size else x
    return out


def _rest_groups(ks, ball_g, fid_of) -> tuple[np.ndarray, np.ndarray]:
    """(first, inverse) as :func:`sim.clearance.unique_segments` gives them for the rows in W of
    a rest broad phase's parts ``ks`` (keys of :func:`_near_samples`: (certificates, program,
    placement)), found without the rows: a part's rows are its program's rows in A moved by its
    placement, so two rows are equal in W when they have the same placement and equal rows in
    A, which the ball's distinct rows already tell (``ball_g``: per program, each row's number
    among them; its ends in A and its allowed feature in the ball's numbering, which names the
    bar's features as this one does) with the same allowed feature here (``fid_of``). Integers
    compared instead of 7 words a row hashed (the 5-axis plan: two broad phases of 4,520 and
    2,692 rows). (A rest broad phase is one work zone's, so its parts share one placement; the
    placement's term keeps the groups right if parts of several placements ever met in one.)"""
    places = {}
    pidx = [places.setdefault(k[2], len(places)) for k in ks]
    g = np.concatenate([ball_g[k[1]] for k in ks])
    fr = np.concatenate([fid_of[k] for k in ks]) + 2  # (>= 0: -2 is none)
    pl = np.repeat(pidx, [len(fid_of[k]) for k in ks])
    _, idx, iv = np.unique((g * (int(fr.max()) + 1) + fr) * len(places) + pl, return_index=True,
                           return_inverse=True)  # (idx: each value's first row)
    order = np.argsort(idx)
    rank = np.empty(len(idx), int)
    rank[order] = np.arange(len(idx))
    return idx.take(order), rank.take(iv)


def _rest_rows(ks, n_k, first, segs_A, ptag, fid_of) -> tuple:
    """(a, b, allowed feature) in W of the rows ``first`` (increasing, of the parts ``ks``
    one after another, ``n_k`` rows each) of a rest broad phase: only those rows of each
    program moved by its placement, both ends as rows of one product (row by row: the same numbers
    as the program's every row moved, :func:`_near_samples`' ``rows_W``)."""
    off = np.cumsum([0] + list(n_k))
    cut = np.searchsorted(first, off)
    A, B, F = [], [], []
    for j, k in enumerate(ks):
        sel = first[cut[j]:cut[j + 1]] - off[j]
        if sel.size:
            pid, _, place = ptag[k]
            a, _, nxt = segs_A[pid]
            X = np.concatenate([a.take(sel, axis=0), a.take(nxt.take(sel), axis=0)]) @ place[:3, :3].T + place[:3, 3]
            A.append(X[:len(sel)]), B.append(X[len(sel):]), F.append(fid_of[k].take(sel))
    return np.concatenate(A), np.concatenate(B), np.concatenate(F)
