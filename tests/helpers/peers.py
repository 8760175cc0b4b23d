"""Network peers that misbehave, for the deadline tests: one that accepts connections and never
answers (a thread in the test's own process), and a port where nothing listens."""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Iterator


@contextlib.contextmanager
def silent_peer() -> Iterator[int]:
    """A port on 127.0.0.1 whose listener accepts every connection, reads what it is sent and
    never writes a byte; closed when the block ends."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(16)
    listener.settimeout(0.1)
    stop = threading.Event()
    accepted: list[socket.socket] = []

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = listener.accept()
            except OSError:  # the 0.1 s poll, or the listener closed
                continue
            conn.settimeout(0.1)
            accepted.append(conn)
            for held in list(accepted):
                with contextlib.suppress(OSError):
                    held.recv(65536)

    thread = threading.Thread(target=serve, name="silent-peer", daemon=True)
    thread.start()
    try:
        yield listener.getsockname()[1]
    finally:
        stop.set()
        thread.join(5)
        for conn in accepted:
            conn.close()
        listener.close()


def closed_port() -> int:
    """A TCP port on 127.0.0.1 nobody listens on now (connections to it are refused)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]
