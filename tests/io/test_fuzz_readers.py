"""Mutation fuzzing of every reader: any exception other than the project's InputError is a
bug. A small budget runs by default (a few seconds); ``-m slow`` runs a larger one. Inputs
that once crashed a reader are kept in :data:`CRASH_CORPUS` and replayed."""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robustrtk.core import InputError, ObsBatch

DATA = Path(__file__).resolve().parent / "data"
ROOT = Path(__file__).resolve().parents[1]


def _shared() -> Path | None:
    env = os.environ.get("ROBUSTRTK_SHARED_DATA")
    p = Path(env) if env else ROOT.parents[1] / "shared" / "data"
    return p if p.is_dir() else None


def _head(path: Path, n_lines: int) -> bytes:
    with path.open("rb") as fh:
        return b"".join(fh.readline() for _ in range(n_lines))


def _nav_head(path: Path, n_records: int) -> bytes:
    """The header and the first ``n_records`` records of a RINEX 2/3 navigation file."""
    lines = path.read_bytes().split(b"\n")
    end = next(i for i, ln in enumerate(lines) if b"END OF HEADER" in ln) + 1
    v3 = lines[0][:9].strip().startswith(b"3")
    starts = [
        i
        for i in range(end, len(lines))
        if lines[i][:1].strip() and (lines[i][:1].isalpha() if v3 else lines[i][:2].strip().isdigit())
    ]
    stop = starts[n_records] if len(starts) > n_records else len(lines)
    return b"\n".join(lines[:stop]) + b"\n"


POS_TEXT = (
    b"% program   : robustrtk\n"
    b"%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)"
    b"  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n"
    b"2005/04/02 00:00:00.000   35.7000000  139.5000000   60.0000   1   8   0.0100   0.0100   0.0200"
    b"   0.0000   0.0000   0.0000   0.00    3.0\n"
    b"2005/04/02 00:00:30.000   35.7000001  139.5000001   60.0100   2   7   0.0300   0.0300   0.0500"
    b"   0.0010  -0.0010   0.0020   0.00    1.5\n"
)
SITE_TEXT = (
    b'frame = "local"\nwavelength_m = 0.19029367\nreference = "PL6"\n\n[transmitters]\n'
    b"PL1 = [-3.6, -2.4, 1.9]\nPL4 = [3.8, -2.5, 1.85]\nPL6 = [0.2, 0.3, 1.95]\n\n"
    b"[receivers.base]\nposition = [-1.2, -0.6, -1.6]\n\n"
    b"[receivers.rover]\ninitial_position = [1.5, 1.0, -1.55]\n"
)
TABLE_TEXT = (
    b"time,receiver,transmitter,code_m,phase_cyc,snr_dbhz,lli\n"
    b"0.0,base,PL1,17251.34,414763.48,42.35,0\n0.0,base,PL4,33736.27,531681.90,49.62,0\n"
    b"0.0,rover,PL1,17252.11,414767.52,44.10,0\n0.0,rover,PL4,33730.02,531649.03,47.55,1\n"
    b"0.1,base,PL1,17251.35,414763.50,42.30,0\n0.1,rover,PL1,17252.10,414767.50,44.00,0\n"
)
CONFIG_TEXT = (
    b'mode = "rtk"\n[ar]\nratio = 2.5\n[measurement]\ncode_sigma_m = 0.5\n'
    b'[gnss]\nelev_mask_deg = 10\nfreqs = "L1+L2"\n'
)
RTKLIB_CONF_TEXT = (
    b"pos1-posmode       =kinematic  # (0:single,1:dgps,2:kinematic)\npos1-frequency     =l1+l2\n"
    b"pos1-elmask        =15\npos1-navsys        =13\npos2-armode        =fix-and-hold\n"
    b"pos2-arthres       =3\nstats-eratio1      =100\nant2-postype       =xyz\n"
    b"ant2-pos1          =-3978241.0\nant2-pos2          =3382840.0\nant2-pos3          =3649900.0\n"
)
TRUTH_TEXT = b"time,x,y,z\n0.0,1.0,2.0,3.0\n0.1,1.1,2.0,3.0\n0.2,1.2,2.0,3.0\n"


