"""Headless Chromium screenshots over the DevTools protocol on a pipe (``--remote-debugging-pipe``:
JSON messages separated by NUL on file descriptors 3 and 4), standard library only.

``chromium --screenshot`` takes its picture at the page's load event, before a WebAssembly app
such as rerun's web viewer has fetched and drawn its data; over the protocol we take pictures
until ``ready(png_bytes)`` says the page shows what we wait for.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
from typing import Callable


def chromium_path() -> str | None:
    """Debian's ``chromium`` (or ``chromium-browser``), if installed."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


class _Pipe:
    def __init__(self, to_browser: int, from_browser: int) -> None:
        self.w, self.r = to_browser, from_browser
        self.buf = b""
        self.next_id = 0

    def send(self, method: str, params: dict | None = None, session: str | None = None, timeout: float = 30.0) -> dict:
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self.w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            while b"\0" not in self.buf:
                chunk = os.read(self.r, 1 << 20)
                if not chunk:
                    raise RuntimeError(f"chromium closed the pipe during {method}")
                self.buf += chunk
            raw, _, self.buf = self.buf.partition(b"\0")
            reply = json.loads(raw)
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
        raise TimeoutError(method)


def screenshot(url: str, out: str, *, ready: Callable[[bytes], bool] = lambda png: True, timeout_s: float = 90.0,
               width: int = 1600, height: int = 1000, every_s: float = 2.0) -> tuple[bool, float]:
    """Open ``url`` in headless Chromium (every host but 127.0.0.1 unresolvable) and save a PNG to
    ``out`` once ``ready(png)`` is true or ``timeout_s`` has passed.

    Returns ``(ready, seconds)``.
    """
    exe = chromium_path()
    if exe is None:
        raise FileNotFoundError("chromium is not installed")
    to_r, to_w = os.pipe()       # we write commands, chromium reads fd 3
    from_r, from_w = os.pipe()   # chromium writes replies on fd 4
    profile = tempfile.mkdtemp(prefix="loopwatch-chromium-")
    args = [exe, "--headless=new", "--no-sandbox", "--remote-debugging-pipe", f"--user-data-dir={profile}",
            "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-first-run", "--disable-extensions",
            "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1", f"--window-size={width},{height}",
            "about:blank"]

    def fds() -> None:  # in the child: the pipe ends become fds 3 and 4 (the originals may be 3..6)
        r, w = os.dup(to_r), os.dup(from_w)
        os.dup2(r, 3)
        os.dup2(w, 4)

    proc = subprocess.Popen(args, preexec_fn=fds, close_fds=False, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    os.close(to_r)
    os.close(from_w)
    pipe = _Pipe(to_w, from_r)
    t0 = time.monotonic()
    ok = False
    try:
        target = pipe.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = pipe.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        pipe.send("Emulation.setDeviceMetricsOverride",
                  {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False}, session)
        pipe.send("Page.navigate", {"url": url}, session)
        png = b""
        while time.monotonic() - t0 < timeout_s:
            time.sleep(every_s)
            png = base64.b64decode(pipe.send("Page.captureScreenshot", {"format": "png"}, session)["data"])
            if ready(png):
                ok = True
                break
        with open(out, "wb") as fh:
            fh.write(png)
        try:
            pipe.send("Browser.close", timeout=5.0)
        except (RuntimeError, TimeoutError, OSError):
            pass
    finally:
        os.close(to_w)
        os.close(from_r)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        shutil.rmtree(profile, ignore_errors=True)
    return ok, time.monotonic() - t0
