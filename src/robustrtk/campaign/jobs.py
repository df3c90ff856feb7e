"""Job lists of a processing campaign: one rover/base pair and its output per job.

A job list is a TOML file, a CSV file, or a folder whose ``*.toml`` and ``*.csv`` files are
job lists (read in name order). Relative paths are relative to the file that names them.
Format (docs/batch.md):

TOML — optional ``[defaults]`` (any job key) and one ``[[job]]`` table per job::

    [defaults]
    mode = "rtk"
    out_dir = "solutions"          # where a job without ``out`` writes NAME.pos

    [[job]]
    name = "mosaicx5"              # default: the rover file's stem
    rover = "data/rover.obs"
    base = "data/base.obs"
    nav = ["data/base.nav"]        # a string or a list
    base_pos = [-3817681.1213, 3562839.4311, 3650159.1593]   # or "X,Y,Z" (ECEF m)
    out = "solutions/mosaicx5.pos"
    config = "rtk.toml"            # optional --config of the solve
    args = ["--ar", "par"]         # optional extra ``solve`` flags

CSV — a header line naming columns among ``name, rover, base, nav, base_pos, mode, out,
config, args``; ``nav`` may hold several files separated by ``;``, ``base_pos`` is
``X Y Z`` or ``X;Y;Z`` (or a quoted ``"X,Y,Z"``), ``args`` is split like a shell line.
Blank lines and lines starting with ``#`` are skipped.

Every problem is an :class:`~robustrtk.errors.InputError` naming the file, the line (CSV)
or job number (TOML) and the field.
"""

from __future__ import annotations

import csv
import shlex
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robustrtk.errors import InputError

#: Keys a job may have (TOML keys, CSV columns).
JOB_KEYS = ("name", "rover", "base", "nav", "base_pos", "mode", "out", "config", "args")
#: Modes a job may ask for (those of ``robustrtk solve`` on RINEX input).
JOB_MODES = ("spp", "dgnss", "rtk")
#: Output suffixes a job's ``out`` may have.
OUT_SUFFIXES = (".pos", ".csv", ".nmea", ".kml", ".gpx")


@dataclass(frozen=True)
class Job:
    """One solve of a campaign (absolute paths).

    Attributes
    ----------
    name : str
        Unique label of the job in the campaign.
    rover : str
        Rover observation file.
    base : str or None
        Base observation file (dgnss, rtk).
    nav : tuple of str
        Navigation files.
    base_pos : str or None
        Base ECEF ``"X,Y,Z"`` (m), as ``--base-pos`` takes it.
    mode : str
        ``spp``, ``dgnss`` or ``rtk``.
    out : str
        Solution file the job writes.
    config : str or None
        TOML configuration (``--config``).
    args : tuple of str
        Further ``solve`` flags.
    source : str
        Where the job was defined (``file:line`` or ``file: job N``), for messages.
    """

    name: str
    rover: str
    base: str | None
    nav: tuple[str, ...]
    base_pos: str | None
    mode: str
    out: str
    config: str | None = None
    args: tuple[str, ...] = ()
    source: str = ""

    def solve_args(self) -> list[str]:
        """The ``robustrtk solve`` arguments of this job (without the program name)."""
        argv = ["solve", self.rover]
        if self.base is not None:
            argv += ["--base", self.base]
        for n in self.nav:
            argv += ["--nav", n]
        if self.base_pos is not None:
            argv += ["--base-pos", self.base_pos]
        if self.config is not None:
            argv += ["--config", self.config]
        return [*argv, "--mode", self.mode, *self.args, "--out", self.out, "--quiet"]


@dataclass
class _Spec:
    """A job's raw fields while it is read, with where they came from."""

    fields: dict[str, Any]
    where: str
    folder: Path
    defaults: dict[str, Any] = field(default_factory=dict)


