"""NTRIP client (versions 1 and 2): source table, correction stream, GGA upload, reconnection.

NTRIP (RTCM 10410.1, "Networked Transport of RTCM via Internet Protocol") is HTTP-like:

* version 1: ``GET /MOUNT HTTP/1.0`` with ``User-Agent: NTRIP ...`` and Basic
  authorization; the caster answers ``ICY 200 OK`` and sends the raw stream, or
  ``SOURCETABLE 200 OK`` with the table (unknown mount point), or ``HTTP/1.0 401``;
* version 2: ``GET /MOUNT HTTP/1.1`` with ``Host``, ``Ntrip-Version: Ntrip/2.0``; the caster
  answers ``HTTP/1.1 200 OK``, the stream possibly in ``Transfer-Encoding: chunked``.

``GET /`` returns the source table: ``STR;mountpoint;identifier;format;...`` lines (and
``CAS``/``NET`` lines) up to ``ENDSOURCETABLE``. Network (VRS) mount points need the rover's
position: :class:`NtripClient` sends a GGA sentence right after connecting (or, with no
position yet, as soon as there is one) and then every ``gga_interval_s``. With
``gga_from_table`` it first reads the caster's source table and uploads only to a mount point
whose ``STR`` entry asks for NMEA (field 12 = 1), or that the table does not list (or no
table could be read: a position uploaded to a single base does no harm, a network mount
point left without one sends nothing). A lost connection
(error, end of stream, no data for ``timeout_s``) is retried after 1, 2, 4, ... s (at most
``max_backoff_s``) up to ``max_retries`` times in a row; a refused authorization or an
unknown mount point is not retried (:class:`~robustrtk.core.InputError`).

The client yields raw bytes; feed them to :class:`robustrtk.io.rtcm3.Rtcm3Decoder`.
"""

from __future__ import annotations

import base64
import math
import socket
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

from robustrtk import __version__
from robustrtk.core import InputError

__all__ = ["NtripClient", "SourceEntry", "gga_sentence", "parse_source_table"]

_AGENT = f"NTRIP robustrtk/{__version__}"

#: Longest wait (s) of one read of the stream (the GGA upload is checked between reads).
_POLL_S = 0.5


@dataclass(frozen=True)
class SourceEntry:
    """One ``STR`` line of a source table (fields by RTCM 10410.1 table 4)."""

    mountpoint: str
    identifier: str
    format: str
    format_details: str
    carrier: str
    nav_system: str
    network: str
    country: str
    lat_deg: float
    lon_deg: float
    nmea: bool
    solution: str
    raw: str


def parse_source_table(text: str) -> list[SourceEntry]:
    """The ``STR`` entries of a source table (other lines ignored, short lines padded)."""
    out = []
    for line in text.splitlines():
        f = line.split(";")
        if f[0] != "STR" or len(f) < 2:
            continue
        f = f + [""] * (13 - len(f))

        def num(s: str) -> float:
            try:
                return float(s)
            except ValueError:
                return math.nan

        out.append(
            SourceEntry(
                f[1],
                f[2],
                f[3],
                f[4],
                f[5],
                f[6],
                f[7],
                f[8],
                num(f[9]),
                num(f[10]),
                f[11] == "1",
                f[12],
                line,
            )
        )
    return out


