"""One running FMU instance (fmpy's low-level API), FMI 2.0 or 3.0 co-simulation.

What the rest of :mod:`hil.fmi` needs of an instance and nothing more: instantiate and
initialise, set and get values by variable, ``doStep``, and for FMI 3.0 the event mode with
clocks and binaries that FMI-LS-BUS uses. Every FMI call that fails (an error or fatal status,
a null instance, a library that cannot be loaded) raises :class:`FmuCallError` naming the
function and carrying the FMU's last log messages, so the DUT runner can report what the FMU
said before it failed.
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

from hil.errors import HilError
from hil.fmi.fmufile import FmuFile

__all__ = ["FmuCallError", "FmuInstance"]

#: FMI 3.0 variable types and fmpy's getter/setter suffix
_FMI3_TYPES = {"Float64": "Float64", "Float32": "Float32", "Int8": "Int8", "UInt8": "UInt8",
               "Int16": "Int16", "UInt16": "UInt16", "Int32": "Int32", "UInt32": "UInt32",
               "Int64": "Int64", "UInt64": "UInt64", "Boolean": "Boolean",
               "Enumeration": "Int64"}
_FMI2_TYPES = {"Real": "Real", "Integer": "Integer", "Boolean": "Boolean",
               "Enumeration": "Integer"}
LOG_LINES = 20
#: also given each line the FMU logs (the FMU host writes them to its standard error, so that
#: what an FMU said before it crashed its process is not lost with it)
log_sink: Callable[[str], Any] | None = None


class FmuCallError(HilError, RuntimeError):
    """An FMI call failed; the message names the call and ends with the FMU's last log lines."""


class _MissingFunction:
    """Stands for an FMI function the FMU does not export: calling it is an error naming it."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.argtypes: Any = None
        self.restype: Any = None
        self.argnames: Any = None

    def __call__(self, *args: Any) -> Any:
        raise FmuCallError(f"the FMU does not export {self.name}")


class _LenientLibrary:
    """The FMU's library as fmpy looks functions up in it, missing ones stood in for."""

    def __init__(self, dll: Any) -> None:
        self._dll = dll
        self.missing: list[str] = []

    def __getattr__(self, name: str) -> Any:
        try:
            return getattr(self._dll, name)
        except AttributeError:
            self.missing.append(name)
            return _MissingFunction(name)


def _lenient(cls: type) -> type:
    """fmpy 0.3.32 loads every function the standard declares and fails on the first one a
    library lacks, even one a co-simulation FMU need not export (FMI 3.0's
    ``fmi3ActivateModelPartition``, say); this loads those present and names a missing one
    only if it is called."""

    class Lenient(cls):  # type: ignore[misc, valid-type]
        def _loadFunctions(self) -> None:
            real = self.dll
            self.dll = _LenientLibrary(real)
            try:
                super()._loadFunctions()
            finally:
                self.missing_functions = self.dll.missing
                self.dll = real

    Lenient.__name__ = cls.__name__   # fmpy picks the fmi2/fmi3 prefix by the class name
    return Lenient


