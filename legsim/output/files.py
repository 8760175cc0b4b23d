"""Writing output files so that they never destroy data: complete or absent, never over an input.

Every file legsim writes (recordings, pages, figures, tables, saved executions) goes through
``write_atomic``, which first refuses a target that

* is not a regular file or a new name (a directory, device, FIFO or socket, which the final
  rename would replace: ``--rrd /dev/null`` run as root would replace the system's /dev/null),
* is one of the run's inputs (the scene file, a replayed recording; also through a link),
* lacks the suffix of its kind (``.rrd`` for a recording: ``--rrd scene.toml`` is a typo),
* lies in a folder no file can be created in (saying why: permission denied, read-only file
  system, a file where a folder should be);

then writes the content to a temporary file in the target's own folder (so the final rename is
atomic on every POSIX file system) and renames it over the target only once it is complete. The
temporary file is opened with ``open(..., "xb")``, not ``mkstemp``, so it gets the permissions
of any file the user creates (0666 less the umask), which the renamed file keeps.

On any exception, Ctrl-C included, the temporary file is removed; the command line turns
SIGTERM into the same exception (``legsim.cli``). SIGKILL cannot be caught: the temporary name
carries the writer's process id, and the next write of the same target removes the temporary
files of writers that no longer run.

``OutputPlan`` holds the outputs of one run: each is checked when it is added, before the run
starts, and two outputs of one run may not share a file.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import stat
import tempfile
import uuid
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from ..errors import OutputError

PathLike = str | os.PathLike[str]


# -- names ---------------------------------------------------------------------------------------
def temporary_name(path: Path) -> Path:
    """A hidden name next to ``path`` for its content while it is written. It keeps the suffix,
    since some writers (matplotlib, numpy) choose the format from it, and carries this process's
    id so that a later write can tell a dead writer's leftover from a live writer's file."""
    return path.with_name(f".{path.stem}.{os.getpid()}-{uuid.uuid4().hex[:12]}.partial{path.suffix}")


def _temporary_pattern(path: Path) -> re.Pattern[str]:
    # A writer handed a temporary name may write it atomically in turn: its own temporary file
    # then has the first one's name inside (``..a.PID-X.partial.PID-Y.partial.png``).
    mark = r"\.(\d+)-[0-9a-f]{12}\.partial"
    return re.compile(rf"\.+{re.escape(path.stem)}{mark}(?:{mark})*{re.escape(path.suffix)}")


def _process_runs(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process (EPERM): it runs
        return True
    return True


def remove_stale_temporaries(path: Path) -> list[Path]:
    """Remove the temporary files of ``path`` left by writers that were killed (SIGKILL, power
    loss): those whose process id no longer runs. Returns the files removed."""
    pattern = _temporary_pattern(path)
    removed: list[Path] = []
    try:
        entries = list(os.scandir(path.parent))
    except OSError:
        return removed
    for entry in entries:
        match = pattern.fullmatch(entry.name)
        if match and entry.is_file(follow_symlinks=False) and not _process_runs(int(match.group(1))):
            try:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
            except OSError:
                pass
    return removed


def same_file(a: Path, b: Path) -> bool:
    """True when ``a`` and ``b`` name one file: the same inode when both exist (so a hard or
    symbolic link to a file counts as that file), else the same absolute path."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return Path(os.path.abspath(a)) == Path(os.path.abspath(b))


