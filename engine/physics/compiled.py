"""A scene compiled once for a run: every number a run derives from its Scene, in one frozen,
picklable object that the supervisor hands to every worker and a client builds from the scene it
was sent. Nothing else derives a number from `scene.dt`.

The layout follows brax's `System` beside `pipeline.step`: the description a step needs is built
once (the model's factors and boxes, the cloth net's topology, the control period) and the step
only reads it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from engine.physics.scene import Scene, scene_digest, scene_toml
from engine.physics.world import Model, State, build_model, initial_record, initial_state
from net_kernel import NetSim, NetTopology, build_topology


def duration_ticks(seconds: float, dt: float) -> int:
    """Ticks of dt s that last `seconds`: the nearest whole number, at least one. The one rule for a
    duration in ticks (the control period, an input's hold)."""
    return max(1, round(seconds / dt))


@dataclass(frozen=True)
class CompiledScene:
    """A Scene and what a run derives from it (compile_scene).

    Fields:
        scene: the description. model: engine.physics.world.Model (factors, boxes, the cloth boxes
            cloth_watch and cloth_reach). topology: the cloth net's (net_kernel.NetTopology), when
            the scene steps one; None otherwise.
        control_period: ticks between the players' control ticks; decision_delay: ticks from a
            decision to the control tick its plan takes effect (both None without a match).
        digest: engine.physics.scene.scene_digest, what a served match's welcome carries.
        start: the record and the bats' motion rows at tick 0 (initial_record), copied by
            initial_state.
    """

    scene: Scene
    model: Model = field(repr=False)
    topology: NetTopology | None = field(repr=False)
    control_period: int | None
    decision_delay: int | None
    digest: str
    start: tuple = field(repr=False, compare=False)  # engine.physics.world.initial_record(scene)

    @property
    def dt(self) -> float:
        """s per tick."""
        return self.model.dt

    @property
    def toml(self) -> str:
        """The scene as TOML (engine.physics.scene.scene_toml): what a served match sends a client.
        Raises SceneError for a scene no TOML document describes."""
        return scene_toml(self.scene)

    def ticks(self, seconds: float) -> int:
        """duration_ticks at this scene's tick."""
        return duration_ticks(seconds, self.dt)

    def net_sim(self) -> NetSim | None:
        """A fresh NetSim of the scene's cloth net, as built (None: the scene steps none)."""
        return None if self.topology is None else NetSim(self.topology, self.dt)

    def initial_state(self) -> State:
        """engine.physics.world.initial_state, its cloth net built from this topology."""
        return initial_state(self.scene, self.topology, self.start)


def compile_scene(scene: Scene | CompiledScene) -> CompiledScene:
    """Compile `scene` (a CompiledScene is returned as it is)."""
    if isinstance(scene, CompiledScene):
        return scene
    model = build_model(scene)
    cloth = scene.cloth is not None and "net" in scene.effects
    period = delay = None
    if scene.match is not None:
        period = duration_ticks(1.0 / scene.match.ai_hz, scene.dt)
        delay = period * max(1, round(scene.match.decision_latency / (period * scene.dt)))
    return CompiledScene(scene=scene, model=model, topology=build_topology(scene.cloth) if cloth else None,
                         control_period=period, decision_delay=delay, digest=scene_digest(scene),
                         start=initial_record(scene))
