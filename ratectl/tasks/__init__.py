"""Tasks: what the controller is asked to do, each with a priority (0 highest), a weight
within its level, a gain and a target.

* `Pose` (6 rows), `Position` (3), `Orientation` (3) — a link's frame (default the tool);
* `Posture` — joint positions;
* `Objective`, `JointCentring`, `Manipulability` — the null-space objectives as tasks.

Each gives its rows ``A q̇ ≈ b`` at a configuration (`Task.rows`, `TaskRows`);
`ratectl.solvers.priority` solves levels of them with strict priorities under the limits.
"""


from .base import FrameTask, Task, TaskRows
from .objective import JointCentring, Manipulability, Objective
from .orientation import Orientation
from .pose import Pose
from .position import Position
from .posture import Posture

__all__ = ["Task", "TaskRows", "FrameTask", "Pose", "Position", "Orientation", "Posture", "Objective",
           "JointCentring", "Manipulability"]
