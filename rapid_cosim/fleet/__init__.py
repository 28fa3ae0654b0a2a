"""Many units, one grid event: each unit's record on file played back and judged, the
units whose record fails identified, on a dask cluster, one unit per task
(``rapid-cosim fleet FLEET.toml``, ``rc.fleet``).

``spec`` reads the fleet file, ``playback`` judges a record on a unit's recordings,
``unit_job`` is one unit's whole work, ``result`` the results it returns (typed until
written), ``check`` what every unit is checked for first, ``runner`` distributes the
units and resumes,
``report`` writes the fleet's page, table and records, ``synthetic`` makes fleets for
the tests and the benchmark."""

from .result import FleetResult, Recommendation, Route, UnitResult
from .runner import run_fleet
from .spec import FleetSpec, UnitEntry, load_fleet

__all__ = ["FleetResult", "FleetSpec", "Recommendation", "Route", "UnitEntry", "UnitResult", "load_fleet",
           "run_fleet"]
