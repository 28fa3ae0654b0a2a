"""A steam unit with a binding opening rate, recorded in three grid events (issue 40).

The plant: ANDES 2.0's IEEEG1 on generator 1 (900 MVA) of the Kundur two-area grid, as
ANDES reads it from a PSS/E record composed from ANDES's own field list
(``../electrical/andes_grid.py``): K 20, K1 0.3, K3 0.7, T3 0.1 s, T4 0.3 s, T5 8 s, a
0.5 s governor lag (T1) and an opening rate Uo of 0.015 pu/s (machine base) that binds
on every load switched on; the rest as ``../electrical/generate.py``'s IEEEG1 events
(PMAX 1.2). Three events, each 90 s at 5 ms steps, the event 30 s in (the quiet span the
recorder's noise is estimated from):

- ``steam_on``: 200 MW switched on at bus 7 (area 1);
- ``steam_off``: 200 MW switched off at bus 7 (another load lowered by as much first);
- ``steam_on9``: 150 MW switched on at bus 9 (area 2, across the tie): held out.

Recorded as generate.py records: generator 1's electrical power (MW) and speed as the
frequency (Hz) at 30 frames/s with the same recorder noise (each event its own draw).
The configs hold TG Type I's documented constants (the explanation's base, as the
electrical unit's); ``unit.toml`` names the structures TGOV1 and IEEEG1
(``../electrical/structures``). Each folder also keeps ``clean.csv`` (the same frames
without the noise) and ``truth.json`` (the plant, the event, what ANDES was given).
Run from the repository root::

    .venv/bin/python experiments/steam/generate.py
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "electrical"))

import andes_grid  # noqa: E402
import andes_unit  # noqa: E402

PLANT = {"K": 20.0, "T1": 0.5, "T2": 0.0, "T3": 0.1, "UO": 0.015, "UC": -1.0, "PMAX": 1.2, "PMIN": 0.0,
         "T4": 0.3, "K1": 0.3, "K2": 0.0, "T5": 8.0, "K3": 0.7, "K4": 0.0, "T6": 0.5, "K5": 0.0, "K6": 0.0,
         "T7": 0.5, "K7": 0.0, "K8": 0.0}  # ANDES's names, machine base
T_EVENT, DURATION = andes_unit.T_EVENT, andes_unit.DURATION
EVENTS = andes_unit.three_events("steam", 51)  # name -> (the grid event, the recorder's seed)
HELD_OUT = "steam_on9"


def plant_record() -> str:
    return andes_grid.andes_record("IEEEG1", PLANT)


def main() -> None:
    andes_unit.write_events(HERE, plant_record(), PLANT, EVENTS, "a steam unit (IEEEG1, opening rate binding)",
                            andes_names=True)
    (HERE / "unit.toml").write_text(andes_unit.unit_file(
        "# A steam unit with a binding opening rate (IEEEG1 in ANDES: K 20, K1 0.3, K3 0.7, T5 8, Uo 0.015 pu/s), three\n"
        "# grid events recorded as electrical power, one held out; made by generate.py. `make identify-steam`.\n",
        "ANDES Kundur generator 1 (900 MVA), a steam unit, three grid events", EVENTS, HELD_OUT,
        '\n[structures]\nfiles = ["../electrical/structures/TGOV1.toml", "../electrical/structures/IEEEG1.toml"]\n'))


if __name__ == "__main__":
    main()
