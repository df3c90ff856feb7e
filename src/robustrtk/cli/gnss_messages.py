"""Messages of a GNSS solve shared by the whole-file and streamed paths
(:mod:`robustrtk.cli.gnss`, :mod:`robustrtk.cli.gnss_stream`): warnings about the file as
read, the ``--kalman`` hint, the sanity-check count, and the error of a run that solved
nothing (exit status 3)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import click

from robustrtk.errors import InputError


def warn(text: str) -> None:
    """One ``warning:`` line on stderr."""
    click.echo(f"warning: {text}", err=True)


#: Phone logs (reader kinds of :func:`robustrtk.io.readers.detect_format`).
PHONE_READERS = ("gnsslogger", "gsdc_device_gnss")


def kalman_hint_counts(path: str, n_code: int, with_doppler: int) -> str | None:
    """:func:`robustrtk.cli.gnss.kalman_hint` of a file with ``n_code`` code observations, ``with_doppler`` of
    them with a Doppler."""
    from robustrtk.io.readers import detect_format

    try:
        phone = detect_format(path) in PHONE_READERS
    except InputError:
        phone = False
    if not phone and (n_code == 0 or with_doppler < 0.5 * n_code):
        return None
    what = "a phone log" if phone else "code with Doppler on most rows"
    return (
        f"least-squares SPP uses the code alone; this is {what}: --kalman adds Doppler, carrier "
        "phase and the motion between epochs (GSDC Pixel 5: 28 m → 2.4 m H95)"
    )


def warn_read(
    path: str,
    masked: str,
    duplicates: int,
    coverage: float = 1.0,
    what: str = "rover",
    notes: Sequence[str] = (),
) -> None:
    """The warnings of a receiver's file as read: the impossible values masked (``masked``,
    :func:`robustrtk.io.obs_checks.masked_text`), the repeated epochs dropped, a
    navigation coverage below 1 of its epochs (``what``), and the reader's notes on the
    oddities it tolerated (``meta["read_notes"]``), one line each."""
    for note in notes:
        warn(f"{path}: {note}")
    if masked:
        warn(f"{path}: impossible values masked as missing ({masked}): infinite, or out of physical range")
    if duplicates:
        warn(f"{path}: {duplicates} epoch(s) written twice in a row, byte for byte: the repeat dropped")
    if coverage < 1.0:
        warn(f"{path}: the navigation data covers only {100 * coverage:.1f} % of the {what} epochs")


def note_masked(notes: list[tuple[str, str]] | None, what: str, text: str) -> None:
    """The summary line of the values the reader masked (left out of every solution), from the
    text of :func:`robustrtk.io.obs_checks.masked_text`."""
    if text and notes is not None:
        notes.append(
            ("values excluded", f"{what}: {text} out of physical range (infinite, negative or too large)")
        )


def say_hint(hint: str | None, notes: list[tuple[str, str]] | None, quiet: bool) -> None:
    """The ``--kalman`` hint (:func:`kalman_hint`) as a note on stderr and a summary line."""
    if hint and not quiet:
        click.echo(f"note: {hint}", err=True)
    if hint and notes is not None:
        notes.append(("hint", "--kalman (Kalman SPP on code, Doppler and phase)"))


class NothingSolved(click.ClickException):
    """No epoch of the run was solved: exit status 3, with the epochs counted per cause."""

    exit_code = 3

    def format_message(self) -> str:
        return self.message

    def show(self, file: Any = None) -> None:
        click.echo(f"error: {self.message}", err=True)


def warn_refused(refused: dict[str, int]) -> None:
    """One warning line for the epochs that failed the single-point sanity check, counted
    by the first word of their reason (``residuals``, ``height``, ``position``, ``jump``)."""
    if refused:
        what = ", ".join(f"{n} by {k}" for k, n in sorted(refused.items()))
        warn(f"{sum(refused.values())} epochs failed the single-point sanity check ({what}): written as none")


def nothing_solved(n_epochs: int, n_no_obs: int, n_few: int, min_sats: int) -> NothingSolved:
    """The :class:`NothingSolved` of a run of ``n_epochs`` none solved, ``n_no_obs`` of them
    with no usable observation and ``n_few`` with fewer than ``min_sats`` transmitters."""
    if not n_epochs:
        return NothingSolved("no epoch to solve: no epoch with observations of the kept systems and signals")
    n0, few, sols = n_no_obs, n_few, range(n_epochs)
    rest = len(sols) - n0 - few
    causes = [
        f"{n0} with no usable observation (masks, signals, navigation data, common epochs)",
        f"{few} with fewer than {min_sats} transmitters",
        f"{rest} rejected by the estimator (outliers, geometry)",
    ]
    return NothingSolved(
        f"no epoch solved of {len(sols)}: " + "; ".join(c for c in causes if not c.startswith("0 "))
    )


__all__ = [
    "PHONE_READERS",
    "NothingSolved",
    "kalman_hint_counts",
    "note_masked",
    "nothing_solved",
    "say_hint",
    "warn",
    "warn_read",
    "warn_refused",
]
