"""What one controller cycle returns: `Command`, and the status vocabulary."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..arrays import read_only
from ..errors import RatectlError
from ..singularity import analyze

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["Command", "STATUSES", "make_command"]

#: Status values, most important first (the status of a cycle is the first that applies;
#: ``Command.flags`` lists all that apply).
STATUSES = (
    "halted",                # safe halt: decelerating to zero (reason in Command.reason)
    "limit-recovery",        # a joint measured inside its stopping distance or beyond a position
                             # limit: braking harder than amax, or moving back into the range
    "target-reached",        # servoing to a target (no feed-forward): within the tolerances and
                             # at rest (the command's tool speed within K·tolerance)
    "target-unreachable",    # servoing to a target: at rest outside the tolerances, a best
                             # effort (no motion within the limits lowers the error from here)
    "halted-singularity",    # jogging or approaching: stopped before a singularity that the
                             # commanded direction runs into (moving away is free at once)
    "collision-avoidance",   # a collision damper row holds the motion back (tasks= / collision=)
    "singular",              # the solver failed or needed more than vmax near a singularity
    "joint-limit",           # a joint position limit clipped q̇
    "approaching-singularity",  # jogging or approaching: slowed along the commanded direction
                                # to stop before a singularity
    "velocity-scaled",       # q̇ was scaled down uniformly to respect vmax
    "damped",                # the solver damped (near a singularity; see Command.kind)
    "acceleration-limited",  # the change of q̇ was scaled to respect amax
    "regular",               # exact tracking, nothing limited
)

_RANK = {name: i for i, name in enumerate(STATUSES)}



@dataclass(frozen=True, eq=False, kw_only=True)
class Command:
    """The result of one controller cycle (frozen; keyword-only construction; its arrays
    are read-only and never shared with the controller's state).

    Attributes:
        qd: commanded joint velocity (n,) [rad/s or m/s].
        q_next: joint positions after one period, q + q̇ dt (or the smoother's exact integral).
        qdd: joint acceleration of the command (n,): (q̇ − q̇_prev)/dt, or the smoother's.
        status: one of `STATUSES`.
        flags: every status that applies this cycle.
        reason: a sentence explaining a non-regular status ("" when regular).
        error: pose error e = [p_d − p; log(R_d Rᵀ)] (6,) (zeros without a target).
        position_error: ‖p_d − p‖ [m].
        orientation_error: ‖log(R_d Rᵀ)‖ [rad].
        twist: the twist ξ = ξ_ff + K e that was resolved (6,).
        sigma_min: σ_min(J) of the unscaled Jacobian (mixed units) at the cycle's q, as reported by
            the solver (NaN if it does not compute it): the same quantity as
            ``rc.analyze(chain, q).sigma_min`` (analyze's report prints the scaled σ_min(J_L)).
        damping: damping λ the solver used (0 = undamped).
        task_error: ξ − J q̇_solver, what the solver gave up (6,).
        velocity_scale: uniform factor applied for vmax (1 = none).
        limits_active: kinds of limit that bound: subset of ("velocity", "acceleration", "position").
        time: controller clock at the start of the cycle [s].
        dt: the period [s].
        solve: the solver's full `SolveResult` (None when halted).
        kind: (lazy) the singularity kind at q from `ratectl.analyze`, computed on first
            access only (it costs an SVD); None when unavailable.
    """

    qd: np.ndarray
    q_next: np.ndarray
    qdd: np.ndarray
    status: str
    flags: tuple[str, ...]
    reason: str
    error: np.ndarray
    position_error: float
    orientation_error: float
    twist: np.ndarray
    sigma_min: float
    damping: float
    task_error: np.ndarray
    velocity_scale: float
    limits_active: tuple[str, ...]
    time: float
    dt: float
    solve: object = None

    def __post_init__(self) -> None:
        for name in _ARRAYS:
            object.__setattr__(self, name, read_only(getattr(self, name)))

    @cached_property
    def kind(self) -> str | None:
        """Singularity kind at the cycle's q ("regular", "wrist", "elbow", "shoulder",
        "boundary", "rank-deficient"), from `ratectl.analyze`; None if unavailable
        (a Command built by hand knows no chain)."""
        d = self.__dict__
        return _kind_of(d.get("_chain"), d.get("_q"))

    @property
    def halted(self) -> bool:
        return self.status == "halted"

    def __str__(self) -> str:
        extra = f" ({self.kind})" if self.status in ("damped", "singular") else ""
        r = f": {self.reason}" if self.reason else ""
        return (f"Command[{self.status}{extra}{r}; |e_p| = {self.position_error * 1e3:.3g} mm, "
                f"|e_R| = {math.degrees(self.orientation_error):.3g}°, σ_min(J) = {self.sigma_min:.3g}, "
                f"λ = {self.damping:.3g}, max|q̇| = {float(np.max(np.abs(self.qd))):.3g}]")


def _sigma_min(self: Command) -> float:
    v = self.__dict__["sigma_min"]
    if not isinstance(v, float):  # the cycle's SolveResult: its σ_min, computed once on first read
        v = self.__dict__["sigma_min"] = float(v.sigma_min)
    return v


def _set_sigma_min(self: Command, value: Any) -> None:  # the dataclass __init__ (and make_command)
    self.__dict__["sigma_min"] = value


# σ_min may be given as the solve result whose (lazily computed) σ_min it is: a control cycle
# that does not need the value does not pay for an eigen-decomposition (the property reads
# the field's value from the instance dictionary, where the dataclass keeps it)
Command.sigma_min = property(_sigma_min, _set_sigma_min,  # type: ignore[assignment]
                             doc="σ_min(J) of the cycle (see the class docstring).")


_ARRAYS = ("qd", "q_next", "qdd", "error", "twist", "task_error")
_OWNED = _ARRAYS[:-1]
_F64 = np.dtype(np.float64)


def make_command(fields: dict[str, Any], chain: Chain | None = None, q: ArrayLike | None = None, *,
                 kind: str | None = None) -> Command:
    """A `Command` from ``fields`` (a dict of its field values that the caller made for it
    and keeps no reference to) and the controller's freshly computed arrays, which it owns
    (``qd``, ``q_next``, ``qdd``, ``error``, ``twist`` are made read-only in place, not
    copied — the controller keeps no reference to them): the fast path of one control
    cycle (the dataclass ``__init__`` costs ~4 µs, a call with the fields as keywords
    ~1 µs). ``sigma_min`` may be the cycle's `SolveResult`: its σ_min is then read on first
    access. ``chain`` and ``q`` (the cycle's configuration) are kept, outside the dataclass
    fields, for the lazy `Command.kind` (or its value, ``kind``, when the cycle named it)."""
    cmd = _new(Command)
    f = fields
    for a in (f["qd"], f["q_next"], f["qdd"], f["error"], f["twist"]):  # _OWNED
        a.setflags(write=False)
    te = f["task_error"]  # the solver's: copied unless read-only
    if type(te) is not np.ndarray or te.flags.writeable or te.dtype != _F64:
        f["task_error"] = read_only(te)
    f["_chain"] = chain
    f["_q"] = q
    if kind is not None:
        f["kind"] = kind  # the cached_property's value
    _set_dict(cmd, "__dict__", f)  # the dict itself: no copy (the frozen class refuses setattr)
    return cmd


_new = object.__new__
_set_dict = object.__setattr__


def _kind_of(chain, q) -> str | None:
    if chain is None or q is None or not np.all(np.isfinite(q)):
        return None
    try:
        return str(analyze(chain, q).kind)
    except RatectlError:  # pragma: no cover - defensive
        return None
