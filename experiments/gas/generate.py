"""A gas turbine, recorded in three grid events (issue 53).

The plant: ANDES 2.0's GAST (PSS/E's simple gas turbine, read from a ``.dyr`` record by
ANDES's own parser, ``../electrical/andes_grid.py``) on generator 1 (900 MVA) of the Kundur
two-area grid: R 0.05, T1 0.4 s (fuel valve), T2 0.1 s (fuel system), T3 3 s (the exhaust
temperature's measurement), AT 1.0, KT 2.0, VMAX 1.0, VMIN 0, no damping. The unit's
documentation states a gas turbine (``kind = "gas"``: the shipped GAST and GGOV1
structures). The same three events as the steam unit (``../steam``), recorded by
``../electrical/andes_unit.py``:

- ``gas_on``: 200 MW switched on at bus 7 (area 1);
- ``gas_off``: 200 MW switched off at bus 7 (another load lowered by as much first);
- ``gas_on9``: 150 MW switched on at bus 9 (area 2, across the tie): held out.

Each event is its own draw of the recorder's noise (seeds 71-73). Run from the repository
root::

    .venv/bin/python experiments/gas/generate.py
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "electrical"))

import andes_grid  # noqa: E402
import andes_unit  # noqa: E402

PLANT = {"R": 0.05, "T1": 0.4, "T2": 0.1, "T3": 3.0, "AT": 1.0, "KT": 2.0, "VMAX": 1.0, "VMIN": 0.0,
         "Dt": 0.0}  # ANDES's names (PSS/E's GAST fields), machine base
EVENTS = andes_unit.three_events("gas", 71)  # name -> (the grid event, the recorder's seed)
HELD_OUT = "gas_on9"


def plant_record() -> str:
    return andes_grid.andes_record("GAST", PLANT)


def main() -> None:
    andes_unit.write_events(HERE, plant_record(), PLANT, EVENTS, "a gas turbine (GAST)", andes_names=True)
    (HERE / "unit.toml").write_text(andes_unit.unit_file(
        "# A gas turbine (GAST in ANDES: R 0.05, T1 0.4, T2 0.1, T3 3, AT 1, KT 2), three grid events recorded as\n"
        "# electrical power, one held out; made by generate.py. `make identify-gas`.\n",
        "ANDES Kundur generator 1 (900 MVA), a gas turbine, three grid events", EVENTS, HELD_OUT,
        "\n# no [structures]: the shipped gas ones (GAST, GGOV1)\n").replace('[unit]\n', '[unit]\nkind = "gas"\n'))


if __name__ == "__main__":
    main()
