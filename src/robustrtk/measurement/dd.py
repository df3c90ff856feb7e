"""Double differences between a rover and a base against a reference transmitter.

For transmitters ``s`` and reference ``l`` observed by rover ``r`` and base ``q``
(Li et al. eq. 1)::

    DD = (obs_r^s − obs_q^s) − (obs_r^l − obs_q^l)

which cancels every receiver clock and every transmitter clock. The operator ``D`` maps
the stacked undifferenced vector ``[obs_r (N), obs_q (N)]`` to the DDs, so the DD
covariance ``D R Dᵀ`` is exact, the correlation through the shared reference included.
Transmitters are grouped (``"P:L1"``, ``"G:1C"``, ...); each group has its own reference.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from functools import cached_property, lru_cache
from typing import Any

import numpy as np

from robustrtk.core import CLIGHT, FloatArray, IntArray, MeasurementModel, replaced, row_norms
from robustrtk.geometry.los import OMEGA_E_RAD_S

#: Earth rotation rate (rad/s), WGS84, for the Sagnac term of satellite ranges.
OMEGA_E = OMEGA_E_RAD_S


@dataclass(frozen=True)
class DDIndex:
    """Which DDs, between which transmitters, by which operator: what a :class:`DDSet` and
    a :class:`DDRows` share.

    Attributes
    ----------
    labels : tuple of str, length m
        ``"<tx>-<ref>"``.
    tx, ref, group : tuple of str, length m
        Non-reference transmitter, reference transmitter and group of each row.
    i_tx, i_ref : ndarray of int, shape (m,)
        Indices of ``tx`` and ``ref`` in the undifferenced transmitter list (N).
    D : ndarray, shape (m, 2N)
        Differencing operator on ``[rover (N), base (N)]``.
    """

    labels: tuple[str, ...]
    tx: tuple[str, ...]
    ref: tuple[str, ...]
    group: tuple[str, ...]
    i_tx: IntArray
    i_ref: IntArray
    D: FloatArray

    @property
    def m(self) -> int:
        return len(self.labels)

    def index_fields(self) -> dict[str, Any]:
        """The :class:`DDIndex` fields by name (to build a :class:`DDSet` on these rows)."""
        return {f.name: getattr(self, f.name) for f in fields(DDIndex)}


@dataclass(frozen=True)
class DDSet(DDIndex):
    """Double differences of one observable: the rows of a :class:`DDIndex` with values.

    Attributes
    ----------
    z : ndarray, shape (m,)
        Observed DDs (units of the input: metres for code, cycles for phase).
    R : ndarray, shape (m, m)
        ``D diag(var_rover, var_base) Dᵀ``.
    """

    z: FloatArray
    R: FloatArray


def choose_references(
    tx_ids: Sequence[str],
    groups: Sequence[str],
    available: np.ndarray,
    score: FloatArray,
    preferred: dict[str, str] | None = None,
    previous: dict[str, str] | None = None,
) -> dict[str, str]:
    """Reference transmitter of each group.

    Order of preference: ``preferred[group]`` when available, then the ``previous``
    reference (sticky, so ambiguity states keep their meaning), then the available
    transmitter with the highest ``score`` (e.g. elevation or SNR).

    Parameters
    ----------
    tx_ids, groups : sequence of str, length N
    available : ndarray of bool, shape (N,)
        Observed by both receivers this epoch.
    score : ndarray, shape (N,)
    """
    out: dict[str, str] = {}
    ids = list(tx_ids)
    # the available rows of each group, in row order (groups in order of appearance)
    rows_of: dict[str, list[int]] = {g: [] for g in groups}
    for i, (g, ok) in enumerate(zip(groups, np.asarray(available, dtype=bool).tolist(), strict=True)):
        if ok:
            rows_of[g].append(i)
    for g, cand in rows_of.items():
        if len(cand) < 2:
            continue
        names = [ids[i] for i in cand]
        if preferred and preferred.get(g) in names:
            out[g] = preferred[g]
        elif previous and previous.get(g) in names:
            out[g] = previous[g]
        else:
            s = np.nan_to_num(score[cand], nan=-np.inf)
            out[g] = ids[int(cand[int(np.argmax(s))])]
    return out


@dataclass(frozen=True)
class DDRows(DDIndex):
    """Which DDs a set of undifferenced rows gives: everything of a :class:`DDSet` that does
    not depend on the observed values (:func:`dd_rows`).

    Attributes
    ----------
    ok : ndarray of bool, shape (N,)
        Rows observed by both receivers (the mask the rows were chosen from).
    source : tuple
        ``(tx_ids, groups, refs items)`` the rows were chosen for.
    """

    ok: np.ndarray
    source: tuple[tuple[str, ...], tuple[str, ...], tuple[tuple[str, str], ...]] = ((), (), ())

    def matches(
        self, tx_ids: Sequence[str], groups: Sequence[str], ok: np.ndarray, refs: dict[str, str]
    ) -> bool:
        """Whether these are the rows :func:`dd_rows` would choose for the arguments."""
        return (
            self.ok.shape == ok.shape
            and bool((self.ok == ok).all())  # np.array_equal of two arrays of one shape
            and self.source == (tuple(tx_ids), tuple(groups), tuple(refs.items()))
        )


@lru_cache(maxsize=16)
def _row_layout(
    ids: tuple[str, ...], groups: tuple[str, ...]
) -> tuple[dict[str, int], IntArray, IntArray, dict[str, int]]:
    """What :func:`dd_rows` needs of the row names alone (remembered: a batch's epochs share
    their tuples): the first row of each name, that row for every row, the group code of
    every row and the code of each group."""
    first: dict[str, int] = {}
    for i, t in enumerate(ids):
        first.setdefault(t, i)
    code_of: dict[str, int] = {}
    gcode = np.array([code_of.setdefault(g, len(code_of)) for g in groups], dtype=np.int64)
    first_idx = np.array([first[t] for t in ids], dtype=np.int64)
    gcode.flags.writeable = False
    first_idx.flags.writeable = False
    return first, first_idx, gcode, code_of


def dd_rows(tx_ids: Sequence[str], groups: Sequence[str], ok: np.ndarray, refs: dict[str, str]) -> DDRows:
    """The DD rows of :func:`form_dd` for the rows observed by both receivers ``ok``.

    Parameters
    ----------
    tx_ids, groups : sequence of str, length N
    ok : ndarray of bool, shape (N,)
        Rows observed by both receivers.
    refs : dict
        Reference transmitter per group.

    Returns
    -------
    DDRows
        One row per ``ok`` transmitter whose group has a reference (the first row of that
        name) that is ``ok`` too, the reference itself excepted, in the order of ``tx_ids``.
    """
    ids_t = tuple(tx_ids)
    groups_t = tuple(groups)
    N = len(ids_t)
    if len(groups_t) != N:
        raise ValueError(f"groups has {len(groups_t)} entries for {N} transmitters")
    ok_b = np.asarray(ok, dtype=bool)
    if ok_b.shape != (N,):
        raise ValueError(f"ok has shape {ok_b.shape} for {N} transmitters")
    first, first_idx, gcode, code_of = _row_layout(ids_t, groups_t)
    # each group's reference row, -1 for groups without one (their rows have no DDs)
    ref_by_code = np.full(len(code_of), -1, dtype=np.int64)
    for g, r in refs.items():
        c, j = code_of.get(g), first.get(r)
        if c is not None and j is not None:
            ref_by_code[c] = j
    ref_of = ref_by_code[gcode]
    # observed rows of a group with a reference, other than the reference (by name) ...
    use = ok_b & (ref_of >= 0) & (first_idx != ref_of)
    use[use] = ok_b[ref_of[use]]  # ... whose reference is observed
    i_tx = np.flatnonzero(use).astype(np.int64)
    i_ref = ref_of[i_tx]
    labels, tx, ref, group, D = _dd_operator(ids_t, groups_t, tuple(i_tx.tolist()), tuple(i_ref.tolist()))
    return DDRows(
        ok=ok_b, labels=labels, tx=tx, ref=ref, group=group, i_tx=i_tx, i_ref=i_ref, D=D,
        source=(ids_t, groups_t, tuple(refs.items())),
    )  # fmt: skip


@lru_cache(maxsize=2)
def _dd_operator(
    ids: tuple[str, ...], groups: tuple[str, ...], rows_tx: tuple[int, ...], rows_ref: tuple[int, ...]
) -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...], tuple[str, ...], FloatArray]:
    """The names and the DD operator ``D`` (m, 2N) of the DD rows ``rows_tx`` against
    ``rows_ref`` (:func:`dd_rows`): labels, transmitters, references and groups of the rows,
    and ``D`` with ``+1, −1`` at the rover's transmitter and reference columns and
    ``−1, +1`` at the base's. Remembered for the last two row sets (an epoch's code and
    phase; the next epoch's rows are mostly the same): ``D`` is read-only."""
    N = len(ids)
    m = len(rows_tx)
    i_tx = np.array(rows_tx, dtype=np.int64)
    i_ref = np.array(rows_ref, dtype=np.int64)
    D = np.zeros((m, 2 * N))
    ar = np.arange(m)
    D[ar, i_tx] = 1.0
    D[ar, i_ref] = -1.0
    D[ar, N + i_tx] = -1.0
    D[ar, N + i_ref] = 1.0
    D.flags.writeable = False
    return (
        tuple(f"{ids[a]}-{ids[b]}" for a, b in zip(rows_tx, rows_ref, strict=True)),
        tuple(ids[a] for a in rows_tx),
        tuple(ids[b] for b in rows_ref),
        tuple(groups[a] for a in rows_tx),
        D,
    )


