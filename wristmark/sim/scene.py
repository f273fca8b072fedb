"""The scene file, re-exported: it is parsed in :mod:`rig.loop.scene_file` (no simulated bench),
so that the hardware path (``wristmark servo --scene``) reads it too."""

from __future__ import annotations

from wristmark.rig.loop.scene_file import ARM_KEYS, MAX_ARMS, SCENE_KEYS, Scene, SceneArm, pose_from_xyz_rpy

__all__ = ["ARM_KEYS", "MAX_ARMS", "SCENE_KEYS", "Scene", "SceneArm", "pose_from_xyz_rpy"]
