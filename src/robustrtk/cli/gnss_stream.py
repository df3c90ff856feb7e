"""``robustrtk solve FILE --mode spp`` streamed: least squares on a long RINEX file in the
memory of a block of epochs.

:func:`solve_spp_streamed` runs :func:`robustrtk.pipeline.spp_stream.solve_spp_to_pos` with
the checks and messages of the whole-file path of :func:`robustrtk.cli.gnss.run_gnss`: the
values masked, repeated epochs, navigation coverage and ``--kalman`` hint are counted block
by block and said after the last epoch, in the whole-file order; nothing solved stops with
exit status 3 and the same counts. A run whose whole-file check fails (no epoch, no code,
navigation data covering none of the epochs) or whose reading fails is given back to the
whole-file path (None), which says why in its own words; so is any input
:func:`streamable` refuses.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from robustrtk.cli.gnss_messages import (
    kalman_hint_counts,
    note_masked,
    nothing_solved,
    say_hint,
    warn_read,
    warn_refused,
)
from robustrtk.errors import InputError

if TYPE_CHECKING:
    from robustrtk.pipeline.config import Config
    from robustrtk.pipeline.spp_stream import SppRunCounts

#: The order of :func:`robustrtk.io.obs_checks.mask_impossible`'s counts.
MASKED_ORDER = ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz")
#: First words of the reasons :func:`robustrtk.cli.gnss.warn_refused` counts (``position``:
#: ``position sigma``).
REFUSED_KEYS = ("residuals", "height", "position", "jump")


class _WholeFile(Exception):
    """A check that the whole-file path says in its own words."""


def streamable(rover: str, cfg: Config, out_kind: str, diagnostics: str | None) -> bool:
    """Whether a SPP run can be streamed: least squares (no FGO), no diagnostics, no time
    window or interval, a ``.pos`` output (``out_kind``, :func:`robustrtk.cli.gnss.output_kind`),
    and a plain RINEX 3/4 observation file
    (:func:`robustrtk.io.rinex_chunks.is_streamed`)."""
    from robustrtk.io.readers import detect_format
    from robustrtk.io.rinex_chunks import is_streamed
    from robustrtk.pipeline.gnss_inputs import window_set

    if cfg.estimator.filter != "lsq" or cfg.spp.fgo or diagnostics or window_set(cfg.gnss):
        return False
    try:
        return out_kind == "pos" and detect_format(rover) == "rinex_obs" and is_streamed(rover)
    except (InputError, OSError):
        return False


def solve_spp_streamed(
    rover: str,
    eph: Any,
    cfg: Config,
    out: str,
    nav: Sequence[str],
    progress: Callable[[int, int], None] | None,
    notes: list[tuple[str, str]] | None,
    quiet: bool,
) -> SppRunCounts | None:
    """The least-squares SPP of ``rover`` streamed to ``out``, with the warnings, notes and
    errors of the whole-file path; None (``out`` untouched) when that path must say why the
    file cannot be solved."""
    from robustrtk.pipeline.gnss_inputs import nav_coverage_of
    from robustrtk.pipeline.spp_stream import solve_spp_to_pos

    systems = cfg.gnss.systems.upper() if cfg.gnss.systems else None

    def finish(c: SppRunCounts) -> None:
        if c.epochs == 0 or not c.has_code:
            raise _WholeFile("no observations")
        frac = nav_coverage_of(c.times(), c.systems, eph)
        if frac == 0.0:
            raise _WholeFile("no navigation coverage")
        masked = ", ".join(f"{c.masked[k]} {k}" for k in MASKED_ORDER if c.masked.get(k))
        warn_read(rover, masked, c.duplicates, frac, "rover", c.read_notes)
        note_masked(notes, "rover", masked)
        say_hint(kalman_hint_counts(rover, c.n_code, c.with_doppler), notes, quiet)
        warn_refused({k: n for k, n in c.refused.items() if k in REFUSED_KEYS})
        if c.single == 0:
            raise nothing_solved(c.epochs, c.no_obs, c.few_sats, 4)

    inputs = [str(rover)] + [str(n) for n in nav]
    bar = progress
    if progress is not None and getattr(progress, "enabled", True):
        total = epoch_lines(rover)

        def bar(done: int, _total: int) -> None:
            progress(done, max(total, done))

    try:
        return solve_spp_to_pos(
            rover, eph, out, cfg, systems=systems, inputs=inputs, progress=bar, finish=finish
        )
    except (_WholeFile, InputError):
        return None


def epoch_lines(path: str) -> int:
    """The epoch records (lines starting ``>``) of a RINEX 3/4 file: the total a progress
    bar shows (events included, so at least the epochs solved)."""
    n, last = 0, b"\n"
    with open(path, "rb") as fh:
        while block := fh.read(1 << 22):
            n += block.count(b"\n>") + (last == b"\n" and block[:1] == b">")
            last = block[-1:]
    return n


__all__ = ["MASKED_ORDER", "REFUSED_KEYS", "epoch_lines", "solve_spp_streamed", "streamable"]
