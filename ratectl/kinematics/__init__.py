"""Kinematics of a serial chain: forward kinematics, the geometric Jacobian, J̇, the Hessian.

* `codegen` — generated straight-line kernels (scalar and batched);
* `forward` — ``fk``, ``jacobian``, ``fk_jacobian`` on those kernels,
  and Jacobian re-referencing (point, axes);
* `reference` — the plain 4×4 recursion (frames, joint axes, the
  reference the kernels are checked against), finite differences;
* `derivatives` — J̇ and statics τ = Jᵀ F;
* `hessian` — ∂J/∂q.

The functions take the chain as their first argument; `ratectl.Chain` exposes
them as methods.
"""

from .derivatives import jacobian_dot, joint_torques
from .forward import (
    KERNEL_MODE,
    build_kernel,
    build_links_kernel,
    check_frame,
    check_point,
    fk,
    fk_jacobian,
    jacobian,
    kernel_source,
    refer_jacobian,
    rotate_jacobian,
    shift_jacobian,
)
from .hessian import hessian_from_jacobian, jacobian_hessian, numerical_hessian
from .reference import frames, joint_axes, numerical_jacobian, reference_fk_jacobian

__all__ = [
    "fk", "jacobian", "fk_jacobian", "frames", "joint_axes", "jacobian_dot", "joint_torques",
    "shift_jacobian", "rotate_jacobian", "refer_jacobian", "check_frame", "check_point",
    "numerical_jacobian", "reference_fk_jacobian", "build_kernel", "build_links_kernel", "kernel_source",
    "KERNEL_MODE",
    "hessian_from_jacobian", "jacobian_hessian", "numerical_hessian",
]
