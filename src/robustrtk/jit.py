"""When the cooperative UKF's numba step pays for itself: the choice between its numpy and
compiled paths (the only numba kernel left, :mod:`robustrtk.estimation.coop_kernels`).

The compiled step runs many times faster than the numpy one, but numba's first use in a
process costs about a second and about 125 MiB of memory, so a short run finishes sooner on
the numpy path. The choice is a rent-or-buy problem (algorithms.md §27):

* every step on the numpy path *charges* an estimate of its own cost (µs; deterministic,
  never a clock, so a run's output does not depend on the machine's load);
* a run that knows its length (:func:`begin_run`) projects its numpy cost from the epochs
  done (:func:`end_epoch`) and switches to the kernel as soon as the projected rest exceeds
  the kernel's fixed cost :data:`FIXED_COST_US`;
* without a known length, the switch comes when the charges reach the fixed cost.

``ROBUSTRTK_JIT`` selects ``auto`` (default), ``on`` (kernel from the first call) or ``off``
(numpy only); ``ROBUSTRTK_NO_JIT=1`` is ``off``. Both paths give the same numbers to
rounding. This module imports only the standard library.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Literal

from robustrtk.errors import InputError

Mode = Literal["auto", "on", "off"]

#: The kernel's fixed cost, in the units of the charges (estimated numpy-path µs).
FIXED_COST_US = 1.0e6

#: Estimated numpy cost of one cooperative UKF step that the compiled step would take (µs).
COOP_STEP_US = 200.0

_MODES: dict[str, Mode] = {"auto": "auto", "on": "on", "1": "on", "off": "off", "0": "off"}


def mode() -> Mode:
    """The policy in force: :func:`use`'s, else the environment's (``ROBUSTRTK_JIT``,
    ``ROBUSTRTK_NO_JIT``), read here by :func:`refresh`.

    Raises
    ------
    InputError
        ``ROBUSTRTK_JIT`` is set to something other than auto, on, off, 1 or 0.
    """
    if _OVERRIDE:
        return _OVERRIDE[-1]
    return refresh()


def refresh() -> Mode:
    """Read the environment now and keep its mode for :func:`compiled` until the next call
    of this function, of :func:`mode` or of :func:`begin_run`.

    Raises
    ------
    InputError
        ``ROBUSTRTK_JIT`` is set to something other than auto, on, off, 1 or 0.
    """
    md: Mode
    if os.environ.get("ROBUSTRTK_NO_JIT", "") not in ("", "0"):
        md = "off"
    else:
        raw = os.environ.get("ROBUSTRTK_JIT", "auto").strip().lower() or "auto"
        if raw not in _MODES:
            raise InputError(f"environment variable ROBUSTRTK_JIT={raw!r}: expected auto, on or off")
        md = _MODES[raw]
    _ENV_MODE[:] = [md]
    return md


def current() -> Mode:
    """The policy in force without reading the environment again (read now if never)."""
    if _OVERRIDE:
        return _OVERRIDE[-1]
    return _ENV_MODE[0] if _ENV_MODE else refresh()


@dataclass
class Meter:
    """The numpy-path cost charged in one run (µs) and the epochs it covers."""

    spent_us: float = 0.0
    epochs_done: int = 0
    epochs_total: int | None = None
    switched: bool = False


_METER = Meter()
_OVERRIDE: list[Mode] = []
_ENV_MODE: list[Mode] = []  # the environment's mode as last read by refresh()


def begin_run(n_epochs: int | None) -> None:
    """Start a run of ``n_epochs`` epochs (None: unknown): charges and the switch reset, the
    environment is read afresh."""
    refresh()
    _METER.spent_us = 0.0
    _METER.epochs_done = 0
    _METER.epochs_total = n_epochs if n_epochs is not None and n_epochs > 0 else None
    _METER.switched = False


def charge(cost_us: float) -> None:
    """Record ``cost_us`` of work done on the numpy path that the kernel would have done."""
    if _METER.switched:
        return
    _METER.spent_us += cost_us
    if _METER.epochs_total is None and _METER.spent_us >= FIXED_COST_US:
        _METER.switched = True


def end_epoch() -> None:
    """One epoch of the run is done: switch when the projected numpy cost of the rest,
    ``spent / done · (total − done)``, exceeds :data:`FIXED_COST_US`."""
    m = _METER
    m.epochs_done += 1
    if m.switched or m.epochs_total is None or m.spent_us <= 0.0:
        return
    rest = max(m.epochs_total - m.epochs_done, 0)
    if m.spent_us / m.epochs_done * rest > FIXED_COST_US:
        m.switched = True


def compiled() -> bool:
    """True when the next cooperative UKF step should take the compiled path."""
    md = current()
    if md == "on":
        return True
    if md == "off":
        return False
    return _METER.switched


@contextmanager
def use(md: Mode) -> Iterator[None]:
    """Run a block with the policy ``md`` whatever the environment says (tests, benches)."""
    if md not in ("auto", "on", "off"):
        raise ValueError(f"mode {md!r}: expected auto, on or off")
    _OVERRIDE.append(md)
    try:
        yield
    finally:
        _OVERRIDE.pop()


__all__ = [
    "COOP_STEP_US",
    "FIXED_COST_US",
    "Meter",
    "Mode",
    "begin_run",
    "charge",
    "compiled",
    "current",
    "end_epoch",
    "mode",
    "refresh",
    "use",
]
