"""Real-time DGNSS / RTK: epochs as they arrive, one solution per rover epoch.

:class:`StreamSolver` is the per-epoch front end in front of the one epoch loop
(:class:`~robustrtk.pipeline.loop.EpochLoop`): each rover or base epoch (all signals, as an
:class:`~robustrtk.io.epoch_source.EpochSource` yields it) becomes signal rows of the
configured slots (:func:`~robustrtk.measurement.signals.signal_rows`, the signal of each
slot chosen per epoch), runs through its receiver's online slip detector (RTK:
:func:`~robustrtk.pipeline.rtk_gnss.online_detector`, the flags of the whole-file
front end), and is paired and solved by the loop. Ephemerides may arrive any time
(:meth:`StreamSolver.on_nav`).

A rover epoch is held until the base has sent an epoch tagged at or after ``t_rover`` (a
later base epoch cannot be nearer: the pairing of
:func:`~robustrtk.pipeline.base_buffer.pair_base_epochs` is then decided), or until the
rover has run ``wait_s`` ahead of it (the base is late or lost: the epoch pairs with the
latest base epoch within ``max_age_s``, carried to its tag; beyond that age it gets its
single-point solution). Over
the same epochs this gives the solutions of the whole-file solve, except what the file
solve estimates from the whole file: the code noise from code-minus-carrier
(``code_sigma_from_data``: the stream estimates it from the epochs so far and resolves no
ambiguities until it is known, docs/algorithms.md §42) and the initial position (the
stream starts from the first rover epoch with a single-point solution).

GLONASS (FDMA) carrier phase is solved as in the file solve (:mod:`robustrtk.pipeline.rtk_gnss`,
:mod:`robustrtk.measurement.glonass`): each GLONASS row needs its satellite's frequency channel,
which the stream tells as it goes -- the wavelengths of the decoded epochs (RTCM 3 MSM5/7
extended information, 1009-1012, 1020 ephemerides; UBX RXM-RAWX ``freqId``) of either receiver,
and the GLONASS ephemerides (:meth:`StreamSolver.on_nav`, or the fixed navigation data). A row
whose channel is not known yet has no wavelength, hence no carrier phase, until it is.
``glonass_ar = auto`` fixes the GLONASS ambiguities once both receivers are known to be of one
make (:func:`~robustrtk.measurement.glonass.same_make`: :meth:`StreamSolver.set_receiver_type`,
from RTCM 1033 or a UBX stream) and keeps them float until then; the file solve decides the same
from the whole files.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from robustrtk.core import FloatArray, InputError, ObsEpoch, Solution, TransmitterSource
from robustrtk.cycleslip.online import EpochSlips, OnlineSlipDetector
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.navdata import NavData
from robustrtk.gnss import wavelength_m as carrier_wavelength_m
from robustrtk.io.epoch_source import epoch_batch
from robustrtk.io.raw_collect import merge_nav
from robustrtk.measurement.base_propagation import propagate_base_epoch
from robustrtk.measurement.code_noise import (
    MAX_CODE_SIGMA_M,
    STRETCH_S,
    OnlineCodeSigma,
    combined_code_sigma_m,
    epoch_sin_elevations,
)
from robustrtk.measurement.glonass import fill_glonass_wavelengths, same_make
from robustrtk.measurement.signals import RowSource, parse_slots, signal_rows
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.engine import DDEngine
from robustrtk.pipeline.gnss import first_fix_position
from robustrtk.pipeline.loop import EpochLoop, EventLog
from robustrtk.pipeline.results import EpochInputs
from robustrtk.pipeline.rows import row_map
from robustrtk.pipeline.rtk_gnss import RTK_SYSTEMS, online_detector
from robustrtk.pipeline.spp import select_band1, solve_spp

#: Pairing tolerance of GNSS epochs (s), that of the file solve.
TOL_S = 0.5


@dataclass(frozen=True)
class StreamStatus:
    """What the live status line shows after an epoch."""

    t_s: float
    status: str
    n_used: int
    age_s: float
    ratio: float
    held: int


def glonass_channel_of(signal: str, wavelength_m: float) -> int | None:
    """The GLONASS FDMA frequency channel (-7..6) whose ``signal`` (band 1 or 2) has the
    wavelength ``wavelength_m`` (m, to 1e-7 relative: neighbouring channels differ by
    3.5e-4), None when none has it."""
    if not signal or signal[0] not in "12" or not math.isfinite(wavelength_m):
        return None
    for ch in range(-7, 7):
        lam = carrier_wavelength_m("R", signal, ch)
        if math.isfinite(lam) and abs(lam - wavelength_m) <= 1e-7 * lam:
            return ch
    return None


def epoch_glonass_channels(epoch: ObsEpoch) -> dict[str, int]:
    """GLONASS frequency channels an epoch's wavelengths tell (satellite id -> channel; the
    decoder gave them from the stream's channel information)."""
    out: dict[str, int] = {}
    wl = np.asarray(epoch.wavelength_m, float)
    for n, (tx, system) in enumerate(zip(epoch.tx_ids, epoch.system, strict=True)):
        if system != "R":
            continue
        for k, sig in enumerate(epoch.signals):
            ch = glonass_channel_of(sig, float(wl[n, k]))
            if ch is not None:
                out[tx] = ch
                break
    return out


