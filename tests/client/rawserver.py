"""A tiny scripted TCP server on 127.0.0.1 (thread, blocking sockets) for the driver's error paths:
it parses real request frames and answers with whatever bytes the test's handler returns, including
corrupted frames, late replies, or a dropped connection."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable

from pywsg.protocol import Frame, FrameParser

Handler = Callable[["RawConn", Frame], None]


class RawConn:
    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.closed = False

    def send(self, data: bytes) -> None:
        if not self.closed:
            self.sock.sendall(data)

    def reply(self, frame: Frame, status: int, params: bytes = b"") -> None:
        self.send(Frame.reply(frame.command_id, status, params).encode())

    def close(self) -> None:
        self.closed = True
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.sock.close()


class RawServer:
    """``with RawServer(handler) as srv: srv.url`` - handler(conn, request_frame) per request."""

    def __init__(self, handler: Handler) -> None:
        self.handler = handler
        self.lsock = socket.socket()
        self.lsock.bind(("127.0.0.1", 0))
        self.lsock.listen(4)
        self.port = self.lsock.getsockname()[1]
        self.url = f"tcp://127.0.0.1:{self.port}"
        self.requests: list[Frame] = []
        self.conns: list[RawConn] = []
        self._stop = False
        self._thread = threading.Thread(target=self._serve, daemon=True)

    def __enter__(self) -> RawServer:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop = True
        try:
            self.lsock.shutdown(socket.SHUT_RDWR)  # wakes accept() so the port really closes
        except OSError:
            pass
        self.lsock.close()
        for c in self.conns:
            c.close()
        self._thread.join(2)

    def _serve(self) -> None:
        while not self._stop:
            try:
                s, _ = self.lsock.accept()
            except OSError:
                return
            conn = RawConn(s)
            self.conns.append(conn)
            threading.Thread(target=self._client, args=(conn,), daemon=True).start()

    def _client(self, conn: RawConn) -> None:
        parser = FrameParser()
        while not conn.closed:
            try:
                data = conn.sock.recv(4096)
            except OSError:
                return
            if not data:
                return
            for ev in parser.feed(data):
                if isinstance(ev, Frame):
                    self.requests.append(ev)
                    self.handler(conn, ev)

    def wait_requests(self, n: int, timeout: float = 2.0) -> None:
        deadline = time.monotonic() + timeout
        while len(self.requests) < n and time.monotonic() < deadline:
            time.sleep(0.002)
