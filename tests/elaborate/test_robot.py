"""robot.py: both formulations against the numeric kinematics, and the shape of the DAG."""

from __future__ import annotations

import math
from collections import Counter
from importlib.util import find_spec

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.elaborate.chains import FORMULATIONS, Frame, forward_point
from calib_dsl.ir.dag import Dag
from calib_dsl.studies.evaluate import evaluate
from calib_dsl.studies.kinematics import RX90_PARAMS, RX90_TOOL, forward, rx90_frames

# A joint: (alpha, d, theta0, r0, prismatic); a None parameter is the structural constant 0.
angle = st.one_of(st.none(), st.floats(-math.pi, math.pi))
length = st.one_of(st.none(), st.floats(-1.0, 1.0))
joint = st.tuples(angle, length, angle, length, st.booleans())
coord = st.floats(-0.5, 0.5)


def build_chain(dag: Dag, joints, q, *, constants: bool):
    """Frames for `joints` at joint values q ((J,) or (J,N)), plus {var node: value}.

    constants=True: every value is a point constant (folded by interval arithmetic);
    otherwise every parameter and joint value is a var (nothing to fold), except the Nones.
    """
    values: dict[int, object] = {}
    zero = dag.const(0.0)

    def leaf(name: str, x):
        if constants:
            return dag.const(float(x))
        node = dag.var(name, -10.0, 10.0)
        values[node] = x
        return node

    frames = []
    for j, (alpha, d, theta, r, prismatic) in enumerate(joints):
        a, dd, t, rr = (zero if x is None else leaf(f"{p}{j}", x)
                        for p, x in zip(("alpha", "d", "theta", "r"), (alpha, d, theta, r),
                                        strict=True))
        qj = leaf(f"q{j}", q[j])
        if prismatic:
            rr = dag.op("add", rr, qj)
        else:
            t = dag.op("add", t, qj)
        frames.append(Frame(a, dd, t, rr))
    return frames, values


def numeric_frames(joints, q):
    out = []
    for j, (alpha, d, theta, r, prismatic) in enumerate(joints):
        a, dd, t, rr = (0.0 if x is None else x for x in (alpha, d, theta, r))
        out.append((a, dd, t, rr + q[j]) if prismatic else (a, dd, t + q[j], rr))
    return out


# -- values ---------------------------------------------------------------------------------
@pytest.mark.parametrize("formulation", FORMULATIONS)
@settings(max_examples=150, deadline=None)
@given(joints=st.lists(joint, min_size=0, max_size=8), data=st.data())
def test_general_chain_with_variables(formulation, joints, data):
    # Revolute and prismatic joints, random DH parameters, some structurally zero.
    n = 4
    q = np.array([data.draw(st.lists(st.floats(-3.0, 3.0), min_size=n, max_size=n))
                  for _ in joints]).reshape(len(joints), n)
    b = data.draw(st.tuples(coord, coord, coord))
    dag = Dag()
    frames, values = build_chain(dag, joints, q, constants=False)
    bx = tuple(dag.var(f"b{i}", -1.0, 1.0) for i in range(3))
    values.update({bx[i]: b[i] for i in range(3)})
    out = forward_point(dag, frames, bx, formulation)
    val = evaluate(dag, values)
    got = np.array([np.broadcast_to(val[o], (n,)) for o in out]).T
    ref = np.broadcast_to(forward(numeric_frames(joints, q), b), (n, 3))
    np.testing.assert_allclose(got, ref, atol=1e-12)


# -- guaranteed enclosure under constant folding ---------------------------------------------
# Folding is the interval arithmetic of calib_dsl.arith; the exact reference uses mpmath
# when it is installed (60 digits: the real value of the float inputs, to within 1e-55).
needs_mpmath = pytest.mark.skipif(find_spec("mpmath") is None, reason="mpmath not installed")


def exact_g(frames, point):
    """Algorithm g in 60-digit arithmetic."""
    from mpmath import mp

    mp.dps = 60
    c1, c2, c3 = (mp.mpf(float(x)) for x in point)
    for a, d, t, r in reversed(frames):
        a, d, t, r = (mp.mpf(float(x)) for x in (a, d, t, r))
        c3 += r
        c1, c2 = c1 * mp.cos(t) - c2 * mp.sin(t), c1 * mp.sin(t) + c2 * mp.cos(t)
        c1 += d
        c2, c3 = c2 * mp.cos(a) - c3 * mp.sin(a), c2 * mp.sin(a) + c3 * mp.cos(a)
    return c1, c2, c3


