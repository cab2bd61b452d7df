"""Virtual CMM: measurands of a user's task and their Monte Carlo uncertainty.

A *task* (a TOML file, format ``vmt-task/1``) names features fitted from
groups of a plan's targets and the measurands derived from them; it also
declares what is uncertain about the machine (error limits per ISO 230-1
symbol with their distribution) and the probe. This module is the pure
part of the virtual CMM (ISO 15530-4): reading a task, evaluating its
measurands from touches, drawing the declared errors, and the adaptive
Monte Carlo statistics of JCGM 101:2008 (7.7, 7.9). Simulating the touches
of each run is the scenario's job (``scenarios.vcmm``): core never
imports the simulator.

Task file (units in the key names)::

    format = "vmt-task/1"

    [features.bore]              # a feature: a kind and the plan rows it fits
    kind = "circle"              # plane | line (in XY) | circle (in XY) | sphere | cylinder
    feature = "bore"             # rows whose plan column `feature` is this
    # targets = ["B01", "B02"]   # or/and these targets; setup = "S1" narrows

    [[measurands]]
    name = "bore diameter"
    quantity = "diameter"        # of one circle, sphere or cylinder
    of = "bore"
    # quantity = "position", axis = "x" | "y" | "z": a centre coordinate
    # quantity = "distance", of = [A, B]: plane-plane (along A's normal),
    #   centre-centre, plane-centre
    # quantity = "angle", of = [A, B]: between plane normals / cylinder axes /
    #   lines (their outward normals); of = L (one line): its direction from +X
    # quantity = "flatness" | "straightness" | "roundness" | "sphericity" | "cylindricity"
    # quantity = "profile", statistic = "max" | "min" | "rms" | "zone": the
    #   deviations from the nominal (ISO 1101 profile of a surface, no best fit)

    [declared.EXX]               # MPE-style limits of one ISO 230-1 symbol
    slope_um_per_m = 5.0         # each term drawn within +-bound
    distribution = "uniform"     # uniform | normal (bound = U at k = 2) |
                                 # triangular | arcsine

    [probe]
    noise_um = 0.25              # repeatability, k = 1 (default: the machine's)
    pretravel_um = 0.5           # residual pre-travel after calibration, drawn within +-0.5 um
    lobing_um = 0.3              # lobing amplitude within +-0.3 um (a cos(k phi - phi0), phase uniform)
    lobes = 3                    # k, the lobing's order (default 3: a kinematic probe)
    distribution = "uniform"     # of pretravel_um and lobing_um (as [declared])

    [form.bore]                  # the part's own form of feature "bore", drawn per run
    amplitude_um = 1.0           # a, drawn within +-1 um (distribution), phase uniform
    lobes = 3                    # circle, cylinder: a cos(k theta + phi) about the axis
    # wavelength_mm = 40.0       # plane, line: a cos(2 pi s / wavelength + phi), s along the
    # along = "x"                #   surface (line: its direction; plane: this axis projected on it)
    distribution = "uniform"

    [drift]                      # the machine's thermal drift during the measurement
    x_um_per_h = 3.0             # rate of the X offset (an EXX growing with time), drawn within +-3 um/h
    z_um_per_h = 5.0             # (x, y, z: each one source "EXX drift", "EYY drift", "EZZ drift")
    distribution = "uniform"
    touches_per_min = 6.0        # when the plan has no t_s: row i starts at i / rate (plan order)

    [temperature]                # results at 20 C, corrected with the best estimates
    part_C = 22.0                # the part's temperature during the measurement
    u_part_K = 0.5               # its standard uncertainty (normal)
    part_alpha_per_K = 11.5e-6   # the part's expansion coefficient
    u_part_alpha_per_K = 1.0e-6
    scales_C = 21.0              # the machine's scales (one temperature for X, Y, Z)
    u_scales_K = 0.3
    scales_alpha_per_K = 8.0e-6
    u_scales_alpha_per_K = 0.5e-6

    [mc]
    significant_digits = 1       # JCGM 101 7.9.2: u stable to this many digits
    # tolerance_um = 0.05        # or an absolute numerical tolerance
    batch_runs = 200             # M per batch (JCGM 101 asks 1e4; see below)
    max_runs = 20000
    coverage = 0.95

A ``line`` is the trace of a face touched at one height: a least-squares
line of the tip centres in XY (their Z ignored), its direction ``d = z x n``
with ``n`` its outward normal in XY (the mean of the nominal normals'
sense), i.e. a boss's outline runs anticlockwise seen from +Z; its
``straightness`` is the peak-to-valley of the signed XY residuals about the
least-squares line (ISO 12780 LS reference). A line's ``angle`` alone is the
angle of ``d`` from +X in XY, on the branch of the nominal direction (that
of the nominal normals, in (-180, 180] deg): it does not jump when a line
along -X tilts across the cut at 180 deg; between two lines the
angle of their outward normals, in [0, 180] deg, so two perpendicular faces
of a block read 90. ``distance`` with a line: the
XY distance of the other feature's point (line: its centroid; circle,
sphere: centre) from the line.

Profile deviation (ISO 1101 profile of a surface, the plan's frame being the
datum system: no best fit): each touch's deviation is ``d_i = n_i . (p_i -
Xn_i)``, the reported minus the nominal tip centre along the nominal outward
normal, equal to the surface point's deviation (the ball's radius cancels).
Sign: positive where the surface lies outside the nominal (excess
material), negative inside it. ``statistic`` max, min, rms (``sqrt(mean
d^2)``) or zone ``2 max |d|``: the width of the tolerance zone centred on
the nominal that just holds every point (the part conforms to a profile
tolerance ``t`` when zone <= t).

The part's form (``[form.FEATURE]``): the feature's surface lies ``f`` out of
its nominal along the nominal outward normal (+ = excess material, as the
profile deviation's sign), a circle's or cylinder's
``f = a cos(k theta + phi)`` with ``theta`` the azimuth about its axis (a
circle: about Z from +X; a cylinder: anticlockwise about its axis directed
along its largest component, positive, from the axis' perpendicular nearest
+X, or +Y for an axis along X), a plane's or line's ``f = a cos(2 pi s / wavelength +
phi)`` with ``s`` the coordinate along the surface; ``a`` drawn within
+-``amplitude_um`` by the distribution, ``phi`` uniform, each feature one
source ``form of FEATURE``. A point-contact model: ``f`` is taken at the tip
centre's foot on the nominal surface (the ball's mechanical filtering of
waves shorter than about its radius is not modelled). A sphere takes no
form.

Drift (``[drift]``): the axis's positioning error grows as ``v t`` (m, ``v``
drawn within +-the rate), zero at the plan's first row (the datum is taken
there), ``t`` the start of a touch's approach: the plan's ``t_s`` minus its
first finite value when every used row has one, else the row's index in
the plan over ``touches_per_min`` (rows no feature uses still take their
time). The touch meets the part ``CLEARANCE / feed`` later (0.25 s), the same
for every touch.

Declared terms: ``constant_U``, and for a linear axis's motion errors also
``slope_U_per_m`` and ``quadratic_U_per_m2`` (``U`` = ``um`` for a
translation, ``urad`` for a rotation) of the axis (joint) position
``q = reading + J`` (J the stylus's probe offset: on vmc-3axis, J_Z 150 mm,
a touch reading Z -17 mm is at q = 133 mm), the same polynomial as a
machine file's and evaluated where its errors are, and ``periodic_U`` with ``period_mm``: a
periodic error ``a sin(2 pi x / period + phi)`` (a screw's pitch error,
the ripple an identification's tables cannot follow between their nodes)
with its amplitude ``a`` drawn within +-``periodic_U`` by the distribution
and its phase ``phi`` uniform; a location error (``EC0Y``, ``EX0C``, ...)
and a rotary axis's motion errors take ``constant_U`` only. Every term is
one independent source of the budget.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field

import numpy as np

from . import fit as F
from . import iso
from .exceptions import ConfigError, FitError
from .keyreader import KeyReader, read_text_file

FORMAT = "vmt-task/1"
KINDS = ("plane", "line", "circle", "sphere", "cylinder")
#: quantity -> feature kinds it applies to (one feature), form names.
FORM_OF = {"flatness": "plane", "straightness": "line", "roundness": "circle", "sphericity": "sphere",
           "cylindricity": "cylinder"}
QUANTITIES = ("diameter", "position", "distance", "angle", "profile") + tuple(FORM_OF)
#: ``statistic`` of a ``profile`` measurand (see the module doc).
PROFILE_STATISTICS = ("max", "min", "rms", "zone")
DISTRIBUTIONS = ("uniform", "normal", "triangular", "arcsine")
#: Standard uncertainty of a term declared with half-width (bound) 1 (normal: bound = U at k = 2).
U_PER_BOUND = {"uniform": 1 / math.sqrt(3), "normal": 0.5, "triangular": 1 / math.sqrt(6),
               "arcsine": 1 / math.sqrt(2)}
#: Power of the axis position (reading + J) of each declared term.
TERM_POWER = {"constant": 0, "slope": 1, "quadratic": 2, "periodic": 0, "pretravel": 0, "lobing": 0, "form": 0,
              "drift": 0}
PROBE_SOURCE = "probe repeatability"
#: The declared probe terms' budget names (``[probe] pretravel_um``, ``lobing_um``).
PRETRAVEL_SOURCE = "probe pre-travel"
LOBING_SOURCE = "probe lobing"
#: Reference temperature of dimensional measurement (ISO 1), C.
T_REF_C = 20.0
#: Temperature sources: name -> (value key, its u key) of :class:`Temperature`.
THERMAL_SOURCES = {"part temperature": ("part_C", "u_part_K"),
                   "part expansion": ("part_alpha_per_K", "u_part_alpha_per_K"),
                   "scale temperature": ("scales_C", "u_scales_K"),
                   "scale expansion": ("scales_alpha_per_K", "u_scales_alpha_per_K")}


class TaskFileError(ConfigError):
    """A task file that cannot be used: the file, the key, what is wrong."""


@dataclass(frozen=True)
class FeatureSpec:
    """One feature of a task: a kind and the plan rows it is fitted to."""

    name: str
    kind: str
    feature: str | None = None
    targets: tuple | None = None
    setup: str | None = None


@dataclass(frozen=True)
class Measurand:
    """One scalar result of the task.

    ``unit`` is the unit of its value in reports (``mm``, ``um`` for a form
    deviation, ``deg`` for an angle), ``u_unit`` that of its uncertainty
    (``um``, ``urad``); ``scale`` / ``u_scale`` convert from SI.
    """

    name: str
    quantity: str
    of: tuple
    axis: str | None = None
    statistic: str | None = None   # profile: one of PROFILE_STATISTICS

    @property
    def unit(self) -> str:
        return {"angle": "deg"}.get(self.quantity, "um" if self.quantity in FORM_OF or self.quantity == "profile" else "mm")

    @property
    def scale(self) -> float:
        return {"mm": 1e3, "um": 1e6, "deg": 180.0 / math.pi}[self.unit]

    @property
    def u_unit(self) -> str:
        return "urad" if self.quantity == "angle" else "um"

    @property
    def u_scale(self) -> float:
        return 1e6


@dataclass(frozen=True)
class DeclaredTerm:
    """One declared error term: ``symbol``'s ``term`` drawn within +-``bound`` (SI per reading^power)."""

    symbol: str
    term: str
    bound: float
    distribution: str
    period: float | None = None   # m, the periodic term's

    @property
    def source(self) -> str:
        """Name of the source in the budget, e.g. ``EXX slope``."""
        return f"{self.symbol} {self.term}"

    @property
    def power(self) -> int:
        return TERM_POWER[self.term]

    @property
    def u(self) -> float:
        """Standard uncertainty of the coefficient (SI)."""
        return self.bound * U_PER_BOUND[self.distribution]


