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
"""

from __future__ import annotations

import bz2
import csv
import gzip
import math
import re
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from decimal import ROUND_HALF_UP, Decimal, InvalidOperation
from os import PathLike
from pathlib import Path
from typing import Literal

import numpy as np
import numpy.typing as npt

from robustrtk.core import InputError
from robustrtk.gnss import wavelength_m
from robustrtk.io.atomic import atomic_path
from robustrtk.io.rinex_obs import (
    RINEX2_SIGNAL_MAP,
    SYSTEM_ORDER,
    _epochs_v2,
    _epochs_v3,
    _Header,
    _parse_header,
    read_rinex_bytes,
)

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

Kind = Literal["phase", "code", "slip"]
IntArray = npt.NDArray[np.int64]

#: Columns of the CSV log, in order.
LOG_COLUMNS = (
    "epoch_index", "time", "sat", "obs_code", "kind", "size_m", "size_native",
    "original", "new", "lli_original", "lli_new",
)  # fmt: skip

_FIELD_FMT = "{:14.3f}"
_MILLI = Decimal("0.001")

# --------------------------------------------------------------------------------------------
# specs


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


# --------------------------------------------------------------------------------------------
# results


@dataclass(frozen=True)
class Change:
    """One changed observation value (one row of the log).

    ``new - original == size_native`` exactly (as decimals; ``original`` and ``new`` are
    the field texts, stripped). ``size_m`` is the requested size for phase and code and
    ``cycles * wavelength`` for slips (NaN when the wavelength is unknown). ``line`` is
    the 1-based line of the plain RINEX text.
    """

    epoch_index: int
    time: str
    sat: str
    obs_code: str
    kind: Kind
    size_m: float
    size_native: str
    original: str
    new: str
    lli_original: str
    lli_new: str
    line: int

    def row(self) -> list[str]:
        """The CSV row (columns :data:`LOG_COLUMNS`)."""
        size_m = "" if math.isnan(self.size_m) else f"{self.size_m:.6f}"
        return [
            str(self.epoch_index), self.time, self.sat, self.obs_code, self.kind, size_m,
            self.size_native, self.original, self.new, self.lli_original, self.lli_new,
        ]  # fmt: skip


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
# the file's layout


class _Layout:
    """Where every satellite record of every kept epoch is, in the plain RINEX text."""

    def __init__(self, data: bytes, path: str):
        self.data = data
        self.path = path
        buf = np.frombuffer(data, dtype=np.uint8)
        nl = np.flatnonzero(buf == 10)
        self.starts = np.concatenate([[0], nl + 1]).astype(np.int64)
        self.ends = np.concatenate([nl, [buf.shape[0]]]).astype(np.int64)
        n_lines = int(self.starts.shape[0])
        if n_lines > 1 and self.starts[-1] == buf.shape[0]:
            n_lines -= 1
        head: list[str] = []
        for k in range(n_lines):
            text = self.text(k)
            head.append(text)
            label = text[60:].strip()
            if label == "END OF HEADER" or (k == 0 and label != "RINEX VERSION / TYPE"):
                break
        self.h: _Header = _parse_header(head, path)
        hb = self.h.n_lines
        self.v3 = self.h.version >= 3.0
        bufp = np.concatenate([buf, np.full(4, 32, np.uint8)])
        if self.v3:
            while n_lines > hb and not data[self.starts[n_lines - 1] : self.ends[n_lines - 1]].strip():
                n_lines -= 1
            ep = _epochs_v3(data, bufp, self.starts, self.ends, hb, n_lines, path)
            self.per_sat = 1
        else:
            if not self.h.obs_types2:
                raise InputError("missing '# / TYPES OF OBSERV' header record", path)
            ep = _epochs_v2(data, self.starts, self.ends, hb, n_lines, len(self.h.obs_types2), path)
            self.per_sat = max(1, -(-len(self.h.obs_types2) // 5))
        self.ep = ep
        self.n_epochs = len(ep.line)
        nsat = np.asarray(ep.nsat, dtype=np.int64)
        first = np.asarray(ep.first_rec, dtype=np.int64)
        self.ep_of: IntArray = np.repeat(np.arange(self.n_epochs, dtype=np.int64), nsat)
        offs = np.arange(int(nsat.sum()), dtype=np.int64) - np.repeat(np.cumsum(nsat) - nsat, nsat)
        self.rec_line: IntArray = np.repeat(first, nsat) + offs * self.per_sat
        if self.v3:
            st = self.starts[self.rec_line]
            ids = np.stack([bufp[st], bufp[st + 1], bufp[st + 2]], axis=1)
        else:
            txt = "".join("".join(s) for s in ep.sats).encode("ascii", "replace")
            ids = np.frombuffer(txt, np.uint8).reshape(-1, 3)
        sy = ids[:, 0].copy()
        sy[sy == 32] = ord("G")
        d1 = ids[:, 1].astype(np.int64)
        d2 = ids[:, 2].astype(np.int64)
        prn = np.where(d1 == 32, 0, d1 - 48) * 10 + (d2 - 48)
        self.key: IntArray = sy.astype(np.int64) * 1000 + prn

    def text(self, k: int) -> str:
        return self.data[self.starts[k] : self.ends[k]].decode("ascii", "replace")

    def obs_codes(self, system: str) -> list[str]:
        if self.v3:
            return list(self.h.obs_types.get(system, []))
        return list(self.h.obs_types2)

    def field_of(self, rec_line: int, j: int) -> tuple[int, int]:
        """(0-based line, 0-based column of the value) of observation ``j`` of a record."""
        if self.v3:
            return rec_line, 3 + 16 * j
        return rec_line + j // 5, 16 * (j % 5)

    def records(self, sat: str) -> tuple[IntArray, IntArray]:
        """(epoch indices, record lines) of ``sat``'s records, in epoch order."""
        k = ord(sat[0]) * 1000 + int(sat[1:])
        m = self.key == k
        return self.ep_of[m], self.rec_line[m]

    def time_iso(self, e: int) -> str:
        """Epoch ``e``'s time tag as written in the file, ISO 8601 (file's time system)."""
        t = self.text(self.ep.line[e])
        if self.v3:
            y, sec = int(t[2:6]), t[18:29]
            mo, d, hh, mi = int(t[7:9]), int(t[10:12]), int(t[13:15]), int(t[16:18])
        else:
            yy = int(t[1:3])
            y = yy + (1900 if yy >= 80 else 2000)
            mo, d, hh, mi, sec = int(t[4:6]), int(t[7:9]), int(t[10:12]), int(t[13:15]), t[15:26]
        whole, dot, frac = sec.strip().partition(".")
        return f"{y:04d}-{mo:02d}-{d:02d}T{hh:02d}:{mi:02d}:{int(whole or '0'):02d}{dot}{frac}"


