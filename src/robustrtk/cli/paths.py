"""Output paths checked before any work: an output never overwrites an input or another output.

Paths are compared resolved (symbolic links and ``..`` followed) and, for files that
exist, by device and inode (:func:`os.path.samefile`), so a hard link or a second spelling
of the same file is caught too.
"""

from __future__ import annotations

import os
from collections.abc import Iterable

from robustrtk.errors import InputError

#: (option or argument label, path) pairs; ``None`` paths are skipped.
Labelled = Iterable[tuple[str, "str | os.PathLike[str] | None"]]


def _same(a: str, b: str) -> bool:
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet), or is unreadable
        return False


def check_output_paths(inputs: Labelled, outputs: Labelled) -> None:
    """Refuse outputs that are an input or another output (one line naming both).

    Parameters
    ----------
    inputs : iterable of (str, path or None)
        Input files with the option that names them (``"OBS"``, ``"--nav"``, ...).
    outputs : iterable of (str, path or None)
        Output files with their option (``"--out"``, ``"--diagnostics"``, ...).

    Raises
    ------
    InputError
        ``--out obs.csv is also the input OBS: refusing to overwrite an input``, or two
        outputs naming one file.
    """
    ins = [(label, os.fspath(p)) for label, p in inputs if p is not None]
    outs = [(label, os.fspath(p)) for label, p in outputs if p is not None]
    for k, (olabel, opath) in enumerate(outs):
        for ilabel, ipath in ins:
            if _same(opath, ipath):
                raise InputError(
                    f"{olabel} {opath} is also the input {ilabel} ({ipath}): refusing to overwrite an input"
                )
        for olabel2, opath2 in outs[:k]:
            if _same(opath, opath2):
                raise InputError(
                    f"{olabel} {opath} and {olabel2} {opath2} are the same file: give each output its own"
                )


__all__ = ["check_output_paths"]
