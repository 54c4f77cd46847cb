"""The joint path q(s) along a Cartesian path (step 1 of the governor).

The path P(s), s ∈ [0, L], with unit-speed tangent twist t(s) = dP/ds, is followed by the
joint curve q(s) with fk(q(s)) = P(s). Differentiating, J(q) q′ = t: the joint tangent
q′ = dq/ds solves a linear system. It is integrated by a Heun predictor and corrected onto
the exact pose P(s) by Newton steps.

**Feasibility comes from the task, not from σ_min alone.** At a regular point q′ = J⁻¹t
(J⁺t plus a joint-centring null-space term for a redundant arm). At a singular point the
path can still be followed when

* its tangent lies in the range of J — the *range-space residual* ρ = |u_minᵀ t| / ‖t‖
  (u_min: the left singular vector of σ_min, the direction J loses at the singularity)
  vanishes as σ_min → 0 — and
* q′ stays bounded.

An *exact* crossing of a wrist, elbow or shoulder singularity along such a path has a
smooth joint path through it. Two branches meet there: the smooth one, on which σ_min
passes through zero linearly and det J changes sign (the arm passes from one
configuration — wrist flipped or not, elbow up or down, shoulder left or right — to the
other), and one that keeps the configuration, which needs a jump of the joints (a wrist
flip of π in q4 and q6, say) and so unbounded joint speed. **The integrator always takes
the smooth branch**: its tangent is chosen continuous,

    q′ = q′_prev + J⁺(t − J q′_prev)        (J⁺ with the singular directions truncated),

which equals J⁻¹t wherever J is invertible and keeps the previous null-space component
where it is not. Each crossing is recorded in `JointPath.crossings` with the branch
taken (``"configuration changes"`` when det J changed sign there, ``"configuration kept"``
for a near miss that only came close).

The integration stops — with a message that says which — only where

* the path leaves the reachable set (the Newton correction cannot reach P(s) and the
  range-space residual ρ there is not small: the tangent points out of the range of J), or
* the joint path needs unbounded joint speed in the interior (|q′| grows without bound
  although ρ → 0).

A path that *ends* at a singular pose (at full reach, say, where q′ ~ 1/√(L − s) grows
without bound but stays integrable) is completed by a damped IK onto the end pose; the
plan's speed profile then comes to rest there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..arrays import read_only
from ..errors import InputError, RatectlError
from ..singularity import analyze
from ..solvers import JointCentring
from ..spatial import pose_error
from .ik import ik

if TYPE_CHECKING:
    from ..model.chain import Chain
    from ..paths.base import Path

__all__ = ['Crossing', 'JointPath', 'joint_path']

_RCOND = 1e-9          # singular values below this × σ_max are treated as zero
_RESIDUAL_TOL = 1e-3   # ρ above this at a stop: the tangent leaves the range of J
_QPRIME_MAX = 1e5      # [rad/m] |q′| beyond this in the interior: unbounded joint speed


@dataclass(frozen=True, kw_only=True)
class Crossing:
    """A place where the joint path passes through (or next to) a singularity.

    Attributes:
        s: path parameter of the smallest σ_min [m]. sigma_min: that σ_min.
        kind: the singularity kind from `ratectl.analyze` ("wrist", "elbow", …) or None.
        branch: ``"configuration changes"`` (det J changed sign: the smooth branch through an
            exact or near-exact singularity, e.g. q5 of a UR passing through zero) or
            ``"configuration kept"`` (a near miss: σ_min dipped and came back).
    """

    s: float
    sigma_min: float
    kind: str | None
    branch: str

    def __str__(self) -> str:
        return (f"{self.kind or 'a'} singularity at s = {self.s:.6g} m (σ_min = {self.sigma_min:.2e}): "
                f"{self.branch}")


@dataclass(frozen=True, kw_only=True)
class JointPath:
    """The joint path q(s) along a Cartesian path (step 1 of the governor); immutable.

    Attributes:
        s: (N,) path parameters [m], non-decreasing from 0; a corner of the path (`Path.corners`)
            appears twice in a row, first with the incoming tangent in ``dq``, then with the
            outgoing one (the derivatives are taken piece by piece between corners).
        q: (N, n) joint positions with fk(q[k]) = P(s[k]) (to ~1e-10).
        dq: (N, n) q′(s) = dq/ds [rad/m]; ddq: (N, n) q″(s) [rad/m²]; dddq: (N, n) q‴(s)
            [rad/m³] (differences of q′).
        sigma_min: (N,) smallest singular value of J along the path.
        residual: (N,) range-space residual ρ of the path tangent (0 where J is regular).
        complete: True when the whole path was integrated.
        message: why the integration stopped early ("" when complete), or a note on a
            singular end.
        crossings: the singular neighbourhoods passed, with the branch taken.
        singular_end: the path ends at a singular pose (q′ unbounded at s = L).
    """

    s: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    dddq: np.ndarray
    sigma_min: np.ndarray
    residual: np.ndarray
    complete: bool
    message: str = ""
    crossings: tuple[Crossing, ...] = ()
    singular_end: bool = False

    def __post_init__(self) -> None:
        for name in ("s", "q", "dq", "ddq", "dddq", "sigma_min", "residual"):
            object.__setattr__(self, name, read_only(getattr(self, name)))

    @property
    def rest_points(self) -> np.ndarray:
        """Grid indices where the progress must be at rest (ṡ = 0): both entries of every
        corner (the joint velocity q′ṡ would jump there otherwise)."""
        dup = np.flatnonzero(np.diff(self.s) == 0.0)
        return np.union1d(dup, dup + 1)

    def interpolate(self, s: np.ndarray | float) -> np.ndarray:
        """q at path parameters ``s`` (scalar or (M,)) by cubic Hermite interpolation of q, q′."""
        s = np.asarray(s, dtype=float)
        flat = np.atleast_1d(s)
        grid = self.s
        k = np.clip(np.searchsorted(grid, flat, side="right") - 1, 0, len(grid) - 2)
        h = grid[k + 1] - grid[k]
        u = np.clip((flat - grid[k]) / h, 0.0, 1.0)[:, None]
        h = h[:, None]
        u2, u3 = u * u, u * u * u
        h00, h10, h01, h11 = 2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2
        d0, d1 = self._secant_limited(k)
        out = (h00 * self.q[k] + h10 * h * d0 + h01 * self.q[k + 1] + h11 * h * d1)
        return out[0] if s.ndim == 0 else out

    def _secant_limited(self, k):
        """Hermite slopes of segments k; where a tangent is several times longer than the
        secant (the last segments before a singular end, where q′ → ∞, a cubic with the
        exact slopes would overshoot) the secant is used instead."""
        d0, d1 = self.dq[k], self.dq[k + 1]
        sec = (self.q[k + 1] - self.q[k]) / (self.s[k + 1] - self.s[k])[:, None]
        ns = np.linalg.norm(sec, axis=1)
        steep = (np.maximum(np.linalg.norm(d0, axis=1), np.linalg.norm(d1, axis=1)) > 2.0 * ns)[:, None]
        return np.where(steep, sec, d0), np.where(steep, sec, d1)

    def derivatives(self, s: np.ndarray | float):
        """(q′(s), q″(s)) at ``s`` (M,) by linear interpolation of the grid values."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        d1 = np.stack([np.interp(s, self.s, self.dq[:, i]) for i in range(self.dq.shape[1])], axis=1)
        d2 = np.stack([np.interp(s, self.s, self.ddq[:, i]) for i in range(self.ddq.shape[1])], axis=1)
        return d1, d2

    def trimmed(self, k: int, *, complete: bool, message: str, singular_end: bool = False) -> JointPath:
        """The first ``k`` grid points as a joint path of their own."""
        return JointPath(s=self.s[:k], q=self.q[:k], dq=self.dq[:k], ddq=self.ddq[:k], dddq=self.dddq[:k],
                         sigma_min=self.sigma_min[:k], residual=self.residual[:k], complete=complete,
                         message=message, crossings=tuple(c for c in self.crossings if c.s <= self.s[k - 1]),
                         singular_end=singular_end)


