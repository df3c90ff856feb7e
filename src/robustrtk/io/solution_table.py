"""Solution tables and helpers shared by the solution file readers and writers.

See :mod:`robustrtk.io.solution` for the formats.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import IO

import numpy as np
import numpy.typing as npt

from robustrtk.core import STATUSES, FloatArray, InputError, IntArray, Solution
from robustrtk.io.atomic import atomic_path

__all__ = [
    "PathLike",
    "SolutionTable",
    "StrArray",
    "check_status",
    "float_field",
    "fmt_float",
    "int_field",
    "require_ecef",
    "POS_FRAMES",
    "open_atomic_text",
    "read_text_lines",
    "writable_solutions",
]

PathLike = str | os.PathLike[str]
StrArray = npt.NDArray[np.str_]


@dataclass(frozen=True)
class SolutionTable:
    """Solutions of T epochs as arrays.

    Attributes
    ----------
    t_s : ndarray, shape (T,)
        Epoch times (s).
    pos_m : ndarray, shape (T, 3)
        Positions (ECEF for GNSS, local for pseudolites), m.
    std_m : ndarray, shape (T, 3)
        Standard deviations of the position components in the same frame (m); NaN if
        unknown.
    status : ndarray of str, shape (T,)
        Values of :data:`robustrtk.core.STATUSES`.
    n_used : ndarray of int, shape (T,)
        Observations used (RTKLIB ``ns``: satellites).
    ratio : ndarray, shape (T,)
        Ratio test value (NaN or 0 where none).
    n_fixed, n_amb : ndarray of int, shape (T,)
        Fixed ambiguities and ambiguities in the state; -1 when the file does not say
        (RTKLIB ``.pos``).
    vel_m_s : ndarray, shape (T, 3), or None
        Velocities (NaN rows where absent).
    """

    t_s: FloatArray
    pos_m: FloatArray
    std_m: FloatArray
    status: StrArray
    n_used: IntArray
    ratio: FloatArray
    n_fixed: IntArray
    n_amb: IntArray
    vel_m_s: FloatArray | None = None

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    @classmethod
    def from_solutions(cls, solutions: Iterable[Solution]) -> SolutionTable:
        """Stack :class:`Solution` records (standard deviations from ``cov_m2``)."""
        sols = list(solutions)
        T = len(sols)
        t = np.array([s.t_s for s in sols], dtype=float)
        pos = np.array([np.asarray(s.pos_m, float) for s in sols]).reshape(T, 3)
        cov = np.array([np.asarray(s.cov_m2, float) for s in sols]).reshape(T, 3, 3)
        with np.errstate(invalid="ignore"):
            std = np.sqrt(np.diagonal(cov, axis1=1, axis2=2))
        vel = None
        if any(s.vel_m_s is not None for s in sols):
            vel = np.array(
                [
                    np.full(3, np.nan) if s.vel_m_s is None else np.asarray(s.vel_m_s, float) for s in sols
                ]  # fmt: skip
            ).reshape(T, 3)
        return cls(
            t_s=t,
            pos_m=pos,
            std_m=std,
            status=np.array([s.status for s in sols], dtype=str).reshape(T),
            n_used=np.array([s.n_used for s in sols], dtype=np.int64).reshape(T),
            ratio=np.array([s.ratio for s in sols], dtype=float).reshape(T),
            n_fixed=np.array([s.n_fixed for s in sols], dtype=np.int64).reshape(T),
            n_amb=np.array([s.n_amb for s in sols], dtype=np.int64).reshape(T),
            vel_m_s=vel,
        )


@contextlib.contextmanager
def open_atomic_text(path: PathLike, newline: str | None = None) -> Iterator[IO[str]]:
    """Open a temporary file beside ``path`` and rename it over ``path`` on success.

    Parameters
    ----------
    path : path-like
        Target file.
    newline : str, optional
        As for :func:`open` (``""`` keeps the writer's line ends).

    Yields
    ------
    file object
        UTF-8 text file open for writing.
    """
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline=newline) as fh:
        yield fh


def read_text_lines(path: PathLike) -> list[str]:
    """Lines of a UTF-8 text file (undecodable bytes replaced); :class:`InputError` if
    unreadable or not a regular file (a FIFO or a device is refused at once)."""
    from robustrtk.io.rinex_file import check_regular_file

    check_regular_file(str(path))
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return fh.read().splitlines()
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", path=str(path)) from exc


def check_status(status: str) -> str:
    """``status`` if it is one of :data:`robustrtk.core.STATUSES`, else :class:`InputError`."""
    if status not in STATUSES:
        raise InputError(f"unknown solution status {status!r}; expected one of {STATUSES}")
    return status


#: Frames of solution positions: ``ecef`` (GNSS, WGS84 ECEF metres) or ``local`` (pseudolites).
POS_FRAMES = ("ecef", "local")


def require_ecef(pos_frame: str, what: str, path: PathLike | None) -> None:
    """:class:`InputError` unless ``pos_frame`` is ``"ecef"``: ``what`` (a ``.pos``, NMEA,
    a map track) needs geodetic positions, which a local (pseudolite) frame has not.

    The frame is the caller's statement (the ``frame`` of :class:`robustrtk.pipeline.series.SolutionSeries`),
    never a guess from the magnitude of the positions: one wild epoch does not turn a
    GNSS run into a "local" one.
    """
    if pos_frame not in POS_FRAMES:
        raise InputError(f"position frame: expected one of {POS_FRAMES}, got {pos_frame!r}",
                         None if path is None else str(path))  # fmt: skip
    if pos_frame != "ecef":
        raise InputError(f"{what} needs ECEF (GNSS) positions; {pos_frame}-frame solutions go to .csv",
                         None if path is None else str(path))  # fmt: skip


def writable_solutions(solutions: Iterable[Solution]) -> list[Solution]:
    """Solutions with a status other than ``"none"`` and a finite position (statuses
    checked)."""
    sols = [s for s in solutions if s.status != "none" and np.all(np.isfinite(s.pos_m))]
    for s in sols:
        check_status(s.status)
    return sols


def fmt_float(v: float) -> str:
    """Shortest text that reads back as the same float (``repr``)."""
    return repr(float(v))


def float_field(text: str, name: str, path: PathLike, line: int) -> float:
    """``float(text)``, or :class:`InputError` naming the field, file and line."""
    try:
        return float(text)
    except ValueError:
        raise InputError(f"field {name!r}: expected a number, got {text!r}", str(path), line) from None


def int_field(text: str, name: str, path: PathLike, line: int) -> int:
    """``int(text)``, or :class:`InputError` naming the field, file and line."""
    try:
        return int(text)
    except ValueError:
        raise InputError(f"field {name!r}: expected an integer, got {text!r}", str(path), line) from None
