"""Collision avoidance: distances between the arm's links and to obstacles, from the URDF's
own collision geometry, computed by coal (the ``collision`` extra:
``pip install 'ratectl[collision]'``), entering the solve as velocity-damper rows
``G q̇ ≤ h`` (see `ratectl.collision.model`).

* `SelfCollision` — the arm's links (adjacent pairs, and pairs that overlap in the default
  configuration, left out and listed);
* `Obstacles` — the links against `Sphere`, `Box` and `Mesh` obstacles in the base frame;
* `CollisionModel`, `CollisionRows` — what both are and give.

Importing this package does not import coal; building a model does.
"""


from .model import CollisionModel, CollisionRows, Shape
from .self_collision import Obstacles, SelfCollision
from .shapes import Box, Mesh, Sphere

__all__ = ["SelfCollision", "Obstacles", "CollisionModel", "CollisionRows", "Shape", "Sphere", "Box", "Mesh"]
