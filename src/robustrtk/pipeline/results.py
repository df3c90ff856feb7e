"""What one epoch of the engine takes and gives: inputs, results, diagnostics rows."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from robustrtk.core import BoolArray, FloatArray, ObsEpoch, Solution

if TYPE_CHECKING:  # annotations only: a least-squares solve does not import the filters
    from robustrtk.estimation.adaptive import AdaptiveOutcome
    from robustrtk.estimation.state import GaussianState, UpdateResult


@dataclass(frozen=True)
class EpochInputs:
    """Everything one engine step needs besides its own state.

    Attributes
    ----------
    rover, base : ObsEpoch
        Matched epochs of the two receivers (the base reindexed to the rover's rows by the
        engine).
    base_pos_m : ndarray, shape (3,), optional
        Base position at this epoch (a moving base); None = the engine's base receiver
        position source.
    slip : ndarray of bool, shape (N,), optional
        Undifferenced slip flags per rover row from detectors of either receiver
        (geometry-free, Doppler); LLI flags are read from the epochs themselves.
    half_cycle : ndarray of bool, shape (N,), optional
        Half-cycle-unresolved flags per rover row (either receiver).
    """

    rover: ObsEpoch
    base: ObsEpoch
    base_pos_m: FloatArray | None = None
    slip: BoolArray | None = None
    half_cycle: BoolArray | None = None


class DiagRow(NamedTuple):
    """One DD of one epoch: what the robust filter saw and decided.

    ``kind`` is ``"code"`` or ``"phase"``; an engine event (``"reinit"``: the filter was
    restarted from a single-epoch solution) is a row of its own with ``dd`` naming it.
    A named tuple (immutable, fields by name or position): an RTK epoch makes one per DD
    row, and a tuple is built in a quarter of a frozen dataclass's time.
    """

    t_s: float
    dd: str
    kind: str
    innovation: float
    residual: float
    std_residual: float
    dv: float
    factor: float
    situation: int


@dataclass(frozen=True)
class EpochResult:
    """The outcome of one engine step: the solution and its diagnostics rows."""

    solution: Solution
    diagnostics: list[DiagRow] = field(default_factory=list)
    events: tuple[str, ...] = ()


@dataclass
class RowTally:
    """Running counts of the robust filter's decisions over a run, epoch by epoch: what a
    run's summary reports, without keeping every diagnostics row (a day of 1 Hz RTK makes
    millions of them, about 280 bytes each).

    A row is *down-weighted* when its factor satisfies ``1 < γ < ∞`` and *rejected* when
    ``γ = ∞`` (algorithms.md §1); engine events are not rows; an epoch is *flagged* when
    one of its rows is down-weighted or rejected.
    """

    rows_downweighted: int = 0
    rows_rejected: int = 0
    epochs_flagged: int = 0

    def add_epoch(self, rows: Iterable[DiagRow]) -> None:
        """Count one epoch's rows."""
        down, rej, times = flag_counts(rows)
        self.rows_downweighted += down
        self.rows_rejected += rej
        self.epochs_flagged += int(bool(times))

    def as_dict(self) -> dict[str, int]:
        """The three counts by name (``RunResult.info["row_tally"]``)."""
        return {
            "rows_downweighted": self.rows_downweighted,
            "rows_rejected": self.rows_rejected,
            "epochs_flagged": self.epochs_flagged,
        }


def flag_counts(rows: Iterable[DiagRow]) -> tuple[int, int, set[float]]:
    """Rows down-weighted (``1 < γ < ∞``), rows rejected (``γ = ∞``) and the times of the
    epochs with either; engine events are not rows (one comparison for a row at its nominal
    weight: NaN and 1 are not above 1)."""
    down = rej = 0
    times: set[float] = set()
    for d in rows:
        g = d.factor
        if g > 1.0 and d.kind != "event":
            times.add(d.t_s)
            if g == math.inf:
                rej += 1
            else:
                down += 1
    return down, rej, times


