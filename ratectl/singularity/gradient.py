"""The analytic gradient of manipulability with respect to q, from the kinematic Hessian.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..kinematics.hessian import hessian_from_jacobian
from .measures import _others_product, _scaled

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ['manipulability_gradient']


# ====================================================================== gradient, paths
def manipulability_gradient(chain: Chain, q: ArrayLike, *, length: float | None = None) -> np.ndarray:
    """Analytic gradient ∂w/∂q of the Yoshikawa manipulability, (n,) or (..., n).

    With J = U Σ Vᵀ (thin SVD, m = min(6, n) singular values) and the kinematic Hessian
    H_k = ∂J/∂q_k (`ratectl.hessian`), ∂σ_i/∂q_k = u_iᵀ H_k v_i, so

        ∂w/∂q_k = Σ_i (Π_{j≠i} σ_j) · u_iᵀ H_k v_i,

    which equals the classic w·tr(J⁺ H_k) where w > 0 and needs no inverse (it stays
    finite at a singularity; there w = Π σ_i has a kink for a square J and this is the
    one-sided derivative along the lost singular direction).

    Args:
        chain: the robot model.
        q: joint positions (n,) or (..., n).
        length: if given, the gradient of the unit-consistent w(J_L) (J_L = diag(I/L, I)·J,
            H scaled the same way); default the raw w(J) of `manipulability`.

    Returns:
        ∂w/∂q in the units of w per rad (or per m for prismatic joints).
    """
    J = chain.jacobian(q)
    if length is not None:
        J = _scaled(J, length)
    H = hessian_from_jacobian(J)
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    c = _others_product(s)
    M = np.swapaxes(Vt, -1, -2) @ (c[..., :, None] * np.swapaxes(U, -1, -2))  # V diag(c) Uᵀ, (..., n, 6)
    return np.einsum("...kab,...ba->...k", H, M)
