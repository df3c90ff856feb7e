"""When the compiled kernels pay for themselves: the choice between the pure and numba paths.

The numba kernels (LAMBDA, the DD filter update) run 30–100× faster
than their pure references, but the first use in a process costs about a second (numba's
import, its CPU target and the cached machine code), and about 125 MiB of memory. A short
file therefore finishes sooner, and in less memory, on the pure path. The choice is a
rent-or-buy problem (algorithms.md §27):

* every call on the pure path *charges* an estimate of its own cost (µs, from the problem's
  size: deterministic, never a clock, so a run's output does not depend on the machine's load);
* a run that knows its length (:func:`begin_run`) projects its pure cost from the epochs done
  (:func:`end_epoch`) and switches to the kernels as soon as the projected rest exceeds the
  kernels' fixed cost :data:`FIXED_COST_US`;
* without a known length (a library call outside a run), the switch comes when the charges
  reach the fixed cost — the break-even rule, never more than twice the better choice.

``ROBUSTRTK_JIT`` selects ``auto`` (default), ``on`` (kernels from the first call) or ``off``
(pure only); ``ROBUSTRTK_NO_JIT=1`` is ``off``. Pure and compiled paths give the same numbers
to rounding; a switch changes nothing else. This module imports only the standard library.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Literal

from robustrtk.errors import InputError

Mode = Literal["auto", "on", "off"]

#: The kernels' fixed cost, in the units of the charges: estimated pure-path µs on the
#: machine the constants were measured on (bench/bench_jit.py prints both sides).
FIXED_COST_US = 1.0e6

#: Estimated pure cost of one LAMBDA reduction of ``n`` ambiguities: ``REDUCE_US_N2 · n²``.
REDUCE_US_N2 = 9.0
#: Estimated pure cost of one DD filter update that the compiled update would take (µs).
UPDATE_US = 200.0

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
    """Read the environment now, whatever :func:`use` says, and keep its mode for
    :func:`current` and :func:`compiled` (a kernel call does not read it) until the next
    call of this function, of :func:`mode` or of :func:`begin_run`.

    Returns
    -------
    Mode
        The environment's mode (not :func:`use`'s).

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
    _READS[0] += 1
    return md


def current() -> Mode:
    """The policy in force, without reading the environment again: :func:`use`'s, else the
    environment's as last read by :func:`refresh` (read now if never).

    This is what a kernel look-up asks (a fraction of a microsecond, where reading the
    environment costs microseconds): a change of ``ROBUSTRTK_JIT`` takes effect at the
    next run (:func:`begin_run`), :func:`refresh` or :func:`mode` call.
    """
    if _OVERRIDE:
        return _OVERRIDE[-1]
    return _ENV_MODE[0] if _ENV_MODE else refresh()


def reads() -> int:
    """How many times :func:`refresh` has read the environment. Another setting taken from the
    environment (the LAMBDA backend) may be kept while this count is unchanged, so that it
    is read again exactly when the policy is."""
    return _READS[0]


@dataclass
class Meter:
    """The pure-path cost charged in one run (µs) and the epochs it covers."""

    spent_us: float = 0.0
    epochs_done: int = 0
    epochs_total: int | None = None
    switched: bool = False


_METER = Meter()
_OVERRIDE: list[Mode] = []
_ENV_MODE: list[Mode] = []  # the environment's mode as last read by refresh()
_READS: list[int] = [0]  # how many times refresh() has read the environment


def begin_run(n_epochs: int | None) -> None:
    """Start a run of ``n_epochs`` epochs (None: unknown): charges and the switch reset.

    Each run decides afresh, so its output is the same in a fresh process and in a worker
    that has run other jobs before it.
    """
    refresh()  # the environment is read afresh for every run
    _METER.spent_us = 0.0
    _METER.epochs_done = 0
    _METER.epochs_total = n_epochs if n_epochs is not None and n_epochs > 0 else None
    _METER.switched = False


def charge(cost_us: float) -> None:
    """Record ``cost_us`` of work done on the pure path that a kernel would have done."""
    if _METER.switched:
        return
    _METER.spent_us += cost_us
    if _METER.epochs_total is None and _METER.spent_us >= FIXED_COST_US:
        _METER.switched = True


def end_epoch() -> None:
    """One epoch of the run is done: switch when the projected pure cost of the rest,
    ``spent / done · (total − done)``, exceeds :data:`FIXED_COST_US`."""
    m = _METER
    m.epochs_done += 1
    if m.switched or m.epochs_total is None or m.spent_us <= 0.0:
        return
    rest = max(m.epochs_total - m.epochs_done, 0)
    if m.spent_us / m.epochs_done * rest > FIXED_COST_US:
        m.switched = True


def compiled() -> bool:
    """True when the next kernel call should take the compiled path."""
    md = current()
    if md == "on":
        return True
    if md == "off":
        return False
    return _METER.switched


def meter() -> Meter:
    """A copy of the current run's meter (for diagnostics and tests)."""
    return Meter(_METER.spent_us, _METER.epochs_done, _METER.epochs_total, _METER.switched)


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
    "FIXED_COST_US",
    "REDUCE_US_N2",
    "UPDATE_US",
    "Meter",
    "Mode",
    "begin_run",
    "charge",
    "compiled",
    "current",
    "end_epoch",
    "meter",
    "mode",
    "reads",
    "refresh",
    "use",
]
