"""Shared timing helpers for the benchmark scripts (in-process, median of many calls)."""

from __future__ import annotations

import statistics
import time

CLOCKS = {"wall": time.perf_counter, "cpu": time.thread_time}
"""``wall``: elapsed time; ``cpu``: this thread's CPU time, which leaves out the time other
processes hold the core — steadier ratios on a shared machine (caches are still shared)."""


def median_us(fn, *, number: int = 2000, repeat: int = 15, clock: str = "wall") -> float:
    """Median over ``repeat`` rounds of the mean time per call [µs] of ``number`` calls."""
    now = CLOCKS[clock]
    fn()  # warm up (kernel compilation, caches)
    rounds = []
    for _ in range(repeat):
        t0 = now()
        for _ in range(number):
            fn()
        rounds.append((now() - t0) / number)
    return statistics.median(rounds) * 1e6


def median_s(fn, *, repeat: int = 7, clock: str = "wall") -> float:
    """Median time of one call [s] over ``repeat`` calls (after one warm-up call)."""
    now = CLOCKS[clock]
    fn()
    rounds = []
    for _ in range(repeat):
        t0 = now()
        fn()
        rounds.append(now() - t0)
    return statistics.median(rounds)
