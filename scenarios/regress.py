"""Regression studies: inject known errors, identify them, check they are recovered.

A *study file* (TOML, format ``vmt-study/1``) states a virtual machine and
its injected errors, the campaign and its probing noise, the seeds, the
identification to run and, per identified quantity, the acceptance rule.
:func:`load_study` reads it, :func:`run_study` runs it (one simulated
campaign and one identification per seed) and compares every identified
quantity with the injected truth *expressed in the identification's own
gauge and ISO 230-1 sign convention* (every error value is the tool's
displacement relative to the workpiece). ``vmt regress`` is the command
line of this module; :mod:`scenarios.testing` its pytest face.

Study file
----------
::

    format = "vmt-study/1"
    name = "cross-pocket self-calibration, nmv3000"
    identification = "selfcal"    # selfcal | mfb-3axis | mfb-5axis | iso230-2 | discover
    machine = "nmv3000"           # a built-in machine, or a machine file (path relative to the study)
    seeds = [1, 2]                # one campaign per seed (its probing noise)
    noise_um = 0.3                # probing noise, k = 1 (default: the machine's probe;
                                  # iso230-2: the scatter of a reading, default 0.5)

    [injected]                    # optional: the machine's errors, machine-file keys
    errors = "realistic"          # "none" | "realistic" (the papers' magnitudes) ...
    seed = 3                      # ... drawn from this seed
    ripple = false
    [injected.probe]              # the machine file's [probe] keys (lobing, pretravel_um, ...)
    lobing = [{ k = 3, cos_um = 0.4, sin_um = 0.0 }]
    [injected.error.EC0Y]         # any [error.SYMBOL] of a machine file
    constant_urad = -20.0

    [plan]                        # the identification's plan (keys below)
    c_angles_deg = [0, 75, 130, 210]

    [accept.EXX]                  # one table per quantity checked
    within_u95 = "simultaneous"   # every value of the simultaneous quantities within k_sim x U95 at once
    [accept.EYY]
    within_u95 = 1.0              # |identified - injected| <= 1.0 x U95 at every node
    max_u95_um = 3.8              # optional: the largest U95 allowed (max_u95_urad for urad)
    [accept.EC0Y]
    tolerance_urad = 2.0          # or an absolute tolerance with its unit (um | urad)

    [mutate]                      # optional: the check's self-test (see below)
    flip_sign = ["EC0Y"]

Identifications, their quantities and ``[plan]`` keys:

``selfcal``
    the cross-pocket campaign (the self-calibration paper's artefact) at
    ``c_angles_deg`` (default 0, 75, 130, 210), identified by
    :func:`core.selfcal.self_calibrate` on the grid ``grid_mm = [lo, hi,
    step]`` (default -110, 110, 22) exactly as ``vmt identify`` does.
    Quantities: ``EXX EYX EXY EYY`` (um, per grid node), ``ECY`` or
    ``ECX`` (the chain's yaw, urad), ``EC0Y`` (urad), ``workpiece`` (the
    part's deviation per target, um), ``EXC EYC`` (um) and ``ECC`` (urad)
    per set-up, ``EBC EAC`` (urad, per set-up, when touches lie at two
    heights). U95 = 2 x the identification's standard uncertainty (probing
    noise and the model-error budget). Truth: the exact simulator's
    (:func:`scenarios.selfcal_coverage.block_truth`), moved into the
    identification's gauge (:meth:`core.selfcal.SelfCalDesign.to_gauge`).
    ``declared_ripple = { EXX = [0.38, 10], ... }``: a sub-grid ripple per
    table (amplitude um, urad for the yaw; period mm) the U95 holds, as
    ``vmt identify --declared-ripple-um-mm`` (:func:`core.selfcal.self_calibrate`
    ``subgrid``); a table the chain's yaw is not is left out.
``mfb-3axis``, ``mfb-5axis``
    the multi-feature bar plan (:mod:`scenarios.mfb`), 21 errors: ``EXX``
    ... ``EA0Z`` (um or urad, per node; straightness against its end-point
    line). ``[plan] mc_runs`` (default 0: linear propagation for U95). The
    machine's chain must be the plan's machine's. Truth: the injected
    functions at the nodes in the same conventions (:func:`scenarios.mfb.run`).
``iso230-2``
    a positioning test of one axis (:mod:`sim.positioning`) evaluated by
    :func:`core.positioning.iso230_2`. ``[plan] axis`` (X), ``targets``
    (11), ``cycles`` (5), ``cycle`` (linear | pilgrim). Quantities:
    ``mean`` (the bidirectional mean deviation per target, um, U95 =
    2 sqrt(s_up^2/n_up + s_down^2/n_down) / 2), ``reversal`` (B_i per
    target, um, U95 = 2 sqrt(s_up^2/n_up + s_down^2/n_down)), and the axis
    figures ``E``, ``M``, ``B`` (um, absolute tolerance only). Truth: the
    exact chain's deviation at the measuring line at each reading's time
    and direction, without scatter, averaged per target and direction, and
    the figures computed from it here (ISO 230-2 definitions).

``discover``
    the cross-pocket campaign as for ``selfcal``, written as a probe log
    and read by ``vmt discover``'s own code path
    (:func:`scenarios.discover_run.run_discover`). One quantity, ``cause``:
    the causes its JSON report names (``findings[*].cause``, e.g.
    ``periodic_axis_error``, ``probe_lobing``), checked by ``[accept.cause]
    expected = ["periodic_axis_error"]``: the whole set, every expected
    cause named and no other (a finding beyond them fails, named in the
    note: a discover that named every cause would pass otherwise, review29c;
    ``others = "allowed"`` lets it name more), ``expected = []`` or
    ``"none"``: no cause may be named (a machine without a hidden effect).
    Only the cause names are relied on: the discovery engine is being
    rewritten, its fitted magnitudes are not checked.

Acceptance rules (``[accept.QUANTITY]``, exactly one key; discover:
``expected``, optionally ``others``): ``within_u95 = "simultaneous"`` (every element of every
quantity so marked, together: ``|identified - injected| <= k_sim U95 +
1e-6``, ``k_sim`` the 95 % point of the largest ``|identified - injected| /
U95`` of them under the run's own joint covariance, :func:`simultaneous_k`:
a correct identification passes with probability 95 % however many values
are checked; per seed, printed with the number of values), ``within_u95 = k``
(every element: ``|identified - injected| <= k U95 + 1e-6``; needs probing
noise; the 1e-6 um / urad lets an element fixed by the ISO convention, U95
0, match to rounding: :data:`GAUGE_FLOOR`), ``tolerance_um = t`` or ``tolerance_urad = t`` (every element:
``|identified - injected| <= t``, the unit the quantity's). A quantity
passes for a seed when every element passes; the study passes when every
(quantity, seed) passes. The *margin* is ``limit - |identified -
injected|`` at the element where ``|identified - injected| / limit`` is
largest (negative: failed by that much).

``max_u95_um`` / ``max_u95_urad`` (optional, beside the rule, the quantity's unit): the check also fails when
the largest U95 of the quantity's values exceeds it (review33a F1). The band ``k x U95`` is the run's own, so a
regression that widens the U95 with the error (a noise read in the wrong unit, a constraint lost) would
otherwise pass; the shipped studies pin each U95 by a rule stated in the file.

The band itself is checked (:func:`band_consistency`, review33a F2): each simultaneous value's U95 must be
``2 sqrt`` of its variance under the covariance ``k_sim`` is drawn from, and (known scales) ``k_sim`` must lie
between one value's 0.98 and Sidak's bound; otherwise every simultaneous check of the seed fails, naming why.

Power (:func:`power`, :attr:`StudyResult.power`): per checked quantity and seed, the detection limit of each
value (the smallest change of it alone that fails the check with probability :data:`DETECTION_POWER`) and
whether the quantity's sign is testable (a flip moves some value by its limit or more); ``vmt regress`` prints
the quantities whose sign it cannot test, the JSON (``power``) every limit (review31b F4). Per quantity also the
smallest gain error (the quantity reported ``1 + g`` times) caught with that power, ``2 / flip_ratio``
(:attr:`Power.smallest_gain`, its derivation and assumptions there; JSON ``smallest_gain_error``), printed one
line per seed with how many quantities a 10 % and a 20 % gain error can pass (review33a F10).

Mutations (``[mutate]``, and the ``hook`` argument of :func:`run_study`):
the documented place where a change enters the identification, between
the estimator and the comparison. ``flip_sign = [Q, ...]`` reports Q with
the opposite sign: for these linear least-squares identifications that is
exactly what a sign error in Q's columns of the model gives when Q's gauge
conditions are homogeneous (the solution of the flipped model is Q
negated, everything else unchanged). ``scale = {Q = c, ...}`` reports Q
times c: a gain error in Q's columns (a wrong unit or lever arm; the
solution of the model with Q's columns divided by c). ``drop = [Q, ...]`` reports Q as
identically zero, what a model without the term assumes; unlike a real
model without it, the other quantities do not absorb its effect here.
``planar = true`` (selfcal) is a change inside the estimator itself: the
self-calibration runs without its height terms (the C axis's tilt per
set-up, the tool's Abbe terms), so their effect on the raised targets
leaks into the other quantities as it would in a real regression. A
study with a mutation is expected to FAIL on the mutated quantities: that
is how a user proves the acceptance rules would catch such a change.

Bad input (a malformed study, an unknown key, quantity or machine) raises
:class:`StudyError` (one line naming the file and the key).
"""

