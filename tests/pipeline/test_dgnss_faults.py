"""Code DGNSS with silent gross code errors (issue 5 acceptance).

Twenty epochs (``random20``, seed 1) with +10 m on one GPS satellite's band-1 code (RINEX 3
``C1C``, RINEX 2 ``C1``), loss-of-lock flags untouched (``robustrtk.sim.inject``), as in the
data README's "How RTKLIB reacts to silent gross errors" (RTKLIB dgps: horizontal 95 % about
3x worse). Target: H95 and V95 at most 10 % worse than on clean data, and every DD carrying
the faulty code flagged by the robust filter (situation > 1) at the injected epochs.

Per dataset two satellites: the GPS reference the engine picks (a faulty reference spoils
every DD of its group) and a low-elevation one. Cases where the default DGNSS does not reach
the target are strict ``xfail`` with the measured numbers in the reason, so that a change
that closes the gap shows up as XPASS (and the mark must then go). Default DGNSS settings
(kamakura: kinematic, as in ``test_dgnss.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import ObsBatch
from robustrtk.geometry.frames import ecef2enu_deg, ecef2geodetic_deg, geodetic2ecef_deg
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.gnss import DgnssResult, dgnss_config, solve_dgnss
from robustrtk.sim.inject import inject_file, parse_spec

SIZE_M = "10"  # metres, spelt as on the command line (the random draw is seeded by the spec text)
EPOCHS = "random20"
SEED = 1
MAX_RATIO = 1.10

Truth = Callable[[float, float], "np.ndarray | None"]


@dataclass(frozen=True)
class Dataset:
    rover: Path
    base: Path
    nav: Path
    base_pos_m: np.ndarray
    cfg: Config
    code: str  # band-1 GPS code as the file's header spells it
    truths: dict[str, Truth]  # name -> truth(t_s, t0_s) (ECEF m or None = not evaluated)


def _keyed(path: Path) -> dict[str, str]:
    out = {}
    for line in path.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            k, v = line.split(None, 1)
            out[k] = v
    return out


def _dataset(root: Path, name: str) -> Dataset:
    if name == "geonet":
        d = root / "geonet_0759_3040_static_3km"
        kv = _keyed(d / "truth_and_base.txt")
        rover = np.array(kv["rover_xyz_selfderived"].split(), float)
        return Dataset(
            d / "07590920.05o",
            d / "30400920.05o",
            d / "30400920.05n",
            np.array(kv["base_xyz"].split(), float),
            dgnss_config(),
            "C1",
            {"static": lambda t, t0: rover},
        )
    if name == "mosaic":
        d = root / "mosaicx5_static_1m"
        b = [float(v) for v in (d / "base_position.txt").read_text().split()[:3]]
        r = [float(v) for v in (d / "rover_position.txt").read_text().split()[:3]]
        rover = geodetic2ecef_deg(*r)
        return Dataset(
            d / "rover.obs",
            d / "base.obs",
            d / "base.nav",
            geodetic2ecef_deg(*b),
            dgnss_config(),
            "C1C",
            {"static": lambda t, t0: rover},
        )
    d = root / "kamakura_kinematic_5km"
    kv = _keyed(d / "truth_and_base.txt")
    start = geodetic2ecef_deg(*(float(v) for v in kv["rover_start_llh"].split()))
    ref = np.loadtxt(d / "rtklib/pseudoref_comb_fh_traj.txt", comments=("%", "#"))
    t_ref = ref[:, 0] * 604800.0 + ref[:, 1]

    def traj(t: float, t0: float) -> np.ndarray | None:
        j = int(np.argmin(np.abs(t_ref - t)))
        return ref[j, 2:5] if abs(t_ref[j] - t) < 0.01 else None

    return Dataset(
        d / "SEPT265G.21O",
        d / "3034265G.21O",
        d / "SEPT2650.21P",
        np.array(kv["base_xyz"].split(), float),
        dgnss_config(dynamics="kinematic", sigma_vel_m_s=10.0),
        "C1C",
        {"start": lambda t, t0: start if t - t0 <= 34.5 else None, "trajectory": traj},
    )


def errors95(res: DgnssResult, truth: Truth) -> tuple[float, float, int]:
    """95th percentiles of horizontal and |vertical| errors (m) and the epoch count."""
    t0 = res.solutions[0].t_s
    enu = []
    for s in res.solutions:
        tr = truth(s.t_s, t0)
        if s.status == "dgnss" and tr is not None:
            ll = np.array(ecef2geodetic_deg(tr)).ravel()
            enu.append(ecef2enu_deg(s.pos_m, *ll))
    e = np.array(enu)
    return (
        float(np.percentile(np.hypot(e[:, 0], e[:, 1]), 95)),
        float(np.percentile(np.abs(e[:, 2]), 95)),
        len(e),
    )


@dataclass
class Faulty:
    res: DgnssResult
    rover: ObsBatch
    epochs: list[int]


class Runner:
    """Runs (and caches) the clean and faulty DGNSS solutions of each dataset."""

    def __init__(self, root: Path, tmp: Path) -> None:
        self.root, self.tmp = root, tmp
        self._ds: dict[str, Dataset] = {}
        self._obs: dict[str, tuple[ObsBatch, ObsBatch]] = {}
        self._clean: dict[str, DgnssResult] = {}
        self._faulty: dict[tuple[str, str], Faulty] = {}
        self._removed: dict[tuple[str, str], DgnssResult] = {}

    def ds(self, name: str) -> Dataset:
        if name not in self._ds:
            self._ds[name] = _dataset(self.root, name)
        return self._ds[name]

    def _solve(self, name: str, rover: ObsBatch) -> DgnssResult:
        d = self.ds(name)
        return solve_dgnss(rover, self.obs(name)[1], [d.nav], d.base_pos_m, d.cfg)

    def obs(self, name: str) -> tuple[ObsBatch, ObsBatch]:
        if name not in self._obs:
            d = self.ds(name)
            self._obs[name] = (read_rinex_obs(d.rover), read_rinex_obs(d.base))
        return self._obs[name]

    def clean(self, name: str) -> DgnssResult:
        if name not in self._clean:
            self._clean[name] = self._solve(name, self.obs(name)[0])
        return self._clean[name]

    def faulty(self, name: str, sat: str) -> Faulty:
        if (name, sat) not in self._faulty:
            d = self.ds(name)
            spec = parse_spec(f"{sat}:{d.code}:{SIZE_M}:{EPOCHS}", "code")
            out = self.tmp / f"{name}_{sat}{d.rover.suffix}"
            inj = inject_file(d.rover, out, [spec], seed=SEED)
            epochs = sorted({c.epoch_index for c in inj.changes})
            assert len(epochs) == 20
            rover = read_rinex_obs(out)
            self._faulty[name, sat] = Faulty(self._solve(name, rover), rover, epochs)
        return self._faulty[name, sat]

    def removed(self, name: str, sat: str) -> DgnssResult:
        """Clean data without the satellite's code at the injected epochs (ideal exclusion)."""
        if (name, sat) not in self._removed:
            rover = self.obs(name)[0]
            code = rover.code_m.copy()
            band1 = [k for k, sig in enumerate(rover.signals) if sig.startswith("1")]  # the faulty C1
            ep = np.asarray(self.faulty(name, sat).epochs)
            code[np.ix_(ep, [rover.tx_ids.index(sat)], band1)] = np.nan
            self._removed[name, sat] = self._solve(name, replace(rover, code_m=code))
        return self._removed[name, sat]


