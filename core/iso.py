"""ISO 230-1 / ISO 230-7 geometric error vocabulary.

Every error symbol of a machine tool, named exactly as ISO 230-1:2012 and
ISO 230-7:2015 (and the papers in ``shared/papers``) name it, with what it
means: the axis whose motion it belongs to, the direction of the error, its
kind and its SI unit.

Naming rule (ISO 230-1, 3.4): ``E`` + direction of the error + moving axis.
``EXX`` is the positioning error of X (error in X direction, X moving),
``EYX`` the straightness of X in Y, ``EAX`` the roll of X. Location errors
carry a ``0``: ``EC0Y`` is the squareness of Y to X (orientation of the
Y reference line about Z), ``EX0C`` the X position of the C-axis average
line.

Sign conventions (ISO 230-1; used by ``core``, by the simulator ``sim``
and in every output, CONTRIBUTING.md "Error conventions"): an error motion
is the displacement of the TOOL relative to the WORKPIECE, whichever side
of the bed the axis is on (a table-moving X with ``EXX = +1 um`` leaves the
tool 1 um further in +X relative to the part than commanded, as a
tool-moving X does); translations are positive along the positive axis
directions of ISO 841, angular errors right-handed rotations about X (A),
Y (B), Z (C), in radians. Location errors are the position and
orientation of an axis's reference (or average) line with all axes at zero,
the same value whichever side the axis is on: a linear axis's line in the
machine frame R; a rotary axis's relative to the axis carrying it, in that
carrier's frame (R only for an axis on the bed): a C carried by A has its
line in R at A = 0 at ``EX0C``, ``EY0C`` plus what A's errors add there
(``EY0A``; ``EB0A`` times the height above A's line), CONTRIBUTING.md
"Error conventions".

Zero conventions of ISO 230-1 (X primary, Y secondary): the zero-position
errors ``EX0X``, ``EY0Y``, ``EZ0Z`` and the offsets of the linear reference
lines are set to zero; ``EB0X = EC0X = 0`` (X defines the machine X axis),
``EA0Y = 0`` (Y defines the XY plane). What remains of the linear axes'
location errors is the three squarenesses ``EC0Y``, ``EB0Z``, ``EA0Z``.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from .exceptions import ConfigError

LINEAR_AXES = ("X", "Y", "Z")
ROTARY_AXES = ("A", "B", "C")
_ROT_ABOUT = {"A": "X", "B": "Y", "C": "Z"}


class Kind(enum.Enum):
    """Kind of a geometric error (ISO 230-1 clause 3, ISO 230-7 clause 3)."""

    POSITIONING = "positioning"  # linear: along the motion; rotary: angular positioning
    STRAIGHTNESS = "straightness"  # linear axis, translational, across the motion
    ANGULAR = "angular"  # linear axis: roll, pitch, yaw
    RADIAL = "radial"  # rotary axis, translational, across the axis
    AXIAL = "axial"  # rotary axis, translational, along the axis
    TILT = "tilt"  # rotary axis, angular, across the axis
    LOCATION = "location"  # squareness / position / orientation of an axis line


@dataclass(frozen=True)
class Symbol:
    """What one ISO error symbol means.

    Attributes
    ----------
    name : str
        ISO symbol, e.g. ``"EXX"``, ``"EC0Y"``, ``"EX0C"``.
    axis : str
        Axis the error belongs to (``"X"``, ..., ``"C"``).
    direction : str
        Direction of the error: ``"X"``, ``"Y"``, ``"Z"`` for a translation,
        ``"A"``, ``"B"``, ``"C"`` for a rotation about X, Y, Z.
    kind : Kind
    location : bool
        True for a location error (constant; no ``(position)`` argument).
    """

    name: str
    axis: str
    direction: str
    kind: Kind
    location: bool

    @property
    def angular(self) -> bool:
        """True when the error is a rotation (unit rad)."""
        return self.direction in ROTARY_AXES

    @property
    def unit(self) -> str:
        """SI unit of the error's value inside vmt: ``"m"`` or ``"rad"``."""
        return "rad" if self.angular else "m"

    @property
    def report_unit(self) -> str:
        """Unit used in reports and JSON: ``"um"`` or ``"urad"``."""
        return "urad" if self.angular else "um"

    @property
    def report_scale(self) -> float:
        """Factor from the SI value to the report unit (1e6 for both)."""
        return 1e6

    @property
    def rotary(self) -> bool:
        """True for an error of a rotary axis (ISO 230-7)."""
        return self.axis in ROTARY_AXES


def _linear_motion(axis: str) -> list[Symbol]:
    out = []
    for d in LINEAR_AXES:
        kind = Kind.POSITIONING if d == axis else Kind.STRAIGHTNESS
        out.append(Symbol(f"E{d}{axis}", axis, d, kind, False))
    for d in ROTARY_AXES:
        out.append(Symbol(f"E{d}{axis}", axis, d, Kind.ANGULAR, False))
    return out


