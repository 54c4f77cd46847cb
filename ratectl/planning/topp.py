"""Time-optimal admissible path speed by reachability analysis on x = ṡ² (step 2 of the governor).

Along the joint path q(s) the joint velocity and acceleration are

    q̇ = q′ ṡ,        q̈ = q′ s̈ + q″ ṡ².

With x = ṡ² and u = s̈ (so dx/ds = 2u) every limit is linear in (u, x):

    |q′_i| √x ≤ v_i          →  x ≤ (v_i / |q′_i|)²               (velocity)
    −a_i ≤ q′_i u + q″_i x ≤ a_i                                   (acceleration)
    x ≤ ṡ_max²,  |u| ≤ s̈_max                                       (the path's own limits)

written as rows ``a u + b x ≤ c`` per grid point s_k. Between grid points u is constant
(x_{k+1} = x_k + 2 Δ_k u_k, Δ_k = s_{k+1} − s_k), as in TOPP-RA (Pham & Pham, "A new approach
to time-optimal path parameterization based on reachability analysis", IEEE T-RO 2018):

1. **Controllable sets**, backwards: K_N = {x_end}; K_k = {x : some u satisfies the rows of
   stage k and x + 2Δ_k u ∈ K_{k+1}}. Each K_k is an interval [lo_k, hi_k]: eliminating u
   (Fourier–Motzkin) pairs every lower bound on u with every upper bound, and the pairs
   that involve K_{k+1} give, per row r (a_r ≠ 0),

       x (2Δ b_r − a_r) ≤ 2Δ c_r − a_r·(lo_{k+1} if a_r > 0 else hi_{k+1}),

   while the pairs among the rows themselves give the maximum-velocity curve (MVC).
2. **Greedy forward pass**: from x_0 = x_start take the largest u the rows of stage k allow
   that keeps x_{k+1} in K_{k+1}. This is time-optimal for the discretised problem and never
   gets stuck (every x_k is controllable).

Both passes are closed-form per stage (numpy only). The time of a segment is
Δt_k = 2Δ_k / (√x_k + √x_{k+1}).

At a corner of the path (`JointPath.rest_points`: the grid point appears twice, with the
incoming and the outgoing q′) the maximum-velocity curve is set to 0, so the profile comes
to rest there and leaves from rest; the zero-length stage between the two entries keeps x.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .joint_path import JointPath

__all__ = ['SpeedProfile', 'reachability_profile']

_TINY = 1e-12


@dataclass(frozen=True, kw_only=True)
class SpeedProfile:
    """The time-optimal x = ṡ² on the joint-path grid.

    Attributes:
        s: (N,) grid [m]; x: (N,) ṡ² [m²/s²]; u: (N,) s̈ on each segment (last 0) [m/s²];
        mvc: (N,) maximum-velocity curve (largest admissible x per point);
        t: (N,) time at each grid point [s]; duration: t[-1] [s];
        rest: (N,) segments traversed from rest to rest (both ends x = 0, at a singular end).
    """

    s: np.ndarray
    x: np.ndarray
    u: np.ndarray
    mvc: np.ndarray
    t: np.ndarray
    duration: float
    rest: np.ndarray

    def __post_init__(self) -> None:
        for name in ("s", "x", "u", "mvc", "t", "rest"):
            a = np.array(getattr(self, name), dtype=bool if name == "rest" else float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    def sample(self, dt: float):
        """(s, ṡ, s̈) at t = 0, dt, 2dt, … up to the end (the last sample at the end, at rest)."""
        K = int(np.ceil(self.duration / dt - 1e-9)) + 1
        s, sd, sdd = self.at(np.minimum(np.arange(K) * dt, self.duration))
        s[-1], sd[-1] = self.s[-1], 0.0
        return s, sd, sdd

    def at(self, t: np.ndarray):
        """(s, ṡ, s̈) at the times ``t`` (M,) [s] within [0, duration]."""
        tk = np.asarray(t, dtype=float)
        i = np.clip(np.searchsorted(self.t, tk, side="right") - 1, 0, len(self.s) - 2)
        tau = tk - self.t[i]
        sd0 = np.sqrt(self.x[i])
        s = np.minimum(self.s[i] + sd0 * tau + 0.5 * self.u[i] * tau**2, self.s[i + 1])
        sd = np.maximum(sd0 + self.u[i] * tau, 0.0)
        T = np.maximum(self.t[i + 1] - self.t[i], 1e-300)
        r = np.where(self.rest[i], tau / T, 0.0)
        h = self.s[i + 1] - self.s[i]
        s = np.where(self.rest[i], self.s[i] + h * r * r * (3.0 - 2.0 * r), s)
        sd = np.where(self.rest[i], 6.0 * h * r * (1.0 - r) / T, sd)
        return s, sd, self.u[i].copy()


def constraint_rows(jp: JointPath, vlim: Any, alim: Any, path_speed: Any, path_acc: Any):
    """Rows a u + b x ≤ c per grid point ((N, m) arrays a, b, c) and the velocity bound on x.

    ``vlim`` and ``alim`` may be (n,) or (N, n) (per-point margins), ``path_speed`` and
    ``path_acc`` scalars or (N,)."""
    d1, d2 = jp.dq, jp.ddq
    N, n = d1.shape
    alim = np.broadcast_to(alim, (N, n))
    vlim = np.broadcast_to(vlim, (N, n))
    a = np.concatenate([d1, -d1, np.ones((N, 1)), -np.ones((N, 1))], axis=1)
    b = np.concatenate([d2, -d2, np.zeros((N, 2))], axis=1)
    pa = np.broadcast_to(np.asarray(path_acc, dtype=float).reshape(-1, 1), (N, 2))
    c = np.concatenate([alim, alim, pa], axis=1)
    with np.errstate(divide="ignore", over="ignore"):
        xv = np.min((vlim / np.maximum(np.abs(d1), 1e-300)) ** 2, axis=1)
    return a, b, c, np.minimum(xv, path_speed**2)


def accel_mvc(a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Largest x per grid point for which some u satisfies every row (pairs of rows)."""
    N, m = a.shape
    zero = np.abs(a) <= _TINY
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.min(np.where(zero & (b > 0), c / b, np.inf), axis=1)
        ba = np.where(zero, np.nan, b / a)
        ca = np.where(zero, np.nan, c / a)
    pos, neg = a > _TINY, a < -_TINY
    # (c_k − b_k x)/a_k ≤ (c_j − b_j x)/a_j for a_j > 0 > a_k  ⇔  x (b_j/a_j − b_k/a_k) ≤ c_j/a_j − c_k/a_k
    coef = ba[:, :, None] - ba[:, None, :]
    rhs = ca[:, :, None] - ca[:, None, :]
    valid = pos[:, :, None] & neg[:, None, :] & (coef > 1e-300)
    with np.errstate(divide="ignore", invalid="ignore"):
        xp = np.where(valid, rhs / np.where(valid, coef, 1.0), np.inf)
    return np.maximum(np.minimum(x, np.min(xp.reshape(N, -1), axis=1)), 0.0)


