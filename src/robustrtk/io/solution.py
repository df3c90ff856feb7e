"""Solution files: CSV, RTKLIB ``.pos``, NMEA GGA, and the per-DD diagnostics CSV.

Writers take a sequence of :class:`robustrtk.core.Solution`; readers return a
:class:`SolutionTable` (arrays). Every writer writes a temporary file in the target's
directory and renames it over the target (:func:`os.replace`), so an error never leaves a
truncated or missing output. Readers raise :class:`robustrtk.core.InputError` naming the
file, the line and what was expected.

Times: ``t_s`` is GPS time in seconds since 1980-01-06 for GNSS solutions, the table's own
seconds for pseudolite solutions. RTKLIB ``.pos`` and NMEA carry geodetic coordinates and
calendar times, so only ECEF (GNSS) solutions can be written to them: the caller states
the frame of the positions (``pos_frame``, the solver's :attr:`SolutionSeries.frame`), and
a local (pseudolite) frame raises :class:`InputError` instead of producing a file that
plots on the wrong continent. The frame is never guessed from the positions' magnitude, so
one wild epoch cannot make a whole GNSS run unwritable. Use the CSV writer for local frames.

Status vocabulary and its mapping (RTKLIB ``Q`` / NMEA GGA quality):

=========  ===  ====  ========================================================
status     Q    GGA   meaning
=========  ===  ====  ========================================================
fixed      1    4     every ambiguity of the epoch fixed to a validated integer
partial    1    4     a validated subset of the ambiguities fixed (the rest float)
float      2    5     carrier-phase solution, ambiguities real-valued
dgnss      4    2     code differential (DGNSS mode)
code       4    2     code DDs only inside an RTK run (before or without phase)
single     5    1     single-point (SPP) solution
none       --   --    no solution (epoch not written to ``.pos``/NMEA; ``none`` in CSV)
=========  ===  ====  ========================================================

``Q = 1`` means what it means in RTKLIB: the position comes from a validated integer fix.
RTKLIB's own partial ambiguity resolution (it leaves out satellites until the ratio test
passes) also writes ``Q = 1``, so ``partial`` is written as 1 too; the CSV, the API and the
end-of-run summary keep ``fixed`` and ``partial`` apart, and the summary's *fix rate* is the
share of ``Q = 1`` epochs (``fixed`` + ``partial``), the same number as
:meth:`robustrtk.pipeline.api.SolutionSeries.fix_rate`.

Reading ``Q``: 1 fixed, 2 float, 3 (SBAS) dgnss, 4 dgnss, 5 single, 6 (PPP) float (a ``.pos``
does not tell ``fixed`` from ``partial``).

The ``.pos`` ``ns`` column and the GGA satellite count are satellites used (references
included), as RTKLIB counts them; the CSV's ``n_used`` counts measurement rows (DDs).

Modules: :mod:`robustrtk.io.solution_table` (tables, shared helpers),
:mod:`robustrtk.io.solution_csv`, :mod:`robustrtk.io.solution_pos`,
:mod:`robustrtk.io.solution_nmea` and :mod:`robustrtk.io.diagnostics`; every public name is
importable from here.
"""

from robustrtk.io.diagnostics import DIAG_COLUMNS, DiagTable, read_diagnostics_csv, write_diagnostics_csv
from robustrtk.io.solution_csv import CSV_COLUMNS, CSV_VEL_COLUMNS, read_solution_csv, write_solution_csv
from robustrtk.io.solution_nmea import gga_sentence, nmea_checksum, write_nmea
from robustrtk.io.solution_pos import read_pos, write_pos
from robustrtk.io.solution_table import PathLike, SolutionTable, StrArray

__all__ = [
    "CSV_COLUMNS",
    "CSV_VEL_COLUMNS",
    "DIAG_COLUMNS",
    "DiagTable",
    "PathLike",
    "SolutionTable",
    "StrArray",
    "gga_sentence",
    "nmea_checksum",
    "read_diagnostics_csv",
    "read_pos",
    "read_solution_csv",
    "write_diagnostics_csv",
    "write_nmea",
    "write_pos",
    "write_solution_csv",
]
