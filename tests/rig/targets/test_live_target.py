"""Live targets (rig/targets/live_target.py): the JSON line format, the workspace clamp, the
speed bound, the hold after a silent stream, malformed lines counted and dropped, and the TCP
source on loopback with a real socket."""

from __future__ import annotations

import io
import json
import os
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from wristmark.models.errors import InputError
from wristmark.rig.targets.live_target import (
    MAX_WARNINGS,
    LiveTargets,
    StdinTargets,
    TargetFollower,
    TcpTargets,
    Workspace,
    live_trajectory,
    parse_target,
    parse_target_spec,
)

C = np.array([0.08, 0.0, 0.15])


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def store(clock: FakeClock | None = None, warn: io.StringIO | None = None) -> LiveTargets:
    return LiveTargets(Workspace.around(C), timeout=0.2, clock=clock or time.monotonic, warn=warn or io.StringIO())


def test_a_line_is_time_position_and_optional_quaternion() -> None:
    t, p, R = parse_target('{"t": 1.5, "p": [0.08, 0.0, 0.15]}')
    assert t == 1.5 and p.tolist() == [0.08, 0.0, 0.15] and R is None
    _, _, R = parse_target(b'{"t": 2, "p": [0, 0, 0], "q": [0, 0, 0.7071068, 0.7071068]}\n')
    assert R is not None
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-6)  # 90 deg about z_w


@pytest.mark.parametrize("line, reason", [
    ("not json", "not JSON"),
    ("[1, 2, 3]", "not a JSON object"),
    ('"p"', "not a JSON object"),
    ('{"t": 0}', '"p"'),
    ('{"p": [0, 0]}', '"p"'),
    ('{"p": [0, NaN, 0]}', '"p"'),
    ('{"p": [0, Infinity, 0]}', '"p"'),
    ('{"p": [0, "1", 0]}', '"p"'),
    ('{"p": [true, 0, 0]}', '"p"'),
    ('{"t": NaN, "p": [0, 0, 0]}', '"t"'),
    ('{"t": 0, "p": [0, 0, 0], "q": [0, 0, 0, 0]}', "quaternion norm"),
    ('{"t": 0, "p": [0, 0, 0], "q": [0, 0, 1]}', '"q"'),
    ('{"t": 0, "p": [0, 0, 0], "q": [0, 0, NaN, 1]}', '"q"'),
])
def test_malformed_lines_are_dropped_counted_and_warned_in_one_line(line: str, reason: str) -> None:
    warn = io.StringIO()
    s = store(warn=warn)
    assert not s.offer_line(line)
    assert s.counts.dropped == 1 and s.counts.received == 0 and s.newest()[0] is None
    lines = warn.getvalue().splitlines()
    assert len(lines) == 1 and "dropped" in lines[0] and reason in lines[0]


def test_warnings_stop_after_a_few_but_every_drop_is_counted() -> None:
    warn = io.StringIO()
    s = store(warn=warn)
    for _ in range(50):
        s.offer_line("{")
    assert s.counts.dropped == 50 and len(warn.getvalue().splitlines()) == MAX_WARNINGS


def test_outside_the_workspace_is_clamped_and_counted() -> None:
    s = store()
    assert s.offer_line(json.dumps({"t": 0, "p": [1.0, -1.0, 0.15]}))
    target, fresh = s.newest()
    assert fresh and target is not None
    ws = s.workspace
    np.testing.assert_allclose(target.p, [C[0] + ws.half[0], C[1] - ws.half[1], 0.15])
    assert s.counts.clamped == 1 and s.counts.received == 1


def test_an_older_time_than_the_newest_is_dropped() -> None:
    s = store()
    assert s.offer(C + [0.001, 0, 0], t=2.0)
    assert not s.offer(C + [0.002, 0, 0], t=1.0)
    np.testing.assert_allclose(s.newest()[0].p, C + [0.001, 0, 0])  # type: ignore[union-attr]
    assert s.counts.dropped == 1


def test_the_follower_is_speed_bounded_and_holds_when_the_stream_is_silent() -> None:
    clock = FakeClock()
    s = store(clock)
    f = TargetFollower(s, C, None, max_speed=0.01)
    f.advance(0.0)
    f.advance(1.0)
    np.testing.assert_allclose(f.pose()[0], C)  # nothing received: the start is held
    assert s.counts.holds == 0
    s.offer(C + [0.02, 0, 0], t=0.0)
    f.advance(1.5)  # 0.5 s at 10 mm/s: 5 mm of the 20
    np.testing.assert_allclose(f.pose()[0], C + [0.005, 0, 0], atol=1e-12)
    clock.t += 0.3  # silent for longer than the timeout: held where the target stands
    f.advance(2.5)
    f.advance(3.5)
    np.testing.assert_allclose(f.pose()[0], C + [0.005, 0, 0], atol=1e-12)
    assert s.counts.holds == 1
    s.offer(C + [0.006, 0, 0], t=1.0)  # a fresh target resumes
    f.advance(4.5)
    np.testing.assert_allclose(f.pose()[0], C + [0.006, 0, 0], atol=1e-12)
    assert not f.holding