def form_dd(
    tx_ids: Sequence[str],
    groups: Sequence[str],
    rover: FloatArray,
    base: FloatArray,
    var_rover: FloatArray,
    var_base: FloatArray,
    refs: dict[str, str],
    rows: DDRows | None = None,
) -> DDSet:
    """Form the DDs of one observable.

    Parameters
    ----------
    tx_ids, groups : sequence of str, length N
    rover, base : ndarray, shape (N,)
        Undifferenced observations (NaN = absent).
    var_rover, var_base : ndarray, shape (N,)
        Their variances.
    refs : dict
        Reference transmitter per group (from :func:`choose_references`).
    rows : DDRows, optional
        :func:`dd_rows` chosen for another observable of the epoch: used when it was chosen
        for these ``tx_ids``, ``groups`` and ``refs`` and this call's mask of rows observed
        by both receivers (:meth:`DDRows.matches`), else the rows are chosen afresh.

    Returns
    -------
    DDSet
        One row per transmitter observed by both receivers whose group has a reference
        that is also observed, in the order of ``tx_ids``.
    """
    ok = np.isfinite(rover) & np.isfinite(base)
    if rows is None or not rows.matches(tx_ids, groups, ok, refs):
        rows = dd_rows(tx_ids, groups, ok, refs)
    D = rows.D
    u = np.concatenate([np.where(ok, rover, 0.0), np.where(ok, base, 0.0)])
    var = np.concatenate([np.where(ok, var_rover, 0.0), np.where(ok, var_base, 0.0)])
    z = D @ u
    R = (D * var) @ D.T
    return DDSet(**rows.index_fields(), z=z, R=0.5 * (R + R.T))


