"""Atomic output: write to temporary files beside the targets, then rename them over.

:func:`atomic_path` handles one file; :func:`atomic_paths` a set of files written by one
run (solution, diagnostics), renamed together at the end in the order given — the caller
puts the solution last, so a run interrupted before the end leaves the previous set intact
and one interrupted between the renames never leaves an old solution beside new side files
that claim to describe it. On any exception (``KeyboardInterrupt`` and the SIGTERM exception
of :mod:`robustrtk.cli.entry` included) the temporaries are removed.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

from robustrtk.core import InputError


def _temporary_beside(path: str | os.PathLike[str]) -> tuple[Path, str]:
    target = Path(path)
    directory = target.parent if str(target.parent) else Path(".")
    if not directory.is_dir():
        raise InputError("output directory does not exist", path=str(target))
    if target.is_dir():
        raise InputError("is a directory, expected a file", path=str(target))
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise InputError(f"cannot create the output file ({exc.strerror or exc})", path=str(target)) from None
    os.close(fd)
    return target, tmp


def _publish(tmp: str, target: Path) -> None:
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, target)
    except OSError as exc:
        raise InputError(f"cannot write the output file ({exc.strerror or exc})", path=str(target)) from None


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[str]:
    """Yield a temporary path in the target's directory; on success it is renamed over
    ``path`` (with the usual umask permissions), on failure removed — the old file stays.

    Raises :class:`InputError` (naming ``path``, not the temporary) when the target
    directory does not exist or the file cannot be created there.
    """
    with atomic_paths([path]) as tmps:
        yield tmps[0]


@contextlib.contextmanager
def atomic_paths(paths: Sequence[str | os.PathLike[str]]) -> Iterator[list[str]]:
    """Temporaries for every path of ``paths``, renamed over them in that order once the
    block succeeds (put the main output last); all removed if it fails.

    Parameters
    ----------
    paths : sequence of path-like
        Target files (distinct).

    Yields
    ------
    list of str
        One temporary path per target, in the same directory.
    """
    made: list[tuple[Path, str]] = []
    try:
        for p in paths:
            made.append(_temporary_beside(p))
        yield [tmp for _, tmp in made]
        for target, tmp in made:
            _publish(tmp, target)
    finally:
        for _, tmp in made:
            with contextlib.suppress(OSError):
                os.unlink(tmp)


__all__ = ["atomic_path", "atomic_paths"]
