"""Print the Jacobian of a built-in arm (the smallest possible ratectl program)."""

import numpy as np

import ratectl as rc

arm = rc.robots.ur5e()
q = np.array([0.0, -1.2, 1.4, -1.8, -1.57, 0.3])
T, J = arm.fk_jacobian(q)
np.set_printoptions(precision=4, suppress=True)
print(arm.describe())
print("\ntool pose T_world_tool at q =", q)
print(T)
print("\ngeometric Jacobian (rows v; ω, base axes, at the tool origin)")
print(J)
