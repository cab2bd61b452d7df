"""ISO 10791 kinematic chain strings.

A machine's structure is written as in ISO 10791-2 / -6 (and the papers in
``shared/papers``): ``V[w-C-A-b-Y-X-Z-(C)-t]`` (DMG Mori NMV3000, self-
calibration paper case 2), ``[w C' A' b X Y Z (C1) t]`` (Mikron UCP710, MFB
paper), ``V[w-X-Y-b-Z-(C)-t]`` (3-axis vertical machining centre).

Reading rule: ``w`` is the workpiece, ``b`` the bed, ``t`` the tool. The
axes between ``w`` and ``b`` form the workpiece branch, listed from the
workpiece down to the bed (``w-C-A-b``: the part sits on C, C rides on A,
A on the bed); the axes between ``b`` and ``t`` form the tool branch, listed
from the bed up to the tool (``b-Y-X-Z``: Y on the bed, X on Y, Z on X).
A parenthesised axis (``(C)``, ``(C1)``) is the spindle: kept as a name,
never indexed. A prime (``C'``: the axis moves the workpiece) is accepted
and dropped; the side is known from the position in the chain. Tokens are
separated by ``-`` or blanks; a leading letter (``V`` vertical, ``H``
horizontal) is the spindle orientation and is ignored.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from .exceptions import ConfigError
from .iso import LINEAR_AXES, ROTARY_AXES

_OUTER = re.compile(r"^\s*([A-Za-z]?)\s*\[(.*)\]\s*$")
_AXIS = re.compile(r"^([XYZABC])(['\u2019]?)$")
_SPINDLE = re.compile(r"^\(([XYZABC][0-9]*['\u2019]?)\)$")


@dataclass(frozen=True)
class Chain:
    """A parsed kinematic chain.

    Attributes
    ----------
    text : str
        The chain string as given.
    workpiece_axes : tuple of str
        Axes carrying the workpiece, from the workpiece down to the bed.
    tool_axes : tuple of str
        Axes carrying the tool, from the bed up to the tool.
    spindle : str or None
        Name of the spindle axis (``"C"``, ``"C1"``), never indexed.
    """

    text: str
    workpiece_axes: tuple[str, ...]
    tool_axes: tuple[str, ...]
    spindle: str | None = None

    @property
    def axes(self) -> tuple[str, ...]:
        """Every indexed axis, workpiece branch (bed outward) then tool branch."""
        return self.workpiece_from_bed + self.tool_axes

    @property
    def workpiece_from_bed(self) -> tuple[str, ...]:
        """Workpiece-branch axes from the bed out to the workpiece."""
        return tuple(reversed(self.workpiece_axes))

    @property
    def linear_axes(self) -> tuple[str, ...]:
        """Linear axes of the chain, in X, Y, Z order."""
        return tuple(a for a in LINEAR_AXES if a in self.axes)

    @property
    def rotary_axes(self) -> tuple[str, ...]:
        """Indexed rotary axes of the chain, in A, B, C order."""
        return tuple(a for a in ROTARY_AXES if a in self.axes)

    def side(self, axis: str) -> str:
        """``"workpiece"`` or ``"tool"``: the branch that carries ``axis``."""
        if axis in self.workpiece_axes:
            return "workpiece"
        if axis in self.tool_axes:
            return "tool"
        raise ConfigError(f"axis {axis!r} is not in chain {self.text!r}")

    def sign(self, axis: str) -> int:
        """+1 on the tool branch, -1 on the workpiece branch (a table moving
        by -q moves the tool by +q relative to the part)."""
        return 1 if self.side(axis) == "tool" else -1

    def parent(self, axis: str) -> str | None:
        """The axis ``axis`` rides on, or None when it sits on the bed."""
        branch = self.workpiece_from_bed if self.side(axis) == "workpiece" else self.tool_axes
        i = branch.index(axis)
        return branch[i - 1] if i > 0 else None


def parse_chain(text: str) -> Chain:
    """Parse an ISO 10791 kinematic chain string.

    Parameters
    ----------
    text : str
        E.g. ``"V[w-C-A-b-Y-X-Z-(C)-t]"`` or ``"[w C' A' b X Y Z (C1) t]"``.

    Returns
    -------
    Chain

    Raises
    ------
    ConfigError
        Missing brackets, ``w`` / ``b`` / ``t`` missing or out of order, an
        unknown token, a repeated axis or a second spindle.
    """
    if not isinstance(text, str):
        raise ConfigError(f"chain must be a string, got {type(text).__name__}")
    m = _OUTER.match(text)
    if not m:
        raise ConfigError(f"chain {text!r}: expected '[w-...-b-...-t]' with optional V/H prefix")
    tokens = [tok for tok in re.split(r"[\s\-]+", m.group(2).strip()) if tok]
    if not tokens or tokens[0] != "w":
        raise ConfigError(f"chain {text!r}: must start with 'w' (workpiece)")
    if tokens[-1] != "t":
        raise ConfigError(f"chain {text!r}: must end with 't' (tool)")
    if tokens.count("b") != 1:
        raise ConfigError(f"chain {text!r}: needs exactly one 'b' (bed)")
    if tokens.count("w") != 1 or tokens.count("t") != 1:
        raise ConfigError(f"chain {text!r}: 'w' and 't' must appear once each")
    ib = tokens.index("b")
    work: list[str] = []
    tool: list[str] = []
    spindle = None
    seen: set[str] = set()
    for k, tok in enumerate(tokens[1:-1], start=1):
        if tok == "b":
            continue
        sp = _SPINDLE.match(tok)
        if sp:
            if k < ib:
                raise ConfigError(f"chain {text!r}: spindle {tok!r} on the workpiece side")
            if spindle is not None:
                raise ConfigError(f"chain {text!r}: more than one spindle")
            spindle = sp.group(1).rstrip("'\u2019")
            continue
        ax = _AXIS.match(tok)
        if not ax:
            raise ConfigError(f"chain {text!r}: unknown token {tok!r}; expected X Y Z A B C, w, b, t or (C)")
        name = ax.group(1)
        if name in seen:
            raise ConfigError(f"chain {text!r}: axis {name} appears twice")
        seen.add(name)
        (work if k < ib else tool).append(name)
    return Chain(text=text, workpiece_axes=tuple(work), tool_axes=tuple(tool), spindle=spindle)
