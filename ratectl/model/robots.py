"""Built-in arm models with their published kinematic parameters.

Each function returns a fresh `Chain`. Position and velocity
limits are the manufacturer's (or the cited source's) where published; where a
source gives no acceleration or jerk limits the values here are conservative
ratectl defaults and the docstring says so.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ModelError
from .chain import Chain
from .joints import DH, MDH

__all__ = ["ur5e", "panda", "puma560", "stanford", "iiwa7", "rpr", "planar2r", "BUILTIN"]

_PI = math.pi
_D = math.radians


def ur5e() -> Chain:
    """Universal Robots UR5e, standard DH, tool = flange.

    Source: Universal Robots, "DH parameters for calculations of kinematics and
    dynamics" (universal-robots.com support article, UR5e row):
    a = [0, −0.425, −0.3922, 0, 0, 0] m, d = [0.1625, 0, 0, 0.1333, 0.0997, 0.0996] m,
    α = [π/2, 0, 0, π/2, −π/2, 0].
    Limits: ±2π on every joint except the elbow (±π), 180 °/s = π rad/s on every joint
    (UR5e technical specifications; ``ur_description`` joint_limits.yaml).
    Acceleration (10 rad/s²) and jerk (100 rad/s³) are ratectl defaults — UR
    publishes none.
    """
    a = [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0]
    d = [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996]
    alpha = [_PI / 2, 0.0, 0.0, _PI / 2, -_PI / 2, 0.0]
    names = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]
    rows = [
        DH(a=a[i], alpha=alpha[i], d=d[i], qlim=(-_PI, _PI) if i == 2 else (-2 * _PI, 2 * _PI),
           vmax=_PI, amax=10.0, jmax=100.0, name=names[i])
        for i in range(6)
    ]
    return Chain.from_dh(rows, name="UR5e")


def panda(*, flange: bool = True) -> Chain:
    """Franka Emika Panda (FR3-compatible kinematics), modified (Craig) DH.

    Source: Franka Control Interface documentation, "Robot and interface
    specifications" (Denavit–Hartenberg parameters and joint limits):

    ====  ========  =======  ========
    i     a_{i-1}   d_i      α_{i-1}
    ====  ========  =======  ========
    1     0         0.333    0
    2     0         0        −π/2
    3     0         0.316    π/2
    4     0.0825    0        π/2
    5     −0.0825   0.384    −π/2
    6     0         0        π/2
    7     0.088     0        π/2
    F     0         0.107    0
    ====  ========  =======  ========

    Position limits q_min/q_max, velocity (2.175, 2.61 rad/s), acceleration
    (15, 7.5, 10, 12.5, 15, 20, 20 rad/s²) and jerk (7500 … 10000 rad/s³) limits are
    Franka's. ``flange=True`` adds the flange frame F as the tool (Tz(0.107)).
    """
    a = [0.0, 0.0, 0.0, 0.0825, -0.0825, 0.0, 0.088]
    d = [0.333, 0.0, 0.316, 0.0, 0.384, 0.0, 0.0]
    alpha = [0.0, -_PI / 2, _PI / 2, _PI / 2, -_PI / 2, _PI / 2, _PI / 2]
    lo = [-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]
    hi = [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]
    vmax = [2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61]
    amax = [15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]
    jmax = [7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]
    rows = [MDH(a=a[i], alpha=alpha[i], d=d[i], qlim=(lo[i], hi[i]), vmax=vmax[i],
                amax=amax[i], jmax=jmax[i], name=f"panda_joint{i + 1}") for i in range(7)]
    tool = None
    if flange:
        tool = np.eye(4)
        tool[2, 3] = 0.107
    return Chain.from_mdh(rows, tool=tool, name="Panda")


def puma560() -> Chain:
    """Unimation PUMA 560, standard DH (the kinematic model of Corke's Robotics Toolbox).

    Source: P. Corke and B. Armstrong-Hélouvry, "A search for consensus among model
    parameters reported for the PUMA 560 robot", ICRA 1994; the toolbox model
    ``mdl_puma560``: a = [0, 0.4318, 0.0203, 0, 0, 0] m, d = [0, 0, 0.15005, 0.4318, 0, 0] m,
    α = [π/2, 0, −π/2, π/2, −π/2, 0]; limits [−160, 160], [−45, 225], [−225, 45],
    [−110, 170], [−100, 100], [−266, 266] degrees. Velocity (≈ 2–4 rad/s),
    acceleration and jerk limits are ratectl defaults; the sources give none.
    """
    a = [0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0]
    d = [0.0, 0.0, 0.15005, 0.4318, 0.0, 0.0]
    alpha = [_PI / 2, 0.0, -_PI / 2, _PI / 2, -_PI / 2, 0.0]
    qlim = [(-160, 160), (-45, 225), (-225, 45), (-110, 170), (-100, 100), (-266, 266)]
    vmax = [2.0, 2.0, 2.0, 4.0, 4.0, 4.0]
    rows = [DH(a=a[i], alpha=alpha[i], d=d[i], qlim=(_D(qlim[i][0]), _D(qlim[i][1])),
               vmax=vmax[i], amax=10.0, jmax=100.0, name=f"joint{i + 1}") for i in range(6)]
    return Chain.from_dh(rows, name="PUMA 560")


def stanford() -> Chain:
    """Stanford arm (Scheinman), standard DH, prismatic joint 3.

    Source: R. P. Paul, *Robot Manipulators: Mathematics, Programming and Control*,
    MIT Press 1981, with the dimensions of Corke's toolbox model ``mdl_stanford``:
    d1 = 0.412 m, d2 = 0.154 m, joint 3 prismatic with θ3 = −π/2, a3 = 0.0203 m and
    travel 0.3048–1.27 m (12–50 in), d6 = 0.263 m; α = [−π/2, π/2, 0, −π/2, π/2, 0].
    Rotary limits ±170° and all velocity/acceleration/jerk limits are ratectl
    defaults.
    """
    L = 170.0
    rows = [
        DH(d=0.412, alpha=-_PI / 2, qlim=(_D(-L), _D(L)), name="joint1"),
        DH(d=0.154, alpha=_PI / 2, qlim=(_D(-L), _D(L)), name="joint2"),
        DH(theta=-_PI / 2, a=0.0203, alpha=0.0, joint="prismatic", qlim=(0.3048, 1.27),
           name="joint3"),
        DH(alpha=-_PI / 2, qlim=(_D(-L), _D(L)), name="joint4"),
        DH(alpha=_PI / 2, qlim=(_D(-L), _D(L)), name="joint5"),
        DH(d=0.263, qlim=(_D(-L), _D(L)), name="joint6"),
    ]
    vmax = [1.5, 1.5, 0.5, 3.0, 3.0, 3.0]
    rows = [DH(a=r.a, alpha=r.alpha, d=r.d, theta=r.theta, joint=r.joint, qlim=r.qlim,
               vmax=vmax[k], amax=10.0 if r.joint == "revolute" else 2.0,
               jmax=100.0 if r.joint == "revolute" else 20.0, name=r.name)
            for k, r in enumerate(rows)]
    return Chain.from_dh(rows, name="Stanford arm")


def iiwa7() -> Chain:
    """KUKA LBR iiwa 7 R800, standard DH, 7 joints (redundant), tool = flange.

    Source: KUKA, *LBR iiwa 7 R800 specification* (link lengths 0.340, 0.400, 0.400,
    0.126 m to the media flange; axis ranges ±170°, ±120°, ±170°, ±120°, ±170°, ±120°,
    ±175°; speeds 98, 98, 100, 130, 140, 180, 180 °/s), with the DH frame
    assignment α = [−π/2, π/2, π/2, −π/2, −π/2, π/2, 0] used in the iiwa literature
    (e.g. Faria et al., "Position-based kinematics for 7-DoF serial manipulators",
    Mechanism and Machine Theory 2018). Acceleration and jerk limits are ratectl
    defaults.
    """
    d = [0.340, 0.0, 0.400, 0.0, 0.400, 0.0, 0.126]
    alpha = [-_PI / 2, _PI / 2, _PI / 2, -_PI / 2, -_PI / 2, _PI / 2, 0.0]
    lim = [170, 120, 170, 120, 170, 120, 175]
    vel = [98, 98, 100, 130, 140, 180, 180]
    rows = [DH(d=d[i], alpha=alpha[i], qlim=(_D(-lim[i]), _D(lim[i])), vmax=_D(vel[i]),
               amax=10.0, jmax=100.0, name=f"iiwa_joint_{i + 1}") for i in range(7)]
    return Chain.from_dh(rows, name="iiwa7")


def rpr(*, d1: float = 0.4, d3: float = 0.1, q2_range: tuple[float, float] = (0.1, 0.8)) -> Chain:
    """The RPR arm of the worked example in the documentation, standard DH.

    ====  =========  ==  ====  ====  =====
    i     type       θ   d     a     α
    ====  =========  ==  ====  ====  =====
    1     revolute   q1  d1    0     +90°
    2     prismatic  0   q2    0     0
    3     revolute   q3  d3    0     0
    ====  =========  ==  ====  ====  =====

    Args:
        d1: height of joint 2's frame above the base [m].
        d3: constant offset of the tool along z2 [m].
        q2_range: travel of the prismatic joint [m].
    """
    for name, v in (("d1", d1), ("d3", d3)):
        if not math.isfinite(v):
            raise ModelError(f"{name} must be finite, got {v!r}", field=name, value=v)
    rows = [
        DH(d=d1, alpha=_PI / 2, qlim=(-_PI, _PI), vmax=2.0, amax=10.0, jmax=100.0, name="q1"),
        DH(joint="prismatic", qlim=q2_range, vmax=0.5, amax=2.0, jmax=20.0, name="q2"),
        DH(d=d3, qlim=(-_PI, _PI), vmax=2.0, amax=10.0, jmax=100.0, name="q3"),
    ]
    return Chain.from_dh(rows, name="RPR example")


def planar2r(*, l1: float = 1.0, l2: float = 1.0) -> Chain:
    """Planar two-link arm (link lengths l1, l2 [m]), standard DH, moving in the xy plane."""
    rows = [DH(a=l1, vmax=2.0, amax=10.0, jmax=100.0), DH(a=l2, vmax=2.0, amax=10.0, jmax=100.0)]
    return Chain.from_dh(rows, name="planar 2R")


#: The built-in arms by command-line name.
BUILTIN = {
    "ur5e": ur5e,
    "panda": panda,
    "puma560": puma560,
    "stanford": stanford,
    "iiwa7": iiwa7,
    "rpr": rpr,
    "planar2r": planar2r,
}
