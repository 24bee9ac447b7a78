"""Float evaluation of a DAG (not guaranteed: for simulation and tests only).

Nodes are grouped by (depth, op) so each group is one numpy operation: a DAG of 500k nodes
costs a few hundred groups, not 500k Python steps. Values may be batched: a var given an array
of shape (K,) makes every node's value an array of shape (K,).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib_dsl.ir.dag import Dag

Array = NDArray[np.float64]


def _pow(k: int) -> Callable[[Array], Array]:
    return lambda x: np.power(x, float(k))


_FUNCS: dict[str, Callable[..., Array]] = {
    "neg": np.negative, "sqr": np.square, "sqrt": np.sqrt, "exp": np.exp, "log": np.log,
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "abs": np.abs,
    "add": np.add, "sub": np.subtract, "mul": np.multiply, "div": np.divide,
    "atan2": np.arctan2,
    "rotu": lambda b, u, v: u * np.cos(b) - v * np.sin(b),
    "rotv": lambda b, u, v: u * np.sin(b) + v * np.cos(b),
}


@dataclass
class _Group:
    func: Callable[..., Array]
    nodes: NDArray[np.intp]
    args: list[NDArray[np.intp]]  # one index array per argument position


class Evaluator:
    """Evaluation plan of a DAG as it is now (build once, evaluate many value sets)."""

    def __init__(self, dag: Dag) -> None:
        self.size = len(dag.nodes)
        const_ids, const_vals, var_ids, var_names = [], [], [], []
        depth = [0] * self.size
        keyed: dict[tuple[int, str, object], list[int]] = {}
        for i, n in enumerate(dag.nodes):
            if n.op == "const":
                lo, hi = n.data[:2]
                const_ids.append(i)
                const_vals.append(lo if lo == hi else 0.5 * lo + 0.5 * hi)  # the midpoint
            elif n.op == "var":
                var_ids.append(i)
                var_names.append(n.data)
            else:
                d = 1 + max([depth[a] for a in n.args])
                depth[i] = d
                key = (d, n.op, n.data if n.op == "pow" else None)
                group = keyed.get(key)
                if group is None:
                    keyed[key] = [i]
                else:
                    group.append(i)
        self.const_ids = np.array(const_ids, dtype=np.intp)
        self.const_vals = np.array(const_vals, dtype=float)
        self.var_ids: list[int] = var_ids
        self.var_names: list[str] = var_names
        self.groups = [self._group(dag, key, ids) for key, ids in sorted(keyed.items(),
                                                                          key=lambda kv: kv[0][0])]

    @staticmethod
    def _group(dag: Dag, key: tuple[int, str, object], ids: list[int]) -> _Group:
        _, op, data = key
        func = _pow(int(data)) if op == "pow" else _FUNCS[op]  # type: ignore[call-overload]
        arity = len(dag.nodes[ids[0]].args)
        args = [np.array([dag.nodes[i].args[k] for i in ids], dtype=np.intp)
                for k in range(arity)]
        return _Group(func, np.array(ids, dtype=np.intp), args)

    def __call__(self, values: Mapping[int, ArrayLike], default: float | None = None) -> Array:
        """Every node's value, shape (n_nodes,) + batch; `values` maps var node ids to values.

        A var missing from `values` takes `default` (e.g. nan for "unknown yet"), or is an error.
        """
        batch = np.broadcast_shapes(*(np.shape(v) for v in values.values()))
        out = np.empty((self.size,) + batch)
        out[self.const_ids] = self.const_vals.reshape((-1,) + (1,) * len(batch))
        for i, name in zip(self.var_ids, self.var_names, strict=True):
            if i in values:
                out[i] = values[i]
            elif default is not None:
                out[i] = default
            else:
                raise KeyError(f"no value for variable {name!r} (node {i})")
        with np.errstate(all="ignore"):  # nan/inf propagate: the caller decides
            for g in self.groups:
                out[g.nodes] = g.func(*(out[a] for a in g.args))
        return out


def evaluate(dag: Dag, values: Mapping[int, ArrayLike], default: float | None = None) -> Array:
    """Float value of every node in node order (constants at their midpoint)."""
    return Evaluator(dag)(values, default)


def values_by_name(dag: Dag, named: Mapping[str, ArrayLike]) -> dict[int, ArrayLike]:
    """{variable name: value} to the {node id: value} that `evaluate` takes."""
    return {dag.variables[name].node: v for name, v in named.items()}
