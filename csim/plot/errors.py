"""The error of ``csim plot`` and ``csim animate``: a bad request, reported without a traceback."""
from __future__ import annotations

from csim.errors import CsimError


class PlotError(CsimError):
    """A figure or animation cannot be made as asked: an unknown figure name or format, a
    figure the file has no data for, a mechanism without a drawing, an unwritable output.

    The CLI reports it as bad input (exit code 2); bad or missing result files raise
    :class:`csim.errors.ResultFileError` instead.
    """


#: the highest ``--dpi``: a 6.4 x 4.8 in figure is then 7680 x 5760 pixels (about 180 MB
#: while drawn); beyond it the image backend refuses the size or exhausts memory
MAX_DPI = 1200.0


def check_dpi(dpi: float) -> None:
    """Raise :class:`PlotError` unless 0 < ``dpi`` <= :data:`MAX_DPI`."""
    if not 0 < dpi <= MAX_DPI:
        raise PlotError(f"--dpi: got {dpi:g}; expected a positive number of dots per inch, at most {MAX_DPI:g}")
