"""Writing a simulation to disk and the one-call entry point used by the CLI."""

from __future__ import annotations

import csv
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from robustrtk.io.atomic import atomic_path
from robustrtk.io.obstable import write_obs_table
from robustrtk.io.site import write_site
from robustrtk.sim.pseudolite import SimResult, simulate
from robustrtk.sim.scenario import load_scenario

#: Files written by :func:`write_simulation`.
OUTPUT_FILES = ("obs.csv", "site.toml", "truth.csv", "ambiguities.csv", "faults.csv")


def _write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[object]]) -> None:
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        w.writerows(rows)


def _f(values: np.ndarray) -> list[str]:
    return [repr(float(v)) for v in values.tolist()]


def write_simulation(result: SimResult, out_dir: str | os.PathLike[str]) -> dict[str, Path]:
    """Write ``obs.csv``, ``site.toml``, ``truth.csv``, ``ambiguities.csv``, ``faults.csv``.

    * ``obs.csv``: observation table of receivers ``base`` and ``rover``.
    * ``truth.csv``: ``time,x,y,z`` true rover position (m).
    * ``ambiguities.csv``: ``time,transmitter,reference,N_cyc``, the true DD ambiguity
      (rover - base, transmitter - reference, cycles) per epoch and non-reference
      transmitter, slips included.
    * ``faults.csv``: ``time,epoch,receiver,transmitter,observable,kind,size,unit,source``,
      one row per injected gross error (``size`` m) or cycle slip (``size`` cycles).

    Returns
    -------
    dict of str to Path
        File name -> written path.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {name: out / name for name in OUTPUT_FILES}
    write_obs_table(result.batches, paths["obs.csv"])
    write_site(result.site, paths["site.toml"])
    t = result.t_s
    pos = result.truth_pos_m
    _write_csv(
        paths["truth.csv"],
        ("time", "x", "y", "z"),
        zip(_f(t), _f(pos[:, 0]), _f(pos[:, 1]), _f(pos[:, 2]), strict=True),
    )
    ref = result.site.reference
    cols = [i for i, tx in enumerate(result.tx_ids) if tx != ref]
    T = t.shape[0]
    amb_rows = (
        (repr(float(t[k])), result.tx_ids[i], ref, int(result.dd_ambiguity_cyc[k, i]))
        for k in range(T)
        for i in cols
    )
    _write_csv(paths["ambiguities.csv"], ("time", "transmitter", "reference", "N_cyc"), amb_rows)
    f = result.faults
    _write_csv(
        paths["faults.csv"],
        (
            "time",
            "epoch",
            "receiver",
            "transmitter",
            "observable",
            "kind",
            "size",
            "unit",
            "source",
        ),
        zip(
            _f(f.time_s),
            f.epoch.tolist(),
            f.receiver,
            f.transmitter,
            f.observable,
            f.kind,
            _f(f.size),
            f.unit,
            f.source,
            strict=True,
        ),
    )
    return paths


def run_simulate(scenario: str, seed: int, out_dir: str | os.PathLike[str]) -> SimResult:
    """Load ``scenario`` (path or preset name), simulate with ``default_rng(seed)``, write
    the files of :func:`write_simulation` into ``out_dir`` and return the result."""
    sc = load_scenario(scenario)
    result = simulate(sc, np.random.default_rng(seed))
    write_simulation(result, out_dir)
    return result
