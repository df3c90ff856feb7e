"""Phone profile: each part of the model checked against the geodetic file it degrades."""

from __future__ import annotations

import csv
from functools import cache
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.inject import inject
from robustrtk.core import InputError, ObsBatch
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.sim.phone import PHONE_SIGNALS, PhoneProfile, PhoneResult, parse_params, phone_profile

KAMAKURA = "kamakura_kinematic_5km/SEPT265G.21O"
MOSAIC = "mosaicx5_static_1m/rover.obs"


@cache
def _geo(root: str, rel: str) -> ObsBatch:
    return read_rinex_obs(Path(root) / rel)


@cache
def _phone(root: str, rel: str, seed: int) -> PhoneResult:
    return phone_profile(_geo(root, rel), seed=seed)


def _matched(geo: ObsBatch, ph: ObsBatch) -> list[int]:
    """Column of ``geo`` of each phone signal."""
    return [geo.signals.index(s) for s in ph.signals]


def test_same_seed_same_output_other_seed_differs(shared_data: Path) -> None:
    a = _phone(str(shared_data), KAMAKURA, 1).batch
    b = phone_profile(_geo(str(shared_data), KAMAKURA), seed=1).batch
    c = _phone(str(shared_data), KAMAKURA, 2).batch
    for name in ("code_m", "phase_cyc", "cn0_dbhz", "lli"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(np.nan_to_num(a.code_m), np.nan_to_num(c.code_m))


def test_only_phone_signals_are_kept(shared_data: Path) -> None:
    for rel in (KAMAKURA, MOSAIC):
        ph = _phone(str(shared_data), rel, 1).batch
        assert {s[0] for s in ph.signals} <= {"1", "2", "5"}
        for j, sig in enumerate(ph.signals):
            for n, system in enumerate(ph.system):
                allowed = any(sig in prefs for prefs in PHONE_SIGNALS.get(system, ()))
                if not allowed:
                    assert not np.isfinite(ph.code_m[:, n, j]).any(), (system, sig)
    assert _phone(str(shared_data), KAMAKURA, 1).batch.signals == ("1C", "5Q")


def test_cn0_is_lowered_by_the_band_loss(shared_data: Path) -> None:
    geo = _geo(str(shared_data), KAMAKURA)
    ph = _phone(str(shared_data), KAMAKURA, 1).batch
    prof = PhoneProfile()
    for j, k in enumerate(_matched(geo, ph)):
        d = ph.cn0_dbhz[:, :, j] - geo.cn0_dbhz[:, :, k]
        loss = prof.cn0_loss_l5_db if ph.signals[j][0] == "5" else prof.cn0_loss_l1_db
        # the walk has zero mean; losing the weakest cells biases the median up a little
        assert abs(float(np.nanmedian(d)) + loss) < 1.0, ph.signals[j]
    assert np.nanmin(ph.cn0_dbhz) >= prof.track_min_dbhz


def test_code_noise_matches_the_reported_sigma(shared_data: Path) -> None:
    geo = _geo(str(shared_data), KAMAKURA)
    res = _phone(str(shared_data), KAMAKURA, 1)
    ph = res.batch
    assert ph.code_sigma_m is not None
    nlos = np.zeros(ph.code_m.shape, dtype=bool)
    for ev in res.events:
        if ev.kind == "nlos":
            nlos[ev.start : ev.start + ev.epochs, ph.tx_ids.index(ev.tx), ph.signals.index(ev.signal)] = True
    k = _matched(geo, ph)
    z = (ph.code_m - geo.code_m[:, :, k]) / ph.code_sigma_m
    z = z[np.isfinite(z) & ~nlos]
    assert z.size > 3000
    # the geodetic code noise (dm) is small against a phone's (m): the ratio is ~N(0, 1)
    std = 1.4826 * float(np.median(np.abs(z - np.median(z))))
    assert 0.9 < std < 1.1 and abs(float(np.mean(z))) < 0.1
    # the NLOS bursts are there, of the drawn sizes
    d = (ph.code_m - geo.code_m[:, :, k])[nlos]
    assert np.nanmedian(d) > 9.0


def _phase_offsets(root: str, rel: str, seed: int) -> tuple[PhoneResult, np.ndarray, set[tuple[int, int]]]:
    geo = _geo(root, rel)
    res = _phone(root, rel, seed)
    ph = res.batch
    d = ph.phase_cyc - geo.phase_cyc[:, :, _matched(geo, ph)]
    drift = {(ph.tx_ids.index(e.tx), ph.signals.index(e.signal)) for e in res.events if e.kind == "drift"}
    return res, d, drift


def test_phase_offsets_are_integers_or_flagged_half_cycles(shared_data: Path) -> None:
    res, d, drift = _phase_offsets(str(shared_data), KAMAKURA, 1)
    ph = res.batch
    half = (ph.lli & 2) != 0
    n_half = 0
    for n in range(d.shape[1]):
        for j in range(d.shape[2]):
            if (n, j) in drift:
                continue
            ok = np.isfinite(d[:, n, j])
            x = d[ok, n, j] - np.where(half[ok, n, j], 0.5, 0.0)
            sigma = ph.phase_sigma_cyc[ok, n, j]  # type: ignore[index]
            # within 5 σ of the phone's white phase noise (the geodetic noise is ~1 mm)
            assert np.all(np.abs(x - np.round(x)) < 5 * sigma + 0.01), (ph.tx_ids[n], ph.signals[j])
            n_half += int(half[ok, n, j].sum())
    assert n_half > 50


def test_the_integer_offset_changes_only_with_a_loss_of_lock(shared_data: Path) -> None:
    """A phone arc that continues without the loss-of-lock bit keeps its ambiguity: the
    property that makes keeping an ambiguity through an unflagged gap safe in this model."""
    res, d, drift = _phase_offsets(str(shared_data), KAMAKURA, 1)
    ph = res.batch
    n_reset = n_silent_gap = 0
    for n in range(d.shape[1]):
        for j in range(d.shape[2]):
            if (n, j) in drift:
                continue
            idx = np.flatnonzero(np.isfinite(d[:, n, j]))
            half = np.where((ph.lli[idx, n, j] & 2) != 0, 0.5, 0.0)
            off = np.round(d[idx, n, j] - half)
            for a, b in zip(idx[:-1], idx[1:], strict=True):
                ia, ib = np.searchsorted(idx, a), np.searchsorted(idx, b)
                lost = bool(ph.lli[b, n, j] & 1)
                if off[ib] != off[ia]:
                    assert lost, (ph.tx_ids[n], ph.signals[j], int(b))
                    n_reset += 1
                elif b - a > 1 and not lost:
                    n_silent_gap += 1
    assert n_reset > 20 and n_silent_gap > 20


def test_duty_cycle_gaps_are_short(shared_data: Path) -> None:
    res = _phone(str(shared_data), KAMAKURA, 1)
    prof = PhoneProfile()
    gaps = [e for e in res.events if e.kind in ("gap", "reset")]
    assert len(gaps) > 100
    assert all(1 <= e.epochs <= prof.duty_gap_max_epochs for e in gaps)
    ph = res.batch
    for e in gaps[:50]:
        n, j = ph.tx_ids.index(e.tx), ph.signals.index(e.signal)
        assert not np.isfinite(ph.phase_cyc[e.start : e.start + e.epochs, n, j]).any()


def test_profile_parameters_are_checked() -> None:
    assert PhoneProfile().updated(duty_on_s=10).duty_on_s == 10.0
    assert parse_params(["p_half=0.5", "duty_gap_max_epochs=2"]) == {
        "p_half": 0.5,
        "duty_gap_max_epochs": 2.0,
    }
    with pytest.raises(InputError, match="unknown parameter 'nope'"):
        PhoneProfile().updated(nope=1)
    with pytest.raises(InputError, match="p_half is a probability"):
        PhoneProfile(p_half=1.5).validate()
    with pytest.raises(InputError, match="NAME=NUMBER"):
        parse_params(["p_half"])


@click.group()
def _cli() -> None:
    """Test group holding the command as the real CLI does."""


_cli.add_command(inject)


def test_inject_phone_profile_writes_rinex_and_event_log(shared_data: Path, tmp_path: Path) -> None:
    out = tmp_path / "phone.obs"
    r = CliRunner().invoke(
        _cli, ["inject", str(shared_data / KAMAKURA), "--phone-profile", "--seed", "1", "--out", str(out)]
    )
    assert r.exit_code == 0, r.output
    back = read_rinex_obs(out)
    mem = _phone(str(shared_data), KAMAKURA, 1)
    assert back.signals == mem.batch.signals
    k = [mem.batch.tx_ids.index(t) for t in back.tx_ids]
    np.testing.assert_allclose(back.code_m, mem.batch.code_m[:, k], atol=6e-4, equal_nan=True)
    np.testing.assert_allclose(back.phase_cyc, mem.batch.phase_cyc[:, k], atol=6e-4, equal_nan=True)
    np.testing.assert_array_equal(back.lli, mem.batch.lli[:, k])
    with open(str(out) + ".phone.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(mem.events)
    bad = CliRunner().invoke(
        _cli,
        [
            "inject",
            str(shared_data / KAMAKURA),
            "--phone-profile",
            "--phase",
            "G05:L1C:1:3",
            "--out",
            str(out),
        ],
    )
    assert bad.exit_code == 2 and "--phone-profile" in bad.stderr and "Traceback" not in bad.output
    bad = CliRunner().invoke(
        _cli,
        [
            "inject",
            str(shared_data / KAMAKURA),
            "--phone-profile",
            "--phone-param",
            "p_half=3",
            "--out",
            str(out),
        ],
    )
    assert bad.exit_code == 2 and "p_half" in bad.stderr