@dataclass
class RunResult:
    """Solutions, diagnostics and facts about the run (reference chosen, counts).

    ``diagnostics`` is empty when the run was told not to keep its rows; ``info["row_tally"]``
    (:meth:`RowTally.as_dict`) counts them either way.
    """

    solutions: list[Solution] = field(default_factory=list)
    diagnostics: list[DiagRow] = field(default_factory=list)
    info: dict[str, object] = field(default_factory=dict)


def diag_rows(t_s: float, labels: tuple[str, ...], kinds: list[str], res: UpdateResult) -> list[DiagRow]:
    """One :class:`DiagRow` per row of an update."""
    cols = zip(
        labels, kinds, np.asarray(res.innovation, float).tolist(), np.asarray(res.residual, float).tolist(),
        np.asarray(res.std_residual, float).tolist(), np.asarray(res.dv, float).tolist(),
        np.asarray(res.factors, float).tolist(), np.asarray(res.situation).astype(int).tolist(), strict=False,
    )  # fmt: skip
    return [DiagRow(t_s, *c) for c in cols]


def event_row(t_s: float, name: str) -> DiagRow:
    """A diagnostics row that records an engine event (no measurement)."""
    nan = float("nan")
    return DiagRow(t_s, name, "event", nan, nan, nan, nan, nan, 0)


def adaptive_row(t_s: float, outcome: AdaptiveOutcome) -> DiagRow:
    """The epoch's adaptive-factor row (``dd = kind = "adaptive"``).

    ``factor`` is the largest widening of the prediction ``1/min αᵢ`` (1: prediction kept,
    ``1/floor``: some component all but dropped), ``std_residual`` the largest discrepancy
    ``max Δx̃ᵢ`` of the first pass (algorithms.md §23). ``situation`` is 0, as for other
    non-DD rows, so the per-epoch situation statistics count DDs only.
    """
    nan = float("nan")
    return DiagRow(t_s, "adaptive", "adaptive", nan, nan, outcome.delta_max, nan, 1.0 / outcome.alpha_min, 0)


def imm_rows(t_s: float, names: Iterable[str], probabilities: Iterable[float]) -> list[DiagRow]:
    """The IMM's mode probabilities of one epoch as ``imm:<model>`` rows (in ``factor``)."""
    nan = float("nan")
    return [
        DiagRow(t_s, f"imm:{n}", "imm", nan, nan, nan, nan, float(p), 0)
        for n, p in zip(names, probabilities, strict=True)
    ]


def solution_of(state: GaussianState, t_s: float, status: str, n_used: int, **kw: Any) -> Solution:
    """The reported :class:`Solution` of a state (position, covariance, velocity if any)."""
    vel = state.get("vel").copy() if state.layout.has("vel") else None
    return Solution(
        t_s=t_s, pos_m=np.array(state.get("pos"), float), cov_m2=np.array(state.cov("pos"), float),
        status=status, n_used=n_used, vel_m_s=vel, **kw,
    )  # fmt: skip


def notify_progress(progress: Callable[[int, int], None] | None, done: int, total: int, status: str) -> None:
    """Tell a progress callback that epoch ``done`` of ``total`` is solved with ``status``.

    A callback with an ``epoch(done, total, status)`` method (the command line's bar,
    :class:`robustrtk.cli.progress.ProgressBar`) gets the status too, so it can show the
    fix rate so far; a plain ``(done, total)`` callable gets the counts only.
    """
    if progress is None:
        return
    epoch = getattr(progress, "epoch", None)
    if callable(epoch):
        epoch(done, total, status)
    else:
        progress(done, total)


__all__ = [
    "DiagRow",
    "EpochInputs",
    "EpochResult",
    "RowTally",
    "RunResult",
    "adaptive_row",
    "diag_rows",
    "event_row",
    "flag_counts",
    "notify_progress",
    "solution_of",
]
