"""Every tuning constant of the solver, named once, with why it has its value.

A strategy receives one frozen `Settings` from its caller and hands the parts its contractors
need down to them; the constants of one concern form a group of their own (`LPSettings`,
`RoundsSettings`, `SamplingSettings`, `OutlierSettings`, `InnerSettings`: `GROUPS`), and
`tuned(name=value)` sets any field by its own name. Only the pipeline, the API and the
command line read `DEFAULT`: below them every function takes its caller's settings, and a
number bound at module level there is arithmetic, not a tuning (tests/test_house.py,
`NOT_TUNING`). analysis/'s groups (`FitSettings`, `MinErrorSettings`) live in
settings_analysis.py, which keeps this module a size a reader can hold. These are choices of
speed against tightness; none of them can make a result unsound (soundness rests on outward
rounding, which has no knobs). Input limits that guard against runaway models live with the
front end and the elaborator, not here.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, fields, replace
from typing import Any

from calib_dsl.settings_analysis import FitSettings, MinErrorSettings, OutlierSettings
from calib_dsl.settings_strategy import BlockSettings, LooseSettings


# The cores the solver's LP threads, chunk threads and piece processes share: CALIBC_CORES
# when set (the test suite sets 1 in each pytest-xdist worker, as the workers fill the
# cores), else this machine's. Results do not depend on it.
def _cores() -> int:
    text = os.environ.get("CALIBC_CORES", "").strip()
    if not text:
        return os.cpu_count() or 1
    if not (text.isascii() and text.isdigit()) or int(text) < 1:  # ("²" is a digit to str)
        # read once at import, before any command runs: a user error all the same
        print(f"error: CALIBC_CORES must be a whole number of cores, 1 or more (not {text!r})",
              file=sys.stderr)
        raise SystemExit(2)
    return int(text)


CORES = _cores()


@dataclass(frozen=True)
class LPSettings:
    """HiGHS and the certified bounds over its LPs (lp/)."""

    workers: int = min(2, CORES)  # HiGHS models solved in parallel threads
    # Per objective in a first-order round: a degenerate LP near the fixed point can crawl.
    # The pivot limit stops it the same way on every machine (results do not depend on
    # load); the time limit is a backstop.
    iterations: int = 1000
    seconds: float = 1.0
    # Above this many rows an LP starts from a subset and adds the rows its optimum violates
    # (row generation), at most rows_added per pass: a tall LP (9000 rows, 33 columns) is
    # far faster so.
    rows_at_once: int = 2000
    rows_added: int = 500
    # HiGHS's simplex_strategy for such an LP with at least tall_primal_columns columns:
    # primal. Each objective starts from the last one's optimum, which a new cost leaves
    # primal feasible, so the primal simplex needs fewer pivots than the dual. With few
    # columns the dual stays faster, and on LPs that hold all their rows (docs/decisions/06).
    tall_simplex: int = 4
    tall_primal_columns: int = 64
    scaling: int = 0  # HiGHS's simplex_scale_strategy: none (the bounds are certified anyway)
    probes: int = 4  # at most this many probe LPs before the objectives are shared out
    # Above this many matrix entries (or for a sparse matrix and few objectives), certified
    # bounds work row by row of the multipliers on the sparse matrix, not on a dense copy.
    dense_entries: int = 4_000_000


@dataclass(frozen=True)
class InnerSettings:
    """Certified inner bounds (inner/bounds.py, inner/lp.py)."""

    # Each row aims inside this share of its bound: room for the rounding and for the
    # remainder of the linearization at the LP's optimum, which is of this order near a thin
    # solution set; aiming deeper costs the ends width (docs/decisions/14).
    aim: float = 1.0 - 1e-5

    # A failed LP optimum is pulled back towards the centre only where that costs the end at
    # most this share of the unknown's width; else its LP is re-solved with the failed rows
    # tightened, which loses less of the end than a long pull-back (docs/decisions/14)
    pulled: float = 1e-3
    # Ends per wave: their LPs shared among the threads, their points checked in one pass (a
    # pass over many points costs little more than one check); a narrower wave leaves the
    # threads idle, a wider one runs LPs for ends that an earlier wave's points would have
    # reached (docs/decisions/14)
    wave: int = 16
    corrections: int = 6  # re-solves of an end's LP with the rows the check found violated
    escalate: float = 4.0  # how much more a row that fails again is tightened
    overshoot: float = 2.0  # a violated row is tightened by this many times its excess
    # An end that a certified point reaches to within this share of the outer width gets no
    # LP of its own (an earlier end's LP often puts the other unknowns at their bounds,
    # notably those known beforehand as well as the data know them). The ends an LP finds
    # fall about as short, so a tighter share buys LPs, not width
    reached: float = 1e-3
    computed_aim: float = 1e-3  # the first tightening of a failed row between computed values
    pullbacks: int = 10  # halvings towards the centre when the corrections did not succeed
    # An end whose certified point falls short of its LP's optimum by more than this share of
    # the unknown's width (the remainder made the corrections pull it in) is sought again
    # over the model linearized at that point, where the remainder is small (a tall LP from
    # the rows the first LPs came to hold: docs/decisions/31). A smaller share seeks more ends
    # again for no wider inner interval, a larger one leaves ends short (docs/decisions/14)
    refine: float = 1e-2
    # Linearizations of such an end at most, each at the point the last one certified, while
    # each gains `refine` and still falls short of its LP's optimum by as much: near a thin
    # solution set's end the remainder of one linearization is what holds the end back
    # (docs/decisions/31)
    refine_steps: int = 3
    # The centre's fit stops once its linearized model predicts the largest residual to
    # within this share: the centre needs a margin inside every bound, not the best fit,
    # and the fit's later steps gain next to nothing
    settle: float = 1e-3


@dataclass(frozen=True)
class RoundsSettings:
    """The rounds of LPs (strategy/rounds.py): which relaxation each round takes, when a
    phase ends and which follows, when the last LPs' multipliers are reused."""

    max_rounds: int = 40  # rounds of LPs at most, a guard: real solves stop far sooner
    min_gain: float = 0.1  # a cell round gaining less than this (relative width) is the last
    # Measurement errors get LP columns of their own (the hull of the linearized problem)
    # up to this many measured values; beyond, the LP would grow too large and they stay
    # folded into each row.
    max_cell_columns: int = 3000
    stalled: float = 1e-3  # an unknown that gained less in a folded round sits out the next
    folded_until: float = 0.3  # fold the errors while some unknown gains more than this
    # A relaxation whose remainder is below this share of its rows' widths is final: the
    # next relaxation would be the same LP.
    settled: float = 0.01
    # Above this curvature (the first-order remainder over the first-order range, median
    # over rows) first-order rounds stall, and rounds use second-order models instead
    # (docs/decisions/01: rounds converge below about a seventh).
    wide: float = 0.06
    wide_min_gain: float = 0.02  # a second-order round gaining less ends the search
    # When first-order rounds are over and their remainder is still above this share of the
    # rows' widths, the error bounds are tighter than the model is linear over the box (as
    # real data from realistic priors are), and fine second-order rounds follow: every
    # product kept and tied to its factors by McCormick's inequalities.
    remainder_wide: float = 0.5
    # Below that but above this share, where the model reads measured values (joint
    # readings) as arguments, the fine rounds keep their errors as LP columns instead
    # (quadratic_readings.py), without McCormick's inequalities (which add rows for little
    # more narrowing there). Below it the remainder leaves nothing to gain
    # (docs/decisions/10).
    remainder_readings: float = 0.005
    # When fine rounds with McCormick's inequalities stall and the rows' remainders still cost
    # some unknown's bounds this share of its width (the last LPs' multipliers times the
    # remainders), fine rounds with the readings' errors as LP columns and McCormick's
    # inequalities follow. Below this share such rounds cost about a solve again for a few
    # per cent (docs/decisions/10).
    readings_cost: float = 0.2
    # A fine round gaining less than this (the largest share of an unknown's width) is the
    # last: the gains fall fast, and a round costs the same whatever it gains
    # (docs/decisions/12).
    fine_min_gain: float = 0.05
    # The second-order LPs are dense and one objective's optimum is far from the next's:
    # the simplex from the previous objective's optimum beats the interior point method,
    # each objective's own old basis (the box moved much in between), and probe LPs.
    wide_solver: str = "simplex"
    wide_own_bases: bool = False
    wide_probes: bool = False
    # A fine round's tall LP (row generation) keeps a column per reading's error, thousands
    # that a new objective leaves at their bounds: HiGHS's dual simplex (1) from the last
    # optimum took fewer pivots there than the primal (lp.tall_simplex), in half the time
    # on most rounds (docs/decisions/35).
    fine_simplex: int = 1
    wide_iterations: int = 20000  # simplex pivots per objective in a second-order round
    wide_seconds: float = 30.0
    # After a round of LPs the next rounds reuse its multipliers on the new box (a matrix
    # product, certified again there) while such a round narrows some unknown by this
    # much, at most reuse_rounds in a row; then the LPs are solved again.
    reuse_gain: float = 0.1
    reuse_rounds: int = 20
    # A second-order round narrows its bounds again with the same multipliers on the
    # relaxation narrowed to them, while that narrows some unknown by narrowed_gain.
    narrowed_rounds: int = 10
    narrowed_gain: float = 0.01
    # A product goes back into the remainders when that costs no row more than this share of
    # its width (data error plus remainder): fewer LP columns, a slightly looser relaxation.
    prune: float = 0.25