# -- checks --------------------------------------------------------------------------------------
def check_target(path: Path, what: str, *, suffixes: Iterable[str] = (), inputs: Iterable[Path] = ()) -> None:
    """Refuse a target that is not a regular file or a new name (a directory, device, FIFO or
    socket would be replaced by the rename), is one of ``inputs``, or has none of ``suffixes``
    (when given). OutputError naming ``what`` and the path."""
    if "\x00" in str(path):
        raise OutputError(f"{what} {str(path)!r}: a file name cannot contain a NUL character")
    try:
        mode = path.stat().st_mode
    except (FileNotFoundError, NotADirectoryError):
        mode = None  # a new name (or one under a file, which check_folder reports)
    except OSError as exc:
        raise OutputError(f"{what} {path}: cannot write: {os_reason(exc)}") from exc
    if mode is not None and stat.S_ISDIR(mode):
        raise OutputError(f"{what} {path}: is a directory")
    if mode is not None and not stat.S_ISREG(mode):
        raise OutputError(f"{what} {path}: is not a regular file ({file_kind(mode)}); refusing to replace it")
    for source in inputs:
        if same_file(path, source):
            raise OutputError(f"{what} {path}: is an input of this run ({source}); refusing to overwrite it")
    suffixes = tuple(s.lower() for s in suffixes)
    if suffixes and path.suffix.lower() not in suffixes:
        raise OutputError(f"{what} {path}: unsupported format '{path.suffix}'; use one of {list(suffixes)}")
    if mode is not None:
        check_replaceable(path, what, mode)


#: How the files of each suffix legsim writes begin (text kinds compared in lower case): an
#: existing file of that suffix beginning otherwise is no earlier output, and is kept.
_HTML, _JPEG = (b"<!doctype html", b"<html"), (b"\xff\xd8\xff",)
SIGNATURES = {
    ".rrd": (b"rrf2",),
    ".html": _HTML,
    ".htm": _HTML,
    ".png": (b"\x89png",),
    ".svg": (b"<?xml", b"<svg"),
    ".pdf": (b"%pdf",),
    ".jpg": _JPEG,
    ".jpeg": _JPEG,
    ".npz": (b"pk",),
}


def check_replaceable(path: Path, what: str, mode: int) -> None:
    """OutputError naming ``what`` unless the existing file ``path`` (of ``st_mode``) may be
    replaced: not read-only (its owner made it so to keep it; the rename would not ask), and,
    for a suffix in ``SIGNATURES``, empty or beginning as such a file does."""
    if not mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH):
        raise OutputError(
            f"{what} {path}: is read-only; refusing to replace it (make it writable, or choose another name)"
        )
    signatures = SIGNATURES.get(path.suffix.lower())
    if signatures is None:
        return
    try:
        with open(path, "rb") as fh:
            head = fh.read(16)
    except OSError as exc:
        raise OutputError(f"{what} {path}: cannot read what it holds: {os_reason(exc)}") from exc
    if head and not head.lower().startswith(signatures):
        raise OutputError(
            f"{what} {path}: holds no {path.suffix} file (it begins {head[:8]!r}); refusing to replace it "
            f"(remove it, or choose another name)"
        )


def file_kind(mode: int) -> str:
    """What a file of ``st_mode`` is, as a message says it."""
    for test, name in (
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISREG, "a regular file"),
    ):
        if test(mode):
            return name
    return "a special file"


def input_size(path: Path, what: str, error: type[Exception]) -> int:
    """The size (bytes) of ``path``, a file to be read as ``what``: ``error`` naming it when it
    is missing, cannot be looked at, or is no regular file (a folder, a FIFO, a device)."""
    try:
        info = path.stat()
    except FileNotFoundError:
        raise error(f"{path}: no such {what}") from None
    except OSError as exc:
        raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        raise error(f"{path}: not a {what} (it is {file_kind(info.st_mode)})")
    return info.st_size


def cannot_create_in(folder: Path) -> str | None:
    """The OS's reason why no file can be created in the existing ``folder``, or None when one
    can. Probes with an unnamed temporary file, which leaves nothing behind, because permission
    bits alone say yes to root on a read-only or virtual file system (/proc, /sys), and
    ``os.access`` says "permission denied" where the truth is "read-only file system"."""
    try:
        with tempfile.TemporaryFile(dir=folder):
            return None
    except OSError as exc:
        return os_reason(exc)