# --------------------------------------------------------------------------------------------
# injection


def _signal_of(layout: _Layout, system: str, code: str) -> str | None:
    """RINEX 3 signal name (band + attribute) of an observation code, None if unknown."""
    if layout.v3:
        sig = code[1:]
        if system == "C" and layout.h.version < 3.03 and code[1] == "1" and code[2:3] in ("I", "Q", "X"):
            sig = "2" + code[2]
        return sig
    return RINEX2_SIGNAL_MAP.get(system, {}).get(code)


def _wavelength(layout: _Layout, spec: FaultSpec, required: bool) -> float:
    system = spec.sat[0]
    sig = _signal_of(layout, system, spec.obs_code)
    ch = layout.h.glo_channel.get(spec.sat) if system == "R" else None
    wl = wavelength_m(system, sig, ch) if sig else math.nan
    if required and not math.isfinite(wl):
        if system == "R" and sig and sig[0] in "12" and ch is None:
            why = (
                f"GLONASS {spec.sat} has no frequency channel in the header (record "
                "'GLONASS SLOT / FRQ #' missing or without this satellite)"
            )
        else:
            why = f"the wavelength of {spec.obs_code} on system {system} is unknown"
        raise InputError(f"{spec.text}: cannot convert metres to cycles: {why}", layout.path)
    return wl


