"""Damped least squares: fixed λ (DLS), adaptive λ (Maciejewski & Klein; Chiaverini),
and selectively damped least squares (Buss & Kim 2005).
"""

from __future__ import annotations

import math
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError, SingularityError
from .base import (
    _MAX_ENTRY,
    EXACT_DIRECTION_FLOOR,
    DirectionTwist,
    Solver,
    SolveResult,
    _dot,
    _dposv,
    _dpotrf,
    _dpotrs,
    _dsyev,
    _LazySigma,
    _positive,
    _store,
    exact_direction_floor,
    min_norm_direction,
    svd_values,
    thin_svd,
)

__all__ = ['DLS', 'AdaptiveDLS', 'SDLS', 'adaptive_damping']


_SQRT_HALF = math.sqrt(0.5)

_hypot = math.hypot

_new = object.__new__


def adaptive_damping(sigma: ArrayLike, *, epsilon: float, max_damping: float):
    """The σ-scheduled damping of Maciejewski & Klein / Chiaverini:

    λ² = (1 − (σ/ε)²)·λ_max² for σ < ε, else 0.  Returns λ (scalar or array like σ).
    """
    s = np.asarray(sigma, dtype=float)
    r = np.clip(s / epsilon, 0.0, 1.0)
    lam = max_damping * np.sqrt(1.0 - r * r)
    return float(lam) if lam.ndim == 0 else lam


def exact_direction(solver: Solver, J: np.ndarray, d: np.ndarray, *, q: np.ndarray | None,
                    dt: float | None) -> tuple[np.ndarray, Any, float]:
    """`Solver.solve_direction` of the damped solvers: with W J the weighted J (the task and
    joint weights), the exact direction J w = d of least W_q-norm (`min_norm_direction`)
    wherever σ_min(W J) is above `exact_direction_floor`, returned with damping 0 and σ_min
    (lazily); below, the solver's own answer (`Solver.solve_direction`, through ``solve``)."""
    Jw, dw = solver._apply_weights(J, d) if solver._weighted else (J, d)
    m, n = Jw.shape
    G = _dot(Jw, Jw.T) if m <= n else _dot(Jw.T, Jw)  # the Gram matrix of σ_min and of w
    sigma = _LazySigma(G)
    if sigma.value() >= exact_direction_floor(J=Jw):
        w = min_norm_direction(Jw, dw, gram=G)
        if w is not None:
            return (w if solver._isw is None else w * solver._isw), sigma, 0.0
    return Solver.solve_direction(solver, J, d, q=q, dt=dt)


def _gain_bound_adaptive(epsilon: float, lam_max: float) -> float:
    """sup over σ ≥ 0 of the per-direction gain σ/(σ² + λ(σ)²) under the σ schedule.

    For σ ≥ ε the gain is 1/σ ≤ 1/ε. Below, g(σ) = σ/(aσ² + b) with a = 1 − λ_max²/ε²,
    b = λ_max²; its maximum is 1/(2λ_max√a) at σ* = √(b/a) when λ_max ≤ ε/√2, else 1/ε.
    """
    if lam_max <= epsilon * _SQRT_HALF:
        a = 1.0 - (lam_max / epsilon) ** 2
        return max(1.0 / epsilon, 1.0 / (2.0 * lam_max * math.sqrt(a)))
    return 1.0 / epsilon


