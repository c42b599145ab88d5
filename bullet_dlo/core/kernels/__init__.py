"""Numba kernels of the core: arrays and scalars in, preallocated arrays out (``@njit(cache=True)``)."""
