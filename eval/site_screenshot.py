"""Screenshots of a results site (``clfd-bench site``) in headless Chromium, for the docs.

    python eval/site_screenshot.py results/site docs/figures/site.png

Writes the top of ``index.html`` (leaderboard) to OUT and its video wall to
``OUT``'s name with ``_wall`` added; prints any console error (and exits 1 on one). Needs
Playwright (the ``dev`` extra) and Debian's Chromium (``apt-get install chromium``); never
``playwright install``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("site", type=Path, help="the site's folder (holds index.html)")
    parser.add_argument("out", type=Path, help="PNG of the page's top")
    parser.add_argument("--width", type=int, default=1280, help="a laptop's window (default)")
    parser.add_argument("--height", type=int, default=800)
    parser.add_argument("--browser", default="/usr/bin/chromium")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    index = (args.site / "index.html").resolve()
    if not index.is_file():
        print(f"{index} not found: build the site first (clfd-bench site RESULTS_DIR)",
              file=sys.stderr)
        return 2
    problems: list[str] = []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=args.browser, args=ARGS)
        page = browser.new_page(viewport={"width": args.width, "height": args.height})
        page.on("console", lambda m: problems.append(f"{m.type}: {m.text}")
                if m.type == "error" else None)
        page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
        page.goto(index.as_uri())
        # the wall shows each tile's poster (its closing frame) until it is pointed at
        page.wait_for_function("() => Array.from(document.images).every(i => i.complete)",
                               timeout=60_000)
        page.wait_for_timeout(2000)  # posters load like images but are not in document.images
        args.out.parent.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(args.out))
        wall = args.out.with_name(f"{args.out.stem}_wall{args.out.suffix}")
        page.locator("#wall").screenshot(path=str(wall))
        browser.close()
    for png in (args.out, wall):  # 256 colours: a third of the size, enough for the docs
        from PIL import Image

        image = Image.open(png).convert("RGB")
        image.quantize(colors=256, method=Image.Quantize.MEDIANCUT,
                       dither=Image.Dither.NONE).save(png, optimize=True)
    for line in problems:
        print(line, file=sys.stderr)
    print(args.out, wall)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
