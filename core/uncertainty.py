"""Uncertainty of the 2D self-calibration, two ways that must agree.

- :func:`linear_uncertainty`: linear propagation ``u^2 DZ M^-1 DZ^T`` of the
  probing standard uncertainty through the constrained least squares of
  :mod:`core.selfcal` (JCGM 100 law of propagation; exact here because the
  estimator is linear in the observations).
- :func:`monte_carlo`: JCGM 101 Monte Carlo (paper section 6: 1,000 runs,
  u = 1.38 um): every run adds N(0, u^2) to every touch and re-estimates
  with the SAME factorisation (:class:`core.lsq.LinearEstimator`), so
  1,000 runs of the cross-pocket case take milliseconds.

Expanded uncertainty ``U95 = 2 u`` (k = 2); Monte Carlo also gives the
probabilistically symmetric 95 % coverage interval of the estimation error.
Both take nominal target points/normals in W and C angles, so a study runs
on a nominal design without simulation; ``*_touches`` variants take the
touches of a log.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .exceptions import ConfigError
from .lsq import LinearEstimator, remove_span
from .selfcal import SelfCalDesign, Grid, Yaw, estimator, nominal_touches
from .touches import Touches

#: Standard probing uncertainty (k = 1) of the paper's section 6, m.
U_PROBE_M = 1.38e-6
#: Coverage factor for the expanded uncertainty.
K = 2.0


@dataclass(frozen=True)
class SelfCalUncertainty:
    """Uncertainty of every self-calibration parameter.

    Attributes
    ----------
    design : SelfCalDesign
        Names (``design.names``), blocks (``design.slices``), grid, targets.
    u : (n_params,) float
        Standard uncertainty, m / rad (0 for the gauge-fixed values).
    U95 : (n_params,) float
        Expanded uncertainty ``k u`` with k = 2.
    method : str
        ``"linear"`` or ``"monte-carlo"``.
    runs : int
        Monte Carlo runs (0 for linear).
    lo, hi : (n_params,) float or None
        Monte Carlo 95 % coverage interval of the estimation error
        (estimate minus truth), m / rad.
    u_se : (n_params,) float or None
        Sampling standard error of the Monte Carlo ``u`` (about
        ``u / sqrt(2 (runs - 1))``).
    u_probe_m : float
        Probing standard uncertainty used, m.
    G_form_u : (N_w,) float
        Standard uncertainty of the workpiece FORM: G after least-squares
        removal of the workpiece's shift, rotation and scale (the G-parts of
        the gauge directions, :func:`form_projector`), m. The G values
        themselves also carry the uncertainty of the datum the gauge
        defines, which for the cross pocket is dominated by the weakly
        observed edge nodes where eq 17 is imposed; the paper's Fig. 18
        values match the form uncertainty.
    """

    design: SelfCalDesign
    u: np.ndarray
    U95: np.ndarray
    method: str
    runs: int
    lo: np.ndarray | None
    hi: np.ndarray | None
    u_se: np.ndarray | None
    u_probe_m: float
    G_form_u: np.ndarray

    @property
    def G_form_U95(self) -> np.ndarray:
        """(N_w,) expanded (k = 2) form uncertainty of G, m."""
        return K * self.G_form_u

    @property
    def max_form_U95(self) -> float:
        """Largest expanded form uncertainty of G, m."""
        return float(self.G_form_U95.max())

    def block(self, name: str, which: str = "U95") -> np.ndarray:
        """Values of one block (``"G"``, ``"EXX"``, ``"ECC"``, ...)."""
        return getattr(self, which)[self.design.slices[name]]

    @property
    def max_workpiece_U95(self) -> float:
        """Largest expanded uncertainty of G over the targets, m."""
        return float(self.block("G").max())


def form_projector(des: SelfCalDesign) -> np.ndarray:
    """(N_w, N_w) projector removing a workpiece shift, rotation and scale from G.

    ``P = I - N_G N_G^+`` with ``N_G`` the G rows of the null directions
    "workpiece X/Y shift", "workpiece rotation" and "scale"
    (:func:`core.selfcal.null_space`).
    """
    Ng = des.N[des.slices["G"]][:, [4, 5, 7, 10]]
    return remove_span(np.eye(Ng.shape[0]), Ng)


def _check_u(u_probe_m):
    if not (np.isfinite(u_probe_m) and u_probe_m > 0):
        raise ConfigError(f"u_probe_m must be > 0, got {u_probe_m}")


def linear_uncertainty_touches(touches: Touches, grid: Grid, u_probe_m: float = U_PROBE_M,
                               delta_L_m: float | None = None, *, yaw: Yaw | str = Yaw.ECY) -> SelfCalUncertainty:
    """Linear propagation for the touches of a log (only their geometry is used)."""
    _check_u(u_probe_m)
    des, est = estimator(touches, grid, delta_L_m, yaw=yaw)
    u = est.std(u_probe_m)
    Cg = est.covariance_of(des.slices["G"], u_probe_m)
    P = form_projector(des)
    uf = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", P, Cg, P), 0))
    return SelfCalUncertainty(design=des, u=u, U95=K * u, method="linear", runs=0, lo=None, hi=None, u_se=None,
                       u_probe_m=float(u_probe_m), G_form_u=uf)


def linear_uncertainty(w_W, wn_W, c_deg, grid: Grid, u_probe_m: float = U_PROBE_M, *,
                       stylus_r_m: float = 0.0) -> SelfCalUncertainty:
    """Linear propagation for a nominal design.

    Parameters
    ----------
    w_W, wn_W : (N_w, 2) float
        Target contact points (m) and outward unit normals, workpiece frame W.
    c_deg : sequence of float
        C angles, degrees.
    grid : Grid
    u_probe_m : float
        Probing standard uncertainty, m.
    """
    return linear_uncertainty_touches(nominal_touches(w_W, wn_W, c_deg, stylus_r_m=stylus_r_m), grid, u_probe_m)


def mc_errors(est: LinearEstimator, n_obs: int, u_probe_m: float, runs: int,
              rng: np.random.Generator) -> np.ndarray:
    """(runs, n_params) estimation errors of ``runs`` Monte Carlo runs.

    One draw of N(0, u^2) per touch and run, pushed through the factored
    estimator (the estimate is linear, so error = estimate(noise)).
    """
    e = rng.standard_normal((n_obs, runs)) * u_probe_m
    return est.noise_gain(e).T


def monte_carlo_touches(touches: Touches, grid: Grid, u_probe_m: float = U_PROBE_M, *, runs: int = 1000,
                        rng: np.random.Generator, delta_L_m: float | None = None,
                        yaw: Yaw | str = Yaw.ECY) -> SelfCalUncertainty:
    """JCGM 101 Monte Carlo for the touches of a log (design factored once)."""
    _check_u(u_probe_m)
    if int(runs) < 10:
        raise ConfigError(f"runs must be >= 10, got {runs}")
    if not isinstance(rng, np.random.Generator):
        raise ConfigError("rng must be a numpy.random.Generator")
    des, est = estimator(touches, grid, delta_L_m, yaw=yaw)
    err = mc_errors(est, touches.n, u_probe_m, int(runs), rng)
    return summarise_mc(des, err, u_probe_m)


def summarise_mc(des: SelfCalDesign, err: np.ndarray, u_probe_m: float) -> SelfCalUncertainty:
    """Standard uncertainty, k = 2 band and 95 % coverage interval from MC errors (runs, n)."""
    runs = err.shape[0]
    u = err.std(axis=0, ddof=1)
    lo, hi = np.quantile(err, [0.025, 0.975], axis=0)
    uf = (err[:, des.slices["G"]] @ form_projector(des).T).std(axis=0, ddof=1)
    return SelfCalUncertainty(design=des, u=u, U95=K * u, method="monte-carlo", runs=runs, lo=lo, hi=hi,
                       u_se=u / np.sqrt(2.0 * (runs - 1)), u_probe_m=float(u_probe_m), G_form_u=uf)


def monte_carlo(w_W, wn_W, c_deg, grid: Grid, u_probe_m: float = U_PROBE_M, *, runs: int = 1000,
                rng: np.random.Generator, stylus_r_m: float = 0.0) -> SelfCalUncertainty:
    """JCGM 101 Monte Carlo for a nominal design (see :func:`linear_uncertainty`)."""
    return monte_carlo_touches(nominal_touches(w_W, wn_W, c_deg, stylus_r_m=stylus_r_m), grid, u_probe_m,
                               runs=runs, rng=rng)
