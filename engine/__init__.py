"""The simulation itself, in one process: dtypes, scenes, integrators, forces, collisions, contact."""
from engine.jit_cache import use_source_keyed_cache

use_source_keyed_cache()  # before any kernel of the engine is decorated (engine/jit_cache.py says why)

__all__: list[str] = []
