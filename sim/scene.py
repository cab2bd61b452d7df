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

from .artefacts import Artefact, make_T
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


def _f(v) -> str:
    return " ".join(map(repr, np.ravel(np.asarray(v, float)).tolist()))


def scene_mjcf(artefact: Artefact, probe: ProbeConfig, T_W_A: np.ndarray | None = None) -> tuple[str, list]:
    """MJCF text of the scene and the feature name of each table geom (in order)."""
    T_W_A = artefact.T_W_A if T_W_A is None else np.asarray(T_W_A, float)
    geoms, feats = [], []
    for k, s in enumerate(artefact.solids):
        T = T_W_A @ make_T(s.rot, s.pos)
        name = f"{s.feature or 'body'}__{k}"
        common = f'name="{name}" pos="{_f(T[:3, 3])}" quat="{_f(_quat(T[:3, :3]))}" contype="1" conaffinity="0"'
        if s.kind == "box":
            geoms.append(f'<geom type="box" size="{_f(s.size)}" {common}/>')
        elif s.kind == "cylinder":
            geoms.append(f'<geom type="cylinder" size="{_f(s.size)}" {common}/>')
        elif s.kind == "sphere":
            geoms.append(f'<geom type="sphere" size="{_f(s.size)}" {common}/>')
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
        self.set_table(np.eye(4))

    def set_table(self, T_R_W: np.ndarray) -> None:
        """Place the table (frame W) in R."""
        T = np.asarray(T_R_W, float)
        self.data.qpos[self._tq:self._tq + 3] = T[:3, 3]
        self.data.qpos[self._tq + 3:self._tq + 7] = _quat(T[:3, :3])

    def set_tip(self, p_R) -> None:
        """Place the stylus-tip centre at ``p_R`` (3,), probe frame aligned with R."""
        self.data.qpos[self._sq:self._sq + 3] = p_R
        self.data.qpos[self._sq + 3:self._sq + 7] = (1.0, 0.0, 0.0, 0.0)
        self._mj.mj_kinematics(self.model, self.data)

    def collisions(self, p_R, allow_feature: str = "") -> list[tuple[str, str, float]]:
        """Collisions with the tip at ``p_R``: (probe geom, artefact geom, depth m).

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
        return out

    def clearance(self):
        """The broad phase (:class:`sim.clearance.Clearance`) at the current table pose."""
        from .clearance import Clearance, model_geoms

        key = np.array(self.data.qpos[self._tq:self._tq + 7])
        if self._clr is None or not np.array_equal(self._clr[0], key):
            self.set_tip(np.zeros(3))
            m = self.model
            table = m.body("table").id
            tg = [i for i in range(m.ngeom) if m.geom_bodyid[i] == table]
            pg = [i for i in range(m.ngeom) if m.geom_bodyid[i] != table]
            self._clr = (key, Clearance(model_geoms(m, self.data, pg), model_geoms(m, self.data, tg),
                                        self.geom_feature[tg], pg.index(self.stylus)))
        return self._clr[1]

    def geom_distance(self, geom_a: str, geom_b: str, distmax: float = 1.0) -> float:
        """MuJoCo's signed distance between two named geoms (current poses), m."""
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
    from .clearance import path_samples

    paths = []  # (target index, phase, polyline, step, allowed feature), in the order checked
    for i in range(len(targets)):
        if links[i] is not None and len(links[i]) > 1:
            paths.append((i, "link move", links[i], link_step_m, ""))
        paths.append((i, "approach/retract path", approach[i], approach_step_m, features[i]))
    pts, seg, which = path_samples([p[2] for p in paths], [p[3] for p in paths], joints=True)
    allow = np.array([p[4] for p in paths], dtype=object)[which]
    near = scene.clearance().near(pts, allow, seg) if broad_phase else np.ones(len(pts), bool)
    for k in np.flatnonzero(near):  # in path order
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
    h.update(scene.mjcf.encode())
    h.update(np.ascontiguousarray(scene.data.qpos[scene._tq:scene._tq + 7], float).tobytes())
    h.update(np.array([link_step_m, approach_step_m, COLLISION_TOL_M]).tobytes())
    for f in features:
        h.update(str(f).encode() + b"\0")
    for ln in links:
        if ln is None:
            h.update(b"N")
        else:
            a = np.ascontiguousarray(ln, float)
            h.update(b"L" + np.array(a.shape, np.int64).tobytes() + a.tobytes())
    a = np.ascontiguousarray(approach, float)
    h.update(b"A" + np.array(a.shape, np.int64).tobytes() + a.tobytes())
    return h.digest()
