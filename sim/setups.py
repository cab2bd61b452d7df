"""Set-ups of a campaign: where the artefact sits and where the rotary axes stand.

A :class:`Setup` is one artefact placement (``T_W_A``) or one rotary-table
index; :func:`c_angle_setups` makes one per C angle (self-calibration),
:func:`mfb_placements` the 17 placements of the multi-feature bar. The
default set-ups of each artefact are on its record (:mod:`sim.catalog`).

Frames: W table, A artefact (``T_W_A`` placement of A in W).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.exceptions import ConfigError

from . import artefacts as A
from .probe import rotary_count


@dataclass(frozen=True)
class Setup:
    """One set-up: placement ``T_W_A`` (nominal), rotary positions, true pose.

    Attributes
    ----------
    name : str
        The ``setup`` id in the log.
    T_W_A : (4,4) float
        Nominal placement of A in W, m.
    rot_rad : tuple of float
        Rotary axis positions in the machine's ``rotary_axes`` order, rad.
    T_W_A_true : (4,4) float or None
        True placement (default: the nominal one).
    """

    name: str
    T_W_A: np.ndarray = field(compare=False)
    rot_rad: tuple = ()
    T_W_A_true: np.ndarray | None = field(default=None, compare=False)


def c_angle_setups(machine, artefact: A.Artefact, c_angles_deg) -> list[Setup]:
    """One set-up per C angle (deg), artefact in its default placement."""
    axes = tuple(getattr(machine, "rotary_axes", ()) or ())
    out = []
    seen = {}
    for c in c_angles_deg:
        c = float(c)
        if not np.isfinite(c):
            raise ConfigError(f"C angle {c!r} is not finite")
        turn = round(c % 360.0, 9) % 360.0     # 0 and 360, -90 and 270: the same set-up
        if turn in seen:
            raise ConfigError(f"C angles {seen[turn]:g} and {c:g} deg are the same set-up (equal modulo 360): "
                              "give each angle once")
        seen[turn] = c
        rot = np.zeros(len(axes))
        if "C" in axes:
            rot[axes.index("C")] = np.deg2rad(c)
        elif c != 0.0:
            raise ConfigError(f"C angle {c:g} deg: machine {machine_name(machine)!r} has no C axis "
                              f"(rotary axes {', '.join(axes) or 'none'}); only 0 is possible")
        out.append(Setup(f"C{c:g}", artefact.T_W_A, tuple(rot)))
    return out


def mfb_placements(machine=None, artefact: A.Artefact | None = None) -> list[Setup]:
    """17 MFB placements (the paper's count), the bar horizontal.

    Chosen to fit the smallest machine (vmc-3axis, X 600 x Y 400 mm): along
    X at y = -120, 0, +120 mm on 60 mm supports and on a 200 mm riser; at
    +-30 deg about Z (centred) and +-15 deg (y = +-80 mm) at both heights;
    reversed (180 deg, mistake-proofing) at both heights; one along X at
    100 mm. A vertical probe cannot reach the holes of a vertical bar, so
    there is no vertical placement (Z-axis positioning must come from
    elsewhere, e.g. a tilted bar with the A axis).
    """
    art = artefact or A.multi_feature_bar()
    k = rotary_count(machine) if machine is not None else 0
    xc = float(art.info["poi_nominal_m"][-1, 0]) / 2
    z0 = float(art.T_W_A[2, 3])
    out = []

    def add(theta_deg, cy, dz):
        T = A.make_T(A.rot_z(np.deg2rad(theta_deg)), (0.0, cy, z0 + dz)) @ A.make_T(None, (-xc, 0.0, 0.0))
        out.append(Setup(f"P{len(out) + 1:02d}", T, tuple(np.zeros(k))))

    for dz in (0.0, 0.2):
        for y in (-0.12, 0.0, 0.12):
            add(0.0, y, dz)
        add(30.0, 0.0, dz)
        add(-30.0, 0.0, dz)
        add(15.0, -0.08, dz)
        add(-15.0, 0.08, dz)
        add(180.0, 0.0, dz)
    add(0.0, 0.0, 0.1)
    return out


def machine_name(machine) -> str:
    """The machine's name (``name`` or ``config.name``), else its type's name."""
    for a in ("name",):
        v = getattr(machine, a, None)
        if isinstance(v, str) and v:
            return v
    cfg = getattr(machine, "config", None)
    v = getattr(cfg, "name", None)
    return v if isinstance(v, str) and v else type(machine).__name__
