"""Reports a scientist reads: text summaries and figures of analysis results."""

from tsa_bench.report.diagnose_report import format_report, write_figures, write_json, write_report

__all__ = ["format_report", "write_figures", "write_json", "write_report"]
