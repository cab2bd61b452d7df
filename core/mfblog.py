"""A multi-feature bar's probe log (``# artefact: mfb``) read into the volumetric identification's inputs.

The MFB identification (:mod:`core.volumetric`, Viprey 2016 eqs 8-12) and its discovery baseline
(:func:`core.baseline.volumetric`) take *measurements*: one probing of the bar in one set-up (a bar pose on
the table and, on a 5-axis machine, its rotary positions) with one stylus (probe offsets J, eq. 8). A
``probe-log/1`` file of such a campaign carries them, row by row (docs/formats.md, "A multi-feature bar's
log"):

- ``setup``: the set-up (one bar pose: the touches of every stylus in it share the placement's six
  nuisance values); ``stylus`` (a column naming each row's stylus, its offsets J on the log's
  ``stylus_offsets_mm`` line: ``T0=0,0,150; TY1=0,-100,150``), or one stylus for the whole log (the
  ``tool_offset_mm`` line, as ``vmt probe`` writes it); ``measurement`` (optional): the measurement's name
  (default: the set-up's, with ``a``, ``b``, ... after it when the set-up has several styli);
- ``feature`` (``holeNN``, ``rodNN``, ``faceLNN``, ``faceRNN``: the points of interest are fitted from
  them, :func:`core.mfb.points_of_interest_batched`), ``wx_mm``..``wz_mm`` and ``wnx``..``wnz`` (each
  touch's nominal contact point and normal in the bar's frame A: the extraction's gain
  :func:`core.mfb.poi_noise_gain` is taken there, and with the nominal tip centres ``Xn_mm``..``Zn_mm``
  they give the set-up's nominal bar pose, :func:`bar_pose_W`), the stylus radius (column or line), the
  rotary positions (``A_deg``, ``B_deg``, ``C_deg``, the chain's), ``t_s`` (a measurement's time: the mean
  of its touches', for the discovery's time covariate);
- lines: ``kinematic_chain`` (required), ``bar_calibration_E_um`` and ``bar_calibration_u_um`` (the bar's
  certificate: 36 numbers each, Exx, Eyx, Ezx of its 12 points of interest and their standard
  uncertainties, um, as ``vmt-bar-calibration/1``'s ``E_um``, ``u_um``; or given apart, ``--bar-calibration
  FILE``), ``error_table_nodes_mm`` (optional: ``X=...; Y=...; Z=...``, axis positions reading + J; default
  :func:`derived_nodes`), ``rotary_points_mm`` (optional: a point on each rotary axis, R, all axes at zero;
  default the origin: a wrong point only translates each set-up's W, which its fitted pose takes),
  ``probe_repeatability_k2_um`` (the probe's, k = 2; ``plan_probe_repeatability_k2_um`` in a log made from
  a plan).

What is missing is refused in one line naming it (:class:`~core.exceptions.ConfigError`). core only: numpy.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from .exceptions import ConfigError, VmtError
from .mfb import MFB
from .units import MM, UM

#: The value of the ``artefact`` line of a multi-feature bar's log.
MFB_ARTEFACT = "mfb"
#: Line naming each stylus's probe offsets J (spindle gauge point minus stylus-tip centre), mm.
STYLUS_OFFSETS_KEY = "stylus_offsets_mm"
#: Line of one probe's offsets J for the whole log (``vmt probe`` / ``vmt import grbl --tool-offset-mm``), mm.
TOOL_OFFSET_KEY = "tool_offset_mm"
#: Line of the error tables' nodes (axis positions, reading + J), mm.
NODES_KEY = "error_table_nodes_mm"
#: Line of a point on each rotary axis (R, all axes at zero), mm.
ROTARY_POINTS_KEY = "rotary_points_mm"
#: Lines of the bar's calibration certificate at its 12 points of interest: Exx, Eyx, Ezx (um), and their u.
BAR_E_KEY = "bar_calibration_E_um"
BAR_U_KEY = "bar_calibration_u_um"
#: The probe's repeatability line (k = 2, um), and its name in a log made from a plan.
REPEATABILITY_KEYS = ("probe_repeatability_k2_um", "plan_probe_repeatability_k2_um")
#: Columns: each row's stylus, and (optional) its measurement's name.
STYLUS_COLUMN = "stylus"
MEASUREMENT_COLUMN = "measurement"
#: The largest number of nodes :func:`derived_nodes` puts along an axis: a bar of 12 holes has 11 rods, its only
#: height sensors, so 12 nodes along X leave one EZX combination seen by curvature alone (``scenarios.mfb``'s
#: 3-axis plan: 9 nodes over its 12 holes).
MAX_NODES = 9
#: A fitted bar pose's rotation entries within this of 0 or +-1 are taken as exactly 0 or +-1 (:func:`bar_pose_W`).
SNAP = 1.0e-12
#: The log's holes (their axes from the nominal contact points and normals, ``wx_mm``.., ``wnx``..) must sit where
#: the bar's design puts them (:data:`core.mfb.MFB`: every pitch from hole 1's axis, the mistake-proofing holes
#: shifted in y) to this, mm: the identification takes the points' nominal places from that design, so a log of
#: another bar, or of this bar in other units (m, um), is refused naming the hole, not identified against the
#: wrong bar (the same 0.01 mm as a certificate's ``x_mm``, ``scenarios.mfb.BAR_X_TOL_MM``; session 38).
HOLE_PLACE_TOL_MM = 0.01
#: Within a set-up, every stylus's touches must give one bar pose (:func:`bar_pose_W`) to this, m: the nominal
#: columns are a perfect machine's, so they agree to their printing.
POSE_TOL_M = 1.0e-6


def is_mfb_log(log) -> bool:
    """Whether ``log`` (a :class:`core.probelog.ProbeLog`) declares a multi-feature bar (its ``artefact`` line)."""
    return str(log.meta.get("artefact", "")).strip().lower() == MFB_ARTEFACT


def _named_vectors(text: str, key: str, src: str, width: int | None = 3) -> dict:
    """``"T0=0,0,150; TY1=0,-100,150"`` -> {name: (k,) float} (the numbers as written)."""
    out = {}
    for part in str(text).split(";"):
        if not part.strip():
            continue
        name, eq, vals = part.partition("=")
        try:
            v = np.array([float(x) for x in vals.split(",")], float) if eq else np.zeros(0)
        except ValueError:
            v = np.zeros(0)
        if (not eq or not name.strip() or v.size == 0 or (width is not None and v.size != width)
                or not np.all(np.isfinite(v))):
            want = f"{width} numbers" if width else "numbers"
            raise ConfigError(f"{src}: its {key} line: {part.strip()!r} is not NAME={want} separated by commas "
                              f"(entries separated by ';')")
        out[name.strip()] = v
    if not out:
        raise ConfigError(f"{src}: its {key} line is empty")
    return out


def format_named_vectors(vectors: dict) -> str:
    """The inverse of :func:`_named_vectors`: ``{name: values}`` -> ``"NAME=v,v,v; ..."`` (shortest round trip)."""
    return "; ".join(f"{k}=" + ",".join(repr(float(v)) for v in np.ravel(vals)) for k, vals in vectors.items())


def _numbers(text: str, key: str, src: str, count: int) -> np.ndarray:
    try:
        v = np.array([float(x) for x in str(text).replace(";", ",").split(",") if x.strip()], float)
    except ValueError:
        v = np.zeros(0)
    if v.size != count or not np.all(np.isfinite(v)):
        raise ConfigError(f"{src}: its {key} line must hold {count} finite numbers separated by commas, got "
                          f"{v.size if v.size else 'none readable'}")
    return v


def format_numbers(values) -> str:
    return ",".join(repr(float(v)) for v in np.ravel(values))


@dataclass(frozen=True)
class BarCertificate:
    """The bar's calibration at its points of interest: ``E_m`` (12, 3) deviations Exx, Eyx, Ezx in A, m, and
    ``u_m`` (12, 3) their standard uncertainties, m; ``source`` says where they came from."""

    E_m: np.ndarray = field(repr=False)
    u_m: np.ndarray = field(repr=False)
    source: str = ""


def certificate_of_log(log) -> BarCertificate | None:
    """The log's own certificate (its ``bar_calibration_E_um`` and ``bar_calibration_u_um`` lines), or None
    when it has neither; one without the other is refused."""
    src, m = log.source, log.meta
    has = [k for k in (BAR_E_KEY, BAR_U_KEY) if str(m.get(k, "")).strip()]
    if not has:
        return None
    if len(has) == 1:
        other = BAR_U_KEY if has[0] == BAR_E_KEY else BAR_E_KEY
        raise ConfigError(f"{src}: its {has[0]} line has no {other} line beside it (the bar's certificate: both)")
    n = MFB.n_holes
    E = _numbers(m[BAR_E_KEY], BAR_E_KEY, src, 3 * n).reshape(n, 3) * UM
    u = _numbers(m[BAR_U_KEY], BAR_U_KEY, src, 3 * n).reshape(n, 3) * UM
    if np.any(u < 0):
        raise ConfigError(f"{src}: its {BAR_U_KEY} line must hold standard uncertainties >= 0")
    return BarCertificate(E, u, f"the log's {BAR_E_KEY} and {BAR_U_KEY} lines")


def certificate_lines(E_m, u_m) -> dict:
    """The two metadata lines of a certificate (:func:`certificate_of_log` reads them)."""
    return {BAR_E_KEY: format_numbers(np.asarray(E_m, float) / UM),
            BAR_U_KEY: format_numbers(np.asarray(u_m, float) / UM)}


def probe_sigma_of_log(log) -> float | None:
    """The probe's repeatability as a standard deviation (k = 1), m, from the log's line, or None."""
    for k in REPEATABILITY_KEYS:
        v = str(log.meta.get(k, "")).strip()
        if v:
            x = _numbers(v, k, log.source, 1)[0]
            if x < 0:
                raise ConfigError(f"{log.source}: its {k} line must be >= 0 (um, k = 2), got {v}")
            return float(x) / 2.0 * UM
    return None


def bar_pose_W(c_A: np.ndarray, p_W: np.ndarray) -> np.ndarray:
    """(4, 4) the rigid pose T_W_A that takes the nominal stylus centres ``c_A`` (t, 3, bar frame) onto ``p_W``
    (t, 3, W): least squares (Kabsch, no scale). Raises ConfigError when they do not span a plane or do not
    fit one pose (:data:`POSE_TOL_M`)."""
    ca, pw = c_A.mean(axis=0), p_W.mean(axis=0)
    H = (c_A - ca).T @ (p_W - pw)
    U, s, Vt = np.linalg.svd(H)
    if s.size < 3 or s[1] <= 1e-12 * max(s[0], 1e-300):
        raise ConfigError("the touches' nominal points lie on a line: no bar pose")
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    # a designed pose's exact entries (0, +-1: a bar along an axis, or a tilt in one plane) kept exact: the fit
    # leaves them 1e-16 off, and core.volumetric then gives 1e-16 where a nominal pose gives exactly zero (the roll
    # of the mistake-proofing holes; until session 38 core.baseline.volumetric left such rows out only when they
    # were zero, now by the pose's structure, core.volumetric.roll_rows): the log's numbers the in-memory run's
    R[np.abs(R) < SNAP] = 0.0
    R[np.abs(np.abs(R) - 1.0) < SNAP] = np.sign(R[np.abs(np.abs(R) - 1.0) < SNAP])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = pw - R @ ca
    miss = float(np.max(np.linalg.norm(c_A @ R.T + T[:3, 3] - p_W, axis=1)))
    if miss > POSE_TOL_M:
        raise ConfigError(f"the touches' nominal contact points (wx_mm..) and nominal tip centres (Xn_mm..) do not "
                          f"fit one bar pose: {miss / MM:.4g} mm off")
    return T


def check_hole_places(w_A: np.ndarray, wn_A: np.ndarray, feature, geom=MFB, src: str = "") -> None:
    """Refuse (ConfigError, naming the first hole off) a log whose holes are not the bar's design: each hole's
    axis (x, y in the bar's frame A) from its touches' nominal contact points ``w_A`` and normals ``wn_A``
    (m; the contact point is the axis plus the radius against the normal, which points into the hole: least
    squares for the axis and the radius) must be ((i - 1) pitch, shift_i) within :data:`HOLE_PLACE_TOL_MM`.
    A hole whose touches do not fix an axis (fewer than two distinct normals) is left to the fit, which
    refuses it by name."""
    feature = np.asarray(feature, object)
    for f in dict.fromkeys(feature):
        name = str(f).strip()
        if not (name.startswith("hole") and name[4:].isdigit()):
            continue
        i = int(name[4:])
        idx = np.flatnonzero(feature == f)
        n = np.asarray(wn_A, float)[idx, :2]
        if len(idx) < 2 or np.linalg.matrix_rank(n, tol=1e-6) < 2:
            continue
        # axis c and radius R: w = c - R n  ->  [I | -n] (c, R) = w
        A = np.zeros((2 * len(idx), 3))
        A[0::2, 0] = A[1::2, 1] = 1.0
        A[:, 2] = -n.ravel()
        c = np.linalg.lstsq(A, np.asarray(w_A, float)[idx, :2].ravel(), rcond=None)[0][:2]
        want = np.array([(i - 1) * geom.pitch_m, geom.shift_of(i)]) if 1 <= i <= geom.n_holes else None
        if want is None or np.max(np.abs(c - want)) > HOLE_PLACE_TOL_MM * MM:
            where = (f"where the bar's design puts it at x = {want[0] / MM:.4g}, y = {want[1] / MM:.4g} mm"
                     if want is not None else f"a hole the bar does not have (it has {geom.n_holes})")
            raise ConfigError(
                f"{src}: the bar in its wx_mm.. columns is not vmt's multi-feature bar: {name}'s axis at x = "
                f"{c[0] / MM:.6g}, y = {c[1] / MM:.6g} mm in the bar's frame, {where} (holes every "
                f"{geom.pitch_m / MM:g} mm from hole01's axis, the frame's origin; within {HOLE_PLACE_TOL_MM} mm): "
                "a log in other units than mm, or of another bar")


def derived_nodes(meas, chain: str, rotary_points_R_m=None) -> dict:
    """The error tables' nodes where the log's line gives none: per linear axis, the axis positions (reading +
    J) of the nominal points of interest (the bar's design in its nominal pose) of the bars that lie along that
    axis in R (within 1 deg), from the lowest to the highest, evenly spaced, as many as the most holes one such
    measurement probed, at most :data:`MAX_NODES` (``scenarios.mfb``'s plans: 9 along X over 12 holes, one per
    hole along Y and Z; tests/scenarios/test_mfb_log_route.py checks both plans' own nodes come out). Raises
    ConfigError naming an axis no bar lies along."""
    from .kinematics import ChainGeometry
    from .volumetric import _nominal_readings

    out = {}
    for j, a in enumerate("XYZ"):
        lo, hi, most = np.inf, -np.inf, 0
        for m in meas:
            T = np.asarray(m.T_W_A, float)
            g = ChainGeometry.of(chain, m.J_m, rotary_points_R_m or {})
            R_RW = _R_RW(g, m.rot_rad)
            x_R = R_RW @ T[:3, 0]
            if abs(x_R[j]) < np.cos(np.deg2rad(1.0)):
                continue
            q = _nominal_readings(m, chain, rotary_points_R_m)[:, j] + float(m.J_m[j])
            lo, hi, most = min(lo, q.min()), max(hi, q.max()), max(most, len(m.holes))
        if most < 2:
            raise ConfigError(f"no bar lies along {a}: the error tables of {a} have no nodes (give them on an "
                              f"{NODES_KEY} line)")
        out[a] = np.linspace(lo, hi, min(most, MAX_NODES))
    return out


def _R_RW(g, rot_rad) -> np.ndarray:
    """(3, 3) the nominal orientation of W in R at the rotary positions (the identity without rotary axes)."""
    from .kinematics import tip_W

    nr = len(g.chain.rotary_axes)
    rot = np.tile(np.asarray(rot_rad, float).reshape(1, -1), (4, 1)) if nr else None
    q4 = np.vstack([np.zeros(3), np.eye(3)])
    t4 = tip_W(g, q4, rot, None)
    M = (t4[1:] - t4[0]).T   # d tip_W / d reading: R_WR
    return M.T


@dataclass(frozen=True)
class MfbLog:
    """What a multi-feature bar's probe log gives the volumetric identification and its discovery baseline.

    Attributes
    ----------
    meas : tuple of core.volumetric.Measurement
        One per (set-up, stylus), in the log's order.
    chain : str
    nodes : dict axis -> (k,) float
        The error tables' nodes (axis positions, reading + J), m.
    nodes_from : str
        ``"log"`` (its :data:`NODES_KEY` line) or ``"derived"`` (:func:`derived_nodes`).
    rotary_points_R_m : dict
    times_s : dict measurement name -> s
        Each measurement's time: the mean of its touches' ``t_s``.
    certificate : BarCertificate
    sigma_probe_m : float or None
        The probe's repeatability (k = 1), m: the log's line, else None.
    touches : int
        Valid touches read.
    styli : dict name -> (3,) float
        The styli's probe offsets J, m.
    t_range_s : (float, float)
        The first and last valid touch's ``t_s`` (NaN when the log has no times).
    """

    meas: tuple
    chain: str
    nodes: dict = field(repr=False)
    nodes_from: str
    rotary_points_R_m: dict = field(repr=False)
    times_s: dict = field(repr=False)
    certificate: BarCertificate = field(repr=False)
    sigma_probe_m: float | None
    touches: int
    styli: dict = field(repr=False)
    t_range_s: tuple = (float("nan"), float("nan"))

    @property
    def setups(self) -> tuple:
        return tuple(dict.fromkeys(m.placement for m in self.meas))


def _styli(log, rows) -> tuple[np.ndarray, dict]:
    """(each row's stylus name, {name: J (3,) m})."""
    src, m = log.source, log.meta
    if log.has(STYLUS_COLUMN):
        names = np.array([str(s).strip() for s in log.col(STYLUS_COLUMN)[rows]], object)
        if np.any(names == ""):
            r = int(rows[np.flatnonzero(names == "")[0]])
            raise ConfigError(f"{src}: data row {r + 1} has no stylus (its {STYLUS_COLUMN} cell is empty)")
        if not str(m.get(STYLUS_OFFSETS_KEY, "")).strip():
            raise ConfigError(f"{src}: an MFB log with a {STYLUS_COLUMN} column needs a {STYLUS_OFFSETS_KEY} line "
                              "(each stylus's probe offsets J, mm: T0=0,0,150; TY1=0,-100,150)")
        J = {k: v * MM for k, v in _named_vectors(m[STYLUS_OFFSETS_KEY], STYLUS_OFFSETS_KEY, src).items()}
        missing = sorted(set(names) - set(J))
        if missing:
            raise ConfigError(f"{src}: stylus {missing[0]!r} has no offsets on its {STYLUS_OFFSETS_KEY} line "
                              f"(it names {', '.join(J)})")
        return names, J
    v = str(m.get(TOOL_OFFSET_KEY, "")).strip()
    if not v:
        raise ConfigError(f"{src}: an MFB log needs its probe offsets J: a {STYLUS_COLUMN} column with a "
                          f"{STYLUS_OFFSETS_KEY} line, or one probe's {TOOL_OFFSET_KEY} line (mm)")
    J = _numbers(v, TOOL_OFFSET_KEY, src, 3) * MM
    return np.full(len(rows), "J", object), {"J": J}


#: The feature names the points of interest are fitted from (core.mfb ignores others): named in a refusal.
_FEATURE_NAME = re.compile(r"(hole|rod|faceL|faceR)\d+")

REQUIRED_COLUMNS = ("feature", "wx_mm", "wy_mm", "wz_mm", "wnx", "wny", "wnz")


def missing_inputs(log, has_certificate: bool) -> list[str]:
    """What an MFB log lacks for the identification, each in words naming where it goes (empty: nothing):
    the chain, the columns, the probe offsets J, the bar's calibration (``has_certificate``: given apart)."""
    out = []
    if not str(log.meta.get("kinematic_chain", "")).strip():
        out.append("its kinematic_chain line (the machine's chain, e.g. [w X Y b Z t])")
    cols = [c for c in REQUIRED_COLUMNS if not log.has(c)]
    if cols:
        out.append(f"the columns {', '.join(cols)} (the touches' features and nominal points and normals in the "
                   "bar's frame)")
    if log.has(STYLUS_COLUMN):
        if not str(log.meta.get(STYLUS_OFFSETS_KEY, "")).strip():
            out.append(f"a {STYLUS_OFFSETS_KEY} line for its {STYLUS_COLUMN} column (each stylus's probe offsets J, "
                       "mm: T0=0,0,150; TY1=0,-100,150)")
    elif not str(log.meta.get(TOOL_OFFSET_KEY, "")).strip():
        out.append(f"the probe offsets J (a {STYLUS_COLUMN} column with a {STYLUS_OFFSETS_KEY} line, or one "
                   f"probe's {TOOL_OFFSET_KEY} line, mm)")
    if not has_certificate:
        out.append(f"the bar's calibration (--bar-calibration FILE, vmt-bar-calibration/1, or the log's {BAR_E_KEY} "
                   f"and {BAR_U_KEY} lines)")
    return out


def read_mfb_log(log, certificate: BarCertificate | None = None, *, geom=MFB, progress=None) -> MfbLog:
    """The volumetric identification's inputs from a multi-feature bar's probe log (module doc).

    Parameters
    ----------
    log : core.probelog.ProbeLog
        A validated campaign log with ``artefact: mfb``.
    certificate : BarCertificate, optional
        The bar's calibration (e.g. a ``vmt-bar-calibration/1`` file); default the log's own lines.
    progress : callable, optional
        ``progress(done, total)`` before the first measurement's noise gain (``done`` 0: the points of interest
        fitted) and after each (most of the reading's cost: 17 measurements, 0.2 s each on a busy core), ``total``
        the measurements.

    Raises
    ------
    ConfigError
        Naming what is missing or inconsistent: the chain, a column, the styli's offsets, the certificate, a
        measurement whose touches do not give its points of interest (a feature missing), a set-up whose
        styli see two bar poses, a measurement that turns within itself.
    """
    from . import volumetric as vol
    from .chain import parse_chain
    from .kinematics import ChainGeometry, tip_W
    from .mfb import points_of_interest_batched, poi_noise_gain
    from .touches import from_log

    src = log.source
    if not is_mfb_log(log):
        raise ConfigError(f"{src}: not a multi-feature bar's log (its artefact line is not '{MFB_ARTEFACT}')")
    chain = str(log.meta.get("kinematic_chain", "")).strip()
    cert = certificate if certificate is not None else certificate_of_log(log)
    lacks = missing_inputs(log, cert is not None)
    if lacks:
        raise ConfigError(f"{src}: this multi-feature bar's log cannot be identified: it lacks " + "; ".join(lacks))
    ch = parse_chain(chain)
    t = from_log(log)
    rows = np.asarray(t.row, int)
    r_mm = np.asarray(log.col("stylus_r_mm"), float)[rows]
    if not np.all(np.isfinite(r_mm)):
        raise ConfigError(f"{src}: data row {int(rows[np.flatnonzero(~np.isfinite(r_mm))[0]]) + 1} has no stylus "
                          "radius (a stylus_r_mm column or line)")
    if np.any(np.array([str(f).strip() == "" for f in t.feature])):
        raise ConfigError(f"{src}: every touch of an MFB log needs its feature (holeNN, rodNN, faceLNN, faceRNN)")
    names, J = _styli(log, rows)
    setup = np.asarray(t.setup_ids, object)[t.setup]
    if log.has(MEASUREMENT_COLUMN):
        mname = np.array([str(s).strip() for s in log.col(MEASUREMENT_COLUMN)[rows]], object)
        if np.any(mname == ""):
            r = int(rows[np.flatnonzero(mname == "")[0]])
            raise ConfigError(f"{src}: data row {r + 1} has no measurement (its {MEASUREMENT_COLUMN} cell is empty)")
        keys = list(dict.fromkeys(mname))
        groups = [np.flatnonzero(mname == k) for k in keys]
        for k, g in zip(keys, groups):
            if len(set(setup[g])) != 1 or len(set(names[g])) != 1:
                raise ConfigError(f"{src}: measurement {k!r} spans several set-ups or styli (one of each per "
                                  "measurement)")
    else:
        pairs = list(dict.fromkeys(zip(setup, names)))
        per_setup: dict = {}
        for s, st in pairs:
            per_setup.setdefault(s, []).append(st)
        keys = [s if len(per_setup[s]) == 1 else f"{s}{_letters(per_setup[s].index(st))}" for s, st in pairs]
        groups = [np.flatnonzero((setup == s) & (names == st)) for s, st in pairs]
    # rotary positions in the chain's order
    rot_cols = [f"{a}_deg" for a in ch.rotary_axes]
    rot_all = np.column_stack([np.asarray(log.col(c), float)[rows] * np.pi / 180.0 for c in rot_cols]) \
        if rot_cols else np.zeros((len(rows), 0))
    rp = {}
    if str(log.meta.get(ROTARY_POINTS_KEY, "")).strip():
        rp = {k: tuple(v * MM) for k, v in _named_vectors(log.meta[ROTARY_POINTS_KEY], ROTARY_POINTS_KEY, src).items()}
        extra = sorted(set(rp) - set(ch.rotary_axes))
        if extra:
            raise ConfigError(f"{src}: its {ROTARY_POINTS_KEY} line names {extra[0]!r}, not a rotary axis of "
                              f"its chain {chain}")
    w_A, wn_A = t.w_A, t.wn_A
    check_hole_places(w_A, wn_A, t.feature, geom, src)
    r_m = r_mm * MM
    c_A = w_A + r_m[:, None] * wn_A
    parts, specs = [], []
    for k, g in zip(keys, groups):
        rot = rot_all[g]
        if rot.shape[1] and np.ptp(rot, axis=0).max() > 1e-9:
            raise ConfigError(f"{src}: measurement {k!r} turns its rotary axes within itself (one set of rotary "
                              "positions per measurement)")
        rot_k = tuple(float(v) for v in rot[0]) if rot.shape[1] else ()
        st = str(names[g[0]])
        geo = ChainGeometry.of(chain, J[st], rp)
        p_W = tip_W(geo, t.pn_R[g], np.tile(np.asarray(rot_k).reshape(1, -1), (len(g), 1)) if rot_k else None, None)
        try:
            T = bar_pose_W(c_A[g], p_W)
        except ConfigError as e:
            raise ConfigError(f"{src}: measurement {k!r}: {e}") from None
        parts.append((t.p_R[g], t.feature[g], t.n_R[g]))
        specs.append((k, str(setup[g[0]]), st, rot_k, T, g))
    # one bar pose per set-up (its styli's touches)
    first: dict = {}
    for k, s, st, rot_k, T, g in specs:
        if s in first:
            k0, T0 = first[s]
            off = float(np.max(np.abs(T[:3, :3] - T0[:3, :3])) * 1.0 + np.max(np.abs(T[:3, 3] - T0[:3, 3])))
            if off > POSE_TOL_M:
                raise ConfigError(f"{src}: set-up {s!r}: measurements {k0!r} and {k!r} see two bar poses (their "
                                  "nominal columns disagree): one set-up, one pose")
        else:
            first[s] = (k, T)
    try:
        pois = points_of_interest_batched(parts, geom)
    except VmtError as e:   # (FitError: a feature missing or too few touches on one)
        names = sorted({str(f).strip() for f in t.feature})
        odd = [f for f in names if not _FEATURE_NAME.fullmatch(f)]
        hint = (f" (the features are named holeNN, rodNN, faceLNN, faceRNN; this log's other names: "
                f"{', '.join(odd[:6])}{', ...' if len(odd) > 6 else ''})") if odd else ""
        raise ConfigError(f"{src}: the points of interest cannot be fitted: {e}{hint}") from None
    E, u = np.asarray(cert.E_m, float), np.asarray(cert.u_m, float)
    if E.shape != (geom.n_holes, 3) or u.shape != (geom.n_holes, 3):
        raise ConfigError(f"the bar calibration ({cert.source}) must be ({geom.n_holes}, 3) deviations and u")
    meas, times = [], {}
    if progress is not None:
        progress(0, len(specs))     # the points of interest fitted: the gains start
    for i, ((k, s, st, rot_k, T, g), poi) in enumerate(zip(specs, pois)):
        holes = tuple(int(h) for h in poi.holes)
        idx = [h - 1 for h in holes]
        try:
            G = poi_noise_gain(c_A[g], t.feature[g], wn_A[g], -wn_A[g], geom)
        except VmtError as e:
            raise ConfigError(f"{src}: measurement {k!r}: {e}") from None
        meas.append(vol.Measurement(k, s, holes, poi.O_R, geom.O_A(holes) + E[idx], T, rot_k, tuple(J[st]), G,
                                    q_R=t.p_R[g], c_A=c_A[g], d_A=-wn_A[g], feature=tuple(t.feature[g]),
                                    n_A=wn_A[g]))
        times[k] = float(np.mean(t.t_s[g]))
        if progress is not None:
            progress(i + 1, len(specs))
    if str(log.meta.get(NODES_KEY, "")).strip():
        nodes = {a: np.sort(v * MM) for a, v in _named_vectors(log.meta[NODES_KEY], NODES_KEY, src, None).items()}
        lack = [a for a in "XYZ" if a not in nodes or nodes[a].size < 2]
        if lack:
            raise ConfigError(f"{src}: its {NODES_KEY} line needs two nodes or more for each of X, Y, Z "
                              f"({lack[0]} has fewer)")
        nodes_from = "log"
    else:
        try:
            nodes = derived_nodes(meas, chain, rp)
        except ConfigError as e:
            raise ConfigError(f"{src}: {e}") from None
        nodes_from = "derived"
    tt = np.asarray(t.t_s, float)
    tt = tt[np.isfinite(tt)]
    return MfbLog(tuple(meas), chain, nodes, nodes_from, rp, times, cert, probe_sigma_of_log(log), int(len(rows)),
                  dict(J), (float(tt.min()), float(tt.max())) if tt.size else (float("nan"), float("nan")))


def _letters(i: int) -> str:
    """a, b, ..., z, aa, ab, ...: the suffix of a set-up's i-th stylus (``scenarios.mfb``'s plans name them so)."""
    s = ""
    i += 1
    while i:
        i, r = divmod(i - 1, 26)
        s = chr(97 + r) + s
    return s
