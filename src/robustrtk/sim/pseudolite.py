"""Indoor pseudolite observation simulator (base + rover, code + carrier phase).

For receiver r, transmitter s and epoch k (all vectorised over epochs)::

    code_m[k]    = rho_r^s[k] + c dt_r[k] - c dt^s[k] + m_r^s[k] + e_r^s[k] + g_r^s[k]
    phase_cyc[k] = (rho_r^s[k] + c dt_r[k] - c dt^s[k] + mu_r^s[k] + eps_r^s[k] + h_r^s[k])
                   / lambda + N_r^s + phi_r + phi^s + S_r^s[k]

``rho`` geometric range, ``dt_r`` / ``dt^s`` receiver / transmitter clocks (each a
random-walk-drift oscillator; the transmitter clock is the same in both receivers' data at
one epoch), ``m`` / ``mu`` Gauss-Markov code / phase multipath, ``e`` / ``eps`` white
noise, ``g`` / ``h`` injected gross errors (m), ``N`` integer ambiguity, ``phi_r`` /
``phi^s`` fractional initial phases of receiver and transmitter, ``S`` cumulative cycle
slips. The double difference (rover - base, s - reference) cancels both clocks and both
fractional phases::

    DD phase * lambda = DD rho + lambda DD(N + S) + DD(mu + eps + h)
    DD code           = DD rho + DD(m + e + g)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.signal import lfilter

from robustrtk.core import CLIGHT, FloatArray, InputError, ObsBatch
from robustrtk.io.site import Site
from robustrtk.sim.scenario import RECEIVERS, Scenario, Trajectory


@dataclass(frozen=True)
class FaultTable:
    """Injected faults, one row per (epoch, receiver, transmitter, observable, source).

    ``kind`` is ``"gross"`` (``size`` in metres added to the observable; for phase the
    cycles added are ``size / wavelength``) or ``"slip"`` (``size`` integer cycles added to
    the phase from that epoch on). ``source`` is ``scheduled``, ``random_gross``, ``burst``
    or ``slip``.
    """

    epoch: npt.NDArray[np.int64]
    time_s: FloatArray
    receiver: tuple[str, ...]
    transmitter: tuple[str, ...]
    observable: tuple[str, ...]
    kind: tuple[str, ...]
    size: FloatArray
    unit: tuple[str, ...]
    source: tuple[str, ...]

    def __len__(self) -> int:
        return int(self.epoch.shape[0])


@dataclass(frozen=True)
class SimResult:
    """Output of :func:`simulate`.

    Attributes
    ----------
    scenario : Scenario
        The scenario simulated (with ``n_epochs`` as run).
    site : Site
        Site description (transmitters, base, rover initial position with its error).
    t_s : ndarray, shape (T,)
    tx_ids : tuple of str, length N
    truth_pos_m : ndarray, shape (T, 3)
        True rover antenna positions (m).
    batches : dict of str to ObsBatch
        ``"base"`` and ``"rover"`` observations, ``(T, N, 1)``.
    dd_ambiguity_cyc : ndarray of int64, shape (T, N)
        True DD ambiguity (rover - base, transmitter - reference) including slips; 0 in the
        reference column.
    faults : FaultTable
    """

    scenario: Scenario
    site: Site
    t_s: FloatArray
    tx_ids: tuple[str, ...]
    truth_pos_m: FloatArray
    batches: dict[str, ObsBatch]
    dd_ambiguity_cyc: npt.NDArray[np.int64]
    faults: FaultTable
    meta: dict[str, object] = field(default_factory=dict)


# --------------------------------------------------------------------------------------
# building blocks
# --------------------------------------------------------------------------------------


def trajectory_m(tr: Trajectory, t_s: FloatArray, rng: np.random.Generator) -> FloatArray:
    """Rover positions ``(T, 3)`` (m) along the trajectory at times ``t_s``.

    rail: ``p(t) = start + u s(t)``, ``s = min(v t, L)`` (one pass) or the triangle wave
    of period ``2L`` (back and forth). free: ``x(t) = c_x + h_x sum_i a_i sin(w_i t +
    phi_i)`` with ``sum a_i = 1`` (so the curve stays in the box), likewise for y, with
    ``w_i ~ v / h * U(0.5, 1.5)``.
    """
    T = t_s.shape[0]
    start = np.asarray(tr.start_m, dtype=float)
    if tr.kind == "static":
        return np.broadcast_to(start, (T, 3)).copy()
    if tr.kind == "rail":
        assert tr.end_m is not None
        d = np.asarray(tr.end_m, dtype=float) - start
        length = float(np.linalg.norm(d))
        if length == 0.0:
            return np.broadcast_to(start, (T, 3)).copy()
        s = tr.speed_m_s * (t_s - t_s[0])
        if tr.rail_mode == "one_pass":
            s = np.minimum(s, length)
        else:
            s = length - np.abs(np.mod(s, 2 * length) - length)
        return start + (s / length)[:, None] * d
    # free drive
    x0, x1, y0, y1 = tr.area_m
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    half = np.array([(x1 - x0) / 2, (y1 - y0) / 2])
    n_harm = 3
    a = rng.dirichlet(np.ones(n_harm), size=2)  # (2, n_harm), rows sum to 1
    w = tr.speed_m_s / half[:, None] * rng.uniform(0.5, 1.5, size=(2, n_harm))
    ph = rng.uniform(0, 2 * np.pi, size=(2, n_harm))
    xy = centre + half * np.einsum(
        "ah,tah->ta", a, np.sin(w[None] * (t_s - t_s[0])[:, None, None] + ph[None])
    )
    return np.column_stack([xy, np.full(T, start[2])])


def clock_m(
    n: int,
    t_s: FloatArray,
    offset_s: float,
    drift_s_s: float,
    rw: float,
    rng: np.random.Generator,
) -> FloatArray:
    """Clock offsets times c ``(n, T)`` (m).

    ``b_0 ~ U(-offset, offset)``, ``d_0 ~ U(-drift, drift)``,
    ``d_k = d_{k-1} + rw sqrt(dt) w_k``, ``b_k = b_{k-1} + d_{k-1} dt``.
    """
    T = t_s.shape[0]
    b0 = rng.uniform(-offset_s, offset_s, size=n)
    d0 = rng.uniform(-drift_s_s, drift_s_s, size=n)
    dt = np.diff(t_s)
    w = rng.standard_normal((n, max(T - 1, 0)))
    drift = np.concatenate([d0[:, None], d0[:, None] + np.cumsum(rw * np.sqrt(dt) * w, axis=1)], axis=1)
    bias = np.concatenate([b0[:, None], b0[:, None] + np.cumsum(drift[:, :-1] * dt, axis=1)], axis=1)
    return CLIGHT * bias


def gauss_markov(
    shape: tuple[int, ...], sigma: float, tau_s: float, dt_s: float, rng: np.random.Generator
) -> FloatArray:
    """Stationary first-order Gauss-Markov sequences along axis 0, shape ``shape``.

    ``x_0 ~ N(0, sigma^2)``, ``x_k = a x_{k-1} + sqrt(1 - a^2) sigma w_k``,
    ``a = exp(-dt / tau)``.
    """
    w = rng.standard_normal(shape)
    if sigma == 0.0 or shape[0] == 0:
        return np.zeros(shape)
    a = float(np.exp(-dt_s / tau_s))
    e = np.sqrt(1.0 - a * a) * sigma * w
    e[0] = sigma * w[0]
    return np.asarray(lfilter([1.0], [1.0, -a], e, axis=0), dtype=float)


class _Faults:
    """Accumulates fault arrays and table rows."""

    def __init__(self, T: int, N: int):
        self.code_m = {r: np.zeros((T, N)) for r in RECEIVERS}
        self.phase_m = {r: np.zeros((T, N)) for r in RECEIVERS}
        self.slip_cyc = {r: np.zeros((T, N), dtype=np.int64) for r in RECEIVERS}
        self.lli = {r: np.zeros((T, N), dtype=np.int8) for r in RECEIVERS}
        self.rows: list[tuple[np.ndarray, str, np.ndarray, str, str, np.ndarray, str]] = []

    def gross(self, rx: str, obs: str, ep: np.ndarray, tx: np.ndarray, size: np.ndarray, source: str) -> None:
        if ep.size == 0:
            return
        target = self.code_m[rx] if obs == "code" else self.phase_m[rx]
        np.add.at(target, (ep, tx), size)
        self.rows.append((ep, rx, tx, obs, "gross", size.astype(float), source))

    def slip(self, rx: str, ep: np.ndarray, tx: np.ndarray, cyc: np.ndarray, silent: np.ndarray) -> None:
        if ep.size == 0:
            return
        np.add.at(self.slip_cyc[rx], (ep, tx), cyc)
        self.lli[rx][ep[~silent], tx[~silent]] |= 1
        self.rows.append((ep, rx, tx, "phase", "slip", cyc.astype(float), "slip"))

    def table(self, t_s: FloatArray, tx_ids: tuple[str, ...]) -> FaultTable:
        if not self.rows:
            e = np.zeros(0, dtype=np.int64)
            return FaultTable(e, np.zeros(0), (), (), (), (), np.zeros(0), (), ())
        ep = np.concatenate([r[0] for r in self.rows]).astype(np.int64)
        rx = np.concatenate([np.full(r[0].size, r[1], dtype=object) for r in self.rows])
        tx = np.concatenate([r[2] for r in self.rows]).astype(np.int64)
        obs = np.concatenate([np.full(r[0].size, r[3], dtype=object) for r in self.rows])
        kind = np.concatenate([np.full(r[0].size, r[4], dtype=object) for r in self.rows])
        size = np.concatenate([r[5] for r in self.rows])
        src = np.concatenate([np.full(r[0].size, r[6], dtype=object) for r in self.rows])
        rx_i = np.array([RECEIVERS.index(r) for r in rx], dtype=np.int64)
        order = np.lexsort((tx, rx_i, ep))
        unit = np.where(kind == "slip", "cyc", "m")
        tx_names = np.asarray(tx_ids, dtype=object)[tx]
        return FaultTable(
            epoch=ep[order],
            time_s=t_s[ep[order]],
            receiver=tuple(rx[order].tolist()),
            transmitter=tuple(tx_names[order].tolist()),
            observable=tuple(obs[order].tolist()),
            kind=tuple(kind[order].tolist()),
            size=size[order],
            unit=tuple(unit[order].tolist()),
            source=tuple(src[order].tolist()),
        )


def _bursts(f: _Faults, sc: Scenario, T: int, tx_ids: tuple[str, ...], rng: np.random.Generator) -> None:
    b = sc.bursts
    non_ref = np.array([i for i, t in enumerate(tx_ids) if t != sc.reference], dtype=np.int64)
    if b.weights:
        wmap = dict(b.weights)
        p = np.array([wmap.get(tx_ids[i], 0.0) for i in non_ref], dtype=float)
    else:
        p = np.ones(non_ref.size)
    p = p / p.sum()
    for obs in ("code", "phase"):
        prob = getattr(b, f"{obs}_probability")
        lo, hi = getattr(b, f"{obs}_length_epochs")
        smin, smax = getattr(b, f"{obs}_size_m")
        start_mask = rng.random(T) < prob
        starts = np.flatnonzero(start_mask)
        nb = starts.size
        length = rng.integers(lo, hi + 1, size=nb)
        size = rng.uniform(smin, smax, size=nb) * rng.choice([-1.0, 1.0], size=nb)
        tx = non_ref[rng.choice(non_ref.size, size=nb, p=p)] if nb else np.zeros(0, np.int64)
        if nb == 0:
            continue
        burst = np.repeat(np.arange(nb), length)
        offset = np.arange(burst.size) - np.repeat(np.cumsum(length) - length, length)
        ep = starts[burst] + offset
        keep = ep < T
        f.gross(b.receiver, obs, ep[keep], tx[burst][keep], size[burst][keep], "burst")


def _random_gross(
    f: _Faults, sc: Scenario, T: int, tx_ids: tuple[str, ...], rng: np.random.Generator
) -> None:
    non_ref = np.array([i for i, t in enumerate(tx_ids) if t != sc.reference], dtype=np.int64)
    for rg in sc.random_gross:
        n = min(rg.count, T)
        ep = np.sort(rng.choice(T, size=n, replace=False)) if n else np.zeros(0, np.int64)
        tx = non_ref[rng.integers(0, non_ref.size, size=n)]
        sign = rng.choice([-1.0, 1.0], size=n) if rg.random_sign else np.ones(n)
        f.gross(rg.receiver, rg.observable, ep.astype(np.int64), tx, rg.size_m * sign, "random_gross")


def _slips(f: _Faults, sc: Scenario, T: int, tx_ids: tuple[str, ...], rng: np.random.Generator) -> None:
    sl = sc.slips
    N = len(tx_ids)
    for rx in RECEIVERS:
        u = rng.random((T, N))
        mag = rng.integers(1, sl.max_cycles + 1, size=(T, N))
        sign = np.where(rng.random((T, N)) < 0.5, -1, 1)
        if rx not in sl.receivers or sl.probability <= 0:
            continue
        hit = u < sl.probability
        hit[0] = False  # a slip at the first epoch is indistinguishable from an ambiguity
        ep, tx = np.nonzero(hit)
        f.slip(rx, ep, tx, (mag * sign)[ep, tx], np.full(ep.size, sl.silent))
    for s in sc.slips.scheduled:
        if s.epoch >= T:
            continue
        f.slip(
            s.receiver,
            np.array([s.epoch]),
            np.array([tx_ids.index(s.transmitter)]),
            np.array([s.cycles]),
            np.array([s.silent]),
        )


# --------------------------------------------------------------------------------------
# the simulator
# --------------------------------------------------------------------------------------


def simulate(scenario: Scenario, rng: np.random.Generator, n_epochs: int | None = None) -> SimResult:
    """Simulate base and rover pseudolite observations for ``scenario``.

    Parameters
    ----------
    scenario : Scenario
    rng : numpy.random.Generator
        The only source of randomness. Independent child streams are spawned in a fixed
        order (clocks, ambiguities, trajectory, noise, multipath, SNR, slips, bursts, random
        gross errors), so switching a fault family on or off leaves every other stream --
        and therefore the fault-free observations -- unchanged.
    n_epochs : int, optional
        Override ``scenario.n_epochs`` (shorter runs for tests); scheduled faults beyond the
        last epoch are dropped.

    Returns
    -------
    SimResult
    """
    import dataclasses

    T = scenario.n_epochs if n_epochs is None else int(n_epochs)
    if T < 1:
        raise InputError(f"--epochs: expected a positive number of epochs, got {T}")
    if T != scenario.n_epochs:
        scenario = dataclasses.replace(
            scenario,
            n_epochs=T,
            gross=tuple(
                dataclasses.replace(g, epochs=tuple(e for e in g.epochs if e < T)) for g in scenario.gross
            ),
            slips=dataclasses.replace(
                scenario.slips,
                scheduled=tuple(s for s in scenario.slips.scheduled if s.epoch < T),
            ),
        )
    (g_clk, g_amb, g_traj, g_noise, g_mp, g_snr, g_slip, g_burst, g_gross, g_init) = rng.spawn(10)

    lam = scenario.wavelength_m
    dt = scenario.interval_s
    t_s = np.arange(T) * dt
    tx_ids = scenario.tx_ids
    N = len(tx_ids)
    tx_map = dict(scenario.transmitters)
    tx_pos = np.array([tx_map[t] for t in tx_ids], dtype=float)  # (N, 3)
    ref = tx_ids.index(scenario.reference)

    rover = trajectory_m(scenario.trajectory, t_s, g_traj)
    base = np.broadcast_to(np.asarray(scenario.base_position_m, float), (T, 3))
    pos = {"base": base, "rover": rover}

    ck = scenario.clocks
    rx_clk = clock_m(
        2, t_s, ck.receiver_offset_s, ck.receiver_drift_s_s, ck.drift_rw_s_s_sqrt_s, g_clk
    )  # (2, T)
    tx_clk = clock_m(
        N, t_s, ck.transmitter_offset_s, ck.transmitter_drift_s_s, ck.drift_rw_s_s_sqrt_s, g_clk
    )  # (N, T)

    amax = scenario.ambiguity_max_cyc
    amb = g_amb.integers(-amax, amax + 1, size=(2, N))
    frac_rx = g_amb.random(2)
    frac_tx = g_amb.random(N)

    faults = _Faults(T, N)
    _slips(faults, scenario, T, tx_ids, g_slip)
    _bursts(faults, scenario, T, tx_ids, g_burst)
    _random_gross(faults, scenario, T, tx_ids, g_gross)
    for g in scenario.gross:
        ep = np.asarray(g.epochs, dtype=np.int64)
        faults.gross(
            g.receiver,
            g.observable,
            ep,
            np.full(ep.size, tx_ids.index(g.transmitter)),
            np.full(ep.size, g.size_m),
            "scheduled",
        )

    batches: dict[str, ObsBatch] = {}
    slips_cum: dict[str, npt.NDArray[np.int64]] = {}
    for r, rx in enumerate(RECEIVERS):
        nz = scenario.noise_of(rx)
        rho = np.linalg.norm(tx_pos[None, :, :] - pos[rx][:, None, :], axis=2)  # (T, N)
        clocks = rx_clk[r][:, None] - tx_clk.T  # (T, N)
        e_code = nz.code_sigma_m * g_noise.standard_normal((T, N))
        e_phase = nz.phase_sigma_m * g_noise.standard_normal((T, N))
        mp_on = rx in scenario.multipath.receivers
        mp = scenario.multipath
        m_code = gauss_markov((T, N), mp.code_sigma_m if mp_on else 0.0, mp.code_tau_s, dt, g_mp)
        m_phase = gauss_markov((T, N), mp.phase_sigma_m if mp_on else 0.0, mp.phase_tau_s, dt, g_mp)
        snr_mean = g_snr.uniform(*nz.snr_range_dbhz, size=N)
        snr = snr_mean + nz.snr_sigma_dbhz * g_snr.standard_normal((T, N))
        slips_cum[rx] = np.cumsum(faults.slip_cyc[rx], axis=0)

        code = rho + clocks + m_code + e_code + faults.code_m[rx]
        phase = (
            (rho + clocks + m_phase + e_phase + faults.phase_m[rx]) / lam
            + amb[r][None, :]
            + frac_rx[r]
            + frac_tx[None, :]
            + slips_cum[rx]
        )
        batches[rx] = ObsBatch(
            t_s=t_s.copy(),
            tx_ids=tx_ids,
            system=("P",) * N,
            signals=("L1",),
            code_m=code[..., None],
            phase_cyc=phase[..., None],
            doppler_hz=np.full((T, N, 1), np.nan),
            cn0_dbhz=np.round(snr, 2)[..., None],
            lli=faults.lli[rx][..., None].copy(),
            wavelength_m=np.full((N, 1), lam),
            receiver=rx,
            approx_pos_m=pos[rx][0].copy(),
            meta={"scenario": scenario.name},
        )

    n_total = (amb[1][None, :] + slips_cum["rover"]) - (amb[0][None, :] + slips_cum["base"])
    dd_amb = (n_total - n_total[:, [ref]]).astype(np.int64)

    init_err = g_init.uniform(-1.0, 1.0, size=3) * scenario.initial_position_error_m
    site = Site(
        frame="local",
        wavelength_m=lam,
        reference=scenario.reference,
        transmitters={t: tx_pos[i].copy() for i, t in enumerate(tx_ids)},
        base_pos_m=np.asarray(scenario.base_position_m, float),
        rover_initial_pos_m=rover[0] + init_err,
    )
    return SimResult(
        scenario=scenario,
        site=site,
        t_s=t_s,
        tx_ids=tx_ids,
        truth_pos_m=rover,
        batches=batches,
        dd_ambiguity_cyc=dd_amb,
        faults=faults.table(t_s, tx_ids),
    )
