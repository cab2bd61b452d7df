"""Touches in SI units: the arrays every estimator in ``core`` starts from.

:func:`from_log` converts a :class:`~core.probelog.ProbeLog` (mm, degrees)
into a :class:`Touches` (metres, radians), keeps only the rows whose status
is ``ok`` (``row`` maps back to the log's 0-based rows) and indexes set-ups
and targets.

Frames: ``_R`` is the machine reference frame (MCS), ``_A`` the artefact's
own frame (the probe log's ``wx_mm``.. and ``wnx``.. columns). Self-calibration
takes A as its workpiece frame W (the artefact sits on the table).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from .exceptions import ProbeLogError
from .probelog import ProbeLog
from .units import DEG, MM


class ProbeStatus(StrEnum):
    """Outcome of one touch: the probe log's ``status`` column (the values are its strings).

    Only ``ok`` touches enter a fit (:func:`from_log`); :data:`STATUS_MESSAGES`
    says what the others mean.
    """

    OK = "ok"
    NO_TRIGGER = "no_trigger"
    EARLY_TRIGGER = "early_trigger"


#: What each :class:`ProbeStatus` means, in words.
STATUS_MESSAGES = {
    ProbeStatus.OK: "triggered on the surface: a valid touch",
    ProbeStatus.NO_TRIGGER: "the probing move ended without contact (surface missing or farther than planned)",
    ProbeStatus.EARLY_TRIGGER: "the stylus was already in contact at the start of the approach",
}


@dataclass(frozen=True)
class Touches:
    """Valid touches of one campaign, SI units.

    Attributes
    ----------
    row : (n,) int
        0-based row of each touch in the source log.
    p_R : (n, 3) float
        Reported stylus-tip centre, machine frame, m. None on the copy a
        planar baseline keeps (``core.baseline.PLANAR_TOUCHES_DROPPED``, as
        ``wn_A``: read only while the baseline is built); ``dq_m`` then
        refuses.
    pn_R : (n, 3) float
        Nominal stylus-tip centre at contact, machine frame, m.
    n_R : (n, 3) float
        Nominal outward surface normal, machine frame (unit).
    d_R : (n, 3) float
        Approach direction of the stylus, machine frame (unit).
    rot_rad : (n, 3) float
        Rotary axis positions A, B, C, rad.
    t_s : (n,) float
        Time since the campaign started, s.
    setup : (n,) int
        Index into ``setup_ids``.
    target : (n,) int
        Index into ``target_ids``.
    setup_ids, target_ids : tuple of str
        Ids in order of first appearance.
    feature : (n,) object
        Feature id per touch (``""`` when the log has none).
    w_A : (n, 3) float
        Nominal contact point, artefact frame, m (NaN when absent).
    wn_A : (n, 3) float
        Nominal normal, artefact frame (NaN when absent).
    temps_C : dict[str, (n,) float]
        Temperature columns, degrees Celsius.
    d_prev_R : (n, 3) float or None
        Approach direction of the log row just before each touch that has
        one, a row that did not trigger included (the probe moved along it
        all the same), machine frame; NaN for a touch with none before it
        (the log's first). None where not built (touches not read from a
        log).
    n_step : float
        The step the log printed the normals' components to where the
        reader normalised them (:attr:`core.probelog.ProbeLog.unit_steps`,
        e.g. 1e-4 for ``0.7071``); 0.0 where they were read as written
        (``n_R``'s own digits then say their step).
    text_steps : dict or None
        The steps the log's text printed its nominal and normal columns to
        (:attr:`core.probelog.ProbeLog.text_steps`: ``Xn_mm`` printed
        ``10.0000000`` has 1e-7 whatever its values), the precision the
        file declares; None for touches not read from text (a log built in
        memory, the simulator's): their values' own digits say it.
    """

    row: np.ndarray
    p_R: np.ndarray
    pn_R: np.ndarray
    n_R: np.ndarray
    d_R: np.ndarray
    rot_rad: np.ndarray
    t_s: np.ndarray
    setup: np.ndarray
    target: np.ndarray
    setup_ids: tuple
    target_ids: tuple
    feature: np.ndarray
    w_A: np.ndarray
    wn_A: np.ndarray
    temps_C: dict
    d_prev_R: np.ndarray | None = None
    n_step: float = 0.0
    text_steps: dict | None = None

    @property
    def n(self) -> int:
        """Number of touches."""
        return len(self.row)

    @property
    def dq_m(self) -> np.ndarray:
        """(n,) measured normal deviation ``n . (p - pn)``, m (spec's ``dq``)."""
        if self.p_R is None:
            raise ValueError("touches: no measured tip centres (p_R) here: a planar baseline's copy drops them "
                             "once built (core.baseline.PLANAR_TOUCHES_DROPPED); use the baseline's y")
        return np.einsum("ij,ij->i", self.n_R, self.p_R - self.pn_R)

    def subset(self, mask: np.ndarray, *, reindex: bool = False) -> "Touches":
        """Touches selected by a bool mask or index array.

        ``reindex=False`` keeps ``setup_ids``/``target_ids`` (indices stay
        comparable with the full set); ``True`` keeps only the set-ups and
        targets that still have touches, renumbered by first appearance.
        """
        kw = {}
        for k, v in self.__dict__.items():
            if isinstance(v, np.ndarray):
                kw[k] = v[mask]
            elif k == "temps_C":
                kw[k] = {n: a[mask] for n, a in v.items()}
            else:
                kw[k] = v
        if reindex:
            for idx, ids in (("setup", "setup_ids"), ("target", "target_ids")):
                kw[idx], kw[ids] = _index(np.array([self.__dict__[ids][i] for i in kw[idx]], dtype=object))
        return Touches(**kw)


def _index(ids: np.ndarray) -> tuple[np.ndarray, tuple]:
    uniq = tuple(dict.fromkeys(ids.tolist()))
    pos = {u: i for i, u in enumerate(uniq)}
    return np.array([pos[s] for s in ids], dtype=int), uniq


def from_log(log: ProbeLog, *, include_invalid: bool = False) -> Touches:
    """Convert a probe log to SI :class:`Touches`.

    Parameters
    ----------
    log : ProbeLog
    include_invalid : bool
        Keep rows whose ``status`` is not ``ok`` (default: leave them out,
        as every fit does).

    Raises
    ------
    ProbeLogError
        If the log is a plan (no measured positions) or has no valid touch.
    """
    mask = np.ones(log.n, bool) if include_invalid else log.ok
    if log.n and log.is_plan:
        raise ProbeLogError(f"{log.source}: is a plan (measured columns empty), not a campaign")
    if not mask.any():
        raise ProbeLogError(f"{log.source}: no valid touch (every status is not 'ok')")
    rows = np.flatnonzero(mask)

    def v3(names, scale=1.0):
        return np.column_stack([log.col(c)[rows] for c in names]) * scale

    # the move before each touch: the previous log row with an approach direction, whether it triggered or not
    d_all = np.column_stack([np.asarray(log.col(c), float) for c in ("dx", "dy", "dz")])
    has_d = np.flatnonzero(np.all(np.isfinite(d_all), axis=1))
    before = np.searchsorted(has_d, rows) - 1
    d_prev = np.full((len(rows), 3), np.nan)
    d_prev[before >= 0] = d_all[has_d[before[before >= 0]]]
    setup, setup_ids = _index(log.col("setup")[rows])
    target, target_ids = _index(log.col("target")[rows])
    return Touches(
        row=rows,
        p_R=v3(("X_mm", "Y_mm", "Z_mm"), MM),
        pn_R=v3(("Xn_mm", "Yn_mm", "Zn_mm"), MM),
        n_R=v3(("nx", "ny", "nz")),
        d_R=v3(("dx", "dy", "dz")),
        rot_rad=v3(("A_deg", "B_deg", "C_deg"), DEG),
        t_s=log.col("t_s")[rows].astype(float),
        setup=setup,
        target=target,
        setup_ids=setup_ids,
        target_ids=target_ids,
        feature=log.col("feature")[rows],
        w_A=v3(("wx_mm", "wy_mm", "wz_mm"), MM),
        wn_A=v3(("wnx", "wny", "wnz")),
        temps_C={c: log.col(c)[rows] for c in log.temperature_columns()},
        d_prev_R=d_prev,
        n_step=float(log.unit_steps.get("nx", 0.0)),
        text_steps=dict(log.text_steps) or None,
    )
