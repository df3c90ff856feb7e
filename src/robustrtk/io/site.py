"""Pseudolite site file (TOML): surveyed transmitter positions, base and rover start.

Example::

    frame = "local"
    wavelength_m = 0.19029367
    reference = "PL6"            # optional

    [transmitters]
    PL1 = [-3.6, -2.4, 1.9]
    PL4 = [3.8, -2.5, 1.85]

    [receivers.base]
    position = [-1.2, -0.6, -1.6]

    [receivers.rover]            # optional
    initial_position = [1.8, 0.9, -1.5]

Coordinates are metres in the site's local Cartesian frame (``frame = "local"``, the only
frame supported). ``wavelength_m`` defaults to the GPS L1 wavelength.
"""

from __future__ import annotations

import json
import math
import os
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from robustrtk.core import CLIGHT, FloatArray, InputError
from robustrtk.io.atomic import atomic_path
from robustrtk.io.obstable import natural_key
from robustrtk.io.rinex_file import check_regular_file

#: Frames a site file may declare.
FRAMES = ("local",)
#: Default carrier wavelength (m): GPS L1, c / 1575.42 MHz.
L1_WAVELENGTH_M = CLIGHT / 1575.42e6

_TOP_KEYS = ("frame", "wavelength_m", "reference", "transmitters", "receivers")
_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")
_TOML_LINE = re.compile(r"line (\d+)")


@dataclass(frozen=True)
class Site:
    """Surveyed geometry of a pseudolite installation.

    Attributes
    ----------
    frame : str
        Coordinate frame name (``"local"``).
    wavelength_m : float
        Carrier wavelength (m).
    reference : str or None
        Reference transmitter for double differences (None: the caller chooses).
    transmitters : dict of str to ndarray, shape (3,)
        Transmitter antenna positions (m), in natural id order.
    base_pos_m : ndarray, shape (3,)
        Base receiver antenna position (m).
    rover_initial_pos_m : ndarray, shape (3,) or None
        Rover initial position for known-point initialisation (m).
    path : Path or None
        The file read (None for a site built in code).
    """

    frame: str
    wavelength_m: float
    reference: str | None
    transmitters: dict[str, FloatArray]
    base_pos_m: FloatArray
    rover_initial_pos_m: FloatArray | None = None
    path: Path | None = field(default=None, compare=False)

    @property
    def tx_ids(self) -> tuple[str, ...]:
        """Transmitter ids in natural order."""
        return tuple(sorted(self.transmitters, key=natural_key))

    def tx_positions_m(self, tx_ids: tuple[str, ...] | list[str] | None = None) -> FloatArray:
        """Positions ``(N, 3)`` (m) of ``tx_ids`` (default: all, natural order); NaN rows for
        unknown ids."""
        ids = self.tx_ids if tx_ids is None else tuple(tx_ids)
        out = np.full((len(ids), 3), np.nan)
        for i, t in enumerate(ids):
            if t in self.transmitters:
                out[i] = self.transmitters[t]
        return out


def _vec3(value: Any, name: str, p: str) -> FloatArray:
    ok = (
        isinstance(value, list)
        and len(value) == 3
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    )
    if ok:
        arr = np.asarray(value, dtype=float)
        if np.all(np.isfinite(arr)) and np.all(np.abs(arr) < 1e9):
            return arr
    raise InputError(f"{name}: expected a list of 3 finite numbers (m, below 1e9), got {value!r}", path=p)


def read_site(path: str | os.PathLike[str]) -> Site:
    """Read a site TOML file.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    Site

    Raises
    ------
    InputError
        Naming the file and the field (or the line of a TOML syntax error) and what was
        expected.
    """
    p = Path(path)
    ps = str(p)
    check_regular_file(str(p))
    try:
        with open(p, "rb") as fh:
            doc = tomllib.load(fh)
    except FileNotFoundError:
        raise InputError("site file not found", path=ps) from None
    except tomllib.TOMLDecodeError as exc:
        m = _TOML_LINE.search(str(exc))
        raise InputError(f"TOML syntax error: {exc}", path=ps, line=int(m.group(1)) if m else None) from None
    except UnicodeDecodeError:
        raise InputError("not a UTF-8 text file: expected TOML", path=ps) from None
    return site_from_dict(doc, ps, path=p)


#: Smallest accepted distance (m) between two transmitters, or a transmitter and the base.
MIN_SEPARATION_M = 0.01


