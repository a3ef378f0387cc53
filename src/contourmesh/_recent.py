"""A memory of a deterministic function's last few answers, keyed by what the function reads.

The general mesher asks some questions again with the same arguments: a bridged join built once
more after a pass restarts, a band whose rules are tried twice, a keyhole search repeated inside a
sectioned join.  Each such function keeps a :class:`Recent` of its last answers, keyed by the bytes
(shapes, dtypes) of its arguments and the settings it reads, so that the same key always gets the
answer the function would give.  What is kept and what is handed out (a read-only copy kept, a
fresh copy returned) stays with the caller, who knows which answers are mutable.
"""

from __future__ import annotations

import threading

#: What :meth:`Recent.get` returns for a key it does not hold, where the caller asks for it (an
#: answer may itself be None).
MISSING = object()


class Recent:
    """The answers put for the last ``keep`` keys, the oldest put dropped first (first in, first
    out: reading a key does not keep it longer).  Safe for meshers running in threads of one
    process: a put and its evictions happen under a lock; two threads that miss the same key both
    compute the same answer and the second put replaces the first."""

    __slots__ = ("keep", "_seen", "_lock")

    def __init__(self, keep: int):
        keep = int(keep)
        if keep < 1:
            raise ValueError(f"keep must be at least 1; got {keep}")
        self.keep = keep
        self._seen: dict = {}
        self._lock = threading.Lock()

    def get(self, key, default=None):
        """The answer kept for ``key``, else ``default``."""
        return self._seen.get(key, default)

    def put(self, key, value) -> None:
        """Keep ``value`` for ``key``, dropping the oldest keys beyond :attr:`keep`."""
        with self._lock:
            while len(self._seen) >= self.keep:
                del self._seen[next(iter(self._seen))]  # the oldest (dicts keep insertion order)
            self._seen[key] = value

    def clear(self) -> None:
        with self._lock:
            self._seen.clear()

    def items(self):
        """The kept ``(key, answer)`` pairs, oldest first."""
        return self._seen.items()

    def __len__(self) -> int:
        return len(self._seen)

    def __contains__(self, key) -> bool:
        return key in self._seen
