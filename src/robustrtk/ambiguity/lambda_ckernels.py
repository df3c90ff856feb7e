"""LAMBDA kernels in C (``_lambda_c.c``, loaded with ctypes): the compiled twin of
:mod:`robustrtk.ambiguity.lambda_pure`.

The LᵀDL factorisation, the reduction, the search and the whole integer least squares of the
pure references, computed by a small C99 library compiled when the package is installed
(``setup.py``; optional: without a compiler the pure references serve). The C code does the
references' arithmetic operation for operation, in the same order, without contraction into
fused multiply-adds and with half-to-even rounding, so the reduction and the search give
bit-identical results to the pure references (tests/ambiguity/test_lambda_ckernels.py;
algorithms.md §22).

The library costs nothing to start (about a millisecond to load and a megabyte of memory),
so :func:`robustrtk.ambiguity.lambda_.kernels` takes it from the first call.

Importing this module raises ImportError when the library was not built.

Error codes: ``OK = 0``, ``NOT_PD = 1``, ``SEARCH_LIMIT = 2``,
``NONFINITE_A = 3``, ``NONFINITE_Q = 4``, ``ASYMMETRIC_Q = 5``; and ``NO_MEMORY = 6`` (the C
library could not allocate its work arrays; the wrappers raise :class:`MemoryError`) and
``BAD_OPS = 7`` (operation rows that do not index the vector), ``BAD_SIZE = 8`` (a search
with no ambiguity or no candidate), both :class:`ValueError`.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

OK = 0
NOT_PD = 1
SEARCH_LIMIT = 2
NONFINITE_A = 3
NONFINITE_Q = 4
ASYMMETRIC_Q = 5
NO_MEMORY = 6
BAD_OPS = 7
BAD_SIZE = 8

#: Tolerance that prevents endless swapping in the reduction (as in ``lambda_pure``; the C code
#: holds the same constant).
SWAP_TOL = 1e-6

#: ABI version the wrappers below expect of the library (``rrtk_version()``).
ABI_VERSION = 1


def library_path() -> Path:
    """The built library next to this module (``_lambda_c*.so`` / ``.pyd`` / ``.dylib``).

    Raises
    ------
    ImportError
        No built library is there.
    """
    here = Path(__file__).resolve().parent
    for pattern in ("_lambda_c*.so", "_lambda_c*.pyd", "_lambda_c*.dylib"):
        found = sorted(here.glob(pattern))
        if found:
            return found[0]
    raise ImportError(f"the C LAMBDA kernels are not built (no _lambda_c*.so/.pyd in {here})")


def _load() -> ctypes.CDLL:
    path = library_path()
    try:
        lib = ctypes.CDLL(str(path))
    except OSError as err:
        raise ImportError(f"cannot load the C LAMBDA kernels {path}: {err}") from err
    i64, ptr = ctypes.c_int64, ctypes.c_void_p
    sigs: dict[str, list[type]] = {
        "rrtk_version": [],
        "rrtk_ltdl": [i64, ptr, ptr, ptr],
        "rrtk_reduce": [i64, ptr, ptr, i64, ptr, ptr, ptr],
        "rrtk_search": [i64, ptr, ptr, ptr, i64, i64, ptr, ptr],
        "rrtk_apply_zt": [i64, i64, ptr, ptr],
        "rrtk_apply_zinvt": [i64, i64, ptr, i64, ptr],
        "rrtk_ils_from_reduced": [i64, ptr, i64, ptr, ptr, ptr, i64, i64, ptr, ptr],
        "rrtk_ils": [i64, ptr, ptr, i64, i64, ptr, ptr, ptr],
        "rrtk_lambda_all": [i64, ptr, ptr, i64, i64, ptr, ptr],
    }
    try:
        for name, argtypes in sigs.items():
            fn = getattr(lib, name)
            fn.argtypes = argtypes
            fn.restype = i64
    except AttributeError as err:
        raise ImportError(f"{path} is not the C LAMBDA kernels library: {err}") from err
    version = lib.rrtk_version()
    if version != ABI_VERSION:
        raise ImportError(f"{path}: library version {version}, expected {ABI_VERSION} (rebuild it)")
    return lib


_LIB = _load()
_ltdl = _LIB.rrtk_ltdl
_reduce = _LIB.rrtk_reduce
_search = _LIB.rrtk_search
_apply_zt = _LIB.rrtk_apply_zt
_apply_zinvt = _LIB.rrtk_apply_zinvt
_ils_from_reduced = _LIB.rrtk_ils_from_reduced
_ils = _LIB.rrtk_ils
_lambda_all = _LIB.rrtk_lambda_all


_from_buffer = ctypes.c_char.from_buffer
_addressof = ctypes.addressof


def _addr(x: np.ndarray) -> int:
    """Address of the (C-contiguous) data of ``x``.

    Through the buffer protocol (about a third of the time of ``x.ctypes.data``, which builds
    a helper object per call); read-only or empty arrays, which it refuses, take ``x.ctypes``.
    """
    try:
        return _addressof(_from_buffer(x))  # type: ignore[arg-type]
    except (TypeError, ValueError, BufferError):
        return int(x.ctypes.data)


def _f64(x: npt.ArrayLike) -> FloatArray:
    """``x`` as a C-contiguous float64 array (the same object when it already is one)."""
    return np.ascontiguousarray(x, dtype=np.float64)


def _ops(ops: npt.ArrayLike) -> IntArray:
    """Operation rows as a C-contiguous int64 array of shape (k, 3)."""
    return np.ascontiguousarray(ops, dtype=np.int64).reshape(-1, 3)


def _shape(x: np.ndarray, shape: tuple[int, ...], name: str) -> None:
    """Raise ValueError unless ``x`` has ``shape`` (the C code trusts the sizes it is given)."""
    if x.shape != shape:
        raise ValueError(f"{name} has shape {x.shape}, expected {shape}")


def _count(m: int) -> int:
    """The number of candidates as an int, at least 1."""
    m = int(m)
    if m < 1:
        raise ValueError(f"m must be >= 1, got {m}")
    return m


def _checked(code: int) -> int:
    """``code`` as an int; MemoryError / ValueError for the C library's own failures."""
    if code == NO_MEMORY:
        raise MemoryError("C LAMBDA kernels: out of memory")
    if code == BAD_OPS:
        raise ValueError("operation rows (j, i, mu) do not index the vector")
    if code == BAD_SIZE:
        raise ValueError("the search needs at least one ambiguity and one candidate")
    return int(code)


