"""The simulation itself, in one process: dtypes, scenes, integrators, forces, collisions, contact."""
__all__: list[str] = []
