"""report.html for a study: plots (matplotlib), renders (``cadfeat.render``), tables, provenance.

``write_report(out_dir, results, context)`` is the entry point called by the study runner and by
``cadfeat evaluate --out``; ``results`` has the keys of results.json (contracts.md). Matplotlib and
PyVista are imported only while writing.
"""

from __future__ import annotations

from cadfeat.report.context import ReportContext
from cadfeat.report.write import ReportOutput, build_report, read_results, report_renders, write_report

__all__ = ["ReportContext", "ReportOutput", "build_report", "read_results", "report_renders", "write_report"]
