"""Path-speed governor: slow the progress along a path so the joints stay within limits.

A Cartesian path fixes *where* the tool goes; its time law fixes *when*. Near a
singular configuration the joint velocities a fixed time law demands grow without
bound (``q̇ = J⁻¹ξ``), and every inverse-velocity solver then gives something up:
the exact inverse exceeds the limits, a clipping QP or a damped inverse leaves the
path. The governor gives up *time* instead: it keeps the tool on the path and
re-times the progress s(t) so that

    q̇ = q'(s) ṡ,    q̈ = q'(s) s̈ + q''(s) ṡ²

stay within ``velocity_margin·vmax`` and ``acceleration_margin·amax`` on every joint
(``q' = dq/ds``, ``q'' = d²q/ds²`` along the joint path), and within the path's own
speed and acceleration limits.

How (all done once, before the motion — `plan`):

1. **Joint path.** Integrate ``dq/ds = J⁺(q) dP/ds`` from q0 with steps small enough
   that no joint moves more than ``max_joint_step`` [rad], correcting every step by
   Newton iterations ``q ← q + J⁺ e`` onto the exact pose P(s) (e = pose error). For a
   redundant arm the null-space term ``(I − J⁺J) z`` with z = −k W (q − q_mid) keeps the
   joints away from their limits. q'(s) comes from the same formula, q''(s) from
   differences of q'. The integration stops at a configuration where σ_min(J) falls
   below ``sigma_tolerance`` (a workspace boundary): the plan then ends there and
   says so.
2. **Admissible speed** (TOPP by numerical integration on x = ṡ²). The velocity
   limits give ``x ≤ (v_i/|q'_i|)²``; the acceleration limits
   ``−a_i ≤ q'_i u + q''_i x ≤ a_i`` (u = s̈) bound u for each x and, where they cannot
   all hold, bound x itself. A forward pass (accelerate as much as allowed) and a
   backward pass (decelerate in time for every dip) give the fastest feasible x(s).
3. **Jerk-limited progress.** A 1-D Ruckig trajectory generator advances s every
   control period with |s̈| ≤ path acceleration and |s⃛| ≤ path jerk: its velocity
   interface follows, as target speed, the smallest admissible ṡ over a look-ahead
   window ahead of s, and near the end its position interface brings s to the end at
   rest. So the progress variable is jerk-limited, and it slows *before* the singular
   neighbourhood.
4. **Check.** The discrete joint motion the executor will command (secant velocities
   between planned configurations and their differences) is checked against the
   limits; if any exceeds ``check_fraction`` of a limit, the margins shrink by 15 %
   (and, for an acceleration excess, the progress acceleration by 40 %: q̈ contains
   q's̈, which only a smaller s̈ reduces where |q'| is large) and steps 2–3 are repeated
   (at most ``max_iterations`` times). A joint path that ends at a singularity is
   trimmed back to where σ_min ≥ 3·``sigma_tolerance`` (closer, q' ~ 1/σ makes the
   timing meaningless). With
   ``check_jerk`` (used when a jerk-limited smoother executes the plan) the planned
   joint jerk is checked against jmax as well, halving the progress jerk until it fits.
   A joint path that crosses a joint *position* limit is reported in the plan's message
   (re-timing cannot avoid it).

The executor (`ratectl.follow`) then feeds the planned joint velocity forward
and closes the loop on the pose error through the controller, so the tool stays on
the path to within the feedback's accuracy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .joint_path import JointPath, joint_path
from .topp import _topp

__all__ = ['Governor', 'GovernorPlan', 'plan']


# ---------------------------------------------------------------------- plan
@dataclass(frozen=True)
class GovernorPlan:
    """A governed, jerk-limited timing of a path for a control period ``dt``.

    Step k (time ``t[k] = k·dt``) has progress ``s[k]``, ``sd[k]``, ``sdd[k]`` and the
    planned joint positions ``q[k]`` (on the joint path, fk(q[k]) = P(s[k])).
    ``qd_ff[k] = (q[k+1] − q[k])/dt`` is the joint velocity that carries the arm from
    step k to step k+1.

    Attributes:
        dt: control period [s].
        t: (K,) times [s].
        s: (K,) path parameter [m].
        sd: (K,) ṡ [m/s].
        sdd: (K,) s̈ [m/s²].
        q: (K, n) planned joint positions.
        qd_ff: (K, n) feed-forward joint velocities (the last row is zero).
        joint_path: the `JointPath` of step 1.
        x_limit: (N,) admissible ṡ² on the joint-path grid (after margins).
        nominal_duration: duration of the path's own time law [s].
        duration: duration of the governed motion [s].
        velocity_ratio: the largest |q̇_i|/vmax_i of the planned discrete motion.
        acceleration_ratio: the largest |q̈_i|/amax_i of the planned discrete motion.
        margins: (velocity, acceleration) fractions finally used.
        complete: the plan reaches the end of the path.
        message: why not, if not.
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
    velocity_ratio: float
    acceleration_ratio: float
    margins: tuple[float, float]
    complete: bool
    message: str = ""
    info: dict = field(default_factory=dict)

    @property
    def slowdown(self) -> float:
        """duration / nominal duration (≥ 1 when the governor had to slow down)."""
        return self.duration / self.nominal_duration if self.nominal_duration > 0 else 1.0

    def __len__(self) -> int:
        return len(self.t)


