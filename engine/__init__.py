"""The simulation itself, in one process, in four rooms (physics, play, learning, tools): see their packages."""
# Imported first: importing net_kernel points numba's cache at a directory keyed on the engine's
# and the net kernels' sources, before any kernel of the engine is decorated (net_kernel/jit_cache.py).
import net_kernel  # noqa: F401

__all__: list[str] = []
