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

Status mapping (RTKLIB ``Q`` / NMEA GGA quality):

=========  ===  ====
status     Q    GGA
=========  ===  ====
fixed      1    4
partial    1    4
float      2    5
dgnss      4    2
code       4    2
single     5    1
none       (epoch not written)
=========  ===  ====

Reading ``Q``: 1 fixed, 2 float, 3 (SBAS) dgnss, 4 dgnss, 5 single, 6 (PPP) float.

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
