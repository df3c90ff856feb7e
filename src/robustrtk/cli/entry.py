"""Process entry point of the ``robustrtk`` command: signals become clean exits.

Ctrl-C (SIGINT) prints ``interrupted`` and exits with status 130, SIGTERM prints
``terminated`` and exits with status 143 — never a traceback, whether the signal arrives
while the library is still being imported, during a solve or during the final write. The
signal is raised as an exception in the main thread, so every ``with`` block on the way out
runs: output temporaries are removed and the previous outputs stay as they were.

This module imports nothing heavy before the handlers are installed.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Sequence
from types import FrameType

from robustrtk.blas import BLAS_THREAD_VARS, single_threaded_blas

#: Exit status after SIGINT (128 + 2) and SIGTERM (128 + 15).
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 143


class Terminated(BaseException):
    """Raised in the main thread when the process receives SIGTERM."""


#: The signal received, if any: an exception raised inside an extension module's
#: initialisation comes back as another type (``ImportError``), so the handler records it.
_received: list[int] = []


def _on_sigterm(signum: int, frame: FrameType | None) -> None:
    _received.append(signum)
    raise Terminated(signum)


def _on_sigint(signum: int, frame: FrameType | None) -> None:
    _received.append(signum)
    raise KeyboardInterrupt


def install_signal_handlers() -> None:
    """SIGTERM raises :class:`Terminated`; SIGINT raises :class:`KeyboardInterrupt`
    (also when Python's default handler was replaced)."""
    signal.signal(signal.SIGTERM, _on_sigterm)
    if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        signal.signal(signal.SIGINT, _on_sigint)


def _interrupted(status: int, word: str) -> int:
    # a second signal while reporting the first must not produce a traceback either
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    try:
        sys.stderr.write(f"\n{word}\n")
        sys.stderr.flush()
    except (OSError, ValueError):
        pass
    return status


def run(argv: Sequence[str] | None = None) -> int:
    """Run the command line ``argv`` (default ``sys.argv[1:]``) and return its exit status.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after the program name.

    Returns
    -------
    int
        0 on success, 2 for bad input, 130 after SIGINT, 143 after SIGTERM, or the status
        the command chose.
    """
    try:
        install_signal_handlers()
        import click

        from robustrtk.cli.main import main

        try:
            args = list(argv) if argv is not None else None
            rv = main.main(args=args, prog_name="robustrtk", standalone_mode=False)
        except click.exceptions.Abort as exc:
            if isinstance(exc.__context__, KeyboardInterrupt):
                raise KeyboardInterrupt from None
            return _interrupted(1, "aborted")
        except click.ClickException as exc:
            exc.show()
            return exc.exit_code
        except click.exceptions.Exit as exc:
            return int(exc.exit_code)
        return rv if isinstance(rv, int) else 0
    except KeyboardInterrupt:
        return _interrupted(EXIT_INTERRUPTED, "interrupted")
    except Terminated:
        return _interrupted(EXIT_TERMINATED, "terminated")
    except SystemExit as exc:
        code = exc.code
        if code is None:
            return 0
        if isinstance(code, int):
            return code
        sys.stderr.write(f"{code}\n")
        return 1
    except BrokenPipeError:
        return 1
    except Exception:
        # a signal that surfaced as another exception (raised inside a C extension, say)
        if _received:
            if _received[0] == signal.SIGTERM:
                return _interrupted(EXIT_TERMINATED, "terminated")
            return _interrupted(EXIT_INTERRUPTED, "interrupted")
        raise


def main() -> None:
    """Console-script entry point: :func:`run` then exit with its status."""
    single_threaded_blas()
    status = run()
    if status in (EXIT_INTERRUPTED, EXIT_TERMINATED):
        # an interrupt seen inside some extension module's code marks the interpreter, which
        # would then kill itself with SIGINT at exit instead of returning this status
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(status)
    sys.exit(status)


__all__ = [
    "BLAS_THREAD_VARS",
    "EXIT_INTERRUPTED",
    "EXIT_TERMINATED",
    "Terminated",
    "install_signal_handlers",
    "main",
    "run",
    "single_threaded_blas",
]
