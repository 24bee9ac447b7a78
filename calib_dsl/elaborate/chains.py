"""A serial chain as DAG expressions: the workshop coordinates of a tool point.

Khalil–Kleinfinger modified DH: frame j-1 to frame j is `Rx(alpha_j) Tx(d_j) Rz(theta_j) Tz(r_j)`.
Two formulations of the same model (PAPER_NOTES, algorithms f and g):

- "matrix": 4x4 homogeneous matrices with symbolic entries, multiplied out to scalar
  expressions (M := T_j M from the last joint back), then x = M p. The matrix entries do not
  depend on the point, so hash-consing shares them between the tool points.
- "rotation": the point is carried through the chain, each rotation one `rot` primitive
  (the `rotu`/`rotv` pair), so the propagator can contract it as a whole.

Only exact simplifications are made (an angle that is the constant 0 is no rotation; adding or
multiplying by the constants 0 and 1 creates no node), so no value is ever lost.
"""

from __future__ import annotations

from dataclasses import dataclass

from calib_dsl.ir.dag import Dag

FORMULATIONS = ("matrix", "rotation")

Vec3 = tuple[int, int, int]
# A 3x4 block of node ids: the top of a homogeneous transform (the last row is 0 0 0 1).
Mat34 = list[list[int]]


@dataclass
class Frame:
    """One modified-DH transform Rx(alpha) Tx(d) Rz(theta) Tz(r); entries are DAG node ids."""

    alpha: int
    d: int
    theta: int
    r: int


@dataclass
class Transform:
    """Any other frame: elementary steps in product order, each ("Rx" | "Ry" | "Rz" | "Tx" |
    "Ty" | "Tz", node): T = step1 . step2 . ..."""

    steps: tuple[tuple[str, int], ...]


def xyz_euler(x: int, y: int, z: int, rx: int, ry: int, rz: int) -> Transform:
    """A 6-DOF frame: the translation (x, y, z), then the rotation Rx(rx) Ry(ry) Rz(rz)
    (intrinsic X-Y-Z Euler angles: about x, then the new y, then the new z)."""
    return Transform((("Tx", x), ("Ty", y), ("Tz", z), ("Rx", rx), ("Ry", ry), ("Rz", rz)))


def standard_dh(theta: int, d: int, a: int, alpha: int) -> Transform:
    """A standard (Denavit-Hartenberg) joint frame: Rz(theta) Tz(d) Tx(a) Rx(alpha)."""
    return Transform((("Rz", theta), ("Tz", d), ("Tx", a), ("Rx", alpha)))


AnyFrame = Frame | Transform


def forward_point(dag: Dag, frames: list[AnyFrame], point: Vec3, formulation: str) -> Vec3:
    """Workshop coordinates T0 T1 ... Tn . point as DAG nodes (`point` is in the last frame)."""
    if formulation == "matrix":
        return _apply(dag, _cached_chain_matrix(dag, frames), point)
    if formulation == "rotation":
        return _rotation_chain(dag, frames, point)
    raise ValueError(f"unknown formulation {formulation!r}; expected one of {FORMULATIONS}")


def forward_axes(dag: Dag, frames: list[AnyFrame], formulation: str) -> tuple[int, ...]:
    """The rotation part of T0 T1 ... Tn (the last frame's axes in the workshop frame), row
    by row: 9 nodes. The rotation formulation carries each unit vector through the chain's
    rotations alone (a direction is not translated), one `rot` primitive per rotation."""
    if formulation == "matrix":
        m = _cached_chain_matrix(dag, frames)
        return tuple(m[i][k] for i in range(3) for k in range(3))
    if formulation == "rotation":
        zero, one = dag.const(0.0), dag.const(1.0)
        units: list[Vec3] = [(one, zero, zero), (zero, one, zero), (zero, zero, one)]
        columns = [_rotation_chain(dag, frames, u, translate=False) for u in units]
        return tuple(columns[k][i] for i in range(3) for k in range(3))
    raise ValueError(f"unknown formulation {formulation!r}; expected one of {FORMULATIONS}")


