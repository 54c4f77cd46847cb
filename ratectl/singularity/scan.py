"""Many configurations at once: `scan` (batched classification), `path_distance`,
and the task directions a chain can never move in (`fixed_lost_directions`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ..kinematics.hessian import hessian_from_jacobian
from .analysis import _check_options, _core
from .measures import (
    _TINY,
    DEFAULT_FACTOR_TOL,
    DEFAULT_NEAR,
    DEFAULT_RTOL,
    KINDS,
    _cond,
    _ro,
    _scaled,
    check_chain,
)

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ['scan', 'ScanResult', 'path_distance', 'PathDistance', 'fixed_lost_directions']


# ====================================================================== batched scan
@dataclass(frozen=True, kw_only=True)
class ScanResult:
    """Measures over a batch of configurations (see `scan`); arrays of shape batch + (...).

    ``kind_code`` indexes `KINDS`; `kinds` gives the names. ``sigma_scaled``
    are the singular values of J_L (batch + (m,)); ``sigma`` and ``condition`` (raw J)
    are present only with ``raw=True``.
    """

    q: np.ndarray
    length: float
    sigma_scaled: np.ndarray
    sigma_min_scaled: np.ndarray
    manipulability: np.ndarray
    manipulability_scaled: np.ndarray
    condition_scaled: np.ndarray
    inverse_condition_scaled: np.ndarray
    rank: np.ndarray
    singular: np.ndarray
    near_singular: np.ndarray
    kind_code: np.ndarray
    manipulability_translational: np.ndarray
    manipulability_rotational: np.ndarray
    condition_translational: np.ndarray
    condition_rotational: np.ndarray
    factor_wrist: np.ndarray
    factor_elbow: np.ndarray
    factor_shoulder: np.ndarray
    sigma: np.ndarray | None = None
    condition: np.ndarray | None = None

    @property
    def kinds(self) -> np.ndarray:
        """Kind names, an array of str of the batch shape."""
        return np.asarray(KINDS)[self.kind_code]

    def count(self) -> dict:
        """How many configurations of each kind."""
        codes = np.bincount(self.kind_code.ravel(), minlength=len(KINDS))
        return {k: int(v) for k, v in zip(KINDS, codes, strict=True)}


_SCAN_CHUNK = 16384


def scan(chain: Chain, qs: ArrayLike, *, length: float | None = None, rtol: float = DEFAULT_RTOL,
         near: float = DEFAULT_NEAR, factor_tol: float = DEFAULT_FACTOR_TOL,
         raw: bool = False) -> ScanResult:
    """Singularity measures and kinds for many configurations, batched.

    Args:
        chain: the robot model.
        qs: joint positions (..., n).
        length: characteristic length [m], as in `analyze`.
        rtol: rank tolerance, as in `analyze`.
        near: near-singularity threshold, as in `analyze`.
        factor_tol: geometric-factor tolerance, as in `analyze`.
        raw: also compute the singular values and condition number of the raw J (one
            more batched SVD).

    Returns:
        A frozen `ScanResult`; entry ``[i]`` equals the corresponding field of
        ``analyze(chain, qs[i], ...)``.
    """
    check_chain(chain)
    a = chain.check_q(qs, name="qs")
    L = _check_options(chain, length, rtol, near, factor_tol)
    batch = a.shape[:-1]
    flat = a.reshape(-1, chain.dof)
    parts = []
    for start in range(0, max(flat.shape[0], 1), _SCAN_CHUNK):
        J = chain.jacobian(flat[start:start + _SCAN_CHUNK])
        parts.append(_core(chain, J, L, rtol, near, factor_tol, raw))

    def cat(get: Any, tail: Any = 0):
        x = np.concatenate([get(p) for p in parts], axis=0)
        return _ro(x.reshape(batch + x.shape[1:]))

    m = min(6, chain.dof)
    s = cat(lambda p: p["sigma_scaled"])
    smin = cat(lambda p: p["sigma_min_scaled"])
    rk = cat(lambda p: p["rank"])
    return ScanResult(
        q=_ro(a.copy()), length=L, sigma_scaled=s, sigma_min_scaled=smin,
        manipulability=cat(lambda p: p["manipulability"]),
        manipulability_scaled=cat(lambda p: p["manipulability_scaled"]),
        condition_scaled=cat(lambda p: p["condition_scaled"]),
        inverse_condition_scaled=_ro(_cond(s[..., 0], smin, True)),
        rank=rk, singular=_ro(rk < m), near_singular=_ro(smin < near),
        kind_code=cat(lambda p: p["kind_code"]),
        manipulability_translational=cat(lambda p: p["manipulability_translational"]),
        manipulability_rotational=cat(lambda p: p["manipulability_rotational"]),
        condition_translational=cat(lambda p: p["condition_translational"]),
        condition_rotational=cat(lambda p: p["condition_rotational"]),
        factor_wrist=cat(lambda p: p["geo"]["wrist"]),
        factor_elbow=cat(lambda p: p["geo"]["elbow"]),
        factor_shoulder=cat(lambda p: p["geo"]["shoulder"]),
        sigma=cat(lambda p: p["sigma"]) if raw else None,
        condition=cat(lambda p: p["condition"]) if raw else None,
    )


@dataclass(frozen=True, kw_only=True)
class PathDistance:
    """Distance to singularity along a path of configurations (see `path_distance`).

    Attributes (one entry per configuration):
        s: cumulative joint-space arc length ‖Δq‖ summed along the path [rad, mixed
            with m for prismatic joints].
        sigma_min_scaled: σ_min(J_L), the spectral-norm distance of J_L to the nearest
            rank-deficient matrix (Eckart–Young).
        inverse_condition_scaled: σ_min/σ_max of J_L.
        manipulability: Yoshikawa w of the raw J.
        joint_distance: σ_min(J_L)/‖∇_q σ_min(J_L)‖, a first-order estimate of the
            joint-space distance to the singular set [rad].
        kind_code: as in `ScanResult`; ``kinds`` gives names.
        closest: index of the configuration with the smallest σ_min(J_L).
    """

    s: np.ndarray
    sigma_min_scaled: np.ndarray
    inverse_condition_scaled: np.ndarray
    manipulability: np.ndarray
    joint_distance: np.ndarray
    kind_code: np.ndarray
    closest: int

    @property
    def kinds(self) -> np.ndarray:
        return np.asarray(KINDS)[self.kind_code]


def path_distance(chain: Chain, qs: ArrayLike, *, length: float | None = None, near: float = DEFAULT_NEAR,
                  factor_tol: float = DEFAULT_FACTOR_TOL) -> PathDistance:
    """Distance to singularity along a path of configurations qs (N, n).

    Returns σ_min(J_L), 1/κ, w, a first-order joint-space distance to the singular set
    (σ_min / ‖∂σ_min/∂q‖, with ∂σ_min/∂q_k = u_minᵀ H_k v_min from the kinematic
    Hessian) and the kind at each configuration.
    """
    check_chain(chain)
    a = chain.check_q(qs, name="qs")
    if a.ndim != 2:
        raise InputError(f"qs must be a path of shape (N, {chain.dof}), got {a.shape}",
                         argument="qs", value=qs)
    L = _check_options(chain, length, DEFAULT_RTOL, near, factor_tol)
    J = chain.jacobian(a)
    core = _core(chain, J, L, DEFAULT_RTOL, near, factor_tol, False)
    JL = _scaled(J, L)
    U, sv, Vt = np.linalg.svd(JL, full_matrices=False)
    m = sv.shape[-1]
    g = np.einsum("...a,...kab,...b->...k", U[..., :, m - 1], hessian_from_jacobian(JL),
                  Vt[..., m - 1, :])
    gn = np.linalg.norm(g, axis=-1)
    smin = sv[..., -1]
    jd = np.divide(smin, gn, out=np.where(smin == 0, 0.0, np.inf), where=gn > 0)
    ds = np.linalg.norm(np.diff(a, axis=0), axis=-1)
    return PathDistance(
        s=_ro(np.concatenate([[0.0], np.cumsum(ds)])), sigma_min_scaled=_ro(smin),
        inverse_condition_scaled=_ro(_cond(sv[..., 0], smin, True)),
        manipulability=_ro(core["manipulability"]), joint_distance=_ro(jd),
        kind_code=_ro(core["kind_code"]), closest=int(np.argmin(smin)))


def fixed_lost_directions(chain: Chain, *, samples: int = 64, rng: np.random.Generator | int | None = 0,
                          rtol: float = 1e-9) -> np.ndarray:
    """Task directions the arm can never move in, at any configuration: (6, k) orthonormal.

    These are the unit twists u (raw [v; ω] coordinates) with uᵀ J(q) = 0 for every q —
    the common left null space of J over ``samples`` random configurations (the null
    space of the stacked Jᵀ). Example: the RPR arm gives [0, 0, 1, 0, 0, 0] (v_z: the
    tool height is fixed).
    """
    if not (isinstance(samples, int) and samples >= 1):
        raise InputError(f"samples must be a positive int, got {samples!r}", argument="samples",
                         value=samples)
    J = chain.jacobian(chain.random_q(samples, rng=rng))  # (S, 6, n)
    M = np.concatenate(list(J), axis=1)  # 6 × (S·n)
    U, s, _ = np.linalg.svd(M)
    k = int(np.sum(s > rtol * max(s[0], _TINY)))
    return U[:, k:]
