"""The base buffer: which base epoch serves each rover epoch, its age, and its events."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import ObsEpoch
from robustrtk.measurement.base_propagation import PropagatedEpoch, age_variance_m2, propagate_base_epoch
from robustrtk.pipeline.base_buffer import BaseEvents, pair_base_epochs, with_base_events


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 40),
    rate=st.sampled_from([0.1, 0.2, 1.0]),
    base_every=st.sampled_from([1, 5, 30]),
    jitter=st.floats(-0.012, 0.012),
    max_age=st.floats(0.0, 60.0),
)
def test_pairs_follow_the_rule(n: int, rate: float, base_every: int, jitter: float, max_age: float) -> None:
    tr = 1000.0 + rate * np.arange(n * int(round(1 / rate)))
    tb = 1000.0 + jitter + base_every * np.arange(n)
    pairs = pair_base_epochs(tr, tb, 0.005 if rate < 1 else 0.5, max_age)
    seen = {p.i_rover for p in pairs}
    for p in pairs:
        dt = tr[p.i_rover] - tb[p.i_base]
        if p.exact:
            assert p.age_s == 0.0 and abs(dt) <= (0.005 if rate < 1 else 0.5)
        else:
            # the latest base epoch not after the rover epoch, no older than max_age
            assert p.age_s == pytest.approx(dt) and 0 < p.age_s <= max_age
            assert p.i_base == int(np.searchsorted(tb, tr[p.i_rover], side="right")) - 1
    for i, t in enumerate(tr):
        if i in seen:
            continue
        older = tb[tb <= t]
        assert older.size == 0 or t - older[-1] > max_age


def test_same_epochs_pair_exactly_whatever_the_age() -> None:
    t = 5000.0 + np.arange(30.0)
    for max_age in (0.0, 30.0):
        pairs = pair_base_epochs(t - 0.011, t + 0.003, 0.5, max_age)
        got = [(p.i_rover, p.i_base, p.age_s, p.exact) for p in pairs]
        assert got == [(i, i, 0.0, True) for i in range(30)]


def test_too_old_is_not_differential() -> None:
    pairs = pair_base_epochs(np.array([0.0, 10.0, 31.0]), np.array([0.0]), 0.5, 30.0)
    assert [p.i_rover for p in pairs] == [0, 1]


def test_unusable_base_epochs_are_passed_over() -> None:
    tb = np.array([0.0, 1.0, 2.0])
    pairs = pair_base_epochs(np.array([2.0]), tb, 0.5, 30.0, usable=np.array([True, True, False]))
    assert (pairs[0].i_base, pairs[0].age_s, pairs[0].exact) == (1, 1.0, False)


def test_base_events_reach_the_next_rover_epoch_once() -> None:
    flags = np.zeros((6, 2), bool)
    flags[2, 0] = True  # a slip on a base epoch that serves no rover epoch
    flags[4, 1] = True
    ev = BaseEvents(flags)
    got = [ev.since_last(j).tolist() for j in (0, 1, 1, 3, 3, 4, 5)]
    assert got == [[0, 0], [0, 0], [0, 0], [1, 0], [0, 0], [0, 1], [0, 0]]


def _epoch(t: float, code: np.ndarray, lam: float = 0.19) -> ObsEpoch:
    n = code.size
    return ObsEpoch(
        t_s=t, tx_ids=tuple(f"P{i}" for i in range(n)), system=("P",) * n, signals=("L1",),
        code_m=code[:, None].copy(), phase_cyc=(code / lam)[:, None] + 7.0,
        doppler_hz=np.full((n, 1), np.nan),
        cn0_dbhz=np.full((n, 1), 45.0), lli=np.ones((n, 1), np.int8), wavelength_m=np.full((n, 1), lam),
    )  # fmt: skip


class MovingSource:
    """Transmitters on straight lines, clocks drifting (pseudolite-like, local frame)."""

    def __init__(self) -> None:
        self.p0 = np.array([[100.0, 0, 50], [0, 200.0, 80], [-150.0, 40, 60]])
        self.v = np.array([[3.0, 1, 0], [-2.0, 0, 1], [0.5, -4, 0]])
        self.drift = np.array([0.1, -0.2, 0.05])

    def positions(self, t_s: float, tx_ids: object, code_m: object = None) -> tuple[np.ndarray, np.ndarray]:
        return self.p0 + self.v * t_s, self.drift * t_s


def test_propagation_reproduces_the_later_observation() -> None:
    src, pos = MovingSource(), np.array([1.0, 2.0, 0.0])

    def observed(t: float) -> ObsEpoch:
        p, c = src.positions(t, None)
        return _epoch(t, np.linalg.norm(p - pos, axis=1) - c + 3.0)  # + a receiver clock

    e = propagate_base_epoch(
        observed(10.0), 17.0, src, pos, sagnac=False, troposphere=False, sigma_age_m_s=0.01
    )
    later = observed(17.0)
    assert isinstance(e, PropagatedEpoch) and e.t_s == 17.0 and e.age_s == pytest.approx(7.0)
    np.testing.assert_allclose(e.code_m, later.code_m, atol=1e-9)
    np.testing.assert_allclose(e.phase_cyc, later.phase_cyc, atol=1e-8)
    assert e.age_var_m2 == pytest.approx(age_variance_m2(7.0, 0.01)) == pytest.approx(0.07**2)
    # the loss-of-lock event is the first use's alone; the half-cycle bit is a state and stays
    ep = with_base_events(_epoch(0.0, np.ones(3)), np.zeros((3, 1), bool))
    assert (ep.lli == 0).all()
    half = _epoch(0.0, np.ones(3))
    half = type(half)(**{**half.__dict__, "lli": np.full((3, 1), 3, np.int8)})
    half = with_base_events(half, np.zeros((3, 1), bool))
    assert (half.lli == 2).all()
