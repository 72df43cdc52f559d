"""What a computation may keep between calls, and the algorithm's own choice: nothing.

The region pipeline's helpers (the kit's grasps, open-hand spaces, object bounds and own
verdicts; the exact arm's solid bounds; the footprint's blocked regions) are pure functions
of their keys. Each asks a :class:`Keep` for an earlier answer; from scratch that is
:class:`KeepNothing`, which remembers nothing, so every answer is computed. The speed-ups
(:mod:`pickstop.speedups.region_planner`) hand in bounded caches instead
(:class:`pickstop.caching.Cache` is a :class:`Keep`); the answers are the same either way.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any, Protocol, TypeVar

K = TypeVar("K")
V = TypeVar("V")


class Keep(Protocol[K, V]):
    """Answers kept by key (the subset of :class:`pickstop.caching.Cache` computations use)."""

    def get(self, key: K) -> V | None:
        """The answer kept under ``key`` (None: none kept)."""
        ...

    def put(self, key: K, value: V) -> V:
        """Keep ``value`` under ``key`` (or not); returns ``value``."""
        ...

    def get_or_make(self, key: K, make: Callable[[], V]) -> V:
        """The answer kept under ``key``, else ``make()`` (kept, or not)."""
        ...

    def __iter__(self) -> Iterator[K]: ...

    def items(self) -> list[tuple[K, V]]: ...


class KeepNothing:
    """A :class:`Keep` that remembers nothing: every answer is made anew."""

    def get(self, key: Any) -> None:
        return None

    def put(self, key: Any, value: V) -> V:
        return value

    def get_or_make(self, key: Any, make: Callable[[], V]) -> V:
        return make()

    def __iter__(self) -> Iterator[Any]:
        return iter(())

    def items(self) -> list[tuple[Any, Any]]:
        return []
