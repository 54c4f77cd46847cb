"""Shared timing helpers for the benchmark scripts (in-process, median of many calls)."""

from __future__ import annotations

import statistics
import time


def median_us(fn, *, number: int = 2000, repeat: int = 15) -> float:
    """Median over ``repeat`` rounds of the mean time per call [µs] of ``number`` calls."""
    fn()  # warm up (kernel compilation, caches)
    rounds = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        rounds.append((time.perf_counter() - t0) / number)
    return statistics.median(rounds) * 1e6


def median_s(fn, *, repeat: int = 7) -> float:
    """Median wall time of one call [s] over ``repeat`` calls (after one warm-up call)."""
    fn()
    rounds = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        rounds.append(time.perf_counter() - t0)
    return statistics.median(rounds)
