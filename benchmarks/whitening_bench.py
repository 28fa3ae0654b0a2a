"""The whitener's band product (``make bench``'s ``whitening`` section, issue 42): the
pairs of lanes every processor can take against the wider ways this one has (AVX2,
AVX-512: four rows of the band at a time), on the whitener of a PMU-style recording, for
the batches of residual rows the optimisers whiten (8 to 300). Each is checked against
scipy's CSR product bit for bit; scipy's time is printed beside them.

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
    ways = band._ways(lib)
    print(f"whitening: the band product of a PMU-style recording's whitener ({b.n} samples, "
          f"{lengths.mean():.0f} coefficients a row, up to {lengths.max()}); this processor takes "
          f"{band.WAYS[ways[-1]]}; time per product, and the pairs' time over each way's")
    print("  residual rows   scipy CSR   " + "".join(f"{band.WAYS[w]:>16s}" for w in ways) + "   same numbers")
    for m in (8, 32, 64, 128, 300):
        r = np.random.default_rng(m).standard_normal((m, b.n)) * 1e-3
        expected = np.asarray((w.W @ r.T).T)
        t_scipy = _best(lambda: w.W @ r.T, 3, 2)
        times, same = {}, True
        for way in ways:
            same &= np.array_equal(b.rows_by(lib, way, r), expected)
            times[way] = _best(lambda: b.rows_by(lib, way, r))
        cells = "".join(f"{1e3 * times[way]:7.2f} ms x{times[1] / times[way]:4.2f}" for way in ways)
        print(f"  {m:13d}   {1e3 * t_scipy:6.2f} ms   {cells}   {'yes' if same else 'NO'}")
