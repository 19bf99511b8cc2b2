"""Screenshots of the Snakemake report with headless Chromium, to see that it shows the tables and figures.

    python bench/report_screenshot.py results/report.html --out results/report_screenshots

The report is a single-page React app whose first view is the workflow
description; the tables and figures open on click. For each view below this
script writes a copy of the report with a few lines of JavaScript that open
that result (as a click in the navigation would: the caption on the left, the
result on the right), then asks Chromium for a screenshot of the copy:

- ``workflow.png``: the landing page (workflow description and rule graph);
- ``tables.png``: results/tables/tables.html (the paper's Tables 1, 2, 4, 5);
- ``claims.png``: results/tables/claims.html;
- ``maps.png``, ``relight.png``: the first capture's figures.

Chromium comes from Debian's ``chromium`` package (``make report-deps``). Exit
status 2 means no Chromium was found.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

# Names a Chromium build goes by on Debian, Ubuntu and in Google's packages.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "chromium-headless-shell", "google-chrome", "google-chrome-stable")

# View name -> (suffix of the result path to open, window size). None: the landing page.
VIEWS: dict[str, tuple[str | None, tuple[int, int]]] = {
    "workflow": (None, (1600, 1000)),
    "tables": ("results/tables/tables.html", (1800, 1500)),
    "claims": ("results/tables/claims.html", (1800, 1000)),
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
    script = OPEN_RESULT_JS % json.dumps(suffix)
    head, sep, tail = report_html.rpartition("</body>")
    if not sep:
        raise ValueError("report HTML has no </body>: not a Snakemake report?")
    return head + script + sep + tail


def screenshot(chromium: str, page: Path, out: Path, size: tuple[int, int], budget_ms: int = 30000) -> None:
    """Render ``page`` headless and write a PNG of the window.

    ``--virtual-time-budget`` lets the page's scripts (React, Vega) and the
    timer above run before the capture; ``--no-sandbox`` is needed as root.
    At 15 s a figure was once still blank on a loaded machine (image decoding
    does not wait for virtual time); idle virtual time is skipped, so a larger
    budget costs little.
    """
    command = [
        chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--hide-scrollbars",
        "--no-first-run", "--mute-audio", f"--window-size={size[0]},{size[1]}",
        f"--virtual-time-budget={budget_ms}", f"--screenshot={out}", page.resolve().as_uri(),
    ]
    run = subprocess.run(command, capture_output=True, text=True, timeout=180)
    if run.returncode != 0 or not out.is_file():
        raise RuntimeError(f"{chromium} failed (exit {run.returncode}) on {page}:\n{run.stderr[-2000:]}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("report", type=Path, help="self-contained report (snakemake --report X.html)")
    parser.add_argument("--out", type=Path, default=Path("results/report_screenshots"), help="output directory")
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
            screenshot(chromium, page, args.out / f"{name}.png", size)
            print(args.out / f"{name}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