from __future__ import annotations

import hashlib
import math
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.exceptions import ConfigError
from core.keyreader import KeyReader, read_text_file
from core.memo import Memo

FORMAT = "vmt-study/1"
#: The identifications a study can run.
IDENTIFICATIONS = ("selfcal", "mfb-3axis", "mfb-5axis", "iso230-2", "discover")
#: Quantities of each identification and their unit (um | urad).
_SELFCAL_Q = {"EXX": "um", "EYX": "um", "EXY": "um", "EYY": "um", "ECY": "urad", "ECX": "urad",
              "EC0Y": "urad", "workpiece": "um", "EXC": "um", "EYC": "um", "ECC": "urad",
              "EBC": "urad", "EAC": "urad"}
_MFB_Q = {s: ("urad" if s[1] in "ABC" else "um") for s in
          ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX", "EYY", "EXY", "EZY", "EAY", "EBY", "ECY",
           "EZZ", "EXZ", "EYZ", "EAZ", "EBZ", "ECZ", "EC0Y", "EB0Z", "EA0Z")}
_POS_Q = {"mean": "um", "reversal": "um", "E": "um", "M": "um", "B": "um"}
QUANTITIES = {"selfcal": _SELFCAL_Q, "mfb-3axis": _MFB_Q, "mfb-5axis": _MFB_Q, "iso230-2": _POS_Q,
              "discover": {"cause": "cause"}}
#: Added to ``k U95``, in the quantity's unit (1 pm, 1 prad): an element fixed by the identification's ISO
#: convention (its U95 is 0, e.g. EXX at the first node) must match the injected value in the same gauge to
#: the rounding of the gauge transform (~1e-14), so a gauge or sign mismatch there fails.
GAUGE_FLOOR = 1e-6
#: ``within_u95 = "simultaneous"``: the probability, under the identification's joint normal model, that
#: every value of every simultaneous quantity of a run lies within ``k_sim x U95`` (:func:`simultaneous_k`).
JOINT_COVERAGE = 0.95
#: Monte Carlo draws of :func:`simultaneous_k` and their fixed seed (the same k_sim for the same covariance).
SIM_DRAWS = 100_000
SIM_SEED = 20261202
#: A study's power (:func:`power`): the probability with which a change of one value by its *detection limit*
#: fails the study on a run (review31b F4: flipped, the sign of several shipped studies' terms stayed inside the
#: band). A value's error is normal with standard deviation U95 / 2, so a change ``d`` at a value checked
#: against ``k x U95`` is caught with probability >= DETECTION_POWER once ``d >= (k + POWER_Z / 2) x U95``
#: (the far side's tail only adds to it): ``(1.718 + 0.822) x U95 = 2.54 x U95`` on the 3-axis MFB study.
DETECTION_POWER = 0.95
#: The one-sided normal quantile of :data:`DETECTION_POWER` (Phi^-1(0.95)).
POWER_Z = 1.6448536269514722
#: The gain errors (a quantity reported ``1 + g`` times) whose count of quantities that can pass them
#: :meth:`StudyResult.gain_power` prints (review33a F10: a study that tests every sign may still pass a 20 %
#: gain error on most quantities).
GAIN_SUMMARY = (0.10, 0.20)
#: ``[accept.cause] expected = "none"``: the same as ``expected = []``, discover may name no cause (a study of
#: a machine without a hidden effect: a finding there is a false alarm, review29c).
NO_CAUSE = "none"
#: Quantities that have no U95 (absolute tolerance only).
_NO_U95 = {"iso230-2": ("E", "M", "B")}
_PLAN_KEYS = {"selfcal": ("c_angles_deg", "grid_mm", "declared_ripple"), "mfb-3axis": ("mc_runs",), "mfb-5axis": ("mc_runs",),
              "iso230-2": ("axis", "targets", "cycles", "cycle"), "discover": ("c_angles_deg",)}
_TOP = ("format", "name", "description", "identification", "machine", "seeds", "noise_um", "injected", "plan",
        "accept", "mutate")
_INJECTED = ("errors", "seed", "ripple", "error", "probe")


class StudyError(ConfigError):
    """A study file that cannot be run: the file, the key, what is wrong."""


def _factor(cov) -> np.ndarray:
    """A square-root factor ``F`` of a symmetric covariance, ``cov = F F^T`` (its non-negative eigen-decomposition)."""
    C = np.asarray(cov, float)
    w, V = np.linalg.eigh(0.5 * (C + C.T))
    return V * np.sqrt(np.clip(w, 0.0, None))


def simultaneous_k(estimates, coverage: float = JOINT_COVERAGE, draws: int = SIM_DRAWS,
                   seed: int | None = SIM_SEED) -> tuple[float, int]:
    """``(k_sim, n)``: the ``coverage`` quantile of ``max_i |e_i| / U95_i`` over the ``n`` values with a U95
    (> 0) of ``estimates``, ``e`` drawn from their joint normal distribution ``N(0, F F^T)``
    (:attr:`Estimate.factor`, rows stacked): the band ``k_sim x U95`` holds every value of a run at once
    with probability ``coverage`` when the model is right.

    Monte Carlo with ``draws`` draws from a fixed seed (the same covariance gives the same k_sim; its
    sampling error at 1e5 draws is about 0.01 in k). Between two bounds: one value's k (1, U95 = 2 u) when
    the values move together, Sidak's ``Phi^-1((1 + coverage^(1/n)) / 2) / 2`` when they are independent.
    With :attr:`Estimate.dof` (the U95 itself estimated from the run's scatter) each draw also draws the
    sources' estimated variances (``chi2(dof) / dof`` times the given) and divides by the U95 they give
    (the studentized maximum, the factor's scales taken as the true ones): wider than the normal band,
    as a t quantile is wider than a normal one.

    ``seed``: an int (the band is kept by its inputs and served again) or None (fresh entropy: drawn on
    every call, never kept).
    """
    dofs = {tuple(np.asarray(e.dof, float)) for e in estimates if getattr(e, "dof", None) is not None}
    if len(dofs) > 1 or (dofs and any(getattr(e, "dof", None) is None for e in estimates)):
        raise ValueError("simultaneous_k: estimates with different degrees of freedom of their sources")
    dof = np.asarray(dofs.pop(), float) if dofs else None
    rows, U = [], []
    for e in estimates:
        if e.factor is None or e.u95 is None:
            raise ValueError("simultaneous_k: an estimate without its covariance factor or U95")
        u = np.asarray(e.u95, float)
        k = u > 1e-9  # values a convention fixes (U95 0) are checked to GAUGE_FLOOR, not drawn
        rows.append(np.asarray(e.factor, float)[k])
        U.append(u[k])
    F, U = np.vstack(rows), np.concatenate(U)
    n = len(U)
    if n == 0:
        raise ValueError("simultaneous_k: no value with a U95")
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
        # None (fresh entropy: draws not to be repeated) or anything numpy takes that an int key would not
        # name (a Generator, a SeedSequence: drawn from their state; 1.5 is numpy's to refuse): nothing kept
        return _simultaneous_k(F, U, dof, coverage, draws, seed)
    key = (hashlib.sha256(b"".join(np.ascontiguousarray(a, float).tobytes() + repr(a.shape).encode()
                                   for a in (F, U) + (() if dof is None else (dof,)))).hexdigest(),
           dof is None, float(coverage), int(draws), int(seed))
    return _SIMULTANEOUS_K.get_or_compute(key, lambda: _simultaneous_k(F, U, dof, coverage, draws, seed))


#: :func:`band_consistency`: the largest relative difference allowed between a value's U95 and ``2 sqrt`` of its
#: variance under the joint covariance the band is drawn from (both come from one computation, so only rounding
#: separates them: 3e-9 at most on the shipped studies, seeds 1-4; the MFB's U95 pass through its report).
U95_REL_TOL = 1e-6
#: :func:`band_consistency`: the slack on ``k_sim``'s bounds, twice its Monte Carlo error (about 0.01 at
#: :data:`SIM_DRAWS` draws).
K_SIM_SLACK = 0.02


