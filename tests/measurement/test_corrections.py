"""Saastamoinen troposphere and Klobuchar ionosphere."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import CLIGHT
from robustrtk.geometry.frames import ecef2geodetic
from robustrtk.geometry.los import azimuth_elevation
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.measurement.corrections import (
    iono_klobuchar,
    standard_atmosphere,
    tropo_saastamoinen,
    tropo_zenith_saastamoinen,
)

ALPHA = np.array([0.9313e-08, 0.1490e-07, -0.5960e-07, -0.1192e-06])
BETA = np.array([0.8806e05, 0.4915e05, -0.1311e06, -0.3277e06])


def test_standard_atmosphere_sea_level() -> None:
    p, t, e = standard_atmosphere(0.0, humidity=0.7)
    assert p == pytest.approx(1013.25)
    assert t == pytest.approx(288.16)
    assert e == pytest.approx(11.98, abs=0.05)  # hand-computed Magnus-type formula


def test_zenith_delay_sea_level() -> None:
    zhd, zwd = tropo_zenith_saastamoinen(np.radians(45.0), 0.0)
    # 0.0022768 * 1013.25 / (1 - 0) = 2.30697 m at 45 deg (cos 90 = 0)
    assert zhd == pytest.approx(0.0022768 * 1013.25, abs=1e-6)
    assert 0.05 < zwd < 0.2
    assert zhd + zwd == pytest.approx(2.43, abs=0.02)
    # higher sites see less: ~ -12 % per km near sea level for the hydrostatic part
    zhd1, _ = tropo_zenith_saastamoinen(np.radians(45.0), 1000.0)
    assert zhd1 / zhd == pytest.approx((1 - 2.2557e-2) ** 5.2568, rel=1e-3)


def test_slant_mappings() -> None:
    lat, h = np.radians(35.0), 50.0
    el = np.radians([90.0, 60.0, 30.0, 15.0, 10.0])
    z = tropo_saastamoinen(lat, h, el, mapping="zenith")
    s = tropo_saastamoinen(lat, h, el, mapping="sine")
    sa = tropo_saastamoinen(lat, h, el)
    np.testing.assert_allclose(s, z / np.sin(el))
    assert sa[0] == pytest.approx(z[0], rel=1e-3)
    assert np.all(np.diff(sa) > 0)  # grows toward the horizon
    # the two mappings agree within 0.5 % down to 30 deg, 2 % at 15 deg
    np.testing.assert_allclose(sa[:3], s[:3], rtol=0.005)
    np.testing.assert_allclose(sa[3], s[3], rtol=0.02)
    # no correction below the horizon or at absurd heights
    assert tropo_saastamoinen(lat, h, -0.1) == 0.0
    assert tropo_saastamoinen(lat, 2.0e4, 0.5) == 0.0
    with pytest.raises(ValueError):
        tropo_saastamoinen(lat, h, 0.5, mapping="bogus")


def test_klobuchar_night_and_bounds() -> None:
    lat, lon = np.radians(37.4), np.radians(-122.1)
    # local midnight at lon -122.1 deg: GPS time of day ~ 8.1 h
    t_night = 8.14 * 3600.0
    d = iono_klobuchar(t_night, lat, lon, 0.0, np.pi / 2, ALPHA, BETA)
    # night-time zenith: F * 5 ns * c with F = 1 + 16 (0.53 - 0.5)^3
    assert d == pytest.approx(CLIGHT * 5e-9 * (1 + 16 * 0.03**3), rel=1e-9)
    # over a day the zenith delay varies between the night floor and a daytime peak
    t = np.arange(0.0, 86400.0, 600.0)
    day = iono_klobuchar(t, lat, lon, 0.0, np.pi / 2, ALPHA, BETA)
    assert day.min() >= d - 1e-9
    assert 2.0 < day.max() < 30.0
    peak_local_h = (t[np.argmax(day)] / 3600.0 + np.degrees(lon) / 15.0) % 24.0
    assert abs(peak_local_h - 14.0) < 1.5
    # low satellites see more (obliquity factor up to ~3)
    low = iono_klobuchar(t, lat, lon, 0.0, np.radians(5.0), ALPHA, BETA)
    assert np.all(low > day) and np.all(low < 3.5 * day)


def test_klobuchar_frequency_scaling_and_horizon() -> None:
    lat, lon = 0.3, 2.0
    d1 = iono_klobuchar(50000.0, lat, lon, 1.0, 0.6, ALPHA, BETA)
    d5 = iono_klobuchar(50000.0, lat, lon, 1.0, 0.6, ALPHA, BETA, freq_hz=1176.45e6)
    assert d5 / d1 == pytest.approx((1575.42 / 1176.45) ** 2)
    assert iono_klobuchar(50000.0, lat, lon, 1.0, -0.1, ALPHA, BETA) == 0.0


def test_klobuchar_matches_vendor(shared_data: Path) -> None:
    """device_gnss.csv carries the vendor's Klobuchar delays for brdc1190.21n coefficients."""
    base = shared_data / "android_parser_fixtures"
    nav = read_rinex_nav(base / "rinex/nav/brdc1190.21n")
    with open(base / "google_decimeter_2022/device_gnss.csv", newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["SvPositionXEcefMeters"]]
    sat = np.array([[float(r[f"SvPosition{a}EcefMeters"]) for a in "XYZ"] for r in rows])
    rx = np.array([float(rows[0][f"WlsPosition{a}EcefMeters"]) for a in "XYZ"])
    lat, lon, h = ecef2geodetic(rx)
    az, el = azimuth_elevation(sat, rx)
    t = np.array([float(r["ArrivalTimeNanosSinceGpsEpoch"]) * 1e-9 for r in rows])
    f = np.array([float(r["CarrierFrequencyHz"]) for r in rows])
    assert nav.ion_gps_alpha is not None and nav.ion_gps_beta is not None
    iono = iono_klobuchar(t, float(lat), float(lon), az, el, nav.ion_gps_alpha, nav.ion_gps_beta, f)
    ref = np.array([float(r["IonosphericDelayMeters"]) for r in rows])
    assert np.abs(iono - ref).max() < 1e-3  # all systems and bands (GLONASS FDMA too)
    # vendor troposphere: model unpublished; within each epoch its elevation dependence
    # matches Saastamoinen's above 10 deg (a constant ratio, 2-3 % from other meteorology)
    tropo = tropo_saastamoinen(float(lat), float(h), el)
    ref_t = np.array([float(r["TroposphericDelayMeters"]) for r in rows])
    epoch = np.array([r["utcTimeMillis"] for r in rows])
    high = el > np.radians(10.0)
    ratio = tropo / ref_t
    for ep in np.unique(epoch):
        sel = high & (epoch == ep)
        assert sel.sum() >= 5
        assert np.ptp(ratio[sel]) < 0.005
    assert abs(ratio[high].mean() - 1.0) < 0.05
