"""``robustrtk run``: real-time SPP, DGNSS or RTK from streams (docs/realtime.md).

Each SOURCE (a file replayed at ``--speed``, ``tcp://host:port``,
``ntrip://user:pass@host:port/MOUNT`` or ``serial://DEVICE?baud=N``) is read by its own
thread and decoded as it arrives (:class:`robustrtk.io.epoch_source.StreamDecoder`, UBX or
RTCM 3 picked by content); the main thread hands the epochs and ephemerides to
:class:`robustrtk.pipeline.stream.StreamSolver` (DGNSS, RTK: a rover and a base) or
:class:`robustrtk.pipeline.spp_kalman_stream.SppStreamSolver` (SPP: the rover alone, the
Kalman SPP of ``solve --mode spp --kalman``) and writes each solution as it comes: a
``.pos`` line (flushed), NMEA GGA and RMC to a file and/or TCP clients, and a one-line live
status. Every line is written whole, so an interrupted run (Ctrl-C, SIGTERM) or one stopped
by ``--stall-timeout-s`` leaves valid files. NTRIP sources get the rover's position as GGA.
"""

from __future__ import annotations

import queue
import sys
import threading
import time
from collections.abc import Callable
from typing import IO, Any

import click

from robustrtk.cli.errors import one_line_errors
from robustrtk.cli.main import ConfigCommand
from robustrtk.errors import InputError

#: Exit status of a run stopped because every stream went silent (``--stall-timeout-s``).
EXIT_STALLED = 4

#: How long (wall s) the main thread waits for an event before looking at its sources again.
POLL_S = 0.2


class ReplayClock:
    """The shared clock of replayed files: an epoch tagged ``t`` is released at
    ``wall₀ + (t − t₀) / speed`` (``t₀`` the first tag any file released)."""

    def __init__(self, speed: float) -> None:
        self.speed = speed
        self.lock = threading.Lock()
        self.t0: float | None = None
        self.wall0 = 0.0

    def wait(self, t_s: float, stop: threading.Event) -> None:
        if self.speed <= 0:
            return
        with self.lock:
            if self.t0 is None:
                self.t0, self.wall0 = t_s, time.monotonic()
            due = self.wall0 + (t_s - self.t0) / self.speed
        delay = due - time.monotonic()
        if delay > 0:
            stop.wait(delay)


class RoverPosition:
    """The rover's position for an NTRIP caster's network (VRS) mount point: the latest
    solution, before the first one the approximate position given (the base's), else none.

    :meth:`gga` is called from the base's reader thread; :meth:`update` from the main
    thread (one attribute assigned whole: no lock needed)."""

    def __init__(self, approx_ecef_m: Any = None) -> None:
        import numpy as np

        self.fix: tuple[Any, int] | None = None
        if approx_ecef_m is not None:
            self.fix = (np.asarray(approx_ecef_m, float).reshape(3), 0)

    def update(self, sol: Any) -> None:
        import numpy as np

        pos = np.asarray(sol.pos_m, float).reshape(3)
        if sol.status != "none" and np.all(np.isfinite(pos)):
            self.fix = (pos, int(sol.n_used))

    def gga(self) -> str | None:
        """A ``$GPGGA`` sentence (``\\r\\n``-terminated) at the current UTC time, or None."""
        import math

        from robustrtk.geometry.frames import ecef2geodetic
        from robustrtk.io.ntrip import gga_sentence

        fix = self.fix
        if fix is None:
            return None
        lat, lon, h = (float(v) for v in ecef2geodetic(fix[0]))
        # Unix time modulo a day is the UTC time of day
        return gga_sentence(math.degrees(lat), math.degrees(lon), h, time.time(), fix[1] or 10)


