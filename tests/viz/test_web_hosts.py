"""The 3D view listens on loopback only unless --host asks for more (issue 17, item 1).

The listening sockets are read from the server processes themselves (psutil): by default every
one is on 127.0.0.1 or ::1; ``--host ADDRESS`` adds that address and says so on stderr.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import psutil
import pytest

from wristmark.viz.web_hosts import exposure_notice, listen_addresses

pytestmark = [pytest.mark.network]

ROOT = Path(__file__).resolve().parents[2]
LOOPBACK = {"127.0.0.1", "::1"}


def listening(pid: int) -> set[tuple[str, int]]:
    """(address, port) of every listening TCP socket of ``pid`` and its descendants."""
    procs = [psutil.Process(pid)]
    procs += procs[0].children(recursive=True)
    out = set()
    for p in procs:
        try:
            conns = p.net_connections(kind="inet")
        except psutil.NoSuchProcess:
            continue
        out |= {(c.laddr.ip, c.laddr.port) for c in conns if c.status == psutil.CONN_LISTEN}
    return out


@contextmanager
def served_view(*extra: str) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """``wristmark view --json`` running; yields the process and the URL it printed."""
    proc = subprocess.Popen([sys.executable, "-m", "wristmark", "view", "--json", "--serve-seconds", "120", *extra],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line, proc.stderr.read() if proc.stderr else ""
        yield proc, json.loads(line)["url"]
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _port(url: str) -> int:
    return int(url.split(":")[2].split("/")[0])


def test_view_listens_on_loopback_only() -> None:
    with served_view() as (proc, url):
        socks = listening(proc.pid)
        port = _port(url)
        assert any(p == port for _, p in socks), socks  # the page's port is one of them
        assert {ip for ip, _ in socks} <= LOOPBACK, f"listening beyond loopback: {sorted(socks)}"
        with urllib.request.urlopen(url, timeout=10) as r:  # and the printed URL answers
            assert r.status == 200 and b"wristmark" in r.read()
        with urllib.request.urlopen(url + "/status", timeout=10) as r:
            assert r.status == 200


def test_host_opts_in_to_another_address_and_says_so() -> None:
    # 127.0.0.3 stands for "another interface": the opt-in is shown without exposing the test's
    # server beyond loopback (what 0.0.0.0 would add is checked by listen_addresses below).
    with served_view("--host", "127.0.0.3") as (proc, url):
        socks = listening(proc.pid)
        assert ("127.0.0.3", _port(url)) in socks, socks
        with urllib.request.urlopen(url, timeout=10) as r:  # the loopback URL still works
            assert r.status == 200
    assert proc.stderr is not None
    err = proc.stderr.read()
    assert "also listens on 127.0.0.3" in err and "anyone" in err, err


def test_the_live_view_is_on_loopback_too() -> None:
    from wristmark.viz.live import start_live_view

    view = start_live_view(stream=None)
    try:
        socks = listening(view.server.proc.pid)
        assert any(p == _port(view.url) for _, p in socks), socks
        assert {ip for ip, _ in socks} <= LOOPBACK, sorted(socks)
    finally:
        view.close()


def test_an_address_not_on_this_machine_is_one_line() -> None:
    p = subprocess.run([sys.executable, "-m", "wristmark", "view", "--serve-seconds", "1", "--host", "192.0.2.1"],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    assert len(p.stderr.strip().splitlines()) == 1 and "cannot listen on 192.0.2.1" in p.stderr


@pytest.mark.parametrize(("host", "required"), [
    (None, ["127.0.0.1"]), ("0.0.0.0", ["0.0.0.0"]), ("::", ["::", "127.0.0.1"]),
    ("10.1.2.3", ["10.1.2.3", "127.0.0.1"]),
])
def test_listen_addresses_keep_loopback(host: str | None, required: list[str]) -> None:
    assert listen_addresses(host)[0] == required
    assert (exposure_notice(host, 7000) is None) == (host is None)
