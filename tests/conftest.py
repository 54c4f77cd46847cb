import numpy as np
import pytest

import ratectl as rc

BUILTIN_ARMS = ["ur5e", "panda", "puma560", "stanford", "iiwa7", "rpr", "planar2r"]


@pytest.fixture(params=BUILTIN_ARMS)
def arm(request):
    """Every built-in arm, freshly built."""
    return rc.robots.BUILTIN[request.param]()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
