"""Paths through exact singularities, built so that their tangent lies in the range of J."""

import pytest
from singular_paths import UR5E_WRIST_Q, UR5E_WRIST_QD, crossing_line

import ratectl as rc


@pytest.fixture(scope="session")
def ur5e_exact_wrist():
    """(arm, line, q0): a UR5e line through the wrist singularity q5 = 0 itself."""
    arm = rc.robots.ur5e()
    line, q0 = crossing_line(arm, UR5E_WRIST_Q, UR5E_WRIST_QD, half=0.1)
    return arm, line, q0
