"""Segments of a filter run, written once for every filter of the pipeline: when the filter
starts again (a streak of suspect epochs, a time gap too long to predict across), and the
forward–backward smoothing of each segment.

The DD engine (:class:`~robustrtk.pipeline.engine.DDEngine`: a streak of epochs whose robust
update rejected most rows, the integrity monitor's gap) and Kalman SPP
(:mod:`robustrtk.pipeline.spp_kalman`: a streak of epochs in which the filter and the
least-squares solution disagree, the same gap) both restart through :class:`Streak` and
:func:`gap_exceeded`, and both smooth with :func:`smooth_steps`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from robustrtk.core import FloatArray

if TYPE_CHECKING:  # the smoother is imported where it runs (smoothing is off by default)
    from robustrtk.estimation.smoother import FilterStep


class Streak:
    """Epochs in a row on which a condition held; the filter restarts when the run reaches
    ``needed`` epochs (``needed = 0``: never).

    Parameters
    ----------
    needed : int
        Length of the run that calls for a restart (0 = never).
    """

    def __init__(self, needed: int) -> None:
        self.needed = int(needed)
        self.count = 0

    def update(self, hit: bool) -> None:
        """One more epoch: the run grows when ``hit``, else it ends."""
        self.count = self.count + 1 if hit else 0

    def reset(self) -> None:
        """The run ends (the filter restarted)."""
        self.count = 0

    @property
    def due(self) -> bool:
        """The run is long enough for a restart."""
        return self.count >= self.needed > 0


def gap_exceeded(t_s: float, last_t_s: float, max_gap_s: float) -> bool:
    """The time since the filter's last epoch (s) is longer than it may predict across."""
    return t_s - last_t_s > max_gap_s


def smooth_steps(steps: Sequence[FilterStep | None]) -> list[tuple[FloatArray, FloatArray] | None]:
    """Rauch–Tung–Striebel estimates of a forward run, one segment at a time.

    A segment is a run of consecutive recorded epochs the filter carried across: it ends at
    an epoch without a record (None: no filter that epoch) and before a record without
    transition (``F`` None: the filter started again).

    Parameters
    ----------
    steps : sequence of FilterStep or None, length K

    Returns
    -------
    list, length K
        The smoothed mean and covariance ``(x, P)`` of each recorded epoch; None where
        ``steps`` holds None.
    """
    from robustrtk.estimation.smoother import rts_smooth

    out: list[tuple[FloatArray, FloatArray] | None] = [None] * len(steps)
    segments: list[list[int]] = []
    for k, st in enumerate(steps):
        if st is None:
            continue
        if st.F is None or not segments or segments[-1][-1] != k - 1:
            segments.append([k])
        else:
            segments[-1].append(k)
    for seg in segments:
        chain = [steps[k] for k in seg]
        for k, xp in zip(seg, rts_smooth([c for c in chain if c is not None]), strict=True):
            out[k] = xp
    return out


__all__ = ["Streak", "gap_exceeded", "smooth_steps"]
