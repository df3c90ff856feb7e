"""NTRIP client against a small loopback caster in the test: source table, versions 1 and 2
(chunked), Basic authorization, GGA upload, reconnection after the caster drops the stream."""

from __future__ import annotations

import base64
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError
from robustrtk.io.ntrip import NtripClient, gga_sentence, parse_source_table
from robustrtk.io.rtcm3 import Rtcm3Decoder, read_rtcm3

TABLE = (
    "STR;BASE1;Galway;RTCM 3.3;1005(10),1077(1),1087(1);2;GPS+GLO;NONE;IRL;53.28;-9.06;0;0;"
    "u-blox;none;B;N;9600;\r\n"
    "STR;VRS;Network;RTCM 3.3;1077(1);2;GPS;NET;IRL;53.00;-9.00;1;1;sNTRIP;none;B;N;9600;\r\n"
    "ENDSOURCETABLE\r\n"
)


class Caster:
    """A loopback caster serving ``data`` on mount point ``BASE1`` to user ``u`` / ``p``.

    The first ``drop_after`` bytes of the first connection are sent, then the connection is
    closed (a lost link); later connections send the rest."""

    def __init__(self, data: bytes, drop_after: int | None = None) -> None:
        self.data = data
        self.drop_after = drop_after
        self.sent = 0
        self.requests: list[str] = []
        self.gga: list[str] = []
        self.srv = socket.socket()
        self.srv.bind(("127.0.0.1", 0))
        self.srv.listen(5)
        self.port = self.srv.getsockname()[1]
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.srv.accept()
            except OSError:
                return
            with conn:
                self._handle(conn)

    def _handle(self, conn: socket.socket) -> None:
        req = b""
        while b"\r\n\r\n" not in req:
            chunk = conn.recv(4096)
            if not chunk:
                return
            req += chunk
        head = req.split(b"\r\n\r\n")[0].decode()
        self.requests.append(head)
        path = head.split()[1]
        v2 = "Ntrip-Version: Ntrip/2.0" in head
        if path == "/":
            if v2:
                conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Type: gnss/sourcetable\r\n\r\n" + TABLE.encode())
            else:
                conn.sendall(b"SOURCETABLE 200 OK\r\nContent-Type: text/plain\r\n\r\n" + TABLE.encode())
            return
        auth = "Authorization: Basic " + base64.b64encode(b"u:p").decode()
        if auth not in head:
            conn.sendall(b"HTTP/1.1 401 Unauthorized\r\n\r\n" if v2 else b"HTTP/1.0 401 Unauthorized\r\n\r\n")
            return
        if path != "/BASE1":
            conn.sendall(b"SOURCETABLE 200 OK\r\n\r\n" + TABLE.encode())
            return
        conn.sendall(b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n" if v2 else b"ICY 200 OK\r\n")
        conn.settimeout(2.0)
        try:
            self.gga.append(conn.recv(200).decode())
        except TimeoutError:
            pass
        end = len(self.data)
        if self.drop_after is not None and self.sent == 0:
            end = self.drop_after
        while self.sent < end:
            piece = self.data[self.sent : min(self.sent + 3000, end)]
            conn.sendall(b"%x\r\n%s\r\n" % (len(piece), piece) if v2 else piece)
            self.sent += len(piece)
        if v2 and end == len(self.data):
            conn.sendall(b"0\r\n\r\n")

    def close(self) -> None:
        self.srv.close()


@pytest.fixture(scope="module")
def base_stream(shared_data: Path) -> Path:
    p = shared_data / "galway_m8p_l1_lowcost" / "s1_static" / "base-20181004-1236.rtcm3"
    if not p.is_file():
        pytest.skip(f"{p} absent")
    return p


def test_source_table_v1_and_v2() -> None:
    caster = Caster(b"")
    try:
        for version in (1, 2):
            table = NtripClient("127.0.0.1", caster.port, version=version).source_table()
            assert [e.mountpoint for e in table] == ["BASE1", "VRS"]
            assert table[1].nmea and not table[0].nmea
            assert table[0].lat_deg == 53.28 and table[0].format == "RTCM 3.3"
    finally:
        caster.close()
    assert parse_source_table("CAS;x\r\nSTR;M\r\n")[0].mountpoint == "M"


@pytest.mark.parametrize("version", [1, 2])
def test_stream_with_gga_and_reconnection_equals_file(base_stream: Path, version: int) -> None:
    data = base_stream.read_bytes()
    caster = Caster(data, drop_after=len(data) // 3)
    gga = gga_sentence(53.28, -9.06, 66.1, 45_000.0)
    waits: list[float] = []
    client = NtripClient(
        "127.0.0.1", caster.port, "BASE1", "u", "p", version=version, gga=lambda: gga, sleep=waits.append
    )
    dec = Rtcm3Decoder(t_ref_s=read_rtcm3(base_stream)[0].t_s[0])
    got = 0
    try:
        for chunk in client.stream():
            dec.feed(chunk)
            got += len(chunk)
            if got >= len(data):
                break
    finally:
        caster.close()
    assert client.connections == 2 and waits == [1.0]  # one loss, one reconnection after 1 s
    assert caster.gga and caster.gga[0] == gga
    body, star, ck = gga[1:].strip().partition("*")
    assert star and int(ck, 16) == np.bitwise_xor.reduce(np.frombuffer(body.encode(), np.uint8))
    assert gga.startswith("$GPGGA,123000.00,5316.80000,N,00903.60000,W,1,10,")
    ref = read_rtcm3(base_stream)[0]
    b = dec.batch()
    assert len(b) == len(ref) == 623
    np.testing.assert_array_equal(b.code_m, ref.code_m)
    assert ("Ntrip-Version: Ntrip/2.0" in caster.requests[0]) == (version == 2)


def test_refused_authorization_and_unknown_mountpoint_are_not_retried() -> None:
    caster = Caster(b"\xd3\x00\x00\x47\xea\x4b")
    waits: list[float] = []
    try:
        with pytest.raises(InputError, match="authorization refused"):
            next(NtripClient("127.0.0.1", caster.port, "BASE1", "u", "wrong", sleep=waits.append).stream())
        with pytest.raises(InputError, match="not found"):
            next(
                NtripClient(
                    "127.0.0.1", caster.port, "NOPE", "u", "p", version=1, sleep=waits.append
                ).stream()
            )
    finally:
        caster.close()
    assert waits == []


def test_unreachable_caster_backs_off_then_gives_up() -> None:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nothing listens there
    waits: list[float] = []
    client = NtripClient("127.0.0.1", port, "BASE1", max_retries=4, max_backoff_s=5.0, sleep=waits.append)
    with pytest.raises(InputError):
        next(client.stream())
    assert waits == [1.0, 2.0, 4.0, 5.0]


class VrsCaster:
    """A network (VRS) mount point: answers, then sends nothing until the client uploads a
    GGA sentence; from then on a small piece every 0.1 s for ``serve_s``, collecting every
    GGA line (with the piece count at its arrival). Without a GGA it closes after
    ``wait_s``."""

    def __init__(self, serve_s: float, wait_s: float = 3.0) -> None:
        self.serve_s, self.wait_s = serve_s, wait_s
        self.gga: list[tuple[int, str]] = []
        self.pieces = 0
        self.srv = socket.create_server(("127.0.0.1", 0))
        self.port = self.srv.getsockname()[1]
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        conn, _ = self.srv.accept()
        with conn:
            req = b""
            while b"\r\n\r\n" not in req:
                req += conn.recv(4096)
            conn.sendall(b"ICY 200 OK\r\n\r\n")
            conn.settimeout(0.1)
            buf = b""
            waited = served = 0.0
            while served < self.serve_s and waited < self.wait_s:
                try:
                    chunk = conn.recv(1024)
                except TimeoutError:
                    chunk = b""
                buf += chunk
                *lines, buf = buf.split(b"\r\n")
                self.gga += [(self.pieces, ln.decode()) for ln in lines if ln.startswith(b"$GPGGA")]
                if self.gga:
                    conn.sendall(b"x" * 10)
                    self.pieces += 1
                    served += 0.1
                else:
                    waited += 0.1
        self.srv.close()


def test_gga_waits_for_a_position_then_repeats_every_interval() -> None:
    """No position at first: nothing is sent (the caster stays silent, the client keeps
    asking); the first GGA goes as soon as there is one, then one every interval."""
    caster = VrsCaster(serve_s=2.0)
    gga = gga_sentence(53.28, -9.06, 66.1, 45_000.0)
    asked: list[float] = []
    t0 = time.monotonic()

    def position() -> str | None:
        asked.append(time.monotonic() - t0)
        return gga if time.monotonic() - t0 > 0.8 else None  # a first solution after 0.8 s

    client = NtripClient(
        "127.0.0.1", caster.port, "VRS", gga=position, gga_interval_s=0.5, max_retries=0, sleep=lambda s: None
    )
    got = b""
    t_first = t_last = 0.0
    with pytest.raises(InputError, match="closed"):
        for chunk in client.stream():
            t_last = time.monotonic()
            t_first = t_first or t_last
            got += chunk
    assert len(asked) >= 3 and asked[0] < 0.8  # asked again while there was no position
    assert len(got) == 10 * caster.pieces and caster.pieces >= 10
    sent = [s for _, s in caster.gga]
    assert sent and all(s == gga.strip() for s in sent)
    assert caster.gga[0][0] == 0  # the first upload before any data came
    # then one every 0.5 s while the data flowed (±1 for where the stream's ends fall)
    assert abs(len(sent) - 1 - (t_last - t_first) / 0.5) <= 1.5 and len(sent) >= 3
    assert client.gga_sent == len(sent)


def test_gga_interval_zero_sends_nothing() -> None:
    caster = VrsCaster(serve_s=1.0, wait_s=1.0)
    gga = gga_sentence(53.28, -9.06, 66.1, 45_000.0)
    client = NtripClient(
        "127.0.0.1",
        caster.port,
        "VRS",
        gga=lambda: gga,
        gga_interval_s=0.0,
        max_retries=0,
        sleep=lambda s: None,
    )
    with pytest.raises(InputError, match="closed"):
        for _ in client.stream():
            pass
    assert caster.gga == [] and client.gga_sent == 0
