"""The fuzz suite: hypothesis properties over kinematics, solvers, importers and paths.

Every property calls the library on generated (often hostile) inputs and checks what
the library promises: a finite answer or a ratectl error (never a foreign exception),
limits held to 1e-6 relative, QP answers equal to an exact reference, hostile files
refused quickly without reading outside files.

Budget: the default run is bounded (the whole directory in ~15 s on two cores);
``pytest tests/fuzz --soak`` (or ``RATECTL_FUZZ_SOAK=1``) multiplies the examples by
``SOAK_FACTOR`` and draws fresh random examples (``RATECTL_SOAK_FACTOR`` overrides the
factor). The number of library calls made and the failures seen are printed at the end
of the run (``fuzz: ...``).
"""

from __future__ import annotations

import collections
import os

import pytest
from hypothesis import HealthCheck, settings

SOAK_FACTOR = int(os.environ.get("RATECTL_SOAK_FACTOR", "40"))

_COUNTS: collections.Counter = collections.Counter()


class Fuzz:
    """Budget and call counter handed to every fuzz test."""

    def __init__(self, soak: bool) -> None:
        self.soak = soak

    def examples(self, n: int) -> int:
        """The number of hypothesis examples for a property whose default budget is ``n``."""
        return n * SOAK_FACTOR if self.soak else n

    def loops(self, n: int) -> int:
        """The number of iterations of a plain loop whose default budget is ``n``."""
        return n * SOAK_FACTOR if self.soak else n

    def settings(self, n: int, **kw) -> settings:
        """hypothesis settings with the budget: no deadline (two shared cores), and in soak
        mode fresh random draws instead of the derandomised default."""
        return settings(max_examples=self.examples(n), deadline=None, derandomize=not self.soak,
                        suppress_health_check=list(HealthCheck), database=None, **kw)

    def count(self, what: str, k: int = 1) -> None:
        """Record ``k`` library calls of kind ``what`` (reported at the end of the run)."""
        _COUNTS[what] += k


@pytest.fixture
def fuzz(request) -> Fuzz:
    return Fuzz(_soak(request.config))


def _soak(config) -> bool:
    """The long mode: ``--soak`` or the environment variable ``RATECTL_FUZZ_SOAK=1``."""
    env = os.environ.get("RATECTL_FUZZ_SOAK", "")
    return bool(config.getoption("--soak", default=False)) or env not in ("", "0")


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if not _COUNTS:
        return
    failures = len(terminalreporter.stats.get("failed", []))
    total = sum(_COUNTS.values())
    parts = ", ".join(f"{k} {v}" for k, v in sorted(_COUNTS.items()))
    mode = "soak" if _soak(config) else "default"
    terminalreporter.write_line(f"fuzz ({mode}): {total} library calls ({parts}); failures: {failures}")
