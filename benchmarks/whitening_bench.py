"""The whitener's band product (``make bench``'s ``whitening`` section, issue 42): the
pairs of lanes every processor takes against the way this one takes (AVX-512, four
rows of the band at a time, where it has them), on the whitener of a PMU-style
recording, for the batches of residual rows the optimisers whiten (8 to 300). Both are
checked against scipy's CSR product bit for bit; scipy's time is printed beside them.

The recording: 120 s at 30 frames/s with 3 ms of jitter and three dropped frames, the
recorder's noise white plus a slow component, with the derived ROCOF's noise (a
Savitzky-Golay derivative of the frequency's own noise), so that each row of the band
holds a couple of hundred coefficients, as on the committed ANDES events.
"""

from __future__ import annotations

import time

import numpy as np

DT = 1 / 30


def _whitener():
    from rapid_cosim.noise import RecorderNoise
    from rapid_cosim.noise.timed import DerivedNoise, TimedWhitener
    from rapid_cosim.simulator.rocof import rocof_operator

    rng = np.random.default_rng(0)
    t = np.delete(np.arange(3600) * DT + rng.uniform(-0.003, 0.003, 3600), [400, 401, 1500])
    derived = DerivedNoise(RecorderNoise(0.3e-3, ((0.9e-3, 0.15),), DT), (1.0,), time=t,
                           matrix=(0.2 * rocof_operator(t, breaks=(60.0,)).matrix).tocsr())
    return TimedWhitener(RecorderNoise(0.9e-3, ((1.2e-3, 0.6),), DT), t, derived, np.arange(t.size))


def _best(fn, repeats: int = 5, inner: int = 5) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        times.append((time.perf_counter() - t0) / inner)
    return min(times)


def bench_whitening() -> None:
    from rapid_cosim.noise import band

    lib = band.library()
    w = _whitener()
    b = w._band
    if lib is None or b is None:
        print("whitening: the band kernel is not in use here (no C compiler, or it differs from scipy)")
        return
    lengths = np.diff(b.ptr)
    print(f"whitening: the band product of a PMU-style recording's whitener ({b.n} samples, "
          f"{lengths.mean():.0f} coefficients a row, up to {lengths.max()}); this processor: "
          f"{'AVX-512, four rows at a time' if band.wide() else 'pairs of lanes'}")
    print("  residual rows   scipy CSR    pairs of lanes   this processor's way   pairs / this   same numbers")
    args = (b.ptr.ctypes.data, b.first.ctypes.data, b.data.ctypes.data)
    for m in (8, 32, 64, 128, 300):
        r = np.random.default_rng(m).standard_normal((m, b.n)) * 1e-3
        xT = np.ascontiguousarray(r.T)
        pairs, this = np.empty((b.n, m)), np.empty((b.n, m))
        expected = np.asarray((w.W @ r.T).T)
        t_scipy = _best(lambda: w.W @ r.T, 3, 2)
        t_pairs = _best(lambda: lib.rc_band_rows_pairs(m, b.n, *args, xT.ctypes.data, pairs.ctypes.data))
        t_this = _best(lambda: lib.rc_band_rows(m, b.n, *args, xT.ctypes.data, this.ctypes.data))
        same = np.array_equal(pairs.T, expected) and np.array_equal(this.T, expected)
        print(f"  {m:13d}   {1e3 * t_scipy:7.2f} ms   {1e3 * t_pairs:10.2f} ms   {1e3 * t_this:16.2f} ms   "
              f"{'x' + format(t_pairs / t_this, '.2f'):>13s}   {'yes' if same else 'NO'}")
