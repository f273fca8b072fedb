"""Reading a coded sleeve's cells along a fitted pose: absolute column ids, direction and roll.

The corner fit ``T_fit`` (pose of {wm} in {ll} with relative corner indices) leaves 2 n
hypotheses (cvs.marker.code: roll by s columns, either direction of z_wm). ``CodeDecoder.read``
projects every code cell's centre (column centre angle, band centre height, on the sleeve) into
both cameras along ``T_fit``, keeps the cells facing the camera (cos_view >= ``min_cos_view``)
and samples the grey level there (bilinear). Each cell's darkness is measured against local
references, the neighbouring checker patches of the same column on the same side (the dark and
the white one(s) among columns j - 1, j, j + 1 of the nearer checker row; where one of the two
neighbours is not seen, column j's patch of that colour in the other row instead, as one
neighbour alone, nearer the light, is shaded unlike the cell; which of them are
dark, the checker's phase in the fit's relative columns, is measured from all references, and
fixes the parity of the shift):
``d = (W - v) / (W - B)`` (1 black, 0 white), averaged over the cameras weighted by contrast.
A column whose two checker patches both clip in a camera lies under the coaxial light's stripe
(docs/notes/highlight-stripe.md): in that camera neither its patches nor its cells are read.

Decision: each hypothesis' log-likelihood over the cells read (cell dark with probability
clip(d)), the best one; then a Hamming test on the confidently read cells (d > ``dark`` or
d < ``light``; the others are erasures, never errors): the best hypothesis is accepted if it
disagrees with at most one confident cell and every other hypothesis differs from it in at
least 2 (no disagreement) or 3 (one disagreement) of those cells. So one misread cell is
corrected or rejected, never turned into a wrong identity, whatever cells are seen; with the
shipped code three readable columns always give margin 4 (docs/marker_code.md). Otherwise the
reading is not ok and the caller keeps the modulo-column pose (``roll_known`` false).

A marker set (``family``: the sleeves of one family in use, cvs.marker.family) is decoded over
the union of all members' hypotheses with the same rule: the identity is (arm, shift,
direction), so one misread cell is corrected or rejected, never read as another arm's; a
sleeve whose cells cannot decide it gets no arm (``ok`` false, ``arm`` None).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.marker.cells import cell_darkness, sample_sleeve
from wristmark.cvs.marker.code import hypotheses
from wristmark.cvs.tracking.stereo_pose import HALF_TURN_X
from wristmark.models.errors import ConfigError
from wristmark.models.marker import MarkerModel

Array = NDArray[np.float64]
IntArray = NDArray[np.int_]


@dataclass(frozen=True)
class CodeReadSettings:
    """min_cos_view: cells (and references) seen more obliquely are not read [-]; dark, light:
    darkness above / below which a cell reads dark / white (between: not read) [-];
    min_contrast: least white - black reference difference [grey levels]; min_cells: least
    confidently read cells for a decision [-]; clipped_level: a column whose two checker patches
    both reach this grey level lies under a clipped highlight, and neither they nor its cells are
    read in that camera [grey levels]."""

    min_cos_view: float = 0.3
    dark: float = 0.65
    light: float = 0.35
    min_contrast: float = 25.0
    min_cells: int = 6
    clipped_level: float = 250.0

    def validate(self) -> None:
        """Raise ConfigError naming the offending key."""
        if not (0.0 <= self.light < self.dark <= 1.0):
            raise ConfigError("code reading needs 0 <= light < dark <= 1")
        if not (0.0 <= self.min_cos_view < 1.0 and self.min_contrast > 0 and self.min_cells >= 1):
            raise ConfigError("code reading needs 0 <= min_cos_view < 1, min_contrast > 0, min_cells >= 1")


@dataclass(frozen=True)
class CodeReading:
    """What the cells said. ok: identity decided; reason ('' when ok); shift, direction: the
    hypothesis (cvs.marker.code); T_fit_abs: 4x4 with T_abs = T_fit @ T_fit_abs (the absolute,
    rolled and oriented pose of {wm}); cells: confidently read cells; errors: of them, those
    that disagree with the decision; margin: least cell difference to another hypothesis over
    those cells; llr: log-likelihood of the best hypothesis minus the second best [-]; member:
    index of the decided sleeve in the decoder's marker set (-1: none), arm: its ``arm`` name."""

    ok: bool
    reason: str
    shift: int = 0
    direction: int = 1
    T_fit_abs: Array | None = None
    cells: int = 0
    errors: int = 0
    margin: int = 0
    llr: float = 0.0
    member: int = -1
    arm: str | None = None

    def absolute_ids(self, relative: IntArray, columns: int) -> IntArray:
        """Absolute corner ids of relative corner indices (-1 stays -1)."""
        rel = np.asarray(relative, int)
        ids = (rel + self.shift) % columns if self.direction > 0 else (self.shift - rel) % columns
        return np.where(rel >= 0, ids, -1)