def reader(
    role: str,
    spec: Any,
    t_ref_s: float | None,
    clock: ReplayClock,
    out: queue.Queue[Any],
    stop: threading.Event,
    retries: int = 5,
    last_bytes: dict[str, float] | None = None,
    gga: Callable[[], str | None] | None = None,
    gga_interval_s: float = 10.0,
    gga_from_table: bool = False,
    glo_channels: dict[str, int] | None = None,
    beidou_gpst: bool = False,
) -> None:
    """Decode one source into ``out``: ``(role, event, station)`` items (the RTCM 3 station
    data and the ``receiver_type``), then
    ``(role, None, error)`` at its end. ``last_bytes[role]``: the wall time (monotonic s)
    of the latest bytes received; ``gga``: the rover position uploaded to an NTRIP caster
    (with ``gga_from_table``: only to a mount point its source table says wants it);
    ``glo_channels``: the GLONASS channels the sources share (:class:`StreamDecoder`);
    ``beidou_gpst``: an RTCM 3 source's BeiDou MSM epochs are tagged in GPS time."""
    from robustrtk.core import ObsEpoch
    from robustrtk.io.epoch_source import StreamDecoder
    from robustrtk.io.streams import open_bytes

    error = None
    try:
        dec = StreamDecoder(t_ref_s=t_ref_s, glo_channels=glo_channels, beidou_gpst=beidou_gpst)
        chunks = open_bytes(
            spec,
            stop,
            max_retries=retries,
            gga=gga,
            gga_interval_s=gga_interval_s,
            gga_from_table=gga_from_table,
        )
        for data in chunks:
            if last_bytes is not None:
                last_bytes[role] = time.monotonic()
            for ev in dec.feed(data):
                if spec.kind == "file" and isinstance(ev, ObsEpoch):
                    clock.wait(ev.t_s, stop)
                out.put((role, ev, {**dec.station, "receiver_type": dec.receiver_type}))
            if stop.is_set():
                break
        for ev in dec.close():
            out.put((role, ev, {**dec.station, "receiver_type": dec.receiver_type}))
        if dec.fmt is None and not stop.is_set():
            error = f"{spec.label}: no UBX or RTCM 3 frame in what it sent"
    except InputError as exc:
        error = str(exc)
    except Exception as exc:  # a source must never take the run down with a traceback
        error = f"{spec.label}: {type(exc).__name__}: {exc}"
    out.put((role, None, error))


def rtcm_time_ref(spec: Any, time_ref: str | None) -> float | None:
    """The approximate GPST of an RTCM 3 source: ``--time-ref``, else a file's own
    (:func:`robustrtk.io.rtcm3.reference_time_s`), else the computer's clock."""
    from robustrtk.timeutil import parse_gpst_instant

    if time_ref is not None:
        return parse_gpst_instant(time_ref, 0.0, "--time-ref")
    if spec.kind == "file":
        from robustrtk.io.raw_file import read_binary_log
        from robustrtk.io.rtcm3 import reference_time_s

        data, _ = read_binary_log(spec.path)
        t = reference_time_s(spec.path, data)
        if t is not None:
            return t
    from robustrtk.timeutil import utc2gpst

    return float(utc2gpst(time.time() - 315_964_800.0))


#: What a file that is not a receiver's byte stream holds, for the one-line refusal.
_FILE_KINDS = {
    "rinex_obs": "a RINEX observation file",
    "rinex_nav": "a RINEX navigation file (give it as --nav)",
    "obs_table_parquet": "a pseudolite observation table",
    "obs_table_csv": "a pseudolite observation table",
    "site_toml": "a pseudolite site file",
    "gnsslogger": "an Android GnssLogger log",
    "gsdc_device_gnss": "a GSDC device_gnss.csv",
}


def refuse_non_stream_file(path: str, flag: str) -> None:
    """Refuse, in one line, a file ``run`` would read as bytes of nothing: one whose content
    is recognised as another format (RINEX, phone logs, tables). Content recognised as
    nothing is left to the stream decoder (a log may open with bytes it skips)."""
    from robustrtk.io.readers import detect_format

    try:
        name = detect_format(path)
    except InputError:
        return
    if name in _FILE_KINDS:
        raise InputError(
            f"{flag}: {_FILE_KINDS[name]}, not a receiver's UBX or RTCM 3 bytes; run replays "
            "those (`robustrtk solve` reads this file)",
            path,
        )


