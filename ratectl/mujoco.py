"""MuJoCo and mink interop: export to MJCF, MuJoCo/mink kinematics, mink limits, simulation.

* :func:`to_mjcf` writes a chain as an MJCF model (capsule links, hinge/slide joints
  with limits, a ``tool`` site, optional position/velocity actuators and obstacles)
  whose kinematics equal ratectl's to rounding.
* :func:`mujoco_fk_jacobian` evaluates a MuJoCo model's frame pose and Jacobian in
  ratectl's conventions.
* :class:`MinkKinematics` is a chain-compatible kinematics source backed by a
  ``mink.Configuration`` (MuJoCo's kinematics), for :class:`ratectl.ResolvedRateController`.
* :func:`mink_inequalities` and :class:`MinkLimitedSolver` turn mink limits — in
  particular ``mink.CollisionAvoidanceLimit`` — into velocity-level inequality rows
  ``G q̇ ≤ h`` for ratectl's QP.
* :func:`simulate` closes the loop through MuJoCo's physics and records an
  :class:`~ratectl.execution.Execution` like :func:`ratectl.follow`;
  :func:`render_frames` renders configurations offscreen.

``mujoco`` and ``mink`` (the ``ratectl[mujoco]`` extra) are imported here only;
the rest of ratectl never needs them.

Conventions (ratectl's): Jacobian rows ``[v; ω]`` in world axes with the linear part
at the frame origin. MuJoCo's ``mj_jacSite``/``mj_jacBody`` already return exactly
that (``jacp`` = world-frame velocity of the frame origin, ``jacr`` = world angular
velocity). mink's ``Configuration.get_frame_jacobian`` returns the *body* (local)
Jacobian ``ᴮJ = blockdiag(Rᵀ, Rᵀ) · [jacp; jacr]`` with ``R`` the frame's world
rotation, so ratectl's Jacobian is ``J = blockdiag(R, R) · ᴮJ``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from .chain import Chain
from .errors import InputError, SolverError
from .importers import chain_from_mjcf, mjcf_joint_addresses
from .spatial import quat_from_rotation

__all__ = [
    "to_mjcf",
    "compile_mjcf",
    "mujoco_fk_jacobian",
    "MinkKinematics",
    "mink_inequalities",
    "MinkLimitedSolver",
    "geom_distance",
    "simulate",
    "SimulationLog",
    "render_frames",
    "ACTUATIONS",
]


# ---------------------------------------------------------------------- export
_UNLIMITED = 1e10  # stands for an absent bound of a one-sided joint range [rad or m]

def _num(x: float) -> str:
    """Shortest round-trip text of a float (so the export is exact to the last bit)."""
    x = float(x)
    if x == 0.0:
        return "0"
    return repr(x)


def _vec(v) -> str:
    return " ".join(_num(x) for x in np.asarray(v, dtype=float).ravel())


def _pose_attrs(T: np.ndarray) -> str:
    out = []
    p = T[:3, 3]
    if np.any(p != 0.0):
        out.append(f'pos="{_vec(p)}"')
    R = T[:3, :3]
    if np.any(R != np.eye(3)):
        out.append(f'quat="{_vec(quat_from_rotation(R))}"')
    return " ".join(out)


def _attr_text(value) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | np.integer):
        return str(int(value))
    a = np.asarray(value, dtype=float)
    return _vec(a)


def _xml_escape(s: str) -> str:
    return (s.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;").replace(">", "&gt;"))


def to_mjcf(chain: Chain, *, name: str | None = None, radius: float = 0.03,
            site: str = "tool", actuators: str | None = None, kp: float = 20000.0,
            kv: float | None = None, armature: float = 0.1, damping: float = 0.0,
            timestep: float = 0.001, gravity: bool = True, gravity_compensation: bool = True,
            obstacles: Sequence[Mapping] = (), density: float = 1000.0,
            link_contype: int = 1, link_conaffinity: int = 1, floor: bool = False) -> str:
    """MJCF text of ``chain`` that MuJoCo compiles, with the same kinematics.

    Body ``i`` is the frame of joint i: its pose relative to body ``i−1`` is
    ``post_{i−1} · pre_i`` (``base · pre_1`` for the first), and joint i is a hinge
    (revolute) or slide (prismatic) about/along its z axis through its origin. The
    ``site`` sits at ``post_n · tool`` in the last body, so the site pose is
    ``chain.fk(q)`` and ``mj_jacSite`` is ``chain.jacobian(q)``. Positions and
    quaternions are written with round-trip float text; agreement is to ~1e-15.

    Args:
        chain: the arm.
        name: model name (default the chain name).
        radius: capsule radius of the link geoms [m]; each body gets a capsule from
            its origin to the next joint (or the tool) and a sphere at the joint.
        site: name of the tool site.
        actuators: ``None``, ``"position"`` (``<position kp kv>``: force =
            kp·(ctrl − q) − kv·q̇) or ``"velocity"`` (``<velocity kv>``: force =
            kv·(ctrl − q̇)), one per joint, named like the joint.
        kp: position gain [N·m/rad or N/m].
        kv: velocity gain [N·m·s/rad or N·s/m]; default ``2·sqrt(kp·armature)``
            (critical damping of the armature) for position actuators and
            ``3000·armature`` [1/s · kg·m²] for velocity actuators (the implicit
            integrator keeps these stiff velocity servos stable).
        armature: rotor inertia added to every joint [kg·m² or kg]; it keeps stiff
            servos stable with small wrist inertias.
        damping: joint viscous damping [N·m·s/rad].
        timestep: physics time step [s].
        gravity: include gravity (−9.81 m/s² along world z).
        gravity_compensation: set ``gravcomp="1"`` on the links (the servo need not
            hold the arm up).
        obstacles: static geoms added to the world, as MJCF attribute mappings, e.g.
            ``{"name": "ball", "type": "sphere", "size": 0.05, "pos": (0.4, 0, 0.3)}``;
            they collide with the links (contype/conaffinity 1 unless given).
        density: link density [kg/m³] (masses come from the geoms).
        link_contype, link_conaffinity: collision bits of the link geoms.
        floor: add a visual-only floor plane at z = 0 (for rendering; it collides with
            nothing).

    Returns:
        The MJCF document as a string.
    """
    if not isinstance(chain, Chain):
        raise InputError(f"chain must be a ratectl.Chain, got {type(chain).__name__}",
                         argument="chain", value=chain)
    if actuators not in (None, "position", "velocity"):
        raise InputError(f"actuators must be None, 'position' or 'velocity', got {actuators!r}",
                         argument="actuators", value=actuators)
    for arg, v in (("radius", radius), ("kp", kp), ("timestep", timestep), ("density", density)):
        try:
            fv = float(v)
        except (TypeError, ValueError):
            fv = math.nan
        if not (fv > 0 and math.isfinite(fv)):
            raise InputError(f"{arg} must be a positive number, got {v!r}", argument=arg, value=v)
    if not (armature >= 0 and damping >= 0):
        raise InputError("armature and damping must be >= 0", argument="armature", value=armature)
    if kv is None:
        kv = 2.0 * math.sqrt(kp * max(armature, 1e-3)) if actuators == "position" else 3000.0 * max(
            armature, 1e-3)
    joints = chain.joints
    n = len(joints)
    names = list(chain.joint_names)
    if len(set(names)) != n:
        raise InputError(f"joint names must be unique for MJCF, got {names}", argument="chain",
                         value=names)
    mname = _xml_escape(name if name is not None else chain.name)
    grav = "0 0 -9.81" if gravity else "0 0 0"
    lines = [f'<mujoco model="{mname}">',
             '  <compiler angle="radian" autolimits="true"/>',
             f'  <option timestep="{_num(timestep)}" integrator="implicitfast" gravity="{grav}"/>',
             "  <default>",
             f'    <joint armature="{_num(armature)}" damping="{_num(damping)}"/>',
             f'    <geom contype="{link_contype}" conaffinity="{link_conaffinity}" '
             f'density="{_num(density)}" rgba="0.55 0.6 0.7 1"/>',
             "  </default>"]
    if floor:
        lines += ["  <asset>",
                  '    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.75 0.82 0.9" '
                  'rgb2="1 1 1" width="64" height="64"/>',
                  "  </asset>"]
    lines += ["  <worldbody>",
             '    <light pos="0 0 3" dir="0 0 -1" directional="true"/>']
    if floor:
        lines.append('    <geom name="floor" type="plane" size="3 3 0.05" contype="0" conaffinity="0" '
                     'rgba="0.82 0.84 0.86 1"/>')
    for k, ob in enumerate(obstacles):
        if not isinstance(ob, Mapping):
            raise InputError(f"obstacles[{k}] must be a mapping of MJCF geom attributes, got "
                             f"{type(ob).__name__}", argument="obstacles", value=ob)
        attrs = {"name": f"obstacle{k}", "contype": 1, "conaffinity": 1, "rgba": "0.85 0.3 0.25 0.6"}
        attrs.update(ob)
        text = " ".join(f'{key}="{_xml_escape(_attr_text(v))}"' for key, v in attrs.items())
        lines.append(f"    <geom {text}/>")
    gc = ' gravcomp="1"' if gravity_compensation else ""
    indent = "    "
    prev_post = chain.base
    for i, j in enumerate(joints):
        B = prev_post @ j.pre
        nxt = j.post @ (joints[i + 1].pre if i + 1 < n else chain.tool)
        body = _xml_escape(f"link{i + 1}")
        lines.append(f'{indent}<body name="{body}" {_pose_attrs(B)}{gc}>')
        indent += "  "
        jtype = "hinge" if j.kind == "revolute" else "slide"
        lim = ""
        lo, hi = j.qlim
        if math.isfinite(lo) and math.isfinite(hi):
            lim = f' range="{_num(lo)} {_num(hi)}" limited="true"'
        elif math.isfinite(lo) or math.isfinite(hi):
            big = _UNLIMITED  # MJCF has no one-sided range; the importer reads this back as ±inf
            lim = (f' range="{_num(lo if math.isfinite(lo) else -big)} '
                   f'{_num(hi if math.isfinite(hi) else big)}" limited="true"')
        lines.append(f'{indent}<joint name="{_xml_escape(names[i])}" type="{jtype}" axis="0 0 1"{lim}/>')
        lines.append(f'{indent}<geom name="{body}_joint" type="sphere" size="{_num(radius * 1.2)}"/>')
        p = nxt[:3, 3]
        if np.linalg.norm(p) > 1e-9:
            lines.append(f'{indent}<geom name="{body}_link" type="capsule" size="{_num(radius)}" '
                         f'fromto="0 0 0 {_vec(p)}"/>')
        prev_post = j.post
    lines.append(f'{indent}<site name="{_xml_escape(site)}" {_pose_attrs(prev_post @ chain.tool)} '
                 'size="0.01" rgba="0.2 0.8 0.2 1"/>')
    for _ in range(n):
        indent = indent[:-2]
        lines.append(f"{indent}</body>")
    lines.append("  </worldbody>")
    if actuators is not None:
        lines.append("  <actuator>")
        for jn in names:
            jn = _xml_escape(jn)
            if actuators == "position":
                lines.append(f'    <position name="{jn}" joint="{jn}" kp="{_num(kp)}" kv="{_num(kv)}"/>')
            else:
                lines.append(f'    <velocity name="{jn}" joint="{jn}" kv="{_num(kv)}"/>')
        lines.append("  </actuator>")
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"


def compile_mjcf(model_or_xml):
    """An ``MjModel`` from an ``MjModel`` (returned as is), MJCF text or a file path.

    Text and files go through :func:`ratectl.importers.chain_from_mjcf`'s safety
    checks (no DTD/entities, mesh files ignored).
    """
    if isinstance(model_or_xml, mujoco.MjModel):
        return model_or_xml
    from .importers import _compile_mjcf

    return _compile_mjcf(model_or_xml)[0]


# ---------------------------------------------------------------------- kinematics
_FRAME_TYPES = ("site", "body")


def _frame_id(model, frame: str, frame_type: str) -> int:
    if frame_type not in _FRAME_TYPES:
        raise InputError(f"frame_type must be one of {_FRAME_TYPES}, got {frame_type!r}",
                         argument="frame_type", value=frame_type)
    obj = mujoco.mjtObj.mjOBJ_SITE if frame_type == "site" else mujoco.mjtObj.mjOBJ_BODY
    i = mujoco.mj_name2id(model, obj, frame)
    if i < 0:
        raise InputError(f"the model has no {frame_type} named {frame!r}", argument="frame", value=frame)
    return i


def mujoco_fk_jacobian(model, data, chain: Chain, q, *, frame: str, frame_type: str = "site"):
    """MuJoCo's pose (4×4) and Jacobian (6×n, ratectl conventions) of a site or body at q.

    Sets the chain's joints of ``data.qpos`` to ``q`` (other joints keep their value),
    runs ``mj_kinematics`` and ``mj_comPos``, and returns ``T_world_frame`` and
    ``[jacp; jacr]`` restricted to the chain's dofs — world axes, linear part at the
    frame origin, i.e. exactly ``chain.fk(q)``/``chain.jacobian(q)`` when the chain
    describes the same arm.
    """
    qadr, dadr = mjcf_joint_addresses(model, chain)
    fid = _frame_id(model, frame, frame_type)
    data.qpos[qadr] = chain.check_q(q)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    jp = np.zeros((3, model.nv))
    jr = np.zeros((3, model.nv))
    if frame_type == "site":
        pos, mat = data.site_xpos[fid], data.site_xmat[fid]
        mujoco.mj_jacSite(model, data, jp, jr, fid)
    else:
        pos, mat = data.xpos[fid], data.xmat[fid]
        mujoco.mj_jacBody(model, data, jp, jr, fid)
    T = np.eye(4)
    T[:3, :3] = mat.reshape(3, 3)
    T[:3, 3] = pos
    return T, np.vstack([jp[:, dadr], jr[:, dadr]])


class MinkKinematics:
    """A chain-compatible kinematics source backed by a ``mink.Configuration``.

    ``fk``, ``jacobian`` and ``fk_jacobian`` are computed by MuJoCo through mink
    (``Configuration.update`` then ``get_transform_frame_to_world`` and
    ``get_frame_jacobian``); mink's body-frame Jacobian ``ᴮJ`` is converted to ratectl's
    convention by ``J = blockdiag(R, R) · ᴮJ`` (world axes, linear part at the frame
    origin) and restricted to the chain's dofs. Limits, names, ``dof`` and every
    other attribute come from ``chain`` (by default imported from the same model with
    :func:`~ratectl.importers.chain_from_mjcf`), so a
    :class:`~ratectl.ResolvedRateController` can use this object in place of a chain.

    Joints of the model that are not in the chain keep their values in
    ``configuration.data.qpos`` (they are treated as fixed).

    Args:
        configuration: a ``mink.Configuration`` (or an ``MjModel``, wrapped in one).
        frame: name of the tool site or body.
        frame_type: ``"site"`` or ``"body"``.
        chain: the ratectl chain of the arm (joint names must match the model's).
    """

    def __init__(self, configuration, *, frame: str, frame_type: str = "site",
                 chain: Chain | None = None) -> None:
        import mink

        if isinstance(configuration, mujoco.MjModel):
            configuration = mink.Configuration(configuration)
        if not isinstance(configuration, mink.Configuration):
            raise InputError("configuration must be a mink.Configuration or a mujoco.MjModel, got "
                             f"{type(configuration).__name__}", argument="configuration",
                             value=configuration)
        self.configuration = configuration
        model = configuration.model
        _frame_id(model, frame, frame_type)
        if chain is None:
            chain = chain_from_mjcf(model, tip=frame)
        self.chain = chain
        self.frame = frame
        self.frame_type = frame_type
        self.qpos_indices, self.dof_indices = mjcf_joint_addresses(model, chain)

    def __getattr__(self, name):
        # everything that is not kinematics (limits, names, dof, ...) comes from the chain
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.__dict__["chain"], name)

    def __repr__(self) -> str:
        return (f"MinkKinematics(frame={self.frame!r}, frame_type={self.frame_type!r}, "
                f"chain={self.chain!r})")

    def update(self, q) -> None:
        """Set the chain joints to q (n,) and run mink's forward kinematics."""
        qfull = np.array(self.configuration.data.qpos, dtype=float)
        qfull[self.qpos_indices] = q
        self.configuration.update(qfull)

    def _single(self, q):
        self.update(q)
        cfg = self.configuration
        T = cfg.get_transform_frame_to_world(self.frame, self.frame_type).as_matrix()
        R = T[:3, :3]
        BJ = cfg.get_frame_jacobian(self.frame, self.frame_type)[:, self.dof_indices]
        J = np.empty_like(BJ)
        J[:3] = R @ BJ[:3]
        J[3:] = R @ BJ[3:]
        return T, J

    def fk_jacobian(self, q, *, frame: str = "base", point=None):
        """``(T_world_frame, J)`` from MuJoCo via mink; ``frame``/``point`` as in
        :meth:`ratectl.Chain.jacobian`."""
        from .kinematics import _post

        a = self.chain.check_q(q)
        batch = a.shape[:-1]
        flat = a.reshape(-1, a.shape[-1])
        Ts = np.empty((flat.shape[0], 4, 4))
        Js = np.empty((flat.shape[0], 6, flat.shape[1]))
        for k, qk in enumerate(flat):
            Ts[k], Js[k] = self._single(qk)
        T, J = Ts.reshape(batch + (4, 4)), Js.reshape(batch + Js.shape[1:])
        if frame != "base" or point is not None:
            from .kinematics import _check_frame

            _check_frame(frame)
            J = _post(J, T, frame, point)
        return T, J

    def fk(self, q) -> np.ndarray:
        """Pose of the frame in the world (..., 4, 4), from MuJoCo."""
        return self.fk_jacobian(q)[0]

    def jacobian(self, q, *, frame: str = "base", point=None) -> np.ndarray:
        """Geometric Jacobian (..., 6, n) in ratectl's conventions, from mink/MuJoCo."""
        return self.fk_jacobian(q, frame=frame, point=point)[1]

    def body_jacobian(self, q) -> np.ndarray:
        """mink's own body-frame Jacobian ᴮJ (6, n) at q (for cross-checks)."""
        self.update(q)
        return self.configuration.get_frame_jacobian(self.frame, self.frame_type)[:, self.dof_indices]


# ---------------------------------------------------------------------- mink limits
def mink_inequalities(limits, configuration, *, dt: float, dofs=None,
                      keep_inactive: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Velocity-level rows ``G q̇ ≤ h`` [rad/s or m/s on the left] from mink limits.

    mink's ``compute_qp_inequalities(configuration, dt)`` returns rows
    ``G Δq ≤ h`` on the *displacement* ``Δq = q̇·dt`` of one step. For
    ``ConfigurationLimit`` and ``VelocityLimit`` ``h`` is a displacement (gain ·
    distance to the joint limit [rad], ``vmax·dt``), so the velocity rows are
    ``G q̇ ≤ h/dt``.

    ``CollisionAvoidanceLimit`` is different: its bound ``gain·(d − d_min)/dt +
    relaxation`` is velocity-scaled although its row ``G = −n̂ᵀ(J₂ − J₁)`` multiplies a
    displacement, so read literally it lets one step close ``gain·(d − d_min)/dt``
    metres — 1/dt times more than intended (100× at 100 Hz). ratectl evaluates it
    with ``dt = 1`` so that ``h = gain·(d − d_min) + relaxation`` is the distance [m]
    the step may close, and divides by the real ``dt``:

        −ḋ = −n̂ᵀ(J₂ − J₁) q̇ ≤ gain·(d − d_min)/dt   [m/s]

    which keeps ``d_{k+1} − d_min ≥ (1 − gain)(d_k − d_min)`` to first order, so
    the distance never falls below ``d_min``. Rows whose bound is ``+inf`` (pairs
    farther apart than the detection distance) are dropped unless ``keep_inactive``
    (then they stay as zero rows with ``h = +inf``, so the number of rows is constant
    and a warm QP keeps its structure).

    Args:
        limits: mink ``Limit`` objects.
        configuration: the ``mink.Configuration``, already updated to the current q.
        dt: control period [s].
        dofs: dof indices of the chain joints in the model (columns kept, in chain
            order); default all dofs.

    Returns:
        ``(G, h)`` with ``G`` (m, n) and ``h`` (m,).
    """
    import mink

    if not (dt > 0 and math.isfinite(dt)):
        raise InputError(f"dt must be a positive time step [s], got {dt!r}", argument="dt", value=dt)
    nv = configuration.model.nv
    cols = np.arange(nv) if dofs is None else np.asarray(dofs, dtype=int)
    Gs, hs = [], []
    for lim in limits:
        if isinstance(lim, mink.CollisionAvoidanceLimit):
            c = lim.compute_qp_inequalities(configuration, 1.0)
        else:
            c = lim.compute_qp_inequalities(configuration, dt)
        if c.G is None or c.h is None:
            continue
        G = np.atleast_2d(np.asarray(c.G, dtype=float))
        h = np.asarray(c.h, dtype=float).ravel()
        keep = np.ones(h.shape, dtype=bool) if keep_inactive else np.isfinite(h)
        if not np.any(keep):
            continue
        Gs.append(G[keep][:, cols])
        hs.append(h[keep] / dt)
    if not Gs:
        return np.zeros((0, cols.size)), np.zeros(0)
    return np.vstack(Gs), np.concatenate(hs)


def geom_distance(model, data, pairs, *, distmax: float = 1.0) -> float:
    """Smallest signed distance [m] over geom pairs (names or ids) at ``data``'s state
    (``mj_geomDistance``; capped at ``distmax``)."""
    best = distmax
    geom = mujoco.mjtObj.mjOBJ_GEOM
    for g1, g2 in pairs:
        i1 = g1 if isinstance(g1, int | np.integer) else mujoco.mj_name2id(model, geom, g1)
        i2 = g2 if isinstance(g2, int | np.integer) else mujoco.mj_name2id(model, geom, g2)
        if i1 < 0 or i2 < 0:
            raise InputError(f"unknown geom in pair {(g1, g2)!r}", argument="pairs", value=(g1, g2))
        best = min(best, float(mujoco.mj_geomDistance(model, data, int(i1), int(i2), distmax, None)))
    return best


class MinkLimitedSolver:
    """Wrap a ratectl QP so that every solve also obeys mink limits.

    On ``solve(J, xi, *, q, dt, ...)`` the kinematics' mink configuration is updated to
    ``q``, the limits are turned into velocity rows by :func:`mink_inequalities` and
    passed to the wrapped solver as ``extra_inequalities=(G, h)`` (``G q̇ ≤ h``).

    Args:
        kinematics: the :class:`MinkKinematics` whose configuration the limits read.
        limits: mink ``Limit`` objects (e.g. ``mink.CollisionAvoidanceLimit``).
        solver: a solver accepting ``extra_inequalities`` (default ``ratectl.solvers.QP()``).
        drop_acceleration_on_conflict: when the QP is infeasible (the rows and the
            acceleration bounds |q̇ − q̇_prev| ≤ amax·dt conflict), solve again without the
            acceleration bounds — the distance comes first — and say so in
            ``result.info["acceleration_bounds_dropped"]``; False re-raises the
            :class:`~ratectl.errors.SolverError`.

    Choosing the gain: the rows let the distance close at most at ``gain·(d − d_min)/dt``
    [m/s], an exponential approach at rate ``gain/dt``; braking from a closing speed v
    then needs a Cartesian deceleration of about ``v·gain/dt``. Keep ``gain ≤ a·dt/v`` for
    the arm's deceleration a (e.g. gain 0.1 at 100 Hz for 0.25 m/s and 2.5 m/s²),
    otherwise the acceleration bounds cannot be met near obstacles.
    """

    method = "qp+mink"

    def __init__(self, kinematics: MinkKinematics, limits, *, solver=None,
                 drop_acceleration_on_conflict: bool = True) -> None:
        if not isinstance(kinematics, MinkKinematics):
            raise InputError("kinematics must be a ratectl.mujoco.MinkKinematics",
                             argument="kinematics", value=kinematics)
        if solver is None:
            from . import solvers

            solver = solvers.QP()
        self.kinematics = kinematics
        self.limits = tuple(limits)
        self.solver = solver
        self.drop_acceleration_on_conflict = bool(drop_acceleration_on_conflict)
        self.last_rows = (np.zeros((0, kinematics.chain.dof)), np.zeros(0))

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.__dict__["solver"], name)

    def solve(self, J, xi, *, limits=None, q=None, qd_prev=None, dt=None, **options):
        if q is None or dt is None:
            raise InputError("MinkLimitedSolver needs q and dt (the mink limits depend on the "
                             "configuration and the step)", argument="q", value=q)
        self.kinematics.update(q)
        G, h = mink_inequalities(self.limits, self.kinematics.configuration, dt=dt,
                                 dofs=self.kinematics.dof_indices, keep_inactive=True)
        extra = options.pop("extra_inequalities", None)
        if extra is not None:
            G = np.vstack([G, extra[0]])
            h = np.concatenate([h, extra[1]])
        self.last_rows = (G, h)
        try:
            return self.solver.solve(J, xi, limits=limits, q=q, qd_prev=qd_prev, dt=dt,
                                     extra_inequalities=(G, h), **options)
        except SolverError as exc:
            if qd_prev is None or not self.drop_acceleration_on_conflict:
                raise
            # the rows and the acceleration bounds conflict (the arm approaches faster than
            # it can brake within amax·dt): keeping the distance comes first
            res = self.solver.solve(J, xi, limits=limits, q=q, qd_prev=None, dt=dt,
                                    extra_inequalities=(G, h), **options)
            return dataclasses.replace(res, info={**res.info, "acceleration_bounds_dropped": str(exc)})



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


class _Reference:
    """Desired pose and feed-forward twist over time, from a path or a list of poses."""

    def __init__(self, path_or_targets, *, position_tolerance, orientation_tolerance) -> None:
        p = path_or_targets
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

    def at(self, t: float, T_actual: np.ndarray):
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
        while self.index < len(self.poses) - 1 and self.reached(T_actual):
            self.index += 1
        return self.poses[self.index], None, None

    def reached(self, T_actual) -> bool:
        from .spatial import pose_error

        e = pose_error(self.poses[self.index], T_actual)
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
    """What :func:`simulate` measured besides the execution record (arrays over steps)."""

    def __init__(self, *, qd_command, tau, min_distance, substeps, actuation, physics):
        self.qd_command = qd_command
        self.tau = tau
        self.min_distance = min_distance
        self.substeps = substeps
        self.actuation = actuation
        self.physics = physics

    def __repr__(self) -> str:
        return (f"SimulationLog(actuation={self.actuation!r}, physics={self.physics}, "
                f"substeps={self.substeps}, steps={len(self.qd_command)})")


def simulate(model_or_xml, chain: Chain, path_or_targets, q0, *, dt: float, controller=None,
             actuation: str = "position", frame: str = "tool", frame_type: str = "site",
             duration: float | None = None, settle: float = 0.0, physics: bool = True,
             distance_pairs=None, position_tolerance: float = 1e-3,
             orientation_tolerance: float = 1e-2, on_step=None):
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
            :func:`to_mjcf` and actuators of the requested kind.
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
        frame, frame_type: the tool site (or body) in the model.
        duration: run time [s]; default the path duration + ``settle``, or 10 s for targets
            (a run on targets ends when the last one is reached).
        settle: extra time after the path's end [s].
        physics: False for the kinematic reference run (no MuJoCo stepping).
        distance_pairs: optional geom pairs ``[(geom1, geom2), ...]`` whose smallest
            distance is recorded every step (``log.min_distance`` [m]).
        position_tolerance, orientation_tolerance: target-reached tolerances [m], [rad].
        on_step: optional callback ``on_step(k, model, data)`` after every period
            (e.g. to grab rendered frames).

    Returns:
        ``(execution, log)``: an :class:`~ratectl.execution.Execution` with the measured
        t, q, q̇, q̈, tool poses, errors, statuses and σ_min, and a :class:`SimulationLog`
        with the commanded q̇, the actuator forces and the recorded distances.
    """
    if actuation not in ACTUATIONS:
        raise InputError(f"actuation must be one of {ACTUATIONS}, got {actuation!r}",
                         argument="actuation", value=actuation)
    if not isinstance(chain, Chain):
        raise InputError(f"chain must be a ratectl.Chain, got {type(chain).__name__}", argument="chain",
                         value=chain)
    if not (isinstance(dt, int | float) and dt > 0 and math.isfinite(dt)):
        raise InputError(f"dt must be a positive control period [s], got {dt!r}", argument="dt", value=dt)
    if model_or_xml is None:
        model_or_xml = to_mjcf(chain, actuators=actuation, site=frame)
    model = compile_mjcf(model_or_xml)
    data = mujoco.MjData(model)
    qadr, dadr = mjcf_joint_addresses(model, chain)
    jids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in chain.joint_names]
    fid = _frame_id(model, frame, frame_type)
    nsub = int(round(dt / model.opt.timestep))
    if nsub < 1 or abs(nsub * model.opt.timestep - dt) > 1e-9 * max(dt, 1.0):
        raise InputError(f"dt = {dt} s must be a whole multiple of the model time step "
                         f"{model.opt.timestep} s", argument="dt", value=dt)
    if physics:
        act_ids, kp, kv = _actuators_for(model, jids, chain.joint_names, actuation)
        ff = np.where(kp > 0, kv / np.where(kp > 0, kp, 1.0), 0.0)
    q = chain.check_q(q0).astype(float).copy()
    if q.shape != (chain.dof,):
        raise InputError(f"q0 must have shape ({chain.dof},), got {q.shape}", argument="q0", value=q0)
    if controller is None:
        from .controller import ResolvedRateController

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
    data.qpos[qadr] = q
    data.qvel[:] = 0.0
    if physics:
        data.ctrl[act_ids] = q if actuation == "position" else 0.0
    mujoco.mj_forward(model, data)

    def tool_pose():
        T = np.eye(4)
        if frame_type == "site":
            T[:3, :3] = data.site_xmat[fid].reshape(3, 3)
            T[:3, 3] = data.site_xpos[fid]
        else:
            T[:3, :3] = data.xmat[fid].reshape(3, 3)
            T[:3, 3] = data.xpos[fid]
        return T

    ts, qs, qds, poses, desired, cmds, taus, dists, commands = [], [], [], [], [], [], [], [], []
    qd_meas = np.zeros(n)
    halted = ""
    for k in range(steps + 1):
        t = k * dt
        if physics:
            # mj_step leaves the kinematics of the state before its last integration:
            # refresh them so that the pose belongs to the measured q
            mujoco.mj_kinematics(model, data)
            q = np.array(data.qpos[qadr])
            qd_meas = np.array(data.qvel[dadr])
            T = tool_pose()
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
                data.qpos[qadr] = q
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
        if actuation == "velocity":
            data.ctrl[act_ids] = qd_cmd
        tau_acc = np.zeros(n)
        h = model.opt.timestep
        data.warning[_BADQACC].number = 0
        time0 = data.time
        for s in range(nsub):
            if actuation == "position":
                data.ctrl[act_ids] = q + qd_cmd * (s * h) + ff * qd_cmd
            mujoco.mj_step(model, data)
            tau_acc += data.actuator_force[act_ids]
        taus.append(tau_acc / nsub)
        if data.warning[_BADQACC].number > 0 or data.time < time0:
            halted = (f"the MuJoCo simulation became unstable at t = {t + dt:.4g} s (non-finite or huge "
                      "accelerations; MuJoCo reset the state); lower the servo gains or the time step")
            break
        if on_step is not None:
            on_step(k, model, data)
    log = SimulationLog(qd_command=np.array(cmds).reshape(-1, n), tau=np.array(taus).reshape(-1, n),
                        min_distance=np.array(dists), substeps=nsub, actuation=actuation,
                        physics=physics)
    ex = _execution(chain, ref, np.array(ts), np.array(qs), np.array(qds), np.array(poses),
                    np.array(desired), commands, dt=dt, halted=halted, physics=physics,
                    log_info={"actuation": actuation if physics else None, "substeps": nsub,
                              "timestep": float(model.opt.timestep)})
    return ex, log


def render_frames(model, data, chain: Chain, qs, *, width: int = 480, height: int = 360,
                  lookat=(0.0, 0.0, 0.3), distance: float = 2.0, azimuth: float = 135.0,
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
    """Fill an :class:`~ratectl.execution.Execution` from the recorded arrays."""
    from .execution import Execution
    from .spatial import pose_error

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