def ranges(pos_m: FloatArray, tx_pos_m: FloatArray, sagnac: bool = False) -> FloatArray:
    """Ranges from receiver positions to transmitters.

    Parameters
    ----------
    pos_m : ndarray, shape (..., 3)
    tx_pos_m : ndarray, shape (N, 3)
    sagnac : bool
        Add the Earth-rotation term ``ωe (xˢ yᵣ − yˢ xᵣ)/c`` (ECEF satellites).

    Returns
    -------
    ndarray, shape (..., N)
    """
    diff = pos_m[..., None, :] - tx_pos_m
    r = np.sqrt(np.einsum("...k,...k->...", diff, diff))
    if sagnac:
        r = (
            r
            + OMEGA_E * (tx_pos_m[:, 0] * pos_m[..., None, 1] - tx_pos_m[:, 1] * pos_m[..., None, 0]) / CLIGHT
        )
    return r


class RangeMemo:
    """Rover ranges and line-of-sight unit vectors of one epoch, remembered by position.

    Within an epoch the DD code and phase models share their transmitters, and the
    integrity snapshot, the filter's linearisation, its posterior residuals and the fixed
    solution evaluate them at a few positions, often the same one (the predicted
    position, for the snapshot's first iteration, the linearisation of both models and
    the new ambiguities' start values). The models of :func:`dd_range_model` given one
    memo compute each ``(position, transmitters)`` once; an entry is used only for the
    very arrays it was computed from (identity of the transmitter positions and delays:
    they are not to be modified in place, as for :class:`DDRangeModel`), so the numbers
    are those of :func:`ranges` and of :meth:`DDRangeModel.jacobian` computed afresh.
    """

    __slots__ = ("_ranges", "_units")

    #: Entries kept of each kind (an epoch asks about a few positions).
    SIZE = 8

    def __init__(self) -> None:
        self._ranges: dict[tuple[bytes, bool], tuple[FloatArray, FloatArray | None, FloatArray]] = {}
        self._units: dict[bytes, tuple[FloatArray, FloatArray]] = {}

    def ranges(
        self, pos_m: FloatArray, tx_pos_m: FloatArray, sagnac: bool, tx_corr_m: FloatArray | None
    ) -> FloatArray:
        """``ranges(pos_m, tx_pos_m, sagnac) (+ tx_corr_m)`` (N,) for one position (3,),
        read-only."""
        key = (pos_m.tobytes(), sagnac)
        hit = self._ranges.get(key)
        if hit is not None and hit[0] is tx_pos_m and hit[1] is tx_corr_m:
            return hit[2]
        r = ranges(pos_m, tx_pos_m, sagnac)
        if tx_corr_m is not None:
            r = r + tx_corr_m
        r.flags.writeable = False
        if len(self._ranges) >= self.SIZE:
            self._ranges.clear()
        self._ranges[key] = (tx_pos_m, tx_corr_m, r)
        return r

    def units(self, pos_m: FloatArray, tx_pos_m: FloatArray) -> FloatArray:
        """Unit vectors (N, 3) from the transmitters to ``pos_m`` (3,), read-only."""
        key = pos_m.tobytes()
        hit = self._units.get(key)
        if hit is not None and hit[0] is tx_pos_m:
            return hit[1]
        e = line_of_sight(pos_m, tx_pos_m)
        e.flags.writeable = False
        if len(self._units) >= self.SIZE:
            self._units.clear()
        self._units[key] = (tx_pos_m, e)
        return e


