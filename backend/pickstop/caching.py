"""One bounded cache for every memo: the least recently used entries go first.

A :class:`Cache` is bounded by its number of entries (``max_items``), by their total weight
(``max_weight``: bytes, or whatever ``weigh`` counts), or both. It counts hits, misses and
evictions; :func:`cache_stats` reads them for every live cache in one place, by name.

Values are kept as they are, never copied: a value that grows in place is weighed again by
:meth:`Cache.reweigh`. Over the weight bound, the entry used last stays even alone (one entry
heavier than the bound is kept until another is used); over the item bound nothing stays
(``max_items=0`` keeps nothing).

A cache may be shared between threads: each call holds the cache's lock, never while
``make`` runs (:meth:`Cache.get_or_make`: two threads missing one key may both make it, the
last one is kept). A forked child gives every cache a new lock.
"""

from __future__ import annotations

import os
import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterator
from dataclasses import dataclass, replace
from typing import Any, Generic, TypeVar

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")

_MISSING: Any = object()


@dataclass(frozen=True)
class CacheStats:
    """What one cache, or every live cache of one name, holds and has done."""

    name: str
    caches: int  # live caches counted
    items: int
    weight: int  # total weight of the items (0 for a cache bounded by items alone)
    hits: int
    misses: int
    evictions: int  # entries dropped to keep within the bounds (not pop or clear)
    max_items: int | None  # per cache (None: not bounded so, or the caches differ)
    max_weight: int | None

    @property
    def hit_rate(self) -> float:
        """Hits per lookup (0 before the first lookup)."""
        n = self.hits + self.misses
        return self.hits / n if n else 0.0

    def merged(self, other: CacheStats) -> CacheStats:
        """The figures of this cache and ``other`` (of the same name) together."""
        return replace(
            self,
            caches=self.caches + other.caches,
            items=self.items + other.items,
            weight=self.weight + other.weight,
            hits=self.hits + other.hits,
            misses=self.misses + other.misses,
            evictions=self.evictions + other.evictions,
            max_items=self.max_items if self.max_items == other.max_items else None,
            max_weight=self.max_weight if self.max_weight == other.max_weight else None,
        )


