"""agrihil core: buses, clocks, recording, the CLI and (later) runners, metrics and reports."""

from hil.errors import HilError

__all__ = ["HilError", "__version__"]
__version__ = "0.1.0"
