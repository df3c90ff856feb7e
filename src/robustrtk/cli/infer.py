"""What ``solve`` infers when the user does not say: the mode of a run with a base.

With ``--base`` and no mode (flag, TOML file or RTKLIB ``.conf``), the run is relative:
``rtk`` when both receivers record carrier phase, ``dgnss`` when either records code only.
A RINEX file says what it records in its header (``# / TYPES OF OBSERV`` in version 2,
``SYS / # / OBS TYPES`` in version 3 and 4: an ``L`` type is carrier phase); receiver logs
(UBX ``RXM-RAWX``, RTCM 3 MSM, phone logs) carry phase by their format.
"""

from __future__ import annotations

import os

from robustrtk.io.readers import HEAD_BYTES, detect_format, read_head

__all__ = ["has_phase", "infer_gnss_mode"]


def _rinex_types(head: bytes) -> list[str] | None:
    """Observation types listed in a RINEX observation header (None when none is found)."""
    types: list[str] = []
    found = False
    for raw in head.split(b"\n"):
        line = raw.decode("ascii", "replace")
        label = line[60:].strip()
        if label == "# / TYPES OF OBSERV":
            found = True
            types += line[6:60].split() if line[:6].strip() else line[6:60].split()
        elif label == "SYS / # / OBS TYPES":
            found = True
            types += line[7:60].split()
        elif label == "END OF HEADER":
            break
    return types if found else None


def has_phase(path: str | os.PathLike[str]) -> bool:
    """Whether an observation file records carrier phase (see the module docstring).

    A RINEX header without any ``L`` type: False; a RINEX header the first
    :data:`~robustrtk.io.readers.HEAD_BYTES` do not end: judged on the types seen. Receiver
    logs: True. An unreadable file: True (the reader names the problem when it reads it).
    """
    try:
        fmt = detect_format(path)
    except Exception:  # the reader names the problem in its own words later
        return True
    if fmt != "rinex_obs":
        return True
    types = _rinex_types(read_head(path, HEAD_BYTES))
    if types is None:
        return True
    return any(t.startswith("L") for t in types)


def infer_gnss_mode(rover: str | os.PathLike[str], base: str | os.PathLike[str]) -> tuple[str, str]:
    """The mode of a RINEX run given a base and no mode, and the one-line reason.

    Returns
    -------
    mode : {"rtk", "dgnss"}
    reason : str
        What was seen (for the notice and the summary).
    """
    no_phase = [str(p) for p in (rover, base) if not has_phase(p)]
    if not no_phase:
        return "rtk", "--base given and both receivers record carrier phase (--mode dgnss for code only)"
    return "dgnss", f"--base given and {', '.join(no_phase)} records no carrier phase"
