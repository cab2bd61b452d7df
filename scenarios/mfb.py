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

- X1, X2, X3: bar along X at (y, z) = (-40, 70), (-40, 270), (110, 70) mm,
  straight stylus T0 (J_Z 150 mm): EXX, EYX, EZX; X2-X1 (dz 200 mm): EBX
  (positioning), EAX (horizontal straightness); X3-X1 (dy 150 mm): ECX
  (positioning), EAX (vertical straightness);
- Y1, Y2: bar along Y at (x, z) = (-25, 70), (-25, 270) mm, T0: EYY, EXY,
  EZY; Y2-Y1 (dz): EAY, EBY;
- Y3: along Y at x = 125 mm with TXF (star arm 100 mm along X with a
  40 mm finger): Y3-Y1 (dJ_X 100 mm) gives ECY by differential positioning
  and EBY by differential vertical straightness (with T0 it gave neither:
  the weakest combination was an ECY ramp, relative sv 1.3e-4 -> 6.5e-4);
- VY: standing bar (along Z) at (-25, -20) mm, holes facing -Y, star
  styli TY1, TY2 (arm 100, 150 mm along Y) and TYL (TY1 on J_Z 250 mm,
  holes 1-5): EZZ, EXZ, EYZ; dJ_Y: ECZ, EAZ; dJ_Z: EBZ, EAZ (session 26:
  at y = -40 mm TY2's spindle went 13 mm past Y's -200 mm on its links,
  and TYL over holes 6-7 put the spindle 93 mm past Z's 400 mm: a stroke
  bounds the axis, reading + J - the machine's J, docs/formats.md);
- VX: standing bar, holes facing -X, TX1 and TX2: ECZ, EBZ; EXZ, EYZ with
  the other Abbe arm;
- DXY (flat, 45 deg in XY, T0), DXZ (tilted 45 deg in XZ, holes facing
  -Y, TY1), DYZ (tilted 45 deg in YZ, holes facing -X, TX1): the
  squarenesses EC0Y, EB0Z, EA0Z (a bar parallel to an axis absorbs the
  slope into its pose);
- AXY, AXZ, AYZ: the anti-diagonals (x_A along X-Y, Z-X, Z-Y; the tilted
  ones rise from z = 97.5 to 345 mm, the bar's unprobed holes 9-12 above,
  so no part of the bar is below the table face). A linear twist of the table (an EAX
  ramp, an EBY ramp) moves every bar parallel to an axis rigidly, so only
  the diagonals see it, as a bend ``a s^2 / 2`` that the bar's own bow
  (calibrated, to ``u_cal``) imitates; the anti-diagonal bends the other
  way under the same bow. With one diagonal per plane the twist is the
  plan's largest uncertainty (EAX / EBY U95 33 / 30 urad, seed 1 without
  AXY, AXZ, AYZ), with the pairs 14 / 13 urad; the squarenesses gain alike
  (EB0Z 13 -> 6 urad).

