"""Figures of results (`calibc plot`, `solve --plot`, `validate --plot`), rendered on the Agg
canvas from real solver results on the planar arm; each test reads what the Figure draws
(axes, bars, ranges, marks, scales), not only that a file was written."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from matplotlib.collections import LineCollection, PathCollection
from matplotlib.patches import Rectangle

from calib_dsl import cli
from calib_dsl.plot.figure import available, figure

ROOT = Path(__file__).resolve().parents[1]
ARM = ROOT / "models" / "examples"
OUTLIER_ROW = 3  # its measured x moved by 1 cm: 100 times the error bound


def run(*args: object):
    return CliRunner().invoke(cli.main, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def arm(tmp_path_factory) -> Path:
    """The planar arm with one bad row (OUTLIER_ROW), beside its robot."""
    tmp = tmp_path_factory.mktemp("arm")
    shutil.copy(ARM / "planar_arm.cal", tmp)
    shutil.copy(ARM / "planar_arm_robot.cal", tmp)
    lines = (ARM / "planar_arm.csv").read_text().splitlines()
    cells = lines[OUTLIER_ROW].split(",")
    cells[2] = repr(float(cells[2]) + 0.01)
    lines[OUTLIER_ROW] = ",".join(cells)
    (tmp / "planar_arm.csv").write_text("\n".join(lines) + "\n")
    return tmp / "planar_arm.cal"


@pytest.fixture(scope="module")
def solved(arm) -> dict:
    """Solved without the bad row (--exclude), with the residuals of every row."""
    out = arm.parent / "r.json"
    res = run("solve", arm, "--exclude", OUTLIER_ROW, "--residuals", "--json", out)
    assert res.exit_code == 0, res.output
    assert "1 outliers of the result" in res.output
    return json.loads(out.read_text())


@pytest.fixture(scope="module")
def validated(arm) -> dict:
    """Validated on 8 simulated held-out rows, the 4th moved by 1 cm."""
    held = arm.parent / "held.csv"
    assert run("simulate", ROOT / "models" / "examples" / "planar_arm.cal", "--configs", 8,
               "--seed", 3, "-o", held).exit_code == 0
    lines = held.read_text().splitlines()
    cells = lines[4].split(",")
    cells[3] = repr(float(cells[3]) - 0.01)
    lines[4] = ",".join(cells)
    held.write_text("\n".join(lines) + "\n")
    out = arm.parent / "v.json"
    res = run("validate", arm, "--at", held, "--exclude", OUTLIER_ROW, "--json", out,
              "--plot", arm.parent / "v.png")
    assert res.exit_code == 0, res.output
    assert "drew prediction" in res.output and (arm.parent / "v.png").stat().st_size > 1000
    return json.loads(out.read_text())


def axes(fig, label: str) -> list:
    return [ax for ax in fig.axes if ax.get_label() == label]


def test_domains_bars_on_a_log_scale_and_the_truth(solved):
    fig = figure(solved, "domains")
    (ax,) = axes(fig, "domains")
    assert ax.get_xscale() == "log"
    assert [t.get_text() for t in ax.get_yticklabels()] == ["l1", "l2"]
    bars = [p for p in ax.patches if isinstance(p, Rectangle)]
    assert len(bars) == 6  # a domain, a result and a certified inner interval per parameter
    heights = {round(b.get_height(), 2) for b in bars}
    assert heights == {0.8, 0.45, 0.15}
    by = {h: sorted(b.get_width() for b in bars if round(b.get_height(), 2) == h)
          for h in heights}
    result = [solved["parameters"][n]["result"] for n in ("l1", "l2")]
    inner = [solved["parameters"][n]["inner"] for n in ("l1", "l2")]
    assert by[0.45] == sorted(hi - lo for lo, hi in result)
    assert by[0.15] == sorted(b - a for a, b in inner)
    assert by[0.8] == pytest.approx([0.4, 0.4])
    (truth,) = axes(fig, "domains:true")
    (points,) = [c for c in truth.collections if isinstance(c, PathCollection)]
    x = points.get_offsets()[:, 0]
    assert len(x) == 2 and np.all(np.abs(x) <= 1)  # both true values inside their results


def test_residual_ranges_bounds_and_the_outlier(solved):
    rows = solved["residuals"]["rows"]
    assert [r["row"] for r in rows] == [1, 2, 3, 4, 5]
    assert [r["used"] for r in rows] == [True, True, False, True, True]
    assert solved["residuals"]["outliers"] == [{"table": "m", "row": OUTLIER_ROW, "line": 4}]
    bad = rows[OUTLIER_ROW - 1]["columns"]["x"]
    assert bad["residual"][0] > bad["bound"]  # wholly above +e: proven not to fit
    fig = figure(solved, "residuals")
    (ax,) = axes(fig, "residuals")  # x and y share their bound: one panel
    ranges = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert [c.get_label() for c in ranges] == ["x", "y"]
    assert all(len(c.get_segments()) == 5 for c in ranges)
    segment = ranges[0].get_segments()[OUTLIER_ROW - 1]
    assert segment[0, 1] == pytest.approx(bad["residual"][0])
    levels = sorted(ln.get_ydata()[0] for ln in ax.lines if ln.get_linestyle() == "--")
    assert levels == pytest.approx([-1e-4, 1e-4], rel=1e-6)
    (marks,) = [ln for ln in ax.lines if ln.get_marker() == "x"]  # on x's bar, beside y's
    assert list(marks.get_xdata()) == [pytest.approx(OUTLIER_ROW - 0.2)]
    assert list(marks.get_ydata()) == [pytest.approx(sum(bad["residual"]) / 2)]
    grey = [p for p in ax.patches if p.get_facecolor()[:3] == pytest.approx((0.85,) * 3)]
    assert len(grey) == 1  # the row left out


def test_prediction_marks_the_rows_not_covered(validated):
    """Bands over the rows sorted by their guaranteed error, the row not covered marked at
    its rank, and the summary line with the coverage."""
    from calib_dsl.plot.prediction import column_order, errors

    assert validated["coverage"] == pytest.approx(7 / 8)
    fig = figure(validated, "prediction")
    (ax,) = axes(fig, "prediction")
    bands = [c for c in ax.collections if c.get_label() in ("x", "y")]
    assert [c.get_label() for c in bands] == ["x", "y"]
    found, reach, covered = errors(validated)
    for name in ("x", "y"):
        order = column_order(found[name])
        size = np.fmax(*(np.abs(v[order]) for v in found[name]))
        assert np.all(np.diff(size) >= 0)
    # row 4 (index 3): not covered, its y interval outside +-e, marked at its rank for y
    (marks,) = [ln for ln in ax.lines if ln.get_marker() == "x"]
    assert list(marks.get_xdata()) == [int(np.flatnonzero(column_order(found["y"]) == 3)[0])]
    levels = sorted(ln.get_ydata()[0] for ln in ax.lines if ln.get_linestyle() == "--")
    assert levels == pytest.approx([-validated["held_out"][0]["columns"]["x"]["bound"],
                                    validated["held_out"][0]["columns"]["x"]["bound"]],
                                   rel=1e-2)
    title = ax.get_title(loc="left")
    assert "coverage 0.875" in title and "1 not covered" in title
    assert f"max {np.max(reach):.3g}" in title


def test_history_widths_against_seconds(solved):
    fig = figure(solved, "history")
    (ax,) = axes(fig, "history")
    assert ax.get_yscale() == "log"
    steps = solved["history"]["steps"]
    assert len(ax.lines) == 2
    for line, j in zip(ax.lines, range(2), strict=True):
        assert list(line.get_xdata()) == [s["seconds"] for s in steps]
        np.testing.assert_allclose(line.get_ydata(), [s["widths"][j] for s in steps])
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["l1", "l2"]


def test_accuracy_histograms_and_the_guaranteed_bound(solved):
    fig = figure(solved, "accuracy")
    (ax,) = axes(fig, "accuracy")
    acc = solved["accuracy"]
    # one histogram per point, each counting every pose once
    bars = [p for p in ax.patches if p.get_label() != "_nolegend_"]
    assert len(bars) == len(acc["points"]) == 3
    for patch in bars:
        assert "rms" in patch.get_label()
    # the rows the solve used (--exclude left one out)
    assert acc["configurations"] == sum(r["used"] for r in solved["residuals"]["rows"])
    for p in acc["points"].values():
        assert len(p["distances"]) == acc["configurations"]
    # the bound's largest and median values as vertical lines, at or beyond every distance
    xs = [line.get_xdata()[0] for line in ax.lines]
    assert xs == [pytest.approx(acc["bound"]["max"]), pytest.approx(acc["bound"]["median"])]
    after = max(acc["points"]["least_squares"]["distances"])
    assert acc["bound"]["max"] >= after
    assert ax.get_xlim()[1] >= acc["bound"]["max"]


def test_all_kinds_in_one_figure(solved, validated):
    assert available(solved) == ["domains", "residuals", "accuracy", "history"]
    assert available(validated) == ["prediction"]
    fig = figure(solved)
    assert len(fig.subfigs) == 4
    assert [ax.get_label() for ax in fig.axes] == ["domains", "domains:true", "residuals",
                                                  "accuracy", "history"]


@pytest.mark.parametrize("suffix, magic", [(".png", b"\x89PNG"), (".svg", b"<?xml"),
                                           (".pdf", b"%PDF")])
def test_plot_command_writes_the_format_of_the_extension(solved, tmp_path, suffix, magic):
    result = tmp_path / "r.json"
    result.write_text(json.dumps(solved))
    out = tmp_path / f"f{suffix}"
    res = run("plot", result, "-o", out, "--kind", "domains")
    assert res.exit_code == 0 and "drew domains" in res.output
    assert out.read_bytes().startswith(magic)


def test_solve_and_validate_draw_with_plot(arm, tmp_path):
    out = tmp_path / "s.png"
    res = run("solve", arm, "--exclude", OUTLIER_ROW, "--plot", out)
    assert res.exit_code == 0 and "drew domains, residuals, accuracy, history" in res.output
    assert out.stat().st_size > 1000


@pytest.mark.parametrize("args, message", [
    (["-o", "f.gif"], "must end in .png, .svg, .pdf"),
    (["-o", "f.png", "--kind", "prediction"], "calibc validate MODEL --at HELDOUT"),
])
def test_plot_user_errors(solved, tmp_path, args, message):
    result = tmp_path / "r.json"
    result.write_text(json.dumps(solved))
    res = run("plot", result, *[tmp_path / a if a.startswith("f.") else a for a in args])
    assert res.exit_code == 2 and message in res.output


def test_plot_of_something_else(tmp_path):
    bad = tmp_path / "r.json"
    bad.write_text("[1, 2]")
    res = run("plot", bad, "-o", tmp_path / "f.png")
    assert res.exit_code == 2 and "is not a result JSON" in res.output


def test_without_matplotlib_the_message_says_how_to_get_it(monkeypatch, solved, arm,
                                                           tmp_path):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # `import matplotlib` fails
    result = tmp_path / "r.json"
    result.write_text(json.dumps(solved))
    res = run("plot", result, "-o", tmp_path / "f.png")
    assert res.exit_code == 2
    assert res.output.strip() == ("error: plotting needs matplotlib, which is not "
                                  "installed: pip install calibc[plot]")
    res = run("solve", arm, "--plot", tmp_path / "f.png")
    assert res.exit_code == 2 and "pip install calibc[plot]" in res.output
    assert "status:" not in res.output  # refused before solving


def _param(unit, dom, res, inner=None):
    return {"kind": "param", "domain": dom, "result": res, "true": None, "unit": unit,
            "inner": inner}


def test_domains_one_panel_per_unit_and_the_legend_over_no_bar():
    """Millimetres and radians never share a log axis; the legend sits above the panels."""
    data = {"model": "m.cal", "parameters": {
        "d2": _param("mm", [-5, 5], [-1, 1], [-0.5, 0.5]),
        "alpha2": _param("rad", [-0.01, 0.01], [-0.001, 0.002]),
        "tx": _param("mm", [-5, 5], [-4, 4.5]),
        "k": _param(None, [0, 1], [0.2, 0.3])}}
    fig = figure(data, "domains")
    panels = axes(fig, "domains")
    assert [[t.get_text() for t in ax.get_yticklabels()] for ax in panels] == \
        [["d2", "tx"], ["alpha2"], ["k"]]
    assert ["mm" in panels[0].get_xlabel(), "rad" in panels[1].get_xlabel()] == [True, True]
    fig.canvas.draw()
    legend = panels[0].get_legend().get_window_extent()
    for ax in panels:
        assert legend.y0 >= ax.get_window_extent().y1  # above every panel, over no bar


def test_history_names_every_narrowed_parameter_in_a_colour_never_grey():
    names = [f"p{j}" for j in range(25)]
    units = ["mm" if j % 2 else "rad" for j in range(25)]
    narrowed = set(range(22))
    steps = [{"seconds": s, "widths": [1.0 if s == 0 or j not in narrowed else 0.5 / (1 + s)
                                       for j in range(25)]} for s in range(4)]
    data = {"parameters": {n: {"unit": u} for n, u in zip(names, units, strict=True)},
            "history": {"parameters": names, "steps": steps}}
    fig = figure(data, "history")
    panels = axes(fig, "history")
    assert sorted("mm" in ax.get_ylabel() for ax in panels) == [False, True]
    legends = [t.get_text() for ax in panels for t in ax.get_legend().get_texts()]
    assert sorted(legends) == sorted(names[j] for j in narrowed)
    for ax in panels:
        for line in ax.lines:
            from matplotlib.colors import to_rgb

            r, g, b = to_rgb(line.get_color())
            grey = abs(r - g) < 0.02 and abs(g - b) < 0.02
            assert grey == (line.get_label().startswith("_")), line.get_label()
