"""Fault injection into RINEX observation files: silent gross errors and cycle slips.

A copy of a RINEX 2.10/2.11 or 3.0x observation file is written with chosen observation
values changed *in place*: only the 14 value columns (``F14.3``) of the edited fields
differ, every other byte of the plain RINEX text is kept (header, epoch lines, other
fields, loss-of-lock and signal-strength digits, line endings). Each change is listed in
a CSV log so a test or an evaluation knows exactly what was done.

Fault kinds
-----------
``phase``  ``SAT:SIGNAL:SIZE_M:EPOCHS``
    Adds ``SIZE_M`` metres to the carrier phase of ``SIGNAL`` (a phase observation code,
    ``L1C`` in RINEX 3, ``L1`` in RINEX 2) at the selected epochs, converted to cycles with
    the signal's wavelength: ``dphi_cyc = SIZE_M / lambda_m``, ``lambda_m = c / f``
    (:func:`robustrtk.gnss.wavelength_m`; GLONASS FDMA bands need the satellite's channel
    from the header's ``GLONASS SLOT / FRQ #`` record). Silent: LLI and SSI untouched.
``code``   ``SAT:SIGNAL:SIZE_M:EPOCHS``
    Adds ``SIZE_M`` metres to the pseudorange ``SIGNAL`` (``C1C``, ``C1``, ``P2``, ...).
    Silent.
``slip``   ``SAT:SIGNAL:CYCLES:EPOCH``
    Adds an integer number of cycles to the phase from ``EPOCH`` to the end of the file (a
    real slip persists). LLI untouched unless ``slip_lli`` is set, then bit 0 (loss of
    lock) is set at ``EPOCH`` only.

``EPOCHS`` are 0-based indices of the file's observation epochs (event flags 0 and 1, the
epochs :func:`robustrtk.io.rinex_obs.read_rinex_obs` returns, in the same order):
``"100"``, ``"100-119"`` (inclusive), ``"5,9,30"``, ``"30-220/10"`` (start-stop/step;
items may be mixed with commas) or ``"random20"`` (20 distinct epochs among those where
the satellite has a value of that observation, drawn with a seeded generator).

Arithmetic is exact in the file's units: the original field is read as a decimal number,
the change is rounded to 0.001 (the format's resolution), the sum is written as ``F14.3``.
So ``new - original`` equals the logged ``size_native`` exactly (phase: cycles; code:
metres; slip: cycles), and differs from the requested ``SIZE_M`` by at most half a
thousandth of a cycle or a millimetre. ``SYS / SCALE FACTOR`` (RINEX 3) is honoured.
Several faults on the same value add up, each logged with the value before and after it.

Modules
-------
:mod:`robustrtk.sim.fault_spec` parses the options, :mod:`robustrtk.sim.rinex_edit`
rewrites the plain RINEX text (:func:`inject_bytes`), :mod:`robustrtk.sim.inject_log` writes
the CSV log; this module reads and writes the files (compression from content on input,
from the name on output). All public names are importable from here.
"""

from __future__ import annotations

import bz2
import gzip
import re
from collections.abc import Sequence
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

from robustrtk.core import InputError
from robustrtk.io.atomic import atomic_path
from robustrtk.io.rinex_file import read_rinex_bytes
from robustrtk.sim.fault_spec import EpochSelection, FaultSpec, parse_epochs, parse_spec
from robustrtk.sim.inject_log import LOG_COLUMNS, Change, write_changes_csv, write_log
from robustrtk.sim.rinex_edit import inject_bytes

__all__ = [
    "Change",
    "EpochSelection",
    "FaultSpec",
    "InjectResult",
    "LOG_COLUMNS",
    "inject_bytes",
    "inject_file",
    "output_compression",
    "parse_epochs",
    "parse_spec",
    "write_log",
]


