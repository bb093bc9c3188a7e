"""Figures from result files (``polydem report``); one module per figure family."""

from .make import make_report, overlay

__all__ = ["make_report", "overlay"]
