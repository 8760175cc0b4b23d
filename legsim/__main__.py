"""``python -m legsim`` runs the command line."""

from .cli import entry

entry()