def sidak_k(n: int, coverage: float = JOINT_COVERAGE) -> float:
    """Sidak's band for ``n`` independent normal values in U95 units, ``Phi^-1((1 + coverage^(1/n)) / 2) / 2``:
    the largest ``k_sim`` any joint normal covariance gives (Sidak's inequality); 0.980 for one value."""
    from statistics import NormalDist

    return NormalDist().inv_cdf((1.0 + coverage ** (1.0 / n)) / 2.0) / 2.0


def band_consistency(estimates: dict, k_sim: float, n: int) -> str:
    """Why the simultaneous band of one run cannot be trusted, or ``""`` (review33a F2).

    ``estimates``: the simultaneous quantities (``{name: Estimate}``). The band ``k_sim x U95`` holds
    what it says only when each U95 is ``2 sqrt`` of the value's variance under the covariance ``F F^T``
    it was drawn from: a U95 computed apart (a noise model changed in one place and not the other) is
    named with its ratio (beyond :data:`U95_REL_TOL`). With known scales (no ``dof``) ``k_sim`` must also
    lie between one value's ``Phi^-1(0.975) / 2`` (values that move together) and :func:`sidak_k` (they are
    independent), each widened by :data:`K_SIM_SLACK`; with scales estimated from the run (ISO 230-2) the
    studentized band is wider than Sidak's and only the U95 is checked.
    """
    bad = []
    for q, e in estimates.items():
        u = np.asarray(e.u95, float)
        d = 2.0 * np.sqrt(np.sum(np.asarray(e.factor, float) ** 2, axis=1))
        m = u > 1e-9
        if not m.any():
            continue
        rel = u[m] / np.where(d[m] > 0, d[m], np.nan)
        worst = int(np.nanargmax(np.abs(rel - 1.0))) if np.all(np.isfinite(rel)) else int(np.argmin(np.isfinite(rel)))
        if not np.all(np.isfinite(rel)) or abs(rel[worst] - 1.0) > U95_REL_TOL:
            bad.append(f"{q} ({rel[worst]:.4g} x at {np.asarray(e.labels)[m][worst]})")
    why = []
    if bad:
        shown = bad if len(bad) <= 3 else bad[:3] + [f"{len(bad) - 3} more quantities"]  # one line per check
        why.append("U95 is not 2 sqrt(diag) of the joint covariance the band is drawn from: " + ", ".join(shown))
    if all(getattr(e, "dof", None) is None for e in estimates.values()):
        lo, hi = sidak_k(1) - K_SIM_SLACK, sidak_k(n) + K_SIM_SLACK
        if not lo <= k_sim <= hi:
            why.append(f"k_sim {k_sim:.3f} lies outside [{sidak_k(1):.3f}, {sidak_k(n):.3f}] (one value's k, Sidak's "
                       f"for {n} values), which no joint normal covariance gives")
    return "; ".join(why)


#: :func:`simultaneous_k` by its inputs (the factor rows and U95 drawn, the sources' dof, the coverage, draws and
#: seed: everything the draws read, hashed): a study's mutated runs and a file's repeated checks ask for the same
#: band again (1e5 draws, 0.06-0.3 s each). Safe: a pure function of the key; the value is an immutable tuple.
_SIMULTANEOUS_K = Memo(64)


