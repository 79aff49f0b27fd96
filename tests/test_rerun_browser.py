"""Browser check: rerun's web viewer, served on 127.0.0.1, renders the demo recording in headless
Chromium (Debian's ``chromium``; skipped with a message when it is not installed).

The recording comes from ``loopwatch demo`` itself (a small plant, fast).  The page is ready when
the PV and OP series colours of the drill-down plot cover enough pixels and two screenshots in a
row show the same amount of them (the viewer has loaded everything).  ``LOOPWATCH_UPDATE_SCREENSHOT=1`` writes
the picture to ``docs/dashboard.png`` once the page has settled (consecutive pictures differ in
< 0.2 % of the pixels); ``LOOPWATCH_SCREENSHOT_RRD=FILE`` screenshots an existing
recording instead of running the demo (e.g. ``out/demo.rrd`` of ``make demo``).
"""

import io
import os
from pathlib import Path

import numpy as np
import pytest

from adapters.rerun_dashboard import COLORS, _stop, start_web_viewer, web_viewer_url
from service.cli import main as cli_main

from .cdp_screenshot import chromium_path, screenshot
from .conftest import loopback_port

ROOT = Path(__file__).resolve().parents[1]
pytestmark = [pytest.mark.slow, pytest.mark.timeout(1500)]


def colour_pixels(png: bytes, rgb) -> int:
    from PIL import Image

    a = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    return int((np.abs(a - np.array(rgb)).sum(-1) < 30).sum())


def test_web_viewer_renders_the_demo_recording(tmp_path):
    if chromium_path() is None:
        pytest.skip("chromium is not installed (Debian: apt-get install -y chromium); browser check skipped")
    rrd = os.environ.get("LOOPWATCH_SCREENSHOT_RRD")
    if not rrd:
        rrd = str(tmp_path / "demo.rrd")
        code = cli_main(["demo", "--loops", "6", "--duration", "2600", "--speed", "400",
                         "--port", str(loopback_port(62)), "--rerun", f"save:{rrd}"])
        assert code == 0
    grpc, web = loopback_port(63), loopback_port(64)
    viewer = start_web_viewer(rrd, web_port=web, grpc_port=grpc)
    out = ROOT / "docs" / "dashboard.png" if os.environ.get("LOOPWATCH_UPDATE_SCREENSHOT") else tmp_path / "shot.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    settle = bool(os.environ.get("LOOPWATCH_UPDATE_SCREENSHOT"))
    last = {"counts": None, "pixels": None}

    def ready(png: bytes) -> bool:
        counts = (colour_pixels(png, COLORS["pv"]), colour_pixels(png, COLORS["op"]))
        stable, last["counts"] = counts == last["counts"], counts
        if settle:  # for the docs picture: wait until the viewer has ingested everything
            from PIL import Image

            pixels = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
            prev, last["pixels"] = last["pixels"], pixels
            stable = stable and prev is not None and np.mean(np.any(pixels != prev, axis=-1)) < 0.002
        return min(counts) > 500 and stable

    try:
        ok, seconds = screenshot(web_viewer_url(web, f"rerun+http://127.0.0.1:{grpc}/proxy"), str(out),
                                 ready=ready, timeout_s=900.0 if settle else 300.0, every_s=3.0)
    finally:
        _stop(viewer)
    png = out.read_bytes()
    print(f"web viewer screenshot after {seconds:.0f} s: {out}; PV pixels {colour_pixels(png, COLORS['pv'])}, "
          f"OP pixels {colour_pixels(png, COLORS['op'])}")
    assert ok, f"the web viewer did not show the PV and OP plots within {seconds:.0f} s (see {out})"
