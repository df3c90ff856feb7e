"""The one epoch loop of the pipeline: every mode steps its epochs through :class:`EpochLoop`.

A mode's per-epoch work is a :class:`Stage` (one object with a ``step``):
:class:`~robustrtk.pipeline.engine.DDEngine` for RTK, DGNSS and DPL, the Kalman SPP filter
(:class:`~robustrtk.pipeline.spp_kalman.KalmanSppStage`), least-squares SPP by epoch or by
block of epochs (:class:`~robustrtk.pipeline.spp.EpochwiseSpp`,
:class:`~robustrtk.pipeline.spp.BlockSolver`), the cooperative nodes
(:class:`~robustrtk.pipeline.coop.loops.PeerNetwork`) and the central joint filter
(:class:`~robustrtk.pipeline.coop.central.JointFilter`). :meth:`EpochLoop.step` hands one
item (an epoch, a block of epochs, a paired rover epoch) to the stage.

For double differences :class:`EpochLoop` also takes base epochs and rover epochs one at a
time, in the order of their tags (a base epoch as soon as it can serve: at
``t_base − tol_s``), pairs each rover epoch with its base epoch
(:class:`~robustrtk.pipeline.base_buffer.BaseBuffer`, the rule of
:func:`~robustrtk.pipeline.base_buffer.pair_base_epochs`), gives it the base's
loss-of-lock events since the base epoch used before (:class:`EventLog`), carries an
older base epoch to the rover's tag, and steps the :class:`~robustrtk.pipeline.engine.
DDEngine`: one :class:`~robustrtk.core.Solution` per paired rover epoch.

:func:`run_dd` (whole files) runs this loop over the two batches merged by tag; a stream
(:mod:`robustrtk.cli.run`) runs it as epochs arrive. What each pair's
:class:`~robustrtk.pipeline.results.EpochInputs` holds (detector slip flags, a moving
base's position) comes from a builder: by default just the two epochs.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from functools import cached_property
from typing import TYPE_CHECKING, Any, Protocol, cast

import numpy as np

from robustrtk.blas import one_blas_thread
from robustrtk.core import BoolArray, FloatArray, InputError, ObsBatch, ObsEpoch, Solution, TransmitterSource
from robustrtk.pipeline.reinit import smooth_steps
from robustrtk.pipeline.results import EpochInputs, EpochResult, RowTally, RunResult, notify_progress

if TYPE_CHECKING:  # the smoother is imported where it runs (smoothing is off by default);
    # the DD engine, base buffer and row maps where the DD modes use them (the other modes'
    # stages do not need them: their start-up stays as short as before)
    from robustrtk.estimation.smoother import FilterStep
    from robustrtk.geometry.receivers import PositionSource
    from robustrtk.pipeline.base_buffer import BaseBuffer, BasePair
    from robustrtk.pipeline.config import Config
    from robustrtk.pipeline.engine import DDEngine

#: Builds a pair's step inputs: ``(i_rover, rover_epoch, i_base, base_epoch)``.
InputBuilder = Callable[[int, ObsEpoch, int, ObsEpoch], EpochInputs]

#: Epochs whose inputs are built, and satellite positions evaluated, together in :func:`run_dd`.
PREFETCH_EPOCHS = 64


def union_rows(entries: list[tuple[tuple[str, ...], np.ndarray]], ids: tuple[str, ...]) -> BoolArray:
    """Flags ``(ids_e, flags_e)`` OR-ed by row name onto the rows ``ids`` (rows named in no
    entry are False); ``flags_e`` has shape ``(len(ids_e), ...)``."""
    shape = (len(ids),) + entries[0][1].shape[1:] if entries else (len(ids),)
    if entries and all(e[0] == ids for e in entries):
        if len(entries) == 1:
            return entries[0][1].copy()
        return np.any(np.stack([e[1] for e in entries]), axis=0)
    out = np.zeros(shape, dtype=bool)
    for e_ids, flags in entries:
        from robustrtk.pipeline.rows import row_map

        _, have, src = row_map(e_ids, ids)
        out[have] |= flags[src]
    return out


class EventLog:
    """Event flags of the base epochs (loss of lock, detector slips) as the rover sees them:
    a rover epoch served by base epoch ``j`` gets the flags of every base epoch since the
    one that served the previous rover epoch, up to ``j``; a base epoch used again brings
    none; the first rover epoch gets its own base epoch's flags only
    (:class:`~robustrtk.pipeline.base_buffer.BaseEvents`, by row name and one epoch at a
    time)."""

    def __init__(self) -> None:
        self.pending: dict[int, tuple[tuple[str, ...], np.ndarray]] = {}
        self.last = -1

    def push(self, seq: int, ids: tuple[str, ...], flags: np.ndarray) -> None:
        """The flags of base epoch ``seq`` (rows ``ids``)."""
        self.pending[seq] = (ids, np.asarray(flags, bool))

    def since_last(self, j: int, ids: tuple[str, ...], shape: tuple[int, ...]) -> BoolArray:
        """Flags of base epochs ``last+1 … j`` on the rows ``ids`` (``shape`` when none)."""
        if j <= self.last:
            out = np.zeros(shape, dtype=bool)
        else:
            lo = j if self.last < 0 else self.last + 1
            out = union_rows([self.pending[k] for k in range(lo, j + 1) if k in self.pending], ids)
            if out.shape != shape:
                out = np.zeros(shape, dtype=bool) | out.reshape((len(ids),) + (1,) * (len(shape) - 1))
        for k in [k for k in self.pending if k <= j]:
            del self.pending[k]
        self.last = max(self.last, j)
        return out


class Stage(Protocol):
    """A mode's work on one item of the loop (an epoch, a block of epochs, a paired rover
    epoch): its state lives in the stage, from one step to the next."""

    def step(self, item: Any, /) -> Any:
        """The mode's output of ``item``."""
        ...