class Outputs:
    """The ``.pos`` file, NMEA file and NMEA server of a run; each solution written whole."""

    def __init__(self, out: str | None, nmea: tuple[str, ...], header: list[str]) -> None:
        from robustrtk.io.solution_pos import pos_column_header
        from robustrtk.io.streams import NmeaServer

        self.pos: IO[str] | None = None
        self.nmea_files: list[IO[str]] = []
        self.servers: list[NmeaServer] = []
        if out is not None:
            self.pos = open(out, "w", encoding="utf-8")  # noqa: SIM115 - closed in close()
            self.pos.write("".join(f"{h}\n" for h in header) + "\n".join(pos_column_header()) + "\n")
            self.pos.flush()
        for target in nmea:
            if target.startswith("tcp://"):
                host, _, port = target[6:].rpartition(":")
                if not port.isdigit():
                    raise InputError(f"--nmea: expected tcp://[host]:PORT or a file, got {target!r}")
                self.servers.append(NmeaServer(host, int(port)))
            else:
                self.nmea_files.append(open(target, "w", encoding="ascii", newline=""))  # noqa: SIM115

    def write(self, sol: Any) -> None:
        from robustrtk.io.solution_nmea import gga_sentence
        from robustrtk.io.solution_pos import pos_lines
        from robustrtk.io.streams import rmc_sentence

        if sol.status == "none":
            return
        if self.pos is not None:
            self.pos.write("".join(pos_lines([sol])))
            self.pos.flush()
        if self.nmea_files or self.servers:
            text = (
                gga_sentence(sol.t_s, sol.pos_m, sol.status, sol.n_used, sol.age_s) + "\r\n"
                + rmc_sentence(sol.t_s, sol.pos_m, sol.vel_m_s, True, sol.status) + "\r\n"
            )  # fmt: skip
            for fh in self.nmea_files:
                fh.write(text)
                fh.flush()
            for srv in self.servers:
                srv.send(text)

    def close(self) -> None:
        for fh in [*([self.pos] if self.pos else []), *self.nmea_files]:
            fh.close()
        for srv in self.servers:
            srv.close()


def status_line(st: Any, counts: dict[str, int]) -> str:
    """The live status: time, solution type, satellites, age, ratio, epochs by type."""
    from robustrtk.timeutil import gpst_text

    tally = " ".join(f"{k} {v}" for k, v in sorted(counts.items()))
    return (
        f"{gpst_text(st.t_s)}  {st.status:7s} sats {st.n_used:2d}  age {st.age_s:5.1f} s  "
        f"ratio {st.ratio:5.1f}  | {tally}"
    )