@dataclass(frozen=True)
class SamplingSettings:
    """Work on some of a table's rows before all of them: the rounds' working set
    (strategy/working.py) and the least-squares estimate's sample (analysis/lsq.py)."""

    # The rounds of LPs over a loop of table rows start on this many of its rows, evenly
    # spread (strategy/working.py), and rows join while the LPs' optima violate them: a
    # cost choice, not a strength one (every phase of the rounds runs on the working set,
    # and the check sees every row). It measures what an LP of the rounds can hold and
    # stay fast: a second-order LP has 3 rows per configuration and a few hundred dense
    # columns; a working set of all rows is the plain rounds, without a check.
    working_rows: int = 1000
    # At most this many checks of the optima on every row (each a fine second-order round
    # on the working set and a point check per bound on every row).
    working_passes: int = 2
    # A pass that a check follows runs this many fine rounds: a further round on the same
    # rows only confirmed the last one's fixed point (gains of 1e-4 and 4e-3 of a width on
    # the 1500-row campaign, docs/decisions/35), while the next pass's rounds run with the
    # rows the check joins; where it joins none, the rounds go on until their phases end.
    fine_rounds_per_check: int = 1
    # A least-squares estimate (analysis/lsq.py) over many configurations starts on an
    # evenly spread sample of them, a tenth, at least lsq_min_rows and at most lsq_rows,
    # then is polished on every row with lsq_polish evaluations (then more if needed)
    # (docs/decisions/11).
    lsq_rows: int = 1000
    lsq_min_rows: int = 100
    lsq_polish: int = 10
    # A Levenberg-Marquardt-type fit needs a few evaluations per unknown from a far start (its
    # Jacobian's columns explored once each, then the nearly linear end): the smallest budget
    # of a fit that did not stop on a tolerance, per unknown.
    lsq_per_unknown: int = 10


