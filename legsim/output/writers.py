"""The writers of pictures and recordings, found by name: ``legsim.output.rrd.write_rrd`` (public as
``legsim.record.write_rrd``) for ``rrd``, and for every other kind (``html``, ``plot``, the sweep's
maps) the entry point of that name in the ``legsim.writers`` group, which the pictures package
(``legsim.viz``) registers: the core and the commands never import the pictures, only ask for them."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import LegsimError

#: The entry-point group of output writers.
WRITER_GROUP = "legsim.writers"
#: ``writer(execution_or_table, scene_or_info, path, **extra)``: writes one file at ``path``.
Writer = Callable[[Any, Any, Path], Any]


def find_writer(kind: str, source: str = "") -> Writer:
    """The writer for ``kind`` (rrd, html, plot); LegsimError naming ``source`` when it is missing."""
    label = source or f"--{kind}"
    if kind == "rrd":
        try:
            from .rrd import write_rrd
        except ModuleNotFoundError as exc:
            if exc.name and not exc.name.startswith("legsim"):
                raise LegsimError(
                    f"{label}: the Rerun recorder needs {exc.name!r}, which is not installed (pip install rerun-sdk)"
                ) from exc
            raise LegsimError(f"{label}: Rerun recordings are not available: {exc}") from exc
        except ImportError as exc:  # a broken or partial install
            raise LegsimError(f"{label}: Rerun recordings are not available: {exc}") from exc
        return write_rrd
    from importlib import metadata

    eps = metadata.entry_points(group=WRITER_GROUP, name=kind)
    if not eps:
        raise LegsimError(f"{label}: no '{kind}' writer is registered in the {WRITER_GROUP} entry points")
    ep = next(iter(eps))
    try:
        writer = ep.load()
    except Exception as exc:
        raise LegsimError(
            f"{label}: the '{kind}' writer {ep.value} could not be loaded: {type(exc).__name__}: {exc}"
        ) from exc
    if not callable(writer):
        raise LegsimError(f"{label}: the '{kind}' writer {ep.value} is not callable")
    return writer