def line_of_sight(pos_m: FloatArray, tx_pos_m: FloatArray) -> FloatArray:
    """Unit vectors (N, 3) from the transmitters ``tx_pos_m`` (N, 3) to ``pos_m`` (3,) (m):
    the position rows of a range Jacobian."""
    diff = pos_m - tx_pos_m
    return np.asarray(diff / row_norms(diff)[:, None], float)


@dataclass(frozen=True)
class DDRangeModel:
    """Measurement model of DDs in metres: geometry (+ λ·ambiguity).

    ``h(x) = [ρ(x, sᵢ) − ρ(x, s_ref)] − [ρ_q^i − ρ_q^ref] + λᵢ Nᵢ`` with rover position
    ``x[pos]`` and ambiguity states ``x[amb_idx]`` (cycles) for rows with ``amb_idx ≥ 0``.

    Attributes
    ----------
    tx_pos_m : ndarray, shape (N, 3)
        Transmitter positions (rover side).
    base_range_m : ndarray, shape (N,)
        Base–transmitter ranges (computed once from the known base position).
    i_tx, i_ref : ndarray of int, shape (m,)
    pos_slice : slice
        Position block of the state.
    amb_idx : ndarray of int, shape (m,)
        State index of each row's ambiguity, −1 for none (code).
    wavelength_m : ndarray, shape (m,)
    z : ndarray, shape (m,)  (metres)
    R : ndarray, shape (m, m)  (m²)
    labels : tuple of str
    sagnac : bool
    tx_corr_m : ndarray, shape (N,), optional
        Delays added to the rover ranges (m), e.g. the troposphere at the prior position;
        the base's delays are part of ``base_range_m``.
    memo : RangeMemo, optional
        Shared by the models of one epoch: rover ranges and unit vectors computed once
        per position (the same numbers).
    """

    tx_pos_m: FloatArray
    base_range_m: FloatArray
    i_tx: IntArray
    i_ref: IntArray
    pos_slice: slice
    amb_idx: IntArray
    wavelength_m: FloatArray
    z: FloatArray
    R: FloatArray
    labels: tuple[str, ...]
    sagnac: bool = False
    tx_corr_m: FloatArray | None = None
    memo: RangeMemo | None = field(default=None, compare=False, repr=False)

    @cached_property
    def row_constants(self) -> tuple[FloatArray, IntArray, IntArray, FloatArray]:
        """What :meth:`h` and :meth:`jacobian` take from the model alone, built on first use
        and kept (the model's arrays are not to be modified in place): the base's DD ranges
        ``ρ_q^i − ρ_q^ref`` (m,), the rows with an ambiguity, their state indices and their
        wavelengths (m)."""
        base_dd = self.base_range_m[self.i_tx] - self.base_range_m[self.i_ref]
        rows = np.flatnonzero(self.amb_idx >= 0)
        return base_dd, rows, self.amb_idx[rows], self.wavelength_m[rows]

    def h(self, X: FloatArray) -> FloatArray:
        X = np.asarray(X, float)
        pos = X[..., self.pos_slice]
        if self.memo is not None and pos.ndim == 1:
            r = self.memo.ranges(pos, self.tx_pos_m, self.sagnac, self.tx_corr_m)
        else:
            r = ranges(pos, self.tx_pos_m, self.sagnac)
            if self.tx_corr_m is not None:
                r = r + self.tx_corr_m
        base_dd, rows, idx, wl = self.row_constants
        out = (r[..., self.i_tx] - r[..., self.i_ref]) - base_dd
        if rows.size:
            out[..., rows] += X[..., idx] * wl
        return out

    def on_position(self) -> DDRangeModel:
        """The same rows as a model of the position alone (a state of shape (3,)): the
        numbers of :meth:`h` and of the position columns of :meth:`jacobian` unchanged,
        without the other states' columns (a single-epoch fit of the position moves
        nothing else). Only for rows without ambiguities (code)."""
        if np.any(self.amb_idx >= 0):
            raise ValueError("on_position: the model has rows with ambiguity states")
        pm = replaced(self, pos_slice=slice(0, 3))
        # the same rows: their constants (which do not depend on the state) are shared
        pm.__dict__["row_constants"] = self.row_constants
        return pm

    def jacobian(self, x: FloatArray) -> FloatArray:
        pos = np.asarray(x, float)[self.pos_slice]
        if self.memo is not None:
            e = self.memo.units(pos, self.tx_pos_m)
        else:
            e = line_of_sight(pos, self.tx_pos_m)
        _, rows, idx, wl = self.row_constants
        d = e[self.i_tx] - e[self.i_ref]
        n = x.shape[0]
        if not rows.size and self.pos_slice == slice(0, n):
            return d  # a model of the position alone (on_position): the columns are the rows
        H = np.zeros((len(self.i_tx), n))
        H[:, self.pos_slice] = d
        H[rows, idx] = wl
        return H


