"""Model discovery: what the baseline gets wrong, where, why, and what fixing it gains.

:func:`discover` takes a self-calibration campaign, builds the planar
baseline (Ibaraki et al. eqs 1-18, :func:`core.baseline.planar`) and runs
:func:`discover_baseline`, which works on any :class:`core.baseline.Baseline`
(the MFB volumetric model and ISO 230-2 positioning runs have their own).

What it does, in order, and the statistics behind each step
-----------------------------------------------------------
1. **Outliers**: studentized deleted residuals beyond the Bonferroni bound
   ``t(1 - a / 2n, dof - 1)``, removed one at a time (at a target whose
   touches disagree, the assignment setting aside the touches that read
   more material where it fits as well, :func:`_chips_read_more`, is built
   and off: :data:`OUTLIER_CHIPS_READ_MORE`; the assignment setting aside
   the touches its face's other targets say disagree,
   :func:`_chips_by_likelihood`, is built: :data:`OUTLIER_CHIPS_LIKELIHOOD`); then judged by
   where they fall (:func:`concentration_p`): concentrated in a covariate
   they are a systematic effect and nothing is removed; at random they
   are dust, up to :attr:`Settings.outlier_max_frac_dust` of the rows.
   One set-up's outliers count as one event (a chip stays on the part
   until it is set up again), unless one rigid step of the part within
   that set-up explains them (a fixture slip: structure). Where on the
   part they fall is tested too (:class:`Places`: outliers that share a
   feature or a target, set-up after set-up, more than chips at random
   places would, are that feature's structure).
   Where touches are set aside and a ripple or a bump is named beside
   them, the error-map grid is chosen again by BIC on the touches kept and
   the search runs again on it where it differs (:func:`discover`,
   :data:`GRID_AFTER_OUTLIERS`, :data:`GRID_AFTER_OUTLIERS_CAUSES`).
2. **Noise floor** (catalogue-free): the scatter of repeated touches (pure
   error) after a time trend per set-up (:func:`drift_trend`: a drift
   between drift-check repeats is not noise), the lack-of-fit F test of the
   baseline against the plain pure error, and the gap between held-out and
   in-sample residuals: ``cv_ss / rss`` against its parametric bootstrap
   (the fitted model plus noise at the estimated sigma through the same
   fit and folds, :func:`_cv_gap`). The noise is never below the data's
   own rounding (:func:`roundoff_floor_m`, :data:`ROUNDOFF_ULPS`: exact
   repeats of a noise-free campaign scatter by 0), and a baseline whose
   every residual is within it leaves nothing to find (no outlier, no
   structure, no search: ``none``).
3. **Diagnosis** (catalogue-free, :mod:`core.diagnosis`): for every
   covariate a smooth term is tested against the model (nested F test,
   Holm over the covariates); its debiased explained RMS says how much of
   the residual follows that covariate.
4. **Named causes** (:mod:`core.causes`), greedily, each round the best of
   those that earn it:

   a. significance: nested F test of its columns, Bonferroni over the
      causes and the effective number of trials of its scan (periods,
      positions, sensors);
   b. identifiability: the variance inflation of the cause's combinations
      of columns against the model: those numerically inside it are left
      out (a magnitude that needs them is not reported), and a cause whose
      best combination is inflated more than :attr:`Settings.vif_max` is
      confounded and refused (the principal angle to the model is
      reported);
   c. material cross-validated gain: the held-out mean square must fall by
      at least ``(material_sigma * sigma)^2`` per row, per row the cause's
      columns reach for a cause that books to the workpiece
      (:func:`_support_share`); where the trial of smallest p falls short,
      the cause's other significant forms are judged in turn by every test
      (:data:`HELD_OUT_FALLBACK`; the form so taken is named hedged unless
      its gain clears the materiality times the forms it was chosen among,
      :data:`FALLBACK_SELECTION_COUNTED`); where it is confounded, b, every other
      significant form is judged and, of those that pass, the one of least
      variance inflation beside the model is taken
      (:data:`CONFOUNDED_FALLBACK_LEAST_INFLATION`, on since session 26;
      counted as the fallback's with :data:`CONFOUNDED_SELECTION_COUNTED`,
      built, off;
      the first that passes by p, :data:`CONFOUNDED_FALLBACK`, is off, its
      measured cost, and so are session 25's other variants,
      :data:`CONFOUNDED_FALLBACK_BY_GAIN` and
      :data:`CONFOUNDED_FALLBACK_SAME_COVARIATE`);
   d. plausibility: magnitudes inside the cause's bounds (beyond their
      U95), periods above the Nyquist limit;
   e. the structure lives where the cause says: no smooth function of a
      covariate of another family (time, position, direction, feature:
      :attr:`core.diagnosis.Covariate.family`) explains materially more
      than both the cause's columns and the best smooth function of a
      covariate of its own family (debiased sums of squares); a family
      whose term nests the cause's on the design (:data:`NESTING_FAMILIES`:
      the feature per set-up, for a position cause; or a categorical term
      that holds the cause's columns exactly, :func:`_spans_exactly`: the
      feature per set-up, for the stylus's bending where each feature of a
      set-up is probed at one elevation) refuses it only when
      neither the cause's columns nor the best smooth of its own family
      explain :attr:`Settings.rival_share` of it (the larger of the two,
      as against any other family);
   f. its plainer counter-explanation (:attr:`core.causes.Cause.counter`)
      does not explain as much, or the cause explains something material
      and significant beyond it (step 5's test, made before adoption too, so
      that a plainer cause of the catalogue can win the round: the probe's
      fixed lobes against lobes turned per set-up). Only a plainer
      explanation that is itself a catalogue cause
      (:attr:`core.causes.Cause.counter_cause`) refuses the cause; one
      without a name (a finer error map) leaves it named, ``ambiguous``.

   Among those, the lowest cross-validated mean square wins; within the
   materiality margin of it, the fewest columns (parsimony); a cause
   whose form entered the round and lost it takes the round on another
   of its significant forms that passes every test and predicts the
   held-out set-up better than the winner by the materiality margin (each
   cause enters by its trial of smallest p, in-sample, but the round is
   decided held-out: :data:`ENTRANT_FORM_HELD_OUT`, session 25); and a
   candidate of the same covariate with fewer columns that is one
   explanation with the winner
   under another name (step 8's test: its columns reproduce the winner's
   signal and explain as much, the winner nothing material and
   significant beyond them) takes the round whatever the held-out
   difference, which between two such spans is how each extrapolates to
   the held-out set-up (:func:`_plainer_one_explanation`: lost motion
   against the probe's lobes where every approach is along the normal).
   A penalised cause (:attr:`core.causes.Cause.penalised`: the non-rigid
   field) is fitted with a ridge on its columns, the penalty chosen by
   the held-out mean square (:func:`_evaluate_penalised`); that one fit
   gives its held-out gain, magnitudes, residuals and workpiece, and it is
   not refused as confounded (the penalty decides what the baseline's
   span keeps).
5. **Rival check**: a named cause must explain the structure in its own
   covariate at least :attr:`Settings.rival_share` as well as a
   catalogue-free smooth function of that covariate does (debiased sums of
   squares), or fall short of it by an immaterial amount while itself
   explaining a material amount (where it explains less, the share
   decides: forgiving any immaterial shortfall would keep a cause that
   explains almost nothing of a structure just above materiality); and
   its plainer
   counter-explanation (:attr:`core.causes.Cause.counter`, e.g. a finer
   error map against a non-rigid coupling) must not explain as much; and
   it must explain something material beyond the best trial of its
   :attr:`core.causes.Cause.counter_scan` (a one-off slip of the part in
   one set-up, debiased for the choice among its trials), and stay
   significant beside it (F test, the Bonferroni factor of its adoption)
   unless it explains materially more than the slip.
   Otherwise it was a guess that caught part of something else: it is
   dropped and said so. A cause that fails on the rows left after an
   outlier removal is judged again with the outliers put back (they may
   be its largest residuals): those whose residual it cuts by a quarter
   or more are put back, the others stay set aside; if it stands there
   (judged with the cleaned rows' noise), they were its structure
   (``outliers_put_back`` in its evidence). The causes adopted after a
   dropped cause were searched with it in the model: each is judged again,
   in the order of adoption, by the search's tests (4a-f, its form chosen
   again) beside the causes before it that stay, and refused
   (``judged again without ...`` in ``rejected``) or adopted again
   (``judged_again_without`` in its evidence). With
   :data:`DROPPED_ROUND_REOPENED` (on since session 36) the round the dropped cause
   won is decided again: the search resumes beside the causes that stay,
   every dropped cause kept out (``round_reopened_without`` in the
   evidence of what it adopts), and what it adopts meets this check too.
   With :data:`PAIR_REFUSED_DECIDED` (built, off) a cause dropped beside a
   cause adopted after it, which is then refused when judged again without
   it, is judged once more beside the causes that stay (the search's tests,
   then this check): passing, it is restored (``pair_restored_over`` in its
   evidence) and the refused cause kept out of every round after.
6. **Unexplained**: first a penalised named cause's ridge is chosen again
   over its grid in the model as it now stands (its rows and the causes
   beside it final: :func:`_penalties_rechosen`, session 20); where it
   moved, the gates that depend on the ridge are made again there (the
   held-out gain against materiality, the bounds: :func:`_rechosen_gate`,
   session 21) and a cause that fails is refused, the causes after it
   judged again without it (with :data:`RECHOSEN_ROUND_REOPENED`, built,
   off, the round it won is decided again as a dropped cause's is). A
   refusal made beside a cause the final model does not hold says so in
   ``rejected`` (:data:`REFUSALS_BESIDE_DROPPED_MARKED`). Then, if
   structure remains (diagnosis, lack of fit or CV gap
   significant and material), the cause list gains ``unexplained`` with
   the diagnosis; a penalised smooth term in the strongest covariate
   (P-spline, penalty by cross-validation) is fitted and kept when its
   held-out gain is material, reported as unnamed.
7. **Estimates**: the estimand (the workpiece) of the baseline and of the
   extended model with U95 (k = 2, sigma from each model's residuals),
   null where the design cannot identify it; every magnitude with its U95
   (delta method through the covariance of the cause's coefficients and
   nonlinear parameters). Beside an unnamed smooth (no physics: how the
   unknown effect splits between machine and part is the smooth's form),
   the workpiece shift the smooth makes is tested against its own scatter
   (Hausman) and, when real, carried in the extended U95
   (:func:`_unnamed_shift`); beside a penalised named cause likewise (its
   penalty, not the data, splits what the baseline's span holds). A
   penalised cause's magnitudes take their U95 from a parametric
   bootstrap with the ridge chosen again (:func:`_penalised_bootstrap`;
   the penalised covariance ``s^2 (E^T E + P)^-1`` of :func:`_penalised_fit`
   by the delta method where no folds are given), and a cause beside it is
   fitted with its columns penalised in the nuisance (session 16). A named
   cause beside an unnamed smooth has its magnitudes fitted beside the
   smooth's columns too, with its penalty, the smooth's shift of them
   carried in their U95 where real (:func:`_beside_smooth`, session 20).
   A named cause whose form has a direction inflated beyond ``vif_max``
   is read in its other determined passing forms too, the largest real
   workpiece shift carried in the extended U95 (:data:`FORM_SHIFT_CARRIED`,
   session 28).
8. **Confidence** (each finding's ``confidence``, ``named`` or
   ``ambiguous`` with ``confidence_reason``): ``named`` says the name holds
   against the alternatives the engine can test. A named cause: no smooth
   term in a covariate of another family reproduces its signal, nor
   explains materially more while reproducing half of it; no plainer
   explanation without a name explains as much (step 4f); no other
   catalogue cause's fixed columns (any of its few fixed layouts: a
   drift's degrees, one per temperature sensor) reproduce its signal and
   explain as much while it explains nothing material and significant
   beyond them (:func:`_cause_alternatives`: lost motion and lobing
   when every touch approaches along the normal; a drift and a temperature
   that follows the clock; the other cause is then listed in
   ``ambiguous_with``); its magnitudes are determined on the design (a
   cause significant and earning its gain whose plausibility check cannot
   be made because its magnitudes are not determined,
   :class:`core.causes.Undetermined`, is named ``ambiguous``, and its
   workpiece shift is tested and carried as an unnamed smooth's); a gradual cause (:attr:`core.causes.Cause.gradual`)
   is not matched by a one-off event or by the probe's size changing with
   time (:func:`_time_alternatives`); a richer catalogue cause that nests
   it (:attr:`core.causes.Cause.richer`: lobes turned per set-up for fixed
   lobes) is neither significant beyond it by its own F test nor left
   possible by the design (:func:`core.causes.turned_lobes`: fixed lobes
   are confident only where a turn of the fitted lobes would have shown,
   and the data favour them by odds of 1 / alpha: :data:`RICHER_NEEDS_ODDS`);
   no unnamed smooth of its own covariate's family was adopted beside it
   (step 6 keeps a cause beside such a smooth as its refinement; the
   smooth's material held-out gain says the covariate holds a structure
   of a form the cause lacks: gen_a thermal_bending 1322 and 1340,
   ``part_change`` taking one feature of a bending that moves them all,
   session 18)
   (a rule
   "every combination of its columns inflated at most vif_max" was
   measured and withdrawn: on fresh seeds it flagged 20-23 % more right
   names and no wrong one; docs/discovery.md); and the extended model's
   residuals do not scatter significantly more within repeats than overall
   by at least what the cause explains (:func:`_repeats_beyond_residual`:
   a conservative one-sided F statistic against the whole residual, at a
   nominal alpha_family whose real level is design-dependent and far
   below it; designed on one campaign, gen_a reseat_hysteresis 1609).
   Outliers: at least
   two independent events, falling at random by the concentration test at
   the overall :attr:`Settings.alpha` (one event cannot tell a chip from
   an intermittent mechanism), and, two or more of them on a planar
   campaign, residuals that do not follow the turn of the approach taken
   relative to their target's other touches (:func:`centred_turn_p` at
   ``alpha_family``: a re-seat a target's parameter half absorbs), nor the
   sign of approach along X or Y (:func:`approach_sign_p` at
   ``alpha_family``: the lost motion's column less its target's mean, or
   the touches whose approach moves an axis least, where a lost motion's
   state is the one earlier moves left; then ambiguous with ``reversal``;
   gen_a reversal, session 20); nor, by BIC, one column of structure (a
   target's time, the reversed approach) explain them as well as one free
   value per outlier does (:func:`outliers_structure`,
   :data:`OUTLIERS_STRUCTURE_HEDGED`, session 33). Three
   rules beside the findings (session 16) only move such a flag: outliers
   that lead beside structure left unnamed are not confidently dust (the
   largest residuals of a misfit sit where it peaks; :func:`_ordered`); a
   named cause smaller than outliers whose own tests say mechanism is
   ambiguous (:func:`_doubt_beside_gathered_outliers`); and a named cause
   beside an unexplained noise excess whose rival check read nothing (its
   rival debiased to zero by that noise) is ambiguous
   (:func:`_doubt_beside_noise_excess`). A name reported ``ambiguous`` is the best
   the catalogue offers, not a claim that the mechanism is known.
9. **Order**: the findings best first, the first the report's cause
   (:func:`_ordered`): the systematic ones by what they explain, the
   outliers after them unless they are material and beside them is only
   unnamed structure that explains less than they carry, with no noise
   excess; outliers leading beside such structure keep their place and
   lose their confidence (step 8); so do outliers beside a
   ``local_scale_defect`` that a smooth error map explains as well and
   that cuts none of their residuals, where they carry more than all
   beside them (:data:`OUTLIERS_LEAD_BESIDE_SMOOTH_DEFECT`, session 29).

Family-wise false-alarm rate: :attr:`Settings.alpha`, split equally over
the four families of tests (lack of fit, CV gap, diagnosis, named causes).

Cross-validation: leave one group out (set-ups for the planar baseline),
a prediction for an unseen group only along part of the model. Every
direction of the model's column space is predicted from the other groups'
rows when they see at least :attr:`Settings.cv_seen` of it (its training
share, a cosine: a property of the column space, not of its columns), by
exact least squares; the others, and the held-out group's own columns (its
C-axis errors, targets seen only there), are refitted on the held-out group
(leave one row out): along those (about a quarter of the baseline's
directions per fold on the simulator's four-set-up cross pocket) the figure
is a within-group leave-one-row-out error, which costs power against global
effects and depends on the threshold (docs/discovery.md). The extension
columns are fitted on their part outside the baseline's span by a second
threshold (:attr:`Settings.cv_seen_extension`, on ``lambda``, the squared
share): ``lambda >= 0.01`` predicted, ``lambda < 1e-10`` the held-out
group's own, in between neither (:class:`Folds`: a known discontinuity);
the same for every model compared, so the held-out residuals do not change
when the same span is reparametrised, the campaign moved or its set-ups
reordered, and the baseline's own fitted field predicts itself exactly (no
extrapolation bias; not so along an extension's direction in the band). A long planar log's design (a
:class:`core.lsq.BlockDesign`) is never formed rows by parameters: its
targets are eliminated (means per target), the same rule acts on the
held-out group's targets and the machine's columns beside them
(:class:`Folds`' ``"blocks"`` mode) and the workpiece is solved from the
normal matrix.
"""

from __future__ import annotations

import contextvars
import copy
import dataclasses
import functools
import hashlib
import itertools
import re
import weakref
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sps
from scipy import integrate, optimize, special, stats

from . import baseline as bl_mod
from . import causes as causes_mod
from . import lsq as lsq_mod
from . import selfcal
from .baseline import Baseline
from .diagnosis import (IN_SPAN, CvGap, close_pair_scatter, cv_gap, diagnose, fmt_p, lack_of_fit, nested_f,
                        nested_f_batch, new_basis, nested_f_trials, orth, release_projections, replicate_scatter, separated_groups, StepTrials, straddled_groups, take_rows,
                        term_bases, tied, trials_take,
                        extends, _batch_tests, _first_largest, _nested_f_ss)
from .exceptions import ConfigError, IdentifiabilityError, counted
from .lsq import Basis, BlockDesign, DiagLowRank, _dense, group_sums, leverage, orth_of
from .memo import Memo, kept_on
from .touches import Touches
from .units import MM, UM


#: Format of :meth:`Discovery.to_report` (what ``vmt discover --json`` writes).
REPORT_FORMAT = "vmt-discover/1"
#: Singular value (columns normalised, outside the model) below which a
#: direction of a cause's columns counts as unseen (variance inflation 1e4:
#: a hundredfold loss of precision; its magnitudes are not reported).
WEAK_SV = 1e-2
#: Leverage within its group above which a row is the only support of one of
#: the group's own columns (it cannot be predicted; left out of the CV).
OWN_LEVERAGE = 1e-3

#: Families of tests sharing the false-alarm rate (Bonferroni split).
FAMILIES = ("lack_of_fit", "cv_gap", "diagnosis", "causes")


@dataclass(frozen=True)
class Settings:
    """Decision thresholds of discovery (one documented place).

    Attributes
    ----------
    alpha : float
        Family-wise false-alarm rate of "there is structure", split
        equally over :data:`FAMILIES`. 0.01: the aim is at most 5 % false
        alarms on effect-free campaigns; the rate is an upper bound under
        Gaussian noise, and materiality cuts it further.
    material_sigma : float
        Structure whose RMS per row is below ``material_sigma`` times the
        noise is immaterial: never a finding, never "structure". 0.3
        (a tenth of the noise variance): an effect that small biases a
        target's workpiece estimate, averaged over its set-ups, by less
        than half its own standard uncertainty ``sigma / sqrt(N_c)`` for
        ``N_c <= 3`` set-ups, and the cross-validated mean square of
        effect-free campaigns scatters by a few hundredths of the noise
        variance (the 0.98-0.997 CV ratios of the false alarms that
        motivated this threshold).
    vif_max : float
        A cause whose best-determined combination of columns is inflated
        more than this against the model is confounded with it and refused:
        100, ten times less certain than if it were orthogonal to the model
        (principal angle below ~6 deg). Combinations inflated beyond
        ``1 / WEAK_SV^2`` are left out of every cause.
    rival_share : float
        A named cause must explain at least this share of what a smooth
        function of its covariate explains (debiased): 0.8.
    outlier_alpha : float
        Family-wise rate of the outlier test.
    outlier_max_frac : float
        At most this fraction of rows may be outliers when nothing says
        where they fall; if the test wants more, they are structure, not
        dust, and none is removed.
    outlier_max_frac_dust : float
        The same for outliers that fall at random over every covariate the
        log holds (the concentration test of :func:`find_outliers`): 0.05.
        Chips and dust hit touches at random, and a short campaign in a
        dirty shop may see several (5 of 140 touches is 3.6 %); outliers
        concentrated in a covariate are structure at any count, and more
        than 5 % of the touches is no chip.
    outlier_events : str
        What one piece of dust corrupts together, for the concentration
        test (planar baselines; others count each row): ``"target"`` (the
        touches of one target within one set-up) or ``"setup"`` (every
        touch of one set-up: a chip on the part stays until the part is
        set up again, so chips on several targets of one set-up are one
        dirty set-up, side by side in time). ``"setup"`` also lets
        outliers confined to one set-up (a fixture slip's touches after
        the slip) pass the test as one event; ``"setup_slip"`` counts
        per set-up too, but a set-up's outliers are no dust when the best
        one-off rigid step of the part within that set-up
        (:func:`core.causes.fixture_slip`), adopted on every row, leaves
        none of them an outlier (they were the slip's touches) and either
        they outnumber its parameters or the set-up's other touches see
        it (:func:`_slip_explains`); the outliers of set-ups that no step
        explains stay dust (:data:`SLIP_VETO_PER_EVENT`): the
        default, measured against the other two on fresh seeds
        (docs/discovery.md).
    grid_steps_mm : tuple of float
        Error-map grid steps tried for the planar baseline.
    select_grid : bool
        Choose the grid by BIC (else the finest identifiable).
    max_findings : int
        Named causes adopted at most.
    cv_draws : int
        Monte Carlo draws of the CV-gap null distribution (its mean and
        spread; the p-value is the tail of a chi-square scaled to them).
    cv_seen : float
        Training share (cosine: ``|s_tr| / |s|``) from which a direction
        ``s`` of the model's column space is predicted from a fold's
        training rows; below it the held-out group's own rows fit it
        (:class:`Folds`). ``1/sqrt(2)``: a direction is predicted from the
        rows that see more of it (the training estimate's variance
        ``sigma^2 / c^2`` is then at most the held-out rows' own
        ``sigma^2 / (1 - c^2)``), so no held-out residual amplifies the
        noise more than twofold, and the rule depends on the column space
        only, not on how its columns are scaled or mixed. A variance
        argument only, the value kept on development-seed outcomes; the CV
        figures depend on it (baseline held-out RMS on the simulator's part
        change 1000: 1.03 / 0.84 / 0.41 um at 0.3 / 1/sqrt(2) / 0.9), and
        the directions below it are the held-out group's own
        (within-group leave-one-row-out, no prediction; docs/discovery.md).
    cv_seen_extension : float
        The same share for an extension's directions outside the baseline
        (their training share beyond the baseline's training image): 0.1,
        noise amplified at most 99 times along one direction. Below it a
        direction predicts nothing on the held-out rows (the extension is
        on trial: no credit, no loss); one no training row sees at all
        (``lambda < 1e-10``) is the held-out group's own, refitted on its
        rows: a discontinuity (:class:`Folds`). Measured: 1/sqrt(2) here left the
        synthetic thermal drift and part change unnamed, 0.3 named a
        pre-travel settling ``thermal_drift`` (docs/discovery.md).
    shortlist : int
        Trials of a scan evaluated exactly after the periodogram-like
        pre-screen.
    noise_max_um : float
        The largest probing noise (1 sigma, um) a touch-trigger probe on a
        machine tool gives: 1.5 um, three times a kinematic probe's stated
        unidirectional repeatability (2 sigma <= 1 um) with the machine's
        own repeatability added. A planar campaign whose noise estimate
        (repeats, else residuals) is larger carries structure no covariate
        follows (a seat that settles one way on some touches, a loose
        stylus): never ``none``. Positioning runs and the whitened MFB
        points have their own noise and are not judged by it.
    """

    alpha: float = 0.01
    material_sigma: float = 0.3
    vif_max: float = 100.0
    rival_share: float = 0.8
    outlier_alpha: float = 0.001
    outlier_max_frac: float = 0.02
    outlier_max_frac_dust: float = 0.05
    outlier_events: str = "setup_slip"
    grid_steps_mm: tuple = (22.0, 30.0, 40.0, 55.0, 80.0)
    select_grid: bool = True
    max_findings: int = 3
    cv_draws: int = 99
    cv_seen: float = float(np.sqrt(0.5))
    cv_seen_extension: float = 0.1
    shortlist: int = 8
    noise_max_um: float = 1.5

    @property
    def alpha_family(self) -> float:
        return self.alpha / len(FAMILIES)


# ---------------------------------------------------------------------------
# cross-validation
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class _Fold:
    """One held-out group of :class:`Folds` (internal).

    ``tr``, ``te``: training and held-out rows. ``U`` (n_te, r): the left
    singular vectors of the held-out rows ``Q_te`` of the model's
    orthonormal basis (the eigenvectors of the hat matrix's held-out block
    ``H_te = Q_te Q_te^T``; ``r = min(n_te, p)``, less the largest cluster
    of equal shares of a square fold, kept implicit: ``m``), ordered by ``c2`` (r,),
    the training share squared of the direction each stands for
    (``1 - s^2``, ``s`` its singular value; 1 where ``Q_te`` reaches no
    direction), largest first: the first ``k`` (``c2 >= seen^2``) are
    predicted, the first ``f`` (``c2 > SEEN_ZERO^2``) are in the training
    image, the others from ``k`` on are the held-out group's own (``Qo``).
    ``C`` (p', f - k): the own directions the training rows see, ``v`` up
    to scale over the basis columns ``cols`` the held-out rows reach (None:
    all, in order; ``C`` None when there are none). Their training parts
    ``Q_tr v`` are never formed but for directions with ``c2`` below
    :data:`OWN_SEEN_DIRECT` (only their products with the data are needed,
    :meth:`Folds._own_seen`), never kept: kept, they grow as rows x rows
    when most targets are seen mostly by one set-up.

    ``m`` predicted directions sharing one training share ``c2m`` (a cluster
    of equal eigenvalues of ``H_te``, :data:`FOLD_CLUSTER_TOL`) are not kept
    as columns when ``U`` would be square (``n_te <= p'``): they span the
    complement of the kept columns, so every product along them is a
    projection ``I - U U^T`` (:meth:`Folds.residuals`). A long log whose
    targets are touched once per set-up has most of its directions there
    (``H_te = I / set-ups + D D^T``): all but at most the machine's 326
    columns of 1,000 per fold on the benchmark's 1e5-row log (at most 2.6 of
    8 MB kept). ``U``, ``c2``, ``k``, ``f``
    describe the kept columns. The training rows ``tr`` are the held-out
    rows' complement in ``range(n)``, formed when asked for (kept, they
    were rows x 8 bytes per fold: 79 MB at 1e5 rows).
    """

    n: int
    te: np.ndarray
    U: np.ndarray
    c2: np.ndarray
    k: int
    f: int
    C: np.ndarray | None = None
    cols: np.ndarray | None = None
    m: int = 0
    c2m: float = 1.0

    @property
    def tr(self) -> np.ndarray:
        keep = np.ones(self.n, dtype=bool)
        keep[self.te] = False
        return np.flatnonzero(keep)

    @property
    def Qo(self) -> np.ndarray:
        return self.U[:, self.k:]

    @property
    def c(self) -> np.ndarray:
        """The training shares (cosines) of the directions the training rows see, largest first."""
        return np.sqrt(self.c2[:self.f])


#: Training share (cosine) below which a direction of the model counts as unseen by a fold's training rows:
#: they hold less than 1e-10 of its squared norm (the eigenvalues of the training Gram are exact to about 1e-16).
SEEN_ZERO = 1e-5
#: Squared shares within this of a threshold count as reaching it: designs put directions exactly at simple
#: fractions (a target probed in two of four set-ups is half seen, c^2 = 1/2 = cv_seen^2), which rounding
#: (about 1e-15) must not split two ways. (Absolute: squared shares lie in 0..1; the other ties, core.diagnosis'
#: ``TIE_RTOL`` and ``ARGMAX_TIE_RTOL``, are relative to the size of what they compare.)
SEEN_TIE = 1e-9
#: An own direction the training rows see with c^2 below this takes its training part from those rows
#: (Folds._own_seen): |Q_tr v|^2 as a difference carries eps / c^2 relative error, which must stay well
#: below SEEN_ZERO^2 (the own / band decision on the extension's training Gram): at 1e-6 a reviewer saw
#: that Gram's eigenvalues moved by 3e-10 (above 1e-10); at 1e-4 by less than 1e-13.
OWN_SEEN_DIRECT = 1e-4
#: Predicted directions of a fold whose squared training shares lie within this of each other form one cluster
#: (_Fold.m): treated as sharing their mean share, 1 / c2 moves by at most 4e-13 absolute (2e-13 relative,
#: c2 >= 1/2), and the outputs by that times the fold's conditioning (a reviewer's ill-conditioned penalised
#: fold, shares 1e-12 apart merged: 2.4e-5 against lstsq where keeping them apart gave 9.3e-8, so the
#: tolerance is no looser than needed). eigh's eigenvalues of the hat block (norm at most 1) are exact to
#: about 1e-15 (spreads of exact multiple eigenvalues measured at most 1.9e-15 on the demo, gen_a, gen_b and
#: 1e4-row logs), so an exact multiple eigenvalue of the design (equal counts per target) is one cluster,
#: with a margin of about 50.
FOLD_CLUSTER_TOL = 1e-13
#: The fewest directions a cluster must hold to be kept implicit (a projection) rather than as columns.
FOLD_CLUSTER_MIN = 2


#: A held-out set-up's rows of a block basis (:meth:`Folds._q_rows`) are formed dense while their indicator part
#: is at most this many bytes (every stored campaign's and the bench's 1e5-row log's: 8 MB a set-up); larger, they
#: are kept sparse (a set-up of the 1e6-row log: 10,000 rows by 10,000 targets). Small ones stay dense because the
#: sparse products round differently: with this at 0 (every set-up sparse) the 16 identity campaigns forced through
#: the block design kept every decision and text, but gen_a knock 1's smooth cv_gain_um2 moved 7.6e-9 relative
#: (a difference of held-out mean squares from a penalised system; the identity test measures 1.6e-8 for it across
#: BLAS kernels), so the stored campaigns' reports stay those of the dense products.
FOLD_ROWS_DENSE_BYTES = 64 << 20


def _largest_cluster(c2: np.ndarray) -> tuple[int, int]:
    """``(a, b)``: the longest run ``c2[a:b]`` of a sorted array whose values lie within :data:`FOLD_CLUSTER_TOL`
    of each other (the first of equal length)."""
    best, a = (0, 0), 0
    for i in range(1, len(c2) + 1):
        if i == len(c2) or abs(c2[a] - c2[i]) > FOLD_CLUSTER_TOL:
            if i - a > best[1] - best[0]:
                best = (a, i)
            a = i
    return best


#: :meth:`Folds.residuals` keeps the answers of its last this many calls with one column of data ...
FOLDS_MEMO_CALLS = 4
#: ... whose data, extension and penalty take at most this many bytes (copies kept: the demo's are 45 KB; a
#: 1e5-row log's with four extension columns 4 MB, more columns are not kept).
FOLDS_MEMO_BYTES = 4 << 20


def _same_array(a, b) -> bool:
    """Both None, or arrays of one shape and dtype with equal values (a kept input against a new one)."""
    if a is None or b is None:
        return a is None and b is None
    b = np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b)


class Folds:
    """Leave-one-group-out cross-validation of linear models over one design (rows fixed).

    Every decision is made on the model's column space, not on its columns
    (so the same span, reparametrised, scaled or mixed, gives the same
    held-out residuals to rounding). ``Q`` is an orthonormal basis of the
    design's column space over the model's rows. For a held-out group, each
    direction ``s`` of that space has a training share ``c = |s_tr| / |s|``
    (the cosines of the principal angles between the column space and the
    training rows' coordinates: the eigenvalues of ``Q_tr^T Q_tr`` are
    ``c^2``). A direction with ``c >= seen`` is predicted from the training
    rows by exact least squares (its coefficient ``u^T y_tr / c``, its noise
    amplified on the held-out rows by ``(1 - c^2) / c^2``, at most 1 at the
    default ``seen = 1/sqrt(2)``); one with ``c < seen`` is seen better by
    the held-out group itself and is the group's own: fitted on its other
    rows (leave-one-row-out), as a set-up's own columns (its C-axis errors,
    targets only it sees) always were. Nothing of the baseline is truncated
    to zero: the held-out prediction (or own refit) of any element of the
    baseline's column space is exact, so the baseline's own fitted field
    adds nothing to the held-out residuals (no extrapolation bias for the
    CV-gap null to miss).

    What the held-out residuals estimate therefore differs by direction:
    along the predicted ones, the error of a prediction for an unseen group;
    along the own ones (``c < seen``; about a quarter of the baseline's
    directions per fold on the simulator's four-set-up cross pocket), a
    within-group leave-one-row-out error, the same for every model compared,
    so an effect's part along them on the held-out group earns no held-out
    gain (power lost against global effects) and the figures depend on
    ``seen`` (docs/discovery.md). ``1/sqrt(2)`` rests on the variance
    argument above only and was kept on development-seed outcomes.

    Extension columns ``E`` (not penalised) are replaced by an orthonormal
    basis ``F`` of their part outside the column space (the model's span is
    then ``span(Q) + span(F)``); per fold ``F``'s training part outside the
    training image of ``Q`` has Gram eigenvalues ``lambda`` (its training
    share beyond the baseline, squared, between 0 and 1), and a second
    threshold applies, with three outcomes: ``lambda >= seen_extension^2``
    fitted on the training rows (predicted); ``lambda < SEEN_ZERO^2 = 1e-10``
    the held-out group's own (refitted on its rows, leave one row out);
    in between neither: its coefficient is zero on the held-out rows, which
    keep what the data have along it. The rule jumps at 1e-10 (a
    per-set-up term exactly zero elsewhere is own, the same with a 1e-4 leak
    is in the band: held-out gain 4.13 against 0.20 in a toy,
    docs/discovery.md), and along a band direction the model's own fitted
    part is not predicted (the claim above holds for the baseline's column
    space and the extension outside the band). A penalised term (the unnamed
    smooth) is a ridge in its own coefficients, not a span: it is fitted on
    the training rows (columns scaled to unit training norm, the penalty
    scaled with them), its columns that no training row sees being the
    group's own. Columns a penalised call leaves unpenalised (zero rows and
    columns of the penalty: a candidate beside an adopted penalised cause,
    named terms beside the unnamed smooth) follow the unpenalised rule above,
    their kept directions fitted jointly with the ridge's columns; a penalty
    that is zero throughout is no penalty.

    Linear in the observations: :meth:`residuals` takes (n,) or (n, B).
    Computed without refitting (case deletion): the directions ``v`` of a
    fold are the right singular vectors of the held-out rows ``Q_te``
    (``Q_te v = s u``, ``c^2 = 1 - s^2``; every direction ``Q_te`` does not
    reach has ``c = 1``), so a fold keeps the left ones ``U`` only (the
    eigenvectors of the hat matrix's held-out block ``H_te = Q_te Q_te^T``,
    from its eigh when it is the smaller problem, else from the SVD of
    ``Q_te``; a long log probed once per target and set-up from the SVD of
    the basis's dense rows alone, :meth:`_fold_one_touch_per_target`;
    ``n_te x min(n_te, p')`` numbers, ``p'`` the columns the held-out rows reach, less the largest cluster of predicted directions
    sharing one share, kept as the projection on what the others leave:
    :class:`_Fold`), beside the own directions the training rows see a
    little over those ``p'`` columns (``v`` up to scale, at most ``p' x
    min(n_te, p')``; their training products come from ``Q^T V`` less the
    held-out rows' part, no rows x directions array per fold), and
    the held-out residuals follow from the full fit's residuals ``R``:
    along a predicted ``u``, ``u^T R_te / c^2`` (the training rows' fit
    predicted on the held-out rows, ``(I - H_te)^-1`` on those directions);
    outside ``U``, ``R_te``'s own part (for a square fold, less the cluster's
    part ``P R_te / c2m``, ``P`` the projection on what ``U`` leaves). An extension's training Gram outside
    the training image is ``R_X^T R`` less the held-out rows' part by the
    same algebra, an own direction's training products (the few the training
    rows see below ``seen``) from ``Q_tr^T V_tr`` over the held-out rows'
    columns (the training rows' own form where ``c^2 < OWN_SEEN_DIRECT``); a
    penalised extension's (not projected outside the design, so it may be
    small on the training rows, where that difference would cancel) is
    formed from the training rows' products instead. For a
    :class:`core.lsq.BlockDesign` (a long self-calibration log) ``Q_te`` is
    formed over the indicators of the targets the held-out group touches
    and the basis's dense columns only (the other targets are zero on its
    rows). The same rule for every design: exact algebra, rounding apart.
    """

    def __init__(self, A, groups: np.ndarray, seen: float, seen_extension: float | None = None, basis=None):
        """``basis``: ``orth(A)`` already made by the caller (the same numbers: the engine's model basis of
        these rows), not factored again; ignored for a block design (its own basis)."""
        seen_extension = seen if seen_extension is None else seen_extension
        for v in (seen, seen_extension):
            if not 0.0 < v < 1.0:
                raise ConfigError(f"Folds: the training share of a predicted direction must lie in (0, 1), not {v!r}")
        self.n = A.shape[0]
        self.seen = float(seen)
        self.seen_extension = float(seen_extension)
        self.items: list[_Fold] = []
        gs = np.unique(groups)
        if basis is not None and not isinstance(A, BlockDesign) and np.shape(basis)[0] != self.n:
            raise ConfigError(f"Folds: a basis of {np.shape(basis)[0]} rows for a design of {self.n}")
        self.Q = A.basis() if isinstance(A, BlockDesign) else orth(A) if basis is None else basis
        for g in gs:
            te = np.flatnonzero(groups == g)
            if te.size == 0 or te.size == self.n:  # (no held-out rows, or no training rows)
                continue
            self.items.append(self._fold(te))
        if not self.items:
            raise IdentifiabilityError("cross-validation needs at least two groups (set-ups)")
        # the baseline's held-out rows (residuals' count: a row alone supporting an own direction is not one)
        # (``last_predicted``: which rows the last residuals call predicted, ``last_dof`` of them; the
        # others' residuals are exactly 0, but a predicted row's may be too)
        self.last_predicted = np.zeros(self.n, bool)
        for f in self.items:
            self.last_predicted[f.te[np.sum(f.Qo ** 2, axis=1) < 1 - OWN_LEVERAGE] if f.Qo.shape[1] else f.te] = True
        self.last_dof = int(self.last_predicted.sum())
        self.dof = max(self.last_dof, 1)
        self._memo: list = []  # residuals' last answers for one column of data: ((Y, E, penalty), out, dof, predicted)

    def _q_rows(self, te):
        """``Q_te`` (n_te, p'): the held-out rows of the basis over the columns they reach (a block basis: the
        indicators of the ids they touch, then its dense columns; the other indicators are zero on them), and
        where those columns sit among the basis's (None: all of them, in order). A block basis's indicator part
        has one entry a row: formed when it is at most :data:`FOLD_ROWS_DENSE_BYTES`, else the whole is kept
        sparse (CSR; products with it dense, the same to rounding: 800 MB per set-up of the bench's 1e6-row log
        when formed)."""
        Q = self.Q
        if not isinstance(Q, Basis):
            return Q[te], None
        J, jinv = np.unique(Q.ids[te], return_inverse=True)
        cols = np.concatenate([Q.indicator_columns(J), np.arange(Q.k, Q.shape[1])])
        scale = 1.0 / np.sqrt(Q.counts[J][jinv])
        if 8 * te.size * len(J) > FOLD_ROWS_DENSE_BYTES:
            G = sps.csr_matrix((scale, (np.arange(te.size), jinv)), shape=(te.size, len(J)))
            return sps.hstack([G, sps.csr_matrix(Q.dense_rows(te))], format="csr"), cols
        G = np.zeros((te.size, len(J)))
        G[np.arange(te.size), jinv] = scale
        return np.hstack([G, Q.dense_rows(te)]), cols

    def _fold_one_touch_per_target(self, te) -> _Fold | None:
        """:meth:`_fold` of a block basis whose held-out rows each touch their own target, every target with one
        count (a long log probed once per target and set-up), from the SVD of the basis's dense rows ``W``
        (n_te, r) instead of the eigh of ``H_te`` (n_te, n_te); None where that does not hold (:meth:`_fold`).

        There the indicators' part of ``H_te`` is ``delta I`` (``delta = (1 / sqrt(count))^2``, the product eigh
        sees), so ``H_te = delta I + W W^T``: its eigenvectors are ``W``'s left singular vectors (``delta + sv^2``)
        and ``delta`` repeated on what they leave, the largest cluster of equal shares, kept implicit as
        :meth:`_fold` keeps it (the same shares, ``k``, ``f``, cluster and kept columns, to rounding; None,
        so :meth:`_fold`, if the largest cluster is not that one). ``H_te`` and its eigenvectors were n_te^2
        numbers each and n_te^3 work per fold (at 1e6 rows 800 MB and 1e12 flops per set-up), this n_te r^2."""
        Q = self.Q
        if not isinstance(Q, Basis) or Q.U.shape[1] or not Q.k:
            return None
        ids = Q.ids[te]
        J = np.unique(ids)
        cnt = Q.counts[J]
        if J.size != te.size or cnt.min() != cnt.max():
            return None
        W = Q.dense_rows(te)
        Uw, sv, _ = np.linalg.svd(W, full_matrices=False)
        sc = 1.0 / np.sqrt(cnt[0])
        n0 = te.size - sv.size  # the directions W leaves: delta alone
        s2 = np.concatenate([np.full(n0, sc * sc), sc * sc + sv[::-1] ** 2])  # ascending, as eigh's
        c2 = np.clip(1.0 - s2, 0.0, 1.0)
        k = int(np.sum(c2 >= self.seen ** 2 - SEEN_TIE))
        f = int(np.sum(c2 > SEEN_ZERO ** 2))
        a, b = _largest_cluster(c2[:k]) if k else (0, 0)
        if a != 0 or b < n0 or b - a < FOLD_CLUSTER_MIN:
            return None
        m, c2m = b - a, float(np.mean(c2[a:b]))
        U = np.ascontiguousarray(Uw[:, ::-1][:, b - n0:])
        c2, k, f = c2[b:], k - m, f - m
        cols = np.concatenate([Q.indicator_columns(J), np.arange(Q.k, Q.shape[1])])
        C = self._q_rows(te)[0].T @ U[:, k:f] if f > k else None
        return _Fold(self.n, te, U, c2, k, f, C, cols, m, c2m)

    def _fold(self, te) -> _Fold:
        quick = self._fold_one_touch_per_target(te)
        if quick is not None:
            return quick
        Qte, cols = self._q_rows(te)
        Qte = Qte.toarray() if sps.issparse(Qte) else Qte  # (its eigenvectors are n_te^2 numbers anyway)
        if Qte.shape[0] <= Qte.shape[1]:  # the hat block is the smaller problem (a long log's set-up): its eigh
            s2, U = np.linalg.eigh(Qte @ Qte.T)  # s^2 ascending: largest training share first
        else:
            U, sv, _ = np.linalg.svd(Qte, full_matrices=False)
            U, s2 = U[:, ::-1], sv[::-1] ** 2
        c2 = np.clip(1.0 - s2, 0.0, 1.0)
        k = int(np.sum(c2 >= self.seen ** 2 - SEEN_TIE))
        f = int(np.sum(c2 > SEEN_ZERO ** 2))
        m, c2m = 0, 1.0
        if U.shape[1] == U.shape[0] and k:  # square: the largest cluster of predicted directions kept implicit
            a, b = _largest_cluster(c2[:k])
            if b - a >= FOLD_CLUSTER_MIN:
                m, c2m = b - a, float(np.mean(c2[a:b]))
                U, c2 = np.delete(U, np.s_[a:b], axis=1), np.delete(c2, np.s_[a:b])
                k, f = k - m, f - m
        # own directions the training rows see a little: the directions v (Q_te v = s u) up to their scale, over
        # the columns the held-out rows reach (their training products are formed when used: _own_seen)
        C = Qte.T @ U[:, k:f] if f > k else None
        return _Fold(self.n, te, np.ascontiguousarray(U), c2, k, f, C, cols, m, c2m)

    def _own_seen(self, f: _Fold, Qte: np.ndarray, D: np.ndarray, V: np.ndarray) -> np.ndarray:
        """(f - k, b') ``Z^T V_tr``, ``Z`` the unit training parts ``Q_tr v / |Q_tr v|`` of the fold's own
        directions the training rows see, from ``D = Q_tr^T V_tr`` over the columns the held-out rows reach
        (``Qte`` those rows there): ``C^T D / |Q_tr v|`` with ``|Q_tr v|^2 = |C|^2 - |Q_te C|^2`` (``Q``
        orthonormal), no rows x directions product per fold and call. That difference cancels (error about
        eps / c^2 relative), so a direction with ``c^2 < OWN_SEEN_DIRECT`` takes its training part from the
        training rows themselves, normalised by its own norm (``1 - s^2`` is exact to 1e-16 absolute only)."""
        C = f.C
        n2 = np.sum(C ** 2, axis=0) - np.sum((Qte @ C) ** 2, axis=0)
        low = f.c2[f.k:f.k + C.shape[1]] < OWN_SEEN_DIRECT
        out = (C.T @ D) / np.sqrt(np.where(low, 1.0, n2))[:, None]
        if low.any():
            Cl = C[:, low]
            if f.cols is not None:
                Cl = np.zeros((self.Q.shape[1], Cl.shape[1]))
                Cl[f.cols] = C[:, low]
            Z = (self.Q @ Cl)[f.tr]
            out[low] = (Z / np.linalg.norm(Z, axis=0)).T @ V[f.tr]
        return out

    def outside(self, E: np.ndarray) -> np.ndarray:
        """Orthonormal basis (n, k') of ``E``'s part outside the design's column space."""
        return new_basis(self.Q, E)

    def _outside_image(self, f: _Fold, RXR: np.ndarray, R_te: np.ndarray, Gam: np.ndarray, V: np.ndarray,
                       QtV: np.ndarray, b: int) -> np.ndarray:
        """``X_tr^T (I - P) V_tr`` (kx, b + kx), ``P`` the projection on the fold's training image, ``V = [Y, X]``.

        From the full fit (case deletion): ``R_X^T R_V`` over every row (``RXR``) less the held-out rows' part,
        where ``R_te`` are the full fit's held-out residuals and ``Gam = U^T R_te``: outside ``U`` as they are,
        along a predicted direction divided by ``c2``. Along an own direction (``beta = u^T V_te``, ``alpha =
        (beta - u^T R_te) / s`` its coefficient in the full fit) ``alpha alpha' - beta beta'``, less its part in
        the training image if the training rows see it (``z z'``, ``z`` the training rows' coordinates on its
        unit training part, by :meth:`_own_seen` from ``Q^T V`` less the held-out rows' part: ``u^T R_te / c2``
        would carry R's rounding divided by ``c``). ``QtV = Q^T V`` (every row).
        """
        Gx, k = Gam[:, b:], f.k
        out = RXR - R_te[:, b:].T @ R_te + Gx.T @ Gam - (Gx[:k] / f.c2[:k, None]).T @ Gam[:k]
        if f.m:  # the implicit cluster (predicted, c2m): R_X^T P R (1 - 1 / c2m), P = I - U U^T its projection
            out = out + (1.0 - 1.0 / f.c2m) * (R_te[:, b:].T @ (R_te - f.U @ Gam))
        if k < f.U.shape[1]:
            beta = f.U[:, k:].T @ V[f.te]
            alpha = (beta - Gam[k:]) / np.sqrt(1.0 - f.c2[k:])[:, None]
            out = out + alpha[:, b:].T @ alpha - beta[:, b:].T @ beta
            if f.C is not None:
                Qte, cols = self._q_rows(f.te)
                z = self._own_seen(f, Qte, (QtV if cols is None else QtV[cols]) - Qte.T @ V[f.te], V)
                out = out - z[:, b:].T @ z
        return out

    def _outside_image_direct(self, f: _Fold, X: np.ndarray, V: np.ndarray, QtY: np.ndarray, b: int) -> np.ndarray:
        """``X_tr^T (I - P) V_tr`` as :meth:`_outside_image`, from the training rows themselves: ``X_tr^T V_tr``
        less ``a^T M d`` (``a = Q_tr^T X_tr`` from ``X`` with the held-out rows zeroed, ``d = Q_tr^T V_tr``, ``M``
        the pseudo-inverse of ``Q_tr^T Q_tr = I - Q_te^T Q_te`` on the training image: ``1 / c2`` along a
        predicted direction; an own direction's training products by :meth:`_own_seen` from ``[d, a]``).
        For a penalised extension, which is not projected outside the design first: one mostly inside the
        held-out group is small on the training rows, and the full fit less the held-out rows' part cancels
        (a review: relative error 7e-7 where refitting gives 3e-14). ``QtY = Q^T Y`` (every row)."""
        te, k = f.te, f.k
        Xz = X.copy()
        Xz[te] = 0.0
        a = self.Q.T @ Xz  # (p, kx) the training rows' own products: small when X is there
        Qte, cols = self._q_rows(te)
        ac = a if cols is None else a[cols]
        QA = Qte @ ac  # Q_te a
        dY = (QtY if cols is None else QtY[cols]) - Qte.T @ V[te, :b]  # Q_tr^T Y_tr over the held-out rows' columns
        # a^T d; then along each direction w = Q_te^T u = s v of the fold: + w w^T / c2 (predicted: M's 1 / c2 - 1 =
        # s^2 / c2), - w w^T / s^2 (own: out of M, the training part of a seen one added back from the rows below)
        ad = np.hstack([a.T @ QtY - QA.T @ V[te, :b], a.T @ a])
        Ga = f.U.T @ QA
        Gd = np.hstack([f.U.T @ (Qte @ dY), Ga])
        wt = np.concatenate([1.0 / f.c2[:k], -1.0 / np.maximum(1.0 - f.c2[k:], 1e-300)])
        P = ad + (Ga * wt[:, None]).T @ Gd
        if f.m:  # the implicit cluster (predicted): (Q_te a)^T P [Q_te dY, Q_te a] / c2m, P = I - U U^T
            Z = np.hstack([Qte @ dY, QA])
            P = P + QA.T @ (Z - f.U @ Gd) / f.c2m
        if f.C is not None:
            zV = self._own_seen(f, Qte, np.hstack([dY, ac]), V)  # Q_tr^T V_tr: [dY, a] over those columns
            P = P + zV[:, b:].T @ zV
        return Xz.T @ V - P  # X_tr^T V_tr: the held-out rows are exact zeros in Xz (no copy of V's training rows)

    def residuals(self, Y: np.ndarray, E: np.ndarray | None = None, penalty: np.ndarray | None = None) -> np.ndarray:
        """:meth:`_residuals`, its last few answers for one column of data kept (:data:`FOLDS_MEMO_BYTES`).

        The engine asks the same question more than once: the baseline's held-out residuals for its mean square
        and again for the CV gap; the adopted model's for the gap, its held-out mean square and the report's
        per-set-up sums (the demo: 4 of its 10 calls, 4.1 of 17.6 ms). A call whose data, extension and penalty
        equal a kept call's, value for value, takes that call's answer (a copy) and its ``last_predicted`` and
        ``last_dof``: the same computation on the same operands, so the same numbers bit for bit.
        """
        Y = np.asarray(Y)
        key = None
        if Y.ndim == 1:
            parts = [Y] + [np.asarray(a) for a in (E, penalty) if a is not None]
            if sum(a.nbytes for a in parts) <= FOLDS_MEMO_BYTES:
                key = (Y, E, penalty)
                for (Yk, Ek, Pk), out, dof, pred in self._memo:
                    if _same_array(Yk, Y) and _same_array(Ek, E) and _same_array(Pk, penalty):
                        self.last_dof, self.last_predicted = dof, pred.copy()
                        return out.copy()
        out = self._residuals(Y, E, penalty)
        if key is not None:
            self._memo.append((tuple(None if a is None else np.array(a, copy=True) for a in key), out.copy(),
                               self.last_dof, self.last_predicted.copy()))
            del self._memo[:-FOLDS_MEMO_CALLS]
        return out

    def _residuals(self, Y: np.ndarray, E: np.ndarray | None = None, penalty: np.ndarray | None = None) -> np.ndarray:
        """Held-out residuals of the baseline (plus extension columns ``E`` (n, k)).

        ``penalty`` (k, k): a ridge penalty on the extension's coefficients
        (a penalised smooth term), symmetric non-negative (else ValueError);
        its columns with zero penalty follow the unpenalised rule.

        From the full fit's residuals ``R`` by the hat matrix's held-out
        block (case deletion): along a predicted direction ``u`` (a column of
        the fold's ``U``), the held-out residual of the training rows' fit is
        ``u^T R_te / c2`` (``(I - H_te)^-1 R_te`` restricted to the predicted
        directions; for a square fold, the largest cluster of equal shares
        ``c2m`` is the projection ``P`` on what ``U`` leaves: ``P R_te / c2m``);
        outside those it is ``R_te``'s (the held-out rows' part
        no direction of the model reaches); along the own directions it is
        the data's, then fitted on the group's other rows. The same algebra
        as refitting on the training rows, with nothing (rows x directions)
        kept per fold beyond ``U``.

        Sets ``last_predicted`` (n,) (the rows predicted: the others' residuals
        are 0, a row alone supporting a direction of the held-out set-up,
        the extension's unseen columns included; a predicted row's may be 0
        too) and ``last_dof`` (their count): state of this call, valid until
        the next ``residuals`` or ``mse`` call on the same object.
        """
        one = Y.ndim == 1
        Y2 = Y[:, None] if one else Y
        out = np.zeros_like(Y2, dtype=float)
        self.last_dof = 0
        self.last_predicted = np.zeros(self.n, bool)
        has_e = E is not None and E.shape[1] > 0
        ku = 0  # a penalised call's unpenalised columns: the last ku of X, their part outside the design
        if has_e and penalty is not None:
            penalty = np.asarray(penalty, dtype=float)
            if penalty.shape != (E.shape[1],) * 2 or not np.all(np.isfinite(penalty)):
                raise ValueError(f"Folds: penalty {penalty.shape} for {E.shape[1]} extension columns, or not finite")
            # non-negative relative to the penalty's own size (a ridge on columns in metres is ~1e-12 and below:
            # an absolute floor would pass any such matrix); a column with no penalty of its own (a zero diagonal)
            # coupled to another is not non-negative either, whatever the rounding of the eigenvalues says
            free = np.diag(penalty) == 0
            if not np.allclose(penalty, penalty.T) or np.any(penalty[free] != 0) or np.any(penalty[:, free] != 0) or \
                    np.linalg.eigvalsh((penalty + penalty.T) / 2).min() < -1e-12 * np.abs(penalty).max():
                raise ValueError("Folds: the penalty is not symmetric non-negative")
            if free.all():  # no column penalised: the unpenalised rule
                penalty = None
            elif free.any():  # the penalised columns by the ridge, the others by the seen-share rule (below)
                Xu = self.outside(E[:, free])
                ku = Xu.shape[1]
                E = np.hstack([E[:, ~free], Xu])
                penalty = np.pad(penalty[np.ix_(~free, ~free)], ((0, ku), (0, ku)))
        X = (self.outside(E) if penalty is None else E) if has_e else None
        if X is not None and X.shape[1] == 0:
            X = None
        b = Y2.shape[1]
        V = Y2 if X is None else np.hstack([Y2, X])
        QtV = self.Q.T @ V  # kept for the own directions' training products (_own_seen)
        R = self.Q @ QtV  # the full fit Q Q^T V (every row)
        np.subtract(V, R, out=R)  # in place: with the null draws V is rows x 99 (80 MB at 1e5 rows)
        RXR = None if X is None or penalty is not None else R[:, b:].T @ R
        QtY = self.Q.T @ Y2 if X is not None and penalty is not None else None
        for f in self.items:
            tr, te = f.tr, f.te
            V_te, R_te = V[te], R[te]
            Gam = f.U.T @ R_te
            own = f.Qo
            if X is None:
                W, GW = V_te, Gam
            else:
                O = (self._outside_image(f, RXR, R_te, Gam, V, QtV, b) if penalty is None
                     else self._outside_image_direct(f, X, V, QtY, b))
                G, rhs = O[:, b:], O[:, :b]
                if penalty is None:
                    # F's directions by their training share beyond the baseline (lambda in [0, 1]): fitted on
                    # the training rows, not predicted (too little seen), or the held-out group's own (unseen)
                    w, Vg = np.linalg.eigh(G)
                    keep = w >= self.seen_extension ** 2 - SEEN_TIE
                    coef = Vg[:, keep] @ ((Vg[:, keep].T @ rhs) / w[keep][:, None])
                    unseen = w < SEEN_ZERO ** 2
                    if unseen.any():
                        own = np.hstack([own, X[te] @ Vg[:, unseen]])
                else:
                    Xtr, Pf, T = X[tr], penalty, None
                    if ku:
                        # the unpenalised columns (orthonormal outside the design) as without a penalty: their
                        # directions by the training share beyond the baseline, kept ones fitted beside the
                        # penalised columns (coefficients T c), unseen ones the held-out group's own, the band
                        # neither
                        kp = X.shape[1] - ku
                        wu, Vu = np.linalg.eigh(G[kp:, kp:])
                        keep = wu >= self.seen_extension ** 2 - SEEN_TIE
                        unseen = wu < SEEN_ZERO ** 2
                        if unseen.any():
                            own = np.hstack([own, X[te][:, kp:] @ Vu[:, unseen]])
                        T = np.zeros((X.shape[1], kp + int(keep.sum())))
                        T[:kp, :kp] = np.eye(kp)
                        T[kp:, kp:] = Vu[:, keep]
                        G, rhs, Pf = T.T @ G @ T, T.T @ rhs, T.T @ penalty @ T
                        Xtr = np.hstack([Xtr[:, :kp], Xtr[:, kp:] @ Vu[:, keep]])
                    en = np.linalg.norm(Xtr, axis=0)
                    eu = en > 1e-9 * max(en.max(), 1e-300)
                    sc = np.where(eu, 1.0 / np.where(eu, en, 1.0), 0.0)
                    Gm = (G * np.outer(sc, sc))[np.ix_(eu, eu)] + (Pf * np.outer(sc, sc))[np.ix_(eu, eu)]
                    w, Vg = np.linalg.eigh(Gm)
                    good = w > 1e-12 * max(w.max(), 1e-300) if w.size else w > 0
                    cs = Vg[:, good] @ ((Vg[:, good].T @ (rhs[eu] * sc[eu][:, None])) / w[good][:, None])
                    coef = np.zeros((Xtr.shape[1], b))
                    coef[eu] = cs * sc[eu][:, None]
                    if (~eu).any():  # a column no training row holds (the penalised ones: the kept are seen)
                        own = np.hstack([own, (X[te] if T is None else X[te] @ T)[:, ~eu]])
                    if T is not None:
                        coef = T @ coef
                # the baseline on what the extension leaves of the training rows, the extension on the held-out rows
                W, GW = V_te[:, :b] - V_te[:, b:] @ coef, Gam[:, :b] - Gam[:, b:] @ coef
            Uk, k = f.U[:, :f.k], f.k
            e = W + Uk @ (GW[:k] / f.c2[:k, None] - Uk.T @ W)
            if f.m:  # the implicit cluster (predicted, c2m): P (W' / c2m - W), W' what GW is U^T of
                Dm = (R_te if X is None else R_te[:, :b] - R_te[:, b:] @ coef) / f.c2m - W
                e += Dm - f.U @ (f.U.T @ Dm)
            if own.shape[1] > f.Qo.shape[1]:
                own = orth(own)
            if own.shape[1]:
                # the held-out group's own directions, fitted on its other rows:
                # leave-one-row-out residuals within the group, e / (1 - h);
                # a row that alone supports an own direction (h = 1) says nothing
                h = np.sum(own ** 2, axis=1)
                ok = h < 1 - OWN_LEVERAGE
                e = (e - own @ (own.T @ e)) / np.where(ok, 1 - h, 1.0)[:, None]
                e[~ok] = 0.0
                self.last_dof += int(ok.sum())
                self.last_predicted[te[ok]] = True
            else:
                self.last_dof += te.size
                self.last_predicted[te] = True
            out[te] = e
        return out[:, 0] if one else out

    def mse(self, y: np.ndarray, E: np.ndarray | None = None, penalty: np.ndarray | None = None) -> float:
        """Held-out mean square over the rows that can be predicted."""
        e = self.residuals(y, E, penalty)
        return float(e @ e) / max(self.last_dof, 1)


class CpEstimate:
    """Mallows' Cp in place of cross-validation, for designs without redundancy.

    When every parameter is seen by a few rows only (an MFB plan: each table
    node by the points of one or two placements), predicting held-out rows
    extrapolates and cross-validation measures that, not the model. The
    prediction error is then estimated in sample: ``(RSS + 2 k s^2) / n``
    with ``k`` the model's dimensions (effective ones for a penalised term)
    and ``s^2`` the baseline's residual variance, fixed for every model
    compared (Mallows 1973).
    """

    def __init__(self, A: np.ndarray, groups: np.ndarray, seen: float, seen_extension: float | None = None,
                 basis=None):
        """``groups``, ``seen``, ``seen_extension`` and ``basis`` are :class:`Folds`' (no folds here: unused but
        ``basis``, ``orth(A)`` already made)."""
        self.n = len(A)
        self.Q = orth(A) if basis is None else basis
        self.s2 = None
        self.dof = self.n
        self.last_dof = self.n

    def set_sigma(self, y: np.ndarray) -> None:
        r = y - self.Q @ (self.Q.T @ y)
        self.s2 = float(r @ r) / max(self.n - self.Q.shape[1], 1)

    def residuals(self, Y: np.ndarray, E: np.ndarray | None = None, penalty: np.ndarray | None = None):
        """In-sample residuals (the null draws of a CV gap have no meaning here)."""
        Q = self.Q if E is None or not E.shape[1] else np.hstack([self.Q, new_basis(self.Q, E)])
        return Y - Q @ (Q.T @ Y)

    def mse(self, y: np.ndarray, E: np.ndarray | None = None, penalty: np.ndarray | None = None) -> float:
        if self.s2 is None:
            self.set_sigma(y)
        if E is None or not E.shape[1]:
            r = y - self.Q @ (self.Q.T @ y)
            k = self.Q.shape[1]
        elif penalty is None:
            U = new_basis(self.Q, E)
            r = y - self.Q @ (self.Q.T @ y)
            r = r - U @ (U.T @ r)
            k = self.Q.shape[1] + U.shape[1]
        else:
            Sp = E - self.Q @ (self.Q.T @ E)
            M = Sp.T @ Sp + penalty
            r0 = y - self.Q @ (self.Q.T @ y)
            c = np.linalg.lstsq(M, Sp.T @ r0, rcond=1e-12)[0]
            r = r0 - Sp @ c
            k = self.Q.shape[1] + float(np.trace(np.linalg.lstsq(M, Sp.T @ Sp, rcond=1e-12)[0]))
        return (float(r @ r) + 2 * k * self.s2) / self.n


# ---------------------------------------------------------------------------
# the model being extended
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Term:
    """Columns added to the baseline: a named cause, or the unnamed smooth term.

    ``penalty`` (k, k): the term's columns are fitted with this ridge
    penalty (the unnamed smooth; a named cause marked
    :attr:`core.causes.Cause.penalised`); ``unnamed``: the term is the
    unnamed smooth (no physics), whatever its penalty.
    """

    cause: str
    columns: np.ndarray = field(repr=False)  # (N, k) over all baseline rows
    labels: tuple
    info: dict
    covariate: str
    tries: float = 1.0
    evidence: dict = field(default_factory=dict)
    penalty: np.ndarray | None = field(default=None, repr=False)
    weak: int = 0  # directions of the cause's columns left out as not identifiable
    origin: object = field(default=None, repr=False)  # the core.causes.Cause record
    labels_all: tuple = ()  # the scan's labels (the magnitudes' coefficient layout)
    map: np.ndarray | None = field(default=None, repr=False)  # (k_all, k): label coefficients per column
    cols_all: np.ndarray | None = field(default=None, repr=False)  # (N, k_all) the scan's columns
    # (Qo, rows, magnitudes, u95, _pen_key of the penalised terms it was fitted beside) of the adoption test: the model
    # it was judged beside (Qo does not show the penalised terms)
    at_adoption: tuple | None = field(default=None, repr=False, compare=False)
    unnamed: bool = False
    # (cause, info, (N, k) columns) of the other candidates that passed every test of the round this term won, each
    # in the form it passed with: tested as its alternatives under another name (CAUSE_ALTERNATIVES_OF_THE_ROUND)
    round_rivals: tuple = field(default=(), repr=False, compare=False)
    # (form text, (N, k) columns of its determined combinations) of the cause's other significant forms that pass every
    # test, kept where this term's form has a direction inflated beyond vif_max (FORM_SHIFT_CARRIED)
    form_rivals: tuple = field(default=(), repr=False, compare=False)


def _stack(terms, rows) -> np.ndarray:
    if not terms:
        return np.zeros((len(rows), 0))
    return np.hstack([t.columns[rows] for t in terms])


def _penalty(terms) -> np.ndarray | None:
    if not any(t.penalty is not None for t in terms):
        return None
    k = sum(t.columns.shape[1] for t in terms)
    P = np.zeros((k, k))
    o = 0
    for t in terms:
        kk = t.columns.shape[1]
        if t.penalty is not None:
            P[o:o + kk, o:o + kk] = t.penalty
        o += kk
    return P


def _penalty_beside(terms, k: int, P: np.ndarray | None = None) -> np.ndarray | None:
    """The penalty of ``terms``' columns followed by ``k`` more (penalised by ``P``, else not); None if none is."""
    Pt = _penalty(terms)
    if Pt is None and P is None:
        return None
    kt = sum(t.columns.shape[1] for t in terms)
    out = np.zeros((kt + k, kt + k))
    if Pt is not None:
        out[:kt, :kt] = Pt
    if P is not None:
        out[kt:, kt:] = P
    return out


#: The ridge penalties tried for a penalised named cause, times its columns' mean squared norm outside the model
#: (the unnamed smooth's grid, :func:`_unnamed_smooth`).
PENALTY_GRID = tuple(np.logspace(-4, 2, 7))

#: How a ridge penalty is chosen from the held-out mean squares over :data:`PENALTY_GRID` (:func:`_penalty_pick`;
#: every such choice: a penalised named cause's at adoption, chosen again, its bootstrap's refits, the unnamed
#: smooth's). The largest penalty whose held-out mean square is within this relative tolerance of the grid's least is
#: taken: of penalties the held-out set-ups cannot tell apart, the one that claims least of the data (the smoothest
#: term, the one that moves the extended workpiece least). ``None``: the first least value (the smallest penalty of
#: exact ties), the rule before session 32. Session 32 (review32c F8): the unnamed smooth in ``feature`` (the feature,
#: differently in each set-up) has every column the held-out set-up's own (no training row sees it; refitted on the
#: held-out rows, :class:`Folds`), so its held-out mean square does not depend on the penalty at all: flat to 3e-15
#: relative on review32c's both_outlier_clamp_relax_20002 while the extended workpiece moved 167.6 um from one end of
#: the grid to the other, and rounding (a translation of the log by 1000 mm) chose the end. 1e-9 is a numerical
#: tie: far above the curves' rounding (1e-14) and far below the least relative spread of a curve that discriminates
#: (0.0076 on review32c's 240 logs), so no curve that discriminates is read differently. A one-standard-error rule
#: across folds was not taken: with two to four set-ups the folds' spread is poorly estimated, and it would move the
#: penalty (and the magnitudes) of every penalised named cause whose curve does discriminate.
PENALTY_TIE_RTOL: float | None = 1e-9


def _penalty_pick(cvs) -> int:
    """The index into :data:`PENALTY_GRID` chosen from the held-out mean squares ``cvs`` (one per grid value, in
    the grid's order; an (n_grid, B) array: one index per column), by :data:`PENALTY_TIE_RTOL`."""
    cvs = np.where(np.isnan(cvs), np.inf, np.asarray(cvs, float))  # (a failed fit is never chosen over one)
    if PENALTY_TIE_RTOL is None:
        return np.argmin(cvs, axis=0) if cvs.ndim > 1 else int(np.argmin(cvs))
    lo = np.min(cvs, axis=0)
    ok = cvs <= lo + PENALTY_TIE_RTOL * np.abs(lo)
    last = len(cvs) - 1 - np.argmax(ok[::-1], axis=0)
    return last if cvs.ndim > 1 else int(last)


def _penalty_flatness(cvs) -> float:
    """The held-out curve's relative spread over the grid, ``(max - min) / min`` (0: flat; ``inf``: a zero least
    value with a spread). Reported in a term's evidence (``penalty_cv_spread``)."""
    cvs = np.asarray(cvs, float)
    lo, hi = float(np.min(cvs)), float(np.max(cvs))
    return (hi - lo) / lo if lo > 0 else (0.0 if hi == lo else float("inf"))


def _penalised_fit(Eo: np.ndarray, r: np.ndarray, P: np.ndarray, dof0: int):
    """The ridge fit of residuals ``r`` on columns ``Eo`` (projected out of the model): coefficients, covariance.

    The joint fit of the model and the columns with the penalty ``P`` on
    the columns' coefficients only (Frisch-Waugh-Lovell holds for it: the
    model's part is unpenalised). Covariance ``s^2 (E^T E + P)^-1``, the
    penalised fit's Bayesian covariance (Wahba 1983; the extended
    workpiece's), ``s^2`` on ``dof0`` less the fit's effective degrees of
    freedom ``tr((E^T E + P)^-1 E^T E)``. Returns (c, cov, s2, edf).

    Raises ValueError on inconsistent shapes, non-finite values or a
    penalty that is not symmetric non-negative (a ridge has no negative
    eigenvalue: one would reward large coefficients).
    """
    Eo, r, P = np.asarray(Eo, float), np.asarray(r, float), np.asarray(P, float)
    k = Eo.shape[1] if Eo.ndim == 2 else -1
    if Eo.ndim != 2 or r.shape != (Eo.shape[0],) or P.shape != (k, k):
        raise ValueError(f"penalised fit: columns {Eo.shape}, residuals {r.shape}, penalty {P.shape} do not match")
    if not (np.all(np.isfinite(Eo)) and np.all(np.isfinite(r)) and np.all(np.isfinite(P))):
        raise ValueError("penalised fit: non-finite columns, residuals or penalty")
    if k and (not np.allclose(P, P.T) or np.linalg.eigvalsh((P + P.T) / 2).min() < -1e-12 * np.abs(P).max()):
        raise ValueError("penalised fit: the penalty is not symmetric non-negative")
    G = Eo.T @ Eo
    M = G + P
    Mi = np.linalg.pinv(M, rcond=1e-12, hermitian=True)
    c = Mi @ (Eo.T @ r)
    res = r - Eo @ c
    edf = float(np.trace(Mi @ G))
    s2 = float(res @ res) / max(dof0 - edf, 1.0)
    return c, s2 * Mi, s2, edf


@dataclass
class _State:
    """In-sample fit of baseline + terms on the rows kept (internal)."""

    rows: np.ndarray
    Q: np.ndarray
    r: np.ndarray
    rss: float
    dof: int
    k_base: int = 0

    @property
    def sigma(self) -> float:
        return float(np.sqrt(self.rss / max(self.dof, 1)))


#: A set-aside touch is a cause's when the cause cuts its residual by at least this fraction (:func:`_explained_outliers`).
EXPLAINED_CUT = 0.25


def _explained_outliers(Qall: np.ndarray, y: np.ndarray, all_rows: np.ndarray, rows: np.ndarray, tm, terms) -> np.ndarray:
    """The rows set aside (``all_rows`` not in ``rows``) whose residual the term ``tm`` cuts materially.

    Fitted on every row (``Qall`` the baseline's basis there) with
    ``terms`` and without ``tm``: a set-aside touch is the cause's when
    ``tm`` cuts its residual's magnitude by at least :data:`EXPLAINED_CUT`
    (a quarter). Dust on a touch the cause does not reach keeps its
    residual whatever the cause (its column there is about zero: a 5 um
    chip on gen_b local_scale_defect 829, cut 0-5 %) and stays set aside;
    the largest touches of a bump the cause follows only in part have
    theirs cut by about half or more (829: 47-82 %), so a quarter sits between
    them with margin on both sides. A heuristic, not a test: a chip on a
    touch the cause reaches, of the sign the cause predicts there, is put
    back with it.
    """
    out = np.setdiff1d(all_rows, rows)
    if out.size == 0:
        return out
    r_wo = _state(Qall, y, all_rows, [t for t in terms if t is not tm]).r[out]
    r_w = _state(Qall, y, all_rows, terms).r[out]
    return out[np.abs(r_wo) - np.abs(r_w) >= EXPLAINED_CUT * np.abs(r_wo)]


def _explains_set_aside(Qall: np.ndarray, y: np.ndarray, all_rows: np.ndarray, rows: np.ndarray, terms,
                        events: np.ndarray, rows_kept_beside_cause: np.ndarray) -> bool:
    """Whether one of ``terms`` (adopted on every row) cuts the touches set aside (not in ``rows``) in two events.

    A trigger, not a filter. The touches counted are its
    :func:`_explained_outliers` (residual cut by a quarter or more, fitted
    on every row) that stay beyond the bound beside it (not in
    ``rows_kept_beside_cause``, the rows its own outlier screen kept), in
    two events or more. The caller asks only on a planar log with
    set-ups as events (``per_setup``): elsewhere the events are
    ``bl.replicate``, -1 on a volumetric log (every row its own event:
    "two events" would be any two rows) and the target and direction on
    an ISO 230-2 one, neither a set-up. A bump the catalogue's form follows
    only in part (narrower than its narrowest scanned half-width) leaves
    its largest touches beyond the bound beside it, as many as before,
    and cuts them set-up after set-up (gen_a local_scale_defect 1021 by
    0.26-0.53, gen_b 1170 by 0.29-0.72, 1222 by 0.29-0.38). Dust can
    fire it too: the cut on every row measures the touch's leverage on a
    fit that contains it. On gen_a outlier 1163 (the generator's chips)
    part_change cuts two chips in two set-ups by 0.62 and 0.34; predicted
    from the kept rows alone its cut there is 0.02-0.04 (the bumps'
    0.05-0.17). What filters is the rival check that follows (step 4 of
    :func:`discover`): 1163's part_change is dropped there and its
    put-back undone. The longer-term fix is the cut on residuals
    predicted from the kept rows (not done: the margin, 0.04 against
    0.05 on these campaigns, is too thin to set a threshold on).

    Guards: a touch it takes in whole (no longer beyond the bound beside
    it: a bump fitted on a chip, gen_b outlier 1175) does not count; and
    the touches set aside beside it must be among those set aside before
    (the same outliers, none new: otherwise the caller's count of
    outliers, not this rule, decides).
    """
    if not np.all(np.isin(np.setdiff1d(all_rows, rows_kept_beside_cause), np.setdiff1d(all_rows, rows))):
        return False  # a touch set aside beside the cause that was kept before: not the same outliers, fewer or not
    for tm in terms:
        if tm.unnamed:
            continue
        ex = np.setdiff1d(_explained_outliers(Qall, y, all_rows, rows, tm, terms), rows_kept_beside_cause)
        if len(first_per_event(list(ex), events)) >= 2:
            return True
    return False


#: A workpiece cause (part_change) adopted with every row in, to explain touches the first screen set aside, must be
#: seen on the touches that screen kept where those it reaches are single touches, each alone in its set-up
#: (:func:`_workpiece_unseen_without_outliers`); False: the behaviour before (session 22).
WORKPIECE_SEEN_WITHOUT_OUTLIERS = True


def _workpiece_unseen_without_outliers(Qk: np.ndarray, y: np.ndarray, rows: np.ndarray, terms, settings,
                                       setups: np.ndarray | None = None) -> bool:
    """Whether a cause of ``terms`` booked to the workpiece is a chip's reading: not seen on ``rows`` (the touches
    the outlier screen kept), and the set-aside touches it reaches single touches (``setups``: the set-up of each
    row; none of them shares its set-up with another; None: no set-ups, never).

    The search with every row in (step 3's second search) takes its causes where they leave fewer outliers than
    the search without them: the touches set aside were the cause's largest residuals. A part change moves every
    later touch of its feature's wall by a common amount, so it is seen on the touches the screen kept as well; a
    chip sits under one touch. A part change's columns are one feature's walls, and on a small feature (a pin:
    every target its own wall) a wall is one target: where that target is touched in few set-ups, its column
    gives one touch a parameter of its own, and a chip on that touch is "explained" (no longer beyond the bound:
    its leverage there is about one, so the outlier test cannot judge it; gen_b outlier 1174, a chip (residual
    +11.8 um) on pin2's 225 deg target, touched at tau 0.024, 0.936 and 0.982, was read as part_change, confident, that wall
    changing by -32.6 um over the campaign, its extended workpiece 3.75 um from the truth against the
    baseline's 2.27, U95 0.55). The test: each such term's columns F-tested on ``rows`` beside the baseline
    (``Qk``, its basis on those rows) and the other terms, unadjusted, at ``Settings.alpha``: the cause
    stands where its own columns see it on the touches no one doubts; otherwise the touches it took back are
    not its evidence and the search without them stands. Unadjusted: the trial is the one the search chose
    with every row in (a lenient test, which keeps a part change the kept touches show at all).

    Only where the touches set aside that the cause reaches are single touches, each alone of them in its
    set-up: a chip sits under one touch. A part that changes early and then holds (gen_a's, ``1 - exp(-t /
    tau)``) differs before the change on the feature's first touches, touched in one pass: the screen sets them
    aside together and the kept touches, all after the change, do not see it (gen_a part_change 1002, wall3's
    three first touches, p 0.107 on the kept ones; 1019, bore2's two first touches and one later, p 0.012); the
    cause reads them as the part before it changed, which the test above alone refused (both named right
    before; read `outlier` with the test alone). Two or more of them in one set-up leave the cause as it was.
    """
    if setups is None:
        return False
    aside = np.setdiff1d(np.arange(len(y)), rows)
    for tm in terms:
        if tm.unnamed or getattr(tm.origin, "books_to", None) != "workpiece":
            continue
        reached = aside[np.any(tm.columns[aside] != 0, axis=1)]
        if reached.size == 0:
            continue  # it took back none of the touches set aside: not the case this rule is about
        if np.unique(setups[reached]).size < reached.size:
            continue  # several of its touches set aside in one set-up: the part before it changed, possibly
        so = _state(Qk, y, rows, [t for t in terms if t is not tm])
        U = new_basis(so.Q, tm.columns[rows])
        if nested_f(U, so.r, so.rss, so.dof).p_value >= settings.alpha:  # (no direction left: p 1)
            return True
    return False


#: Whether touches the outlier screen set aside on one feature are looked at again as that feature's part change
#: (:func:`_part_change_outlier_look`, session 35, cat35): where the other touches, fitted without them, predict
#: their deviation (a one-sided test of the prediction's sign, the feature's part_change trials counted and the look
#: counted twice, the second look it is), part_change is searched again on every row with that feature's layouts
#: alone, and taken as the second search's causes are (fewer outliers left beside it, seen on the touches the
#: screen kept). A part change early in a campaign whose feature is touched a few times (gen_a part_change 1010,
#: 1080, 1092: 3 targets of one wall or bore in 3-5 set-ups) is carried by the first set-up's touch or touches, whose
#: deviation from their targets' later touches the screen sets aside before part_change is tried; counted over every
#: feature, layout and form (58-74 trials, times the causes) part_change is then not adopted with it back. Built and
#: left off: it mends none of the three (1010, 1092: the other touches predict the touch's sign at p 0.015 and
#: 0.004 before the count of 12; 1080 passes, then part_change loses held-out as without the look, on a change
#: that settled early) and changed no reading on 390 tuning campaigns (gen_a part_change, outlier, local_scale_defect, none,
#: knock, reseat_hysteresis; gen_b and gen_c outlier, part_change): docs/discovery-studies.md, "Session 35: a part change
#: carried by one touch, and the frame of gen_a's defect centres (cat35)".
PART_CHANGE_OUTLIER_LOOK = False


def _part_change_outlier_look(A: np.ndarray, y: np.ndarray, rows: np.ndarray, base: np.ndarray, features,
                              pc_scans, alpha: float) -> dict | None:
    """The part change of the feature holding every touch set aside (not in ``rows``), where the kept touches
    predict those touches' deviation (:data:`PART_CHANGE_OUTLIER_LOOK`); None otherwise.

    ``A`` the baseline's design on every row (dense), ``base`` the columns of the causes already adopted on every
    row, ``features`` each row's feature, ``pc_scans`` part_change's scans. The touches set aside must all lie on
    one feature that has part_change layouts. For each of that feature's trials ``C`` (every layout and time form):
    the model ``[A, base]`` and ``[A, base, C]`` are both fitted on the kept rows; at each set-aside touch ``o``
    the difference of their predictions is ``d_o y_kept`` (a linear map of the kept rows alone), and the
    statistic is ``T = sum_o sign(r_o) d_o y_kept``, ``r_o`` the touch's residual from the kept rows' fit of
    ``[A, base]`` (its deleted residual). Where no part change is, the kept rows' noise is independent of the
    set-aside touches (a chip, or noise that happened to stand out), so ``T`` is centred on 0 whatever signs the
    set-aside touches took: ``T / (s ||sum_o sign(r_o) d_o||)`` is Student's t with the extended fit's degrees of
    freedom, tested one-sided (a part change the other touches see predicts the set-aside touch's sign). A touch
    whose row the kept rows do not determine under ``[A, base, C]`` (its target touched nowhere else: the trial
    would give it a parameter of its own) is left out of ``T``; a trial without one determined touch is no trial.
    The smallest p is counted over the feature's trials and twice (the look is a second look at the catalogue's
    part change: ``p m 2 < alpha``). Returns ``{"feature", "rows", "scans", "p", "trials"}`` with the passing
    feature's scans, or None.
    """
    out = np.setdiff1d(np.arange(len(y)), rows)
    if out.size == 0 or not isinstance(A, np.ndarray):
        return None
    feats = np.asarray(features, dtype=object)
    f = set(feats[out].tolist())
    if len(f) != 1:
        return None
    f = f.pop()
    mine = [sc for sc in pc_scans if sc.infos[0].get("feature") == str(f)]
    m = sum(sc.size for sc in mine)
    if not mine or m == 0:
        return None

    def fit(X):
        # the kept rows' least squares (columns scaled: the baseline's are m, a part change's per unit): the map
        # from y_kept to the predictions at the set-aside rows, the residual scale and degrees of freedom
        Xk = X[rows]
        sc_ = np.linalg.norm(Xk, axis=0)
        sc_[sc_ == 0] = 1.0
        U, sv, Vt = np.linalg.svd(Xk / sc_, full_matrices=False)
        keep = sv > 1e-10 * sv[0]
        U, sv, Vt = U[:, keep], sv[keep], Vt[keep]
        xo = X[out] / sc_
        determined = np.linalg.norm(xo - (xo @ Vt.T) @ Vt, axis=1) <= 1e-6 * np.maximum(np.linalg.norm(xo, axis=1),
                                                                                        1e-300)
        L = (xo @ Vt.T / sv) @ U.T  # predictions at the set-aside rows: L @ y_kept
        r = y[rows] - U @ (U.T @ y[rows])
        dof = len(rows) - int(keep.sum())
        return L, determined, float(np.sqrt(r @ r / dof)) if dof > 0 else float("nan"), dof

    X0 = np.hstack([A, base])
    L0, det0, _, _ = fit(X0)
    r_o = y[out] - L0 @ y[rows]
    best = None
    for sc in mine:
        Cs = sc.build(np.arange(sc.size))
        for j in range(sc.size):
            L1, det1, s1, dof1 = fit(np.hstack([X0, Cs[j]]))
            use = det0 & det1
            if not use.any() or not dof1 > 0 or not s1 > 0:
                continue
            w = np.sign(r_o[use]) @ (L1[use] - L0[use])
            nw = float(np.linalg.norm(w))
            if nw == 0:
                continue
            t = float(w @ y[rows]) / (s1 * nw)
            p = float(stats.t.sf(t, dof1))
            if best is None or p < best[0]:
                best = (p, out[use])
    if best is None or best[0] * m * 2 >= alpha:
        return None
    return {"feature": str(f), "rows": [int(r) for r in best[1]], "scans": mine, "p": min(best[0] * m * 2, 1.0),
            "trials": 2 * m}


#: :func:`_state`'s last answers in a run, ``(id(Qb), id(y), rows, ids of the terms) -> (Qb, y, terms, state)``
#: (the objects held so that the ids name them; a dense ``Qb`` of at most :data:`STATES_KEEP_BYTES` only: sixteen
#: states' bases beside it, up to about 64 MiB). The engine builds the same model again: the rival check's and the
#: report's models without and with each cause, the search's state after an adoption (on the demo 6 of 11 calls,
#: 2.6 of 4.1 ms; its Qb is 0.5 MB). Cleared when a run ends (:func:`release_states`).
_STATES = Memo(16)
STATES_KEEP_BYTES = 4 << 20


def release_states() -> None:
    """Forget :func:`_state`'s answers (the end of an engine run: a later run's bases are other arrays)."""
    _STATES.clear()


def _state(Qb: np.ndarray, y: np.ndarray, rows: np.ndarray, terms) -> _State:
    """The model of the baseline's basis ``Qb`` and the terms on ``rows`` (a model built before from these very
    objects and rows: that state itself, :data:`_STATES`; no caller writes into a state)."""
    terms = list(terms)
    if not isinstance(Qb, np.ndarray) or Qb.nbytes > STATES_KEEP_BYTES:
        return _state_made(Qb, y, rows, terms)
    rows_a = np.asarray(rows)
    key = (id(Qb), id(y), rows_a.dtype.str, rows_a.tobytes(), tuple(id(t) for t in terms))
    hit = _STATES.get(key)
    if hit is not None and hit[0] is Qb and hit[1] is y and len(hit[2]) == len(terms) and all(
            a is b for a, b in zip(hit[2], terms)):
        return hit[3]
    st = _state_made(Qb, y, rows, terms)
    _STATES.put(key, (Qb, y, terms, st))
    return st


def _state_made(Qb: np.ndarray, y: np.ndarray, rows: np.ndarray, terms) -> _State:
    E = _stack([t for t in terms if t.penalty is None], rows)
    extends(Qb, Qb)  # (the columns' parts outside Qb kept for the next state beside it: project_out)
    Q = Qb if E.shape[1] == 0 else extends(np.hstack([Qb, new_basis(Qb, E)]), Qb)
    yr = y[rows]
    r = yr - Q @ (Q.T @ yr)
    # a penalised term: its fitted part removed by the ridge solution
    pen = [t for t in terms if t.penalty is not None]
    dof = len(rows) - Q.shape[1]
    if pen:
        S = _stack(pen, rows)
        Sp = S - Q @ (Q.T @ S)
        Pm = _penalty(pen)
        M = Sp.T @ Sp + Pm
        c = np.linalg.lstsq(M, Sp.T @ r, rcond=1e-12)[0]
        r = r - Sp @ c
        edf = float(np.trace(np.linalg.lstsq(M, Sp.T @ Sp, rcond=1e-12)[0]))
        dof = int(round(len(rows) - Q.shape[1] - edf))
    # (a state is shared by every caller that asks for the same model in a run, :func:`_state`: its own arrays are
    # read-only, so a caller that wrote into one would fail, not change another's model)
    r.flags.writeable = False
    if Q is not Qb and isinstance(Q, np.ndarray):
        Q.flags.writeable = False
    return _State(rows, Q, r, float(r @ r), max(dof, 1), Qb.shape[1])


def _white(bl, C: np.ndarray) -> np.ndarray:
    """Columns ``C`` (every row of the log) in the rows the engine fits: through the baseline's whitening where it
    has one (a point's touches, :func:`core.baseline.planar`'s point whitening), else ``C`` itself."""
    return C if bl.whiten is None else bl.whiten @ C


# ---------------------------------------------------------------------------
# outliers
# ---------------------------------------------------------------------------
def _deleted_t(Q, r: np.ndarray, dof: int) -> tuple:
    """Each row's deleted-residual t statistic (the residual ``r`` against the scatter of the fit without the row,
    ``Q`` the fit's orthonormal basis, ``dof`` its residual degrees of freedom) and whether the row can be judged:
    a row that (nearly) alone determines a parameter (leverage 0.99 or more) cannot, its statistic 0."""
    h = leverage(Q)
    ok = h < 0.99
    rss = float(r @ r)
    den = np.where(ok, 1 - h, 1.0)
    s2 = (rss - np.where(ok, r ** 2 / den, 0.0)) / (dof - 1)
    return np.where(ok, np.abs(r) / np.sqrt(np.maximum(s2, 1e-300) * den), 0.0), ok


#: The outlier screen's refitted bases (the rows kept after a removal on a long log, an extended design's screen,
#: the slip test's and the chip rules' fits) drop a direction at the baseline's ``rank_tol`` (the log's printed
#: precision, :func:`core.baseline.precision_rank_tol`), as the first pass's ``Qall`` does; False: at ``orth_of``'s
#: 1e-9 (the behaviour before). Session 30 (rank30b, docs/discovery.md): a 4-decimal plate log's rounding directions
#: (QR pivots at ~1-2 q / L) are no parameters of the baseline, and no parameters of its refits either.
OUTLIER_RANK_TOL = True


#: The outlier screen's set checked from a robust start (:func:`_robust_outliers`, session 36, out36): the
#: least-absolute-deviations fit of the baseline names a first set (residuals beyond 3 robust sigma), each set-aside
#: row is then tested again by its prediction from the kept rows and each kept row on the clean fit, until stable; that
#: set replaces the screen's where the screen set rows aside, it holds no more, and its clean fit's scatter is
#: significantly smaller (F at the screen's alpha). The one-pass deletion (one row at a time, never
#: tested again) masks: on blind gen_b outlier 11505 (five chips of 14-27 um, 204 touches, 108 parameters, most
#: targets of two to four touches) the chips' targets' own parameters absorbed three of them (leverage 0.79-0.88),
#: their neighbours stood out, and the screen set aside six good rows and missed the three chips. False: the screen
#: as before. Measured (docs/discovery-studies.md, "Session 36: the outlier screen's masking"): 837 tuning campaigns screened,
#: 14 could differ, none moved a reading or a workpiece; 11505's workpiece 7.57 -> 0.20 um. On since session 36 (the
#: lead, at no cost on tuning seeds; built after reading set F's 11505, so set F is not a blind figure for it: the
#: next blind set is).
OUTLIER_ROBUST_START = True
#: The robust start's first set: rows whose least-absolute-deviations residual is beyond this many robust sigma
#: (1.4826 MAD of the residuals the fit does not interpolate). Only a start: the prediction test decides each row.
OUTLIER_ROBUST_START_SIGMA = 3.0
#: With :data:`OUTLIER_ROBUST_START`: the robust start also where the screen set nothing aside (two gross errors that
#: inflate the scatter so that neither passes the bound: masked wholly), its set then up to the screen's cap. Off
#: (measured, session 36): on tuning campaigns of gen_b reseat_settling and gen_a/gen_b part_change it sets aside the
#: effect's own structured touches where the screen set none (the screen's later tests then judge them).
OUTLIER_ROBUST_START_EMPTY = False
#: Logs longer than this are not given the robust start (its linear program is dense in the rows).
OUTLIER_ROBUST_START_MAX_ROWS = 4000


def _lad_residuals(Q: np.ndarray, y: np.ndarray) -> np.ndarray | None:
    """The residuals of the least-absolute-deviations fit of ``y`` on the columns of ``Q`` (a linear program,
    HiGHS); None where the solver fails. Robust to gross errors in ``y``: a target of three touches, one a chip, is
    fitted on the other two (the least-squares fit shares the chip among all three)."""
    n, p = Q.shape
    sc = float(np.max(np.abs(y)))
    if not np.isfinite(sc) or sc == 0.0:
        return None
    eye = sps.identity(n, format="csr")
    A = sps.hstack([sps.csr_matrix(Q), eye, -eye], format="csr")
    c = np.r_[np.zeros(p), np.ones(2 * n)]
    res = optimize.linprog(c, A_eq=A, b_eq=y / sc, bounds=[(None, None)] * p + [(0, None)] * (2 * n),
                           method="highs")
    if res.status != 0 or res.x is None:
        return None
    return (y / sc - Q @ res.x[:p]) * sc


def _clean_fit(Q: np.ndarray, y: np.ndarray, aside) -> tuple:
    """The fit of the rows not in ``aside`` on the basis ``Q`` (n, r) of every row: the kept rows, their residuals,
    an orthonormal basis of their fit (its leverages), its dof and the prediction t of every set-aside row (its
    residual from the kept rows' fit over ``s sqrt(1 + h*)``, ``h*`` its prediction leverage: the row's deleted t in
    the fit of the kept rows and it), 0 where the row cannot be judged (it alone determines a direction: leverage
    0.99 or more with it in, as :func:`_deleted_t`)."""
    n = len(y)
    aside = np.asarray(sorted(aside), dtype=int)
    keep = np.setdiff1d(np.arange(n), aside)
    M = Q[keep]
    U, sv, Vt = np.linalg.svd(M, full_matrices=False)
    on = sv > 1e-6 * max(float(sv[0]) if sv.size else 0.0, 1e-300)
    U, sv, Vt = U[:, on], sv[on], Vt[on]
    coef = Vt.T @ ((U.T @ y[keep]) / sv)
    r = y[keep] - M @ coef
    dof = len(keep) - int(on.sum())
    tp = np.zeros(len(aside))
    if len(aside) and dof >= 2:
        s2 = float(r @ r) / dof
        qs = Q[aside]
        z = (qs @ Vt.T) / sv
        hstar = np.sum(z ** 2, axis=1)
        off = np.linalg.norm(qs - (qs @ Vt.T) @ Vt, axis=1)
        e = y[aside] - qs @ coef
        ok = (hstar < 99.0) & (off < 1e-6)
        tp = np.where(ok, np.abs(e) / np.sqrt(max(s2, 1e-300) * (1.0 + np.where(ok, hstar, 0.0))), 0.0)
    return keep, r, U, dof, tp


def _settle_outliers(Q: np.ndarray, y: np.ndarray, start, alpha: float) -> tuple:
    """From the set-aside rows ``start``: the set-aside row whose prediction from the kept rows falls within the
    Bonferroni bound (the smallest first) is put back; else the kept row of the largest deleted t beyond it is set
    aside; until neither moves (or a set comes round again). Returns (rows set aside, most extreme first; the kept
    fit's residual variance)."""
    S = set(int(i) for i in start)
    seen: set = set()
    for _ in range(4 * len(y)):  # (each pass moves one row; a set come round again stops it sooner)
        keep, r, U, dof, tp = _clean_fit(Q, y, S)
        if frozenset(S) in seen or dof < 3:
            break
        seen.add(frozenset(S))
        rows = sorted(S)
        if rows:
            j = int(np.argmin(tp))
            # (its deleted t in the fit of the kept rows and it: dof of that fit less one, the kept fit's dof)
            if tp[j] <= stats.t.isf(alpha / (2 * (len(keep) + 1)), dof):
                S.discard(rows[j])
                continue
        t, _ = _deleted_t(U, r, dof)
        k = _first_largest(t)
        if t[k] > stats.t.isf(alpha / (2 * len(keep)), dof - 1):
            S.add(int(keep[k]))
            continue
        break
    keep, r, U, dof, tp = _clean_fit(Q, y, S)
    rows = sorted(S)
    order = [rows[i] for i in np.argsort(-tp, kind="stable")] if rows else []
    return order, float(r @ r) / max(dof, 1)


#: :func:`_robust_outliers`' answers, keyed by everything they depend on (the bytes of ``X`` and ``y``, the screen's
#: set, alpha, cap, rank tolerance and the module's constants): a discovery screens the same design and
#: observations with the same set again in its later steps: 6 of 32 calls on five gen_a campaigns, each a linear
#: program of 0.1-0.5 s (:func:`_lad_residuals`: 16 % of the discover time of tests/core/test_discover_misses.py).
#: Exact (the same function of the same values; session 38, fast38). False: computed every time.
ROBUST_OUTLIERS_MEMO = True
_ROBUST = Memo(32)


def _robust_outliers(X: np.ndarray, y: np.ndarray, out: list, alpha: float, cap: int, tol: float,
                     Q: np.ndarray | None = None) -> list:
    """:func:`_robust_outliers_of`, once for each set of values (:data:`ROBUST_OUTLIERS_MEMO`)."""
    n = len(y)
    if (not out and not OUTLIER_ROBUST_START_EMPTY) or n > OUTLIER_ROBUST_START_MAX_ROWS or n < 8:
        return out
    if not ROBUST_OUTLIERS_MEMO or Q is not None:
        return _robust_outliers_of(X, y, out, alpha, cap, tol, Q)
    X, y = np.asarray(X), np.asarray(y)
    h = hashlib.blake2b(digest_size=32)
    for a in (X, y):
        h.update(repr((a.shape, a.dtype.str)).encode())
        h.update(np.ascontiguousarray(a).tobytes())
    key = (h.hexdigest(), tuple(int(i) for i in out), float(alpha), int(cap), float(tol), OUTLIER_ROBUST_START_EMPTY,
           OUTLIER_ROBUST_START_SIGMA, OUTLIER_ROBUST_START_MAX_ROWS)
    got = _ROBUST.get(key)
    if got is None:
        got = _ROBUST.put(key, tuple(_robust_outliers_of(X, y, out, alpha, cap, tol)))
    return list(got)


def _robust_outliers_of(X: np.ndarray, y: np.ndarray, out: list, alpha: float, cap: int, tol: float,
                        Q: np.ndarray | None = None) -> list:
    """The one-pass screen's outliers ``out``, or the set a robust start settles on (:data:`OUTLIER_ROBUST_START`).

    The screen removes one row at a time and never tests a removed row
    again: a chip on a target of few touches is shared by that target's
    own parameters, its neighbours look outlying, and once they are gone
    the chip alone determines the parameter (leverage near one: never
    judged). Here the least-absolute-deviations fit (robust to gross errors
    in ``y``, :func:`_lad_residuals`) names a first set, its rows beyond
    :data:`OUTLIER_ROBUST_START_SIGMA` robust sigma, and
    :func:`_settle_outliers` tests each set-aside row again by its
    prediction from the kept rows and each kept row on the clean fit, until
    stable. That set replaces the screen's where its clean fit's residual
    variance is significantly smaller (F at ``alpha``: on gen_b outlier
    1129 the two sets differ by one touch of a pair that alone carries a
    parameter, the same variance either way, and the screen's set, the
    truth, stays). The rule mends swamping
    (good rows set aside for the gross errors beside them) and only that:
    it runs where the screen set rows aside, and the robust set replaces
    them only where it holds no more rows than they (a robust set beyond
    the screen's count, or beside a screen that set nothing aside, is
    structure the screen's own tests judge: on gen_b reseat_settling and
    gen_a part_change tuning campaigns the robust start set aside the
    touches of the effect's own structure where the screen set none).
    """
    n = len(y)
    if (not out and not OUTLIER_ROBUST_START_EMPTY) or n > OUTLIER_ROBUST_START_MAX_ROWS or n < 8:
        return out
    Q0 = Q if isinstance(Q, np.ndarray) and Q.shape[0] == n else orth_of(X, tol)
    if n - Q0.shape[1] < 4:
        return out
    r = _lad_residuals(Q0, y)
    if r is None:
        return out
    fitted = np.abs(r) > 1e-9 * float(np.max(np.abs(r)))
    if not np.any(fitted):
        return out
    sig = 1.4826 * float(np.median(np.abs(r[fitted]))) * np.sqrt(n / max(n - Q0.shape[1], 1))
    start = np.flatnonzero(np.abs(r) > OUTLIER_ROBUST_START_SIGMA * sig)
    robust, v_robust = _settle_outliers(Q0, y, start, alpha)
    if not robust or len(robust) > min(cap, len(out) if out else cap) or set(robust) == set(out):
        return out
    _, r_out, _, dof_out, _ = _clean_fit(Q0, y, out)
    dof_robust = n - len(robust) - Q0.shape[1]  # (the kept rows' dof where the rank is kept; a floor of 1 below)
    # significantly smaller (F at the screen's alpha): two sets the data cannot tell apart (a chip on one of the
    # two touches that alone carry a parameter: either may be it) leave the screen's
    f = stats.f.isf(alpha, max(dof_robust, 1), max(dof_out, 1))
    return robust if v_robust * f < float(r_out @ r_out) / max(dof_out, 1) else out


def find_outliers(X: np.ndarray, y: np.ndarray, alpha: float = 0.001, max_frac: float = 0.02,
                  Q: np.ndarray | None = None, ranks: np.ndarray | None = None,
                  rng: np.random.Generator | None = None, max_frac_dust: float = 0.05,
                  alpha_concentration: float = 0.0025, events: np.ndarray | None = None,
                  slips=None, places: Places | None = None, rank_tol: float | None = None) -> list[int]:
    """Indices (into y) of gross outliers: studentized deleted residuals, one at a time.

    Each pass removes the most extreme row if its studentized deleted
    residual exceeds the Bonferroni bound ``t(1 - alpha / 2n, dof - 1)``.
    If more than ``max_frac`` of the rows (at least 3) would go, the large
    residuals are structure, not dust: nothing is returned.

    With ``ranks`` (the rows' covariates as normalised ranks) the set is
    also judged by where it falls. Dust (a chip, a bad trigger) has no
    memory: it hits touches at random, so the outliers' mean rank in every
    covariate is that of ``k`` touches drawn at random
    (:func:`concentration_p`). Outliers concentrated in one covariate (the
    touches after a reversal, after a long rest, late in a set-up) are
    structure: nothing is returned. Outliers that fall at random are dust
    up to ``max_frac_dust`` of the rows (more than that many chips is no
    chip).

    Parameters
    ----------
    X : (n, p) float
        The model's design (any scaling; the column space matters).
    y : (n,) float
    Q : (n, r) float, optional
        Orthonormal basis of X's column space (saves the first factorisation).
    ranks : (n, m) float, optional
        Normalised ranks (0..1) of the rows in ``m`` covariates
        (:func:`covariate_ranks`).
    rng : np.random.Generator, optional
        Draws of the concentration test's null (needed with ``ranks``).
    max_frac_dust : float
        Largest fraction of outliers that fall at random (with ``ranks``).
    alpha_concentration : float
        Family-wise level of the concentration test (Bonferroni over the
        covariates).
    events : (n,) int, optional
        Rows that one piece of dust corrupts together (the touches of one
        target within one set-up: a chip stays on the part until the part
        is set up again, and every touch of that target hits it); negative:
        a row of its own. The concentration test counts one outlier per
        event.
    slips : callable, optional
        ``slips() -> (T, n, k)``: one-off steps within an event (a fixture
        slip's trials, :func:`core.causes.fixture_slip`). Two or more
        outliers of one event are no dust when a trial, adopted on every
        row, leaves none of them beyond the bound, and either they
        outnumber its parameters or it is significant on the other touches
        (every outlier set aside): they were that step's touches
        (:func:`_slip_explains`). With :data:`SLIP_VETO_PER_EVENT` only those
        events' outliers are kept; the others' are returned.
    places : Places, optional
        Where on the part each row touches (feature, target) and what one
        piece of dust corrupts at one place (:func:`places_of`): the
        concentration test also asks whether the outliers, one per place
        unit, share a feature or a target more than dust would
        (:func:`concentration_p`), when they span two or more events (one
        set-up's chips may gather where its swarf fell; a place that
        collects outliers set-up after set-up, the part cleaned and set up
        again in between, is no chip).
    rank_tol : float, optional
        The relative pivot below which a refitted basis of ``X``'s rows
        (``X`` itself without ``Q``, the rows kept after a removal on a long
        log, the slip test's and the chip rules' fits) drops a direction:
        the baseline's ``rank_tol`` (the log's printed precision,
        :func:`core.baseline.precision_rank_tol`), as ``Q`` itself is cut;
        None (or :data:`OUTLIER_RANK_TOL` off): ``orth_of``'s 1e-9.
    """
    tol = rank_tol if OUTLIER_RANK_TOL and rank_tol is not None else 1e-9
    n = len(y)
    judged = ranks is not None and ranks.shape[1] > 0 and rng is not None
    cap = max(3, int((max_frac_dust if judged else max_frac) * n))
    keep = np.ones(n, bool)
    out: list[int] = []
    k = -1  # (the row the previous pass set aside; none before the first)
    while True:
        idx = np.flatnonzero(keep)
        if Q is None or (len(idx) != n and not isinstance(Q, np.ndarray)):
            Q = orth_of(X[idx], tol)  # (a long log's Basis: factored afresh without the row)
        elif len(idx) != n:
            Q = _without_row(Q, k)  # the previous pass's basis less its row k: X[idx]'s column space
        r = y[idx] - Q @ (Q.T @ y[idx])
        dof = len(idx) - Q.shape[1]
        if dof < 3:
            break
        tstat, _ = _deleted_t(Q, r, dof)
        k = _first_largest(tstat)
        if tstat[k] <= stats.t.isf(alpha / (2 * len(idx)), dof - 1):
            break
        if len(out) >= cap:
            return []
        out.append(int(idx[k]))
        keep[idx[k]] = False
    if OUTLIER_ROBUST_START and isinstance(X, np.ndarray):
        out = _robust_outliers(X, y, out, alpha, cap, tol)
    if OUTLIER_CHIPS_LIKELIHOOD and out and places is not None and isinstance(X, np.ndarray):
        out = _chips_by_likelihood(X, y, out, places, alpha, cap, tol)
    if OUTLIER_CHIPS_READ_MORE and out and places is not None and isinstance(X, np.ndarray):
        out = _chips_read_more(X, y, out, places, alpha, cap, tol)
    if judged:
        first = out if events is None else first_per_event(out, events)
        # places only across events: one set-up's chips may gather where its swarf fell
        at = None if places is None or len(first) < 2 else first_per_event(out, places.units)
        if len(first) >= 2 and concentration_p(ranks, first, rng, places=places, place_idx=at) < alpha_concentration:
            return []
        if slips is not None and events is not None:
            ev = np.asarray(events)
            explained: list = []
            if _slip_explains(X, y, out, ev, slips, alpha, alpha_concentration, tol,
                              explained=explained if SLIP_VETO_PER_EVENT else None):
                if not SLIP_VETO_PER_EVENT:
                    return []
                # a step explains its own event's outliers, not another set-up's: those stay dust
                out = [i for i in out if int(ev[i]) not in explained]
    return sorted(out)


#: The outlier screen's slip veto keeps only the outliers of the events (set-ups) a fixture slip's step explains
#: (:func:`_slip_explains`); the outliers of the other events stay set aside as dust (True). False: the rule before,
#: one set-up's step explaining its outliers kept every outlier of the campaign, other set-ups' chips too.
#: review32c F3 (cat_outlier_20010, its own generator): chips of 11.5, 18.5, 12.3 um on rows 19, 26 (set-up S1) and
#: 96 (S3); S3's step fitted row 96 exactly (leverage >= 0.99, unjudged) and S3's other touches saw a step (p 2.4e-5,
#: 0.0017 after Bonferroni against 0.0025: :data:`SLIP_UNJUDGED_BY_OTHERS`), so S1's two chips, which no step
#: explained, were kept too and the report read a confident `unexplained`. Session 32, docs/discovery-studies.md,
#: "Session 32: a slip explains its own set-up's outliers".
#: **Off since session 32's end** (the lead): the fresh clone's full suite found a cost slip32's 730 tuning campaigns
#: did not hold: gen_a knock 1085 (out of the catalogue; tests/core/test_discover_misses.py) reads `unexplained`
#: without it, the right reading, and `outlier?` with it (one touch of another set-up set aside beside the knock's
#: step): right -> wrong, against 20010's wrong -> right on the reviewer's generator; on the session's 2,560 blind
#: campaigns it moved nothing. To be measured again on the knock and reseat kinds before it is switched on.
SLIP_VETO_PER_EVENT = False


#: The outlier screen's choice at a target whose touches disagree takes the physics of dust: the touches reading
#: more material are the suspects when that fits as well (:func:`_chips_read_more`); False: the behaviour before.
#: Built, measured and left off (session 22, docs/discovery.md): it mends no failure; on gen_b outlier 1000-1499 it
#: moved four workpieces, two nearer the truth (1000: 1.49 -> 0.22 um, 1179: 5.81 -> 1.13) and two further (1137:
#: 0.73 -> 1.85, 1450: 0.48 -> 1.39: burr skids, which read less material, set aside in place of their clean
#: neighbour), every check and name unchanged; on gen_a outlier, whose dust is chips only, only nearer.
OUTLIER_CHIPS_READ_MORE = False
#: With :data:`OUTLIER_CHIPS_READ_MORE`: the assignment reading more material may set aside more of a target's
#: touches than the screen's own (a target's majority; False: only as many or fewer, the screen's parsimony kept).
#: Measured and left off (session 22): it mends gen_a outlier 1505 (three chips on four touches, workpiece 1.01 ->
#: 0.22 um) but on gen_b outlier 1000-1029 it changed 20 of 30 campaigns, named right 29 -> 21 (six unexplained,
#: one local_scale_defect, one part_change confidently), workpiece_ok 28 -> 23: gen_b's burr skids read less material,
#: alone, and the clean touches beside one were set aside in its place.
OUTLIER_CHIPS_MAJORITY = False


#: The outlier screen's choice at a target whose touches disagree by likelihood: the touch set aside is the one the
#: target's face, predicted from its other targets, says disagrees (:func:`_chips_by_likelihood`); False: the
#: behaviour before (the touch furthest from the target's own fit, the majority of its touches kept).
#: Built, measured and left off (session 23, docs/discovery.md): on gen_a outlier 1000-1999 and gen_b outlier
#: 1000-1499 it changed the first screen's set in four campaigns, every workpiece nearer the truth (gen_a 1505:
#: 1.011 -> 0.216 um, 1555 0.573 -> 0.213, 1963 0.302 -> 0.209; gen_b 1000 1.488 -> 0.220), no name moved (1505
#: `outlier` -> `outlier?`: three outliers on one target); on gen_a/gen_b's other effects and the simulator it moved
#: no outcome; but no failure on the tuning seeds was left to mend, and on gen_b outlier 1500-1999 (beyond the
#: brief's seeds) it moved 1682 nearer (2.946 -> 0.416 um) and 1752 further (0.160 -> 1.425, baseline 1.486: a skid
#: on a blade, a free form the face's basis does not follow, whose three clean touches it set aside).
OUTLIER_CHIPS_LIKELIHOOD = False


def _target_z(X: np.ndarray, y: np.ndarray, keep: np.ndarray, places: Places, T: int, rows: np.ndarray):
    """(z, dof) of the rows ``rows`` of target ``T`` against the prediction of the target from its face's other
    targets, or None where the face does not predict it.

    The model is fitted on the rows ``keep`` less every touch of ``T``
    (least squares, minimum norm: ``T``'s parameter is then 0 and the
    other targets' parameters are in one gauge). A face's targets lie on a
    smooth surface; what the design cannot see of them (a shift, rotation
    and scale of the part and an offset, ``places.target_basis``) is
    fitted to the face's other targets and gives ``T``'s prediction, the
    same in every gauge. Its scatter ``tau^2`` is pooled over every face
    with targets beyond its basis' rank (the form the basis leaves, plus
    the targets' own estimation noise), with that many degrees of freedom;
    ``z = (y - machine part - prediction) / sqrt(s^2 + v + tau^2 (1 + h))``,
    ``s^2`` the fit's residual variance, ``v`` the variance of the
    estimate (``s^2`` through the fit: the machine's part at a touch that
    only ``T``'s touches tied is barely known), ``h`` the prediction's
    leverage in the face's basis. None where the face leaves no degree of freedom
    beyond the basis without ``T``, where ``T``'s row of the basis is
    outside the other targets' span, where the fit without ``T``'s touches
    does not determine the rest of the model at its rows (a set-up's
    height terms only ``T`` sees), or where no face pools a scatter.
    """
    tid, col, B, grp = places.target_idx, places.target_col, places.target_basis, places.target_group
    K = keep & (tid != T)
    has = np.bincount(tid[K], minlength=len(col)) > 0  # targets the fit sees (not T)
    m = np.flatnonzero((grp == grp[T]) & has)
    if m.size < 2 or m.size - np.linalg.matrix_rank(B[m], tol=1e-9 * np.linalg.norm(B[m], 2)) < 1:
        return None  # (the face alone decides, before the fit: a pin of four targets never predicts one)
    U, S, Vt = np.linalg.svd(X[K], full_matrices=False)
    rk = int(np.sum(S > 1e-9 * S[0])) if S.size else 0
    dof = int(K.sum()) - rk
    if rk == 0 or dof < 2:
        return None
    U, S, Vt = U[:, :rk], S[:rk], Vt[:rk]
    c = U.T @ y[K]
    theta = Vt.T @ (c / S)
    rs = y[K] - U @ c
    s2 = float(rs @ rs) / dof
    g = theta[col]
    ss, dd = 0.0, 0
    mine = None
    for G in np.unique(grp):
        m = np.flatnonzero((grp == G) & has)
        if m.size < 2:
            continue
        Ub, Sb, Vb = np.linalg.svd(B[m], full_matrices=False)
        r = int(np.sum(Sb > 1e-9 * Sb[0])) if Sb.size and Sb[0] > 0 else 0
        if G == grp[T]:
            mine = (m, Ub[:, :r], Sb[:r], Vb[:r])
        if m.size - r < 1:
            continue
        e = g[m] - Ub[:, :r] @ (Ub[:, :r].T @ g[m])
        ss += float(e @ e)
        dd += m.size - r
    if mine is None or dd == 0 or mine[0].size - mine[1].shape[1] < 1:
        return None
    m, Ub, Sb, Vb = mine
    b = B[T]
    if np.linalg.norm(b - Vb.T @ (Vb @ b)) > 1e-6 * max(np.linalg.norm(b), 1e-300):
        return None
    a = (Vb @ b) / Sb
    tau2 = ss / dd
    # each row's prediction as one linear function of the parameters: the rest of the model at the row, T's
    # parameter replaced by the face's fit of the other targets' parameters (estimable: the same in every gauge)
    L = X[rows].copy()
    L[:, col[T]] = 0.0
    L[:, col[m]] += Ub @ a
    if np.any(np.linalg.norm(L - (L @ Vt.T) @ Vt, axis=1) > 1e-6 * np.maximum(np.linalg.norm(L, axis=1), 1e-300)):
        return None  # the fit without T's touches does not determine it
    e = y[rows] - L @ theta
    est = s2 * np.sum(((L @ Vt.T) / S) ** 2, axis=1)  # the estimate's own variance (the machine's part's, mostly)
    return e / np.sqrt(s2 + est + tau2 * (1.0 + float(a @ a))), dd


def _chips_by_likelihood(X: np.ndarray, y: np.ndarray, out: list, places: Places, alpha: float, cap: int,
                         tol: float = 1e-9) -> list:
    """The screen's outliers ``out``, or the assignment the targets' faces choose where a target's touches disagree.

    At a target whose touches disagree beyond the outlier bound the
    deleted-residual screen sets aside the touch furthest from the
    target's own fit, the mean of its touches: with two chips among three
    touches it sets aside the clean one and keeps the chips, which agree
    (gen_a outlier 1505: three chips among four touches). Both assignments
    then fit; the target alone cannot tell them. Its face can: two chips
    agree only by chance, their heights independent draws, while a clean
    touch agrees with the face's other targets, a smooth surface, by
    construction. No sign is assumed (a burr's skid reads less material).

    The other assignment is the same greedy screen where, at each pass,
    the row it would set aside has touches of its target kept beside it:
    their z against the target's prediction from its face's other targets
    (:func:`_target_z`, fitted without the target's touches) are computed,
    and where the row the screen chose agrees with the prediction
    (``|z| <= t(1 - alpha / 2m, dof)``, ``m`` the target's kept touches,
    ``dof`` the pooled face scatter's) and the touch furthest from it does
    not, that touch is set aside in its place. It is taken when every row
    it sets aside is beyond the screen's bound as a prediction from the
    rows it keeps and every row of ``out`` it keeps is within it (as
    :func:`_chips_read_more`'s), at most ``cap`` rows.

    Only a screen of the baseline itself (``X`` as wide as
    ``places.n_base``): beside a cause's columns, which may reach a
    target's touches as its own parameter does, the screen's choice
    stands. Measured (session 23): on every screen, gen_b outlier 1916's
    later screen beside a local scale defect's bump set aside the true
    chip in place of a clean touch, and the bump, which that clean
    touch's misfit had refuted, was named (``outlier`` ->
    ``local_scale_defect?``); on the baseline's screens alone, nothing else
    measured moved.
    """
    if (places.target_idx is None or places.target_basis is None or len(places.target_idx) != len(y)
            or X.shape[1] != places.n_base):
        return out  # (the baseline's screens only: beside a cause's columns the face's prediction is not formed)
    tid = places.target_idx
    keep = np.ones(len(y), bool)
    keep[out] = False
    if not any(np.any(keep & (tid == tid[i])) for i in out):
        return out
    swapped = False

    def choose(keep, idx, r, ok, k):
        nonlocal swapped
        mates = np.flatnonzero(tid[idx] == tid[idx[k]])
        if mates.size >= 2:
            zd = _target_z(X, y, keep, places, int(tid[idx[k]]), idx[mates])
            if zd is not None:
                z, dd = zd
                c = stats.t.isf(alpha / (2 * mates.size), dd)
                j = int(np.argmax(np.abs(z)))
                if mates[j] != k and abs(z[j]) > c and abs(z[int(np.flatnonzero(mates == k)[0])]) <= c:
                    swapped = True
                    return int(mates[j])
        return k

    screened = _greedy_screen(X, y, alpha, cap, choose, tol)
    if screened is None:
        return out
    alt, keep = screened
    if not swapped or sorted(alt) == sorted(out):
        return out
    return sorted(alt) if _assignment_holds(X, y, keep, out, alt, alpha) else out


def _greedy_screen(X: np.ndarray, y: np.ndarray, alpha: float, cap: int, choose, tol: float = 1e-9):
    """The deleted-residual screen's greedy removals, where ``choose`` may set aside another row in the screen's
    place: the row of the largest studentized deleted residual beyond the Bonferroni t bound, one at a time, each
    fit refactored on the rows kept; ``choose(keep, idx, r, ok, k)`` (``idx`` the rows kept, ``r`` their
    residuals, ``ok`` where the deleted t is defined, ``k`` the screen's choice, positions in ``idx``) returns the
    position set aside. ``(alt, keep)``: the rows set aside in order and the mask of those kept; None where more
    than ``cap`` rows would be. What :func:`_chips_by_likelihood` and :func:`_chips_read_more` try beside the
    screen's own choice."""
    keep = np.ones(len(y), bool)
    alt: list[int] = []
    while True:
        idx = np.flatnonzero(keep)
        Q = orth_of(X[idx], tol)  # (the screen's cut: find_outliers' rank_tol)
        dof = len(idx) - Q.shape[1]
        if dof < 3:
            break
        r = y[idx] - Q @ (Q.T @ y[idx])
        tstat, ok = _deleted_t(Q, r, dof)
        k = _first_largest(tstat)
        if tstat[k] <= stats.t.isf(alpha / (2 * len(idx)), dof - 1):
            break
        if len(alt) >= cap:
            return None
        k = choose(keep, idx, r, ok, k)
        alt.append(int(idx[k]))
        keep[idx[k]] = False
    return alt, keep


def _assignment_holds(X: np.ndarray, y: np.ndarray, keep: np.ndarray, out, alt, alpha: float) -> bool:
    """Whether the other assignment ``alt`` (kept rows ``keep``) explains the data as the screen's ``out`` does:
    every row it sets aside beyond the screen's bound as a prediction from the rows it keeps, and every row of
    ``out`` it keeps within it."""
    t_alt, dof = _prediction_t(X, y, keep, np.asarray(alt))
    bound = stats.t.isf(alpha / (2 * int(keep.sum())), dof - 1)
    back = np.setdiff1d(out, alt)
    t_back = _prediction_t(X, y, keep, back)[0] if back.size else np.zeros(0)
    return bool(np.all(np.isfinite(t_alt)) and np.all(np.abs(t_alt) > bound)
                and np.all(np.isfinite(t_back)) and np.all(np.abs(t_back) <= bound))


def _prediction_t(X: np.ndarray, y: np.ndarray, keep: np.ndarray, rows: np.ndarray):
    """(t, bound_dof) the prediction t of ``rows`` from the least-squares fit on the rows ``keep`` (boolean)
    of ``X``, signed (positive: the row reads more than the fit), and that fit's residual dof; t is NaN for a row
    the kept rows do not determine (a component outside their row space)."""
    Xk = X[keep]
    U, S, Vt = np.linalg.svd(Xk, full_matrices=False)
    rk = int(np.sum(S > 1e-9 * S[0])) if S.size else 0
    U, S, Vt = U[:, :rk], S[:rk], Vt[:rk]
    dof = int(keep.sum()) - rk
    r = y[keep] - U @ (U.T @ y[keep])
    s2 = float(r @ r) / max(dof, 1)
    Xr = X[rows]
    A = (Xr @ Vt.T) / S
    out_of_span = np.linalg.norm(Xr - (Xr @ Vt.T) @ Vt, axis=1) > 1e-6 * np.maximum(np.linalg.norm(Xr, axis=1), 1e-300)
    e = y[rows] - Xr @ (Vt.T @ ((U.T @ y[keep]) / S))
    t = e / np.sqrt(max(s2, 1e-300) * (1.0 + np.sum(A ** 2, axis=1)))
    return np.where(out_of_span, np.nan, t), dof


def _chips_read_more(X: np.ndarray, y: np.ndarray, out: list, places: Places, alpha: float, cap: int,
                     tol: float = 1e-9) -> list:
    """The screen's outliers ``out``, or the other assignment at the targets whose touches disagree.

    Dust on a touch is a particle between the stylus and the surface (a
    chip, debris, swarf): the stylus meets it first and the touch triggers
    early, reading more material, never less. Where a target (the same
    place of the part, every set-up) has touches that disagree beyond the
    outlier bound, the deleted-residual screen removes the touch furthest
    from the fit, and the fit there is the mean of the target's touches:
    two chips of one target among three touches pull the fit towards
    themselves and leave the clean touch furthest (reading less material),
    so the screen sets aside the clean touch and keeps the chips, which
    agree (gen_a outlier 1505: two chips among four touches, the two clean
    ones removed). Both assignments then fit; only the physics tells them.

    The other assignment is the same greedy screen where the row it would
    remove reads less material than the fit and its target has kept
    touches reading more: the target's touch reading most material is set
    aside in its place (at most ``cap`` rows, the screen's own cap). It is
    taken when (1) every row it sets aside is beyond the bound as a
    prediction from the touches it keeps, (2) every row of ``out`` it keeps
    is within the bound there, and (3) at each target where it set a touch
    aside in place of another it sets aside no more of the target's touches
    than ``out`` (:data:`OUTLIER_CHIPS_MAJORITY`: also more), the screen's
    parsimony kept: where the counts tie the data do not choose, and the
    physics does. Elsewhere it may set aside more (a smaller chip the
    disagreeing target hid, beyond the bound once its chips are out). A skid on a burr (the stylus slides off
    an edge and triggers late) reads less material, alone; where one sits
    among clean touches of its target, both assignments fit too, the
    skid's setting aside one touch against the clean touches' two or more:
    (3) keeps it.
    """
    if "target" not in places.names:
        return out
    tg = places.codes[:, places.names.index("target")]
    keep = np.ones(len(y), bool)
    keep[out] = False
    t_out, _ = _prediction_t(X, y, keep, np.asarray(out))
    # only where a removed row reads less material than the fit and its target keeps other touches
    if not any(t < 0 and np.any(keep & (tg == tg[i])) for i, t in zip(out, t_out) if np.isfinite(t)):
        return out
    swapped: set = set()

    def choose(keep, idx, r, ok, k):
        if r[k] < 0:
            mates = np.flatnonzero((tg[idx] == tg[idx[k]]) & (r > 0) & ok)
            if mates.size:
                k = int(mates[np.argmax(r[mates])])
                swapped.add(int(tg[idx[k]]))
        return k

    screened = _greedy_screen(X, y, alpha, cap, choose, tol)
    if screened is None:
        return out
    alt, keep = screened
    if not swapped or sorted(alt) == sorted(out):
        return out
    if not OUTLIER_CHIPS_MAJORITY and any(np.sum(tg[alt] == T) > np.sum(tg[out] == T) for T in swapped):
        return out
    return sorted(alt) if _assignment_holds(X, y, keep, out, alt, alpha) else out


def _without_row(Q: np.ndarray, k: int) -> np.ndarray:
    """An orthonormal basis of the column space ``Q`` (n, r) spans on its rows but row ``k``, (n - 1, r).

    The rows left have the Gram matrix ``I - q q^T`` (``q = Q[k]``, ``s = q . q``
    its leverage, below 1): ``Q' = Q_rest (I + c q q^T)`` with
    ``c = (1 / sqrt(1 - s) - 1) / s`` is orthonormal (``(1 + c s)^2 (1 - s) = 1``
    along ``q``, the identity across it) and spans the same space: the
    downdate of the factorisation by one row, O(n r) instead of a pivoted QR
    of the rows left (O(n r^2)). The same span to rounding, so the same
    residuals and leverages (``find_outliers`` removes only rows of leverage
    below 0.99: the factor ``1 / sqrt(1 - s)`` stays below 10 and the rank
    is kept). Not always the rank a fresh factorisation would find: ``orth``
    cuts a pivoted QR at ``|R_ii| <= 1e-9 |R_00|``, so a direction of the rows
    left lying near that cut-off could be dropped by a fresh ``orth`` where the
    downdate keeps it (the basis then one column wider: y's share along that
    direction is projected out too, and the dof one fewer).
    """
    q = Q[k].copy()
    s = float(q @ q)
    rest = np.delete(Q, k, axis=0)
    if s == 0.0:
        return rest
    c = (1.0 / np.sqrt(1.0 - s) - 1.0) / s
    return rest + (rest @ q)[:, None] * (c * q)[None, :]


def first_per_event(idx, events) -> list:
    """The first of the rows ``idx`` (in their order) in each event of ``events``; a negative key: a row of its own.

    What the concentration test counts: one piece of dust corrupts an
    event's touches together (:func:`find_outliers`'s ``events``).
    """
    ev = np.asarray(events)[idx]
    ev = np.where(ev >= 0, ev, -1 - np.arange(len(idx)))
    return [idx[i] for i in sorted(np.unique(ev, return_index=True)[1])]


def _exact_step(Cs: StepTrials, best: int, Q0: np.ndarray, r0: np.ndarray, rows=None, examined=None) -> np.ndarray:
    """(n, k) the step of trial ``best``'s set-up that explains most of ``r0``, its split at any touch near ``best``'s.

    :func:`core.causes.fixture_slip` keeps at most ``SLIP_SPLITS`` splits
    per set-up, at quantiles of its touches in time: on a set-up of more
    touches a slip's own first touch is between two trials' splits (gen_a's
    set-ups of about 70 touches, a split every second touch), and the best
    trial starts the step one touch late or early. A step of a few um then
    leaves that touch at the step's full size, beyond the outlier bound:
    gen_a knock 1040, the knock from row 202, the best trial from row 203,
    row 202 left 3.36 um at t 11.8 against the bound 4.79 (noise 0.35 um),
    so the slip veto read the knock's seven touches as dust. The step's
    split is refined to the touch between the best trial's neighbours
    (every split there, or ``SLIP_SPLITS`` of them at quantiles and again
    between the best's neighbours, down to one touch: the same bounded
    number of columns per pass as the scan), by the same criterion: the
    sum of squares it explains on every row. Only the step the veto adopts
    changes, not its trials, tests or their Bonferroni counts.

    The counts stay honest. In the veto the refined step enters only the
    first condition of :func:`_slip_explains` (no outlier left beyond the
    bound), a heuristic with no stated level; its test (the second
    condition) is the trials' own F test on the kept touches, Bonferroni
    over the event's trials, not refined. In the rival check the refined
    split is chosen by the data after the trials' maximum, so its debias
    counts every split whose sum of squares was computed (``examined``):
    the trials' ``T`` plus about two per refinement on a set-up split every
    second touch (gen_a), up to ``SLIP_SPLITS`` per pass on a longer one.
    A strict count of every split the search could end at is every touch
    of every set-up, at most about ``2 T`` where the trials take every
    second touch; the median of the largest of ``2 T`` chi-squares (3 dof)
    exceeds that of ``T`` by 1.5 (T 80-640, about ``2 ln 2``), against 0.01-0.05
    for ``T + 2``, in units of ``s^2``. Neighbouring splits differ by one
    touch, so their sums of squares are nearly the same and the effective
    number of trials grows far less than the positions: the count examined
    is within 1.5 ``s^2`` of the strict one, and not smaller than the
    trials' own.

    ``rows`` (None: every row): the rows ``Q0`` and ``r0`` hold, the step
    returned on them (the rival check of a cause, :func:`_evaluate`, whose
    slip is refined the same way). ``examined`` (a list): the splits tried
    beyond the trial's own are appended to it (the rival's debias counts
    them as trials).
    """
    j = int(np.searchsorted(Cs.offsets, best, side="right")) - 1
    idx, splits = Cs.groups[j]
    i = best - int(Cs.offsets[j])
    split = int(splits[i])
    lo = int(splits[i - 1]) + 1 if i > 0 else 1
    hi = int(splits[i + 1]) - 1 if i + 1 < splits.size else idx.size - 1
    rss0 = float(r0 @ r0)
    dof0 = len(r0) - Q0.shape[1]
    while hi > lo:
        cand = np.arange(lo, hi + 1)
        if cand.size > causes_mod.SLIP_SPLITS:
            cand = np.unique(np.round(np.linspace(lo, hi, causes_mod.SLIP_SPLITS)).astype(int))
        ss, _, _, _ = nested_f_trials(StepTrials(Cs.M, [(idx, cand)]), rows, Q0, r0, rss0, dof0)
        if examined is not None:
            examined.extend(int(c) for c in cand if c != int(splits[i]))
        b = int(np.argmax(ss))
        split = int(cand[b])
        if cand.size == hi - lo + 1:
            break
        lo = int(cand[b - 1]) + 1 if b > 0 else lo
        hi = int(cand[b + 1]) - 1 if b + 1 < cand.size else hi
    return StepTrials(Cs.M, [(idx, np.array([split]))]).take([0], rows)[0]


#: Where the slip veto's step fits every outlier of the event exactly (each of leverage 0.99 or more beside it: none
#: judged, :func:`_slip_explains`), the set-up's other touches decide (its second condition, the step's F test with
#: every outlier set aside, which keeps its level under dust whichever rows the chips hit) instead of the event
#: being left dust unasked. A knock just after a set-up's last touches that fix the part's turn (gen_a knock 6109:
#: the set-up's first touches bores and bosses, blind to a turn about their axis; the two touches before the knock,
#: wall4 and slot4, fixed the step's turn, leverage 0.9994 and 0.995) leaves those two touches as the outliers the
#: step fits exactly; the other touches saw the step at p 3e-36, and the report read `outlier?`. False: the rule
#: before (session 25, docs/discovery.md "Session 25: hedged outliers of effects that are not dust").
SLIP_UNJUDGED_BY_OTHERS = True
#: An event's single outlier is judged by the slip veto too (True), where the step leaves it within the bound (or
#: fits it exactly) and the set-up's other touches see the step (the veto's second condition: one outlier never
#: outnumbers the step's parameters). False: only events of two or more outliers are judged (the rule before).
SLIP_ONE_OUTLIER_BY_OTHERS = True


def _slip_explains(X: np.ndarray, y: np.ndarray, out: list, events: np.ndarray, slips, alpha: float,
                   alpha_step: float, tol: float = 1e-9, explained: list | None = None) -> bool:
    """Whether one step of :func:`find_outliers`'s ``slips`` explains an event's outliers (two or more; one with
    :data:`SLIP_ONE_OUTLIER_BY_OTHERS`, judged by the second condition below: one never outnumbers the step's
    parameters).

    A slip moves the part once and every touch after it stays moved; a chip
    corrupts the touch it sits under and nothing else. A step explains an
    event's outliers when, adopted on every row, it leaves none of them
    beyond the Bonferroni bound ``t(1 - alpha / 2n, dof - 1)`` (they are
    the step's), and that agreement is evidence, one of:

    1. the outliers outnumber the step's free parameters (its columns:
       two translations and a turn; counted among those it judges: an
       outlier it fits exactly (leverage above 0.99), has no deleted
       residual and is neither left beyond the bound nor agreeing; gen_a
       knock 1609's first touch of its set-up. Such a row is explained by
       the step without evidence of its own, beside judged outliers that
       agree; with none judged the step explains nothing by this
       condition, and the second decides (:data:`SLIP_UNJUDGED_BY_OTHERS`,
       session 25: gen_a knock 6109)): their agreement
       with one rigid motion
       then constrains it (as many constraints as outliers beyond the
       parameters, each at the outlier bound). A heuristic, not a test of
       known level: its false-alarm rate under dust is not computed (the
       best of the set-up's trials is chosen on the same rows). A knock of 5-25 um moves
       every touch after it beyond the bound (gen_a knock 811: the 12
       touches after it, all outliers, nothing else left to see it);
    2. or, fewer outliers than the step has parameters (the step can fit
       any of their values), the set-up's other touches see a step: with
       every outlier set aside, the trial confined to that event that
       explains most of the rest (nested F test against the model ``X``)
       is significant at ``alpha_step``, Bonferroni over that event's
       trials and the events tested. Under dust the outliers' rows are
       independent of the other touches' noise, so this keeps its level
       whichever rows the chips hit. The step adopted is still the best
       trial on every row (the other touches' own best trial left an
       outlier beyond the bound at gen_b fixture_slip 929 and gen_a knock
       818 and 828, all real slips).

    The step adopted is the best trial's set-up's step with its split
    refined to the touch (:func:`_exact_step`): the trials split a long
    set-up only at quantiles, and a step one touch late leaves its own
    first touch beyond the bound (session 22: gen_a knock 1040, 1034, 1085,
    gen_b fixture_slip 1030).

    Known and kept: the step adopted need not move the outliers it
    explains (on structured data the step's misfit inflates ``s^2`` and an
    unmoved outlier falls inside the bound: gen_a knock 1028, outliers at
    rows 179 and 181, the adopted step moving rows 182-215); and the F test
    refits the trials' columns on the other touches freely (it does not
    ask that fit to predict the outliers). Both checks were tried (session
    10): 9 real knocks and fixture slips of 640 tuning campaigns then lost
    their cause (unexplained -> outlier), none gained.

    Without the second condition's test, the step's three parameters placed
    next to two chips of one set-up absorbed them with nothing else moving
    (gen_a outlier 800, 813, 830, 840, 1108, 1109: chips kept, ``none`` or
    ``unexplained``). ``alpha_step``: the concentration test's family level
    (:func:`find_outliers`'s ``alpha_concentration``): this test, like that
    one, decides that outliers are structure rather than dust.

    ``explained``: a list to which every event a step explains is appended
    (all events are then judged, not only up to the first explained); the
    return value is the same (whether any is).
    """
    out = np.asarray(out, int)
    ev = events[out]
    multi = [e for e in np.unique(ev[ev >= 0]) if np.sum(ev == e) >= (1 if SLIP_ONE_OUTLIER_BY_OTHERS else 2)]
    if not multi:
        return False
    Cs = slips()  # (T, n, k) dense, or StepTrials (built where used)
    if Cs.shape[0] == 0:
        return False
    if isinstance(Cs, StepTrials):
        moved = Cs.moved_event(events)  # (T,) the one event each trial moves, if one
    else:
        on = np.any(Cs != 0, axis=2)  # (T, n) rows each trial moves
    n = len(y)
    Q0 = orth_of(X, tol)  # (the screen's cut: find_outliers' rank_tol)
    r0 = y - Q0 @ (Q0.T @ y)
    kept = np.setdiff1d(np.arange(n), out)
    Qk = rk = None

    def fits(C, rows):
        """(the step's parameters, whether adopted on every row it leaves none of ``rows`` beyond the bound,
        how many of ``rows`` it judges); ``C`` (n, k): the step's columns.

        A row the trial fits exactly (leverage 1: the step's turn fixed by
        that one touch, the set-up's other touches before the step all on a
        bore, blind to a turn about its axis: gen_a knock 1609's first touch
        of its set-up) has no deleted residual: it is neither left beyond the
        bound nor evidence of agreement, and is not counted as judged.
        """
        W = new_basis(Q0, C)
        Q = np.hstack([Q0, W])
        r = y - Q @ (Q.T @ y)
        dof = n - Q.shape[1]
        if dof < 3:
            return W.shape[1], False, 0
        den = 1 - leverage(Q)[rows]
        judged = den >= 0.01
        if not np.any(judged):
            return W.shape[1], False, 0
        rj, dj = r[rows][judged], den[judged]
        s2 = (float(r @ r) - rj ** 2 / dj) / (dof - 1)
        tstat = np.abs(rj) / np.sqrt(np.maximum(s2, 1e-300) * dj)
        return W.shape[1], bool(np.all(tstat <= stats.t.isf(alpha / (2 * n), dof - 1))), int(judged.sum())

    for e in multi:
        rows = out[ev == e]
        if isinstance(Cs, StepTrials):
            trials = np.flatnonzero(moved == e)
        else:
            trials = np.flatnonzero(np.all(~on[:, events != e], axis=1) & np.any(on[:, events == e], axis=1))
        if trials.size == 0:
            continue
        # 1. the step that fits every row best (removes most of the residual): more outliers than its
        # parameters, all its own (the event's trials, at most SLIP_SPLITS: one batch, or blocks on a long log)
        ss0, _, _, _ = nested_f_trials(Cs, None, Q0, r0, float(r0 @ r0), n - Q0.shape[1], ts=trials)
        best = trials[int(np.argmax(ss0))]
        q, ok, judged = fits(_exact_step(Cs, best, Q0, r0) if isinstance(Cs, StepTrials)
                             else trials_take(Cs, [best])[0], rows)
        if not ok and not (SLIP_UNJUDGED_BY_OTHERS and judged == 0):
            continue
        if judged > q:
            if explained is None:
                return True
            explained.append(int(e))
            continue
        # 2. fewer outliers than parameters: the other touches must see a step in this event
        if Qk is None:
            Qk = orth_of(X[kept], tol)
            rk = y[kept] - Qk @ (Qk.T @ y[kept])
        dof_k = len(kept) - Qk.shape[1]
        _, k, _, p = nested_f_trials(Cs, kept, Qk, rk, float(rk @ rk), dof_k, ts=trials)
        p = np.where((k > 0) & (dof_k - k >= 3), p, np.inf)
        if p.min() * len(trials) * len(multi) < alpha_step:
            if explained is None:
                return True
            explained.append(int(e))
    return bool(explained)


def _place_carries(Q: np.ndarray, r: np.ndarray, kept: np.ndarray, out, events: np.ndarray, places: Places,
                   alpha: float, material_sigma: float) -> dict | None:
    """The feature holding outliers of two or more events whose other touches carry structure, if any.

    Dust corrupts the touches it sits under and nothing else: the rest of
    the feature it fell on is as clean as any. A feature that changes (a
    wall relaxing, a boss growing) moves all its touches, and the outliers
    are only its largest residuals, set-up after set-up. So, per feature
    holding outliers of at least two events (one set-up's chips cannot
    tell), its other touches are tested with the outliers set aside: any
    pattern of that feature set-up by set-up (``places.columns``) against
    the model (``Q`` orthonormal on the rows ``kept``, ``r`` their
    residuals), nested F test, Bonferroni over the features tested at
    ``alpha``, and material (debiased, ``material_sigma`` noise sigmas per
    touch of the feature). Under dust the outliers' places are independent
    of the other touches' noise, so the test keeps its level whichever
    feature they picked. Returns ``{feature, F, p_adjusted, k,
    explained_ss_um2}`` of the first such feature, or None.
    """
    if places.feature is None or places.columns is None:
        return None
    out = np.asarray(out, int)
    feats = places.feature
    tested = []
    for f in dict.fromkeys(feats[out].tolist()):
        on = out[feats[out] == f]
        if np.unique(events[on][events[on] >= 0]).size + int(np.sum(events[on] < 0)) >= 2:
            tested.append(f)
    dof = len(kept) - Q.shape[1]
    for f in tested:
        W = new_basis(Q, np.asarray(places.columns(f), float)[kept])
        k = W.shape[1]
        if k == 0 or dof - k < 3:
            continue
        ss = float(np.sum((W.T @ r) ** 2))
        s2 = (float(r @ r) - ss) / (dof - k)
        F = (ss / k) / max(s2, 1e-300)
        p = float(stats.f.sf(F, k, dof - k)) * len(tested)
        if p < alpha and ss - k * s2 >= material_sigma ** 2 * s2 * int(np.sum(feats[kept] == f)):
            return {"feature": str(f), "F": F, "p_adjusted": min(p, 1.0), "k": int(k),
                    "explained_ss_um2": (ss - k * s2) / UM ** 2}
    return None


#: Draws of the concentration test's null (its smallest p-value is 1 / (draws + 1)).
CONCENTRATION_DRAWS = 20000
#: A drawn statistic of normalised ranks (a mean rank's shift, a spread of ranks: values in 0..1) within this of the
#: observed one reaches it (counted as an exceedance: a tie goes against the test). Drawing the outliers' own ranks
#: in another order gives the same statistic up to rounding (a mean of k values below 1: about k eps, 1e-13 for
#: k = 500), which must not pass for smaller. The same rule as :func:`centred_turn_p`'s tolerance, which is
#: relative instead (1e-9 of a bound of its statistic) because that statistic is in residual units, not ranks;
#: not the tests' ties of core.diagnosis (``TIE_RTOL``: sums of squares against one model, relative to its rss).
RANK_TIE = 1e-12


#: Covariate families of a touch's own history (the move that led to it: :func:`_outlier_finding`'s ``history``).
HISTORY_FAMILIES = ("history",)


def covariate_ranks(covariates, families=None) -> np.ndarray:
    """(n, m) normalised ranks ``(rank - 1/2) / n`` (ties averaged) of the scalar covariates that vary.

    Smooth covariates only: a category has no order, an angle no ends
    (categories are tested as places, :class:`Places`). ``families``: only
    the covariates of those families (default: all).
    """
    cols = []
    for c in covariates:
        v = np.asarray(c.values)
        if c.kind != "smooth" or v.ndim != 1 or np.ptp(v) <= 0:
            continue
        if families is not None and c.family not in families:
            continue
        cols.append((stats.rankdata(v) - 0.5) / len(v))
    return np.column_stack(cols) if cols else np.zeros((0, 0))


@dataclass(frozen=True)
class Places:
    """Where on the part each row touches, for the concentration test's categories.

    Attributes
    ----------
    codes : (n, c) int
        Per row its category in each of ``names`` (the feature; the target,
        the same place of the part in every set-up).
    names : tuple of str
    units : (n,) int
        What one piece of dust corrupts at one place: the target within its
        set-up (a chip corrupts the touches of the place it sits on, in that
        set-up, and nothing else; two chips of one set-up sit at independent
        places). Negative: a row of its own.
    feature : (n,) object, optional
        Each row's feature (the :func:`find_outliers` place check).
    columns : callable(feature) -> (n, m), optional
        Any pattern of that feature's touches set-up by set-up (each wall
        of it in each set-up: :func:`core.causes.part_change_rival`), what
        a feature that changes could do.
    target_idx : (n,) int, optional
        Each row's target (0 .. N_w - 1: the baseline's workpiece parameters, in their order).
    target_col : (N_w,) int, optional
        Each target's workpiece parameter: its column in the design.
    target_basis : (N_w, b) float, optional
        Each target's row of what the design cannot see of the workpiece (a shift, rotation and scale of the part
        and a common offset: :func:`core.selfcal.workpiece_gauge_basis`), the span in which one face's targets are
        predicted from one another (:func:`_target_z`).
    target_group : (N_w,) int, optional
        Each target's face: a feature's targets of one normal where the feature has three normals or fewer (a
        wall, a slot's sides), else the feature's (a bore, a boss).
    n_base : int, optional
        The baseline design's number of columns (a screen of the baseline itself: :func:`_chips_by_likelihood`).
    """

    codes: np.ndarray = field(repr=False)
    names: tuple
    units: np.ndarray = field(repr=False)
    feature: np.ndarray | None = field(default=None, repr=False)
    columns: object = field(default=None, repr=False)
    target_idx: np.ndarray | None = field(default=None, repr=False)
    target_col: np.ndarray | None = field(default=None, repr=False)
    target_basis: np.ndarray | None = field(default=None, repr=False)
    target_group: np.ndarray | None = field(default=None, repr=False)
    n_base: int | None = None


def places_of(bl: Baseline) -> Places | None:
    """The places of a planar campaign's rows (feature, target; units per target and set-up); None for others."""
    if bl.kind != "planar":
        return None
    t = bl.data.touches
    cols, names = [], []
    for name, v in (("feature", np.asarray(t.feature, dtype=object)), ("target", np.asarray(t.target))):
        codes = np.unique(v.astype(str), return_inverse=True)[1]
        if codes.max(initial=0) >= 1:  # a category that varies
            cols.append(codes)
            names.append(name)
    if not cols:
        return None
    units = np.asarray(t.setup, int) * (int(np.max(t.target)) + 1) + np.asarray(t.target, int)
    feats = np.asarray(t.feature, dtype=object)
    return Places(np.column_stack(cols), tuple(names), units, feats,
                  lambda f: causes_mod.part_change_rival(bl, {"feature": f}), *_target_faces(bl, t, feats))


def _target_faces(bl: Baseline, t: Touches, feats: np.ndarray) -> tuple:
    """(target_idx, target_col, target_basis, target_group, n_base) of :class:`Places`, or five Nones where the
    baseline has no workpiece parameter per target (its geometry unknown)."""
    geo = getattr(bl, "geometry", None)
    n_w = len(bl.estimand) if bl.estimand is not None else 0
    tid = np.asarray(t.target, int)
    if geo is None or n_w == 0 or len(geo[0]) != n_w or tid.size == 0 or tid.max() >= n_w:
        return None, None, None, None, None
    P, N = np.asarray(geo[0], float), np.asarray(geo[1], float)
    if (fz := selfcal.target_heights(t, n_w)) is None:
        return None, None, None, None, None
    first, dz = fz  # each target's first touch, its height above the common level
    B = selfcal.workpiece_gauge_basis(P, N, dz if np.any(dz != 0) else None)
    f_t = feats[first].astype(str)
    nrm = np.round(N, 3)
    key, planar_faces = [], {}  # (a feature's faces told apart when it has at most three normals: once a feature)
    for j in range(n_w):
        if f_t[j] not in planar_faces:
            planar_faces[f_t[j]] = len(np.unique(nrm[f_t == f_t[j]], axis=0)) <= 3
        key.append((f_t[j], tuple(nrm[j])) if planar_faces[f_t[j]] else (f_t[j],))
    grp = np.unique(np.array([repr(k) for k in key]), return_inverse=True)[1]
    return tid, np.asarray(bl.estimand, int), B, grp, int(bl.A.shape[1])


#: Elements of one block of :func:`_max_share`'s draws (memory stays at a few tens of MB whatever the count).
SHARE_BLOCK = 1 << 21


def _max_share(codes: np.ndarray) -> np.ndarray:
    """(d, k) category codes -> (d,) the largest number of each row's codes equal to one another (sorted runs)."""
    codes = np.atleast_2d(codes)
    d, k = codes.shape
    out = np.empty(d, int)
    step = max(1, SHARE_BLOCK // max(k, 1))
    pos = np.arange(k)
    for a in range(0, d, step):
        S = np.sort(codes[a:a + step], axis=1)
        start = np.where(np.concatenate([np.ones((len(S), 1), bool), S[:, 1:] != S[:, :-1]], axis=1), pos, 0)
        out[a:a + step] = np.max(pos - np.maximum.accumulate(start, axis=1), axis=1) + 1
    return out


def _shift_p(ranks: np.ndarray, rows: np.ndarray, drawn: np.ndarray) -> np.ndarray:
    """(m,) Monte Carlo p-values of the two-sided shift ``|mean rank of the rows - mean rank of all|`` per column.

    ``drawn`` (draws, k, m): the null's rows; p = (1 + exceedances) / (draws + 1).
    """
    mu = ranks.mean(axis=0)
    shift = np.abs(ranks[rows].mean(axis=0) - mu)
    return (1 + np.sum(np.abs(drawn.mean(axis=1) - mu) >= shift - RANK_TIE, axis=0)) / (len(drawn) + 1)


def concentration_p(ranks: np.ndarray, idx, rng: np.random.Generator, draws: int = CONCENTRATION_DRAWS,
                    places: Places | None = None, place_idx=None, history_ranks: np.ndarray | None = None,
                    place_rows=None) -> float:
    """Bonferroni-adjusted p-value that the rows ``idx`` fall at random over every covariate.

    Two statistics per covariate: the shift ``|mean rank of the rows -
    mean rank of all|`` (the rows sit at either end: early or late in the
    campaign, after long rests or short ones) and the spread ``max - min`` of
    their ranks (the rows sit together anywhere: the touches after a part
    moved in the middle of a set-up). Null: ``k`` rows drawn at random
    (with replacement: a slightly wider null than without, so the test is
    conservative), ``draws`` Monte Carlo draws, p = (1 + exceedances) /
    (draws + 1); the smallest over the ``2 m`` statistics times ``2 m``.

    With ``places``, one statistic per category as well (the feature, the
    target: :class:`Places`): the largest number of the rows ``place_idx``
    (one per dust unit) that share one category. Dust falls at random
    places; a feature that changes, a wall that relaxes, leaves its largest
    residuals on that feature, set-up after set-up. Null: as many units
    drawn at random (with replacement) from all the campaign's units;
    the Bonferroni factor counts these statistics too.

    With ``history_ranks`` ((n, h) ranks of the covariates of a touch's own
    history, which ``ranks`` also holds), the shift alone of the rows
    ``place_rows`` (one per place: target and set-up) in each of them,
    against as many rows drawn at random (with replacement, every row
    alike); two-sided, as the shift above (the rows sit at either end:
    after long rests or short ones, after large turns or none); the
    Bonferroni factor counts these ``h`` statistics too, so the whole is
    one family at one level (:func:`_outlier_finding`: the history counted
    per event by ``ranks`` and per place here).
    """
    idx = np.asarray(idx, int)
    n, m = ranks.shape if ranks.ndim == 2 else (0, 0)
    ps = []
    if m and idx.size >= 2:
        Rn = ranks[rng.integers(0, n, (draws, idx.size))]  # (draws, k, m)
        ps.append(_shift_p(ranks, idx, Rn))
        ps.append((1 + np.sum(np.ptp(Rn, axis=1) <= np.ptp(ranks[idx], axis=0) + RANK_TIE, axis=0)) / (draws + 1))
    n_stats = 2 * m if ps else 0
    if places is not None and place_idx is not None and len(place_idx) >= 2:
        pi = np.asarray(place_idx, int)
        u = np.where(places.units >= 0, places.units, -1 - np.arange(len(places.units)))
        reps = np.unique(u, return_index=True)[1]  # one row per unit: the null's draws
        obs = [_max_share(places.codes[pi, c][None])[0] for c in range(places.codes.shape[1])]
        exceed = np.zeros(len(obs))
        step = max(1, SHARE_BLOCK // pi.size)  # (one block of draws for any campaign's outliers but a huge one)
        for a in range(0, draws, step):
            pick = reps[rng.integers(0, reps.size, (min(step, draws - a), pi.size))]
            exceed += [np.sum(_max_share(places.codes[pick, c]) >= o) for c, o in enumerate(obs)]
        ps.append((1 + exceed) / (draws + 1))
        n_stats += places.codes.shape[1]
    if (history_ranks is not None and place_rows is not None and len(place_rows) >= 2 and history_ranks.ndim == 2
            and history_ranks.shape[1]):
        pr = np.asarray(place_rows, int)
        ps.append(_shift_p(history_ranks, pr, history_ranks[rng.integers(0, len(history_ranks), (draws, pr.size))]))
        n_stats += history_ranks.shape[1]
    if not ps:
        return 1.0
    return float(min(1.0, min(float(np.min(p)) for p in ps) * n_stats))


#: Draws of the centred-turn test's null (:func:`centred_turn_p`): Monte Carlo SE of a p-value of 0.0025
#: (``alpha_family``) sqrt(0.0025 * 0.9975 / 1e5) = 1.6e-4, 6 % of it; smallest p 1e-5.
TURN_DRAWS = 100_000


def centred_turn_of(t_s, d, target) -> np.ndarray:
    """(n,) each touch's turn of the approach less the mean turn of its target's touches (all set-ups), deg.

    ``t_s`` (n,) touch times, ``d`` (n, 3) unit approach directions, ``target``
    (n,) the place of the part each touch measures (the same in every
    set-up). The turn is the engine's history covariate
    (:func:`core.baseline.touch_history`: the angle between the approach and
    the previous touch's, in time order). The campaign's first touch has no
    previous touch: its turn is that covariate's convention, 0 (no turn), and
    it enters its target's mean as such (a probe fresh from its
    qualification has not re-seated; the test's level does not rest on it, as
    the null draws touches whatever their turns). A target touched once has
    its centred turn 0.
    """
    t_s = np.asarray(t_s, float)
    d = np.asarray(d, float)
    target = np.asarray(target)
    n = len(t_s)
    if d.shape != (n, 3) or target.shape != (n,):
        raise ConfigError(f"centred_turn_of: t_s (n,), d (n, 3), target (n,) expected, got {t_s.shape}, "
                         f"{d.shape}, {target.shape}")
    if not (np.all(np.isfinite(t_s)) and np.all(np.isfinite(d))):
        raise ConfigError("centred_turn_of: touch times and approach directions must be finite")
    if n == 0:
        return np.zeros(0)
    _, turn = bl_mod.touch_history(t_s, d)
    tg = np.unique(target, return_inverse=True)[1].ravel()
    mean = np.bincount(tg, weights=turn) / np.bincount(tg)
    return turn - mean[tg]


def centred_turn(bl: Baseline) -> np.ndarray | None:
    """:func:`centred_turn_of` of a planar campaign's touches; None for a campaign without targets (not
    planar) or where every centred turn is 0 (no target's touches differ in their turn: nothing to test), and
    None where the touches do not map one to one onto the baseline's rows (the test is then off, with no
    key in the evidence; met on no campaign of the session-13 studies)."""
    if bl.kind != "planar":
        return None
    t = bl.data.touches
    if len(np.asarray(t.t_s)) != len(bl.y):
        return None
    d_prev = getattr(t, "d_prev_R", None)
    if TURN_THROUGH_NO_TRIGGER and d_prev is not None and bool(np.all(np.diff(np.asarray(t.t_s, float)) >= 0)):
        c = centred_turn_through(t.d_R, d_prev, t.target)
    else:
        c = centred_turn_of(t.t_s, t.d_R, t.target)
    return c if np.any(np.abs(c) > 1e-9) else None


#: The outliers' centred turn (:func:`centred_turn`) takes each touch's turn from the move just before it in the log,
#: a row that did not trigger included (:attr:`core.touches.Touches.d_prev_R`), where the log's rows are in the
#: order of their times: a probe's seat moves along every approach, triggered or not, and a retry after a missed
#: approach turns from that approach, not from the touch before it (gen_a reseat_hysteresis 6306, session 24's blind
#: check: the retry's turn 10 deg, not 129; centred turn 0.0056 -> 6e-5, `outlier` confident -> `unexplained`;
#: tuning seeds: reseat 1324 `outlier?` -> `unexplained`, 1555 `stylus_bending` confident -> ambiguous, no gen_a
#: outlier of 1000-1999 moved). The history covariate of the diagnosis (:func:`core.baseline.touch_history`) keeps
#: the touches alone. False: the turn from the previous touch (sessions 13-24).
TURN_THROUGH_NO_TRIGGER = True


def centred_turn_through(d, d_prev, target) -> np.ndarray:
    """(n,) each touch's turn from the move before it less the mean turn of its target's touches (all set-ups), deg.

    ``d`` (n, 3) unit approach directions, ``d_prev`` (n, 3) the approach of
    the log row just before each touch (NaN where none: its turn is 0, as
    :func:`centred_turn_of` gives the first touch), ``target`` (n,). The turn
    is rounded to 1 deg as :func:`core.baseline.touch_history` rounds it.
    """
    d = np.asarray(d, float)
    d_prev = np.asarray(d_prev, float)
    target = np.asarray(target)
    n = len(target)
    if d.shape != (n, 3) or d_prev.shape != (n, 3):
        raise ConfigError(f"centred_turn_through: d (n, 3), d_prev (n, 3), target (n,) expected, got {d.shape}, "
                         f"{d_prev.shape}, {target.shape}")
    if n == 0:
        return np.zeros(0)
    ok = np.all(np.isfinite(d_prev), axis=1)
    turn = np.zeros(n)
    turn[ok] = np.round(np.degrees(np.arccos(np.clip(np.sum(d[ok] * d_prev[ok], axis=1), -1.0, 1.0))))
    tg = np.unique(target, return_inverse=True)[1].ravel()
    mean = np.bincount(tg, weights=turn) / np.bincount(tg)
    return turn - mean[tg]


def centred_turn_p(c: np.ndarray, idx, r: np.ndarray, rng: np.random.Generator, draws: int = TURN_DRAWS) -> float:
    """Monte Carlo p-value of the residuals ``r`` of the rows ``idx`` against the centred turn ``c``, under the null that they do not follow it.

    Statistic ``S = |sum_i r_i c_i|`` over the rows (``c``: :func:`centred_turn`).
    A move-driven effect that a target's parameter half absorbs (a seat that
    reads short after a turn: the target takes the mean of its readings) leaves
    as outliers the minority readings, short where a touch turned more than its
    target's other touches, long where it turned less: ``r`` and ``c`` of opposite
    signs, both kinds adding to ``S``. Null: dust, as many touches drawn at random
    (with replacement) from all the campaign's, each carrying one of the observed
    residuals; p = (1 + exceedances) / (draws + 1). Two-sided.
    """
    c = np.asarray(c, float)
    idx = np.asarray(idx, int)
    r = np.asarray(r, float)
    if c.ndim != 1 or idx.ndim != 1 or r.shape != idx.shape:
        raise ConfigError(f"centred_turn_p: c (n,), idx (k,), r (k,) expected, got {c.shape}, {idx.shape}, {r.shape}")
    if idx.size < 2 or not np.all(np.isfinite(r)) or not np.all(np.isfinite(c)):
        raise ConfigError("centred_turn_p: at least two rows with finite residuals and centred turns")
    if np.any(idx < 0) or np.any(idx >= c.size):
        raise ConfigError("centred_turn_p: row index outside the campaign")
    s = abs(float(r @ c[idx]))
    # a draw within rounding of the observed statistic reaches it (RANK_TIE's rule): relative here, 1e-9 of
    # sum |r| max |c| (a bound of |S| and of its rounding, k eps of it), as S is in residual units
    tol = 1e-9 * (float(np.sum(np.abs(r))) * float(np.max(np.abs(c))) + 1e-300)
    exceed = 0
    step = max(1, SHARE_BLOCK // idx.size)
    for a in range(0, draws, step):
        pick = rng.integers(0, c.size, (min(step, draws - a), idx.size))
        exceed += int(np.sum(np.abs(c[pick] @ r) >= s - tol))
    return (1 + exceed) / (draws + 1)


def centred_sign_of(n, d, target) -> np.ndarray:
    """(n, 2) each touch's lost-motion column per axis (X, Y) less its target's mean over all set-ups.

    The catalogue's ``reversal`` column of an axis is ``-n_ax sign(d_ax) / 2``
    (:func:`core.causes.reversal_scans`; here without the factor ``-1 / 2``,
    which the test below does not see): the normal's component along the
    axis, signed by the approach's. A target's parameter in the baseline takes
    the mean of its touches' readings, so what of a lost motion the baseline
    cannot absorb lies on the targets whose touches approach with both signs
    along the axis (an approach nearly across it, the sign set by the
    approach's scatter about the normal), and there it is this column less
    its target's mean. ``n``, ``d`` (n, 3) unit normals and approach
    directions in the machine frame, ``target`` (n,) the place of the part
    each touch measures. A touch whose approach has no component along the
    axis (``|d_ax| <= 1e-9``) takes sign 0, as the catalogue's column does.
    """
    n = np.asarray(n, float)
    d = np.asarray(d, float)
    target = np.asarray(target)
    k = len(target)
    if n.shape != (k, 3) or d.shape != (k, 3) or target.shape != (k,):
        raise ConfigError(f"centred_sign_of: n (k, 3), d (k, 3), target (k,) expected, got {n.shape}, {d.shape}, "
                         f"{target.shape}")
    if not (np.all(np.isfinite(n)) and np.all(np.isfinite(d))):
        raise ConfigError("centred_sign_of: normals and approach directions must be finite")
    if k == 0:
        return np.zeros((0, 2))
    s = np.where(np.abs(d[:, :2]) > 1e-9, np.sign(d[:, :2]), 0.0)
    c = n[:, :2] * s
    tg = np.unique(target, return_inverse=True)[1].ravel()
    cnt = np.bincount(tg).astype(float)
    mean = np.column_stack([np.bincount(tg, weights=c[:, j]) / cnt for j in range(2)])
    return c - mean[tg]


def near_across_p(a: np.ndarray, idx, rng: np.random.Generator, draws: int = TURN_DRAWS) -> float:
    """Monte Carlo p-value that the rows ``idx`` sit on the touches whose approach moves an axis least.

    ``a`` (n,): each touch's ``|d_ax|``, the approach's component along the
    axis. Statistic ``S = sum_i log q_i`` over the rows, ``q_i`` the share of
    the campaign's touches with ``a <= a_i`` (ties take the largest rank, which
    errs towards no finding). An approach nearly across an axis barely moves
    it: a lost motion's state there is the one earlier moves left, not the
    approach's sign (the catalogue's column reads the approach's), and a touch
    whose state differs from its target's other touches reads a full step
    ``|n_ax| B`` off them, an outlier. Null: dust, as many touches drawn at
    random (with replacement) from all the campaign's; p = (1 + exceedances)
    / (draws + 1). One-sided (small ``a`` only).
    """
    a = np.asarray(a, float)
    idx = np.asarray(idx, int)
    if a.ndim != 1 or idx.ndim != 1 or idx.size < 1 or not np.all(np.isfinite(a)):
        raise ConfigError(f"near_across_p: a (n,) finite and idx (k,) expected, got {a.shape}, {idx.shape}")
    if np.any(idx < 0) or np.any(idx >= a.size):
        raise ConfigError("near_across_p: row index outside the campaign")
    lq = np.log(np.searchsorted(np.sort(a), a, side="right") / a.size)
    s = float(np.sum(lq[idx]))
    tol = 1e-9 * (abs(s) + 1.0)
    exceed = 0
    step = max(1, SHARE_BLOCK // idx.size)
    for b in range(0, draws, step):
        pick = rng.integers(0, a.size, (min(step, draws - b), idx.size))
        exceed += int(np.sum(lq[pick].sum(axis=1) <= s + tol))
    return (1 + exceed) / (draws + 1)


def approach_sign_p(bl: Baseline, outliers, r_um: np.ndarray, seed) -> tuple | None:
    """(p, test, axis) of the outliers against the sign of approach along the X and Y axes; None where untested.

    One family, Bonferroni over its tests: per axis the centred sign
    (:func:`centred_sign_of` through :func:`centred_turn_p`'s statistic: the
    outliers' residuals follow the lost-motion column less its target's mean)
    where some target is approached with both signs, and per axis the
    nearest-across test (:func:`near_across_p`: the outliers sit on the
    touches whose approach moves the axis least). ``test`` and ``axis`` name
    the smallest. Planar campaigns whose touches map one to one onto the
    baseline's rows, two or more outliers.
    """
    if bl.kind != "planar" or len(outliers) < 2:
        return None
    t = bl.data.touches
    if len(np.asarray(t.t_s)) != len(bl.y):
        return None
    c = centred_sign_of(t.n_R, t.d_R, t.target)
    outliers = np.asarray(outliers, int)
    r_um = np.asarray(r_um, float)
    rev = causes_mod.lookup("reversal", bl.kind)
    b_max = {j: max((abs(float(v)) for v in rev.bounds.get(f"{ax}_lost_motion_um", (np.inf,))), default=np.inf)
             if rev is not None else np.inf for j, ax in enumerate("xy")}
    ps = []
    for j in range(2):
        if np.any(np.abs(c[:, j]) > 1e-9):
            ps.append((centred_turn_p(c[:, j], outliers, r_um, np.random.default_rng([seed, 2, j])),
                       "centred sign", "XY"[j]))
        # a lost motion moves a touch by at most |n_ax| B: an outlier on a touch whose normal cannot carry its
        # residual within the reversal cause's plausible |B| is no lost motion's along this axis, whatever its
        # approach; the test counts only the outliers a lost motion could have made (two or more)
        carry = np.abs(np.asarray(t.n_R, float)[outliers, j]) * b_max[j] >= np.abs(r_um)
        if np.count_nonzero(carry) >= 2:
            ps.append((near_across_p(np.abs(t.d_R[:, j]), outliers[carry], np.random.default_rng([seed, 3, j])),
                       "nearly across", "XY"[j]))
    p, test, ax = min(ps)
    return min(1.0, len(ps) * p), test, ax


# ---------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Finding:
    """One cause with the figures that support it.

    Attributes
    ----------
    cause : str
    evidence : dict
        Figures behind the decision (F, p-values, CV, VIF, rival share ...).
    params : dict
        Fitted magnitudes, units in the keys (strings for choices).
    params_u95 : dict
        U95 (k = 2) of each numeric magnitude, same keys; None where the
        data do not determine it.
    rms_um : float
        Residual RMS of the extended model, um.
    books_to : str
        ``machine``, ``probe``, ``workpiece``, ``data`` or ``unknown``.
    """

    cause: str
    evidence: dict
    params: dict
    params_u95: dict
    rms_um: float
    books_to: str = "machine"


def _report_u95(f: Finding, kind: str) -> dict:
    """A finding's U95 under the report's keys: one for every key of ``params`` (the spec: "same keys"), None
    for a choice (an axis, a feature), where the data do not determine it, and for an angle whose U95 reaches
    half its circle (:attr:`core.causes.Cause.circular`: a periodic error's phase beside an amplitude consistent
    with zero came out as 13 rad, session 25's review)."""
    cause = causes_mod.lookup(f.cause, kind)
    circ = cause.circular if cause is not None else {}
    out = {}
    for key in f.params:
        u = f.params_u95.get(key)
        if u is not None and any(_matches(key, pat) and u >= period / 2 for pat, period in circ.items()):
            u = None
        out[key] = u
    return out


@dataclass(frozen=True)
class Discovery:
    """Everything :func:`discover_baseline` found (``to_report`` gives the spec's JSON)."""

    baseline: Baseline = field(repr=False)
    baseline_rms_um: float
    baseline_cv_rms_um: float
    baseline_n_params: int
    findings: tuple
    extended_model: str
    extended_rms_um: float
    extended_cv_rms_um: float
    noise: dict
    diagnosis: tuple
    diagnosis_extended: tuple
    workpiece: tuple
    outlier_rows: tuple
    residuals_baseline_um: np.ndarray = field(repr=False)
    residuals_extended_um: np.ndarray = field(repr=False)
    conventions: tuple = ()
    workpiece_identifiable: bool = True
    G_baseline_m: np.ndarray | None = field(default=None, repr=False)
    G_extended_m: np.ndarray | None = field(default=None, repr=False)
    cov_G_baseline: np.ndarray | DiagLowRank | None = field(default=None, repr=False)  # (a long log's: factored)
    cov_G_extended: np.ndarray | DiagLowRank | None = field(default=None, repr=False)
    structure: dict = field(default_factory=dict)
    rejected: tuple = ()
    cv_rms_ratio_95: list | None = None
    #: why the extended workpiece is not offered as the estimate (:data:`SMOOTH_WORKPIECE_EARNED`,
    #: :data:`WORKPIECE_U95_GROWTH_WITHHELD`), None where it is; the extended fit's own estimate and covariance then kept
    #: here (the report's ``extended_um`` null, its rows' ``extended_fit_um``)
    workpiece_not_offered: dict | None = None
    G_extended_fit_m: np.ndarray | None = field(default=None, repr=False)
    cov_G_extended_fit: np.ndarray | DiagLowRank | None = field(default=None, repr=False)

    @property
    def cause(self) -> str:
        return self.findings[0].cause if self.findings else causes_mod.NONE

    def to_report(self) -> dict:
        """The discovery report of the probe-log spec (plus the keys it invites)."""
        b = self.baseline
        b_cv = self.baseline_cv_rms_um
        rep = {
            "format": REPORT_FORMAT,
            "baseline": {"model": b.model, "n": int(b.n), "n_params": self.baseline_n_params,
                         "rms_um": self.baseline_rms_um, **{k: v for k, v in b.info.items()
                                                          if isinstance(v, (int, float, str, list))}},
            "findings": [{"cause": f.cause, "evidence": f.evidence, "params": f.params,
                          "params_u95": _report_u95(f, b.kind), "rms_um": f.rms_um, "books_to": f.books_to}
                         for f in self.findings],
            "cause": self.cause,
            "extended": {"model": self.extended_model, "rms_um": self.extended_rms_um,
                         "cv_rms_um": self.extended_cv_rms_um},
            "baseline_cv_rms_um": b_cv,
            "gain": {"rms_ratio": self.extended_rms_um / max(self.baseline_rms_um, 1e-300),
                     "cv_rms_ratio": self.extended_cv_rms_um / max(b_cv, 1e-300),
                     "cv_rms_ratio_95": self.cv_rms_ratio_95},
            "noise_um": self.noise,
            "diagnosis": [d.to_dict() for d in self.diagnosis],
            "diagnosis_extended": [d.to_dict() for d in self.diagnosis_extended],
            "structure": self.structure,
            "workpiece": [dict(w) for w in self.workpiece],
            "workpiece_identifiable": self.workpiece_identifiable,
            "outlier_rows": [int(r) for r in self.outlier_rows],
            "rejected": list(self.rejected),
            "conventions": list(self.conventions),
        }
        if self.workpiece_not_offered is not None:  # (the key only where the rule withheld it: reports unchanged)
            rep["workpiece_not_offered"] = {k: v for k, v in self.workpiece_not_offered.items() if k != "text"}
        # (a positioning run's report in its words, cycles and readings, and a rotary one's in arc seconds: session 31)
        return bl_mod.positioning_report(rep, b)


# ---------------------------------------------------------------------------
# the engine
# ---------------------------------------------------------------------------
def discover(t: Touches, *, grid_step_mm: float | None = None, settings: Settings = Settings(),
             chain: str | None = None, rng: np.random.Generator | None = None, progress=None,
             extra: dict | None = None) -> Discovery:
    """Find what the 2D self-calibration model gets wrong in a campaign.

    Parameters
    ----------
    t : Touches
        Valid touches (``core.touches.from_log``) at two or more C angles.
        Touches whose normal is out of the XY plane are left out (said in
        ``conventions``).
    grid_step_mm : float or None
        Error-map grid step of the baseline; None = chosen by BIC among
        ``settings.grid_steps_mm`` (and again on the touches the outlier
        screen keeps: :data:`GRID_AFTER_OUTLIERS`).
    chain : str or None
        The log's ``kinematic_chain``: which axis carries the other decides
        the rigid-body yaw term (:func:`core.selfcal.yaw_for_chain`).
    rng : np.random.Generator or None
        Draws of the CV-gap null distribution; None = a generator seeded 0
        (the report is then reproducible).
    progress : callable(done, total) or None
        Called as the work advances (the CLI shows time left).
    extra : dict[str, (n,) float] or None
        Further covariates per touch (the log's other numeric columns,
        :func:`core.baseline.extra_columns`), aligned with ``t``.

    Raises
    ------
    ConfigError
        Fewer than 10 planar touches.
    IdentifiabilityError
        No baseline (one set-up, too few targets).
    """
    planar = np.abs(t.n_R[:, 2]) <= selfcal.NZ_MAX
    left_out = int(t.n - planar.sum())
    extra = {k: np.asarray(v, float) for k, v in (extra or {}).items()}
    for k, v in extra.items():
        if v.shape != (t.n,):
            raise ConfigError(f"extra covariate {k!r}: expected {t.n} values, got {v.shape}")
    if left_out:
        t = t.subset(planar, reindex=True)
        extra = {k: v[planar] for k, v in extra.items()}
    bl_mod.check_planar(t)
    yaw = selfcal.yaw_for_chain(chain)
    chosen = grid_step_mm is None and settings.select_grid and len(settings.grid_steps_mm) > 1
    regrid, finer = GRID_AFTER_OUTLIERS and chosen, FINER_MAP_CHECK and chosen
    # (the finest identifiable grid's design, built by BIC's comparison, kept for the finer-map check's call on the
    # same touches: core.baseline.planar's designs; FINER_DESIGN_REUSE)
    designs = {} if finer and FINER_DESIGN_REUSE else None
    bl = bl_mod.planar(t, grid_step_mm, settings.grid_steps_mm, select_grid=settings.select_grid, yaw=yaw,
                       extra=extra, designs=designs)
    note = f"{counted(left_out, 'touch')} {LEFT_OUT_NOTE}"
    if left_out:
        bl = _with_convention(bl, note)
    # (a search again, on another grid, draws as the first did)
    rng0 = copy.deepcopy(rng) if (regrid or finer) and rng is not None else None
    # the baseline holds what the search reads: the caller's touches can go (core.baseline.planar_data); the two
    # arrays its copy drops are kept where the grid may be chosen again (2 x 24 MB at 1e6 rows)
    dropped = {k: getattr(t, k) for k in bl_mod.PLANAR_TOUCHES_DROPPED} if regrid or finer else None
    del t, extra
    d = discover_baseline(bl, settings=settings, rng=rng, progress=progress)
    tried = {bl.info["grid_step_mm"]}
    while regrid and d.outlier_rows and (GRID_AFTER_OUTLIERS_CAUSES is None
                                         or any(f.cause in GRID_AFTER_OUTLIERS_CAUSES for f in d.findings)):
        # the grid BIC chooses on the touches the screen kept (GRID_AFTER_OUTLIERS): where it is another, the
        # search runs again on it, its own screen on that grid; until the grid is one already tried
        t = dataclasses.replace(bl.data.touches, **dropped)  # (the touches again, as the caller gave them)
        extra = bl.data.extra
        step = _grid_on_kept(t, extra, d.outlier_rows, settings, yaw)
        if step is None or step in tried:
            break
        g0, n_out = d.baseline.info["grid_step_mm"], len(d.outlier_rows)
        del d  # (its baseline's touches let go: one copy alive while the search runs again)
        tried.add(step)
        bl = bl_mod.planar(t, step, settings.grid_steps_mm, select_grid=False, yaw=yaw, extra=extra)
        del t, extra
        bl = _with_convention(bl, f"error-map grid {step:g} mm: chosen by BIC on the touches the outlier screen "
                                  f"kept ({counted(n_out, 'touch')} set aside on the {g0:g} mm grid "
                                  "BIC chose with them in)")
        if left_out:
            bl = _with_convention(bl, note)
        d = discover_baseline(bl, settings=settings, rng=copy.deepcopy(rng0) if rng0 is not None else None,
                              progress=progress)
    if (not finer or d.cause not in FINER_MAP_CAUSES
            or d.baseline.info["grid_step_mm"] <= min(settings.grid_steps_mm)):
        return d
    kept = (dataclasses.replace(bl.data.touches, **dropped), bl.data.extra)  # (the touches again)
    return _finer_map_check(d, kept, settings, yaw, copy.deepcopy(rng0) if rng0 is not None else None,
                            note if left_out else None, designs=designs)


#: :func:`discover`'s finer-map check builds the finest identifiable grid's design from the one BIC's comparison
#: built in the first :func:`core.baseline.planar` call (its ``designs`` cache, checked against the same touches),
#: and that call takes the first identifiable grid without building the grids after it. Exact (the same design,
#: factorisation and choice; the reports the same to the bit, session 38, fast38): False builds it again.
FINER_DESIGN_REUSE = True


#: Whether the error-map grid is chosen again, by BIC, on the touches the outlier screen kept (:func:`discover`;
#: where a finding of :data:`GRID_AFTER_OUTLIERS_CAUSES` is made beside them): where it is another grid the search
#: runs again on it (its own screen there), until the grid is one already tried. BIC chooses the grid on every
#: touch, before the screen; a few chips' residuals (131 um^2 against the smooth machine's 15) make a coarser grid's
#: extra misfit cheap, and once they are set aside that misfit, which repeats with the grid step, is read as a
#: ripple at the grid step (gen_c outlier 5105: 80 mm chosen, 55 mm without the chips; `periodic_axis_error` at
#: 81.5 mm, confident). Session 26 diagnosis, session 27 study (docs/discovery-studies.md, "Session 27: the grid chosen
#: again on the touches the outlier screen kept": gen_c outlier 200-599 right 365 -> 376, no right -> wrong on
#: gen_a, gen_b, gen_c or the simulator).
GRID_AFTER_OUTLIERS = True
#: With :data:`GRID_AFTER_OUTLIERS`: the causes of which a finding must be made beside the touches set aside for the
#: grid to be chosen again (None: wherever touches are set aside). A coarse grid's misfit of a smooth machine repeats
#: with its nodes, and the catalogue reads it as a ripple at the grid step (``periodic_axis_error``) or as bumps
#: between the nodes (``local_scale_defect``); where neither is named the misfit was read as no cause, and a finer
#: grid moves the screen's own bound instead (gen_c part_change 298: on 55 mm both walls of a bore's first set-up
#: are set aside, a change of its size, where 80 mm set aside one; a bump at the bore's place then reads the rest of
#: the change, confident; `outlier?` on 80 mm). Session 27 (docs/discovery-studies.md, "Session 27: the grid chosen
#: again on the touches the outlier screen kept").
GRID_AFTER_OUTLIERS_CAUSES = ("periodic_axis_error", "local_scale_defect")


def _grid_on_kept(t: Touches, extra: dict, outlier_rows, settings: Settings, yaw: str) -> float | None:
    """The grid step (mm) BIC chooses among ``settings.grid_steps_mm`` on the touches of ``t`` not in
    ``outlier_rows`` (log row numbers), or None where no grid is identifiable on them."""
    keep = ~np.isin(np.asarray(t.row), np.asarray(outlier_rows))
    try:
        kb = bl_mod.planar(t.subset(keep, reindex=True), None, settings.grid_steps_mm, yaw=yaw,
                           extra={k: v[keep] for k, v in extra.items()})
    except (IdentifiabilityError, ConfigError):
        return None
    return kb.info["grid_step_mm"] if kb.identifiable else None



#: Whether a reading of a kind a map's misfit can take (:data:`FINER_MAP_CAUSES`) on an error-map grid BIC chose coarser
#: than the finest is checked against the finest identifiable map (:func:`_finer_map_check`): where the search on
#: that map finds nothing (``none``), the reading was the coarse map's own interpolation misfit of the machine's
#: smooth axis errors (the baseline's world, not an effect), and the finer map's discovery is reported. BIC's
#: penalty (log n per parameter) keeps a coarse grid whose misfit the search's tests (F tests at the family's
#: level, materiality 0.3 sigma) then find: gen_c's smooth machine (quadratic and cubic axis errors), effect-free,
#: read something on 49 of 960 campaigns (48 on the 80 mm grid BIC chose), 8 of 960 on its affine machine
#: (errors every map represents); on the 22 mm map 41 of the 49 read none. Session 27 study (docs/discovery-studies.md,
#: "Session 27: gen_c's false alarms are the coarse map's misfit").
FINER_MAP_CHECK = True

#: The readings :data:`FINER_MAP_CHECK` checks: structure no catalogue cause takes, and the named causes whose
#: columns are smooth functions of the touch's position (a ripple, a non-separable field: what a coarse map's
#: misfit can look like). Not ``local_scale_defect``: checked too, true bumps narrower than the finest map's step
#: were lost to it (tests/core/test_discover_defect.py's 1.2 um bump, seed 3; gen_a local_scale_defect 1013, the
#: simulator's 4023, both named before); its own rule already contests the smooth map (the grid's tables as
#: cubic splines).
FINER_MAP_CAUSES = ("unexplained", "periodic_axis_error", "nonrigid")

#: The finer map is taken only where it determines the workpiece about as well as the coarse one: the RMS over
#: the targets of its baseline U95 at most this factor times the coarse map's. A finer map that trades the
#: workpiece for the map (nearly confounded on the design: gen_b c_drift 1000, part_change 1000, signal_latency
#: 1004 and 1011, U95 4.5-10 times the coarse map's, the workpiece 3-8 um off against 0.6-0.9) reads ``none``
#: for want of power, not because the structure was the map's; on gen_c's smooth machine the ratio was 0.2-1.6
#: (41 campaigns). Set from those two sets (session 27), a round factor between them.
FINER_MAP_U95_RATIO = 2.0

#: With :data:`FINER_MAP_CHECK`: the finer map's discovery is taken also where it reads only outliers the coarse
#: map's screen set aside too (every finding ``outlier``, its rows among the coarse map's:
#: :func:`_finer_reads_the_same_outliers`), not only where it reads ``none``. A coarse grid's misfit of the smooth
#: machine read as a ripple at the grid step, beside a few gross touches set aside: the finer map reads the same
#: outliers and nothing else, and the check, asking for ``none``, kept the ripple (blind gen_c outlier 6106,
#: session 31: BIC's 80 mm grid with the outliers in and without them, so :data:`GRID_AFTER_OUTLIERS` finds no other;
#: ``periodic_axis_error`` at 81.4 mm, 0.12 um, confident; the log without the three touches reads the same ripple
#: on 80 mm and ``none`` through the check; the 22 mm map reads the three outliers alone). On (diag31): it fired on
#: 2 of 935 tuning campaigns, both wrong -> right (twins of 6106: gen_c outlier 134, a confident ripple, and 162, a
#: hedged ``nonrigid``; both ``outlier``), 0 right -> wrong: nowhere else on gen_a/gen_b 1000-1004 every effect and
#: none 1000-1019, the simulator 4000-4009, gen_c 200-219 every effect, gen_c outlier 0-199 or gen_a
#: thermal_bending 1100-1199. docs/discovery-studies.md, "Session 31: a coarse map's ripple beside outliers, and a part
#: change inflated 181 times (diag31)".
FINER_MAP_OUTLIERS_AGREE = True


def _u95_rms(d: Discovery) -> float:
    """RMS over the targets of the baseline workpiece's U95 (k = 2) outside the workpiece's gauge (a translation
    and rotation of the part, and its size where the scale is unknown: :func:`core.selfcal.workpiece_gauge_basis`,
    as the blind harness scores it; the per-target U95 of the report depends on the map's gauge), m; nan where the
    covariance is not a formed matrix (a long log) or not finite."""
    return _u95_rms_of(d.cov_G_baseline, d.baseline)


def _u95_rms_of(C, bl: Baseline) -> float:
    """:func:`_u95_rms` of the covariance ``C`` of ``bl``'s workpiece."""
    if not isinstance(C, np.ndarray) or not np.all(np.isfinite(C)):
        return float("nan")
    P, N = bl.geometry
    Pm = lsq_mod.remove_span(np.eye(C.shape[0]), selfcal.workpiece_gauge_basis(P, N))
    return float(np.sqrt(np.mean(4 * np.maximum(np.einsum("ij,jk,ik->i", Pm, C, Pm), 0))))


def _finer_map_check(d: Discovery, kept, settings: Settings, yaw: str, rng, note, designs=None) -> Discovery:
    """``d``, or the discovery on the finest identifiable error map where that one reads ``none``
    (:data:`FINER_MAP_CHECK`); ``kept`` the (touches, extra) ``d``'s baseline was made from, ``yaw`` its yaw table.
    With :data:`FINER_MAP_SHORTCUT` the search on the finer map is not run where what it would give is known
    beforehand not to be taken (the same answer, :func:`_finer_map_search`). ``designs``: the first planar call's
    cache (:data:`FINER_DESIGN_REUSE`)."""
    u95_d = _u95_rms(d)
    if FINER_MAP_SHORTCUT and not np.isfinite(u95_d):
        return d  # (no finer discovery passes ``u95 <= ratio * nan``: the test below always returns d)
    t, extra = kept
    g0 = d.baseline.info["grid_step_mm"]
    try:
        bl = bl_mod.planar(t, None, settings.grid_steps_mm, select_grid=False, yaw=yaw, extra=extra,
                           designs=designs)
    except (IdentifiabilityError, ConfigError):
        return d
    if not bl.identifiable or bl.info["grid_step_mm"] >= g0:
        return d
    del t, extra, kept
    if note:
        bl = _with_convention(bl, note)
    bl = _with_convention(bl, f"error-map grid {bl.info['grid_step_mm']:g} mm, the finest identifiable: on the "
                              f"{g0:g} mm grid BIC chose the search read {d.cause}, and nothing on this one "
                              "(the coarse map's misfit of the machine's smooth errors)")
    df = _finer_map_search(bl, d, settings, rng, u95_d)
    if df is None:
        return d
    agree = _finer_reads_the_same_outliers(df, d)
    if (df.cause != causes_mod.NONE and not agree) or not _u95_rms(df) <= FINER_MAP_U95_RATIO * u95_d:
        return d
    if agree:
        df = dataclasses.replace(df, conventions=tuple(
            c.replace(", and nothing on this one", ", and on this one only the outliers the screen set aside on that "
                                                 "one too") for c in df.conventions))
    return df


#: :func:`_finer_map_check` skips the search on the finer map where its answer is known beforehand not to be taken
#: (:func:`_finer_map_search`): the same report, at a fraction of the cost (the search on the finer map was 40 % of
#: a discovery's CPU on gen_a's campaigns where it ran, and read something other than ``none`` on nearly all of
#: them). Exact: False runs the search everywhere, as before (session 37, fast37; docs/discovery-studies.md, "Session 37:
#: the finer-map check's cost").
FINER_MAP_SHORTCUT = True


def _baseline_u95_rms(bl: Baseline) -> float:
    """:func:`_u95_rms` of any discovery on ``bl`` (a dense design), from the baseline alone: the covariance
    :func:`_workpiece` gives the report's baseline workpiece, by the same call (``linear_map`` changes nothing of it
    on a dense design)."""
    cb = _constrained(bl.A, bl.y, bl.C, bl.d, np.arange(bl.n), None, 0, tol=getattr(bl, "rank_tol", None))[1]
    return _u95_rms_of(cb[np.ix_(bl.estimand, bl.estimand)], bl)


class _NoneImpossible(Exception):
    """Raised by :func:`discover_baseline` (``stop_unless_none_possible``) where its report cannot read ``none``."""


def _finer_map_search(bl: Baseline, d: Discovery, settings: Settings, rng, u95_d: float) -> Discovery | None:
    """The discovery on the finer map ``bl`` for :func:`_finer_map_check`, or None where with
    :data:`FINER_MAP_SHORTCUT` it is known beforehand that the check would not take it (it returns ``d``).

    The check takes the finer discovery only where (a) it reads ``none``, or only outliers ``d`` set aside too,
    and (b) its baseline workpiece's U95 (RMS) is at most :data:`FINER_MAP_U95_RATIO` times ``d``'s. Two
    conditions known before the search, each sufficient for the check to return ``d``:

    * (b) fails. The baseline workpiece's covariance of a report is :func:`_workpiece`'s
      ``_constrained(A, y, C, d, every row, no penalty)`` of the baseline alone: no term, no outlier, nothing the
      search finds enters it. Computed here by the same call on the same baseline (a dense design: its covariance
      does not depend on ``linear_map``; a long log's block design takes another path with it, and is not
      pre-judged here).
    * (a) fails. Where ``d`` set no touch aside, only ``none`` passes (a) (:func:`_finer_reads_the_same_outliers`
      asks for ``d``'s outliers). A report reads ``none`` only with no finding at all, and
      :func:`discover_baseline` ends so: (1) a touch set aside at the end makes an ``outlier`` finding; (2) with
      none set aside the final rows are every row, and the baseline's structure ``structure_b`` was judged on them
      (every change of the rows after the first screen is followed by ``judge_rows_again``); (3) where no finding
      was made and ``structure_b`` is present, ``unexplained`` is made; (4) what follows (ordering, hedges,
      ``unexplained`` put ahead of outliers) only reorders, flags or adds findings. So a baseline whose structure,
      judged on every row, is present cannot read ``none``: that judgement (``judge_baseline`` on every row, made
      by the search itself first, or once more where its first screen set touches aside) is the search's first
      step, and the search stops there (``stop_unless_none_possible``).
    """
    if FINER_MAP_SHORTCUT and isinstance(bl.A, np.ndarray) \
            and not _baseline_u95_rms(bl) <= FINER_MAP_U95_RATIO * u95_d:
        return None
    stop = FINER_MAP_SHORTCUT and not (FINER_MAP_OUTLIERS_AGREE and d.outlier_rows)
    _PLAIN_STRUCTURE[0] = True
    try:
        return discover_baseline(bl, settings=settings, rng=rng, stop_unless_none_possible=stop)
    except _NoneImpossible:
        return None
    finally:
        _PLAIN_STRUCTURE[0] = False


def _finer_reads_the_same_outliers(df: Discovery, d: Discovery) -> bool:
    """Whether the finer map's discovery ``df`` reads nothing but outliers the coarse map's ``d`` set aside too
    (:data:`FINER_MAP_OUTLIERS_AGREE`): every finding ``outlier``, its rows among ``d``'s (the two baselines hold
    the same touches in the same order)."""
    return bool(FINER_MAP_OUTLIERS_AGREE and df.findings and d.outlier_rows
                and all(f.cause == causes_mod.OUTLIER for f in df.findings)
                and set(df.outlier_rows) <= set(d.outlier_rows))



def _with_convention(bl: Baseline, text: str) -> Baseline:
    return dataclasses.replace(bl, conventions=bl.conventions + (text,))


def _releasing(run):
    """``run`` that releases what it kept for itself when it ends, returned or raised (the parts outside this
    run's bases, :func:`core.diagnosis.release_projections`, and its models, :func:`release_states`: no later run
    takes them)."""
    @functools.wraps(run)
    def released(*args, **kwargs):
        try:
            return run(*args, **kwargs)
        finally:
            release_projections()
            release_states()  # (the models kept within the run, :func:`_state`)
    return released


@_releasing
def discover_baseline(bl: Baseline, *, settings: Settings = Settings(), rng: np.random.Generator | None = None,
                      progress=None, stop_unless_none_possible: bool = False) -> Discovery:
    """Discovery on any baseline (module docstring: the steps and their statistics).

    ``stop_unless_none_possible`` (the finer-map check's, :func:`_finer_map_search`): raise
    :class:`_NoneImpossible` as soon as the baseline judged on every row shows structure (the report could not
    read ``none``)."""
    rng = np.random.default_rng(0) if rng is None else rng
    catalogue = causes_mod.for_kind(bl.kind)
    total = 8 + settings.max_findings * max(len(catalogue), 1)
    done = [0]

    def tick(k=1):
        done[0] = min(done[0] + k, total - 1)
        if progress is not None:
            progress(done[0], total)

    y = bl.y
    N = bl.n
    all_rows = np.arange(N)
    use_cv = bool(bl.info.get("cv", True))
    if isinstance(bl.A, BlockDesign):  # a long log: bases built when asked for, not kept (never whitened: planar)
        bases = term_bases(bl.covariates, bl.modes, lazy=True)
    else:
        bases = {k: (_white(bl, B) if not isinstance(B, tuple) else B) for k, B in term_bases(bl.covariates, bl.modes).items()}

    ranks = covariate_ranks(bl.covariates)
    places = places_of(bl)
    if settings.outlier_events not in ("target", "setup", "setup_slip"):
        raise ConfigError("Settings.outlier_events must be 'target', 'setup' or 'setup_slip', not "
                          f"{settings.outlier_events!r}")
    per_setup = settings.outlier_events != "target" and bl.kind == "planar"
    events = bl.groups if per_setup else bl.replicate

    @functools.cache
    def scan_trials(fn):
        """A one-off alternative's (T, n, k) trials (``fn(bl)``), whitened: made once in this run. Kept as their
        splits where the scan gives them so (:class:`core.diagnosis.StepTrials`, unwhitened: built a block at a
        time where used); whitened or given dense, the dense array as before."""
        Cs = fn(bl)
        if isinstance(Cs, StepTrials):
            if bl.whiten is None:
                return Cs
            Cs = Cs.dense()
        Cs = Cs if bl.whiten is None else np.einsum("ij,tjk->tik", bl.whiten, Cs)
        Cs.flags.writeable = False  # shared by every caller of this run
        return Cs

    # the outlier screen's steps are the rival check's fixture slips: the same trials
    slips = (functools.partial(scan_trials, causes_mod.fixture_slip)
             if per_setup and settings.outlier_events == "setup_slip" else None)

    def outliers_of(X, Q=None):
        # each call draws its own null from a generator seeded by the caller's: the
        # answer does not depend on how many other tests drew before it
        if at_roundoff:  # (no residual beyond the data's rounding: none stands out of anything but rounding)
            return np.zeros(0, dtype=int)
        return find_outliers(X, y, settings.outlier_alpha, settings.outlier_max_frac, Q, ranks=ranks,
                             rng=np.random.default_rng(outlier_seed), max_frac_dust=settings.outlier_max_frac_dust,
                             alpha_concentration=settings.alpha_family, events=events, slips=slips,
                             places=places, rank_tol=rank_tol)

    outlier_seed = int(rng.spawn(1)[0].integers(2 ** 32))  # spawning leaves rng's own stream as it was
    gap_seed = int(rng.spawn(1)[0].integers(2 ** 32))  # the held-out gap's bootstrap draws
    # 0. baseline fit and a first outlier screen
    # (the planar baseline's grid choice factored A already; cut at its rank tolerance, the log's precision's)
    rank_tol = getattr(bl, "rank_tol", None)
    Qall = orth_of(bl.A, qr=bl.qr) if rank_tol is None else orth_of(bl.A, tol=rank_tol, qr=bl.qr)
    st0 = _state(Qall, y, all_rows, [])
    # the data's own numerical precision: the noise is never taken below it, and a baseline that leaves every
    # residual below it (a noise-free campaign the model represents exactly) leaves nothing to find: no outlier,
    # no structure, no search (ROUNDOFF_ULPS, session 26)
    floor = roundoff_floor_m(bl)
    at_roundoff = bool(N and np.max(np.abs(st0.r)) <= floor)
    rows = np.setdiff1d(all_rows, outliers_of(bl.A, Qall))
    tick()

    cache: dict = {}

    def model(rows_, terms):
        key = tuple(rows_.tolist()) if len(rows_) != N else None
        if key not in cache:
            # every row of a long log's block design: the design itself, whose basis (Qall's, kept by the design)
            # the folds share, not a copy of its rows factored again (the same numbers: the same rows in order);
            # after an outlier removal one copy of the rows, whose block basis the folds share with Qb
            A_r = bl.A if key is None and isinstance(bl.A, BlockDesign) else bl.A[rows_]
            Qb = (orth_of(A_r) if rank_tol is None else orth_of(A_r, tol=rank_tol)) if key is not None else Qall
            # (the model's basis of these rows is orth(A_r), the numbers the estimate would factor again)
            est = (Folds if use_cv else CpEstimate)(A_r, bl.groups[rows_], settings.cv_seen,
                                                       settings.cv_seen_extension,
                                                       basis=Qb if isinstance(Qb, np.ndarray) else None)
            if not use_cv:
                est.set_sigma(y[rows_])
            cache[key] = (Qb, est)
        Qb, folds = cache[key]
        return Qb, folds, _state(Qb, y, rows_, terms)

    Qb, folds, st = model(rows, [])
    def repeats_of(key):
        """(plain pure error, trend kind, the scatter after that trend) of the repeat groups ``key``."""
        rep_ = replicate_scatter(key[rows], y[rows])  # the plain pure error: the lack-of-fit test's
        # the noise: the repeats' scatter once what drifts linearly in time within a set-up is taken out (a rate
        # per set-up, else one rate shared by the set-ups, else none: the first that leaves 10 degrees of freedom)
        return (rep_,) + next(((k, r) for k, r in ((k, replicate_scatter(key[rows], y[rows],
                                                                          drift_trend(bl, rows, k == "shared", True)))
                                                    for k in ("per set-up", "shared")) if r.dof >= 10), ("none", rep_))

    rep_key = bl.replicate  # the repeat groups whose scatter is pure error
    rep, trend, rep_t = repeats_of(rep_key)
    straddled = np.zeros(0, dtype=np.asarray(bl.replicate).dtype)
    if REPEATS_STRADDLED and rep_t.dof:
        # groups whose repeats straddle a step (their scatter an outlying variance among the groups', under the
        # trend just chosen) are no pure error: set aside, and the choice made again on the rest
        eligible = None
        cov_t = bl.covariate("time") if STRADDLED_SEPARATED else None
        if cov_t is not None:
            # only a group whose touches something separates (another touch between, or beyond the short-term
            # scale) can straddle a step: every row of the log counts as a touch between (session 32, review32c F1)
            eligible = separated_groups(bl.replicate, np.asarray(cov_t.values, float), bl.groups)
        straddled = straddled_groups(bl.replicate[rows], y[rows],
                                     drift_trend(bl, rows, trend == "shared", True) if trend != "none" else None,
                                     settings.alpha, eligible)
        if straddled.size:
            key_s = np.where(np.isin(bl.replicate, straddled), -1, bl.replicate)
            rest = repeats_of(key_s)
            # the rest serves as the floor only with the 10 degrees of freedom any repeats' floor needs: with few
            # groups the test fires mostly because the rest happen to scatter little (the session 23 review: given
            # a firing on 4-5 groups of 3 under pure noise the rest's variance is 0.07-0.16 of the truth; gen_a none
            # 1305 and 1648 read `unexplained` on floors of 8 and 6 degrees of freedom), so there nothing is set aside
            if rest[2].dof >= 10:
                rep_key, (rep, trend, rep_t) = key_s, rest
            else:
                straddled = straddled[:0]
    sigma_rep = rep_t.sigma_m if rep_t.dof >= 10 else None
    rep_of: dict = {}
    short = _short_term(bl, rows, y, rep_t, rep_key) if sigma_rep is not None else None
    if short is not None and short["used"]:
        sigma_rep = short["sigma_m"]
    elif sigma_rep is not None and REPEATS_BEYOND_FIT:
        if _repeats_beyond_fit(st, rep, settings.alpha) is not None:
            sigma_rep = None  # the repeats scatter more than the whole fit leaves: not the probe's noise

    def noise_of(s: _State) -> tuple[float, str, int]:
        """The noise beside the model ``s``: (sigma, method, degrees of freedom).

        The short-term pairs' scatter when their test fired (they see the
        probing noise alone: nothing of a model to take out of them).
        Otherwise the repeats' scatter beyond the model: a drift's
        curvature within a set-up stays in the repeats' scatter when only
        a rate per set-up is taken out; once a term represents it, its
        columns' variation within the groups is removed with the rates
        (:func:`core.diagnosis.replicate_scatter`, its degrees of freedom
        reduced by their rank). A term constant within each group (a
        lobing: one target, one set-up, one direction) changes nothing.
        Only where that leaves at least 10 degrees of freedom, or at least
        :data:`NOISE_BEYOND_TERMS_MIN_DOF` where what the terms take out of
        the repeats is shown to be more than noise (:func:`short_term_test`
        of the repeats with the rates alone, on the same rows, against
        their scatter beyond the terms, at
        :data:`SHORT_TERM_ALPHA`, as the short-term pairs are judged); else
        the repeats' scatter with the rates alone is kept (the repeats
        cannot tell the noise from the terms there). gen_a thermal_drift
        1201: 5 repeat groups, 10 degrees of freedom, no rate taken out
        (either leaves fewer than 10), 0.84 um for a true 0.35 um; beyond
        the adopted drift's 4 columns 8 degrees of freedom at 0.32 um,
        what they take out F = 30 (p = 2e-4); the floor of 10 kept 0.84.
        """
        if sigma_rep is None:
            return s.sigma, "residuals", s.dof
        if short is not None and short["used"]:
            return sigma_rep, "short-term repeats", short["dof"]
        if s.Q.shape[1] <= s.k_base:
            return sigma_rep, "repeats", rep_t.dof
        key = (tuple(s.rows.tolist()), s.Q.shape[1], float(s.rss))
        if key not in rep_of:
            # only the repeats' rows hold anything of the scatter: the rates formed dense there alone (dense on
            # every row they were rows x modes x set-ups, 2.4 GB at the bench's 1e6 rows and 100 set-ups); the
            # same values in the same order as on every row
            rep_rows = np.flatnonzero(rep_key[s.rows] >= 0)
            key_r, y_r = rep_key[s.rows][rep_rows], y[s.rows][rep_rows]
            rates = (_dense(drift_trend(bl, s.rows, trend == "shared", True)[rep_rows]) if trend != "none"
                     else np.zeros((len(rep_rows), 0)))
            T = np.hstack([rates, s.Q[:, s.k_base:][rep_rows]])
            r = replicate_scatter(key_r, y_r, T)
            # (terms constant within the groups leave the estimate and its degrees of freedom as they were:
            # the repeats' own, said so)
            terms_hold_structure = False
            if NOISE_BEYOND_TERMS_MIN_DOF <= r.dof < 10:
                # the rates-only scatter on the same rows (rep_t is on the first screen's: after the outlier
                # re-screen or the put-back its sum of squares would hold the touches dropped or added too)
                rep_s = replicate_scatter(key_r, y_r, rates if trend != "none" else None)
                terms_hold_structure = (r.dof < rep_s.dof
                                        and short_term_test(rep_s, r)[1] < SHORT_TERM_ALPHA)
            rep_of[key] = ((r.sigma_m, "repeats beyond the model's terms", r.dof)
                           if 10 <= r.dof < rep_t.dof or terms_hold_structure
                           else (sigma_rep, "repeats", rep_t.dof))
        return rep_of[key]

    def noise_sigma(s: _State) -> float:
        return max(noise_of(s)[0], floor)  # (never below the data's rounding: exact repeats scatter by 0)

    def diagnosis(s: _State, covariates, rows_=None, known=()) -> list:
        """The diagnosis of model ``s``'s residuals over ``covariates`` (on ``rows_``; None: every row)."""
        return diagnose(s.Q, s.r, s.dof, covariates, bl.modes, sigma_m=noise_sigma(s),
                        material_sigma=settings.material_sigma, rows=rows_, bases=bases, known=known)

    def judge_baseline(st, folds, rows):
        """The baseline's prediction error (and per set-up), held-out gap, lack of fit, diagnosis and structure on ``rows``."""
        # 1. noise floor of the baseline
        # the baseline's prediction error as every candidate's is measured (Mallows'
        # Cp includes its 2 k s^2 / n where there is no cross-validation)
        cv, held = _held_out(folds, y[rows], bl.groups[rows])
        gap = _cv_gap(folds, st, y, None, None, settings, gap_seed, noise_sigma(st))
        lof = lack_of_fit(st.rss, st.dof, rep)
        tick()
        # 2. diagnosis of the baseline
        diag = diagnosis(st, bl.covariates, rows)
        tick()
        structure = _structure(diag, gap, lof, st, noise_sigma(st), settings, bl.kind, floor)
        # (the guard only where the structure stands: at the data's rounding there is none)
        structure = ({**structure, "present": False} if at_roundoff
                     else _floor_guarded(structure, lof, st, gap, drop=True))
        return cv, held, gap, lof, diag, structure

    cv_b, held_b, gap_b, lof_b, diag_b, structure_b = judge_baseline(st, folds, rows)
    if stop_unless_none_possible:
        # (:func:`_finer_map_search`: the baseline judged on every row, as the report's would be where it keeps
        # every row; where the first screen set touches aside, judged once more, on every row)
        s_all = structure_b
        if len(rows) < N:
            _, f_all, st_all = model(all_rows, [])
            s_all = judge_baseline(st_all, f_all, all_rows)[5]
        if s_all["present"]:
            raise _NoneImpossible

    # 3. named causes, greedily
    scans = {c.name: c.scans(bl) for c in catalogue}
    if bl.whiten is not None:  # every column the causes build goes through the baseline's whitening
        scans = {k: ([dataclasses.replace(sc, build=(lambda idx, b=sc.build: bl.whiten @ b(idx)), score=None,
                                          build_sparse=None, build_rows=None, path_at=None) for sc in v[0]],
                                v[1])
                 for k, v in scans.items()}
    n_causes = max(sum(1 for c in catalogue if scans[c.name][0]), 1)
    rejected: list[dict] = []
    # every judgement of adoption as (cause, the named causes beside it), and how each named cause that left the
    # model went: a refusal made beside one the final model does not hold is marked (REFUSALS_BESIDE_DROPPED_MARKED)
    judged: list[tuple] = []
    gone_how: dict[str, str] = {}

    def named_in(ts) -> tuple:
        return tuple(t.cause for t in ts if not t.unnamed)
    # bumps refused by the all-touch support count alone (OUTLIERS_UNDER_SUPPORT_REFUSED_BUMP): their reach
    refused_bumps: list[dict] = []
    # causes refused in a search round as confounded with the model (their magnitudes not determined, their
    # presence not tested): each named cause is judged against their visible part (_cause_alternatives)
    confounded: set = set()

    smooth_covs = [c for c in bl.covariates if c.kind != "spectral"]  # later rounds: the smooth terms' families
    # the causes whose scans are fixed layouts (step 8 tests each of their layouts: fixed() below)
    fixed_causes = [k for k, v in scans.items() if v[0] and all(_readings_only(sc) for sc in v[0])]  # (in order)

    def evaluate(cause, st_: _State, folds_: Folds, terms_, cv_, families_) -> dict:
        """:func:`_evaluate` of ``cause`` (its scans and tries) beside ``terms_`` in model ``st_``."""
        sc, tries = scans[cause.name]
        return _evaluate(cause, sc, tries * n_causes, bl, st_, folds_, terms_, cv_, noise_sigma(st_), settings,
                         families_, scan_tries=tries)

    def search(rows, st, folds, Qb, diag0, cv0, seen, start=(), kept_out=frozenset()):
        """Greedy rounds from a set of rows; outliers re-judged after each adoption.

        ``seen``: (state, diagnoses) pairs, the diagnoses made against that
        model; each round's is appended (a later test against the same
        model takes its tests, :func:`_made_on`). ``start``: the terms the
        rounds resume beside (``st``, ``folds``, ``cv0`` their model's; the
        rounds left of ``max_findings`` are run); ``kept_out``: causes no
        round judges (:data:`DROPPED_ROUND_REOPENED`).
        """
        terms: list[Term] = list(start)
        cv_cur = cv0
        for rnd in range(len(terms), len(terms) if at_roundoff else settings.max_findings):
            best = None
            # where the structure lives now, per covariate family (debiased sums of squares)
            diag_now = diag0 if rnd == 0 else diagnosis(st, smooth_covs, rows)
            if rnd:
                seen.append((st, diag_now))
            families = _family_ss(bl, diag_now, len(rows), st.rss)
            # the candidates that passed the round's tests and may be the winner's plainer one-explanation name
            # (_plainer_one_explanation takes no penalised, unnamed or covariate-less one): only those are kept,
            # and none beyond the choice (their columns are the term's, n x k each)
            passed = []
            other_forms = []  # (cause, its other forms' judge) of each candidate that passed: ENTRANT_FORM_HELD_OUT
            # (COUNTER_NEEDS_PLAINER_PASSING: a cause refused for its plainer catalogue cause is judged once more,
            # at the end of the round's list, where that plainer cause fails its own tests in the round)
            queue, waive, refused_now = list(catalogue), {}, {}
            for cause in queue:
                if any(tm.cause == cause.name for tm in terms) or cause.name in kept_out:
                    continue
                tick()
                if not scans[cause.name][0]:
                    continue
                judged.append((cause.name, named_in(terms)))
                if cause.name in waive:
                    token = _COUNTER_WAIVED.set(waive.pop(cause.name))
                    try:
                        cand = evaluate(cause, st, folds, terms, cv_cur, families)
                    finally:
                        _COUNTER_WAIVED.reset(token)
                else:
                    cand = evaluate(cause, st, folds, terms, cv_cur, families)
                if COUNTER_NEEDS_PLAINER_PASSING and cand.get("reason"):
                    _counter_requeue(cause, cand, catalogue, queue, waive, refused_now)
                if "other_forms" in cand:
                    other_forms.append((cause.name, cand.pop("other_forms")))
                if cand.get("reason"):
                    if "support_refused_bump" in cand:
                        refused_bumps.append(cand["support_refused_bump"])
                    if cand.get("significant"):
                        rejected.append(_Refusal({"cause": cause.name, "reason": cand["reason"]},
                                                 beside=named_in(terms), at=len(judged)))
                        if cand.get("form_refused") == "confounded":
                            confounded.add(cause.name)
                    continue
                if _may_be_plainer(cand["term"]):
                    passed.append(cand)
                margin = settings.material_sigma ** 2 * noise_sigma(st) ** 2
                if best is None or cand["cv"] < best["cv"] - margin or (
                        cand["cv"] <= best["cv"] + margin
                        and cand["term"].columns.shape[1] < best["term"].columns.shape[1]):
                    best = cand
            if best is None:
                break
            if ENTRANT_FORM_HELD_OUT:
                best = _entrant_form_held_out(best, other_forms, passed, noise_sigma(st), settings)
            forms_of = dict(other_forms)
            del other_forms
            best = _plainer_one_explanation(best, passed, st, noise_sigma(st), settings)
            if FORM_SHIFT_CARRIED and _beyond_vif_max(best["term"].evidence, settings) \
                    and best["term"].cause in forms_of:
                # the form adopted is inflated beyond vif_max along a direction: the cause's other passing forms, in
                # their determined combinations, are its readings under the same name (_workpiece's forms)
                tb = best["term"]
                rivals = tuple((_layout_text(r["term"].info), r["term"].columns @ r["term"].map
                                if r["term"].map is not None else r["term"].columns)
                               for r in forms_of[tb.cause](any_covariate=True)
                               if (not FORM_SHIFT_DETERMINED_ONLY or not _beyond_vif_max(r["term"].evidence, settings))
                               and r["term"].info is not tb.info and not (
                                   r["term"].columns.shape == tb.columns.shape
                                   and np.array_equal(r["term"].columns, tb.columns)))
                if rivals:
                    best["term"] = dataclasses.replace(tb, form_rivals=rivals)
            del forms_of
            if CAUSE_ALTERNATIVES_OF_THE_ROUND:
                # the round's other passing candidates, in the forms they passed with: step 8 tests them as the
                # winner's alternatives (their columns, already built, kept only for causes of no fixed layouts:
                # step 8 tests the others' every layout anyway)
                best["term"] = dataclasses.replace(best["term"], round_rivals=tuple(
                    (c["term"].cause, c["term"].info, c["term"].columns) for c in passed
                    if c["term"].cause != best["term"].cause and c["term"].cause not in fixed_causes))
            del passed  # (not held through the outlier screen and refit below)
            terms.append(best["term"])
            # outliers judged against the better model: a systematic effect is no dust
            X = np.hstack([bl.A, _stack(terms, all_rows)])
            before, rows = rows, np.setdiff1d(all_rows, outliers_of(X))
            Qb, folds, st = model(rows, terms)
            # the same rows: the winner's own cross-validation was of this very model
            cv_cur = best["cv"] if np.array_equal(rows, before) else folds.mse(y[rows], _stack(terms, rows),
                                                                                _penalty(terms))
        return terms, rows, st, folds, Qb

    rows_b = rows  # the rows the baseline was judged on

    def judge_rows_again(rows_):
        """The baseline judged again on ``rows_`` if they are not those it was judged on (the report's
        baseline structure is that of the rows the report keeps); returns the rows it is judged on."""
        nonlocal cv_b, held_b, gap_b, lof_b, diag_b, structure_b
        if not np.array_equal(rows_, rows_b):
            _, fa_, sa_ = model(rows_, [])
            cv_b, held_b, gap_b, lof_b, diag_b, structure_b = judge_baseline(sa_, fa_, rows_)
        return rows_

    seen = [(st, diag_b)]
    terms, rows, st, folds, Qb = search(rows, st, folds, Qb, diag_b, cv_b, seen)
    if len(rows) < N:
        # the rows called outliers may be a systematic effect's largest
        # residuals: search again with every row; if a cause is then adopted
        # and fewer outliers are left against it, or it cuts theirs in two
        # set-ups (_explains_set_aside: a bump its form follows only in part
        # leaves as many), the "outliers" it explains were its structure
        Qa, fa, sa = model(all_rows, [])
        t1 = terms
        seen2 = []  # (its first diagnosis is of every row, rows=None: not one the others can take)
        t2, r2, s2, f2, q2 = search(all_rows, sa, fa, Qa, diagnosis(sa, bl.covariates), fa.mse(y), seen2)
        if t2 and (len(r2) > len(rows) or per_setup and _explains_set_aside(Qall, y, all_rows, rows, t2, events, r2)) \
                and not (WORKPIECE_SEEN_WITHOUT_OUTLIERS
                         and _workpiece_unseen_without_outliers(model(rows, [])[0], y, rows, t2, settings,
                                                                events if per_setup else None)):
            # a cause explains some of them: they were its structure
            terms, rows, st, folds, Qb = t2, r2, s2, f2, q2
        seen += seen2
        for tm in (t1 if terms is t2 else t2):  # (the search not taken: a refusal beside its causes is marked)
            gone_how.setdefault(tm.cause, "adopted in another search of this run, which the report does not take")
    if PART_CHANGE_OUTLIER_LOOK and len(rows) < N and not any(tm.cause == "part_change" for tm in terms) \
            and "part_change" in scans and scans["part_change"][0] and bl.kind == "planar":
        look = _part_change_outlier_look(bl.A, y, rows, _stack(terms, all_rows), bl.data.touches.feature,
                                         scans["part_change"][0], settings.alpha_family)
        if look is not None:
            # part_change searched again on every row with the feature's layouts alone, its count the look's
            # (those trials, twice); the other causes as the second search had them
            held = scans["part_change"]
            scans["part_change"] = (look["scans"], float(look["trials"]))
            try:
                Qa, fa, sa = model(all_rows, [])
                seen3 = []
                t3, r3, s3, f3, q3 = search(all_rows, sa, fa, Qa, diagnosis(sa, bl.covariates), fa.mse(y), seen3)
            finally:
                scans["part_change"] = held
            if any(tm.cause == "part_change" for tm in t3) and len(r3) > len(rows) \
                    and not (WORKPIECE_SEEN_WITHOUT_OUTLIERS
                             and _workpiece_unseen_without_outliers(model(rows, [])[0], y, rows, t3, settings,
                                                                    events if per_setup else None)):
                for tm in t3:
                    if tm.cause == "part_change":
                        tm.evidence["outlier_look"] = {k: look[k] for k in ("feature", "rows", "p", "trials")}
                t_prev, terms, rows, st, folds, Qb = terms, t3, r3, s3, f3, q3
                seen += seen3
            for tm in (t_prev if terms is t3 else t3):  # (likewise)
                gone_how.setdefault(tm.cause, "adopted in another search of this run, which the report does not take")
    tick()

    by_name = {c.name: c for c in catalogue}

    def judge_later_again(later: list, kept: list, rows_, gone: Term, put_back: bool, put_back_by) -> tuple:
        """The causes ``later`` (adopted after ``gone``, searched with it in the model) judged again in the order of
        adoption beside ``kept`` (each that stands appended to it, :func:`judge_again`). A put-back of outliers goes
        with its cause where that is refused, or to its new term. ``(put_back, put_back_by, undone)``: the put-back
        after, and whether one was undone. The rival check's drop and a re-chosen ridge's refusal both take it."""
        undone = False
        for old in later:
            new = judge_again(old, kept, rows_, gone)
            if new is not None:
                kept.append(new)
            if old is put_back_by:
                if new is None:
                    put_back, put_back_by, undone = False, None, True
                else:
                    put_back_by = new
        return put_back, put_back_by, undone

    def rows_screened(kept: list) -> np.ndarray:
        """Every row but the outliers judged against the baseline and ``kept`` (the baseline alone when none)."""
        return np.setdiff1d(all_rows, outliers_of(np.hstack([bl.A, _stack(kept, all_rows)])) if kept
                            else outliers_of(bl.A, Qall))

    def evaluated_again(cause: str, kept: list, rows_) -> dict:
        """The search's evaluation of ``cause`` beside ``kept`` on ``rows_`` (its round's model, diagnosis and
        held-out base), recorded in ``seen`` and ``judged`` as a round's: :func:`judge_again`'s and
        :func:`pair_decided`'s one step."""
        _, f_, s_ = model(rows_, kept)
        # the search's own diagnosis of a round: every covariate in its first, the smooth ones after
        diag_ = diagnosis(s_, smooth_covs if kept else bl.covariates, rows_)
        seen.append((s_, diag_))
        cv_ = f_.mse(y[rows_], _stack(kept, rows_), _penalty(kept)) if kept else f_.mse(y[rows_])
        judged.append((cause, named_in(kept)))
        return evaluate(by_name[cause], s_, f_, kept, cv_, _family_ss(bl, diag_, len(rows_), s_.rss))

    def judge_again(old: Term, kept: list, rows_, gone: Term) -> Term | None:
        """The cause of ``old``, adopted with ``gone`` in the model, judged again by the search's tests beside
        ``kept`` alone (the causes adopted before it that stay) on ``rows_``: its term as adopted there (its form
        chosen again), or None (refused, said so in ``rejected``)."""
        cand = evaluated_again(old.cause, kept, rows_)
        if cand.get("reason"):
            rejected.append(_Refusal({"cause": old.cause, "reason": f"judged again without {gone.cause} (adopted "
                                      f"before it, then dropped): {cand['reason']}"},
                                     beside=named_in(kept), at=len(judged)))
            gone_how[old.cause] = f"refused when judged again without {gone.cause}"
            return None
        cand["term"].evidence["judged_again_without"] = gone.cause
        return cand["term"]

    def round_reopened(kept: list, out: list) -> tuple:
        """The search resumed beside ``kept`` (the causes the rival check left), every cause it dropped (``out``)
        kept out of its rounds (:data:`DROPPED_ROUND_REOPENED`), on the rows the outlier screen keeps against
        ``kept``: ``(terms, rows, state, folds, basis)`` as :func:`search` gives them, each term it adds marked
        ``round_reopened_without`` (the dropped causes' names)."""
        rows_ = rows_screened(kept)
        Qb_, f_, s_ = model(rows_, kept)
        cv_ = f_.mse(y[rows_], _stack(kept, rows_), _penalty(kept)) if kept else f_.mse(y[rows_])
        # (the first round beside no cause takes the baseline's diagnosis on these rows, as the first search's does)
        diag_ = None if kept else diagnosis(s_, bl.covariates, rows_)
        gone = sorted({t.cause for t in out})
        t_, r_, s_, f_, q_ = search(rows_, s_, f_, Qb_, diag_, cv_, seen, start=kept, kept_out=frozenset(gone))
        for tm in t_[len(kept):]:
            tm.evidence["round_reopened_without"] = gone
        return t_, r_, s_, f_, q_

    def rival_checked(terms, first: int, rows_, st_, folds_, Qb_, out: list) -> tuple:
        """The terms from ``first`` on (adopted in a round reopened after :func:`_rechosen_gate`'s refusal of a
        cause, :data:`RECHOSEN_ROUND_REOPENED`) judged by the rival check as step 5 judges every term: one that fails
        is dropped and said so, the causes adopted after it judged again without it, and (with
        :data:`DROPPED_ROUND_REOPENED`) the round reopened again, every dropped cause and ``out`` kept out; until
        none fails. Not the check's put-back of outliers (the reopening runs only where none were put back).
        ``(terms, rows, state, folds, basis)``."""
        changed = True
        while changed:
            changed = False
            for tm in terms[first:]:
                share = _rival_share(bl, tm, terms, Qb_, y, rows_, noise_sigma(st_), settings, bases, scan_trials)
                tm.evidence.update(share)
                if share["kept"]:
                    continue
                at = next(i for i, t in enumerate(terms) if t is tm)
                later, terms = terms[at + 1:], terms[:at]
                dropped.append(tm)
                demoted.append({"cause": tm.cause, **share})
                rejected.append(_Refusal({"cause": tm.cause, "reason": _demotion_reason(share, tm.covariate,
                                                                                         settings)},
                                         beside=named_in(terms + later), at=len(judged)))
                gone_how[tm.cause] = "dropped by the rival check"
                judge_later_again(later, terms, rows_, tm, False, None)
                Qb_, folds_, st_ = model(rows_, terms)
                if DROPPED_ROUND_REOPENED and len(terms) < settings.max_findings:
                    terms, rows_, st_, folds_, Qb_ = round_reopened(terms, dropped + out)
                changed = True
                break
        return terms, rows_, st_, folds_, Qb_

    # PAIR_REFUSED_DECIDED: causes restored (once each: the loop guard) and the causes refused beside their drop that
    # a restoration decided against (kept out of every round after it)
    pair_restored: set = set()
    pair_out: list = []

    def pair_decided(gone: Term, later: list, kept: list, rows_) -> Term | None:
        """``gone``, just dropped by the rival check beside ``later`` (adopted after it), judged once more where a cause
        of ``later`` was then refused when judged again without it (:data:`PAIR_REFUSED_DECIDED`): beside ``kept`` (the
        causes that stay, the refused one's model) by the search's tests, then by the rival check in the model with it.
        Its new term (evidence ``pair_restored_over``: the refused causes, which join ``pair_out``), or None (stays
        dropped; a refusal at the tests is said in ``rejected``)."""
        refused = [o for o in later if o.cause not in named_in(kept)]
        if not refused or gone.cause in pair_restored or len(kept) >= settings.max_findings:
            return None
        names = ", ".join(o.cause for o in refused)
        cand = evaluated_again(gone.cause, kept, rows_)
        if cand.get("reason"):
            rejected.append(_Refusal({"cause": gone.cause, "reason": f"judged again once {names} (adopted after it) "
                                      f"was refused without it: {cand['reason']}"},
                                     beside=named_in(kept), at=len(judged)))
            return None
        tm = cand["term"]
        with_ = kept + [tm]
        q_, _, s2_ = model(rows_, with_)
        share = _rival_share(bl, tm, with_, q_, y, rows_, noise_sigma(s2_), settings, bases, scan_trials)
        tm.evidence.update(share)
        if not share["kept"]:
            rejected.append(_Refusal({"cause": gone.cause, "reason": f"judged again once {names} (adopted after it) "
                                      f"was refused without it: {_demotion_reason(share, tm.covariate, settings)}"},
                                     beside=named_in(kept), at=len(judged)))
            return None
        tm.evidence["pair_restored_over"] = [o.cause for o in refused]
        pair_restored.add(gone.cause)
        pair_out.extend(refused)
        return tm

    # 4. rival check: a named cause must explain its covariate's structure
    demoted = []
    dropped = []  # the terms the rival check dropped (their columns re-tested beyond the final model, step 5)
    put_back = False  # the outliers were a named cause's structure: never set aside again in this run
    put_back_by = None  # the cause that put them back: if it is dropped later, they are judged again
    undone = False  # a put-back undone (its cause dropped)
    changed = True
    while changed and terms:
        changed = False
        for tm in list(terms):
            share = _rival_share(bl, tm, terms, Qb, y, rows, noise_sigma(st), settings, bases, scan_trials)
            if not share["kept"] and len(rows) < N:
                # the touches set aside as outliers may be this cause's own largest residuals (a local
                # defect's bump, whose form the cause follows only in part): judged without them, the
                # cause is left with the rest of its structure and a plainer rival does as well. Those
                # it explains (_explained_outliers) are put back and it is judged again, with the noise
                # of the cleaned rows (the in-sample sigma with them in is inflated by any left). If it
                # stands, they were its structure, not dust; the others stay set aside (a chip where the
                # cause does not reach). gen_b local_scale_defect 812, 829, 1003: the bump's 6-8 largest
                # touches set aside, then the slip "explained as much".
                back_rows = np.union1d(rows, _explained_outliers(Qall, y, all_rows, rows, tm, terms))
                if len(back_rows) > len(rows):
                    Qa, _, _ = model(back_rows, terms)
                    back = _rival_share(bl, tm, terms, Qa, y, back_rows, noise_sigma(st), settings, bases,
                                        scan_trials)
                    if back["kept"]:
                        share = {**back, "outliers_put_back": int(len(back_rows) - len(rows))}
                        rows, put_back, put_back_by = back_rows, True, tm
                        Qb, folds, st = model(rows, terms)
                        changed = True
            tm.evidence.update(share)
            if changed:
                break  # (every term judged again on every row)
            if not share["kept"]:
                at = next(i for i, t in enumerate(terms) if t is tm)
                later = terms[at + 1:]
                terms = terms[:at]
                dropped.append(tm)
                if tm is put_back_by:  # what it put back was its structure only if it stays named
                    put_back, put_back_by = False, None
                    undone = True
                demoted.append({"cause": tm.cause, **share})
                rejected.append(_Refusal({"cause": tm.cause, "reason": _demotion_reason(share, tm.covariate, settings)},
                                         beside=named_in(terms + later), at=len(judged)))
                gone_how[tm.cause] = "dropped by the rival check"
                # the causes adopted after it were searched with it in the model: each is judged again, in the
                # order of adoption, beside the causes before it that stay (section 4's "a search built on a
                # dropped cause")
                put_back, put_back_by, gone_back = judge_later_again(later, terms, rows, tm, put_back, put_back_by)
                undone = undone or gone_back
                back = pair_decided(tm, later, terms, rows) if PAIR_REFUSED_DECIDED and not put_back else None
                if back is not None:  # (the drop referred to a model that no longer stands: it is undone)
                    terms.append(back)
                    dropped.pop()  # (tm, the last dropped and demoted: judge_later_again adds to neither)
                    demoted.pop()
                    gone_how.pop(tm.cause, None)
                Qb, folds, st = model(rows, terms)
                if DROPPED_ROUND_REOPENED and not put_back and len(terms) < settings.max_findings:
                    # the round the dropped cause won is decided again without it, and the rounds after it: the
                    # search resumes beside the causes that stay, every dropped cause kept out (a candidate that
                    # passed that round, or was refused only beside the dropped cause, is judged again); what it
                    # adopts meets this check in turn (the loop runs again)
                    terms, rows, st, folds, Qb = round_reopened(terms, dropped + pair_out)
                changed = True
                break
    if (terms or undone) and demoted and not put_back:
        # (none dropped: the search judged the outliers against these terms last; a put-back undone: its touches
        # are judged again, against the baseline alone when no cause is left)
        rows = rows_screened(terms)
    rows_b = judge_rows_again(rows)
    Qb, folds, st = model(rows, terms)
    if PENALTY_RECHOSEN and any(t.penalty is not None and not t.unnamed for t in terms):
        terms = _penalties_rechosen(terms, folds, y, rows)
        st = _state(Qb, y, rows, terms)
        if PENALTY_RECHOSEN_GATED:
            # the gates of adoption that depend on the ridge, run again where it moved (_rechosen_gate)
            for tm in [t for t in terms if "penalty_at_adoption" in t.evidence]:
                rest = [t for t in terms if t is not tm]
                so = _state(Qb, y, rows, rest)
                why = _rechosen_gate(tm, rest, terms, bl, folds, y, rows, so,
                                     (settings.material_sigma * noise_sigma(so)) ** 2)
                if why is None:
                    continue
                # refused as its adoption would have been: the causes adopted after it were searched beside it
                # and are judged again without it (as after the rival check's drop)
                at = next(i for i, t in enumerate(terms) if t is tm)
                later, terms = terms[at + 1:], terms[:at]
                rejected.append(_Refusal({"cause": tm.cause, "reason": why}, beside=named_in(terms + later),
                                         at=len(judged)))
                gone_how[tm.cause] = "refused at its ridge chosen again in the final model"
                if put_back_by is not None and put_back_by.cause == tm.cause:  # (its put-back undone with it)
                    put_back, put_back_by = False, None
                # (a later cause's put-back goes with it, or to its new term: the rival check's rule; the session
                # 21 review)
                put_back, put_back_by, _ = judge_later_again(later, terms, rows, tm, put_back, put_back_by)
                if not put_back:  # the outliers judged against the terms that stay (the rival check's rule)
                    rows = rows_screened(terms)
                    rows_b = judge_rows_again(rows)
                Qb, folds, st = model(rows, terms)
                if RECHOSEN_ROUND_REOPENED and not put_back and len(terms) < settings.max_findings:
                    # the round the refused cause won decided again without it (as DROPPED_ROUND_REOPENED after the
                    # rival check's drop): what it adopts meets the rival check
                    first = len(terms)
                    terms, rows, st, folds, Qb = round_reopened(terms, dropped + [tm])
                    terms, rows, st, folds, Qb = rival_checked(terms, first, rows, st, folds, Qb, [tm])
                    rows_b = judge_rows_again(rows)
                break  # (one refusal: a second penalised named cause is not in the catalogue)
    tick()

    # 5. what remains
    sig = noise_sigma(st)
    diag_e = diagnosis(st, bl.covariates, rows, known=_made_on(seen, st))
    st_e = st  # (the model diag_e's tests were made against)
    E_named = _stack(terms, rows)
    gap_e = _cv_gap(folds, st, y, E_named, _penalty(terms), settings, gap_seed, sig) if terms else gap_b
    lof_e = lack_of_fit(st.rss, st.dof, rep) if _constant_within(rep_key[rows], E_named) else None
    structure_e = _structure(diag_e, gap_e, lof_e, st, sig, settings, bl.kind, floor)
    if at_roundoff:
        structure_e = {**structure_e, "present": False}
    left = _dropped_still_significant(dropped, st, rows, y, folds, terms, sig, settings)
    if left:
        structure_e = {**structure_e, "present": True, "dropped_still_significant": left}
    structure_e = _floor_guarded(structure_e, lof_e, st, gap_e)
    cv_named = folds.mse(y[rows], E_named, _penalty(terms)) if terms else cv_b
    tick()
    smooth = None
    if structure_e["present"]:
        smooth = _unnamed_smooth(bl, diag_e, terms, folds, st, y, rows, cv_named, sig, settings, bases)
        if smooth is not None and smooth.columns.shape[1]:
            # a named cause that the unnamed term makes redundant explained part
            # of that structure, not its own: it goes
            E_s = smooth.columns[rows]
            cv_s = folds.mse(y[rows], np.hstack([E_named, E_s]), _penalty(terms + [smooth]))
            fam_s = bl.covariate(smooth.covariate).family
            def carries_the_nesting_smooth(tm) -> bool:
                # step 4e's test: beside the other terms, the cause explains at least rival_share of what
                # the nesting smooth explains (its columns unpenalised: a ridge's field is counted at full
                # size, which errs towards keeping it)
                so = _state(Qb, y, rows, [t for t in terms if t is not tm])
                d_c = _candidate_ss(nested_f_batch(tm.columns[None, rows], so.Q, so.r, so.rss, so.dof), so)
                d_s = _candidate_ss(nested_f_batch(E_s[None], so.Q, so.r, so.rss, so.dof), so)
                return d_c >= settings.rival_share * d_s

            for tm in list(terms):
                cov_n = bl.covariate(tm.covariate)
                if cov_n is not None and (cov_n.family == fam_s or (
                        fam_s in NESTING_FAMILIES.get(cov_n.family, ()) and carries_the_nesting_smooth(tm))):
                    # the unnamed term refines the cause's own covariate, or nests the cause's family on the
                    # design (a feature's offset per set-up takes any position or direction structure over the
                    # feature, the cause's included: step 4e's NESTING_FAMILIES) and the cause explains
                    # rival_share of what it does (4e's test; a cause explaining less of it leaves the smooth
                    # holding a structure of its own: gen_a thermal_bending 1064, out of the catalogue, a
                    # local defect of 62 % at one position explaining 23 of the smooth's 37 um^2 was kept and
                    # named, session 19's review): its making the cause redundant is no evidence against the
                    # cause. The cause stays
                    continue
                rest = [t for t in terms if t is not tm]
                cv_wo = folds.mse(y[rows], np.hstack([_stack(rest, rows), E_s]), _penalty(rest + [smooth]))
                if cv_wo - cv_s < (settings.material_sigma * sig) ** 2:
                    terms.remove(tm)
                    demoted.append({"cause": tm.cause, "redundant_with": smooth.covariate,
                                    "cv_gain_over_unnamed_um2": (cv_wo - cv_s) / UM ** 2})
                    rejected.append(_Refusal({"cause": tm.cause, "reason": "no material gain once the unnamed "
                                              f"structure in {smooth.covariate} is modelled"},
                                             beside=named_in(rest), at=len(judged)))
                    gone_how[tm.cause] = f"dropped as redundant with the unnamed structure in {smooth.covariate}"
            terms.append(smooth)
            # outliers judged against the model with the smooth term
            X = np.hstack([bl.A, _stack(terms, all_rows)])
            new_rows = rows if put_back else np.setdiff1d(all_rows, outliers_of(X))
            if not np.array_equal(new_rows, rows):
                rows = new_rows
                Qb, folds, _ = model(rows, [])
                rows_b = judge_rows_again(rows)
            st = _state(Qb, y, rows, terms)
    alone = structure_e.get("lack_of_fit_alone")
    if alone is not None and smooth is not None and smooth.columns.shape[1]:
        # an unnamed term adopted for its held-out gain is evidence beside the lack of fit: nothing to soften
        # (gen_a reseat_hysteresis 1036: the turn from the previous touch, 1.5 um^2 gained held out)
        structure_e = {**structure_e, "lack_of_fit_alone": {**alone, "softened": False, "smooth_adopted": True}}
    elif alone is not None and alone["softened"] and LOF_ALONE_FLOOR_GUARD == "none":
        structure_e = {**structure_e, "present": False}  # (after the smooth's search, which it may pass)
    tick()

    # 6. estimates
    def fixed():
        # every cause whose scans are all single trials (a few fixed layouts: degrees of a drift, one per
        # temperature sensor, one per feature), for the named causes' alternatives: each layout's columns
        # (whitened) built when that layout is tested and not kept (held all at once they were 105 columns
        # per row on gen_a, ~84 MB more on a 1e5-row log)
        # (a scan whose trials are one layout in two readings of the pre-travel, core.causes.PRETRAVEL_ALONG, is
        # two fixed layouts: each reading tested; the session 21 review found probe_lobing dropped from this check
        # once its scan offered both)
        return {k: _Layouts(scans[k][0]) for k in fixed_causes}

    findings = _findings(bl, terms, Qb, y, rows, st, settings, structure_e, diag_e, demoted, smooth, cv_named, bases,
                         seen + [(st_e, diag_e)], fixed=fixed, confounded=confounded,
                         repeats=_repeats_beyond_residual(rep_key[rows], st, settings), folds=folds)
    E_all = _stack(terms, rows)
    cv_e, held_e = _held_out(folds, y[rows], bl.groups[rows], E_all, _penalty(terms)) if terms else (cv_b, held_b)
    outliers = np.setdiff1d(all_rows, rows)
    if outliers.size:
        findings.append(_outlier_finding(bl, outliers, st0, st, ranks, events, outlier_seed, settings, places,
                                         covariate_ranks(bl.covariates, families=HISTORY_FAMILIES)))
        _doubt_beside_turned_outliers(findings, settings)
        _doubt_beside_gathered_outliers(findings, settings)
    # the causes named beside outliers that one column of structure explains, judged again with those rows back
    # and that column beside them (OUTLIER_STRUCTURE_REJUDGED): {cause: (column text, (N,) column)}
    rejudged = (_rejudged_beside_outlier_structure(bl, findings, terms, Qall, y, all_rows, outliers, sig, settings)
                if OUTLIER_STRUCTURE_REJUDGED and outliers.size else {})
    _doubt_beside_noise_excess(findings)
    if not findings and structure_b["present"]:
        findings.append(_unexplained_only(diag_b, structure_b, st, sig, settings))
        _floor_hedge(findings[-1].evidence, structure_b)
    elif (not findings and REPEATS_FLOOR_NONE_RECHECKED and sigma_rep is not None and not at_roundoff
          and not (short is not None and short["used"])):
        made = _none_at_the_residual_floor(bl, st, rep, rows, settings, bases, known=_made_on([(st_e, diag_e)], st))
        if made is not None:
            findings.append(made)
    findings = _ordered(findings, (settings.material_sigma * sig) ** 2 * len(rows) / UM ** 2)
    if OUTLIERS_LEAD_BESIDE_SMOOTH_DEFECT and len(rows) < len(all_rows):
        findings = _outliers_lead_beside_smooth_defect(
            findings, (settings.material_sigma * sig) ** 2 * len(rows) / UM ** 2,
            lambda c: any(_explained_outliers(Qall, y, all_rows, rows, t, terms).size for t in terms if t.cause == c))
    if OUTLIERS_TURNED_UNEXPLAINED:
        findings = _turned_outliers_unexplained(findings, settings, st.sigma / UM)
    if NAMED_BESIDE_TURNED_OUTLIERS_UNEXPLAINED:
        findings = _named_beside_turned_outliers_unexplained(findings, settings, st.sigma / UM)
    if OUTLIERS_UNDER_SUPPORT_REFUSED_BUMP and outliers.size:
        _doubt_outliers_under_refused_bump(findings, outliers, refused_bumps)
    if OUTLIERS_NOT_GROSS_HEDGED and outliers.size:
        _doubt_outliers_not_gross(findings, st.sigma / UM)
    if bl.kind == "volumetric":
        _volumetric_hedges(bl, findings, structure_e, st, settings)
        if VOLUMETRIC_IMPLAUSIBLE_UNEXPLAINED and not findings:
            made = _volumetric_implausible_unexplained(rejected, structure_e, st)
            if made is not None:
                findings.append(made)
    tick()
    # outliers the report does not call dust with confidence (one event, or a pattern beside them): whether
    # their touches are dust or the part's own state is the removal's assumption, and its shift of the
    # workpiece is tested and carried where real (:func:`_workpiece`'s ``doubted``)
    fo = next((f for f in findings if f.cause == causes_mod.OUTLIER), None)
    form = _outliers_span_a_form(bl, outliers) if (fo is not None and OUTLIER_SHIFT_CARRIED and
                                                   fo.evidence.get("confidence") == "ambiguous") else None
    # the named causes' alternatives under another name (their columns; never in the report)
    alt_cols = {f.cause: f.evidence.pop("_alt_columns") for f in findings if "_alt_columns" in f.evidence}
    # the richer causes significant beyond a named one (RICHER_SHIFT_CARRIED): their added columns, built on demand
    richer_cols = {f.cause: f.evidence.pop("_richer_columns") for f in findings if "_richer_columns" in f.evidence}
    # the cause's other passing forms where the adopted one is inflated beyond vif_max (FORM_SHIFT_CARRIED)
    form_cols = {f.cause: f.evidence.pop("_form_columns") for f in findings if "_form_columns" in f.evidence}
    # the named causes' terms on their determined directions only (HEDGED_SHIFT_READING "determined")
    det_cols = {f.cause: f.evidence.pop("_determined_columns") for f in findings if "_determined_columns" in f.evidence}
    # outliers that share their target with touches kept (the screen chose which of the target's touches are the
    # part's): those reading less material than the fit are no particle (:func:`_workpiece`'s ``beside_kept``)
    shared = _outliers_beside_kept(bl, outliers, rows) if OUTLIER_BELOW_KEPT and outliers.size else None
    named_shift = {}
    # the named causes whose own term's shift is tested and carried (HEDGED_SHIFT_CARRIED): the hedged ones, the
    # hedged inflated ones, or every inflated one
    hedged_names = {f.cause for f in findings if f.evidence.get("confidence") == "ambiguous"}
    without = {f.cause for f in findings if HEDGED_SHIFT_CARRIED and (
        f.cause in hedged_names if HEDGED_SHIFT_CARRIED == "hedged" else
        _beyond_vif_max(f.evidence, settings) and (HEDGED_SHIFT_CARRIED == "inflated_any" or f.cause in hedged_names))}
    if rejudged:  # the structure's column in the cause's place: one more reading whose shift is tested and carried
        alt_cols = {c: list(alt_cols.get(c, ())) if NAMED_ALTERNATIVE_SHIFT_CARRIED else [] for c in
                    set(alt_cols) | set(rejudged)}
        for c, (text, col) in rejudged.items():
            alt_cols[c].append((text, col[:, None]))
    # hedged terms finer than the targets are apart (FINE_SHIFT_CARRIED): their shift tested and carried as well
    fine = _fine_hedged(bl, terms, {f.cause: f.evidence for f in findings if f.cause in hedged_names},
                        settings.alpha_family) if FINE_SHIFT_CARRIED else {}
    without |= set(fine)
    wp, ident, Gb, Ge, cGb, cGe, shift = _workpiece(
        bl, terms, y, rows, st0, st, settings.alpha_family, form if form is not None and form.size else None,
        alternatives=alt_cols if NAMED_ALTERNATIVE_SHIFT_CARRIED or rejudged else None, beside_kept=shared,
        named=named_shift,
        richer=richer_cols or None, forms=form_cols or None, without=without or None, determined=det_cols or None)
    # the extended workpiece not offered where the extension has not earned it (SMOOTH_WORKPIECE_EARNED,
    # WORKPIECE_U95_GROWTH_WITHHELD; both off): the finding and its diagnosis stay, the baseline's workpiece is the estimate
    unearned = _workpiece_unearned(terms, folds, y, rows, bl.groups, cv_e, held_e, wp,
                                   _u95_gauge_free(bl, Gb, Ge, cGb, cGe) if WORKPIECE_U95_GROWTH_WITHHELD else None) \
        if SMOOTH_WORKPIECE_EARNED or WORKPIECE_U95_GROWTH_WITHHELD else None
    Ge_fit = cGe_fit = None
    if unearned is not None and not unearned["withheld"]:
        unearned = None
    if unearned is not None:
        Ge_fit, cGe_fit = Ge, cGe
        wp = _withheld_rows(wp)
        Ge, cGe = np.full_like(Ge, np.nan), None
    if named_shift:
        for f in findings:
            if f.cause in named_shift:
                fig = named_shift[f.cause]
                f.evidence["workpiece_shift_form" if fig.get("form") else
                           "workpiece_shift_determined" if fig.get("determined") else
                           "workpiece_shift_without" if fig.get("without") else
                           "workpiece_shift_richer" if fig.get("richer") else "workpiece_shift_alternative"] = \
                    _clean({k: v for k, v in fig.items() if k not in ("richer", "form", "without", "determined")})
    for f in findings:
        if f.cause in fine:
            f.evidence["fine_term"] = {"length_mm": fine[f.cause][0] * 1e3,
                                       "target_spacing_mm": fine[f.cause][1] * 1e3}
    if shift is not None and shift.get("of") == "outliers":
        fo.evidence["workpiece_shift"] = _clean({k: v for k, v in shift.items() if k not in ("of", "beside")})
    res_e = np.full(N, np.nan)
    res_e[rows] = st.r
    conv = list(bl.conventions) + [
        ("cv: leave one group (set-up) out; the held-out group's own columns refitted on it" if use_cv else
         "no cross-validation (the design has no redundancy to predict held-out rows): the prediction error "
         "is Mallows' Cp, (RSS + 2 k s^2) / n"),
        f"false-alarm rate {settings.alpha:g} split over {', '.join(FAMILIES)}; "
        f"materiality {settings.material_sigma:g} sigma per row",
        "U95: k = 2, sigma from each model's residuals",
        *([f"every baseline residual within the data's rounding ({floor / UM:.2g} um: {ROUNDOFF_ULPS:g} eps times "
           "its largest coordinate): nothing beyond rounding to find"] if at_roundoff else []),
        "gain's cv_rms_ratio_95: 95 % interval over set-ups (delete-one-set-up jackknife of the ratio's "
        "logarithm, Student's t at 97.5 % with set-ups - 1 degrees of freedom); none without an extension, "
        "cross-validation or three set-ups"]
    smooth_terms = [t for t in terms if t.unnamed]
    pen_named = [t.cause for t in terms if t.penalty is not None and not t.unnamed]
    if pen_named:
        conv.append("a penalised named cause (" + ", ".join(pen_named) +
                    "): its ridge chosen by the held-out mean square; the same penalised fit gives its held-out "
                    "gain, magnitudes (U95 from s^2 (E^T E + P)^-1), residuals and extended workpiece")
    if smooth_terms:
        conv.append("extended workpiece beside an unnamed smooth: the smooth takes no combination the baseline "
                    "spans exactly; U95 from the penalised fit's covariance s^2 (A^T A + P)^-1 (the Bayesian "
                    "covariance of a penalised spline, Wahba 1983); an estimate only where the data alone "
                    "determine it")
    if shift is not None and shift.get("of") == "outliers":
        conv.append(f"removing the outliers moves the workpiece by {shift['shift_rms_um']:.3g} um RMS (form only), "
                    f"{fmt_p(shift['p'])} against its own scatter: real, and the report does not call them dust "
                    "with confidence" + (" or they read less material than the touches kept at their targets (no "
                                         "particle does; " if OUTLIER_BELOW_KEPT else " (") +
                    "they may be the part's own state at those touches): the extended U95 "
                    "carries the shift (u = |shift| / 2 per target)")
        shift = shift.get("beside")  # the smooth's own figures, tested and not carried (the session 21 review)
    if shift is not None:
        for f in findings:
            if (f.cause == causes_mod.UNEXPLAINED and "smooth" in f.evidence) or f.evidence.get(
                    "magnitudes_not_determined") or f.cause in pen_named:
                f.evidence["workpiece_shift"] = _clean(shift)
        smooth_in = any(t.unnamed for t in terms)
        # who moves the workpiece, and whose assumption splits the effect between machine and part: the
        # smooth's (no physics), a penalised cause's penalty (its field spans part of what the baseline spans,
        # the penalty deciding the split), or the fit's (a cause whose magnitudes the design does not determine)
        who, split = (("the unnamed smooth", "an unnamed effect between machine and part is the smooth's")
                      if smooth_in else
                      (f"the penalised {', '.join(pen_named)}", "what both the cause and the baseline span between "
                       "machine and part is the penalty's") if pen_named else
                      ("a cause whose magnitudes this design does not determine",
                       "an undetermined effect between machine and part is the fit's"))
        conv.append(f"{who} moves the workpiece by {shift['shift_rms_um']:.3g} um RMS (form only), "
                    f"{fmt_p(shift['p'])} against its own scatter: " + (
                        f"real, and the split of {split} "
                        "assumption: the extended U95 carries the shift (u = |shift| / 2 per target)"
                        if shift["carried_in_u95"] else "within the noise the extended U95 already carries"))
    for c, fig in named_shift.items():
        if fig.get("form") and fig["carried_in_u95"]:
            conv.append(f"{c}'s form has a direction inflated beyond vif_max = {settings.vif_max:g}; "
                        f"{fig['alternative']} (another of its forms, passing every test) moves the workpiece by "
                        f"{fig['shift_rms_um']:.3g} um RMS (form only), {fmt_p(fig['p'])} against its own scatter: "
                        "real, and the workpiece not determined between the cause's forms: the extended U95 carries "
                        "the shift (u = |shift| / 2 per target)")
        if fig.get("determined") and fig["carried_in_u95"]:
            doubt = ("named with doubt" if c in hedged_names else "named")
            conv.append(f"{c} is {doubt}, its form inflated beyond vif_max = {settings.vif_max:g} along a direction, "
                        f"and its term fitted on its determined directions only moves the workpiece by "
                        f"{fig['shift_rms_um']:.3g} um RMS (form only) from its term fitted on every direction, "
                        f"{fmt_p(fig['p'])} against its own scatter: real, and the workpiece not determined along "
                        "the inflated directions: the extended U95 carries the shift (u = |shift| / 2 per target)")
        if fig.get("without") and not fig.get("determined") and fig["carried_in_u95"]:
            doubt = ("named with doubt" if c in hedged_names else
                     f"named, its form inflated beyond vif_max = {settings.vif_max:g} along a direction,")
            conv.append(f"{c} is {doubt} and its term moves the workpiece by {fig['shift_rms_um']:.3g} um "
                        f"RMS (form only), {fmt_p(fig['p'])} against its own scatter: real, and the workpiece not "
                        f"determined between the readings with and without {c}: the extended U95 carries the shift "
                        "(u = |shift| / 2 per target)")
        if c in fine and fig.get("without") and fig["carried_in_u95"]:
            conv.append(f"{c}'s length ({fine[c][0] * 1e3:.3g} mm) is below the median distance between neighbouring "
                        f"targets ({fine[c][1] * 1e3:.3g} mm): its term takes at each target a value the target's own "
                        "parameter can take, so its shift of the workpiece was tested")
        if fig.get("richer") and fig["carried_in_u95"]:
            conv.append(f"{fig['alternative']}, richer than {c} and not excluded beside it, moves the workpiece by "
                        f"{fig['shift_rms_um']:.3g} um RMS (form only) from {c}'s reading, {fmt_p(fig['p'])} against "
                        f"its own scatter: real, and {c} a choice the data doubt: the extended U95 carries the "
                        "shift (u = |shift| / 2 per target)")
    if unearned is not None:
        conv.append(unearned["text"])
    lost = [w["target"] for w in wp if w["baseline_um"] is not None and w["extended_um"] is None]
    if lost and unearned is None:
        conv.append(f"extended workpiece not reported at {len(lost)} target(s) (e.g. {lost[0]}): the data alone "
                    "do not determine it beside " + ", ".join(t.cause if not t.unnamed else
                                                               f"the unnamed smooth in {t.covariate}" for t in terms))
    named = [t.cause if not t.unnamed else f"unnamed smooth in {t.covariate}" for t in terms]
    model_name = bl.model.split(" (")[0] + "".join(f" + {c}" for c in named) + (" - outliers" if outliers.size else "")
    if progress is not None:
        progress(total, total)
    return Discovery(
        baseline=bl, baseline_rms_um=float(np.sqrt(st0.rss / N)) / UM, baseline_cv_rms_um=float(np.sqrt(cv_b)) / UM,
        baseline_n_params=int(Qall.shape[1]), findings=tuple(findings), extended_model=model_name,
        extended_rms_um=float(np.sqrt(st.rss / len(rows))) / UM, extended_cv_rms_um=float(np.sqrt(cv_e)) / UM,
        noise=_noise_report(rep_t, rep, trend, st0, gap_b, lof_b, noise_of(st), short, straddled.size,
                            ("time_by_direction",) if _noise_beyond(bl) is not None else ()),
        diagnosis=tuple(dataclasses.replace(d, basis=None) for d in diag_b),  # (the bases served this run's tests)
        diagnosis_extended=tuple(dataclasses.replace(d, basis=None) for d in diag_e), workpiece=tuple(wp),
        outlier_rows=tuple(int(bl.rows[i]) for i in outliers), residuals_baseline_um=st0.r / UM,
        residuals_extended_um=res_e / UM, conventions=tuple(conv), workpiece_identifiable=ident,
        G_baseline_m=Gb, G_extended_m=Ge, cov_G_baseline=cGb, cov_G_extended=cGe,
        structure={"baseline": structure_b, "extended": structure_e}, rejected=tuple(
            _refusals_marked(rejected, set(named_in(terms)), gone_how, judged) if REFUSALS_BESIDE_DROPPED_MARKED
            else (dict(r) for r in rejected)),
        cv_rms_ratio_95=_ratio_interval(held_b, held_e, float(np.sqrt(cv_e / cv_b)) if cv_b > 0 else float("nan")),
        workpiece_not_offered=unearned, G_extended_fit_m=Ge_fit, cov_G_extended_fit=cGe_fit)


# ---------------------------------------------------------------------------
# steps
# ---------------------------------------------------------------------------
def cv_ratio_text(gain: dict) -> str:
    """The report's cross-validated RMS ratio as words: ``x0.27, 95 %: 0.20-0.36``, the interval where there is one."""
    iv = gain.get("cv_rms_ratio_95")
    return f"x{gain['cv_rms_ratio']:.2f}" + (f", 95 %: {iv[0]:.2f}-{iv[1]:.2f}" if iv is not None else "")


def _held_out(folds, y: np.ndarray, groups: np.ndarray, E: np.ndarray | None = None,
              penalty: np.ndarray | None = None) -> tuple[float, dict | None]:
    """The held-out mean square (``folds.mse``) and, per group, its sum of squares and rows.

    The per-group sums are what :func:`_ratio_interval` resamples; None where
    there is no cross-validation (Mallows' Cp is one in-sample figure: no
    held-out group to leave out).
    """
    if not isinstance(folds, Folds):
        return folds.mse(y, E, penalty), None
    e = folds.residuals(y, E, penalty)
    gs, inv = np.unique(groups, return_inverse=True)
    ss = np.bincount(inv, weights=e * e, minlength=gs.size)
    # rows that could be predicted (Folds.residuals' mask, not ``e != 0``: a predicted row's residual may be
    # exactly 0); their count per group is that group's share of ``last_dof``
    nd = np.bincount(inv, weights=folds.last_predicted.astype(float), minlength=gs.size)
    return float(e @ e) / max(folds.last_dof, 1), {g.item(): (a, b) for g, a, b in zip(gs, ss, nd)}


def _ratio_interval(held_b: dict | None, held_e: dict | None, ratio: float) -> list | None:
    """95 % interval of the cross-validated RMS ratio (extended / baseline) over set-ups: [low, high].

    The measurand is the ratio that new set-ups of the same kind would
    give: the set-ups are the sampled units (the rows of one share its
    placement, its C angle and its time). The ratio ``sqrt((S_e / n_e) /
    (S_b / n_b))`` (S the held-out sums of squares, n the predicted rows)
    is recomputed with each set-up left out in turn; the jackknife
    (Efron & Stein 1981) runs on its logarithm, whose standard deviation
    times Student's t at 97.5 % with G - 1 degrees of freedom gives the
    factor ``f`` of the interval ``[ratio / f, ratio * f]`` (a ratio is
    positive: a symmetric U95 gave negative lower limits). On set-ups that
    differ from each other more than by noise (other C angles, other
    times) it is wider than the spread of repeated campaigns of the same
    set-ups: it includes the set-up-to-set-up variation. None when there is
    no extension, no cross-validation, or fewer than three set-ups.
    """
    if held_b is None or held_e is None or held_b is held_e or not ratio > 0:
        return None
    gs = sorted(set(held_b) & set(held_e))
    if len(gs) < 3:
        return None
    sb, nb = (np.array([held_b[g][k] for g in gs]) for k in (0, 1))
    se, ne = (np.array([held_e[g][k] for g in gs]) for k in (0, 1))
    with np.errstate(divide="ignore", invalid="ignore"):
        lr = 0.5 * np.log(((se.sum() - se) / (ne.sum() - ne)) / ((sb.sum() - sb) / (nb.sum() - nb)))
    if not np.all(np.isfinite(lr)):
        return None
    G = len(gs)
    f = float(np.exp(stats.t.ppf(0.975, G - 1) * np.sqrt((G - 1) / G * np.sum((lr - lr.mean()) ** 2))))
    return [float(ratio / f), float(ratio * f)]


def _cv_gap(folds: Folds, st: _State, y, E, penalty, settings, seed: int, sigma: float) -> CvGap:
    """The held-out gap against its parametric bootstrap: the fitted model plus noise at ``sigma``, same folds.

    Each draw is the model's in-sample fit plus ``sigma`` times standard
    normal noise, put through the same folds and the same in-sample fit, so
    the null's held-out inflation holds whatever the folds do to the fitted
    field itself (its extrapolation) as well as to the noise. With
    :class:`Folds` the held-out prediction of any element of the baseline's
    column space, and of an extension's directions outside the band
    ``1e-10 <= lambda < cv_seen_extension^2``, is exact (what a fold cannot
    predict is the held-out group's own), so there the fitted part cancels
    to rounding and the null is that of the noise alone. Along a band
    direction the fitted part is neither predicted nor refitted: it stays in
    the held-out residuals of the data and of every draw alike, so the
    p-value still compares like with like but ``sigma_cv_m`` (scaled by the
    draws' mean) is biased low. ``seed`` fixes the draws (the answer does not
    depend on what else drew before).
    """
    if isinstance(folds, CpEstimate):  # no cross-validation: no gap to test
        return CvGap(float("nan"), float("nan"), 1.0, float("nan"), 0)
    yr = y[st.rows]
    e = folds.residuals(yr, E, penalty)
    fit = yr - st.r
    n, B = len(yr), settings.cv_draws
    # the draws (rows x cv_draws: 80 MB at 1e5 rows, 792 MB at 1e6) a block of draws at a time, at most
    # CV_DRAWS_BLOCK_BYTES, and what is made of them in place, one table at a time (the fits are linear:
    # a draw's sums do not depend on the others drawn beside it)
    width = max(1, min(B, CV_DRAWS_BLOCK_BYTES // max(8 * n, 1)))
    cv_ss, null_rss = np.empty(B), np.empty(B)
    for j0 in range(0, B, width):
        j1 = min(B, j0 + width)
        Ys = _null_draws(seed, n, B, j0, j1)
        Ys *= sigma
        Ys += fit[:, None]
        eZ = folds.residuals(Ys, E, penalty)
        cv_ss[j0:j1] = np.sum(np.square(eZ, out=eZ), axis=0)
        del eZ
        rZ = st.Q @ (st.Q.T @ Ys)
        np.subtract(Ys, rZ, out=rZ)
        null_rss[j0:j1] = np.sum(np.square(rZ, out=rZ), axis=0)
        del Ys, rZ
    return cv_gap(float(e @ e), st.rss, cv_ss, null_rss, scale=sigma)


#: The CV gap's null draws (:func:`_cv_gap`) are put through the folds this many bytes at a time (a block of
#: draws over every row; the folds' tables of them, two or three, as large): all 99 at once below about 42,000
#: rows (every stored campaign), 41 at a time at the bench's 1e5 rows, 4 at its 1e6, where all 99 were 792 MB
#: (755 MiB). Below the 64 MiB above which vmt's allocator maps an array afresh (``scenarios.cli.MALLOPT``):
#: smaller ones reuse the freed heap it keeps (248 MiB of it free, 221 MiB mapped, when the 1e6-row log's
#: discover reached the draws at 1,936 MiB of address space: 16 draws at a time, 122 MiB, stopped there).
CV_DRAWS_BLOCK_BYTES = 32 << 20
#: Rows of the null draws generated at a time when only some of their columns are kept (:func:`_null_draws`).
NULL_DRAW_ROWS = 4096


def _null_draws(seed: int, n: int, B: int, j0: int, j1: int) -> np.ndarray:
    """Columns ``j0:j1`` of ``default_rng(seed).standard_normal((n, B))``, the same numbers, without the rest.

    The generator fills its array in C order, one value after the other from one stream, so blocks of rows
    drawn in sequence are the same stream: a block of columns is taken from each block of rows as it is drawn
    (the whole stream is drawn again for each block of columns; all at once when ``j0:j1`` is every column).
    """
    if not (n >= 0 and 0 <= j0 < j1 <= B):
        raise ValueError(f"_null_draws: columns {j0}:{j1} of {B} over {n} rows is no block of draws")
    rng = np.random.default_rng(seed)
    if j0 == 0 and j1 == B:
        return rng.standard_normal((n, B))
    out = np.empty((n, j1 - j0))
    for r0 in range(0, n, NULL_DRAW_ROWS):
        r1 = min(n, r0 + NULL_DRAW_ROWS)
        out[r0:r1] = rng.standard_normal((r1 - r0, B))[:, j0:j1]
    return out


def _constant_within(key: np.ndarray, E: np.ndarray) -> bool:
    """True when every column of E is constant within each replicate group."""
    if E.shape[1] == 0:
        return True
    ok = key >= 0
    if not ok.any():
        return True
    # every group's range per column at once: rows sorted by group, max and min over each run
    idx = np.flatnonzero(ok)
    idx = idx[np.argsort(key[idx], kind="stable")]
    Es = E[idx]
    start = np.flatnonzero(np.r_[True, key[idx][1:] != key[idx][:-1]])
    ptp = np.maximum.reduceat(Es, start, axis=0) - np.minimum.reduceat(Es, start, axis=0)
    return not np.any(ptp > 1e-9 * np.maximum(np.abs(E).max(axis=0), 1e-300))


#: Set (``[True]``) while :func:`_finer_map_check` searches the finer map: :data:`STRUCTURE_SELECTION_DEBIAS` and
#: :data:`LOF_MATERIAL_TEST` are not applied there. The check turns a reading into ``none`` where the finer map reads
#: nothing; judged with the two rules that search reads nothing more often, and a real effect the coarse map reads
#: is lost to it (gen_a knock 1085, 2.0 sigma, out of the catalogue: `unexplained` on BIC's grid by the feature,
#: 0.43 um, material either way; on the finest map the set-up term's 0.30 um, 0.25 once debiased as the largest of
#: 21, under the materiality 0.29: `none` there, taken). The conversion to ``none`` is judged as before the rules.
#: Session 29.
_PLAIN_STRUCTURE = [False]


#: Whether the lack of fit makes structure (:func:`_structure`) only where it is material beyond chance: the F of
#: the lack-of-fit mean square over the pure error's, divided by ``1 + material_sigma^2``, below ``alpha_family`` on
#: F(lack-of-fit dof, pure-error dof) (the test of H0: the lack-of-fit variance component is at most
#: ``material_sigma^2`` times the pure error's, its boundary), besides the plain F test and the point estimate's
#: materiality. The point estimate ``sigma_lof^2 = ms_lof - ms_pe`` carries the pure error's own sampling (40 degrees
#: of freedom on gen_c): repeats drawn low (0.6-0.8 of the true noise) inflate it several times over, and the plain
#: test then finds the coarse map's misfit, 0.24 of the noise, material (gen_c none 263, 274, 571 read `unexplained`
#: on the lack of fit alone; 274 and 571 read none with it, 263 at F = 2.79 on (258, 40) still fires). Session 29
#: (docs/discovery-studies.md, "Session 29: gen_c's false alarms near the materiality").
LOF_MATERIAL_TEST = True


#: Whether a covariate makes structure (:func:`_structure`: an ``unexplained`` reading, the unnamed smooth's search)
#: only where its explained RMS stays material once debiased for its choice as the largest of the covariates
#: tested (:func:`_selection_material`), not only for its own columns' noise. The diagnosis debiases the in-sample
#: sum of squares of each covariate's term by its mean under noise (``k s^2``), but the covariate reported is the one
#: that explains most of ~19: under noise its sum of squares is the largest of ~19 draws, whose mean is well above
#: ``k s^2``. Near the materiality (0.3 sigma) that selection decides: gen_c's smooth machine between the 80 mm
#: map's nodes (0.047 um, 0.24 of the noise, noise-free) read 0.066 um at 0.193 (none 5405, blind, `unexplained`
#: confident; 0.053 debiased as the largest of 19). Measured on gen_c none 200-599 (the false alarms 10 -> 8 with
#: :data:`LOF_MATERIAL_TEST`), every effect 200-239 (no cause or confidence changed; 17 second `unexplained` findings
#: at 1.0-1.3 times the materiality dropped), gen_a, gen_b and the simulator (no cause changed but below visibility).
#: Session 29 (docs/discovery-studies.md, "Session 29: gen_c's false alarms near the materiality").
STRUCTURE_SELECTION_DEBIAS = True


def _selection_material(d, m: int, n: int, sigma: float, settings) -> bool:
    """Whether diagnosis ``d`` (one of ``m`` covariates tested on ``n`` rows) explains a material RMS once its
    in-sample sum of squares is debiased by the mean of the largest of ``m`` independent chi-square draws on its
    ``k`` dimensions (:func:`_chi2_max_mean`, times the term's residual variance ``s^2``) rather than by one draw's
    mean ``k s^2`` (:data:`STRUCTURE_SELECTION_DEBIAS`). Tests dependent between covariates (time and touch order)
    make ``m`` fewer in effect: the debias errs large, towards fewer readings near the materiality. Without its
    test's figures (``d.test`` None) it is ``d.material``."""
    t = d.test
    if t is None or not t.k or not t.F > 0 or n <= 0:
        return bool(d.material)
    s2 = t.ss / (t.k * t.F)
    q = _chi2_max_mean(max(int(m), 1), int(t.k))
    return bool(np.sqrt(max(t.ss - q * s2, 0.0) / n) >= settings.material_sigma * sigma)


@functools.lru_cache(maxsize=None)
def _chi2_max_mean(m: int, k: int) -> float:
    """The mean of the largest of ``m`` independent chi-square draws on ``k`` degrees of freedom,
    ``integral over x > 0 of 1 - F_k(x)^m`` (``k`` for ``m = 1``). ``F_k`` is ``special.chdtr(k, x)``: what
    ``stats.chi2.cdf(x, k)`` computes for ``x > 0`` (the only points quad asks for here), bit for bit, without its
    argument handling (0.5 ms a call, ~500 calls an integral: 5 % of the discover tests' CPU; session 38, fast38)."""
    if m <= 1:
        return float(k)
    return float(integrate.quad(lambda x: 1.0 - special.chdtr(k, x) ** m, 0.0, np.inf, limit=200)[0])


def _structure(diag, gap: CvGap, lof, st: _State, sigma: float, settings, kind: str = "", floor: float = 0.0) -> dict:
    """Is there structure the model misses (catalogue-free)?

    Besides the diagnosis, the held-out gap and the lack of fit: a planar
    campaign's noise above :attr:`Settings.noise_max_um` is no probe's
    noise (``noise_excess``, with the figure in ``noise_um``). ``floor``:
    the data's rounding (:func:`roundoff_floor_m`), below which the fit's
    residual scatter is not taken when the held-out gap is judged material.
    """
    a = settings.alpha_family
    m2 = (settings.material_sigma * sigma) ** 2
    plain = _PLAIN_STRUCTURE[0]  # (the finer-map check's search: the rules below off)
    sig_cov = [d.covariate for d in diag if d.significant(a)
               and (not STRUCTURE_SELECTION_DEBIAS or plain
                    or _selection_material(d, len(diag), len(st.r), sigma, settings))]
    # the held-out residuals amplify what the model misses (a held-out set-up
    # is predicted, not fitted): material when they imply a noise 30 % above the fit's
    gap_sig = (bool(gap.draws) and gap.p_value < a
               and gap.sigma_cv_m >= (1 + settings.material_sigma) * max(st.sigma, floor))
    lof_sig = lof is not None and lof.p_value < a and lof.sigma_lof_m ** 2 >= m2
    if lof_sig and LOF_MATERIAL_TEST and not plain and lof.dof_pe:
        # material beyond chance: H0 the lack-of-fit variance at most material_sigma^2 times the pure error's
        lof_sig = float(stats.f.sf(lof.F / (1.0 + settings.material_sigma ** 2), lof.dof, lof.dof_pe)) < a
    excess = kind == "planar" and sigma > settings.noise_max_um * UM
    out = {"present": bool(sig_cov or gap_sig or lof_sig or excess), "covariates": sig_cov, "cv_gap": bool(gap_sig),
           "lack_of_fit": bool(lof_sig), "noise_excess": bool(excess), "noise_um": sigma / UM}
    if STRUCTURE_NOT_COUNTED_SAID:
        out["not_counted"] = [_why_not_counted(d, len(diag), len(st.r), sigma, settings)
                              for d in diag if d.p_value < NOT_COUNTED_P and d.covariate not in sig_cov]
    return out


#: A structure whose only evidence is the lack of fit against the repeats (no covariate significant and material, no
#: held-out gap, no noise excess, no dropped cause still significant: :func:`_lack_of_fit_alone`) rests on one ratio
#: of two variance estimates, and a repeats' floor drawn low by chance reads exactly as a lack of fit does: within a
#: campaign nothing else tells the two apart (the fit's scatter and the held-out scatter carry the lack of fit
#: themselves; the floor's lower-tail odds against them are a function of the same F). What the guard does with
#: such a structure where the floor's odds (:data:`LOF_ALONE_FLOOR_P`) do not exclude a low draw: None, nothing
#: (the reading before session 33); ``"hedged"``: the ``unexplained`` finding stays, flagged ``ambiguous`` with the
#: figures; ``"none"``: no structure (the report's ``structure.extended.lack_of_fit_alone`` says why). gen_b none
#: 9704 (spent blind, session 32's diag32): repeats 0.152 um on 24 dof against the fit's 0.275 um on 116 (true
#: 0.280), lack of fit F = 3.89, p = 1.9e-4, odds of a floor that low 4.1e-4 against the fit's scatter; the baseline
#: of gen_a part_change 1029 (tuning, a real change its catalogue names) stands on the lack of fit alone at odds 4.3e-4.
#: An unnamed smooth adopted beside it (its own held-out gain) is evidence of its own: then nothing is softened (gen_a
#: reseat_hysteresis 1036). Measured on 2,740 tuning campaigns (gen_a, gen_b 1000-1039, gen_c 0-39, the simulator
#: 4000-4019 every effect; 420 more effect-free): ``"hedged"`` (on) changes one confidence (gen_c none 59, a false
#: alarm both ways); ``"none"`` reads gen_c none 59 ``none`` and drops gen_b outlier 1015's second finding (F = 40.9),
#: no cause moving, but loses a structure no diagnosis sees (tests/core/test_discover_floor33.py), so it is off.
#: ``"hedged"`` does not remove a false alarm from issue 13's count (any cause but ``none``). Session 33 (fa33;
#: docs/discovery-studies.md, "Session 33: a lack of fit on a floor drawn low").
LOF_ALONE_FLOOR_GUARD = "hedged"
#: The floor's lower-tail odds (:func:`_lack_of_fit_alone`'s ``p_floor``) at or above which a lack of fit alone is
#: softened by :data:`LOF_ALONE_FLOOR_GUARD`: 0 softens every lack of fit alone; ``Settings.alpha_family`` would
#: judge the low-floor reading at the level the lack of fit is judged at.
LOF_ALONE_FLOOR_P = 0.0


def _lack_of_fit_alone(structure: dict, lof, st: _State, gap: CvGap | None) -> dict | None:
    """The figures of a structure present on the lack of fit alone (:data:`LOF_ALONE_FLOOR_GUARD`), else None.

    ``p_floor``: the chance that repeats scattering with the fit's own
    residual variance (``st.rss / st.dof``: under no structure the pooled
    estimate of the noise on the most degrees of freedom) give a pure-error
    mean square as small as the observed one, ``chi2(dof_pe).cdf(dof_pe
    ms_pe / s^2)``; ``p_floor_held_out`` the same against the noise the
    held-out residuals imply (``gap.sigma_cv_m``), where the gap was drawn.
    Both are monotone in the lack-of-fit F given the degrees of freedom:
    they say how the evidence reads as a floor drawn low, not a second
    test. ``ms_pe = rss / (dof_pe + dof_lof F)`` (the F's own identity).
    """
    if not (structure.get("present") and structure.get("lack_of_fit")) or lof is None or not lof.dof_pe:
        return None
    if (structure.get("covariates") or structure.get("cv_gap") or structure.get("noise_excess")
            or structure.get("dropped_still_significant")):
        return None
    ms_pe = float(st.rss) / (lof.dof_pe + lof.dof * lof.F)
    s2 = float(st.rss) / st.dof
    out = {"lack_of_fit_F": float(lof.F), "p_value": float(lof.p_value), "dof_lof": int(lof.dof),
           "dof_pe": int(lof.dof_pe), "repeats_sigma_um": float(np.sqrt(ms_pe)) / UM,
           "residual_sigma_um": float(np.sqrt(s2)) / UM, "residual_dof": int(st.dof),
           "p_floor": float(stats.chi2.cdf(lof.dof_pe * ms_pe / s2, lof.dof_pe))}
    if gap is not None and gap.draws:
        out["held_out_sigma_um"] = float(gap.sigma_cv_m) / UM
        out["p_gap"] = float(gap.p_value)
        out["p_floor_held_out"] = float(stats.chi2.cdf(lof.dof_pe * ms_pe / gap.sigma_cv_m ** 2, lof.dof_pe))
    out["softened"] = bool(LOF_ALONE_FLOOR_GUARD in ("hedged", "none") and out["p_floor"] >= LOF_ALONE_FLOOR_P)
    gap_words = (f"the held-out gap is within the noise ({fmt_p(gap.p_value)})" if gap is not None and gap.draws
                 else "no held-out gap was drawn")
    out["text"] = (f"the only evidence is the lack of fit against the repeats (F = {lof.F:.3g} on {lof.dof} and "
                   f"{lof.dof_pe} dof, {fmt_p(lof.p_value)}): no covariate carries it and {gap_words}; repeats "
                   f"whose plain scatter is {np.sqrt(ms_pe) / UM:.3g} um ({lof.dof_pe} dof) against the fit's residual "
                   f"sigma {np.sqrt(s2) / UM:.3g} um ({st.dof} dof) read the same when the floor is drawn low by chance "
                   f"(the chance of repeats this still at the fit's scatter: {fmt_p(out['p_floor'])})")
    return out


def _floor_guarded(structure: dict, lof, st: _State, gap: CvGap | None, drop: bool = False) -> dict:
    """``structure`` with its lack-of-fit-alone figures (``lack_of_fit_alone``, :func:`_lack_of_fit_alone`); with
    ``drop``, where :data:`LOF_ALONE_FLOOR_GUARD` ``"none"`` softens it, no structure (``present`` False;
    ``lack_of_fit`` stays the test's answer). Unchanged where the lack of fit is not alone. The extended model's
    structure is dropped after the unnamed smooth's search instead (an adopted smooth is evidence of its own), and
    ``"hedged"`` acts on the finding (:func:`_floor_hedge`)."""
    alone = _lack_of_fit_alone(structure, lof, st, gap)
    if alone is None:
        return structure
    out = {**structure, "lack_of_fit_alone": _clean(alone)}
    if drop and alone["softened"] and LOF_ALONE_FLOOR_GUARD == "none":
        out["present"] = False
    return out


def _floor_hedge(ev: dict, structure: dict) -> None:
    """An ``unexplained`` finding's evidence ``ev`` flagged ``ambiguous`` where :func:`_floor_guarded` hedged its
    ``structure`` (:data:`LOF_ALONE_FLOOR_GUARD` ``"hedged"``), in place."""
    alone = structure.get("lack_of_fit_alone")
    if alone is None:
        return
    ev["lack_of_fit_alone"] = alone
    if alone.get("softened") and LOF_ALONE_FLOOR_GUARD == "hedged":
        ev["confidence"] = "ambiguous"
        ev["confidence_reason"] = alone["text"]


#: Whether :func:`_structure` says, for each diagnosis with p below :data:`NOT_COUNTED_P` (the CLI's and the
#: report page's cut for printing a diagnosis line) that it does not count as structure, why (``not_counted``):
#: p not below ``alpha_family``, or an explained RMS below the materiality (its own columns' noise debiased, then
#: its choice among the covariates). Without it the CLI printed "x position periodically (period 12.4 mm) p =
#: 0.0012" above "none: ... within the probing noise" and the page "the residuals show no structure" under the
#: panel (review30c's screw_saw-312: 0.158 um < 0.3 x 0.546 um). Words only: no reading moves. Session 30.
STRUCTURE_NOT_COUNTED_SAID = True
#: The p-value below which the CLI and the report page print a diagnosis line (scenarios/cli/discover.py).
NOT_COUNTED_P = 0.01


#: The words of the planar baseline's convention line on the touches it leaves out (top faces, normals out of the
#: XY plane), which the CLI summary finds and says (scenarios/cli/discover.py; review30c: 36 of 456 rows left out,
#: said only in the JSON's conventions, a spindle Z growth undetectable by design). Session 30.
LEFT_OUT_NOTE = "with normals out of the XY plane left out of the planar baseline"


def not_counted_words(rep: dict) -> dict:
    """covariate -> why its diagnosis (p < :data:`NOT_COUNTED_P`, printed by the CLI and the report page) is not
    counted as the baseline's structure (the report's ``structure.baseline.not_counted``); empty without them."""
    st = (rep.get("structure") or {}).get("baseline") or {}
    return {w["covariate"]: w["text"] for w in st.get("not_counted") or ()}


def _why_not_counted(d, m: int, n: int, sigma: float, settings) -> dict:
    """Why diagnosis ``d`` (one of ``m`` covariates on ``n`` rows) is no structure (:func:`_structure`): a dict with
    the covariate, its p-value, the reason (``not_significant``: p >= alpha_family; ``below_materiality``: its
    explained RMS below ``material_sigma`` times the noise, as debiased for its own columns (``explained_rms_um``)
    or for its choice as the largest of ``m`` (``debiased_rms_um``)) and the figures, and the words."""
    a = settings.alpha_family
    thr = settings.material_sigma * sigma / UM
    base = {"covariate": d.covariate, "p_value": float(d.p_value), "explained_rms_um": float(d.explained_rms_um),
            "materiality_um": float(thr), "alpha_family": float(a)}
    if not d.p_value < a:
        return {**base, "reason": "not_significant",
                "text": (f"p not below {a:.3g}, the 0.01 false-alarm rate split over the {len(FAMILIES)} families of "
                         "tests: not counted as structure")}
    rms = float(d.explained_rms_um)
    t = d.test
    if d.material and STRUCTURE_SELECTION_DEBIAS and t is not None and t.k and t.F > 0 and n > 0:
        s2 = t.ss / (t.k * t.F)
        rms = float(np.sqrt(max(t.ss - _chi2_max_mean(max(int(m), 1), int(t.k)) * s2, 0.0) / n) / UM)
        how = f", debiased for its choice as the largest of {m} covariates"
    else:
        how = ""
    return {**base, "reason": "below_materiality", "debiased_rms_um": rms,
            "text": (f"significant but below materiality ({rms:.3g} um{how} < {settings.material_sigma:g} x "
                     f"{sigma / UM:.3g} um noise = {thr:.3g} um): not counted as structure")}


def _dropped_still_significant(dropped, st: _State, rows, y, folds: Folds, terms, sigma: float, settings) -> list:
    """The terms the rival check dropped whose columns still explain structure beyond the final model ``st``.

    Each was adopted: significant after its Bonferroni correction and a
    material held-out gain; dropped because a plainer rival explains as
    much (a one-off slip of the part, a smooth in another covariate), which
    says what the structure is not sure to be, not that it is noise. Its
    columns are judged again beyond the model the report keeps ``terms``
    (on ``rows``) by the two bounds of its adoption: the nested F test, p
    times the term's own tries below ``alpha_family``, and a held-out mean
    square lowered by at least ``(material_sigma sigma)^2``. Where both
    hold the structure is present, whatever the catalogue-free tests say
    (their noise can be the structure itself: gen_b part_change 1508 and
    1701 read `none` at p = 1.6e-5 and 8e-16 after part_change's
    Bonferroni, dropped for a slip). The held-out gain is no independent
    check of the selection: the term's columns were chosen on all the data
    (the folds refit its coefficients, not its choice), so the two bounds
    are those of its adoption, not a fresh test (effect-free gen_a/gen_b
    1250-1499: 2 of 500 campaigns made `unexplained` by it, docs/discovery.md).
    ``dropped_because``: the rival check's reason (:func:`_demotion_reason`).
    """
    out = []
    if not dropped:
        return out
    E = _stack(terms, rows)
    cv0 = folds.mse(y[rows], E, _penalty(terms)) if terms else folds.mse(y[rows])
    for tm in dropped:
        ss, k, _, p = nested_f_batch(tm.columns[None, rows], st.Q, st.r, st.rss, st.dof)
        if not (k[0] > 0 and p[0] * tm.tries < settings.alpha_family):
            continue
        gain = cv0 - folds.mse(y[rows], np.hstack([E, tm.columns[rows]]), _penalty(terms + [tm]))
        if gain >= (settings.material_sigma * sigma) ** 2:
            out.append({"cause": tm.cause, "dropped_because": _demotion_reason(tm.evidence, tm.covariate, settings),
                        "p_adjusted": float(min(1.0, p[0] * tm.tries)),
                        "explained_ss_um2": float(ss[0]) / UM ** 2, "cv_gain_um2": gain / UM ** 2})
    return out


def _no_covariate_words(structure: dict, settings) -> str:
    """What an ``unexplained`` finding says when no covariate carries the structure."""
    why = [k for k in ("cv_gap", "lack_of_fit") if structure[k]]
    why += [f"the form of {d['cause']}, dropped ({d['dropped_because']}), still explains "
            f"{d['explained_ss_um2']:.3g} um^2, {fmt_p(d['p_adjusted'])} after Bonferroni, held-out gain "
            f"{d['cv_gain_um2']:.2g} um^2" for d in structure.get("dropped_still_significant", ())]
    if structure.get("noise_excess"):
        why.append(f"a scatter of {structure['noise_um']:.2g} um, above any touch-trigger probe's noise "
                   f"({settings.noise_max_um:g} um)")
    return "no single covariate carries it: " + ", ".join(why)


#: Response modes whose rate of change within a set-up the noise estimate removes from the repeats (planar: the
#: scalar mode and the two translations, a part or probe moving during the set-up; the first mode elsewhere).
DRIFT_MODES = 3


def drift_trend(bl: Baseline, rows: np.ndarray, shared: bool = False,
                sparse: bool = False) -> np.ndarray | sps.csr_matrix:
    """(len(rows), q) columns of a drift linear in time within each group (set-up): time x mode (x group).

    What :func:`core.diagnosis.replicate_scatter` removes from the repeats
    before their scatter is the noise: a drift-check target touched minutes
    apart moves with whatever drifts in between. Only time's variation
    within a replicate group counts; the first :data:`DRIFT_MODES` response
    modes of a planar baseline (the scalar mode and the x and y
    translations), the first mode of others; one rate per group, or with
    ``shared`` one rate for all (fewer columns, for logs with few repeats).
    A baseline without a ``time`` covariate gets none (q = 0). With
    ``sparse`` the per-group columns come as a CSR matrix of the same values
    (each row's in its group's columns only: dense they are rows x modes x
    groups, 2.4 GB at the bench's 1e6 rows and 100 set-ups). A positioning
    run's (:data:`POSITIONING_NOISE_BEYOND_TIME_BY_DIRECTION`) gains its
    ``time_by_direction`` columns after the rates (a reversal that changes
    through the test: each target's repeats in one direction lie in
    different cycles and move with it).
    """
    cov = bl.covariate("time")
    if cov is None:
        return np.zeros((len(rows), 0))
    t = np.asarray(cov.values, float)[rows]
    m = bl.modes[rows][:, :DRIFT_MODES if bl.kind == "planar" else 1]
    tbd = _noise_beyond(bl)
    if tbd is not None:  # (a positioning run's reversal that changes through the test: beside the rates, its columns)
        T = np.hstack([_time_rates(t, m, bl.groups[rows], shared, False), np.asarray(tbd.values, float)[rows]])
        return sps.csr_matrix(T) if sparse else T
    return _time_rates(t, m, bl.groups[rows], shared, sparse)


def _noise_beyond(bl: Baseline):
    """The covariate whose columns :func:`drift_trend` takes out of the repeats beside the rates: a positioning
    run's ``time_by_direction`` (:data:`POSITIONING_NOISE_BEYOND_TIME_BY_DIRECTION`), else None."""
    if not (POSITIONING_NOISE_BEYOND_TIME_BY_DIRECTION and bl.kind == "positioning"):
        return None
    return bl.covariate("time_by_direction")


def _time_rates(t: np.ndarray, m: np.ndarray, g: np.ndarray, shared: bool, sparse: bool):
    """:func:`drift_trend`'s rates: time (less its mean per group) x modes ``m``, one rate per group ``g`` or with
    ``shared`` one for all."""
    if shared:
        return (t - t.mean())[:, None] * m
    ug, gi = np.unique(g, return_inverse=True)
    tc = np.empty(len(t))
    for gg in ug:  # each group's times less their mean
        sel = g == gg
        tc[sel] = t[sel] - t[sel].mean()
    q = m.shape[1]
    idx = gi.ravel()[:, None] * q + np.arange(q)
    T = sps.csr_matrix(((tc[:, None] * m).ravel(), idx.ravel(), np.arange(0, q * len(t) + 1, q)),
                       shape=(len(t), q * len(ug)))
    return T if sparse else T.toarray()


#: A positioning run's repeats (one target in one direction, one reading per cycle) are its noise once
#: :func:`drift_trend` has also taken out the baseline's ``time_by_direction`` columns
#: (:data:`core.baseline.POSITIONING_TIME_BY_DIRECTION`): a reversal that grows through the test moves the + and -
#: repeats of every target apart from cycle to cycle, and their plain scatter pooled it as noise (review30c's
#: backlash_grow3 401: 1.134 um printed for a true 0.616 um; beyond these columns 0.675 um). Under no effect the
#: columns are fixed regressors and the estimate stays unbiased (3 degrees of freedom fewer: 67 -> 64).
#: docs/discovery-studies.md, "Session 30: a positioning run's noise beyond a reversal that changes (posn30)".
#: False: the rates per cycle alone, as before.
POSITIONING_NOISE_BEYOND_TIME_BY_DIRECTION = True
#: Short-term pairs needed before their scatter may replace the repeats' (:func:`_short_term`).
SHORT_TERM_MIN_PAIRS = 5
#: Fewest degrees of freedom of the repeats' scatter beyond the model's terms (fewer than 10) that may be the
#: noise, and then only where what the terms take out of the repeats is shown to be structure (discovery's
#: ``noise_of``). A scatter on 5 degrees of freedom gives sigma within about +-30 % (1 s.d., 1 / sqrt(2 dof));
#: below that the F test of the terms' share has little power and a false firing (at SHORT_TERM_ALPHA) would
#: rest on an estimate that can be half the truth. gen_a thermal_drift 1201 has 8.
NOISE_BEYOND_TERMS_MIN_DOF = 5
#: Level of the F test that the repeats' scatter exceeds the short-term pairs' (:func:`_short_term`).
SHORT_TERM_ALPHA = 0.01


def short_term_test(rep, pairs) -> tuple[float, float]:
    """(F, p): whether the repeats' scatter ``rep`` holds more than the short-term ``pairs``' scatter.

    The repeats' contrasts hold the pairs' own, so the remainder (repeats
    less pairs, ``rep.dof - pairs.dof`` degrees of freedom) is tested
    against the pairs: under pure noise two near-independent chi-squares
    (a reviewer's 159 effect-free gen_a campaigns: p-values uniform by
    decile; testing the whole repeats against the pairs fired at 0.26 % for
    a nominal 1 %). (nan, 1.0) when the repeats have no contrast beyond
    the pairs.
    """
    if rep.dof <= pairs.dof or not pairs.dof:
        return float("nan"), 1.0
    F = ((rep.ss - pairs.ss) / (rep.dof - pairs.dof)) / max(pairs.ss / pairs.dof, 1e-300)
    return float(F), float(stats.f.sf(F, rep.dof - pairs.dof, pairs.dof))


def _short_term(bl: Baseline, rows: np.ndarray, y: np.ndarray, rep, key: np.ndarray | None = None) -> dict | None:
    """The short-term repeatability, and whether it replaces the repeats' scatter as the noise.

    Repeats touched one right after the other
    (:func:`core.diagnosis.close_pair_scatter`) see the probing noise
    alone; repeats minutes apart see it plus whatever drifted in between
    that the linear trend of :func:`drift_trend` does not remove (a
    saturating warm-up, a creep). When the repeats' scatter ``rep``
    exceeds the pairs' by an F test at :data:`SHORT_TERM_ALPHA` (``rep.dof``
    against the pairs' degrees of freedom, at least
    :data:`SHORT_TERM_MIN_PAIRS`), the excess is structure, not noise, and
    the pairs' scatter is the noise (on gen_a's thermal drift, seed 1204:
    repeats 2.39 um, pairs 0.35 um, true 0.30 um). The F test compares the
    repeats' remaining contrasts with the pairs' (the repeats' sum of
    squares holds the pairs'). Under pure noise it fires at its level, and
    then picks the smaller estimate (biased low, few degrees of freedom);
    a reviewer's 159 effect-free gen_a campaigns had it fire at most once,
    their mean sigma / true 0.987 with and without it. The pairs' estimate
    has 5-6 degrees of freedom on gen_a (sigma within about +-30 %, 1 s.d.):
    taken only when the repeats' is shown to hold more than noise. The
    pairs are those of the raw repeats (a pair 5 % of a set-up apart moves
    by that share of the set-up's drift). None without a time covariate or
    pairs.
    """
    cov = bl.covariate("time")
    if cov is None:
        return None
    key = bl.replicate if key is None else key  # (the repeat groups that are pure error: every one, else as given)
    cp = close_pair_scatter(key[rows], y[rows], np.asarray(cov.values, float)[rows], bl.groups[rows])
    if not cp.dof or not rep.dof:
        return None
    F, p = short_term_test(rep, cp)
    return {"sigma_m": cp.sigma_m, "dof": cp.dof, "targets": cp.groups, "F": float(F), "p_value": p,
            "used": bool(cp.dof >= SHORT_TERM_MIN_PAIRS and p < SHORT_TERM_ALPHA)}


def _noise_report(rep, rep_plain, trend, st0, gap, lof, used_noise, short=None, straddled: int = 0,
                  beyond=()) -> dict:
    """``used_noise``: (sigma, method, dof) of the noise the final model was judged with; ``straddled``: the repeat
    groups set aside as holding a step (:data:`REPEATS_STRADDLED`), said only where there are some; ``beyond``: the
    covariates whose columns :func:`drift_trend` took out of the repeats beside the rates (said where some)."""
    used = short is not None and short["used"]
    sigma, method, dof = used_noise
    out = {"sigma_um": sigma / UM, "method": method, "dof": int(dof),
           "repeats": {"sigma_um": rep.sigma_m / UM if rep.dof else None, "dof": rep.dof, "groups": rep.groups,
                       "time_trend": trend,
                       "sigma_plain_um": rep_plain.sigma_m / UM if rep_plain.dof else None,
                       "dof_plain": rep_plain.dof},
           "in_sample": {"sigma_um": st0.sigma / UM, "dof": st0.dof},
           "cv_gap": {"sigma_cv_um": gap.sigma_cv_m / UM, "ratio": gap.ratio, "expected_ratio": gap.expected,
                      "p_value": gap.p_value, "draws": gap.draws}}
    if straddled:
        out["repeats"]["straddled_groups"] = int(straddled)
    if beyond and trend != "none":  # (the covariates' columns taken out of the repeats beside the rates)
        out["repeats"]["beyond"] = list(beyond)
    if short is not None:
        out["short_term"] = {"sigma_um": short["sigma_m"] / UM, "dof": short["dof"], "targets": short["targets"],
                             "F_repeats_over_short": short["F"], "p_value": short["p_value"], "used": used}
    if lof is not None:
        out["lack_of_fit"] = {"F": lof.F, "p_value": lof.p_value, "sigma_lof_um": lof.sigma_lof_m / UM, "dof": lof.dof}
    return out


def _coarse(Ecols: np.ndarray, r: np.ndarray, keep: int) -> np.ndarray:
    """Indices of the ``keep`` best trials by a periodogram-like score (columns treated as orthogonal).

    The numerator ``(r . e)^2`` is exact (r is orthogonal to the model);
    the denominator ignores the model's share of ``e``.
    """
    num = (np.swapaxes(Ecols, 1, 2) @ r) ** 2
    den = np.sum(Ecols ** 2, axis=1)
    score = np.sum(num / np.maximum(den, 1e-300), axis=1)
    return np.argsort(-score)[:keep]


#: Trials per block when :func:`_path_tries` projects a scan's columns out of the model (bounds its memory),
#: at most; fewer on a long log, so that one block's columns hold at most :data:`PATH_BLOCK_BYTES`.
PATH_CHUNK = 64
#: Bytes of one block of :func:`_path_tries`' trial columns (rows x trials x 8): at the bench's 1e6-row log
#: 64 trials were 512 MB a copy, and a block is copied about four times (built, taken, projected, normalised).
PATH_BLOCK_BYTES = 32 << 20


def _path_tries(scans, st: _State, level: float) -> float:
    """Effective number of independent trials of path scans (:attr:`core.causes.Scan.path`) at ``level``.

    A scan of one column along a continuous parameter (a bump's centre)
    is a chi-square process with one degree of freedom; Davies (1987,
    Biometrika 74, 33-43) bounds its supremum above ``u``:
    ``P(sup Z^2 > u) <= P(chi2_1 > u) + V exp(-u / 2) / pi``, ``V`` the
    length of the path the unit columns trace beside the model (each
    trial's column projected out of ``st.Q`` and normalised; ``V`` the
    sum of the angles between consecutive trials, the path's length on
    the sphere at the scan's resolution). Summed over the scans, the bound
    equals ``level`` at one single-trial p-value ``p*``; the count is
    ``level / p*``, the Bonferroni factor whose decision at ``level`` is
    the bound's (at a stronger statistic the bound's own factor grows,
    as ``sqrt(u)``: the count is that of the decision, which the engine's
    further tests with this factor share). Beside the model the columns
    lose their per-target mean and decorrelate faster than extent over
    half-width says: on the simulator's effect-free campaign 3301 V = 86
    beside the baseline against 37.5 counted, and 400 draws of pure noise
    there gave a 1 % quantile of the scan's least p-value that this bound
    puts at 0.015 and the count at 0.0039 (gen_a local_scale_defect 801,
    300 draws: 0.0079 and 0.0022). The widths are counted as separate
    paths; the refinement of a width between and beyond them
    (:func:`_refine`, 0.75 to 1.33 times the scanned one) is not counted,
    and it matters: a reviewer's 20,000 draws of pure noise beside the
    effect-free synthetic seed 0's baseline had the scanned grid's least
    p-value times this count below 0.05 3.3 % of the time (0.67 % below
    0.01), but the engine's statistic, with the width refined, 6.25 %
    (1.49 % below 0.01, 0.83 % below 0.0056): about 1.5 times the
    nominal level at the small levels, still anticonservative (the scan's
    own count with refined widths: 17 %, 4.6 %, 2.9 %). Bounding the
    (centre, width) field is not done. A scan of ``k > 1`` columns a trial
    (the periodic scan's four, session 24) is a chi-square process of ``m``
    degrees of freedom along its path, ``m`` the dimension of a trial's span
    beside the model (``k`` unless the model takes some of it): its steps are
    measured and booked per ``m`` (:func:`_subspace_path`), each length
    counted at its own rate (:func:`_chi2_upcrossing_rate`), the start term
    one single-trial p-value per scan. Cost: every trial's column projected once, in blocks of
    :data:`PATH_CHUNK` trials (fewer on a long log, :data:`PATH_BLOCK_BYTES`: the same angles summed
    in other groups); the engine asks for it only where the scan's own count finds the candidate
    significant. Beyond :data:`PATH_ARC_ROWS` rows a scan that builds its columns at any value of its
    parameter (:attr:`core.causes.Scan.path_at`: the periodic scan) has its length estimated instead
    (:func:`_arc_path`: the integral of the path's speed over the range the refinement reaches, from
    :data:`PATH_ARC_SAMPLES` values, plus :data:`PATH_ARC_Z` standard errors; at least the trial-by-trial
    sum but for the estimate's error): 64 trials a scan projected instead of its 4,096 (session 25).
    """
    rows = st.rows
    Vs, ks = [], []
    for sc in scans:
        k = int(sc.build(np.arange(1)).shape[2])
        # (k > 1: blocks as large as PATH_BLOCK_BYTES allows, the whole scan on a short log: one projection, one
        # batch; in blocks of 64 the demo's two periodic paths cost 0.079 s of CPU)
        chunk = max(1, (PATH_BLOCK_BYTES if k > 1 else min(PATH_CHUNK * 8 * len(rows), PATH_BLOCK_BYTES))
                    // max(8 * k * len(rows), 1))
        V, Vm = 0.0, {}  # (k = 1: the length; k > 1: the lengths by the steps' dimension beside the model)
        whole = k > 1 and chunk >= sc.size  # the whole scan one block: its model-free parts kept for the next model
        arc = k > 1 and sc.path_at is not None and sc.path_range is not None and len(rows) > PATH_ARC_ROWS
        if arc:  # a long log: the length from the path's speed at a sample of its parameter's values
            Vm, whole = _arc_path(sc, st, chunk), True
        elif whole:
            parts = _path_parts(sc, rows)
            Vm = _subspace_path_of(parts, st, _path_product(sc, parts, st.Q)) if parts is not None else {}
        for a in () if whole else range(0, sc.size, chunk):  # each block from the previous block's last trial
            C = take_rows(sc.build(np.arange(max(a - 1, 0), min(a + chunk, sc.size))), rows, 1)
            if k == 1:
                M = C[:, :, 0].T
                M = M - st.Q @ (st.Q.T @ M)
                nrm = np.linalg.norm(M, axis=0)
                M = M[:, nrm > 0] / nrm[nrm > 0]
                cos = np.abs(np.sum(M[:, 1:] * M[:, :-1], axis=0))
                V += float(np.sum(np.arccos(np.clip(cos, 0.0, 1.0))))
            else:
                for m, v in _subspace_path(C, st).items():
                    Vm[m] = Vm.get(m, 0.0) + v
        if k == 1:
            Vs.append(V)
            ks.append(k)
        for m in sorted(Vm):
            Vs.append(Vm[m])
            ks.append(m)
    ns = len(scans)  # each scan's first trial: P(chi2 > u) = p

    def excess(log_p):  # log of the bound over level at the single-trial p-value exp(log_p)
        p = np.exp(log_p)
        if all(k == 1 for k in ks):
            return np.log(ns * p + sum(Vs) * np.exp(-float(stats.chi2.isf(p, 1)) / 2) / np.pi) - np.log(level)
        return np.log(ns * p + sum(V * _chi2_upcrossing_rate(float(stats.chi2.isf(p, k)), k)
                                         for V, k in zip(Vs, ks))) - np.log(level)

    lo = np.log(level / max(ns, 1))  # the bound at least ns p: above level here...
    hi = lo
    while excess(hi) > 0 and hi > -700:  # ...and below it far enough out
        hi -= 5.0
    if excess(hi) > 0:  # the bound above level even at p = exp(-700): a count as large as that says
        return float(level / np.exp(hi))
    if excess(lo) <= 0:  # no length: one trial per scan
        return float(ns)
    return float(level / np.exp(optimize.brentq(excess, hi, lo, xtol=1e-6)))


#: Whether :func:`_judge_trial` puts off the path count (:func:`_path_tries`) of a candidate that a bound on that
#: count already shows significant (:func:`_path_count_below`: every step between consecutive trials at its
#: largest, pi / 2) until a test after the significance test reads the count (the counter-explanation's, the
#: smoothness verdict's, the penalised cause's, the term's own): a candidate refused before that (by the structure's
#: family, by :attr:`core.causes.Cause.check`) has its path never measured. Every count made is the number it was,
#: and every decision: exact (session 26: the demo's first round refuses the periodic scan at p = 4.5e-16 by its
#: family, after a count of about 22 ms whose 1,073 tries decided nothing). False: counted before the significance
#: test, as before.
PATH_COUNT_DEFERRED = True
#: The factor by which the adjusted p-value at :func:`_path_count_below`'s bound must be below ``alpha_family`` for
#: the count to be put off (:data:`PATH_COUNT_DEFERRED`): :func:`_path_tries` finds its count to a relative 1e-6
#: (``brentq``'s tolerance on the log of the single-trial p-value); 2 leaves room for that and for rounding.
PATH_BOUND_MARGIN = 2.0


def _path_count_below(scans, rows: int, level: float, count: float) -> bool:
    """Whether :func:`_path_tries`' count of ``scans`` at ``level`` is surely below ``count``, from the scans'
    sizes alone (no model, no columns).

    The count is ``level / p*``, ``p*`` where Davies' bound summed over the
    scans, ``B(p) = ns p + sum_m V_m rate_m(u_m(p))`` (``u_m`` the
    chi-square quantile of ``m`` degrees of freedom above which ``p`` lies),
    equals ``level``. ``B`` rises with ``p`` at these levels (the upcrossing
    rate falls as ``u`` grows beyond ``m - 1``, and ``p`` is below
    ``level``, at most ``alpha_family``: ``u_4`` beyond 16), so the count is
    below ``count`` where ``B(level / count) < level``. ``B`` is bounded
    above from the sizes: each step between consecutive trials is at most
    pi / 2 (an angle between unit columns, or the root mean square of
    principal angles, each at most pi / 2), so a scan of ``T`` trials is at
    most ``(T - 1) pi / 2`` long whatever the dimensions ``m <= k`` its steps
    are booked to, and its part of ``B`` at most that length times the
    largest of the rates ``m = 1 .. k`` (``k`` read from a trial's columns
    as :func:`_path_tries` reads it). False beyond :data:`PATH_ARC_ROWS` rows
    (the arc estimate there is no chord sum: it may be longer), for a count
    not above the scans' number (the count is at least that: ``B(p) >= ns
    p``) and at a level of 0.25 a scan or more (where the rate need not
    fall: the engine asks at most ``alpha_family``).
    """
    ns = len(scans)
    if rows > PATH_ARC_ROWS or not count > ns or not level / max(ns, 1) < 0.25:
        return False
    q = level / count
    if q <= 0.0:  # (a count beyond any bound: a p-value of zero)
        return True
    bound = ns * q
    for sc in scans:
        V = max(int(sc.size) - 1, 0) * np.pi / 2
        if V > 0:
            k = int(sc.build(np.arange(1)).shape[2])
            bound += V * max(_chi2_upcrossing_rate(float(special.chdtri(m, q)), m) for m in range(1, k + 1))
    return bool(np.isfinite(bound) and bound < level)


#: Rows beyond which a path scan that can build its columns at any value of its parameter (:attr:`Scan.path_at`:
#: the periodic scan) has its path's length estimated by :func:`_arc_path` instead of summed trial by trial: every
#: stored campaign is far below (hundreds to a few thousand rows); the bench's 1e5- and 1e6-row logs above, where the
#: trial-by-trial sum projects every trial out of the model (about 30 min of CPU at 1e6 rows; docs/discovery.md,
#: "Session 25: the periodic path count on long logs").
PATH_ARC_ROWS = 50_000
#: Strata of :func:`_arc_path`'s estimate (one value of the parameter drawn in each, evenly sized; even, paired for
#: the variance).
PATH_ARC_SAMPLES = 32
#: Standard errors :func:`_arc_path` adds to its estimate (one-sided): the length counted is the estimate's upper
#: bound at about 99.9 % (normal), so that the count is the trial-by-trial one's or more.
PATH_ARC_Z = 3.0
#: :func:`_arc_path`'s difference step, as a share of the scan's own step: the chord over it is the speed times
#: the step to about ``(speed step)^2 / 24`` relative (a share 1e-3 of a fine step: a chord of about 6e-4 rad).
PATH_ARC_H = 1e-3
#: Seed of :func:`_arc_path`'s draws (fixed: a report is reproducible).
PATH_ARC_SEED = 20251205


def _arc_path(sc, st: _State, chunk: int) -> dict:
    """Length of a path scan's path beside the model ``st.Q`` estimated from its speed at a sample of values.

    The path :func:`_path_tries` sums trial by trial is the chord sum of a
    continuous path: the span of the columns :attr:`Scan.path_at` builds at
    each value ``f`` of the parameter, beside the model. Its length over
    the range the engine can reach (:attr:`Scan.path_range`: the scan's,
    widened by the refinement's one step either side) is the integral of
    its speed, ``|d gamma / d f|``, which is at least every chord sum over
    the same range (a chord is never longer than its arc), so the count it
    gives is the trial-by-trial one's or more and bounds the continuous
    scan the refinement searches. The range is cut into
    :data:`PATH_ARC_SAMPLES` equal strata and one value drawn in each
    (:data:`PATH_ARC_SEED`); the speed there is the step between the spans
    at ``f -+ h / 2`` over ``h`` (:func:`_subspace_steps`, ``h`` a share
    :data:`PATH_ARC_H` of the scan's step); the strata's speeds times
    their width sum to an unbiased estimate, whose variance is estimated
    from the strata in adjacent pairs (the collapsed-strata estimator,
    biased up), and the length counted is the estimate plus
    :data:`PATH_ARC_Z` standard errors, booked per dimension ``m`` of the
    spans as the samples are. Cost: ``2 PATH_ARC_SAMPLES`` trials
    projected out of the model, whatever the scan's size, ``chunk`` pairs'
    worth of trials at a time (at least one pair).
    """
    a, b = sc.path_range
    S = PATH_ARC_SAMPLES
    w = (b - a) / S
    f = a + w * (np.arange(S) + np.random.default_rng(PATH_ARC_SEED).random(S))
    speed, dims = _arc_speeds(sc, st, f, PATH_ARC_H * (b - a) / max(sc.size, 1), chunk)
    est = w * speed
    V = float(np.sum(est))
    se = float(np.sqrt(np.sum((est[0::2] - est[1::2]) ** 2))) if S > 1 else V
    grow = 1.0 + PATH_ARC_Z * se / V if V > 0 else 1.0
    return {int(d): float(np.sum(est[dims == d])) * grow for d in np.unique(dims) if d > 0}


def _arc_speeds(sc, st: _State, f: np.ndarray, h: float, chunk: int) -> tuple:
    """(speed, m): the speed of a path scan's path beside the model at the values ``f`` of its parameter, the step
    between the spans at ``f -+ h / 2`` over ``h`` (:func:`_subspace_steps`), and the dimension of those spans;
    ``chunk`` trials' worth built at a time (at least one pair)."""
    S = len(f)
    vals = np.column_stack([f - h / 2, f + h / 2]).ravel()
    per = max(1, chunk // 2)  # pairs a block
    speed, dims = np.empty(S), np.empty(S, int)
    for j in range(0, S, per):
        C = take_rows(sc.path_at(vals[2 * j:2 * min(j + per, S)]), st.rows, 1)
        parts = _subspace_parts(C)
        step, m = _subspace_steps(parts, st)
        speed[j:j + per], dims[j:j + per] = step[0::2] / h, m[0::2]
        del C, parts
    return speed, dims


def _chi2_upcrossing_rate(u: float, k: int) -> float:
    """Expected upcrossings of ``u`` per unit path length of a chi-square process of ``k`` degrees of freedom.

    ``Y = |U(t)^T z|^2``, ``z`` white noise, ``U(t)`` an orthonormal basis
    of ``k`` columns moving along a path: by Rice's formula, given
    ``w = U^T z`` on the sphere ``|w|^2 = u``, ``Y' = 2 w^T U'^T z`` is
    normal with variance ``4 w^T G w`` (``G = U'^T U'``, ``U'`` the basis'
    motion out of its own span), whose mean over the sphere is at most
    ``4 u tr(G) / k``; with the path's length measured by
    ``sqrt(tr(G) / k)`` (:func:`_subspace_path`) the rate is at most
    ``u^((k-1)/2) e^(-u/2) 2^((1-k)/2) / (sqrt(pi) Gamma(k/2))``: Davies
    (1987)'s bound for ``k`` columns; ``e^(-u/2) / pi`` at ``k = 1``.
    """
    return float(np.exp((k - 1) / 2 * np.log(u) - u / 2 + (1 - k) / 2 * np.log(2.0) - 0.5 * np.log(np.pi)
                        - special.gammaln(k / 2)))


def _subspace_path(C: np.ndarray, st: _State) -> dict:
    """Lengths of the path that consecutive trials' column spaces (``C``: trials x rows x k) trace beside the model.

    Each trial's ``k`` columns projected out of ``st.Q``; a step between
    two trials whose spans beside the model have ``m`` dimensions (the
    lesser of the two; ``m = k`` unless a trial loses columns to the
    model) counts ``sqrt(sum(theta_j^2) / m)`` over their ``m`` principal
    angles ``theta_j`` (the root mean square speed of the ``m``
    components: at ``m = 1`` the angle between the two unit columns,
    :func:`_path_tries`' step), and is booked to a chi-square process of
    ``m`` degrees of freedom: the result maps ``m`` to its length (a
    reviewer found trials of rank 2 and 3 on gen_a periodic designs, whose
    steps divided by 4 and counted at 4 degrees of freedom made the count
    0.73-0.88 times the rank's own). A trial not finite has no span and
    no step (its Gram's eigen-decomposition would fail). The angles from the trials' Gram matrices
    beside the model (``C^T C - B^T B``, ``B = Q^T C``), each trial made
    orthonormal by its Gram's eigenvectors (directions below ``1e-10`` of
    its largest eigenvalue left out), in one batch: a step is small, so
    squaring the conditioning costs nothing the bound needs (to about
    1e-8 rad; the per-trial SVDs of the columns were 0.17 s of the demo's
    0.39 s).
    """
    parts = _subspace_parts(C)
    return {} if parts is None else _subspace_path_of(parts, st)


def _subspace_parts(C: np.ndarray):
    """The model-free parts of :func:`_subspace_path` of trials ``C`` (trials x rows x k): ``(Ct, G0, X0)``.

    ``Ct`` the trials' columns side by side (rows x trials * k, C-contiguous,
    for ``Q^T C``), ``G0 = C^T C`` per trial and ``X0`` the consecutive
    trials' cross products; None below two trials. The same operations on
    the same arrays as before they were kept apart: the path from them is
    the same bit for bit.
    """
    T, n, k = C.shape
    if T < 2:
        return None
    Ct = np.ascontiguousarray(np.transpose(C, (1, 0, 2))).reshape(n, T * k)
    Ch = np.swapaxes(C, 1, 2)  # (T, k, n)
    return Ct, Ch @ C, Ch[:-1] @ C[1:]


def _subspace_parts_rows(R: np.ndarray):
    """:func:`_subspace_parts` of the trials ``np.transpose(R, (1, 0, 2))``, ``R`` rows first (rows x trials x k,
    C-contiguous: :attr:`core.causes.Scan.build_rows`): ``Ct`` is ``R`` itself, reshaped; ``C^T C`` and the cross
    products the same matrix products of the same numbers (each trial's ``n x k`` block read with the rows'
    stride instead of ``k``: BLAS packs its operands, the sums are the same, tested byte for byte)."""
    n, T, k = R.shape
    if T < 2:
        return None
    C = np.transpose(R, (1, 0, 2))  # (T, n, k), a view
    Ch = np.swapaxes(C, 1, 2)
    return R.reshape(n, T * k), Ch @ C, Ch[:-1] @ C[1:]


def _subspace_path_of(parts, st: _State, QtC: np.ndarray | None = None) -> dict:
    """:func:`_subspace_path` from :func:`_subspace_parts` beside the model ``st.Q`` (only ``Q^T C`` is the model's;
    ``QtC``: that product when made already, :func:`_path_product`)."""
    step, m = _subspace_steps(parts, st, QtC)
    return {int(d): float(np.sum(step[m == d])) for d in np.unique(m) if d > 0}


def _subspace_steps(parts, st: _State, QtC: np.ndarray | None = None) -> tuple:
    """(step, m): each consecutive pair of trials' step and the dimension it is booked to (:func:`_subspace_path`;
    ``QtC`` as :func:`_subspace_path_of`)."""
    Ct, G0, X0 = parts
    T, k = G0.shape[0], G0.shape[1]
    QtC = np.asarray(st.Q.T @ Ct) if QtC is None else QtC
    B = QtC.reshape(-1, T, k).transpose(1, 0, 2)  # (T, r, k)
    Bh = np.swapaxes(B, 1, 2)  # (T, k, r)
    G = G0 - Bh @ B
    X = X0 - Bh[:-1] @ B[1:]
    bad = ~np.isfinite(G).all(axis=(1, 2))  # a trial not finite: no span, no step to or from it
    if bad.any():
        G[bad] = 0.0
        X[bad[:-1] | bad[1:]] = 0.0
    lam, V = np.linalg.eigh(G)  # ascending
    top = lam[:, -1:]
    ok = (lam > 1e-10 * top) & (top > 0)
    W = V * np.where(ok, 1.0 / np.sqrt(np.where(ok, lam, 1.0)), 0.0)[:, None, :]
    cos = np.linalg.svd(np.swapaxes(W[:-1], 1, 2) @ X @ W[1:], compute_uv=False)  # (T - 1, k), descending
    m = np.minimum(ok[:-1].sum(1), ok[1:].sum(1))  # the angles the two spans have
    th = np.where(np.arange(k)[None, :] < m[:, None], np.arccos(np.clip(cos, 0.0, 1.0)), 0.0)
    step = np.sqrt(np.sum(th ** 2, axis=1) / np.maximum(m, 1))
    return step, m


#: Bytes of scans' model-free path parts (:func:`_path_parts`: the trials' columns on the rows, ``C^T C`` and the
#: consecutive cross products) kept for the next model's count, all scans together (the oldest dropped first); a
#: scan larger is built afresh each time (a long log's blocks never are kept). The demo's two periodic scans hold
#: 5.9 MiB each (440 trials, 432 rows, 4 columns), and with each its last ``Q^T C`` and a copy of its basis
#: (:data:`_PATH_PRODUCTS`, 2.4 MiB at 145 columns): 16.6 MiB in all, so 24 MiB since session 25 (16 before).
PATH_CACHE_BYTES = 24 << 20
#: id(scan) -> (weak reference to the scan, its rows, parts, their bytes): an entry goes with its scan (and when the
#: rows differ).
_PATH_CACHE: dict = {}


def _path_parts(sc, rows: np.ndarray):
    """:func:`_subspace_parts` of every trial of the scan ``sc`` on ``rows``, kept while the scan lives.

    The engine counts the path of the same scans on the same rows beside
    successive models (the demo's discover twice, 145 then 149 columns):
    the columns, ``C^T C`` and the consecutive cross products do not
    depend on the model and are made once; only ``Q^T C`` is redone. Kept
    only where they hold at most :data:`PATH_CACHE_BYTES` with the other
    scans' kept (the oldest dropped), under the scan's identity and a copy of its rows
    (other rows: built afresh and kept in their place); the entry goes
    when the scan is collected.
    """
    key = id(sc)
    hit = _PATH_CACHE.get(key)
    if hit is not None and hit[0]() is sc and np.array_equal(hit[1], rows):
        return hit[2]
    if sc.build_rows is not None:  # rows first: the trials side by side without a transposed copy (the same doubles)
        parts = _subspace_parts_rows(take_rows(sc.build_rows(np.arange(sc.size)), rows, 0))
    else:
        parts = _subspace_parts(take_rows(sc.build(np.arange(sc.size)), rows, 1))
    _PATH_CACHE.pop(key, None)
    _PATH_PRODUCTS.pop(key, None)
    size = 0 if parts is None else sum(a.nbytes for a in parts)
    if parts is not None and size <= PATH_CACHE_BYTES:
        while True:  # (a snapshot: an entry may go with its scan at any collection)
            held = list(_PATH_CACHE)
            if not held or size + _path_held() <= PATH_CACHE_BYTES:
                break
            _PATH_CACHE.pop(held[0], None)  # the oldest first, its product with it
            _PATH_PRODUCTS.pop(held[0], None)
        _PATH_CACHE[key] = (weakref.ref(sc, lambda _, key=key: (_PATH_CACHE.pop(key, None),
                                                               _PATH_PRODUCTS.pop(key, None))),
                            np.array(rows, copy=True), parts, size)
    return parts


#: Whether the path count beside a model whose first columns are the last one counted for the scan (``Q = [Qb, U]``,
#: ``Qb``'s bytes: the demo's second count, 149 columns after 145, the engine's next state beside the baseline's
#: basis) takes ``Qb^T C`` from that count and forms only ``U^T C`` (:func:`_path_product`). Not bit for bit in
#: general: OpenBLAS blocks a product's rows by its shape, and on its Haswell kernels rows 144 and 148 of the demo's
#: 149-row product differ from the 145-row product and the new rows' by up to 3.1e-15 (on SkylakeX kernels they are
#: the same bytes); the demo's path lengths and every identity campaign's report are the same bytes on both kernels
#: (session 25, docs/performance.md: 2 of the 4 products a demo discover, about 8 ms). Off: every product made whole.
PATH_PRODUCT_REUSE = True
#: id(scan) -> (a copy of the model basis ``Q``, ``Q^T C``, the parts it was made from) of the scan's last whole path
#: count (:func:`_path_product`): kept only beside the parts kept in :data:`_PATH_CACHE` (counted in its bound, the
#: copy of ``Q`` with it), gone with them.
_PATH_PRODUCTS: dict = {}


def _path_product(sc, parts, Q) -> np.ndarray:
    """``Q^T C`` of the scan's trials side by side (``parts[0]``, :func:`_path_parts`) beside the model basis ``Q``.

    Where the scan's parts are kept (:data:`_PATH_CACHE`) the product is
    kept with a copy of its ``Q`` for the next count: a ``Q`` of the same
    bytes takes it whole (the same product of the same numbers); a ``Q``
    whose first columns are those bytes takes its rows and forms only the
    other columns' (:data:`PATH_PRODUCT_REUSE`); any other ``Q`` (its
    numbers changed in place included) makes the product whole, as
    :func:`_subspace_path_of` makes it.
    """
    Ct = parts[0]
    key = id(sc)
    ent = _PATH_CACHE.get(key)
    if (ent is None or ent[2] is not parts or not isinstance(Q, np.ndarray) or Q.ndim != 2
            or Q.dtype != np.float64):  # (parts not kept, or a basis not a dense array: nothing kept)
        return np.asarray(Q.T @ Ct)
    prev = _PATH_PRODUCTS.get(key)
    if prev is not None and prev[2] is not parts:  # (kept beside other parts: the scan's other rows)
        prev = None
    kb = prev[0].shape[1] if prev is not None else 0
    same = (prev is not None and Q.shape[0] == prev[0].shape[0] and kb <= Q.shape[1]
            and bool((Q[:, :kb].view(np.int64) == prev[0].view(np.int64)).all()))
    if same and kb == Q.shape[1]:
        return prev[1]
    if same and kb and PATH_PRODUCT_REUSE:
        B = np.vstack([prev[1], Q[:, kb:].T @ Ct])
    else:
        B = np.asarray(Q.T @ Ct)
    _PATH_PRODUCTS.pop(key, None)
    if _path_held() + B.nbytes + Q.nbytes <= PATH_CACHE_BYTES:
        Qk = np.array(Q, copy=True)
        B.flags.writeable = Qk.flags.writeable = False
        _PATH_PRODUCTS[key] = (Qk, B, parts)
    return B


def _path_held() -> int:
    """Bytes :data:`_PATH_CACHE` and :data:`_PATH_PRODUCTS` hold (snapshots: an entry may go with its scan at any
    collection)."""
    return sum(v[3] for v in list(_PATH_CACHE.values())) + sum(v[0].nbytes + v[1].nbytes
                                                                for v in list(_PATH_PRODUCTS.values()))


#: A long log's refinement (:func:`_refine`) builds this many bytes of one grid's trials at a time (at least one
#: trial), counted on the rows tested; the peak per group is about two to three times it (the rebuild makes every
#: row, the rows taken are a copy, each trial tested from its own contiguous copy).
REFINE_BLOCK_BYTES = 16 << 20


def _refine_group(st: _State, n: int, k: int) -> int | None:
    """Trials of a refinement's grid built at once: all (None) against an array basis (a short log), else about
    :data:`REFINE_BLOCK_BYTES` of ``n`` rows by ``k`` columns (at least one)."""
    return None if not isinstance(st.Q, Basis) else max(1, REFINE_BLOCK_BYTES // max(8 * n * k, 1))


def _refine_ss(cause, bl, info: dict, name: str, grid: np.ndarray, st: _State, rows, g: int | None) -> np.ndarray:
    """Sums of squares of the trials ``info`` with ``name`` each value of ``grid`` (beside the model ``st``).

    ``g`` None (an array basis, a short log): the grid's trials built and
    tested at once. Else (a long log's block basis, :func:`_refine_group`)
    ``g`` of them built at a time and each tested on its own, from its
    own C-contiguous copy: ``rebuild`` makes a trial's columns from its own
    parameter value, and a trial tested alone is summed the same way
    whatever the trials built beside it, so every group size gives the same
    sums bit for bit (the whole grid in one :func:`nested_f_batch` does
    not: its column norms are one ``einsum`` over the grid, whose buffered
    sums over rows split where the grid's size puts them, a few units of
    the last place). The local defect's 11 centres over 1e6 rows were
    84 MiB of bump columns, with as much again of the window's temporaries.
    """
    if g is None:
        inf = dict(info)
        inf[name] = grid
        return nested_f_batch(take_rows(cause.rebuild(bl, inf), rows, 1), st.Q, st.r, st.rss, st.dof)[0]
    out = np.empty(len(grid))
    for a in range(0, len(grid), g):
        inf = dict(info)
        inf[name] = grid[a:a + g]
        C = take_rows(cause.rebuild(bl, inf), rows, 1)
        for t in range(C.shape[0]):
            out[a + t] = nested_f_batch(np.array(C[t:t + 1], order="C"), st.Q, st.r, st.rss, st.dof)[0][0]
        del C
    return out


def _refine(cause, bl, info: dict, st: _State, rows) -> dict:
    """Refine the nonlinear parameters of a trial on two nested grids (exact sums of squares).

    Each parameter in turn: 11 values over the neighbourhood the scan's
    step leaves open, then 9 around the best (a resolution of 1/40 of the
    scan's step); the trial's value is kept unless a better one is found.
    A parameter the cause gives a range to (:attr:`core.causes.Cause.search_range`) is sought over that whole
    range instead (:func:`_refine_bounded`, :data:`REFINE_OVER_RANGE`).
    """
    info = dict(info)
    bounds = cause.search_range(bl) if getattr(cause, "search_range", None) is not None else {}
    for name in cause.nonlinear:
        if name not in info:  # (a layout without it: a drift's polynomial)
            continue
        if name in bounds and REFINE_OVER_RANGE:
            info[name] = _refine_bounded(cause, bl, info, name, bounds[name], st, rows)
            continue
        v0 = info[name]
        if name == "period_m":
            span = np.ptp((bl.data.x, bl.data.y)["XY".index(info["axis"])])
            f0, df = 1 / v0, info.get("scan_step_per_m", 1 / (3 * max(span, 1e-9)))  # one scan step
            lo, hi = 1 / (f0 + df), 1 / max(f0 - df, 1e-12)
        elif name == "half_width_m":
            lo, hi = v0 * 0.75, v0 * 1.33
        else:
            h = info.get("half_width_m", abs(v0)) / 4
            lo, hi = v0 - h, v0 + h
        C0 = take_rows(cause.rebuild(bl, info), rows, 1)
        g = _refine_group(st, C0.shape[1], C0.shape[2])
        if g is not None:  # (tested as the grid's trials are: alone, from a C-contiguous copy)
            C0 = np.array(C0, order="C")
        best_v, best_ss = v0, nested_f_batch(C0, st.Q, st.r, st.rss, st.dof)[0][0]
        del C0
        for _ in range(2):
            grid = np.linspace(lo, hi, 11 if _ == 0 else 9)
            ss = _refine_ss(cause, bl, info, name, grid, st, rows, g)
            i = int(np.argmax(ss))
            if ss[i] > best_ss:
                best_v, best_ss = float(grid[i]), float(ss[i])
            step = grid[1] - grid[0]
            lo, hi = best_v - step, best_v + step
        info[name] = best_v
    return info


#: A nonlinear parameter a cause gives a range to (:attr:`core.causes.Cause.search_range`: warm-up's time constant)
#: is refined over that whole range (:func:`_refine_bounded`), not within +-25 % of the scan's trial (False: as
#: before). Session 27, review27 fault 2: the window's two passes ended at its edges (740 -> 925 -> 962 s) where
#: the sum of squares peaks at 1110 s.
REFINE_OVER_RANGE = True
#: Points of :func:`_refine_bounded`'s first grid over the whole range (geometric), before the bounded search
#: between the best point's neighbours: a sum of squares with several local maxima over the range (a warm-up's
#: time constant beside a drift's) is searched globally at 2.3 % (40x range), then to :data:`REFINE_BOUNDED_XTOL`.
REFINE_BOUNDED_POINTS = 161
#: Tolerance of the bounded search, in the parameter's logarithm (1e-5: the value to 0.001 %).
REFINE_BOUNDED_XTOL = 1e-5


def _refine_bounded(cause, bl, info: dict, name: str, rng: tuple, st: _State, rows) -> float:
    """The value of the positive nonlinear parameter ``name`` in ``rng`` = (lo, hi) that explains most beside
    ``st`` (:attr:`core.causes.Cause.search_range`, session 27): a geometric grid over the whole range, then a bounded
    1-D search (scipy's ``minimize_scalar``, in the logarithm) between the best point's neighbours. The scan's
    trial is kept unless a better value is found. Unlike :func:`_refine`'s window of one scan step, the answer
    is not stopped at an edge the scan's choice sets (review27: a warm-up's 740 s trial refined to the edge of
    +-25 %, 925 s, then 962 s, where the sum of squares peaks at 1110 s); it is at an end of ``rng`` only where
    the data ask for a value beyond it."""
    lo, hi = float(rng[0]), float(rng[1])
    v0 = float(info[name])
    if not 0 < lo < hi < np.inf:  # (no range to search: the scan's trial as it is)
        return v0

    C0 = take_rows(cause.rebuild(bl, info), rows, 1)
    g = _refine_group(st, C0.shape[1], C0.shape[2])  # (a long log's: built a block at a time, as _refine's)
    del C0

    def ss(v):
        return _refine_ss(cause, bl, info, name, np.atleast_1d(np.asarray(v, float)), st, rows, g)

    best_v, best_ss = v0, float(ss(v0)[0])
    grid = np.geomspace(lo, hi, REFINE_BOUNDED_POINTS)
    s = ss(grid)
    i = int(np.argmax(s))
    if s[i] > best_ss:
        best_v, best_ss = float(grid[i]), float(s[i])
    a, b = np.log(grid[max(i - 1, 0)]), np.log(grid[min(i + 1, grid.size - 1)])
    res = optimize.minimize_scalar(lambda u: -float(ss(np.exp(u))[0]), bounds=(a, b), method="bounded",
                                   options={"xatol": REFINE_BOUNDED_XTOL})
    if res.success and -float(res.fun) > best_ss:
        best_v = float(np.exp(res.x))
    return best_v


def _counter_ss(bl, cause, st: _State, rows, sigma: float) -> tuple:
    """Debiased sum of squares the cause's plainer explanation (``cause.counter``) explains beside the model ``st``.

    Returns
    -------
    (debiased sum of squares, m^2; Uc (len(rows), kc): its orthonormal basis outside ``st.Q``,
    for :func:`_beyond`)
    """
    Bc = _white(bl, cause.counter(bl))
    Uc = new_basis(st.Q, Bc[rows])
    return float(np.sum((Uc.T @ st.r) ** 2)) - Uc.shape[1] * sigma ** 2, Uc


#: Effective units the evidence of a confined cause must come from (:attr:`core.causes.Cause.support`).
MIN_SUPPORT = 2.0


def _positions_text(n_eff: float) -> str:
    """``n_eff`` effective positions as the support message prints it: two significant digits, more where two
    would round a count short of :data:`MIN_SUPPORT` up to it (1.986 printed "2" hid why a bump was refused:
    blind gen_b 8306, session 29)."""
    shown = f"{n_eff:.2g}"
    if n_eff < MIN_SUPPORT <= float(shown):
        shown = next(t for t in (f"{n_eff:.{k}g}" for k in range(3, 18)) if float(t) < MIN_SUPPORT)
    return shown


def _support(bl, cause, info, st: _State, E: np.ndarray, reached_only: bool = False) -> dict:
    """Over how many units (``cause.support``: positions along an axis) the cause's evidence spreads.

    What the columns ``E`` (rows used) explain beside the model ``st``,
    ``f . r`` (``f`` the fitted part), summed per unit, ``s_u``; the
    effective number of units is the total over the largest,
    ``sum s_u / max s_u``: 1 when one unit carries it all, 2 when the
    largest carries half. Below :data:`MIN_SUPPORT` the cause is refused:
    what it explains is mostly one unit's, and dropping that unit would
    leave less than half of it. Returns the evidence, with ``refused``,
    ``reason`` and ``where`` (the count in words, without the verdict).

    ``reached_only``: the units counted only at the touches the cause's own
    columns reach (a row of ``E`` not all zero): beside the model, the
    fitted part spreads over every touch, so a narrow bump centred beside
    one gross error passes the count over all touches (gen_b outlier 1175:
    2.4 effective positions, the largest carrying 42 %, two 13 mm outside
    a 1.5 mm half-width). A real narrow bump touched at its peak and two
    shoulders can fail it too (its peak carries over half): the finding
    is then ambiguous with ``outlier``, not refused (:func:`_findings`),
    unless the touches away from that place contradict it
    (:func:`_beyond_one_place`, :data:`DEFECT_BEYOND_ONE_PLACE`: refused at
    adoption).
    """
    rows = st.rows
    U = new_basis(st.Q, E)
    f = U @ (U.T @ st.r)
    lab = np.asarray(cause.support(bl, info))[rows]
    w = f * st.r
    if reached_only:
        on = np.any(np.asarray(E) != 0, axis=1)
        lab, w = lab[on], w[on]
    s = np.bincount(lab, weights=w)
    top = float(s.max()) if s.size else 0.0
    n_eff = float(s.sum()) / top if top > 0 else 0.0
    where = (f"one position carries {top / max(float(s.sum()), 1e-300):.0%} of what it explains "
             f"({_positions_text(n_eff)} "
             f"effective positions, at least {MIN_SUPPORT:g})")
    return {"refused": bool(n_eff < MIN_SUPPORT), "support_units": n_eff, "where": where,
            "reason": f"not seen at two places: {where}"}


#: A confined cause (:attr:`core.causes.Cause.support`: the local scale defect's bump) whose evidence, where its
#: columns reach, is one position's (:func:`_support` with ``reached_only`` below :data:`MIN_SUPPORT`) is tested
#: once more on the touches it reaches away from that place (:func:`_beyond_one_place`): a scale defect moves every
#: touch whose axis position lies under the bump, the same target's other touches and the neighbours on its flanks,
#: in every set-up; a chip moves the touches it sits under (one target's, in one set-up). Where the other touches,
#: at the bump's fitted size, would show it and contradict it (and do not show it), the cause is refused at
#: adoption (a gross error at that place: the outlier screen then sets it aside); where they show it, the data
#: decide for the bump (with :data:`DEFECT_SEEN_BEYOND_ONE_PLACE_NAMED`, off, it would not be made ambiguous with
#: ``outlier``); where they cannot tell (no other touch lies where the bump would move it detectably) the two
#: readings are indistinguishable on the design and the finding stays ambiguous with ``outlier``, said in those
#: words. Session 29 (out29, docs/discovery-studies.md): the simulator's outlier 4021 and 4047 (tuning) and 6609 (blind)
#: `local_scale_defect?` -> `outlier?`, nothing else moved on the tuning sets (gen_a/gen_b outlier and
#: local_scale_defect 1000-1099, every effect 1000-1009, none 1000-1049; the simulator's 4000-4049 and every effect
#: 4000-4019; gen_c 200-299 and every effect 200-219), no identity leaf. False: the behaviour before.
DEFECT_BEYOND_ONE_PLACE = True
#: With :data:`DEFECT_BEYOND_ONE_PLACE`: a bump the touches away from its largest place show (one-sided at
#: ``Settings.alpha``) is named without the ``outlier`` ambiguity of :func:`_findings`' reached-only support count.
#: Off: two chips under one bump show it to each other (gen_c outlier 205, 218; gen_b 1015), so "seen" does not
#: exclude a chip. False: that count alone decides the ambiguity (the behaviour before).
DEFECT_SEEN_BEYOND_ONE_PLACE_NAMED = False


def _beyond_one_place(st: _State, E: np.ndarray, sigma: float, settings, lab: np.ndarray) -> dict | None:
    """What a one-column confined cause's columns ``E`` (rows used) show on the touches away from its largest place.

    ``lab`` (rows used): the cause's units (:attr:`core.causes.Cause.support`, a position along the axis to 1 um:
    one target's touches in one set-up, a chip there staying for its repeats). The largest place is the unit, among
    those the columns reach, that contributes most to what the column explains beside the model ``st`` (``f_i r_i``
    summed, ``f`` the fitted part). Its touches set aside (the model refitted without those rows: a low-rank
    downdate of ``st.Q``, exact), the column's amplitude is fitted on the other rows beside the model, ``a_rest +-
    s_rest`` (``s_rest = sigma / |e'|``, ``e'`` the column outside the model there), and compared with the amplitude
    fitted on every row, ``a_all``, in its sign:

    - ``seen``: ``a_rest / s_rest`` beyond ``z(1 - alpha)`` (one-sided, ``Settings.alpha``): the other touches
      carry the bump themselves;
    - ``refuted``: not seen, and ``(a_all - a_rest) / s_rest`` beyond the same bound: at its fitted size the bump
      would have moved the other touches it reaches (the same target's other touches, the neighbours on its
      flanks), and they did not move; one place carries it (a gross error there);
    - ``cannot tell``: neither: no other touch lies where the bump, at its fitted size, would move it detectably
      (``a_all / s_rest``, the expected z, is reported).

    None where the column is not one column or lies in the model, or the place's touches are their own parameters
    (the model without them loses a direction). ``sigma`` is the probe's noise (the same units as ``st.r``).
    """
    if E.ndim != 2 or E.shape[1] != 1 or sigma <= 0 or not isinstance(st.Q, np.ndarray):
        return None
    e = np.asarray(E[:, 0], float)
    Q, r = st.Q, st.r
    qe = Q.T @ e
    e_perp = e - Q @ qe
    ee = float(e_perp @ e_perp)
    scale = float(np.linalg.norm(e))
    if ee <= (1e-5 * scale) ** 2:
        return None
    a_all = float(e_perp @ r) / ee
    contrib = a_all * e_perp * r  # (f_i r_i)
    on = e != 0
    lab = np.asarray(lab)
    per = np.bincount(lab[on], weights=contrib[on], minlength=int(lab.max()) + 1)
    S = np.flatnonzero(lab == int(np.argmax(per)))
    QS = Q[S]
    H = QS @ QS.T
    w_, V_ = np.linalg.eigh(np.eye(len(S)) - H)
    if w_.min() < 1e-9:
        return None
    Minv = lambda v: v + QS.T @ (V_ @ ((V_.T @ (QS @ v)) / w_))  # (I - QS^T QS)^-1 v, Woodbury
    keep = np.ones(len(r), bool)
    keep[S] = False
    Qk = Q[keep]
    r_k = r[keep] + Qk @ Minv(QS.T @ r[S])  # (Q^T r = 0: Qk^T r_k0 = -QS^T r_S)
    e_k = e[keep] - Qk @ Minv(qe - QS.T @ e[S])
    ek = float(e_k @ e_k)
    if ek <= (1e-5 * scale) ** 2:
        return {"verdict": "cannot tell", "rows": S, "z_rest": 0.0, "z_expected": 0.0, "z_short": 0.0}
    a_rest = float(e_k @ r_k) / ek
    s_rest = sigma / np.sqrt(ek)
    sgn = 1.0 if a_all >= 0 else -1.0
    z_rest = sgn * a_rest / s_rest
    z_short = sgn * (a_all - a_rest) / s_rest
    bound = float(stats.norm.isf(settings.alpha))
    verdict = "seen" if z_rest > bound else ("refuted" if z_short > bound else "cannot tell")
    return {"verdict": verdict, "rows": S, "z_rest": float(z_rest), "z_expected": float(abs(a_all) / s_rest),
            "z_short": float(z_short), "bound": bound}


#: A confined cause (the local scale defect's bump) whose evidence one *feature* carries most of (its share of what
#: the column explains beside the model, every touch of the feature counted, over half: fewer than
#: :data:`MIN_SUPPORT` effective features) is tested once more on the other features' touches
#: (:func:`_beyond_one_feature`): a scale defect moves every touch whose axis position lies under the bump, whatever
#: the feature; a change of the part (the slot closing) moves one feature's touches. Where the other features'
#: touches it reaches, at the bump's fitted size, would show it and do not (``refuted``), and a change of that
#: feature (the catalogue's ``part_change`` layouts on it) explains at least ``rival_share`` as much as the bump
#: (:func:`_feature_change_ratio`), the bump is refused at adoption (one feature changing, not an axis error; the
#: round goes on without it). Named, a bump the other features do not show (``refuted`` or ``cannot tell`` beside
#: the final model) is hedged, ambiguous with ``part_change``, where that change explains as much by the same
#: share. Both gates measured: gen_b's true bumps lie mostly on the long blade, whose change explains 0.01-0.36 of
#: them (ungated, the hedge took 10 of 100 right confident readings); gen_a local_scale_defect 1065's bump, refuted
#: beyond its feature (2.4 sigma expected, -0.6 seen), is one no change of that feature explains (0.02): ungated,
#: the refusal turned its `local_scale_defect?` into `unexplained`. Session 30 (mis30, docs/discovery-studies.md "Session 30: two confident
#: misnamings of the blind check"): blind gen_b part_change 8101 read `local_scale_defect` (confident; the slot
#: carries 73 % of the bump, the other features 2.0 sigma where 3.9 was expected, the slot's change explains 1.41
#: times as much) -> `local_scale_defect?` ambiguous with `part_change`. False: the behaviour before.
DEFECT_BEYOND_ONE_FEATURE = True


def _feature_names(bl) -> np.ndarray | None:
    """The log's feature names, sorted (the codes of :func:`_feature_codes`), or None where it names none."""
    t = getattr(getattr(bl, "data", None), "touches", None)
    f = getattr(t, "feature", None) if t is not None else None
    return None if f is None else np.unique(np.asarray(f, dtype=object).astype(str))


def _feature_codes(bl, rows) -> np.ndarray | None:
    """(rows) integer codes of the touches' features, or None where the log names none (or one feature only)."""
    t = getattr(getattr(bl, "data", None), "touches", None)
    f = getattr(t, "feature", None) if t is not None else None
    if f is None:
        return None
    codes = np.unique(np.asarray(f, dtype=object).astype(str), return_inverse=True)[1].ravel()[rows]
    return codes if np.unique(codes).size >= 2 else None


def _beyond_one_feature(st: _State, E: np.ndarray, sigma: float, settings, feat: np.ndarray) -> dict | None:
    """What a one-column confined cause's columns ``E`` (rows used) show on the features other than its largest.

    ``feat`` (rows used): integer feature codes. Each feature's share of what the column explains beside the model
    ``st`` (``f_i r_i`` summed over every touch of the feature, ``f`` the fitted part) is taken; where the largest
    carries over half (``sum / max`` below :data:`MIN_SUPPORT` effective features), that feature's touches are set
    aside, the model refitted on the rest (the projection on the span of ``st.Q``'s remaining rows: exact, and a
    direction only those touches held, such as that feature's own target parameters, drops out), and the column's
    amplitude fitted on the rest beside it, ``a_rest +- s_rest`` (``s_rest = sigma / |e'|``), against the
    amplitude fitted on every row, ``a_all``, in its sign, as :func:`_beyond_one_place` judges a place:
    ``seen`` (``a_rest / s_rest`` beyond ``z(1 - alpha)``, one-sided), ``refuted`` (not seen, and ``(a_all -
    a_rest) / s_rest`` beyond the same bound: the other features would show it at its fitted size and do not),
    ``cannot tell`` (neither; ``z_expected = |a_all| / s_rest``). Returns None where the test does not apply (not
    one column, the column in the model, one feature only or none carrying more than half, no positive share).
    ``feature_share`` is the largest feature's share, ``n_features_eff`` the effective count.
    """
    if E.ndim != 2 or E.shape[1] != 1 or sigma <= 0 or not isinstance(st.Q, np.ndarray):
        return None
    e = np.asarray(E[:, 0], float)
    Q, r = st.Q, st.r
    e_perp = e - Q @ (Q.T @ e)
    ee = float(e_perp @ e_perp)
    scale = float(np.linalg.norm(e))
    if ee <= (1e-5 * scale) ** 2:
        return None
    a_all = float(e_perp @ r) / ee
    feat = np.asarray(feat, int)
    if np.unique(feat).size < 2:  # (one feature: nothing beside it)
        return None
    per = np.bincount(feat, weights=a_all * e_perp * r)
    top = int(np.argmax(per))
    if per[top] <= 0:
        return None
    n_eff = float(per.sum()) / float(per[top])
    if n_eff >= MIN_SUPPORT:
        return None
    keep = feat != top
    out = {"feature_share": float(per[top] / per.sum()), "n_features_eff": n_eff, "feature": top}
    Qk = Q[keep]
    w, V = np.linalg.eigh(Qk.T @ Qk)  # (Q orthonormal: 0 <= w <= 1; w ~ 0 a direction the feature alone held)
    good = w > 1e-9
    Uk = (Qk @ V[:, good]) / np.sqrt(w[good])
    r_k = r[keep] - Uk @ (Uk.T @ r[keep])  # (r = y - Q Q^T y: its part outside span(Qk) is y's there)
    e_k = e[keep] - Uk @ (Uk.T @ e[keep])
    ek = float(e_k @ e_k)
    if ek <= (1e-5 * scale) ** 2:
        return {**out, "verdict": "cannot tell", "z_rest": 0.0, "z_expected": 0.0, "z_short": 0.0}
    s_rest = sigma / np.sqrt(ek)
    sgn = 1.0 if a_all >= 0 else -1.0
    a_rest = float(e_k @ r_k) / ek
    z_rest = sgn * a_rest / s_rest
    z_short = sgn * (a_all - a_rest) / s_rest
    bound = float(stats.norm.isf(settings.alpha))
    verdict = "seen" if z_rest > bound else ("refuted" if z_short > bound else "cannot tell")
    return {**out, "verdict": verdict, "z_rest": float(z_rest), "z_expected": float(abs(a_all) / s_rest),
            "z_short": float(z_short), "bound": bound}


def _part_change_layouts(bl):
    """The catalogue's ``part_change`` layouts (``(info, (N, k) columns)``, each built when asked, through the
    baseline's whitening as the search builds them), or () where the catalogue has none for this baseline."""
    pc = causes_mod.lookup("part_change", bl.kind)
    if pc is None or pc.scans is None:
        return ()
    scans = pc.scans(bl)[0]
    if bl.whiten is not None:
        scans = [dataclasses.replace(sc, build=(lambda idx, b=sc.build: bl.whiten @ b(idx))) for sc in scans]
    return _Layouts(scans)


def _feature_change_ratio(bl, E: np.ndarray, so: _State, sigma: float, layouts, code: int) -> float | None:
    """What a change of one feature explains, as a share of what the columns ``E`` (every row) explain, beside ``so``.

    The feature is the one of code ``code`` (:func:`_feature_codes`' order); its changes are the catalogue's
    ``part_change`` layouts on it (``layouts``: :func:`_part_change_layouts`, each a wall's shift, turn or bow in
    time, its form), each's sum of squares beside the model debiased by its directions (``ss - k sigma^2``), the
    largest taken, over ``E``'s own (debiased). None where there is no such layout or ``E`` explains nothing.
    """
    names = _feature_names(bl)
    if names is None or not 0 <= code < len(names):
        return None
    rows = so.rows
    U = new_basis(so.Q, np.asarray(E)[rows])
    d_n = float(np.sum((U.T @ so.r) ** 2)) - U.shape[1] * sigma ** 2
    if d_n <= 0:
        return None
    best = None
    for info, B in layouts:
        if str(info.get("feature")) != names[code]:
            continue
        V = new_basis(so.Q, np.asarray(B)[rows])
        d = float(np.sum((V.T @ so.r) ** 2)) - V.shape[1] * sigma ** 2
        best = d if best is None else max(best, d)
    return None if best is None else max(best, 0.0) / d_n


#: A turn of the table growing in time (``c_drift``) moves every touch by ``(R90 (p - c0)) . n ECC(t)``: touches
#: with a mainly-X normal through their y lever, touches with a mainly-Y normal through their x lever, by the one
#: angle. A straightness of one axis growing in time (the X guideway bowing with warm-up) moves touches through one
#: normal component only, and its slope across the touched region is the closest catalogue shape, a turn. Before
#: ``c_drift`` is adopted its columns are split by the touches' normal (mainly X, mainly Y) and the split F-tested
#: beside the model and the turn (:func:`_turn_split`: the two groups' angles differ); where they differ at
#: ``Settings.alpha`` and one group does not show the turn (its share of the turn fitted on every touch, fitted
#: beside the model and the other group's, below ``z(1 - alpha)`` sigma) the cause is refused (not one angle of the
#: table; the round goes on without it). The second condition keeps a turn both groups carry beside a misfit of its
#: form (gen_a c_drift 1072: the per-set-up rates, shares 1.08 and 0.90 at 20+ sigma, the F test alone p 7e-4).
#: Session 30 (mis30, docs/discovery-studies.md "Session 30: two confident misnamings of the blind check"): blind gen_a
#: thermal_bending 8100 read `c_drift` (confident; the effect's sum of squares 1853 um^2 on mainly-Y normals against
#: 132 on mainly-X; split p 0.0063, the mainly-X share 0.20 at 0.8 sigma) -> `unexplained`. False: the behaviour
#: before.
C_DRIFT_NORMALS_AGREE = True


def _turn_split(bl, st: _State, E: np.ndarray) -> dict | None:
    """Whether a table turn's columns ``E`` (rows used) are one angle on touches of mainly-X and mainly-Y normals.

    The touches are split by their normal (``|n_x| >= |n_y|``: mainly X); ``E`` restricted to the mainly-X touches
    is F-tested beside the model ``st`` and ``E`` (the test that the two groups' angles are equal, exact under the
    model). Returns the test (``F``, ``p_value``, ``k``), what ``E`` on each group explains beside the model alone
    (``ss_x_um2``, ``ss_y_um2``), and each group's share of the turn fitted on every touch (``f = E c``, ``c`` its
    fit beside the model: ``f`` on each group's touches, the two fitted together beside the model; 1 where the group
    carries the turn at its joint size) with its z (``share_x``, ``z_x``, ``share_y``, ``z_y``; the residual's
    variance after the two), or None where the split does not apply (one group empty, no part of it outside the
    model and the turn, the two groups' columns collinear, no normals).
    """
    d = getattr(bl, "data", None)
    nx, ny = getattr(d, "nx", None), getattr(d, "ny", None)
    if nx is None or ny is None or not isinstance(st.Q, np.ndarray):
        return None
    gx = np.abs(np.asarray(nx)[st.rows]) >= np.abs(np.asarray(ny)[st.rows])
    if gx.all() or not gx.any():
        return None
    E = np.asarray(E, float)
    U = new_basis(st.Q, E)
    if U.shape[1] == 0 or st.dof - U.shape[1] < 2:
        return None
    r1 = st.r - U @ (U.T @ st.r)
    V = new_basis(np.hstack([st.Q, U]), E * gx[:, None])
    if V.shape[1] == 0:
        return None
    t = nested_f(V, r1, float(r1 @ r1), st.dof - U.shape[1])
    ss = [float(np.sum((new_basis(st.Q, E * g[:, None]).T @ st.r) ** 2)) / UM ** 2 for g in (gx, ~gx)]
    # each group's share of the turn fitted on every touch (its one time course f), fitted beside the model and the
    # other group's: 1 where the group carries the turn at its joint size, 0 where it does not move
    f = E @ np.linalg.lstsq(E - st.Q @ (st.Q.T @ E), st.r, rcond=None)[0]
    P = np.column_stack([f * gx, f * ~gx])
    P = P - st.Q @ (st.Q.T @ P)
    G = P.T @ P
    if np.linalg.cond(G) > 1e12:
        return None
    a = np.linalg.solve(G, P.T @ st.r)
    res = st.r - P @ a
    s2 = float(res @ res) / max(st.dof - 2, 1)
    se = np.sqrt(np.diag(np.linalg.inv(G)) * s2)
    z = a / se
    return {"F": float(t.F), "p_value": float(t.p_value), "k": int(t.k), "ss_x_um2": ss[0], "ss_y_um2": ss[1],
            "share_x": float(a[0]), "share_y": float(a[1]), "z_x": float(z[0]), "z_y": float(z[1])}


def _demotion_reason(share: dict, covariate: str, settings) -> str:
    """Why the rival step (:func:`_rival_share`'s verdict ``share``) dropped an adopted cause.

    A support or confinement refusal is its own reason whatever the
    rival share; otherwise a plainer explanation that explains as much,
    else the cause explaining only part of its covariate's structure.
    """
    return (share.get("not_supported") or share.get("not_confined") or
            (f"a plainer explanation ({share['counter']}) explains as much"
             if "counter_explained_ss_um2" in share and share["rival_share"] >= settings.rival_share else
             f"explains only part of the structure in {covariate} (share {share['rival_share']:.2f} of "
             "a smooth term's)"))


def _half_power_nc(k: int, alpha: float) -> float:
    """The noncentrality at which a chi-square test on ``k`` dof at level ``alpha`` has 50 % power.

    ``P(ncx2(k, lam) > chi2.isf(alpha, k)) = 0.5``, solved for ``lam``
    (the noise variance known: the nested F test's denominator has many
    degrees of freedom on these campaigns). Hand values: k = 1,
    alpha = 0.05 gives 3.84 (the critical value itself: the noncentral
    chi-square with one dof has its median close to ``lam`` there).
    """
    crit = float(stats.chi2.isf(alpha, k))
    return float(optimize.brentq(lambda lam: float(stats.ncx2.sf(crit, k, lam)) - 0.5, 1e-9, 10 * crit + 100))


#: Whether a confined cause (:attr:`core.causes.Cause.smooth`: the local scale defect) whose signal the smooth error
#: map holds on the design (:func:`_smooth_verdict`'s power clause, ``inside``: its part outside the map below the
#: test's half power) is refused, not named ambiguous, where the map also explains significant structure beyond it
#: (``p_smooth_beyond_cause`` below ``alpha_family``) and as much as it, the cause adding nothing beyond the map
#: (session 35, wp35). The power clause exists because a bump read at a few positions along an axis cannot be told
#: from the map there: failing to see it beyond the map says nothing. But the map seen beyond the bump is a test
#: that has power: where the bump is (nearly) a special case of the map, the nested F test of the map beyond it
#: rejects the bump's restriction, and naming a place for the structure the map spreads is a claim the data refuse.
#: Set C's gen_a feed_latency 10105 (spent): ``local_scale_defect?`` (half-width 4.33 mm) beside a fine periodic
#: term, its signal wholly inside the map (outside 2e-24 noise variances; half power 25.9), the map 17.4 against
#: 11.8 um^2 and beyond the bump p = 4.5e-4, the bump beyond the map p = 1. False: the behaviour before (named
#: ambiguous, ``indistinguishable_counter``). Switched on by the lead in session 36 before blind set F (it moved 0
#: of 830 tuning readings); set F reads it (docs/discovery.md, "The last blind check").
INSIDE_SMOOTH_REFUSED = True


def _smooth_verdict(bl, cause, st: _State, E: np.ndarray, sigma: float, tries: float, settings) -> dict:
    """A confined cause (columns ``E``, rows used) against the same error smooth over its covariate (``cause.smooth``).

    The cause is refused when the smooth form, beside the model ``st``,
    explains about as much as it does (debiased: at least
    :attr:`Settings.rival_share` of it, the ratio by which a cause must
    match a smooth term in the rival check, here the other way round) and
    the cause's columns add nothing significant beyond the smooth form
    (nested F test with the Bonferroni factor ``tries`` of its adoption):
    the structure is then
    spread along the covariate, which the baseline's grid did not follow,
    not confined where the cause puts it. Only where the test has power:
    the part of the cause's fitted signal outside the smooth form (what a
    true cause of the fitted size leaves beyond it), in noise variances,
    must reach the noncentrality at which that test has 50 % power at
    its level ``alpha_family / tries`` (:func:`_half_power_nc`; 16.6 for
    3 columns at 0.01 / 30). Below that (a few positions along the axis,
    which the smooth form passes through whatever their values: gen_a's
    parts keep 0.0 % of the bump's signal outside it, a gen_b defect
    0.4 %; the simulator's defects, seeds 1, 5, 14), failing to find the
    bump beyond the smooth form says nothing: the cause is not refused
    but ``indistinguishable`` (named ambiguous, the smooth form given as
    the reason). The fitted signal is the selected trial's, larger than
    the true one on average, so this power is if anything optimistic.

    The smooth form has many columns (four tables of cubic B-splines: 20
    to 44 outside the baseline on the campaigns seen) against the cause's
    one: "explains as much" alone does not say the structure is spread,
    for the smooth form explains a true bump's signal too, through many of
    its columns (the simulator's Gaussian defects 45 and 57 of 0-69, with
    93 % and 80 % of the fitted bump inside the smooth form). The cause is
    refused only when the smooth form also explains something significant
    beyond the cause (its nested F test beside the model and the cause's
    columns at ``alpha_family``, no Bonferroni factor: one fixed
    hypothesis): structure the bump does not hold, spread along the axes.
    Where neither adds significantly beyond the other, the design cannot
    tell them apart: ``indistinguishable`` (named ambiguous). (Simulator
    defects 45 and 57: the smooth form beyond the bump p = 0.96 and 0.12;
    the effect-free synthetic seed 8 of tests/core/discover_synth.py
    0.051.) Returns the evidence, with ``refused`` and
    ``indistinguishable`` (bool) and ``reason``.
    """
    rows = st.rows
    s2 = sigma ** 2
    Bs = _white(bl, cause.smooth(bl))
    Us = new_basis(st.Q, Bs[rows])
    d_s = float(np.sum((Us.T @ st.r) ** 2)) - Us.shape[1] * s2
    Un = new_basis(st.Q, E)
    d_n = float(np.sum((Un.T @ st.r) ** 2)) - Un.shape[1] * s2
    Qa = np.hstack([st.Q, Us])
    ra = st.r - Us @ (Us.T @ st.r)
    Ub = new_basis(Qa, E)
    d_b = float(np.sum((Ub.T @ ra) ** 2)) - Ub.shape[1] * s2
    dof = len(rows) - Qa.shape[1]
    p_b = min(1.0, nested_f(Ub, ra, float(ra @ ra), dof).p_value * tries) if Ub.shape[1] else 1.0
    name = cause.smooth.__name__.replace("_", " ")
    as_much = d_s >= settings.rival_share * d_n
    f = Un @ (Un.T @ st.r)  # the cause's fitted signal, and its part outside the smooth form
    f_out = f - Us @ (Us.T @ f)
    lam = float(f_out @ f_out) / s2 if s2 > 0 else np.inf  # its noncentrality beside the smooth form
    inside = lam < _half_power_nc(max(Ub.shape[1], 1), settings.alpha_family / tries)  # (the test cannot tell)
    # the smooth form beyond the cause: is there structure the cause does not hold?
    Q_with_cause = np.hstack([st.Q, Un])
    r_beyond_cause = st.r - Un @ (Un.T @ st.r)
    U_smooth_beyond_cause = new_basis(Q_with_cause, Bs[rows])
    p_s = (nested_f(U_smooth_beyond_cause, r_beyond_cause, float(r_beyond_cause @ r_beyond_cause),
                    len(rows) - Q_with_cause.shape[1]).p_value if U_smooth_beyond_cause.shape[1] else 1.0)
    smooth_beyond_cause_significant = p_s < settings.alpha_family
    refused = bool(as_much and not inside and p_b >= settings.alpha_family and smooth_beyond_cause_significant)
    # (INSIDE_SMOOTH_REFUSED, session 35: the power clause waived where the smooth form holds more than the cause)
    held = bool(INSIDE_SMOOTH_REFUSED and as_much and inside and p_b >= settings.alpha_family
                and smooth_beyond_cause_significant)
    out = {"refused": refused or held, "smooth": name, "smooth_explained_ss_um2": max(d_s, 0.0) / UM ** 2,
           "explained_beyond_smooth_ss_um2": max(d_b, 0.0) / UM ** 2, "p_adjusted_beyond_smooth": p_b,
           "p_smooth_beyond_cause": float(p_s),
           "indistinguishable": bool(not held and as_much and (inside or (p_b >= settings.alpha_family
                                                                          and not smooth_beyond_cause_significant))),
           "reason": f"not confined: a {name} explains as much ({max(d_s, 0.0) / UM ** 2:.3g} against "
                     f"{max(d_n, 0.0) / UM ** 2:.3g} um^2), it adds nothing significant beyond it "
                     f"({fmt_p(p_b)} after Bonferroni over {tries:.0f} tries) and it explains structure "
                     f"beyond the cause ({fmt_p(p_s)})"}
    if held:
        out["inside_smooth"] = {"signal_outside_nc": lam, "half_power_nc": _half_power_nc(
            max(Ub.shape[1], 1), settings.alpha_family / tries)}
        out["reason"] = (f"not confined: a {name} explains as much ({max(d_s, 0.0) / UM ** 2:.3g} against "
                         f"{max(d_n, 0.0) / UM ** 2:.3g} um^2) and structure beyond the cause ({fmt_p(p_s)}), and "
                         f"on this design it holds the cause's signal (beyond it {lam:.2g} noise variances, below "
                         "the test's half power): the cause's form is a special case of the map that the data "
                         "reject, not a place of its own")
    return out


def _beyond(st: _State, U_alt: np.ndarray, E: np.ndarray, sigma: float, tries: float, settings,
            share: float = 1.0) -> tuple:
    """What the cause's columns ``E`` (rows used) explain once a plainer explanation is in the model.

    ``U_alt``: the plainer explanation's orthonormal basis outside ``st.Q``
    (the cause's counter, :func:`_counter_ss`'s; a time alternative's best
    trial).

    The plainer explanation explaining as much does not make the cause's
    own part vanish: a machine can have a finer rigid error map *and* a
    non-separable coupling, or lobes that are partly fixed and partly
    turned. The cause stands beside it when its columns, added to
    model + alternative, still explain a material amount (debiased, at
    least ``(material_sigma * sigma)^2`` per row) that is significant
    (nested F test with the Bonferroni factor ``tries`` of its adoption).
    ``share``: the rows the cause acts on, as a share of ``st``'s
    (:func:`_support_share`): the materiality is counted over those.

    Returns
    -------
    (debiased sum of squares beyond the alternative, m^2; its adjusted p-value; stands: bool)
    """
    rows = st.rows
    Qa = np.hstack([st.Q, U_alt])
    ra = st.r - U_alt @ (U_alt.T @ st.r)
    Un = new_basis(Qa, E)
    d = float(np.sum((Un.T @ ra) ** 2)) - Un.shape[1] * sigma ** 2
    p = min(1.0, nested_f(Un, ra, float(ra @ ra), len(rows) - Qa.shape[1]).p_value * tries)
    stands = bool(d >= (settings.material_sigma * sigma) ** 2 * len(rows) * share and p < settings.alpha_family)
    return d, p, stands


def _one_explanation(B: np.ndarray, signal: tuple, E: np.ndarray, st: _State, sigma: float, tries: float, settings,
                     *, visible_only: bool = False, above: float | None = None,
                     at_alternative_sigma: bool = False) -> tuple | None:
    """Whether an alternative's columns ``B`` and a named cause's ``E`` (both (N, k), every baseline row) are one
    explanation under two names beside ``st`` (step 8's test, :func:`_cause_alternatives`; the round's choice,
    :func:`_plainer_one_explanation`): ``B``'s part outside ``st.Q`` reproduces at least ``rival_share`` of the named
    cause's ``signal`` (:func:`_signal`) and explains at least ``rival_share`` as much (:func:`_reproduces`), and the
    named cause explains nothing material and significant beyond it (:func:`_beyond`, ``tries``: the Bonferroni
    factor of its adoption). ``(overlap, d_w, d_b, p_b)`` (the share reproduced, what ``B`` explains and what ``E``
    explains beyond it, m^2, and that test's adjusted p-value) when they are, else None.

    The two callers differ, each for its reason (said there): ``visible_only``, a cause refused as confounded with
    the model is judged by what its visible part explains alone, without the overlap; ``above``, a layout goes to
    the ``_beyond`` test only if it explains more than this (a cause's best layout so far); ``at_alternative_sigma``,
    what the named cause explains beyond is judged material at the residual sigma of the model with ``B`` in it where
    that is lower than ``sigma``.
    """
    U = new_basis(st.Q, B[st.rows])
    if U.shape[1] == 0:
        return None
    overlap, d_w, ind = _reproduces(U, signal, st, sigma, settings)
    if visible_only:
        ind = d_w >= settings.rival_share * signal[1]
    if not ind or (above is not None and d_w <= above):
        return None
    if at_alternative_sigma:
        ra = st.r - U @ (U.T @ st.r)
        sigma = min(sigma, float(np.sqrt(ra @ ra / max(len(st.rows) - st.Q.shape[1] - U.shape[1], 1))))
    d_b, p_b, stands = _beyond(st, U, E[st.rows], sigma, tries, settings)
    return None if stands else (overlap, d_w, d_b, p_b)


def _may_be_plainer(tm: Term) -> bool:
    """Whether :func:`_plainer_one_explanation` compares the term at all: named, unpenalised, of a covariate."""
    return tm.penalty is None and not tm.unnamed and tm.covariate is not None


#: Whether step 8 (:func:`_cause_alternatives`) also tests, as a named cause's alternatives under another name, the
#: other candidates that passed every test of the round it won, each in the form it passed with (True), beside the
#: catalogue's fixed layouts. Without it a cause whose scan is a search (a periodic error's period, a local defect's
#: position and width) was never tested as an alternative: gen_a periodic_axis_error 6706 (session 25's blind check)
#: read ``local_scale_defect``, ambiguous with ``nonrigid`` alone, though the periodic error passed round one within
#: 0.004 um^2 of it held out (materiality 0.075; the bump led on one column against two), explaining 61.3 against
#: 61.0 um^2. The test is step 8's own
#: (:func:`_one_explanation`); only the report's alternatives and the confidence they make read it. Session 25.
CAUSE_ALTERNATIVES_OF_THE_ROUND = True


#: Whether a cause whose form entered a round and lost it may take the round on another of its significant forms
#: that passes every test and predicts the held-out set-up better than the round's winner by the materiality margin
#: (:func:`_entrant_form_held_out`; session 25). False: each cause enters a round by its form of smallest p alone.
ENTRANT_FORM_HELD_OUT = True
#: Whether those other forms are only the cause's forms of the covariate its entrant form follows (True): another
#: shape of the same dependence (a drift's quadratic over the campaign, its warm-ups), not another hypothesis under
#: the cause's name (another axis of a periodic error or a scale defect), which the catalogue's count and p compare.
#: The covariate is the scan's: part_change's features all follow ``feature``, so another feature's change is among
#: the forms (gen_a thermal_bending 1016: another wall takes round one, the report the same). Session 25: without
#: it the rule also let a periodic error's X axis (held-out 1.27 um^2) take the round from part_change (8.87) where
#: its Y axis had entered, on gen_a part_change 1009 (part_change? -> periodic_axis_error?, the extended workpiece
#: 0.54 -> 1.96 um, the baseline's 1.03).
ENTRANT_FORM_SAME_COVARIATE = True


def _entrant_form_held_out(best: dict, other_forms: list, passed: list, sigma: float, settings) -> dict:
    """The round's winner, or another form of a cause that lost the round which beats it on held-out data.

    Each cause enters a round by one form, its trial of smallest p over its
    scans (in-sample), but the round is decided on held-out data. A cause
    whose chosen form passed and lost the round may hold another
    significant form, refused nothing, that predicts the held-out set-up
    better than the winner: gen_a thermal_drift 6105 (session 24's blind
    check), the quadratic over the campaign (p 8.5e-55, held-out gain 1.28
    um^2) entered where the warm-up of 430 s (p 1.1e-54, gain 3.37 um^2)
    would have won, and c_drift's rates per set-up (gain 2.31) won and
    carried 3.2 um of a thermal drift into the workpiece. Here every
    candidate that passed and lost has its other significant forms judged by
    every test (:func:`_evaluate`'s ``other_forms``, the order of p); the
    one whose held-out mean square lies below the winner's by more than the
    round's materiality margin (``(material_sigma * sigma)^2``, as a
    candidate beats another in the round), the lowest of them, takes the
    round. Where the winner's lead is within the margin, or the cause's
    other forms predict no better, the round stands as it was: the rule
    only acts where the cause's in-sample choice of its own form decided
    the round (session 24's rule (a'); choosing every cause's form held-out
    moved 175 workpieces and two names right -> wrong). ``other_forms``:
    ``(cause, judge)`` pairs; ``passed`` gains the form that takes the
    round when :func:`_may_be_plainer` holds of it.
    """
    margin = settings.material_sigma ** 2 * sigma ** 2
    better = [res for name, judge in other_forms if name != best["term"].cause
              for res in judge() if res["cv"] < best["cv"] - margin]
    if not better:
        return best
    out = min(better, key=lambda r: r["cv"])  # (the first of equal ones: the catalogue's order, then p)
    out["term"].evidence["entrant_form_held_out"] = {
        "won_over": best["term"].cause, "its_cv_um2": best["cv"] / UM ** 2, "cv_um2": out["cv"] / UM ** 2,
        "margin_um2": margin / UM ** 2}
    if _may_be_plainer(out["term"]):
        passed.append(out)
    return out


def _plainer_one_explanation(best: dict, passed: list, st: _State, sigma: float, settings) -> dict:
    """The round's winner, or a plainer candidate that is the same explanation under another name.

    The round picks the lowest held-out mean square, and within the
    materiality margin of it the fewest columns. Two candidates that are
    one explanation under two names on the design (step 8's test,
    :func:`_cause_alternatives`: the plainer one's columns reproduce at
    least ``rival_share`` of the winner's signal and explain at least
    ``rival_share`` as much, and the winner explains nothing material and
    significant beyond them, with the Bonferroni factor of its adoption)
    differ in held-out error only by how their columns extrapolate to the
    held-out set-up, which says nothing of which mechanism it is: then the
    plainer (fewer columns) leads, as the margin already has it. gen_b's
    lost motion, every approach along the normal (``|n_x| / 2``,
    ``|n_y| / 2``: even harmonics of the azimuth, 2 columns), against the
    probe's fixed lobes (harmonics 1-4, 8 columns): reversal 1001 explains
    60.9 um^2 in-sample, the lobes 59.9 and nothing beyond it, while the
    held-out mean squares are 6.21 against 5.21 um^2 (the baseline's 33.2,
    its in-sample residual 0.09: the held-out figure is the set-ups'
    extrapolation). Only causes of the same covariate are compared (both
    functions of ``approach_azimuth``, there): fewer columns are then a
    plainer form of one dependence, while across covariates a column count
    says nothing of which is plainer (a drift's time layout of 8 columns
    against one temperature sensor's 4, where the sensor follows the
    clock: session 15's question, left to the report's ``ambiguous_with``;
    compared across covariates, gen_b thermal_drift 1001, 0.43 sigma, went
    from ``thermal_drift`` to ``temperature_expansion``, both ambiguous,
    the drift's held-out 2.34 against the sensor's 3.47 um^2; the engine
    puts a temperature in the time family, so the family does not separate
    them). Penalised candidates (the non-rigid field) are not compared here
    (their signal is the ridge's). Among several plainer ones that
    qualify, the fewest columns, then the lowest held-out mean square.

    What the winner explains beyond the plainer one is judged material
    against the residual sigma of the model *with the plainer one in it*
    (when lower than the round's): in round one the round's sigma still
    carries the very structure in question, and the materiality it sets
    grows with the effect. gen_a probe_lobing 4100 (4.3 sigma, the lead's
    blind seeds of session 19): the lobes explain 128 um^2 beyond the lost
    motion (p 9e-60), against a materiality of 188 um^2 from the round's
    sigma of 2.43 um (the generator's noise 0.2 um); with that figure the
    lost motion led, the lobes were refused in the next round and the
    azimuth was left carrying 0.73 um (p 1e-61). With the lost motion in
    the model the sigma is about 0.8 um and the lobes stand. gen_b reversal
    1001 and 1059 keep the plainer name (the sigma barely moves there).
    """
    tb = best["term"]
    if not _may_be_plainer(tb):
        return best
    k_best = tb.columns.shape[1]
    plainer = [c for c in passed if c is not best and _may_be_plainer(c["term"])
               and c["term"].columns.shape[1] < k_best and c["term"].covariate == tb.covariate]
    if not plainer:
        return best
    signal = _signal(tb, st, sigma)
    if signal[1] <= 0:
        return best
    out = best
    for c in sorted(plainer, key=lambda c: (c["term"].columns.shape[1], c["cv"])):
        # (what the winner explains beyond it at the sigma of the model with the plainer one in it: see above)
        if _one_explanation(c["term"].columns, signal, tb.columns, st, sigma, tb.tries, settings,
                            at_alternative_sigma=True) is not None:
            c["term"].evidence["plainer_than"] = {"cause": tb.cause, "columns": int(k_best),
                                                   "cv_um2": c["cv"] / UM ** 2, "its_cv_um2": best["cv"] / UM ** 2}
            out = c
            break
    return out


def _candidate_ss(test, st: _State) -> float:
    """Debiased sum of squares a candidate's columns explain beside the model.

    ``test``: :func:`core.diagnosis.nested_f_batch` of its columns (1, n, k) against ``st``.
    """
    ss, k, _, _ = test
    s2 = max(st.rss - ss[0], 1e-300) / max(st.dof - k[0], 1)
    return float(max(ss[0] - k[0] * s2, 0.0))


def _smallest_angle_deg(Q: np.ndarray, Qe: np.ndarray) -> float:
    """Smallest principal angle between the spans of orthonormal ``Q`` and ``Qe``, degrees.

    ``atan2(sin, cos)`` of the pair (Bjorck and Golub): the sine, the
    smallest singular value of ``Qe``'s part outside ``Q``, carries a small
    angle to full relative precision, where ``arccos`` of the cosine alone
    gives ``sqrt(2 eps)`` rad (1e-6 deg) for a span inside the model, a
    different figure on every floating-point kernel.
    """
    if not (Qe.shape[1] and Q.shape[1]):
        return 90.0
    c = np.linalg.svd(Q.T @ Qe, compute_uv=False)
    s = np.linalg.svd(Qe - Q @ (Q.T @ Qe), compute_uv=False)
    return float(np.degrees(np.arctan2(s.min(), c.max())))


def _gram_beside(Pn: np.ndarray, Q: np.ndarray, pen: tuple | None) -> np.ndarray:
    """``Pn^T Pn`` (columns already out of ``Q``), or, beside penalised columns ``pen = (S, P)``, what is left of it
    after their ridge fit: ``Pn^T Pn - Pn^T S_p (S_p^T S_p + P)^-1 S_p^T Pn`` (``S_p``: S out of ``Q``)."""
    G = Pn.T @ Pn
    if pen is None or not pen[0].shape[1]:
        return G
    Sp = pen[0] - Q @ (Q.T @ pen[0])
    B = Sp.T @ Pn
    return G - B.T @ np.linalg.pinv(Sp.T @ Sp + pen[1], rcond=1e-12, hermitian=True) @ B


def _pen_of(terms, rows) -> tuple | None:
    """``(S, P)`` of the penalised terms among ``terms`` (rows used), or None: the nuisance a cause adopted beside
    them is fitted with (:func:`_determined`, :func:`_magnitudes`)."""
    pen = [t for t in terms if t.penalty is not None]
    return (_stack(pen, rows), _penalty(pen)) if pen else None


def _pen_key(terms) -> tuple:
    """The penalised terms among ``terms`` a cause's magnitudes are fitted beside, by name AND penalty: the key of the
    magnitudes cached at adoption (``Term.at_adoption``). By name alone a penalty chosen again in the final model
    (:func:`_penalties_rechosen`) left a cause adopted after it with magnitudes fitted beside the old ridge (session
    20's review: gen_a nonrigid 1013 with the ridge forced ten times, ``EXX_amplitude`` 0.280 +- 0.123 cached against
    0.371 +- 0.129 beside the ridge reported)."""
    return tuple((t.cause, np.asarray(t.penalty, float).tobytes()) for t in terms if t.penalty is not None)


#: Whether a finding says which of its magnitudes have no value because each needs a direction of its columns the
#: data cannot see beside the model (evidence ``magnitude_not_seen``; :func:`_magnitudes`' weak-direction rule),
#: where no other note names them (``magnitude_undetermined``, ``one_sided``, ``magnitudes_not_determined``).
#: Words only: the confidence does not read it (session 37).
MAGNITUDE_NOT_SEEN_NOTE = True


#: Whether a magnitude whose gradient touches an exactly-zero column of its cause is unseen, said so at once
#: (:func:`_magnitudes`). Off, the weak test divides the gradient by the column norms floored at 1e-300: any
#: gradient above about 1e-146 there makes the norm overflow to inf ("overflow encountered in dot") and the
#: magnitude passes the test, reported from coefficients the data never saw. Seen with core.causes.STYLUS_LOBING_MENDED on (its
#: exactly-zero columns: once per lobing campaign, no figure of session 37's MFB study moved); it may move a
#: reading wherever another cause has such a column, unmeasured on the other generators: off while the lead's
#: blind check runs (session 37).
MAGNITUDE_ZERO_COLUMN_UNSEEN = False


#: Whether a cause's directions inflated beyond ``vif_max`` are left out of it (True), as those beyond
#: ``1 / WEAK_SV^2`` always are, once its best direction is within ``vif_max`` (:func:`_determined`): the
#: form is kept, fitted on the directions the data determine at most ``vif_max`` times worse than an orthogonal
#: design, and a magnitude that needs a dropped direction is not reported ("not determined on this design":
#: :func:`_magnitudes` counts the directions outside the map as unseen), its variance and its bias gone from the
#: extended workpiece and its U95. False: only the best direction is judged against ``vif_max``. Session 27's blind
#: check, gen_a c_drift 7302: a creep common to every set-up fitted to per-set-up creeps of alternating sign along
#: a direction inflated 936 times (best 12.3) carried 12.8 um into the extended workpiece against baseline 1.17 +
#: U95 1.50; its tuning twins 1560, 1682, 1904, 1929, 1998 alike. Off (session 28, v328; diag27's "v3"): it mends
#: 7302, 1560, 1904, 1998 but not 1682 or 1929 (the common creep's kept directions still carry the wrong form's
#: bias), names nothing wrong on gen_a/gen_b 1000-1019, the simulator 4000-4049 or gen_c 200-239, but hedges
#: lobing_per_setup (a norm over every set-up's lobes loses its value with one direction: 6 of gen_a's 20 named ->
#: hedged) and throws away the drift a right form carries along such directions (gen_a thermal_drift 1000-1019:
#: mean extended error 0.250 -> 0.538 um); :data:`VIF_DROP_LEAST_INFLATION` (off too) was measured beside it.
#: docs/discovery-studies.md, "Session 28: directions inflated beyond vif_max". Re-measured in session 32 (vif32,
#: 685 tuning campaigns): the same costs to the digit (gen_a lobing_per_setup 1003 confident -> hedged, thermal_drift
#: 1004 0.372 -> 1.341 um), 0 right -> wrong, no check gained; it mends gen_a thermal_bending 8907 (1.485 against
#: 1.053 + 1.951), which :data:`HEDGED_SHIFT_CARRIED` holds instead. Still off.
VIF_DROP_BEYOND_MAX = False


#: Whether a cause whose best direction is within ``vif_max`` but whose worst determined direction is inflated beyond
#: it is refused as confounded (True), every direction of its columns judged against the model, not only the best
#: (:func:`_judge_trial`; the smallest principal angle's limit, ``1 / sin^2`` of it). The harsher sibling of
#: :data:`VIF_DROP_BEYOND_MAX` (which keeps the cause on its other directions). Session 32 (vif32): it mends gen_a
#: thermal_bending 8907 (a hedged part_change, best direction 4.7, worst 181, 6.9 um carried into the extended
#: workpiece: 0.694 against 1.053 + 1.289 with it) but refuses right forms, which are inflated beyond ``vif_max``
#: along some direction as a rule: 24 right -> wrong on gen_a/gen_b 1000-1004's 175 effect campaigns (thermal_drift,
#: probe_lobing, reversal, c_drift, lobing_per_setup, stylus_bending, part_change -> ``unexplained``), none wrong ->
#: right, no check gained. Off. docs/discovery-studies.md, "Session 32: a workpiece moved along an inflated direction".
VIF_WORST_REFUSED = False


#: Whether a named cause whose form has directions inflated beyond ``vif_max`` is named with doubt (``ambiguous``,
#: never refused: its name, estimate and workpiece stay) where its significance rests on those directions: beside the
#: final model its determined directions alone are not significant (:func:`_inflated_split`'s nested F test of them,
#: Bonferroni over the cause's own tries, at ``alpha_family``) and its inflated ones carry most of its fitted values
#: on the touches (at least :data:`INFLATED_MAGNITUDE_SHARE` of their norm). Such a term is read through a few
#: degrees of angle to the model: any effect with a small part along that sliver (another cause's, the model's
#: error) reads as the cause at an amplified size. Session 33 (vif33), gen_b stylus_bending 9702 (blind, 0.31
#: sigma): ``probe_lobing`` adopted confidently (F 4.67, p_adj 9.5e-4 over 22 tries), 4 of its 8 directions beyond
#: ``vif_max`` (worst 2163, 1.2 deg to the baseline) carrying 99 % of its fitted values (4.65 um RMS, 0.18 um on
#: the determined directions alone) and 75 % of what it explains; the determined four alone F 2.3, not
#: significant. Finer than :data:`VIF_WORST_REFUSED` (refuses whatever the signal): right forms are inflated along
#: some direction as a rule, and the data along it are rarely all they rest on. **On since session 33**: on the
#: tuning seeds (gen_a/gen_b 1000-1039 every effect, the simulator 4000-4019, gen_c 0-39) no name right -> wrong
#: or wrong -> right, no workpiece check moved; its price, 8 confident -> hedged right names, all gen_b thermal_drift
#: (1001, 1002, 1013, 1015, 1021, 1028, 1029, 1031: a warm-up read through a sliver beside the set-up offsets has
#: 9702's very split and differs from it only in strength, own p_adj 1e-8 and below against 9.5e-4).
#: docs/discovery-studies.md, "Session 33: a term nearly inside the baseline".
INFLATED_SIGNAL_HEDGED = True
#: :data:`INFLATED_SIGNAL_HEDGED`'s share of the term's fitted values (norm over the touches) its inflated
#: directions carry, at least.
INFLATED_MAGNITUDE_SHARE = 0.5


def _determined(Q: np.ndarray, E: np.ndarray, vif_max: float, pen: tuple | None = None, drop: bool | None = None):
    """The combinations of a cause's columns the data determine beside the model.

    ``pen`` ``(S, P)``: penalised columns of the model (an adopted penalised
    cause, rows used) and their penalty: the Gram matrix is then the one
    left beside their ridge fit (the Schur complement
    ``P_E^T (I - S_p (S_p^T S_p + P)^-1 S_p^T) P_E``, session 16), as the
    cause's coefficients are fitted beside them (:func:`_magnitudes`).

    Columns normalised, projected out of the model; eigen-decomposition of
    their Gram matrix. A direction with eigenvalue ``w`` has its coefficient
    inflated ``1 / w`` times over an orthogonal design (its variance
    inflation). Directions beyond ``1 / WEAK_SV^2`` are numerically inside
    the model (or the cause's other columns): left out, never extrapolated,
    and a magnitude that needs them is not reported. The cause is
    confounded, and refused, when even its best direction is inflated more
    than ``vif_max``; otherwise, with :data:`VIF_DROP_BEYOND_MAX`, its
    directions inflated more than ``vif_max`` are left out as the weak ones
    are (counted in ``weak``; ``vif_worst`` is then at most ``vif_max``).
    ``drop`` True / False: leave them out, or not, whatever :data:`VIF_DROP_BEYOND_MAX` says (None: as it says;
    :data:`HEDGED_SHIFT_READING`'s reading of the term on its determined directions).

    Returns
    -------
    M : (k, r) float
        Columns to use: ``E @ M`` (label coefficients ``c = M c'``); r = 0
        when the cause is confounded.
    vif : float
        Inflation of the best-determined direction.
    vif_worst : float
        Largest inflation among the directions kept.
    angle_deg : float
        Smallest principal angle between the cause's span and the model's.
    weak : int
        Directions left out.
    beyond : int
        Of them, those left out for their inflation beyond ``vif_max`` alone
        (:data:`VIF_DROP_BEYOND_MAX`; 0 without it).
    """
    nrm, nz, En, P, w, V, good = _directions_beside(Q, E, pen)
    M = V[:, good] / np.where(nz, nrm, 1.0)[:, None]
    Qe = orth(En)
    ang = _smallest_angle_deg(Q, Qe)
    best = float(1.0 / w.max()) if w.size and w.max() > 0 else np.inf
    worst = float(1.0 / w[good].min()) if good.any() else np.inf
    beyond = 0
    if best > vif_max:
        M = M[:, :0]
    elif (VIF_DROP_BEYOND_MAX if drop is None else drop) and worst > vif_max:
        # (a direction the data determine only vif_max+ times worse than an orthogonal design is treated as one
        # they do not determine: session 27's gen_a c_drift 7302, a direction inflated 936 times carried 12 um)
        beyond = int(np.sum(good & (w < 1.0 / vif_max)))
        good &= w >= 1.0 / vif_max
        M = V[:, good] / np.where(nz, nrm, 1.0)[:, None]
        worst = float(1.0 / w[good].min())
    return M, best, worst, ang, int((~good).sum()), beyond


def _directions_beside(Q: np.ndarray, E: np.ndarray, pen: tuple | None = None) -> tuple:
    """The eigen-directions of ``E``'s normalised columns beside the model basis ``Q`` (and the ridge ``pen``).

    Returns ``(nrm, nz, En, P, w, V, good)``: the columns' norms, which are non-zero, the normalised columns and
    their part beside ``Q``, the eigenvalues ``w`` and vectors ``V`` of their Gram matrix beside the model (:func:`_gram_beside`: the
    inflation of direction ``j`` is ``1 / w_j``), and the directions kept: not weak (``w >= WEAK_SV^2``) and
    without a part on a zero column. Shared by :func:`_determined` and :func:`_inflated_split`, which must
    see the same directions.
    """
    nrm = np.linalg.norm(E, axis=0)
    nz = nrm > 0
    En = E / np.where(nz, nrm, 1.0)
    P = En - Q @ (Q.T @ En)
    w, V = np.linalg.eigh(_gram_beside(P, Q, pen))
    good = (w >= WEAK_SV ** 2) & (np.abs(V[~nz]).max(axis=0, initial=0.0) < 1e-12)
    return nrm, nz, En, P, w, V, good


def _inflated_split(Q: np.ndarray, E: np.ndarray, r: np.ndarray, dof: int, vif_max: float,
                    pen: tuple | None = None) -> dict | None:
    """How a cause's fit beside the model splits between its directions within ``vif_max`` and those beyond it.

    ``E`` the cause's columns on the model's rows, ``Q`` the model's basis, ``r`` the residual beside it (the
    model's ``st.r``) on ``dof`` degrees of freedom, ``sigma^2 = r^T r / dof``. In the eigenbasis of the columns'
    Gram matrix beside the model (:func:`_determined`: ``w_j`` the eigenvalues of the normalised columns projected out of ``Q``, the directions'
    inflation ``1 / w_j``), the fit is a sum over directions: direction ``j`` explains ``b_j^2 / w_j`` of the
    residual (``b = V^T P^T r``) and carries the coefficient ``b_j / w_j``, whose standard error is
    ``sigma / sqrt(w_j)``. Its signal in sigmas is ``z_j = b_j / (sigma sqrt(w_j))``: what the data say along it,
    whatever its inflation; what the term's values on the touches carry along it is ``E_n V_j b_j / w_j``,
    amplified ``1 / sqrt(w_j)`` over the signal. Returns None where no kept direction is inflated beyond
    ``vif_max`` (or none is within it: the cause is then confounded), else

    - ``k_inflated``, ``k_determined``: the directions beyond and within ``vif_max`` (the weak ones,
      ``w < WEAK_SV^2``, left out as :func:`_determined` leaves them);
    - ``F_determined``, ``p_determined``: the nested F test of the determined directions alone (what they explain,
      ``sum b_j^2 / w_j`` over them, against the residual left by every kept direction, as the adoption's test
      of all the columns is made): is the cause seen where the data determine it?
    - ``chi2_inflated``, ``p_inflated``: ``sum z_j^2`` over the inflated directions and its chi-square tail on
      ``k_inflated`` degrees of freedom (is anything seen along them at all?);
    - ``ss_share_inflated``: their share of what the cause explains;
    - ``magnitude_share_inflated``: the share of the term's fitted values on the touches (their norm,
      ``|E c_inflated| / |E c|``) its inflated directions carry: near 1 when the fitted size is the inflated
      directions' amplification;
    - ``rms_um``, ``rms_determined_um``: the term's fitted values' RMS over the touches, with every direction and
      with the determined ones only.

    Beside penalised columns ``pen`` the Gram matrix is :func:`_gram_beside`'s (the ridge's Schur complement) and
    ``r`` the residual beside the ridge fit: the split is then that of the fit's first-order decomposition.
    """
    rss = float(r @ r)
    if E.shape[1] == 0 or not rss > 0:
        return None
    nrm, nz, En, P, w, V, good = _directions_beside(Q, E, pen)
    infl = good & (w < 1.0 / vif_max)
    det = good & ~infl
    if not infl.any() or not det.any():
        return None
    b = V.T @ (P.T @ r)
    ss = np.where(good, b ** 2 / np.where(good, w, 1.0), 0.0)  # (what each direction explains)
    z2 = ss / (rss / max(dof, 1))
    coef = np.where(good, b / np.where(good, w, 1.0), 0.0)
    f_inf = En @ (V[:, infl] @ coef[infl])
    f_det = En @ (V[:, det] @ coef[det])
    f_all = f_inf + f_det
    n_all = float(np.linalg.norm(f_all))
    chi_inf = float(z2[infl].sum())
    k_all, k_det = int(good.sum()), int(det.sum())
    s2 = max(rss - float(ss.sum()), 1e-300) / max(dof - k_all, 1)
    F_det = float(ss[det].sum()) / k_det / s2
    return {"k_inflated": int(infl.sum()), "k_determined": k_det,
            "F_determined": F_det, "p_determined": float(special.fdtrc(k_det, max(dof - k_all, 1), F_det)),
            "chi2_inflated": chi_inf, "p_inflated": float(stats.chi2.sf(chi_inf, int(infl.sum()))),
            "ss_share_inflated": chi_inf / float(z2.sum()) if z2.sum() > 0 else 0.0,
            "magnitude_share_inflated": float(np.linalg.norm(f_inf)) / n_all if n_all > 0 else 0.0,
            "rms_um": n_all / np.sqrt(len(r)) / UM,
            "rms_determined_um": float(np.linalg.norm(f_det)) / np.sqrt(len(r)) / UM}


def _matches(key: str, pattern: str) -> bool:
    """``*`` in a bound's key pattern stands for any text (brackets are literal)."""
    return _key_pattern(pattern).fullmatch(key) is not None


@functools.lru_cache(maxsize=256)
def _key_pattern(pattern: str) -> re.Pattern:
    """A bound's key pattern compiled once (:func:`_matches`)."""
    return re.compile(re.escape(pattern).replace(r"\*", ".*"))


def _made_on(seen, st: _State) -> tuple:
    """The diagnoses of ``seen`` ((state, diagnoses) pairs) made against the model ``st`` itself, else ().

    Itself: the same rows, dof, basis and residuals bit for bit (a model
    rebuilt from the same terms is), so every test they made is the test
    that would be made again.
    """
    for s, diag in seen:
        if s is st or (s.dof == st.dof and np.array_equal(s.rows, st.rows) and s.Q.shape == st.Q.shape
                       and np.array_equal(s.Q, st.Q) and np.array_equal(s.r, st.r)):
            return tuple(diag)
    return ()


def _family_ss(bl, diag, n, rss: float | None = None) -> dict:
    """Largest debiased sum of squares a smooth term explains, per covariate family: {family: (ss, covariate)}.

    ``rss``: the residual sum of squares the diagnoses were made against;
    given, a term that ties with the family's current one
    (:func:`core.diagnosis.tied`: the same span outside the model) does not
    displace it, so the first in ``diag``'s order (the registry's, for a
    tie) names the family whatever the rounding.
    """
    out: dict = {}
    lead: dict = {}
    for d in diag:
        cov = bl.covariate(d.covariate)
        if cov is None or not cov.family:
            continue
        ss = (d.explained_rms_um * UM) ** 2 * n
        cur = lead.get(cov.family)
        if rss is not None and cur is not None and d.test is not None and cur.test is not None \
                and tied(d.test.ss, d.test.k, cur.test.ss, cur.test.k, rss):
            continue
        if ss > out.get(cov.family, (-1.0, ""))[0]:
            out[cov.family] = (ss, d.covariate)
            lead[cov.family] = d
    return out


#: Covariate families whose smooth term nests a cause of the key's family on a
#: campaign's design, {cause family: (nesting families)}. A feature of the part
#: in one set-up sits at one place of the machine, so a per-feature-per-set-up
#: translation (the ``feature`` covariate) represents any machine error field
#: that is smooth over a feature's extent: a position cause's structure, its
#: imperfect form included, is inside it. Such a term explaining a few per cent
#: more than a few-parameter position cause is the same structure, fitted more
#: loosely, not structure that lives elsewhere; it refuses the cause at adoption
#: (step 4e) only when neither the cause's columns nor the best smooth of its
#: own family explain ``rival_share`` of it (the larger of the two: ``own`` in
#: :func:`_evaluate`, as against any other family). The converse does not hold (a smooth of positions does not represent one
#: feature changing per set-up), so a feature cause keeps the plain test.
#: A direction cause (the probe's lobes, fixed or per set-up; the reversal) is nested the same way where a feature
#: is probed over a narrow arc of azimuths in a set-up (gen_b's slot walls and blade): its offset there takes any
#: function of the azimuth, the lobes' form error (a six-lobe part beside the catalogue's harmonics 1-4) included.
#: Session 18: gen_b probe_lobing 1016 and lobing_per_setup 1023, 1080, 1099 read `unexplained` by step 4e at their
#: own size and still at 10 sigmas (the same campaign scaled), a refusal of form, not of power. With the entry, gen_b
#: 1000-1029 every effect: 3 wrong -> right (probe_lobing 1016, reversal 1008, lobing_per_setup 1023, all ambiguous),
#: gen_a 1000-1029: 1 (reversal 1016), gen_b 1900-1939: 1 (lobing_per_setup 1905); nothing else changed cause or
#: confidence, false alarms 0, confident misnamings and workpiece checks equal; the simulator 4000-4049 lost one
#: (part_change 4037, 1.37 sigma: the lobes per set-up now win round one, ambiguous) (docs/discovery.md).
#: Session 19: where the feature term decides a position cause's refusal, the family's own figure is also taken by
#: the fine position smooth (:func:`_fine_position`; gen_a nonrigid 1048 named), and step 5 does not drop a cause
#: as redundant beside an unnamed smooth of a family that nests the cause's (gen_a reversal 1054, nonrigid 1047).
NESTING_FAMILIES = {"position": ("feature",), "direction": ("feature",)}


#: Largest total degree ``i + j`` of the products ``P_i(xs) P_j(ys)`` (i, j >= 1) of the position family's fine
#: smooth (:func:`_fine_position`), against which step 4e measures the family's own share of a nesting term.
FINE_POSITION_DEGREE = 6
#: Whether step 4e credits a position cause with the fine smooth's figure only where the cause itself explains
#: ``rival_share`` of its family's best (coarse) smooth (session 21, tried: gen_a local_scale_defect 1934 against
#: gen_a nonrigid 1048).
FINE_POSITION_NEEDS_SHARE = False


def _fine_position_credited(ss_n: float, ss_family: float, settings) -> bool:
    """Whether step 4e takes the position family's fine smooth as a position cause's own figure against a nesting
    term: always (the rule of session 19), or with :data:`FINE_POSITION_NEEDS_SHARE` only where the cause explains
    ``rival_share`` of its family's best coarse smooth ``ss_family`` (the cause holds the family's structure; the fine
    smooth refines it)."""
    return not FINE_POSITION_NEEDS_SHARE or ss_n >= settings.rival_share * ss_family


def _fine_position(bl) -> np.ndarray:
    """(n, k) the position family's fine smooth: ``-n_x B`` and ``-n_y B``, ``B`` the Legendre products
    ``P_i(xs) P_j(ys)``, i, j >= 1, i + j <= :data:`FINE_POSITION_DEGREE` (the diagnosis' ``xy`` term at a finer
    resolution; its separable part is the baseline's error map).

    Why (step 4e, :data:`NESTING_FAMILIES`): the feature-per-set-up term nests a position cause at the spacing of
    the features, far finer than the diagnosis' ``xy`` term (degree 4: a deflection changing sign about once along
    each stroke). A machine field that changes sign two or three times along a stroke (gen_a nonrigid's couplings,
    half-waves 100-250 mm over extents up to 276 mm) is position structure the ``xy`` term holds in part, and the
    feature term holds whole: compared with the coarse term alone, the finer the field, the more it reads as
    structure of the features. Where the feature term decides a position cause's refusal, the family's own figure is
    also taken at this degree, as the product a P-spline of position would be: what a position cause's form cannot
    hold then shows in the later gates (its held-out gain, the rival check against its own covariate's smooth, the
    counter-explanation) and in what is left unexplained, not as a structure of the part.
    """
    d = bl.data
    from numpy.polynomial import legendre as leg

    eye = np.eye(FINE_POSITION_DEGREE)
    P = [leg.legval(d.xs, eye[i]) for i in range(FINE_POSITION_DEGREE)]
    R = [leg.legval(d.ys, eye[j]) for j in range(FINE_POSITION_DEGREE)]
    B = np.column_stack([P[i] * R[j] for i in range(1, FINE_POSITION_DEGREE) for j in range(1, FINE_POSITION_DEGREE)
                         if i + j <= FINE_POSITION_DEGREE])
    return np.hstack([-d.nx[:, None] * B, -d.ny[:, None] * B])


def _fine_position_of(bl) -> np.ndarray:
    """:func:`_fine_position` of the campaign, built once and kept on its data (:func:`core.memo.kept_on`; it
    goes with them), read-only as the run's other shared alternatives are (``scan_trials``): step 4e takes it in
    each round where it decides a position cause's refusal (gen_a nonrigid 1048: twice)."""
    def make():
        F = _fine_position(bl)
        F.flags.writeable = False
        return F
    return kept_on(bl.data, "_fine_position", make)


def _spans_exactly(bl, covariate: str, E: np.ndarray, rows) -> bool:
    """Whether a categorical covariate's term spans the columns ``E`` (rows ``rows``) exactly on this design.

    A categorical term acting through the scalar mode (mode 0, a column of
    ones on a planar baseline) holds every column that is constant within
    each of its categories: on a design that probes each feature of a set-up
    at one approach elevation (gen_b), the feature-per-set-up term is any
    function of the elevation, a stylus's bending included, and its form
    error besides. Such a term nests the cause as it nests a position cause
    (:data:`NESTING_FAMILIES`), measured here on the design rather than
    assumed for a family.
    """
    cov = bl.covariate(covariate)
    if (cov is None or cov.kind != "categorical" or 0 not in cov.modes or E.ndim != 2 or E.shape[1] == 0
            or len(E) == 0 or not np.all(np.isfinite(E))):  # (a NaN column is no function of anything)
        return False
    m0 = bl.modes[rows, 0]
    if not np.all(m0 == m0[0]) or m0[0] == 0:
        return False
    codes = np.unique(np.asarray(cov.values)[rows], return_inverse=True)[1]
    return _constant_within(codes, E)


class _Trial(NamedTuple):
    """One trial of a cause's scan against the current model (:func:`_evaluate`).

    ``test``: the F test of the trial's own columns when made once for it
    (a scan of one trial, or a grown layout), else None; ``order``: (scan,
    trial) index in the catalogue's order; ``cols``: the grown layout's
    columns (:func:`_grow_layout`), None when the trial is the scan's own
    (built by the caller for the chosen trial only).
    """

    p: float
    F: float
    k: int
    scan: Any
    index: int
    test: Any
    ss: float
    order: tuple
    cols: Any = None


def _better_trial(cand: _Trial, best: _Trial, rss: float) -> bool:
    """Whether trial ``cand`` beats ``best`` against one model.

    The smaller p-value, then the larger F; two trials that tie
    (:func:`core.diagnosis.tied`: the same span outside the model, so equal
    but for rounding, e.g. a campaign-long C drift and one within each
    set-up beside the set-ups' own angles) go to the one first in the
    catalogue's order (its scans', then the trials' index in the scan).
    """
    if tied(cand.ss, cand.k, best.ss, best.k, rss):
        return cand.order < best.order
    return (cand.p, -cand.F) < (best.p, -best.F)


def _grow_layout(own: _Trial, scans, si: int, rows, bl, st: _State, folds: Folds, terms, settings) -> _Trial:
    """Trial ``own`` of ``scans[si]`` grown along the richer scans that follow and nest it (``extends_previous``).

    Part_change's walls turning beside their shifting, then bowing as well:
    each richer layout is taken when its new columns are significant beyond
    the layout taken so far at ``alpha_family`` (where the turns were not
    taken, the bows are tested with the turns, both new) and it lowers the
    held-out mean square below that same layout; its own F test is then the
    trial's. Each layout is one of the cause's trials in its Bonferroni
    count (:func:`core.causes.part_change_scans`): the trial compared with
    the others is the layout grown here, chosen by its own p-value. Returns
    the grown trial with its layout's columns in ``cols`` (``own`` as it is
    when nothing follows the scan: built by the caller for the chosen trial
    only).
    """
    richer = list(itertools.takewhile(lambda r: r.infos[0].get("extends_previous"), scans[si + 1:]))
    if not richer:
        return own
    ext_test, ext_cols = own.test, own.scan.build([own.index])[0]
    cur_cols, held_cur = ext_cols, None
    for rich in richer:
        rich_cols = rich.build([0])[0]
        if ext_test is None:  # (the plain trial's test, made once when its scan's batch did not make it)
            ext_test = nested_f_batch(ext_cols[None, rows], st.Q, st.r, st.rss, st.dof)
        t_f = nested_f_batch(rich_cols[None, rows], st.Q, st.r, st.rss, st.dof)
        k_x = int(t_f[1][0]) - int(ext_test[1][0])
        dof_f = st.dof - int(t_f[1][0])
        if k_x <= 0 or dof_f <= 0:
            continue
        F_x = (float(t_f[0][0]) - float(ext_test[0][0])) / k_x / ((st.rss - float(t_f[0][0])) / dof_f)
        if float(stats.f.sf(F_x, k_x, dof_f)) >= settings.alpha_family:
            continue
        held = [folds.mse(bl.y[rows], np.hstack([_stack(terms, rows), C[rows]]) if terms else C[rows],
                          _penalty_beside(terms, C.shape[1]))
                for C in ((cur_cols,) if held_cur is None else ()) + (rich_cols,)]
        held_cur = held[0] if held_cur is None else held_cur
        if held[-1] < held_cur:
            own = _Trial(float(t_f[3][0]), float(t_f[2][0]), int(t_f[1][0]), rich, 0, t_f, float(t_f[0][0]), own.order)
            cur_cols, held_cur = rich_cols, held[-1]
            ext_test, ext_cols = t_f, rich_cols  # the next richer scan is tested beyond this layout
    return own._replace(cols=cur_cols)


def _trials(sc, idx, st: _State):
    """The scan's trials ``idx`` (T, n, k): kept sparse (:class:`core.diagnosis.SparseTrials`) where the scan can
    and the model's basis is a long log's (its test then takes their Gram matrices), else dense."""
    return sc.build_sparse(idx) if sc.build_sparse is not None and isinstance(st.Q, Basis) else sc.build(idx)


#: A long log's shortlisted dense trials are built and tested this many bytes of columns at a time (at least one
#: trial): :func:`_test_trials`.
TRIALS_BLOCK_BYTES = 32 << 20


#: Whether :func:`_evaluate` answers "not significant" at once where every scan's best trial (grown) has its p-value
#: times the Bonferroni count at 1 or more: :func:`_time_forms_chosen` only drops trials and :func:`_judge_trial`
#: refines a trial only below ``p tries = 1`` and counts a path only below ``alpha_family``, so its answer is then
#: ``p = 1`` over the same count whichever trial it is given: the same words (session 26, exact: the demo's
#: part_change, p 0.16-0.23 over 90 tries in each of its three rounds, chose between its time forms, 1.6 ms a round,
#: to be refused so). False: the time forms chosen and the best trial judged, as before.
NOT_SIGNIFICANT_AT_ONCE = True


def _test_trials(sc, idx, st: _State):
    """:func:`nested_f_batch` of the scan's trials ``idx`` on the model's rows.

    Against a long log's basis (``st.Q`` a :class:`core.lsq.Basis`) dense
    trials are built and tested a group of trials at a time (about
    :data:`TRIALS_BLOCK_BYTES` of columns, at least one trial): that branch
    tests each trial on its own (its Gram matrices, then a batched
    eigen-decomposition), so the groups' results side by side are the
    whole batch's bit for bit. Eight ripple trials over 1e6 rows were 256 MB
    of columns, built through as many again of temporaries.
    """
    rows = st.rows
    n, k = len(rows), max(len(sc.labels), 1)
    g = max(1, TRIALS_BLOCK_BYTES // (8 * n * k))
    if not isinstance(st.Q, Basis) or sc.build_sparse is not None or len(idx) <= g:
        return nested_f_batch(take_rows(_trials(sc, idx, st), rows, 1), st.Q, st.r, st.rss, st.dof)
    parts = [nested_f_batch(take_rows(sc.build(idx[a:a + g]), rows, 1), st.Q, st.r, st.rss, st.dof)
             for a in range(0, len(idx), g)]
    return tuple(np.concatenate([p[i] for p in parts]) for i in range(4))


def _evaluate(cause, scans, tries, bl, st: _State, folds: Folds, terms, cv_cur, sigma, settings,
              families=None, scan_tries: float | None = None) -> dict:
    """One cause against the current model: the tests of adoption (module docstring 4a-e).

    ``tries``: the Bonferroni factor (the cause's scans' count of
    independent trials, ``scan_tries``, times the causes tried); where
    the scans are paths (:attr:`core.causes.Scan.path`) and the candidate
    is significant, the scans' count is raised to :func:`_path_tries`'s
    where that is larger. Scans marked ``extends_previous`` follow the scan
    they nest (part_change's walls shifting, then turning, then bowing) and
    are no trials: each is tested beyond the layout taken so far (F test at
    ``alpha_family`` of all its columns that layout lacks) and taken where
    it also lowers the held-out mean square below that same layout.
    """
    rows = st.rows
    best = None
    owns = []  # each scan's best trial (grown)
    for si, sc in enumerate(scans):
        if sc.infos[0].get("extends_previous"):  # tested only beyond its plainer trial, in _grow_layout
            continue
        if sc.size <= settings.shortlist or sc.exhaustive:
            idx = np.arange(sc.size)
        elif sc.score is not None:
            idx = np.argsort(-sc.score(st.r, rows))[:settings.shortlist]
        else:
            idx = _coarse(sc.build(np.arange(sc.size))[:, rows, :], st.r, settings.shortlist)
        test = _test_trials(sc, idx, st)
        ss, k, F, p = test
        own = None  # the scan's best trial
        for j in np.flatnonzero(k > 0):
            cand = _Trial(float(p[j]), float(F[j]), int(k[j]), sc, int(idx[j]), test if len(idx) == 1 else None,
                          float(ss[j]), (si, int(idx[j])))
            if own is None or _better_trial(cand, own, st.rss):
                # a scan of one trial: its test is the F test of the trial's own columns
                own = cand
        if own is None:
            continue
        # the trial grown along the richer scans that nest it (each feature's walls turning, then bowing), before
        # the trials are compared: a wall that bows has a weak plain trial (gen_a part_change 1503: the bowing
        # wall's shift p = 0.068 behind another wall's 0.0029; its bow explained 16.0 of the 18.8 um^2 left)
        own = _grow_layout(own, scans, si, rows, bl, st, folds, terms, settings)
        owns.append(own)
    if owns and NOT_SIGNIFICANT_AT_ONCE and settings.alpha_family <= 1.0 and all(o.p * tries >= 1.0 for o in owns):
        # every trial's p times the count at 1 or more: _judge_trial's answer whichever the time forms keep (they only
        # drop trials) and whichever is best (no refinement below p tries = 1, no path count above alpha_family; a
        # family level above 1, which no campaign is run at, would count a path there and pass p = 1)
        return {"reason": f"not significant ({fmt_p(1.0)} after Bonferroni over {tries:.0f} tries)"}
    owns = _time_forms_chosen(owns, rows, st, settings, bl)
    for own in owns:
        if best is None or _better_trial(own, best, st.rss):
            best = own
    if best is None:
        return {"reason": "no columns outside the model"}
    out = _judge_trial(cause, best, scans, tries, bl, st, folds, terms, cv_cur, sigma, settings, families, scan_tries)

    def other_forms(chosen, judged=()):
        """The cause's other significant forms (those not ``chosen`` nor already ``judged``), in the same order, each
        judged by every test; the results of those that pass (:data:`ENTRANT_FORM_HELD_OUT`, made by the round
        only where the chosen form lost it)."""
        def judge(any_covariate: bool = False) -> list:
            # (any_covariate: every other form, whatever its covariate: FORM_SHIFT_CARRIED's readings)
            res = [_judge_trial(cause, o, scans, tries, bl, st, folds, terms, cv_cur, sigma, settings, families,
                                scan_tries)
                   for o in sorted((o for o in owns if o is not chosen and all(o is not j for j in judged)
                                    and o.p * tries < settings.alpha_family
                                    and (any_covariate or not ENTRANT_FORM_SAME_COVARIATE
                                         or o.scan.covariate == chosen.scan.covariate)),
                                   key=functools.cmp_to_key(lambda a, b: -1 if _better_trial(a, b, st.rss)
                                                            else (1 if _better_trial(b, a, st.rss) else 0)))]
            return [r for r in res if not r.get("reason")]
        return judge

    if not out.get("reason"):
        if (VIF_DROP_LEAST_INFLATION or VIF_FORM_BY_GAIN) and _beyond_vif_max(out["term"].evidence, settings):
            return _least_inflated_form(out, best, owns, other_forms, cause, scans, tries, bl, st, folds, terms,
                                        cv_cur, sigma, settings, families, scan_tries)
        out["other_forms"] = other_forms(best)
    confounded_step = CONFOUNDED_FALLBACK or CONFOUNDED_FALLBACK_LEAST_INFLATION  # (the variant opens the step)
    if not out.get("form_refused") or not HELD_OUT_FALLBACK or (
            out.get("form_refused") == "confounded" and not confounded_step):
        return out
    # the trial of smallest p does not predict held-out data, or the data do not determine it beside the model: the
    # cause's other forms that are significant under the same count, next in the same order, each judged by every
    # test (gen_a c_drift 1135: a quadratic over the campaign, p 5.1e-112, held-out gain -0.028 um^2, beside the
    # per-set-up rates, p 2.3e-110, gain 2.52; gen_b c_drift 1187: the quadratic over the campaign confounded with the
    # set-ups' own angles, inflation 208, beside the per-set-up rates, p 1.8e-81, gain 0.30)
    rest = sorted((o for o in owns if o is not best and o.p * tries < settings.alpha_family),
                  key=functools.cmp_to_key(lambda a, b: -1 if _better_trial(a, b, st.rss)
                                           else (1 if _better_trial(b, a, st.rss) else 0)))
    by_vif = CONFOUNDED_FALLBACK_LEAST_INFLATION
    if out.get("form_refused") == "confounded" and (CONFOUNDED_FALLBACK_BY_GAIN or CONFOUNDED_FALLBACK_SAME_COVARIATE
                                                    or by_vif):
        # session 25 (conf25): the confounded step's variants, each behind its own switch
        if CONFOUNDED_FALLBACK_SAME_COVARIATE:
            rest = [o for o in rest if o.scan.covariate == best.scan.covariate]
        if CONFOUNDED_FALLBACK_BY_GAIN or by_vif:
            passed = []
            for alt in rest:
                res = _judge_trial(cause, alt, scans, tries, bl, st, folds, terms, cv_cur, sigma, settings, families,
                                   scan_tries)
                if not res.get("reason"):
                    passed.append((alt, res))
            if not passed:
                return out
            # the least variance inflation beside the model, else the largest held-out gain; ties by the order
            alt, res = min(passed, key=lambda ar: ar[1]["term"].evidence["vif"] if by_vif else ar[1]["cv"])
            res["term"].evidence["held_out_fallback"] = (
                f"the form of smallest p ({_layout_text(best.scan.infos[best.index])}) {out['reason']}; of the "
                f"{len(passed)} other forms that pass, the one of "
                f"{'least variance inflation' if by_vif else 'largest held-out gain'}")
            if CONFOUNDED_SELECTION_COUNTED:
                # (the forms the step chose among, the refused one with them: _fallback_short's count, as for the
                # held-out fallback below)
                ev_ = res["term"].evidence
                ev_["held_out_fallback_forms"] = len(rest) + 1
                ev_["held_out_fallback_gain_um2"] = ev_.get("cv_gain_um2")
                ev_["held_out_fallback_materiality_um2"] = ev_.get("materiality_um2")
                ev_["held_out_fallback_step"] = "confounded"
            res["other_forms"] = other_forms(alt, [o for o in rest if o is not alt] + [best])
            return res
    for alt in rest:
        res = _judge_trial(cause, alt, scans, tries, bl, st, folds, terms, cv_cur, sigma, settings, families,
                           scan_tries)
        if not res.get("reason"):
            res["term"].evidence["held_out_fallback"] = (
                f"the form of smallest p ({_layout_text(best.scan.infos[best.index])}) {out['reason']}")
            # (FALLBACK_SELECTION_COUNTED: the forms the fallback chose among, the refused one with them)
            res["term"].evidence["held_out_fallback_forms"] = len(rest) + 1
            res["term"].evidence["held_out_fallback_gain_um2"] = res["term"].evidence.get("cv_gain_um2")
            res["term"].evidence["held_out_fallback_materiality_um2"] = res["term"].evidence.get("materiality_um2")
            if (VIF_DROP_LEAST_INFLATION or VIF_FORM_BY_GAIN) and _beyond_vif_max(res["term"].evidence, settings):
                return _least_inflated_form(res, alt, [o for o in owns if o is not best], other_forms, cause, scans,
                                            tries, bl, st, folds, terms, cv_cur, sigma, settings, families,
                                            scan_tries, judged=[best])
            res["other_forms"] = other_forms(alt, rest[:rest.index(alt)] + [best])
            return res
    return out


#: Whether a form that passes every test but has a direction inflated beyond ``vif_max`` (kept, or left out by
#: :data:`VIF_DROP_BEYOND_MAX`) is weighed against the cause's other significant forms that pass every test, and the
#: one of least best-direction inflation beside the model taken (True; :func:`_least_inflated_form`): the choice
#: :data:`CONFOUNDED_FALLBACK_LEAST_INFLATION` makes for a confounded form, for a form confounded in part. Off
#: (session 28, v328; "v5"): it mends gen_a c_drift 7302 (session 27's blind failure, 12.8 -> 0.61 um) and its twins
#: 1560, 1682, 1904, 1929, 1998 (the per-set-up rates, inflation ~3, taken for a common creep), but makes a failure of
#: its own at gen_a c_drift 1791 (the per-set-up rates, best inflation 1.15, worst 4,771, given up for the creep after
#: each indexing at 1.13: 0.584 -> 1.960 um against 0.644 + U95 0.659; best inflations near 1 do not rank forms) and
#: moves four campaigns right -> wrong (gen_b thermal_drift 1001, 1006, gen_a c_drift 1076 below one sigma; gen_c
#: clamp_creep 223, 1.25 sigma, `part_change` -> `thermal_drift?`) against two wrong -> right. Its step is reached on
#: a quarter to a third of the campaigns (an inflation beyond 100 somewhere in a passing form is common).
#: docs/discovery-studies.md, "Session 28: directions inflated beyond vif_max".
VIF_DROP_LEAST_INFLATION = False
#: Whether the step :data:`VIF_DROP_LEAST_INFLATION` opens (a passing form with a direction inflated beyond
#: ``vif_max``, weighed against the cause's other passing forms) takes the form of the largest held-out gain, the
#: lowest held-out mean square (True; ties: the adopted form, then the order by p) rather than the least inflated.
#: Off (session 28, form28, "v7", measured with :data:`VIF_DROP_BEYOND_MAX` on as v328 proposed): it mends all seven
#: gen_a c_drift failures by the estimate (7302 12.815 -> 0.612 um, 1791 kept within its check where the least
#: inflated form fails it) but carries the drop's costs (7 gen_a campaigns named -> hedged, gen_a's mean extended error
#: +0.057 um) and moves gen_a c_drift 1076 (0.85 sigma) and gen_b thermal_drift 1016 (2.74 sigma) right -> wrong;
#: :data:`FORM_SHIFT_CARRIED` is on instead. docs/discovery-studies.md, "Session 28: the workpiece not determined between a
#: cause's forms". Measured alone too (session 29, form29, "v9": the drop off, :data:`FORM_SHIFT_CARRIED` on, the shift
#: then read against the chosen form's other forms): it mends five of the seven by the estimate (7302 12.815 -> 0.612
#: um, U95 12.483 -> 0.671; 1682, 1904, 1929, 1998) and costs none of the drop's hedging on lobing_per_setup, but the
#: names session 28 put on the drop move again, so they were the choice's: gen_a c_drift 1076 (0.85 sigma) and gen_b
#: thermal_drift 1016 (2.74 sigma, confident) -> ``unexplained``, and gen_a thermal_drift 1086 (1.03 sigma) too; it
#: hedges gen_a thermal_drift 1110, 1194 and gen_b 1019 (0.137 -> 0.829 um) and swaps gen_a thermal_drift's warm-up
#: on 73 of 200 campaigns for a mean extended error 0.249 -> 0.256 um: still off (the forms it takes are mostly
#: inflated as well; :data:`FORM_BY_GAIN_DETERMINED_ONLY` is the lead).
#: docs/discovery-studies.md, "Session 29: the form of largest held-out gain without the drop".
#: **On since session 30 (form30), with :data:`FORM_BY_GAIN_DETERMINED_ONLY` ("v9b")**: measured where session 29 had
#: not (see that constant), the pair moves no confident name and no workpiece check anywhere.
VIF_FORM_BY_GAIN = True
#: With :data:`VIF_FORM_BY_GAIN`: another form is taken only where it is itself within ``vif_max`` in every direction
#: (True; the adopted form is kept otherwise). Off (session 29, form29, "v9b", rerun where v9's step was reached): it
#: mends the same five of the seven and moves no record on gen_b's 360 nor gen_a thermal_drift's mean, but leaves
#: gen_a c_drift 1076 right -> wrong (0.85 sigma) and hedges c_drift 1139 (3.13 sigma) and thermal_drift 1110 (2.74).
#: docs/discovery-studies.md, "Session 29: the form of largest held-out gain without the drop".
#: **On since session 30 (form30)**, with :data:`VIF_FORM_BY_GAIN`, after measuring it where session 29 had not (gen_a
#: and gen_b c_drift and thermal_drift 1200-1399 (gen_a 1200-1599), the simulator's c_drift and thermal_drift
#: 4000-4099, gen_c c_drift and thermal_drift 200-399, every effect of gen_a/gen_b 1000-1009, the simulator 4000-4019
#: and gen_c 200-219, none gen_a/gen_b 1000-1049): no false alarm, no workpiece check lost, no confident name lost;
#: the names it loses are below one sigma (gen_a c_drift 1076 0.85, gen_b c_drift 1393 0.34 -> ``unexplained``,
#: where the check counts no miss) and its five hedges of a right name (gen_a c_drift 1139, 1397 at 3.13 sigma, 1421
#: at 4.35; thermal_drift 1110 at 2.74, 1580 at 4.02) say what the truth holds: an unnamed smooth of the cause's own covariate earns a material held-out gain
#: beside the determined form (per-set-up creeps of either sign beside a creep common to the set-ups; a warm-up of
#: two time constants beside one), its real workpiece shift carried in the U95. docs/discovery-studies.md, "Session 30: v9b
#: measured where it was not".
FORM_BY_GAIN_DETERMINED_ONLY = True
#: With :data:`VIF_FORM_BY_GAIN`: another form is taken only where its held-out mean square lies below the adopted
#: form's by the round's materiality margin ``(material_sigma * sigma)^2`` (True). Off (session 29, form29, "v9c":
#: 1929 left unmended, gen_a c_drift 1076 right -> wrong, thermal_drift 1110 and 1194 hedged).
FORM_BY_GAIN_MATERIAL = False


def _beyond_vif_max(ev: dict, settings) -> bool:
    """Whether a passing form has a direction inflated beyond ``vif_max`` (left out by :data:`VIF_DROP_BEYOND_MAX`,
    or kept without it)."""
    return bool(ev.get("directions_beyond_vif_max")) or ev.get("max_vif", 0.0) > settings.vif_max


def _least_inflated_form(out, chosen, owns, other_forms, cause, scans, tries, bl, st, folds, terms, cv_cur, sigma,
                         settings, families, scan_tries, judged=()):
    """Of ``chosen``'s result ``out`` (passing, with directions left out beyond ``vif_max``) and the cause's other
    significant forms in ``owns`` that pass every test, the one of least best-direction inflation beside the model
    (ties: ``chosen``, then the order by p), with its ``other_forms`` (:data:`VIF_DROP_LEAST_INFLATION`); with
    :data:`VIF_FORM_BY_GAIN` (on since session 30, with :data:`FORM_BY_GAIN_DETERMINED_ONLY`) the one of lowest
    held-out mean square instead, among ``chosen`` and the others within ``vif_max`` in every direction."""
    rest = sorted((o for o in owns if o is not chosen and o.p * tries < settings.alpha_family),
                  key=functools.cmp_to_key(lambda a, b: -1 if _better_trial(a, b, st.rss)
                                           else (1 if _better_trial(b, a, st.rss) else 0)))
    passed, failed = [(chosen, out)], []
    for alt in rest:
        res = _judge_trial(cause, alt, scans, tries, bl, st, folds, terms, cv_cur, sigma, settings, families,
                           scan_tries)
        if res.get("reason"):
            failed.append(alt)
        else:
            passed.append((alt, res))
    if VIF_FORM_BY_GAIN and (FORM_BY_GAIN_DETERMINED_ONLY or FORM_BY_GAIN_MATERIAL):
        # (session 29's variants: an alternative only where it is within vif_max in every direction, and / or where
        # its held-out mean square lies below the adopted form's by the round's materiality margin)
        margin = settings.material_sigma ** 2 * sigma ** 2 if FORM_BY_GAIN_MATERIAL else 0.0
        passed = [(a, r) for a, r in passed if a is chosen or (
            (not FORM_BY_GAIN_DETERMINED_ONLY or not _beyond_vif_max(r["term"].evidence, settings))
            and r["cv"] < out["cv"] - margin)]
    alt, res = min(passed, key=lambda ar: ar[1]["cv"] if VIF_FORM_BY_GAIN else ar[1]["term"].evidence["vif"])
    if alt is not chosen:
        res["term"].evidence["least_inflated_form"] = (
            f"the form ({_layout_text(chosen.scan.infos[chosen.index])}) has directions inflated beyond "
            f"{settings.vif_max:g} (best inflation {out['term'].evidence['vif']:.3g}); of the {len(passed)} "
            f"forms that pass, the one of "
            f"{'largest held-out gain' if VIF_FORM_BY_GAIN else 'least variance inflation'}")
    # (the forms that failed, and the one set aside, are no entrants: ENTRANT_FORM_HELD_OUT)
    res["other_forms"] = other_forms(alt, failed + ([chosen] if alt is not chosen else []) + list(judged))
    return res


def _time_forms_chosen(owns: list, rows, st: _State, settings, bl) -> list:
    """Each feature's trial in one time form (:func:`core.causes.part_change_times`): the step per set-up where the
    data ask for it, else the continuous form (the form before there were two).

    A scan's trial whose layout names a ``time_form`` other than ``continuous`` (part_change's step per set-up)
    is kept beside the continuous trial of the same feature only where its columns are significant beyond the
    continuous trial's (F test at ``alpha_family``) and the continuous trial's are not beyond its own: the steps
    explain what a change linear in time cannot, and no change within a set-up is seen. Where the continuous
    columns are significant beyond the steps (the part changes while it is measured: gen_a's and gen_b's
    ``1 - exp(-t / tau)``) or neither beyond the other (the design cannot tell them), the continuous trial is
    kept; where the steps are chosen, the continuous trial is dropped. Either way one trial per feature is
    compared with the others (each form still counted in the Bonferroni factor).

    A step per set-up is also a one-off event's form where the set-ups' levels are one jump: a stylus picking up
    material and wiped before a set-up, a clamp giving once between two set-ups (gen_b stylus_pickup 1012, out of
    the catalogue: its slot's steps chosen, then named part_change beside a thermal drift, its extended workpiece
    7.71 um off against the baseline's 1.72, U95 2.80). So the steps are kept only where they are also significant
    beyond the same layout stepping once, at the one set-up change where that explains most
    (:func:`_steps_beyond_one_off`, :data:`STEP_BEYOND_ONE_OFF`): a part that changes at every set-up (the
    simulator's wall grown by a step per set-up, four set-ups) against an event at one set-up change. On two
    set-ups the two are one column set: the continuous form is kept.
    """
    cont = {}
    for o in owns:
        info = o.scan.infos[o.index]
        if info.get("time_form") == "continuous":
            cont[info.get("feature")] = o
    if not cont:
        return owns
    drop = set()
    level = dict(causes_mod.part_change_times(bl)).get("per_setup")
    for o in owns:
        info = o.scan.infos[o.index]
        form = info.get("time_form")
        if form is None or form == "continuous":
            continue
        c = cont.get(info.get("feature"))
        if c is None:
            continue
        cs = o.cols if o.cols is not None else o.scan.build([o.index])[0]
        cc = c.cols if c.cols is not None else c.scan.build([c.index])[0]
        choice = _forms_gram_choice if _forms_by_gram(st, rows, cs, cc) else _forms_dense_choice
        drop.add(id(c) if choice(cs, cc, level, rows, st, settings)[0] else id(o))
    return [o for o in owns if id(o) not in drop]


def _forms_dense_choice(cs, cc, level, rows, st: _State, settings) -> tuple:
    """:func:`_time_forms_chosen`'s choice for one feature, the columns formed on the model's rows: ``(steps,
    (p_steps, p_cont, p_once))``, ``steps`` True for the steps ``cs``, False for the continuous ``cc`` (both (N, k)
    over the baseline's rows, dense or sparse); ``p_once`` (:func:`_one_off_p`) None where not needed."""
    cs, cc = (x.toarray()[rows] if sps.issparse(x) else np.asarray(x)[rows] for x in (cs, cc))
    # the steps beyond the continuous form, the continuous form beyond the steps (_beyond's F test, unadjusted)
    p_steps = _beyond(st, new_basis(st.Q, cc), cs, st.sigma, 1.0, settings)[1]
    p_cont = _beyond(st, new_basis(st.Q, cs), cc, st.sigma, 1.0, settings)[1]
    if not (p_steps < settings.alpha_family and p_cont >= settings.alpha_family):
        return False, (p_steps, p_cont, None)
    if not STEP_BEYOND_ONE_OFF:
        return True, (p_steps, p_cont, None)
    p_once = _one_off_p(cs, level, rows, st, settings)
    return p_once < settings.alpha_family, (p_steps, p_cont, p_once)


#: :func:`_time_forms_chosen` on a long log (the model's basis a :class:`core.lsq.Basis`) whose feature's columns on
#: the model's rows are more than this many bytes (either form's) tests the forms :data:`FORMS_BLOCK_ROWS` rows at
#: a time (:func:`_forms_gram_choice`: the columns projected a block at a time, their Gram matrices summed), not
#: from the columns formed dense: at the bench's 1e6 rows the dense tests formed the columns, their projections and the model's basis
#: stacked with the alternative's (a (1e6, 8) copy of 61 MiB refused under the 2,048 MB limit, session 21), and the
#: one-off steps' trials at every set-up change at once (99 x 1e6 x 4 doubles, 3.2 GB, had the steps been
#: significant). The same tests to rounding (tests/core/test_forms_gram.py); below it, the dense tests as before.
FORMS_DENSE_BYTES = 16 << 20
#: Rows a block of :class:`_Projected`'s and :func:`_forms_gram`'s sums (8192 x 8 columns: 512 KiB).
FORMS_BLOCK_ROWS = 8192


def _forms_by_gram(st: _State, rows, *cols) -> bool:
    """Whether :func:`_time_forms_chosen` tests the forms a block of rows at a time (:data:`FORMS_DENSE_BYTES`)."""
    return isinstance(st.Q, Basis) and 8 * len(rows) * max(x.shape[1] for x in cols) > FORMS_DENSE_BYTES


def _rows_reader(x, rows):
    """``pos -> x[rows[pos]]`` dense (``x`` (N, k) dense or sparse, ``rows`` the model's rows)."""
    def read(pos):
        b = x[rows[pos]]
        return b.toarray() if sps.issparse(b) else np.asarray(b, float)
    return read


def _forms_gram(st: _State, readers, pos_all=None) -> tuple:
    """``(X^T X, Q^T X, X^T r)`` of the columns ``X = [reader(pos) ...]`` on the model's rows (``st.Q``'s, a
    :class:`core.lsq.Basis`), summed :data:`FORMS_BLOCK_ROWS` rows at a time; ``pos_all``: only these rows
    (positions in ``st.rows``: the others' columns are zero)."""
    pos_all = np.arange(len(st.rows)) if pos_all is None else np.asarray(pos_all, int)
    S = XR = QX = None
    for a in range(0, max(len(pos_all), 1), FORMS_BLOCK_ROWS):
        pos = pos_all[a:a + FORMS_BLOCK_ROWS]
        X = np.hstack([rd(pos) for rd in readers])
        if S is None:
            S, XR, QX = np.zeros((X.shape[1],) * 2), np.zeros(X.shape[1]), np.zeros((st.Q.shape[1], X.shape[1]))
        if len(pos):
            S += X.T @ X
            XR += X.T @ st.r[pos]
            st.Q.rows_rmatmul(pos, X, out=QX)
    return S, QX, XR


def _gram_directions(G: np.ndarray) -> np.ndarray:
    """``W`` (k, k') with ``P W`` :func:`core.diagnosis.new_basis`'s result for ``P`` (columns normalised and
    projected out of the model) of Gram matrix ``G = P^T P``: the eigenvectors kept (singular value above
    ``max(IN_SPAN, 1e-5)``), each over its singular value."""
    if not G.shape[0]:
        return np.zeros((0, 0))
    w, V = np.linalg.eigh(G)
    good = w > max(IN_SPAN, 1e-5) ** 2
    return V[:, good] / np.sqrt(w[good])


class _Projected:
    """Columns ``X = [reader(pos) ...]`` on the model's rows (``st.Q`` a :class:`core.lsq.Basis`), each normalised
    and projected out of ``Q`` (``P = X' - Q Q^T X'``, as :func:`core.diagnosis.new_basis` projects them), made a
    block of :data:`FORMS_BLOCK_ROWS` rows at a time from ``Q^T X`` and the norms (summed in one pass over the rows):
    nothing rows x columns is formed beyond a block. ``G = P^T P`` and ``P^T r`` are summed over ``P``'s blocks as
    made (not from ``X^T X - (Q^T X)^T Q^T X``, whose cancellation costs about 1e-6 relative where a direction's
    singular value is near the cut of 1e-5)."""

    def __init__(self, st: _State, readers):
        self.st, self.readers, n = st, readers, len(st.rows)
        ss = QX = None
        for pos in self.blocks():
            X = self.read(pos)
            if QX is None:
                ss, QX = np.zeros(X.shape[1]), np.zeros((st.Q.shape[1], X.shape[1]))
            ss += np.einsum("ij,ij->j", X, X)
            st.Q.rows_rmatmul(pos, X, out=QX)
        nrm = np.sqrt(ss)
        self.keep = nrm > 0  # (new_basis drops a zero column)
        self.inv = np.where(self.keep, 1.0 / np.where(self.keep, nrm, 1.0), 0.0)
        self.QXn = QX * self.inv
        self.G, self.Pr = np.zeros((len(nrm),) * 2), np.zeros(len(nrm))
        for pos in self.blocks():
            P = self.rows(pos)
            self.G += P.T @ P
            self.Pr += P.T @ st.r[pos]
        self.n = n

    def blocks(self):
        n = len(self.st.rows)
        return (np.arange(a, min(a + FORMS_BLOCK_ROWS, n)) for a in range(0, n, FORMS_BLOCK_ROWS))

    def read(self, pos) -> np.ndarray:
        return np.hstack([rd(pos) for rd in self.readers])

    def rows(self, pos) -> np.ndarray:
        """``P``'s rows ``pos``."""
        return self.read(pos) * self.inv - self.st.Q.rows_matmul(pos, self.QXn)


def _beyond_projected(pj: _Projected, a, e, sigma: float, tries: float, settings, share: float = 1.0) -> tuple:
    """:func:`_beyond` of the cause's columns ``X[:, e]`` beside the alternative's ``U_alt = new_basis(Q, X[:, a])``,
    ``pj``'s columns ``X`` (:class:`_Projected`), a block of rows at a time: ``U_alt = P_a W_a`` (``W_a`` from
    ``P_a^T P_a``), then the cause's columns beyond ``[Q, U_alt]`` made a block at a time (``P_e - U_alt U_alt^T
    P_e``) and their Gram matrix and products with ``ra = r - U_alt U_alt^T r`` summed over the blocks. The same
    ``(d, p, stands)`` to rounding."""
    st = pj.st
    a, e = (np.asarray(i, int) for i in (a, e))
    a, e = a[pj.keep[a]], e[pj.keep[e]]
    Wa = _gram_directions(pj.G[np.ix_(a, a)])
    u = Wa.T @ pj.Pr[a]  # U_alt^T r
    M = Wa.T @ pj.G[np.ix_(a, e)]  # U_alt^T P_e
    Ge, be, rr = np.zeros((len(e), len(e))), np.zeros(len(e)), 0.0
    for pos in pj.blocks():
        P = pj.rows(pos)
        Ua = P[:, a] @ Wa
        Pe = P[:, e] - Ua @ M
        ra = st.r[pos] - Ua @ u
        Ge += Pe.T @ Pe
        be += Pe.T @ ra
        rr += float(ra @ ra)
    We = _gram_directions(Ge)
    b = We.T @ be  # Un^T ra
    k, n = We.shape[1], pj.n
    ss, dof = float(b @ b), n - (st.Q.shape[1] + Wa.shape[1])
    d = ss - k * sigma ** 2
    p = 1.0 if k == 0 or dof - k < 1 else _nested_f_ss(k, ss, n, rr, dof).p_value
    p = min(1.0, p * tries)
    stands = bool(d >= (settings.material_sigma * sigma) ** 2 * n * share and p < settings.alpha_family)
    return d, p, stands


def _forms_gram_choice(cs, cc, level, rows, st: _State, settings) -> tuple:
    """:func:`_forms_dense_choice` a block of rows at a time (:data:`FORMS_DENSE_BYTES`): nothing rows x columns
    formed beyond a block of rows, the one-off steps' trials one at a time (:func:`_one_off_p`'s, the same
    order)."""
    rows = np.asarray(rows)
    rs, rc = _rows_reader(cs, rows), _rows_reader(cc, rows)
    ks, kc = cs.shape[1], cc.shape[1]
    pj = _Projected(st, [rs, rc])
    i_s, i_c = np.arange(ks), ks + np.arange(kc)
    p_steps = _beyond_projected(pj, i_c, i_s, st.sigma, 1.0, settings)[1]
    p_cont = _beyond_projected(pj, i_s, i_c, st.sigma, 1.0, settings)[1]
    del pj
    if not (p_steps < settings.alpha_family and p_cont >= settings.alpha_family):
        return False, (p_steps, p_cont, None)
    if not STEP_BEYOND_ONE_OFF:
        return True, (p_steps, p_cont, None)
    p_once = _one_off_p_gram(rs, ks, level, rows, st, settings)
    return p_once < settings.alpha_family, (p_steps, p_cont, p_once)


def _one_off_levels(level, rows) -> tuple:
    """The one-off trials' levels, one definition for :func:`_one_off_p` and :func:`_one_off_p_gram`: the per-set-up
    level on the model's rows ``L``, the levels a trial starts at ``lv`` (every level after the first's 0), and the
    divisor that takes the steps back to their pattern (``L``; 1 on the first set-up, where the steps are 0)."""
    L = np.asarray(level, float)[rows]
    lv = np.unique(L)
    return L, lv[lv > 1e-12], np.where(L > 1e-12, L, 1.0)


def _one_off_p_gram(rs, ks: int, level, rows, st: _State, settings) -> float:
    """:func:`_one_off_p` a block of rows at a time (``rs``: the steps' block reader, ``ks`` their columns): each
    one-off trial's test beside the model from its Gram matrices (:func:`core.diagnosis.nested_f_batch`'s
    block-basis branch, which :func:`_one_off_p` takes on a long log), summed over its own rows, then the steps beyond
    the best as :func:`_beyond_projected` tests them."""
    if level is None:
        return 0.0
    L, lv, safe = _one_off_levels(level, rows)
    if lv.size < 2:
        return 1.0
    Qr = st.Q.T @ st.r

    def once(v):  # (the pattern: the steps over the level, as _one_off_p's cs / safe)
        return lambda pos: np.where((L[pos] >= v - 1e-12)[:, None], rs(pos) / safe[pos][:, None], 0.0)

    G, bb = np.empty((lv.size, ks, ks)), np.empty((lv.size, ks))
    for j, v in enumerate(lv):  # nested_f_batch's block-basis branch, each trial's sums over its own rows
        Sj, QC, Cr = _forms_gram(st, [once(v)], np.flatnonzero(L >= v - 1e-12))
        nrm = np.maximum(np.sqrt(np.maximum(np.diag(Sj), 0.0)), 1e-300)
        inv = np.where(nrm > 1e-300, 1.0 / nrm, 0.0)
        QC = QC * inv
        G[j] = Sj * np.outer(inv, inv) - QC.T @ QC
        bb[j] = Cr * inv - QC.T @ Qr
    ss, k, _, _ = _batch_tests(G, bb, st.rss, st.dof)
    if not np.any(k > 0):
        return 0.0
    v = lv[int(np.argmax(np.where(k > 0, ss, -np.inf)))]
    pj = _Projected(st, [once(v), rs])
    return _beyond_projected(pj, np.arange(ks), ks + np.arange(ks), st.sigma, 1.0, settings)[1]


def _steps_beyond_one_off(cs: np.ndarray, level: np.ndarray | None, rows, st: _State, settings) -> bool:
    """Whether a feature's steps per set-up (``cs``, its layout's columns on the model's rows, each the layout's
    pattern times the set-up's level) are significant beyond the same pattern stepping once, at the one set-up
    change where that explains most (:data:`STEP_BEYOND_ONE_OFF`).

    ``level`` (n,): the per-set-up time of :func:`core.causes.part_change_times` (0 on the first set-up, 1 on the
    last). The one-off trials: the pattern (``cs`` over the level) on every set-up from the ``j``-th level on, 0
    before it, for each level after the first; the best (largest sum of squares beside the model) is put in the
    model and the steps tested beyond it (F test at ``alpha_family``, unadjusted, as the forms' own test). On two
    set-ups the steps are the one-off step: not beyond it.
    """
    return _one_off_p(cs, level, rows, st, settings) < settings.alpha_family


def _one_off_p(cs: np.ndarray, level: np.ndarray | None, rows, st: _State, settings) -> float:
    """:func:`_steps_beyond_one_off`'s p-value of the steps beyond the best one-off step (0 where there is no level,
    or the one-off steps lie in the model; 1 on two set-ups)."""
    if level is None:
        return 0.0
    L, lv, safe = _one_off_levels(level, rows)
    if lv.size < 2:
        return 1.0
    pat = cs / safe[:, None]
    C = np.stack([np.where((L >= v - 1e-12)[:, None], pat, 0.0) for v in lv])
    ss, k, _, _ = nested_f_batch(C, st.Q, st.r, st.rss, st.dof)
    if not np.any(k > 0):  # the one-off steps lie in the model: they explain nothing the steps need beat
        return 0.0
    j = int(np.argmax(np.where(k > 0, ss, -np.inf)))
    return _beyond(st, new_basis(st.Q, C[j]), cs, st.sigma, 1.0, settings)[1]


#: Whether :func:`_time_forms_chosen` keeps a feature's steps per set-up only where they are significant beyond the
#: same layout stepping once, at one set-up change (:func:`_steps_beyond_one_off`): a part that changes at every
#: set-up against a one-off event at one set-up change (gen_b stylus_pickup 1012).
STEP_BEYOND_ONE_OFF = True


#: Whether a cause whose trial of smallest p falls short of its held-out gain, or is confounded with the model, is
#: judged on its other significant forms, in the same order (:func:`_evaluate`; session 17, gen_a c_drift's
#: per-set-up creep, gen_b's common creep). False: the rule before. Off (session 17, the lead): on the session's
#: blind check (gen_a 2400-2409, every effect) it named no campaign more and named gen_a thermal_bending 2400 (out of
#: the catalogue) part_change confidently: c_drift, refused on its form of smallest p (held-out gain -0.116 um^2),
#: was adopted on another form, part_change (slot6, wall changes -24, +8, +22 um) adopted beside it in the next
#: round, and c_drift then dropped by the rival check (share 0.34), leaving part_change named on a search path a
#: dropped cause had opened (without the fallback: `unexplained`). A confident wrong name is issue 13's worst
#: outcome; the tuning gains (gen_a c_drift 175 -> 181 of 183) waited for the path to be undone when its cause is
#: dropped. On again (session 18): a cause adopted after a cause the rival check drops is now judged again beside
#: the causes before it that stay (discover_baseline, step 5). Measured with the undo, on against off, on gen_a
#: and gen_b every effect 1000-1039 and 1900-1929 and sim 4000-4019 (2,830 campaigns): catalogue +6 (gen_b
#: thermal_drift 1023, c_drift 1028, 1920; gen_a thermal_drift 1902, c_drift 1903, 1925), eight more named right
#: below one sigma, no right -> wrong, no confident misnaming, the workpiece checks as before (gen_a
#: thermal_bending 1036, `unexplained` -> thermal_drift, ambiguous, both right: its extended workpiece 1.18 um
#: against U95 1.04 before, 1.39 against 0.95 now, outside either way). The blind 2400 not rerun (a blind seed);
#: its tuning likeness, thermal_bending 1008, reads part_change, ambiguous, as with the step off (part_change judged
#: again without c_drift takes another form and stands), where session 17's code with the step read `unexplained`.
HELD_OUT_FALLBACK = True
#: Whether the form :data:`HELD_OUT_FALLBACK` adopts is named hedged unless its held-out gain clears the materiality
#: times the count of the cause's significant forms it was chosen among, the refused one with them (True;
#: :func:`_fallback_short`). The fallback is a second selection: after the form of smallest p fails its held-out
#: test, the next form that passes is taken, so a pass is the best of several chances, and the single-look materiality
#: is no longer the size a form must show; the count scales it as the tries scale a p-value (Bonferroni in size
#: units: a rough correction, not a level). gen_a thermal_bending 10309 (set C, out of the catalogue, read a confident
#: `c_drift`): the per-set-up creep, held-out gain 0.165 um^2 against materiality 0.065 and 3 forms (2.5x, under
#: 3x: hedged, the margin thin). The six right names the fallback brought (session 18) clear it: gen_b
#: thermal_drift 1023 25x (12 forms), gen_b c_drift 1920 10x (6), gen_a thermal_drift 1902 14.5x (13), gen_a
#: c_drift 1903 12.6x (6), 1925 18.9x (6); gen_b c_drift 1028's reading is not a fallback form. Session 34 (sel34).
#: Measured (on against off, 610 tuning campaigns: gen_a 1000-1024 c_drift, thermal_drift, thermal_bending,
#: probe_lobing, lobing_per_setup, reversal; gen_b 1000-1029 c_drift, thermal_drift, probe_lobing, lobing_per_setup,
#: reversal, stylus_bending; gen_a/gen_b 1900-1929 c_drift, thermal_drift; gen_c 0-19 c_drift, thermal_drift,
#: clamp_creep, probe_lobing; the simulator 4000-4019 c_drift, thermal_drift, probe_lobing, lobing_per_setup):
#: 11 have a fallback finding, 3 move, each a right name below visibility made hedged (gen_b c_drift 1910 1.0x and
#: 1914 1.6x among 6 forms, thermal_drift 1916 2.5x among 12; visible 0.44-0.59 sigma), workpieces unchanged;
#: nothing right -> wrong, the six names of session 18 kept. On (sel34).
FALLBACK_SELECTION_COUNTED = True


def _fallback_short(ev: dict) -> str | None:
    """:data:`FALLBACK_SELECTION_COUNTED`'s hedge of a finding's evidence ``ev``: the reason, or None where the form
    is no fallback or its held-out gain at adoption clears the materiality times the forms it was chosen among."""
    if not ev.get("held_out_fallback"):
        return None
    n, g, m = (ev.get(k) for k in ("held_out_fallback_forms", "held_out_fallback_gain_um2",
                                   "held_out_fallback_materiality_um2"))
    if n is None or g is None or m is None or not g < n * m:
        return None
    step = ("was refused as confounded with the model (CONFOUNDED_SELECTION_COUNTED)"
            if ev.get("held_out_fallback_step") == "confounded" else "failed its held-out test")
    return (f"its form was taken after the form of smallest p {step}: a second selection among "
            f"{n} significant forms, and its held-out gain ({g:.3g} um^2) does not clear the materiality counted "
            f"for them ({n} x {m:.3g} um^2): the name rests on a choice the data could make by chance")


#: Whether a cause refused because its plainer catalogue cause (``counter_cause``: the probe's fixed lobes for lobes
#: turned per set-up) explains as much is judged once more, that refusal waived, where the plainer cause is refused by
#: its own tests in the same round (True; :func:`_counter_requeue`), and named hedged if it then passes. The
#: refusal's premise is that the plainer cause is the reading; where the plainer cause itself fails (gen_a
#: probe_lobing 10304, session 33's strongest catalogue miss, vis 5.56: lobing_per_setup refused for common lobing,
#: 1,110 against 1,140 um^2, and common lobing then refused at its held-out gain, -5.11 against 0.51 um^2) the
#: richer cause was refused in favour of a cause never adopted, and the campaign read a confident `unexplained`.
#: The hedge says what the refusal said (the plainer explains as much); the rival check's drop for the plainer cause
#: (:func:`_rival_share`) becomes the same hedge on such a term. Session 34 (sel34). Off: it does not mend 10304
#: (lobing_per_setup, judged again, is refused on its own plausibility check: its lobes' orientations agree across
#: the set-ups, 14 +- 130 deg, "the probe is oriented": fixed lobes, the plainer cause, which passes every test and
#: the rival check in round 1 of the search and in the finer map's, and fails its held-out test in round 2 beside
#: reversal, which the rival check then drops: session 35, :data:`DROPPED_ROUND_REOPENED`), and on the 610 tuning
#: campaigns of :data:`FALLBACK_SELECTION_COUNTED` it fires on 15 and moves
#: 3, all below visibility: gen_a reversal 1009 right -> wrong (`reversal?` -> `periodic_axis_error?` then
#: lobing_per_setup; extended workpiece 0.46 -> 3.86 um, baseline 3.08, U95 1.87), gen_b probe_lobing 1003
#: (`unexplained`) and 1012 (`outlier?`) -> `lobing_per_setup?` with probe_lobing among its alternatives.
COUNTER_NEEDS_PLAINER_PASSING = False
#: (:data:`COUNTER_NEEDS_PLAINER_PASSING`) the reason the plainer cause failed while a cause is judged again with the
#: plainer-explanation refusal waived; empty: not waived. A context variable, so the judging functions keep their
#: signatures (set and reset around one :func:`_evaluate` call only).
_COUNTER_WAIVED: contextvars.ContextVar = contextvars.ContextVar("_COUNTER_WAIVED", default="")


def _counter_requeue(cause, cand: dict, catalogue, queue: list, waive: dict, seen: dict) -> None:
    """One refused candidate of a search round seen by :data:`COUNTER_NEEDS_PLAINER_PASSING`, in place.

    ``seen``: the round's record (``refused``: name -> first reason; ``counter``: names refused for their plainer
    cause; ``queued``: names queued again); ``waive``: the causes queued again (name -> why the plainer cause
    failed). A cause refused for its plainer catalogue cause (``counter_refused``) is queued at the end of the
    round's ``queue`` with that refusal waived once the plainer cause is refused by its own tests too, whichever of
    the two the catalogue lists first; at most once a round.
    """
    refused, counter, queued = (seen.setdefault(k, v) for k, v in (("refused", {}), ("counter", set()),
                                                                   ("queued", set())))
    refused.setdefault(cause.name, cand["reason"])
    if cand.get("counter_refused"):
        counter.add(cause.name)
    for rich in catalogue:
        plain = rich.counter_cause
        if rich.name in counter and plain in refused and plain != rich.name and rich.name not in queued:
            queued.add(rich.name)
            waive[rich.name] = f"the plainer cause ({plain}) is refused by its own tests ({refused[plain]})"
            queue.append(rich)
#: Whether that fallback also follows a confounded form (True), or only one short of its held-out gain (False).
#: Off (session 17, the lead's call): on, it named five more visible campaigns right on gen_a/gen_b 1000-1199
#: (gen_b c_drift 1139 and 1187, gen_b thermal_drift 1016, gen_a local_scale_defect 1096 and 1144) but named
#: gen_a local_scale_defect 1144 on a bump of variance inflation 31 whose extended workpiece is 4.6 um off
#: against the baseline's 1.7 (U95 2.4): an extension reported outside its own uncertainty costs more than
#: a name missed. gen_b c_drift 1187's test runs it on. Still off (session 18): on the 2,830 campaigns above it
#: adds gen_b thermal_drift 1016 alone to the held-out step, and the undo of a dropped cause's search does not
#: reach 1144 (nothing is dropped there: the confounded bump is the cause named). Session 26: the step is taken,
#: by least inflation, whatever this switch while :data:`CONFOUNDED_FALLBACK_LEAST_INFLATION` is on (the default).
CONFOUNDED_FALLBACK = False
#: Whether that confounded step takes, of the cause's other significant forms that pass every test, the one of
#: largest held-out gain (True) rather than the first by p (False). Off (session 25, conf25): with the step on it
#: keeps gen_a local_scale_defect 1144's workpiece check (`unexplained`, 6.77 um against 1.74 + U95 7.70) and names
#: what the step names on gen_a/gen_b 1000-1099 and c_drift 1100-1199 (1096, 1125, gen_b 1139, 1187), but at gen_a
#: c_drift 1267 the largest gain (0.226 um^2) is the refused creep's degree 2, a near-confounded neighbour 0.02 um^2
#: above the campaign quadratic the step takes, and its extended workpiece is 9.48 um off against 0.56 + U95 1.92
#: (docs/discovery.md, "Session 25: the confounded step measured again").
CONFOUNDED_FALLBACK_BY_GAIN = False
#: Whether that confounded step judges only the cause's forms of the refused form's covariate (True; session 25's
#: :data:`ENTRANT_FORM_SAME_COVARIATE` idea applied to the fallback). Off (session 25, conf25): by p or by gain it
#: takes that neighbour at gen_a c_drift 1267 (9.48 um, lost) and local_scale_defect 1144 (4.61 um, lost), and
#: leaves gen_a c_drift 1125 `unexplained` (its passing forms are of another covariate).
CONFOUNDED_FALLBACK_SAME_COVARIATE = False
#: Whether a confounded form of smallest p opens the step (True, whatever :data:`CONFOUNDED_FALLBACK`) and the step
#: takes, of the cause's other significant forms that pass every test, the one of least variance inflation beside the
#: model (before :data:`CONFOUNDED_FALLBACK_BY_GAIN`; where none passes the confounded refusal stands). On since
#: session 26 (conf26; proposed by conf25 on the deciding campaigns: gen_a c_drift 6500 named). Measured on every
#: effect of gen_a/gen_b 1000-1099 and the simulator 4000-4049 (4,300 campaigns; 107 reach a confounded refusal,
#: the rest identical by construction, 300 of them rerun field for field): local_scale_defect 1096
#: `periodic_axis_error?` -> `local_scale_defect?`, gen_b c_drift 1058, 1075 (below one sigma) `unexplained` ->
#: `c_drift`; nothing right -> wrong, false alarms, confident misnaming and workpiece checks as before. Beyond the
#: sets: gen_a c_drift 1125 and 1267 named (1267's extended workpiece 0.19 um against 0.56 + U95 0.36, where the
#: choice by gain is 9.48 um off), gen_b c_drift 1139, 1187 named, gen_a local_scale_defect 1144 `part_change?` ->
#: `unexplained` with its check kept but its extended workpiece 6.77 um off (baseline 1.74, U95 7.70; docs/discovery.md,
#: "Session 26: the confounded step by least inflation").
CONFOUNDED_FALLBACK_LEAST_INFLATION = True
#: Whether a cause the rival check drops (step 5) leaves the round it won open (True; :func:`discover_baseline`'s
#: ``round_reopened``): the search resumes beside the causes that stay (those adopted before it, and those after it
#: judged again without it), every cause the check dropped kept out of its rounds, and what it adopts meets the
#: rival check in turn. Without it, only the causes *adopted* after the dropped one are judged again; a candidate
#: that passed every test of the round the dropped cause won, or was refused in a later round only beside it, is
#: never judged again, and the search ends with nothing where a cause earned its adoption. gen_a probe_lobing 10304
#: (set C, spent; vis 5.56, read `unexplained`): round 1 on BIC's 80 mm grid, probe_lobing (pre-travel along the
#: approach) passes every test (p 7.8e-64) and reversal (p 2.3e-18) wins the round; round 2, beside reversal,
#: probe_lobing is refused at held-out gain -5.11 um^2 (materiality 0.512); the rival check then drops reversal
#: (0.66 of a smooth in approach_azimuth) and the search ends empty. Not where outliers were put back by a cause that
#: stays (the search's own screen would set them aside again). Session 35 (sel35). On, 10304 reads `probe_lobing?`
#: (extended workpiece 0.52 um, U95 1.15; baseline 5.29). Measured on 1,659 tuning campaigns (the rival check drops a
#: cause in 134, 3 move): gen_a local_scale_defect 1009 (vis 2.46; the same pattern: a ripple won round 1, the bump
#: refused beside it at -4.62 um^2, the ripple dropped) `unexplained` -> `local_scale_defect?`; gen_b
#: lobing_per_setup 1067 and signal_latency 1008 gain an outlier finding beside `unexplained`; nothing right ->
#: wrong, every workpiece within its check. Off: built, measured, for the lead (docs/discovery-studies.md, "Session 35: the
#: round a dropped cause won, decided again"). Switched on by the lead in session 36 before blind set F (0 right ->
#: wrong on the tuning campaigns); set F reads it (docs/discovery.md, "The last blind check").
DROPPED_ROUND_REOPENED = True
#: Whether a form the confounded step takes (:data:`CONFOUNDED_FALLBACK_LEAST_INFLATION`: the form of smallest p
#: refused as confounded, the least inflated of the cause's other significant forms that pass every test taken) is
#: counted as :data:`FALLBACK_SELECTION_COUNTED` counts the held-out fallback's (True): named hedged unless its
#: held-out gain clears the materiality times the cause's significant forms the step chose among, the refused one
#: with them (:func:`_fallback_short`; the evidence's ``held_out_fallback_forms``, ``..._gain_um2``,
#: ``..._materiality_um2`` and ``held_out_fallback_step`` ``"confounded"``). The step is a second selection too:
#: each form that passes had its chance at the held-out test, so a pass is the best of several. Session 35 (sel35).
#: Measured on the same 1,659 tuning campaigns: 8 reach the step's form, 3 move, right names made hedged (gen_b c_drift
#: 1178, 1187, 1196, vis 0.68-1.47; 1187: gain 0.275 against 6 x 0.189 um^2), workpieces unchanged; gen_a c_drift
#: 1125 (9.6x among 6) and gen_b 1139 kept named. Off: built, measured, for the lead (docs/discovery-studies.md,
#: "Session 35: the round a dropped cause won, decided again").
CONFOUNDED_SELECTION_COUNTED = False
#: Whether a refusal in ``rejected`` made beside a named cause the final model does not hold is marked so (True;
#: :func:`_refusals_marked`): its reason gains "made beside X (how X went), which the final model does not hold" and
#: whether the refused cause was judged again later beside a model without X; the entry gains
#: ``made_beside_dropped`` (those causes' names) and ``judged_again_later``. A refusal is a judgement beside the
#: model of its moment (a round's adopted causes, the causes kept when judged again, the terms beside a dropped or
#: refused one); where a cause of that model is later dropped by the rival check, refused when judged again,
#: refused at its ridge chosen again, made redundant by the unnamed smooth or adopted in a search the report does
#: not take, the reason referred to a model that no longer stands (gen_a local_scale_defect 1009: the bump refused
#: at -4.62 um^2 held out beside the ripple the rival check then dropped; :data:`DROPPED_ROUND_REOPENED` judges it
#: again and names it, and the report still said "refused because" beside the ripple). Bookkeeping only: no
#: cause, confidence or workpiece moves (the refusal's text changes only in the report's ``rejected``, after every
#: rule that reads it). Session 36 (sel36).
REFUSALS_BESIDE_DROPPED_MARKED = True
#: Whether a penalised named cause :func:`_rechosen_gate` refuses (its ridge chosen again in the final model, a gate
#: of its adoption failed there) leaves the round it won open, as :data:`DROPPED_ROUND_REOPENED` leaves a dropped
#: cause's (True: :func:`discover_baseline`'s ``round_reopened`` beside the causes that stay, the refused cause and
#: every dropped one kept out, what it adopts judged by the rival check, ``rival_checked``). Without it only the
#: causes adopted after the refused one are judged again; a cause refused in a round beside it (or never reached,
#: the rounds spent) is not. Not where outliers were put back by a cause that stays. Session 36 (sel36); off: built,
#: measured, for the lead (docs/discovery-studies.md, "Session 36: ...").
RECHOSEN_ROUND_REOPENED = False
#: Whether a cause the rival check drops beside a cause adopted after it, which is then refused when judged again
#: without it, is judged once more in the model that stands (True; :func:`discover_baseline`'s ``pair_decided``). The
#: drop referred to a model holding the later cause (A dropped beside B: B's columns took A's structure, or nested
#: A's, as lobes turned per set-up nest the probe's fixed lobes); once B is refused without A, neither stands and the
#: search never judges A again (every dropped cause is kept out of the reopened rounds). Here A, as a candidate of
#: the search beside the causes that stay (B refused on that very model: the two judged side by side, B first),
#: passes every test of adoption (4a-f, its form chosen again) and then the rival check in the model with it and
#: without B, or stays dropped. Restored, it stands against B: B is kept out of every round after (beside A it would
#: be adopted and drop A again: the loop), and A is restored once per run (the loop guard: dropped a second time, it
#: stays dropped). Not where outliers were put back. Session 37 (pair37): sel36's third gap, gen_a lobing_per_setup
#: 1153 (probe_lobing dropped at 0.57 of a smooth in approach_azimuth beside lobing_per_setup, lobing_per_setup
#: refused without it for its plainer counter, common lobing, at 85 % of its signal): on, ``probe_lobing?``,
#: ambiguous with lobing_per_setup (the truth; the data cannot tell lobes turned by small angles from fixed lobes
#: with a wobble). Measured on 1,661 tuning campaigns (gen_a, gen_b, gen_c; effect-free 120): a dropped cause judged
#: again in 43, restored in 1153 alone, which is the one campaign that moves; no right -> wrong, no workpiece check
#: moved, no false alarm. Off: built, measured, for the lead (docs/discovery-studies.md, "Session 37: a pair of causes each
#: refused beside the other").
PAIR_REFUSED_DECIDED = False


class _Refusal(dict):
    """A ``rejected`` entry with what it was judged beside: ``beside``, the named causes in the model then;
    ``at``, the count of judgements of adoption made up to and including its own (:func:`_refusals_marked`).
    Neither is in the report (the entry leaves :func:`discover_baseline` a plain dict)."""

    def __init__(self, *args, beside=(), at=0, **kw):
        super().__init__(*args, **kw)
        self.beside, self.at = tuple(beside), int(at)


def _refusals_marked(rejected: list, final: set, gone_how: dict, judged: list) -> list:
    """``rejected`` as plain dicts, each refusal made beside a named cause not in ``final`` (the final model's named
    causes) marked (:data:`REFUSALS_BESIDE_DROPPED_MARKED`): ``made_beside_dropped`` (those causes, in the order of
    the model), ``judged_again_later`` (the refused cause is in the final model, or was judged again, by
    ``judged``'s record ``(cause, named causes beside)`` of every judgement of adoption, after this refusal beside a
    model holding none of them), and the reason's words with ``gone_how``'s account of how each went."""
    out = []
    for r in rejected:
        stale = [c for c in dict.fromkeys(getattr(r, "beside", ())) if c not in final]
        if not stale:
            out.append(dict(r))
            continue
        at = getattr(r, "at", len(judged))
        again = r["cause"] in final or any(c == r["cause"] and not set(b) & set(stale) for c, b in judged[at:])
        words = ", ".join(f"{c} ({gone_how.get(c, 'not in the final model')})" for c in stale)
        them = "it" if len(stale) == 1 else "them"
        out.append({**r, "reason": f"{r['reason']}; made beside {words}, which the final model does not hold"
                    + (f"; {r['cause']} judged again later without {them}" if again else
                       f"; {r['cause']} not judged again without {them}"),
                    "made_beside_dropped": stale, "judged_again_later": bool(again)})
    return out


def _layout_text(info: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in info.items() if not isinstance(v, (np.ndarray, list, tuple)) or len(v) < 8)


#: Whether a cause that no held-out set-up can see is judged by leaving out one touch at a time instead
#: (:func:`_held_out_by_touches`; session 26). Leaving one of three set-ups out, the two left may hold nothing of a
#: cause beyond the baseline: gen_b stylus_bending 6508 (three set-ups, 60 targets each probed once per set-up at
#: another elevation, 118 baseline parameters in 204 touches, 23-27 residual degrees of freedom on two set-ups) puts
#: both of the bending's directions in every fold's band (training share beyond the baseline 1e-7 to 2.5e-3, below
#: ``cv_seen_extension^2`` = 0.01): its held-out gain is zero to rounding in every round (-2e-13 um^2) while it is
#: significant at p x tries 1e-22 and predicts each touch from the others (leave one touch out) 2.4 um^2 better than
#: the baseline (materiality 0.0033). The set-ups' figure is kept wherever it sees any direction of the cause.
#: Measured (700342a against this, every field of the study's records): gen_a every effect 1000-1099 (1,900) and the
#: simulator 4000-4049 (600) identical; gen_b every effect 1000-1099 (1,800) seven changed: reversal 1061 (2.07
#: sigma), stylus_bending 1005 (1.06) named (from `unexplained`, `probe_lobing?`), reversal 1069, stylus_bending
#: 1054, 1094 (below one sigma) `unexplained` -> the true cause, ambiguous; lobing_per_setup 1070 (0.47 sigma)
#: `unexplained` -> `probe_lobing?` with lobing_per_setup its alternative (the one right -> wrong); reversal 1054
#: (0.64) `unexplained` both, its outlier finding gone; no false alarm, confident misnaming or workpiece check moved.
#: gen_b every effect 1100-1149 (900, after the decision): six named (stylus_bending 1115 visible), one lost:
#: signal_latency 1133 (out of the catalogue, 1.11 sigma) `unexplained` -> `part_change?`, within its check.
#: False: such a cause is refused at its zero gain (the rule before session 26).
HELD_OUT_UNSEEN_BY_TOUCHES = True


def terms_unpenalised(terms) -> bool:
    """Whether no adopted term carries a penalty (the touch-by-touch figure is of an unpenalised fit)."""
    return _penalty(terms) is None


def _unseen_by_every_fold(folds, B0: np.ndarray, C: np.ndarray, settings) -> bool:
    """Whether every direction of ``C``'s part outside the model ``B0`` (orthonormal, rows of the folds) lies in every
    fold's band: its training share beyond the training image of the model in ``[SEEN_ZERO^2, seen_extension^2)``
    (:class:`Folds`: neither predicted nor the held-out group's own; the held-out figure is then that of the model
    without it)."""
    F = new_basis(B0, C)
    if F.shape[1] == 0:
        return False
    lo, hi = SEEN_ZERO ** 2, settings.cv_seen_extension ** 2 - SEEN_TIE
    for f in folds.items:
        tr = f.tr
        Bt = orth(B0[tr])
        R = F[tr] - Bt @ (Bt.T @ F[tr]) if Bt.shape[1] else F[tr]
        w = np.linalg.eigvalsh(R.T @ R)
        if w.min() < lo or w.max() >= hi:
            return False
    return True


def _held_out_by_touches(folds, y: np.ndarray, T: np.ndarray | None, C: np.ndarray, settings) -> float | None:
    """The held-out gain of the columns ``C`` beside the model (the folds' baseline and the adopted terms ``T``) by
    leaving out one touch at a time, where no held-out set-up can see them (:data:`HELD_OUT_UNSEEN_BY_TOUCHES`);
    None where a set-up does (the set-ups' figure stands) or the folds are not dense set-up folds.

    Each touch predicted from every other (the model refitted without it: ``e / (1 - h)``, exact least squares);
    the mean square over the touches the larger model leaves a leverage below ``1 - OWN_LEVERAGE`` (a touch that
    alone supports a direction predicts nothing), the same touches for both models. The figure asks whether the
    cause predicts a touch it was not fitted on; unlike the set-ups' it does not ask whether it predicts a new
    set-up, which no fold here can answer.
    """
    if not isinstance(folds, Folds) or not isinstance(folds.Q, np.ndarray) or not folds.items:
        return None
    B0 = folds.Q if T is None or T.shape[1] == 0 else np.hstack([folds.Q, new_basis(folds.Q, T)])
    if not _unseen_by_every_fold(folds, B0, C, settings):
        return None
    B1 = np.hstack([B0, new_basis(B0, C)])
    r0 = y - B0 @ (B0.T @ y)
    r1 = y - B1 @ (B1.T @ y)
    h0, h1 = leverage(B0), leverage(B1)
    ok = h1 < 1 - OWN_LEVERAGE
    if not ok.any():
        return None
    p0 = np.sum((r0[ok] / (1 - h0[ok])) ** 2) / ok.sum()
    p1 = np.sum((r1[ok] / (1 - h1[ok])) ** 2) / ok.sum()
    return float(p0 - p1)


#: A ``periodic_axis_error`` trial is refused where its period is below the Nyquist limit of every set-up's own
#: positions along its axis (resolved only by set-ups interleaved) AND what it explains beside the model spreads
#: over fewer effective targets than this share of the log's targets (:func:`_periodic_target_spread`: ``sum / max``
#: of the explained part ``f . r`` summed per target, the count :func:`_support` makes per position). An axis
#: error moves every target it is touched at; a period fitted through a few dented places of the part does not
#: (blind gen_c clamp_creep 5603, session 29: 4.19 mm, below each set-up's 5.3-6.8 mm, through three clamps'
#: dents, 9.3 effective targets of 74). Either condition alone costs a true periodic error on tuning seeds (gen_c
#: 206: 5.40 mm below its set-ups' 6.33 mm, 24 targets; gen_a 1010: 8.2 effective targets of 63). None: off.
#: Left off by session 30's study (docs/discovery-studies.md, "Session 30: a periodic error through a few dented edges"):
#: on gen_c's true periodic errors 200-249 the fewest were 13.6 of 74 (a margin of 1.5 over 5603, on one blind
#: draw), and the before/after measurement the rule needs was not made in the session.
PERIODIC_MIN_TARGET_SHARE: float | None = None


def _periodic_target_spread(bl, st: _State, E: np.ndarray, info: dict) -> dict | None:
    """Over how many effective targets what the columns ``E`` (rows used) explain beside ``st`` spreads.

    The explained part ``f = U U^T r`` (``U`` the columns' basis beside the
    model), ``f . r`` summed per target (every set-up's touches of one
    target are one unit), ``n_eff = sum / max``: 1 when one target carries
    it all. With it ``setup_nyquist_m``: the shortest Nyquist limit of one
    set-up's positions along the trial's axis (twice their mean spacing,
    :func:`core.causes.nyquist_period_m`); the engine's own limit pools
    every set-up's touches (a part turned between set-ups interleaves
    them). None where there is nothing explained (or no target labels).
    """
    T = getattr(bl.data, "touches", None)
    target, setup = getattr(T, "target", None), getattr(T, "setup", None)
    if target is None or setup is None:
        return None
    a = (bl.data.x, bl.data.y)["XY".index(info["axis"])]
    setup = np.asarray(setup)
    nyq = [causes_mod.nyquist_period_m(a[setup == k]) for k in np.unique(setup)]
    nyq = [v for v in nyq if np.isfinite(v)]
    if not nyq:
        return None
    U = new_basis(st.Q, E)
    f = U @ (U.T @ st.r)
    lab = np.asarray(target)[st.rows]
    s = np.bincount(lab, weights=f * st.r)
    top = float(s.max()) if s.size else 0.0
    if top <= 0:
        return None
    return {"n_eff": float(s.sum()) / top, "n_targets": int(np.unique(np.asarray(target)).size),
            "top_share": top / float(s.sum()), "setup_nyquist_m": float(min(nyq))}


def _judge_trial(cause, best: _Trial, scans, tries, bl, st: _State, folds: Folds, terms, cv_cur, sigma, settings,
                 families=None, scan_tries: float | None = None, support_count: bool = True) -> dict:
    """The tests of adoption (module docstring 4a-e) of one trial of the cause, chosen by :func:`_evaluate`.

    ``support_count`` False: the all-touch support count (:func:`_support`) is not made (every other test is):
    :data:`OUTLIERS_UNDER_SUPPORT_REFUSED_BUMP` asks whether that count alone refused the trial."""
    rows = st.rows
    p_val, F_val, k_val, sc, i, single = best[:6]
    info = sc.infos[i]
    # the grown layout's columns (built in _grow_layout), else the trial's as its scan's test took them: sparse on
    # a long log's basis where the scan can (lobing per set-up), formed dense below once significant
    cols = best.cols if best.cols is not None else _trials(sc, [i], st)[0]
    # single: the F test of the chosen trial's own columns, made once (refined, beside families, counter)
    if cause.nonlinear and cause.rebuild is not None and p_val * tries < 1.0:  # refining only helps a candidate
        info = _refine(cause, bl, info, st, rows)
        cols = cause.rebuild(bl, info)[0]
        single = nested_f_batch(cols[None, rows], st.Q, st.r, st.rss, st.dof)  # (the refined trial's)
        _, kk, FF, pp = single
        p_val, F_val, k_val = float(pp[0]), float(FF[0]), int(kk[0])
    deferred = None  # the path count's level where the count is put off (PATH_COUNT_DEFERRED)
    if scan_tries and p_val * tries < settings.alpha_family and all(s.path for s in scans):
        # the scan's count checked against Davies' bound on its trials' path (never lowered)
        level = settings.alpha_family * scan_tries / tries
        margin = PATH_BOUND_MARGIN * p_val * tries  # (the adjusted p-value at a count c is p_val tries c / scan_tries)
        if PATH_COUNT_DEFERRED and margin < settings.alpha_family and _path_count_below(
                scans, len(rows), level, settings.alpha_family * scan_tries / margin if margin > 0 else np.inf):
            deferred = level  # significant at the count's bound: counted once a test below asks for the count
        else:
            tries *= max(1.0, _path_tries(scans, st, level) / scan_tries)
    p_adj = min(1.0, p_val * tries)
    ev = {"F": F_val, "p_value": p_val, "p_adjusted": p_adj, "tries": float(tries), "k": k_val}
    if p_adj >= settings.alpha_family:
        return {"reason": f"not significant ({fmt_p(p_adj)} after Bonferroni over {tries:.0f} tries)"}
    cols = cols.toarray() if sps.issparse(cols) else cols  # (a trial kept sparse, formed once it is significant)
    if single is None and (families or cause.counter is not None):  # (both checks below take it)
        single = nested_f_batch(cols[None, rows], st.Q, st.r, st.rss, st.dof)
    if info.get("signed_by") == "approach+move":  # (core.causes.REVERSAL_MOVE_SIGNED's layout)
        p_move = _move_pair_p(cols[rows], st, single)
        ev["move_signed_p"] = p_move
        ev["move_signed_p_adjusted"] = min(1.0, p_move * tries)
        if REVERSAL_MOVE_EARNS and not p_move * tries < settings.alpha_family:
            return {"reason": f"the lost motion signed by the move is not significant beside the one signed by the "
                              f"approach ({fmt_p(min(1.0, p_move * tries))} after Bonferroni over {tries:.0f} tries): "
                              "the four columns owe their test to the approach's pair",
                    "significant": True, "form_refused": "move-signed"}
        if REVERSAL_TWO_LOBE_YIELDS:
            sig = _two_lobe_signature(cols[rows], st)
            if sig is not None:
                return {"reason": f"the lost motions signed by the approach are of opposite signs and alike in size "
                                  f"(balance {sig[0]:.2f}) with the move-signed pair {sig[1]:.2f} of them: a two-lobe "
                                  "pre-travel's signature on approaches along the normal, the four columns owe their "
                                  "test to it", "significant": True, "form_refused": "move-signed"}
    # e. the structure must live where the cause says: a smooth function of a
    # covariate of another family may not explain materially more than it
    if families:
        ss_n = _candidate_ss(single, st)
        cov = bl.covariate(sc.covariate)
        fam = cov.family if cov is not None else ""
        m_ss = (settings.material_sigma * sigma) ** 2 * len(rows)
        own = max(ss_n, families.get(fam, (0.0, ""))[0])
        for f, (ss_f, name) in families.items():
            # the feature-per-set-up term nests a position cause: it is judged
            # as the cause's own covariate's smooth is (NESTING_FAMILIES)
            # (the design's exact nesting measured only where it decides: a refusal otherwise)
            if (f != fam and ss_f > own + m_ss and own < settings.rival_share * ss_f
                    and f in NESTING_FAMILIES.get(fam, ()) and fam == "position"):
                # the nesting term is fine-grained: the position family's own figure at a finer resolution
                # (FINE_POSITION_DEGREE), measured only where it decides
                if _fine_position_credited(ss_n, families.get(fam, (0.0, ""))[0], settings):
                    own = max(own, _candidate_ss(nested_f_batch(_fine_position_of(bl)[None, rows], st.Q, st.r,
                                                                st.rss, st.dof), st))
            if f != fam and ss_f > own + m_ss and not (own >= settings.rival_share * ss_f and (
                    f in NESTING_FAMILIES.get(fam, ()) or _spans_exactly(bl, name, cols[rows], rows))):
                return {"reason": f"the structure follows {name} ({f}) more than this cause's form or its "
                                  f"family ({ss_f / UM ** 2:.3g} against {own / UM ** 2:.3g} um^2)",
                        "significant": True}
        ev["explained_ss_um2_at_adoption"] = ss_n / UM ** 2
    why = cause.check(info, bl) if cause.check else None
    if why:
        return {"reason": f"implausible: {why}", "significant": True}
    if deferred is not None:  # (every test below may read the count: made now, as it would have been above)
        tries *= max(1.0, _path_tries(scans, st, deferred) / scan_tries)
        p_adj = min(1.0, p_val * tries)
        ev.update({"p_adjusted": p_adj, "tries": float(tries)})
        if p_adj >= settings.alpha_family:  # (never, by the bound: the test above, as it stood)
            return {"reason": f"not significant ({fmt_p(p_adj)} after Bonferroni over {tries:.0f} tries)"}
    if cause.counter is not None:
        # the plainer explanation is tested before adoption too, so that a plainer
        # cause of the catalogue (the probe's fixed lobes for lobes turned per
        # set-up, which nest them) can win the round instead of the richer one
        # being adopted and then dropped to `unexplained` by the rival check
        ss_c, k_c, _, _ = single
        d_n = float(ss_c[0]) - int(k_c[0]) * sigma ** 2
        d_c, Uc = _counter_ss(bl, cause, st, rows, sigma)
        reach = _support_share(cols[rows], cause)  # (materiality over the touches the cause acts on)
        if d_c > d_n - (settings.material_sigma * sigma) ** 2 * len(rows) * reach \
                and cause.counter_cause is not None and not _beyond(st, Uc, cols[rows], sigma, tries, settings,
                                                                   reach)[2]:
            why_c = (f"a plainer explanation ({cause.counter.__name__.replace('_', ' ')}) explains as much "
                     f"({max(d_c, 0.0) / UM ** 2:.3g} against {max(d_n, 0.0) / UM ** 2:.3g} um^2)")
            waived = _COUNTER_WAIVED.get()
            if not waived:
                return {"reason": why_c, "significant": True, "counter_refused": True}
            ev["counter_waived"] = f"{why_c}, but {waived}"  # (COUNTER_NEEDS_PLAINER_PASSING: named, hedged)
        # (FIXED_SHARE_TEST: after the check above, which keeps its reason where both refuse)
        if cause.counter_cause is not None and FIXED_SHARE_TEST and d_n > 0:
            fs = _fixed_share(st, Uc, cols[rows], sigma)
            if fs is not None:
                ev["fixed_share"] = fs
                if fs["p"] < settings.alpha:
                    why_f = (f"a plainer explanation ({cause.counter.__name__.replace('_', ' ')}) explains "
                             f"{fs['share']:.0%} of its signal, where lobes turned at random in every "
                             f"set-up leave it {fs['null_median']:.0%} on this design ({fmt_p(fs['p'])}): "
                             f"fixed lobes (or a lost motion) with a wobble, not a probe turned")
                    waived = _COUNTER_WAIVED.get()
                    if not waived:
                        return {"reason": why_f, "significant": True, "counter_refused": True}
                    ev["counter_waived"] = f"{why_f}, but {waived}"  # (COUNTER_NEEDS_PLAINER_PASSING)
    if cause.support is not None:
        sp = _support(bl, cause, info, st, cols[rows])
        if sp["refused"] and support_count:
            out = {"reason": sp["reason"], "significant": True}
            if OUTLIERS_UNDER_SUPPORT_REFUSED_BUMP and cols.ndim == 2 and cols.shape[1] == 1:
                # refused by this count alone? (every other test made, the one-place test included: a bump
                # refuted beyond its largest place is a gross error there, not a rival reading of outliers)
                alone = _judge_trial(cause, best, scans, tries, bl, st, folds, terms, cv_cur, sigma, settings,
                                     families, scan_tries, support_count=False)
                if not alone.get("reason"):
                    out["support_refused_bump"] = {
                        "info": dict(info), "support_units": sp["support_units"],
                        "reach": np.flatnonzero(np.asarray(cols[:, 0]) != 0)}  # (rows of the whole log's basis)
            return out
        if DEFECT_BEYOND_ONE_PLACE:
            # one position's where its columns reach: the other touches it reaches must not contradict it
            reach = _support(bl, cause, info, st, cols[rows], reached_only=True)
            one = (_beyond_one_place(st, cols[rows], sigma, settings, np.asarray(cause.support(bl, info))[rows])
                   if reach["refused"] else None)
            if one is not None and one["verdict"] == "refuted":
                return {"reason": f"carried by one place: where it reaches, {reach['where']}, and without its "
                                  f"largest place the other touches it reaches, which at its fitted size would show it "
                                  f"({one['z_expected']:.2g} sigma expected), do not ({one['z_rest']:.2g} sigma): "
                                  "a gross error at that place (outlier), not an axis error",
                        "significant": True}
        if DEFECT_BEYOND_ONE_FEATURE and (feat := _feature_codes(bl, rows)) is not None:
            # one feature's: the other features' touches it reaches must not contradict it
            onef = _beyond_one_feature(st, cols[rows], sigma, settings, feat)
            ratio = (_feature_change_ratio(bl, cols, st, sigma, _part_change_layouts(bl), onef["feature"])
                     if onef is not None and onef["verdict"] == "refuted" else None)
            if ratio is not None and ratio >= settings.rival_share:
                return {"reason": f"carried by one feature ({_feature_names(bl)[onef['feature']]}): it carries "
                                  f"{onef['feature_share']:.0%} of what the bump "
                                  f"explains, without it the other features' touches it reaches, which at its fitted "
                                  f"size would show it ({onef['z_expected']:.2g} sigma expected), do not "
                                  f"({onef['z_rest']:.2g} sigma), and a change of that feature (part_change) explains "
                                  f"as much (x{ratio:.2g}): the part, not an axis error",
                        "significant": True}
    if PERIODIC_MIN_TARGET_SHARE is not None and cause.name == "periodic_axis_error":
        spread = _periodic_target_spread(bl, st, cols[rows], info)
        if spread is not None and info["period_m"] < spread["setup_nyquist_m"] \
                and spread["n_eff"] < PERIODIC_MIN_TARGET_SHARE * spread["n_targets"]:
            return {"reason": f"not an error of the axis: a period of {info['period_m'] * 1e3:.3g} mm, below the "
                              f"Nyquist limit of every set-up's targets along {info['axis']} (at least "
                              f"{spread['setup_nyquist_m'] * 1e3:.3g} mm), and what it explains spreads over "
                              f"{spread['n_eff']:.2g} effective targets of {spread['n_targets']} (at least "
                              f"{PERIODIC_MIN_TARGET_SHARE:.0%} of them), the largest carrying "
                              f"{spread['top_share']:.0%}: a period fitted through a few places of the part",
                    "significant": True}
    if C_DRIFT_NORMALS_AGREE and cause.name == "c_drift":
        split = _turn_split(bl, st, cols[rows])
        bound = float(stats.norm.isf(settings.alpha))
        if split is not None and split["p_value"] < settings.alpha and min(split["z_x"], split["z_y"]) < bound:
            weak = "X" if split["z_x"] < split["z_y"] else "Y"
            return {"reason": f"not one turn of the table: fitted on the touches of mainly-X and of mainly-Y normals "
                              f"apart, the angles differ (F = {split['F']:.3g}, {fmt_p(split['p_value'])}) and the "
                              f"mainly-{weak} normals do not show it ({split['share_' + weak.lower()]:.2g} of the turn "
                              f"fitted on every touch, {split['z_' + weak.lower()]:.2g} sigma; it explains "
                              f"{split['ss_x_um2']:.3g} um^2 on the mainly-X normals, {split['ss_y_um2']:.3g} on the "
                              "mainly-Y): an error of one axis growing in time, not the table turning",
                    "significant": True}
    if cause.smooth is not None:
        sm = _smooth_verdict(bl, cause, st, cols[rows], sigma, tries, settings)
        if sm["refused"]:
            return {"reason": sm["reason"], "significant": True}
    M, vif, vif_worst, ang, weak, beyond = _determined(st.Q, cols[rows], settings.vif_max,
                                                       None if cause.penalised else _pen_of(terms, rows))
    ev.update({"vif": vif, "max_vif": vif_worst, "principal_angle_deg": ang, "weak_directions": weak})
    if beyond:
        ev["directions_beyond_vif_max"] = beyond
    if cause.penalised:
        return _evaluate_penalised(cause, sc, info, cols, tries, bl, st, folds, terms, cv_cur, sigma, settings, ev)
    if VIF_WORST_REFUSED and M.shape[1] and vif_worst > settings.vif_max:
        # (session 32, vif32: every direction judged, not only the best; gen_a thermal_bending 8907's part_change,
        # best 4.7, worst 181, carried 6.9 um into the extended workpiece along its worst direction)
        model_words = "the baseline" + "".join(f" + {t.cause}" for t in terms)
        return {"reason": f"confounded with {model_words} along a direction (worst variance inflation "
                          f"{vif_worst:.3g} > {settings.vif_max:g}, principal angle {ang:.2g} deg; best {vif:.3g})",
                "significant": True, "form_refused": "confounded"}
    if M.shape[1] == 0:
        # (the model it is confounded with: the baseline and the causes adopted in earlier rounds; gen_a
        # reversal 1208: determined beside the baseline alone, best variance inflation 9, confounded beside
        # the baseline and probe_lobing, 151; the decision is the best direction's inflation, the smallest
        # principal angle that of the worst direction)
        model_words = "the baseline" + "".join(f" + {t.cause}" for t in terms)
        return {"reason": f"confounded with {model_words} (best variance inflation {vif:.3g} > {settings.vif_max:g}, "
                          f"principal angle {ang:.2g} deg)", "significant": True, "form_refused": "confounded"}
    # prediction and CV use the cause's own columns (a held-out set-up refits the
    # columns that are its own); the determined combinations M carry the
    # magnitudes and the extended workpiece
    kept = cols
    # an adopted penalised cause keeps its ridge here (cv_cur is its penalised figure; refitted unpenalised it
    # would be another model, and the winner's figure the next cv_cur): the candidate's columns are not penalised
    cv = folds.mse(bl.y[rows], np.hstack([_stack(terms, rows), kept[rows]]) if terms else kept[rows],
                   _penalty_beside(terms, kept.shape[1]))
    gain = cv_cur - cv
    # materiality per touch the cause acts on (a local cause, one feature's walls, counted over its own touches)
    m2 = (settings.material_sigma * sigma) ** 2 * _support_share(kept[rows], cause)
    ev.update({"cv_rms_before_um": float(np.sqrt(cv_cur)) / UM, "cv_rms_after_um": float(np.sqrt(cv)) / UM,
               "cv_gain_um2": gain / UM ** 2, "materiality_um2": m2 / UM ** 2})
    if gain < m2 and HELD_OUT_UNSEEN_BY_TOUCHES and terms_unpenalised(terms):
        # no held-out set-up's training rows see any of the cause beyond the model (every fold puts every
        # direction of it in the band: neither credit nor loss): judged by leaving out one touch at a time
        by_rows = _held_out_by_touches(folds, bl.y[rows], _stack(terms, rows) if terms else None, kept[rows],
                                       settings)
        if by_rows is not None:
            ev["held_out_by_touches"] = {"cv_gain_um2": by_rows / UM ** 2, "cv_gain_by_setups_um2": gain / UM ** 2}
            if by_rows >= m2:
                gain = by_rows
    if gain < m2:
        return {"reason": f"cross-validated gain {gain / UM ** 2:.3g} um^2 below materiality {m2 / UM ** 2:.3g} um^2",
                "significant": True, "form_refused": "held-out"}
    tm = Term(cause.name, kept, tuple(sc.labels), info, sc.covariate, tries, ev, weak=weak, origin=cause,
              labels_all=tuple(sc.labels), map=M, cols_all=cols)
    return _plausible(cause, bl, tm, st, rows, cv, boot=(folds, terms))


#: Whether a cause's own sums of squares are held to materiality over the touches its columns act on (True) or
#: over every touch (False, the rule before session 16): its held-out gain at adoption, what it explains beyond its
#: counter-explanation (at adoption and in the rival check) and the margin within which the best fixture slip
#: explains as much as it (not the remainder beyond a material slip). :func:`_support_share`.
MATERIALITY_OVER_SUPPORT = True


#: Whether reversal's move-signed layout (:data:`core.causes.REVERSAL_MOVE_SIGNED`: the lost motion signed by the
#: approach and by the net move from the previous touch) is taken only where its move-signed pair is significant
#: beyond the model and the approach-signed pair (:func:`_move_pair_p`, the partial F test :func:`_grow_layout` makes
#: of a nesting layout's new columns), under the cause's own Bonferroni count (the move-signed pair is a claim of its
#: own, reported as ``x_move_lost_motion_um``, ``y_move_lost_motion_um``). Without it the four columns pass the
#: confounding check on the move pair's well determined directions while the signal they explain is the
#: approach-signed pair's, confounded with the probe's lobes (gen_b probe_lobing 1007: the approach-signed layout
#: refused beside probe_lobing, inflation 518; the four columns taken as its fallback, best inflation 2, worst 1,460,
#: lost motion 7.3 um signed by the approach against 0.24 um by the move, U95 0.23 um; on gen_b's along-normal
#: approaches the approach-signed pair is ``|n_x| / 2``, ``|n_y| / 2``, whose difference carries the sixth harmonic of
#: the azimuth, the generator's six-lobe part the catalogue's lobes (harmonics 1-4) lack). Session 29 (lobe29),
#: docs/discovery-studies.md "Session 29: the move-signed reversal must earn its move".
REVERSAL_MOVE_EARNS = True


#: Whether reversal's move-signed layout gives way (refused as :data:`REVERSAL_MOVE_EARNS` refuses it, so the
#: approach-signed layout is judged alone) where its fitted lost motions have the signature of a two-lobe probe
#: (:func:`_two_lobe_signature`): the approach-signed pair of opposite signs and alike in size (the smaller at least
#: :data:`TWO_LOBE_BALANCE` of the larger) and the move-signed pair small beside it (its norm below
#: :data:`TWO_LOBE_MOVE_SHARE` of the approach pair's). On approaches along the normal the approach pair's columns are
#: ``|n_x| / 2``, ``|n_y| / 2``; equal and opposite lost motions are ``(|cos| - |sin|) / 2``, a two-lobe pre-travel
#: (harmonics 2, 6, 10). Session 30 (form30; the simulator's probe_lobing 4003 and the spent blind 6803, each read
#: `reversal?` through the four columns with balance 0.67 / 0.65 and move share 0.13 / 0.19). On: measured (this
#: tree's defaults, and with the rule rerun where a four-column layout judged had the signature) on the simulator's
#: probe_lobing and reversal 4000-4099, gen_a/gen_b reversal 1000-1099, gen_c travel_hysteresis and reversal
#: 200-399 / 200-299, gen_b probe_lobing 1000-1049 and more: 4003 and 6803 `reversal?` -> `probe_lobing?`, nothing
#: right -> wrong, no workpiece check moved (docs/discovery-studies.md, "Session 30: the move-signed reversal on two-lobe
#: probes"). False: the four columns judged by :data:`REVERSAL_MOVE_EARNS` alone.
REVERSAL_TWO_LOBE_YIELDS = True
#: :data:`REVERSAL_TWO_LOBE_YIELDS`' balance: the smaller approach-signed lost motion over the larger, at least.
TWO_LOBE_BALANCE = 0.5
#: :data:`REVERSAL_TWO_LOBE_YIELDS`' move share: the move-signed pair's norm over the approach-signed pair's, below.
TWO_LOBE_MOVE_SHARE = 0.3


def _two_lobe_signature(C: np.ndarray, st: _State):
    """``(balance, move share)`` of reversal's four-column layout ``C`` (on the model's rows) fitted beside the model
    ``st`` where it has a two-lobe probe's signature (:data:`REVERSAL_TWO_LOBE_YIELDS`), else None: the approach-signed
    lost motions (columns 0-1) of opposite signs with the smaller at least :data:`TWO_LOBE_BALANCE` of the larger,
    the move-signed pair's norm (columns 2-3) below :data:`TWO_LOBE_MOVE_SHARE` of the approach pair's."""
    C = np.asarray(C, float)
    if C.ndim != 2 or C.shape[1] != 4 or C.shape[0] != len(st.r):
        raise ValueError(f"the move-signed layout has four columns on the model's {len(st.r)} rows, not {C.shape}")
    if not np.all(np.isfinite(C)):
        raise ValueError("the move-signed layout has non-finite columns")
    Cp = C - st.Q @ (st.Q.T @ C)
    b = np.linalg.lstsq(Cp, st.r, rcond=None)[0]
    ax, ay = float(b[0]), float(b[1])
    big = max(abs(ax), abs(ay))
    if not (ax * ay < 0.0) or big <= 0.0:
        return None
    bal = min(abs(ax), abs(ay)) / big
    share = float(np.hypot(b[2], b[3]) / np.hypot(ax, ay))
    if bal >= TWO_LOBE_BALANCE and share < TWO_LOBE_MOVE_SHARE:
        return bal, share
    return None


def _move_pair_p(C: np.ndarray, st: _State, single=None) -> float:
    """p-value of the F test of the move-signed pair (columns 2-3 of reversal's four-column layout ``C`` on the
    model's rows) beyond the model ``st`` and the approach-signed pair (columns 0-1): the partial F test of
    :func:`_grow_layout` with the approach pair as the plainer layout. ``single``: the four columns' own
    :func:`nested_f_batch` against ``st`` where made. 1 where the move pair adds no direction."""
    C = np.asarray(C, float)
    if C.ndim != 2 or C.shape[1] != 4 or C.shape[0] != len(st.r):
        raise ValueError(f"the move-signed layout has four columns on the model's {len(st.r)} rows, not {C.shape}")
    t_a = nested_f_batch(C[None, :, :2], st.Q, st.r, st.rss, st.dof)
    t_f = single if single is not None else nested_f_batch(C[None], st.Q, st.r, st.rss, st.dof)
    k_x = int(t_f[1][0]) - int(t_a[1][0])
    dof_f = st.dof - int(t_f[1][0])
    if k_x <= 0 or dof_f <= 0:
        return 1.0
    F_x = (float(t_f[0][0]) - float(t_a[0][0])) / k_x / max((st.rss - float(t_f[0][0])) / dof_f, 1e-300)
    return float(stats.f.sf(max(F_x, 0.0), k_x, dof_f))


def _support_share(E: np.ndarray, cause=None) -> float:
    """The share of rows on which any column of ``E`` (n, k) acts: the scale of a cause's materiality.

    Only for a cause that books to the workpiece (``cause.books_to``: part_change, one feature's walls); 1 for
    the machine's and the probe's causes and without a cause (session 17's blind check, gen_a outlier 2402: a
    local_scale_defect reaching 5 % of the touches, all at one position, passed materiality scaled to them,
    0.017 against 0.0013 um^2, 0.025 over every touch, and led the report at 0.08 um^2 explained beside 12 um^2
    of chips, ambiguous: one position cannot tell a defect from a gross error there). A workpiece-local cause
    moves the estimates of its own feature's targets only, so its relevance is counted over their touches; a
    machine-side local cause is judged over the campaign, as before session 16.

    Materiality is ``(material_sigma sigma)^2`` per touch of the effect: an
    effect that small moves a target's workpiece estimate by less than half
    its own uncertainty. A cause whose columns are zero off a few touches (a
    changing feature: its walls' columns vanish off that feature) acts on
    those touches only; counted over every touch of the campaign its
    threshold grows with the touches it never reaches, so that a change of
    1 sigma per touch on a wall of 16 touches in 256 (6 %) is immaterial by
    construction (it needs 9 %). The held-out gain (a mean square over all
    rows) is compared with the materiality scaled by this share, i.e. its
    sum of squares with ``(material_sigma sigma)^2`` per touch reached.
    A row is reached where a column's magnitude exceeds 1e-9 of that
    column's largest; a cause acting on every row keeps the share 1 (the
    rule unchanged), as does every cause when :data:`MATERIALITY_OVER_SUPPORT`
    is off. Materiality is a relevance gate beside the significance test:
    the false-alarm rate stays that of the cause's Bonferroni-corrected F test.
    """
    E = np.asarray(E, float)
    if E.ndim != 2 or E.shape[0] == 0:
        raise ValueError(f"_support_share needs an (n, k) matrix with rows, got shape {E.shape}")
    if not np.all(np.isfinite(E)):
        raise ValueError("_support_share: columns with non-finite values")
    if not MATERIALITY_OVER_SUPPORT or E.shape[1] == 0 or getattr(cause, "books_to", None) != "workpiece":
        return 1.0
    a = np.abs(E)
    top = a.max(axis=0)
    reached = np.any((a > 1e-9 * top) & (top > 0), axis=1)
    return float(max(np.mean(reached), 1.0 / E.shape[0]))


def _undetermined_text(key: str, lo, hi, where: str = "") -> str:
    """What the report says of a magnitude whose U95 is wider than its whole plausible range: that it is not
    determined, and the range, never the value or its U95 (numbers of a direction the design leaves open:
    review30c's MFB Z step read ``pretravel_pv = 4.46e+09 +- 7.87e+09`` um; session 30)."""
    rng = f" {lo:g}..{hi:g}" if lo is not None and hi is not None else ""
    return f"{key} not determined{' ' + where if where else ''} (its U95 wider than its plausible range{rng})"


def _plausible(cause, bl, tm: Term, st: _State, rows, cv: float, boot: tuple | None = None) -> dict:
    """The last gate of :func:`_evaluate` and :func:`_evaluate_penalised`: the term's magnitudes (with their U95,
    :func:`_magnitudes`, the penalised branch for a penalised term) within the cause's bounds and its own
    plausibility check. ``{"cv", "term"}`` (the term with its magnitudes at adoption), or a refusal."""
    wide, iv = [], {}
    vals, u95 = _magnitudes(cause, bl, tm, st.Q, rows, wide, boot=boot, intervals=iv)
    tm.evidence.pop("magnitude_intervals", None)
    if iv:  # a norm's 95 % interval (its U95 the symmetric cover): with the magnitudes cached below
        tm.evidence["magnitude_intervals"] = iv
    if wide:  # named at most ambiguous (step 8): the data do not say how large it is
        tm.evidence["magnitude_undetermined"] = "; ".join(
            _undetermined_text(k, lo, hi) for k, v, u, lo, hi in wide)
    # (the penalised terms it was fitted beside: Qo does not show them)
    tm = dataclasses.replace(tm, at_adoption=(st.Q, rows, vals, u95, _pen_key(boot[1] if boot else ())))
    bad = _out_of_bounds(cause, vals, u95)
    if bad:
        return {"reason": bad, "significant": True}
    why = cause.plausible(vals, u95) if cause.plausible else None
    if isinstance(why, causes_mod.Undetermined):
        # the magnitudes the check needs are not determined on this design: not
        # implausible, only unmeasured; the cause is significant and earns its
        # gain, so it is named, ambiguous (step 8)
        tm.evidence["magnitudes_not_determined"] = str(why)
    elif why:
        return {"reason": f"implausible: {why}", "significant": True}
    return {"cv": cv, "term": tm}


def _evaluate_penalised(cause, sc, info, cols, tries, bl, st: _State, folds: Folds, terms, cv_cur, sigma, settings,
                        ev: dict) -> dict:
    """The held-out gain and magnitudes of a penalised named cause (:attr:`core.causes.Cause.penalised`).

    One estimator: the ridge penalty on the cause's columns is chosen by the
    held-out mean square over :data:`PENALTY_GRID` (times the columns' mean
    squared norm outside the model, as the unnamed smooth's), and that
    penalised fit gives the held-out gain, the magnitudes and their U95
    (:func:`_magnitudes`' penalised branch), and, adopted, the in-sample
    residuals (:func:`_state`) and the extended workpiece (:func:`_workpiece`).
    Not refused as confounded: a penalised field spans in part what the
    baseline spans, and the penalty decides the split (the joint fit leaves
    the baseline's span to the baseline where the penalty makes the field's
    coefficients cost more); the variance inflation and principal angle of
    the unpenalised columns are reported only. The gain is the gate.
    """
    rows = st.rows
    E = cols[rows]
    Eo = E - st.Q @ (st.Q.T @ E)
    scale = float(np.trace(Eo.T @ Eo)) / max(E.shape[1], 1)
    if not scale > 0:
        return {"reason": "no columns outside the model"}
    En = _stack(terms, rows)
    cvs = [folds.mse(bl.y[rows], np.hstack([En, E]) if terms else E,
                     _penalty_beside(terms, E.shape[1], f * scale * np.eye(E.shape[1]))) for f in PENALTY_GRID]
    i = _penalty_pick(cvs)
    cv, f = cvs[i], PENALTY_GRID[i]
    gain = cv_cur - cv
    m2 = (settings.material_sigma * sigma) ** 2
    ev.update({"cv_rms_before_um": float(np.sqrt(cv_cur)) / UM, "cv_rms_after_um": float(np.sqrt(cv)) / UM,
               "cv_gain_um2": gain / UM ** 2, "materiality_um2": m2 / UM ** 2, "penalty": float(f),
               "penalty_cv_spread": _penalty_flatness(cvs)})
    if gain < m2:
        return {"reason": f"cross-validated gain {gain / UM ** 2:.3g} um^2 below materiality {m2 / UM ** 2:.3g} um^2",
                "significant": True}
    k = cols.shape[1]
    tm = Term(cause.name, cols, tuple(sc.labels), info, sc.covariate, tries, ev, penalty=f * scale * np.eye(k),
              origin=cause, labels_all=tuple(sc.labels), map=np.eye(k), cols_all=cols)
    return _plausible(cause, bl, tm, st, rows, cv, boot=(folds, terms))


#: Whether a penalised named cause's ridge is chosen again, over the search's grid, in the model the report gives
#: (:func:`_penalties_rechosen`, before step 5). Session 20 (issue 13, gen_a nonrigid 1001, 1092): chosen in the round
#: that adopted it, the penalty is stale once the rows (outliers) and the terms beside it are final.
PENALTY_RECHOSEN = True


def _penalties_rechosen(terms, folds, y, rows) -> list:
    """The terms with each penalised named cause's ridge chosen again by the held-out mean square in this model.

    One estimator (session 15): a penalised named cause's penalty is the one whose fit predicts the held-out set-ups
    best, and its magnitudes, residuals and extended workpiece come from that fit. At adoption the penalty is chosen
    beside the model of that round (its rows, the causes adopted before it); the report's model is the final one,
    after the rival check, the dropped causes and the outliers judged again. Chosen again here over the same grid
    (:data:`PENALTY_GRID` times the scale of its adoption, on which the bootstrap's refits choose too), the others'
    penalties as they are, one term at a time in the order of adoption. The unnamed smooth of step 5 is then judged
    beside the cause's own fit: before, gen_a nonrigid 1001 kept the field at its round-one ridge (10 times the
    scale; held-out 9.37 um^2 in the final model) and the unnamed smooth in ``xy``, the same twelve columns, was
    adopted beside it at 1 (gain 1.72 um^2), read as "a form the cause lacks" and named first; the field chosen
    again at 1 predicts 7.73 um^2 of the smooth's 7.67.
    """
    out = list(terms)
    for i, tm in enumerate(out):
        if tm.penalty is None or tm.unnamed or "penalty" not in tm.evidence or not tm.evidence["penalty"] > 0:
            continue
        k = tm.columns.shape[1]
        scale = float(tm.penalty[0, 0]) / float(tm.evidence["penalty"])
        o = sum(t.columns.shape[1] for t in out[:i])
        E = _stack(out, rows)
        P = _penalty(out)
        cvs = []
        for f in PENALTY_GRID:
            Pf = P.copy()
            Pf[o:o + k, o:o + k] = f * scale * np.eye(k)
            cvs.append(folds.mse(y[rows], E, Pf))
        f = float(PENALTY_GRID[_penalty_pick(cvs)])
        if f != float(tm.evidence["penalty"]):
            ev = {**tm.evidence, "penalty": f, "penalty_at_adoption": float(tm.evidence["penalty"])}
            out[i] = dataclasses.replace(tm, penalty=f * scale * np.eye(k), evidence=ev)
    return out


#: Whether a penalised named cause whose ridge :func:`_penalties_rechosen` moved must pass again, at that ridge in
#: the final model, the gates of its adoption that depend on the ridge (:func:`_rechosen_gate`; session 21, issue 13).
PENALTY_RECHOSEN_GATED = True


def _rechosen_gate(tm: Term, rest: list, terms: list, bl, folds, y, rows, so: _State, m2: float) -> str | None:
    """Why a penalised named cause fails, at the ridge chosen again in the final model, a gate of its adoption that
    depends on the ridge (None: it passes). The figures go to its evidence.

    The gates of :func:`_judge_trial` are of two kinds. The significance F test, the family check (4e), the
    counter-explanation, the support and smooth checks and the variance inflation (reported only for a penalised
    cause) take the cause's unpenalised columns: the ridge does not enter them, and the rival check has judged the
    final model's terms and rows. The held-out gain (:func:`_evaluate_penalised`) and the magnitudes' bounds
    (:func:`_plausible`) are figures of the penalised fit: they are made again here.

    - *Held-out gain*: the final model's held-out mean square without the cause (the others with their penalties)
      less that with it at its new ridge, against materiality ``m2`` (the noise beside the model without it, as at
      adoption). The ridge is the one predicting best, so the gain is the largest the grid gives: a gain below
      materiality here was below it at the adoption's ridge too. A ridge at the grid's largest value is the held-out
      set-ups asking for as little of the field as the grid allows; its limit, an infinite ridge, is the model
      without the field, so whether the edge means "no field" is this same comparison (``penalty_at_grid_edge``
      said in the evidence).
    - *Bounds*: where the ridge went down the field's magnitudes may grow: they are fitted again (the delta method's
      U95, as at adoption) and refused wholly outside the cause's bounds or by its own plausibility check (as
      :func:`_plausible`; `nonrigid` has none). A larger ridge shrinks them: not refitted.
    """
    cv_w = folds.mse(y[rows], _stack(terms, rows), _penalty(terms))
    cv_wo = folds.mse(y[rows], _stack(rest, rows), _penalty(rest)) if rest else folds.mse(y[rows])
    gain = cv_wo - cv_w
    f, f0 = float(tm.evidence["penalty"]), float(tm.evidence["penalty_at_adoption"])
    tm.evidence.update({"cv_gain_um2_rechosen": gain / UM ** 2, "materiality_um2_rechosen": m2 / UM ** 2,
                        "penalty_at_grid_edge": bool(f >= max(PENALTY_GRID))})
    if gain < m2:
        return (f"its ridge chosen again in the final model ({f:g} times its scale, {f0:g} at adoption"
                + (", the grid's largest" if f >= max(PENALTY_GRID) else "")
                + f"): cross-validated gain {gain / UM ** 2:.3g} um^2 below materiality {m2 / UM ** 2:.3g} um^2")
    if f < f0 and tm.origin is not None:
        vals, u95 = _magnitudes(tm.origin, bl, tm, so.Q, rows, boot=(folds, rest))
        bad = _out_of_bounds(tm.origin, vals, u95)
        why = tm.origin.plausible(vals, u95) if tm.origin.plausible else None  # (nonrigid has no such check)
        if not bad and why and not isinstance(why, causes_mod.Undetermined):
            bad = f"implausible: {why}"
        if bad:
            return f"its ridge chosen again in the final model ({f:g} times its scale, {f0:g} at adoption): {bad}"
    return None


def _out_of_bounds(cause, vals: dict, u95: dict) -> str | None:
    """The first magnitude whose interval (value +- U95) lies wholly outside the cause's bounds, as words (None:
    none does): :func:`_plausible`'s bounds gate."""
    for key, v in vals.items():
        if not isinstance(v, float) or v is None:
            continue
        for pat, (lo, hi) in cause.bounds.items():
            if _matches(key, pat):
                u = u95.get(key) or 0.0
                if v + u < lo or v - u > hi:
                    return f"implausible {key} = {v:.3g} (bounds {lo:g}..{hi:g})"
    return None


#: Parametric bootstrap refits of a penalised named cause's magnitudes (:func:`_penalised_bootstrap`), and the seed of
#: their draws (fixed: one campaign, one U95).
PENALISED_BOOT = 200
#: A named cause's magnitudes and U95 in the report fitted beside the unnamed smooth when one is adopted (session 20;
#: False: beside the other named causes alone, as before, the smooth's columns left out of their covariance).
MAGNITUDES_BESIDE_SMOOTH = True
#: Beside the smooth, the value reported: "named_alone" (the fit beside the named causes alone, its U95
#: hypot(U95 beside the smooth, shift): session 20's review's alternative, kept: on the 30 magnitudes of the tuning
#: campaigns beside a smooth with a known truth 24 inside U95 against 23, median |error| 0.76 against 1.28, the same
#: median U95 1.38) or "smooth" (the fit beside the smooth's columns, the shift carried where significant).
MAGNITUDES_BESIDE_SMOOTH_VALUE = "named_alone"
#: A magnitude a cause declares the norm of a coefficient pair (:attr:`core.causes.Cause.norms`: a harmonic's
#: amplitude) takes its U95 from the 95 % interval of the norm (:func:`norm_interval`, session 21; False: the delta
#: method's, as before, which covered the generators' zero amplitudes 50-56 % of the time).
NORM_INTERVALS = True
PENALISED_BOOT_SEED = 16


def _penalised_bootstrap(cause, bl, tm: Term, Ep, ro, yr, Qo, rows, folds, others, c_hat, s2, vals, num) -> dict:
    """U95 of a penalised named cause's magnitudes by a parametric bootstrap with the ridge chosen again (session 16).

    The ridge's Bayesian covariance ``s^2 (E^T E + P)^-1`` ignores the
    shrinkage's bias and, through the delta method, treats a field's RMS
    near zero and its signed peak (a maximum over the extent) as linear in
    the coefficients, and a bootstrap from the fitted field alone has no
    spread along what the data do not determine (the field's split with
    the baseline, one axis' field for the other's). Here
    :data:`PENALISED_BOOT` truths are drawn from the ridge's posterior
    ``N(c, s^2 (E^T E + P)^-1)`` and a data set from each (the model's
    part beside the cause, the truth's field, normal noise of the fit's
    ``s``; the draws fixed by :data:`PENALISED_BOOT_SEED`); each chooses
    its own penalty over the search's grid (:data:`PENALTY_GRID` times the
    scale the search used, so the reported fit's penalty is on it) by the same
    held-out mean square as the search (the folds, beside the other terms with their
    penalties) and is refitted as the magnitudes are. From the refits'
    errors ``d = m(refit) - m(truth)``, the basic (bias-corrected) 95 %
    interval ``[m - q97.5(d), m - q2.5(d)]`` around the fitted magnitude
    ``m``: the refits' mean shortfall (the shrinkage's bias) is put back
    on the other side. The U95 reported beside ``m`` is the larger of its
    two sides. A magnitude bounded below by zero (an RMS) whose interval
    reaches zero is not distinguishable from none: its upper one-sided
    95 % bound ``m - q5(d)`` is given and the U95 reaches from zero to it.
    The intervals go to the term's evidence (``magnitude_interval95``).

    Returns {key: U95 or None (a refit gave a non-finite magnitude)}. Raises ValueError on inconsistent shapes or
    a noise variance ``s2`` that is not finite and non-negative.
    """
    n = len(rows)
    Ep, ro, yr, c_hat = (np.asarray(a, float) for a in (Ep, ro, yr, c_hat))
    k = Ep.shape[1] if Ep.ndim == 2 else -1
    if Ep.ndim != 2 or Ep.shape[0] != n or ro.shape != (n,) or yr.shape != (n,) or Qo.shape[0] != n \
            or c_hat.shape != (k,):
        raise ValueError(f"penalised bootstrap: columns {Ep.shape}, residuals {ro.shape}, data {yr.shape}, model "
                         f"{Qo.shape}, coefficients {c_hat.shape} for {n} rows do not match")
    if not (np.isfinite(s2) and s2 >= 0):
        raise ValueError(f"penalised bootstrap: noise variance {s2} is not finite and non-negative")
    E = tm.columns[rows]
    G = Ep.T @ Ep
    # the search's own grid (PENALTY_GRID times the scale of the columns outside the model the cause was adopted
    # beside, :func:`_evaluate_penalised`), on which the reported fit's penalty lies; the columns' scale outside the
    # final model (trace(G) / k) is another (0.76-1.14 of it on gen_a nonrigid 1000-1091): session 17's review
    scale = float(tm.penalty[0, 0]) / float(tm.evidence["penalty"])
    rng = np.random.default_rng(PENALISED_BOOT_SEED)
    # the truths: the fitted coefficients plus a draw of the ridge's posterior s^2 (E^T E + P)^-1 (its prior's spread
    # along what the data do not determine: the split with the baseline, one axis' field for the other's)
    # (through the covariance's principal square root V sqrt(w) V^T, unique for a symmetric positive semi-definite
    # matrix: V alone is not where eigenvalues (nearly) repeat, and BLAS kernels that round differently rotate it,
    # so V sqrt(w) drew other truths on other machines: gen_a nonrigid 2's EX peak interval 5.64 to 6.09 um high)
    w, V = np.linalg.eigh(s2 * np.linalg.pinv(G + tm.penalty, rcond=1e-12, hermitian=True))
    Ct = c_hat[:, None] + ((V * np.sqrt(np.maximum(w, 0.0))) @ V.T) @ rng.standard_normal((k, PENALISED_BOOT))
    Z = rng.standard_normal((n, PENALISED_BOOT)) * np.sqrt(s2)
    fit = Ep @ Ct
    Y = (yr - ro)[:, None] + fit + Z  # the model's part beside the cause, each truth's field, noise
    Ro = fit + (Z - Qo @ (Qo.T @ Z))
    X = np.hstack([_stack(others, rows), E]) if others else E
    C = np.zeros((k, PENALISED_BOOT))
    ErO = Ep.T @ Ro
    cvs = np.empty((len(PENALTY_GRID), PENALISED_BOOT))
    for j, f in enumerate(PENALTY_GRID):
        e = folds.residuals(Y, X, _penalty_beside(others, k, f * scale * np.eye(k)))
        cvs[j] = np.sum(e ** 2, axis=0) / max(folds.last_dof, 1)
    pick = _penalty_pick(cvs)  # each refit's penalty, by the search's rule
    for j, f in enumerate(PENALTY_GRID):
        won = pick == j
        if won.any():
            C[:, won] = np.linalg.solve(G + f * scale * np.eye(k), ErO[:, won])
    if getattr(cause.magnitudes, "columns", False):  # every refit at once (nonrigid_magnitudes)
        draws, truths = cause.magnitudes(tm.info, C, bl), cause.magnitudes(tm.info, Ct, bl)
    else:  # one refit at a time
        draws, truths = ({key: np.array([float(mg.get(key, np.nan)) for mg in ms]) for key in num}
                         for ms in ([cause.magnitudes(tm.info, A[:, b], bl) for b in range(PENALISED_BOOT)]
                                    for A in (C, Ct)))
    out, iv = {}, {}
    for key in num:
        m = float(vals[key])
        d = np.asarray(draws.get(key, np.nan), float) - np.asarray(truths.get(key, np.nan), float)
        d = np.broadcast_to(d, (PENALISED_BOOT,))
        if not np.all(np.isfinite(d)):
            out[key] = None
            continue
        lo, hi = m - np.quantile(d, 0.975), m - np.quantile(d, 0.025)
        if lo <= 0 and any(_matches(key, pat) and b[0] == 0 for pat, b in cause.bounds.items()):
            up = m - float(np.quantile(d, 0.05))
            out[key] = float(max(up - m, m))
            iv[key] = {"upper_one_sided": up}
        else:
            out[key] = float(max(hi - m, m - lo))
            iv[key] = {"low": float(lo), "high": float(hi)}
    tm.evidence["magnitude_interval95"] = {"method": f"parametric bootstrap, {PENALISED_BOOT} refits, the ridge chosen "
                                                    "again on each", **iv}
    return out


def _magnitudes(cause, bl, tm: Term, Qo: np.ndarray, rows, wide: list | None = None, boot: tuple | None = None,
                lin: dict | None = None, intervals: dict | None = None, held: bool = False, lower: dict | None = None):
    """Magnitudes of a term and their U95 (delta method over coefficients and nonlinear parameters).

    ``boot`` ``(folds, others[, report])``: the folds the model's held-out
    figures use and the other terms of the model (``Qo`` spans the baseline
    and the unpenalised ones). With it an unpenalised cause's coefficients
    are fitted beside the penalised others with their penalty (session 16:
    before, beside ``Qo`` alone, as if the penalised cause were not in the
    model); with ``report`` true a penalised named cause's U95 comes from
    :func:`_penalised_bootstrap` (the report's findings; else, at each
    adoption test, the ridge's Bayesian covariance by the delta method).

    A bounded magnitude whose U95 is wider than its whole plausible range is
    reported as no value (it determines nothing); its key, the value and
    the U95 are appended to ``wide`` when given.

    ``lin`` (an unpenalised cause, a dict): filled with the fit's linear map
    from the data to the reduced coefficients (``"A"``, ``c = A y[rows]``),
    the label map ``"M"``, the residual variance ``"s2"`` and each magnitude's
    gradient over the label coefficients (``"g"``): what
    :func:`_beside_smooth`'s shift test needs for the exact variance of a
    difference of two such fits.

    ``intervals`` (a dict): filled with ``key: [lo, hi]``, the 95 % interval of
    each norm magnitude (:attr:`core.causes.Cause.norms`, :func:`norm_interval`)
    whose U95 is its symmetric cover (unpenalised causes).

    ``held`` (an unpenalised cause): the label directions outside the span of
    ``tm.map`` are held at 0 by construction, not because the data cannot see
    them (:func:`_reading_u95` fits the other reading of the pre-travel in
    the chosen reading's combinations: on gen_b the approach reading's first
    harmonic, which the normal reading leaves in the baseline): a magnitude
    that needs one is not reported, as one that needs an unseen direction is
    not (before, the held coefficient read as a measured zero: gen_b
    probe_lobing 1002's other reading showed ``k1_amplitude_um`` 9e-17 +-
    7e-17 um; session 23).

    ``lower`` (a dict): filled with ``key: value`` of each norm not reported
    because a coefficient of its pair is unseen or held: the norm with that
    coefficient at 0, a lower bound of the amplitude (:func:`_reading_u95`
    carries it).

    ``Qo``: orthonormal basis of the model without the term (rows used).
    By Frisch-Waugh-Lovell the term's coefficients in the joint fit are the
    least squares of the other model's residuals on the term's columns
    projected out of it; their covariance ``s^2 (E_p^T E_p)^-1`` widens with
    the nonlinear parameters' Jacobian columns.
    """
    M = tm.map
    labels_all = tm.labels_all
    E = tm.columns[rows] @ M
    yr = bl.y[rows]
    ro = yr - Qo @ (Qo.T @ yr)
    Ep = E - Qo @ (Qo.T @ E)
    k_all = len(labels_all)
    if tm.penalty is not None and not tm.unnamed:
        # a penalised named cause: the ridge fit's coefficients and its covariance s^2 (E^T E + P)^-1; every
        # direction is determined by the penalty (none is reported weak: the penalty, chosen by the held-out
        # mean square, decides what the baseline's span keeps)
        c_red, cov, s2, _ = _penalised_fit(Ep, ro, tm.penalty, len(rows) - Qo.shape[1])
        vals = cause.magnitudes(tm.info, c_red, bl)
        num = [key for key, v in vals.items() if isinstance(v, (float, int, np.floating)) and not isinstance(v, bool)]
        if boot is not None and len(boot) > 2 and boot[2] and isinstance(boot[0], Folds):
            u95b = _penalised_bootstrap(cause, bl, tm, Ep, ro, yr, Qo, rows, boot[0], boot[1], c_red, s2, vals, num)
            out, u95 = {}, {}
            for key, v in vals.items():
                if key not in num:
                    out[key] = v
                elif u95b.get(key) is None:
                    out[key], u95[key] = float(v), None
                else:
                    out[key], u95[key] = _within_range(cause, key, float(v), u95b[key], wide)
            return out, u95
        # central differences, each coefficient's pair of magnitudes made once for every key
        grads = {key: np.zeros(k_all) for key in num}
        for j in range(k_all):
            h = max(np.sqrt(max(cov[j, j], 0.0)) * 1e-3, abs(c_red[j]) * 1e-6, 1e-12)
            cp, cm = c_red.copy(), c_red.copy()
            cp[j] += h
            cm[j] -= h
            mp, mm = cause.magnitudes(tm.info, cp, bl), cause.magnitudes(tm.info, cm, bl)
            for key in num:
                grads[key][j] = (mp[key] - mm[key]) / (2 * h)
        u95, out = {}, {}
        for key, v in vals.items():
            if key not in grads:
                out[key] = v
                continue
            g = grads[key]
            out[key], u95[key] = _within_range(cause, key, float(v), float(2 * np.sqrt(max(g @ cov @ g, 0.0))),
                                               wide)
        return out, u95
    # penalised terms of the model (an adopted nonrigid): fitted with the cause's columns, with their penalty (Qo spans
    # only the baseline and the unpenalised terms)
    pen = _pen_of(boot[1], rows) if boot is not None else None
    if pen is not None:
        Sp = pen[0] - Qo @ (Qo.T @ pen[0])
        c_red, _, s2, _ = _penalised_fit(np.hstack([Ep, Sp]), ro, np.pad(pen[1], ((Ep.shape[1], 0),) * 2),
                                         len(rows) - Qo.shape[1])
        c_red = c_red[:Ep.shape[1]]
        if lin is not None:  # c = (X^T X + P)^-1 X^T ro, its cause's rows (X's columns lie outside Qo: ro -> yr)
            Xa = np.hstack([Ep, Sp])
            Pa = np.pad(pen[1], ((Ep.shape[1], 0),) * 2)
            lin["A"] = (np.linalg.pinv(Xa.T @ Xa + Pa, rcond=1e-12, hermitian=True) @ Xa.T)[:Ep.shape[1]]
    else:
        c_red = np.linalg.lstsq(Ep, ro, rcond=1e-12)[0]
        if lin is not None:
            lin["A"] = np.linalg.pinv(Ep, rcond=1e-12)
        res = ro - Ep @ c_red
        dof = max(len(rows) - Qo.shape[1] - E.shape[1], 1)
        s2 = float(res @ res) / dof
    coef = M @ c_red
    nl = [nm for nm in cause.nonlinear if nm in tm.info] if cause.rebuild is not None else []
    # Jacobian columns of the nonlinear parameters at the fit
    J = []
    for name in nl:
        h = max(abs(tm.info[name]) * 1e-6, 1e-9)
        ip, im = dict(tm.info), dict(tm.info)
        ip[name] += h
        im[name] -= h
        J.append((cause.rebuild(bl, ip)[0][rows] - cause.rebuild(bl, im)[0][rows]) @ coef / (2 * h))
    X = np.hstack([Ep] + [(j - Qo @ (Qo.T @ j))[:, None] for j in J]) if J else Ep
    if pen is not None:  # the block of the joint penalised fit's Bayesian covariance (as _penalised_fit's)
        nx = X.shape[1]
        Xa = np.hstack([X, Sp])
        cov_all = s2 * np.linalg.pinv(Xa.T @ Xa + np.pad(pen[1], ((nx, 0),) * 2), rcond=1e-12, hermitian=True)[:nx, :nx]
    else:  # conditioning checked (review31d F6): inv where well conditioned, else X's own SVD at lsq's rank tolerance
        cov_all = s2 * lsq_mod.normal_inverse(X)
    vec0 = np.concatenate([coef, [tm.info[nm] for nm in nl]])  # label coefficients, then nl

    def f(vec):
        inf = dict(tm.info)
        for j, nm in enumerate(nl):
            inf[nm] = float(vec[k_all + j])
        return cause.magnitudes(inf, vec[:k_all], bl)

    vals = f(vec0)
    if lin is not None:
        lin["M"], lin["s2"], lin["g"] = M, float(s2), {}
    # covariance of the label coefficients (c = M c') and the nonlinear parameters
    r = M.shape[1]
    nv = k_all + len(nl)
    T = np.zeros((nv, r + len(nl)))
    T[:k_all, :r] = M
    T[k_all:, r:] = np.eye(len(nl))
    cov = T @ cov_all @ T.T
    std = np.sqrt(np.maximum(np.diag(cov), 0))
    grads = {}
    for j in range(nv):
        h = max(std[j] * 1e-3, abs(vec0[j]) * 1e-9, 1e-15 if j >= k_all else 1e-12)
        vp, vm = vec0.copy(), vec0.copy()
        vp[j] += h
        vm[j] -= h
        fp, fm = f(vp), f(vm)
        for key in vals:
            if isinstance(vals[key], float):
                grads.setdefault(key, np.zeros(nv))[j] = (fp.get(key, np.nan) - fm.get(key, np.nan)) / (2 * h)
    if lin is not None:
        lin["g"] = {key: g[:k_all] for key, g in grads.items()}
    # a magnitude is determined when it does not move along a direction of the
    # cause's columns that the data cannot see (inside the model, or collinear)
    Eall = tm.cols_all[rows] if tm.cols_all is not None else E
    zero_col = np.linalg.norm(Eall, axis=0) == 0
    nrm = np.maximum(np.linalg.norm(Eall, axis=0), 1e-300)
    Pn = Eall / nrm - Qo @ (Qo.T @ (Eall / nrm))
    if pen is not None:  # what the penalised terms' ridge leaves of the columns (_gram_beside)
        w, V = np.linalg.eigh(_gram_beside(Pn, Qo, pen))
        weak = V.T[np.sqrt(np.maximum(w, 0.0)) < WEAK_SV]
    else:
        _, sv, Vt = np.linalg.svd(Pn, full_matrices=False)
        weak = Vt[sv < WEAK_SV]
    if held and M.shape[1] < k_all:
        # the directions the map holds at 0, in the same normalised coordinates as weak's (c_j = v_j / nrm_j): the
        # complement of the map's span there. The directions the data cannot see are looked for within the map's
        # span only, where the term is fitted (before, over all the labels: a direction weak outside the span but
        # leaning on a held one sent gen_b probe_lobing 1294's other-reading k3 and k4 to their lower bounds, though
        # that reading measures them, 1.997 +- 0.758 and 0.024 +- 0.088 um; the session 23 review)
        Uh, sh, _ = np.linalg.svd(nrm[:, None] * M, full_matrices=True)
        rk = int(np.sum(sh > 1e-12 * max(sh.max(initial=0.0), 1e-300)))
        B = Uh[:, :rk]
        if pen is not None:
            w, V = np.linalg.eigh(B.T @ _gram_beside(Pn, Qo, pen) @ B)
            weak = (B @ V[:, np.sqrt(np.maximum(w, 0.0)) < WEAK_SV]).T
        else:
            _, sv, Vt = np.linalg.svd(Pn @ B, full_matrices=False)
            weak = Vt[sv < WEAK_SV] @ B.T
        weak = np.vstack([weak, Uh[:, rk:].T])
    elif VIF_DROP_BEYOND_MAX and M.shape[1] < k_all:
        # the directions _determined left out (beyond vif_max, or WEAK_SV where the model has since changed) are
        # held at 0 by the map: a magnitude that needs one is not reported, as one that needs an unseen direction
        # is not (session 28: gen_a c_drift 1998's creep read -31 +- 6 urad with its inflated direction held at 0)
        Uh, sh, _ = np.linalg.svd(nrm[:, None] * M, full_matrices=True)
        rk = int(np.sum(sh > 1e-12 * max(sh.max(initial=0.0), 1e-300)))
        weak = np.vstack([weak, Uh[:, rk:].T])
    u95, out = {}, {}
    norms = getattr(cause, "norms", None)  # (a cause-like record without the field: none)
    for key, v in vals.items():
        if not (isinstance(v, (float, int, np.floating)) and not isinstance(v, bool)):
            out[key] = v
            continue
        g = grads.get(key)
        if g is None or not np.all(np.isfinite(g)):
            out[key], u95[key] = float(v), None
            continue
        if MAGNITUDE_ZERO_COLUMN_UNSEEN and np.any(g[:k_all][zero_col] != 0):
            # it moves with the coefficient of a column that is exactly zero (no data at all: a mended lobing
            # column, core.causes.STYLUS_LOBING_MENDED), a direction unseen by construction. Said here, not through
            # g / 1e-300 below, whose norm overflows to inf and lets such a magnitude through (session 37)
            out[key], u95[key] = None, None
            continue
        gn = g[:k_all] / nrm
        if weak.shape[0] and np.max(np.abs(weak @ gn)) > 1e-2 * max(np.linalg.norm(gn), 1e-300):
            out[key], u95[key] = None, None
            continue
        pair = norms(tm.info).get(key) if norms is not None else None
        if pair is not None and weak.shape[0] and np.max(np.abs(weak[:, list(pair)])) > 1e-2:
            # a norm whose pair has a coefficient along a direction the data cannot see: its gradient there is 0
            # where that coefficient is held at 0, yet |m| = hypot(c_i, c_j) grows with it: the value is a lower
            # bound, not an estimate (gen_a periodic_axis_error 1025: EXX amplitude 3.970 +- 0.273 um reported with
            # its cos coefficient undetermined; the session 22 review)
            out[key], u95[key] = None, None
            if lower is not None:
                lower[key] = float(v)
            continue
        u = float(2 * np.sqrt(max(g @ cov @ g, 0.0)))
        nu = _norm_u95(cause, tm.info, key, float(v), coef, cov[:k_all, :k_all]) if NORM_INTERVALS else None
        if nu is not None:  # a harmonic's amplitude: the interval of a norm (session 21), not the delta method's
            u = nu[0]
            if intervals is not None:
                intervals[key] = list(nu[1])
        out[key], u95[key] = _within_range(cause, key, float(v), u, wide)
        if intervals is not None and out[key] is None:
            intervals.pop(key, None)
    return out, u95


#: Gauss-Legendre nodes of :func:`norm_cdf`'s one integral (over the normal's first principal axis, within
#: NORM_CDF_SPAN of its standard deviations): the probability to about 1e-10 where checked against 1e6 draws' 1e-3
#: and down to an eigenvalue ratio of 1e-2 against adaptive quadrature (1e-12); below it the inner CDF is nearly a step
#: and the nodes too few: 6.6e-4 at a ratio of 1e-3, 9e-3 at 1e-6 (the session 21 review; the campaigns it logged had
#: ratios down to 0.05)
_NORM_NODES = np.polynomial.legendre.leggauss(96)
NORM_CDF_SPAN = 9.0


def norm_cdf(r: float, mu: np.ndarray, S: np.ndarray) -> float:
    """``P(|X| <= r)`` for ``X ~ N(mu, S)`` in two dimensions (the length of a 2-D normal vector).

    In the principal axes of ``S`` (variances ``l1 >= l2``, ``mu`` there ``nu``) it is one integral over the
    first coordinate ``x``, of its density times ``P(|x2| <= sqrt(r^2 - x^2))``; ``x = r sin t`` takes the
    square root's end points smoothly, and only ``x`` within :data:`NORM_CDF_SPAN` of its standard deviations of
    ``nu_1`` is integrated (the rest weighs below 1e-18). Isotropic ``S`` gives the Rice distribution's CDF
    (noncentral chi-square with two degrees of freedom of ``r^2 / s^2``).
    """
    return float(_norm_cdf_many(r, np.asarray(mu, float)[None], np.linalg.eigh(np.asarray(S, float)))[0])


#: The coverage of a norm's interval (:func:`norm_interval`): the report's U95 is twice the standard uncertainty
#: (k = 2, 95.45 % of a normal), so far from zero the interval is the delta method's ``|m| +- 2 u``
NORM_LEVEL = float(stats.norm.cdf(2.0) - stats.norm.cdf(-2.0))


#: The share of :func:`norm_interval`'s miss probability spent on the phase (Berger and Boos 1994): the phases
#: consistent with the estimate at this level are the ones the amplitude's test is run over
NORM_PHASE_SHARE = 0.1
#: Phases (over the hull of those allowed, within half a turn: ``|X|``'s law is the same at ``mu`` and ``-mu``)
#: :func:`norm_interval` tries besides the estimate's own, where ``S`` is not isotropic (its eigenvalues' ratio
#: below :data:`NORM_ISOTROPIC`; at or above it every phase gives the same law and the estimate's alone is tried)
NORM_PHASES = 12
NORM_ISOTROPIC = 1 - 1e-6


def _norm_cdf_many(r: float, MU: np.ndarray, eig) -> np.ndarray:
    """:func:`norm_cdf` at every row of ``MU``, ``S``'s eigen-decomposition ``eig = (w, V)`` given (one integral
    per row, the same nodes)."""
    w, V = eig
    l1, l2 = max(w[1], 0.0), max(w[0], 0.0)
    NU = np.asarray(MU, float) @ V
    nu1, nu2 = NU[:, 1], NU[:, 0]
    s1 = np.sqrt(l1)
    if r <= 0 or s1 == 0:
        return (np.hypot(nu1, nu2) <= r).astype(float)
    s2 = max(np.sqrt(l2), 1e-12 * s1)
    a, b = np.maximum(nu1 - NORM_CDF_SPAN * s1, -r), np.minimum(nu1 + NORM_CDF_SPAN * s1, r)
    ok = a < b
    a, b = np.where(ok, a, 0.0), np.where(ok, b, 0.0)
    ta, tb = np.arcsin(a / r), np.arcsin(b / r)
    x, wt = _NORM_NODES
    t = 0.5 * (tb - ta)[:, None] * x + 0.5 * (tb + ta)[:, None]
    ct = np.cos(t)
    x1, h = r * np.sin(t), r * ct
    inner = special.ndtr((h - nu2[:, None]) / s2) - special.ndtr((-h - nu2[:, None]) / s2)
    dens = np.exp(-0.5 * ((x1 - nu1[:, None]) / s1) ** 2) / (s1 * np.sqrt(2 * np.pi))
    out = 0.5 * (tb - ta) * np.sum(wt * dens * inner * r * ct, axis=1)
    return np.where(ok, np.clip(out, 0.0, 1.0), 0.0)


def _root_in_cell(f, grid: np.ndarray, g: np.ndarray, target: float, xtol: float) -> float:
    """The root of ``f(A) = target`` for ``f`` decreasing, ``g = f(grid)`` known: the grid's cell that brackets
    it, then the Illinois variant of regula falsi on the probits (``f`` a tail probability is nearly a normal
    CDF of ``A``: its probit nearly linear, a few steps), to ``xtol``."""
    i = int(np.searchsorted(-g, -target, side="left"))  # first grid point at or below the target
    i = min(max(i, 1), grid.size - 1)
    a, b = float(grid[i - 1]), float(grid[i])
    z = float(special.ndtri(target))

    def pz(v):  # (special.ndtri: stats.norm.ppf's values without its overhead)
        return float(special.ndtri(min(max(v, 1e-300), 1 - 1e-16))) - z

    fa, fb = pz(float(g[i - 1])), pz(float(g[i]))
    if fa <= 0:
        return a
    if fb >= 0:
        return b
    side = 0
    for _ in range(60):
        c = b - fb * (b - a) / (fb - fa)
        if not a < c < b:
            c = 0.5 * (a + b)
        fc = pz(f(c))
        if fc > 0:
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
        else:
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
        if b - a <= xtol or fc == 0:
            break
    return float(c)


def norm_interval(m: np.ndarray, S: np.ndarray, level: float = NORM_LEVEL) -> tuple:
    """The ``level`` confidence interval ``(lo, hi)`` of ``|mu|`` from ``m ~ N(mu, S)`` in two dimensions.

    The amplitude of a harmonic (the norm of its cos and sin coefficients) is no normal estimate: ``|m|``
    is biased up by the noise (the Rice bias: at ``mu = 0`` its mean is ``1.25 s``) and a true zero lies on
    the boundary, so the delta method's ``|m| +- 2 sqrt(u^T S u)`` (``u = m / |m|``) covers a zero about half
    the time. Here the equal-tailed test of ``|mu| = A`` by ``|m|`` is inverted: ``A`` is inside when
    ``(1 - a) / 2 <= P(|X| <= |m|) <= (1 + a) / 2`` for ``X ~ N(A u_phi, S)`` (:func:`norm_cdf`) at some phase
    ``phi`` the data allow. With ``S`` not isotropic that probability depends on the unknown phase (the
    session 21 review: holding the estimate's phase covered 0.87-0.92 along the noisy axis of
    ``diag(1, 0.01)``-``diag(1, 0.067)`` at amplitudes of 0.5-3 noise widths), so the phase is a nuisance
    handled as Berger and Boos (1994) do: the phases whose direction across ``u_phi`` the estimate is
    consistent with, ``|m . v_phi| <= z sqrt(v_phi^T S v_phi)`` (``v_phi`` across ``u_phi``: exact, that
    component is pure noise at the true phase) at the level ``g = NORM_PHASE_SHARE (1 - level)``, and the
    amplitude's test at ``a = level + g`` (both misses add to at most ``1 - level``). Near zero every phase is
    allowed (the interval of the worst phase); far from it only phases near the estimate's, and the
    interval is the delta method's with ``k`` about 2.05-2.1 instead of 2. The allowed phases are found on a
    fine grid over half a turn; :data:`NORM_PHASES` + 1 phases over their hull (its ends included) and the
    estimate's own are tried (the estimate's alone where ``S`` is isotropic, :data:`NORM_ISOTROPIC`). ``lo = 0`` where a zero is consistent with ``|m|``; where
    ``|m|`` is below the lower quantile of the zero's own distribution (a draw of the lower tail) the set
    is ``{0}``: ``(0, 0)``. Each phase's probability falls as ``A`` grows (Anderson's theorem: a disc
    centred on 0), so the least and the largest over the phases do too, and each end is one root.
    """
    m = np.asarray(m, float)
    r = float(np.hypot(*m))
    S = np.asarray(S, float)
    sd = float(np.sqrt(max(np.max(np.linalg.eigvalsh(S)), 0.0)))
    if sd == 0 or not np.isfinite(sd):
        return r, r
    if r == 0:  # the estimate at the origin: every phase alike, and |m| = 0 is no draw above any quantile
        return 0.0, 0.0
    u = m / r
    g = NORM_PHASE_SHARE * (1 - level)
    a = level + g
    lo_p, hi_p = (1 - a) / 2, (1 + a) / 2
    # the allowed phases, about the estimate's (d = phi - phi_m over half a turn, on a fine grid: their hull, its
    # ends and the estimate's own among NORM_PHASES + 1 phases tried)
    d = np.linspace(-np.pi / 2, np.pi / 2, 8 * NORM_PHASES + 1)
    ph = d + np.arctan2(u[1], u[0])
    Vx = np.column_stack([-np.sin(ph), np.cos(ph)])
    across = np.abs(Vx @ m) <= -special.ndtri(g / 2) * np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", Vx, S, Vx), 0.0))
    # the estimate's own phase (d = 0, the grid's middle) is allowed by construction: m . v = 0 there in exact
    # arithmetic. Rounding leaves about 1e-16 |m|, which a pair whose spread across m is itself a rounding cannot
    # hold (a pair with one coefficient undetermined by the design: a candidate periodic_axis_error's EXY/EYY
    # on the gen_a probe_lobing 1025 campaign, S's eigenvalues 1.5e-45 and 3.6e-14 m^2, and session 22's blind
    # gen_a seed 5307; the set was empty and discover stopped with an IndexError. _magnitudes does not report
    # such a norm: only its interval given S is asked here)
    across[4 * NORM_PHASES] = True
    k = np.flatnonzero(across)
    w = np.linalg.eigvalsh(S)
    d = (np.union1d(np.linspace(d[k[0]], d[k[-1]], NORM_PHASES + 1), [0.0]) if w[0] < NORM_ISOTROPIC * w[1]
         else np.zeros(1))
    ph = d + np.arctan2(u[1], u[0])
    U = np.column_stack([np.cos(ph), np.sin(ph)])
    eig = np.linalg.eigh(S)

    def F(A):  # (least, largest) over the phases, at every amplitude of A
        A = np.atleast_1d(np.asarray(A, float))
        P = _norm_cdf_many(r, (A[:, None, None] * U[None]).reshape(-1, 2), eig).reshape(A.size, len(U))
        return P.min(axis=1), P.max(axis=1)

    F0 = float(F(0.0)[1][0])  # (every phase alike at A = 0)
    if F0 <= lo_p:  # |m| below the lower quantile even of a zero: no A > 0 is consistent (the test's own tail)
        return 0.0, 0.0
    # both ends on one grid of amplitudes (one evaluation for all), each refined in its cell
    top = r + 4 * sd
    while F(top)[1][0] > lo_p:
        top += 4 * sd
    grid = np.linspace(0.0, top, 17)
    gmin, gmax = F(grid)
    lo = 0.0
    if F0 > hi_p:
        lo = _root_in_cell(lambda A: F(A)[0][0], grid, gmin, hi_p, 1e-6 * sd)
    hi = _root_in_cell(lambda A: F(A)[1][0], grid, gmax, lo_p, 1e-6 * sd)
    return float(lo), float(hi)


#: A scan's refined nonlinear parameters that a cause declares (:attr:`core.causes.Cause.profile`: a local scale
#: defect's centre and half-width) take their U95 from the profile likelihood over a grid (:func:`_profile_u95`,
#: session 21; False: the delta method's, as before)
PROFILE_NONLINEAR = True
#: Trials of :func:`_profile_u95` fitted at once (their columns are trials x rows), fewer on a long log: a chunk's
#: columns and their projection stay within :data:`PROFILE_CHUNK_BYTES` (1,000 trials up to about 11,000 rows, so
#: every campaign of the tests and studies is fitted as before; a 1e6-row log takes 11 trials a chunk, 270 MB,
#: where 1,000 would be 24 GB)
PROFILE_CHUNK = 1000
PROFILE_CHUNK_BYTES = 256 << 20


def _profile_u95(cause, bl, tm: Term, Qo: np.ndarray, rows) -> dict:
    """Profile-likelihood intervals of a cause's nonlinear parameters (:attr:`core.causes.Cause.profile`).

    On the grid of every declared parameter (all combinations), the term's one column is rebuilt and fitted
    beside ``Qo`` (the model without it: its linear coefficients profiled out by projection, as
    :func:`_magnitudes` fits). A value is inside where the least residual sum of squares over the other
    parameters' grid stays within ``4 s^2`` of the least over all (``s^2`` the fit's residual variance; 4 the
    chi-square quantile of one degree of freedom at k = 2, 95.45 %): the interval ``[lo, hi]`` is the hull of
    those values widened to the next grid point out on each side (the set's boundary lies before it), the U95 ``max(hi - v, v - lo)`` about the fitted ``v``. The delta method linearises the
    residuals at the fit; a bump's centre and width are read off the few touches under it, where the sum of
    squares moves in steps. ``{key: (U95, lo, hi, at_edge)}`` in the magnitudes' units; ``at_edge`` where the
    set reaches the grid's end (the interval is then at least that). Unpenalised terms only.
    """
    profile = getattr(cause, "profile", None)
    if not PROFILE_NONLINEAR or profile is None or getattr(cause, "rebuild", None) is None or tm.penalty is not None:
        return {}
    # (a parameter sought over a range the log sets, Cause.search_range: its grid from the log too)
    prof = profile(tm.info, bl) if getattr(cause, "search_range", None) is not None else profile(tm.info)
    names = list(prof)
    mesh = np.meshgrid(*[prof[nm][0] for nm in names], indexing="ij")
    flat = {nm: g.ravel() for nm, g in zip(names, mesh)}
    yr = bl.y[rows]
    ro = yr - Qo @ (Qo.T @ yr)
    base = float(ro @ ro)

    def rss(info):
        E = np.asarray(cause.rebuild(bl, info))
        if E.ndim == 2:
            E = E[None]
        if E.shape[2] != 1:  # several columns (a warm-up's offset and scale, session 27): each trial's projection
            E = E[:, rows, :]
            Ep = E - np.einsum("rk,tkc->trc", Qo, np.einsum("rk,trc->tkc", Qo, E))
            num = np.einsum("trc,r->tc", Ep, ro)
            G = np.einsum("trc,trd->tcd", Ep, Ep)
            return base - np.einsum("tc,tc->t", num, np.einsum("tcd,td->tc", np.linalg.pinv(G, hermitian=True), num))
        E = E[:, rows, 0]
        Ep = E - (E @ Qo) @ Qo.T
        den = np.einsum("ij,ij->i", Ep, Ep)
        num = Ep @ ro
        ok = den > 1e-300
        return np.where(ok, base - np.where(ok, num, 0.0) ** 2 / np.where(ok, den, 1.0), base)

    r0 = rss(dict(tm.info))
    if r0 is None:
        return {}
    r0 = float(r0[0])
    k = np.shape(cause.rebuild(bl, dict(tm.info)))[-1]  # the term's columns (1: a bump's; 2: a warm-up's)
    T = flat[names[0]].size
    r = np.empty(T)
    ch = int(max(1, min(PROFILE_CHUNK, PROFILE_CHUNK_BYTES // (3 * 8 * max(np.size(bl.y), 1)))))  # E, its rows, its projection
    for a in range(0, T, ch):
        r[a:a + ch] = rss({**tm.info, **{nm: flat[nm][a:a + ch] for nm in names}})
    s2 = r0 / max(len(rows) - Qo.shape[1] - k - len(names), 1)
    inside = (r <= min(r.min(), r0) + 4.0 * s2).reshape(mesh[0].shape)
    out = {}
    for ax, nm in enumerate(names):
        grid, key, scale = prof[nm]
        hit = np.any(inside, axis=tuple(i for i in range(len(names)) if i != ax))
        v = float(tm.info[nm])
        if not hit.any():
            continue
        # the set's boundary lies between its last grid point and the next one out: the hull reaches the latter
        idx = np.flatnonzero(hit)
        lo, hi = float(grid[max(idx[0] - 1, 0)]), float(grid[min(idx[-1] + 1, grid.size - 1)])
        lo, hi = min(lo, v), max(hi, v)
        # (the end it reaches: "low", "high", "both"; False inside)
        edge = ("both" if hit[0] and hit[-1] else "low" if hit[0] else "high" if hit[-1] else False)
        out[key] = (max(hi - v, v - lo) * scale, lo * scale, hi * scale, edge)
    return out


#: A nonlinear parameter sought over a whole range (:attr:`core.causes.Cause.search_range`: a warm-up's time constant)
#: whose profile-likelihood set reaches an end of that range is reported one-sided, ``time_constant_s >= X``, with
#: no value +- U95, and the finding named at most ambiguous (session 27, review27 fault 2: the shipped 525 s
#: positioning sample, its recipe's warm-up 1200 s, was reported 223 +- 190 s, the scan's end of 262 s holding the
#: optimum). False: the value and the profile's U95 (at least the delta method's at an end) as for a local defect.
ONE_SIDED_AT_BOUND = True


def _one_sided(cause, prof: dict, vals: dict) -> dict:
    """``{key: ({"at_least": lo} | {"at_most": hi} | {"not_determined": [lo, hi]}, words)}`` for the magnitudes of
    ``cause``'s bounded parameters (:attr:`core.causes.Cause.search_range`) whose profile set (:func:`_profile_u95`'s
    ``prof``) reaches an end of the range; the rest are reported as value +- U95."""
    if getattr(cause, "search_range", None) is None:
        return {}
    out = {}
    for key, (_, lo, hi, edge) in prof.items():
        if not edge or vals.get(key) is None:
            continue
        if edge == "high":
            out[key] = ({"at_least": lo}, f"{key} >= {lo:.3g}: not determined (its 95 % profile set reaches the "
                                          f"longest the range holds, {hi:.3g}: a slower change is a drift here)")
        elif edge == "low":
            out[key] = ({"at_most": hi}, f"{key} <= {hi:.3g}: not determined (its 95 % profile set reaches the "
                                         f"shortest the range holds, {lo:.3g})")
        else:
            out[key] = ({"not_determined": [lo, hi]}, f"{key} not determined: its 95 % profile set spans the whole "
                                                      f"range, {lo:.3g} to {hi:.3g}")
    return out


def _norm_u95(cause, info: dict, key: str, v: float, coef: np.ndarray, cov: np.ndarray) -> tuple | None:
    """A norm magnitude's ``(U95, (lo, hi))``: :func:`norm_interval` of its coefficient pair (``cov`` the label
    coefficients' covariance), the U95 the half-width ``max(hi - v, v - lo)`` of the symmetric interval about
    the value that holds it (the report's ``value +- U95`` then holds the 95 % interval). None where the cause
    declares no such norm or the value is not that norm."""
    norms = getattr(cause, "norms", None)  # (a cause-like record without the field: none)
    if norms is None:
        return None
    pair = norms(info).get(key)
    if pair is None:
        return None
    i, j = pair
    m = np.array([coef[i], coef[j]], float)
    S = cov[np.ix_([i, j], [i, j])]
    if not (np.all(np.isfinite(m)) and np.all(np.isfinite(S))) \
            or not np.isclose(float(np.hypot(*m)) / UM, v, rtol=1e-9, atol=1e-12):
        return None
    lo, hi = norm_interval(m, S)
    return float(max(hi / UM - v, v - lo / UM)), (float(lo / UM), float(hi / UM))


def _within_range(cause, key: str, v: float, u: float, wide: list | None) -> tuple:
    """``(v, u)``, or ``(None, None)`` when the U95 ``u`` is wider than the whole plausible range of a bounded
    magnitude (it determines nothing; ``(key, v, u, lo, hi)`` appended to ``wide`` when given)."""
    for pat, (lo, hi) in cause.bounds.items():
        if _matches(key, pat) and u > hi - lo:
            if wide is not None:
                wide.append((key, v, u, lo, hi))
            return None, None
    return v, u


def _magnitudes_beside_smooth(cause, bl, tm: Term, Qo, rows, folds, others, smooth_terms, vals, u95, alpha) -> tuple:
    """An unpenalised named cause's magnitudes in the model that holds the unnamed smooth ``smooth_terms`` too.

    ``vals``, ``u95``: fitted beside the named causes ``others`` alone (:func:`_magnitudes`). Fitted again beside
    the smooth's columns with its penalty, the shift tested and carried (:func:`_beside_smooth`, its variance exact:
    :func:`_shift_variance`); then the plausible range: a bounded magnitude whose U95 so made (the shift carried) is
    wider than its whole range is reported as no value and its size said undetermined (``wider_than_range``; the
    finding named at most ambiguous, as a magnitude wide at adoption is). Before (session 20's review) the range was
    judged beside the smooth before the carry, the magnitude labelled ``not_determined`` (the smooth's ridge leaving
    a direction open: a different reason) without the finding's flag, and the carried U95 never judged.
    Returns (values, U95, evidence figures, the note for ``magnitude_undetermined`` or None).
    """
    lin0, lin_s, wide_s = {}, {}, []
    _magnitudes(cause, bl, tm, Qo, rows, boot=(folds, others), lin=lin0)  # vals' fit: its linear map
    vals_s, u95_s = _magnitudes(cause, bl, tm, Qo, rows, wide_s, boot=(folds, others + smooth_terms), lin=lin_s)
    for key, v, u, _, _ in wide_s:  # the plausible range is judged after the carry, below
        vals_s[key], u95_s[key] = v, u
    vals, u95, fig = _beside_smooth(vals, u95, vals_s, u95_s, alpha, _shift_variance(lin0, lin_s))
    wide = []
    for key in list(u95):
        if vals.get(key) is not None and u95[key] is not None:
            vals[key], u95[key] = _within_range(cause, key, float(vals[key]), float(u95[key]), wide)
    fig = {"smooth": ", ".join(t.covariate for t in smooth_terms), **fig, "wider_than_range": [w[0] for w in wide]}
    note = ("; ".join(_undetermined_text(k, lo, hi, "beside the unnamed smooth") for k, _, _, lo, hi in wide)
            if wide else None)
    return vals, u95, fig, note


def _shift_variance(lin0: dict, lin_s: dict) -> dict:
    """The exact variance of each magnitude's shift ``D = v_s - v_0`` between two fits linear in the data.

    ``lin0``, ``lin_s``: :func:`_magnitudes`' ``lin`` of the fit beside the named causes alone and beside the smooth
    too (``c = A y``, same label map ``M``). To first order ``D = g^T M (A_s - A_0) y`` with ``g`` the magnitude's
    gradient over the label coefficients (the smooth fit's), so ``var D = s^2 || (A_s - A_0)^T M^T g ||^2`` under
    white noise of variance ``s^2`` (the smooth fit's): as :func:`_unnamed_shift` tests the workpiece's shift. Before
    (session 20) ``(U95_s^2 - U95^2) / 4``, two Bayesian covariances on two ``s^2``, which is not the variance of a
    difference with a ridge on one side and is 0 (any shift "real") where ``U95_s <= U95``. ``{key: variance}``."""
    if lin0.get("g") is None or lin_s.get("g") is None or "A" not in lin0 or "A" not in lin_s \
            or lin0["A"].shape != lin_s["A"].shape:
        return {}
    dA = lin_s["A"] - lin0["A"]
    out = {}
    for key, g in lin_s["g"].items():
        if not np.all(np.isfinite(g)):
            continue
        w = dA.T @ (lin_s["M"].T @ g)
        out[key] = float(lin_s["s2"] * (w @ w))
    return out


def _beside_smooth(vals: dict, u95: dict, vals_s: dict, u95_s: dict, alpha: float, var_d: dict) -> tuple:
    """A named cause's magnitudes in the model that holds the unnamed smooth beside it (session 20).

    ``vals``, ``u95``: the magnitudes and U95 fitted beside the other named
    causes alone; ``vals_s``, ``u95_s``: beside the smooth's columns too,
    with its penalty (the model reported: the joint ridge fit of
    :func:`_magnitudes`, its U95 from the fit's Bayesian covariance
    ``s^2 (X^T X + P)^-1``, as the extended workpiece's; a magnitude along
    a direction the smooth's ridge leaves undetermined is None there).
    The smooth has no physics: how an effect splits between it and the
    cause is its form's and its penalty's, not a measurement. The two
    estimates of one magnitude are compared as :func:`_unnamed_shift`
    compares the workpiece's (Hausman 1978), the shift ``D`` against its
    exact variance ``var_d`` (:func:`_shift_variance`: both estimates are
    linear in the data), chi-square with one degree of freedom at ``alpha``
    (a shift whose variance is zero, the two fits one map, is no shift);
    the variance inflation the smooth brings is ``(U95_s / U95)^2``.
    Reported (:data:`MAGNITUDES_BESIDE_SMOOTH_VALUE`): ``"named_alone"``,
    the default, the value beside the named causes alone with U95
    ``hypot(U95_s, D)`` (the shift always carried: the U95 reaches the
    answer beside the smooth); ``"smooth"``, the value beside the smooth
    with U95 ``U95_s``, ``hypot(U95_s, D)`` where the shift is significant.
    A magnitude determined beside the named causes alone and not beside the
    smooth is reported as no value (``not_determined``).

    Returns (values, U95, figures for the evidence).
    """
    out_v, out_u = {}, {}
    fig = {"variance_inflation": {}, "shift": {}, "p_value": {}, "carried_in_u95": [], "not_determined": []}
    for key, v in vals_s.items():
        out_v[key] = v
        if key not in u95_s:
            continue
        u_s, v0, u0 = u95_s.get(key), vals.get(key), u95.get(key)
        out_u[key] = u_s
        if v is None and v0 is not None:
            # determined beside the named causes alone, not beside the smooth's columns (its ridge leaves a
            # direction the magnitude moves with undetermined): no estimate
            fig["not_determined"].append(key)
        if v is None or u_s is None or v0 is None or u0 is None or not u0 > 0 or key not in var_d:
            continue
        d = float(v) - float(v0)
        vd = var_d[key]
        chi2 = d * d / vd if vd > 0 else 0.0
        p = float(stats.chi2.sf(chi2, 1))
        fig["variance_inflation"][key] = float((u_s / u0) ** 2)
        fig["shift"][key] = d
        fig["p_value"][key] = p
        if MAGNITUDES_BESIDE_SMOOTH_VALUE == "named_alone":
            # the value beside the named causes alone (the smooth's split has no physics), its U95 reaching the
            # answer beside the smooth: the shift always carried
            out_v[key], out_u[key] = v0, float(np.hypot(u_s, d))
            fig["carried_in_u95"].append(key)
        elif p < alpha:
            out_u[key] = float(np.hypot(u_s, d))
            fig["carried_in_u95"].append(key)
    return out_v, out_u, fig


def _named_ss(so: _State, sf: _State, sigma: float) -> float:
    """Debiased sum of squares a term explains: the model without it (``so``) against with it (``sf``).

    The parameters it adds are its columns outside the model, or, for a
    penalised term (not in ``Q``), its effective degrees of freedom (the
    states' residual degrees of freedom differ by them, rounded).
    """
    k = sf.Q.shape[1] - so.Q.shape[1]
    if k == 0 and sf.dof < so.dof:
        k = so.dof - sf.dof
    return (so.rss - sf.rss) - k * sigma ** 2


def _rival_share(bl, tm: Term, terms, Qb, y, rows, sigma, settings, bases, trials) -> dict:
    """How much of what a smooth term in the cause's covariate explains the cause explains.

    ``trials``: ``trials(counter_scan) -> (T, n, k)``, that scan's trials,
    whitened (built once per run, shared with the outlier screen's slips).
    """
    others = [o for o in terms if o is not tm]
    so = _state(Qb, y, rows, others)
    sf = _state(Qb, y, rows, others + [tm])
    cause = tm.origin
    if cause is not None and cause.rival is not None:
        B = _white(bl, cause.rival(bl, tm.info))[rows]
    else:
        cov = bl.covariate(tm.covariate)
        if cov is None:
            return {"kept": True, "rival_share": 1.0, "rival": None}
        B = bases[cov.name][rows]
    s2 = sigma ** 2
    if tm.penalty is not None and not tm.unnamed:
        # a penalised cause against its rival by the same estimator: the rival is the cause's columns and the
        # smooth's directions beyond them (orthonormal, scaled to the columns' mean norm outside the model), all
        # with the cause's ridge, each debiased by its effective degrees of freedom (an unpenalised rival beside a
        # penalised cause measures the penalty's shrinkage, not the form: the synthetic x y coupling of
        # tests/core/test_discover_generalisation.py seed 4, share 0.62 so)
        E = tm.columns[rows]
        Eo = E - so.Q @ (so.Q.T @ E)
        Ub = new_basis(np.hstack([so.Q, new_basis(so.Q, E)]), B)
        lam = float(np.mean(np.diag(tm.penalty)))
        scale = float(np.trace(Eo.T @ Eo)) / max(E.shape[1], 1)
        R = np.hstack([Eo, np.sqrt(scale) * Ub])
        _, _, _, edf_n = _penalised_fit(Eo, so.r, tm.penalty, so.dof)
        c_r, _, _, edf_r = _penalised_fit(R, so.r, lam * np.eye(R.shape[1]), so.dof)
        rr = so.r - R @ c_r
        d_n = (so.rss - sf.rss) - edf_n * s2
        d_r = (so.rss - float(rr @ rr)) - edf_r * s2
    else:
        d_n = _named_ss(so, sf, sigma)
        U = new_basis(so.Q, np.hstack([B, tm.columns[rows]]))
        ss_r = float(np.sum((U.T @ so.r) ** 2))
        k_r = U.shape[1]
        d_r = ss_r - k_r * s2
    share = d_n / d_r if d_r > 0 else 1.0
    m_ss = (settings.material_sigma * sigma) ** 2 * len(rows)
    # a shortfall below materiality is forgiven only where the cause itself
    # explains a material amount: it then holds the covariate's material
    # structure but for an immaterial rest. Where it explains less, the
    # share decides (forgiving it there would keep a cause that explains
    # almost nothing of a structure just above materiality, share ~0: the
    # check must be able to fail). The allowance steps from 0.25 d_n to
    # materiality where d_n reaches materiality.
    immaterial = (d_r - d_n) < m_ss and d_n >= m_ss
    out = {"kept": bool(share >= settings.rival_share or immaterial), "rival_share": float(share),
           "rival": tm.covariate, "explained_ss_um2": max(d_n, 0.0) / UM ** 2,
           "rival_explained_ss_um2": max(d_r, 0.0) / UM ** 2}
    if cause is not None and cause.counter is not None:
        # the plainer explanation (a finer error map for a coupling): it must not do as well
        d_c, Uc = _counter_ss(bl, cause, so, rows, sigma)
        out["counter"] = cause.counter.__name__.replace("_", " ")
        out["counter_explained_ss_um2"] = max(d_c, 0.0) / UM ** 2
        reach = _support_share(tm.columns[rows], cause)  # (materiality over the touches the cause acts on)
        if d_c > d_n - m_ss * reach:
            d_b, p_b, stands = _beyond(so, Uc, tm.columns[rows], sigma, tm.tries, settings, reach)
            out["explained_beyond_counter_ss_um2"] = max(d_b, 0.0) / UM ** 2
            out["p_adjusted_beyond_counter"] = p_b
            if not stands and cause.counter_cause is not None and not (COUNTER_NEEDS_PLAINER_PASSING
                                                                       and tm.evidence.get("counter_waived")):
                out["kept"] = False  # the plainer catalogue cause is named in its own right
            elif not stands:
                # a plainer explanation without a name does as well: named, but ambiguous
                out["indistinguishable_counter"] = out["counter"]
    if cause is not None and cause.support is not None and out["kept"]:
        sp = _support(bl, cause, tm.info, so, tm.columns[rows])
        out["support_units"] = sp["support_units"]
        if sp["refused"]:
            out["kept"] = False
            out["not_supported"] = sp["reason"]
    if cause is not None and cause.smooth is not None and out["kept"]:
        sm = _smooth_verdict(bl, cause, so, tm.columns[rows], sigma, tm.tries, settings)
        out.update({k: v for k, v in sm.items() if k not in ("refused", "reason", "indistinguishable")})
        if sm["refused"]:
            out["kept"] = False
            out["not_confined"] = sm["reason"]
        elif sm["indistinguishable"]:  # named, ambiguous: the design cannot tell it from smooth axis errors
            out["indistinguishable_counter"] = sm["smooth"]
            out["counter_explained_ss_um2"] = sm["smooth_explained_ss_um2"]
    if cause is not None and cause.counter_scan is not None and out["kept"]:
        # a one-off alternative chosen among T trials: its best sum of squares is
        # debiased by the median of the largest of T chi-squares (k dof) under noise
        Cs = trials(cause.counter_scan)
        if Cs.shape[0]:  # (StepTrials: built and tested a block at a time, the same numbers)
            ss_s, k_s, _, _ = nested_f_trials(Cs, rows, so.Q, so.r, so.rss, so.dof)
            j = int(np.argmax(ss_s))
            C_j = trials_take(Cs, [j], rows)[0]
            examined: list = []
            if SLIP_RIVAL_EXACT and isinstance(Cs, StepTrials):  # the slip's split refined to the touch (the veto's)
                C_x = _exact_step(Cs, j, so.Q, so.r, rows, examined)
                ss_x = float(np.sum((new_basis(so.Q, C_x).T @ so.r) ** 2))
                if ss_x > float(ss_s[j]):  # (a coarse refinement of a long set-up need not revisit the trial's split)
                    C_j, ss_s = C_x, ss_s.copy()
                    ss_s[j] = ss_x
            null_max = float(stats.chi2.isf(np.log(2) / (Cs.shape[0] + len(set(examined))), max(int(k_s[j]), 1)))
            d_s = float(ss_s[j]) - null_max * s2
            # what the cause still explains once the slip is in the model
            Qs = np.hstack([so.Q, new_basis(so.Q, C_j)])
            rs = so.r - Qs[:, so.Q.shape[1]:] @ (Qs[:, so.Q.shape[1]:].T @ so.r)
            Un = new_basis(Qs, tm.columns[rows])
            ss_ns = float(np.sum((Un.T @ rs) ** 2))
            d_ns = ss_ns - Un.shape[1] * s2
            # and whether it is still significant beside the slip (its F test with
            # the Bonferroni factor of its adoption)
            p_ns = min(1.0, nested_f(Un, rs, float(rs @ rs), len(rows) - Qs.shape[1]).p_value * tm.tries)
            out["slip_explained_ss_um2"] = max(d_s, 0.0) / UM ** 2
            out["explained_beyond_slip_ss_um2"] = max(d_ns, 0.0) / UM ** 2
            out["p_adjusted_beyond_slip"] = p_ns
            # (the margin within which the slip explains as much as the cause: the cause's materiality, over the
            # touches it acts on; the remainder beyond a material slip stays material over every touch, the clause
            # that keeps a machine-side bending from being named a changing part: docs/discovery.md, session 16)
            m_own = m_ss * _support_share(tm.columns[rows], cause)
            refuse = (d_s >= m_ss and d_ns < m_ss) or (p_ns >= settings.alpha_family and d_s >= d_n - m_own)
            if refuse and SLIP_OFF_FEATURE and cause.books_to == "workpiece":
                p_off = _slip_off_feature(C_j, tm.columns[rows], so,
                                          _feature_rows(bl, tm.info.get("feature"), rows))
                out["p_slip_off_feature"] = p_off
                if p_off >= settings.alpha and _curve_confined(tm):
                    # a settling curve seen only on its feature that a step does as well: the curve's bulge is
                    # what lets the line follow a step (a knock read as the part settling), so it is not named
                    # for it (docs/discovery.md, "Session 24")
                    out["curve_slip_on_feature"] = True
                elif p_off >= settings.alpha:
                    # the slip is seen on the cause's own feature only: the data cannot tell the part moving once
                    # from that feature changing; named, ambiguous with the slip
                    refuse = False
                    out["indistinguishable_counter"] = cause.counter_scan.__name__.replace("_", " ")
                    out["counter_explained_ss_um2"] = out["slip_explained_ss_um2"]
            if refuse:
                out["kept"] = False
                out["counter"] = cause.counter_scan.__name__.replace("_", " ")
                out["counter_explained_ss_um2"] = out["slip_explained_ss_um2"]
    if cause is not None and cause.books_to == "workpiece" and out["kept"] and PART_CHANGE_CONFINED:
        conf = _confined_to_feature(bl, tm, so, sf, rows, sigma, settings)
        if conf is not None:
            out["other_features"] = conf
            if conf["refused"]:
                out["kept"] = False
                out["not_confined"] = conf["reason"]
    if cause is not None and out["kept"] and RING_SIZE_CONFINED and tm.info.get("ring_size"):
        own = _ring_size_own(bl, tm, sf, rows, sigma, settings)
        out["ring_size"] = own
        if own["refused"]:
            out["kept"] = False
            out["not_confined"] = own["reason"]
    return out


#: Whether a change of the part (a cause booked to the workpiece: part_change) is refused where it is not the feature's
#: own: its feature moves as a whole (its change nothing significant beyond the feature's rigid motion) while the
#: other features move in the same time form too (:func:`_confined_to_feature`; session 22: gen_a thermal_bending,
#: out of the catalogue, read part_change). False: the rule before.
PART_CHANGE_CONFINED = True

#: Whether a part change curving in time (:data:`core.causes.PART_CHANGE_CURVE`'s layouts, ``curve`` in their info)
#: is held to the settling of one feature alone (session 24, docs/discovery.md): refused where the other features
#: move in its time forms, even where its feature's change is one of form (a warm-up bends the machine by a field
#: whose gradient over a bore is a change of the bore's form: the rigid-motion test cannot tell it from the part's
#: own), and not saved by a slip seen on its feature only (:data:`SLIP_OFF_FEATURE`: the curve's bulge is what lets
#: a change in time follow a step). Acts only on curved layouts: with the curve off no decision moves.
PART_CHANGE_CURVE_CONFINED = True


#: Whether lobes turned per set-up (a cause with a plainer nested explanation, ``counter_cause``: the probe's lobes
#: fixed in the machine frame) are refused where the fixed lobes explain a share of their signal that lobes turned
#: at random in every set-up would leave them with probability below ``Settings.alpha`` on this design
#: (:func:`_fixed_share`). Session 28 (docs/discovery-studies.md, "Session 28: gen_c's wound lost motion read as lobes per
#: set-up"): gen_c travel_hysteresis (out of the catalogue, a lost motion winding up along the path) read
#: `lobing_per_setup?`, the fixed lobes 0.92-1.02 of its signal on 10 of 11 (true turned lobes 0.03-0.75 on gen_a and
#: gen_b, up to 0.97 on the simulator's cross pocket, where a turn leaves them as much). Measured: gen_c
#: travel_hysteresis 200-399 acceptable 131 -> 156 of 180 visible (26 wrong -> right, 1 right -> wrong: 256
#: `unexplained` -> `probe_lobing?`, the lost motion's twin on gen_c's design); the simulator's lobing_per_setup and
#: probe_lobing 4000-4099 and gen_a every effect 1000-1049 unchanged. False: the rule before (refused only where
#: the plainer explains as much and the turned lobes are not significant beyond it).
FIXED_SHARE_TEST = True

#: Monte Carlo draws of :func:`_fixed_share`'s null (lobes turned at random in every set-up).
FIXED_SHARE_DRAWS = 2000


def _canonical_basis(M: np.ndarray) -> np.ndarray:
    """An orthonormal basis of span(``M``) that depends on the subspace alone, not on how ``M`` spans it.

    The columns of ``M`` may come from an eigen-decomposition whose vectors within a repeated eigenvalue
    are any rotation of each other (:func:`core.diagnosis.new_basis`), and the SVD of ``M`` rotates such a
    space as freely: a Monte Carlo that draws its noise in that basis gets another sample path on another
    machine's LAPACK kernels (session 33: the simulator's lobing_per_setup 1000's fixed-share null median
    0.7556 on an Intel machine, 0.7574 on an AMD EPYC, p 0.645 vs 0.648, the same data). Here the projector
    onto the span (unique) carries a fixed seeded Gaussian matrix into it, and the Loewdin (symmetric)
    orthonormalisation of the result (unique: the principal inverse square root of its Gram matrix) is the
    basis: continuous in the data, the same to rounding on every kernel. Its rank is the SVD's (singular
    values above 1e-9 of the largest), as before.
    """
    U, sv, _ = np.linalg.svd(M, full_matrices=False)
    B0 = U[:, sv > 1e-9 * sv[0]]
    R = np.random.default_rng(20261205).standard_normal((M.shape[0], B0.shape[1]))
    A = B0 @ (B0.T @ R)
    w, V = np.linalg.eigh(A.T @ A)
    return A @ ((V / np.sqrt(w)) @ V.T)


def _fixed_share(st: _State, Uc: np.ndarray, E: np.ndarray, sigma: float) -> dict | None:
    """The share of the turned lobes' signal the fixed lobes explain, and how rare it is were the lobes turned.

    ``E`` (rows used): the lobes per set-up, a pair of columns (``cos k phi``,
    ``sin k phi``) per set-up; ``Uc``: the fixed lobes' basis beside the model
    ``st`` (:func:`_counter_ss`). The share is ``d_c / d_n``, each the
    debiased sum of squares beside the model. Null: one probe's lobes turned
    by an independent uniform angle in every set-up (each set-up's vector
    ``A (cos theta_j, sin theta_j)``), ``A`` set so that the turned lobes'
    expected signal is the one seen, plus the noise ``sigma`` in the tested
    directions; ``p`` = P(share >= seen | null), ``(1 + count) / (draws + 1)``,
    draws from a generator seeded 0 (the same campaign, the same p). On a
    design of few telling directions (the simulator's cross pocket) turned
    lobes leave most of their signal to the fixed ones and a large share is
    no evidence; where many directions tell (gen_c: a share about one
    set-up's) it is. None where ``E`` is not in pairs or nothing is tested.
    """
    if E.shape[1] % 2 or Uc.shape[1] == 0:
        return None
    UL = new_basis(st.Q, E)
    if UL.shape[1] == 0:
        return None
    s2 = sigma ** 2
    d_n = float(np.sum((UL.T @ st.r) ** 2)) - UL.shape[1] * s2
    d_c = float(np.sum((Uc.T @ st.r) ** 2)) - Uc.shape[1] * s2
    if d_n <= 0:
        return None
    B = _canonical_basis(np.hstack([UL, Uc]))  # (the noise drawn once in the directions either test sees)
    GL, Gc, NL, Nc = UL.T @ E, Uc.T @ E, UL.T @ B, Uc.T @ B
    rng = np.random.default_rng(0)
    theta = rng.uniform(0.0, 2 * np.pi, (E.shape[1] // 2, FIXED_SHARE_DRAWS))
    coef = np.empty((E.shape[1], FIXED_SHARE_DRAWS))
    coef[0::2], coef[1::2] = np.cos(theta), np.sin(theta)
    sig_L = np.sum((GL @ coef) ** 2, axis=0)
    amp = np.sqrt(d_n / max(float(np.mean(sig_L)), 1e-300))
    z = rng.standard_normal((B.shape[1], FIXED_SHARE_DRAWS)) * sigma
    ss_L = np.sum((amp * GL @ coef + NL @ z) ** 2, axis=0) - UL.shape[1] * s2
    ss_c = np.sum((amp * Gc @ coef + Nc @ z) ** 2, axis=0) - Uc.shape[1] * s2
    share = d_c / d_n
    null = np.where(ss_L > 0, ss_c / np.where(ss_L > 0, ss_L, 1.0), np.inf)
    p = (1 + int(np.sum(null >= share))) / (FIXED_SHARE_DRAWS + 1)
    return {"share": share, "p": p, "null_median": float(np.median(null[np.isfinite(null)])) if np.any(
        np.isfinite(null)) else float("nan"), "draws": FIXED_SHARE_DRAWS}

#: Whether a ring's size change (:data:`core.causes.RING_SIZE`: part_change's ring layout with its size column) is
#: refused where every feature's size changes with it (:func:`_ring_size_own`): a probe's pre-travel drifting moves
#: every touch along its normal alike, a ring's size among them (gen_a probe_heating 1057, out of the catalogue, read
#: `part_change?` on its boss with the size column alone, its workpiece check lost). Session 28 (docs/discovery-studies.md,
#: "Session 28: a ring's size change, held to the ring"). False: the size column unguarded.
RING_SIZE_CONFINED = True


def _ring_size_own(bl, tm, sf: _State, rows, sigma: float, settings) -> dict:
    """Whether a ring's size change (``tm``: part_change's ring layout with its size, ``ring_size`` in its info) is
    the ring's own, or every feature's size changing with it (:data:`RING_SIZE_CONFINED`).

    A probe's pre-travel that drifts (heating, a stylus that settles)
    moves every touch along its normal by the same amount at each moment:
    the ring's size changes, and so does every other feature's (a wall's
    place, a bore's size), in the same time. A ring that grows on its own
    leaves the other touches still. The test: the other touches' common
    change along their normals in the trial's time form (one column, ``time``
    on every touch off the ring), beside the model with the cause (``sf``),
    at ``alpha_family``. Refused where it is significant, material or not: a
    probe that warms with use (gen_a probe_heating 1057) moves the others by
    its heat, not by the time, and most of that the targets' own columns take;
    what is left beside the ring's size is small (2.9 um^2 against a
    materiality of 4.7) but significant (p 5e-5). Where no touch lies off the
    ring (a log of the ring alone) the two cannot be told apart and the size
    is refused too.
    """
    d = bl.data
    t = d.touches
    time = dict(causes_mod.part_change_times(bl)).get(tm.info.get("time_form", "continuous"), d.tau)
    off = np.asarray(t.feature, dtype=object) != tm.info["feature"]
    O = _white(bl, (off * time)[:, None])[rows]
    Uo = new_basis(sf.Q, O)
    if Uo.shape[1] == 0 or sf.dof - Uo.shape[1] <= 0:
        return {"refused": True, "reason": (f"{tm.info['feature']}'s size change cannot be told from a probe's "
                                            f"pre-travel drifting: no touch off it tests the others' sizes")}
    s2 = sigma ** 2
    p = float(nested_f(Uo, sf.r, sf.rss, sf.dof).p_value)
    ss = float(np.sum((Uo.T @ sf.r) ** 2)) - s2
    refused = p < settings.alpha_family
    out = {"others_size_p": p, "others_size_ss_um2": max(ss, 0.0) / UM ** 2, "refused": bool(refused)}
    if refused:
        out["reason"] = (f"not the ring's own size change: every other touch moves along its normal with "
                         f"{tm.info['feature']} ({ss / UM ** 2:.3g} um^2, {fmt_p(p)}): a probe's pre-travel "
                         f"drifting, not the part")
    return out


def _curve_confined(tm) -> bool:
    """Whether trial ``tm`` is a curved part change held to :data:`PART_CHANGE_CURVE_CONFINED`'s rules."""
    return PART_CHANGE_CURVE_CONFINED and bool(tm.info.get("curve"))


def _confined_to_feature(bl, tm, so: _State, sf: _State, rows, sigma: float, settings) -> dict | None:
    """Whether a change of one feature (``tm``: part_change) is that feature's own, or its place moving with the rest.

    A part that relaxes changes one feature's form: a wall bows, a bore goes
    oval, a slot closes; the other features hold still. What moves every
    feature where it sits, growing with time, is the machine or its
    environment (a guideway bending as it warms moves each feature by the
    error at its place, a slowly varying function of position: over one
    feature nearly a translation). Two tests, both at ``alpha_family``,
    unadjusted (the feature is the one adopted, no scan is made here):

    - ``rigid``: the cause's columns beyond the feature's rigid motion in the
      part's frame in the cause's time form (its two translations and its
      turn about its centre: ``time * n``, ``time * (w - c) x n`` on its
      touches), beside the model without the cause (``so``): a change of the
      feature's form shows there (a wall that turns against its opposite
      one, a bow, an ovalisation, a slot closing); a feature moving as a whole
      does not. On a feature of one wall every shift is a translation: the
      data cannot tell a change of it from its place moving, and the test
      is not passed.
    - ``others``: the other features' translations in the same time form
      (each feature probed in two set-ups or more: ``time * n_x``, ``time *
      n_y`` on its touches), beside the model with the cause (``sf``):
      significant and material (``material_sigma`` sigma per touch they
      reach), the other features move too.

    The cause is refused when the feature's change is no change of its form
    and the other features move: what is left is structure no cause names
    (``unexplained``, diagnosed by covariate). Measured in docs/discovery.md,
    "Session 22: a change of the part is confined to its feature".

    A change curving in time (``curve`` in its info, :data:`PART_CHANGE_CURVE_CONFINED`)
    is refused wherever the others move (``others`` significant, material
    or not), its change of form notwithstanding: a warm-up's field has a
    gradient over a bore, which reads as a change of the bore's form (gen_a
    thermal_bending 1138; docs/discovery.md, "Session 24").

    Returns None where the log names no features or no other feature is
    probed in two set-ups; else the figures and ``refused`` with its reason.
    """
    d = getattr(bl, "data", None)
    t = getattr(d, "touches", None)
    f = tm.info.get("feature")
    if t is None or f is None or getattr(t, "feature", None) is None:
        return None
    feats = np.asarray(t.feature, dtype=object)
    time = dict(causes_mod.part_change_times(bl)).get(tm.info.get("time_form", "continuous"), d.tau)
    # a change curving in time (causes.PART_CHANGE_CURVE): the rigid motion and the others' in both its time forms
    times = (time, time * (1 - time)) if tm.info.get("curve") else (time,)
    cn, sn = np.cos(d.wn_az), np.sin(d.wn_az)
    other = []
    for g in sorted(set(feats.tolist()) - {f}):
        m = feats == g
        if np.unique(np.asarray(t.setup)[m]).size >= 2:
            other += [m * tt * c for tt in times for c in (cn, sn)]
    if not other:
        return None
    mf = feats == f
    w = np.asarray(t.w_A, float)[:, :2]
    if not np.all(np.isfinite(w[mf])):
        return None
    c = w[mf].mean(axis=0)
    turn = np.where(mf, (w[:, 0] - c[0]) * sn - (w[:, 1] - c[1]) * cn, 0.0)  # (another feature's w may be NaN)
    rigid = np.column_stack([col for tt in times for col in (mf * tt * cn, mf * tt * sn, tt * turn)])

    s2 = sigma ** 2
    # the change beyond the feature's rigid motion
    Ur = new_basis(so.Q, _white(bl, rigid)[rows])
    Qr = np.hstack([so.Q, Ur])
    rr = so.r - Ur @ (Ur.T @ so.r)
    Un = new_basis(Qr, tm.columns[rows])
    if Un.shape[1]:
        p_form = float(nested_f(Un, rr, float(rr @ rr), len(rows) - Qr.shape[1]).p_value)
        d_form = float(np.sum((Un.T @ rr) ** 2)) - Un.shape[1] * s2
    else:
        p_form, d_form = 1.0, 0.0
    # the other features moving beside the cause
    O = _white(bl, np.column_stack(other))[rows]
    Uo = new_basis(sf.Q, O)
    if Uo.shape[1] == 0 or sf.dof - Uo.shape[1] <= 0:
        return None
    p_oth = float(nested_f(Uo, sf.r, sf.rss, sf.dof).p_value)
    d_oth = float(np.sum((Uo.T @ sf.r) ** 2)) - Uo.shape[1] * s2
    reach = float(np.mean(np.any(O != 0, axis=1)))
    m_oth = (settings.material_sigma * sigma) ** 2 * len(rows) * reach
    form = p_form < settings.alpha_family
    moves = p_oth < settings.alpha_family and d_oth >= m_oth
    # a curved change (PART_CHANGE_CURVE_CONFINED): a warm-up's form change over the feature is the others' motion
    # continued, so where the others move (significant; material or not) its change of form does not make it the
    # feature's own
    curved = _curve_confined(tm)
    refused = (p_oth < settings.alpha_family) if curved else (moves and not form)
    out = {"form_beyond_rigid_p": p_form, "form_beyond_rigid_ss_um2": max(d_form, 0.0) / UM ** 2,
           "form_beyond_rigid_k": int(Un.shape[1]), "others_move_p": p_oth,
           "others_move_ss_um2": max(d_oth, 0.0) / UM ** 2, "others_move_k": int(Uo.shape[1]),
           "others_materiality_um2": m_oth / UM ** 2, "refused": bool(refused)}
    if refused and curved:
        form_txt = fmt_p(p_form) if Un.shape[1] else "nothing beyond its rigid motion to test"
        out["reason"] = (f"not the feature's own change: {f}'s change curves in time as a warm-up does and the other "
                         f"features move with it ({d_oth / UM ** 2:.3g} um^2, {fmt_p(p_oth)}, {Uo.shape[1]} "
                         f"directions): its change of form ({form_txt}) may be their field's over it, not the part's")
    elif refused:
        out["reason"] = (f"not the feature's own change: {f} moves as a whole (its change beyond its rigid motion "
                         f"{fmt_p(p_form)}) and the other features move with it ({d_oth / UM ** 2:.3g} um^2, "
                         f"{fmt_p(p_oth)}, {Uo.shape[1]} directions): their places move, not one feature's form")
    return out


#: Whether a cause's rival slip (:func:`_evaluate`'s ``counter_scan``) has its split refined to the touch, as the
#: outlier screen's slip veto has (:func:`_exact_step`): tried in session 22 and off (docs/discovery.md, "Session 22:
#: a slip's first touch between two trials' splits"): on, gen_a knock 1292's thermal_drift (ambiguous) beside the
#: refined veto's kept step is refused and the knock reads `unexplained` again. Measured across the catalogue
#: (docs/discovery.md, "Session 22: the rival check's slip refined to its touch, measured"): the only other
#: campaigns it changed were five c_drift below visibility (gen_b 1048, 1133, 1198, simulator 4007, 4066), right -> wrong
#: (`c_drift` -> `unexplained`), and none gained: off.
SLIP_RIVAL_EXACT = False

#: Whether repeats that scatter more than the baseline's whole residual can hold (the lack-of-fit F in its lower
#: tail, below ``Settings.alpha``) are set aside as the noise floor, the residuals' scatter used as on a log
#: without repeats: tried in session 22 and off (docs/discovery.md, "Session 22: a slip's first touch between two
#: trials' splits": gen_b fixture_slip 201/211 -> 209/211, gen_a reseat_hysteresis three right -> wrong). Session 23's
#: :data:`REPEATS_STRADDLED` sets aside only the groups that scatter beyond the others (the re-seats' 1167 and 1275,
#: every group inflated alike, keep their repeats; docs/discovery.md, "Session 23").
REPEATS_BEYOND_FIT = False

#: Whether repeat groups whose scatter is an outlying variance among the groups' (a step between two repeats of
#: one target: :func:`core.diagnosis.straddled_groups`, at ``Settings.alpha``) are set aside from the repeats the
#: noise floor and the lack-of-fit test take as pure error (session 23, docs/discovery.md), where the rest keep the
#: 10 degrees of freedom a repeats' floor needs (else none is: the session 23 review's gen_a none 1305 and 1648).
REPEATS_STRADDLED = True

#: Whether only repeat groups whose touches something separates (another touch of the set-up between two of them in
#: time, or a gap beyond :data:`core.diagnosis.CLOSE_PAIR_FRACTION` of the set-up's span:
#: :func:`core.diagnosis.separated_groups`) may be set aside by :data:`REPEATS_STRADDLED`; needs a time covariate
#: (without one every group may, as before). Two touches one right after the other hold no step between them;
#: Cochran's test is not robust to a heavy-tailed probe, and review32c F1's none_20011 (Student-t 4 noise) lost
#: such a pair 7 s apart (a noise tail), its floor 0.083 um for a true 0.227 -> `unexplained: lack_of_fit`
#: (docs/discovery-studies.md, "Session 32: heavy-tailed probing noise").
STRADDLED_SEPARATED = True

#: Whether the slip that refuses a workpiece-local cause must be seen off that cause's feature to refuse it
#: (:func:`_slip_off_feature`; docs/discovery.md, session 21); where it is not, the cause is named, ambiguous.
SLIP_OFF_FEATURE = True


def _feature_rows(bl, feature, rows) -> np.ndarray | None:
    """The rows (of ``rows``) that touch ``feature``, or None where the log names no features."""
    t = getattr(getattr(bl, "data", None), "touches", None)
    if feature is None or t is None or getattr(t, "feature", None) is None:
        return None
    return np.asarray(t.feature, dtype=object)[rows] == feature


def _slip_off_feature(C: np.ndarray, E: np.ndarray, so, feature_rows=None) -> float:
    """p of the best slip's step on the touches off the cause's feature alone (1.0: it moves none there).

    A fixture slip moves the whole part at one moment: every touch after it in its set-up, on every feature,
    is off by the same translation and rotation (:func:`core.causes.fixture_slip`'s columns ``C``). A change of
    one feature's form moves that feature's touches alone. So a slip that is there is seen on the other
    features' touches it moves, without the feature's own (gen_b fixture_slip: the features probed after the
    slip); a "slip" seen only through the feature (gen_b part_change: a step after the slot's first wall that
    moves its second wall and the blade's few drift-check re-touches, which do not move) is the feature's own
    change read as a step, and the data cannot tell the two. The test: the slip's columns with the feature's
    rows zeroed, F-tested beside the model without the slip (``so``), unadjusted: the moment is the one the
    slip check chose on every row, and a small p keeps the slip's refusal. The feature's rows are its touches
    (``feature_rows``) with ``E``'s support: in part_change's step-per-set-up form the columns are 0 on the
    first set-up, whose touches of the feature are still the feature's (the session 21 review: counted as
    off, they made the "slip" seen elsewhere, p 1e-17 to 6e-37 on gen_b part_change with that form forced).
    """
    on = np.any(np.abs(E) > 1e-9 * np.max(np.abs(E), axis=0, initial=0.0), axis=1)
    if feature_rows is not None:
        on = on | feature_rows
    Co = C * (~on)[:, None]
    if not np.any(Co != 0):
        return 1.0
    U = new_basis(so.Q, Co)
    if U.shape[1] == 0 or so.dof - U.shape[1] <= 0:
        return 1.0
    return float(nested_f(U, so.r, so.rss, so.dof).p_value)


#: Moments tried for a one-off event by :func:`_time_alternatives` (quantiles of the touches' times).
EVENT_SPLITS = 40


def _time_alternatives(bl, tm: Term, so: _State, sigma, settings) -> list:
    """Plainer explanations of a cause that changes with time, which the data may not tell from it.

    A machine drift (thermal, a creeping C axis, a temperature) is not the
    only thing that changes the readings over a campaign:

    - ``event``: a one-off change at one moment that stays (a knock, the
      probe re-seating): every response mode of the baseline (an offset and
      an affine displacement of the tip) changing by a constant at one
      moment, the best of :data:`EVENT_SPLITS`; a drift's columns correlate
      with a step (a ramp with a step at its middle: 0.87);
    - ``probe_size``: the probe's effective ball size changing with use
      (dirt picked up, the probe warming): the scalar mode (every touch
      triggers earlier or later by the same amount) times a Legendre
      polynomial of time of degree 1-3, the best of the three; an equal
      change of the X and Y scales reads on a part probed around its centre
      much like a change of size.

    Each alternative's best trial is debiased by the median of the largest
    of that many chi-squares under noise (as the slip's). It does as well
    when it explains as much as the cause (within materiality) and the
    cause explains nothing material and significant beyond it (nested F,
    the Bonferroni factor of its adoption): the data cannot tell the
    drift from it, and the name is ``ambiguous``.

    Returns
    -------
    list of dict: the alternatives that do as well, with their figures.
    """
    if bl.kind != "planar":
        return []
    rows = so.rows
    t = np.asarray(bl.data.touches.t_s, float)[rows]
    ts = np.unique(t)
    if ts.size < 4:
        return []
    M = bl.modes[rows]
    cut = np.unique(np.quantile(ts[1:], np.linspace(0, 1, EVENT_SPLITS)))
    u = 2 * (t - t.min()) / max(np.ptp(t), 1e-300) - 1
    P = causes_mod._legendre(u, 3)
    trials = {"event": (M[None, :, :] * (t[None, :, None] >= cut[:, None, None]), cut),
              "probe_size": (np.stack([np.hstack([M[:, :1] * P[:, :g], np.zeros((len(rows), 3 - g))])
                                       for g in (1, 2, 3)]), np.arange(1, 4))}
    s2 = sigma ** 2
    E = tm.columns[rows]
    Un = new_basis(so.Q, E)
    d_n = float(np.sum((Un.T @ so.r) ** 2)) - Un.shape[1] * s2
    m_ss = (settings.material_sigma * sigma) ** 2 * len(rows)
    out = []
    for name, (C, what) in trials.items():
        ss, k, _, _ = nested_f_batch(C, so.Q, so.r, so.rss, so.dof)
        j = int(np.argmax(ss))
        d_a = float(ss[j]) - float(stats.chi2.isf(np.log(2) / C.shape[0], max(int(k[j]), 1))) * s2
        if d_a < d_n - m_ss:
            continue
        d_b, p_b, stands = _beyond(so, new_basis(so.Q, C[j]), E, sigma, tm.tries, settings)
        if stands:
            continue
        out.append({"alternative": name, ("at_s" if name == "event" else "degree"): float(what[j]),
                    "explained_ss_um2": max(d_a, 0.0) / UM ** 2, "cause_beyond_it_ss_um2": max(d_b, 0.0) / UM ** 2,
                    "p_adjusted_cause_beyond_it": p_b})
    return out


def _signal(tm: Term, so: _State, sigma) -> tuple:
    """The cause's signal in the joint fit and its debiased sum of squares.

    Its columns' part outside the rest of the model ``so`` (the other named
    causes) times their coefficients: ``(sig (n_rows,), ss - k sigma^2)``.
    """
    E = tm.columns[so.rows]
    Ep = E - so.Q @ (so.Q.T @ E)
    sig = Ep @ np.linalg.lstsq(Ep, so.r, rcond=1e-12)[0]
    return sig, float(sig @ sig) - E.shape[1] * sigma ** 2


def _reproduces(U: np.ndarray, signal: tuple, so: _State, sigma, settings) -> tuple:
    """Whether the columns ``U`` (orthonormal, outside ``so.Q``) reproduce a cause's signal and explain as much.

    ``signal``: :func:`_signal`'s ``(sig, d_n)``. Returns ``(overlap, d_w,
    ind)``: the share of the signal's square norm inside span(U), the
    debiased sum of squares U explains beside ``so`` (m^2), and whether both
    reach ``rival_share`` (of 1 and of ``d_n``).
    """
    sig_n, d_n = signal
    overlap = float(np.sum((U.T @ sig_n) ** 2) / max(sig_n @ sig_n, 1e-300))
    d_w = float(np.sum((U.T @ so.r) ** 2)) - U.shape[1] * sigma ** 2
    return overlap, d_w, overlap >= settings.rival_share and d_w >= settings.rival_share * d_n


def _readings_only(sc) -> bool:
    """A scan of one layout: a single trial, or trials that differ only in the pre-travel's reading
    (``pretravel_along``: the same columns read along the normal or along the approach)."""
    if sc.size == 1:
        return True
    # the reading's key first (a scan of many layouts, the usual one, has none: refused without building a
    # label per trial, 8,060 labels a discover of the demo's campaign), then stop at the second label seen
    if not sc.infos or not all("pretravel_along" in (info or {}) for info in sc.infos):
        return False
    first = None
    for info in sc.infos:
        label = tuple(sorted((k, v) for k, v in _layout_label(info).items() if k != "pretravel_along"))
        if first is None:
            first = label
        elif label != first:
            return False
    return True


class _Layouts(Sequence):
    """A cause's fixed layouts (single-trial scans, or one layout's readings: :func:`_readings_only`) as
    ``(info, (n, k) columns)``, each built when asked, not kept."""

    def __init__(self, scans):
        self._items = [(sc, j) for sc in scans for j in range(sc.size)]

    def __len__(self):
        return len(self._items)

    def __getitem__(self, i):
        sc, j = self._items[i]
        return sc.infos[j], sc.build([j])[0]


def _layout_label(info) -> dict:
    """The choices naming a layout (a drift's degree, a sensor, a feature, a form): its text and integer items."""
    return {k: v for k, v in (info or {}).items() if isinstance(v, (str, int)) and not isinstance(v, bool)}


def _cause_alternatives(tm: Term, so: _State, sigma, settings, fixed, signal: tuple, confounded=()) -> list:
    """Other catalogue causes (a few fixed layouts each) whose columns reproduce the named cause's signal.

    Two causes whose columns span nearly the same thing on a design are
    one explanation under two names there: lost motion on touches that
    each approach along the surface normal is a function of the approach
    direction alone (``|n_x| / 2``: harmonics 0, 2, 4, ... of the azimuth,
    99 % of it in harmonics 2 and 4), which a probe's lobing also is; a
    machine that drifts with time and expands with a temperature that
    itself follows the clock (a slow sensor: the bed, the room) read the
    same offsets and scales changing smoothly over the campaign. Parsimony
    picks one, but the data do not. The test is :func:`_alternatives`'
    with the other cause's columns in place of a smooth term: it
    reproduces at least ``rival_share`` of the signal and explains at
    least ``rival_share`` as much (debiased), and the named cause explains
    nothing material and significant beyond it (:func:`_beyond`, the
    Bonferroni factor of its adoption: where it does, the data prefer it,
    as for a gradual cause's time alternatives). A cause with several fixed
    layouts (a drift's degrees 1-3, one layout per temperature sensor, per
    changed feature) is an alternative when one of them is: the test is
    against the named cause's signal, which no layout reproduces by
    fitting the noise. Causes that nest one another (``counter_cause``)
    are judged by the counter check, not here.

    ``fixed``: ``fixed() -> {cause name: layouts}`` of the catalogue's
    causes whose scans are all single trials, the layouts a sequence of
    ``(info, (n, k) columns, all rows)`` (:class:`_Layouts`: built when
    tested); a bare ``(n, k)`` array is one layout without a label.
    ``signal``: :func:`_signal` of ``tm`` beside ``so``. Each alternative
    names the layout that matched (``layout``: its degree, sensor,
    feature or form).

    ``confounded``: the causes refused in a search round as confounded with
    the model (variance inflation beyond ``vif_max``: their magnitudes are
    not determined, so their presence was never tested against the named
    cause's). For these the part of their columns outside the model is all
    the data can see of them, and it need not lie along the named cause's
    signal: lost motion mostly inside the baseline's span leaves a sliver
    outside it, and lobes' eight columns take what of the same structure
    falls in their own span (gen_a reversal 1457, 1535, 1222, tuning seeds:
    reversal refused at variance inflation 830-1440, its visible part
    explaining 7.3-10.7 um^2 against the lobes' 6.7-8.3, reproducing
    14-48 % of their signal; the lobes named confidently). Such a cause is
    an alternative without the overlap condition: its visible part
    explains at least ``rival_share`` as much and the named cause nothing
    material and significant beyond it (``refused_confounded``: True).

    ``tm.round_rivals`` (:data:`CAUSE_ALTERNATIVES_OF_THE_ROUND`): the other candidates that passed every test of
    the round ``tm`` won, in the form each passed with, are tested the same way where their cause has no fixed
    layouts (a periodic error's period, a local defect's position and width: searches, which ``fixed`` lacks);
    such an alternative carries ``of_the_round``: True.
    """
    d_n = signal[1]
    out = []
    if d_n <= 0:
        return out
    cause = tm.origin
    pool = list(fixed().items())
    # the round's other passing candidates whose scans are not fixed layouts (a period, a defect's position and
    # width): the form each passed the round with (CAUSE_ALTERNATIVES_OF_THE_ROUND)
    of_round = {r[0] for r in tm.round_rivals} - {n for n, _ in pool} if CAUSE_ALTERNATIVES_OF_THE_ROUND else set()
    pool += [(n, [(info, B)]) for n, info, B in tm.round_rivals if n in of_round]
    for name, layouts in pool:
        other = causes_mod.lookup(name, cause.kinds[0]) if cause is not None else None
        if name == tm.cause or (cause is not None and cause.counter_cause == name) or (
                other is not None and other.counter_cause == tm.cause):
            continue
        best = None
        for info, B in ([({}, layouts)] if isinstance(layouts, np.ndarray) else layouts):
            # (a confounded cause's visible part need not lie along the signal: see above; standing beside a
            # layout, material and significant, the data would tell them apart)
            one = _one_explanation(B, signal, tm.columns, so, sigma, tm.tries, settings,
                                   visible_only=name in confounded, above=None if best is None else best[1])
            if one is not None:
                best = (*one, info, B if NAMED_ALTERNATIVE_SHIFT_CARRIED else None)
        if best is not None:
            out.append({"cause": name, "layout": _layout_label(best[4]), **({"of_the_round": True} if name in of_round
                                                                          else {}), "overlap": best[0],
                        "explained_ratio": best[1] / d_n, "cause_beyond_it_ss_um2": max(best[2], 0.0) / UM ** 2,
                        "p_adjusted_cause_beyond_it": best[3],
                        **({"refused_confounded": True} if name in confounded else {}),
                        # (the layout's columns, for the workpiece: popped by the caller; held only where used)
                        **({"_columns": best[5]} if best[5] is not None else {})})
    return out


def _alternatives(bl, tm: Term, so: _State, sigma, settings, bases, signal: tuple, known=()) -> list:
    """Covariates of other families whose smooth term reproduces the cause's signal.

    The cause's signal is its contribution to the joint fit (its columns'
    part outside the rest of the model, times their coefficients). A smooth
    function of a covariate of another family (:attr:`Covariate.family`)
    that reproduces at least ``rival_share`` of it and explains at least
    ``rival_share`` as much (debiased) means the design cannot tell the
    cause from "something following that covariate": the name is then
    flagged as ambiguous. ``known``: diagnoses made against ``so`` itself
    (their term bases outside it are taken, not projected again).
    ``signal``: :func:`_signal` of ``tm`` beside ``so``.
    """
    have = {d.covariate: d.basis for d in known if d.basis is not None}
    fam = bl.covariate(tm.covariate).family if bl.covariate(tm.covariate) is not None else ""
    rows = so.rows  # so: the model without the cause (the other named causes)
    d_n = signal[1]
    m_ss = (settings.material_sigma * sigma) ** 2 * len(rows)
    out = []
    if d_n <= 0:
        return out
    for cov in bl.covariates:
        if not cov.family or cov.family == fam or cov.name not in bases:
            continue
        B = bases[cov.name]  # built once: a long log's LazyBases builds it on every access
        if isinstance(B, tuple):
            continue
        U = have[cov.name] if cov.name in have else new_basis(so.Q, B[rows])
        if U.shape[1] == 0:
            continue
        overlap, d_w, ind = _reproduces(U, signal, so, sigma, settings)
        # the structure lives there more than in the cause: it explains materially
        # more than the cause (beyond 1 / rival_share of it) and reproduces at
        # least half of the cause's signal, so the cause may have caught only
        # the part of it that its columns can bend to
        dom = overlap >= 0.5 and d_w >= d_n / settings.rival_share and d_w - d_n >= m_ss
        if overlap >= 0.5:
            out.append({"covariate": cov.name, "overlap": overlap, "explained_ratio": d_w / d_n,
                        "indistinguishable": bool(ind), "explains_more": bool(dom)})
            if ALTERNATIVES_TWO_WAY != "off":
                out[-1].update(_two_way(so, U, B[rows], tm, sigma, settings))
    if ALTERNATIVES_TWO_WAY != "off":
        for a in out:  # the count of alternatives the two-way test was made against, said with each
            a["two_way"]["alternatives_tried"] = len(out)
            p_a = a["two_way"].pop("p_alternative_beyond")
            a["two_way"]["p_adjusted_alternative_beyond"] = min(1.0, p_a * len(out))
            a["two_way"]["by_ratios"] = a["indistinguishable"]  # (the two ratios' verdict, kept for the report)
            ind = a["indistinguishable"] if ALTERNATIVES_TWO_WAY == "add" else False
            a["indistinguishable"] = bool(ind or not a["two_way"]["cause_stands"])
    return out


#: Step 8's alternatives gate as a two-way non-nested test (session 34, alt34), beside or instead of its two hard
#: ratios (the smooth's overlap with the cause's signal and what it explains, each at least ``rival_share``). For
#: every covariate of another family whose smooth term reproduces at least half of the named cause's signal (the
#: alternatives the report lists), two nested F tests, each of the one model inside the union of both (Cox's
#: non-nested comparison made by the comprehensive model): the cause's columns beyond model + the smooth (the
#: Bonferroni factor of the cause's adoption, material over the rows: :func:`_beyond`, step 8's test for a catalogue
#: alternative), and the smooth's beyond model + the cause (Bonferroni over the alternatives tried, at
#: ``alpha_family``). The name is hedged (the covariate joins ``indistinguishable_from``) where the cause does not
#: stand beyond the smooth: the data do not prefer it to "something following that covariate". No Bonferroni over the
#: alternatives on the cause's side: the confident name claims the cause stands beyond each of them, an
#: intersection of rejections whose error is at most one test's level (an intersection-union test). ``"off"``: the
#: ratios alone (the behaviour before); ``"add"``: hedged by the ratios or by the test; ``"replace"``: by the test
#: alone (a smooth reproducing 80 % of the signal beside which the cause still stands no longer hedges it).
#: **``"add"`` since session 34**: set C's gen_c clamp_creep 6704 (`thermal_drift` confident beside a feature smooth
#: reproducing 0.787 of its signal and explaining 1.05 times as much) reads `thermal_drift?` (beyond the smooth 8.0
#: um^2, p_adj 1.5e-5, against a materiality of 10.4: significant, not material). On the tuning seeds (gen_a, gen_b
#: 1000-1004 and gen_c 0-4 every effect, the simulator 4000-4004: 320 campaigns) no cause, confidence or workpiece
#: check moved (8 findings hedged by the test were hedged already); on gen_a reseat_hysteresis 1005-1104 and gen_c
#: clamp_creep 5-88 (184) one reading moved, right -> right: clamp_creep 68 `part_change` -> `part_change?`.
#: ``"replace"`` would besides make 16 of those 320 right names confident (the ratios hedged them, the cause standing
#: beyond every smooth), none wrong: not measured on outcomes, left to the lead. docs/discovery-studies.md, "Session 34: the
#: alternatives gate as a two-way test, and an outlier finding's doubt carried back (alt34)".
ALTERNATIVES_TWO_WAY = "add"


def _two_way(so: _State, U: np.ndarray, B: np.ndarray, tm: Term, sigma: float, settings) -> dict:
    """:data:`ALTERNATIVES_TWO_WAY`'s two nested F tests between a named cause ``tm`` and one smooth alternative.

    ``U``: the smooth's orthonormal basis outside ``so.Q``; ``B``: its columns on ``so.rows``. The cause's side is
    :func:`_beyond` (debiased sum of squares beyond the smooth, its p-value times the cause's adoption tries, and
    whether it stands: material and significant at ``alpha_family``); the smooth's side the same test of ``B``
    beyond model + cause, unadjusted here (the caller knows the count). Returns ``{"two_way": {...}}`` in um^2.
    """
    E = tm.columns[so.rows]
    d_c, p_c, stands = _beyond(so, U, E, sigma, tm.tries, settings)
    Uc = new_basis(so.Q, E)
    d_a, p_a, _ = _beyond(so, Uc, B, sigma, 1.0, settings)
    return {"two_way": {"cause_beyond_ss_um2": d_c / UM ** 2, "p_adjusted_cause_beyond": p_c,
                        "cause_stands": bool(stands), "material_ss_um2": (settings.material_sigma * sigma) ** 2
                        * len(so.rows) / UM ** 2, "alternative_beyond_ss_um2": d_a / UM ** 2,
                        "p_alternative_beyond": p_a}}


def _pspline_penalty(cov, n_modes: int, m: int) -> np.ndarray:
    """Second-difference penalty per mode on B-spline coefficients (identity for others)."""
    if cov.kind == "smooth" and m >= 3:
        D = np.diff(np.eye(m), 2, axis=0)
        P1 = D.T @ D + 1e-6 * np.eye(m)
    else:
        P1 = np.eye(m)
    return np.kron(np.eye(n_modes), P1)


#: Whether the unnamed smooth is refused as an extension (reported, not adopted: no columns, the workpiece the
#: baseline's) when its held-out curve over :data:`PENALTY_GRID` is flat within :data:`PENALTY_TIE_RTOL`: the held-out
#: set-ups then validate the term's presence (its columns the held-out set-up's own, refitted unpenalised leave one
#: row out, :class:`Folds`) but not its penalty, which alone decides what it takes of the workpiece. Session 32
#: (review32c F8, issue 13 item 3b): measured both ways on the tuning campaigns (docs/discovery.md); False: adopted
#: at the largest penalty of the tie (:data:`PENALTY_TIE_RTOL`).
UNNAMED_SMOOTH_FLAT_REFUSED = False


def _unnamed_smooth(bl, diag, terms, folds, st, y, rows, cv_cur, sigma, settings, bases) -> Term | None:
    """The penalised smooth term in the strongest remaining covariate, if it earns its keep."""
    top = B = None
    for d in diag:  # each basis fetched once: a long log's LazyBases builds it on every access
        if d.significant(settings.alpha_family) and d.covariate in bases:
            B = bases[d.covariate]  # all rows
            if not isinstance(B, tuple):
                top = d
                break
    if top is None:
        return None
    cov = bl.covariate(top.covariate)
    if cov is None:
        return None
    m = B.shape[1] // len(cov.modes)
    P1 = _pspline_penalty(cov, len(cov.modes), m)
    E_named = _stack(terms, rows)
    Br = B[rows]
    Bp = Br - st.Q @ (st.Q.T @ Br)
    scale = float(np.trace(Bp.T @ Bp)) / max(B.shape[1], 1)
    lams = scale * np.asarray(PENALTY_GRID)
    cvs = []
    for lam in lams:
        Pm = np.zeros((E_named.shape[1] + B.shape[1],) * 2)
        Pn = _penalty(terms)
        if Pn is not None:  # a penalised named cause keeps its own penalty
            Pm[:E_named.shape[1], :E_named.shape[1]] = Pn
        Pm[E_named.shape[1]:, E_named.shape[1]:] = lam * P1
        cvs.append(folds.mse(y[rows], np.hstack([E_named, Br]), Pm))
    i = _penalty_pick(cvs)  # of penalties the held-out set-ups cannot tell apart, the largest (PENALTY_TIE_RTOL)
    cv, lam = cvs[i], lams[i]
    gain = cv_cur - cv
    m2 = (settings.material_sigma * sigma) ** 2
    ev = {"covariate": cov.name, "diagnosis": top.words, "cv_rms_before_um": float(np.sqrt(cv_cur)) / UM,
          "cv_rms_after_um": float(np.sqrt(cv)) / UM, "cv_gain_um2": gain / UM ** 2, "penalty": float(lam / scale),
          "penalty_cv_spread": _penalty_flatness(cvs), "adopted": bool(gain >= m2)}
    if UNNAMED_SMOOTH_FLAT_REFUSED and gain >= m2 and PENALTY_TIE_RTOL is not None \
            and ev["penalty_cv_spread"] <= PENALTY_TIE_RTOL:
        ev.update({"adopted": False, "penalty_not_identified": True})
        return Term(causes_mod.UNEXPLAINED, np.zeros((bl.n, 0)), (), {}, cov.name, evidence=ev,
                    penalty=np.zeros((0, 0)), unnamed=True)
    if gain < m2:
        return Term(causes_mod.UNEXPLAINED, np.zeros((bl.n, 0)), (), {}, cov.name, evidence=ev,
                    penalty=np.zeros((0, 0)), unnamed=True)
    return Term(causes_mod.UNEXPLAINED, B, tuple(f"smooth[{i}]" for i in range(B.shape[1])), {"covariate": cov.name},
                cov.name, evidence=ev, penalty=lam * P1, unnamed=True)


def _repeats_beyond_residual(key: np.ndarray, st: _State, settings) -> dict | None:
    """The model's residuals scattering significantly more within repeats than overall: figures, else None.

    ``key`` is the replicate group of each of ``st.rows``
    (:attr:`core.baseline.Baseline.replicate`: touches of one target in one
    set-up, the same design row; ``< 0`` none). The extended model's
    residuals at repeats, less their group's mean, are what the model
    leaves varying between touches of one place (the baseline is the same
    there; a term that varies within the group, a drift, a lobing under
    approaches a few degrees apart, has taken its share). A within-repeats
    mean square well above the model's in-sample one says touches of one
    place may vary with something the model does not hold (a touch's
    history: the approach's turn, a re-seat), and the repeats the noise was
    taken from carry it: the materiality, debias and rival checks of an
    adoption judged with that noise took it for the probe's.

    The statistic: F = (within-repeats sum of squares / the groups' sum of
    (size - 1)) / (``st.rss`` / ``st.dof``), judged one-sided on F(sum of
    (size - 1), ``st.dof``) at ``settings.alpha_family`` (0.0025). It is a
    conservative hybrid, not the lack-of-fit test's other tail: that would
    divide by the rest of the residual, (rss - ss_within) / (dof -
    dof_within); this divides by the whole residual, which contains the
    within-repeats sum, so the two mean squares correlate under the null.
    Its real level is design-dependent and below the nominal 0.25 % (the
    review's Monte Carlo of session 12, null residuals: 0.13 % at 6 and 200
    dof, 0.05 % at 12 and 148, 0.0004 % at 12 and 60, up to 600 times below;
    ``test_repeats_beyond_residual_null_calibration``: 3 of 8,000 draws at 12
    and 148). The groups' sum of (size - 1) also overstates the
    within-repeats residuals' dof by tr(W H) (W the within-group centring,
    H the model's hat matrix: what the model's columns varying within the
    groups take; the review's figures: 0.10 at 1609, 4.17 of 12 at gen_a
    c_drift 1113), which
    makes it more conservative still. The statistic was kept as measured
    (every before/after figure here and in docs/discovery.md is of it); the exact other-tail
    version was not measured on campaigns.

    Repeats separated in time can honestly scatter more than the whole
    residual, against the naive expectation: where the model's form of a
    drift is imperfect over the gaps between repeats, the within-repeats
    residuals carry that imperfection (gen_b thermal_drift 1050-1079, a
    tuning seed range, the review's count: 6 of 30 at p < 0.05, 2 of 30 at
    p < 0.0025,
    1055 p = 0.0012 and 1072 p = 6.5e-4). So the F test alone does not carry
    the rule; the comparison below does, and it is a point-estimate
    heuristic (the within-repeats mean square rests on 6-24 dof, a relative
    standard error of 29-58 %).

    ``beyond_residual_ss_um2``: the within-repeats mean square above the
    model's, times the model's rows: what the structure varying between
    touches of one place would amount to over the campaign if the repeats
    are typical of its touches. :func:`_findings` makes a named cause
    ambiguous by it only where that is at least what the cause explains
    (the rival check's "explains as much"): then the cause may hold a part
    of that structure. gen_b thermal_drift 1072: 117 um^2 beside the
    314 um^2 the drift explains, named; gen_a reseat_hysteresis 1609:
    394 um^2 beside `c_drift`'s 30, ambiguous. Near miss (a tuning seed):
    gen_a probe_lobing 1041, 67.8 um^2 beside 74.0 explained, p = 0.0053
    (at ``settings.alpha``, 0.01, where first tried, it made that and gen_a
    c_drift 1041 ambiguous at p = 0.0052-0.0053; hence the family's level).

    It fixes the campaign it was designed on, 1609, and has no independent
    confirmation: it changed no cause or confidence on 4,550 tuning
    campaigns nor 370 fresh ones, and the 9 named confident misnamings of
    gen_a reseat_hysteresis on the tuning seeds it does not reach have
    p = 0.28-0.95 or no repeat groups.
    """
    rep = replicate_scatter(key, st.r)
    if rep.dof < 1 or st.dof < 1 or not st.rss > 0:
        return None
    F = (rep.ss / rep.dof) / (st.rss / st.dof)
    p = float(stats.f.sf(F, rep.dof, st.dof))
    if p >= settings.alpha_family:
        return None
    return {"repeats_sigma_um": float(np.sqrt(rep.ss / rep.dof)) / UM, "repeats_dof": int(rep.dof),
            "model_sigma_um": st.sigma / UM, "model_dof": int(st.dof), "F": float(F), "p_value": p,
            "beyond_residual_ss_um2": float((rep.ss / rep.dof - st.rss / st.dof) * len(st.rows)) / UM ** 2}


#: The magnitudes of a cause read in one of two readings of the pre-travel (``pretravel_along``,
#: :data:`core.causes.PRETRAVEL_ALONG`: the data chose the better-fitting one) take a U95 that carries the
#: choice (:func:`_reading_u95`, session 22); False: the chosen reading's as if it were known, as before.
READING_U95 = True
#: The weight of the other reading above which a magnitude it leaves free (undetermined, or a norm only bounded
#: below) gets no U95 (:func:`_reading_u95`; session 23 review): the mixture's 95 % interval is bounded only where
#: the chosen reading alone can hold 0.95 of it, ``(1 - w_o) >= 0.95``. At or below it the chosen reading's U95
#: stands (its coverage in the mixture at least ``0.9545 (1 - w_o)``, 0.907 at the level).
READING_FREE_WEIGHT = 0.05


def _other_reading(bl, tm: Term):
    """The same layout of ``tm``'s cause in its other reading of the pre-travel: ``(info, (N, k) columns)``
    (whitened as the engine's), or None where the term has no reading or its scan offers one only."""
    info = tm.info or {}
    cause = tm.origin
    if "pretravel_along" not in info or cause is None or cause.scans is None:
        return None
    rest = {k: v for k, v in info.items() if k != "pretravel_along"}
    for sc in cause.scans(bl)[0]:
        if sc.size < 2 or not _readings_only(sc):
            continue
        for j, inf in enumerate(sc.infos):
            if inf.get("pretravel_along") != info["pretravel_along"] and \
                    {k: v for k, v in inf.items() if k != "pretravel_along"} == rest:
                C = np.asarray(sc.build(np.array([j]))[0], float)
                return inf, _white(bl, C)
    return None


def _reading_u95(cause, bl, tm: Term, so: _State, rows, vals: dict, u95: dict, sigma: float, settings, folds,
                 others) -> dict | None:
    """The U95 of magnitudes whose reading of the pre-travel the data chose: the choice's uncertainty carried.

    ``probe_lobing`` reads its lobes along the normal or along the approach
    (:data:`core.causes.PRETRAVEL_ALONG`), whichever fits better; its
    magnitudes' U95 was the chosen reading's as if that reading were known.
    The two readings are two models of the same lobes (the chosen reading's
    label combinations, ``tm.map``) beside the same others (``so``), of
    ``k_c`` and ``k_o`` determined columns (``k_o < k_c`` where the other
    reading leaves some of them undetermined); with the noise ``sigma`` known
    their weights are Akaike's (the weights of Buckland et al.),
    ``w_o = 1 / (1 + exp(D / (2 sigma^2) + (k_o - k_c)))`` (from
    ``AIC_o - AIC_c = D / sigma^2 + 2 (k_o - k_c)``), ``D`` what the
    chosen reading's columns explain beside ``so`` less what the other's
    do. With equal counts (gen_a: 8 and 8) that is the likelihood ratio's
    weight. On gen_b the normal reading's first harmonic lies in the
    baseline and the approach reading's does not: with its own
    combinations the other reading had two or four columns more, and what
    they caught of anything counted for it (the session 22 review:
    w_o > 0.5 in 53 of gen_b probe_lobing 1000-1199's 148 findings, all
    written along the normal). A magnitude's uncertainty is then that of the
    mixture of the two readings' estimates ``N(a_c, u_c^2)`` and
    ``N(a_o, u_o^2)`` (``u = U95 / 2``), taken about the value reported
    (the chosen reading's ``a_c``): its second moment
    ``(1 - w_o) u_c^2 + w_o (u_o^2 + (a_o - a_c)^2)`` (the unconditional
    variance of model averaging, Buckland, Burnham and Augustin 1997,
    Biometrics 53, 603-618), U95 twice its root. Where the data prefer the
    chosen reading clearly (``D`` many ``sigma^2``) ``w_o`` vanishes and the
    U95 is the chosen reading's; it is never narrowed below that.

    Session 23 (the session 22 second review's three latent faults): ``k_c``
    and ``k_o`` are counted by one cut, the directions :func:`_determined`
    keeps beside ``so`` (before, ``k_o`` by its ``WEAK_SV`` of 1e-2 and
    ``k_c`` by :func:`new_basis`'s 1e-5: a direction between the two counted
    for the chosen reading alone, and what it caught too). The directions
    the chosen reading's combinations hold at 0 are not the other reading's
    estimates (``held``, :func:`_magnitudes`: gen_b probe_lobing 1002's
    ``k1_amplitude_um`` read 9e-17 +- 7e-17 um there). A magnitude the other
    reading's fit refused by the plausible range keeps its value and U95 in
    the mixture (before: skipped, as if the other reading agreed), a norm it
    does not report because a coefficient of its pair is held or unseen
    keeps its lower bound (the norm with that coefficient at 0: the
    mixture's second moment about ``v`` is at least ``w_o (lower - v)^2``
    where the bound lies above ``v``), and the carried U95 is judged against
    the plausible range (:func:`_within_range`, as the carry beside an
    unnamed smooth is). A magnitude the other reading does not determine
    and holds no bound of is not carried (its U95 the chosen reading's).

    The session 23 review's mends: the other reading's weak directions are
    looked for within the combinations it is fitted in (``held``); a
    magnitude it leaves free (undetermined, or a norm bounded below only)
    gets no U95 where its weight ``w_o`` exceeds
    :data:`READING_FREE_WEIGHT` (``"free_in_other"``; the mixture's 95 %
    interval is unbounded there), the chosen U95 (with the floor of a lower
    bound) standing at or below it; both counts are made without the
    ``vif_max`` refusal (a chosen reading refused there counted ``k_c = 0``
    and gave ``w_o = 1``) and beside the model's penalised terms, as
    :func:`_magnitudes`' weak test is.

    Returns None where the term has no other reading (approaches along the
    normal: one reading), else ``{"other": its reading, "explained_gap_um2": D,
    "columns": [k_c, k_o], "weight_other": w_o, "other_values": .., "other_u95": .., "u95_chosen": .., "carried_in_u95":
    [keys whose U95 grew], "u95": the new U95 dict}``, with ``"other_lower_bounds"`` (the norms that entered by their
    lower bound), ``"wider_than_range"`` (the keys whose carried U95 is wider than their plausible range: the
    report gives them no value) and ``"free_in_other"`` (the keys given no U95) where there are any.
    """
    got = _other_reading(bl, tm)
    if got is None or not (sigma > 0):
        return None
    inf_o, C = got
    # the other reading of the same lobes: the chosen reading's label combinations (tm.map), those of them the
    # other reading determines beside so. (Its own combinations on gen_b held the first harmonic the normal
    # reading leaves in the baseline: two columns of anything else counted for it; the session 22 review.)
    Ec, Eo = tm.columns[rows] @ tm.map, C[rows] @ tm.map
    # the penalised terms of the model (an adopted nonrigid), beside which _magnitudes fits both readings and judges
    # their weak directions: the same Gram matrix for the counting cut (session 23 review)
    pen = _pen_of(others, rows) if folds is not None else None
    sub = _determined(so.Q, Eo, np.inf, pen)[0]
    if sub.shape[1] == 0:
        return None
    Mo = tm.map @ sub
    tm_o = dataclasses.replace(tm, columns=C, info=inf_o, map=Mo, cols_all=C, at_adoption=None, evidence={})
    # (the directions outside Mo are held at 0: a magnitude that needs one is not the other reading's estimate; a
    # norm so left out keeps its lower bound, and one the plausible range refused its value and U95: session 23)
    wide_o, lower_o = [], {}
    vals_o, u95_o = _magnitudes(cause, bl, tm_o, so.Q, rows, wide_o,
                                boot=(folds, others) if folds is not None else None, held=True, lower=lower_o)
    for key, v, u, _, _ in wide_o:
        vals_o[key], u95_o[key] = v, u
    # each reading's count k by one cut: the directions _determined keeps beside so (before, the other reading's by
    # _determined's WEAK_SV, 1e-2, and the chosen reading's by new_basis's, 1e-5: a direction between the two counted
    # once for the chosen reading alone, and the weight favoured the other by e per such direction; session 23)
    # (no refusal by vif_max for counting, in either reading: a chosen reading whose best direction is inflated
    # beyond it counted k_c = 0 and gave w_o = 1, its own columns ignored; the session 23 review. The count is of
    # the directions the data determine, WEAK_SV's cut; the term was adopted by its own tests)
    sub_c = _determined(so.Q, Ec, np.inf, pen)[0]
    Uc = new_basis(so.Q, Ec if sub_c.shape[1] == Ec.shape[1] else Ec @ sub_c)
    Uo = new_basis(so.Q, C[rows] @ Mo)
    D = float(np.sum((Uc.T @ so.r) ** 2) - np.sum((Uo.T @ so.r) ** 2))
    k_c, k_o = Uc.shape[1], Uo.shape[1]
    w_o = float(special.expit(-D / (2 * sigma ** 2) + (k_c - k_o)))  # (Akaike's weight: -AIC / 2 = -RSS / 2s^2 - k)
    new, grown, floors, refused, free = dict(u95), [], [], [], []
    for key, v in vals.items():
        if not (isinstance(v, (float, int, np.floating)) and not isinstance(v, bool)):
            continue
        vo, uc, uo = vals_o.get(key), u95.get(key), u95_o.get(key)
        if uc is None:
            continue
        if vo is not None and uo is not None:
            u = 2 * float(np.sqrt((1 - w_o) * (uc / 2) ** 2 + w_o * ((uo / 2) ** 2 + (float(vo) - float(v)) ** 2)))
        elif w_o > READING_FREE_WEIGHT:
            # the other reading leaves the magnitude free (undetermined, or only bounded below): the mixture's 95 %
            # interval cannot be bounded, the chosen reading alone holding less than 0.95 of it (session 23 review)
            new[key] = None
            free.append(key)
            continue
        elif key in lower_o:
            # (a free reading of negligible weight) the other reading's amplitude is at least lower_o[key] (a
            # coefficient of its pair held or unseen): the mixture's second moment about v is at least
            # w_o (lower - v)^2 where the bound lies above v (Jensen)
            u = 2 * float(np.sqrt((1 - w_o) * (uc / 2) ** 2 + w_o * max(lower_o[key] - float(v), 0.0) ** 2))
            floors.append(key)
        else:
            continue
        if u > uc:
            new[key] = u
            grown.append(key)
            if _within_range(cause, key, float(v), u, None)[0] is None:  # the carried U95 beyond the plausible range
                refused.append(key)
    return {"other": inf_o["pretravel_along"], "explained_gap_um2": D / UM ** 2, "columns": [k_c, k_o],
            "weight_other": w_o,
            "other_values": {k: v for k, v in vals_o.items() if k in vals and k != "pretravel_along"},
            "other_u95": {k: v for k, v in u95_o.items() if k in vals},
            **({"other_lower_bounds": {k: lower_o[k] for k in floors}} if floors else {}),
            **({"wider_than_range": refused} if refused else {}),
            **({"free_in_other": free} if free else {}),
            "u95_chosen": {k: u95[k] for k in grown}, "carried_in_u95": grown, "u95": new}


#: A ``local_scale_defect``'s centre in words (``vmt discover``'s summary prints it under the finding): the bump is
#: a function of the machine's axis position, read at each touch's nominal contact point as the log gives it
#: (``Xn_mm``, ``Yn_mm``: the machine frame R, the error map's own), not a place on the part. A user reading "centre
#: 52.6 mm on Y" reads the Y axis at 52.6 mm on the machine's scale (session 35, cat35).
DEFECT_CENTRE_FRAME = ("the machine's {axis} axis position in mm, the frame of the log's nominal contact points "
                       "(Xn_mm, Yn_mm: the machine frame, the error map's own; not a place on the part)")
#: Two bump columns are one reading when their parts outside the model differ by at most this share of the bump's
#: own part (:func:`_defect_centre_images`): the same fit within rounding (an exact image differs by 1e-15 or so; a
#: bump elsewhere by an order one share).
DEFECT_IMAGE_REL = 1e-6


def _defect_centre_images(bl, tm, so, rows) -> list:
    """The other bumps the design cannot tell from ``tm``'s (a ``local_scale_defect`` term; ``so`` the model
    without it on ``rows``): its images under the table's quarter turns about the C axis (``bl.data.c0_m``).

    A part symmetric under a turn by 180 deg (or 90), measured only at C angles that differ by that turn, has a
    touch at every image of a touch's position, on the target the turn maps it onto, along the normal turned with
    it; a bump of one axis at ``q`` then moves the same targets' readings, set-up against set-up, as the bump at
    its image (the same axis at ``2 c0 - q`` for the half turn; the other axis for a quarter turn), which the
    targets' parameters and the set-ups' own terms cannot tell apart: both columns have the same part outside
    the model (gen_a local_scale_defect 1121, hexagon-pocket-sym at C 0 and 180 deg: the truth at Y -52.77 mm,
    the report at +52.59 mm, the two parts outside the baseline equal to rounding). The quarter turns' images (a
    four-fold part turned by 90 deg) are checked too; on gen_a's octagon-pocket-sym campaigns 1017, 1065, 1078,
    1091 none is one reading with the bump (each reported centre within its U95 of the drawn one). Each image
    (its axis, centre in mm, the turn, and the sign its amplitude takes) whose part outside ``so`` differs from
    the bump's by at most :data:`DEFECT_IMAGE_REL` of it, either sign, is returned; none where the C-axis centre
    is unknown. The centre's U95 (the profile's, about the centre reported) holds about each image alike.
    """
    d = bl.data
    c0 = np.asarray(d.c0_m, float)
    if c0.shape != (2,) or not np.all(np.isfinite(c0)) or not isinstance(so.Q, np.ndarray):
        return []
    ax = "XY".index(tm.info["axis"])
    q, w = float(tm.info["centre_m"]), float(tm.info["half_width_m"])
    u = q - c0[ax]
    # the line {p_ax = q} turned about c0 by 90, 180 and 270 deg (counter-clockwise): (axis, centre) of its image
    images = ({0: ((1, c0[1] + u), (0, c0[0] - u), (1, c0[1] - u)),
               1: ((0, c0[0] - u), (1, c0[1] - u), (0, c0[0] + u))}[ax])
    Q = so.Q

    def outside(C):
        v = np.asarray(_white(bl, C), float)[rows]
        return v - Q @ (Q.T @ v)

    own = outside(causes_mod._defect_cols(d, ax, q, w)[0])[:, 0]
    n_own = float(np.linalg.norm(own))
    if not n_own > 0:
        return []
    out = []
    for turn, (a2, q2) in zip((90, 180, 270), images):
        if abs(q2 - q) <= 1e-9 and a2 == ax:
            continue  # the bump is its own image (centred on the C axis)
        img = outside(causes_mod._defect_cols(d, a2, q2, w)[0])[:, 0]
        for sign in (1.0, -1.0):
            if np.linalg.norm(own - sign * img) <= DEFECT_IMAGE_REL * n_own:
                out.append({"axis": "XY"[a2], "centre_mm": q2 / MM, "turn_deg": turn,
                            "amplitude_sign": "same" if sign > 0 else "opposite",
                            "text": f"the design cannot tell this bump from one on the {'XY'[a2]} axis at "
                                    f"{q2 / MM:.4g} mm (its image under a {turn} deg turn about the C axis at "
                                    f"X {c0[0] / MM + 0.0:.2f}, Y {c0[1] / MM + 0.0:.2f} mm): both fit the touches "
                                    "alike"})
                break
    return out


def _findings(bl, terms, Qb, y, rows, st, settings, structure_e, diag_e, demoted, smooth, cv_named, bases,
              seen=(), fixed=None, repeats=None, folds=None, confounded=()) -> list:
    out = []
    sig = st.sigma
    named = [t for t in terms if not t.unnamed]
    # an unnamed smooth adopted beside the named causes: (its covariate's family, its covariate, its held-out gain)
    own_smooth = (_family(bl, smooth.covariate), smooth.covariate, smooth.evidence["cv_gain_um2"]) \
        if smooth is not None and smooth.columns.shape[1] else None
    # the model with every named cause: st itself when there is no unnamed smooth (same Qb, rows, terms)
    sf = (st if len(named) == len(terms) else _state(Qb, y, rows, named)) if named else None
    # the unnamed smooth adopted beside the named causes (with columns): the magnitudes are fitted beside it too
    smooth_terms = [t for t in terms if t.unnamed and t.columns.shape[1]]
    for tm in terms:
        if tm.cause == causes_mod.UNEXPLAINED:
            continue
        cause = tm.origin
        others = [t for t in named if t is not tm]
        so = _state(Qb, y, rows, others)
        a = tm.at_adoption  # judged beside this very model at its adoption: the same magnitudes
        # (a penalised named cause's U95 is the bootstrap's, made here once for the model reported: at adoption, in
        # every round it was tried, the delta method's)
        if a is not None and np.array_equal(a[1], rows) and a[0].shape == so.Q.shape and np.array_equal(a[0], so.Q) \
                and a[4] == _pen_key(others) and (tm.penalty is None or tm.unnamed or folds is None):
            vals, u95 = dict(a[2]), dict(a[3])
            iv = dict(tm.evidence.get("magnitude_intervals") or {})
        else:
            iv = {}
            vals, u95 = _magnitudes(cause, bl, tm, so.Q, rows,
                                    boot=(folds, others, True) if folds is not None else None, intervals=iv)
        prof = _profile_u95(cause, bl, tm, so.Q, rows)
        for key, (u, lo, hi, edge) in prof.items():  # a scan's refined parameters: the profile's interval (session 21)
            if vals.get(key) is not None and u95.get(key) is not None:
                u95[key] = max(u, u95[key]) if edge else u
                iv[key] = [lo, hi]
        beside_smooth, wide_note = None, None
        if smooth_terms and tm.penalty is None and MAGNITUDES_BESIDE_SMOOTH:
            # the model reported holds the unnamed smooth too: the magnitudes are fitted beside its columns with
            # its penalty (the joint ridge fit, _magnitudes' penalised nuisance), and the shift the smooth makes
            # carried where it is real (session 20)
            vals, u95, beside_smooth, wide_note = _magnitudes_beside_smooth(
                cause, bl, tm, so.Q, rows, folds, others, smooth_terms, vals, u95, settings.alpha_family)
            for key, (u, _, _, _) in prof.items():  # the profile's interval stays inside the carried one
                if vals.get(key) is not None and u95.get(key) is not None:
                    u95[key] = max(u95[key], u)
        reading = (_reading_u95(cause, bl, tm, so, rows, vals, u95, sig, settings, folds, others)
                   if READING_U95 and beside_smooth is None and tm.penalty is None else None)
        if reading is not None:
            u95 = reading.pop("u95")
            # a norm's interval [lo, hi] widened at both ends as its U95 is (the choice's spread is no Rice law)
            iv = {k: ([max(0.0, x[0] - (u95[k] - reading["u95_chosen"][k])), x[1] + u95[k] - reading["u95_chosen"][k]]
                      if k in reading["carried_in_u95"] else x) for k, x in iv.items()}
            if reading.get("wider_than_range"):
                # the U95 carried across the readings is wider than the plausible range: no value (as _within_range
                # and the carry beside a smooth judge it), the finding named at most ambiguous (session 23)
                wide_note = "; ".join(_undetermined_text(k, None, None, "across the two pre-travel readings")
                                      for k in reading["wider_than_range"])
                for k in reading["wider_than_range"]:
                    vals[k], u95[k] = None, None
            if reading.get("free_in_other"):
                # the other reading, of weight above READING_FREE_WEIGHT, leaves the magnitude free: no U95 (the
                # value is the chosen reading's), the finding named at most ambiguous (session 23 review)
                free_note = "; ".join(
                    f"{k} = {vals[k]:.3g} um in the reading chosen, free in the other (weight "
                    f"{reading['weight_other']:.3g} > {READING_FREE_WEIGHT:g}): no U95 across the two pre-travel readings"
                    for k in reading["free_in_other"])
                wide_note = "; ".join(x for x in (wide_note, free_note) if x)
        one_sided = _one_sided(cause, prof, vals) if ONE_SIDED_AT_BOUND else {}
        for key, (side, note) in one_sided.items():  # no value +- U95 where the profile reaches the range's end
            vals[key], u95[key] = None, None
            wide_note = "; ".join(x for x in (wide_note, note) if x)
        if tm.evidence.get("magnitudes_not_determined"):
            # the design does not determine the cause's magnitudes: none is reported
            # (a value computed from the determined directions alone means nothing)
            vals = {k: (None if isinstance(v, (float, int)) and not isinstance(v, bool) else v)
                    for k, v in vals.items()}
            u95 = {k: None for k in u95}
        ev = dict(tm.evidence)
        ev.pop("magnitude_intervals", None)
        said_nd = " ".join(str(x) for x in (ev.get("magnitude_undetermined"), wide_note) if x)
        unseen = [k for k, v in vals.items() if v is None and k in u95 and u95[k] is None and k not in one_sided
                  and not re.search(rf"(^|[\s;(]){re.escape(k)}[\s:]", said_nd)]
        if MAGNITUDE_NOT_SEEN_NOTE and unseen and not ev.get("magnitudes_not_determined"):
            # a magnitude the weak-direction rule (_magnitudes) left without a value was said nowhere (session 37:
            # mfb-3axis lobing_per_stylus seed 1, all 8 keys null, the reason naming 2); said, not judged: the
            # confidence does not read it
            ev["magnitude_not_seen"] = (f"{', '.join(unseen)}: not determined on this design: each needs a "
                                        "combination of the cause's columns the data cannot see beside the model"
                                        + (f" ({tm.weak} of its {len(tm.labels_all)} directions unseen)"
                                           if tm.weak else ""))
        if tm.form_rivals:
            ev["_form_columns"] = list(tm.form_rivals)  # (FORM_SHIFT_CARRIED: never in the report)
        # a norm's 95 % interval [lo, hi] (its U95 the symmetric cover, session 21): where its value and U95 are the
        # ones reported (beside a smooth the U95 is hypot(U95_s, shift): no such interval)
        iv = {k: x for k, x in iv.items() if vals.get(k) is not None and u95.get(k) is not None
              and not (beside_smooth is not None and k in beside_smooth.get("carried_in_u95", ()))}
        if iv:
            ev["magnitude_intervals"] = iv
        edges = [k for k, x in prof.items() if x[3] and k in iv]
        if edges:  # the profile's set reached its grid's end: its U95 at least the delta method's
            ev["profile_at_grid_edge"] = edges
        if one_sided:
            ev["one_sided"] = {k: x[0] for k, x in one_sided.items()}
        if tm.cause == "local_scale_defect" and bl.kind == "planar" and "centre_m" in tm.info:
            # the centres the design cannot tell from the one reported (session 35, cat35; its frame in words:
            # DEFECT_CENTRE_FRAME, printed by the command's summary and said in docs/discovery.md)
            images = _defect_centre_images(bl, tm, so, rows)
            if images:
                ev["centre_images"] = images
        if tm.weak:
            ev["not_identifiable_directions"] = int(tm.weak)
        if beside_smooth is not None:
            ev["magnitudes_beside_smooth"] = beside_smooth
        if reading is not None:
            ev["pretravel_reading"] = reading
        if wide_note is not None:  # named at most ambiguous (step 8), as a magnitude wide at adoption is
            ev["magnitude_undetermined"] = "; ".join(x for x in (ev.get("magnitude_undetermined"), wide_note) if x)
        # what the cause explains beside the others (the rival check's own figure; its tests were made)
        explained = max(_named_ss(so, sf, sig), 0.0) / UM ** 2
        ev["explained_ss_um2"] = explained
        signal = _signal(tm, so, sig)  # (both alternative checks test it)
        alt = _alternatives(bl, tm, so, sig, settings, bases, signal, _made_on(seen, so))
        ev["alternatives"] = alt
        ev["indistinguishable_from"] = [a["covariate"] for a in alt if a["indistinguishable"]]
        # confident: no other family's covariate reproduces the signal, and no
        # plainer explanation without a name explains as much (rival check)
        why = []
        by_test = [a for a in alt if a["indistinguishable"] and "two_way" in a and not a["two_way"]["by_ratios"]]
        by_ratio = [a["covariate"] for a in alt if a["indistinguishable"] and a not in by_test]
        if by_ratio:
            why.append("indistinguishable from a smooth term in " + ", ".join(by_ratio))
        if by_test:  # ALTERNATIVES_TWO_WAY: the cause does not stand beyond the smooth, though the ratios miss
            why.append("beyond a smooth term in " + ", ".join(
                f"{a['covariate']} (reproducing {a['overlap']:.0%} of its signal) it explains "
                f"{max(a['two_way']['cause_beyond_ss_um2'], 0.0):.3g} um^2 (materiality "
                f"{a['two_way']['material_ss_um2']:.3g}, {fmt_p(a['two_way']['p_adjusted_cause_beyond'])})"
                for a in by_test)
                       + ", nothing material and significant: the data do not prefer the name")
        more = [a for a in alt if a.get("explains_more") and not a["indistinguishable"]]
        if more:
            why.append("a smooth term in " + ", ".join(f"{a['covariate']} (x{a['explained_ratio']:.2g}, reproducing "
                                                        f"{a['overlap']:.0%} of its signal)" for a in more)
                       + " explains materially more: the structure may live there, the cause catching part of it")
        if ev.get("indistinguishable_counter"):
            why.append(f"a {ev['indistinguishable_counter']} explains as much "
                       f"({ev['counter_explained_ss_um2']:.3g} against {ev['explained_ss_um2']:.3g} um^2) and the "
                       "cause nothing material beyond it: this design cannot tell them apart")
        if FALLBACK_SELECTION_COUNTED and (fb := _fallback_short(ev)) is not None:
            why.append(fb)
        if ev.get("counter_waived"):  # (COUNTER_NEEDS_PLAINER_PASSING: refused for it at adoption, then kept)
            why.append(f"at its adoption {ev['counter_waived']}: named because the plainer cause failed, "
                       "though this cause is not shown beyond it")
            if cause.counter_cause and cause.counter_cause not in ev.get("ambiguous_with", []):
                ev["ambiguous_with"] = list(ev.get("ambiguous_with", [])) + [cause.counter_cause]
        calt = _cause_alternatives(tm, so, sig, settings, fixed if fixed is not None else dict, signal, confounded)
        if calt:
            # the matched layouts' columns leave the evidence here: the extended workpiece is refitted with each
            # (not a refused-confounded one: its size is not determined) in the cause's place (_workpiece)
            cols = [(a["cause"], a.pop("_columns", None)) for a in calt]
            if NAMED_ALTERNATIVE_SHIFT_CARRIED and any(not a.get("refused_confounded") for a in calt):
                ev["_alt_columns"] = [c for c, a in zip(cols, calt) if not a.get("refused_confounded")]
            ev["cause_alternatives"] = calt
            ev["ambiguous_with"] = [a["cause"] for a in calt]
            same = [a["cause"] for a in calt if not a.get("refused_confounded")]
            hidden = [a for a in calt if a.get("refused_confounded")]
            if same:
                why.append(f"the columns of {', '.join(same)} reproduce its signal on this design "
                           "and explain as much: one explanation under two names here")
            if hidden:
                why.append(", ".join(f"{a['cause']} (refused as confounded with the model: its size not determined)"
                                     for a in hidden)
                           + " explains as much with its part outside the model "
                           + ", ".join(f"(x{a['explained_ratio']:.2g})" for a in hidden)
                           + " and the cause nothing material beyond it: the data do not prefer the name")
        if cause.support is not None:
            # seen at two places where the cause reaches, or one gross error there could do as much
            reach = _support(bl, cause, tm.info, so, tm.columns[rows], reached_only=True)
            ev["support_units_reached"] = reach["support_units"]
            one = (_beyond_one_place(so, tm.columns[rows], sig, settings,
                                     np.asarray(cause.support(bl, tm.info))[rows])
                   if reach["refused"] and DEFECT_BEYOND_ONE_PLACE else None)
            if one is not None:
                ev["beyond_one_place"] = {k: v for k, v in one.items() if k != "rows"}
            if reach["refused"] and not (one is not None and one["verdict"] == "seen"
                                         and DEFECT_SEEN_BEYOND_ONE_PLACE_NAMED):
                if one is not None and one["verdict"] == "cannot tell":
                    why.append(f"where it reaches, {reach['where']}, and no other touch lies where it would move "
                               f"detectably ({one['z_expected']:.2g} sigma expected beyond its largest place): a "
                               "gross error at that one place (outlier) does as much, and this design cannot tell "
                               "them apart")
                else:
                    why.append(f"where it reaches, {reach['where']}: a gross error at that one place (outlier) "
                               "could do as much")
                ev["ambiguous_with"] = list(ev.get("ambiguous_with", [])) + [causes_mod.OUTLIER]
            if DEFECT_BEYOND_ONE_FEATURE and (feat := _feature_codes(bl, rows)) is not None:
                # one feature's: where the other features cannot tell (or, beside the final model, contradict)
                onef = _beyond_one_feature(so, tm.columns[rows], sig, settings, feat)
                if onef is not None and onef["verdict"] != "seen":
                    # the change of that feature the hedge would name, by the catalogue's own layouts
                    onef["part_change_ratio"] = _feature_change_ratio(bl, tm.columns, so, sig,
                                                                      _part_change_layouts(bl), onef["feature"])
                if onef is not None:
                    ev["beyond_one_feature"] = {k: v for k, v in onef.items() if k != "feature"}
                if onef is not None and onef["verdict"] != "seen" and (
                        onef["part_change_ratio"] is not None and onef["part_change_ratio"] >= settings.rival_share):
                    names = _feature_names(bl)
                    why.append(f"one feature ({names[onef['feature']]}) carries {onef['feature_share']:.0%} of what it "
                               "explains, and the other "
                               "features' touches "
                               + (f"it reaches would show it at its fitted size "
                                  f"({onef['z_expected']:.2g} sigma expected) and do not ({onef['z_rest']:.2g} sigma)"
                                  if onef["verdict"] == "refuted" else
                                  f"tell too little ({onef['z_expected']:.2g} sigma expected, "
                                  f"{onef['z_rest']:.2g} seen)")
                               + f", and a change of that feature (part_change) explains as much "
                                 f"(x{onef['part_change_ratio']:.2g})"
                               + (": the part, not the axis" if onef["verdict"] == "refuted" else
                                  ": this design cannot tell them apart"))
                    if "part_change" not in ev.get("ambiguous_with", []):
                        ev["ambiguous_with"] = list(ev.get("ambiguous_with", [])) + ["part_change"]
        if cause.richer is not None:
            # a richer cause nesting this one (lobes turned per set-up for fixed lobes): seen, or not excludable
            rich = cause.richer(bl, so.Q, y[rows], rows, tm.columns[rows], sig, WEAK_SV, info=tm.info)
            if rich is not None:
                ev["richer"] = {"cause": cause.richer_cause, **rich}
                seen_r = rich["p_value"] < settings.alpha_family
                odds = rich.get("log10_odds_fixed")
                weak = (RICHER_NEEDS_ODDS and odds is not None and rich["p_turned"] < settings.alpha
                        and odds < np.log10(1.0 / settings.alpha))
                if seen_r or rich["p_turned"] >= settings.alpha or weak:
                    why.append(f"{cause.richer_cause} explains {rich['beyond_ss_um2']:.3g} um^2 beyond it "
                               f"({fmt_p(rich['p_value'])}, {rich['dof']} directions): the data show it, if not "
                               "materially" if seen_r else
                               f"{cause.richer_cause} at the magnitudes fitted here would look as little different "
                               f"in a share {rich['p_turned']:.2g} of draws ({rich['dof']} directions tell them apart on "
                               "this design): the data cannot exclude it" if not weak else
                               f"{cause.richer_cause} at the magnitudes fitted here would look as little different "
                               f"in a share {rich['p_turned']:.2g} of draws, but the data favour the fixed lobes by odds "
                               f"of only {10 ** odds:.3g} (at most {10 ** rich['log10_odds_most']:.3g} on this design, "
                               f"{rich['dof']} directions tell them apart; {1 / settings.alpha:.3g} needed): the data "
                               "cannot exclude it")
                    ev["ambiguous_with"] = list(ev.get("ambiguous_with", [])) + [cause.richer_cause]
                    if RICHER_SHIFT_CARRIED and cause.richer_columns is not None:
                        # the richer cause's columns, the combinations the data determine beside the other terms
                        # (as the engine adopts a cause: _determined), built only if the extended workpiece is
                        # refitted with them in this cause's place (_workpiece's richer; they leave the evidence
                        # there); None where they are confounded with the model
                        def _richer_cols(c=cause.richer_columns, i=tm.info, Q=so.Q, pen=_pen_of(others, rows)):
                            B = c(bl, info=i)
                            M = _determined(Q, B[rows], settings.vif_max, pen)[0]
                            return B @ M if M.shape[1] else None
                        ev["_richer_columns"] = (cause.richer_cause, _richer_cols)
        if cause.gradual:
            talt = _time_alternatives(bl, tm, so, sig, settings)
            if talt:
                ev["time_alternatives"] = talt
            for a in talt:
                what = (f"a one-off change of the readings at t = {a['at_s']:.0f} s (an event: a knock, the probe "
                        "re-seating)" if a["alternative"] == "event" else
                        "the probe's effective size changing with time (dirt picked up, the probe warming)")
                why.append(f"{what} explains as much ({a['explained_ss_um2']:.3g} um^2) and the cause nothing "
                           "material beyond it")
        if own_smooth is not None and own_smooth[0] is not None and _family(bl, tm.covariate) == own_smooth[0]:
            # step 5 keeps a cause beside an unnamed smooth of its own covariate's family (the smooth refines
            # it); the smooth earned a material held-out gain beside it, so that covariate holds more than the
            # cause's form takes: the cause may be the part of a structure of another form its columns bend to
            why.append(f"an unnamed smooth term in {own_smooth[1]}, of its own covariate's family, earns a "
                       f"material held-out gain beside it ({own_smooth[2]:.3g} um^2 per touch): the structure "
                       "there has a form the cause lacks, the cause holding part of it")
        if ev.get("magnitudes_not_determined"):
            why.append(ev["magnitudes_not_determined"])
        if ev.get("magnitude_undetermined"):
            why.append("its size is not determined on this design: " + ev["magnitude_undetermined"])
        if repeats is not None and repeats["beyond_residual_ss_um2"] >= explained:
            ev["repeats_beyond_residual"] = repeats
            why.append(f"the model's residuals scatter more within repeats than overall "
                       f"({repeats['repeats_sigma_um']:.3g} against {repeats['model_sigma_um']:.3g} um, "
                       f"F = {repeats['F']:.3g}, {fmt_p(repeats['p_value'])}): touches of one place vary with "
                       f"something the model does not hold, worth {repeats['beyond_residual_ss_um2']:.3g} um^2 over the "
                       f"campaign against the {explained:.3g} um^2 the cause explains, and the noise its checks "
                       "were judged with carries it")
        if PART_CHANGE_ONE_TARGET and tm.cause == "part_change":
            share = _one_target_share(bl, tm, so, rows)
            if share is not None:
                ev["one_target_share"] = share
                if share >= PART_CHANGE_ONE_TARGET_SHARE:
                    why.append(f"one target carries {share:.0%} of the change: a change of one place has no form "
                               "of the part to tell it from that touch's own history (the path before it, a lost "
                               "motion the traverse winds)")
        if HEDGED_SHIFT_READING == "determined" and tm.penalty is None and _beyond_vif_max(ev, settings):
            # the term on its directions within vif_max only (VIF_DROP_BEYOND_MAX's reading), beside the other
            # named causes as the term is reported; built only if the workpiece is refitted with it (_workpiece's
            # determined; it leaves the evidence there)
            def _determined_cols(c=tm.columns, Q=so.Q, pen=_pen_of(others, rows)):
                M = _determined(Q, c[rows], settings.vif_max, pen, drop=True)[0]
                return c @ M if M.shape[1] else None
            ev["_determined_columns"] = _determined_cols
        if INFLATED_SIGNAL_HEDGED and tm.penalty is None and _beyond_vif_max(ev, settings):
            split = _inflated_split(so.Q, tm.columns[rows], so.r, so.dof, settings.vif_max, _pen_of(others, rows))
            if split is not None:
                p_det = min(1.0, split["p_determined"] * float(ev.get("tries", 1.0)))
                if p_det >= settings.alpha_family and split["magnitude_share_inflated"] >= INFLATED_MAGNITUDE_SHARE:
                    ev["inflated_signal"] = _clean(dict(split, p_determined_adjusted=p_det))
                    why.append(
                        f"its significance rests on {split['k_inflated']} of its directions inflated beyond vif_max = "
                        f"{settings.vif_max:g} (worst {ev.get('max_vif', float('nan')):.3g}, "
                        f"{ev.get('principal_angle_deg', float('nan')):.2g} deg to the model): its "
                        f"{split['k_determined']} determined directions alone are not significant (F = "
                        f"{split['F_determined']:.3g}, {fmt_p(p_det)} after Bonferroni over "
                        f"{float(ev.get('tries', 1.0)):.0f} tries) and the inflated ones carry "
                        f"{min(split['magnitude_share_inflated'], 1.0):.0%} of its fitted values "
                        f"({split['rms_um']:.3g} um RMS, {split['rms_determined_um']:.3g} on the determined ones): "
                        "read through a sliver of angle to the model, any effect with a small part there reads "
                        "as this cause, amplified")
        ev["confidence"] = "ambiguous" if why else "named"
        if why:
            ev["confidence_reason"] = "; ".join(why)
        ev["explained_rms_um"] = float(np.sqrt(explained / len(rows)))
        out.append(Finding(tm.cause, _clean(ev), {**_info_params(tm.info), **vals}, u95,
                           float(np.sqrt(st.rss / len(rows))) / UM, cause.books_to))
    if structure_e["present"]:
        ev = {"diagnosis": [d.to_dict() for d in diag_e if d.significant(settings.alpha_family)],
              "cv_gap": structure_e["cv_gap"], "lack_of_fit": structure_e["lack_of_fit"],
              "noise_excess": structure_e["noise_excess"],
              "partially_consistent_with": [{k: v for k, v in d.items() if k != "kept"} for d in demoted]}
        words = "; ".join(d.words for d in diag_e if d.significant(settings.alpha_family))
        if not words:
            words = _no_covariate_words(structure_e, settings)
        ev["text"] = words
        params, u95 = {}, {}
        if smooth is not None:
            ev["smooth"] = smooth.evidence
            if smooth.columns.shape[1]:
                ss = _smooth_ss(bl, terms, smooth, Qb, y, rows)
                ev["explained_ss_um2"] = ss / UM ** 2
                params = {"covariate": smooth.covariate, "explained_rms_um": float(np.sqrt(ss / len(rows))) / UM}
                u95 = {"explained_rms_um": None}
        if "explained_ss_um2" not in ev:
            top = next((d for d in diag_e if d.significant(settings.alpha_family)), None)
            ev["explained_ss_um2"] = (top.explained_rms_um ** 2 * len(rows)) if top else 0.0
        _floor_hedge(ev, structure_e)
        out.append(Finding(causes_mod.UNEXPLAINED, _clean(ev), params, u95, st.sigma / UM, "unknown"))
    return out


#: R1 (session 28's diagnosis, docs/discovery-studies.md "Session 28: the blind check's two gen_c faults, diagnosed";
#: built in session 29, lobe29): a part_change finding whose signal one target carries a share
#: :data:`PART_CHANGE_ONE_TARGET_SHARE` or more of (:func:`_one_target_share`) is named at most ambiguous. A part
#: that changes moves a wall, a ring, a boss: several targets; a change of one target has no spatial form to tell it
#: from that touch's own history (gen_c travel_hysteresis 5409: bore2's first touch after the traverse, a wound lost
#: motion's two levels in time order, read `part_change` confidently, share 0.91). Off: measured in session 29 (lobe29,
#: docs/discovery-studies.md "Session 29: the move-signed reversal must earn its move") on gen_a, gen_b, the simulator and
#: gen_c (1,150 campaigns, part_change 1000-1049 / 4000-4049 / 200-299 among them) it moves nothing right -> wrong or
#: wrong -> right and hedges three right confident readings (gen_a part_change 1039, 1045, 1049: shares 0.83-0.93, a
#: pin's wall is one target), while 5409 reads `reversal` through :data:`core.causes.REVERSAL_MOVE_SIGNED`.
PART_CHANGE_ONE_TARGET = False
#: The share of a part_change finding's signal one target must carry for :data:`PART_CHANGE_ONE_TARGET` to hedge it:
#: 0.8, above the largest share of a true change session 28 measured on gen_c (0.67); session 29 found true changes up
#: to 0.93 on gen_a (gen_b 0.39, the simulator 0.08, gen_c 200-299 0.59).
PART_CHANGE_ONE_TARGET_SHARE = 0.8


def _one_target_share(bl, tm, so: _State, rows) -> float | None:
    """The largest share of a term's fitted signal one target carries: the term's columns times their coefficients
    fitted beside the other terms ``so`` (the model reported), squared and summed over each target's touches, over
    all its touches. None where the term explains nothing."""
    E = np.asarray(tm.columns, float)[rows]
    Ep = E - so.Q @ (so.Q.T @ E)
    coef = np.linalg.lstsq(Ep, so.r, rcond=None)[0]
    s2 = (E @ coef) ** 2
    tot = float(s2.sum())
    if not tot > 0:
        return None
    tg = np.asarray(bl.data.touches.target, dtype=object)[rows]
    _, inv = np.unique(tg.astype(str), return_inverse=True)
    return float(np.bincount(inv, weights=s2).max() / tot)


def _family(bl, covariate) -> str | None:
    """The family of a covariate of the baseline's (None where it has none or there is no such covariate)."""
    cov = bl.covariate(covariate) if covariate is not None else None
    return (cov.family or None) if cov is not None else None


def _smooth_ss(bl, terms, smooth, Qb, y, rows) -> float:
    without = [t for t in terms if t is not smooth]
    return max(_state(Qb, y, rows, without).rss - _state(Qb, y, rows, terms).rss, 0.0)


def _info_params(info: dict) -> dict:
    return {k: v for k, v in info.items() if isinstance(v, str)}


def _clean(d):
    """JSON-friendly: numpy scalars to float, inf to None."""
    if isinstance(d, dict):
        return {k: _clean(v) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [_clean(v) for v in d]
    if isinstance(d, (bool, np.bool_)):
        return bool(d)
    if isinstance(d, (int, np.integer)):
        return int(d)
    if isinstance(d, (float, np.floating)):
        return float(d) if np.isfinite(d) else None
    return d


def _ordered(findings: list, material_ss_um2: float = 0.0) -> list:
    """The findings best first; the first is the report's cause.

    The systematic findings by the sum of squares they explain. The
    outliers (touches set aside, with the sum of squares of their baseline
    residuals) after them, as data set aside rather than a cause, unless
    they are the campaign's story: they carry a material sum of squares
    (``material_ss_um2``: the materiality over the campaign's rows), beside
    them only structure left unnamed (``unexplained``), which explains less
    than they carry (a held-out gap, 0.1 um following one covariate, beside
    75 um^2 of chips), and what
    remains after them within a probe's noise (an ``unexplained`` noise
    excess says the scatter left is itself no probe's: the outliers are not
    the whole story). A named cause, flagged or not, keeps the lead here:
    outliers beside it may be its own largest residuals (a local scale
    defect's, whose bump the cause's form follows only in part); only
    outliers that follow the turn and carry more than the named causes
    explain hand its lead to ``unexplained``
    (:data:`NAMED_BESIDE_TURNED_OUTLIERS_UNEXPLAINED`).

    Outliers that lead beside structure left unnamed are not confidently
    dust (flagged ``ambiguous`` here, in place): the outlier test judges
    each touch against a model it takes as right but for the outliers,
    and the ``unexplained`` finding beside them says it is not. The largest
    residuals of a misfit sit where the misfit peaks, so the test cannot
    tell dust from that misfit's tails (the place version is
    :func:`_place_carries`; this is its covariate version, over the whole
    campaign). Session 16 (docs/discovery.md, "Session 16: confident
    misnamings"): gen_a knock 1085 (a knock's step read as five outliers of
    one set-up beside structure in time) and reseat_hysteresis 1036 (the
    re-seats' two minority readings beside a lack of fit against the
    repeats), both `outlier` confident before.
    """
    def ss(f):
        return f.evidence.get("explained_ss_um2") or 0.0

    out = sorted(findings, key=lambda f: (f.cause == causes_mod.OUTLIER, -ss(f)))
    dust = [f for f in out if f.cause == causes_mod.OUTLIER]
    rest = [f for f in out if f.cause != causes_mod.OUTLIER]
    if dust and rest and all(f.cause == causes_mod.UNEXPLAINED and not f.evidence.get("noise_excess")
                             for f in rest):
        d = dust[0]
        if ss(d) > max(sum(max(ss(f), 0.0) for f in rest), material_ss_um2):
            d.evidence["leads"] = ("the outliers carry more sum of squares than the structure left unnamed "
                                   f"({ss(d):.3g} against {sum(max(ss(f), 0.0) for f in rest):.3g} um^2)")
            if d.evidence.get("confidence") == "named":
                d.evidence["confidence"] = "ambiguous"
                d.evidence["confidence_reason"] = (
                    "beside them the residuals keep structure the model does not name (" +
                    "; ".join(f.evidence.get("text") or "unexplained" for f in rest) +
                    "): the outliers were judged against a model that is not right but for them, and may be "
                    "that structure's largest residuals, not dust")
            out = [d] + rest
    return out


#: Outliers beside a local scale defect that the design cannot tell from smooth axis errors (its finding's
#: ``indistinguishable_counter``: a smooth error map explains as much and the bump nothing material beyond it) lead
#: the report (:func:`_outliers_lead_beside_smooth_defect`) when they carry more than every finding beside them and
#: the bump cuts none of their residuals (:func:`_explained_outliers`: they are not its largest residuals); they
#: lead as :func:`_ordered` lets them lead beside unnamed structure, ambiguous. Session 29 (out29): gen_c outlier
#: 5400 (three chips, 312 um^2, named, beside a 0.48 um bump 36 mm wide explaining 1.3 um^2 that a smooth error map
#: explains as well) read `local_scale_defect?`; on tuning gen_a outlier 1098, gen_c 205 and 245
#: `local_scale_defect?` -> `outlier?`, nothing else moved (gen_a/gen_b outlier and local_scale_defect 1000-1099, the
#: simulator's 4000-4049, gen_c 200-299; on every effect and none it can reach only those outlier campaigns, the only
#: ones whose first finding is a bump beside outliers). False: a named cause keeps the lead (the behaviour before).
OUTLIERS_LEAD_BESIDE_SMOOTH_DEFECT = True


def _outliers_lead_beside_smooth_defect(findings: list, material_ss_um2: float, explains_outliers) -> list:
    """The ordered findings with the outliers first where beside them is only a bump the design cannot tell from
    smooth axis errors, or structure left unnamed (:data:`OUTLIERS_LEAD_BESIDE_SMOOTH_DEFECT`).

    ``explains_outliers(cause)``: whether that cause's term cuts any set-aside touch's residual by
    :data:`EXPLAINED_CUT` (then the outliers may be its own largest residuals and the cause keeps the lead).
    """
    dust = [f for f in findings if f.cause == causes_mod.OUTLIER]
    rest = [f for f in findings if f.cause != causes_mod.OUTLIER]
    if not dust or not rest or findings[0].cause == causes_mod.OUTLIER:
        return findings
    def ss(f):
        return f.evidence.get("explained_ss_um2") or 0.0
    smooth_like = [f for f in rest if f.cause == "local_scale_defect" and f.evidence.get("indistinguishable_counter")]
    if not smooth_like or not all(f in smooth_like or (f.cause == causes_mod.UNEXPLAINED
                                                       and not f.evidence.get("noise_excess")) for f in rest):
        return findings
    d = dust[0]
    carried = sum(max(ss(f), 0.0) for f in rest)
    if not ss(d) > max(carried, material_ss_um2) or explains_outliers("local_scale_defect"):
        return findings
    d.evidence["leads"] = (f"the outliers carry more sum of squares than a bump the design cannot tell from smooth "
                           f"axis errors, which cuts none of them ({ss(d):.3g} against {carried:.3g} um^2)")
    if d.evidence.get("confidence") == "named":
        d.evidence["confidence"] = "ambiguous"
        d.evidence["confidence_reason"] = (
            "beside them the residuals keep structure whose name the design cannot hold (a bump that a smooth error "
            "map explains as well): the outliers were judged against a model that is not right but for them, and "
            "may be that structure's largest residuals, not dust")
    return [d] + rest


#: Outliers named with confidence whose every touch lies under a local scale defect's bump that the search refused
#: by the all-touch support count alone (:func:`_support`: every other test of adoption passed, the one-place test
#: :func:`_beyond_one_place` included, which refutes a bump carried by one place) are made ambiguous with
#: ``local_scale_defect`` (:func:`_doubt_outliers_under_refused_bump`). A damaged scale moves every touch whose axis
#: position lies under the bump; its largest touches, beyond the outlier bound, are set aside as outliers, and the
#: support count over the rest may then find one position carrying half of what the bump explains. Chips do not line
#: up on one machine-axis coordinate across targets and set-ups. Session 30 (out30): blind gen_b local_scale_defect
#: 8306 (the bump's three largest touches, three targets in two set-ups within 2.6 mm in y, `outlier` confident; the
#: bump refused at 1.986 effective positions against :data:`MIN_SUPPORT` 2.0). False: the behaviour before.
OUTLIERS_UNDER_SUPPORT_REFUSED_BUMP = True


#: Outliers named with confidence whose largest residual (the baseline's, every row in, as the finding reports it) is
#: under this many times the noise are made ambiguous (:func:`_doubt_outliers_not_gross`; with
#: :data:`OUTLIERS_NOT_GROSS_HEDGED`). The noise is the final model's residual scatter on the touches kept (its
#: ``rms_um``, ``st.sigma``: tens to hundreds of degrees of freedom), not the repeats' (16 degrees of freedom at
#: 0.204 um for a true 0.346 um on blind gen_b signal_latency 8105; drawn high they hedge real chips: gen_a outlier
#: 1456 and 1387 at 4.6 and 4.9 times the repeats', 7.0 and 6.6 times the fit's). Session 30 (out30), measured on the
#: tuning seeds before it was set: the smallest largest-residual of a confident leading outlier finding is 5.3 times
#: that noise on gen_a outlier 1000-1499 (1415; 6.0 the next, of 317), 14.0 on gen_b 1000-1099, 14.4 on gen_c
#: 200-399, and the simulator's 4000-4099 name none confidently (7.5 the smallest of any); 8105's two "outliers"
#: reach 3.24. 4 is about the geometric middle of 3.24 and 5.3 (margins 1.23 and 1.33: thin, said so).
OUTLIER_GROSS_SIGMAS = 4.0
#: Whether :data:`OUTLIER_GROSS_SIGMAS` is applied. False: the behaviour before.
OUTLIERS_NOT_GROSS_HEDGED = True


def _doubt_outliers_not_gross(findings: list, sigma_um: float) -> None:
    """The confident outlier finding made ambiguous, in place, where its largest residual is under
    :data:`OUTLIER_GROSS_SIGMAS` times ``sigma_um`` (the noise, um): no gross error, and a smooth effect's misfit plus
    a draw of about a sigma reaches the outlier bound on a design of few residual degrees of freedom
    (:data:`OUTLIERS_NOT_GROSS_HEDGED`)."""
    fo = next((f for f in findings if f.cause == causes_mod.OUTLIER), None)
    if fo is None or fo.evidence.get("confidence") != "named" or not sigma_um > 0:
        return
    top = max(abs(v) for v in fo.evidence["residual_um"])
    if top >= OUTLIER_GROSS_SIGMAS * sigma_um:
        return
    fo.evidence["confidence"] = "ambiguous"
    fo.evidence["confidence_reason"] = (
        f"not gross: the largest outlier's residual is {top:.3g} um, {top / sigma_um:.2g} times the noise "
        f"({sigma_um:.3g} um), under {OUTLIER_GROSS_SIGMAS:g}: a smooth effect's misfit plus a draw of about a sigma "
        "reaches the outlier bound as well as dust does")


def _doubt_outliers_under_refused_bump(findings: list, outliers: np.ndarray, refused_bumps: list) -> None:
    """The confident outlier finding made ambiguous with ``local_scale_defect``, in place, where every outlier row
    lies where one of ``refused_bumps`` (the search's bumps refused by the all-touch support count alone: ``info``,
    ``support_units``, ``reach`` the rows its column moves) reaches (:data:`OUTLIERS_UNDER_SUPPORT_REFUSED_BUMP`)."""
    fo = next((f for f in findings if f.cause == causes_mod.OUTLIER), None)
    # (a finding hedged by :data:`OUTLIER_STRONG_EVENTS` alone is still offered the bump: the more specific reading)
    weak = (fo.evidence.get("strong_events") or {}).get("strong_events", 2) < 2 if fo is not None else False
    if fo is None or (fo.evidence.get("confidence") != "named" and not weak):
        return
    under = [b for b in refused_bumps if np.all(np.isin(outliers, b["reach"]))]
    if not under:
        return
    b = under[-1]  # (the latest search's)
    i = b["info"]
    before = fo.evidence.get("confidence_reason") if fo.evidence.get("confidence") == "ambiguous" else None
    fo.evidence["confidence"] = "ambiguous"
    fo.evidence["ambiguous_with"] = sorted(set(fo.evidence.get("ambiguous_with", [])) | {"local_scale_defect"})
    fo.evidence["confidence_reason"] = ("" if not before else before + "; ") + (
        f"every outlier lies under a local scale defect's bump ({i['axis']} at {i['centre_m'] * 1e3:.4g} mm, "
        f"half-width {i['half_width_m'] * 1e3:.3g} mm) that passed every test of adoption but the support count "
        f"({_positions_text(b['support_units'])} effective positions, at least {MIN_SUPPORT:g}): they may be that "
        "bump's largest touches (a damaged scale moves every touch under it, in every set-up), not dust")


def _doubt_beside_turned_outliers(findings: list, settings) -> None:
    """Named causes beside an outlier finding whose residuals follow the centred turn made ambiguous, in place.

    The outliers then read as the minority readings of a mechanism of the
    move that the targets' parameters half absorb (:func:`centred_turn_p`
    below ``alpha_family``), out of the catalogue: its majority readings
    are in the fit, and a catalogue cause named beside it may be taking
    their share (gen_a reseat_hysteresis 1047 `stylus_bending`, 1060
    `c_drift`: confident, wrong, their outlier findings' centred turn p
    8e-5 and 0.0023). Measured on gen_a and gen_b 1000-1099, every
    effect (3,700 campaigns, 1,093 with a confident named cause first): 22
    have a tested outlier finding beside it, 2 fire, those two
    (docs/discovery.md).
    """
    turned = [f for f in findings if f.cause == causes_mod.OUTLIER
              and f.evidence.get("centred_turn_p", 1.0) < settings.alpha_family]
    if not turned:
        return
    p = turned[0].evidence["centred_turn_p"]
    for f in findings:
        if f.cause in (causes_mod.OUTLIER, causes_mod.UNEXPLAINED) or f.evidence.get("confidence") != "named":
            continue
        f.evidence["confidence"] = "ambiguous"
        f.evidence["confidence_reason"] = (
            f"beside it the outliers follow the turn of the approach relative to their targets' other touches "
            f"(centred turn {fmt_p(p)}): a mechanism of the move out of the catalogue, whose other readings are in "
            "the fit, may carry what this cause explains")


#: Outliers that would lead the report (beside no named cause) whose own centred-turn test says they follow the turn
#: of the approach relative to their targets' other touches (:func:`centred_turn_p` below ``alpha_family``) hand the
#: lead to ``unexplained`` (:func:`_turned_outliers_unexplained`): a chip sits under the touch it corrupts whatever
#: move brought the probe there, a mechanism of the move (a probe seat that settles differently after a turn) acts on
#: every touch the move reaches and leaves its minority readings as outliers (gen_a reseat_hysteresis: 16 of the 23
#: `outlier?` misses of 1000-1299, session 24). False: the outliers lead (sessions 16-23).
OUTLIERS_TURNED_UNEXPLAINED = True
#: With :data:`OUTLIERS_TURNED_UNEXPLAINED`: outliers that would lead beside an ``unexplained`` finding whose strongest
#: covariate is the turn of the approach from the previous touch's (:data:`TURN_COVARIATE`, the diagnosis of the
#: touches kept) hand it the lead whatever their own centred turn: the structure the kept touches carry is then a
#: mechanism of the move, which no chip makes (a chip corrupts the touch it sits under, set aside with it), and the
#: outliers lead it only by their sum of squares (gen_a reseat_hysteresis 1036, 1154, 1192, 1193, session 24).
OUTLIERS_BESIDE_TURN_UNEXPLAINED = True
#: The history covariate of the turn of the approach from the previous touch's (:func:`core.baseline.touch_history`).
TURN_COVARIATE = "turn_from_previous"


def _turned_outliers_unexplained(findings: list, settings, sigma_um: float) -> list:
    """The findings with ``unexplained`` ahead of outliers that follow the turn of the approach (when they lead).

    Applies only where the outlier finding leads the ordered findings
    (:func:`_ordered`: beside it no named cause, only structure left unnamed
    that explains less than the outliers carry, or nothing) and its own
    centred-turn test fired (``centred_turn_p`` below ``alpha_family``, the
    level that already makes the finding ``ambiguous``). The outliers'
    residuals then read short where their touch turned more than its
    target's other touches and long where it turned less: the minority
    readings of a mechanism of the move that each target's parameter half
    absorbs, which is out of the catalogue (no cause depends on the previous
    touch's approach). Dust has no memory of the move: a chip's reading does
    not depend on the turn that brought the probe to it. The report then
    reads ``unexplained``: an ``unexplained`` finding beside the outliers
    leads (its diagnosis of the touches kept says where the rest of the
    structure lives, its text adds the outliers' turn, and the outliers lose
    ``leads``); where there is none
    (the majority readings sit inside the noise once each target's parameter
    took their mean), one is made from the outlier finding's own test, its
    text saying where the mechanism lives (the turn of the approach, the
    outliers as its minority readings) and its ``explained_ss_um2`` the
    outliers' sum of squares (``of``: ``outliers``; the outlier finding keeps
    them as touches set aside). The outliers stay a finding, second, with
    their confidence and reasons unchanged. A named cause beside turned
    outliers keeps the lead here (:func:`_doubt_beside_turned_outliers` makes
    it ambiguous; :func:`_named_beside_turned_outliers_unexplained` hands
    the lead on where the outliers carry more than it explains). With :data:`OUTLIERS_BESIDE_TURN_UNEXPLAINED`, outliers whose
    own centred turn did not fire hand the lead as well to an ``unexplained``
    finding beside them whose strongest covariate is the turn of the approach
    from the previous touch's (its diagnosis of the touches kept): the
    structure the kept touches carry is a mechanism of the move, which no
    chip makes, and the outliers led it by their sum of squares alone.
    """
    if not findings or findings[0].cause != causes_mod.OUTLIER:
        return findings
    fo = findings[0]
    rest = findings[1:]
    if any(f.cause not in (causes_mod.OUTLIER, causes_mod.UNEXPLAINED) for f in rest):
        return findings
    un = [f for f in rest if f.cause == causes_mod.UNEXPLAINED]
    p = fo.evidence.get("centred_turn_p")

    def turn_first(f) -> bool:  # the unnamed structure's strongest covariate is the turn
        return (f.evidence.get("diagnosis") or [{}])[0].get("covariate") == TURN_COVARIATE

    if p is not None and p < settings.alpha_family:
        why = _turned_why(p, settings)
        fo.evidence["turned_lead"] = why
        if un:
            _add_text(un[0], why)
    elif OUTLIERS_BESIDE_TURN_UNEXPLAINED and any(turn_first(f) for f in un):
        un.sort(key=lambda f: not turn_first(f))  # (its figures are in its own text)
        fo.evidence["turned_lead"] = (
            "the structure left in the touches kept follows the turn of the approach from the previous touch's "
            "first: a mechanism of the move out of the catalogue, whose largest readings the outliers may be")
    else:
        return findings
    if un:
        fo.evidence.pop("leads", None)
        return un + [fo] + [f for f in rest if f.cause != causes_mod.UNEXPLAINED]
    return [_unexplained_of_outliers(why, fo.evidence.get("explained_ss_um2") or 0.0, p, sigma_um)] + findings


def _turned_why(p: float, settings, extra: str = "") -> str:
    """What an ``unexplained`` finding led by turned outliers says (``extra``: a clause after the test's figures)."""
    return (f"the touches set aside as outliers read short or long as their touch's turn of the approach differs "
            f"from its target's other touches (centred turn {fmt_p(p)}, below {settings.alpha_family:g}){extra}: a "
            "mechanism of the move out of the catalogue (a probe seat that settles differently after a turn), whose "
            "majority readings each target's parameter took; the outliers are its minority readings, not dust")


def _add_text(f: Finding, why: str) -> None:
    """``why`` appended to a finding's text, in place."""
    f.evidence["text"] = "; ".join(w for w in (f.evidence.get("text"), why) if w)


def _unexplained_of_outliers(why: str, carried: float, p: float, sigma_um: float) -> Finding:
    """An ``unexplained`` finding made from turned outliers' own test (``of``: ``outliers``, their sum of squares)."""
    return Finding(causes_mod.UNEXPLAINED, _clean({
        "text": why, "diagnosis": [], "cv_gap": False, "lack_of_fit": False, "noise_excess": False,
        "explained_ss_um2": carried, "of": "outliers", "centred_turn_p": p}), {}, {}, sigma_um, "unknown")


#: Named causes that lead beside outliers whose own centred-turn test fired (:func:`centred_turn_p` below
#: ``alpha_family``) and that together explain less than those outliers carry (their baseline sum of squares) hand
#: the lead to ``unexplained`` (:func:`_named_beside_turned_outliers_unexplained`): the outliers are then the
#: minority readings of a mechanism of the move out of the catalogue (a re-seat), whose majority readings are in the
#: fit, and the named cause a small share of them (:func:`_doubt_beside_turned_outliers` already makes it
#: ambiguous); the report reads the larger structure. gen_a reseat_hysteresis 6300 (blind check of session 24,
#: `stylus_bending?` explaining 1.73 um^2 beside 13 turned outliers carrying 154 um^2, centred turn p = 1e-5),
#: session 25. Measured (docs/discovery.md, "Session 25"): gen_a reseat_hysteresis 1047, 1146, 1279 `stylus_bending?`,
#: `local_scale_defect?` -> `unexplained` on the tuning seeds, nothing else moved on gen_a/gen_b every effect
#: 1000-1099, reseat and none 1100-1299, the simulator's none, outlier and lobing sets. False: the named cause keeps
#: the lead, ambiguous (sessions 16-24).
NAMED_BESIDE_TURNED_OUTLIERS_UNEXPLAINED = True


def _named_beside_turned_outliers_unexplained(findings: list, settings, sigma_um: float) -> list:
    """The findings with ``unexplained`` ahead of named causes smaller than turned outliers beside them.

    Applies where a named cause leads (:func:`_ordered` keeps a named cause
    first whatever the outliers carry: they may be its own largest
    residuals), an outlier finding beside it has its centred-turn test fired
    (``centred_turn_p`` below ``alpha_family``: its residuals read short or
    long as their touch's turn of the approach differs from its target's
    other touches, which no chip and no catalogue cause does: no cause
    depends on the previous touch's approach), and the named causes
    together explain less than the outliers carry (``explained_ss_um2``,
    the comparison of :func:`_doubt_beside_gathered_outliers`). A cause's
    own largest residuals would not follow the turn; a cause smaller than
    the turned outliers beside it cannot be the campaign's story. An
    ``unexplained`` finding already in the list moves first (the outliers'
    turn added to its text), else one is made from the outlier finding's
    test as :func:`_turned_outliers_unexplained` makes it (``of``:
    ``outliers``); the named causes follow, ambiguous as
    :func:`_doubt_beside_turned_outliers` left them, then the rest.
    """
    if not findings or findings[0].cause in (causes_mod.OUTLIER, causes_mod.UNEXPLAINED):
        return findings
    turned = [f for f in findings if f.cause == causes_mod.OUTLIER
              and f.evidence.get("centred_turn_p", 1.0) < settings.alpha_family]
    if not turned:
        return findings
    fo = turned[0]
    carried = fo.evidence.get("explained_ss_um2") or 0.0
    named = [f for f in findings if f.cause not in (causes_mod.OUTLIER, causes_mod.UNEXPLAINED)]
    named_ss = sum(max(f.evidence.get("explained_ss_um2") or 0.0, 0.0) for f in named)
    if not named_ss < carried:
        return findings
    p = fo.evidence["centred_turn_p"]
    why = _turned_why(p, settings, f" and carry {carried:.3g} um^2, more than the named causes beside them explain "
                                   f"({named_ss:.3g} um^2)")
    fo.evidence["turned_lead"] = why
    un = [f for f in findings if f.cause == causes_mod.UNEXPLAINED]
    if un:
        _add_text(un[0], why)
        return [un[0]] + [f for f in findings if f is not un[0]]
    return [_unexplained_of_outliers(why, carried, p, sigma_um)] + findings


def _doubt_beside_noise_excess(findings: list) -> None:
    """Named causes beside an ``unexplained`` noise excess made ambiguous, in place.

    A noise excess (the model's noise above any touch-trigger probe's,
    :attr:`Settings.noise_max_um`) is itself a mechanism the model does not
    hold, and the noise it leaves is the floor every confidence check of a
    named cause was judged with: the rival's and the slip's shares are
    debiased by ``k sigma^2`` and materialities are ``0.3 sigma``, so an
    inflated sigma leaves those checks blind (docs/discovery.md, gen_a
    reseat_hysteresis 1609: the rival debiased to 0 um^2 with the repeats'
    1.52 um). A cause they pass is then not confidently named where the
    rival check read nothing (its rival debiased to 0 um^2): where the
    rival still explains something the comparison was made with that noise
    in it and the cause won it (gen_a probe_lobing 1933, right, its rival
    73 um^2 against the cause's 167, stays named). Session 16
    (docs/discovery.md, "Session 16: confident misnamings"): gen_a
    reseat_hysteresis 1130, `c_drift` confident beside a 3.0 um scatter of
    the repeats, its rival (time within the set-up) debiased to 0 um^2.
    """
    if not any(f.cause == causes_mod.UNEXPLAINED and f.evidence.get("noise_excess") for f in findings):
        return
    for f in findings:
        if f.cause in (causes_mod.OUTLIER, causes_mod.UNEXPLAINED) or f.evidence.get("confidence") != "named":
            continue
        if f.evidence.get("rival") is None or (f.evidence.get("rival_explained_ss_um2") or 0.0) > 0.0:
            continue
        f.evidence["confidence"] = "ambiguous"
        f.evidence["confidence_reason"] = (
            "beside it the scatter left is above any touch-trigger probe's noise (an unexplained noise "
            f"excess): its rival ({f.evidence['rival']}) was debiased with that noise to nothing, so the "
            "check that would have seen a plainer explanation was blind")


#: On the volumetric (MFB) baseline the outlier finding counts the placements of the bar its outliers fall in
#: (:func:`_volumetric_hedges`, ``placements`` in its evidence): outliers all in one placement are one event, which
#: cannot tell dust from the bar moving in its fixture between that placement's measurements, so the finding is
#: ``ambiguous`` (the moved bar named where the placement was measured more than once). Only ever a hedge: the
#: concentration test keeps its events (every row its own), since counted per placement its fewer events passed
#: outliers it had found gathered (the simulator's `none` 4008: `outlier` ambiguous -> named). None: not counted
#: (the behaviour before). The screen that removes them is unchanged. Session 31 (review31c F1, docs/discovery-studies.md
#: "Session 31: MFB discovery that does not confidently misname a moved or warmed bar"): a bar turned 1 um at its
#: ends in its fixture after a placement's first measurement read `outlier` confidently on 14 of 20 campaigns.
VOLUMETRIC_OUTLIER_EVENTS = "placement"

#: On the volumetric baseline a confidently named finding (a catalogue cause or the outliers) beside a covariate the
#: extended model leaves significant (p below ``alpha_family``) though below materiality is made ``ambiguous``
#: (:func:`_volumetric_hedges`): the structure left is a mechanism the name does not hold, and the noise that
#: judged it immaterial is the residuals', which that mechanism inflates. False: the behaviour before. Session 31
#: (review31c F2, F3): a temperature gradient along the bar read `outlier` named beside ``along_bar`` at p = 2.9e-6
#: (0.083 um against a materiality of 0.080 debiased); a bar that slipped 1.5 um read `thermal_drift` named beside
#: ``time`` and ``stylus`` at p = 9e-7 (0.198 um against 0.201).
VOLUMETRIC_HEDGE_SIGNIFICANT_LEFT = True
#: With :data:`VOLUMETRIC_HEDGE_SIGNIFICANT_LEFT`, a named catalogue cause is hedged only where it explains less than
#: this share of what a plain smooth of its own covariate explains (its ``rival_share``: the smooth holds a
#: mechanism beyond the cause's form); the outliers always. None: every named cause. Session 31: review31c's slipped
#: bar read `thermal_drift` at a share of 0.61 (time left at p = 9e-7); the right names the rule hedged without it
#: (review31c's grid: 8 of 218, shares 0.81-1.00) keep their confidence.
VOLUMETRIC_HEDGE_LEFT_RIVAL_SHARE = 0.75

#: On the volumetric baseline the outlier finding asks whether the measurements its outliers fall in carry structure
#: in their other rows (:func:`_measurement_carries`): dust in a hole moves that hole's point and nothing else, while
#: a bar that deforms or moves within a measurement (a temperature gradient along it, a turn in its fixture) moves
#: every point of that measurement, and the outliers are then only its largest residuals. Per measurement holding an
#: outlier, its other rows (every outlier set aside) are tested for a line and a parabola along the bar in each W
#: component (six columns, less what the model already spans) against the extended model, nested F, Bonferroni over
#: the measurements tested at ``alpha_family``, and material (debiased, ``material_sigma`` noise sigmas per row of
#: that measurement): where one does, a named outlier finding is ``ambiguous`` (``measurement_structure`` in its
#: evidence). The planar analogue is the place test (:func:`_place_carries`). Only a hedge: no cause changes, and the
#: named causes beside it are not touched (the key is not ``place_structure``). False: not asked (the behaviour
#: before). Session 32 (mfbre32, docs/discovery-studies.md "Session 32: MFB discovery re-measured with session 31's two
#: changes together"): review31c's realistic bar with a 3 um temperature gradient along it (seed 315) read `outlier`
#: named, its two outliers the ends of two standing bars' gradients along z, whose measurements' other rows carried
#: the same parabola.
VOLUMETRIC_OUTLIER_MEASUREMENT_STRUCTURE = True


def _measurement_carries(bl, st, outliers, alpha: float, material_sigma: float) -> dict | None:
    """The measurement holding outliers whose other rows carry structure along the bar, if any (volumetric only).

    ``st`` the model the outliers were set aside from (its orthonormal basis on its rows ``st.rows``, their
    residuals ``st.r``). For each measurement holding an outlier: the columns ``P_1(s)``, ``P_2(s)`` (``s`` the
    row's position along the bar over the holes that measurement probed, -1..1) on that measurement's rows of each
    W component (six columns, whitened as the rows are), the part outside the model's span, nested F test on the
    kept rows, Bonferroni over the measurements tested at ``alpha``, material as :func:`_place_carries` asks
    (debiased explained sum of squares at least ``material_sigma ** 2`` noise variances per kept row of that
    measurement). Under dust in holes the other rows are the model's residuals like any: the test keeps its level
    whichever measurement the dust picked. Returns ``{measurement, F, p_adjusted, k, explained_ss_um2}`` of the
    first such measurement, or None.
    """
    d = bl.data
    meas = np.asarray(d.meas)
    kept = np.asarray(st.rows, int)
    out = np.asarray(outliers, int)
    tested = list(dict.fromkeys(meas[out].tolist()))
    dof = len(kept) - st.Q.shape[1]
    s = np.asarray(d.s, float)
    comp = np.asarray(d.comp)
    for m in tested:
        on = meas == m
        C = np.column_stack([(on & (comp == c)) * P for c in range(3) for P in (s, (3 * s ** 2 - 1) / 2)])
        W = new_basis(st.Q, _white(bl, C)[kept])
        k = W.shape[1]
        if k == 0 or dof - k < 3:
            continue
        ss = float(np.sum((W.T @ st.r) ** 2))
        s2 = (float(st.r @ st.r) - ss) / (dof - k)
        F = (ss / k) / max(s2, 1e-300)
        p = float(stats.f.sf(F, k, dof - k)) * len(tested)
        if p < alpha and ss - k * s2 >= material_sigma ** 2 * s2 * int(np.sum(on[kept])):
            return {"measurement": str(d.meas_names[m]), "F": F, "p_adjusted": min(p, 1.0), "k": int(k),
                    "explained_ss_um2": (ss - k * s2) / UM ** 2}
    return None


#: On the volumetric baseline a named ``bar_bending`` is ``ambiguous`` where the points also move ALONG the bar, unevenly
#: and differently in each measurement (:func:`_along_bar_carries`): a parabola of the position along the bar, one
#: per measurement, along the bar's axis (the bar's own x_A in W), significant beside the extended model at
#: ``alpha_family`` and material (debiased, ``material_sigma`` noise sigmas per row). Gravity bends a bar across its
#: axis and moves no point along it; a temperature gradient along the bar, which changes from measurement to
#: measurement, expands it unevenly along its axis, and its part outside the baseline can look like a sag (review31c's
#: bar_gradient read `bar_bending` named once bend31's columns took the sag about the bar's middle). Only a hedge: no
#: cause changes. False: not asked. Session 32 (mfbre32, docs/discovery-studies.md "Session 32: MFB discovery re-measured
#: with session 31's two changes together"): review31c's bar_gradient 1.5 um (bar as calibrated, seed 349) and 3 um
#: (realistic bar, seed 311) named `bar_bending` (3.9 and 8.1 um) at rival shares 0.82 and 0.81 (the session-31
#: hedge's cut 0.75), the along-bar parabolas F 68 and 29 beside them; right sags F 0.5-2.2.
VOLUMETRIC_BENDING_ALONG_BAR_RIVAL = True


def _along_bar_carries(bl, st, alpha: float, material_sigma: float) -> dict | None:
    """Whether the points move along their bar, unevenly and per measurement, beside the model ``st``.

    Columns: for each measurement, ``P_2(s)`` (``s`` the position along the bar over the holes it probed, -1..1)
    times the row's component of the bar's axis (``VolumetricData.x_bar``), whitened as the rows are; their part
    outside the model's span on its rows ``st.rows``; nested F test at ``alpha``; material where the debiased
    explained sum of squares is at least ``material_sigma ** 2`` noise variances per row. Returns ``{F, p_value, k,
    explained_ss_um2}`` where both hold, else None (also where the baseline has no bar axis per row).
    """
    d = bl.data
    if getattr(d, "x_bar", None) is None:
        return None
    kept = np.asarray(st.rows, int)
    meas = np.asarray(d.meas)
    P2 = (3 * np.asarray(d.s, float) ** 2 - 1) / 2 * np.asarray(d.x_bar, float)
    C = np.column_stack([(meas == m) * P2 for m in np.unique(meas)])
    W = new_basis(st.Q, _white(bl, C)[kept])
    k = W.shape[1]
    dof = len(kept) - st.Q.shape[1]
    if k == 0 or dof - k < 3:
        return None
    ss = float(np.sum((W.T @ st.r) ** 2))
    s2 = (float(st.r @ st.r) - ss) / (dof - k)
    F = (ss / k) / max(s2, 1e-300)
    p = float(stats.f.sf(F, k, dof - k))
    if p < alpha and ss - k * s2 >= material_sigma ** 2 * s2 * len(kept):
        return {"F": F, "p_value": p, "k": int(k), "explained_ss_um2": (ss - k * s2) / UM ** 2}
    return None


#: On the volumetric baseline a ``lobing_per_stylus`` or ``thermal_drift`` finding on a plan with a placement measured
#: more than once names those measurements (``moved_bar``), and an ambiguous one says in its reason that a bar moved
#: in its fixture between them is its rival: a moved bar shifts a placement's later measurements alike, as a stylus
#: used only there (VYb, VYc, VXb on the 3-axis plan) or a drift in time would (:func:`_volumetric_hedges`). Words
#: only. False: not said. Session 31 (review31c F5).
VOLUMETRIC_MOVED_BAR_RIVAL = True


#: On the volumetric baseline a report that would read ``none`` while a catalogue cause was refused as implausible
#: though significant (a bar "sagging" upward: :data:`core.causes.BAR_SAG_GRAVITY_SIGN`) reads ``unexplained``
#: (:func:`_volumetric_implausible_unexplained`): the structure that cause fitted is there, only no catalogue
#: cause's physics holds it. False: ``none`` (the refusal in ``rejected`` only). Session 31 (review31c F2).
VOLUMETRIC_IMPLAUSIBLE_UNEXPLAINED = True


def _volumetric_implausible_unexplained(rejected: list, structure_e: dict, st) -> Finding | None:
    """An ``unexplained`` finding for a report left with no finding whose catalogue cause was refused as
    implausible though significant (``rejected``' reasons starting "implausible"), or None where none was."""
    refused = [r for r in rejected if str(r.get("reason", "")).startswith("implausible")]
    if not refused:
        return None
    left = [w for w in (structure_e.get("not_counted") or ()) if w.get("p_value", 1.0) < w.get("alpha_family", 0.0)]
    text = ("a catalogue cause fits structure here significantly, with a magnitude its physics does not allow ("
            + "; ".join(f"{r['cause']}: {r['reason']}" for r in refused) + ")"
            + ("" if not left else "; left in " + ", ".join(
                f"{w['covariate']} ({fmt_p(w['p_value'])}, {w['explained_rms_um']:.3g} um)" for w in left)))
    return Finding(causes_mod.UNEXPLAINED, _clean({
        "text": text, "refused_implausible": [dict(r) for r in refused], "diagnosis": [dict(w) for w in left],
        "cv_gap": False, "lack_of_fit": False, "noise_excess": False,
        "explained_ss_um2": float(sum(w["explained_rms_um"] ** 2 for w in left[:1]) * st.dof)}),
        {}, {}, st.sigma / UM, "unknown")


def _moved_bar_words(bl, rows) -> str | None:
    """Words naming the measurements of placements measured more than once among ``rows`` (baseline rows), or None
    where none is: where a bar that moved in its fixture between that placement's measurements would read."""
    d = bl.data
    pl = np.asarray(d.placement)[np.asarray(rows, int)]
    multi = [p for p in np.unique(pl) if np.unique(np.asarray(d.meas)[np.asarray(d.placement) == p]).size >= 2]
    if not multi:
        return None
    parts = []
    for p in multi:
        ms = np.unique(np.asarray(d.meas)[np.asarray(d.placement) == p])
        parts.append(f"{d.placements[p]} ({', '.join(d.meas_names[m] for m in ms)})")
    return "; ".join(parts)


def _volumetric_hedges(bl, findings: list, structure_e: dict, st=None, settings=None) -> None:
    """The volumetric baseline's hedges of named findings, in place (session 31, review31c F1-F3, F5).

    - outliers all in one placement (:data:`VOLUMETRIC_OUTLIER_EVENTS`): ``ambiguous``; where that placement was
      measured more than once the reason names the bar moved in its fixture between its measurements as their
      rival (``moved_bar``);
    - a named finding beside a covariate left significant though below materiality
      (:data:`VOLUMETRIC_HEDGE_SIGNIFICANT_LEFT`): ``ambiguous``, the covariates in the reason;
    - a ``lobing_per_stylus`` or ``thermal_drift`` (:data:`VOLUMETRIC_MOVED_BAR_RIVAL`) where the plan has a
      placement measured more than once: ``moved_bar`` names those measurements, and an ambiguous finding's reason
      names the bar moved between them as its rival;
    - a ``bar_bending`` beside points that move along their bar per measurement
      (:data:`VOLUMETRIC_BENDING_ALONG_BAR_RIVAL`, with ``st`` the extended model's state and ``settings``):
      ``ambiguous``, an uneven expansion along the bar its rival.
    """
    left = [w for w in (structure_e.get("not_counted") or ()) if w.get("reason") == "below_materiality"]
    for f in findings:
        ev = f.evidence
        if (VOLUMETRIC_BENDING_ALONG_BAR_RIVAL and f.cause == "bar_bending" and st is not None
                and settings is not None and ev.get("confidence") == "named"):
            along = _along_bar_carries(bl, st, settings.alpha_family, settings.material_sigma)
            if along is not None:
                ev["along_bar_structure"] = _clean(along)
                ev["confidence"] = "ambiguous"
                ev["confidence_reason"] = (
                    f"the points also move along their bar, unevenly and differently in each measurement (a parabola "
                    f"per measurement along the bar's axis, F = {along['F']:.3g}, {fmt_p(along['p_value'])}, "
                    f"{along['explained_ss_um2']:.3g} um^2): gravity bends a bar across it, so an uneven expansion "
                    "along the bar (a temperature gradient along it) may be what this sag fits (out of the catalogue)")
        at = np.searchsorted(bl.rows, ev.get("rows") or [])
        if f.cause == causes_mod.OUTLIER and VOLUMETRIC_OUTLIER_EVENTS == "placement" and len(at):
            ev["placements"] = int(np.unique(np.asarray(bl.data.placement)[at]).size)
        if f.cause == causes_mod.OUTLIER and ev.get("placements") == 1:
            where = _moved_bar_words(bl, at)
            ev["confidence"] = "ambiguous"
            if where is not None:
                ev["moved_bar"] = where
                ev["confidence_reason"] = (
                    f"the outliers are all in one placement measured more than once, {where}: dust, or the bar "
                    "moved in its fixture between that placement's measurements (out of the catalogue)")
            else:
                pl = bl.data.placements[int(np.asarray(bl.data.placement)[at[0]])]
                ev["confidence_reason"] = (f"the outliers are all in one placement ({pl}): one event cannot show "
                                           "whether they are dust or a mechanism of that placement")
        if VOLUMETRIC_MOVED_BAR_RIVAL and f.cause in ("lobing_per_stylus", "thermal_drift") \
                and ev.get("confidence") in ("named", "ambiguous"):
            where = _moved_bar_words(bl, np.arange(len(bl.rows)))
            if where is not None:
                ev["moved_bar"] = where
                if ev.get("confidence") == "ambiguous":
                    ev["confidence_reason"] = "; ".join(w for w in (ev.get("confidence_reason"), (
                        f"or a bar that moved in its fixture between the measurements of {where}: a moved bar "
                        "shifts a placement's later measurements alike, as a stylus used only there or a drift in "
                        "time would")) if w)
        share = ev.get("rival_share")
        if VOLUMETRIC_HEDGE_SIGNIFICANT_LEFT and left and ev.get("confidence") == "named" and (
                f.cause == causes_mod.OUTLIER or VOLUMETRIC_HEDGE_LEFT_RIVAL_SHARE is None
                or (share is not None and share < VOLUMETRIC_HEDGE_LEFT_RIVAL_SHARE)):
            ev["confidence"] = "ambiguous"
            ev["confidence_reason"] = (
                "beside it structure is left in " + ", ".join(
                    f"{w['covariate']} ({fmt_p(w['p_value'])}, {w['explained_rms_um']:.3g} um)" for w in left)
                + ", significant though below materiality: a mechanism this name does not hold, judged immaterial "
                "against a noise it inflates")


def _doubt_beside_gathered_outliers(findings: list, settings) -> None:
    """Named causes smaller than an outlier finding that is no dust made ambiguous, in place.

    The outlier finding's own tests say its touches are a mechanism, not
    dust, when they gather in a covariate, a place or the moves that reach
    them (concentration p below ``alpha``) or sit on a feature whose other
    touches carry structure (``place_structure``). A mechanism that puts
    some touches beyond the outlier bound puts others below it, in the fit;
    a catalogue cause named beside it that explains less than the outliers
    carry (their baseline sum of squares) may be taking a share of those
    readings rather than its own physics. The centred turn's version, which
    needs no size, is :func:`_doubt_beside_turned_outliers`. Session 16
    (docs/discovery.md, "Session 16: confident misnamings"): gen_a
    reseat_hysteresis 1087, `stylus_bending` (2.8 um^2) confident beside
    six outliers carrying 59 um^2, concentration p 0.0098.
    """
    gathered = [f for f in findings if f.cause == causes_mod.OUTLIER and (
        (f.evidence.get("concentration_p") is not None and f.evidence["concentration_p"] < settings.alpha)
        or f.evidence.get("place_structure") is not None)]
    if not gathered:
        return
    d = gathered[0]
    carried = d.evidence.get("explained_ss_um2") or 0.0
    for f in findings:
        if f.cause in (causes_mod.OUTLIER, causes_mod.UNEXPLAINED) or f.evidence.get("confidence") != "named":
            continue
        if (f.evidence.get("explained_ss_um2") or 0.0) >= carried:
            continue
        f.evidence["confidence"] = "ambiguous"
        f.evidence["confidence_reason"] = (
            f"beside it outliers that are no dust (they gather in a covariate or on a place of the part) carry "
            f"{carried:.3g} um^2, more than this cause explains ({f.evidence.get('explained_ss_um2') or 0.0:.3g} "
            "um^2): the mechanism behind them, out of the catalogue, has readings below the outlier bound in the "
            "fit, which this cause may be taking")


#: Whether a confident ``outlier`` finding needs two events that stand beyond :data:`OUTLIER_EVENT_MARGIN` times the
#: screen's bound (:func:`_strong_events`): an event just beyond the bound may be a heavy-tailed probe's
#: own tail, and one strong event with such a one is no second independent piece of dust; the finding is then
#: ambiguous, with the reason. Session 32 (review32c F5, docs/discovery-studies.md "Session 32: heavy-tailed probing noise"): a local
#: scale defect's largest touch plus one Student-t 4 noise tail (0.63 of the bound with every row in) made two
#: events and read `outlier`, confident. (A kurtosis test of the kept residuals was tried first: one campaign of
#: 60 residual dof cannot see the probe's tail once its tail touch is set aside, excess kurtosis 0.20, p 0.26.)
OUTLIER_STRONG_EVENTS = True

#: The multiple of the screen's bound an event must reach (its largest row's deleted residual: the prediction error
#: from the fit of the rows kept) to count as one of the two events a confident outlier needs
#: (:data:`OUTLIER_STRONG_EVENTS`). 1.25: review32c F5's two events reach 1.11 and 1.44 of the bound; on the tuning
#: outlier campaigns (gen_a/gen_b/gen_c/simulator 1000-1029 / 200-229 / 4000-4029) two confident right readings
#: (gen_a 1004: 1.17, 1.69; 1026: 1.05, 3.52) become ambiguous, no other; a Student-t 4 probe at unit variance
#: puts a touch of 136 beyond 1.25 of the bound in 12 % of campaigns (26 % beyond the bound itself).
OUTLIER_EVENT_MARGIN = 1.25


def _strong_events(st0, outliers, events, settings) -> dict | None:
    """How many of the outliers' events stand beyond :data:`OUTLIER_EVENT_MARGIN` times the screen's bound.

    ``st0``: the baseline on every row (its basis an ndarray; else None).
    The baseline refitted on the rows kept (every row but ``outliers``);
    each outlier's prediction error from it over ``sigma sqrt(1 + l)``
    (``sigma`` the kept fit's scatter, ``l`` the row's leverage on the kept
    rows' Gram matrix: the deleted residual of the row put back alone) is
    its strength, an event's its largest row's; the bound is the screen's
    own, ``t(1 - outlier_alpha / 2n, dof - 1)``. Returns the bound, the
    margin, the count of events beyond, each row's strength."""
    Q = st0.Q
    if not isinstance(Q, np.ndarray) or len(st0.r) != Q.shape[0]:
        return None
    n = Q.shape[0]
    out = np.asarray(outliers)
    kept = np.setdiff1d(np.arange(n), out)
    r0 = st0.r
    coef, *_ = np.linalg.lstsq(Q[kept], r0[kept], rcond=None)
    e = r0[kept] - Q[kept] @ coef
    dof = kept.size - int(np.linalg.matrix_rank(Q[kept]))
    if dof < 3:
        return None
    sigma = float(np.sqrt(e @ e / dof))
    # each outlier's prediction error from the kept fit over its standard deviation there (its leverage from the
    # kept rows' Gram matrix: the deleted residual of the row put back alone)
    G = np.linalg.pinv(Q[kept].T @ Q[kept])
    lev = np.einsum("ij,jk,ik->i", Q[out], G, Q[out])
    z = np.abs(r0[out] - Q[out] @ coef) / (max(sigma, 1e-300) * np.sqrt(1 + np.maximum(lev, 0)))
    bound = float(stats.t.isf(settings.outlier_alpha / (2 * n), st0.dof - 1))
    ev = np.asarray(events)[out]
    ev = np.where(ev >= 0, ev, -1 - np.arange(len(out)))
    strong = int(sum(float(z[ev == k].max()) > OUTLIER_EVENT_MARGIN * bound for k in np.unique(ev)))
    return {"bound": bound, "margin": OUTLIER_EVENT_MARGIN, "strong_events": strong,
            "strength": [float(v) for v in z]}


#: Whether a confident ``outlier`` finding needs dust to explain its set-aside rows better than one column of
#: structure does (:func:`outliers_structure`): where the baseline plus one structural column, every row kept,
#: has a lower BIC (Schwarz: each parameter costs ``log n``; the best of the ``m`` columns tried pays ``2 log m``
#: more, the prior of "structure" split over its ``m`` forms) than the baseline plus one free value per set-aside
#: row (the screen's own reading: dust), the rows are a structure's largest residuals as likely as dust, and the
#: finding is ambiguous with the reason. The columns, fixed before the data are seen: per target holding two or
#: more of the rows and touched at least once more, the time of its touches (a target whose value moves with time
#: across its visits: a wall that bows, a part that changes); and the touches whose approach reversed the move
#: before it (the cosine of the turn negative: a seat that lands differently after a reversal). Session 33
#: (docs/discovery-studies.md, "Session 33: outliers that one column of structure explains"): gen_a part_change 9707 (a
#: bowing wall's two early visits, delta BIC -2.4 for its target's time) and reseat_hysteresis 9702 (five odd
#: touches of a re-seat, -19.1 for the reversal) read `outlier` confidently before. On the tuning seeds (gen_a, gen_b
#: 1000-1039, gen_c 0-39, the simulator 4000-4019: 2,320 campaigns) it fires on 7 findings, each hedged already or
#: beside an `unexplained` that leads, and moves no outcome; the 82 confident right `outlier` readings it is asked
#: about read +205 to +2,219 (dust). False: the behaviour before.
OUTLIERS_STRUCTURE_HEDGED = True


def outliers_structure(Q: np.ndarray, r: np.ndarray, outliers, columns: dict) -> dict | None:
    """Whether one column of structure explains the set-aside rows better than dust (BIC).

    ``Q`` (n, p) an orthonormal basis of the baseline's columns, ``r`` (n,)
    the baseline's residuals on every row, ``outliers`` the rows the screen
    set aside (k of them), ``columns`` name -> (n,) candidate columns (each
    in the units of the rows as ``Q`` has them: whitened where the baseline
    is). Dust: the baseline fitted on the kept rows, one free value per
    outlier, ``rank(Q_kept) + k`` parameters. Structure: the baseline plus
    one column, every row kept, ``p + 1``. ``BIC = n log(RSS / n) + params
    log n``; a column inside the baseline's span (nothing left once
    projected) is skipped; the best column pays ``2 log m`` for the ``m``
    tried. Returns None when no column is left to try or the kept fit has
    no residual dof; else ``{"column", "delta_bic", "bic_dust", "bic_structure",
    "tried", "explains"}`` with ``delta_bic`` the best column's BIC (penalty
    included) less dust's and ``explains`` whether it is below 0."""
    Q = np.asarray(Q, float)
    r = np.asarray(r, float)
    n = len(r)
    out = np.unique(np.asarray(outliers, int))
    if Q.ndim != 2 or Q.shape[0] != n or out.size == 0 or out.min() < 0 or out.max() >= n:
        raise ConfigError(f"outliers_structure: Q (n, p), r (n,), outliers within 0..n-1 expected, got "
                          f"{Q.shape}, {r.shape}, {out.tolist()[:5]}")
    kept = np.setdiff1d(np.arange(n), out)
    Qk = Q[kept]
    rank_k = int(np.linalg.matrix_rank(Qk))
    if kept.size - rank_k < 1:
        return None
    coef, *_ = np.linalg.lstsq(Qk, r[kept], rcond=None)
    e = r[kept] - Qk @ coef
    rss_dust = float(e @ e)
    rss0 = float(r @ r)
    tried = {}
    for name, x in columns.items():
        x = np.asarray(x, float)
        if x.shape != (n,):
            raise ConfigError(f"outliers_structure: column {name} has shape {x.shape}, ({n},) expected")
        xp = x - Q @ (Q.T @ x)
        if not xp @ xp > 1e-12 * max(float(x @ x), 1e-300):
            continue
        tried[name] = max(rss0 - float(xp @ r) ** 2 / float(xp @ xp), 0.0)
    if not tried or rss_dust <= 0:
        return None
    tiny = 1e-300
    best = min(tried, key=tried.get)
    p = Q.shape[1]
    bic_dust = n * np.log(max(rss_dust, tiny) / n) + (rank_k + out.size) * np.log(n)
    bic_struct = n * np.log(max(tried[best], tiny) / n) + (p + 1) * np.log(n) + 2 * np.log(len(tried))
    return {"column": best, "delta_bic": float(bic_struct - bic_dust), "bic_dust": float(bic_dust),
            "bic_structure": float(bic_struct), "tried": sorted(tried), "explains": bool(bic_struct < bic_dust)}


#: Whether an outlier finding's structure doubt (:data:`OUTLIERS_STRUCTURE_HEDGED`: one column of structure explains
#: the set-aside rows better than dust) reaches the causes named beside it (session 34, alt34). Each named cause
#: judged confident was adopted on the rows the screen kept; it is judged again on every row, those rows back, with
#: that column in the model beside the other terms: its columns must still explain something material and
#: significant (:func:`_beyond`, the nested F test with the Bonferroni factor of its adoption, at ``alpha_family``;
#: material, ``(material_sigma sigma)^2`` per row). Where they do not, the name is hedged (the rows and the column
#: say as much as the cause does) and the extended workpiece is read once more with the column in the cause's place,
#: its shift tested and carried as a named alternative's is (:func:`_workpiece`'s ``alternatives``). Set C's gen_a
#: reseat_hysteresis 10100 (docs/discovery-studies.md, "Session 33: the third blind check's misses (diag33)", miss
#: 1): four touches after a reversed approach set aside, `c_drift` named on the rest. False: the behaviour before.
#: **On since session 34**: 10100 reads `c_drift?` (1.48 um^2 beyond the column with the rows back, p_adj 1), its
#: workpiece 2.96 -> 5.254 um held by a U95 of 5.253 (0.744 before: the reading with the column in c_drift's place
#: carried). On the tuning seeds (the 320 campaigns of :data:`ALTERNATIVES_TWO_WAY` and gen_a reseat_hysteresis
#: 1005-1104, gen_c clamp_creep 5-88) it never fired: out33's column explained the rows beside a confident named cause
#: on none of them (beside a hedged one on gen_a reseat_hysteresis 1087).
OUTLIER_STRUCTURE_REJUDGED = True


def _rejudged_beside_outlier_structure(bl, findings, terms, Qall, y, all_rows, outliers, sigma, settings) -> dict:
    """:data:`OUTLIER_STRUCTURE_REJUDGED`'s test on ``findings`` (hedged in place). Returns ``{cause: (text, (N,)
    column)}`` of the causes hedged, for the workpiece's reading with the column in their place."""
    fo = next((f for f in findings if f.cause == causes_mod.OUTLIER), None)
    s = fo.evidence.get("structure") if fo is not None else None
    if not s or not s.get("explains") or not isinstance(Qall, np.ndarray):
        return {}
    col = outlier_structure_columns(bl, outliers).get(s["column"])
    if col is None:
        return {}
    out = {}
    for tm in terms:
        f = next((f for f in findings if f.cause == tm.cause), None)
        if tm.unnamed or f is None or f.evidence.get("confidence") != "named":
            continue
        so = _state(Qall, y, all_rows, [t for t in terms if t is not tm])
        U = new_basis(so.Q, col[all_rows][:, None])
        if U.shape[1] == 0:
            continue
        d, p, stands = _beyond(so, U, tm.columns[all_rows], sigma, tm.tries, settings)
        ev = f.evidence
        ev["outlier_structure_rejudged"] = {"column": s["column"], "rows_back": int(len(outliers)),
                                            "cause_beyond_ss_um2": d / UM ** 2, "p_adjusted": p,
                                            "stands": bool(stands)}
        if not stands:
            ev["confidence"] = "ambiguous"
            ev["confidence_reason"] = "; ".join(x for x in (ev.get("confidence_reason"), (
                f"the {len(outliers)} rows set aside as outliers are explained by one column of structure, "
                f"{s['column']}: with them back and that column beside it the cause explains "
                f"{max(d, 0.0) / UM ** 2:.3g} um^2 ({fmt_p(p)}), nothing material and significant")) if x)
            out[tm.cause] = (s["column"] + " in its place", col)
    return out


#: :func:`outlier_structure_columns` tries also ``reversed approach travel`` beside ``reversed approach``: on the
#: touches after a reversed approach, the cosine of the approach with the surface normal (0 elsewhere), the reading
#: of a fixed extra travel along the approach (a probe seat that lands differently after a reversal needs ``h`` more
#: travel along the approach: ``h d.n`` on the normal) where the 0/1 column is a fixed step along the normal. Blind
#: gen_a reseat_hysteresis 11700 (session 36, out36; the generator's extra travel along the approach, touches 0-33 deg
#: off their normal): the 0/1 column leaves the cosine's spread (8.4-10 um of a 10 um travel) and loses to dust by
#: BIC +60.5; this column explains the six set-aside rows at -36.1, and the confident `outlier` is hedged. Session 36,
#: docs/discovery-studies.md, "Session 36: the outlier screen's masking". False: the 0/1 column alone (the behaviour before).
#: On since session 36 (the lead: it flips no tuning reading; built after reading set F's 11700, so set F is not a
#: blind figure for it: the next blind set is).
OUTLIER_STRUCTURE_REVERSAL_TRAVEL = True

def outlier_structure_columns(bl: Baseline, outliers) -> dict:
    """The structural columns :func:`outliers_structure` tries for a planar campaign's set-aside rows (empty for
    another kind, or where the touches do not map one to one onto the baseline's rows). Per target holding two or
    more of ``outliers`` and touched at least once more: ``time <target id>``, its touches' times (s) less their
    mean, 0 elsewhere. Where the log gives the move before each touch (``d_prev_R``): ``reversed approach``, 1 on
    the touches whose approach has a negative cosine with that move's (0 where there is none). Whitened as the
    baseline's rows are (``bl.whiten``)."""
    if bl.kind != "planar":
        return {}
    t = bl.data.touches
    n = len(bl.y)
    if len(np.asarray(t.t_s)) != n:
        return {}
    tg = np.asarray(t.target)
    ts = np.asarray(t.t_s, float)
    out = np.asarray(outliers, int)
    cols = {}
    ids = getattr(t, "target_ids", None)
    u, cnt = np.unique(tg[out], return_counts=True)
    for T, k in zip(u, cnt):
        m = tg == T
        if k >= 2 and int(m.sum()) > k:
            x = np.zeros(n)
            x[m] = ts[m] - ts[m].mean()
            cols[f"time {ids[T] if ids is not None and int(T) < len(ids) else T}"] = x
    dp = getattr(t, "d_prev_R", None)
    if dp is not None:
        dp = np.asarray(dp, float)
        ok = np.all(np.isfinite(dp), axis=1)
        cosv = np.zeros(n)
        cosv[ok] = np.sum(np.asarray(t.d_R, float)[ok] * dp[ok], axis=1)
        cols["reversed approach"] = (cosv < 0).astype(float)
        if OUTLIER_STRUCTURE_REVERSAL_TRAVEL:
            # the seat's extra travel is along the approach: it reads on the normal as the approach's cosine with it
            nd = np.sum(np.asarray(t.d_R, float) * np.asarray(t.n_R, float), axis=1)
            cols["reversed approach travel"] = (cosv < 0).astype(float) * nd
    if bl.whiten is not None:
        W = bl.whiten
        cols = {k: W @ v for k, v in cols.items()}
    return cols


def _outlier_finding(bl, outliers, st0, st, ranks, events, seed, settings, places=None, history=None) -> Finding:
    """The outliers as a finding, with how confidently they are dust.

    Calling touches outliers says they are dust: a chip or a bad trigger,
    with no memory, falling at random over every covariate. An intermittent
    mechanism (a probe seat that re-seats after reversals, a clamp that
    slips) also leaves a few large residuals; only where they fall tells
    the two apart. So the finding is ``named`` (confident) only when that
    test could have seen a pattern and saw none: at least two independent
    events (one touch, or one set-up's touches, cannot show a pattern), and
    the concentration p-value (:func:`concentration_p`, over the covariates
    and the places ``places``) at least the engine's overall false-alarm
    rate ``alpha``, not only the family level that decides the removal;
    and the feature they sit on carries no structure in its other touches
    (:func:`_place_carries`: then they may be that structure's largest
    residuals). The concentration test holds, besides the covariates
    counted one per event, the covariates of the touch's own history
    (``history``: the ranks of the time since the previous touch and of the
    turn of the approach) counted one per place (target and set-up): their
    shift, two-sided (after long rests or short ones, after large turns or
    none), in the same Bonferroni family (:func:`concentration_p`'s
    ``history_ranks``; the history per event and per place are two looks
    at the same covariates, so the family's factor counts both). The
    removal counts a set-up's outliers as one event, as a set-up's chips
    may gather where its swarf fell and share the moves that reach that
    place (the simulator's chips on its pocket: counted per touch, the
    history test removed none of them, its outlier 2301 lost); the
    confidence asks whether dust is the only reading, and outliers of two
    or more set-ups that follow the moves touch by touch are also a
    mechanism of the move (a probe that re-seats after a turn: gen_a
    reseat_hysteresis 876, ten of eleven outliers after turns of 86 deg or
    more in three set-ups, `outlier` confident before, concentration p
    0.069 without the history per place). Under dust at random touches of
    the whole part the family keeps its level (``alpha`` of such campaigns
    flagged at most). Under dust confined to one feature, whose touches
    share their moves, it does not: 2-4 random touches of one feature in
    two or more set-ups trip the history statistic alone (Bonferroni over
    its two covariates) at 1 % in 10-38 % of draws (gen_b 800 pin1 0.19,
    gen_a 1406 bore1 0.23, the simulator's spheres 0.35-0.38; draws over
    all touches 0.007-0.010; a reviewer's measurement, 300 draws each); drawing the null within the outliers' feature is no clean
    cure (it loses gen_a reseat_hysteresis 860 and keeps gen_a outlier 1406
    flagged). So an ``ambiguous`` flag from it reads "a mechanism of the
    move, or dust on one feature whose touches share their moves". Besides,
    for two or more outlier rows on a planar campaign, the centred turn
    (:func:`centred_turn_p`, at ``alpha_family``, its own test): a mechanism
    of the move that each target's parameter half absorbs (gen_a
    reseat_hysteresis: the baseline takes a target's mean reading, so a
    re-seat where most set-ups are clean reads short, a clean touch where
    most re-seat reads long) leaves outliers at both ends of the turn at
    once, which the shift of the mean rank above does not see; their
    residuals follow the turn taken relative to the target's other touches
    (gen_a reseat_hysteresis 1012, 1088, 1262: `outlier` confident before,
    centred-turn p 1.2e-4, 1.0e-5, 1.5e-4). And for two or more outlier
    rows on a planar campaign, the sign of approach (:func:`approach_sign_p`,
    at ``alpha_family``): a lost motion lies almost inside the baseline's
    span (each target's parameter takes it where the target is approached
    with one sign along the axis) and shows only on touches whose approach
    is nearly across the axis, where a touch whose state differs from its
    target's other touches reads a full step ``|n_ax| B`` off them (gen_a
    reversal 1033, 1299, 1430, 1688: `outlier` confident before, session
    20); the finding is then ambiguous with ``reversal`` (``ambiguous_with``).
    Otherwise ``ambiguous``, with the reason.
    """
    alpha = settings.alpha
    r0 = st0.r[outliers]
    ss = float(np.sum(r0 ** 2))
    first = first_per_event(outliers, events)
    if len(first) < 2 or ranks.shape[1] == 0:
        p_conc, why = None, ("one event (a touch, or one set-up's touches) cannot show whether it is dust or an "
                             "intermittent mechanism" if len(first) < 2 else "no covariate to test the pattern in")
    else:
        at = None if places is None else first_per_event(list(outliers), places.units)
        # one family at one level: the covariates per event, the places, the history per place
        hist = history if history is not None and history.ndim == 2 and history.shape[1] else None
        p_conc = concentration_p(ranks, first, np.random.default_rng(seed), places=places, place_idx=at,
                                 history_ranks=hist, place_rows=None if hist is None else
                                 (list(outliers) if at is None else at))
        why = (None if p_conc >= alpha else
               "the outliers gather in a covariate or on one place of the part" +
               ("" if hist is None else ", or follow the moves that reach them place by place") +
               f" (concentration {fmt_p(p_conc)}, below the overall false-alarm rate {alpha:g}): they may be an "
               "intermittent mechanism" + (", not dust" if hist is None else
                                          ", or dust on one feature whose touches share their moves, not dust "
                                          "at random touches"))
    place = None
    if places is not None and len(first) >= 2:
        place = _place_carries(st.Q, st.r, st.rows, outliers, np.asarray(events), places, settings.alpha_family,
                               settings.material_sigma)
        if place is not None:
            why = "; ".join(w for w in (why, (
                f"the feature {place['feature']} they sit on carries structure in its other touches "
                f"({place['explained_ss_um2']:.3g} um^2, {fmt_p(place['p_adjusted'])}): they may be its largest "
                "residuals, not dust")) if w)
    p_turn = None
    c = centred_turn(bl) if len(outliers) >= 2 else None
    meas_struct = None
    if bl.kind == "volumetric" and VOLUMETRIC_OUTLIER_MEASUREMENT_STRUCTURE:
        meas_struct = _measurement_carries(bl, st, outliers, settings.alpha_family, settings.material_sigma)
        if meas_struct is not None:
            why = "; ".join(w for w in (why, (
                f"the measurement {meas_struct['measurement']} they fall in carries structure along the bar in its "
                f"other points ({meas_struct['explained_ss_um2']:.3g} um^2, {fmt_p(meas_struct['p_adjusted'])}): "
                "they may be its largest residuals (the bar deformed or moved within it), not dust")) if w)
    if c is not None:
        p_turn = centred_turn_p(c, outliers, r0 / UM, np.random.default_rng([seed, 1]))
        if p_turn < settings.alpha_family:
            why = "; ".join(w for w in (why, (
                "the outliers read short or long as their touch's turn of the approach differs from its target's "
                f"other touches (centred turn {fmt_p(p_turn)}, below {settings.alpha_family:g}): a mechanism of "
                "the move that the target's parameter half absorbed, or dust of one sign on touches whose turns "
                "differ alike from their targets', not dust at random touches")) if w)
    p_sign, alt = None, []
    sgn = approach_sign_p(bl, outliers, r0 / UM, seed)
    if sgn is not None:
        p_sign, test, ax = sgn
        if p_sign < settings.alpha_family:
            alt = [c for c in ("reversal",) if causes_mod.lookup(c, bl.kind) is not None]
            what = (f"read short or long as their touch's sign of approach along {ax} differs from its target's "
                    "other touches" if test == "centred sign" else
                    f"sit on the touches whose approach moves {ax} least (nearly across it)")
            why = "; ".join(w for w in (why, (
                f"the outliers {what} (sign of approach {fmt_p(p_sign)}, {test} along {ax}, below "
                f"{settings.alpha_family:g}): a lost motion whose state the approach did not set, or that the "
                "targets' parameters half absorb, or dust that falls there, not dust at random touches")) if w)
    heavy = _strong_events(st0, outliers, events, settings) if OUTLIER_STRONG_EVENTS and len(first) >= 2 \
        else None
    if heavy is not None and heavy["strong_events"] < 2:
        why = "; ".join(w for w in (why, (
            f"only {heavy['strong_events']} of the {len(first)} events stand beyond {heavy['margin']:g} times the "
            f"screen's bound ({heavy['bound']:.2f}): a touch just beyond it may be a heavy-tailed probe's own tail "
            "or a narrow structure's largest touch, not a second piece of dust")) if w)
    structure = None
    if OUTLIERS_STRUCTURE_HEDGED and len(first) >= 2 and isinstance(st0.Q, np.ndarray) \
            and len(st0.r) == st0.Q.shape[0]:
        structure = outliers_structure(st0.Q, st0.r, outliers, outlier_structure_columns(bl, outliers))
        if structure is not None and structure["explains"]:
            why = "; ".join(w for w in (why, (
                f"one column of structure, {structure['column']}, explains them as well as dust does (BIC "
                f"{structure['delta_bic']:+.3g} against one free value per outlier, every row kept, "
                f"{len(structure['tried'])} column(s) tried): they may be a structure's largest residuals "
                "(a target that moves with time, touches after a reversed approach), not dust")) if w)
    return Finding(causes_mod.OUTLIER, {
        "rows": [int(bl.rows[i]) for i in outliers], "residual_um": [float(v) / UM for v in r0],
        **({"strong_events": heavy} if heavy is not None else {}),
        **({"structure": structure} if structure is not None else {}),
        "explained_ss_um2": ss / UM ** 2, "events": len(first), "concentration_p": p_conc,
        **({"centred_turn_p": p_turn} if p_turn is not None else {}),
        **({"approach_sign_p": p_sign, "approach_sign_test": f"{test} along {ax}"} if p_sign is not None else {}),
        **({"ambiguous_with": alt} if alt else {}),
        **({"place_structure": _clean(place)} if place is not None else {}),
        **({"measurement_structure": _clean(meas_struct)} if meas_struct is not None else {}),
        "confidence": "ambiguous" if why else "named", **({"confidence_reason": why} if why else {}),
        "test": "studentized deleted residual beyond the Bonferroni t bound"},
        {"n_outliers": int(len(outliers)), "max_deviation_um": float(np.max(np.abs(r0))) / UM},
        {"max_deviation_um": None}, st.sigma / UM, "data")


#: A report that would read ``none`` with its noise floor taken from the repeats, where those repeats scatter more
#: than the whole fit leaves (the lack-of-fit F in its lower tail, below ``Settings.alpha``), is judged again at the
#: residuals' floor by the covariate diagnosis alone; where a covariate is significant and material there the report
#: reads ``unexplained`` (:func:`_none_at_the_residual_floor`). A mechanism that moves every repeat group alike (a
#: re-seat after each turn of the approach, a C clamp's creep) inflates the floor the materiality of every test is
#: judged with: gen_a reseat_hysteresis 6100 (session 24's blind check) read `none` beside a turn of the approach at
#: p = 8e-14, 0.31 um against a materiality of 0.43 um from repeats of 1.43 um (true noise 0.41, the residuals'
#: 0.70). Unlike :data:`REPEATS_BEYOND_FIT` (the whole selection at the residuals' floor: two re-seats read
#: `c_drift?` there) it names nothing: it only turns `none` into `unexplained`. Session 25 (docs/discovery.md):
#: on the tuning seeds gen_a reseat 1000, 1022, 1140, 1206, 1209, 1280 and gen_b fixture_slip 1075, 1096 `none` ->
#: `unexplained`, ten campaigns below visibility and gen_b c_drift 1187, 1220 (a miss either way) too; no
#: effect-free campaign of gen_a, gen_b (500) or the simulator (100) moved.
REPEATS_FLOOR_NONE_RECHECKED = True

#: The floor of the noise, in units of the data's own numerical precision (:func:`roundoff_floor_m`): the
#: machine epsilon times the largest coordinate of the campaign (its nominal tip centres, m) times this many. A
#: reading enters as a double parsed from the log and scaled mm -> m (each coordinate within one ulp of its value,
#: eps |x|), and the deviation ``n . (p - pn)`` subtracts two such points: a row carries up to a few eps |x| of
#: rounding whatever the probe did, and the fit's own rounding is far smaller (it acts on deviations of um, not on
#: coordinates of 0.1 m). 64: measured, gen_c's noise-free campaigns on an affine machine leave the baseline's
#: residuals at 3.3-3.6e-18 m RMS (0.15 eps |x|, |x| 0.1 m) and 2e-12 um on the workpiece; the floor there,
#: 1.4e-15 m, is 400 times that and seven orders of magnitude below any probe's noise (gen_c draws 0.2-0.5 um)
#: or the smallest structure a noise-free campaign holds (the smooth machine's grid interpolation, 5e-9 m RMS).
#: Session 26 (docs/discovery.md, "Session 26: discover on noise-free data").
ROUNDOFF_ULPS = 64.0


def roundoff_floor_m(bl: Baseline) -> float:
    """The data's own numerical precision, m: :data:`ROUNDOFF_ULPS` eps times its largest coordinate.

    Planar: the nominal tip centres' X and Y (``bl.data``); every kind: the
    observations themselves (a floor of their own rounding where no
    coordinate is known). What a model leaves below it is rounding, not
    anything the probe or the machine did: the noise is never taken below it
    (no test divides by a zero scatter of exact repeats), and a baseline whose
    every residual is below it leaves nothing to find (:func:`discover_baseline`).
    """
    mag = float(np.max(np.abs(bl.y))) if len(bl.y) else 0.0
    data = bl.data if bl.kind == "planar" else None
    for v in (getattr(data, "x", None), getattr(data, "y", None)):
        if v is not None and len(v):
            mag = max(mag, float(np.max(np.abs(v))))
    return ROUNDOFF_ULPS * float(np.finfo(float).eps) * mag


def _none_at_the_residual_floor(bl, st, rep, rows, settings, bases=None, known=()) -> Finding | None:
    """An ``unexplained`` finding for a report that reads ``none`` at an inflated repeats' floor, else None.

    Called only where the report has no finding and its noise floor is the
    repeats' scatter (not the short-term pairs'). ``st`` is the final model
    (the baseline alone there), ``rep`` the repeats' plain pure error the
    lack-of-fit test uses. Pure error cannot scatter more than the whole
    fit leaves but by chance: the lack-of-fit F (:func:`lack_of_fit`) in its
    lower tail, ``F(d1, dof_pe).cdf(F)`` below ``settings.alpha`` (0.01),
    says the repeats hold something the probe's noise does not (the test of
    :data:`REPEATS_BEYOND_FIT`, there in place of the floor). The baseline's
    residuals are then diagnosed again at their own scatter
    (``st.sigma``, on ``st.dof`` degrees of freedom, as on a log without
    repeats): the diagnosis's p-values do not depend on the floor, only its
    materiality (``material_sigma`` times the floor) does. A covariate
    significant and material there (:meth:`core.diagnosis.Diagnosis.significant`
    at ``alpha_family``) makes the finding, with the floor's figures in
    ``repeats_floor``. Under pure noise both tests must fire, each at its
    own level (1 % and the diagnosis's family level). The cv gap and lack of
    fit are not judged again (the first is judged against the fit's own
    sigma already, the second is the test that fired in its other tail).
    ``known``: diagnoses made against ``st`` itself over the covariates
    (step 5's, at the repeats' floor): their tests are taken, only their
    materiality is judged again (session 26: the same numbers, one
    diagnosis of every covariate fewer).
    """
    beyond = _repeats_beyond_fit(st, rep, settings.alpha)
    if beyond is None:
        return None
    lof, p_low = beyond
    diag = diagnose(st.Q, st.r, st.dof, bl.covariates, bl.modes, sigma_m=st.sigma,
                    material_sigma=settings.material_sigma, rows=rows, bases=bases, known=known)
    sig_cov = [d.covariate for d in diag if d.significant(settings.alpha_family)]
    if not sig_cov:
        return None
    structure = {"present": True, "covariates": sig_cov, "cv_gap": False, "lack_of_fit": False,
                 "noise_excess": False}
    f = _unexplained_only(diag, structure, st, st.sigma, settings)
    sigma_pe = float(np.sqrt(rep.ss / rep.dof))
    f.evidence["repeats_floor"] = _clean({
        "repeats_sigma_um": sigma_pe / UM, "repeats_dof": int(rep.dof), "residual_sigma_um": st.sigma / UM,
        "residual_dof": int(st.dof), "lack_of_fit_F": float(lof.F), "p_lower": p_low,
        "text": (f"the repeats scatter more than the whole fit leaves ({sigma_pe / UM:.3g} against "
                 f"{st.sigma / UM:.3g} um, lack-of-fit F = {lof.F:.3g}, lower tail {fmt_p(p_low)}): they hold "
                 "structure, not the probe's noise alone; judged at the residuals' scatter")})
    f.evidence["text"] = f"{f.evidence['text']}; {f.evidence['repeats_floor']['text']}"
    return f


def _repeats_beyond_fit(st, rep, alpha: float) -> tuple | None:
    """``(lack of fit, p)`` where the repeats' pure error ``rep`` scatters more than the whole fit ``st`` leaves
    beyond chance (the lack-of-fit F in its lower tail, ``p = F(d1, dof_pe).cdf(F)`` below ``alpha``), else None."""
    lof = lack_of_fit(st.rss, st.dof, rep)
    if lof is None:
        return None
    p_low = float(stats.f.cdf(lof.F, lof.dof, rep.dof))
    return (lof, p_low) if p_low < alpha else None


def _unexplained_only(diag, structure, st, sigma, settings) -> Finding:
    words = "; ".join(d.words for d in diag if d.covariate in structure["covariates"])
    if not words:
        words = _no_covariate_words(structure, settings)
    top = next((d for d in diag if d.covariate in structure["covariates"]), None)
    return Finding(causes_mod.UNEXPLAINED, _clean({
        "text": words, "diagnosis": [d.to_dict() for d in diag if d.covariate in structure["covariates"]],
        "cv_gap": structure["cv_gap"], "lack_of_fit": structure["lack_of_fit"],
        "noise_excess": structure["noise_excess"],
        "explained_ss_um2": (top.explained_rms_um ** 2 * st.dof) if top else 0.0}), {}, {}, st.sigma / UM, "unknown")


#: Outliers the report does not call dust with confidence, on :data:`OUTLIER_FORM_TARGETS` or more targets of one
#: feature and reading there both more and less material than the extended fit (a particle reads more, never
#: less): their removal's shift of the extended workpiece tested and, where real, carried in its U95
#: (:func:`_workpiece`'s ``doubted``). False: the behaviour before session 21 (the extended U95 from the rows
#: kept alone).
OUTLIER_SHIFT_CARRIED = True
#: The removal's shift (:func:`_workpiece`'s ``doubted``) refits the extended model with the form's outliers put back,
#: only those (True); False: every outlier put back (session 21), a single chip on another feature's touch counted
#: in the form's shift as well.
OUTLIER_REFIT_FORM_ONLY = True
#: A named cause that is one explanation with another catalogue cause under two names on the design
#: (``ambiguous_with``, step 8): the workpiece shift between the two readings tested and, where real, carried in
#: the extended U95 (:func:`_workpiece`'s ``alternatives``). False (kept, session 22): the U95 of the name reported
#: alone. Measured on: it covers gen_a feed_latency 1009, 1144, 1145 (U95 7.3 -> 51, 8.2 -> 3766, 9.0 -> 191 um) but
#: inflates covering U95s where the name was right and the alternative's fit degenerate (reversal 1009 1.5 -> 43 um
#: beside nonrigid, local_scale_defect read on outlier 1824 2.9 -> 29 um beside part_change): the shift measures
#: the alternative's model error as much as the name's (docs/discovery.md, session 22).
NAMED_ALTERNATIVE_SHIFT_CARRIED = False
#: Fixed lobes (a cause whose ``richer`` nests it) named confidently only where the data favour them over the
#: richer cause by odds of at least ``1 / alpha`` (:func:`core.causes.turned_lobes`' ``log10_odds_fixed``: the
#: Bayes factor with the turn taken as Gaussian), not only where a turn would have shown in all but ``alpha``
#: of draws (``p_turned``). Where few directions tell a turn from fixed lobes the odds are capped at about the
#: turn's amplitude over the noise per direction (``log10_odds_most``): the simulator's cross pocket (2
#: directions, one carrying the turn) reaches at most 8-100 on its tuning seeds, so its small ``p_turned``
#: (a calibrated test of low power, about 15 %) leaves fixed lobes ambiguous with ``lobing_per_setup``; gen_a
#: and gen_c (12-30 directions) reach odds of 10^2-10^17. True (session 27: simulator lobing_per_setup 6101
#: and tuning twin 4038, confidently ``probe_lobing``, hedged; the simulator's 14 confident fixed-lobe names
#: of 4000-4099 hedged too, no cause changed on 1,235 tuning campaigns; docs/discovery-studies.md, "Session 27: fixed
#: lobes need odds, not only a small p_turned").
RICHER_NEEDS_ODDS = True
#: A named cause hedged because a richer catalogue cause that nests it is significant beyond it or cannot be
#: excluded (step 8's ``evidence.richer``: lobes turned per set-up against fixed lobes, seen but not material, or a
#: turn the design could have missed, by ``p_turned`` or the odds): the extended workpiece refitted with the richer
#: cause's columns (:attr:`core.causes.Cause.richer_columns`, their determined combinations) in the named one's
#: place, its shift from the named reading tested by :func:`_unnamed_shift` against its own scatter and, where real,
#: carried in the extended U95 as ``D D^T / 4`` (:func:`_workpiece`'s ``richer``; the report's
#: ``workpiece_shift_richer`` and a convention line). The richer fit nests the named one (unlike a rival of the same
#: richness, whose fit may be degenerate: :data:`NAMED_ALTERNATIVE_SHIFT_CARRIED`), so a real shift is the named
#: reading's bias if the richer cause is the truth, a model choice the report itself doubts. False: the U95 of the
#: named model alone (before session 28: simulator lobing_per_setup 6403 and its tuning twin 4086 missed their
#: workpiece checks by 1 %). Measured on 2,540 tuning campaigns (simulator, gen_a, gen_b, gen_c): no cause changed,
#: workpiece failures 3 -> 2 (on the simulator 1 -> 0: 4086, U95 0.310 -> 0.649), the U95 grown on 97 campaigns
#: (simulator 91: mean x1.11, max x2.09), none of them needlessly wide (error < U95 / 3). Session 28
#: (docs/discovery-studies.md, "Session 28: the richer cause's workpiece shift carried in the extended U95").
RICHER_SHIFT_CARRIED = True
#: Whether, where the form a named cause is adopted in has a direction inflated beyond ``vif_max`` (its best
#: direction within it: :func:`_determined`, ``max_vif``), the cause's other significant forms that pass every test
#: (whatever their covariate) are fitted in its place, in their determined combinations, and the largest real shift
#: of the extended workpiece between the adopted form and them carried in the extended U95 (True; :func:`_workpiece`'s
#: ``forms``: the same test, :func:`_unnamed_shift`, and the same quadrature, ``D D^T / 4``, as
#: :data:`RICHER_SHIFT_CARRIED`; the report's ``workpiece_shift_form`` and a convention line). The name, the form and
#: the estimate do not change: the U95 says the workpiece is not determined between the cause's forms. Session 28
#: (form28, "v8"): gen_a c_drift 7302 (session 27's blind failure) and its tuning twins 1560, 1682, 1904, 1929, 1998
#: adopt a creep common to the set-ups for per-set-up creeps of alternating sign along a direction inflated 563-8,559
#: times; all six pass with it (7302: U95 1.496 -> 12.483 um against an error of 12.815 beside the baseline's 1.170),
#: no name or estimate moves anywhere (by construction), the U95 grows only where it fires. The choice of form by
#: held-out gain instead (:data:`VIF_FORM_BY_GAIN`, "v7") mends the six by the estimate but moves gen_a c_drift 1076
#: right -> wrong and carries :data:`VIF_DROP_BEYOND_MAX`'s costs. docs/discovery-studies.md, "Session 28: the workpiece not
#: determined between a cause's forms".
FORM_SHIFT_CARRIED = True
#: Which hedged named causes (``confidence`` ``ambiguous``) have the workpiece shift their own term makes tested and,
#: where real, carried in the extended U95: the same extended model fitted without the cause's term (every other
#: term kept) is one more reading in its place (:func:`_workpiece`'s ``without``), its shift from the reported
#: reading tested by :func:`_unnamed_shift` against its own scatter and carried as ``D D^T / 4`` as
#: :data:`FORM_SHIFT_CARRIED`'s are (the report's ``workpiece_shift_without`` and a convention line). A hedged name
#: is one the report doubts; where its term moves the workpiece beyond the noise, whether the workpiece is the
#: reading with it or without it is the doubt's, and the U95 then reaches both. The name, the form and the estimate
#: do not change. ``"inflated"``: only a hedged cause whose form has a direction inflated beyond ``vif_max``
#: (:func:`_beyond_vif_max`: a term the data determine poorly along a direction, whose fit along it is the noise's
#: and the model error's amplified); ``"hedged"``: every hedged named cause; ``"inflated_any"`` (below); None:
#: neither (before session 32).
#: Session 32 (vif32): gen_a thermal_bending 8907, a hedged part_change of one bore (best direction inflated 4.7,
#: worst 181) moved the extended workpiece 6.9 um from the truth against baseline 1.05 + U95 2.11; with
#: ``"inflated"`` its U95 is 6.94 (the shift 6.61 um RMS, p < 1e-6) and the check holds, name and estimate unchanged.
#: **``"inflated"`` since session 32**: on 685 tuning campaigns (gen_a/gen_b 1000-1004 every effect and none
#: 1000-1019, gen_a thermal_bending and part_change 1000-1029, the simulator 4000-4009, gen_c 200-219) no name,
#: confidence or estimate moved (by construction), no workpiece check moved (653 of 654 hold both ways), the U95 grew
#: on 42 (median x1.21, max x4.9), 7 of them newly more than three times their error; ``"hedged"`` grew 158 (25
#: newly). docs/discovery-studies.md, "Session 32: a workpiece moved along an inflated direction".
#: ``"inflated_any"``: every named cause, hedged or confident, whose form has a direction beyond ``vif_max`` (the
#: lead, session 32, on the blind check's miss gen_b signal_latency 9309: a confident second-finding part_change of
#: a slot's two walls, +16.3 and -12.3 um +- 7 um beside an unnamed smooth, moved the extended workpiece 4.80 um
#: from the truth against baseline 0.22 + U95 2.22; with ``"inflated_any"`` its U95 is 5.19 and the check holds).
#: **On since session 32**: on the same 685 tuning campaigns against ``"inflated"`` no name, confidence, estimate or
#: workpiece check moved (653 of 654 hold both ways), 22 more U95s grew (confident thermal_drift, probe_lobing,
#: reversal, c_drift, lobing_per_setup, part_change: gen_a thermal_drift 1004 0.570 -> 1.608 um against an error of
#: 0.372, most under x1.7). A confident name's term along a direction the data hardly determine moves the workpiece
#: as much as a hedged one's: the U95 says so. docs/discovery-studies.md, "Session 32: the shift of a confident inflated
#: term carried".
HEDGED_SHIFT_CARRIED = "inflated_any"
#: The reading :data:`HEDGED_SHIFT_CARRIED` sets beside a named cause whose form has a direction inflated beyond
#: ``vif_max``: ``"without"``, the extended model without the cause's term (session 32); ``"determined"``, its term
#: fitted on its determined directions only (those within ``vif_max``, :func:`_determined` with ``drop``: the reading
#: :data:`VIF_DROP_BEYOND_MAX` makes), so that the shift carried is the one the inflated directions make, not the
#: whole term's (a hedged cause not inflated, under ``"hedged"``, keeps the reading without it). **``"determined"``
#: since session 33** (vif33): gen_a thermal_bending 8907 and gen_b signal_latency 9309 stay held (6.909 <= 1.053 +
#: 6.884, 4.798 <= 0.221 + 5.052); on the tuning seeds no name or estimate moved (by construction) and no workpiece
#: check failed either way (gen_a/gen_b 1000-1039, the simulator 4000-4019, gen_c 0-39: 2,320 campaigns); the U95
#: moved on 249 (shrank on 229, grew on 20, at most x1.68), those more than three times their error 112 -> 38 of
#: them; ten fell below their own error, every check holding (gen_a c_drift 1013 by 0.04 um: where the determined
#: directions carry a wrong form's bias too, the whole term's shift covered it). docs/discovery-studies.md, "Session 33: a term nearly inside the baseline".
HEDGED_SHIFT_READING = "determined"
#: Whether a hedged named cause whose term is *fine* (:func:`_fine_hedged`: its length, a periodic error's period or a
#: bump's half-width, below the median distance between neighbouring targets of the part) has the workpiece shift
#: its own term makes tested and, where real, carried in the extended U95, as :data:`HEDGED_SHIFT_CARRIED` does for
#: a term inflated beyond ``vif_max`` (the same reading without the term, the same test :func:`_unnamed_shift` at
#: ``alpha_family``, the same ``D D^T / 4``; the report's ``workpiece_shift_without``, a convention line and the
#: term's ``fine_term``). A term that turns over a shorter length than the targets are apart takes, at each target,
#: a value the target's own parameter can take as well: its columns trade off with the part's, and where its name is
#: doubted the workpiece is not determined between the readings with and without it, whatever its VIF over the
#: whole design says. The name, the form and the estimate do not change; only the U95 grows, and only where the
#: shift is real. **True since session 34** (wp34): set C's gen_a feed_latency 10105 (``periodic_axis_error?`` Y 4.21
#: mm + ``local_scale_defect?`` half-width 4.33 mm adding nothing beyond the smooth map, targets 9.47 mm apart) moved
#: its extended workpiece 3.12 -> 15.04 um against a U95 of 9.51; the two terms' shifts are 11.9 and 12.1 um RMS (p
#: 1e-19, 3e-12), carried: U95 19.44, the check holds. On 881 tuning campaigns (gen_a every effect 1000-1014, its
#: feed_latency, periodic_axis_error, local_scale_defect and nonrigid 1015-1039, feed_latency 1040-1199; gen_b every
#: effect 1000-1007; gen_c 0-7; the simulator 4000-4005) no name, confidence or estimate moved (by construction), the
#: U95 moved on 3 (all gen_a feed_latency, out of the catalogue, a hedged periodic error of 5.6-6.8 mm: 1009 12.98 ->
#: 15.33, 1144 9.42 -> 22.01, 1145 8.96 -> 23.18 um), workpiece checks failing 1 -> 0 (1145: 18.34 against 8.55 +
#: 8.96, now + 23.18), none newly wider than three times its error. docs/discovery-studies.md, "Session 34: a hedged fine
#: term's shift of the workpiece carried".
FINE_SHIFT_CARRIED = True
#: With :data:`FINE_SHIFT_CARRIED`: a fine term whose own significance holds beyond the smooth error map (its
#: ``p_adjusted_beyond_smooth``, :func:`_smooth_verdict`'s nested F test beside the map with its adoption's Bonferroni
#: factor, below ``alpha_family``, the level that verdict judges it at) is left out of the test: the data see it
#: confined where it sits, not only as structure a smooth machine error along the axis also explains, so its move of
#: the workpiece is what its evidence supports. Where that test was not made (a periodic error has no smooth twin)
#: the shift is tested. True (session 34): on the tuning seeds the rule without it grew the U95 of right, hedged
#: ``local_scale_defect`` readings whose bump the data see beyond the map (p 1e-8 to 1e-80; gen_a local_scale_defect
#: 1016: 15.7 -> 122 um against an error of 8.1), while 10105's bump adds nothing beyond the map (p 1.0).
FINE_SHIFT_EXEMPT_BEYOND_SMOOTH = True
#: The keys of a term's ``info`` that are its length along its axis (m): a periodic axis error's period, a local
#: scale defect's half-width (:func:`core.causes._hann`'s width at half height).
FINE_SCALE_KEYS = ("period_m", "half_width_m")


def _target_spacing_m(bl) -> float | None:
    """The median distance from each distinct target position of the part to its nearest other (m).

    The positions are the baseline's ``geometry`` (each target's nominal
    point in one frame of the part), distinct to 1 um (targets touched from
    several depths share a point). None without a geometry (volumetric,
    positioning) or with fewer than two distinct positions.
    """
    geo = getattr(bl, "geometry", None)
    if geo is None:
        return None
    P = np.unique(np.round(np.asarray(geo[0], float) / 1e-6), axis=0) * 1e-6
    if len(P) < 2:
        return None
    from scipy.spatial import cKDTree

    return float(np.median(cKDTree(P).query(P, 2)[0][:, 1]))


def _fine_hedged(bl, terms, hedged: dict, alpha: float) -> dict:
    """``{cause: (length m, target spacing m)}`` of the hedged named terms finer than the targets are apart.

    ``hedged``: ``{cause: evidence}`` of the hedged named findings. A named
    term (not the unnamed smooth) whose cause is there and whose ``info``
    gives a length (:data:`FINE_SCALE_KEYS`, the shortest if several) below
    :func:`_target_spacing_m`; with :data:`FINE_SHIFT_EXEMPT_BEYOND_SMOOTH`
    not one whose evidence holds beyond the smooth error map
    (``p_adjusted_beyond_smooth`` below ``alpha``). Empty where none is.
    """
    cands = []
    for t in terms:
        if t.unnamed or t.cause not in hedged:
            continue
        p_b = hedged[t.cause].get("p_adjusted_beyond_smooth")
        if FINE_SHIFT_EXEMPT_BEYOND_SMOOTH and p_b is not None and p_b < alpha:
            continue
        ls = [float(np.min(t.info[k])) for k in FINE_SCALE_KEYS if k in (t.info or {})]
        if ls:
            cands.append((t.cause, min(ls)))
    if not cands:
        return {}
    s = _target_spacing_m(bl)
    if s is None:
        return {}
    return {c: (length, s) for c, length in cands if length < s}


#: Whether :data:`FORM_SHIFT_CARRIED` reads the cause only in those of its other forms that have no direction inflated
#: beyond ``vif_max`` themselves (True), or in every other passing form (False). A reading inflated as the adopted
#: one is carries its own amplification along the inflated direction into the shift: on gen_a thermal_drift
#: 1000-1019 (the warm-up's right form, inflated, beside polynomials over the campaign) every form widened 11 U95s, 8
#: of them newly to more than three times the error (1004: 0.570 -> 1.147 um, error 0.372), the determined forms 8,
#: 4 of them (1004 unchanged); the six c_drift failures are mended either way. Session 28 (form28).
FORM_SHIFT_DETERMINED_ONLY = True
#: Outliers whose target has touches kept, reading less material than the fit there, doubted whatever the report
#: calls them (:func:`_workpiece`'s ``beside_kept``): the removal's shift tested and carried as the form's.
#: False (kept, session 22): measured on, it raised the covering U95 of 65 of gen_b outlier 1000-1099's 93
#: (median 0.343 -> 0.486 um; its chips and skids read on either side of the touches kept) and of four gen_a
#: outlier campaigns for no check gained (gen_a outlier 1505, the case it was made for, held its check before).
OUTLIER_BELOW_KEPT = False
#: Distinct targets of one feature the doubted outliers must touch for the part's own state to be a reading of
#: them: what the workpiece estimates is a form, and a feature's form is seen at three targets or more (two are
#: a size and a tilt, which the part's gauge and the feature's other targets share); a chip or a skid
#: corrupts the touch it sits under (gen_a 1-4 random touches, gen_b 2-5, the simulator 1-3 on one wall).
OUTLIER_FORM_TARGETS = 3


def _outliers_span_a_form(bl: Baseline, outliers) -> np.ndarray:
    """The outliers on features where they touch :data:`OUTLIER_FORM_TARGETS` or more distinct targets (rows)."""
    outliers = np.asarray(outliers, int)
    t = getattr(getattr(bl, "data", None), "touches", None)
    if t is None or getattr(t, "feature", None) is None or len(outliers) < OUTLIER_FORM_TARGETS:
        return outliers[:0]
    feat = np.asarray(t.feature, dtype=object)[outliers]
    tgt = np.asarray(t.target)[outliers]
    on = np.zeros(len(outliers), bool)
    for f in set(feat.tolist()):
        if f != "" and np.unique(tgt[feat == f]).size >= OUTLIER_FORM_TARGETS:
            on |= feat == f
    return outliers[on]


def _outliers_beside_kept(bl: Baseline, outliers, rows) -> np.ndarray:
    """The outliers whose target has touches kept in ``rows`` (rows)."""
    outliers = np.asarray(outliers, int)
    t = getattr(getattr(bl, "data", None), "touches", None)
    if t is None or getattr(t, "target", None) is None or outliers.size == 0:
        return outliers[:0]
    tgt = np.asarray(t.target)
    return outliers[np.isin(tgt[outliers], tgt[np.asarray(rows, int)])]


#: Whether the extended workpiece beside an unnamed smooth is offered as the estimate only when the smooth has earned
#: its held-out gain beyond doubt (True): the 95 % interval of the held-out RMS ratio of the extended model with the
#: smooth to the same model without it (:func:`_ratio_interval`, the jackknife over set-ups) lies below 1. Where it
#: reaches 1 ("no gain" inside it) the finding, its diagnosis and the smooth's fit stay, and the report's extended
#: workpiece is null (the extended fit's own under ``extended_fit_um``), the baseline's the estimate, the reason in
#: ``workpiece_not_offered`` and the summary. The smooth is adopted on the point estimate of its held-out gain against
#: materiality (step 6); that is the threshold for reporting structure, not for moving the workpiece by an effect
#: without physics. Without an interval (no cross-validation, fewer than three set-ups) it does not apply. Session 35
#: (earn35, audit35's F4): gen_a knock 0, a smooth in ``feature`` at x0.92 (95 %: 0.33-2.58) moved the workpiece
#: 0.99 -> 1.90 um against the truth, U95 max 5.6 -> 55.3 um. Off, and not proposed: on 256 tuning campaigns with an
#: extension it withholds 55 extended workpieces, 38 of them better than the baseline's (20.1 um of error in sum), 7
#: worse (1.0 um): the smooth's gain is uncertain over a campaign's few set-ups while its workpiece is right
#: (docs/discovery-studies.md, "Session 35: an extended workpiece offered only when earned").
SMOOTH_WORKPIECE_EARNED = False

#: Whether the extended workpiece is offered as the estimate only where its U95 has not grown beyond
#: :data:`WORKPIECE_U95_GROWTH_MAX` times the baseline's (True), both the RMS over the targets of the U95 (k = 2)
#: outside the part's gauge (its translation, rotation and size: :func:`core.selfcal.workpiece_gauge_basis`, as the
#: blind harness scores it and :func:`_u95_rms` judges the finer map; the per-target U95 of the report depends on the
#: map's gauge, and its largest value mostly measures that). Beyond it the baseline's workpiece is the estimate, as with
#: :data:`SMOOTH_WORKPIECE_EARNED`. The extended U95 grows where it carries a real workpiece shift of a reading the
#: data do not determine (an unnamed smooth's split, an inflated direction's, a hedged term's: u = |shift| / 2 per
#: target); three times the baseline's means the extension moved the part by about three of the baseline's own U95
#: on that assumption, and its interval holds the baseline's answer and more: an estimate the report cannot vouch for.
#: Session 35 (earn35): over 256 tuning campaigns with an extension and both workpieces reported, the ratio exceeds
#: 3 once (gen_a feed_latency 1009, 4.75: part_change? read, 13.61 um from the truth against the baseline's 4.96),
#: besides gen_a knock 0 (5.5, audit35's F4); the next are 2.85 (gen_c speed_pretravel 11, which mends the workpiece
#: 1.04 -> 0.65 um) and 2.25 (gen_a feed_latency 1003, 3.49 -> 0.47 um); no extended workpiece that mends the
#: baseline's is withheld, readings and confidence never move (the rule acts after them): docs/discovery-studies.md,
#: "Session 35: an extended workpiece offered only when earned". On since session 35 (the lead, on these tuning figures;
#: the blind set E read with it after: docs/discovery-studies.md, "The blind check of session 35").
WORKPIECE_U95_GROWTH_WITHHELD = True
#: :data:`WORKPIECE_U95_GROWTH_WITHHELD`'s factor.
WORKPIECE_U95_GROWTH_MAX = 3.0


def _u95_growth(wp) -> tuple | None:
    """(largest extended U95, largest baseline U95, their ratio) over the targets both report, um; None if none."""
    w = [r for r in wp if r.get("extended_u95_um") is not None and r.get("baseline_u95_um") is not None]
    if not w:
        return None
    e, b = max(r["extended_u95_um"] for r in w), max(r["baseline_u95_um"] for r in w)
    return e, b, (e / b if b > 0 else float("inf"))


def _u95_gauge_free(bl: Baseline, Gb, Ge, cGb, cGe) -> tuple | None:
    """(extended, baseline) RMS over the targets both determine of the workpiece's U95 (k = 2) outside the part's
    gauge, um (:data:`WORKPIECE_U95_GROWTH_WITHHELD`); None without geometry, formed covariances or six targets."""
    geo = getattr(bl, "geometry", None)
    if geo is None or not isinstance(cGb, np.ndarray) or not isinstance(cGe, np.ndarray):
        return None
    keep = np.isfinite(np.asarray(Gb, float)) & np.isfinite(np.asarray(Ge, float))
    if keep.sum() < 6 or len(keep) != len(geo[0]):
        return None
    Pm = lsq_mod.remove_span(np.eye(int(keep.sum())), selfcal.workpiece_gauge_basis(geo[0][keep], geo[1][keep]))

    def rms(C):
        C = C[np.ix_(keep, keep)]
        return float(np.sqrt(np.mean(4 * np.maximum(np.einsum("ij,jk,ik->i", Pm, C, Pm), 0)))) / UM

    return rms(cGe), rms(cGb)


def _workpiece_unearned(terms, folds, y, rows, groups, cv_e: float, held_e, wp, gauge_free=None) -> dict | None:
    """Whether the extended workpiece is offered: the figures of :data:`SMOOTH_WORKPIECE_EARNED` and
    :data:`WORKPIECE_U95_GROWTH_WITHHELD`, ``withheld`` True where a rule that is on says no (with its ``reason``,
    ``rule`` and a convention line ``text``); None without an extension. ``gauge_free`` the (extended, baseline)
    U95 of :func:`_u95_gauge_free`, or None."""
    if not terms:
        return None
    out = {"withheld": False}
    texts, rules = [], []
    smooth = [t for t in terms if t.unnamed and t.columns.shape[1]]
    if smooth:
        named = [t for t in terms if not (t.unnamed and t.columns.shape[1])]
        E_n = _stack(named, rows) if named else None
        cv_n, held_n = _held_out(folds, y[rows], groups[rows], E_n, _penalty(named) if named else None)
        ratio = float(np.sqrt(cv_e / cv_n)) if cv_n > 0 else float("nan")
        iv = _ratio_interval(held_n, held_e, ratio)
        out["smooth"] = {"covariate": smooth[0].covariate, "cv_rms_ratio": ratio, "cv_rms_ratio_95": iv}
        if SMOOTH_WORKPIECE_EARNED and iv is not None and iv[1] >= 1.0:
            rules.append("smooth_gain_interval")
            texts.append(f"the unnamed smooth in {smooth[0].covariate} has not earned its held-out gain beyond doubt "
                         f"(held-out RMS x{ratio:.2f} beside it, 95 %: {iv[0]:.2f}-{iv[1]:.2f}, reaching 1: no gain)")
    g = _u95_growth(wp)
    if g is not None:
        out["u95_max_um"] = {"baseline": g[1], "extended": g[0], "ratio": g[2]}
    if gauge_free is not None:
        e, b = gauge_free
        r = e / b if b > 0 else float("inf")
        out["u95_rms_gauge_free_um"] = {"baseline": b, "extended": e, "ratio": r}
        if WORKPIECE_U95_GROWTH_WITHHELD and r > WORKPIECE_U95_GROWTH_MAX:
            rules.append("u95_growth")
            texts.append(f"its U95 ({e:.3g} um RMS over the targets, the part's gauge removed) is {r:.3g} times the "
                         f"baseline's ({b:.3g} um), beyond {WORKPIECE_U95_GROWTH_MAX:g}")
    if rules:
        out.update(withheld=True, rule="+".join(rules), reason="; ".join(texts))
        out["text"] = ("extended workpiece not offered as the estimate: " + out["reason"] +
                       "; the baseline's workpiece is the estimate (the extended fit's under extended_fit_um)")
    return out


def _withheld_rows(wp) -> list:
    """The workpiece rows with the extended estimate withheld: ``extended_um`` and its U95 null, the fit's own kept
    under ``extended_fit_um`` and ``extended_fit_u95_um``."""
    return [{**r, "extended_um": None, "extended_u95_um": None, "extended_fit_um": r["extended_um"],
             "extended_fit_u95_um": r["extended_u95_um"]} for r in wp]


def _workpiece(bl: Baseline, terms, y, rows, st0, st, alpha: float = 0.01, doubted=None, alternatives=None,
               beside_kept=None, named=None, richer=None, forms=None, without=None, determined=None):
    """Estimand per id for the baseline and the extended model, with U95 (k = 2).

    Beside an unnamed smooth the extended U95 carries the workpiece shift
    the smooth makes when the data say it is real (:func:`_unnamed_shift`).

    ``doubted`` (optional): the rows of the outliers the report does not
    call dust with confidence that lie on a feature where they touch
    :data:`OUTLIER_FORM_TARGETS` targets or more. A particle between the
    stylus and the surface makes a touch read more material, never less
    (every generator's chips; a burr's skid reads less, alone): where the
    latter rows read both more and less material than the extended fit,
    they are not all dust. Removing a touch says it holds nothing of the
    part; an intermittent mechanism of the part (a feature relaxing in the
    campaign's first minutes: gen_a part_change 1139, the first eleven
    touches of a boss before it ovalised, removed as one event) leaves
    touches that are the part's own state. Which of the two they are is
    the removal's assumption, as the split of an unnamed effect is the
    smooth's: the shift the removal makes (the same extended model fitted
    with and without them) is tested by :func:`_unnamed_shift` and, when
    real, carried in the extended U95; the returned figures then carry
    ``of = "outliers"``. Where the smooth's shift is already carried it
    reaches the baseline's answer (the outliers in it), and nothing more is
    added.

    ``alternatives`` (optional): ``{cause: [(other cause, (n, k) columns), ...]}``, the catalogue causes a
    named cause is one explanation with under two names on this design (step 8's ``ambiguous_with``: their
    columns reproduce its signal and explain as much, the cause nothing material beyond them). The data do
    not choose between the names; where the two book the effect differently between machine and part the
    workpiece depends on the name, not on the data. The same extended model is fitted with the other
    cause's columns in the named one's place (every other term kept), its shift ``D`` of the workpiece
    tested by :func:`_unnamed_shift` against its own scatter, and, when real, carried as ``D D^T / 4``:
    two readings the data support equally, the one reported is off by 0 or by ``D`` with equal weight, a
    systematic component of standard deviation ``|D| / 2`` per target (the between-model term of a
    model-averaged variance, Burnham and Anderson 2002, sect. 4.3.2, with two equal weights); of several
    alternatives of one cause the largest real shift is carried, and the shifts of different named causes
    add (their names are separate choices). Only where no term is penalised (a smooth's or a penalised
    cause's shift is carried by its own test).

    ``richer`` (optional): ``{cause: (richer cause, build)}``, ``build()`` the (n, m) columns of a richer
    catalogue cause that nests the named one (:attr:`core.causes.Cause.richer_columns`), the combinations
    the data determine beside the other terms (:func:`_determined`, as a cause is adopted; None where
    confounded), for a named cause hedged because the richer one is significant beyond it or cannot be
    excluded (:data:`RICHER_SHIFT_CARRIED`). Tested and carried as an alternative is, in the named cause's
    place; the figures carry ``richer = True``. Both readings are under the engine's one convention (the
    determined combinations; the richer columns refitted as the fixed lobes alone shift nothing,
    session 28), so the shift is the model's: the richer fit nests the named one, its workpiece consistent
    whichever of the two is the truth, and a real shift is the named reading's bias if the richer cause is
    true, a model choice the report itself doubts. Carried as ``D D^T / 4`` like the alternatives' (u =
    ``|D| / 2``: the U95 at k = 2 reaches the richer reading at every target), not as a bias bound added
    linearly (``U95 + |D|``), which would take the richer cause for the truth the report did not name.

    ``forms`` (optional): ``{cause: [(form text, (n, m) columns), ...]}``, the named cause's other significant forms
    that pass every test, in their determined combinations, where the form adopted has a direction inflated beyond
    ``vif_max`` (:data:`FORM_SHIFT_CARRIED`): each tested and carried in its place as an alternative is (the largest
    real shift of all the cause's readings carried); the figures carry ``form = True``.

    ``without`` (optional): the hedged named causes whose own term's shift is tested (:data:`HEDGED_SHIFT_CARRIED`):
    the extended model without the cause's term is one more reading in its place, tested and carried as the
    others are; the figures carry ``without = True``. ``determined`` (optional, :data:`HEDGED_SHIFT_READING`
    ``"determined"``): ``{cause: builder}`` of such a cause's term on its determined directions only (columns, or
    None): that reading takes the place of the one without the term (figures ``determined = True``); a cause whose
    builder gives None (or none) keeps the reading without it.

    ``named`` (optional dict): filled with ``{cause: figures}`` of the alternatives' (and the richer
    causes', the other forms', the term left out's) tests.

    Returns (rows of the report, identifiable, G_b, G_e, cov_b, cov_e, shift),
    ``shift`` the test's figures (None without an unnamed smooth).
    """
    q = bl.estimand
    A0 = bl.A
    rt = getattr(bl, "rank_tol", None)  # the baseline's rank tolerance (the log's precision), None: the gauge's own
    # the linear maps (data -> parameters) serve only the shift test of an unnamed smooth or of a
    # named cause whose magnitudes this design does not determine: such a cause has, here, no more
    # physics than an unnamed smooth to say how its effect splits between machine and part, so its
    # shift of the workpiece is tested and carried alike
    smooth = any(t.penalty is not None for t in terms)
    need_maps = smooth or any(t.evidence.get("magnitudes_not_determined") for t in terms)
    gb, cb, eb, *lin = _constrained(A0, y, bl.C, bl.d, np.arange(bl.n), None, 0, linear_map=need_maps, tol=rt)
    # a named cause enters with the combinations the data determine (its map)
    E = np.hstack([t.columns @ t.map if t.map is not None else t.columns for t in terms]) if terms \
        else np.zeros((bl.n, 0))
    A1 = np.hstack([A0, E])
    C1 = np.hstack([bl.C, np.zeros((bl.C.shape[0], E.shape[1]))])
    P = None
    d1 = bl.d
    if smooth:
        P = np.zeros((E.shape[1], E.shape[1]))
        pen = np.zeros(A1.shape[1], bool)
        o = A0.shape[1]
        for t in terms:
            k = t.map.shape[1] if t.map is not None else t.columns.shape[1]
            if t.penalty is not None:
                P[o - A0.shape[1]:o - A0.shape[1] + k, o - A0.shape[1]:o - A0.shape[1] + k] = t.penalty
                pen[o:o + k] = True
            o += k
        C1, d1 = _smooth_gauge(A1, C1, d1, rows, pen, rt)
    if not E.shape[1] and P is None and len(rows) == bl.n and np.array_equal(rows, np.arange(bl.n)):
        # nothing extends the baseline and no row is left out: the extended fit is the baseline's, the same system
        # solved again (A1 is A0, C1 a copy of its gauge rows); at 1e6 rows it was a second normal matrix's
        # elimination beside the first's (session 23)
        ge, ce, ee, lin_e = gb, cb, eb, list(lin)
    else:
        ge, ce, ee, *lin_e = _constrained(A1, y, C1, d1, rows, P, E.shape[1], linear_map=need_maps, tol=rt)
    shift = None
    if P is not None:
        # the penalty's ridge rows make every parameter formally estimable:
        # the extended workpiece is an estimate only where the data alone
        # determine it (else the penalty's strength, not the campaign, decides)
        ee = ee & _constrained(A1, y, C1, d1, rows, None, 0, tol=rt)[2]
    if need_maps:
        ce, shift = _unnamed_shift(bl, rows, gb, ge, ce, lin[0], lin_e[0], lin_e[1], eb & ee[:len(eb)], alpha)
    if doubted is not None:
        r_form = y[doubted] - A1[doubted] @ ge  # the rows on a feature's form against the fit without them
        if not (np.any(r_form > 0) and np.any(r_form < 0)):
            doubted = None
    if beside_kept is not None and len(beside_kept):
        # removed touches of a target whose other touches were kept, reading less material than the fit (which
        # those kept touches make there): no particle reads less, and a particle under the kept ones would make
        # them read more; which of the target's touches are the part's is then the removal's assumption
        beside_kept = np.asarray(beside_kept, int)
        below = beside_kept[(y[beside_kept] - A1[beside_kept] @ ge) < 0]
        if below.size:
            doubted = below if doubted is None else np.union1d(doubted, below)
    if doubted is not None and not (shift is not None and shift["carried_in_u95"]):
        # the same extended model with the form's outliers put back (only those: a chip elsewhere is no reading
        # of the part's form, and putting it back would count its own shift) against it without them
        back = np.union1d(rows, doubted) if OUTLIER_REFIT_FORM_ONLY else np.arange(bl.n)
        ga, _, ea, La_b, _ = _constrained(A1, y, C1, d1, back, P, E.shape[1], linear_map=True, tol=rt)
        La = np.zeros((La_b.shape[0], bl.n))
        La[:, back] = La_b
        if not need_maps:
            lin_e = _constrained(A1, y, C1, d1, rows, P, E.shape[1], linear_map=True, tol=rt)[3:]
        ce2, sh2 = _unnamed_shift(bl, rows, ga[:len(eb)], ge, ce, La[:len(eb)], lin_e[0], lin_e[1],
                                  ea[:len(eb)] & ee[:len(eb)], alpha)
        if sh2 is not None and sh2["carried_in_u95"]:
            ce, shift = ce2, dict(sh2, of="outliers", beside=shift)  # (the smooth's figures kept for the report)
    named = {} if named is None else named
    if (alternatives or richer or forms or without) and P is None and isinstance(ce, np.ndarray):
        Le_map, s2e = (lin_e[0], lin_e[1]) if need_maps else \
            _constrained(A1, y, C1, d1, rows, None, E.shape[1], linear_map=True, tol=rt)[3:]
        o = 0
        for t in terms:
            k = t.map.shape[1] if t.map is not None else t.columns.shape[1]
            best = None
            # each reading takes the named cause's place: an alternative's columns, a richer cause's (built here)
            readings = [(other, B, False) for other, B in (alternatives or {}).get(t.cause, ())]
            if t.cause in (richer or {}):
                B = richer[t.cause][1]()
                if B is not None and B.shape[1]:
                    readings.append((richer[t.cause][0], B, True))
            readings += [(f"{t.cause} as {text}", B, "form") for text, B in (forms or {}).get(t.cause, ())
                         if B.shape[1]]
            if not t.unnamed and t.cause in (without or ()):
                Bd = determined[t.cause]() if t.cause in (determined or {}) else None
                readings.append((f"{t.cause} on its determined directions", Bd, "determined") if Bd is not None
                                and Bd.shape[1] else (f"no {t.cause}", E[:, :0], "without"))
            for other, B, nests in readings:
                Ea = np.hstack([E[:, :o], B, E[:, o + k:]])
                Aa = np.hstack([A0, Ea])
                Ca = np.hstack([bl.C, np.zeros((bl.C.shape[0], Ea.shape[1]))])
                # the other cause takes no combination the rest of the model spans exactly (the smooth's gauge,
                # _smooth_gauge: its layout is raw columns, the named cause's its determined combinations)
                on_b = np.zeros(Aa.shape[1], bool)
                on_b[A0.shape[1] + o:A0.shape[1] + o + B.shape[1]] = True
                Ca, da = _smooth_gauge(Aa, Ca, bl.d, rows, on_b, rt)
                ga, _, ea, La_r, _ = _constrained(Aa, y, Ca, da, rows, None, Ea.shape[1], linear_map=True, tol=rt)
                La = np.zeros((La_r.shape[0], bl.n))
                La[:, rows] = La_r
                p0 = len(eb)
                ce_a, fig = _unnamed_shift(bl, rows, ga[:p0], ge, ce, La[:p0], Le_map, s2e, eb & ee[:p0] & ea[:p0],
                                           alpha)
                if fig is None:
                    continue
                fig = dict(fig, alternative=other, **({"form": True} if nests == "form" else
                                                      {"without": True} if nests == "without" else
                                                      {"without": True, "determined": True}
                                                      if nests == "determined" else
                                                      {"richer": True} if nests else {}))
                if best is None or (fig["carried_in_u95"], fig["shift_rms_um"]) > (best[1]["carried_in_u95"],
                                                                                   best[1]["shift_rms_um"]):
                    best = (ce_a - ce, fig)
            if best is not None:
                named[t.cause] = best[1]
                if best[1]["carried_in_u95"]:
                    ce = ce + best[0]
            o += k
    out = []
    vb, ve = cb.diagonal(), ce.diagonal()
    for i, tid in enumerate(bl.estimand_ids):
        j = q[i]
        out.append({"target": tid,
                    "baseline_um": float(gb[j]) / UM if eb[j] else None,
                    "extended_um": float(ge[j]) / UM if ee[j] else None,
                    "baseline_u95_um": float(2 * np.sqrt(max(vb[j], 0))) / UM if eb[j] else None,
                    "extended_u95_um": float(2 * np.sqrt(max(ve[j], 0))) / UM if ee[j] else None})
    ident = bool(np.all(eb[q]) and np.all(ee[q]))

    def on_q(c):  # the estimand's block (a long log's kept factored: q x q is 800 MB at 10,000 targets)
        return c.take(q) if isinstance(c, DiagLowRank) else c[np.ix_(q, q)]

    return (out, ident, np.where(eb[q], gb[q], np.nan), np.where(ee[q], ge[q], np.nan), on_q(cb), on_q(ce), shift)


def _unnamed_shift(bl, rows, gb, ge, ce, Lb, Le, s2, est, alpha):
    """The workpiece shift an unnamed smooth makes, its test, and the extended covariance that carries it.

    An unnamed smooth has no physics: how the unknown effect splits between
    the machine, the probe and the part is the smooth's form, not a
    measurement (a named cause books its effect by its model). Its shift
    ``D = G_e - G_b`` of the workpiece (what self-calibration can see: the
    part's translation, rotation, scale and size removed, eqs 16-17) is
    tested against its own covariance ``s^2 (L_e - L_b)(L_e - L_b)^T``
    (both estimates are linear in the data, ``G = L y``; the test of
    Hausman 1978 for two estimators of one quantity), chi-square at
    ``alpha``. A shift the data do not support is noise, already in the
    extended U95. A real one says the effect moves the workpiece by as much
    as the smooth's assumed split: that split is a systematic component of
    the extended workpiece's uncertainty, added as ``D D^T / 4`` (fully
    correlated, ``u = |D| / 2`` per target: the U95, k = 2, reaches the
    baseline's answer at each target).

    ``Lb`` (p, n) and ``Le`` (p, len(rows)) map the data to the baseline's
    and the extended parameters (:func:`_constrained`), ``s2`` the extended
    fit's residual variance. Returns (cov_e, figures): the covariance of all
    parameters (only the estimand block changed) and a JSON-friendly dict of
    the test.
    """
    q = np.unique(bl.estimand)
    q = q[est[q]]
    if q.size == 0:
        return ce, None
    n = bl.n
    Le_n = np.zeros((Le.shape[0], n))
    Le_n[:, rows] = Le
    L = Le_n[q] - Lb[q]
    D = ge[q] - gb[q]
    if getattr(bl, "geometry", None) is not None:
        Pw, Nw = bl.geometry
        idx = {j: i for i, j in enumerate(bl.estimand)}  # geometry rows follow the estimand ids
        Gq = selfcal.workpiece_gauge_basis(Pw[[idx[j] for j in q]], Nw[[idx[j] for j in q]])
        Qg = orth(Gq)
        proj = np.eye(q.size) - Qg @ Qg.T
    else:
        proj = np.eye(q.size)
    Dv, Lv = proj @ D, proj @ L
    U, sv, _ = np.linalg.svd(Lv, full_matrices=False)
    good = sv > 1e-9 * sv.max(initial=0.0)
    r = int(good.sum())
    z = (U[:, good].T @ Dv) / sv[good]
    chi2 = float(z @ z) / max(s2, 1e-300) if r else 0.0
    p_val = float(stats.chi2.sf(chi2, r)) if r else 1.0
    real = p_val < alpha
    fig = {"shift_rms_um": float(np.sqrt(np.mean(Dv ** 2))) / UM, "chi2": chi2, "dof": r, "p": p_val,
           "alpha": alpha, "carried_in_u95": bool(real)}
    if not real:
        return ce, fig
    ce = ce.copy()
    ce[np.ix_(q, q)] += np.outer(D, D) / 4.0
    return ce, fig


def _smooth_gauge(A, C, d, rows, pen, tol=None):
    """Gauge rows for a penalised (smooth) term: it takes no combination the rest of the model spans exactly.

    A smooth basis (B-splines sum to one, per set-up modes) can reproduce
    exactly some of the baseline's columns (a set-up's offset, the size of
    the part): along those directions the fitted values do not change and
    only the penalty would split the signal between the workpiece and the
    smooth. Each such null direction of the unpenalised system that moves
    the smooth's coefficients (``pen``) is fixed by one row ``K theta = 0``
    on those coefficients: what the baseline can represent stays the
    baseline's. The fitted values are unchanged (only null directions are
    pinned). Returns (C, d) with the rows appended.
    """
    p = A.shape[1]
    Ns = _gauge_svd(A[rows], C, tol)[-1][pen]
    if Ns.shape[1] == 0:
        return C, d
    K = orth(Ns).T  # (r, n_pen)
    rows_K = np.zeros((K.shape[0], p))
    rows_K[:, pen] = K
    return np.vstack([C, rows_K]), np.concatenate([d, np.zeros(K.shape[0])])


#: The gauge's singular-value cut (:func:`_gauge_svd`, :func:`_gauge_eig`): a direction of the column-scaled design in
#: the gauge's null space below this share of the largest is unseen; a baseline's ``rank_tol`` (the log's precision,
#: :func:`core.baseline.precision_rank_tol`) raises it, never lowers it.
GAUGE_SV_TOL = 1e-6


def _gauge_svd(Ar: np.ndarray, C: np.ndarray, tol: float | None = None):
    """The gauge's null space and the SVD of the design in it: what :func:`_constrained` and :func:`_smooth_gauge` solve by.

    ``theta = theta0 + Z phi`` with ``C Z = 0`` (``Z`` from the SVD of
    ``C``, rank at 1e-12 of its largest singular value; the identity
    without gauge rows); ``M = Ar Z`` with its columns scaled by ``sc``;
    its thin SVD ``U s Vt``; ``good`` the singular values above
    :data:`GAUGE_SV_TOL` (or ``tol``, the baseline's ``rank_tol``, where
    larger) of the largest. ``null`` (p, m): the parameter directions the rows do not
    see, ``Z Vt[~good]^T / sc``, and, when ``M`` has more columns than rows
    (a thin SVD has only as many directions as rows), every direction
    beyond them as well (the full SVD's remaining rows of ``Vt``): those
    are unseen too.

    Returns (Z, sc, U, s, Vt, good, null).
    """
    p = Ar.shape[1]
    Z = _gauge_svd_z(C, p)
    if isinstance(Ar, BlockDesign):
        return _gauge_eig(Ar.gram(), Z, tol)
    M = Ar @ Z
    sc = np.linalg.norm(M, axis=0)
    sc = np.where(sc > 0, sc, 1.0)
    U, s, Vt = np.linalg.svd(M / sc, full_matrices=False)
    good = s > (_gauge_cut(tol) * s.max() if s.size else 0.0)
    Vn = Vt[~good]
    if M.shape[1] > s.size:  # more unknowns than rows: the rest is null too
        Vn = np.vstack([Vn, np.linalg.svd(M / sc)[2][s.size:]])
    null = Z @ (Vn.T / sc[:, None]) if Vn.shape[0] else np.zeros((p, 0))
    return Z, sc, U, s, Vt, good, null


def _gauge_cut(tol: float | None) -> float:
    """The relative singular-value cut of the gauge: :data:`GAUGE_SV_TOL`, or a baseline's larger ``rank_tol``."""
    return GAUGE_SV_TOL if tol is None else max(GAUGE_SV_TOL, tol)


def _gauge_eig(N: np.ndarray, Z: np.ndarray, tol: float | None = None):
    """:func:`_gauge_svd` from the normal matrix ``N = A^T A`` (p, p) of a block design (a long log).

    The SVD of the column-scaled ``A Z`` from the eigen-decomposition of
    ``Z^T N Z`` scaled: the same singular values (``s = sqrt(w)``) and right
    vectors, no left ones (``U`` is None: the callers form what they need
    from ``A^T``). Squaring the design costs precision: a direction near the
    1e-6 cut keeps about 4 digits where the SVD keeps 10; the rows stay
    unfactored (n x p never formed).
    """
    NZ = Z.T @ N @ Z
    sc = np.sqrt(np.maximum(np.diag(NZ), 0.0))
    sc = np.where(sc > 0, sc, 1.0)
    w, V = np.linalg.eigh(NZ / np.outer(sc, sc))
    w, V = w[::-1], V[:, ::-1]  # decreasing, as an SVD's
    s = np.sqrt(np.maximum(w, 0.0))
    good = s > (_gauge_cut(tol) * s.max() if s.size else 0.0)
    Vt = V.T
    null = Z @ (Vt[~good].T / sc[:, None]) if (~good).any() else np.zeros((Z.shape[0], 0))
    return Z, sc, None, s, Vt, good, null


def _constrained_blocks(A: BlockDesign, y, C, d, rows, penalty, k_ext, linear_map=False, tol=None):
    """:func:`_constrained` for a block design: the same solution from its normal matrix.

    Without the linear map, the targets eliminated (:func:`_constrained_schur`) where the
    system is well posed in the gauge; else (and for the map) from the whole normal
    matrix (:func:`_gauge_eig`), ``p x p`` numbers several times over.
    """
    every = len(rows) == len(A) and np.array_equal(rows, np.arange(len(A)))
    Ar = A if every else A[rows]  # (every row: no copy of the dense block)
    yr = y[rows]
    p = A.shape[1]
    if not linear_map:
        out = _constrained_schur(Ar, yr, C, d, penalty, k_ext, tol)  # (well posed: every direction far above any cut)
        if out is not None:
            return out
    N = Ar.gram()
    if penalty is not None and k_ext:  # the ridge rows R (R^T R = the penalty's non-negative part)
        w, V = np.linalg.eigh(penalty)
        N[p - k_ext:, p - k_ext:] += (V * np.maximum(w, 0)) @ V.T
    theta0 = np.linalg.lstsq(C, d, rcond=None)[0] if C.shape[0] else np.zeros(p)
    Z, sc, _, s, Vt, good, null = _gauge_eig(N, _gauge_svd_z(C, p), tol)
    Vg = Vt[good].T / sc[:, None]
    Atb = Ar.T @ yr - N @ theta0  # A^T (b) with b = y - A theta0 (the ridge rows' part included)
    phi = Vg @ ((Vg.T @ (Z.T @ Atb)) / s[good] ** 2)
    theta = theta0 + Z @ phi
    res = yr - Ar @ theta
    dof = max(len(rows) - int(good.sum()), 1)
    s2 = float(res @ res) / dof
    T = Z @ (Vg / s[good])
    cov = s2 * (T @ T.T)
    est = _estimable(null, p)
    if linear_map:  # theta per unit of y[rows]: (p, len(rows)), dense
        W = T @ (Z @ (Vg / s[good])).T
        return theta, cov, est, (Ar @ W.T).T, s2
    return theta, cov, est


#: :func:`_constrained_schur` solves by eliminating the targets only where the equilibrated reduced system's
#: condition number is below this; above it (near the 1e12 of :func:`_gauge_eig`'s singular-value cut, 1e-6
#: squared) the whole normal matrix decides which directions are unseen, as before.
SCHUR_COND_MAX = 1e8
#: With a baseline's ``rank_tol`` (the log's printed precision, :func:`core.baseline.precision_rank_tol`), the
#: elimination also needs the equilibrated condition number below ``1 / (SCHUR_TOL_MARGIN * cut)^2``, ``cut`` the
#: gauge's (:func:`_gauge_cut`: ``max(GAUGE_SV_TOL, tol)``): a direction within this factor of the cut is the whole
#: normal matrix's to decide (without a ``rank_tol``, or below 1e-5, ``SCHUR_COND_MAX`` is the smaller).
#: Measured (session 30, rank30b, review30c's two plate logs at full precision and 5, 4, 3 decimals on
#: every grid: 40 designs): the condition number is 1.3-2.9 times ``(s_max / s_min)^2`` of the gauge's singular
#: values (1.1 with a near-collinear extension at 2 decimals: the test's), the elimination ran on the 20 designs
#: whose smallest gauge direction is 0.016-0.036 of the largest (condition 2.2e3-5.2e3, far below
#: ``1 / (10 tol)^2`` = 6.9e5 even at 3 decimals) and agreed with the dense fit to 5e-14; on the other 20 (a
#: direction cut) the condition number is 1e17 and up. None: off (SCHUR_COND_MAX only).
SCHUR_TOL_MARGIN: float | None = 10.0


def _constrained_schur(Ar: BlockDesign, yr, C, d, penalty, k_ext, tol=None):
    """:func:`_constrained_blocks` with the targets eliminated: (theta, cov, est), or None where it does not apply.

    The gauge-constrained least squares is the saddle-point system
    ``[[N, C^T], [C, 0]] [theta; lam] = [A^T y; d]`` (``C`` reduced to its
    row space, the rows of :func:`_gauge_svd_z`'s complement). ``N``'s
    target block is diagonal (each target's count of rows), so the targets
    eliminate exactly: the Schur complement ``S`` over the machine's columns
    and the gauge's multipliers (``m + r`` square: 366 at the bench's 1e6 rows
    against 10,356 parameters). Where the system is well posed in the gauge
    (every target seen, ``S``'s equilibrated condition number below
    :data:`SCHUR_COND_MAX`) the null-space method of :func:`_constrained`
    keeps every direction (nothing below its cut) and has this unique
    solution; the covariance ``s^2 Z (Z^T N Z)^-1 Z^T`` is the top-left block
    of the saddle matrix's inverse, ``s^2 (diag(1 / count) + L S^-1 L^T)``
    on the targets and the machine (:class:`core.lsq.DiagLowRank`, never
    ``p x p``); every parameter estimable. Else None: the caller decides
    from the whole normal matrix which directions are unseen. ``tol``: the
    baseline's rank tolerance (the gauge's cut): the elimination also needs
    the condition number below ``1 / (SCHUR_TOL_MARGIN max(1e-6, tol))^2``.
    """
    p, g = Ar.shape[1], Ar.g
    gc, dc = Ar.g_cols, Ar.d_cols
    cnt = np.bincount(Ar.ids, minlength=g).astype(float)
    if np.any(cnt == 0):  # a target no row sees: unseen, the whole normal matrix says which
        return None
    theta0 = np.linalg.lstsq(C, d, rcond=None)[0] if C.shape[0] else np.zeros(p)
    VtC, r = _gauge_rows_svd(C, p, full=False)
    Cr = VtC[:r]  # (r, p) orthonormal rows: C theta = d is Cr theta = Cr theta0
    dr = Cr @ theta0
    m = len(dc)
    M = _dense(Ar.D.T @ Ar.D)
    pos, Pen = np.zeros(0, int), np.zeros((0, 0))
    if penalty is not None and k_ext:  # the ridge rows on the design's last k_ext columns (the extension's)
        w, V = np.linalg.eigh(penalty)
        at = np.empty(p, int)
        at[dc] = np.arange(m)
        pos = at[p - k_ext:]  # where the design's columns p - k_ext .. p - 1 sit in the machine block
        Pen = (V * np.maximum(w, 0)) @ V.T
        M[np.ix_(pos, pos)] += Pen
    F = np.hstack([group_sums(Ar.ids, g, Ar.D), Cr[:, gc].T])  # (g, m + r)
    H = np.zeros((m + r, m + r))
    H[:m, :m] = M
    H[:m, m:] = Cr[:, dc].T
    H[m:, :m] = Cr[:, dc]
    Fc = F / cnt[:, None]
    S = H - F.T @ Fc
    sc = 1.0 / np.sqrt(np.maximum(np.abs(S).max(axis=1), 1e-300))  # rows and columns equilibrated (a multiplier's
    # diagonal is zero where its gauge row holds no target)
    cond_max = SCHUR_COND_MAX
    if SCHUR_TOL_MARGIN is not None:  # (the gauge's own 1e-6 cut gives 1e10: SCHUR_COND_MAX decides there)
        cond_max = min(cond_max, 1.0 / (SCHUR_TOL_MARGIN * _gauge_cut(tol)) ** 2)
    if not np.isfinite(S).all() or np.linalg.cond(S * np.outer(sc, sc)) > cond_max:
        return None
    Si = np.linalg.inv(S)
    theta = np.zeros(p)
    res = yr
    for _ in range(2):  # the solve, then once more on its residuals (one step of refinement: the normal
        # equations square the conditioning; the step takes the rows' own residuals back to the dense SVD's)
        bt = group_sums(Ar.ids, g, res)
        bm = _dense(Ar.D.T @ res)
        bm[pos] -= Pen @ theta[dc][pos]  # the ridge rows' residuals (their data are zeros)
        z = Si @ (np.concatenate([bm, dr - Cr @ theta]) - Fc.T @ bt)
        theta[gc] += bt / cnt - Fc @ z
        theta[dc] += z[:m]
        res = yr - Ar @ theta
    dof = max(len(yr) - (p - r), 1)
    s2 = float(res @ res) / dof
    L = np.zeros((p, m + r))
    L[gc] = -Fc
    L[dc, np.arange(m)] = 1.0
    dg = np.zeros(p)
    dg[gc] = 1.0 / cnt
    return theta, DiagLowRank(dg, L, (Si + Si.T) / 2, s2), np.ones(p, bool)


def _estimable(null: np.ndarray, p: int) -> np.ndarray:
    """(p,) bool: the parameters no unseen direction (``null``'s columns) moves."""
    if not null.shape[1]:
        return np.ones(p, bool)
    return np.linalg.norm(orth(null), axis=1) < 1e-6


def _gauge_rows_svd(C: np.ndarray, p: int, full: bool = True) -> tuple[np.ndarray, int]:
    """The gauge rows ``C`` (r0, p) by their SVD: ``(Vt, r)``, ``r`` the rank at 1e-12 of the largest singular
    value, ``Vt[:r]`` orthonormal rows spanning ``C``'s row space and, with ``full`` (p x p), ``Vt[r:]`` its null
    space (the identity without gauge rows); without ``full`` only ``min(r0, p)`` rows (a long log's ``p`` is
    10,356: the full ``Vt`` would be 858 MB)."""
    if not C.shape[0]:
        return (np.eye(p) if full else np.zeros((0, p))), 0
    _, sC, VtC = np.linalg.svd(C, full_matrices=full)
    return VtC, int(np.sum(sC > 1e-12 * max(sC.max(initial=0), 1e-300)))


def _gauge_svd_z(C: np.ndarray, p: int) -> np.ndarray:
    """The null space ``Z`` of the gauge rows (as :func:`_gauge_svd` takes it)."""
    VtC, rC = _gauge_rows_svd(C, p)
    return VtC[rC:].T


def _constrained(A, y, C, d, rows, penalty, k_ext, linear_map=False, tol=None):
    """Gauge-constrained least squares with covariance and per-parameter estimability.

    Null-space method: ``theta = theta0 + Z phi`` with ``C theta = d``;
    ``phi`` by the pseudo-inverse of the column-scaled ``A Z`` (plus the
    ridge rows of a penalised term). A parameter is estimable when no
    direction the data cannot see moves it. sigma from the residuals.
    With ``linear_map`` also ``L`` (p, len(rows)), ``theta = theta0 + L y[rows]``
    (the estimate is linear in the data, penalised or not), and ``s^2``.
    A :class:`core.lsq.BlockDesign` (a long log) is solved from its normal
    matrix (:func:`_constrained_blocks`).
    """
    if isinstance(A, BlockDesign):
        return _constrained_blocks(A, y, C, d, rows, penalty, k_ext, linear_map, tol)
    Ar = A[rows]
    yr = y[rows]
    p = A.shape[1]
    if penalty is not None and k_ext:
        w, V = np.linalg.eigh(penalty)
        R = (V * np.sqrt(np.maximum(w, 0))).T
        Ar = np.vstack([Ar, np.hstack([np.zeros((k_ext, p - k_ext)), R])])
        yr = np.concatenate([yr, np.zeros(k_ext)])
    theta0 = np.linalg.lstsq(C, d, rcond=None)[0] if C.shape[0] else np.zeros(p)
    Z, sc, U, s, Vt, good, null = _gauge_svd(Ar, C, tol)
    Vg = Vt[good].T / sc[:, None]  # (nz, r): phi = Vg diag(1/s) U^T b
    b = yr - Ar @ theta0
    phi = Vg @ ((U[:, good].T @ b) / s[good])
    theta = theta0 + Z @ phi
    res = yr - Ar @ theta
    dof = max(len(rows) - int(good.sum()), 1)
    s2 = float(res[:len(rows)] @ res[:len(rows)]) / dof
    T = Z @ (Vg / s[good])  # theta per unit of U^T b
    cov = s2 * (T @ T.T)
    est = _estimable(null, p)
    if linear_map:
        return theta, cov, est, T @ U[:len(rows), good].T, s2
    return theta, cov, est
