"""Progress bar and end-of-run summary of the long commands (solve, experiment, demo).

:class:`ProgressBar` is a ``(done, total)`` callback, the kind every pipeline takes; it
also has the ``epoch(done, total, status)`` method that the pipelines call through
:func:`robustrtk.pipeline.results.notify_progress`, so it shows the fix rate so far::

    solving rtk ━━━━━━━━━━╺━━━━━━━━━ 54/120 epochs   38.2 epochs/s   fix 91 %   ETA 2 s

The bar is drawn by ``rich`` on one line of a terminal (at most every ``min_interval_s``)
and nothing is drawn when disabled: :func:`bar_wanted` is the rule (a terminal, and not
``--quiet``). ``rich`` is imported only when a bar is drawn, so a run without a terminal
never loads it.

:func:`format_summary` is the one-screen summary printed at the end of a solve.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Sequence
from typing import IO, Any

from robustrtk.pipeline.api import FIXED_STATUSES, RunSummary


def bar_wanted(quiet: bool, stream: IO[str] | None = None) -> bool:
    """The rule of every command: a bar only on a terminal, never with ``--quiet``."""
    if quiet:
        return False
    s = sys.stderr if stream is None else stream
    try:
        return bool(s.isatty())
    except (AttributeError, ValueError):  # closed or not a file
        return False


def _duration(s: float) -> str:
    if not math.isfinite(s):
        return "?"
    s = max(0.0, s)
    if s < 90:
        return f"{s:.0f} s"
    if s < 5400:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"


class ProgressBar:
    """A one-line progress bar on a stream (stderr by default), drawn by ``rich``.

    Parameters
    ----------
    label : str
        Text before the bar (``"solving rtk"``).
    unit : str
        What is counted (``"epochs"``, ``"tasks"``).
    enabled : bool
        Draw at all (see :func:`bar_wanted`); a disabled bar only counts.
    stream : text stream, optional
        Default ``sys.stderr``.
    show_fix : bool
        Show the fix rate so far (``fixed`` and ``partial`` of the epochs reported with a
        status); otherwise the solved rate is shown when statuses arrive.
    min_interval_s : float
        Least time between two redraws (the last one is always drawn).
    width : int
        Characters of the bar itself.
    clock : callable, optional
        Seconds (default :func:`time.perf_counter`); tests pass a fake one.
    after : str, optional
        Work that follows the last unit without callbacks of its own (``"RTS smoothing the
        track"``): shown once every unit is done, until the bar is closed.
    """

    def __init__(
        self,
        label: str,
        unit: str = "epochs",
        *,
        enabled: bool = True,
        stream: IO[str] | None = None,
        show_fix: bool = False,
        min_interval_s: float = 0.1,
        width: int = 20,
        clock: Callable[[], float] | None = None,
        after: str | None = None,
    ) -> None:
        self.label = label
        self.after = after
        self.unit = unit
        self.enabled = enabled
        self.stream = stream
        self.show_fix = show_fix
        self.min_interval_s = min_interval_s
        self.width = width
        self.clock = clock or time.perf_counter
        self.done = 0
        self.total = 0
        self.n_status = 0
        self.n_fixed = 0
        self.n_solved = 0
        self._t0: float | None = None
        self._last_draw = -math.inf
        self._last_text = ""
        self.closing = False
        self._progress: Any = None  # rich.progress.Progress once drawn
        self._task: Any = None

    # -------------------------------------------------------------- callbacks
    def __call__(self, done: int, total: int) -> None:
        """Unit ``done`` of ``total`` is finished."""
        if self._t0 is None:
            self._t0 = self.clock()
        self.done, self.total = done, total
        self._maybe_draw()

    def epoch(self, done: int, total: int, status: str) -> None:
        """Epoch ``done`` of ``total`` is finished with ``status`` (counts the fix rate)."""
        self.n_status += 1
        self.n_fixed += status in FIXED_STATUSES
        self.n_solved += status != "none"
        self(done, total)

    # -------------------------------------------------------------- rendering
    def rate(self) -> float:
        """Units per second since the first callback (NaN before two instants)."""
        if self._t0 is None:
            return float("nan")
        dt = self.clock() - self._t0
        return self.done / dt if dt > 0 else float("nan")

    def line(self) -> str:
        """What the bar shows beside the bar itself: count, rate, fix or solved rate, ETA."""
        n = len(str(self.total))
        parts = [f"{self.done:>{n}}/{self.total} {self.unit}"]
        rate = self.rate()
        if math.isfinite(rate):
            parts.append(f"{rate:.1f} {self.unit}/s")
        if self.n_status:
            if self.show_fix:
                parts.append(f"fix {100.0 * self.n_fixed / self.n_status:.0f} %")
            else:
                parts.append(f"solved {100.0 * self.n_solved / self.n_status:.0f} %")
        if math.isfinite(rate) and rate > 0 and self.done < self.total:
            parts.append(f"ETA {_duration((self.total - self.done) / rate)}")
        if self.after and self.total and self.done >= self.total and not self.closing:
            parts.append(f"{self.after}...")
        return "   ".join(parts)

    def _start(self) -> Any:
        """Build the ``rich`` display (not yet drawn) and return it."""
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn

        out = sys.stderr if self.stream is None else self.stream
        console = Console(file=out, highlight=False, soft_wrap=False)
        self._progress = Progress(
            TextColumn(self.label),
            BarColumn(bar_width=self.width),
            TextColumn("{task.fields[info]}"),
            console=console,
            auto_refresh=False,
            transient=False,
        )
        self._task = self._progress.add_task(self.label, total=max(self.total, 1), info="")
        return self._progress

    def _maybe_draw(self, force: bool = False) -> None:
        if not self.enabled:
            return
        now = self.clock()
        if not force and self.done < self.total and now - self._last_draw < self.min_interval_s:
            return
        self._last_draw = now
        text = self.line()
        if self._progress is not None and text == self._last_text:
            return
        self._last_text = text
        if self._progress is None:
            progress = self._start()
            progress.update(self._task, completed=self.done, total=max(self.total, 1), info=text)
            progress.start()  # draws the first frame
            return
        self._progress.update(self._task, completed=self.done, total=max(self.total, 1), info=text)
        self._progress.refresh()

    def close(self) -> None:
        """Draw the final state and end the line (nothing if nothing was drawn)."""
        self.closing = True
        if self.enabled and self._t0 is not None:
            self._maybe_draw(force=True)
        if self._progress is not None:
            self._progress.stop()  # the last frame stays, the line is ended
            self._progress = None

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _pct(n: int, total: int) -> str:
    return f"{100.0 * n / total:.1f} %" if total else "n/a"


def format_summary(
    summary: RunSummary,
    *,
    title: str,
    wall_s: float,
    outputs: Sequence[str] = (),
    fix_mode: bool = True,
    flagged_what: str = "DD rows",
    extra: Sequence[tuple[str, str]] = (),
) -> str:
    """The one-screen summary at the end of a run.

    Parameters
    ----------
    summary : RunSummary
        Counts of the solution written (:func:`robustrtk.pipeline.api.summarize`).
    title : str
        First line (command, mode, estimator).
    wall_s : float
        Wall time of the solve (s).
    outputs : sequence of str
        Files written.
    fix_mode : bool
        The mode resolves ambiguities (fix rate and time to first fix are shown).
    flagged_what : str
        What the robust counts count (``"DD rows"``, ``"satellites"`` for SPP's FDE).
    extra : sequence of (name, value)
        More lines (reference transmitters, ...).

    Returns
    -------
    str
        Lines ``name  value`` under ``title``, no trailing newline.
    """
    s = summary
    status = ", ".join(f"{k} {v}" for k, v in s.by_status.items())
    rows: list[tuple[str, str]] = [("epochs", f"{s.epochs} ({s.solved} solved; {status})")]
    if fix_mode:
        rate = "n/a" if not math.isfinite(s.fix_rate) else f"{100.0 * s.fix_rate:.1f} %"
        full = s.by_status.get("fixed", 0)
        part = s.by_status.get("partial", 0)
        rows.append(
            (
                "fix rate",
                f"{rate} of {s.epochs} epochs (Q=1): fixed {full} ({_pct(full, s.epochs)}), "
                f"partial {part} ({_pct(part, s.epochs)})",
            )
        )
        ttff = s.time_to_first_fix_s
        rows.append(
            ("first fix", "none" if not math.isfinite(ttff) else f"{ttff:.0f} s after the first epoch")
        )
    if flagged_what == "satellites":
        rows.append(
            ("faults flagged", f"{s.rows_rejected} satellites excluded by FDE in {s.epochs_flagged} epochs")
        )
    else:
        rows.append(
            (
                "faults flagged",
                f"{s.rows_downweighted} {flagged_what} down-weighted, {s.rows_rejected} rejected, "
                f"in {s.epochs_flagged} epochs",
            )
        )
    rows += list(extra)
    rate_s = s.epochs / wall_s if wall_s > 0 else float("nan")
    rows.append(
        ("time", f"{wall_s:.2f} s ({rate_s:.0f} epochs/s)" if math.isfinite(rate_s) else f"{wall_s:.2f} s")
    )
    if outputs:
        rows.append(("wrote", ", ".join(outputs)))
    w = max(len(k) for k, _ in rows)
    return "\n".join([title] + [f"  {k:<{w}}  {v}" for k, v in rows])


__all__ = ["ProgressBar", "bar_wanted", "format_summary"]
