"""Forward kinematics and the geometric Jacobian, on chain-specialised generated code.

All functions take a `Chain` and joint positions ``q`` of shape
``(n,)`` or ``(..., n)`` and broadcast over the leading dimensions.

The Jacobian maps q̇ to the tool twist ``ξ = [v; ω]``; by default its rows are in
base axes and the linear rows are taken at the tool origin. Column i is

* revolute:  ``[ z_i × (p − o_i) ; z_i ]``
* prismatic: ``[ z_i ; 0 ]``

where ``z_i`` is the joint's world axis and ``o_i`` a point on it.

``fk`` and ``jacobian`` run chain-specialised generated code
(`ratectl.kinematics.codegen`): one configuration on Python floats, a batch on
numpy arrays in chunks. With the environment variable ``RATECTL_KERNELS=reference``
set before ratectl is imported, every kernel is replaced by the plain reference
implementation (`ratectl.kinematics.reference`), for debugging.

Thread safety: kernels are compiled once per chain and are pure functions; batched
calls use per-thread work arrays and write only into the arrays they return. Any number
of threads may evaluate the same chain or different chains at once, with results equal
bit for bit to a serial run.
"""

from __future__ import annotations

import os
import threading
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..checks import real_array
from ..errors import InputError
from .codegen import compile_kernel
from .reference import check_prismatic_range, reference_fk_jacobian

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = [
    "fk",
    "jacobian",
    "fk_jacobian",
    "shift_jacobian",
    "rotate_jacobian",
    "refer_jacobian",
    "check_frame",
    "check_point",
    "build_kernel",
    "build_links_kernel",
    "kernel_source",
    "KERNEL_MODE",
]

KERNEL_MODE = "reference" if os.environ.get("RATECTL_KERNELS", "").strip().lower() == "reference" \
    else "generated"
"""``"generated"`` (default) or ``"reference"`` (``RATECTL_KERNELS=reference`` at import)."""

#: Chains with more joints than this use the reference kernel (no generated code).
MAX_GENERATED_DOF = 64
_FRAMES = ("base", "tool")


def build_kernel(chain: Chain, key: Any) -> Any:
    """Compile (once per chain) and cache the generated kernel ``key = (what, batched)``.

    ``what`` is ``"fk"``, ``"jac"`` or ``"fkjac"``. In reference mode the kernel is a
    wrapper with the same calling convention around `reference_fk_jacobian`.
    """
    fn = chain._kernels.get(key)
    if fn is None:
        what, batched = key
        if KERNEL_MODE == "reference" or chain.dof > MAX_GENERATED_DOF:
            # very long chains: generating and compiling straight-line code grows with n
            # (~1 ms per joint); the reference recursion is linear and needs no compile
            fn = _reference_kernel(chain, what, batched)
        else:
            fn = compile_kernel(chain.joints, chain.base, chain.tool, what=what, batched=batched,
                                label=chain.name, guard=check_prismatic_range if
                                chain.prismatic.any() else None, chain=chain)
        chain._kernels[key] = fn
    return fn


def build_links_kernel(chain: Chain, key: Any, placements: list[tuple[int, np.ndarray]]) -> Any:
    """Compile (once per chain and ``key``) the scalar kernel of several links' poses and
    Jacobians (`ratectl.kinematics.codegen.generate_source` with ``what="links"``: each
    placement ``(k, T)``, 1 ≤ k ≤ n, gives 16 pose and 6·k Jacobian entries); None in
    reference mode and for chains beyond `MAX_GENERATED_DOF` (the caller then computes
    each link on its own)."""
    fn = chain._kernels.get(key)
    if fn is None:
        if KERNEL_MODE == "reference" or chain.dof > MAX_GENERATED_DOF:
            return None
        fn = compile_kernel(chain.joints, chain.base, chain.tool, what="links", batched=False,
                            label=chain.name, guard=check_prismatic_range if chain.prismatic.any() else None,
                            chain=chain, placements=placements)
        chain._kernels[key] = fn
    return fn


