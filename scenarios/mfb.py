"""MFB scenarios: the placement plans for a 3-axis and a 5-axis machine and the runner.

A *placement* is a bar pose on the table; a *measurement* is one probing
of a placement with one stylus (probe offsets J, eq. 8). What each
placement senses follows from the first-order model (Viprey 2016 eqs
10-12) *of this machine's chain* and is checked by
:func:`core.volumetric.observability` (rank, conditioning, and the
combinations lost when a placement is removed, by name).

3-axis (``vmc-3axis``: table on X on Y, spindle on Z, chain
``w-X-Y-b-Z-t``). The table moves under a fixed tool, so an angular error
of X or Y acts through the arm from the carriage to the *tool* point: a
bar shifted on the table changes the arm only along axes that carry the X
carriage (y, z for X; z for Y); the x arm of Y's errors must come from the
stylus (J_X). Placements (14), measurements (17):

- X1, X2, X3: bar along X at (y, z) = (-40, 60), (-40, 260), (110, 60) mm,
  straight stylus T0 (J_Z 150 mm): EXX, EYX, EZX; X2-X1 (dz 200 mm): EBX
  (positioning), EAX (horizontal straightness); X3-X1 (dy 150 mm): ECX
  (positioning), EAX (vertical straightness);
- Y1, Y2: bar along Y at (x, z) = (-25, 60), (-25, 260) mm, T0: EYY, EXY,
  EZY; Y2-Y1 (dz): EAY, EBY;
- Y3: along Y at x = 125 mm with TXF (star arm 100 mm along X with a
  40 mm finger): Y3-Y1 (dJ_X 100 mm) gives ECY by differential positioning
  and EBY by differential vertical straightness (with T0 it gave neither:
  the weakest combination was an ECY ramp, relative sv 1.3e-4 -> 6.5e-4);
- VY: standing bar (along Z) at (-25, -40) mm, holes facing -Y, star
  styli TY1, TY2 (arm 100, 150 mm along Y) and TYL (TY1 on J_Z 250 mm):
  EZZ, EXZ, EYZ; dJ_Y: ECZ, EAZ; dJ_Z: EBZ, EAZ;
- VX: standing bar, holes facing -X, TX1 and TX2: ECZ, EBZ; EXZ, EYZ with
  the other Abbe arm;
- DXY (flat, 45 deg in XY, T0), DXZ (tilted 45 deg in XZ, holes facing
  -Y, TY1), DYZ (tilted 45 deg in YZ, holes facing -X, TX1): the
  squarenesses EC0Y, EB0Z, EA0Z (a bar parallel to an axis absorbs the
  slope into its pose);
- AXY, AXZ, AYZ: the anti-diagonals (x_A along X-Y, X-Z, Y-Z; the tilted
  ones start at z = 345 mm and fall). A linear twist of the table (an EAX
  ramp, an EBY ramp) moves every bar parallel to an axis rigidly, so only
  the diagonals see it, as a bend ``a s^2 / 2`` that the bar's own bow
  (calibrated, to ``u_cal``) imitates; the anti-diagonal bends the other
  way under the same bow. With one diagonal per plane the twist was the
  plan's largest uncertainty (EAX / EBY U95 36 / 44 urad), with the pairs
  14 / 11 urad; the squarenesses gain alike (EB0Z 14 -> 5 urad).

Each bar is probed over the holes that fit the strokes (12 along X, 8
along Y, 7 standing), with the rods and faces the planes PL_i need (rod k
of a bar probed to hole k lies 25 mm beyond it). The error tables have
their nodes at the points of interest, where a bar senses all three
directions: 8 along Y and 7 along Z (one per hole), 9 along X over the
12 holes (a 12-hole bar has 11 rods, its only height sensors: 12 nodes
leave one EZX combination seen by curvature alone). The end nodes are the
end holes; over the rods and faces beyond them (up to 34 mm) the tables
continue along their end tangent (:data:`core.volumetric.NODE_MARGIN_M`).
End nodes spanning every touch (the previous layout) sat where only one
direction is sensed, and the end-point conventions hung every table on
them: U95 reached 47 um (EZX) and 110 urad (EBY) at 0.25 um probing noise.

Identification (:mod:`core.volumetric`): the machine errors enter through
the touches, carried into the points of interest by the extraction's gain;
then Gauss-Newton on the exact chain; reported in the ISO 230-1 form
(straightness against its end-point line, the slope kept beside it).
Noise-free on the default realistic machine: 0.074 um / 0.15 urad (the
tables' interpolation of its 9-knot profiles and the tangent continuation
over the end rods); 0.003 um / 0.03 urad for errors the tables represent
(``on_nodes=True``).

Uncertainty: probing noise (0.125 um standard deviation, the paper's 0.25 um
at k = 2), the bar's calibration (the
true bar differs from its calibration by a draw of ``u_cal_um``) and the
placement errors (:data:`U_PLACE`, roll included, drawn in the simulator),
by linear propagation and Monte Carlo (JCGM 101) through the same
estimator. At 0.25 um probing noise, over four seeded campaigns, U95 at
the nodes: positioning median 0.8 um, max 2.1 um; straightness 1.3 / 4.3 um
(EZX next to its end nodes, bar calibration dominated); angular 5.0 / 15.8
urad (the EAX / EBY twist ramps); squareness 4.9 / 8.7 urad. 97 % of 504
identified values within U95 (RMS error / U95 0.46); a noisy run is off by
1-4 um / 5-11 urad. What is left weakest: ``observability(...).weakest``.

The scenario injects ``sim.machines.realistic_errors`` of the machine's
linear axes minus the 10 mm screw-pitch ripple: a bar of 50 mm pitch
samples every hole at the same ripple phase and the hole fit averages it
over +-5 mm, so no MFB plan can see a ripple shorter than twice its pitch
(``ripple=True`` keeps it).

5-axis (``mfb-5axis``, ``mikron-ucp710``): :func:`plan_5axis`, 4 bar
placements on the table (flat; flat on a 150 mm riser; on edge on an angle
plate; flat for the XZ anti-diagonal), presented by A and C in 13 set-ups,
17 measurements; every touch, approach and link move checked for
collisions and reach in the MuJoCo work zone (:func:`check_plan`,
:mod:`sim.mfb_scene`); the rotary axes' errors are absorbed by each
set-up's pose. Noise-free on the realistic machine (rotary axes' errors
included): 0.041 um / 0.49 urad (EBY). At 0.125 um probing noise (seed 1):
U95 max 1.1 um positioning, 1.6 um straightness; the twists: EAX U95 30
urad on a 4.8 urad peak-to-peak signal (not resolved: on this tool-side
chain a ramp of an angular error of X moves every bar along X rigidly, and
only the diagonals' bend, ~0.1 um, sees it), EBY 7.8 urad on 5.95 (seen by
T0 vs TXF in one pose, dJ_X 100 mm), ECZ 9.1 urad on 3.6 (dJ 50 mm star
arms; not resolved at this noise).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from core.units import MM


@dataclass(frozen=True)
class MeasurementSpec:
    """One measurement of a plan.

    Attributes
    ----------
    name, placement : str
    T_W_A : (4,4) float
        Bar pose in W, m.
    rot_rad : tuple
        Rotary positions (chain order), rad.
    J_m : (3,) float
        Probe offsets, m.
    holes : tuple of int
        Holes probed (1-based); the rods and faces needed come with them.
    senses : str
        What the measurement is for (derivation, in words).
    """

    name: str
    placement: str
    T_W_A: np.ndarray = field(compare=False)
    rot_rad: tuple = ()
    J_m: tuple = (0.0, 0.0, 0.150)
    holes: tuple = tuple(range(1, 13))
    senses: str = ""
    stylus: str = "T0"
    setup: str = ""

    @property
    def setup_key(self) -> str:
        """The set-up (placement and rotary positions): one bar pose in R, one
        set of nuisance values in the identification."""
        return self.setup or self.placement


@dataclass(frozen=True)
class MfbPlan:
    machine: str
    measurements: tuple
    nodes: dict = field(compare=False)
    fixtures: dict = field(default_factory=dict, compare=False)

    @property
    def setups(self) -> tuple:
        return tuple(dict.fromkeys(m.setup_key for m in self.measurements))

    @property
    def placements(self) -> tuple:
        return tuple(dict.fromkeys(m.placement for m in self.measurements))

    def without(self, placement: str) -> "MfbPlan":
        return MfbPlan(self.machine, tuple(m for m in self.measurements if m.placement != placement), self.nodes,
                       {k: v for k, v in self.fixtures.items() if k != placement})


def _T(cols, p):
    T = np.eye(4)
    T[:3, :3] = np.column_stack(cols)
    T[:3, 3] = p
    return T


_X, _Y, _Z = np.eye(3)
_S2 = np.sqrt(0.5)

#: Styli of the 3-axis plan: name -> probe offsets J (eq. 8), m (gauge point
#: minus tip centre). T0: straight 150 mm; TY1/TY2: star
#: arm of 100/150 mm pointing +Y (tip at +Y of the spindle axis, so the spindle
#: stays on the -Y side of a bar whose holes face -Y); TYL: TY1 on a 250 mm
#: extension (J_Z 250 mm); TX1/TX2 likewise along +X; TXF: the TX1 arm with a
#: 40 mm finger down (J_Z 190 mm), so the arm passes 35 mm above a flat bar.
STYLI = {"T0": (0.0, 0.0, 0.150), "TYL": (0.0, -0.100, 0.250),
         "TY1": (0.0, -0.100, 0.150), "TY2": (0.0, -0.150, 0.150),
         "TX1": (-0.100, 0.0, 0.150), "TX2": (-0.150, 0.0, 0.150),
         "TXF": (-0.100, 0.0, 0.190)}
#: Star styli whose ball hangs on a finger below the arm: name -> finger length, m.
FINGERS = {"TXF": 0.040}


def plan_3axis() -> MfbPlan:
    """The 3-axis plan for ``vmc-3axis``: 14 placements, 17 measurements (module doc)."""
    L = 0.050
    ms = []

    def add(name, x_A, z_A, p, holes, styli=("T0",), senses=""):
        x_A, z_A = np.asarray(x_A, float), np.asarray(z_A, float)
        T = _T((x_A, np.cross(z_A, x_A), z_A), p)
        for k, st in enumerate(styli):
            ms.append(MeasurementSpec(name if len(styli) == 1 else f"{name}{'abc'[k]}", name, T, (),
                                      STYLI[st], tuple(holes), senses, st))

    h12, h8, h7 = tuple(range(1, 13)), tuple(range(1, 9)), tuple(range(1, 8))
    add("X1", _X, _Z, (-0.275, -0.040, 0.060), h12, senses="EXX, EYX, EZX (tables along X at y=-40, z=60 mm)")
    add("X2", _X, _Z, (-0.275, -0.040, 0.260), h12,
        senses="with X1 (arm dz = 200 mm): EBX by differential positioning, EAX by differential horizontal straightness")
    add("X3", _X, _Z, (-0.275, 0.110, 0.060), h12,
        senses="with X1 (arm dy = 150 mm): ECX by differential positioning, EAX by differential vertical straightness")
    add("Y1", _Y, _Z, (-0.025, -0.190, 0.060), h8, senses="EYY, EXY, EZY (tables along Y at x=-25, z=60 mm)")
    add("Y2", _Y, _Z, (-0.025, -0.190, 0.260), h8,
        senses="with Y1 (arm dz = 200 mm): EAY by differential positioning, EBY by differential horizontal straightness")
    add("Y3", _Y, _Z, (0.125, -0.190, 0.060), h8, ("TXF",),
        senses="with Y1, Abbe arm dJ_X = 100 mm: ECY by differential positioning, EBY by differential "
               "vertical straightness (the table does not move in X under the tool when Y moves, so a bar "
               "shifted in x gives no arm: the arm must come from the stylus)")
    add("VY", _Z, -_Y, (-0.025, -0.040, 0.060), h7, ("TY1", "TY2", "TYL"),
        senses="standing bar, holes facing -Y, probed with a star stylus arm along +Y: EZZ, EXZ, EYZ; "
               "arm 100 vs 150 mm (dJ_Y = 50 mm): ECZ (x) and EAZ (z); stylus 150 vs 250 mm (dJ_Z): EBZ (x), EAZ (y)")
    add("VX", _Z, -_X, (-0.025, -0.040, 0.060), h7, ("TX1", "TX2"),
        senses="standing bar, holes facing -X, star stylus arm along +X: arm 100 vs 150 mm: ECZ (y), EBZ (z); "
               "EXZ / EYZ again with the other Abbe arm")
    add("DXY", (_X + _Y) * _S2, _Z, (-0.125, -0.140, 0.060), h8, senses="EC0Y (face diagonal in XY)")
    add("DXZ", (_X + _Z) * _S2, -_Y, (-0.125, -0.040, 0.060), h8, ("TY1",),
        senses="EB0Z (face diagonal in XZ, tilted 45 deg, holes facing -Y, star stylus arm along +Y)")
    add("DYZ", (_Y + _Z) * _S2, -_X, (-0.025, -0.140, 0.060), h8, ("TX1",),
        senses="EA0Z (face diagonal in YZ, tilted 45 deg, holes facing -X, star stylus arm along +X)")
    # the anti-diagonals: a linear twist of the table (EAX ~ a x, EBY ~ -a y)
    # moves every bar parallel to an axis rigidly (absorbed by its placement)
    # and bends a diagonal by a s^2 / 2, which the bar's own bow (calibrated,
    # to u_cal) imitates; the anti-diagonal bends the other way under the
    # same bow, so the pair separates twist from bar (and the squarenesses
    # from the bar's length): EAX / EBY ramps 36 / 44 -> 14 / 11 urad U95
    add("AXY", (_X - _Y) * _S2, _Z, (-0.125, 0.107, 0.060), h8,
        senses="with DXY: twist of X and Y (EAX, EBY ramps) and EC0Y, free of the bar's bow")
    add("AXZ", (_X - _Z) * _S2, -_Y, (-0.125, -0.040, 0.345), h8, ("TY1",),
        senses="with DXZ: EAX ramp and EB0Z, free of the bar's bow (z falls along the bar)")
    add("AYZ", (_Y - _Z) * _S2, -_X, (-0.025, -0.140, 0.345), h8, ("TX1",),
        senses="with DYZ: EBY ramp and EA0Z, free of the bar's bow (z falls along the bar)")
    # table nodes at the points of interest, where the bar senses every
    # direction: the end nodes at the first and last holes (X +-275 mm, Y
    # -190 / 160 mm, Z 60 / 360 mm), the tables continued along their end
    # tangent over the rods and faces beyond (core.volumetric.NODE_MARGIN_M).
    # Y and Z: one node per hole (8, 7; each hole k has its rod k). X: a bar
    # of 12 holes has 11 rods, the only height sensors, so 12 nodes leave
    # EZX one combination sensed by nothing but curvature (U95 ~25 um); 9
    # nodes (68.75 mm) keep it at ~4 um and interpolate the realistic
    # profiles to < 0.08 um.
    nodes = {"X": np.linspace(-0.275, 0.275, 9), "Y": np.linspace(-0.190, 0.160, 8),
             "Z": np.linspace(0.060, 0.360, 7)}
    return MfbPlan("vmc-3axis", tuple(ms), nodes)


#: Star styli of the 5-axis plan besides :data:`STYLI` (none needed: the bar's
#: holes face +Z, -Y or -X in every measurement, probed with T0, TY*, TX*).

#: 5-axis nodes (R, m): the points of interest of the bars along each axis
#: (X: holes 1-10 of a bar whose first hole is at x = -175 mm, 9 nodes as
#: the 3-axis plan's; Y: 8 holes from y = -225 to 125 mm; Z: 6 holes of the
#: standing bars, z = -45 to 205 mm, the A line being 120 mm below the
#: table face). Every reading of every measurement lies within the nodes
#: (plus :data:`core.volumetric.NODE_MARGIN_M`) of all three axes.
NODES_5AXIS = {"X": np.linspace(-0.175, 0.275, 9), "Y": np.linspace(-0.225, 0.125, 8),
               "Z": np.linspace(-0.045, 0.205, 6)}


def plan_5axis() -> MfbPlan:
    """The 5-axis plan for ``mikron-ucp710``: 4 bar placements, 13 rotary set-ups, 17 measurements.

    Chain ``[w C' A' b X Y Z (C1) t]``: the table turns (C on A, the A line
    120 mm below the table face), all linear axes carry the tool (eq. 8).
    A *placement* is where the bar is fixed on the table (W frame, with its
    workholder, :class:`sim.mfb_scene.Block`); the rotary axes then present
    it in several orientations (*set-ups*); each set-up is probed with one
    or more styli (*measurements*). The rotary axes' errors are constant
    within a set-up and move the bar rigidly: the estimator gives each
    set-up its own pose (5 nuisance values), so they are absorbed exactly
    and nothing of the rotary axes is assumed known. Every touch, approach
    and link move is checked in the MuJoCo work zone (:func:`check_plan`).

    - **P1**: the bar flat on its two supports on the table, along W x,
      first hole at (x, y) = (-175, 80) mm. X1 (A = C = 0, T0): along X at
      (y, z) = (80, 70) mm; X3 (A = -90, C = 0, TY1): along X at (-190, -40)
      mm, holes facing -Y; Y1 (C = 90; T0 and TXF in one pose): along -Y at
      (x, z) = (80, 70) mm; VY (A = -90, C = -90; TY1, TY2, TYL): standing,
      holes facing -Y; DXY / AXY (C = -45 / +45, T0) and DXZ (A = -90,
      C = -45, TY1): diagonals.
    - **P2**: the bar flat on a 150 mm riser block: X2 (A = C = 0, T0) at
      (y, z) = (0, 220) mm, Y2 (C = 90, T0) at (x, z) = (0, 220) mm.
    - **P3**: the bar on its edge along W y, holes facing -W x, its
      supports bolted to an angle plate, 105 mm above the table: Y3 (A = C =
      0, TX1), VX (A = -90; TX1, TX2), DYZ (A = -45, TX1).
    - **P4**: flat along W x, first hole at (-300, 160) mm: AXZ (A = -90,
      C = 45, TY1), the XZ anti-diagonal (from P1 it falls below the Z
      stroke after 4 holes).

    The YZ anti-diagonal is not in the plan: A turns about X, so a line
    at height h on the table keeps y + z = 1.41 (h + 120 mm) - 120 mm at A
    = +45 deg; the anti-diagonal through the Z and Y reach needs h ~ 0 (a
    bar on edge 30 mm into the table) or holes tilted 45 deg to the stylus.

    What each senses (tool-side chain; module doc): X1, X2, X3 at three
    (y, z) not on one line: EXX, EYX, EZX and, by differential straightness
    and positioning, the *curvature* of EAX and EBX, ECX (a ramp of an
    angular error of X moves a bar along X rigidly); Y1 a / b (dJ_X 100 mm in
    one pose): ECY, EBY with their ramps; Y2 - Y1 (dz 150 mm): EAY, EBY; Y3;
    VY (dJ_Y 50 mm, dJ_Z 100 mm) and VX (dJ_X 50 mm), one pose each: ECZ,
    EAZ, EBZ with their ramps; the diagonals: EC0Y, EB0Z, EA0Z and the
    twist ramps. The paper's 6 placements: this chain needs 4 (run with
    ``drop=`` to see what is lost without each).
    """
    from sim.machine import Machine
    from sim.machines import MACHINES
    from sim.mfb_scene import Block

    m = Machine(MACHINES["mikron-ucp710"]())
    axes = m.rotary_axes
    ms = []
    fixtures = {}

    def place(name, x_W, z_W, origin, blocks=()):
        x_W, z_W = np.asarray(x_W, float), np.asarray(z_W, float)
        fixtures[name] = tuple(blocks)
        return name, _T((x_W, np.cross(z_W, x_W), z_W), origin)

    def add(pl, name, rot_deg, holes, styli=("T0",), senses=""):
        p, T = pl
        r = tuple(float(np.deg2rad(rot_deg[a])) for a in axes)
        if holes == _DIAG:
            T_R_W = np.asarray(m.T_R_W_nominal(np.asarray(r)[None, :]), float).reshape(4, 4)
            holes = _fit_holes(T_R_W @ T, _reach(m.config.strokes), STYLI[styli[0]])
        key = f"{p}@" + ",".join(f"{a}{rot_deg[a]:g}" for a in axes)
        for k, st in enumerate(styli):
            ms.append(MeasurementSpec(name if len(styli) == 1 else f"{name}{'abc'[k]}", p, T, r,
                                      STYLI[st], tuple(holes), senses, st, setup=key))

    h10, h29, h611, h18, h712 = (tuple(range(1, 11)), tuple(range(2, 10)), tuple(range(6, 12)),
                                 tuple(range(1, 9)), tuple(range(7, 13)))
    P1 = place("P1", _X, _Z, (-0.175, 0.080, 0.070))
    P2 = place("P2", _X, _Z, (-0.175, 0.000, 0.220),
               (Block("riser", (-0.095, -0.045, 0.0), (0.295, 0.045, 0.150)),))
    P3 = place("P3", _Y, -_X, (-0.060, -0.225, 0.105),
               (Block("angle_plate", (0.010, -0.135, 0.0), (0.030, 0.235, 0.140)),))
    P4 = place("P4", _X, _Z, (-0.300, 0.160, 0.070))
    add(P1, "X1", {"A": 0, "C": 0}, h10, senses="EXX, EYX, EZX at (y, z) = (80, 70) mm")
    add(P2, "X2", {"A": 0, "C": 0}, h10, senses="with X1 (dy -80, dz 150 mm): EAX, EBX, ECX")
    add(P1, "X3", {"A": -90, "C": 0}, h10, ("TY1",), senses="with X1, X2 (y, z) = (-190, -40) mm: EAX, EBX, ECX")
    add(P1, "Y1", {"A": 0, "C": 90}, h29, ("T0", "TXF"),
        senses="EYY, EXY, EZY at (x, z) = (80, 70) mm; T0 vs TXF in one pose (dJ_X 100 mm): ECY, EBY "
               "with their ramps (a ramp is a bar's yaw or pitch to any bar set up alone)")
    add(P2, "Y2", {"A": 0, "C": 90}, h29, senses="with Y1 (dz 150 mm): EAY, EBY")
    add(P3, "Y3", {"A": 0, "C": 0}, h18, ("TX1",), senses="with Y1 (dJ_X 100 mm): ECY, EBY")
    add(P1, "VY", {"A": -90, "C": -90}, h611, ("TY1", "TY2", "TYL"),
        senses="EZZ, EXZ, EYZ; dJ_Y: ECZ, EAZ; dJ_Z: EBZ, EAZ")
    add(P3, "VX", {"A": -90, "C": 0}, h712, ("TX1", "TX2"), senses="dJ_X: ECZ, EBZ")
    add(P1, "DXY", {"A": 0, "C": -45}, _DIAG, senses="EC0Y, twist")
    add(P1, "AXY", {"A": 0, "C": 45}, _DIAG, senses="EC0Y, twist")
    add(P1, "DXZ", {"A": -90, "C": -45}, _DIAG, ("TY1",), senses="EB0Z, twist")
    add(P4, "AXZ", {"A": -90, "C": 45}, _DIAG, ("TY1",), senses="EB0Z, twist (the XZ anti-diagonal: out of "
        "reach from P1, whose bar falls below the Z stroke)")
    add(P3, "DYZ", {"A": -45, "C": 0}, _DIAG, ("TX1",), senses="EA0Z, twist")
    return MfbPlan("mikron-ucp710", tuple(ms), dict(NODES_5AXIS), fixtures)


#: Holes of the diagonal measurements: chosen per set-up (:func:`_fit_holes`).
_DIAG = ()


def _reach(strokes) -> dict:
    """Where a 5-axis reading may lie: the strokes, and the node box of each axis
    widened by 30 mm (within :data:`core.volumetric.NODE_MARGIN_M`)."""
    return {a: (max(strokes[a][0], NODES_5AXIS[a][0] - 0.030), min(strokes[a][1], NODES_5AXIS[a][-1] + 0.030))
            for a in "XYZ"}


def _fit_holes(T_R_A, reach, J_m, prefer=((1, 8), (2, 9), (6, 11), (7, 12), (1, 10)),
               margin_m: float = 5.0e-3) -> tuple:
    """Holes of a diagonal measurement: the longest of the plan's other hole
    runs (``prefer``, first, last; their extraction gains are computed once)
    whose touches and approach starts lie ``margin_m`` inside ``reach``; else
    the longest run of consecutive reachable holes (at least 4)."""
    from sim import artefacts as A
    from core.exceptions import PlanError

    art = A.multi_feature_bar(deviations_m=np.zeros((12, 3)))
    ok = []
    for h in range(1, 13):
        pl = _plan_for(art, (h,))
        c = A.apply_T(T_R_A, pl.w_A + 3.0e-3 * pl.wn_A)
        c = np.vstack([c, c + pl.clearance_m * A.apply_R(T_R_A, pl.wn_A)])
        ok.append(all(np.all((c[:, j] >= reach[a][0] + margin_m) & (c[:, j] <= reach[a][1] - margin_m))
                      for j, a in enumerate("XYZ")))
    fits = [(hi - lo, lo, hi) for lo, hi in prefer if all(ok[lo - 1:hi])]
    if fits:
        _, lo, hi = max(fits)
        return tuple(range(lo, hi + 1))
    best, k = (0, 0), 0
    while k < 12:
        j = k
        while j < 12 and ok[j]:
            j += 1
        if j - k > best[1] - best[0]:
            best = (k, j)
        k = j + 1
    if best[1] - best[0] < 4:
        raise PlanError(f"fewer than 4 consecutive holes of the bar within reach (J = {J_m})")
    return tuple(range(best[0] + 1, best[1] + 1))


PLANS = {"mfb-3axis": plan_3axis, "mfb-5axis": plan_5axis}


#: Default placement uncertainty of a bar set by hand on the table (standard):
#: 0.2 mm along x_A, y_A, 0.1 mm along z_A; 0.5 mrad roll and pitch, 1 mrad yaw.
U_PLACE = (0.2e-3, 0.2e-3, 0.1e-3, 0.5e-3, 0.5e-3, 1.0e-3)


def _strip_ripple(f):
    from sim.errorfuncs import Periodic, Sum

    if isinstance(f, Sum):
        terms = tuple(t for t in f.terms if not isinstance(t, Periodic))
        if not terms:  # a rotary axis' periodic motion, not a screw ripple
            return f
        return terms[0] if len(terms) == 1 else Sum(terms)
    return f


def default_machine(name: str, ripple: bool = False, J_m=(0.0, 0.0, 0.150)):
    """The realistic truth machine of a scenario (sim), ripple removed unless asked."""
    from sim.machine import Machine
    from sim.machines import MACHINES, realistic_errors

    cfg = MACHINES[name]()
    axes = tuple(a for a in ("X", "Y", "Z", "A", "C") if a in cfg.strokes)
    errs = realistic_errors(axes, strokes=cfg.strokes)
    if not ripple:
        errs = {k: _strip_ripple(v) for k, v in errs.items()}
    return MACHINES[name](errors=errs, J_m=J_m), errs


class _NoSafeHeight:
    """Adapter: the campaign's link moves go via a safe height above the
    bar's top, which for a standing bar is above the Z stroke; a real
    program would retract sideways. The touches themselves are checked
    against the strokes by :func:`_check_touch_strokes` instead."""

    def __init__(self, machine):
        self._m = machine
        self.config = type("Cfg", (), {"name": machine.config.name, "strokes": {},
                                       "kinematic_chain": machine.config.chain})()

    def __getattr__(self, k):
        return getattr(self._m, k)


#: Collision checks already made (a pure function of the nominal plan).
_CHECKS: dict = {}


def check_plan(plan: MfbPlan, stylus_r_m: float = 3.0e-3) -> dict:
    """Collision and reach check of every measurement of a plan with a workholder (MuJoCo).

    Each measurement's touches, approach/retract and link moves are checked
    in :class:`sim.mfb_scene.WorkZone` (table, workholder, bar and its
    supports; stylus ball, star arm, extension, probe body, spindle) at the
    set-up's rotary positions, and the touches against the strokes of the
    readings. Returns the summary for the report (``passed``, per
    measurement: set-up, stylus, holes, touches, path points, collisions,
    least clearance from the table side).

    Raises
    ------
    PlanError
        A collision, the bar below the table face, or a touch outside a stroke
        (measurement and what hits what named).
    """
    from core.exceptions import PlanError
    from sim import artefacts as A
    from sim.machine import Machine
    from sim.machines import MACHINES
    from sim.mfb_scene import TABLE_R_M, TABLE_T_M, check_measurement

    key = (plan.machine, tuple((m.name, m.setup_key, m.holes, m.J_m) for m in plan.measurements), stylus_r_m)
    if key in _CHECKS:
        return _CHECKS[key]
    t0 = time.time()
    mach = Machine(MACHINES[plan.machine]())
    art = A.multi_feature_bar(deviations_m=np.zeros((12, 3)))
    per, n_t, n_s = {}, 0, 0
    for ms in plan.measurements:
        rot = np.asarray(ms.rot_rad, float)[None, :] if len(ms.rot_rad) else None
        T_R_W = np.asarray(mach.T_R_W_nominal(rot), float).reshape(4, 4)
        pl = _plan_for(art, ms.holes)
        r = check_measurement(ms.name, art, ms.T_W_A, T_R_W, plan.fixtures.get(ms.placement, ()), ms.J_m,
                              stylus_r_m, pl, FINGERS.get(ms.stylus, 0.0))
        if not r.ok:
            raise PlanError(f"measurement {ms.name!r} ({ms.setup_key}, {ms.stylus}): {r.collisions[0]}")
        c = A.apply_T(T_R_W @ ms.T_W_A, pl.w_A + stylus_r_m * pl.wn_A)
        for j, ax in enumerate("XYZ"):
            lo, hi = mach.config.strokes[ax]
            if c[:, j].min() < lo - 1e-9 or c[:, j].max() > hi + 1e-9:
                raise PlanError(f"measurement {ms.name!r}: a touch at {ax} outside the stroke [{lo / MM:g}, "
                                f"{hi / MM:g}] mm")
        per[ms.name] = {"placement": ms.placement, "setup": ms.setup_key, "stylus": ms.stylus,
                        "J_mm": [round(v / MM, 3) for v in ms.J_m], "holes": list(ms.holes),
                        "touches": r.touches, "path_points": r.samples, "collisions": len(r.collisions),
                        "min_clearance_from_table_side_mm": round(r.min_table_clearance_mm, 2),
                        "touch_range_mm": {ax: [round(float(c[:, j].min()) / MM, 1), round(float(c[:, j].max()) / MM, 1)]
                                           for j, ax in enumerate("XYZ")}}
        n_t += r.touches
        n_s += r.samples
    out = {"passed": True, "engine": "MuJoCo (sim.mfb_scene.WorkZone)",
           "checked": "table disc (R %g mm, %g mm thick), workholder blocks, bar and its supports vs stylus ball, "
                      "star arm, extension, probe body, spindle nose; approach/retract and link moves; the bar "
                      "above the table face; touches within the strokes" % (TABLE_R_M / MM, TABLE_T_M / MM),
           "touches": n_t, "path_points": n_s, "seconds": round(time.time() - t0, 1), "measurements": per,
           "fixtures": {p: [{"name": b.name, "lo_mm": [v / MM for v in b.lo], "hi_mm": [v / MM for v in b.hi]}
                            for b in bl] for p, bl in plan.fixtures.items()}}
    _CHECKS[key] = out
    return out


def describe_collision_check(c: dict) -> str:
    """The collision check's summary for the terminal: one line per placement, then the verdict."""
    by = {}
    for name, m in c["measurements"].items():
        by.setdefault(m["placement"], []).append(f"{name}({m['setup'].split('@')[1]}, {m['stylus']})")
    lines = [f"  {p}: {', '.join(v)}" for p, v in by.items()]
    lines.append(f"collision check ({c['engine']}): {'passed' if c['passed'] else 'FAILED'}, "
                 f"{c['touches']} touches, {c['path_points']} path points, {c['seconds']} s")
    return "\n".join(lines)