def ltdl_k(q: FloatArray) -> tuple[FloatArray, FloatArray, int]:
    """``Q = Lᵀ diag(d) L`` by elimination from the last row to the first.

    Parameters
    ----------
    q : ndarray, shape (n, n)
        Symmetric covariance (cycles²); not modified.

    Returns
    -------
    L, d : ndarray, shapes (n, n) and (n,)
        As :func:`robustrtk.ambiguity.lambda_pure.ltdl_py` (void when not positive definite).
    code : int
        ``OK`` or ``NOT_PD``.
    """
    qc = _f64(q)
    n = qc.shape[0]
    _shape(qc, (n, n), "q")
    out = np.empty(n * n + n)  # one buffer for the outputs: one address to take, not two
    p = _addr(out)
    code = _checked(_ltdl(n, _addr(qc), p, p + 8 * n * n))
    return out[: n * n].reshape(n, n), out[n * n :], code


def reduce_into_k(L: FloatArray, d: FloatArray, cap: int) -> tuple[IntArray, int, FloatArray, FloatArray]:
    """Integer Gauss transformations and permutations (works on copies).

    Parameters
    ----------
    L : ndarray, shape (n, n)
        Unit lower-triangular factor.
    d : ndarray, shape (n,)
        Its diagonal (cycles²).
    cap : int
        Room for operations.

    Returns
    -------
    ops : ndarray of int64, shape (cap, 3)
        The operations ``(j, i, mu)`` (``i = -1``: permutation of ``j, j+1``), in order, in
        the first ``nops`` rows.
    nops : int
        Their number; ``-1`` when ``cap`` was too small (the other outputs are then void).
    L, d : ndarray
        The reduced factors, ``Zᵀ Q Z = Lᵀ diag(d) L``.
    """
    Lc = _f64(L)
    dc = _f64(d)
    n = dc.shape[0]
    _shape(Lc, (n, n), "L")
    ops = np.empty((cap, 3), dtype=np.int64)
    out = np.empty(n * n + n)
    p = _addr(out)
    nops = int(_reduce(n, _addr(Lc), _addr(dc), cap, _addr(ops), p, p + 8 * n * n))
    return ops, (nops if nops <= cap else -1), out[: n * n].reshape(n, n), out[n * n :]


