"""campaign.py: pose shapes and the smooth, pose-dependent error of a simulated campaign;
a campaign with that error keeps the truth inside the solve at a bound above its size."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.studies.campaign import POSES, Campaign, poses, systematic
from calib_dsl.studies.simulate import simulate_model
from tests.studies.test_simulate import Q_COLS, rx90_sim_model

ROOT = Path(__file__).resolve().parents[2]
ANGLES = [(-math.pi, math.pi)] * 6


@settings(max_examples=60, deadline=None)
@given(amplitude=st.floats(0.0, 1e3), inputs=st.integers(1, 8), seed=st.integers(0, 2**32),
       scale=st.floats(0.1, 100.0))
def test_the_systematic_error_never_exceeds_its_amplitude(amplitude, inputs, seed, scale):
    rng = np.random.default_rng(seed)
    err = systematic(amplitude, inputs, rng)
    q = rng.uniform(-scale, scale, size=(500, inputs))
    e = err(q)
    assert np.all(np.abs(e) <= amplitude)
    # smooth and periodic: the same pose gives the same error (to the last bits: numpy's
    # vectorized sine may round a long array's elements apart from a short one's), a turn
    # later too
    np.testing.assert_allclose(err(q[:5]), e[:5], rtol=0, atol=1e-13 * (1 + amplitude))
    np.testing.assert_allclose(err(q[:5] + 2 * math.pi), e[:5], atol=1e-9 * (1 + amplitude))


def test_the_systematic_error_fills_much_of_its_amplitude_and_varies_with_the_pose():
    err = systematic(2.0, 6, np.random.default_rng(3))
    e = err(poses(Campaign(), ANGLES, 2000, np.random.default_rng(4)))
    assert np.max(np.abs(e)) > 1.0 and np.std(e) > 0.2  # not a constant offset


def test_grid_poses_are_distinct_cell_centres():
    q = poses(Campaign("grid"), ANGLES, 700, np.random.default_rng(0))
    assert q.shape == (700, 6) and len(np.unique(q, axis=0)) == 700
    levels = 3  # the least L with L^6 >= 700
    cells = (q + math.pi) / (2 * math.pi) * levels - 0.5
    np.testing.assert_allclose(cells, np.round(cells), atol=1e-9)


def test_repeated_poses_repeat():
    q = poses(Campaign("repeated", repeats=4), ANGLES, 30, np.random.default_rng(0))
    distinct = np.unique(q, axis=0)
    assert len(distinct) == 8  # ceil(30 / 4)
    np.testing.assert_array_equal(q[:8], q[8:16])


def test_random_poses_are_the_seed_s_old_file():
    """Random poses without a systematic error: the draws the seed always gave (the
    inputs column by column, then the noise), so existing files stay reproducible."""
    model = rx90_sim_model(20)
    a = simulate_model(model, 9)["m"]
    rng = np.random.default_rng(9)
    q = np.column_stack([rng.uniform(-math.pi, math.pi, size=20) for _ in Q_COLS])
    assert np.all(np.abs(a[:, :6] - q) <= 1e-5)


@pytest.mark.parametrize("shape", POSES)
def test_the_campaign_s_error_on_measured_columns(shape):
    """Without noise the outputs differ from the exact ones by the systematic error alone
    (at most its amplitude, and the same at a repeated pose); the inputs are the poses."""
    model = rx90_sim_model(60, tol_q=0.0, tol_x=0.0)
    clean = simulate_model(model, 5, Campaign(shape, 3))["m"]
    off = simulate_model(model, 5, Campaign(shape, 3, systematic=0.01, noise=False))["m"]
    np.testing.assert_array_equal(clean[:, :6], off[:, :6])
    diff = off[:, 6:] - clean[:, 6:]
    assert np.all(np.abs(diff) <= 0.01 + 1e-12) and np.max(np.abs(diff)) > 0.004
    if shape == "repeated":
        np.testing.assert_allclose(diff[:20], diff[20:40], atol=1e-12)


def test_bad_campaigns_are_user_errors():
    with pytest.raises(CalError, match="pose shape"):
        Campaign("spiral")
    with pytest.raises(CalError, match="amplitude"):
        Campaign(systematic=math.nan)


def test_the_command_line_writes_a_shaped_campaign(tmp_path):
    """`calibc simulate --poses grid --systematic A --no-noise`: the file's measured values
    are the exact ones plus an error of at most A; a bad amplitude is one line, exit 2."""
    from click.testing import CliRunner

    from calib_dsl.cli import main

    model = _model_with_noise(tmp_path, 1e-9)
    out = [tmp_path / f"{k}.csv" for k in "ab"]
    for path, extra in zip(out, ([], ["--systematic", "0.5", "--no-noise"]), strict=True):
        res = CliRunner().invoke(main, ["simulate", str(model), "--configs", "30", "--poses",
                                        "grid", "-o", str(path), "-q", *extra])
        assert res.exit_code == 0, res.output
    a, b = (np.loadtxt(p, delimiter=";", skiprows=1, converters=lambda s: float(
        s.replace(",", "."))) for p in out)
    np.testing.assert_allclose(a[:, :6], b[:, :6], atol=1e-8)
    assert 0.1 < np.max(np.abs(a[:, 6:] - b[:, 6:])) <= 0.5 + 1e-6
    bad = CliRunner().invoke(main, ["simulate", str(model), "--configs", "3", "-o",
                                    str(out[0]), "--systematic", "nan"])
    assert bad.exit_code == 2 and "amplitude" in bad.output and "Traceback" not in bad.output


def _model_with_noise(tmp_path: Path, noise: float) -> Path:
    models = ROOT / "models"
    text = ((models / "ur10_simulated.cal").read_text()
            .replace("const e = 0.1;", f"const e = {noise};")
            .replace('include "robots/ur10.cal";', f'include "{models}/robots/ur10.cal";')
            .replace('include "ur10_cell.cal";', f'include "{models}/ur10_cell.cal";'))
    path = tmp_path / "sim.cal"
    path.write_text(text)
    return path


@pytest.mark.slow
@settings(max_examples=1, deadline=None)  # 4 in bench/checks/test_soundness_full.py
@given(amplitude=st.floats(0.2, 1.5), noise=st.sampled_from([0.0, 0.05]),
       shape=st.sampled_from(POSES), seed=st.integers(0, 1000),
       margin=st.floats(1.0, 1.3))
def test_the_truth_lies_inside_a_solve_of_systematic_data(tmp_path_factory, amplitude, noise,
                                                          shape, seed, margin):
    """UR10 campaigns whose error is smooth and systematic (plus noise): solved at a bound
    at least the error's, every true parameter lies in the result."""
    from calib_dsl.elaborate.elaborator import Inputs
    from calib_dsl.pipeline import load
    from calib_dsl.strategy.tight import solve_tight
    from calib_dsl.studies.simulate import simulate
    from tests.test_ur10 import TRACKER, truth

    tmp = tmp_path_factory.mktemp("sys")
    table = tmp / "sim.csv"
    simulate(_model_with_noise(tmp, max(noise, 1e-9)), 24, seed, out_csv=table,
             campaign=Campaign(shape, 3, systematic=amplitude, noise=noise > 0))
    bound = (amplitude + noise) * margin
    prog = load(TRACKER, inputs=Inputs(data={"m": table}, consts={"e": repr(bound)}))
    res = solve_tight(prog)
    assert res.status == "contracted"
    for name, t in truth().items():
        i = prog.slots.names.index(name)
        assert res.lo[i] <= t <= res.hi[i], (name, res.lo[i], t, res.hi[i])