def _path(value: Any, folder: Path, key: str, where: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise InputError(f"{where}: {key}: expected a file path, got {value!r}")
    p = Path(value.strip()).expanduser()
    return str(p if p.is_absolute() else (folder / p).resolve())


def _base_pos(value: Any, where: str) -> str:
    if isinstance(value, list | tuple):
        parts = [str(v) for v in value]
    elif isinstance(value, str):
        parts = [w for w in value.replace(";", " ").replace(",", " ").split() if w]
    else:
        raise InputError(f"{where}: base_pos: expected X,Y,Z (ECEF m), got {value!r}")
    try:
        xyz = [float(p) for p in parts]
    except ValueError:
        raise InputError(f"{where}: base_pos: expected three numbers X,Y,Z (ECEF m), got {value!r}") from None
    if len(xyz) != 3 or not all(abs(v) < 1e8 for v in xyz):
        raise InputError(f"{where}: base_pos: expected three finite numbers X,Y,Z (ECEF m), got {value!r}")
    return ",".join(repr(v) for v in xyz)


def _job(spec: _Spec) -> Job:
    raw = {**spec.defaults, **spec.fields}
    where, folder = spec.where, spec.folder
    unknown = sorted(set(raw) - set(JOB_KEYS) - {"out_dir"})
    if unknown:
        raise InputError(
            f"{where}: unknown key(s) {', '.join(unknown)}; expected {', '.join(JOB_KEYS)}, out_dir"
        )
    if "rover" not in raw:
        raise InputError(f"{where}: rover: a rover observation file is required")
    rover = _path(raw["rover"], folder, "rover", where)
    mode = raw.get("mode", "rtk")
    if mode not in JOB_MODES:
        raise InputError(f"{where}: mode: expected one of {', '.join(JOB_MODES)}, got {mode!r}")
    base = _path(raw["base"], folder, "base", where) if raw.get("base") not in (None, "") else None
    if mode != "spp" and base is None:
        raise InputError(f"{where}: base: mode {mode} needs a base observation file")
    nav_raw = raw.get("nav", [])
    if isinstance(nav_raw, str):
        nav_raw = [w for w in nav_raw.split(";") if w.strip()]
    if not isinstance(nav_raw, list) or not nav_raw:
        raise InputError(f"{where}: nav: expected one or more navigation files")
    nav = tuple(_path(n, folder, "nav", where) for n in nav_raw)
    base_pos = _base_pos(raw["base_pos"], where) if raw.get("base_pos") not in (None, "") else None
    name = raw.get("name") or Path(rover).stem
    if not isinstance(name, str):
        raise InputError(f"{where}: name: expected a string, got {name!r}")
    if raw.get("out") not in (None, ""):
        out = _path(raw["out"], folder, "out", where)
    else:
        out_dir = raw.get("out_dir", ".")
        out = _path(str(Path(str(out_dir)) / f"{name}.pos"), folder, "out_dir", where)
    if Path(out).suffix.lower() not in OUT_SUFFIXES:
        raise InputError(f"{where}: out: expected a file ending in {', '.join(OUT_SUFFIXES)}, got {out!r}")
    config = _path(raw["config"], folder, "config", where) if raw.get("config") not in (None, "") else None
    args_raw = raw.get("args", [])
    if isinstance(args_raw, str):
        args_raw = shlex.split(args_raw)
    if not isinstance(args_raw, list) or not all(isinstance(a, str) for a in args_raw):
        raise InputError(f"{where}: args: expected a list of solve flags, got {args_raw!r}")
    banned = {"--out", "--base", "--nav", "--base-pos", "--mode", "--config"} & set(args_raw)
    if banned:
        raise InputError(f"{where}: args: {', '.join(sorted(banned))} belong in the job's own fields")
    return Job(name, rover, base, nav, base_pos, mode, out, config, tuple(args_raw), where)


def _read_toml(path: Path) -> list[Job]:
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}", str(path)) from None
    extra = sorted(set(data) - {"defaults", "job"})
    if extra:
        raise InputError(f"unknown table(s) {', '.join(extra)}; expected [defaults] and [[job]]", str(path))
    defaults = data.get("defaults", {})
    jobs_raw = data.get("job", [])
    if not isinstance(defaults, dict) or not isinstance(jobs_raw, list):
        raise InputError("expected a [defaults] table and [[job]] tables", str(path))
    return [
        _job(_Spec(j, f"{path}: job {i + 1}", path.parent, defaults))
        for i, j in enumerate(jobs_raw)
        if isinstance(j, dict)
    ]


def _read_csv(path: Path) -> list[Job]:
    text = path.read_text(encoding="utf-8")
    rows = [
        (n + 1, ln)
        for n, ln in enumerate(text.splitlines())
        if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not rows:
        return []
    header_line, header = rows[0]
    cols = [c.strip() for c in next(csv.reader([header]))]
    unknown = [c for c in cols if c not in JOB_KEYS]
    if unknown:
        raise InputError(
            f"unknown column(s) {', '.join(unknown)}; expected {', '.join(JOB_KEYS)}", str(path), header_line
        )
    jobs = []
    for line_no, line in rows[1:]:
        values = next(csv.reader([line]))
        if len(values) != len(cols):
            raise InputError(
                f"expected {len(cols)} fields ({', '.join(cols)}), got {len(values)}", str(path), line_no
            )
        fields = {c: v.strip() for c, v in zip(cols, values, strict=True) if v.strip()}
        jobs.append(_job(_Spec(fields, f"{path}:{line_no}", path.parent)))
    return jobs


def read_jobs(path: str | Path) -> list[Job]:
    """The jobs of a TOML or CSV job list, or of every ``*.toml`` / ``*.csv`` in a folder.

    Parameters
    ----------
    path : str or path
        Job list file or folder.

    Returns
    -------
    list of Job
        In file order (folder: files in name order).

    Raises
    ------
    InputError
        Missing or malformed file, unknown key, missing rover/base/nav, duplicate job name
        or output.
    """
    p = Path(path)
    if p.is_dir():
        files = sorted(q for q in p.iterdir() if q.suffix.lower() in (".toml", ".csv") and q.is_file())
        if not files:
            raise InputError("no *.toml or *.csv job list in this folder", str(p))
    elif p.is_file():
        files = [p]
    else:
        raise InputError("job list not found (a .toml or .csv file, or a folder of them)", str(p))
    jobs: list[Job] = []
    for f in files:
        if f.suffix.lower() == ".toml":
            jobs += _read_toml(f)
        elif f.suffix.lower() == ".csv":
            jobs += _read_csv(f)
        else:
            raise InputError("expected a .toml or .csv job list", str(f))
    if not jobs:
        raise InputError("the job list holds no job", str(p))
    seen_names: dict[str, str] = {}
    seen_outs: dict[str, str] = {}
    for j in jobs:
        if j.name in seen_names:
            raise InputError(f"{j.source}: name: {j.name!r} is also the name of {seen_names[j.name]}")
        if j.out in seen_outs:
            raise InputError(f"{j.source}: out: {j.out} is also the output of {seen_outs[j.out]}")
        seen_names[j.name] = j.source
        seen_outs[j.out] = j.source
    return jobs


__all__ = ["JOB_KEYS", "JOB_MODES", "Job", "read_jobs"]
