"""Cooperative positioning of N receivers on RINEX input (Zhou et al. 2018; algorithms.md §21).

By job: :mod:`~robustrtk.pipeline.coop.types` (settings, nodes, range links, per-epoch
results), :mod:`~robustrtk.pipeline.coop.links` (inter-node ranges from our RTK or a file),
:mod:`~robustrtk.pipeline.coop.loops` (the peer-to-peer and the centralised epoch loops) and
:mod:`~robustrtk.pipeline.coop.stats` (errors against a known position). The names below are
their public interface.
"""

from robustrtk.pipeline.coop.links import read_range_file, rtk_range_link
from robustrtk.pipeline.coop.loops import JointLocationTime, solve_coop, solve_coop_central
from robustrtk.pipeline.coop.stats import horizontal_errors
from robustrtk.pipeline.coop.types import CoopNode, CoopResult, CoopSettings, NodeEpoch, RangeLink, load_node

__all__ = [
    "CoopNode",
    "CoopResult",
    "CoopSettings",
    "JointLocationTime",
    "NodeEpoch",
    "RangeLink",
    "horizontal_errors",
    "load_node",
    "read_range_file",
    "rtk_range_link",
    "solve_coop",
    "solve_coop_central",
]