# ---------------------------------------------------------------------- linear algebra
def _tangent(J, t, base):
    """(q′, σ_min, ρ): q′ = base + J⁺(t − J·base) with J⁺ the SVD pseudo-inverse truncated at
    ``_RCOND``·σ_max, the σ_min of J and the range-space residual ρ = |u_minᵀt|/‖t‖ of t: its
    part outside the range of the rank-5 approximation of J (u_min: the left singular vector
    of σ_min). Where σ_min → 0 a followable tangent has ρ → 0; one with ρ bounded away
    from zero points out of the reachable set."""
    U, sig, Vt = np.linalg.svd(J, full_matrices=False)
    r = int(np.count_nonzero(sig > _RCOND * sig[0]))
    smin = float(sig[-1]) if len(sig) >= 6 else 0.0
    Ur = U[:, :r]
    tn = float(np.linalg.norm(t))
    # the part of t outside the range of J without its weakest direction (6 × n, n ≥ 6)
    rho = float(np.linalg.norm(U[:, 5:].T @ t)) / tn if tn > 0 and len(sig) >= 6 else 0.0
    res = t - J @ base
    dq = base + Vt[:r].T @ ((Ur.T @ res) / sig[:r])
    return dq, smin, rho


def _correct(chain, q, Td, *, iters: int = 10, tol: float = 1e-10):
    """Newton steps q ← q + J⁺e onto the pose Td (J⁺ truncated like the tangent's)."""
    for _ in range(iters):
        T, J = chain.fk_jacobian(q)
        e = pose_error(Td, T)
        if np.max(np.abs(e)) < tol:
            return q, True
        U, sig, Vt = np.linalg.svd(J, full_matrices=False)
        r = int(np.count_nonzero(sig > 1e-7 * sig[0]))
        q = q + Vt[:r].T @ ((U[:, :r].T @ e) / sig[:r])
    return q, bool(np.max(np.abs(pose_error(Td, chain.fk(q)))) < 1e-9)


