"""Chain-specialised kinematics kernels, generated as straight-line Python.

Why: a generic loop of 4×4 numpy products costs ~100 µs per configuration, almost
all of it numpy's per-call overhead on tiny arrays. A chain's constant geometry
(DH a, d, α, base and tool) is known when the chain is built, so we write out the
forward recursion symbolically once, fold away every product with 0 and ±1
(most DH twists are 0 or ±90°), drop dead code, and compile the result with
``exec``. The same source runs

* on Python floats (``math.cos``), for one configuration — a few µs;
* on numpy arrays (``numpy.cos``), for a batch — one ufunc call per line over the
  whole batch, using the structure of each joint transform instead of generic
  4×4 products.

The recursion for joint i is ``T_i = T_{i-1} · P_i · M_i(q_i) · Q_i`` with constant
``P_i``, ``Q_i`` and the joint motion ``M_i`` = Rz(q) (revolute) or Tz(q) (prismatic),
see `ratectl.model.joints.Joint`. The joint's world axis is the z axis of
``T_{i-1} P_i`` and its origin a point on it, which gives the geometric Jacobian
columns:

* revolute:  ``[ z × (p_ref − o) ; z ]``
* prismatic: ``[ z ; 0 ]``
"""

from __future__ import annotations

import itertools
import linecache
import math
import re

import numpy as np

from .reference import MAX_PRISMATIC

_SNAP = 1e-15


def _snap(x: float) -> float:
    """Round values within 1e-15 of 0, ±1 to exactly that (cos(π/2) → 0)."""
    for target in (0.0, 1.0, -1.0):
        if abs(x - target) < _SNAP:
            return target
    return float(x)


class _Emitter:
    """Builds straight-line code over symbolic scalars.

    A scalar is a Python float (a known constant) or a string naming a local
    variable, optionally prefixed by ``-``.
    """

    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []  # (target, expression)
        self._n = 0

    def new(self, expr: str, prefix: str = "t") -> str:
        name = f"{prefix}{self._n}"
        self._n += 1
        self.lines.append((name, expr))
        return name

    def lin(self, terms) -> float | str:
        """Value of Σ coef·Πfactors, folding constants, zeros and signs."""
        const = 0.0
        parts: list[tuple[float, list[str]]] = []
        for coef, factors in terms:
            coef = float(coef)
            names: list[str] = []
            for f in factors:
                if isinstance(f, str):
                    if f.startswith("-"):
                        coef = -coef
                        f = f[1:]
                    names.append(f)
                else:
                    coef *= f
            coef = _snap(coef)
            if coef == 0.0:
                continue
            if not names:
                const += coef
            else:
                parts.append((coef, sorted(names)))
        const = _snap(const)
        if not parts:
            return const
        if len(parts) == 1 and const == 0.0 and abs(parts[0][0]) == 1.0 and len(parts[0][1]) == 1:
            name = parts[0][1][0]
            return name if parts[0][0] > 0 else "-" + name
        # Factor out a sign so that the emitted line starts with a positive term:
        # callers fold the sign of the returned reference for free.
        sign = 1.0
        if all(c < 0 for c, _ in parts) and const <= 0.0:
            sign = -1.0
            parts = [(-c, names) for c, names in parts]
            const = -const
        parts.sort(key=lambda t: t[0] < 0)
        text = ""
        for k, (coef, names) in enumerate(parts):
            prod = "*".join(names)
            mag = abs(coef)
            term = prod if mag == 1.0 else f"{prod}*{mag!r}"
            if k == 0:
                text = term if coef > 0 else f"{prod}*{coef!r}"
            else:
                text += (" + " if coef > 0 else " - ") + term
        if const != 0.0:
            if const > 0 and parts[0][0] < 0:
                text = f"{const!r} + {text}"
            else:
                text += (" + " if const > 0 else " - ") + repr(abs(const))
        name = self.new(text)
        return name if sign > 0 else "-" + name
        return self.new(text)


def _ref(v) -> str:
    """Source text of a symbolic scalar."""
    if isinstance(v, str):
        return f"({v})" if v.startswith("-") else v
    return repr(float(v))


