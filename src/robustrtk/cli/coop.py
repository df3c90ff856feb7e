"""``robustrtk coop``: cooperative positioning of a receiver with its peers (docs/coop.md).

::

    robustrtk coop NODE.obs --peer PEER.obs [--peer ...] --nav NAV
        --filter {ekf,ukf,pf,ls} --cooperation {improved,traditional,off}
        [--peer-pos X,Y,Z] [--range-m M | --range FILE | --range-from-rtk]
        --out NODE.pos [--nodes DIR] [--diagnostics CSV] [--config TOML]

Every node (the peers in the order given, then NODE) runs its own filter
(:func:`robustrtk.pipeline.coop.rinex.solve_coop`); ``--central`` runs the centralised joint
filter instead. Settings start from :data:`robustrtk.pipeline.config.COOP_PRESET`, then the
TOML of ``--config`` (the ``[coop]`` section of the configuration tree and the shared keys it
reads, docs/configuration.md), then the flags. Bad input: one line, exit status 2;
outputs are written only after the whole run succeeded.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from robustrtk.cli.errors import one_line_errors
from robustrtk.errors import InputError

if TYPE_CHECKING:  # numpy loads with the command that uses it (start-up time)
    import numpy as np


def _parse_xyz(text: str, what: str) -> np.ndarray:
    import numpy as np

    parts = [p for p in text.replace(" ", ",").split(",") if p]
    try:
        vals = np.array([float(p) for p in parts])
    except ValueError:
        raise InputError(f"{what}: expected X,Y,Z in metres (ECEF), got {text!r}") from None
    if vals.shape != (3,) or not np.all(np.isfinite(vals)) or not 6.0e6 < float(np.linalg.norm(vals)) < 7.0e6:
        raise InputError(
            f"{what}: expected three finite ECEF coordinates near the Earth's surface, got {text!r}"
        )
    return vals


def load_coop_settings(path: str | None, overrides: dict[str, Any]) -> Any:
    """The :class:`~robustrtk.pipeline.config.Config` of a cooperative run:
    :data:`~robustrtk.pipeline.config.COOP_PRESET`, then the TOML file (any section of the
    tree; ``[coop]`` and the shared leaves act), then the non-None ``overrides`` (flat keys);
    unknown keys, wrong types and values out of range are :class:`InputError`."""
    from robustrtk.pipeline.config import COOP_PRESET, read_config_dict

    flat: dict[str, Any] = read_config_dict(path) if path is not None else {}
    source = path if path is not None else "command line"
    try:
        return COOP_PRESET.updated(**flat).updated(**overrides).validate(source)
    except InputError as exc:
        raise InputError(exc.message, source) from None


def coop_summary(per_node: dict[str, Any], wall_s: float) -> str:
    """One line per node: epochs solved, the median formal horizontal σ, and the 95th
    percentile of the horizontal distance from the node's median position (the accuracy of
    a static node; the extent of a moving one's track), then the wall time.

    ``per_node`` maps a node name to its solutions (ECEF); the last node is the one solved
    for (NODE_OBS).
    """
    import numpy as np

    from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic

    rows = []
    for nm, sols in per_node.items():
        ok = [s for s in sols if s.status != "none" and np.all(np.isfinite(s.pos_m))]
        if not ok:
            rows.append(f"  {nm:<12s} 0/{len(sols)} epochs solved")
            continue
        pos = np.array([s.pos_m for s in ok], float)
        med = np.median(pos, axis=0)
        lat, lon, _ = ecef2geodetic(med)
        r = ecef2enu_rotation(float(lat), float(lon))
        enu = (pos - med) @ r.T
        h = np.hypot(enu[:, 0], enu[:, 1])
        cov = np.array([r @ np.asarray(s.cov_m2, float) @ r.T for s in ok])
        sig_h = np.sqrt(np.clip(cov[:, 0, 0] + cov[:, 1, 1], 0.0, None))
        rows.append(
            f"  {nm:<12s} {len(ok)}/{len(sols)} epochs solved; σ_H median {np.nanmedian(sig_h):.2f} m; "
            f"H95 about its median position {np.percentile(h, 95):.2f} m"
        )
    return "\n".join(
        ["accuracy (no truth: formal σ, and the spread of a static node)", *rows, f"  time {wall_s:.1f} s"]
    )


def _names(paths: list[str]) -> list[str]:
    out: list[str] = []
    for p in paths:
        base = Path(p).stem or "node"
        name, k = base, 2
        while name in out:
            name, k = f"{base}_{k}", k + 1
        out.append(name)
    return out


def _write_diagnostics(result: Any, path: str) -> None:
    from robustrtk.io.solution_table import open_atomic_text

    with open_atomic_text(path, newline="") as fh:
        fh.write("node,gpst_s,solved,n_sats,n_ranges,range_residual_m,range_sigma_m,trace_p_m2,ess\n")
        for name in result.nodes:
            for e in result.epochs[name]:
                fh.write(
                    f"{name},{e.t_s:.3f},{int(e.solved)},{e.n_sats},{e.n_ranges},"
                    f"{e.range_residual_m:.4f},{e.range_sigma_m:.4f},{e.trace_p_m2:.4f},{e.ess:.1f}\n"
                )


@click.command("coop")
@click.argument("node_obs", type=click.Path(dir_okay=False))
@click.option("--peer", "peers", multiple=True, required=True, help="A peer's observation file (repeatable).")
@click.option("--nav", "navs", multiple=True, required=True, help="Broadcast navigation file(s).")
@click.option(
    "--filter", "filter_", type=click.Choice(["ekf", "ukf", "pf", "ls"]), default=None, help="Filter (ekf)."
)
@click.option(
    "--cooperation",
    type=click.Choice(["improved", "traditional", "off"]),
    default=None,
    help="improved: range variance inflated by the reset peer covariance (eqs. 24, 29, 30) (default).",
)
@click.option(
    "--peer-pos", "peer_pos", multiple=True, help="Surveyed ECEF X,Y,Z of the peers, in --peer order."
)
@click.option("--range-m", type=float, default=None, help="Constant range NODE–peer (m; one peer).")
@click.option("--range-sigma-m", type=float, default=0.05, show_default=True, help="σ of --range-m (m).")
@click.option(
    "--range", "range_file", type=click.Path(dir_okay=False), default=None, help="Range file (one peer)."
)
@click.option(
    "--range-from-rtk", is_flag=True, help="Range from our DD carrier-phase RTK of NODE and each peer."
)
@click.option(
    "--session-range", is_flag=True, help="With --range-from-rtk: one session value (static nodes)."
)
@click.option(
    "--out", "out", type=click.Path(dir_okay=False), required=True, help="NODE's solution (.pos or .csv)."
)
@click.option(
    "--nodes", "nodes_dir", type=click.Path(file_okay=False), default=None, help="Write every node here."
)
@click.option(
    "--diagnostics", type=click.Path(dir_okay=False), default=None, help="Per-epoch diagnostics CSV."
)
@click.option(
    "--config",
    "config",
    type=click.Path(dir_okay=False),
    default=None,
    help="TOML configuration: [coop] and the shared keys it reads.",
)
@click.option("--central", is_flag=True, help="Centralised joint filter over all nodes (reference).")
@click.option("--particles", type=int, default=None, help="Particle-filter size (10000).")
@click.option("--seed", type=int, default=None, help="Particle-filter seed (0).")
@click.option("--systems", default=None, help="System letters of the code (GECJ).")
@click.option(
    "--windowsill", type=int, default=None, help="Occlude NODE: one 180° sky sector, at most K sats."
)
@click.option(
    "--windowsill-seed", type=int, default=0, show_default=True, help="Seed of the sector's centre."
)
@one_line_errors
def coop(
    node_obs: str,
    peers: tuple[str, ...],
    navs: tuple[str, ...],
    filter_: str | None,
    cooperation: str | None,
    peer_pos: tuple[str, ...],
    range_m: float | None,
    range_sigma_m: float,
    range_file: str | None,
    range_from_rtk: bool,
    session_range: bool,
    out: str,
    nodes_dir: str | None,
    diagnostics: str | None,
    config: str | None,
    central: bool,
    particles: int | None,
    seed: int | None,
    systems: str | None,
    windowsill: int | None,
    windowsill_seed: int,
) -> None:
    """Cooperative positioning of NODE_OBS with its peers (Zhou et al. 2018)."""
    import numpy as np

    from robustrtk.cli.gnss import write_solutions
    from robustrtk.cli.paths import check_output_paths
    from robustrtk.pipeline.coop.central import solve_coop_central
    from robustrtk.pipeline.coop.links import read_range_file, rtk_range_link
    from robustrtk.pipeline.coop.rinex import solve_coop
    from robustrtk.pipeline.coop.scenarios import windowsill_mask
    from robustrtk.pipeline.coop.types import CoopNode, RangeLink, coop_systems
    from robustrtk.pipeline.gnss import check_has_epochs, load_obs, nav_source

    check_output_paths(
        [("NODE_OBS", node_obs), ("--config", config), ("--range", range_file)]
        + [("--peer", p) for p in peers] + [("--nav", n) for n in navs],
        [("--out", out), ("--diagnostics", diagnostics)],
    )  # fmt: skip

    if (range_m is not None or range_file is not None) and len(peers) != 1:
        raise InputError("--range-m and --range give one range: use them with exactly one --peer")
    if session_range and not range_from_rtk:
        raise InputError("--session-range applies only with --range-from-rtk")
    if range_m is not None and not (range_m > 0 and range_sigma_m > 0):
        raise InputError("--range-m and --range-sigma-m must be positive")
    if peer_pos and len(peer_pos) != len(peers):
        raise InputError(f"--peer-pos: give one per --peer ({len(peers)}), got {len(peer_pos)}")
    if not str(out).lower().endswith((".pos", ".csv")):
        raise InputError(f"--out: expected a file ending in .pos or .csv, got {out!r}")
    if windowsill is not None and windowsill < 1:
        raise InputError("--windowsill: expected a positive number of satellites")
    if particles is not None and particles < 2:
        raise InputError("--particles: expected at least 2")
    cfg = load_coop_settings(
        config,
        {
            "coop_filter": filter_,
            "cooperation": cooperation,
            "n_particles": particles,
            "seed": seed,
            "systems": systems,
        },
    )
    n_src = sum(x is not None and x is not False for x in (range_m, range_file, range_from_rtk or None))
    if cfg.coop.cooperation == "off" and n_src:
        raise InputError("a range source does not apply with --cooperation off")
    if cfg.coop.cooperation != "off" and n_src != 1:
        raise InputError("give exactly one range source: --range-m, --range or --range-from-rtk")
    if cfg.coop.filter != "pf" and (particles is not None or seed is not None):
        raise InputError("--particles and --seed apply only to --filter pf")
    surveyed = [_parse_xyz(p, "--peer-pos") for p in peer_pos]
    eph = nav_source(list(navs))
    names = _names([*peers, node_obs])
    batches = []
    for path, nm in zip([*peers, node_obs], names, strict=True):
        b = load_obs(path, None)
        check_has_epochs(b, nm)
        batches.append(b)
    me = names[-1]
    vis = None
    if windowsill is not None:
        pos = batches[-1].approx_pos_m
        if pos is None or not np.all(np.isfinite(pos)):
            raise InputError("--windowsill needs an approximate position in NODE's header", node_obs)
        vis, _ = windowsill_mask(
            batches[-1], eph, np.asarray(pos, float), max_sats=windowsill, seed=windowsill_seed,
            systems=coop_systems(cfg),
        )  # fmt: skip
    nodes = [CoopNode(nm, b) for nm, b in zip(names[:-1], batches[:-1], strict=True)]
    nodes.append(CoopNode(me, batches[-1], vis))
    links: list[RangeLink] = []
    if n_src == 0:
        pass
    elif range_m is not None:
        links.append(RangeLink.constant(me, names[0], range_m, range_sigma_m))
    elif range_file is not None:
        links.append(read_range_file(range_file, me, names[0]))
    else:
        for i, nm in enumerate(names[:-1]):
            lk, _ = rtk_range_link(
                batches[-1],
                batches[i],
                eph,
                a=me,
                b=nm,
                b_pos_m=surveyed[i] if surveyed else None,
                session=session_range,
            )
            links.append(lk)
    from robustrtk.cli.progress import ProgressBar, bar_wanted

    t0 = time.perf_counter()
    if central:
        click.echo(f"coop: centralised filter over {len(names)} nodes (no progress bar)...", err=True)
        result = solve_coop_central(nodes, links, eph, cfg, timeline=me)
    else:
        with ProgressBar(f"coop {cfg.coop.filter}", enabled=bar_wanted(False)) as bar:
            result = solve_coop(nodes, links, eph, cfg, progress=bar, timeline=me)
    wall_s = time.perf_counter() - t0
    sols = result.solutions(me)
    if not any(s.status != "none" for s in sols):
        click.echo(f"warning: {me}: no epoch solved", err=True)
    if nodes_dir is not None:
        os.makedirs(nodes_dir, exist_ok=True)
    write_solutions(sols, out)
    if nodes_dir is not None:
        for nm in names:
            write_solutions(result.solutions(nm), os.path.join(nodes_dir, f"{nm}.pos"))
    if diagnostics is not None:
        _write_diagnostics(result, diagnostics)
    n_ok = sum(s.status != "none" for s in sols)
    click.echo(
        f"coop {cfg.coop.filter}/{cfg.coop.cooperation}{' central' if central else ''}: "
        f"{me} solved {n_ok}/{len(sols)} "
        f"epochs with {len(names) - 1} peer(s); wrote {out}"
    )
    click.echo(coop_summary({nm: result.solutions(nm) for nm in names}, wall_s))


__all__ = ["coop", "load_coop_settings"]