No bar reaches below the table face (W z = 0, R's origin at the table
surface: sim/machines.py): the flat bars' hole line at z = 70 mm, the bar's
10 mm half thickness on its 60 mm supports standing on the table (the
earlier plan had the hole line at 60 mm, 10 mm into the table, and its
anti-diagonals falling from 345 mm to 75.7 mm below the face; the tests
compute every bar's lowest point apart from :func:`check_plan`). Every bar
stands on something (:func:`_fixtures_3axis`): the 6 flat bars (X1, X3, Y1,
Y3, DXY, AXY) on the table; X2 and Y2 on a 200 mm riser; the bars whose
holes face -Y (VY standing, DXZ, AXZ tilted 45 deg in XZ) have their
supports, pointing +Y, bolted to an angle plate whose face is y = 30 mm,
those facing -X (VX, DYZ, AYZ) to one at x = 45 mm (the tilt lies in the
plate's face: no tilted block is needed); a test checks by hand geometry
that every support's foot lies on the table or on a fixture's face. Every
run is collision-checked (:func:`check_plan`: 3,888 touches since session
26, 3,944 before, fixtures included; the probe never nears them: a fixture's face moved toward the bar
is first met 60.9 mm in, 0.9 mm inside the bar's body). Until session 11
the plan had no fixtures, 11 of its measurements' bars floating with their
supports' feet on nothing, and :func:`run` did not check it; the bar poses
and every figure of its results are the same.

Every position the program commands (touches, approach starts, overshoot
ends, links) lies within the strokes as an axis position (reading + J -
the machine's J, :func:`check_program_strokes`), checked on every run by
:func:`check_plan`. Each bar is probed over the holes that fit the strokes
(12 along X, 8 along Y, 7 standing; VYc 5), with the rods and faces the planes PL_i need (rod k
of a bar probed to hole k lies 25 mm beyond it). The error tables have
their nodes at the points of interest, where a bar senses all three
directions: 8 along Y and 7 along Z (one per hole), 9 along X over the
12 holes (a 12-hole bar has 11 rods, its only height sensors: 12 nodes
leave one EZX combination seen by curvature alone). The end nodes are the
end holes; over the rods and faces beyond them (up to 34 mm) the tables
continue along their end tangent (:data:`core.volumetric.NODE_MARGIN_M`).
Since session 27 the tables (and the truth's error functions) are functions
of the axis (joint) positions ``reading + J`` (eq. 8), so the nodes are
joint positions: the holes as T0 reaches them (Z 150 mm above the holes'
heights, 210-510 mm), and a stylus with another J visits other carriage
positions (VYc's TYL probes the standing bar's holes 1-5). The gauge fixes
21 conventions (EXY, EXZ, EYZ at both ends now: the slope is one
combination with the squareness and a constant angular error,
:mod:`core.volumetric`). Seed 1 (0.125 um noise, 200 Monte Carlo runs):
123 of 126 node values within U95 (19 of 21 errors whole; the model
expects 104-126); seeds 1-10: 1,176 of 1,260 (93.3 %; 1,184, 94.0 %, at
63c4d4f), the lowest seed 8's 101 (112 before: a hard campaign either
way); U95 max EAZ / EBZ / ECZ 10.3 / 10.5 / 13.3
urad, EB0Z / EA0Z 10.7 / 7.1 (7.3 / 6.5 / 7.1, 5.9 / 5.0 before: the
combination the lever arms alone sense now; 500 Monte Carlo runs). Noise-free 0.047 um / 0.33
urad (EA0Z). Figures in this doc not restated here were measured before
that change (errors at the tip readings).
End nodes spanning every touch (the previous layout) sat where only one
direction is sensed, and the end-point conventions hung every table on
them: U95 reached 47 um (EZX) and 110 urad (EBY) at 0.25 um probing noise.

Identification (:mod:`core.volumetric`): the machine errors enter through
the touches, carried into the points of interest by the extraction's gain;
then Gauss-Newton on the exact chain; reported in the ISO 230-1 form
(straightness against its end-point line, the slope kept beside it).
Noise-free on the default realistic machine: 0.047 um / 0.33 urad (the
tables' interpolation of its 9-knot profiles and the tangent continuation
over the end rods; session 27, errors at the axis positions: 0.045 / 0.17
before); 0.003 um / 0.038 urad for errors the tables represent
(``on_nodes=True``; 0.003 / 0.025 before).

Uncertainty: probing noise (0.125 um standard deviation, the paper's 0.25 um
at k = 2), the bar's calibration (the
true bar differs from its calibration by a draw of ``u_cal_um``, its 12
heights kept to what its 11 rods can give: :func:`core.mfb.calibration_map`,
propagated alike) and the
placement errors (:data:`U_PLACE`, roll included, drawn in the simulator),
by linear propagation and Monte Carlo (JCGM 101) through the same
estimator. At 0.25 um probing noise (k = 2), over four seeded campaigns
(seeds 11-14), U95 at the nodes: positioning median 0.67 um, max 0.84 um;
straightness 0.90 / 3.6 um (EZX next to its end nodes, bar calibration
dominated); angular 3.5 / 13.7 urad (the EAX / EBY twist ramps); squareness
3.6 / 5.8 urad. 94 % of 504 identified values within U95 (RMS error / U95
0.51); a noisy run is off by 0.9-2.9 um / 6.8-9.2 urad. What is left weakest: ``observability(...).weakest``.

The scenario injects ``sim.machines.realistic_errors`` of the machine's
linear axes minus the 10 mm screw-pitch ripple: a bar of 50 mm pitch
samples every hole at the same ripple phase and the hole fit averages it
over +-5 mm, so no MFB plan can see a ripple shorter than twice its pitch
(``ripple=True`` keeps it).

5-axis (``mfb-5axis``, ``mikron-ucp710``): :func:`plan_5axis`, 4 bar
placements on the table (flat; flat on a 150 mm riser; on edge on an angle
plate; flat for the XZ anti-diagonal), presented by A and C in 12 set-ups,
15 measurements; every touch, approach and link move checked for
collisions and reach in the MuJoCo work zone (:func:`check_plan`,
:mod:`sim.mfb_scene`) and within the strokes as axis positions; the rotary
axes' errors are absorbed by each set-up's pose. Noise-free on the
realistic machine (rotary axes' errors included): 0.020 um / 0.20 urad
(EAX; session 26; 0.041 / 0.31 with the plan before). At 0.125 um probing
noise (seed 1): U95 max 0.66 um positioning, 1.4 um straightness (EYZ);
the twists: EAX U95 28.9 urad on a 4.8 urad peak-to-peak signal (not
resolved: on this tool-side chain a ramp of an angular error of X moves
every bar along X rigidly, and only the diagonals' bend, ~0.1 um, sees
it), EBY 7.2 urad on 5.95 (seen by T0 vs TXF in one pose, dJ_X 100 mm),
ECZ 8.9 urad on 3.6 (TX1 vs TX3 on VX, dJ_X 150 mm; not resolved at this
noise). Session 26 took the standing bar VY (holes facing -Y) out: A = -90
deg puts its holes at R y ~ -190 mm and the program's links at -213 mm, so
a star arm along +Y keeps the spindle within Y's -275 mm only up to 62 mm,
and at 60 mm the spindle nose already meets the bar's upper holes (MuJoCo,
0.4-0.5 mm deep; 40-50 mm arms 7-13 mm): the Z axis's errors now come from
VX with TX1, TX3 (250 mm arm, dJ_X 150 mm) and TXL (dJ_Z 100 mm for EAZ).
What moved (seed 1, U95 max, plan before -> now): EA0Z 4.0 -> 11.9 urad,
EC0Y 4.8 -> 7.4 urad, ECZ 8.4 -> 8.9, EBZ 3.1 -> 3.5, EYZ 1.0 -> 1.4 um,
EXZ 1.5 -> 1.1 um, EAZ 4.7 -> 4.0 urad; the rest within 10 %. (With TX2's
50 mm arm in place of TX3: ECZ 12.1, EBZ 6.1, EA0Z 14.8 urad, EYZ 2.3 um.)
The figures above are of the errors at the tip readings.

Session 27 (the errors at the axis positions, reading + J; nodes as joint
positions: Z 105-355 mm): VX's TX3 put its carriage 250 mm beyond its tip
in X, at -311 mm, 136 mm below the X nodes, where no X bar senses the X
errors it carries; P3 (Y3, VX, DYZ) moved to x = 90 mm (-161 mm), and
VXc's TXL probes holes 5-10 (two lower than TX1 / TX3's 7-12), so its
carriage passes the same Z positions: an angular error of Z is told from a
straightness by dJ_Z only where both carriages pass. The diagonals' reach
is the node box widened by NODE_MARGIN_M (TYM's carriage, 60 mm beyond
its tip in Y, reaches -258 mm). Seed 1: 117 of 120 node values within U95
(expected 97-120), seeds 1-10 1,130 of 1,200 (94.2 %; 1,132, 94.3 %, at
63c4d4f); U95 max (seed 1, 500 runs; 63c4d4f in brackets): positioning
0.77 um (0.70), EYZ 2.6 um (1.4), ECY 6.3 (4.5), EBY 14.9 (7.2), EAY 3.1
(2.7), EAZ 17.9 (4.0), ECZ 9.3 (8.9), EBZ 6.0 (3.5), EA0Z 14.4 (11.9),
EC0Y 7.5 (7.4), EB0Z 8.3 (3.0), EAX 17.1 (28.9) urad. The 3-axis plan's
(seed 1, same settings): ECY 5.3, EBY 13.4, EAY 2.7, EAZ 10.3 urad: the Y
errors of the order of the 3-axis plan's, EAZ under twice (TXL's 6 holes
against VY's TY1 / TY2 / TYL). Noise-free 0.021 um /
0.125 urad (EB0Z); on the nodes 0.002 / 0.031.

The bar's calibration: declared (its default deviations, u_cal_um) or the
reversal on a simulated CMM (:func:`reversal_on_cmm`, eqs 5-7, written by
:func:`bar_calibration_doc`, read by :func:`read_bar_calibration`) fed to
:func:`run` (``bar_calibration``, ``bar_true_m``); the result keeps the
bar's true and calibrated deviations (``doc['bar']``). The budget
(:func:`budget`): each source's share per error (probing noise, bar
calibration, placement, stylus offsets, lobing, the bar's and the machine's
temperature) and a Monte Carlo through the whole pipeline.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field

import numpy as np

from core.memo import Memo
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
    # (compared: plans of other workholding are other plans; not hashed, a dict: the hash is the
    # measurements', equal plans still hash equal)
    fixtures: dict = field(default_factory=dict, hash=False)

    @property
    def setups(self) -> tuple:
        return tuple(dict.fromkeys(m.setup_key for m in self.measurements))

    @property
    def placements(self) -> tuple:
        return tuple(dict.fromkeys(m.placement for m in self.measurements))

    @property
    def rotary(self) -> bool:
        """Whether rotary axes present the bars (the set-ups have rotary positions: a 5-axis plan)."""
        return any(len(m.rot_rad) for m in self.measurements)

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
    ms = []

    def add(name, x_A, z_A, p, holes, styli=("T0",), senses="", stylus_holes=None):
        x_A, z_A = np.asarray(x_A, float), np.asarray(z_A, float)
        T = _T((x_A, np.cross(z_A, x_A), z_A), p)
        for k, st in enumerate(styli):
            ms.append(MeasurementSpec(name if len(styli) == 1 else f"{name}{'abc'[k]}", name, T, (),
                                      STYLI[st], tuple((stylus_holes or {}).get(st, holes)), senses, st))

    h12, h8, h7 = tuple(range(1, 13)), tuple(range(1, 9)), tuple(range(1, 8))
    add("X1", _X, _Z, (-0.275, -0.040, 0.070), h12, senses="EXX, EYX, EZX (tables along X at y=-40, z=70 mm)")
    add("X2", _X, _Z, (-0.275, -0.040, 0.270), h12,
        senses="with X1 (arm dz = 200 mm): EBX by differential positioning, EAX by differential horizontal straightness")
    add("X3", _X, _Z, (-0.275, 0.110, 0.070), h12,
        senses="with X1 (arm dy = 150 mm): ECX by differential positioning, EAX by differential vertical straightness")
    add("Y1", _Y, _Z, (-0.025, -0.190, 0.070), h8, senses="EYY, EXY, EZY (tables along Y at x=-25, z=70 mm)")
    add("Y2", _Y, _Z, (-0.025, -0.190, 0.270), h8,
        senses="with Y1 (arm dz = 200 mm): EAY by differential positioning, EBY by differential horizontal straightness")
    add("Y3", _Y, _Z, (0.125, -0.190, 0.070), h8, ("TXF",),
        senses="with Y1, Abbe arm dJ_X = 100 mm: ECY by differential positioning, EBY by differential "
               "vertical straightness (the table does not move in X under the tool when Y moves, so a bar "
               "shifted in x gives no arm: the arm must come from the stylus)")
    # VY at y = -20 mm (was -40: TY2's spindle went 13 mm past Y's -200 mm on its links) and
    # TYL over holes 1-5 (its spindle is 100 mm above the reference tool's: holes 6-7 put it
    # 93 mm past Z's 400 mm): every position within the strokes as axis positions (check_plan)
    add("VY", _Z, -_Y, (-0.025, -0.020, 0.060), h7, ("TY1", "TY2", "TYL"),
        senses="standing bar, holes facing -Y, probed with a star stylus arm along +Y: EZZ, EXZ, EYZ; "
               "arm 100 vs 150 mm (dJ_Y = 50 mm): ECZ (x) and EAZ (z); stylus 150 vs 250 mm (dJ_Z, holes "
               "1-5): EBZ (x), EAZ (y)", stylus_holes={"TYL": tuple(range(1, 6))})
    add("VX", _Z, -_X, (-0.025, -0.040, 0.060), h7, ("TX1", "TX2"),
        senses="standing bar, holes facing -X, star stylus arm along +X: arm 100 vs 150 mm: ECZ (y), EBZ (z); "
               "EXZ / EYZ again with the other Abbe arm")
    add("DXY", (_X + _Y) * _S2, _Z, (-0.125, -0.140, 0.070), h8, senses="EC0Y (face diagonal in XY)")
    add("DXZ", (_X + _Z) * _S2, -_Y, (-0.125, -0.040, 0.060), h8, ("TY1",),
        senses="EB0Z (face diagonal in XZ, tilted 45 deg, holes facing -Y, star stylus arm along +Y)")
    add("DYZ", (_Y + _Z) * _S2, -_X, (-0.025, -0.140, 0.060), h8, ("TX1",),
        senses="EA0Z (face diagonal in YZ, tilted 45 deg, holes facing -X, star stylus arm along +X)")
    # the anti-diagonals: a linear twist of the table (EAX ~ a x, EBY ~ -a y)
    # moves every bar parallel to an axis rigidly (absorbed by its placement)
    # and bends a diagonal by a s^2 / 2, which the bar's own bow (calibrated,
    # to u_cal) imitates; the anti-diagonal bends the other way under the
    # same bow, so the pair separates twist from bar (and the squarenesses
    # from the bar's length): EAX / EBY ramps 33 / 30 -> 14 / 13 urad U95 (seed 1)
    add("AXY", (_X - _Y) * _S2, _Z, (-0.125, 0.107, 0.070), h8,
        senses="with DXY: twist of X and Y (EAX, EBY ramps) and EC0Y, free of the bar's bow")
    add("AXZ", (-_X + _Z) * _S2, -_Y, (-0.125 + 0.35 * _S2, -0.040, 0.345 - 0.35 * _S2), h8, ("TY1",),
        senses="with DXZ: EAX ramp and EB0Z, free of the bar's bow (z rises along the bar)")
    add("AYZ", (-_Y + _Z) * _S2, -_X, (-0.025, -0.140 + 0.35 * _S2, 0.345 - 0.35 * _S2), h8, ("TX1",),
        senses="with DYZ: EBY ramp and EA0Z, free of the bar's bow (z rises along the bar)")
    # table nodes at the points of interest, where the bar senses every
    # direction: the end nodes at the first and last holes (X +-275 mm, Y
    # -190 / 160 mm, Z 60 / 360 mm), the tables continued along their end
    # tangent over the rods and faces beyond (core.volumetric.NODE_MARGIN_M).
    # Y and Z: one node per hole (8, 7; each hole k has its rod k). X: a bar
    # of 12 holes has 11 rods, the only height sensors, so 12 nodes leave
    # EZX one combination sensed by nothing but curvature (U95 ~25 um); 9
    # nodes (68.75 mm) keep it at ~4 um and interpolate the realistic
    # profiles to < 0.08 um.
    # The nodes are axis (joint) positions, reading + J (core.volumetric): the points of
    # interest as T0 (J_Z 150 mm) reaches them, so Z's sit 150 mm above the holes' heights.
    nodes = {"X": np.linspace(-0.275, 0.275, 9), "Y": np.linspace(-0.190, 0.160, 8),
             "Z": np.linspace(0.060, 0.360, 7) + STYLI["T0"][2]}
    return MfbPlan("vmc-3axis", tuple(ms), nodes, _fixtures_3axis())


def _fixtures_3axis() -> dict:
    """The workholding of the 3-axis placements (:class:`sim.mfb_scene.Block`, W, m): what each
    bar's two supports stand on or are bolted to (their feet: 8 mm discs 70 mm from the hole line,
    at x_A = 114.43 and 435.57 mm; module doc). The 6 bars flat on the table need none.

    - X2, Y2: a 200 mm riser under the feet (hole line at 270 mm = 200 + 60 + 10), 90 mm wide,
      reaching 39.4 mm beyond each foot's centre;
    - the bars whose holes face -Y (VY standing, DXZ and AXZ tilted 45 deg in XZ): their
      supports point +Y, feet in the plane y = 30 mm, bolted to the face of an angle plate
      (30 mm thick, behind the bar); the tilt is within the plate's face, so no tilted block is
      needed; likewise the bars facing -X (VX, DYZ, AYZ) on a plate whose face is x = 45 mm.
      Each plate's edges nearest the feet are 39.4-45.0 mm from the feet's centres (measured:
      39.4 VY/VX's top, 535 mm high above the upper foot at 495.6 mm; 45.0 their sides; 40.9 and
      42.0 DXZ/DYZ; 39.5 and 43.4 AXZ/AYZ), 31.4-37.0 mm beyond the 8 mm discs; the risers' 39.4
      mm along the bar, 45.0 mm across. Each plate is its upright alone: its base and ribs
      (behind it, away from the bar) are not modelled.
    """
    from sim.mfb_scene import Block

    def b(name, lo_mm, hi_mm):
        return (Block(name, tuple(v * MM for v in lo_mm), tuple(v * MM for v in hi_mm)),)

    return {"X2": b("riser", (-200, -85, 0), (200, 5, 200)),
            "Y2": b("riser", (-70, -115, 0), (20, 285, 200)),
            "VY": b("angle_plate", (-70, 50, 0), (20, 80, 535)),
            "VX": b("angle_plate", (45, -85, 0), (75, 5, 535)),
            "DXZ": b("angle_plate", (-85, 30, 0), (225, 60, 410)),
            "AXZ": b("angle_plate", (-225, 30, 0), (85, 60, 445)),
            "DYZ": b("angle_plate", (45, -100, 0), (75, 210, 410)),
            "AYZ": b("angle_plate", (45, -240, 0), (75, 70, 445))}


#: Star styli of the 5-axis plan besides :data:`STYLI`: short arms along +Y. A bar whose
#: holes face -Y is presented by A = -90 deg (the A line 120 mm below the table face), so its
#: hole line lies at R y = -(z_W + 120 mm) ~ -190 mm and the program's links, 10 mm beyond the
#: bar's face, at -213 mm: the spindle (reading + J_Y) stays within Y's -275 mm only with an arm
#: of at most 62 mm (TY1's 100 mm put it 38 mm beyond, TY2's 150 mm 88 mm; session 26).
#: TYM: a 60 mm arm (X3, DXZ, AXZ). The standing bar facing -Y (VY) is out: at 60 mm the
#: spindle nose meets the bar's upper holes (0.4-0.5 mm deep; 40-50 mm arms 7-13 mm), so the Z
#: axis is measured on VX (holes facing -X, X's stroke leaves room): TX1, TX3 (a 250 mm arm
#: along +X, dJ_X 150 mm: ECZ U95 12.1 -> 8.9 urad, EBZ 6.1 -> 3.5 against TX2's 50 mm, seed 1)
#: and TXL (TX1 on the 250 mm extension, J_Z 250 mm: dJ_Z for EAZ).
STYLI_5AXIS = {"TYM": (0.0, -0.060, 0.150), "TX3": (-0.250, 0.0, 0.150), "TXL": (-0.100, 0.0, 0.250)}

#: 5-axis nodes (R, m): the points of interest of the bars along each axis
#: (X: holes 1-10 of a bar whose first hole is at x = -175 mm, 9 nodes as
#: the 3-axis plan's; Y: 8 holes from y = -225 to 125 mm; Z: 6 holes of the
#: standing bars, z = -45 to 205 mm, the A line being 120 mm below the
#: table face). Every reading of every measurement lies within the nodes
#: (plus :data:`core.volumetric.NODE_MARGIN_M`) of all three axes.
#: The nodes are axis (joint) positions, reading + J (core.volumetric, session 27): Z's are the
#: holes' heights as T0 (J_Z 150 mm) reaches them, 105-355 mm; the carriages of the other styli
#: stay within them (P3 moved to x = 90 mm for TX3, TXL two holes lower, plan_5axis) but for
#: TYM's Y (60 mm beyond its tip: X3, DXZ, AXZ at Y -258 .. -244 mm, within NODE_MARGIN_M).
NODES_5AXIS = {"X": np.linspace(-0.175, 0.275, 9), "Y": np.linspace(-0.225, 0.125, 8),
               "Z": np.linspace(-0.045, 0.205, 6) + 0.150}


def plan_5axis() -> MfbPlan:
    """The 5-axis plan for ``mikron-ucp710``: 4 bar placements, 12 rotary set-ups, 15 measurements.

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
      (y, z) = (80, 70) mm; X3 (A = -90, C = 0, TYM): along X at (-190, -40)
      mm, holes facing -Y; Y1 (C = 90; T0 and TXF in one pose): along -Y at
      (x, z) = (80, 70) mm; DXY / AXY (C = -45 / +45, T0) and DXZ (A = -90,
      C = -45, TYM): diagonals. (X3, DXZ, AXZ on TYM, a 60 mm arm: at A =
      -90 their links lie at R y -213 mm, and TY1's 100 mm arm put the
      spindle 38 mm past Y's -275 mm; the standing VY, holes facing -Y, is
      out: no arm both keeps its spindle within Y and clears the bar.)
    - **P2**: the bar flat on a 150 mm riser block: X2 (A = C = 0, T0) at
      (y, z) = (0, 220) mm, Y2 (C = 90, T0) at (x, z) = (0, 220) mm.
    - **P3**: the bar on its edge along W y at x = 90 mm, holes facing -W x,
      its supports bolted to an angle plate, 105 mm above the table: Y3 (A =
      C = 0, TX1, holes 1-8), VX (A = -90; TX1 and TX3 on holes 7-12, TXL on
      5-10: the standing bar for the Z axis, dJ_X 150 mm between TX1 and
      TX3's 250 mm arm, dJ_Z 100 mm to TXL, whose carriage then passes the
      same Z positions), DYZ (A = -45, TX1).
    - **P4**: flat along W x, first hole at (-300, 160) mm: AXZ (A = -90,
      C = 45, TYM), the XZ anti-diagonal (from P1 it falls below the Z
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
    VX (dJ_X 150 mm, dJ_Z 100 mm), one pose: ECZ, EAZ, EBZ with their
    ramps; the diagonals: EC0Y, EB0Z, EA0Z and the
    twist ramps. The paper's 6 placements: this chain needs 4 (run with
    ``drop=`` to see what is lost without each).
    """
    from sim.machine import Machine
    from sim.machines import MACHINES
    from sim.mfb_scene import Block

    m = Machine(MACHINES["mikron-ucp710"]())
    axes = m.rotary_axes
    styli_5 = {**STYLI, **STYLI_5AXIS}
    ms = []
    fixtures = {}

    def place(name, x_W, z_W, origin, blocks=()):
        x_W, z_W = np.asarray(x_W, float), np.asarray(z_W, float)
        fixtures[name] = tuple(blocks)
        return name, _T((x_W, np.cross(z_W, x_W), z_W), origin)

    def add(pl, name, rot_deg, holes, styli=("T0",), senses="", stylus_holes=None):
        p, T = pl
        r = tuple(float(np.deg2rad(rot_deg[a])) for a in axes)
        if holes == _DIAG:
            T_R_W = np.asarray(m.T_R_W_nominal(np.asarray(r)[None, :]), float).reshape(4, 4)
            holes = _fit_holes(T_R_W @ T, _reach(m.config.strokes, styli_5[styli[0]], m.config.J_m), styli_5[styli[0]], m.config.strokes, m.config.J_m)
        key = f"{p}@" + ",".join(f"{a}{rot_deg[a]:g}" for a in axes)
        for k, st in enumerate(styli):
            ms.append(MeasurementSpec(name if len(styli) == 1 else f"{name}{'abc'[k]}", p, T, r,
                                      styli_5[st], tuple((stylus_holes or {}).get(st, holes)), senses, st,
                                      setup=key))

    h10, h29, h18, h712 = (tuple(range(1, 11)), tuple(range(2, 10)), tuple(range(1, 9)), tuple(range(7, 13)))
    P1 = place("P1", _X, _Z, (-0.175, 0.080, 0.070))
    P2 = place("P2", _X, _Z, (-0.175, 0.000, 0.220),
               (Block("riser", (-0.095, -0.045, 0.0), (0.295, 0.045, 0.150)),))
    # P3 at x = 90 mm (was -60, session 27): VX's TX3 (arm 250 mm along +X) puts its carriage at
    # reading - 250 mm in X, -161 mm here (-311 before: 136 mm below the X nodes, where no X bar
    # senses the X errors its carriage then carries); Y3 and DYZ share the placement
    P3 = place("P3", _Y, -_X, (0.090, -0.225, 0.105),
               (Block("angle_plate", (0.160, -0.135, 0.0), (0.180, 0.235, 0.140)),))
    P4 = place("P4", _X, _Z, (-0.300, 0.160, 0.070))
    add(P1, "X1", {"A": 0, "C": 0}, h10, senses="EXX, EYX, EZX at (y, z) = (80, 70) mm")
    add(P2, "X2", {"A": 0, "C": 0}, h10, senses="with X1 (dy -80, dz 150 mm): EAX, EBX, ECX")
    add(P1, "X3", {"A": -90, "C": 0}, h10, ("TYM",), senses="with X1, X2 (y, z) = (-190, -40) mm: EAX, EBX, ECX")
    add(P1, "Y1", {"A": 0, "C": 90}, h29, ("T0", "TXF"),
        senses="EYY, EXY, EZY at (x, z) = (80, 70) mm; T0 vs TXF in one pose (dJ_X 100 mm): ECY, EBY "
               "with their ramps (a ramp is a bar's yaw or pitch to any bar set up alone)")
    add(P2, "Y2", {"A": 0, "C": 90}, h29, senses="with Y1 (dz 150 mm): EAY, EBY")
    add(P3, "Y3", {"A": 0, "C": 0}, h18, ("TX1",), senses="with Y1 (dJ_X 100 mm): ECY, EBY")
    # TXL (J_Z 250 mm) two holes lower than TX1 and TX3 (holes 5-10 against 7-12): its carriage
    # is 100 mm above theirs at one hole, so these holes put it over the same Z axis positions
    # (105-355 mm): an angular error of Z is sensed by dJ_Z only where both styli's carriages pass
    add(P3, "VX", {"A": -90, "C": 0}, h712, ("TX1", "TX3", "TXL"), stylus_holes={"TXL": tuple(range(5, 11))},
        senses="EZZ, EXZ, EYZ; dJ_X (TX1 vs TX3, 150 mm): ECZ, EBZ; dJ_Z (TX1 vs TXL, the same axis "
               "positions): EBZ, EAZ")
    add(P1, "DXY", {"A": 0, "C": -45}, _DIAG, senses="EC0Y, twist")
    add(P1, "AXY", {"A": 0, "C": 45}, _DIAG, senses="EC0Y, twist")
    add(P1, "DXZ", {"A": -90, "C": -45}, _DIAG, ("TYM",), senses="EB0Z, twist")
    add(P4, "AXZ", {"A": -90, "C": 45}, _DIAG, ("TYM",), senses="EB0Z, twist (the XZ anti-diagonal: out of "
        "reach from P1, whose bar falls below the Z stroke)")
    add(P3, "DYZ", {"A": -45, "C": 0}, _DIAG, ("TX1",), senses="EA0Z, twist")
    return MfbPlan("mikron-ucp710", tuple(ms), dict(NODES_5AXIS), fixtures)


#: Holes of the diagonal measurements: chosen per set-up (:func:`_fit_holes`).
_DIAG = ()


def _reach(strokes, J_m, J_ref_m) -> dict:
    """Where a 5-axis reading may lie with probe offsets ``J_m``: the strokes (axis positions,
    reading + J - ``J_ref_m``) and the node box of each axis (axis positions, reading + J) widened
    by :data:`core.volumetric.NODE_MARGIN_M` (the touches then lie :func:`_fit_holes`' 5 mm margin
    inside it; 30 mm until session 27, when the TYM diagonals' carriages, 60 mm beyond their
    tips in Y, came to be the ones checked), each less its offset."""
    from core.volumetric import NODE_MARGIN_M

    J, dJ = np.asarray(J_m, float), np.asarray(J_m, float) - np.asarray(J_ref_m, float)
    return {a: (max(strokes[a][0] - dJ[i], NODES_5AXIS[a][0] - NODE_MARGIN_M - J[i]),
                min(strokes[a][1] - dJ[i], NODES_5AXIS[a][-1] + NODE_MARGIN_M - J[i])) for i, a in enumerate("XYZ")}


@functools.lru_cache(maxsize=1)
def _nominal_bar():
    """The nominal bar (no deviations, :func:`sim.artefacts.multi_feature_bar`), one object per
    process: the plans are made on it (:func:`_fit_holes`), their program's margin is measured on
    its touches (:func:`placement_margin_m`) and their collision check runs on it
    (:func:`check_plan`). Building it costs 3 ms, its touch program 2.7 ms: they were built again by
    each of those three. Shared: its arrays are read only."""
    from sim import artefacts as A

    art = A.multi_feature_bar(deviations_m=np.zeros((12, 3)))
    for x in (art.T_W_A, *art.info.values()):
        if isinstance(x, np.ndarray):
            x.flags.writeable = False
    return art


def _fit_holes(T_R_A, reach, J_m, strokes=None, J_ref_m=None,
               prefer=((1, 8), (2, 9), (6, 11), (7, 12), (1, 10)), margin_m: float = 5.0e-3,
               stroke_margin_m: float = 1.0e-3) -> tuple:
    """Holes of a diagonal measurement: the longest of the plan's other hole
    runs (``prefer``, first, last; their extraction gains are computed once)
    whose touches and approach starts lie ``margin_m`` inside ``reach`` (readings)
    and, given ``strokes``, whose whole program at the default placement
    tolerance (touches, approach starts, overshoot ends, links:
    :func:`program_positions`) lies ``stroke_margin_m`` inside the strokes as
    axis positions (reading + ``J_m`` - ``J_ref_m``, the machine's reference tool;
    :func:`check_program_strokes`, session 26); else the longest run of
    consecutive reachable holes (at least 4)."""
    from sim import artefacts as A
    from core.exceptions import PlanError

    art = _nominal_bar()
    dJ = np.asarray(J_m, float) - np.asarray(J_m if J_ref_m is None else J_ref_m, float)
    ok = []
    for h in range(1, 13):
        pl = _plan_for(art, (h,))
        c = A.apply_T(T_R_A, pl.w_A + 3.0e-3 * pl.wn_A)
        c = np.vstack([c, c + pl.clearance_m * A.apply_R(T_R_A, pl.wn_A)])
        fit = all(np.all((c[:, j] >= reach[a][0] + margin_m) & (c[:, j] <= reach[a][1] - margin_m))
                  for j, a in enumerate("XYZ"))
        if fit and strokes is not None:
            q = np.concatenate(list(program_positions(T_R_A, _plan_for(art, (h,), **_program(U_PLACE)), 3.0e-3,
                                                      art).values())) + dJ
            fit = all(np.all((q[:, j] >= strokes[a][0] + stroke_margin_m) & (q[:, j] <= strokes[a][1] - stroke_margin_m))
                      for j, a in enumerate("XYZ"))
        ok.append(fit)
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


def plan_truth_spec(plan: str, machine: str | None, errors: str | None):
    """The truth machine ``--machine``/``--errors`` ask for on MFB plan ``plan`` (`vmt scenario`, `vmt simulate`),
    or None: the plan's own machine with the study's errors (naming it, or omitting both, is the same)."""
    if machine is None and errors is None:
        return None
    own = PLANS[plan]().machine
    if (machine or own) == own and (errors or "study") == "study":
        return None
    from sim.machinefile import truth_machine

    return truth_machine(machine or own, errors, "study")


#: Default placement uncertainty of a bar set by hand on the table (standard):
#: 0.2 mm along x_A, y_A, 0.1 mm along z_A; 0.5 mrad roll and pitch, 1 mrad yaw.
U_PLACE = (0.2e-3, 0.2e-3, 0.1e-3, 0.5e-3, 0.5e-3, 1.0e-3)

#: Re-placement uncertainty of the bar on the CMM between repeats of the reversal (standard,
#: :func:`reversal_on_cmm`): 0.1 mm along x, y, z; 0.5 mrad roll (about its axis: as on the
#: machine, :data:`U_PLACE`; a bar laid by hand on its supports, nothing in the set-up fixes it;
#: the CMM's alignment takes it out from the rods, :func:`core.mfb.align_on_cmm`), 0.2 mrad
#: pitch and yaw. Until session 31 the roll was 0 (review31b F1).
U_PLACE_CMM = (0.1e-3, 0.1e-3, 0.1e-3, 0.5e-3, 0.2e-3, 0.2e-3)

#: Default declared calibration uncertainty of the bar's 12 points (standard, um): x_A, y_A, z_A.
#: Half the paper's "average uncertainty 0.4 um and 0.7 um" (positioning, straightnesses): the paper
#: states no coverage factor; reading them as k = 2 is vmt's assumption (read as k = 1, u twice these:
#: seed 1's EXX U95 max 0.66 -> 1.22 um on the 3-axis plan, docs/papers-mfb.md, review31b F3).
U_CAL_UM = (0.2, 0.35, 0.35)


#: Thermal expansion of the machine's scales (steel ball screws and their encoders, cast
#: iron frame; not Invar), 1/degC: an assumption of the budget, the paper gives none.
MACHINE_CTE_PER_C = 11.5e-6


def thermal_scales(errs: dict, temperature_C: float) -> dict:
    """The machine's errors at ``temperature_C``: each linear axis' positioning error
    (EXX, EYY, EZZ) gains ``MACHINE_CTE_PER_C (T - 20) pos`` (its scale expands from
    the axis zero); the other errors are kept. Returns a new dict."""
    from sim.errorfuncs import Polynomial, Sum

    k = MACHINE_CTE_PER_C * (float(temperature_C) - 20.0)
    out = dict(errs)
    for s in ("EXX", "EYY", "EZZ"):
        ramp = Polynomial((0.0, k))
        out[s] = ramp if errs.get(s) is None else Sum((errs[s], ramp))
    return out


def bar_gauge(E_m) -> np.ndarray:
    """(12, 3) bar deviations in the reversal calibration's gauge: Exx from O_1, Eyx
    and Ezx against the line O_1 O_12 (what a rigid move of the bar changes; the MFB
    identification absorbs it in each set-up's pose)."""
    E = np.array(E_m, float)
    u = np.arange(len(E)) / (len(E) - 1)
    E[:, 0] -= E[0, 0]
    E[:, 1:] -= E[0, 1:] + np.outer(u, E[-1, 1:] - E[0, 1:])
    return E


def within_u95(errors: dict, cov=None, slices: dict | None = None, rng: np.random.Generator | None = None,
               draws: int = 4000) -> dict:
    """How many identified values lie within their U95 of the injected ones (values the
    conventions fix, U95 = 0, left out): ``{inside, total, text, errors_inside, errors_total}``,
    ``errors_inside`` counting the errors with every node within.

    The values are the nodes of 21 errors, and an error's nodes miss together (the bar's
    calibration, seen over its rods, moves a straightness everywhere at once): the count spreads far
    wider than 126 independent values would. With ``cov`` (n, n) the reported values' covariance
    (m^2, rad^2: the linear propagation in the report's gauge), ``slices`` ({symbol: slice} into it)
    and ``rng``: what the model expects of the same counts over ``draws`` joint normal draws of the
    errors, ``expected`` / ``errors_expected`` (means) and ``range95`` / ``errors_range95`` (2.5 and
    97.5 % points).
    """
    inside = total = e_in = e_tot = 0
    idx, U, group = [], [], []
    for s, e in errors.items():
        if e.get("u95") is None or e.get("injected") is None:
            continue
        u = np.asarray(e["u95"], float)
        dev = np.abs(np.asarray(e["identified"], float) - np.asarray(e["injected"], float))
        k = u > 1e-9
        inside += int(np.sum(dev[k] <= u[k]))
        total += int(np.sum(k))
        if k.any():
            e_in += int(np.all(dev[k] <= u[k]))
            e_tot += 1
        if cov is not None:
            idx.extend(np.arange(slices[s].start, slices[s].stop)[k])
            U.extend(u[k] * 1e-6)  # um / urad -> m / rad
            group.extend([e_tot - 1] * int(np.sum(k)))
    out = {"inside": inside, "total": total, "text": f"{inside}/{total}", "errors_inside": e_in, "errors_total": e_tot}
    if cov is not None and idx:
        C = np.asarray(cov, float)[np.ix_(idx, idx)]
        w, V = np.linalg.eigh(0.5 * (C + C.T))
        x = rng.standard_normal((int(draws), len(idx))) @ (V * np.sqrt(np.clip(w, 0.0, None))).T
        hit = np.abs(x) <= np.asarray(U)
        out_ = np.zeros((len(x), e_tot), int)  # per draw and error: nodes outside
        np.add.at(out_.T, np.asarray(group), (~hit).T)
        for key, n in (("", hit.sum(axis=1)), ("errors_", np.sum(out_ == 0, axis=1))):
            out[key + "expected"] = float(n.mean())
            out[key + "range95"] = [int(np.quantile(n, q, method="inverted_cdf")) for q in (0.025, 0.975)]
    return out


def _bar_doc(E_cal_m, u_cal_m, E_true_m, source: str, cal_map=None) -> dict:
    """The bar block of the result JSON: calibrated and true deviations of the points
    of interest in one gauge (:func:`bar_gauge`), um, U95 = 2 u. ``cal_map`` given
    (:func:`core.mfb.calibration_map`): ``u_cal_m`` is each point's own (the declared
    calibration, drawn through the map), and U95 is that of calibrated - true in the gauge:
    every point referred to O_1 (and O_12), an inner height's u 0.41-0.46 um for a declared
    0.35, the ends' 0. Without: ``u_cal_m`` is already in the gauge (a reversal's)."""
    from sim import artefacts as A

    cal, tru = bar_gauge(E_cal_m), bar_gauge(E_true_m)
    u = np.asarray(u_cal_m, float)
    if cal_map is not None:  # bar_gauge is linear: its matrix from the unit deviations
        G = np.column_stack([bar_gauge(e.reshape(u.shape)).ravel() for e in np.eye(u.size)])
        GM = G @ np.asarray(cal_map, float) * u.ravel()[None, :]
        u = np.sqrt(np.einsum("ij,ij->i", GM, GM)).reshape(u.shape)
    return {"source": source, "x_mm": (np.arange(12) * A.MFB_PITCH_M * 1e3).tolist(),
            "calibrated_um": (cal * 1e6).tolist(), "U95_um": (2.0 * u * 1e6).tolist(),
            "true_um": (tru * 1e6).tolist(), "calibrated_minus_true_max_um": float(np.abs(cal - tru).max() * 1e6),
            "gauge": "Exx from O_1; Eyx, Ezx against the line O_1 O_12 (a rigid move of the bar, absorbed by "
                     "each set-up's pose)"}


def default_machine(name: str, ripple: bool = False, J_m=(0.0, 0.0, 0.150)):
    """The realistic truth machine of a scenario (sim), ripple removed unless asked: the error set
    ``study`` (``realistic`` with the ripple) of :func:`sim.machinefile.truth_machine`, the rule every
    command's ``--errors`` follows, on the built-in machine with the probe offset ``J_m``."""
    from sim.machinefile import truth_machine
    from sim.machines import MACHINES

    errs = dict(truth_machine(name, "realistic" if ripple else "study").config.errors)
    return MACHINES[name](errors=errs, J_m=J_m), errs


#: Collision checks already made (a pure function of the nominal plan): keyed by the machine,
#: every measurement's name, set-up, holes, stylus (name, position), rotary positions, bar pose
#: and workholder (its sim.mfb_scene.Block objects: frozen, compared and hashed by value), the
#: stylus radius and the program's margin (before: without the poses and workholder, so a plan
#: of the same names with other fixtures got the first one's answer); the summaries are only
#: read (reports copy them into JSON). 64 checks
#: (before: unbounded; a few kilobytes each, a session checks a handful of plans).
_CHECKS = Memo(64)


def check_plan(plan: MfbPlan, stylus_r_m: float = 3.0e-3, u_place=U_PLACE) -> dict:
    """Collision and reach check of every measurement of a plan, its workholder included (MuJoCo).

    The program checked is the one :func:`run` simulates for the placement
    tolerance ``u_place`` (its approach margins, :func:`placement_margin_m`):
    a wider tolerance starts every touch further out, and that path is the
    one checked.

    Each measurement's touches, approach/retract and link moves are checked
    in :class:`sim.mfb_scene.WorkZone` (table, workholder, bar and its
    supports; stylus ball, star arm, extension, probe body, spindle) at the
    set-up's rotary positions, the workholder blocks against the bar and its
    supports (:func:`sim.mfb_scene.block_overlaps`: a block running into them
    is a collision; a foot on a block's face is not), and the touches
    against the strokes of the readings. Returns the summary for the report (``passed``, per
    measurement: set-up, stylus, holes, touches, path points, collisions,
    least clearance of the probe from the table side at the approach starts).

    Raises
    ------
    PlanError
        A collision, the bar below the table face, a workholder block running
        into the bar or a support, or a touch outside a stroke
        (measurement and what hits what named).
    """
    from core.exceptions import PlanError
    from sim import artefacts as A
    from sim.machine import nominal_T_R_W
    from sim.machines import MACHINES
    from sim.mfb_scene import TABLE_R_M, TABLE_T_M, check_measurements

    program = _program(u_place)  # the program run() simulates for this placement tolerance
    # (every input of the check: a plan of the same names with other poses or fixtures is another plan)
    key = (plan.machine, tuple((m.name, m.setup_key, m.holes, m.J_m, m.stylus, tuple(m.rot_rad),
                                np.asarray(m.T_W_A, float).tobytes(), tuple(plan.fixtures.get(m.placement, ())))
                               for m in plan.measurements), stylus_r_m, program["clearance_m"], program["overshoot_m"])
    hit = _CHECKS.get(key)
    if hit is not None:
        return hit
    t0 = time.time()
    cfg = MACHINES[plan.machine]()  # nominal: its table poses need no Machine (sim.machine.nominal_T_R_W)
    art = _nominal_bar()
    per, n_t, n_s, todo, programs = {}, 0, 0, [], {}
    # the table pose of every set-up in one call (measurements share them; row by row the
    # numbers of one call per set-up: every operation of the nominal product is per row)
    rots = list(dict.fromkeys(tuple(ms.rot_rad) for ms in plan.measurements))
    if rots and len(rots[0]):
        poses = np.asarray(nominal_T_R_W(cfg, np.asarray(rots, float)), float).reshape(-1, 4, 4)
    else:
        poses = np.asarray(nominal_T_R_W(cfg, None), float).reshape(-1, 4, 4)[[0] * len(rots)]
    poses.flags.writeable = False  # shared: read only
    table_poses = dict(zip(rots, poses))
    for ms in plan.measurements:
        T_R_W = table_poses[tuple(ms.rot_rad)]
        pl = programs.get(ms.holes)  # (one per set of holes: measurements share them, read only)
        if pl is None:
            pl = programs[ms.holes] = _plan_for(art, ms.holes, **program)
        todo.append((ms.name, ms.T_W_A, T_R_W, plan.fixtures.get(ms.placement, ()), ms.J_m, pl,
                     FINGERS.get(ms.stylus, 0.0)))
    # every measurement's paths at once (sim.mfb_scene.check_measurements), then in order
    for ms, (_, _, T_R_W, _, _, pl, _), r in zip(plan.measurements, todo, check_measurements(art, todo, stylus_r_m)):
        if not r.ok:
            raise PlanError(f"measurement {ms.name!r} ({ms.setup_key}, {ms.stylus}): {r.collisions[0]}")
        c = r.contacts_R  # (the check's own: apply_T(T_R_W @ T_W_A, w_A + r wn_A), the same numbers)
        if c is None:
            c = A.apply_T(T_R_W @ ms.T_W_A, pl.w_A + stylus_r_m * pl.wn_A)
        c_lo, c_hi = _column_range(c)  # (the touches' range per axis)
        # (the program's positions as the check computed them: program_positions' arrays, the same
        # expressions on the same operands, so the same numbers; tests/scenarios/test_mfb_strokes.py)
        pos = r.positions_R
        if pos is None:
            pos = program_positions(T_R_W @ ms.T_W_A, pl, stylus_r_m, art)
        q_lo, q_hi = check_program_strokes(ms.name, pos, ms.J_m, cfg.J_m, cfg.strokes)
        per[ms.name] = {"placement": ms.placement, "setup": ms.setup_key, "stylus": ms.stylus,
                        "J_mm": [round(v / MM, 3) for v in ms.J_m], "holes": list(ms.holes),
                        "touches": r.touches, "path_points": r.samples, "collisions": len(r.collisions),
                        "min_clearance_at_approach_starts_mm": round(r.min_table_clearance_mm, 2),
                        "touch_range_mm": {ax: [round(c_lo[j] / MM, 1), round(c_hi[j] / MM, 1)]
                                           for j, ax in enumerate("XYZ")},
                        "axis_range_mm": {ax: [round(q_lo[j] / MM, 1), round(q_hi[j] / MM, 1)]
                                          for j, ax in enumerate("XYZ")}}
        n_t += r.touches
        n_s += r.samples
    out = {"passed": True, "engine": "MuJoCo (sim.mfb_scene.WorkZone)",
           "checked": "table disc (R %g mm, %g mm thick), workholder blocks, bar and its supports vs stylus ball, "
                      "star arm, extension, probe body, spindle nose; approach/retract and link moves; the bar "
                      "above the table face; the workholder blocks clear of the bar and its supports "
                      "(separating axes, a support or rod as its square prism); every touch, approach start, overshoot end and "
                      "link point within the strokes as axis positions (reading + J - the machine's J: "
                      "check_program_strokes)" % (TABLE_R_M / MM, TABLE_T_M / MM),
           "touches": n_t, "path_points": n_s, "seconds": round(time.time() - t0, 1), "measurements": per,
           "program_mm": {"clearance": round(program["clearance_m"] / MM, 3),
                          "overshoot": round(program["overshoot_m"] / MM, 3)},
           "fixtures": {p: [{"name": b.name, "lo_mm": [v / MM for v in b.lo], "hi_mm": [v / MM for v in b.hi]}
                            for b in bl] for p, bl in plan.fixtures.items()}}
    _CHECKS[key] = out
    return out


def _column_range(c: np.ndarray) -> tuple[list, list]:
    """(least, largest) of each column of ``c`` (n,3), lists: ``c.min(axis=0)``, ``c.max(axis=0)``.

    By one ``reduceat`` over the rows (3 us against 18 us a call on the 5-axis plan's (280,3)
    contacts: numpy reduces along a first axis of 3 columns slowly). The least or largest of
    floats is one of them, the same whatever the order of the comparisons, but for two zeros of
    different sign or a NaN: a column whose answer is zero or NaN (and an empty ``c``) takes the
    expression itself, so the answer is its, bit for bit."""
    if len(c):
        lo = np.minimum.reduceat(c, _ROW0, axis=0)[0].tolist()
        hi = np.maximum.reduceat(c, _ROW0, axis=0)[0].tolist()
        v = lo + hi
        if 0.0 not in v and all(map(float.__eq__, v, v)):  # (no zero, no NaN: a NaN is not equal to itself)
            return lo, hi
    return c.min(axis=0).tolist(), c.max(axis=0).tolist()


#: :func:`_column_range`'s one slice (every row).
_ROW0 = np.zeros(1, np.intp)


def describe_collision_check(c: dict) -> str:
    """The collision check's summary for the terminal: one line per placement, then the verdict."""
    by = {}
    for name, m in c["measurements"].items():
        rot = m["setup"].partition("@")[2]  # (the rotary positions of a 5-axis set-up; none on a 3-axis plan)
        by.setdefault(m["placement"], []).append(f"{name}({rot + ', ' if rot else ''}{m['stylus']})")
    lines = [f"  {p}: {', '.join(v)}" for p, v in by.items()]
    lines.append(f"collision check ({c['engine']}): {'passed' if c['passed'] else 'FAILED'}, "
                 f"{c['touches']} touches, {c['path_points']} path points, {c['seconds']} s")
    return "\n".join(lines)


#: The extraction's gains already computed (pure functions of the nominal plan): keyed by the
#: touches' targets, features, points and normals (bytes) and the stylus radius; read-only
#: arrays. 64 gains (before: oldest dropped at 64).
_GAINS = Memo(64)


def _noise_gain(pl_ok, r_m, fits=None, full=None):
    """:func:`core.mfb.poi_noise_gain` of the touches ``pl_ok`` (a plan's nominal
    geometry and stylus radius only), kept for the next run of the same plan
    (the same for every campaign of it). ``fits``:
    the light fits of the run's other hole sets (``fits`` of :func:`core.mfb.poi_noise_gain`).

    ``full``: the bar's whole program (:func:`sim.plans.mfb_plan`) when ``pl_ok`` is a part of it
    made of whole features (:func:`_plan_for`): the whole program's gain is computed once (and
    kept) and ``pl_ok``'s is its rows of ``pl_ok``'s holes and columns of its touches (:func:`_part_of`:
    a point of interest depends only on its hole's and its two rods' touches; the same numbers
    bit for bit, tests/scenarios/test_mfb_scenario.py)."""
    from core import mfb

    def gain():
        part = None if full is None else _part_of(full, pl_ok)
        if part is not None:
            rows, cols = part
            G = _noise_gain(full, r_m, fits)[rows][:, cols]
        else:
            G = mfb.poi_noise_gain(pl_ok.w_A + r_m * pl_ok.wn_A, pl_ok.feature, pl_ok.wn_A, -pl_ok.wn_A, fits=fits)
        G.setflags(write=False)  # shared between runs: read only
        return G

    key = (tuple(pl_ok.target), tuple(pl_ok.feature), pl_ok.w_A.tobytes(), pl_ok.wn_A.tobytes(), float(r_m))
    return _GAINS.get_or_compute(key, gain)


def _part_of(full, pl) -> tuple | None:
    """(rows, cols): where the gain of the plan ``pl`` stands in the gain of ``full`` (rows of
    its holes' points of interest, columns of its touches), or None unless ``pl`` is a part of
    ``full`` its gain can be cut from: each of its features with all of ``full``'s touches of
    it at the same places, and each of its holes' plane PL_i through the rods ``full`` uses."""
    from core import mfb
    from core.exceptions import FitError

    at = {t: k for k, t in enumerate(full.target)}
    if any(t not in at for t in pl.target):
        return None
    cols = np.array([at[t] for t in pl.target], int)
    f_full = np.asarray(full.feature, object)
    if not (np.array_equal(pl.w_A, full.w_A[cols]) and np.array_equal(pl.wn_A, full.wn_A[cols])
            and all(np.count_nonzero(f_full == f) == n
                    for f, n in zip(*np.unique(np.asarray(pl.feature, object), return_counts=True)))):
        return None

    def holes_rods(features):
        holes = sorted({int(f[4:]) for f in features if f.startswith("hole")})
        return holes, {int(f[3:]) for f in features if f.startswith("rod")}

    (h_full, r_full), (h_pl, r_pl) = holes_rods(full.feature), holes_rods(pl.feature)
    try:
        if any(mfb._rod_pair(i, r_pl) != mfb._rod_pair(i, r_full) for i in h_pl):
            return None
    except FitError:  # a hole without its two rods: the gain's own error, raised from the plan itself
        return None
    row = {h: k for k, h in enumerate(h_full)}
    return np.concatenate([np.arange(3 * row[h], 3 * row[h] + 3) for h in h_pl]), cols


def program_positions(T_R_A, pl, stylus_r_m: float, art=None) -> dict:
    """Every position a measurement's program commands, in readings (R, m): kind -> (k, 3).

    ``touches`` (the nominal stylus-centre contacts), ``approach starts`` (``clearance_m`` out
    along the normal), ``overshoot ends`` (``overshoot_m`` past the contact: where a touch that
    never triggers stops) and ``links`` (the moves between consecutive starts that
    :func:`check_plan` checks for collisions, :func:`sim.mfb_scene.link_points`: along the
    feature's level, else out to 10 mm beyond the bar's top along z_A, across and back)."""
    from sim import artefacts as A
    from sim.mfb_scene import link_points
    from sim.scene import artefact_points

    art = _nominal_bar() if art is None else art
    r = float(stylus_r_m)
    Xn = A.apply_T(T_R_A, pl.w_A + r * pl.wn_A)
    n_R = A.apply_R(T_R_A, pl.wn_A)
    start = Xn + pl.clearance_m * n_R
    out = {"touches": Xn, "approach starts": start, "overshoot ends": Xn - pl.overshoot_m * n_R}
    if pl.n > 1:
        top = float(artefact_points(art)[:, 2].max()) + r
        out["links"] = link_points(T_R_A, start, pl.feature, pl.level, top)[0]
    return out


def measurement_programs(plan: MfbPlan, cfg, u_place=U_PLACE):
    """Each measurement of ``plan`` with its nominal frame and program on the machine ``cfg``: yields
    ``(ms, T_R_W, pl, art)``, the measurement, the nominal table frame at its rotary positions
    (:func:`sim.machine.nominal_T_R_W`), its touch plan at ``u_place``'s margins and the nominal bar
    (one object for every measurement)."""
    from sim.machine import nominal_T_R_W

    art, program = _nominal_bar(), _program(u_place)
    for ms in plan.measurements:
        rot = np.asarray([ms.rot_rad], float) if len(ms.rot_rad) else None
        T_R_W = np.asarray(nominal_T_R_W(cfg, rot), float).reshape(-1, 4, 4)[0]
        yield ms, T_R_W, _plan_for(art, ms.holes, **program), art


def check_plan_strokes(plan: MfbPlan, cfg, stylus_r_m: float = 3.0e-3, u_place=U_PLACE) -> None:
    """:func:`check_program_strokes` of every measurement of ``plan`` on the machine ``cfg`` (a
    :class:`sim.machine.MachineConfig`: its strokes, its tool's offsets ``J_m`` the reference),
    the program at ``u_place``'s margins: what :func:`check_plan` checks on the plan's built-in
    machine, for another machine file of the same chain (``run(machine=...)``)."""
    for ms, T_R_W, pl, art in measurement_programs(plan, cfg, u_place):
        check_program_strokes(ms.name, program_positions(T_R_W @ ms.T_W_A, pl, stylus_r_m, art), ms.J_m,
                              cfg.J_m, cfg.strokes)


def check_program_strokes(name: str, positions: dict, J_m, J_ref_m, strokes) -> tuple:
    """PlanError unless every commanded position lies within the machine's linear strokes as an
    axis position: the stroke limits the axis (the carriage and spindle gauge point), as a
    controller's soft limits do, stated for the machine's reference tool (its file's
    ``[tool] offset_mm``, ``J_ref_m``); a reading with the offsets ``J_m`` puts the axis at
    ``q = reading + J_m - J_ref_m`` in those terms (docs/formats.md, "Strokes").

    ``positions``: kind -> (k, 3) readings (:func:`program_positions`). Returns the axis
    positions' (least, largest) per axis (lists, m). The rule is :func:`sim.campaign.first_outside_stroke`'s;
    the error names the measurement, the kind of position, the axis, the first such position out
    (kinds in ``positions``' order) and its excess."""
    from core.exceptions import PlanError
    from sim.campaign import first_outside_stroke

    dJ = np.asarray(J_m, float) - np.asarray(J_ref_m, float)
    # every kind's positions in one pass when none is beyond a stroke: the least and largest of
    # floats are the same numbers whatever the grouping (but for a zero's sign or a NaN: then, or
    # when a position is beyond a stroke, the rule below, sim.campaign.first_outside_stroke, which
    # names the first in its order). A stroke's excess rises with the position (rounding is monotone), so the largest position's
    # excess is above 1e-9 exactly when one of the kinds' is
    qs = [P for P in positions.values() if len(P)]
    if qs:
        q = (np.concatenate(qs) if len(qs) > 1 else np.asarray(qs[0], float)) + dJ
        lo_all, hi_all = _column_range(q)
        v = lo_all + hi_all
        if (0.0 not in v and all(map(float.__eq__, v, v))
                and all(hi_all[j] - strokes[ax][1] <= 1e-9 and strokes[ax][0] - lo_all[j] <= 1e-9
                        for j, ax in enumerate("XYZ"))):
            return lo_all, hi_all
    q = {kind: np.asarray(P, float).reshape(-1, 3) + dJ for kind, P in positions.items()}
    for kind, qk in q.items():
        if not np.isfinite(qk).all():
            raise PlanError(f"measurement {name!r}: a position at its {kind} is not a finite number")
        if (hit := first_outside_stroke(qk, strokes)) is not None:
            _, j, v, lim, over = hit
            raise PlanError(f"measurement {name!r}: axis {'XYZ'[j]} at {v / MM:.1f} mm at its {kind} "
                            f"(reading + J - the machine's J), {over / MM:.1f} mm beyond its stroke's "
                            f"{lim / MM:g} mm")
    qa = np.concatenate(list(q.values()) or [np.empty((0, 3))])
    if not len(qa):
        return [np.inf] * 3, [-np.inf] * 3
    return qa.min(axis=0).tolist(), qa.max(axis=0).tolist()


#: _declared_poi_deviations's answers by the declared deviations' bytes (a pure function of them:
#: every run with the declared calibration asks the same). Read-only (12, 3) arrays. 4 entries.
_DECLARED_POI = Memo(4)


def _declared_poi_deviations(E_cal) -> np.ndarray:
    """(12, 3) deviations of the points of interest the declared bar deviations ``E_cal`` give, m:
    Exx, Eyx as declared, Ezx through the rods (:func:`sim.artefacts.multi_feature_bar`'s
    ``E_MFB_m``); kept per ``E_cal`` (:data:`_DECLARED_POI`: building the bar for it took a
    tenth of a budget run's simulation)."""
    from sim import artefacts as A

    E_cal = np.asarray(E_cal, float)

    def compute():
        out = np.column_stack([E_cal[:, :2], A.multi_feature_bar(deviations_m=E_cal).info["E_MFB_m"][:, 2]])
        out.flags.writeable = False
        return out

    return _DECLARED_POI.get_or_compute(E_cal.tobytes(), compute)


#: Coverage factor of the MFB program's approach margins against the placement
#: tolerance (:func:`placement_margin_m`).
PLACEMENT_MARGIN_K = 5.0


#: placement_margin_m's answers by (u_place, k): a pure function of them, asked by every run
#: and every check (it builds the nominal bar and its full plan). Floats. 64 (before: cleared at 64).
_MARGINS = Memo(64)


def placement_margin_m(u_place=U_PLACE, k: float = PLACEMENT_MARGIN_K) -> float:
    """Approach margin of the MFB program for a bar placed within ``u_place``, m.

    A placement error (translation t, small rotation w, :data:`U_PLACE`)
    moves the bar's surface point w_A along its normal n by t.n + w.(w_A x n).
    The program (start ``clearance_m`` before the nominal surface, search
    ``overshoot_m`` beyond it) must cover that for every touch of the full
    bar: the largest ``k`` standard deviations of it, rounded up to 0.5 mm,
    and at least the plan's 2 mm clearance / 3 mm overshoot. With
    :data:`U_PLACE` the far end's face touches (550 mm from O_1, approached
    along y_A) give sqrt(0.2^2 + (1 mrad x 550 mm)^2) = 0.585 mm per sigma:
    2.93 mm at k = 5, so 3.0 mm. (A 2 mm clearance, 3.4 sigma there, let about
    one Monte Carlo run in 25 start a face touch inside the bar: seed 23 of
    the 3-axis budget.)

    Kept per (``u_place``, ``k``) (:data:`_MARGINS`). Measured on the nominal bar's touches as the
    plans were made (:func:`_nominal_bar`, :func:`_plan_for`'s margins: a plan's points and normals
    do not depend on its margins).
    """
    from sim.plans import mfb_plan

    u = np.asarray(u_place, float)
    if u.shape != (6,) or not np.all(np.isfinite(u) & (u >= 0)):
        from core.exceptions import ConfigError

        raise ConfigError(f"u_place must be 6 standard deviations >= 0 (m, m, m, rad, rad, rad), got {u_place!r}")
    def margin():
        pl = mfb_plan(_nominal_bar(), clearance_m=2.0 * MM, overshoot_m=3.0 * MM)
        s = np.sqrt(((u[:3] * pl.wn_A) ** 2).sum(axis=1) + ((u[3:] * np.cross(pl.w_A, pl.wn_A)) ** 2).sum(axis=1))
        return float(np.ceil(k * s.max() / (0.5 * MM) - 1e-9) * 0.5 * MM)

    return _MARGINS.get_or_compute((u.tobytes(), float(k)), margin)


def _program(u_place) -> dict:
    """The MFB program's approach for a placement tolerance: ``clearance_m`` before the nominal
    surface and ``overshoot_m`` beyond it (:func:`sim.plans.mfb_plan`), the plan's 2 / 3 mm or the
    placement margin (:func:`placement_margin_m`) if larger. What :func:`run` simulates and
    :func:`check_plan` checks."""
    margin = placement_margin_m(u_place)
    return {"clearance_m": max(2.0 * MM, margin), "overshoot_m": max(3.0 * MM, margin)}


def _check_touches_ok(log, name, program):
    """Every touch of an MFB measurement must trigger on its target: a touch that
    starts inside the bar (``early_trigger``: on a machine, the probe strikes the
    bar on its way in) or meets nothing (``no_trigger``) means the bar as placed
    lies beyond the program's margins; the fit must not quietly go on without it."""
    from core.exceptions import PlanError

    st = np.asarray(log.col("status"), object)
    bad = np.flatnonzero(st != "ok")
    if bad.size:
        feats = sorted({str(log.col("feature")[i]) for i in bad})
        kinds = sorted({str(st[i]) for i in bad})
        raise PlanError(f"measurement {name!r}: {bad.size} touches {'/'.join(kinds)} on {', '.join(feats)}: the "
                        f"bar as placed lies beyond the program's approach margins (clearance "
                        f"{program['clearance_m'] / MM:g} mm, overshoot {program['overshoot_m'] / MM:g} mm)")


def _plan_for(art, holes, overshoot_m=3.0 * MM, clearance_m=2.0 * MM):
    """The touches of ``holes`` of the bar ``art`` (and of the rods and faces their planes need),
    selected from its full program (:func:`sim.plans.mfb_plan` with these margins, kept per bar)."""
    from sim.plans import mfb_plan

    full = mfb_plan(art, clearance_m=clearance_m, overshoot_m=overshoot_m)
    # the rods each probed hole's plane PL_i needs: (i-1, i); (1, 2) for hole 1, (10, 11) for
    # hole 12 alone (core.mfb._rod_pair)
    lo, hi = min(holes), max(holes)
    rods = set(range(max(lo - 1, 1), min(hi, 11) + 1))
    if len(rods) < 2:
        rods = {lo, lo + 1} if lo < 11 else {10, 11}
    # by name (sim.plans.mfb_plan's features: holeNN, rodNN, faceLNN, faceRNN): one set look-up a
    # touch instead of parsing its number (0.22 -> 0.11 ms a measurement, selection included)
    want = {_feature_name("hole", h) for h in holes} | {_feature_name(k, r) for r in rods
                                                       for k in ("rod", "faceL", "faceR")}
    # (the rows whose feature is wanted, in order: each row's feature as a number, kept per program
    # (_feature_codes), looked up in a table of the wanted numbers; 22 -> 6 us a selection)
    num, codes = _feature_codes(full)
    lut = np.zeros(len(num), bool)
    lut[[num[f] for f in want if f in num]] = True
    return full.select(np.flatnonzero(lut.take(codes)))


#: The bar's feature names by (kind, number): :func:`_feature_name`'s (f"{kind}{number:02d}"), written once.
_FEATURE_NAMES = {(k, i): f"{k}{i:02d}" for k in ("hole", "rod", "faceL", "faceR") for i in range(1, 100)}


def _feature_name(kind: str, i: int) -> str:
    """f"{kind}{i:02d}" (:func:`sim.plans.mfb_plan`'s feature names), from :data:`_FEATURE_NAMES`
    when it holds it (one look-up instead of formatting: 16 -> 5 us a selection's names)."""
    return _FEATURE_NAMES.get((kind, i)) or f"{kind}{i:02d}"


#: Per touch program object (:func:`sim.plans.mfb_plan`'s, kept in the entry and checked with ``is``):
#: (feature -> number in order of first row, each row's number (n,) int) for :func:`_plan_for`'s
#: selections. Safe: a function of the program's features (a frozen tuple); read only. 64 programs.
_FEATURE_CODES = Memo(64)


def _feature_codes(full) -> tuple:
    """(feature -> number, each row's feature number (n,) int) of the program ``full`` (kept)."""
    def build():
        num = {}
        codes = np.fromiter((num.setdefault(f, len(num)) for f in full.feature), np.intp, full.n)
        codes.flags.writeable = False
        return num, codes

    return _FEATURE_CODES.get_or_compute(id(full), build, owner=full)


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
    #: axis -> (min, max) axis positions (reading + J, m) the truth machine's strokes reach
    #: (``strokes`` + its ``J_m``): where the compensation files run beyond the node box (review29b F1)
    strokes_m: dict = field(default=None, compare=False)
    #: the truth machine's probe offset J (reading = axis position - J), m: where the per-axis files are exact
    #: (:func:`describe_comp_line`)
    J_m: tuple = field(default=None, compare=False)
    #: the simulated campaign as a probe log would hold it (:func:`campaign_log` writes it): each measurement's
    #: simulated log (``sim.campaign.simulate_measurements``) and what the identification was given beside the
    #: touches (``E_cal_m``, ``u_cal_m`` (12, 3) the bar's calibration at its points of interest, ``dJ_m``
    #: {stylus: (3,)} the styli's calibration errors added to their readings, ``rotary_points_R_m``, ``sigma_m``)
    campaign: dict = field(default=None, compare=False, repr=False)

    def write_comp(self, directory, line_m=None) -> list:
        """Write the LinuxCNC per-axis compensation files and the vmt JSON tables.

        ``<dir>/<X|Y|Z>.comp`` (``[JOINT_n] COMP_FILE``, ``COMP_FILE_TYPE =
        0``: nominal, actual forward, actual reverse in mm, every 5 mm along
        the table by its C2 spline, :func:`hardware.linuxcnc.comp_file`),
        indexed by the joint position (reading + J, as the tables are), and
        ``<dir>/<scenario>-comp.json`` (``vmt-comp/1``,
        :func:`core.volumetric.tables_json`). Returns the paths written.

        Each error is applied at the fraction that leaves the least
        mean-square error against its uncertainty (:func:`compensation_plan`,
        :func:`core.comprule.select_terms`; 0: left out): the ``.comp`` files
        carry the positioning tables so scaled; the JSON keeps the identified
        values with ``applied_factor`` and the decision's figures per error
        (controllers apply ``applied_factor`` times the table,
        :func:`core.volumetric.comp_tables`), the rule, and the residual
        predicted over the node box with its U95.

        ``line_m`` (3,) readings, m (``vmt scenario --comp-line-mm``): each ``.comp`` file carries its axis's
        error along the line through this point instead (X.comp along X at its Y and Z, ...; each file's
        own axis's entry unused; :func:`comp_line_tables`), exact there; the JSON gets ``per_axis_line``
        and its ``predicted_residual.per_axis_files`` is of those tables. Default: ``E<a><a>``, the line
        through readings 0 (:func:`describe_comp_line`).
        """
        import json
        from dataclasses import replace as _rep
        from pathlib import Path

        from core import volumetric as vol
        from core.atomic import write_text_atomic
        from hardware.linuxcnc import comp_file

        plan = compensation_plan(self, line_m)
        dec = plan["terms"]
        res, slopes = self.result, dict(self.slopes or {})
        theta = np.array(res.theta, float)
        for s, d in dec.items():
            theta[res.design.slices[s]] *= d["factor"]
            if s in slopes:
                slopes[s] *= d["factor"]
        res_applied = _rep(res, theta=theta)
        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        out = []
        strokes = self.strokes_m or {}
        errors = {} if line_m is None else comp_line_tables(self, line_m, plan["terms"])
        for a in ("X", "Y", "Z"):
            out.append(write_text_atomic(d / f"{a}.comp", comp_file(res_applied, a, step_m=0.005,
                                                                     range_m=strokes.get(a), error=errors.get(a))))
        doc = json.loads(vol.tables_json(self.result, self.unc, self.slopes))
        doc.update(compensation_range(self.plan.nodes, strokes))
        for s, e in doc["errors"].items():
            e["applied_factor"] = dec[s]["factor"]
            e["decision"] = {k: v for k, v in dec[s].items() if k != "factor"}
        doc["applied_rule"] = plan["rule"]
        doc["predicted_residual"] = plan["predicted_residual"]
        if line_m is not None:
            doc["per_axis_line"] = comp_line_doc(line_m)
        if nc := rotary_not_compensated(res.chain):   # the rotary axes: none of their errors is in the tables
            doc["not_compensated"] = nc
        out.append(write_text_atomic(d / f"{self.doc['scenario']}-comp.json", json.dumps(doc, indent=1)))
        return [Path(p) for p in out]


def compensation_range(nodes, strokes_m: dict | None) -> dict:
    """The range statement of a compensation's JSON (review29b F1): ``compensated_range_mm`` (axis ->
    [first node, last node], axis positions, mm: where the tables were measured), ``strokes_mm`` (axis ->
    the machine's strokes as axis positions, mm, when known) and ``extrapolation`` (:data:`COMP_EXTRAPOLATION`;
    without strokes the files stop at the end nodes and LinuxCNC holds their end values)."""
    out = {"compensated_range_mm": {a: [float(nodes[a][0]) * 1e3, float(nodes[a][-1]) * 1e3] for a in "XYZ"}}
    if strokes_m:
        out["strokes_mm"] = {a: [v * 1e3 for v in strokes_m[a]] for a in "XYZ"}
        out["extrapolation"] = COMP_EXTRAPOLATION
    return out


def describe_compensation_range(doc: dict) -> str:
    """One line of the run's output: the compensated range per axis, and that beyond it the
    correction is an extrapolation (``doc``: :func:`compensation_range`'s keys)."""
    cr, st = doc["compensated_range_mm"], doc.get("strokes_mm")
    ax = ", ".join(f"{a} {cr[a][0]:.0f}..{cr[a][1]:.0f}" + (f" of stroke {st[a][0]:.0f}..{st[a][1]:.0f}" if st else "")
                   for a in "XYZ")
    tail = ("outside it the correction is an extrapolation along the tables' end tangents (the .comp files and "
            "the JSON alike)" if st else "outside it LinuxCNC holds the files' end values")
    return f"compensated range (the node box, axis positions, mm): {ax}; {tail}"


#: What the run prints when it writes ``.comp`` files (review32a F2): how LinuxCNC takes them.
COMP_FILES_REPLACE = ("the .comp files replace each joint's BACKLASH and any earlier COMP_FILE in LinuxCNC (one "
                      "table per joint; BACKLASH is not used with a COMP_FILE) and carry no lost motion (forward = "
                      "reverse): they are right for a machine measured with both off; an identification made with "
                      "a table loaded measured its residual, to be added to that table, not loaded in its place "
                      "(README, 'Compensation files')")


def describe_comp_line(nodes, J_m, point_m=None) -> str:
    """Where the per-axis ``.comp`` files are exact (review32a F4). By default each carries its axis's
    positioning error ``E<a><a>`` of vmt's model, the error on the line through readings 0 of the other two
    axes (zero Abbe arms); with ``point_m`` (3,) readings, m (``--comp-line-mm``) the error along the lines
    through that point (:func:`comp_line_tables`). Elsewhere the angular errors' Abbe terms (and the other
    axes' errors that vary across the lines) stay. ``nodes``: axis -> node positions (axis positions, m);
    ``J_m``: the machine's probe offset (reading = axis position - J). Says which lines miss the node box,
    and the box's centre in readings (a line through it: ``--comp-line-mm``)."""
    J = np.asarray(J_m, float)
    pt = np.zeros(3) if point_m is None else np.asarray(point_m, float)
    box = {a: (float(nodes[a][0]) - J[i], float(nodes[a][-1]) - J[i]) for i, a in enumerate("XYZ")}
    out = []
    for a in "XYZ":
        others = [b for b in "XYZ" if b != a]
        miss = [b for b in others if not box[b][0] - 1e-9 <= pt["XYZ".index(b)] <= box[b][1] + 1e-9]
        where = (" outside the node box (" + ", ".join(f"{b} readings {box[b][0] * 1e3:.0f}..{box[b][1] * 1e3:.0f} "
                                                          "mm" for b in miss) + ")") if miss else ""
        if point_m is None:
            out.append(f"{a}.comp on {' = '.join(others)} = 0{where}")
        else:
            out.append(f"{a}.comp on " + ", ".join(f"{b} = {pt['XYZ'.index(b)] * 1e3:g}" for b in others) + where)
    centre = ",".join(f"{(box[a][0] + box[a][1]) / 2 * 1e3:g}" for a in "XYZ")
    head = ("the per-axis .comp files are right only on their axis's line through readings 0 of the other axes "
            "(zero Abbe arms): " if point_m is None else
            "the per-axis .comp files carry each axis's error along its line through the readings "
            + ",".join(f"{v * 1e3:g}" for v in pt) + " mm (--comp-line-mm), right only there: ")
    return (head + "; ".join(out) + "; elsewhere the errors that depend on the other axes' positions remain (the "
            "angular errors' Abbe terms: the vmt-comp/1 JSON corrects them volumetrically; closed_loop measures "
            f"what the files leave); the node box's centre is at readings {centre} mm (--comp-line-mm X,Y,Z "
            "chooses the lines' point)")


def _node_box(nodes) -> np.ndarray:
    """The plan's node box: every (x, y, z) of the X, Y, Z nodes, (n, 3) m."""
    gx, gy, gz = (np.asarray(nodes[a], float) for a in "XYZ")
    return np.stack(np.meshgrid(gx, gy, gz, indexing="ij"), axis=-1).reshape(-1, 3)


def _prediction(r: "ScenarioResult", factors: dict, line_m=None) -> dict:
    """What compensating ``factors`` (symbol -> fraction applied) of ``r``'s estimate is predicted to
    leave over ``r``'s node box (:func:`core.comprule.predicted_residual`, stylus :data:`COMP_STYLUS`,
    a rigid motion removed): ``residual``, ``U95``, ``U95_added``, each (n, 3) m. ``line_m``: the
    compensation is per-axis tables on the lines through that point (readings, m; :func:`comp_line_tables`):
    each point gets each table's value at its axis position, along that axis only."""
    from core.comprule import line_map, predicted_residual, rigid_projected, tip_map
    from core.state import loads_estimate

    state = loads_estimate(r.doc["estimate"])
    J = np.asarray(STYLI[COMP_STYLUS], float)  # the node box is of axis positions: the readings are less J
    P = _node_box(r.plan.nodes) - J
    G = tip_map(state, r.result.chain, P, J, r.result.rotary_points_R_m)
    if line_m is None:
        return predicted_residual(state, factors, G)
    A = np.zeros_like(G)
    for i, a in enumerate("XYZ"):
        x, where = np.unique(P[:, i] + J[i], return_inverse=True)
        A[i::3] = line_map(state, r.result.chain, a, x, line_m, J, r.result.rotary_points_R_m,
                           ref_m=float(r.plan.nodes[a][0]))[where]
    return predicted_residual(state, factors, G, applied=rigid_projected(A, P))


def comp_line_tables(r: "ScenarioResult", line_m, terms: dict | None = None) -> dict:
    """axis -> ``error(x)`` for :func:`hardware.linuxcnc.comp_file`: the axis's error along its line through
    ``line_m`` (3,) readings of the stylus :data:`COMP_STYLUS`, m (:func:`core.comprule.line_table`), of
    the part of ``r``'s estimate the compensation applies (``terms``: :func:`compensation_plan`'s), zero at
    the axis's first node (the identified positioning error's gauge). Exact on the line to the chain's
    second order; at readings 0 it is ``E<a><a>``, the default files' table."""
    from core.comprule import line_table
    from core.state import loads_estimate

    state = loads_estimate(r.doc["estimate"])
    terms = compensation_plan(r)["terms"] if terms is None else terms
    factors = {s: d["factor"] for s, d in terms.items()}
    J = tuple(STYLI[COMP_STYLUS])
    pt = np.asarray(line_m, float)

    def table(a):
        return lambda x: line_table(state, factors, r.result.chain, a, x, pt, J, r.result.rotary_points_R_m,
                                    ref_m=float(r.plan.nodes[a][0]))
    return {a: table(a) for a in "XYZ"}


def comp_line_doc(line_m) -> dict:
    """The compensation JSON's ``per_axis_line`` (``vmt scenario --comp-line-mm``): where the ``.comp`` files
    are exact."""
    return {"readings_mm": [float(v) * 1e3 for v in line_m], "stylus": COMP_STYLUS,
            "meaning": "each .comp file carries its axis's component of the tool-tip error (the applied part of the "
                       "estimate) along its axis's line through this point: X.comp along X at this Y and Z, "
                       "Y.comp along Y at this X and Z, Z.comp along Z at this X and Y (readings: stylus-tip "
                       "centre in R, mm), zero at the axis's first node; exact on those lines, elsewhere the "
                       "errors that depend on the other axes' positions (Abbe terms, straightness, squareness) "
                       "remain"}


def compensation_plan(r: "ScenarioResult", line_m=None) -> dict:
    """How much of each error ``r``'s compensation applies and what it is predicted to leave.

    ``terms``: :func:`core.comprule.select_terms` of ``r``'s estimate (``doc["estimate"]``, the
    tables the controllers get: their U95 by linear propagation); ``rule``: the rule in words;
    ``predicted_residual``: over the plan's node box, a rigid motion removed, per axis X/Y/Z the
    largest predicted |residual|, the largest U95 of what is left and the largest U95 the applied
    part adds (a machine without errors: the compensation's whole effect), um, for the volumetric
    table and for the per-axis files (EXX, EYY, EZZ alone; with ``line_m``, readings m, their tables on
    the lines through that point, :func:`comp_line_tables`).
    """
    from core.comprule import select_terms
    from core.state import loads_estimate

    dec = select_terms(loads_estimate(r.doc["estimate"]))
    factors = {s: d["factor"] for s, d in dec.items()}
    pred = {}
    per_axis = {s: factors[s] for s in ("EXX", "EYY", "EZZ")} if line_m is None else factors
    for key, fs, line in (("volumetric", factors, None), ("per_axis_files", per_axis, line_m)):
        p = _prediction(r, fs, line)
        pred[key] = {a: {"max_abs_um": float(np.abs(p["residual"][:, i]).max() * 1e6),
                         "u95_max_um": float(p["U95"][:, i].max() * 1e6),
                         "u95_added_max_um": float(p["U95_added"][:, i].max() * 1e6)} for i, a in enumerate("XYZ")}
    pred["points"] = "the plan's node box, rotary axes at 0, stylus " + COMP_STYLUS + ", a rigid motion removed"
    return {"terms": dec, "predicted_residual": pred,
            "rule": ("each error function (table or squareness) is applied at the fraction "
                     "max(0, 1 - mean(u^2) / mean(e^2)) over its nodes (u = U95 / 2, linear propagation): applying "
                     "a fraction l of an estimate e^ of e leaves (1 - l)^2 e^2 + l^2 u^2 in mean square, least at "
                     "e^2 / (e^2 + u^2), e^2 estimated by mean(e^2) - mean(u^2); 0: left out (core.comprule)")}


#: The stylus the closed loop's volumetric residual is evaluated with (T0: a 150 mm probe); the
#: LinuxCNC files are indexed by joint position, whatever stylus is mounted.
COMP_STYLUS = "T0"


def _check_machine_for_plan(cfg, plan, name, source: str | None = None):
    """Refuse a machine whose chain is not the plan's, naming it as the user did (``source``: the machine
    file's path or the built-in name given to --machine; default the machine's own name)."""
    from core.chain import parse_chain
    from core.exceptions import ConfigError
    from sim.machines import MACHINES

    want = parse_chain(MACHINES[plan.machine]().chain)
    got = parse_chain(cfg.chain)
    if (got.workpiece_axes, got.tool_axes) != (want.workpiece_axes, want.tool_axes):
        raise ConfigError(f"--machine {source or cfg.name}: chain {cfg.chain!r} is not the {name} plan's "
                          f"{want.text!r} (the plan is designed for that structure)")


def simulation_items(plan, art, probe, cfg_true, program: dict, machines: dict, T_true: dict | None = None, *,
                     compensate=None, hook=None, progress=None) -> list:
    """(artefact, machine, probe, set-up, plan) of each measurement of ``plan``, as :func:`run` simulates them
    (``sim.campaign.simulate_measurements``).

    One machine per stylus (``cfg_true`` with its offsets, through ``compensate`` if given; kept in
    ``machines``, stylus -> Machine), one touch program per bar and hole set at ``program``'s margins
    (:func:`_program`), the placement's true pose ``T_true[placement]`` (None: nominal); ``hook(k, ms,
    art, probe, machine) -> (art, probe, machine)`` may change a measurement's; ``progress(k)`` before each.
    """
    from dataclasses import replace

    from sim.machine import Machine
    from sim.setups import Setup

    items, plans = [], {}  # plans by bar and holes
    for k, ms in enumerate(plan.measurements):
        if progress is not None:
            progress(k)
        if ms.stylus not in machines:
            machines[ms.stylus] = Machine(replace(cfg_true, J_m=tuple(ms.J_m)))
            if compensate is not None:
                machines[ms.stylus] = compensate(machines[ms.stylus])
        m = machines[ms.stylus]
        art_i, probe_i = art, probe
        if hook is not None:
            art_i, probe_i, m = hook(k, ms, art, probe, m)
        if (id(art_i), ms.holes) not in plans:  # the bar's part per hole set (its program: mfb_plan's cache)
            plans[id(art_i), ms.holes] = _plan_for(art_i, ms.holes, **program)
        T = None if T_true is None else T_true[ms.placement]
        items.append((art_i, m, probe_i, Setup(ms.name, ms.T_W_A, tuple(ms.rot_rad), T), plans[id(art_i), ms.holes]))
    return items


@dataclass(frozen=True)
class _Judged:
    """An identification (``res_g``, in its gauge) judged against the inputs' noise model: what :func:`run` and
    :func:`identify_log` compute alike (:func:`_judge`) and report alike (:func:`_report_tail`)."""
    res_g: object           # core.volumetric's result in the identification's gauge
    res: object             # its ISO 230-1 view (straightness against the end-point line)
    L_iso: np.ndarray       # gauge -> ISO view
    meas: list
    sigma_m: float          # probing noise (k = 1), m
    noisy: bool
    draw: bool              # the placements are drawn (run: draw_inputs; a log: its noise): u_place enters
    u_cal: np.ndarray       # the bar certificate's u (the U95's and the covariance's)
    u_cal_fit: np.ndarray   # the bar's u the residual tests hold (run: zero where the bar is not drawn)
    u_place: np.ndarray     # the placements' tolerance (6,)
    u_place_fit: np.ndarray | None  # u_place where draw, else None
    declared: dict
    cal_map: object
    rip_g: list | None
    noise: object
    lof: object
    share: object
    gate: bool
    me_g: np.ndarray | None
    unc: object


def _judge(res_g, meas, chain: str, rp: dict, *, sigma_m: float, noisy: bool, draw: bool, u_cal, u_cal_fit,
           u_place, declared: dict, mc_runs: int, rng, model_error_held: bool = True) -> _Judged:
    """The calls :func:`run` and :func:`identify_log` make after the identification ``res_g``, in this order:
    its ISO view, the declared ripples' columns, the residuals' noise model, lack of fit, the model-error share
    behind :data:`MFB_MODEL_ERROR_SHARE` and its gate (:data:`MFB_MODEL_ERROR_GATE`), the U95 (Monte Carlo
    ``mc_runs`` from ``rng``, or linear). ``draw``: the placements' tolerance ``u_place`` enters (:func:`run`'s
    drawn inputs; a log's probing noise); ``u_cal_fit`` the bar's u the residual tests hold; ``model_error_held``
    as :func:`run`'s (False: no share computed where the gate stays closed, no exact tails)."""
    from core import mfb, volumetric as vol

    L_iso = vol.iso_map(res_g.design)
    res = vol.iso_view(res_g)
    cal_map = mfb.calibration_map()  # the bar's heights as its rods give them
    rip_g = [vol.ripple_columns(res_g, meas, chain, s, a, p, rp)
             for s, (a, p) in declared.items()] or None  # (the gauge's; the report's below, L_iso of them)
    up = np.asarray(u_place, float)
    u_place_fit = up if draw else None
    # the residuals' model-error share (review29b F2b): per motion table a fine table the residuals show the
    # tables miss (z > 3 over the probing noise), propagated into the node values and the U95.
    # The residuals' noise model once for the three tests (it was computed by each: session 34, bn34)
    noise = vol.residual_noise(res_g, meas, sigma_m, u_cal_fit, u_place_fit, cal_map=cal_map)
    lof = vol.lack_of_fit(res_g, meas, sigma_m, u_cal_fit, u_place_fit, cal_map=cal_map, noise=noise)
    opens = not MFB_MODEL_ERROR_GATE or (lof is not None and not lof.fits)
    # (every table's exact tail where the gate opens: the shares are reported with their p; elsewhere only where
    # it could decide, core.volumetric.EXACT_TAIL_NEAR_LEVEL)
    share = (vol.model_error_share(res_g, meas, sigma_m, u_cal_fit, u_place_fit, cal_map=cal_map,
                                   exact_p=model_error_held, all_exact=opens, noise=noise)
             if MFB_MODEL_ERROR_SHARE and noisy and (opens or model_error_held) else None)
    # the tables' shares are 18 tests of a skewed statistic (realistic machine, 40 seeds: some table past z = 3
    # on 10 runs): they enter only when the residuals' lack-of-fit test (one test, level 1e-3) says the model
    # misses structure (MFB_MODEL_ERROR_GATE)
    gate = share is not None and opens
    me_g = share.columns if gate and share.entered else None
    # the U95 whenever an input has an uncertainty: the probing noise, a declared ripple, or the bar's
    # calibration u (given, noise or not: a noise-free run's U95 is the calibration's alone, linear, or
    # Monte Carlo with mc_runs); none only for a noise-free run with u_cal 0 and no Monte Carlo asked
    unc = (vol.uncertainty(res, meas, sigma_m, u_cal, runs=mc_runs, rng=rng, u_place=u_place_fit, cal_map=cal_map,
                           ripples=None if rip_g is None else [L_iso @ c for c in rip_g],
                           model_error=None if me_g is None else L_iso @ me_g)
           if mc_runs or noisy or declared or np.any(u_cal > 0) else None)
    return _Judged(res_g, res, L_iso, meas, sigma_m, noisy, draw, u_cal, u_cal_fit, up, u_place_fit, declared,
                   cal_map, rip_g, noise, lof, share, gate, me_g, unc)


def _report_tail(doc: dict, j: _Judged, *, identified_on: dict, nodes: dict, head: dict | None = None,
                 u95_scope: str | None = None, u95_growth: bool = False) -> np.ndarray:
    """What :func:`run` and :func:`identify_log` add alike to their document ``doc`` after its errors, in this
    order: ``estimate`` (vmt-estimate/1, from the covariance; its ``identified_on``), ``head``'s keys (run:
    ``machine``), ``declared_ripple``, ``u95_scope`` (given: run's unseen-ripple note), ``u95_inputs`` and
    ``u95_method``, ``model_error`` (with ``u95_growth`` when asked: run's), ``lack_of_fit`` and its note on
    ``nodes``, ``between_nodes`` and its note. Returns the covariance (the gauge's)."""
    from core import iso, volumetric as vol

    declared, unc, me_g = j.declared, j.unc, j.me_g
    cov_g = vol.covariance(j.res_g, j.meas, j.sigma_m, j.u_cal, j.u_place_fit, cal_map=j.cal_map, ripples=j.rip_g,
                           model_error=me_g)
    doc["estimate"] = vol.estimate(j.res_g, cov_g)  # vmt-estimate/1
    doc["estimate"]["identified_on"] = identified_on
    if declared:
        doc["estimate"]["method"] += "; declared ripples (type B, unknown phase): " + ", ".join(declared)
    doc.update(head or {})
    if declared:
        doc["declared_ripple"] = {s: {"amplitude_" + ("urad" if iso.symbol(s).angular else "um"): a * 1e6,
                                      "period_mm": p * 1e3} for s, (a, p) in declared.items()}
    if u95_scope:
        doc["u95_scope"] = u95_scope
    if unc is not None:  # what the U95 holds (a noise-free run: the bar calibration's u alone, and a ripple)
        doc["u95_inputs"] = [k for k, on in (("probing noise", j.noisy), ("bar calibration", bool(np.any(j.u_cal > 0))),
                                             ("placement", j.draw and bool(np.any(j.u_place > 0))),
                                             ("declared ripple", bool(declared)),
                                             ("model error (residuals)", me_g is not None)) if on]
        doc["u95_method"] = (f"Monte Carlo (JCGM 101), {unc.runs} runs" if unc.runs
                             else "linear propagation (JCGM 100 eq. 13), k = 2")
    # the residuals against the inputs' noise model (review29b F2): a note when the tables miss structure
    if j.share is not None:
        doc["model_error"] = j.share.as_dict()
        if not j.gate:  # past z = 3 but the residuals as a whole fit: held out of the U95
            doc["model_error"]["held"] = doc["model_error"].pop("entered")
            doc["model_error"]["entered"] = []
            doc["model_error"].pop("u")
        if u95_growth and unc is not None and me_g is not None:  # how much the share widens the linear U95
            u_s = np.sqrt(np.einsum("ij,ij->i", j.L_iso @ me_g, j.L_iso @ me_g))
            u0 = np.sqrt(np.maximum(unc.u_lin ** 2 - u_s ** 2, 0.0))
            ok = u0 > 0  # (nodes with a U95)
            g = unc.u_lin[ok] / u0[ok] - 1.0
            doc["model_error"]["u95_growth"] = {"median": float(np.median(g)), "max": float(np.max(g))}
    if j.lof is not None:
        doc["lack_of_fit"] = j.lof.as_dict()
        if not j.lof.fits:
            doc["model_fit_note"] = lack_of_fit_note(j.lof, nodes)
    # between two nodes of a table (review33a F5): a local error the whole-residual test dilutes
    bn = (vol.between_nodes_fit(j.res_g, j.meas, j.sigma_m, j.u_cal_fit, j.u_place_fit, cal_map=j.cal_map,
                                noise=j.noise) if MFB_BETWEEN_NODES and j.noisy else None)
    if bn is not None:
        doc["between_nodes"] = bn.as_dict()
        if not bn.fits:
            doc["between_nodes_note"] = between_nodes_note(bn)
    return cov_g


#: :func:`run`'s progress marks (of 100, a run's CPU in percent): the touches simulated and their features fitted,
#: then identified (``make bench`` splits its end-to-end time at them, scenarios/bench/mfb.py)
PROGRESS_SIMULATED = 12
PROGRESS_IDENTIFIED = 43


def run(name: str = "mfb-3axis", *, seed: int = 1, noise_um: float | None = None, mc_runs: int = 500,
        exact: bool = True, ripple: bool = False, drop: str | None = None, on_nodes: bool = False,
        u_cal_um: tuple = U_CAL_UM, bar_cal_error: bool = True,
        u_place: tuple = U_PLACE, machine=None, compensate=None, bar_seed: int | None = None,
        u_stylus_um: float = 0.0, bar_temperature_C: float = 20.0, hook=None, progress=None,
        bar_calibration=None, bar_true_m=None, draw_inputs: bool | None = None, lobing_m: tuple = (),
        machine_temperature_C: float = 20.0, stylus_dJ_m: dict | None = None,
        declared_ripple: dict | None = None, extraction: bool | None = None,
        model_error_held: bool = True, simulate_only: bool = False) -> ScenarioResult:
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
        (half the paper's 0.4 / 0.7 um "average uncertainty", read as k = 2:
        vmt's assumption, the paper states no coverage factor; :data:`U_CAL_UM`).
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
    bar_calibration : core.mfb.BarCalibration, optional
        The bar's calibration to identify with (e.g. the reversal on a CMM,
        :func:`reversal_on_cmm`, read back by :func:`read_bar_calibration`):
        its ``E_m`` replace the declared deviations and its ``u_m`` the
        declared ``u_cal_um`` (per point and direction). Default: the
        declared calibration (:func:`sim.artefacts.mfb_default_deviations`, ``u_cal_um``).
    bar_true_m : (12, 3) float, optional
        The simulated bar's true deviations (``deviations_m`` of
        :func:`sim.artefacts.multi_feature_bar`; with ``bar_calibration``:
        the bar that was calibrated). Default: the calibration + a draw of
        its u (with ``draw_inputs``).
    draw_inputs : bool, optional
        Draw the bar's calibration error and the placement errors (default:
        when there is probing noise); False/True to switch them apart from
        the noise (the budget's one source at a time, :func:`budget`).
    stylus_dJ_m : dict, optional
        ``{stylus: (3,) m}``: these probe-offset errors instead of a draw of
        ``u_stylus_um`` (styli not named: none); the budget's stylus share
        component by component (:func:`budget_shares`).
    lobing_m : tuple of (k, a, b)
        The probe's lobing left after its calibration (:class:`sim.probe.ProbeConfig`),
        m; not in the identification's model.
    machine_temperature_C : float
        The machine's temperature: its linear axes' scales expand by
        :data:`MACHINE_CTE_PER_C` from the axis zero (the truth, and the
        tables compared with, stay the 20 degC machine's).
    declared_ripple : dict, optional
        ``{symbol: (amplitude, period_m)}``: periodic errors the user declares the machine holds and no MFB
        plan sees (shorter than twice the bar's pitch, :func:`unseen_ripple`), amplitude in m (rad for an
        angular symbol), phase unknown (uniform): their effect on the identified values
        (:func:`core.volumetric.ripple_columns`) joins the U95 and the covariance as a type B term. Default
        none: the U95 is the noise's, the calibration's and the placements'.
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
        ``progress(done, total)`` in percent of a run's CPU (``total`` 100):
        each measurement's program prepared (0-3), the touches simulated and
        fitted (12), identified (43), the residual tests and the U95 (100).
    extraction : bool, optional
        The identification's Gauss-Newton predicts the points of interest by
        the exact extraction (the touches, which carry their features and
        normals, moved by the errors and fitted again) or by the linear gain
        (default :data:`core.volumetric.EXACT_EXTRACTION`).
    model_error_held : bool
        With :data:`MFB_MODEL_ERROR_SHARE` on: compute the tables' model-error statistics also when the
        lack-of-fit gate keeps them out of the U95 (JSON ``model_error.held``, its ``z`` and ``p``; the
        default). False skips them there (the U95 and covariance are the same: no share enters through a
        closed gate) and the tables' exact tails ``p`` where it opens (``model_error.p`` null), as the budget
        study's runs do (:func:`budget_run`, no JSON kept): most of a run's CPU.
    simulate_only : bool
        Stop after the simulated campaign (session 38): the result's ``meas``, ``campaign``, ``plan``,
        ``n_touches``, ``strokes_m`` and ``J_m`` are a full run's, bit for bit (nothing after the measurements
        draws from the seed's stream before them); no identification, U95 or truth (``result``, ``unc``,
        ``truth`` None; ``doc`` only the campaign's head: format, scenario, machine, seed, noise_um,
        touches, ``simulated_only`` true). For a caller that reads the measurements only
        (:func:`scenarios.hidden.hidden_mfb`: discovery on the campaign; the identification, its residual
        tests and the U95 were 1.2 of the 3.0 s CPU of a hidden campaign with its discovery).
    """
    from core import iso, mfb, volumetric as vol
    from core.exceptions import ConfigError
    from dataclasses import replace

    from core.touches import from_log
    from sim import artefacts as A
    from sim.campaign import simulate_measurements
    from sim.plans import mfb_plan
    from sim.probe import ProbeConfig

    if name not in PLANS:
        raise ConfigError(f"unknown MFB scenario {name!r}; known: {', '.join(PLANS)}")
    from core.uncertainty import check_mc_runs

    mc_runs = check_mc_runs(mc_runs, "mc_runs", zero_ok=True)  # before the campaign, not after it
    t0 = time.time()
    plan = PLANS[name]()
    if drop:
        if drop not in plan.placements:
            raise ConfigError(f"drop: no placement {drop!r} in {name} ({', '.join(plan.placements)})")
        plan = plan.without(drop)
    declared = _check_declared_ripple(declared_ripple)
    rng = np.random.default_rng(seed)
    if machine is not None:
        _check_machine_for_plan(machine.config, plan, name, getattr(machine, "source", None))
        probe = machine.probe
        cfg, errs = machine.config, dict(machine.config.errors)
    else:
        probe = ProbeConfig()
        cfg, errs = default_machine(plan.machine, ripple)
    if noise_um is not None:
        if not (np.isfinite(noise_um) and noise_um >= 0):
            raise ConfigError(f"noise_um must be >= 0 (a standard deviation, um), got {noise_um!r}")
        probe = replace(probe, repeatability_k2_m=2.0 * float(noise_um) * 1e-6)
    if lobing_m:
        probe = replace(probe, lobing_m=tuple(tuple(t) for t in lobing_m))
    sigma_um = probe.sigma_m * 1e6
    noisy = sigma_um > 0
    draw = noisy if draw_inputs is None else bool(draw_inputs)
    if bar_calibration is None:
        E_cal = A.mfb_default_deviations()
        u_cal = np.tile(np.asarray(u_cal_um, float) * 1e-6, (12, 1))
        E_cal_O = _declared_poi_deviations(E_cal)
    else:
        E_cal = E_cal_O = np.asarray(bar_calibration.E_m, float)
        u_cal = np.asarray(bar_calibration.u_m, float)
        if E_cal.shape != (12, 3) or u_cal.shape != (12, 3) or not (np.all(np.isfinite(E_cal))
                                                                     and np.all(np.isfinite(u_cal))):
            raise ConfigError(f"bar_calibration: E_m and u_m must be finite (12, 3), got {E_cal.shape}, {u_cal.shape}")
    bar_rng = rng if bar_seed is None else np.random.default_rng(bar_seed)
    if bar_true_m is not None:
        E_true = np.asarray(bar_true_m, float)
    else:
        E_true = E_cal + (bar_rng.standard_normal(E_cal.shape) * u_cal if (draw and bar_cal_error) else 0.0)
    art = A.multi_feature_bar(deviations_m=E_true, temperature_C=bar_temperature_C)
    if not (np.isfinite(u_stylus_um) and u_stylus_um >= 0):
        raise ConfigError(f"u_stylus_um must be >= 0 (a standard uncertainty, um), got {u_stylus_um!r}")
    styli = list(dict.fromkeys(ms.stylus for ms in plan.measurements))
    if stylus_dJ_m is not None:
        bad = [k for k in stylus_dJ_m if k not in styli]
        if bad or not all(np.shape(v) == (3,) and np.all(np.isfinite(v)) for v in stylus_dJ_m.values()):
            raise ConfigError(f"stylus_dJ_m: finite (3,) offsets of the plan's styli ({', '.join(styli)}), "
                              f"got {sorted(stylus_dJ_m)!r}")
        dJ = {st: np.asarray(stylus_dJ_m.get(st, np.zeros(3)), float) for st in styli}
    else:
        dJ = {st: (rng.standard_normal(3) * u_stylus_um * 1e-6 if u_stylus_um > 0 else np.zeros(3)) for st in styli}
    O_A_cal = art.info["poi_nominal_m"] + E_cal_O
    if on_nodes:
        from sim.errorfuncs import SplineTable

        errs = {k: (SplineTable(tuple(plan.nodes[iso.symbol(k).axis]), tuple(np.asarray(
            f(plan.nodes[iso.symbol(k).axis]), float))) if k in vol.MOTION else f) for k, f in errs.items()}
        cfg = replace(cfg, errors=errs)
    if not np.isfinite(machine_temperature_C):
        raise ConfigError(f"machine_temperature_C must be finite, got {machine_temperature_C!r}")
    cfg_true = cfg if machine_temperature_C == 20.0 else replace(
        cfg, errors=thermal_scales(errs, machine_temperature_C))

    # the program's approach margins cover the declared placement tolerance (not the draw)
    program = _program(u_place)
    collision = check_plan(plan, u_place=u_place)  # after the inputs are checked
    if machine is not None:  # another machine file: the program within its strokes too
        check_plan_strokes(plan, machine.config, probe.stylus_r_m, u_place)
    machines = {}
    meas, G_cache, n_touch = [], {}, 0
    gain_fits: dict = {}  # the gains' light fits, shared by the hole sets of this run (same touches, same fits)
    T_true = {}
    for p in plan.placements:  # bar placement errors (by hand on the table), roll included
        T = next(m.T_W_A for m in plan.measurements if m.placement == p)
        if draw:
            xi = rng.standard_normal(6) * np.asarray(u_place, float)
            dT = np.eye(4)
            dT[:3, :3] = A.rot_z(xi[5]) @ A.rot_y(xi[4]) @ A.rot_x(xi[3])
            dT[:3, 3] = xi[:3]
            T_true[p] = T @ dT
        else:
            T_true[p] = None
    # progress in percent of a run's CPU (cli38's timers, mfb-3axis, 12.9 s at load): preparing each
    # measurement's program 0-3, simulating the touches and fitting the features to PROGRESS_SIMULATED, the
    # identification to PROGRESS_IDENTIFIED, its residual tests, model-error share and U95 to 100 (a count per
    # measurement read 17/19 at 13 %)
    steps = 100
    n_items = max(len(plan.measurements), 1)
    items = simulation_items(plan, art, probe, cfg_true, program, machines, T_true, compensate=compensate,
                             hook=hook, progress=None if progress is None else
                             (lambda k: progress(min(3, 3 * k // n_items), steps)))
    # every measurement's touches in one simulation (its styli on one machine, sim.campaign).
    # The strokes: check_plan (above, always) has checked every position the program commands
    # (touches, approach starts, overshoot ends, links) as axis positions; sim.campaign's own
    # check is not the program's: its links pass over the bar's top in R z (a standing bar's
    # top is above the Z stroke), where the program's retract out along the holes' normal
    logs = simulate_measurements(items, rng if noisy else None, stroke_check=False)
    done = []  # (spec, J, touches, readings, plan of the valid touches) of each measurement simulated
    for ms, (_, m, _, _, pl), log in zip(plan.measurements, items, logs):
        _check_touches_ok(log, ms.name, program)
        t = from_log(log)
        n_touch += t.n
        # the stylus's calibration error: the controller converts joints to tip positions
        # with the offsets it was given, J, while the tip sits at J + dJ: every reading of
        # this stylus is off by dJ (the tool does not turn on these chains). (A machine
        # built with J + dJ would move and read with the same offsets: no error at all.)
        p_R = t.p_R + dJ[ms.stylus]
        # the touches that were fitted (valid ones, plan order)
        done.append((ms, tuple(ms.J_m), t, p_R, pl.select(np.asarray(log.ok, bool))))
    # simulated touches, each checked to trigger on its target: fitted in batches (to rounding),
    # the features of every measurement together (each one's numbers as its own batch gives)
    pois = mfb.points_of_interest_batched([(p_R, t.feature, t.n_R) for _, _, t, p_R, _ in done])
    for (ms, J, t, p_R, pl_ok), poi, item in zip(done, pois, items):
        # the gain of the extraction at the nominal places of the touches (A frame, stylus centres),
        # cut from the gain of the bar's whole program (kept by mfb_plan)
        key = (tuple(pl_ok.target), probe.stylus_r_m)
        if key not in G_cache:
            G_cache[key] = _noise_gain(pl_ok, probe.stylus_r_m, gain_fits, full=mfb_plan(item[0], **program))
        idx = [h - 1 for h in poi.holes]
        meas.append(vol.Measurement(ms.name, ms.setup_key, poi.holes, poi.O_R, O_A_cal[idx], ms.T_W_A,
                                    tuple(ms.rot_rad), J, G_cache[key], q_R=p_R,
                                    c_A=pl_ok.w_A + probe.stylus_r_m * pl_ok.wn_A, d_A=-pl_ok.wn_A,
                                    feature=tuple(t.feature), n_A=pl_ok.wn_A))
    if simulate_only:  # the campaign alone: what a run identifies, nothing identified
        doc = {"format": MFB_FORMAT, "scenario": name, "machine": plan.machine, "seed": seed, "noise_um": sigma_um,
               "touches": int(n_touch), "simulated_only": True}
        return ScenarioResult(plan, None, None, None, n_touch, time.time() - t0, doc, None, meas, axis_strokes_m(cfg),
                              tuple(float(v) for v in cfg.J_m), _campaign_of(logs, E_cal_O, u_cal, dJ, cfg, probe))
    chain = cfg.chain
    rp = dict(cfg.rotary_points_R_m)
    if progress is not None:
        progress(PROGRESS_SIMULATED, steps)
    res_g = vol.identify_volumetric(meas, chain, plan.nodes, rp, exact=exact, extraction=extraction)
    if progress is not None:
        progress(PROGRESS_IDENTIFIED, steps)
    # the residual tests hold the bar's u only where the true bar is drawn from it (or given)
    u_cal_fit = u_cal if (bar_true_m is not None or (draw and bar_cal_error)) else np.zeros_like(u_cal)
    j = _judge(res_g, meas, cfg.chain, rp, sigma_m=probe.sigma_m, noisy=noisy, draw=draw, u_cal=u_cal,
               u_cal_fit=u_cal_fit, u_place=u_place, declared=declared, mc_runs=mc_runs, rng=rng,
               model_error_held=model_error_held)
    res, L_iso, unc = j.res, j.L_iso, j.unc
    # truth in the same gauge
    d = res.design
    truth = np.zeros(len(res.theta))
    # a time-varying table (a machine file's thermal drift) has no one truth: its mean over the campaign's
    # touch times (the measurements run on one clock, sim.campaign.simulate_measurements; review30b F2)
    t_touch = np.concatenate([np.asarray(log.col("t_s"), float) for log in logs])
    t_touch = t_touch[np.isfinite(t_touch)]
    varying = {}  # table -> its span over the campaign (max over nodes of max - min in time), SI
    for s in vol.MOTION:
        a = iso.symbol(s).axis
        x = d.nodes[a]
        lin = np.zeros((len(x), 3))
        lin[:, iso.LINEAR_AXES.index(a)] = x
        f = errs.get(s)
        if f is not None:
            truth[d.slices[s]] = _campaign_mean(f, x, t_touch, s, varying)
    for s in vol.SQUARENESS:
        f = errs.get(s)
        if f is not None:
            truth[d.slices[s]] = float(_campaign_mean(f, np.zeros(1), t_touch, s, varying)[0])
    truth_raw = d.to_gauge(truth)
    truth_g = L_iso @ truth_raw
    slopes = (vol.end_point_slopes(d, res_g.theta), vol.end_point_slopes(d, truth_raw))
    doc = _document(name, plan, res, unc, truth_g, n_touch, seed, sigma_um, slopes)
    from core.state import identified_on

    unseen = [(s, p) for s, p in unseen_ripple(errs) if not _declared_covers(declared, s, p)]
    cov_g = _report_tail(doc, j, identified_on=identified_on(   # its tables run along Z: no single height
        cfg.name, cfg.chain, sorted({tuple(float(v) * 1e3 for v in m.J_m) for m in plan.measurements}), None,
        (float(t_touch.min()), float(t_touch.max())) if t_touch.size else None),  # the campaign's clock (F8)
        nodes=plan.nodes, head={"machine": cfg.name}, u95_scope=unseen_ripple_note(unseen) if unseen else None,
        u95_growth=True)
    if unc is not None:  # the count beside what the model expects of it (drawn last: nothing above moves)
        doc["within_u95"] = within_u95(doc["errors"], L_iso @ cov_g @ L_iso.T, d.slices, rng)
    if varying:  # what `injected` is for a table that drifts in time (review30b F2)
        doc["injected_note"] += ("; a table that drifts in time (" + ", ".join(varying) + "): its mean over the "
                                 "campaign's touch times (injected_time)")
        doc["injected_time"] = {
            "rule": "mean over the campaign's touch times (the tables drift in time; a static table: its value)",
            "t_s": [float(t_touch.min()), float(t_touch.max())], "t_mean_s": float(t_touch.mean()),
            "touches": int(t_touch.size),
            "span": {k: v * 1e6 for k, v in varying.items()},
            "span_units": "um (urad for angles, um/m for squareness): max over the nodes of the drift over the campaign"}
    doc["bar"] = _bar_doc(E_cal_O, u_cal, art.info["E_MFB_m"],
                          "declared" if bar_calibration is None else "calibration given (e.g. reversal on a CMM)",
                          j.cal_map if bar_calibration is None else None)
    if collision is not None:
        doc["collision_check"] = collision
    if progress is not None:
        progress(steps, steps)
    return ScenarioResult(plan, res, unc, truth_g, n_touch, time.time() - t0, doc, slopes[0], meas,
                          axis_strokes_m(cfg), tuple(float(v) for v in cfg.J_m),
                          _campaign_of(logs, E_cal_O, u_cal, dJ, cfg, probe))


def _campaign_of(logs, E_cal_O, u_cal, dJ: dict, cfg, probe) -> dict:
    """:class:`ScenarioResult`'s ``campaign`` of a run (its field's description)."""
    return {"logs": tuple(logs), "E_cal_m": np.asarray(E_cal_O, float), "u_cal_m": np.asarray(u_cal, float),
            "dJ_m": dJ, "rotary_points_R_m": dict(cfg.rotary_points_R_m), "sigma_m": float(probe.sigma_m)}


#: The residuals' model-error share in the U95 (:func:`core.volumetric.model_error_share`, review29b F2b):
#: per motion table a fine table (1 mm) entering when the residuals show it (z > 3 over the probing noise),
#: propagated through K into the node values, the U95 and the covariance. Session 29, docs/papers-mfb.md
#: "A model-error share in the U95 (session 29)". ON since session 34 (share34, review33a F4): off until then
#: because on the budget studies' runs (stylus, lobing and temperature drawn, outside the noise model) the
#: lack-of-fit gate opens on about a quarter of the runs and the share widens their own U95, so the stored
#: 1,000-run studies had to be made again with it. Both were (scenarios/data/mfb-*-budget-study.npz, key
#: ``model_error_share``: every run's error bit for bit the same, the gate open on 273 of the 3-axis study's
#: 1,000 runs and 204 of the 5-axis study's; their tables' cells are the shares', which the share does not
#: touch): docs/papers-mfb.md, "Remaking the budget studies with the share (session 34)".
MFB_MODEL_ERROR_SHARE = True
#: The model-error share enters only when :func:`core.volumetric.lack_of_fit` rejects the noise model (the
#: run's ``model_fit_note``): without this gate the per-table z > 3 rule let a share into the U95 on 10 of
#: the realistic machine's 40 seeds (z 3.1-5.2, no note on any) and on the demo's 3-axis seed 1 (EBX, z 3.6,
#: lack-of-fit p 0.20). Session 29, docs/papers-mfb.md "A model-error share in the U95 (session 29)".
MFB_MODEL_ERROR_GATE = True


def _campaign_mean(f, x, t_s: np.ndarray, name: str, varying: dict) -> np.ndarray:
    """``f`` at ``x`` as the MFB scenario reports its truth: ``f(x)`` when ``f`` takes the same values at every
    touch time ``t_s`` (a static table: the same doubles as before), else its mean over those times, with
    the table's span over the campaign (max over ``x`` of max - min in time) put in ``varying[name]``."""
    v0 = np.asarray(f(x), float)
    if t_s.size == 0:
        return v0
    V = np.asarray(f(np.tile(x, t_s.size), np.repeat(t_s, x.size)), float).reshape(t_s.size, x.size)
    if np.array_equal(V, np.broadcast_to(v0, V.shape)):
        return v0
    varying[name] = float(np.max(V.max(axis=0) - V.min(axis=0)))
    return V.mean(axis=0)


