"""``tcp://:PORT``: run listens and a receiver (or a bridge) connects and sends its bytes; one
client at a time, the next waited for when it leaves."""

from __future__ import annotations

import socket
import threading
import time

import pytest

from robustrtk.core import InputError
from robustrtk.io.streams import open_bytes, parse_source


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _send(port: int, data: bytes) -> None:
    for _ in range(100):  # until the server listens
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=2.0) as c:
                c.sendall(data)
            return
        except ConnectionRefusedError:
            time.sleep(0.05)
    raise AssertionError("the server never listened")


def test_parse_listen_and_connect() -> None:
    spec = parse_source("tcp://:2101")
    assert (spec.kind, spec.host, spec.port, spec.label) == ("tcpsvr", "", 2101, "tcp://:2101")
    assert parse_source("tcp://host.example:2101").kind == "tcp"
    with pytest.raises(InputError, match="tcp://:port to listen"):
        parse_source("tcp://:")


def test_server_reads_one_client_after_another() -> None:
    port = _free_port()
    stop = threading.Event()
    got: list[bytes] = []

    def consume() -> None:
        for chunk in open_bytes(parse_source(f"tcp://:{port}"), stop, timeout_s=5.0):
            got.append(chunk)
            if sum(map(len, got)) >= 20_000:
                stop.set()

    t = threading.Thread(target=consume, daemon=True)
    t.start()
    first, second = bytes(range(256)) * 40, b"\xd3" * 9_760  # 10 240 + 9 760 bytes
    _send(port, first)
    time.sleep(0.3)  # the first client has left: the next one is waited for
    _send(port, second)
    t.join(timeout=10.0)
    assert not t.is_alive()
    assert b"".join(got) == first + second
