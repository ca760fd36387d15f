"""The recorded animation opened in a real browser: headless Chromium.

The page must load from a file with no network, raise no error, and show the
scene: a screenshot must contain about as many target-red and vehicle-orange
pixels as the target sphere and the vehicle body project to from the camera
framing, both at load (t = 0) and in the middle of the recording, and the two
screenshots must differ (the recording moves the scene).
"""

from __future__ import annotations

import io
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from pydrake.geometry import Meshcat

from drake_uuv.visualization import MeshcatScene, SceneStyle, record_animation
from drake_uuv.visualization.animation import LEGEND_ID
from drake_uuv.visualization.scene import MESHCAT_DEFAULT_FOV_DEG
from tests.visualization._chromium import Chromium, find_chromium
from tests.visualization.synthetic_log import BASELINE_B, TIME_STEP, synthetic_log

CHROMIUM = find_chromium()
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        CHROMIUM is None,
        reason="Chromium is not installed (Debian package `chromium`, see .ci/apt-packages.txt)",
    ),
]

REPO = Path(__file__).resolve().parents[2]
SCREENSHOT = REPO / "out" / "animation_screenshot.png"
WIDTH, HEIGHT = 1280, 960
STEPS = 100

# Scene loaded: the recording is attached and the scene tree has stopped growing.
SCENE_SIZE_JS = """(() => {
  if (typeof viewer === "undefined" || !viewer.animator) return -1;
  const root = viewer.scene.getObjectByName("uuv_scene");
  if (!root || viewer.animator.actions.length === 0) return -1;
  let n = 0; root.traverse(() => { n += 1; }); return n;
})()"""

# The key to the colours: shown or not, its box in the window, its text.
LEGEND_JS = f"""(() => {{
  const e = document.getElementById("{LEGEND_ID}");
  if (!e) return {{shown: false, box: [0, 0, 0, 0], text: ""}};
  const r = e.getBoundingClientRect();
  return {{shown: getComputedStyle(e).display !== "none" && r.width > 0,
          box: [r.left, r.top, r.right, r.bottom], text: e.innerText}};
}})()"""

NEXT_FRAMES_JS = (
    "new Promise(r => requestAnimationFrame(() => requestAnimationFrame(() => r(true))))"
)