#: The between-node test in every noisy MFB run (:func:`core.volumetric.between_nodes_fit`, review33a F5, session
#: 34): JSON ``between_nodes`` and, when it rejects, ``between_nodes_note``. A note, nothing else: the U95 stays
#: the node values' (docs/papers-mfb.md, "Between the nodes (session 34)").
MFB_BETWEEN_NODES = True


def between_nodes_note(bn) -> str:
    """The run's one-line note when a table misses structure between two of its nodes (:func:`core.volumetric.
    between_nodes_fit`, review33a F5)."""
    a, b = (v * 1e3 for v in bn.interval_m)
    return (f"between {bn.symbol}'s nodes at {a:g} and {b:g} mm the residuals are {bn.ratio:.1f} x what the probing "
            f"noise leaves (p = {bn.p:.1e}, {bn.p_family:.1e} over the {bn.intervals} intervals tested): the tables' "
            "interpolation misses structure there; the U95 holds at the nodes, the map between them may be off by "
            "more")


def lack_of_fit_note(lof, nodes) -> str:
    """The run's one-line note when its residuals exceed the inputs' noise model
    (:func:`core.volumetric.lack_of_fit`; review29b F2)."""
    h = sorted({round(float(np.median(np.diff(np.asarray(nodes[a], float)))) * 1e3) for a in "XYZ"})
    return (f"residuals {lof.rms_m * 1e6:.3f} um RMS against {lof.expected_rms_m * 1e6:.3f} um expected from the "
            f"probing noise, bar calibration and placements (p = {lof.p:.1e}, {lof.dof:.0f} effective degrees of "
            f"freedom): the {'/'.join(str(v) for v in h)} mm tables miss structure; U95 may under-cover")


