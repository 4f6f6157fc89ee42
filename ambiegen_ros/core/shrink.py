"""Delta debugging: the fewest parts of a failing input that still fail (Zeller and Hildebrandt's ddmin).

A fuzzer's finding is reported on a minimal input, and so is ours: a failing map is shrunk to the
walls and cells without which the failure goes. ``Ddmin`` is the algorithm as ask and tell, one
candidate at a time, because each test is a run on a real stack that a runner schedules: ``ask``
gives the next subset to try, ``tell`` whether it still failed. It tries the complements (the
parts minus one of ``n`` chunks): a failing complement is kept and ``n`` drops by one, a round with
none doubles ``n``, and with ``n`` at the number of parts no single part can go: the result is
1-minimal (removing any one part loses the failure), assuming the test is deterministic.
"""
from __future__ import annotations

from typing import Generic, Sequence, TypeVar

T = TypeVar("T")


def chunks(items: Sequence[T], n: int) -> list[list[T]]:
    """``items`` in ``n`` consecutive chunks whose sizes differ by one at most."""
    n = max(1, min(n, len(items)))
    size, extra = divmod(len(items), n)
    out, start = [], 0
    for i in range(n):
        end = start + size + (i < extra)
        out.append(list(items[start:end]))
        start = end
    return out


class Ddmin(Generic[T]):
    """ddmin over ``parts`` (hashable, kept in their order). ``ask()`` -> the parts to keep in the next test,
    or None once minimal; ``tell(failed)`` -> that test's answer. ``current`` is the smallest
    failing set so far (the input itself, which must fail, until a test says otherwise)."""

    def __init__(self, parts: Sequence[T]):
        self.current: list[T] = list(parts)
        self.n = 2
        self.tests = 0
        self._round: list[list[T]] = []
        self._next = 0
        self._asked: list[T] | None = None
        self._new_round()

    def _new_round(self) -> None:
        if not self.current:
            self._round = []
            return
        self.n = min(self.n, len(self.current))
        keep = [[p for p in self.current if p not in gone] for gone in (set(c) for c in chunks(self.current, self.n))]
        self._round, self._next = keep, 0

    @property
    def done(self) -> bool:
        return self._next >= len(self._round)

    def ask(self) -> list[T] | None:
        if self._asked is not None:
            return self._asked
        if self.done:
            return None
        self._asked = self._round[self._next]
        return self._asked

    def tell(self, failed: bool) -> None:
        if self._asked is None:
            raise RuntimeError("tell() without ask()")
        tried, self._asked = self._asked, None
        self.tests += 1
        if failed:  # the failure survives without that chunk: keep the smaller set, one chunk fewer
            self.current = tried
            self.n = max(self.n - 1, 2)
            self._new_round()
            return
        self._next += 1
        if self.done and self.n < len(self.current):  # no chunk could go: finer chunks
            self.n = min(2 * self.n, len(self.current))
            self._new_round()


__all__ = ["Ddmin", "chunks"]