def _pick_epochs(
    spec: FaultSpec, layout: _Layout, seed: int, occurrence: int
) -> tuple[list[tuple[int, int]], dict[int, int]]:
    """Selected ``(epoch, record line)`` pairs and the map of the satellite's epochs with a
    value of the observation (epoch -> record line)."""
    j = layout.obs_codes(spec.sat[0]).index(spec.obs_code)
    eps, lines = layout.records(spec.sat)
    avail: dict[int, int] = {}
    for e, rl in zip(eps.tolist(), lines.tolist(), strict=True):
        li, col = layout.field_of(rl, j)
        s, t = int(layout.starts[li]), int(layout.ends[li])
        if layout.data[s + col : min(s + col + 14, t)].strip():
            avail[e] = rl
    sel = spec.epochs
    if sel.n_random:
        if len(avail) < sel.n_random:
            raise InputError(
                f"{spec.text}: {spec.sat} has {spec.obs_code} at {len(avail)} epochs only, "
                f"cannot draw {sel.n_random}",
                layout.path,
            )
        key = zlib.crc32(f"{spec.kind}:{spec.text}".encode())
        rng = np.random.default_rng([seed, key, occurrence])
        cand = np.array(sorted(avail), dtype=np.int64)
        chosen = sorted(rng.choice(cand, size=sel.n_random, replace=False).tolist())
        return [(e, avail[e]) for e in chosen], avail
    out = []
    for e in sel.indices:
        if e >= layout.n_epochs:
            raise InputError(
                f"{spec.text}: epoch {e} out of range: the file has {layout.n_epochs} epochs "
                f"(0-{layout.n_epochs - 1})",
                layout.path,
            )
        if e not in avail:
            raise InputError(
                f"{spec.text}: epoch {e} ({layout.time_iso(e)}) has no {spec.obs_code} value for {spec.sat}",
                layout.path,
                layout.ep.line[e] + 1,
            )
        out.append((e, avail[e]))
    return out, avail


class _Editor:
    """Changed lines of the text (0-based line index -> bytes)."""

    def __init__(self, layout: _Layout):
        self.layout = layout
        self.lines: dict[int, bytearray] = {}

    def line(self, li: int) -> bytearray:
        if li not in self.lines:
            lay = self.layout
            raw = lay.data[lay.starts[li] : lay.ends[li]]
            self.lines[li] = bytearray(raw)
        return self.lines[li]

    def apply(
        self, li: int, col: int, delta_milli: int, set_lli: bool, what: str
    ) -> tuple[str, str, str, str]:
        """Add ``delta_milli`` thousandths to the F14.3 field at (li, col); returns
        (original, new, lli_original, lli_new) texts."""
        body = self.line(li)
        field = bytes(body[col : col + 14]).decode("ascii", "replace")
        lli_old = bytes(body[col + 14 : col + 15]).decode("ascii", "replace").strip()
        try:
            orig = Decimal(field.strip())
            if not orig.is_finite():
                raise InvalidOperation
        except InvalidOperation:
            raise InputError(
                f"{what}: columns {col + 1}-{col + 14}: expected a number in F14.3, found {field.strip()!r}",
                self.layout.path,
                li + 1,
            ) from None
        new = (orig + Decimal(delta_milli).scaleb(-3)).quantize(_MILLI)
        text = _FIELD_FMT.format(new)
        if len(text) > 14:
            raise InputError(
                f"{what}: new value {text.strip()} does not fit the F14.3 field (original "
                f"{field.strip()}, columns {col + 1}-{col + 14})",
                self.layout.path,
                li + 1,
            )
        need = col + (15 if set_lli else 14)
        if len(body) < need:
            body.extend(b" " * (need - len(body)))
        body[col : col + 14] = text.encode("ascii")
        lli_new = lli_old
        if set_lli:
            old = int(lli_old) if lli_old.isdigit() else 0
            lli_new = str(old | 1)
            body[col + 14 : col + 15] = lli_new.encode("ascii")
        return field.strip(), text.strip(), lli_old, lli_new

    def output(self) -> bytes:
        lay = self.layout
        parts: list[bytes] = []
        pos = 0
        for li in sorted(self.lines):
            s, t = int(lay.starts[li]), int(lay.ends[li])
            parts.append(lay.data[pos:s])
            parts.append(bytes(self.lines[li]))
            pos = t
        parts.append(lay.data[pos:])
        return b"".join(parts)


def _milli(x: float) -> int:
    """Round to an integer number of thousandths (half away from zero)."""
    return int(Decimal(repr(x)).scaleb(3).quantize(Decimal(1), rounding=ROUND_HALF_UP))