def gga_sentence(lat_deg: float, lon_deg: float, height_m: float, t_utc_s: float, n_sats: int = 10) -> str:
    """An NMEA GGA sentence (with checksum, ``\\r\\n``) for a position and a UTC instant
    (seconds since 1980-01-06 or any count whose modulo-day is the time of day): quality 1,
    HDOP 1.0, geoid separation 0 (``height_m`` is written as the antenna altitude)."""
    tod = t_utc_s % 86400.0
    hh, mm, ss = int(tod // 3600), int(tod % 3600 // 60), tod % 60
    la, lo = abs(lat_deg), abs(lon_deg)
    lat = f"{int(la):02d}{(la - int(la)) * 60:08.5f},{'N' if lat_deg >= 0 else 'S'}"
    lon = f"{int(lo):03d}{(lo - int(lo)) * 60:08.5f},{'E' if lon_deg >= 0 else 'W'}"
    body = f"GPGGA,{hh:02d}{mm:02d}{ss:05.2f},{lat},{lon},1,{n_sats:02d},1.0,{height_m:.3f},M,0.000,M,,"
    ck = 0
    for ch in body.encode("ascii"):
        ck ^= ch
    return f"${body}*{ck:02X}\r\n"


@dataclass
class NtripClient:
    """A client of one caster mount point.

    Parameters
    ----------
    host, port : str, int
    mountpoint : str
        Without the leading ``/``.
    user, password : str, optional
        Basic authorization.
    version : {1, 2}
    gga : callable () -> str, optional
        Returns the GGA sentence to upload (None or ``""``: no position yet; asked again
        at the next read, every 0.5 s at most, until it gives one).
    gga_interval_s : float
        Seconds between uploads after the first; 0: no upload at all.
    gga_from_table : bool
        Upload only when the source table's entry of the mount point has ``nmea`` = 1 (or
        the table does not list it); False: whenever ``gga`` is given.
    timeout_s : float
        Socket timeout; a stream silent this long is reconnected.
    max_retries : int
        Reconnections in a row before giving up (the count restarts after data flowed).
    max_backoff_s : float
    sleep : callable
        ``time.sleep`` (replaceable in tests).
    """

    host: str
    port: int
    mountpoint: str = ""
    user: str | None = None
    password: str | None = None
    version: int = 2
    gga: Callable[[], str | None] | None = None
    gga_interval_s: float = 10.0
    gga_from_table: bool = False
    timeout_s: float = 10.0
    max_retries: int = 5
    max_backoff_s: float = 60.0
    sleep: Callable[[float], None] = time.sleep
    connections: int = 0
    gga_sent: int = 0
    log: list[str] = field(default_factory=list)
    #: Whether the mount point gets GGA sentences (None: not decided yet).
    gga_wanted: bool | None = None

    # ------------------------------------------------------------------ requests
    def _request(self, path: str) -> bytes:
        lines = []
        if self.version == 1:
            lines.append(f"GET /{path} HTTP/1.0")
        else:
            lines += [f"GET /{path} HTTP/1.1", f"Host: {self.host}:{self.port}", "Ntrip-Version: Ntrip/2.0"]
        lines.append(f"User-Agent: {_AGENT}")
        if self.user is not None:
            cred = base64.b64encode(f"{self.user}:{self.password or ''}".encode()).decode("ascii")
            lines.append(f"Authorization: Basic {cred}")
        lines.append("Connection: close")
        return ("\r\n".join(lines) + "\r\n\r\n").encode("ascii")

    def _connect(self, path: str) -> tuple[socket.socket, str, dict[str, str], bytes]:
        """Open, send the request, read the status line and headers.

        Returns the socket, the status line, the headers (lower-case names) and the bytes of
        the body already received."""
        sock = socket.create_connection((self.host, self.port), timeout=self.timeout_s)
        self.connections += 1
        sock.sendall(self._request(path))
        buf = b""
        while b"\r\n\r\n" not in buf and b"\n\n" not in buf:
            chunk = sock.recv(4096)
            if not chunk:
                break
            buf += chunk
            if buf.startswith(b"ICY 200 OK") and b"\r\n" in buf:
                # NTRIP 1: the stream may follow the status line without a blank line
                line, _, after = buf.partition(b"\r\n")
                after = after[2:] if after.startswith(b"\r\n") else after
                return sock, line.decode("latin-1").strip(), {}, after
            if len(buf) > 64 * 1024:
                break
        sep = b"\r\n\r\n" if b"\r\n\r\n" in buf else b"\n\n"
        head, _, rest = buf.partition(sep)
        lines = head.decode("latin-1").splitlines()
        status = lines[0].strip() if lines else ""
        headers = {}
        for ln in lines[1:]:
            k, _, v = ln.partition(":")
            headers[k.strip().lower()] = v.strip()
        return sock, status, headers, rest

    def source_table(self) -> list[SourceEntry]:
        """The caster's source table (``GET /``).

        Raises
        ------
        InputError
            Connection refused or an answer that is not a source table.
        """
        try:
            sock, status, headers, body = self._connect("")
            with sock:
                while b"ENDSOURCETABLE" not in body:
                    chunk = sock.recv(4096)
                    if not chunk:
                        break
                    body += chunk
        except OSError as exc:
            raise InputError(f"NTRIP caster {self.host}:{self.port}: {exc}") from None
        if not (status.startswith("SOURCETABLE 200") or status.split()[1:2] == ["200"]):
            raise InputError(f"NTRIP caster {self.host}:{self.port}: expected a source table, got {status!r}")
        if headers.get("transfer-encoding", "").lower() == "chunked":
            body = _dechunk_all(body)
        return parse_source_table(body.decode("latin-1"))

    # ------------------------------------------------------------------ stream
    def _open_stream(self) -> tuple[socket.socket, bool, bytes]:
        sock, status, headers, rest = self._connect(self.mountpoint)
        parts = status.split()
        if status.startswith("ICY 200") or (
            len(parts) >= 2 and parts[1] == "200" and status.startswith("HTTP")
        ):
            if "gnss/sourcetable" in headers.get("content-type", ""):
                sock.close()
                raise InputError(
                    f"NTRIP mount point {self.mountpoint!r} not found at {self.host}:{self.port}"
                )
            chunked = headers.get("transfer-encoding", "").lower() == "chunked"
            return sock, chunked, rest
        sock.close()
        if status.startswith("SOURCETABLE") or (len(parts) >= 2 and parts[1] == "404"):
            raise InputError(f"NTRIP mount point {self.mountpoint!r} not found at {self.host}:{self.port}")
        if len(parts) >= 2 and parts[1] in ("401", "403"):
            raise InputError(
                f"NTRIP {self.host}:{self.port}/{self.mountpoint}: authorization refused ({status})"
            )
        raise ConnectionError(f"unexpected answer {status!r}")

    def _decide_gga(self) -> None:
        """Set :attr:`gga_wanted` (once): from the source table with ``gga_from_table``."""
        if self.gga_wanted is not None:
            return
        if self.gga is None or self.gga_interval_s <= 0:
            self.gga_wanted = False
            return
        if not self.gga_from_table:
            self.gga_wanted = True
            return
        try:
            entry = next((e for e in self.source_table() if e.mountpoint == self.mountpoint), None)
        except InputError as exc:
            self.gga_wanted = True
            self.log.append(f"no source table ({exc}): GGA uploaded")
            return
        self.gga_wanted = True if entry is None else entry.nmea
        why = "not in the source table" if entry is None else f"source table nmea={int(entry.nmea)}"
        self.log.append(
            f"mount point {self.mountpoint}: {why}: GGA {'uploaded' if self.gga_wanted else 'not sent'}"
        )

    def _send_gga(self, sock: socket.socket) -> bool:
        """Send the current GGA sentence; False when there is none yet (or no upload)."""
        if self.gga is None or self.gga_interval_s <= 0 or not self.gga_wanted:
            return False
        s = self.gga()
        if not s:
            return False
        sock.sendall(s.encode("ascii"))
        self.gga_sent += 1
        return True

    def stream(self) -> Iterator[bytes]:
        """The mount point's bytes, reconnecting after losses (see the module docstring).

        Raises
        ------
        InputError
            Authorization refused, unknown mount point, or ``max_retries`` failed
            reconnections in a row.
        """
        failures = 0
        self._decide_gga()
        while True:
            try:
                sock, chunked, rest = self._open_stream()
            except OSError as exc:
                failures += 1
                self.log.append(f"connect failed: {exc}")
                if failures > self.max_retries:
                    raise InputError(f"NTRIP {self.host}:{self.port}/{self.mountpoint}: {exc}") from None
                self.sleep(min(2.0 ** (failures - 1), self.max_backoff_s))
                continue
            dechunk = _Dechunker() if chunked else None
            try:
                with sock:
                    # short reads: the GGA is due on time even while the caster is silent
                    sock.settimeout(min(_POLL_S, self.timeout_s))
                    sent = self._send_gga(sock)
                    t_gga = t_data = time.monotonic()
                    data = rest
                    while True:
                        if data:
                            out = dechunk.feed(data) if dechunk is not None else data
                            if out:
                                failures = 0
                                yield out
                            if dechunk is not None and dechunk.done:
                                raise ConnectionError("end of chunked stream")
                        now = time.monotonic()
                        # the first sentence as soon as there is a position, then every interval
                        if self.gga_wanted:
                            if not sent or now - t_gga >= self.gga_interval_s:
                                sent = self._send_gga(sock) or sent
                                t_gga = now
                        try:
                            data = sock.recv(4096)
                        except TimeoutError:
                            if time.monotonic() - t_data >= self.timeout_s:
                                raise ConnectionError(f"no data for {self.timeout_s:g} s") from None
                            data = b""
                            continue
                        if not data:
                            raise ConnectionError("stream closed by the caster")
                        t_data = time.monotonic()
            except OSError as exc:
                failures += 1
                self.log.append(f"stream lost: {exc}")
                if failures > self.max_retries:
                    raise InputError(f"NTRIP {self.host}:{self.port}/{self.mountpoint}: {exc}") from None
                self.sleep(min(2.0 ** (failures - 1), self.max_backoff_s))


class _Dechunker:
    """HTTP/1.1 chunked transfer decoding, incremental: size line, data, CRLF, ..."""

    def __init__(self) -> None:
        self.buf = b""
        self.state = "size"
        self.left = 0
        self.done = False

    def feed(self, data: bytes) -> bytes:
        self.buf += data
        out = []
        while not self.done:
            if self.state == "size":
                line, sep, rest = self.buf.partition(b"\r\n")
                if not sep:
                    break
                try:
                    size = int(line.split(b";")[0].strip() or b"0", 16)
                except ValueError:
                    raise ConnectionError(f"bad chunk size {line[:20]!r}") from None
                self.buf = rest
                if size == 0:
                    self.done = True
                    break
                self.left, self.state = size, "data"
            elif self.state == "data":
                if not self.buf:
                    break
                take = self.buf[: self.left]
                out.append(take)
                self.buf = self.buf[len(take) :]
                self.left -= len(take)
                if self.left == 0:
                    self.state = "crlf"
            else:
                if len(self.buf) < 2:
                    break
                self.buf = self.buf[2:]
                self.state = "size"
        return b"".join(out)


def _dechunk_all(body: bytes) -> bytes:
    return _Dechunker().feed(body)
