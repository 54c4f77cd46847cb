"""Planning: inverse kinematics, joint paths along Cartesian paths, the path-speed governor.

* `ik` — `ik`, damped Newton IK (the package's one IK);
* `joint_path` — q(s) along a path, corrected onto it;
* `topp` — admissible path speed from joint limits;
* `governor` — `Governor`, the jerk-limited progress plan.
"""

from .governor import Governor, GovernorPlan, plan
from .ik import IKResult, ik
from .joint_path import JointPath, joint_path

__all__ = ["ik", "IKResult", "Governor", "GovernorPlan", "JointPath", "joint_path", "plan"]
