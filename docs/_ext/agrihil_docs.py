"""Sphinx directives that generate reference tables from the code, so the pages cannot drift.

``measurement-catalogue``
    Every measurement of ``hil/limits.py`` for one rig (``:rig:``): name, unit, definition, the
    default limit a qualification judges it against when the DUT's profile sets none
    (``hil.limits.default_limit_text``) and the standard it comes from, or why the measurement
    is information only; per-condition limits as such (``to_mm=20: <= 2; otherwise <= 3``), and
    the conditions each measurement carries. ``hil limits`` prints the same table.
``pytest-plugin-options``
    The ``--hil-*`` options of the pytest plugin, read from its ``pytest_addoption``.
``profile-schema``
    Every table and key of a DUT profile with its type, default, valid range and meaning, read
    from the profile loader's dataclasses and their docstrings (``hil.dut.schema``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

from docutils import nodes
from docutils.parsers.rst import directives
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective

ROOT = Path(__file__).resolve().parents[2]


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown (GFM) table: the pages are MyST, so generated content is parsed as Markdown."""
    lines = ["| " + " | ".join(_cell(h) for h in header) + " |",
             "|" + "---|" * len(header)]
    lines.extend("| " + " | ".join(_cell(c) for c in row) + " |" for row in rows)
    return lines


def _definition(spec: Any) -> str:
    """The measurement's definition and the conditions it carries (what ``when`` may name)."""
    if spec.conditions is None:
        return spec.description
    if not spec.conditions:
        return f"{spec.description} (no conditions)"
    return f"{spec.description} (conditions: {', '.join(spec.conditions)})"


class _Generated(SphinxDirective):
    def _emit(self, lines: list[str]) -> list[nodes.Node]:
        container = nodes.container()
        self.state.nested_parse(StringList(lines, source="agrihil_docs"), self.content_offset,
                                container)
        return list(container.children)


class MeasurementCatalogue(_Generated):
    """The measurement catalogue of one rig: default limits and where they come from."""

    option_spec: ClassVar[dict[str, Any]] = {"rig": directives.unchanged_required}

    def run(self) -> list[nodes.Node]:
        from hil.limits import MEASUREMENTS, default_limit_text

        rig = self.options["rig"]
        self.env.note_dependency(str(ROOT / "hil" / "limits.py"))
        rows = [[f"`{spec.name}`", spec.unit, _definition(spec),
                 "information only" if spec.information else default_limit_text(name),
                 spec.information or spec.source or "(not stated)"]
                for name, spec in MEASUREMENTS.items() if spec.rig in (rig, "*")]
        return self._emit(_table(["measurement", "unit", "definition",
                                  "default limit (the profile sets none)",
                                  "from (or why information only)"], rows))


class ProfileSchema(_Generated):
    """Every table and key of a DUT profile, read from the loader's dataclasses."""

    def run(self) -> list[nodes.Node]:
        from hil.dut import profile
        from hil.dut.schema import markdown

        self.env.note_dependency(profile.__file__)
        return self._emit(markdown())


class PytestPluginOptions(_Generated):
    """The command-line options the agrihil pytest plugin adds."""

    def run(self) -> list[nodes.Node]:
        from hil import pytest_plugin

        options: list[tuple[tuple[str, ...], dict[str, Any]]] = []

        class _Group:
            def addoption(self, *names: str, **attrs: Any) -> None:
                options.append((names, attrs))

        class _Parser:
            def getgroup(self, *args: Any, **kwargs: Any) -> _Group:
                return _Group()

        pytest_plugin.pytest_addoption(_Parser())  # type: ignore[arg-type]
        rows = []
        for names, attrs in options:
            metavar = attrs.get("metavar") or ("|".join(attrs["choices"]) if "choices" in attrs
                                               else "")
            rows.append([f"`{' '.join((names[0], metavar)).strip()}`",
                         f"`{attrs.get('default')!s}`", attrs.get("help", "")])
        return self._emit(_table(["option", "default", "what"], rows))


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_directive("measurement-catalogue", MeasurementCatalogue)
    app.add_directive("pytest-plugin-options", PytestPluginOptions)
    app.add_directive("profile-schema", ProfileSchema)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
