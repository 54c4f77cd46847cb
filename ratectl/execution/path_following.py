"""Run a resolved-rate controller along a Cartesian path: `follow`.

Two modes:

* ``governor=True`` (default): the path-speed governor (`ratectl.planning.governor`)
  plans the joint path and a jerk-limited, limit-respecting progress s(t); each
  cycle the controller gets the planned joint velocity as feed-forward (``qd_ff``)
  and the path pose P(s_k) as target, so feedback corrects any drift. The motion
  takes as long as the limits require and stays on the path; it comes to rest at every
  sharp corner of the path. The path's own time law is replaced, its speed,
  acceleration and jerk limits kept (the message says so).
* ``governor=False``: the path's own time law drives the controller with
  ``target = P(s(t))`` and ``twist = dP/ds·ṡ(t)``; near singularities the solver
  (and the controller's limits) decide what gives — typically the path error.

After the schedule ends the controller keeps the end pose as target for at most
``settle`` seconds, until the pose is within ``tolerance``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..checks import positive_number
from ..control import ResolvedRateController, move
from ..errors import InputError
from ..paths import Path
from ..planning import Governor, ik
from ..spatial import pose_error, rotation_angle
from .record import Execution
from .reference import PathReference

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["follow"]


def follow(chain: Chain, path: Path, q0: ArrayLike, *, dt: float,
           controller: ResolvedRateController | None = None, governor: Governor | bool | None = True,
           settle: float = 0.5, tolerance: tuple[float, float] = (1e-4, 1.75e-4),
           path_tolerance: tuple[float, float] = (5e-5, 1.75e-4), approach: bool = True,
           record_kinds: bool = True) -> Execution:
    """Follow ``path`` with ``chain`` from joint positions ``q0``; returns an `Execution`.

    Args:
        chain: the arm.
        path: a `ratectl.paths.Path`.
        q0: (n,) start configuration.
        dt: control period [s].
        controller: a `ResolvedRateController` (default: a new one with
            the default solver, the chain's limits and no smoothing). It is reset first.
        governor: True (default options), False (the path's time law), or a
            `Governor` with custom options.
        settle: time allowed after the schedule to converge on the end pose [s].
        tolerance: (position [m], orientation [rad]) for "completed" at the end pose.
        path_tolerance: (position [m], orientation [rad]) the governed run must stay within
            along the whole path; a governed run that leaves the path by more is reported as
            not completed, with the departure (a time-law run trades path error for time by
            design and is not checked). The distance from the path is measured near the s the
            step commanded (see `Execution.position_error`), so a path that revisits a
            position is measured against the visit the tool is on.
        approach: if fk(q0) is not at the path start, first solve IK for the start pose and move
            there with a jerk-limited joint move (recorded in ``info["approach"]``); if False,
            such a q0 is an error.
        record_kinds: ask `ratectl.analyze` for the singularity kind on steps whose status
            is "damped" or "singular" (evaluated every 20 ms within such a stretch, carried
            over in between).

    Returns:
        An `Execution`. Its ``duration`` ends where the tool arrives within ``tolerance`` of
        the end pose for good, and ``nominal_duration`` is the time at which the path's own
        law, sampled every dt, arrives within the same tolerance (like for like;
        ``info["law_duration"]`` is the law's full duration). ``info`` also holds
        ``end_position_error`` [m] and ``end_orientation_error`` [rad] — the final pose's
        distance from the path's *end pose*, always — and, when the governor's plan stops
        short of the end, ``stop_s`` [m], ``stop_position_error`` [m] and
        ``stop_orientation_error`` [rad] (the final pose against the pose where it stopped);
        ``plan`` (the `GovernorPlan`), ``approach``, ``solver``, ``smoothing``, ``governor``.
    """
    dt, q, ctrl = _validate(chain, path, q0, dt, controller)
    settle, tolerance, path_tolerance = _options(governor, settle, tolerance, path_tolerance)
    ctrl.reset()
    info: dict = {"solver": type(ctrl.solver).__name__, "smoothing": ctrl.filter is not None}
    # --- reach the start of the path
    e0 = pose_error(path.start, chain.fk(q))
    if np.linalg.norm(e0[:3]) > 1e-6 or np.linalg.norm(e0[3:]) > 1e-5:
        if not approach:
            raise InputError("q0 is not at the start of the path (fk(q0) is "
                             f"{np.linalg.norm(e0[:3]) * 1e3:.3g} mm / "
                             f"{math.degrees(np.linalg.norm(e0[3:])):.3g}° "
                             "away); pass approach=True", argument="q0", value=q0)
        info["approach"] = _approach(chain, path, q, dt)
        q = info["approach"].q[-1].copy()
    plan, gov = None, None
    if governor is not False and governor is not None:
        gov = governor if isinstance(governor, Governor) else Governor(check_jerk=ctrl.filter is not None)
        plan = gov.plan(chain, path, q, dt=dt)
        info["plan"] = plan
    ref = PathReference(path, plan)
    T_end = ref.end_pose  # the path end, or where the governor had to stop
    rec = _run(chain, ref, q, ctrl, T_end, dt=dt, settle=settle, tolerance=tolerance,
               record_kinds=record_kinds)
    return _evaluate(chain, path, rec, plan, gov, T_end, info, dt=dt, settle=settle, tolerance=tolerance,
                     path_tolerance=path_tolerance)


def _validate(chain, path, q0, dt, controller):
    """Checked (dt, q0 copy, controller) or InputError."""
    if not isinstance(path, Path):
        raise InputError(f"path must be a ratectl.paths.Path, got {type(path).__name__}", argument="path",
                         value=path)
    dt = positive_number("dt", dt, unit="[s]")
    path.steps(dt)  # the nominal schedule is bounded up front (a clear error for dt = 1e-9)
    q = chain.check_q(q0).astype(float).copy()
    if q.shape != (chain.dof,):
        raise InputError(f"q0 must be one configuration ({chain.dof},), got {q.shape}", argument="q0",
                         value=q0)
    outside = np.flatnonzero((q < chain.lower) | (q > chain.upper))
    if outside.size:
        names = chain.joint_names
        detail = "; ".join(f"joint {names[i]!r}: q = {q[i]:.6g}, limits "
                           f"[{chain.lower[i]:.6g}, {chain.upper[i]:.6g}]" for i in outside)
        raise InputError(f"q0 is outside the joint position limits ({detail}); start inside the "
                         "range", argument="q0", value=q0)
    # (a path is the constraint: where its end is blocked, the default controller stops there
    # rather than leave the path for an alternative in joint space)
    ctrl = controller if controller is not None else ResolvedRateController(chain, blocked="stop")
    if not isinstance(ctrl, ResolvedRateController):
        raise InputError(f"controller must be a ratectl.ResolvedRateController, got "
                         f"{type(controller).__name__}", argument="controller", value=controller)
    if not _same_kinematics(ctrl.chain, chain, q):
        raise InputError(f"the controller was built for another arm ({ctrl.chain.name!r}, "
                         f"{ctrl.chain.dof} joints) than the one given ({chain.name!r}, {chain.dof} "
                         "joints): their forward kinematics differ", argument="controller",
                         value=controller)
    return dt, q, ctrl


def _same_kinematics(a: Chain, b: Chain, q: np.ndarray) -> bool:
    """True if chains ``a`` and ``b`` are the same arm: the same object, or the same number of
    joints and the same tool pose (to 1e-12) at q and at two seeded random configurations
    (two calls of ``rc.robots.ur5e()`` are the same arm)."""
    if a is b:
        return True
    if a.dof != b.dof:
        return False
    qs = np.vstack([q, b.random_q(2, rng=np.random.default_rng(0))])
    return bool(np.allclose(a.fk(qs), b.fk(qs), rtol=0.0, atol=1e-12))


def _options(governor, settle, tolerance, path_tolerance):
    """Checked (settle, tolerance, path_tolerance) or InputError; ``governor`` must be
    True, False, None or a `Governor`."""
    if not (governor is None or isinstance(governor, bool | Governor)):
        raise InputError(f"governor must be True, False or a ratectl.planning.Governor, got {governor!r}",
                         argument="governor", value=governor)
    settle = positive_number("settle", settle, allow_zero=True, unit="[s]")
    pairs = []
    for name, value in (("tolerance", tolerance), ("path_tolerance", path_tolerance)):
        try:
            p, o = value
        except (TypeError, ValueError):
            raise InputError(f"{name} must be a pair (position [m], orientation [rad]), got {value!r}",
                             argument=name, value=value) from None
        pairs.append((positive_number(f"{name}[0] (position)", p, unit="[m]"),
                      positive_number(f"{name}[1] (orientation)", o, unit="[rad]")))
    return settle, pairs[0], pairs[1]


def _command(ctrl, ref: PathReference, q, dt):
    """The controller command at the reference's schedule time: the plan's feed-forward and
    pose, or the path's time law (`PathReference.at`)."""
    r = ref.at(dt, smoothed=ctrl.filter is not None)
    return r.s, ctrl.step(q, target=r.pose, twist=r.twist, qd_ff=r.qd_ff, qdd_ff=r.qdd_ff, dt=dt)


def _run(chain, ref: PathReference, q, ctrl, T_end, *, dt, settle, tolerance, record_kinds):
    """The control loop: the schedule, then up to ``settle`` seconds on the end pose."""
    path, plan = ref.path, ref.plan
    n_sched = len(plan) if plan is not None else int(math.ceil(path.duration / dt - 1e-9)) + 1
    n_settle = int(math.ceil(settle / dt))
    Q, QD, QDD, ST, RS, S, KINDS = [], [], [], [], [], [], []
    pos_tol, ori_tol = tolerance
    k, halted_reason = 0, ""
    kind, kind_at, kind_every = None, -(10**9), max(1, round(0.02 / dt))
    while True:
        if k < n_sched:
            ref.tau = k * dt  # step k of the schedule, exactly
            s, cmd = _command(ctrl, ref, q, dt)
        else:
            s = float(plan.s[-1]) if plan is not None else path.length
            cmd = ctrl.step(q, target=T_end, dt=dt)
        Q.append(q)
        QD.append(cmd.qd)
        QDD.append(cmd.qdd)
        ST.append(cmd.status)
        RS.append(cmd.reason)
        S.append(s)
        if record_kinds and cmd.status in ("damped", "singular"):
            # rc.analyze costs about a millisecond: within a stretch of damped/singular steps
            # it is evaluated every `kind_every` steps (20 ms) and the kind carried over
            if k - kind_at >= kind_every or not ST[-2:-1] or ST[-2] not in ("damped", "singular"):
                kind, kind_at = cmd.kind, k
            KINDS.append(kind)
        else:
            KINDS.append(None)
        if cmd.status == "halted" and ctrl.halted:
            halted_reason = cmd.reason
        q = cmd.q_next
        k += 1
        if k >= n_sched:
            if k >= n_sched + n_settle:
                break
            if cmd.position_error <= pos_tol * 0.1 and cmd.orientation_error <= ori_tol * 0.1 \
                    and float(np.max(np.abs(cmd.qd))) < 1e-4:
                break  # on the end pose and (practically) at rest
    # final state (after the last command)
    Q.append(q)
    QD.append(QD[-1] if ctrl.filter is None else ctrl.filter.velocity)
    QDD.append(np.zeros(chain.dof) if ctrl.filter is None else ctrl.filter.acceleration)
    ST.append(ST[-1])
    RS.append(RS[-1])
    S.append(S[-1])
    KINDS.append(KINDS[-1])
    return {"q": np.array(Q), "qd": np.array(QD), "qdd": np.array(QDD), "statuses": tuple(ST),
            "reasons": tuple(RS), "s": np.array(S), "kinds": tuple(KINDS), "halted": halted_reason}


def _path_errors(chain, path, Q, S):
    """Poses, σ_min, and per step the distance from the path / from the reference [m, rad].

    The distance from the path is measured at the nearest point in the pose metric of
    `Path.distance`, searched locally — from the commanded s of the step and from the previous
    step's nearest point (for a tool that lags its schedule; skipped when the tool is within
    0.1 µm and 0.1 µrad of the path already), each within a window of 5 % of the length
    (+1 mm) — never globally: a path that revisits a pose, turns back on itself or rotates
    on the spot has other near points that the tool is not at."""
    poses, J = chain.fk_jacobian(Q)
    sig = np.linalg.svd(J, compute_uv=False)[:, -1]
    perr, oerr, terr = np.empty(len(Q)), np.empty(len(Q)), np.empty(len(Q))
    window = 0.05 * path.length + 1e-3
    rho2 = path.rotation_length ** 2
    s_near = None
    for i in range(len(Q)):
        best = path.distance(poses[i], s_hint=S[i], window=window)
        if s_near is not None and abs(s_near - S[i]) > 1e-12 and (best[0] > 1e-7 or best[1] > 1e-7):
            other = path.distance(poses[i], s_hint=s_near, window=window)
            if other[0] ** 2 + rho2 * other[1] ** 2 < best[0] ** 2 + rho2 * best[1] ** 2:
                best = other
        perr[i], oerr[i], s_near = best
        terr[i] = float(np.linalg.norm(poses[i][:3, 3] - path.position_at(S[i])))
    return poses, sig, perr, oerr, terr


def _evaluate(chain, path, rec, plan, gov, T_end, info, *, dt, settle, tolerance, path_tolerance):
    """The `Execution` of a run, with "completed" and its message."""
    Q = rec["q"]
    t = np.arange(len(Q)) * dt
    poses, sig, perr, oerr, terr = _path_errors(chain, path, Q, rec["s"])
    eend = pose_error(T_end, poses[-1])
    end_p, end_o = float(np.linalg.norm(eend[:3])), float(np.linalg.norm(eend[3:]))
    reached = end_p <= tolerance[0] and end_o <= tolerance[1]
    # the duration ends where the end pose is reached for good (not after the settle wait)
    end_ok = (np.linalg.norm(poses[:, :3, 3] - T_end[:3, 3], axis=1) <= tolerance[0]) \
        & (rotation_angle(np.swapaxes(poses[:, :3, :3], -1, -2) @ T_end[:3, :3]) <= tolerance[1])
    late = np.flatnonzero(~end_ok)
    arrival = min(int(late[-1]) + 1, len(t) - 1) if len(late) else 0
    duration = float(t[arrival]) if reached else float(t[-1])
    nominal = _nominal_arrival(path, tolerance, dt=dt)  # like-for-like with `duration`
    completed, message = False, ""
    if rec["halted"]:
        message = f"halted: {rec['halted']}"
    elif plan is not None and not plan.complete:
        message = f"governor: {plan.message}"
    elif plan is not None and not plan.within_limits:
        message = f"governor: {plan.message}"
    elif not reached:
        message = (f"end pose not reached: {end_p * 1e3:.3g} mm, {math.degrees(end_o):.3g}° from it "
                   f"after {settle:g} s of settling")
    elif plan is not None and (perr.max() > path_tolerance[0] or oerr.max() > path_tolerance[1]):
        k = int(np.argmax(perr / path_tolerance[0] + oerr / path_tolerance[1]))
        message = (f"left the path: {perr.max() * 1e3:.3g} mm / {math.degrees(oerr.max()):.3g}° from it "
                   f"(largest near s = {rec['s'][k]:.4g} m; path tolerance "
                   f"{path_tolerance[0] * 1e3:.3g} mm / "
                   f"{math.degrees(path_tolerance[1]):.3g}°)")
    else:
        completed = True
        message = _completion_message(path, gov, duration, nominal, tolerance)
    # the end errors always measure the distance to the path's end pose; a run whose plan stops
    # short also gets the distance to where it stopped (its settle target) under stop_*
    e_path = pose_error(path.end, poses[-1])
    info.update({"law_duration": path.duration, "end_position_error": float(np.linalg.norm(e_path[:3])),
                 "end_orientation_error": float(np.linalg.norm(e_path[3:])),
                 "governor": repr(gov) if gov is not None else None})
    if plan is not None and not plan.joint_path.complete:
        info.update({"stop_s": float(rec["s"][-1]), "stop_position_error": end_p,
                     "stop_orientation_error": end_o})
    return Execution(t=t, q=Q, qd=rec["qd"], qdd=rec["qdd"], poses=poses, position_error=perr,
                     orientation_error=oerr, tracking_error=terr, statuses=rec["statuses"],
                     reasons=rec["reasons"], kinds=rec["kinds"],
                     sigma_min=sig, s=rec["s"], nominal_duration=nominal, duration=duration,
                     completed=completed, message=message,
                     source="follow" + (" (governor)" if plan is not None else " (time law)"),
                     chain_name=chain.name, joint_names=tuple(chain.joint_names),
                     vmax=np.array(chain.vmax), amax=np.array(chain.amax), info=info)


def _nominal_arrival(path, tolerance, *, dt: float) -> float:
    """Time [s] from which the path's own time law, sampled every ``dt``, stays within
    ``tolerance`` (position [m], orientation [rad]) of the end pose: the nominal counterpart
    of a run's ``duration`` (which ends where the tool arrives within the same tolerance)."""
    T_end, L = path.end, path.length
    n = int(math.ceil(path.duration / dt - 1e-9))
    k = n
    while k > 0:
        e = pose_error(T_end, path.pose_at(path.progress((k - 1) * dt)[0]))
        if np.linalg.norm(e[:3]) > tolerance[0] or np.linalg.norm(e[3:]) > tolerance[1]:
            break
        k -= 1
    return min(k * dt, path.duration) if L > 0 else 0.0


def _completion_message(path, gov, duration: float, nominal: float, tolerance) -> str:
    """'completed in …, nominal …' (both to within ``tolerance`` of the end pose); for a governed
    run, what replaced the path's time law."""
    ratio = duration / nominal if nominal > 0 else 1.0
    message = (f"completed in {duration:.3f} s, nominal {nominal:.3f} s ({duration - nominal:+.3f} s, "
               f"×{ratio:.2f}; both to within {tolerance[0] * 1e3:.3g} mm / "
               f"{math.degrees(tolerance[1]):.3g}° of the end pose)")
    if gov is None:
        return message
    jerk = gov.progress_jerk_limit(path)
    limits = f"speed {path.speed:g} m/s, acceleration {path.acceleration:g} m/s²" + \
        (f", jerk {jerk:.3g} m/s³" if jerk else "")
    return (f"{message}; the governor replaced the path's {path.law.name} law by the time-optimal "
            f"progress within the joint limits and the path's {limits}")


def _approach(chain, path, q0, dt) -> Execution:
    """IK for the path start, then a jerk-limited joint move there (ratectl.smoothing.move)."""
    res = ik(chain, path.start, q0, tol=(1e-10, 1e-10))
    q_goal, ep, eo = np.array(res.q), res.position_error, res.orientation_error
    if ep > 1e-6 or eo > 1e-5:
        raise InputError(f"cannot reach the start of the path from q0: IK ends {ep * 1e3:.3g} mm / "
                         f"{math.degrees(eo):.3g}° away", argument="q0", value=q0)
    lo, hi = chain.lower, chain.upper
    if np.any(q_goal < lo) or np.any(q_goal > hi):
        raise InputError("the IK solution for the path start violates the joint limits; pass a q0 "
                         "closer to the start", argument="q0", value=q0)
    traj = move(q0, q_goal, vmax=chain.vmax, amax=chain.amax, jmax=chain.jmax)
    t, q, qd, qdd = traj.sample(dt)
    q[-1] = q_goal
    return Execution(t=t, q=q, qd=qd, qdd=qdd, poses=chain.fk(q), statuses=("approach",) * len(t),
                     reasons=("joint move to the path start",) * len(t),
                     nominal_duration=traj.duration, duration=float(t[-1]), completed=True,
                     message=f"joint move to the path start in {traj.duration:.3f} s", source="approach",
                     chain_name=chain.name, joint_names=tuple(chain.joint_names),
                     vmax=np.array(chain.vmax), amax=np.array(chain.amax))
