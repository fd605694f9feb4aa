"""Sphinx directive ``rig-quantities``: every quantity of a rig's bus contract, from the code.

``:rig:`` names the rig; the table lists each quantity (name, unit, direction, range,
resolution, per row, required, kind and values, what it is) with its carrier in the rig's
default binding, read from the rig's own registration (:func:`hil.contract.registry.
rig_contract`), so the page cannot drift from what the rig sends.
"""

from __future__ import annotations

from typing import Any, ClassVar

from docutils import nodes
from docutils.parsers.rst import directives
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective


def _cell(text: object) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


class RigQuantities(SphinxDirective):
    """The quantity table of one rig."""

    option_spec: ClassVar[dict[str, Any]] = {"rig": directives.unchanged_required}

    def run(self) -> list[nodes.Node]:
        from hil.contract.binding import DdiCarrier, load_binding
        from hil.contract.registry import rig_contract

        contract = rig_contract(self.options["rig"])
        binding = load_binding(contract.default_binding_file)
        self.env.note_dependency(str(contract.default_binding_file))
        header = ["quantity", "unit", "direction", "range", "resolution", "per row",
                  "required", "kind", "what", f"carrier in {binding.database.name}"]
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        for q in contract.quantities:
            carrier = binding.carriers.get(q.name)
            if carrier is None:
                where = "not carried"
            elif isinstance(carrier, DdiCarrier):
                where = carrier.describe()
            else:
                where = f"`{carrier.describe()}`"
            kind = q.kind if not q.values else \
                f"{q.kind}: " + ", ".join(f"{k} {v}" for k, v in q.values.items())
            direction = "rig → DUT" if q.direction == "to_dut" else "DUT → rig"
            row = [f"`{q.name}`", q.unit or "-", direction, f"{q.minimum:g} … {q.maximum:g}",
                   f"{q.resolution:g}", "yes" if q.per_row else "", "yes" if q.required
                   else "", kind, q.description + (" (event-driven)" if q.event_driven else ""),
                   where]
            lines.append("| " + " | ".join(_cell(c) for c in row) + " |")
        container = nodes.container()
        self.state.nested_parse(StringList(lines, source="rig_quantities"), self.content_offset,
                                container)
        return list(container.children)


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_directive("rig-quantities", RigQuantities)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
