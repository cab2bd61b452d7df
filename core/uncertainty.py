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

from dataclasses import dataclass, field

import numpy as np

from .exceptions import ConfigError
from .lsq import LinearEstimator, remove_span
from .selfcal import SelfCalDesign, Grid, Yaw, estimator, nominal_touches
from .touches import Touches

#: Standard probing uncertainty (k = 1) of the paper's section 6, m.
U_PROBE_M = 1.38e-6
#: Coverage factor for the expanded uncertainty.
K = 2.0
#: The fewest Monte Carlo runs any vmt Monte Carlo takes (JCGM 101). The volumetric identification's U95
#: (:func:`core.volumetric.uncertainty`, ``vmt scenario mfb-*``) is the half-width between the 2.5 % and
#: 97.5 % percentiles of the runs, and of fewer runs those are the runs' extremes or less (of one run a width
#: of 0: every U95 zero, review of session 26); the self-calibration's (``vmt identify --mc``,
#: :func:`summarise_mc`) is 2 x the runs' std (Gaussian errors by construction), whose 9 degrees of freedom
#: at 10 runs give it about 24 % scatter. One rule for every ``--mc`` of the CLI.
MC_MIN_RUNS = 10


def check_mc_runs(runs, what: str = "runs", *, zero_ok: bool = False) -> int:
    """``runs`` as an int if it is a Monte Carlo size vmt takes (>= :data:`MC_MIN_RUNS`; 0 too with
    ``zero_ok``: no Monte Carlo), else a ConfigError naming ``what`` (``"--mc"`` in the CLI)."""
    n = int(runs)
    if n != runs or not (n >= MC_MIN_RUNS or (zero_ok and n == 0)):
        zero = " (0: none)" if zero_ok else ""
        raise ConfigError(f"{what} {runs}: a Monte Carlo needs at least {MC_MIN_RUNS} runs{zero}: its U95 is "
                          "read from the runs' spread: their 2.5 % and 97.5 % percentiles, or 2 std in identify")
    return n


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
        Expanded uncertainty ``k u`` with k = 2, linear and Monte Carlo alike (the Monte Carlo's ``u``: its
        runs' std). Not the percentile half-width ``(hi - lo) / 2`` the volumetric Monte Carlo reports
        (:func:`core.volumetric.uncertainty`): these errors are Gaussian by construction (Gaussian probing
        noise through a linear estimator, :func:`mc_errors`), so both estimate the same interval
        (1.96 u against 2 u: the k = 2 convention of the linear U95 it stands beside), and ``k`` std
        scatters less (about 3.5 % against 5 % of U95 at 400 runs). :attr:`lo`, :attr:`hi` keep the
        percentile interval (review30b F3: the CLI and README said percentiles for every ``--mc``).
    method : str
        ``"linear"`` or ``"monte-carlo"``.
    runs : int
        Monte Carlo runs (0 for linear).
    lo, hi : (n_params,) float or None
        Monte Carlo 95 % coverage interval of the estimation error
        (estimate minus truth), m / rad.
    u_probe_m : float
        Probing standard uncertainty used, m.
    G_form_u : (N_w,) float
        Standard uncertainty of the workpiece FORM: G after least-squares
        removal of the workpiece's shift, rotation and scale (the G-parts of
        the gauge directions, :func:`form_projector`), m. The G values
        themselves also carry the uncertainty of the datum the gauge
        defines, which for the cross pocket is dominated by the weakly
        observed edge nodes where eq 17 is imposed. The paper's Figs. 18-19
        are read as the G values themselves (``block("G")``, the gauge of
        eqs 16-17: scenarios.crosspocket.U95_READING); the form is one part
        of that value (:func:`workpiece_components`), not another reading.
    """

    design: SelfCalDesign
    u: np.ndarray
    U95: np.ndarray
    method: str
    runs: int
    lo: np.ndarray | None
    hi: np.ndarray | None
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
    cols = [4, 5, 7, 10] + list(range(11, des.N.shape[1]))  # and the height terms' own (tilt, twist, growth)
    Ng = des.N[des.slices["G"]][:, cols]
    return remove_span(np.eye(Ng.shape[0]), Ng)


def _check_u(u_probe_m):
    if not (np.isfinite(u_probe_m) and u_probe_m > 0):
        raise ConfigError(f"u_probe_m must be > 0, got {u_probe_m}")


def linear_uncertainty_touches(touches: Touches, grid: Grid, u_probe_m: float = U_PROBE_M,
                               delta_L_m: float | None = None, *, yaw: Yaw | str = Yaw.ECY,
                               heights: bool | str = "auto") -> SelfCalUncertainty:
    """Linear propagation for the touches of a log (only their geometry is used)."""
    _check_u(u_probe_m)
    des, est = estimator(touches, grid, delta_L_m, yaw=yaw, heights=heights)
    u = est.std(u_probe_m)
    Cg = est.covariance_of(des.slices["G"], u_probe_m)
    P = form_projector(des)
    uf = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", P, Cg, P), 0))
    return SelfCalUncertainty(design=des, u=u, U95=K * u, method="linear", runs=0, lo=None, hi=None,
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
                        yaw: Yaw | str = Yaw.ECY, heights: bool | str = "auto") -> SelfCalUncertainty:
    """JCGM 101 Monte Carlo for the touches of a log (design factored once; probing noise only)."""
    _check_u(u_probe_m)
    runs = check_mc_runs(runs)
    if not isinstance(rng, np.random.Generator):
        raise ConfigError("rng must be a numpy.random.Generator")
    des, est = estimator(touches, grid, delta_L_m, yaw=yaw, heights=heights)
    err = mc_errors(est, touches.n, u_probe_m, int(runs), rng)
    return summarise_mc(des, err, u_probe_m)


def summarise_mc(des: SelfCalDesign, err: np.ndarray, u_probe_m: float) -> SelfCalUncertainty:
    """Standard uncertainty (the runs' std), U95 = k u (k = 2) and the 95 % coverage interval (the runs' 2.5 %
    and 97.5 % percentiles) from MC errors (runs, n).

    ``k`` std, not the percentile half-width, for the reason :class:`SelfCalUncertainty` gives (Gaussian
    errors by construction); on errors that are not Gaussian the two differ (a uniform draw: 2 std is 1.155 a,
    the half-width 0.95 a; tests/core/test_uncertainty.py), and the percentile interval is ``lo``, ``hi``.
    """
    runs = err.shape[0]
    if runs < MC_MIN_RUNS:
        raise ConfigError(f"summarise_mc: {runs} runs, fewer than MC_MIN_RUNS = {MC_MIN_RUNS}")
    u = err.std(axis=0, ddof=1)
    lo, hi = np.quantile(err, [0.025, 0.975], axis=0)
    uf = (err[:, des.slices["G"]] @ form_projector(des).T).std(axis=0, ddof=1)
    return SelfCalUncertainty(design=des, u=u, U95=K * u, method="monte-carlo", runs=runs, lo=lo, hi=hi,
                       u_probe_m=float(u_probe_m), G_form_u=uf)


def monte_carlo(w_W, wn_W, c_deg, grid: Grid, u_probe_m: float = U_PROBE_M, *, runs: int = 1000,
                rng: np.random.Generator, stylus_r_m: float = 0.0) -> SelfCalUncertainty:
    """JCGM 101 Monte Carlo for a nominal design (see :func:`linear_uncertainty`)."""
    return monte_carlo_touches(nominal_touches(w_W, wn_W, c_deg, stylus_r_m=stylus_r_m), grid, u_probe_m,
                               runs=runs, rng=rng)


# ---------------------------------------------------------------------------
# model error: what the look-up tables cannot follow, in the budget
# ---------------------------------------------------------------------------
#: Step of the fine table that stands for what an error table cannot follow, m.
MODEL_ERROR_STEP_M = 1.0e-3
#: A table's model-error component enters the budget when its residual statistic exceeds what probing noise
#: alone gives by this many standard deviations (``model_error_z``). The statistic is a quadratic form of few
#: effective degrees of freedom, heavier-tailed than the normal the z reads: measured on noise-only campaigns
#: (session 30, small30; identify's path, 400 draws each, 0.3 um) z > 3 enters a table 0.55 % of the time on
#: the cross pocket at 4 and at 8 C angles, 0.05 % on the pin circle (0.38 % pooled), and the paper pocket's
#: yaw table (ECY) 0.92 % (40,000 draws): not the 0.135 % a normal's z > 3 gives. Kept (the exact gate below
#: is built and off): docs/discovery-studies.md "Session 30: identify's model-error budget ...".
MODEL_ERROR_Z = 3.0
#: The exact gate, built and OFF (:data:`MODEL_ERROR_EXACT_GATE`): a table enters when its statistic's exact
#: tail probability under probing noise alone (``model_error_p``; :func:`core.lsq.quadratic_form_sf` on the
#: ratio of the statistic to the residuals' sum of squares, a ratio of quadratic forms of the noise) is below
#: the one-sided normal tail at 3 (``scipy.stats.norm.sf(3)``). On the noise-only campaigns above it enters
#: 0.12 % of tables (pooled), the ECY one 0.118 %.
MODEL_ERROR_P = 1.3498980316300946e-3
#: Gate the model-error components on ``model_error_p < MODEL_ERROR_P`` instead of ``z > MODEL_ERROR_Z``.
#: OFF: calibrated on noise, but the ratio is taken against residuals that hold every table's model error, so
#: model error in two tables dilutes each one's test: EXX and EYY 1.5 um / 15 mm ripples at one phase, noise
#: 0.3 um (vmt regress, seeds 1000-1019): each p 0.003-0.005, neither entered, EXX's nodes within U95 on 1/20
#: seeds and EYY's on 13/20 (z > 3: 20/20, 20/20). Re-testing the others against the noise and model error
#: beside an entered table, and a test of the tables' sum, did not recover EYY (the shared 45 deg touches
#: let EXX's fine table hold it). docs/discovery-studies.md "Session 30: identify's model-error budget ...".
MODEL_ERROR_EXACT_GATE = False
#: ``model_error_p`` (the exact tails: an SVD of each table's ``R Phi`` and its tail, Imhof's quadrature then, about
#: half of a cross-pocket self-calibration's CPU; the saddlepoint contour since session 37, 1.6 x Imhof's per tail)
#: is computed when first read (``ModelErrorBudget.p``: ``vmt identify``'s report) or when
#: :data:`MODEL_ERROR_EXACT_GATE` gates on it; until then the budget holds the tables' ``R Phi`` (dense), so beyond
#: this many cells in all it is computed at once instead (same doubles either way; session 31, ripple31).
MODEL_ERROR_P_LAZY_CELLS = 4.0e6
#: Largest ``n_touches x fine nodes`` for which the budget is computed (dense work arrays).
MODEL_ERROR_MAX_CELLS = 3.0e7
#: The approach-direction test's second stage (``probe_p``: can the budget's noise and model error explain the
#: residuals along the lobe columns?) counts the declared sub-grid ripples among that model error (their residual
#: part along the columns, at a uniform phase, beside the tables' fine model error), and the probing sigma it
#: tests against is the one beside them. Session 30 (small30): sclob29 left them out; docs/discovery-studies.md
#: "Session 30: identify's model-error budget ..." (its second part).
DECLARED_IN_PROBE_P = True
#: The probing sigma, when tables entered, is the residuals' beside every entered table's fine span (``|P
#: r|^2 / (dof - rank)``: noise alone there, whatever shape the tables' model error has), not the joint
#: moment equations' (which take a smooth misfit for more than the white fine table holds and drive the
#: noise to 0: a 2 um / 37 mm EYY ripple, noise 0.3 um, gave sigma 0.000 on 20/20 seeds; sclob29, session
#: 30 small30). Needs :data:`SIGMA_BESIDE_MIN_DOF` degrees of freedom there, else the moment equations.
SIGMA_BESIDE_TABLES = True
#: Fewest residual degrees of freedom beside the entered tables for :data:`SIGMA_BESIDE_TABLES` (20: the
#: sigma's relative sampling sd 1 / sqrt(2 dof) within 16 %).
SIGMA_BESIDE_MIN_DOF = 20
#: The declared sub-grid ripples' expected part of the residuals (a uniform phase: ``A^2 / 2 |Phi_T^T R
#: Phi_r|^2`` in each table's statistic, ``A^2 / 2 |R Phi_r|^2`` in ``r.r``) is taken off before the gate and the
#: moment equations, so a declared ripple the residuals show is not also booked as the table's white model
#: error (counted twice: review30b F1, session 30 ripple30; docs/discovery-studies.md "Session 30: a ripple
#: finer than the grid ..."). Switched ON in session 31 (ripple31, with :data:`DECLARED_MOMENTS_SPAN`) after
#: the selfcal coverage studies' declared rows were re-run with it (``python -m scenarios.selfcal_coverage
#: --seeds 20 40`` and ``200 240 --budget declared``, both machines, noise 0 and 0.5 um): at 0.5 um every block
#: 0.939-0.988 (was 0.937-0.986), noise free the workpiece's median U95 1.16-1.32 -> 1.04-1.05 um and the
#: nmv3000's C axis 0.981 (was 1.000); docs/discovery-studies.md "Session 31: declared ripples counted once ...".
DECLARED_IN_MOMENTS = True
#: How :data:`DECLARED_IN_MOMENTS` takes the declared ripples off: True, the residuals' part along each declared
#: ripple's residual directions (``span(R Phi_r)``, 2 per ripple: its sine and cosine parts) is projected out before
#: the gate, the moment equations and the noise (their degrees of freedom less that rank), so what the *realized*
#: phase left is taken off; False, ripple30's phase average (``A^2 / 2 |...|^2``) is subtracted, which leaves the
#: noise at 0 where a phase shows less than the average (small30's 2 um / 37 mm EYY test, seed 101: sigma 0.000
#: against a true 0.3 um; session 31, ripple31).
DECLARED_MOMENTS_SPAN = True
#: Prototype, OFF (None: the white 1 mm fine table): the tables' model error as a smooth random process of the
#: axis position (squared-exponential correlation of this length, m), its variance from the same moment
#: equations; a tuple of lengths (None among them for the white table): per table the one whose gate statistic
#: ``z`` stands out most. Session 31 (ripple31): under an undeclared EXX ripple at random phases (10-60 mm) the
#: chosen length mends EXX/EYY at 27.5-60 mm but not the set-ups' yaw (65 %) nor the 10 mm workpiece (88 %), and
#: the realistic mikron's residuals-only rows get worse; docs/discovery-studies.md "Session 31: declared ripples counted
#: once ...".
MODEL_ERROR_CORR_M = None
#: The tables whose unrepresented part is budgeted (the yaw is ECY or ECX).
TABLES = ("EXX", "EYX", "EXY", "EYY", "ECY", "ECX")

MODEL_ERROR_RULE = (
    "model error: what each error table (EXX, EYX, EXY, EYY, and the yaw) cannot follow between its nodes is taken as "
    "a random function of its axis position, the same for touches within 1 mm along that axis and independent beyond "
    "(a fine table, 1 mm step); a table's part enters when the residuals show it (z > 3 against probing noise alone; "
    "measured on noise alone about 0.4 % of tables enter, not a normal's 0.135 %), "
    "the probing noise estimated from the residuals beside the entered tables' fine span (from the moment equations "
    "when that leaves fewer than 20 degrees of freedom), its variance from the moment equations; it is propagated "
    "through the "
    "estimator and, as the difference between a table's value and the function at its node, through the gauge")


SUBGRID_RULE = (
    "declared sub-grid ripples ({}): each a sinusoid of amplitude A (the spec's bound) along its table's axis at a "
    "phase the design cannot see (uniform: its sine and cosine parts each of variance A^2 / 2), propagated through "
    "the estimator and, as its value at the nodes where eqs 16-17 set the datum, through the gauge{}")


SUBGRID_SPAN_RULE = ("; the residuals' part along each declared ripple's own directions (its sine and cosine) is "
                     "the ripple's: not read again as a table's model error nor as probing noise")


@dataclass(frozen=True)
class ModelErrorBudget:
    """The self-calibration's uncertainty from probing noise and from model error.

    Attributes
    ----------
    sigma_probe_m : float
        Probing standard deviation used, m (given, or the noise component
        estimated beside the model error).
    components : dict[str, float]
        Per table, the standard deviation of its unrepresented part, m
        (rad for the yaw); 0 when the residuals do not show it.
    z : dict[str, float]
        Per table, the residual statistic's excess over probing noise alone, in its standard deviations.
    u_probe : (n_params,) float
        Standard uncertainty from probing noise, m / rad.
    u_model : (n_params,) float
        Standard uncertainty from model error, m / rad.
    cov_model : (n_params, n_params) float or None
        Its covariance (when asked for).
    computed : bool
        False when the design was too large (:data:`MODEL_ERROR_MAX_CELLS`):
        the budget is then probing noise alone.
    rule : str
    probe_p : float or None
        With ``probe_cols``: the p-value of the residuals' part along them
        (their chi-square against this budget's noise and table model error:
        small when the tables cannot explain it); else None.
    p : dict[str, float] or None
        Per table, the statistic's exact tail probability under probing
        noise alone (the gate: :data:`MODEL_ERROR_P`); None when not computed.
        A property: computed on first read (:data:`MODEL_ERROR_P_LAZY_CELLS`),
        ``p_tail`` holding the computation until then.
    """

    sigma_probe_m: float
    components: dict
    z: dict
    u_probe: np.ndarray
    u_model: np.ndarray
    cov_model: np.ndarray | None
    computed: bool
    rule: str = MODEL_ERROR_RULE
    probe_p: float | None = None
    p_tail: object = field(default=None, repr=False, compare=False)

    @property
    def p(self) -> dict | None:
        """``p`` above: computed on first use (``p_tail`` holds the computation until then) and kept."""
        v = self.p_tail
        if callable(v):
            v = v()
            object.__setattr__(self, "p_tail", v)
        return v

    @property
    def u(self) -> np.ndarray:
        """(n_params,) combined standard uncertainty, m / rad."""
        return np.sqrt(self.u_probe ** 2 + self.u_model ** 2)


def _table_axis(des: SelfCalDesign, touches: Touches, name: str):
    """(coef (n,), v (n,), nodes): table ``name``'s coefficient in eq 14 for each touch, the touch's position
    along the table's axis (x for EXX, EYX, ECX; y for EXY, EYY, ECY), m, and the table's nodes on that axis."""
    x, y = touches.pn_R[:, 0], touches.pn_R[:, 1]
    nx, ny = touches.n_R[:, 0], touches.n_R[:, 1]
    coef, v, on_x = {"EXX": (-nx, x, True), "EYX": (-ny, x, True), "EXY": (-nx, y, False), "EYY": (-ny, y, False),
                     "ECY": (-ny * x, y, False), "ECX": (nx * y, x, True)}[name]
    return coef, v, des.grid.x_m if on_x else des.grid.y_m


def _fine_table(des: SelfCalDesign, touches: Touches, name: str, step_m: float, ell=None):
    """(Phi (n, f) sparse, S (n_params, f)) of one table's fine model-error table.

    ``Phi[i, :]``: how touch i sees the fine table (the table's coefficient
    in eq 14 times the hat weights at its axis position); ``S``: the table's
    node values as point values of the fine table (hat weights at each node).
    """
    import scipy.sparse as sp

    coef, v, nodes = _table_axis(des, touches, name)
    lo, hi = nodes[0], nodes[-1]
    f = max(int(np.ceil((hi - lo) / step_m - 1e-9)), 1)
    h = (hi - lo) / f
    k = np.clip(np.floor((v - lo) / h).astype(int), 0, f - 1)
    z = (v - lo) / h - k
    n = len(v)
    Phi = sp.csr_matrix((np.concatenate([coef * (1 - z), coef * z]), (np.tile(np.arange(n), 2), np.concatenate([k, k + 1]))),
                        shape=(n, f + 1))
    kn = np.clip(np.floor((nodes - lo) / h + 1e-9).astype(int), 0, f - 1)
    zn = (nodes - lo) / h - kn
    S = np.zeros((des.n_params, f + 1))
    idx = np.arange(des.slices[name].start, des.slices[name].stop)
    np.add.at(S, (idx, kn), 1 - zn)
    np.add.at(S, (idx, kn + 1), zn)
    if ell:   # a smooth process along the axis: e = Lf w, w white, Lf Lf^T the correlation
        Lf = _corr_factor(f + 1, h, float(ell))
        return sp.csr_matrix(Phi @ Lf), S @ Lf
    return Phi, S


def _corr_factor(m: int, h: float, ell: float) -> np.ndarray:
    """(m, k) factor of the squared-exponential correlation ``exp(-d^2 / (2 ell^2))`` of ``m`` points ``h``
    apart (its eigenvectors times the root of its eigenvalues above 1e-10 of the largest)."""
    x = np.arange(m) * h
    C = np.exp(-0.5 * ((x[:, None] - x[None, :]) / ell) ** 2)
    w, V = np.linalg.eigh(C)
    k = w > w[-1] * 1e-10
    return V[:, k] * np.sqrt(w[k])


def _check_subgrid(t, v) -> tuple[float, float]:
    """(amplitude, period) of one declared sub-grid ripple, or a ConfigError naming it."""
    if t not in TABLES:
        raise ConfigError(f"subgrid: unknown table {t!r} (one of {', '.join(TABLES)})")
    try:
        a, p = (float(x) for x in v)
    except (TypeError, ValueError):
        raise ConfigError(f"subgrid: {t} must be (amplitude, period), got {v!r}") from None
    if not (np.isfinite(a) and a >= 0):
        raise ConfigError(f"subgrid: {t} amplitude must be finite and >= 0, got {a}")
    if not (np.isfinite(p) and p > 0):
        raise ConfigError(f"subgrid: {t} period must be finite and > 0, got {p}")
    return a, p


def _ripple_table(des: SelfCalDesign, touches: Touches, name: str, period_m: float):
    """(Phi (n, 2), S (n_params, 2)) of a sinusoid of period ``period_m`` along table ``name``'s axis.

    Columns: its sine and cosine parts. ``Phi[i]``: how touch i sees them
    (the table's coefficient in eq 14 times their values at its axis
    position, as :func:`_fine_table`); ``S``: their values at the table's
    nodes (what the table's truth holds there).
    """
    coef, v, nodes = _table_axis(des, touches, name)
    w = 2.0 * np.pi / period_m
    Phi = np.column_stack([coef * np.sin(w * v), coef * np.cos(w * v)])
    S = np.zeros((des.n_params, 2))
    S[des.slices[name], 0] = np.sin(w * nodes)
    S[des.slices[name], 1] = np.cos(w * nodes)
    return Phi, S


def model_error_budget(des: SelfCalDesign, est: LinearEstimator, touches: Touches, residuals_m: np.ndarray,
                       sigma_m: float | None = None, *, full: bool = False,
                       step_m: float = MODEL_ERROR_STEP_M, subgrid: dict | None = None,
                       extra_free: int = 0, probe_cols: tuple | None = None) -> ModelErrorBudget:
    """The uncertainty of a self-calibration with its model error estimated from the residuals.

    The tables of eqs 8-11 are piecewise linear: what an error motion does
    between the nodes (a screw's ripple, curvature) they cannot follow, and
    the touches see it. Treating it as probing noise (``sigma`` from the
    residuals, independent per touch) misses two things: touches at one
    axis position see the same unrepresented error (correlated, not white),
    and a table's value differs from the function at its node by it (the
    quantity the table is compared with, and the gauge of eqs 16-17 is
    defined on node values). Here each table ``T`` gets a model-error
    component: a fine table ``e_T`` (step ``step_m``, independent values of
    variance ``s_T^2``) seen by touch i as ``c_Ti e_T(v_i)`` (``c`` its
    coefficient in eq 14, ``v`` its axis position: ``Phi_T``), so

        dq = A theta + sum_T Phi_T e_T + noise,
        theta_hat - theta_true = K (sum_T Phi_T e_T + noise) - Q sum_T S_T e_T,

    with ``K`` the estimator, ``S_T`` the node values of ``e_T`` and ``Q =
    I - N (C N)^-1 C`` the gauge (eqs 16-17) applied to them. The variances
    come from the residuals ``r = (I - H) dq`` by the moment equations
    ``E[r.r] = sigma^2 tr(I - H) + sum_T s_T^2 |R Phi_T|^2`` and ``E[|Phi_T^T
    r|^2] = sigma^2 |R Phi_T|^2 + sum_U s_U^2 |Phi_T^T R Phi_U|^2``
    (``R = I - H``), solved non-negative, over the tables whose statistic
    ``|Phi_T^T r|^2`` exceeds its probing-noise expectation by
    :data:`MODEL_ERROR_Z` of its standard deviations (``z``; the others get
    0). Beside it, ``p``: the statistic's exact tail probability under
    probing noise alone, its ratio to ``r.r`` being a ratio of quadratic
    forms of the noise, ``P(|Phi_T^T r|^2 / r.r > c) = P(e^T R (Phi_T
    Phi_T^T - c I) R e > 0)``, weights ``lambda_i - c`` (``lambda`` the
    eigenvalues of ``Phi_T^T R Phi_T``) and ``-c`` on the rest of the
    residual space (:func:`core.lsq.quadratic_form_sf`); the gate when
    :data:`MODEL_ERROR_EXACT_GATE` (off). When tables entered, the probing
    sigma is the residuals' beside their fine tables' span (``|P r|^2 /
    (dof - rank)``, ``P`` the projector off ``span(R Phi_T)`` of the entered
    ``T``: noise alone there, whatever the shape of the tables' model error),
    given :data:`SIGMA_BESIDE_MIN_DOF` degrees of freedom there
    (:data:`SIGMA_BESIDE_TABLES`); else the joint moment solution.

    Parameters
    ----------
    des, est : the design and its factored estimator (:func:`core.selfcal.estimator`).
    touches : Touches
    residuals_m : (n,) float
        ``dq - A theta_hat``, m.
    sigma_m : float or None
        Probing standard deviation when known (then only the model-error
        components are estimated), m.
    full : bool
        Also the model error's covariance (n_params, n_params).
    subgrid : dict or None
        Declared sub-grid ripples: table -> (amplitude bound ``A`` m, rad
        for the yaw; period m), e.g. a screw's pitch ripple from the
        machine's spec. Each is a sinusoid ``A sin(2 pi v / p + phi)``
        along the table's axis at a phase the design cannot see (uniform:
        ``A cos(phi)`` and ``A sin(phi)`` independent, variance ``A^2 / 2``
        each), propagated like the fine tables (through ``K`` and, as its
        values at the nodes, through the gauge), beside what the residuals
        show; the probing noise (when estimated) is then what the residuals
        hold beside every component (moment equation, at least 0). A
        ripple finer than the nodes is seen by the touches but its value
        at the datum's nodes is not: the residuals alone miss that part
        (docs/discovery-studies.md, "Session 27: a declared sub-grid ripple").
    extra_free : int
        Degrees of freedom taken from the residuals beside the design's
        (``residuals_m`` already has that many more directions projected
        out, e.g. the approach-direction structure of
        :func:`core.selfcal.direction_structure`); 0: none.
    probe_cols : (U, proj) or None
        ``U`` (n, q) orthonormal directions of the residual space (the
        approach-direction columns the fit leaves) and ``proj = U^T r`` of
        the raw residuals: the budget then also says whether the tables'
        model error and the noise it finds explain ``proj``
        (``probe_p``: ``proj^T S^-1 proj`` against chi-square(q), ``S =
        sigma^2 I + sum_T s_T^2 (U^T R Phi_T)(U^T R Phi_T)^T``).

    Returns
    -------
    ModelErrorBudget
    """
    r = np.asarray(residuals_m, float)
    n = touches.n
    u1 = est.std(1.0)
    dof = n - est.n_free - int(extra_free)
    s0 = float(np.sqrt(r @ r / dof)) if dof > 0 else 0.0
    tables = [k for k in TABLES if k in des.slices]
    span = {k: (des.grid.x_m if k in ("EXX", "EYX", "ECX") else des.grid.y_m) for k in tables}
    n_fine = sum(max(int(np.ceil((v[-1] - v[0]) / step_m - 1e-9)), 1) + 1 for v in span.values())
    cells = max(n, des.n_params) * n_fine  # the dense work arrays: (touches or parameters) x fine nodes
    sig = s0 if sigma_m is None else float(sigma_m)
    zero = np.zeros(des.n_params)
    if cells > MODEL_ERROR_MAX_CELLS or dof <= 0:
        return ModelErrorBudget(sig, {k: 0.0 for k in tables}, {k: float("nan") for k in tables}, sig * u1, zero,
                                None, False)
    A = est.A
    cands = MODEL_ERROR_CORR_M if isinstance(MODEL_ERROR_CORR_M, tuple) else (MODEL_ERROR_CORR_M,)
    fine, KP, RP = [], [], []
    for k in tables:   # per table the correlation length whose statistic stands out most (prototype, off)
        best = None
        for ell in cands:
            P, S_ = _fine_table(des, touches, k, step_m, ell)
            Pd = P.toarray()
            kp = est.noise_gain(Pd)
            rp = Pd - A @ kp
            if len(cands) > 1:
                zc = (float(np.sum((P.T @ r) ** 2)) - s0 ** 2 * float(np.sum(rp ** 2))) / max(
                    np.sqrt(2.0 * s0 ** 4 * float(np.sum((P.T @ rp) ** 2))), 1e-300)
            else:
                zc = 0.0
            if best is None or zc > best[0]:
                best = (zc, (P, S_), kp, rp)
        fine.append(best[1]); KP.append(best[2]); RP.append(best[3])
    RP_raw = RP   # before the declared ripples' span is taken off (DECLARED_MOMENTS_SPAN): the probe test's
    span_decl = DECLARED_IN_MOMENTS and DECLARED_MOMENTS_SPAN and bool(subgrid)
    if span_decl:   # the residuals beside the declared ripples' span: what the realized ripple left is not tested
        D = [_ripple_table(des, touches, t, _check_subgrid(t, v)[1])[0] for t, v in subgrid.items()
             if t in tables and _check_subgrid(t, v)[0] > 0]
        if D:
            D = np.hstack([d - A @ est.noise_gain(d) for d in D])
            if probe_cols is not None:   # the residuals are beside those columns too (``extra_free``)
                Uc = np.asarray(probe_cols[0], float)
                D = D - Uc @ (Uc.T @ D)
            Ud, sd, _ = np.linalg.svd(D, full_matrices=False)
            Ud = Ud[:, sd > (sd[0] * 1e-10 if sd.size and sd[0] > 0 else np.inf)]
            r = r - Ud @ (Ud.T @ r)
            dof -= Ud.shape[1]
            RP = [rp - Ud @ (Ud.T @ rp) for rp in RP]   # R' = (I - Ud Ud^T) R, the residual maker beside them
            if dof <= 0:
                return ModelErrorBudget(sig, {k: 0.0 for k in tables}, {k: float("nan") for k in tables}, sig * u1,
                                        zero, None, False)
            s0 = float(np.sqrt(r @ r / dof))
    q = np.array([float(np.sum((P.T @ r) ** 2)) for P, _ in fine])
    tr = np.array([float(np.sum(rp ** 2)) for rp in RP])  # tr(Phi^T R Phi)
    cross = np.array([[float(np.sum((P.T @ rq) ** 2)) for rq in RP] for P, _ in fine])  # |Phi_T^T R Phi_U|^2
    dq_decl, drr_decl, rr_decl = np.zeros(len(tables)), 0.0, []   # the declared ripples' part (DECLARED_IN_MOMENTS)
    if DECLARED_IN_MOMENTS and subgrid and not span_decl:
        for t, v in subgrid.items():
            a, p = _check_subgrid(t, v)
            if t in tables and a > 0:
                Pr, _ = _ripple_table(des, touches, t, p)
                Rr = Pr - A @ est.noise_gain(Pr)
                drr_decl += 0.5 * a ** 2 * float(np.sum(Rr ** 2))
                rr_decl.append((a, Rr))
                dq_decl += np.array([0.5 * a ** 2 * float(np.sum((P.T @ Rr) ** 2)) for P, _ in fine])
    s0n = float(np.sqrt(max(float(r @ r) - drr_decl, 0.0) / dof)) if drr_decl else s0
    var0 = 2.0 * s0n ** 4 * np.diag(cross)
    z = np.where(var0 > 0, (q - dq_decl - s0n ** 2 * tr) / np.sqrt(np.where(var0 > 0, var0, 1.0)), 0.0)
    rr_all = float(r @ r)

    def tails(RP_=RP, q_=q, dof_=dof):
        """The exact tails ``model_error_p`` per table (an SVD and :func:`core.lsq.quadratic_form_sf` at 0 each)."""
        return {t: _null_tail(rp, float(qk), rr_all, dof_) for t, rp, qk in zip(tables, RP_, q_)}

    p_tail = tails   # on first use of ModelErrorBudget.p (a report), unless the gate needs it now
    if MODEL_ERROR_EXACT_GATE or sum(rp.size for rp in RP) > MODEL_ERROR_P_LAZY_CELLS:
        p_tail = tails()
    if MODEL_ERROR_EXACT_GATE:
        pv = np.array([p_tail[t] for t in tables])
        keep = np.flatnonzero(pv < MODEL_ERROR_P)
    else:
        keep = np.flatnonzero(z > MODEL_ERROR_Z)

    def noise_beside(kept):
        """(sigma, s2, span basis or None, residuals beside the span, their dof) with tables ``kept`` entered."""
        s2k = np.zeros(len(tables))
        Ub_, r_o, d_o = None, r, dof
        if SIGMA_BESIDE_TABLES and kept.size:
            B = np.hstack([RP[k] for k in kept])
            Ub_, sv, _ = np.linalg.svd(B, full_matrices=False)
            Ub_ = Ub_[:, sv > (sv[0] * 1e-10 if sv.size and sv[0] > 0 else np.inf)]
            r_o, d_o = r - Ub_ @ (Ub_.T @ r), dof - Ub_.shape[1]
        pure_ = sigma_m is None and Ub_ is not None and d_o >= SIGMA_BESIDE_MIN_DOF
        sg = float(np.sqrt(float(r_o @ r_o) / d_o)) if pure_ else (s0 if sigma_m is None else float(sigma_m))
        if pure_ and rr_decl:   # the declared ripples' part beside the span is not noise either
            o = sum(0.5 * a ** 2 * float(np.sum((Rr - Ub_ @ (Ub_.T @ Rr)) ** 2)) for a, Rr in rr_decl)
            sg = float(np.sqrt(max(float(r_o @ r_o) - o, 0.0) / d_o))
        if kept.size:
            from scipy.optimize import nnls

            lhs = np.vstack([np.concatenate([[float(dof)], tr[kept]]),
                             np.column_stack([tr[kept], cross[np.ix_(kept, kept)]])])
            rhs = np.concatenate([[float(r @ r) - drr_decl], q[kept] - dq_decl[kept]])
            if sigma_m is None and not pure_:
                scale = np.sqrt((lhs ** 2).sum(axis=0))
                sol, _ = nnls(lhs / scale, rhs)
                sol = sol / scale
                sg = float(np.sqrt(sol[0]))
                s2k[kept] = sol[1:]
            else:
                scale = np.sqrt((lhs[:, 1:] ** 2).sum(axis=0))
                sol, _ = nnls(lhs[:, 1:] / scale, rhs - lhs[:, 0] * sg ** 2)
                s2k[kept] = sol / scale
        return sg, s2k, (Ub_ if pure_ else None), r_o, d_o

    sig, s2, Ub, r_out, dof_out = noise_beside(keep)
    pure = Ub is not None
    sig_tables = sig  # the noise beside the tables' model error alone (before the declared ripples)
    declared = {}
    rip = []  # (amplitude, Gk (n_params, 2)) of each declared ripple
    rip_res = []  # (amplitude, (I - H) Phi_r (n, 2)): what each leaves in the residuals
    Q = des.N @ np.linalg.solve(des.C @ des.N, des.C)  # gauge part of I - Q
    if subgrid:
        extra = 0.0
        for t, v in subgrid.items():
            a, p = _check_subgrid(t, v)
            if t in tables and a > 0:
                declared[t] = (a, p)
                Pr, Sr = _ripple_table(des, touches, t, p)
                kr = est.noise_gain(Pr)
                rip_res.append((a, Pr - A @ kr))
                extra += 0.5 * a ** 2 * float(np.sum(rip_res[-1][1] ** 2))
                rip.append((a, kr - (Sr - Q @ Sr)))
        if span_decl:   # the noise was estimated beside the declared ripples' span: none of them is in it
            pass
        elif declared and sigma_m is None and pure:   # beside the entered span: the ripples' part outside it
            out = sum(0.5 * a ** 2 * float(np.sum((Rr - Ub @ (Ub.T @ Rr)) ** 2)) for a, Rr in rip_res)
            sig = float(np.sqrt(max(float(r_out @ r_out) - out, 0.0) / dof_out))
        elif declared and sigma_m is None:  # the residuals' variance beside every component (moment equation)
            sig = float(np.sqrt(max(float(r @ r) - float(s2 @ tr) - extra, 0.0) / dof))
    probe_p = None
    if probe_cols is not None:
        from scipy import stats

        U, proj = probe_cols
        U, proj = np.asarray(U, float), np.asarray(proj, float)
        Sg = (sig if DECLARED_IN_PROBE_P else sig_tables) ** 2 * np.eye(U.shape[1])
        for k in np.flatnonzero(s2 > 0):
            W = U.T @ RP_raw[k]
            Sg += s2[k] * (W @ W.T)
        if DECLARED_IN_PROBE_P:   # the declared ripples are model error the budget holds: they may explain it too
            for a, Rr in rip_res:
                W = U.T @ Rr
                Sg += 0.5 * a ** 2 * (W @ W.T)
        try:
            chi = float(proj @ np.linalg.solve(Sg, proj))
            probe_p = float(stats.chi2.sf(chi, U.shape[1]))
        except np.linalg.LinAlgError:   # no noise and no model error along them: anything there is unexplained
            probe_p = 0.0 if float(proj @ proj) > 0 else 1.0
    u2 = np.zeros(des.n_params)
    cov = np.zeros((des.n_params, des.n_params)) if full else None
    for k in np.flatnonzero(s2 > 0):
        S = fine[k][1]
        Gk = KP[k] - (S - Q @ S)
        u2 += s2[k] * np.einsum("ij,ij->i", Gk, Gk)
        if full:
            cov += s2[k] * (Gk @ Gk.T)
    for a, Gk in rip:  # a sinusoid at a uniform phase: its sine and cosine parts each of variance a^2 / 2
        u2 += 0.5 * a ** 2 * np.einsum("ij,ij->i", Gk, Gk)
        if full:
            cov += 0.5 * a ** 2 * (Gk @ Gk.T)
    return ModelErrorBudget(sig, {t: float(np.sqrt(v)) for t, v in zip(tables, s2)},
                            {t: float(v) for t, v in zip(tables, z)}, sig * u1, np.sqrt(u2), cov, True,
                            MODEL_ERROR_RULE + ("; " + SUBGRID_RULE.format(", ".join(
                                f"{t} {a * 1e6:g} {'urad' if t in ('ECY', 'ECX') else 'um'} per {p * 1e3:g} mm"
                                for t, (a, p) in declared.items()), SUBGRID_SPAN_RULE if span_decl else "")
                                if declared else ""), probe_p,
                            p_tail=p_tail)


def _null_tail(RPk: np.ndarray, q: float, rr: float, dof: int) -> float:
    """``P(|Phi^T r|^2 / r.r >= q / rr)`` for residuals ``r = R e`` of white noise (``RPk = R Phi``; ``dof`` the
    residual space's dimension): the ratio of quadratic forms as one, weights ``lambda_i - c`` (``lambda`` the
    squared singular values of ``R Phi``) and ``-c`` on the residual space's other ``dof - rank`` directions."""
    from .lsq import quadratic_form_sf

    if not rr > 0:
        return 1.0
    c = q / rr
    lam = np.linalg.svd(RPk, compute_uv=False) ** 2
    lam = lam[lam > (lam[0] * 1e-12 if lam.size and lam[0] > 0 else np.inf)]
    rest = dof - lam.size
    w = np.concatenate([lam - c, [-c] if rest > 0 else []])
    h = np.concatenate([np.ones(lam.size), [rest] if rest > 0 else []])
    if not lam.size or float(h.sum()) < 2:
        return 1.0
    return quadratic_form_sf(w, 0.0, h)


# ---------------------------------------------------------------------------
# the paper's section 6 quantities from Monte Carlo errors
# ---------------------------------------------------------------------------
#: The workpiece gauge directions of :func:`core.selfcal.null_space` (columns of ``design.N``) by name.
WORKPIECE_GAUGE = {"shift": (4, 5), "rotation": (7,), "scale": (10,)}


def error_map_operator(des: SelfCalDesign) -> np.ndarray:
    """(2 N_x N_y, n_params) linear map from the parameters to ``[E_X,total; E_Y,total]`` on the nodes (eqs 4-5).

    Rows: ``E_X`` then ``E_Y``, each over the nodes ``(x_k, y_l)`` with
    ``k`` major (``np.meshgrid(x, y, indexing="ij")`` order), m per unit
    parameter. The yaw is the design's (``ECY``: ``E_Y += x ECY(y)``;
    ``ECX``: ``E_X -= y ECX(x)``), as :func:`core.selfcal.error_map`.
    """
    g, s = des.grid, des.slices
    nx, ny = len(g.x_m), len(g.y_m)
    X, Y = np.meshgrid(g.x_m, g.y_m, indexing="ij")
    K, L = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    K, L, X, Y = K.ravel(), L.ravel(), X.ravel(), Y.ravel()
    r = np.arange(nx * ny)
    M = np.zeros((2 * nx * ny, des.n_params))
    M[r, s["EXX"].start + K] = 1.0
    M[r, s["EXY"].start + L] = 1.0
    M[r, s["EC0Y"].start] = -Y
    M[nx * ny + r, s["EYX"].start + K] = 1.0
    M[nx * ny + r, s["EYY"].start + L] = 1.0
    if des.yaw == Yaw.ECY:
        M[nx * ny + r, s["ECY"].start + L] = X
    else:
        M[r, s["ECX"].start + K] = -Y
    return M


def error_map_u95(des: SelfCalDesign, err: np.ndarray) -> np.ndarray:
    """(N_x, N_y) expanded uncertainty of the 2D positioning error on the nodes (the paper's Fig. 20), m.

    ``U95 = k sqrt(u_X^2 + u_Y^2)``: the root sum of squares of the standard
    uncertainties of ``E_X,total`` and ``E_Y,total`` (the 2D error's
    magnitude), k = 2, from Monte Carlo errors ``err`` (runs, n_params) in the
    gauge of eqs 16-17 (so 0 at the origin node, eq 16).
    """
    e = np.asarray(err, float) @ error_map_operator(des).T
    u = e.std(axis=0, ddof=1)
    n = u.size // 2
    shape = (len(des.grid.x_m), len(des.grid.y_m))
    return K * np.sqrt(u[:n] ** 2 + u[n:] ** 2).reshape(shape)


def workpiece_components(des: SelfCalDesign, err: np.ndarray) -> dict:
    """U95 of the workpiece ``G`` split into its form and what the datum of eqs 16-17 adds, m.

    The error of ``G`` (``err`` (runs, n_params) Monte Carlo errors) is
    split by least squares into the workpiece's gauge directions
    (:data:`WORKPIECE_GAUGE`: shift, rotation, scale in W, the G rows of
    ``design.N``) and the rest (the form). Returns, per part, the (N_w,)
    expanded uncertainty ``k u`` of that part's contribution at each target,
    and ``"total"``.
    """
    eg = np.asarray(err, float)[:, des.slices["G"]]
    NG = des.N[des.slices["G"]]
    cols = [c for v in WORKPIECE_GAUGE.values() for c in v]
    B = NG[:, cols]
    coef = np.linalg.lstsq(B, eg.T, rcond=None)[0].T  # (runs, 4)
    out = {"total": K * eg.std(axis=0, ddof=1)}
    j = 0
    for name, c in WORKPIECE_GAUGE.items():
        part = coef[:, j:j + len(c)] @ B[:, j:j + len(c)].T
        out[name] = K * part.std(axis=0, ddof=1)
        j += len(c)
    out["form"] = K * (eg - coef @ B.T).std(axis=0, ddof=1)
    return out