def os_reason(exc: OSError) -> str:
    """The OS's words for ``exc`` ("Read-only file system", "Permission denied", ...)."""
    if exc.errno is not None and not exc.strerror:
        return os.strerror(exc.errno)
    return str(exc.strerror or exc)


def check_folder(path: Path, what: str) -> None:
    """OutputError naming ``what`` unless ``path`` can be created: its folder exists and a file
    can be made in it, or the folder can be made inside one where a file can. Makes nothing."""
    ancestor = path.parent
    while not ancestor.exists() and ancestor != ancestor.parent:
        if ancestor.is_symlink():
            raise OutputError(f"{what} {path}: {ancestor} is a broken symbolic link")
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise OutputError(f"{what} {path}: {ancestor} is not a directory")
    reason = cannot_create_in(ancestor)
    if reason is not None:
        raise OutputError(f"{what} {path}: cannot write in {ancestor} ({reason})")


# -- writing -------------------------------------------------------------------------------------
def write_atomic(
    path: PathLike,
    write: Callable[[Path], object],
    *,
    what: str = "output",
    suffixes: Iterable[str] = (),
    inputs: Iterable[PathLike] = (),
) -> Path:
    """Call ``write(tmp)`` on a temporary file next to ``path``, then rename it to ``path``.

    ``what`` names the output in messages (``--rrd``, ``execution file``); ``suffixes`` are the
    file types the output may have (any when empty); ``inputs`` the files the run read, which
    must not be overwritten. Missing folders are created. On any failure, Ctrl-C and SIGTERM
    included, the temporary file is removed and an older file at ``path`` is left as it was.
    Raises ``OutputError`` naming the path for a refused target, an OS error (chained to it, as
    ``__cause__``) or a writer that wrote nothing; other exceptions of ``write`` pass through.
    """
    staging = Staging()
    try:
        staging.write(path, write, what=what, suffixes=suffixes, inputs=inputs)
        staging.commit()
    finally:
        staging.discard()  # nothing is left to discard after a commit
    return Path(path)


class Staging:
    """Outputs written to temporary files now and renamed over their targets together when the
    ``with`` block ends without an exception: a run's outputs appear together or not at all. An
    exception (Ctrl-C and SIGTERM included) removes every temporary file and leaves every older
    file as it was. Renaming a file is one system call, so the outputs appear within microseconds
    of each other, where writing them may take seconds."""

    def __init__(self) -> None:
        self._pending: list[tuple[Path, Path, str]] = []

    def __enter__(self) -> Staging:
        return self

    def __exit__(self, kind: object, *exc: object) -> None:
        try:
            if kind is None:
                self.commit()
        finally:
            self.discard()

    def write(
        self,
        path: PathLike,
        write: Callable[[Path], object],
        *,
        what: str = "output",
        suffixes: Iterable[str] = (),
        inputs: Iterable[PathLike] = (),
    ) -> Path:
        """``write(tmp)`` into a temporary file for ``path``, renamed when the block ends (see
        ``write_atomic``); a failure removes this output's temporary file only."""
        path = Path(path)
        check_target(path, what, suffixes=suffixes, inputs=[Path(p) for p in inputs])
        check_folder(path, what)
        remove_stale_temporaries(path)
        tmp = temporary_name(path)
        # The name is this process's and random: a file of that name can only be ours, so it is
        # removed on any failure. Marking it pending before it is created leaves no line between
        # its creation and the mark where a signal would leave it behind (the staging's exit
        # removes every pending file).
        entry = (tmp, path, what)
        self._pending.append(entry)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            open(tmp, "xb").close()
            write(tmp)
            if not tmp.exists():
                raise OutputError(f"{what} {path}: the writer returned without writing the file")
        except BaseException as exc:
            _remove(tmp)
            self._pending.remove(entry)
            if isinstance(exc, OSError):
                raise OutputError(f"{what} {path}: cannot write: {_write_reason(exc, path)}") from exc
            raise
        return path

    def commit(self) -> None:
        """Rename every written file over its target, in the order written. The caller discards
        what is left when a rename fails or a signal lands (``discard``)."""
        while self._pending:
            tmp, path, what = self._pending[0]
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise OutputError(f"{what} {path}: cannot write: {_write_reason(exc, path)}") from exc
            self._pending.pop(0)

    def discard(self) -> None:
        """Remove every temporary file not yet renamed."""
        for tmp, _, _ in self._pending:
            _remove(tmp)
        self._pending.clear()


