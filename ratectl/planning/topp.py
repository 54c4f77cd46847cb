"""Admissible path speed on x = ṡ² from joint velocity and acceleration limits (step 2 of the
governor): forward and backward passes over the maximum-velocity curve.
"""

from __future__ import annotations

import numpy as np

from .joint_path import JointPath


# ---------------------------------------------------------------------- TOPP
def _constraints(jp: JointPath, vlim, alim, path_speed, path_acc):
    """Rows a u + b x ≤ c for every grid point: (N, m) arrays a, b, c, and the velocity bound."""
    d1, d2 = jp.dq, jp.ddq
    N = len(jp.s)
    a = np.concatenate([d1, -d1, np.ones((N, 1)), -np.ones((N, 1))], axis=1)
    b = np.concatenate([d2, -d2, np.zeros((N, 2))], axis=1)
    c = np.concatenate([np.broadcast_to(alim, d1.shape), np.broadcast_to(alim, d1.shape),
                        np.full((N, 2), path_acc)], axis=1)
    with np.errstate(divide="ignore", over="ignore"):
        xv = np.min((vlim / np.maximum(np.abs(d1), 1e-300)) ** 2, axis=1)
    xv = np.minimum(xv, path_speed**2)
    return a, b, c, xv


def _u_bounds(a, b, c, x):
    """Bounds [u_lo, u_hi] on s̈ at x = ṡ² for rows a u + b x ≤ c (one grid point or many)."""
    r = c - b * x[..., None]
    tiny = 1e-12
    pos, neg = a > tiny, a < -tiny
    with np.errstate(divide="ignore", invalid="ignore"):
        q = r / a
    hi = np.min(np.where(pos, q, np.inf), axis=-1)
    lo = np.max(np.where(neg, q, -np.inf), axis=-1)
    return lo, hi


def _accel_mvc(a, b, c):
    """Largest x per grid point for which some u satisfies every row."""
    N, m = a.shape
    tiny = 1e-12
    x = np.full(N, np.inf)
    # rows with a ≈ 0: b x ≤ c
    zero = np.abs(a) <= tiny
    with np.errstate(divide="ignore", invalid="ignore"):
        xz = np.where(zero & (b > 0), c / b, np.inf)
    x = np.minimum(x, np.min(xz, axis=1))
    # pairs (j: a_j > 0 upper bound, k: a_k < 0 lower bound):
    # (c_k − b_k x)/a_k ≤ (c_j − b_j x)/a_j  ⇔  x (b_j/a_j − b_k/a_k) ≤ c_j/a_j − c_k/a_k
    with np.errstate(divide="ignore", invalid="ignore"):
        ba = np.where(zero, np.nan, b / a)
        ca = np.where(zero, np.nan, c / a)
    pos, neg = a > tiny, a < -tiny
    coef = ba[:, :, None] - ba[:, None, :]
    rhs = ca[:, :, None] - ca[:, None, :]
    valid = pos[:, :, None] & neg[:, None, :] & (coef > 1e-300)
    with np.errstate(divide="ignore", invalid="ignore"):
        xp = np.where(valid, rhs / np.where(valid, coef, 1.0), np.inf)
    x = np.minimum(x, np.min(xp.reshape(N, -1), axis=1))
    return np.maximum(x, 0.0)


def _topp(jp: JointPath, vlim, alim, path_speed, path_acc):
    """Fastest x = ṡ² profile on the grid; both ends are left to the limits (the
    jerk-limited executor starts and ends at rest by itself)."""
    a, b, c, xv = _constraints(jp, vlim, alim, path_speed, path_acc)
    mvc = np.minimum(xv, _accel_mvc(a, b, c))
    S = jp.s
    N = len(S)
    x = np.empty(N)
    x[0] = mvc[0]  # the jerk-limited executor starts from rest by itself
    for k in range(N - 1):
        h = S[k + 1] - S[k]
        _, hi = _u_bounds(a[k], b[k], c[k], np.array(x[k]))
        x[k + 1] = min(mvc[k + 1], max(x[k] + 2.0 * h * float(hi), 0.0))
    for k in range(N - 2, -1, -1):
        h = S[k + 1] - S[k]
        lo, _ = _u_bounds(a[k + 1], b[k + 1], c[k + 1], np.array(x[k + 1]))
        x[k] = min(x[k], max(x[k + 1] - 2.0 * h * float(lo), 0.0))
    return np.maximum(x, 0.0), mvc
