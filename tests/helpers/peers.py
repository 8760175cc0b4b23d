"""Network peers that misbehave, for the deadline tests: one that accepts connections and never
answers (a thread in the test's own process), and a port where nothing listens."""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Iterator


class Peer:
    """A listening peer's port and what it has seen: ``accepted`` connections, and how many of
    them the other side has closed (``closed``)."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.accepted = 0
        self.closed = 0


#: What an HTTP/2 server sends first: an empty SETTINGS frame.
HTTP2_SETTINGS = bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])


@contextlib.contextmanager
def silent_peer(first: bytes = b"") -> Iterator[Peer]:
    """A port on 127.0.0.1 whose listener accepts every connection, reads what it is sent and
    never writes a byte, but ``first`` once on each connection when it has read something (a
    server's opening, after which it stalls); closed when the block ends."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(16)
    listener.settimeout(0.1)
    stop = threading.Event()
    accepted: list[socket.socket] = []
    peer = Peer(listener.getsockname()[1])
    answered: set[int] = set()
    ended: set[int] = set()

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = listener.accept()
                conn.settimeout(0.05)
                accepted.append(conn)
                peer.accepted += 1
            except OSError:  # the 0.1 s poll, or the listener closed
                pass
            for k, held in enumerate(list(accepted)):
                if k in ended:
                    continue
                try:
                    data = held.recv(65536)
                except OSError:
                    continue
                if not data:
                    ended.add(k)
                    peer.closed += 1
                elif first and k not in answered:
                    answered.add(k)
                    held.sendall(first)

    thread = threading.Thread(target=serve, name="silent-peer", daemon=True)
    thread.start()
    try:
        yield peer
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
