"""The per-epoch slip detector gives, epoch by epoch, the flags of the whole-array front end."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import ObsBatch
from robustrtk.cycleslip.lli import half_cycle_flags
from robustrtk.pipeline.rtk_gnss import (
    detector_slips,
    mark_half_cycle_jumps,
    online_detector,
    rtk_gnss_config,
)


def rows_batch(seed: int, T: int, n_sat: int, gaps: float) -> ObsBatch:
    """A random signal-row batch: two slots per satellite, slips, gaps, LLI bits, Doppler."""
    rng = np.random.default_rng(seed)
    sats = [f"G{k + 1:02d}" for k in range(n_sat)]
    ids = tuple(f"{s}:{slot}" for slot in ("L1", "L2") for s in sats)
    R = len(ids)
    dt = rng.choice([0.2, 1.0, 1.0, 3.0, 150.0], size=T)
    t = 1000.0 + np.cumsum(dt)
    rate = rng.normal(0, 500, R)
    phase = rate[None, :] * (t - t[0])[:, None] + rng.normal(0, 0.02, (T, R))
    phase += np.cumsum(rng.random((T, R)) < 0.05, axis=0) * rng.choice([1.0, 0.5, 3.0], size=R)
    phase[rng.random((T, R)) < gaps] = np.nan
    doppler = -rate[None, :] + rng.normal(0, 0.2, (T, R))
    doppler[rng.random((T, R)) < 0.1] = np.nan
    lli = rng.choice(np.array([0, 0, 0, 1, 2, 3], np.int8), size=(T, R))
    lam = np.where(np.arange(R) < n_sat, 0.19, 0.244)[:, None]
    nanf = np.full((T, R, 1), np.nan)
    return ObsBatch(
        t_s=t, tx_ids=ids, system=tuple("G" for _ in ids), signals=("f",), code_m=nanf.copy(),
        phase_cyc=phase[:, :, None], doppler_hz=doppler[:, :, None], cn0_dbhz=nanf.copy(),
        lli=lli[:, :, None], wavelength_m=lam,
    )  # fmt: skip


def assert_same_flags(batch: ObsBatch, detectors: str, window_s: float) -> None:
    cfg = rtk_gnss_config(slip=detectors, gf_window_s=window_s)
    marked = mark_half_cycle_jumps(batch)
    want = detector_slips(marked, cfg)
    want_half = half_cycle_flags(marked.lli[:, :, 0])
    det = online_detector(cfg)
    for i in range(len(batch)):
        out = det.step(batch.epoch(i))
        np.testing.assert_array_equal(out.slip, want[i], err_msg=f"epoch {i}")
        np.testing.assert_array_equal(out.half_cycle, want_half[i])
        np.testing.assert_array_equal(out.epoch.lli, marked.lli[i])


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    T=st.integers(1, 60),
    n_sat=st.integers(1, 4),
    gaps=st.sampled_from([0.0, 0.1, 0.4]),
    detectors=st.sampled_from(["gf+doppler", "gf", "doppler", "none"]),
    window_s=st.sampled_from([0.0, 3.0, 10.0]),
)
def test_online_flags_equal_whole_array(
    seed: int, T: int, n_sat: int, gaps: float, detectors: str, window_s: float
) -> None:
    assert_same_flags(rows_batch(seed, T, n_sat, gaps), detectors, window_s)


def test_online_flags_equal_on_a_shared_rover(shared_data: Path) -> None:
    """Kamakura's moving rover (GPS/GAL/QZS L1/L2/L5): every detector, drift window on."""
    from robustrtk.io.rinex_obs import read_rinex_obs
    from robustrtk.measurement.signals import signal_rows

    path = shared_data / "kamakura_kinematic_5km" / "SEPT265G.21O"
    if not path.is_file():
        pytest.skip(f"{path} absent")
    rover = signal_rows(read_rinex_obs(path), ("L1", "L2", "L5"), "GECJ")
    cfg = rtk_gnss_config(slip="gf+doppler", gf_window_s=10.0)
    assert detector_slips(mark_half_cycle_jumps(rover), cfg).any()  # the comparison sees slips
    assert_same_flags(rover, "gf+doppler", 10.0)