def axis_strokes_m(cfg) -> dict:
    """axis -> (min, max): the axis positions (reading + J, the tables' and the ``.comp`` files'
    abscissa, m) a machine's linear strokes allow: ``strokes`` are written in the readings of the
    configuration's own offsets ``J_m`` (sim.machine.MachineConfig), so the axis positions are the
    stroke plus ``J_m``."""
    J = np.asarray(cfg.J_m, float)
    return {a: (float(cfg.strokes[a][0] + J[i]), float(cfg.strokes[a][1] + J[i])) for i, a in enumerate("XYZ")}


#: The one rule of both compensation outputs beyond the node box (review29b F1), stated in the
#: vmt-comp/1 JSON, the run's output and README "Compensation files".
COMP_EXTRAPOLATION = ("beyond the end nodes along the end tangent (the C2 spline's), to the machine's strokes: "
                      "the .comp files carry a line at each stroke end on that tangent (LinuxCNC interpolates "
                      "linearly between lines and holds the end lines beyond them); outside compensated_range_mm "
                      "the correction is an extrapolation, not a measurement")


#: How each twist (an axis' rotation about itself) is sensed by the 5-axis plan
#: (tool-side chain), and what limits it.
TWIST_SENSING = {
    "EAX": "not sensed by the X bars: the arm of X's angular errors is the tip's Y, Z reading, so a ramp of "
           "EAX moves every bar along X rigidly (absorbed by its pose) and its constant is the ISO gauge; only "
           "the bend of the XY / XZ diagonals (a s^2 / 2, ~0.1 um over the bar) sees it, against the bar's "
           "calibrated bow (u 0.35 um) and the probing noise",
    "EBY": "T0 vs TXF on Y1 in one pose (dJ_X 100 mm): differential vertical straightness; Y2 - Y1 (dz 150 mm) "
           "only its curvature (separate poses); limited by the probing noise over the 100 mm arm",
    "ECZ": "TX1 vs TX3 on VX in one pose (dJ_X 150 mm): differential positioning; limited by the probing "
           "noise over the 150 mm arm difference (the "
           "standing bar facing -Y is out of the plan: no star arm along Y keeps the spindle within the Y "
           "travel and clears the bar)",
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


def rotary_not_compensated(chain: str) -> dict | None:
    """The ``not_compensated`` entry of an MFB run's JSON and of its ``vmt-comp/1`` file (review33b F2): on a
    chain with rotary axes, that none of their errors (location errors and error motions, ISO 230-7) is
    identified or compensated: the MFB identifies the linear axes' 21, and each set-up's pose (the bar as the
    rotary axes present it) absorbs theirs. None on a chain without rotary axes."""
    from core import iso
    from core.chain import parse_chain

    axes = parse_chain(chain).rotary_axes
    if not axes:
        return None
    names = [sy.name for a in axes for loc in (True, False) for sy in iso.symbols_of_axis(a, location=loc)]
    return {"axes": list(axes), "errors": names,
            "why": f"not identified: the MFB identifies the linear axes' 21 errors; each set-up's pose (the bar "
                   f"as {' and '.join(axes)} present it) absorbs the rotary axes' location errors and error "
                   "motions at its angles, so no table or file here corrects them: the tip relative to the part keeps "
                   "them at every rotary position until they are measured (ISO 230-7, e.g. an R-test) and "
                   "compensated on their own"}


def describe_not_compensated(nc: dict) -> str:
    """The terminal's note line for :func:`rotary_not_compensated`'s entry."""
    return (f"note: not compensated: the rotary axes {', '.join(nc['axes'])} ({len(nc['errors'])} errors, "
            f"{nc['errors'][0]}..{nc['errors'][-1]}): {nc['why']}")


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
    return {"format": MFB_FORMAT, "scenario": name, "machine": plan.machine, "seed": seed, "noise_um": sigma_um,
            "noise_note": "probing noise: a standard deviation (k = 1) along the approach",
            "placements": len(plan.placements), "setups": len(plan.setups),
            "measurements": len(plan.measurements),
            "touches": int(n_touch), "model": "first order (eqs 8-12) + exact Gauss-Newton"
                     + (" (the points fitted again from the touches at each step)" if res.extraction else "")
            if res.iterations else "first order (eqs 8-12)", "gauss_newton_iterations": res.iterations,
            "conventions": list(res.design.gauge), "rms_residual_um": res.rms_m * 1e6,
            "errors": errors, "max_dev_um": dev_um, "max_dev_urad": dev_urad,
            "twists": _twists(errors) if plan.rotary else {},  # (TWIST_SENSING: the 5-axis plan's sensing)
            **({"not_compensated": nc} if (nc := rotary_not_compensated(res.chain)) else {}),
            "injected_note": "truth at the nodes, expressed in the same ISO 230-1 conventions (gauge)"}


def unseen_ripple(errs: dict, pitch_m: float = 0.050) -> list:
    """The injected errors holding a periodic term shorter than twice the bar's pitch, ``[(symbol, period_m)]``.

    No MFB plan sees such a ripple (module docstring): every hole samples it at one phase and the hole fit averages
    it, so the nodes' tables carry it aliased and their U95 (the noise's, the placements', the calibration's) does
    not cover it: on the ``realistic`` set's 10 mm screw ripple EXX's nodes fell within their U95 in 83 % of 1,600
    (200 seeds; 94-95 % without the ripple), off by up to 0.42 um against a U95 of 0.66 um (session 25's review).
    A declared ripple (``run``'s ``declared_ripple``) puts its term in the U95: 96 % with all six declared.
    """
    from sim.errorfuncs import Periodic, Sum

    def periods(f):
        if isinstance(f, Sum):  # (a sum of sums: a thermal ramp added to a profile, thermal_scales)
            return [p for t in f.terms for p in periods(t)]
        return [float(f.period)] if isinstance(f, Periodic) else []

    return sorted({(sym, p) for sym, f in errs.items() for p in periods(f) if p < 2 * pitch_m})


def _check_declared_ripple(declared) -> dict:
    """``run``'s ``declared_ripple`` checked: ``{motion symbol: (amplitude >= 0, period_m > 0)}`` finite, or ConfigError."""
    from core import volumetric as vol
    from core.exceptions import ConfigError

    if not declared:
        return {}
    out = {}
    for s, v in dict(declared).items():
        if s not in vol.MOTION:
            raise ConfigError(f"declared_ripple: {s!r} is not a motion error ({', '.join(vol.MOTION)})")
        try:
            a, p = (float(x) for x in v)
        except (TypeError, ValueError):
            raise ConfigError(f"declared_ripple {s}: expected (amplitude, period_m), got {v!r}") from None
        if not (np.isfinite(a) and np.isfinite(p) and a >= 0 and p > 0):
            raise ConfigError(f"declared_ripple {s}: amplitude >= 0 and period > 0, finite, got {v!r}")
        out[s] = (a, p)
    return out


def _declared_covers(declared: dict, symbol: str, period_m: float) -> bool:
    """Whether a declared ripple of ``symbol`` has this period (to 1e-9 m): the U95 then holds its term."""
    return symbol in declared and abs(declared[symbol][1] - period_m) <= 1e-9


def unseen_ripple_note(unseen: list) -> str:
    """One line for the report: which injected ripples the U95 leaves out, and why."""
    per = sorted({p for _, p in unseen})
    return (f"the U95 covers what the node tables can represent; the truth holds a ripple of "
            f"{', '.join(f'{p * 1e3:g}' for p in per)} mm period in {', '.join(s for s, _ in unseen)}, shorter than "
            f"twice the bar's 50 mm pitch: no MFB plan sees it, the tables carry it aliased beyond their U95 "
            f"(--errors study leaves it out; --declared-ripple-um-mm / -urad-mm puts it in the U95)")


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


def _volumetric_deviation(machine, nodes) -> np.ndarray:
    """The machine's tip deviation (exact sim) at the plan's node box (:func:`_node_box`: axis positions,
    so the readings are the nodes less the machine's probe offsets J), rotary axes at zero, a rigid motion
    removed, (n, 3) m."""
    P = _node_box(nodes) - np.asarray(machine.config.J_m, float)
    rot = None if not machine.rotary_axes else np.zeros((len(P), len(machine.rotary_axes)))
    D = np.asarray(machine.tip_W(P, rot), float) - np.asarray(machine.tip_W_nominal(P, rot), float)
    return _rigid_residual(D, P)


def volumetric_residual_um(machine, nodes) -> dict:
    """The machine's tip deviation (tool relative to the part, exact sim) over the
    plan's node box (axis positions: the readings are the nodes less the machine's
    probe offsets J), rotary axes at zero, a rigid motion removed: max |.| per axis, um."""
    R = _volumetric_deviation(machine, nodes)
    return {a: float(np.abs(R[:, i]).max() * 1e6) for i, a in enumerate("XYZ")} | {
        "rms": float(np.sqrt(np.mean(R ** 2)) * 1e6), "points": int(len(R))}


def volumetric_check(R_before, R_after, pred) -> dict:
    """The closed loop's volumetric verdict per axis X/Y/Z (um): the exact tip deviation over the node
    box before and after compensation (rigid motion removed); the residual predicted with the U95 of
    what is left and the U95 the applied part adds (:func:`_prediction`); ``within_u95``: points where
    the residual found lies within the prediction's U95; ``improved``: the largest deviation fell by
    more than the largest U95 of what is left (the compensation helped beyond its uncertainty);
    ``not_worse``: the largest deviation after is no more than before plus that U95 (what a
    compensation must never break: a good machine made worse than its stated residual U95). The U95
    the applied part adds (``u95_added_max_um``) is beside them, not in the verdicts: the factors are
    chosen on the estimate itself, which its linear propagation does not see (a zero term applied in
    part is one whose estimate came out large: on a machine without errors it can exceed it)."""
    out = {}
    for i, a in enumerate("XYZ"):
        b, f = float(np.abs(R_before[:, i]).max() * 1e6), float(np.abs(R_after[:, i]).max() * 1e6)
        r, U = pred["residual"][:, i], pred["U95"][:, i]
        u = float(U.max() * 1e6)
        out[a] = {"before_max_um": b, "after_max_um": f, "predicted_max_um": float(np.abs(r).max() * 1e6),
                  "u95_max_um": u, "u95_added_max_um": float(pred["U95_added"][:, i].max() * 1e6),
                  "within_u95": f"{int(np.sum(np.abs(R_after[:, i] - r) <= U))}/{len(r)}",
                  "improved": bool(b - f > u), "not_worse": bool(f <= b + u)}
    return out


def _applied_in(directory, name: str) -> dict:
    """symbol -> fraction the compensation in ``directory`` applies (its JSON's ``applied_factor``; 1
    for every error when the JSON has none or is absent)."""
    import json
    from pathlib import Path

    from core.volumetric import MOTION, SQUARENESS

    pj = Path(directory) / f"{name}-comp.json"
    errs = json.loads(pj.read_text()).get("errors", {}) if pj.is_file() else {}
    return {s: float(errs.get(s, {}).get("applied_factor", 1.0)) for s in MOTION + SQUARENESS}


def compensators(directory, name: str):
    """The two controllers a compensation directory feeds (``--apply-comp DIR``).

    Returns ``{"per_axis_files": f, "volumetric": g}``, each ``f(machine) ->
    machine``: LinuxCNC with ``<dir>/X.comp``, ``Y.comp``, ``Z.comp``
    (:class:`sim.compensation.AxisCompensation`, looked up at the joint
    positions of the stylus mounted) and a volumetric controller with
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
        out["per_axis_files"] = lambda m: AxisCompensation(m, joints)  # at reading + the mounted stylus's J
    pj = d / f"{name}-comp.json"
    if pj.is_file():
        from core.keyreader import read_text_file

        try:  # not UTF-8 (e.g. compressed): one line naming it, as every text reader (was a traceback)
            doc = json.loads(read_text_file(pj, ConfigError, "compensation file"))
        except json.JSONDecodeError as e:
            raise ConfigError(f"{pj}: not JSON ({e.msg}, line {e.lineno})") from None
        chain, tables, const, pts = comp_tables(doc, source=str(pj))
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


def line_positioning_m(machine, nodes, point_m) -> dict:
    """The machine's exact error along each axis's line through ``point_m`` (3,) readings, m (sim): axis a's
    reading moved over its nodes (axis positions, less the machine's J), the other two at ``point_m``'s, rotary
    axes at 0: the tip deviation's a component, minus its value at the first node (what a per-axis table on
    that line corrects, :func:`comp_line_tables`). ``machine`` with the compensation's stylus."""
    J = np.asarray(machine.config.J_m, float)
    out = {}
    for i, a in enumerate("XYZ"):
        x = np.asarray(nodes[a], float)
        lin = np.tile(np.asarray(point_m, float), (len(x), 1))
        lin[:, i] = x - J[i]
        rot = None if not machine.rotary_axes else np.zeros((len(x), len(machine.rotary_axes)))
        d = np.asarray(machine.tip_W(lin, rot), float)[:, i] - lin[:, i]
        out[a] = d - d[0]
    return out


def _line_in(directory, name: str):
    """The ``per_axis_line`` point of the compensation in ``directory`` (readings, m; its JSON's
    ``readings_mm``), or None: the default files, on the lines through readings 0."""
    import json
    from pathlib import Path

    pj = Path(directory) / f"{name}-comp.json"
    line = json.loads(pj.read_text()).get("per_axis_line") if pj.is_file() else None
    return None if line is None else np.asarray(line["readings_mm"], float) * MM


def stroke_grid(nodes, strokes_m: dict) -> dict:
    """axis -> the nodes continued at their end spacings out to the strokes (axis positions, m; the
    stroke ends included, a point closer than half a spacing to one dropped): the closed loop's grid
    beyond the node box (review29b F1)."""
    out = {}
    for a in "XYZ":
        x = np.asarray(nodes[a], float)
        lo, hi = strokes_m[a]
        h0, h1 = (x[1] - x[0], x[-1] - x[-2]) if len(x) > 1 else (0.025, 0.025)
        below = np.arange(x[0] - h0, lo + 0.5 * h0, -h0)[::-1]
        above = np.arange(x[-1] + h1, hi - 0.5 * h1, h1)
        out[a] = np.r_[[lo] if lo < x[0] - 1e-6 else [], below, x, above, [hi] if hi > x[-1] + 1e-6 else []]
    return out


def stroke_residual_um(machine, nodes, strokes_m: dict) -> dict:
    """The machine's exact errors over its strokes (:func:`stroke_grid`), apart from the node box's:
    per axis the positioning error (:func:`true_positioning_m`'s, zero at the first node) at its grid
    points outside the nodes (``positioning_outside_max_um``) and inside (``positioning_inside_max_um``),
    and the tip deviation over the stroke box (:func:`volumetric_residual_um` on the grid: a rigid
    motion removed over that box). ``machine`` with ``J_m = 0`` for the positioning, the compensation's
    stylus for the box: pass ``(machine_J0, machine_stylus)``."""
    m0, m = machine
    g = stroke_grid(nodes, strokes_m)
    pos = true_positioning_m(m0, g)
    out = {"range_mm": {a: [float(g[a][0]) * 1e3, float(g[a][-1]) * 1e3] for a in "XYZ"},
           "positioning_outside_max_um": {}, "positioning_inside_max_um": {}}
    for a in "XYZ":
        x, n = g[a], np.asarray(nodes[a], float)
        t = np.abs(pos[a] - pos[a][int(np.argmin(np.abs(x - n[0])))]) * 1e6  # zero at the first node
        inside = (x >= n[0] - 1e-9) & (x <= n[-1] + 1e-9)
        out["positioning_outside_max_um"][a] = float(t[~inside].max()) if (~inside).any() else 0.0
        out["positioning_inside_max_um"][a] = float(t[inside].max())
    out["volumetric_residual_um"] = volumetric_residual_um(m, g)
    return out


def closed_loop(name: str, directory, before: ScenarioResult | None = None, *, progress=None, **kw) -> dict:
    """Apply the compensation in ``directory`` to the virtual machine, run the plan again, identify again.

    ``before`` is the uncompensated run (default: :func:`run` with ``kw``).
    Each controller of :func:`compensators` is put in front of the same
    truth machine, and a new campaign is run: the same bar (its true
    deviations drawn with the first run's seed), new probing noise and bar
    placements (seed + 1), identified again. Per axis X, Y, Z: the
    positioning error (``EXX``, ``EYY``, ``EZZ``) identified before and after
    with the U95 of each identification, and the machine's exact
    positioning error (:func:`true_positioning_m`) before and after, and
    whether it lies within the U95 of the identification the compensation
    came from, at every node (``true_within_u95``). The machine's exact
    volumetric error (:func:`volumetric_residual_um`, a rigid motion
    removed), and per controller ``volumetric_check``
    (:func:`volumetric_check`): that error before and after against the
    residual predicted from ``before``'s estimate for the fractions the
    directory's JSON applies (``applied_factor``; all 1 without it), with
    its U95: the verdict on what the user cares about. The prediction
    assumes the directory was written from ``before``. ``progress(done,
    total)``: over the new campaigns, each :func:`run`'s steps (the CLI's
    line with the time left).
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

    def block(r, comp=None, applied=None, pred_line=None):
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
        m = truth(STYLI[COMP_STYLUS], comp)
        out = {"positioning": pos, "volumetric_residual_um": volumetric_residual_um(m, r.plan.nodes)}
        on = line_positioning_m(m, r.plan.nodes, np.zeros(3) if line is None else line)
        out["on_comp_line"] = {"readings_mm": [0.0, 0.0, 0.0] if line is None else [float(v) / MM for v in line],
                               "max_abs_um": {a: float(np.abs(on[a]).max() * 1e6) for a in "XYZ"}}
        if before.strokes_m:  # beyond the node box, out to the strokes: the extrapolation checked (F1)
            out["strokes"] = stroke_residual_um((truth((0.0, 0.0, 0.0), comp), m), r.plan.nodes, before.strokes_m)
        if applied is not None:  # the exact volumetric error against the one predicted from `before`
            out["volumetric_check"] = volumetric_check(R_before, _volumetric_deviation(m, r.plan.nodes),
                                                       _prediction(before, applied, pred_line))
            out["applied_factor"] = dict(applied)
        return out

    R_before = _volumetric_deviation(truth(STYLI[COMP_STYLUS]), before.plan.nodes)
    applied = _applied_in(directory, name)
    line = _line_in(directory, name)

    doc = {"format": CLOSED_LOOP_FORMAT, "scenario": name, "directory": str(directory), "seed_before": seed,
           "seed_after": seed + 1,
           "criterion": "volumetric_check: the exact tip deviation over the node box (rigid motion removed) "
                        "after compensation against the residual predicted from the identification with its U95 "
                        "(within_u95: points inside), improved: fell by more than the U95, not_worse: never above "
                        "before + U95; beside it the true positioning error (exact sim) within the U95 of the "
                        "identification the compensation came from, at every node (true_within_u95)",
           "before": block(before)}
    for i, (key, comp) in enumerate(ctl.items()):
        each = None if progress is None else (lambda k, n, i=i: progress(i * n + k, len(ctl) * n))
        r = run(name, seed=seed + 1, bar_seed=seed, compensate=comp, progress=each, **kw)
        doc[key] = block(r, comp, applied if key == "volumetric" or line is not None
                         else {s: applied[s] for s in ("EXX", "EYY", "EZZ")},
                         line if key == "per_axis_files" else None)
    return doc


# --------------------------------------------------------------------------- reversal on a CMM (eqs 5-7)
def reversal_on_cmm(*, repeats: int = 5, seed: int = 1, noise_um: float = 0.05, deviations_m=None,
                    cmm_errors: dict | None = None, u_place=None, align_roll: bool = True,
                    step_gauge_abbe: bool = True) -> dict:
    """Calibrate the bar by reversal on a simulated CMM, touches and all (Viprey 2016 eqs 5-7).

    The CMM is the ``vmc-3axis`` chain with its own errors (default: EXX 2
    um/m, EYX and EZX bows of 1.5 / -1.1 um over the bar against its
    end-point line), probing noise
    ``noise_um`` (k = 1). The bar lies along the CMM's X, probed over its
    12 holes, rods and faces: ``repeats`` times as it is (NR) and turned 180
    deg about its x axis (R, the rods touched from the other side), each
    time re-placed (``u_place``: translation m, rotation rad, standard; default
    :data:`U_PLACE_CMM`, a roll of 0.5 mrad among them).
    Points of interest from the touches (:func:`core.mfb.points_of_interest`),
    aligned as the CMM's operator aligns on the bar (:func:`core.mfb.align_on_cmm`:
    O_1 at the origin, the roll from the bar's PL_ref, y and z against O_1 O_12;
    ``align_roll=False``: the line alone, which leaves a roll common to both
    orientations in Ezx at the shifted holes 2 and 5, review31b F1).
    The CMM's positioning error at the holes as a step gauge along the bar's
    line gives it: the x error of the CMM's tip there, its angular errors at
    that line's offsets (Abbe) included (``step_gauge_abbe=False``: EXX(x) alone,
    what this did before session 31, off by the Abbe terms: review31b F5), plus a
    draw of the paper's U(k=2) = 0.3 um + 1.5e-6 L. Then
    :func:`core.mfb.reversal_calibration`.

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
    u_place = U_PLACE_CMM if u_place is None else u_place
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
            poi = mfb.points_of_interest(t.p_R, t.feature, t.n_R)
            # the CMM's alignment on the bar (the bar "carefully aligned along the CMM
            # axis"; eq. 6 then gives the straightness against its end-point line), the
            # roll from the bar's rods
            M[key].append(mfb.align_on_cmm(poi.O_R, poi.T_R_M[:3, 2], roll=align_roll))
    x_cmm = T_nr[0, 3] + np.arange(12) * A.MFB_PITCH_M
    if step_gauge_abbe:
        # the step gauge lies along the bar's line (O_i of the bar as designed, unshifted, in
        # the CMM's frame) and is probed with the same stylus: what it reads there is the x
        # component of the CMM's tip error at those points, Abbe terms and all (eq. 5's sign:
        # M = true - E, E = actual tip - reading)
        line = (T_nr @ np.c_[np.arange(12) * A.MFB_PITCH_M, np.zeros((12, 2)), np.ones(12)].T).T[:, :3]
        exx = (cmm.tip_W(line) - cmm.tip_W_nominal(line))[:, 0]
    else:
        exx = np.asarray(errs["EXX"](x_cmm), float) if "EXX" in errs else np.zeros(12)
    # the step gauge's calibrated distances from its reference face at O_1 (core's u, one formula), each with
    # its certificate's error; the reference face's own distance is 0 by definition, without error (session 31,
    # tests31: drawing one there too put it into every hole's Exx, as compared from hole 1, beyond the U95 of the
    # distance's certificate: seeds 2-25, holes 2-12, 21/264 outside, RMS error/U95 0.566; without it 16/264, 0.513)
    sg_err = rng.standard_normal(12) * mfb.step_gauge_u_m(np.arange(12) * A.MFB_PITCH_M)
    sg_err[0] = 0.0   # (its u, step_gauge_u_m(0), is 0 since session 32: the draw there is 0 * N(0, 1), maybe -0.0)
    exx_sg = exx - exx[0] + sg_err
    cal = mfb.reversal_calibration(np.array(M["NR"]), np.array(M["R"]), exx_sg)
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
    return {"calibration": cal, "true_m": truth, "deviations_m": E_true, "compared_um": out, "repeats": int(repeats),
            "touches": 2 * int(repeats) * pl.n}