def _linear_location(axis: str) -> list[Symbol]:
    """All location errors of a linear axis's reference line (ISO 230-1 3.4.5)."""
    out = []
    for d in LINEAR_AXES:
        out.append(Symbol(f"E{d}0{axis}", axis, d, Kind.LOCATION, True))
    for d in ROTARY_AXES:
        if _ROT_ABOUT[d] == axis:
            continue  # a rotation about the line itself is no location error
        out.append(Symbol(f"E{d}0{axis}", axis, d, Kind.LOCATION, True))
    return out


def _rotary_motion(axis: str) -> list[Symbol]:
    along = _ROT_ABOUT[axis]
    out = []
    for d in LINEAR_AXES:
        kind = Kind.AXIAL if d == along else Kind.RADIAL
        out.append(Symbol(f"E{d}{axis}", axis, d, kind, False))
    for d in ROTARY_AXES:
        kind = Kind.POSITIONING if d == axis else Kind.TILT
        out.append(Symbol(f"E{d}{axis}", axis, d, kind, False))
    return out


def _rotary_location(axis: str) -> list[Symbol]:
    """Position and orientation of a rotary axis average line (ISO 230-7)."""
    along = _ROT_ABOUT[axis]
    out = []
    for d in LINEAR_AXES:
        if d != along:
            out.append(Symbol(f"E{d}0{axis}", axis, d, Kind.LOCATION, True))
    for d in ROTARY_AXES:
        if d != axis:
            out.append(Symbol(f"E{d}0{axis}", axis, d, Kind.LOCATION, True))
    return out


def _all_symbols() -> list[Symbol]:
    out: list[Symbol] = []
    for a in LINEAR_AXES:
        out += _linear_motion(a)
    for a in LINEAR_AXES:
        out += _linear_location(a)
    for a in ROTARY_AXES:
        out += _rotary_motion(a)
        out += _rotary_location(a)
    return out


#: Largest rotation error a machine file (sim.machinefile) or a vmt-comp/1 table (core.volumetric.comp_tables)
#: may give, urad (1 mrad, 206 arcsec, 1 mm per metre): vmt's estimators take the chain's angular errors to first
#: order (identify's Jacobian, discover's baseline), and the neglected second-order term e^2/2 of a rotation e
#: reaches 0.5 um a metre from its axis at 1 mrad, the size of the probing noise they are sized for; and 1 mrad
#: over a 1 m lever is MAX_LINEAR_UM. Real machines' angular errors are tens of urad (the built-in machines'
#: 'realistic' sets, 31 seeds each: at most 98.6 urad, EBX; 38.2 um, EXX).
MAX_ANGULAR_URAD = 1000.0
#: Largest translation error a machine file or a vmt-comp/1 table may give, um (1 mm): half the default 2 mm
#: approach clearance of the plans (sim.plans.Plan.clearance_m), beyond which a planned touch starts in the
#: material or misses, and tens of times a real machine's uncompensated positioning error (tens of um per metre
#: of stroke).
MAX_LINEAR_UM = 1000.0

#: Every symbol, in the one fixed order vmt uses for parameter vectors.
SYMBOLS: tuple[Symbol, ...] = tuple(_all_symbols())
_BY_NAME = {s.name: s for s in SYMBOLS}

#: The 18 motion errors of three linear axes (X, Y, Z; 6 each), fixed order.
LINEAR_MOTION: tuple[str, ...] = tuple(
    s.name for s in SYMBOLS if s.axis in LINEAR_AXES and not s.location
)
#: The three squareness errors left by the ISO 230-1 zero conventions.
SQUARENESS: tuple[str, ...] = ("EC0Y", "EB0Z", "EA0Z")
#: The 21 errors of three linear axes (MFB paper, section 5.2), fixed order.
TWENTY_ONE: tuple[str, ...] = LINEAR_MOTION + SQUARENESS
#: Location errors of linear axes that the ISO 230-1 conventions set to zero.
ZERO_BY_CONVENTION: tuple[str, ...] = tuple(
    s.name
    for s in SYMBOLS
    if s.axis in LINEAR_AXES and s.location and s.name not in SQUARENESS
)


def symbol(name: str) -> Symbol:
    """Look up an ISO symbol by name.

    Accepts the paper spelling with parentheses too (``"EC(0X)Y"`` is
    ``"EC0Y"``: squareness of Y with respect to X).

    Raises
    ------
    ConfigError
        If ``name`` is no ISO 230-1 / 230-7 symbol known to vmt.
    """
    key = name.strip().upper()
    if "(" in key:  # EC(0X)Y -> EC0Y
        head, rest = key.split("(", 1)
        inner, tail = rest.split(")", 1) if ")" in rest else (rest, "")
        key = head + inner[:1] + tail
    try:
        return _BY_NAME[key]
    except KeyError:
        raise ConfigError(f"unknown ISO error symbol {name!r}") from None


def symbols_of_axis(axis: str, *, location: bool | None = None) -> tuple[Symbol, ...]:
    """All symbols of one axis, optionally only motion or only location errors."""
    axis = axis.upper()
    if axis not in LINEAR_AXES + ROTARY_AXES:
        raise ConfigError(f"unknown axis {axis!r}; expected one of X Y Z A B C")
    return tuple(
        s for s in SYMBOLS if s.axis == axis and (location is None or s.location == location)
    )