class EpochLoop:
    """The epoch loop: items in time order, one stage step each; for double differences
    also rover and base epochs in (time order), one engine step per paired rover epoch out.

    Parameters
    ----------
    stage : Stage
        The mode's per-epoch work (a :class:`DDEngine` for the DD modes).
    tol_s, max_age_s, sigma_age_m_s : float
        Pairing tolerance, largest age of differential and its variance growth (see
        :func:`run_dd`; DD modes only).
    build : InputBuilder, optional
        The step inputs of a pair (default: the two epochs).
    """

    def __init__(
        self,
        stage: Stage,
        tol_s: float = 0.0,
        max_age_s: float = 0.0,
        sigma_age_m_s: float = 0.0,
        build: InputBuilder | None = None,
    ) -> None:
        self.stage = stage
        self.tol_s = tol_s
        self.sigma_age_m_s = sigma_age_m_s
        self.max_age_s = max_age_s
        self.lli_events = EventLog()
        self.build = build
        self.refs_seen: set[str] = set()
        self.tally = RowTally()
        self.n_solved = 0

    @cached_property
    def buffer(self) -> BaseBuffer[tuple[int, ObsEpoch]]:
        """The base epochs waiting to serve (DD modes)."""
        from robustrtk.pipeline.base_buffer import BaseBuffer

        return BaseBuffer(self.tol_s, self.max_age_s)

    @property
    def engine(self) -> DDEngine:
        """The stage of the DD modes."""
        return cast("DDEngine", self.stage)

    def step(self, item: Any) -> Any:
        """The stage's step of one item: the one place where every mode's epochs are solved."""
        return self.stage.step(item)

    def push_base(self, epoch: ObsEpoch, usable: bool = True) -> int:
        """Add the next base epoch (``usable``: it may serve, e.g. RTK needs its phases);
        returns its sequence number."""
        seq = self.buffer.n_pushed
        self.lli_events.push(seq, epoch.tx_ids, (np.asarray(epoch.lli) & 1) != 0)
        return self.buffer.push(epoch.t_s, (seq, epoch), usable)

    def prepare(self, i_rover: int, rover: ObsEpoch) -> tuple[EpochInputs, BasePair] | None:
        """The step inputs of the next rover epoch and its pair (None: no base epoch serves).
        Every base epoch tagged up to ``t_rover + tol_s`` must have been pushed."""
        from robustrtk.pipeline.base_buffer import aged_inputs, with_base_events

        got = self.buffer.pair(rover.t_s, i_rover)
        if got is None:
            return None
        pair, (j, base_epoch) = got
        eng = self.engine
        if self.build is not None:
            inp = self.build(i_rover, rover, j, base_epoch)
        else:
            inp = EpochInputs(rover, base_epoch)
        b = inp.base
        lli = np.asarray(b.lli)
        if b.tx_ids == base_epoch.tx_ids and lli.shape == np.asarray(base_epoch.lli).shape:
            b = with_base_events(b, self.lli_events.since_last(j, b.tx_ids, lli.shape))
        if pair.exact:
            return (inp if b is inp.base else replace(inp, base=b)), pair
        t_r = float(rover.t_s)
        pos_b = inp.base_pos_m if inp.base_pos_m is not None else eng.base.position(float(b.t_s))
        aged = aged_inputs(
            replace(inp, base=b), t_r, eng.source, np.asarray(pos_b, float), sagnac=eng.sagnac,
            troposphere=eng.frame == "ecef", signal=eng.signal, sigma_age_m_s=self.sigma_age_m_s,
        )  # fmt: skip
        return aged, pair

    def solve(self, inp: EpochInputs, pair: BasePair) -> tuple[EpochResult, Solution]:
        """One engine step; the solution carries the pair's age of differential."""
        res: EpochResult = self.step(inp)
        sol = res.solution
        if pair.age_s != 0.0:
            sol = replace(sol, age_s=pair.age_s)
        self.tally.add_epoch(res.diagnostics)
        self.refs_seen.update(self.engine.refs.values())
        self.n_solved += 1
        return res, sol

    def push_rover(self, i_rover: int, rover: ObsEpoch) -> tuple[EpochResult, Solution] | None:
        """:meth:`prepare` and :meth:`solve` of one rover epoch (streams)."""
        got = self.prepare(i_rover, rover)
        return None if got is None else self.solve(*got)


