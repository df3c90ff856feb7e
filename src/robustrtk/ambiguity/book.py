"""The ambiguity book: one object for the bookkeeping of every DD ambiguity state.

Each ambiguity is named by an :class:`AmbKey` — the receiver pair, the transmitter (or
transmitter row, ``"G05:L1"``) and the signal group (``"G:L1"``, the DD group with its own
reference) — and has one :class:`AmbEntry`: the reference it is differenced against, how
many epochs it has been tracked, whether a slip is suspected (and how many epochs the
robust filter has rejected it since), and its last validated integer. The filter state
holds the values (the layout's ambiguity keys are the same ``AmbKey`` objects); the book
holds everything else, so the engine and the RTK stage read and write one object.
"""

from __future__ import annotations

from collections.abc import Container, Iterable, Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from robustrtk.core import FloatArray


class AmbKey(NamedTuple):
    """Name of one DD ambiguity.

    Attributes
    ----------
    tx : str
        Transmitter (row) id, e.g. ``"PL4"`` or ``"G05:L1"``.
    signal : str
        DD group: ``"<system>:<signal or slot>"``, e.g. ``"G:L1"``.
    receivers : tuple of str
        ``(rover, base)`` receiver names of the double difference.
    """

    tx: str
    signal: str
    receivers: tuple[str, str] = ("rover", "base")


@dataclass
class AmbEntry:
    """Bookkeeping of one ambiguity.

    Attributes
    ----------
    ref : str
        Reference transmitter of the DD.
    lock : int
        Epochs of continuous tracking (1 on the epoch it was added).
    suspect : int or None
        ``None`` when no slip is suspected; otherwise the number of epochs the robust
        filter has rejected the row since a detector flagged it.
    fixed : float or None
        Last validated integer (cycles), None when never fixed.
    """

    ref: str
    lock: int = 1
    suspect: int | None = None
    fixed: float | None = None