def _rz(a: float) -> Array:
    c, s = np.cos(a), np.sin(a)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


class CodeDecoder:
    """Reads one coded marker's cells in stereo pairs of one calibration (module doc); with a
    ``family`` (marker set with ``marker``'s cell layout), decides which member it is too."""

    def __init__(self, camera: StereoCamera, marker: MarkerModel, settings: CodeReadSettings | None = None,
                 family: Sequence[MarkerModel] = ()) -> None:
        if marker.code is None:
            raise ConfigError("this marker has no 'code': nothing to decode")
        self.members: tuple[MarkerModel, ...] = tuple(family) or (marker,)
        for m in self.members:
            if m.code is None or m.code.bands != marker.code.bands or m.columns != marker.columns:
                raise ConfigError("a marker set needs coded sleeves with the same columns and code bands")
        self.settings = settings or CodeReadSettings()
        self.settings.validate()
        self.camera, self.marker = camera, marker
        n, beta, r, h = marker.columns, marker.beta, marker.radius, marker.row_height
        code = marker.code
        zc = np.array([0.5 * (a + b) for a, b in code.bands])
        nb = zc.size
        ang = (np.arange(n) + 0.5) * beta
        # cells in (column, band) order, then the checker patch centres (upper row, lower row)
        ca, cz = np.repeat(ang, nb), np.tile(zc, n)
        ra, rz = np.tile(ang, 2), np.repeat([0.5 * h, -0.5 * h], n)
        a, z = np.concatenate([ca, ra]), np.concatenate([cz, rz])
        self._points = np.column_stack([r * np.cos(a), r * np.sin(a), z])
        self._normals = np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)])
        self._n_cells = ca.size
        col = np.repeat(np.arange(n), nb)
        upper = cz > 0
        row0 = np.where(upper, 0, n)  # reference row offset of each cell
        dark_upper = (col % 2 == 0)  # upper-row patch j is black for even j (relative indices)
        own_dark = np.where(upper, dark_upper, ~dark_upper)
        # the neighbours in the nearer row, then the same colour in the cell's own column of the other
        # row (used only when a neighbour is not seen: one neighbour alone is shaded differently)
        nb_idx = np.column_stack([(col - 1) % n + row0, (col + 1) % n + row0, col + n - row0])
        own = np.column_stack([col, col, col]) + row0[:, None]
        self._dark_ref = np.where(own_dark[:, None], own, nb_idx)
        self._white_ref = np.where(own_dark[:, None], nb_idx, own)
        preds, shifts, dirs, member = [], [], [], []
        for i, m in enumerate(self.members):  # the union of all members' hypotheses
            assert m.code is not None
            pred, sh, di = hypotheses(m.code.bits(), m.code.mirror())
            preds.append(pred.reshape(pred.shape[0], -1))
            shifts.append(sh)
            dirs.append(di)
            member.append(np.full(sh.size, i))
        self._shift, self._dir, self._member = (np.concatenate(v) for v in (shifts, dirs, member))
        self._pred = np.concatenate(preds).astype(bool)  # (2 n M, cells)
        self._hyp = [np.flatnonzero(self._shift % 2 == ph) for ph in (0, 1)]
        self._pred_phase = [self._pred[h] for h in self._hyp]
        T_rl = np.eye(4)
        T_rl[:3, :3], T_rl[:3, 3] = camera.R, camera.T
        self._T_rl = T_rl
        self._cams = [(np.asarray(c.K, float), np.asarray(c.dist, float).reshape(5))
                      for c in (camera.left, camera.right)]

    def _darkness(self, images: tuple[NDArray[np.uint8], NDArray[np.uint8]], T_fit: Array) -> tuple[Array, int]:
        """Per cell: darkness (NaN when not read); and the checker's phase in T_fit's relative
        columns (0: upper-row patch j dark for even j, 1: for odd j; -1: unclear). The phase is
        measured, not assumed: a detector's corner polarity need not match the model's."""
        s = self.settings
        vs = np.array([sample_sleeve(img, self._points, self._normals, T, K, dist, s.min_cos_view)
                       for img, (K, dist), T in zip(images, self._cams, (T_fit, self._T_rl @ T_fit))])
        n, nc = self.marker.columns, self._n_cells
        with np.errstate(invalid="ignore"):
            lit = np.minimum(vs[:, nc:nc + n], vs[:, nc + n:]) >= s.clipped_level  # (cameras, columns)
        if lit.any():  # a highlight along the sleeve: both colours clip, the column tells nothing
            vs[:, nc:] = np.where(np.tile(lit, 2), np.nan, vs[:, nc:])
            vs[:, :nc] = np.where(np.repeat(lit, nc // n, axis=1), np.nan, vs[:, :nc])
        return cell_darkness(vs, self._n_cells, self._dark_ref, self._white_ref, s.min_contrast)

    def read(self, images: tuple[NDArray[np.uint8], NDArray[np.uint8]], T_fit: Array) -> CodeReading:
        """Decide the identity along the fitted pose ``T_fit`` of {wm} in {ll} (module doc)."""
        s = self.settings
        d, phase = self._darkness(images, np.asarray(T_fit, float))
        if phase < 0:
            return CodeReading(False, "code not readable (no clear checker contrast next to the cells)")
        seen = np.isfinite(d)
        conf = seen & ((d > s.dark) | (d < s.light))
        n_conf = int(conf.sum())
        if n_conf < s.min_cells:
            return CodeReading(False, f"code not readable ({n_conf} cells read, need {s.min_cells})", cells=n_conf)
        p = np.clip(d[seen], 0.02, 0.98)
        hyp = self._hyp[phase]  # the checker's phase fixes the shift's parity
        pred = self._pred_phase[phase]
        P = pred[:, seen]
        ll = np.where(P, np.log(p), np.log1p(-p)).sum(axis=1)
        order = np.argsort(-ll)
        best = int(order[0])
        read = d[conf] > s.dark
        Pc = pred[:, conf]
        dist = (Pc != read).sum(axis=1)
        others = (Pc != Pc[best]).sum(axis=1)
        others[best] = 10**9
        margin, errors = int(others.min()), int(dist[best])
        llr = float(ll[best] - ll[order[1]])
        if errors > 1 or dist[best] > dist.min() or margin < 2 + errors:
            return CodeReading(False, f"code ambiguous ({errors} misread of {n_conf}, margin {margin})",
                               cells=n_conf, errors=errors, margin=margin, llr=llr)
        sh, di = int(self._shift[hyp[best]]), int(self._dir[hyp[best]])
        member = int(self._member[hyp[best]])
        T = (_rz(-sh * self.marker.beta) if di > 0 else HALF_TURN_X @ _rz(-sh * self.marker.beta))
        return CodeReading(True, "", sh, di, T, n_conf, errors, margin, llr, member, self.members[member].arm)
