"""Per-receiver slip detectors of the GNSS RTK driver on synthetic rows."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from robustrtk.core import empty_batch
from robustrtk.pipeline.rtk_gnss import detector_slips, rtk_gnss_config


def _rows(T: int = 30) -> object:
    lam1, lam2 = 0.19029367, 0.24421021
    b = empty_batch(
        np.arange(T, dtype=float),
        ("G01:L1", "G01:L2", "G02:L1"),
        ("G", "G", "G"),
        ("f",),
        wavelength_m=np.array([[lam1], [lam2], [lam1]]),
    )
    t = np.arange(T, dtype=float)
    rng_m = 2.0e7 + 500.0 * t  # range rate 500 m/s
    ph = np.stack([rng_m / lam1, rng_m / lam2, (rng_m + 100.0) / lam1], axis=1)[:, :, None]
    # RINEX sign: phase rate = -Doppler
    dop = np.tile([-500.0 / lam1, -500.0 / lam2, -500.0 / lam1], (T, 1))[:, :, None]
    return replace(b, phase_cyc=ph.copy(), doppler_hz=dop.copy())


def test_geometry_free_flags_both_rows_of_the_satellite() -> None:
    b = _rows()
    ph = b.phase_cyc.copy()  # type: ignore[attr-defined]
    ph[15:, 0, 0] += 1.0  # one-cycle slip on G01 L1 from epoch 15
    flags = detector_slips(replace(b, phase_cyc=ph), rtk_gnss_config(slip="lli+gf"))  # type: ignore[type-var]
    assert flags[15, 0] and flags[15, 1]  # both frequencies of G01
    assert flags.sum() == 2  # nothing else (G02 has no second frequency, no jump)


def test_doppler_flags_the_slipped_row_only_and_clean_data_is_quiet() -> None:
    b = _rows()
    cfg = rtk_gnss_config(slip="lli+doppler")
    assert not detector_slips(b, cfg).any()
    ph = b.phase_cyc.copy()  # type: ignore[attr-defined]
    ph[20:, 2, 0] -= 1.0
    flags = detector_slips(replace(b, phase_cyc=ph), cfg)  # type: ignore[type-var]
    assert flags[20, 2] and flags.sum() == 1


def test_no_detectors_no_flags() -> None:
    b = _rows()
    ph = b.phase_cyc.copy()  # type: ignore[attr-defined]
    ph[10:, 0, 0] += 5.0
    assert not detector_slips(replace(b, phase_cyc=ph), rtk_gnss_config(slip="lli")).any()  # type: ignore[type-var]
