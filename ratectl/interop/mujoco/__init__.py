"""MuJoCo and mink interop: export to MJCF, MuJoCo/mink kinematics, mink limits, simulation.

* `to_mjcf` writes a chain as an MJCF model (capsule links, hinge/slide joints
  with limits, a ``tool`` site, optional position/velocity actuators and obstacles)
  whose kinematics equal ratectl's to rounding.
* `mujoco_fk_jacobian` evaluates a MuJoCo model's frame pose and Jacobian in
  ratectl's conventions.
* `MinkKinematics` is a chain-compatible kinematics source backed by a
  ``mink.Configuration`` (MuJoCo's kinematics), for `ratectl.ResolvedRateController`.
* `mink_inequalities` and `MinkLimitedSolver` turn mink limits — in
  particular ``mink.CollisionAvoidanceLimit`` — into velocity-level inequality rows
  ``G q̇ ≤ h`` for ratectl's QP.
* `simulate` closes the loop through MuJoCo's physics and records an
  `Execution` like `ratectl.follow`;
  `render_frames` renders configurations offscreen; `MujocoDriver` is a
  MuJoCo model behind the `ratectl.drivers.Driver` protocol, for `ratectl.run`.

``mujoco`` and ``mink`` (the ``mujoco`` extra: ``pip install -e ".[mujoco]"``) are imported here only;
the rest of ratectl never needs them.

Conventions (ratectl's): Jacobian rows ``[v; ω]`` in world axes with the linear part
at the frame origin. MuJoCo's ``mj_jacSite``/``mj_jacBody`` already return exactly
that (``jacp`` = world-frame velocity of the frame origin, ``jacr`` = world angular
velocity). mink's ``Configuration.get_frame_jacobian`` returns the *body* (local)
Jacobian ``ᴮJ = blockdiag(Rᵀ, Rᵀ) · [jacp; jacr]`` with ``R`` the frame's world
rotation, so ratectl's Jacobian is ``J = blockdiag(R, R) · ᴮJ``.
"""


from .driver import MujocoDriver
from .export import compile_mjcf, to_mjcf
from .kinematics import MinkKinematics, mujoco_fk_jacobian
from .limits import MinkLimitedSolver, geom_distance, mink_inequalities
from .simulation import ACTUATIONS, SimulationLog, render_frames, simulate

__all__ = ["to_mjcf", "compile_mjcf", "mujoco_fk_jacobian", "MinkKinematics", "mink_inequalities",
           "MinkLimitedSolver", "geom_distance", "simulate", "SimulationLog", "render_frames", "ACTUATIONS",
           "MujocoDriver"]
