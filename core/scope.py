"""Is a probe log within the scope of the planar analyses? If not, say why in words.

``identify`` (2D self-calibration, Ibaraki et al. eqs 1-18) and
``discover`` (which starts from the same model) use touches whose nominal
normal lies in the XY plane (``|nz| <= selfcal.NZ_MAX``), made on targets
probed at two or more set-ups (C angles). A log from another kind of job
(a surface probed along Z, a sphere) fails deep inside them with a message
about what broke there; :func:`check_planar_scope` names the real reason
first and, when the log looks like a job vmt can analyse otherwise, which
command to use. The CLI calls it before ``identify``; the discovery engine
(``core.discover.discover``) can call it on its log for the same words.
"""

from __future__ import annotations

import numpy as np

from .exceptions import IdentifiabilityError, counted
from .probelog import ProbeLog
from .selfcal import NZ_MAX


def _statuses(log: ProbeLog) -> str:
    st = log.col("status")
    names, counts = np.unique(st.astype(str), return_counts=True)
    return ", ".join(f"{c} {n}" for n, c in sorted(zip(names, counts), key=lambda t: -t[1]))


def _looks_like(n: np.ndarray, p: np.ndarray) -> str:
    """What job the valid touches look like: a hint naming a vmt command, or ''."""
    nz = np.abs(n[:, 2])
    if np.all(nz > 1 - 1e-6):
        return ("this looks like a surface (Z) probing file: try `vmt fit plane LOG` "
                "(flatness and the height of each point above the plane)")
    if len(p) >= 4:
        # a sphere: p_i = c + R n_i for one centre c and radius R (least squares, 4 unknowns)
        A = np.zeros((3 * len(p), 4))
        A[:, :3] = np.tile(np.eye(3), (len(p), 1))
        A[:, 3] = n.ravel()
        sol, _res, rank, _sv = np.linalg.lstsq(A, p.ravel(), rcond=None)
        misfit = np.sqrt(np.mean((A @ sol - p.ravel()) ** 2))
        if rank == 4 and abs(sol[3]) > 0 and misfit < 0.01 * abs(sol[3]):
            return "the normals point through one centre, as on a sphere: try `vmt fit sphere LOG`"
    return ""


def check_planar_scope(log: ProbeLog, command: str = "identify", *, min_touches: int = 1) -> None:
    """Raise, naming the real reason, when ``log`` is out of the planar analyses' scope.

    Parameters
    ----------
    log : ProbeLog
        A campaign log.
    command : str
        The command named in the message (``identify``, ``discover``).
    min_touches : int
        Fewest valid in-plane touches the command needs.

    Raises
    ------
    IdentifiabilityError
        The log is a plan; no touch is valid (the statuses are listed); no
        valid touch has a normal in the XY plane (what the touches look like,
        and the command that fits them); fewer than ``min_touches`` in-plane
        touches; every in-plane touch in one set-up (one C angle).
    """
    src = log.source
    if log.n == 0:
        raise IdentifiabilityError(f"{src}: no rows")
    ok = log.ok
    if not ok.any():
        if log.has("status") and np.any(log.col("status").astype(str) != "ok"):
            raise IdentifiabilityError(f"{src}: no valid touch: every row's status is not 'ok' "
                                       f"({_statuses(log)})")
        raise IdentifiabilityError(f"{src}: is a plan (measured columns empty), not a campaign: "
                                   f"probe it first (vmt probe, vmt simulate, vmt import)")
    n = log.normals()[ok]
    p = log.positions_mm()[ok]
    planar = np.abs(n[:, 2]) <= NZ_MAX
    if not planar.any():
        hint = _looks_like(n, p)
        raise IdentifiabilityError(
            f"{src}: no touch has a normal in the XY plane (|nz| <= {NZ_MAX:g}): {command} needs "
            "touches on vertical walls (bores, pins, pocket sides) at several C angles"
            + (f"; {hint}" if hint else ""))
    if planar.sum() < min_touches:
        raise IdentifiabilityError(f"{src}: {counted(int(planar.sum()), 'valid touch')} with a normal in the XY "
                                   f"plane; {command} needs at least {min_touches}")
    setups = np.unique(log.col("setup")[ok][planar].astype(str))
    if setups.size < 2:
        raise IdentifiabilityError(
            f"{src}: every touch on a vertical wall is in one set-up ({str(setups[0])!r}): {command} "
            "separates the workpiece from the machine only with the same targets at two or more "
            "set-ups (C angles)")