def _kind(chain, q) -> str | None:
    """The singularity kind from `ratectl.analyze` (None if unavailable)."""
    try:
        return str(analyze(chain, q).kind)
    except RatectlError:  # the kind only decorates a message
        return None


class _Integrator:
    """State of one joint-path integration (see the module docstring)."""

    def __init__(self, chain: Chain, path: Path, *, max_joint_step: Any, max_step: Any, nullspace_gain: Any,
                 max_points: Any):
        self.chain, self.path = chain, path
        self.n = chain.dof
        self.redundant = self.n > 6
        self.L = path.length
        self.max_joint_step = max_joint_step
        self.max_step = max_step or max(self.L / 200.0, 1e-6)
        self.max_points = max_points
        self.centring = JointCentring(chain)
        self.nullspace_gain = float(nullspace_gain)
        self.S: list[float] = []
        self.Q: list[np.ndarray] = []
        self.D: list[np.ndarray] = []
        self.SIG: list[float] = []
        self.RHO: list[float] = []

    def base(self, q: np.ndarray | float, dq_prev: Any):
        """The null-space preference: joint centring (redundant arm; the gradient of the
        solvers' `JointCentring` objective times ``nullspace_gain``) or the previous tangent."""
        if self.redundant:
            return self.nullspace_gain * self.centring(q)
        return dq_prev if dq_prev is not None else np.zeros(self.n)

    def tangent(self, q: np.ndarray | float, s: np.ndarray | float, dq_prev: Any, side: str = "after"):
        _, J = self.chain.fk_jacobian(q)
        return _tangent(J, self.path.twist_at(s, side=side), self.base(q, dq_prev))

    def step(self, q: np.ndarray | float, s: np.ndarray | float, dq: Any, stop: float):
        """One accepted step (s1, q1) from (s, q) with tangent dq, s1 ≤ ``stop`` (the next corner
        or the end, landed on exactly), or None."""
        h = min(self.max_step, stop - s, self.max_joint_step / max(float(np.max(np.abs(dq))), 1e-12))
        while h > 1e-10 * max(self.L, 1e-3):
            s1 = s + h if stop - (s + h) > 1e-12 else stop
            qp = q + (s1 - s) * dq
            dqp, _, _ = self.tangent(qp, s1, dq, side="before")
            if np.max(np.abs(dqp - dq)) > 0.1 * max(float(np.max(np.abs(dq))), 1.0) and h > 1e-7:
                h *= 0.5  # q′ changes fast (near a singularity): a finer grid resolves q″
                continue
            qh = q + 0.5 * (s1 - s) * (dq + dqp)
            qn, ok = _correct(self.chain, qh, self.path.pose_at(s1))
            if (ok and np.max(np.abs(qn - q)) <= 2.5 * self.max_joint_step + 1e-9
                    and np.max(np.abs(qn - qh)) <= 0.25 * self.max_joint_step + 1e-9):
                return s1, qn
            h *= 0.5
        return None

    def record(self, s: float, q: np.ndarray, dq: np.ndarray, smin: float, rho: float) -> None:
        self.S.append(s)
        self.Q.append(q.copy())
        self.D.append(dq)
        self.SIG.append(smin)
        self.RHO.append(rho)

    def run(self, q: np.ndarray) -> tuple[bool, str, bool]:
        """Integrate from q at s = 0; returns (complete, message, singular_end). Each corner of
        the path (`Path.corners`) is landed on and recorded twice: with the incoming tangent,
        then (at the same s and q) with the outgoing one."""
        s, dq = 0.0, None
        stops = [float(c) for c in self.path.corners if 0.0 < c < self.L] + [self.L]
        while True:
            dq, smin, rho = self.tangent(q, s, dq)
            self.record(s, q, dq, smin, rho)
            if s >= self.L:
                return True, "", False
            if len(self.S) >= self.max_points:
                return False, f"too many integration points ({self.max_points}) at s = {s:.6g} m", False
            nxt = None if np.max(np.abs(dq)) > _QPRIME_MAX else self.step(q, s, dq, stops[0])
            if nxt is None:
                return self.stopped(q, s, dq, smin, rho)
            s, q = nxt
            if s == stops[0] and len(stops) > 1:  # on a corner: its incoming side first
                dq, smin, rho = self.tangent(q, s, dq, side="before")
                self.record(s, q, dq, smin, rho)
                stops.pop(0)

    def stopped(self, q: np.ndarray | float, s: np.ndarray | float, dq: Any, smin: Any, rho: Any):
        """The integration cannot go on from (s, q): a singular end, or a stop that says why."""
        L = self.L
        if L - s <= 1e-4:  # within 0.1 mm of the end: reach the end pose itself
            res = ik(self.chain, self.path.pose_at(L), q, tol=(1e-9, 1e-8), max_iter=400, damping=1e-6,
                     max_step=0.05)
            if res.converged and np.max(np.abs(res.q - q)) < 0.5:
                qe = np.array(res.q)
                sec = (qe - q) / (L - s) if L > s else dq
                _, J = self.chain.fk_jacobian(qe)
                self.record(L, qe, sec, float(np.linalg.svd(J, compute_uv=False)[-1]), rho)
                return True, (f"the path ends at a singular pose (σ_min = {self.SIG[-1]:.2e}); "
                              "the plan comes to rest there"), True
        kind = _kind(self.chain, q)
        where = (f"at s = {s:.6g} m of {L:.6g} m, {(L - s) * 1e3:.3g} mm before the end "
                 f"({kind + ' ' if kind else ''}singularity, σ_min = {smin:.2e})")
        if rho > _RESIDUAL_TOL:
            return False, (f"the path leaves the reachable set {where}: its tangent has a component "
                           f"{rho:.2g} outside the range of J, so no joint motion follows it"), False
        return False, (f"the path needs unbounded joint speed {where}: |q′| = "
                       f"{float(np.max(np.abs(dq))):.3g} rad/m although its tangent lies in the range of J "
                       f"(ρ = {rho:.1e})"), False


