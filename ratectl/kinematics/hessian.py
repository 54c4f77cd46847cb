"""Kinematic Hessian: the derivative of the geometric Jacobian with respect to q.

``H[..., k, :, i] = ∂J_i/∂q_k`` is a (..., n, 6, n) array: slice ``H[..., k, :, :]`` is
the 6×n matrix ∂J/∂q_k. It is what the analytic gradient of manipulability
(`ratectl.singularity.manipulability_gradient`) and the first-order distance to
a singularity need.

Derivation (base axes, linear rows at a point p fixed to the tool, e.g. the tool
origin). Column i of J is ``J_i = [z_i × (p − o_i); z_i]`` for a revolute joint and
``[z_i; 0]`` for a prismatic one, where z_i is the world axis of joint i and o_i a point
on it. Moving joint k:

* the axis z_i of a later joint (i > k) is carried by the motion of joint k, so for a
  revolute joint k: ``∂z_i/∂q_k = z_k × z_i`` (k < i), and 0 for k ≥ i or a prismatic k;
* the tool point p moves with the tool velocity column: ``∂p/∂q_k = J_v,k``;
* the point o_i moves like p when k < i (both are carried by joint k), so
  ``∂(p − o_i)/∂q_k = z_k × (p − o_i)`` (revolute k < i), 0 (prismatic k < i), and
  ``J_v,k`` (k ≥ i, o_i does not move).

Putting these into the column formulas and using the Jacobi identity
``(a × b) × c + b × (a × c) = a × (b × c)``:

* k < i:  ``∂J_i/∂q_k = [ J_ω,k × J_v,i ; J_ω,k × J_ω,i ]``
* k ≥ i:  ``∂J_i/∂q_k = [ J_ω,i × J_v,k ; 0 ]``

Both lines hold for revolute and prismatic joints alike, because the angular column
``J_ω`` of a prismatic joint is zero (which makes the terms that must vanish vanish).
So H is a function of J alone: `hessian_from_jacobian`. The formula needs J in
base axes (``frame="base"``), referred to any point fixed to the tool.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["hessian_from_jacobian", "jacobian_hessian", "numerical_hessian"]


def _cross(a, b):
    """Cross product over the last axis without np.cross's per-call overhead."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), axis=-1)


def hessian_from_jacobian(J: ArrayLike) -> np.ndarray:
    """Kinematic Hessian ``H[..., k, :, i] = ∂J_i/∂q_k`` (..., n, 6, n) from the Jacobian alone.

    Args:
        J: geometric Jacobian (..., 6, n) in **base axes**, linear rows at a point fixed
            to the tool (the default of `Chain.jacobian`, or ``point=...``).

    Implements ``∂J_i/∂q_k = [J_ω,k × J_v,i ; J_ω,k × J_ω,i]`` for k < i and
    ``[J_ω,i × J_v,k ; 0]`` for k ≥ i (module docstring). Units: the linear rows are in
    m/rad² (revolute), the angular rows in 1/rad².
    """
    J = np.asarray(J, dtype=float)
    if J.ndim < 2 or J.shape[-2] != 6:
        raise InputError(f"J must have shape (..., 6, n), got {J.shape}", argument="J", value=J)
    n = J.shape[-1]
    Jv = np.swapaxes(J[..., :3, :], -1, -2)  # (..., n, 3)
    Jw = np.swapaxes(J[..., 3:, :], -1, -2)
    A = _cross(Jw[..., :, None, :], Jv[..., None, :, :])  # A[k, i] = J_ω,k × J_v,i
    B = _cross(Jw[..., :, None, :], Jw[..., None, :, :])  # B[k, i] = J_ω,k × J_ω,i
    upper = np.triu(np.ones((n, n), dtype=bool), 1)[:, :, None]  # k < i
    lin = np.where(upper, A, np.swapaxes(A, -2, -3))  # k ≥ i: A[i, k] = J_ω,i × J_v,k
    ang = np.where(upper, B, 0.0)
    H = np.empty(J.shape[:-2] + (n, 6, n))
    H[..., :3, :] = np.swapaxes(lin, -1, -2)
    H[..., 3:, :] = np.swapaxes(ang, -1, -2)
    return H


def jacobian_hessian(chain: Chain, q: ArrayLike, *, point: ArrayLike | None = None) -> np.ndarray:
    """Kinematic Hessian of ``chain`` at q: (..., n, 6, n), ``H[..., k, :, i] = ∂J_i/∂q_k``.

    Args:
        chain: the robot model.
        q: joint positions (n,) or (..., n).
        point: reference point of the linear rows in tool-frame coordinates [m]
            (default the tool origin), as in `Chain.jacobian`. Base axes only.
    """
    return hessian_from_jacobian(chain.jacobian(q, point=point))


def numerical_hessian(chain: Chain, q: ArrayLike, *, step: float = 1e-6,
                      point: ArrayLike | None = None) -> np.ndarray:
    """Central finite differences of `Chain.jacobian`, (n, 6, n), for checking.

    ``H_k ≈ (J(q + h e_k) − J(q − h e_k)) / 2h``; error O(h²) + O(ε/h).
    """
    a = chain.check_q(q)
    if a.ndim != 1:
        raise InputError("numerical_hessian takes one configuration (n,)", argument="q", value=q)
    E = np.eye(chain.dof) * step
    return (chain.jacobian(a + E, point=point) - chain.jacobian(a - E, point=point)) / (2 * step)
