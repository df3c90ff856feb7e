"""Atomic output: write to temporary files beside the targets, then rename them over.

:func:`atomic_path` handles one file; :func:`atomic_paths` the set of files one run writes
(solution, diagnostics) as one transaction:

1. every temporary ``.<name>.<random>.tmp`` is created and recorded with SIGINT/SIGTERM
   deferred, so a signal can never leave a temporary that the clean-up does not know of;
2. the caller writes all of them (nothing visible changes yet; an exception, a signal or a
   full disk here removes the temporaries and leaves the previous outputs as they were);
3. commit: with the signals deferred, each existing target is hard-linked to a backup
   ``.<name>.<random>.tmp``, then the temporaries are renamed over the targets. If a rename
   fails, the targets already replaced are restored from their backups, so the set is old
   or new as a whole, never a new diagnostics file beside an old solution. The backups are
   removed, and a signal received meanwhile is delivered once the commit is over.

A disk error while writing (no space left, quota, I/O error, read-only file system) is an
:class:`InputError` naming the target, never the temporary. Only a SIGKILL or a power cut
during the commit (a few renames) can leave the set mixed.
"""

from __future__ import annotations

import contextlib
import errno
import os
import signal
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import FrameType
from typing import Any

from robustrtk.errors import InputError

#: ``errno`` values of a disk that cannot take the output (reported as one line).
DISK_ERRNOS = frozenset(
    e
    for e in (errno.ENOSPC, getattr(errno, "EDQUOT", None), errno.EIO, errno.EROFS, errno.EFBIG)
    if e is not None
)
_DEFERRED = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM for the duration of the block, then deliver them.

    Outside the main thread (where handlers cannot be changed) the block runs as is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []

    def hold(signum: int, frame: FrameType | None) -> None:
        pending.append(signum)

    old: dict[int, Any] = {}
    try:
        for s in _DEFERRED:
            old[s] = signal.signal(s, hold)
        yield
    finally:
        for signum, handler in old.items():
            signal.signal(signum, handler)
        for signum in dict.fromkeys(pending):
            if callable(old.get(signum)) or old.get(signum) == signal.SIG_DFL:
                signal.raise_signal(signum)


def disk_error(exc: OSError, target: str | os.PathLike[str]) -> InputError:
    """The one-line :class:`InputError` for a failed write of ``target``."""
    return InputError(f"cannot write the output file ({exc.strerror or exc})", path=str(target))


#: Open flags of a new temporary: created here or failing, never through a link.
_CREATE_FLAGS = os.O_RDWR | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_BINARY", 0)


def _create_empty(path: str) -> None:
    """Create the empty file ``path`` (mode 0600); :class:`FileExistsError` if it exists."""
    os.close(os.open(path, _CREATE_FLAGS, 0o600))


def _temporary_beside(target: Path, kind: str = "") -> str:
    """A new empty file ``.<name>.<kind><random>.tmp`` beside ``target`` (mode 0600; its
    absolute path), as :func:`tempfile.mkstemp` makes one, without loading ``tempfile``
    (with ``shutil`` and ``random``, a few ms of every command's start)."""
    directory = target.parent if str(target.parent) else Path(".")
    for _ in range(100):  # 48 random bits a name: a clash is all but impossible
        tmp = os.path.abspath(directory / f".{target.name}.{kind}{os.urandom(6).hex()}.tmp")
        try:
            _create_empty(tmp)
        except FileExistsError:
            continue
        except OSError as exc:
            raise InputError(
                f"cannot create the output file ({exc.strerror or exc})", path=str(target)
            ) from None
        return tmp
    raise InputError("cannot create the output file (no free temporary name beside it)", path=str(target))


def _check_target(path: str | os.PathLike[str]) -> Path:
    target = Path(path)
    directory = target.parent if str(target.parent) else Path(".")
    if not directory.is_dir():
        raise InputError("output directory does not exist", path=str(target))
    if target.is_dir():
        raise InputError("is a directory, expected a file", path=str(target))
    return target


def _commit(made: Sequence[tuple[Path, str]], backups: list[str]) -> None:
    """Rename every temporary over its target; on a failure restore the replaced ones."""
    umask = os.umask(0)
    os.umask(umask)
    saved: dict[Path, str | None] = {}  # backup; "" when there was no old file; None: no backup
    for target, _ in made:
        saved[target] = ""
        if target.exists():
            backup = _temporary_beside(target, "old.")
            backups.append(backup)
            try:
                os.unlink(backup)
                os.link(target, backup)
                saved[target] = backup
            except OSError:
                saved[target] = None  # no hard links here: no way back for this one
    done: list[Path] = []
    try:
        for target, tmp in made:
            try:
                os.chmod(tmp, 0o666 & ~umask)
                os.replace(tmp, target)
            except OSError as exc:
                raise disk_error(exc, target) from None
            done.append(target)
    except BaseException:
        for restored in reversed(done):
            bak = saved[restored]
            with contextlib.suppress(OSError):
                if bak:
                    os.replace(bak, restored)
                elif bak == "":
                    os.unlink(restored)
        raise


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[str]:
    """Yield a temporary path in the target's directory; on success it is renamed over
    ``path`` (with the usual umask permissions), on failure removed — the old file stays.

    Raises :class:`InputError` (naming ``path``, not the temporary) when the target
    directory does not exist, the file cannot be created there or the disk is full.
    """
    with atomic_paths([path]) as tmps:
        yield tmps[0]


@contextlib.contextmanager
def atomic_paths(paths: Sequence[str | os.PathLike[str]]) -> Iterator[list[str]]:
    """Temporaries for every path of ``paths``, published together as one transaction
    once the block succeeds (see the module docstring); all removed if it fails.

    Parameters
    ----------
    paths : sequence of path-like
        Target files (distinct).

    Yields
    ------
    list of str
        One temporary path per target, in the same directory.

    Raises
    ------
    InputError
        A target directory is missing, a target is a directory, or a disk error (no space,
        I/O error) while writing or renaming; the message names the target. An
        :class:`InputError` raised in the block that names a temporary is re-raised naming
        its target.
    """
    targets = [_check_target(p) for p in paths]
    made: list[tuple[Path, str]] = []
    backups: list[str] = []
    try:
        for target in targets:
            with signals_deferred():
                made.append((target, _temporary_beside(target)))
        try:
            yield [tmp for _, tmp in made]
        except OSError as exc:
            if exc.errno not in DISK_ERRNOS:
                raise
            failed = next((t for t, tmp in made if exc.filename == tmp), made[-1][0])
            raise disk_error(exc, failed) from None
        except InputError as exc:
            named = next((t for t, tmp in made if exc.path == tmp), None)
            if named is None:
                raise
            raise InputError(exc.message, path=str(named), line=exc.line) from None
        with signals_deferred():
            _commit(made, backups)
    finally:
        with signals_deferred():
            for name in [tmp for _, tmp in made] + backups:
                with contextlib.suppress(OSError):
                    os.unlink(name)


__all__ = ["DISK_ERRNOS", "atomic_path", "atomic_paths", "disk_error", "signals_deferred"]
