"""The artefacts vmt can simulate: one record each, the single table of them.

An :class:`ArtefactRecord` holds everything the rest of vmt needs to know
about an artefact beyond its geometry (:mod:`sim.artefacts`) and its probing
plan (:mod:`sim.plans`): the factory, the plan, the default virtual machine
and the default set-ups (C angles of a self-calibration, or the bar's
placements), the pause between set-ups, and a one-line description. The
campaign runner (:func:`sim.campaign.simulate_campaign`), the emulator's
scenes (``hardware.virtual``) and the ``vmt simulate`` command take their
choices, defaults and help text from :data:`CATALOG`.

A new artefact: its factory in ``sim/artefacts.py``, its plan in
``sim/plans.py``, one record here.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

from core.exceptions import ConfigError

from . import artefacts as A
from . import plans as P
from .setups import Setup, c_angle_setups, mfb_placements


@dataclass(frozen=True)
class ArtefactRecord:
    """One artefact: how to build it, probe it and set it up.

    Attributes
    ----------
    name : str
        Its name in logs (``artefact`` metadata), on the command line and in
        ``Artefact.name``.
    description : str
        One line for help texts.
    factory : callable
        ``factory(**kw) -> sim.artefacts.Artefact``.
    plan : callable
        ``plan(artefact, **kw) -> sim.plans.Plan``, its standard plan.
    default_machine : str
        Name in ``sim.machines.MACHINES`` of the machine it is probed on by default.
    default_c_deg : tuple of float
        C angles of its default campaign on a machine with a C axis, deg
        (empty for an artefact set up by placements).
    placements : callable or None
        ``placements(machine, artefact) -> list[Setup]``: its default
        placements (None: one set-up per C angle).
    setup_change_s : float
        Time between two set-ups, s (re-placing a bar takes longer than
        indexing a table).
    links_along_z_A : bool
        The moves between touches are its part program's: out along the
        artefact's own z_A to a clearance plane above its top, across,
        back (:func:`sim.mfb_scene.link_points`, a bar in any
        orientation); False: up to a safe height along the machine's z
        (an artefact lying on the table).
    """

    name: str
    description: str
    factory: Callable[..., A.Artefact]
    plan: Callable[..., P.Plan]
    default_machine: str
    default_c_deg: tuple = ()
    placements: Callable[..., list] | None = None
    setup_change_s: float = 10.0
    links_along_z_A: bool = False

    def default_setups(self, machine, artefact: A.Artefact) -> list[Setup]:
        """The set-ups :func:`sim.campaign.simulate_campaign` uses when given none.

        The placements of a placed artefact; else one set-up at C = 0.
        """
        if self.placements is not None:
            return self.placements(machine, artefact)
        return c_angle_setups(machine, artefact, [0.0])

    def setups_text(self) -> str:
        """The default set-ups in words: ``17 placements`` or ``C = 0,75,130,210``."""
        if self.placements is not None:
            return f"{_placement_count(self.placements)} placements"
        return f"C = {','.join(f'{c:g}' for c in self.default_c_deg)}"

    def defaults_text(self) -> str:
        """``mfb on mikron-ucp710 (17 placements)``: the defaults, for help texts."""
        if self.placements is not None:
            return f"{self.name} on {self.default_machine} ({self.setups_text()})"
        return f"{self.name} on {self.default_machine} at {self.setups_text()}"


@functools.cache
def _placement_count(placements: Callable[..., list]) -> int:
    """How many placements ``placements`` makes: built once (it builds the artefact), as
    every ``vmt`` command's help text asks for it when the parser is built."""
    return len(placements(None, None))


#: Every artefact by name, in the order help texts list them.
CATALOG: dict[str, ArtefactRecord] = {r.name: r for r in (
    ArtefactRecord("mfb", "the multi-feature bar (Viprey et al. 2016): 12 holes, 11 rods, 22 faces",
                   A.multi_feature_bar, P.mfb_plan, "mikron-ucp710", placements=mfb_placements,
                   setup_change_s=300.0, links_along_z_A=True),
    ArtefactRecord("cross-pocket", "the cross-shaped pocket with two spheres (Ibaraki et al., section 4.2)",
                   A.cross_pocket, P.cross_pocket_plan, "nmv3000", default_c_deg=(0.0, 75.0, 130.0, 210.0)),
    ArtefactRecord("pin-circle", "the circle of 18 pins with two spheres (Ibaraki et al., section 5)",
                   A.pin_circle, P.pin_circle_plan, "mikron-ucp710",
                   default_c_deg=(0.0, 31.0, 83.0, 137.0, 191.0, 227.0, 257.0, 313.0)),
    ArtefactRecord("freeform", "a point-asymmetric free-form boss with two spheres",
                   A.freeform_plate, P.freeform_plan, "nmv3000", default_c_deg=(0.0, 75.0, 130.0, 210.0)),
)}


def record(name: str) -> ArtefactRecord:
    """The record of artefact ``name`` (ConfigError naming the choices if unknown)."""
    if name not in CATALOG:
        raise ConfigError(f"unknown artefact {name!r} (choose from {', '.join(CATALOG)})")
    return CATALOG[name]


def make_artefact(name: str, **kw) -> A.Artefact:
    """Build the artefact called ``name`` (ConfigError naming the choices if unknown)."""
    return record(name).factory(**kw)


def make_plan(art: A.Artefact, **kw) -> P.Plan:
    """The standard plan of ``art`` (by its name)."""
    if art.name not in CATALOG:
        raise ConfigError(f"no plan for artefact {art.name!r} (known: {', '.join(CATALOG)})")
    return CATALOG[art.name].plan(art, **kw)


def describe() -> str:
    """One line per artefact: name, description and defaults (for ``--help``)."""
    return "\n".join(f"{r.name:13s} {r.description}\n{'':13s} default: on {r.default_machine}, {r.setups_text()}"
                     for r in CATALOG.values())
