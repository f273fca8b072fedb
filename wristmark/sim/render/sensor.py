"""The image sensor: shot + read noise, 8-bit quantisation and an optional JPEG round trip.

One fused numba pass over the frame (float32 arithmetic) turns the signal s [grey levels] into
``s + sqrt(max(s, 0) * shot_gain + read_noise^2) * n`` rounded half up and saturated to 0..255,
where n is a standard normal deviate drawn afresh for every pixel and channel of every frame.

Normal deviates: a counter-based generator, deterministic per ``key`` and independent of
threading and of the order of evaluation. Element i of the frame (flat row-major index of
pixel and channel) takes 16-bit field i mod 4 of word i div 4; word k is
splitmix64(key + (k + 1) * golden gamma) (the SplitMix64 generator of Steele, Lea and Flood,
2014). The field indexes an inverse-CDF table, entry j = Phi^-1((j + 1/2) / 65536) rescaled to
unit variance: deviates are quantised to 65536 levels (16-bit resolution: steps of 4e-5 sigma
near the mean) and truncated at +-4.33 sigma (a tail mass of 1.5e-5, irrelevant for images).
"""

from __future__ import annotations

import functools
import math
import sys

import cv2
import numba
import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtri

from wristmark.models.errors import InputError
from wristmark.sim.render.settings import RenderSettings

F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]
TABLE_BITS = 16
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1, _M2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S16 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(16)
_MASK = np.uint64((1 << TABLE_BITS) - 1)

_jit = numba.njit(cache=True, nogil=True, fastmath=False)
if sys.byteorder != "little":  # the kernel reads a generator word's 16-bit fields as a uint16 view
    raise ImportError("wristmark.sim.render.sensor needs a little-endian machine")


@functools.cache
def normal_table() -> F32:
    """Inverse-CDF table of the standard normal at the 2^16 bin midpoints, unit variance."""
    t = ndtri((np.arange(1 << TABLE_BITS) + 0.5) / (1 << TABLE_BITS))
    return (t / np.sqrt(np.mean(t * t))).astype(np.float32)


@_jit
def _splitmix(z: np.uint64) -> np.uint64:
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


@_jit
def _quantise(s: np.float32, g: np.float32, shot: np.float32, read2: np.float32) -> np.uint8:
    """Signal s plus g standard deviations of its noise, rounded and saturated to 0..255."""
    sd = np.float32(math.sqrt(max(s, np.float32(0.0)) * shot + read2))
    return np.uint8(min(max(s + sd * g + np.float32(0.5), np.float32(0.0)), np.float32(255.0)))


@_jit
def _run(src: F32, s0: int, n: int, i0: int, out: U8, o0: int, shot: float, read2: float, key: np.uint64,
         table: F32, words: NDArray[np.uint64], fields: NDArray[np.uint16], dev: F32) -> None:
    """Image elements i0 .. i0+n-1 (flat) from the signal ``src[s0:s0+n]`` into ``out[o0:o0+n]``;
    the generator index is the image index, so a pixel's noise does not depend on where its
    signal comes from or where it is written.
    Three simple loops, the first and the last vectorized by the compiler: the generator words
    of the span into ``words``; each element's deviate into ``dev`` from its 16-bit field
    (``fields`` is ``words`` viewed as uint16: field i mod 4 of word i div 4 on a little-endian
    machine); the noisy, quantised signal."""
    if n <= 0:
        return
    k0 = i0 >> 2
    nk = ((i0 + n - 1) >> 2) - k0 + 1
    for k in range(nk):
        words[k] = _splitmix(key + np.uint64(k0 + k + 1) * _GOLDEN)
    fld = fields[i0 - 4 * k0 : i0 - 4 * k0 + n]
    for i in range(n):
        dev[i] = table[fld[i]]
    sh, rd = np.float32(shot), np.float32(read2)
    o, sv = out[o0 : o0 + n], src[s0 : s0 + n]  # slices: the loop vectorizes (indices with offsets do not)
    for i in range(n):
        o[i] = _quantise(sv[i], dev[i], sh, rd)


