"""Screenshot of a capture viewer (results/viewer/.../viewer.html) once its models have loaded.

    python bench/viewer_screenshot.py results/viewer/sphere/studio/gt/viewer.html --out shots \
        [--shot "plain=rotate=0" --shot "sunny=rotate=0&env=sunny&entropy=1"] [--size 1400x900]

Writes shots/NAME.png for each --shot, the page's address options applied in
turn, and prints a JSON line: the page's status ("ready" or "error"), its
status text, where each panel is on the screenshots (CSS pixels = screenshot
pixels here) and the PNGs written.

Chromium's ``--screenshot`` flag cannot wait for the page: the models' textures
decode outside its virtual time, so a timed screenshot may show empty panels.
This script drives headless Chromium over the DevTools protocol on a pipe
(``--remote-debugging-pipe``: commands on fd 3, replies on fd 4, each a JSON
message ended by a NUL byte), polls ``document.body.dataset.status`` until the
viewer says it is ready, and only then asks for the screenshot.

Exit status 2: no Chromium found (as bench/report_screenshot.py); 1: the page
reported an error or did not get ready in time.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from report_screenshot import CHROMIUM_NAMES, find_chromium


class DevTools:
    """A headless Chromium and one page in it, driven over ``--remote-debugging-pipe``."""

    def __init__(self, chromium: str, size: tuple[int, int]) -> None:
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()
        # WebGL needs SwiftShader where there is no GPU; Chromium asks for the opt-in flag.
        command = [chromium, "--headless", "--no-sandbox", "--disable-dev-shm-usage", "--hide-scrollbars",
                   "--no-first-run", "--mute-audio", "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
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


def viewer_screenshots(chromium: str, page: Path, shots: dict[str, str], out: Path,
                       size: tuple[int, int] = (1400, 900), timeout_s: float = 120.0) -> dict:
    """Open ``page``, wait until it is ready or failed, then write ``out/NAME.png`` for each
    ``NAME: options`` of ``shots`` (the page's address options, applied in turn without reloading).

    Returns
    -------
    dict
        ``status`` ("ready", "error", or "loading" on timeout), ``message`` (the page's status
        text), ``panels`` (name, left, top, width, height of each panel's drawing area) and
        ``shots`` (name -> PNG path; none unless ready).
    """
    browser = DevTools(chromium, size)
    try:
        browser.call("Page.navigate", session=True, url=page.resolve().as_uri())
        deadline = time.monotonic() + timeout_s
        status = None
        while time.monotonic() < deadline:
            status = browser.evaluate("document.body ? document.body.dataset.status : null")
            if status in ("ready", "error"):
                break
            time.sleep(0.2)
        message = browser.evaluate("document.getElementById('status') ? document.getElementById('status').textContent : ''")
        panels = json.loads(browser.evaluate("document.body.dataset.panels || '[]'"))
        written = {}
        out.mkdir(parents=True, exist_ok=True)
        for name, options in shots.items() if status == "ready" else ():
            # set the address options, then let two frames draw with them
            browser.evaluate(f"""new Promise((done) => {{
                const drawn = () => requestAnimationFrame(() => requestAnimationFrame(() => done(true)));
                if (location.hash.slice(1) === {json.dumps(options)}) drawn();
                else {{ addEventListener("hashchange", drawn, {{once: true}}); location.hash = {json.dumps(options)}; }}
            }})""", await_promise=True)
            shot = browser.call("Page.captureScreenshot", session=True, format="png")
            written[name] = str(out / f"{name}.png")
            Path(written[name]).write_bytes(base64.b64decode(shot["data"]))
        return {"status": status or "loading", "message": message, "panels": panels, "shots": written}
    finally:
        browser.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("page", type=Path, help="a viewer.html")
    parser.add_argument("--out", type=Path, required=True, help="directory for the PNGs")
    parser.add_argument("--shot", action="append", metavar="NAME=OPTIONS",
                        help="a screenshot NAME.png with the page's address OPTIONS (repeatable; "
                             "default: viewer=rotate=0)")
    parser.add_argument("--size", default="1400x900", help="window size WIDTHxHEIGHT")
    parser.add_argument("--chromium", help="Chromium executable (default: found on PATH)")
    args = parser.parse_args(argv)
    chromium = args.chromium or find_chromium()
    if chromium is None:
        print(f"no Chromium on PATH (looked for {', '.join(CHROMIUM_NAMES)}); run `make report-deps`", file=sys.stderr)
        return 2
    shots = dict(shot.split("=", 1) for shot in (args.shot or ["viewer=rotate=0"]))
    width, height = (int(v) for v in args.size.split("x"))
    result = viewer_screenshots(chromium, args.page, shots, args.out, (width, height))
    print(json.dumps(result))
    return 0 if result["status"] == "ready" else 1


if __name__ == "__main__":
    sys.exit(main())