#: The extraction's gains already computed (pure functions of the nominal plan).
_GAINS: dict = {}


def _noise_gain(pl_ok, r_m):
    """:func:`core.mfb.poi_noise_gain` of the touches ``pl_ok`` (a plan's nominal
    geometry and stylus radius only), kept for the next run of the same plan:
    it is two thirds of a run's time and the same for every campaign."""
    from core import mfb

    key = (tuple(pl_ok.target), tuple(pl_ok.feature), pl_ok.w_A.tobytes(), pl_ok.wn_A.tobytes(), float(r_m))
    if key not in _GAINS:
        if len(_GAINS) >= 64:
            _GAINS.pop(next(iter(_GAINS)))
        G = mfb.poi_noise_gain(pl_ok.w_A + r_m * pl_ok.wn_A, pl_ok.feature, pl_ok.wn_A, -pl_ok.wn_A)
        G.setflags(write=False)  # shared between runs: read only
        _GAINS[key] = G
    return _GAINS[key]


def _check_touch_strokes(log, machine, name):
    from core.exceptions import PlanError

    p = np.column_stack([log.col("Xn_mm"), log.col("Yn_mm"), log.col("Zn_mm")]) * MM
    for j, ax in enumerate("XYZ"):
        lo, hi = machine.config.strokes[ax]
        bad = (p[:, j] < lo - 1e-9) | (p[:, j] > hi + 1e-9)
        if bad.any():
            raise PlanError(f"measurement {name!r}: a touch at {ax} = {p[bad][0, j] / MM:.1f} mm is outside the stroke")