def merged_order(t_rover_s: FloatArray, t_base_s: FloatArray, tol_s: float) -> Iterator[tuple[int, int]]:
    """``(kind, index)`` of rover (1) and base (0) epochs in the loop's order: a base epoch
    at ``t_base − tol_s`` (a millisecond early: it must be in before any rover epoch it may
    pair with exactly), before a rover epoch of the same key."""
    kb = np.asarray(t_base_s, float) - tol_s - 1e-3
    kr = np.asarray(t_rover_s, float)
    keys = np.concatenate([kb, kr])
    kinds = np.concatenate([np.zeros(kb.size, np.int64), np.ones(kr.size, np.int64)])
    idx = np.concatenate([np.arange(kb.size), np.arange(kr.size)])
    order = np.lexsort((kinds, keys))
    for o in order:
        yield int(kinds[o]), int(idx[o])


def smoothed_solutions(
    solutions: list[Solution], steps: list[FilterStep], floors: Sequence[FloatArray | None] | None = None
) -> list[Solution]:
    """The solutions with positions (and velocities) from the RTS smoother over ``steps``
    (post-processing: each epoch uses the data before and after it, :func:`~robustrtk.
    pipeline.reinit.smooth_steps`); unsolved epochs stay. ``floors`` (one per step): the
    epoch's snapshot covariance, below which the smoothed covariance is not reported (as the
    forward solution's, :func:`~robustrtk.estimation.integrity.covariance_floor`: the code's
    time-correlated errors do not average out over the epochs the smoother adds)."""
    from robustrtk.estimation.integrity import covariance_floor  # a least-squares run needs no filter

    out = []
    fl = list(floors) if floors is not None and len(floors) == len(steps) else [None] * len(steps)
    for sol, step, xp, floor in zip(solutions, steps, smooth_steps(steps), fl, strict=True):
        if sol.status == "none" or step.layout is None or xp is None:
            out.append(sol)
            continue
        x, P = xp
        p = step.layout.slice("pos")
        vel = x[step.layout.slice("vel")].copy() if step.layout.has("vel") else sol.vel_m_s
        cov = P[p, p].copy() if floor is None else covariance_floor(P[p, p], floor)
        out.append(replace(sol, pos_m=x[p].copy(), cov_m2=cov, vel_m_s=vel))
    return out


