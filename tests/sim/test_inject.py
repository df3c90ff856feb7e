"""Fault injection into RINEX: the reader sees exactly the logged changes and nothing else."""

from __future__ import annotations

import csv
import gzip
import math
from collections.abc import Sequence
from decimal import Decimal
from pathlib import Path

import hatanaka
import numpy as np
import pytest

from robustrtk.core import CLIGHT, InputError, ObsBatch
from robustrtk.io.rinex_obs import RINEX2_SIGNAL_MAP, read_rinex_obs
from robustrtk.sim.inject import (
    LOG_COLUMNS,
    Change,
    EpochSelection,
    FaultSpec,
    inject_bytes,
    inject_file,
    output_compression,
    parse_epochs,
    parse_spec,
)

MOSAIC = "mosaicx5_static_1m/rover.obs"
GEONET = "geonet_0759_3040_static_3km/07590920.05o"

# --------------------------------------------------------------------------------------------
# synthetic files


def _h(content: str, label: str) -> str:
    return content.ljust(60) + label


def _f(v: float | None, lli: str = " ", ssi: str = " ") -> str:
    return " " * 16 if v is None else f"{v:14.3f}{lli}{ssi}"


def rinex3_text() -> str:
    """RINEX 3.04: G, R, E; GLONASS channels for R02 only; a blank field, a short line,
    an event epoch (flag 3) between epochs 2 and 3."""
    head = [
        _h("     3.04           OBSERVATION DATA    M", "RINEX VERSION / TYPE"),
        _h("synthetic", "PGM / RUN BY / DATE"),
        _h("SYN3", "MARKER NAME"),
        _h("G    6 C1C L1C D1C S1C C2W L2W", "SYS / # / OBS TYPES"),
        _h("R    2 C1C L1C", "SYS / # / OBS TYPES"),
        _h("E    4 C1C L1C C5Q L5Q", "SYS / # / OBS TYPES"),
        _h("     1.000", "INTERVAL"),
        _h("  2024     6    24     8    20    0.0000000     GPS", "TIME OF FIRST OBS"),
        _h("  1 R02 -4", "GLONASS SLOT / FRQ #"),
        _h("", "END OF HEADER"),
    ]
    body: list[str] = []
    for e in range(6):
        if e == 3:
            body.append("> 2024 06 24 08 20  2.5000000  3  1")
            body.append(_h("new site occupation", "COMMENT"))
        sec = float(e)
        body.append(f"> 2024 06 24 08 20{sec:11.7f}  0  5")
        g1 = [22e6 + 100 * e, 115.6e6 + 500 * e + 0.25, -1500.25, 45.5]
        body.append("G01" + _f(g1[0], " ", "7") + _f(g1[1], "0", "7") + _f(g1[2]) + _f(g1[3]))  # short
        g2_l1 = None if e == 2 else 120.1e6 + 480 * e + 0.5
        body.append(
            "G02"
            + _f(21e6 + 90 * e, " ", "6")
            + _f(g2_l1, "0", "6")
            + _f(-1200.0)
            + _f(44.0)
            + _f(21e6 + 95 * e)
            + _f(93.6e6 + 370 * e, "4", "6")
        )
        body.append("R02" + _f(19e6 + 80 * e) + _f(101.0e6 + 420 * e, "0", "7"))
        body.append("R09" + _f(20e6 + 70 * e) + _f(106.0e6 + 370 * e, "0", "7"))
        body.append(
            "E11" + _f(24e6 + 60 * e) + _f(126.0e6 + 310 * e) + _f(24e6 + 61 * e) + _f(-96.0e6 - 240 * e)
        )
    return "\n".join(head + body) + "\n"