def _take_rows(ep: ObsEpoch, idx: list[tuple[ObsEpoch, int]]) -> ObsEpoch:
    """An epoch (tag and signals of ``ep``) of the rows ``(epoch, row)`` listed (at least one;
    the epochs have ``ep``'s signal columns)."""

    def col(name: str) -> np.ndarray | None:
        parts = [getattr(e, name) for e, _ in idx]
        if any(p is None for p in parts):
            return None
        return np.stack([np.asarray(p)[k] for p, (_, k) in zip(parts, idx, strict=True)])

    def req(name: str) -> np.ndarray:
        out = col(name)
        assert out is not None
        return out

    return ObsEpoch(
        t_s=ep.t_s, tx_ids=tuple(e.tx_ids[k] for e, k in idx), system=tuple(e.system[k] for e, k in idx),
        signals=ep.signals, code_m=req("code_m"), phase_cyc=req("phase_cyc"), doppler_hz=req("doppler_hz"),
        cn0_dbhz=req("cn0_dbhz"), lli=req("lli").astype(np.int8), wavelength_m=req("wavelength_m"),
        code_sigma_m=col("code_sigma_m"), phase_sigma_cyc=col("phase_sigma_cyc"),
    )  # fmt: skip


class BaseSystemFill:
    """The stream's :class:`~robustrtk.measurement.base_propagation.SystemFill`: a base epoch
    (signal rows, one column) lacking the phases of a system the base regularly sends gets
    that system's rows from the latest earlier epoch that had them (at most ``max_age_s``
    older), carried to its tag; the copied rows lose their loss-of-lock bit.

    *Regular* is decided from the epochs so far (the file solve decides it over the whole
    file): a system with phases in at least half of the base's epochs with any phase since
    the first that had it. Epochs without any phase are passed as they are (they do not serve).
    """

    def __init__(self, max_age_s: float) -> None:
        self.max_age_s = max_age_s
        self.last: dict[str, ObsEpoch] = {}
        self.n_any: dict[str, int] = {}
        self.n_has: dict[str, int] = {}

    def __call__(self, ep: ObsEpoch, source: TransmitterSource, pos_m: FloatArray) -> ObsEpoch:
        ph = np.isfinite(np.asarray(ep.phase_cyc, float)[:, 0]) if len(ep.tx_ids) else np.zeros(0, bool)
        if not ph.any():
            return ep
        present = {ep.system[i] for i in np.flatnonzero(ph)}
        for sy in self.n_any:
            self.n_any[sy] += 1
        for sy in present:
            if sy not in self.n_any:
                self.n_any[sy] = 1
            self.n_has[sy] = self.n_has.get(sy, 0) + 1
        fill = [
            sy for sy in sorted(self.last)
            if sy not in present and self.n_has[sy] >= 0.5 * self.n_any[sy]
            and float(ep.t_s) - float(self.last[sy].t_s) <= self.max_age_s
        ]  # fmt: skip
        for sy in present:
            self.last[sy] = ep
        if not fill:
            return ep
        rows: list[tuple[ObsEpoch, int]] = [(ep, i) for i, sy in enumerate(ep.system) if sy not in fill]
        for sy in fill:
            old = propagate_base_epoch(self.last[sy], ep.t_s, source, pos_m, sagnac=True, troposphere=True)
            old = replace(old, lli=np.asarray(old.lli) & ~np.int8(1))
            rows += [(old, i) for i, s2 in enumerate(old.system) if s2 == sy]
        order = "GRECJSI"
        rows.sort(key=lambda r: (order.find(r[0].system[r[1]]), r[0].tx_ids[r[1]]))
        return _take_rows(ep, rows)


