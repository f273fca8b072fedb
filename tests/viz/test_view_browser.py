"""The 3D view in a real browser: headless Debian Chromium (driven by Playwright through its
``executable_path``; never a downloaded browser) loads the static snapshots and the served
pages (replay and live), takes screenshots and checks that the arm's segments, the marker's
checker and the tip spheres are drawn where the scene's camera puts them, in their colours.

Chromium comes from ``scripts/ensure-chromium.sh`` (``make browser``, run by ``make pytest``);
without it these tests fail with that hint rather than skip. Screenshots are kept in the test's
tmp folder and copied to ``runs/test-artifacts/``.
"""

from __future__ import annotations

import colorsys
import json
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from tests.viz.test_viz_scene import fake_records, make_fake_run
from wristmark.cli.main import main
from wristmark.sim.setup import load_setup
from wristmark.viz.framing import CameraView
from wristmark.viz.replay import load_run
from wristmark.viz.scene import ROOT, ArmScene, SceneConfig, SceneState
from wristmark.viz.snapshot import recording_visualizer
from wristmark.viz.style import RGB, TIP_KINDS, TIP_STYLES

pytestmark = [pytest.mark.browser]

WIDTH, HEIGHT = 1200, 800  # [px] viewport
ARTIFACTS = Path(__file__).resolve().parents[2] / "runs" / "test-artifacts"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
SEGMENT1: RGB = (0.20, 0.45, 0.85)  # models.urdf.MATERIALS
SEGMENT2: RGB = (0.15, 0.70, 0.45)
SEGMENT3: RGB = (0.85, 0.35, 0.55)  # models.arm_urdf.EXTRA_MATERIALS
PAPER_SEGMENTS = (("segment 1", "seg1_link_2_0", SEGMENT1), ("segment 2", "seg2_link_3_0", SEGMENT2))


def _chromium() -> str:
    path = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None)
    if path is None:
        pytest.fail("Debian chromium is not installed: run `make browser` (scripts/ensure-chromium.sh)")
    return path


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail("playwright is missing: pip install -e '.[test]' (the browser itself comes from apt)")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=_chromium(), args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser: Any) -> Iterator[Any]:
    pg = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT}, device_scale_factor=1)
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    yield pg
    pg.close()
    assert not errors, errors


# -- helpers ---------------------------------------------------------------------------------
def open_scene(page: Any, url: str, animated: bool) -> None:
    page.goto(url)
    page.wait_for_function("() => !!(window.viewer && viewer.scene.getObjectByName('true'))", timeout=30000)
    if animated:
        page.wait_for_function("() => viewer.animator.actions.length > 0", timeout=30000)


def seek(page: Any, t: float) -> None:
    """Show the animation at replay time ``t`` [s] (a key frame: no interpolation)."""
    page.evaluate(f"() => {{ viewer.animator.play(); viewer.animator.pause(); viewer.animator.seek({t!r}); }}")


def page_view(page: Any) -> CameraView:
    """The camera the page really uses: scene shift and camera position read back from three.js."""
    v = page.evaluate("""() => ({
        shift: viewer.scene_tree.find(['meshcat', 'wristmark']).object.position.toArray(),
        cam: viewer.camera.position.toArray(), fov: viewer.camera.fov })""")
    x, y, z = v["cam"]
    return CameraView(-np.asarray(v["shift"], float), np.array([x, -z, y]), float(v["fov"]))


def screenshot(page: Any, name: str, tmp_path: Path) -> np.ndarray:
    time.sleep(0.3)  # let the render loop draw the last change
    out = tmp_path / f"{name}.png"
    page.screenshot(path=str(out))
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    shutil.copy(out, ARTIFACTS / out.name)
    img = np.asarray(Image.open(out).convert("RGB"))
    assert img.shape == (HEIGHT, WIDTH, 3)
    assert img.reshape(-1, 3).std(axis=0).max() > 20, "blank canvas"
    return img


def hsv(img: np.ndarray) -> np.ndarray:
    f = img.astype(float) / 255.0
    mx, mn = f.max(axis=2), f.min(axis=2)
    d = np.where(mx - mn == 0, 1e-9, mx - mn)
    r, g, b = f[..., 0], f[..., 1], f[..., 2]
    h = np.where(mx == r, (g - b) / d % 6, np.where(mx == g, (b - r) / d + 2, (r - g) / d + 4)) * 60.0
    s = np.where(mx > 0, (mx - mn) / np.maximum(mx, 1e-9), 0)
    return np.stack([h, s, mx], axis=2)


