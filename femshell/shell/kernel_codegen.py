r"""Generator of the C element-Hessian kernel (:mod:`femshell.shell.fast_element` compiles it):
straight-line value, gradient and Hessian of the element's small nonlinear pieces, followed by the
hand-written element (``element_kernel.c``) that combines them as the split Hessian of
:mod:`femshell.shell.element` does.

A function is traced into a tape of scalar operations (:class:`Tape`) and emitted as
forward-over-reverse code: each node carries its value v and tangent Dv (one lane per input), the
reverse sweep the adjoint w = ∂f/∂v and its tangent Ew, so that at an input i, w_i = ∂f/∂u_i and
Ew_i = ∂²f/∂u_i∂u (the Hessian row). Lanes are short fixed loops, which the C compiler vectorises.

Pieces (the arithmetic of :mod:`femshell.shell.bending` and :mod:`femshell.shell.materials`):

* ``q_<kind>(u, ...)``: :math:`q_k = s_k h_k` of one edge (:func:`~femshell.shell.bending.edge_q`)
  in the 10 unknowns u = (b − a, c − a, p − a, θ) relative to the edge's first vertex a (b its
  second vertex, c the element's third, p the vertex across; q is translation invariant), for
  the edge kinds interior, free, clamped and symmetry; the conormal times the altitude is written
  :math:`b \times N / |b|^2` with :math:`N = b \times c` (equal to bending's
  :math:`(b \times n_f / |b|)(|N| / |b|)`, with two square roots fewer);
* ``w_<law>(z, ...)``: the element energy as a function of z = (a11, a12, a22, q0, q1, q2)
  (:func:`~femshell.shell.element.energy_of_forms`).

``python -m femshell.shell.kernel_codegen`` prints the source.
"""

from __future__ import annotations

from pathlib import Path

from .bending import CLAMPED, FREE, INTERIOR, SYMMETRY

ELEMENT_SOURCE = Path(__file__).with_name("element_kernel.c")


class Node:
    """One scalar of a traced function (operator overloading records it on its tape)."""

    def __init__(self, tape, op, args=(), name=None):
        self.tape, self.op, self.args, self.name = tape, op, args, name
        self.active = op == "in" or any(a.active for a in args)
        self.id = len(tape.nodes)
        tape.nodes.append(self)

    def _node(self, other):
        return other if isinstance(other, Node) else self.tape.const(other)

    def __add__(self, o):
        return self.tape.op("add", self, self._node(o))

    __radd__ = __add__

    def __sub__(self, o):
        return self.tape.op("sub", self, self._node(o))

    def __rsub__(self, o):
        return self.tape.op("sub", self._node(o), self)

    def __mul__(self, o):
        return self.tape.op("mul", self, self._node(o))

    __rmul__ = __mul__

    def __truediv__(self, o):
        return self.tape.op("div", self, self._node(o))

    def __rtruediv__(self, o):
        return self.tape.op("div", self._node(o), self)

    def __neg__(self):
        return self.tape.op("neg", self)


class Tape:
    """The nodes of one traced function, in order; ``inputs`` (lanes) and named ``params``."""

    def __init__(self, n_inputs, params):
        self.nodes, self._cache = [], {}
        self.inputs = [Node(self, "in", name=f"u[{i}]") for i in range(n_inputs)]
        self.params = {p: Node(self, "par", name=p) for p in params}

    def const(self, c):
        key = ("const", float(c))
        if key not in self._cache:
            self._cache[key] = Node(self, "const", name=repr(float(c)))
        return self._cache[key]

    def op(self, op, *args):
        key = (op,) + tuple(a.id for a in args)
        if key not in self._cache:                    # common subexpressions traced once
            self._cache[key] = Node(self, op, args)
        return self._cache[key]


def sqrt(x):
    return x.tape.op("sqrt", x)


def log(x):
    return x.tape.op("log", x)


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def unit(v):
    n = sqrt(dot(v, v))
    return [c / n for c in v]


def sub(a, b):
    return [x - y for x, y in zip(a, b)]


# ---- the pieces ---------------------------------------------------------------------------------

def edge_q(tape, kind):
    """q = s h of an edge (module docstring); params: sign, d0..d2 (clamped normal or symmetry-plane
    normal), flip (the symmetry normal's frozen orientation, ±1)."""
    u = tape.inputs
    b, c, p, theta = u[0:3], u[3:6], u[6:9], u[9]
    P = tape.params
    N = cross(b, c)                                # a = 0: the face normal (times twice the area)
    nf = unit(N)
    t = [P["sign"] * x for x in unit(b)]
    if kind in ("interior", "free"):
        m = unit([x + y for x, y in zip(nf, unit(cross([-x for x in b], sub(p, b))))]) if kind == "interior" else nf
        tm = cross(t, m)
        root = sqrt(1.0 + theta * theta)
        ne = [(x + theta * y) / root for x, y in zip(m, tm)]
    elif kind == "clamped":
        ne = [P["d0"], P["d1"], P["d2"]]
    else:                                            # symmetry: in the plane of normal d, across the edge
        ne = [P["flip"] * x for x in unit(cross([P["d0"], P["d1"], P["d2"]], t))]
    # conormal times altitude: (b × n_f / |b|) (|N| / |b|) = b × N / |b|²
    return dot(ne, cross(b, N)) / dot(b, b)