def folded_point(formulation, joints, q, b):
    dag = Dag()
    frames, _ = build_chain(dag, joints, q, constants=True)
    out = forward_point(dag, frames, tuple(dag.const(x) for x in b), formulation)
    nodes = [dag.nodes[o] for o in out]
    assert all(n.op == "const" for n in nodes), "constants must fold"
    return [n.data for n in nodes]


def assert_contains(boxes, ref, slack=0.0):
    for (lo, hi), x in zip(boxes, ref, strict=True):
        assert lo - slack <= x <= hi + slack, (lo, x, hi)
        assert hi - lo < 1e-9, "folding should stay tight"


def rx90_joints():
    """The RX90 as (alpha, d, theta0, r0, prismatic) rows: the base, then joints 1..6."""
    p = RX90_PARAMS
    return ([(None, None, p["theta0"], p["r0"], False)]
            + [(p[f"alpha{j}"], p[f"d{j}"], p[f"theta{j}"], p[f"r{j}"], False)
               for j in range(1, 6)]
            + [(p["alpha6"], p["d6"], None, None, False)])


@pytest.mark.parametrize("formulation", FORMULATIONS)
@settings(max_examples=100, deadline=None)
@given(q=st.lists(st.floats(-math.pi, math.pi), min_size=6, max_size=6),
       b=st.tuples(coord, coord, coord))
def test_rx90_constants_fold_to_an_enclosure(formulation, q, b):
    joints, qs = rx90_joints(), np.array([0.0, *q])  # the base does not move
    boxes = folded_point(formulation, joints, qs, b)
    frames = numeric_frames(joints, qs)
    assert_contains(boxes, forward(frames, b)[0], slack=1e-13)  # numpy has its own rounding
    if find_spec("mpmath") is not None:
        assert_contains(boxes, exact_g(frames, b))  # the real value: strictly inside


@needs_mpmath
@pytest.mark.parametrize("formulation", FORMULATIONS)
@settings(max_examples=100, deadline=None)
@given(joints=st.lists(joint, min_size=1, max_size=7), data=st.data())
def test_general_chain_constants_fold_to_an_enclosure(formulation, joints, data):
    q = np.array(data.draw(st.lists(st.floats(-3.0, 3.0), min_size=len(joints),
                                    max_size=len(joints))))
    b = data.draw(st.tuples(coord, coord, coord))
    boxes = folded_point(formulation, joints, q, b)
    assert_contains(boxes, exact_g(numeric_frames(joints, q), b))


# -- structure --------------------------------------------------------------------------------
def rx90_params(dag: Dag, values: dict) -> dict[str, int]:
    """All 33 parameters of the RX90 (PAPER_NOTES) as vars at their nominal values."""
    nodes = {}
    names = ["theta0", "r0"] + [f"{k}{j}" for j in range(1, 6) for k in ("alpha", "d", "theta",
                                                                         "r")]
    names += ["alpha6", "d6"] + [f"b{k}{c}" for k in range(1, 4) for c in "xyz"]
    tool = {f"b{k}{c}": RX90_TOOL[k - 1][i] for k in range(1, 4) for i, c in enumerate("xyz")}
    for name in names:
        nodes[name] = dag.var(name, -10.0, 10.0)
        values[nodes[name]] = tool[name] if name in tool else RX90_PARAMS[name]
    return nodes


def rx90_config(dag: Dag, values: dict, p: dict[str, int], q, tag: str = "") -> list[Frame]:
    """The frames of one configuration: a data var per joint angle, theta_j = theta_j° + q_j."""
    qs = []
    for j in range(1, 7):
        qs.append(dag.var(f"q{j}{tag}", -4.0, 4.0, kind="data"))
        values[qs[-1]] = q[j - 1]
    zero = dag.const(0.0)
    frames = [Frame(zero, zero, p["theta0"], p["r0"])]
    frames += [Frame(p[f"alpha{j}"], p[f"d{j}"], dag.op("add", p[f"theta{j}"], qs[j - 1]),
                     p[f"r{j}"]) for j in range(1, 6)]
    frames.append(Frame(p["alpha6"], p["d6"], qs[5], zero))
    return frames


def tool_points(p: dict[str, int], n: int = 3) -> list[tuple[int, int, int]]:
    return [(p[f"b{k}x"], p[f"b{k}y"], p[f"b{k}z"]) for k in range(1, n + 1)]


def test_rx90_both_formulations_vectorized():
    rng = np.random.default_rng(3)
    q = rng.uniform(-np.pi, np.pi, (6, 100))
    dag, values = Dag(), {}
    p = rx90_params(dag, values)
    frames = rx90_config(dag, values, p, q)
    ref = [forward(rx90_frames(q.T), b) for b in RX90_TOOL]
    for formulation in FORMULATIONS:
        outs = [forward_point(dag, frames, b, formulation) for b in tool_points(p)]
        val = evaluate(dag, values)
        for out, r in zip(outs, ref, strict=True):
            np.testing.assert_allclose(np.array([val[o] for o in out]).T, r, atol=1e-13)


