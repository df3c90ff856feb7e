"""Byte streams in and NMEA out for real-time runs.

Sources (:func:`parse_source`, :func:`open_bytes`):

* a file path — read whole (plain or compressed) and handed on in chunks; the caller
  paces its epochs (replay at real or accelerated speed);
* ``tcp://host:port`` — a TCP client; a lost connection is retried after 1, 2, 4, ... s
  (at most 30 s) up to ``max_retries`` times in a row;
* ``tcp://:port`` — a TCP server (RTKLIB's ``tcpsvr``): a receiver or a bridge connects and
  sends its bytes; one client at a time, the next one waited for when it leaves or stays
  silent;
* ``ntrip://[user[:password]@]host[:port]/MOUNT`` — an NTRIP caster's mount point
  (:class:`~robustrtk.io.ntrip.NtripClient`, version 2, port 2101 by default);
* ``serial:///dev/ttyUSB0?baud=115200`` (``serial://COM3?baud=...`` on Windows) — a serial
  port, 8N1, 115200 baud by default, through the optional pyserial
  (``pip install 'robustrtk[serial]'``); a port that fails (unplugged) is reopened like a
  lost TCP connection.

Out: :class:`NmeaServer` serves lines (GGA, RMC) to every client connected to a TCP port;
:func:`rmc_sentence` is the RMC sentence of a solution (GGA:
:func:`robustrtk.io.solution_nmea.gga_sentence`).
"""

from __future__ import annotations

import math
import os
import socket
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from urllib.parse import parse_qs, unquote, urlsplit

import numpy as np
import numpy.typing as npt

from robustrtk.core import InputError
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.io.solution_nmea import nmea_checksum
from robustrtk.timeutil import gpst2utc

__all__ = ["NmeaServer", "SourceSpec", "open_bytes", "parse_source", "rmc_sentence"]

#: Chunk size (bytes) of file and socket reads.
CHUNK = 4096


@dataclass(frozen=True)
class SourceSpec:
    """A parsed ``SOURCE`` argument."""

    kind: str  # "file", "tcp", "tcpsvr" (a TCP server), "ntrip" or "serial"
    path: str = ""
    host: str = ""
    port: int = 0
    mount: str = ""
    user: str | None = None
    password: str | None = None
    baud: int = 0

    @property
    def label(self) -> str:
        """The source without its password."""
        if self.kind == "file":
            return self.path
        if self.kind in ("tcp", "tcpsvr"):
            return f"tcp://{self.host}:{self.port}"
        if self.kind == "serial":
            return f"serial://{self.path}?baud={self.baud}"
        who = f"{self.user}@" if self.user else ""
        return f"ntrip://{who}{self.host}:{self.port}/{self.mount}"


def parse_source(text: str, what: str = "SOURCE") -> SourceSpec:
    """A file path, ``tcp://host:port`` (``tcp://:port``: a TCP server),
    ``ntrip://user:pass@host:port/MOUNT`` or ``serial://DEVICE?baud=N``.

    Raises
    ------
    InputError
        An unknown scheme, a missing host, port, mount point or device, a bad baud rate, a
        file that does not exist, or a serial port without pyserial installed.
    """
    if "://" not in text:
        if not os.path.isfile(text):
            raise InputError(
                f"{what}: no such file (expected a file, tcp://host:port, ntrip://... or serial://...)", text
            )
        return SourceSpec("file", path=text)
    u = urlsplit(text)
    if u.scheme == "serial":
        return _parse_serial(u.netloc + u.path, u.query, text, what)
    try:
        port = u.port
    except ValueError:
        raise InputError(f"{what}: bad port in {text!r}") from None
    if u.scheme == "tcp":
        if port is None or (not u.hostname and not u.netloc.startswith(":")):
            raise InputError(f"{what}: expected tcp://host:port (or tcp://:port to listen), got {text!r}")
        if not u.hostname:
            return SourceSpec("tcpsvr", host="", port=port)
        return SourceSpec("tcp", host=u.hostname, port=port)
    if u.scheme == "ntrip":
        mount = u.path.lstrip("/")
        if not u.hostname or not mount:
            raise InputError(f"{what}: expected ntrip://[user:pass@]host[:port]/MOUNT, got {text!r}")
        user = unquote(u.username) if u.username else None
        pw = unquote(u.password) if u.password else None
        return SourceSpec("ntrip", host=u.hostname, port=port or 2101, mount=mount, user=user, password=pw)
    raise InputError(f"{what}: unknown scheme {u.scheme!r} (expected a file, tcp://, ntrip:// or serial://)")


