"""Least-squares SPP of a long observation file in bounded memory: the file is read a block
of epochs at a time (:func:`robustrtk.io.rinex_chunks.iter_rinex_obs`), each block solved
(:func:`robustrtk.pipeline.spp.solve_spp_chunks`) and its ``.pos`` lines written at once
into the temporary of an atomic output (:func:`robustrtk.io.atomic.atomic_paths`: the
target is replaced only when the whole run succeeds). Nothing per epoch is kept but a few
counters, so the memory is that of one block whatever the file's length.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from os import PathLike

from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.io.atomic import atomic_paths
from robustrtk.io.rinex_chunks import EPOCHS_PER_CHUNK, iter_rinex_obs
from robustrtk.io.rinex_nav import NavData
from robustrtk.io.solution_pos import pos_column_header, pos_header, pos_lines
from robustrtk.pipeline.api import RunSummary
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.spp import solve_spp_chunks


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
) -> SppRunCounts:
    """Least-squares SPP of the RINEX file ``obs`` written to the ``.pos`` file ``out``.

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
        Epochs read and solved at a time.
    inputs : sequence of str
        ``% inp file`` header lines (default: ``obs``).
    progress : callable (done, total), optional
        Called after each block with the epochs done (total unknown: -1).

    Returns
    -------
    SppRunCounts
    """
    counts = SppRunCounts()
    chunks = iter_rinex_obs(obs, systems=systems, epochs_per_chunk=epochs_per_chunk)
    with atomic_paths([out]) as tmps:
        with open(tmps[0], "w") as fh:
            fh.write("".join(f"{h}\n" for h in pos_header(list(inputs) or [str(obs)], None, "llh", ())))
            fh.write("\n".join(pos_column_header("llh")) + "\n")
            for epochs in solve_spp_chunks(chunks, nav, cfg, systems, block_epochs=epochs_per_chunk):
                counts.epochs += len(epochs)
                for e in epochs:
                    counts.excluded += len(e.excluded)
                    counts.epochs_flagged += bool(e.excluded)
                    if e.status == "single":
                        counts.single += 1
                    elif e.reason:
                        key = e.reason.split(" ", 1)[0]
                        counts.refused[key] = counts.refused.get(key, 0) + 1
                fh.write("".join(pos_lines((e.to_solution() for e in epochs), "llh")))
                if progress is not None:
                    progress(counts.epochs, -1)
    return counts


__all__ = ["SppRunCounts", "solve_spp_to_pos"]
