"""The start-up heap is exempt from later garbage collections, and what is allocated afterwards
is still collected."""

from __future__ import annotations

import gc
import weakref

from wristmark.rig.loop.heap_freeze import freeze_heap


class _Node:
    def __init__(self) -> None:
        self.other: _Node | None = None


def _cycle() -> weakref.ref[_Node]:
    a, b = _Node(), _Node()
    a.other, b.other = b, a
    return weakref.ref(a)


def test_freeze_moves_the_live_heap_out_of_the_collector_and_later_garbage_is_still_collected() -> None:
    kept = _Node()
    try:
        before = gc.get_freeze_count()
        assert freeze_heap() >= 0.0
        assert gc.get_freeze_count() > before
        assert not any(o is kept for o in gc.get_objects())  # frozen: no collection walks it
        dead = _cycle()  # a reference cycle made after the freeze
        assert dead() is not None
        gc.collect()
        assert dead() is None
    finally:
        gc.unfreeze()
    assert any(o is kept for o in gc.get_objects())
