"""Plant emulators: physical models of the rigs and the CAN devices they play."""
