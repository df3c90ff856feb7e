"""Phone profile: a geodetic receiver's observations degraded into smartphone-like ones.

:func:`phone_profile` takes the :class:`~robustrtk.core.ObsBatch` of a real receiver (a
RINEX file of a geodetic or survey-grade rover) and returns the observations a
smartphone would have made at the same place and time, together with a log of every
discrete event it drew. Everything is seeded: each (transmitter, signal) series draws
from its own generator seeded by ``(seed, crc32("<sat>:<signal>"))``, so a series does not
depend on the other satellites of the file. The model and its defaults are described
in ``docs/phone_profile.md`` and in ``docs/algorithms.md`` § 24; in short,
per series (satellite ``s``, signal on band ``b``) and epoch ``t``:

1. **Signals**: only what phone chipsets track: GPS/QZSS L1 C/A and L5, Galileo E1 and
   E5a, BeiDou B1I and B2a, GLONASS L1 C/A (one tracking mode per band; the rest is dropped).
2. **C/N0**: ``C/N0_phone = C/N0 - loss_b + w_t`` (dB-Hz), ``loss_b`` the antenna and
   front-end loss of band ``b`` and ``w`` a first-order Gauss-Markov process
   (``w_t = a w_{t-1} + sqrt(1 - a²) σ_w η``, ``a = exp(-Δt/τ_w)``). Below
   ``track_min_dbhz`` nothing is tracked; below ``phase_min_dbhz`` no carrier phase.
3. **Code**: ``σ_P(C/N0) = σ_P0 f_b 10^((C/N0_0 - C/N0)/20)`` (so the variance is
   proportional to 1/(C/N0) in linear units); the pseudorange gains white noise of that σ
   plus a Gauss-Markov multipath term of σ ``m σ_P`` and correlation time ``τ_mp``.
4. **Phase**: white noise ``σ_φ(C/N0) = σ_φ0 10^((C/N0_0 - C/N0)/20)`` (m). Duty cycling:
   an arc of carrier phase lasts an exponential time of mean ``duty_on_s``, then the
   phase is absent for 1 to ``duty_gap_max_epochs`` epochs; after the gap the
   accumulated delta range is reset (new integer offset, loss-of-lock bit set) with
   probability ``p_gap_reset``, else it simply continues (same integer ambiguity, no flag).
5. **Half cycles**: with probability ``p_half`` a new arc starts with the half-cycle
   ambiguity unresolved: phase ``+ 0.5`` cycle and LLI bit 1 for ``U(2, half_max_s)``
   seconds; then the receiver resolves it (the half cycle is removed, the bit cleared).
6. **Phase-code inconsistency**: at a rate ``drift_rate_per_h`` per series a silent phase
   drift (rate ``U(1, 3)`` cm/s of either sign, ``U(5, 20)`` s, no flag) ends in an ADR
   reset with loss of lock; at a rate ``nlos_rate_per_h`` a code burst (``U(10, 40)`` m,
   ``U(2, 8)`` epochs, silent) models a reflected (NLOS) signal.
7. **Doppler**: white noise ``σ_D(C/N0) = σ_D0 10^((C/N0_0 - C/N0)/20)`` (m/s, written in Hz).

The returned batch carries the model's σ per measurement in ``code_sigma_m`` and
``phase_sigma_cyc`` (what a phone reports as ``ReceivedSvTimeUncertaintyNanos`` and
``AccumulatedDeltaRangeUncertaintyMeters``); RINEX 3 has no field for them, so a RINEX
output keeps only the C/N0 they derive from.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field, fields, replace

import numpy as np

from robustrtk.core import FloatArray, InputError, ObsBatch

__all__ = [
    "EVENT_COLUMNS",
    "PHONE_SIGNALS",
    "PhoneEvent",
    "PhoneProfile",
    "PhoneResult",
    "parse_params",
    "phone_profile",
    "phone_profile_file",
]

#: Signals a phone tracks, per system and band, in order of preference (RINEX 3 band +
#: attribute); the first present in the input is kept.
PHONE_SIGNALS: dict[str, tuple[tuple[str, ...], ...]] = {
    "G": (("1C",), ("5Q", "5X", "5I")),
    "J": (("1C",), ("5Q", "5X", "5I")),
    "E": (("1C", "1X", "1B"), ("5Q", "5X", "5I")),
    "C": (("2I", "2X"), ("5P", "5X", "5D")),
    "R": (("1C",),),
}


@dataclass(frozen=True)
class PhoneProfile:
    """Parameters of the phone model (see the module docstring for the equations).

    Attributes
    ----------
    cn0_loss_l1_db, cn0_loss_l5_db : float
        C/N0 loss of a phone's antenna and front end on band 1 and band 5 (dB).
    cn0_walk_db, cn0_tau_s : float
        σ (dB) and correlation time (s) of the Gauss-Markov C/N0 fluctuation.
    track_min_dbhz, phase_min_dbhz : float
        C/N0 below which nothing / no carrier phase is tracked (dB-Hz).
    cn0_ref_dbhz : float
        ``C/N0_0`` of the noise models (dB-Hz).
    code_sigma_m : float
        ``σ_P0``: code σ at ``cn0_ref_dbhz`` on band 1 (m).
    code_l5_factor : float
        ``f_b`` on band 5 (wider band, sharper correlation peak).
    multipath_ratio, multipath_tau_s : float
        ``m`` and ``τ_mp`` of the code multipath.
    phase_sigma_m : float
        ``σ_φ0`` (m).
    doppler_sigma_m_s : float
        ``σ_D0`` (m/s).
    duty_on_s : float
        Mean length of a continuous carrier-phase arc (s); 0 disables duty cycling.
    duty_gap_max_epochs : int
        Longest duty-cycle gap (epochs); lengths are uniform in 1..this.
    p_gap_reset : float
        Probability that the ADR is reset (with loss of lock) after a gap.
    p_half : float
        Probability that a new arc starts half-cycle ambiguous.
    half_max_s : float
        Longest time to half-cycle resolution (s).
    drift_rate_per_h, nlos_rate_per_h : float
        Rates of silent phase drifts and of NLOS code bursts per series and hour.
    """

    cn0_loss_l1_db: float = 8.0
    cn0_loss_l5_db: float = 10.0
    cn0_walk_db: float = 2.0
    cn0_tau_s: float = 30.0
    track_min_dbhz: float = 18.0
    phase_min_dbhz: float = 24.0
    cn0_ref_dbhz: float = 45.0
    code_sigma_m: float = 0.6
    code_l5_factor: float = 0.5
    multipath_ratio: float = 1.0
    multipath_tau_s: float = 15.0
    phase_sigma_m: float = 0.0015
    doppler_sigma_m_s: float = 0.02
    duty_on_s: float = 30.0
    duty_gap_max_epochs: int = 3
    p_gap_reset: float = 0.5
    p_half: float = 0.3
    half_max_s: float = 8.0
    drift_rate_per_h: float = 2.0
    nlos_rate_per_h: float = 4.0

    def updated(self, **kw: float) -> PhoneProfile:
        """A copy with the given parameters changed (names as the attributes)."""
        names = {f.name: f for f in fields(self)}
        clean: dict[str, float | int] = {}
        for k, v in kw.items():
            if k not in names:
                raise InputError(
                    f"phone profile: unknown parameter {k!r}; expected one of {', '.join(names)}"
                )
            clean[k] = int(v) if names[k].type in ("int", int) else float(v)
        return replace(self, **clean)  # type: ignore[arg-type]

    def validate(self) -> PhoneProfile:
        """Refuse negative σ, probabilities outside [0, 1] and the like."""
        for f in fields(self):
            v = getattr(self, f.name)
            if not math.isfinite(v):
                raise InputError(f"phone profile: {f.name} must be finite, got {v!r}")
            if f.name.startswith("p_") and not 0.0 <= v <= 1.0:
                raise InputError(f"phone profile: {f.name} is a probability, expected 0..1, got {v!r}")
            if f.name not in ("cn0_loss_l1_db", "cn0_loss_l5_db") and v < 0:
                raise InputError(f"phone profile: {f.name} must be >= 0, got {v!r}")
        if self.duty_gap_max_epochs < 1:
            raise InputError("phone profile: duty_gap_max_epochs must be >= 1")
        return self


@dataclass(frozen=True)
class PhoneEvent:
    """One discrete event drawn by the profile (``kind``: ``gap``, ``reset``, ``half``,
    ``drift``, ``nlos``, ``lost``), from epoch ``start`` for ``epochs`` epochs; ``value``
    is its size (drift m/s, NLOS m, gap/half epochs; 0 otherwise)."""

    tx: str
    signal: str
    kind: str
    start: int
    epochs: int
    value: float = 0.0


@dataclass
class PhoneResult:
    """The phone-like batch and the events drawn."""

    batch: ObsBatch
    events: list[PhoneEvent] = field(default_factory=list)


def _keep_signals(batch: ObsBatch) -> tuple[list[int], list[int]]:
    """(kept signal indices, their band numbers 1 or 5) over the whole batch: per system
    and band the first preferred signal present; a signal kept for one system but absent
    for another is masked there by :func:`phone_profile`."""
    keep: set[int] = set()
    sys_arr = np.asarray(batch.system)
    for s, bands in PHONE_SIGNALS.items():
        rows = np.flatnonzero(sys_arr == s)
        if rows.size == 0:
            continue
        for prefs in bands:
            for sig in prefs:
                if sig in batch.signals:
                    k = batch.signals.index(sig)
                    if (
                        np.isfinite(batch.code_m[:, rows, k]).any()
                        or np.isfinite(batch.phase_cyc[:, rows, k]).any()
                    ):
                        keep.add(k)
                        break
    idx = sorted(keep)
    return idx, [5 if batch.signals[k][0] == "5" else 1 for k in idx]


def _gauss_markov(rng: np.random.Generator, t_s: FloatArray, sigma: float, tau_s: float) -> FloatArray:
    """First-order Gauss-Markov sequence of stationary σ ``sigma`` and correlation time
    ``tau_s`` at the times ``t_s`` (shape (T,))."""
    n = t_s.size
    out = np.zeros(n)
    if n == 0 or sigma == 0:
        return out
    eta = rng.standard_normal(n)
    out[0] = sigma * eta[0]
    dt = np.diff(t_s)
    a = np.exp(-dt / tau_s) if tau_s > 0 else np.zeros(n - 1)
    for i in range(1, n):
        out[i] = a[i - 1] * out[i - 1] + math.sqrt(1.0 - a[i - 1] ** 2) * sigma * eta[i]
    return out


def _allowed(system: str, signal: str) -> bool:
    return any(signal in prefs for prefs in PHONE_SIGNALS.get(system, ()))


def phone_profile(batch: ObsBatch, profile: PhoneProfile | None = None, *, seed: int = 0) -> PhoneResult:
    """Degrade a receiver's observations into phone-like ones (module docstring).

    Parameters
    ----------
    batch : ObsBatch
        Observations of a real receiver, shape (T, N, K).
    profile : PhoneProfile, optional
        Model parameters (defaults: :class:`PhoneProfile`).
    seed : int
        Seed; the same seed and input give the same output.

    Returns
    -------
    PhoneResult
        ``batch``: shape (T, N, K') with only phone signals, ``code_sigma_m`` and
        ``phase_sigma_cyc`` set; ``events``: every gap, reset, half-cycle period, drift,
        NLOS burst and loss of track.

    Raises
    ------
    InputError
        No phone signal in the input, invalid profile.
    """
    prof = (profile or PhoneProfile()).validate()
    kept, bands = _keep_signals(batch)
    if not kept:
        raise InputError(
            "phone profile: the input has none of the signals phones track (L1/E1/B1I, L5/E5a/B2a)"
        )
    T = len(batch)
    N = len(batch.tx_ids)
    K = len(kept)
    t = np.asarray(batch.t_s, float)
    dt_med = float(np.median(np.diff(t))) if T > 1 else 1.0
    code = batch.code_m[:, :, kept].copy()
    phase = batch.phase_cyc[:, :, kept].copy()
    dop = batch.doppler_hz[:, :, kept].copy()
    cn0_in = batch.cn0_dbhz[:, :, kept]
    lli = np.zeros((T, N, K), dtype=np.int8)
    cn0 = np.full((T, N, K), np.nan)
    sig_code = np.full((T, N, K), np.nan)
    sig_phase = np.full((T, N, K), np.nan)
    wl = batch.wavelength_m[:, kept]
    signals = tuple(batch.signals[k] for k in kept)
    events: list[PhoneEvent] = []
    for n, tx in enumerate(batch.tx_ids):
        system = batch.system[n]
        for j, sig in enumerate(signals):
            has = np.isfinite(code[:, n, j]) | np.isfinite(phase[:, n, j])
            if not _allowed(system, sig) or not has.any():
                code[:, n, j] = phase[:, n, j] = dop[:, n, j] = np.nan
                continue
            rng = np.random.default_rng([seed, zlib.crc32(f"{tx}:{sig}".encode())])
            loss = prof.cn0_loss_l5_db if bands[j] == 5 else prof.cn0_loss_l1_db
            c_in = np.where(np.isfinite(cn0_in[:, n, j]), cn0_in[:, n, j], prof.cn0_ref_dbhz)
            c = c_in - loss + _gauss_markov(rng, t, prof.cn0_walk_db, prof.cn0_tau_s)
            tracked = has & (c >= prof.track_min_dbhz)
            lost = has & ~tracked
            if lost.any():
                events.append(PhoneEvent(tx, sig, "lost", int(np.flatnonzero(lost)[0]), int(lost.sum())))
            scale = 10.0 ** ((prof.cn0_ref_dbhz - c) / 20.0)
            f_b = prof.code_l5_factor if bands[j] == 5 else 1.0
            s_code = prof.code_sigma_m * f_b * scale
            mp = _gauss_markov(rng, t, 1.0, prof.multipath_tau_s) * prof.multipath_ratio * s_code
            white = rng.standard_normal(T) * s_code
            code_new = code[:, n, j] + white + mp
            lam = float(wl[n, j])
            s_ph_m = prof.phase_sigma_m * scale
            ph_new = phase[:, n, j] + rng.standard_normal(T) * s_ph_m / lam
            dop_new = dop[:, n, j] + rng.standard_normal(T) * prof.doppler_sigma_m_s * scale / lam
            # NLOS code bursts
            nlos_p = prof.nlos_rate_per_h * dt_med / 3600.0
            for e in np.flatnonzero(rng.random(T) < nlos_p):
                length = int(rng.integers(2, 9))
                size = float(rng.uniform(10.0, 40.0))
                code_new[e : e + length] += size
                events.append(PhoneEvent(tx, sig, "nlos", int(e), min(length, T - int(e)), size))
            # carrier phase: arcs, duty-cycle gaps, resets, half cycles, drifts
            ph_ok = tracked & np.isfinite(ph_new) & (c >= prof.phase_min_dbhz) & math.isfinite(lam)
            ph_out = np.full(T, np.nan)
            flags = np.zeros(T, dtype=np.int8)
            offset = 0.0
            in_arc = False  # an ADR arc runs (also through a duty-cycle gap without reset)
            any_phase = False
            gap_left = 0
            on_left = rng.exponential(prof.duty_on_s) if prof.duty_on_s > 0 else math.inf
            half_left = 0.0
            drift_rate_m_s = 0.0
            drift_left = 0
            drift_acc_m = 0.0
            drift_p = prof.drift_rate_per_h * dt_med / 3600.0
            for i in range(T):
                dti = float(t[i] - t[i - 1]) if i > 0 else dt_med
                if gap_left > 0:
                    gap_left -= 1
                    continue
                if not ph_ok[i]:
                    in_arc = False  # lost the carrier: the ADR restarts
                    continue
                if not in_arc:  # a new ADR arc: arbitrary integer start, loss of lock
                    offset = float(rng.integers(-50_000, 50_000))
                    if any_phase:
                        flags[i] |= 1
                    half_left = (
                        float(rng.uniform(2.0, prof.half_max_s)) if rng.random() < prof.p_half else 0.0
                    )
                    if half_left > 0:
                        events.append(PhoneEvent(tx, sig, "half", i, int(math.ceil(half_left / dt_med))))
                    drift_left, drift_acc_m = 0, 0.0
                    in_arc = True
                if drift_left == 0 and rng.random() < drift_p:
                    drift_left = int(rng.integers(5, 21))
                    drift_rate_m_s = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.01, 0.03))
                    events.append(PhoneEvent(tx, sig, "drift", i, min(drift_left, T - i), drift_rate_m_s))
                if drift_left > 0:
                    drift_acc_m += drift_rate_m_s * dti
                    drift_left -= 1
                    if drift_left == 0:
                        in_arc = False  # the tracking loop gives up: ADR reset next epoch
                val = ph_new[i] + offset + drift_acc_m / lam
                if half_left > 0:
                    val += 0.5
                    flags[i] |= 2
                    half_left -= dti
                ph_out[i] = val
                any_phase = True
                if not in_arc:
                    continue
                on_left -= dti
                if on_left <= 0:
                    gap_left = int(rng.integers(1, prof.duty_gap_max_epochs + 1))
                    reset = bool(rng.random() < prof.p_gap_reset)
                    if i + 1 < T:
                        events.append(
                            PhoneEvent(tx, sig, "reset" if reset else "gap", i + 1, min(gap_left, T - i - 1))
                        )
                    in_arc = not reset
                    on_left = rng.exponential(prof.duty_on_s)
            code[:, n, j] = np.where(tracked, code_new, np.nan)
            phase[:, n, j] = ph_out
            dop[:, n, j] = np.where(tracked, dop_new, np.nan)
            cn0[:, n, j] = np.where(tracked, np.round(c, 3), np.nan)
            lli[:, n, j] = np.where(np.isfinite(ph_out), flags, 0)
            sig_code[:, n, j] = np.where(tracked, s_code * math.sqrt(1.0 + prof.multipath_ratio**2), np.nan)
            sig_phase[:, n, j] = np.where(np.isfinite(ph_out), s_ph_m / lam, np.nan)
    meta = dict(batch.meta)
    meta["phone_profile"] = {"seed": seed, **{f.name: getattr(prof, f.name) for f in fields(prof)}}
    out = ObsBatch(
        t_s=t.copy(),
        tx_ids=batch.tx_ids,
        system=batch.system,
        signals=signals,
        code_m=code,
        phase_cyc=phase,
        doppler_hz=dop,
        cn0_dbhz=cn0,
        lli=lli,
        wavelength_m=wl.copy(),
        receiver=batch.receiver,
        approx_pos_m=None if batch.approx_pos_m is None else np.asarray(batch.approx_pos_m).copy(),
        meta=meta,
        code_sigma_m=sig_code,
        phase_sigma_cyc=sig_phase,
    )
    return PhoneResult(out, events)


#: Columns of the event log written by :func:`phone_profile_file`.
EVENT_COLUMNS = ("tx", "signal", "kind", "start_epoch", "epochs", "value")


def parse_params(items: tuple[str, ...] | list[str]) -> dict[str, float]:
    """``["p_half=0.5", "duty_on_s=10"]`` -> ``{"p_half": 0.5, "duty_on_s": 10.0}``.

    Raises
    ------
    InputError
        An item that is not ``NAME=NUMBER``.
    """
    out: dict[str, float] = {}
    for item in items:
        name, eq, val = item.partition("=")
        try:
            if not eq:
                raise ValueError
            out[name.strip()] = float(val)
        except ValueError:
            raise InputError(f"--phone-param {item!r}: expected NAME=NUMBER, e.g. p_half=0.3") from None
    return out


def phone_profile_file(
    obs_path: str,
    out_path: str,
    profile: PhoneProfile | None = None,
    *,
    seed: int = 0,
    log_path: str | None = None,
) -> tuple[PhoneResult, dict[str, int]]:
    """Read ``obs_path`` (any observation format :func:`~robustrtk.io.readers.read_observations`
    takes), write its phone profile as RINEX 3.04 to ``out_path`` and the event log (CSV,
    :data:`EVENT_COLUMNS`, default ``out_path + ".phone.csv"``), both atomically.

    Returns
    -------
    result : PhoneResult
    stats : dict
        The RINEX writer's counts.
    """
    import csv
    from pathlib import Path

    from robustrtk.io.atomic import atomic_path
    from robustrtk.io.readers import read_observations
    from robustrtk.io.rinex_write import rinex_obs_text

    log = log_path if log_path is not None else out_path + ".phone.csv"
    if Path(out_path).resolve() == Path(obs_path).resolve():
        raise InputError("--out must differ from the input file (the input is never overwritten)", out_path)
    if Path(log).resolve() in (Path(out_path).resolve(), Path(obs_path).resolve()):
        raise InputError("--log must differ from the input and output files", log)
    batch = read_observations(obs_path)
    if len(batch) == 0:
        raise InputError("no epochs with observations", obs_path)
    res = phone_profile(batch, profile, seed=seed)
    text, stats = rinex_obs_text(res.batch)
    with atomic_path(out_path) as tmp_out:
        with atomic_path(log) as tmp_log:
            with open(tmp_out, "w", encoding="ascii", newline="\n") as fo:
                fo.write(text)
            with open(tmp_log, "w", newline="", encoding="ascii") as fh:
                w = csv.writer(fh)
                w.writerow(EVENT_COLUMNS)
                for ev in res.events:
                    w.writerow([ev.tx, ev.signal, ev.kind, ev.start, ev.epochs, repr(ev.value)])
    return res, stats