class _Frame:
    """Symbolic pose: rotation R (3×3 scalars) and position p (3 scalars)."""

    def __init__(self, T: np.ndarray) -> None:
        self.R = [[_snap(T[r, c]) for c in range(3)] for r in range(3)]
        self.p = [_snap(T[r, 3]) for r in range(3)]

    def apply_constant(self, em: _Emitter, C: np.ndarray) -> None:
        R, p = self.R, self.p
        CR = [[_snap(C[r, c]) for c in range(3)] for r in range(3)]
        Cp = [_snap(C[r, 3]) for r in range(3)]
        newp = [em.lin([(1.0, (p[r],))] + [(Cp[k], (R[r][k],)) for k in range(3)])
                for r in range(3)]
        newR = [[em.lin([(CR[k][c], (R[r][k],)) for k in range(3)]) for c in range(3)]
                for r in range(3)]
        self.R, self.p = newR, newp

    def apply_rz(self, em: _Emitter, c: str, s: str) -> None:
        R = self.R
        for r in range(3):
            x, y = R[r][0], R[r][1]
            R[r][0] = em.lin([(1.0, (c, x)), (1.0, (s, y))])
            R[r][1] = em.lin([(-1.0, (s, x)), (1.0, (c, y))])

    def apply_tz(self, em: _Emitter, q: str) -> None:
        self.p = [em.lin([(1.0, (self.p[r],)), (1.0, (q, self.R[r][2]))]) for r in range(3)]


def _is_identity(T: np.ndarray) -> bool:
    return bool(np.all(np.abs(T - np.eye(4)) < _SNAP))


def _symbolic_chain(joints, base: np.ndarray, tool: np.ndarray):
    """Run the recursion symbolically.

    Returns the emitter, the tool frame, and per joint its axis (3 scalars),
    a point on it (3 scalars) and its kind.
    """
    em = _Emitter()
    frame = _Frame(base)
    pending = np.eye(4)
    axes = []
    for i, joint in enumerate(joints):
        pending = pending @ joint.pre
        if not _is_identity(pending):
            frame.apply_constant(em, pending)
        pending = np.eye(4)
        z = [frame.R[r][2] for r in range(3)]
        o = list(frame.p)
        axes.append((joint.kind, z, o))
        if joint.kind == "revolute":
            c = em.new(f"cos(q{i})", prefix="c")
            s = em.new(f"sin(q{i})", prefix="s")
            frame.apply_rz(em, c, s)
        else:
            frame.apply_tz(em, f"q{i}")
        pending = joint.post
    pending = pending @ tool
    if not _is_identity(pending):
        frame.apply_constant(em, pending)
    return em, frame, axes


def _jacobian_entries(em: _Emitter, frame: _Frame, axes) -> list[list]:
    """6×n symbolic geometric Jacobian at the tool origin, base axes."""
    pn = frame.p
    cols = []
    for kind, z, o in axes:
        if kind == "revolute":
            d = [em.lin([(1.0, (pn[r],)), (-1.0, (o[r],))]) for r in range(3)]
            v = [
                em.lin([(1.0, (z[1], d[2])), (-1.0, (z[2], d[1]))]),
                em.lin([(1.0, (z[2], d[0])), (-1.0, (z[0], d[2]))]),
                em.lin([(1.0, (z[0], d[1])), (-1.0, (z[1], d[0]))]),
            ]
            cols.append(v + list(z))
        else:
            cols.append(list(z) + [0.0, 0.0, 0.0])
    return [[cols[c][r] for c in range(len(cols))] for r in range(6)]


_NAME = re.compile(r"\b[a-z]\w*\b")


def _live_lines(em: _Emitter, outputs: list) -> list[tuple[str, str]]:
    """Dead-code elimination: keep only lines that outputs depend on."""
    need = set()
    for v in outputs:
        if isinstance(v, str):
            need.add(v.lstrip("-"))
    kept = []
    for target, expr in reversed(em.lines):
        if target in need:
            kept.append((target, expr))
            need.update(_NAME.findall(expr))
    kept.reverse()
    return kept


def generate_source(joints, base: np.ndarray, tool: np.ndarray, *, what: str,
                    batched: bool, guard: bool = False) -> str:
    """Python source of ``kernel(q0, …, q{n-1}[, out])``.

    ``what`` is ``"fk"`` (16 pose entries), ``"jac"`` (6n Jacobian entries) or
    ``"fkjac"`` (both). Scalar kernels return a flat tuple of floats; batched
    kernels fill ``out`` of shape ``(k, B)`` row by row and return it.
    """
    em, frame, axes = _symbolic_chain(joints, base, tool)
    outputs: list = []
    if what in ("fk", "fkjac"):
        for r in range(3):
            outputs += [frame.R[r][0], frame.R[r][1], frame.R[r][2], frame.p[r]]
        outputs += [0.0, 0.0, 0.0, 1.0]
    if what in ("jac", "fkjac"):
        J = _jacobian_entries(em, frame, axes)
        for r in range(6):
            outputs += J[r]
    lines = _live_lines(em, outputs)
    n = len(joints)
    if batched:
        return _batched_source(n, lines, outputs)
    args = ", ".join(f"q{i}" for i in range(n))
    body = [f"def kernel({args}):"]
    if guard:  # prismatic joint values beyond ±_QMAX m are refused (see MAX_PRISMATIC)
        for i, j in enumerate(joints):
            if j.kind == "prismatic":
                body.append(f"    if not -_QMAX <= q{i} <= _QMAX: _refuse(q{i}, {i})")
    for target, expr in lines:
        body.append(f"    {target} = {expr}")
    body.append("    return (" + ", ".join(_ref(v) for v in outputs) + ",)")
    return "\n".join(body) + "\n"


