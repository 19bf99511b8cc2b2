"""Screenshot of a capture viewer (`freqbrdf.layout.VIEWER`) once its models have loaded.

    python bench/viewer_screenshot.py VIEWER --out shots \
        [--shot "plain=rotate=0" --shot "sunny=rotate=0&env=sunny&overlay=uncertainty"] [--size 1400x900]

VIEWER is a capture's ``viewer.html`` (`freqbrdf.layout.VIEWER`, e.g.
sphere/studio's with gt poses, in the results directory).

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
import sys
import time
from pathlib import Path

from devtools import DevTools
from report_screenshot import CHROMIUM_NAMES, find_chromium


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
    parser.add_argument("page", type=Path, help="a viewer.html (layout.VIEWER)")
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
