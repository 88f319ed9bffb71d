"""Looking at a result document without writing code: its trajectory as CSV and its plots.

Everything here reads a result document (the JSON the service stores and ``trajopt solve``
writes) and nothing else, so the service, the command line and a script give the same output.
"""

from app.report.plots import PLOT_FORMATS, available_plots, render_plot
from app.report.table import trajectory_csv

__all__ = ["PLOT_FORMATS", "available_plots", "render_plot", "trajectory_csv"]