def kernel_source(chain: Chain, what: str = "fkjac", *, batched: bool = False) -> str:
    """The generated Python source of ``chain``'s kernel (``what`` in "fk", "jac", "fkjac").

    The same text is registered with `linecache`, so tracebacks, `inspect.getsource`
    and pdb show it.
    """
    if what not in ("fk", "jac", "fkjac"):
        raise InputError(f"what must be 'fk', 'jac' or 'fkjac', got {what!r}", argument="what",
                         value=what)
    fn = compile_kernel(chain.joints, chain.base, chain.tool, what=what, batched=batched,
                        label=chain.name)
    return fn.__source__


def _reference_kernel(chain, what: str, batched: bool):
    n = chain.dof

    def flat(q: ArrayLike) -> np.ndarray:
        T, J = reference_fk_jacobian(chain, q)
        parts = []
        if what in ("fk", "fkjac"):
            parts.append(T.reshape(T.shape[:-2] + (16,)))
        if what in ("jac", "fkjac"):
            parts.append(J.reshape(J.shape[:-2] + (6 * n,)))
        return np.concatenate(parts, axis=-1)

    def scalar_kernel(*q: Any) -> tuple[float, ...]:
        return tuple(flat(np.array(q, dtype=float)).tolist())

    def batched_kernel(qT: Any, W: Any, rows: Any) -> None:
        vals = flat(np.ascontiguousarray(qT.T))
        W[:vals.shape[1]] = vals.T

    # read by _batched like a generated kernel's: the output rows are all the work it needs
    batched_kernel.__nwork__ = {"fk": 16, "jac": 6 * n, "fkjac": 16 + 6 * n}[what]  # type: ignore[attr-defined]
    batched_kernel.__prepare__ = lambda W: None  # type: ignore[attr-defined]  # writes every row itself
    return batched_kernel if batched else scalar_kernel


def _kernel(chain, what: str, batched: bool):
    return build_kernel(chain, (what, batched))


def _single(chain, q):
    """Return q as a list of n Python floats when q is one valid configuration, else None."""
    if type(q) is np.ndarray and q.shape == (chain._n,) and q.dtype == np.float64:
        vals = q.tolist()
    elif isinstance(q, (list, tuple)) and len(q) == chain._n:
        try:
            vals = [float(x) for x in q if not isinstance(x, complex)]
        except (TypeError, ValueError):
            return None
        if len(vals) != chain._n:  # complex entries: check_q refuses them
            return None
    else:
        return None
    s = sum(vals)
    if s - s != 0.0:  # NaN or inf somewhere
        return None
    return vals


_tls = threading.local()

_CHUNK_BYTES = 6 * 1024 * 1024  # work rows (outputs included) of one chunk, at most
_CHUNK_MIN, _CHUNK_MAX = 512, 6144


def _chunk(width: int, nwork: int) -> int:
    """Columns per batched kernel call.

    Each generated line is one ufunc call (~0.2 µs overhead), so chunks must be long: on
    the UR5e (94 work rows) 5000-6000 columns were best, 2000 10 % slower, 1000 40 %
    slower, and 8000 no better; a 24-joint chain (328 rows) was also fastest at 5000-6000
    and 10-20 % slower at 2000 (2400 columns fill the 6 MB budget). The work array is
    capped at ``_CHUNK_BYTES`` (longer chains get shorter chunks, 512 at least). An odd multiple
    of 8 columns: rows an odd number of 64-byte cache lines apart spread over all cache
    sets, which the transposing copy of the output rows (one entry from each of k rows per
    configuration) needs; rows a multiple of 4 kB apart would all map to the same sets
    and that copy would run 2-4× slower.
    """
    m = _CHUNK_BYTES // (8 * nwork)
    m = max(_CHUNK_MIN, min(_CHUNK_MAX, m)) // 16 * 16
    return m + 8


