"""Broad phase of the path checks: which path samples are provably clear, in numpy.

The MuJoCo scenes (:mod:`sim.scene`, :mod:`sim.mfb_scene`) have two bodies:
the table (its geoms fixed for one table pose) and the spindle, which only
translates (origin at the stylus-tip centre, axes parallel to R). A path
check asks MuJoCo's ``mj_collision`` at samples of polylines; most samples
are centimetres from anything. This module takes the scene's geoms (type,
size, pose: the definitions its MJCF is written from, or the compiled
model's) and computes LOWER BOUNDS on the distance between each probe geom
(moved with the tip) and each table geom; a sample whose bounds all exceed
:data:`MARGIN_M` cannot collide and is skipped, and only the others go to
``mj_collision`` (the same call as before, in the same order, so the first
collision found is the same).

The bound is the separating-axis gap of two convex sets: for any unit
vector u, ``|(c_G - c_H) . u| - ext_G(u) - ext_H(u)`` is at most their
distance, with ``ext`` the support function about the geom's centre
(sphere ``r``; capsule ``l |a.u| + r``; cylinder ``h |a.u| + r sqrt(1 -
(a.u)^2)``; box ``sum e_i |R_i . u|``; any other type its MuJoCo bounding
radius). The axes tried per pair: the table geom's three axes, the probe
geom's axis, their cross products and the direction from the table geom's
closest point to the probe geom's centre (exact for a sphere against a box,
cylinder or sphere). Candidate pairs come from the geoms' axis-aligned
boxes (exact for the probe's axis-aligned geoms; table geoms' boxes from
their corners or analytic extents), each a sound superset.

Whole segments at once (:meth:`Clearance.near_segments`): along a straight
move ``a -> b`` the offset ``(c_G - c_H) . u`` is linear, so its least
magnitude over the segment is 0 if it changes sign, else the smaller end's:
that gap bounds the distance at every sample of the segment (a swept-geom
bound), and only the pairs it cannot clear are bounded sample by sample.
Each call leaves per-segment certificates (the radius within which the
segment stays clear, since a distance moves no farther than the tip): the
same plan at another placement turned the same way is cleared segment by
segment in a few vector operations. :func:`near_segments_many` does the same
for several broad phases and paths in one pass (a whole plan's measurements:
one set of numpy operations instead of one per measurement and broad phase).

Frames: the geoms may be given in any frame F fixed to the table (``T_F_R``;
the scene uses the artefact's frame A, so one broad phase serves every
placement of the artefact turned the same way); tips are always given in R
(the machine reference, MuJoCo's world); units m.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from core.kinematics import _cross_rows as _cross  # (a_k x b_k for (k,3) rows, without np.cross's overhead)
from core.memo import Memo

#: A sample is skipped only when every probe/table geom pair is at least this far
#: apart (m): 100x MuJoCo's default CCD tolerance (1e-6 m), far above any rounding
#: of its narrow phase, far below the clearances of the plans (mm).
MARGIN_M = 1.0e-4

#: MuJoCo's geom type codes (mjtGeom) by the type names the MJCF writes.
GEOM_TYPE = {"sphere": 2, "capsule": 3, "cylinder": 5, "box": 6}
_SPHERE, _CAPSULE, _CYLINDER, _BOX = (GEOM_TYPE[k] for k in ("sphere", "capsule", "cylinder", "box"))
#: Consecutive segment boxes tested together against the clusters of table geoms first.
_BLOCK = 16
#: Segment boxes are padded by this much (m) before the pairs' boxes are tested: a pair left
#: out is then farther than MARGIN_M from any segment within this distance (the certificates
#: of :meth:`Clearance.near_segments`).
CERT_PAD_M = 0.5e-3


def rbound(kind: np.ndarray, size: np.ndarray) -> np.ndarray:
    """(k,) bounding radii (MuJoCo's geom_rbound) of spheres, capsules, cylinders and boxes of
    types ``kind`` (k,) (:data:`GEOM_TYPE`) and sizes ``size`` (k,3) (MuJoCo's, zero-padded), m."""
    return np.where(kind == _BOX, _row_norm(size),  # (np.linalg.norm(size, axis=1), the same floats)
                    np.where(kind == _CYLINDER, np.hypot(size[:, 0], size[:, 1]),
                             np.where(kind == _CAPSULE, size[:, 0] + size[:, 1], size[:, 0])))


@dataclass(frozen=True)
class Geoms:
    """Convex geoms in R: centre (k,3), axes (k,3,3) columns, type (k,), size (k,3), rbound (k,)."""

    centre: np.ndarray
    axes: np.ndarray
    kind: np.ndarray
    size: np.ndarray
    rbound: np.ndarray

    def take(self, idx) -> "Geoms":
        """The geoms ``idx`` (indices, or a bool mask) in that order: ``np.take`` along the first axis
        (the same values as indexing, a few times faster on rows of several numbers)."""
        idx = np.asarray(idx)
        if idx.dtype == bool:
            idx = np.flatnonzero(idx)
        return Geoms(self.centre.take(idx, axis=0), self.axes.take(idx, axis=0), self.kind.take(idx),
                     self.size.take(idx, axis=0), self.rbound.take(idx))

    def extent(self, u: np.ndarray) -> np.ndarray:
        """Support function about the centre, ``ext(u) = max_x (x - c) . u``, (k,) for unit u (k,3)."""
        au = _tmv(self.axes, u)  # u in the geom's frame
        s = self.size
        r, h = s[:, 0], s[:, 1]
        az = np.abs(au[:, 2])
        return _by_kind(self.kind, ((_SPHERE, lambda: r), (_CAPSULE, lambda: h * az + r),
                                    (_CYLINDER, lambda: h * az + r * np.sqrt(np.maximum(0.0, 1.0 - az * az))),
                                    (_BOX, lambda: np.abs(au[:, 0]) * s[:, 0] + np.abs(au[:, 1]) * s[:, 1]
                                     + np.abs(au[:, 2]) * s[:, 2])), lambda: self.rbound)

    def closest(self, q: np.ndarray) -> np.ndarray:
        """A point of each geom near ``q`` (k,3): the closest for a box, cylinder, sphere (centre
        for other types); only used to choose a separating axis."""
        ql = _tmv(self.axes, q - self.centre)
        s = self.size
        box = np.clip(ql, -s, s)
        rho = np.hypot(ql[:, 0], ql[:, 1])
        f = np.minimum(1.0, s[:, 0] / np.where(rho > 0, rho, 1.0))
        cyl = np.column_stack([ql[:, 0] * f, ql[:, 1] * f, np.clip(ql[:, 2], -s[:, 1], s[:, 1])])
        loc = np.where((self.kind == _BOX)[:, None], box,
                       np.where((self.kind == _CYLINDER)[:, None], cyl, 0.0))
        return self.centre + _mv(self.axes, loc)

    def aabb(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) (k,3): axis-aligned boxes containing the geoms."""
        A = np.abs(self.axes)  # rows: world axis, columns: geom axis
        s = self.size
        r, h = s[:, 0], s[:, 1]
        az = A[:, :, 2]
        half = _by_kind(self.kind[:, None], ((_BOX, lambda: _mv(A, s)), (_CAPSULE, lambda: h[:, None] * az + r[:, None]),
                                             (_CYLINDER, lambda: h[:, None] * az
                                              + r[:, None] * np.sqrt(np.maximum(0.0, 1.0 - az * az))),
                                             (_SPHERE, lambda: r[:, None])), lambda: self.rbound[:, None])
        return self.centre - half, self.centre + half


def _by_kind(kind: np.ndarray, cases, other):
    """Per geom the value of its type's case: ``cases`` ((type code, () -> array), ...), ``other()``
    for any other type; ``kind`` (k,) or (k, 1) the geoms' types. The nested ``np.where`` of every
    case, computed for the types present only (each case's value row by row: the same numbers)."""
    present = set(kind.ravel().tolist())
    fs = [(c, f) for c, f in cases if c in present]
    if not fs or present - {c for c, _ in cases}:  # (a type without a case, or none present)
        out = other()
    else:  # (the last case present stands for every geom the others leave)
        out = fs.pop()[1]()
    for c, f in reversed(fs):
        out = np.where(kind == c, f(), out)
    return out


def model_geoms(model, data, ids) -> Geoms:
    """The geoms ``ids`` of a MuJoCo model at the poses of ``data`` (after ``mj_kinematics``)."""
    ids = np.asarray(ids, int)
    return Geoms(np.array(data.geom_xpos[ids], float), np.array(data.geom_xmat[ids], float).reshape(-1, 3, 3),
                 np.array(model.geom_type[ids], int), np.array(model.geom_size[ids], float),
                 np.array(model.geom_rbound[ids], float))


def _mv(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A_k v_k for (k,3,3), (k,3)."""
    return A[:, :, 0] * v[:, 0, None] + A[:, :, 1] * v[:, 1, None] + A[:, :, 2] * v[:, 2, None]


def _tmv(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A_k^T v_k for (k,3,3), (k,3)."""
    return A[:, 0, :] * v[:, 0, None] + A[:, 1, :] * v[:, 1, None] + A[:, 2, :] * v[:, 2, None]


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = _row_norm(v)  # (np.linalg.norm(v, axis=-1), the same floats)
    ok = n > 1e-12
    return v / np.where(ok, n, 1.0)[..., None], ok


class Clearance:
    """Lower bounds of the probe/table distances for a spindle that only translates.

    Parameters
    ----------
    probe : Geoms
        The spindle body's geoms with the tip centre at the origin, axes of the frame F.
    table : Geoms
        The table body's geoms at the current table pose, frame F.
    table_feature : (k_table,) object
        Feature name of each table geom ("" for none).
    ball : int
        Index in ``probe`` of the stylus ball (the geom allowed to touch its feature).
    T_F_R : (4,4) float, optional
        The frame F the geoms are given in, from R (default: F = R). Every method
        takes tips in R and moves them to F (rounding: 1e-16 m, against the bounds'
        :data:`MARGIN_M`). A frame fixed to the table lets one Clearance serve every
        placement of an artefact with the same orientation to the spindle.
    cert_pad_m : float
        The segment boxes' padding of :meth:`near_segments`, the largest radius of
        its certificates (0: fewer pairs bounded, no certificates; for a broad
        phase that will not see the same plan again).
    pairs : (k_probe, k_table) bool, optional
        The probe/table geom pairs this broad phase bounds (default: all). The
        others are left to another broad phase (:class:`sim.mfb_scene.WorkZone`
        bounds its stylus ball against the bar in one shared by every probe).

    Attributes
    ----------
    pair_probe, pair_table : (k,) int
        The geoms (indices in ``probe`` and ``table``) of every pair the bounds speak of.
    """

    def __init__(self, probe: Geoms, table: Geoms, table_feature, ball: int, T_F_R=None,
                 cert_pad_m: float = CERT_PAD_M, pairs: np.ndarray | None = None, probe_box=None):
        self.probe, self.table, self.ball = probe, table, int(ball)
        self.cert_pad_m = float(cert_pad_m)
        self.T_F_R = None if T_F_R is None else np.array(T_F_R, float)
        plo, phi = probe.aabb() if probe_box is None else probe_box  # (probe_box: its aabb, computed with others')
        self.feature, tlo, thi, cl, h_order, self._fid, tfid = _table_prep(table, table_feature)
        st = _pair_structure(table, table_feature, len(probe.kind), self.ball, pairs)
        self.pair_probe, self.pair_table, self._cstart, self._ccount, self._cballf, cg, ch, (tloT, thiT, pn) = st
        # the tip p puts geom g in collision range of h only if p lies in this box
        # (one coordinate a row, (3, k), for _overlap_rows and box_bound; _lo, _hi (k, 3) are their views).
        # The table side's rows are the pair structure's (tlo.T[:, pair_table], ...); the probe's
        # repeated per probe geom (pair_probe runs through the probe geoms in order, pn pairs each)
        self._loT = tloT - np.repeat(phi.T, pn, axis=1) - MARGIN_M
        self._hiT = thiT - np.repeat(plo.T, pn, axis=1) + MARGIN_M
        self._lo, self._hi = self._loT.T, self._hiT.T
        # (the centre offset at p = 0 of a pair, probe geom's centre minus table geom's: computed for
        # the rows asked, _d0_of; the same subtraction as for every pair at once)
        npair = len(self.pair_probe)
        self._U, self._E = np.empty((npair, 7, 3)), np.empty((npair, 7))  # filled on demand (_axes)
        self._have = np.zeros(npair, bool)
        self._certs = _Certificates()  # of near_segments (shared by the moved copies: same frame)
        # each cluster's box: its table geoms' (ch, the union of their boxes) for its probe geom cg
        # (the same numbers as the least and largest of its pairs' boxes: a difference is monotone),
        # one coordinate a row (3, c), for _overlap_rows and _block_candidates (ch kept so by the
        # pair structure: each element the same subtraction as on the (c, 3) rows, transposed)
        self._cloT = ch[0] - phi.take(cg, axis=0).T - MARGIN_M
        self._chiT = ch[1] - plo.take(cg, axis=0).T + MARGIN_M

    def _axes(self, pair: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(U (r,7,3), E (r,7)): the fixed axes of pairs ``pair`` (the table geom's three, the
        probe geom's axis, their cross products) and the sum of the two extents on each
        (inf on a degenerate cross product: it proves nothing). Computed once per pair."""
        want = np.zeros(len(self._have), bool)
        want[pair] = True
        need = np.flatnonzero(want & ~self._have)  # (sorted, once each)
        if need.size:
            g, h = self.pair_probe[need], self.pair_table[need]
            Ht, Pa = self.table.axes.take(h, axis=0), self.probe.axes.take(g, axis=0)[:, :, 2]
            U = np.empty((len(need), 7, 3))
            U[:, :3] = Ht.transpose(0, 2, 1)  # the table geom's three axes (rows)
            U[:, 3] = Pa
            for j in range(3):  # Pa x (table axis j)
                U[:, 4 + j] = _cross(Pa, Ht[:, :, j])
            U, ok = _unit(U)
            P, T = self.probe.take(np.repeat(g, 7)), self.table.take(np.repeat(h, 7))
            flat = U.reshape(-1, 3)
            E = (P.extent(flat) + T.extent(flat)).reshape(len(need), 7)
            self._U[need], self._E[need] = U, np.where(ok, E, np.inf)
            self._have[need] = True
        return self._U.take(pair, axis=0), self._E.take(pair, axis=0)

    def _d0_of(self, g: np.ndarray, h: np.ndarray) -> np.ndarray:
        """(r,3) the centre offset at p = 0 (probe geom's centre minus table geom's) of the pairs of
        probe geoms ``g`` and table geoms ``h`` (r,): each row the subtraction of every pair's array."""
        return self.probe.centre.take(g, axis=0) - self.table.centre.take(h, axis=0)

    def moved(self, T_F_R) -> "Clearance":
        """The same geoms in F, F now at ``T_F_R`` from R (the table moved with its artefact);
        the pair data (computed or to be) is shared."""
        out = object.__new__(type(self))  # (a shallow copy: copy.copy's protocol costs more)
        out.__dict__.update(self.__dict__)
        out.T_F_R = np.array(T_F_R, float)
        return out

    def to_frame(self, p_R: np.ndarray) -> np.ndarray:
        """Tips ``p_R`` (n,3) in R -> the frame of the geoms (n,3)."""
        p = np.ascontiguousarray(p_R, float).reshape(-1, 3)
        if self.T_F_R is None:
            return p
        return p @ self.T_F_R[:3, :3].T + self.T_F_R[:3, 3]

    def candidates(self, p_R: np.ndarray, group: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(sample index, pair index) of every pair whose boxes overlap at a sample of ``p_R`` (n,3).

        Three levels, each a superset of the next: the box of each ``group`` of
        consecutive samples (a path segment) against the box of each cluster of
        table geoms (one feature's geoms), then against each table geom, then each sample.
        """
        p_R = self.to_frame(p_R)
        n = len(p_R)
        if group is None:
            group = np.zeros(n, int)
        cut = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
        s_cnt = np.diff(np.r_[cut, n])
        s_lo, s_hi = np.minimum.reduceat(p_R, cut, axis=0), np.maximum.reduceat(p_R, cut, axis=0)
        seg, pair = self._box_pairs(s_lo, s_hi)
        # -> (sample, pair)
        k, i = _expand(cut[seg], s_cnt[seg])
        pair = pair[k]
        q = p_R.take(i, axis=0)
        ok = _overlap(q, q, self._lo.take(pair, axis=0), self._hi.take(pair, axis=0))
        return i[ok], pair[ok]

    def _box_pairs(self, s_lo: np.ndarray, s_hi: np.ndarray, allow: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
        """(box index, pair index) of every pair in collision range of a tip somewhere in the
        boxes ``[s_lo, s_hi]`` (s,3): runs of :data:`_BLOCK` consecutive boxes (a path's
        neighbouring segments) against clusters, then each box against the clusters it
        may meet, then against the clusters' pairs; each level a superset of the next.
        ``allow`` (s,) int: per box, the feature (:meth:`feature_ids`) the ball may touch:
        the ball's pairs with its geoms are left out (a cluster is one feature's geoms)."""
        seg, cp = self._block_candidates(s_lo, s_hi, allow)
        return _pair_candidates(s_lo.T.copy(), s_hi.T.copy(), seg, cp, self._cloT, self._chiT, self._cstart,
                                self._ccount, self._loT, self._hiT)

    def _block_candidates(self, s_lo: np.ndarray, s_hi: np.ndarray, allow: np.ndarray | None = None
                          ) -> tuple[np.ndarray, np.ndarray]:
        """(box index, cluster index) of :meth:`_box_pairs`'s first level: runs of :data:`_BLOCK`
        consecutive boxes against the clusters (the ball's clusters of each box's ``allow``
        feature left out).

        :func:`_block_candidates_many` gives the same for several broad phases at once; for one
        it is slower (its row-by-row test against this dense blocks x clusters one: a campaign's
        path checks, 2 calls of 986 and 222 rows, 0.233 -> 0.349 ms), so both are kept."""
        n = len(s_lo)
        cut = np.arange(0, n, _BLOCK)
        b_lo, b_hi = np.minimum.reduceat(s_lo, cut, axis=0), np.maximum.reduceat(s_hi, cut, axis=0)
        # the clusters the box of all the boxes meets (a cluster no block meets is left out: it
        # meets no block either; the rest keep their order, so the output is the same): a work
        # zone's paths meet a fifth of its ~300 clusters' boxes, and the dense test below costs
        # blocks x clusters
        a_lo, a_hi = b_lo.min(axis=0), b_hi.max(axis=0)
        cloT, chiT = self._cloT, self._chiT
        near = (a_hi[0] >= cloT[0]) & (a_lo[0] <= chiT[0]) & (a_hi[1] >= cloT[1]) & (a_lo[1] <= chiT[1]) \
            & (a_hi[2] >= cloT[2]) & (a_lo[2] <= chiT[2])
        cl = np.flatnonzero(near)
        cloT, chiT = cloT[:, cl], chiT[:, cl]
        b_lo, b_hi = b_lo.T[:, :, None], b_hi.T[:, :, None]  # (3, blocks, 1): one coordinate a row
        hit = b_hi[0] >= cloT[0]
        for ax in range(3):  # (a reduction over a last axis of 3 is slow in numpy)
            if ax:
                hit &= b_hi[ax] >= cloT[ax]
            hit &= b_lo[ax] <= chiT[ax]
        blk, cp = np.nonzero(hit)
        cp = cl[cp]
        # (the boxes of each block hit: _expand's runs, all of _BLOCK boxes but the last block's)
        seg = (cut[blk][:, None] + np.arange(_BLOCK)).ravel()
        cp = np.repeat(cp, _BLOCK)
        if n % _BLOCK:
            ok = seg < n
            seg, cp = seg[ok], cp[ok]
        if allow is not None:
            ok = self._cballf[cp] != allow[seg]
            seg, cp = seg[ok], cp[ok]
        return seg, cp

    def swept_bound(self, a_R: np.ndarray, b_R: np.ndarray, pair: np.ndarray) -> np.ndarray:
        """Lower bound (m) of the distance of pair ``pair`` (r,) for every tip on the segment ``a_R -> b_R`` (r,3).

        On an axis u the centre offset ``(d0 + p) . u`` is linear along the
        segment, so its least magnitude is 0 when its signs at the ends differ and
        the smaller end's otherwise; minus the two extents, it bounds the distance
        at every point of the segment (the separating-axis gap of the geom swept
        along the segment). Axes: the direction from the table geom's point nearest
        the probe geom's centre at the segment's middle and, for rows it does not
        prove farther than :data:`MARGIN_M`, the pair's fixed ones.
        """
        return self._swept(self.to_frame(a_R), self.to_frame(b_R), pair)

    def _swept(self, a: np.ndarray, b: np.ndarray, pair: np.ndarray) -> np.ndarray:
        """:meth:`swept_bound` for ends already in the geoms' frame."""
        g, h = self.pair_probe[pair], self.pair_table[pair]
        d0 = self._d0_of(g, h)
        da, db = d0 + a, d0 + b

        def gap(U, E, da, db):  # U (r,j,3), E (r,j)
            sa = U[:, :, 0] * da[:, 0, None] + U[:, :, 1] * da[:, 1, None] + U[:, :, 2] * da[:, 2, None]
            sb = U[:, :, 0] * db[:, 0, None] + U[:, :, 1] * db[:, 1, None] + U[:, :, 2] * db[:, 2, None]
            return np.where(sa * sb > 0, np.minimum(np.abs(sa), np.abs(sb)), 0.0) - E

        # the direction from the table geom's point nearest the probe geom's centre at the
        # segment's middle: most pairs are cleared by it alone
        T = self.table.take(h)
        c_g = self.probe.centre.take(g, axis=0) + 0.5 * (a + b)
        u, ok = _unit(c_g - T.closest(c_g))
        E = self.probe.take(g).extent(u) + T.extent(u)
        out = np.where(ok, gap(u[:, None, :], E[:, None], da, db)[:, 0], -np.inf)
        r = np.flatnonzero(out <= MARGIN_M)
        if r.size:  # the pair's fixed axes (computed once per pair) for the rest
            U, E = self._axes(pair[r])
            out[r] = np.maximum(out[r], np.max(gap(U, E, da.take(r, axis=0), db.take(r, axis=0)), axis=1))
        return out

    def feature_ids(self, features) -> np.ndarray:
        """(k,) int: the table features ``features`` (k,) of str as numbers (-2: "" or none of
        the table's), the same for this broad phase and its moved copies."""
        f = np.asarray(features, dtype=object).ravel()
        return np.fromiter(map(self._fid.get, f, itertools.repeat(-2)), int, len(f))  # ("" is no key)

    def near_segments(self, sg: "Segments", allow_feature=None, feature_ids=None) -> np.ndarray:
        """Sorted sample numbers of ``sg`` where some probe/table pair may be closer than :data:`MARGIN_M`.

        Every other sample is provably farther than :data:`MARGIN_M` from every table
        geom (its ball's pairs with the allowed feature aside), as with :meth:`near` on
        all of ``sg``'s samples; fewer samples may be kept. Per segment: its box
        against the pairs' boxes (padded by ``cert_pad_m``), then
        :meth:`swept_bound` per (segment, pair); only the pairs it cannot clear are
        bounded sample by sample (:meth:`bound`).

        Certificates: each call remembers, per segment it bounded (in the geoms'
        frame), a radius ``r`` within which any segment is clear (the least swept
        bound minus the margin, at most the box padding: every point of a segment
        whose ends moved at most ``r`` moved at most ``r``, and a distance moves no
        farther than the tip). A later call clears at once every segment whose ends
        lie within ``r`` of a remembered segment's with the same allowed feature,
        found by nearest-neighbour search (the same plan at another placement turned
        the same way, another measurement of the same work zone sharing its moves).

        ``allow_feature`` (number of polylines,) of str: as in :meth:`near`, per polyline; or
        ``feature_ids`` (number of polylines,) int: the same already as :meth:`feature_ids` gives them.
        """
        sg_F = Segments(self.to_frame(sg.a), self.to_frame(sg.b), sg.k, sg.m, sg.first, sg.path)
        if feature_ids is not None:
            allow_seg = np.asarray(feature_ids, int)[sg.path]
        else:
            allow_seg = np.full(len(sg.a), -2) if allow_feature is None else self.feature_ids(allow_feature)[sg.path]
        return near_segments_many([(self, sg_F, allow_seg)])[0]

    def box_bound(self, p_R: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """(n, pairs): a lower bound (m) of the signed distance of each pair of ``pairs`` at every
        tip ``p_R`` (n,3), from the two geoms' axis-aligned boxes (frame F): their distance when
        apart, else their largest gap along a box axis (negative, at most the geoms' overlap
        along that axis, so at most their penetration depth, as for :meth:`bound`'s axes).
        Looser than :meth:`bound`, a few operations per row."""
        return self._box_bound_F(self.to_frame(p_R), pairs)

    def _box_bound_F(self, p: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """:meth:`box_bound` of tips ``p`` (n,3) already in the geoms' frame."""
        lo, hi = self._loT.take(pairs, axis=1) + MARGIN_M, self._hiT.take(pairs, axis=1) - MARGIN_M  # the tip's box of contact
        # the boxes' gap along x, y, z, (3, n, pairs)
        pT = p.T[:, :, None]
        g = np.maximum(lo[:, None, :] - pT, pT - hi[:, None, :])
        worst = np.maximum(np.maximum(g[0], g[1]), g[2])
        m = np.maximum(g, 0.0)
        m *= m
        return np.where(worst > 0, np.sqrt(m[0] + m[1] + m[2]), worst)

    def bound(self, p_R: np.ndarray, i: np.ndarray, pair: np.ndarray, enough: float = np.inf) -> np.ndarray:
        """Lower bound of the distance (m) of pair ``pair`` with the tip at sample ``i`` of ``p_R``.

        ``enough``: rows whose fixed axes already prove more than this skip the
        closest-point axis (their bound is then that smaller, still valid, value).
        """
        return self._bound_F(self.to_frame(p_R).take(i, axis=0), pair, enough)

    def _bound_F(self, p: np.ndarray, pair: np.ndarray, enough: float = np.inf) -> np.ndarray:
        """:meth:`bound` of pair ``pair`` (r,) with the tip at ``p`` (r,3), already in the geoms' frame."""
        d = self._d0_of(self.pair_probe[pair], self.pair_table[pair]) + p
        U, E = self._axes(pair)
        out = np.max(np.abs(U[:, :, 0] * d[:, 0, None] + U[:, :, 1] * d[:, 1, None] + U[:, :, 2] * d[:, 2, None])
                     - E, axis=1)
        r = np.flatnonzero(out <= enough)
        if not r.size:
            return out
        g, h, d = self.pair_probe[pair[r]], self.pair_table[pair[r]], d.take(r, axis=0)
        T = self.table.take(h)
        c_g = self.probe.centre.take(g, axis=0) + p.take(r, axis=0)
        u, ok = _unit(c_g - T.closest(c_g))
        dyn = np.abs(u[:, 0] * d[:, 0] + u[:, 1] * d[:, 1] + u[:, 2] * d[:, 2]) - self.probe.take(g).extent(u) - T.extent(u)
        out[r] = np.maximum(out[r], np.where(ok, dyn, -np.inf))
        return out

    def near(self, p_R, allow_feature=None, group=None) -> np.ndarray:
        """(n,) bool: samples where some probe/table pair may be closer than :data:`MARGIN_M`.

        ``allow_feature`` (n,) of str: at each sample, the stylus ball's pairs with the
        geoms of that feature are ignored (the exact primitives judge that contact).
        ``group`` (n,) int: runs of equal values are path segments (speed only: any
        grouping gives the same answer).
        """
        p = np.ascontiguousarray(p_R, float).reshape(-1, 3)
        out = np.zeros(len(p), bool)
        i, pair = self.candidates(p, None if group is None else np.asarray(group))
        if allow_feature is not None:
            allow = np.asarray(allow_feature, dtype=object)
            f = self.feature[self.pair_table[pair]]
            skip = (self.pair_probe[pair] == self.ball) & (f != "") & (f == allow[i])
            i, pair = i[~skip], pair[~skip]
        if i.size:
            close = self.bound(p, i, pair, enough=MARGIN_M) <= MARGIN_M
            out[i[close]] = True
        return out


def axisymmetric(probe: Geoms) -> bool:
    """Whether the probe (about the tip, axes of R) is spheres, capsules and cylinders on its z
    axis: it then looks the same from every direction about that axis."""
    k = probe.kind
    return bool(np.all(probe.centre[:, :2] == 0) and np.all(np.abs(probe.axes[:, 2, 2]) == 1)
                and np.all((k == _SPHERE) | (k == _CAPSULE) | (k == _CYLINDER)))


class ByOrientation:
    """The broad phases of one probe against one table side given in a frame F fixed to the
    table, one per orientation of F to R, each moved with the table (:meth:`Clearance.moved`).

    A probe that translates sees the table side the same way whenever F has the same
    rotation to R; an axisymmetric one (:func:`axisymmetric`) whenever F's image of the
    spindle axis (R's z) is the same: placements that differ by a turn about the spindle
    axis then share one broad phase, its pair data and its certificates. Used by
    :meth:`sim.scene.Scene.clearance` (F = the artefact's frame) and
    :class:`sim.mfb_scene.WorkZone` (F = the table's frame W).

    Parameters
    ----------
    probe : Geoms
        About the tip, axes of R.
    build : callable (probe in F's axes: Geoms, T_F_R (4,4)) -> Clearance
    maxsize : int
        Orientations kept (least recently used out first).
    table : (Geoms, table_feature), optional
        The table side every build passes to :class:`Clearance` (its geoms in F and their
        features): :func:`orientations_ahead` then prepares the table sides of several
        ByOrientation at once (:func:`tables_ahead`). None: each build prepares its own.
    """

    def __init__(self, probe: Geoms, build, maxsize: int = 32, table=None):
        self.probe, self._build = probe, build
        self.axisym = axisymmetric(probe)
        self._memo = Memo(maxsize)
        self.table = table

    def _key(self, R: np.ndarray) -> bytes:
        """The memo key of the orientation ``R`` (3,3) of F to R."""
        return np.ascontiguousarray((R[:, 2] if self.axisym else R) + 0.0).tobytes()  # (+0.0: -0 is +0)

    def _in_F(self, R: np.ndarray) -> Geoms:
        """The probe about the tip, axes of F (F at rotation ``R`` from R)."""
        P = self.probe
        return Geoms(P.centre @ R.T, R @ P.axes, P.kind, P.size, P.rbound)

    def get(self, T_F_R: np.ndarray, move: bool = True) -> Clearance:
        """The broad phase with F at ``T_F_R`` (4,4) from R. ``move=False``: the broad phase of that
        orientation wherever it was last placed (its geoms in F, pairs and certificates, all a
        caller with segments already in F uses; its ``T_F_R`` may be another pose's)."""
        T_F_R = np.asarray(T_F_R, float)
        R = T_F_R[:3, :3]
        key = self._key(R)
        hit = self._memo.get(key)
        if hit is None:
            hit = self._memo[key] = self._build(self._in_F(R), T_F_R)
        elif move and not np.array_equal(hit.T_F_R, T_F_R):
            hit = self._memo[key] = hit.moved(T_F_R)
        return hit


def _pieces(x: np.ndarray, cut) -> list:
    """``np.split(x, cut)`` (views of ``x`` between the increasing row numbers ``cut``) by slicing:
    the same views, without ``np.split``'s per-piece axis swaps (~8 us a piece, 66 pieces a fresh
    5-axis check)."""
    ends = [0, *(int(c) for c in cut), len(x)]
    return [x[i:j] for i, j in zip(ends[:-1], ends[1:])]


def orientations_ahead(asks) -> None:
    """The broad phases ``asks`` ((ByOrientation, T_F_R (4,4)) each) will be asked for, built now if
    not kept, as :meth:`ByOrientation.get` would build each at its first ask (in the order of
    ``asks``, placed at that ask's ``T_F_R``), the probes' boxes in one :meth:`Geoms.aabb` of every
    new orientation's probe (row by row: the same numbers as one probe at a time). Each
    ByOrientation's build must take ``probe_box`` ((lo, hi), the probe's aabb in F)."""
    new, seen = [], set()
    for bo, T_F_R in asks:
        T_F_R = np.asarray(T_F_R, float)
        R = T_F_R[:3, :3]
        key = bo._key(R)
        if (id(bo), key) in seen or bo._memo.get(key) is not None:
            continue
        seen.add((id(bo), key))
        new.append((bo, key, T_F_R, bo._in_F(R)))
    if not new:
        return
    tables_ahead([bo.table for bo, _, _, _ in new if bo.table is not None])
    if len(new) == 1:
        boxes = [new[0][3].aabb()]
    else:
        Ps = [x[3] for x in new]
        lo, hi = Geoms(*(np.concatenate([getattr(P, f) for P in Ps]) for f in ("centre", "axes", "kind", "size", "rbound"))).aabb()
        cut = np.cumsum([len(P.kind) for P in Ps])[:-1]
        boxes = list(zip(_pieces(lo, cut), _pieces(hi, cut)))
    for (bo, key, T_F_R, P), box in zip(new, boxes):
        bo._memo[key] = bo._build(P, T_F_R, probe_box=box)


#: The table side's part of :class:`Clearance` (boxes, clusters, feature numbers) by table
#: Geoms and feature list objects (kept in the entry, so their ids stay theirs): the work
#: zones of one placement (sim.mfb_scene) share their table's geoms, whatever the probe.
#: Safe: keyed by the ids of the two objects the entry keeps (checked with ``is``); read only.
#: Beside them (keys ("features", the names)) the part drawn from a feature list alone (:func:`_feature_prep`),
#: so the 16 entries hold tables and their feature lists together (a fresh 5-axis check asks for
#: 5 table preps on fewer lists; before: cleared at 16).
_TABLE_PREP = Memo(16)


def _table_prep(table: Geoms, table_feature):
    """(feature (k,) object, tlo, thi (k,3), cluster (k,) int, geoms in cluster order (k,),
    feature -> number, each geom's feature number (k,) int (-1: none)) of a table side; computed
    once per (table, table_feature) objects, its feature part (:func:`_feature_prep`) once per
    ``table_feature`` object (a bar's placements on one workholder share it)."""
    return _TABLE_PREP.get_or_compute((id(table), id(table_feature)), lambda: _build_table_prep(table, table_feature),
                                      owner=(table, table_feature))


def _build_table_prep(table: Geoms, table_feature, box=None) -> tuple:
    """:func:`_table_prep`'s answer, computed (``box``: the table's aabb, computed with others')."""
    feature, cl, h_order, fid, tfid = _feature_prep(table_feature)
    tlo, thi = table.aabb() if box is None else box
    return feature, tlo, thi, cl, h_order, fid, tfid


def tables_ahead(tables) -> None:
    """The table preps (:func:`_table_prep`) of ``tables`` ((table Geoms, table_feature) each) not
    kept yet, computed now, in the order given (each table's feature part first, as
    :func:`_build_table_prep` takes it), their boxes in one :meth:`Geoms.aabb` of every new
    table's geoms (row by row: the same numbers as one table at a time; the 5-axis plan's fresh
    check: four table sides of 253-257 geoms, four aabb calls in one)."""
    new, seen = [], set()
    for table, tf in tables:
        key = (id(table), id(tf))
        if key in seen:
            continue
        seen.add(key)
        e = _TABLE_PREP._d.get(key)
        if e is not None and e[0][0] is table and e[0][1] is tf:  # (kept: the memo's own test of its owner)
            continue
        new.append((table, tf))
    if len(new) < 2:
        return
    lo, hi = Geoms(*(np.concatenate([getattr(t, f) for t, _ in new]) for f in ("centre", "axes", "kind", "size", "rbound"))).aabb()
    cut = np.cumsum([len(t.kind) for t, _ in new])[:-1]
    for (table, tf), box in zip(new, zip(_pieces(lo, cut), _pieces(hi, cut))):
        _TABLE_PREP.get_or_compute((id(table), id(tf)), lambda: _build_table_prep(table, tf, box), owner=(table, tf))


def _feature_prep(table_feature) -> tuple:
    """(feature (k,) object, cluster (k,) int, geoms in cluster order (k,), feature -> number, each
    geom's feature number (k,) int (-1: none)) of a table side's features ``table_feature``: what
    :func:`_table_prep` draws from them alone, kept per list of names (in :data:`_TABLE_PREP`; equal
    lists, e.g. two placements' on equal workholders, share one)."""
    def build():
        feature = np.asarray(table_feature, dtype=object)
        # clusters of table geoms (one per feature, one per geom without): pairs sorted by
        # (probe geom, cluster, table geom), with the union of each cluster's boxes
        k = [f if f else f"#{j}" for j, f in enumerate(feature)]
        rank = {x: i for i, x in enumerate(sorted(set(k)))}  # (np.unique's inverse: keys in code-point order)
        cl = np.fromiter(map(rank.__getitem__, k), int, len(k))
        h_order = np.lexsort((np.arange(len(feature)), cl))
        fid = {f: n for n, f in enumerate(dict.fromkeys(filter(None, feature)))}  # features as numbers
        tfid = np.fromiter(map(fid.get, feature, itertools.repeat(-1)), int, len(feature))  # per geom (-1: none)
        return feature, cl, h_order, fid, tfid

    # (keyed by the names themselves: two placements of a bar on equal workholders have equal
    # lists, two objects, one build; the key is the whole value's input, so no owner is needed,
    # the memo's entries all having one: _BY_CONTENT stands for it)
    return _TABLE_PREP.get_or_compute(("features", tuple(table_feature)), build, owner=_BY_CONTENT)


#: The owner of the memo entries keyed by their whole input (:func:`_feature_prep`): no object to keep.
_BY_CONTENT = ("by content",)


#: The pair structure of :class:`Clearance` (pairs sorted by probe geom, cluster, table geom;
#: clusters) by table side, number of probe geoms, ball and pair mask: the broad phases of one
#: table side with the same probe's geom count (a work zone's orientations) share it. Safe: keyed
#: by the ids of the table side's two objects (kept in the entry) and the other inputs; read only.
#: Beside them, the pairs' order drawn from the feature list alone (:func:`_pair_order`), keyed by
#: that list's id (kept in the entry) and the other inputs.
_PAIRS = Memo(64)


def _pair_structure(table: Geoms, table_feature, ng: int, ball: int, pairs):
    """(pair_probe, pair_table (k,) int, cluster start, count (c,) int, each cluster's feature
    number when it is the ball's else -1 (c,), its probe geom (c,), its table geoms' box
    (2, 3, c): lo, hi one coordinate a row, and the table side's rows (tlo.T, thi.T (3, k) of each
    pair's table geom, the pairs of each probe geom (ng,))) for ``ng`` probe geoms against
    ``table`` (:meth:`Clearance.__init__`)."""
    mask = None if pairs is None else np.ascontiguousarray(pairs, bool)
    key = (id(table), id(table_feature), int(ng), int(ball), None if mask is None else (mask.shape, mask.tobytes()))

    def build():
        _, tlo, thi, _, _, _, _ = _table_prep(table, table_feature)
        pair_probe, pair_table, cstart, ccount, cballf, pn = _pair_order(table_feature, ng, ball, key[4], mask)
        # the table side of every pair's rows (whatever the probe's orientation) and the pairs of
        # each probe geom (pair_probe is sorted); each cluster's box reduced along those rows (one
        # coordinate a row: the same least and largest values, reduceat along a row being faster)
        rows = (tlo.T.take(pair_table, axis=1), thi.T.take(pair_table, axis=1), pn)
        cbox = np.stack([np.minimum.reduceat(rows[0], cstart, axis=1), np.maximum.reduceat(rows[1], cstart, axis=1)])
        return pair_probe, pair_table, cstart, ccount, cballf, pair_probe[cstart], cbox, rows

    return _PAIRS.get_or_compute(key, build, owner=(table, table_feature))


def _pair_order(table_feature, ng: int, ball: int, mkey, mask) -> tuple:
    """(pair_probe, pair_table (k,) int, cluster start, count (c,) int, each cluster's feature number
    when it is the ball's else -1 (c,), the pairs of each probe geom (ng,)) of :func:`_pair_structure`:
    its part drawn from the table side's features alone (:func:`_feature_prep`), kept per features
    list object, probe geom count, ball and pair mask (``mkey``: the mask's key) in :data:`_PAIRS`."""
    def build():
        _, cl, h_order, _, tfid = _feature_prep(table_feature)
        nh = len(cl)
        pair_probe, pair_table = np.repeat(np.arange(ng), nh), np.tile(h_order, ng)
        if mask is not None:  # (the order kept: by probe geom, cluster, table geom)
            keep = mask[pair_probe, pair_table]
            pair_probe, pair_table = pair_probe[keep], pair_table[keep]
        ck = pair_probe * (cl.max() + 1) + cl[pair_table]
        cstart = np.flatnonzero(np.concatenate([[True], ck[1:] != ck[:-1]]))
        ccount = np.diff(np.append(cstart, len(ck)))
        # each cluster's feature as a number (_fid) when it is the ball's (the clusters a touch
        # of that feature may meet), else -1
        cballf = np.where(pair_probe[cstart] == ball, tfid[pair_table[cstart]], -1)
        return pair_probe, pair_table, cstart, ccount, cballf, np.bincount(pair_probe, minlength=ng)

    fp = _feature_prep(table_feature)  # (the order is drawn from it alone: kept per its object, shared by equal lists)
    return _PAIRS.get_or_compute(("order", id(fp), int(ng), int(ball), mkey), build, owner=fp)


class _Certificates:
    """Certificates of :meth:`Clearance.near_segments`: segments ``a -> b`` (geoms' frame, m),
    their allowed feature and the radius ``r`` (m) within which a segment is clear.

    :func:`near_segments_many` finds, per query segment, a remembered one with the same allowed
    feature whose ends are nearest: first the segment at the same place in a remembered call of
    as many segments (:meth:`in_order`: the same plan at another placement), then, for the rest,
    the remembered segment in the same cell of a :data:`_CERT_GRID_M` grid in (a, b)
    (:meth:`by_cell`: the same move in another measurement). A certificate applies when ``moved = max(|a - a0|, |b - b0|) < r``
    (a segment whose ends moved by at most ``moved`` has every point moved by at most that);
    a segment whose neighbour lies in another cell is only bounded again.
    """

    def __init__(self):
        self.blocks = []  # (a, b, allow, r) per call
        self._by_len: dict = {}  # the blocks by their number of segments
        self._sorted: list = []  # per block, once needed: (keys, feature, a, b, r) in the keys' order
        self._ids: dict = {}
        self._n = 0

    def _key(self, a, b, allow) -> tuple[np.ndarray, np.ndarray]:
        """(key (n,) uint64, allow (n,) int64): a hash of each segment's grid cell and allowed
        feature, and the feature as a number. Different cells may share a hash: a match is
        only a candidate (:meth:`by_cell` checks its feature and its distance)."""
        if np.issubdtype(np.asarray(allow).dtype, np.integer):  # features as numbers already
            f = np.asarray(allow, np.int64)
        else:
            f = np.fromiter((self._ids.setdefault(x, len(self._ids)) for x in allow), np.int64, len(allow))
        # the cells and the feature weighted by random odd numbers (wraps modulo 2^64), a column
        # at a time: the same sum modulo 2^64 as the row-by-weights product, which numpy does
        # more slowly for integers (the 5-axis plan's check hashes 18,652 rows: 1.0 -> 0.84 ms)
        h = np.round(a[:, 0] * _CELLS[0]).astype(np.int64).view(np.uint64) * _HASH[2]
        for j, x in enumerate((a[:, 1], a[:, 2], b[:, 0], b[:, 1], b[:, 2], f), start=1):
            h += np.round(x * _CELLS[j]).astype(np.int64).view(np.uint64) * _HASH[2 + j]
        h = (h ^ (h >> _S30)) * _HASH[0]  # then splitmix64's finalizer
        h = (h ^ (h >> _S27)) * _HASH[1]
        return h ^ (h >> _S31), f

    def add(self, a, b, allow, r) -> None:
        keep = r > 0
        n = int(np.count_nonzero(keep))
        if not n:
            return
        if self._n + n > _CERT_MAX:
            self.__init__()
        if n == len(r):  # (every segment kept: copies, the same arrays as the compress gives, without its gathers)
            blk = (np.array(a, copy=True), np.array(b, copy=True), np.array(allow, copy=True), np.array(r, copy=True))
        else:
            blk = (a.compress(keep, axis=0), b.compress(keep, axis=0), allow.compress(keep), r.compress(keep))
        self.blocks.append(blk)
        self._by_len.setdefault(len(blk[0]), []).append(blk)
        self._n += n

    def in_order(self, a, b, allow) -> tuple[np.ndarray, np.ndarray]:
        """(r0, moved) (n,) per segment ``a -> b`` (n,3) with ``allow`` (n,): the certificate chosen
        and how far its segment's ends are from the query's (r0 = -inf: none), from the remembered
        calls of as many segments with the same allowed features (the same plan at another
        placement)."""
        n = len(a)
        r0, moved = np.full(n, -np.inf), np.full(n, np.inf)
        if not self._n or not n:
            return r0, moved
        for a0, b0, allow0, rr in self._by_len.get(n, ()):
            if np.array_equal(allow0, allow):
                mv = _moved(a, b, a0, b0)
                better = rr - mv > r0 - moved
                r0[better], moved[better] = rr[better], mv[better]
                if (moved < r0).all():  # (every segment cleared: other blocks cannot clear more)
                    break
        return r0, moved

    def by_cell(self, a, b, allow, rest, r0, moved) -> None:
        """After :meth:`in_order`, for the segments ``rest`` (sorted indices) only: the
        remembered segment in the same grid cell (the same move elsewhere), block by block;
        ``r0``, ``moved`` updated in place."""
        q, f = self._key(a.take(rest, axis=0), b.take(rest, axis=0), allow[rest])
        for j in range(len(self.blocks)):
            if j == len(self._sorted):  # (each block's keys computed and sorted once)
                A, B, F, R = self.blocks[j]
                k, fk = self._key(A, B, F)
                o = np.argsort(k, kind="stable")
                self._sorted.append((k[o], fk[o], A.take(o, axis=0), B.take(o, axis=0), R[o]))
            keys, F, A, B, R = self._sorted[j]
            i = np.minimum(np.searchsorted(keys, q), len(keys) - 1)
            hit = np.flatnonzero((keys[i] == q) & (F[i] == f))  # (a hash match with another feature: none)
            if not hit.size:
                continue
            at, i = rest[hit], i[hit]
            mv = _moved(a.take(at, axis=0), b.take(at, axis=0), A.take(i, axis=0), B.take(i, axis=0))
            better = R[i] - mv > r0[at] - moved[at]
            r0[at[better]], moved[at[better]] = R[i][better], mv[better]
            left = ~(moved[rest] < r0[rest])
            if not left.all():
                rest, q, f = rest[left], q[left], f[left]
                if not rest.size:
                    break


#: Remembered segments per broad phase before the certificates are forgotten (memory).
_CERT_MAX = 200_000
#: Grid (m) of the certificates' second lookup: segments whose ends round to the same cells.
_CERT_GRID_M = 1.0e-6
#: The certificates' cell hash (:meth:`_Certificates._key`): splitmix64's two multipliers, then
#: seven odd weights (drawn once) of the six cell coordinates and the feature; the shifts; the
#: scale of each column (cells of _CERT_GRID_M, the feature number as it is).
_HASH = np.array([0xBF58476D1CE4E5B9, 0x94D049BB133111EB, 0x8F1A6C3B5D2E4F71, 0xC6A4A7935BD1E995,
                  0x2545F4914F6CDD1D, 0xD1B54A32D192ED03, 0xAEF17502108EF2D9, 0xF1357AEA2E62A9C5,
                  0x9FB21C651E98DF25], dtype=np.uint64)
_S30, _S27, _S31, _S29 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(29)
_CELLS = np.array([1.0 / _CERT_GRID_M] * 6 + [1.0])


def _overlap(lo1, hi1, lo2, hi2) -> np.ndarray:
    """(k,) bool: boxes [lo1, hi1] and [lo2, hi2] (k,3) intersect (closed)."""
    ok = (hi1[:, 0] >= lo2[:, 0]) & (lo1[:, 0] <= hi2[:, 0])
    for ax in (1, 2):
        ok &= (hi1[:, ax] >= lo2[:, ax]) & (lo1[:, ax] <= hi2[:, ax])
    return ok


def _moved(a, b, a0, b0) -> np.ndarray:
    """(n,) how far segments ``a0 -> b0`` moved to ``a -> b`` (n,3): the larger of their ends'
    distances, which bounds every point's."""
    da, db = a - a0, b - b0
    return np.sqrt(np.maximum(np.einsum("ij,ij->i", da, da), np.einsum("ij,ij->i", db, db)))


def _overlap_rows(lo1, hi1, i1, lo2, hi2, i2) -> np.ndarray:
    """Sorted positions r where boxes ``i1[r]`` of (lo1, hi1) and ``i2[r]`` of (lo2, hi2) intersect
    (closed; boxes given one coordinate a row, (3, k)): :func:`_overlap` one axis at a time,
    each on the rows the axes before left."""
    # (np.take and compress: the same elements as indexing, faster on tens of thousands of rows)
    r = np.flatnonzero((hi1[0].take(i1) >= lo2[0].take(i2)) & (lo1[0].take(i1) <= hi2[0].take(i2)))
    for ax in (1, 2):
        a, b = i1.take(r), i2.take(r)
        r = r.compress((hi1[ax].take(a) >= lo2[ax].take(b)) & (lo1[ax].take(a) <= hi2[ax].take(b)))
    return r


def _pair_candidates(sT_lo, sT_hi, seg, cp, cloT, chiT, cstart, ccount, loT, hiT, rows_done: bool = False
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(box index, pair index) of the (box ``seg``, cluster ``cp``) candidates whose boxes meet:
    each box against its clusters' box, then against each pair of the cluster (:meth:`Clearance._box_pairs`'s
    second and third levels). Boxes (3, s) one coordinate a row; clusters ``cloT``, ``chiT`` (3, c)
    with their pairs ``cstart``, ``ccount`` (c,) among the pairs' boxes ``loT``, ``hiT`` (3, k).
    ``rows_done``: the candidates have passed the first test already (:func:`_block_rows`)."""
    if not rows_done:
        ok = _overlap_rows(sT_lo, sT_hi, seg, cloT, chiT, cp)
        seg, cp = seg.take(ok), cp.take(ok)
    # -> (segment, pair) for the cluster's member geoms (_expand's runs, each candidate's segment
    # repeated along its run: the same rows as seg.take of _expand's run numbers, one gather fewer)
    cnt = ccount.take(cp)
    pair = np.arange(int(cnt.sum())) + np.repeat(cstart.take(cp) - (np.cumsum(cnt) - cnt), cnt)
    seg = np.repeat(seg, cnt)
    ok = _overlap_rows(sT_lo, sT_hi, seg, loT, hiT, pair)
    return seg.take(ok), pair.take(ok)


def near_segments_many(parts, samples: bool = True) -> list:
    """:meth:`Clearance.near_segments` of several broad phases and paths at once.

    Parameters
    ----------
    parts : sequence of (Clearance, Segments, (s,) int)
        Per part a broad phase, the segments of its paths already in its geoms' frame
        (:class:`Segments` whose ``a``, ``b`` are in F; the sample numbers are its own) and
        each segment's allowed feature as a number (:meth:`Clearance.feature_ids`; -2: none).

    samples : bool
        False: stop before the samples and return, per part, which segments are left open.

    Returns
    -------
    list of (k,) int
        Per part, its sorted sample numbers where some pair may come closer than
        :data:`MARGIN_M`: every other sample is provably farther. With ``samples=False``, per
        part a (s,) bool: the segments that no certificate and no swept bound proves clear
        (a covered row, below, as the row before it); every point of the others is provably
        farther (their ``k``, ``m``, ``first`` are not read: any sampling of them is clear).

    Each part is first looked up in its broad phase's certificates (as they stand before
    this call; the grid-cell look-up for every part of a broad phase at once), then the
    segments no certificate clears go through the same three box levels, swept bound and
    sample bounds as in :meth:`Clearance.near_segments`, the parts of every broad phase
    together (one set of numpy operations for a whole plan, the first box level too:
    :func:`_block_candidates_many`; the swept and sample bounds per broad phase); each part
    then leaves its certificates. Parts of moved copies of one broad phase
    (:meth:`Clearance.moved`) share its pair data and certificates.

    A polyline's closing point (a segment of one sample where the segment before ends, the
    same feature allowed: :func:`_covered`; two in five of a plan's rows) is neither looked
    up nor bounded nor remembered: it lies on the segment before, so it is clear when that
    one is (cleared by a certificate, or every pair's swept bound above the margin); when that
    one may come near, the point is bounded after it on its own. The set of samples
    returned may differ from bounding the point itself only by samples proven clear.
    """
    n_parts = len(parts)
    out = [np.zeros(0, int)] * n_parts
    if not n_parts:
        return out
    bases, base_of = [], []  # the distinct broad phases (moved copies share their certificates)
    where = {}
    for clr, sg, allow in parts:
        b = where.setdefault(id(clr._certs), len(bases))
        if b == len(bases):
            bases.append(clr)
        base_of.append(b)
    # the rows covered by the row before them (:func:`_covered`: a polyline's closing point, the
    # end of its last segment) are neither looked up nor bounded: the row before clears them
    # (every point of a segment proven clear is clear) or they are bounded after it (below)
    n_of = np.fromiter((len(p[1].a) for p in parts), int, n_parts)
    off = np.r_[0, np.cumsum(n_of)]
    if n_parts == 1:
        cat = (parts[0][1].a, parts[0][1].b, parts[0][2])
    else:
        cat = (np.concatenate([p[1].a for p in parts]), np.concatenate([p[1].b for p in parts]),
               np.concatenate([p[2] for p in parts]))
    cov = _covered(*cat, off)
    # each part's rows looked up (None: all of them, as they are)
    own = [np.flatnonzero(~cov[off[j]:off[j + 1]]) for j in range(n_parts)] if cov.any() else [None] * n_parts
    # the certificates: per part in order, then by grid cell for every part of a broad phase at once
    todo, full = [None] * n_parts, [False] * n_parts  # (full: every segment of the part, no gather)
    plain = True  # (no certificate: every part's rows looked up are bounded)
    for b, clr in enumerate(bases):
        js = [j for j in range(n_parts) if base_of[j] == b]
        if not clr._certs._n:  # (no certificate yet: every segment is bounded)
            for j in js:
                todo[j], full[j] = (np.arange(n_of[j]), True) if own[j] is None else (own[j], False)
            continue
        plain = False
        def looked_up(j, x):  # (part j's rows of x that are looked up)
            return x if own[j] is None else x.take(own[j], axis=0)

        qa = [looked_up(j, parts[j][1].a) for j in js]
        qb = [looked_up(j, parts[j][1].b) for j in js]
        qf = [looked_up(j, parts[j][2]) for j in js]
        found = [clr._certs.in_order(x, y, f) for x, y, f in zip(qa, qb, qf)]
        cut = np.cumsum([0] + [len(x[0]) for x in found])
        r_old, moved = np.concatenate([x[0] for x in found]), np.concatenate([x[1] for x in found])
        rest = np.flatnonzero(~(moved < r_old))
        if rest.size and clr._certs._n:
            clr._certs.by_cell(np.concatenate(qa), np.concatenate(qb), np.concatenate(qf), rest, r_old, moved)
        for k, j in enumerate(js):  # the segments no certificate clears
            left = np.flatnonzero(~(moved[cut[k]:cut[k + 1]] < r_old[cut[k]:cut[k + 1]]))
            todo[j] = left if own[j] is None else own[j][left]
    # the segments to bound, every part's in turn (the parts of one broad phase together): ends
    # (F), padded boxes, steps, samples
    live = sorted((j for j in range(n_parts) if len(todo[j])), key=lambda j: base_of[j])
    if not live:
        return out if samples else [np.zeros(n, bool) for n in n_of]
    cnt = np.zeros(n_parts, int)
    cnt[live] = [len(todo[j]) for j in live]
    row0 = np.zeros(n_parts, int)
    row0[live] = np.cumsum(cnt[live]) - cnt[live]
    def pick(x, j):  # part j's rows of x to bound
        return x if full[j] else x.take(todo[j], axis=0)

    if plain and live == list(range(n_parts)):  # (the rows not covered, as they are: one gather of all)
        A, B, allow = cat if not cov.any() else (x.compress(~cov, axis=0) for x in cat)
    else:
        A = np.concatenate([pick(parts[j][1].a, j) for j in live])
        B = np.concatenate([pick(parts[j][1].b, j) for j in live])
        allow = np.concatenate([pick(parts[j][2], j) for j in live])
    pad = np.repeat([parts[j][0].cert_pad_m for j in live], cnt[live])
    lo, hi = np.minimum(A, B) - pad[:, None], np.maximum(A, B) + pad[:, None]
    # the pairs and clusters of every broad phase as one table
    pair0 = np.cumsum([0] + [len(c.pair_probe) for c in bases])
    cl0 = np.cumsum([0] + [len(c._cstart) for c in bases])
    if len(bases) == 1:
        U = bases[0]
        cloT, chiT, cstart, ccount, loT, hiT = U._cloT, U._chiT, U._cstart, U._ccount, U._loT, U._hiT
    else:
        cloT = np.concatenate([c._cloT for c in bases], axis=1)
        chiT = np.concatenate([c._chiT for c in bases], axis=1)
        cstart = np.concatenate([c._cstart + pair0[b] for b, c in enumerate(bases)])
        ccount = np.concatenate([c._ccount for c in bases])
        loT = np.concatenate([c._loT for c in bases], axis=1)
        hiT = np.concatenate([c._hiT for c in bases], axis=1)
    sT_lo, sT_hi = lo.T.copy(), hi.T.copy()  # (the boxes one coordinate a row: the box levels' rows)
    # the first box level (blocks of rows against clusters), every broad phase's rows at once
    groups = [(b, row0[js[0]], row0[js[-1]] + cnt[js[-1]])
              for b, js in ((b, list(js)) for b, js in itertools.groupby(live, key=lambda j: base_of[j]))]
    if len(groups) == 1:
        b, r0, r1 = groups[0]
        seg, cp = bases[b]._block_candidates(lo[r0:r1], hi[r0:r1], allow[r0:r1])
        seg, cp = seg + r0, cp + cl0[b]
    else:
        cballf = np.concatenate([c._cballf for c in bases])
        seg, cp = _block_candidates_many(groups, cl0, lo, hi, allow, cloT, chiT, cballf, rows=True, loT=sT_lo,
                                         hiT=sT_hi)
    seg, pair = _pair_candidates(sT_lo, sT_hi, seg, cp, cloT, chiT, cstart, ccount, loT, hiT,
                                 rows_done=len(groups) > 1)
    # swept bounds, every broad phase's rows in one pass (_swept_many: each broad phase's geoms of its
    # rows gathered; session 26 found one call on every broad phase's whole geoms concatenated dearer
    # than one call per broad phase, 0.70-1.35 against 0.54-1.00 ms)
    if len(bases) > 1:
        pb = np.searchsorted(pair0, pair, side="right") - 1
        lb = _swept_many(bases, pb, pair - pair0.take(pb), A.take(seg, axis=0), B.take(seg, axis=0))
    else:
        pb = np.zeros(len(seg), int)
        lb = bases[0]._swept(A.take(seg, axis=0), B.take(seg, axis=0), pair) if len(seg) else np.empty(0)
    # certificates: per bounded segment the radius within which it stays clear
    r = pad.copy()
    np.minimum.at(r, seg, lb - MARGIN_M)
    for j in live:  # (part j's rows bounded are rows row0[j] .. of A, B, allow: its picked rows, in order)
        clr = parts[j][0]
        if clr.cert_pad_m > 0:
            k0, k1 = row0[j], row0[j] + cnt[j]
            clr._certs.add(A[k0:k1], B[k0:k1], allow[k0:k1], r[k0:k1])
    open_ = lb <= MARGIN_M
    seg, pair, pb = seg[open_], pair[open_], pb[open_]
    if not samples:
        return _open_rows(n_of, off, cov, live, todo, full, row0, cnt, np.unique(seg))
    # the covered rows after a bounded row that may come near (an open pair): bounded themselves
    # (a second call: they are not covered there, their row before is not in it)
    if cov.any():
        at = np.full(len(cov), -1)  # row -> its bounded position
        at[np.concatenate([off[j] + todo[j] for j in live])] = np.arange(len(A))
        gc = np.flatnonzero(cov)
        prev = at[gc - 1]
        gc = gc[prev >= 0]
        gc = gc[np.isin(prev[prev >= 0], seg)]  # (the row before has an open pair)
        if gc.size:
            pj = np.searchsorted(off, gc, side="right") - 1
            js = np.unique(pj)
            sub = []
            for j in js:
                i = gc[pj == j] - off[j]
                sg = parts[j][1]
                sub.append((parts[j][0], Segments(sg.a.take(i, axis=0), sg.b.take(i, axis=0), sg.k[i], sg.m[i],
                                                  sg.first[i], sg.path[i]),
                            parts[j][2][i]))
            for j, x in zip(js, near_segments_many(sub)):
                out[j] = x
    if not seg.size:
        return out
    # sample by sample for the pairs the swept bound leaves open (points in F)
    part = np.repeat(np.array(live), cnt[live])  # the part of each bounded segment
    first = np.concatenate([pick(parts[j][1].first, j) for j in live])
    m = np.concatenate([pick(parts[j][1].m, j) for j in live])
    k_ = np.concatenate([pick(parts[j][1].k, j) for j in live])
    kk, idx = _expand(first[seg], m[seg])
    seg, pair, pb = seg[kk], pair[kk], pb[kk]
    i = idx - first[seg]
    f = i * (1.0 / k_[seg])
    f[i == k_[seg]] = 1.0
    q = A.take(seg, axis=0) + f[:, None] * (B - A).take(seg, axis=0)
    ok = _overlap(q, q, loT.T.take(pair, axis=0), hiT.T.take(pair, axis=0))
    seg, pair, pb, idx, q = seg[ok], pair[ok], pb[ok], idx[ok], q.compress(ok, axis=0)
    if not seg.size:
        return out
    close = np.zeros(len(seg), bool)
    for b, clr in enumerate(bases):
        rows = np.flatnonzero(pb == b)
        if rows.size:
            close[rows] = clr._bound_F(q.take(rows, axis=0), pair[rows] - pair0[b], enough=MARGIN_M) <= MARGIN_M
    pj = part[seg[close]]
    idx = idx[close]
    for j in np.unique(pj):
        out[j] = np.union1d(idx[pj == j], out[j])
    return out


def _swept_many(bases, pb, pair, a, b) -> np.ndarray:
    """:meth:`Clearance._swept` of rows of several broad phases at once: row i is pair ``pair[i]``
    of ``bases[pb[i]]`` for the segment ``a[i] -> b[i]`` (n,3, in that broad phase's frame). Each
    broad phase's geoms of its rows are gathered (``Geoms.take``), then every step of ``_swept``
    (the centre offsets, the axis from the nearest point, the extents, the gaps, and for the rows
    it leaves at or below :data:`MARGIN_M` the pairs' fixed axes, ``_axes`` per broad phase) runs
    once on all rows: the same element-by-element operations on the same numbers as one call per
    broad phase, so the same floats (a case of ``Geoms.extent``/``closest`` is computed row by row
    whatever other types are present). The 5-axis plan check: 1,189 rows of 12 broad phases in
    one pass instead of 12 (session 27, perf27b; concatenating every broad phase's whole geoms
    instead cost more, session 26)."""
    n = len(pb)
    out = np.empty(n)
    if not n:
        return out
    order = np.argsort(pb, kind="stable")  # (rows grouped by broad phase, in order within each)
    sp = pb.take(order)
    cut = np.flatnonzero(np.r_[True, sp[1:] != sp[:-1]])
    ends = np.r_[cut[1:], n]
    lp = pair.take(order)
    Ps, Ts = [], []
    for c0, c1 in zip(cut, ends):
        clr = bases[sp[c0]]
        q = lp[c0:c1]
        Ps.append(clr.probe.take(clr.pair_probe.take(q)))
        Ts.append(clr.table.take(clr.pair_table.take(q)))
    if len(Ps) == 1:
        P, T = Ps[0], Ts[0]
    else:
        fields = ("centre", "axes", "kind", "size", "rbound")
        P, T = (Geoms(*(np.concatenate([getattr(x, f) for x in xs]) for f in fields)) for xs in (Ps, Ts))
    a, b = a.take(order, axis=0), b.take(order, axis=0)
    d0 = P.centre - T.centre
    da, db = d0 + a, d0 + b

    def gap(U, E, da, db):  # U (r,j,3), E (r,j)  (Clearance._swept's)
        sa = U[:, :, 0] * da[:, 0, None] + U[:, :, 1] * da[:, 1, None] + U[:, :, 2] * da[:, 2, None]
        sb = U[:, :, 0] * db[:, 0, None] + U[:, :, 1] * db[:, 1, None] + U[:, :, 2] * db[:, 2, None]
        return np.where(sa * sb > 0, np.minimum(np.abs(sa), np.abs(sb)), 0.0) - E

    c_g = P.centre + 0.5 * (a + b)
    u, ok = _unit(c_g - T.closest(c_g))
    E = P.extent(u) + T.extent(u)
    res = np.where(ok, gap(u[:, None, :], E[:, None], da, db)[:, 0], -np.inf)
    r = np.flatnonzero(res <= MARGIN_M)
    if r.size:  # the pairs' fixed axes (computed once per pair, per broad phase) for the rest
        rc = np.searchsorted(r, cut)
        re = np.r_[rc[1:], len(r)]
        UE = [bases[sp[c0]]._axes(lp.take(r[i0:i1])) for c0, i0, i1 in zip(cut, rc, re) if i1 > i0]
        U = UE[0][0] if len(UE) == 1 else np.concatenate([x[0] for x in UE])
        E = UE[0][1] if len(UE) == 1 else np.concatenate([x[1] for x in UE])
        res[r] = np.maximum(res[r], np.max(gap(U, E, da.take(r, axis=0), db.take(r, axis=0)), axis=1))
    out[order] = res
    return out


def _block_candidates_many(groups, cl0, lo, hi, allow, cloT, chiT, cballf, rows: bool = False, loT=None, hiT=None
                           ) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Clearance._block_candidates` of several broad phases' rows at once: ``groups`` (base,
    first row, end row) in row order, covering the rows of ``lo``, ``hi`` (n,3) and ``allow`` (n,);
    each base's clusters at ``cl0[base]`` of ``cloT``, ``chiT`` (3, c) and ``cballf`` (c,). Returns
    (row, cluster) in those numberings, in the order the per-base calls give them one after
    another (blocks of :data:`_BLOCK` rows within a group, each against the clusters the box of
    its group's blocks meets, then each block's boxes; the ball's clusters of a row's allowed
    feature left out): the same candidates, each comparison the same.

    ``rows=True``: the next level too (:func:`_pair_candidates`' first test, each row's box
    against its candidate cluster's), done block by block: the (row, cluster) candidates whose
    boxes meet, in the same order, from the same comparisons (:func:`_block_rows`; ``loT``, ``hiT``:
    ``lo.T``, ``hi.T`` contiguous, (3, n), when the caller has them)."""
    g_b = np.array([g[0] for g in groups])
    g_r0 = np.array([g[1] for g in groups])
    g_r1 = np.array([g[2] for g in groups])
    nblk = (g_r1 - g_r0 + _BLOCK - 1) // _BLOCK
    gb = np.repeat(np.arange(len(groups)), nblk)  # each block's group
    b0 = np.cumsum(nblk) - nblk
    cut = g_r0[gb] + (np.arange(len(gb)) - b0[gb]) * _BLOCK
    if loT is None:
        loT, hiT = lo.T.copy(), hi.T.copy()
    # (each block's box and each group's, one coordinate a row: reduceat along contiguous rows, the
    # same least and largest values as along the columns of (n, 3))
    b_lo, b_hi = np.minimum.reduceat(loT, cut, axis=1), np.maximum.reduceat(hiT, cut, axis=1)
    a_lo, a_hi = np.minimum.reduceat(b_lo, b0, axis=1), np.maximum.reduceat(b_hi, b0, axis=1)
    # the clusters of each group's base that the box of all its blocks meets
    g_of = np.full(len(cl0) - 1, -1)
    g_of[g_b] = np.arange(len(groups))
    gc = np.repeat(g_of, np.diff(cl0))  # each cluster's group (-1: a base with no rows here)
    cl = np.flatnonzero(gc >= 0)
    gcl = gc[cl]
    near = (a_hi[0][gcl] >= cloT[0][cl]) & (a_lo[0][gcl] <= chiT[0][cl]) & (a_hi[1][gcl] >= cloT[1][cl]) \
        & (a_lo[1][gcl] <= chiT[1][cl]) & (a_hi[2][gcl] >= cloT[2][cl]) & (a_lo[2][gcl] <= chiT[2][cl])
    cl, gcl = cl[near], gcl[near]
    ncl = np.bincount(gcl, minlength=len(groups))
    # every (block, near cluster of its group), block by block, clusters in order (_expand's runs):
    # the boxes meeting on x, then on y and z among those (:func:`_overlap_rows`' comparisons; the
    # blocks' side repeated along the runs and the near clusters' taken by run element, rather than
    # both gathered by (block, cluster) numbers: 28,041 pairs, 1,289 kept, on the 5-axis plan check)
    cnt = ncl.take(gb)
    at = np.arange(int(cnt.sum())) + np.repeat((np.cumsum(ncl) - ncl).take(gb) - (np.cumsum(cnt) - cnt), cnt)
    r = np.flatnonzero((np.repeat(b_hi[0], cnt) >= cloT[0].take(cl).take(at))
                       & (np.repeat(b_lo[0], cnt) <= chiT[0].take(cl).take(at)))
    blk, cp = np.repeat(np.arange(len(cnt)), cnt).take(r), cl.take(at.take(r))
    ok = (b_hi[1].take(blk) >= cloT[1].take(cp)) & (b_lo[1].take(blk) <= chiT[1].take(cp)) \
        & (b_hi[2].take(blk) >= cloT[2].take(cp)) & (b_lo[2].take(blk) <= chiT[2].take(cp))
    blk, cp = blk.compress(ok), cp.compress(ok)
    if rows:
        return _block_rows(cut, g_r1.take(gb), blk, cp, loT, hiT, allow, cloT, chiT, cballf)
    seg = (cut.take(blk)[:, None] + np.arange(_BLOCK)).ravel()
    cp = np.repeat(cp, _BLOCK)
    ok = seg < np.repeat(g_r1[gb[blk]], _BLOCK)  # (a group's last block: its rows only)
    seg, cp = seg.compress(ok), cp.compress(ok)
    ok = cballf.take(cp) != allow.take(seg)
    return seg.compress(ok), cp.compress(ok)


def _block_rows(cut, end, blk, cp, loT, hiT, allow, cloT, chiT, cballf) -> tuple[np.ndarray, np.ndarray]:
    """(row, cluster) of every row of the blocks ``blk`` (blocks of :data:`_BLOCK` rows from
    ``cut``, each block's rows before ``end``) whose box ``[lo, hi]`` (``loT``, ``hiT`` (3, n), one
    coordinate a row) meets the box of the cluster ``cp`` (``cloT``, ``chiT`` (3, c)) hit with its
    block, but the ball's clusters of the row's ``allow`` feature (``cballf``): what
    :func:`_block_candidates_many` gives, each block's rows against its cluster, then
    :func:`_pair_candidates`' row level (:func:`_overlap_rows`), the same comparisons of the same
    numbers and the same rows in the same order (hit by hit, a block's rows in order). Each hit's
    16 row numbers as one (hits, 16) array: the first axis's two comparisons on all of them (one
    1-D take of a coordinate row each), then the other axes' and the feature's only on the rows
    the first kept (flat, in the same row-major order: a (row, cluster) kept is one that passes
    every comparison, whatever their order). The 5-axis plan check: 523 blocks, 1,289 hits, 20,624
    slots, 2,394 kept; 880 -> 180-240 us a call against session 26's (hits, 16, 3) gathers of
    both boxes and six strided comparisons (session 27, perf27b)."""
    c = cut.take(blk)
    slot = c[:, None] + np.arange(_BLOCK)
    ok = slot < end.take(blk)[:, None]  # (a group's last block: its rows only)
    slot = np.where(ok, slot, c[:, None])  # (the others read the block's first row, then dropped)
    ok &= hiT[0].take(slot) >= cloT[0].take(cp)[:, None]
    ok &= loT[0].take(slot) <= chiT[0].take(cp)[:, None]
    r = np.flatnonzero(ok)
    s, q = slot.ravel().take(r), np.repeat(cp, _BLOCK).take(r)
    keep = (hiT[1].take(s) >= cloT[1].take(q)) & (loT[1].take(s) <= chiT[1].take(q)) \
        & (hiT[2].take(s) >= cloT[2].take(q)) & (loT[2].take(s) <= chiT[2].take(q)) & (allow.take(s) != cballf.take(q))
    return s.compress(keep), q.compress(keep)


def _open_rows(n_of, off, cov, live, todo, full, row0, cnt, rows) -> list:
    """:func:`near_segments_many`'s answer with ``samples=False``: per part a (s,) bool, True on the
    rows it bounded whose positions ``rows`` (sorted, in its bounded rows' order) have an open
    pair, and on each covered row (:func:`_covered`) whose row before is open."""
    res = [np.zeros(n, bool) for n in n_of]
    part = np.repeat(np.array(live), cnt[live])[rows]
    for j in np.unique(part):
        loc = rows[part == j] - row0[j]
        res[j][loc if full[j] else todo[j][loc]] = True
    if cov.any():
        for j in range(len(n_of)):
            c = np.flatnonzero(cov[off[j]:off[j + 1]])  # (never a part's first row)
            if c.size:
                res[j][c] = res[j][c - 1]
    return res


def _covered(a: np.ndarray, b: np.ndarray, allow: np.ndarray, off: np.ndarray) -> np.ndarray:
    """(n,) bool: the rows of segments ``a -> b`` (n,3) (parts' rows one after another, part j's
    ``off[j] .. off[j + 1] - 1``) that are a point (``a == b``) where the row before in the same
    part, not a point, ends, with the same allowed feature ``allow`` (n,): a polyline's closing
    sample (:func:`flat_path_segments` without joints). Such a point lies on the segment before:
    if that one is proven clear (every pair farther than the margin at each of its points), so
    is the point (a certificate of its segment covers it too)."""
    pt = (a[:, 0] == b[:, 0]) & (a[:, 1] == b[:, 1]) & (a[:, 2] == b[:, 2])
    cov = np.zeros(len(a), bool)
    if not pt.any():  # (a campaign's paths, with joints: no point segments)
        return cov
    cov[1:] = pt[1:] & ~pt[:-1] & (b[:-1, 0] == a[1:, 0]) & (b[:-1, 1] == a[1:, 1]) & (b[:-1, 2] == a[1:, 2]) \
        & (allow[:-1] == allow[1:])
    cov[off[:-1][off[:-1] < len(a)]] = False  # (a part's first row: the row before is another part's)
    return cov


def unique_segments(a: np.ndarray, b: np.ndarray, allow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first (u,) int, inverse (n,) int): the distinct rows of segments ``a -> b`` (n,3) with
    allowed feature ``allow`` (n,) int, rows equal bit for bit (-0.0 and 0.0 differ): ``first``
    holds each distinct row's first occurrence, increasing, and row i equals row
    ``first[inverse[i]]`` (``np.unique(..., axis=0, return_index=True)``'s rows, in the order of
    their first occurrence). Found by a hash of the rows' bits (each word's high bits folded onto
    its low ones, weighted, summed, splitmix64's finalizer), sorted: a few times faster than
    sorting the rows. Rows whose hash equals a different
    row's (a collision) are told apart by ``np.unique`` among themselves."""
    a, b = np.ascontiguousarray(a, float), np.ascontiguousarray(b, float)
    f = np.ascontiguousarray(allow, np.int64)
    n = len(f)
    if not n:
        return np.zeros(0, int), np.zeros(0, int)
    au, bu = a.view(np.uint64), b.view(np.uint64)
    bits = [au[:, 0], au[:, 1], au[:, 2], bu[:, 0], bu[:, 1], bu[:, 2], f.view(np.uint64)]
    h = (bits[0] ^ (bits[0] >> _S29)) * _HASH[2]
    for j in range(1, 7):  # (each word's high bits folded onto its low ones: round numbers end in zeros)
        h += (bits[j] ^ (bits[j] >> _S29)) * _HASH[2 + j]
    h = (h ^ (h >> _S30)) * _HASH[0]  # (splitmix64's finalizer)
    h = (h ^ (h >> _S27)) * _HASH[1]
    h ^= h >> _S31
    # sorted by hash with each row's number in the low bits of its key (one sort of the keys, not
    # an argsort: 18,364 rows 0.56 -> 0.24 ms); rows whose hashes agree above those bits run
    # together, in row order, and are compared bit for bit below as any run is
    nb = max(int(n - 1).bit_length(), 1)
    low = np.uint64((1 << nb) - 1)
    keys = np.sort((h & ~low) | np.arange(n, dtype=np.uint64))
    order = (keys & low).astype(np.intp)
    hs = keys & ~low
    new = np.empty(n, bool)
    new[0] = True
    np.not_equal(hs[1:], hs[:-1], out=new[1:])
    run = np.flatnonzero(new)
    rep = np.minimum.reduceat(order, run).take(np.cumsum(new) - 1)  # per sorted row, its run's first row
    # (whole rows compared, taken with np.take: faster than the seven words gathered one by one)
    ea, eb = au.take(order, axis=0) == au.take(rep, axis=0), bu.take(order, axis=0) == bu.take(rep, axis=0)
    same = ea[:, 0] & ea[:, 1] & ea[:, 2] & eb[:, 0] & eb[:, 1] & eb[:, 2] & (bits[6].take(order) == bits[6].take(rep))
    to = np.empty(n, int)
    to[order] = rep
    if not same.all():  # (a collision: rows unlike their run's first, grouped among themselves)
        odd = np.sort(order[~same])
        rows = np.column_stack(bits)[odd]
        _, i0, inv = np.unique(rows, axis=0, return_index=True, return_inverse=True)
        to[odd] = odd[i0][inv.ravel()]
    isfirst = to == np.arange(n)
    first = np.flatnonzero(isfirst)
    return first, (np.cumsum(isfirst) - 1).take(to)  # (each row's first occurrence's rank among the first)


def _expand(start: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(which run, element): the elements ``start[r] .. start[r] + count[r] - 1`` of every run r."""
    tot = int(count.sum())
    r = np.repeat(np.arange(len(count)), count)
    # (element i of the whole is start[r] + i - (count before run r): integers, the same sum taken as
    # i + (start - count before) repeated, one repeat and one add instead of a repeat, a take and two)
    return r, np.arange(tot) + np.repeat(start - (np.cumsum(count) - count), count)


@dataclass(frozen=True)
class Segments:
    """The straight segments of several sampled polylines, in path order (:func:`path_segments`).

    Segment j holds the ``m[j]`` samples ``a[j] + f (b[j] - a[j])``, ``f = i (1 / k[j])``
    for ``i = 0 .. m[j] - 1`` (``f = 1`` exactly when ``i = k[j]``): every sample lies
    on the closed segment ``[a[j], b[j]]`` (to rounding), which is what lets
    :meth:`Clearance.near_segments` clear a whole segment at once. Samples are
    numbered in path order; segment j's are ``first[j] .. first[j] + m[j] - 1``.

    Attributes
    ----------
    a, b : (s,3) float
    k, m, first, path : (s,) int
        Steps, samples, index of the first sample, index of the polyline.
    """

    a: np.ndarray
    b: np.ndarray
    k: np.ndarray
    m: np.ndarray
    first: np.ndarray
    path: np.ndarray

    @property
    def n_samples(self) -> int:
        return int(self.m.sum())

    def segment_of(self, idx: np.ndarray) -> np.ndarray:
        """(n,) int: the segment of each sample number ``idx`` (n,)."""
        return np.searchsorted(self.first, idx, side="right") - 1

    def points(self, idx: np.ndarray) -> np.ndarray:
        """(n,3): the samples numbered ``idx`` (n,), computed as :func:`path_samples` does."""
        idx = np.asarray(idx, int)
        seg = self.segment_of(idx)
        j = idx - self.first[seg]
        f = j * (1.0 / self.k[seg])
        f[j == self.k[seg]] = 1.0
        return self.a.take(seg, axis=0) + f[:, None] * (self.b - self.a).take(seg, axis=0)


def touch_polylines(starts, ends, has_link, link_points, link_counts) -> tuple:
    """The polylines of a sequence of touches in the order a path check takes them, as one
    array: per touch i its link move into ``starts[i]`` (if ``has_link[i]``), then its
    approach/retract ``starts[i] -> ends[i]``.

    Parameters
    ----------
    starts, ends : (n,3) float
        Each touch's approach start and nominal contact (m).
    has_link : (n,) bool
    link_points : (sum link_counts, 3) float
        The link polylines' points, the touches' with a link in order (m).
    link_counts : (has_link.sum(),) int >= 2
        Points of each link.

    Returns
    -------
    P : (m,3) float
        Every polyline's points in turn (for :func:`flat_path_segments`).
    n_pt : (polylines,) int
    touch : (polylines,) int
        The touch of each polyline.
    is_link : (polylines,) bool
    """
    has_link = np.asarray(has_link, bool)
    cnt = np.asarray(link_counts, int)
    n = len(has_link)
    app = np.arange(n) + np.cumsum(has_link)  # each approach's polyline; its link (if any) just before
    n_pt = np.full(n + int(has_link.sum()), 2)
    n_pt[app[has_link] - 1] = cnt
    first = np.cumsum(n_pt) - n_pt
    # every point taken from the starts, ends and link points one after another (np.take: the
    # same rows as assigning them in place, a few times faster)
    src = np.empty(int(n_pt.sum()), int)  # each point's row of (starts, ends, link_points)
    src[first[app]], src[first[app] + 1] = np.arange(n), np.arange(n, 2 * n)
    if cnt.size:
        into = np.repeat(first[app[has_link] - 1] - (np.cumsum(cnt) - cnt), cnt) + np.arange(int(cnt.sum()))
        src[into] = np.arange(2 * n, 2 * n + int(cnt.sum()))
    P = np.concatenate([np.asarray(starts, float).reshape(-1, 3), np.asarray(ends, float).reshape(-1, 3),
                        np.asarray(link_points, float).reshape(-1, 3)]).take(src, axis=0)
    touch = np.empty(len(n_pt), int)
    touch[app], touch[app[has_link] - 1] = np.arange(n), np.flatnonzero(has_link)
    is_link = np.ones(len(n_pt), bool)
    is_link[app] = False
    return P, n_pt, touch, is_link


def path_segments(polylines, steps_m, joints: bool) -> Segments:
    """The segments of several polylines sampled at once (:func:`path_samples` without the samples).

    Each segment ``a -> b`` of polyline j gets ``k = max(1, ceil(|b - a| / steps_m[j]))``
    equal steps. ``joints``: every segment keeps both ends (``k + 1`` samples: a joint
    appears twice, as in :meth:`sim.scene.Scene.check_path`), else each segment drops
    its end (``k`` samples) and the polyline's last point closes it, as a segment of
    one sample from that point to itself (as in :func:`sim.mfb_scene.check_measurement`).

    Parameters
    ----------
    polylines : sequence of (m_j, 3) float, m_j >= 2
    steps_m : (len(polylines),) float
    joints : bool
    """
    n_pt = np.fromiter(map(len, polylines), int, len(polylines))
    return flat_path_segments(np.concatenate(polylines, dtype=float).reshape(-1, 3), n_pt, steps_m, joints)


def _row_norm(d: np.ndarray) -> np.ndarray:
    """(...) the length of each row of ``d`` (..., 3) along its last axis: ``sqrt((x^2 + y^2) + z^2)``,
    the sum in the order ``np.add.reduce(d * d, axis=-1)`` adds a row's three squares
    (``np.linalg.norm(d, axis=-1)``'s own sum for real rows), bit for bit (tests/sim/test_clearance.py),
    without its reduction over an axis of 3, which numpy runs element by element (20,000 rows:
    ~760 -> ~20 us; the 5-axis plan check's paths, session 26)."""
    d = np.asarray(d, float)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    s = x * x
    s += y * y
    s += z * z
    return np.sqrt(s, out=s)


def flat_path_segments(P: np.ndarray, n_pt: np.ndarray, steps_m, joints: bool) -> Segments:
    """:func:`path_segments` of polylines given as one array: ``P`` (sum n_pt, 3) holds the
    points of polyline 0, then 1, ...; ``n_pt`` (polylines,) int >= 2 their counts."""
    P = np.asarray(P, float)
    n_pt = np.asarray(n_pt, int)
    first = np.cumsum(n_pt) - n_pt
    starts = np.ones(len(P), bool)
    starts[first + n_pt - 1] = False
    a_idx = np.flatnonzero(starts)  # every point that starts a segment
    path_of_seg = np.repeat(np.arange(len(n_pt)), n_pt - 1)
    step = np.asarray(steps_m, float)[path_of_seg]
    if joints:
        a, b = P.take(a_idx, axis=0), P.take(a_idx + 1, axis=0)
        L = _row_norm(b - a)
    else:  # (the same differences b - a, row by row, of every point and the next, the segments' taken)
        L = _row_norm(P[1:] - P[:-1]).take(a_idx)
    k = np.maximum(1, np.ceil(L / step).astype(int))
    if not joints:  # the last point of each polyline: a segment of one sample at fraction 0
        # segments in point order: the one starting at point i is number i (a polyline's last
        # point starts its closing segment, from that point to itself)
        k_all = np.ones(len(P), int)
        k_all[a_idx] = k
        a, b = P.copy(), P.take(np.arange(len(P)) + starts, axis=0)
        k, m = k_all, k_all.copy()
        path_of_seg = np.repeat(np.arange(len(n_pt)), n_pt)
    else:
        m = k + 1
    return Segments(a, b, k, m, np.cumsum(m) - m, path_of_seg)


def path_samples(polylines, steps_m, joints: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Samples of several polylines at once, in path order (the samples of :func:`path_segments`).

    ``a + (i / k)(b - a)`` is computed as numpy's ``linspace(0, 1, k + 1)`` does
    (``i * (1 / k)``, the last fraction exactly 1).

    Parameters
    ----------
    polylines : sequence of (m_j, 3) float, m_j >= 2
    steps_m : (len(polylines),) float
    joints : bool

    Returns
    -------
    samples : (k, 3) float
    segment : (k,) int
        A running number of the segment (runs of equal values, for :meth:`Clearance.near`).
    path : (k,) int
        Index of the polyline.
    """
    sg = path_segments(polylines, steps_m, joints)
    idx = np.arange(sg.n_samples)
    seg = np.repeat(np.arange(len(sg.k)), sg.m)
    return sg.points(idx), seg, sg.path[seg]
