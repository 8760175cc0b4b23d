"""A headless Rerun server for the live-streaming tests: a free port, waiting for it to listen,
waiting for it to finish writing what it received, and stopping it."""

from __future__ import annotations

import signal
import socket
import subprocess
import time
from pathlib import Path


def free_port() -> int:
    """A TCP port on 127.0.0.1 nobody listens on now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def wait_for(port: int, server: subprocess.Popen, seconds: float = 30.0) -> None:
    """Until the server listens on ``port``; AssertionError if it exits or takes ``seconds``."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if server.poll() is not None:
            raise AssertionError(f"the Rerun server exited with {server.returncode} before listening")
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
            return
        except OSError:
            time.sleep(0.1)
    raise AssertionError(f"the Rerun server on port {port} did not start within {seconds} s")


def settle(saved: Path, quiet: float = 1.0, seconds: float = 30.0) -> None:
    """Wait until the server has stopped writing to ``saved`` for ``quiet`` s: what the client
    sent last may still be on its way when the client returns, and a stopped server drops it."""
    deadline, size, since = time.monotonic() + seconds, -1, time.monotonic()
    while time.monotonic() < deadline:
        now = saved.stat().st_size if saved.exists() else -1
        if now != size:
            size, since = now, time.monotonic()
        elif size > 0 and time.monotonic() - since >= quiet:
            return
        time.sleep(0.1)


def stop(server: subprocess.Popen) -> None:
    """Ctrl-C, which makes the server finish its file; killed if it does not stop."""
    if server.poll() is None:
        server.send_signal(signal.SIGINT)
        try:
            server.wait(timeout=30)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
