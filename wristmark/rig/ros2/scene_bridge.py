"""Several arms on one ROS 2 graph (``wristmark servo --scene SCENE --ros2 [NS]``): one Cyclone DDS
participant for the process and one :class:`rig.ros2.bridge.Ros2Bridge` per arm under
``NS/NAME`` (``NS/NAME/measured_cp``, ``NS/NAME/marker/measured_cp``, ``NS/NAME/measured_js``,
``NS/NAME/setpoint_js``; with ``--target NAME=ros2``, ``NS/NAME/servo_cp`` in), the same message
types and QoS as one arm. Poses are in the scene's {w} (frame_id ``world``, as a scene's
``--record``): each arm's tip and marker moved out of its own {w} by its base pose, each
``servo_cp`` moved into it before its target store (clamped, speed bounded there).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import Arm
from wristmark.rig.ros2.bridge import Ros2Bridge, clean_namespace
from wristmark.rig.ros2.dds_config import open_participant
from wristmark.rig.targets.live_target import LiveTargets

Array = NDArray[np.float64]


def arm_namespace(namespace: str | None, arm: str) -> str:
    """Arm ``arm``'s namespace under ``namespace`` (``/NS/NAME``); ValueError for a name ROS 2 refuses."""
    return clean_namespace(f"{clean_namespace(namespace)}/{arm}")


class SceneBridges:
    """Every arm's bridge on one participant; :meth:`on_cycle` is the scene loop's ``on_cycle(arm, record)``."""

    def __init__(self, namespace: str | None, params: Mapping[str, Arm], bases: Mapping[str, Array],
                 targets: Mapping[str, LiveTargets] | None = None, links: Mapping[str, Any] | None = None,
                 participant: Any = None) -> None:
        """``params`` and ``bases`` (4x4 [m], the arm's {w} in the scene's) by arm; ``targets``: the
        store of each arm that follows its ``servo_cp``; ``links`` (set once the boxes are open):
        each arm's link, whose last state gives its measured actuators; ``participant``: one of
        dds_config.open_participant shared with the arms' ROS 2 links (None: its own)."""
        self.namespace = clean_namespace(namespace)
        self.links: dict[str, Any] = dict(links or {})
        self.participant = participant if participant is not None else open_participant()
        self.bridges: dict[str, Ros2Bridge] = {}
        try:
            for n, p in params.items():
                self.bridges[n] = Ros2Bridge(arm_namespace(namespace, n), p, (targets or {}).get(n), wall_clock=True,
                                             participant=self.participant, base=np.asarray(bases[n], float))
        except BaseException:
            self.close()
            raise

    def on_cycle(self, arm: str, rec: Any) -> None:
        """Arm ``arm``'s cycle to its bridge (never blocks)."""
        self.bridges[arm].on_cycle(rec, self.links.get(arm))

    def report(self) -> dict[str, dict[str, Any]]:
        """Each arm's topics and counters (Ros2Bridge.report)."""
        return {n: b.report() for n, b in self.bridges.items()}

    def close(self) -> None:
        """Close every arm's bridge, then the participant."""
        for b in self.bridges.values():
            b.close()
        self.participant = None
