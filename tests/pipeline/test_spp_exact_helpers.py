"""Bit-exact replacements in the Kalman SPP's per-epoch work: each gives the very numbers
of the expression it replaces."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.state import StateLayout
from robustrtk.pipeline.spp_dynamics import SppProcessModel, _acceleration_psd, spp_layout


def _reference_transition(
    model: SppProcessModel, layout: StateLayout, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """The whole-state ``F``, ``Q`` written out on all ``n`` states (the class formulas)."""
    n, nf = layout.size, layout.n_fixed
    a = abs(dt)
    F, Q = np.eye(n), np.zeros((n, n))
    p, v, d = layout.slice("pos"), layout.slice("vel"), layout.slice("drift").start
    F[p, v] = np.eye(3) * dt
    qa = _acceleration_psd(model.up_at_m, model.sigma_acc_m_s2, model.sigma_acc_up_m_s2)
    Q[p, p] = qa * a**3 / 3
    Q[p, v] = Q[v, p] = qa * dt**2 / 2
    Q[v, v] = qa * a
    clocks = list(range(layout.slice("clk").start, layout.slice("clk").stop))
    q_own = [model.q_clk_m2_s] * len(clocks)
    if layout.has("pclk"):
        pc = list(range(layout.slice("pclk").start, layout.slice("pclk").stop))
        clocks += pc
        q_own += [model.q_phase_clk_m2_s] * len(pc)
    ci = np.array(clocks)
    F[ci, d] = dt
    Q[np.ix_(ci, ci)] = model.q_drift_m2_s3 * a**3 / 3 + np.diag(q_own) * a
    Q[ci, d] = Q[d, ci] = model.q_drift_m2_s3 * dt**2 / 2
    Q[d, d] = model.q_drift_m2_s3 * a
    if layout.has("ifb"):
        f = layout.slice("ifb")
        Q[f, f] = np.eye(f.stop - f.start) * model.q_ifb_m2_s * a
    for r in range(nf, n):
        Q[r, r] = model.q_amb_m2_s * a
    return F, Q


@settings(max_examples=300, deadline=None)
@given(
    st.floats(-5.0, 5.0, width=64),
    st.integers(1, 4),
    st.booleans(),
    st.integers(0, 3),
    st.integers(0, 6),
    st.sampled_from([None, (-2.7e6, -4.3e6, 3.85e6), (6.378e6, 0.0, 0.0)]),
)
def test_remembered_transition_is_fresh_one(
    dt: float, n_sys: int, phase: bool, n_b2: int, n_amb: int, up: tuple[float, float, float] | None
) -> None:
    fixed = spp_layout(n_sys, phase, min(n_b2, n_sys))
    layout = StateLayout(blocks=fixed.blocks, amb_keys=tuple(("G01", 0, k) for k in range(n_amb)))
    model = SppProcessModel(up_at_m=up)
    for _ in range(2):  # the second call is served from memory
        F, Q = model.transition(layout, dt)
        Fr, Qr = _reference_transition(model, layout, dt)
        assert F.tobytes() == Fr.tobytes() and Q.tobytes() == Qr.tobytes()
        F[0, 0] = 7.0  # the caller owns its arrays
    F0, _ = model.transition(StateLayout(blocks=fixed.blocks), -0.0)
    F1, _ = model.transition(StateLayout(blocks=fixed.blocks), 0.0)
    assert math.copysign(1.0, F0[0, 3]) == -1.0 and math.copysign(1.0, F1[0, 3]) == 1.0


def test_step_part_remembered_across_verticals() -> None:
    """The same step at new positions (an epoch after another): the step-only part is
    served from memory, the position–velocity block follows the vertical."""
    layout = StateLayout(blocks=spp_layout(3, True, 2).blocks, amb_keys=(("G01", 0, 0), ("E11", 1, 2)))
    for up in [(-2.7e6, -4.3e6, 3.85e6), (-2.7e6, -4.3e6, 3.86e6), None, (4.0e6, 1.0e6, 4.8e6)]:
        model = SppProcessModel(up_at_m=up)
        F, Q = model.transition(layout, 1.0)
        Fr, Qr = _reference_transition(model, layout, 1.0)
        assert F.tobytes() == Fr.tobytes() and Q.tobytes() == Qr.tobytes()


def test_at_remembers_only_the_same_bits() -> None:
    base = SppProcessModel()
    p = np.array([-2.7e6, 0.0, 3.85e6])
    a = base.at(p)
    assert base.at(p.copy()) is a and a == SppProcessModel(up_at_m=(-2.7e6, 0.0, 3.85e6))
    b = base.at(np.array([-2.7e6, -0.0, 3.85e6]))
    assert b is not a and math.copysign(1.0, b.up_at_m[1]) == -1.0  # type: ignore[index]
    assert SppProcessModel(sigma_acc_m_s2=1.0).at(p).sigma_acc_m_s2 == 1.0
