"""An indexed binary min-heap on flat arrays, for the compiled searches (2-D Dijkstra and ARA*).

The heap is a `Heap` of arrays: `keys[1..n]`, `items[1..n]`, with `n = size[0]`; `pos[item]` is the item's slot,
0 when it is not in the heap. Each item is in the heap at most once, so a decrease of its key is a
sift-up, never a duplicate. (numba's on-disk cache does not see edits to this module from the
modules that call it: clear their `__pycache__/*.nbi` after changing it.)
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from trials.lattice.compiled import inlined_kernel, kernel


class Heap(NamedTuple):
    """The heap's arrays, passed to the compiled functions as one argument."""

    keys: np.ndarray   # int64, slots 1..n
    items: np.ndarray  # int32, slots 1..n
    pos: np.ndarray    # int32, per item: its slot, 0 when not in the heap
    size: np.ndarray   # int64, [n]


def new_heap(capacity: int) -> Heap:
    """An empty heap for up to `capacity` items numbered 0..capacity-1."""
    return Heap(np.zeros(capacity + 1, np.int64), np.zeros(capacity + 1, np.int32), np.zeros(capacity, np.int32),
                np.zeros(1, np.int64))


@inlined_kernel
def _place(heap, slot, key, item):
    heap.keys[slot] = key
    heap.items[slot] = item
    heap.pos[item] = slot


@kernel
def sift_up(heap, slot):
    keys, items = heap.keys, heap.items
    key, item = keys[slot], items[slot]
    while slot > 1:
        parent = slot >> 1
        if keys[parent] <= key:
            break
        _place(heap, slot, keys[parent], items[parent])
        slot = parent
    _place(heap, slot, key, item)


@kernel
def sift_down(heap, slot):
    keys, items = heap.keys, heap.items
    n = heap.size[0]
    key, item = keys[slot], items[slot]
    while True:
        child = slot << 1
        if child > n:
            break
        if child < n and keys[child + 1] < keys[child]:
            child += 1
        if keys[child] >= key:
            break
        _place(heap, slot, keys[child], items[child])
        slot = child
    _place(heap, slot, key, item)


@kernel
def push_or_update(heap, item, key):
    """Insert `item` with `key`, or move it to `key` if it is already in the heap."""
    slot = heap.pos[item]
    if slot == 0:
        heap.size[0] += 1
        slot = heap.size[0]
        _place(heap, slot, key, item)
        sift_up(heap, slot)
    elif key < heap.keys[slot]:
        heap.keys[slot] = key
        sift_up(heap, slot)
    elif key > heap.keys[slot]:
        heap.keys[slot] = key
        sift_down(heap, slot)


@kernel
def pop_min(heap):
    """Remove and return the item of the smallest key (the heap must not be empty)."""
    top = heap.items[1]
    heap.pos[top] = 0
    n = heap.size[0]
    heap.size[0] = n - 1
    if n > 1:
        _place(heap, 1, heap.keys[n], heap.items[n])
        sift_down(heap, 1)
    return top


@kernel
def heapify(heap):
    """Restore the heap order after keys were changed in place."""
    for slot in range(heap.size[0] >> 1, 0, -1):
        sift_down(heap, slot)