@pytest.fixture(scope="module")
def runner(shared_data: Path, tmp_path_factory: pytest.TempPathFactory) -> Runner:
    return Runner(shared_data, tmp_path_factory.mktemp("dgnss_faults"))


def _xfail(reason: str) -> pytest.MarkDecorator:
    return pytest.mark.xfail(strict=True, reason=reason)


_slow = pytest.mark.slow

# references (highest at the start): geonet G11 (50-69 deg), mosaic G13 (71), kamakura G15 (66);
# low: geonet G19 (16-32 deg), mosaic G29 (17), kamakura G14 (16). With the default DGNSS (post-fit
# policy, the engine's faulty-reference check) every case equals ideal exclusion to ~0.1 cm.
RATIO_CASES = [
    pytest.param("geonet", "G11", "static", id="geonet-G11ref"),
    pytest.param("geonet", "G19", "static", id="geonet-G19low"),
    pytest.param("mosaic", "G13", "static", id="mosaic-G13ref", marks=_slow),
    pytest.param("mosaic", "G29", "static", id="mosaic-G29low", marks=_slow),
    pytest.param("kamakura", "G15", "trajectory", id="kamakura-G15ref-trajectory", marks=_slow),
    pytest.param("kamakura", "G15", "start", id="kamakura-G15ref-start", marks=_slow),
    pytest.param("kamakura", "G14", "trajectory", id="kamakura-G14low-trajectory", marks=_slow),
    pytest.param("kamakura", "G14", "start", id="kamakura-G14low-start", marks=_slow),
]

