"""The error of ``csim plot`` and ``csim animate``: a bad request, reported without a traceback."""
from __future__ import annotations

from csim.errors import CsimError


class PlotError(CsimError):
    """A figure or animation cannot be made as asked: an unknown figure name or format, a
    figure the file has no data for, a mechanism without a drawing, an unwritable output.

    The CLI reports it as bad input (exit code 2); bad or missing result files raise
    :class:`csim.errors.ResultFileError` instead.
    """