def _simultaneous_k(F: np.ndarray, U: np.ndarray, dof, coverage: float, draws: int, seed) -> tuple[float, int]:
    """:func:`simultaneous_k`'s draws from the stacked factor rows ``F`` (n, m), U95 ``U`` (n,) and ``dof`` (m,) or None."""
    n = len(U)
    if dof is None:
        F = _factor(F @ F.T)  # the same distribution on n columns (fewer than the sources: faster draws)
    elif dof.shape != (F.shape[1],) or not np.all(dof > 0):
        raise ValueError("simultaneous_k: dof must be positive, one per column of the factor")
    rng = np.random.default_rng(seed)
    mx = np.empty(int(draws))
    step = max(1, 2_000_000 // max(F.shape[1], 1))
    for a in range(0, len(mx), step):
        b = min(a + step, len(mx))
        x = rng.standard_normal((b - a, F.shape[1])) @ F.T
        if dof is None:
            mx[a:b] = (np.abs(x) / U).max(axis=1)
        else:  # the U95 this draw's scatter would give
            w = rng.chisquare(dof, (b - a, len(dof))) / dof
            mx[a:b] = (np.abs(x) / (2.0 * np.sqrt(w @ (F * F).T))).max(axis=1)
    return float(np.quantile(mx, coverage)), n


@dataclass(frozen=True)
class Rule:
    """The acceptance rule of one quantity.

    Attributes
    ----------
    quantity : str
    k : float or None
        ``within_u95``: pass when ``|identified - injected| <= k U95``.
    tolerance : float or None
        Absolute tolerance, in ``unit``.
    unit : str
        ``um`` or ``urad``: the quantity's unit (``cause`` for discover).
    expected : tuple of str
        Discover: the causes the findings must name (empty: none may be named).
    others_allowed : bool
        Discover: findings beyond ``expected`` pass (``others = "allowed"``); by default each fails the
        check, named in its note (a discover that names every cause would otherwise pass, review29c).
    max_u95 : float or None
        ``max_u95_um`` / ``max_u95_urad``: the check also fails when the largest U95 of the quantity's values
        exceeds it (review33a F1: the band ``k x U95`` comes from the run under test, so a regression that
        widens the U95 with the error, a noise read in the wrong unit, a lost constraint, would pass).
    simultaneous : bool
        ``within_u95 = "simultaneous"``: pass when ``|identified - injected| <= k_sim U95``, ``k_sim``
        from the seed's joint covariance of every simultaneous quantity (:func:`simultaneous_k`).
    """

    quantity: str
    k: float | None
    tolerance: float | None
    unit: str
    expected: tuple[str, ...] = ()
    simultaneous: bool = False
    others_allowed: bool = False
    max_u95: float | None = None

    def text(self, k_sim: float | None = None, values: int = 0) -> str:
        if self.unit == "cause":
            if not self.expected:
                return "names no cause"
            return ("names " + ", ".join(self.expected) + (" (others allowed)" if self.others_allowed else
                                                           " and no other cause"))
        if self.simultaneous:
            t = ("<= k_sim x U95 (simultaneous)" if k_sim is None else
                 f"<= {k_sim:.3f} x U95 (simultaneous, {JOINT_COVERAGE:.0%} over {values} values)")
        else:
            t = f"<= {self.k:g} x U95" if self.k is not None else f"<= {self.tolerance:g} {self.unit}"
        return t  # (a max_u95 is named in the check's note when it fails: the limit here is the deviation's)


@dataclass(frozen=True)
class Mutation:
    """A change injected into the identification (module docstring): quantities sign-flipped or dropped;
    ``planar``: the self-calibration run without its height terms (a different estimator)."""

    flip_sign: tuple[str, ...] = ()
    drop: tuple[str, ...] = ()
    planar: bool = False
    scale: tuple = ()  # ((quantity, factor), ...)

    def __call__(self, identification: str, estimates: dict) -> dict:
        out = dict(estimates)
        for q in self.flip_sign:
            if q in out:
                out[q] = out[q].replaced(identified=-out[q].identified)
        for q, c in self.scale:
            if q in out and not isinstance(out[q], Causes):
                out[q] = out[q].replaced(identified=c * out[q].identified)
        for q in self.drop:
            if isinstance(out.get(q), Causes):
                out[q] = Causes(())
            elif q in out:
                out[q] = out[q].replaced(identified=np.zeros_like(out[q].identified))
        return out


@dataclass(frozen=True)
class Study:
    """A study read from a file (module docstring).

    ``plan`` holds the ``[plan]`` values as (key, value) pairs; ``machine``
    is the truth machine (:class:`sim.machinefile.MachineSpec`) with the
    injected errors.
    """

    source: str
    name: str
    identification: str
    machine: object
    seeds: tuple[int, ...]
    noise_um: float | None
    plan: tuple
    rules: tuple[Rule, ...]
    mutation: Mutation | None = None
    description: str = ""

    def plan_value(self, key, default):
        return dict(self.plan).get(key, default)


@dataclass(frozen=True)
class Estimate:
    """One identified quantity beside its injected truth, in its unit (um or urad).

    Attributes
    ----------
    identified, injected : (n,) float
    u95 : (n,) float or None
        Expanded uncertainty (k = 2) of each element; None when the
        identification gives none.
    labels : tuple of str
        What each element is (a node, a set-up, a target).
    unit : str
    factor : (n, m) float or None
        This quantity's rows of a square-root factor of the identification's joint covariance, in
        ``unit``: the errors ``identified - injected`` of all quantities of one run are, to the
        identification's linear model, normal with covariance ``F F^T`` (``F`` their rows stacked, one
        column per independent source). None when the identification gives no joint covariance.
    dof : (m,) float or None
        Per column of ``factor``: the degrees of freedom with which that source's scale was estimated
        from the run itself (ISO 230-2: a direction's scatter at a target from its ``n`` readings, ``n -
        1``); the U95 then varies from run to run with it and :func:`simultaneous_k` draws it too. None:
        the scales are known (declared probing noise, calibration, placements).
    """

    identified: np.ndarray
    injected: np.ndarray
    u95: np.ndarray | None
    labels: tuple[str, ...]
    unit: str
    factor: np.ndarray | None = None
    dof: np.ndarray | None = None

    def replaced(self, **kw) -> "Estimate":
        from dataclasses import replace

        return replace(self, **kw)


@dataclass(frozen=True)
class Causes:
    """What ``vmt discover`` named (its JSON's ``findings[*].cause``), in order."""

    named: tuple[str, ...]


@dataclass(frozen=True)
class Check:
    """The verdict on one quantity for one seed (figures at the element with the largest ratio to its limit)."""

    seed: int
    quantity: str
    unit: str
    rule: str
    passed: bool
    where: str = ""
    injected: float = math.nan
    identified: float = math.nan
    u95: float = math.nan
    limit: float = math.nan
    n: int = 0
    note: str = ""

    @property
    def deviation(self) -> float:
        return abs(self.identified - self.injected)

    @property
    def margin(self) -> float:
        """``limit - |identified - injected|`` (negative: failed by that much), in ``unit``."""
        return self.limit - self.deviation

    def message(self) -> str:
        """One line: the quantity, where, the deviation, the limit and the margin."""
        if self.note:
            return f"{self.quantity} (seed {self.seed}): {self.note}"
        verdict = "within" if self.passed else "exceeds"
        return (f"{self.quantity} (seed {self.seed}) at {self.where}: |identified - injected| = "
                f"|{self.identified:.4g} - {self.injected:.4g}| = {self.deviation:.4g} {self.unit} {verdict} "
                f"{self.rule} = {self.limit:.4g} {self.unit}; margin {self.margin:+.4g} {self.unit}")

    def to_json(self) -> dict:
        def num(v):
            return None if not math.isfinite(v) else float(v)

        return {"seed": self.seed, "quantity": self.quantity, "unit": self.unit, "rule": self.rule,
                "passed": self.passed, "where": self.where, "elements": self.n, "injected": num(self.injected),
                "identified": num(self.identified), "u95": num(self.u95), "limit": num(self.limit),
                "deviation": num(self.deviation), "margin": num(self.margin), "message": self.message()}


@dataclass(frozen=True)
class StudyResult:
    """Every check of a study, the seconds each seed took and, per seed, the simultaneous band
    ``(seed, k_sim, values)`` (:func:`simultaneous_k`; empty without a simultaneous rule)."""

    study: Study
    checks: tuple[Check, ...]
    seconds: tuple[float, ...]
    estimates: dict = field(default=None, compare=False, repr=False)
    simultaneous: tuple = ()
    power: tuple = field(default=(), compare=False, repr=False)

    def sign_untestable(self) -> list[str]:
        """One line per seed naming the checked quantities whose sign the study cannot test (:func:`power`),
        or saying that it tests every sign; empty without a power (a discover study)."""
        out = []
        for sd in dict.fromkeys(p.seed for p in self.power):
            ps = [p for p in self.power if p.seed == sd]
            bad = [p for p in ps if not p.sign_testable]
            if bad:
                out.append(f"seed {sd}: sign not testable on {len(bad)} of {len(ps)} quantities (flipped, no value "
                           f"moves by its detection limit, {DETECTION_POWER:.0%} power): "
                           + ", ".join(f"{p.quantity} ({p.flip_ratio:.2f} of it)" for p in bad))
            else:
                out.append(f"seed {sd}: sign testable on all {len(ps)} quantities (flipped, each moves a value by "
                           f"its detection limit or more, {DETECTION_POWER:.0%} power)")
        return out

    def gain_power(self) -> list[str]:
        """One line per seed: each checked quantity's smallest gain error caught with :data:`DETECTION_POWER`
        (:attr:`Power.smallest_gain`, most sensitive first) and, for each gain of :data:`GAIN_SUMMARY`, on
        how many quantities it can pass (is not caught with that power); empty without a power."""
        out = []
        for sd in dict.fromkeys(p.seed for p in self.power):
            ps = sorted((p for p in self.power if p.seed == sd), key=lambda p: p.smallest_gain)
            each = ", ".join(f"{p.quantity} {_percent(p.smallest_gain)}" for p in ps)
            summ = "; ".join(f"a gain error of {g:.0%} can pass on {sum(p.smallest_gain > g for p in ps)} of "
                             f"{len(ps)}" for g in GAIN_SUMMARY)
            out.append(f"seed {sd}: smallest gain error caught with {DETECTION_POWER:.0%} power (one value at its "
                       f"detection limit): {each}; {summ}")
        return out

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks)

    @property
    def failures(self) -> tuple[Check, ...]:
        return tuple(c for c in self.checks if not c.passed)

    def to_json(self) -> dict:
        s = self.study
        return {"format": "vmt-regress/1", "study": s.source, "name": s.name, "identification": s.identification,
                "machine": s.machine.config.name, "seeds": list(s.seeds), "noise_um": s.noise_um,
                "convention": "ISO 230-1: every error is the tool's displacement relative to the workpiece; "
                              "injected values in the identification's gauge",
                "mutation": None if s.mutation is None else {"flip_sign": list(s.mutation.flip_sign),
                                                             "drop": list(s.mutation.drop),
                                                             "scale": dict(s.mutation.scale),
                                                             "planar": s.mutation.planar},
                "passed": self.passed, "n_checks": len(self.checks), "n_failed": len(self.failures),
                "seconds": [round(t, 3) for t in self.seconds],
                "simultaneous": [{"seed": sd, "k_sim": k, "values": n, "coverage": JOINT_COVERAGE,
                                  "k_one_value": sidak_k(1), "k_sidak": sidak_k(n),
                                  "method": f"Monte Carlo, {SIM_DRAWS} joint normal draws, seed {SIM_SEED}"}
                                 for sd, k, n in self.simultaneous],
                "checks": [c.to_json() for c in self.checks],
                "power": [p.to_json() for p in self.power]}

    def table(self) -> str:
        """The printed table: quantity, seed, where, injected, identified, U95, limit, verdict."""
        head = ("quantity", "seed", "where", "injected", "identified", "U95", "limit", "verdict")
        rows = []
        for c in self.checks:
            def f(v):
                return "-" if not math.isfinite(v) else f"{v:.4g}"

            rows.append((c.quantity if c.unit == "cause" else f"{c.quantity} [{c.unit}]", str(c.seed), c.where or "-", f(c.injected), f(c.identified),
                         f(c.u95), f(c.limit), ("pass" if c.passed else "FAIL") + (f" ({c.note})" if c.note else "")))
        w = [max(len(r[i]) for r in rows + [head]) for i in range(len(head))]
        lines = ["  ".join(h.ljust(w[i]) for i, h in enumerate(head))]
        lines += ["  ".join(v.ljust(w[i]) for i, v in enumerate(r)) for r in rows]
        for sd, k, n in self.simultaneous:
            lines.append(f"seed {sd}: simultaneous band k_sim = {k:.3f} x U95 over {n} values (every value within it "
                         f"with probability {JOINT_COVERAGE:.0%} under the run's joint covariance; 1 x U95 is one "
                         f"value's 95 %)")
        return "\n".join(lines)


def _percent(g: float) -> str:
    """A gain fraction as a percentage for the printed power line (whole percents; two significant figures
    below 10 %; beyond 1000 % so said)."""
    if not math.isfinite(g):
        return "none (injected 0)"
    if g > 10:
        return "> 1000 %"
    return f"{100 * g:.0f} %" if g >= 0.1 else f"{100 * g:.2g} %"


# --------------------------------------------------------------------------- reading
class _Reader(KeyReader):
    error_class = StudyError

    def names(self, key, v, known) -> tuple[str, ...]:
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            self.fail(key, f"expected a list of quantity names, got {v!r}")
        for x in v:
            if x not in known:
                self.fail(key, f"unknown quantity {x!r} (known: {', '.join(known)})")
        return tuple(v)


