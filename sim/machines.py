"""Named virtual machines and a "realistic" truth error set.

``MACHINES[name](errors=..., **geometry) -> MachineConfig``; each built-in
machine is a machine file shipped in the package (``sim/data/machines/``,
:mod:`sim.machinefile`):

- ``vmc-3axis``: 3-axis vertical machining centre ``V[w-X-Y-b-Z-(C)-t]``
  (table on X on Y, spindle on Z).
- ``mikron-ucp710``: 5-axis trunnion ``[w C' A' b X Y Z (C1) t]`` of the MFB
  paper (Viprey et al. 2016), all linear axes on the tool side (eq. 8).
- ``nmv3000``: 5-axis ``V[w-C-A-b-Y-X-Z-(C)-t]`` of the self-calibration
  paper (Ibaraki et al.), X riding on Y.

R's origin is on the C-axis centre line at the table surface (self-
calibration paper, section 2.1); readings are stylus-tip positions in R.
Error values are ISO 230-1 values: the tool relative to the workpiece
(CONTRIBUTING.md, "Error conventions").
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from core import iso
from core.exceptions import ConfigError
from sim.errorfuncs import Constant, ErrorFunction, Periodic, Polynomial, SplineTable, Sum
from sim.machine import MachineConfig
from core.units import DEG

#: Default probe offsets (J_X, J_Y, J_Z), m: a 150 mm probe below the gauge line.
DEFAULT_J_M = (0.0, 0.0, 0.150)


@functools.lru_cache(maxsize=None)
def _builtin_config(file_name: str) -> MachineConfig:
    from sim.machinefile import builtin_text, loads

    return loads(builtin_text(file_name), source=file_name).config


def _builtin(file_name: str) -> Callable[..., MachineConfig]:
    def factory(*, errors: Mapping[str, ErrorFunction] | None = None, J_m=None,
                rotary_points_R_m: Mapping | None = None, strokes: Mapping | None = None,
                name: str | None = None) -> MachineConfig:
        from dataclasses import replace

        cfg = _builtin_config(file_name)
        st = dict(cfg.strokes)
        st.update(strokes or {})
        pts = dict(cfg.rotary_points_R_m)
        pts.update(rotary_points_R_m or {})
        return replace(cfg, name=name or cfg.name, strokes=st, rotary_points_R_m=pts,
                       J_m=tuple(cfg.J_m if J_m is None else J_m), errors=dict(errors or {}))

    factory.__name__ = file_name.replace("-", "_")
    factory.__doc__ = (f"The built-in machine ``{file_name}`` (``sim/data/machines/{file_name}.toml``), "
                       "with these truth errors (default none) and geometry overrides.")
    return factory


vmc_3axis = _builtin("vmc-3axis")
mikron_ucp710 = _builtin("mikron-ucp710")
nmv3000 = _builtin("nmv3000")

#: Machine factories by name (``vmt simulate --machine``).
MACHINES: dict[str, Callable[..., MachineConfig]] = {
    "vmc-3axis": vmc_3axis,
    "mikron-ucp710": mikron_ucp710,
    "nmv3000": nmv3000,
}


def describe() -> str:
    """One line per machine: name, chain, strokes (mm, deg)."""
    lines = []
    for name, f in MACHINES.items():
        c = f()
        st = ", ".join(
            f"{a} {lo / DEG:.0f}..{hi / DEG:.0f} deg" if a in iso.ROTARY_AXES
            else f"{a} {lo * 1e3:.0f}..{hi * 1e3:.0f} mm"
            for a, (lo, hi) in sorted(c.strokes.items(), key=lambda kv: "XYZABC".index(kv[0])))
        lines.append(f"{name:14s} {c.chain:26s} {st}")
    return "\n".join(lines)


# --------------------------------------------------------------------------- realistic errors
_DEFAULT_STROKES = {"X": (-0.355, 0.355), "Y": (-0.275, 0.275), "Z": (-0.10, 0.40),
                    "A": (-120 * DEG, 120 * DEG), "C": (-math.pi, math.pi)}

# (symbol, shape, magnitude): "lin" ramps 0..mag over the stroke, "bow" is a
# smooth arc with peak mag (a straightness or an angular profile), "s" an S
# curve. Magnitudes from the papers: MFB paper section 6 (EXX up to 38 um,
# roughly linear; straightness 2-3 um; EBX up to 98 um/m, EAX < 10 um/m,
# ECX < 40 um/m), self-calibration paper (EC0Y -43.4 urad, (EX0C, EY0C) =
# (15, 6) um).
_LINEAR = {
    "X": [("EXX", "lin", 38e-6), ("EYX", "bow", 2.5e-6), ("EZX", "s", 3.0e-6),
          ("EAX", "bow", 8e-6), ("EBX", "lin", 98e-6), ("ECX", "s", 35e-6)],
    "Y": [("EXY", "bow", 2.0e-6), ("EYY", "lin", 20e-6), ("EZY", "s", 2.5e-6),
          ("EAY", "s", 25e-6), ("EBY", "bow", 9e-6), ("ECY", "lin", 15e-6)],
    "Z": [("EXZ", "s", 2.0e-6), ("EYZ", "bow", 3.0e-6), ("EZZ", "lin", 15e-6),
          ("EAZ", "bow", 20e-6), ("EBZ", "lin", 30e-6), ("ECZ", "bow", 6e-6)],
}
_SQUARENESS = {"EC0Y": -43.4e-6, "EB0Z": 20e-6, "EA0Z": -15e-6}
_ROTARY = {
    "C": {"loc": {"EX0C": 15e-6, "EY0C": 6e-6, "EA0C": 10e-6, "EB0C": -8e-6},
          "radial": ("EXC", "EYC", 1.5e-6), "axial": ("EZC", 0.8e-6),
          "tilt": ("EAC", "EBC", 3e-6), "pos": ("ECC", 12e-6)},
    "A": {"loc": {"EY0A": 10e-6, "EZ0A": -12e-6, "EB0A": 15e-6, "EC0A": -10e-6},
          "radial": ("EYA", "EZA", 2e-6), "axial": ("EXA", 1.0e-6),
          "tilt": ("EBA", "ECA", 5e-6), "pos": ("EAA", 20e-6)},
    "B": {"loc": {"EX0B": 10e-6, "EZ0B": -8e-6, "EA0B": 10e-6, "EC0B": -6e-6},
          "radial": ("EXB", "EZB", 2e-6), "axial": ("EYB", 1.0e-6),
          "tilt": ("EAB", "ECB", 5e-6), "pos": ("EBB", 20e-6)},
}


#: Period of the screw-pitch ripple on the linear axes' "lin" profiles, m; its amplitude is 1 % of the profile's.
RIPPLE_PERIOD_M = 0.010


def _profile(shape: str, mag: float, lo: float, hi: float, k: int = 9, ripple: bool = True) -> ErrorFunction:
    if shape == "lin":  # 0 at the low end, mag at the high end, plus a 1 % screw pitch ripple
        slope = mag / (hi - lo)
        if not ripple:
            return Polynomial((-slope * lo, slope))
        return Sum((Polynomial((-slope * lo, slope)), Periodic(0.01 * abs(mag), RIPPLE_PERIOD_M)))
    u = np.linspace(0.0, 1.0, k)
    y = mag * (4 * u * (1 - u) if shape == "bow" else np.sin(2 * np.pi * u))
    return SplineTable(tuple(lo + u * (hi - lo)), tuple(y))


def realistic_errors(axes: Sequence[str] = ("X", "Y", "Z", "C"), *,
                     strokes: Mapping[str, tuple[float, float]] | None = None, J_m=None,
                     rng: np.random.Generator | None = None,
                     ripple: bool = True, ripple_phase: float | None = None) -> dict[str, ErrorFunction]:
    """A realistic truth error set with the magnitudes the papers report.

    Parameters
    ----------
    axes : sequence of str
        Axes to give errors to (``"X"``, ..., ``"C"``); squarenesses come
        with the linear axes they belong to (``EC0Y`` with Y, ``EB0Z`` and
        ``EA0Z`` with Z).
    strokes : mapping axis -> (min, max), optional
        The machine's strokes (m / rad) as a machine file writes them: in
        the readings of its reference tool (docs/formats.md, "Strokes");
        default a Mikron-like workspace. Pass ``config.strokes`` with
        ``J_m=config.J_m``.
    J_m : (3,) float, optional
        The reference tool's offsets (J_X, J_Y, J_Z), m, that ``strokes``
        are written for: required with ``strokes``; default (with the
        default strokes) :data:`DEFAULT_J_M`, the Mikron's 150 mm probe.
        A linear axis's profile is laid over the axis positions its stroke
        allows, ``stroke + J`` (the errors are functions of the axis
        position q = reading + J, and every stylus's positions are checked
        as ``q - J_ref`` against the stroke), so the positions the machine
        reaches see the paper's magnitude and none runs on a table's
        end-tangent extension. Until session 28 the profiles were laid
        over the strokes as readings: with J_Z = 150 mm, 30 % of the Z
        travel lay beyond the Z tables (EAZ 20 -> 46.7 urad p-p over the
        positions reached).
    rng : np.random.Generator, optional
        None: the nominal set (reproducible, paper magnitudes, every phase
        0). Given: each magnitude is scaled by U(0.5, 1) with a random sign,
        each rotary axis's phase drawn, and (with ``ripple``) each linear
        axis's screw ripple at a phase drawn U(0, 2 pi), one per screw
        (EXX, EBX, ECX ... of X share X's phase). The ripple phases are
        drawn after every other value, so a seed's magnitudes, signs and
        rotary phases are the same with or without the ripple.
    ripple : bool
        Add the 10 mm screw-pitch ripple (1 % of the positioning error) to
        the positioning errors (default). ``False`` gives errors that the
        papers' smooth look-up-table models represent (a "no hidden
        effect" machine for model-discovery tests).
    ripple_phase : float, optional
        Every screw's ripple at this phase (rad) instead: ``0.0`` is the
        set every seed gave before session 27 (a phase that flatters the
        self-calibration's workpiece and C-axis U95, docs/discovery-studies.md,
        "Session 27: the screw ripple's phase"). Nothing is drawn for it.

    Returns
    -------
    dict symbol -> ErrorFunction (SI units)
    """
    if strokes is not None and J_m is None:
        raise ConfigError("realistic_errors: strokes given without J_m, the reference tool's offsets they are "
                          "written for (pass config.J_m; (0, 0, 0) for strokes already in axis positions)")
    J = np.asarray(DEFAULT_J_M if J_m is None else J_m, float)
    if J.shape != (3,) or not np.all(np.isfinite(J)):
        raise ConfigError(f"realistic_errors: J_m must be 3 finite values (m), got {J_m!r}")
    st = dict(_DEFAULT_STROKES)
    st.update(strokes or {})
    out: dict[str, ErrorFunction] = {}

    def mag(m):
        return m if rng is None else m * rng.uniform(0.5, 1.0) * rng.choice((-1.0, 1.0))

    for a in axes:
        if a not in st:
            raise ConfigError(f"realistic_errors: unknown axis {a!r}")
        lo, hi = st[a]
        if a in _LINEAR:  # laid over the axis positions: the stroke + the reference tool's J
            lo, hi = lo + float(J["XYZ".index(a)]), hi + float(J["XYZ".index(a)])
            for sym, shape, m in _LINEAR[a]:
                out[sym] = _profile(shape, mag(m), lo, hi, ripple=ripple)
            for sq, v in _SQUARENESS.items():
                if iso.symbol(sq).axis == a:
                    out[sq] = Constant(mag(v))
        elif a in _ROTARY:
            d = _ROTARY[a]
            for sym, v in d["loc"].items():
                out[sym] = Constant(mag(v))
            ph = 0.0 if rng is None else rng.uniform(0, 2 * np.pi)
            r1, r2, m = d["radial"]  # once-per-rev radial motion in quadrature + a 2nd harmonic
            out[r1] = Periodic(mag(m), 2 * np.pi, ph) + Periodic(0.3 * m, np.pi, ph)
            out[r2] = Periodic(mag(m), 2 * np.pi, ph + np.pi / 2)
            ax, m = d["axial"]
            out[ax] = Periodic(mag(m), np.pi, ph)
            t1, t2, m = d["tilt"]
            out[t1] = Periodic(mag(m), 2 * np.pi, ph + 0.3)
            out[t2] = Periodic(mag(m), 2 * np.pi, ph + 0.3 + np.pi / 2)
            ps, m = d["pos"]  # angular positioning: eccentric worm gear, once and 4x per rev
            out[ps] = Periodic(mag(m), 2 * np.pi, ph) + Periodic(0.25 * m, np.pi / 2, ph)
        else:
            raise ConfigError(f"realistic_errors: unknown axis {a!r}")
    if ripple and (rng is not None or ripple_phase is not None):
        # a real screw's ripple sits at an arbitrary phase: phase 0 (sine zero at the axis origin) in every
        # seed is one fixed phase, near the worst for a feature centred on a whole period (session 26)
        for a in axes:
            if a in _LINEAR:
                ph = float(rng.uniform(0.0, 2.0 * np.pi)) if ripple_phase is None else float(ripple_phase)
                for sym, shape, _ in _LINEAR[a]:
                    if shape == "lin":
                        poly, rip = out[sym].terms
                        out[sym] = Sum((poly, Periodic(rip.amplitude, rip.period, ph)))
    return out
