"""Input/output: CSV histories, ParaView files, figures."""

from .history import History, read_csv

__all__ = ["History", "read_csv"]