def _read_config(p: str) -> Any:
    from robustrtk.pipeline.config import load_config

    return load_config(p)


def _read_truth(p: str) -> Any:
    from robustrtk.eval.truth import read_truth_file

    return read_truth_file(p)


def _reader(name: str) -> Callable[[str], Any]:
    from robustrtk.io import readers, rinex_nav, rinex_obs, site, solution_pos
    from robustrtk.io.gnsslogger import read_gnsslogger
    from robustrtk.io.gsdc import read_device_gnss
    from robustrtk.io.obstable import read_obs_table
    from robustrtk.pipeline.rtklib_conf import read_rtklib_conf

    return {
        "rinex_obs": rinex_obs.read_rinex_obs,
        "rinex_nav": rinex_nav.read_rinex_nav,
        "table": lambda p: read_obs_table(p, fmt="csv"),
        "site": site.read_site,
        "config": _read_config,
        "pos": solution_pos.read_pos,
        "truth": _read_truth,
        "gnsslogger": read_gnsslogger,
        "gsdc": read_device_gnss,
        "rtklib_conf": read_rtklib_conf,
        "any": readers.read_observations,
    }[name]


def _seeds() -> list[tuple[str, str, bytes]]:
    """(reader, file suffix, content) of every seed input."""
    seeds: list[tuple[str, str, bytes]] = [
        ("rinex_obs", ".o", (DATA / "tiny_v211.o").read_bytes()),
        ("rinex_obs", ".rnx", (DATA / "tiny_v304.rnx").read_bytes()),
        ("any", ".rnx", (DATA / "tiny_v304.rnx").read_bytes()),
        ("pos", ".pos", POS_TEXT),
        ("truth", ".pos", POS_TEXT),
        ("site", ".toml", SITE_TEXT),
        ("table", ".csv", TABLE_TEXT),
        ("config", ".toml", CONFIG_TEXT),
        ("truth", ".csv", TRUTH_TEXT),
        ("rtklib_conf", ".conf", RTKLIB_CONF_TEXT),
    ]
    shared = _shared()
    if shared is not None:
        geo = shared / "geonet_0759_3040_static_3km"
        if geo.is_dir():
            seeds.append(("rinex_obs", ".o", _head(geo / "30400920.05o", 57)))
            seeds.append(("rinex_nav", ".n", _nav_head(geo / "30400920.05n", 3)))
        kam = shared / "kamakura_kinematic_5km" / "SEPT2650.21P"
        if kam.is_file():
            seeds.append(("rinex_nav", ".rnx", _nav_head(kam, 4)))
        log = shared / "gnsslogger_static_2016" / "pseudoranges_log_2016_06_30_21_26_07.txt"
        if log.is_file():
            seeds.append(("gnsslogger", ".txt", _head(log, 120)))
            seeds.append(("any", ".txt", _head(log, 120)))
        fixtures = shared / "android_parser_fixtures"
        gsdc = fixtures / "google_decimeter_2022" / "device_gnss.csv"
        if gsdc.is_file():
            seeds.append(("gsdc", ".csv", _head(gsdc, 40)))
            seeds.append(("any", ".csv", _head(gsdc, 40)))
        log23 = fixtures / "google_decimeter_2023" / "2023-09-07-18-59-us-ca" / "pixel7pro" / "gnss_log.txt"
        if log23.is_file():
            seeds.append(("gnsslogger", ".txt", _head(log23, 200)))
        conf = shared / "mosaicx5_static_1m" / "rtk_matrtklib_kinematic_example.conf"
        if conf.is_file():
            seeds.append(("rtklib_conf", ".conf", conf.read_bytes()))
    return seeds


SEEDS = _seeds()
TOKENS = [b"nan", b"inf", b"-", b"+", b".", b"e", b"D", b"1e300", b"\x00", b"\xff", b"\r", b"\n", b" ", b"\t",
          b",", b"=", b"[", b"]", b'"', b"9" * 20, b"0", b">", b"G", b"R99", b"END OF HEADER"]  # fmt: skip


