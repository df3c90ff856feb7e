"""One-line errors for every command: expected failures print ``error: ...`` on stderr and
exit with status 2, never a traceback."""

from __future__ import annotations

import contextlib
import functools
import sys
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

import click

from robustrtk.errors import InputError
from robustrtk.io.atomic import DISK_ERRNOS

F = TypeVar("F", bound=Callable[..., Any])


#: Longest error message printed (characters); longer ones are cut with an ellipsis.
MAX_MESSAGE = 300


def one_line(text: str, limit: int = MAX_MESSAGE) -> str:
    """``text`` on one line: its non-blank lines joined by ``"; "``, at most ``limit``
    characters (a longer message ends with ``"…"``)."""
    line = "; ".join(ln.strip() for ln in text.splitlines() if ln.strip())
    return line if len(line) <= limit else line[: limit - 1] + "…"


def one_line_errors(fn: F) -> F:
    """Turn expected failures (bad input, missing, unreadable files) into one-line errors
    with exit status 2."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kw: Any) -> Any:
        try:
            return fn(*args, **kw)
        except InputError as exc:
            click.echo(f"error: {one_line(str(exc))}", err=True)
            sys.exit(2)
        except FileNotFoundError as exc:
            click.echo(f"error: {exc.filename}: file not found", err=True)
            sys.exit(2)
        except IsADirectoryError as exc:
            click.echo(f"error: {exc.filename}: is a directory, expected a file", err=True)
            sys.exit(2)
        except PermissionError as exc:
            click.echo(f"error: {exc.filename}: permission denied", err=True)
            sys.exit(2)
        except OSError as exc:
            if exc.errno not in DISK_ERRNOS:
                raise
            where = f"{exc.filename}: " if exc.filename else ""
            click.echo(one_line(f"error: {where}{exc.strerror or exc}"), err=True)
            sys.exit(2)

    return wrapper  # type: ignore[return-value]


@contextlib.contextmanager
def bad_input_exits() -> Iterator[None]:
    """Within the block, an :class:`InputError` or any ``OSError`` (with its file name when
    known) becomes a one-line error with exit status 2."""
    try:
        yield
    except InputError as exc:
        click.echo(f"error: {one_line(str(exc))}", err=True)
        sys.exit(2)
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        click.echo(f"error: {where}{exc.strerror or exc}", err=True)
        sys.exit(2)


__all__ = ["MAX_MESSAGE", "bad_input_exits", "one_line", "one_line_errors"]