def _differences(S, D):
    """dD/dS on a non-uniform grid, piece by piece between corners (where S repeats)."""
    out = np.zeros_like(D)
    cuts = np.concatenate([[0], np.flatnonzero(np.diff(S) == 0.0) + 1, [len(S)]])
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        out[a:b] = _differences_smooth(S[a:b], D[a:b])
    return out


def _differences_smooth(S, D):
    """Central differences dD/dS on a non-uniform, increasing grid (one-sided at the ends)."""
    out = np.zeros_like(D)
    if len(S) >= 3:
        out[1:-1] = (D[2:] - D[:-2]) / (S[2:] - S[:-2])[:, None]
        out[0] = (D[1] - D[0]) / (S[1] - S[0])
        out[-1] = (D[-1] - D[-2]) / (S[-1] - S[-2])
    elif len(S) == 2:
        out[:] = (D[1] - D[0]) / (S[1] - S[0])
    return out


def _crossings(chain, S, Q, SIG, threshold: float = 1e-2) -> tuple[Crossing, ...]:
    """Local minima of σ_min below ``threshold`` with the branch taken there."""
    out = []
    if len(S) < 3 or chain.dof != 6:
        return ()
    _, J = chain.fk_jacobian(Q)
    det = np.linalg.det(J)
    for k in range(1, len(S) - 1):
        if SIG[k] < threshold and SIG[k] <= SIG[k - 1] and SIG[k] <= SIG[k + 1]:
            lo, hi = max(k - 3, 0), min(k + 3, len(S) - 1)
            flips = np.sign(det[lo]) != np.sign(det[hi])
            out.append(Crossing(s=float(S[k]), sigma_min=float(SIG[k]), kind=_kind(chain, Q[k]),
                                branch="configuration changes" if flips else "configuration kept"))
    return tuple(out)


