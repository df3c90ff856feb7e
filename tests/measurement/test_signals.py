"""Signal selection into (satellite, frequency slot) rows."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from robustrtk.core import empty_batch
from robustrtk.measurement.signals import RowSource, choose_signals, parse_slots, row_satellite, signal_rows


def _batch() -> object:
    sigs = ("1C", "2L", "2W", "5Q", "7Q")
    b = empty_batch(
        np.arange(4.0),
        ("G01", "G02", "E03"),
        ("G", "G", "E"),
        sigs,
        wavelength_m=np.arange(15.0).reshape(3, 5) + 1.0,
    )
    code = b.code_m.copy()
    ph = b.phase_cyc.copy()
    code[:, :, 0] = 2e7
    ph[:, :, 0] = 1e8
    # GPS L2: 2W on both satellites (more phase), 2L only on G01
    code[:, :2, 2] = 2e7
    ph[:, :2, 2] = 1e8
    code[:, 0, 1] = 2e7
    ph[:, 0, 1] = 1e8
    # Galileo: E5b (7Q) present, E5a (5Q) present too
    code[:, 2, 4] = 2e7
    ph[:, 2, 4] = 1e8
    code[:, 2, 3] = 2e7
    ph[:, 2, 3] = 1e8
    return replace(b, code_m=code, phase_cyc=ph)


def test_parse_slots() -> None:
    assert parse_slots("L1+L2") == ("L1", "L2")
    assert parse_slots("1,5") == ("L1", "L5")
    with pytest.raises(ValueError, match="given twice"):  # a repeated frequency is a typo, not L2
        parse_slots("l2+L2")
    with pytest.raises(ValueError, match="L1, L2 or L5"):
        parse_slots("L7")
    with pytest.raises(ValueError):
        parse_slots("+")


def test_choose_signals_prefers_most_phase_and_band_order() -> None:
    b = _batch()
    cols = choose_signals(b, ("L1", "L2", "L5"))  # type: ignore[arg-type]
    sig = {k: b.signals[v] for k, v in cols.items()}  # type: ignore[attr-defined]
    assert sig[("G", "L1")] == "1C"
    assert sig[("G", "L2")] == "2W"  # on both satellites, 2L on one only
    assert sig[("E", "L2")] == "7Q"  # E5b preferred over E5a for the L2 slot
    assert sig[("E", "L5")] == "5Q"
    assert ("G", "L5") not in cols  # no data


def test_signal_rows_layout_and_values() -> None:
    b = _batch()
    rows = signal_rows(b, ("L1", "L2"), systems="GE")  # type: ignore[arg-type]
    assert rows.tx_ids == ("G01:L1", "G02:L1", "E03:L1", "G01:L2", "G02:L2", "E03:L2")
    assert rows.system == ("G", "G", "E", "G", "G", "E")
    assert rows.code_m.shape == (4, 6, 1)
    # wavelengths follow the chosen columns: G01 L2 is 2W (column 2), E03 L2 is 7Q (column 4)
    assert rows.wavelength_m[3, 0] == b.wavelength_m[0, 2]  # type: ignore[attr-defined]
    assert rows.wavelength_m[5, 0] == b.wavelength_m[2, 4]  # type: ignore[attr-defined]
    assert rows.meta["signal_by_slot"]["G:L2"] == "2W"
    only_g = signal_rows(b, ("L1",), systems="G")  # type: ignore[arg-type]
    assert only_g.tx_ids == ("G01:L1", "G02:L1")
    assert row_satellite("G01:L2") == "G01"


class _Fake:
    def __init__(self) -> None:
        self.calls: list[tuple[list[str], np.ndarray | None]] = []

    def positions(
        self, t_s: float, ids: list[str], code: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        self.calls.append((list(ids), None if code is None else np.asarray(code)))
        pos = np.array([[float(i[1:]), 0.0, 0.0] for i in ids])
        return pos, np.zeros(len(ids))


def test_row_source_evaluates_each_satellite_once() -> None:
    fake = _Fake()
    src = RowSource(fake)
    ids = ("G01:L1", "G02:L1", "G01:L2", "G02:L2")
    pos, _ = src.positions(0.0, ids, np.array([np.nan, 2.0e7, 2.1e7, 2.2e7]))
    assert fake.calls[0][0] == ["G01", "G02"]
    # first finite pseudorange of each satellite: G01 from its L2 row, G02 from L1
    assert np.allclose(fake.calls[0][1], [2.1e7, 2.0e7])  # type: ignore[arg-type]
    assert np.allclose(pos[:, 0], [1.0, 2.0, 1.0, 2.0])


def test_signal_rows_carry_the_reported_sigmas() -> None:
    b = empty_batch(np.arange(3.0), ("G01", "G02"), ("G", "G"), ("1C", "5Q"))
    code = np.arange(12.0).reshape(3, 2, 2)
    b = replace(b, code_m=code, code_sigma_m=code + 100.0, phase_sigma_cyc=code / 100.0)
    rows = signal_rows(b, ("L1", "L5"), "G")
    assert rows.tx_ids == ("G01:L1", "G02:L1", "G01:L5", "G02:L5")
    assert rows.code_sigma_m is not None and rows.phase_sigma_cyc is not None
    np.testing.assert_array_equal(rows.code_sigma_m - 100.0, rows.code_m)
    np.testing.assert_allclose(rows.phase_sigma_cyc * 100.0, rows.code_m)


def test_row_satellites_and_their_first_finite_pseudorange() -> None:
    from robustrtk.measurement.signals import RowSource

    rows = ("G05:L1", "G05:L2", "E11:E1", "G07:L1", "E11:E5a", "G07:L5")
    code = np.array([np.nan, 2.1e7, 2.3e7, 2.2e7, 2.35e7, np.nan])
    for _ in range(2):  # the second call takes the remembered row layout
        uniq, inv, code_u = RowSource._satellites(rows, code)
        assert uniq == ["G05", "E11", "G07"]
        np.testing.assert_array_equal(inv, [0, 0, 1, 2, 1, 2])
        assert code_u is not None
        np.testing.assert_array_equal(code_u, [2.1e7, 2.3e7, 2.2e7])
    _, _, none = RowSource._satellites(rows, None)
    assert none is None
    _, _, all_nan = RowSource._satellites(rows, np.full(6, np.nan))
    assert all_nan is not None and np.all(np.isnan(all_nan))
