"""GGA upload decided by the caster's source table: a loopback caster lists a single base
(``nmea`` = 0) and a network mount point (``nmea`` = 1); the client uploads the rover's
position only to the latter, unless told to upload everywhere (``run --gga-interval-s``)."""

from __future__ import annotations

import socket
import threading
from pathlib import Path

import pytest

from robustrtk.cli.entry import run as cli_run
from robustrtk.core import InputError
from robustrtk.io.ntrip import NtripClient, gga_sentence
from robustrtk.io.raw_file import read_binary_log

TABLE = (
    "STR;S1;Galway;RTCM 3.2;1005(10),1077(1);2;GPS;NONE;IRL;53.28;-9.06;0;0;u-blox;none;B;N;9600;\r\n"
    "STR;NET;Network;RTCM 3.2;1077(1);2;GPS;NET;IRL;53.00;-9.00;1;1;sNTRIP;none;B;N;9600;\r\n"
    "ENDSOURCETABLE\r\n"
)
GGA = gga_sentence(53.28, -9.06, 66.1, 45_000.0)


class TableCaster:
    """Answers ``GET /`` with :data:`TABLE` and any other mount point with ``data`` (then
    holds the connection ``hold_s``), collecting the GGA lines each mount point received."""

    def __init__(self, data: bytes, hold_s: float = 1.0, table: bool = True) -> None:
        self.data, self.hold_s, self.table = data, hold_s, table
        self.gga: dict[str, list[str]] = {}
        self.paths: list[str] = []
        self.srv = socket.create_server(("127.0.0.1", 0))
        self.port = self.srv.getsockname()[1]
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.srv.accept()
            except OSError:
                return
            threading.Thread(target=self._handle, args=(conn,), daemon=True).start()

    def _handle(self, conn: socket.socket) -> None:
        with conn:
            req = b""
            while b"\r\n\r\n" not in req:
                chunk = conn.recv(4096)
                if not chunk:
                    return
                req += chunk
            path = req.split()[1].decode()
            self.paths.append(path)
            if path == "/":
                if self.table:
                    conn.sendall(b"SOURCETABLE 200 OK\r\nContent-Type: text/plain\r\n\r\n" + TABLE.encode())
                else:
                    conn.sendall(b"HTTP/1.1 404 Not Found\r\n\r\n")
                return
            got = self.gga.setdefault(path[1:], [])
            conn.sendall(b"ICY 200 OK\r\n\r\n" + self.data)
            conn.settimeout(0.1)
            buf = b""
            for _ in range(int(self.hold_s / 0.1)):
                try:
                    chunk = conn.recv(1024)
                except TimeoutError:
                    continue
                if not chunk:
                    return
                *lines, buf = (buf + chunk).split(b"\r\n")
                got += [ln.decode() for ln in lines if ln.startswith(b"$GPGGA")]

    def close(self) -> None:
        self.srv.close()


def stream_all(client: NtripClient) -> bytes:
    got = b""
    with pytest.raises(InputError):
        for chunk in client.stream():
            got += chunk
    return got


@pytest.mark.parametrize(
    ("mount", "from_table", "expect"), [("S1", True, False), ("NET", True, True), ("S1", False, True)]
)
def test_gga_only_to_mount_points_whose_entry_asks_for_it(mount: str, from_table: bool, expect: bool) -> None:
    caster = TableCaster(b"x" * 100)
    try:
        client = NtripClient(
            "127.0.0.1", caster.port, mount, gga=lambda: GGA, gga_interval_s=0.2, gga_from_table=from_table,
            max_retries=0, sleep=lambda s: None,
        )  # fmt: skip
        assert stream_all(client) == b"x" * 100
    finally:
        caster.close()
    assert client.gga_wanted is expect
    sent = caster.gga[mount]
    assert (len(sent) >= 2) if expect else (sent == [])
    assert all(s == GGA.strip() for s in sent)
    assert ("/" in caster.paths) is from_table  # the table is read only when it decides
    assert client.gga_sent == len(sent)


def test_gga_sent_when_the_table_cannot_tell() -> None:
    """No source table, or a mount point it does not list: the position is uploaded."""
    for table, mount in ((False, "S1"), (True, "HIDDEN")):
        caster = TableCaster(b"y" * 10, table=table)
        try:
            client = NtripClient(
                "127.0.0.1", caster.port, mount, gga=lambda: GGA, gga_interval_s=0.2, gga_from_table=True,
                max_retries=0, sleep=lambda s: None,
            )  # fmt: skip
            stream_all(client)
        finally:
            caster.close()
        assert client.gga_wanted is True
        assert caster.gga[mount] and client.log[0].startswith(("no source table", "mount point HIDDEN"))


@pytest.fixture(scope="module")
def s1(shared_data: Path) -> Path:
    d = shared_data / "galway_m8p_l1_lowcost" / "s1_static"
    if not d.is_dir():
        pytest.skip(f"{d} absent")
    return d


def test_run_uploads_gga_by_the_source_table_unless_the_interval_is_given(s1: Path, tmp_path: Path) -> None:
    base, _ = read_binary_log(s1 / "base-20181004-1236.rtcm3")
    rover_all, _ = read_binary_log(s1 / "rover-20181004-1237.ubx.gz")
    rover = tmp_path / "rover.ubx"
    rover.write_bytes(rover_all[: len(rover_all) // 10])
    nav = s1 / "rover-20181004-1237.nav"
    sent: dict[tuple[str, bool], int] = {}
    for mount, forced in (("S1", False), ("NET", False), ("S1", True)):
        caster = TableCaster(base[: len(base) // 20], hold_s=3.0)
        out = tmp_path / f"{mount}{forced}.pos"
        args = [
            "run", "--rover", str(rover), "--base", f"ntrip://127.0.0.1:{caster.port}/{mount}",
            "--nav", str(nav), "--time-ref", "2018/10/04 12:00:00", "--speed", "50", "--retries", "0",
            "--out", str(out), "--quiet", "--mode", "dgnss", "--freqs", "L1",
        ]  # fmt: skip
        if forced:
            args += ["--gga-interval-s", "0.5"]
        try:
            assert cli_run(args) == 0
        finally:
            caster.close()
        assert out.is_file()
        sent[mount, forced] = len(caster.gga.get(mount, []))
    assert sent["S1", False] == 0  # a single base that does not ask for NMEA
    assert sent["NET", False] >= 1 and sent["S1", True] >= 1
