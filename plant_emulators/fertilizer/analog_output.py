"""Output stage of the CAN analog output module (C-3402, CiA 401): raw value → volts.

The controller writes object 0x6411 (Write Analog Output 16-bit, INTEGER16) through RPDO1. The
rig's scaling (README, EDS comments): the value is the output in millivolts, 0..10000 for
0..10 V; values outside are clipped. The module's DAC quantizes the output and each module has
a small gain and offset error, drawn per run. On a communication error (heartbeat consumer
timeout, NMT stop) CiA 401's error mode 0x6443 = 1 makes the output take the error value of
0x6444, here 0 mV: the motor stops.

Example
-------
>>> import numpy as np
>>> from plant_emulators.fertilizer.config import load_rig_config
>>> ch = AnalogOutputChannel(load_rig_config().analog_output, np.random.default_rng(0))
>>> abs(ch.volts(5000) - 5.0) < 0.02
True
>>> ch.volts(-300), ch.volts(20000) == ch.volts(10000)
(0.0, True)
"""

from __future__ import annotations

import numpy as np

from plant_emulators.fertilizer.config import AnalogOutputConfig
from plant_emulators.fertilizer.noise import spawn

__all__ = ["AnalogOutputChannel"]


class AnalogOutputChannel:
    """One 0-10 V channel of the analog output module.

    Parameters
    ----------
    config : AnalogOutputConfig
        The ``[analog_output]`` section.
    rng : numpy.random.Generator
        The run's generator; the channel draws its gain and offset error from a child stream.
    """

    def __init__(self, config: AnalogOutputConfig, rng: np.random.Generator) -> None:
        self.config = config
        own = spawn(rng)
        self.gain_error_frac = config.gain_error_sd_frac * float(own.standard_normal())
        """This channel's gain error (fraction)."""
        self.offset_error_v = config.offset_error_sd_mv * 1e-3 * float(own.standard_normal())
        """This channel's offset error (V)."""
        self._codes = (1 << config.dac_bits) - 1
        self._full_scale_v = config.full_scale_mv / 1000.0

    def clip_raw(self, raw: int) -> int:
        """The value of 0x6411 the module acts on: ``raw`` clipped to 0..full scale (mV)."""
        return min(max(int(raw), 0), self.config.full_scale_mv)

    def volts(self, raw: int) -> float:
        """Output voltage (V) for the 0x6411 value ``raw`` (mV), never below 0 V."""
        code = round(self.clip_raw(raw) / self.config.full_scale_mv * self._codes)
        v = code / self._codes * self._full_scale_v * (1.0 + self.gain_error_frac)
        v += self.offset_error_v if code > 0 else 0.0
        return v if v > 0.0 else 0.0

    def error_volts(self) -> float:
        """Output voltage (V) in the communication-error state (0x6444 error value)."""
        return self.volts(self.config.error_value_mv)
