"""The table net: topology builder, numba spring kernels and their numpy twins."""
__all__: list[str] = []