def _plan_for(art, holes, overshoot_m=3.0 * MM):
    from sim.plans import mfb_plan

    full = mfb_plan(art, overshoot_m=overshoot_m)
    hs = set(holes)
    # the rods each probed hole's plane PL_i needs: (i-1, i), (1, 2) for hole 1
    lo, hi = min(holes), max(holes)
    rods = set(range(max(lo - 1, 1), min(hi, 11) + 1))
    if len(rods) < 2:
        rods = {lo, lo + 1}
    keep = []
    for k, f in enumerate(full.feature):
        if f.startswith("hole") and int(f[4:]) in hs:
            keep.append(k)
        elif f.startswith("rod") and int(f[3:]) in rods:
            keep.append(k)
        elif f.startswith("face") and int(f[5:]) in rods:
            keep.append(k)
    return full.select(np.array(keep))


@dataclass(frozen=True)
class ScenarioResult:
    plan: MfbPlan
    result: object
    unc: object
    truth: np.ndarray
    n_touches: int
    seconds: float
    doc: dict
    slopes: dict = field(default=None, compare=False)
    meas: list = field(default=None, compare=False)  # the core.volumetric.Measurement list identified

    def write_comp(self, directory) -> list:
        """Write the LinuxCNC per-axis compensation files and the vmt JSON tables.

        ``<dir>/<X|Y|Z>.comp`` (``[JOINT_n] COMP_FILE``, ``COMP_FILE_TYPE =
        0``: nominal, actual forward, actual reverse in mm, every 5 mm along
        the table by its C2 spline, :func:`hardware.linuxcnc.comp_file`),
        indexed by the joint position of the reference stylus
        (:data:`COMP_STYLUS`: reading + its offsets J), and
        ``<dir>/<scenario>-comp.json`` (``vmt-comp/1``,
        :func:`core.volumetric.tables_json`). Returns the paths written.
        """
        from pathlib import Path

        from core import volumetric as vol
        from core.atomic import write_text_atomic
        from hardware.linuxcnc import comp_file

        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        out = []
        J = STYLI[COMP_STYLUS]
        for i, a in enumerate(("X", "Y", "Z")):
            out.append(write_text_atomic(d / f"{a}.comp", comp_file(self.result, a, step_m=0.005,
                                                                    joint_offset_m=J[i])))
        out.append(write_text_atomic(d / f"{self.doc['scenario']}-comp.json",
                                     vol.tables_json(self.result, self.unc, self.slopes)))
        return [Path(p) for p in out]


