"""A receiver's code noise and multipath from its own data (code minus carrier).

On one continuous carrier arc, code minus carrier ``CMC = P − λΦ`` removes the geometry,
the clocks and the troposphere::

    CMC = 2 I − λ N + e_P + m_P     (phase noise and multipath negligible)

so within a short stretch of the arc (the ionosphere and the ambiguity constant) its
deviation from the stretch's median is the code's own error, noise and multipath
together. Scaled by ``sin(el)`` (the elevation model of
:func:`robustrtk.measurement.weighting.variance`), its robust spread estimates the zenith
code σ that the elevation weighting assumes.

Why it matters: code multipath on a patch antenna is metres and correlated over minutes.
Weighted as the few decimetres of a geodetic antenna and averaged epoch after epoch as if
white, it gives a float solution metres off with a decimetre σ, and LAMBDA's ratio test
then validates integers fitted to that wrong float (the best candidate need only be three
times better than the next, not close). A code σ that covers what the receiver's code
really does keeps the float's covariance honest.
"""

from __future__ import annotations

import numpy as np

from robustrtk.core import FloatArray, ObsBatch, TransmitterSource, median_of
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import elevation_rot

#: Tolerated gap inside an arc (s); a longer one starts a new arc.
MAX_GAP_S = 10.0
#: Length of the stretches whose median is removed (s): short enough for the ionosphere
#: to change little, long enough to keep the multipath's slow part.
STRETCH_S = 300.0
#: Fewest samples of a stretch that count.
MIN_STRETCH = 20
#: Fewest samples overall for an estimate.
MIN_SAMPLES = 200
#: Time over which a float RTK solution averages code before its ambiguities are fixed (s):
#: the code σ is taken at this time scale (:func:`receiver_code_sigma_m`).
CORRELATION_WINDOW_S = 30.0
#: Largest code σ (m) the data may set (:func:`combined_code_sigma_m`).
MAX_CODE_SIGMA_M = 30.0


def zenith_code_sigma_m(
    t_s: FloatArray,
    code_m: FloatArray,
    phase_cyc: FloatArray,
    wavelength_m: FloatArray,
    lli: np.ndarray,
    sin_el: FloatArray,
    min_sin_el: float = 0.26,
    block: int = 1,
) -> float | None:
    """Robust zenith code σ (m) of one receiver from its code minus carrier.

    Parameters
    ----------
    t_s : ndarray, shape (T,)
    code_m, phase_cyc, wavelength_m : ndarray, shape (T, R)
        One signal per row (NaN where absent).
    lli : ndarray of int, shape (T, R)
        Loss-of-lock indicators (bit 0 starts a new arc).
    sin_el : ndarray, shape (T, R)
        Sine of each row's elevation (NaN where unknown).
    min_sin_el : float
        Rows lower than this (15° by default) are left out.

    block : int
        With ``block > 1``: the σ of white noise whose means over ``block`` consecutive
        samples scatter as the code's do, ``√block · 1.4826 · MAD(block means)``. Multipath
        correlated over the block makes this larger than the per-sample spread: it is the σ
        a filter that averages ``block`` epochs as independent must assume to stay honest.

    Returns
    -------
    float or None
        ``1.4826 · median |(CMC − stretch median) · sin el|`` (``block = 1``), or the block
        σ above; None with fewer than :data:`MIN_SAMPLES` samples.
    """
    t = np.asarray(t_s, float)
    cmc = np.asarray(code_m, float) - np.asarray(phase_cyc, float) * np.asarray(wavelength_m, float)
    s = np.asarray(sin_el, float)
    ok = np.isfinite(cmc) & np.isfinite(s) & (s >= min_sin_el)
    T, R = cmc.shape
    if T == 0 or R == 0:
        return None
    # arc number per cell: a new arc at loss of lock, a gap, or a missing sample
    brk = (np.asarray(lli) & 1).astype(bool) | ~ok
    dt = np.diff(t, prepend=t[0])
    brk |= (dt > MAX_GAP_S)[:, None]
    arc = np.cumsum(brk, axis=0)
    stretch = np.floor((t - t[0]) / STRETCH_S).astype(np.int64)[:, None]
    rows = np.broadcast_to(np.arange(R)[None, :], (T, R))
    # one integer per (row, arc, stretch): arcs number at most T + 1 per row, stretches at
    # most T; the groups' numbering does not enter the statistic, only which cells share one
    stretch -= stretch.min()
    n_st = int(stretch.max()) + 1
    key = (rows[ok].astype(np.int64) * (T + 1) + arc[ok]) * n_st + np.broadcast_to(stretch, (T, R))[ok]
    if key.shape[0] < MIN_SAMPLES:
        return None
    _, group, counts = np.unique(key, return_inverse=True, return_counts=True)
    group = group.reshape(-1)
    vals = cmc[ok]
    order = np.argsort(group, kind="stable")
    g_sorted = group[order]
    starts = np.flatnonzero(np.r_[True, g_sorted[1:] != g_sorted[:-1]])
    med = group_medians(group, vals, counts)
    keep = counts[group] >= MIN_STRETCH
    if np.count_nonzero(keep) < MIN_SAMPLES:
        return None
    dev_all = (vals - med[group]) * s[ok]
    if block <= 1:
        dev = dev_all[keep]
        return float(1.4826 * median_of(np.abs(dev - median_of(dev))))
    # means of `block` consecutive samples of a stretch (samples in time order per group)
    sizes = np.r_[starts[1:], g_sorted.size] - starts
    seg = np.repeat(np.arange(starts.size), sizes)
    pos = np.arange(g_sorted.size) - starts[seg]
    blk = pos // block
    full = sizes[seg]
    use = keep[order] & ((blk + 1) * block <= full)
    if np.count_nonzero(use) < MIN_SAMPLES:
        return None
    bkey = g_sorted[use] * 100_000 + blk[use]
    _, binv, bcnt = np.unique(bkey, return_inverse=True, return_counts=True)
    means = np.bincount(binv.reshape(-1), weights=dev_all[order][use]) / bcnt
    spread = 1.4826 * median_of(np.abs(means - median_of(means)))
    return float(np.sqrt(block) * spread)


