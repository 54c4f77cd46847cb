"""Path-speed governor: time the progress along a path so the joints stay within limits.

A Cartesian path fixes *where* the tool goes; its time law fixes *when*. Near a singular
configuration the joint velocities a fixed time law demands grow without bound
(``q̇ = J⁻¹ξ``), and every inverse-velocity solver then gives something up: the exact
inverse exceeds the limits, a clipping QP or a damped inverse leaves the path. The governor
gives up *time* instead: it keeps the tool on the path and re-times the progress s(t) so that

    q̇ = q′ṡ,    q̈ = q′s̈ + q″ṡ²,    q⃛ = q′s⃛ + 3q″ṡs̈ + q‴ṡ³

stay within ``velocity_margin·vmax``, ``acceleration_margin·amax`` (and, for a jerk-limited
executor, jmax) on every joint, and within the path's own speed, acceleration and jerk
limits (`Governor.progress_jerk_limit`): the governor *replaces* the path's time law by this
progress, and keeps the law's limits.

How (all done once, before the motion — `Governor.plan`):

1. **Joint path** (`joint_path`): q(s) with q′, q″, q‴,
   following exact singularities wherever the path tangent lies in the range of J and q′
   stays bounded (the smooth branch; the crossings are listed with the branch taken), and
   stopping with a specific message only where the path leaves the reachable set or needs
   unbounded joint speed. A path that ends at a singular pose is followed to it. A sharp
   corner of the path (`Path.corners`) is recorded twice, with the incoming and the
   outgoing tangent.
2. **Time-optimal admissible speed** (`reachability_profile`):
   reachability analysis on x = ṡ² as in TOPP-RA — backward controllable sets, greedy
   forward pass — starting and ending at rest, and at rest at every sharp corner.
3. **Progress.** Without a smoother the progress s(t) *is* the time-optimal profile, sampled
   every control period. With a jerk-limited smoother (``check_jerk``) the progress is the
   profile's moving average over a window T that bounds the ``q′s⃛`` term of the joint jerk
   (`_smooth_progress`, `Governor._averaging_window`); the ``3q″ṡs̈`` and ``q‴ṡ³`` terms are
   bounded by step 4, which lowers the speed where they bind. A pointwise speed bound
   ``|q‴_i|ṡ³ ≤ jmax_i`` is not used: it ignores that the terms cancel — on the
   velocity-limit curve next to a singularity q̇_i = q′_iṡ is constant, so the binding
   joint's jerk is zero however large q‴ is — and it made those plans 1.4–1.5× slower than
   the unsmoothed ones where the check alone needs 1.15×. With a jerk limit j of the
   progress the progress is averaged too, over at least the shortest window that keeps
   |s⃛| ≤ j (`_progress_jerk_window`), and the profile's s̈ is capped at √(ṡ_max j). The
   average is taken piece by piece between sharp corners, so the progress rests at each.
4. **Check.** The discrete joint motion the executor will command (secant velocities between
   planned configurations and their differences) is checked against ``check_fraction`` of
   every limit. Where it exceeds one, the margins are lowered *locally* — on the grid points
   within a short window of the violation, by 10 % per round — and steps 2–3 repeat (at most
   ``max_iterations`` times). A plan that still exceeds a limit says so in its message with
   the excess and `GovernorPlan.within_limits` is False; ``follow`` then reports the run
   as not completed. A joint path that crosses a joint *position* limit is reported too.

The executor (`ratectl.follow`) feeds the planned joint velocity forward and closes
the loop on the pose error through the controller, so the tool stays on the path to within
the feedback's accuracy.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from .joint_path import JointPath, joint_path
from .topp import SpeedProfile, reachability_profile

if TYPE_CHECKING:
    from ..model.chain import Chain
    from ..paths.base import Path

__all__ = ['Governor', 'GovernorPlan', 'plan']


# ---------------------------------------------------------------------- plan
@dataclass(frozen=True, kw_only=True)
class GovernorPlan:
    """A governed timing of a path for a control period ``dt``; immutable (read-only arrays).

    Step k (time ``t[k] = k·dt``) has progress ``s[k]``, ``sd[k]``, ``sdd[k]`` and the planned
    joint positions ``q[k]`` (on the joint path, fk(q[k]) = P(s[k])).
    ``qd_ff[k] = (q[k+1] − q[k])/dt`` is the joint velocity that carries the arm from step k
    to step k+1.

    Attributes:
        dt: control period [s]; t, s, sd, sdd: (K,) arrays; q: (K, n); qd_ff: (K, n)
            (the last row is zero).
        joint_path: the `JointPath` of step 1 (with its singularity crossings).
        x_limit: (N,) time-optimal admissible ṡ² on the joint-path grid (after margins).
        nominal_duration: duration of the path's own time law [s].
        duration: duration of the governed motion [s].
        optimal_duration: duration of the reachability profile itself at the margins used [s].
        velocity_ratio, acceleration_ratio, jerk_ratio: the largest |q̇_i|/vmax_i, |q̈_i|/amax_i,
            |q⃛_i|/jmax_i of the planned discrete motion (jerk_ratio NaN unless checked).
        margins: the smallest (velocity, acceleration) fractions used anywhere on the path.
        iterations: planning rounds (step 4).
        complete: the plan reaches the end of the path and its joint path stays inside the
            position limits; within_limits: the planned motion meets every checked limit.
        message: what stopped it or what it exceeds ("" when neither).
        info: read-only mapping with ``iterations``, ``grid_points``, ``jerk_ratio``,
            ``check_fraction``, ``progress_jerk`` (the largest |s⃛| of the planned progress,
            third differences [m/s³]), ``progress_jerk_limit`` (the limit it was planned to,
            or None) and ``averaging_window`` (of a smoothed progress [s], 0 if not smoothed).
    """

    dt: float
    t: np.ndarray
    s: np.ndarray
    sd: np.ndarray
    sdd: np.ndarray
    q: np.ndarray
    qd_ff: np.ndarray
    joint_path: JointPath
    x_limit: np.ndarray
    nominal_duration: float
    duration: float
    optimal_duration: float
    velocity_ratio: float
    acceleration_ratio: float
    jerk_ratio: float
    margins: tuple[float, float]
    iterations: int
    complete: bool
    within_limits: bool = True
    message: str = ""
    info: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))

    def __post_init__(self) -> None:
        for name in ("t", "s", "sd", "sdd", "q", "qd_ff", "x_limit"):
            a = np.array(getattr(self, name), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "info", MappingProxyType(dict(self.info)))

    def __reduce__(self):
        values = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        values["info"] = dict(values["info"])
        return _restore_plan, (values,)

    @property
    def slowdown(self) -> float:
        """duration / nominal duration (≥ 1 when the governor had to slow down)."""
        return self.duration / self.nominal_duration if self.nominal_duration > 0 else 1.0

    def __len__(self) -> int:
        return len(self.t)


def _restore_plan(values) -> GovernorPlan:
    """Unpickle a `GovernorPlan` (its read-only mapping is pickled as a dict)."""
    return GovernorPlan(**values)


@dataclass(frozen=True)
class _Check:
    """Ratios of the planned discrete motion and the path parameters where limits are exceeded."""

    rv: float
    ra: float
    rj: float
    bad_s: np.ndarray


class Governor:
    """Path-speed governor options (see the module docstring for the method).

    Args:
        velocity_margin: plan joint speeds to this fraction of vmax (room for feedback).
        acceleration_margin: plan joint accelerations to this fraction of amax.
        jerk: jerk limit of the progress s⃛ [m/s³] (default: the path's, see
            `progress_jerk_limit`; without one the progress jerk is limited only through the
            joints' jmax, and only with ``check_jerk``).
        max_joint_step: joint-path integration step [rad]; nullspace_gain: joint centring for
            redundant arms [1/m]; sigma_tolerance: ignored (feasibility comes from the
            range-space residual, see `joint_path`).
        check_fraction: accept the plan when the planned discrete motion stays below this
            fraction of every limit; otherwise lower the margins locally (``max_iterations``).
        check_jerk: plan for a jerk-limited smoother: jerk-limited progress and the planned
            joint jerk checked against ``check_fraction·jmax`` as well.
    """

    def __init__(self, *, velocity_margin: float = 0.98, acceleration_margin: float = 0.96,
                 jerk: float | None = None, max_joint_step: float = 0.004,
                 sigma_tolerance: float | None = None, nullspace_gain: float = 1.0,
                 check_fraction: float = 0.99, check_jerk: bool = False, max_iterations: int = 12) -> None:
        for name, v in (("velocity_margin", velocity_margin), ("acceleration_margin", acceleration_margin),
                        ("check_fraction", check_fraction)):
            if not (0.0 < float(v) <= 1.0):
                raise InputError(f"{name} must be in (0, 1], got {v!r}", argument=name, value=v)
        self.velocity_margin = float(velocity_margin)
        self.acceleration_margin = float(acceleration_margin)
        self.jerk = None if jerk is None else float(jerk)
        self.max_joint_step = float(max_joint_step)
        self.sigma_tolerance = sigma_tolerance
        self.nullspace_gain = float(nullspace_gain)
        self.check_fraction = float(check_fraction)
        self.check_jerk = bool(check_jerk)
        self.max_iterations = int(max_iterations)

    def __repr__(self) -> str:
        return (f"Governor(velocity_margin={self.velocity_margin}, "
                f"acceleration_margin={self.acceleration_margin}, check_jerk={self.check_jerk})")

    def plan(self, chain: Chain, path: Path, q0: ArrayLike, *, dt: float) -> GovernorPlan:
        """Plan the governed motion of ``chain`` along ``path`` from ``q0`` with period ``dt`` [s]."""
        dt = float(dt)
        if not (dt > 0.0 and math.isfinite(dt)):
            raise InputError(f"dt must be a positive period [s], got {dt!r}", argument="dt", value=dt)
        path.steps(dt)  # the work is bounded up front: too many steps raise here, not hours later
        if not path.length > 0.0:
            raise InputError("the path has zero length (its start and end poses coincide): there is "
                             "nothing to plan; to hold a pose, step the controller with target=",
                             argument="path", value=path)
        jp = joint_path(chain, path, q0, max_joint_step=self.max_joint_step,
                        nullspace_gain=self.nullspace_gain)
        if len(jp.s) < 2 or (not jp.complete and jp.s[-1] < 1e-6):
            raise InputError(f"the governor cannot plan this path from q0: {jp.message or 'no joint path'}; "
                             "start from a configuration the path can leave (or follow with governor=False, "
                             "which damps through it)", argument="q0", value=q0)
        jp = _trim_singular_end(jp)
        # absent limits (inf) become very large finite ones, so the TOPP rows stay finite
        lim = tuple(np.where(np.isfinite(v), v, big) for v, big in
                    ((chain.vmax, 1e6), (chain.amax, 1e8), (chain.jmax, 1e10)))
        N = len(jp.s)
        mv = np.full(N, self.velocity_margin)
        ma = np.full(N, self.acceleration_margin)
        window = None  # the smoothing window, set in the first round and kept
        for it in range(1, self.max_iterations + 1):
            prof, (s, sd, sdd), window = self._progress(jp, path, lim, mv, ma, dt, window)
            q = jp.interpolate(s)
            chk = _check(q, s, dt, lim, self.check_jerk, spread_steps=int(math.ceil(window / dt)))
            f = self.check_fraction
            if max(chk.rv, chk.ra, chk.rj) <= f or it == self.max_iterations:
                break
            _lower_locally(jp.s, chk.bad_s, mv, ma, speed=chk.rv > f or chk.rj > f,
                           accel=chk.ra > f or chk.rj > f)
        progress = {"progress_jerk": _progress_jerk(s, dt),
                    "progress_jerk_limit": self.progress_jerk_limit(path), "averaging_window": window}
        return _assemble(chain, path, jp, dt, prof, s, sd, sdd, q, chk, (float(mv.min()), float(ma.min())),
                         it, self.check_fraction, progress)

    def progress_jerk_limit(self, path: Path) -> float | None:
        """The limit of |s⃛| the progress is planned to [m/s³], or None: this governor's
        ``jerk`` if given, else the path's: its ``jerk`` or, for the quintic law, the law's
        own largest jerk 60L/T³ (a smooth law asks for a smooth progress; the trapezoid
        asks for none)."""
        if self.jerk is not None:
            return self.jerk
        limits = [j for j in (path.jerk, path.law.max_jerk) if j is not None and math.isfinite(j) and j > 0]
        return min(limits) if limits else None

    def _progress(self, jp: JointPath, path, lim, mv, ma, dt, window: float | None):
        """The speed profile at the current margins, the progress (s, ṡ, s̈) sampled every dt and
        the averaging window of a smoothed progress [s] (0 without smoothing; ``window``
        None: chosen from this profile by `_averaging_window`, then kept).

        The progress is smoothed for a jerk-limited executor (``check_jerk``) and wherever
        the progress itself has a jerk limit (``jerk``, or the path's own ``jerk``): the
        window is then at least the shortest one whose moving average keeps |s⃛| within that
        limit (`_progress_jerk_window`)."""
        vmax, amax, _ = lim
        jerk = self.progress_jerk_limit(path)
        # with a jerk limit j the progress reaches at most s̈ = √(ṡ_max j) on the way to ṡ_max
        acc = path.acceleration if jerk is None else min(path.acceleration, math.sqrt(path.speed * jerk))
        # a margin lowered locally lowers the path's own speed and acceleration there too
        prof = reachability_profile(jp, mv[:, None] * vmax, ma[:, None] * amax,
                                    path.speed * mv / self.velocity_margin,
                                    acc * ma / self.acceleration_margin)
        if not self.check_jerk and not jerk:
            return prof, prof.sample(dt), 0.0
        if window is None:
            window = self._averaging_window(jp, lim, prof, dt=dt) if self.check_jerk else 0.0
        if jerk:
            window = max(window, _progress_jerk_window(prof, jp, dt=dt, jerk=jerk))
        return prof, _smooth_progress(prof, jp, dt=dt, window=window), window

    def _averaging_window(self, jp: JointPath, lim, prof: SpeedProfile, *, dt: float) -> float:
        """Window T [s] of the moving average that makes the progress jerk-limited.

        Averaging s over T turns a jump Δs̈ of the profile's (piecewise constant) s̈ into
        s⃛ = Δs̈/T, so joint i sees the jerk term q′_i Δs̈/T. The largest jump of q′_i s̈ on
        the time-optimal profile is at most twice its peak, so
        T = 2 max_k,i |q′_i(s_k) s̈_k| / jmax_i / ``check_fraction``, but never more than
        2 ``acceleration_margin``·amax_i/jmax_i: near a singularity q′_i s̈ can exceed amax_i
        where q″ṡ² cancels it, and there step 4 bounds what is left. The motion takes
        about T longer than the profile; ``lim`` = (vmax, amax, jmax) per joint."""
        _, amax, jmax = lim
        s, _, sdd = prof.sample(dt)
        dq, _ = jp.derivatives(s)
        peak = 2.0 * float(np.max(np.abs(dq * sdd[:, None]) / jmax))
        window = min(peak, 2.0 * float(np.max(self.acceleration_margin * amax / jmax)))
        return max(window / self.check_fraction, 2.0 * dt)


def _trim_singular_end(jp: JointPath, *, reach: float = 5e-5, qprime: float = 300.0) -> JointPath:
    """End a joint path that runs into a singular pose (|q′| → ∞ at s = L) up to ``reach`` [m]
    before it, where |q′| ≤ ``qprime`` [rad/m]: the last micrometres, where q ~ √(L − s), are
    not resolved by the grid (their interpolated q̈ is noise) and are left to the feedback,
    which settles on the end pose. A joint path that stopped (the path leaves the reachable
    set) is cut back the same way, without the ``reach`` bound: the plan stops short of it."""
    L = float(jp.s[-1])
    big = np.max(np.abs(jp.dq), axis=1) > qprime
    if not big[-1]:
        return jp
    keep = np.flatnonzero(~big | ((L - jp.s > reach) & jp.complete))
    k = int(keep[-1]) + 1 if keep.size else len(jp.s)
    if k >= len(jp.s) - 1 or k < 2:
        return jp
    if not jp.complete:  # stop where the joint speed is still resolved, short of the stop
        keep = np.flatnonzero(~(np.max(np.abs(jp.dq), axis=1) > 0.2 * qprime))
        k = max(int(keep[-1]) + 1 if keep.size else 2, 2)
        return jp.trimmed(k, complete=False, message=jp.message)
    note = (f"the path ends at a singular pose (σ_min = {jp.sigma_min[-1]:.2e}); the plan stops "
            f"{(L - jp.s[k - 1]) * 1e6:.3g} µm before it, where |q′| ≤ {qprime:g} rad/m, and the "
            "feedback settles on the end pose")
    return jp.trimmed(k, complete=True, message=note, singular_end=True)


def _check(q, s, dt, lim, with_jerk: bool, spread_steps: int = 0) -> _Check:
    """Limit ratios of the discrete motion q[k] (secant velocities, their differences)."""
    vmax, amax, jmax = lim
    qd = np.zeros_like(q)
    qd[:-1] = np.diff(q, axis=0) / dt
    qdd = np.diff(qd, axis=0, prepend=np.zeros((1, q.shape[1]))) / dt
    rv_k = np.max(np.abs(qd) / vmax, axis=1)
    ra_k = np.max(np.abs(qdd) / amax, axis=1)
    rj_k = np.zeros(len(s))
    if with_jerk:
        rj_k[1:] = np.max(np.abs(np.diff(qdd, axis=0)) / dt / jmax, axis=1)
    worst = np.maximum(np.maximum(rv_k, ra_k), rj_k)
    bad = np.flatnonzero(worst > 0.99)
    # a smoothed progress at step k depends on the profile over the averaging window before it
    spread = np.arange(-spread_steps - 1, 2)
    near = np.clip((bad[:, None] + spread[None, :]).ravel(), 0, len(s) - 1)
    return _Check(rv=float(rv_k.max()), ra=float(ra_k.max()), rj=float(rj_k.max()) if with_jerk else math.nan,
                  bad_s=s[np.unique(near)])


def _lower_locally(grid, bad_s, mv, ma, *, speed: bool, accel: bool, factor: float = 0.9) -> None:
    """Lower the margins by ``factor`` on the grid points next to the offending path parameters."""
    if bad_s.size == 0:
        return
    k = np.unique(np.clip(np.searchsorted(grid, bad_s), 0, len(grid) - 1))
    idx = np.unique(np.clip(np.concatenate([k + d for d in range(-3, 4)]), 0, len(grid) - 1))
    if speed:
        mv[idx] *= factor
    if accel:
        ma[idx] *= factor


def _assemble(chain, path, jp, dt, prof: SpeedProfile, s, sd, sdd, q, chk: _Check, margins, iterations,
              fraction, progress) -> GovernorPlan:
    """The `GovernorPlan` with its messages."""
    qd = np.zeros_like(q)
    qd[:-1] = np.diff(q, axis=0) / dt
    t = np.arange(len(s)) * dt
    complete, notes = jp.complete, [jp.message] if jp.message else []
    outside = (jp.q < chain.lower) | (jp.q > chain.upper)
    if np.any(outside):
        k, j = np.argwhere(outside)[0]
        complete = False
        notes.append(f"the joint path crosses the position limit of joint {j} ({chain.joint_names[j]}) at "
                     f"s = {jp.s[k]:.4g} m (re-timing cannot avoid it; the controller will hold the limit)")
    within = chk.rv <= 1.0 and chk.ra <= 1.0 and not (chk.rj > 1.0)
    if not within:
        jerk = "" if math.isnan(chk.rj) else f", |q⃛|/jmax = {chk.rj:.3f}"
        notes.append(f"the planned motion exceeds the limits after {iterations} rounds (|q̇|/vmax = "
                     f"{chk.rv:.3f}, |q̈|/amax = {chk.ra:.3f}{jerk})")
    info = {"iterations": iterations, "grid_points": len(jp.s),
            "jerk_ratio": None if math.isnan(chk.rj) else chk.rj, "check_fraction": fraction, **progress}
    return GovernorPlan(dt=dt, t=t, s=s, sd=sd, sdd=sdd, q=q, qd_ff=qd, joint_path=jp, x_limit=prof.x,
                        nominal_duration=path.duration, duration=float(t[-1]),
                        optimal_duration=prof.duration, velocity_ratio=chk.rv, acceleration_ratio=chk.ra,
                        jerk_ratio=chk.rj, margins=margins, iterations=iterations, complete=complete,
                        within_limits=within, message="; ".join(notes), info=info)


def _pieces(prof: SpeedProfile, jp: JointPath, dt: float):
    """The progress sampled every dt piece by piece between the corners of the path (where the
    profile is at rest): a list of s arrays, each from rest to rest, its first sample at
    the piece's start and its last at the piece's end (the last interval ≤ dt)."""
    inner = np.unique(prof.t[jp.rest_points]) if len(jp.rest_points) else np.zeros(0)
    bounds = np.concatenate([[0.0], inner[(inner > 0.0) & (inner < prof.duration)], [prof.duration]])
    out = []
    for ta, tb in zip(bounds[:-1], bounds[1:], strict=True):
        M = int(math.ceil((tb - ta) / dt - 1e-9))
        s = prof.at(np.minimum(ta + np.arange(M + 1) * dt, tb))[0]
        out.append(s)
    out[-1][-1] = prof.s[-1]
    return out


def _smooth_progress(prof: SpeedProfile, jp: JointPath, *, dt: float, window: float):
    """Jerk-limited progress: the time-optimal s(t) averaged over a moving window of T seconds.

    The profile's s̈ is piecewise constant; the moving average s_T(t) = (1/T)∫_{t−T}^{t} s dτ has a
    continuous s̈ and s⃛ = (s̈(t) − s̈(t − T))/T. Where the joint accelerations q′s̈ stay within
    amax, the q′s⃛ term of the joint jerk is then within 2 amax/T, so T = 2 amax/jmax (the
    default ``window``) bounds it; the motion takes T longer and still starts and ends at rest.
    The other terms (3q″ṡs̈, q‴ṡ³) are left to the speed profile and the check. The average
    is taken piece by piece between the corners of the path (`_pieces`), so the smoothed
    progress comes to rest at each corner too (an average across one would not stop there)."""
    W = max(int(math.ceil(window / dt)), 2)
    parts = []
    for i, s in enumerate(_pieces(prof, jp, dt)):
        padded = np.concatenate([np.full(W - 1, s[0]), s, np.full(W - 1, s[-1])])
        c = np.concatenate([[0.0], np.cumsum(padded)])
        sf = (c[W:] - c[:-W]) / W
        sf[0], sf[-1] = s[0], s[-1]
        parts.append(sf if i == 0 else sf[1:])
    sf = np.concatenate(parts)
    sd = np.gradient(sf, dt)
    sdd = np.gradient(sd, dt)
    sd[0] = sd[-1] = sdd[0] = sdd[-1] = 0.0
    return sf, sd, sdd


def _progress_jerk(s: np.ndarray, dt: float) -> float:
    """Largest |s⃛| of a progress sampled every dt: its third differences [m/s³]."""
    return float(np.max(np.abs(np.diff(s, 3)))) / dt**3 if len(s) > 3 else 0.0


def _progress_jerk_window(prof: SpeedProfile, jp: JointPath, *, dt: float, jerk: float) -> float:
    """The shortest averaging window T [s] (`_smooth_progress`) whose progress has |s⃛| ≤ ``jerk``.

    A window T turns the profile's jumps of s̈ into s⃛ = Δs̈/T. On a trapezoid the jumps are
    s̈_max each and T = s̈_max/jerk gives exactly the jerk-limited (S-curve) law of the same
    speed and acceleration; a jump from +s̈_max to −s̈_max (no cruise) needs up to twice
    that. Windows between the two are tried — the first four periods, then steps of about
    5 % — and the first whose sampled progress meets the limit is taken (2 s̈_max/jerk
    always does)."""
    umax = float(np.max(np.abs(prof.u))) if len(prof.u) else 0.0
    if umax <= 0.0:
        return 0.0
    w0 = max(int(math.ceil(umax / (jerk * dt))), 2)
    w1 = max(int(math.ceil(2.0 * umax / (jerk * dt))), w0)
    # the first few periods above the lower bound (sampling moves the profile's kinks by < dt),
    # then steps of about 5 %
    candidates = np.concatenate([w0 + np.arange(4), np.round(np.geomspace(w0, w1, 16))]).astype(int)
    for W in np.unique(candidates[candidates <= w1]):
        if _progress_jerk(_smooth_progress(prof, jp, dt=dt, window=W * dt)[0], dt) <= jerk * (1 + 1e-9):
            return float(W * dt)
    return float(w1 * dt)


def plan(chain: Chain, path: Path, q0: ArrayLike, *, dt: float, **options: Any) -> GovernorPlan:
    """Shorthand for ``Governor(**options).plan(chain, path, q0, dt=dt)``."""
    return Governor(**options).plan(chain, path, q0, dt=dt)
