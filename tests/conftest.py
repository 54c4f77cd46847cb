import math
import os

import numpy as np
import pytest
from hypothesis import settings

import ratectl as rc

# Property tests are derandomised by default so that a run is reproducible (CI included);
# HYPOTHESIS_PROFILE=explore draws fresh examples each run to search for new failures.
settings.register_profile("default", derandomize=True, deadline=None, print_blob=True)
settings.register_profile("explore", derandomize=False, max_examples=500, deadline=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


def pytest_addoption(parser):
    # for tests/fuzz (a subdirectory conftest cannot add options): long runs
    parser.addoption("--soak", action="store_true", default=False,
                     help="fuzz suite: many more examples and fresh random draws (long run)")


BUILTIN_ARMS = ["ur5e", "panda", "puma560", "stanford", "iiwa7", "rpr", "planar2r"]


@pytest.fixture(params=BUILTIN_ARMS)
def arm(request):
    """Every built-in arm, freshly built."""
    return rc.robots.BUILTIN[request.param]()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


# The acceptance line of issue #5: UR5e, 0.3 m at 0.2 m/s and constant orientation, whose
# closest approach to the wrist singularity is |q5| = 0.01 rad (at WRIST_Q_CLOSEST).
WRIST_Q_CLOSEST = np.array([0.0, -2.0, -1.6, -1.2, 0.01, 0.0])
WRIST_DIRECTION = np.array([math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0])
WRIST_HALF = 0.15  # m on each side of the closest approach


@pytest.fixture(scope="session")
def ur5e_wrist_line():
    """(arm, line, q0): the line through the tool pose of WRIST_Q_CLOSEST and its start q
    on the same branch (integrated back from WRIST_Q_CLOSEST)."""
    from ratectl.planning import joint_path

    arm = rc.robots.ur5e()
    T0 = arm.fk(WRIST_Q_CLOSEST)
    Ta, Tb = T0.copy(), T0.copy()
    Ta[:3, 3] -= WRIST_HALF * WRIST_DIRECTION
    Tb[:3, 3] += WRIST_HALF * WRIST_DIRECTION
    back = joint_path(arm, rc.paths.Line(T0, Ta, speed=0.2, acceleration=1.0), WRIST_Q_CLOSEST)
    assert back.complete
    return arm, rc.paths.Line(Ta, Tb, speed=0.2, acceleration=1.0), back.q[-1]