@contextlib.contextmanager
def temporary_folder(prefix: str) -> Iterator[Path]:
    """A new folder in the temporary folder, removed with its content on every exit, Ctrl-C and
    SIGTERM included. Its name (``prefix``, this process's id, random) is chosen before it is
    made, and it is made inside the ``try`` that removes it: a signal landing just after it is
    made still removes it (``tempfile.TemporaryDirectory`` makes its folder before the block
    that removes it is entered, and a signal between the two, followed by the command line's
    fast exit, leaves it behind)."""
    folder = Path(tempfile.gettempdir()) / f"{prefix}{os.getpid()}-{uuid.uuid4().hex[:12]}"
    try:
        folder.mkdir(mode=0o700)
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _remove(tmp: Path) -> None:
    with contextlib.suppress(OSError):
        tmp.unlink(missing_ok=True)


def _write_reason(exc: OSError, path: Path) -> str:
    if exc.errno == errno.EEXIST and not path.parent.is_dir():
        return f"{path.parent} is not a directory"
    return os_reason(exc)


def write_bytes_atomic(
    path: PathLike, data: bytes, *, what: str = "output", suffixes: Iterable[str] = (), inputs: Iterable[PathLike] = ()
) -> Path:
    """``write_atomic`` for content already in memory; flushed to disk before the rename."""

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())

    return write_atomic(path, write, what=what, suffixes=suffixes, inputs=inputs)


# -- the outputs of one run ----------------------------------------------------------------------
@dataclass(frozen=True)
class PlannedOutput:
    """One output of a run: the file, how messages name it, the file types it may have."""

    path: Path
    what: str
    suffixes: tuple[str, ...] = ()


class OutputPlan:
    """The files one run will write, checked together before the run starts.

    ``inputs`` are the files the run reads (the scene file, a replayed recording): no output may
    overwrite them. ``add`` checks an output at once (type, suffix, input, folder, and that no
    other output of the run has the same file); ``write`` writes it through ``write_atomic``.
    """

    def __init__(self, inputs: Iterable[PathLike] = ()) -> None:
        self.inputs = tuple(Path(p) for p in inputs)
        self.outputs: dict[str, PlannedOutput] = {}

    def add(self, key: str, path: PathLike, *, what: str, suffixes: Iterable[str] = ()) -> Path:
        """Plan output ``key`` at ``path``; OutputError naming ``what`` when it cannot be written."""
        planned = PlannedOutput(Path(path), what, tuple(suffixes))
        check_target(planned.path, what, suffixes=planned.suffixes, inputs=self.inputs)
        for other in self.outputs.values():
            if same_file(planned.path, other.path):
                raise OutputError(
                    f"{what} {planned.path}: {other.what} writes the same file; give each output its own file"
                )
        check_folder(planned.path, what)
        self.outputs[key] = planned
        return planned.path

    def write(self, key: str, write: Callable[[Path], None], staging: Staging | None = None) -> Path:
        """Write the planned output ``key`` with ``write(tmp)`` (see ``write_atomic``), or into
        ``staging``, which renames it with the run's other outputs."""
        planned = self.outputs[key]
        if staging is None:
            return write_atomic(planned.path, write, what=planned.what, suffixes=planned.suffixes, inputs=self.inputs)
        return staging.write(planned.path, write, what=planned.what, suffixes=planned.suffixes, inputs=self.inputs)

    def __iter__(self) -> Iterator[str]:
        return iter(self.outputs)

    def __len__(self) -> int:
        return len(self.outputs)
