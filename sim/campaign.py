"""Campaigns: set-ups x plan -> moves, times, simulated touches -> probe log.

A campaign runs one :class:`~sim.plans.Plan` in each :class:`Setup` (one
artefact placement or one rotary-table index). For every touch it builds
the nominal geometry in R (``Xn``: nominal stylus-tip centre at contact on
a perfect machine with a perfect artefact in its nominal pose; ``n``: the
nominal normal in R), the moves (link from the previous retract point,
direct inside one feature level, else via the safe height, or for the bar
as its part program moves, along z_A; approach along
``-n`` from ``clearance`` outside ``Xn``; retract back), their times from
the feeds (``t_s``), checks the paths in the MuJoCo scene, then simulates
the touches of all set-ups at once (:func:`sim.probe.simulate_touches`) and
writes every ``probe-log/1`` column through :func:`core.probelog.make_log`.

Frames: R machine reference, W table (``T_R_W`` nominal from the machine,
paper eq. 1 for a C table), A artefact (``T_W_A`` placement).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.exceptions import ConfigError, PlanError, counted
from core.probelog import ProbeLog, make_log
from core.touches import STATUS_MESSAGES, ProbeStatus
from core.units import MM

from . import artefacts as A
from .catalog import CATALOG, make_artefact, make_plan
from .plans import Plan
from .probe import (ProbeConfig, T_R_W_nominal, find_contacts, rotary_count,
                    simulate_touches)
from .scene import artefact_points
from .setups import Setup, c_angle_setups, machine_name

#: Default feeds: probing 240 mm/min (MFB paper), rapid 10 m/min.
PROBING_FEED_MPS = 0.240 / 60.0
RAPID_FEED_MPS = 10.0 / 60.0
#: Dwell per touch (trigger, reset), s.
DWELL_S = 0.2
#: Safe-height margin above the artefact's top, m.
SAFE_MARGIN_M = 5.0 * MM
#: Time between set-ups of an artefact without a record in :data:`sim.catalog.CATALOG`, s.
DEFAULT_SETUP_CHANGE_S = 10.0
#: An axis position beyond its stroke by up to this much is within it, m (sums of lengths rounded; one
#: value for every stroke check: :func:`check_strokes`, ``scenarios.mfb.check_program_strokes``).
STROKE_TOL_M = 1e-9


def first_outside_stroke(q_m, strokes, tol_m: float = STROKE_TOL_M):
    """The first axis position outside its stroke, or None: ``(row, axis index j, value, limit, excess)``.

    ``q_m``: (n, 3) axis positions X, Y, Z (m), in the order they are reached; ``strokes``: axis ->
    (least, largest) m (an axis without one is not checked). The first offender is the first row
    with any axis beyond ``tol_m``, and of its axes the first in X, Y, Z order; ``limit`` is the end
    of the stroke it passes, ``excess`` (> ``tol_m``) by how much. The one stroke rule of the linear
    axes (:func:`check_strokes` and ``scenarios.mfb.check_program_strokes`` word their own errors)."""
    q = np.asarray(q_m, float).reshape(-1, 3)
    over = np.full(q.shape, -np.inf)
    for j, ax in enumerate("XYZ"):
        if ax in strokes:
            lo, hi = strokes[ax]
            over[:, j] = np.maximum(lo - q[:, j], q[:, j] - hi)
    bad = over > tol_m
    if not bad.any():
        return None
    i = int(np.flatnonzero(bad.any(axis=1))[0])
    j = int(np.flatnonzero(bad[i])[0])
    lo, hi = strokes["XYZ"[j]]
    v = float(q[i, j])
    return i, j, v, float(hi if v > hi else lo), float(over[i, j])


def check_strokes(machine, setup: Setup, plan: Plan, mv: "SetupMoves", J_ref_m=None) -> None:
    """PlanError when a move leaves the machine's strokes (``machine.config.strokes``).

    A stroke limits the axis (the carriage, the spindle's gauge point), as a controller's soft
    limits do, stated for the machine's reference tool (offsets ``J_ref_m``; default the
    machine's own ``config.J_m``, whose readings are then the axis positions); a reading taken
    with the machine's offsets J puts the axis at ``reading + J - J_ref`` in those terms
    (docs/formats.md, "Strokes"). Checked: every link point (they end at the approach starts)
    and every overshoot end (a touch lies between its start and its overshoot end), by
    :func:`first_outside_stroke`. The error names the set-up, the target, the axis, its position and
    the excess of the first point out in the order the moves reach them."""
    strokes = getattr(getattr(machine, "config", None), "strokes", None)
    if not strokes:
        return
    J = np.asarray(getattr(machine.config, "J_m", (0.0, 0.0, 0.0)), float)
    dJ = np.zeros(3) if J_ref_m is None else J - np.asarray(J_ref_m, float)
    # every link point and overshoot end, touch by touch, in the order the moves reach them
    n_pt = np.array([len(ln) + 1 for ln in mv.links], int)
    pts = np.zeros((int(n_pt.sum()), 3))
    if plan.n:  # touch i: its link points, then its overshoot end
        end = np.cumsum(n_pt) - 1
        pts[end] = mv.Xn_R - plan.overshoot_m * mv.n_R
        on_link = np.ones(len(pts), bool)
        on_link[end] = False
        pts[on_link] = np.concatenate(mv.links)
    if dJ.any():
        pts = pts + dJ
    touch = np.repeat(np.arange(plan.n), n_pt)
    hit = first_outside_stroke(pts, strokes)
    if hit is not None:
        row, j, v, _, over = hit
        lo, hi = strokes["XYZ"[j]]
        raise PlanError(f"set-up {setup.name!r} target {plan.target[int(touch[row])]!r}: {'XYZ'[j]} = {v * 1e3:.3f} mm "
                        f"is outside the stroke {lo * 1e3:.0f}..{hi * 1e3:.0f} mm by "
                        f"{over * 1e3:.3f} mm" + (" (axis position: reading + J - the reference "
                                                  "tool's J)" if dJ.any() else ""))
    for ax, v in zip(getattr(machine, "rotary_axes", ()), setup.rot_rad):
        if ax in strokes and not (strokes[ax][0] - 1e-12 <= v <= strokes[ax][1] + 1e-12):
            raise PlanError(f"set-up {setup.name!r}: {ax} = {np.rad2deg(v):g} deg is outside its stroke")


def _kinematic_chain(machine) -> str:
    for obj in (machine, getattr(machine, "config", None)):
        for a in ("kinematic_chain", "chain"):
            v = getattr(obj, a, None)
            if isinstance(v, str) and v:
                return v
    return ""


def _feature_groups(plan: Plan) -> tuple[list, np.ndarray]:
    """(the plan's features sorted, (n,) index of each touch's feature in them)."""
    feats = sorted(set(plan.feature))
    at = {f: i for i, f in enumerate(feats)}
    return feats, np.array([at[f] for f in plan.feature], int)


def validate_plan(art: A.Artefact, plan: Plan, probe: ProbeConfig) -> None:
    """On a perfect machine and artefact, each touch must meet its own target.

    Raises PlanError naming the first target whose stylus meets the feature
    elsewhere first (e.g. a pocket wall point closer than the stylus
    radius to a concave corner) or misses it.
    """
    r = probe.stylus_r_m
    feats, grp = _feature_groups(plan)
    sdf = [art.feature(f).nominal.sdf for f in feats]
    start = plan.w_A + (r + plan.clearance_m) * plan.wn_A
    travel = np.full(plan.n, plan.clearance_m + plan.overshoot_m)

    dist = A.GroupedSdf(sdf)

    def g(idx, s):
        return dist(grp[idx], start[idx] - s[:, None] * plan.wn_A[idx]) - r

    s, status = find_contacts(g, plan.n, travel)
    bad = (status != ProbeStatus.OK) | ~(np.abs(s - plan.clearance_m) < 1e-9)
    if bad.any():
        i = int(np.argmax(bad))
        what = (f"meets {plan.feature[i]!r} {(plan.clearance_m - s[i]) * 1e3:.6f} mm before the target"
                if status[i] == ProbeStatus.OK else f"gives {status[i]} ({STATUS_MESSAGES[status[i]]})")
        raise PlanError(f"plan {plan.artefact!r} target {plan.target[i]!r}: on a perfect machine the "
                        f"stylus {what} (too close to a corner or an edge?)")


@dataclass(frozen=True)
class SetupMoves:
    """Nominal geometry and moves of one set-up, frame R, SI units."""

    T_R_W: np.ndarray
    Xn_R: np.ndarray
    n_R: np.ndarray
    start_R: np.ndarray
    links: list
    link_len_m: np.ndarray


def _links(start: np.ndarray, plan: Plan, z_safe: float, start_from) -> list[np.ndarray]:
    """Each touch's link from the previous start (R, m): straight along a feature's level,
    else up to the safe height (or the higher end), across and down; from above the first
    start when there is no previous point."""
    n = len(start)
    if n == 0:
        return []
    prev = np.empty((n, 3))
    prev[1:] = start[:-1]
    fresh = np.zeros(n, bool)  # no previous point
    if start_from is None:
        fresh[0] = True
        prev[0] = np.nan
    else:
        prev[0] = np.asarray(start_from, float)
    feat, lev = np.asarray(plan.feature, object), np.asarray(plan.level)
    same = np.zeros(n, bool)
    same[1:] = (feat[1:] == feat[:-1]) & (lev[1:] == lev[:-1])
    same &= ~fresh
    zs = np.maximum(np.maximum(z_safe, prev[:, 2]), start[:, 2])
    paths = np.empty((n, 4, 3))
    paths[:, 0], paths[:, 1], paths[:, 2], paths[:, 3] = prev, prev, start, start
    paths[:, 1, 2] = paths[:, 2, 2] = zs
    paths[same, 1] = start[same]
    paths[fresh, 2, 2] = z_safe
    paths[fresh, 3] = start[fresh]
    k = np.where(same | fresh, 2, 4)
    return [paths[i, 4 - k[i]:] if fresh[i] else paths[i, :k[i]] for i in range(n)]


def _program_links(T_R_A, start: np.ndarray, plan: Plan, top_A_m: float) -> list[np.ndarray]:
    """Each touch's link (R, m) as a bar's part program moves (:func:`sim.mfb_scene.link_points`, the
    moves ``scenarios.mfb`` checks for collisions and strokes): between two starts of one feature and
    level directly, else out along z_A to ``top_A_m`` + its clearance, across and back; the first
    start from that plane above it. ``top_A_m``: the bar's top plus the stylus radius, A."""
    from .mfb_scene import LINK_CLEAR_M, link_points

    n = len(start)
    if n == 0:
        return []
    s_A = A.apply_T(A.inv_T(T_R_A), start[:1])[0]
    above = A.apply_T(T_R_A, np.array([[s_A[0], s_A[1], max(top_A_m + LINK_CLEAR_M, s_A[2])]]))
    links = [np.concatenate([above, start[:1]])]
    if n > 1:
        P, cnt = link_points(T_R_A, start, plan.feature, plan.level, top_A_m)
        cut = [0, *np.cumsum(cnt)[:-1].tolist(), len(P)]  # np.split(P, np.cumsum(cnt)[:-1])'s pieces, sliced
        links += [P[a:b] for a, b in zip(cut[:-1], cut[1:])]  # directly (its per-piece checks: ~2 us each, n pieces)
    return links


def setup_moves(machine, art: A.Artefact, plan: Plan, setup: Setup, probe: ProbeConfig,
                start_from: np.ndarray | None = None) -> SetupMoves:
    """Nominal contact centres, normals, start points and link moves in R."""
    k = rotary_count(machine)
    rot = np.asarray(setup.rot_rad, float).reshape(1, -1) if k else None
    if k and rot.shape[1] != k:
        raise ConfigError(f"set-up {setup.name!r}: rot_rad has {counted(rot.shape[1], 'value')}, machine has {counted(k, 'rotary axis', 'rotary axes')}")
    T_R_W = T_R_W_nominal(machine, rot, 1)[0]
    T_R_A = T_R_W @ np.asarray(setup.T_W_A, float)
    r = probe.stylus_r_m
    Xn = A.apply_T(T_R_A, plan.w_A + r * plan.wn_A)
    n_R = A.apply_R(T_R_A, plan.wn_A)
    start = Xn + plan.clearance_m * n_R
    rec = CATALOG.get(art.name)
    if rec is not None and rec.links_along_z_A and start_from is None:
        links = _program_links(T_R_A, start, plan, float(artefact_points(art)[:, 2].max()) + r)
    else:
        top = float(np.max(A.apply_T(T_R_A, artefact_points(art))[:, 2]))
        links = _links(start, plan, top + r + SAFE_MARGIN_M, start_from)
    lens = np.zeros(plan.n)
    if plan.n:  # each link's length: the sum of its segments' lengths, in order
        P = np.concatenate(links)
        first = np.cumsum([len(p) for p in links]) - np.array([len(p) for p in links])
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
        keep = np.ones(len(seg), bool)
        keep[first[1:] - 1] = False  # the step from one link's end to the next link's start
        lens = np.add.reduceat(seg[keep], first - np.arange(plan.n))
    return SetupMoves(T_R_W, Xn, n_R, start, links, lens)




def _resolve_setups(machine, art, setups) -> list[Setup]:
    """Set-ups from C angles, placements or Setup objects; None: the artefact's defaults (its record)."""
    if setups is None:
        if art.name in CATALOG:
            return CATALOG[art.name].default_setups(machine, art)
        return c_angle_setups(machine, art, [0.0])
    setups = list(setups)
    if not setups:
        raise ConfigError("no set-ups (c_angles_deg or placements is empty)")
    if all(isinstance(s, Setup) for s in setups):
        return setups
    if all(np.ndim(s) == 0 for s in setups):
        return c_angle_setups(machine, art, setups)
    out = []
    k = rotary_count(machine)
    for j, T in enumerate(setups):
        T = np.asarray(T, float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ConfigError(f"placement {j} is not a finite 4x4 transform")
        out.append(Setup(f"P{j + 1:02d}", T, tuple(np.zeros(k))))
    return out


def simulate_campaign(artefact, machine, probe: ProbeConfig | None = None, setups=None,
                      rng: np.random.Generator | None = None, *, plan: Plan | None = None,
                      feed_mps: float = PROBING_FEED_MPS, rapid_mps: float = RAPID_FEED_MPS,
                      setup_change_s: float | None = None, check_collisions: bool = True,
                      plan_only: bool = False, meta: dict | None = None, stroke_check: bool = True,
                      t_start_s: float = 0.0) -> ProbeLog:
    """Simulate a campaign into a probe log (or write the plan only).

    Parameters
    ----------
    artefact : str or Artefact
        ``mfb``, ``cross-pocket``, ``pin-circle``, ``freeform`` or an Artefact.
    machine : object with ``tip_W`` (``sim.machine.Machine``)
    probe : ProbeConfig, optional
    setups : sequence of float (C angles, deg), of (4,4) placements, or of Setup
        Default: the artefact's record (:mod:`sim.catalog`): the 17 MFB
        placements, or C = 0 for the other artefacts.
    rng : np.random.Generator, optional
        Noise source (None: noiseless).
    plan : Plan, optional
        Default: the artefact's standard plan.
    feed_mps, rapid_mps : float
        Probing and rapid feeds, m/s.
    setup_change_s : float, optional
        Time between set-ups (default the record's: 300 s to re-place the
        bar, 10 s for an index).
    check_collisions : bool
        Check every link, approach and retract path in the MuJoCo scene.
    plan_only : bool
        Write the plan: measured columns (X/Y/Z_mm, t_s) empty.
    stroke_check : bool
        Check every move against the machine's strokes (:func:`check_strokes`); False
        when the caller checks its own program's moves (the MFB runs: ``scenarios.mfb.check_plan``
        checks every touch, approach start, overshoot end and link of the program as axis
        positions against the machine's reference tool, each stylus's offsets counted). The
        bar's links are its program's (out along z_A: :func:`_program_links`, since session 27;
        before, a climb along R z over the bar's top, a standing bar's above the Z stroke),
        so its touches' t_s follow the program's path.
    t_start_s : float
        The machine's clock at the campaign's start, s (default 0): its first link starts then.
        A campaign that is one part of a longer one (:func:`simulate_measurements`) starts where the
        part before it ended, so a time-varying error (thermal drift) goes on across the parts.

    Returns
    -------
    ProbeLog
        Every ``probe-log/1`` column; ``status`` ``no_trigger`` /
        ``early_trigger`` rows have empty measured cells.

    Raises
    ------
    PlanError
        A path crashes (set-up and target named), or a target cannot be
        touched even on a perfect machine.
    ConfigError
        Bad set-ups, feeds, or a C angle on a machine without C.
    """
    art = make_artefact(artefact) if isinstance(artefact, str) else artefact
    probe = probe or ProbeConfig()
    _check_feeds(feed_mps, rapid_mps)
    plan = plan or make_plan(art)
    setups = _resolve_setups(machine, art, setups)
    if len({s.name for s in setups}) != len(setups):
        raise ConfigError("set-up names must be unique")
    validate_plan(art, plan, probe)
    if setup_change_s is None:
        setup_change_s = CATALOG[art.name].setup_change_s if art.name in CATALOG else DEFAULT_SETUP_CHANGE_S
    feats, grp = _feature_groups(plan)
    sdf_true = [art.feature(f).true.sdf for f in feats]
    travel = np.full(plan.n, plan.clearance_m + plan.overshoot_m)
    paths = _PathChecker(art, probe) if check_collisions else None
    t_cursor = float(t_start_s)
    if not np.isfinite(t_cursor):
        raise ConfigError(f"t_start_s must be finite, got {t_start_s!r}")
    moves = []  # (set-up, moves, approach start times) in order, every path checked first
    failed = None  # (a set-up's error: raised after the paths of the set-ups before it are checked)
    try:
        for si, st in enumerate(setups):
            mv = setup_moves(machine, art, plan, st, probe)
            if stroke_check:
                check_strokes(machine, st, plan, mv)
            if paths is not None:
                paths.check(st, plan, mv)  # (taken; checked by flush, every set-up's at once)
            if si > 0:
                t_cursor += setup_change_s
            t0, t_cursor = _touch_start_times(mv, travel, t_cursor, feed_mps, rapid_mps)
            moves.append((st, mv, t0))
    except Exception as e:
        failed = e
    if paths is not None:  # (a crash of a set-up before the failed one is raised first, as it was)
        paths.flush()
    if failed is not None:
        raise failed
    if plan_only:
        empty = (np.full((plan.n, 3), np.nan), np.full(plan.n, ProbeStatus.OK, dtype=object), np.full(plan.n, np.nan))
        touched = [empty] * len(moves)
    else:
        touched = _simulate_setups(machine, probe, rng, moves, travel, feed_mps, sdf_true, grp)
    return _campaign_log([(plan, st, mv) + tuple(res) for (st, mv, _), res in zip(moves, touched)],
                         machine, art, probe, feed_mps, meta)


def _check_feeds(feed_mps: float, rapid_mps: float) -> None:
    """ConfigError unless both feeds (m/s) are finite and positive."""
    if not (np.isfinite(feed_mps) and feed_mps > 0 and np.isfinite(rapid_mps) and rapid_mps > 0):
        raise ConfigError("feed_mps and rapid_mps must be positive")


def _campaign_log(rows, machine, art, probe, feed_mps: float, meta) -> ProbeLog:
    """The probe log of ``rows``, each set-up's ``(plan, setup, moves, positions, status, times)``
    in order, on ``machine`` (its rotary positions and the log's metadata)."""
    cols: dict[str, list] = {c: [] for c in LOG_COLUMNS}
    for plan, st, mv, pos, status, t_s in rows:
        _append_rows(cols, plan, st, mv, pos, status, t_s, _rotary_deg(machine, st), probe.stylus_r_m)
    columns = {c: (np.concatenate(v) if v and isinstance(v[0], np.ndarray) else v) for c, v in cols.items()}
    return make_log(columns, _campaign_meta(machine, art, probe, feed_mps, meta))


def simulate_measurements(items, rng: np.random.Generator | None = None, *,
                          feed_mps: float = PROBING_FEED_MPS, rapid_mps: float = RAPID_FEED_MPS,
                          meta: dict | None = None, stroke_check: bool = True,
                          setup_change_s: float | None = None) -> list[ProbeLog]:
    """One probe log per measurement ``(artefact, machine, probe, setup, plan)`` of ``items``: what
    ``simulate_campaign(artefact, machine, probe, [setup], rng, plan=plan, check_collisions=False,
    stroke_check=stroke_check, t_start_s=t)`` gives called for each in turn, the noise drawn in the
    same order, on one clock: each measurement starts ``setup_change_s`` after the one before it ended
    (default the first artefact's record, 300 s for the bar, as :func:`simulate_campaign` between its
    set-ups), the first at t = 0. So a time-varying error (a machine file's thermal drift) acts across
    the whole campaign, as in ``vmt simulate mfb`` (review30b F2: before session 30 every measurement
    restarted the clock at 0; time-invariant machines give the same touches either way, only t_s moves).

    Measurements of one artefact and one probe on machines that differ only in their probe
    offsets (``Machine(replace(config, J_m=J))``, one per stylus: :func:`_styli_of_one_machine`)
    are simulated in one :func:`sim.probe.simulate_touches` call, each touch with its stylus's
    offsets (a call's cost is mostly fixed: a few ms per kinematics evaluation) and each plan
    validated once; the logs are the same bit for bit (tests/sim/test_campaign.py). Others
    (e.g. a compensated machine, a hook's own artefact): one campaign each.
    """
    items = list(items)
    if not _styli_of_one_machine(items):
        return _simulate_each_measurement(items, rng, feed_mps=feed_mps, rapid_mps=rapid_mps, meta=meta,
                                          stroke_check=stroke_check, setup_change_s=setup_change_s)
    _check_feeds(feed_mps, rapid_mps)
    art, machine, probe = items[0][:3]
    change_s = _measurement_change_s(art, setup_change_s)
    t_cursor = -change_s  # (the first measurement starts at 0)
    plans = {}  # id -> (plan, its travel); each plan validated once
    feats = sorted({f for *_, pl in items for f in pl.feature})
    at = {f: i for i, f in enumerate(feats)}
    moves, parts = [], []
    for _, m, _, st, pl in items:
        if id(pl) not in plans:
            validate_plan(art, pl, probe)
            plans[id(pl)] = (pl, np.full(pl.n, pl.clearance_m + pl.overshoot_m))
        travel = plans[id(pl)][1]
        mv = setup_moves(m, art, pl, st, probe)
        if stroke_check:
            check_strokes(m, st, pl, mv)
        t0, t_cursor = _touch_start_times(mv, travel, t_cursor + change_s, feed_mps, rapid_mps)
        moves.append((m, st, pl, mv))
        parts.append(_setup_touches(m, st, mv, t0) + (travel, np.array([at[f] for f in pl.feature], int),
                                                       np.broadcast_to(np.asarray(m.config.J_m, float), (pl.n, 3))))
    start, d, rot, t0, T_A_W, travel, grp, J = (None if parts[0][k] is None else np.concatenate([p[k] for p in parts])
                                                for k in range(8))
    res = simulate_touches(machine, probe, rng, start, d, travel, rot, t0, np.full(len(start), feed_mps),
                           [art.feature(f).true.sdf for f in feats], grp, T_A_W, J_m=J)
    pos, status, t_s = _result_rows(res)
    logs, k = [], 0
    for m, st, pl, mv in moves:
        b = slice(k, k + pl.n)
        k += pl.n
        logs.append(_campaign_log([(pl, st, mv, pos[b], status[b], t_s[b])], m, art, probe, feed_mps, meta))
    return logs


def _simulate_each_measurement(items, rng=None, *, feed_mps: float = PROBING_FEED_MPS,
                               rapid_mps: float = RAPID_FEED_MPS, meta: dict | None = None,
                               stroke_check: bool = True, setup_change_s: float | None = None) -> list[ProbeLog]:
    """:func:`simulate_measurements` one campaign per measurement (the path for measurements that
    cannot share a kinematics call, and the path before: the oracle of the tests, the reference
    of the bench), each started where the one before ended plus the set-up change."""
    logs, t_cursor = [], None
    for a, m, p, st, pl in items:
        change_s = _measurement_change_s(make_artefact(a) if isinstance(a, str) else a, setup_change_s)
        t_start = 0.0 if t_cursor is None else t_cursor + change_s
        logs.append(simulate_campaign(a, m, p, [st], rng, plan=pl, feed_mps=feed_mps, rapid_mps=rapid_mps,
                                      check_collisions=False, meta=meta, stroke_check=stroke_check,
                                      t_start_s=t_start))
        art = make_artefact(a) if isinstance(a, str) else a
        mv = setup_moves(m, art, pl, st, p or ProbeConfig())  # (its end on the clock: the same moves)
        _, t_cursor = _touch_start_times(mv, np.full(pl.n, pl.clearance_m + pl.overshoot_m), t_start,
                                         feed_mps, rapid_mps)
    return logs


def _measurement_change_s(art, setup_change_s: float | None) -> float:
    """The time between two measurements of :func:`simulate_measurements`, s: ``setup_change_s`` or the
    artefact's record's (:func:`simulate_campaign`'s default between set-ups); ConfigError unless >= 0."""
    if setup_change_s is None:
        name = getattr(art, "name", None)
        setup_change_s = CATALOG[name].setup_change_s if name in CATALOG else DEFAULT_SETUP_CHANGE_S
    c = float(setup_change_s)
    if not (np.isfinite(c) and c >= 0):
        raise ConfigError(f"setup_change_s must be >= 0 (s), got {setup_change_s!r}")
    return c


def _styli_of_one_machine(items) -> bool:
    """Whether the measurements ``(artefact, machine, probe, setup, plan)`` share one artefact
    and one probe (the same objects) and run on :class:`sim.machine.Machine` s whose configurations
    differ at most in their probe offsets ``J_m`` (the same error functions, not copies)."""
    from .machine import Machine

    if not items:
        return False
    a0, m0, p0 = items[0][:3]
    if not isinstance(a0, A.Artefact) or type(m0) is not Machine:
        return False
    c0 = m0.config
    for a, m, p, *_ in items:
        if a is not a0 or p is not p0 or type(m) is not Machine:
            return False
        c = m.config
        if (c.name, c.chain, dict(c.strokes), dict(c.rotary_points_R_m)) != (
                c0.name, c0.chain, dict(c0.strokes), dict(c0.rotary_points_R_m)) or list(c.errors) != list(c0.errors) \
                or any(c.errors[e] is not c0.errors[e] for e in c0.errors):
            return False
    return True


#: Every column a campaign writes, in the order of ``probe-log/1``.
LOG_COLUMNS = ("setup", "target", "t_s", "X_mm", "Y_mm", "Z_mm", "Xn_mm", "Yn_mm", "Zn_mm", "nx", "ny", "nz",
               "feature", "A_deg", "B_deg", "C_deg", "dx", "dy", "dz", "wx_mm", "wy_mm", "wz_mm",
               "wnx", "wny", "wnz", "stylus_r_mm", "status")


class _PathChecker:
    """Every link, approach and retract path of a campaign's set-ups checked in the MuJoCo scene.

    The scene is built once per artefact placement and re-posed per table index. :meth:`check`
    takes a set-up's moves; :meth:`flush` checks every set-up taken since, in order, their
    polylines made and sampled at once (:func:`sim.scene.check_touch_paths_many`: each set-up
    as :func:`sim.scene.check_touch_paths` checks it alone).
    """

    def __init__(self, art: A.Artefact, probe: ProbeConfig):
        self.art, self.probe = art, probe
        self.scene = self.T_W_A = None
        self._todo = []

    def check(self, st: Setup, plan: Plan, mv: SetupMoves) -> None:
        self._todo.append((st, plan, mv))

    def _pose(self, st: Setup, mv: SetupMoves):
        from .scene import scene_for

        if self.scene is None or not np.array_equal(self.T_W_A, st.T_W_A):
            self.scene = scene_for(self.art, self.probe, st.T_W_A)
            self.T_W_A = np.asarray(st.T_W_A)
        self.scene.set_table(mv.T_R_W)
        return self.scene

    def flush(self) -> None:
        """Check the set-ups taken (PlanError: the first crash of the first set-up that crashes)."""
        from .scene import check_touch_paths_many

        todo, self._todo = self._todo, []
        check_touch_paths_many([(lambda st=st, mv=mv: self._pose(st, mv), st.name, plan.target, plan.feature,
                                 mv.links, np.stack([mv.start_R, mv.Xn_R], axis=1)) for st, plan, mv in todo])


def _touch_start_times(mv: SetupMoves, travel: np.ndarray, t_cursor: float, feed_mps: float,
                       rapid_mps: float) -> tuple[np.ndarray, float]:
    """(t0 (n,) s: start of each approach, end of the set-up s) from the link lengths and feeds.

    Each touch: its link at rapid feed, then the approach and the search at
    the probing feed, the retract at rapid feed and the dwell.
    """
    per = travel / feed_mps + travel / rapid_mps + DWELL_S
    t0 = t_cursor + np.cumsum(mv.link_len_m / rapid_mps) + np.concatenate([[0.0], np.cumsum(per)[:-1]])
    return t0, float(t0[-1] + per[-1])


def _rotary_deg(machine, st: Setup) -> np.ndarray:
    """(3,) A, B, C of the set-up, deg (0 for axes the machine lacks), rounded to 1e-9 deg."""
    rot_deg = np.zeros(3)
    for a, v in zip(tuple(getattr(machine, "rotary_axes", ()) or ()), st.rot_rad):
        if a in "ABC":
            rot_deg["ABC".index(a)] = np.round(np.rad2deg(v), 9)
    return rot_deg


def _setup_touches(machine, st: Setup, mv: SetupMoves, t0):
    """(start_R, d_R, rot, t0, T_A_W) of one set-up's touches, the arguments of :func:`simulate_touches`."""
    n = len(t0)
    rot = np.tile(np.asarray(st.rot_rad, float), (n, 1)) if rotary_count(machine) else None
    T_true = np.asarray(st.T_W_A if st.T_W_A_true is None else st.T_W_A_true, float)
    return mv.start_R, -mv.n_R, rot, t0, np.broadcast_to(A.inv_T(T_true), (n, 4, 4))


def _result_rows(res) -> tuple:
    return res.pos_R, res.status, np.where(res.status == ProbeStatus.OK, res.t_s, np.nan)


def _simulate_setups(machine, probe: ProbeConfig, rng, moves: list, travel, feed_mps: float, sdf_true, grp) -> list:
    """[(pos_R (n, 3) m, status (n,), t_s (n,) s)] of every set-up's touches, all simulated at once.

    One :func:`sim.probe.simulate_touches` call for the whole campaign: each kinematics
    evaluation covers every set-up's touches (its cost per call is mostly fixed, a few ms,
    against a few us per pose). The noise is drawn in the same order as set-up by set-up
    (:func:`_simulate_each_setup`, the path before, kept as the tests' oracle), so the log is
    the same to the root finder's tolerance.
    """
    if not moves:
        return []
    parts = [_setup_touches(machine, st, mv, t0) for st, mv, t0 in moves]
    start, d, rot, t0, T_A_W = (None if parts[0][k] is None else np.concatenate([p[k] for p in parts])
                                for k in range(5))
    m = len(travel)
    res = simulate_touches(machine, probe, rng, start, d, np.tile(travel, len(moves)), rot, t0,
                           np.full(len(start), feed_mps), sdf_true, np.tile(grp, len(moves)), T_A_W)
    pos, status, t_s = _result_rows(res)
    return [(pos[i * m:(i + 1) * m], status[i * m:(i + 1) * m], t_s[i * m:(i + 1) * m]) for i in range(len(moves))]


def _simulate_each_setup(machine, probe: ProbeConfig, rng, moves: list, travel, feed_mps: float, sdf_true,
                         grp) -> list:
    """:func:`_simulate_setups` one set-up at a time (the path before; the oracle of the tests and
    the reference of the bench)."""
    out = []
    for st, mv, t0 in moves:
        start, d, rot, t0, T_A_W = _setup_touches(machine, st, mv, t0)
        res = simulate_touches(machine, probe, rng, start, d, travel, rot, t0, np.full(len(t0), feed_mps),
                               sdf_true, grp, T_A_W)
        out.append(_result_rows(res))
    return out


def _append_rows(cols: dict, plan: Plan, st: Setup, mv: SetupMoves, pos, status, t_s, rot_deg,
                 stylus_r_m: float) -> None:
    """Add the set-up's rows to the log columns (file units: mm, deg)."""
    cols["setup"] += [st.name] * plan.n
    cols["target"] += list(plan.target)
    cols["feature"] += list(plan.feature)
    cols["status"] += list(status)
    d_R = -mv.n_R
    for j, c in enumerate("XYZ"):
        cols[f"{c}_mm"].append(pos[:, j] / MM)
        cols[f"{c}n_mm"].append(mv.Xn_R[:, j] / MM)
        cols[f"n{c.lower()}"].append(mv.n_R[:, j])
        cols[f"d{c.lower()}"].append(d_R[:, j])
        cols[f"w{c.lower()}_mm"].append(plan.w_A[:, j] / MM)
        cols[f"wn{c.lower()}"].append(plan.wn_A[:, j])
    cols["t_s"].append(t_s)
    for j, c in enumerate("ABC"):
        cols[f"{c}_deg"].append(np.full(plan.n, rot_deg[j]))
    cols["stylus_r_mm"].append(np.full(plan.n, stylus_r_m / MM))


def _campaign_meta(machine, art: A.Artefact, probe: ProbeConfig, feed_mps: float, meta: dict | None) -> dict:
    """The log's metadata: machine, artefact, chain, probe, feed; ``meta`` on top."""
    r = probe.stylus_r_m
    m = {"machine": machine_name(machine), "artefact": art.name, "stylus_r_mm": repr(r / MM),
         "kinematic_chain": _kinematic_chain(machine),
         "probe_repeatability_k2_um": repr(probe.repeatability_k2_m * 1e6),
         "feed_mm_per_min": repr(feed_mps * 60e3), "generator": "vmt sim.campaign"}
    m.update(meta or {})
    return m
