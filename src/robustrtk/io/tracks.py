"""Track files for map viewers: KML (Google Earth) and GPX, coloured by solution status.

Both writers take ECEF (GNSS) solutions, as a :class:`~robustrtk.io.solution.SolutionTable`
or a sequence of :class:`~robustrtk.core.Solution`, and write atomically. Epochs with status
``"none"`` or a non-finite position are left out; positions not near the Earth's surface
(a local pseudolite frame) raise :class:`~robustrtk.core.InputError`.

The track is cut into *runs*: consecutive epochs of the same status. Colours follow
RTKLIB's rtkplot: fixed green, float orange, DGNSS blue, single red.

* KML: one ``Style`` per status, one ``LineString`` placemark per run (in its status
  colour) and one point placemark per epoch (time, status, ``ns``) in a folder.
* GPX 1.1: one ``trk`` per run, its ``type`` the status and a Garmin ``DisplayColor``
  extension (the colour names GPX viewers know), with a ``trkpt`` (UTC time, ellipsoidal
  height) per epoch. GPX has no status field of its own; ``trkpt/fix`` carries
  ``dgps`` for differential solutions and ``3d`` for single ones.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from xml.sax.saxutils import escape

import numpy as np

from robustrtk.core import FloatArray, InputError, Solution
from robustrtk.geometry.frames import ecef2geodetic_deg
from robustrtk.io.solution_table import (
    PathLike,
    SolutionTable,
    open_atomic_text,
    require_ecef,
    writable_solutions,
)
from robustrtk.timeutil import calendar_from_gpst, gpst2utc

__all__ = ["STATUS_COLORS", "status_runs", "track_points", "write_gpx", "write_kml"]

#: Display colour of each status: (RGB hex, GPX/Garmin colour name).
STATUS_COLORS: dict[str, tuple[str, str]] = {
    "fixed": ("00a000", "Green"),
    "partial": ("00a000", "Green"),
    "float": ("ff8c00", "Yellow"),
    "dgnss": ("1e64ff", "Blue"),
    "code": ("1e64ff", "Blue"),
    "single": ("e00000", "Red"),
}
_GPX_FIX = {
    "fixed": "dgps",
    "partial": "dgps",
    "float": "dgps",
    "dgnss": "dgps",
    "code": "dgps",
    "single": "3d",
}


def _table(track: SolutionTable | Iterable[Solution]) -> SolutionTable:
    if isinstance(track, SolutionTable):
        return track
    return SolutionTable.from_solutions(writable_solutions(track))


def track_points(
    track: SolutionTable | Iterable[Solution], path: PathLike | None = None, pos_frame: str = "ecef"
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, list[str], np.ndarray]:
    """The writable epochs of ``track`` in time order, as geodetic coordinates.

    Returns
    -------
    t_s, lat_deg, lon_deg, h_m : ndarray, shape (T,)
    status : list of str
    n_used : ndarray of int, shape (T,)

    Raises
    ------
    InputError
        A local ``pos_frame`` (the frame the solver reports; positions are not judged by
        their magnitude), or an unknown status.
    """
    require_ecef(pos_frame, "a map track", path)
    table = _table(track)
    ok = (table.status != "none") & np.all(np.isfinite(table.pos_m), axis=1)
    order = np.argsort(table.t_s[ok], kind="stable")
    pos = table.pos_m[ok][order]
    status = [str(s) for s in table.status[ok][order]]
    for s in set(status):
        if s not in STATUS_COLORS:
            raise InputError(f"unknown solution status {s!r}", None if path is None else str(path))
    if pos.shape[0]:
        lat, lon, h = ecef2geodetic_deg(pos)
    else:
        lat = lon = h = np.zeros(0)
    return (table.t_s[ok][order], np.atleast_1d(lat), np.atleast_1d(lon), np.atleast_1d(h), status,
            table.n_used[ok][order])  # fmt: skip


def status_runs(status: list[str]) -> list[tuple[int, int]]:
    """Half-open index ranges ``(start, stop)`` of consecutive equal statuses.

    Each run after the first also starts with the last epoch of the run before, so that
    the drawn line has no gaps (``status[start]`` may then differ from the run's status,
    which is ``status[stop - 1]``).
    """
    runs: list[tuple[int, int]] = []
    i = 0
    while i < len(status):
        j = i + 1
        while j < len(status) and status[j] == status[i]:
            j += 1
        runs.append((max(i - 1, 0), j))
        i = j
    return runs


def _utc_text(t_s: float) -> str:
    y, mo, d, h, mi, s = calendar_from_gpst(float(gpst2utc(t_s)))
    return f"{y:04d}-{mo:02d}-{d:02d}T{h:02d}:{mi:02d}:{s:06.3f}Z"


def _kml_color(rgb: str, alpha: str = "ff") -> str:
    """KML colours are ``aabbggrr``."""
    return alpha + rgb[4:6] + rgb[2:4] + rgb[0:2]


def write_kml(
    track: SolutionTable | Iterable[Solution],
    path: PathLike,
    *,
    name: str = "robustrtk track",
    pos_frame: str = "ecef",
) -> None:
    """Write a KML 2.2 track coloured by status (see the module docstring).

    Parameters
    ----------
    track : SolutionTable or iterable of Solution
        ECEF (GNSS) solutions.
    path : path-like
    name : str
        Document name shown by the viewer.
    pos_frame : {"ecef", "local"}
        The frame of the positions, as their producer states it; ``local`` is refused.
    """
    t, lat, lon, h, status, ns = track_points(track, path, pos_frame)
    with open_atomic_text(path) as fh:
        fh.write('<?xml version="1.0" encoding="UTF-8"?>\n')
        fh.write('<kml xmlns="http://www.opengis.net/kml/2.2">\n<Document>\n')
        fh.write(f"<name>{escape(name)}</name>\n")
        for st, (rgb, _) in STATUS_COLORS.items():
            fh.write(
                f'<Style id="{st}"><LineStyle><color>{_kml_color(rgb)}</color><width>3</width></LineStyle>'
                f"<IconStyle><color>{_kml_color(rgb)}</color><scale>0.4</scale><Icon><href>"
                "http://maps.google.com/mapfiles/kml/shapes/shaded_dot.png</href></Icon></IconStyle>"
                "<LabelStyle><scale>0</scale></LabelStyle></Style>\n"
            )
        fh.write("<Folder><name>track</name>\n")
        for start, stop in status_runs(status):
            st = status[stop - 1]
            coords = " ".join(f"{lon[i]:.9f},{lat[i]:.9f},{h[i]:.4f}" for i in range(start, stop))
            fh.write(
                f"<Placemark><name>{st} {_utc_text(t[start])}</name><styleUrl>#{st}</styleUrl>"
                f"<LineString><altitudeMode>absolute</altitudeMode><coordinates>{coords}</coordinates>"
                "</LineString></Placemark>\n"
            )
        fh.write("</Folder>\n<Folder><name>epochs</name>\n")
        for i in range(t.shape[0]):
            fh.write(
                f"<Placemark><TimeStamp><when>{_utc_text(t[i])}</when></TimeStamp>"
                f"<styleUrl>#{status[i]}</styleUrl><description>{status[i]}, ns {int(ns[i])}"
                f"</description><Point><altitudeMode>absolute</altitudeMode><coordinates>"
                f"{lon[i]:.9f},{lat[i]:.9f},{h[i]:.4f}</coordinates></Point></Placemark>\n"
            )
        fh.write("</Folder>\n</Document>\n</kml>\n")


def write_gpx(
    track: SolutionTable | Iterable[Solution],
    path: PathLike,
    *,
    name: str = "robustrtk track",
    pos_frame: str = "ecef",
) -> None:
    """Write a GPX 1.1 track, one ``trk`` per run of equal status (see the module docstring).

    Parameters as :func:`write_kml`, except ``name``: the prefix of the track names.
    """
    t, lat, lon, h, status, ns = track_points(track, path, pos_frame)
    with open_atomic_text(path) as fh:
        fh.write('<?xml version="1.0" encoding="UTF-8"?>\n')
        fh.write(
            '<gpx version="1.1" creator="robustrtk" xmlns="http://www.topografix.com/GPX/1/1" '
            'xmlns:gpxx="http://www.garmin.com/xmlschemas/GpxExtensions/v3">\n'
        )
        if t.shape[0]:
            fh.write(f"<metadata><name>{escape(name)}</name><time>{_utc_text(t[0])}</time></metadata>\n")
        for start, stop in status_runs(status):
            st = status[stop - 1]
            fh.write(
                f"<trk><name>{escape(name)}: {st} from {_utc_text(t[start])}</name><type>{st}</type>"
                f"<extensions><gpxx:TrackExtension><gpxx:DisplayColor>{STATUS_COLORS[st][1]}"
                "</gpxx:DisplayColor></gpxx:TrackExtension></extensions>\n<trkseg>\n"
            )
            for i in range(start, stop):
                ele = f"<ele>{h[i]:.4f}</ele>" if math.isfinite(h[i]) else ""
                fh.write(
                    f'<trkpt lat="{lat[i]:.9f}" lon="{lon[i]:.9f}">{ele}<time>{_utc_text(t[i])}</time>'
                    f"<fix>{_GPX_FIX[status[i]]}</fix></trkpt>\n"
                )
            fh.write("</trkseg>\n</trk>\n")
        fh.write("</gpx>\n")