def joint_path(chain: Chain, path: Path, q0: ArrayLike, *, max_joint_step: float = 0.004,
               max_step: float | None = None, sigma_tolerance: float | None = None,
               nullspace_gain: float = 1.0, pose_tolerance: float = 1e-4,
               max_points: int = 200000) -> JointPath:
    """Integrate the joint path q(s) along ``path`` from ``q0`` (see the module docstring).

    Args:
        chain: the arm.
        path: a `ratectl.paths.Path`.
        q0: joint positions at the start (fk(q0) must be within ``pose_tolerance``
            [m / rad] of the path start; it is corrected onto it by Newton iterations).
        max_joint_step: largest joint change per integration step [rad].
        max_step: largest step in s [m] (default length/200).
        sigma_tolerance: ignored (kept for compatibility): feasibility is decided from the
            range-space residual and the boundedness of q′, not from a σ_min threshold.
        nullspace_gain: k of the joint-centring null-space term for redundant arms [1/m].
    """
    del sigma_tolerance
    q = chain.check_q(q0).astype(float).copy()
    if q.ndim != 1:
        raise InputError(f"q0 must be one configuration (n,), got shape {q.shape}", argument="q0", value=q0)
    err0 = pose_error(path.pose_at(0.0), chain.fk(q))
    if np.linalg.norm(err0[:3]) > pose_tolerance or np.linalg.norm(err0[3:]) > pose_tolerance * 10:
        ang = math.degrees(np.linalg.norm(err0[3:]))
        raise InputError("q0 is not at the start of the path: tool is "
                         f"{np.linalg.norm(err0[:3]) * 1e3:.3g} mm / {ang:.3g}° "
                         "away; move there first (ratectl.smoothing.move) or pass a matching q0",
                         argument="q0", value=q0)
    q, _ = _correct(chain, q, path.pose_at(0.0))
    it = _Integrator(chain, path, max_joint_step=max_joint_step, max_step=max_step,
                     nullspace_gain=nullspace_gain, max_points=max_points)
    complete, message, singular_end = it.run(q)
    S = np.array(it.S)
    Q = np.array(it.Q).reshape(-1, chain.dof)
    D = np.array(it.D).reshape(-1, chain.dof)
    DD = _differences(S, D)
    DDD = _differences(S, DD)
    crossings = _crossings(chain, S, Q, np.array(it.SIG))
    return JointPath(s=S, q=Q, dq=D, ddq=DD, dddq=DDD, sigma_min=np.array(it.SIG), residual=np.array(it.RHO),
                     complete=complete, message=message, crossings=crossings, singular_end=singular_end)
