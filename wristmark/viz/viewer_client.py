"""Start our Meshcat server process and talk to it (the client side of viz.meshcat_server).

``MeshcatServer.start()`` runs ``python -m viz.meshcat_server`` with its output handled (the
server silences itself after printing its URLs, so no pipe can fill up and hang it) and ends
it on ``close()``, at interpreter exit, or by itself when this process dies.
:class:`ZmqWindow` is a drop-in for ``meshcat.visualizer.ViewerWindow`` whose ``batch()``
groups every command sent inside it into one ZMQ round trip.
"""

from __future__ import annotations

import atexit
import contextlib
import json
import os
import select
import subprocess
import sys
import threading
import time
import urllib.parse
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, TextIO

import meshcat
import zmq

from wristmark.models.errors import WristmarkError
from wristmark.viz import command_tree
from wristmark.viz.style import LegendRow
from wristmark.viz.web_hosts import exposure_notice

STARTUP_TIMEOUT = 30.0  # [s] for the server to print its URLs (imports on a loaded machine)
REPLY_TIMEOUT_MS = 10000  # [ms] a command without a reply means the server is gone


class ViewerError(WristmarkError):
    """The Meshcat server could not be started or stopped answering."""


class ZmqWindow:
    """Meshcat window talking to a running server over ZMQ, with command batching.

    Not thread-safe: use it from one thread at a time.
    """

    def __init__(self, zmq_url: str, web_url: str) -> None:
        self.zmq_url = zmq_url
        self.web_url = web_url
        self._socket: zmq.Socket[bytes] = zmq.Context.instance().socket(zmq.REQ)
        self._socket.setsockopt(zmq.LINGER, 0)
        self._socket.setsockopt(zmq.RCVTIMEO, REPLY_TIMEOUT_MS)
        self._socket.connect(zmq_url)
        self._batch: list[bytes] | None = None
        self._lock = threading.Lock()

    def _request(self, frames: list[bytes]) -> bytes:
        with self._lock:
            try:
                self._socket.send_multipart(frames)
                return bytes(self._socket.recv())
            except zmq.Again as e:
                raise ViewerError(f"the Meshcat server at {self.zmq_url} stopped answering") from e
            except zmq.ZMQError as e:
                raise ViewerError(f"Meshcat server connection failed: {e}") from e

    def send(self, command: Any) -> None:
        """Send (or, inside ``batch()``, queue) one meshcat.commands object."""
        kind, path, data = command_tree.pack(command)
        frames = [kind.encode(), path.encode(), data]
        if self._batch is not None:
            self._batch += frames
        else:
            self._request(frames)

    @contextlib.contextmanager
    def batch(self) -> Iterator[None]:
        """Queue every command sent in the block; send them in one request at its end."""
        if self._batch is not None:  # nested: the outer block sends
            yield
            return
        self._batch = []
        try:
            yield
            frames = self._batch
        finally:
            self._batch = None
        if frames:
            reply = self._request([b"wm_batch", *frames])
            if reply != b"ok":
                raise ViewerError(f"Meshcat server refused a batch: {reply.decode(errors='replace')}")

    def send_status(self, status: dict[str, str]) -> None:
        """Set the status line shown under the legend of live pages."""
        self._request([b"wm_status", json.dumps(status).encode()])

    def get_scene(self) -> str:
        """Meshcat's own static HTML of the current scene."""
        return self._request([b"get_scene"]).decode("utf-8")

    def close(self) -> None:
        """Close the socket (the server keeps running)."""
        self._socket.close(0)


class MeshcatServer:
    """A running ``viz.meshcat_server`` process; ``url`` is the page to open."""

    def __init__(self, proc: subprocess.Popen[bytes], zmq_url: str, url: str) -> None:
        self.proc = proc
        self.zmq_url = zmq_url
        self.url = url
        self._windows: list[ZmqWindow] = []
        atexit.register(self.close)

    @classmethod
    def start(cls, title: str = "wristmark", controls: bool = False, status: bool = True,
              host: str | None = None, stream: TextIO | None = sys.stderr,
              legend: Sequence[LegendRow] | None = None) -> MeshcatServer:
        """Start the server process; return once it listens (raises ViewerError otherwise).

        The page is served on loopback only unless ``host`` adds an address (viz.web_hosts);
        then a line on ``stream`` says who else can reach it. ``legend``: the page's legend rows
        (default style.LEGEND)."""
        args = [sys.executable, "-u", "-m", "wristmark.viz.meshcat_server", "--title", title,
                "--parent", str(os.getpid())]
        if controls:
            args.append("--controls")
        if not status:
            args.append("--no-status")
        if host is not None:
            args += ["--host", host]
        if legend is not None:
            args += ["--legend", json.dumps([[label, [list(c) for c in colors]] for label, colors in legend])]
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        try:
            proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                    stdin=subprocess.DEVNULL, env=env, start_new_session=True)
        except OSError as e:
            raise ViewerError(f"cannot start the Meshcat server: {e}") from e
        assert proc.stdout is not None
        lines: dict[str, str] = {}
        buf = b""
        fd = proc.stdout.fileno()
        deadline = time.monotonic() + STARTUP_TIMEOUT
        while not {"zmq_url", "web_url"} <= lines.keys():
            left = deadline - time.monotonic()
            if "error" in lines or left <= 0 or proc.poll() is not None:
                proc.kill()
                proc.wait()
                if "error" in lines:
                    raise ViewerError(f"the 3D view cannot start: {lines['error']} (--host {host})")
                raise ViewerError("the Meshcat server did not start (is port 7000+ free? is meshcat installed?)")
            ready, _, _ = select.select([fd], [], [], min(left, 0.5))
            if not ready:
                continue
            chunk = os.read(fd, 4096)
            if not chunk:
                time.sleep(0.05)  # the server is exiting: poll() sees it next round
                continue
            buf += chunk
            *complete, buf = buf.split(b"\n")
            for line in complete:
                key, _, value = line.decode(errors="replace").strip().partition("=")
                if key in ("zmq_url", "web_url", "error"):
                    lines[key] = value
        proc.stdout.close()
        server = cls(proc, lines["zmq_url"], lines["web_url"])
        notice = exposure_notice(host, server.port)
        if notice and stream is not None:
            print(notice, file=stream, flush=True)
        return server

    @property
    def port(self) -> int:
        """The web server's port."""
        return int(urllib.parse.urlsplit(self.url).port or 80)

    def visualizer(self) -> meshcat.Visualizer:
        """A Meshcat visualizer bound to this server (its window is a :class:`ZmqWindow`)."""
        window = ZmqWindow(self.zmq_url, self.url)
        self._windows.append(window)
        return meshcat.Visualizer(window=window)

    def close(self) -> None:
        """Stop the server process (idempotent)."""
        for w in self._windows:
            w.close()
        self._windows.clear()
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        atexit.unregister(self.close)