class DLS(Solver):
    """Damped least squares with a fixed λ [units of σ]:

    q̇ = Jᵀ(JJᵀ + λ²I)⁻¹ξ  (= (JᵀJ + λ²I)⁻¹Jᵀξ),

    the minimiser of ‖Jq̇ − ξ‖² + λ²‖q̇‖². Each singular direction gets the gain
    σ/(σ² + λ²) ≤ 1/(2λ), so ‖q̇‖ ≤ ‖ξ‖/(2λ) everywhere, singular or not. Solved with a
    Cholesky factorisation (no SVD); ``result.sigma_min`` is computed on first access.
    """

    method = "dls"

    def __init__(self, *, damping: float = 0.05, velocity_policy: str | None = "scale",
                 task_weights: ArrayLike | None = None, joint_weights: ArrayLike | None = None) -> None:
        super().__init__(velocity_policy=velocity_policy, task_weights=task_weights,
                         joint_weights=joint_weights)
        self.damping = _positive("damping", damping)
        self._lam2 = self.damping**2
        self._lam2I: dict[int, np.ndarray] = {}

    def __repr__(self) -> str:
        return f"DLS(damping={self.damping!r}, velocity_policy={self.velocity_policy!r})"

    def gain_bound(self) -> float:
        """Largest possible ‖q̇‖/‖ξ‖: 1/(2λ) [1/units of σ]."""
        return 0.5 / self.damping

    def solve_direction(self, J: np.ndarray, d: np.ndarray, *, q: np.ndarray | None,
                        dt: float | None) -> tuple[np.ndarray, Any, float]:
        """`Solver.solve_direction`: the exact direction wherever J has full rank
        (`exact_direction`), not turned by the damping, which shrinks each singular
        direction by σ²/(σ² + λ²) on its own; at a singularity, the DLS answer."""
        return exact_direction(self, J, d, q=q, dt=dt)

    def _raw(self, J, xi):
        m, n = J.shape
        if m <= n:
            G = _dot(J, J.T)
            k = m
        else:
            G = _dot(J.T, J)
            k = n
        L = self._lam2I.get(k)
        if L is None:
            L = self._lam2I[k] = self._lam2 * np.eye(k)
        if m <= n:
            _, y, info = _dposv(G + L, xi)
            t = sum(y.tolist())
            if info != 0 or t - t != 0.0:  # a tiny λ on a singular J: y overflows
                raise np.linalg.LinAlgError(f"JJᵀ + λ²I is not positive definite or too "
                                            f"ill-conditioned for λ = {self.damping:g} (dposv info {info})")
            qd = _dot(y, J)
        else:
            _, qd, info = _dposv(G + L, _dot(xi, J))
        if info != 0:
            raise np.linalg.LinAlgError(f"JJᵀ + λ²I is not positive definite (dposv info {info})")
        return qd, self.damping, _LazySigma(G), {}


