"""A headless Chromium driven over the DevTools protocol on a pipe (used by the screenshot scripts).

Chromium's ``--screenshot`` flag cannot wait for a page: images and textures
decode outside its virtual time, so a timed screenshot may show an empty
figure on a loaded machine. With ``--remote-debugging-pipe`` (commands on fd 3,
replies on fd 4, each a JSON message ended by a NUL byte) a script can poll the
page until it is ready and only then ask for the screenshot.
"""

from __future__ import annotations

import base64
import json
import os
import subprocess
import tempfile
import time
from pathlib import Path


class DevTools:
    """A headless Chromium and one page in it, driven over ``--remote-debugging-pipe``."""

    def __init__(self, chromium: str, size: tuple[int, int], webgl: bool = True) -> None:
        """``webgl``: whether the page draws with WebGL (the viewer). WebGL needs SwiftShader where
        there is no GPU (Chromium asks for the opt-in flag), and compositing through it makes each
        screenshot of a large window take seconds; a page without WebGL (the report) is drawn in
        software, ``--disable-gpu``, in a fraction of that."""
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()
        graphics = ["--enable-unsafe-swiftshader", "--use-angle=swiftshader"] if webgl else ["--disable-gpu"]
        command = [chromium, "--headless", "--no-sandbox", "--disable-dev-shm-usage", "--hide-scrollbars",
                   "--no-first-run", "--mute-audio", *graphics,
                   f"--window-size={size[0]},{size[1]}", "--remote-debugging-pipe", "about:blank"]

        def pipe_ends_at_3_and_4() -> None:
            # Chromium reads fd 3 and writes fd 4. Both ends are copied first, so that
            # placing one cannot overwrite the other; dup2's copies are inheritable,
            # the pipes' own fds are not, and close_fds=False keeps just these open.
            ends = os.dup(to_browser_r), os.dup(from_browser_w)
            os.dup2(ends[0], 3)
            os.dup2(ends[1], 4)

        # A file, not a pipe: Chromium's GL warnings could fill a pipe nobody reads and stall it.
        self._stderr = tempfile.TemporaryFile(mode="w+")
        self.process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=self._stderr,
                                        close_fds=False, preexec_fn=pipe_ends_at_3_and_4)
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._buffer, self._next_id = b"", 0
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        self.call("Emulation.setDeviceMetricsOverride", session=True, width=size[0], height=size[1],
                  deviceScaleFactor=1, mobile=False)

    def call(self, method: str, session: bool = False, **params) -> dict:
        """Send one command and return its result (events in between are dropped)."""
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params}
        if session:
            message["sessionId"] = self.session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        while True:
            while b"\0" not in self._buffer:
                chunk = os.read(self._from_browser, 1 << 20)
                if not chunk:
                    self._stderr.seek(0)
                    raise RuntimeError(f"Chromium closed the DevTools pipe during {method}: {self._stderr.read()[-2000:]}")
                self._buffer += chunk
            raw, self._buffer = self._buffer.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]

    def evaluate(self, expression: str, await_promise: bool = False):
        """The value of a JavaScript expression in the page (with ``await_promise``, of the promise it makes)."""
        return self.call("Runtime.evaluate", session=True, expression=expression, returnByValue=True,
                         awaitPromise=await_promise)["result"].get("value")

    def close(self) -> None:
        try:
            self.call("Browser.close")
        except (RuntimeError, OSError):
            pass
        try:
            self.process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        os.close(self._to_browser)
        os.close(self._from_browser)
        self._stderr.close()

    def wait_for(self, expression: str, timeout_s: float, poll_s: float = 0.2) -> bool:
        """Poll a JavaScript expression until it is truthy; False on timeout."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.evaluate(expression):
                return True
            time.sleep(poll_s)
        return False

    def screenshot(self, out: Path) -> None:
        """Write a PNG of the window after two more frames have been drawn."""
        self.evaluate("new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(() => done(true))))",
                      await_promise=True)
        shot = self.call("Page.captureScreenshot", session=True, format="png")
        Path(out).write_bytes(base64.b64decode(shot["data"]))
