"""Registries: the named variants of one concept (methods, inertia forms), each added by one entry.

A :class:`Registry` is a dict in registration order, so ``list(r)``, ``r.values()`` and
``name in r`` work as usual; :meth:`Registry.get_checked` is the one lookup that fails with a
:class:`~hconv.errors.UsageError` naming the choices, in the same words for every concept.
"""

from __future__ import annotations

from typing import TypeVar

from hconv.errors import UsageError

T = TypeVar("T")


class Registry(dict[str, T]):
    """Named variants of one concept, in the order they were added."""

    def __init__(self, what: str):
        super().__init__()
        self.what = what  #: how messages name one entry, e.g. "method"

    def add(self, name: str, entry: T) -> T:
        """Add ``entry`` under ``name``; a name can be added once."""
        if name in self:
            raise ValueError(f"{self.what} {name!r} is already registered")
        self[name] = entry
        return entry

    def get_checked(self, name: str) -> T:
        """The entry called ``name``; UsageError (a ValueError) naming the choices otherwise."""
        try:
            return self[name]
        except KeyError:
            raise UsageError(f"unknown {self.what} {name!r}; choose one of: {', '.join(self)}") from None
