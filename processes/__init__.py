"""OS processes and their plumbing: shared memory, locks, workers, supervisor, gateway, CLI."""
__all__: list[str] = []
