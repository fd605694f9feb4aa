"""The plant of a rig of your own: a co-simulation FMU (FMI 2.0 or 3.0) stepped through fmpy.

:class:`FmuPlant` instantiates the FMU once per run, applies the rig file's parameters and
start values, and steps it by the rig's physics step. Variables are addressed by name; an
element of an FMI 3.0 array by ``name[i]`` (``i`` from 1, as Modelica writes it). Only
floating-point variables carry signals (Real / Float64 / Float32); parameters may also be
integers and booleans. Structural parameters (FMI 3.0 array sizes) keep their start values.
"""

from __future__ import annotations

import re
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.errors import ConfigError

_ELEMENT = re.compile(r"^(?P<name>.+)\[(?P<index>\d+)\]$")
FLOAT_TYPES = ("Real", "Float64", "Float32")
INT_TYPES = ("Integer", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64",
             "Enumeration")


@dataclass(frozen=True)
class VariableRef:
    """One scalar of the FMU: a variable (or an element of an array variable)."""

    text: str           # as the rig file writes it
    name: str           # the model variable's name
    index: int          # 0-based element (0 for a scalar)
    size: int           # the variable's element count
    value_reference: int
    causality: str
    variability: str
    type: str
    unit: str
    description: str


class FmuDescription:
    """An FMU's model description, read once, and the checks a rig file needs of it.

    Parameters
    ----------
    path : Path
        The ``.fmu`` file.
    source : str
        The rig file, named in errors.
    """

    def __init__(self, path: Path, source: str) -> None:
        from fmpy import read_model_description

        self.path = path
        self.source = source
        if not path.is_file():
            raise ConfigError(f"FMU not found: {path}", path=source, key="fmu.path")
        try:
            self.md = read_model_description(str(path), validate=False)
        except Exception as exc:  # fmpy raises plain Exceptions for broken archives and XML
            raise ConfigError(f"{path.name} is not a readable FMU: {exc}", path=source,
                              key="fmu.path") from exc
        if self.md.coSimulation is None:
            raise ConfigError(f"{path.name} has no co-simulation interface (FMI "
                              f"{self.md.fmiVersion}; model exchange only)", path=source,
                              key="fmu.path")
        self.fmi_version = str(self.md.fmiVersion)
        if not self.fmi_version.startswith(("2.", "3.")):
            raise ConfigError(f"{path.name} is FMI {self.fmi_version}; FMI 2.0 and 3.0 "
                              f"co-simulation FMUs are supported", path=source, key="fmu.path")
        self.variables = {v.name: v for v in self.md.modelVariables}
        self._structural = {v.valueReference: v for v in self.md.modelVariables
                            if v.causality == "structuralParameter"}

    def _size(self, variable: Any) -> int:
        size = 1
        for dim in variable.dimensions:
            if dim.start is not None:
                size *= int(dim.start)
            else:
                ref = self._structural.get(dim.valueReference)
                size *= int(ref.start) if ref is not None and ref.start is not None else 1
        return size

    def ref(self, text: str, key: str, *, causality: Sequence[str] = (),
            floating: bool = True) -> VariableRef:
        """The scalar ``text`` names (``name`` or ``name[i]``), checked.

        Raises
        ------
        ConfigError
            No such variable, an element out of range, a whole array, the wrong causality or
            a type that carries no signal (naming the rig file and ``key``).
        """
        match = _ELEMENT.match(text)
        name, index = (match["name"], int(match["index"])) if match else (text, 0)
        variable = self.variables.get(name) or (self.variables.get(text) if match else None)
        if variable is self.variables.get(text) and variable is not None:
            name, index, match = text, 0, None
        if variable is None:
            close = [n for n in self.variables if n.lower() == name.lower()]
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ConfigError(f"{self.path.name} has no variable {name!r}{hint}",
                              path=self.source, key=key)
        size = self._size(variable)
        if match:
            if not 1 <= index <= size:
                raise ConfigError(f"{name} has {size} element(s); {text!r} is out of range "
                                  f"(elements count from 1)", path=self.source, key=key)
            index -= 1
        elif size != 1:
            raise ConfigError(f"{name} is an array of {size}: name one element, {name}[1] .. "
                              f"{name}[{size}]", path=self.source, key=key)
        if causality and variable.causality not in causality:
            raise ConfigError(f"{name} is {variable.causality!r}; this needs "
                              f"{' or '.join(map(repr, causality))}", path=self.source, key=key)
        if floating and variable.type not in FLOAT_TYPES:
            raise ConfigError(f"{name} is {variable.type}; signals are floating-point "
                              f"variables", path=self.source, key=key)
        unit = variable.unit or (variable.declaredType.unit
                                 if variable.declaredType is not None else None) or ""
        return VariableRef(text, name, index, size, variable.valueReference,
                           variable.causality, variable.variability, variable.type,
                           unit, variable.description or "")

    def parameter_refs(self, values: Mapping[str, Any], key: str) -> list[tuple[Any, Any]]:
        """(model variable, value list) of every parameter or start value, checked."""
        out = []
        for name, value in values.items():
            where = f"{key}.{name}"
            variable = self.variables.get(name)
            if variable is None:
                raise ConfigError(f"{self.path.name} has no variable {name!r}", path=self.source,
                                  key=where)
            if variable.causality == "structuralParameter":
                raise ConfigError(f"{name} is a structural parameter (an array size): the rig "
                                  f"keeps its start value", path=self.source, key=where)
            if variable.causality in ("output", "independent") or (
                    variable.causality == "local" and variable.variability != "continuous"):
                raise ConfigError(f"{name} is {variable.causality!r}: only parameters, inputs "
                                  f"and continuous states take a value", path=self.source,
                                  key=where)
            items = list(value) if isinstance(value, list | tuple) else [value]
            size = self._size(variable)
            if len(items) != size:
                raise ConfigError(f"{name} takes {size} value(s), got {len(items)}",
                                  path=self.source, key=where)
            kind = variable.type
            for item in items:
                ok = (isinstance(item, bool) if kind == "Boolean" else
                      isinstance(item, int) and not isinstance(item, bool) if kind in INT_TYPES
                      else isinstance(item, int | float) and not isinstance(item, bool)
                      if kind in FLOAT_TYPES else False)
                if not ok:
                    raise ConfigError(f"{name} is {kind}; got {item!r}", path=self.source,
                                      key=where)
            out.append((variable, items))
        return out