def window(img: np.ndarray, uv: np.ndarray, r: float) -> np.ndarray:
    u, v = int(round(uv[0])), int(round(uv[1]))
    r = int(np.ceil(r))
    assert 0 <= u < img.shape[1] and 0 <= v < img.shape[0], f"({u}, {v}) is off screen"
    return img[max(0, v - r):v + r + 1, max(0, u - r):u + r + 1]


def count_hue(img: np.ndarray, uv: np.ndarray, r: float, rgb: RGB, tol: float = 20.0, min_sat: float = 0.3) -> int:
    """Pixels within ``r`` px of ``uv`` whose hue is within ``tol`` deg of ``rgb``'s."""
    target = 360.0 * colorsys.rgb_to_hsv(*rgb)[0]
    w = hsv(window(img, uv, r))
    dh = np.abs((w[..., 0] - target + 180.0) % 360.0 - 180.0)
    return int(np.sum((dh <= tol) & (w[..., 1] >= min_sat) & (w[..., 2] >= 0.15)))


def pixel_radius(view: CameraView, p: np.ndarray, radius: float) -> float:
    """Projected size [px] of ``radius`` [m] at ``p``."""
    fwd = -view.eye_offset / np.linalg.norm(view.eye_offset)
    side = np.cross(fwd, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    uv = view.project(np.array([p, p + radius * side]), WIDTH, HEIGHT)
    return float(np.linalg.norm(uv[1] - uv[0]))


def check_scene(img: np.ndarray, view: CameraView, state: SceneState, config: SceneConfig,
                tips: tuple[str, ...] = TIP_KINDS,
                segments: tuple[tuple[str, str, RGB], ...] = PAPER_SEGMENTS) -> dict[str, int]:
    """Assert that the ``segments`` (name, visual node, colour; default: the paper arm's segment
    1 and 2), the marker's black and white patches and the given tip spheres show in their
    colours where ``view`` projects them; return the pixel counts."""
    vis, _ = recording_visualizer()
    poses = dict(ArmScene(vis, config, view).node_poses(state))
    found: dict[str, int] = {}
    arm_r = config.params.outer_diameter / 2.0
    for name, node, rgb in segments:
        p = poses[f"{ROOT}/arm/visuals/{node}"][:3, 3]
        uv = view.project(p[None], WIDTH, HEIGHT)[0]
        found[name] = count_hue(img, uv, max(2.0, 0.8 * pixel_radius(view, p, arm_r)), rgb)
    p = poses[f"{ROOT}/marker"][:3, 3]
    w = window(img, view.project(p[None], WIDTH, HEIGHT)[0], pixel_radius(view, p, config.marker.radius))
    grey = hsv(w)
    found["marker black"] = int(np.sum(grey[..., 2] < 0.2))
    found["marker white"] = int(np.sum((grey[..., 2] > 0.75) & (grey[..., 1] < 0.15)))
    for kind in tips:
        p = np.asarray(state.tips[kind], float)
        uv = view.project(p[None], WIDTH, HEIGHT)[0]
        found[f"{kind} tip"] = count_hue(img, uv, 1.0 + pixel_radius(view, p, TIP_STYLES[kind].radius) * 0.8,
                                         TIP_STYLES[kind].color)
    missing = {k: n for k, n in found.items() if n < 3}
    assert not missing, f"not drawn where expected: {missing} (all counts: {found})"
    return found


# -- tests -----------------------------------------------------------------------------------
def test_static_replay_snapshot_shows_arm_marker_and_tips(page: Any, tmp_path: Path) -> None:
    run = make_fake_run(tmp_path / "run", cycles=30)
    out = tmp_path / "replay.html"
    assert main(["view", str(run), "--snapshot", str(out)]) == 0
    rep = load_run(run)
    k = len(rep.states) - 5  # closed loop: all four tips
    open_scene(page, out.resolve().as_uri(), animated=True)
    seek(page, float(rep.times[k]))
    img = screenshot(page, "view-snapshot-replay", tmp_path)
    print(check_scene(img, page_view(page), rep.states[k], rep.config))


def test_static_home_snapshot_shows_arm_and_marker(page: Any, tmp_path: Path) -> None:
    out = tmp_path / "home.html"
    assert main(["view", "--snapshot", str(out)]) == 0
    open_scene(page, out.resolve().as_uri(), animated=False)
    img = screenshot(page, "view-snapshot-home", tmp_path)
    setup = load_setup()
    state = SceneState.at_rest(setup.params)
    view = page_view(page)
    assert 0.08 < view.distance < 0.4  # framed on the centimetre-sized arm
    print(check_scene(img, view, state, SceneConfig.from_setup(setup), tips=("true",)))


def test_static_home_snapshot_of_a_three_segment_arm_shows_its_links(page: Any, tmp_path: Path) -> None:
    robot = Path(__file__).resolve().parents[2] / "configs" / "robots" / "tendon3.yaml"
    out = tmp_path / "tendon3.html"
    assert main(["view", "--snapshot", str(out), "--robot", str(robot)]) == 0
    open_scene(page, out.resolve().as_uri(), animated=False)
    links = page.evaluate("""() => {
        const names = [];
        viewer.scene_tree.find(['meshcat', 'wristmark', 'arm', 'visuals']).object.traverse(o => names.push(o.name));
        return names; }""")
    for t in (1, 2, 3):  # every segment's links are objects of the scene
        assert sum(n.startswith(f"seg{t}_link_") for n in links) == 6, sorted(links)
    img = screenshot(page, "view-snapshot-tendon3", tmp_path)
    setup = load_setup(robot=robot)
    state = SceneState.at_rest(setup.params)
    segments = (("segment 1", "seg1_link_3_0", SEGMENT1), ("segment 2", "seg2_link_3_0", SEGMENT2),
                ("segment 3", "seg3_link_3_0", SEGMENT3))
    print(check_scene(img, page_view(page), state, SceneConfig.from_setup(setup), tips=("true",), segments=segments))


def test_served_replay_page_shows_arm_marker_and_tips(page: Any, tmp_path: Path) -> None:
    run = make_fake_run(tmp_path / "run", cycles=30)
    proc = subprocess.Popen([sys.executable, "-m", "wristmark", "view", str(run), "--serve-seconds", "120",
                             "--no-play", "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line, proc.stderr.read() if proc.stderr else ""
        url = json.loads(line)["url"]
        assert url.startswith("http://127.0.0.1:") and url.endswith("/wristmark")
        rep = load_run(run)
        k = len(rep.states) - 1
        open_scene(page, url, animated=True)
        seek(page, float(rep.times[k]))
        img = screenshot(page, "view-served-replay", tmp_path)
        print(check_scene(img, page_view(page), rep.states[k], rep.config))
        assert "closed loop: mean 0.80 mm" in page.inner_text("#wm-legend")
    finally:
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(timeout=15)
    assert code == 0


def test_live_page_follows_the_loop(page: Any, tmp_path: Path) -> None:
    from wristmark.cvs.sources.frames import StereoFrame
    from wristmark.rig.loop.tip_sensors import TipMeasurement
    from wristmark.viz.live import start_live_view

    recs = [r for r in fake_records(30) if r.phase == "closed_loop"]
    setup = load_setup()
    view = start_live_view(setup, stream=None)
    w, h = setup.camera.image_size
    left = np.zeros((h, w, 3), np.uint8)
    left[:, : w // 2] = (255, 0, 255)  # magenta left half, dark right half
    frame = StereoFrame(left, left, 0.0, 0)
    corners = np.array([[w * 0.75, h * 0.5], [w * 0.8, h * 0.6]])
    try:
        for rec in recs:
            view.on_cycle(rec)
            view.on_frame(frame, TipMeasurement(True, rec.p_est, corners_left=corners))
            time.sleep(0.01)
        last = recs[-1]
        open_scene(page, view.url, animated=False)
        want = json.dumps([float(v) for v in last.p_true])
        page.wait_for_function(f"""() => {{
            const p = viewer.scene_tree.find(['meshcat', 'wristmark', 'tips', 'true']).object.position.toArray();
            const w = {want}; return p.every((v, i) => Math.abs(v - w[i]) < 1e-7); }}""", timeout=15000)
        page.wait_for_function("() => document.getElementById('wm-status').textContent.includes('closed_loop')",
                               timeout=15000)
        # the latest left frame, with its corners, on a pane at the left frustum's far end
        page.wait_for_function("""() => {
            const n = viewer.scene_tree.find(['meshcat', 'wristmark', 'endoscope', 'left_image']);
            let map = null;
            if (n && n.object) n.object.traverse(c => { if (c.material && c.material.map) map = c.material.map; });
            return !!(map && map.image && map.image.width === 384 && map.image.height === 216); }""", timeout=15000)
        texel = page.evaluate("""() => {
            const n = viewer.scene_tree.find(['meshcat', 'wristmark', 'endoscope', 'left_image']);
            let map = null;
            n.object.traverse(c => { if (c.material && c.material.map) map = c.material.map; });
            const c = document.createElement('canvas'); c.width = 384; c.height = 216;
            const g = c.getContext('2d'); g.drawImage(map.image, 0, 0);
            const at = (x, y) => Array.from(g.getImageData(x, y, 1, 1).data.slice(0, 3));
            return {left: at(50, 108), right: at(330, 150), corner: at(288 + 4, 108)}; }""")
        assert texel["left"][0] > 200 and texel["left"][1] < 60 and texel["left"][2] > 200  # magenta
        assert max(texel["right"]) < 40  # dark
        assert texel["corner"][0] > 150 and texel["corner"][1] > 150  # a yellow corner circle
        img = screenshot(page, "view-live", tmp_path)
        print(check_scene(img, page_view(page), SceneState.from_record(last), SceneConfig.from_setup(setup)))
    finally:
        view.close()
    assert view.stats.error == "" and view.stats.frames >= 1 and view.stats.images >= 1


def test_static_scene_replay_shows_every_arm_with_its_tips(page: Any, tmp_path: Path) -> None:
    """A run of two arms in one view (tests/data/scene_run): both arms' bodies and their desired,
    estimated and true tips in each arm's colour, where the page's camera projects them in the
    scene's {w}; the legend names both arms."""
    from tests.viz.test_scene_replay import SCENE_RUN
    from wristmark.viz.scene_replay import load_scene_run
    from wristmark.viz.style import arm_tip_styles

    out = tmp_path / "scene.html"
    assert main(["view", str(SCENE_RUN), "--snapshot", str(out)]) == 0
    rep = load_scene_run(SCENE_RUN)
    open_scene(page, out.resolve().as_uri(), animated=True)
    k = len(rep.arms["a"].states) - 1  # the last closed-loop cycle: every tip known
    seek(page, float(rep.arms["a"].times[k]))
    img = screenshot(page, "view-snapshot-scene", tmp_path)
    view = page_view(page)
    legend = page.inner_text("#wm-legend")
    assert "arm a: desired / estimated / true tip" in legend and "arm b: desired / estimated / true tip" in legend
    found: dict[str, int] = {}
    for name, arm in rep.arms.items():
        B = rep.config.bases[name]
        part = ArmScene(recording_visualizer()[0], arm.config, view, stage=False, ghost=False)
        poses = dict(part.node_poses(arm.states[k]))
        p = B[:3, :3] @ poses[f"{ROOT}/arm/visuals/seg1_link_2_0"][:3, 3] + B[:3, 3]
        found[f"{name} segment 1"] = count_hue(img, view.project(p[None], WIDTH, HEIGHT)[0], 3.0, SEGMENT1)
        own = arm_tip_styles(rep.config.color(name))
        other = arm_tip_styles(rep.config.color("b" if name == "a" else "a"))
        for kind in ("desired", "estimated"):
            q = B[:3, :3] @ np.asarray(arm.states[k].tips[kind], float) + B[:3, 3]
            uv = view.project(q[None], WIDTH, HEIGHT)[0]
            r = 2.0 + 0.8 * pixel_radius(view, q, own[kind].radius)
            found[f"{name} {kind} tip"] = count_hue(img, uv, r, own[kind].color, min_sat=0.25)
            assert count_hue(img, uv, r, other[kind].color, min_sat=0.25) < 3  # in its own arm's colour
    missing = {key: n for key, n in found.items() if n < 3}
    assert not missing, f"not drawn where expected: {missing} (all counts: {found})"
    print(found)
