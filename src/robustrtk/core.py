"""Core data types shared by every package.

The data model follows the flow ``io -> geometry -> measurement -> estimation -> ambiguity``:

* :class:`ObsBatch` holds the observations of **one receiver** over many epochs as
  ``(T, N, K)`` float64 arrays (epochs x transmitters x signals) with NaN for absent
  cells, so a 5-pseudolite room (N=5, K=1) and a multi-GNSS receiver (N~40, K~3) run
  through the same code.
* :class:`ObsEpoch` is one epoch of one receiver (``(N, K)`` arrays).
* :class:`TransmitterSource` gives transmitter positions (ephemeris for satellites, a
  surveyed table for pseudolites).
* :class:`Solution` is one epoch of output.

Time convention: ``t_s`` is float seconds. For GNSS it is GPS time in seconds since
1980-01-06T00:00:00 GPST (see :data:`GPS_EPOCH`); for pseudolite tables it is the table's
own clock in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, is_dataclass, replace
from functools import lru_cache
from typing import Any, Protocol, TypeVar

import numpy as np
import numpy.typing as npt

from robustrtk.errors import InputError as InputError  # re-exported: the same class

FloatArray = npt.NDArray[np.floating[Any]]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: Speed of light in vacuum (m/s), IS-GPS-200.
CLIGHT = 299_792_458.0

#: ISO string of the origin of ``t_s`` for GNSS data (GPS time scale).
GPS_EPOCH = "1980-01-06T00:00:00"

#: Solution status values, best first.
STATUSES = ("fixed", "partial", "float", "dgnss", "code", "single", "none")


@dataclass(frozen=True)
class ObsEpoch:
    """Observations of one receiver at one epoch.

    Attributes
    ----------
    t_s : float
        Receiver time tag (s), see module docstring.
    tx_ids : tuple of str, length N
        Transmitter identifiers (``"G05"``, ``"E11"``, ``"PL4"``).
    system : tuple of str, length N
        One-letter system per transmitter (``G R E C J S I``; ``P`` for pseudolites).
    signals : tuple of str, length K
        Signal names (RINEX 3 band+attribute such as ``"1C"``, ``"2W"``; ``"L1"`` for
        pseudolites).
    code_m, phase_cyc, doppler_hz, cn0_dbhz : ndarray, shape (N, K)
        Pseudorange (m), carrier phase (cycles), Doppler (Hz), C/N0 or SNR (dB-Hz); NaN
        where absent.
    lli : ndarray of int8, shape (N, K)
        Loss-of-lock indicator; bit 0 = loss of lock / possible slip, bit 1 = half-cycle
        ambiguity (RINEX). 0 where absent.
    wavelength_m : ndarray, shape (N, K)
        Carrier wavelength (m) of each cell (per cell for GLONASS FDMA); NaN if unknown.
    code_sigma_m : ndarray, shape (N, K), or None
        Per-measurement 1-sigma of ``code_m`` (m) reported by the receiver (e.g. Android
        ``ReceivedSvTimeUncertaintyNanos``); None when the input has none, NaN where unknown.
    phase_sigma_cyc : ndarray, shape (N, K), or None
        Per-measurement 1-sigma of ``phase_cyc`` (cycles); None or NaN as above.
    """

    t_s: float
    tx_ids: tuple[str, ...]
    system: tuple[str, ...]
    signals: tuple[str, ...]
    code_m: FloatArray
    phase_cyc: FloatArray
    doppler_hz: FloatArray
    cn0_dbhz: FloatArray
    lli: npt.NDArray[np.int8]
    wavelength_m: FloatArray
    code_sigma_m: FloatArray | None = None
    phase_sigma_cyc: FloatArray | None = None

    @property
    def n_tx(self) -> int:
        return len(self.tx_ids)

    def index(self, tx_id: str) -> int:
        """Row index of ``tx_id`` (raises ``KeyError`` when absent)."""
        try:
            return self.tx_ids.index(tx_id)
        except ValueError as exc:
            raise KeyError(tx_id) from exc


@dataclass(frozen=True)
class ObsBatch:
    """Observations of one receiver over T epochs, stacked as ``(T, N, K)`` arrays.

    The transmitter axis is the union of all transmitters seen in the file, the signal
    axis the union of all signals; absent cells are NaN (``lli`` 0).

    Attributes
    ----------
    t_s : ndarray, shape (T,)
        Epoch time tags (s), strictly increasing.
    tx_ids, system, signals : tuple of str
        As in :class:`ObsEpoch`.
    code_m, phase_cyc, doppler_hz, cn0_dbhz : ndarray, shape (T, N, K)
    lli : ndarray of int8, shape (T, N, K)
    wavelength_m : ndarray, shape (N, K)
        Wavelength per transmitter and signal (constant over time).
    receiver : str
        Receiver name (marker name or the table's ``receiver`` column).
    approx_pos_m : ndarray, shape (3,) or None
        Approximate receiver position from the file header (may be wrong!), in the file's
        frame (ECEF for RINEX, local for pseudolite tables).
    meta : dict
        Free-form header information (file name, interval, receiver type...).
    code_sigma_m : ndarray, shape (T, N, K), or None
        Per-measurement 1-sigma of ``code_m`` (m) reported by the receiver; None when the
        input carries none (RINEX), NaN in cells without a value.
    phase_sigma_cyc : ndarray, shape (T, N, K), or None
        Per-measurement 1-sigma of ``phase_cyc`` (cycles); None or NaN as above.
    """

    t_s: FloatArray
    tx_ids: tuple[str, ...]
    system: tuple[str, ...]
    signals: tuple[str, ...]
    code_m: FloatArray
    phase_cyc: FloatArray
    doppler_hz: FloatArray
    cn0_dbhz: FloatArray
    lli: npt.NDArray[np.int8]
    wavelength_m: FloatArray
    receiver: str = ""
    approx_pos_m: FloatArray | None = None
    meta: dict[str, object] = field(default_factory=dict)
    code_sigma_m: FloatArray | None = None
    phase_sigma_cyc: FloatArray | None = None

    def __post_init__(self) -> None:
        # A sigma array that no longer matches the observations (e.g. after a
        # ``dataclasses.replace`` that sliced only the classic arrays) is dropped rather
        # than left misaligned; :meth:`select_epochs` keeps it.
        for name in ("code_sigma_m", "phase_sigma_cyc"):
            a = getattr(self, name)
            if a is not None and np.shape(a) != np.shape(self.code_m):
                object.__setattr__(self, name, None)

    @classmethod
    def from_stacked(
        cls,
        t_s: FloatArray,
        tx_ids: tuple[str, ...],
        signals: tuple[str, ...],
        obs: FloatArray,
        lli: npt.NDArray[np.int8],
        wavelength_m: FloatArray,
        receiver: str,
        approx_pos_m: FloatArray | None,
        meta: dict[str, object],
    ) -> ObsBatch:
        """A batch from a decoder's stacked observations ``obs`` (4, T, N, K): code (m),
        phase (cycles), Doppler (Hz) and C/N0 (dB-Hz); each system is its id's first letter."""
        return cls(
            t_s=t_s, tx_ids=tx_ids, system=tuple(t[0] for t in tx_ids), signals=signals,
            code_m=obs[0], phase_cyc=obs[1], doppler_hz=obs[2], cn0_dbhz=obs[3], lli=lli,
            wavelength_m=wavelength_m, receiver=receiver, approx_pos_m=approx_pos_m, meta=meta,
        )  # fmt: skip

    def select_epochs(self, idx: npt.ArrayLike) -> ObsBatch:
        """The batch restricted to epochs ``idx`` (indices, slice or boolean mask).

        Every per-epoch array (including the sigma arrays and ``meta["t_ns"]`` when
        present) is indexed the same way; transmitters and signals are unchanged.
        """
        key = idx if isinstance(idx, slice) else np.asarray(idx)

        def take(a: Any) -> Any:
            return None if a is None else np.asarray(a)[key]

        meta = dict(self.meta)
        t_ns = meta.get("t_ns")
        if isinstance(t_ns, np.ndarray) and t_ns.shape[:1] == self.t_s.shape:
            meta["t_ns"] = t_ns[key]
        return ObsBatch(
            t_s=np.asarray(self.t_s)[key],
            tx_ids=self.tx_ids,
            system=self.system,
            signals=self.signals,
            code_m=take(self.code_m),
            phase_cyc=take(self.phase_cyc),
            doppler_hz=take(self.doppler_hz),
            cn0_dbhz=take(self.cn0_dbhz),
            lli=take(self.lli),
            wavelength_m=self.wavelength_m,
            receiver=self.receiver,
            approx_pos_m=self.approx_pos_m,
            meta=meta,
            code_sigma_m=take(self.code_sigma_m),
            phase_sigma_cyc=take(self.phase_sigma_cyc),
        )

    def select_systems(self, systems: str) -> ObsBatch:
        """The batch restricted to transmitters of the system letters ``systems`` (``"GE"``)."""
        keep = np.array([i for i, s in enumerate(self.system) if s in systems.upper()], dtype=np.int64)

        def take(a: Any) -> Any:
            return None if a is None else np.asarray(a)[:, keep]

        return ObsBatch(
            t_s=self.t_s,
            tx_ids=tuple(self.tx_ids[i] for i in keep),
            system=tuple(self.system[i] for i in keep),
            signals=self.signals,
            code_m=take(self.code_m),
            phase_cyc=take(self.phase_cyc),
            doppler_hz=take(self.doppler_hz),
            cn0_dbhz=take(self.cn0_dbhz),
            lli=take(self.lli),
            wavelength_m=np.asarray(self.wavelength_m)[keep],
            receiver=self.receiver,
            approx_pos_m=self.approx_pos_m,
            meta=dict(self.meta),
            code_sigma_m=take(self.code_sigma_m),
            phase_sigma_cyc=take(self.phase_sigma_cyc),
        )

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    def epoch(self, i: int) -> ObsEpoch:
        """The ``i``-th epoch as an :class:`ObsEpoch` (all N rows, NaN where absent)."""
        return ObsEpoch(
            t_s=float(self.t_s[i]),
            tx_ids=self.tx_ids,
            system=self.system,
            signals=self.signals,
            code_m=self.code_m[i],
            phase_cyc=self.phase_cyc[i],
            doppler_hz=self.doppler_hz[i],
            cn0_dbhz=self.cn0_dbhz[i],
            lli=self.lli[i],
            wavelength_m=self.wavelength_m,
            code_sigma_m=None if self.code_sigma_m is None else self.code_sigma_m[i],
            phase_sigma_cyc=None if self.phase_sigma_cyc is None else self.phase_sigma_cyc[i],
        )

    def __iter__(self):  # type: ignore[no-untyped-def]
        for i in range(len(self)):
            yield self.epoch(i)


_D = TypeVar("_D")

#: Per dataclass: its field names when :func:`replaced` may copy its instances directly,
#: else an empty set (it then calls :func:`dataclasses.replace`).
_PLAIN_FIELDS: dict[type, frozenset[str]] = {}


def _plain_fields(cls: type) -> frozenset[str]:
    """The field names of a dataclass whose ``__init__`` only stores its arguments (every
    field an init field, no ``InitVar``, no ``__post_init__``), else an empty set."""
    if not is_dataclass(cls) or hasattr(cls, "__post_init__") or hasattr(cls, "__slots__"):
        return frozenset()
    fs = fields(cls)
    if not all(f.init for f in fs) or len(fs) != len(getattr(cls, "__dataclass_fields__", {})):
        return frozenset()  # an InitVar or ClassVar pseudo-field
    return frozenset(f.name for f in fs)


def replaced(obj: _D, **changes: Any) -> _D:
    """``dataclasses.replace(obj, **changes)``, without its generic walk over the fields
    for a plain dataclass (see :func:`_plain_fields`; the epoch loop replaces a solution
    or a result several times per epoch): a new instance with the same attributes but
    ``changes``, which is what ``replace`` builds for such a class. Other objects, and
    instances carrying more than their fields (a cached property's value), go through
    :func:`dataclasses.replace`. Unknown field names raise :class:`TypeError` either way."""
    cls = type(obj)
    names = _PLAIN_FIELDS.get(cls)
    if names is None:
        names = _PLAIN_FIELDS[cls] = _plain_fields(cls)
    state = getattr(obj, "__dict__", None)
    if not names or state is None or len(state) != len(names) or not changes.keys() <= names:
        return replace(obj, **changes)  # type: ignore[type-var]
    new = object.__new__(cls)
    new.__dict__.update(state)
    new.__dict__.update(changes)
    return new


def nan_to(a: npt.ArrayLike, nan: float) -> FloatArray:
    """``np.nan_to_num(a, nan=nan)`` of a real array (a float64 copy: NaN → ``nan``, ±inf →
    ± the largest float), the same numbers without its generic machinery."""
    out = np.array(a, dtype=np.float64)
    out[np.isnan(out)] = nan
    inf = np.isinf(out)
    if inf.any():
        out[inf] = np.copysign(np.finfo(np.float64).max, out[inf])
    return out


@lru_cache(maxsize=64)
def identity(n: int) -> FloatArray:
    """``np.eye(n)``, read-only and remembered (the epoch loop's updates subtract from it
    or scale it a few times per epoch; the results are new arrays)."""
    out = np.eye(n)
    out.flags.writeable = False
    return out


def row_norms(a: FloatArray) -> FloatArray:
    """``np.linalg.norm(a, axis=-1)`` of a real float array, the same numbers (``√(Σ aᵢ²)``
    with numpy's sum over the last axis), without the generic checks that cost more than
    the sum for an epoch's few rows."""
    return np.sqrt(np.add.reduce(a * a, axis=-1))


def vector_norm(v: FloatArray) -> float:
    """``float(np.linalg.norm(v))`` of a real float vector, the same number (``√(v·v)``),
    without the generic checks."""
    return float(np.sqrt(v.dot(v)))


def median_of(values: FloatArray) -> float:
    """Median of a 1-D array, the number :func:`numpy.median` gives (the middle value of the
    sorted values, or the mean ``(a + b) / 2`` of the two middle ones; NaN when any value is
    NaN or there is none), without its generic machinery: an epoch loop calls it every
    epoch on a few dozen values, where ``np.median`` costs ten times the sort itself.

    Parameters
    ----------
    values : ndarray, shape (k,)

    Returns
    -------
    float
    """
    s = np.sort(np.asarray(values, float).ravel())
    n = s.size
    if n == 0 or np.isnan(s[-1]):  # NaN sorts last
        return float("nan")
    k = n // 2
    # numpy's mean of the middle value(s): a sum from +0.0 (a -0.0 median is +0.0), then / n
    return float(0.0 + s[k]) if n % 2 else float(((0.0 + s[k - 1]) + s[k]) / 2.0)


def empty_batch(
    t_s: FloatArray,
    tx_ids: tuple[str, ...],
    system: tuple[str, ...],
    signals: tuple[str, ...],
    wavelength_m: FloatArray | None = None,
    receiver: str = "",
) -> ObsBatch:
    """An :class:`ObsBatch` of the given shape filled with NaN (``lli`` zeros)."""
    T, N, K = len(t_s), len(tx_ids), len(signals)
    nan = np.full((T, N, K), np.nan)
    wl = np.full((N, K), np.nan) if wavelength_m is None else np.asarray(wavelength_m, float)
    return ObsBatch(
        t_s=np.asarray(t_s, dtype=float),
        tx_ids=tuple(tx_ids),
        system=tuple(system),
        signals=tuple(signals),
        code_m=nan.copy(),
        phase_cyc=nan.copy(),
        doppler_hz=nan.copy(),
        cn0_dbhz=nan.copy(),
        lli=np.zeros((T, N, K), dtype=np.int8),
        wavelength_m=wl,
        receiver=receiver,
    )


class MeasurementModel(Protocol):
    """Observation ``z = h(x) + v``, ``v ~ N(0, R)``: any model with rows (DD code or phase,
    pseudorange, Doppler, range to a peer), as the filters and measurement stacks take it.

    Attributes
    ----------
    z : ndarray, shape (m,)
    R : ndarray, shape (m, m)
    labels : tuple of str, length m
    """

    @property
    def z(self) -> FloatArray: ...

    @property
    def R(self) -> FloatArray: ...

    @property
    def labels(self) -> tuple[str, ...]: ...

    def h(self, X: FloatArray) -> FloatArray:
        """Predicted observations for states ``X`` of shape ``(..., n)`` → ``(..., m)``."""
        ...

    def jacobian(self, x: FloatArray) -> FloatArray:
        """``∂h/∂x`` at ``x`` (n,) → ``(m, n)``."""
        ...


class TransmitterSource(Protocol):
    """Where transmitters are.

    Satellites: broadcast ephemeris evaluated at signal transmission time (Sagnac is the
    caller's business). Pseudolites: a surveyed table, clock unknown (returned as NaN and
    cancelled by differencing).
    """

    def positions(
        self, t_s: float, tx_ids: tuple[str, ...] | list[str], code_m: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Transmitter positions and clock offsets.

        Parameters
        ----------
        t_s : float
            Receiver time tag (s).
        tx_ids : sequence of str, length N
        code_m : ndarray, shape (N,), optional
            Pseudoranges, used to compute the transmission time (satellites).

        Returns
        -------
        pos_m : ndarray, shape (N, 3)
            Positions in the source's frame (ECEF for satellites, local for pseudolites);
            NaN rows where unavailable.
        clock_m : ndarray, shape (N,)
            Transmitter clock offset times c (m); 0 or NaN where unknown.
        """
        ...


@dataclass(frozen=True)
class Solution:
    """One epoch of solution output.

    Attributes
    ----------
    t_s : float
        Epoch time (s).
    pos_m : ndarray, shape (3,)
        Position (local frame for pseudolites, ECEF for GNSS).
    cov_m2 : ndarray, shape (3, 3)
        Position covariance (m^2).
    status : str
        One of :data:`STATUSES`.
    n_used : int
        Number of observations (DDs) used.
    ratio : float
        Ratio-test value of the last ambiguity search (NaN when none).
    n_fixed, n_amb : int
        Fixed ambiguities and ambiguities in the state.
    vel_m_s : ndarray, shape (3,) or None
    age_s : float
        Age of differential (s): how much older the base observations are than the
        rover's (0 for a base epoch at the same time, and without a base).
    n_sat : int
        Satellites (transmitters) used, references included; 0 when the producer does not
        count them (then ``n_used`` is the count: single-point solutions).
    """

    t_s: float
    pos_m: FloatArray
    cov_m2: FloatArray
    status: str
    n_used: int = 0
    ratio: float = float("nan")
    n_fixed: int = 0
    n_amb: int = 0
    vel_m_s: FloatArray | None = None
    age_s: float = 0.0
    n_sat: int = 0
