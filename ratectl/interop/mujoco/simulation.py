"""Close the loop through MuJoCo's physics (`simulate`) and render configurations.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ...control import ResolvedRateController
from ...errors import InputError
from ...execution import Execution
from ...io.mjcf import mjcf_joint_addresses
from ...model import Chain
from ...spatial import pose_error
from .export import compile_mjcf, to_mjcf
from .kinematics import _frame_id
from .limits import geom_distance

if TYPE_CHECKING:
    from ...paths.base import Path

__all__ = ['simulate', 'SimulationLog', 'render_frames', 'ACTUATIONS']


# ---------------------------------------------------------------------- simulation
ACTUATIONS = ("position", "velocity")


_BADQACC = int(mujoco.mjtWarning.mjWARN_BADQACC)


def _actuators_for(model, joint_ids, names, actuation: str):
    """Actuator index, kp, kv per chain joint for the requested actuation kind.

    A position servo is an actuator with force = kp·ctrl − kp·q − kv·q̇ (gain [kp],
    bias [0, −kp, −kv]); a velocity servo has force = kv·ctrl − kv·q̇ (gain [kv],
    bias [0, 0, −kv]) — what MJCF's ``<position>`` and ``<velocity>`` compile to.
    """
    trn_joint = int(mujoco.mjtTrn.mjTRN_JOINT)
    ids, kps, kvs = [], [], []
    for jid, jn in zip(joint_ids, names, strict=True):
        found = None
        for a in range(model.nu):
            if int(model.actuator_trntype[a]) != trn_joint or int(model.actuator_trnid[a, 0]) != jid:
                continue
            g = float(model.actuator_gainprm[a, 0])
            b1, b2 = float(model.actuator_biasprm[a, 1]), float(model.actuator_biasprm[a, 2])
            if abs(float(model.actuator_gear[a, 0]) - 1.0) > 1e-12 or g <= 0:
                continue
            if actuation == "position" and abs(b1 + g) <= 1e-9 * g:
                found = (a, g, -b2)
                break
            if actuation == "velocity" and b1 == 0.0 and abs(b2 + g) <= 1e-9 * g:
                found = (a, 0.0, g)
                break
        if found is None:
            raise InputError(
                f"the MuJoCo model has no {actuation} actuator (MJCF <{actuation}>, gear 1) on joint "
                f"{jn!r}; export the chain with to_mjcf(chain, actuators={actuation!r}) or add one",
                argument="model_or_xml", value=jn)
        ids.append(found[0])
        kps.append(found[1])
        kvs.append(found[2])
    return np.array(ids, dtype=int), np.array(kps), np.array(kvs)


def _servo_period(model, data, act_ids, q, qd_cmd, ff, nsub: int, actuation: str):
    """Step the physics ``nsub`` times toward the commanded joint velocity ``qd_cmd`` from ``q``.

    Position servos get the ramp ``u(τ) = q + q̇_cmd·τ + (kv/kp)·q̇_cmd`` (``ff`` = kv/kp),
    velocity servos ``u = q̇_cmd``. Returns (mean actuator force over the period, stable): not
    stable when MuJoCo flagged bad accelerations or reset its state.
    """
    if actuation == "velocity":
        data.ctrl[act_ids] = qd_cmd
    tau_acc = np.zeros(len(act_ids))
    h = model.opt.timestep
    data.warning[_BADQACC].number = 0
    time0 = data.time
    for s in range(nsub):
        if actuation == "position":
            data.ctrl[act_ids] = q + qd_cmd * (s * h) + ff * qd_cmd
        mujoco.mj_step(model, data)
        tau_acc += data.actuator_force[act_ids]
    stable = not (data.warning[_BADQACC].number > 0 or data.time < time0)
    return tau_acc / nsub, stable


class _Reference:
    """Desired pose and feed-forward twist over time, from a path or a list of poses."""

    def __init__(self, path_or_targets: Any, *, position_tolerance: float,
                 orientation_tolerance: float) -> None:
        p = path_or_targets  # duck-typed: a path, a recorded Execution, or poses
        self.path = None
        self.replay = None
        if all(hasattr(p, a) for a in ("pose", "twist", "duration")):
            self.path = p
            self.poses = None
            self.end_time = float(p.duration)
        elif all(hasattr(p, a) for a in ("t", "q", "qd", "poses")) and p.poses is not None:
            self.replay = p
            self.poses = None
            t = np.asarray(p.t, dtype=float)
            self.replay_dt = float(t[1] - t[0]) if len(t) > 1 else math.nan
            self.end_time = float(t[-1])
        else:
            try:
                poses = np.asarray(p, dtype=float)
            except (TypeError, ValueError):
                poses = None
            if poses is None or poses.shape[-2:] != (4, 4) or poses.ndim not in (2, 3):
                raise InputError("path_or_targets must be a ratectl path (with pose(t), twist(t), "
                                 "duration) or a 4x4 pose or a sequence of 4x4 poses",
                                 argument="path_or_targets", value=p)
            if not np.all(np.isfinite(poses)):
                raise InputError("target poses must be finite", argument="path_or_targets", value=p)
            self.poses = poses.reshape(-1, 4, 4)
            self.end_time = math.inf
        self.index = 0
        self.ptol = position_tolerance
        self.rtol = orientation_tolerance

    def at(self, t: float, T_actual: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """(desired pose, feed-forward twist or None, joint feed-forward or None) at time t;
        advances through targets."""
        if self.path is not None:
            return self.path.pose(t), self.path.twist(t), None
        if self.replay is not None:
            r = self.replay
            k = int(round(t / self.replay_dt)) if len(r.t) > 1 else 0
            if k >= len(r.t) - 1:
                return r.poses[-1], None, None
            return r.poses[k], None, np.asarray(r.qd[k], dtype=float)
        while self.index < len(self._targets) - 1 and self.reached(T_actual):
            self.index += 1
        return self._targets[self.index], None, None

    @property
    def _targets(self) -> np.ndarray:
        if self.poses is None:  # pragma: no cover - a path or a replay is handled before
            raise InputError("no target poses to follow", argument="path_or_targets")
        return self.poses

    def reached(self, T_actual: ArrayLike) -> bool:
        e = pose_error(self._targets[self.index], T_actual)
        return bool(np.linalg.norm(e[:3]) <= self.ptol and np.linalg.norm(e[3:]) <= self.rtol)

    @property
    def last(self) -> bool:
        return self.poses is not None and self.index == len(self.poses) - 1


def _cmd_attr(cmd, *names, default=math.nan):
    for n in names:
        obj = cmd
        ok = True
        for part in n.split("."):
            if not hasattr(obj, part):
                ok = False
                break
            obj = getattr(obj, part)
        if ok:
            return obj
    return default


class SimulationLog:
    """What `simulate` measured besides the execution record (arrays over steps)."""

    def __init__(self, *, qd_command: Any, tau: Any, min_distance: Any, substeps: Any, actuation: Any,
                 physics: Any) -> None:
        self.qd_command = qd_command
        self.tau = tau
        self.min_distance = min_distance
        self.substeps = substeps
        self.actuation = actuation
        self.physics = physics

    def __repr__(self) -> str:
        return (f"SimulationLog(actuation={self.actuation!r}, physics={self.physics}, "
                f"substeps={self.substeps}, steps={len(self.qd_command)})")


def simulate(model_or_xml: mujoco.MjModel | str | os.PathLike[str] | None, chain: Chain,
             path_or_targets: Path | Execution | ArrayLike, q0: ArrayLike, *, dt: float,
             controller: ResolvedRateController | None = None, actuation: str = "position",
             frame: str = "tool", frame_type: str = "site", duration: float | None = None,
             settle: float = 0.0, physics: bool = True, distance_pairs: Sequence[tuple[str,
             str]] | None = None, position_tolerance: float = 1e-3, orientation_tolerance: float = 1e-2,
             on_step: Callable[[int, mujoco.MjModel, mujoco.MjData],
             None] | None = None) -> tuple[Execution, SimulationLog]:
    """Run ratectl's controller in closed loop on a MuJoCo model, with physics.

    Every control period ``dt``:

    1. read the measured joint positions and velocities of the chain's joints from
       ``data.qpos``/``data.qvel`` and the tool pose from the ``frame`` site/body;
    2. ``cmd = controller.step(q_measured, target=T_d(t), twist=ξ_d(t), dt=dt)``;
    3. command the actuators for ``dt/timestep`` physics steps (``mj_step``):

       * ``"position"`` servos (force = kp·(u − q) − kv·q̇): the setpoint follows the
         commanded motion within the period with velocity feed-forward,
         ``u(τ) = q_k + q̇_cmd·τ + (kv/kp)·q̇_cmd`` (τ = time since the start of the
         period), so that force = kp·(q_k + q̇_cmd τ − q) + kv·(q̇_cmd − q̇) — a PD
         tracker of the commanded ramp;
       * ``"velocity"`` servos (force = kv·(u − q̇)): ``u = q̇_cmd``.

    With ``physics=False`` the same loop integrates ``q_{k+1} = cmd.q`` instead (the
    kinematic run the physics run is compared with).

    Args:
        model_or_xml: an ``MjModel``, MJCF text or path; ``None`` exports the chain with
            `to_mjcf` and actuators of the requested kind.
        chain: the ratectl chain of the arm; its joint names select the model's joints
            and actuators.
        path_or_targets: a ratectl path (``pose(t)``, ``twist(t)``, ``duration``), or a
            4×4 target pose or a sequence of them (visited in order; the next target is
            taken when the tool is within the tolerances of the current one).
        q0: initial joint positions (n,) [rad or m]; the arm starts at rest.
        dt: control period [s]; a multiple of the model's time step.
        controller: anything with ``step(q, *, target, twist, dt)`` returning a command
            with ``qd``, ``q`` and ``status`` (default ``ResolvedRateController(chain)``).
        actuation: ``"position"`` or ``"velocity"``.
        frame: the tool site (or body) in the model.
        frame_type: ``"site"`` or ``"body"``, the kind of ``frame``.
        duration: run time [s]; default the path duration + ``settle``, or 10 s for targets
            (a run on targets ends when the last one is reached).
        settle: extra time after the path's end [s].
        physics: False for the kinematic reference run (no MuJoCo stepping).
        distance_pairs: optional geom pairs ``[(geom1, geom2), ...]`` whose smallest
            distance is recorded every step (``log.min_distance`` [m]).
        position_tolerance: target-reached tolerance on the position [m].
        orientation_tolerance: target-reached tolerance on the orientation [rad].
        on_step: optional callback ``on_step(k, model, data)`` after every period
            (e.g. to grab rendered frames).

    Returns:
        ``(execution, log)``: an `Execution` with the measured
        t, q, q̇, q̈, tool poses, errors, statuses and σ_min, and a `SimulationLog`
        with the commanded q̇, the actuator forces and the recorded distances.
    """
    plant = _Plant.build(model_or_xml, chain, dt=dt, actuation=actuation, frame=frame,
                         frame_type=frame_type, physics=physics)
    q = chain.check_q(q0).astype(float).copy()
    if q.shape != (chain.dof,):
        raise InputError(f"q0 must have shape ({chain.dof},), got {q.shape}", argument="q0", value=q0)
    if controller is None:
        controller = ResolvedRateController(chain)
    ref = _Reference(path_or_targets, position_tolerance=position_tolerance,
                     orientation_tolerance=orientation_tolerance)
    if ref.replay is not None and len(ref.replay.t) > 1 and abs(ref.replay_dt - dt) > 1e-9 * dt:
        raise InputError(f"the replayed execution was recorded every {ref.replay_dt} s; simulate it with "
                         f"the same dt (got {dt})", argument="dt", value=dt)
    if duration is None:
        duration = (ref.end_time + settle) if math.isfinite(ref.end_time) else 10.0
    if not (duration > 0 and math.isfinite(duration)):
        raise InputError(f"duration must be a positive time [s], got {duration!r}", argument="duration",
                         value=duration)
    steps = int(math.floor(duration / dt + 1e-9))
    n = chain.dof
    plant.reset(q)
    model, data = plant.model, plant.data
    ts, qs, qds, poses, desired, cmds, taus, dists, commands = [], [], [], [], [], [], [], [], []
    qd_meas = np.zeros(n)
    halted = ""
    for k in range(steps + 1):
        t = k * dt
        if physics:
            q, qd_meas, T = plant.measure()
        else:
            T = chain.fk(q)
        Td, xi_ff, qd_ff = ref.at(t, T)
        ts.append(t)
        qs.append(q.copy())
        qds.append(qd_meas.copy())
        poses.append(T)
        desired.append(Td)
        if distance_pairs is not None:
            if not physics:
                data.qpos[plant.qadr] = q
                mujoco.mj_kinematics(model, data)
            dists.append(geom_distance(model, data, distance_pairs))
        if k == steps:
            break
        if ref.poses is not None and ref.last and ref.reached(T) and np.max(np.abs(qd_meas)) < 1e-3:
            break
        try:
            if qd_ff is None:
                cmd = controller.step(q, target=Td, twist=xi_ff, dt=dt)
            else:
                cmd = controller.step(q, target=Td, twist=xi_ff, dt=dt, qd_ff=qd_ff)
        except Exception as exc:  # a controller must not take the simulation down silently
            halted = f"controller raised {type(exc).__name__}: {exc}"
            break
        qd_cmd = np.asarray(cmd.qd, dtype=float)
        commands.append(cmd)
        cmds.append(qd_cmd.copy())
        if not physics:
            q = np.asarray(cmd.q_next, dtype=float).copy()
            qd_meas = qd_cmd.copy()
            taus.append(np.zeros(n))
            continue
        tau, stable = plant.apply(q, qd_cmd)
        taus.append(tau)
        if not stable:
            halted = (f"the MuJoCo simulation became unstable at t = {t + dt:.4g} s (non-finite or huge "
                      "accelerations; MuJoCo reset the state); lower the servo gains or the time step")
            break
        if on_step is not None:
            on_step(k, model, data)
    log = SimulationLog(qd_command=np.array(cmds).reshape(-1, n), tau=np.array(taus).reshape(-1, n),
                        min_distance=np.array(dists), substeps=plant.nsub, actuation=actuation,
                        physics=physics)
    ex = _execution(chain, ref, np.array(ts), np.array(qs), np.array(qds), np.array(poses),
                    np.array(desired), commands, dt=dt, halted=halted, physics=physics,
                    log_info={"actuation": actuation if physics else None, "substeps": plant.nsub,
                              "timestep": float(model.opt.timestep)})
    return ex, log


@dataclasses.dataclass
class _Plant:
    """The MuJoCo side of `simulate`: the model, its state, the chain's addresses in it
    and the actuators that command them."""

    model: mujoco.MjModel
    data: mujoco.MjData
    qadr: np.ndarray
    dadr: np.ndarray
    frame_id: int
    frame_type: str
    nsub: int
    actuation: str
    physics: bool
    act_ids: np.ndarray | None = None
    ff: np.ndarray | None = None

    @classmethod
    def build(cls, model_or_xml: mujoco.MjModel | str | os.PathLike[str] | None, chain: Chain, *, dt: float,
              actuation: str, frame: str, frame_type: str, physics: bool) -> _Plant:
        if actuation not in ACTUATIONS:
            raise InputError(f"actuation must be one of {ACTUATIONS}, got {actuation!r}",
                             argument="actuation", value=actuation)
        if not isinstance(chain, Chain):
            raise InputError(f"chain must be a ratectl.Chain, got {type(chain).__name__}",
                             argument="chain", value=chain)
        if not (isinstance(dt, int | float) and dt > 0 and math.isfinite(dt)):
            raise InputError(f"dt must be a positive control period [s], got {dt!r}", argument="dt",
                             value=dt)
        if model_or_xml is None:
            model_or_xml = to_mjcf(chain, actuators=actuation, site=frame)
        model = compile_mjcf(model_or_xml)
        qadr, dadr = mjcf_joint_addresses(model, chain)
        nsub = int(round(dt / model.opt.timestep))
        if nsub < 1 or abs(nsub * model.opt.timestep - dt) > 1e-9 * max(dt, 1.0):
            raise InputError(f"dt = {dt} s must be a whole multiple of the model time step "
                             f"{model.opt.timestep} s", argument="dt", value=dt)
        plant = cls(model=model, data=mujoco.MjData(model), qadr=qadr, dadr=dadr,
                    frame_id=_frame_id(model, frame, frame_type), frame_type=frame_type, nsub=nsub,
                    actuation=actuation, physics=physics)
        if physics:
            jids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, nm) for nm in chain.joint_names]
            act_ids, kp, kv = _actuators_for(model, jids, chain.joint_names, actuation)
            plant.act_ids = act_ids
            plant.ff = np.where(kp > 0, kv / np.where(kp > 0, kp, 1.0), 0.0)
        return plant

    def reset(self, q: np.ndarray) -> None:
        """The arm at rest at q, servo setpoints on it."""
        self.data.qpos[self.qadr] = q
        self.data.qvel[:] = 0.0
        if self.physics:
            self.data.ctrl[self.act_ids] = q if self.actuation == "position" else 0.0
        mujoco.mj_forward(self.model, self.data)

    def tool_pose(self) -> np.ndarray:
        T = np.eye(4)
        d, i = self.data, self.frame_id
        if self.frame_type == "site":
            T[:3, :3] = d.site_xmat[i].reshape(3, 3)
            T[:3, 3] = d.site_xpos[i]
        else:
            T[:3, :3] = d.xmat[i].reshape(3, 3)
            T[:3, 3] = d.xpos[i]
        return T

    def measure(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, q̇, tool pose) as measured. mj_step leaves the kinematics of the state before its
        last integration: they are refreshed so that the pose belongs to the measured q."""
        mujoco.mj_kinematics(self.model, self.data)
        return np.array(self.data.qpos[self.qadr]), np.array(self.data.qvel[self.dadr]), self.tool_pose()

    def apply(self, q: np.ndarray, qd_cmd: np.ndarray) -> tuple[np.ndarray, bool]:
        """Command q̇ for one control period (``nsub`` physics steps); returns the mean actuator
        force and False when MuJoCo found the state unstable (and reset it)."""
        return _servo_period(self.model, self.data, self.act_ids, q, qd_cmd, self.ff, self.nsub,
                             self.actuation)