def _parse_serial(device: str, query: str, text: str, what: str) -> SourceSpec:
    params = parse_qs(query)
    baud_text = params.pop("baud", ["115200"])[-1]
    if not device or params or not baud_text.isdigit() or int(baud_text) <= 0:
        raise InputError(
            f"{what}: expected serial://DEVICE[?baud=N] (serial:///dev/ttyUSB0?baud=115200), got {text!r}"
        )
    try:
        import serial  # noqa: F401 - pyserial, the optional extra
    except ImportError:
        raise InputError(f"{what}: serial ports need pyserial: pip install 'robustrtk[serial]'") from None
    return SourceSpec("serial", path=device, baud=int(baud_text))


def _serial_bytes(spec: SourceSpec, stop: threading.Event, max_retries: int) -> Iterator[bytes]:
    """A serial port's bytes as they come (a silent port is waited for: a receiver may be
    quiet; a failing one is reopened after 1, 2, 4, ... s, ``max_retries`` times in a row)."""
    import serial

    failures = 0
    while not stop.is_set():
        try:
            with serial.Serial(spec.path, spec.baud, timeout=0.5) as port:
                while not stop.is_set():
                    data = port.read(1)  # returns at the first byte, or empty after 0.5 s
                    if data:
                        data += port.read(port.in_waiting)
                        failures = 0
                        yield data
        except OSError as exc:  # serial.SerialException is an OSError
            failures += 1
            if failures > max_retries:
                raise InputError(f"{spec.label}: {exc}") from None
            stop.wait(min(2.0 ** (failures - 1), 30.0))


def _tcp_bytes(
    spec: SourceSpec, stop: threading.Event, max_retries: int, timeout_s: float
) -> Iterator[bytes]:
    failures = 0
    while not stop.is_set():
        try:
            with socket.create_connection((spec.host, spec.port), timeout=timeout_s) as sock:
                sock.settimeout(0.5)
                silent = 0.0
                while not stop.is_set():
                    try:
                        data = sock.recv(CHUNK)
                    except TimeoutError:
                        silent += 0.5
                        if silent >= timeout_s:
                            raise ConnectionError("no data") from None
                        continue
                    if not data:
                        raise ConnectionError("closed by the server")
                    failures, silent = 0, 0.0
                    yield data
        except OSError as exc:
            failures += 1
            if failures > max_retries:
                raise InputError(f"{spec.label}: {exc}") from None
            stop.wait(min(2.0 ** (failures - 1), 30.0))


def _tcp_server_bytes(spec: SourceSpec, stop: threading.Event, timeout_s: float) -> Iterator[bytes]:
    """A TCP server's bytes: one client at a time (a receiver or a bridge that connects to
    us); when it leaves, or stays silent ``timeout_s``, the next client is waited for."""
    try:
        server = socket.create_server((spec.host, spec.port))
    except OSError as exc:
        raise InputError(f"{spec.label}: cannot listen: {exc}") from None
    with server:
        server.settimeout(0.5)
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except TimeoutError:
                continue
            with conn:
                conn.settimeout(0.5)
                silent = 0.0
                while not stop.is_set():
                    try:
                        data = conn.recv(CHUNK)
                    except TimeoutError:
                        silent += 0.5
                        if silent >= timeout_s:
                            break
                        continue
                    except OSError:
                        break
                    if not data:
                        break
                    silent = 0.0
                    yield data


def open_bytes(
    spec: SourceSpec,
    stop: threading.Event | None = None,
    *,
    max_retries: int = 5,
    timeout_s: float = 10.0,
    gga: Callable[[], str | None] | None = None,
    gga_interval_s: float = 10.0,
    gga_from_table: bool = False,
) -> Iterator[bytes]:
    """The source's bytes in chunks, until its end (files; a stream whose reconnections
    failed ``max_retries`` times in a row: :class:`InputError`) or ``stop`` is set.
    ``gga``: the sentence an NTRIP network mount point is sent (the rover's position),
    after connecting and then every ``gga_interval_s`` (0: never); with ``gga_from_table``
    only when the caster's source table says the mount point wants it (see
    :class:`~robustrtk.io.ntrip.NtripClient`)."""
    stop = stop or threading.Event()
    if spec.kind == "file":
        from robustrtk.io.raw_file import read_binary_log

        data, _ = read_binary_log(spec.path)
        for k in range(0, len(data), CHUNK):
            if stop.is_set():
                return
            yield data[k : k + CHUNK]
        return
    if spec.kind == "tcp":
        yield from _tcp_bytes(spec, stop, max_retries, timeout_s)
        return
    if spec.kind == "tcpsvr":
        yield from _tcp_server_bytes(spec, stop, timeout_s)
        return
    if spec.kind == "serial":
        yield from _serial_bytes(spec, stop, max_retries)
        return
    from robustrtk.io.ntrip import NtripClient

    client = NtripClient(
        spec.host, spec.port, spec.mount, spec.user, spec.password, gga=gga, gga_interval_s=gga_interval_s,
        gga_from_table=gga_from_table, timeout_s=timeout_s, max_retries=max_retries,
        sleep=lambda s: None if stop.wait(s) else None,
    )  # fmt: skip
    for data in client.stream():
        if stop.is_set():
            return
        yield data


