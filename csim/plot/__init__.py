"""Figures and animations of csim's result files (``csim plot``, ``csim animate``).

Modules, one concept each:

``source``              read a result or comparison file, rebuild the mechanism and units
``series``              series names (``qd:q1``, ``observable:ram_x``, ``phi:max``) -> data
``drawing``             the mechanism drawn from its geometry, 2-D or 3-D
``run_figures``         figures of one run (time histories, the mechanism at instants)
``comparison_figures``  figures of a comparison (constraint errors, work-precision)
``registry``            the figures by name, and which a file can give
``files``               plot a file: build and write its figures
``animate``             the mechanism moving, as GIF or MP4
``style``               one look for every figure (Agg canvases, fonts, colours)

Everything draws on Agg canvases; nothing opens a window.
"""
from csim.plot.animate import MechanismAnimation, animate_file
from csim.plot.errors import PlotError
from csim.plot.files import PlotReport, figures, plot_file
from csim.plot.registry import COMPARISON_FIGURES, RUN_FIGURES

__all__ = [
    "COMPARISON_FIGURES",
    "RUN_FIGURES",
    "MechanismAnimation",
    "PlotError",
    "PlotReport",
    "animate_file",
    "figures",
    "plot_file",
]
