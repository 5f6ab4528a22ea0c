"""The kernels compiled without numba's runtime (`_nrt=False`) hold no references of their own.

Most of the engine's and the net's kernels are compiled with `_nrt=False`: numba then takes and
drops no reference count for each array argument and each view (`a[k]`, `a[i:j]`), which it
otherwise does with an atomic operation per view and per argument per call, costlier than the
arithmetic of a physics tick (numba issues #2350, #9393; numba's own string kernels use the same
option). Such a kernel allocates nothing (numba refuses to compile an allocation there) and must
return no array: numba accepts returning an argument, but the caller, compiled with the runtime,
would then drop a reference it was never given and free the array under its owner. This test
runs what the suite's matches and environments run, then checks every compiled signature of
every such kernel.
"""
import sys

import numpy as np
from numba import types
from numba.core.registry import CPUDispatcher

from engine.learning.vector_env import PingPongVectorEnv
from engine.physics.scene import load_scene
from engine.play.match import Match

PACKAGES = ("engine", "net_kernel")
HOT = {  # kernels a tick, a batched step or a stroke's search runs: they must stay without the runtime
    "engine.physics.tick.advance_ticks", "engine.physics.collision.ball_tick", "engine.physics.bat.bat_step",
    "engine.physics.integrators.advance", "engine.learning.batch.run_tables", "engine.play.arm.control_bats",
    "engine.play.ai.search.search_strokes",
}


def _without_runtime() -> dict[str, CPUDispatcher]:
    """The package's dispatchers compiled with _nrt=False, by qualified name."""
    found = {}
    for name, module in list(sys.modules.items()):
        if module is None or name.split(".")[0] not in PACKAGES:
            continue
        for value in vars(module).values():
            if isinstance(value, CPUDispatcher) and value.targetoptions.get("_nrt") is False:
                found[f"{value.py_func.__module__}.{value.py_func.__name__}"] = value
    return found


def _holds_array(ty) -> bool:
    if isinstance(ty, types.ArrayCompatible):
        return True
    if isinstance(ty, types.BaseTuple):
        return any(_holds_array(t) for t in ty.types)
    return isinstance(ty, (types.List, types.ListType, types.DictType, types.Optional)) and any(
        _holds_array(getattr(ty, attr)) for attr in ("dtype", "key_type", "value_type", "type") if hasattr(ty, attr))


def test_no_kernel_without_runtime_returns_an_array():
    Match(load_scene("match"), 0).play(max_ticks=400)  # the cloth net, its contact with the ball
    Match(load_scene("match_rigid"), 1).play(max_ticks=400)
    vector = PingPongVectorEnv(2, opponent="novice", version=1)
    vector.reset(seed=0)
    for _ in range(20):
        vector.step(np.zeros((2, 6)))
    kernels = _without_runtime()
    assert HOT <= set(kernels), f"compiled with the runtime again: {sorted(HOT - set(kernels))}"
    checked = 0
    for name, kernel in kernels.items():
        for cres in kernel.overloads.values():
            returned = cres.signature.return_type
            assert not _holds_array(returned), (
                f"{name} is compiled with _nrt=False and returns {returned}: return scalars, or compile it with "
                f"the runtime")
            checked += 1
    assert checked >= len(HOT)  # the workload above compiled (or loaded) at least the hot kernels
