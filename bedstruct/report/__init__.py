"""Self-contained HTML + JSON reports of a powder bed.

>>> from bedstruct.report import build_report, ReportOptions
"""

from ._model import Quantity, Report, Section, Table, run_section, skip
from ._render import render_html, write_report
from .build import build_report
from .options import ReportOptions, select_frames
from .inputs import load_report_inputs, report_on_files
from .run_summary import write_run_summary

__all__ = ["Quantity", "Report", "Section", "Table", "run_section", "skip", "render_html",
           "write_report", "ReportOptions", "build_report", "select_frames", "load_report_inputs",
           "report_on_files", "write_run_summary"]