def render_frames(model: mujoco.MjModel, data: mujoco.MjData, chain: Chain, qs: ArrayLike, *,
                  width: int = 480, height: int = 360, lookat: Sequence[float] = (0.0, 0.0, 0.3),
                  distance: float = 2.0, azimuth: float = 135.0,
                  elevation: float = -25.0) -> list[np.ndarray]:
    """Render the arm at each configuration of ``qs`` (k, n) with MuJoCo's offscreen
    renderer; returns k RGB images (height, width, 3) uint8.

    Needs an offscreen OpenGL context: set ``MUJOCO_GL=egl`` (or ``osmesa``) before
    ``mujoco`` is first imported. Raises ``RuntimeError`` when no context can be made.
    """
    qadr, _ = mjcf_joint_addresses(model, chain)
    try:
        renderer = mujoco.Renderer(model, height, width)
    except Exception as exc:  # mujoco raises several kinds when there is no GL
        raise RuntimeError(f"no offscreen OpenGL context (MUJOCO_GL=egl or osmesa): {exc}") from exc
    cam = mujoco.MjvCamera()
    cam.lookat[:] = lookat
    cam.distance = distance
    cam.azimuth = azimuth
    cam.elevation = elevation
    frames = []
    try:
        for q in np.atleast_2d(np.asarray(qs, dtype=float)):
            data.qpos[qadr] = q
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera=cam)
            frames.append(renderer.render().copy())
    finally:
        renderer.close()
    return frames


