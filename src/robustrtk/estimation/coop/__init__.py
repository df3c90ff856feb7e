"""Cooperative positioning estimators (Zhou et al. 2018; algorithms.md §21).

Each node ``m`` estimates ``x_m = [p_m (3), b_m,1 .. b_m,c]`` (ECEF m; one clock per
satellite system, in metres; optionally a velocity block) from its own pseudoranges and the
ranges to its peers, using the positions and covariances the peers broadcast
(:mod:`robustrtk.measurement.coop` has the rows). What does not depend on GNSS files, by job:

* :mod:`~robustrtk.estimation.coop.process` — the process model of eq. 8
  (:class:`LocationTimeModel`) and the node's state layout;
* :mod:`~robustrtk.estimation.coop.nodes` — the node filters behind one interface
  (:class:`NodeFilter`: EKF and UKF on :mod:`robustrtk.estimation.filters`, the particle
  filter of :mod:`robustrtk.estimation.particle`, per-epoch least squares);
* :mod:`~robustrtk.estimation.coop.policy` — the cooperation modes, eq. 24 inflation and
  eq. 29 / 30 covariance reset, the peers' broadcasts and short windows;
* :mod:`~robustrtk.estimation.coop.ranges` — the range rows to the peers (eq. 11).

The names below are the public interface of all four.
"""

from robustrtk.estimation.coop.nodes import (
    FILTER_KINDS,
    Belief,
    FilterKind,
    KalmanNode,
    LeastSquaresNode,
    LsqResult,
    NodeFilter,
    NodeStep,
    ParticleNode,
    gauss_newton,
    make_node_filter,
)
from robustrtk.estimation.coop.policy import (
    COOPERATION,
    Cooperation,
    PeerBroadcast,
    PeerWindow,
    ResetSettings,
    range_variance,
    reset_covariance,
)
from robustrtk.estimation.coop.process import LocationTimeModel, clock_index, node_layout
from robustrtk.estimation.coop.ranges import RangeObservation, peer_range_model

__all__ = [
    "COOPERATION",
    "FILTER_KINDS",
    "Belief",
    "Cooperation",
    "FilterKind",
    "KalmanNode",
    "LeastSquaresNode",
    "LocationTimeModel",
    "LsqResult",
    "NodeFilter",
    "NodeStep",
    "ParticleNode",
    "PeerBroadcast",
    "PeerWindow",
    "RangeObservation",
    "ResetSettings",
    "clock_index",
    "gauss_newton",
    "make_node_filter",
    "node_layout",
    "peer_range_model",
    "range_variance",
    "reset_covariance",
]