def energy_of_forms(tape, law):
    """W(z) = A [h ψ(ā⁻¹a) + h³/12 ‖ā⁻¹(b − b̄)‖²] (:func:`femshell.shell.element.energy_of_forms`)."""
    z, P = tape.inputs, tape.params
    ai = [[P["ai00"], P["ai01"]], [P["ai10"], P["ai11"]]]
    a = [[z[0], z[1]], [z[1], z[2]]]
    b = [[2.0 * (z[3] + z[4]), 2.0 * z[3]], [2.0 * z[3], 2.0 * (z[3] + z[5])]]
    bb = [[P["bb00"], P["bb01"]], [P["bb10"], P["bb11"]]]
    alpha, beta = P["alpha"], P["beta"]

    def matmul(x, y):
        return [[x[i][0] * y[0][j] + x[i][1] * y[1][j] for j in range(2)] for i in range(2)]

    def norm2(M):
        tr = M[0][0] + M[1][1]
        return 0.5 * alpha * tr * tr + beta * (M[0][0] * M[0][0] + M[0][1] * M[1][0] + M[1][0] * M[0][1]
                                               + M[1][1] * M[1][1])

    C = matmul(ai, a)
    if law == "svk":
        psi = 0.25 * norm2([[C[0][0] - 1.0, C[0][1]], [C[1][0], C[1][1] - 1.0]])
    else:
        det = C[0][0] * C[1][1] - C[0][1] * C[1][0]
        log_det = log(det)
        psi = 0.5 * beta * (C[0][0] + C[1][1] - 2.0 - log_det) + 0.25 * alpha * (det - 1.0 - log_det)
    M = matmul(ai, [[b[i][j] - bb[i][j] for j in range(2)] for i in range(2)])
    h = P["hbar"]
    return P["area"] * h * psi + P["area"] * h * h * h / 12.0 * norm2(M)


# ---- emission (C) -------------------------------------------------------------------------------

