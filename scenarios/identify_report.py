"""The report of a 2D self-calibration with the record of what it was identified on.

One place for what ``vmt identify`` and ``vmt demo`` write as ``identify.json``: the report
(:meth:`core.selfcal.SelfCalResult.to_report`, its tables at reading + J) and its
``estimate.identified_on`` record (:func:`core.state.identified_on`: machine, chain, probe
offsets J, Z of the touches), by which ``vmt vcmm --machine-state`` refuses a state on another
machine or with another probe. A report made without the record is applied anywhere with a
notice meant for files written before session 26 (review29c F2: the demo's file was).
"""

from __future__ import annotations

import numpy as np


def identify_record(log, J_mm=None, used=None) -> dict:
    """What a state identified from ``log``'s touches is identified on: the keyword arguments of
    :func:`core.state.identified_on` (machine, chain and controller from the log's header
    (:func:`core.state.log_machine`: the machine its plan was made for, not the controller), ``J_mm`` (3,) mm or
    None (unknown: probe-log/1 holds none), the Z readings' range of the touches ``used``
    (a bool mask, default ``log.ok``), their time span and temperatures (:func:`core.state.log_conditions`)).
    Made before the log is let go (the identification needs only the touches), turned into the record by
    :func:`identify_report`."""
    from core.state import log_conditions, log_machine

    used = log.ok if used is None else used
    z = log.col("Z_mm")[used]
    z = z[np.isfinite(z)]
    machine, controller = log_machine(log.meta)   # the plan's machine, not the controller's name (session 37)
    return dict(machine=machine, chain=log.meta.get("kinematic_chain"), controller=controller,
                probe_offsets_J_mm=None if J_mm is None else [J_mm],
                z_mm=(float(z.min()), float(z.max())) if z.size else None,
                **log_conditions(log, used))   # when and at what temperature (review33a F8): t_s, temp_*_C


def identify_report(res, mc, on: dict) -> dict:
    """``res``'s report (``mc``: its Monte Carlo or None) with ``estimate.identified_on`` from ``on``
    (:func:`identify_record`); the tables at reading + the probe offsets ``on`` names (unknown: at the
    readings). The note on the C circle's centre names what the axis carrying C adds to it in ``on``'s
    chain (the log's ``kinematic_chain``; :func:`core.selfcal.c_centre_note`)."""
    from core.selfcal import c_centre_note
    from core.state import identified_on

    J = on["probe_offsets_J_mm"]
    report = res.to_report(mc, None if J is None else [v * 1e-3 for v in J[0]])   # the state at reading + J
    conv, generic = report.get("conventions"), c_centre_note(None)
    if conv and "notes" in conv:
        conv["notes"] = [c_centre_note(on.get("chain")) if n == generic else n for n in conv["notes"]]
    if "estimate" in report:
        report["estimate"]["identified_on"] = identified_on(**on)
    return report
