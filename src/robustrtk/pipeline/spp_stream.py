"""Least-squares SPP of a long observation file in bounded memory: the file is read a block
of epochs at a time (:func:`robustrtk.io.rinex_chunks.iter_rinex_obs`), each block solved
(:class:`robustrtk.pipeline.spp.BlockSolver`, blocks aligned as the whole-file run's) and
its ``.pos`` lines written at once into the temporary of an atomic output
(:func:`robustrtk.io.atomic.atomic_paths`: the target is replaced only when the whole run
succeeds). Nothing per epoch is kept but its time (8 bytes, for the navigation coverage of
the whole file) and a few counters, so the memory is that of one block whatever the
file's length. ``robustrtk solve --mode spp`` runs it (:mod:`robustrtk.cli.gnss_stream`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from os import PathLike
from typing import TextIO

import numpy as np

from robustrtk.core import FloatArray, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.io.atomic import atomic_paths
from robustrtk.io.rinex_chunks import EPOCHS_PER_CHUNK, iter_rinex_obs
from robustrtk.io.rinex_nav import NavData
from robustrtk.io.solution_pos import pos_column_header, pos_header, pos_table_lines
from robustrtk.io.solution_table import check_status
from robustrtk.pipeline.api import RunSummary
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.loop import EpochLoop
from robustrtk.pipeline.spp import BLOCK_EPOCHS, BlockSolver
from robustrtk.pipeline.spp_common import (
    BAND1_PREFERENCE,
    SppEpoch,
    lsq_settings,
    nav_and_source,
    select_band1,
)


@dataclass
class SppRunCounts:
    """What a streamed run did.

    Attributes
    ----------
    epochs : int
    single : int
        Epochs written (status ``single``).
    excluded : int
        Satellites excluded by FDE, over the run.
    epochs_flagged : int
        Epochs with at least one satellite excluded.
    refused : dict str -> int
        Epochs written as none by the first word of their reason (``height``, ``residuals``,
        ``position``, ``jump``, ``no``).
    """

    epochs: int = 0
    single: int = 0
    excluded: int = 0
    epochs_flagged: int = 0
    refused: dict[str, int] = field(default_factory=dict)
    no_obs: int = 0
    few_sats: int = 0
    t_s: list[FloatArray] = field(default_factory=list)
    systems: set[str] = field(default_factory=set)
    has_code: bool = False
    masked: dict[str, int] = field(default_factory=dict)
    duplicates: int = 0
    n_code: int = 0
    with_doppler: int = 0
    info: dict[str, object] = field(default_factory=dict)
    read_notes: list[str] = field(default_factory=list)

    def add_batch(self, batch: ObsBatch) -> None:
        """Count what the whole-file checks read of a block as read (before signal choice):
        its epoch times and systems (navigation coverage), whether it has code, the values
        masked, the repeated epochs dropped, code with Doppler (the Kalman hint), and the
        reader's notes (each distinct sentence once)."""
        self.t_s.append(np.asarray(batch.t_s, float))
        self.systems.update(batch.system)
        code = np.isfinite(batch.code_m)
        n_code = int(code.sum())
        self.has_code |= n_code > 0
        self.n_code += n_code
        self.with_doppler += int((code & np.isfinite(batch.doppler_hz)).sum())
        masked = batch.meta.get("masked_values")
        if isinstance(masked, dict):
            for k, n in masked.items():
                self.masked[k] = self.masked.get(k, 0) + int(n)
        dup = batch.meta.get("duplicate_epochs_dropped", 0)
        self.duplicates += int(dup) if isinstance(dup, int) else 0
        notes = batch.meta.get("read_notes")
        for note in notes if isinstance(notes, list) else []:
            if str(note) not in self.read_notes:
                self.read_notes.append(str(note))

    def add_epochs(self, epochs: Sequence[SppEpoch]) -> None:
        """Count solved epochs."""
        self.epochs += len(epochs)
        for e in epochs:
            self.excluded += len(e.excluded)
            self.epochs_flagged += bool(e.excluded)
            if e.status == "single":
                self.single += 1
                continue
            if e.reason:
                key = e.reason.split(" ", 1)[0]
                self.refused[key] = self.refused.get(key, 0) + 1
            n_used = e.n_used
            self.no_obs += n_used == 0
            self.few_sats += 0 < n_used < 4

    def times(self) -> FloatArray:
        """Every epoch time read (GPST s)."""
        return np.concatenate(self.t_s) if self.t_s else np.zeros(0)

    def summary(self) -> RunSummary:
        """The end-of-run numbers, as :meth:`robustrtk.pipeline.api.SolutionSeries.summary`
        gives them for the same run kept whole."""
        by_status = {"none": self.epochs - self.single, "single": self.single}
        return RunSummary(
            epochs=self.epochs,
            solved=self.single,
            by_status={k: v for k, v in sorted(by_status.items()) if v},
            fixed=0,
            fix_rate=0.0 if self.epochs else float("nan"),
            time_to_first_fix_s=float("nan"),
            rows_downweighted=0,
            rows_rejected=self.excluded,
            epochs_flagged=self.epochs_flagged,
        )