def per_configuration(formulation: str, n_points: int) -> Counter:
    """Node ops one configuration adds (q vars, theta sums, chain), the parameters existing."""
    dag, values = Dag(), {}
    p = rx90_params(dag, values)
    before = Counter(n.op for n in dag.nodes)
    frames = rx90_config(dag, values, p, np.zeros(6))
    for b in tool_points(p, n_points):
        forward_point(dag, frames, b, formulation)
    return Counter(n.op for n in dag.nodes) - before


def test_matrix_entries_are_shared_between_tool_points():
    one, three = per_configuration("matrix", 1), per_configuration("matrix", 3)
    assert sum(three.values()) < 1.5 * sum(one.values())
    # Each extra point costs only x = M p: 3 x (3 mul + 3 add).
    assert three - one == Counter(mul=18, add=18)
    assert "rotu" not in three


def test_rotation_formulation_uses_rotation_primitives():
    one, three = per_configuration("rotation", 1), per_configuration("rotation", 3)
    assert three["rotu"] == three["rotv"] == 3 * one["rotu"] > 0
    assert not {"cos", "sin", "mul"} & set(three)


def test_rotation_formulation_skips_zero_angles_and_zero_lengths():
    dag = Dag()
    zero = dag.const(0.0)
    t = dag.var("t", -1.0, 1.0)
    p = tuple(dag.var(c, -1.0, 1.0) for c in "xyz")
    before = len(dag.nodes)
    out = forward_point(dag, [Frame(zero, zero, t, zero)], p, "rotation")
    assert [dag.nodes[i].op for i in range(before, len(dag.nodes))] == ["rotu", "rotv"]
    assert out[2] == p[2]


def test_matrix_zero_alpha_collapses():
    # Rx(0) Tx(0) Rz(t) Tz(r) is Rz(t) Tz(r): only cos t, sin t and -sin t, no alpha terms.
    dag = Dag()
    zero = dag.const(0.0)
    t, r = dag.var("t", -1.0, 1.0), dag.var("r", -1.0, 1.0)
    p = tuple(dag.var(c, -1.0, 1.0) for c in "xyz")
    before = len(dag.nodes)
    forward_point(dag, [Frame(zero, zero, t, r)], p, "matrix")
    ops = Counter(dag.nodes[i].op for i in range(before, len(dag.nodes))
                  if dag.nodes[i].op != "const")
    # x = ct px + (-st) py; y = st px + ct py; z = pz + r.
    assert ops == Counter(cos=1, sin=1, neg=1, mul=4, add=3)


def test_empty_chain_and_unknown_formulation():
    dag = Dag()
    p = tuple(dag.var(c, -1.0, 1.0) for c in "xyz")
    for formulation in FORMULATIONS:
        assert forward_point(dag, [], p, formulation) == p
    with pytest.raises(ValueError, match="formulation"):
        forward_point(dag, [], p, "quaternion")


def test_matrix_is_built_once_per_configuration():
    # Each tool point of a configuration reuses the chain's matrix: few dag.op calls per point.
    dag, values = Dag(), {}
    p = rx90_params(dag, values)
    frames = rx90_config(dag, values, p, np.zeros(6))
    calls = Counter()
    op = dag.op

    def counting(*args, **kwargs):
        calls["op"] += 1
        return op(*args, **kwargs)

    dag.op = counting  # type: ignore[method-assign]
    forward_point(dag, frames, tool_points(p)[0], "matrix")
    first = calls["op"]
    forward_point(dag, frames, tool_points(p)[1], "matrix")
    assert calls["op"] - first == 18  # x = M p only


def test_matrix_cache_never_crosses_dags():
    # Same frame node ids in two DAGs that mean different things.
    results = []
    for sign in (1.0, -1.0):
        dag = Dag()
        zero = dag.const(0.0)
        t = dag.var("t", -9.0, 9.0)
        frame = Frame(zero, zero, t, zero)
        pt = tuple(dag.var(c, -9.0, 9.0) for c in "xyz")
        out = forward_point(dag, [frame], pt, "matrix")
        val = evaluate(dag, {t: sign * 0.5, pt[0]: 1.0, pt[1]: 0.0, pt[2]: 0.0})
        results.append([val[o] for o in out])
        del dag
    np.testing.assert_allclose(results[0], [math.cos(0.5), math.sin(0.5), 0.0])
    np.testing.assert_allclose(results[1], [math.cos(0.5), -math.sin(0.5), 0.0])
