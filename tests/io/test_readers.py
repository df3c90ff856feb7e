"""Input format detection by content and the observation reader registry."""

from __future__ import annotations

import bz2
import gzip
import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError, ObsBatch
from robustrtk.io import readers
from robustrtk.io.info import summarize_file
from robustrtk.io.obstable import write_obs_table
from robustrtk.io.readers import detect_format, read_observations, register_reader, registered_readers
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.io.site import Site, write_site

DATA = Path(__file__).parent / "data"

REAL = {
    "geonet_0759_3040_static_3km/07590920.05o": "rinex_obs",
    "geonet_0759_3040_static_3km/07590920.05n": "rinex_nav",
    "mosaicx5_static_1m/rover.obs": "rinex_obs",
    "mosaicx5_static_1m/base.nav": "rinex_nav",
    "kamakura_kinematic_5km/SEPT265G.21O": "rinex_obs",
    "kamakura_kinematic_5km/SEPT2650.21P": "rinex_nav",
    "gnsslogger_static_2016/hour1820.16n": "rinex_nav",
    "rinex4_kms3_1h/KMS300DNK_R_20221591000_01H_30S_MO.crx": "rinex_obs",
    "rinex4_kms3_1h/KMS300DNK_R_20221591000_01H_MN.rnx.gz": "rinex_nav",
}


@pytest.fixture
def clean_registry() -> Iterator[None]:
    saved = list(readers._REGISTRY)
    yield
    readers._REGISTRY[:] = saved


def _table(tmp_path: Path, name: str, receivers: tuple[str, ...] = ("rover",)) -> Path:
    from robustrtk.core import empty_batch

    t = np.arange(3.0)
    batches = {}
    for k, r in enumerate(receivers):
        b = empty_batch(t, ("PL1", "PL2"), ("P", "P"), ("L1",), receiver=r)
        b.code_m[...] = 10.0 + k
        b.phase_cyc[...] = 50.0
        batches[r] = b
    return write_obs_table(batches, tmp_path / name)


@pytest.mark.parametrize("rel", sorted(REAL))
def test_real_files_detected(shared_data: Path, rel: str) -> None:
    assert detect_format(shared_data / rel) == REAL[rel]


@pytest.mark.parametrize("name", ["tiny_v211.o", "tiny_v304.rnx"])
def test_small_rinex_detected(name: str) -> None:
    assert detect_format(DATA / name) == "rinex_obs"


def test_renamed_and_compressed_rinex_detected_by_content(tmp_path: Path) -> None:
    src = DATA / "tiny_v304.rnx"
    plain = tmp_path / "notes.txt"
    shutil.copy(src, plain)
    gz = tmp_path / "archive.bin"
    gz.write_bytes(gzip.compress(src.read_bytes()))
    bz = tmp_path / "x.dat"
    bz.write_bytes(bz2.compress(src.read_bytes()))
    ref = read_rinex_obs(src)
    for p in (plain, gz, bz):
        assert detect_format(p) == "rinex_obs"
        b = read_observations(p)
        assert b.tx_ids == ref.tx_ids and b.signals == ref.signals
        np.testing.assert_array_equal(b.code_m, ref.code_m)


def test_renamed_hatanaka_detected(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / "rinex4_kms3_1h/KMS300DNK_R_20221591000_01H_30S_MO.crx"
    p = tmp_path / "obs.data"
    p.write_bytes(gzip.compress(src.read_bytes()))
    assert detect_format(p) == "rinex_obs"


def test_obs_tables_and_site_detected(tmp_path: Path) -> None:
    csv_path = _table(tmp_path, "obs.csv")
    pq_path = _table(tmp_path, "obs.parquet")
    renamed = tmp_path / "table.log"
    shutil.copy(csv_path, renamed)
    renamed_pq = tmp_path / "table.bin"
    shutil.copy(pq_path, renamed_pq)
    assert detect_format(csv_path) == "obs_table_csv"
    assert detect_format(renamed) == "obs_table_csv"
    assert detect_format(pq_path) == "obs_table_parquet"
    assert detect_format(renamed_pq) == "obs_table_parquet"
    for p in (renamed, renamed_pq):
        b = read_observations(p)
        assert isinstance(b, ObsBatch) and b.tx_ids == ("PL1", "PL2")
        assert np.all(b.code_m == 10.0)
    site = Site(
        frame="local",
        wavelength_m=0.19,
        reference=None,
        transmitters={"PL1": np.zeros(3), "PL2": np.ones(3)},
        base_pos_m=np.full(3, 0.5),
    )
    site_path = write_site(site, tmp_path / "site.toml")
    other = tmp_path / "site.cfg"
    shutil.copy(site_path, other)
    assert detect_format(other) == "site_toml"
    with pytest.raises(InputError, match="holds no observations"):
        read_observations(other)


def test_table_with_several_receivers_needs_a_choice(tmp_path: Path) -> None:
    p = _table(tmp_path, "two.csv", ("base", "rover"))
    with pytest.raises(InputError, match="receiver=NAME"):
        read_observations(p)
    assert np.all(read_observations(p, receiver="base").code_m == 10.0)
    assert np.all(read_observations(p, receiver="rover").code_m == 11.0)
    with pytest.raises(InputError, match="not in the table"):
        read_observations(p, receiver="nobody")


def test_garbage_rejected(tmp_path: Path) -> None:
    junk = tmp_path / "junk.obs"
    junk.write_bytes(np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(InputError, match="expected one of: rinex_obs") as exc:
        detect_format(junk)
    assert exc.value.path == str(junk)
    empty = tmp_path / "empty.rnx"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match="empty file"):
        read_observations(empty)
    bad_gz = tmp_path / "bad.gz"
    bad_gz.write_bytes(b"\x1f\x8b" + b"\x00" * 50)
    with pytest.raises(InputError, match="gzip"):
        detect_format(bad_gz)
    with pytest.raises(InputError, match="not found"):
        detect_format(tmp_path / "missing.obs")


def test_navigation_file_is_not_observations(shared_data: Path) -> None:
    with pytest.raises(InputError, match="rinex_nav holds no observations"):
        read_observations(shared_data / "mosaicx5_static_1m/base.nav")


def test_register_a_new_reader(tmp_path: Path, clean_registry: None) -> None:
    from robustrtk.core import empty_batch

    p = tmp_path / "phone.txt"
    p.write_text("# Version: v1.4.0.0 Platform: N\nRaw,1,2,3\n")

    def sniff(head: bytes) -> bool:
        return head.startswith(b"# Version:")

    def read(path: str, **kw: object) -> ObsBatch:
        return empty_batch(np.zeros(1), ("G01",), ("G",), ("1C",))

    with pytest.raises(InputError):
        detect_format(p)
    register_reader("phone_demo", sniff, read)
    assert detect_format(p) == "phone_demo"
    assert read_observations(p).tx_ids == ("G01",)
    assert [r.name for r in registered_readers()][-1] == "phone_demo"
    register_reader("phone_demo", sniff, read)  # replacing keeps one entry
    assert sum(r.name == "phone_demo" for r in registered_readers()) == 1


def test_summarize_file_uses_detection(tmp_path: Path) -> None:
    p = tmp_path / "renamed.bin"
    shutil.copy(DATA / "tiny_v211.o", p)
    s = summarize_file(p)
    assert s["format"] == "rinex_obs"
    assert s["epochs"] == len(read_rinex_obs(DATA / "tiny_v211.o"))
