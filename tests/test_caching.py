"""The one cache primitive: bounds respected, least recently used first, figures counted and
readable in one place; against a plain reference over random calls."""

from __future__ import annotations

import gc
import os
import signal
import threading

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop.caching import Cache, cache_stats

KEYS = st.integers(0, 7)
OPS = st.lists(
    st.one_of(
        st.tuples(st.just("put"), KEYS, st.integers(0, 5)),
        st.tuples(st.just("get"), KEYS, st.just(0)),
        st.tuples(st.just("make"), KEYS, st.integers(0, 5)),
        st.tuples(st.just("peek"), KEYS, st.just(0)),
        st.tuples(st.just("touch"), KEYS, st.just(0)),
        st.tuples(st.just("pop"), KEYS, st.just(0)),
        st.tuples(st.just("grow"), KEYS, st.integers(0, 5)),
    ),
    max_size=60,
)


class Reference:
    """The same cache, obviously: a list of [key, value] least recently used first; values
    are one-element lists whose element is the weight."""

    def __init__(self, max_items: int | None, max_weight: int | None) -> None:
        self.max_items, self.max_weight = max_items, max_weight
        self.entries: list[list] = []
        self.hits = self.misses = self.evictions = 0
        self.weights: dict[int, int] = {}  # as last weighed

    def find(self, key):
        return next((e for e in self.entries if e[0] == key), None)

    def use(self, e):
        self.entries.remove(e)
        self.entries.append(e)

    def put(self, key, value):
        e = self.find(key)
        if e is not None:
            self.entries.remove(e)
        self.entries.append([key, value])
        self.weights[key] = value[0]
        self.evict()

    def weight(self):
        return sum(self.weights[k] for k, _ in self.entries)

    def evict(self):
        while self.entries and (
            (self.max_items is not None and len(self.entries) > self.max_items)
            or (
                self.max_weight is not None
                and self.weight() > self.max_weight
                and len(self.entries) > 1
            )
        ):
            self.entries.pop(0)
            self.evictions += 1

    def get(self, key):
        e = self.find(key)
        if e is None:
            self.misses += 1
            return None
        self.hits += 1
        self.use(e)
        return e[1]


@settings(max_examples=300, deadline=None)
@given(
    ops=OPS,
    max_items=st.one_of(st.none(), st.integers(0, 5)),
    max_weight=st.one_of(st.none(), st.integers(0, 12)),
)
def test_the_cache_behaves_as_the_reference(ops, max_items, max_weight):
    if max_items is None and max_weight is None:
        max_items = 3
    cache: Cache[int, list[int]] = Cache(
        "test.reference", max_items=max_items, max_weight=max_weight, weigh=lambda v: v[0]
    )
    ref = Reference(max_items, max_weight)
    for op, key, w in ops:
        if op == "put":
            cache.put(key, [w])
            ref.put(key, [w])
        elif op == "get":
            assert cache.get(key) == ref.get(key)
        elif op == "make":
            got = cache.get_or_make(key, lambda w=w: [w])
            kept = ref.get(key)
            if kept is None:
                kept = [w]
                ref.put(key, kept)
            assert got == kept
        elif op == "peek":
            e = ref.find(key)
            assert cache.peek(key) == (None if e is None else e[1])
        elif op == "touch":
            cache.touch(key)
            if (e := ref.find(key)) is not None:
                ref.use(e)
        elif op == "pop":
            e = ref.find(key)
            assert cache.pop(key) == (None if e is None else e[1])
            if e is not None:
                ref.entries.remove(e)
        elif op == "grow" and (e := ref.find(key)) is not None:  # changed in place, reweighed
            cache.peek(key)[0] = w
            e[1][0] = w
            cache.reweigh()
            ref.weights = {k: v[0] for k, v in ref.entries}
            ref.evict()
        # The same entries in the same order, within the bounds (the entry used last may
        # stay alone over the weight bound).
        assert cache.items() == [tuple(e) for e in ref.entries]
        assert max_items is None or len(cache) <= max_items
        assert max_weight is None or cache.weight <= max_weight or len(cache) == 1
        s = cache.stats()
        assert (s.hits, s.misses, s.evictions) == (ref.hits, ref.misses, ref.evictions)
        if max_weight is not None:
            assert s.weight == cache.weight == ref.weight()


