"""The box a fine round of fresh LPs relaxed is kept in its certificates (`Certificates.box`) as
the round's own arrays, not a copy (strategy/rounds.py): that holds only while no box a round has
is written in place. On working-set solves of random robots, every box so kept still holds,
when the row check reads it and when the solve ends, the values it had when its LPs ran."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.settings import DEFAULT
from calib_dsl.strategy import rounds, working
from calib_dsl.strategy.tight import solve_tight
from tests.relax.test_linearize import random_robot, robot_draws


@settings(max_examples=8, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
# (spatial robots of two or three joints, in matrices: their rows compiled once, a working set)
@given(**{**robot_draws(st.integers(14, 30)), "formulation": st.just("matrix"),
          "seed": st.integers(0, 5000).map(lambda k: 2 * k + 1), "joints": st.integers(2, 3)})
def test_the_boxes_kept_for_the_row_check_are_never_written(
        tmp_path_factory, monkeypatch, seed, joints, rows, formulation) -> None:
    prog = random_robot(tmp_path_factory.mktemp("boxes"), seed, joints, rows, formulation).prog
    if prog.rows is None:  # (a loop whose rows were compiled one by one: no working set)
        return
    kept: dict[int, tuple[tuple, tuple]] = {}  # id of a kept box: (the box, its values)
    read: list[int] = []
    bounds, check = rounds._Rounds.bounds, working.violated_rows

    def recorded(self, this):
        out = bounds(self, this)
        for certs in (self.fine_certs, self.spec.certs):
            if certs.box is not None and id(certs.box) not in kept:
                kept[id(certs.box)] = (certs.box, (certs.box[0].copy(), certs.box[1].copy()))
        return out

    def unchanged(box: tuple) -> bool:
        values = kept[id(box)][1]
        return all(np.array_equal(a, b, equal_nan=True) for a, b in zip(box, values,
                                                                         strict=True))

    def checked(prog, certs, rows, workers=1):
        if certs.box is not None:
            assert unchanged(certs.box)
            read.append(id(certs.box))
        return check(prog, certs, rows, workers)

    monkeypatch.setattr(rounds._Rounds, "bounds", recorded)
    monkeypatch.setattr(working, "violated_rows", checked)
    sol = solve_tight(prog, settings=DEFAULT.tuned(working_rows=6), combinations=False)
    assert sol.status != "infeasible"
    assert all(unchanged(box) for box, _ in kept.values())
