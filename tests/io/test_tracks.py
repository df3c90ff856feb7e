"""KML and GPX track writers: valid XML, one coloured run per status change, every epoch."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError, Solution
from robustrtk.geometry.frames import ecef2geodetic_deg, geodetic2ecef_deg
from robustrtk.io.tracks import STATUS_COLORS, status_runs, write_gpx, write_kml

KML = "{http://www.opengis.net/kml/2.2}"
GPX = "{http://www.topografix.com/GPX/1/1}"
GPXX = "{http://www.garmin.com/xmlschemas/GpxExtensions/v3}"
T0 = 1316327400.0  # 2021-09-22 06:30:00 GPST


def _solutions() -> list[Solution]:
    base = geodetic2ecef_deg(35.342, 139.522, 47.5)
    status = ["single", "float", "float", "fixed", "fixed", "fixed", "none", "float", "fixed", "fixed"]
    out = []
    for k, st in enumerate(status):
        pos = base + np.array([k * 1.0, k * 0.5, 0.0])
        out.append(Solution(t_s=T0 + k, pos_m=pos, cov_m2=np.eye(3) * 1e-4, status=st, n_used=8))
    return out


def test_status_runs_overlap_by_one_epoch() -> None:
    assert status_runs(["a", "a", "b", "c", "c"]) == [(0, 2), (1, 3), (2, 5)]
    assert status_runs([]) == []


def test_kml_is_valid_and_coloured(tmp_path: Path) -> None:
    out = tmp_path / "track.kml"
    write_kml(_solutions(), out, name="test & track")
    root = ET.parse(out).getroot()
    doc = root.find(f"{KML}Document")
    assert doc is not None and doc.findtext(f"{KML}name") == "test & track"
    styles = {s.get("id"): s for s in doc.findall(f"{KML}Style")}
    assert set(STATUS_COLORS) <= set(styles)
    # KML colour aabbggrr of fixed green 00a000
    assert styles["fixed"].findtext(f"{KML}LineStyle/{KML}color") == "ff00a000"
    folders = doc.findall(f"{KML}Folder")
    lines = folders[0].findall(f"{KML}Placemark")
    assert [p.findtext(f"{KML}styleUrl") for p in lines] == [
        "#single",
        "#float",
        "#fixed",
        "#float",
        "#fixed",
    ]
    points = folders[1].findall(f"{KML}Placemark")
    assert len(points) == 9  # the "none" epoch is left out
    lon, lat, h = (float(v) for v in points[0].findtext(f"{KML}Point/{KML}coordinates").split(","))
    lat0, lon0, h0 = ecef2geodetic_deg(_solutions()[0].pos_m)
    assert lat == pytest.approx(float(lat0), abs=1e-9) and lon == pytest.approx(float(lon0), abs=1e-9)
    assert h == pytest.approx(float(h0), abs=1e-4)
    assert points[0].findtext(f"{KML}TimeStamp/{KML}when") == "2021-09-22T06:29:42.000Z"  # UTC


def test_gpx_is_valid_and_coloured(tmp_path: Path) -> None:
    out = tmp_path / "track.gpx"
    write_gpx(_solutions(), out)
    root = ET.parse(out).getroot()
    assert root.tag == f"{GPX}gpx" and root.get("version") == "1.1"
    trks = root.findall(f"{GPX}trk")
    assert [t.findtext(f"{GPX}type") for t in trks] == ["single", "float", "fixed", "float", "fixed"]
    colours = [t.findtext(f"{GPX}extensions/{GPXX}TrackExtension/{GPXX}DisplayColor") for t in trks]
    assert colours == ["Red", "Yellow", "Green", "Yellow", "Green"]
    pts = [p for t in trks for p in t.findall(f"{GPX}trkseg/{GPX}trkpt")]
    assert len(pts) == 9 + len(trks) - 1  # each run after the first repeats the joint epoch
    assert {p.findtext(f"{GPX}fix") for p in pts} == {"3d", "dgps"}
    assert all(p.findtext(f"{GPX}time").endswith("Z") for p in pts)


def test_tracks_refuse_local_frames(tmp_path: Path) -> None:
    sol = [Solution(t_s=0.0, pos_m=np.array([1.0, 2.0, 3.0]), cov_m2=np.eye(3), status="fixed")]
    for fn, name in ((write_kml, "a.kml"), (write_gpx, "a.gpx")):
        with pytest.raises(InputError, match="ECEF"):
            fn(sol, tmp_path / name, pos_frame="local")
        assert not (tmp_path / name).exists()


def test_solve_dispatches_kml_and_gpx(tmp_path: Path) -> None:
    from robustrtk.cli.gnss import output_kind, write_solutions

    assert output_kind("x.KML") == "kml" and output_kind("x.gpx") == "gpx"
    write_solutions(_solutions(), tmp_path / "t.kml")
    write_solutions(_solutions(), tmp_path / "t.gpx")
    ET.parse(tmp_path / "t.kml")
    ET.parse(tmp_path / "t.gpx")
