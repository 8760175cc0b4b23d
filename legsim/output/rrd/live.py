"""Showing recordings in a Rerun viewer: a run streamed live (``legsim run --spawn`` or
``--connect ADDRESS``) and a recording file opened (``legsim replay --spawn``).

The checks run before any work: ``--spawn`` needs a display, and ``--connect`` an address that
accepts a connection now, since Rerun's own client only logs, and drops the data, when nothing
listens there.

Rerun's viewer collects usage analytics unless they are turned off, and a viewer's first run on
a machine writes a setting that turns them on for every later one. legsim never decides that
for its user: before it starts a viewer on a machine where Rerun has no analytics setting yet,
it runs Rerun's documented opt-out, ``rerun analytics disable`` (``viewer_analytics_off``); a
setting the user made (``rerun analytics enable`` or ``disable``) or ``FORCE_RERUN_ANALYTICS``
is left alone. Sending to a viewer the user started (``--connect``) starts none.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from ...builders import Model
from ...errors import LegsimError
from ...execution import Execution
from ...hybrid import HybridSystem
from .write import prepare, record, recording_stream

#: Rerun's default port for a viewer or proxy; ``--connect`` without a port uses it.
DEFAULT_PORT = 9876
#: Seconds to wait for the viewer's address to accept a connection, and for the sent data.
CONNECT_TIMEOUT = 5.0
#: Rerun's environment variable that turns its analytics on whatever the setting: the user's
#: to set; legsim reads it and never sets it.
FORCE_ANALYTICS = "FORCE_RERUN_ANALYTICS"
#: Seconds ``rerun analytics disable`` may take.
ANALYTICS_TIMEOUT = 60.0


def has_display() -> bool:
    """True when a graphical viewer can open a window here."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def check_display(flag: str, instead: str) -> None:
    """LegsimError naming ``flag`` when no window can open here; ``instead`` says what to do."""
    if not has_display():
        raise LegsimError(
            f"{flag} needs a display, and there is none here (DISPLAY and WAYLAND_DISPLAY are unset); {instead}"
        )


def rerun_analytics_setting() -> Path:
    """The file holding Rerun's analytics setting (what ``rerun analytics config`` shows): its
    ``analytics.json`` in Rerun's configuration folder, found as Rerun finds it (the
    ``directories`` crate's project folder ``rerun``: XDG on Linux)."""
    if sys.platform == "darwin":
        folder = Path.home() / "Library" / "Application Support" / "rerun"
    elif sys.platform == "win32":
        folder = Path(os.environ.get("APPDATA") or Path.home() / "AppData" / "Roaming") / "rerun" / "config"
    else:
        xdg = os.environ.get("XDG_CONFIG_HOME", "")
        folder = (Path(xdg) if os.path.isabs(xdg) else Path.home() / ".config") / "rerun"
    return folder / "analytics.json"


def viewer_analytics_off() -> None:
    """Before legsim starts a Rerun viewer: when Rerun has no analytics setting here yet (its
    first run would write one that turns them on) and ``FORCE_RERUN_ANALYTICS`` is not set, run
    Rerun's opt-out ``rerun analytics disable`` and say so on stderr. LegsimError when that
    fails: the viewer is then not started."""
    # The values Rerun reads as true (re_log::env_var_flag); any other leaves its setting in charge.
    forced = os.environ.get(FORCE_ANALYTICS, "").strip().lower() in ("1", "true", "yes", "on")
    setting = rerun_analytics_setting()
    if forced or setting.exists():
        return
    command = [sys.executable, "-m", "rerun_cli", "analytics", "disable"]
    try:
        done = subprocess.run(
            command, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=ANALYTICS_TIMEOUT, check=False
        )
        reason = f"exit code {done.returncode}: {done.stderr.strip()[-300:]}"
    except (OSError, subprocess.SubprocessError) as exc:
        done, reason = None, f"{type(exc).__name__}: {exc}"
    if done is None or done.returncode != 0 or not setting.exists():
        raise LegsimError(
            f"Rerun has no analytics setting here ({setting}), and `rerun analytics disable` failed "
            f"({reason}); run `rerun analytics disable` (or `rerun analytics enable`) yourself before "
            f"starting a viewer from legsim"
        )
    print(
        f"legsim: Rerun had no analytics setting here; turned its usage analytics off with "
        f"`rerun analytics disable` before starting its viewer (setting in {setting}; "
        f"`rerun analytics enable` turns them on)",
        file=sys.stderr,
    )


def viewer_url(address: str) -> str:
    """The gRPC URL of a Rerun viewer or proxy at ``address``: a port (``9876``), ``HOST:PORT``
    or a full ``rerun+http://HOST:PORT/proxy`` URL; LegsimError naming it otherwise."""
    text = address.strip()
    if text.isdigit():
        text = f"127.0.0.1:{text}"
    if "://" not in text:
        text = f"rerun+http://{text}/proxy"
    try:
        parts = urlsplit(text)
        port = parts.port
    except ValueError:
        parts, port = None, None
    if (
        parts is None
        or parts.scheme not in ("rerun", "rerun+http", "rerun+https")
        or not parts.hostname
        or parts.path.rstrip("/") != "/proxy"
        or (port is not None and not 0 < port < 65536)
    ):
        raise LegsimError(
            f"--connect {address!r}: not a Rerun viewer address; give a port (9876), HOST:PORT "
            f"or rerun+http://HOST:PORT/proxy"
        )
    return text


def check_reachable(address: str, url: str) -> None:
    """LegsimError naming ``address`` when nothing accepts a connection at ``url``."""
    parts = urlsplit(url)
    port = parts.port or DEFAULT_PORT
    try:
        socket.create_connection((parts.hostname, port), timeout=CONNECT_TIMEOUT).close()
    except OSError as exc:
        raise LegsimError(
            f"--connect {address}: no Rerun viewer answers at {parts.hostname}:{port} "
            f"({exc.strerror or exc}); start one with `rerun` (or `rerun --serve-grpc`) "
            f"there first"
        ) from None


def stream_rrd(
    execution: Execution,
    scene: Any = None,
    *,
    spawn: bool = False,
    connect: str | None = None,
    model: Model | HybridSystem | None = None,
    rate: float | None = None,
) -> None:
    """Send the recording of ``execution`` (as ``write_rrd`` would write it, with the same
    ``scene``, ``model`` and ``rate``) to a new viewer (``spawn``) or to the viewer at
    ``connect`` (an address for ``viewer_url``)."""
    if spawn == (connect is not None):
        raise LegsimError("stream_rrd needs one of spawn=True or connect=ADDRESS")
    url = viewer_url(connect) if connect is not None else None
    if url is not None:
        check_reachable(str(connect), url)
    content = prepare(execution, scene, model, rate, f"--connect {connect}" if connect else "--spawn")
    if spawn:
        viewer_analytics_off()
    with recording_stream() as rec:
        if url is not None:
            rec.connect_grpc(url)
        else:
            rec.spawn(connect=True)
        record(rec, content)


def open_in_viewer(path: Path) -> None:
    """Open the recording file ``path`` in Rerun's bundled viewer, detached so that the viewer
    outlives this command."""
    viewer_analytics_off()
    # rerun-sdk runs its bundled viewer as `python -m rerun_cli FILE`.
    subprocess.Popen(
        [sys.executable, "-m", "rerun_cli", str(path)],
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
