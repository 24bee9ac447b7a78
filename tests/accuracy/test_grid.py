"""`calibc predict --grid`: the poses of a grid of joint values, the guaranteed error bound at
each (it holds the true arm's position: the simulation's lengths), CSV and JSON, and the
workspace figure."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from cli_run import run
from planar_arm import simulated_arm, tip

from calib_dsl.accuracy.grid import MAX_CELLS, check_size, parse_grid
from calib_dsl.frontend.diagnostics import CalError


@pytest.fixture(scope="module")
def mapped(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("grid")
    simulated_arm(tmp, 10, 5)
    res = run("predict", "planar_arm.cal", "-D", "e=0.01", "--grid", "q1=-1:1:0.5,q2=0:2:1",
              "--json", "g.json", "--csv", "g.csv", "-q", cwd=tmp)
    assert res.exit_code == 0, res.output
    assert "guaranteed error bound at 15 poses" in res.output
    return tmp, json.loads((tmp / "g.json").read_text())


def test_every_pose_of_the_grid_and_the_truth_within_its_bound(mapped):
    _, doc = mapped
    poses = [(r["pose"]["q1"], r["pose"]["q2"]) for r in doc["rows"]]
    assert poses == [(a, b) for a in (-1, -0.5, 0, 0.5, 1) for b in (0, 1, 2)]
    for r in doc["rows"]:
        x, y = tip(1.0, 0.5, r["pose"]["q1"], r["pose"]["q2"])  # planar_arm.cal's truth
        assert r["x"][0] <= x <= r["x"][1] and r["y"][0] <= y <= r["y"][1]
        middle = (0.5 * sum(r["x"]), 0.5 * sum(r["y"]))
        assert np.hypot(x - middle[0], y - middle[1]) <= r["bound"] <= r["with_e"]
        assert r["with_e"] >= np.hypot(0.5 * (r["x"][1] - r["x"][0]) + 0.01,
                                       0.5 * (r["y"][1] - r["y"][0]) + 0.01)
    bounds = [r["bound"] for r in doc["rows"]]
    assert doc["bound"]["max"] == max(bounds) and doc["bound"]["unbounded"] == 0


def test_the_csv_holds_the_json(mapped):
    tmp, doc = mapped
    with open(tmp / "g.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(doc["rows"])
    for r, j in zip(rows, doc["rows"], strict=True):
        assert float(r["q1"]) == j["pose"]["q1"] and float(r["bound"]) == j["bound"]
        assert float(r["x_lo"]) == j["x"][0] and float(r["y_hi"]) == j["y"][1]


def test_the_workspace_figure(mapped):
    pytest.importorskip("matplotlib")
    from calib_dsl.plot.figure import available, figure

    _, doc = mapped
    assert available(doc) == ["workspace"]
    fig = figure(doc, "workspace")
    index = [ax for ax in fig.axes if ax.get_label() == "workspace"][0]
    (line,) = index.lines
    np.testing.assert_allclose(line.get_ydata(), [r["bound"] for r in doc["rows"]])
    (where,) = [ax for ax in fig.axes if ax.get_label() == "workspace:positions"]
    (dots,) = where.collections
    np.testing.assert_allclose(dots.get_array(), [r["bound"] for r in doc["rows"]])


def test_grid_specs():
    assert parse_grid("q1=0:1:0.25, q2=3") == {"q1": [0, 0.25, 0.5, 0.75, 1.0], "q2": [3.0]}
    assert len(parse_grid("a=0:1:0.1")["a"]) == 11  # exact decimal steps: 1 is included
    for bad in ("q1", "q1=1:0:0.1", "q1=0:1:0", "q1=0:x:1", "", "q1=0:1:1e-7", "q1=1e400",
                "q1=0:1e400:1e395", "q1=nan", "q1=-inf:0:1", "q1=0,q1=1"):
        with pytest.raises(CalError):
            parse_grid(bad)


def test_grid_size_measured_in_poses_times_unknowns_per_row():
    values = parse_grid("a=1:100:1,b=1:100:1")  # 10,000 poses
    check_size(values, MAX_CELLS // 10_000)
    with pytest.raises(CalError, match=f"at most {MAX_CELLS // 401} poses"):
        check_size(values, 401)


def test_grid_mistakes_are_user_errors(mapped):
    tmp, _ = mapped
    res = run("predict", "planar_arm.cal", "--grid", "q1=0:1:0.5", cwd=tmp)
    assert res.exit_code == 2 and "give q2 too" in res.output
    res = run("predict", "planar_arm.cal", "--grid", "q1=0,q2=0,w=1", cwd=tmp)
    assert res.exit_code == 2 and "no column w" in res.output
    res = run("predict", "planar_arm.cal", "--grid", "q1=-3:3:0.01,q2=-3:3:0.01", cwd=tmp)
    assert res.exit_code == 2 and "361201 poses" in res.output and "larger steps" in res.output
    res = run("predict", "planar_arm.cal", cwd=tmp)
    assert res.exit_code == 2 and "--at FILE is required" in res.output


def test_a_grid_over_a_measured_column_or_beside_at_is_a_user_error(mapped):
    """(a grid over x repeated each pose, one per value of x, and --at beside --grid was
    ignored: exit 0 either way)"""
    tmp, _ = mapped
    res = run("predict", "planar_arm.cal", "--grid", "q1=0:1:0.5,q2=0,x=0:1:0.5", cwd=tmp)
    assert res.exit_code == 2, res.output
    assert "x: a measured column" in res.output and "its inputs: q1, q2" in res.output
    res = run("predict", "planar_arm.cal", "--grid", "q1=0,q2=0", "--at", "planar_arm.csv",
              cwd=tmp)
    assert res.exit_code == 2 and "not both" in res.output, res.output
