"""What a fleet's run returns, typed until it is written: each unit's :class:`UnitResult`
(its :class:`Route` through the fleet, the record on file's playback, the recommended
record) and the :class:`FleetResult`. JSON appears only where a result is written and
read back: a unit's resume file (``units/<name>.json``) and the fleet's ``fleet.json``."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from enum import Enum

from .playback import Playback


class Route(str, Enum):
    """How a unit went through the fleet (its value is what the page and the CSV say)."""

    PASSED = "record on file passes"
    FAILS = "record on file fails"  # and, the fleet only checking, not identified
    IDENTIFIED = "identified"
    UNSUPPORTED = "record on file not supported"  # of a governor model no table reads: listed, not checked
    FAILED = "failed"


@dataclass
class Recommendation:
    """The identification's recommended record, as read back from the file written: its
    model and fit, its values and the key ones, why it was recommended, its playback."""

    model: str
    fit: str
    parameters: dict[str, float]
    key: dict[str, float]
    reason: str
    playback: Playback

    @classmethod
    def from_json(cls, data: dict) -> "Recommendation":
        return cls(**{**data, "playback": Playback.from_json(data["playback"])})


@dataclass
class UnitResult:
    """One unit's result. ``changes``: what the new record changes from the one on file
    (a key value's relative change by name, or ``model``/``from`` in words)."""

    unit: str
    folder: str
    route: Route
    error: str = ""
    on_file: Playback | None = None  # the record on file's playback
    unsupported: str = ""  # the model of a record on file no table reads (Route.UNSUPPORTED)
    recommended: Recommendation | None = None
    explanation: str = ""
    unexplained: bool = False  # the explanation found nothing it knows that explains the unit
    flags: list[str] = field(default_factory=list)
    changes: dict[str, float | str] = field(default_factory=dict)
    files: dict[str, str] = field(default_factory=dict)  # relative to the fleet's results folder
    seconds: float = 0.0
    digest: str = ""  # of what the result was made from: a rerun keeps it while it matches

    def to_json(self) -> dict:
        return {**asdict(self), "route": self.route.value}

    @classmethod
    def from_json(cls, data: dict) -> "UnitResult":
        return cls(**{**data, "route": Route(data["route"]),
                      "on_file": Playback.from_json(data["on_file"]) if data.get("on_file") else None,
                      "recommended": Recommendation.from_json(data["recommended"]) if data.get("recommended")
                      else None})


@dataclass
class FleetResult:
    """Every unit's result, how many failed, what was run now and what was kept, and the
    files written."""

    name: str
    units: list[UnitResult]
    ran: list[str]
    kept: list[str]
    seconds: float
    workers: int
    files: dict[str, str] = field(default_factory=dict)

    @property
    def failed(self) -> int:
        return self.count(Route.FAILED)

    def count(self, route: Route) -> int:
        return sum(u.route is route for u in self.units)

    def summary(self) -> str:
        """The units by route, as the CLI and the page say it."""
        fails, unsupported = self.count(Route.FAILS), self.count(Route.UNSUPPORTED)
        return (f"{len(self.units)} units: {self.count(Route.PASSED)} records on file pass, "
                + (f"{fails} fail (checked only, not identified), " if fails else "")
                + f"{self.count(Route.IDENTIFIED)} identified, "
                + (f"{unsupported} not checked (their records on file of a model not supported), "
                   if unsupported else "") + f"{self.failed} failed")

    def to_json(self) -> dict:
        return {**asdict(self), "units": [u.to_json() for u in self.units]}
