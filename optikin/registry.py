"""Name -> implementation registries for arms, problem kinds and solver backends.

Later modules extend them with ``@ARMS.register("name")`` etc.; an unknown name
raises :class:`optikin.errors.UnknownNameError` listing the known ones.
"""

from __future__ import annotations

from typing import Callable, Generic, TypeVar

from optikin.errors import UnknownNameError

T = TypeVar("T")


class Registry(Generic[T]):
    """A named collection of implementations of one kind of thing."""

    def __init__(self, what: str):
        self.what = what
        self._items: dict[str, T] = {}

    def register(self, name: str) -> Callable[[T], T]:
        def add(item: T) -> T:
            if name in self._items:
                raise ValueError(f"{self.what} {name!r} is registered twice")
            self._items[name] = item
            return item

        return add

    def get(self, name: str) -> T:
        if name not in self._items:
            raise UnknownNameError(self.what, name, list(self._items))
        return self._items[name]

    def names(self) -> list[str]:
        return sorted(self._items)

    def __contains__(self, name: str) -> bool:
        return name in self._items


ARMS: Registry[Callable[..., object]] = Registry("arm")
PROBLEM_KINDS: Registry[object] = Registry("problem kind")
BACKENDS: Registry[object] = Registry("solver backend")