def reduce_k(L: FloatArray, d: FloatArray) -> tuple[IntArray, FloatArray, FloatArray]:
    """Integer Gauss transformations and permutations (works on copies).

    Parameters and returns as :func:`reduce_into_k`, without its ``cap`` and ``nops``: the
    ``k`` operations are all the rows of ``ops``, shape (k, 3).

    Notes
    -----
    The library counts every operation, also those beyond the room given: when
    ``4 n² + 64`` rows were not enough the reduction runs once more with exactly the room it
    needs.
    """
    Lc = _f64(L)
    dc = _f64(d)
    n = dc.shape[0]
    _shape(Lc, (n, n), "L")
    cap = 4 * n * n + 64
    out = np.empty(n * n + n)
    p = _addr(out)
    pL, pd = _addr(Lc), _addr(dc)
    while True:
        ops = np.empty((cap, 3), dtype=np.int64)
        nops = int(_reduce(n, pL, pd, cap, _addr(ops), p, p + 8 * n * n))
        if nops <= cap:
            return ops[:nops].copy(), out[: n * n].reshape(n, n), out[n * n :]
        cap = nops


def search_k(
    L: FloatArray, d: FloatArray, zs: FloatArray, m: int, max_nodes: int
) -> tuple[FloatArray, FloatArray, int]:
    """MLAMBDA depth-first search (Schnorr–Euchner zig-zag, shrinking ellipsoid).

    Parameters
    ----------
    L : ndarray, shape (n, n)
        Unit lower-triangular factor of ``Qz = Lᵀ diag(d) L``.
    d : ndarray, shape (n,)
        Positive conditional variances (cycles²).
    zs : ndarray, shape (n,)
        Float ambiguities in the decorrelated space (cycles).
    m : int
        Number of candidates (≥ 1).
    max_nodes : int
        Cap on the search steps.

    Returns
    -------
    Zfix : ndarray, shape (n, m)
        Candidates as columns, best first.
    s : ndarray, shape (m,)
        Their squared norms, ascending.
    code : int
        ``OK`` or ``SEARCH_LIMIT``.
    """
    Lc, dc, zc = _f64(L), _f64(d), _f64(zs)
    n = dc.shape[0]
    m = _count(m)
    _shape(Lc, (n, n), "L")
    _shape(zc, (n,), "zs")
    out = np.empty(n * m + m)
    p = _addr(out)
    code = _search(n, _addr(Lc), _addr(dc), _addr(zc), m, max_nodes, p, p + 8 * n * m)
    return out[: n * m].reshape(n, m), out[n * m :], _checked(code)


def apply_zt_k(ops: IntArray, v: FloatArray) -> FloatArray:
    """``Zᵀ v`` for ``v`` of shape (n,) from the operation list (in order)."""
    o = _ops(ops)
    x = np.array(v, dtype=np.float64, order="C")
    _checked(_apply_zt(x.shape[0], o.shape[0], _addr(o), _addr(x)))
    return x


def apply_zinvt_k(ops: IntArray, V: FloatArray) -> FloatArray:
    """``Z⁻ᵀ V`` for ``V`` of shape (n, k) from the operation list (in reverse order)."""
    o = _ops(ops)
    X = np.array(V, dtype=np.float64, order="C")
    if X.ndim != 2:
        raise ValueError(f"V must be 2-d, got shape {X.shape}")
    _checked(_apply_zinvt(X.shape[0], o.shape[0], _addr(o), X.shape[1], _addr(X)))
    return X


