"""Inverse velocity: from a desired twist ξ to joint velocities q̇.

Every solver is an object with the same call::

    result = solver.solve(J, xi, *, limits=None, q=None, qd_prev=None, dt=None)

and returns a frozen :class:`SolveResult`. ``limits`` is anything with the arrays
``lower``, ``upper``, ``vmax``, ``amax`` (a :class:`~ratectl.chain.Chain` works, or
:class:`Limits`). Non-QP solvers use only ``vmax``, through their velocity-limit
policy (``"scale"``: scale q̇ uniformly so that no joint exceeds its limit, which keeps
the direction of motion; ``"clip"``: clip each joint; ``None``: ignore the limits).
The QP (:class:`ratectl.qp.QP`, re-exported here) also uses ``q`` and ``dt``
(position limits) and ``qd_prev`` and ``dt`` (acceleration limits);
:class:`NullSpace` uses ``q`` for its secondary objective.

Solvers (m task rows, n joints; σ_i, u_i, v_i are the singular values and left/right
singular vectors of J):

* :class:`Inverse` — q̇ = J⁻¹ξ (square J); raises :class:`SingularityError`.
* :class:`PseudoInverse` — q̇ = Σ_{σ_i > tol} σ_i⁻¹ v_i u_iᵀ ξ (truncated).
* :class:`DLS` — q̇ = Jᵀ(JJᵀ + λ²I)⁻¹ξ, fixed λ; ‖q̇‖ ≤ ‖ξ‖/(2λ).
* :class:`AdaptiveDLS` — λ scheduled on σ_min (``mode="sigma"``), per direction
  (``mode="filtered"``) or on the manipulability (``mode="manipulability"``).
* :class:`SDLS` — selectively damped least squares (Buss & Kim 2005).
* :class:`NullSpace` — a primary solver plus a secondary objective projected into the
  null space of J (Liégeois 1977).

Task weights (``task_weights=``: a (m,) vector, ``"position"`` or ``"orientation"``)
and joint weights (``joint_weights=``: a (n,) vector) are constructor options of every
solver: they solve min ‖J q̇ − ξ‖²_Wx + λ² q̇ᵀ W_q q̇ (rows of weight 0 are dropped).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import lapack as _lapack

from .errors import InputError, RatectlError, SingularityError, SolverError

__all__ = [  # noqa: F822 - QP is re-exported lazily from ratectl.qp (module __getattr__)
    "Limits", "SolveResult", "Solver", "Inverse", "PseudoInverse", "DLS", "AdaptiveDLS", "SDLS",
    "NullSpace", "JointCentring", "Manipulability", "Gradient", "QP", "POSITION_ONLY",
    "ORIENTATION_ONLY", "VELOCITY_POLICIES", "adaptive_damping",
]

VELOCITY_POLICIES = ("scale", "clip", None)

#: Task weights for a position-only task (the angular rows are ignored).
POSITION_ONLY = (1.0, 1.0, 1.0, 0.0, 0.0, 0.0)
#: Task weights for an orientation-only task (the linear rows are ignored).
ORIENTATION_ONLY = (0.0, 0.0, 0.0, 1.0, 1.0, 1.0)

_F64 = np.dtype(np.float64)
_dot = np.dot
_zeros = np.zeros
_dposv = _lapack.dposv
_dpotrf = _lapack.dpotrf
_dsyev = _lapack.dsyev
_dgesdd = _lapack.dgesdd
_dgesv = _lapack.dgesv
_SQRT_HALF = math.sqrt(0.5)


def __getattr__(name: str):
    # ``QP`` lives in ratectl.qp (which imports this module); re-export it lazily.
    if name == "QP":
        from .qp import QP

        return QP
    raise AttributeError(f"module 'ratectl.solvers' has no attribute {name!r}")


# --------------------------------------------------------------------------- limits
@dataclass(frozen=True, slots=True)
class Limits:
    """Joint limits in SI units; ±inf where absent. Shapes (n,).

    Attributes:
        lower, upper: position limits [rad or m].
        vmax: velocity limits (magnitudes) [rad/s or m/s].
        amax: acceleration limits (magnitudes) [rad/s² or m/s²].
    """

    lower: np.ndarray
    upper: np.ndarray
    vmax: np.ndarray
    amax: np.ndarray

    def __post_init__(self) -> None:
        for name in ("lower", "upper", "vmax", "amax"):
            try:
                a = np.array(getattr(self, name), dtype=float)
            except (TypeError, ValueError):
                raise InputError(f"Limits.{name} must be an array of numbers, got "
                                 f"{getattr(self, name)!r}", argument=name,
                                 value=getattr(self, name)) from None
            if a.ndim != 1:
                raise InputError(f"Limits.{name} must be a 1-D array (one value per joint), got "
                                 f"shape {a.shape}", argument=name, value=a)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        if not (self.lower.shape == self.upper.shape == self.vmax.shape == self.amax.shape):
            raise InputError("Limits.lower, upper, vmax and amax must have the same length",
                             argument="limits", value=self)

    @classmethod
    def of(cls, obj, n: int) -> Limits:
        """Limits from a Chain, a Limits, any object with those four arrays, or None
        (unlimited)."""
        if obj is None:
            inf = np.full(n, math.inf)
            return cls(-inf, inf, inf, inf)
        if type(obj) is cls and obj.lower.shape == (n,):
            return obj
        try:
            arrs = [np.asarray(getattr(obj, k), dtype=float) for k in ("lower", "upper", "vmax", "amax")]
        except AttributeError:
            raise InputError("limits must have arrays lower, upper, vmax, amax (a Chain or "
                             f"ratectl.solvers.Limits), got {type(obj).__name__}",
                             argument="limits", value=obj) from None
        for name, a in zip(("lower", "upper", "vmax", "amax"), arrs, strict=True):
            if a.shape != (n,):
                raise InputError(f"limits.{name} must have one value per joint ({n}), got shape "
                                 f"{a.shape}", argument="limits", value=obj)
            if np.any(np.isnan(a)):
                raise InputError(f"limits.{name} contains NaN", argument="limits", value=obj)
        if np.any(arrs[2] <= 0) or np.any(arrs[3] <= 0):
            raise InputError("limits.vmax and limits.amax must be positive magnitudes (inf where "
                             "absent)", argument="limits", value=obj)
        if np.any(arrs[0] > arrs[1]):
            raise InputError("limits.lower must not exceed limits.upper", argument="limits", value=obj)
        return cls(*arrs)


# --------------------------------------------------------------------------- result
class _LazySigma:
    """σ_min of J computed on first access from the Gram matrix G (JJᵀ or JᵀJ, the
    smaller), as √λ_min(G): about 1e-8 absolute accuracy near zero, exact enough for
    reporting and scheduling. Keeps plain DLS free of an eigen-decomposition."""

    __slots__ = ("G", "J")

    def __init__(self, G, J=None):
        self.G = G
        self.J = J

    def value(self) -> float:
        G = self.G
        if G is None:
            J = self.J
            G = J @ J.T if J.shape[0] <= J.shape[1] else J.T @ J
        if G.shape[0] == 0:
            return 0.0
        w, _, info = _dsyev(G, compute_v=0)
        return math.sqrt(max(float(w[0]), 0.0)) if info == 0 else math.nan


@dataclass(frozen=True, slots=True, eq=False)
class SolveResult:
    """What an inverse-velocity solver returns.

    Attributes:
        qd: joint velocities (n,) [rad/s or m/s].
        achieved: the twist actually produced, ``J q̇`` (m,).
        task_error: ``ξ − J q̇`` (m,): what the solver gave up (damping, limits).
        damping: damping λ used (0 for undamped solutions; the largest per-direction λ
            for filtered damping).
        sigma_min: smallest singular value of J (of the weighted J for weighted
            solvers). Fixed-λ DLS computes it on first access (it is not needed for
            the solution), so reading it costs ~2 µs there.
        method: solver name ("inverse", "pinv", "dls", "adaptive-dls", "sdls", "qp", ...).
        velocity_policy: the velocity-limit policy *applied*: "none", "scaled" or "clipped".
        velocity_scale: the uniform factor applied by "scaled" (1.0 otherwise).
        bound: (n,) booleans, joints that sit at an active bound.
        limits_active: which kinds of limit bound: subset of
            ("velocity", "position", "acceleration").
        fallback: True when the requested method failed and a fallback answered.
        info: extra numbers (solver-specific), e.g. rank, iteration counts.
    """

    qd: np.ndarray
    achieved: np.ndarray
    task_error: np.ndarray
    damping: float
    sigma_min: float
    method: str
    velocity_policy: str = "none"
    velocity_scale: float = 1.0
    bound: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    limits_active: tuple[str, ...] = ()
    fallback: bool = False
    info: dict = field(default_factory=dict)

    # A hand-written __init__ (the dataclass keeps it): it stores the slots through their
    # descriptors, ~2x cheaper than the generated frozen __init__ (this is a hot path).
    def __init__(self, qd, achieved, task_error, damping, sigma_min, method,
                 velocity_policy="none", velocity_scale=1.0, bound=None, limits_active=(),
                 fallback=False, info=None):
        s = _SETTERS
        s[0](self, qd)
        s[1](self, achieved)
        s[2](self, task_error)
        s[3](self, damping)
        s[4](self, sigma_min)
        s[5](self, method)
        s[6](self, velocity_policy)
        s[7](self, velocity_scale)
        s[8](self, np.zeros(len(qd), dtype=bool) if bound is None else bound)
        s[9](self, limits_active)
        s[10](self, fallback)
        s[11](self, {} if info is None else info)


_FIELDS = ("qd", "achieved", "task_error", "damping", "sigma_min", "method", "velocity_policy",
           "velocity_scale", "bound", "limits_active", "fallback", "info")
_SETTERS = tuple(SolveResult.__dict__[f].__set__ for f in _FIELDS)
# σ_min may be stored lazily: replace the slot's attribute by a property over the slot.
_SIGMA_SLOT = SolveResult.__dict__["sigma_min"]


def _get_sigma(self):
    v = _SIGMA_SLOT.__get__(self, SolveResult)
    if type(v) is _LazySigma:
        v = v.value()
        _SIGMA_SLOT.__set__(self, v)
    return v


SolveResult.sigma_min = property(_get_sigma, _SIGMA_SLOT.__set__,
                                 doc="σ_min of (weighted) J (computed lazily by DLS).")


def _make_result(qd, J, xi, damping, sigma, method, policy, scale, bound, active, fallback, info):
    achieved = J @ qd
    return SolveResult(qd, achieved, xi - achieved, damping, sigma, method, policy, scale, bound,
                       active, fallback, info)


# --------------------------------------------------------------------------- helpers
def _check_problem(J, xi):
    if type(J) is not np.ndarray or J.dtype != _F64:
        try:
            J = np.asarray(J, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"J must be a numeric (m, n) matrix, got {J!r}", argument="J",
                             value=J) from None
    if type(xi) is not np.ndarray or xi.dtype != _F64:
        try:
            xi = np.asarray(xi, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"xi must be a numeric twist, got {xi!r}", argument="xi",
                             value=xi) from None
    if J.ndim != 2:
        raise InputError(f"J must be a 2-D (m, n) matrix, got shape {J.shape}", argument="J", value=J)
    if xi.shape != (J.shape[0],):
        raise InputError(f"xi must have shape ({J.shape[0]},) to match J {J.shape}, got {xi.shape}",
                         argument="xi", value=xi)
    # finiteness through Python float sums: cheaper than np.isfinite and never warns
    s = sum(J.ravel().tolist()) + sum(xi.tolist())
    if s - s != 0.0:
        _check_finite(J, xi)
    return J, xi


def _check_finite(J, xi):
    if not np.all(np.isfinite(J)):
        raise InputError("J must be finite (got NaN or inf)", argument="J", value=J)
    if not np.all(np.isfinite(xi)):
        raise InputError("xi must be finite (got NaN or inf)", argument="xi", value=xi)


def _positive(name, value, *, allow_zero=False):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}", argument=name, value=value) from None
    ok = (v >= 0 if allow_zero else v > 0) and math.isfinite(v)
    if not ok:
        kind = "non-negative" if allow_zero else "positive"
        raise InputError(f"{name} must be a finite {kind} number, got {value!r}", argument=name,
                         value=value)
    return v


def _weights(task_weights, joint_weights):
    """Normalise the weight options: (rows, sqrt task weights or None, 1/sqrt joint weights)."""
    rows = sw = isw = None
    if task_weights is not None:
        if isinstance(task_weights, str):
            table = {"position": POSITION_ONLY, "orientation": ORIENTATION_ONLY,
                     "full": (1.0,) * 6}
            if task_weights not in table:
                raise InputError(f"task_weights must be 'position', 'orientation', 'full' or a "
                                 f"vector of non-negative weights, got {task_weights!r}",
                                 argument="task_weights", value=task_weights)
            task_weights = table[task_weights]
        w = np.asarray(task_weights, dtype=float)
        if w.ndim != 1 or not np.all(np.isfinite(w)) or np.any(w < 0) or not np.any(w > 0):
            raise InputError("task_weights must be a vector of finite non-negative weights, one per "
                             f"task row, not all zero; got {task_weights!r}",
                             argument="task_weights", value=task_weights)
        rows = np.flatnonzero(w > 0)
        sw = np.sqrt(w[rows])
        rows = (rows, w.shape[0])
    if joint_weights is not None:
        w = np.asarray(joint_weights, dtype=float)
        if w.ndim != 1 or not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise InputError("joint_weights must be a vector of finite positive weights, one per "
                             f"joint; got {joint_weights!r}", argument="joint_weights",
                             value=joint_weights)
        isw = 1.0 / np.sqrt(w)
    return rows, sw, isw


def adaptive_damping(sigma, *, epsilon: float, max_damping: float):
    """The σ-scheduled damping of Maciejewski & Klein / Chiaverini:

    λ² = (1 − (σ/ε)²)·λ_max² for σ < ε, else 0.  Returns λ (scalar or array like σ).
    """
    s = np.asarray(sigma, dtype=float)
    r = np.clip(s / epsilon, 0.0, 1.0)
    lam = max_damping * np.sqrt(1.0 - r * r)
    return float(lam) if lam.ndim == 0 else lam


def _gain_bound_adaptive(epsilon: float, lam_max: float) -> float:
    """sup over σ ≥ 0 of the per-direction gain σ/(σ² + λ(σ)²) under the σ schedule.

    For σ ≥ ε the gain is 1/σ ≤ 1/ε. Below, g(σ) = σ/(aσ² + b) with a = 1 − λ_max²/ε²,
    b = λ_max²; its maximum is 1/(2λ_max√a) at σ* = √(b/a) when λ_max ≤ ε/√2, else 1/ε.
    """
    if lam_max <= epsilon * _SQRT_HALF:
        a = 1.0 - (lam_max / epsilon) ** 2
        return max(1.0 / epsilon, 1.0 / (2.0 * lam_max * math.sqrt(a)))
    return 1.0 / epsilon


# --------------------------------------------------------------------------- base class
class Solver:
    """Base class: validation, weights, the velocity-limit policy and the result.

    Subclasses implement ``_raw(J, xi) -> (qd, damping, sigma_min, info)`` on the
    weighted problem (rows of zero task weight removed, columns scaled by W_q^{-1/2}).

    Args:
        velocity_policy: ``"scale"`` (uniform scaling, keeps the direction), ``"clip"``
            (per joint) or ``None`` (ignore the velocity limits).
        task_weights: (m,) non-negative weights of the task rows, or ``"position"`` /
            ``"orientation"``; zero-weight rows are dropped (partial twists).
        joint_weights: (n,) positive weights W_q of the joint-velocity norm (a heavier
            joint moves less).
    """

    method = "base"

    def __init__(self, *, velocity_policy: str | None = "scale", task_weights=None,
                 joint_weights=None) -> None:
        if velocity_policy not in VELOCITY_POLICIES:
            raise InputError(f"velocity_policy must be one of {VELOCITY_POLICIES}, "
                             f"got {velocity_policy!r}", argument="velocity_policy",
                             value=velocity_policy)
        self.velocity_policy = velocity_policy
        self.task_weights = task_weights
        self.joint_weights = joint_weights
        self._rows, self._sw, self._isw = _weights(task_weights, joint_weights)
        self._weighted = self._rows is not None or self._isw is not None
        self._lim_obj = None
        self._lim_vmax = None

    def __repr__(self) -> str:
        return f"{type(self).__name__}(velocity_policy={self.velocity_policy!r})"

    def _raw(self, J, xi):  # pragma: no cover - abstract
        raise NotImplementedError

    def _apply_weights(self, J, xi):
        if self._rows is not None:
            rows, m = self._rows
            if J.shape[0] != m:
                raise InputError(f"task_weights has {m} entries but J has {J.shape[0]} rows",
                                 argument="task_weights", value=self.task_weights)
            J = J[rows] * self._sw[:, None]
            xi = xi[rows] * self._sw
        if self._isw is not None:
            if J.shape[1] != self._isw.shape[0]:
                raise InputError(f"joint_weights has {self._isw.shape[0]} entries but J has "
                                 f"{J.shape[1]} columns", argument="joint_weights",
                                 value=self.joint_weights)
            J = J * self._isw
        return J, xi

    def _vmax(self, limits, n):
        if limits is self._lim_obj:
            return self._lim_vmax
        vmax = Limits.of(limits, n).vmax
        self._lim_obj, self._lim_vmax = limits, vmax
        return vmax

    def _policy(self, qd, limits, n):
        """Apply the velocity-limit policy: (qd, policy, scale, bound, active)."""
        vmax = self._vmax(limits, n)
        ratio = np.abs(qd) / vmax
        worst = float(ratio.max()) if n else 0.0
        if not worst > 1.0:
            return qd, "none", 1.0, np.zeros(n, dtype=bool), ()
        if self.velocity_policy == "scale":
            scale = 1.0 / worst
            return qd * scale, "scaled", scale, ratio >= worst * (1 - 1e-12), ("velocity",)
        return np.clip(qd, -vmax, vmax), "clipped", 1.0, ratio > 1.0, ("velocity",)

    def _solve_weighted(self, J, xi):
        """Solve the weighted problem and map q̇ back to joint space."""
        if not self._weighted:
            return self._raw(J, xi)
        Jw, xiw = self._apply_weights(J, xi)
        qd, damping, sigma, info = self._raw(Jw, xiw)
        if self._isw is not None:
            qd = qd * self._isw
        return qd, damping, sigma, info

    def solve(self, J, xi, *, limits=None, q=None, qd_prev=None, dt=None) -> SolveResult:
        """Joint velocities q̇ (n,) for the twist ``xi`` (m,) with the Jacobian ``J`` (m, n).

        Args:
            J: Jacobian (m, n), rows [linear; angular] in SI units.
            xi: desired twist (m,) [m/s; rad/s].
            limits: joint limits (a Chain or :class:`Limits`); non-QP solvers use
                ``vmax`` through the velocity-limit policy.
            q, qd_prev, dt: current joint positions, previous joint velocities and the
                step [s]; used by the QP and by :class:`NullSpace` (``q``).
        """
        J, xi = _check_problem(J, xi)
        n = J.shape[1]
        try:
            if self._weighted:
                qd, damping, sigma, info = self._solve_weighted(J, xi)
            else:
                qd, damping, sigma, info = self._raw(J, xi)
        except RatectlError:
            raise
        except (ValueError, np.linalg.LinAlgError) as exc:  # LAPACK failures
            raise SolverError(f"{self.method}: linear algebra failed: {exc}") from exc
        achieved = _dot(J, qd)
        err = xi - achieved
        if limits is None or self.velocity_policy is None:
            return SolveResult(qd, achieved, err, damping, sigma, self.method, "none", 1.0,
                               _zeros(n, dtype=bool), (), False, info)
        qd, policy, scale, bound, active = self._policy(qd, limits, n)
        if policy == "none":
            return SolveResult(qd, achieved, err, damping, sigma, self.method, policy, scale, bound,
                               active, False, info)
        return _make_result(qd, J, xi, damping, sigma, self.method, policy, scale, bound, active,
                            False, info)


# --------------------------------------------------------------------------- linear algebra
def _svd(J):
    """Thin SVD (U (m,k), s (k,), Vt (k,n)) through LAPACK dgesdd."""
    u, s, vt, info = _dgesdd(J, compute_uv=1, full_matrices=0)
    if info != 0:
        raise np.linalg.LinAlgError(f"SVD did not converge (dgesdd info {info})")
    return u, s, vt


# --------------------------------------------------------------------------- solvers
class Inverse(Solver):
    """Exact inverse q̇ = J⁻¹ξ for a square J.

    Raises :class:`SingularityError` (carrying ``sigma_min`` and ``tolerance``) when
    σ_min(J) < ``tolerance`` [same units as J's singular values].
    """

    method = "inverse"

    def __init__(self, *, tolerance: float = 1e-6, velocity_policy: str | None = None,
                 task_weights=None, joint_weights=None) -> None:
        super().__init__(velocity_policy=velocity_policy, task_weights=task_weights,
                         joint_weights=joint_weights)
        self.tolerance = _positive("tolerance", tolerance, allow_zero=True)

    def _raw(self, J, xi):
        m, n = J.shape
        if m != n:
            raise InputError(f"the exact inverse needs a square J, got {J.shape}; use "
                             "PseudoInverse, DLS or QP for m != n", argument="J", value=J)
        _, s, _, info = _dgesdd(J, compute_uv=0)
        if info != 0:
            raise np.linalg.LinAlgError(f"SVD did not converge (dgesdd info {info})")
        smin = float(s[-1])
        if not smin >= self.tolerance:
            _check_finite(J, xi)
            raise SingularityError(
                f"J is singular: sigma_min = {smin:.3e} < tolerance {self.tolerance:.1e}; "
                "use a damped solver (DLS, AdaptiveDLS) near singular configurations",
                sigma_min=smin, tolerance=self.tolerance)
        _, _, x, info = _dgesv(J, xi)
        if info != 0:  # pragma: no cover - excluded by the σ_min test
            raise np.linalg.LinAlgError(f"dgesv info {info}")
        return x, 0.0, smin, {}


class PseudoInverse(Solver):
    """Truncated Moore–Penrose pseudo-inverse, any m×n J:

    q̇ = Σ_{σ_i > tol} σ_i⁻¹ v_i u_iᵀ ξ.

    Singular values at or below ``tolerance`` are treated as exactly zero (their
    directions are dropped); ``info["rank"]`` is the number kept. Undamped: the gain
    is 1/σ for the smallest kept σ, unbounded as σ → tol⁺.
    """

    method = "pinv"

    def __init__(self, *, tolerance: float = 1e-6, velocity_policy: str | None = "scale",
                 task_weights=None, joint_weights=None) -> None:
        super().__init__(velocity_policy=velocity_policy, task_weights=task_weights,
                         joint_weights=joint_weights)
        self.tolerance = _positive("tolerance", tolerance, allow_zero=True)

    def _raw(self, J, xi):
        u, s, vt = _svd(J)
        keep = s > self.tolerance
        coef = np.zeros_like(s)
        coef[keep] = (xi @ u[:, keep]) / s[keep]
        smin = float(s[-1]) if min(J.shape) == s.shape[0] and s.shape[0] else 0.0
        return coef @ vt, 0.0, smin, {"rank": int(keep.sum()), "singular_values": s}


class DLS(Solver):
    """Damped least squares with a fixed λ [units of σ]:

    q̇ = Jᵀ(JJᵀ + λ²I)⁻¹ξ  (= (JᵀJ + λ²I)⁻¹Jᵀξ),

    the minimiser of ‖Jq̇ − ξ‖² + λ²‖q̇‖². Each singular direction gets the gain
    σ/(σ² + λ²) ≤ 1/(2λ), so ‖q̇‖ ≤ ‖ξ‖/(2λ) everywhere, singular or not. Solved with a
    Cholesky factorisation (no SVD); ``result.sigma_min`` is computed on first access.
    """

    method = "dls"

    def __init__(self, *, damping: float = 0.05, velocity_policy: str | None = "scale",
                 task_weights=None, joint_weights=None) -> None:
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

    In every mode the per-direction gain is at most :meth:`gain_bound`
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
                 velocity_policy: str | None = "scale", task_weights=None,
                 joint_weights=None) -> None:
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
            self.manipulability_threshold = _positive("manipulability_threshold",
                                                      manipulability_threshold)
        else:
            self.manipulability_threshold = manipulability_threshold
        self._lm2 = self.max_damping**2
        self._ie2 = 1.0 / self.epsilon**2
        self._eye: dict[int, np.ndarray] = {}

    def __repr__(self) -> str:
        return (f"AdaptiveDLS(epsilon={self.epsilon!r}, max_damping={self.max_damping!r}, "
                f"mode={self.mode!r})")

    def gain_bound(self) -> float:
        """sup ‖q̇‖/‖ξ‖ over all J for the σ modes (see the class docstring)."""
        return _gain_bound_adaptive(self.epsilon, self.max_damping)

    def damping_at(self, sigma):
        """λ(σ) of the schedule (scalar or array)."""
        return adaptive_damping(sigma, epsilon=self.epsilon, max_damping=self.max_damping)

    def _raw(self, J, xi):
        if self.mode == "filtered":
            return self._filtered(J, xi)
        m, n = J.shape
        wide = m <= n
        G = J @ J.T if wide else J.T @ J
        k = G.shape[0]
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
            wm = float(np.prod(np.diagonal(c))) if info == 0 else 0.0
            r = wm / self.manipulability_threshold
            lam2 = self._lm2 * (1.0 - r) ** 2 if r < 1.0 else 0.0
            sigma = _LazySigma(G)
            smin = None
        lam = math.sqrt(lam2)
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
        info_d = {"gain_bound": bound}
        if self.mode == "manipulability":
            info_d["manipulability"] = wm
        return qd, lam, sigma, info_d

    def _filtered(self, J, xi):
        u, s, vt = _svd(J)
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
                 task_weights=None, joint_weights=None) -> None:
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
        u, s, vt = _svd(Js)
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
            sv = _dgesdd(J, compute_uv=0)[1]
            smin = float(sv[-1]) if full and sv.size else 0.0
        else:
            smin = float(s[-1]) if full and k else 0.0
        return qd, 0.0, smin, {"gammas": gammas, "rank": int(keep.sum())}


# --------------------------------------------------------------------------- null space
class JointCentring:
    """Secondary objective: stay near the middle of the joint ranges.

    H(q) = ½ Σ ((q_i − c_i)/r_i)², c = (lower + upper)/2, r = (upper − lower)/2;
    the secondary velocity is z = −∇H = −(q − c)/r² [1/rad]. Joints without finite
    limits are left alone. ``limits`` is a Chain or :class:`Limits`.
    """

    def __init__(self, limits) -> None:
        lower = np.asarray(limits.lower, dtype=float)
        upper = np.asarray(limits.upper, dtype=float)
        finite = np.isfinite(lower) & np.isfinite(upper)
        self.centre = np.where(finite, 0.5 * (lower + upper), 0.0)
        half = np.where(finite, 0.5 * (upper - lower), 1.0)
        self._w = np.where(finite, 1.0 / half**2, 0.0)

    def cost(self, q) -> float:
        """H(q), dimensionless."""
        d = np.asarray(q, dtype=float) - self.centre
        return 0.5 * float(d @ (self._w * d))

    def __call__(self, q) -> np.ndarray:
        return -self._w * (np.asarray(q, dtype=float) - self.centre)


class Manipulability:
    """Secondary objective: increase the manipulability w(q) = √det(JJᵀ) of ``chain``;
    z = ∇w(q) from :func:`ratectl.singularity.manipulability_gradient`."""

    def __init__(self, chain) -> None:
        self.chain = chain

    def __call__(self, q) -> np.ndarray:
        from .singularity import manipulability_gradient

        return np.asarray(manipulability_gradient(self.chain, q), dtype=float)


class Gradient:
    """Secondary objective from a user gradient ``f(q) -> (n,)`` of a cost H(q).

    ``maximize=False`` (default) descends the cost (z = −∇H); ``True`` ascends it.
    """

    def __init__(self, f, *, maximize: bool = False) -> None:
        if not callable(f):
            raise InputError(f"Gradient needs a callable f(q) -> (n,), got {f!r}", argument="f",
                             value=f)
        self.f = f
        self.sign = 1.0 if maximize else -1.0

    def __call__(self, q) -> np.ndarray:
        return self.sign * np.asarray(self.f(q), dtype=float)


def _objective(objective, chain):
    if isinstance(objective, str):
        if chain is None:
            raise InputError(f"objective {objective!r} needs chain= (for the joint limits or the "
                             "manipulability gradient)", argument="chain", value=None)
        if objective in ("centring", "centering"):
            return JointCentring(chain)
        if objective == "manipulability":
            return Manipulability(chain)
        raise InputError("objective must be 'centring', 'manipulability', a JointCentring/"
                         f"Manipulability/Gradient object or a callable; got {objective!r}",
                         argument="objective", value=objective)
    if callable(objective):
        return objective
    raise InputError(f"objective must be a string or a callable q -> (n,), got {objective!r}",
                     argument="objective", value=objective)


class NullSpace(Solver):
    """A primary solver plus a secondary objective in the null space of J (Liégeois 1977):

    q̇ = q̇_primary + k·(I − J⁺J)·z(q),

    where z(q) is the objective's joint velocity (−∇H for a cost H) and J⁺ is the
    **undamped, truncated** pseudo-inverse (singular values ≤ ``tolerance`` dropped).
    With that projector J(I − J⁺J) = 0 up to the dropped σ's, so the secondary motion
    never leaks into the task even when the primary solver is damped (a damped J⁺
    would give J(I − J⁺_λ J) ≠ 0). Needs ``q=`` in :meth:`solve`.

    Args:
        primary: any solver (called without limits, so its velocity policy does not act;
            this wrapper's policy applies to the sum). A QP primary gets the limits, but
            the added null-space motion is not bounded by them: for a limit-aware
            secondary objective use ``QP(objective=...)``.
        objective: ``"centring"``, ``"manipulability"`` (both need ``chain``), a
            :class:`JointCentring`, :class:`Manipulability` or :class:`Gradient`, or any
            callable q -> (n,) returning the desired secondary joint velocity.
        gain: k [1/s], the gain on z.
        chain: the chain, for the string objectives.
        tolerance: truncation tolerance of the projector's pseudo-inverse.
    """

    method = "nullspace"

    def __init__(self, primary: Solver, objective="centring", *, gain: float = 1.0, chain=None,
                 tolerance: float = 1e-6, velocity_policy: str | None = "scale") -> None:
        super().__init__(velocity_policy=velocity_policy)
        if not isinstance(primary, Solver):
            raise InputError(f"primary must be a ratectl solver, got {primary!r}",
                             argument="primary", value=primary)
        self.primary = primary
        self.objective = _objective(objective, chain)
        self.gain = _positive("gain", gain, allow_zero=True)
        self.tolerance = _positive("tolerance", tolerance, allow_zero=True)
        self.method = f"nullspace({primary.method})"

    def solve(self, J, xi, *, limits=None, q=None, qd_prev=None, dt=None) -> SolveResult:
        """As :meth:`Solver.solve`; ``q`` (n,) is required for the objective."""
        J, xi = _check_problem(J, xi)
        m, n = J.shape
        if q is None:
            raise InputError("NullSpace.solve needs q= (the joint positions) for its secondary "
                             "objective", argument="q", value=None)
        q = np.asarray(q, dtype=float)
        if q.shape != (n,) or not np.all(np.isfinite(q)):
            raise InputError(f"q must be a finite ({n},) vector, got shape {q.shape}", argument="q",
                             value=q)
        # the primary's velocity policy acts only with limits: pass none (this wrapper applies
        # its policy to the sum), except to a QP, whose bounds are part of its solution
        p = self.primary.solve(J, xi, limits=limits if self.primary.method == "qp" else None, q=q,
                               qd_prev=qd_prev, dt=dt)
        z = np.asarray(self.objective(q), dtype=float)
        if z.shape != (n,) or not np.all(np.isfinite(z)):
            raise InputError(f"the secondary objective must return a finite ({n},) vector, got "
                             f"shape {z.shape}", argument="objective", value=z)
        _, s, vt = _svd(J)
        Vr = vt[s > self.tolerance]
        zp = z - (z @ Vr.T) @ Vr
        qd = p.qd + self.gain * zp
        info = dict(p.info)
        info.update(secondary=self.gain * zp, primary_qd=p.qd, rank=int(Vr.shape[0]))
        policy, scale, bound, active = "none", 1.0, np.zeros(n, dtype=bool), ()
        if limits is not None and self.velocity_policy is not None:
            qd, policy, scale, bound, active = self._policy(qd, limits, n)
        return _make_result(qd, J, xi, p.damping, p.sigma_min, self.method, policy, scale, bound,
                            active, p.fallback, info)
