"""The Meshcat server process (``python -m viz.meshcat_server``): Meshcat's ZMQ <-> websocket
bridge plus what the wristmark view needs.

- ``/wristmark`` serves our page (legend overlay, status line) around Meshcat's viewer bundle;
  ``/wristmark/status`` returns the latest status JSON; ``/static/`` is Meshcat's plain page.
- ZMQ command ``wm_batch`` carries many scene commands in one round trip (frames: b"wm_batch",
  then type, path, data per command): a live frame costs one request, not ~50.
- ZMQ command ``wm_status`` stores the status JSON.
- The web server listens on loopback only (127.0.0.1 and ::1) unless ``--host ADDRESS`` adds
  one (viz.web_hosts); ZMQ is on 127.0.0.1.
- It prints ``zmq_url=...`` and ``web_url=...`` on stdout (or ``error=...`` and exits 2), then
  silences stdout and stderr (nobody drains them: a full pipe would hang the server), and exits
  when its parent dies.
"""

from __future__ import annotations

import argparse
import errno
import json
import os
import sys
from typing import Any

import tornado.httpserver
import tornado.ioloop
import tornado.netutil
import tornado.web
from meshcat.servers.zmqserver import ZMQWebSocketBridge

from wristmark.viz import command_tree
from wristmark.viz.page import served_page
from wristmark.viz.view_priority import lower_priority
from wristmark.viz.web_hosts import listen_addresses

PAGE_PATH = "/wristmark"


class _PageHandler(tornado.web.RequestHandler):
    def initialize(self, bridge: WristmarkBridge) -> None:
        self.bridge = bridge

    def get(self) -> None:
        self.set_header("Content-Type", "text/html; charset=utf-8")
        self.set_header("Cache-Control", "no-store")
        self.write(self.bridge.page)


class _StatusHandler(tornado.web.RequestHandler):
    def initialize(self, bridge: WristmarkBridge) -> None:
        self.bridge = bridge

    def get(self) -> None:
        self.set_header("Content-Type", "application/json")
        self.set_header("Cache-Control", "no-store")
        self.write(self.bridge.status)


class AddressError(Exception):
    """A --host address this machine cannot listen on (not an OSError: meshcat's port search
    would take it for a busy port and try the next thousand)."""


def listen_on(app: tornado.web.Application, port: int, required: list[str], optional: list[str],
              **kwargs: Any) -> tornado.httpserver.HTTPServer:
    """Serve ``app`` on ``port`` at each address (tornado's own ``listen`` binds every interface).
    OSError (port busy) on a required address; optional ones are skipped where they fail."""
    sockets: list[Any] = []
    try:
        for host in required + optional:
            try:
                sockets += tornado.netutil.bind_sockets(port, host)
            except OSError as e:
                if host in optional and e.errno != errno.EADDRINUSE:  # e.g. no IPv6 here
                    continue
                if e.errno == errno.EADDRINUSE:  # meshcat tries the next port
                    raise
                raise AddressError(f"cannot listen on {host}: {e.strerror or e}") from e
    except BaseException:
        for sock in sockets:
            sock.close()
        raise
    server = tornado.httpserver.HTTPServer(app, **kwargs)
    server.add_sockets(sockets)
    return server


class WristmarkBridge(ZMQWebSocketBridge):  # type: ignore[misc]
    """Meshcat's bridge with our page, batched commands and a status line, served on the
    addresses of ``viz.web_hosts.listen_addresses(host)`` (loopback only by default)."""

    def __init__(self, page: str, web_host: str | None = None, **kwargs: Any) -> None:
        self.page = page
        self.status = b"{}"
        self.tree: Any = None  # set by the base class
        self.web_addresses = listen_addresses(web_host)
        super().__init__(**kwargs)

    def make_app(self) -> tornado.web.Application:
        app: tornado.web.Application = super().make_app()
        app.add_handlers(r".*", [
            (PAGE_PATH + r"/?", _PageHandler, {"bridge": self}),
            (PAGE_PATH + r"/status", _StatusHandler, {"bridge": self}),
        ])
        required, optional = self.web_addresses
        app.listen = lambda port, **kw: listen_on(app, port, required, optional, **kw)  # type: ignore[method-assign]
        return app

    def handle_zmq(self, frames: list[bytes]) -> None:
        cmd = bytes(frames[0])
        if cmd == b"wm_batch":
            ok = b"ok"
            for i in range(1, len(frames) - 2, 3):
                kind, path, data = (bytes(f) for f in frames[i:i + 3])
                try:
                    self.tree, forward = command_tree.apply(self.tree, kind.decode(), path.decode(), data)
                except ValueError as e:
                    ok = f"error: {e}".encode()
                    continue
                if forward:
                    for ws in self.websocket_pool:
                        ws.write_message(data, binary=True)
            self.zmq_socket.send(ok)
        elif cmd == b"wm_status":
            self.status = bytes(frames[1]) if len(frames) > 1 else b"{}"
            self.zmq_socket.send(b"ok")
        else:
            super().handle_zmq(frames)


def _silence_std_streams() -> None:
    devnull = os.open(os.devnull, os.O_WRONLY)
    sys.stdout.flush()
    sys.stderr.flush()
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)


def main(argv: list[str] | None = None) -> int:
    """Run the server until the parent process exits (or SIGTERM/SIGINT)."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--title", default="wristmark")
    ap.add_argument("--controls", action="store_true", help="open the control panel (animation slider)")
    ap.add_argument("--no-status", action="store_true", help="do not poll the status line")
    ap.add_argument("--parent", type=int, default=os.getppid(), help="exit when this pid is gone")
    ap.add_argument("--host", default=None, help="web server: also listen on this address (default: loopback only)")
    ap.add_argument("--legend", default=None, help="the legend's rows as JSON: [[label, [[r, g, b], ...]], ...]")
    args = ap.parse_args(argv)
    legend = None if args.legend is None else [(str(label), tuple(tuple(c) for c in colors))
                                               for label, colors in json.loads(args.legend)]
    lower_priority()
    try:
        bridge = WristmarkBridge(served_page(args.title, args.controls, not args.no_status, legend), web_host=args.host,
                                 host="127.0.0.1")
    except AddressError as e:
        print(f"error={e}", flush=True)
        return 2
    base = bridge.web_url.rsplit("/static/", 1)[0]
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={base}{PAGE_PATH}", flush=True)
    _silence_std_streams()

    def check_parent() -> None:
        try:
            os.kill(args.parent, 0)
        except OSError:
            tornado.ioloop.IOLoop.current().stop()
            return
        if os.getppid() != args.parent:
            tornado.ioloop.IOLoop.current().stop()

    tornado.ioloop.PeriodicCallback(check_parent, 500).start()
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