#: Format tag of the bar calibration file (:func:`bar_calibration_doc`).
BAR_CALIBRATION_FORMAT = "vmt-bar-calibration/1"
#: Format of a scenario's document (:attr:`ScenarioResult.doc`, ``vmt scenario mfb-3axis --json``).
MFB_FORMAT = "vmt-mfb/1"
#: Format of :func:`closed_loop`'s document (``closed_loop`` in the scenario's JSON).
CLOSED_LOOP_FORMAT = "vmt-mfb-closed-loop/1"


def bar_calibration_doc(rev: dict) -> dict:
    """The reversal calibration (:func:`reversal_on_cmm`) as a JSON document.

    ``format`` (:data:`BAR_CALIBRATION_FORMAT`), ``x_mm`` (12 nominal x of
    the points of interest), ``E_um`` and ``u_um`` ((12, 3) lists: Exx, Eyx,
    Ezx of each point and their standard uncertainties), ``U95_um``,
    ``n_repeats``; for a simulated bar also ``true_deviations_um`` (the
    deviations the simulated bar was built with, what an MFB run then
    simulates) and ``compared_um`` (the estimate against them).
    """
    from sim import artefacts as A

    cal = rev["calibration"]
    doc = {"format": BAR_CALIBRATION_FORMAT, "x_mm": (np.arange(12) * A.MFB_PITCH_M * 1e3).tolist(),
           "E_um": (np.asarray(cal.E_m) * 1e6).tolist(), "u_um": (np.asarray(cal.u_m) * 1e6).tolist(),
           "U95_um": (np.asarray(cal.U95_m) * 1e6).tolist(), "n_repeats": int(cal.n_repeats),
           "touches": rev.get("touches"), "compared_um": rev.get("compared_um")}
    if rev.get("deviations_m") is not None:
        doc["true_deviations_um"] = (np.asarray(rev["deviations_m"]) * 1e6).tolist()
    return doc