def _machine(r: _Reader, doc: dict, base_dir: Path):
    """The truth machine: the study's machine with its ``[injected]`` keys over it."""
    from sim import machinefile as mf

    m = doc.get("machine")
    if not isinstance(m, str) or not m:
        r.fail("machine", "missing: a built-in machine name or a machine file")
    inj = r.table("injected", doc.get("injected", {}))
    for k in inj:
        if k not in _INJECTED:
            r.fail(f"injected.{k}", f"unknown key (expected one of {', '.join(_INJECTED)})")
    if m in mf.builtin_names():
        mdoc, src = {"base": m}, m
    else:
        p = Path(m)
        p = p if p.is_absolute() else base_dir / p
        if not p.is_file():
            r.fail("machine", f"{m!r}: no such machine file and not a built-in machine "
                              f"({', '.join(mf.builtin_names())})")
        try:  # not UTF-8 (e.g. compressed): read_text_file says so, as every text reader
            mdoc = tomllib.loads(read_text_file(p, mf.MachineFileError, "machine file"))
        except tomllib.TOMLDecodeError as e:
            raise mf.MachineFileError(f"{p}: not a TOML machine file: {e}") from None
        src = str(p)
    mdoc = dict(mdoc)
    for k, v in inj.items():
        if k in ("error", "probe"):
            merged = dict(r.table(f"injected.{k}", mdoc.get(k, {})))
            merged.update(r.table(f"injected.{k}", v))
            mdoc[k] = merged
        else:
            mdoc[k] = v
    if inj.get("errors") == "none" and "seed" not in inj:
        mdoc.pop("seed", None)
    # the machine-file reader names the key that is wrong (source: the study's machine with its injections)
    try:
        return mf._Reader(f"{r.source}: machine {src}" + (" with [injected]" if inj else "")).spec(mdoc)
    except mf.MachineFileError as e:
        raise StudyError(str(e)) from None


def loads_study(text: str, source: str = "<study>", base_dir=".") -> Study:
    """Read a study's TOML text (module docstring); ``base_dir``: where a relative machine file is."""
    r = _Reader(source)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise StudyError(f"{source}: not TOML: {e}") from None
    for k in doc:
        if k not in _TOP:
            r.fail(k, f"unknown key (expected one of {', '.join(_TOP)})")
    if doc.get("format", FORMAT) != FORMAT:
        r.fail("format", f"expected {FORMAT!r}, got {doc.get('format')!r}")
    if not doc:
        raise StudyError(f"{source}: empty study (no keys; a study needs format, identification, machine, "
                         "seeds and [accept.*]: README 'Regression studies')")
    ident = doc.get("identification")
    if ident is None:
        r.fail("identification", f"missing (one of {', '.join(IDENTIFICATIONS)})")
    if ident not in IDENTIFICATIONS:
        r.fail("identification", f"expected one of {', '.join(IDENTIFICATIONS)}, got {ident!r}")
    known = QUANTITIES[ident]
    name = doc.get("name", Path(source).stem)
    if not isinstance(name, str) or not name.strip():
        r.fail("name", f"expected a non-empty string, got {name!r}")
    seeds = doc.get("seeds")
    if not isinstance(seeds, list) or not seeds:
        r.fail("seeds", "missing: a non-empty list of integer seeds")
    seeds = tuple(r.integer(f"seeds[{i}]", s, lo=0) for i, s in enumerate(seeds))
    if len(set(seeds)) != len(seeds):
        r.fail("seeds", f"a seed given twice: {list(seeds)}")
    noise = doc.get("noise_um")
    noise = None if noise is None else r.number("noise_um", noise, nonneg=True)
    plan = r.table("plan", doc.get("plan", {}))
    for k in plan:
        if k not in _PLAN_KEYS[ident]:
            r.fail(f"plan.{k}", f"unknown key for {ident} (expected one of {', '.join(_PLAN_KEYS[ident])})")
    _check_plan(r, ident, plan)
    machine = _machine(r, doc, Path(base_dir))
    if noise is None:
        noise = machine.probe.sigma_m * 1e6 if ident != "iso230-2" else 0.5
    acc = r.table("accept", doc.get("accept", {}))
    if not acc:
        r.fail("accept", "missing: at least one [accept.QUANTITY] table (a study that checks nothing)")
    rules = []
    for q, body in acc.items():
        key = f"accept.{q}"
        if q not in known:
            r.fail(key, f"unknown quantity for {ident} (known: {', '.join(known)})")
        body = r.table(key, body)
        unit = known[q]
        if ident == "discover":
            for k in body:
                if k not in ("expected", "others"):
                    r.fail(f"{key}.{k}", "unknown key (expected: expected = [\"cause\", ...], the whole set of causes "
                                         "discover must name, [] for none; others = \"allowed\" to let it name more)")
            if "expected" not in body:
                r.fail(key, "missing: expected = [\"cause\", ...] (the causes discover must name; [] for none)")
            exp = body["expected"]
            exp = [] if exp == NO_CAUSE else [exp] if isinstance(exp, str) else exp
            if not isinstance(exp, list) or not all(isinstance(x, str) and x and x != NO_CAUSE for x in exp):
                r.fail(f"{key}.expected", f"expected a cause name, a list of them, [] or {NO_CAUSE!r} (no cause may be "
                                          f"named), got {body['expected']!r}")
            others = body.get("others", "refused")
            if others not in ("allowed", "refused"):
                r.fail(f"{key}.others", f"expected \"allowed\" or \"refused\" (the default), got {others!r}")
            if not exp and others == "allowed":
                r.fail(key, "expected = [] with others = \"allowed\": a check that nothing can fail")
            rules.append(Rule(q, None, None, unit, tuple(exp), others_allowed=others == "allowed"))
            continue
        allowed = ("within_u95", f"tolerance_{unit}")
        mkey = f"max_u95_{unit}"
        for k in body:
            if k not in allowed + (mkey,):
                r.fail(f"{key}.{k}", f"unknown key (expected one of {', '.join(allowed + (mkey,))}; {q} is in {unit})")
        max_u95 = None
        if mkey in body:
            if q in _NO_U95.get(ident, ()):
                r.fail(f"{key}.{mkey}", f"{q} has no U95")
            body = dict(body)
            max_u95 = r.number(f"{key}.{mkey}", body.pop(mkey), positive=True)
        if len(body) != 1:
            r.fail(key, f"expected exactly one of {', '.join(allowed)} (and optionally {mkey})")
        if "within_u95" in body:
            if q in _NO_U95.get(ident, ()):
                r.fail(f"{key}.within_u95", f"{q} has no U95; use tolerance_{unit}")
            if noise == 0:
                r.fail(f"{key}.within_u95", "needs probing noise (noise_um > 0): a noise-free run's U95 is not "
                                            "a statement about noise; use an absolute tolerance")
            v = body["within_u95"]
            if isinstance(v, str):
                if v != "simultaneous":
                    r.fail(f"{key}.within_u95", f"expected a number or \"simultaneous\", got {v!r}")
                rules.append(Rule(q, None, None, unit, simultaneous=True, max_u95=max_u95))
            else:
                rules.append(Rule(q, r.number(f"{key}.within_u95", v, positive=True), None, unit, max_u95=max_u95))
        else:
            rules.append(Rule(q, None, r.number(f"{key}.tolerance_{unit}", body[f"tolerance_{unit}"],
                                                positive=True), unit, max_u95=max_u95))
    mutation = None
    if "mutate" in doc:
        mt = r.table("mutate", doc["mutate"])
        for k in mt:
            if k not in ("flip_sign", "drop", "planar", "scale"):
                r.fail(f"mutate.{k}", "unknown key (expected flip_sign, drop, planar, scale)")
        planar = mt.get("planar", False)
        if not isinstance(planar, bool):
            r.fail("mutate.planar", f"expected true or false, got {planar!r}")
        if planar and ident != "selfcal":
            r.fail("mutate.planar", "only for the self-calibration (its height terms)")
        if ident == "discover" and mt.get("flip_sign"):
            r.fail("mutate.flip_sign", "a cause has no sign (discover: drop only)")
        sc = r.table("mutate.scale", mt.get("scale", {}))
        if ident == "discover" and sc:
            r.fail("mutate.scale", "a cause has no magnitude (discover: drop only)")
        r.names("mutate.scale", list(sc), known)
        scale = tuple((q, r.number(f"mutate.scale.{q}", c)) for q, c in sc.items())
        mutation = Mutation(r.names("mutate.flip_sign", mt.get("flip_sign", []), known),
                            r.names("mutate.drop", mt.get("drop", []), known), planar, scale)
        if ident == "discover" and "cause" in mutation.drop and any(not u.expected for u in rules):
            r.fail("mutate.drop", "the study expects no cause: dropping the findings cannot fail it")
    desc = doc.get("description", "")
    if not isinstance(desc, str):
        r.fail("description", f"expected a string, got {desc!r}")
    return Study(source, name.strip(), ident, machine, seeds, noise, tuple(sorted(plan.items())), tuple(rules),
                 mutation, desc)