def hsv(image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hue (degrees), saturation and value of an RGB float image."""
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    v = image.max(axis=-1)
    c = v - image.min(axis=-1)
    s = np.where(v > 0, c / np.maximum(v, 1e-12), 0.0)
    safe = np.maximum(c, 1e-12)
    h = np.select(
        [c == 0, v == r, v == g],
        [0.0, ((g - b) / safe) % 6.0, (b - r) / safe + 2.0],
        (r - g) / safe + 4.0,
    )
    return 60.0 * h, s, v


def colour_masks(png: bytes) -> dict[str, np.ndarray]:
    """Pixels of the target's red and of the vehicle body's orange.

    The bands leave room for Phong shading and for the translucent magenta
    covariance ellipsoid in front (red shifts towards 350°, orange to ~24°),
    and exclude every other colour of the scene: trails (yellow ~53°; light red
    of saturation 0.45), estimate (magenta 300°), sonars, beams, background
    (grey, blue).
    """
    image = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float) / 255.0
    h, s, v = hsv(image)
    vivid = (s > 0.5) & (v > 0.25)
    return {
        "target": vivid & ((h >= 340.0) | (h <= 12.0)),
        "vehicle": vivid & (h >= 18.0) & (h <= 45.0),
    }


def expected_areas(scene: MeshcatScene, style: SceneStyle, reach: float) -> dict[str, float]:
    """Smallest projected areas (pixels) of the target sphere and the vehicle body.

    The target sits at the look-at point, at the camera distance D; the vehicle is
    at most ``reach`` farther, seen at worst across its two smallest semi-axes.
    """
    distance = scene.camera_distance()
    focal = (HEIGHT / 2.0) / np.tan(np.deg2rad(MESHCAT_DEFAULT_FOV_DEG) / 2.0)
    a = sorted(style.body_semi_axes)
    return {
        "target": np.pi * (style.target_radius * focal / distance) ** 2,
        "vehicle": np.pi * a[0] * a[1] * (focal / (distance + reach)) ** 2,
    }


def test_animation_renders_in_headless_chromium(tmp_path: Path) -> None:
    started = time.monotonic()
    log = synthetic_log(STEPS, seed=0)
    style = SceneStyle()
    html = record_animation(log, BASELINE_B, TIME_STEP, tmp_path / "animation.html", style=style)

    # The framing the page was written with (same code, fresh Meshcat).
    scene = MeshcatScene(Meshcat(), BASELINE_B, style=style)
    scene.frame_log(log)
    reach = float(np.max(np.linalg.norm(log["p_WU"] - log["p_WT"], axis=1)))
    expected = expected_areas(scene, style, reach)

    profile = tmp_path / "chromium-profile"
    profile.mkdir()
    shots: dict[str, bytes] = {}
    with Chromium(CHROMIUM, profile) as browser:
        browser.set_viewport(WIDTH, HEIGHT)
        browser.navigate(html.as_uri())
        # Wait until the scene tree is complete (its size is stable) and rendered.
        sizes: list[int] = []
        deadline = time.monotonic() + 60.0
        while len(sizes) < 3 or sizes[-1] < 0 or len(set(sizes[-3:])) != 1:
            assert time.monotonic() < deadline, f"scene never loaded: {sizes[-5:]}"
            sizes.append(browser.evaluate(SCENE_SIZE_JS))
            time.sleep(0.2)
        assert sizes[-1] > 2 * (STEPS - 1), "trail segments missing from the page"
        legend = browser.evaluate(LEGEND_JS)
        shots["legend"] = browser.screenshot()
        # The key's swatches share the scene's colours: hidden for the colour counts.
        browser.evaluate(f"document.getElementById('{LEGEND_ID}').style.display = 'none'")
        duration = STEPS / (1.0 / TIME_STEP)
        for name, at in (("load", 0.0), ("middle", 0.5 * duration)):
            browser.evaluate(f"viewer.animator.pause(); viewer.animator.seek({at});")
            browser.evaluate(NEXT_FRAMES_JS, await_promise=True)
            shots[name] = browser.screenshot()
        errors = browser.page_errors()
        console = browser.console_messages()
    elapsed = time.monotonic() - started

    SCREENSHOT.parent.mkdir(parents=True, exist_ok=True)
    SCREENSHOT.write_bytes(shots["legend"])
    SCREENSHOT.with_name("animation_screenshot_middle.png").write_bytes(shots["middle"])

    assert errors == [], f"page errors: {errors}\nconsole: {console}"
    # The key is shown, whole, inside the window, and names the target and the estimate.
    left, top, right, bottom = legend["box"]
    assert legend["shown"] and 0 <= left < right <= WIDTH and 0 <= top < bottom <= HEIGHT
    assert "target (true position)" in legend["text"] and "estimated target" in legend["text"]
    masks = {}
    for name in ("load", "middle"):
        png = shots[name]
        masks[name] = colour_masks(png)
        for thing, mask in masks[name].items():
            count = int(mask.sum())
            # At least a third of the smallest projected area (shading, partial
            # occlusion by the sonars), and not absurdly more (colour leaking).
            low, high = expected[thing] / 3.0, 30.0 * expected[thing]
            assert low < count < high, (
                f"{name}: {count} {thing} pixels, expected {low:.0f}..{high:.0f} "
                f"(screenshot {SCREENSHOT.parent})"
            )
    # The recording moves things: the vehicle is not where it was at load.
    moved = masks["load"]["vehicle"] ^ masks["middle"]["vehicle"]
    assert moved.sum() > 0.5 * expected["vehicle"]
    assert elapsed < 120.0
    print(f"browser test: {elapsed:.1f} s; screenshot {SCREENSHOT}")