class AdaptiveDLS(Solver):
    """Damped least squares with damping scheduled by the distance to a singularity.

    Modes:

    * ``"sigma"`` (Maciejewski & Klein 1988; Chiaverini 1994): one λ for all
      directions, λ² = (1 − (σ_min/ε)²)·λ_max² when σ_min < ε, else 0;
      q̇ = Jᵀ(JJᵀ + λ²I)⁻¹ξ. Exact (λ = 0) while σ_min ≥ ε.
    * ``"filtered"`` (numerical filtering; Maciejewski & Klein 1988, Chiaverini 1997):
      damp only the singular directions whose σ_i < ε, each with λ_i from the same
      schedule: q̇ = Σ σ_i/(σ_i² + λ_i²) v_i u_iᵀ ξ. The other directions are tracked
      exactly, so the task error lies in span{u_i : σ_i < ε}.
    * ``"manipulability"`` (Nakamura & Hanafusa 1986): w = √det(JJᵀ);
      λ² = λ_max²·(1 − w/w₀)² when w < w₀, else 0 (``manipulability_threshold`` = w₀).

    In every mode the per-direction gain is at most `gain_bound`
    (``1/(2λ_max√(1 − λ_max²/ε²))`` or ``1/ε``, whichever is larger) in the σ modes,
    and each call reports ``info["gain_bound"]``, the bound for that call
    (``‖q̇‖ ≤ gain_bound·‖ξ‖``).

    Args:
        epsilon: ε, the σ threshold below which damping starts [units of σ].
        max_damping: λ_max, the damping at σ = 0.
        mode: ``"sigma"``, ``"filtered"`` or ``"manipulability"``.
        manipulability_threshold: w₀ for ``mode="manipulability"`` (required in that
            mode; same units as √det(JJᵀ)).
    """

    method = "adaptive-dls"
    MODES = ("sigma", "filtered", "manipulability")

    def __init__(self, *, epsilon: float = 0.05, max_damping: float = 0.05, mode: str = "sigma",
                 manipulability_threshold: float | None = None,
                 velocity_policy: str | None = "scale", task_weights: ArrayLike | None = None,
                 joint_weights: ArrayLike | None = None) -> None:
        super().__init__(velocity_policy=velocity_policy, task_weights=task_weights,
                         joint_weights=joint_weights)
        self.epsilon = _positive("epsilon", epsilon)
        self.max_damping = _positive("max_damping", max_damping)
        if mode not in self.MODES:
            raise InputError(f"mode must be one of {self.MODES}, got {mode!r}", argument="mode",
                             value=mode)
        self.mode = mode
        if mode == "manipulability":
            if manipulability_threshold is None:
                raise InputError("mode='manipulability' needs manipulability_threshold (w₀, the "
                                 "manipulability below which damping starts)",
                                 argument="manipulability_threshold", value=None)
            self.manipulability_threshold: float | None = _positive("manipulability_threshold",
                                                                    manipulability_threshold)
        else:
            self.manipulability_threshold = manipulability_threshold
        self._lm2 = self.max_damping**2
        self._ie2 = 1.0 / self.epsilon**2
        self._eye: dict[int, np.ndarray] = {}

    def __repr__(self) -> str:
        return (f"AdaptiveDLS(epsilon={self.epsilon!r}, max_damping={self.max_damping!r}, "
                f"mode={self.mode!r})")

    def solve_direction(self, J: np.ndarray, d: np.ndarray, *, q: np.ndarray | None,
                        dt: float | None) -> tuple[np.ndarray, Any, float]:
        """`Solver.solve_direction`: the exact direction wherever J has full rank
        (`exact_direction`: the schedule's damping would shrink each singular direction
        below ε on its own, turning the motion); at a singularity, the damped answer."""
        return exact_direction(self, J, d, q=q, dt=dt)

    def solve_direction_twist(self, J: np.ndarray, d: np.ndarray, xi: np.ndarray, *,
                              q: np.ndarray | None, dt: float | None) -> DirectionTwist:
        """`Solver.solve_direction_twist` in the ``"sigma"`` mode from one Gram matrix G (JJᵀ,
        or JᵀJ for a tall J) and one eigen-decomposition of it: σ_min = √λ_min(G) both says
        whether the direction is exact (`exact_direction`: above `exact_direction_floor`,
        w = `min_norm_direction`) and schedules the feedback's damping λ² = (1 −
        (σ_min/ε)²)·λ_max² (0 above ε), c = Jᵀ(G + λ²I)⁻¹ξ as `solve` without limits; the
        feedback's `SolveResult` (``info["gain_bound"]`` as `solve`'s) is built by
        `DirectionTwist.result` only. Other modes, weights, J near a singularity or out of
        range take the two entries in turn (the default): the same answers."""
        if self.mode != "sigma" or self._weighted:
            return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)
        m, n = J.shape
        entries = J.ravel().tolist()
        if not _hypot(*entries, *xi.tolist()) < _MAX_ENTRY:  # (the check of `solve`)
            return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)
        wide = m <= n
        G = _dot(J, J.T) if wide else _dot(J.T, J)
        ev, _, info = _dsyev(G, compute_v=0)
        if info != 0:
            return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)
        s2 = max(float(ev[0]), 0.0)
        smin = math.sqrt(s2)
        norm = _hypot(*entries)
        if not smin >= EXACT_DIRECTION_FLOOR * norm:
            return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)
        # the feedback, as `_raw` (its damped solve on the same G); undamped (σ_min ≥ ε), one
        # Cholesky factor of G for both (G + 0·I, which `_raw` factors, is G: the same numbers)
        lam2 = self._lm2 * (1.0 - s2 * self._ie2) if s2 * self._ie2 < 1.0 else 0.0
        if lam2 == 0.0:
            factor, info = _dpotrf(G)
            w = min_norm_direction(J, d, factor=factor) if info == 0 else None
            if w is None:
                return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)
            if wide:
                y, info = _dpotrs(factor, xi)
                c = y @ J
            else:
                c, info = _dpotrs(factor, xi @ J)
            if info != 0:  # (not after dpotrf succeeded; `solve` says what failed)
                return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)
            lam, bound = 0.0, (1.0 / smin if smin else math.inf)
        else:
            w = min_norm_direction(J, d, gram=G)
            if w is None:
                return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)
            c, lam, bound = self._damped(J, xi, G, wide, lam2, smin)
        # ‖J c‖ ≤ ‖J‖_F‖c‖: the achieved twist and the task error are finite below 1e300
        if not _hypot(*c.tolist()) * norm < 1e300:
            return Solver.solve_direction_twist(self, J, d, xi, q=q, dt=dt)

        def make(xi_c: np.ndarray, qd: np.ndarray) -> SolveResult:
            """The feedback's result (as `solve`'s without limits) for the command ``qd``."""
            achieved = J.dot(qd)
            r = _new(SolveResult)
            _store(r, qd if qd is c else qd.copy(), achieved, xi_c - achieved, lam, smin, self.method,
                   "none", 1.0, np.zeros(n, dtype=bool), (), False,
                   MappingProxyType({"gain_bound": bound}))
            return r

        return DirectionTwist(w, _LazySigma(G, value=smin), 0.0, c, J=J, make=make)

    def gain_bound(self) -> float:
        """sup ‖q̇‖/‖ξ‖ over all J for the σ modes (see the class docstring)."""
        return _gain_bound_adaptive(self.epsilon, self.max_damping)

    def damping_at(self, sigma: ArrayLike):
        """λ(σ) of the schedule (scalar or array)."""
        return adaptive_damping(sigma, epsilon=self.epsilon, max_damping=self.max_damping)

    def _raw(self, J, xi):
        if self.mode == "filtered":
            return self._filtered(J, xi)
        m, n = J.shape
        wide = m <= n
        G = J @ J.T if wide else J.T @ J
        if self.mode == "sigma":
            w, _, info = _dsyev(G, compute_v=0)
            if info != 0:
                raise np.linalg.LinAlgError(f"eigenvalues did not converge (dsyev info {info})")
            s2 = max(float(w[0]), 0.0)
            smin = math.sqrt(s2)
            lam2 = self._lm2 * (1.0 - s2 * self._ie2) if s2 * self._ie2 < 1.0 else 0.0
            sigma = smin
        else:  # manipulability
            c, info = _dpotrf(G)
            with np.errstate(over="ignore", under="ignore"):
                wm = float(np.prod(np.diagonal(c))) if info == 0 else 0.0
            r = wm / self.manipulability_threshold
            lam2 = self._lm2 * (1.0 - r) ** 2 if r < 1.0 else 0.0
            sigma = _LazySigma(G)
            smin = None
        qd, lam, bound = self._damped(J, xi, G, wide, lam2, smin)
        info_d = {"gain_bound": bound}
        if self.mode == "manipulability":
            info_d["manipulability"] = wm
        return qd, lam, sigma, info_d

    def _damped(self, J, xi, G, wide: bool, lam2: float,
                smin: float | None) -> tuple[np.ndarray, float, float]:
        """(q̇, λ, the gain bound) of q̇ = Jᵀ(G + λ²I)⁻¹ξ for a wide J (G = JJᵀ), else
        (G + λ²I)⁻¹Jᵀξ (G = JᵀJ), with ``smin`` σ_min (None when not known): the bound
        ‖q̇‖/‖ξ‖ ≤ σ/(σ² + λ²) at σ_min, 1/(2λ) at most, 1/σ_min undamped. Raises
        `SingularityError` when G + λ²I is not positive definite (λ = 0 at a singularity)."""
        lam = math.sqrt(lam2)
        k = G.shape[0]
        eye = self._eye.get(k)
        if eye is None:
            eye = self._eye[k] = np.eye(k)
        A = G + lam2 * eye
        if wide:
            _, y, info = _dposv(A, xi, overwrite_a=1)
            qd = y @ J
        else:
            _, qd, info = _dposv(A, xi @ J, overwrite_a=1)
        if info != 0:
            raise SingularityError(
                f"J is singular (sigma_min ≈ 0) and the scheduled damping is 0 (mode "
                f"{self.mode!r}); increase the threshold", sigma_min=0.0,
                tolerance=self.epsilon)
        if lam > 0.0:
            if smin is None or smin <= lam:
                bound = 0.5 / lam
            else:
                bound = smin / (smin * smin + lam2)
        else:
            bound = 1.0 / smin if smin else math.inf
        return qd, lam, bound

    def _filtered(self, J, xi):
        u, s, vt = thin_svd(J)
        s2 = s * s
        lam2 = np.maximum(1.0 - s2 * self._ie2, 0.0) * self._lm2
        lam = np.sqrt(lam2)
        denom = s2 + lam2
        gain = np.divide(s, denom, out=np.zeros_like(s), where=denom > 0)
        qd = (gain * (xi @ u)) @ vt
        full = s.shape[0] == min(J.shape)
        smin = float(s[-1]) if full and s.shape[0] else 0.0
        return qd, float(lam.max()) if lam.size else 0.0, smin, {
            "gain_bound": float(gain.max()) if gain.size else 0.0,
            "damped_directions": int(np.count_nonzero(lam > 0)),
            "singular_values": s,
            "dampings": lam,
        }


