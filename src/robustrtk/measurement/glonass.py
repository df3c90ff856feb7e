"""GLONASS FDMA carrier phase in the double differences (docs/algorithms.md, "GLONASS FDMA").

Each GLONASS satellite ``s`` transmits on its own frequency channel ``k_s`` (L1:
``f = 1602 + 0.5625 k_s`` MHz), so its wavelength ``λ_s`` differs from the reference's.
The single difference (rover ``r`` minus base ``b``) of a phase in cycles reads::

    φ_rb^s = (ρ_rb^s + c δt_rb) / λ_s + N_rb^s

with the receivers' clock difference ``δt_rb`` (the satellite clock cancels already).
Differenced in cycles between satellites of different channels the clock term
``c δt_rb (1/λ_i − 1/λ_k)`` stays (kilometres of metres for a millisecond clock offset),
so the DD is formed in metres, where the clock cancels exactly::

    λ_i φ_rb^i − λ_k φ_rb^k = ρ_rb^ik + λ_i N_rb^i − λ_k N_rb^k
                           = ρ_rb^ik + λ_i (N_rb^i − N_rb^k) + (λ_i − λ_k) N_rb^k

(Wang 2000; Leick, Rapoport & Tatarnikov 2015, § 7.x; RTKLIB carries the single-difference
ambiguities ``N_rb^s`` as states and forms ``λ_i N^i − λ_k N^k`` the same way). The DD
integer ``N_rb^ik = N_rb^i − N_rb^k`` is estimable once the reference's single-difference
ambiguity ``N_rb^k`` is known to a few cycles: its coefficient ``λ_i − λ_k`` is at most
``13 · 0.5625 / 1602 · λ ≈ 0.85 mm`` per cycle. ``N_rb^k`` is the single difference of
phase minus code in cycles, ``φ_rb^k − P_rb^k / λ_k`` (the clock cancels between the
receiver's own phase and code), averaged over the reference's continuous arc
(:class:`SdAmbiguityMeans`); its error enters the DD with the σ of that mean times
``λ_i − λ_k`` (a millimetre after a few epochs of metre-level code).

What is left is the receivers' inter-frequency (inter-channel) phase bias, which differs
per channel: for two receivers of the same make it cancels in the single difference and
the DD integers are integers (RTKLIB's ``pos2-gloarmode = on``); for different makes the
remaining bias (millimetres to centimetres per channel number) makes them non-integer,
and the GLONASS ambiguities are kept float (``glonass_ar = off``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from robustrtk.core import FloatArray, ObsBatch
from robustrtk.gnss import wavelength_m as carrier_wavelength_m
from robustrtk.measurement.dd import DDSet


def receiver_make(meta: Mapping[str, object]) -> str:
    """Manufacturer token of a receiver: the first word of ``meta["receiver_type"]``
    (RINEX ``REC # / TYPE / VERS``, RTCM 1033, ``"u-blox"`` for UBX input) in lower case with
    everything but letters and digits removed (``"u-blox"`` and ``"UBLOX"`` are one make);
    ``""`` when unknown."""
    text = str(meta.get("receiver_type", "") or "").strip()
    if not text:
        return ""
    return re.sub(r"[^a-z0-9]", "", text.split()[0].lower())


def same_make(meta_a: Mapping[str, object], meta_b: Mapping[str, object]) -> bool:
    """Whether two receivers are known to be of the same make (:func:`receiver_make`); False
    when either is unknown (an empty ``REC # / TYPE``, as convbin writes for u-blox logs)."""
    a, b = receiver_make(meta_a), receiver_make(meta_b)
    return bool(a) and a == b


def header_channels(meta: Mapping[str, object]) -> dict[str, int]:
    """GLONASS frequency channels a file's metadata carries (``meta["glonass_channels"]``:
    RINEX ``GLONASS SLOT / FRQ #``, RTCM 1020 / MSM, UBX ``freqId``); empty when none."""
    ch = meta.get("glonass_channels")
    if not isinstance(ch, Mapping):
        return {}
    return {str(k): int(v) for k, v in ch.items()}


def fill_glonass_wavelengths(rows: ObsBatch, channels: Mapping[str, int]) -> ObsBatch:
    """Signal rows (:func:`robustrtk.measurement.signals.signal_rows`) with the GLONASS
    wavelengths their file left unknown (no ``GLONASS SLOT / FRQ #`` header) taken from
    ``channels`` (satellite -> frequency channel: the navigation data, the other receiver's
    header); rows without a channel stay NaN (no carrier phase)."""
    wl = rows.wavelength_m.copy()
    row_sat = rows.meta.get("row_sat")
    sats = row_sat if isinstance(row_sat, tuple) else tuple(t.split(":", 1)[0] for t in rows.tx_ids)
    slots = rows.meta.get("signal_by_slot")
    by_slot: Mapping[str, object] = slots if isinstance(slots, Mapping) else {}
    changed = False
    for i, (tx, system) in enumerate(zip(rows.tx_ids, rows.system, strict=True)):
        if system != "R" or np.isfinite(wl[i, 0]):
            continue
        slot = tx.split(":", 1)[1] if ":" in tx else ""
        sig = by_slot.get(f"R:{slot}")
        ch = channels.get(str(sats[i]))
        if sig is None or ch is None:
            continue
        wl[i, 0] = carrier_wavelength_m("R", str(sig), int(ch))
        changed = True
    return replace(rows, wavelength_m=wl) if changed else rows


class SdAmbiguityMeans:
    """Running mean of each row's single-difference ambiguity ``φ_rb − P_rb / λ`` (cycles)
    over its continuous arc: the reference's ``N_rb^k`` of the FDMA DD (module notes).

    An arc restarts on a slip flag, after ``max_gap_s`` without the row, and on a value more
    than ``6 σ`` from the mean (a slip no flag reported; σ of one epoch's value).
    """

    def __init__(self, max_gap_s: float = 30.0) -> None:
        self.max_gap_s = max_gap_s
        self._sum: dict[str, float] = {}
        self._n: dict[str, int] = {}
        self._var1: dict[str, float] = {}
        self._t: dict[str, float] = {}

    def update(
        self,
        t_s: float,
        tx_ids: Sequence[str],
        sd_cyc: FloatArray,
        var1_cyc2: FloatArray,
        restart: np.ndarray,
    ) -> tuple[FloatArray, FloatArray]:
        """Add one epoch; the means (NaN where no value) and the variances of the means.

        Parameters
        ----------
        t_s : float
        tx_ids : sequence of str, length N
        sd_cyc : ndarray, shape (N,)
            ``φ_rb − P_rb / λ`` this epoch (cycles), NaN where absent.
        var1_cyc2 : ndarray, shape (N,)
            Variance of one epoch's value (cycles², the code's).
        restart : ndarray of bool, shape (N,)
            Slip flags (either receiver).

        Returns
        -------
        mean_cyc, var_mean_cyc2 : ndarray, shape (N,)
        """
        N = len(tx_ids)
        mean = [math.nan] * N
        var = [math.nan] * N
        # the rows as Python floats and bools (the same values, without a numpy scalar per
        # operation: the loop runs over every row of every epoch); math.sqrt and np.sqrt
        # are both the correctly rounded square root
        sd_l = np.asarray(sd_cyc, float).tolist()
        var1_l = np.broadcast_to(np.asarray(var1_cyc2, float), (N,)).tolist()
        restart_l = np.broadcast_to(np.asarray(restart), (N,)).tolist()
        sums, counts, var1s, times = self._sum, self._n, self._var1, self._t
        for i, tx in enumerate(tx_ids):
            v = sd_l[i]
            if not math.isfinite(v):
                continue
            n = counts.get(tx, 0)
            fresh = (
                n == 0
                or bool(restart_l[i])
                or t_s - times.get(tx, -math.inf) > self.max_gap_s
                or abs(v - sums[tx] / n) > 6.0 * math.sqrt(max(var1_l[i], 1e-6))
            )
            if fresh:
                sums[tx], counts[tx], var1s[tx] = v, 1, var1_l[i]
            else:
                sums[tx] += v
                counts[tx] = n + 1
                var1s[tx] += var1_l[i]
            times[tx] = t_s
            n = counts[tx]
            mean[i] = sums[tx] / n
            var[i] = var1s[tx] / n**2  # var of the mean of n values of those variances
        return np.array(mean, dtype=float), np.array(var, dtype=float)


def fdma_phase_dd(
    dd: DDSet,
    phase_r_cyc: FloatArray,
    phase_b_cyc: FloatArray,
    var_r_m2: FloatArray,
    var_b_m2: FloatArray,
    wavelength_m: FloatArray,
    n_sd_cyc: FloatArray,
    var_n_sd_cyc2: FloatArray,
) -> DDSet:
    """The DD phase set with the rows whose transmitter and reference wavelengths differ
    formed in metres and expressed in cycles of the transmitter's wavelength (module notes)::

        z_i = [λ_i φ_rb^i − λ_k φ_rb^k − (λ_i − λ_k) N̂_rb^k] / λ_i
            = ρ_rb^ik / λ_i + N_rb^ik + ε

    Rows of equal wavelengths are returned as they are (bit for bit).

    Parameters
    ----------
    dd : DDSet
        DD phase in cycles (:func:`robustrtk.measurement.dd.form_dd`).
    phase_r_cyc, phase_b_cyc : ndarray, shape (N,)
        Undifferenced phases (cycles).
    var_r_m2, var_b_m2 : ndarray, shape (N,)
        Their variances (m²).
    wavelength_m : ndarray, shape (N,)
    n_sd_cyc, var_n_sd_cyc2 : ndarray, shape (N,)
        Single-difference ambiguity of each row and its variance
        (:class:`SdAmbiguityMeans`); only the references' are used.

    Returns
    -------
    DDSet
        ``z`` (cycles of ``λ_i``) and ``R`` (cycles²) replaced on the mixed rows; the
        variance of ``(λ_i − λ_k) N̂_rb^k`` is added (correlated between rows of one reference).
    """
    lam = np.asarray(wavelength_m, float)
    if dd.m == 0:
        return dd
    lam_i, lam_k = lam[dd.i_tx], lam[dd.i_ref]
    mixed = lam_i != lam_k
    if not mixed.any():
        return dd
    sd = np.asarray(phase_r_cyc, float) - np.asarray(phase_b_cyc, float)
    dlam = lam_i - lam_k
    n_ref = np.asarray(n_sd_cyc, float)[dd.i_ref]
    n_ref = np.where(np.isfinite(n_ref), n_ref, 0.0)
    z_m = lam_i * sd[dd.i_tx] - lam_k * sd[dd.i_ref] - dlam * n_ref
    z = dd.z.copy()
    z[mixed] = z_m[mixed] / lam_i[mixed]
    # R in metres: the metre-domain DD λ_i φ^i − λ_k φ^k differences the undifferenced
    # phases in metres, whose variances are given in m², so the operator acts with its
    # signs alone (no wavelength: the variances are metres already)
    var_m = np.concatenate([np.asarray(var_r_m2, float), np.asarray(var_b_m2, float)])
    var_m = np.where(np.isfinite(var_m), var_m, 0.0)
    R_m = (dd.D * var_m) @ dd.D.T
    var_n = np.asarray(var_n_sd_cyc2, float)[dd.i_ref]
    var_n = np.where(np.isfinite(var_n), var_n, 0.0)
    same_ref = dd.i_ref[:, None] == dd.i_ref[None, :]
    R_m = R_m + same_ref * np.outer(dlam * np.sqrt(var_n), dlam * np.sqrt(var_n))
    R_cyc = R_m / np.outer(lam_i, lam_i)
    R = dd.R.copy()
    R[mixed, :] = R_cyc[mixed, :]
    R[:, mixed] = R_cyc[:, mixed]
    return DDSet(**dd.index_fields(), z=z, R=0.5 * (R + R.T))


__all__ = [
    "SdAmbiguityMeans",
    "fdma_phase_dd",
    "fill_glonass_wavelengths",
    "header_channels",
    "receiver_make",
    "same_make",
]