class Governor:
    """Path-speed governor options (see the module docstring for the method).

    Args:
        velocity_margin: plan joint speeds to this fraction of vmax (room for feedback).
        acceleration_margin: plan joint accelerations to this fraction of amax.
        jerk: jerk limit of the progress s⃛ [m/s³] (default: the path's jerk, else
            20 × its acceleration).
        lookahead: extra look-ahead time for the velocity cap [s] (default: 2 a/j, the
            time the jerk-limited progress needs to change its acceleration).
        max_joint_step: joint-path integration step [rad].
        sigma_tolerance: see `joint_path`.
        nullspace_gain: joint centring for redundant arms [1/m].
        check_fraction: accept the plan when the planned discrete motion stays below this
            fraction of every limit; otherwise shrink the margins (``max_iterations``).
        check_jerk: also require the planned joint jerk to stay below ``check_fraction·jmax``
            (shrinking the acceleration margin until it does) — used when a jerk-limited
            smoother executes the plan, so that it can track it without lag.
    """

    def __init__(self, *, velocity_margin: float = 0.9, acceleration_margin: float = 0.8,
                 jerk: float | None = None, lookahead: float | None = None, max_joint_step: float = 0.004,
                 sigma_tolerance: float = 1e-3, nullspace_gain: float = 1.0, check_fraction: float = 0.95,
                 check_jerk: bool = False, max_iterations: int = 8) -> None:
        for name, v in (("velocity_margin", velocity_margin), ("acceleration_margin", acceleration_margin),
                        ("check_fraction", check_fraction)):
            if not (0.0 < float(v) <= 1.0):
                raise InputError(f"{name} must be in (0, 1], got {v!r}", argument=name, value=v)
        self.velocity_margin = float(velocity_margin)
        self.acceleration_margin = float(acceleration_margin)
        self.jerk = None if jerk is None else float(jerk)
        self.lookahead = lookahead
        self.max_joint_step = float(max_joint_step)
        self.sigma_tolerance = float(sigma_tolerance)
        self.nullspace_gain = float(nullspace_gain)
        self.check_fraction = float(check_fraction)
        self.check_jerk = bool(check_jerk)
        self.max_iterations = int(max_iterations)

    def __repr__(self) -> str:
        return (f"Governor(velocity_margin={self.velocity_margin}, "
                f"acceleration_margin={self.acceleration_margin})")

    def plan(self, chain, path, q0, *, dt: float) -> GovernorPlan:
        """Plan the governed motion of ``chain`` along ``path`` from ``q0`` with period ``dt`` [s]."""
        dt = float(dt)
        if not (dt > 0.0 and math.isfinite(dt)):
            raise InputError(f"dt must be a positive period [s], got {dt!r}", argument="dt", value=dt)
        jp = joint_path(chain, path, q0, max_joint_step=self.max_joint_step,
                        sigma_tolerance=self.sigma_tolerance, nullspace_gain=self.nullspace_gain)
        if len(jp.s) < 2:
            raise InputError(f"the governor cannot plan this path from q0: {jp.message or 'no joint path'}; "
                             "start from a regular configuration (or follow with governor=False, "
                             "which damps through it)", argument="q0", value=q0)
        if not jp.complete:
            jp = _trim_singular_end(jp, 3.0 * self.sigma_tolerance)
        # absent limits (inf) become very large finite ones, so the TOPP rows stay finite
        vmax = np.where(np.isfinite(chain.vmax), chain.vmax, 1e6)
        amax = np.where(np.isfinite(chain.amax), chain.amax, 1e8)
        jmax = np.where(np.isfinite(chain.jmax), chain.jmax, 1e10)
        jerk = self.jerk or path.jerk or 20.0 * path.acceleration
        vm, am = self.velocity_margin, self.acceleration_margin
        acc = path.acceleration
        best = None
        for it in range(self.max_iterations):
            x, mvc = _topp(jp, vm * vmax, am * amax, path.speed, acc)
            s, sd, sdd = _track(jp, x, dt=dt, acc=acc, jerk=jerk, lookahead=self.lookahead)
            q = jp.interpolate(s)
            qd = np.zeros_like(q)
            qd[:-1] = np.diff(q, axis=0) / dt
            qdd = np.diff(qd, axis=0, prepend=np.zeros((1, q.shape[1]))) / dt
            with np.errstate(invalid="ignore"):
                rv = float(np.max(np.abs(qd) / vmax))
                ra = float(np.max(np.abs(qdd) / amax))
                rj = float(np.max(np.abs(np.diff(qdd, axis=0)) / dt / jmax)) if self.check_jerk else 0.0
            best = (x, s, sd, sdd, q, qd, rv, ra, (vm, am), it + 1, jerk, rj, acc)
            if rv <= self.check_fraction and ra <= self.check_fraction and rj <= self.check_fraction:
                break
            if rv > self.check_fraction:
                vm *= 0.85
            if ra > self.check_fraction:
                am *= 0.85
                # q̈ = q' s̈ + q'' ṡ²: where |q'| is large (near a singularity) the progress
                # acceleration itself must come down, not only the speed
                acc *= 0.6
            if rj > self.check_fraction:
                jerk *= 0.5
        x, s, sd, sdd, q, qd, rv, ra, margins, iters, jerk, rj, acc = best
        t = np.arange(len(s)) * dt
        complete = jp.complete
        message = jp.message
        outside = (jp.q < chain.lower) | (jp.q > chain.upper)
        if np.any(outside):
            k, j = np.argwhere(outside)[0]
            complete = False
            message = (message + "; " if message else "") + (
                f"the joint path crosses the position limit of joint {j} ({chain.joint_names[j]}) at "
                f"s = {jp.s[k]:.4g} m "
                "(re-timing cannot avoid it; the controller will hold the limit)")
        if rv > 1.0 or ra > 1.0:
            message = (message + "; " if message else "") + (
                f"planned motion exceeds the limits (|q̇|/vmax = {rv:.3f}, |q̈|/amax = {ra:.3f})")
        return GovernorPlan(dt=dt, t=t, s=s, sd=sd, sdd=sdd, q=q, qd_ff=qd, joint_path=jp, x_limit=x,
                            nominal_duration=path.duration, duration=float(t[-1]), velocity_ratio=rv,
                            acceleration_ratio=ra, margins=margins, complete=complete, message=message,
                            info={"iterations": iters, "jerk": jerk, "acceleration": acc,
                                  "grid_points": len(jp.s),
                                  "jerk_ratio": rj if self.check_jerk else None})


