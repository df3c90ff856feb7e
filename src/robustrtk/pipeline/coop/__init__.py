"""Cooperative positioning of N receivers on RINEX input (Zhou et al. 2018; algorithms.md §21).

By job: :mod:`~robustrtk.pipeline.coop.types` (nodes, range links, per-epoch results; the
settings are the ``[coop]`` section of :class:`~robustrtk.pipeline.config.Config`),
:mod:`~robustrtk.pipeline.coop.links` (inter-node ranges from our RTK or a file),
:mod:`~robustrtk.pipeline.coop.loops` (the peer-to-peer epoch loop, whatever the nodes' rows),
:mod:`~robustrtk.pipeline.coop.rinex` (nodes on RINEX files: :func:`solve_coop`),
:mod:`~robustrtk.pipeline.coop.central` (the centralised joint filter),
:mod:`~robustrtk.pipeline.coop.scenarios` (test scenarios on real files: a windowsill sky, a
code bias) and
:mod:`~robustrtk.pipeline.coop.stats` (errors against a known position). The names below are
their public interface.
"""

from robustrtk.pipeline.coop.central import JointLocationTime, solve_coop_central
from robustrtk.pipeline.coop.links import read_range_file, rtk_range_link
from robustrtk.pipeline.coop.loops import LoopNode, NodeSource, NodeStart, peer_to_peer
from robustrtk.pipeline.coop.rinex import RinexNode, solve_coop
from robustrtk.pipeline.coop.scenarios import inject_code_bias, windowsill_mask
from robustrtk.pipeline.coop.stats import horizontal_errors
from robustrtk.pipeline.coop.types import (
    CoopNode,
    CoopResult,
    NodeEpoch,
    RangeLink,
    coop_systems,
    load_node,
    reset_settings,
)

__all__ = [
    "CoopNode",
    "CoopResult",
    "JointLocationTime",
    "LoopNode",
    "NodeEpoch",
    "NodeSource",
    "NodeStart",
    "RangeLink",
    "RinexNode",
    "horizontal_errors",
    "inject_code_bias",
    "coop_systems",
    "load_node",
    "peer_to_peer",
    "reset_settings",
    "read_range_file",
    "rtk_range_link",
    "solve_coop",
    "solve_coop_central",
    "windowsill_mask",
]
