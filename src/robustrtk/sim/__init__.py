"""Simulation: indoor pseudolite scenarios (room, trajectories, clocks, noise, multipath,
faults) -> observation tables, site file and truth."""

from robustrtk.sim.files import OUTPUT_FILES, run_simulate, write_simulation
from robustrtk.sim.pseudolite import FaultTable, SimResult, simulate
from robustrtk.sim.scenario import Scenario, list_presets, load_scenario, scenario_from_dict

__all__ = [
    "OUTPUT_FILES",
    "FaultTable",
    "Scenario",
    "SimResult",
    "list_presets",
    "load_scenario",
    "run_simulate",
    "scenario_from_dict",
    "simulate",
    "write_simulation",
]
