"""Measures of a Jacobian: singular values, manipulability, condition number, rank.

All take J (..., 6, n) and broadcast; ``length`` divides the linear rows by a
characteristic length L [m] so that linear and angular rows are comparable.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..arrays import read_only
from ..errors import InputError

__all__ = ['KINDS', 'singular_values', 'manipulability', 'condition_number', 'rank']


#: Singularity kinds; ``ScanResult.kind_code`` indexes this tuple.
KINDS = ("regular", "wrist", "elbow", "shoulder", "boundary", "rank-deficient")


_REGULAR, _WRIST, _ELBOW, _SHOULDER, _BOUNDARY, _RANKDEF = range(6)


DEFAULT_RTOL = 1e-8  # rank: σ_i(J_L) > rtol·σ₁(J_L)


DEFAULT_NEAR = 0.01  # near-singular: σ_min(J_L) < near (dimensionless; κ(J_L) ≳ 100-200)


DEFAULT_FACTOR_TOL = 0.2  # a geometric factor (sine of an angle) below this names the kind


_TINY = 1e-300


# ====================================================================== measures from J
_MAX_ENTRY = 1e145  # |J| beyond this: J Jᵀ overflows


def _as_jacobian(J, name="J") -> np.ndarray:
    try:
        if isinstance(J, str | bytes) or np.iscomplexobj(J):
            raise TypeError(name)
        a = np.asarray(J, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be a real matrix (..., m, n), got {J!r}"[:300], argument=name,
                         value=J) from None
    if a.ndim < 2 or a.shape[-1] < 1 or a.shape[-2] < 1:
        raise InputError(f"{name} must have shape (..., m, n), typically (..., 6, n); got {a.shape}",
                         argument=name, value=J)
    # checked before LAPACK sees it: a NaN makes LAPACK print to stdout and fail
    big = float(np.max(np.abs(a))) if a.size else 0.0
    if not big <= _MAX_ENTRY:
        if not np.all(np.isfinite(a)):
            bad = np.argwhere(~np.isfinite(a))[0].tolist()
            raise InputError(f"{name} must be finite; got NaN or inf at index {bad}", argument=name,
                             value=J)
        raise InputError(f"{name} has entries of {big:.3g}; at most {_MAX_ENTRY:.0e} in magnitude is "
                         "accepted (products overflow floating point)", argument=name, value=J)
    return a


def _scaled(J: np.ndarray, length) -> np.ndarray:
    """J_L = diag(I/L, I)·J for a 6-row Jacobian; J itself when length is None."""
    if length is None:
        return J
    L = float(length)
    if not (L > 0 and math.isfinite(L)):
        raise InputError(f"length must be a positive characteristic length [m], got {length!r}",
                         argument="length", value=length)
    if J.shape[-2] != 6:
        raise InputError(f"length scaling needs a (..., 6, n) Jacobian, got {J.shape}",
                         argument="J", value=J)
    out = J.copy()
    out[..., :3, :] /= L
    return out


def check_chain(chain: Any) -> None:
    """`InputError` unless ``chain`` is a `ratectl.Chain`."""
    from ..model.chain import Chain

    if not isinstance(chain, Chain):
        raise InputError(f"chain must be a ratectl.Chain (e.g. rc.robots.ur5e()), got {chain!r}"[:200],
                         argument="chain", value=chain)


def _jacobian_of(J: Any, q: Any) -> np.ndarray:
    """The Jacobian of a measure's first arguments: ``J`` itself, or ``chain.jacobian(q)``
    when the first argument is a `Chain` (then ``q`` is required)."""
    from ..model.chain import Chain

    if isinstance(J, Chain):
        if q is None:
            raise InputError(f"give the joint positions with the chain: f({J.name}, q) (q of shape "
                             f"(..., {J.dof})), or the Jacobian alone: f(J)", argument="q", value=None)
        return J.jacobian(q)
    if q is not None:
        raise InputError("q is given with a Jacobian; pass either a Jacobian J (..., 6, n) or a chain "
                         "and q: f(chain, q)", argument="q", value=q)
    return _as_jacobian(J)


def singular_values(J: Any, q: ArrayLike | None = None, *, length: float | None = None) -> np.ndarray:
    """Singular values σ₁ ≥ … ≥ σ_m of J, (..., m) with m = min(rows, n).

    Args:
        J: Jacobian (..., 6, n) (or any (..., r, n) matrix when ``length`` is None), or a
            `Chain`, with ``q``: ``singular_values(chain, q)`` is
            ``singular_values(chain.jacobian(q))``.
        q: joint positions (..., n) when ``J`` is a chain.
        length: if given, the characteristic length L [m]: the singular values of
            J_L = diag(I/L, I)·J (dimensionless) are returned.
    """
    return np.linalg.svd(_scaled(_jacobian_of(J, q), length), compute_uv=False)


def manipulability(J: Any, q: ArrayLike | None = None, *, length: float | None = None) -> np.ndarray:
    """Yoshikawa manipulability w = σ₁⋯σ_m, (...,).

    w = √det(J Jᵀ) when J has at least as many columns as rows (n ≥ 6), and
    √det(Jᵀ J) otherwise (for n < 6, √det(J Jᵀ) is identically 0). Units: product of
    the singular values' units (m³/rad⁶ · … for the raw 6×n J); dimensionless for J_L.
    ``J`` is a Jacobian (..., 6, n), or a `Chain` with joint positions ``q`` (as for
    `singular_values`).
    """
    A = _scaled(_jacobian_of(J, q), length)
    G = A @ np.swapaxes(A, -1, -2) if A.shape[-1] >= A.shape[-2] else np.swapaxes(A, -1, -2) @ A
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        w = np.sqrt(np.maximum(np.linalg.det(G), 0.0))
    if not np.all(np.isfinite(w)):
        # det(G) left floating-point range: the product of the singular values in logs
        s = np.linalg.svd(A, compute_uv=False)
        with np.errstate(divide="ignore"):
            logw = np.sum(np.log(s), axis=-1)
        if np.any(logw > 709.0):
            raise InputError("manipulability overflows floating point (the product of the "
                             f"singular values exceeds 1e308; largest σ = {float(s.max()):.3g})",
                             argument="J", value=J)
        w = np.exp(logw)
    return w


def condition_number(J: Any, q: ArrayLike | None = None, *, length: float | None = None,
                     inverse: bool = False) -> np.ndarray:
    """Condition number κ = σ₁/σ_m (inf where σ_m = 0), or its inverse σ_m/σ₁ ∈ [0, 1].

    Args:
        J: Jacobian (..., 6, n) or any (..., r, n), or a `Chain` with ``q``.
        q: joint positions (..., n) when ``J`` is a chain.
        length: characteristic length L [m] for the unit-consistent κ(J_L). The raw κ(J)
            mixes m/rad and rad/rad and changes with the choice of units.
        inverse: return 1/κ (0 at a singularity, well-behaved for plotting).
    """
    s = singular_values(J, q, length=length)
    return _cond(s[..., 0], s[..., -1], inverse)


def _cond(smax, smin, inverse):
    if inverse:
        return np.divide(smin, smax, out=np.zeros_like(smin), where=smax > 0)
    return np.divide(smax, smin, out=np.full_like(smax, np.inf), where=smin > 0)


def rank(J: ArrayLike, *, length: float | None = None, rtol: float = DEFAULT_RTOL) -> np.ndarray:
    """Numerical rank: the number of σ_i > rtol·σ₁ (an int array of the batch shape)."""
    s = singular_values(J, length=length)
    return np.sum(s > rtol * s[..., :1], axis=-1)


def _others_product(s: np.ndarray) -> np.ndarray:
    """c_i = Π_{j≠i} s_j without division (exact at zeros), over the last axis."""
    m = s.shape[-1]
    left = np.ones_like(s)
    right = np.ones_like(s)
    for i in range(1, m):
        left[..., i] = left[..., i - 1] * s[..., i - 1]
        right[..., m - 1 - i] = right[..., m - i] * s[..., m - i]
    return left * right


def _fast_singular_values(A: np.ndarray, refine: float = 1e-3) -> np.ndarray:
    """Singular values (descending) of a batch A (B, r, c) via the eigenvalues of the smaller
    Gram matrix, with an SVD for the rows where σ_min < refine·σ_max.

    The eigenvalues λ of A Aᵀ carry an absolute error ~ε·σ_max², so √λ is accurate to
    ~1e-9 relative for σ ≥ 1e-3·σ_max; smaller singular values are recomputed by SVD
    (so exact singularities give σ_min ~ 1e-16, not ~1e-8). Deterministic per matrix:
    a batch gives the same numbers as one matrix at a time.
    """
    r, c = A.shape[-2:]
    At = np.swapaxes(A, -1, -2)
    G = A @ At if r <= c else At @ A
    lam = np.linalg.eigvalsh(G)[..., ::-1]
    s = np.sqrt(np.maximum(lam, 0.0))
    redo = s[..., -1] < refine * s[..., 0]
    if np.any(redo):
        s[redo] = np.linalg.svd(A[redo], compute_uv=False)
    return s


# ====================================================================== the report
def _ro(a):
    return read_only(a, dtype=None)
