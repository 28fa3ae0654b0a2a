"""The one timing rule of the benchmarks: the best of a few runs after a warm-up (library
loads, a first CVODE allocation), since on a shared machine the minimum is what repeats."""

from __future__ import annotations

import time


def best(fn, repeats: int = 5) -> float:
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)