#: The stylus whose joint positions index the LinuxCNC files (T0: a 150 mm probe).
COMP_STYLUS = "T0"


def _check_machine_for_plan(cfg, plan, name):
    from core.chain import parse_chain
    from core.exceptions import ConfigError
    from sim.machines import MACHINES

    want = parse_chain(MACHINES[plan.machine]().chain)
    got = parse_chain(cfg.chain)
    if (got.workpiece_axes, got.tool_axes) != (want.workpiece_axes, want.tool_axes):
        raise ConfigError(f"--machine {cfg.name!r}: chain {cfg.chain!r} is not the {name} plan's "
                          f"{want.text!r} (the plan is designed for that structure)")


def run(name: str = "mfb-3axis", *, seed: int = 1, noise_um: float | None = None, mc_runs: int = 500,
        exact: bool = True, ripple: bool = False, drop: str | None = None, on_nodes: bool = False,
        u_cal_um: tuple = (0.2, 0.35, 0.35), bar_cal_error: bool = True,
        u_place: tuple = U_PLACE, machine=None, compensate=None, bar_seed: int | None = None,
        u_stylus_um: float = 0.0, bar_temperature_C: float = 20.0, hook=None, progress=None) -> ScenarioResult:
    """Simulate the default realistic machine, run the plan, identify, compare.

    Parameters
    ----------
    noise_um : float, optional
        Probing noise, a standard deviation (k = 1) along the approach, um;
        default the probe's (the paper's 0.25 um at k = 2: 0.125); 0 for a
        noise-free run.
    machine : sim.machinefile.MachineSpec, optional
        The truth machine (a machine file) instead of the plan's built-in
        machine with its realistic errors; its chain must be the plan's
        machine's, its probe is used (noise overridden by ``noise_um``).
    compensate : callable, optional
        ``compensate(machine) -> machine``: the controller's compensation
        (:mod:`sim.compensation`) in front of the truth machine of every
        measurement (one per stylus); the truth stays the same.
    bar_seed : int, optional
        Seed of the bar's true deviations from its calibration (default: drawn
        first from ``seed``'s stream; give the first run's seed to probe the
        same bar again with new noise).
    u_cal_um : (3,) float
        Standard uncertainty of the bar calibration (Exx, Eyx, Ezx), um
        (about half the paper's 0.4 / 0.7 um expanded).
    bar_cal_error : bool
        With noise: the true bar differs from its calibration by a draw of
        ``u_cal_um`` (what the uncertainty must cover).
    u_place : (6,) float
        With noise: standard deviation of each placement's error (translation
        along x_A, y_A, z_A in m; rotation about x_A (roll), y_A, z_A in
        rad), drawn once per placement and applied to the true bar pose of
        all its measurements; propagated alike (:func:`core.volumetric.uncertainty`).
    u_stylus_um : float
        Standard uncertainty of each probe-offset component of each stylus
        (its calibration), um: the simulated styli's true offsets differ from
        the ones the identification uses by a draw (one per stylus and run).
    bar_temperature_C : float
        The bar's true temperature (Invar, :data:`sim.artefacts.INVAR_CTE_PER_C`);
        the identification uses its 20 degC calibration.
    drop : str, optional
        A placement to remove (to see the observability report refuse).
    on_nodes : bool
        Inject instead the C2 splines through the realistic errors' values at
        the plan's nodes (errors the tables represent exactly: what is left
        is the model's own truncation, not the interpolation's).
    hook : callable(i, spec, artefact, probe, machine) -> (artefact, probe, machine), optional
        Replaces what measurement ``i`` is simulated with (effects hidden
        for model discovery, scenarios/hidden.py).
    progress : callable, optional
        ``progress(done, total)``: one step per simulated measurement, then
        the identification and the uncertainty.
    """
    from core import iso, mfb, volumetric as vol
    from core.exceptions import ConfigError
    from dataclasses import replace

    from core.touches import from_log
    from sim import artefacts as A
    from sim.campaign import simulate_campaign
    from sim.setups import Setup
    from sim.machine import Machine
    from sim.probe import ProbeConfig

    if name not in PLANS:
        raise ConfigError(f"unknown MFB scenario {name!r}; known: {', '.join(PLANS)}")
    t0 = time.time()
    plan = PLANS[name]()
    if drop:
        if drop not in plan.placements:
            raise ConfigError(f"drop: no placement {drop!r} in {name} ({', '.join(plan.placements)})")
        plan = plan.without(drop)
    rng = np.random.default_rng(seed)
    if machine is not None:
        _check_machine_for_plan(machine.config, plan, name)
        probe = machine.probe
        cfg, errs = machine.config, dict(machine.config.errors)
    else:
        probe = ProbeConfig()
        cfg, errs = default_machine(plan.machine, ripple)
    if noise_um is not None:
        if not (np.isfinite(noise_um) and noise_um >= 0):
            raise ConfigError(f"noise_um must be >= 0 (a standard deviation, um), got {noise_um!r}")
        probe = replace(probe, repeatability_k2_m=2.0 * float(noise_um) * 1e-6)
    sigma_um = probe.sigma_m * 1e6
    noisy = sigma_um > 0
    E_cal = A.mfb_default_deviations()
    u_cal = np.tile(np.asarray(u_cal_um, float) * 1e-6, (12, 1))
    bar_rng = rng if bar_seed is None else np.random.default_rng(bar_seed)
    E_true = E_cal + (bar_rng.standard_normal(E_cal.shape) * u_cal if (noisy and bar_cal_error) else 0.0)
    art = A.multi_feature_bar(deviations_m=E_true, temperature_C=bar_temperature_C)
    if not (np.isfinite(u_stylus_um) and u_stylus_um >= 0):
        raise ConfigError(f"u_stylus_um must be >= 0 (a standard uncertainty, um), got {u_stylus_um!r}")
    dJ = {st: (rng.standard_normal(3) * u_stylus_um * 1e-6 if u_stylus_um > 0 else np.zeros(3))
          for st in dict.fromkeys(ms.stylus for ms in plan.measurements)}
    art_nom = A.multi_feature_bar(deviations_m=np.zeros((12, 3)))
    O_A_cal = art.info["poi_nominal_m"] + np.column_stack([E_cal[:, :2], A.multi_feature_bar(deviations_m=E_cal).info["E_MFB_m"][:, 2]])
    if on_nodes:
        from sim.errorfuncs import SplineTable

        errs = {k: (SplineTable(tuple(plan.nodes[iso.symbol(k).axis]), tuple(np.asarray(
            f(plan.nodes[iso.symbol(k).axis]), float))) if k in vol.MOTION else f) for k, f in errs.items()}
        cfg = replace(cfg, errors=errs)

    collision = check_plan(plan) if plan.fixtures else None  # after the inputs are checked
    machines = {}
    meas, G_cache, n_touch = [], {}, 0
    T_true = {}
    for p in plan.placements:  # bar placement errors (by hand on the table), roll included
        T = next(m.T_W_A for m in plan.measurements if m.placement == p)
        if noisy:
            xi = rng.standard_normal(6) * np.asarray(u_place, float)
            dT = np.eye(4)
            dT[:3, :3] = A.rot_z(xi[5]) @ A.rot_y(xi[4]) @ A.rot_x(xi[3])
            dT[:3, 3] = xi[:3]
            T_true[p] = T @ dT
        else:
            T_true[p] = None
    steps = len(plan.measurements) + 2
    for k, ms in enumerate(plan.measurements):
        if progress is not None:
            progress(k, steps)
        J = tuple(ms.J_m)
        if ms.stylus not in machines:  # the true offsets: the calibrated ones + the calibration's error
            machines[ms.stylus] = Machine(replace(cfg, J_m=tuple(np.asarray(J) + dJ[ms.stylus])))
            if compensate is not None:
                machines[ms.stylus] = compensate(machines[ms.stylus])
        m = machines[ms.stylus]
        art_i, probe_i = art, probe
        if hook is not None:
            art_i, probe_i, m = hook(len(meas), ms, art, probe, m)
        pl = _plan_for(art_i, ms.holes)
        log = simulate_campaign(art_i, _NoSafeHeight(m), probe_i, [Setup(ms.name, ms.T_W_A, tuple(ms.rot_rad), T_true[ms.placement])],
                                rng if noisy else None, plan=pl, check_collisions=False)
        _check_touch_strokes(log, m, ms.name)
        t = from_log(log)
        n_touch += t.n
        poi = mfb.points_of_interest(t.p_R, t.feature, t.n_R)
        # the touches that were fitted (valid ones, plan order) and the gain of the
        # extraction at their nominal places (A frame, stylus centres)
        pl_ok = pl.select(np.asarray(log.ok, bool))
        key = (tuple(pl_ok.target), probe.stylus_r_m)
        if key not in G_cache:
            G_cache[key] = _noise_gain(pl_ok, probe.stylus_r_m)
        idx = [h - 1 for h in poi.holes]
        meas.append(vol.Measurement(ms.name, ms.setup_key, poi.holes, poi.O_R, O_A_cal[idx], ms.T_W_A,
                                    tuple(ms.rot_rad), J, G_cache[key], q_R=t.p_R,
                                    c_A=pl_ok.w_A + probe.stylus_r_m * pl_ok.wn_A, d_A=-pl_ok.wn_A))
    chain = cfg.chain
    rp = dict(cfg.rotary_points_R_m)
    if progress is not None:
        progress(steps - 2, steps)
    res_g = vol.identify_volumetric(meas, chain, plan.nodes, rp, exact=exact)
    # reported in the ISO 230-1 form: straightness against the end-point
    # reference line (identified and injected alike)
    L_iso = vol.iso_map(res_g.design)
    res = vol.iso_view(res_g)
    if progress is not None:
        progress(steps - 1, steps)
    unc = (vol.uncertainty(res, meas, probe.sigma_m, u_cal, runs=mc_runs, rng=rng,
                           u_place=np.asarray(u_place, float) if noisy else None)
           if mc_runs or noisy else None)
    # truth in the same gauge
    d = res.design
    truth = np.zeros(len(res.theta))
    mach = next(iter(machines.values()))
    for s in vol.MOTION:
        a = iso.symbol(s).axis
        x = d.nodes[a]
        lin = np.zeros((len(x), 3))
        lin[:, iso.LINEAR_AXES.index(a)] = x
        f = errs.get(s)
        if f is not None:
            truth[d.slices[s]] = np.asarray(f(x), float)
    for s in vol.SQUARENESS:
        f = errs.get(s)
        if f is not None:
            truth[d.slices[s]] = float(np.asarray(f(np.zeros(1)))[0])
    truth_raw = d.to_gauge(truth)
    truth_g = L_iso @ truth_raw
    slopes = (vol.end_point_slopes(d, res_g.theta), vol.end_point_slopes(d, truth_raw))
    doc = _document(name, plan, res, unc, truth_g, n_touch, seed, sigma_um, slopes)
    doc["estimate"] = vol.estimate(res_g, vol.covariance(res_g, meas, probe.sigma_m, u_cal,  # vmt-estimate/1
                                                         np.asarray(u_place, float) if noisy else None))
    doc["machine"] = cfg.name
    if collision is not None:
        doc["collision_check"] = collision
    if progress is not None:
        progress(steps, steps)
    return ScenarioResult(plan, res, unc, truth_g, n_touch, time.time() - t0, doc, slopes[0], meas)