class Cache(Generic[K, V]):
    """A bounded map of memo entries, least recently used first (see the module).

    name: what :func:`cache_stats` lists it under (caches of one name are summed).
    max_items: most entries kept (None: no bound by count).
    max_weight: most total weight kept (None: no bound by weight); needs ``weigh``.
    weigh: a value's weight, a non-negative int (e.g. its bytes).

    Lookups (:meth:`get`, :meth:`get_or_make`) count a hit or a miss and make the entry the
    most recently used; :meth:`peek`, ``in``, ``cache[key]`` and iteration (least recently
    used first) do neither.
    """

    def __init__(
        self,
        name: str,
        *,
        max_items: int | None = None,
        max_weight: int | None = None,
        weigh: Callable[[V], int] | None = None,
    ) -> None:
        if max_items is None and max_weight is None:
            raise ValueError(f"cache {name!r}: give max_items, max_weight or both")
        if max_items is not None and max_items < 0:
            raise ValueError(f"cache {name!r}: max_items must be >= 0, got {max_items}")
        if max_weight is not None and (max_weight < 0 or weigh is None):
            raise ValueError(f"cache {name!r}: max_weight needs weigh and must be >= 0")
        self.name = name
        self.max_items = max_items
        self.max_weight = max_weight
        self._weigh = weigh
        self._data: OrderedDict[K, V] = OrderedDict()
        self._weights: dict[K, int] = {}
        self._weight = 0
        self._hits = self._misses = self._evictions = 0
        self._lock = threading.Lock()
        _CACHES.add(self)

    # -- lookups -------------------------------------------------------------------------------
    def get(self, key: K, *, touch: bool = True) -> V | None:
        """The value of ``key`` (None: not kept), counted as a hit or a miss; ``touch``: made
        the most recently used."""
        with self._lock:
            value = self._data.get(key, _MISSING)
            if value is _MISSING:
                self._misses += 1
                return None
            self._hits += 1
            if touch:
                self._data.move_to_end(key)
            return value  # type: ignore[no-any-return]

    def get_or_make(self, key: K, make: Callable[[], V]) -> V:
        """The value of ``key``, else ``make()`` kept under it (None is a value too)."""
        with self._lock:
            value = self._data.get(key, _MISSING)
            if value is not _MISSING:
                self._hits += 1
                self._data.move_to_end(key)
                return value  # type: ignore[no-any-return]
            self._misses += 1
        made = make()
        self.put(key, made)
        return made

    def peek(self, key: K) -> V | None:
        """The value of ``key`` (None: not kept), neither counted nor touched."""
        return self._data.get(key)

    def __getitem__(self, key: K) -> V:
        return self._data[key]

    def __contains__(self, key: object) -> bool:
        return key in self._data

    def __len__(self) -> int:
        return len(self._data)

    def __iter__(self) -> Iterator[K]:
        """The keys, least recently used first (a copy: the cache may change meanwhile)."""
        return iter(self.keys())

    def keys(self) -> list[K]:
        with self._lock:
            return list(self._data)

    def values(self) -> list[V]:
        with self._lock:
            return list(self._data.values())

    def items(self) -> list[tuple[K, V]]:
        with self._lock:
            return list(self._data.items())

    @property
    def weight(self) -> int:
        """The total weight of the entries (as last weighed)."""
        return self._weight

    # -- changes -------------------------------------------------------------------------------
    def put(self, key: K, value: V) -> V:
        """Keep ``value`` under ``key`` as the most recently used, then drop the least
        recently used entries while over a bound; returns ``value``."""
        w = 0 if self._weigh is None else int(self._weigh(value))
        with self._lock:
            self._data[key] = value
            self._data.move_to_end(key)
            if self._weigh is not None:
                self._weight += w - self._weights.get(key, 0)
                self._weights[key] = w
            self._evict()
        return value

    def touch(self, key: K) -> None:
        """Make ``key`` the most recently used, if kept (not counted)."""
        with self._lock:
            if key in self._data:
                self._data.move_to_end(key)

    def pop(self, key: K) -> V | None:
        """Drop ``key``; its value (None: not kept)."""
        with self._lock:
            self._weight -= self._weights.pop(key, 0)
            return self._data.pop(key, None)

    def clear(self) -> None:
        """Drop every entry (the counts stay)."""
        with self._lock:
            self._data.clear()
            self._weights.clear()
            self._weight = 0

    def reweigh(self) -> None:
        """Weigh every entry again (values that grew or shrank in place), then drop the least
        recently used while over a bound."""
        weigh = self._weigh
        if weigh is None:
            return
        with self._lock:
            self._weights = {k: int(weigh(v)) for k, v in self._data.items()}
            self._weight = sum(self._weights.values())
            self._evict()

    def _evict(self) -> None:
        """Drop the least recently used entries while over a bound (the lock held)."""
        data, n_max, w_max = self._data, self.max_items, self.max_weight
        while data and (
            (n_max is not None and len(data) > n_max)
            or (w_max is not None and self._weight > w_max and len(data) > 1)
        ):
            key, _ = data.popitem(last=False)
            self._weight -= self._weights.pop(key, 0)
            self._evictions += 1

    # -- figures -------------------------------------------------------------------------------
    def stats(self) -> CacheStats:
        """This cache's figures."""
        with self._lock:
            return CacheStats(
                self.name, 1, len(self._data), self._weight, self._hits, self._misses,
                self._evictions, self.max_items, self.max_weight,
            )  # fmt: skip

    def __getstate__(self) -> dict[str, Any]:
        """Pickled with its entries and counts, not its lock (a process of its own gets one)."""
        with self._lock:
            state = dict(self.__dict__)
        del state["_lock"]
        state["_data"] = OrderedDict(state["_data"])
        state["_weights"] = dict(state["_weights"])
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()
        _CACHES.add(self)

    def __repr__(self) -> str:
        return (
            f"Cache({self.name!r}, items={len(self._data)}, weight={self._weight}, "
            f"max_items={self.max_items}, max_weight={self.max_weight})"
        )


#: Every live cache, for :func:`cache_stats` (a cache that is garbage leaves it).
_CACHES: weakref.WeakSet[Cache[Any, Any]] = weakref.WeakSet()


def cache_stats() -> dict[str, CacheStats]:
    """The figures of every live cache of this process by name, caches of one name summed
    (e.g. the memos of every region kit), sorted by name."""
    out: dict[str, CacheStats] = {}
    for cache in list(_CACHES):
        s = cache.stats()
        out[s.name] = out[s.name].merged(s) if s.name in out else s
    return dict(sorted(out.items()))


def _new_locks() -> None:
    """In a forked child: a lock another thread of the parent held stays held in the child,
    so every cache gets a new one."""
    for cache in list(_CACHES):
        cache._lock = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_new_locks)
