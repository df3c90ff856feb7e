"""Indoor pseudolite simulation scenarios loaded from TOML (:func:`load_scenario`,
:func:`scenario_from_dict`); presets live in ``robustrtk/sim/presets/*.toml`` and are loaded
by name (:func:`list_presets`). The scenario types and their validation are in
:mod:`robustrtk.sim.scenario_model` and re-exported here.

Frame: local Cartesian, metres, origin at the centre of the room, x along the 10 m side,
y along the 7 m side, z up; the floor is at z = -2 m and the ceiling at z = +2 m.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from robustrtk.core import InputError
from robustrtk.io.obstable import natural_key
from robustrtk.sim.scenario_model import (
    DEFAULT_BASE_M,
    DEFAULT_ROVER_M,
    DEFAULT_TRANSMITTERS,
    OBSERVABLES,
    PL_WAVELENGTH_M,
    RECEIVERS,
    ROOM_SIZE_M,
    Bursts,
    Clocks,
    Multipath,
    Noise,
    RandomGross,
    Scenario,
    ScheduledGross,
    ScheduledSlip,
    Slips,
    Trajectory,
    Vec3,
    validate_scenario,
)

_PRESET_DIR = "presets"


class _Table:
    """Typed access to one TOML table with field-named errors and unknown-key detection."""

    def __init__(self, doc: Any, prefix: str, where: str | None):
        self.prefix = prefix
        self.where = where
        if doc is None:
            doc = {}
        if not isinstance(doc, dict):
            raise InputError(f"{prefix or 'document'}: expected a table", path=where)
        self.doc = doc
        self.used: set[str] = set()

    def name(self, key: str) -> str:
        return f"{self.prefix}.{key}" if self.prefix else key

    def err(self, key: str, expected: str) -> InputError:
        v = self.doc.get(key)
        return InputError(f"{self.name(key)}: expected {expected}, got {v!r}", path=self.where)

    def raw(self, key: str) -> Any:
        self.used.add(key)
        return self.doc.get(key)

    def has(self, key: str) -> bool:
        return key in self.doc

    def float_(self, key: str, default: float, minimum: float | None = None, unit: str = "") -> float:
        v = self.raw(key)
        if v is None:
            return default
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise self.err(key, f"a number{unit}")
        if minimum is not None and v < minimum:
            raise self.err(key, f"a number >= {minimum}{unit}")
        return float(v)

    def int_(self, key: str, default: int | None, minimum: int | None = None) -> int:
        v = self.raw(key)
        if v is None:
            if default is None:
                raise InputError(f"{self.name(key)}: missing; expected an integer", path=self.where)
            return default
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.err(key, "an integer")
        if minimum is not None and v < minimum:
            raise self.err(key, f"an integer >= {minimum}")
        return int(v)

    def str_(self, key: str, default: str, choices: tuple[str, ...] | None = None) -> str:
        v = self.raw(key)
        if v is None:
            return default
        if not isinstance(v, str) or (choices is not None and v not in choices):
            raise self.err(key, "one of " + ", ".join(repr(c) for c in choices) if choices else "a string")
        return v

    def bool_(self, key: str, default: bool) -> bool:
        v = self.raw(key)
        if v is None:
            return default
        if not isinstance(v, bool):
            raise self.err(key, "true or false")
        return v

    def nums(self, key: str, n: int, unit: str = "") -> tuple[float, ...] | None:
        v = self.raw(key)
        if v is None:
            return None
        if not (
            isinstance(v, list)
            and len(v) == n
            and all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in v)
        ):
            raise self.err(key, f"a list of {n} numbers{unit}")
        return tuple(float(x) for x in v)

    def vec3(self, key: str, default: Vec3 | None) -> Vec3 | None:
        v = self.nums(key, 3, " (m)")
        return default if v is None else (v[0], v[1], v[2])

    def pair(self, key: str, default: tuple[float, float], unit: str = "") -> tuple[float, float]:
        v = self.nums(key, 2, unit)
        return default if v is None else (v[0], v[1])

    def int_pair(self, key: str, default: tuple[int, int]) -> tuple[int, int]:
        v = self.raw(key)
        if v is None:
            return default
        if not (
            isinstance(v, list)
            and len(v) == 2
            and all(isinstance(x, int) and not isinstance(x, bool) for x in v)
        ):
            raise self.err(key, "a list of 2 integers")
        return (int(v[0]), int(v[1]))

    def str_list(self, key: str, default: tuple[str, ...]) -> tuple[str, ...]:
        v = self.raw(key)
        if v is None:
            return default
        if not (isinstance(v, list) and all(isinstance(x, str) for x in v)):
            raise self.err(key, "a list of strings")
        return tuple(v)

    def sub(self, key: str) -> _Table:
        return _Table(self.raw(key), self.name(key), self.where)

    def tables(self, key: str) -> list[_Table]:
        v = self.raw(key)
        if v is None:
            return []
        if isinstance(v, dict):
            v = [v]
        if not isinstance(v, list):
            raise self.err(key, "a table or an array of tables")
        return [_Table(x, f"{self.name(key)}[{i}]", self.where) for i, x in enumerate(v)]

    def finish(self) -> None:
        extra = [k for k in self.doc if k not in self.used]
        if extra:
            raise InputError(f"{self.name(extra[0])}: unknown key", path=self.where)


def _epochs(t: _Table, key: str) -> tuple[int, ...]:
    """Epoch list: integers and inclusive ranges ``[first, last]``."""
    v = t.raw(key)
    if not isinstance(v, list) or not v:
        raise t.err(key, "a non-empty list of epoch indices or [first, last] ranges")
    out: list[int] = []
    for x in v:
        if isinstance(x, int) and not isinstance(x, bool):
            out.append(x)
        elif (
            isinstance(x, list)
            and len(x) == 2
            and all(isinstance(y, int) and not isinstance(y, bool) for y in x)
            and x[0] <= x[1]
        ):
            out.extend(range(x[0], x[1] + 1))
        else:
            raise t.err(key, "epoch indices (integers) or inclusive ranges [first, last]")
    return tuple(sorted(set(out)))


def _noise(t: _Table, base: Noise) -> Noise:
    return Noise(
        code_sigma_m=t.float_("code_sigma_m", base.code_sigma_m, 0.0, " (m)"),
        phase_sigma_m=t.float_("phase_sigma_m", base.phase_sigma_m, 0.0, " (m)"),
        snr_range_dbhz=t.pair("snr_range_dbhz", base.snr_range_dbhz, " (dB-Hz)"),
        snr_sigma_dbhz=t.float_("snr_sigma_dbhz", base.snr_sigma_dbhz, 0.0, " (dB-Hz)"),
    )


def scenario_from_dict(doc: dict[str, Any], where: str | None = None) -> Scenario:
    """Build a :class:`Scenario` from a parsed TOML document (``where`` names the source)."""
    top = _Table(doc, "", where)
    name = top.str_("name", "scenario")
    description = top.str_("description", "")
    n_epochs = top.int_("n_epochs", None, 1)
    interval_s = top.float_("interval_s", 1.0, 1e-9, " (s)")
    wavelength_m = top.float_("wavelength_m", PL_WAVELENGTH_M, 1e-9, " (m)")
    reference = top.str_("reference", "PL6")
    init_err = top.float_("initial_position_error_m", 0.0, 0.0, " (m)")
    amb_max = top.int_("ambiguity_max_cyc", 1_000_000, 0)
    base_pos = top.vec3("base_position_m", DEFAULT_BASE_M)
    assert base_pos is not None

    txs: tuple[tuple[str, Vec3], ...] = tuple(DEFAULT_TRANSMITTERS.items())
    if top.has("transmitters"):
        tt = top.sub("transmitters")
        items = []
        for k in tt.doc:
            v = tt.vec3(k, None)
            assert v is not None
            items.append((str(k), v))
        tt.finish()
        txs = tuple(sorted(items, key=lambda kv: natural_key(kv[0])))

    tr = top.sub("trajectory")
    traj = Trajectory(
        kind=tr.str_("kind", "static", ("static", "rail", "free")),
        start_m=tr.vec3("start_m", DEFAULT_ROVER_M) or DEFAULT_ROVER_M,
        end_m=tr.vec3("end_m", None),
        speed_m_s=tr.float_("speed_m_s", 0.02, 0.0, " (m/s)"),
        rail_mode=tr.str_("rail_mode", "one_pass", ("one_pass", "back_and_forth")),
        area_m=tuple(tr.nums("area_m", 4, " (m)") or (-4.0, 4.0, -2.5, 2.5)),  # type: ignore[arg-type]
    )
    tr.finish()

    ck = top.sub("clocks")
    d = Clocks()
    clocks = Clocks(
        receiver_offset_s=ck.float_("receiver_offset_s", d.receiver_offset_s, 0.0, " (s)"),
        receiver_drift_s_s=ck.float_("receiver_drift_s_s", d.receiver_drift_s_s, 0.0, " (s/s)"),
        transmitter_offset_s=ck.float_("transmitter_offset_s", d.transmitter_offset_s, 0.0, " (s)"),
        transmitter_drift_s_s=ck.float_("transmitter_drift_s_s", d.transmitter_drift_s_s, 0.0, " (s/s)"),
        drift_rw_s_s_sqrt_s=ck.float_("drift_rw_s_s_sqrt_s", d.drift_rw_s_s_sqrt_s, 0.0),
    )
    ck.finish()

    nz = top.sub("noise")
    common = _noise(nz, Noise())
    per_rx = []
    for rx in RECEIVERS:
        sub = nz.sub(rx)
        per_rx.append(_noise(sub, common))
        sub.finish()
    nz.finish()

    mp = top.sub("multipath")
    dm = Multipath()
    multipath = Multipath(
        code_sigma_m=mp.float_("code_sigma_m", dm.code_sigma_m, 0.0, " (m)"),
        code_tau_s=mp.float_("code_tau_s", dm.code_tau_s, 1e-9, " (s)"),
        phase_sigma_m=mp.float_("phase_sigma_m", dm.phase_sigma_m, 0.0, " (m)"),
        phase_tau_s=mp.float_("phase_tau_s", dm.phase_tau_s, 1e-9, " (s)"),
        receivers=mp.str_list("receivers", dm.receivers),
    )
    mp.finish()

    sl = top.sub("slips")
    ds = Slips()
    sched = []
    for t in sl.tables("scheduled"):
        sched.append(
            ScheduledSlip(
                receiver=t.str_("receiver", "rover"),
                transmitter=t.str_("transmitter", ""),
                epoch=t.int_("epoch", None, 0),
                cycles=t.int_("cycles", None),
                silent=t.bool_("silent", False),
            )
        )
        t.finish()
    slips = Slips(
        probability=sl.float_("probability", ds.probability, 0.0),
        max_cycles=sl.int_("max_cycles", ds.max_cycles, 1),
        silent=sl.bool_("silent", ds.silent),
        receivers=sl.str_list("receivers", ds.receivers),
        scheduled=tuple(sched),
    )
    sl.finish()

    bu = top.sub("bursts")
    db = Bursts()
    weights: tuple[tuple[str, float], ...] = ()
    if bu.has("weights"):
        wt = bu.sub("weights")
        weights = tuple((str(k), wt.float_(k, 0.0, 0.0)) for k in list(wt.doc))
        wt.finish()
    bursts = Bursts(
        code_probability=bu.float_("code_probability", db.code_probability, 0.0),
        code_length_epochs=bu.int_pair("code_length_epochs", db.code_length_epochs),
        code_size_m=bu.pair("code_size_m", db.code_size_m, " (m)"),
        phase_probability=bu.float_("phase_probability", db.phase_probability, 0.0),
        phase_length_epochs=bu.int_pair("phase_length_epochs", db.phase_length_epochs),
        phase_size_m=bu.pair("phase_size_m", db.phase_size_m, " (m)"),
        receiver=bu.str_("receiver", db.receiver),
        weights=weights,
    )
    bu.finish()

    rgs = []
    for t in top.tables("random_gross"):
        rgs.append(
            RandomGross(
                observable=t.str_("observable", "code", OBSERVABLES),
                count=t.int_("count", None, 0),
                size_m=t.float_("size_m", math.nan, None, " (m)"),
                random_sign=t.bool_("random_sign", False),
                receiver=t.str_("receiver", "rover"),
            )
        )
        if math.isnan(rgs[-1].size_m):
            raise InputError(f"{t.name('size_m')}: missing; expected a number (m)", path=where)
        t.finish()

    gs = []
    for t in top.tables("gross"):
        if not t.has("transmitter"):
            raise InputError(f"{t.name('transmitter')}: missing; expected a transmitter id", path=where)
        if not t.has("size_m"):
            raise InputError(f"{t.name('size_m')}: missing; expected a number (m)", path=where)
        gs.append(
            ScheduledGross(
                observable=t.str_("observable", "code", OBSERVABLES),
                transmitter=t.str_("transmitter", ""),
                epochs=_epochs(t, "epochs"),
                size_m=t.float_("size_m", 0.0, None, " (m)"),
                receiver=t.str_("receiver", "rover"),
            )
        )
        t.finish()
    top.finish()

    return Scenario(
        n_epochs=n_epochs,
        name=name,
        description=description,
        interval_s=interval_s,
        wavelength_m=wavelength_m,
        reference=reference,
        transmitters=txs,
        base_position_m=base_pos,
        initial_position_error_m=init_err,
        ambiguity_max_cyc=amb_max,
        trajectory=traj,
        clocks=clocks,
        noise=(per_rx[0], per_rx[1]),
        multipath=multipath,
        slips=slips,
        bursts=bursts,
        random_gross=tuple(rgs),
        gross=tuple(gs),
        source=where,
    )


_TOML_LINE = re.compile(r"line (\d+)")


def list_presets() -> list[str]:
    """Names of the bundled scenario presets."""
    d = resources.files("robustrtk.sim") / _PRESET_DIR
    return sorted(p.name[:-5] for p in d.iterdir() if p.name.endswith(".toml"))


def load_scenario(path_or_name: str | os.PathLike[str]) -> Scenario:
    """Load a scenario from a TOML file or a preset name (see :func:`list_presets`).

    Raises
    ------
    InputError
        Unknown preset, missing file, TOML syntax error (with its line) or a bad field
        (named, with what was expected).
    """
    s = str(path_or_name)
    p = Path(s)
    if p.suffix.lower() == ".toml" or os.sep in s or p.is_file():
        if not p.is_file():
            raise InputError("scenario file not found", path=s)
        text = p.read_bytes()
        where = s
    else:
        res = resources.files("robustrtk.sim") / _PRESET_DIR / f"{s}.toml"
        if not res.is_file():
            raise InputError(
                f"unknown scenario {s!r}: expected a .toml path or one of the presets "
                + ", ".join(list_presets())
            )
        text = res.read_bytes()
        where = f"preset:{s}"
    try:
        doc = tomllib.loads(text.decode("utf-8"))
    except tomllib.TOMLDecodeError as exc:
        m = _TOML_LINE.search(str(exc))
        raise InputError(
            f"TOML syntax error: {exc}", path=where, line=int(m.group(1)) if m else None
        ) from None
    except UnicodeDecodeError:
        raise InputError("not a UTF-8 text file: expected TOML", path=where) from None
    return scenario_from_dict(doc, where)


__all__ = [
    "Bursts",
    "Clocks",
    "DEFAULT_BASE_M",
    "DEFAULT_ROVER_M",
    "DEFAULT_TRANSMITTERS",
    "Multipath",
    "Noise",
    "OBSERVABLES",
    "PL_WAVELENGTH_M",
    "RECEIVERS",
    "ROOM_SIZE_M",
    "RandomGross",
    "Scenario",
    "ScheduledGross",
    "ScheduledSlip",
    "Slips",
    "Trajectory",
    "Vec3",
    "list_presets",
    "load_scenario",
    "scenario_from_dict",
    "validate_scenario",
]
