"""Outputs of a run: files written atomically (``files``)."""

from .files import write_atomic, write_bytes_atomic

__all__ = ["write_atomic", "write_bytes_atomic"]