def _check_plan(r: _Reader, ident: str, plan: dict) -> None:
    if ident in ("selfcal", "discover"):
        if "c_angles_deg" in plan:
            v = plan["c_angles_deg"]
            if not isinstance(v, list) or len(v) < 2:
                r.fail("plan.c_angles_deg", f"expected a list of at least 2 C angles in degrees, got {v!r}")
            [r.number(f"plan.c_angles_deg[{i}]", x) for i, x in enumerate(v)]
        if "grid_mm" in plan:
            v = plan["grid_mm"]
            if not isinstance(v, list) or len(v) != 3:
                r.fail("plan.grid_mm", f"expected [lo, hi, step] in mm, got {v!r}")
            lo, hi, st = (r.number(f"plan.grid_mm[{i}]", x) for i, x in enumerate(v))
            if not (lo < hi and st > 0):
                r.fail("plan.grid_mm", f"expected lo < hi and step > 0, got {v!r}")
        if "declared_ripple" in plan:
            if ident != "selfcal":
                r.fail("plan.declared_ripple", "only for selfcal")
            from core.uncertainty import TABLES

            v = plan["declared_ripple"]
            if not isinstance(v, dict) or not v:
                r.fail("plan.declared_ripple", f"expected a table {{ EXX = [amplitude, period_mm], ... }}, got {v!r}")
            for k, ap in v.items():
                w = f"plan.declared_ripple.{k}"
                if k not in TABLES:
                    r.fail(w, f"not a table of the self-calibration (one of {', '.join(TABLES)})")
                if not isinstance(ap, list) or len(ap) != 2:
                    r.fail(w, f"expected [amplitude (um; urad for ECY, ECX), period mm], got {ap!r}")
                a, per = (r.number(f"{w}[{i}]", x) for i, x in enumerate(ap))
                if not (a >= 0 and per > 0):
                    r.fail(w, f"expected amplitude >= 0 and period > 0, got {ap!r}")
    elif ident.startswith("mfb"):
        if "mc_runs" in plan:
            r.integer("plan.mc_runs", plan["mc_runs"], lo=0)
    else:
        if "axis" in plan and plan["axis"] not in ("X", "Y", "Z"):
            r.fail("plan.axis", f"expected X, Y or Z, got {plan['axis']!r}")
        if "targets" in plan:
            r.integer("plan.targets", plan["targets"], lo=2)
        if "cycles" in plan:
            r.integer("plan.cycles", plan["cycles"], lo=2)
        if "cycle" in plan and plan["cycle"] not in ("linear", "pilgrim"):
            r.fail("plan.cycle", f"expected linear or pilgrim, got {plan['cycle']!r}")


def load_study(path) -> Study:
    """Read a study file (relative machine files are found beside it).

    Raises
    ------
    StudyError
        No such file, not UTF-8 TOML, or a key that is wrong (named).
    """
    p = Path(path)
    return loads_study(read_text_file(p, StudyError, "study file"), str(p), p.parent)


# --------------------------------------------------------------------------- identifications
def _cross_pocket(study: Study, seed: int):
    """(machine, artefact, plan, probe log): the cross-pocket campaign of ``seed`` on the study's machine."""
    from dataclasses import replace

    from sim import artefacts as A
    from sim.campaign import simulate_campaign
    from sim.catalog import make_plan
    from sim.machine import Machine

    spec = study.machine
    if "C" not in spec.config.strokes:
        raise StudyError(f"{study.source}: machine {spec.config.name}: the cross-pocket campaign needs a C axis")
    m = Machine(spec.config)
    noise_m = study.noise_um * 1e-6
    probe = replace(spec.probe, repeatability_k2_m=2.0 * noise_m)
    art = A.cross_pocket()
    plan = make_plan(art)
    angles = [float(c) for c in study.plan_value("c_angles_deg", [0.0, 75.0, 130.0, 210.0])]
    rng = np.random.default_rng(seed) if noise_m > 0 else None
    log = simulate_campaign(art, m, probe, angles, rng, check_collisions=False,
                            meta={"errors": f"study {study.name}", "seed": str(seed)})
    return m, art, plan, log


#: Share (percent) of one seed's work done after each stage of a runner that has no finer count of its own, for
#: ``vmt regress``'s time left within a seed (a shipped study has one or two seeds of 4-11 s: the line sat at 0/1
#: with no time left until the end, session 38). Measured on the shipped studies (regress-selfcal-nmv3000: the
#: campaign 0.8 s, the self-calibration 2.1 s, the truth in its gauge 0.4 s; regress-discover-nmv3000: the
#: campaign 0.1-0.8 s of a 3.6-5 s seed, the rest discover's own count).
SEED_SHARES = {"selfcal": (25, 88, 100), "discover": (15, 100)}


def _stage(progress, done: int, total: int = 100) -> None:
    if progress is not None:
        progress(done, total)


def _selfcal(study: Study, seed: int, progress=None) -> dict:
    """Cross-pocket campaign on the study's machine, self-calibration, truth in its gauge."""
    from core.selfcal import Grid, self_calibrate, yaw_for_chain
    from core.touches import from_log
    from scenarios.selfcal_coverage import Campaign, block_truth

    spec = study.machine
    _stage(progress, 0)
    m, art, plan, log = _cross_pocket(study, seed)
    _stage(progress, SEED_SHARES["selfcal"][0])
    noise_m = study.noise_um * 1e-6
    t = from_log(log.select(np.abs(log.col("nz")) <= 0.01))
    lo, hi, st = (v * 1e-3 for v in study.plan_value("grid_mm", [-110.0, 110.0, 22.0]))
    heights = False if (study.mutation is not None and study.mutation.planar) else "auto"
    dec = study.plan_value("declared_ripple", None)
    sub = None if not dec else {k: (a * 1e-6, p * 1e-3) for k, (a, p) in dec.items()}
    res = self_calibrate(t, Grid.regular(lo, hi, st), yaw=yaw_for_chain(spec.config.chain), heights=heights,
                         subgrid=sub)
    _stage(progress, SEED_SHARES["selfcal"][1])
    des = res.design
    raw, _ = block_truth(Campaign(m, t, art, plan, seed, noise_m), des)
    truth = des.to_gauge(raw)
    U = 2.0 * res.std
    F = None if res.cov is None else _factor(res.cov) * 1e6
    out = {}
    blocks = {q: q for q in _SELFCAL_Q}
    blocks["workpiece"] = "G"
    for q, blk in blocks.items():
        if blk not in des.slices:
            continue
        sl = des.slices[blk]
        out[q] = Estimate(res.theta[sl] * 1e6, truth[sl] * 1e6, U[sl] * 1e6, tuple(des.names[sl]), _SELFCAL_Q[q],
                          None if F is None else F[sl])
    return out


def _mfb(study: Study, seed: int, progress=None) -> dict:
    from core import volumetric as vol
    from scenarios import mfb

    runs = int(study.plan_value("mc_runs", 0))
    r = mfb.run(study.identification, seed=seed, noise_um=study.noise_um, mc_runs=runs, machine=study.machine,
                progress=progress)
    # the joint covariance of the reported values: the run's linear propagation (probing noise, bar
    # calibration, placements; vmt-estimate/1, um^2 / urad^2, identification gauge) in the report's
    # ISO 230-1 form (straightness against its end-point line)
    d = r.result.design
    L = vol.iso_map(d)
    F = _factor(L @ np.asarray(r.doc["estimate"]["covariance"], float) @ L.T)
    out = {}
    for s, e in r.doc["errors"].items():
        n = len(e["identified"])
        labels = tuple(f"{s}@{x:g}mm" for x in e["nodes_mm"]) if "nodes_mm" in e else (s,) * n
        u = np.asarray(e["u95"], float) if "u95" in e else None
        out[s] = Estimate(np.asarray(e["identified"], float), np.asarray(e["injected"], float), u, labels,
                          _MFB_Q[s], F[d.slices[s]])
    return out


