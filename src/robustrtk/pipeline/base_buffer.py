"""Which base epoch serves each rover epoch, and how old it is (age of differential).

Rule (RTKLIB's ``pos2-maxage``): a rover epoch pairs with the base epoch whose tag is
within ``tol_s`` of its own (the nearest one, as before: receiver-clock offsets of a few
milliseconds need no propagation, the engine computes the base's satellites at the base's
own tag) — an *exact* pair, age 0, used as it is. Otherwise it pairs with the latest
base epoch before it, when that is at most ``max_age_s`` old: the base observations are
then carried to the rover's tag (:func:`robustrtk.measurement.base_propagation.
propagate_base_epoch`) and their variances grow with the age. A rover epoch with no base
epoch within ``max_age_s`` gets no differential solution.

A base epoch may so serve several rover epochs (a 10-Hz rover against a 1-Hz base, a
5-s CORS, a radio link with gaps). Its loss-of-lock flags are events, not states: they
apply to the first rover epoch it serves, and the flags of base epochs that served no
rover epoch carry over to the next one that does (:class:`BaseEvents`).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, replace
from typing import Generic, TypeVar

import numpy as np

from robustrtk.core import BoolArray, FloatArray, ObsEpoch, TransmitterSource
from robustrtk.measurement.base_propagation import PropagatedEpoch, propagate_base_epoch
from robustrtk.pipeline.results import EpochInputs

#: Default largest age of differential (s), RTKLIB's ``pos2-maxage``.
DEFAULT_MAX_AGE_S = 30.0


@dataclass(frozen=True)
class BasePair:
    """One rover epoch and the base epoch that serves it.

    Attributes
    ----------
    i_rover, i_base : int
        Epoch indices.
    age_s : float
        ``t_rover − t_base`` (s) of a propagated pair; 0 for an exact pair (a tag
        difference within the tolerance is the receivers' clocks, not age).
    exact : bool
        Tags within the matching tolerance: the base epoch is used as it is.
    """

    i_rover: int
    i_base: int
    age_s: float
    exact: bool


def pair_base_epochs(
    t_rover_s: FloatArray,
    t_base_s: FloatArray,
    tol_s: float,
    max_age_s: float,
    usable: BoolArray | None = None,
) -> list[BasePair]:
    """The base epoch of each rover epoch by the module's rule.

    Parameters
    ----------
    t_rover_s, t_base_s : ndarray, shape (T,), (B,)
        Time tags (s), each increasing.
    tol_s : float
        Exact-pair tolerance (s).
    max_age_s : float
        Largest age of a propagated pair (s); 0 pairs exact epochs only.
    usable : ndarray of bool, shape (B,), optional
        Base epochs that can serve (e.g. RTK: those with carrier phases; a radio link's
        code-only epochs are passed over for the latest one with phases). Default all.

    Returns
    -------
    list of BasePair
        In rover order; rover epochs with no base epoch are absent.
    """
    tr = np.asarray(t_rover_s, float)
    tb_all = np.asarray(t_base_s, float)
    keep = np.arange(tb_all.size) if usable is None else np.flatnonzero(np.asarray(usable, bool))
    tb = tb_all[keep]
    out: list[BasePair] = []
    if tb.size == 0:
        return out
    j = np.searchsorted(tb, tr)
    for i, jj in enumerate(j):
        t = float(tr[i])
        best = None
        for c in (jj - 1, jj):  # the nearest within tol (the exact rule of align_epochs)
            if 0 <= c < tb.size and abs(tb[c] - t) <= tol_s:
                if best is None or abs(tb[c] - t) < abs(tb[best] - t):
                    best = c
        if best is not None:
            out.append(BasePair(i, int(keep[best]), 0.0, True))
            continue
        if max_age_s <= 0.0:
            continue
        last = int(np.searchsorted(tb, t, side="right")) - 1
        if last >= 0 and t - float(tb[last]) <= max_age_s:
            out.append(BasePair(i, int(keep[last]), t - float(tb[last]), False))
    return out


class BaseEvents:
    """Per-epoch event flags of the base (loss of lock, detector slips) as the rover sees
    them: each rover epoch gets the flags of every base epoch since the one that served
    the previous rover epoch, up to and including its own; a base epoch used again
    brings none.

    Parameters
    ----------
    flags : ndarray of bool, shape (B, ...)
        Flags per base epoch.

    Notes
    -----
    Stateful: ask in rover order (:func:`robustrtk.pipeline.loop.run_dd` builds the
    inputs in that order).
    """

    def __init__(self, flags: np.ndarray) -> None:
        self.flags = np.asarray(flags, bool)
        self.last = -1

    def since_last(self, j: int) -> BoolArray:
        """Flags of base epochs ``last+1 … j`` OR-ed (none when ``j`` was the last)."""
        if j <= self.last:
            out = np.zeros(self.flags.shape[1:], dtype=bool)
        elif j == self.last + 1 or self.last < 0:
            out = self.flags[j].copy()
        else:
            out = np.any(self.flags[self.last + 1 : j + 1], axis=0)
        self.last = max(self.last, j)
        return out


_P = TypeVar("_P")


class BaseBuffer(Generic[_P]):
    """The pairing rule of :func:`pair_base_epochs`, one epoch at a time (streams).

    Base epochs are pushed in time order; each rover epoch asks :meth:`pair` for its base
    epoch once every base epoch tagged up to ``t_rover + tol_s`` has been pushed (a
    caller merging two time-ordered sources by tag pushes base epochs first at
    ``t_base − tol_s``). The answer is that of :func:`pair_base_epochs` over the same
    epochs: the nearest usable base epoch within ``tol_s`` (the earlier one on a tie),
    else the latest usable one at most ``max_age_s`` old. Base epochs that can no longer
    serve are dropped, so memory is bounded by the age window, not the run.

    Parameters
    ----------
    tol_s, max_age_s : float
        As in :func:`pair_base_epochs`.

    Notes
    -----
    Each pushed epoch carries a payload (the epoch itself, its flags) and a sequence
    number (its index among all pushed base epochs, usable or not), returned as
    ``BasePair.i_base``.
    """

    def __init__(self, tol_s: float, max_age_s: float) -> None:
        self.tol_s = tol_s
        self.max_age_s = max_age_s
        self.t: list[float] = []
        self.seq: list[int] = []
        self.payload: list[_P] = []
        self.n_pushed = 0

    def push(self, t_s: float, payload: _P, usable: bool = True) -> int:
        """Add the next base epoch; returns its sequence number."""
        k = self.n_pushed
        self.n_pushed += 1
        if usable:
            self.t.append(float(t_s))
            self.seq.append(k)
            self.payload.append(payload)
        return k

    def pair(self, t_rover_s: float, i_rover: int = 0) -> tuple[BasePair, _P] | None:
        """The base epoch of a rover epoch tagged ``t_rover_s`` and its payload (None when
        no base epoch serves); older base epochs than can serve a later rover epoch are
        dropped."""
        t = float(t_rover_s)
        tb = self.t
        jj = bisect.bisect_left(tb, t)
        best = None
        for c in (jj - 1, jj):
            if 0 <= c < len(tb) and abs(tb[c] - t) <= self.tol_s:
                if best is None or abs(tb[c] - t) < abs(tb[best] - t):
                    best = c
        out: tuple[BasePair, _P] | None = None
        if best is not None:
            out = BasePair(i_rover, self.seq[best], 0.0, True), self.payload[best]
        elif self.max_age_s > 0.0:
            last = bisect.bisect_right(tb, t) - 1
            if last >= 0 and t - tb[last] <= self.max_age_s:
                out = BasePair(i_rover, self.seq[last], t - tb[last], False), self.payload[last]
        self._drop_before(t)
        return out

    def _drop_before(self, t: float) -> None:
        """Forget base epochs that no later rover epoch (tag ≥ ``t``) can pair with: all but
        the latest of those older than ``t − tol_s``, and that one too when it is older
        than ``t − max_age_s``."""
        horizon = t - self.tol_s
        n_old = bisect.bisect_left(self.t, horizon)
        keep_from = n_old - 1 if n_old > 0 and t - self.t[n_old - 1] <= self.max_age_s else n_old
        if keep_from > 0:
            del self.t[:keep_from], self.seq[:keep_from], self.payload[:keep_from]


def base_lli_events(base_lli: np.ndarray) -> BaseEvents:
    """:class:`BaseEvents` of the loss-of-lock bit (bit 0) of a base batch's LLI (B, N, K)."""
    return BaseEvents((np.asarray(base_lli) & 1).astype(bool))


def with_base_events(epoch: ObsEpoch, lost: BoolArray) -> ObsEpoch:
    """The base epoch with its loss-of-lock bit replaced by ``lost`` (N, K): the events of
    :class:`BaseEvents` (other LLI bits, such as the half-cycle state, kept)."""
    lli = np.asarray(epoch.lli)
    new = (lli & ~np.int8(1)) | np.asarray(lost, bool).astype(np.int8)
    if np.array_equal(new, lli):
        return epoch
    return replace(epoch, lli=new.astype(np.int8))


def aged_inputs(
    inp: EpochInputs,
    t_rover_s: float,
    source: TransmitterSource,
    base_pos_m: FloatArray,
    *,
    sagnac: bool,
    troposphere: bool,
    signal: int,
    sigma_age_m_s: float,
) -> EpochInputs:
    """``inp`` with its base epoch carried to the rover's tag and the base position of the
    base's own epoch (a moving base is held where it observed)."""
    base: PropagatedEpoch = propagate_base_epoch(
        inp.base, t_rover_s, source, base_pos_m, sagnac=sagnac, troposphere=troposphere, signal=signal,
        sigma_age_m_s=sigma_age_m_s,
    )  # fmt: skip
    return replace(inp, base=base, base_pos_m=np.asarray(base_pos_m, float))


__all__ = [
    "DEFAULT_MAX_AGE_S",
    "BaseBuffer",
    "BaseEvents",
    "BasePair",
    "aged_inputs",
    "base_lli_events",
    "pair_base_epochs",
    "with_base_events",
]
