import os

import numpy as np
import pytest
from hypothesis import settings

import ratectl as rc

# Property tests are derandomised by default so that a run is reproducible (CI included);
# HYPOTHESIS_PROFILE=explore draws fresh examples each run to search for new failures.
settings.register_profile("default", derandomize=True, print_blob=True)
settings.register_profile("explore", derandomize=False, max_examples=500, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


BUILTIN_ARMS = ["ur5e", "panda", "puma560", "stanford", "iiwa7", "rpr", "planar2r"]


@pytest.fixture(params=BUILTIN_ARMS)
def arm(request):
    """Every built-in arm, freshly built."""
    return rc.robots.BUILTIN[request.param]()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
