"""The standard structures that ship with rapid-cosim, as a page (``rapid-cosim docs
structures``): per structure, its benches, what it estimates and in which range, what its
optional parts carry, and which kinds of plant get it by default. Made from the shipped
files themselves, so it cannot drift from them."""

from __future__ import annotations

from .shipped import KINDS, standard_file
from .structure import Structure

_SHIPPED = ("TGTypeI", "TGOV1", "IEEEG1", "GGOV1", "HYGOV", "GAST")


def structures_page() -> str:
    lines = ["# Standard structures", "",
             "A unit's `[structures] standard = [...]` names these, or its `[unit] kind` picks them: "
             + "; ".join(f"{kind}: {', '.join(names)}" for kind, names in KINDS.items())
             + "; no kind: the unit's own `structures/<name>.toml` of these names where it has that folder, else "
             "every one but TG Type I. A file of the unit's own (`[structures] files`) follows the "
             "same form (`rapid-cosim docs config`, the structure file's keys).", ""]
    for name in _SHIPPED:
        s = Structure.load(standard_file(name))
        kinds = [k for k, names in KINDS.items() if name in names]
        lines += [f"## {s.name}", "",
                  f"- staged tests on `{s.bench}`" + (f"; recorded events on `{s.input_bench}`" if s.input_bench
                                                       else "; no recorded-event bench"),
                  "- estimates: " + ", ".join(f"{k.removeprefix('gov.')} [{e.min:g}, {e.max:g}]"
                                              for k, e in s.estimate.items())]
        for effect in s.effects:
            parts = ", ".join(f"{k.removeprefix('gov.')} [{s.optional[k].min:g}, {s.optional[k].max:g}]"
                              for k in s.parts(effect))
            lines.append(f"- optional, freed only where the data call for it: {effect} ({parts})")
        if s.fixed:
            lines.append("- fixed: " + ", ".join(f"{k.removeprefix('gov.')} = {v:g}" for k, v in s.fixed.items()))
        lines += [f"- the default of: {', '.join(kinds)} units" if kinds else "- the default of: no kind (named "
                  "only)", ""]
    return "\n".join(lines)