class AmbiguityBook:
    """Entries by :class:`AmbKey` for one receiver pair (a mutable object owned by an engine).

    Parameters
    ----------
    receivers : tuple of str
        ``(rover, base)`` names carried by every key this book makes.
    """

    def __init__(self, receivers: tuple[str, str] = ("rover", "base")) -> None:
        self.receivers = receivers
        self._entries: dict[AmbKey, AmbEntry] = {}

    # ------------------------------------------------------------------ access
    def key(self, tx: str, signal: str) -> AmbKey:
        """The key of transmitter ``tx`` in group ``signal`` for this book's receivers."""
        return AmbKey(tx, signal, self.receivers)

    def keys(self, txs: Iterable[str], signals: Iterable[str]) -> list[AmbKey]:
        """:meth:`key` of each ``(tx, signal)`` pair (the rows of one DD set, in order)."""
        r = self.receivers
        return [AmbKey(tx, s, r) for tx, s in zip(txs, signals, strict=True)]

    def __contains__(self, key: object) -> bool:
        return key in self._entries

    def __iter__(self) -> Iterator[AmbKey]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def entry(self, key: AmbKey) -> AmbEntry | None:
        """The entry of ``key`` (None when not tracked)."""
        return self._entries.get(key)

    def ref(self, key: AmbKey) -> str | None:
        """Reference transmitter of ``key`` (None when not tracked)."""
        e = self._entries.get(key)
        return None if e is None else e.ref

    def lock(self, key: AmbKey) -> int:
        """Epochs of continuous lock of ``key`` (0 when not tracked)."""
        e = self._entries.get(key)
        return 0 if e is None else e.lock

    def locked(self, keys: Iterable[AmbKey], epochs: int) -> list[bool]:
        """Whether each key's :meth:`lock` is at least ``epochs``, in order."""
        entries = self._entries
        out = []
        for k in keys:
            e = entries.get(k)
            out.append((0 if e is None else e.lock) >= epochs)
        return out

    def stale(
        self, keys: Iterable[AmbKey], present: Container[AmbKey], ref_of: dict[str, str]
    ) -> list[AmbKey]:
        """The keys, in order, that are not ``present`` or whose :meth:`ref` is not the
        reference ``ref_of`` gives their group (None for a group it lacks)."""
        entries = self._entries
        out = []
        for k in keys:
            if k not in present:
                out.append(k)
                continue
            e = entries.get(k)
            if (None if e is None else e.ref) != ref_of.get(k.signal):
                out.append(k)
        return out

    # ------------------------------------------------------------------ life cycle
    def add(self, key: AmbKey, ref: str) -> None:
        """Start tracking ``key`` against ``ref`` (lock 1, nothing suspected or fixed)."""
        self._entries[key] = AmbEntry(ref=ref)

    def forget(self, keys: Iterable[AmbKey]) -> None:
        """Stop tracking ``keys`` (dropped from the state, reset or re-added)."""
        for k in keys:
            self._entries.pop(k, None)

    def tick(self, keys: Iterable[AmbKey]) -> None:
        """One more epoch of lock for each tracked key among ``keys``."""
        for k in keys:
            e = self._entries.get(k)
            if e is not None:
                e.lock += 1

    def set_fixed(self, keys: Iterable[AmbKey], values: Iterable[float]) -> None:
        """Record validated integers."""
        for k, v in zip(keys, values, strict=True):
            e = self._entries.get(k)
            if e is not None:
                e.fixed = float(v)

    # ------------------------------------------------------------------ suspected slips
    def suspect(self, key: AmbKey) -> None:
        """A detector flagged ``key``: start counting rejections (no-op when already suspect)."""
        e = self._entries.get(key)
        if e is not None and e.suspect is None:
            e.suspect = 0

    def rejections(self, key: AmbKey) -> int | None:
        """Rejections counted since ``key`` became suspect (None when not suspect)."""
        e = self._entries.get(key)
        return None if e is None else e.suspect

    def confirmed_slips(self, keys: Iterable[AmbKey], flagged: Iterable[bool], limit: int) -> list[int]:
        """For each key in order, :meth:`suspect` when ``flagged``, then whether its
        :meth:`rejections` reached ``limit``: the positions of those that did."""
        entries = self._entries
        out = []
        for i, (key, flag) in enumerate(zip(keys, flagged, strict=True)):
            e = entries.get(key)
            if e is None:
                continue
            if flag and e.suspect is None:
                e.suspect = 0
            if e.suspect is not None and e.suspect >= limit:
                out.append(i)
        return out

    def judge(self, key: AmbKey, situation: int) -> None:
        """Update a suspect key with its robust situation (1 accepted, 3 rejected).

        An accepted row was a transient error: suspicion clears. A rejected one counts.
        """
        self.judge_all((key,), (situation,))

    def judge_all(self, keys: Iterable[AmbKey], situations: Iterable[int]) -> None:
        """:meth:`judge` of each key with its situation (the rows of one update, in order)."""
        entries = self._entries
        for key, situation in zip(keys, situations, strict=False):
            e = entries.get(key)
            if e is None or e.suspect is None:
                continue
            if situation == 1:
                e.suspect = None
            elif situation == 3:
                e.suspect += 1

    # ------------------------------------------------------------------ reference change
    def rereference(self, signal: str, old_ref: str, new_ref: str) -> None:
        """Group ``signal`` changes reference from ``old_ref`` to ``new_ref``.

        The new reference's entry becomes the old reference's (``N^{k'k} → N^{kk'} =
        −N^{k'k}``: lock kept, fixed value negated) and every entry of the group is
        re-referenced to ``new_ref``; see :func:`rereference_map`.
        """
        k_new = self.key(new_ref, signal)
        k_old = self.key(old_ref, signal)
        moved = self._entries.pop(k_new, None)
        n_ref = None if moved is None else moved.fixed
        for k, e in self._entries.items():
            if k.signal == signal and k.receivers == self.receivers:
                e.ref = new_ref
                # N^{ik'} = N^{ik} − N^{k'k}: known only when both integers are
                e.fixed = None if e.fixed is None or n_ref is None else e.fixed - n_ref
        if moved is not None:
            moved.ref = new_ref
            moved.suspect = None  # a new combination: suspicion does not carry over
            moved.fixed = None if n_ref is None else -n_ref
            self._entries[k_old] = moved


def rereference_map(
    keys: tuple[AmbKey, ...], n_fixed: int, signal: str, old_ref: str, new_ref: str
) -> tuple[FloatArray, tuple[AmbKey, ...]] | None:
    """The state map of a reference change in group ``signal`` (None when nothing to map).

    With old reference ``k`` and new reference ``k'`` (which had the ambiguity ``N^{k'k}``):
    ``N^{ik'} = N^{ik} − N^{k'k}`` for every other ``i`` of the group, and the old
    reference gets ``N^{kk'} = −N^{k'k}``; a unimodular map ``T`` (``x ← T x``,
    ``P ← T P Tᵀ``) that keeps all information and keeps integers integer.

    Returns
    -------
    (T, new_keys) : ndarray (n, n) and the ambiguity keys after the change, or None when
        the new reference had no ambiguity state (left to the usual drop-and-re-add).
    """
    kref = next((k for k in keys if k.signal == signal and k.tx == new_ref), None)
    if kref is None:
        return None
    n = n_fixed + len(keys)
    T = np.eye(n)
    j = n_fixed + keys.index(kref)
    for i, key in enumerate(keys):
        if key != kref and key.signal == signal:
            T[n_fixed + i, j] -= 1.0
    T[j, :] = 0.0
    T[j, j] = -1.0
    new_keys = list(keys)
    new_keys[keys.index(kref)] = kref._replace(tx=old_ref)
    return T, tuple(new_keys)


__all__ = ["AmbEntry", "AmbKey", "AmbiguityBook", "rereference_map"]