@dataclass(frozen=True)
class InjectResult:
    """What :func:`inject_file` did: output and log paths, the changes, selected epochs
    per spec (``spec.text -> epoch indices``), the input's compression and the output's."""

    out_path: str
    log_path: str
    changes: tuple[Change, ...]
    epochs: dict[str, tuple[int, ...]]
    input_compression: str
    output_compression: str


# --------------------------------------------------------------------------------------------
# files

_HATANAKA_NAME = re.compile(r".*\.(crx|\d\dd)$", re.IGNORECASE)


def output_compression(path: str | PathLike[str]) -> str:
    """Output kind from the name: ``.crx``/``.yyd`` -> ``"hatanaka"``, plus ``.gz`` ->
    ``"hatanaka+gzip"``; ``.gz`` -> ``"gzip"``; ``.bz2`` -> ``"bzip2"``; else ``"none"``.

    Raises
    ------
    InputError
        ``.Z`` and ``.zip`` outputs (not written).
    """
    name = Path(path).name
    low = name.lower()
    outer = "none"
    if low.endswith(".gz"):
        outer, name = "gzip", name[:-3]
    elif low.endswith(".bz2"):
        outer, name = "bzip2", name[:-4]
    elif low.endswith(".z") or low.endswith(".zip"):
        raise InputError("--out: .Z and .zip output are not supported; use .gz, .bz2 or plain", str(path))
    if _HATANAKA_NAME.fullmatch(name):
        return "hatanaka" if outer == "none" else f"hatanaka+{outer}"
    return outer


def _encode(text: bytes, kind: str, path: str) -> bytes:
    out = text
    if kind.startswith("hatanaka"):
        import hatanaka

        try:
            out = hatanaka.compress(text, compression="none")
        except Exception as exc:  # the converter's own failure: report it on one line
            msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise InputError(f"Hatanaka compression failed: {msg}", path) from None
    if kind.endswith("gzip"):
        out = gzip.compress(out, compresslevel=6, mtime=0)
    elif kind.endswith("bzip2"):
        out = bz2.compress(out)
    return out


def _uses_crlf(path: str) -> bool:
    """Whether an uncompressed file ends its lines with CR LF."""
    with open(path, "rb") as fh:
        return b"\r\n" in fh.read(4096)


def inject_file(
    obs_path: str | PathLike[str],
    out_path: str | PathLike[str],
    specs: Sequence[FaultSpec],
    *,
    seed: int = 0,
    slip_lli: bool = False,
    log_path: str | PathLike[str] | None = None,
) -> InjectResult:
    """Read ``obs_path`` (plain, gzip, bzip2 or Hatanaka), inject ``specs``, write
    ``out_path`` (compression from its name, :func:`output_compression`) and the CSV log
    (default ``out_path + ".inject.csv"``). Both files are written through temporary files
    and renamed only when both are complete.

    Raises
    ------
    InputError
        See :func:`inject_bytes`; also output equal to the input, unsupported output
        compression, missing output directory.
    """
    src, dst = str(obs_path), str(out_path)
    log = str(log_path) if log_path is not None else dst + ".inject.csv"
    if Path(dst).resolve() == Path(src).resolve():
        raise InputError("--out must differ from the input file (the input is never overwritten)", dst)
    if Path(log).resolve() in (Path(dst).resolve(), Path(src).resolve()):
        raise InputError("--log must differ from the input and output files", log)
    out_kind = output_compression(dst)
    data, in_kind = read_rinex_bytes(src)  # line ends are LF here
    new, changes, epochs = inject_bytes(data, specs, seed=seed, slip_lli=slip_lli, path=src)
    if out_kind == "none" and in_kind == "none" and _uses_crlf(src):
        new = new.replace(b"\n", b"\r\n")  # a plain CR LF file stays byte-identical
    payload = _encode(new, out_kind, dst)
    with atomic_path(dst) as tmp_out:
        with atomic_path(log) as tmp_log:
            Path(tmp_out).write_bytes(payload)
            write_changes_csv(changes, tmp_log)
    return InjectResult(dst, log, tuple(changes), epochs, in_kind, out_kind)
