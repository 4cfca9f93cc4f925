"""hydromon.store.quietgc: automatic collection off inside the context, cycles still collected in idle(),
nesting across threads, the collector's state restored."""

from __future__ import annotations

import gc
import threading
import weakref

import pytest

from hydromon.store.quietgc import QuietGC


class _Node:
    pass


def _cycle():
    a, b = _Node(), _Node()
    a.other, b.other = b, a
    return weakref.ref(a)


def test_off_inside_restored_after_and_cycles_collected_when_due():
    assert gc.isenabled()
    now = [0.0]
    with QuietGC(young_s=0.1, full_s=1.0, clock=lambda: now[0], first_full_s=1.0) as q:
        assert not gc.isenabled()
        ref = _cycle()
        q.idle()  # not due yet: the cycle is still there
        assert ref() is not None and q.collections == 0
        now[0] = 0.2
        q.idle()  # due: the young generations are collected, and the cycle with them
        assert ref() is None and q.collections == 1
        now[0] = 1.5
        q.idle()  # a full collection
        assert q.collections == 2
    assert gc.isenabled() and gc.get_freeze_count() == 0


def test_a_full_collection_freezes_its_survivors_so_the_next_looks_only_at_newer_objects():
    now = [0.0]
    with QuietGC(young_s=0.1, full_s=30.0, clock=lambda: now[0], first_full_s=2.0) as q:
        frozen = gc.get_freeze_count()
        keep = [_Node() for _ in range(1000)]  # loaded after entry, alive for good
        now[0] = 1.0
        q.idle()  # young only
        assert gc.get_freeze_count() == frozen
        now[0] = 2.0
        q.idle()  # the first full collection, early: the survivors are frozen
        assert gc.get_freeze_count() >= frozen + len(keep)
        assert not any(o is keep[0] for o in gc.get_objects(2))
        ref = _cycle()  # cycles made afterwards are still found
        now[0] = 32.0
        q.idle()
        assert ref() is None and q.collections == 3
    assert gc.get_freeze_count() == 0


def test_nested_contexts_across_threads_restore_only_at_the_last_exit():
    inner_entered, release = threading.Event(), threading.Event()

    def other():
        with QuietGC():
            inner_entered.set()
            release.wait(10)

    with QuietGC():
        t = threading.Thread(target=other)
        t.start()
        assert inner_entered.wait(10)
    # the outer context has exited, the thread's has not: collection stays off
    assert not gc.isenabled()
    release.set()
    t.join(10)
    assert gc.isenabled() and gc.get_freeze_count() == 0


def test_without_collect_first_garbage_from_before_entry_is_collected_after_exit():
    # the entry freezes without collecting: a cycle that was garbage already must come back to the collector
    gc.collect()
    node = _Node()
    node.me = node
    ref = weakref.ref(node)
    del node
    with QuietGC(collect_first=False):
        gc.collect()
        assert ref() is not None  # frozen with everything alive on entry
    gc.collect()
    assert ref() is None
    node = _Node()
    node.me = node
    ref = weakref.ref(node)
    del node
    with QuietGC():  # collect_first: gone on entry
        assert ref() is None


def test_a_disabled_collector_stays_disabled():
    gc.disable()
    try:
        with QuietGC():
            pass
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_bad_intervals_are_refused():
    with pytest.raises(ValueError):
        QuietGC(young_s=0.0)
    with pytest.raises(ValueError):
        QuietGC(young_s=2.0, full_s=1.0)
    with pytest.raises(ValueError):
        QuietGC(full_s=10.0, first_full_s=20.0)
