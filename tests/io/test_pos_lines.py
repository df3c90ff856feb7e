"""The ``.pos`` line writer formats all lines at once: each line must be the one the
per-solution formatting writes (times rounded to the millisecond as ``gpst_text`` rounds
them, numbers as the ``14.9f``/``8.4f``... format specifications write them)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robustrtk.core import Solution
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.io.solution_pos import pos_lines
from robustrtk.timeutil import gpst_text


def _one_line(s: Solution, frame: str) -> str:
    """One line formatted field by field (the writer's layout, written independently)."""
    q = {"fixed": 1, "partial": 1, "float": 2, "dgnss": 4, "code": 4, "single": 5}[s.status]
    pos = np.asarray(s.pos_m, float)
    cov = np.asarray(s.cov_m2, float)
    if frame == "llh":
        lat, lon, h = (float(v) for v in ecef2geodetic(pos))
        rot = ecef2enu_rotation(np.array([lat]), np.array([lon]))[0]
        c = rot @ cov @ rot.T
        pairs = [(1, 1), (0, 0), (2, 2), (1, 0), (0, 2), (2, 1)]
        coords = f"{math.degrees(lat):14.9f} {math.degrees(lon):14.9f} {h:10.4f}"
    else:
        c = cov
        pairs = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (2, 0)]
        coords = f"{pos[0]:14.4f} {pos[1]:14.4f} {pos[2]:14.4f}"
    sd = []
    for k, (i, j) in enumerate(pairs):
        v = float(c[i, j])
        x = math.sqrt(abs(v)) if k < 3 else float(np.sign(v) * np.sqrt(abs(v)))
        sd.append(x if math.isfinite(x) else 0.0)
    ns = s.n_sat if s.n_sat > 0 else s.n_used
    age = s.age_s if math.isfinite(s.age_s) and s.age_s > 0 else 0.0
    ratio = s.ratio if math.isfinite(s.ratio) else 0.0
    return (
        f"{gpst_text(s.t_s, trim_zero_fraction=False)} {coords} {q:3d} {min(ns, 999):3d} "
        + " ".join(f"{v:8.4f}" for v in sd)
        + f" {min(age, 9999.99):6.2f} {min(ratio, 999.9):6.1f}\n"
    )


@pytest.mark.parametrize("frame", ["llh", "ecef"])
def test_pos_lines_match_field_by_field_formatting(frame: str) -> None:
    rng = np.random.default_rng(7)
    sols = []
    statuses = ["fixed", "float", "dgnss", "single", "none", "partial", "code"]
    for k in range(400):
        t = float(rng.uniform(1.0e9, 1.5e9))
        if k % 5 == 0:  # on a half millisecond: rounding to even
            t = round(t) + 0.0005 * float(rng.integers(-3, 4))
        pos = ecef2geodetic_inverse(rng)
        a = rng.normal(size=(3, 3)) * float(rng.choice([1e-3, 1.0, 1e3]))
        cov = a @ a.T
        if k % 11 == 0:
            cov[0, 1] = cov[1, 0] = np.nan
        if k % 17 == 0:
            pos = pos * np.array([1.0, np.nan, 1.0])
        sols.append(
            Solution(
                t_s=t,
                pos_m=pos,
                cov_m2=cov,
                status=statuses[k % len(statuses)],
                n_used=int(rng.integers(0, 2000)),
                n_sat=int(rng.integers(0, 3)) * int(rng.integers(0, 40)),
                ratio=float(rng.choice([np.nan, np.inf, 2.5, 1234.5, -1.0])),
                age_s=float(rng.choice([0.0, 1.25, np.nan, 12345.0, -2.0])),
            )
        )
    want = [_one_line(s, frame) for s in sols if s.status != "none" and np.all(np.isfinite(s.pos_m))]
    got = pos_lines(sols, frame)
    assert len(want) > 200
    assert got == want


def ecef2geodetic_inverse(rng: np.random.Generator) -> np.ndarray:
    """A point near the Earth's surface (ECEF m), anywhere."""
    u = rng.normal(size=3)
    return u / np.linalg.norm(u) * float(rng.uniform(6.36e6, 6.40e6))


def test_pos_lines_times_round_as_gpst_text() -> None:
    rng = np.random.default_rng(3)
    t = np.concatenate(
        [
            rng.uniform(-1e11, 1e11, 3000),
            np.round(rng.uniform(1e9, 1.5e9, 3000)) + rng.choice([0.0005, -0.0005, 0.9995, 0.0], 3000),
            [0.0, -0.0005, 0.0005, 86399.9995, -1e-9],
        ]
    )
    sols = [
        Solution(t_s=float(x), pos_m=np.array([6.4e6, 0.0, 0.0]), cov_m2=np.eye(3), status="single")
        for x in t
    ]
    got = pos_lines(sols, "ecef")
    want = [gpst_text(float(x), trim_zero_fraction=False) for x in t]
    assert len(got) == len(want)
    assert all(line.startswith(w + " ") for line, w in zip(got, want, strict=True))


def test_streamed_spp_lines_are_those_of_its_solutions() -> None:
    """The streamed SPP writes its epochs' lines from their columns: the lines of
    ``pos_lines`` over ``SppEpoch.to_solution``."""
    from robustrtk.pipeline.spp_common import SppEpoch
    from robustrtk.pipeline.spp_stream import _pos_lines

    rng = np.random.default_rng(11)
    epochs = []
    for k in range(300):
        pos = ecef2geodetic_inverse(rng)
        if k % 13 == 0:
            pos[2] = np.nan
        a = rng.normal(size=(3, 3)) * 3.0
        status = "none" if k % 7 == 0 else "single"
        epochs.append(
            SppEpoch(
                float(rng.uniform(1.2e9, 1.3e9)), pos, {"G": 1.0}, a @ a.T, int(rng.integers(0, 1200)), status
            )
        )
    want = pos_lines([e.to_solution() for e in epochs], "llh")
    assert len(want) > 200
    assert _pos_lines(epochs) == want
    assert _pos_lines([e for e in epochs if e.status == "none"]) == []