def euler_xyz(dag: Dag, rx: int, ry: int, rz: int) -> tuple[int, ...]:
    """Rx(rx) Ry(ry) Rz(rz) (intrinsic X-Y-Z Euler angles), row by row: 9 nodes."""
    m = _transform_matrix(dag, Transform((("Rx", rx), ("Ry", ry), ("Rz", rz))))
    return tuple(m[i][k] for i in range(3) for k in range(3))


def compose(dag: Dag, a: tuple[int, ...], b: tuple[int, ...]) -> tuple[int, ...]:
    """The product a . b of two 3x3 matrices given row by row (9 nodes each)."""
    def rows(v: tuple[int, ...]) -> Mat34:
        zero = dag.const(0.0)
        return [[v[3 * i], v[3 * i + 1], v[3 * i + 2], zero] for i in range(3)]

    m = _matmul(dag, rows(a), rows(b))
    return tuple(m[i][k] for i in range(3) for k in range(3))


# -- algorithm f: homogeneous matrices ------------------------------------------------------
def chain_matrix(dag: Dag, frames: list[AnyFrame]) -> Mat34:
    """The top 3x4 block of T0 T1 ... Tn, built from the last joint back as the paper does."""
    if not frames:
        return _identity(dag)
    m = frame_matrix(dag, frames[-1])
    for frame in reversed(frames[:-1]):
        m = _matmul(dag, frame_matrix(dag, frame), m)
    return m


# The elaborator asks for each tool point of a configuration in turn: hash-consing would
# share the matrix anyway, but rebuilding it repeats every dag.op call (docs/decisions/09).
# Nodes never change, so the DAG keeps the last few matrices, by the nodes of their frames.
_CACHE_SIZE = 8


def _cached_chain_matrix(dag: Dag, frames: list[AnyFrame]) -> Mat34:
    cache: dict[tuple, Mat34] = dag.memo.setdefault("chain matrices", {})
    key = tuple((f.alpha, f.d, f.theta, f.r) if isinstance(f, Frame) else f.steps
                for f in frames)
    hit = cache.get(key)
    if hit is not None:
        return hit
    m = chain_matrix(dag, frames)
    if len(cache) >= _CACHE_SIZE:
        del cache[next(iter(cache))]  # the oldest
    cache[key] = m
    return m


def frame_matrix(dag: Dag, f: AnyFrame) -> Mat34:
    """A frame's matrix; for the modified-DH Frame, Rx(alpha) Tx(d) Rz(theta) Tz(r)
    multiplied out:

        [ ct      -st      0    d      ]
        [ ca st    ca ct  -sa  -sa r   ]
        [ sa st    sa ct   ca   ca r   ]
    """
    if isinstance(f, Transform):
        return _transform_matrix(dag, f)
    ca, sa = _cos_sin(dag, f.alpha)
    ct, st = _cos_sin(dag, f.theta)
    msa = _neg(dag, sa)  # shared by the (1,2) and (1,3) entries
    zero = dag.const(0.0)

    def mul(x: int, y: int) -> int:
        return dag.op("mul", x, y)

    return [
        [ct, _neg(dag, st), zero, f.d],
        [mul(ca, st), mul(ca, ct), msa, mul(msa, f.r)],
        [mul(sa, st), mul(sa, ct), ca, mul(ca, f.r)],
    ]


def _transform_matrix(dag: Dag, f: Transform) -> Mat34:
    """The product of the elementary matrices of the steps (a zero step is the identity)."""
    m = _identity(dag)
    for kind, node in f.steps:
        if dag.point(node) == 0.0:
            continue
        m = _matmul(dag, m, _elementary(dag, kind, node))
    return m


def _elementary(dag: Dag, kind: str, node: int) -> Mat34:
    m = _identity(dag)
    if kind[0] == "T":
        m["xyz".index(kind[1].lower())][3] = node
        return m
    c, s = _cos_sin(dag, node)
    i, j = {"Rx": (1, 2), "Ry": (2, 0), "Rz": (0, 1)}[kind]  # the plane it turns: i -> j
    m[i][i], m[j][j] = c, c
    m[i][j], m[j][i] = _neg(dag, s), s
    return m


