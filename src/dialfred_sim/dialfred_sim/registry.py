"""A registry of named extensions of one kind (no ROS): task types, jobs, question types' rules, performer
models each keep theirs in one.

    r = Registry('task type')
    r.add(name, item)      # ValueError if the name is taken
    r.named(name)          # the item; ValueError naming the known ones otherwise
    r.remove(name)         # ValueError if none is registered so
    name in r, list(r), r.values(), r.get(name)    # read as a mapping, in the order of registration
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Generic, TypeVar

T = TypeVar('T')


class Registry(Mapping, Generic[T]):
    """Items by name, in the order they were registered; `what` names the kind in its errors (and
    `sorted_names` lists the known names sorted there)."""

    def __init__(self, what: str, sorted_names: bool = False):
        self.what, self.sorted_names = what, sorted_names
        self._items: dict[str, T] = {}

    def add(self, name: str, item: T) -> T:
        if name in self._items:
            raise ValueError(f'a {self.what} named {name!r} is registered already')
        self._items[name] = item
        return item

    def remove(self, name: str) -> T:
        if name not in self._items:
            raise ValueError(f'no {self.what} named {name!r} is registered')
        return self._items.pop(name)

    def named(self, name: str) -> T:
        if name not in self._items:
            known = sorted(self._items) if self.sorted_names else list(self._items)
            raise ValueError(f'unknown {self.what} {name!r}; expected one of {", ".join(known)}')
        return self._items[name]

    def __getitem__(self, name: str) -> T:
        return self._items[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __repr__(self) -> str:
        return f'Registry({self.what!r}: {", ".join(self._items)})'
