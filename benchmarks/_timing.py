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


def machine() -> str:
    """Date, CPU model, cores and load average: the line a results table in the docs needs."""
    import datetime
    import os
    import platform

    load = ", ".join(f"{x:.1f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "n/a"
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return (f"{datetime.date.today().isoformat()} ({cpu}, {os.cpu_count()} cores, load average "
            f"{load} at the end; Python {platform.python_version()})")


def update_docs(script: str, text: str, path: str | None = None) -> None:
    """Write ``text`` into docs/benchmarks.md (or ``path``) between the markers
    ``<!-- {script} --update-docs: begin -->`` and ``<!-- {script} --update-docs: end -->``:
    each benchmark script owns one block of the page and rewrites it with ``--update-docs``."""
    import os

    if path is None:
        path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "benchmarks.md")
    begin = f"<!-- {script} --update-docs: begin -->"
    end = f"<!-- {script} --update-docs: end -->"
    with open(path, encoding="utf-8") as f:
        doc = f.read()
    head, sep, rest = doc.partition(begin)
    _old, sep2, tail = rest.partition(end)
    if not sep or not sep2:
        raise SystemExit(f"{path} has no {begin} … {end} block")
    with open(path, "w", encoding="utf-8") as f:
        f.write(f"{head}{begin}\n{text}{end}{tail}")
    print(f"wrote the table into {path}")
