"""The live page and the viewer in a real browser (headless Chromium with software WebGL).

The live page is loaded while `hivox demo --view` runs and again when the run has finished; the
viewer is loaded on the run's output folder. The screenshots are checked for what a person
should see: the model's picture and the 3D view are not blank, and the level colours on them are
those the server's own level picture and the mesh's levels say. Needs Debian's chromium and
python3-pil; skipped without them unless HIVOX_REQUIRE_BROWSER=1 (as in scripts/test).
"""
import json
import os
import re
import shutil
import signal
import subprocess
import time
import urllib.request
from pathlib import Path

import pytest

HIVOX = os.environ.get("HIVOX_BIN", "build/hivox")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
try:
    from PIL import Image
except ImportError:  # pragma: no cover
    Image = None

if os.environ.get("HIVOX_REQUIRE_BROWSER") != "1" and (CHROMIUM is None or Image is None):
    pytest.skip("chromium or python3-pil not installed (scripts/install-deps --browser)",
                allow_module_level=True)

WINDOW = (1400, 1000)
BACKGROUND = (0x15, 0x17, 0x1B)


def chromium(url, *args, timeout=90):
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--use-gl=swiftshader",
           "--enable-unsafe-swiftshader", "--hide-scrollbars", "--disable-gpu-sandbox",
           f"--window-size={WINDOW[0]},{WINDOW[1]}", "--virtual-time-budget=8000", *args, url]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


def dom(url):
    """The page's DOM after its scripts ran: the <body> element's data attributes."""
    out = chromium(url, "--dump-dom").stdout
    body = re.search(r"<body([^>]*)>", out)
    assert body, out[:500]
    return dict(re.findall(r'data-([a-z-]+)="([^"]*)"', body.group(1)))


def screenshot(url, path):
    chromium(url, f"--screenshot={path}")
    assert path.exists(), f"no screenshot of {url}"
    return Image.open(path).convert("RGB")


def fetch(url):
    with urllib.request.urlopen(url, timeout=10) as r:
        return r.read()


