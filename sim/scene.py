"""The MuJoCo scene: table with the artefact, spindle with the probe; path checks.

The MJCF model holds two moving bodies, each on a free joint whose pose we
set from the kinematics (we never integrate dynamics; MuJoCo is the
collision engine):

- ``table``: the (rotary) table, pose ``T_R_W``; the artefact's solids are
  its geoms, at ``T_W_A`` times each solid's own pose;
- ``spindle``: origin at the stylus-tip centre, carrying the stylus sphere,
  the shank (capsule along +z of P) and the probe body (a cylinder).

Exactness. Planes (box faces), outer cylinders, spheres are MuJoCo box,
cylinder and sphere geoms whose sphere-box, sphere-cylinder and
sphere-sphere distances are analytic (checked against the exact
primitives to < 1 nm in tests/sim/test_scene.py). A hole has no MuJoCo
primitive: it is represented by convex boxes whose inner faces form the
16-gon inscribed in the hole (they contain all the material, so they are
conservative for collisions); the stylus contact with a *targeted* hole
(and with any targeted feature) is judged by the exact analytic primitive
in :mod:`sim.probe`, so collisions between the stylus and the geoms of the
touch's own feature are ignored while the shank and the probe body are
checked against everything.

A path that collides raises :class:`~core.exceptions.PlanError` naming the
set-up, the target and the phase (link, approach/retract).
"""

from __future__ import annotations

import hashlib

import numpy as np

from core.exceptions import PlanError
from core.memo import Memo

from .artefacts import Artefact, inv_T, make_T, solids_points
from .clearance import GEOM_TYPE, Geoms, Segments, flat_path_segments, rbound, touch_polylines
from .probe import ProbeConfig

#: A contact deeper than this counts as a collision (m).
COLLISION_TOL_M = 1e-9
PROBE_BODY_R_M = 12.5e-3
PROBE_BODY_H_M = 40e-3


def _quat(R: np.ndarray) -> np.ndarray:
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, float).ravel())
    return q


def _free_joint_T(qpos) -> np.ndarray:
    """(4,4) the pose of a free joint's ``qpos`` (7,) (position, quaternion w x y z) as MuJoCo
    computes it (the quaternion normalised, ``mju_normalize4``, turned by ``mju_quat2Mat``)."""
    import mujoco

    q = np.array(qpos, float)
    mujoco.mju_normalize4(q[3:])
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q[3:])
    return make_T(R.reshape(3, 3), q[:3])