def run_dd(
    rover: ObsBatch,
    base: ObsBatch,
    cfg: Config,
    source: TransmitterSource,
    base_pos_m: FloatArray | PositionSource,
    rover_pos0_m: FloatArray,
    reference: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    sagnac: bool = False,
    frame: str = "local",
    elev_mask_deg: float = 15.0,
    signal: int = 0,
    row_groups: bool = False,
    align_tol_s: float = 0.005,
    inputs: Callable[[int, int], EpochInputs] | None = None,
    engine: DDEngine | None = None,
    keep_diagnostics: bool = True,
    max_age_s: float = 0.0,
    sigma_age_m_s: float = 0.0,
    base_usable: BoolArray | None = None,
) -> RunResult:
    """Run the DD engine over all matched epochs of two batches (:class:`EpochLoop`).

    ``frame``, ``elev_mask_deg``, ``signal`` and ``row_groups`` are passed to
    :class:`DDEngine` (``frame="ecef"`` for satellites: ellipsoidal elevations and an
    elevation mask). Epochs pair when their tags agree within ``align_tol_s``; with
    ``max_age_s > 0`` a rover epoch without such a base epoch pairs with the latest base
    epoch at most that old, carried to the rover's tag with variances growing by
    ``sigma_age_m_s`` per second of age (:mod:`robustrtk.pipeline.base_buffer`; the
    solution's ``age_s`` says how old; ``base_usable`` (B,) marks the base epochs that
    may serve, default all);
    ``inputs(i_rover, i_base)`` builds each step's :class:`EpochInputs` (detector slip
    flags, a moving base's position) — by default just the two epochs. ``engine`` replaces
    the engine built from the other arguments (a filter or policy of one's own).
    ``keep_diagnostics=False`` keeps no diagnostics row, only their counts (a long run's
    rows outweigh its observations).

    Returns
    -------
    RunResult
        One :class:`Solution` per rover epoch with a base match, the diagnostics of each
        DD (none without ``keep_diagnostics``), and ``info`` (references used, epoch counts,
        re-initialisation times, ``row_tally``: the robust filter's decisions counted).
    """
    from robustrtk.ambiguity.lambda_ import backend as lambda_backend
    from robustrtk.pipeline.base_buffer import pair_base_epochs
    from robustrtk.pipeline.engine import DDEngine

    eng = engine or DDEngine(
        cfg, source, base_pos_m, rover_pos0_m, signal=signal, sagnac=sagnac, reference=reference, frame=frame,
        elev_mask_deg=elev_mask_deg, row_groups=row_groups,
    )  # fmt: skip
    out = RunResult()
    # the number of pairs, for the progress total (the loop pairs the same, epoch by epoch)
    n_pairs = len(pair_base_epochs(rover.t_s, base.t_s, align_tol_s, max_age_s, base_usable))
    if n_pairs == 0:
        raise InputError("no common epochs between rover and base observations")
    build: InputBuilder | None = None
    if inputs is not None:
        make = inputs

        def build(i: int, _r: ObsEpoch, j: int, _b: ObsEpoch) -> EpochInputs:
            return make(i, j)

    loop = EpochLoop(eng, align_tol_s, max_age_s, sigma_age_m_s, build)
    usable = np.ones(len(base), bool) if base_usable is None else np.asarray(base_usable, bool)
    # the matrices are small: BLAS threads only contend (tens of times slower when the
    # machine is busy), so the loop runs single-threaded
    # epochs go in chunks: the satellite positions of a chunk are evaluated at once
    lambda_backend()  # read for this run; a bad ROBUSTRTK_LAMBDA_BACKEND stops it here, not in a search
    chunk: list[tuple[EpochInputs, BasePair]] = []

    def flush() -> None:
        prefetch = getattr(eng, "prefetch", None)
        if prefetch is not None:
            prefetch([c[0] for c in chunk])
        for inp, pair in chunk:
            res, sol = loop.solve(inp, pair)
            out.solutions.append(sol)
            if keep_diagnostics:
                out.diagnostics.extend(res.diagnostics)
            notify_progress(progress, loop.n_solved, n_pairs, res.solution.status)
        chunk.clear()

    with one_blas_thread():
        for kind, k in merged_order(rover.t_s, base.t_s, align_tol_s):
            if kind == 0:
                loop.push_base(base.epoch(k), bool(usable[k]))
                continue
            got = loop.prepare(k, rover.epoch(k))
            if got is not None:
                chunk.append(got)
                if len(chunk) == PREFETCH_EPOCHS:
                    flush()
        flush()
    if eng.steps is not None and len(eng.steps) == len(out.solutions):
        out.solutions = smoothed_solutions(out.solutions, eng.steps, eng.floors)
        out.info["smoothed"] = True
    out.info["references"] = sorted(loop.refs_seen)
    out.info["epochs"] = n_pairs
    out.info["reinitialised_at_s"] = list(eng.reinits)
    out.info["row_tally"] = loop.tally.as_dict()
    out.info["integrity"] = dict(eng.integrity.counts)
    return out


__all__ = [
    "PREFETCH_EPOCHS",
    "EpochLoop",
    "EventLog",
    "InputBuilder",
    "Stage",
    "merged_order",
    "run_dd",
    "smoothed_solutions",
    "union_rows",
]