class SignalChoiceChanged(Exception):
    """Raised inside a streamed run when its blocks chose different band-1 signals for a
    system (the whole-file run chooses once): the run is made again with the choice fixed."""


def solve_spp_to_pos(
    obs: str | PathLike[str],
    nav: NavData | EphemerisSource,
    out: str | PathLike[str],
    cfg: Config | None = None,
    *,
    systems: str | None = None,
    epochs_per_chunk: int = EPOCHS_PER_CHUNK,
    inputs: Sequence[str] = (),
    progress: Callable[[int, int], None] | None = None,
    finish: Callable[[SppRunCounts], None] | None = None,
) -> SppRunCounts:
    """Least-squares SPP of the RINEX file ``obs`` written to the ``.pos`` file ``out``.

    The epochs are solved in blocks of :data:`robustrtk.pipeline.spp.BLOCK_EPOCHS` counted
    from the file's first epoch, each started from the last position accepted before it, and
    the band-1 signal of each system is the one the whole file would choose
    (:func:`robustrtk.pipeline.spp_common.select_band1`): when the blocks of the file chose
    differently, the file is solved a second time with the whole file's choice. So the
    ``.pos`` is that of :func:`robustrtk.pipeline.spp.solve_spp` on the whole file.

    Parameters
    ----------
    obs : path-like
        RINEX observation file (plain RINEX 3/4 streamed; others read whole).
    nav : NavData or EphemerisSource
    out : path-like
        The ``.pos`` file (RTKLIB llh), replaced atomically at the end.
    cfg : Config, optional
        ``preset("spp")`` by default.
    systems : str, optional
        System letters to keep.
    epochs_per_chunk : int
        Epochs read at a time.
    inputs : sequence of str
        ``% inp file`` header lines (default: ``obs``).
    progress : callable (done, total), optional
        Called after each block with the epochs done (total unknown: -1).
    finish : callable (counts), optional
        Called after the last epoch, before ``out`` is replaced: an exception it raises
        leaves ``out`` as it was (the checks of a run that need the whole file).

    Returns
    -------
    SppRunCounts
    """
    with atomic_paths([out]) as tmps:
        with open(tmps[0], "w") as fh:
            try:
                counts = _stream(obs, nav, fh, cfg, systems, epochs_per_chunk, inputs, progress, None)
            except SignalChoiceChanged as changed:
                fh.seek(0)
                fh.truncate()
                choice = changed.args[0]
                counts = _stream(obs, nav, fh, cfg, systems, epochs_per_chunk, inputs, progress, choice)
        if finish is not None:
            finish(counts)
    return counts