@st.composite
def _mutation(draw: st.DrawFn) -> tuple[int, list[tuple[str, float, float, bytes]]]:
    seed = draw(st.integers(0, len(SEEDS) - 1))
    ops = draw(
        st.lists(
            st.tuples(
                st.sampled_from(["replace", "insert", "delete", "dup_line", "drop_line", "truncate"]),
                st.floats(0.0, 1.0),
                st.floats(0.0, 1.0),
                st.sampled_from(TOKENS) | st.binary(min_size=1, max_size=4),
            ),
            min_size=1,
            max_size=4,
        )
    )
    return seed, ops


def _apply(data: bytes, ops: list[tuple[str, float, float, bytes]]) -> bytes:
    for op, a, b, tok in ops:
        n = len(data)
        i = min(int(a * n), max(n - 1, 0))
        if op == "replace":
            data = data[:i] + tok + data[i + len(tok) :]
        elif op == "insert":
            data = data[:i] + tok + data[i:]
        elif op == "delete":
            data = data[:i] + data[i + 1 + int(b * 40) :]
        elif op == "truncate":
            data = data[:i]
        else:
            lines = data.split(b"\n")
            k = min(int(a * len(lines)), len(lines) - 1)
            if op == "dup_line":
                lines.insert(k, lines[k])
            elif len(lines) > 1:
                del lines[k]
            data = b"\n".join(lines)
    return data


def _check(tmp: Path, seed: int, data: bytes) -> None:
    name, suffix, _ = SEEDS[seed]
    p = tmp / f"input{suffix}"
    p.write_bytes(data)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a numpy warning leaking to the user fails too
        try:
            batch = _reader(name)(str(p))
        except InputError:
            return  # the project's one-line error is an accepted outcome; anything else fails the test
    _no_infinite_observations(batch)


def _no_infinite_observations(batch: Any) -> None:
    """An accepted observation batch holds no infinite value and no impossible pseudorange."""
    if not isinstance(batch, ObsBatch):
        return
    for name in ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz"):
        assert not np.isinf(getattr(batch, name)).any(), name
    code = batch.code_m[np.isfinite(batch.code_m)]
    if batch.meta.get("format") != "table":
        assert np.all((code > 0) & (code < 1e9)) or not code.size


def _run(tmp_path_factory: pytest.TempPathFactory, case: tuple[int, list[Any]]) -> None:
    seed, ops = case
    _check(tmp_path_factory.mktemp("fuzz", numbered=True), seed, _apply(SEEDS[seed][2], ops))


@settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(case=_mutation())
def test_mutated_inputs_raise_only_input_error(tmp_path_factory: pytest.TempPathFactory, case: Any) -> None:
    _run(tmp_path_factory, case)