_UFUNC = {"+": "add", "-": "subtract", "*": "multiply"}


def _split_last(expr: str):
    """Split ``expr`` at its last top-level operator: (left, op, right), or None."""
    i_plus, i_minus = expr.rfind(" + "), expr.rfind(" - ")
    i = max(i_plus, i_minus)
    if i >= 0:
        return expr[:i], expr[i + 1], expr[i + 3:]
    i = expr.rfind("*")
    if i >= 0 and not expr.startswith("-"):
        return expr[:i], "*", expr[i + 1:]
    return None


def _batched_source(n: int, lines, outputs) -> str:
    """Batched kernel ``kernel(q, out, first)``: q is (n, m), out is (k, m).

    Trigonometric functions run once over the whole (n, m) block. Output rows are
    computed in place (``out=`` of the last ufunc of their expression); constant
    outputs are written only when ``first`` is true (the buffer is reused).
    """
    body = ["def kernel(q, out, first):"]
    body += [f"    q{i} = q[{i}]" for i in range(n)]
    first_use: dict[str, int] = {}
    for k, v in enumerate(outputs):
        if isinstance(v, str) and not v.startswith("-") and v not in first_use:
            first_use[v] = k
    defined_in_place = set()
    for target, expr in lines:
        if expr.startswith("cos(q"):
            # cos and sin from one SIMD tan of the half angle (numpy's float64 tan is
            # ~6x faster than its cos/sin): t = tan(q/2), cos q = (1 − t²)/(1 + t²),
            # sin q = 2t/(1 + t²); exact to ~1 ulp, finite for every finite q.
            i = expr[5:-1]
            body.append(f"    h{i} = tan(q{i}*0.5)")
            body.append(f"    hh{i} = h{i}*h{i}")
            body.append(f"    hi{i} = 1.0/(1.0 + hh{i})")
            body.append(f"    {target} = (1.0 - hh{i})*hi{i}")
            continue
        if expr.startswith("sin(q"):
            i = expr[5:-1]
            body.append(f"    {target} = (h{i} + h{i})*hi{i}")
            continue
        k = first_use.get(target)
        split = _split_last(expr) if k is not None else None
        if split is None:
            body.append(f"    {target} = {expr}")
            continue
        left, op, right = split
        body.append(f"    {target} = {_UFUNC[op]}({left}, {right}, out=out[{k}])")
        defined_in_place.add(target)
    consts = []
    for k, v in enumerate(outputs):
        if isinstance(v, str):
            if v in defined_in_place and first_use[v] == k:
                continue
            if v.startswith("-"):
                body.append(f"    negative({v[1:]}, out=out[{k}])")
            else:
                body.append(f"    out[{k}] = {v}")
        else:
            consts.append(f"        out[{k}] = {float(v)!r}")
    if consts:
        body.append("    if first:")
        body += consts
    body.append("    return out")
    return "\n".join(body) + "\n"


_SERIAL = itertools.count()


def compile_kernel(joints, base, tool, *, what: str, batched: bool, label: str = "chain",
                   guard=None, chain=None):
    """Compile the generated source; returns the function (its source text in ``__source__``).

    The source is registered with `linecache` under a unique file name
    (``<ratectl kernel LABEL fkjac #k>``), so tracebacks, `inspect.getsource` and
    pdb show the generated lines.
    """
    src = generate_source(joints, base, tool, what=what, batched=batched,
                          guard=guard is not None and not batched)
    if batched:
        namespace = {"tan": np.tan, "add": np.add, "subtract": np.subtract,
                     "multiply": np.multiply, "negative": np.negative}
    else:
        namespace = {"cos": math.cos, "sin": math.sin}
        if guard is not None:
            n = len(joints)

            def _refuse(value, i):  # raises the range error of ``guard`` (``chain`` given)
                a = np.zeros(n)
                a[i] = value
                guard(chain, a)

            namespace["_refuse"] = _refuse
            namespace["_QMAX"] = MAX_PRISMATIC
    filename = f"<ratectl kernel {label} {what}{' batched' if batched else ''} #{next(_SERIAL)}>"
    linecache.cache[filename] = (len(src), None, src.splitlines(True), filename)
    exec(compile(src, filename, "exec"), namespace)
    fn = namespace["kernel"]
    fn.__source__ = src
    return fn
