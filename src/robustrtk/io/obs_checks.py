"""Physically impossible observation values, masked and counted by every GNSS reader.

A reader that parses a field as a number can still get ``inf``, a pseudorange of 1e11 m
or a negative one. Such values are not observations: :func:`mask_impossible` sets them to
NaN (missing), counts them per kind in ``meta["masked_values"]``, and the command line says
so (``warning: FILE: N values masked ...``), so a run never solves with them silently and
never drops an epoch without a word.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from robustrtk.core import FloatArray, ObsBatch

#: Pseudoranges (m) a GNSS receiver can report: positive and below this bound (3.3 light
#: seconds; a satellite is at most ~4e7 m away, a receiver clock a few hundred km off).
CODE_RANGE_M = (0.0, 1.0e9)
#: Largest magnitude of a carrier phase (cycles; RINEX holds at most 1e10) and a Doppler
#: shift (Hz; a LEO user sees tens of kHz) kept.
MAX_PHASE_CYC = 1.0e12
MAX_DOPPLER_HZ = 1.0e6
#: Carrier-to-noise densities (dB-Hz) kept.
CN0_RANGE_DBHZ = (-50.0, 150.0)


def _bad(a: FloatArray, lo: float, hi: float, strict_lo: bool = False) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        low = a <= lo if strict_lo else a < lo
        return np.isinf(a) | low | (a >= hi)


def mask_impossible(batch: ObsBatch) -> ObsBatch:
    """``batch`` with impossible values set to NaN, counted in ``meta["masked_values"]``
    (``{"code_m": n, ...}``, present only when some value was masked).

    Masked: non-finite values (``inf``); pseudoranges outside :data:`CODE_RANGE_M` (zero
    and negative included); phases beyond :data:`MAX_PHASE_CYC`; Dopplers beyond
    :data:`MAX_DOPPLER_HZ`; C/N0 outside :data:`CN0_RANGE_DBHZ`.
    """
    checks = {
        "code_m": _bad(batch.code_m, *CODE_RANGE_M, strict_lo=True),
        "phase_cyc": _bad(batch.phase_cyc, -MAX_PHASE_CYC, MAX_PHASE_CYC),
        "doppler_hz": _bad(batch.doppler_hz, -MAX_DOPPLER_HZ, MAX_DOPPLER_HZ),
        "cn0_dbhz": _bad(batch.cn0_dbhz, *CN0_RANGE_DBHZ),
    }
    counts = {k: int(m.sum()) for k, m in checks.items() if m.any()}
    if not counts:
        return batch
    fields = {}
    for k, m in checks.items():
        a = getattr(batch, k)
        if m.any():
            a = a.copy()
            a[m] = np.nan
        fields[k] = a
    meta = dict(batch.meta)
    meta["masked_values"] = counts
    return replace(batch, meta=meta, **fields)


def masked_text(batch: ObsBatch) -> str:
    """``"3 code_m, 1 phase_cyc values"`` of ``meta["masked_values"]`` (empty when none)."""
    counts = batch.meta.get("masked_values")
    if not isinstance(counts, dict):
        return ""
    return ", ".join(f"{n} {k}" for k, n in counts.items())


__all__ = [
    "CN0_RANGE_DBHZ",
    "CODE_RANGE_M",
    "MAX_DOPPLER_HZ",
    "MAX_PHASE_CYC",
    "mask_impossible",
    "masked_text",
]
