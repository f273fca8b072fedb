"""The actuators of an arm on a ROS 2 graph (``wristmark servo --actuator ros2:NS``): an
:class:`rig.link.actuator_link.ActuatorLink` over Cyclone DDS, without ROS, in real time on the
host's ``time.monotonic()``.

Topics (CRTK names): out ``NS/servo_jp`` (sensor_msgs/JointState: the actuator targets, named
after the robot file's actuators: phi, d, s1a, s1b, s2a, s2b [rad, m, m, m, m, m] for the
reference arm, e.g. d, s1a, ..., s3c for tendon3) and ``NS/crtk_command``
(std_msgs/String: ``enable`` before the first target, ``disable`` at the end); in
``NS/measured_js`` (sensor_msgs/JointState from the arm's driver: the encoders, by name, any
order, extra joints ignored) and ``NS/operating_state`` (crtk_msgs/OperatingState: ENABLED,
DISABLED, PAUSED, FAULT). QoS: reliable, keep last 1 out (only the newest target matters);
best effort, keep last 1 in; operating_state reliable (no change lost), volatile (it matches a
volatile and a transient-local writer alike), keep last 8 (every change, in order).

Safety: nothing moves before a ``measured_js`` arrived (:meth:`probe`, before any motion); the
arm silent (no ``measured_js``) for longer than ``timeout`` [s] while the loop runs is an
:class:`ActuatorError` (the loop's safe stop); :meth:`hold` commands the measured positions;
:meth:`close` holds and disables and never raises (a failure is kept in ``close_error``). A
malformed ``measured_js`` (a name missing, a non-finite position) is counted and ignored.

The arm's operating state: after ``enable`` nothing is sent until the arm reports ENABLED
(``ENABLE_TIMEOUT_S`` at most, then an :class:`ActuatorNotEnabled`, nothing moved); from then on a
state other than ENABLED (its watchdog tripped, an operator disabled or paused it, a fault) is an
:class:`ActuatorNotEnabled` (the loop's safe stop, as the serial box's "not enabled"). An arm that
publishes no ``operating_state`` is refused after that wait, unless ``require_operating_state`` is
False (``--no-operating-state``, unsafe: a disabled arm then goes unnoticed until it reports).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.models.actuation import ACTUATOR_NAMES
from wristmark.rig.link.actuator_driver import ActuatorError, ActuatorNotEnabled
from wristmark.rig.ros2.bridge import clean_namespace
from wristmark.rig.ros2.dds_config import open_participant, require_cyclonedds

Array = NDArray[np.float64]
ARM_TIMEOUT_S = 0.25  # [s] the arm's driver silent for longer: a safe stop
KEEPALIVE_S = 0.05  # [s] while the loop waits, the last target is sent again this often (the arm's watchdog)
MATCH_TIMEOUT_S = 5.0  # [s] longest wait for the arm's driver to subscribe to servo_jp and crtk_command
FIRST_STATE_TIMEOUT_S = 10.0  # [s] longest wait for the first measured_js (discovery included)
ENABLE_TIMEOUT_S = 3.0  # [s] longest wait after enable for the arm's operating_state ENABLED
STATE_CAUSES = {"DISABLED": "its watchdog or an operator", "PAUSED": "paused by an operator or its driver",
                "FAULT": "a fault in the arm"}  # CRTK's states other than ENABLED, and what says so


@dataclass(frozen=True)
class ArmState:
    """The newest ``measured_js``: positions [rad, m, ...] in the link's actuator order, arrival [s]."""

    positions: Array
    arrival: float


