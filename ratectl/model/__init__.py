"""The robot model: joints (DH, modified DH, general), the chain, built-in robots.

* `joints` — `DH`, `MDH` table rows and the general `Joint`;
* `chain` — `Chain`: joints, base and tool, limits, kinematics methods;
* `robots` — UR5e, Panda, PUMA 560, Stanford, iiwa7, RPR, planar 2R.
"""

from . import robots
from .chain import Chain
from .joints import DH, JOINT_KINDS, MDH, Joint

__all__ = ["DH", "MDH", "Joint", "Chain", "JOINT_KINDS", "robots"]
