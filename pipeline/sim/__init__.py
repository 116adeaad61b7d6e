"""The synthetic fisheye flight simulator: scenario, ray-casting renderer, ground truth, writer.

``load_scenario`` reads a scenario YAML; ``Simulation`` renders it frame by frame; ``simulate``
writes the videos and ground truth of ``fisheye-des simulate``; ``raycast`` casts rays into the
scene at any time (the renderer's own code path) for ground truth.
"""

from pipeline.sim.scene import Scenario, dump_scenario, load_scenario, scenario_from_dict
from pipeline.sim.world import SKY_ID, World, raycast

__all__ = [
    "SKY_ID",
    "Scenario",
    "World",
    "dump_scenario",
    "load_scenario",
    "raycast",
    "scenario_from_dict",
]