#: How each twist (an axis' rotation about itself) is sensed by the 5-axis plan
#: (tool-side chain), and what limits it.
TWIST_SENSING = {
    "EAX": "not sensed by the X bars: the arm of X's angular errors is the tip's Y, Z reading, so a ramp of "
           "EAX moves every bar along X rigidly (absorbed by its pose) and its constant is the ISO gauge; only "
           "the bend of the XY / XZ diagonals (a s^2 / 2, ~0.1 um over the bar) sees it, against the bar's "
           "calibrated bow (u 0.35 um) and the probing noise",
    "EBY": "T0 vs TXF on Y1 in one pose (dJ_X 100 mm): differential vertical straightness; Y2 - Y1 (dz 150 mm) "
           "only its curvature (separate poses); limited by the probing noise over the 100 mm arm",
    "ECZ": "TY1 vs TY2 on VY and TX1 vs TX2 on VX, one pose each (dJ 50 mm): differential positioning; "
           "limited by the probing noise over the 50 mm arm difference (a longer star arm puts the spindle "
           "beyond the Y travel)",
}


def _twists(errors: dict) -> dict:
    """Each twist's signal (injected peak-to-peak), error, U95 and whether it is resolved
    (U95 max at most half the signal), with the reason it is or is not (:data:`TWIST_SENSING`)."""
    out = {}
    for s, why in TWIST_SENSING.items():
        e = errors.get(s, {})
        if "u95" not in e or "injected" not in e:
            continue
        inj = np.asarray(e["injected"], float)
        u = float(np.max(e["u95"]))
        pp = float(np.ptp(inj))
        out[s] = {"signal_pp_urad": pp, "u95_max_urad": u, "error_max_urad": float(e["max_dev"]),
                  "resolved": bool(u <= 0.5 * pp), "sensing": why}
    return out


