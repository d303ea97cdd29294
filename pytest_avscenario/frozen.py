"""A compact read-only mapping, for what a run holds per case to its end.

A 100,000-case campaign keeps every case's slot (its parameters, from collection on) and
every row (its parameters and ρ per metric, to the report). As dicts behind read-only views
those cost ~0.25 KB each; the names repeat from case to case, so here they are one tuple the
mappings of a test share, and each mapping keeps a tuple of its values (issue #35).
"""

from __future__ import annotations

import sys
from collections.abc import Iterator, Mapping
from typing import Any


class CompactMapping(Mapping):
    """A read-only ``{name: value}``: the names are one tuple that every mapping of the same
    names shares, the values a tuple of its own. Equal to the dict of the same items."""

    __slots__ = ("_names", "_values")

    #: the shared name tuples: the slots and rows of a test have the same names
    _known: dict[tuple[str, ...], tuple[str, ...]] = {}

    def __init__(self, items: Mapping[str, Any]):
        names = tuple(items)
        shared = CompactMapping._known.get(names)
        if shared is None:
            if len(CompactMapping._known) > 4096:  # mappings of many shapes: nothing left to share
                CompactMapping._known.clear()
            shared = CompactMapping._known[names] = tuple(
                sys.intern(n) if type(n) is str else n for n in names)
        self._names = shared
        self._values = tuple(items.values())

    @classmethod
    def of(cls, items: Mapping[str, Any]) -> "CompactMapping":
        """``items`` as a compact mapping (itself if it is one already)."""
        return items if type(items) is cls else cls(items)

    def __getitem__(self, key: str) -> Any:
        try:  # a handful of names: a scan (in C) beats a shared index dict
            return self._values[self._names.index(key)]
        except ValueError:
            raise KeyError(key) from None

    def get(self, key: str, default: Any = None) -> Any:
        try:
            return self._values[self._names.index(key)]
        except ValueError:
            return default

    def __iter__(self) -> Iterator[str]:
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)

    def __contains__(self, key: object) -> bool:
        return key in self._names

    def __eq__(self, other: object) -> bool:
        if isinstance(other, CompactMapping):
            if self._names == other._names:
                return self._values == other._values
            return dict(zip(self._names, self._values)) == dict(zip(other._names, other._values))
        if isinstance(other, Mapping):
            return dict(zip(self._names, self._values)) == dict(other.items())
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]  # as a dict's

    def __repr__(self) -> str:
        return repr(dict(zip(self._names, self._values)))

    def __reduce__(self) -> Any:
        return (CompactMapping, (dict(zip(self._names, self._values)),))