FLAG_CASES = [
    pytest.param("geonet", "G11", id="geonet-G11ref"),
    pytest.param("geonet", "G19", id="geonet-G19low"),
    pytest.param("mosaic", "G13", id="mosaic-G13ref", marks=_slow),
    pytest.param("mosaic", "G29", id="mosaic-G29low", marks=_slow),
    pytest.param("kamakura", "G15", id="kamakura-G15ref", marks=_slow),
    pytest.param("kamakura", "G14", id="kamakura-G14low", marks=_slow),
]


@pytest.mark.parametrize(("name", "sat", "truth"), RATIO_CASES)
def test_h95_v95_within_10_percent_of_clean(runner: Runner, name: str, sat: str, truth: str) -> None:
    tr = runner.ds(name).truths[truth]
    h0, v0, n0 = errors95(runner.clean(name), tr)
    h1, v1, n1 = errors95(runner.faulty(name, sat).res, tr)
    print(
        f"\n{name} {sat} {truth}: clean H95 {h0 * 100:.1f} V95 {v0 * 100:.1f} cm; "
        f"faulty H95 {h1 * 100:.1f} V95 {v1 * 100:.1f} cm (x{h1 / h0:.2f}, x{v1 / v0:.2f})"
    )
    assert n1 == n0 and n0 >= 35
    assert h1 <= MAX_RATIO * h0
    assert v1 <= MAX_RATIO * v0


@pytest.mark.parametrize(("name", "sat"), FLAG_CASES)
def test_faulty_dds_flagged(runner: Runner, name: str, sat: str) -> None:
    """At each injected epoch where the satellite is in a DD, every DD containing it (one, or
    the whole group while it is the reference) has situation > 1."""
    f = runner.faulty(name, sat)
    by_t: dict[float, list] = {}
    for row in f.res.run.diagnostics:
        by_t.setdefault(row.t_s, []).append(row)
    used = flagged = 0
    for i in f.epochs:
        # the fault is on the L1 code: the satellite's L1 rows (as transmitter or reference)
        rows = [r for r in by_t.get(float(f.rover.t_s[i]), []) if f"{sat}:L1" in r.dd.split("-")]
        if rows:
            used += 1
            flagged += all(r.situation > 1 for r in rows)
    print(f"\n{name} {sat}: {flagged} of {used} injected epochs in use flagged")
    assert used >= 13  # geonet G19: 19 (one epoch below the mask), others 20
    assert flagged == used


def test_geonet_matches_ideal_exclusion(runner: Runner) -> None:
    """With a non-reference faulty satellite the robust DGNSS is as good as leaving the faulty
    codes out (what any outlier handling can at best do): within 2 % in H95 and V95."""
    tr = runner.ds("geonet").truths["static"]
    h1, v1, _ = errors95(runner.faulty("geonet", "G19").res, tr)
    h2, v2, _ = errors95(runner.removed("geonet", "G19"), tr)
    print(
        f"\ngeonet G19: faulty H95 {h1 * 100:.1f} V95 {v1 * 100:.1f} cm; "
        f"faulty codes removed H95 {h2 * 100:.1f} V95 {v2 * 100:.1f} cm"
    )
    assert h1 <= 1.02 * h2 and v1 <= 1.02 * v2


@pytest.mark.parametrize(
    ("name", "sat"),
    [
        pytest.param("geonet", "G11", id="geonet"),
        pytest.param("mosaic", "G13", id="mosaic", marks=_slow),
        pytest.param("kamakura", "G15", id="kamakura", marks=_slow),
    ],
)
def test_reference_case_is_the_engines_gps_reference(runner: Runner, name: str, sat: str) -> None:
    """The satellite the "ref" cases corrupt is the GPS reference of most clean epochs."""
    refs: dict[str, set[float]] = {}
    for row in runner.clean(name).run.diagnostics:
        if row.kind != "code":  # engine rows (imm, integrity, adaptive) are not DDs
            continue
        tx, ref = row.dd.split("-")
        if tx.startswith("G") and tx.endswith(":L1"):
            refs.setdefault(ref.split(":")[0], set()).add(row.t_s)
    assert max(refs, key=lambda r: len(refs[r])) == sat