def describe_twists(tw: dict) -> str:
    """One line per twist for the terminal: signal, error, U95, resolved or not and why."""
    return "\n".join(f"{s}: signal {v['signal_pp_urad']:.1f} urad p-p, error {v['error_max_urad']:.1f}, U95 "
                     f"{v['u95_max_urad']:.1f} urad: {'resolved' if v['resolved'] else 'NOT resolved'} "
                     f"({v['sensing'].split(';')[0].split(':')[0]})" for s, v in tw.items())


def _document(name, plan, res, unc, truth, n_touch, seed, sigma_um, slopes=None) -> dict:
    from core import iso, volumetric as vol

    errors = vol.report(res, unc, truth)  # one entry per ISO symbol, um / urad
    dev_um, dev_urad = 0.0, 0.0
    for s, e in errors.items():
        sy = iso.symbol(s)
        if sy.kind == iso.Kind.STRAIGHTNESS:
            e["reference"] = "end-point straight line"
            if slopes is not None:
                e["end_point_slope_urad"] = {"identified": slopes[0][s] * 1e6, "injected": slopes[1][s] * 1e6}
        dmax = float(np.max(np.abs(np.asarray(e["identified"]) - np.asarray(e["injected"]))))
        e["max_dev"] = dmax
        if sy.angular:
            dev_urad = max(dev_urad, dmax)
        else:
            dev_um = max(dev_um, dmax)
    return {"scenario": name, "machine": plan.machine, "seed": seed, "noise_um": sigma_um,
            "noise_note": "probing noise: a standard deviation (k = 1) along the approach",
            "placements": len(plan.placements), "setups": len(plan.setups),
            "measurements": len(plan.measurements),
            "touches": int(n_touch), "model": "first order (eqs 8-12) + exact Gauss-Newton"
            if res.iterations else "first order (eqs 8-12)", "gauss_newton_iterations": res.iterations,
            "conventions": list(res.design.gauge), "rms_residual_um": res.rms_m * 1e6,
            "errors": errors, "max_dev_um": dev_um, "max_dev_urad": dev_urad,
            "twists": _twists(errors) if plan.fixtures else {},
            "injected_note": "truth at the nodes, expressed in the same ISO 230-1 conventions (gauge)"}