def _execution(chain, ref, t, q, qd, poses, desired, commands, *, dt, halted, physics, log_info):
    """Fill an `Execution` from the recorded arrays."""

    K = len(t)
    qdd = np.zeros_like(qd)
    if K > 1:
        qdd[1:] = np.diff(qd, axis=0) / dt
    e = pose_error(desired, poses)
    tracking = np.linalg.norm(e[:, :3], axis=1)
    if ref.path is not None:
        pos_err, ori_err, s_ref = np.empty(K), np.empty(K), np.empty(K)
        s_hint = 0.0
        for k in range(K):
            s_ref[k] = ref.path.progress(t[k])[0]
            pos_err[k], ori_err[k], s_hint = ref.path.distance(poses[k])
        nominal = float(ref.path.duration)
        end_err = pose_error(ref.path.pose(nominal), poses[-1])
    elif ref.replay is not None:
        pos_err, ori_err, s_ref = tracking, np.linalg.norm(e[:, 3:], axis=1), None
        nominal = float(ref.replay.duration)
        end_err = pose_error(ref.replay.poses[-1], poses[-1])
    else:
        pos_err, ori_err, s_ref = tracking, np.linalg.norm(e[:, 3:], axis=1), None
        nominal = math.nan
        end_err = pose_error(ref.poses[-1], poses[-1])
    statuses = [str(getattr(c, "status", "")) for c in commands]
    sig = [float(getattr(c, "sigma_min", math.nan)) for c in commands]
    if statuses and len(statuses) < K:  # the last sample has no command of its own
        statuses += [statuses[-1]] * (K - len(statuses))
        sig += [sig[-1]] * (K - len(sig))
    p_end, r_end = float(np.linalg.norm(end_err[:3])), float(np.linalg.norm(end_err[3:]))
    completed = (not halted and p_end <= ref.ptol and r_end <= ref.rtol
                 and (ref.poses is None or ref.last))
    if halted:
        message = halted
    elif completed:
        message = f"reached the end within {p_end * 1e3:.3g} mm and {math.degrees(r_end):.3g}°"
    else:
        message = (f"ended {p_end * 1e3:.3g} mm and {math.degrees(r_end):.3g}° from the end pose "
                   f"(tolerances {ref.ptol * 1e3:.3g} mm, {math.degrees(ref.rtol):.3g}°)")
        if statuses:
            last = statuses[-1]
            reason = getattr(commands[-1], "reason", "")
            message += f"; last status {last!r}" + (f": {reason}" if reason else "")
    return Execution(
        t=t, q=q, qd=qd, qdd=qdd, poses=poses, position_error=pos_err, orientation_error=ori_err,
        tracking_error=tracking, statuses=tuple(statuses), sigma_min=np.array(sig) if sig else None,
        s=s_ref, nominal_duration=nominal, duration=float(t[-1] - t[0]) if K else 0.0,
        completed=bool(completed), message=message,
        source="simulate" if physics else "simulate (kinematic)", chain_name=chain.name,
        joint_names=chain.joint_names, vmax=np.array(chain.vmax), amax=np.array(chain.amax),
        info={"dt": dt, **log_info})
