"""A steam unit with a frequency deadband, recorded in four grid events (issue 53).

The plant: ANDES 2.0's TGOV1DB (TGOV1 with ANDES's no-step deadband DeadBand1 on the speed
deviation) on generator 1 (900 MVA) of the Kundur two-area grid: R 0.05, T1 0.4 s, T2 1.5 s,
T3 6.0 s, VMAX 1.0, VMIN 0, and a band of +-0.0006 pu of speed (36 mHz at 60 Hz, the widest
NERC's primary frequency response guideline asks for). ANDES's ``.dyr`` reader has no
TGOV1DB, so the plant is given as PowerWorld's TGOV1D record, read by PowerWorld's field
list into ANDES's TGOV1DB (``../electrical/andes_grid.py``). The unit's documentation
states a steam unit (``kind = "steam"``: the shipped TGOV1 and IEEEG1 structures, each
with its deadband as an optional part), nothing about a deadband. Four events, recorded
by ``../electrical/andes_unit.py``, the first three the steam unit's (``../steam``):

- ``db_on``: 200 MW switched on at bus 7 (area 1);
- ``db_off``: 200 MW switched off at bus 7 (another load lowered by as much first);
- ``db_on9``: 150 MW switched on at bus 9 (area 2, across the tie);
- ``db_on100``: 100 MW switched on at bus 7, the frequency 2.5 bands out.

Two units of the same plant: ``unit.toml`` trains on ``db_on`` and ``db_on100`` and holds
out ``db_off``; ``one_size.toml`` trains on ``db_on`` and ``db_off`` and holds out
``db_on9``, as the steam unit. Why: on a band the frequency leaves, a deadband and a droop
differ only in how the response grows with the deviation, (|dw| - db) / R against
|dw| / R'. Events of one size, one each way, fit either: on ``one_size.toml`` the
explanation finds nothing missing and does not exclude a deadband, TGOV1 without one fits
as well (its droop 22 % large) and misses the held-out event by 1.4 noise units, and the
story says that the recordings do not determine the band. Events of two sizes determine
it; the held-out event of the other sign checks that the band is the same both ways.

Each event is its own draw of the recorder's noise (seeds 61-64). ``make bench-replay``
adds a fifth event, 50 MW switched on at bus 9, whose frequency leaves the band by about
a third of its width, for the records' replay only. Run from the repository root::

    .venv/bin/python experiments/deadband/generate.py
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "electrical"))

import andes_grid  # noqa: E402
import andes_unit  # noqa: E402

PLANT = {"R": 0.05, "T1": 0.4, "VMAX": 1.0, "VMIN": 0.0, "T2": 1.5, "T3": 6.0, "Dt": 0.0, "dbH": 0.0006,
         "dbL": -0.0006, "Trate": 0.0}  # PowerWorld's TGOV1D fields, machine base, pu of speed
EVENTS = {**andes_unit.three_events("db", 61),  # name -> (the grid event, the recorder's seed)
          "db_on100": (andes_unit.grid_event(+1, 7, 100.0), 64)}
UNITS = {  # file -> (its events, the one held out, what it shows)
    "unit.toml": (("db_on", "db_on100", "db_off"), "db_off", "events of two sizes: the band determined"),
    "one_size.toml": (("db_on", "db_off", "db_on9"), "db_on9", "events of one size: the band not determined"),
}
SMALL = andes_unit.grid_event(+1, 9, 50.0)  # near the band: make bench-replay's fifth event


def plant_record() -> str:
    return andes_grid.powerworld_record("TGOV1D", PLANT)


def main() -> None:
    andes_unit.write_events(HERE, plant_record(), PLANT, EVENTS, "a steam unit with a deadband (TGOV1DB)",
                            layout="TGOV1D (PowerWorld), run as ANDES's TGOV1DB")
    for file, (names, held_out, shows) in UNITS.items():
        (HERE / file).write_text(andes_unit.unit_file(
            f"# A steam unit with a 36 mHz deadband (ANDES's TGOV1DB: R 0.05, T1 0.4, T2 1.5, T3 6, db +-0.0006 pu), "
            f"three\n# grid events recorded as electrical power, one held out: {shows}; made by generate.py.\n",
            f"ANDES Kundur generator 1 (900 MVA), a steam unit with a deadband, {shows.split(':')[0]}",
            {n: EVENTS[n] for n in names}, held_out,
            "\n# no [structures]: the shipped steam ones (TGOV1, IEEEG1)\n").replace('[unit]\n', '[unit]\nkind = "steam"\n'))


if __name__ == "__main__":
    main()