class FmuInstance:
    """An instantiated co-simulation FMU.

    Parameters
    ----------
    fmu : FmuFile
        The FMU.
    instance_name : str
        The instance's name.
    event_mode : bool, optional
        FMI 3.0: instantiate with ``eventModeUsed`` (LS-BUS needs it).
    """

    def __init__(self, fmu: FmuFile, instance_name: str, *, event_mode: bool = False) -> None:
        self.fmu = fmu
        self.fmi3 = fmu.fmi_major == 3
        self.log: deque[str] = deque(maxlen=LOG_LINES)
        self._tmp = tempfile.mkdtemp(prefix="agrihil-fmu-")
        self._slave: Any = None
        self.time = 0.0
        self.event_mode = event_mode
        self.in_event_mode = False
        try:
            self._slave = self._instantiate(instance_name, event_mode)
            if self.fmi3:
                self._prepare_fast()
        except BaseException:
            self.close()
            raise

    # --- life cycle ----------------------------------------------------------------------
    def _logger3(self, env: Any, status: int, category: Any, message: Any) -> None:
        text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
        line = f"[{_status(status)}] {text}"
        self.log.append(line)
        if log_sink is not None:
            log_sink(line)

    def _instantiate(self, name: str, event_mode: bool) -> Any:
        from fmpy import extract
        from fmpy.fmi2 import FMU2Slave
        from fmpy.fmi3 import FMU3Slave

        path = self.fmu.path
        unzip = str(path) if path.is_dir() else extract(str(path), unzipdir=self._tmp)
        md = self.fmu.description
        kwargs = {"guid": md.guid if not self.fmi3 else md.instantiationToken,
                  "modelIdentifier": self.fmu.model_identifier,
                  "unzipDirectory": str(unzip), "instanceName": name}
        try:
            if self.fmi3:
                slave = _lenient(FMU3Slave)(**kwargs)
                slave.instantiate(eventModeUsed=event_mode, loggingOn=True,
                                  logMessage=self._logger3)
            else:
                slave = _lenient(FMU2Slave)(**kwargs)
                slave.instantiate(loggingOn=False)
        except Exception as exc:
            raise FmuCallError(self._text("instantiate", exc)) from exc
        return slave

    def _text(self, call: str, exc: BaseException) -> str:
        said = f"; the FMU said: {' | '.join(self.log)}" if self.log else ""
        return f"{call} failed: {' '.join(str(exc).split()) or type(exc).__name__}{said}"

    def call(self, name: str, *args: Any) -> Any:
        """``slave.<name>(*args)``, an FMI error turned into :class:`FmuCallError`."""
        try:
            return getattr(self._slave, name)(*args)
        except Exception as exc:
            raise FmuCallError(self._text(name, exc)) from exc

    def initialize(self, start_time: float = 0.0) -> None:
        """Enter and exit initialisation mode (FMI 3.0 with event mode: ends in event mode,
        else in step mode)."""
        self.time = start_time
        if self.fmi3:
            self.call("enterInitializationMode", None, start_time)
            self.call("exitInitializationMode")
            self.in_event_mode = self.event_mode
        else:
            self.call("setupExperiment", None, start_time)
            self.call("enterInitializationMode")
            self.call("exitInitializationMode")

    def close(self) -> None:
        """Terminate and free the instance (safe to call twice)."""
        slave, self._slave = self._slave, None
        if slave is not None:
            with contextlib.suppress(Exception):
                slave.terminate()
            with contextlib.suppress(Exception):
                slave.freeInstance()
        shutil.rmtree(self._tmp, ignore_errors=True)

    # --- values ----------------------------------------------------------------------------
    def _kind(self, var: Any) -> str:
        table = _FMI3_TYPES if self.fmi3 else _FMI2_TYPES
        kind = table.get(var.type)
        if kind is None:
            raise FmuCallError(f"variable {var.name!r} is of type {var.type}, which agrihil "
                               f"does not set or get")
        return kind

    def set(self, var: Any, value: float | int | bool) -> None:
        kind = self._kind(var)
        if kind == "Boolean":
            value = bool(value)
        elif kind not in ("Real", "Float64", "Float32"):
            value = round(value)
        else:
            value = float(value)
        self.call(f"set{kind}", [var.valueReference], [value])

    def get(self, var: Any) -> float | int | bool:
        kind = self._kind(var)
        return self.call(f"get{kind}", [var.valueReference])[0]  # type: ignore[no-any-return]

    def set_boolean_vr(self, vr: int, value: bool) -> None:
        self.call("setBoolean", [vr], [value])

    # --- stepping --------------------------------------------------------------------------
    def do_step(self, to_time: float) -> bool:
        """``doStep`` from the instance's time to ``to_time``; True when the FMU asks for
        event handling (FMI 3.0). No call when ``to_time`` is not later."""
        step = to_time - self.time
        if step <= 1e-12:
            return False
        if self.in_event_mode:
            self.enter_step_mode()
        if self.fmi3:
            event, terminate, _early, last = self.call("doStep", self.time, step)
            if terminate:
                raise FmuCallError(f"doStep at t = {self.time:.3f} s: the FMU asked to "
                                   f"terminate the simulation")
            self.time = float(last) if last and last > self.time else to_time
            return bool(event)
        self.call("doStep", self.time, step)
        self.time = to_time
        return False

    # --- FMI 3.0 event mode (LS-BUS): the hot path, straight to the library ------------
    # fmpy's wrappers build ctypes arrays and a status check for every call; an LS-BUS node
    # takes several calls per frame, so these reuse preallocated arguments and call the
    # library's functions (as fmpy loaded them, argument types set) directly.
    def _raw(self, name: str) -> Any:
        return self._slave._functions[name]

    def _prepare_fast(self) -> None:
        import ctypes

        self._c = ctypes
        self._vr1 = (ctypes.c_uint32 * 1)()
        self._size1 = (ctypes.c_size_t * 1)()
        self._bin1 = (ctypes.POINTER(ctypes.c_uint8) * 1)()
        self._clock1 = (ctypes.c_bool * 1)()
        self._flags = [ctypes.c_bool() for _ in range(5)]
        self._next_event = ctypes.c_double()
        self._fn = {name: self._raw(name) for name in (
            "fmi3SetBinary", "fmi3GetBinary", "fmi3SetClock", "fmi3GetClock",
            "fmi3UpdateDiscreteStates", "fmi3EnterEventMode", "fmi3EnterStepMode")}

    def _check(self, name: str, status: int) -> None:
        if status > 1:   # fmi3Warning is fine; discard, error, fatal are not
            said = f"; the FMU said: {' | '.join(self.log)}" if self.log else ""
            raise FmuCallError(f"{name} failed with status {status} ({_status(status)}) at "
                               f"t = {self.time:.3f} s{said}")

    def enter_event_mode(self) -> None:
        if not self.in_event_mode:
            self._check("fmi3EnterEventMode", self._fn["fmi3EnterEventMode"](
                self._slave.component))
            self.in_event_mode = True

    def enter_step_mode(self) -> None:
        if self.in_event_mode:
            self._check("fmi3EnterStepMode", self._fn["fmi3EnterStepMode"](
                self._slave.component))
            self.in_event_mode = False

    def update_discrete_states(self) -> None:
        """``updateDiscreteStates`` until the FMU needs no more (bounded)."""
        c = self._c
        need, terminate, nominals, values, defined = self._flags
        fn = self._fn["fmi3UpdateDiscreteStates"]
        for _ in range(100):
            self._check("fmi3UpdateDiscreteStates", fn(
                self._slave.component, c.byref(need), c.byref(terminate), c.byref(nominals),
                c.byref(values), c.byref(defined), c.byref(self._next_event)))
            if terminate.value:
                raise FmuCallError(f"updateDiscreteStates at t = {self.time:.3f} s: the FMU "
                                   f"asked to terminate the simulation")
            if not need.value:
                return
        raise FmuCallError(f"updateDiscreteStates at t = {self.time:.3f} s: the FMU still "
                           f"needs an update after 100 iterations")

    def set_binary(self, vr: int, data: bytes) -> None:
        c = self._c
        self._vr1[0] = vr
        self._size1[0] = len(data)
        buffer = (c.c_uint8 * max(1, len(data))).from_buffer_copy(data or b"\0")
        self._bin1[0] = c.cast(buffer, c.POINTER(c.c_uint8))
        self._check("fmi3SetBinary", self._fn["fmi3SetBinary"](
            self._slave.component, self._vr1, 1, self._size1, self._bin1, 1))

    def get_binary(self, vr: int) -> bytes:
        self._vr1[0] = vr
        self._check("fmi3GetBinary", self._fn["fmi3GetBinary"](
            self._slave.component, self._vr1, 1, self._size1, self._bin1, 1))
        size = self._size1[0]
        if not size or not self._bin1[0]:
            return b""
        return self._c.string_at(self._bin1[0], size)

    def set_clock(self, vrs: Sequence[int]) -> None:
        c = self._c
        arr = (c.c_uint32 * len(vrs))(*vrs)
        values = (c.c_bool * len(vrs))(*([True] * len(vrs)))
        self._check("fmi3SetClock", self._fn["fmi3SetClock"](
            self._slave.component, arr, len(vrs), values))

    def get_clock(self, vr: int) -> bool:
        self._vr1[0] = vr
        self._check("fmi3GetClock", self._fn["fmi3GetClock"](
            self._slave.component, self._vr1, 1, self._clock1))
        return bool(self._clock1[0])


def _status(status: int) -> str:
    names = ("OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING")
    return names[status] if 0 <= status < len(names) else str(status)

