"""``robustrtk run`` on the galway s1 logs served over loopback sockets: the base's RTCM 3 by
a small NTRIP caster, the rover's UBX by a TCP server, both at accelerated speed.

* Same data, same configuration: ``run`` writes the forward solution ``solve`` writes (the
  data-driven code σ off: it is estimated from the whole file; the base position given: the
  stream's 1005 message comes 52 s after its first epoch; ``--base-wait`` long, so that the
  rover always waits for its base epoch whatever the two servers' pace).
* The base silent for 40 s in the middle: the run goes on, the age of differential grows,
  the status falls to float / single, and RTK comes back when the base returns.
"""

from __future__ import annotations

import base64
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from robustrtk.cli.entry import run as cli_run
from robustrtk.io.raw_file import read_binary_log

BASE_POS = "3774089.212,-601661.6157,5089321.2474"  # the base's own 1005 position
ROVER, BASE, NAV = "rover-20181004-1237.ubx.gz", "base-20181004-1236.rtcm3", "rover-20181004-1237.nav"
SETTINGS = ["--mode", "rtk", "--freqs", "L1", "--no-code-sigma-from-data"]


@pytest.fixture(scope="module")
def s1(shared_data: Path) -> Path:
    d = shared_data / "galway_m8p_l1_lowcost" / "s1_static"
    if not d.is_dir():
        pytest.skip(f"{d} absent")
    return d


class Server:
    """Serves ``data`` once to the first client, ``rate`` bytes per second (0: at once),
    skipping the bytes in ``gap`` (fractions of the data) after a pause as long as they
    would have taken; NTRIP: answers the source-table request (``S1`` asks for NMEA when
    ``need_gga``) and then the request of mount point ``/S1`` (user u, password p). Later
    connections are refused (closed at once)."""

    def __init__(
        self,
        data: bytes,
        rate: float,
        ntrip: bool,
        gap: tuple[float, float] | None = None,
        delay_s: float = 0.0,
        need_gga: bool = False,
        hold_s: float = 0.0,
    ) -> None:
        self.data, self.rate, self.ntrip, self.gap, self.delay_s = data, rate, ntrip, gap, delay_s
        self.need_gga, self.hold_s = need_gga, hold_s
        self.srv = socket.create_server(("127.0.0.1", 0))
        self.port = self.srv.getsockname()[1]
        self.request = ""
        self.gga: list[str] = []  # the GGA sentences the client uploaded (NTRIP)
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        conn, _ = self.srv.accept()
        with conn:
            if self.ntrip:
                req = b""
                while b"\r\n\r\n" not in req:
                    req += conn.recv(4096)
                self.request = req.decode()
                while self.request.startswith("GET / "):  # the source table, then the stream
                    nmea = int(self.need_gga)
                    table = f"STR;S1;Galway;RTCM 3.2;1077(1);2;GPS;NONE;IRL;53;-9;{nmea};0;x;none;B;N;0;\r\n"
                    conn.sendall(b"SOURCETABLE 200 OK\r\n\r\n" + table.encode() + b"ENDSOURCETABLE\r\n")
                    conn.close()
                    conn, _ = self.srv.accept()
                    req = b""
                    while b"\r\n\r\n" not in req:
                        req += conn.recv(4096)
                    self.request = req.decode()
                auth = "Authorization: Basic " + base64.b64encode(b"u:p").decode()
                if " /S1 " not in self.request or auth not in self.request:
                    conn.sendall(b"HTTP/1.1 401 Unauthorized\r\n\r\n")
                    return
                conn.sendall(b"ICY 200 OK\r\n\r\n")
                if self.need_gga:  # a network (VRS) mount point: nothing before a position
                    self._wait_gga(conn)
            time.sleep(self.delay_s)
            n = len(self.data)
            lo, hi = (int(self.gap[0] * n), int(self.gap[1] * n)) if self.gap else (n, n)
            t0 = time.monotonic()
            k = 0
            try:
                while k < n:
                    if k == lo:
                        k = hi  # the link is silent: those bytes are lost
                        continue
                    part = self.data[k : min(k + 2048, lo if k < lo else n)]
                    if self.rate > 0:
                        delay = t0 + (k + len(part)) / self.rate - time.monotonic()
                        if delay > 0:
                            time.sleep(delay)
                    conn.sendall(part)
                    k += len(part)
            except OSError:
                return
            time.sleep(self.hold_s)  # connected and silent: a stalled link
        self.srv.close()  # one client only: a reconnection is refused

    def _wait_gga(self, conn: socket.socket) -> None:
        """Read the client's lines until a GGA sentence, then keep collecting them."""
        conn.settimeout(30.0)
        buf = b""
        while not self.gga:
            chunk = conn.recv(1024)
            if not chunk:
                return
            buf += chunk
            *lines, buf = buf.split(b"\r\n")
            self.gga += [ln.decode("ascii") for ln in lines if ln.startswith(b"$GPGGA")]
        conn.settimeout(None)

        def collect() -> None:
            rest = buf
            while True:
                try:
                    chunk = conn.recv(1024)
                except OSError:
                    return
                if not chunk:
                    return
                *lines, rest = (rest + chunk).split(b"\r\n")
                self.gga += [ln.decode("ascii") for ln in lines if ln.startswith(b"$GPGGA")]

        threading.Thread(target=collect, daemon=True).start()


