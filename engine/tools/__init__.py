"""Tools over the simulation: running a scene, the stability study, rendering and replay files."""