def _trim_singular_end(jp: JointPath, sigma: float) -> JointPath:
    """Drop the end of a joint path that stopped at a singularity where σ_min < ``sigma``:
    there q' ~ 1/σ grows without bound, the interpolated joint motion is dominated by
    its own rounding, and a plan cannot approach it usefully anyway (it ends there)."""
    keep = np.flatnonzero(jp.sigma_min >= sigma)
    if keep.size < 2 or keep[-1] == len(jp.s) - 1:
        return jp
    k = int(keep[-1]) + 1
    return JointPath(jp.s[:k], jp.q[:k], jp.dq[:k], jp.ddq[:k], jp.sigma_min[:k], jp.complete,
                     jp.message)


def _track(jp: JointPath, x, *, dt, acc, jerk, lookahead):
    """Jerk-limited progress with 1-D Ruckig, |s̈| ≤ acc, |s⃛| ≤ jerk. Away from the end the
    velocity interface follows a target speed — the smallest admissible ṡ over a look-ahead
    window ahead of s, so the progress slows before every dip of the admissible speed;
    near the end the position interface brings s to the end of the joint path at rest
    (its velocity limit still capped the same way)."""
    import ruckig

    S = jp.s
    end = float(S[-1])
    sdmax = np.sqrt(np.maximum(x, 0.0))
    T_look = lookahead if lookahead is not None else 2.0 * acc / jerk
    otg = ruckig.Ruckig(1, dt)
    inp = ruckig.InputParameter(1)
    out = ruckig.OutputParameter(1)
    inp.control_interface = ruckig.ControlInterface.Velocity
    inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [0.0], [0.0]
    inp.target_position, inp.target_velocity, inp.target_acceleration = [end], [0.0], [0.0]
    inp.max_acceleration, inp.max_jerk = [acc], [jerk]
    vfloor = 1e-7
    s_list, sd_list, sdd_list = [0.0], [0.0], [0.0]
    s, sd, sdd = 0.0, 0.0, 0.0
    final = False
    max_time = 3600.0  # [s] a governed motion slower than this is a stuck profile, not a plan
    for _ in range(int(max_time / dt)):
        window = sd * (T_look + dt) + 0.5 * max(sdd, 0.0) * T_look**2 + 1e-9
        i0 = max(int(np.searchsorted(S, s, side="right")) - 1, 0)
        i1 = int(np.searchsorted(S, s + window, side="right"))
        # min of the (piecewise-linear) admissible speed over [s, s + window]
        cap = min(float(np.interp(s, S, sdmax)), float(np.interp(min(s + window, end), S, sdmax)))
        if i1 > i0 + 1:
            cap = min(cap, float(np.min(sdmax[i0 + 1:i1])))
        cap = max(cap, vfloor)
        if not final:
            brake = sd * sd / (2.0 * acc) + sd * (acc / jerk + 2.0 * dt) + 0.5 * abs(sdd) ** 3 / (acc * jerk)
            if end - s <= 1.5 * brake + 1e-9:
                final = True
                inp.control_interface = ruckig.ControlInterface.Position
                inp.target_velocity = [0.0]
        if final:
            inp.max_velocity = [cap]
        else:
            inp.target_velocity = [cap]
        res = otg.update(inp, out)
        if res not in (ruckig.Result.Working, ruckig.Result.Finished):
            raise InputError(f"the progress generator failed (Ruckig {res}); check the path limits",
                             argument="path", value=None)
        out.pass_to_input(inp)
        s = min(float(out.new_position[0]), end)
        sd = float(out.new_velocity[0])
        sdd = float(out.new_acceleration[0])
        s_list.append(s)
        sd_list.append(sd)
        sdd_list.append(sdd)
        if final and (res == ruckig.Result.Finished or (end - s < 1e-9 and abs(sd) < 1e-6)):
            break  # at the end and at rest (1 nm, 1 µm/s)
    else:
        raise InputError(f"the governed progress did not reach the end of the path within {max_time:.0f} s "
                         f"(at s = {s:.4g} of {end:.4g} m, ṡ = {sd:.3g} m/s): the admissible speed there "
                         "is too small to plan; shorten the path before the singularity or raise the limits",
                         argument="path", value=None)
    s_arr = np.array(s_list)
    s_arr[-1] = end
    sd_arr = np.array(sd_list)
    sd_arr[-1] = 0.0
    sdd_arr = np.array(sdd_list)
    sdd_arr[-1] = 0.0
    return s_arr, sd_arr, sdd_arr


def plan(chain, path, q0, *, dt: float, **options) -> GovernorPlan:
    """Shorthand for ``Governor(**options).plan(chain, path, q0, dt=dt)``."""
    return Governor(**options).plan(chain, path, q0, dt=dt)