def rinex2_text() -> str:
    """RINEX 2.11 with 7 types (2 lines per satellite), 13 satellites (satellite list
    continued on a second line), an event epoch (flag 4) after epoch 1, a blank field."""
    types = ["L1", "L2", "C1", "P2", "D1", "S1", "C2"]
    head = [
        _h("     2.11           OBSERVATION DATA    M (MIXED)", "RINEX VERSION / TYPE"),
        _h("synthetic", "PGM / RUN BY / DATE"),
        _h("SYN2", "MARKER NAME"),
        _h(f"{len(types):6d}" + "".join(f"{t:>6s}" for t in types), "# / TYPES OF OBSERV"),
        _h("    30.000", "INTERVAL"),
        _h("  2005     4     2     0     0    0.0000000     GPS", "TIME OF FIRST OBS"),
        _h("", "END OF HEADER"),
    ]
    sats = [f"G{k:02d}" for k in range(1, 13)] + ["R03"]
    body: list[str] = []
    for e in range(4):
        if e == 2:
            body.append(" 05  4  2  0  0 45.0000000  4  1")
            body.append(_h("antenna moved", "COMMENT"))
        sec = 30.0 * (e % 2)
        mi = e // 2
        body.append(f" 05  4  2  0 {mi:2d}{sec:11.7f}  0{len(sats):3d}" + "".join(sats[:12]))
        body.append(" " * 32 + "".join(sats[12:]))
        for s, sat in enumerate(sats):
            base = 2e7 + 1e5 * s + 10 * e
            l1 = None if (sat == "G05" and e == 2) else 1.05e8 + 1e6 * s + 50 * e + 0.125
            vals = [l1, 0.82e8 + 1e6 * s + 39 * e, base, base + 3.0, -1000.0 + s, 45.0, base + 1.5]
            lli = ["1" if (sat == "G07" and e == 1) else " ", " ", " ", " ", " ", " ", " "]
            fields = [_f(v, lli[i], "7" if i < 2 and v is not None else " ") for i, v in enumerate(vals)]
            body.append("".join(fields[:5]).rstrip())
            body.append("".join(fields[5:]).rstrip())
    return "\n".join(head + body) + "\n"


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_bytes(text.encode("ascii"))
    return p


# --------------------------------------------------------------------------------------------
# checking helpers


def _field_and_signal(b: ObsBatch, ch: Change) -> tuple[str, int, int]:
    """(array name, tx index, signal index) a change lands in, in the reader's arrays."""
    v3 = float(b.meta["rinex_version"]) >= 3.0  # type: ignore[arg-type]
    sig = ch.obs_code[1:] if v3 else RINEX2_SIGNAL_MAP[ch.sat[0]][ch.obs_code]
    name = "code_m" if ch.kind == "code" else "phase_cyc"
    return name, b.tx_ids.index(ch.sat), b.signals.index(sig)