def _matmul(dag: Dag, a: Mat34, b: Mat34) -> Mat34:
    """a . b for homogeneous transforms (implicit last rows 0 0 0 1)."""
    zero = _zeros(dag, a, b)
    op = dag.op
    out: Mat34 = []
    for i in range(3):
        ai = a[i]
        row = []
        for k in range(4):
            # a product with a structural zero is the zero constant, and adding it makes no
            # node: leaving it out of the sum makes the same nodes, in the same order
            terms = [op("mul", ai[j], b[j][k]) for j in range(3)
                     if not (zero[ai[j]] or zero[b[j][k]])]
            if k == 3:
                terms.append(ai[3])
            row.append(_sum(dag, terms))
        out.append(row)
    return out


def _apply(dag: Dag, m: Mat34, p: Vec3) -> Vec3:
    """x = M . (p, 1)."""
    x = [_sum(dag, [dag.op("mul", m[i][j], p[j]) for j in range(3)] + [m[i][3]])
         for i in range(3)]
    return x[0], x[1], x[2]


def _zeros(dag: Dag, a: Mat34, b: Mat34) -> dict[int, bool]:
    """Which entries of a and b are the constant 0 (the point [0, 0]); by node id."""
    return {e: dag.point(e) == 0.0 for row in (*a, *b) for e in row}


def _identity(dag: Dag) -> Mat34:
    zero, one = dag.const(0.0), dag.const(1.0)
    return [[one if i == k else zero for k in range(4)] for i in range(3)]


# -- algorithm g: one rotation primitive per rotation ---------------------------------------
def _rotation_chain(dag: Dag, frames: list[AnyFrame], point: Vec3,
                    translate: bool = True) -> Vec3:
    """The point carried through the chain, the last frame first; without `translate`, a
    direction: the rotations alone."""
    c1, c2, c3 = point
    for f in reversed(frames):
        if isinstance(f, Transform):
            c1, c2, c3 = _rotation_steps(dag, f, (c1, c2, c3), translate)
            continue
        if translate:
            c3 = dag.op("add", c3, f.r)
        c1, c2 = _rot(dag, f.theta, c1, c2)
        if translate:
            c1 = dag.op("add", c1, f.d)
        c2, c3 = _rot(dag, f.alpha, c2, c3)
    return c1, c2, c3


def _rotation_steps(dag: Dag, f: Transform, c: Vec3, translate: bool = True) -> Vec3:
    """The steps applied to a point, the last first: a translation adds, a rotation is one
    `rot` primitive in its plane (Rx turns (y, z), Ry (z, x), Rz (x, y))."""
    xyz = list(c)
    for kind, node in reversed(f.steps):
        if kind[0] == "T":
            if not translate:
                continue
            k = "xyz".index(kind[1].lower())
            xyz[k] = dag.op("add", xyz[k], node)
            continue
        i, j = {"Rx": (1, 2), "Ry": (2, 0), "Rz": (0, 1)}[kind]
        xyz[i], xyz[j] = _rot(dag, node, xyz[i], xyz[j])
    return xyz[0], xyz[1], xyz[2]


def _rot(dag: Dag, beta: int, u: int, v: int) -> tuple[int, int]:
    # Exact: a zero angle or a zero vector is left unchanged, and creates no node.
    if dag.point(beta) == 0.0 or (dag.point(u) == 0.0 and dag.point(v) == 0.0):
        return u, v
    return dag.rot(beta, u, v)


# -- exact helpers --------------------------------------------------------------------------
def _cos_sin(dag: Dag, angle: int) -> tuple[int, int]:
    # The constant angle 0 is the identity rotation: no cos/sin node, no folding needed.
    if dag.point(angle) == 0.0:
        return dag.const(1.0), dag.const(0.0)
    return dag.op("cos", angle), dag.op("sin", angle)


def _neg(dag: Dag, x: int) -> int:
    # -0 is 0: keeps structural zeros structural (and needs no constant folding).
    return x if dag.point(x) == 0.0 else dag.op("neg", x)


def _sum(dag: Dag, terms: list[int]) -> int:
    """Left fold of `add`; `dag.op` drops the structural zeros (no terms: the zero)."""
    if not terms:
        return dag.const(0.0)
    total = terms[0]
    op = dag.op
    for t in terms[1:]:
        total = op("add", total, t)
    return total
