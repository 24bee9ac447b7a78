"""The tuning constants of analysis/ (what the solver relies on: fits, the bracket of the
smallest error bound): groups of `Settings` (settings.py), kept apart so that settings.py
stays a size a reader can hold. Every field says why it has its value."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FitSettings:
    """The fits and the rules over them (analysis/chebyshev.py, priors.py, leverage.py,
    unit_spreads.py)."""

    # A Chebyshev fit: at most chebyshev_lps linear programs lowering the largest residual,
    # each step within chebyshev_trust of the domains; a step that did not lower it makes
    # the next chebyshev_shrink as long (the model was not linear over it), and the fit
    # stops once its steps would be under chebyshev_min_trust.
    chebyshev_lps: int = 8
    chebyshev_trust: float = 0.5
    chebyshev_shrink: float = 0.25
    chebyshev_min_trust: float = 1e-4
    # The least-squares estimate that centres `lsq +- w` domains (priors.py): evaluations of
    # the residuals at most; from a far start it needs more than 30.
    prior_evaluations: int = 200
    # The least-squares estimate a search starts from (the conflict search's ranking, the
    # priors and units at fault, a Chebyshev fit, advice, the reference hull): from the
    # domains' middle, far from the data's fit, it needs more evaluations than a polish.
    lsq_evaluations: int = 200
    # A data row carrying more than leverage_share of a parameter's estimate is reported;
    # directions the data see less than leverage_rcond (relative) are not estimated.
    leverage_share: float = 0.5
    leverage_rcond: float = 1e-8
    unit_near: float = 1.5  # a spread ratio within this factor of a unit's factor names it


@dataclass(frozen=True)
class MinErrorSettings:
    """The bracket of the smallest consistent error bound (analysis/min_error.py)."""

    binding: float = 0.01  # a row within this share of the bound's value binds it
    steps: tuple[float, ...] = (1.02, 1.05, 1.1, 1.25, 1.5, 2.0, 4.0)  # lower trials: hi / these
    max_solves: int = 8  # tight solves to prove the lower end, at most
    # A bracket wider than this (hi / lo - 1) gets `proofs` more trials, each a solve and,
    # where it leaves the trial open, a proof effort: the 2 % every shipped model is to meet.
    wide: float = 0.02
    proofs: int = 4
    goal_inside: float = 1e-6  # the goal trial sits this share above hi / (1 + wide): rounded
    certify_tries: int = 4  # raises of the bound by the point's excess before hi gives up
    # A trial the solve leaves open gets at most this share of the solve's time for a proof
    # (fine rounds, a split): the lower end is only as high as the highest bound proven
    # infeasible, and a fine round with the readings as LP columns, the one that proves
    # most, costs about ten solves where parameters the data cannot separate keep their
    # whole domains (the solve is quick, its rounds over them loose).
    share: float = 12.0


@dataclass(frozen=True)
class OutlierSettings:
    """Solves with at most K rows at fault (outliers/solve.py, outliers/proof.py)."""

    # Rounds of LPs over the relaxations that let at most K rows fail: a round that narrows
    # no unknown by `gain` of its width ends them; LP pivots per objective (a stopped LP
    # still certifies a weaker bound).
    gain: float = 0.01
    max_rounds: int = 40
    lp_iterations: int = 5000
    most_sets: int = 4  # tight solves of sets of rows at most, unless K + 1 are needed
    # With suspects in groups of their own, the sets at most (k = 1: four suspects): with the
    # rows at fault alone, the sets that leave one out are consistent and the others refuted,
    # which names exactly those rows (docs/decisions/16).
    most_suspect_sets: int = 8
    suspect_residual: float = 1.0  # a least-squares residual above this many bounds: a suspect
    deal_seed: int = 0  # the shuffle that deals the other rows into groups (fixed: results repeat)
    extra_suspects: int = 3  # suspects beyond k (as many as most_suspect_sets allows)
    # Rows proven outliers before any LP (proof.py): candidates tried beyond K (a candidate
    # may fail to be proven), and the least residual (in error bounds) of a candidate: a row
    # the least-squares fit satisfies is none.
    extra_candidates: int = 2
    min_residual: float = 1.0
    # Naming what makes data inconsistent (conflict.py): rows left out at most (each count
    # k tries the k worst rows; beyond a few, the fault is rarely rows);
    conflict_rows: int = 3
    # the widened domains that test the priors (prior_faults.py): this many times the
    # declared half-widths, far enough for a wrong prior's value, near enough to fit from;
    prior_widen: float = 10.0
    # the units (unit_hints.py): least squares leaves data drawn within their bounds with
    # most residuals near a bound (the largest just over it), and this quantile of them
    # measures the bound, a few gross rows aside; a bound in the wrong unit leaves more than
    # unit_most of the rows beyond it; a joint turns at most unit_turns turns either way (a
    # UR's limits are +- 2 pi), readings beyond are not radians; the robust fit takes at
    # most unit_evaluations evaluations from the least-squares estimate (nearby).
    unit_quantile: float = 0.9
    unit_most: float = 0.5
    unit_turns: int = 2
    unit_evaluations: int = 50
