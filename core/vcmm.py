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
    kind = "circle"              # plane | circle (in XY) | sphere | cylinder
    feature = "bore"             # rows whose plan column `feature` is this
    # targets = ["B01", "B02"]   # or/and these targets; setup = "S1" narrows

    [[measurands]]
    name = "bore diameter"
    quantity = "diameter"        # of one circle, sphere or cylinder
    of = "bore"
    # quantity = "position", axis = "x" | "y" | "z": a centre coordinate
    # quantity = "distance", of = [A, B]: plane-plane (along A's normal),
    #   centre-centre, plane-centre
    # quantity = "angle", of = [A, B]: between plane normals / cylinder axes
    # quantity = "flatness" | "roundness" | "sphericity" | "cylindricity"

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

Declared terms: ``constant_U``, and for a linear axis's motion errors also
``slope_U_per_m`` and ``quadratic_U_per_m2`` (``U`` = ``um`` for a
translation, ``urad`` for a rotation) of the axis reading, the same
polynomial as a machine file's, and ``periodic_U`` with ``period_mm``: a
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
KINDS = ("plane", "circle", "sphere", "cylinder")
#: quantity -> feature kinds it applies to (one feature), form names.
FORM_OF = {"flatness": "plane", "roundness": "circle", "sphericity": "sphere", "cylindricity": "cylinder"}
QUANTITIES = ("diameter", "position", "distance", "angle") + tuple(FORM_OF)
DISTRIBUTIONS = ("uniform", "normal", "triangular", "arcsine")
#: Standard uncertainty of a term declared with half-width (bound) 1 (normal: bound = U at k = 2).
U_PER_BOUND = {"uniform": 1 / math.sqrt(3), "normal": 0.5, "triangular": 1 / math.sqrt(6),
               "arcsine": 1 / math.sqrt(2)}
#: Power of the axis reading of each declared term.
TERM_POWER = {"constant": 0, "slope": 1, "quadratic": 2, "periodic": 0, "pretravel": 0, "lobing": 0}
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

    @property
    def unit(self) -> str:
        return {"angle": "deg"}.get(self.quantity, "um" if self.quantity in FORM_OF else "mm")

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
class Temperature:
    """Temperatures and expansion coefficients with their standard uncertainties (normal draws).

    The part expands about the centroid of its probed surface points by
    ``e_p = alpha_p (T_p - 20)``; the scales by ``e_s = alpha_s (T_s - 20)``
    (a reading is the true position over ``1 + e_s``: the tool sits at the
    reading times ``1 + e_s``, an ``EXX``, ``EYY``, ``EZZ`` slope of ``e_s``). The
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
                   centre: np.ndarray) -> np.ndarray:
    """Reported tip centres corrected to 20 C with the strains' best estimates, (n, 3) m.

    The tool is at the reading times ``1 + e_scales``; the surface point is
    ``r`` back along the normal; at 20 C the part is ``1 + e_part`` smaller
    about ``centre``; the tip centre goes back out by ``r`` (the ball does
    not belong to the part).
    """
    s = p_R * (1.0 + e_scales) - stylus_r * n_R
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

    @property
    def probe_sources(self) -> tuple:
        """The declared probe terms' budget names."""
        return ((PRETRAVEL_SOURCE,) if self.pretravel is not None else ()) + (
            (LOBING_SOURCE,) if self.lobing is not None else ())

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
    return _TaskReader(source).task(doc)