def _stream(
    obs: str | PathLike[str],
    nav: NavData | EphemerisSource,
    fh: TextIO,
    cfg: Config | None,
    systems: str | None,
    epochs_per_chunk: int,
    inputs: Sequence[str],
    progress: Callable[[int, int], None] | None,
    choice: dict[str, str] | None,
) -> SppRunCounts:
    """One pass over the file (:func:`solve_spp_to_pos`), written to ``fh``; with ``choice``
    (system letter -> signal) that band-1 signal for each system, else
    :class:`SignalChoiceChanged` (with the whole file's choice) when two blocks chose
    differently."""
    counts = SppRunCounts()
    cfg = cfg or preset("spp")
    settings = lsq_settings(cfg)
    navd, eph = nav_and_source(nav)
    fh.write("".join(f"{h}\n" for h in pos_header(list(inputs) or [str(obs)], None, "llh", ())))
    fh.write("\n".join(pos_column_header("llh")) + "\n")
    solver: BlockSolver | None = None
    seed: FloatArray | None = None
    chosen: dict[str, tuple[int, int, str]] = {}
    changed = False
    for batch in iter_rinex_obs(obs, systems=systems, epochs_per_chunk=epochs_per_chunk):
        counts.add_batch(batch)
        b1 = select_band1(batch if choice is None else _only_signals(batch, choice), systems)
        if choice is None and _check_choice(batch, b1.meta["signal_by_system"], chosen):
            changed = True
        if changed:
            continue  # only the choices of the rest of the file are wanted now
        solver = BlockSolver(b1, eph, navd, settings, after=solver)
        loop = EpochLoop(solver)
        lo = 0
        while lo < len(b1):
            g = counts.epochs
            if g % BLOCK_EPOCHS == 0:  # a block starts here: its seed, as the whole-file run's
                seed = np.zeros(3) if solver.prev is None else solver.prev
            hi = min(len(b1), lo + BLOCK_EPOCHS - g % BLOCK_EPOCHS)
            epochs = loop.step((lo, hi, seed))
            counts.add_epochs(epochs)
            fh.write("".join(_pos_lines(epochs)))
            lo = hi
        if progress is not None:
            progress(counts.epochs, -1)
    if changed:
        raise SignalChoiceChanged({s: r[2] for s, r in chosen.items()})
    return counts


def _pos_lines(epochs: Sequence[SppEpoch]) -> list[str]:
    """The ``.pos`` lines (llh) of solved epochs: what :func:`robustrtk.io.solution_pos.
    pos_lines` writes for their :meth:`~robustrtk.pipeline.spp_common.SppEpoch.to_solution`
    (``ns`` the rows used, no age, no ratio), from their columns."""
    cand = [e for e in epochs if e.status != "none"]
    if not cand:
        return []
    pos = np.array([e.pos_ecef_m for e in cand], dtype=float).reshape(len(cand), 3)
    finite = np.isfinite(pos).all(axis=1)
    sel = [e for e, ok in zip(cand, finite.tolist(), strict=True) if ok]
    for e in sel:
        check_status(e.status)
    return pos_table_lines(
        [e.t_s for e in sel],
        pos[finite],
        np.array([e.cov_m2 for e in sel], dtype=float),
        [e.status for e in sel],
        [int(e.n_used) for e in sel],
        [0.0] * len(sel),
        [math.nan] * len(sel),
        "llh",
    )


def _band_rank(system: str, signal: str, signals: Sequence[str]) -> tuple[int, int]:
    """Where ``signal`` stands in :func:`select_band1`'s order for ``system``."""
    bands = BAND1_PREFERENCE.get(system, ("1",))
    return bands.index(signal[:1]), list(signals).index(signal)


def _check_choice(batch: ObsBatch, got: object, chosen: dict[str, tuple[int, int, str]]) -> bool:
    """Record the band-1 signals a block chose (per system the first in preference order
    of those chosen so far: the whole file's choice at the end); whether a system's changed."""
    changed = False
    assert isinstance(got, dict)
    for s, sig in got.items():
        rank = (*_band_rank(s, sig, batch.signals), sig)
        if s in chosen and chosen[s] != rank:
            changed = True
        chosen[s] = min(chosen.get(s, rank), rank)
    return changed


def _only_signals(batch: ObsBatch, choice: dict[str, str]) -> ObsBatch:
    """``batch`` with the code of every other band-1 candidate of a system in ``choice``
    masked, so that :func:`select_band1` takes that system's chosen signal or none."""
    code = batch.code_m.copy()
    sys_arr = np.array(batch.system)
    for s, sig in choice.items():
        rows = np.flatnonzero(sys_arr == s)
        bands = BAND1_PREFERENCE.get(s, ("1",))
        for k, other in enumerate(batch.signals):
            if other != sig and other[:1] in bands:
                code[:, rows, k] = np.nan
    return replace(batch, code_m=code)


__all__ = ["SignalChoiceChanged", "SppRunCounts", "solve_spp_to_pos"]
