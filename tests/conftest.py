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


@pytest.fixture(scope="session")
def ur5e_wrist_line():
    """(arm, line, q0): the UR5e line past the wrist singularity of ``ratectl demo``
    (`ratectl.cli.demo.wrist_line`, the one definition shared by the demo, the docs,
    the benchmarks and these tests)."""
    from ratectl.cli.demo import wrist_line

    sc = wrist_line("ur5e")
    return sc.chain, sc.path, sc.q0
