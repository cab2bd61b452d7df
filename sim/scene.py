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

from .artefacts import Artefact, inv_T, make_T, solid_points
from .clearance import Geoms
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
        self.mjcf, feats = scene_mjcf(artefact, self.probe, T_W_A)
        self.model = mujoco.MjModel.from_xml_string(self.mjcf)
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.geom_feature = np.array([""] * m.ngeom, dtype=object)
        self.geom_name = np.array([m.geom(i).name for i in range(m.ngeom)], dtype=object)
        table = m.body("table").id
        tg = [i for i in range(m.ngeom) if m.geom_bodyid[i] == table]
        for i, f in zip(tg, feats):
            self.geom_feature[i] = f
        self.stylus = m.geom("stylus").id
        self._tq = m.jnt_qposadr[m.joint("table").id]
        self._sq = m.jnt_qposadr[m.joint("spindle").id]
        self._clr = None
        self._table_geoms = np.array(tg, int)
        self._local = None
        self.T_W_A = np.array(artefact.T_W_A if T_W_A is None else T_W_A, float)
        self._model_T_W_A = self.T_W_A  # the placement the model holds (compiled there)
        self._mjcf_digest = hashlib.blake2b(self.mjcf.encode(), digest_size=32).digest()
        self.set_table(np.eye(4))

    def place(self, T_W_A) -> None:
        """Move the artefact to the placement ``T_W_A`` (4,4) in the compiled model.

        The table geoms' poses are written as the compiler would have read them
        from :func:`scene_mjcf` (``T_W_A`` times each solid's pose; quaternion
        normalised): no recompilation. They are written when MuJoCo next needs
        them (:meth:`set_tip`, :meth:`geom_distance`): the broad phase
        (:meth:`clearance`, in the artefact's frame) does not. Artefacts with mesh
        solids (which the compiler re-centres) cannot be moved: build a new :class:`Scene`.
        """
        if any(s.kind not in ("box", "cylinder", "sphere") for s in self.artefact.solids):
            raise ValueError("Scene.place: an artefact with mesh solids needs a new Scene")
        self.T_W_A = np.array(T_W_A, float)  # (the broad phases kept in self._clr are in A: they stay valid)

    def _sync(self) -> None:
        """Write the placement :meth:`place` recorded into the model, if not yet done."""
        if self._model_T_W_A is self.T_W_A:
            return
        T_W_A = self.T_W_A
        m = self.model
        if self._local is None:  # each solid's pose on the artefact, (k,3,3) and (k,3)
            self._local = (np.array([make_T(s.rot, s.pos)[:3, :3] for s in self.artefact.solids]).reshape(-1, 3, 3),
                           np.array([make_T(s.rot, s.pos)[:3, 3] for s in self.artefact.solids]).reshape(-1, 3))
        R_loc, p_loc = self._local
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
        self.data.qpos[self._tq:self._tq + 3] = T[:3, 3]
        self.data.qpos[self._tq + 3:self._tq + 7] = _quat(T[:3, :3])

    def set_tip(self, p_R) -> None:
        """Place the stylus-tip centre at ``p_R`` (3,), probe frame aligned with R."""
        self._sync()
        self.data.qpos[self._sq:self._sq + 3] = p_R
        self.data.qpos[self._sq + 3:self._sq + 7] = (1.0, 0.0, 0.0, 0.0)
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

        Built in the artefact's frame A from the compiled model's geoms and kept per
        orientation of A to the spindle: every placement of the artefact turned the
        same way (a campaign's set-ups moved across the table) shares one, its pair
        data computed once. (Another placement's geoms in A differ from the kept ones
        by rounding, 1e-16 m, against the bounds' 0.1 mm margin.)
        """
        from .clearance import Clearance, model_geoms

        m, d = self.model, self.data
        table = m.body("table").id
        self._mj.mj_kinematics(m, d)
        T_R_A = make_T(np.array(d.xmat[table], float).reshape(3, 3), d.xpos[table]) @ self.T_W_A
        key = np.ascontiguousarray(T_R_A[:3, :3]).tobytes()
        if self._clr is None:
            self._clr = {}
        hit = self._clr.get(key)
        if hit is None:
            if len(self._clr) >= 32:
                self._clr.clear()
            self.set_tip(np.zeros(3))
            tg = self._table_geoms
            pg = [i for i in range(m.ngeom) if m.geom_bodyid[i] != table]
            T_A_R = inv_T(T_R_A)
            R = T_A_R[:3, :3]
            P, H = model_geoms(m, d, pg), model_geoms(m, d, tg)
            P = Geoms(P.centre @ R.T, R @ P.axes, P.kind, P.size, P.rbound)  # about the tip, axes of A
            H = Geoms(H.centre @ R.T + T_A_R[:3, 3], R @ H.axes, H.kind, H.size, H.rbound)
            hit = self._clr[key] = Clearance(P, H, self.geom_feature[tg], pg.index(self.stylus), T_F_R=T_A_R)
        elif not np.array_equal(hit.T_F_R, inv_T(T_R_A)):
            hit = self._clr[key] = hit.moved(inv_T(T_R_A))
        return hit

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
_POINTS: dict = {}


def artefact_points(art: Artefact) -> np.ndarray:
    """All the points of ``art``'s solids (k,3), A frame, m (cached per artefact object)."""
    hit = _POINTS.get(id(art))
    if hit is None or hit[0] is not art:
        if len(_POINTS) > 16:
            _POINTS.clear()
        hit = _POINTS[id(art)] = (art, np.concatenate([solid_points(s) for s in art.solids]))
    return hit[1]


#: Compiled scenes by (artefact object, probe): campaigns re-place them instead of compiling
#: (a study's seeds, the same campaign with other machine errors, each set-up's placement).
_SCENES: dict = {}


def scene_for(artefact: Artefact, probe: ProbeConfig, T_W_A) -> Scene:
    """The :class:`Scene` of ``artefact`` at ``T_W_A`` with ``probe``: compiled once per
    artefact and probe, moved to each placement (:meth:`Scene.place`; a new one per
    placement for an artefact with meshes).

    The table pose is whatever the last user set: set it before use.
    """
    T = np.ascontiguousarray(T_W_A, float)
    movable = all(s.kind in ("box", "cylinder", "sphere") for s in artefact.solids)
    # the probe's geoms are made of these three lengths (scene_mjcf)
    key = (id(artefact), float(probe.stylus_r_m), float(probe.shank_r_m), float(probe.shank_length_m),
           None if movable else T.tobytes())
    hit = _SCENES.get(key)
    if hit is None or hit[0] is not artefact:  # the artefact is kept in the entry: its id stays its own
        if len(_SCENES) >= 64:
            _SCENES.clear()
        hit = _SCENES[key] = (artefact, Scene(artefact, probe, T))
    if not np.array_equal(hit[1].T_W_A, T):
        hit[1].place(T)
    return hit[1]


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
    key = _paths_key(scene, features, links, approach, link_step_m, approach_step_m)
    if key in _PASSED:
        return
    from .clearance import path_segments

    paths = []  # (target index, phase, polyline, step, allowed feature), in the order checked
    for i in range(len(targets)):
        if links[i] is not None and len(links[i]) > 1:
            paths.append((i, "link move", links[i], link_step_m, ""))
        paths.append((i, "approach/retract path", approach[i], approach_step_m, features[i]))
    sg = path_segments([p[2] for p in paths], [p[3] for p in paths], joints=True)
    if broad_phase:
        idx = scene.clearance().near_segments(sg, [p[4] for p in paths])
    else:
        idx = np.arange(sg.n_samples)
    pts, which = sg.points(idx), sg.path[sg.segment_of(idx)]
    for k in range(len(idx)):  # in path order
        i, phase, _, _, feat = paths[which[k]]
        c = scene.collisions(pts[k], feat)
        if c:
            raise PlanError(f"set-up {setup!r} target {targets[i]!r}: {phase} crashes: {c[0][0]} hits "
                            f"{c[0][1]} at {np.round(pts[k] * 1e3, 3).tolist()} mm")
    _PASSED.add(key)


#: Digests of the path checks that found no collision in this process. A check
#: is a pure function of the scene (its MJCF: artefact, probe, placement), the
#: table pose, the paths and the steps; campaigns that repeat a plan on the same
#: set-ups (a study's seeds, a campaign simulated again with other machine
#: errors: the paths are nominal) check it once. Checks that crash are never stored.
_PASSED: set[bytes] = set()


def _paths_key(scene: Scene, features, links, approach, link_step_m: float, approach_step_m: float) -> bytes:
    """Digest of everything :func:`check_touch_paths` reads except the names in its messages."""
    h = hashlib.blake2b(digest_size=32)
    h.update(scene._mjcf_digest)  # the scene as compiled (artefact, probe)
    h.update(np.ascontiguousarray(scene.T_W_A, float).tobytes())  # the placement (Scene.place)
    h.update(np.ascontiguousarray(scene.data.qpos[scene._tq:scene._tq + 7], float).tobytes())
    h.update(np.array([link_step_m, approach_step_m, COLLISION_TOL_M]).tobytes())
    h.update("\0".join(str(f) for f in features).encode() + b"\1")
    arrs = [np.asarray(ln, float) for ln in links if ln is not None]
    # each link's shape (-1 for none), then all their points
    h.update(np.array([x for ln in links for x in ((-1,) if ln is None else (np.ndim(ln),) + np.shape(ln))],
                      np.int64).tobytes() + b"\1")
    if arrs:
        h.update(np.concatenate([a.ravel() for a in arrs]).tobytes())
    a = np.ascontiguousarray(approach, float)
    h.update(b"A" + np.array(a.shape, np.int64).tobytes() + a.tobytes())
    return h.digest()
