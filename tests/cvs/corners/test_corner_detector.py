"""The paper's marker-corner detector (cvs.corners.detector): eq. 6-10 on synthetic corners,
the Fig. 4 chain on rendered marker images (half resolution, 960x540), ROI tracking, no-marker
images, the stereo tracker with detector='paper', and the planar-board helpers."""

from __future__ import annotations

import math
import time

import cv2
import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.corners.detector import (
    CornerChain,
    DetectorSettings,
    MarkerCornerDetector,
    assemble_grid,
    corner_likelihood,
    detect_xcorners,
    htm_refine,
    quadric_subpixel,
)
from wristmark.cvs.tracking.tracker import MarkerTracker, TrackerSettings
from wristmark.models.arm_shape import arm_shape
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.render.stereo_renderer import RenderedPair, StereoRenderer
from wristmark.sim.visibility import random_visible_psi

CAM = scaled_stereo_camera(load_calibration(CONFIG_DIR / "camera.yaml"), 0.5)
MARKER = MarkerModel()
SPREAD = (0.25, 0.012, 0.2, 0.6, 0.3, 0.6)  # as `wristmark render`


def _gray(img: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img


def synthetic_corner(
    centre: tuple[float, float],
    edge_a: float,
    edge_b: float,
    size: int = 41,
    blur: float = 0.8,
    noise: float = 1.0,
    bright_ab: bool = True,
    seed: int = 0,
) -> np.ndarray:
    """uint8 X-corner (8x8 supersampled): edges through ``centre`` [px] at angles edge_a, edge_b
    [rad]; the sector between +edge_a and +edge_b is bright if ``bright_ab``."""
    ss = 8
    o = (np.arange(size * ss) + 0.5) / ss - 0.5
    X, Y = np.meshgrid(o - centre[0], o - centre[1])
    na = np.array([-np.sin(edge_a), np.cos(edge_a)]) * np.sign(np.sin(edge_b - edge_a))
    nb = np.array([-np.sin(edge_b), np.cos(edge_b)]) * -np.sign(np.sin(edge_b - edge_a))
    inside = ((X * na[0] + Y * na[1]) > 0) == ((X * nb[0] + Y * nb[1]) > 0)
    img = np.where(inside == bright_ab, 200.0, 40.0).reshape(size, ss, size, ss).mean(axis=(1, 3))
    img = cv2.GaussianBlur(img, (0, 0), blur)
    img += np.random.default_rng(seed).normal(0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


# ------------------------------------------------------------------ eq. 6-10 on synthetic corners


def test_corner_likelihood_peaks_at_axis_aligned_and_diagonal_corners() -> None:
    for ea, eb in ((np.pi / 2, 0.0), (3 * np.pi / 4, np.pi / 4)):  # c_xy, then c_45 dominates
        g = synthetic_corner((20.0, 20.0), ea, eb, noise=0.0)
        cl, ix, iy = corner_likelihood(cv2.GaussianBlur(g, (7, 7), 1.5), 2.0, 1 / 255)
        assert cl.dtype == np.float32 and ix.shape == g.shape
        y, x = np.unravel_index(int(np.argmax(cl[5:-5, 5:-5])), (31, 31))
        assert (x + 5, y + 5) == (20, 20)
        ex, ey = np.rint(20 + 8 * np.cos(eb)).astype(int), np.rint(20 + 8 * np.sin(eb)).astype(int)
        assert cl[20, 20] > 0.1 and cl[ey, ex] < 0  # on an edge (one gradient): penalised


def test_quadric_subpixel_recovers_a_paraboloid_peak() -> None:
    yy, xx = np.mgrid[0:21, 0:21].astype(np.float64)
    x0, y0 = 10.3, 9.6
    cl = (1.0 - 0.02 * (xx - x0) ** 2 - 0.03 * (yy - y0) ** 2 + 0.01 * (xx - x0) * (yy - y0)).astype(np.float32)
    out = quadric_subpixel(cl, np.array([10]), np.array([10]), size=7)
    assert np.allclose(out[0], [x0, y0], atol=1e-4)
    flat = np.zeros((21, 21), np.float32)  # no maximum: the integer peak is returned
    assert np.allclose(quadric_subpixel(flat, np.array([10]), np.array([10]))[0], [10, 10])


@pytest.mark.parametrize(
    ("angles", "tol_deg", "tol_px"),
    [((np.radians(92.0), np.radians(3.0)), 1.0, 0.03), ((np.radians(115.0), np.radians(-20.0)), 3.0, 0.06)],
)
def test_htm_refine_on_synthetic_corners(angles: tuple[float, float], tol_deg: float, tol_px: float) -> None:
    """Sub-pixel centre and edge angles from a start 0.5 px and 3 degrees off; an oblique corner
    (135 degree sector) is fitted less well by the tanh product after blurring."""
    rng = np.random.default_rng(3)
    errs = []
    for k in range(10):
        c = (20.0 + rng.uniform(-0.5, 0.5), 20.0 + rng.uniform(-0.5, 0.5))
        g = synthetic_corner(c, *angles, noise=1.5, seed=k)
        start = np.array([[20.0, 20.0]])
        ref, edges, ok = htm_refine(g, start, np.array([angles]) + 0.05, r=4, sigma_w=4.0)
        assert ok.tolist() == [True]
        errs.append(np.hypot(*(ref[0] - c)))
        assert np.allclose(edges[0], angles, atol=np.radians(tol_deg))
    assert np.sqrt(np.mean(np.square(errs))) < tol_px


def test_xcorner_test_polarity_and_edges() -> None:
    """One synthetic corner each way round: detected with |CC| >= 0.8, the edges of the
    documented convention (a near vertical pointing down, b pointing right) and polarity +1 when
    the sector between them is bright."""
    ea, eb = np.radians(95.0), np.radians(-8.0)
    for bright, pol in ((True, 1), (False, -1)):
        g = synthetic_corner((20.3, 19.6), ea, eb, noise=1.0, bright_ab=bright)
        xc = detect_xcorners(g)
        assert xc.corners.shape == (1, 2) and xc.polarity.tolist() == [pol]
        assert xc.cc[0] >= 0.8 and xc.cl[0] >= 0.06
        assert np.allclose(xc.edges[0], [ea, eb], atol=np.radians(3.0))
        assert np.hypot(*(xc.corners[0] - [20.3, 19.6])) < 0.1
        # the paper's eq. 10 position is kept as well (coarser)
        assert np.hypot(*(xc.corners_quadric[0] - [20.3, 19.6])) < 1.0
    flat = np.random.default_rng(1).normal(120, 2, (41, 41)).clip(0, 255).astype(np.uint8)
    assert detect_xcorners(flat).corners.shape == (0, 2)


# ------------------------------------------------------------------ rendered marker images


@pytest.fixture(scope="module")
def frames() -> list[RenderedPair]:
    """Three rendered half-resolution pairs at the default render noise."""
    params = RobotParams()
    rng = np.random.default_rng(8)
    renderer = StereoRenderer(CAM, MARKER, noise_preset("default"), seed=8)
    return [renderer.render(arm_shape(params, random_visible_psi(params, CAM, MARKER, rng, SPREAD))) for _ in range(3)]


def _truth_index(chain: CornerChain, truth: tuple) -> tuple[np.ndarray, np.ndarray]:
    uv = np.array([c.uv for c in truth])
    d = np.hypot(*(chain.corners[:, None] - uv[None]).transpose(2, 0, 1))
    idx = d.argmin(axis=1)
    return idx, d[np.arange(idx.size), idx]


def test_chain_accuracy_order_and_polarity(frames: list[RenderedPair]) -> None:
    det = MarkerCornerDetector()
    errs = []
    for f in frames:
        pol_by_index: list[dict[int, int]] = []
        for img, truth in ((f.left, f.corners_left), (f.right, f.corners_right)):
            ch = det.detect(_gray(img))
            n = ch.corners.shape[0]
            assert n >= 3 and ch.polarity.shape == (n,) and ch.cc.shape == (n,) and ch.roi is None
            idx, d = _truth_index(ch, truth)
            errs += d.tolist()
            steps = np.diff(idx) % MARKER.columns  # consecutive marker corners, one direction
            assert np.all(steps == steps[0]) and steps[0] in (1, MARKER.columns - 1)
            assert ch.corners[0, 1] < ch.corners[-1, 1]  # ordered from the top end
            assert np.all(ch.polarity[1:] == -ch.polarity[:-1])  # alternating along the chain
            assert all(truth[i].cos_view > 0 for i in idx)
            pol_by_index.append(dict(zip(idx.tolist(), ch.polarity.tolist())))
        common = set(pol_by_index[0]) & set(pol_by_index[1])
        assert len(common) >= 3 and all(pol_by_index[0][i] == pol_by_index[1][i] for i in common)
    assert np.sqrt(np.mean(np.square(errs))) < 0.3
    assert max(errs) < 0.5


def test_roi_tracking_used_on_second_frame_and_faster(frames: list[RenderedPair]) -> None:
    det = MarkerCornerDetector()
    g = _gray(frames[0].left)
    cold = det.track(g)  # first frame: whole frame
    assert cold.roi is None and cold.corners.shape[0] >= 3
    warm = det.track(g)
    assert warm.roi is not None
    x, y, w, h = warm.roi
    assert w * h < 0.25 * g.size
    assert np.all((cold.corners >= [x, y]) & (cold.corners <= [x + w, y + h]))
    np.testing.assert_allclose(warm.corners, cold.corners, atol=1e-9)  # same result in the ROI
    t_cold = min(_timed(lambda: det.detect(g)) for _ in range(3))
    t_roi = min(_timed(lambda: det.track(g)) for _ in range(5))
    assert t_roi < 0.5 * t_cold, (t_roi, t_cold)


def _timed(fn) -> float:  # type: ignore[no-untyped-def]
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def test_lost_marker_falls_back_to_whole_frame(frames: list[RenderedPair]) -> None:
    det = MarkerCornerDetector()
    g = _gray(frames[1].left)
    assert det.track(g).corners.shape[0] >= 3
    empty = np.full_like(g, 90)
    lost = det.track(empty)
    assert lost.corners.shape == (0, 2) and lost.roi is None  # ROI failed, whole frame searched
    again = det.track(g)
    assert again.roi is None and again.corners.shape[0] >= 3  # no stale ROI after a loss
    det.reset()
    assert det.track(g).roi is None


def test_no_marker_gives_an_empty_chain(frames: list[RenderedPair]) -> None:
    det = MarkerCornerDetector()
    noise = np.random.default_rng(0).normal(120, 2, (540, 960)).clip(0, 255).astype(np.uint8)
    assert det.detect(noise).corners.shape == (0, 2)
    f = frames[2]
    for img, truth in ((f.left, f.corners_left), (f.right, f.corners_right)):
        img = img.copy()  # the rendered scene (tissue texture, arm) with the marker painted over
        uv = np.array([c.uv for c in truth])
        lo, hi = (uv.min(axis=0) - 40).astype(int), (uv.max(axis=0) + 40).astype(int)
        img[lo[1] : hi[1], lo[0] : hi[0]] = np.median(img.reshape(-1, 3), axis=0).astype(np.uint8)
        res = det.detect(img)
        assert res.corners.shape == (0, 2) and res.polarity.shape == (0,)


def test_marker_tracker_with_the_paper_detector(frames: list[RenderedPair]) -> None:
    tracker = MarkerTracker(CAM, MARKER, TrackerSettings(detector="paper"))
    assert isinstance(tracker.detector_left, MarkerCornerDetector)
    for f in frames[:2]:
        tracker.reset()
        res = tracker.track(f.left, f.right)
        assert res.ok, res.reason
        assert np.linalg.norm(res.tip_left - f.tip_left) < 0.5e-3  # type: ignore[operator]
        again = tracker.track(f.left, f.right)  # ROI tracking
        assert again.ok and np.linalg.norm(again.tip_left - f.tip_left) < 0.5e-3  # type: ignore[operator]


def test_settings_change_behaviour(frames: list[RenderedPair]) -> None:
    g = _gray(frames[0].right)
    strict = MarkerCornerDetector(DetectorSettings(cc_min=0.9999)).detect(g)
    assert strict.corners.shape == (0, 2)
    paper_only = MarkerCornerDetector(DetectorSettings(refine=False)).detect(g)
    assert paper_only.corners.shape[0] >= 3
    np.testing.assert_allclose(paper_only.corners, paper_only.corners_quadric)


# ------------------------------------------------------------------ planar boards


def _board_image(H: np.ndarray, size: tuple[int, int], squares: tuple[int, int]) -> np.ndarray:
    """A chessboard (unit squares, board corner at (0, 0)) seen through homography H board ->
    image, 4x4 supersampled, blurred, with noise."""
    w, h = size
    ss = 4
    o = (np.arange(ss) + 0.5) / ss - 0.5
    xs = (np.arange(w)[:, None] + o[None]).ravel()
    ys = (np.arange(h)[:, None] + o[None]).ravel()
    X, Y = np.meshgrid(xs, ys)
    P = np.linalg.inv(H) @ np.vstack([X.ravel(), Y.ravel(), np.ones(X.size)])
    u, v = P[0] / P[2], P[1] / P[2]
    on = (u >= 0) & (v >= 0) & (u < squares[0]) & (v < squares[1])
    black = (np.floor(u).astype(int) + np.floor(v).astype(int)) % 2 == 0
    val = np.where(on, np.where(black, 30.0, 220.0), 150.0).reshape(h, ss, w, ss).mean(axis=(1, 3))
    val = cv2.GaussianBlur(val, (0, 0), 0.7) + np.random.default_rng(5).normal(0, 1.5, val.shape)
    return np.clip(np.rint(val), 0, 255).astype(np.uint8)


def test_board_grid_matches_truth_and_opencv_order() -> None:
    H = np.array([[30.0, 6.0, 60.0], [-5.0, 28.0, 70.0], [0.0005, 0.001, 1.0]])
    g = _board_image(H, (480, 360), (10, 7))
    grid = assemble_grid(detect_xcorners(g), (9, 6), g)
    assert grid is not None and grid.shape == (54, 2)
    ij = np.mgrid[1:7, 1:10][::-1].reshape(2, -1).T.astype(float)  # inner corners, row by row
    P = H @ np.vstack([ij.T, np.ones(54)])
    truth = (P[:2] / P[2]).T
    ok, sb = cv2.findChessboardCornersSB(g, (9, 6), flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
    assert ok
    sb = sb.reshape(-1, 2)
    np.testing.assert_array_less(np.hypot(*(grid - sb).T), 0.5)  # same order as OpenCV
    err = np.hypot(*(grid[:, None] - truth[None]).transpose(2, 0, 1)).min(axis=1)
    assert np.sqrt(np.mean(err**2)) < 0.05
    assert assemble_grid(detect_xcorners(g), (8, 6), g) is None  # two 8x6 windows: ambiguous


# ------------------------------------------------------------------ compiled kernels vs references


def _cl_opencv(f: np.ndarray, epsilon: float = 2.0, gs: float = 1 / 255) -> tuple[np.ndarray, ...]:
    """Eq. 6 with OpenCV filters (the formulation the compiled kernel replaces)."""
    ix = cv2.Sobel(f, cv2.CV_32F, 1, 0, ksize=3, scale=0.125 * gs)
    iy = cv2.Sobel(f, cv2.CV_32F, 0, 1, ksize=3, scale=0.125 * gs)
    ixy = np.abs(cv2.Sobel(f, cv2.CV_32F, 1, 1, ksize=3, scale=0.25 * gs))
    d2 = np.array([[0, -1, 0], [1, 0, 1], [0, -1, 0]], np.float32) * np.float32(gs)
    i4545 = np.abs(cv2.filter2D(f, cv2.CV_32F, d2))
    ax, ay = np.abs(ix), np.abs(iy)
    e2, pen = epsilon**2, 1.5 * epsilon
    c_xy = cv2.addWeighted(ixy, e2, np.maximum(ax, ay), -pen * np.sqrt(2.0), 0.0)
    c_45 = cv2.addWeighted(i4545, 0.5 * e2, ax + ay, -pen, 0.0)
    return np.maximum(c_xy, c_45), ix, iy


def test_corner_likelihood_kernel_matches_the_opencv_filters(frames: list[RenderedPair]) -> None:
    """Whole image, odd-width crops (OpenCV's row-filter tail) and a 1-row strip (reflected
    borders): the same values (bit for bit on the machine it was written on; a few float32 ulp
    allowed elsewhere)."""
    g = cv2.GaussianBlur(_gray(frames[0].left), (7, 7), 1.5)
    for img in (g, np.ascontiguousarray(g[100:377, 50:333]), g[200:201, 10:47].copy(), g[:, :3].copy()):
        ref = _cl_opencv(img)
        for a, b in zip(corner_likelihood(img, 2.0, 1 / 255), ref):
            assert a.shape == b.shape and a.dtype == np.float32
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-6)


def test_orientation_bins_are_the_exact_atan2_bins() -> None:
    """The polynomial arctangent with an atan2 fallback near boundaries gives the bin of the exact
    atan2 for random, quantised (Sobel sums of a uint8 image), axis-aligned, diagonal and
    one-ulp-off gradients."""
    from wristmark.cvs.corners.xcorner_test import NBINS, orientation_bin

    rng = np.random.default_rng(0)
    s = np.float32(0.125 / 255)
    q = rng.integers(-60, 61, (4000, 2)).astype(np.float32) * s
    g = np.concatenate(
        [
            rng.normal(size=(4000, 2)),
            q.astype(np.float64),
            np.nextafter(q, np.float32(1)).astype(np.float64),
            [[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [-1, 1], [1, -1], [-1, -1], [0.0, -0.0], [-0.0, 1.0]],
        ]
    )
    for gx, gy in g:
        a = math.atan2(gy, gx)
        a = a + 2 * math.pi if a < 0 else a  # in [0, 2 pi), as the histogram of eq. 7 bins it
        assert orientation_bin(float(gx), float(gy), NBINS) == int(a * (NBINS / math.pi)) % NBINS, (gx, gy)


def test_htm_correlation_matches_the_tanh_model() -> None:
    """Separable exponentials give the correlation of eq. 8 (and math.tanh where they would
    overflow: a very sharp template)."""
    from wristmark.cvs.corners.xcorner_test import htm_correlation

    rng = np.random.default_rng(1)
    img = rng.integers(0, 256, (40, 40)).astype(np.uint8)
    yy, xx = np.mgrid[-5:6, -5:6].astype(np.float64)
    for ea, eb, scale in ((1.6, 0.1, 1.0), (2.0, -0.4, 0.7), (1.2, 0.3, 0.005)):
        na = 1.0 if np.sin(eb - ea) > 0 else -1.0
        t = np.tanh(na * (-np.sin(ea) * xx + np.cos(ea) * yy) / scale)
        t = t * np.tanh(-na * (-np.sin(eb) * xx + np.cos(eb) * yy) / scale)
        p = img[15:26, 15:26].astype(np.float64)
        ref = np.corrcoef(p.ravel(), t.ravel())[0, 1]
        assert abs(htm_correlation(img, 20, 20, 5, ea, eb, scale) - ref) < 1e-12


def test_lazy_xcorner_tests_give_the_chain_of_testing_all(frames: list[RenderedPair]) -> None:
    """The chain search tests candidates only when it reaches them; testing every candidate
    first changes nothing, and the lazy search tests far fewer."""
    from wristmark.cvs.corners.chain import find_chain
    from wristmark.cvs.corners.likelihood import find_candidates
    from wristmark.cvs.corners.xcorner_test import check_xcorners

    s = DetectorSettings()
    for f in frames:
        g = _gray(f.left)
        lazy = find_candidates(g, s)
        chain = find_chain(lazy, s)
        full = find_candidates(g, s)
        check_xcorners(full, np.arange(full.xs.size), s)
        assert chain.size >= 3 and np.array_equal(find_chain(full, s), chain)
        assert lazy.tested.sum() < 0.5 * full.xs.size


def test_colour_frames_in_roi_tracking_convert_only_the_box(
    frames: list[RenderedPair], monkeypatch: pytest.MonkeyPatch
) -> None:
    """BGR input gives the same chain as grey input; in ROI tracking only the box is converted."""
    converted: list[tuple[int, ...]] = []
    real = cv2.cvtColor

    def spy(img: np.ndarray, code: int) -> np.ndarray:
        converted.append(img.shape)
        return real(img, code)

    bgr = frames[1].left
    g = _gray(bgr)
    monkeypatch.setattr(cv2, "cvtColor", spy)
    grey = MarkerCornerDetector()
    colour = MarkerCornerDetector()
    for step in range(3):
        a, b = grey.track(g), colour.track(bgr)
        assert a.roi == b.roi and (a.roi is None) == (step == 0)
        np.testing.assert_array_equal(a.corners, b.corners)
        np.testing.assert_array_equal(a.polarity, b.polarity)
    h, w = bgr.shape[:2]
    assert converted[0][:2] == (h, w)  # the cold search converts the whole frame ...
    assert all(s[0] * s[1] < 0.25 * h * w for s in converted[1:])  # ... ROI tracking only boxes


def test_detector_rejects_images_it_cannot_read() -> None:
    det = MarkerCornerDetector()
    for bad in (np.zeros((50, 60), np.float32), np.zeros((50, 60, 2), np.uint8), np.zeros(60, np.uint8)):
        with pytest.raises(InputError, match="expected a uint8 grayscale or BGR image"):
            det.detect(bad)
        with pytest.raises(ValueError):
            detect_xcorners(bad)
    with pytest.raises(ValueError, match="leaves the 21x21 image"):
        quadric_subpixel(np.zeros((21, 21), np.float32), np.array([2]), np.array([10]))


def test_an_enlarged_box_gives_the_same_corners_in_the_image_pixels(frames: list[RenderedPair]) -> None:
    """``detect(img, roi, magnify=2)`` searches the box enlarged and returns the image's own
    pixels: the same corners as at scale 1 (the HTM fit on the bicubic enlargement), within
    0.15 px, and closer to the truth than 0.3 px."""
    f = frames[0]
    g = _gray(f.left)
    one = MarkerCornerDetector().detect(g)
    assert one.corners.shape[0] >= 3
    lo, hi = one.corners.min(axis=0) - 30, one.corners.max(axis=0) + 30
    box = (int(lo[0]), int(lo[1]), int(hi[0] - lo[0]), int(hi[1] - lo[1]))
    two = MarkerCornerDetector().detect(g, box, magnify=2.0)
    assert two.corners.shape == one.corners.shape
    np.testing.assert_allclose(two.corners, one.corners, atol=0.15)
    np.testing.assert_array_equal(two.polarity, one.polarity)
    truth = np.array([c.uv for c in f.corners_left])
    err = [float(np.hypot(*(truth - c).T).min()) for c in two.corners]
    assert max(err) < 0.3
    with pytest.raises(InputError, match="magnify"):
        MarkerCornerDetector().detect(g, box, magnify=0.5)
