"""A record kept in memory without growing with run time: the first entries and the latest.

The VT's events, command records and responses are lists a run's record and the browser VT
read. A working set that sends thousands of commands a second for hours must not grow them
without bound: :class:`BoundedLog` is a list that keeps its first ``head`` entries (how the run
began) and the latest ones, ``limit`` in all, and counts what it left out between them.
"""

from __future__ import annotations

from typing import TypeVar

_T = TypeVar("_T")


class BoundedLog(list[_T]):
    """A list of at most ``limit`` entries: the first ``head`` and the latest.

    Attributes
    ----------
    total : int
        Entries ever appended.
    omitted : int
        Entries left out (``total - len(self)``).
    """

    def __init__(self, limit: int, head: int | None = None) -> None:
        super().__init__()
        if limit < 2:
            raise ValueError(f"a bounded log keeps at least 2 entries, not {limit}")
        self.limit = limit
        self.head = limit // 4 if head is None else min(head, limit - 1)
        self.total = 0
        self.omitted = 0

    def append(self, item: _T) -> None:
        """Add ``item``; past ``limit``, drop a quarter of the entries after the head."""
        super().append(item)
        self.total += 1
        if len(self) > self.limit:
            cut = max(1, (self.limit - self.head) // 4)
            del self[self.head:self.head + cut]
            self.omitted += cut