def _ddmm(value_deg: float, deg_digits: int) -> str:
    """``(d)ddmm.mmmmmmm`` of an absolute angle (deg)."""
    minutes = round(abs(value_deg) * 60.0, 7)
    deg = int(minutes // 60.0)
    return f"{deg:0{deg_digits}d}{minutes - deg * 60.0:010.7f}"


def rmc_sentence(
    t_s: float,
    pos_ecef_m: npt.ArrayLike,
    vel_ecef_m_s: npt.ArrayLike | None,
    valid: bool,
    status: str = "",
) -> str:
    """One ``$GPRMC`` sentence (no terminator): UTC time and date, status ``A`` (valid) or
    ``V``, latitude, longitude, speed over ground (knots) and course (deg from north) from
    the ECEF velocity rotated to the local east-north-up frame (empty without one),
    magnetic variation empty, mode ``A`` (autonomous: a solution of status ``single``),
    ``D`` (differential) or ``N`` (not valid)."""
    p = np.asarray(pos_ecef_m, float).reshape(3)
    lat, lon, _ = (float(v) for v in ecef2geodetic(p))
    utc = float(gpst2utc(t_s))
    cs = int(round(utc * 100.0))
    sod, cc = divmod(cs % (86_400 * 100), 100)
    hh, rem = divmod(sod, 3600)
    mm, ss = divmod(rem, 60)
    day = time.gmtime(315_964_800 + math.floor(utc))  # GPS epoch 1980-01-06 in Unix time
    speed = course = ""
    if vel_ecef_m_s is not None and np.all(np.isfinite(np.asarray(vel_ecef_m_s, float))):
        e, n, _ = ecef2enu_rotation(lat, lon) @ np.asarray(vel_ecef_m_s, float).reshape(3)
        speed = f"{math.hypot(e, n) / 0.514444:.3f}"
        course = f"{math.degrees(math.atan2(e, n)) % 360.0:.2f}"
    lat_d, lon_d = math.degrees(lat), math.degrees(lon)
    mode = ("A" if status == "single" else "D") if valid else "N"
    body = (
        f"GPRMC,{hh:02d}{mm:02d}{ss:02d}.{cc:02d},{'A' if valid else 'V'},"
        f"{_ddmm(lat_d, 2)},{'N' if lat_d >= 0 else 'S'},{_ddmm(lon_d, 3)},{'E' if lon_d >= 0 else 'W'},"
        f"{speed},{course},{day.tm_mday:02d}{day.tm_mon:02d}{day.tm_year % 100:02d},,,{mode}"
    )
    return f"${body}*{nmea_checksum(body)}"


class NmeaServer:
    """Lines to every client of a TCP port (clients that fail or lag are dropped).

    Parameters
    ----------
    host, port : str, int
        Where to listen; port 0 takes a free port (see :attr:`port`).
    """

    def __init__(self, host: str = "", port: int = 0) -> None:
        self.sock = socket.create_server((host, port), reuse_port=False)
        self.sock.settimeout(0.2)
        self.port = int(self.sock.getsockname()[1])
        self.clients: list[socket.socket] = []
        self.lock = threading.Lock()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._accept, name="nmea-server", daemon=True)
        self.thread.start()

    def _accept(self) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.settimeout(1.0)
            with self.lock:
                self.clients.append(conn)

    def send(self, text: str) -> None:
        """Send ``text`` (whole lines) to every client."""
        data = text.encode("ascii")
        with self.lock:
            alive = []
            for c in self.clients:
                try:
                    c.sendall(data)
                    alive.append(c)
                except OSError:
                    c.close()
            self.clients = alive

    def close(self) -> None:
        """Stop listening and close every client."""
        self.stop.set()
        self.sock.close()
        with self.lock:
            for c in self.clients:
                c.close()
            self.clients = []
        self.thread.join(timeout=1.0)