def group_medians(group: np.ndarray, vals: FloatArray, counts: np.ndarray) -> FloatArray:
    """Median of ``vals`` per group, as :func:`numpy.median` of each group gives it.

    Parameters
    ----------
    group : ndarray of int, shape (M,)
        Group number of each value, ``0 … G−1``.
    vals : ndarray, shape (M,)
        Finite values.
    counts : ndarray of int, shape (G,)
        Values per group (each ≥ 1).

    Returns
    -------
    ndarray, shape (G,)
        ``(v[(c−1)//2] + v[c//2]) / 2`` of each group's sorted values ``v`` (count ``c``).
    """
    srt = np.lexsort((vals, group))
    v = np.asarray(vals, float)[srt]
    first = np.r_[0, np.cumsum(counts)[:-1]]
    lo = v[first + (counts - 1) // 2]
    hi = v[first + counts // 2]
    return np.asarray((lo + hi) / 2.0, float)


def row_sin_elevations(
    batch: ObsBatch, source: TransmitterSource, pos_m: FloatArray, every_s: float = 30.0
) -> FloatArray:
    """``sin(el)`` of each cell of a row batch (T, R) seen from ``pos_m`` (ECEF), evaluated
    every ``every_s`` and held in between (elevations change by about 0.1° in 30 s)."""
    pos = np.asarray(pos_m, float)
    lat, lon, _ = ecef2geodetic(pos)
    rot = ecef2enu_rotation(float(lat), float(lon))
    T, R = batch.code_m.shape[:2]
    out = np.full((T, R), np.nan)
    # the sample epochs and the epochs each one stands for: [starts[k], starts[k + 1])
    starts = [0]
    while starts[-1] < T:
        i = starts[-1]
        starts.append(max(int(np.searchsorted(batch.t_s, batch.t_s[i] + every_s, side="left")), i + 1))
    prefetch = getattr(source, "prefetch", None)
    if prefetch is not None:  # one vectorised ephemeris pass (row by row the same numbers)
        prefetch([(float(batch.t_s[i]), batch.tx_ids, batch.code_m[i, :, 0]) for i in starts[:-1]])
    for i, j in zip(starts[:-1], starts[1:], strict=True):
        p, _ = source.positions(float(batch.t_s[i]), batch.tx_ids, batch.code_m[i, :, 0])
        p = np.asarray(p, float)
        ok = np.all(np.isfinite(p), axis=1)
        if ok.any():
            el = np.full(R, np.nan)
            el[ok] = elevation_rot(p[ok], pos, rot)
            out[i:j] = np.sin(el)
    return out


def epoch_sin_elevations(
    source: TransmitterSource, t_s: float, tx_ids: tuple[str, ...], code_m: FloatArray, pos_m: FloatArray
) -> FloatArray:
    """``sin(el)`` of one epoch's rows (shape (N,), NaN where the transmitter has no
    position) seen from ``pos_m`` (ECEF, m); ``code_m`` (N,) gives the transmit times."""
    pos = np.asarray(pos_m, float)
    out = np.full(len(tx_ids), np.nan)
    if not tx_ids:
        return out
    lat, lon, _ = ecef2geodetic(pos)
    rot = ecef2enu_rotation(float(lat), float(lon))
    p, _ = source.positions(float(t_s), tx_ids, np.asarray(code_m, float))
    p = np.asarray(p, float)
    ok = np.all(np.isfinite(p), axis=1)
    if ok.any():
        out[ok] = np.sin(elevation_rot(p[ok], pos, rot))
    return out


def block_samples(dt_s: float, window_s: float = CORRELATION_WINDOW_S) -> int | None:
    """Samples of interval ``dt_s`` (s) in ``window_s`` (at least 1); None where samples so
    sparse that a stretch (:data:`STRETCH_S`) cannot hold :data:`MIN_STRETCH` of them."""
    if dt_s > 0 and STRETCH_S / dt_s + 1 < MIN_STRETCH:
        return None
    return max(1, int(round(window_s / dt_s))) if dt_s > 0 else 1


def receiver_code_sigma_m(
    batch: ObsBatch, source: TransmitterSource, pos_m: FloatArray, window_s: float = CORRELATION_WINDOW_S
) -> float | None:
    """Zenith code σ (m) of one receiver's first signal column at the time scale
    ``window_s`` (:func:`zenith_code_sigma_m` with ``block`` = the samples in that window)."""
    if len(batch) < 2:
        return None
    dt = median_of(np.diff(batch.t_s))
    block = block_samples(dt, window_s)
    # nothing to estimate: stretches too sparse to count, or too few code-and-phase cells
    if block is None:
        return None
    both = np.isfinite(batch.code_m[:, :, 0]) & np.isfinite(batch.phase_cyc[:, :, 0])
    if np.count_nonzero(both) < MIN_SAMPLES:
        return None
    sin_el = row_sin_elevations(batch, source, pos_m)
    lam = np.broadcast_to(batch.wavelength_m[None, :, 0], batch.code_m.shape[:2])
    code, phase, lli = batch.code_m[:, :, 0], batch.phase_cyc[:, :, 0], batch.lli[:, :, 0]
    return zenith_code_sigma_m(batch.t_s, code, phase, lam, lli, sin_el, block=block)


def combined_code_sigma_m(
    sigma_rover_m: float | None, sigma_base_m: float | None, sigma_m: float, min_ratio: float = 1.0
) -> float | None:
    """The one code σ (m) of a receiver pair from their estimates, where it replaces the
    configured ``sigma_m``; None where it does not.

    The DD code variance is the sum of the two receivers', so the one σ of both is
    ``√((σ_r² + σ_b²) / 2)`` (``sigma_m`` standing in for a receiver without an estimate,
    None when neither has one). It replaces ``sigma_m`` only when larger than ``min_ratio``
    times it (never lowered), capped at :data:`MAX_CODE_SIGMA_M`.
    """
    if sigma_rover_m is None and sigma_base_m is None:
        return None
    sig = float(np.sqrt(((sigma_rover_m or sigma_m) ** 2 + (sigma_base_m or sigma_m) ** 2) / 2.0))
    if not sig > min_ratio * sigma_m:
        return None
    return min(sig, MAX_CODE_SIGMA_M)


class OnlineCodeSigma:
    """Causal :func:`receiver_code_sigma_m`: one receiver's zenith code σ from the epochs
    so far (a real-time stream), the same statistic over the latest ``window_s``.

    Epochs are pushed in time order (:meth:`push`) with the sine of each row's elevation;
    :meth:`sigma_m` evaluates :func:`zenith_code_sigma_m` on them at the time scale
    :data:`CORRELATION_WINDOW_S` (arcs, stretches and the block σ exactly as the file
    estimate; the stretches counted from the window's first epoch).

    Parameters
    ----------
    window_s : float
        Span of the epochs kept (s): bounds memory and time of a long stream.
    """

    def __init__(self, window_s: float = 3600.0) -> None:
        self.window_s = window_s
        self.epochs: list[tuple[float, tuple[str, ...], FloatArray, np.ndarray, FloatArray]] = []

    def push(
        self,
        t_s: float,
        tx_ids: tuple[str, ...],
        code_m: FloatArray,
        phase_cyc: FloatArray,
        wavelength_m: FloatArray,
        lli: np.ndarray,
        sin_el: FloatArray,
    ) -> None:
        """One epoch's rows (shape (N,) each: code (m), phase (cycles), wavelength (m),
        loss-of-lock indicators, sine of elevation; NaN where absent)."""
        cmc = np.asarray(code_m, float) - np.asarray(phase_cyc, float) * np.asarray(wavelength_m, float)
        self.epochs.append(
            (float(t_s), tuple(tx_ids), cmc, np.asarray(lli).astype(np.int64), np.asarray(sin_el, float))
        )
        t0 = float(t_s) - self.window_s
        if self.epochs[0][0] < t0:
            self.epochs = [e for e in self.epochs if e[0] >= t0]

    def span_s(self) -> float:
        """Time (s) from the first epoch kept to the latest."""
        return self.epochs[-1][0] - self.epochs[0][0] if self.epochs else 0.0

    def possible(self) -> bool:
        """False when the epochs so far are too sparse for an estimate ever
        (:func:`block_samples`); True until that is known."""
        if len(self.epochs) < 2:
            return True
        dt = float(np.median(np.diff([e[0] for e in self.epochs])))
        return block_samples(dt) is not None

    def sigma_bound_m(self) -> float | None:
        """A conservative value (m) of what :meth:`sigma_m` will be once the epochs span a
        detrending stretch, from the epochs so far; None while they span less than two
        correlation windows (or give no estimate).

        Over a record of ``L < STRETCH_S`` seconds the stretch median absorbs the code's slow
        error; a slow error (multipath of periods longer than the record) is, to first order,
        a linear drift over ``L``, whose deviations from the stretch median grow as ``L``.
        So ``σ_L · STRETCH_S / L`` is the full stretch's σ for a drift and above it for faster
        errors (algorithms.md §42). Not a strict bound: on Gauss–Markov errors of 5–900 s
        correlation it was at least the full stretch's σ at 60 s and at least 0.79 of it
        later (tests/pipeline/test_stream_code_sigma.py). With less than two windows of
        :data:`CORRELATION_WINDOW_S` a stretch holds one block, whose mean differs from the
        stretch median only by the block's skew: not yet a spread. From a full stretch on,
        it is :meth:`sigma_m` itself."""
        span = self.span_s()
        if span < 2.0 * CORRELATION_WINDOW_S:
            return None
        sig = self.sigma_m()
        if sig is None:
            return None
        return sig * max(1.0, STRETCH_S / span)

    def sigma_m(self) -> float | None:
        """Zenith code σ (m) of the epochs so far; None while the data do not tell."""
        if len(self.epochs) < 2:
            return None
        t = np.array([e[0] for e in self.epochs])
        block = block_samples(float(np.median(np.diff(t))))
        if block is None:
            return None
        cols: dict[str, int] = {}
        for e in self.epochs:
            for tx in e[1]:
                cols.setdefault(tx, len(cols))
        T, R = t.size, len(cols)
        cmc = np.full((T, R), np.nan)
        s = np.full((T, R), np.nan)
        lli = np.zeros((T, R), np.int64)
        for i, (_, ids, c, f, se) in enumerate(self.epochs):
            k = [cols[tx] for tx in ids]
            cmc[i, k], lli[i, k], s[i, k] = c, f, se
        # code minus carrier already formed: phase 0 of wavelength 1 leaves it as it is
        zeros, ones = np.zeros((T, R)), np.ones((T, R))
        return zenith_code_sigma_m(t, cmc, zeros, ones, lli, s, block=block)


__all__ = [
    "CORRELATION_WINDOW_S",
    "MAX_CODE_SIGMA_M",
    "MAX_GAP_S",
    "MIN_SAMPLES",
    "MIN_STRETCH",
    "STRETCH_S",
    "OnlineCodeSigma",
    "block_samples",
    "combined_code_sigma_m",
    "epoch_sin_elevations",
    "group_medians",
    "receiver_code_sigma_m",
    "row_sin_elevations",
    "zenith_code_sigma_m",
]