class FmuPlant:
    """One instance of the FMU for one run.

    Parameters
    ----------
    description : FmuDescription
        The FMU, read and checked.
    parameters : mapping
        Parameter and start values by variable name (applied before initialisation).
    step_s : float
        The communication step (the rig's physics step).
    outputs : sequence of VariableRef
        The scalars read after each step (outputs and locals the rig traces or senses).
    """

    def __init__(self, description: FmuDescription, parameters: Mapping[str, Any],
                 step_s: float, outputs: Sequence[VariableRef]) -> None:
        from fmpy import extract

        self.description = description
        self.step_s = step_s
        self.time_s = 0.0
        self._dir = tempfile.mkdtemp(prefix="agrihil-fmu-")
        md = description.md
        extract(str(description.path), unzipdir=self._dir)
        kwargs = dict(guid=md.guid, unzipDirectory=self._dir,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="plant")
        self.v3 = description.fmi_version.startswith("3.")
        if self.v3:
            from fmpy.fmi3 import FMU3Slave
            self.fmu: Any = FMU3Slave(**kwargs)
            self.fmu.instantiate()
        else:
            from fmpy.fmi2 import FMU2Slave
            self.fmu = FMU2Slave(**kwargs)
            self.fmu.instantiate()
            self.fmu.setupExperiment(startTime=0.0)
        self._closed = False
        refs = description.parameter_refs(parameters, "fmu.parameters")
        if self.v3:
            self.fmu.enterInitializationMode(startTime=0.0)
            for variable, items in refs:
                self._set_any(variable, items)
        else:
            for variable, items in refs:
                self._set_any(variable, items)
            self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        # what is read after each step: the scalars of one type in one call, each array in one
        self._slots: dict[str, int] = {}
        scalars: dict[str, list[tuple[int, str]]] = {}
        arrays: dict[int, tuple[int, str, list[tuple[int, str]]]] = {}
        for ref in outputs:
            if ref.text in self._slots:
                continue
            self._slots[ref.text] = -1
            if ref.size == 1:
                scalars.setdefault(ref.type, []).append((ref.value_reference, ref.text))
            else:
                arrays.setdefault(ref.value_reference, (ref.size, ref.type, []))[2].append(
                    (ref.index, ref.text))
        self._scalar_reads: list[tuple[str, list[int], list[int]]] = []
        self._array_reads: list[tuple[int, int, str, list[tuple[int, int]]]] = []
        slot = 0
        for kind, items in scalars.items():
            slots = list(range(slot, slot + len(items)))
            for (_, text), i in zip(items, slots, strict=True):
                self._slots[text] = i
            self._scalar_reads.append((kind, [vr for vr, _ in items], slots))
            slot += len(items)
        for vr, (size, kind, items) in arrays.items():
            picks = []
            for index, text in items:
                self._slots[text] = slot
                picks.append((index, slot))
                slot += 1
            self._array_reads.append((vr, size, kind, picks))
        self._values = [0.0] * slot
        self._fresh = False

    def _set_any(self, variable: Any, items: list[Any]) -> None:
        kind, vr, f = variable.type, [variable.valueReference], self.fmu
        if self.v3:
            setter = {"Float64": f.setFloat64, "Float32": f.setFloat32, "Boolean": f.setBoolean,
                      "Int32": f.setInt32, "Int64": f.setInt64, "UInt32": f.setUInt32,
                      "UInt64": f.setUInt64, "Int16": f.setInt16, "UInt16": f.setUInt16,
                      "Int8": f.setInt8, "UInt8": f.setUInt8,
                      "Enumeration": f.setInt64}[kind]
            setter(vr, items)
        elif kind == "Real":
            f.setReal(vr, [float(x) for x in items])
        elif kind == "Boolean":
            f.setBoolean(vr, items)
        else:
            f.setInteger(vr, items)

    def set(self, ref: VariableRef, value: float) -> None:
        """Write one scalar input (an element of an array input: the others are kept)."""
        vr = [ref.value_reference]
        if self.v3:
            getter, setter = ((self.fmu.getFloat32, self.fmu.setFloat32)
                              if ref.type == "Float32" else
                              (self.fmu.getFloat64, self.fmu.setFloat64))
            if ref.size == 1:
                setter(vr, [value])
            else:
                values = list(getter(vr, nValues=ref.size))
                values[ref.index] = value
                setter(vr, values)
        else:
            self.fmu.setReal(vr, [value])
        self._fresh = False

    def advance(self, n: int, dt: float) -> None:
        """``n`` communication steps of ``dt`` (each a doStep: the same as ``n`` calls)."""
        do_step, t = self.fmu.doStep, self.time_s
        for _ in range(n):
            do_step(t, dt)
            t += dt
        self.time_s = t
        self._fresh = False

    def values(self) -> list[float]:
        """The watched scalars now, in slot order (read once per step)."""
        if not self._fresh:
            out = self._values
            v3, fmu = self.v3, self.fmu
            for kind, vrs, slots in self._scalar_reads:
                got = ((fmu.getFloat32 if kind == "Float32" else fmu.getFloat64)(vrs)
                       if v3 else fmu.getReal(vrs))
                for i, value in zip(slots, got, strict=True):
                    out[i] = float(value)
            for vr, size, kind, picks in self._array_reads:
                got = (fmu.getFloat32 if kind == "Float32" else fmu.getFloat64)([vr],
                                                                               nValues=size)
                for index, i in picks:
                    out[i] = float(got[index])
            self._fresh = True
        return self._values

    def slot(self, text: str) -> int:
        """The position of the watched scalar ``text`` in :meth:`values`."""
        return self._slots[text]

    def close(self) -> None:
        """Terminate and free the instance, remove its unpacked files."""
        if self._closed:
            return
        self._closed = True
        try:
            self.fmu.terminate()
        finally:
            try:
                self.fmu.freeInstance()
            finally:
                shutil.rmtree(self._dir, ignore_errors=True)
