"""Import a GRBL session transcript (a sender's console log) with its plan.

Every well-formed ``[PRB:x,y,z(,...):s]`` report in the transcript is one
touch, in order: ``s = 1`` is ``ok`` with the reported X, Y, Z (machine
coordinates, mm), ``s = 0`` is ``no_trigger``. A report answering a ``$#``
query (it follows the ``[G92:...]`` / ``[TLO:...]`` lines of that answer)
repeats the last probe and is skipped. A line that starts like a probe
report but is not one is an error naming the line: garbage is never taken
for a position.

Timestamps, when lines carry them, give ``t_s`` (seconds since the first
timestamp): a leading number of seconds (``12.345 < [PRB:...]``, what
``vmt probe --transcript`` writes), a clock time ``HH:MM:SS(.fff)`` or an
ISO date-time, optionally in brackets. Without timestamps ``t_s`` is the
touch index. ``t_s`` must not go backwards (a clock time passing midnight
is unwrapped).
"""

from __future__ import annotations

import re
from datetime import datetime
from pathlib import Path

import numpy as np

from core.atomic import head_problem, input_problem
from core.exceptions import PlanError, ProbeLogError, counted
from core.probelog import ProbeLog

from .campaign import log_from_plan
from .grbl import parse_prb

_TS = re.compile(
    r"^\s*\[?\s*(?:(?P<iso>\d{4}-\d\d-\d\d[T ]\d\d:\d\d:\d\d(?:[.,]\d+)?)"
    r"|(?P<hms>\d\d?:\d\d:\d\d(?:[.,]\d+)?)"
    r"|(?P<sec>\d+(?:\.\d+)?)(?=\s))\s*\]?")
_PRB_TOKEN = re.compile(r"\[PRB[^\]]*\]?")


def _stamp(line: str) -> float | None:
    m = _TS.match(line)
    if not m:
        return None
    if m.group("iso"):
        return datetime.fromisoformat(m.group("iso").replace(",", ".").replace(" ", "T")).timestamp()
    if m.group("hms"):
        h, mi, s = m.group("hms").replace(",", ".").split(":")
        return int(h) * 3600 + int(mi) * 60 + float(s)
    return float(m.group("sec"))


def read_transcript(path):
    """The probe reports of a transcript.

    Returns
    -------
    pos_mm : (n, 3) float
        Reported X, Y, Z of each probe, machine coordinates, mm.
    touched : (n,) bool
    t_s : (n,) float or None
        Seconds since the transcript's first timestamp, ``None`` without timestamps.
    lines : list of int
        1-based transcript line of each report.

    Raises
    ------
    ProbeLogError
        Missing file, a malformed probe report, timestamps on some probe
        lines only, time going backwards.
    """
    p = Path(path)
    problem = input_problem(p, "transcript")  # (a pipe is read too: vmt import grbl /dev/stdin)
    if problem:
        raise ProbeLogError(f"{p}: {problem}")
    data = p.read_bytes()
    problem = head_problem(p, data[:8])
    if problem:
        raise ProbeLogError(f"{p}: {problem}")
    # a stray byte of serial noise in a line that is not a probe report is harmless: decoded with
    # replacement (a probe report it garbles is refused as malformed, below)
    text = data.decode("utf-8", errors="replace")
    pos, touched, stamps, where = [], [], [], []
    t0 = None
    prev_info = False
    for ln, line in enumerate(text.splitlines(), start=1):
        ts = _stamp(line)
        if ts is not None and t0 is None:
            t0 = ts
        tok = _PRB_TOKEN.search(line)
        if not tok:
            prev_info = bool(re.search(r"\[(G5[4-9]|G28|G30|G92|TLO):", line)) or (
                prev_info and not line.strip())
            continue
        if prev_info:               # the PRB line of a `$#` answer repeats the last probe
            prev_info = False
            continue
        r = parse_prb(tok.group(0))
        if r is None:
            raise ProbeLogError(f"{p}: line {ln}: malformed probe report {tok.group(0)[:60]!r}")
        pos.append(r[0][:3])
        touched.append(r[1])
        stamps.append(ts)
        where.append(ln)
    if not pos:
        raise ProbeLogError(f"{p}: no probe reports ([PRB:...]) in it: not a GRBL session transcript "
                            "(vmt probe --transcript writes one), or of a session that probed nothing")
    have = [s is not None for s in stamps]
    if any(have) and not all(have):
        ln = where[have.index(False)]
        raise ProbeLogError(f"{p}: line {ln}: probe report without a timestamp (others have one)")
    t = None
    if all(have):
        t = np.array(stamps, dtype=float) - t0
        off = 0.0
        for i in range(1, len(t)):
            t[i] += off
            if t[i] < t[i - 1]:
                if t[i - 1] - t[i] > 43200 and _TS.match(text.splitlines()[where[i] - 1]).group("hms"):
                    off += 86400.0
                    t[i] += 86400.0
                else:
                    raise ProbeLogError(f"{p}: line {where[i]}: time goes backwards")
    return np.array(pos), np.array(touched, dtype=bool), t, where


def import_transcript(path, plan: ProbeLog, *, dt_s: float = 1.0) -> ProbeLog:
    """Merge a GRBL transcript with its plan into a full ``probe-log/1``.

    Raises
    ------
    PlanError
        Not one probe report per plan row.
    ProbeLogError
        See :func:`read_transcript`.
    """
    pos, touched, t, _ = read_transcript(path)
    if len(pos) != plan.n:
        raise PlanError(f"{path}: {len(pos)} probe reports but the plan {plan.source} has {counted(plan.n, 'row')}")
    src = "transcript timestamps" if t is not None else f"plan order x {dt_s:g} s (no timestamps)"
    if t is None:
        t = np.arange(plan.n) * float(dt_s)
    status = ["ok" if k else "no_trigger" for k in touched]
    meta = {"machine": "grbl", "source": f"vmt import grbl {Path(path).name}", "t_s_source": src}
    return log_from_plan(plan, pos, status, t, meta, source=str(path))