def emit(name, tape, out, params, hessian=True):
    """C source of ``double name(const double *u, double params..., double *D, double *E, double *grad,
    double *hess)``: the forward-over-reverse sweep of the tape ending at ``out``, returning its value;
    D and E are (nodes × lanes) scratch, grad (lanes) and hess (lanes × lanes, row-major) the outputs.
    ``hessian=False``: ``double name(const double *u, double params..., double *grad)``, the reverse
    sweep alone (no tangents), whose value and gradient are the same expressions, so the same bits."""
    n_lanes = len(tape.inputs)
    loop = f"for (int l = 0; l < {n_lanes}; l++)"
    scratch = ["double *D", "double *E", "double *grad", "double *hess"] if hessian else ["double *grad"]
    sig = ", ".join(["const double *u"] + [f"double {p}" for p in params] + scratch)
    lines = [f"static double {name}({sig})", "{"]
    tangent = lines.append if hessian else (lambda line: None)   # the lines of the second-order sweep

    def lane(arr, node):
        return f"{arr}[{node.id * n_lanes} + l]"

    nodes = [n for n in tape.nodes if n.id <= out.id]
    val = {}
    for n in nodes:                                   # forward: values and tangents
        if n.op in ("par", "const"):
            val[n.id] = n.name
            continue
        if n.op == "in":
            i = tape.inputs.index(n)
            val[n.id] = f"u[{i}]"
            tangent(f"    {loop} D[{n.id * n_lanes} + l] = l == {i} ? 1.0 : 0.0;")
            continue
        v = f"v{n.id}"
        val[n.id] = v
        a = n.args[0]
        A = val[a.id]
        if n.op in ("add", "sub", "mul", "div"):
            bn = n.args[1]
            B = val[bn.id]
            sym = {"add": "+", "sub": "-", "mul": "*", "div": "/"}[n.op]
            lines.append(f"    const double {v} = {A} {sym} {B};")
            if not n.active:
                continue
            da = lane("D", a) if a.active else None
            db = lane("D", bn) if bn.active else None
            if n.op == "add":
                expr = " + ".join(t for t in (da, db) if t)
            elif n.op == "sub":
                expr = " - ".join(t for t in (da or "0.0", db) if t)
            elif n.op == "mul":
                expr = " + ".join(t for t in ((f"{da} * {B}" if da else None), (f"{A} * {db}" if db else None)) if t)
            else:
                expr = "(" + " - ".join(t for t in (da or "0.0", (f"{v} * {db}" if db else None)) if t) + f") / {B}"
            tangent(f"    {loop} {lane('D', n)} = {expr};")
        else:
            fn = {"sqrt": f"sqrt({A})", "log": f"log({A})", "neg": f"-{A}"}[n.op]
            lines.append(f"    const double {v} = {fn};")
            if not n.active:
                continue
            d = {"sqrt": f"{lane('D', a)} * (0.5 / {v})", "log": f"{lane('D', a)} / {A}", "neg": f"-{lane('D', a)}"}
            tangent(f"    {loop} {lane('D', n)} = {d[n.op]};")
    seen = {out.id}
    lines.append(f"    double w{out.id} = 1.0;")
    tangent(f"    {loop} {lane('E', out)} = 0.0;")

    def accumulate(target, w_expr, e_expr):
        """w_target += w_expr; E[target] += e_expr (the first contribution declares)."""
        if target.id in seen:
            lines.append(f"    w{target.id} += {w_expr};")
            tangent(f"    {loop} {lane('E', target)} += {e_expr};")
        else:
            seen.add(target.id)
            lines.append(f"    double w{target.id} = {w_expr};")
            tangent(f"    {loop} {lane('E', target)} = {e_expr};")

    for n in reversed(nodes):                         # reverse: adjoints and their tangents
        if n.op in ("in", "par", "const") or not n.active or n.id not in seen:
            continue
        w, En, v = f"w{n.id}", lane("E", n), val[n.id]
        a = n.args[0]
        A = val[a.id]
        if n.op in ("add", "sub"):
            for arg, s in ((a, ""), (n.args[1], "-" if n.op == "sub" else "")):
                if arg.active:
                    accumulate(arg, f"{s}{w}", f"{s}{En}")
        elif n.op == "mul":
            bn = n.args[1]
            B = val[bn.id]
            if a.active:
                accumulate(a, f"{w} * {B}", f"{En} * {B}" + (f" + {w} * {lane('D', bn)}" if bn.active else ""))
            if bn.active:
                accumulate(bn, f"{w} * {A}", f"{En} * {A}" + (f" + {w} * {lane('D', a)}" if a.active else ""))
        elif n.op == "div":                           # v = a / b
            bn = n.args[1]
            B = val[bn.id]
            if a.active:
                e = f"{En} / {B}" + (f" - {w} * {lane('D', bn)} / ({B} * {B})" if bn.active else "")
                accumulate(a, f"{w} / {B}", e)
            if bn.active:
                accumulate(bn, f"-{w} * {v} / {B}", f"-({En} * {v} + {w} * {lane('D', n)}) / {B}"
                                                    f" + {w} * {v} * {lane('D', bn)} / ({B} * {B})")
        elif n.op == "sqrt":
            accumulate(a, f"{w} * (0.5 / {v})", f"{En} * (0.5 / {v}) - {w} * 0.5 * {lane('D', n)} / ({v} * {v})")
        elif n.op == "log":
            accumulate(a, f"{w} / {A}", f"{En} / {A} - {w} * {lane('D', a)} / ({A} * {A})")
        elif n.op == "neg":
            accumulate(a, f"-{w}", f"-{En}")
    for i, n in enumerate(tape.inputs):
        if n.id in seen:
            lines.append(f"    grad[{i}] = w{n.id};")
            tangent(f"    {loop} hess[{i * n_lanes} + l] = {lane('E', n)};")
        else:
            lines.append(f"    grad[{i}] = 0.0;")
            tangent(f"    {loop} hess[{i * n_lanes} + l] = 0.0;")
    lines += [f"    return {val[out.id]};", "}"]
    return "\n".join(lines), len(nodes)


EDGE_KINDS = ("interior", "free", "clamped", "symmetry")
LAWS = ("svk", "neo-hookean")
EDGE_PARAMS = ("sign", "d0", "d1", "d2", "flip")
LAW_PARAMS = ("ai00", "ai01", "ai10", "ai11", "bb00", "bb01", "bb10", "bb11", "area", "hbar", "alpha", "beta")


def source() -> str:
    """The C source of the element Hessian kernel: the generated pieces, then the hand-written
    element (``element_kernel.c``, which calls them)."""
    parts = ["/* generated by femshell/shell/kernel_codegen.py from the element's formulas */", "#include <math.h>",
             "#include <stddef.h>", "#include <stdint.h>", ""]
    parts += [f"#define {name} {value}" for name, value in
              (("INTERIOR", INTERIOR), ("FREE", FREE), ("CLAMPED", CLAMPED), ("SYMMETRY", SYMMETRY))]
    scratch = 0
    pieces = [(f"q_{kind}", 10, EDGE_PARAMS, lambda tape, k=kind: edge_q(tape, k)) for kind in EDGE_KINDS]
    pieces += [(f"w_{law.replace('-', '_')}", 6, LAW_PARAMS, lambda tape, w=law: energy_of_forms(tape, w)) for law in LAWS]
    for name, n_inputs, params, build in pieces:       # each with its gradient-only twin (name_gradient)
        tape = Tape(n_inputs, params)
        code, nodes = emit(name, tape, build(tape), params)
        tape = Tape(n_inputs, params)
        parts += [code, "", emit(f"{name}_gradient", tape, build(tape), params, hessian=False)[0], ""]
        scratch = max(scratch, nodes * n_inputs)
    parts.append(f"#define SCRATCH {scratch}")
    parts.append(ELEMENT_SOURCE.read_text())
    return "\n".join(parts) + "\n"


if __name__ == "__main__":
    print(source())
