"""Write a chain as an MJCF model whose kinematics equal ratectl's to rounding.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from ...errors import InputError
from ...io.mjcf import compile_mjcf as _compile_mjcf
from ...model import Chain
from ...spatial import quat_from_rotation

__all__ = ['to_mjcf', 'compile_mjcf']


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
        link_contype: collision type bits of the link geoms.
        link_conaffinity: collision affinity bits of the link geoms.
        floor: add a visual-only floor plane at z = 0 (for rendering; it collides with
            nothing).

    Returns:
        The MJCF document as a string.
    """
    kv = _check_export_options(chain, actuators=actuators, radius=radius, kp=kp, kv=kv,
                               timestep=timestep, density=density, armature=armature, damping=damping)
    names = list(chain.joint_names)
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
    lines += _obstacle_lines(obstacles)
    lines += _body_lines(chain, radius=radius, site=site, gravity_compensation=gravity_compensation)
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


def _check_export_options(chain, *, actuators, radius, kp, kv, timestep, density, armature,
                          damping) -> float:
    """Validate `to_mjcf`'s options; returns the velocity gain kv (its default filled in)."""
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
    names = list(chain.joint_names)
    if len(set(names)) != len(names):
        raise InputError(f"joint names must be unique for MJCF, got {names}", argument="chain",
                         value=names)
    if kv is None:
        kv = 2.0 * math.sqrt(kp * max(armature, 1e-3)) if actuators == "position" else 3000.0 * max(
            armature, 1e-3)
    return float(kv)


def _obstacle_lines(obstacles) -> list[str]:
    lines = []
    for k, ob in enumerate(obstacles):
        if not isinstance(ob, Mapping):
            raise InputError(f"obstacles[{k}] must be a mapping of MJCF geom attributes, got "
                             f"{type(ob).__name__}", argument="obstacles", value=ob)
        attrs = {"name": f"obstacle{k}", "contype": 1, "conaffinity": 1, "rgba": "0.85 0.3 0.25 0.6"}
        attrs.update(ob)
        text = " ".join(f'{key}="{_xml_escape(_attr_text(v))}"' for key, v in attrs.items())
        lines.append(f"    <geom {text}/>")
    return lines


def _body_lines(chain: Chain, *, radius: float, site: str, gravity_compensation: bool) -> list[str]:
    """The nested link bodies: body i at ``post_{i−1} · pre_i``, its joint about z, the tool site."""
    joints = chain.joints
    n = len(joints)
    names = chain.joint_names
    lines = []
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
    return lines


def compile_mjcf(model_or_xml: mujoco.MjModel | str | os.PathLike[str] | None) -> mujoco.MjModel:
    """An ``MjModel`` from an ``MjModel`` (returned as is), MJCF text or a file path.

    Text and files go through `ratectl.Chain.from_mjcf`'s safety
    checks (no DTD/entities, mesh files ignored).
    """
    return _compile_mjcf(model_or_xml)