def site_from_dict(doc: dict[str, Any], where: str, path: Path | None = None) -> Site:
    """Validate a parsed site document (see :func:`read_site`); ``where`` names the source
    in error messages."""
    unknown = [k for k in doc if k not in _TOP_KEYS]
    if unknown:
        raise InputError(f"{unknown[0]}: unknown key; expected one of {', '.join(_TOP_KEYS)}", path=where)
    frame = doc.get("frame", "local")
    if frame not in FRAMES:
        raise InputError(f"frame: expected 'local', got {frame!r}", path=where)
    wl = doc.get("wavelength_m", L1_WAVELENGTH_M)
    if not isinstance(wl, int | float) or isinstance(wl, bool) or not math.isfinite(wl) or wl <= 0:
        raise InputError(f"wavelength_m: expected a positive number (m), got {wl!r}", path=where)

    txs = doc.get("transmitters")
    if not isinstance(txs, dict) or len(txs) < 2:
        raise InputError(
            "transmitters: expected a table of at least 2 transmitters, id = [x, y, z] (m)",
            path=where,
        )
    transmitters = {
        str(k): _vec3(v, f"transmitters.{k}", where)
        for k, v in sorted(txs.items(), key=lambda kv: natural_key(str(kv[0])))
    }

    ids = list(transmitters)
    for i, a in enumerate(ids):
        for b in ids[i + 1 :]:
            d = float(np.linalg.norm(transmitters[a] - transmitters[b]))
            if d < MIN_SEPARATION_M:
                raise InputError(
                    f"transmitters.{b}: {d:.3g} m from {a}; expected distinct transmitter positions "
                    f"(at least {MIN_SEPARATION_M} m apart)",
                    path=where,
                )

    ref = doc.get("reference")
    if ref is not None:
        if not isinstance(ref, str):
            raise InputError(f"reference: expected a transmitter id, got {ref!r}", path=where)
        if ref not in transmitters:
            raise InputError(
                f"reference: unknown transmitter {ref!r}; expected one of {', '.join(transmitters)}",
                path=where,
            )

    rxs = doc.get("receivers")
    if not isinstance(rxs, dict):
        raise InputError(
            "receivers: expected tables [receivers.base] (position) and optionally "
            "[receivers.rover] (initial_position)",
            path=where,
        )
    for k in rxs:
        if k not in ("base", "rover"):
            raise InputError(f"receivers.{k}: unknown receiver; expected base, rover", path=where)
    base = rxs.get("base")
    if not isinstance(base, dict) or "position" not in base:
        raise InputError(
            "receivers.base.position: missing; expected the base position [x, y, z] (m)",
            path=where,
        )
    for k in base:
        if k != "position":
            raise InputError(f"receivers.base.{k}: unknown key; expected position", path=where)
    base_pos = _vec3(base["position"], "receivers.base.position", where)
    for t, xyz in transmitters.items():
        if float(np.linalg.norm(xyz - base_pos)) < MIN_SEPARATION_M:
            raise InputError(
                f"receivers.base.position: at transmitter {t}; expected the base away from every transmitter",
                path=where,
            )
    rover_pos: FloatArray | None = None
    rover = rxs.get("rover")
    if rover is not None:
        if not isinstance(rover, dict):
            raise InputError("receivers.rover: expected a table", path=where)
        for k in rover:
            if k != "initial_position":
                raise InputError(f"receivers.rover.{k}: unknown key; expected initial_position", path=where)
        if "initial_position" in rover:
            rover_pos = _vec3(rover["initial_position"], "receivers.rover.initial_position", where)
    return Site(
        frame=frame,
        wavelength_m=float(wl),
        reference=ref,
        transmitters=transmitters,
        base_pos_m=base_pos,
        rover_initial_pos_m=rover_pos,
        path=path,
    )


def _key(k: str) -> str:
    return k if _BARE_KEY.match(k) else json.dumps(k)


def _list3(v: FloatArray) -> str:
    return "[" + ", ".join(repr(float(x)) for x in np.asarray(v, float).ravel()) + "]"


def site_to_toml(site: Site) -> str:
    """TOML text of ``site`` (floats written with the shortest exact representation)."""
    lines = [f"frame = {json.dumps(site.frame)}", f"wavelength_m = {float(site.wavelength_m)!r}"]
    if site.reference is not None:
        lines.append(f"reference = {json.dumps(site.reference)}")
    lines += ["", "[transmitters]"]
    for k in sorted(site.transmitters, key=natural_key):
        lines.append(f"{_key(k)} = {_list3(site.transmitters[k])}")
    lines += ["", "[receivers.base]", f"position = {_list3(site.base_pos_m)}"]
    if site.rover_initial_pos_m is not None:
        lines += ["", "[receivers.rover]", f"initial_position = {_list3(site.rover_initial_pos_m)}"]
    return "\n".join(lines) + "\n"


def write_site(site: Site, path: str | os.PathLike[str]) -> Path:
    """Write ``site`` as TOML (atomically: :func:`robustrtk.io.atomic.atomic_path`)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(p) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(site_to_toml(site))
    return p