#: ``x_mm`` of a bar calibration file must be the bar's 12 points of interest (0, 50, ..., 550 mm: the
#: pitch ``sim.artefacts.MFB_PITCH_M``) within this, mm (review31 F8: another bar's x_mm was used without a
#: word). 0.01 mm holds any rounding of a written or hand-typed position (vmt writes 150.00000000000003)
#: and is 2,500 times below the 25 mm a bar with its holes between ours would be off.
BAR_X_TOL_MM = 0.01


def _check_bar_x(path, doc: dict) -> None:
    """Refuse a calibration whose ``x_mm`` are not the bar's points of interest (:data:`BAR_X_TOL_MM`)."""
    from core.exceptions import ConfigError
    from sim import artefacts as A

    nominal = np.arange(12) * A.MFB_PITCH_M * 1e3
    if "x_mm" not in doc:
        raise ConfigError(f"bar calibration {path}: x_mm missing (the 12 points of interest, "
                          f"{nominal[0]:g}, {nominal[1]:g}, ..., {nominal[-1]:g} mm)")
    try:
        x = np.asarray(doc["x_mm"], float)
    except (TypeError, ValueError):
        x = np.zeros(0)
    if x.shape != (12,) or not np.all(np.isfinite(x)):
        raise ConfigError(f"bar calibration {path}: x_mm must be 12 finite numbers (mm)")
    off = np.flatnonzero(np.abs(x - nominal) > BAR_X_TOL_MM)
    if off.size:
        i = int(off[0])
        raise ConfigError(f"bar calibration {path}: x_mm[{i}] = {x[i]:g} mm is not the bar's point of interest "
                          f"{i + 1} at {nominal[i]:g} mm (tolerance {BAR_X_TOL_MM:g} mm; the bar's points are "
                          f"{nominal[0]:g}, {nominal[1]:g}, ..., {nominal[-1]:g} mm): a calibration of another bar")