class _TaskReader(KeyReader):
    error_class = TaskFileError

    def string(self, key, v, *, nonempty: bool = True) -> str:
        return super().string(key, v, nonempty=nonempty)

    def task(self, doc) -> Task:
        self.keys("", doc, ("format", "description", "features", "measurands", "declared", "probe", "mc",
                            "temperature"))
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
        return Task(feats, meas, tuple(declared), noise, self.mc(self.table("mc", doc.get("mc", {}))), self.source,
                    temp, pre, lob)

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
        self.keys(key, body, ("name", "quantity", "of", "axis"))
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
        want2 = q in ("distance", "angle")
        if len(of) != (2 if want2 else 1):
            self.fail(f"{key}.of", f"{q} takes {'two features' if want2 else 'one feature'}, got {len(of)}")
        axis = None
        if q == "diameter" and k[0] == "plane":
            self.fail(f"{key}.of", "a plane has no diameter")
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
        if q == "distance" and "cylinder" in k:
            self.fail(f"{key}.of", "distance: between planes, circle and sphere centres (not a cylinder)")
        if q == "angle" and not all(x in ("plane", "cylinder") for x in k):
            self.fail(f"{key}.of", "angle: between planes and cylinder axes")
        return Measurand(name, q, tuple(of), axis)

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
        (the fits work in the machine frame R).

    Raises
    ------
    TaskFileError
        A feature that selects no row, or rows at different rotary positions.
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
    return out


# --------------------------------------------------------------------------- evaluating measurands


@dataclass(frozen=True)
class FittedFeature:
    """A feature's surface (stylus radius applied), SI, frame R.

    ``point`` (plane: centroid on the plane; circle: centre with z the mean
    height; sphere: centre; cylinder: a point on the axis), ``direction``
    (plane normal, cylinder axis, else None), ``radius`` (None for a plane),
    ``form`` (peak-to-valley of the residuals about the LS feature).
    """

    kind: str
    point: np.ndarray
    direction: np.ndarray | None
    radius: float | None
    form: float


def _outside(p, n, centre, axis=None) -> bool:
    r = p - centre
    if axis is not None:
        r = r - np.outer(r @ axis, axis)
    return float(np.sum(np.einsum("ij,ij->i", r, n))) >= 0


def fit_feature(kind: str, p_R: np.ndarray, n_R: np.ndarray, stylus_r: float) -> FittedFeature:
    """Least-squares feature of the reported tip centres, then the surface (stylus radius applied).

    Parameters
    ----------
    kind : {"plane", "circle", "sphere", "cylinder"}
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


def measurand_value(m: Measurand, feats: dict) -> float:
    """Value of one measurand from fitted features ``{name: FittedFeature}``, SI (m, rad).

    distance: plane-plane is the distance of B's point from plane A along
    A's normal; plane-centre the centre's distance from the plane;
    centre-centre the Euclidean distance (circles: in XY). angle: between
    plane normals (outward, so two faces of a block at 90 deg read 90),
    or with a cylinder axis (sign-free: in [0, 90] deg).
    """
    a = feats[m.of[0]]
    if m.quantity == "diameter":
        return 2.0 * a.radius
    if m.quantity == "position":
        return float(a.point["xyz".index(m.axis)])
    if m.quantity in FORM_OF:
        return a.form
    b = feats[m.of[1]]
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


def evaluate(task: Task, rows: dict, p_R: np.ndarray, n_R: np.ndarray, stylus_r: float) -> np.ndarray:
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
    """
    feats = {}
    for f in task.features:
        r = rows[f.name]
        if not np.all(np.isfinite(p_R[r])):
            raise FitError(f"feature {f.name!r}: a touch did not trigger")
        feats[f.name] = fit_feature(f.kind, p_R[r], n_R[r], stylus_r)
    return np.array([measurand_value(m, feats) for m in task.measurands])


# --------------------------------------------------------------------------- drawing the declared errors


def draw_periodic(term: DeclaredTerm, rng: np.random.Generator) -> tuple[float, float]:
    """One draw of a periodic term: (amplitude SI drawn as :func:`draw_term`, phase rad uniform in [0, 2 pi))."""
    return draw_term(term, rng), float(rng.uniform(0.0, 2.0 * math.pi))


def draw_term(term: DeclaredTerm, rng: np.random.Generator) -> float:
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