def run_args(s1: Path, rover_port: int, base_port: int, out: Path, *extra: str) -> list[str]:
    return [
        "run", "--rover", f"tcp://127.0.0.1:{rover_port}", "--base", f"ntrip://u:p@127.0.0.1:{base_port}/S1",
        "--nav", str(s1 / NAV), "--base-pos", BASE_POS, "--retries", "0", "--time-ref", "2018/10/04 12:00:00",
        "--out", str(out), "--quiet", *SETTINGS, *extra,
    ]  # fmt: skip


Q = {1: "fixed", 2: "float", 4: "dgnss", 5: "single"}


def pos_columns(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Seconds since the first line, status (``fixed`` for Q 1) and age (s) of a .pos file."""
    rows = [ln.split() for ln in solution_lines(path)]
    hms = np.array([[float(v) for v in r[1].split(":")] for r in rows])
    t = hms[:, 0] * 3600 + hms[:, 1] * 60 + hms[:, 2]
    return t - t[0], np.array([Q[int(r[5])] for r in rows]), np.array([float(r[13]) for r in rows])


def solution_lines(path: Path) -> list[str]:
    return [ln for ln in path.read_text().splitlines() if not ln.startswith("%")]


@pytest.mark.slow
def test_run_over_ntrip_and_tcp_writes_the_solve_solution(s1: Path, tmp_path: Path) -> None:
    rover, _ = read_binary_log(s1 / ROVER)
    base, _ = read_binary_log(s1 / BASE)
    # both logs in about 6 s (≈ 200 times real time)
    r_srv = Server(rover, len(rover) / 6.0, ntrip=False)
    b_srv = Server(base, len(base) / 6.0, ntrip=True)
    out_run = tmp_path / "run.pos"
    assert cli_run(run_args(s1, r_srv.port, b_srv.port, out_run, "--base-wait", "1e9")) == 0
    assert "Ntrip" in b_srv.request or "NTRIP" in b_srv.request
    out_solve = tmp_path / "solve.pos"
    solve = [
        "solve",
        str(s1 / ROVER),
        "--base",
        str(s1 / BASE),
        "--nav",
        str(s1 / NAV),
        "--base-pos",
        BASE_POS,
    ]
    assert cli_run([*solve, *SETTINGS, "--out", str(out_solve), "--quiet"]) == 0
    got, want = solution_lines(out_run), solution_lines(out_solve)
    assert len(want) > 1000
    assert len(got) == len(want)
    g_rows = [ln.split() for ln in got]
    w_rows = [ln.split() for ln in want]
    # time, Q, ns, age and ratio as written; the numbers to the last printed digit or one
    # unit of it (the stream builds each epoch alone, the file a block at a time: rounding)
    for cols in ((0, 1, 5, 6, 13, 14),):
        assert [[r[c] for c in cols] for r in g_rows] == [[r[c] for c in cols] for r in w_rows]
    g_num = np.array([[float(r[c]) for c in (2, 3, 4, 7, 8, 9, 10, 11, 12)] for r in g_rows])
    w_num = np.array([[float(r[c]) for c in (2, 3, 4, 7, 8, 9, 10, 11, 12)] for r in w_rows])
    unit = np.array([1e-9, 1e-9, 1e-4] + [1e-4] * 6)
    assert np.all(np.abs(g_num - w_num) <= 1.5 * unit)


@pytest.mark.slow
def test_run_survives_a_base_outage_and_recovers(s1: Path, tmp_path: Path) -> None:
    rover, _ = read_binary_log(s1 / ROVER)
    base, _ = read_binary_log(s1 / BASE)
    speed = 25.0
    rover = rover[: len(rover) // 4]  # the first ≈ 300 s of each
    base = base[: len(base) // 4]
    dur_b = 0.25 * 1260.0  # the base log spans ≈ 1260 s
    # the rover log starts 52 s after the base's: its server too (in replay time)
    r_srv = Server(rover, len(rover) * speed / (0.25 * 1205.0), ntrip=False, delay_s=52.0 / speed)
    # the base silent from 160 s to 200 s of its log (the rover started 52 s into it)
    b_srv = Server(base, len(base) * speed / dur_b, ntrip=True, gap=(160.0 / dur_b, 200.0 / dur_b))
    out = tmp_path / "run.pos"
    assert cli_run(run_args(s1, r_srv.port, b_srv.port, out, "--base-wait", "5", "--max-age-s", "15")) == 0
    t, status, age = pos_columns(out)
    assert t[-1] > 200.0  # the run went on through the outage
    before = t < 90.0
    during = (t > 125.0) & (t < 145.0)
    after = (t > 175.0) & (t < 235.0)  # the base back (and before its log, cut at ≈ 263 s, ends)
    assert np.isin(status[before], ["fixed", "float"]).all()
    assert np.median(age[before]) < 3.0
    # ageing base, then single-point once it is older than max-age
    assert (age[during] > 5.0).any() or (status[during] == "single").any()
    assert (status[during] == "single").any()
    assert (status[after] == "fixed").mean() > 0.5
    assert np.median(age[after]) < 3.0


def test_interrupted_run_leaves_whole_lines(s1: Path, tmp_path: Path) -> None:
    """SIGINT in the middle of a replay: exit status 130, every line of the .pos and the
    NMEA file whole (the .pos readable)."""
    import signal
    import subprocess
    import sys

    out, nmea = tmp_path / "run.pos", tmp_path / "run.nmea"
    cmd = [
        sys.executable, "-m", "robustrtk", "run", "--rover", str(s1 / ROVER), "--base", str(s1 / BASE),
        "--nav", str(s1 / NAV), "--base-pos", BASE_POS, "--speed", "20", "--out", str(out),
        "--nmea", str(nmea), "--quiet", *SETTINGS,
    ]  # fmt: skip
    # the child takes SIGINT even when this process was started ignoring it (a background job)
    proc = subprocess.Popen(
        cmd,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.monotonic() + 120.0
    while time.monotonic() < deadline and (not out.exists() or len(solution_lines(out)) < 20):
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    lines = solution_lines(out)
    assert len(lines) >= 20
    assert all(len(ln.split()) == 15 for ln in lines)
    t, status, _ = pos_columns(out)
    assert np.all(np.diff(t) > 0)
    sentences = nmea.read_bytes().decode("ascii").split("\r\n")
    assert sentences[-1] == ""  # ends on a whole sentence
    assert all(s.startswith(("$GPGGA", "$GPRMC")) and "*" in s for s in sentences[:-1])


def nmea_fields(sentence: str) -> list[str]:
    """The fields of an NMEA sentence whose checksum is right."""
    body, star, ck = sentence.lstrip("$").partition("*")
    assert star and int(ck, 16) == np.bitwise_xor.reduce(np.frombuffer(body.encode(), np.uint8))
    return body.split(",")


def test_run_uploads_the_rover_position_to_a_network_mount_point(s1: Path, tmp_path: Path) -> None:
    """A VRS-style mount point sends nothing before it has the rover's position: the run
    uploads a GGA of its first solution (no --base-pos: the rover's single-point one), then
    one every --gga-interval-s, each the latest solution written."""
    rover, _ = read_binary_log(s1 / ROVER)
    base, _ = read_binary_log(s1 / BASE)
    rover = rover[: len(rover) // 8]  # ≈ 150 epochs in ≈ 4 s
    r_srv = Server(rover, len(rover) / 4.0, ntrip=False)
    b_srv = Server(base[: len(base) // 4], len(base) / 8.0, ntrip=True, need_gga=True)
    out = tmp_path / "run.pos"
    args = run_args(s1, r_srv.port, b_srv.port, out, "--gga-interval-s", "1")
    args.remove("--base-pos")
    args.remove(BASE_POS)
    assert cli_run(args) == 0
    rows = [ln.split() for ln in solution_lines(out)]
    assert len(rows) > 100
    # the base served once it had a position: RTK solutions after its 1005 message
    _, status, _ = pos_columns(out)
    assert status[0] == "single" and np.isin(status, ["fixed", "float"]).any()
    assert len(b_srv.gga) >= 3
    sols = np.array([[float(r[2]), float(r[3]), float(r[4])] for r in rows])
    for sentence in b_srv.gga:
        f = nmea_fields(sentence)
        assert f[0] == "GPGGA" and f[6] == "1"
        lat = (int(f[2][:2]) + float(f[2][2:]) / 60.0) * (1 if f[3] == "N" else -1)
        lon = (int(f[4][:3]) + float(f[4][3:]) / 60.0) * (1 if f[5] == "E" else -1)
        # one of the solutions written, to the GGA's rounding (1e-5 minute ≈ 2 cm)
        d = np.abs(sols - [lat, lon, float(f[9])])
        assert np.any((d[:, 0] < 2e-7) & (d[:, 1] < 2e-7) & (d[:, 2] < 1e-3)), sentence


def test_a_stalled_run_stops_with_whole_outputs(
    s1: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Both streams send the start of their logs and then nothing while their connections
    stay open: the run stops after --stall-timeout-s with one line and exit status 4, the
    .pos holding every epoch received."""
    rover, _ = read_binary_log(s1 / ROVER)
    base, _ = read_binary_log(s1 / BASE)
    r_srv = Server(rover[: len(rover) // 10], 0.0, ntrip=False, hold_s=60.0)
    b_srv = Server(base[: len(base) // 5], 0.0, ntrip=True, hold_s=60.0)
    out = tmp_path / "run.pos"
    args = run_args(s1, r_srv.port, b_srv.port, out, "--stall-timeout-s", "2")
    assert cli_run(args) == 4
    err = capsys.readouterr().err
    stall = [ln for ln in err.splitlines() if "stalled" in ln]
    assert len(stall) == 1 and "no data for 2 s" in stall[0]
    assert "rover tcp://127.0.0.1" in stall[0] and "base ntrip://u@127.0.0.1" in stall[0]
    lines = solution_lines(out)
    assert all(len(ln.split()) == 15 for ln in lines)
    t, status, _ = pos_columns(out)
    assert len(t) > 100 and np.all(np.diff(t) > 0)
    assert np.isin(status, ["fixed", "float"]).any()  # the base's epochs were used


def test_stall_message_names_the_timeout_not_the_polling_delay() -> None:
    """The stall line states the configured silence whatever the delay before it was noticed
    (a loaded machine notices late); never before the timeout, never for a file replay."""
    from types import SimpleNamespace

    from robustrtk.cli.run import stall_message

    sources = {
        "rover": SimpleNamespace(kind="tcp", label="tcp://h:1"),
        "base": SimpleNamespace(kind="ntrip", label="ntrip://h:2/M"),
    }
    now = time.monotonic()
    for silent in (2.0, 2.6, 3.4, 30.0):
        msg = stall_message(
            sources, {"rover", "base"}, {"rover": now - silent - 5, "base": now - silent}, 2.0
        )
        expected = "run: stalled: no data for 2 s from base ntrip://h:2/M, rover tcp://h:1; "
        assert msg == expected + "stopped (outputs complete)"
    assert stall_message(sources, {"rover", "base"}, {"rover": now - 9, "base": now - 1.5}, 2.0) is None
    assert stall_message(sources, {"rover", "base"}, {"rover": now - 9, "base": now - 9}, 0.0) is None
    files = {"rover": SimpleNamespace(kind="file", label="r.ubx")}
    assert stall_message(files, {"rover"}, {"rover": now - 99}, 2.0) is None
