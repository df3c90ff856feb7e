"""Serial sources of ``run``: ``serial://DEVICE?baud=N`` parsed, refused in one line without
pyserial, and read byte-exact from a pseudo-terminal (a serial port without hardware)."""

from __future__ import annotations

import os
import sys
import threading
import time
import tty

import pytest

from robustrtk.core import InputError
from robustrtk.io.streams import open_bytes, parse_source


def test_parse_serial_sources() -> None:
    pytest.importorskip("serial")
    spec = parse_source("serial:///dev/ttyUSB0?baud=9600")
    assert (spec.kind, spec.path, spec.baud) == ("serial", "/dev/ttyUSB0", 9600)
    assert spec.label == "serial:///dev/ttyUSB0?baud=9600"
    assert parse_source("serial://COM3").baud == 115200 and parse_source("serial://COM3").path == "COM3"
    for bad in (
        "serial://",
        "serial:///dev/ttyS0?baud=fast",
        "serial:///dev/ttyS0?baud=0",
        "serial:///x?parity=E",
    ):
        with pytest.raises(InputError, match="expected serial://DEVICE"):
            parse_source(bad, "--rover")


def test_serial_without_pyserial_is_one_line(monkeypatch: pytest.MonkeyPatch, tmp_path: object) -> None:
    from robustrtk.cli.entry import run as cli_run

    monkeypatch.setitem(sys.modules, "serial", None)  # import serial: ImportError
    with pytest.raises(
        InputError, match=r"--rover: serial ports need pyserial: pip install 'robustrtk\[serial\]'"
    ):
        parse_source("serial:///dev/ttyUSB0?baud=115200", "--rover")
    args = [
        "run",
        "--rover",
        "serial:///dev/ttyUSB0",
        "--base",
        "tcp://127.0.0.1:1",
        "--out",
        "x.pos",
        "--quiet",
    ]
    assert cli_run(args) == 2


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="no pseudo-terminals here")
def test_serial_bytes_from_a_pseudo_terminal_are_exact() -> None:
    pytest.importorskip("serial")
    master, slave = os.openpty()
    tty.setraw(slave)  # no line discipline between the writer and the port
    data = bytes(range(256)) * 40  # every byte value: CR, LF, XON/XOFF, NUL pass untouched
    stop = threading.Event()
    got = bytearray()
    spec = parse_source(f"serial://{os.ttyname(slave)}?baud=115200")

    def read() -> None:
        for chunk in open_bytes(spec, stop, max_retries=0):
            got.extend(chunk)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        # what is written before the port is open may be flushed by the opening: "S" until
        # the reader has something, then the data
        deadline = time.monotonic() + 10.0
        while not got and time.monotonic() < deadline:
            os.write(master, b"S")
            time.sleep(0.05)
        os.write(master, data)
        while data not in got and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        stop.set()
        reader.join(timeout=2.0)
        os.close(master)
        os.close(slave)
    head = bytes(got[: len(got) - len(data)])
    assert bytes(got[len(head) :]) == data and head and head == b"S" * len(head)