def _positioning(study: Study, seed: int, progress=None) -> dict:
    from core.positioning import arrange, iso230_2
    from sim.machine import Machine
    from sim.positioning import deviations_m, positioning_plan, schedule, simulate_positioning

    m = Machine(study.machine.config)
    axis = study.plan_value("axis", "X")
    rng = np.random.default_rng(seed)
    plan = positioning_plan(m, axis, n_targets=int(study.plan_value("targets", 11)),
                            cycles=int(study.plan_value("cycles", 5)),
                            cycle_kind=study.plan_value("cycle", "linear"), rng=rng)
    log = simulate_positioning(m, plan, rng, noise_m=study.noise_um * 1e-6)
    rep = iso230_2(arrange(log)).to_report()
    # the truth: the exact chain without scatter at every reading's time and direction, averaged
    s = schedule(plan)
    dev_um = deviations_m(m, plan, s["target_m"], s["t_s"], s["direction"]) * 1e6
    P = np.asarray(plan.targets_m)
    up = np.array([dev_um[(s["target_index"] == i) & (s["direction"] > 0)].mean() for i in range(P.size)])
    dn = np.array([dev_um[(s["target_index"] == i) & (s["direction"] < 0)].mean() for i in range(P.size)])
    pt = rep["per_target"]
    mu_up = np.array([p["mean_up_um"] for p in pt])
    mu_dn = np.array([p["mean_down_um"] for p in pt])
    u_diff = np.sqrt(np.array([p["s_up_um"] ** 2 / p["n_up"] + p["s_down_um"] ** 2 / p["n_down"] for p in pt]))
    labels = tuple(f"P={p['target_mm']:g}mm" for p in pt)
    # the joint distribution of the two estimates per target: each direction's mean off by a normal of
    # variance s^2 / n (its own scatter), the targets independent: mean = (up + down) / 2, B_i = up - down
    a = np.array([p["s_up_um"] / math.sqrt(p["n_up"]) for p in pt])
    b = np.array([p["s_down_um"] / math.sqrt(p["n_down"]) for p in pt])
    n_t = len(pt)
    F_mean, F_rev = np.zeros((n_t, 2 * n_t)), np.zeros((n_t, 2 * n_t))
    i = np.arange(n_t)
    F_mean[i, 2 * i], F_mean[i, 2 * i + 1] = a / 2, b / 2
    F_rev[i, 2 * i], F_rev[i, 2 * i + 1] = a, -b
    dof = np.ravel([[p["n_up"] - 1, p["n_down"] - 1] for p in pt]).astype(float)
    # ISO 230-2 definitions: mean bidirectional deviation, B_i = up - down, B = max |B_i|, M = range of the
    # bidirectional means, E = max over both directions' means - min over them
    t_mean, t_rev = (up + dn) / 2, up - dn
    one = ("axis",)
    return {
        "mean": Estimate((mu_up + mu_dn) / 2, t_mean, u_diff, labels, "um", F_mean, dof),
        "reversal": Estimate(mu_up - mu_dn, t_rev, 2.0 * u_diff, labels, "um", F_rev, dof),
        "E": Estimate(np.array([rep["E_um"]]), np.array([max(up.max(), dn.max()) - min(up.min(), dn.min())]),
                      None, one, "um"),
        "M": Estimate(np.array([rep["M_um"]]), np.array([np.ptp(t_mean)]), None, one, "um"),
        "B": Estimate(np.array([rep["B_um"]]), np.array([np.abs(t_rev).max()]), None, one, "um"),
    }


