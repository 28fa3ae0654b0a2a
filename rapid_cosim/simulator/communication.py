"""A Co-Simulation batch's communication plan: where the FMU's own solver is stopped, what
inputs it is given there and how outputs are read onto the output times. Made once per
prepared batch, in Python; the C driver (``cosim.c``) and the fmpy loop
(:mod:`.cosim`) both follow it, so that they agree bit for bit.

What is decided (:func:`plan_communication`):

- **Communication points.** For an FMU that can handle a variable communication step size:
  the start, every output time and every row of the input table in between (a recorded
  input reaches the FMU at each of its samples, a step of the table written twice at its
  time); ``communication_step`` splits longer intervals. Otherwise a fixed step: the given
  ``communication_step``, or the output interval when the outputs are a regular grid (else
  their median spacing), from the start time; outputs off that grid are interpolated
  linearly between the points around them (Integer and Boolean ones held).
- **Inputs.** Set at each point to the table's value there (after a step at that time).
  Between points the FMU holds them, unless it declares interpolation: FMI 2.0
  ``canInterpolateInputs`` gets the first derivative over the step (the secant to the
  value just before the next point: exact for a table whose rows are communication
  points); FMI 3.0 ``providesIntermediateUpdate`` (with every input ``intermediateUpdate``)
  asks for its inputs at its own intermediate times and is given the table's value just
  before each.
- **Tolerance and stop time** are passed to the FMU (``fmi2SetupExperiment``,
  ``fmi3EnterInitializationMode``): the simulator's relative tolerance and the last point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SimulationError
from .fmu import LoadedFmu
from .inputs import InputTable


@dataclass(frozen=True, eq=False)
class CommunicationPlan:
    """Communication points and what happens at them (see the module's doc)."""

    comm: np.ndarray      # (p,) points, comm[0] = start
    steps: np.ndarray     # (p - 1,) the step given to doStep at each point
    u: np.ndarray         # (p - 1, k) inputs set at each point
    du: np.ndarray        # (p - 1, k) their derivatives over the step (FMI 2.0 interpolation)
    read: np.ndarray      # (p,) int32: read the outputs there
    out_comm: np.ndarray  # (n,) int32: the point at or after each output time
    out_w: np.ndarray     # (n,) its weight: 1 on the point, else linear from the point before
    interpolation: str    # hold, derivatives, intermediate
    fixed_step: float | None

    @property
    def description(self) -> str:
        grid = f"fixed step {self.fixed_step:g} s" if self.fixed_step else "output times and input rows"
        return f"{grid}, {self.comm.size - 1} steps, inputs {self.interpolation}"


def _tolerance(t: np.ndarray) -> np.ndarray:
    """Two times this close are one (the plan's and ``cosim.c``'s ``TIME_TOL``): a fixed
    step's grid, start + k * step, lands an ulp off the table's rows."""
    return 1e-9 * np.maximum(1.0, np.abs(t))


def right_values(table: InputTable, t: np.ndarray) -> np.ndarray:
    """The table's values just after each time (the value after a step written at it, or
    within :func:`_tolerance` of it)."""
    tt, v = table.time, table.values
    t = np.atleast_1d(np.asarray(t, dtype=float))
    hi = np.searchsorted(tt, t + _tolerance(t), side="right")
    return _between(tt, v, t, hi - 1, hi)


def left_values(table: InputTable, t: np.ndarray) -> np.ndarray:
    """The table's values just before each time (a step written at it, or within
    :func:`_tolerance` of it, keeps its value before): what ``cosim.c``'s
    ``input_before`` computes, with its arithmetic."""
    tt, v = table.time, table.values
    t = np.atleast_1d(np.asarray(t, dtype=float))
    hi = np.searchsorted(tt, t - _tolerance(t), side="left")
    return _between(tt, v, t, hi - 1, hi)


def _between(tt, v, t, lo, hi):
    """Linear between rows lo and hi (the weight clipped to [0, 1]: a time within the
    tolerance outside its segment takes the segment's end)."""
    n = tt.size
    out = np.empty((t.size, v.shape[1]))
    first, last = hi <= 0, hi >= n
    if n == 1:
        out[:] = v[0]
        return out
    out[first] = v[0]
    out[last] = v[-1]
    mid = ~(first | last)
    if mid.any():
        a, b = lo[mid], hi[mid]
        w = np.clip((t[mid] - tt[a]) / (tt[b] - tt[a]), 0.0, 1.0)
        out[mid] = v[a] + w[:, None] * (v[b] - v[a])
    return out


def _default_fixed_step(times: np.ndarray, start: float) -> float:
    gaps = np.diff(np.concatenate([[start], times]))
    gaps = gaps[gaps > 0]
    if not gaps.size:
        return float(times[-1] - start) or 1.0
    return float(np.median(np.diff(times))) if times.size > 1 else float(gaps[-1])


def plan_communication(fmu: LoadedFmu, times: np.ndarray, start_time: float, inputs: InputTable | None,
                       communication_step: float | None = None) -> CommunicationPlan:
    """The communication points of a batch and what is done at each (see the module's doc)."""
    times = np.asarray(times, dtype=float)
    end = float(times[-1])
    if communication_step is not None and not (communication_step > 0 and math.isfinite(communication_step)):
        raise SimulationError(f"communication_step must be a positive number of seconds, not {communication_step!r}")
    tol = _tolerance(times)
    fixed = None
    if fmu.variable_step:
        must = np.unique(np.concatenate([[start_time], times]))
        points = [must]
        if inputs is not None and inputs.time.size:
            rows = np.unique(inputs.time[(inputs.time > start_time) & (inputs.time < end)])
            near = np.searchsorted(must, rows)
            gap_lo = np.abs(rows - must[np.clip(near - 1, 0, must.size - 1)])
            gap_hi = np.abs(must[np.clip(near, 0, must.size - 1)] - rows)
            keep = np.minimum(gap_lo, gap_hi) > _tolerance(rows)
            points.append(rows[keep])
        comm = np.unique(np.concatenate(points))
        if communication_step is not None:
            gaps = np.diff(comm)
            parts = np.maximum(np.ceil(gaps / communication_step - 1e-9).astype(int), 1)
            if np.any(parts > 1):
                pieces = [comm[:1]]
                for j in range(gaps.size):
                    n = parts[j]
                    inner = comm[j] + gaps[j] * np.arange(1, n) / n if n > 1 else np.empty(0)
                    pieces += [inner, comm[j + 1:j + 2]]
                comm = np.concatenate(pieces)
        steps = np.diff(comm)
    else:
        fixed = float(communication_step) if communication_step is not None else _default_fixed_step(times, start_time)
        n = max(math.ceil((end - start_time) / fixed - 1e-9), 1)
        comm = start_time + fixed * np.arange(n + 1)
        steps = np.full(n, fixed)
    # outputs: the point at or after each time
    j = np.searchsorted(comm, times - tol, side="left")
    j = np.minimum(j, comm.size - 1)
    on = np.abs(comm[j] - times) <= tol
    w = np.ones(times.size)
    off = ~on
    if off.any():
        prev = np.maximum(j[off] - 1, 0)
        w[off] = (times[off] - comm[prev]) / (comm[j[off]] - comm[prev])
    read = np.zeros(comm.size, dtype=np.int32)
    read[j] = 1
    read[np.maximum(j[off] - 1, 0)] = 1
    interpolation = fmu.input_interpolation if inputs is not None and fmu.inputs else "hold"
    k = len(inputs.names) if inputs is not None else 0
    if k:
        u = right_values(inputs, comm[:-1])
        du = (left_values(inputs, comm[1:]) - u) / steps[:, None] if interpolation == "derivatives" \
            else np.zeros_like(u)
    else:
        u = du = np.zeros((comm.size - 1, 0))
    return CommunicationPlan(np.ascontiguousarray(comm), np.ascontiguousarray(steps), np.ascontiguousarray(u),
                             np.ascontiguousarray(du), read, j.astype(np.int32), w, interpolation, fixed)
