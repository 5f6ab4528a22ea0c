"""The workers of a run: the registry the supervisor looks a worker up in, and which a scene needs."""
from importlib import import_module

from processes.workers.layout import RunLayout, build_layout
from processes.workers.options import PLAYERS_TIMEOUT_S, RunHandles, RunOptions, speculation_refusal

# Each worker is a function (control, arena, compiled, options) that
# processes.runtime.control.worker_main runs (compiled: the run's
# engine.physics.compiled.CompiledScene, built once by the supervisor), named "module:function"
# and imported only when a run starts it (as Gymnasium's registry names its environments' entry
# points): importing the registry, or the run's layout, loads no worker.
WORKERS = {
    "physics": "processes.workers.physics:physics_worker",
    "ai": "processes.workers.ai:ai_worker",
    "net": "processes.workers.net:net_worker",
    "gateway": "processes.workers.gateway:gateway_worker",
}


def worker_target(kind: str):
    """The worker function registered as `kind`."""
    try:
        module, name = WORKERS[kind].split(":")
    except KeyError:
        raise ValueError(f"no worker {kind!r}; the workers are {', '.join(WORKERS)}") from None
    return getattr(import_module(module), name)


def worker_modules(kinds: list[str]) -> list[str]:
    """The modules of the workers `kinds` (for a forkserver to import once, before it forks them)."""
    return [WORKERS[kind].split(":")[0] for kind in kinds]


def workers_for(scene) -> list[str]:
    """The workers a scene needs, no more: a scene without a cloth net or AI starts none of those."""
    kinds = ["physics"]
    if scene.cloth is not None and "net" in scene.effects:
        kinds.append("net")
    if any(bat.skill is not None for bat in scene.bats):
        kinds.append("ai")
    if "remote" in scene.effects:
        kinds.append("gateway")
    return kinds


__all__ = ["PLAYERS_TIMEOUT_S", "WORKERS", "RunHandles", "RunLayout", "RunOptions", "build_layout",
           "speculation_refusal", "worker_modules", "worker_target", "workers_for"]
