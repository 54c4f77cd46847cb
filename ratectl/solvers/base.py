"""The common parts of every inverse-velocity solver: `Limits`, `SolveResult`,
the `Solver` base class (weights, the velocity-limit policy, input checks).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import lapack as _lapack

from ..arrays import shared_zeros
from ..checks import positive_number as _positive  # noqa: F401  (the solvers import it from here)
from ..checks import real_array as _real_array
from ..errors import InputError, RatectlError, SolverError
from ..model.limits import Limits

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ['SolveResult', 'Solver', 'POSITION_ONLY', 'ORIENTATION_ONLY', 'VELOCITY_POLICIES',
           'solver_declares', 'validated_solve', 'validated_solve_generic', 'direction_result',
           'DirectionTwist', 'direction_twist_entry', 'solve_direction_generic']


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


_dpotrs = _lapack.dpotrs


_dsyev = _lapack.dsyev


_dgesdd = _lapack.dgesdd


_dgesv = _lapack.dgesv


_hypot = math.hypot


_dist = math.dist


# --------------------------------------------------------------------------- limits
# --------------------------------------------------------------------------- result
class _SigmaReference:
    """The last σ_min a solver computed exactly, with its (weighted) Jacobian's entries: the
    reference of `_LazySigma.certainly_at_least` (one per solver; the pair is replaced as
    one tuple, so any pair read is consistent)."""

    __slots__ = ("pair",)

    def __init__(self) -> None:
        # (the entries of J row by row as Python floats, J's shape, σ_min(J), ‖J‖²_F)
        self.pair: tuple[list[float], tuple[int, ...], float, float] | None = None


class _LazySigma:
    """σ_min of J computed on first access from the Gram matrix G (JJᵀ or JᵀJ, the
    smaller), as √λ_min(G): about 1e-8 absolute accuracy near zero, exact enough for
    reporting and scheduling. Keeps plain DLS free of an eigen-decomposition.

    With J's shape and entries (``entries``, row by row as Python floats: a list, which
    nobody changes) and a solver's `_SigmaReference`, "σ_min ≥ threshold" can often be
    decided without it (`certainly_at_least`), and every exact value becomes the new
    reference. Without G, J (an array the solver owns) gives it."""

    __slots__ = ("G", "J", "ref", "shape", "entries", "_value", "_dist")

    def __init__(self, G: np.ndarray | None, J: np.ndarray | None = None,
                 ref: _SigmaReference | None = None, *, shape: tuple[int, ...] | None = None,
                 entries: list[float] | None = None, value: float | None = None) -> None:
        self.G = G
        self.J = J
        self.ref = ref
        self.shape = shape
        self.entries = entries
        self._value: float | None = value  # (given: computed by the caller from G, as `value` would)
        self._dist: tuple[Any, float] | None = None  # (the reference pair, ‖J − J_ref‖_F)

    def value(self) -> float:
        """σ_min (computed once)."""
        v = self._value
        if v is None:
            v = self._value = self._compute()
        return v

    def _compute(self) -> float:
        G = self.G
        if G is None:
            J = self.J
            if J is None:  # pragma: no cover - built with G or J
                return math.nan
            G = J @ J.T if J.shape[0] <= J.shape[1] else J.T @ J
        if G.shape[0] == 0:
            return 0.0
        w, _, info = _dsyev(G, compute_v=0)
        s = math.sqrt(max(float(w[0]), 0.0)) if info == 0 else math.nan
        entries = self.entries
        if self.ref is not None and entries is not None and self.shape is not None and s == s:
            self.ref.pair = (entries, self.shape, s, _hypot(*entries) ** 2)
        return s

    def certainly_at_least(self, threshold: float) -> bool:
        """True when σ_min(J) ≥ threshold follows from the reference (J_ref, σ_ref) by
        Weyl's inequality for singular values, σ_min(J) ≥ σ_ref − ‖J − J_ref‖₂ ≥
        σ_ref − ‖J − J_ref‖_F, with a margin for the rounding of the eigenvalues
        (1e-12·(1 + ‖J_ref‖²_F)/threshold); False means "not decided" (compute the value).
        One distance between two lists of floats instead of an eigen-decomposition: the
        Jacobian of a control loop moves little between cycles; a cycle that asks again
        (another threshold, the same reference) reuses the distance."""
        pair = self.ref.pair if self.ref is not None else None
        entries = self.entries
        if pair is None or entries is None or not threshold > 0.0:
            return False
        ref_entries, ref_shape, s_ref, norm2 = pair
        if ref_shape != self.shape or not s_ref > threshold:
            return False
        return s_ref - self._distance(pair) >= threshold + 1e-12 * (1.0 + norm2) / threshold

    def certainly_below(self, threshold: float) -> float | None:
        """An upper bound of σ_min(J) below ``threshold`` when σ_min(J) < threshold follows
        from the reference by the other side of Weyl's inequality, σ_min(J) ≤ σ_ref +
        ‖J − J_ref‖₂ ≤ σ_ref + ‖J − J_ref‖_F =: u, with a margin for σ_ref's accuracy
        (√λ_min of a Gram matrix: about 1e-8·‖J_ref‖_F absolute near 0, hence u ≤
        threshold − 1e-7·(1 + ‖J_ref‖_F)); None means "not decided". For a caller that only
        compares σ_min with the threshold (a singularity watch): below it, as often as
        above, no eigen-decomposition."""
        pair = self.ref.pair if self.ref is not None else None
        if pair is None or self.entries is None or not threshold > 0.0 or pair[1] != self.shape:
            return None
        upper = pair[2] + self._distance(pair)
        return upper if upper <= threshold - 1e-7 * (1.0 + math.sqrt(pair[3])) else None

    def _distance(self, pair: tuple) -> float:
        """‖J − J_ref‖_F to the reference ``pair`` (math.dist: the hypot of the differences),
        once per reference (a cycle that asks again, another threshold, reuses it)."""
        memo = self._dist
        if memo is not None and memo[0] is pair:
            return memo[1]
        assert self.entries is not None
        d = _dist(self.entries, pair[0])
        self._dist = (pair, d)
        return d


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
            solvers). Fixed-λ DLS and the QP compute it on first access (it is not needed
            for the solution), so reading it costs ~2 µs there; `sigma_min_at_least`
            compares it with a threshold, often without computing it.
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
    info: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))

    # A hand-written keyword-only __init__ (the dataclass keeps it): it stores the slots
    # through their descriptors, ~2x cheaper than the generated frozen __init__ (a hot path).
    # Arrays are made read-only (also those inside ``info``) and ``info`` is a read-only
    # mapping, so nothing a caller does to a result can reach the solver's state.
    def __init__(self, *, qd: np.ndarray, achieved: np.ndarray, task_error: np.ndarray,
                 damping: float, sigma_min: float | _LazySigma, method: str,
                 velocity_policy: str = "none", velocity_scale: float = 1.0,
                 bound: np.ndarray | None = None, limits_active: tuple[str, ...] = (),
                 fallback: bool = False, info: Mapping[str, Any] | None = None) -> None:
        if bound is None:
            bound = np.zeros(len(qd), dtype=bool)
        if info:
            for v in info.values():
                if type(v) is np.ndarray:
                    v.setflags(write=False)
        _store(self, qd, achieved, task_error, damping, sigma_min, method, velocity_policy,
               velocity_scale, bound, limits_active, fallback,
               _EMPTY if not info else MappingProxyType(dict(info)))

    def sigma_min_at_least(self, threshold: float) -> bool:
        """``self.sigma_min >= threshold``, decided without computing σ_min where the
        solver can certify it (the QP: from its last exactly computed σ_min and how far J
        moved since, see `SolveResult.sigma_min`); otherwise by computing it. Cheaper than
        reading ``sigma_min`` when only the comparison is needed (a control cycle's
        "near a singularity?")."""
        v = _SIGMA_SLOT.__get__(self, SolveResult)
        if type(v) is _LazySigma:
            if v.certainly_at_least(threshold):
                return True
            v = _get_sigma(self)
        return v >= threshold

    def __reduce__(self):
        values = {f: getattr(self, f) for f in _FIELDS}
        values["info"] = dict(values["info"])
        return _restore_result, (values,)


_EMPTY: Mapping[str, Any] = MappingProxyType({})


def _restore_result(values: dict) -> SolveResult:
    return SolveResult(**values)


_FIELDS = ("qd", "achieved", "task_error", "damping", "sigma_min", "method", "velocity_policy",
           "velocity_scale", "bound", "limits_active", "fallback", "info")


_SETTERS = tuple(SolveResult.__dict__[f].__set__ for f in _FIELDS)


def _store(r: SolveResult, qd, achieved, task_error, damping, sigma_min, method, velocity_policy,
           velocity_scale, bound, limits_active, fallback, info) -> None:
    """Freeze the four arrays in place and store every field of ``r`` through its slot's
    descriptor (~2× cheaper than the generated frozen ``__init__``: a hot path)."""
    for a in (qd, achieved, task_error, bound):
        a.setflags(write=False)  # cheaper than the flags object's setter
    s = _SETTERS
    s[0](r, qd)
    s[1](r, achieved)
    s[2](r, task_error)
    s[3](r, damping)
    s[4](r, sigma_min)
    s[5](r, method)
    s[6](r, velocity_policy)
    s[7](r, velocity_scale)
    s[8](r, bound)
    s[9](r, limits_active)
    s[10](r, fallback)
    s[11](r, info)


def _owned_result(qd: np.ndarray, achieved: np.ndarray, task_error: np.ndarray, damping: float,
                  sigma_min: float | _LazySigma, method: str, bound: np.ndarray,
                  limits_active: tuple[str, ...], info: dict[str, Any]) -> SolveResult:
    """The `SolveResult` of a solver's own fresh objects, without copies: the arrays are
    frozen in place and ``info`` (a dict nobody else holds, whose arrays the caller has
    already made read-only) is wrapped read-only as it is; no velocity policy applied,
    not a fallback. The QP's per-cycle result (~0.6 µs cheaper than the keyword
    constructor, which copies ``info`` and looks for arrays in it)."""
    r = _new(SolveResult)
    _store(r, qd, achieved, task_error, damping, sigma_min, method, "none", 1.0, bound,
           limits_active, False, MappingProxyType(info))
    return r


_new = object.__new__


# σ_min may be stored lazily: replace the slot's attribute by a property over the slot.
_SIGMA_SLOT = SolveResult.__dict__["sigma_min"]


def _get_sigma(self):
    v = _SIGMA_SLOT.__get__(self, SolveResult)
    if type(v) is _LazySigma:
        v = v.value()
        _SIGMA_SLOT.__set__(self, v)
    return v



# mypy cannot see a slot replaced by a property; the type of the attribute stays float
SolveResult.sigma_min = property(_get_sigma, _SIGMA_SLOT.__set__,  # type: ignore[misc, assignment]
                                 doc="σ_min of (weighted) J (computed lazily by DLS and the QP).")


def result_with_qd(res: SolveResult, J: np.ndarray, xi: np.ndarray, qd: np.ndarray) -> SolveResult:
    """``res`` for another q̇ (n,) of the twist ``xi`` (m,): q̇ = ``qd``, achieved J q̇ and the
    task error ξ − J q̇ recomputed; damping, σ_min (still lazy where it was), method, policy,
    bounds and info kept. For a command made of a solve and a part added to it (the servo's
    progress along its exact direction on top of the solved feedback)."""
    r = _new(SolveResult)
    achieved = J.dot(qd)
    _store(r, qd.copy(), achieved, xi - achieved, res.damping, _SIGMA_SLOT.__get__(res, SolveResult),
           res.method, res.velocity_policy, res.velocity_scale, res.bound, res.limits_active, res.fallback,
           res.info)
    return r


def direction_result(J: np.ndarray, d: np.ndarray, w: np.ndarray, *, damping: float,
                     sigma_min: float | _LazySigma, method: str) -> SolveResult:
    """The `SolveResult` of a direction's answer ``w`` (n,) (`Solver.solve_direction`) for
    the twist ``d`` (m,): q̇ = a copy of w, achieved J w, task error d − J w, no velocity
    policy, no joint at a bound, no info. The same result as the keyword constructor's,
    without its checks of ``info`` and the fresh ``bound`` (a control cycle's jog, every
    period)."""
    r = _new(SolveResult)
    achieved = J.dot(w)
    _store(r, w.copy(), achieved, d - achieved, damping, sigma_min, method, "none", 1.0,
           shared_zeros(w.shape[0], bool), (), False, _EMPTY)
    return r


class DirectionTwist:
    """What `Solver.solve_direction_twist` answers for a direction d and a twist ξ on the
    same J, both without limits: the direction's answer ``w`` (n,), ``sigma`` and
    ``damping`` (as `Solver.solve_direction` returns them) and the twist's ``qd`` (n,), the
    correction c = solver(J, ξ) of `Solver.solve_validated` with ``limits=None``, with the
    ``velocity_policy``, ``velocity_scale`` and ``limits_active`` of its result. `result`
    gives the `SolveResult` of a command q̇ made of that answer and a part added to it (a
    servo's progress along w: q̇ = c + ṡ·w for ξ + ṡ·d), built only then.

    ``feedback`` is the twist's `SolveResult` when the solver made one (the generic entry);
    a solver that answers both at once passes ``make`` instead, a callable
    ``make(xi, qd) -> SolveResult`` with the contract of `result`."""

    __slots__ = ("w", "sigma", "damping", "qd", "velocity_policy", "velocity_scale", "limits_active",
                 "_J", "_feedback", "_make")

    def __init__(self, w: np.ndarray, sigma: Any, damping: float, qd: np.ndarray, *, J: np.ndarray,
                 feedback: SolveResult | None = None, make: Any = None,
                 velocity_policy: str = "none", velocity_scale: float = 1.0,
                 limits_active: tuple[str, ...] = ()) -> None:
        self.w = w
        self.sigma = sigma
        self.damping = damping
        self.qd = qd
        self._J = J
        self._feedback = feedback
        self._make = make
        if feedback is not None:
            velocity_policy = feedback.velocity_policy
            velocity_scale = feedback.velocity_scale
            limits_active = feedback.limits_active
        self.velocity_policy = velocity_policy
        self.velocity_scale = velocity_scale
        self.limits_active = limits_active

    def result(self, xi: np.ndarray, qd: np.ndarray) -> SolveResult:
        """The `SolveResult` of the command ``qd`` (n,) for the twist ``xi`` (m,): the twist's
        own result when ``qd`` is its answer (``qd is self.qd``); otherwise that result for
        another q̇ (`result_with_qd`: q̇ = ``qd``, achieved J q̇, task error ξ − J q̇; damping,
        σ_min, method, policy, bounds and info the twist's)."""
        make = self._make
        if make is not None:
            return make(xi, qd)
        fb = self._feedback
        assert fb is not None
        return fb if qd is self.qd else result_with_qd(fb, self._J, xi, qd)


def _make_result(qd, J, xi, damping, sigma, method, policy, scale, bound, active, fallback, info):
    achieved = J @ qd
    return SolveResult(qd=qd, achieved=achieved, task_error=xi - achieved, damping=damping,
                       sigma_min=sigma, method=method, velocity_policy=policy, velocity_scale=scale,
                       bound=bound, limits_active=active, fallback=fallback, info=info)


# --------------------------------------------------------------------------- helpers
def _check_problem(J, xi):
    """(J, ξ, the entries of J row by row as Python floats) after the checks of shape,
    type, finiteness and range; raises `InputError`."""
    if type(J) is not np.ndarray or J.dtype != _F64:
        J = _real_array("J", J, "a numeric (m, n) matrix")
    if type(xi) is not np.ndarray or xi.dtype != _F64:
        xi = _real_array("xi", xi, "a numeric twist")
    if J.ndim != 2:
        raise InputError(f"J must be a 2-D (m, n) matrix, got shape {J.shape}", argument="J", value=J)
    if J.shape[0] == 0 or J.shape[1] == 0:
        raise InputError(f"J must have at least one row and one column, got shape {J.shape}",
                         argument="J", value=J)
    if xi.shape != (J.shape[0],):
        raise InputError(f"xi must have shape ({J.shape[0]},) to match J {J.shape}, got {xi.shape}",
                         argument="xi", value=xi)
    return J, xi, _checked_entries(J, xi)


def _checked_entries(J: np.ndarray, xi: np.ndarray) -> list[float]:
    """The entries of J row by row as Python floats, after checking that J and ξ (float
    arrays) are finite and small enough that products like JJᵀ cannot overflow (|J|, |ξ| up
    to ~1e145 are accepted): √(‖J‖²_F + ‖ξ‖²) < 1e145, by math.hypot over Python floats in
    one C call (it cannot overflow; NaN or inf make it non-finite; cheaper than numpy here).
    Raises `InputError`."""
    entries = J.ravel().tolist()
    if not _hypot(*entries, *xi.tolist()) < _MAX_ENTRY:
        _check_finite(J, xi)
        raise InputError(f"J and xi must have entries below {_MAX_ENTRY:.0e} in magnitude (their "
                         "products overflow floating point); got max |J| = "
                         f"{float(np.max(np.abs(J))):.3g}, max |xi| = {float(np.max(np.abs(xi))):.3g}",
                         argument="J", value=J)
    return entries


_MAX_ENTRY = 1e145


def _check_finite(J, xi):
    if not np.all(np.isfinite(J)):
        raise InputError("J must be finite (got NaN or inf)", argument="J", value=J)
    if not np.all(np.isfinite(xi)):
        raise InputError("xi must be finite (got NaN or inf)", argument="xi", value=xi)


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
        w = _real_array("task_weights", task_weights, "a vector of non-negative weights")
        if w.ndim != 1 or not np.all(np.isfinite(w)) or np.any(w < 0) or not np.any(w > 0):
            raise InputError("task_weights must be a vector of finite non-negative weights, one per "
                             f"task row, not all zero; got {task_weights!r}",
                             argument="task_weights", value=task_weights)
        rows = np.flatnonzero(w > 0)
        sw = np.sqrt(w[rows])
        rows = (rows, w.shape[0])
    if joint_weights is not None:
        w = _real_array("joint_weights", joint_weights, "a vector of positive weights")
        if w.ndim != 1 or not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise InputError("joint_weights must be a vector of finite positive weights, one per "
                             f"joint; got {joint_weights!r}", argument="joint_weights",
                             value=joint_weights)
        isw = 1.0 / np.sqrt(w)
    return rows, sw, isw


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
    #: The contract a controller reads (a solver that is not a `Solver` may set the same
    #: attributes): ``enforces_limits`` — ``solve`` bounds q̇ by the joint position, velocity
    #: and acceleration limits itself (the QP), so the controller does not limit it again;
    #: ``adds_rows`` — it adds constraint rows of its own (e.g. collision avoidance) that may
    #: hold the tool off a straight line, so a servo follows the proportional law ξ = K·e
    #: and lets the solver bend it around them.
    enforces_limits = False
    adds_rows = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        # a subclass whose own ``solve`` adds something (rows of its own) keeps it on the
        # validated entries too: a ``solve_validated`` / ``solve_direction`` inherited from a
        # parent that skips ``solve`` (the QP's) would bypass it, so such a class gets the
        # generic entries
        super().__init_subclass__(**kwargs)
        if "solve" in cls.__dict__ and "solve_validated" not in cls.__dict__:
            cls.solve_validated = Solver.solve_validated  # type: ignore[method-assign]
        if "solve" in cls.__dict__ and "solve_direction" not in cls.__dict__:
            cls.solve_direction = Solver.solve_direction  # type: ignore[method-assign]
        # the joint entry answers as the two it joins: a class that changes either of them
        # (or ``solve``) and not the joint entry gets the generic one, which calls them
        if (any(k in cls.__dict__ for k in ("solve", "solve_direction", "solve_validated"))
                and "solve_direction_twist" not in cls.__dict__):
            cls.solve_direction_twist = Solver.solve_direction_twist  # type: ignore[method-assign]

    def solve_validated(self, J: np.ndarray, xi: np.ndarray, *, limits: Limits | Chain | None,
                        q: np.ndarray | None, qd_prev: np.ndarray | None, dt: float | None,
                        qd_ff: np.ndarray | None = None) -> SolveResult:
        """The controller's entry (`validated_solve`), for inputs the caller has validated:
        J a float64 (m, n) array, ξ (m,), q, q̇_prev and q̇_ff None or finite (n,) arrays, dt
        None or a positive finite float. Returns the correction c of q̇ = q̇_ff + c (c = q̇
        without ``qd_ff``). The default calls `solve`: a solver that ``enforces_limits``
        takes ``qd_ff=`` (its bounds then hold for the total q̇_ff + c); any other resolves
        the correction from the shifted state q + q̇_ff·dt, q̇_prev − q̇_ff. The QP overrides
        it with an entry that skips the checks the caller has made (same answers)."""
        return validated_solve_generic(self, J, xi, limits=limits, q=q, qd_prev=qd_prev, dt=dt,
                                       qd_ff=qd_ff)

    def solve_direction(self, J: np.ndarray, d: np.ndarray, *, q: np.ndarray | None,
                        dt: float | None) -> tuple[np.ndarray, Any, float]:
        """The answer for a direction ``d`` (m,) without limits, for a caller that has
        validated its inputs (as `solve_validated`): ``(w, sigma, damping)`` with w (n,) the
        q̇ per unit of ``d`` (a fresh writable array), ``sigma`` whatever says σ_min(J) — here
        the `SolveResult` (its ``sigma_min`` / ``sigma_min_at_least``); read it through
        `sigma_at_least` — and the damping λ the answer has (0 for an exact one). A motion
        along ``d`` (a jog, the servo's straight line) is w scaled by a progress: the
        damped solvers (the QP, `DLS`, `AdaptiveDLS`) answer exactly wherever J has full
        rank (σ_min above `exact_direction_floor`), so the motion is not turned. The
        default calls `solve`."""
        res = self.solve(J, d, q=q, dt=dt)
        return np.array(res.qd, dtype=float), res, float(res.damping)

    def solve_direction_twist(self, J: np.ndarray, d: np.ndarray, xi: np.ndarray, *,
                              q: np.ndarray | None, dt: float | None) -> DirectionTwist:
        """A direction ``d`` (m,) and a twist ``xi`` (m,) on the same J, both without limits,
        for a caller that has validated its inputs (as `solve_validated`): the answers of
        ``solve_direction(J, d, q=q, dt=dt)`` and of ``solve_validated(J, xi, limits=None,
        q=q, qd_prev=None, dt=dt)``, in that order, as a `DirectionTwist` (a servo's cycle: its
        progress along w = solver(d) plus the feedback c = solver(K·e) it solves on the same
        J). The default calls the two; a solver that shares their work on J (the QP,
        `AdaptiveDLS`) overrides it with the same answers. An error of either is raised."""
        w, sigma, damping = self.solve_direction(J, d, q=q, dt=dt)
        res = self.solve_validated(J, xi, limits=None, q=q, qd_prev=None, dt=dt)
        return DirectionTwist(w, sigma, damping, res.qd, J=J, feedback=res)

    def __init__(self, *, velocity_policy: str | None = "scale", task_weights: ArrayLike | None = None,
                 joint_weights: ArrayLike | None = None) -> None:
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

    def solve(self, J: np.ndarray, xi: np.ndarray, *, limits: Limits | Chain | None = None,
              q: ArrayLike | None = None, qd_prev: ArrayLike | None = None,
              dt: float | None = None) -> SolveResult:
        """Joint velocities q̇ (n,) for the twist ``xi`` (m,) with the Jacobian ``J`` (m, n).

        Args:
            J: Jacobian (m, n), rows [linear; angular] in SI units.
            xi: desired twist (m,) [m/s; rad/s].
            limits: joint limits (a Chain or `Limits`); non-QP solvers use
                ``vmax`` through the velocity-limit policy.
            q, qd_prev, dt: current joint positions, previous joint velocities and the
                step [s]; used by the QP and by `NullSpace` (``q``).
        """
        J, xi, _ = _check_problem(J, xi)
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
        achieved = J.dot(qd)
        err = xi - achieved
        t = sum(qd.tolist()) + sum(err.tolist())
        if t - t != 0.0:
            raise SolverError(f"{self.method}: the solution is not finite (J is too ill-conditioned "
                              "for floating point at this damping)", status="non-finite",
                              problem={"J": J, "xi": xi})
        if limits is None or self.velocity_policy is None:
            return SolveResult(qd=qd, achieved=achieved, task_error=err, damping=damping,
                               sigma_min=sigma, method=self.method, info=info)
        qd, policy, scale, bound, active = self._policy(qd, limits, n)
        if policy == "none":
            return SolveResult(qd=qd, achieved=achieved, task_error=err, damping=damping,
                               sigma_min=sigma, method=self.method, velocity_policy=policy,
                               velocity_scale=scale, bound=bound, limits_active=active, info=info)
        return _make_result(qd, J, xi, damping, sigma, self.method, policy, scale, bound, active,
                            False, info)


def validated_solve_generic(solver: Any, J: np.ndarray, xi: np.ndarray, *, limits: Limits | Chain | None,
                            q: np.ndarray | None, qd_prev: np.ndarray | None, dt: float | None,
                            qd_ff: np.ndarray | None = None) -> SolveResult:
    """`Solver.solve_validated` through ``solver.solve`` (see there), for any solver object."""
    if qd_ff is not None and solver_declares(solver, "enforces_limits"):
        # a limit-enforcing solver bounds the total q̇_ff + correction itself: velocity,
        # position and acceleration limits hold for what is commanded, not only for c
        return solver.solve(J, xi, limits=limits, q=q, qd_prev=qd_prev, dt=dt, qd_ff=qd_ff)
    if qd_ff is not None:  # the solver resolves the correction on top of q̇_ff: shift its inputs
        q = None if q is None else q + qd_ff * dt
        qd_prev = None if qd_prev is None else qd_prev - qd_ff
    return solver.solve(J, xi, limits=limits, q=q, qd_prev=qd_prev, dt=dt)


def thin_svd(J: np.ndarray, *, full: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thin SVD J = U diag(s) Vᵀ: (U (m, k), s (k,) descending, Vᵀ (k, n)), k = min(m, n),
    through LAPACK's dgesdd; with ``full``, the full factors U (m, m) and Vᵀ (n, n) (a null
    space's basis among the rows of Vᵀ). Raises ``np.linalg.LinAlgError`` if it does not
    converge."""
    u, s, vt, info = _dgesdd(J, compute_uv=1, full_matrices=1 if full else 0)
    if info != 0:
        raise np.linalg.LinAlgError(f"SVD did not converge (dgesdd info {info})")
    return u, s, vt


def svd_values(J: np.ndarray) -> np.ndarray:
    """The singular values of J (min(m, n),), descending, without the vectors (dgesdd);
    raises ``np.linalg.LinAlgError`` if it does not converge."""
    _, s, _, info = _dgesdd(J, compute_uv=0)
    if info != 0:
        raise np.linalg.LinAlgError(f"SVD did not converge (dgesdd info {info})")
    return s


def min_norm_direction(J: np.ndarray, d: np.ndarray, col_scale: np.ndarray | None = None, *,
                       gram: np.ndarray | None = None, factor: np.ndarray | None = None) -> np.ndarray | None:
    """The exact direction w with J w = d in the least-squares sense, for J (m, n) of full
    rank: the minimum-norm solution w = S (J S)ᵀ ((J S)(J S)ᵀ)⁻¹ d when m ≤ n (S =
    diag(``col_scale``), the norm ‖S⁻¹w‖; S = I without it), else (JᵀJ)⁻¹Jᵀd. One Cholesky
    solve of the smaller Gram matrix (``gram``: that matrix, J Jᵀ or JᵀJ, when the caller
    has it; without ``col_scale``; ``factor``: its upper Cholesky factor, `dpotrf`'s, when
    the caller has that: the same numbers as the solve of the Gram matrix, which factors it
    just so); None when it is not positive definite or w is not finite (J rank-deficient
    to working precision)."""
    m, n = J.shape
    Js = J if col_scale is None else J * col_scale
    assert (gram is None and factor is None) or col_scale is None, "gram=, factor=: J's own (no col_scale)"
    if m <= n:
        if factor is not None:
            y, info = _dpotrs(factor, d)
        else:
            _, y, info = _dposv(Js.dot(Js.T) if gram is None else gram, d)
        if info != 0:
            return None
        w = y.dot(Js)
        if col_scale is not None:
            w *= col_scale
    else:
        if factor is not None:
            w, info = _dpotrs(factor, d.dot(J))
        else:
            _, w, info = _dposv(J.T.dot(J) if gram is None else gram, d.dot(J))
        if info != 0:
            return None
    t = sum(w.tolist())
    return w if t - t == 0.0 else None


EXACT_DIRECTION_FLOOR = 1e-7  # σ_min/‖J‖_F below which a direction is not solved exactly


def exact_direction_floor(entries: list[float] | None = None, J: np.ndarray | None = None) -> float:
    """The σ_min below which `Solver.solve_direction` no longer answers a direction exactly:
    `EXACT_DIRECTION_FLOOR`·‖J‖_F (J's entries as floats, or J). Above it the Cholesky
    solve of the Gram matrix (condition κ² ≤ 1e14) keeps w accurate to about 1 %, and the
    progress along w, which the joint limits scale by |w| ∝ 1/σ_min, is already below a
    micrometre per second on any arm: the direction is as good as blocked there."""
    if entries is None:
        assert J is not None
        entries = J.ravel().tolist()
    return EXACT_DIRECTION_FLOOR * _hypot(*entries)


def sigma_at_least(sigma: Any, threshold: float) -> tuple[bool, float]:
    """``(σ_min ≥ threshold, σ_min or NaN when it was not needed)`` for the ``sigma`` of
    `Solver.solve_direction`: a lazy σ (decided from its reference where it can,
    `_LazySigma.certainly_at_least`), a solve result (its ``sigma_min_at_least`` where it
    has one, as a `SolveResult` does, else its ``sigma_min``) or a number."""
    if type(sigma) is _LazySigma:
        if sigma.certainly_at_least(threshold):
            return True, math.nan
        v = sigma.value()
    elif hasattr(sigma, "sigma_min"):
        at_least = getattr(sigma, "sigma_min_at_least", None)
        if at_least is not None and at_least(threshold):
            return True, math.nan
        v = float(sigma.sigma_min)
    else:
        v = float(sigma)
    return v >= threshold, v


def sigma_below(sigma: Any, threshold: float) -> float | None:
    """None when σ_min ≥ ``threshold`` for the ``sigma`` of `Solver.solve_direction` (as
    `sigma_at_least`), else a number below the threshold: σ_min, or, when a lazy σ's
    reference decides it without computing σ_min (`_LazySigma.certainly_below`), an upper
    bound of it. For a caller that only compares σ_min with the threshold."""
    if type(sigma) is _LazySigma:
        v = sigma._value
        if v is not None:  # (computed already, or given: `AdaptiveDLS` has it from its schedule)
            return None if v >= threshold else v
        if not sigma.certainly_at_least(threshold):
            upper = sigma.certainly_below(threshold)
            if upper is not None:
                return upper
    above, v = sigma_at_least(sigma, threshold)
    return None if above else v


def solver_declares(solver: Any, name: str) -> bool:
    """The solver contract's flag ``name`` (``"enforces_limits"``, ``"adds_rows"``): a
    `Solver`'s attribute; an object that is not a `Solver` (a wrapper with a ``solve``
    method) may set the same attribute, False when it does not."""
    if isinstance(solver, Solver):
        return bool(getattr(solver, name))
    return bool(getattr(solver, name, False))


def direction_twist_entry(solver: Any):
    """The joint direction-and-twist entry of any solver object (`Solver.solve_direction_twist`):
    a `Solver`'s own, or for an object that is not a `Solver` the same answers through its
    ``solve`` (the direction's result as ``sigma``, the twist's through
    `validated_solve_generic`)."""
    if isinstance(solver, Solver):
        return solver.solve_direction_twist

    def entry(J: np.ndarray, d: np.ndarray, xi: np.ndarray, *, q: np.ndarray | None,
              dt: float | None) -> DirectionTwist:
        w, r, damping = solve_direction_generic(solver, J, d, q=q, dt=dt)
        res = validated_solve_generic(solver, J, xi, limits=None, q=q, qd_prev=None, dt=dt)
        return DirectionTwist(w, r, damping, res.qd, J=J, feedback=res)
    return entry


def solve_direction_generic(solver: Any, J: np.ndarray, d: np.ndarray, *, q: np.ndarray | None,
                            dt: float | None) -> tuple[np.ndarray, Any, float]:
    """`Solver.solve_direction` for a solver object that is not a `Solver`, through its
    ``solve``: (a copy of its q̇, its result, its damping or 0)."""
    res = solver.solve(J, d, q=q, dt=dt)
    return np.array(res.qd, dtype=float), res, float(getattr(res, "damping", 0.0))


def validated_solve(solver: Any):
    """The validated entry of any solver object: a `Solver`'s ``solve_validated``, or the
    generic one through its ``solve`` (`validated_solve_generic`) for an object that is
    not a `Solver` (its attributes may forward elsewhere: its own ``solve`` is the entry)."""
    if isinstance(solver, Solver):
        return solver.solve_validated
    return lambda J, xi, **kw: validated_solve_generic(solver, J, xi, **kw)