def read_bar_calibration(path):
    """Read a bar calibration file (:func:`bar_calibration_doc`).

    Returns ``(calibration, true_m)``: a :class:`core.mfb.BarCalibration`
    and the simulated bar's true deviations (12, 3) m, or None when the file
    has none. A file that is missing, not JSON, of another format or with
    arrays not finite (12, 3) (u >= 0) raises :class:`core.exceptions.ConfigError`
    naming the problem, as does one whose ``x_mm`` are not the bar's 12
    points of interest (:data:`BAR_X_TOL_MM`).
    """
    import json

    from core.exceptions import ConfigError
    from core.mfb import BarCalibration

    from core.atomic import not_text_problem

    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise ConfigError(f"bar calibration {path}: cannot read ({e.strerror or e})") from None
    try:
        doc = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as e:  # e.g. a compressed file: which compression, how to decompress it
        raise ConfigError(f"bar calibration {path}: {not_text_problem(path, data[:8], e)}") from None
    except json.JSONDecodeError as e:
        raise ConfigError(f"bar calibration {path}: not JSON ({e})") from None
    if not isinstance(doc, dict) or doc.get("format") != BAR_CALIBRATION_FORMAT:
        raise ConfigError(f"bar calibration {path}: format must be {BAR_CALIBRATION_FORMAT!r}")

    def arr(key, required=True):
        if key not in doc:
            if required:
                raise ConfigError(f"bar calibration {path}: {key} missing")
            return None
        try:
            a = np.asarray(doc[key], float)
        except (TypeError, ValueError):
            a = np.zeros(0)
        if a.shape != (12, 3) or not np.all(np.isfinite(a)):
            raise ConfigError(f"bar calibration {path}: {key} must be 12 rows of 3 finite numbers (um)")
        return a * 1e-6

    E, u = arr("E_um"), arr("u_um")
    if np.any(u < 0):
        raise ConfigError(f"bar calibration {path}: u_um must be >= 0 (standard uncertainties)")
    _check_bar_x(path, doc)
    n = doc.get("n_repeats", 0)
    U = arr("U95_um", False)
    return (BarCalibration(E, u, 2.0 * u if U is None else U, int(n) if isinstance(n, int) else 0),
            arr("true_deviations_um", False))


# --------------------------------------------------------------------------- uncertainty budget
#: The budget's sources, in the order of its table.
BUDGET_SOURCES = ("probing noise", "bar calibration", "placement", "stylus offsets", "lobing",
                  "bar temperature", "machine temperature")


def _budget_settings(mc_runs, stylus_runs, temperature_range_C):
    from core.exceptions import ConfigError

    if int(mc_runs) < 2 or int(stylus_runs) < 2:
        raise ConfigError(f"budget: mc_runs and stylus_runs must be >= 2, got {mc_runs!r}, {stylus_runs!r}")
    t_lo, t_hi = (float(t) for t in temperature_range_C)
    if not (np.isfinite(t_lo) and np.isfinite(t_hi) and t_lo <= t_hi):
        raise ConfigError(f"budget: temperature_range_C must be (low, high), got {temperature_range_C!r}")
    return t_lo, t_hi


def budget_draws(seed: int, attempts: int, temperature_range_C: tuple = (19.0, 22.0)) -> np.ndarray:
    """(attempts, 2) the budget's Monte Carlo draws of attempts 1..``attempts``: the shop
    temperature T (degC, uniform over ``temperature_range_C``) and the lobing phase (rad,
    uniform), from ``np.random.default_rng(seed + 1000)`` in attempt order; attempt ``j``
    runs the pipeline with ``seed + j`` (:func:`budget_run`). Any attempt is reproduced
    alone, so a study can be resumed or split between processes."""
    t_lo, t_hi = (float(t) for t in temperature_range_C)
    rng = np.random.default_rng(seed + 1000)
    out = np.empty((int(attempts), 2))
    for j in range(int(attempts)):
        out[j] = float(rng.uniform(t_lo, t_hi)), float(rng.uniform(0.0, 2.0 * np.pi))
    return out


def budget_run(name: str, j: int, *, seed: int = 1, u_stylus_um: float = 0.5, lobing_um: float = 0.25,
               lobing_k: int = 3, temperature_range_C: tuple = (19.0, 22.0), bar_calibration=None,
               bar_true_m=None) -> dict:
    """Monte Carlo attempt ``j`` (1, 2, ...) of :func:`budget`: the whole pipeline with every
    source drawn (:func:`budget_draws` for T and the lobing phase, ``seed + j`` for the rest).

    Returns ``{"j", "T_C", "phase_rad", "error" (n,) identified - true (m, rad), "U95_lin" (n,)
    the run's own linear U95}``, or ``{"j", "T_C", "phase_rad", "lost": message}`` when the
    drawn placement puts the bar beyond the program's margins (a :class:`core.exceptions.PlanError`;
    any other error raises).
    """
    from core.exceptions import PlanError

    T, ph = budget_draws(seed, j, temperature_range_C)[j - 1]
    a = float(lobing_um) * 1e-6
    out = {"j": int(j), "T_C": float(T), "phase_rad": float(ph)}
    try:
        r = run(name, mc_runs=0, bar_calibration=bar_calibration, bar_true_m=bar_true_m, seed=seed + j,
                u_stylus_um=u_stylus_um, lobing_m=((lobing_k, a * np.cos(ph), a * np.sin(ph)),),
                bar_temperature_C=float(T), machine_temperature_C=float(T), model_error_held=False)
    except PlanError as e:
        # the drawn placement puts the bar beyond the program's margins (placement_margin_m, 5 sigma):
        # on a machine the probe would strike or miss the bar and the operator would set it again
        out["lost"] = str(e)
        return out
    out["error"] = r.result.theta - r.truth
    out["U95_lin"] = r.unc.U95_lin
    return out


def budget_shares(name: str = "mfb-3axis", *, seed: int = 1, stylus_runs: int = 6, u_stylus_um: float = 0.5,
                  lobing_um: float = 0.25, lobing_k: int = 3, temperature_range_C: tuple = (19.0, 22.0),
                  bar_calibration=None, bar_true_m=None, stylus_components: bool = False, progress=None) -> dict:
    """Each source's U95 share per parameter (:func:`budget`, one source at a time): ``U``
    {source: (n,)}, ``U_temp`` (n,) bar and machine at one temperature, ``sens`` {source: (n,)}
    per degC, ``keep`` (n,) bool (the 21 errors' values less the ones the conventions fix),
    ``slices`` {symbol: (start, stop)}, ``t_rms``; m / rad.

    ``stylus_components``: the stylus share from one noise-free pipeline run per offset
    component of each stylus (``u_stylus_um`` on it alone: 3 x the plan's styli runs), 2 x the
    root sum of squares of the changes: exact for a response linear in the offsets (the
    draws' share, ``stylus_runs`` random draws, is +-30 % from 6 of them)."""
    from core import mfb, volumetric as vol

    t_lo, t_hi = _budget_settings(2, stylus_runs, temperature_range_C)
    cal_map = mfb.calibration_map()  # the heights as the rods give them (as run propagates them)
    styli = list(dict.fromkeys(ms.stylus for ms in PLANS[name]().measurements)) if name in PLANS else []
    total = 5 + (3 * len(styli) if stylus_components else int(stylus_runs))
    step = [0]

    def go(**kw):
        if progress is not None:
            progress(step[0], total)
        step[0] += 1
        return run(name, mc_runs=0, bar_calibration=bar_calibration, bar_true_m=bar_true_m, **kw)

    quiet = dict(noise_um=0.0, draw_inputs=False)
    base = go(seed=seed, **quiet)
    d = base.result.design
    sigma = 0.125e-6
    u_cal = (np.tile(np.asarray(inspect_default("u_cal_um"), float) * 1e-6, (12, 1))
             if bar_calibration is None else np.asarray(bar_calibration.u_m, float))
    U = {}
    for src, (sg, uc, up) in {"probing noise": (sigma, 0 * u_cal, None),
                              "bar calibration": (0.0, u_cal, None),
                              "placement": (0.0, 0 * u_cal, np.asarray(U_PLACE, float))}.items():
        U[src] = vol.uncertainty(base.result, base.meas, sg, uc, runs=0, u_place=up, cal_map=cal_map).U95_lin
    full_lin = vol.uncertainty(base.result, base.meas, sigma, u_cal, runs=0, u_place=np.asarray(U_PLACE, float),
                               cal_map=cal_map)
    gauge = full_lin.U95_lin <= 1e-12  # values the conventions fix (zero U95 whatever the input)
    th0 = base.result.theta
    if stylus_components:
        u = float(u_stylus_um) * 1e-6
        dst = np.array([go(seed=seed, stylus_dJ_m={st: u * np.eye(3)[c]}, **quiet).result.theta - th0
                        for st in styli for c in range(3)])
        U["stylus offsets"] = 2.0 * np.sqrt(np.sum(dst ** 2, axis=0))
    else:
        dst = np.array([go(seed=seed + 100 + k, u_stylus_um=u_stylus_um, **quiet).result.theta - th0
                        for k in range(int(stylus_runs))])
        U["stylus offsets"] = 2.0 * np.sqrt(np.mean(dst ** 2, axis=0))
    a = float(lobing_um) * 1e-6
    dc = go(seed=seed, lobing_m=((lobing_k, a, 0.0),), **quiet).result.theta - th0
    ds = go(seed=seed, lobing_m=((lobing_k, 0.0, a),), **quiet).result.theta - th0
    U["lobing"] = 2.0 * np.sqrt((dc ** 2 + ds ** 2) / 2.0)
    t_rms = float(np.sqrt(((t_hi - 20.0) ** 3 - (t_lo - 20.0) ** 3) / (3.0 * (t_hi - t_lo)))) if t_hi > t_lo \
        else abs(t_lo - 20.0)
    sens = {"bar temperature": go(seed=seed, bar_temperature_C=21.0, **quiet).result.theta - th0,
            "machine temperature": go(seed=seed, machine_temperature_C=21.0, **quiet).result.theta - th0}
    for src, s_ in sens.items():
        U[src] = 2.0 * np.abs(s_) * t_rms
    # bar and machine share the shop's temperature: one source, their changes add with their signs
    U_temp = 2.0 * np.abs(sens["bar temperature"] + sens["machine temperature"]) * t_rms
    # the 21 errors' values (theta also holds each set-up's pose), less the ones the conventions fix
    errs_idx = np.zeros(len(gauge), bool)
    for s in (*vol.MOTION, *vol.SQUARENESS):
        errs_idx[d.slices[s]] = True
    if progress is not None:
        progress(total, total)
    return {"U": U, "U_temp": U_temp, "sens": sens, "keep": errs_idx & ~gauge, "t_rms": t_rms,
            "slices": {s: (d.slices[s].start, d.slices[s].stop) for s in (*vol.MOTION, *vol.SQUARENESS)},
            "stylus_runs": len(dst), "stylus_components": bool(stylus_components)}


def budget_summary(name: str, shares: dict, errors, U95_lin, *, seed: int = 1, u_stylus_um: float = 0.5,
                   lobing_um: float = 0.25, lobing_k: int = 3, temperature_range_C: tuple = (19.0, 22.0),
                   runs_lost: list = (), runs_drawn: int | None = None) -> dict:
    """The budget's table from the shares (:func:`budget_shares`) and the Monte Carlo runs'
    ``errors`` (runs, n) identified - true and their own linear ``U95_lin`` (runs, n): a pure
    function, so a stored study's summary can be recomputed from its per-run vectors."""
    from core import iso, volumetric as vol

    t_lo, t_hi = (float(t) for t in temperature_range_C)
    errs, own = np.asarray(errors, float), np.asarray(U95_lin, float)
    U, U_temp, keep, t_rms = shares["U"], shares["U_temp"], np.asarray(shares["keep"], bool), shares["t_rms"]
    quad = np.sqrt(sum(U[s] ** 2 for s in BUDGET_SOURCES[:5]) + U_temp ** 2)
    mc = 2.0 * np.sqrt(np.mean(errs ** 2, axis=0))
    per = {}
    for s in (*vol.MOTION, *vol.SQUARENESS):
        if s not in shares["slices"]:
            continue
        sl = slice(*shares["slices"][s])
        k = keep[sl]
        if not np.any(k):
            continue
        q, m = quad[sl][k], mc[sl][k]
        per[s] = {"unit": iso.symbol(s).report_unit,
                  "U95": {src: float(U[src][sl][k].max() * 1e6) for src in BUDGET_SOURCES},
                  "temperature_one_T": float(U_temp[sl][k].max() * 1e6),
                  "quadrature": float(q.max() * 1e6), "mc": float(m.max() * 1e6),
                  "mc_over_quadrature": float(m.max() / q.max()),
                  "dominant": max(BUDGET_SOURCES, key=lambda src: float(U[src][sl][k].max()))}
    ratio = mc[keep] / quad[keep]
    inside = int(np.sum(np.abs(errs[:, keep]) <= quad[keep]))
    inside_own = int(np.sum(np.abs(errs[:, keep]) <= own[:, keep]))
    n = int(errs[:, keep].size)
    runs = len(errs)
    stylus_runs = shares["stylus_runs"]
    return {"scenario": name, "sources": list(BUDGET_SOURCES), "mc_runs": runs, "stylus_runs": stylus_runs,
            "seed": seed, "u_stylus_um": u_stylus_um, "lobing": {"k": lobing_k, "amplitude_um": lobing_um},
            "temperature_range_C": [t_lo, t_hi], "temperature_rms_from_20_C": t_rms,
            "machine_cte_per_C": MACHINE_CTE_PER_C, "bar_cte_per_C": 1.0e-6,
            "method": ("Per source, its U95 share (k = 2, max over the nodes, gauge nodes left out): probing "
                       "noise, bar calibration and placement by linear propagation through the estimator; "
                       + (f"stylus offsets from {stylus_runs} noise-free pipeline runs, one per offset component "
                          "of each stylus (2 x root sum of squares: exact for a linear response); "
                          if shares.get("stylus_components") else
                          f"stylus offsets from {stylus_runs} noise-free pipeline runs with that draw alone "
                          "(2 x RMS); ")
                       + "lobing from 2 pipeline runs (cos and sin term, 2 x RMS over the phase); bar "
                       "and machine temperature from one pipeline run at 21 degC each (2 x change per degC x "
                       f"{t_rms:.2f} degC, the RMS of T - 20 over {t_lo:g}-{t_hi:g} degC; in the sum as one source, "
                       f"bar and machine at the same T, their changes added with their signs). MC: {runs} "
                       "runs of the whole pipeline with every source drawn, 2 x RMS of identified - true."),
            "per_error": per, "runs_lost": list(runs_lost),
            "runs_drawn": runs + len(runs_lost) if runs_drawn is None else int(runs_drawn),
            "runs_lost_note": ("a run is lost when its drawn placement puts the bar beyond the program's approach "
                               f"margins ({placement_margin_m() / MM:g} mm, 5 sigma of the placement at the far "
                               "end): counted here and redrawn, as an operator would set the bar again"),
            "ratio_range": [float(ratio.min()), float(np.median(ratio)), float(ratio.max())],
            "coverage": {"within_quadrature_U95": f"{inside}/{n}", "fraction_quadrature": inside / n,
                         "within_run_linear_U95": f"{inside_own}/{n}", "fraction_run_linear": inside_own / n,
                         "note": "run linear U95: the noise, calibration and placement the identification "
                                 "propagates (what vmt scenario reports without the budget)"},
            "temperature_sensitivity_per_C": {
                src: {s: float(np.abs(v[slice(*shares["slices"][s])]).max() * 1e6) for s in ("EXX", "EYY", "EZZ")
                      if s in shares["slices"]}
                for src, v in shares["sens"].items()}}


def budget(name: str = "mfb-3axis", *, mc_runs: int = 20, seed: int = 1, stylus_runs: int = 6,
           u_stylus_um: float = 0.5, lobing_um: float = 0.25, lobing_k: int = 3,
           temperature_range_C: tuple = (19.0, 22.0), bar_calibration=None, bar_true_m=None,
           progress=None) -> dict:
    """The MFB identification's uncertainty budget, one source at a time, and a Monte
    Carlo through the whole pipeline with all of them (JCGM 101).

    Sources (:data:`BUDGET_SOURCES`) and how each one's share is obtained:

    - probing noise (the probe's 0.125 um, k = 1), bar calibration (``u_cal``
      or ``bar_calibration.u_m``), placement (:data:`U_PLACE`): linear
      propagation through the identification's estimator
      (:func:`core.volumetric.uncertainty`, one source switched on at a time);
    - stylus offsets (each component of each stylus off by N(0, ``u_stylus_um``)):
      ``stylus_runs`` noise-free runs of the pipeline with that draw alone,
      2 x RMS of the change (a rough share: ``stylus_runs`` draws);
    - lobing (``lobing_k`` lobes of amplitude ``lobing_um``, phase unknown,
      uniform): two noise-free pipeline runs, the cos and the sin term; the
      share 2 x RMS over the phase, ``sqrt((d_c^2 + d_s^2) / 2)``, exact for
      the linear response;
    - bar and machine temperature (the shop at ``temperature_range_C``,
      uniform; the bar Invar, the machine's scales :data:`MACHINE_CTE_PER_C`;
      nothing corrected): one noise-free pipeline run at 21 degC each gives
      the change per degC; the share is 2 x that x the RMS of T - 20
      (1.0 degC for 19-22), a bias mostly (mean 20.5). Bar and machine are at
      the shop's one temperature: in the sum they enter as one source, their
      changes added with their signs (``temperature_one_T``).

    The Monte Carlo: ``mc_runs`` runs of the pipeline (simulate, fit,
    extract, identify) with every source drawn (one T for bar and machine,
    the lobing phase uniform); per parameter, 2 x RMS of identified - true
    (``mc_runs`` is too few for percentiles), against the quadrature sum of
    the shares; coverage: the runs' errors within the sum, and within the
    run's own linear U95 (noise, calibration, placement only).

    Returns a JSON-ready dict: ``sources``, ``method``, ``per_error``
    ``{symbol: {unit, U95: {source: max over nodes}, quadrature, mc,
    mc_over_quadrature}}``, ``coverage``, ``ratio_range`` and the settings.
    """
    from core.exceptions import PlanError

    _budget_settings(mc_runs, stylus_runs, temperature_range_C)
    kw = dict(seed=seed, u_stylus_um=u_stylus_um, lobing_um=lobing_um, lobing_k=lobing_k,
              temperature_range_C=temperature_range_C, bar_calibration=bar_calibration, bar_true_m=bar_true_m)
    total = 6 + int(stylus_runs) + int(mc_runs)
    shares = budget_shares(name, stylus_runs=stylus_runs, **kw,
                           progress=None if progress is None else (lambda k, _n: progress(k, total)))
    runs, lost = [], []
    j = 0
    while len(runs) < int(mc_runs):
        j += 1
        if progress is not None:
            progress(6 + int(stylus_runs) + len(runs), total)
        r = budget_run(name, j, **kw)
        if "lost" in r:
            # counted and redrawn (the placement distribution is truncated there); any other error is a
            # bug and raises (in budget_run)
            lost.append({"seed": seed + j, "error": r["lost"]})
            if len(lost) > max(2, int(mc_runs) // 5):
                raise PlanError(f"budget: {len(lost)} of {j} runs lost (the bar beyond the program's margins): "
                                  + r["lost"])
            continue
        runs.append(r)
    if progress is not None:
        progress(total, total)
    kw.pop("bar_calibration"), kw.pop("bar_true_m")
    return budget_summary(name, shares, [r["error"] for r in runs], [r["U95_lin"] for r in runs],
                          runs_lost=lost, runs_drawn=j, **kw)


def describe_budget(b: dict) -> str:
    """The budget for the terminal: one line per error (each source's U95 share, the sum,
    the Monte Carlo, their ratio), then the coverage."""
    short = {"probing noise": "noise", "bar calibration": "bar cal", "placement": "place",
             "stylus offsets": "stylus", "lobing": "lobing", "bar temperature": "T bar",
             "machine temperature": "T mach"}
    head = f"{'error':6s} {'unit':5s}" + "".join(f"{short.get(s, s):>8s}" for s in b["sources"]) + \
        f"{'T one':>8s}{'sum':>8s}{'MC':>8s}{'MC/sum':>8s}"
    lines = [f"uncertainty budget, U95 (k=2) max over the nodes; {b['mc_runs']} pipeline runs (T one: bar and "
             "machine at the same temperature, what the sum takes)", head]
    for s, c in b["per_error"].items():
        lines.append(f"{s:6s} {c['unit']:5s}" + "".join(f"{c['U95'][k]:8.2f}" for k in b["sources"])
                     + f"{c.get('temperature_one_T', float('nan')):8.2f}{c['quadrature']:8.2f}{c['mc']:8.2f}{c['mc_over_quadrature']:8.2f}")
    cv = b["coverage"]
    lo, med, hi = b["ratio_range"]
    lines.append(f"MC / sum per node: {lo:.2f} - {hi:.2f} (median {med:.2f}); within the sum's U95 "
                 f"{cv['within_quadrature_U95']}, within the run's linear U95 {cv['within_run_linear_U95']}"
                 + (f"; {len(b['runs_lost'])} of {b.get('runs_drawn', '?')} runs lost (the bar beyond the "
                    "program's margins) and redrawn" if b.get("runs_lost") else ""))
    return "\n".join(lines)


def inspect_default(param: str):
    """The default of one of :func:`run`'s parameters."""
    import inspect

    return inspect.signature(run).parameters[param].default


# --------------------------------------------------------------------------- a long budget study, resumable
def _npz_atomic(path, **arrays):
    """Write an .npz by a temporary file renamed over ``path`` (a run is whole or absent)."""
    import os
    from pathlib import Path

    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays)
    os.replace(tmp, path)
    return path


