"""Observation table (CSV / Parquet): round trip, layout, and bad-input messages."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import InputError, ObsBatch, empty_batch
from robustrtk.io.obstable import natural_key, read_obs_table, write_obs_table


def _batch(rng: np.random.Generator, name: str, T: int, tx: tuple[str, ...]) -> ObsBatch:
    b = empty_batch(np.arange(T) * 0.5 + 100.0, tx, ("P",) * len(tx), ("L1",), receiver=name)
    b.code_m[...] = rng.normal(1e4, 1e3, b.code_m.shape)
    b.phase_cyc[...] = rng.normal(0, 1e6, b.phase_cyc.shape)
    b.cn0_dbhz[...] = np.round(rng.uniform(30, 50, b.cn0_dbhz.shape), 2)
    b.lli[...] = rng.integers(0, 4, b.lli.shape)
    # knock out some cells and some observables
    gone = rng.random(b.code_m.shape) < 0.2
    b.code_m[gone] = np.nan
    b.phase_cyc[gone] = np.nan
    b.cn0_dbhz[gone] = np.nan
    b.lli[gone] = 0
    b.phase_cyc[rng.random(b.code_m.shape) < 0.1] = np.nan
    b.code_m[rng.random(b.code_m.shape) < 0.1] = np.nan
    return b


def _assert_same(a: ObsBatch, b: ObsBatch) -> None:
    # rows where nothing is present are not written, so compare on the epochs read back
    assert a.tx_ids == b.tx_ids
    idx = np.searchsorted(a.t_s, b.t_s)
    np.testing.assert_array_equal(a.t_s[idx], b.t_s)
    for f in ("code_m", "phase_cyc", "cn0_dbhz", "lli"):
        np.testing.assert_array_equal(getattr(a, f)[idx], getattr(b, f), err_msg=f)


@pytest.mark.parametrize("ext", ["csv", "parquet"])
def test_round_trip_is_bit_exact(tmp_path: Path, ext: str) -> None:
    rng = np.random.default_rng(3)
    tx = ("PL1", "PL4", "PL5", "PL6", "PL8", "PL10")
    batches = {"base": _batch(rng, "base", 40, tx), "rover": _batch(rng, "rover", 40, tx)}
    p = write_obs_table(batches, tmp_path / f"obs.{ext}")
    got = read_obs_table(p, wavelength_m=0.19)
    assert list(got) == ["base", "rover"]
    for k in batches:
        _assert_same(batches[k], got[k])
        assert got[k].system == ("P",) * len(tx)
        assert got[k].signals == ("L1",)
        assert got[k].receiver == k
        np.testing.assert_array_equal(got[k].wavelength_m, np.full((len(tx), 1), 0.19))
    assert not list(tmp_path.glob(".*tmp")), "temporary file left behind"


def test_natural_order_epoch_union_and_absent_cells(tmp_path: Path) -> None:
    p = tmp_path / "t.csv"
    p.write_text(
        "receiver,transmitter,time,code_m,phase_cyc,extra\n"
        "rover,PL10,2.0,10.5,,x\n"
        "rover,PL2,1.0,nan,7.25,y\n"
        "base,PL2,3.0,3.5,4.5,z\n"
        "rover,PL2,2.0,1.0,2.0,w\n"
    )
    got = read_obs_table(p)
    r, b = got["rover"], got["base"]
    assert r.tx_ids == ("PL2", "PL10") == b.tx_ids
    np.testing.assert_array_equal(r.t_s, [1.0, 2.0])
    np.testing.assert_array_equal(b.t_s, [3.0])
    assert np.isnan(r.code_m[0, 0, 0]) and r.phase_cyc[0, 0, 0] == 7.25
    assert r.code_m[1, 1, 0] == 10.5 and np.isnan(r.phase_cyc[1, 1, 0])
    assert np.isnan(r.code_m[0, 1, 0])  # PL10 absent at t=1
    assert np.all(np.isnan(r.cn0_dbhz)) and np.all(r.lli == 0)  # optional columns absent
    assert np.all(np.isnan(r.wavelength_m))


def test_natural_key_orders_numbers_numerically() -> None:
    ids = ["PL10", "PL2", "PL1", "G05", "PL1a", "E11"]
    assert sorted(ids, key=natural_key) == ["E11", "G05", "PL1", "PL1a", "PL2", "PL10"]


@settings(max_examples=25, deadline=None)
@given(values=st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=1, max_size=20))
def test_csv_float_text_is_exact(tmp_path_factory: pytest.TempPathFactory, values: list[float]) -> None:
    d = tmp_path_factory.mktemp("f")
    T = len(values)
    b = empty_batch(np.arange(T, dtype=float), ("PL1",), ("P",), ("L1",), receiver="r")
    b.code_m[:, 0, 0] = values
    b.phase_cyc[:, 0, 0] = values[::-1]
    got = read_obs_table(write_obs_table({"r": b}, d / "o.csv"))["r"]
    np.testing.assert_array_equal(got.code_m, b.code_m)
    np.testing.assert_array_equal(got.phase_cyc, b.phase_cyc)


def _csv(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "bad.csv"
    p.write_text(text)
    return p


def test_missing_required_column(tmp_path: Path) -> None:
    p = _csv(tmp_path, "time,receiver,code_m\n0,base,1\n")
    with pytest.raises(InputError, match=r"bad\.csv:1: missing required column\(s\) transmitter"):
        read_obs_table(p)


def test_missing_observables(tmp_path: Path) -> None:
    p = _csv(tmp_path, "time,receiver,transmitter,snr_dbhz\n0,base,PL1,40\n")
    with pytest.raises(InputError, match="at least one of code_m, phase_cyc"):
        read_obs_table(p)


def test_non_numeric_value_names_its_line(tmp_path: Path) -> None:
    p = _csv(
        tmp_path,
        "time,receiver,transmitter,code_m,phase_cyc\n0,base,PL1,1.0,2.0\n\n1,base,PL1,abc,2.0\n",
    )
    with pytest.raises(InputError) as ei:
        read_obs_table(p)
    assert ei.value.line == 4
    assert "code_m" in str(ei.value) and "'abc'" in str(ei.value)
    assert str(ei.value).startswith(f"{p}:4:")


def test_missing_time_names_its_line(tmp_path: Path) -> None:
    p = _csv(tmp_path, "time,receiver,transmitter,code_m\n0,base,PL1,1\n,base,PL1,2\n")
    with pytest.raises(InputError, match=r":3: column time: expected a finite number"):
        read_obs_table(p)


def test_duplicated_row_names_both_lines(tmp_path: Path) -> None:
    p = _csv(
        tmp_path,
        "time,receiver,transmitter,code_m\n0,base,PL1,1\n0,rover,PL1,1\n1,base,PL1,1\n0.0,base,PL1,5\n",
    )
    with pytest.raises(InputError) as ei:
        read_obs_table(p)
    assert ei.value.line == 5
    assert "first at line 2" in str(ei.value)


@pytest.mark.parametrize("bad", ["1.5", "x", "200", "-1"])
def test_lli_must_be_small_integer(tmp_path: Path, bad: str) -> None:
    p = _csv(tmp_path, f"time,receiver,transmitter,code_m,lli\n0,b,PL1,1,0\n1,b,PL1,1,{bad}\n")
    with pytest.raises(InputError, match=r":3: column lli: expected an integer"):
        read_obs_table(p)


def test_lli_accepts_integral_float_text(tmp_path: Path) -> None:
    p = _csv(tmp_path, "time,receiver,transmitter,code_m,lli\n0,b,PL1,1,1.0\n1,b,PL1,1,\n")
    got = read_obs_table(p)["b"]
    np.testing.assert_array_equal(got.lli[:, 0, 0], [1, 0])


def test_too_many_fields(tmp_path: Path) -> None:
    p = _csv(tmp_path, "time,receiver,transmitter,code_m\n0,b,PL1,1,9\n")
    with pytest.raises(InputError, match=r":2: expected 4 fields"):
        read_obs_table(p)


def test_missing_file_and_bad_extension(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not found"):
        read_obs_table(tmp_path / "nope.csv")
    q = tmp_path / "x.txt"
    q.write_text("a")
    with pytest.raises(InputError, match="expected .csv or .parquet"):
        read_obs_table(q)


def test_parquet_errors_name_the_column(tmp_path: Path) -> None:
    p = tmp_path / "bad.parquet"
    pq.write_table(
        pa.table(
            {"time": ["a", "b"], "receiver": ["r", "r"], "transmitter": ["PL1", "PL2"], "code_m": [1.0, 2.0]}
        ),
        p,
    )
    with pytest.raises(InputError, match="column time: expected a numeric column"):
        read_obs_table(p)
    pq.write_table(
        pa.table(
            {
                "time": [0.0, 1.0],
                "receiver": ["r", "r"],
                "transmitter": ["PL1", "PL2"],
                "code_m": [1.0, 2.0],
                "lli": [0.0, 0.5],
            }
        ),
        p,
    )
    with pytest.raises(InputError, match="column lli: expected integers"):
        read_obs_table(p)
    pq.write_table(pa.table({"time": [0.0], "receiver": ["r"], "code_m": [1.0]}), p)
    with pytest.raises(InputError, match="missing required column"):
        read_obs_table(p)


def test_parquet_nulls_are_absent(tmp_path: Path) -> None:
    p = tmp_path / "n.parquet"
    pq.write_table(
        pa.table(
            {
                "time": [0.0, 0.0],
                "receiver": ["r", "r"],
                "transmitter": ["PL2", "PL1"],
                "code_m": [None, 2.0],
                "phase_cyc": [3.0, None],
                "lli": [None, 1],
            }
        ),
        p,
    )
    got = read_obs_table(p)["r"]
    assert got.tx_ids == ("PL1", "PL2")
    np.testing.assert_array_equal(got.code_m[0, :, 0], [2.0, np.nan])
    np.testing.assert_array_equal(got.phase_cyc[0, :, 0], [np.nan, 3.0])
    np.testing.assert_array_equal(got.lli[0, :, 0], [1, 0])


def test_110k_rows_read_complete(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    tx = ("PL1", "PL4", "PL5", "PL6", "PL8")
    batches = {k: _batch(rng, k, 11000, tx) for k in ("base", "rover")}
    for b in batches.values():
        b.code_m[np.isnan(b.code_m)] = 1.0  # make every cell present: 110,000 rows
    p = write_obs_table(batches, tmp_path / "big.csv")
    got = read_obs_table(p)
    # every row arrives (read speed is measured by bench/, not asserted here)
    assert sum(np.count_nonzero(~np.isnan(g.code_m)) for g in got.values()) == 110_000
