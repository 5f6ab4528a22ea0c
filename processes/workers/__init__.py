"""The workers of a run: the registry the supervisor looks a worker up in, and which a scene needs."""
from processes.workers.ai import ai_worker
from processes.workers.gateway import gateway_worker
from processes.workers.layout import RunLayout, build_layout
from processes.workers.net import net_worker
from processes.workers.options import PLAYERS_TIMEOUT_S, RunOptions
from processes.workers.physics import physics_worker

# Each worker is a function (control, arena, scene, options) run by processes.runtime.control.worker_main.
WORKERS = {"physics": physics_worker, "ai": ai_worker, "net": net_worker, "gateway": gateway_worker}


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


__all__ = ["PLAYERS_TIMEOUT_S", "WORKERS", "RunLayout", "RunOptions", "build_layout", "workers_for"]
