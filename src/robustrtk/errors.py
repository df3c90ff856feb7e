"""The error type of bad user input, importable without numpy (the CLI's start-up path).

:class:`InputError` is re-exported by :mod:`robustrtk.core`; both names are the same class.
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input: a file, field or option that does not match what was expected.

    The message is one line naming the file, the line or field, and what was expected.
    The CLI prints ``str(error)`` and exits with status 2; no traceback.

    Parameters
    ----------
    message : str
        What was wrong and what was expected.
    path : str or None
        The file concerned.
    line : int or None
        1-based line number within ``path``.
    """

    def __init__(self, message: str, path: str | None = None, line: int | None = None):
        self.path = path
        self.line = line
        self.message = message
        where = ""
        if path is not None:
            where = f"{path}"
            if line is not None:
                where += f":{line}"
            where += ": "
        super().__init__(f"{where}{message}")


__all__ = ["InputError"]