class Ros2ActuatorLink:
    """The servo loop's link to an arm driven over ROS 2 (module docstring)."""

    simulated = False

    def __init__(self, namespace: str, timeout: float = ARM_TIMEOUT_S, require_operating_state: bool = True,
                 names: tuple[str, ...] = ACTUATOR_NAMES, participant: Any = None) -> None:
        """names: the arm's actuator names, in its order (models.arm_spec.actuator_names; default
        the reference arm's six); participant: a participant of dds_config.open_participant shared
        with the process's other links and bridges (None: its own)."""
        require_cyclonedds("--actuator ros2:NS")
        from cyclonedds.core import Listener, Policy, Qos
        from cyclonedds.pub import DataWriter
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        from wristmark.rig.ros2 import messages as M

        self.M = M
        self.namespace = clean_namespace(namespace)
        self.names = tuple(names)
        self.timeout = float(timeout)
        self.state: ArmState | None = None
        self.malformed = 0
        self.sent = 0
        self._last_target: Array | None = None
        self._last_sent = -float("inf")
        self.close_error = ""
        self.require_operating_state = bool(require_operating_state)
        self.operating_state: str | None = None  # the newest operating_state's state (None: none yet)
        self.state_changes = 0
        self.malformed_state = 0
        self._enable_sent = False
        self._watch_state = False  # the arm reported ENABLED after enable: any other state stops the loop
        self._longest_gap = 0.0  # [s] between this host's servo_jp (and from enable to the first)
        self._closed = False
        self._lock = threading.Lock()
        self._got_state = threading.Event()
        self.participant = participant if participant is not None else open_participant()
        out_qos = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(1),
                      Policy.Durability.Volatile)
        in_qos = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(1), Policy.Durability.Volatile)

        def topic(name: str, cls: type) -> Any:
            return Topic(self.participant, M.topic_name(f"{self.namespace}/{name}"), cls)

        self._servo_jp = DataWriter(self.participant, topic("servo_jp", M.JointState), out_qos)
        self._command = DataWriter(self.participant, topic("crtk_command", M.String), out_qos)
        self._reader = DataReader(self.participant, topic("measured_js", M.JointState), in_qos,
                                  listener=Listener(on_data_available=self._on_measured))
        state_qos = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(8),
                        Policy.Durability.Volatile)
        self._state_reader = DataReader(self.participant, topic("operating_state", M.OperatingState), state_qos,
                                        listener=Listener(on_data_available=self._on_operating_state))

    @property
    def port(self) -> str:
        """What the link talks to (for the result JSON)."""
        return f"ros2:{self.namespace}"

    # -- in ------------------------------------------------------------------------------------
    def _on_measured(self, reader: Any) -> None:
        now = time.monotonic()
        try:
            samples = reader.take(N=8)
        except Exception:  # noqa: BLE001 - undecodable: counted, ignored
            self.malformed += 1
            return
        for msg in samples:
            if not hasattr(msg, "position"):
                continue  # an InvalidSample: the writer left (no data)
            q = self._positions(msg)
            if q is None:
                self.malformed += 1
                continue
            with self._lock:
                self.state = ArmState(q, now)
            self._got_state.set()

    def _on_operating_state(self, reader: Any) -> None:
        try:
            samples = reader.take(N=16)
        except Exception:  # noqa: BLE001 - undecodable: counted, ignored
            self.malformed_state += 1
            return
        for msg in samples:
            if not hasattr(msg, "state"):
                continue  # an InvalidSample: the writer left (no data)
            state = str(msg.state)
            with self._lock:
                if state != self.operating_state:
                    self.state_changes += 1
                self.operating_state = state
                if state == "ENABLED" and self._enable_sent:
                    self._watch_state = True  # in order: every later sample is after this one

    def _check_operating_state(self) -> None:
        """ActuatorNotEnabled once the arm, having reported ENABLED, reports anything else."""
        with self._lock:
            watch, state = self._watch_state, self.operating_state
        if watch and state != "ENABLED":
            why = STATE_CAUSES.get(str(state), "a state CRTK does not name")
            gap = max(self._longest_gap, time.monotonic() - self._last_sent)
            raise ActuatorNotEnabled(f"{self.port}: the arm reports {state} ({why}; the longest gap between this "
                                     f"host's servo_jp was {1000 * gap:.0f} ms)")

    def _positions(self, msg: Any) -> Array | None:
        names, pos = list(getattr(msg, "name", [])), list(getattr(msg, "position", []))
        if len(names) != len(pos) or not set(self.names) <= set(names):
            return None
        q = np.array([pos[names.index(n)] for n in self.names], float)
        return q if np.all(np.isfinite(q)) else None

    def _fresh_state(self) -> ArmState:
        with self._lock:
            st = self.state
        if st is None:
            raise ActuatorError(f"{self.port}: no measured_js from the arm")
        silent = time.monotonic() - st.arrival
        if silent > self.timeout:
            raise ActuatorError(f"{self.port}: the arm's driver is silent (no measured_js for {silent:.2f} s)")
        self._check_operating_state()
        return st

    # -- the ActuatorLink ------------------------------------------------------------------------
    @property
    def time(self) -> float:
        """The host's monotonic clock [s]."""
        return time.monotonic()

    @property
    def last_target(self) -> Array | None:
        """The target last sent [rad or m each] (None before the first)."""
        return self._last_target

    def probe(self, wait_s: float = FIRST_STATE_TIMEOUT_S) -> Array:
        """Wait for the arm's first measured_js (before any motion); ActuatorError when none comes."""
        if not self._got_state.wait(wait_s):
            raise ActuatorError(f"{self.port}: no measured_js within {wait_s:g} s (is the arm's driver running, "
                                "on this DDS domain and network?)")
        return self._fresh_state().positions.copy()

    def connect(self, t_now: float | None = None) -> None:
        """Enable the arm (``crtk_command`` enable) right before the first target, once the arm's
        driver subscribes to servo_jp and crtk_command (a volatile command sent before would be lost),
        and wait until its operating_state says ENABLED (module docstring)."""
        deadline = time.monotonic() + MATCH_TIMEOUT_S
        while not all(w.get_publication_matched_status().current_count > 0 for w in (self._servo_jp, self._command)):
            if time.monotonic() > deadline:
                raise ActuatorError(f"{self.port}: the arm's driver does not subscribe to servo_jp and crtk_command")
            time.sleep(0.01)
        self._fresh_state()
        with self._lock:
            seen = self.operating_state
            self._enable_sent = True
        if seen == "FAULT":
            raise ActuatorNotEnabled(f"{self.port}: the arm reports FAULT: not enabling it (clear the fault first)")
        self._command.write(self.M.String("enable"))
        self._last_sent = time.monotonic()  # the gaps between servo_jp count from enable
        if seen is None and not self.require_operating_state:
            return  # --no-operating-state and nothing heard: watched only once it reports ENABLED
        deadline = time.monotonic() + ENABLE_TIMEOUT_S
        while True:
            with self._lock:
                watch, state = self._watch_state, self.operating_state
            if watch:
                self._fresh_state()  # ENABLED, then maybe already something else: a safe stop before any target
                return
            if time.monotonic() > deadline:
                break
            self._fresh_state()
            time.sleep(0.005)
        if state is None:
            raise ActuatorNotEnabled(
                f"{self.port}: no operating_state from the arm within {ENABLE_TIMEOUT_S:g} s of enable: refusing to "
                "move an arm whose enabled state cannot be seen (--no-operating-state drives it anyway, unsafe; "
                "docs/ros2.md)")
        raise ActuatorNotEnabled(f"{self.port}: the arm reports {state}, not ENABLED, {ENABLE_TIMEOUT_S:g} s after "
                                 "enable: refusing to move it")

    def advance_to(self, t: float) -> None:
        """Wait until ``t`` on the monotonic clock [s], watching the arm's driver (ActuatorError
        when it fell silent)."""
        while True:
            self._fresh_state()
            now = time.monotonic()
            if self._last_target is not None and now - self._last_sent >= KEEPALIVE_S:
                self.send_target(self._last_target)  # the arm's watchdog sees a live host
            remaining = t - now
            if remaining <= 0:
                return
            time.sleep(min(remaining, 0.01))

    def send_target(self, actuators: Array) -> None:
        """Publish the actuator targets [rad, m, ...] on servo_jp."""
        self._fresh_state()
        self._publish(actuators)

    def _publish(self, actuators: Array) -> None:
        a = np.asarray(actuators, float)
        if a.shape != (len(self.names),) or not np.all(np.isfinite(a)):
            raise ActuatorError(f"{self.port}: refusing a target that is not {len(self.names)} finite numbers")
        M = self.M
        ns = time.time_ns()
        self._servo_jp.write(M.JointState(M.Header(M.Time(ns // 1_000_000_000, ns % 1_000_000_000), ""),
                                          list(self.names), [float(x) for x in a], [], []))
        self.sent += 1
        now = time.monotonic()
        self._longest_gap = max(self._longest_gap, now - self._last_sent) if self._enable_sent else 0.0
        self._last_target, self._last_sent = a.copy(), now

    def hold(self) -> None:
        """Command the measured positions (the arm stays where it is)."""
        with self._lock:
            st = self.state
        if st is not None and time.monotonic() - st.arrival <= self.timeout:
            self._publish(st.positions)  # whatever the arm's operating state: holding moves nothing

    def measured_actuators(self) -> Array:
        """The newest measured_js [rad, m, ...] (ActuatorError when the arm fell silent)."""
        return self._fresh_state().positions.copy()

    def close(self) -> None:
        """Hold, disable, leave the graph. Never raises (the failure is kept in ``close_error``)."""
        if self._closed:
            return
        self._closed = True
        problems = []
        for name, step in (("hold", self.hold), ("disable", lambda: self._command.write(self.M.String("disable")))):
            try:
                step()
            except Exception as e:  # noqa: BLE001 - closing goes on; the cause is kept
                problems.append(f"{name}: {e}")
        time.sleep(0.05)  # let the reliable writers deliver before the participant goes
        self._reader.set_listener(None)
        self._state_reader.set_listener(None)
        self.participant = None
        self.close_error = "; ".join(problems)

    def stats(self) -> dict[str, Any]:
        """Counters for the result JSON."""
        return {"sent": self.sent, "malformed_measured_js": self.malformed,
                "silent_timeout_s": self.timeout if math.isfinite(self.timeout) else None,
                "operating_state": self.operating_state, "operating_state_required": self.require_operating_state,
                "operating_state_changes": self.state_changes, "malformed_operating_state": self.malformed_state,
                "longest_servo_jp_gap_ms": round(1000 * self._longest_gap, 1)}
