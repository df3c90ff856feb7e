"""Bit fields and checksums of binary GNSS streams (UBX, RTCM 3, navigation words).

* :func:`getbitu` / :func:`getbits` read an unsigned / two's-complement field of ``n`` bits
  starting at bit ``pos`` (bit 0 = most significant bit of byte 0), as RTCM 10403.3 and the
  navigation-message ICDs number them.
* :func:`getbitg` reads a sign-magnitude field (GLONASS ICD 4.4: the most significant bit is
  the sign).
* :func:`crc24q` is the CRC-24Q of RTCM 10403.3 section 4 (generator ``0x1864CFB``, initial
  value 0), :func:`fletcher8` the 8-bit Fletcher checksum of a UBX frame (u-blox M8 receiver
  description, "UBX checksum").
"""

from __future__ import annotations

from itertools import accumulate

__all__ = ["crc24q", "fletcher8", "getbitg", "getbits", "getbitu"]


def getbitu(buf: bytes, pos: int, n: int) -> int:
    """Unsigned field of ``n`` bits at bit ``pos`` (MSB first).

    Raises
    ------
    IndexError
        The field runs past the end of ``buf``.
    """
    if n == 0:
        return 0
    end = pos + n
    if end > 8 * len(buf) or pos < 0:
        raise IndexError(f"bit field {pos}+{n} beyond {8 * len(buf)} bits")
    first = pos >> 3
    last = (end - 1) >> 3
    v = int.from_bytes(buf[first : last + 1], "big")
    return (v >> (8 * (last + 1) - end)) & ((1 << n) - 1)


def getbits(buf: bytes, pos: int, n: int) -> int:
    """Two's-complement signed field of ``n`` bits at bit ``pos``."""
    v = getbitu(buf, pos, n)
    return v - (1 << n) if v >> (n - 1) else v


def getbitg(buf: bytes, pos: int, n: int) -> int:
    """Sign-magnitude field of ``n`` bits at bit ``pos`` (sign bit first, 1 = negative)."""
    v = getbitu(buf, pos + 1, n - 1)
    return -v if getbitu(buf, pos, 1) else v


def _crc24q_table() -> list[int]:
    table = []
    for i in range(256):
        c = i << 16
        for _ in range(8):
            c <<= 1
            if c & 0x1000000:
                c ^= 0x1864CFB
        table.append(c & 0xFFFFFF)
    return table


_CRC24Q = _crc24q_table()


def crc24q(data: bytes) -> int:
    """CRC-24Q of ``data`` (RTCM 10403.3 section 4.2; generator polynomial ``0x1864CFB``)."""
    crc = 0
    t = _CRC24Q
    for b in data:
        crc = ((crc << 8) & 0xFFFFFF) ^ t[(crc >> 16) ^ b]
    return crc


def fletcher8(data: bytes) -> tuple[int, int]:
    """UBX checksum ``(CK_A, CK_B)`` over ``data`` (class, id, length and payload).

    ``CK_A = sum(b_i)`` and ``CK_B = sum((n - i) b_i)`` modulo 256, the closed form of the
    running sums of the u-blox receiver description.
    """
    a = sum(data) & 0xFF
    b = sum(accumulate(data)) & 0xFF  # the sum of the running sums: sum((n - i) b_i)
    return a, b
