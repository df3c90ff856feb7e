"""RTKLIB configuration files (``rnx2rtkp``/``rtkpost`` ``.conf``) as robustrtk settings.

:func:`read_rtklib_conf` reads ``key = value  # comment`` lines and maps the common
``pos1-*``, ``pos2-*``, ``stats-*``, ``ant2-*`` and ``out-*`` options to flat
:data:`~robustrtk.pipeline.config.LEAVES` keys (``Config.of(**conf.settings)``), plus the
base position, which ``solve`` takes as ``--base-pos``. Every key of the file ends up in
exactly one of two lists:

* ``used``: mapped to a setting, or its value is what robustrtk does anyway (``out-*`` keys
  that describe the ``.pos`` that ``solve`` writes, ``pos1-sateph = brdc``, empty file
  names, zero antenna offsets ...);
* ``ignored``: no equivalent here (each with the reason), so that nothing in the file is
  silently dropped.

Enumerated values are accepted by name or by number, as RTKLIB does. The mapping:

==========================  =====================================================
RTKLIB                      robustrtk
==========================  =====================================================
pos1-posmode                ``mode``: single → spp, dgps → dgnss, kinematic, static,
                            static-start, movingbase → rtk (``dynamics`` kinematic,
                            static, auto, kinematic + ``base_position`` moving);
                            fixed and ppp-* are refused
pos1-dynamics               kinematic rtk: on → ``kinematic_model`` constant-velocity,
                            off → random-walk
pos1-frequency              ``freqs`` (L1, L1+L2, L1+L2+L5)
pos1-elmask                 ``elev_mask_deg``
pos1-navsys                 ``systems`` (bits 1 G, 2 S, 4 R, 8 E, 16 J, 32 C, 64 I)
pos2-gloarmode              ``glonass_ar``: off, autocal → off (float GLONASS, with a
                            note for autocal); on, fix-and-hold → auto (fixed when both
                            receivers are of one make, with a note)
pos1-snrmask_r/_b, _L*      ``snr_mask_dbhz`` (the lowest value of the bins of the
                            frequencies used; one mask for both receivers)
pos1-tropopt, pos1-ionoopt  ``tropo`` (off, saas), ``iono`` (off, brdc; spp)
pos2-armode                 off → ``ar`` off; continuous → ``hold`` false;
                            instantaneous → ``instantaneous``; fix-and-hold → ``hold``
pos2-arthres                ``ratio`` (arthresmin/max honoured when equal to it)
pos2-arlockcnt              ``ar_lock_epochs``
pos2-arelmask               ``ar_elev_mask_deg``
pos2-elmaskhold             honoured when ≤ arelmask (only fixed ambiguities are held)
pos2-arminfix               ``hold_min_fix``
pos2-varholdamb             ``hold_sigma_cyc`` = √varholdamb
pos2-slipthres, dopthres    ``slip`` lli+gf (+doppler when dopthres > 0),
                            ``gf_threshold_m``, ``doppler_threshold_cyc``
stats-errphase, errphaseel  ``phase_sigma_m`` = √(a² + b²) (zenith σ) and
                            ``weighting`` elevation
stats-eratio1               ``code_sigma_m`` = eratio1 × ``phase_sigma_m``
stats-prnaccelh             ``sigma_acc_m_s2`` (kinematic rtk with dynamics on)
pos2-maxage                 ``max_age_s``
stats-clkstab               ``sigma_age_m_s`` = c × clkstab (dgnss, rtk)
ant2-postype, ant2-pos1..3  base position (llh: deg, deg, m ellipsoidal; xyz: ECEF m);
                            rinexhead: the header position (``solve``'s default);
                            single: ``base_position`` moving (the base's own SPP at
                            each epoch)
==========================  =====================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robustrtk.errors import InputError
from robustrtk.io.rinex_file import check_regular_file
from robustrtk.pipeline.rtklib_keys import (
    ENUMS,
    FREQS,
    NAVSYS_BITS,
    NO_EFFECT,
    ONOFF,
    ONOFF_KEYS,
    SAME_AS_OURS,
)

if TYPE_CHECKING:  # numpy and the frames are imported where a base position is read (start-up time)
    from robustrtk.core import FloatArray

__all__ = ["ENUMS", "RtklibConf", "parse_rtklib_conf", "read_rtklib_conf"]


@dataclass(frozen=True)
class RtklibConf:
    """An RTKLIB configuration file mapped to robustrtk settings.

    Attributes
    ----------
    path : str
    mode : str
        ``spp``, ``dgnss`` or ``rtk``.
    settings : dict
        Flat settings (:data:`~robustrtk.pipeline.config.LEAVES` keys), ``mode`` included.
    sources : dict
        For each key of ``settings``, the RTKLIB keys it came from (``"pos2-arthres"``).
    base_pos_m : ndarray, shape (3,), or None
        Base ECEF position (m) from ``ant2-*``; None for ``rinexhead`` or when not given.
    used : tuple of str
        RTKLIB keys read (mapped, or their value is robustrtk's behaviour).
    ignored : tuple of str
        RTKLIB keys ignored, each as ``"key (reason)"``.
    notes : tuple of str
        Keys read only in part (``"pos2-gloarmode: autocal is not supported ..."``).
    """

    path: str
    mode: str
    settings: dict[str, Any]
    sources: dict[str, str]
    base_pos_m: FloatArray | None
    used: tuple[str, ...] = ()
    ignored: tuple[str, ...] = field(default_factory=tuple)
    notes: tuple[str, ...] = ()

    @property
    def ignored_keys(self) -> tuple[str, ...]:
        """The RTKLIB keys of :attr:`ignored` without their reasons."""
        return tuple(s.split(" ", 1)[0] for s in self.ignored)

    def ignored_text(self) -> str:
        """The ignored keys grouped by reason: ``"reason: key, key; reason: key"``."""
        by_why: dict[str, list[str]] = {}
        for item in self.ignored:
            key, why = item.split(" ", 1)
            by_why.setdefault(why.strip("()"), []).append(key)
        return "; ".join(f"{why}: {', '.join(keys)}" for why, keys in by_why.items())

    def base_pos_text(self) -> str | None:
        """The base position as ``--base-pos`` takes it (``"X,Y,Z"``), or None."""
        if self.base_pos_m is None:
            return None
        return ",".join(f"{v:.4f}" for v in self.base_pos_m)


def _split_line(raw: str) -> tuple[str, str] | None:
    text = raw.strip()
    if not text or text.startswith("#") or "=" not in text:
        return None
    key, val = text.split("=", 1)
    if "#" in val:
        val = val.split("#", 1)[0]
    return key.strip(), val.strip()


def parse_rtklib_conf(text: str, source: str = "rtklib conf") -> RtklibConf:
    """Map the text of an RTKLIB ``.conf`` (see the module docstring).

    Raises
    ------
    InputError
        A bad value (file and line named) or a positioning mode robustrtk does not run.
    """
    raw: dict[str, tuple[str, int]] = {}
    for ln, line in enumerate(text.splitlines(), start=1):
        kv = _split_line(line)
        if kv is not None:
            raw[kv[0]] = (kv[1], ln)
    return _Mapper(raw, source).run()


def read_rtklib_conf(path: str | Path) -> RtklibConf:
    """Read and map an RTKLIB ``.conf`` file (see :func:`parse_rtklib_conf`)."""
    p = Path(path)
    check_regular_file(str(p))
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise InputError("file not found", str(p)) from None
    except IsADirectoryError:
        raise InputError("expected an RTKLIB .conf file, got a directory", str(p)) from None
    return parse_rtklib_conf(data.decode("utf-8", errors="replace"), str(p))


class _Mapper:
    """One pass over the keys of a file: settings, used and ignored keys."""

    def __init__(self, raw: dict[str, tuple[str, int]], source: str) -> None:
        self.raw = raw
        self.source = source
        self.settings: dict[str, Any] = {}
        self.sources: dict[str, str] = {}
        self.used: list[str] = []
        self.ignored: dict[str, str] = {}
        self.base_pos: FloatArray | None = None
        self.notes: list[str] = []

    # ------------------------------------------------------------------ values
    def has(self, key: str) -> bool:
        return key in self.raw

    def text(self, key: str) -> str:
        return self.raw[key][0]

    def error(self, key: str, what: str) -> InputError:
        return InputError(f"{key}: {what}, got {self.text(key)!r}", self.source, self.raw[key][1])

    def enum(self, key: str, default: str | None = None) -> str | None:
        if key not in self.raw:
            return default
        names = ENUMS.get(key, ONOFF)
        v = self.text(key).lower()
        if v and v in names:
            return v
        try:
            k = int(v)
        except ValueError:
            raise self.error(key, f"expected one of {', '.join(n for n in names if n)}") from None
        if not 0 <= k < len(names) or not names[k]:
            raise self.error(key, f"expected one of {', '.join(n for n in names if n)}")
        return names[k]

    def number(self, key: str, default: float | None = None) -> float | None:
        if key not in self.raw:
            return default
        try:
            v = float(self.text(key))
        except ValueError:
            raise self.error(key, "expected a number") from None
        if not math.isfinite(v):
            raise self.error(key, "expected a finite number")
        return v

    def numbers(self, key: str) -> list[float]:
        try:
            return [float(t) for t in self.text(key).replace(",", " ").split()]
        except ValueError:
            raise self.error(key, "expected numbers separated by commas") from None

    # ------------------------------------------------------------------ records
    def set(self, flat: str, value: Any, *keys: str) -> None:
        self.settings[flat] = value
        self.sources[flat] = ", ".join(k for k in keys if self.has(k)) or keys[0]
        self.use(*keys)

    def use(self, *keys: str) -> None:
        self.used += [k for k in keys if self.has(k) and k not in self.used]

    def ignore(self, key: str, why: str) -> None:
        if self.has(key) and key not in self.used:
            self.ignored[key] = why

    # ------------------------------------------------------------------ the mapping
    def run(self) -> RtklibConf:
        mode = self.posmode()
        self.frequencies_and_systems(mode)
        self.masks()
        self.models(mode)
        if mode == "rtk":
            self.ambiguity_resolution()
        else:
            for key in self.raw:
                if key.startswith(
                    (
                        "pos2-ar",
                        "pos2-gloar",
                        "pos2-bdsar",
                        "pos2-elmaskhold",
                        "pos2-varholdamb",
                        "pos2-gainholdamb",
                        "pos2-minfix",
                        "pos2-minhold",
                        "pos2-slip",
                    )
                ):
                    self.ignore(key, f"no ambiguity resolution in {mode}")
        self.noise(mode)
        self.base_age(mode)
        self.clock_stability(mode)
        self.base_position(mode)
        for key, (want, why) in SAME_AS_OURS.items():
            if self.has(key):
                if self.text(key).lower() == want or (want == "0" and self._is_zero(key)):
                    self.use(key)
                elif (key in ENUMS or key in ONOFF_KEYS) and self.enum(key) == want:
                    self.use(key)
                else:
                    self.ignore(key, why)
        self.use(*(k for k in NO_EFFECT if self.has(k)))
        for key in self.raw:
            if key.startswith("file-") and not self.text(key):
                self.use(key)
        for key in self.raw:
            if key not in self.used and key not in self.ignored:
                self.ignored[key] = "no equivalent setting"
        return RtklibConf(
            path=self.source, mode=mode, settings=dict(self.settings), sources=dict(self.sources),
            base_pos_m=self.base_pos, used=tuple(self.used),
            ignored=tuple(f"{k} ({why})" for k, why in self.ignored.items()), notes=tuple(self.notes),
        )  # fmt: skip

    def _is_zero(self, key: str) -> bool:
        try:
            return float(self.text(key)) == 0.0
        except ValueError:
            return False

    def posmode(self) -> str:
        pm = self.enum("pos1-posmode", "kinematic")
        dyn = self.enum("pos1-dynamics", "off")
        if pm in ("fixed", "ppp-kine", "ppp-static", "ppp-fixed"):
            raise self.error(
                "pos1-posmode", "expected single, dgps, kinematic, static, static-start or movingbase"
            )
        mode = {"single": "spp", "dgps": "dgnss"}.get(str(pm), "rtk")
        self.set("mode", mode, "pos1-posmode")
        if mode != "rtk":
            self.ignore("pos1-dynamics", f"no effect in RTKLIB's {pm} mode")
            return mode
        dynamics = {"static": "static", "static-start": "auto"}.get(str(pm), "kinematic")
        self.set("dynamics", dynamics, "pos1-posmode")
        if pm == "movingbase":
            self.set("base_position", "moving", "pos1-posmode")
        if dynamics == "kinematic":
            model = "constant-velocity" if dyn == "on" else "random-walk"
            self.set("kinematic_model", model, "pos1-dynamics")
            if dyn == "on" and self.has("stats-prnaccelh"):
                self.set("sigma_acc_m_s2", self.number("stats-prnaccelh"), "stats-prnaccelh")
            else:
                self.ignore("stats-prnaccelh", "acts only with pos1-dynamics on")
        else:
            self.use("pos1-dynamics")
        return mode

    def frequencies_and_systems(self, mode: str) -> None:
        if self.has("pos1-frequency"):
            f = str(self.enum("pos1-frequency"))
            if mode == "spp":
                self.ignore("pos1-frequency", "SPP uses its own signals")
            else:
                self.set("freqs", FREQS[f], "pos1-frequency")
                if f.endswith("l6"):
                    self.used.remove("pos1-frequency")
                    self.ignored["pos1-frequency"] = "L6 is not supported; L1+L2+L5 used"
        if self.has("pos1-navsys"):
            v = self.number("pos1-navsys")
            assert v is not None
            bits = int(v)
            if bits != v or not 0 < bits < 128:
                raise self.error("pos1-navsys", "expected a sum of system bits 1..64")
            letters = "".join(s for b, s in NAVSYS_BITS if bits & b)
            self.set("systems", letters, "pos1-navsys")

    def masks(self) -> None:
        if self.has("pos1-elmask"):
            self.set("elev_mask_deg", self.number("pos1-elmask"), "pos1-elmask")
        bins = [k for k in ("pos1-snrmask_L1", "pos1-snrmask_L2", "pos1-snrmask_L5") if self.has(k)]
        on = [k for k in ("pos1-snrmask_r", "pos1-snrmask_b") if self.has(k) and self.enum(k) == "on"]
        if not on:
            if self.has("pos1-snrmask_r") or self.has("pos1-snrmask_b"):
                self.set("snr_mask_dbhz", 0.0, "pos1-snrmask_r", "pos1-snrmask_b")
                self.use(*bins)
            return
        nf = {"L1": 1, "L1+L2": 2, "L1+L2+L5": 3}.get(str(self.settings.get("freqs", "L1+L2")), 2)
        vals = [v for k in bins[:nf] for v in self.numbers(k)]
        if vals:
            self.set("snr_mask_dbhz", float(min(vals)), "pos1-snrmask_r", "pos1-snrmask_b", *bins[:nf])
        self.use(*bins)

    def models(self, mode: str) -> None:
        if self.has("pos1-tropopt"):
            t = self.enum("pos1-tropopt")
            if t in ("off", "saas"):
                self.set("tropo", "off" if t == "off" else "saastamoinen", "pos1-tropopt")
            else:
                self.ignore("pos1-tropopt", f"{t} is not supported (off, saas)")
        if self.has("pos1-ionoopt"):
            i = self.enum("pos1-ionoopt")
            if mode != "spp" and i in ("off", "brdc"):
                self.use("pos1-ionoopt")  # short-baseline DD: the ionosphere cancels
            elif mode == "spp" and i in ("off", "brdc"):
                self.set("iono", "off" if i == "off" else "klobuchar", "pos1-ionoopt")
            else:
                self.ignore("pos1-ionoopt", f"{i} is not supported (off, brdc)")

    def ambiguity_resolution(self) -> None:
        am = self.enum("pos2-armode")
        if am is not None:
            if am == "off":
                self.set("ar", "off", "pos2-armode")
            elif am == "instantaneous":
                self.set("instantaneous", True, "pos2-armode")
            else:
                self.set("instantaneous", False, "pos2-armode")
                self.set("hold", am == "fix-and-hold", "pos2-armode")
        gm = self.enum("pos2-gloarmode")
        if gm is not None:
            # fix-and-hold holds the GLONASS integers with the others; autocal (inter-channel
            # bias estimation) is not done here: GLONASS stays float. RTKLIB's on asserts that
            # the inter-channel biases cancel; integers fixed against a receiver of another
            # make are wrong by them, so the receivers' makes decide (auto; algorithms.md § 37)
            self.set("glonass_ar", "off" if gm in ("off", "autocal") else "auto", "pos2-gloarmode")
            if gm == "autocal":
                self.notes.append("pos2-gloarmode: autocal is not supported; GLONASS ambiguities stay float")
            elif gm != "off" and int(self.number("pos1-navsys") or 0) & 4:
                self.notes.append(
                    f"pos2-gloarmode: {gm} read as auto (GLONASS fixed when both receivers are of one make; "
                    "glonass_ar = on to force)"
                )
        ratio = self.number("pos2-arthres")
        if ratio is not None:
            self.set("ratio", ratio, "pos2-arthres")
            for k in ("pos2-arthresmin", "pos2-arthresmax"):
                if self.number(k) == ratio:
                    self.use(k)
                else:
                    self.ignore(k, "no adaptive ratio threshold")
        if self.has("pos2-arlockcnt"):
            self.set("ar_lock_epochs", int(self.number("pos2-arlockcnt") or 0), "pos2-arlockcnt")
        arel = self.number("pos2-arelmask")
        if arel is not None:
            self.set("ar_elev_mask_deg", arel, "pos2-arelmask")
        hold_el = self.number("pos2-elmaskhold")
        if hold_el is not None:
            if hold_el <= (arel if arel is not None else 0.0):
                self.use("pos2-elmaskhold")  # only ambiguities above arelmask are fixed and held
            else:
                self.ignore("pos2-elmaskhold", "no hold mask above the AR mask (pos2-arelmask)")
        if self.has("pos2-arminfix") and am == "fix-and-hold":
            self.set("hold_min_fix", int(self.number("pos2-arminfix") or 0), "pos2-arminfix")
        var = self.number("pos2-varholdamb")
        if var is not None and am == "fix-and-hold" and var > 0:
            self.set("hold_sigma_cyc", math.sqrt(var), "pos2-varholdamb")
        slip = self.number("pos2-slipthres")
        dop = self.number("pos2-dopthres", 0.0)
        if slip is not None and slip > 0:
            self.set("slip", "lli+gf" + ("+doppler" if dop else ""), "pos2-slipthres", "pos2-dopthres")
            self.set("gf_threshold_m", slip, "pos2-slipthres")
            if dop:
                self.set("doppler_threshold_cyc", dop, "pos2-dopthres")

    def noise(self, mode: str) -> None:
        a = self.number("stats-errphase")
        b = self.number("stats-errphaseel")
        if a is None and b is None:
            return
        sigma = math.hypot(a or 0.0, b or 0.0)
        if not sigma > 0:
            raise self.error("stats-errphase", "expected a positive phase error")
        if mode != "spp":  # SPP weights by elevation (and C/N0) in its own model
            self.set("weighting", "elevation", "stats-errphase", "stats-errphaseel")
        if mode == "rtk":
            self.set("phase_sigma_m", sigma, "stats-errphase", "stats-errphaseel")
        else:
            self.use("stats-errphase", "stats-errphaseel")
        ratio = self.number("stats-eratio1")
        if ratio is not None:
            self.set("code_sigma_m", ratio * sigma, "stats-eratio1", "stats-errphase", "stats-errphaseel")
            for k in ("stats-eratio2", "stats-eratio5"):
                if self.number(k) == ratio:
                    self.use(k)
                else:
                    self.ignore(k, "one code/phase error ratio for every frequency")

    def base_age(self, mode: str) -> None:
        age = self.number("pos2-maxage")
        if age is None:
            return
        if mode == "spp":
            self.ignore("pos2-maxage", "no base in spp")
            return
        if not (age >= 0 and math.isfinite(age)):
            raise self.error("pos2-maxage", "expected seconds >= 0")
        self.set("max_age_s", age, "pos2-maxage")

    def clock_stability(self, mode: str) -> None:
        stab = self.number("stats-clkstab")
        if stab is None:
            return
        if mode == "spp":
            self.ignore("stats-clkstab", "no base in spp")
            return
        if not stab >= 0:
            raise self.error("stats-clkstab", "expected a stability >= 0 (s/s)")
        self.set("sigma_age_m_s", stab * 299_792_458.0, "stats-clkstab")

    def base_position(self, mode: str) -> None:
        pt = self.enum("ant2-postype")
        if pt is None:
            return
        pos_keys = ("ant2-pos1", "ant2-pos2", "ant2-pos3")
        if mode == "spp":
            for k in ("ant2-postype", *pos_keys):
                self.ignore(k, "no base in SPP")
            return
        if self.settings.get("base_position") == "moving":
            self.use("ant2-postype", *pos_keys)
            return
        if pt == "rinexhead":
            self.use("ant2-postype", *pos_keys)
            return
        if pt == "single":  # RTKLIB: the base's own single-point solution at each epoch
            self.set("base_position", "moving", "ant2-postype")
            self.use(*pos_keys)
            return
        if pt not in ("llh", "xyz"):
            for k in ("ant2-postype", *pos_keys):
                self.ignore(k, f"base position type {pt} is not supported (llh, xyz, rinexhead, single)")
            return
        vals = [self.number(k) for k in pos_keys]
        if any(v is None for v in vals):
            raise self.error("ant2-postype", "expected ant2-pos1, ant2-pos2 and ant2-pos3 with it")
        v1, v2, v3 = (float(v) for v in vals if v is not None)
        import numpy as np

        from robustrtk.geometry.frames import geodetic2ecef_deg

        if pt == "xyz":
            pos = np.array([v1, v2, v3])
        else:
            if not (-90.0 <= v1 <= 90.0 and -180.0 <= v2 <= 360.0):
                raise self.error("ant2-pos1", "expected latitude and longitude in degrees")
            pos = np.asarray(geodetic2ecef_deg(v1, v2, v3), dtype=float).reshape(3)
        self.base_pos = pos
        self.use("ant2-postype", *pos_keys)
