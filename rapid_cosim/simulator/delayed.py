"""An exact transport delay on a recorded-frequency bench: the input ``f_dev_delayed``.

A delay between the frequency a governor sees and the one recorded acts on a known
input, so it needs no approximant: a bench that declares the input ``f_dev_delayed``
(and ``Effects.TransportDelay dly``) is given the recording at t - ``dly.T``, its own
value of ``dly.T`` for each parameter set. Before the recording starts the value is held
at its first, as every input is (the pre-event steady state).

Each set's table holds the recording's rows and the same rows moved by T, both kept exact:
between them every column is linear in time, so the delayed column is the recording's
linear interpolant moved by T, and a step (a time written twice) stays a step, moved.
A recording without steps takes the short way (interpolation on the merged rows). A set's
table differs from the next one's, so a batch is run set by set (a prepared run per set):
on event1's 6000 rows, 1.15 times a bench without the delay on the exponential runner and
1.6 times on CVODE (``benchmarks/delay_cost.py``, 2026-11-29, 2 busy cores).
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from .communication import left_values, right_values
from .inputs import InputTable
from .rocof import FREQUENCY

DELAYED_FREQUENCY = "f_dev_delayed"  # the benches' delayed frequency input (Hz, deviation from f_nom)
DELAY = "dly.T"  # the delay (s), Effects.TransportDelay's T


def _steps(table: InputTable) -> np.ndarray:
    t = table.time
    return t[1:][t[1:] == t[:-1]]


def with_delayed(table: InputTable) -> InputTable:
    """The table with ``f_dev_delayed`` as ``f_dev`` (no delay): what a bench is prepared
    with, before each set's own is made by :func:`delayed_table`."""
    if DELAYED_FREQUENCY in table.names:
        return table
    column = table.values[:, table.names.index(FREQUENCY)]
    return InputTable(table.time, (*table.names, DELAYED_FREQUENCY), np.column_stack([table.values, column]))


def delayed_table(table: InputTable, delay: float) -> InputTable:
    """``table`` (holding ``f_dev_delayed``) with that column set to ``f_dev`` at t - ``delay``,
    on the union of the rows and the rows moved by ``delay``."""
    if not np.isfinite(delay) or delay < 0:
        raise ParameterError(f"a transport delay must be finite and not negative; got {delay!r} s")
    names = table.names
    source, target = names.index(FREQUENCY), names.index(DELAYED_FREQUENCY)
    if not _steps(table).size:  # a recording: no steps, so plain interpolation on the merged rows
        rows = np.union1d(table.time, table.time + delay)
        values = np.column_stack([np.interp(rows, table.time, table.values[:, j]) for j in range(len(names))])
        values[:, target] = np.interp(rows, table.time + delay, table.values[:, source])
        return InputTable(rows, names, values)
    moved = InputTable(table.time + delay, (FREQUENCY,), table.values[:, [source]])
    times = np.unique(np.concatenate([table.time, moved.time]))
    steps = np.union1d(_steps(table), _steps(moved))
    twice = np.isin(times, steps)
    rows = np.sort(np.concatenate([times, times[twice]]))
    first = np.ones(rows.size, dtype=bool)  # a step's first row holds the values before it
    first[1:] = rows[1:] != rows[:-1]
    before = first & np.isin(rows, steps)
    values = np.where(before[:, None], left_values(table, rows), right_values(table, rows))
    values[:, target] = np.where(before, left_values(moved, rows)[:, 0], right_values(moved, rows)[:, 0])
    return InputTable(rows, names, values)


def set_delays(names: list[str], values: np.ndarray, default: float) -> np.ndarray:
    """Each set's delay: its ``dly.T`` where the sets give it, else the bench's value."""
    if DELAY in names:
        return np.asarray(values[:, names.index(DELAY)], dtype=float)
    return np.full(values.shape[0], float(default))