def _discover(study: Study, seed: int, progress=None) -> dict:
    """The cross-pocket campaign written as a probe log and read by ``vmt discover``'s own code path; the
    causes its JSON report names (``findings[*].cause``): the only part of discover's output a study
    relies on, as its engine is being rewritten."""
    import json
    import tempfile

    from core.probelog import write_probe_log
    from scenarios.discover_run import run_discover

    _stage(progress, 0)
    *_, log = _cross_pocket(study, seed)
    first = SEED_SHARES["discover"][0]
    _stage(progress, first)
    with tempfile.TemporaryDirectory(prefix="vmt-regress-") as d:
        p, j = Path(d) / "campaign.csv", Path(d) / "discover.json"
        write_probe_log(p, log)
        run_discover(str(p), str(j), progress=None if progress is None else (
            lambda k, n: progress(first + (100 - first) * k // max(n, 1), 100)))
        rep = json.loads(j.read_text(encoding="utf-8"))
    return {"cause": Causes(tuple(str(f["cause"]) for f in rep.get("findings", [])))}


#: identification -> callable(study, seed, progress=None) -> {quantity: Estimate (or Causes for discover)};
#: ``progress(done, total)`` within the seed, where the runner counts its work
RUNNERS = {"selfcal": _selfcal, "mfb-3axis": _mfb, "mfb-5axis": _mfb, "iso230-2": _positioning,
           "discover": _discover}


# --------------------------------------------------------------------------- comparing
def check(rule: Rule, est: Estimate | None, seed: int, k_sim: float | None = None, values: int = 0,
          why: str = "") -> Check:
    """The verdict of ``rule`` on one identified quantity (None: the identification did not give it);
    a simultaneous rule needs ``k_sim`` (and ``values``, the count it holds over: :func:`simultaneous_k`);
    ``why``: when there is no ``k_sim``, which simultaneous quantities lacked a joint covariance."""
    text = rule.text(k_sim, values)
    if est is None:
        return Check(seed, rule.quantity, rule.unit, text, False, note="not identified")
    if rule.unit == "cause":
        named = est.named
        missing = [c for c in rule.expected if c not in named]
        extra = [] if rule.others_allowed else [c for c in dict.fromkeys(named) if c not in rule.expected]
        note = ("named " + (", ".join(named) if named else "no cause")
                + (f"; expected {', '.join(missing)} not named" if missing else "")
                + (f"; not expected: {', '.join(extra)}" if extra else ""))
        return Check(seed, rule.quantity, rule.unit, text, not (missing or extra), "findings", n=len(named),
                     note=note)
    dev = np.abs(np.asarray(est.identified, float) - np.asarray(est.injected, float))
    k = k_sim if rule.simultaneous else rule.k
    if rule.simultaneous and k_sim is None:
        return Check(seed, rule.quantity, rule.unit, text, False, note=why or "no joint covariance from the identification")
    if k is not None:
        if est.u95 is None:
            return Check(seed, rule.quantity, rule.unit, text, False, note="no U95 from the identification")
        lim = k * np.asarray(est.u95, float) + GAUGE_FLOOR
    else:
        lim = np.full(dev.shape, rule.tolerance)
    if dev.size == 0:
        return Check(seed, rule.quantity, rule.unit, text, False, note="no free element identified")
    if not (np.all(np.isfinite(dev)) and np.all(np.isfinite(lim))):
        return Check(seed, rule.quantity, rule.unit, text, False, note="not finite")
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(lim > 0, dev / np.where(lim > 0, lim, 1.0), np.where(dev > 0, np.inf, 0.0))
    i = int(np.argmax(ratio))
    u = math.nan if est.u95 is None else float(est.u95[i])
    ok = bool(np.all(dev <= lim))
    note = ""
    if ok and rule.max_u95 is not None:  # the deviation passed: does the band still have the power stated?
        if est.u95 is None:
            ok, note = False, f"no U95 from the identification to hold to max_u95_{rule.unit} {rule.max_u95:g}"
        else:
            uu = np.asarray(est.u95, float)
            j = int(np.argmax(uu))
            if not uu[j] <= rule.max_u95:
                ok = False
                note = (f"U95 at {est.labels[j]} = {uu[j]:.4g} {rule.unit} exceeds the study's max_u95_{rule.unit} "
                        f"{rule.max_u95:g} (x {uu[j] / rule.max_u95:.2f}): the band k x U95 comes from this run, "
                        f"so a wider U95 hides errors; |identified - injected| = {dev[i]:.4g} {rule.unit} at "
                        f"{est.labels[i]} is within {lim[i]:.4g}")
    return Check(seed, rule.quantity, rule.unit, text, ok, est.labels[i],
                 float(est.injected[i]), float(est.identified[i]), u, float(lim[i]), int(dev.size), note)


@dataclass(frozen=True)
class Power:
    """What one check of one seed can detect (:func:`power`).

    Attributes
    ----------
    limits : (n,) float
        Per value, the smallest change of that value alone that fails the check with probability
        :data:`DETECTION_POWER` (``method`` says how), in ``unit``.
    injected : (n,) float
        The injected truth in the identification's gauge (what a sign error moves: a flip changes a value by
        twice it).
    flip_ratio : float
        ``max |2 x injected| / limit`` over the values; ``sign_testable`` when >= 1: flipped, at least one
        value moves by its detection limit or more.
    """

    seed: int
    quantity: str
    unit: str
    method: str
    labels: tuple[str, ...]
    limits: np.ndarray
    injected: np.ndarray
    flip_ratio: float
    where: str

    @property
    def sign_testable(self) -> bool:
        return bool(self.flip_ratio >= 1.0)

    @property
    def smallest_gain(self) -> float:
        """The smallest gain error of this quantity (all its values reported ``(1 + g)`` times, a ``scale``
        mutation: a wrong unit, lever arm or scale in its model columns) caught with probability
        :data:`DETECTION_POWER`, as a fraction (0.06: 6 %; inf when every injected value is 0).

        A gain ``g`` moves value ``i`` by ``g x injected_i`` (the identified value is ``injected_i + e_i``;
        reported ``(1 + g)`` times, its deviation is ``g x injected_i + (1 + g) e_i``), and one value moved by
        its detection limit ``L_i`` or more fails with probability >= DETECTION_POWER: the gain is caught at
        that power once ``|g| >= L_i / |injected_i|`` at one value at least, so the smallest is
        ``min_i L_i / |injected_i| = 2 / flip_ratio`` (a flip is the gain ``g = -2``). Assumptions: the
        error's spread stays ``U95 / 2`` (``(1 + g) e``: exact to first order in ``g``; a gain below 1
        narrows it and only adds to the power, above 1 widens it by ``g``), ``k_sim`` and the U95 are the
        run's own and the gain does not change them, and the quantity's other values are left out: each
        can only add to the power, so this is an upper bound on the smallest gain caught (a gain somewhat
        smaller may also fail, on fewer than 95 % of runs)."""
        return 2.0 / self.flip_ratio if self.flip_ratio > 0 else math.inf

    @property
    def smallest(self) -> tuple[float, str]:
        """(the smallest detection limit, where)."""
        i = int(np.argmin(self.limits))
        return float(self.limits[i]), self.labels[i]

    def to_json(self) -> dict:
        lo, at = self.smallest
        return {"seed": self.seed, "quantity": self.quantity, "unit": self.unit, "method": self.method,
                "power": DETECTION_POWER, "detection_limit_min": lo, "detection_limit_min_where": at,
                "detection_limit_max": float(np.max(self.limits)),
                "injected_max_abs": float(np.max(np.abs(self.injected))),
                "flip_ratio": float(self.flip_ratio), "flip_ratio_where": self.where,
                "sign_testable": self.sign_testable,
                "smallest_gain_error": None if not math.isfinite(self.smallest_gain) else self.smallest_gain,
                "detection_limit": [float(v) for v in self.limits], "labels": list(self.labels)}


def power(rule: Rule, est: Estimate | None, seed: int, k_sim: float | None = None) -> Power | None:
    """What ``rule`` can detect on ``est`` (None for a cause, a missing quantity, or a rule without its band).

    A value checked against ``k x U95`` (``k_sim`` for a simultaneous rule) has an error of standard deviation
    U95 / 2: moved by ``d`` it fails with probability >= :data:`DETECTION_POWER` when ``d >= (k + POWER_Z / 2)
    x U95`` (+ :data:`GAUGE_FLOOR`; a value the convention fixes, U95 0, is caught above the floor). An
    absolute tolerance ``t`` with a U95: ``t + POWER_Z / 2 x U95``; without one (noise-free figures): ``2 t``,
    the change that fails every run that passed. A sign error (``flip_sign``) moves each value by twice its
    injected value in the identification's gauge: its sign is testable when at least one value moves by its
    limit or more (``flip_ratio >= 1``); below, one value alone is caught on fewer than 95 % of runs (a lower
    bound on the flip's power: several values near their limits add to it; review31b F4: flipped, EXZ, EYZ and
    ECZ of the 3-axis MFB study passed the band). ISO 230-2's U95, estimated from 5 readings per direction, is
    taken here as if known (its k_sim, the studentized maximum, is not).
    """
    if est is None or not isinstance(est, Estimate) or rule.unit == "cause":
        return None
    if rule.simultaneous and k_sim is None:  # no joint band: the check itself fails (check), nothing to state
        return None
    u = None if est.u95 is None else np.asarray(est.u95, float)
    k = k_sim if rule.simultaneous else rule.k
    half_z = POWER_Z / 2.0
    if k is not None:
        if u is None:
            return None
        lim = (k + half_z) * u + GAUGE_FLOOR
        method = f"({k:.3f} + {half_z:.3f}) x U95: caught with probability {DETECTION_POWER:.0%}"
    elif u is not None:
        lim = rule.tolerance + half_z * u
        method = (f"{rule.tolerance:g} {rule.unit} + {half_z:.3f} x U95: caught with probability "
                  f"{DETECTION_POWER:.0%}")
    else:
        lim = np.full(np.shape(est.identified), 2.0 * rule.tolerance)
        method = f"2 x {rule.tolerance:g} {rule.unit}: caught on every run that passed"
    inj = np.asarray(est.injected, float)
    if lim.size == 0 or not (np.all(np.isfinite(lim)) and np.all(np.isfinite(inj))):
        return None
    ratio = 2.0 * np.abs(inj) / lim
    i = int(np.argmax(ratio))
    return Power(seed, rule.quantity, rule.unit, method, tuple(est.labels), lim, inj, float(ratio[i]),
                 est.labels[i])


def run_study(study: Study, *, hook=None, progress=None) -> StudyResult:
    """Run every seed of ``study`` and check every rule.

    Parameters
    ----------
    study : Study
    hook : callable, optional
        ``hook(identification, estimates) -> estimates``, called on each
        seed's identified quantities (``{name: Estimate}``) before they are
        compared: the documented place to inject a change into the
        identification (:class:`Mutation` is one). The study's own
        ``[mutate]`` is applied first.
    progress : callable, optional
        ``progress(done, 100)``: the percent of the study's work done, the seeds in turn and each seed's own
        stages within its share (its runner's count: :data:`SEED_SHARES`, the MFB run's steps).
    """
    checks, secs, all_est, sim, powers = [], [], {}, [], []
    run = RUNNERS[study.identification]
    n = len(study.seeds)
    for j, seed in enumerate(study.seeds):
        if progress is not None:
            progress(100 * j // n, 100)
        t0 = time.perf_counter()
        within = None if progress is None else (
            lambda k, m, j=j: progress(min(100 * j + 100 * k // max(m, 1), 100 * (j + 1)) // n, 100))
        est = run(study, seed) if within is None else run(study, seed, progress=within)
        if study.mutation is not None:
            est = study.mutation(study.identification, est)
        if hook is not None:
            est = hook(study.identification, est)
        secs.append(time.perf_counter() - t0)
        all_est[seed] = est
        k_sim, n_sim = None, 0
        joint = {r.quantity: est.get(r.quantity) for r in study.rules if r.simultaneous}
        lacking = [q for q, e in joint.items() if not (isinstance(e, Estimate) and e.factor is not None
                                                       and e.u95 is not None)]
        band = ""
        if joint and not lacking:
            k_sim, n_sim = simultaneous_k(list(joint.values()))
            sim.append((seed, k_sim, n_sim))
            band = band_consistency(joint, k_sim, n_sim)
        why = (f"no joint band: {', '.join(lacking)} {'has' if len(lacking) == 1 else 'have'} no joint covariance"
               if lacking else "")
        for r in study.rules:
            c = check(r, est.get(r.quantity), seed, k_sim, n_sim, why=why)
            if band and r.simultaneous:  # the band itself is wrong: no verdict drawn from it stands
                from dataclasses import replace

                c = replace(c, passed=False, note=f"simultaneous band not trusted: {band}")
            checks.append(c)
        powers += [p for p in (power(r, est.get(r.quantity), seed, k_sim) for r in study.rules) if p is not None]
    if progress is not None:
        progress(100, 100)
    return StudyResult(study, tuple(checks), tuple(secs), all_est, tuple(sim), tuple(powers))


# --------------------------------------------------------------------------- JUnit XML
def _token(s: str) -> str:
    """An xs:token: no tabs or line breaks, no leading, trailing or doubled spaces."""
    return " ".join(str(s).split())


def junit_xml(result: StudyResult, *, timestamp: str | None = None, hostname: str | None = None) -> str:
    """The study as JUnit XML (the common Ant/Jenkins schema, Windy Road ``JUnit.xsd``).

    ``<testsuites>`` holds one ``<testsuite>`` (``id`` 0, ``package`` the
    identification) with ``properties`` (study, machine, seeds, noise),
    one ``<testcase>`` per (quantity, seed) whose ``<failure>`` carries
    :meth:`Check.message`, then ``system-out`` (the table) and an empty
    ``system-err``. Times are decimals in seconds; the timestamp is
    ``YYYY-MM-DDTHH:MM:SS`` without a zone (UTC), as the schema asks.
    """
    import datetime
    import socket
    from xml.etree import ElementTree as ET

    s = result.study
    ts = timestamp or datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S")
    host = _token(hostname or socket.gethostname() or "localhost") or "localhost"
    total = sum(result.seconds)
    root = ET.Element("testsuites")
    suite = ET.SubElement(root, "testsuite", {
        "name": _token(s.name), "timestamp": ts, "hostname": host, "tests": str(len(result.checks)),
        "failures": str(len(result.failures)), "errors": "0", "skipped": "0", "time": f"{total:.3f}",
        "package": _token(f"vmt.regress.{s.identification}"), "id": "0"})
    props = ET.SubElement(suite, "properties")
    for k, v in (("study", s.source), ("identification", s.identification), ("machine", s.machine.config.name),
                 ("seeds", " ".join(map(str, s.seeds))), ("noise_um", f"{s.noise_um:g}"),
                 ("convention", "ISO 230-1, tool relative to workpiece; injected in the identification's gauge")):
        ET.SubElement(props, "property", {"name": k, "value": v})
    per_seed = {seed: t for seed, t in zip(s.seeds, result.seconds)}
    n_rules = max(len(s.rules), 1)
    for c in result.checks:
        tc = ET.SubElement(suite, "testcase", {"name": _token(f"{c.quantity} seed {c.seed}"),
                                               "classname": _token(f"vmt.regress.{s.name}"),
                                               "time": f"{per_seed.get(c.seed, 0.0) / n_rules:.3f}"})
        if not c.passed:
            f = ET.SubElement(tc, "failure", {"message": c.message(), "type": "vmt.regress.NotRecovered"})
            f.text = c.message()
    ET.SubElement(suite, "system-out").text = result.table()
    ET.SubElement(suite, "system-err").text = ""
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
