"""The flat program: primitives grouped by (DAG level, operation).

A group is a handful of integer arrays, and the propagator runs one group with a few numpy
calls, whatever its size.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.compile.decompose import decompose_arrays
from calib_dsl.compile.replicate import NotBatchable, replicate, tile_groups
from calib_dsl.ir.dag import paused_gc
from calib_dsl.ir.model import Model
from calib_dsl.ir.primitives import Primitive, PrimitiveArrays
from calib_dsl.ir.program import Group, Program


def compile_model(model: Model) -> Program:
    """The flat program of an elaborated model; a loop compiled once (`model.batch`) is
    replicated for all its rows, or, if its template rows are no copies of each other,
    elaborated again unrolled."""
    with paused_gc():  # hundreds of thousands of primitives: no cycles to look for
        slots, prims, arrays = decompose_arrays(model)
    truth = {v.name: v.true for v in model.dag.variables.values()}
    domains = {v.name: (v.lo, v.hi) for v in model.dag.variables.values()}
    priors = {v.name: v.prior for v in model.dag.variables.values() if v.prior is not None}
    stated = {v.name for v in model.dag.variables.values() if v.true_stated}
    units = {v.name: v.unit for v in model.dag.variables.values() if v.unit is not None}
    tables = {t.name: (t.path, len(t.numbers) or t.rows) for t in model.tables}
    if model.batch is None:
        return Program(model.path, model.formulation, slots, prims, groups_of(arrays), truth,
                       domains, priors, true_stated=stated, units=units, tables=tables,
                       sources=model.sources)
    try:
        slots, tiled, template, layout = replicate(model, slots, prims, arrays)
    except NotBatchable:
        return compile_model(model.batch.unrolled())
    return Program(model.path, model.formulation, slots, tiled,
                   tile_groups(groups_of(template), layout), truth, domains, priors,
                   true_stated=stated, rows=layout, units=units,
                   tables=tables, sources=model.sources)


def make_groups(prims: list[Primitive]) -> list[Group]:
    buckets: dict[tuple[int, str], list[int]] = {}
    for i, p in enumerate(prims):
        buckets.setdefault((p.level, p.op), []).append(i)
    return [_group(op, level, idx, prims) for (level, op), idx in sorted(buckets.items())]


def groups_of(a: PrimitiveArrays) -> list[Group]:
    """make_groups from the primitives' arrays (the same groups, without a pass over the
    primitive objects)."""
    if not a.op:
        return []
    code = {o: k for k, o in enumerate(sorted(set(a.op)))}  # in the order of the op names
    op = np.fromiter(map(code.__getitem__, a.op), dtype=np.int64, count=len(a.op))
    order = np.lexsort((op, a.level))  # by (level, op name), stable: primitive order within
    key = a.level[order] * len(code) + op[order]
    cut = np.flatnonzero(np.diff(key)) + 1
    groups = []
    for idx in np.split(order, cut):
        i0 = int(idx[0])
        name = a.op[i0]
        k = int(a.arity[i0])
        out = a.out[idx, :2 if name == "rot" else 1]
        args = a.args[idx, :k]
        param = None
        if a.param[i0] is not None:
            param = np.array([a.param[i] for i in idx.tolist()], dtype=float)
        groups.append(Group(name, int(a.level[i0]), np.ascontiguousarray(out),
                            np.ascontiguousarray(args), param, idx.astype(np.int64),
                            tuple(_unique(c) for c in out.T), tuple(_unique(c) for c in args.T)))
    return groups


def _group(op: str, level: int, idx: list[int], prims: list[Primitive]) -> Group:
    out = np.array([prims[i].out for i in idx], dtype=np.int64)
    args = np.array([prims[i].args for i in idx], dtype=np.int64)
    params = [prims[i].param for i in idx]
    param = None if params[0] is None else np.array(params, dtype=float)
    return Group(op, level, out, args, param, np.array(idx, dtype=np.int64),
                 tuple(_unique(c) for c in out.T), tuple(_unique(c) for c in args.T))


def _unique(column: np.ndarray) -> bool:
    """No slot twice in the column (a sort: np.unique hashes, many times slower here)."""
    s = np.sort(column)
    return bool((s[1:] != s[:-1]).all())