def start(args, pattern):
    """Starts hivox; returns the process and the URL it prints."""
    proc = subprocess.Popen([HIVOX, *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    deadline = time.time() + 60
    for line in proc.stdout:
        m = re.search(pattern + r"(http://127\.0\.0\.1:\d+/)", line)
        if m:
            return proc, m.group(1)
        assert time.time() < deadline, "no URL printed"
    raise AssertionError(f"hivox ended without a URL (exit {proc.wait()})")


def hex_rgb(h):
    return tuple(int(h[i:i + 2], 16) for i in (1, 3, 5))


def level_fractions(image, colors, box=None):
    """Fraction of the lit pixels whose hue is each level colour (shading scales a colour, so
    each pixel is compared divided by its brightest channel); plus the lit fraction."""
    if box:
        image = image.crop(box)
    targets = [tuple(c / max(rgb) for c in rgb) for rgb in map(hex_rgb, colors)]
    counts = [0] * len(colors)
    lit = 0
    pixels = list(image.getdata())
    for p in pixels:
        m = max(p)
        if m < 40 or (abs(p[0] - BACKGROUND[0]) < 4 and abs(p[1] - BACKGROUND[1]) < 4
                      and abs(p[2] - BACKGROUND[2]) < 4):
            continue
        lit += 1
        if not targets:
            continue
        n = tuple(c / m for c in p)
        d, k = min((sum((a - b) ** 2 for a, b in zip(n, t)), k) for k, t in enumerate(targets))
        if d < 0.02:
            counts[k] += 1
    return [c / max(lit, 1) for c in counts], lit / max(len(pixels), 1)


def rect_box(text):
    x, y, w, h = map(int, text.split(","))
    return (x + 2, y + 2, x + w - 2, y + h - 2)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("browser") / "live"


def test_live_page_during_and_after_a_run(run_dir, tmp_path):
    proc, url = start(["demo", "--frames", "60", "--out", str(run_dir), "--view",
                       "--view-fps", "10", "--view-linger", "120"], r"live view: ")
    try:
        # During the run: the page shows it running, with frames and a render.
        while json.loads(fetch(url + "api/status.json"))["frames_done"] < 3:
            time.sleep(0.2)
        during = dom(url)
        status = json.loads(fetch(url + "api/status.json"))
        assert during["state"] in ("running", "finished"), during
        assert int(during["frames"]) >= 3
        assert int(during["render-version"]) >= 1
        shot = screenshot(url + "?mode=shaded", tmp_path / "live_running.png")
        _, lit = level_fractions(shot, [], rect_box(during["render-rect"]))
        assert lit > 0.3, f"the model's picture is mostly blank ({lit:.0%} lit)"

        # After the run (the page lingers): the level picture on the page is the server's.
        while json.loads(fetch(url + "api/status.json"))["state"] == "running":
            time.sleep(0.5)
        status = json.loads(fetch(url + "api/status.json"))
        assert status["state"] == "finished"
        after = dom(url + "?mode=levels")
        assert after["state"] == "finished"
        assert int(after["frames"]) == 60
        shot = screenshot(url + "?mode=levels", tmp_path / "live_levels.png")
        shot.save(run_dir.parent / "live_levels.png")
        served_path = tmp_path / "served_levels.png"
        served_path.write_bytes(fetch(url + "api/render/levels.png"))
        served = Image.open(served_path).convert("RGB")
        colors = status["level_colors"]
        on_page, lit = level_fractions(shot, colors, rect_box(after["render-rect"]))
        expected, _ = level_fractions(served, colors)
        assert lit > 0.3
        for level, (a, b) in enumerate(zip(on_page, expected)):
            assert abs(a - b) < 0.05, f"level {level}: {a:.1%} of the page's picture, {b:.1%} of the render"
        assert sum(f > 0.02 for f in expected) >= 2, f"a 3-level run shows one level only: {expected}"
        # The depth panel beside it is not blank either.
        assert "depth_range_m" in status and status["depth_range_m"][1] > status["depth_range_m"][0]
    finally:
        proc.send_signal(signal.SIGINT)  # ends the linger
        out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 0, out
    assert (run_dir / "mesh.ply").exists()


def test_viewer_shows_the_run(run_dir, tmp_path):
    assert (run_dir / "mesh.ply").exists(), "needs the live test's run"
    proc, url = start(["view", str(run_dir), "--seconds", "300"], r"viewer: ")
    try:
        info = json.loads(fetch(url + "api/info.json"))
        page = dom(url + "?color=level")
        assert page["state"] == "ready", page
        assert page["color"] == "level"
        box = rect_box(page["canvas-rect"])
        level_shot = screenshot(url + "?color=level&trajectory=0", tmp_path / "view_level.png")
        level_shot.save(run_dir.parent / "view_level.png")
        fractions, lit = level_fractions(level_shot, info["level_colors"], box)
        assert lit > 0.1, f"the 3D view is mostly empty ({lit:.0%} drawn)"
        vertices = info["vertices_per_level"]
        total = sum(vertices)
        for level, (f, n) in enumerate(zip(fractions, vertices)):
            if n / total > 0.1:
                assert f > 0.02, f"level {level} has {n / total:.0%} of the vertices, {f:.1%} of the view"
            if n == 0:
                assert f < 0.005, f"level {level} has no vertices but {f:.1%} of the view"
        assert sum(fractions) > 0.6, f"most drawn pixels should be level colours: {fractions}"
        rgb_shot = screenshot(url + "?color=rgb", tmp_path / "view_rgb.png")
        rgb_fractions, rgb_lit = level_fractions(rgb_shot, info["level_colors"], box)
        assert rgb_lit > 0.1
        assert sum(rgb_fractions) < 0.5 * sum(fractions), "colour by RGB still shows level colours"
        # The page's own files and the run's files; nothing else.
        assert fetch(url + "files/stats.json")
        with pytest.raises(urllib.error.HTTPError):
            fetch(url + "files/..%2fsecret")
    finally:
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, out
    assert "served" in out