@dataclass(frozen=True)
class PartForm:
    """The declared form of one feature (``[form.FEATURE]``, see the module doc), SI.

    ``bound`` m the amplitude's half-width; ``lobes`` (circle, cylinder) or
    ``wavelength`` m and ``along`` (unit (3,), plane: the axis projected on
    it; line: None, its direction).
    """

    feature: str
    bound: float
    distribution: str
    lobes: int | None = None
    wavelength: float | None = None
    along: tuple | None = None

    @property
    def source(self) -> str:
        return f"form of {self.feature}"

    @property
    def u(self) -> float:
        return self.bound * U_PER_BOUND[self.distribution]


@dataclass(frozen=True)
class Temperature:
    """Temperatures and expansion coefficients with their standard uncertainties (normal draws).

    The part expands about the centroid of its probed surface points by
    ``e_p = alpha_p (T_p - 20)``; the scales by ``e_s = alpha_s (T_s - 20)``
    (an axis position ``q = reading + J`` is the true one over ``1 + e_s``:
    the axis sits at ``q (1 + e_s)``, an ``EXX``, ``EYY``, ``EZZ`` slope of
    ``e_s`` at the axis position). The
    result is corrected to 20 C with the best estimates (:func:`correct_to_20c`);
    what remains is the uncertainty of the draws.
    """

    part_C: float = T_REF_C
    u_part_K: float = 0.0
    part_alpha_per_K: float = 0.0
    u_part_alpha_per_K: float = 0.0
    scales_C: float = T_REF_C
    u_scales_K: float = 0.0
    scales_alpha_per_K: float = 0.0
    u_scales_alpha_per_K: float = 0.0

    @property
    def sources(self) -> tuple:
        """The sources with a non-zero u, in :data:`THERMAL_SOURCES` order."""
        return tuple(k for k, (_, u) in THERMAL_SOURCES.items() if getattr(self, u) > 0)

    def strains(self, draws: dict | None = None) -> tuple[float, float]:
        """(e_part, e_scales): with ``draws`` ``{source: value}`` replacing the best estimates."""
        v = {k: (draws or {}).get(k, getattr(self, key)) for k, (key, _) in THERMAL_SOURCES.items()}
        return (v["part expansion"] * (v["part temperature"] - T_REF_C),
                v["scale expansion"] * (v["scale temperature"] - T_REF_C))

    def draw(self, source: str, rng: np.random.Generator) -> float:
        key, ukey = THERMAL_SOURCES[source]
        return float(getattr(self, key) + getattr(self, ukey) * rng.standard_normal())


