"""Indoor pseudolite simulation scenarios: the frozen dataclasses and their validation.

A scenario describes the room, transmitters, base and rover motion, clocks, noise,
multipath and the faults to inject. Every key is optional except ``n_epochs``; the
defaults reproduce a 10 m x 7 m x 4 m laboratory with five ceiling pseudolites. The key
reference is ``docs/formats.md``; :mod:`robustrtk.sim.scenario` reads them from TOML.

Frame: local Cartesian, metres, origin at the centre of the room, x along the 10 m side,
y along the 7 m side, z up; the floor is at z = -2 m and the ceiling at z = +2 m.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from robustrtk.core import InputError
from robustrtk.io.obstable import natural_key

Vec3 = tuple[float, float, float]

#: GPS L1 wavelength used by the pseudolites (m).
PL_WAVELENGTH_M = 0.19029367
#: Room extent (m) along x, y, z, centred on the origin.
ROOM_SIZE_M: Vec3 = (10.0, 7.0, 4.0)
#: Default ceiling layout (spread over the room, ids as in the laboratory of Li et al. 2019).
DEFAULT_TRANSMITTERS: dict[str, Vec3] = {
    "PL1": (-3.6, -2.4, 1.90),
    "PL4": (3.8, -2.5, 1.85),
    "PL5": (3.5, 2.6, 1.92),
    "PL6": (0.2, 0.3, 1.95),
    "PL8": (-3.4, 2.7, 1.88),
}
DEFAULT_BASE_M: Vec3 = (-1.2, -0.6, -1.6)
DEFAULT_ROVER_M: Vec3 = (1.5, 1.0, -1.55)
RECEIVERS = ("base", "rover")
OBSERVABLES = ("code", "phase")


@dataclass(frozen=True)
class Trajectory:
    """Rover motion.

    ``kind``: ``"static"`` (at ``start_m``), ``"rail"`` (straight line ``start_m`` ->
    ``end_m`` at ``speed_m_s``; ``rail_mode`` ``"one_pass"`` stops at the end,
    ``"back_and_forth"`` reverses), ``"free"`` (smooth random curve inside ``area_m`` =
    (x_min, x_max, y_min, y_max) at height ``start_m[2]``, typical speed ``speed_m_s``).
    """

    kind: str = "static"
    start_m: Vec3 = DEFAULT_ROVER_M
    end_m: Vec3 | None = None
    speed_m_s: float = 0.02
    rail_mode: str = "one_pass"
    area_m: tuple[float, float, float, float] = (-4.0, 4.0, -2.5, 2.5)


@dataclass(frozen=True)
class Clocks:
    """Receiver and transmitter clocks: offset b(t) = b0 + int d, drift d a random walk.

    Initial offsets uniform in +-``*_offset_s``, initial drifts uniform in
    +-``*_drift_s_s``; the drift random walk has density ``drift_rw_s_s_sqrt_s``
    (s/s per sqrt(s)).
    """

    receiver_offset_s: float = 1e-4
    receiver_drift_s_s: float = 1e-7
    transmitter_offset_s: float = 1e-4
    transmitter_drift_s_s: float = 1e-7
    drift_rw_s_s_sqrt_s: float = 1e-10


@dataclass(frozen=True)
class Noise:
    """White noise and SNR of one receiver.

    SNR per link: a mean uniform in ``snr_range_dbhz`` plus white noise ``snr_sigma_dbhz``.
    """

    code_sigma_m: float = 0.15
    phase_sigma_m: float = 0.002
    snr_range_dbhz: tuple[float, float] = (40.0, 50.0)
    snr_sigma_dbhz: float = 1.0


@dataclass(frozen=True)
class Multipath:
    """First-order Gauss-Markov multipath per receiver-transmitter link.

    x_k = a x_{k-1} + sqrt(1 - a^2) sigma w_k, a = exp(-dt / tau), stationary start.
    """

    code_sigma_m: float = 0.2
    code_tau_s: float = 60.0
    phase_sigma_m: float = 0.002
    phase_tau_s: float = 60.0
    receivers: tuple[str, ...] = RECEIVERS


@dataclass(frozen=True)
class ScheduledSlip:
    """A cycle slip of ``cycles`` on ``receiver``/``transmitter`` phase from ``epoch`` on."""

    receiver: str
    transmitter: str
    epoch: int
    cycles: int
    silent: bool = False


@dataclass(frozen=True)
class Slips:
    """Random and scheduled cycle slips.

    Each receiver-transmitter link of ``receivers`` slips with ``probability`` per epoch by
    a nonzero integer uniform in +-[1, ``max_cycles``]; ``silent`` slips leave ``lli`` 0.
    """

    probability: float = 0.0
    max_cycles: int = 20
    silent: bool = False
    receivers: tuple[str, ...] = ("rover",)
    scheduled: tuple[ScheduledSlip, ...] = ()


@dataclass(frozen=True)
class Bursts:
    """Random bursts of small gross errors on one non-reference transmitter of ``receiver``.

    A burst starts at an epoch with probability ``*_probability``, lasts a number of epochs
    uniform in ``*_length_epochs`` (inclusive) and has a size uniform in ``*_size_m`` with a
    random sign, constant over the burst. The transmitter is drawn among the non-reference
    ones with probabilities proportional to ``weights`` (default equal).
    """

    code_probability: float = 0.0
    code_length_epochs: tuple[int, int] = (1, 5)
    code_size_m: tuple[float, float] = (0.6, 2.5)
    phase_probability: float = 0.0
    phase_length_epochs: tuple[int, int] = (1, 3)
    phase_size_m: tuple[float, float] = (0.02, 0.05)
    receiver: str = "rover"
    weights: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class RandomGross:
    """``size_m`` added on ``count`` distinct random epochs, each to one random
    non-reference transmitter of ``receiver``."""

    observable: str
    count: int
    size_m: float
    random_sign: bool = False
    receiver: str = "rover"


@dataclass(frozen=True)
class ScheduledGross:
    """``size_m`` added to ``observable`` of ``transmitter`` at ``receiver`` on ``epochs``
    (0-based epoch indices)."""

    observable: str
    transmitter: str
    epochs: tuple[int, ...]
    size_m: float
    receiver: str = "rover"


@dataclass(frozen=True)
class Scenario:
    """A complete simulation scenario (see ``docs/formats.md`` for every key)."""

    n_epochs: int
    name: str = "scenario"
    description: str = ""
    interval_s: float = 1.0
    wavelength_m: float = PL_WAVELENGTH_M
    reference: str = "PL6"
    transmitters: tuple[tuple[str, Vec3], ...] = tuple(DEFAULT_TRANSMITTERS.items())
    base_position_m: Vec3 = DEFAULT_BASE_M
    initial_position_error_m: float = 0.0
    ambiguity_max_cyc: int = 1_000_000
    trajectory: Trajectory = field(default_factory=Trajectory)
    clocks: Clocks = field(default_factory=Clocks)
    noise: tuple[Noise, Noise] = (Noise(), Noise())  # (base, rover)
    multipath: Multipath = field(default_factory=Multipath)
    slips: Slips = field(default_factory=Slips)
    bursts: Bursts = field(default_factory=Bursts)
    random_gross: tuple[RandomGross, ...] = ()
    gross: tuple[ScheduledGross, ...] = ()
    source: str | None = None

    def __post_init__(self) -> None:
        validate_scenario(self)

    @property
    def tx_ids(self) -> tuple[str, ...]:
        """Transmitter ids in natural order."""
        return tuple(sorted((k for k, _ in self.transmitters), key=natural_key))

    def noise_of(self, receiver: str) -> Noise:
        """Noise settings of ``receiver`` (``"base"`` or ``"rover"``)."""
        return self.noise[RECEIVERS.index(receiver)]


# --------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------


def _fail(s: Scenario, field_name: str, expected: str) -> InputError:
    return InputError(f"{field_name}: {expected}", path=s.source)


def validate_scenario(s: Scenario) -> None:
    """Check cross-field consistency; raise :class:`InputError` naming the field."""
    ids = [k for k, _ in s.transmitters]
    if len(ids) < 2 or len(set(ids)) != len(ids):
        raise _fail(s, "transmitters", "expected at least 2 transmitters with distinct ids")
    if s.reference not in ids:
        raise _fail(s, "reference", f"unknown transmitter {s.reference!r}; expected one of {', '.join(ids)}")
    if s.n_epochs < 1:
        raise _fail(s, "n_epochs", f"expected a positive integer, got {s.n_epochs}")
    if not s.interval_s > 0:
        raise _fail(s, "interval_s", "expected a positive number (s)")
    if not s.wavelength_m > 0:
        raise _fail(s, "wavelength_m", "expected a positive number (m)")
    tr = s.trajectory
    if tr.kind not in ("static", "rail", "free"):
        raise _fail(s, "trajectory.kind", f"expected 'static', 'rail' or 'free', got {tr.kind!r}")
    if tr.kind == "rail" and tr.end_m is None:
        raise _fail(s, "trajectory.end_m", "expected the rail end [x, y, z] (m)")
    if tr.rail_mode not in ("one_pass", "back_and_forth"):
        raise _fail(s, "trajectory.rail_mode", "expected 'one_pass' or 'back_and_forth'")
    if tr.area_m[0] >= tr.area_m[1] or tr.area_m[2] >= tr.area_m[3]:
        raise _fail(s, "trajectory.area_m", "expected [x_min, x_max, y_min, y_max] with min < max")
    for rx in s.multipath.receivers + s.slips.receivers:
        if rx not in RECEIVERS:
            raise _fail(s, "receivers", f"unknown receiver {rx!r}; expected base or rover")
    non_ref = [t for t in ids if t != s.reference]
    for i, g in enumerate(s.gross):
        f = f"gross[{i}]"
        if g.observable not in OBSERVABLES:
            raise _fail(s, f + ".observable", f"expected 'code' or 'phase', got {g.observable!r}")
        if g.receiver not in RECEIVERS:
            raise _fail(s, f + ".receiver", f"expected 'base' or 'rover', got {g.receiver!r}")
        if g.transmitter == s.reference:
            raise _fail(
                s,
                f + ".transmitter",
                f"{g.transmitter} is the reference transmitter: a gross error there would enter "
                "every double difference; expected one of " + ", ".join(non_ref),
            )
        if g.transmitter not in ids:
            raise _fail(
                s,
                f + ".transmitter",
                f"unknown transmitter {g.transmitter!r}; expected one of " + ", ".join(non_ref),
            )
        bad = [e for e in g.epochs if not 0 <= e < s.n_epochs]
        if bad:
            raise _fail(s, f + ".epochs", f"epoch {bad[0]} outside 0..{s.n_epochs - 1}")
    for i, r in enumerate(s.random_gross):
        f = f"random_gross[{i}]"
        if r.observable not in OBSERVABLES:
            raise _fail(s, f + ".observable", f"expected 'code' or 'phase', got {r.observable!r}")
        if r.receiver not in RECEIVERS:
            raise _fail(s, f + ".receiver", f"expected 'base' or 'rover', got {r.receiver!r}")
        if r.count < 0:
            raise _fail(s, f + ".count", "expected a non-negative integer")
    for i, sl in enumerate(s.slips.scheduled):
        f = f"slips.scheduled[{i}]"
        if sl.receiver not in RECEIVERS:
            raise _fail(s, f + ".receiver", f"expected 'base' or 'rover', got {sl.receiver!r}")
        if sl.transmitter not in ids:
            raise _fail(s, f + ".transmitter", f"unknown transmitter {sl.transmitter!r}")
        if not 0 <= sl.epoch < s.n_epochs:
            raise _fail(s, f + ".epoch", f"epoch {sl.epoch} outside 0..{s.n_epochs - 1}")
    b = s.bursts
    if b.receiver not in RECEIVERS:
        raise _fail(s, "bursts.receiver", f"expected 'base' or 'rover', got {b.receiver!r}")
    for name in ("code", "phase"):
        lo, hi = getattr(b, f"{name}_length_epochs")
        if not 1 <= lo <= hi:
            raise _fail(s, f"bursts.{name}_length_epochs", "expected [min, max] with 1 <= min <= max")
        a, c = getattr(b, f"{name}_size_m")
        if not 0 <= a <= c:
            raise _fail(s, f"bursts.{name}_size_m", "expected [min, max] with 0 <= min <= max (m)")
    for t, w in b.weights:
        if t not in non_ref:
            raise _fail(s, f"bursts.weights.{t}", "expected a non-reference transmitter id")
        if not w >= 0:
            raise _fail(s, f"bursts.weights.{t}", "expected a non-negative weight")
    if b.weights and sum(w for _, w in b.weights) <= 0:
        raise _fail(s, "bursts.weights", "expected at least one positive weight")
