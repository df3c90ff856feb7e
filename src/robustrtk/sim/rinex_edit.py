"""Rewriting observation fields of a plain RINEX 2/3 observation text in place.

Only the 14 value columns (``F14.3``) of the edited fields change (and, for slips with
``slip_lli``, the LLI digit); every other byte is kept. See :mod:`robustrtk.sim.inject` for
the fault kinds and the exact arithmetic.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Sequence
from decimal import ROUND_HALF_UP, Decimal, InvalidOperation

import numpy as np
import numpy.typing as npt

from robustrtk.core import InputError
from robustrtk.gnss import wavelength_m
from robustrtk.io.rinex_layout import (
    LLI_OFFSET,
    OBS_VALUE_WIDTH,
    RINEX2_SIGNAL_MAP,
    field_position,
    rinex3_signal,
)
from robustrtk.io.rinex_text import (
    scan_obs_text,
)
from robustrtk.sim.fault_spec import FaultSpec
from robustrtk.sim.inject_log import Change

__all__ = ["inject_bytes"]

IntArray = npt.NDArray[np.int64]

_FIELD_FMT = "{:14.3f}"
_MILLI = Decimal("0.001")


class _Layout:
    """Where every satellite record of every kept epoch is, in the plain RINEX text."""

    def __init__(self, data: bytes, path: str):
        self.data = data
        self.path = path
        scan = scan_obs_text(data, path)
        self.starts = scan.starts
        self.ends = scan.ends
        self.h = scan.header
        self.v3 = scan.v3
        self.per_sat = scan.per_sat
        bufp = scan.bufp
        ep = scan.epochs
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
        return field_position(self.v3, rec_line, j)

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
        return rinex3_signal(system, code, layout.h.version)
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
        if layout.data[s + col : min(s + col + OBS_VALUE_WIDTH, t)].strip():
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
        field = bytes(body[col : col + OBS_VALUE_WIDTH]).decode("ascii", "replace")
        lli_old = bytes(body[col + LLI_OFFSET : col + LLI_OFFSET + 1]).decode("ascii", "replace").strip()
        try:
            orig = Decimal(field.strip())
            if not orig.is_finite():
                raise InvalidOperation
        except InvalidOperation:
            raise InputError(
                f"{what}: columns {col + 1}-{col + OBS_VALUE_WIDTH}: expected a number in F14.3, "
                f"found {field.strip()!r}",
                self.layout.path,
                li + 1,
            ) from None
        new = (orig + Decimal(delta_milli).scaleb(-3)).quantize(_MILLI)
        text = _FIELD_FMT.format(new)
        if len(text) > OBS_VALUE_WIDTH:
            raise InputError(
                f"{what}: new value {text.strip()} does not fit the F14.3 field (original "
                f"{field.strip()}, columns {col + 1}-{col + OBS_VALUE_WIDTH})",
                self.layout.path,
                li + 1,
            )
        need = col + (LLI_OFFSET + 1 if set_lli else OBS_VALUE_WIDTH)
        if len(body) < need:
            body.extend(b" " * (need - len(body)))
        body[col : col + OBS_VALUE_WIDTH] = text.encode("ascii")
        lli_new = lli_old
        if set_lli:
            old = int(lli_old) if lli_old.isdigit() else 0
            lli_new = str(old | 1)
            body[col + LLI_OFFSET : col + LLI_OFFSET + 1] = lli_new.encode("ascii")
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
