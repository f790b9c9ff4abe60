"""An indexed binary min-heap on flat arrays, for the compiled searches (2-D Dijkstra and ARA*).

The heap lives in `keys[1..n]`, `items[1..n]`, with `n = size[0]`; `pos[item]` is the item's slot,
0 when it is not in the heap. Each item is in the heap at most once, so a decrease of its key is a
sift-up, never a duplicate. (numba's on-disk cache does not see edits to this module from the
modules that call it: clear their `__pycache__/*.nbi` after changing it.)
"""

from __future__ import annotations

import numpy as np
from numba import njit


def new_heap(capacity: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Empty heap arrays for up to `capacity` items numbered 0..capacity-1: keys, items, pos, size."""
    return (np.zeros(capacity + 1, np.int64), np.zeros(capacity + 1, np.int32), np.zeros(capacity, np.int32),
            np.zeros(1, np.int64))


@njit(cache=True, inline="always")
def _place(keys, items, pos, slot, key, item):
    keys[slot] = key
    items[slot] = item
    pos[item] = slot


@njit(cache=True)
def sift_up(keys, items, pos, slot):
    key, item = keys[slot], items[slot]
    while slot > 1:
        parent = slot >> 1
        if keys[parent] <= key:
            break
        _place(keys, items, pos, slot, keys[parent], items[parent])
        slot = parent
    _place(keys, items, pos, slot, key, item)


@njit(cache=True)
def sift_down(keys, items, pos, size, slot):
    n = size[0]
    key, item = keys[slot], items[slot]
    while True:
        child = slot << 1
        if child > n:
            break
        if child < n and keys[child + 1] < keys[child]:
            child += 1
        if keys[child] >= key:
            break
        _place(keys, items, pos, slot, keys[child], items[child])
        slot = child
    _place(keys, items, pos, slot, key, item)


@njit(cache=True)
def push_or_update(keys, items, pos, size, item, key):
    """Insert `item` with `key`, or move it to `key` if it is already in the heap."""
    slot = pos[item]
    if slot == 0:
        size[0] += 1
        slot = size[0]
        _place(keys, items, pos, slot, key, item)
        sift_up(keys, items, pos, slot)
    elif key < keys[slot]:
        keys[slot] = key
        sift_up(keys, items, pos, slot)
    elif key > keys[slot]:
        keys[slot] = key
        sift_down(keys, items, pos, size, slot)


@njit(cache=True)
def pop_min(keys, items, pos, size):
    """Remove and return the item of the smallest key (the heap must not be empty)."""
    top = items[1]
    pos[top] = 0
    n = size[0]
    size[0] = n - 1
    if n > 1:
        _place(keys, items, pos, 1, keys[n], items[n])
        sift_down(keys, items, pos, size, 1)
    return top


@njit(cache=True)
def heapify(keys, items, pos, size):
    """Restore the heap order after keys were changed in place."""
    for slot in range(size[0] >> 1, 0, -1):
        sift_down(keys, items, pos, size, slot)