class SDLS(Solver):
    """Selectively damped least squares (Buss & Kim 2005), for 6-D twists.

    The linear rows are in metres and the angular rows in radians; with a characteristic
    length L both become lengths: J̃ = diag(I, L·I) J, ξ̃ = diag(I, L·I) ξ. The twist is
    then treated as two 3-D "end effector" blocks (linear, scaled angular). With the SVD
    J̃ = Σ σ_i u_i v_iᵀ and the columns' blocks ρ_{ℓj}:

    * N_i = Σ_ℓ ‖u_{ℓ,i}‖ (the block norms of u_i),
    * M_i = σ_i⁻¹ Σ_j |v_{ji}| Σ_ℓ ‖ρ_{ℓj}‖,
    * γ_i = min(1, N_i/M_i)·γ_max,
    * φ_i = clamp(σ_i⁻¹ (u_iᵀ ξ̃) v_i, γ_i), q̇ = clamp(Σ φ_i, γ_max),

    where clamp(w, d) scales w so that max|w_j| ≤ d. Here γ_max bounds joint
    *velocity* [rad/s or m/s] (Buss & Kim bound the joint step of one iteration):
    the result is exact (J̃⁻¹ξ̃ = J⁻¹ξ) as long as no clamp acts. Directions with
    σ_i ≤ ``tolerance`` are dropped. Twists with m ≠ 6 rows are split into blocks of 3
    (the last one shorter) without the length scaling.

    Args:
        gamma_max: γ_max [rad/s], the largest joint speed one direction may command.
        characteristic_length: L [m] (use ``chain.characteristic_length``); default 1 m.
        tolerance: singular values at or below it are treated as zero.
    """

    method = "sdls"

    def __init__(self, *, gamma_max: float = math.pi / 4, characteristic_length: float = 1.0,
                 tolerance: float = 1e-9, velocity_policy: str | None = "scale",
                 task_weights: ArrayLike | None = None, joint_weights: ArrayLike | None = None) -> None:
        super().__init__(velocity_policy=velocity_policy, task_weights=task_weights,
                         joint_weights=joint_weights)
        self.gamma_max = _positive("gamma_max", gamma_max)
        self.characteristic_length = _positive("characteristic_length", characteristic_length)
        self.tolerance = _positive("tolerance", tolerance, allow_zero=True)
        L = self.characteristic_length
        self._S = np.array([1.0, 1.0, 1.0, L, L, L])

    def __repr__(self) -> str:
        return (f"SDLS(gamma_max={self.gamma_max!r}, "
                f"characteristic_length={self.characteristic_length!r})")

    def _solve_weighted(self, J, xi):
        # the clamps act on the weighted variables; mapped back by W_q^{-1/2} a joint could
        # exceed γ_max, so the final q̇ is clamped again (uniformly: the direction is kept)
        qd, damping, sigma, info = super()._solve_weighted(J, xi)
        return self._clamp(qd, self.gamma_max), damping, sigma, info

    @staticmethod
    def _clamp(w, d):
        mx = float(np.max(np.abs(w))) if w.size else 0.0
        return w * (d / mx) if mx > d else w

    def _raw(self, J, xi):
        m, n = J.shape
        if m == 6 and not self._weighted:
            Js, xs = J * self._S[:, None], xi * self._S
        else:
            Js, xs = J, xi
        u, s, vt = thin_svd(Js)
        k = s.shape[0]
        nb = -(-m // 3)
        pad = 3 * nb - m
        if pad:  # a last block shorter than 3 rows: pad with zero rows (norms unchanged)
            u_b = np.vstack([u, np.zeros((pad, k))])
            J_b = np.vstack([Js, np.zeros((pad, n))])
        else:
            u_b, J_b = u, Js
        rho = np.sqrt((J_b.reshape(nb, 3, n) ** 2).sum(axis=1)).sum(axis=0)  # Σ_ℓ ‖ρ_ℓj‖, (n,)
        N = np.sqrt((u_b.reshape(nb, 3, k) ** 2).sum(axis=1)).sum(axis=0)   # (k,)
        keep = s > self.tolerance
        sk = np.where(keep, s, 1.0)
        M = (np.abs(vt) @ rho) / sk
        ratio = np.divide(N, M, out=np.ones_like(N), where=M > 0)
        gammas = np.where(keep, np.minimum(1.0, ratio) * self.gamma_max, 0.0)
        phi = np.where(keep, (xs @ u) / sk, 0.0)[:, None] * vt          # (k, n) per direction
        mx = np.abs(phi).max(axis=1) if n else np.zeros(k)
        scale = np.divide(gammas, mx, out=np.ones_like(mx), where=mx > gammas)
        qd = self._clamp((phi * np.minimum(scale, 1.0)[:, None]).sum(axis=0), self.gamma_max)
        full = k == min(m, n)
        if Js is not J:  # σ_min reported for the unscaled J
            sv = svd_values(J)
            smin = float(sv[-1]) if full and sv.size else 0.0
        else:
            smin = float(s[-1]) if full and k else 0.0
        return qd, 0.0, smin, {"gammas": gammas, "rank": int(keep.sum())}
