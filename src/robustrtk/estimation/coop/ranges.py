"""The range rows of a node to its peers (Zhou et al. 2018 eq. 11; algorithms.md §21):
a measured range (:class:`RangeObservation`) to each peer that broadcast, as a
:class:`~robustrtk.measurement.coop.PeerRangeModel` whose variances the cooperation policy
sets (:func:`~robustrtk.estimation.coop.policy.range_variance`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robustrtk.estimation.coop.policy import PeerBroadcast, PeerWindow, range_variance
from robustrtk.measurement.coop import PeerRangeModel


@dataclass(frozen=True)
class RangeObservation:
    """A measured range from this node to ``peer`` (m) and its variance (m²)."""

    peer: str
    range_m: float
    var_m2: float


def peer_range_model(
    observations: Sequence[RangeObservation],
    broadcasts: dict[str, PeerBroadcast],
    cooperation: str,
    kind: str,
    windows: dict[str, PeerWindow] | None = None,
    *,
    pos_start: int = 0,
    n_state: int = 4,
    dt_s: float = 1.0,
) -> PeerRangeModel:
    """The range rows (eq. 11) to the peers that broadcast, variances by :func:`range_variance`.

    Observations of peers without a finite broadcast are skipped; ``off`` gives no rows.
    """
    rows = [
        o
        for o in observations
        if cooperation != "off"
        and o.peer in broadcasts
        and np.all(np.isfinite(broadcasts[o.peer].pos_ecef_m))
        and np.isfinite(o.range_m)
        and np.isfinite(o.var_m2)
    ]
    win = windows or {}
    var = [
        range_variance(o.var_m2, broadcasts[o.peer], cooperation, kind, win.get(o.peer), dt_s) for o in rows
    ]
    return PeerRangeModel(
        z=np.array([o.range_m for o in rows], float),
        peer_pos_m=np.array([broadcasts[o.peer].pos_ecef_m for o in rows], float).reshape(-1, 3),
        var_m2=np.array(var, float),
        pos_start=pos_start,
        n_state=n_state,
        labels=tuple(f"range:{o.peer}" for o in rows),
    )


__all__ = ["RangeObservation", "peer_range_model"]