def solve_stream(
    solver: Any,
    sources: dict[str, Any],
    t_refs: dict[str, float | None],
    speed: float,
    outputs: Outputs,
    show: Callable[[str], None] | None,
    base_pos_given: bool,
    retries: int = 5,
    *,
    rover_pos: RoverPosition | None = None,
    gga_interval_s: float = 10.0,
    gga_from_table: bool = False,
    stall_timeout_s: float = 0.0,
    glo_channels: dict[str, int] | None = None,
    beidou_gpst: bool = False,
) -> tuple[dict[str, int], str | None]:
    """Run the readers and the solver until the rover's source ends, or until no stream
    has sent a byte for ``stall_timeout_s`` wall seconds (0: never; a file still being
    replayed is never stalled). Returns the count of solutions by type and the stall
    message (None: the rover's source ended). ``rover_pos`` follows the solutions and
    gives NTRIP sources their GGA sentence every ``gga_interval_s`` (with ``gga_from_table``:
    those whose source-table entry asks for it); ``glo_channels`` (GLONASS frequency channels,
    e.g. a navigation file's) is shared by the sources' decoders, each adding what its stream
    tells (an RTCM 3 MSM4 phase needs the channel to be in cycles); ``beidou_gpst``: the RTCM 3
    sources tag their BeiDou MSM epochs in GPS time (an encoder's defect; BDT is the standard)."""
    from robustrtk.core import ObsEpoch

    events: queue.Queue[Any] = queue.Queue(maxsize=10_000)
    stop = threading.Event()
    clock = ReplayClock(speed)
    t_start = time.monotonic()
    last_bytes = dict.fromkeys(sources, t_start)
    gga = rover_pos.gga if rover_pos is not None else None
    channels = {} if glo_channels is None else glo_channels
    threads = [
        threading.Thread(
            target=reader,
            args=(
                r,
                s,
                t_refs[r],
                clock,
                events,
                stop,
                retries,
                last_bytes,
                gga,
                gga_interval_s,
                gga_from_table,
                channels,
                beidou_gpst,
            ),
            daemon=True,
            name=r,
        )
        for r, s in sources.items()
    ]
    for th in threads:
        th.start()
    counts: dict[str, int] = {}
    errors: list[str] = []
    stalled: str | None = None

    def emit(sols: list[Any]) -> None:
        for sol in sols:
            outputs.write(sol)
            if rover_pos is not None:
                rover_pos.update(sol)
            counts[sol.status] = counts.get(sol.status, 0) + 1
        if show is not None and solver.last is not None and sols:
            show(status_line(solver.last, counts))

    try:
        running = set(sources)
        while "rover" in running:
            try:
                role, ev, extra = events.get(timeout=POLL_S)
            except queue.Empty:
                stalled = stall_message(sources, running, last_bytes, stall_timeout_s)
                if stalled is not None:
                    break
                continue
            if ev is None:
                running.discard(role)
                if extra:
                    errors.append(f"{role}: {extra}")
                if role == "base":
                    emit(solver.end_base())
                continue
            if isinstance(ev, ObsEpoch):
                if role in ("rover", "base") and extra.get("receiver_type"):
                    solver.set_receiver_type(role, extra["receiver_type"])
                if role == "base":
                    if not base_pos_given and extra.get("arp_ecef_m") is not None:
                        solver.set_base_position(extra["arp_ecef_m"])
                    emit(solver.on_base(ev))
                elif role == "rover":
                    emit(solver.on_rover(ev))
            else:
                solver.on_nav(ev)
        emit(solver.flush())
    finally:
        stop.set()
    rover_error = next((e for e in errors if e.startswith("rover: ")), None)
    if rover_error is not None and not counts:  # nothing solved: the run failed, say why
        raise InputError(f"--{rover_error}")
    for e in errors:
        click.echo(f"warning: {e}", err=True)
    return counts, stalled


def stall_message(
    sources: dict[str, Any], running: set[str], last_bytes: dict[str, float], timeout_s: float
) -> str | None:
    """The one line saying that every running stream has been silent ``timeout_s`` wall
    seconds, or None (not stalled, ``timeout_s`` 0, or a file still being replayed: it
    waits for its replay time, it is not silent)."""
    if timeout_s <= 0 or not running or any(sources[r].kind == "file" for r in running):
        return None
    silent = time.monotonic() - max(last_bytes[r] for r in running)
    if silent < timeout_s:
        return None
    names = ", ".join(f"{r} {sources[r].label}" for r in sorted(running))
    return f"run: stalled: no data for {timeout_s:g} s from {names}; stopped (outputs complete)"


