"""A base epoch carried forward in time to a later rover epoch (age of differential).

A base observation at its time tag ``t_b`` reads, per satellite ``s`` (metres)::

    P_b^s(t_b) = ρ_b^s(t_b) + c δt_b(t_b) − c δt^s(t_b) + T_b^s(t_b) + I_b^s(t_b) + e

(the phase alike, with its ambiguity and ``−I``). Carried to the rover's tag ``t_r = t_b + a``
it becomes the observation a receiver at the same place would have made at ``t_r``, up to
what cannot be predicted::

    P_b^s(t_r) ≈ P_b^s(t_b) + Δρ^s − c Δδt^s + ΔT^s,   Δx = x(t_r) − x(t_b)

with the geometric range ``ρ`` (satellite at its transmission time, Sagnac term), the
broadcast satellite clock ``δt^s`` (relativistic term included) and the modelled
troposphere ``T`` (Saastamoinen) taken from the ephemerides at both instants. The phase
moves by the same metres over its wavelength; the ambiguity is constant. What is left:

* the base receiver clock change ``c Δδt_b``: common to every satellite, it cancels in
  the double differences (so the base's own clock drift need not be known);
* the ionosphere's change and the broadcast orbit's and clock's error change: a few
  millimetres per second at most, covered by the age variance
  (:func:`age_variance_m2`, ``σ_age · a`` in metres, added to the base's undifferenced
  variances).

Why not the base's Doppler: ``Φ(t_r) ≈ Φ(t_b) − D a`` is a first-order extrapolation
whose error is ``½ ρ̈ a²``; satellite range accelerations reach 0.1–0.2 m/s², so the error
passes a carrier cycle (19 cm on L1) after about 1.5 s of age. The ephemeris terms above
are exact to the orbit model at any age (algorithms.md, "Base epochs in time").
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from robustrtk.core import BoolArray, FloatArray, IntArray, ObsBatch, ObsEpoch, TransmitterSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import elevation_rot
from robustrtk.measurement.corrections import tropo_saastamoinen
from robustrtk.measurement.dd import ranges


@dataclass(frozen=True)
class PropagatedEpoch(ObsEpoch):
    """A base epoch carried to a later time tag (:func:`propagate_base_epoch`).

    Attributes
    ----------
    age_s : float
        Age of the base observations at the new tag (s).
    age_var_m2 : float
        Variance (m²) added to each undifferenced code and phase row for that age.
    """

    age_s: float = 0.0
    age_var_m2: float = 0.0


def age_variance_m2(age_s: float, sigma_age_m_s: float) -> float:
    """Undifferenced variance (m²) for base observations ``age_s`` old: ``(σ_age · a)²``.

    The σ grows linearly with the age, as a clock's or a slowly changing atmosphere's
    error does (RTKLIB's satellite-clock-stability term has the same form)."""
    return float((sigma_age_m_s * max(float(age_s), 0.0)) ** 2)


def range_change_m(
    source: TransmitterSource,
    tx_ids: tuple[str, ...],
    code_m: FloatArray,
    t_from_s: float,
    t_to_s: float,
    pos_m: FloatArray,
    sagnac: bool,
    troposphere: bool,
) -> FloatArray:
    """What a receiver standing at ``pos_m`` sees each transmitter's range change by from
    ``t_from_s`` to ``t_to_s`` (m): geometry, minus the transmitter clock, plus the modelled
    troposphere (when ``troposphere``).

    Parameters
    ----------
    source : TransmitterSource
    tx_ids : tuple of str, length N
    code_m : ndarray, shape (N,)
        Pseudoranges at ``t_from_s`` (transmission times); NaN rows give NaN.
    t_from_s, t_to_s : float
        Receiver time tags (s).
    pos_m : ndarray, shape (3,)
        Receiver position (the frame of ``source``).
    sagnac : bool
        ECEF satellites: add the Earth-rotation term to the ranges.
    troposphere : bool
        Add the change of the Saastamoinen slant delay (ECEF only).

    Returns
    -------
    ndarray, shape (N,)
        Range change (m); NaN where a transmitter has no position at either time.
    """
    pos = np.asarray(pos_m, float)
    code = np.asarray(code_m, float)
    p0, c0 = source.positions(t_from_s, tx_ids, code)
    r0 = ranges(pos, np.asarray(p0, float), sagnac) - np.nan_to_num(np.asarray(c0, float))
    delta = np.zeros_like(r0)
    p1 = p0
    for _ in range(2):  # the later transmission time follows the changed travel time
        p1, c1 = source.positions(t_to_s, tx_ids, code + delta)
        r1 = ranges(pos, np.asarray(p1, float), sagnac) - np.nan_to_num(np.asarray(c1, float))
        delta = np.where(np.isfinite(r1 - r0), r1 - r0, 0.0)
    out = r1 - r0
    if troposphere:
        lat, lon, h = ecef2geodetic(pos)
        rot = ecef2enu_rotation(float(lat), float(lon))
        ok = np.all(np.isfinite(p0), axis=1) & np.all(np.isfinite(p1), axis=1)
        el0 = elevation_rot(np.where(ok[:, None], p0, pos + 1.0), pos, rot)
        el1 = elevation_rot(np.where(ok[:, None], p1, pos + 1.0), pos, rot)
        t0 = np.asarray(tropo_saastamoinen(lat, h, np.clip(el0, 1e-3, None)), float)
        t1 = np.asarray(tropo_saastamoinen(lat, h, np.clip(el1, 1e-3, None)), float)
        out = out + np.where(ok, t1 - t0, np.nan)
    return np.asarray(out, float)


def propagate_base_epoch(
    epoch: ObsEpoch,
    t_to_s: float,
    source: TransmitterSource,
    pos_m: FloatArray,
    *,
    sagnac: bool,
    troposphere: bool,
    signal: int = 0,
    sigma_age_m_s: float = 0.0,
) -> PropagatedEpoch:
    """The base epoch carried to the time tag ``t_to_s`` (see the module notes).

    Code and phase of every signal column move by :func:`range_change_m` (the phase in
    cycles of its wavelength); Doppler, C/N0 and loss-of-lock flags are kept as observed.

    Parameters
    ----------
    epoch : ObsEpoch
        The base epoch (tag ``t_b ≤ t_to_s``).
    t_to_s : float
        The rover's time tag (s).
    source : TransmitterSource
    pos_m : ndarray, shape (3,)
        Base position at ``t_b``.
    sagnac, troposphere : bool
        As :func:`range_change_m`.
    signal : int
        Column whose pseudoranges give the transmission times.
    sigma_age_m_s : float
        σ growth rate of :func:`age_variance_m2`.

    Returns
    -------
    PropagatedEpoch
        Tag ``t_to_s``, ``age_s = t_to_s − t_b``.
    """
    age = float(t_to_s) - float(epoch.t_s)
    d = range_change_m(
        source, tuple(epoch.tx_ids), epoch.code_m[:, signal], float(epoch.t_s), float(t_to_s), pos_m,
        sagnac, troposphere,
    )  # fmt: skip
    code = epoch.code_m + d[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        phase = epoch.phase_cyc + d[:, None] / epoch.wavelength_m
    kw = {f: getattr(epoch, f) for f in epoch.__dataclass_fields__ if f not in ("age_s", "age_var_m2")}
    kw.update(t_s=float(t_to_s), code_m=code, phase_cyc=phase)
    return PropagatedEpoch(**kw, age_s=age, age_var_m2=age_variance_m2(age, sigma_age_m_s))


def with_age(epoch: ObsEpoch) -> tuple[float, float]:
    """``(age_s, age_var_m2)`` of an epoch: its own for a :class:`PropagatedEpoch`, else
    zero (an epoch used at its own time)."""
    if isinstance(epoch, PropagatedEpoch):
        return epoch.age_s, epoch.age_var_m2
    return 0.0, 0.0


def age_dd_covariance_m2(D: FloatArray, n_tx: int, age_var_m2: float) -> FloatArray:
    """The part of a DD covariance (m²) that the age variance of the base adds: the base's
    columns of the differencing operator ``D`` (``[rover (N), base (N)]``, signs only) over
    ``age_var_m2`` on each base row, ``age_var · D_b D_bᵀ`` (metres whatever the wavelengths:
    the age variance is of the base's range, :func:`propagate_base_epoch`).

    Parameters
    ----------
    D : ndarray, shape (m, 2N)
        DD operator (:class:`robustrtk.measurement.dd.DDIndex`).
    n_tx : int
        ``N``.
    age_var_m2 : float
        Undifferenced age variance of each base row (m², :func:`age_variance_m2`).

    Returns
    -------
    ndarray, shape (m, m)
    """
    Db = np.asarray(D, float)[:, n_tx:]
    return np.asarray(float(age_var_m2) * (Db @ Db.T), float)


def age_free_fraction(H_pos: FloatArray, R_m2: FloatArray, R_age_m2: FloatArray) -> float:
    """Share of a position's variance that does not come from the age of the base.

    With position rows ``H_pos`` of covariance ``R = R₀ + R_age`` (``R_age`` the base's
    age variance, :func:`age_dd_covariance_m2`), the least-squares position covariances
    with and without the age part are ``C = (Hᵀ R⁻¹ H)⁻¹`` and ``C₀ = (Hᵀ R₀⁻¹ H)⁻¹``; the
    fraction is ``f = tr C₀ / tr C``, in ``(0, 1]`` (``R₀ ≼ R`` gives ``C₀ ≼ C``). A
    σ computed under ``R`` times ``√f`` is the σ the same geometry gives with a fresh base
    (algorithms.md § 37). 1 when ``R_age`` is zero, the rows cannot fix a position
    (fewer than three, or a singular normal matrix) or ``R₀`` is not positive definite.

    Parameters
    ----------
    H_pos : ndarray, shape (m, 3)
        Position columns of the rows' Jacobian.
    R_m2, R_age_m2 : ndarray, shape (m, m)
        Their covariance and its age part (m²).

    Returns
    -------
    float
    """
    H = np.asarray(H_pos, float)
    R = np.asarray(R_m2, float)
    R_age = np.asarray(R_age_m2, float)
    if H.shape[0] < H.shape[1] or not np.any(R_age):
        return 1.0
    try:
        info = H.T @ np.linalg.solve(R, H)
        info0 = H.T @ np.linalg.solve(R - R_age, H)
        tr = float(np.trace(np.linalg.inv(info)))
        tr0 = float(np.trace(np.linalg.inv(info0)))
    except np.linalg.LinAlgError:
        return 1.0
    if not (np.isfinite(tr) and np.isfinite(tr0) and tr > 0.0 and tr0 > 0.0):
        return 1.0
    return float(min(tr0 / tr, 1.0))


class SystemFill:
    """Base epochs completed system by system: the rows of a system the base regularly
    sends but an epoch lacks come from the latest earlier epoch that has them (at most
    ``max_age_s`` older), carried to the epoch's tag (:func:`propagate_base_epoch`).

    A base whose systems arrive in separate messages (RTCM 3 MSM: one message per system)
    over a link with gaps gives epochs with one system only. Served as they are, they drop
    the other systems' double differences, and with them their ambiguities, for that rover
    epoch; passing over them for the latest complete epoch throws away the fresh system.
    Completed, they serve with every system. A system is *regular* when it has phases in at
    least half of the epochs with any. The copied rows keep their half-cycle bit and lose
    the loss-of-lock bit (a slip is reported once, by the epoch that observed it).

    Parameters
    ----------
    batch : ObsBatch
        The base's signal rows (one signal column).
    source : TransmitterSource
    pos_m : ndarray, shape (3,)
        Base position.
    max_age_s : float
    sagnac, troposphere : bool
        As :func:`range_change_m`.
    """

    def __init__(
        self, batch: ObsBatch, source: TransmitterSource, pos_m: FloatArray, max_age_s: float,
        *, sagnac: bool, troposphere: bool,
    ) -> None:  # fmt: skip
        self.batch, self.source, self.pos_m = batch, source, np.asarray(pos_m, float)
        self.sagnac, self.troposphere = sagnac, troposphere
        have = np.isfinite(np.asarray(batch.phase_cyc)[:, :, 0])
        anyv = have.any(axis=1)
        sysarr = np.asarray(list(batch.system))
        t = np.asarray(batch.t_s, float)
        self.rows: dict[str, BoolArray] = {}
        self.src: dict[str, IntArray] = {}
        for s in sorted(set(sysarr.tolist())):
            cols = sysarr == s
            has = have[:, cols].any(axis=1)
            if np.count_nonzero(has & anyv) < 0.5 * max(int(np.count_nonzero(anyv)), 1):
                continue
            idx = np.where(has, np.arange(t.size), -1)
            last = np.maximum.accumulate(idx) if t.size else idx
            ok = (last >= 0) & (t - t[np.maximum(last, 0)] <= max_age_s)
            self.rows[s] = cols
            self.src[s] = np.where(ok, last, -1).astype(np.int64)

    def epoch(self, j: int) -> ObsEpoch:
        """Base epoch ``j``, completed (the epoch itself when it lacks nothing)."""
        ep = self.batch.epoch(j)
        for s, cols in self.rows.items():
            k = int(self.src[s][j])
            if k < 0 or k == j:
                continue
            old = propagate_base_epoch(
                self.batch.epoch(k), ep.t_s, self.source, self.pos_m, sagnac=self.sagnac,
                troposphere=self.troposphere,
            )  # fmt: skip
            code, phase = ep.code_m.copy(), ep.phase_cyc.copy()
            dop, cn0, lli = ep.doppler_hz.copy(), ep.cn0_dbhz.copy(), ep.lli.copy()
            code[cols], phase[cols] = old.code_m[cols], old.phase_cyc[cols]
            dop[cols], cn0[cols] = old.doppler_hz[cols], old.cn0_dbhz[cols]
            lli[cols] = old.lli[cols] & ~np.int8(1)
            ep = replace(ep, code_m=code, phase_cyc=phase, doppler_hz=dop, cn0_dbhz=cn0, lli=lli)
        return ep


__all__ = [
    "PropagatedEpoch",
    "SystemFill",
    "age_dd_covariance_m2",
    "age_free_fraction",
    "age_variance_m2",
    "propagate_base_epoch",
    "range_change_m",
    "with_age",
]
