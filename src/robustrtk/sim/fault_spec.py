"""Fault specifications for :mod:`robustrtk.sim.inject`: parsing of the ``--phase``,
``--code`` and ``--slip`` options and of their epoch selections.

See :mod:`robustrtk.sim.inject` for the meaning of each kind and of ``EPOCHS``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Literal

from robustrtk.core import InputError
from robustrtk.io.rinex_layout import SYSTEM_ORDER

__all__ = ["EpochSelection", "FaultSpec", "Kind", "parse_epochs", "parse_spec"]

#: Fault kinds.
Kind = Literal["phase", "code", "slip"]


@dataclass(frozen=True)
class EpochSelection:
    """Which epochs a fault hits.

    Attributes
    ----------
    indices : tuple of int
        Explicit 0-based epoch indices, sorted, distinct (empty for a random selection).
    n_random : int
        Number of epochs to draw (0 for an explicit list).
    """

    indices: tuple[int, ...] = ()
    n_random: int = 0


_RANGE = re.compile(r"(\d+)(?:-(\d+)(?:/(\d+))?)?")
_RANDOM = re.compile(r"random(\d+)")
_SAT = re.compile(r"([GRECJSI])\s*(\d{1,2})")


def parse_epochs(text: str) -> EpochSelection:
    """Parse an ``EPOCHS`` item: ``"100"``, ``"100-119"``, ``"5,9,30"``, ``"30-220/10"``,
    ``"random20"``.

    Raises
    ------
    InputError
        Anything else (message says what was expected).
    """
    t = text.strip()
    m = _RANDOM.fullmatch(t)
    if m:
        n = int(m.group(1))
        if n < 1:
            raise InputError(f"EPOCHS {text!r}: randomN needs N >= 1")
        return EpochSelection(n_random=n)
    out: set[int] = set()
    for item in t.split(","):
        m = _RANGE.fullmatch(item.strip())
        if not m:
            raise InputError(
                f"EPOCHS {text!r}: expected epoch indices like 100, 100-119, 5,9,30, 30-220/10 "
                f"or random20, found {item.strip()!r}"
            )
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) is not None else a
        step = int(m.group(3)) if m.group(3) is not None else 1
        if b < a:
            raise InputError(f"EPOCHS {text!r}: range {item.strip()!r} ends before it starts")
        if step < 1:
            raise InputError(f"EPOCHS {text!r}: step of {item.strip()!r} must be at least 1")
        out.update(range(a, b + 1, step))
    return EpochSelection(indices=tuple(sorted(out)))


@dataclass(frozen=True)
class FaultSpec:
    """One ``--phase``, ``--code`` or ``--slip`` option.

    Attributes
    ----------
    kind : {"phase", "code", "slip"}
    sat : str
        Satellite id, normalised (``"G05"``).
    obs_code : str
        RINEX observation code as in the file (``"L1C"``, ``"C1"``, ``"P2"``).
    size : float
        Metres (phase, code) or an integer number of cycles (slip).
    epochs : EpochSelection
        Epochs hit (slip: the single first epoch of the slip).
    text : str
        The option as given, for messages (``"--phase G05:L1C:0.15:100-119"``).
    """

    kind: Kind
    sat: str
    obs_code: str
    size: float
    epochs: EpochSelection
    text: str


def parse_spec(text: str, kind: Kind) -> FaultSpec:
    """Parse ``SAT:SIGNAL:SIZE_M:EPOCHS`` (phase, code) or ``SAT:SIGNAL:CYCLES:EPOCH`` (slip).

    The observation code is only checked for its shape here; whether the file has it is
    checked against the file's header by :func:`inject_bytes`.

    Raises
    ------
    InputError
        One line naming the option and the part that is wrong.
    """
    if kind not in ("phase", "code", "slip"):
        raise InputError(f"unknown fault kind {kind!r}; expected phase, code or slip")
    what = f"--{kind} {text!r}"
    form = "SAT:SIGNAL:CYCLES:EPOCH" if kind == "slip" else "SAT:SIGNAL:SIZE_M:EPOCHS"
    parts = text.split(":")
    if len(parts) != 4:
        raise InputError(f"{what}: expected {form} (4 fields separated by ':'), found {len(parts)}")
    sat_t, sig_t, size_t, ep_t = (p.strip() for p in parts)
    m = _SAT.fullmatch(sat_t.upper())
    if not m or int(m.group(2)) < 1:
        raise InputError(
            f"{what}: SAT: expected a satellite id like G05 (system letter from {SYSTEM_ORDER} and "
            f"a number), found {sat_t!r}"
        )
    sat = f"{m.group(1)}{int(m.group(2)):02d}"
    sig = sig_t.upper()
    if not re.fullmatch(r"[A-Z]\d[A-Z]?", sig):
        raise InputError(
            f"{what}: SIGNAL: expected a RINEX observation code like L1C (RINEX 3) or L1, C1, P2 "
            f"(RINEX 2), found {sig_t!r}"
        )
    want = "L" if kind in ("phase", "slip") else "CP"
    if sig[0] not in want:
        noun = "carrier-phase (L..)" if kind != "code" else "pseudorange (C.. or RINEX 2 P.)"
        raise InputError(f"{what}: SIGNAL {sig} is not a {noun} observation code")
    if kind == "slip":
        try:
            cycles = int(size_t)
        except ValueError:
            raise InputError(f"{what}: CYCLES: expected a non-zero integer, found {size_t!r}") from None
        if cycles == 0:
            raise InputError(f"{what}: CYCLES: expected a non-zero integer, found 0")
        if not re.fullmatch(r"\d+", ep_t):
            raise InputError(f"{what}: EPOCH: expected one 0-based epoch index, found {ep_t!r}")
        one = EpochSelection(indices=(int(ep_t),))
        return FaultSpec(kind, sat, sig, float(cycles), one, f"--{kind} {text}")
    try:
        size = float(size_t)
    except ValueError:
        raise InputError(f"{what}: SIZE_M: expected a number of metres, found {size_t!r}") from None
    if not math.isfinite(size) or size == 0.0:
        raise InputError(f"{what}: SIZE_M: expected a finite non-zero number of metres, found {size_t!r}")
    try:
        sel = parse_epochs(ep_t)
    except InputError as exc:
        raise InputError(f"{what}: {exc.message}") from None
    return FaultSpec(kind, sat, sig, size, sel, f"--{kind} {text}")