@pytest.mark.slow
@settings(
    max_examples=5000,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(case=_mutation())
def test_mutated_inputs_raise_only_input_error_long(
    tmp_path_factory: pytest.TempPathFactory, case: Any
) -> None:
    _run(tmp_path_factory, case)


def test_every_seed_reads(tmp_path: Path) -> None:
    for k in range(len(SEEDS)):
        _check(tmp_path, k, SEEDS[k][2])


#: Inputs that once crashed a reader (reader, suffix, content).
CRASH_CORPUS: list[tuple[str, str, bytes]] = [
    ("table", ".csv", TABLE_TEXT.replace(b"PL4", b"P\xffL4", 1)),
    (
        "rinex_obs",
        ".rnx",
        (DATA / "tiny_v304.rnx").read_bytes().replace(b" 0.0000000  0  5", b"30.+000000  0  5"),
    ),
    (
        "rinex_obs",
        ".o",
        (DATA / "tiny_v211.o").read_bytes().replace(b"  5.0000000  0 13", b"30.+000000  0 13", 1),
    ),
    ("pos", ".pos", POS_TEXT.replace(b"   1   8  ", b" nan   8  ")),
    ("pos", ".pos", POS_TEXT.replace(b"   1   8  ", b"   1 inf  ")),
    ("pos", ".pos", POS_TEXT.replace(b"   1   8  ", b"   1 99999999999999999999  ")),
    ("pos", ".pos", POS_TEXT.replace(b"2005/04/02 00:00:30", b"2005/04/99999999999999999999 00:00:30")),
    ("pos", ".pos", POS_TEXT.replace(b"2005/04/02 00:00:30.000", b"1e300 1e300")),
    # found by the mutation runs of the reliability work: each raised another exception or a
    # numpy warning before
    ("pos", ".pos", POS_TEXT.replace(b"0.0100   0.0100   0.0200", b"0.0100   0.0100   1e300 ", 1)),
    ("truth", ".csv", TRUTH_TEXT.replace(b"0.2,1.2,2.0,3.0", b"0.2,1.2,2.0,1e300")),
    ("truth", ".csv", b"0.0,1.0,2.1e300\n"),
    ("site", ".toml", SITE_TEXT.replace(b"PL6 = [0.2, 0.3, 1.95]", b"PL6 = [0.2, 0.3, 1e300]")),
    ("rtklib_conf", ".conf", RTKLIB_CONF_TEXT.replace(b"=l1+l2", b"=")),
    (
        "rinex_obs",
        ".o",
        (DATA / "tiny_v211.o").read_bytes().replace(b"  0 13G01", b"  0 \xc2\xb2G01", 1),
    ),
    (
        "rinex_obs",
        ".rnx",
        (DATA / "tiny_v304.rnx").read_bytes().replace(b"> 2024", b"> 9e99", 1),
    ),
]


@pytest.mark.parametrize("case", range(len(CRASH_CORPUS)))
def test_crash_corpus(tmp_path: Path, case: int) -> None:
    name, suffix, data = CRASH_CORPUS[case]
    p = tmp_path / f"input{suffix}"
    p.write_bytes(data)
    with pytest.raises(InputError):
        _reader(name)(str(p))


def test_rinex3_cut_right_after_the_header_is_an_empty_batch(tmp_path: Path) -> None:
    """Found by the mutation test: a RINEX 3 file cut after END OF HEADER crashed the epoch
    scan (ValueError); it is a batch without epochs (the CLI refuses it as header-only)."""
    text = (DATA / "tiny_v304.rnx").read_bytes()
    cut = text[: text.index(b"END OF HEADER") + len(b"END OF HEADER\n")]
    p = tmp_path / "input.rnx"
    p.write_bytes(cut)
    batch = _reader("rinex_obs")(str(p))
    assert len(batch) == 0


# ----------------------------------------------------------------------------- the long run
def _small(data: bytes, max_bytes: int = 6000) -> bytes:
    """A seed cut to its first lines (at most ``max_bytes``): mutations of a small file
    reach the same code paths, many times faster."""
    if len(data) <= max_bytes:
        return data
    return data[: data.rfind(b"\n", 0, max_bytes) + 1] or data[:max_bytes]


def _binary_seeds() -> list[tuple[str, str, bytes]]:
    """The first frames of the low-cost receivers' UBX log and RTCM 3 stream, read through
    the dispatching reader (nothing when the shared data is absent)."""
    import gzip

    shared = _shared()
    if shared is None:
        return []
    d = shared / "galway_m8p_l1_lowcost" / "s1_static"
    out: list[tuple[str, str, bytes]] = []
    ubx = d / "rover-20181004-1237.ubx.gz"
    if ubx.is_file():
        with gzip.open(ubx, "rb") as fh:
            out.append(("any", ".ubx", fh.read(6000)))
    rtcm = d / "base-20181004-1236.rtcm3"
    if rtcm.is_file():
        with rtcm.open("rb") as fh:
            out.append(("any", ".rtcm3", fh.read(3000)))
    return out


#: Mutated inputs of the long run (``-m slow``): at least 200,000 across every reader.
LONG_RUN_INPUTS = int(os.environ.get("ROBUSTRTK_FUZZ_INPUTS", "200000"))
_OPS = ("replace", "insert", "delete", "dup_line", "drop_line", "truncate")


@pytest.mark.slow
def test_200k_mutated_inputs_raise_only_input_error(tmp_path: Path) -> None:
    """``LONG_RUN_INPUTS`` seeded mutations of small seeds (every reader, the UBX and RTCM 3
    logs through the dispatching reader), in process: no exception but InputError, no
    warning, no accepted infinite or impossible observation. The files go to a RAM disk
    where there is one (a file write there costs microseconds, on a disk milliseconds)."""
    import shutil
    import tempfile

    seeds = [(n, s, _small(d)) for n, s, d in SEEDS] + _binary_seeds()
    shm = Path("/dev/shm")
    work = Path(tempfile.mkdtemp(dir=shm)) if shm.is_dir() and os.access(shm, os.W_OK) else tmp_path
    rng = np.random.default_rng(20261202)
    failures: list[str] = []
    n_input_error = 0
    try:
        for i in range(LONG_RUN_INPUTS):
            k = int(rng.integers(len(seeds)))
            name, suffix, data = seeds[k]
            ops = [
                (
                    _OPS[int(rng.integers(len(_OPS)))],
                    float(rng.random()),
                    float(rng.random()),
                    TOKENS[int(rng.integers(len(TOKENS)))]
                    if rng.random() < 0.7
                    else rng.bytes(int(rng.integers(1, 5))),
                )
                for _ in range(int(rng.integers(1, 5)))
            ]
            p = work / f"input{suffix}"
            p.write_bytes(_apply(data, ops))
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("error")
                    try:
                        batch = _reader(name)(str(p))
                    except InputError:
                        n_input_error += 1
                        continue
                _no_infinite_observations(batch)
            except Exception as exc:  # any other outcome is a bug: collect, report at the end
                if len(failures) < 20:
                    failures.append(f"input {i} (seed {k} {name}{suffix}, ops {ops}): {exc!r}"[:400])
                else:
                    failures.append("")
    finally:
        if work != tmp_path:
            shutil.rmtree(work, ignore_errors=True)
    assert not failures, f"{len(failures)} failures of {LONG_RUN_INPUTS}:\n" + "\n".join(failures[:20])
    assert 0 < n_input_error < LONG_RUN_INPUTS  # the mutations reach both outcomes


def test_long_run_findings_are_one_line_errors(shared_data: Path, tmp_path: Path) -> None:
    """Found by the 200,000-input run: an exponent beyond the double range in a navigation
    field gave a numpy warning (inf − inf), and a TimeNanos of 20 digits in device_gnss.csv
    an OverflowError."""
    from robustrtk.io.readers import read_observations
    from robustrtk.io.rinex_nav import read_rinex_nav

    nav = _nav_head(shared_data / "kamakura_kinematic_5km" / "SEPT2650.21P", 2)
    lines = nav.split(b"\n")
    k = next(i for i, ln in enumerate(lines) if b"END OF HEADER" in ln) + 4  # a broadcast-orbit line
    lines[k] = lines[k][:4] + b"1e3001234".rjust(19) + lines[k][23:]
    p = tmp_path / "n.rnx"
    p.write_bytes(b"\n".join(lines))
    with pytest.raises(InputError, match=r"n.rnx:\d+: expected a finite number in columns 5-23"):
        read_rinex_nav(p)
    gsdc = _head(shared_data / "android_parser_fixtures" / "google_decimeter_2022" / "device_gnss.csv", 40)
    head, first, rest = gsdc.split(b"\n", 2)
    cols = head.decode().split(",")
    f = first.decode().split(",")
    f[cols.index("TimeNanos")] = "99999999999999999999" + f[cols.index("TimeNanos")]
    q = tmp_path / "device_gnss.csv"
    q.write_bytes(b"\n".join([head, ",".join(f).encode(), rest]))
    with pytest.raises(InputError, match="epoch time out of range"):
        read_observations(q)
