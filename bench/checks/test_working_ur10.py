"""The UR10 tracker model's working-set rounds on simulated campaigns of several sizes and
shapes (four whole solves): too heavy for `make test`, where
tests/strategy/test_working.py keeps a UR10 campaign of 40 rows through the working set's
resumed passes (truth inside) and the working-set properties on random robots."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.settings import DEFAULT
from calib_dsl.strategy.tight import solve_tight


@settings(max_examples=4, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(rows=st.sampled_from([20, 30, 40]), amplitude=st.floats(0.3, 1.0),
       shape=st.sampled_from(["random", "grid", "repeated"]), seed=st.integers(0, 500))
def test_ur10_campaigns_of_several_sizes_hold_the_truth(tmp_path_factory, rows, amplitude,
                                                        shape, seed):
    """The UR10 tracker model on simulated campaigns with a systematic error, a working set
    of 10 rows at the start (so the check and the rows it adds carry the result): the truth
    lies inside at a bound of the error's size. (Two to four times the working set: what
    holds does not depend on the campaign's size; bench/checks runs 2100 rows.)"""
    from calib_dsl.elaborate.elaborator import Inputs
    from calib_dsl.pipeline import load
    from calib_dsl.studies.campaign import Campaign
    from calib_dsl.studies.simulate import simulate
    from tests.test_ur10 import TRACKER, _noisy_simulation_model, truth

    tmp = tmp_path_factory.mktemp("ur10")
    table = tmp / "sim.csv"
    simulate(_noisy_simulation_model(tmp, 0.05), rows, seed, out_csv=table,
             campaign=Campaign(shape, 4, systematic=amplitude))
    prog = load(TRACKER, inputs=Inputs(data={"m": table},
                                       consts={"e": repr(amplitude + 0.05)}))
    sol = solve_tight(prog, settings=DEFAULT.tuned(working_rows=10))
    assert sol.status == "contracted"
    for name, t in truth().items():
        i = prog.slots.names.index(name)
        assert sol.lo[i] <= t <= sol.hi[i], (name, sol.lo[i], t, sol.hi[i])
    labels = [step.label for step in sol.history.steps]
    assert any(f"row check on all {rows} rows" in label for label in labels), labels