def dd_range_model(
    dd: DDSet,
    tx_pos_m: FloatArray,
    base_range_m: FloatArray,
    pos_slice: slice,
    *,
    amb_idx: IntArray | None = None,
    wavelength_m: FloatArray | None = None,
    z_m: FloatArray | None = None,
    R_m2: FloatArray | None = None,
    sagnac: bool = False,
    tx_corr_m: FloatArray | None = None,
    memo: RangeMemo | None = None,
) -> DDRangeModel:
    """The :class:`DDRangeModel` of a DD set (code: no ambiguities, ``z``/``R`` of ``dd``).

    ``z_m``/``R_m2`` override the set's values (phase: the cycles scaled to metres);
    ``memo`` is shared by the models of an epoch (:class:`RangeMemo`).
    """
    m = dd.m
    return DDRangeModel(
        tx_pos_m=tx_pos_m,
        base_range_m=base_range_m,
        i_tx=dd.i_tx,
        i_ref=dd.i_ref,
        pos_slice=pos_slice,
        amb_idx=np.full(m, -1, dtype=np.int64) if amb_idx is None else amb_idx,
        wavelength_m=np.zeros(m) if wavelength_m is None else wavelength_m,
        z=dd.z if z_m is None else z_m,
        R=dd.R if R_m2 is None else R_m2,
        labels=dd.labels,
        sagnac=sagnac,
        tx_corr_m=tx_corr_m,
        memo=memo,
    )


#: Any measurement model with rows (the filters' protocol).
RowModel = MeasurementModel


@dataclass(frozen=True)
class StackedModel:
    """Several measurement models of any kind stacked (DD phase then DD code, a range to a
    peer receiver, Doppler, ...); ``R`` is block-diagonal (the parts are independent).
    ``z``, ``R`` and ``labels`` are built on first use and kept (the parts' arrays are not
    to be modified in place, as for :class:`DDRangeModel`)."""

    parts: tuple[RowModel, ...]

    @cached_property
    def z(self) -> FloatArray:
        return np.concatenate([p.z for p in self.parts])

    @cached_property
    def R(self) -> FloatArray:
        sizes = [len(p.labels) for p in self.parts]
        out = np.zeros((sum(sizes), sum(sizes)))
        i = 0
        for p, n in zip(self.parts, sizes, strict=True):
            out[i : i + n, i : i + n] = p.R
            i += n
        return out

    @cached_property
    def labels(self) -> tuple[str, ...]:
        return tuple(lab for p in self.parts for lab in p.labels)

    def h(self, X: FloatArray) -> FloatArray:
        return np.concatenate([p.h(X) for p in self.parts], axis=-1)

    def jacobian(self, x: FloatArray) -> FloatArray:
        return np.vstack([p.jacobian(x) for p in self.parts])
