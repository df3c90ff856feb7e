"""The key tables of RTKLIB configuration files that :mod:`robustrtk.pipeline.rtklib_conf`
maps: enumerated values, on/off options, ``pos1-navsys`` bits, and the keys whose values
robustrtk follows anyway or that have no effect here."""

from __future__ import annotations

__all__ = ["ENUMS", "FREQS", "NAVSYS_BITS", "NO_EFFECT", "ONOFF", "ONOFF_KEYS", "SAME_AS_OURS"]


#: Enumerated RTKLIB options: the names in the order of their numbers.
ENUMS: dict[str, tuple[str, ...]] = {
    "pos1-posmode": (
        "single",
        "dgps",
        "kinematic",
        "static",
        "static-start",
        "movingbase",
        "fixed",
        "ppp-kine",
        "ppp-static",
        "ppp-fixed",
    ),  # fmt: skip
    "pos1-frequency": ("", "l1", "l1+l2", "l1+l2+l5", "l1+l2+l5+l6"),
    "pos1-soltype": ("forward", "backward", "combined", "combined-nophasereset"),
    "pos1-tidecorr": ("off", "on", "otl"),
    "pos1-ionoopt": ("off", "brdc", "sbas", "dual-freq", "est-stec", "ionex-tec", "qzs-brdc"),
    "pos1-tropopt": ("off", "saas", "sbas", "est-ztd", "est-ztdgrad"),
    "pos1-sateph": ("brdc", "precise", "brdc+sbas", "brdc+ssrapc", "brdc+ssrcom"),
    "pos1-posopt3": ("off", "on", "precise"),
    "pos2-armode": ("off", "continuous", "instantaneous", "fix-and-hold"),
    "pos2-gloarmode": ("off", "on", "autocal", "fix-and-hold"),
    "out-solformat": ("llh", "xyz", "enu", "nmea"),
    "out-timesys": ("gpst", "utc", "jst"),
    "out-timeform": ("tow", "hms"),
    "out-degform": ("deg", "dms"),
    "out-height": ("ellipsoidal", "geodetic"),
    "out-geoid": ("internal", "egm96", "egm08_2.5", "egm08_1", "gsi2000"),
    "out-solstatic": ("all", "single"),
    "out-outstat": ("off", "state", "residual"),
    "ant1-postype": ("llh", "xyz", "single", "posfile", "rinexhead", "rtcm"),
    "ant2-postype": ("llh", "xyz", "single", "posfile", "rinexhead", "rtcm"),
}
#: The values of RTKLIB's on/off options ...
ONOFF = ("off", "on")
#: ... and the options that take them.
ONOFF_KEYS = (
    "pos1-snrmask_r", "pos1-snrmask_b", "pos1-dynamics", "pos1-posopt1", "pos1-posopt2", "pos1-posopt4",
    "pos1-posopt5", "pos1-posopt6", "pos2-bdsarmode", "pos2-arfilter", "pos2-syncsol", "out-outhead",
    "out-outopt", "out-outvel", "out-outsingle", "ant2-initrst", "misc-timeinterp",
)  # fmt: skip
#: ``pos1-navsys`` bits and the system letters.
NAVSYS_BITS = ((1, "G"), (4, "R"), (8, "E"), (32, "C"), (16, "J"), (2, "S"), (64, "I"))
#: ``pos1-frequency`` names and robustrtk's ``freqs`` (L6 is not used).
FREQS = {"l1": "L1", "l1+l2": "L1+L2", "l1+l2+l5": "L1+L2+L5", "l1+l2+l5+l6": "L1+L2+L5"}

#: Keys whose value is what robustrtk does anyway (else they are ignored, with the reason).
SAME_AS_OURS: dict[str, tuple[str, str]] = {
    "pos1-soltype": ("forward", "the filter runs forward only in RTK"),
    "pos1-tidecorr": ("off", "no tide corrections"),
    "pos1-sateph": ("brdc", "broadcast ephemerides only"),
    "pos1-posopt1": ("off", "no satellite antenna model"),
    "pos1-posopt2": ("off", "no receiver antenna model"),
    "pos1-posopt3": ("off", "no phase wind-up correction"),
    "pos1-posopt4": ("off", "no eclipse exclusion"),
    "pos1-posopt5": ("off", "no RAIM FDE in RTK"),
    "pos1-posopt6": ("off", "no handover of satellites"),
    "pos1-exclsats": ("", "no per-satellite exclusion setting"),
    "pos2-baselen": ("0", "no baseline-length constraint"),
    "pos2-basesig": ("0", "no baseline-length constraint"),
    "stats-errphasebl": ("0", "no baseline-length term in the variance"),
    "stats-errsnr": ("0", "no SNR term in the DD variance"),
    "stats-errrcv": ("0", "no receiver-noise term"),
    "stats-prnpos": ("0", "no position process noise setting for kinematic RTK"),
    "out-solformat": ("llh", ".pos output is latitude/longitude/height"),
    "out-outhead": ("on", ".pos output has a header"),
    "out-outopt": ("on", ".pos output has a header"),
    "out-outvel": ("off", ".pos output carries no velocity"),
    "out-timesys": ("gpst", ".pos output is in GPST"),
    "out-timeform": ("hms", ".pos times are calendar times"),
    "out-timendec": ("3", ".pos times have 3 decimals"),
    "out-degform": ("deg", ".pos angles are in degrees"),
    "out-fieldsep": ("", ".pos fields are separated by spaces"),
    "out-outsingle": ("off", "no single solution output on AR failure"),
    "out-maxsolstd": ("0", "no solution standard-deviation cut-off"),
    "out-height": ("ellipsoidal", ".pos heights are ellipsoidal"),
    "out-geoid": ("internal", "heights are ellipsoidal (no geoid)"),
    "out-solstatic": ("all", "every epoch is written"),
    "out-nmeaintv1": ("0", "NMEA is written per epoch"),
    "out-nmeaintv2": ("0", "NMEA is written per epoch"),
    "out-outstat": ("off", "solver statistics go to --diagnostics"),
    "ant1-anttype": ("", "no antenna models"),
    "ant1-antdele": ("0", "no rover antenna offset"),
    "ant1-antdeln": ("0", "no rover antenna offset"),
    "ant1-antdelu": ("0", "no rover antenna offset"),
    "ant2-anttype": ("", "no antenna models"),
    "ant2-antdele": ("0", "no base antenna offset"),
    "ant2-antdeln": ("0", "no base antenna offset"),
    "ant2-antdelu": ("0", "no base antenna offset"),
    "misc-sbasatsel": ("0", "no SBAS selection"),
    "misc-rnxopt1": ("", "no RINEX reader options"),
    "misc-rnxopt2": ("", "no RINEX reader options"),
    "misc-pppopt": ("", "no PPP"),
}
#: Keys that name no file or have no effect in the modes robustrtk runs (rover position
#: options act only in RTKLIB's fixed and PPP-fixed modes, refused here).
NO_EFFECT = ("ant1-postype", "ant1-pos1", "ant1-pos2", "ant1-pos3")
