"""Writing output files so that they appear complete or not at all.

Every file legsim writes (recordings, pages, figures, tables, saved executions) goes through
``write_atomic``: the content is written to a temporary file in the target's own folder (so the
final rename is atomic on every POSIX file system) and renamed over the target only once it is
complete. The temporary file is opened with ``open(..., "xb")``, not ``mkstemp``, so it gets the
permissions of any file the user creates (0666 less the umask), which the renamed file keeps.
"""

from __future__ import annotations

import os
import stat
import tempfile
import uuid
from pathlib import Path
from typing import Callable

from ..errors import OutputError


def temporary_name(path: Path) -> Path:
    """A hidden name next to ``path`` for its content while it is written; it keeps the suffix,
    since some writers (matplotlib, numpy) choose the format from it."""
    return path.with_name(f".{path.stem}.{uuid.uuid4().hex[:12]}.partial{path.suffix}")


def check_target(path: Path, what: str) -> None:
    """Refuse a target that is not a regular file or a new name (a directory, device, FIFO or
    socket would be replaced by the rename)."""
    try:
        mode = path.stat().st_mode
    except (FileNotFoundError, NotADirectoryError):
        # A new name (or one under a file, which creating its folder will report).
        return
    except OSError as exc:
        raise OutputError(f"{what} {path}: cannot write: {exc.strerror or exc}") from exc
    if stat.S_ISDIR(mode):
        raise OutputError(f"{what} {path}: is a directory")
    if not stat.S_ISREG(mode):
        raise OutputError(f"{what} {path}: is not a regular file (a device, FIFO or socket); refusing to replace it")


def cannot_create_in(folder: Path) -> str | None:
    """The OS's reason why no file can be created in the existing ``folder``, or None when one
    can. Probes with an unnamed temporary file, which leaves nothing behind, because permission
    bits alone say yes to root on a read-only or virtual file system (/proc, /sys)."""
    try:
        with tempfile.TemporaryFile(dir=folder):
            return None
    except OSError as exc:
        return str(exc.strerror or exc)


def write_atomic(path: str | os.PathLike[str], write: Callable[[Path], None], *, what: str = "output") -> Path:
    """Call ``write(tmp)`` on a temporary file next to ``path``, then rename it to ``path``.

    ``what`` names the output in messages (``--rrd``, ``execution file``). Missing folders are
    created. On any failure, Ctrl-C included, the temporary file is removed and an older file at
    ``path`` is left as it was. Raises ``OutputError`` naming the path for an OS error (chained
    to it, as ``__cause__``) or a writer that wrote nothing; other exceptions of ``write`` pass
    through.
    """
    path = Path(path)
    check_target(path, what)
    tmp = temporary_name(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        open(tmp, "xb").close()
    except OSError as exc:
        raise OutputError(f"{what} {path}: cannot write: {exc.strerror or exc}") from exc
    try:
        write(tmp)
        if not tmp.exists():
            raise OutputError(f"{what} {path}: the writer returned without writing the file")
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise OutputError(f"{what} {path}: cannot write: {exc.strerror or exc}") from exc
        raise
    return path


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes, *, what: str = "output") -> Path:
    """``write_atomic`` for content already in memory; flushed to disk before the rename."""

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())

    return write_atomic(path, write, what=what)