class _Work:
    """A per-thread work array ``W``, its row views, and the kernel whose constant rows it holds."""

    __slots__ = ("W", "rows", "prepared_for")

    def __init__(self, W: np.ndarray) -> None:
        self.W = W
        self.rows = tuple(W)
        self.prepared_for: Any = None


def _workspace(rows: int, m: int, kern: Any) -> _Work:
    """A per-thread (rows, m) float64 work array, reused across calls (fresh buffers cost
    page faults on first touch, and sharing one between threads would race), with the
    constant output rows of ``kern`` filled (once, until another kernel uses it)."""
    cache = getattr(_tls, "work", None)
    if cache is None:
        cache = _tls.work = {}
    work = cache.get((rows, m))
    if work is None:
        if len(cache) >= 3:  # a few kernel shapes per thread, up to _CHUNK_BYTES each
            cache.clear()
        work = cache[(rows, m)] = _Work(np.empty((rows, m)))
    if work.prepared_for is not kern:
        kern.__prepare__(work.W)
        work.prepared_for = kern
    return work


def _batched(chain, flat: np.ndarray, what: str, parts) -> None:
    """Run the batched kernel over ``flat`` (B, n), writing into ``parts``: C-contiguous
    result arrays (B, k_j) whose columns, concatenated, are the kernel's k outputs.

    The kernel reads the joint positions through a transposed view and computes each
    output entry into a contiguous work row; per chunk, one transposing copy per part
    moves the rows into the result (about 0.3 ns per entry, against about 0.65 ns for
    a ufunc writing with the result's stride).

    Every batched evaluation passes here, so the prismatic range check
    (`check_prismatic_range`) is made here, once for all of them.
    """
    check_prismatic_range(chain, flat)
    B = flat.shape[0]
    kern = _kernel(chain, what, True)
    nwork = kern.__nwork__
    m = _chunk(sum(p.shape[1] for p in parts), nwork)
    if B < m:  # one chunk; its rows keep the spread stride (an odd multiple of 8 columns)
        m = -(-B // 16) * 16 + 8
    work = _workspace(nwork, m, kern)
    qT = flat.T
    copyto = np.copyto
    for start in range(0, B, m):
        stop = min(start + m, B)
        if stop - start == m:
            w, rows = work.W, work.rows
        else:  # the last, shorter chunk
            w = work.W[:, :stop - start]
            rows = tuple(w)
        kern(qT[:, start:stop], w, rows)
        row = 0
        for p in parts:
            copyto(p[start:stop], w[row:row + p.shape[1]].T)
            row += p.shape[1]


def _run(chain, q, what: str, width: int):
    """Evaluate a kernel; returns (flat values (..., width), batch shape)."""
    vals = _single(chain, q)
    if vals is not None:
        return np.array(_kernel(chain, what, False)(*vals)), ()
    a = chain.check_q(q)
    batch = a.shape[:-1]
    if batch == ():
        return np.array(_kernel(chain, what, False)(*a.tolist())), ()
    flat = a.reshape(-1, chain._n)
    out = np.empty((flat.shape[0], width))
    if out.size:
        _batched(chain, flat, what, [out])
    return out, batch


def fk(chain: Chain, q: ArrayLike) -> np.ndarray:
    """Pose of the tool in the world, ``T_world_tool = base · A_1 ⋯ A_n · tool``, (..., 4, 4)."""
    vals, batch = _run(chain, q, "fk", 16)
    return vals.reshape(batch + (4, 4))


def check_frame(frame: str) -> None:
    if frame not in _FRAMES:
        raise InputError(f"frame must be 'base' or 'tool', got {frame!r}",
                         argument="frame", value=frame)


def check_point(point: ArrayLike) -> np.ndarray:
    p = real_array("point", point, "a 3-vector in tool-frame coordinates [m]")
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise InputError("point must be a finite 3-vector in tool-frame coordinates [m], "
                         f"got {point!r}", argument="point", value=point)
    return p


def shift_jacobian(J: ArrayLike, r: Any) -> np.ndarray:
    """Refer a base-axes Jacobian's linear rows to a point displaced by ``r`` [m] (base axes).

    ``v' = v + ω × r``, so ``J_v' = J_v − [r]× J_ω``.
    """
    J = np.asarray(J, dtype=float)
    r = np.asarray(r, dtype=float)
    out = J.copy()
    Jw = J[..., 3:, :]
    rx, ry, rz = r[..., 0, None], r[..., 1, None], r[..., 2, None]
    out[..., 0, :] -= ry * Jw[..., 2, :] - rz * Jw[..., 1, :]
    out[..., 1, :] -= rz * Jw[..., 0, :] - rx * Jw[..., 2, :]
    out[..., 2, :] -= rx * Jw[..., 1, :] - ry * Jw[..., 0, :]
    return out


def rotate_jacobian(J: ArrayLike, R: ArrayLike) -> np.ndarray:
    """Express a Jacobian's rows in the axes of a frame with world rotation ``R``: blockdiag(Rᵀ, Rᵀ)·J."""
    J = np.asarray(J, dtype=float)
    Rt = np.swapaxes(np.asarray(R, dtype=float), -1, -2)
    out = np.empty(np.broadcast_shapes(J.shape, Rt.shape[:-2] + J.shape[-2:]))
    out[..., :3, :] = Rt @ J[..., :3, :]
    out[..., 3:, :] = Rt @ J[..., 3:, :]
    return out


def refer_jacobian(J: np.ndarray, T: np.ndarray, frame: str, point: ArrayLike | None) -> np.ndarray:
    """The base-axes, tool-origin Jacobian ``J`` referred to ``point`` (tool coordinates [m]) and
    expressed in ``frame`` axes, given the tool pose ``T`` (see `shift_jacobian`, `rotate_jacobian`)."""
    if point is not None:
        p = check_point(point)
        J = shift_jacobian(J, T[..., :3, :3] @ p)
    if frame == "tool":
        J = rotate_jacobian(J, T[..., :3, :3])
    return J


def jacobian(chain: Chain, q: ArrayLike, *, frame: str = "base",
             point: ArrayLike | None = None) -> np.ndarray:
    """Geometric Jacobian ``J(q)`` (..., 6, n) with rows ``[v; ω]``.

    Args:
        frame: ``"base"``: rows in world axes (default); ``"tool"``: in tool axes.
        point: reference point of the linear rows, given in tool-frame coordinates
            [m]; default the tool origin.
    """
    n = chain._n
    if frame == "base" and point is None:
        vals, batch = _run(chain, q, "jac", 6 * n)
        return vals.reshape(batch + (6, n))
    check_frame(frame)
    T, J = fk_jacobian(chain, q)
    return refer_jacobian(J, T, frame, point)


def fk_jacobian(chain: Chain, q: ArrayLike, *, frame: str = "base",
                point: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(T_world_tool, J)`` evaluated together; see `fk` and `jacobian`."""
    n = chain._n
    vals = _single(chain, q)
    T: np.ndarray
    J: np.ndarray
    if vals is not None or (a := chain.check_q(q)).ndim == 1:
        flat = np.array(_kernel(chain, "fkjac", False)(*(vals if vals is not None else a.tolist())))
        T, J = flat[:16].reshape(4, 4), flat[16:].reshape(6, n)
    else:
        batch = a.shape[:-1]
        qs = a.reshape(-1, n)
        T, J = np.empty((qs.shape[0], 16)), np.empty((qs.shape[0], 6 * n))
        if qs.shape[0]:
            _batched(chain, qs, "fkjac", [T, J])
        T, J = T.reshape(batch + (4, 4)), J.reshape(batch + (6, n))
    if frame == "base" and point is None:
        return T, J
    check_frame(frame)
    return T, refer_jacobian(J, T, frame, point)