def _quats(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z) (k,4) of rotation matrices (k,3,3), w >= 0 (Shepperd)."""
    R = np.asarray(R, float)
    tr = R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2]
    d = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    k = np.argmax(d, axis=1)  # the largest of 4w^2-1, 4x^2-1, ... for a stable square root
    q = np.empty((len(R), 4))
    for j in range(4):
        m = k == j
        Rm = R[m]
        if j == 0:
            s = 2.0 * np.sqrt(1.0 + tr[m])
            q[m] = np.column_stack([s / 4, (Rm[:, 2, 1] - Rm[:, 1, 2]) / s, (Rm[:, 0, 2] - Rm[:, 2, 0]) / s,
                                    (Rm[:, 1, 0] - Rm[:, 0, 1]) / s])
        else:
            a, b, c = j - 1, j % 3, (j + 1) % 3
            s = 2.0 * np.sqrt(1.0 + Rm[:, a, a] - Rm[:, b, b] - Rm[:, c, c])
            v = np.empty((m.sum(), 3))
            v[:, a] = s / 4
            v[:, b] = (Rm[:, b, a] + Rm[:, a, b]) / s
            v[:, c] = (Rm[:, c, a] + Rm[:, a, c]) / s
            q[m] = np.column_stack([(Rm[:, c, b] - Rm[:, b, c]) / s, v])
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def _f(v) -> str:
    return " ".join(map(repr, np.ravel(np.asarray(v, float)).tolist()))


def scene_mjcf(artefact: Artefact, probe: ProbeConfig, T_W_A: np.ndarray | None = None) -> tuple[str, list]:
    """MJCF text of the scene and the feature name of each table geom (in order)."""
    T_W_A = artefact.T_W_A if T_W_A is None else np.asarray(T_W_A, float)
    geoms, feats = [], []
    poses = [T_W_A @ make_T(s.rot, s.pos) for s in artefact.solids]
    pos = [" ".join(map(repr, T[:3, 3].tolist())) for T in poses]
    quat = [" ".join(map(repr, _quat(T[:3, :3]).tolist())) for T in poses]
    for k, s in enumerate(artefact.solids):
        name = f"{s.feature or 'body'}__{k}"
        common = f'name="{name}" pos="{pos[k]}" quat="{quat[k]}" contype="1" conaffinity="0"'
        if s.kind in ("box", "cylinder", "sphere"):
            geoms.append(f'<geom type="{s.kind}" size="{_f(s.size)}" {common}/>')
        else:
            geoms.append(f'<geom type="mesh" mesh="mesh{k}" {common}/>')
        feats.append(s.feature)
    assets = "".join(f'<mesh name="mesh{k}" vertex="{_f(s.vertices)}"/>'
                     for k, s in enumerate(artefact.solids) if s.kind == "mesh")
    r, rs, L = probe.stylus_r_m, probe.shank_r_m, probe.shank_length_m
    probe_geoms = (
        f'<geom name="stylus" type="sphere" size="{r!r}" contype="0" conaffinity="1"/>'
        f'<geom name="shank" type="capsule" fromto="0 0 {r!r} 0 0 {L!r}" size="{rs!r}" contype="0" conaffinity="1"/>'
        f'<geom name="probe_body" type="cylinder" pos="0 0 {L + PROBE_BODY_H_M / 2!r}" '
        f'size="{PROBE_BODY_R_M!r} {PROBE_BODY_H_M / 2!r}" contype="0" conaffinity="1"/>'
    )
    xml = (
        f'<mujoco model="vmt-{artefact.name}"><compiler angle="radian"/>'
        f'<option gravity="0 0 0"/><asset>{assets}</asset><worldbody>'
        f'<body name="table"><freejoint name="table"/>{"".join(geoms)}</body>'
        f'<body name="spindle"><freejoint name="spindle"/>{probe_geoms}</body>'
        f'</worldbody></mujoco>'
    )
    return xml, feats


class Scene:
    """A compiled MuJoCo scene of one artefact placement and one probe.

    Parameters
    ----------
    artefact : Artefact
    probe : ProbeConfig
    T_W_A : (4,4), optional
        Placement of the artefact on the table (default: the artefact's).
    """

    def __init__(self, artefact: Artefact, probe: ProbeConfig | None = None, T_W_A=None):
        import mujoco

        self._mj = mujoco
        self.artefact = artefact
        self.probe = probe or ProbeConfig()
        self.T_W_A = np.array(artefact.T_W_A if T_W_A is None else T_W_A, float)
        self._T0 = self.T_W_A  # the placement the MJCF is written at
        # geom ids, names and features as scene_mjcf writes them: the table body's geoms
        # (one per solid), then the spindle's three
        k = len(artefact.solids)
        names = [f"{s.feature or 'body'}__{j}" for j, s in enumerate(artefact.solids)]
        self.geom_name = np.array(names + ["stylus", "shank", "probe_body"], dtype=object)
        self.geom_feature = np.array([s.feature for s in artefact.solids] + [""] * 3, dtype=object)
        self.stylus = k
        self._table_geoms = np.arange(k)
        self._tq, self._sq = 0, 7  # the two free joints' qpos
        self._qpos = np.zeros(14)
        self._clr = None
        self._local = None
        self._model = self._data = self._mjcf = None
        self._model_T_W_A = None
        self._movable = _movable(artefact)
        self.set_table(np.eye(4))
        if not self._movable:  # meshes: the broad phase reads the compiled model (the compiler re-centres them)
            self.model  # noqa: B018

    @property
    def mjcf(self) -> str:
        """The scene's MJCF (:func:`scene_mjcf`) at the placement it was built with."""
        if self._mjcf is None:
            self._mjcf = scene_mjcf(self.artefact, self.probe, self._T0)[0]
        return self._mjcf

    @property
    def model(self):
        """The compiled MuJoCo model (compiled on first use: the broad phase of an artefact made
        of boxes, cylinders and spheres reads their definitions instead)."""
        if self._model is None:
            m = self._mj.MjModel.from_xml_string(self.mjcf)
            assert [m.geom(i).name for i in range(m.ngeom)] == list(self.geom_name)
            assert m.jnt_qposadr[m.joint("table").id] == self._tq and m.jnt_qposadr[m.joint("spindle").id] == self._sq
            self._model, self._data = m, self._mj.MjData(m)
            self._model_T_W_A = self._T0
        return self._model

    @property
    def data(self):
        self.model  # noqa: B018  (compiles on first use)
        return self._data

    def digest(self) -> bytes:
        """Digest of everything the scene's model is written from (its MJCF at the placement it
        was built with, without writing it out: solids, probe, that placement)."""
        if getattr(self, "_digest", None) is None:
            h = hashlib.blake2b(digest_size=32)
            h.update(b"vmt-scene/2\0")
            sol = self.artefact.solids
            h.update("".join(f"{s.kind}\0{s.feature}\0" for s in sol).encode() + b"\1")
            # every solid's size, rotation, position and vertices (none: empty), with their shapes
            none = np.zeros(0)
            arrs = [np.ascontiguousarray(v, float) for s in sol
                    for v in (s.size, s.rot, s.pos, none if getattr(s, "vertices", None) is None else s.vertices)]
            h.update(np.array([a.shape + (-1,) * (2 - a.ndim) for a in arrs], np.int64).tobytes())
            h.update(b"".join(a.tobytes() for a in arrs))
            pr = self.probe
            h.update(np.array([pr.stylus_r_m, pr.shank_r_m, pr.shank_length_m, PROBE_BODY_R_M,
                               PROBE_BODY_H_M]).tobytes())
            h.update(np.ascontiguousarray(self._T0, float).tobytes())
            self._digest = h.digest()
        return self._digest

    def place(self, T_W_A) -> None:
        """Move the artefact to the placement ``T_W_A`` (4,4) in the compiled model.

        The table geoms' poses are written as the compiler would have read them
        from :func:`scene_mjcf` (``T_W_A`` times each solid's pose; quaternion
        normalised): no recompilation. They are written when MuJoCo next needs
        them (:meth:`set_tip`, :meth:`geom_distance`): the broad phase
        (:meth:`clearance`, in the artefact's frame) does not. Artefacts with mesh
        solids (which the compiler re-centres) cannot be moved: build a new :class:`Scene`.
        """
        if not self._movable:
            raise ValueError("Scene.place: an artefact with mesh solids needs a new Scene")
        self.T_W_A = np.array(T_W_A, float)  # (the broad phases kept in self._clr are in A: they stay valid)

    def _sync(self) -> None:
        """Write the placement :meth:`place` recorded into the model, if not yet done."""
        self.model  # noqa: B018  (compiles on first use)
        if self._model_T_W_A is self.T_W_A:
            return
        T_W_A = self.T_W_A
        m = self.model
        R_loc, p_loc = self._solid_local()
        R = np.einsum("ij,kjl->kil", T_W_A[:3, :3], R_loc)
        q = _quats(R)
        g = self._table_geoms
        m.geom_pos[g] = p_loc @ T_W_A[:3, :3].T + T_W_A[:3, 3]
        m.geom_quat[g] = q / np.sqrt(np.sum(q * q, axis=1))[:, None]
        m.geom_sameframe[g] = 0  # the compiler's "same frame as the body" shortcut no longer holds
        # the compiler's bounding-volume hierarchy of the table body holds the old poses:
        # MuJoCo then tests every geom pair of the two bodies (same contacts, no pruning)
        m.opt.disableflags |= int(self._mj.mjtDisableBit.mjDSBL_MIDPHASE)
        self._model_T_W_A = T_W_A

    def set_table(self, T_R_W: np.ndarray) -> None:
        """Place the table (frame W) in R."""
        T = np.asarray(T_R_W, float)
        self._qpos[self._tq:self._tq + 3] = T[:3, 3]
        self._qpos[self._tq + 3:self._tq + 7] = _quat(T[:3, :3])

    def table_qpos(self) -> np.ndarray:
        """(7,) the table's free-joint position and quaternion (as :meth:`set_table` wrote them)."""
        return self._qpos[self._tq:self._tq + 7]

    def set_tip(self, p_R) -> None:
        """Place the stylus-tip centre at ``p_R`` (3,), probe frame aligned with R."""
        self._sync()
        self._qpos[self._sq:self._sq + 3] = p_R
        self._qpos[self._sq + 3:self._sq + 7] = (1.0, 0.0, 0.0, 0.0)
        self.data.qpos[:] = self._qpos
        self._mj.mj_kinematics(self.model, self.data)

    def collisions(self, p_R, allow_feature: str = "") -> list[tuple[str, str, float]]:
        """Collisions with the tip at ``p_R``: (probe geom, artefact geom, depth m), deepest first.

        Contacts of the stylus with geoms of ``allow_feature`` are ignored
        (the exact primitive judges those).
        """
        self.set_tip(p_R)
        self._mj.mj_collision(self.model, self.data)
        d = self.data
        out = []
        for c in range(d.ncon):
            g1, g2 = d.contact.geom[c]
            dist = d.contact.dist[c]
            if dist > -COLLISION_TOL_M:
                continue
            pg, ag = (g1, g2) if self.geom_feature[g1] == "" and self.model.geom_bodyid[g1] != self.model.geom_bodyid[g2] \
                and self.geom_name[g1] in ("stylus", "shank", "probe_body") else (g2, g1)
            if pg == self.stylus and allow_feature and self.geom_feature[ag] == allow_feature:
                continue
            out.append((str(self.geom_name[pg]), str(self.geom_name[ag]), float(dist)))
        # deepest first (to 1 pm, then by name): MuJoCo's own order (its mid-phase tree)
        # differs between a compiled and a moved scene (Scene.place)
        return sorted(out, key=lambda c: (round(c[2], 12), c[0], c[1]))

    def clearance(self):
        """The broad phase (:class:`sim.clearance.Clearance`) at the current table pose.

        Built in the artefact's frame A and kept per orientation of A to the spindle:
        every placement of the artefact turned the same way (a campaign's set-ups
        moved across the table) shares one, its pair data and certificates computed
        once. The geoms are those the model is written from (:meth:`definition_geoms`;
        the compiled model's for an artefact with meshes); MuJoCo's agree to rounding,
        1e-16 m, against the bounds' 0.1 mm margin.
        """
        from .clearance import ByOrientation, Clearance

        T_A_R = inv_T(_free_joint_T(self.table_qpos()) @ self.T_W_A)
        if self._clr is None:
            P, H = self.definition_geoms() if self._movable else self._model_geoms_A(T_A_R)
            feats = self.geom_feature[self._table_geoms]
            self._clr = ByOrientation(P, lambda P_A, T: Clearance(P_A, H, feats, 0, T_F_R=T))
        return self._clr.get(T_A_R)

    def _solid_local(self) -> tuple[np.ndarray, np.ndarray]:
        """Each solid's pose on the artefact, (k,3,3) and (k,3) (computed once)."""
        if self._local is None:  # (make_T(rot, pos) of every solid)
            sol = self.artefact.solids
            R = np.zeros((len(sol), 3, 3))
            p = np.zeros((len(sol), 3))
            if sol:  # (an empty list does not broadcast into (0, 3, 3))
                R[:] = [np.eye(3) if s.rot is None else s.rot for s in sol]
                p[:] = [s.pos for s in sol]
            self._local = (R, p)
        return self._local

    def definition_geoms(self):
        """(probe, table) :class:`sim.clearance.Geoms` as :func:`scene_mjcf` defines them: the
        probe's about the tip, axes of R (stylus, shank, probe body); the table's in A."""
        if getattr(self, "_defs", None) is not None:
            return self._defs
        art, pr = self.artefact, self.probe
        R_loc, p_loc = self._solid_local()
        kind = np.array([GEOM_TYPE[s.kind] for s in art.solids], int)
        size = np.zeros((len(kind), 3))
        sz = [np.ravel(s.size) for s in art.solids]
        n = np.array([len(v) for v in sz])
        for k in np.unique(n):  # (the solids with k sizes at once)
            j = np.flatnonzero(n == k)
            size[j, :k] = [sz[i] for i in j]
        H = Geoms(p_loc.copy(), R_loc.copy(), kind, size, rbound(kind, size))
        r, rs, L = pr.stylus_r_m, pr.shank_r_m, pr.shank_length_m
        hb = PROBE_BODY_H_M / 2
        # (MuJoCo turns the shank's fromto +z into a frame whose z is -z: the same geom)
        pkind = np.array([GEOM_TYPE[k] for k in ("sphere", "capsule", "cylinder")])
        psize = np.array([[r, 0, 0], [rs, (L - r) / 2, 0], [PROBE_BODY_R_M, hb, 0]])
        P = Geoms(np.array([[0.0, 0, 0], [0.0, 0, (r + L) / 2], [0.0, 0, L + hb]]),
                  np.array([np.eye(3), np.diag([1.0, -1.0, -1.0]), np.eye(3)]), pkind, psize, rbound(pkind, psize))
        self._defs = (P, H)
        return P, H

    def _model_geoms_A(self, T_A_R):
        """(probe about the tip, axes of R; table in A) from the compiled model."""
        from .clearance import model_geoms

        self.set_tip(np.zeros(3))
        m, d = self.model, self.data
        P, H = model_geoms(m, d, [self.stylus, self.stylus + 1, self.stylus + 2]), model_geoms(m, d, self._table_geoms)
        R = T_A_R[:3, :3]
        return P, Geoms(H.centre @ R.T + T_A_R[:3, 3], R @ H.axes, H.kind, H.size, H.rbound)

    def geom_distance(self, geom_a: str, geom_b: str, distmax: float = 1.0) -> float:
        """MuJoCo's signed distance between two named geoms (current poses), m."""
        self._sync()
        m, d = self.model, self.data
        self._mj.mj_kinematics(m, d)
        return float(self._mj.mj_geomDistance(m, d, m.geom(geom_a).id, m.geom(geom_b).id, distmax, None))

    def check_path(self, pts_R: np.ndarray, allow_feature: str = "", step_m: float = 0.5e-3):
        """First collision on the polyline ``pts_R`` (m,3), sampled every ``step_m``.

        MuJoCo at every sample (the reference :func:`check_touch_paths` must agree with).
        Returns ``None`` or ``(point (3,), collisions)``.
        """
        pts = np.asarray(pts_R, float)
        for a, b in zip(pts[:-1], pts[1:]):
            L = np.linalg.norm(b - a)
            k = max(1, int(np.ceil(L / step_m)))
            for f in np.linspace(0.0, 1.0, k + 1):
                p = a + f * (b - a)
                hit = self.collisions(p, allow_feature)
                if hit:
                    return p, hit
        return None


#: Every solid's points (A frame) of the artefacts seen last (the artefact is kept, so its id stays its own).
#: 17 artefacts (before: cleared when above 16, so 17 at most).
_POINTS = Memo(17)


def artefact_points(art: Artefact) -> np.ndarray:
    """All the points of ``art``'s solids (k,3), A frame, m (cached per artefact object)."""
    return _POINTS.get_or_compute(id(art), lambda: solids_points(art.solids), owner=art)


#: Compiled scenes by (artefact object, probe): campaigns re-place them instead of compiling
#: (a study's seeds, the same campaign with other machine errors, each set-up's placement).
#: Safe: keyed by the artefact object (kept in the entry) and the probe lengths the MJCF is made
#: of (and the placement for an artefact with meshes); a scene is moved, never rebuilt, by its
#: users. 64 scenes (before: cleared at 64).
_SCENES = Memo(64)


#: Whether an artefact's solids are all boxes, cylinders and spheres (:func:`_movable`), per artefact
#: object (kept in the entry): :func:`scene_for` asks once per set-up of a campaign (17 x 256 solids
#: looked at for the MFB). 64 artefacts.
_MOVABLE = Memo(64)


def _movable(artefact: Artefact) -> bool:
    """True when a :class:`Scene` of ``artefact`` can be moved (:meth:`Scene.place`): no mesh solid."""
    return all(s.kind in ("box", "cylinder", "sphere") for s in artefact.solids)


def scene_for(artefact: Artefact, probe: ProbeConfig, T_W_A) -> Scene:
    """The :class:`Scene` of ``artefact`` at ``T_W_A`` with ``probe``: compiled once per
    artefact and probe, moved to each placement (:meth:`Scene.place`; a new one per
    placement for an artefact with meshes).

    The table pose is whatever the last user set: set it before use.
    """
    T = np.ascontiguousarray(T_W_A, float)
    movable = _MOVABLE.get_or_compute(id(artefact), lambda: _movable(artefact), owner=artefact)
    # the probe's geoms are made of these three lengths (scene_mjcf)
    key = (id(artefact), float(probe.stylus_r_m), float(probe.shank_r_m), float(probe.shank_length_m),
           None if movable else T.tobytes())
    sc = _SCENES.get_or_compute(key, lambda: Scene(artefact, probe, T), owner=artefact)
    if not np.array_equal(sc.T_W_A, T):
        sc.place(T)
    return sc


def check_touch_paths(scene: Scene, setup: str, targets, features, links, approach,
                      link_step_m: float = 2.0e-3, approach_step_m: float = 0.25e-3,
                      broad_phase: bool = True) -> None:
    """Check every touch's link move and approach/retract path; PlanError on a crash.

    The samples are those of :meth:`Scene.check_path` (every ``link_step_m``
    on the links, ``approach_step_m`` on the approaches), in the same order;
    the ones :mod:`sim.clearance` proves clear of every table geom by more
    than :data:`sim.clearance.MARGIN_M` are skipped, the others go to MuJoCo
    (:meth:`Scene.collisions`), so the first collision reported is the one
    the sample-by-sample check finds.

    Parameters
    ----------
    scene : Scene
        With the table already placed for this set-up.
    setup : str
    targets, features : sequences of str
    links : list of (m,3) arrays
        Link polyline (R, m) from the previous retract point to each start.
    approach : (n,2,3) float
        Start and nominal contact position of the stylus centre (R, m); the
        retract retraces the approach.
    broad_phase : bool
        False: MuJoCo at every sample (the reference the tests compare with).
    """
    check_touch_paths_many([(lambda: scene, setup, targets, features, links, approach)], link_step_m,
                           approach_step_m, broad_phase)


def check_touch_paths_many(items, link_step_m: float = 2.0e-3, approach_step_m: float = 0.25e-3,
                           broad_phase: bool = True) -> None:
    """:func:`check_touch_paths` of several set-ups in turn, their polylines made and sampled at once.

    ``items``: per set-up (pose, setup, targets, features, links, approach), ``pose()`` placing
    the scene for that set-up (its placement and table) and returning it, the rest as
    :func:`check_touch_paths` takes them. The set-ups are checked in order, each as
    :func:`check_touch_paths` checks it alone (its scene posed, its key looked up, its broad
    phase asked, MuJoCo at its samples left open, in path order: the first crash of the first
    set-up that crashes is raised); only the polylines of every set-up (:func:`touch_polylines`)
    and their segments (:func:`flat_path_segments`) are computed in one call each, every value
    row by row, so the same numbers as one set-up at a time (a campaign's 17 set-ups: 34 calls
    -> 2)."""
    if not items:
        return
    # every set-up's polylines in the order checked: per touch its link move (if it has one),
    # then its approach/retract path; all their points in one array
    apps, hass, Ls, cnts = [], [], [], []
    for _, _, targets, _, links, approach in items:
        n = len(targets)
        approach = np.asarray(approach, float).reshape(n, 2, 3)
        try:  # (a campaign's links are all arrays: their lengths in one pass)
            lens = np.fromiter(map(len, links), int, n)
        except TypeError:  # some None
            lens = np.fromiter((0 if ln is None else len(ln) for ln in links), int, n)
        has = lens > 1
        used = links if has.all() else [links[i] for i in np.flatnonzero(has)]
        Ls.append(np.concatenate(used, dtype=float).reshape(-1, 3) if has.any() else np.zeros((0, 3)))
        apps.append(approach), hass.append(has), cnts.append(lens[has])
    if len(items) == 1:
        P, n_pt, touch, is_link = touch_polylines(apps[0][:, 0], apps[0][:, 1], hass[0], Ls[0], cnts[0])
    else:
        A = np.concatenate(apps)
        P, n_pt, touch, is_link = touch_polylines(A[:, 0], A[:, 1], np.concatenate(hass), np.concatenate(Ls),
                                                  np.concatenate(cnts))
    # each set-up's polylines (its touches' and their links), points and segments (n_pt - 1 each)
    n_t = np.array([len(h) for h in hass])
    n_poly = n_t + np.array([int(h.sum()) for h in hass])
    q0 = np.r_[0, np.cumsum(n_poly)]
    t0 = np.r_[0, np.cumsum(n_t)]
    p0 = np.r_[0, np.cumsum(n_pt)][q0]
    s0 = np.r_[0, np.cumsum(n_pt - 1)][q0]
    sg = None  # (every set-up's segments, sampled when a set-up is not found passed)
    joined = {}  # the features' text of the key, per features object
    numbered = {}  # per (broad phase's feature numbering, features object): (that numbering, the features as its numbers)
    for j, (pose, setup, targets, features, _, _) in enumerate(items):
        scene = pose()
        P_j, n_pt_j, is_link_j = P[p0[j]:p0[j + 1]], n_pt[q0[j]:q0[j + 1]], is_link[q0[j]:q0[j + 1]]
        key = _paths_key(scene, features, hass[j], n_pt_j, P_j, link_step_m, approach_step_m, joined)
        if _PASSED.get(key):
            continue
        if sg is None:
            sg = flat_path_segments(P, n_pt, np.where(is_link, link_step_m, approach_step_m), joints=True)
        a, b = s0[j], s0[j + 1]
        sg_j = Segments(sg.a[a:b], sg.b[a:b], sg.k[a:b], sg.m[a:b], sg.first[a:b] - sg.first[a] if a < b else sg.first[a:b],
                        sg.path[a:b] - q0[j])
        if broad_phase:
            # (each polyline's allowed feature as the broad phase's number: -2 on a link, the
            # touch's feature on an approach; the features numbered once per numbering and plan)
            clr = scene.clearance()
            fk = (id(clr._fid), id(features))
            got = numbered.get(fk)
            if got is None or got[0] is not clr._fid:
                got = numbered[fk] = (clr._fid, clr.feature_ids(features))
            ids = np.full(len(n_pt_j), -2)
            ids[~is_link_j] = got[1]
            idx = clr.near_segments(sg_j, feature_ids=ids)
        else:
            idx = np.arange(sg_j.n_samples)
        if idx.size:  # (the allowed features by name, for MuJoCo)
            allow = np.full(len(n_pt_j), "", dtype=object)
            allow[~is_link_j] = np.asarray(features, dtype=object)
        pts, which = sg_j.points(idx), sg_j.path[sg_j.segment_of(idx)]
        touch_j = touch[q0[j]:q0[j + 1]] - t0[j]
        for k in range(len(idx)):  # in path order
            w = which[k]
            c = scene.collisions(pts[k], allow[w])
            if c:
                phase = "link move" if is_link_j[w] else "approach/retract path"
                raise PlanError(f"set-up {setup!r} target {targets[touch_j[w]]!r}: {phase} crashes: {c[0][0]} hits "
                                f"{c[0][1]} at {np.round(pts[k] * 1e3, 3).tolist()} mm")
        _PASSED[key] = True


#: Digests of the path checks that found no collision in this process. A check
#: is a pure function of the scene (its MJCF: artefact, probe, placement), the
#: table pose, the paths and the steps; campaigns that repeat a plan on the same
#: set-ups (a study's seeds, a campaign simulated again with other machine
#: errors: the paths are nominal) check it once. Checks that crash are never stored.
#: Safe: the key is a digest of every input (:func:`_paths_key`). 1,024 checks (32-byte
#: keys; before: unbounded); a repeated MFB campaign's checks take 8 ms with them, 21 ms
#: with the broad phase's certificates alone (CPU, this machine).
_PASSED = Memo(1024)


def _paths_key(scene: Scene, features, has_link: np.ndarray, n_pt: np.ndarray, P: np.ndarray,
               link_step_m: float, approach_step_m: float, joined: dict | None = None) -> bytes:
    """Digest of everything :func:`check_touch_paths` reads except the names in its messages:
    the scene, its placement and table pose, the steps, the features, and the polylines
    checked (which touches have a link move, ``has_link``; the polylines' point counts
    ``n_pt``, links and approaches in turn; their points ``P``). ``joined``: the features' text
    kept per features object (its id; the caller keeps the objects alive: a campaign's set-ups
    share one plan's)."""
    h = hashlib.blake2b(digest_size=32)
    h.update(scene.digest())  # the scene as built (artefact, probe)
    h.update(np.ascontiguousarray(scene.T_W_A, float).tobytes())  # the placement (Scene.place)
    h.update(np.ascontiguousarray(scene.table_qpos(), float).tobytes())
    h.update(np.array([link_step_m, approach_step_m, COLLISION_TOL_M]).tobytes())
    text = None if joined is None else joined.get(id(features))
    if text is None:
        text = "\0".join(map(str, features)).encode() + b"\1"
        if joined is not None:
            joined[id(features)] = text
    h.update(text)
    h.update(np.ascontiguousarray(has_link, bool).tobytes() + b"\1")
    h.update(np.ascontiguousarray(n_pt, np.int64).tobytes() + b"\1")
    h.update(np.ascontiguousarray(P, float).tobytes())
    return h.digest()