def assert_only_logged_changes(a: ObsBatch, b: ObsBatch, changes: Sequence[Change]) -> None:
    """Reader arrays of original ``a`` and injected ``b`` differ exactly by the logged
    amounts at the logged cells; everything else (incl. LLI and SSI) is identical."""
    assert a.tx_ids == b.tx_ids and a.signals == b.signals
    np.testing.assert_array_equal(a.t_s, b.t_s)
    expect = {"code_m": np.zeros(a.code_m.shape), "phase_cyc": np.zeros(a.phase_cyc.shape)}
    for ch in changes:
        name, n, k = _field_and_signal(a, ch)
        d = Decimal(ch.new) - Decimal(ch.original)
        assert d == Decimal(ch.size_native)
        expect[name][ch.epoch_index, n, k] += float(d)
    for name, exp in expect.items():
        va, vb = getattr(a, name), getattr(b, name)
        np.testing.assert_array_equal(np.isnan(va), np.isnan(vb))
        diff = np.nan_to_num(vb - va)
        # F14.3 values near 1e8 parse to float64 with ~1e-8 resolution
        np.testing.assert_allclose(diff, exp, rtol=0, atol=1e-6)
        assert np.all(diff[exp == 0] == 0), f"{name} changed outside the logged cells"
    for name in ("doppler_hz", "cn0_dbhz"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    np.testing.assert_array_equal(a.lli, b.lli)
    np.testing.assert_array_equal(a.meta["ssi"], b.meta["ssi"])


def assert_bytes_only_in_logged_fields(orig: bytes, new: bytes, changes: Sequence[Change]) -> None:
    """Line by line: only logged lines differ, and only inside a 14-character value field."""
    la, lb = orig.split(b"\n"), new.split(b"\n")
    assert len(la) == len(lb)
    logged = {ch.line - 1 for ch in changes}
    differing = {i for i, (x, y) in enumerate(zip(la, lb, strict=True)) if x != y}
    assert differing == logged
    for i in differing:
        x, y = la[i], lb[i]
        assert len(x) == len(y)
        cols = [c for c in range(len(x)) if x[c] != y[c]]
        v3 = x[:1] in (b"G", b"R", b"E", b"C", b"J", b"S", b"I") and not x[:1].isspace()
        for c in cols:
            rel = (c - 3) % 16 if v3 else c % 16
            assert rel < 14, f"line {i + 1} column {c + 1} outside a value field"


def _read_log(path: str | Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return rows


# --------------------------------------------------------------------------------------------
# specs


@pytest.mark.parametrize(
    ("text", "indices", "n_random"),
    [
        ("100", (100,), 0),
        ("100-119", tuple(range(100, 120)), 0),
        ("5,9,30", (5, 9, 30), 0),
        ("30-220/10", tuple(range(30, 221, 10)), 0),
        ("30-35/2,3,31", (3, 30, 31, 32, 34), 0),
        ("random20", (), 20),
    ],
)
def test_parse_epochs(text: str, indices: tuple[int, ...], n_random: int) -> None:
    assert parse_epochs(text) == EpochSelection(indices, n_random)


@pytest.mark.parametrize(
    ("kind", "text", "needle"),
    [
        ("phase", "G05:L1C:0.15", "4 fields"),
        ("phase", "X05:L1C:0.15:3", "SAT"),
        ("phase", "G05:C1C:0.15:3", "carrier-phase"),
        ("code", "G05:L1C:10:3", "pseudorange"),
        ("code", "G05:C1C:ten:3", "SIZE_M"),
        ("code", "G05:C1C:nan:3", "finite"),
        ("code", "G05:C1C:0:3", "non-zero"),
        ("phase", "G05:L1C:0.15:10-5", "ends before"),
        ("phase", "G05:L1C:0.15:5-9/0", "step"),
        ("phase", "G05:L1C:0.15:random0", "N >= 1"),
        ("phase", "G05:L1C:0.15:first", "expected epoch indices"),
        ("slip", "G05:L1C:1.5:3", "integer"),
        ("slip", "G05:L1C:2:3-5", "one 0-based epoch"),
        ("phase", "G05:L1CX:0.15:3", "SIGNAL"),
    ],
)
def test_malformed_spec_is_one_line_error(kind: str, text: str, needle: str) -> None:
    with pytest.raises(InputError) as ei:
        parse_spec(text, kind)  # type: ignore[arg-type]
    msg = str(ei.value)
    assert "\n" not in msg and needle in msg and text in msg


def test_parse_spec_normalises() -> None:
    s = parse_spec("g5:l1c:0.15:1-2", "phase")
    assert (s.sat, s.obs_code, s.size, s.epochs.indices) == ("G05", "L1C", 0.15, (1, 2))
    s = parse_spec("R 3:L2:-4:7", "slip")
    assert (s.sat, s.obs_code, s.size, s.epochs.indices) == ("R03", "L2", -4.0, (7,))


@pytest.mark.parametrize(
    ("name", "kind"),
    [
        ("a.obs", "none"),
        ("a.rnx", "none"),
        ("a.crx", "hatanaka"),
        ("a.24d", "hatanaka"),
        ("a.05D", "hatanaka"),
        ("a.crx.gz", "hatanaka+gzip"),
        ("a.24d.gz", "hatanaka+gzip"),
        ("a.obs.gz", "gzip"),
        ("a.05o.bz2", "bzip2"),
        ("a.24o", "none"),
    ],
)
def test_output_compression_from_name(name: str, kind: str) -> None:
    assert output_compression(name) == kind


# --------------------------------------------------------------------------------------------
# real files (acceptance)


def test_mosaicx5_acceptance_phase_and_code(shared_data: Path, tmp_path: Path) -> None:
    """Twenty +0.15 m L1 phase errors on G05, twenty +10 m C1 code errors on G07 (RINEX 3)."""
    src = shared_data / MOSAIC
    out = tmp_path / "rover_injected.obs"
    specs = [parse_spec("G05:L1C:0.15:random20", "phase"), parse_spec("G07:C1C:10:random20", "code")]
    res = inject_file(src, out, specs, seed=7)
    a, b = read_rinex_obs(src), read_rinex_obs(out)
    assert len(res.changes) == 40
    ph = [c for c in res.changes if c.kind == "phase"]
    co = [c for c in res.changes if c.kind == "code"]
    assert len({c.epoch_index for c in ph}) == 20 and {c.sat for c in ph} == {"G05"}
    assert len({c.epoch_index for c in co}) == 20 and {c.sat for c in co} == {"G07"}
    assert_only_logged_changes(a, b, res.changes)
    # sizes: 0.15 m in cycles of GPS L1, 10 m of code, within the format's 0.001 rounding
    lam = CLIGHT / 1575.42e6
    n5, k1 = a.tx_ids.index("G05"), a.signals.index("1C")
    d_ph = (b.phase_cyc - a.phase_cyc)[[c.epoch_index for c in ph], n5, k1]
    assert np.all(np.abs(d_ph * lam - 0.15) <= 0.0005 * lam + 1e-6)
    n7 = a.tx_ids.index("G07")
    d_co = (b.code_m - a.code_m)[[c.epoch_index for c in co], n7, k1]
    np.testing.assert_allclose(d_co, 10.0, atol=1e-6)
    assert_bytes_only_in_logged_fields(src.read_bytes(), out.read_bytes(), res.changes)
    # the log on disk holds the same rows
    rows = _read_log(res.log_path)
    assert list(rows[0]) == list(LOG_COLUMNS)
    assert [list(r.values()) for r in rows] == [c.row() for c in res.changes]
    for r, c in zip(rows, res.changes, strict=True):
        t = c.epoch_index
        assert r["time"] == f"2024-06-24T08:{20 + t // 60:02d}:{t % 60:02d}.0000000"
        assert r["lli_original"] == r["lli_new"]


def test_geonet_rinex2_phase_code_and_p2(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / GEONET
    out = tmp_path / "07590920.05o"
    specs = [
        parse_spec("G19:L1:0.15:10-29", "phase"),
        parse_spec("G24:C1:10:random20", "code"),
        parse_spec("G28:P2:-7.5:30-110/20", "code"),
        parse_spec("G20:L2:0.15:5,9,30", "phase"),
    ]
    res = inject_file(src, out, specs, seed=3)
    a, b = read_rinex_obs(src), read_rinex_obs(out)
    assert res.epochs[specs[0].text] == tuple(range(10, 30))
    assert res.epochs[specs[2].text] == (30, 50, 70, 90, 110)
    assert len(res.changes) == 20 + 20 + 5 + 3
    assert_only_logged_changes(a, b, res.changes)
    assert_bytes_only_in_logged_fields(src.read_bytes(), out.read_bytes(), res.changes)
    lam2 = CLIGHT / 1227.60e6
    c = next(c for c in res.changes if c.obs_code == "L2")
    assert c.size_native == f"{0.15 / lam2:.3f}"
    times = {int(r["epoch_index"]): r["time"] for r in _read_log(res.log_path)}
    assert times[10] == "2005-04-02T00:05:00.0000000"  # the file's tags, ms offsets kept
    assert times[110] == "2005-04-02T00:55:00.0040000"


def test_slip_persists_to_the_end(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / MOSAIC
    a = read_rinex_obs(src)
    n, k = a.tx_ids.index("G13"), a.signals.index("2W")
    e0 = 200
    for slip_lli in (False, True):
        out = tmp_path / f"slip_{slip_lli}.obs"
        res = inject_file(src, out, [parse_spec("G13:L2W:-3:200", "slip")], slip_lli=slip_lli)
        b = read_rinex_obs(out)
        have = ~np.isnan(a.phase_cyc[:, n, k])
        d = np.nan_to_num(b.phase_cyc[:, n, k] - a.phase_cyc[:, n, k])
        assert np.all(d[:e0] == 0)
        np.testing.assert_allclose(d[e0:][have[e0:]], -3.0, atol=1e-6)
        observed = np.flatnonzero(have)
        assert [c.epoch_index for c in res.changes] == observed[observed >= e0].tolist()
        assert res.changes[-1].epoch_index == int(np.flatnonzero(have)[-1])
        assert all(c.size_native == "-3" for c in res.changes)
        assert math.isclose(res.changes[0].size_m, -3 * CLIGHT / 1227.60e6)
        lli_diff = np.argwhere(b.lli != a.lli)
        if slip_lli:
            assert lli_diff.tolist() == [[e0, n, k]]
            assert b.lli[e0, n, k] == a.lli[e0, n, k] | 1
            assert res.changes[0].lli_new == str(int(a.lli[e0, n, k]) | 1)
        else:
            assert lli_diff.size == 0
            np.testing.assert_array_equal(a.phase_cyc[:, :n], b.phase_cyc[:, :n])


def test_random_selection_reproducible(shared_data: Path, tmp_path: Path) -> None:
    data = (shared_data / MOSAIC).read_bytes()
    spec = [parse_spec("C23:L2I:0.15:random20", "phase")]
    _, ch1, ep1 = inject_bytes(data, spec, seed=11)
    _, ch2, ep2 = inject_bytes(data, spec, seed=11)
    _, _, ep3 = inject_bytes(data, spec, seed=12)
    assert ep1 == ep2 and ch1 == ch2
    assert ep1 != ep3
    picked = ep1[spec[0].text]
    assert len(picked) == 20 == len(set(picked)) and list(picked) == sorted(picked)
    # the selection of one spec does not depend on the others
    _, _, ep4 = inject_bytes(data, [parse_spec("G05:C1C:10:random5", "code"), *spec], seed=11)
    assert ep4[spec[0].text] == picked


def test_hatanaka_and_gzip_round_trips(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / GEONET
    crx_in = tmp_path / "07590920.05d"
    crx_in.write_bytes(hatanaka.compress(src.read_bytes(), compression="none"))
    gz_in = tmp_path / "07590920.05o.gz"
    gz_in.write_bytes(gzip.compress(src.read_bytes()))
    specs = [parse_spec("G11:L1:0.15:random20", "phase"), parse_spec("G03:C1:10:0-19", "code")]
    plain = tmp_path / "plain.05o"
    ref = inject_file(src, plain, specs, seed=5)
    b_ref = read_rinex_obs(plain)
    for inp in (src, crx_in, gz_in):
        for name, kind in (
            ("o.05d", "hatanaka"),
            ("o.05o.gz", "gzip"),
            ("o.crx.gz", "hatanaka+gzip"),
            ("o.05o", "none"),
        ):
            out = tmp_path / f"{inp.name}.{name}"
            res = inject_file(inp, out, specs, seed=5)
            assert res.output_compression == kind
            assert res.changes == ref.changes
            b = read_rinex_obs(out)
            assert (
                b.meta["compression"]
                == {"none": "none", "gzip": "gzip", "hatanaka": "hatanaka", "hatanaka+gzip": "hatanaka+gzip"}[
                    kind
                ]
            )
            for f in ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz", "lli"):
                np.testing.assert_array_equal(getattr(b, f), getattr(b_ref, f))
            if kind == "gzip":
                assert gzip.decompress(out.read_bytes()) == plain.read_bytes()
            if kind == "none":
                assert out.read_bytes() == plain.read_bytes()


def test_crlf_file_stays_byte_identical_elsewhere(tmp_path: Path) -> None:
    text = rinex3_text()
    src = _write(tmp_path, "crlf.rnx", text.replace("\n", "\r\n"))
    out = tmp_path / "crlf_out.rnx"
    res = inject_file(src, out, [parse_spec("E11:C5Q:10:1-2", "code")])
    ref = inject_bytes(text.encode(), [parse_spec("E11:C5Q:10:1-2", "code")])[0]
    assert out.read_bytes() == ref.replace(b"\n", b"\r\n")
    assert len(res.changes) == 2


# --------------------------------------------------------------------------------------------
# synthetic files: layouts and errors


def test_rinex3_synthetic_fields_and_event_epoch(tmp_path: Path) -> None:
    src = _write(tmp_path, "syn.rnx", rinex3_text())
    out = tmp_path / "syn_out.rnx"
    specs = [
        parse_spec("G02:L2W:0.15:0-5", "phase"),  # last field of a record
        parse_spec("R02:L1C:0.15:3", "phase"),  # GLONASS with a channel (k = -4)
        parse_spec("E11:L5Q:-0.15:4", "phase"),  # negative values
        parse_spec("G01:C1C:10:5", "code"),
        parse_spec("G02:L1C:0.15:random5", "phase"),  # G02 L1C is blank at epoch 2
        parse_spec("G02:L2W:2:4", "slip"),  # adds to the phase error on the same values
    ]
    res = inject_file(src, out, specs, seed=1)
    a, b = read_rinex_obs(src), read_rinex_obs(out)
    assert a.phase_cyc.shape[0] == 6  # the event epoch is not an epoch
    assert_only_logged_changes(a, b, res.changes)
    assert_bytes_only_in_logged_fields(src.read_bytes(), out.read_bytes(), res.changes)
    assert 2 not in res.epochs[specs[4].text] and len(res.epochs[specs[4].text]) == 5
    lam_r02 = CLIGHT / (1602.0e6 - 4 * 0.5625e6)
    r = next(c for c in res.changes if c.sat == "R02")
    assert r.size_native == f"{0.15 / lam_r02:.3f}" and r.time == "2024-06-24T08:20:03.0000000"
    # phase error then slip on G02 L2W at epoch 4: the slip row starts from the edited value
    rows = [c for c in res.changes if c.sat == "G02" and c.obs_code == "L2W" and c.epoch_index == 4]
    assert [c.kind for c in rows] == ["phase", "slip"] and rows[1].original == rows[0].new
    n, k = a.tx_ids.index("G02"), a.signals.index("2W")
    d = b.phase_cyc[:, n, k] - a.phase_cyc[:, n, k]
    lam2 = CLIGHT / 1227.60e6
    np.testing.assert_allclose(d, round(0.15 / lam2, 3) + np.array([0, 0, 0, 0, 2, 2]), atol=1e-6)


def test_rinex2_synthetic_continuations(tmp_path: Path) -> None:
    src = _write(tmp_path, "syn.11o", rinex2_text())
    out = tmp_path / "syn_out.11o"
    specs = [
        parse_spec("G12:C2:10:0-3", "code"),  # second record line, last satellite of line 1
        parse_spec("G07:L1:0.15:1", "phase"),  # LLI '1' there stays
        parse_spec("G05:L1:0.15:random3", "phase"),  # blank at epoch 2
        parse_spec("G03:L2:5:1", "slip"),
    ]
    res = inject_file(src, out, specs, seed=2, slip_lli=True)
    a, b = read_rinex_obs(src), read_rinex_obs(out)
    assert a.code_m.shape[0] == 4
    assert res.epochs[specs[2].text] == (0, 1, 3)
    assert "R03" in a.tx_ids
    # LLI: only the slip's first epoch changes (G03 L2 at epoch 1 had a blank LLI)
    n, k = a.tx_ids.index("G03"), a.signals.index("2W")
    assert np.argwhere(a.lli != b.lli).tolist() == [[1, n, k]] and b.lli[1, n, k] == 1
    b.lli[1, n, k] = a.lli[1, n, k]
    assert_only_logged_changes(a, b, res.changes)
    la, lb = src.read_bytes().split(b"\n"), out.read_bytes().split(b"\n")
    slip_line = res.changes[-3].line - 1
    assert res.changes[-3].kind == "slip" and lb[slip_line][30:31] == b"1" and la[slip_line][30:31] == b" "
    assert a.lli[1, a.tx_ids.index("G07"), a.signals.index("1C")] == 1
    g07 = next(c for c in res.changes if c.sat == "G07")
    assert g07.lli_original == g07.lli_new == "1"


def test_absent_observation_at_explicit_epoch(tmp_path: Path) -> None:
    src = _write(tmp_path, "syn.11o", rinex2_text())
    with pytest.raises(InputError) as ei:
        inject_file(src, tmp_path / "o.11o", [parse_spec("G05:L1:0.15:1-3", "phase")])
    msg = str(ei.value)
    assert "epoch 2 " in msg and "G05" in msg and "L1" in msg and "\n" not in msg
    assert not (tmp_path / "o.11o").exists()


@pytest.mark.parametrize(
    ("kind", "spec", "needles"),
    [
        ("phase", "R09:L1C:0.15:1", ("GLONASS R09", "GLONASS SLOT / FRQ #")),
        ("phase", "G01:L5Q:0.15:1", ("L5Q", "SYS / # / OBS TYPES")),
        ("phase", "G01:L1C:0.15:6", ("epoch 6 out of range", "6 epochs")),
        ("code", "G09:C1C:10:1", ("G09", "no observations")),
        ("code", "G01:C1C:1e10:1", ("does not fit",)),
        ("phase", "G02:L1C:0.15:random6", ("cannot draw 6",)),
        ("code", "G01:C1C:0.0004:1", ("rounds to 0",)),
    ],
)
def test_rinex3_errors(tmp_path: Path, kind: str, spec: str, needles: tuple[str, ...]) -> None:
    src = _write(tmp_path, "syn.rnx", rinex3_text())
    with pytest.raises(InputError) as ei:
        inject_file(src, tmp_path / "o.rnx", [parse_spec(spec, kind)])  # type: ignore[arg-type]
    msg = str(ei.value)
    assert "\n" not in msg and msg.startswith(f"{src}")
    for s in needles:
        assert s in msg


def test_rinex2_glonass_without_channel(tmp_path: Path) -> None:
    src = _write(tmp_path, "syn.11o", rinex2_text())
    with pytest.raises(InputError, match="GLONASS R03 has no frequency channel"):
        inject_file(src, tmp_path / "o.11o", [parse_spec("R03:L1:0.15:0", "phase")])
    # a slip needs no wavelength: it is applied, size_m unknown
    res = inject_file(src, tmp_path / "o.11o", [parse_spec("R03:L1:1:2", "slip")])
    assert len(res.changes) == 2 and all(math.isnan(c.size_m) for c in res.changes)
    assert _read_log(res.log_path)[0]["size_m"] == ""


def test_overflow_names_line(tmp_path: Path) -> None:
    src = _write(tmp_path, "syn.rnx", rinex3_text())
    with pytest.raises(InputError) as ei:
        inject_file(src, tmp_path / "o.rnx", [parse_spec("E11:L5Q:-1e9:0", "phase")])
    line = ei.value.line
    assert line is not None and "F14.3" in str(ei.value) and "columns 52-65" in str(ei.value)
    assert rinex3_text().splitlines()[line - 1].startswith("E11")  # the first E11 record
    assert rinex3_text().splitlines()[line - 2].startswith("R09")


def test_output_equal_to_input_refused(tmp_path: Path) -> None:
    src = _write(tmp_path, "syn.rnx", rinex3_text())
    before = src.read_bytes()
    with pytest.raises(InputError, match="must differ"):
        inject_file(src, src, [parse_spec("G01:C1C:10:1", "code")])
    with pytest.raises(InputError, match="nothing to inject"):
        inject_bytes(before, [])
    assert src.read_bytes() == before


def test_log_matches_changes_and_spec_dataclass(tmp_path: Path) -> None:
    src = _write(tmp_path, "syn.rnx", rinex3_text())
    log = tmp_path / "changes.csv"
    spec = FaultSpec("code", "E11", "C1C", 3.25, EpochSelection((0, 5)), "--code E11:C1C:3.25:0,5")
    res = inject_file(src, tmp_path / "o.rnx", [spec], log_path=log)
    assert res.log_path == str(log)
    rows = _read_log(log)
    assert [
        (r["epoch_index"], r["sat"], r["obs_code"], r["kind"], r["size_m"], r["size_native"]) for r in rows
    ] == [("0", "E11", "C1C", "code", "3.250000", "3.250"), ("5", "E11", "C1C", "code", "3.250000", "3.250")]
    assert rows[0]["original"] == "24000000.000" and rows[0]["new"] == "24000003.250"
    assert rows[1]["original"] == "24000300.000" and rows[1]["new"] == "24000303.250"


def test_slip_lli_sets_bit0_keeping_other_bits(tmp_path: Path) -> None:
    src = _write(tmp_path, "syn.rnx", rinex3_text())  # G02 L2W carries LLI 4 (bit 2)
    res = inject_file(src, tmp_path / "o.rnx", [parse_spec("G02:L2W:1:3", "slip")], slip_lli=True)
    a, b = read_rinex_obs(src), read_rinex_obs(tmp_path / "o.rnx")
    n, k = a.tx_ids.index("G02"), a.signals.index("2W")
    assert np.all(a.lli[:, n, k] == 4)
    assert b.lli[:, n, k].tolist() == [4, 4, 4, 5, 4, 4]
    assert [(c.epoch_index, c.lli_original, c.lli_new) for c in res.changes] == [
        (3, "4", "5"),
        (4, "4", "4"),
        (5, "4", "4"),
    ]