# --------------------------------------------------------------------------- closed loop
def _rigid_residual(D, P):
    """Tip deviations D (n, 3) at points P (n, 3), m, minus the least-squares rigid
    motion ``t + w x p`` (what no artefact on the table can tell from a moved part)."""
    n = len(P)
    A = np.zeros((3 * n, 6))
    for i in range(3):
        A[i::3, i] = 1.0
    c = P - P.mean(axis=0)
    A[0::3, 4], A[0::3, 5] = c[:, 2], -c[:, 1]  # (w x p)_x = wy z - wz y
    A[1::3, 3], A[1::3, 5] = -c[:, 2], c[:, 0]  # (w x p)_y = wz x - wx z
    A[2::3, 3], A[2::3, 4] = c[:, 1], -c[:, 0]  # (w x p)_z = wx y - wy x
    sol = np.linalg.lstsq(A, D.ravel(), rcond=None)[0]
    return D - (A @ sol).reshape(n, 3)


def volumetric_residual_um(machine, nodes) -> dict:
    """The machine's tip deviation (tool relative to the part, exact sim) over the
    plan's node box, rotary axes at zero, a rigid motion removed: max |.| per axis, um."""
    gx, gy, gz = (np.asarray(nodes[a], float) for a in "XYZ")
    P = np.stack(np.meshgrid(gx, gy, gz, indexing="ij"), axis=-1).reshape(-1, 3)
    rot = None if not machine.rotary_axes else np.zeros((len(P), len(machine.rotary_axes)))
    D = np.asarray(machine.tip_W(P, rot), float) - np.asarray(machine.tip_W_nominal(P, rot), float)
    R = _rigid_residual(D, P)
    return {a: float(np.abs(R[:, i]).max() * 1e6) for i, a in enumerate("XYZ")} | {
        "rms": float(np.sqrt(np.mean(R ** 2)) * 1e6), "points": int(len(P))}


def compensators(directory, name: str):
    """The two controllers a compensation directory feeds (``--apply-comp DIR``).

    Returns ``{"per_axis_files": f, "volumetric": g}``, each ``f(machine) ->
    machine``: LinuxCNC with ``<dir>/X.comp``, ``Y.comp``, ``Z.comp``
    (:class:`sim.compensation.AxisCompensation`, joint positions of
    :data:`COMP_STYLUS`) and a volumetric controller with
    ``<dir>/<name>-comp.json`` (:class:`sim.compensation.VolumetricCompensation`).
    A missing file leaves its controller out.

    Raises
    ------
    ConfigError
        None of the files, or a bad one (named).
    """
    import json
    from pathlib import Path

    from core.exceptions import ConfigError
    from core.units import MM
    from core.volumetric import comp_tables
    from hardware.linuxcnc import read_comp_file
    from sim.compensation import AxisCompensation, ErrorModel, JointTable, VolumetricCompensation

    d = Path(directory)
    out = {}
    files = {a: d / f"{a}.comp" for a in "XYZ" if (d / f"{a}.comp").is_file()}
    if files:
        joints = {a: JointTable.from_type0(read_comp_file(p) * MM) for a, p in files.items()}
        off = STYLI[COMP_STYLUS]
        out["per_axis_files"] = lambda m: AxisCompensation(m, joints, joint_offset_m=off)
    pj = d / f"{name}-comp.json"
    if pj.is_file():
        try:
            doc = json.loads(pj.read_text(encoding="utf-8"))
        except json.JSONDecodeError as e:
            raise ConfigError(f"{pj}: not JSON ({e.msg}, line {e.lineno})") from None
        chain, tables, const, pts = comp_tables(doc)
        model = ErrorModel(chain, tables, const, pts)
        out["volumetric"] = lambda m: VolumetricCompensation(m, model)
    if not out:
        raise ConfigError(f"--apply-comp {d}: no X.comp, Y.comp, Z.comp or {name}-comp.json there")
    return out


def true_positioning_m(machine, nodes) -> dict:
    """The machine's exact positioning error along each axis (sim), in the ISO gauge.

    Axis a's reading moved over its nodes, the others at 0, a probe without
    offsets (the tip is the carriage's reference point): the tip deviation's a
    component, minus its value at the first node (positioning zero at the
    first node, as identified). ``machine`` with ``J_m = 0``.
    """
    out = {}
    for i, a in enumerate("XYZ"):
        x = np.asarray(nodes[a], float)
        lin = np.zeros((len(x), 3))
        lin[:, i] = x
        rot = None if not machine.rotary_axes else np.zeros((len(x), len(machine.rotary_axes)))
        d = np.asarray(machine.tip_W(lin, rot), float)[:, i] - x
        out[a] = d - d[0]
    return out


