"""What the reliability suite shares: a fast scene, the command line run in-process, a snapshot
of the files that must never change, the temporary files that must never be left, a watchdog
for hangs and the outcome counts of the fuzzers."""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import signal
import stat
from collections import Counter, defaultdict
from pathlib import Path

from legsim.cli import main
from legsim.scene import bundled_dir

FULL = os.environ.get("LEGSIM_FULL") == "1"

#: The bundled bouncing ball, cut to 1.5 s (through its Zeno time, 0.1 s of computing).
BALL_SCENE = (bundled_dir() / "bouncing_ball.toml").read_text().replace("t_final = 2.7", "t_final = 1.5")


def write_ball(folder: Path, name: str = "ball.toml", extra: str = "") -> Path:
    """The ball scene (plus ``extra`` TOML) written to ``folder/name``."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(BALL_SCENE + extra)
    return path


def run_cli(*argv: str) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``legsim ARGV`` run in this process."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def snapshot(root: Path) -> dict[str, tuple]:
    """Every entry under ``root`` (links not followed): relative path -> (kind, size, mtime,
    content digest for regular files), so that any change, creation or removal shows."""
    found: dict[str, tuple] = {}
    for folder, dirs, files in os.walk(root):
        for name in dirs + files:
            path = Path(folder) / name
            info = path.lstat()
            digest = ""
            if stat.S_ISREG(info.st_mode):
                digest = hashlib.sha256(path.read_bytes()).hexdigest()
            found[str(path.relative_to(root))] = (stat.S_IFMT(info.st_mode), info.st_size, info.st_mtime_ns, digest)
    return found


def temporaries(root: Path) -> list[Path]:
    """Temporary files of an interrupted write under ``root`` (legsim's ``.NAME.PID-X.partial.EXT``
    and the ``.tmp`` names of other writers)."""
    return sorted(p for p in root.rglob("*") if ".partial" in p.name or p.name.endswith((".tmp", ".tmp.npz")))


class Hang(BaseException):
    """A fuzzed input ran longer than the watchdog allows."""


@contextlib.contextmanager
def watchdog(seconds: float):
    """Raise ``Hang`` in this (main) thread when the block lasts more than ``seconds``."""

    def fire(signum, frame):
        raise Hang(f"no answer after {seconds} s")

    previous = signal.signal(signal.SIGALRM, fire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


#: fuzzer -> outcome -> count, printed at the end of a run without xdist (see conftest.py).
OUTCOMES: dict[str, Counter] = defaultdict(Counter)

#: The columns of the table in docs/reliability.md; the last six must stay 0.
COLUMNS = (
    "inputs tried",
    "ran (exit 0 or 3)",
    "clear errors (exit 2)",
    "tracebacks",
    "hangs",
    "silent wrong results",
    "files lost or changed",
    "temporaries left",
    "files outside read",
)


def record(fuzzer: str, outcome: str) -> None:
    """Count one input of ``fuzzer`` with ``outcome`` (one of ``COLUMNS`` after the first)."""
    assert outcome in COLUMNS[1:], outcome
    OUTCOMES[fuzzer]["inputs tried"] += 1
    OUTCOMES[fuzzer][outcome] += 1


def outcome_table() -> str:
    """The counts as the markdown table of docs/reliability.md."""
    lines = ["| fuzzer | " + " | ".join(COLUMNS) + " |", "|---" * (len(COLUMNS) + 1) + "|"]
    for fuzzer, counts in sorted(OUTCOMES.items()):
        lines.append(f"| {fuzzer} | " + " | ".join(str(counts[c]) for c in COLUMNS) + " |")
    return "\n".join(lines)


# -- crafted files -------------------------------------------------------------------------------
def npz_arrays(path: Path) -> dict:
    """The arrays of a saved execution, ``meta`` as the parsed JSON document."""
    import json

    import numpy as np

    with np.load(path, allow_pickle=False) as archive:
        arrays = {key: archive[key] for key in archive.files}
    arrays["meta"] = json.loads(str(arrays["meta"]))
    return arrays


def write_npz(path: Path, arrays: dict, meta_text: str | None = None) -> Path:
    """An execution file holding ``arrays`` (``meta`` a JSON document, or ``meta_text`` as is)."""
    import json

    import numpy as np

    payload = {k: v for k, v in arrays.items() if k != "meta"}
    if "meta" in arrays or meta_text is not None:
        payload["meta"] = np.array(meta_text if meta_text is not None else json.dumps(arrays["meta"]))
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **payload)
    return path


def recording_with_meta(path: Path, model, execution, meta_text: str) -> Path:
    """A Rerun recording of ``execution`` whose ``legsim/meta`` document is ``meta_text``."""
    import rerun as rr

    from legsim.output.rrd import write as rrd_write

    original = rrd_write._Logger.header

    def header(self, meta, frames, scenery):
        self.rec.log("legsim/meta", rr.TextDocument(meta_text, media_type="text/plain"), static=True)

    rrd_write._Logger.header = header
    try:
        return rrd_write.write_rrd(execution, None, path, model=model)
    finally:
        rrd_write._Logger.header = original
