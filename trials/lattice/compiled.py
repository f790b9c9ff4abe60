"""How the search kernels are compiled: numba, cached on disk beside the sources, without reference counting.

The kernels allocate nothing and take their arrays in named tuples. With numba's reference counting
every read of an array out of a tuple costs an atomic increment and decrement, which in the innermost
loops more than doubles the search time; without it (`_nrt=False`) a kernel that tried to allocate
would fail to compile rather than leak.
"""

from numba import njit

#: Decorators of a compiled kernel, and of one inlined into the kernels that call it.
kernel = njit(cache=True, _nrt=False)
inlined_kernel = njit(cache=True, inline="always", _nrt=False)