def closed_loop(name: str, directory, before: ScenarioResult | None = None, **kw) -> dict:
    """Apply the compensation in ``directory`` to the virtual machine, run the plan again, identify again.

    ``before`` is the uncompensated run (default: :func:`run` with ``kw``).
    Each controller of :func:`compensators` is put in front of the same
    truth machine, and a new campaign is run: the same bar (its true
    deviations drawn with the first run's seed), new probing noise and bar
    placements (seed + 1), identified again. Per axis X, Y, Z: the
    positioning error (``EXX``, ``EYY``, ``EZZ``) identified before and after
    with the U95 of each identification, and the machine's exact
    positioning error (:func:`true_positioning_m`) before and after; the
    criterion: after compensation the true positioning error lies within
    the U95 of the identification the compensation came from, at every node
    (``true_within_u95``). Beside it the machine's exact volumetric error
    (:func:`volumetric_residual_um`, a rigid motion removed).
    """
    from dataclasses import replace as _rep

    from sim.machine import Machine

    if before is None:
        before = run(name, **kw)
    ctl = compensators(directory, name)
    seed = kw.pop("seed", 1)
    spec = kw.get("machine")
    cfg = spec.config if spec is not None else default_machine(before.plan.machine, kw.get("ripple", False))[0]

    def truth(J, comp=None):
        m = Machine(_rep(cfg, J_m=J))
        return m if comp is None else comp(m)

    def u95(r, a):
        e = r.doc["errors"][f"E{a}{a}"]
        return np.asarray(e.get("u95", [np.nan] * len(e["identified"])), float)

    def block(r, comp=None):
        pos = {}
        true = true_positioning_m(truth((0.0, 0.0, 0.0), comp), r.plan.nodes)
        for a in "XYZ":
            ident = np.abs(np.asarray(r.doc["errors"][f"E{a}{a}"]["identified"], float))
            t = np.abs(true[a]) * 1e6
            u_before, u_now = u95(before, a), u95(r, a)
            pos[a] = {"true_max_um": float(t.max()), "identified_max_um": float(ident.max()),
                      "u95_max_um": float(np.nanmax(u_now)) if np.isfinite(u_now).any() else None}
            if np.isfinite(u_before).all():
                pos[a]["true_within_u95"] = f"{int(np.sum(t <= u_before))}/{len(t)}"
            if np.isfinite(u_now).all():
                pos[a]["identified_within_u95"] = f"{int(np.sum(ident <= u_now))}/{len(ident)}"
        return {"positioning": pos,
                "volumetric_residual_um": volumetric_residual_um(truth(STYLI[COMP_STYLUS], comp), r.plan.nodes)}

    doc = {"scenario": name, "directory": str(directory), "seed_before": seed, "seed_after": seed + 1,
           "criterion": "after compensation, the true positioning error (exact sim) within the U95 of the "
                        "identification the compensation came from, at every node (true_within_u95)",
           "before": block(before)}
    for key, comp in ctl.items():
        r = run(name, seed=seed + 1, bar_seed=seed, compensate=comp, **kw)
        doc[key] = block(r, comp)
    return doc


# --------------------------------------------------------------------------- reversal on a CMM (eqs 5-7)
def reversal_on_cmm(*, repeats: int = 5, seed: int = 1, noise_um: float = 0.05, deviations_m=None,
                    cmm_errors: dict | None = None, u_place=(0.1e-3, 0.1e-3, 0.1e-3, 0.0, 0.2e-3, 0.2e-3)) -> dict:
    """Calibrate the bar by reversal on a simulated CMM, touches and all (Viprey 2016 eqs 5-7).

    The CMM is the ``vmc-3axis`` chain with its own errors (default: EXX 2
    um/m, EYX and EZX bows of 1.5 / -1.1 um over the bar against its
    end-point line), probing noise
    ``noise_um`` (k = 1). The bar lies along the CMM's X, probed over its
    12 holes, rods and faces: ``repeats`` times as it is (NR) and turned 180
    deg about its x axis (R, the rods touched from the other side), each
    time re-placed (``u_place``: translation m, rotation rad, standard).
    Points of interest from the touches (:func:`core.mfb.points_of_interest`),
    O_1 at the origin; the CMM's positioning error at the holes as a step
    gauge gives it (the true value + a draw of the paper's U(k=2) = 0.3 um +
    1.5e-6 L). Then :func:`core.mfb.reversal_calibration`.

    Returns
    -------
    dict
        ``calibration`` (core.mfb.BarCalibration), ``true_m`` (12, 3): the
        bar's true deviations; ``compared_um``: per direction, the estimate
        minus the truth in the calibration's gauge (x from O_1; y and z
        against the end-point line O_1 O_12, the CMM's alignment on the bar),
        its max, the U95 max and how many of the 12 lie within U95.
    """
    from dataclasses import replace

    from core import mfb
    from core.exceptions import ConfigError
    from core.touches import from_log
    from sim import artefacts as A
    from sim.campaign import simulate_campaign
    from sim.errorfuncs import Polynomial
    from sim.machine import Machine
    from sim.machines import MACHINES
    from sim.probe import ProbeConfig
    from sim.setups import Setup

    if int(repeats) < 2:
        raise ConfigError(f"repeats must be >= 2 (the type A uncertainty needs a scatter), got {repeats!r}")
    rng = np.random.default_rng(seed)
    E_true = A.mfb_default_deviations() if deviations_m is None else np.asarray(deviations_m, float)
    art = A.multi_feature_bar(deviations_m=E_true)
    errs = cmm_errors if cmm_errors is not None else {
        "EXX": Polynomial((0.0, 2.0e-6)), "EYX": Polynomial((0.0, 0.0, 2.0e-5)), "EZX": Polynomial((0.0, 0.0, -1.5e-5))}
    cmm = Machine(MACHINES["vmc-3axis"](errors=errs, J_m=(0.0, 0.0, 0.150)))
    probe = ProbeConfig(repeatability_k2_m=2.0 * float(noise_um) * 1e-6)
    pl = _plan_for(art, tuple(range(1, 13)))
    flip = np.array([1.0, 1.0, -1.0])
    pl_rev = replace(pl, w_A=pl.w_A * flip, wn_A=pl.wn_A * flip)
    T_nr = A.make_T(None, (-0.275, 0.0, 0.100))
    T_r = T_nr @ A.make_T(A.rot_x(np.pi))
    M = {"NR": [], "R": []}
    for k in range(int(repeats)):
        for key, T, p in (("NR", T_nr, pl), ("R", T_r, pl_rev)):
            xi = rng.standard_normal(6) * np.asarray(u_place, float)
            dT = A.make_T(A.rot_z(xi[5]) @ A.rot_y(xi[4]) @ A.rot_x(xi[3]), xi[:3])
            log = simulate_campaign(art, cmm, probe, [Setup(f"{key}{k}", T, (), T @ dT)], rng, plan=p,
                                    check_collisions=False)
            t = from_log(log)
            O = mfb.points_of_interest(t.p_R, t.feature, t.n_R).O_R
            O = O - O[0]
            # the CMM's alignment on the bar: y and z against the line O_1 O_12
            # (the bar "carefully aligned along the CMM axis"; eq. 6 then gives
            # the straightness against its end-point line)
            O[:, 1:] -= np.outer(O[:, 0] / O[-1, 0], O[-1, 1:])
            M[key].append(O)
    x_cmm = T_nr[0, 3] + np.arange(12) * A.MFB_PITCH_M
    exx = np.asarray(errs["EXX"](x_cmm), float) if "EXX" in errs else np.zeros(12)
    u_sg = 0.5 * (0.3e-6 + 1.5e-6 * np.arange(12) * A.MFB_PITCH_M)
    exx_sg = exx - exx[0] + rng.standard_normal(12) * u_sg
    cal = mfb.reversal_calibration(np.array(M["NR"]), np.array(M["R"]), exx_sg, u_step_gauge_m=u_sg)
    truth = np.asarray(art.info["E_MFB_m"], float)
    x = np.arange(12) * A.MFB_PITCH_M
    out = {}
    for j, name in enumerate(("Exx", "Eyx", "Ezx")):
        # the same gauge for both: x from O_1; y, z against the end-point line
        d = cal.E_m[:, j] - truth[:, j]
        d = d - d[0] - (x / x[-1] * (d[-1] - d[0]) if j else 0.0)
        inside = int(np.sum(np.abs(d) <= cal.U95_m[:, j]))
        out[name] = {"max_abs_um": float(np.abs(d).max() * 1e6), "U95_max_um": float(cal.U95_m[:, j].max() * 1e6),
                     "within_U95": f"{inside}/12", "deviation_um": (d * 1e6).tolist()}
    return {"calibration": cal, "true_m": truth, "compared_um": out, "repeats": int(repeats),
            "touches": 2 * int(repeats) * pl.n}