def test_the_least_recently_used_goes_first():
    c: Cache[str, int] = Cache("test.lru", max_items=2)
    c.put("a", 1)
    c.put("b", 2)
    assert c.get("a") == 1  # a used: b is now the least recently used
    c.put("c", 3)
    assert list(c) == ["a", "c"] and "b" not in c
    assert c.peek("a") == 1 and list(c) == ["a", "c"]  # a peek changes no order
    c.put("d", 4)
    assert list(c) == ["c", "d"]
    s = c.stats()
    assert (s.hits, s.misses, s.evictions, s.items) == (1, 0, 2, 2)


def test_a_weight_bound_keeps_the_entry_used_last_even_alone():
    c: Cache[str, bytes] = Cache("test.bytes", max_weight=10, weigh=len)
    c.put("a", b"12345")
    c.put("b", b"123456")  # 11 > 10: a goes
    assert list(c) == ["b"] and c.weight == 6
    c.put("c", b"x" * 30)  # heavier than the bound alone: kept, b goes
    assert list(c) == ["c"] and c.weight == 30
    c.put("d", b"")
    assert list(c) == ["d"] and c.weight == 0


def test_no_items_keeps_nothing_and_none_is_a_value():
    nothing: Cache[str, int] = Cache("test.nothing", max_items=0)
    nothing.put("a", 1)
    assert len(nothing) == 0 and nothing.get("a") is None
    calls = []
    c: Cache[str, None] = Cache("test.none", max_items=4)
    for _ in range(3):
        assert c.get_or_make("k", lambda: calls.append(1)) is None
    assert calls == [1] and c.stats().hits == 2


def test_a_cache_needs_a_bound():
    with pytest.raises(ValueError, match="max_items, max_weight"):
        Cache("test.unbounded")
    with pytest.raises(ValueError, match="weigh"):
        Cache("test.weightless", max_weight=10)
    with pytest.raises(ValueError, match=">= 0"):
        Cache("test.negative", max_items=-1)


def test_every_cache_is_listed_by_name_and_leaves_with_its_cache():
    a: Cache[int, int] = Cache("test.listed", max_items=4)
    b: Cache[int, int] = Cache("test.listed", max_items=4)
    a.put(1, 1)
    a.get(1)
    b.get(2)
    b.put(2, 2)
    s = cache_stats()["test.listed"]
    assert (s.caches, s.items, s.hits, s.misses, s.max_items) == (2, 2, 1, 1, 4)
    assert s.hit_rate == 0.5
    del a, b
    gc.collect()
    assert "test.listed" not in cache_stats()


def test_threads_sharing_a_cache_keep_it_within_its_bounds():
    c: Cache[int, bytes] = Cache("test.threads", max_items=50, max_weight=400, weigh=len)

    def work(seed: int) -> None:
        for i in range(2000):
            k = (seed * 7919 + i * 31) % 200
            if c.get(k) is None:
                c.put(k, b"x" * (k % 13))

    threads = [threading.Thread(target=work, args=(s,)) for s in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(c) <= 50 and c.weight <= 400
    assert c.weight == sum(len(v) for v in c.values())
    s = c.stats()
    assert s.hits + s.misses == 4 * 2000


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork here")
def test_a_forked_child_uses_a_cache_whose_lock_the_parent_held():
    c: Cache[int, int] = Cache("test.fork", max_items=4)
    with c._lock:  # held (as by another thread) while the process forks
        pid = os.fork()
        if pid == 0:  # the child: a held lock would hang here
            code = 1
            try:
                signal.alarm(10)
                c.put(1, 1)
                code = 0 if c.get(1) == 1 else 1
            finally:
                os._exit(code)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0


def test_a_cache_pickles_with_its_entries_and_a_lock_of_its_own():
    import pickle

    c = Cache("test.pickled", max_items=2)
    c.put("a", 1)
    c.put("b", 2)
    c.get("a")
    d = pickle.loads(pickle.dumps(c))
    assert d.keys() == ["b", "a"] and d.stats().hits == 1
    d.put("c", 3)
    assert d.keys() == ["a", "c"] and c.keys() == ["b", "a"]
    assert d._lock is not c._lock