class _Front:
    """One receiver's rows and slip detector (GLONASS wavelengths the epoch lacks from
    ``channels``, satellite id -> frequency channel, when given)."""

    def __init__(
        self,
        slots: tuple[str, ...],
        systems: str | None,
        detector: OnlineSlipDetector | None,
        channels: Mapping[str, int] | None = None,
    ) -> None:
        self.slots = slots
        self.systems = systems
        self.detector = detector
        self.channels = channels

    def __call__(self, epoch: ObsEpoch) -> EpochSlips:
        batch = signal_rows(epoch_batch(epoch), self.slots, self.systems)
        if self.channels is not None and "R" in batch.system:
            batch = fill_glonass_wavelengths(batch, self.channels)
        rows = batch.epoch(0)
        if self.detector is not None:
            return self.detector.step(rows)
        n = len(rows.tx_ids)
        return EpochSlips(rows, np.zeros(n, bool), np.zeros(n, bool))


class StreamSolver:
    """DGNSS or RTK on epochs pushed one at a time (see the module docstring).

    Parameters
    ----------
    cfg : Config
        Mode ``dgnss`` or ``rtk``.
    base_pos_m : ndarray, shape (3,), or None
        Base ECEF (m); None: set by :meth:`set_base_position` (an RTCM 1005/1006 message;
        rover epochs before it get single-point solutions), or with ``base_spp`` the
        single-point solution of the latest base epoch when the first rover epoch comes.
    nav : NavData or EphemerisSource, optional
        Fixed ephemerides (a RINEX navigation file): the stream's own ephemerides are then
        ignored.
    wait_s : float
        How far (s of rover time) a rover epoch waits for its base epoch (``inf``: until
        the base passes it or :meth:`end_base`; a replay of files as fast as possible).
    spp_fallback : bool
        A rover epoch that no base epoch serves (none yet, or the base older than
        ``max_age_s``) gets its single-point solution (status ``single``).
    """

    def __init__(
        self,
        cfg: Config,
        base_pos_m: FloatArray | None = None,
        nav: NavData | EphemerisSource | None = None,
        wait_s: float = 3.0,
        spp_fallback: bool = True,
        base_spp: bool = False,
    ) -> None:
        if cfg.mode not in ("dgnss", "rtk"):
            raise InputError(f"mode: real time runs dgnss or rtk, got {cfg.mode!r}")
        self.cfg = cfg
        g = cfg.gnss
        self.slots = parse_slots(g.freqs)
        systems = g.systems.upper() if g.systems else None
        if cfg.mode == "rtk":
            systems = systems or RTK_SYSTEMS  # GLONASS FDMA as in the file solve (module notes)
        self.systems = systems
        rtk = cfg.mode == "rtk"
        # GLONASS channels known so far: the ephemerides', the base's and the rover's epochs'
        # (the later of these wins, as the file solve's navigation data, base and rover headers)
        self.glo_nav: dict[str, int] = {}
        self.glo_obs: dict[str, dict[str, int]] = {"rover": {}, "base": {}}
        self.glo_channels: dict[str, int] = {}
        glo = rtk and (systems is None or "R" in systems)
        chans = self.glo_channels if glo else None
        self.rover_front = _Front(self.slots, systems, online_detector(cfg) if rtk else None, chans)
        self.base_front = _Front(self.slots, systems, online_detector(cfg) if rtk else None, chans)
        self.receiver_types: dict[str, str] = {"rover": "", "base": ""}
        self.fixed_nav = nav is not None
        self.eph: EphemerisSource | None = None
        if isinstance(nav, EphemerisSource):
            self.eph = nav
        elif nav is not None:
            self.eph = EphemerisSource(nav)
        if self.eph is not None:
            self._nav_channels(self.eph.nav)
        self.navs: list[NavData] = []
        self.base_pos_m = None if base_pos_m is None else np.asarray(base_pos_m, float)
        self.wait_s = wait_s
        self.spp_fallback = spp_fallback
        self.base_ended = False
        self.base_spp = base_spp
        self.base_raw_last: ObsEpoch | None = None
        self.spp_cfg: Config | None = None
        self.loop: EpochLoop | None = None
        self.held: deque[tuple[int, ObsEpoch, EpochSlips]] = deque()
        self.pending_base: deque[tuple[ObsEpoch, bool]] = deque()  # not yet in the loop
        # base epochs missing a system completed as the file solve does (RTK)
        self.base_fill = BaseSystemFill(cfg.gnss.max_age_s) if rtk and cfg.gnss.max_age_s > 0 else None
        self._current: EpochSlips | None = None
        self.det_events = EventLog()  # the base's detector slips, as events (RTK)
        self.base_half: dict[int, tuple[tuple[str, ...], np.ndarray]] = {}
        self.t_base_last = -np.inf
        self.n_rover = 0
        self.n_base = 0
        self.last: StreamStatus | None = None
        # the receivers' code σ from their code minus carrier so far (algorithms.md §42)
        m = cfg.measurement
        self.code_noise: dict[str, OnlineCodeSigma] | None = None
        self.code_sigma_m = m.code_sigma_m
        self.code_sigma_known = True
        self.code_sigma_known_t_s: float | None = None  # rover time it became known
        self.code_sigma_bounded = False  # RTK before the σ is known: integers allowed
        self.early_limit_m = 0.0  # largest bound (m) under which AR may start early (RTK)
        self.float_guard = False  # RTK: the float on the conservative σ until it is known
        self.code_sigma_usable_t_s: float | None = None  # rover time AR became possible
        self.code_sigma_data: tuple[float | None, float | None] = (None, None)
        self.t_sigma_next = -np.inf
        self.min_ratio = 1.0
        self.pos0_m: FloatArray | None = None
        if m.code_sigma_from_data and m.weighting == "elevation":
            self.code_noise = {"rover": OnlineCodeSigma(), "base": OnlineCodeSigma()}
            self.code_sigma_known = False
            from robustrtk.estimation.registry import make_robust_policy
            from robustrtk.estimation.robust import rejection_threshold

            rb = cfg.robust
            k1 = rejection_threshold(make_robust_policy(rb.policy, k0=rb.k0, k1=rb.k1))
            if rtk:  # integers before the σ is known only within a rejecting test's reach
                self.early_limit_m = k1 * m.code_sigma_m if np.isfinite(k1) else 0.0
                self.float_guard = True
                self.code_sigma_m = MAX_CODE_SIGMA_M  # nothing known of the code yet
            else:  # DGNSS: beyond the robust test's rejection threshold (§39)
                self.min_ratio = k1

    # ------------------------------------------------------------------ GLONASS
    def _nav_channels(self, nav: NavData) -> None:
        self.glo_nav = nav.glo_channels() if len(nav.glonass) else {}
        self._merge_channels()

    def _merge_channels(self) -> None:
        merged = {**self.glo_nav, **self.glo_obs["base"], **self.glo_obs["rover"]}
        if merged != self.glo_channels:
            self.glo_channels.clear()  # in place: the fronts hold this dict
            self.glo_channels.update(merged)

    def _obs_channels(self, role: str, epoch: ObsEpoch) -> None:
        if "R" not in epoch.system:
            return
        got = epoch_glonass_channels(epoch)
        known = self.glo_obs[role]
        if any(known.get(k) != v for k, v in got.items()):
            known.update(got)
            self._merge_channels()

    @property
    def glonass_ar(self) -> str:
        """The GLONASS ambiguity mode in force: ``cfg.gnss.glonass_ar``, ``auto`` read as
        ``on`` once both receivers are known to be of one make, ``off`` until then."""
        mode = self.cfg.gnss.glonass_ar
        if mode != "auto":
            return mode
        same = same_make(
            {"receiver_type": self.receiver_types["rover"]}, {"receiver_type": self.receiver_types["base"]}
        )
        return "on" if same else "off"

    def _solve_cfg(self) -> Config:
        """The configuration the loop solves with: ``glonass_ar`` resolved, the code σ the
        data show (:meth:`_update_code_sigma`), and (RTK) no ambiguity resolution while
        that σ is neither known nor bounded yet."""
        cfg = self.cfg
        if cfg.mode == "rtk" and cfg.gnss.glonass_ar == "auto":
            cfg = cfg.updated(glonass_ar=self.glonass_ar)
        if self.code_sigma_m != cfg.measurement.code_sigma_m:
            cfg = cfg.updated(code_sigma_m=self.code_sigma_m)
        if cfg.mode == "rtk" and not (self.code_sigma_known or self.code_sigma_bounded):
            cfg = cfg.updated(ar="off")
        return cfg

    def _reconfigure(self) -> None:
        """Hand :meth:`_solve_cfg` to the running loop."""
        if self.loop is not None:
            cfg = self._solve_cfg()
            self.loop.engine.cfg = cfg
            if self.loop.engine.rtk is not None:
                self.loop.engine.rtk.cfg = cfg

    def _code_rows(self, role: str, ep: ObsEpoch, pos_m: FloatArray | None) -> None:
        """One receiver's signal rows into its online code σ estimate."""
        if self.code_noise is None or self.loop is None or pos_m is None or not len(ep.tx_ids):
            return
        code = np.asarray(ep.code_m, float)[:, 0]
        sin_el = epoch_sin_elevations(self.loop.engine.source, float(ep.t_s), ep.tx_ids, code, pos_m)
        self.code_noise[role].push(
            float(ep.t_s), ep.tx_ids, code, np.asarray(ep.phase_cyc, float)[:, 0],
            np.asarray(ep.wavelength_m, float)[:, 0], np.asarray(ep.lli)[:, 0], sin_el,
        )  # fmt: skip

    def _update_code_sigma(self, t_s: float) -> None:
        """The code σ from the epochs so far, by the file solve's rule (every 10 s of rover
        time until known, every 30 s after). It is known once a receiver has an estimate
        over at least one detrending stretch (:data:`~robustrtk.measurement.code_noise.STRETCH_S`:
        a shorter record sees too little of the slow multipath and underestimates it), or
        when the data are too sparse for any (the configured σ then stands, as in the file
        solve). Before that (RTK) the float rests on the larger of the rule's σ and a
        conservative value from the records so far
        (:meth:`~robustrtk.measurement.code_noise.OnlineCodeSigma.sigma_bound_m`, the 30-m cap
        until both receivers have one), and ambiguities are resolved only while that value is
        within the robust test's reach of the configured σ (algorithms.md §42)."""
        if self.code_noise is None or t_s < self.t_sigma_next:
            return
        self.t_sigma_next = t_s + (30.0 if self.code_sigma_known else 10.0)
        rov, bas = self.code_noise["rover"], self.code_noise["base"]
        s_r, s_b = rov.sigma_m(), bas.sigma_m()
        self.code_sigma_data = (s_r, s_b)
        known = self.code_sigma_known or not (rov.possible() or bas.possible())
        known |= any(s is not None and n.span_s() >= STRETCH_S for s, n in ((s_r, rov), (s_b, bas)))
        configured = self.cfg.measurement.code_sigma_m
        sig = combined_code_sigma_m(s_r, s_b, configured, self.min_ratio)
        new = configured if sig is None else sig
        bounded = False
        if not known and self.float_guard:
            b_r, b_b = rov.sigma_bound_m(), bas.sigma_bound_m()
            bound = MAX_CODE_SIGMA_M
            if b_r is not None and b_b is not None:
                bound = min(float(np.sqrt((b_r**2 + b_b**2) / 2.0)), MAX_CODE_SIGMA_M)
            new = max(new, bound)
            bounded = bound <= self.early_limit_m
        if known and not self.code_sigma_known:
            self.code_sigma_known_t_s = t_s
        if (known or bounded) and self.code_sigma_usable_t_s is None:
            self.code_sigma_usable_t_s = t_s
        if known != self.code_sigma_known or bounded != self.code_sigma_bounded or new != self.code_sigma_m:
            self.code_sigma_known, self.code_sigma_bounded, self.code_sigma_m = known, bounded, new
            self._reconfigure()

    def set_receiver_type(self, role: str, receiver_type: str) -> None:
        """The make and model of the ``"rover"`` or ``"base"`` receiver (RTCM 1033 receiver
        descriptor, ``"u-blox"`` for a UBX stream; ``""`` unknown) for ``glonass_ar = auto``."""
        if role not in self.receiver_types:
            raise ValueError(f"role: rover or base, got {role!r}")
        text = str(receiver_type or "")
        if not text or text == self.receiver_types[role]:
            return
        self.receiver_types[role] = text
        if self.loop is not None and self.loop.engine.rtk is not None:
            self._reconfigure()

    # ------------------------------------------------------------------ inputs
    def on_nav(self, nav: NavData) -> None:
        """New ephemerides (ignored when fixed ones were given)."""
        if self.fixed_nav:
            return
        self.navs = [nav] if not self.navs else [merge_nav([*self.navs, nav])]
        self.eph = EphemerisSource(self.navs[0])
        self._nav_channels(self.navs[0])
        if self.loop is not None:
            self.loop.engine.source = RowSource(self.eph)

    def set_base_position(self, pos_m: FloatArray) -> None:
        """The base position (taken until the first rover epoch is solved)."""
        if self.loop is None:
            self.base_pos_m = np.asarray(pos_m, float)

    def on_base(self, epoch: ObsEpoch) -> list[Solution]:
        """A base epoch (the next in time); returns the held rover epochs it lets through."""
        self._obs_channels("base", epoch)
        es = self.base_front(epoch)
        b = es.epoch
        col = b.phase_cyc if self.cfg.mode == "rtk" else b.code_m
        usable = bool(np.isfinite(col[:, 0]).any()) if len(b.tx_ids) else False
        seq = self.n_base
        self.n_base += 1
        self.det_events.push(seq, b.tx_ids, es.slip)
        self.base_half[seq] = (b.tx_ids, es.half_cycle)
        if len(self.base_half) > 64:
            del self.base_half[min(self.base_half)]
        self.base_raw_last = epoch
        self.pending_base.append((b, usable))
        self.t_base_last = max(self.t_base_last, float(b.t_s))
        return self._release(force=False)

    def on_rover(self, epoch: ObsEpoch) -> list[Solution]:
        """A rover epoch; returns the rover epochs solved now (this one once its base is in)."""
        self._obs_channels("rover", epoch)
        es = self.rover_front(epoch)
        self.held.append((self.n_rover, epoch, es))
        self.n_rover += 1
        return self._release(force=False)

    def end_base(self) -> list[Solution]:
        """The base's source ended: held rover epochs need not wait for it any more."""
        self.base_ended = True
        return self._release(force=False)

    def flush(self) -> list[Solution]:
        """End of input: solve every held rover epoch with what has arrived."""
        return self._release(force=True)

    # ------------------------------------------------------------------ the loop
    def _start(self, rover: ObsEpoch) -> EpochLoop | None:
        if self.eph is None:
            return None
        mask = self.cfg.gnss.elev_mask_deg
        if self.base_pos_m is None and self.base_spp and self.base_raw_last is not None:
            try:  # no position given nor broadcast: the base's own single-point solution
                self.base_pos_m = first_fix_position(epoch_batch(self.base_raw_last), self.eph, mask)
            except InputError:
                return None
        if self.base_pos_m is None:
            return None
        try:
            pos0 = first_fix_position(epoch_batch(rover), self.eph, self.cfg.gnss.elev_mask_deg)
        except InputError:
            return None
        self.pos0_m = pos0
        from threadpoolctl import threadpool_limits  # here, not at start-up: its import is slow

        # the matrices are small: BLAS threads only contend (as in run_dd), for the whole run
        self.blas_limits = threadpool_limits(limits=1, user_api="blas")
        eng = DDEngine(
            self._solve_cfg(), RowSource(self.eph), self.base_pos_m, pos0, sagnac=True, frame="ecef",
            elev_mask_deg=self.cfg.gnss.elev_mask_deg, row_groups=True,
        )  # fmt: skip
        g = self.cfg.gnss
        build = self._build if self.cfg.mode == "rtk" else None
        return EpochLoop(eng, TOL_S, g.max_age_s, g.sigma_age_m_s, build)

    def _build(self, i: int, rover: ObsEpoch, j: int, base: ObsEpoch) -> EpochInputs:
        es = self._current
        assert es is not None
        ids = rover.tx_ids
        fb = self.det_events.since_last(j, ids, (len(ids),))
        hb = np.zeros(len(ids), bool)
        got = self.base_half.get(j)
        if got is not None:
            _, have, src = row_map(got[0], ids)
            hb[have] = got[1][src]
        return EpochInputs(rover, base, slip=es.slip | fb, half_cycle=es.half_cycle | hb)

    def _single(self, raw: ObsEpoch) -> Solution | None:
        """The single-point solution of a rover epoch no base epoch serves (None when the
        fallback is off or the epoch has no solution)."""
        if not self.spp_fallback or self.eph is None:
            return None
        if self.spp_cfg is None:
            self.spp_cfg = preset("spp").updated(elev_mask_deg=self.cfg.gnss.elev_mask_deg)
        sol = solve_spp(select_band1(epoch_batch(raw)), self.eph, self.spp_cfg)[0]
        return sol.to_solution() if sol.status == "single" else None

    def _release(self, force: bool) -> list[Solution]:
        out: list[Solution] = []
        while self.held:
            i, raw, es = self.held[0]
            t = float(es.epoch.t_s)
            t_rover_last = float(self.held[-1][2].epoch.t_s)
            # a base epoch at or after t: no later one can be nearer (the pairing rule)
            ready = force or self.base_ended or self.t_base_last >= t or t_rover_last - t > self.wait_s
            if not ready:
                break
            self.held.popleft()
            if self.loop is None:
                self.loop = self._start(raw)
                if self.loop is None:  # no base position or ephemerides yet
                    single = self._single(raw)
                    if single is not None:
                        out.append(single)
                    continue
            loop = self.loop
            # base epochs up to t + tol go in first (those after stay pending)
            while self.pending_base and float(self.pending_base[0][0].t_s) <= t + TOL_S + 1e-3:
                b, usable = self.pending_base.popleft()
                self._code_rows("base", b, self.base_pos_m)
                if self.base_fill is not None and usable and self.base_pos_m is not None:
                    b = self.base_fill(b, loop.engine.source, self.base_pos_m)
                loop.push_base(b, usable)
            self._code_rows("rover", es.epoch, self.pos0_m)
            self._update_code_sigma(t)
            self._current = es
            got = loop.prepare(i, es.epoch)
            if got is None:
                sol = self._single(raw)
                if sol is None:
                    continue
            else:
                sol = loop.solve(*got)[1]
                if self.cfg.mode == "dgnss" and sol.status == "code":
                    sol = replace(sol, status="dgnss")  # as the file solve names it
            out.append(sol)
            self.last = StreamStatus(sol.t_s, sol.status, sol.n_used, sol.age_s, sol.ratio, len(self.held))
        return out


__all__ = ["TOL_S", "StreamSolver", "StreamStatus", "epoch_glonass_channels", "glonass_channel_of"]
