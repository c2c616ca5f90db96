"""Lists built when first read, for the drop-in trackers' Stone Soup tracks
(`usvfast.stonesoup`).

A drop-in `Track` is a plain `stonesoup.types.track.Track` whose `states` and `metadatas`
lists are `LazyList`s: between scans they may lack the newest states, which the core holds
in its history. Any read or change of either list (len, indexing, iteration, `in`, comparison,
copy, pickling, every list method; so also `track.state`, `len(track)`, iterating a track,
`track.metadata`, `Track.append`) first calls the track's filler, which appends the missing
states (and their metadata) exactly as Stone Soup's tracker would have appended them, then
disarms itself until the next scan arms it again. Copies and pickles of a `LazyList` are plain
lists.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any


class LazyList(list):
    """A `list` that calls `_fill()` (when set) before its contents are read or changed.

    `_fill` is a callable without arguments that appends the missing items through the
    `list` methods (it is cleared before it is called, so the list behaves as a plain one
    meanwhile)."""

    __slots__ = ("_fill",)

    def __init__(self, *args: Any) -> None:
        super().__init__(*args)
        self._fill: Callable[[], None] | None = None

    def _force(self) -> None:
        f = self._fill
        if f is not None:
            self._fill = None
            f()

    # The hot reads, written out.
    def __len__(self) -> int:
        if self._fill is not None:
            self._force()
        return list.__len__(self)

    def __getitem__(self, index: Any) -> Any:
        if self._fill is not None:
            self._force()
        return list.__getitem__(self, index)

    def __iter__(self) -> Any:
        if self._fill is not None:
            self._force()
        return list.__iter__(self)

    # Plain results for copies, pickles and concatenation.
    def __copy__(self) -> list:
        self._force()
        return list(list.__iter__(self))

    def __deepcopy__(self, memo: dict) -> list:
        self._force()
        out: list = []
        memo[id(self)] = out
        out.extend(copy.deepcopy(x, memo) for x in list.__iter__(self))
        return out

    def __reduce_ex__(self, protocol: Any) -> Any:
        self._force()
        return (list, (list(list.__iter__(self)),))

    def __reduce__(self) -> Any:
        return self.__reduce_ex__(2)

    def __radd__(self, other: Any) -> Any:
        self._force()
        if isinstance(other, list):
            return list.__add__(list(other), list(list.__iter__(self)))
        return NotImplemented


def _forcing(name: str) -> Callable:
    base = getattr(list, name)

    def method(self: LazyList, *args: Any, **kwargs: Any) -> Any:
        if self._fill is not None:
            self._force()
        return base(self, *args, **kwargs)

    method.__name__ = name
    method.__qualname__ = f"LazyList.{name}"
    method.__doc__ = base.__doc__
    return method


# Every other list method and operator: fill first, then the list's own.
for _name in (
    "__setitem__",
    "__delitem__",
    "__reversed__",
    "__contains__",
    "__eq__",
    "__ne__",
    "__lt__",
    "__le__",
    "__gt__",
    "__ge__",
    "__add__",
    "__iadd__",
    "__mul__",
    "__rmul__",
    "__imul__",
    "__repr__",
    "__str__",
    "__format__",
    "__sizeof__",
    "append",
    "extend",
    "insert",
    "pop",
    "remove",
    "index",
    "count",
    "sort",
    "reverse",
    "clear",
    "copy",
):
    setattr(LazyList, _name, _forcing(_name))
del _name