def _u_bounds(a, b, c, x: float):
    """[u_lo, u_hi] at x for the rows of one stage."""
    r = c - b * x
    with np.errstate(divide="ignore", invalid="ignore"):
        q = r / a
    hi = np.min(np.where(a > _TINY, q, np.inf))
    lo = np.max(np.where(a < -_TINY, q, -np.inf))
    return float(lo), float(hi)


def _controllable(a, b, c, mvc, S, x_end: float):
    """Backward pass: the controllable intervals [lo_k, hi_k] (hi_k < lo_k: not controllable)."""
    N = len(S)
    lo, hi = np.zeros(N), np.zeros(N)
    lo[-1] = hi[-1] = min(x_end, mvc[-1])
    nz = np.abs(a) > _TINY
    for k in range(N - 2, -1, -1):
        d2 = 2.0 * (S[k + 1] - S[k])
        ak, bk, ck = a[k][nz[k]], b[k][nz[k]], c[k][nz[k]]
        alpha = d2 * bk - ak
        beta = d2 * ck - ak * np.where(ak > 0, lo[k + 1], hi[k + 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            bound = beta / alpha
        up = float(np.min(bound[alpha > 0], initial=np.inf))
        dn = float(np.max(bound[alpha < 0], initial=0.0))
        if np.any((np.abs(alpha) <= 1e-300) & (beta < 0)):
            up = -1.0
        lo[k], hi[k] = max(dn, 0.0), min(up, mvc[k])
    return lo, hi


def reachability_profile(jp: JointPath, vlim: Any, alim: Any, path_speed: Any, path_acc: Any, *,
                         x_start: float = 0.0, x_end: float = 0.0) -> SpeedProfile:
    """Time-optimal x = ṡ² on the grid of ``jp`` by reachability analysis (module docstring).

    Args:
        jp: the joint path; vlim, alim: joint velocity / acceleration limits [rad/s, rad/s²],
            (n,) or (N, n) per grid point; path_speed, path_acc: the path's ṡ and s̈ limits
            (scalars or (N,) per grid point).
        x_start, x_end: ṡ² at the ends (0: start and end at rest).

    A grid point where no admissible x exists (the controllable set is empty, e.g. a
    non-zero end speed that cannot be reached) is handled by clamping to the nearest
    admissible value; the caller checks the sampled motion.
    """
    a, b, c, xv = constraint_rows(jp, vlim, alim, path_speed, path_acc)
    mvc = np.minimum(xv, accel_mvc(a, b, c))
    mvc[jp.rest_points] = 0.0  # corners: at rest
    S = np.asarray(jp.s, dtype=float)
    N = len(S)
    lo, hi = _controllable(a, b, c, mvc, S, x_end)
    x = np.zeros(N)
    u = np.zeros(N)
    x[0] = min(max(x_start, lo[0]), max(hi[0], 0.0))
    for k in range(N - 1):
        d2 = 2.0 * (S[k + 1] - S[k])
        if d2 == 0.0:  # the two entries of a corner
            x[k + 1] = x[k]
            continue
        ulo, uhi = _u_bounds(a[k], b[k], c[k], x[k])
        target_hi = max(hi[k + 1], lo[k + 1])
        uk = min(uhi, (target_hi - x[k]) / d2)
        uk = max(uk, ulo, (lo[k + 1] - x[k]) / d2) if uk < ulo else uk
        x[k + 1] = min(max(x[k] + d2 * uk, 0.0), target_hi)
        u[k] = (x[k + 1] - x[k]) / d2
    sq = np.sqrt(x)
    dS = np.diff(S)
    with np.errstate(divide="ignore", invalid="ignore"):
        dt = np.where(dS > 0.0, 2.0 * dS / (sq[:-1] + sq[1:]), 0.0)
    rest = np.zeros(N - 1, dtype=bool)
    for k in np.flatnonzero(x[:-1] + x[1:] < 1e-8).tolist():
        # nearly from rest to rest (a tiny segment at a singular end): accelerating and braking
        # at the acceleration the rows allow at x = 0 takes t = 2√(Δ/u₀), if that is shorter
        u0 = max(_u_bounds(a[k], b[k], c[k], 0.0)[1], 1e-9)
        t_rest = 2.0 * math.sqrt(dS[k] / u0)
        if dS[k] > 0.0 and t_rest < dt[k]:
            dt[k], rest[k] = t_rest, True
    t = np.concatenate([[0.0], np.cumsum(dt)])
    return SpeedProfile(s=S, x=x, u=u, mvc=mvc, t=t, duration=float(t[-1]),
                        rest=np.concatenate([rest, [False]]))
