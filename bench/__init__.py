"""The studies behind `pingpong bench NAME`: the registry they are looked up in.

Each study is named "module:attribute" (a bench.study.Study) and imported only when it runs, as
processes.workers names its workers: importing the registry, for `pingpong --help`, loads no
study. bench imports engine, net_kernel and processes (below its command line); only
processes.cli imports bench (import-linter contracts in pyproject.toml).
"""
from importlib import import_module

# name -> (entry point, one line for `pingpong bench --help`)
STUDIES = {
    "accuracy": ("bench.accuracy:STUDY", "the ball integrators' errors against their cost (work-precision)"),
    "effects": ("bench.effects:STUDY", "what each effect of a scene costs, against the scene without it"),
    "env": ("bench.env:STUDY", "Gymnasium steps/s: one environment, the native vector env, AsyncVectorEnv"),
    "handoff": ("bench.handoff:STUDY", "a lockstep hand-off between workers against a raw semaphore wake-up"),
    "match": ("bench.match:STUDY", "a headless match in worker processes against the in-process reference"),
    "net-resolution": ("bench.net_resolution:STUDY", "the net's grid: accuracy against cost"),
    "net-tail": ("bench.net_tail:STUDY", "the net's linear tail and float32 kernels against the full float64 kernel"),
    "profile-net": ("bench.profile_net:STUDY", "the net kernel's cost against the machine's copy bandwidth"),
    "ringdown": ("bench.ringdown:STUDY", "a struck net's ring: time to sleep, damping, energy taken"),
}


def load_study(name: str):
    """The bench.study.Study registered as `name`."""
    try:
        module, attribute = STUDIES[name][0].split(":")
    except KeyError:
        raise ValueError(f"no study {name!r}; the studies are {', '.join(STUDIES)}") from None
    return getattr(import_module(module), attribute)


__all__ = ["STUDIES", "load_study"]
