"""Sphinx directives that generate reference tables from the code, so the pages cannot drift.

``measurement-catalogue``
    Every measurement of ``hil/limits.py`` for one rig (``:rig:``): name, unit, definition, the
    default limit a qualification judges it against when the DUT's profile sets none
    (``hil.limits.default_limit_text``), and the limit the rig's reference profile sets (the
    limits a new profile usually starts from); per-condition limits as such
    (``to_mm=20: <= 2; otherwise <= 3``), and the conditions each measurement carries.
``pytest-plugin-options``
    The ``--hil-*`` options of the pytest plugin, read from its ``pytest_addoption``.
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

#: the profile whose limits the catalogue shows as defaults, per rig
REFERENCE_PROFILES = {
    "fertilizer": "dut_profiles/fertilizer-piecewise-pid-daemon.toml",
    "sowing_depth": "dut_profiles/sowing-depth-fuzzy-pid-daemon.toml",
}


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown (GFM) table: the pages are MyST, so generated content is parsed as Markdown."""
    lines = ["| " + " | ".join(_cell(h) for h in header) + " |",
             "|" + "---|" * len(header)]
    lines.extend("| " + " | ".join(_cell(c) for c in row) + " |" for row in rows)
    return lines


def _limit_text(limit: Any) -> str:
    """The profile's limit in words, its per-condition cases first (``to_mm=20: <= 2``)."""
    from hil.limits import limit_text

    if limit is None:
        return "not set: the default applies"
    text = limit_text(limit.low, limit.high, limit.cases, otherwise="the default")
    if getattr(limit, "marginal", None) is not None:
        text += f" (marginal band {limit.marginal:g})"
    return text


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
    """The measurement catalogue of one rig, with the reference profile's limits."""

    option_spec: ClassVar[dict[str, Any]] = {"rig": directives.unchanged_required}

    def run(self) -> list[nodes.Node]:
        from hil.dut.profile import load_profile
        from hil.limits import MEASUREMENTS, default_limit_text

        rig = self.options["rig"]
        profile_path = ROOT / REFERENCE_PROFILES[rig]
        self.env.note_dependency(str(profile_path))
        self.env.note_dependency(str(ROOT / "hil" / "limits.py"))
        profile = load_profile(profile_path)
        rows = [[f"`{spec.name}`", spec.unit, _definition(spec), default_limit_text(name),
                 _limit_text(profile.limit(name))]
                for name, spec in MEASUREMENTS.items() if spec.rig in (rig, "*")]
        return self._emit(_table(["measurement", "unit", "definition",
                                  "default limit (the profile sets none)",
                                  f"limit in {profile_path.name}"], rows))


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
    return {"parallel_read_safe": True, "parallel_write_safe": True}