def ils_from_reduced_k(
    a: FloatArray, ops: IntArray, L: FloatArray, d: FloatArray, m: int, max_nodes: int
) -> tuple[FloatArray, FloatArray, int]:
    """Search on reduced factors and back-transform: ``F = round(Z⁻ᵀ ž) + round(â)``.

    Parameters
    ----------
    a : ndarray, shape (n,)
        Float ambiguities (cycles).
    ops, L, d :
        The output of :func:`reduce_k` for ``Q``.
    m, max_nodes : int
        As :func:`search_k`.

    Returns
    -------
    F : ndarray, shape (n, m)
    s : ndarray, shape (m,)
    code : int
    """
    ac, o, Lc, dc = _f64(a), _ops(ops), _f64(L), _f64(d)
    n = ac.shape[0]
    m = _count(m)
    _shape(Lc, (n, n), "L")
    _shape(dc, (n,), "d")
    out = np.empty(n * m + m)
    p = _addr(out)
    code = _ils_from_reduced(
        n, _addr(ac), o.shape[0], _addr(o), _addr(Lc), _addr(dc), m, max_nodes,
        p, p + 8 * n * m,
    )  # fmt: skip
    return out[: n * m].reshape(n, m), out[n * m :], _checked(code)


def ils_k(
    a: FloatArray, q: FloatArray, m: int, max_nodes: int
) -> tuple[FloatArray, FloatArray, FloatArray, int]:
    """Whole ILS on a checked, symmetric ``q``: LᵀDL, reduction, search, back-transform.

    Returns
    -------
    F : ndarray, shape (n, m)
        Candidates, best first (integer values).
    s : ndarray, shape (m,)
        Squared norms, ascending.
    d : ndarray, shape (n,)
        Decorrelated conditional variances (cycles²).
    code : int
        ``OK``, ``NOT_PD`` or ``SEARCH_LIMIT``.
    """
    ac, qc = _f64(a), _f64(q)
    n = ac.shape[0]
    m = _count(m)
    _shape(qc, (n, n), "q")
    nm = n * m
    out = np.empty(nm + m + n)
    p = _addr(out)
    code = _ils(n, _addr(ac), _addr(qc), m, max_nodes, p, p + 8 * nm, p + 8 * (nm + m))
    return out[:nm].reshape(n, m), out[nm : nm + m], out[nm + m :], _checked(code)


def lambda_all(a: FloatArray, Q: FloatArray, m: int, max_nodes: int) -> tuple[FloatArray, FloatArray, int]:
    """Input checks of ``check_q`` (finite, symmetric to ``1e-9 max|Q|``), symmetrisation
    ``(Q + Qᵀ)/2`` and :func:`ils_k`, in one call.

    Returns
    -------
    F : ndarray, shape (n, m)
    s : ndarray, shape (m,)
    code : int
        ``OK``, ``NONFINITE_A``, ``NONFINITE_Q``, ``ASYMMETRIC_Q``, ``NOT_PD`` or
        ``SEARCH_LIMIT``.
    """
    ac, qc = _f64(a), _f64(Q)
    n = ac.shape[0]
    m = _count(m)
    _shape(qc, (n, n), "Q")
    out = np.empty(n * m + m)
    p = _addr(out)
    code = _lambda_all(n, _addr(ac), _addr(qc), m, max_nodes, p, p + 8 * n * m)
    return out[: n * m].reshape(n, m), out[n * m :], _checked(code)


__all__ = [
    "ABI_VERSION",
    "ASYMMETRIC_Q",
    "BAD_OPS",
    "BAD_SIZE",
    "NONFINITE_A",
    "NONFINITE_Q",
    "NOT_PD",
    "NO_MEMORY",
    "OK",
    "SEARCH_LIMIT",
    "SWAP_TOL",
    "apply_zinvt_k",
    "apply_zt_k",
    "ils_from_reduced_k",
    "ils_k",
    "lambda_all",
    "library_path",
    "ltdl_k",
    "reduce_into_k",
    "reduce_k",
    "search_k",
]