@click.command(cls=ConfigCommand, mode_help="spp, dgnss or rtk; default rtk.")
@click.option(
    "--rover",
    "rover_src",
    required=True,
    help="Rover SOURCE: a file (replayed), tcp://host:port (tcp://:port: listen), ntrip://... or "
    "serial://DEVICE?baud=N",
)
@click.option("--base", "base_src", default=None, help="Base SOURCE (RTCM 3 or UBX; dgnss, rtk).")
@click.option("--nav", multiple=True, help="Navigation: RINEX file(s), or a SOURCE with ephemerides.")
@click.option("--out", default=None, type=click.Path(dir_okay=False), help=".pos file, a line per epoch.")
@click.option("--nmea", multiple=True, help="NMEA GGA+RMC to tcp://[host]:PORT (served) and/or a file.")
@click.option(
    "--speed", type=float, default=1.0, show_default=True, help="File replay speed (0: as fast as possible)."
)
@click.option(
    "--base-pos",
    default=None,
    help="Base ECEF X,Y,Z (m), or spp (its own single-point solution); default the RTCM 1005/1006 "
    "position (single-point rover solutions until it arrives).",
)
@click.option("--time-ref", default=None, help="RTCM 3: approximate time 'YYYY/MM/DD HH:MM:SS' (GPST).")
@click.option(
    "--beidou-time",
    type=click.Choice(["bdt", "gpst"]),
    default=None,
    help="RTCM 3: the time scale of the BeiDou MSM epochs [bdt, the standard; gpst for encoders "
    "that write GPS time there].",
)
@click.option(
    "--base-wait", type=float, default=None, help="Rover seconds to wait for a base epoch [3; dgnss, rtk]."
)
@click.option("--config", type=click.Path(), help="TOML config over the mode's preset; flags override it.")
@click.option("--rtklib-conf", type=click.Path(), default=None, help="RTKLIB .conf under --config and flags.")
@click.option(
    "--retries",
    type=int,
    default=5,
    show_default=True,
    help="Reconnections in a row before a stream is given up.",
)
@click.option(
    "--gga-interval-s",
    type=click.FloatRange(min=0.0),
    default=None,
    help="NTRIP: send the rover's position (GGA) after connecting and then every this many s "
    "(0: never) to every mount point [10 s, to the mount points whose source-table entry "
    "asks for NMEA].",
)
@click.option(
    "--stall-timeout-s",
    type=click.FloatRange(min=0.0),
    default=60.0,
    show_default=True,
    help=f"Stop (exit status {EXIT_STALLED}) when no stream has sent anything this many s (0: never).",
)
@click.option("--quiet", is_flag=True, help="No live status line.")
@one_line_errors
def run(
    rover_src: str,
    base_src: str | None,
    nav: tuple[str, ...],
    out: str | None,
    nmea: tuple[str, ...],
    speed: float,
    base_pos: str | None,
    time_ref: str | None,
    beidou_time: str | None,
    base_wait: float | None,
    retries: int,
    gga_interval_s: float | None,
    stall_timeout_s: float,
    config: str | None,
    rtklib_conf: str | None,
    quiet: bool,
    **settings: Any,
) -> None:
    """Solve in real time: DGNSS or RTK (--mode, default rtk) from a rover and a base SOURCE,
    or SPP (the Kalman SPP: code, Doppler, carrier phase) from the rover alone.

    Appends each solution to --out as it is solved and serves NMEA; a lost base ages out
    (float, DGNSS), then single-point, and is used again when it returns.
    """
    import os

    from robustrtk.cli.gnss import parse_xyz
    from robustrtk.cli.settings import resolve_config
    from robustrtk.io.solution_pos import pos_header
    from robustrtk.io.streams import parse_source
    from robustrtk.pipeline.gnss import nav_source
    from robustrtk.pipeline.spp_kalman_stream import SppStreamSolver, stream_config_error
    from robustrtk.pipeline.stream import StreamSolver

    flags = {k: v for k, v in settings.items() if v is not None}
    mode = flags.pop("mode", None) or "rtk"
    if mode == "spp":  # the Kalman SPP, as solve --kalman
        if flags.get("filter", "ekf") not in ("ekf", "ukf"):
            got = flags["filter"]
            raise InputError(f"--filter: run --mode spp is the Kalman SPP (ekf or ukf), got {got}")
        flags.setdefault("filter", "ekf")
    cfg = resolve_config(mode, "gnss", config, flags, rtklib_conf=rtklib_conf)
    if cfg.mode not in ("spp", "dgnss", "rtk"):
        raise InputError(f"--mode: run solves spp, dgnss or rtk, got {cfg.mode!r}")
    if cfg.mode == "spp":
        why = stream_config_error(cfg)
        if why is not None:
            raise InputError(why)
        given = {"--base": base_src, "--base-pos": base_pos, "--base-wait": base_wait}
        for flag, value in given.items():
            if value is not None:
                raise InputError(f"{flag}: does not apply in mode spp (the rover alone)")
    elif base_src is None:
        raise InputError(f"--base: {cfg.mode.upper()} needs a base SOURCE")
    if out is None and not nmea:
        raise InputError("--out or --nmea: nowhere to write the solutions")
    sources = {"rover": parse_source(rover_src, "--rover")}
    if base_src is not None:
        sources["base"] = parse_source(base_src, "--base")
    for role, spec in sources.items():
        if spec.kind == "file":
            refuse_non_stream_file(spec.path, f"--{role}")
    fixed_nav = None
    nav_files = [n for n in nav if "://" not in n]
    if nav_files:
        for n in nav_files:
            if not os.path.isfile(n):
                raise InputError("--nav: no such file", n)
        fixed_nav = nav_source(nav_files)
    streams = [n for n in nav if "://" in n]
    if len(streams) > 1:
        raise InputError("--nav: at most one navigation stream")
    if streams:
        sources["nav"] = parse_source(streams[0], "--nav")
    t_refs = {r: rtcm_time_ref(s, time_ref) for r, s in sources.items()}
    pos = parse_xyz(base_pos) if base_pos is not None else None
    wait_s = 3.0 if base_wait is None else base_wait
    # files replayed at once: the rover waits for the base file whatever the threads' pace
    if speed <= 0 and "base" in sources and sources["base"].kind == "file":
        wait_s = float("inf")
    solver: StreamSolver | SppStreamSolver
    if cfg.mode == "spp":
        solver = SppStreamSolver(cfg, fixed_nav)
    else:
        solver = StreamSolver(cfg, pos, fixed_nav, wait_s=wait_s)
    header = pos_header([s.label for s in sources.values()] + nav_files, pos)
    outputs = Outputs(out, nmea, header)
    show: Callable[[str], None] | None = None
    live = None
    if not quiet:
        from rich.console import Console
        from rich.live import Live

        live = Live("", console=Console(stderr=True), auto_refresh=False, transient=False)
        live.start()

        def show(text: str) -> None:
            assert live is not None
            live.update(text, refresh=True)

    try:
        counts, stalled = solve_stream(
            solver, sources, t_refs, speed, outputs, show, base_pos is not None, retries,
            rover_pos=RoverPosition(pos), gga_interval_s=10.0 if gga_interval_s is None else gga_interval_s,
            gga_from_table=gga_interval_s is None, stall_timeout_s=stall_timeout_s,
            glo_channels=dict(fixed_nav.nav.glo_channels()) if fixed_nav is not None else None,
            beidou_gpst=beidou_time == "gpst",
        )  # fmt: skip
    finally:
        outputs.close()
        if live is not None:
            live.stop()
    if not quiet:
        total = sum(counts.values())
        click.echo(
            f"run: {total} epochs solved ({', '.join(f'{k} {v}' for k, v in sorted(counts.items()))})",
            err=True,
        )
    if stalled is not None:
        click.echo(stalled, err=True)
        sys.exit(EXIT_STALLED)


__all__ = [
    "EXIT_STALLED",
    "Outputs",
    "ReplayClock",
    "RoverPosition",
    "refuse_non_stream_file",
    "rtcm_time_ref",
    "run",
    "solve_stream",
    "stall_message",
    "status_line",
]