@_jit
def _sensor_kernel(
    base: F32, patch: F32, pu0: int, pv0: int, ph: int, pw: int, h: int, w: int, c: int, shot: float, read2: float,
    key: np.uint64, table: F32, out: U8, ostride: int,
) -> None:
    """Flat (row-major, c channels) signal: rows of ``base`` with the (ph, pw) ``patch`` at
    (pu0, pv0) replacing it; image row v goes to the flat ``out[v ostride : v ostride + w c]``
    (rows of a wider image, e.g. one half of a side-by-side pair), the generator index is that of
    the (h, w, c) image."""
    row = w * c
    words = np.empty(row // 4 + 2, np.uint64)
    fields = words.view(np.uint16)
    dev = np.empty(row, np.float32)
    for v in range(h):
        o = out[v * ostride : v * ostride + row]
        if pv0 <= v < pv0 + ph:
            lo, hi = pu0 * c, (pu0 + pw) * c
            _run(base, v * row, lo, v * row, o, 0, shot, read2, key, table, words, fields, dev)
            _run(patch, (v - pv0) * pw * c, hi - lo, v * row + lo, o, lo, shot, read2, key, table, words, fields,
                 dev)
            _run(base, v * row + hi, row - hi, v * row + hi, o, hi, shot, read2, key, table, words, fields, dev)
        else:
            _run(base, v * row, row, v * row, o, 0, shot, read2, key, table, words, fields, dev)


def sensor_image(
    signal: F32,
    settings: RenderSettings,
    key: int,
    patch: F32 | None = None,
    origin: tuple[int, int] = (0, 0),
    out: U8 | None = None,
) -> U8:
    """Noisy 8-bit image (h, w, 3) or (h, w) of the sensor ``signal`` [grey levels], the region
    of ``patch`` (same channels, top-left pixel ``origin`` (u, v)) replacing ``signal`` there.
    Noise stream ``key`` (same key: same image; a pixel's noise does not depend on the patch);
    without noise (shot_gain = read_noise = 0) just rounding. Then the JPEG round trip if set.
    ``out``: write the image there (shape of the signal, uint8, each row contiguous: e.g. one
    half of a side-by-side image) and return it; else a new array."""
    h, w = signal.shape[:2]
    c = 1 if signal.ndim == 2 else signal.shape[2]
    pat = np.zeros((0, 0, c), np.float32) if patch is None else patch
    ph, pw = pat.shape[:2]
    if (1 if pat.ndim == 2 else pat.shape[2]) != c or origin[0] + pw > w or origin[1] + ph > h:
        raise InputError(f"patch {pat.shape} at {origin} does not fit the signal {signal.shape}")
    if out is None:
        out = np.empty(signal.shape, np.uint8)
    elif (out.shape != signal.shape or out.dtype != np.uint8 or out.strides[0] < w * c or out.strides[1] != c
          or (c > 1 and out.strides[2] != 1)):
        raise InputError(f"out must be a uint8 {signal.shape} image with contiguous rows, got {out.dtype} {out.shape}")
    stride = out.strides[0]  # [bytes] a flat view from the first row's start to the last one's end
    flat = np.lib.stride_tricks.as_strided(out, ((h - 1) * stride + w * c,), (1,)) if h else out.reshape(0)
    noisy = settings.shot_gain > 0 or settings.read_noise > 0
    table = normal_table() if noisy else np.zeros(1 << TABLE_BITS, np.float32)  # no noise: all deviates 0
    _sensor_kernel(
        np.ascontiguousarray(signal, np.float32).ravel(), np.ascontiguousarray(pat, np.float32).ravel(),
        int(origin[0]), int(origin[1]), ph, pw, h, w, c, float(settings.shot_gain), float(settings.read_noise) ** 2,
        np.uint64(key), table, flat, stride,
    )
    if settings.jpeg_quality is not None:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(settings.jpeg_quality)])
        if not ok:
            raise InputError("JPEG encoding failed: try another --jpeg quality")
        out[...] = np.asarray(cv2.imdecode(buf, cv2.IMREAD_UNCHANGED), np.uint8).reshape(out.shape)
    u8: U8 = out
    return u8