@dataclass(frozen=True)
class Settings:
    # -- propagation ---------------------------------------------------------------------
    # Between LP rounds: a small box is enough, not a fixed point (the next relaxation
    # contracts far more than the last sweeps would).
    preliminary_tol: float = 1e-2
    # A sweep's step with this many entries per thread (a loop's rows) is shared among the
    # LPs' workers (propagate/kernels.py): below, a handover costs more than it saves.
    sweep_share: int = 4096

    # A program over this many slots whose loop over table rows was compiled once is
    # relaxed and evaluated a chunk of rows at a time (compile/chunks.py): each slot holds a
    # gradient or a model in every unknown in a pass, so memory follows the chunk, not rows.
    chunk_slots: int = 150_000
    # glibc's malloc arenas at most, set when the chunked passes' threads start: each thread
    # otherwise keeps freed memory in an arena of its own (up to 8 per core), which the
    # peak then holds (docs/decisions/41); 0 leaves glibc's default
    malloc_arenas: int = 2


    # -- second-order models (relax/taylor.py, relax/quadratic.py) ---------------------------
    # A bound on the models' memory: slots x n(n+1)/2 coefficients (each group keeps its
    # outputs' models in the unknowns they depend on only). Above it there are no models,
    # and the strategies keep to first order rather than exhaust the memory.
    max_table_bytes: float = 600e6


    # -- the change of unknowns (strategy/reparametrize.py) -----------------------------------
    snap: float = 1e-9  # a coefficient this close to an integer (relative) is that integer

    # -- identifiability (analysis/identify.py) -----------------------------------------------
    rank_tol: float = 1e-9  # singular values below this times the largest are structural zeros
    # The analysis differentiates the whole program w.r.t. every unknown: on large programs it
    # would cost more than the solve itself, and the rank does not need a thousand
    # configurations. Above this many primitives `solve` runs it neither for its report nor
    # for the change of unknowns; `calibc identify` always does.
    routine_max_primitives: int = 50_000

    # -- identifiability advice (studies/advice.py; in error bounds over the whole domain) ---
    seen: float = 1e-4  # a direction fainter than this is below the data's rounding: unseen
    well_seen: float = 1.0  # a parameter adding less than one bound is left to the others
    subset_cond: float = 1e3  # the suggested subset's condition number at most
    leads: float = 0.5  # share of the largest component that leads a weak direction
    absorbs: float = 0.05  # share of the largest coefficient that names an absorbing parameter

    # -- shaving (inner/shave.py) ---------------------------------------------------------
    # After the inner bounds, the unknowns whose result is wider than shave_above times their
    # inner interval (at most shave_unknowns) have each end's gap contracted as a slice of
    # its own by at most shave_rounds fine rounds of LPs, the next end always the worst
    # outer/inner ratio's in the box shaved so far; an end whose gap is under shave_min_gap
    # of the result's width is left as it is. By default an end starts only if, at the mean
    # cost of the ends before, shaving stays within shave_share of the solve's time (an end
    # costs rounds of LPs of its own). Three rounds close most of a gap; a fourth adds little
    # for a third more time (docs/decisions/15). An unknown still loose after them: `loose`.
    shave_above: float = 1.05
    shave_unknowns: int = 8
    shave_rounds: int = 3
    shave_min_gap: float = 0.005
    shave_share: float = 0.3

    # -- verdicts (strategy/verdict.py, strategy/refute.py) -----------------------------------
    # A solve that certified no point spends at most this share of its own time on proving
    # the data inconsistent before it says "undecided" (0: none): the user is owed a verdict,
    # and a proof costs about a solve (a solve without one row, a round of LPs, a split).
    verdict_share: float = 1.0
    # A data row the least-squares fit leaves more than this many error bounds off is tried
    # as a certain outlier (the other rows solved alone): data whose bounds are a few percent
    # too tight leave every row near 1; one faulty coordinate leaves its row far beyond.
    verdict_outlier_bounds: float = 2.0
    verdict_outlier_rows: int = 3  # such rows tried at most, the worst first
    # The least-squares fit from the result's middle that a verdict starts from (near the
    # solutions): at most this many evaluations of the residuals.
    verdict_lsq: int = 100

    # -- splitting (strategy/split.py) -------------------------------------------------------
    # An unknown not identifiable alone and left wider than left_wide of its domain is cut
    # into split_pieces pieces, each refined by at most split_rounds rounds of its own, if
    # a piece's relaxation is narrower than the whole box's by split_worth of the rows'
    # widths; split_tried such unknowns are tried, the widest first.
    left_wide: float = 0.25
    split_pieces: int = 4
    split_rounds: int = 10
    split_worth: float = 0.03
    split_tried: int = 3
    loose: LooseSettings = LooseSettings()  # after shaving (settings_strategy.py)
    blocks: BlockSettings = BlockSettings()  # passes over every row (settings_strategy.py)
    # Pieces are refined in child processes, one per core the LPs use (1: in the solving
    # process), each with cores / processes LP threads (two threads each overcommit).
    piece_processes: int = min(2, CORES)

    lp: LPSettings = LPSettings()  # -- LPs (lp/)
    outliers: OutlierSettings = OutlierSettings()  # -- outliers (outliers/)
    # -- inner bounds (inner/) -------------------------------------------------------------
    inner: InnerSettings = InnerSettings()
    # -- rounds of LPs (strategy/rounds.py) ----------------------------------------------
    rounds: RoundsSettings = RoundsSettings()
    # -- the working set of rows (strategy/working.py) -----------------------------------
    sampling: SamplingSettings = SamplingSettings()
    # -- fits and the smallest error bound (analysis/; settings_analysis.py) --------------
    fits: FitSettings = FitSettings()
    min_error: MinErrorSettings = MinErrorSettings()

    # -- planning a campaign (plan/) -------------------------------------------------------
    # The domains counted as information in the classical designs, in units where a uniform
    # prior over a domain and uniform noise within a bound have the same variance: 1 is
    # one row's worth along every unknown. Less lets the design follow the rows alone (the
    # guaranteed widths are set by the rows; the domains only cap them).
    plan_ridge: float = 0.1
    plan_passes: int = 10  # exchange passes at most, each over every member
    # An exchange pass weighs, for each member, the candidates of highest value on the
    # whole set, not all: a member is worth leaving only for one of them.
    plan_shortlist: int = 200
    plan_tries: int = 4  # members and candidates paired per round of the LP exchange
    # A swap of the LP exchange must lower the score by this much: less is within the LPs'
    # tolerance, and the exchange would chase it.
    plan_improvement: float = 1e-6
    # The LP exchange's budget, in hulls (a hull: two LPs per unknown): a count, not seconds,
    # so a plan is reproducible.
    plan_lp_hulls: int = 40
    # Noise draws a predicted width is the median of: one draw's width spreads widely, and
    # few draws leave the median off by as much (docs/decisions/32 has the figures).
    plan_draws: int = 15
    plan_candidates: int = 3000  # configurations drawn when no candidate file is given

    # -- the accuracy statement ----------------------------------------------------------
    # Its least-squares point (accuracy/fit.py) is polished from the certified centre, near
    # the fit: Levenberg-Marquardt steps at most fit_steps, stopped when one lowers the sum
    # of squares by less than fit_tolerance of it (the floats' noise on a fit's residuals);
    # fit_damping the first step's, relative to the Jacobian's columns.
    fit_steps: int = 50
    fit_tolerance: float = 1e-10
    fit_damping: float = 1e-3
    # -- predictions ---------------------------------------------------------------------
    # Each predicted coordinate's linear part gets its own LP, the objectives visited in a
    # nearest-neighbour path (accuracy/batch_lp.py) built greedily within windows of this
    # many objectives (sorted along their leading direction first): the greedy search costs
    # objectives x window, and a window of a few thousand already finds neighbours within
    # a few degrees of each other on a robot's predictions.
    prediction_path_window: int = 4000
    # Runs of the LP's pivot and time limits (LPSettings) each prediction LP may take before
    # its multipliers are certified as they stand: the path's first LP starts from no basis
    # and a tall relaxation's can need more pivots than one run allows.
    prediction_lp_runs: int = 4
    # The prediction LPs run on the rows the path needs (accuracy/working_rows.py): a row
    # stays in the model until it was inactive at this many consecutive optima, this many
    # more each time it came back (HiGHS's cost per run grows with the model's rows; a row
    # dropped too early comes back as a violated row and costs a re-run); at most
    # prediction_rows_added violated rows are added per pass (the most violated), and at
    # most prediction_row_passes passes per LP (an LP still violating rows after them is
    # certified as it stands and solved again after the walk).
    prediction_rows_kept: int = 10
    prediction_rows_added: int = 20
    prediction_row_passes: int = 8
    # The LP optima of this many predicted coordinates, far apart in direction (both ends),
    # become candidate extremes for the inner intervals (accuracy/extremes.py) where the linearized
    # model gives none: each costs certify_point passes and a place among a row's points.
    prediction_candidates: int = 128
    # Those LPs' optima are pulled back towards the certified centre by bisection until
    # certified (accuracy/extremes.py): pullback_steps halvings leave an end within 2^-steps
    # of the segment short of the last certified share.
    pullback_steps: int = 8
    # Each pass of that bisection evaluates a point only on the calibration rows the rows'
    # second-order bounds leave open (analysis/row_screen.py), one-row chunks at a few points
    # each: about 74 us a point and row against 12 us in the whole check's large chunks
    # (UR10, 100 rows). Above this share of open rows the pass is the whole check.
    pullback_most_open: float = 0.15
    # Directions (predictions' gradients, spread apart) whose extremes over the calibration
    # linearized at the certified centre become candidates too: near the solution set's
    # boundary, where the relaxation's optima lie beyond it
    prediction_linear_lps: int = 1024
    # Each such optimum that its check rejects is re-solved with the rows it violated moved
    # inside (the inner bounds' rule, accuracy/corrections.py) at most this many times
    # before it is pulled back: a correction slides along the solution set's boundary where
    # the pull-back stops on the segment to the centre. On the UR10 most are proven after
    # 2-4; each costs one point check and one LP per candidate still open.
    prediction_corrections: int = 6
    # Whether the relaxation the predictions' LPs run over (accuracy/second_order.py) ties
    # each product column to its factors by McCormick's inequalities: they narrow the
    # predictions a little (their extreme vertices) but give the LP four rows a product,
    # most of its rows, and each LP's pivots cost with them.
    prediction_mccormick: bool = False
    # The inner intervals' ends are evaluated exactly at the certified points each row's
    # approximate model picks, this many of a loop's rows in one pass (accuracy/certified.py
    # inner_at): a pass costs its rows times the points they picked, so fewer rows a pass
    # evaluate fewer points each, at the cost of more passes over the primitives.
    prediction_hull_rows: int = 32
    # The predictions' inner ends evaluated with the predicted configuration's readings moved
    # within their errors towards each end (accuracy/held_readings.py): the outer boxes hold
    # every such value, so an inner end at the readings' middles alone understates them.
    prediction_move_readings: bool = True

    def tuned(self, **changes: Any) -> Settings:
        """These settings with some fields changed, each named by its own name whether it is
        a field of Settings or of one of its groups (`tuned(working_rows=6, stalled=0)`):
        the flat names callers knew before the groups, kept working. A name two groups
        share goes to the first of GROUPS (max_rounds: the rounds'); `group__name` names
        any group's (`outliers__max_rounds=3`), and so does `group_name` where no field has
        that name (`min_error_share`: the min_error group's share)."""
        flat = {f.name for f in fields(self)}
        groups: dict[str, dict[str, Any]] = {}
        mine: dict[str, Any] = {}
        for name, value in changes.items():
            group, _, field = name.rpartition("__")
            if not group:
                group = next((g for g in GROUPS if name not in flat and field in _names(g)),
                             "")
            if not group and name not in flat:  # `min_error_share`: the group's name first
                group, field = next(((g, name[len(g) + 1:]) for g in GROUPS
                                     if name.startswith(g + "_")
                                     and name[len(g) + 1:] in _names(g)), ("", name))
            if not group and name not in flat:
                raise TypeError(f"Settings has no field {name!r}")
            (groups.setdefault(group, {}) if group else mine)[field] = value
        for g, v in groups.items():  # on a group given whole as well (`lp=...`), if any
            mine[g] = replace(mine.get(g, getattr(self, g)), **v)
        return replace(self, **mine)

    @property
    def piece_lp_threads(self) -> int:
        return max(1, self.lp.workers // self.piece_processes)


# Settings' fields that are groups
GROUPS = ("rounds", "sampling", "lp", "inner", "outliers", "fits", "min_error", "loose", "blocks")


def _names(group: str) -> set[str]:
    return {f.name for f in fields(getattr(Settings, group))}


DEFAULT = Settings()
