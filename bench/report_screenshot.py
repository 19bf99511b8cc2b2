"""Screenshots of the Snakemake report with headless Chromium, to see that it shows the tables and figures.

    python bench/report_screenshot.py [REPORT] [--out DIR]

REPORT defaults to the report in the results directory (``report.html`` in
`freqbrdf.layout.RESULTS`, as ``make report`` writes it), DIR to
``report_screenshots`` beside it.

The report is a single-page React app whose first view is the workflow
description; the tables and figures open on click. For each view below this
script writes a copy of the report with a few lines of JavaScript that open
that result (as a click in the navigation would: the caption on the left, the
result on the right), opens the copy in headless Chromium over the DevTools
pipe (``bench/devtools.py``), waits until the result is shown (a figure's
image decoded, a table's frame loaded) and only then takes the screenshot,
with the text the window shows beside it (``{view}.txt``, the page's
``innerText``; a table's frame has its own):

- ``workflow.png``: the landing page (the run's summary: what was run, the
  claims with their verdicts, the headline numbers; then the rule graph);
- ``tables.png``: the table ``tables.html`` (`freqbrdf.layout.TABLE`; the paper's Tables 1, 2, 4, 5);
- ``claims.png``: the table ``claims.html``;
- ``maps.png``, ``relight.png``: the first capture's figures (`freqbrdf.layout.CAPTURE_FIGURE`).

Chromium comes from Debian's ``chromium`` package (``make report-deps``). Exit
status 2 means no Chromium was found.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

from devtools import DevTools

from freqbrdf import layout

# The report and its screenshots, in the results directory (no layout template of their own yet).
REPORT = layout.located(layout.REPORT)
SCREENSHOTS = layout.located(layout.REPORT_SCREENSHOTS)

# Names a Chromium build goes by on Debian, Ubuntu and in Google's packages.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "chromium-headless-shell", "google-chrome", "google-chrome-stable")

# What a view waits for before its screenshot (JavaScript, truthy when shown):
# the opened figure's image decoded, or the table's frame loaded; the landing
# page's rule graph is drawn by Vega into an SVG.
SHOWN_JS = {
    # the opened result's own image: the landing page may hold data: images of its own, which
    # once let a screenshot of it pass for the figure's
    "img": "(() => { const uri = window.reportScreenshotOpened; return uri !== undefined &&"
           " [...document.images].some((i) => i.src === uri && i.complete && i.naturalWidth > 0); })()",
    "html": "(() => { const f = document.querySelector('iframe'); return window.reportScreenshotOpened !== undefined"
            " && f !== null && f.dataset.loaded === '1'; })()",
    None: "document.readyState === 'complete' && document.querySelector('svg') !== null",
}
# A frame of a data: address has an opaque origin: its load event is the only sign it is shown.
MARK_LOADED_FRAMES_JS = """
<script>
document.addEventListener("load", function (e) {
  if (e.target.tagName === "IFRAME") e.target.dataset.loaded = "1";
}, true);
</script>
"""

# View name -> (suffix of the result path to open, window size). None: the landing page.
VIEWS: dict[str, tuple[str | None, tuple[int, int]]] = {
    "workflow": (None, (1600, 1000)),
    "tables": (layout.fill(layout.TABLE, name="tables.html"), (1800, 1500)),
    "claims": (layout.fill(layout.TABLE, name="claims.html"), (1800, 1000)),
    "maps": ("/maps.png", (1600, 1900)),
    "relight": ("/relight.png", (1800, 1100)),
}

# Opens one result the way the report's navigation does. `app`, `results` and
# `categories` are globals of the report page (Snakemake 9 html_reporter).
OPEN_RESULT_JS = """
<script>
window.addEventListener("load", function () {
  setTimeout(function () {
    var suffix = %s;
    var path = Object.keys(results).sort().find(function (p) { return p.endsWith(suffix); });
    if (path === undefined) { document.title = "report_screenshot: no result ending in " + suffix; return; }
    var category, subcategory;
    Object.keys(categories).forEach(function (cat) {
      Object.keys(categories[cat]).forEach(function (sub) {
        if (categories[cat][sub].indexOf(path) >= 0) { category = cat; subcategory = sub; }
      });
    });
    var mime = results[path].mime_type;
    app.setView({
      navbarMode: "resultinfo", category: category, subcategory: subcategory, resultPath: path,
      content: mime === "text/html" ? "html" : "img", contentPath: results[path].data_uri
    });
    window.reportScreenshotOpened = results[path].data_uri;
  }, 300);
});
</script>
"""


def find_chromium() -> str | None:
    """Path of a Chromium executable on PATH, or None."""
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


def page_for_view(report_html: str, suffix: str | None) -> str:
    """The report's HTML, with a script that opens the result ending in ``suffix`` (None: unchanged)."""
    if suffix is None:
        return report_html
    script = MARK_LOADED_FRAMES_JS + OPEN_RESULT_JS % json.dumps(suffix)
    head, sep, tail = report_html.rpartition("</body>")
    if not sep:
        raise ValueError("report HTML has no </body>: not a Snakemake report?")
    return head + script + sep + tail


def shown_expression(suffix: str | None) -> str:
    """JavaScript that is truthy once the view of ``suffix`` is on screen (`SHOWN_JS`)."""
    if suffix is None:
        return SHOWN_JS[None]
    return SHOWN_JS["html" if suffix.endswith(".html") else "img"]


def screenshot(chromium: str, page: Path, out: Path, size: tuple[int, int], suffix: str | None,
               timeout_s: float = 120.0) -> None:
    """Open ``page`` headless, wait until the view is shown, then write a PNG of the window
    and, beside it (``.txt``), the page's text.

    Raises RuntimeError when the view is not shown within ``timeout_s``.
    """
    browser = DevTools(chromium, size, webgl=False)  # the report's pages draw no WebGL
    try:
        browser.call("Page.navigate", session=True, url=page.resolve().as_uri())
        if not browser.wait_for(shown_expression(suffix), timeout_s):
            raise RuntimeError(f"{page}: the view of {suffix or 'the landing page'} was not shown within {timeout_s:.0f} s")
        browser.screenshot(out)
        Path(out).with_suffix(".txt").write_text(browser.evaluate("document.body.innerText") or "", encoding="utf-8")
    finally:
        browser.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("report", type=Path, nargs="?", default=REPORT,
                        help=f"self-contained report (snakemake --report X.html; default {REPORT})")
    parser.add_argument("--out", type=Path, default=SCREENSHOTS, help=f"output directory (default {SCREENSHOTS})")
    parser.add_argument("--views", nargs="+", choices=list(VIEWS), default=list(VIEWS))
    parser.add_argument("--chromium", help="Chromium executable (default: found on PATH)")
    args = parser.parse_args(argv)

    chromium = args.chromium or find_chromium()
    if chromium is None:
        print(f"no Chromium on PATH (looked for {', '.join(CHROMIUM_NAMES)}); run `make report-deps`",
              file=sys.stderr)
        return 2
    report_html = args.report.read_text(encoding="utf-8")
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="report_screenshot_") as tmp:
        for name in args.views:
            suffix, size = VIEWS[name]
            page = Path(tmp) / f"{name}.html"
            page.write_text(page_for_view(report_html, suffix), encoding="utf-8")
            screenshot(chromium, page, args.out / f"{name}.png", size, suffix)
            print(args.out / f"{name}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
