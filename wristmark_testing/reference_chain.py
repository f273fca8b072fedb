"""An independent implementation of docs/design.md's kinematic chain, for tests only.

Written straight from the contract with 4x4 homogeneous matrices and no code shared with
``models``: segment t maps {tb} -> {te} by p = L/theta [cos d (1 - cos t), sin d (cos t - 1),
sin t] (evaluated through the identical chord form 2/theta sin(theta/2) [...] so that theta ->
0 has no cancellation) and R = Rz(-d) Ry(t) Rz(d); the chain is
{w} -> Rz(phi) Tz(d) -> {1b} -> seg 1 -> {1e} -> Tz(L_r) -> {2b} -> seg 2 -> {2e}
-> Tz(l_marker) -> {wm} -> Tz(l_tip) -> tip.
"""

from __future__ import annotations

import math

import numpy as np


def Rz(a: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 0], T[0, 1], T[1, 0], T[1, 1] = math.cos(a), -math.sin(a), math.sin(a), math.cos(a)
    return T


def Ry(a: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 0], T[0, 2], T[2, 0], T[2, 2] = math.cos(a), math.sin(a), -math.sin(a), math.cos(a)
    return T


def Tz(z: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = z
    return T


def segment_eq1(L: float, theta: float, delta: float) -> np.ndarray:
    """Paper eq. 1-2 literally (only for theta well away from 0)."""
    T = Rz(-delta) @ Ry(theta) @ Rz(delta)
    T[:3, 3] = (L / theta) * np.array(
        [
            math.cos(delta) * (1 - math.cos(theta)),
            math.sin(delta) * (math.cos(theta) - 1),
            math.sin(theta),
        ]
    )
    return T


def segment(L: float, theta: float, delta: float) -> np.ndarray:
    """One segment, {te} in {tb}: the arc's chord, exact for every theta (limit L at 0)."""
    half = theta / 2.0
    # 2 L/theta sin(theta/2) = L sinc(theta/2); two series terms below 1e-8 (tiny, subnormal)
    chord = L * (1 - half * half / 6) if abs(half) < 1e-8 else L * math.sin(half) / half
    return Rz(-delta) @ Ry(theta / 2.0) @ Tz(chord) @ Ry(theta / 2.0) @ Rz(delta)


def chain(lengths: dict[str, float], psi: np.ndarray, stem_bend: float = 0.0) -> dict[str, np.ndarray]:
    """Frames in {w}: keys 1b, 1e, 2b, 2e, marker, tip. ``stem_bend`` [rad]: the exposed stem
    (length d) bent as one more constant-curvature segment in segment 1's plane (the simulated
    arm's stem coupling); 0: the straight stem Tz(d) of docs/design.md."""
    phi, d, t1, d1, t2, d2 = (float(x) for x in psi)
    out = {"1b": Rz(phi) @ (Tz(d) if stem_bend == 0.0 else segment(d, stem_bend, d1))}
    out["1e"] = out["1b"] @ segment(lengths["L1"], t1, d1)
    out["2b"] = out["1e"] @ Tz(lengths["Lr"])
    out["2e"] = out["2b"] @ segment(lengths["L2"], t2, d2)
    out["marker"] = out["2e"] @ Tz(lengths["lm"])
    out["tip"] = out["marker"] @ Tz(lengths["lt"])
    return out