def _study_attempt(task):
    """One Monte Carlo attempt of a study, written to its own file (for :func:`budget_study`'s workers)."""
    name, j, directory, kw = task
    from pathlib import Path

    path = Path(directory) / f"run-{j:05d}.npz"
    if path.exists():
        return j
    t0, c0 = time.perf_counter(), time.process_time()
    r = budget_run(name, j, **kw)
    spent = dict(wall_s=time.perf_counter() - t0, cpu_s=time.process_time() - c0)
    if "lost" in r:
        _npz_atomic(path, j=j, T_C=r["T_C"], phase_rad=r["phase_rad"], lost=np.array(r["lost"]), **spent)
    else:
        _npz_atomic(path, j=j, T_C=r["T_C"], phase_rad=r["phase_rad"], error=r["error"], U95_lin=r["U95_lin"],
                    **spent)
    return j


def budget_study(name: str, directory, runs: int = 1000, *, workers: int = 1, seed: int = 1, stylus_runs: int = 6,
                 stylus_components: bool = True, chunk: int = 8, progress=None, **kw) -> dict:
    """:func:`budget` with ``runs`` Monte Carlo runs, each run written to ``directory`` as it ends
    (``run-NNNNN.npz``; the shares to ``shares.npz``): interrupted, it resumes where it stopped and
    loses at most the runs in progress. Attempts run in order (``workers`` processes,
    one pool of spawned processes), each from its own seed (:func:`budget_draws`), so the result does
    not depend on the workers or on the interruptions. The stylus share by components
    (:func:`budget_shares`, ``stylus_components``) unless told otherwise. Returns
    :func:`study_arrays` of what is done."""
    import contextlib
    from pathlib import Path

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    settings = dict(seed=seed, **kw)
    if not (d / "shares.npz").exists():
        sh = budget_shares(name, stylus_runs=stylus_runs, stylus_components=stylus_components, **settings)
        _npz_atomic(d / "shares.npz", keep=sh["keep"], U_temp=sh["U_temp"], t_rms=sh["t_rms"],
                    stylus_runs=sh["stylus_runs"], stylus_components=sh.get("stylus_components", False), slices=np.array([(s, *v) for s, v in sh["slices"].items()], object),
                    **{f"U:{s}": v for s, v in sh["U"].items()}, **{f"sens:{s}": v for s, v in sh["sens"].items()})
    with contextlib.ExitStack() as stack:
        mapper = map
        if workers > 1:
            # one pool for the whole study: its processes keep their imports and first-use caches
            # (the extraction's gains, the nominal design, the 5-axis collision check)
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            mapper = stack.enter_context(ProcessPoolExecutor(max_workers=workers,
                                                             mp_context=mp.get_context("spawn"))).map
        while True:
            st = study_arrays(d, runs)
            ok = int(st["ok"].sum())
            if ok >= runs:
                return st
            if progress is not None:
                progress(ok, runs)
            done = {int(p.stem[4:]) for p in d.glob("run-*.npz")}
            top = max(done, default=0)
            size = max(1, workers) * chunk
            # the holes an interruption left first, then new attempts (a couple beyond the need, for lost runs)
            todo = [j for j in range(1, top + 1) if j not in done][:size] or \
                list(range(top + 1, top + 1 + max(1, min(size, runs - ok + 2))))
            list(mapper(_study_attempt, [(name, j, str(d), settings) for j in todo]))


def remake_study_with_share(name: str, directory, runs: int = 1000, *, stored=None, progress=None) -> dict:
    """Make a stored budget study again with the model-error share on (review33a F4, session 34), into
    ``directory`` (resumable, as :func:`budget_study`): model (3)'s linear extraction, as the stored studies were
    made (``core.volumetric.EXACT_EXTRACTION`` False while it runs), :data:`MFB_MODEL_ERROR_SHARE` True while it
    runs (and :data:`MFB_BETWEEN_NODES` off: a note, it moves neither of the two things a study run keeps), the
    shares (noise-free runs, which the share does not touch) copied from ``stored`` (default
    ``scenarios/data/NAME-budget-study.npz``), every attempt run again in this process. The runs' ``error``
    must come back equal to the stored ones (the share moves no estimate; only the gated runs' own U95 grow):
    check them before :func:`assemble_study` replaces the file. Returns :func:`study_arrays` of what is done."""
    from pathlib import Path

    from core import volumetric as vol

    global MFB_MODEL_ERROR_SHARE, MFB_BETWEEN_NODES
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    stored = Path(__file__).resolve().parent / "data" / f"{name}-budget-study.npz" if stored is None else Path(stored)
    if not (d / "shares.npz").exists():
        keys = ("keep", "U_temp", "t_rms", "stylus_runs", "stylus_components", "slices")
        with np.load(stored, allow_pickle=True) as z:
            _npz_atomic(d / "shares.npz", **{k: z[k] for k in z.files if k in keys or k.startswith(("U:", "sens:"))})
    # the between-node test off while it runs: a note only (it reads no draw and moves neither a run's error nor
    # its U95, the two things a study run keeps), and half of a remade run's CPU (session 34: 3-axis 1.93 -> 0.92 s,
    # 5-axis 1.69 -> 0.87 s a run, means over 52-60 runs each)
    was = (vol.EXACT_EXTRACTION, MFB_MODEL_ERROR_SHARE, MFB_BETWEEN_NODES)
    vol.EXACT_EXTRACTION, MFB_MODEL_ERROR_SHARE, MFB_BETWEEN_NODES = False, True, False
    try:
        return budget_study(name, d, runs, workers=1, progress=progress)
    finally:
        vol.EXACT_EXTRACTION, MFB_MODEL_ERROR_SHARE, MFB_BETWEEN_NODES = was


def study_arrays(directory, runs: int | None = None) -> dict:
    """The runs of a study directory (:func:`budget_study`) as arrays: the attempts 1..J of the
    longest complete prefix, ``ok`` (J,) bool, ``T_C``, ``phase_rad`` (J,), ``error`` and
    ``U95_lin`` (runs ok, n), ``lost`` [(j, message)]; at most ``runs`` runs that are ok."""
    from pathlib import Path

    d = Path(directory)
    js = sorted(int(p.stem[4:]) for p in d.glob("run-*.npz"))
    J = 0
    while J < len(js) and js[J] == J + 1:
        J += 1
    ok, T, ph, err, own, lost = [], [], [], [], [], []
    for j in range(1, J + 1):
        if runs is not None and len(err) >= runs:
            break
        with np.load(d / f"run-{j:05d}.npz") as z:
            T.append(float(z["T_C"]))
            ph.append(float(z["phase_rad"]))
            if "lost" in z.files:
                ok.append(False)
                lost.append((j, str(z["lost"])))
            else:
                ok.append(True)
                err.append(z["error"])
                own.append(z["U95_lin"])
    return {"ok": np.array(ok, bool), "T_C": np.array(T), "phase_rad": np.array(ph),
            "error": np.array(err), "U95_lin": np.array(own), "lost": lost}


def _shares_from(z) -> dict:
    """The shares (:func:`budget_shares`) back from an .npz written by :func:`budget_study`."""
    U = {s: z[f"U:{s}"] for s in BUDGET_SOURCES}
    sens = {s: z[f"sens:{s}"] for s in ("bar temperature", "machine temperature")}
    slices = {str(r[0]): (int(r[1]), int(r[2])) for r in z["slices"]}
    return {"U": U, "U_temp": z["U_temp"], "sens": sens, "keep": z["keep"].astype(bool), "t_rms": float(z["t_rms"]),
            "slices": slices, "stylus_runs": int(z["stylus_runs"]),
            "stylus_components": bool(z["stylus_components"]) if "stylus_components" in z.files else False}


def assemble_study(directory, path, runs: int | None = None, *, name: str = "mfb-3axis", seed: int = 1,
                   model_error_share: bool | None = None) -> dict:
    """One compressed .npz of a study directory (:func:`budget_study`): its shares, every attempt's
    draw (T, lobing phase, ok), the ok runs' ``error`` (runs, n) float64 and ``U95_lin`` float32, the
    lost runs' messages, each run's CPU seconds; ``model_error_share`` (when given) whether the runs were
    made with :data:`MFB_MODEL_ERROR_SHARE` on (their own U95 then hold it where the gate opened; a file
    without the key was made before session 34, with it off). Returns :func:`study_report` of it."""
    from pathlib import Path

    d = Path(directory)
    st = study_arrays(d, runs)
    with np.load(d / "shares.npz", allow_pickle=True) as z:
        sh = {k: z[k] for k in z.files}
    J = len(st["ok"])
    cpu = []
    for j in range(1, J + 1):
        with np.load(d / f"run-{j:05d}.npz") as z:
            cpu.append(float(z["cpu_s"]) if "cpu_s" in z.files else np.nan)
    _npz_atomic(path, name=np.array(name), seed=seed, attempt_T_C=st["T_C"], attempt_phase_rad=st["phase_rad"],
                attempt_ok=st["ok"], attempt_cpu_s=np.array(cpu), error=st["error"],
                U95_lin=st["U95_lin"].astype(np.float32),
                lost_j=np.array([j for j, _ in st["lost"]], int), lost_message=np.array([m for _, m in st["lost"]]),
                **({} if model_error_share is None else {"model_error_share": bool(model_error_share)}), **sh)
    return study_report(path)


def study_report(path) -> dict:
    """The budget table (:func:`budget_summary`) recomputed from a stored study (:func:`assemble_study`),
    with the Monte Carlo's own checks (JCGM 101):

    - ``mc_percentile``: per error, the max over its nodes of the 95th percentile of |error| (the
      half-width covering 95 % of the runs), beside 2 x RMS (``mc``);
    - ``coverage["within_mc_U95"]``: the runs' errors within the MC's 2 x RMS;
    - ``stability``: 2 x RMS of the first and of the second half of the runs per parameter, their
      difference over its standard error (sqrt of the two halves' squared standard errors, each
      U / sqrt(2 n) for a normal spread): the fraction within 1 and 2 standard errors (0.68 / 0.95
      expected when stable), and per error the largest relative difference of the halves' maxima;
    - ``temperature_draws``: the runs' RMS of T - 20 degC and mean T;
    - per error ``linear``: the linear propagation of noise, calibration and placement at the
      nominal pose (the shares' quadrature: what ``vmt scenario`` reports), max over the nodes,
      with ``coverage["within_linear_U95"]``; ``run_linear_mean``: the runs' own stored linear U95
      (mean over the runs, max over the nodes), whose coverage is ``within_run_linear_U95``.
    """
    with np.load(path, allow_pickle=True) as z:
        shares = _shares_from(z)
        err, own = z["error"], z["U95_lin"].astype(float)
        ok, T = z["attempt_ok"], z["attempt_T_C"]
        lost = [{"seed": int(z["seed"]) + int(j), "error": str(m)} for j, m in zip(z["lost_j"], z["lost_message"])]
        name, seed, cpu = str(z["name"]), int(z["seed"]), z["attempt_cpu_s"]
    b = budget_summary(name, shares, err, own, seed=seed, runs_lost=lost, runs_drawn=len(ok))
    keep = shares["keep"]
    n_runs = len(err)
    mc = 2.0 * np.sqrt(np.mean(err ** 2, axis=0))
    p95 = np.percentile(np.abs(err), 95.0, axis=0)
    half = n_runs // 2
    U1 = 2.0 * np.sqrt(np.mean(err[:half] ** 2, axis=0))
    U2 = 2.0 * np.sqrt(np.mean(err[half:2 * half] ** 2, axis=0))
    se = np.sqrt(U1 ** 2 / (2 * half) + U2 ** 2 / (2 * half))
    z_ = np.abs(U1 - U2)[keep] / se[keep]
    per_half = {}
    U = shares["U"]
    lin = np.sqrt(U["probing noise"] ** 2 + U["bar calibration"] ** 2 + U["placement"] ** 2)
    own_mean = own.mean(axis=0)
    for s, c in b["per_error"].items():
        sl = slice(*shares["slices"][s])
        k = keep[sl]
        c["mc_percentile"] = float(p95[sl][k].max() * 1e6)
        c["linear"] = float(lin[sl][k].max() * 1e6)
        c["run_linear_mean"] = float(own_mean[sl][k].max() * 1e6)
        a, bb = float(U1[sl][k].max()), float(U2[sl][k].max())
        per_half[s] = {"first": a * 1e6, "second": bb * 1e6, "relative_difference": abs(a - bb) / max(a, bb)}
    b["coverage"]["within_mc_U95"] = f"{int(np.sum(np.abs(err[:, keep]) <= mc[keep]))}/{err[:, keep].size}"
    b["coverage"]["within_linear_U95"] = f"{int(np.sum(np.abs(err[:, keep]) <= lin[keep]))}/{err[:, keep].size}"
    b["stability"] = {"runs_per_half": half, "within_1_se": float(np.mean(z_ <= 1.0)),
                      "within_2_se": float(np.mean(z_ <= 2.0)), "max_over_se": float(z_.max()),
                      "per_error_max_U95_halves": per_half}
    Tk = T[ok]
    b["temperature_draws"] = {"rms_from_20_C": float(np.sqrt(np.mean((Tk - 20.0) ** 2))), "mean_C": float(Tk.mean())}
    b["cpu_s_per_run_median"] = float(np.nanmedian(cpu)) if np.any(np.isfinite(cpu)) else None
    return b


def study_table_markdown(rep: dict) -> str:
    """The stored study's table for docs/papers-mfb.md (:func:`study_report`): per error each
    source's U95 share, bar and machine at one temperature, their quadrature sum, the run's own
    linear U95, the Monte Carlo (2 x RMS and the 95th percentile of |error|), MC / sum."""
    short = {"probing noise": "noise", "bar calibration": "bar cal", "placement": "place",
             "stylus offsets": "stylus", "lobing": "lobing", "bar temperature": "T bar",
             "machine temperature": "T mach"}
    head = (["error", "unit"] + [short[s] for s in rep["sources"]]
            + ["T one", "sum", "linear", "MC 2xRMS", "MC p95", "MC/sum", "halves"])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    halves = rep["stability"]["per_error_max_U95_halves"]
    for s, c in rep["per_error"].items():
        h = halves[s]
        row = ([s, c["unit"]] + [f"{c['U95'][k]:.2f}" for k in rep["sources"]]
               + [f"{c['temperature_one_T']:.2f}", f"{c['quadrature']:.2f}", f"{c['linear']:.2f}",
                  f"{c['mc']:.2f}", f"{c['mc_percentile']:.2f}", f"{c['mc_over_quadrature']:.2f}",
                  f"{h['first']:.2f} / {h['second']:.2f}"])
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


# --------------------------------------------------------------------------- the campaign as a probe log
def campaign_log(r: ScenarioResult, meta: dict | None = None):
    """The simulated campaign of ``r`` (:func:`run`) as one ``probe-log/1`` log (``artefact: mfb``) that
    :func:`core.mfblog.read_mfb_log` reads back into the same measurements: every measurement's touches in
    the order simulated, ``setup`` the measurement's set-up (one bar pose), ``measurement`` its name,
    ``stylus`` its stylus; lines: the styli's offsets, the plan's error-table nodes, the rotary axes' points,
    the bar's certificate as the identification was given it (declared or ``bar_calibration``) and ``meta``.
    Each stylus's calibration error (``u_stylus_um``, ``stylus_dJ_m``) is in its readings, as the
    identification read them. (``vmt simulate mfb-3axis|mfb-5axis``.)"""
    from core import mfblog
    from core.probelog import make_log

    c = r.campaign
    if not c or not c.get("logs"):
        from core.exceptions import ConfigError

        raise ConfigError("this MFB run kept no campaign to write")
    cols: dict = {}
    order = None
    for ms, log in zip(r.plan.measurements, c["logs"]):
        n = log.n
        own = dict(log.columns)
        dJ = np.asarray(c["dJ_m"].get(ms.stylus, np.zeros(3)), float)
        for j, a in enumerate("XYZ"):
            if dJ[j]:
                own[f"{a}_mm"] = own[f"{a}_mm"] + dJ[j] / MM
        own["setup"] = np.full(n, ms.setup_key, object)
        own[mfblog.MEASUREMENT_COLUMN] = np.full(n, ms.name, object)
        own[mfblog.STYLUS_COLUMN] = np.full(n, ms.stylus, object)
        if order is None:
            order = list(own)
        for k in order:
            cols.setdefault(k, []).append(own[k])
    cols = {k: np.concatenate(v) for k, v in cols.items()}
    m = dict(c["logs"][0].meta)
    m.pop("format", None)
    styli = {ms.stylus: np.asarray(ms.J_m, float) / MM for ms in r.plan.measurements}
    m[mfblog.STYLUS_OFFSETS_KEY] = mfblog.format_named_vectors(styli)
    m[mfblog.NODES_KEY] = mfblog.format_named_vectors({a: np.asarray(v, float) / MM for a, v in r.plan.nodes.items()})
    if c["rotary_points_R_m"]:
        m[mfblog.ROTARY_POINTS_KEY] = mfblog.format_named_vectors(
            {a: np.asarray(v, float) / MM for a, v in c["rotary_points_R_m"].items()})
    m.update(mfblog.certificate_lines(c["E_cal_m"], c["u_cal_m"]))
    m.update(meta or {})
    return make_log(cols, m)


#: Format of ``vmt identify --json`` on a multi-feature bar's log (:func:`identify_log`).
IDENTIFY_LOG_FORMAT = "vmt-identify-mfb/1"


def identify_log(ml, *, sigma_m: float, mc_runs: int = 0, rng: np.random.Generator | None = None,
                 u_place=U_PLACE, source: str = "", machine: str | None = None, progress=None,
                 declared_ripple: dict | None = None) -> dict:
    """The 21 errors of a multi-feature bar's probe log (:func:`core.mfblog.read_mfb_log`'s ``ml``): what
    :func:`run` does after its simulation, with the log's measurements, nodes and certificate and no truth.

    ``sigma_m`` the probe's repeatability (k = 1), m; ``u_place`` the placements' tolerance (:data:`U_PLACE`:
    the bar set by hand); ``mc_runs`` Monte Carlo runs of the U95 (0: the linear propagation), drawn from
    ``rng``; ``declared_ripple`` as :func:`run`'s (a type B term in the U95 and the covariance). After the
    identification, :func:`run`'s own code: :func:`_judge` (the residuals' noise model, lack of fit, model-error
    share behind :data:`MFB_MODEL_ERROR_SHARE` and its gate, the U95) and :func:`_report_tail` (the covariance,
    the estimate, between the nodes), a log's placements entering with its probing noise where :func:`run`'s
    enter when drawn: on :func:`run`'s own campaign written as a log (:func:`campaign_log`) the same numbers
    (tests/scenarios/test_mfb_log_route.py). Returns the ``vmt-identify-mfb/1`` document.
    """
    from core import iso, volumetric as vol
    from core.state import identified_on

    meas = list(ml.meas)
    rp = dict(ml.rotary_points_R_m)
    declared = _check_declared_ripple(declared_ripple)
    rng = np.random.default_rng(0) if rng is None else rng
    res_g = vol.identify_volumetric(meas, ml.chain, ml.nodes, rp)
    if progress is not None:
        progress(1, 3)
    noisy = sigma_m > 0
    u_cal = np.asarray(ml.certificate.u_m, float)
    # a log's placements enter with its probing noise (run()'s drawn inputs), its bar's u always
    j = _judge(res_g, meas, ml.chain, rp, sigma_m=sigma_m, noisy=noisy, draw=noisy, u_cal=u_cal, u_cal_fit=u_cal,
               u_place=u_place, declared=declared, mc_runs=mc_runs, rng=rng)
    res, unc = j.res, j.unc
    if progress is not None:
        progress(2, 3)
    slopes = vol.end_point_slopes(res_g.design, res_g.theta)
    errors = vol.report(res, unc, None)
    for s, e in errors.items():
        if iso.symbol(s).kind == iso.Kind.STRAIGHTNESS:
            e["reference"] = "end-point straight line"
            e["end_point_slope_urad"] = slopes[s] * 1e6
    doc = {"format": IDENTIFY_LOG_FORMAT, "log": str(source), "artefact": "mfb", "chain": ml.chain,
           "noise_um": sigma_m * 1e6, "noise_note": "probing noise: a standard deviation (k = 1) along the approach",
           "setups": len(ml.setups), "measurements": len(meas), "touches": ml.touches,
           "styli_mm": {k: (np.asarray(v, float) / MM).tolist() for k, v in ml.styli.items()},
           "nodes_from": ml.nodes_from, "bar_calibration": ml.certificate.source,
           "model": "first order (eqs 8-12) + exact Gauss-Newton"
                    + (" (the points fitted again from the touches at each step)" if res.extraction else "")
           if res.iterations else "first order (eqs 8-12)", "gauss_newton_iterations": res.iterations,
           "conventions": list(res.design.gauge), "rms_residual_um": res.rms_m * 1e6, "errors": errors,
           **({"not_compensated": nc} if (nc := rotary_not_compensated(res.chain)) else {})}
    _report_tail(doc, j, identified_on=identified_on(
        machine, ml.chain, sorted({tuple(float(v) * 1e3 for v in m.J_m) for m in meas}), None,
        ml.t_range_s if np.all(np.isfinite(ml.t_range_s)) else None), nodes=ml.nodes)
    if progress is not None:
        progress(3, 3)
    return doc
