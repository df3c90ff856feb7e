"""High-level entry points: files in, :class:`~robustrtk.pipeline.engine.RunResult` out."""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping

from robustrtk.core import InputError, ObsBatch
from robustrtk.geometry.surveyed import SurveyedSource
from robustrtk.io.obstable import read_obs_table
from robustrtk.io.site import Site, read_site
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.loop import run_dd
from robustrtk.pipeline.results import RunResult


def solve_pseudolite(
    obs_path: str | os.PathLike[str] | Mapping[str, ObsBatch],
    site: str | os.PathLike[str] | Site,
    cfg: Config,
    progress: Callable[[int, int], None] | None = None,
) -> RunResult:
    """Solve a pseudolite observation table (DPL or RTK per ``cfg.mode``).

    The reference transmitter is ``cfg.measurement.reference`` if set, else the site file's
    ``reference``, else chosen automatically (highest elevation seen from the rover's
    initial position) and reported in ``result.info["references"]``. ``obs_path`` is a
    table file or the batches already read from one (receiver name -> :class:`ObsBatch`).
    """
    st = site if isinstance(site, Site) else read_site(site)
    if isinstance(obs_path, Mapping):
        batches = dict(obs_path)
        where = None
    else:
        batches = read_obs_table(obs_path, wavelength_m=st.wavelength_m)
        where = os.fspath(obs_path)
    for name in (cfg.receivers.base, cfg.receivers.rover):
        if name not in batches:
            raise InputError(
                f"receiver {name!r} not found; the table has {', '.join(sorted(batches))}",
                where,
            )
    for name in (cfg.receivers.base, cfg.receivers.rover):
        unknown = sorted(set(batches[name].tx_ids) - set(st.transmitters))
        if unknown:
            raise InputError(
                f"receiver {name!r} observes transmitter(s) {', '.join(unknown)} that the site file does not "
                f"list (it has {', '.join(sorted(st.transmitters))})",
                where,
            )
    reference = cfg.measurement.reference or st.reference
    if reference is not None and reference not in st.transmitters:
        raise InputError(
            f"reference transmitter {reference!r} is not in the site's transmitters",
            str(st.path) if st.path else None,
        )
    if st.rover_initial_pos_m is None:
        raise InputError(
            "receivers.rover.initial_position: expected [x, y, z] (m), needed to initialise the rover",
            str(st.path) if st.path else None,
        )
    source = SurveyedSource(st.transmitters)
    res = run_dd(
        batches[cfg.receivers.rover],
        batches[cfg.receivers.base],
        cfg,
        source,
        st.base_pos_m,
        st.rover_initial_pos_m,
        reference=reference,
        progress=progress,
    )
    res.info["reference_source"] = (
        "config" if cfg.measurement.reference else ("site" if st.reference else "automatic")
    )
    return res