def test_the_orientation_turns_at_a_bounded_rate() -> None:
    s = store()
    f = TargetFollower(s, C, np.eye(3), max_angular_speed=0.5)
    Rz = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    s.offer(C, Rz, t=0.0)
    f.advance(0.0)
    f.advance(1.0)
    R = f.pose()[1]
    assert R is not None
    assert np.isclose(np.arccos((np.trace(R) - 1) / 2), 0.5)


def test_the_live_trajectory_waits_at_its_start() -> None:
    traj = live_trajectory(C, 3.0, "stdin").with_follower(store(), 0.01)
    assert traj.duration == 3.0 and traj.truncated(2.0).duration == 2.0
    p, v = traj.sample(1.0)
    np.testing.assert_allclose(p, C)
    assert not v.any() and traj.sample_orientation(1.0) is None


@pytest.mark.parametrize("spec", ["tcp:0.0.0.0:5000", "tcp:192.168.1.2:5000", "tcp:127.0.0.1:x", "tcp:70000",
                                  "udp:5000", "circle"])
def test_bad_target_specs_are_one_line_errors(spec: str) -> None:
    with pytest.raises(InputError) as e:
        parse_target_spec(spec)
    assert "\n" not in str(e.value)


def test_tcp_source_on_loopback_takes_lines_from_several_clients() -> None:
    s = store()
    src = TcpTargets(s, 0)
    try:
        assert src.describe == f"tcp:127.0.0.1:{src.port}"
        with socket.create_connection(("127.0.0.1", src.port), timeout=2) as a, \
                socket.create_connection(("127.0.0.1", src.port), timeout=2) as b:
            a.sendall(b'{"t": 0, "p": [0.08, 0.0, 0.15]}\nnonsense\n')
            # b sends only after a's lines are in: the two connections are not ordered otherwise, and
            # a's t = 0 arriving after b's t = 1 would rightly be dropped as older
            deadline = time.monotonic() + 5
            while s.counts.received + s.counts.dropped < 2 and time.monotonic() < deadline:
                time.sleep(0.01)
            b.sendall(b'{"t": 1, "p": [0.081, 0.0, 0.15]}\n' + b"x" * 70000 + b"\n")
            while s.counts.received + s.counts.dropped < 4 and time.monotonic() < deadline:
                time.sleep(0.01)
        assert s.counts.received == 2 and s.counts.dropped == 2
        np.testing.assert_allclose(s.newest()[0].p, [0.081, 0.0, 0.15])  # type: ignore[union-attr]
        listening = src.port
    finally:
        src.close()
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", listening), timeout=1)


def test_stdin_reads_its_file_descriptor_and_stops_when_closed() -> None:
    """Standard input is read from fd 0 (select + os.read), lines split across reads, an
    over-long line dropped, and the reader thread ends on close() though stdin stays open."""
    s = store()
    r, w = os.pipe()
    saved = os.dup(0)
    os.dup2(r, 0)
    try:
        src = StdinTargets(s)
        os.write(w, b'{"t": 0, "p": [0.08, 0.0, ')
        time.sleep(0.05)
        os.write(w, b'0.15]}\n' + b"x" * 70000 + b'\n{"t": 1, "p": [0.081, 0.0, 0.15]}\n')
        deadline = time.monotonic() + 5
        while s.counts.received + s.counts.dropped < 3 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert s.counts.received == 2 and s.counts.dropped == 1
        np.testing.assert_allclose(s.newest()[0].p, [0.081, 0.0, 0.15])  # type: ignore[union-attr]
        src.close()
        src._threads[0].join(timeout=1.0)
        assert not src._threads[0].is_alive()
    finally:
        os.dup2(saved, 0)
        for fd in (saved, r, w):
            os.close(fd)


def test_a_process_reading_targets_on_stdin_exits_cleanly_while_stdin_is_open() -> None:
    """The interpreter's shutdown with the reader waiting on an open stdin: no abort ("could not
    acquire lock for <stdin> at interpreter shutdown", exit -6), exit status 0."""
    code = ("import time\nfrom wristmark.rig.targets.live_target import LiveTargets, StdinTargets, Workspace\n"
            "import numpy as np\n"
            "src = StdinTargets(LiveTargets(Workspace(np.zeros(3) - 1, np.zeros(3) + 1)))\n"
            "time.sleep(0.3)\n")
    for _ in range(3):
        p = subprocess.run([sys.executable, "-c", code], stdin=subprocess.PIPE, capture_output=True, timeout=60)
        assert p.returncode == 0, p.stderr.decode()[-500:]