def correct_to_20c(p_R: np.ndarray, n_R: np.ndarray, stylus_r: float, e_part: float, e_scales: float,
                   centre: np.ndarray, J_m=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Reported tip centres corrected to 20 C with the strains' best estimates, (n, 3) m.

    The scales measure the axis position ``q = reading + J`` (``J_m``: the
    probe offsets of the tool used, CONTRIBUTING's joint position): the axis
    is at ``q (1 + e_scales)``, so the tool at ``(p + J)(1 + e_scales) - J``
    (``p (1 + e_scales)`` only when J = 0); the surface point is ``r`` back
    along the normal; at 20 C the part is ``1 + e_part`` smaller about
    ``centre``; the tip centre goes back out by ``r`` (the ball does not
    belong to the part).
    """
    J = np.asarray(J_m, float)
    s = (p_R + J) * (1.0 + e_scales) - J - stylus_r * n_R
    return centre + (s - centre) / (1.0 + e_part) + stylus_r * n_R


@dataclass(frozen=True)
class MCSettings:
    """JCGM 101 adaptive Monte Carlo settings (7.9).

    ``tolerance`` (SI, m) replaces the tolerance from ``significant_digits``
    when given. ``batch_runs`` is JCGM 101's M; it asks max(100/(1-p), 1e4),
    which a simulator at tens of runs per second cannot afford: a smaller
    batch makes each batch's quantiles coarser, and the adaptive rule then
    simply needs more batches (the statistics are over all h M runs).
    """

    significant_digits: int = 1
    tolerance: float | None = None
    batch_runs: int = 200
    max_runs: int = 20000
    coverage: float = 0.95


@dataclass(frozen=True)
class Task:
    """A read task file."""

    features: tuple
    measurands: tuple
    declared: tuple = ()
    probe_noise_um: float | None = None
    mc: MCSettings = field(default_factory=MCSettings)
    source: str = "<task>"
    temperature: Temperature | None = None
    pretravel: DeclaredTerm | None = None   # symbol "probe", term "pretravel": bound m
    lobing: DeclaredTerm | None = None      # symbol "probe", term "lobing", period = the number of lobes
    forms: tuple = ()                       # PartForm, one per feature at most
    drift: tuple = ()                       # DeclaredTerm "EXX"/"EYY"/"EZZ", term "drift": bound m/s
    touches_per_min: float | None = None    # [drift] touches_per_min

    @property
    def probe_sources(self) -> tuple:
        """The declared probe terms' budget names."""
        return ((PRETRAVEL_SOURCE,) if self.pretravel is not None else ()) + (
            (LOBING_SOURCE,) if self.lobing is not None else ())

    @property
    def drift_sources(self) -> tuple:
        """The declared drifts' budget names, ``EXX drift`` ..."""
        return tuple(t.source for t in self.drift)

    @property
    def form_sources(self) -> tuple:
        """The part's declared forms' budget names, ``form of FEATURE``."""
        return tuple(f.source for f in self.forms)

    def feature(self, name: str) -> FeatureSpec:
        for f in self.features:
            if f.name == name:
                return f
        raise TaskFileError(f"{self.source}: no feature {name!r}")


# --------------------------------------------------------------------------- reading


def load_task(path) -> Task:
    """Read a task file (see the module doc); :class:`TaskFileError` names the key at fault."""
    return loads_task(read_text_file(path, TaskFileError, "task file"), source=str(path))


def loads_task(text: str, source: str = "<task>") -> Task:
    """Read a task file's text."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise TaskFileError(f"{source}: not TOML: {e}") from None
    if not doc:  # said as the logs say it (review32d F11: was "features: missing")
        raise TaskFileError(f"{source}: empty file" + (" (comments only)" if text.strip() else ""))
    return _TaskReader(source).task(doc)


class _TaskReader(KeyReader):
    error_class = TaskFileError

    def string(self, key, v, *, nonempty: bool = True) -> str:
        return super().string(key, v, nonempty=nonempty)

    def task(self, doc) -> Task:
        self.keys("", doc, ("format", "description", "features", "measurands", "declared", "probe", "mc",
                            "temperature", "form", "drift"))
        if "format" in doc and doc["format"] != FORMAT:
            self.fail("format", f"expected {FORMAT!r}, got {doc['format']!r}")
        feats = tuple(self.feature(n, b) for n, b in self.table("features", doc.get("features", {})).items())
        if not feats:
            self.fail("features", "missing: at least one [features.NAME] table")
        ms = doc.get("measurands", [])
        if not isinstance(ms, list) or not ms:
            self.fail("measurands", "missing: at least one [[measurands]] table")
        kinds = {f.name: f.kind for f in feats}
        meas = tuple(self.measurand(i, self.table(f"measurands[{i}]", m), kinds) for i, m in enumerate(ms))
        names = [m.name for m in meas]
        if len(set(names)) != len(names):
            self.fail("measurands", "names must be unique")
        declared = []
        for sym, body in self.table("declared", doc.get("declared", {})).items():
            declared += self.declared(sym, self.table(f"declared.{sym}", body))
        probe = self.table("probe", doc.get("probe", {}))
        self.keys("probe", probe, ("noise_um", "pretravel_um", "lobing_um", "lobes", "distribution"))
        noise = self.number("probe.noise_um", probe["noise_um"], nonneg=True) if "noise_um" in probe else None
        pdist = probe.get("distribution", "uniform")
        if pdist not in DISTRIBUTIONS:
            self.fail("probe.distribution", f"expected one of {', '.join(DISTRIBUTIONS)}, got {pdist!r}")
        pre = lob = None
        if "pretravel_um" in probe:
            pre = DeclaredTerm("probe", "pretravel", self.number("probe.pretravel_um", probe["pretravel_um"],
                                                                 nonneg=True) * 1e-6, pdist)
        if "lobes" in probe and "lobing_um" not in probe:
            self.fail("probe.lobes", "only with lobing_um")
        if "lobing_um" in probe:
            k = self.integer("probe.lobes", probe["lobes"], 1) if "lobes" in probe else 3
            lob = DeclaredTerm("probe", "lobing", self.number("probe.lobing_um", probe["lobing_um"], nonneg=True)
                               * 1e-6, pdist, float(k))
        temp = self.temperature(self.table("temperature", doc["temperature"])) if "temperature" in doc else None
        forms = tuple(self.form(n, self.table(f"form.{n}", b), kinds)
                      for n, b in self.table("form", doc.get("form", {})).items())
        drift, rate = self.drift(self.table("drift", doc["drift"])) if "drift" in doc else ((), None)
        return Task(feats, meas, tuple(declared), noise, self.mc(self.table("mc", doc.get("mc", {}))), self.source,
                    temp, pre, lob, forms, drift, rate)

    def drift(self, t) -> tuple:
        axes = {f"{a}_um_per_h": f"E{a.upper()}{a.upper()}" for a in "xyz"}
        self.keys("drift", t, tuple(axes) + ("distribution", "touches_per_min"))
        dist = t.get("distribution", "uniform")
        if dist not in DISTRIBUTIONS:
            self.fail("drift.distribution", f"expected one of {', '.join(DISTRIBUTIONS)}, got {dist!r}")
        terms = tuple(DeclaredTerm(sym, "drift", self.number(f"drift.{k}", t[k], nonneg=True) * 1e-6 / 3600.0, dist)
                      for k, sym in axes.items() if k in t)
        if not terms:
            self.fail("drift", f"no rate (expected one of {', '.join(axes)})")
        rate = self.number("drift.touches_per_min", t["touches_per_min"], positive=True) if "touches_per_min" in t \
            else None
        return terms, rate

    def form(self, name, body, kinds) -> PartForm:
        key = f"form.{name}"
        if name not in kinds:
            self.fail(key, f"no feature {name!r} (features: {', '.join(kinds)})")
        kind = kinds[name]
        if kind == "sphere":
            self.fail(key, "a sphere takes no form (circle, cylinder: lobes; plane, line: wavelength_mm)")
        lobed = kind in ("circle", "cylinder")
        own = ("lobes",) if lobed else ("wavelength_mm",) + (("along",) if kind == "plane" else ())
        self.keys(key, body, ("amplitude_um", "distribution") + own)
        for k in own:
            if k not in body:
                self.fail(f"{key}.{k}", f"missing: a {kind}'s form needs {', '.join(own)}")
        if "amplitude_um" not in body:
            self.fail(f"{key}.amplitude_um", "missing")
        dist = body.get("distribution", "uniform")
        if dist not in DISTRIBUTIONS:
            self.fail(f"{key}.distribution", f"expected one of {', '.join(DISTRIBUTIONS)}, got {dist!r}")
        a = self.number(f"{key}.amplitude_um", body["amplitude_um"], nonneg=True) * 1e-6
        if lobed:
            return PartForm(name, a, dist, lobes=self.integer(f"{key}.lobes", body["lobes"], 1))
        wl = self.number(f"{key}.wavelength_mm", body["wavelength_mm"], positive=True) * 1e-3
        along = None
        if kind == "plane":
            ax = body["along"]
            if ax not in ("x", "y", "z"):
                self.fail(f"{key}.along", f"expected \"x\", \"y\" or \"z\", got {ax!r}")
            along = tuple(float(i == "xyz".index(ax)) for i in range(3))
        return PartForm(name, a, dist, wavelength=wl, along=along)

    def temperature(self, t) -> Temperature:
        keys = [f.name for f in dataclasses.fields(Temperature)]
        self.keys("temperature", t, keys)
        kw = {}
        for k in keys:
            if k in t:
                kw[k] = self.number(f"temperature.{k}", t[k], nonneg=k.startswith("u_"))
        for k in ("part_C", "scales_C"):
            if k in kw and not -50.0 <= kw[k] <= 100.0:
                self.fail(f"temperature.{k}", f"a workshop temperature in [-50, 100] C, got {kw[k]!r}")
        return Temperature(**kw)

    def feature(self, name, body) -> FeatureSpec:
        key = f"features.{name}"
        body = self.table(key, body)
        self.keys(key, body, ("kind", "feature", "targets", "setup"))
        kind = self.string(f"{key}.kind", body.get("kind"))
        if kind not in KINDS:
            self.fail(f"{key}.kind", f"expected one of {', '.join(KINDS)}, got {kind!r}")
        if "feature" not in body and "targets" not in body:
            self.fail(key, "give feature = \"LABEL\" (the plan's feature column) or targets = [...]")
        feat = self.string(f"{key}.feature", body["feature"]) if "feature" in body else None
        tg = None
        if "targets" in body:
            tg = body["targets"]
            if not isinstance(tg, list) or not tg or not all(isinstance(t, str) for t in tg):
                self.fail(f"{key}.targets", "expected a non-empty list of target names")
            tg = tuple(tg)
        setup = self.string(f"{key}.setup", body["setup"]) if "setup" in body else None
        return FeatureSpec(name, kind, feat, tg, setup)

    def measurand(self, i, body, kinds) -> Measurand:
        key = f"measurands[{i}]"
        self.keys(key, body, ("name", "quantity", "of", "axis", "statistic"))
        name = self.string(f"{key}.name", body.get("name"))
        q = self.string(f"{key}.quantity", body.get("quantity"))
        if q not in QUANTITIES:
            self.fail(f"{key}.quantity", f"expected one of {', '.join(QUANTITIES)}, got {q!r}")
        of = body.get("of")
        of = (of,) if isinstance(of, str) else of
        if not isinstance(of, list | tuple) or not of or not all(isinstance(x, str) for x in of):
            self.fail(f"{key}.of", f"expected a feature name or a list of two, got {body.get('of')!r}")
        for f in of:
            if f not in kinds:
                self.fail(f"{key}.of", f"no feature {f!r} (features: {', '.join(kinds)})")
        k = [kinds[f] for f in of]
        want2 = q == "distance" or (q == "angle" and not (len(of) == 1 and k[0] == "line"))
        if len(of) != (2 if want2 else 1):
            self.fail(f"{key}.of", f"{q} takes {'two features' if want2 else 'one feature'}, got {len(of)}")
        axis = None
        if q == "diameter" and k[0] in ("plane", "line"):
            self.fail(f"{key}.of", f"a {k[0]} has no diameter")
        if q in FORM_OF and k[0] != FORM_OF[q]:
            self.fail(f"{key}.of", f"{q} is the form of a {FORM_OF[q]}, {of[0]!r} is a {k[0]}")
        if q == "position":
            if k[0] not in ("circle", "sphere"):
                self.fail(f"{key}.of", f"position: of a circle's or sphere's centre, {of[0]!r} is a {k[0]}")
            axis = body.get("axis")
            if axis not in ("x", "y", "z"):
                self.fail(f"{key}.axis", f"position needs axis = \"x\", \"y\" or \"z\", got {axis!r}")
        elif "axis" in body:
            self.fail(f"{key}.axis", "only for quantity = \"position\"")
        stat = None
        if q == "profile":
            stat = body.get("statistic")
            if stat not in PROFILE_STATISTICS:
                self.fail(f"{key}.statistic", f"profile needs statistic = one of {', '.join(PROFILE_STATISTICS)}, "
                                              f"got {stat!r}")
        elif "statistic" in body:
            self.fail(f"{key}.statistic", "only for quantity = \"profile\"")
        if q == "distance" and "cylinder" in k:
            self.fail(f"{key}.of", "distance: between planes, lines, circle and sphere centres (not a cylinder)")
        if q == "distance" and "line" in k and "plane" in k:
            self.fail(f"{key}.of", "distance: a line with a line, circle or sphere (not a plane)")
        if q == "angle" and not all(x in ("plane", "cylinder", "line") for x in k):
            self.fail(f"{key}.of", "angle: between planes, lines and cylinder axes")
        if q == "angle" and "line" in k and k.count("line") != len(k):
            self.fail(f"{key}.of", "angle: a line with another line (or one line: its direction)")
        return Measurand(name, q, tuple(of), axis, stat)

    def declared(self, sym, body) -> list[DeclaredTerm]:
        key = f"declared.{sym}"
        try:
            s = iso.symbol(sym)
        except ConfigError:
            self.fail(key, "unknown ISO 230-1 / 230-7 error symbol")
        U = "urad" if s.angular else "um"
        terms = {f"constant_{U}": "constant"}
        if not s.location and s.axis in iso.LINEAR_AXES:
            terms.update({f"slope_{U}_per_m": "slope", f"quadratic_{U}_per_m2": "quadratic",
                          f"periodic_{U}": "periodic"})
        self.keys(key, body, tuple(terms) + ("distribution", "period_mm"))
        dist = body.get("distribution", "uniform")
        if dist not in DISTRIBUTIONS:
            self.fail(f"{key}.distribution", f"expected one of {', '.join(DISTRIBUTIONS)}, got {dist!r}")
        period = None
        if f"periodic_{U}" in terms and (f"periodic_{U}" in body) != ("period_mm" in body):
            self.fail(key, f"periodic_{U} and period_mm go together")
        if "period_mm" in body:
            if f"periodic_{U}" not in terms:
                self.fail(f"{key}.period_mm", "only with a linear axis's periodic term")
            period = self.number(f"{key}.period_mm", body["period_mm"], positive=True) * 1e-3
        out = [DeclaredTerm(s.name, t, self.number(f"{key}.{k}", body[k], nonneg=True) * 1e-6, dist,
                            period if t == "periodic" else None)
               for k, t in terms.items() if k in body]
        if not out:
            self.fail(key, f"no term (expected one of {', '.join(terms)})")
        return out

    def mc(self, t) -> MCSettings:
        self.keys("mc", t, ("significant_digits", "tolerance_um", "batch_runs", "max_runs", "coverage"))
        kw = {}
        if "significant_digits" in t:
            kw["significant_digits"] = self.integer("mc.significant_digits", t["significant_digits"], 1)
        if "tolerance_um" in t:
            kw["tolerance"] = self.number("mc.tolerance_um", t["tolerance_um"], positive=True) * 1e-6
        if "batch_runs" in t:
            kw["batch_runs"] = self.integer("mc.batch_runs", t["batch_runs"], 10)
        if "max_runs" in t:
            kw["max_runs"] = self.integer("mc.max_runs", t["max_runs"], 20)
        if "coverage" in t:
            p = self.number("mc.coverage", t["coverage"])
            if not 0.5 <= p < 1:
                self.fail("mc.coverage", f"expected a probability in [0.5, 1), got {p!r}")
            kw["coverage"] = p
        return MCSettings(**kw)


# --------------------------------------------------------------------------- rows of the plan


def feature_rows(task: Task, target, feature, setup, rotary_deg=None) -> dict:
    """The plan rows of each task feature, ``{name: (k,) int}``.

    Parameters
    ----------
    target, feature, setup : (n,) str
        The plan's columns (``feature`` may be all empty).
    rotary_deg : (n, 3) float, optional
        A, B, C of each row: a feature's rows must share one rotary position
        (the fits work in the machine frame R), so must the two features of
        a measurand, and a ``position`` or a line's ``angle`` from +X needs
        its feature at rotary zero (:func:`_refuse_mixed_rotary`).

    Raises
    ------
    TaskFileError
        A feature that selects no row, or rows at different rotary positions;
        a measurand whose features differ in rotary position, or a frame-bound
        one (position, a line's angle) away from rotary zero.
    """
    target, feature, setup = (np.asarray(c).astype(str) for c in (target, feature, setup))
    out = {}
    for f in task.features:
        m = np.ones(len(target), bool)
        if f.feature is not None:
            m &= feature == f.feature
        if f.targets is not None:
            missing = sorted(set(f.targets) - set(target))
            if missing:
                raise TaskFileError(f"{task.source}: features.{f.name}.targets: not in the plan: "
                                    f"{', '.join(missing[:5])}")
            m &= np.isin(target, f.targets)
        if f.setup is not None:
            m &= setup == f.setup
        rows = np.flatnonzero(m)
        if rows.size == 0:
            known = ", ".join(sorted(set(feature) - {""}))[:200] or "none"
            raise TaskFileError(f"{task.source}: features.{f.name}: selects no plan row "
                                f"(plan features: {known})")
        if rotary_deg is not None and rows.size and np.ptp(np.asarray(rotary_deg)[rows], axis=0).max() > 1e-9:
            raise TaskFileError(f"{task.source}: features.{f.name}: its rows are at different rotary "
                                "positions (fits are in the machine frame; give setup = ...)")
        out[f.name] = rows
    if rotary_deg is not None:
        _refuse_mixed_rotary(task, out, np.asarray(rotary_deg, float))
    return out


def _fmt_rotary(r: np.ndarray) -> str:
    """``A=0 B=0 C=90`` (deg, the axes that are not 0; ``rotary zero`` if none)."""
    s = " ".join(f"{a}={v:g}" for a, v in zip("ABC", r) if abs(v) > 1e-9)
    return s or "rotary zero"


def _refuse_mixed_rotary(task: Task, rows: dict, rotary_deg: np.ndarray) -> None:
    """Refuse what the machine-frame fits cannot give (review30d F1).

    The features are fitted in the machine frame R (:func:`evaluate`). A
    measurand over two features probed at different rotary positions would
    compare them in R, where the part has turned between them (two bores
    84.9 mm apart on the part, at C = 0 and C = 90, measured 0 mm apart);
    a ``position`` or a line's ``angle`` from +X of a feature probed away from
    rotary zero is its R coordinate, not the part's. Doing these right needs
    each feature moved into W and the rotary axes' own errors in the model
    (an ``mfb-5axis`` state holds none: they are absorbed into each set-up's
    pose), so they are refused, naming the measurand and the positions.
    """
    pos = {k: rotary_deg[v[0]] for k, v in rows.items() if len(v)}
    for m in task.measurands:
        if m.quantity == "profile":
            continue                      # deviations along the nominal normals: frame-free
        at = [(f, pos[f]) for f in m.of if f in pos]
        if len(at) == 2 and np.max(np.abs(at[0][1] - at[1][1])) > 1e-9:
            raise TaskFileError(
                f"{task.source}: measurand {m.name!r}: features {at[0][0]!r} ({_fmt_rotary(at[0][1])}) and "
                f"{at[1][0]!r} ({_fmt_rotary(at[1][1])}) were probed at different rotary positions; the fits "
                "are in the machine frame, so vmt vcmm cannot combine them (probe both at one rotary position)")
        frame = m.quantity == "position" or (m.quantity == "angle" and len(m.of) == 1)
        if frame and at and np.max(np.abs(at[0][1])) > 1e-9:
            raise TaskFileError(
                f"{task.source}: measurand {m.name!r}: feature {at[0][0]!r} was probed at "
                f"{_fmt_rotary(at[0][1])}; a {m.quantity} is read in the machine frame, which there is not "
                "the part's (give one probed at rotary zero)")


# --------------------------------------------------------------------------- evaluating measurands


@dataclass(frozen=True)
class FittedFeature:
    """A feature's surface (stylus radius applied), SI, frame R.

    ``point`` (plane: centroid on the plane; circle: centre with z the mean
    height; sphere: centre; cylinder: a point on the axis), ``direction``
    (plane normal, cylinder axis, a line's direction ``z x n`` in XY, else
    None), ``radius`` (None for a plane or line), ``form`` (peak-to-valley of
    the residuals about the LS feature). A line's ``point`` is its surface
    point nearest the tip centres' centroid, with z their mean height.
    """

    kind: str
    point: np.ndarray
    direction: np.ndarray | None
    radius: float | None
    form: float
    nominal_direction: np.ndarray | None = None   # a line's: z x (mean nominal normal), XY unit


def _outside(p, n, centre, axis=None) -> bool:
    r = p - centre
    if axis is not None:
        r = r - np.outer(r @ axis, axis)
    return float(np.sum(np.einsum("ij,ij->i", r, n))) >= 0


def fit_feature(kind: str, p_R: np.ndarray, n_R: np.ndarray, stylus_r: float) -> FittedFeature:
    """Least-squares feature of the reported tip centres, then the surface (stylus radius applied).

    Parameters
    ----------
    kind : {"plane", "line", "circle", "sphere", "cylinder"}
    p_R : (k, 3) float
        Reported stylus-tip centres, R, m.
    n_R : (k, 3) float
        Nominal outward surface normals, R (sides: boss or bore).
    stylus_r : float
        Stylus tip radius, m.

    The fits are those of :mod:`core.fit` (ISO 10360-6-tested Gauss-Newton
    least squares); the surface is offset by the stylus radius exactly as
    :func:`core.features.fit_log_feature` does it.
    """
    if kind == "plane":
        nm = n_R.mean(axis=0)
        f = F.fit_plane(p_R, normal_hint=nm if np.linalg.norm(nm) > 0.5 else None)
        return FittedFeature(kind, f.point - stylus_r * f.normal, f.normal, None, F.form_deviation(f))
    if kind == "line":
        q = np.column_stack([p_R[:, :2], np.zeros(len(p_R))])
        f = F.fit_line(q)
        d = np.array([f.direction[0], f.direction[1], 0.0])
        nrm = np.cross(d, [0.0, 0.0, 1.0])             # n = d x z: d = z x n for n in XY
        if float(np.sum(n_R[:, :2] @ nrm[:2])) < 0:    # the nominal normals' sense: outward
            d, nrm = -d, -nrm
        res = (q - f.point) @ nrm                       # signed XY residuals, + outward
        c = np.array([f.point[0], f.point[1], float(np.mean(p_R[:, 2]))])
        n0 = np.array([*n_R[:, :2].mean(axis=0), 0.0])
        d0 = np.cross([0.0, 0.0, 1.0], n0 / np.linalg.norm(n0)) if np.linalg.norm(n0) > 0 else d
        return FittedFeature(kind, c - stylus_r * nrm, d, None, float(res.max() - res.min()), d0)
    if kind == "circle":
        f = F.fit_circle_2d(p_R[:, :2])
        out = _outside(p_R[:, :2], n_R[:, :2], f.centre)
        c = np.array([f.centre[0], f.centre[1], float(np.mean(p_R[:, 2]))])
        return FittedFeature(kind, c, None, f.radius + (-stylus_r if out else stylus_r), F.form_deviation(f))
    if kind == "sphere":
        f = F.fit_sphere(p_R)
        out = _outside(p_R, n_R, f.centre)
        return FittedFeature(kind, f.centre, None, f.radius + (-stylus_r if out else stylus_r), F.form_deviation(f))
    if kind == "cylinder":
        f = F.fit_cylinder(p_R)
        out = _outside(p_R, n_R, f.point, f.axis)
        return FittedFeature(kind, f.point, f.axis, f.radius + (-stylus_r if out else stylus_r),
                             F.form_deviation(f))
    raise ConfigError(f"feature kind {kind!r}: expected one of {', '.join(KINDS)}")


def _xy_normal(f: FittedFeature) -> np.ndarray:
    """A line's outward normal in XY, ``d x z`` (3,), unit."""
    return np.cross(f.direction, [0.0, 0.0, 1.0])


def profile_deviations(p_R: np.ndarray, Xn_R: np.ndarray, n_R: np.ndarray) -> np.ndarray:
    """Each touch's profile deviation ``n . (p - Xn)`` (k,) m: + outside the nominal surface (see the module doc)."""
    return np.einsum("ij,ij->i", p_R - Xn_R, n_R)


def profile_value(stat: str, d: np.ndarray) -> float:
    """One ``statistic`` of profile deviations ``d`` (k,) m: max, min, rms or zone ``2 max |d|``."""
    if stat == "max":
        return float(d.max())
    if stat == "min":
        return float(d.min())
    if stat == "rms":
        return float(np.sqrt(np.mean(d * d)))
    return float(2.0 * np.abs(d).max())


def measurand_value(m: Measurand, feats: dict) -> float:
    """Value of one measurand from fitted features ``{name: FittedFeature}``, SI (m, rad).

    distance: plane-plane is the distance of B's point from plane A along
    A's normal; plane-centre the centre's distance from the plane;
    centre-centre the Euclidean distance (circles: in XY); with a line, the
    XY distance of the other's point from the line. angle: between
    plane normals (outward, so two faces of a block at 90 deg read 90),
    or with a cylinder axis (sign-free: in [0, 90] deg); between lines, their
    outward normals in XY; a line alone: its direction from +X in
    (-pi, pi]. A ``profile`` measurand is not a fitted feature's
    (:func:`evaluate`).
    """
    a = feats[m.of[0]]
    if m.quantity == "angle" and len(m.of) == 1:   # from +X, on the nominal direction's branch
        d, d0 = a.direction, a.nominal_direction
        return math.atan2(d0[1], d0[0]) + math.atan2(d0[0] * d[1] - d0[1] * d[0], d0[0] * d[0] + d0[1] * d[1])
    if m.quantity == "diameter":
        return 2.0 * a.radius
    if m.quantity == "position":
        return float(a.point["xyz".index(m.axis)])
    if m.quantity in FORM_OF:
        return a.form
    b = feats[m.of[1]]
    if "line" in (a.kind, b.kind):
        if m.quantity == "angle":
            return math.acos(max(-1.0, min(1.0, float(np.dot(_xy_normal(a), _xy_normal(b))))))
        ln, other = (a, b) if a.kind == "line" else (b, a)
        return abs(float(np.dot((other.point - ln.point)[:2], _xy_normal(ln)[:2])))
    if m.quantity == "angle":
        c = float(np.dot(a.direction, b.direction))
        if "cylinder" in (a.kind, b.kind):
            c = abs(c)
        return math.acos(max(-1.0, min(1.0, c)))
    # distance
    if a.kind == "plane" or b.kind == "plane":
        pl, other = (a, b) if a.kind == "plane" else (b, a)
        return abs(float(np.dot(other.point - pl.point, pl.direction)))
    d = b.point - a.point
    if "circle" in (a.kind, b.kind):
        d = d[:2]
    return float(np.linalg.norm(d))


def evaluate(task: Task, rows: dict, p_R: np.ndarray, n_R: np.ndarray, stylus_r: float,
             Xn_R: np.ndarray | None = None) -> np.ndarray:
    """Every measurand of ``task`` from one set of touches, (m,) SI.

    Parameters
    ----------
    rows : dict
        :func:`feature_rows`.
    p_R : (n, 3) float
        Reported stylus-tip centres of the plan's rows, R, m (NaN rows are
        refused: a missed touch is a failed run, named).
    n_R : (n, 3) float
        Nominal outward normals, R.
    stylus_r : float
        m.
    Xn_R : (n, 3) float, optional
        Nominal tip centres, R, m: needed by ``profile`` measurands.
    """
    feats = {}
    for f in task.features:
        r = rows[f.name]
        if not np.all(np.isfinite(p_R[r])):
            raise FitError(f"feature {f.name!r}: a touch did not trigger")
        feats[f.name] = fit_feature(f.kind, p_R[r], n_R[r], stylus_r)
    out = []
    for m in task.measurands:
        if m.quantity == "profile":
            if Xn_R is None:
                raise ConfigError(f"measurand {m.name!r}: a profile deviation needs the nominal points")
            r = rows[m.of[0]]
            out.append(profile_value(m.statistic, profile_deviations(p_R[r], Xn_R[r], n_R[r])))
        else:
            out.append(measurand_value(m, feats))
    return np.array(out)


# --------------------------------------------------------------------------- drawing the declared errors


def draw_periodic(term: "DeclaredTerm | PartForm", rng: np.random.Generator) -> tuple[float, float]:
    """One draw of a periodic term: (amplitude SI drawn as :func:`draw_term`, phase rad uniform in [0, 2 pi))."""
    return draw_term(term, rng), float(rng.uniform(0.0, 2.0 * math.pi))


def draw_term(term: "DeclaredTerm | PartForm", rng: np.random.Generator) -> float:
    """One draw of a declared coefficient (SI): uniform, normal (sigma = bound / 2), triangular
    or arcsine (``bound sin(phi)``, phi uniform: a periodic error at an unknown phase), all
    within +-``bound`` except the normal's tails."""
    b = term.bound
    if term.distribution == "uniform":
        return float(rng.uniform(-b, b))
    if term.distribution == "normal":
        return float(0.5 * b * rng.standard_normal())
    if term.distribution == "triangular":
        return float(rng.triangular(-b, 0.0, b))
    return float(b * math.sin(rng.uniform(0.0, 2.0 * math.pi)))


def run_seeds(seed: int, run: int) -> np.random.SeedSequence:
    """The seed of run ``run``: a run's draws do not depend on how the runs are batched or spread."""
    return np.random.SeedSequence([int(seed), int(run)])


# --------------------------------------------------------------------------- JCGM 101 statistics


@dataclass(frozen=True)
class MCStats:
    """Statistics of Monte Carlo values of one quantity (JCGM 101 7.6, 7.7)."""

    mean: float
    u: float
    low: float
    high: float
    runs: int


def mc_stats(y: np.ndarray, p: float = 0.95) -> MCStats:
    """Mean, standard uncertainty and probabilistically symmetric coverage interval (JCGM 101 7.7.2).

    ``y`` : (M,) values. With ``q = p M`` rounded to an integer and ``r =
    (M - q) / 2`` (``(M - q + 1) / 2`` when ``M - q`` is odd), the interval is
    ``[y_(r), y_(r+q)]`` of the sorted values (1-based).
    """
    y = np.asarray(y, float)
    M = y.size
    if M < 2 or not np.all(np.isfinite(y)):
        raise ConfigError(f"Monte Carlo statistics need >= 2 finite values, got {M}")
    q = int(p * M + 0.5)
    r = (M - q) // 2 if (M - q) % 2 == 0 else (M - q + 1) // 2
    r = max(r, 1)
    s = np.sort(y)
    return MCStats(float(y.mean()), float(y.std(ddof=1)), float(s[r - 1]), float(s[min(r + q, M) - 1]), M)


#: A measurand is flagged biased when the mean of its error (measured - true) over the Monte Carlo
#: runs exceeds this fraction of its U (the half-width of its coverage interval). Noise biases a form
#: measurand (a max - min of residuals) upward: the block's flatness of a perfect top reads +0.59 um on
#: average against U95 0.39 um, so measured +- U95 covers the true 0 in 15 % of runs. An unbiased
#: measurand's mean error is its Monte Carlo error, u / sqrt(M): below U / 60 from M = 1000 runs (k = 2);
#: a tenth of U still lets measured +- U cover the true value in 94.6 % of runs (normal errors, U = 1.96 u:
#: Phi(1.96 - 0.196) + Phi(1.96 + 0.196) - 1).
BIAS_OF_U = 0.1


@dataclass(frozen=True)
class ErrorStats:
    """The Monte Carlo error ``e = measured - true`` of one measurand, run by run (same units as given).

    ``low, high``: its probabilistically symmetric coverage interval (:func:`mc_stats`), so the true
    value lies in ``[measured - high, measured - low]`` with the coverage probability.
    ``U_about_true``: the coverage quantile of ``|e|``: measured +- it covers the true value in that
    share of the runs (a symmetric interval about the measured value). ``covers``: the share of runs
    in which measured +- ``U`` (the measured value's own half-width) covers the true value.
    """

    mean: float
    u: float
    low: float
    high: float
    U_about_true: float
    covers: float
    biased: bool


def error_stats(e: np.ndarray, U: float, p: float = 0.95, floor: float = 1e-12) -> ErrorStats:
    """:class:`ErrorStats` of errors ``e`` (M,) (measured - true per run) against the half-width ``U``
    of the measured value's own coverage interval; ``biased``: ``|mean e| > BIAS_OF_U * U`` and above
    ``floor`` (default 1e-12, for SI lengths: the fits' rounding, so a noise-free run's U = 0 with an
    error of 1e-18 m is not flagged)."""
    e = np.asarray(e, float)
    s = mc_stats(e, p)
    a = np.sort(np.abs(e))
    q = min(max(int(p * e.size + 0.5), 1), e.size)
    return ErrorStats(s.mean, s.u, s.low, s.high, float(a[q - 1]), float(np.mean(np.abs(e) <= U)),
                      bool(abs(s.mean) > max(BIAS_OF_U * U, floor)))


def saltelli_first_order(fA: np.ndarray, fB: np.ndarray, fAB: dict) -> tuple[dict, dict]:
    """First-order Sobol indices and their standard errors from pick-and-freeze samples.

    Saltelli et al. 2010 (Comput. Phys. Commun. 181, 259-270), table 2 (b):
    ``S_i = mean(f_B (f_{A_B^i} - f_A)) / V``, all values centred on the mean of
    ``f_A`` and ``f_B`` (the estimator is unbiased either way, but its variance
    grows with the mean squared), ``V`` the variance of ``f_A`` and ``f_B``
    together. The standard error is that of the numerator's mean over the ``n``
    rows, divided by ``V`` (``V`` taken as known: its own error is second order).

    Parameters
    ----------
    fA, fB : (n, m) float
        The model on the rows of the matrices A and B (m outputs).
    fAB : dict
        ``{source: (n, m)}``: on A with that source's column taken from B.

    Returns
    -------
    (S, se) : dicts ``{source: (m,) float}``; NaN for an output without variance.
    """
    fA, fB = np.atleast_2d(np.asarray(fA, float)), np.atleast_2d(np.asarray(fB, float))
    n = fA.shape[0]
    if n < 2 or fB.shape != fA.shape:
        raise ConfigError(f"Sobol indices need A and B of the same shape with >= 2 rows, got {fA.shape}, {fB.shape}")
    c = np.vstack([fA, fB]).mean(axis=0)
    fA, fB = fA - c, fB - c
    var = np.var(np.vstack([fA, fB]), axis=0)
    S, se = {}, {}
    with np.errstate(invalid="ignore", divide="ignore"):
        for src, f in fAB.items():
            t = fB * (np.asarray(f, float) - c - fA)
            S[src] = np.where(var > 0, t.mean(axis=0) / var, np.nan)
            se[src] = np.where(var > 0, t.std(axis=0, ddof=1) / math.sqrt(n) / var, np.nan)
    return S, se


def numerical_tolerance(u: float, n_dig: int) -> float:
    """JCGM 101 7.9.2: write ``u`` as ``c 10^l`` with ``c`` an ``n_dig``-digit integer; delta = 10^l / 2."""
    if not (u > 0 and math.isfinite(u)):
        return 0.0
    ll = math.floor(math.log10(u)) - (n_dig - 1)
    return 0.5 * 10.0 ** ll


@dataclass(frozen=True)
class Adaptive:
    """The adaptive procedure's verdict after ``h`` batches (JCGM 101 7.9.4 g-j).

    ``s`` : (4,) standard deviations of the batch means of (y, u(y),
    y_low, y_high); ``delta`` the numerical tolerance; ``stable`` when all
    of ``2 s <= delta``.
    """

    h: int
    s: np.ndarray
    delta: float
    stable: bool


def adaptive_check(batches: np.ndarray, u_all: float, n_dig: int = 2, tolerance: float | None = None,
                   which: str = "all") -> Adaptive:
    """JCGM 101 7.9.4 steps g)-j) for one quantity.

    Parameters
    ----------
    batches : (h, 4) float
        Per batch: y, u(y), y_low, y_high (:func:`mc_stats` of each batch).
    u_all : float
        u(y) from all h M values (step h), which sets the tolerance (step i).
    n_dig : int
        Significant digits of u(y) that must be stable.
    tolerance : float, optional
        An absolute numerical tolerance instead.
    which : {"all", "u"}
        Require all four quantities stable, or u(y) only (the budget's
        one-at-a-time runs, which report u only).
    """
    b = np.asarray(batches, float)
    h = b.shape[0]
    delta = tolerance if tolerance is not None else numerical_tolerance(u_all, n_dig)
    if h < 2:
        return Adaptive(h, np.full(4, np.inf), delta, False)
    s = b.std(axis=0, ddof=1) / math.sqrt(h)
    look = s if which == "all" else s[1:2]
    # u_all == 0 (a source without effect): every batch says 0, stable at any tolerance
    return Adaptive(h, s, delta, bool(np.all(2.0 * look <= delta) and (delta > 0 or np.all(look == 0))))