def inject_bytes(
    data: bytes,
    specs: Sequence[FaultSpec],
    *,
    seed: int = 0,
    slip_lli: bool = False,
    path: str = "<rinex>",
) -> tuple[bytes, list[Change], dict[str, tuple[int, ...]]]:
    """Apply ``specs`` to plain RINEX observation text.

    Parameters
    ----------
    data : bytes
        Plain RINEX 2.10/2.11 or 3.0x observation text.
    specs : sequence of FaultSpec
        Applied in order; changes to the same value add up.
    seed : int
        Seed of the ``randomN`` selections. Each spec draws from its own generator seeded
        by ``(seed, spec text, occurrence)``, so a selection does not depend on the other
        specs.
    slip_lli : bool
        Set LLI bit 0 at the first epoch of each slip.
    path : str
        File name for messages.

    Returns
    -------
    data : bytes
        The edited text (only the edited fields differ).
    changes : list of Change
        One per changed value, in the order applied.
    epochs : dict
        ``spec.text`` -> epoch indices it hit (a slip: its first epoch).

    Raises
    ------
    InputError
        Malformed file, observation code or satellite the file lacks, epoch out of range or
        without the observation (explicit selections), unknown wavelength, overflow of F14.3.
    """
    if not specs:
        raise InputError("nothing to inject: give at least one --phase, --code or --slip")
    layout = _Layout(data, path)
    editor = _Editor(layout)
    changes: list[Change] = []
    epochs: dict[str, tuple[int, ...]] = {}
    seen: dict[str, int] = {}
    present = set(np.unique(layout.key).tolist())
    for spec in specs:
        system = spec.sat[0]
        codes = layout.obs_codes(system)
        if spec.obs_code not in codes:
            where = f"'SYS / # / OBS TYPES' for {system}" if layout.v3 else "'# / TYPES OF OBSERV'"
            has = " ".join(c for c in codes if c[0] == spec.obs_code[0]) or "none"
            raise InputError(
                f"{spec.text}: observation {spec.obs_code} is not in the header's {where} "
                f"(this kind there: {has})",
                path,
            )
        if ord(system) * 1000 + int(spec.sat[1:]) not in present:
            raise InputError(f"{spec.text}: satellite {spec.sat} has no observations in the file", path)
        occ = seen.get(spec.text, 0)
        seen[spec.text] = occ + 1
        picked, avail = _pick_epochs(spec, layout, seed, occ)
        j = codes.index(spec.obs_code)
        fac = layout.h.scale.get(system, {})
        scale = fac.get(spec.obs_code, fac.get("*", 1.0)) if layout.v3 else 1.0
        if spec.kind == "slip":
            wl = _wavelength(layout, spec, required=False)
            e0 = picked[0][0]
            hits = [(e, rl) for e, rl in sorted(avail.items()) if e >= e0]
            delta_phys = spec.size
            size_m = spec.size * wl
        else:
            hits = picked
            if spec.kind == "phase":
                wl = _wavelength(layout, spec, required=True)
                delta_phys = spec.size / wl
            else:
                delta_phys = spec.size
            size_m = spec.size
        dm = _milli(delta_phys * scale)
        if dm == 0:
            raise InputError(f"{spec.text}: size rounds to 0 at the format's 0.001 resolution", path)
        size_native = _FIELD_FMT.format(Decimal(dm).scaleb(-3) / Decimal(repr(scale))).strip()
        if spec.kind == "slip" and scale == 1.0:
            size_native = str(int(spec.size))
        epochs[spec.text] = tuple(e for e, _ in picked)
        for e, rl in hits:
            li, col = layout.field_of(rl, j)
            set_lli = spec.kind == "slip" and slip_lli and e == hits[0][0]
            what = f"{spec.text}: epoch {e} {spec.sat} {spec.obs_code}"
            orig, new, lo, ln = editor.apply(li, col, dm, set_lli, what)
            changes.append(
                Change(e, layout.time_iso(e), spec.sat, spec.obs_code, spec.kind, size_m,
                       size_native, orig, new, lo, ln, li + 1)
            )  # fmt: skip
    return editor.output(), changes, epochs


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


def _write_csv(changes: Sequence[Change], path: str) -> None:
    with open(path, "w", newline="", encoding="ascii") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(LOG_COLUMNS)
        for c in changes:
            w.writerow(c.row())


def write_log(changes: Sequence[Change], path: str | PathLike[str]) -> None:
    """Write the CSV log (header :data:`LOG_COLUMNS`, one row per change), atomically."""
    with atomic_path(path) as tmp:
        _write_csv(changes, tmp)


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
            _write_csv(changes, tmp_log)
    return InjectResult(dst, log, tuple(changes), epochs, in_kind, out_kind)
