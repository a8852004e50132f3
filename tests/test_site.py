"""The static results site: built from a small real leaderboard (two methods, two HelloWorld
letters, smoke profile, executed), every file it references exists and decodes, a rebuild
reuses the videos, and in headless Chromium (Debian's, driven by Playwright) the page loads
without console errors, has one leaderboard row and one wall row per method, every video and
image decodes, failed tiles carry their reason and a click on a header sorts the table.

Without Chromium or Playwright the browser tests skip locally and FAIL in CI (``CI`` set):
``.ci/run`` installs both."""

from __future__ import annotations

import os
import shutil
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote

import imageio.v3 as iio
import numpy as np
import pytest

from clfd_bench.execution.saved_run import load_run
from clfd_bench.leaderboard.grid import GridOptions
from clfd_bench.leaderboard.report import leaderboard_runs, paper_values, read_leaderboard
from clfd_bench.leaderboard.runner import run_leaderboard
from clfd_bench.site import build_site

METHODS = ["sg", "ft"]
TASKS = 2
#: Tiny and sparse tiles: software rendering is slow, the checks need no pixels.
STYLE = {"width": 96, "height": 72, "fps": 2.0}
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update",
                 "--disable-sync"]


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    out = tmp_path_factory.mktemp("results")
    result = run_leaderboard(dataset="helloworld", methods=METHODS, profile="smoke", seeds=[0],
                             orders=[0], out=out,
                             options=GridOptions(tasks=TASKS, sim=True, workers=2))
    assert not result.failed
    return out


@pytest.fixture(scope="module")
def site(results):
    out = results / "site"
    built = build_site(results, out, style=STYLE)
    assert built.videos_rendered == len(METHODS) * TASKS and not built.video_errors
    return out, built


class _Refs(HTMLParser):
    """Every href / src / poster of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.refs: list[str] = []

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if name in ("href", "src", "poster") and value and not value.startswith("data:"):
                self.refs.append(value)


def _refs(page: Path) -> list[Path]:
    parser = _Refs()
    parser.feed(page.read_text(encoding="utf-8"))
    for ref in parser.refs:
        assert "://" not in ref and not ref.startswith("/"), f"{page}: non-relative link {ref}"
    return [(page.parent / unquote(ref.split("#")[0])).resolve() for ref in parser.refs]


def test_every_referenced_file_exists_and_decodes(site):
    out, built = site
    assert built.index == out / "index.html"
    assert len(built.pages) == 1 + len(METHODS)  # index + one page per run
    videos = set()
    for page in built.pages:
        for path in _refs(page):
            assert path.is_file(), f"{page.name} references a missing {path}"
            assert path.is_relative_to(out.resolve()), f"{path} is outside the site"
            if path.suffix == ".mp4":
                videos.add(path)
            elif path.suffix == ".png":
                assert iio.imread(path).ndim == 3
    assert len(videos) == len(METHODS) * TASKS
    for video in videos:
        frames = iio.imread(video)
        assert frames.shape[1:] == (STYLE["height"], STYLE["width"], 3) and len(frames) > 1
    assert [p.name for p in out.rglob(".*")] == [".lock"], "temporary files left"


class _Tiles(HTMLParser):
    """(outcome, poster) of every wall tile with a video."""

    def __init__(self) -> None:
        super().__init__()
        self.tiles: list[tuple[str, str]] = []
        self._outcome: str | None = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "figure" and "tile" in (a.get("class") or "").split():
            self._outcome = a["class"].split()[1]
        elif tag == "video" and self._outcome is not None:
            self.tiles.append((self._outcome, a["poster"]))


def test_posters_show_the_recorded_outcome(site):
    """Each tile's poster is its video's closing frame, whose border the re-executed rollout
    colours: it must agree with the outcome the run's execution recorded (the tile's class)."""
    from clfd_bench.viz.video import FAILURE_RGB, SUCCESS_RGB

    out, _ = site
    parser = _Tiles()
    parser.feed((out / "index.html").read_text(encoding="utf-8"))
    assert len(parser.tiles) == len(METHODS) * TASKS
    assert {outcome for outcome, _ in parser.tiles} <= {"success", "failure"}
    for outcome, poster in parser.tiles:
        corner = iio.imread(out / poster)[1, 1, :3].astype(int)
        want = SUCCESS_RGB if outcome == "success" else FAILURE_RGB
        other = FAILURE_RGB if outcome == "success" else SUCCESS_RGB
        assert np.abs(corner - want).sum() < np.abs(corner - other).sum(), (poster, outcome)


def test_rebuild_reuses_videos_and_keeps_the_pages(site, results):
    out, _ = site
    again = build_site(results, out, style=STYLE)
    assert again.videos_rendered == 0 and again.videos_reused == len(METHODS) * TASKS
    assert not again.video_errors


def test_killed_build_resumes_without_half_written_files(results, tmp_path):
    """SIGKILL while a tile's video is being written: the next build removes the temporary
    file, keeps the finished tiles and renders only the missing ones."""
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "site"
    cmd = [sys.executable, "-m", "clfd_bench.cli.main", "site", str(results), "--out",
           str(out), "--size", f"{STYLE['width']}x{STYLE['height']}", "--fps",
           str(STYLE["fps"]), "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    try:
        # Kill once one tile is finished and the next one is being written.
        while time.monotonic() < deadline and proc.poll() is None:
            done = [p for p in out.rglob("*.mp4") if not p.name.startswith(".")]
            if done and list(out.rglob(".*.tmp.mp4")):
                break
            time.sleep(0.05)
        assert proc.poll() is None, f"the build ended before it was killed: {proc.stderr.read()}"
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.stderr.close()
    finished = {p for p in out.rglob("*.mp4") if not p.name.startswith(".")}
    assert finished and list(out.rglob(".*.tmp.mp4"))
    for video in finished:  # every visible video is whole
        assert len(iio.imread(video)) > 1
    again = build_site(results, out, style=STYLE)
    assert again.videos_reused == len(finished)
    assert again.videos_rendered == len(METHODS) * TASKS - len(finished)
    assert [p.name for p in out.rglob(".*")] == [".lock"]


def test_wall_outcomes_are_the_runs_executions(site, results):
    out, _ = site
    html = (out / "index.html").read_text(encoding="utf-8")
    doc = read_leaderboard(results)
    for run in leaderboard_runs(results, doc):
        saved = load_run(run.path)
        for j in range(saved.num_learned):
            ex = saved.execution(j)
            assert ex is not None and len(ex.success) == 8
            if not ex.success[0]:
                assert ex.reasons[0] and ex.kinds[0]
                # Jinja2 escapes the reason; the escaped text is on the page.
                assert ex.reasons[0].replace("'", "&#39;").replace('"', "&#34;") in html


def test_not_a_results_dir_says_what_to_run(tmp_path, capsys):
    from clfd_bench.cli.main import main

    assert main(["site", str(tmp_path), "--out", str(tmp_path / "site")]) == 2
    err = capsys.readouterr().err
    assert "is not a results folder: it has no leaderboard.json" in err
    assert "bash run.sh main" in err
    assert not (tmp_path / "site").exists()


def test_bad_demo_is_refused_before_anything_is_written(results, tmp_path, capsys):
    from clfd_bench.cli.main import main

    assert main(["site", str(results), "--out", str(tmp_path / "site"), "--demo", "8"]) == 2
    err = capsys.readouterr().err
    assert "--demo 8: helloworld/" in err and "has demos 0..7" in err
    assert not (tmp_path / "site").exists()


def test_paper_values_are_the_papers_table():
    from clfd_bench.metrics.paper_numbers import cl_table

    doc = {"paper": {"table": "tab:hw_cl_explicit_time", "dataset": "helloworld",
                     "variant": "t"}}
    values = paper_values(doc)
    assert set(values) == {"sg", "ft", "rep", "si", "mas", "hn", "chn"}
    assert values["hn"] == cl_table("helloworld", "t")["HN"]
    assert paper_values({"paper": {"table": None, "reason": "no table"}}) == {}


# ----------------------------------------------------------------------------- browser
def _chromium():
    """(sync_playwright, executable) or skip (locally) / fail (CI) naming what is missing."""
    in_ci = os.environ.get("CI", "").lower() not in ("", "0", "false")
    missing = None
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        sync_playwright = None
        missing = "playwright is not installed (pip install -e '.[dev]')"
    exe = shutil.which("chromium") or "/usr/bin/chromium"
    if missing is None and not os.access(exe, os.X_OK):
        missing = "Chromium is not installed (apt-get install -y chromium)"
    if missing:
        if in_ci:
            pytest.fail(f"the browser test needs a headless browser in CI: {missing}")
        pytest.skip(missing)
    return sync_playwright, exe


@pytest.fixture(scope="module")
def browser():
    """Debian's Chromium, headless, with a fresh profile (Playwright makes one per launch)."""
    sync_playwright, exe = _chromium()
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS)
        yield b
        b.close()


def _open(browser, path: Path):
    page = browser.new_page(viewport={"width": 1400, "height": 900})
    problems: list[str] = []
    page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}")
            if m.type in ("error", "warning") else None)
    page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
    # A media element cancels its own range request when it is told to load again or to
    # suspend (net::ERR_ABORTED, nothing a reader sees); any other failed request is a problem.
    page.on("requestfailed", lambda r: None if (r.failure == "net::ERR_ABORTED"
                                                and r.url.endswith(".mp4"))
            else problems.append(f"request failed: {r.url} ({r.failure})"))
    page.goto(path.as_uri())
    page.wait_for_load_state("load")
    return page, problems


_MEDIA_READY = """() => {
  const videos = Array.from(document.querySelectorAll('video'));
  const images = Array.from(document.querySelectorAll('img'));
  return videos.every(v => v.readyState >= 2 || v.error)
      && images.every(i => i.complete);
}"""
_MEDIA = """() => ({
  videos: Array.from(document.querySelectorAll('video')).map(v => ({
    src: v.getAttribute('src'), ready: v.readyState, duration: v.duration,
    width: v.videoWidth, error: v.error ? v.error.message || String(v.error.code) : null})),
  images: Array.from(document.querySelectorAll('img')).map(i => ({
    src: i.getAttribute('src'), width: i.naturalWidth}))
})"""


def _check_media(page, expect_videos: int) -> None:
    for video in page.query_selector_all("video"):
        video.evaluate("v => { v.preload = 'auto'; if (v.readyState < 2) v.load(); }")
    page.wait_for_function(_MEDIA_READY, timeout=30_000)
    media = page.evaluate(_MEDIA)
    assert len(media["videos"]) == expect_videos
    for v in media["videos"]:
        assert v["error"] is None and v["ready"] >= 2, v
        assert v["duration"] > 0 and v["width"] == STYLE["width"], v
    for image in media["images"]:
        assert image["width"] > 0, f"image does not decode: {image['src']}"
    posters = page.evaluate("""() => Promise.all(
      Array.from(document.querySelectorAll('video[poster]')).map(v => new Promise(done => {
        const img = new Image();
        img.onload = () => done(img.naturalWidth);
        img.onerror = () => done(0);
        img.src = v.poster;
      })))""")
    assert posters and all(w > 0 for w in posters), "a poster does not decode"


def test_index_in_headless_chromium(site, browser):
    out, _ = site
    page, problems = _open(browser, out / "index.html")
    rows = page.query_selector_all("#leaderboard-table tbody tr")
    assert sorted(r.get_attribute("data-method") for r in rows) == sorted(METHODS)
    wall = page.query_selector_all("table.wall tbody tr")
    assert sorted(r.get_attribute("data-method") for r in wall) == sorted(METHODS)
    _check_media(page, len(METHODS) * TASKS)
    # A tile plays while the pointer is on it, and stops when it leaves.
    tile = page.locator("video.tile").first
    tile.hover()
    page.wait_for_function("() => !document.querySelector('video.tile').paused", timeout=10_000)
    page.mouse.move(0, 0)
    page.wait_for_function("() => document.querySelector('video.tile').paused", timeout=10_000)
    # Failed tiles are marked and say why.
    for tile in page.query_selector_all("figure.tile.failure"):
        assert tile.query_selector(".reason").inner_text().strip()

    def order() -> list[str]:
        return [r.get_attribute("data-method")
                for r in page.query_selector_all("#leaderboard-table tbody tr")]

    header = page.locator("#leaderboard-table thead tr:last-child th", has_text="method")
    header.click()
    assert order() == sorted(METHODS)
    header.click()
    assert order() == sorted(METHODS, reverse=True)
    params = page.locator("#leaderboard-table thead tr:last-child th", has_text="params")
    params.click()
    sizes = [float(c.get_attribute("data-sort")) for c in page.query_selector_all(
        "#leaderboard-table tbody tr td:nth-last-child(2)")]
    assert sizes == sorted(sizes) and len(set(sizes)) == len(METHODS)
    page.screenshot(path=str(out.parent / "site.png"), full_page=True)
    page.close()
    assert problems == []


def test_run_pages_in_headless_chromium(site, browser):
    out, built = site
    for path in built.pages[1:]:
        page, problems = _open(browser, path)
        assert page.query_selector("img.heatmap") is not None
        _check_media(page, TASKS)
        page.close()
        assert problems == [], path.name


# ----------------------------------------------------------------------------- the table
def test_best_marks_rule():
    from clfd_bench.site.build import best_marks

    assert best_marks([0.5, 0.9, None, 0.7], "higher") == [None, "best", None, None]
    assert best_marks([30.0, 10.0, 50.0], "lower") == [None, "best", None]
    assert best_marks([1.0, 1.0, 0.8], "higher") == ["tie", "tie", None]
    assert best_marks([1.0, 1.0, 1.0], "higher") == [None] * 3  # nobody stands out
    assert best_marks([0.4, None], "higher") == [None, None]  # one value: nothing to compare
    assert best_marks([0.4, 0.5], None) == [None, None]  # a column with no better way


def test_directions_come_from_the_glossary():
    """Every score column of the site says which way is better, and the error-like ones
    (costs, failures, ranks) are lower-is-better."""
    from clfd_bench.leaderboard.report import COLUMNS
    from clfd_bench.metrics.glossary import GLOSSARY

    for key, *_ in COLUMNS:
        assert GLOSSARY[key].better in ("higher", "lower"), key
    lower = {k for k, t in GLOSSARY.items() if t.better == "lower"}
    assert {"train_time_s", "final_params", "exec_failures", "rank", "dtw"} <= lower
    assert GLOSSARY["BWT"].better == GLOSSARY["CL_score"].better == "higher"


#: A made-up leaderboard of three methods (no runs): hn best by CL_score; sg and ft tied for
#: the best ACC at the shown precision (1.000 and 0.999 both show 1.00); ft the fastest, the
#: best BWT and the fewest failures; every MS equal (no mark).
_SYNTH = {"sg": {"CL_score": 0.70, "ACC": 1.0, "BWT": -0.5, "MS": 1.0, "train_time_s": 30.0},
          "ft": {"CL_score": 0.50, "ACC": 0.999, "BWT": 0.0, "MS": 1.0, "train_time_s": 10.4},
          "hn": {"CL_score": 0.90, "ACC": 0.80, "BWT": -0.1, "MS": 1.0, "train_time_s": 50.0}}
_SYNTH_FAILS = {"sg": 3, "ft": 0, "hn": 5}


@pytest.fixture(scope="module")
def synthetic_site(tmp_path_factory):
    import json

    from clfd_bench.leaderboard.report import COLUMNS, LEADERBOARD_JSON

    out = tmp_path_factory.mktemp("synthetic")
    rows = []
    for rank, method in enumerate(sorted(_SYNTH, key=lambda m: -_SYNTH[m]["CL_score"]), 1):
        values = _SYNTH[method]
        rows.append({
            "rank": rank, "method": method, "runs_ok": 1, "runs_failed": 0, "paper_rank": None,
            "paper_cl_score": None, "errors": [], "not_provided": [],
            "exec_failures": {"task": _SYNTH_FAILS[method]},
            "metrics": {key: {"median": values.get(key), "q1": values.get(key),
                              "q3": values.get(key),
                              "values": [values[key]] if key in values else []}
                        for key, *_ in COLUMNS}})
    doc = {"schema_version": 1, "rows": rows, "paper": {"table": None, "reason": "made up"},
           "meta": {"dataset": "helloworld", "methods": list(_SYNTH), "profile": "smoke",
                    "seeds": [0], "orders": [0], "node": "t", "tasks": 2, "sim": True,
                    "runs": {}, "figures": []}}
    (out / LEADERBOARD_JSON).write_text(json.dumps(doc), encoding="utf-8")
    build_site(out, out / "site", videos=False)
    return out / "site"


_COLUMN = """key => {
  const heads = Array.from(document.querySelectorAll(
      '#leaderboard-table thead tr:last-child th'));
  const col = heads.findIndex(th => th.dataset.key === key);
  return Array.from(document.querySelectorAll('#leaderboard-table tbody tr')).map(tr => {
    const td = tr.cells[col];
    const mark = td.querySelector('.mark');
    return [tr.dataset.method, td.classList.contains('best'), td.classList.contains('tie'),
            mark ? mark.textContent : null];
  });
}"""


def test_first_click_sorts_best_first_and_marks_the_best(synthetic_site, browser):
    page = browser.new_page(viewport={"width": 1280, "height": 800})
    page.goto((synthetic_site / "index.html").as_uri())

    def order() -> list[str]:
        return [r.get_attribute("data-method")
                for r in page.query_selector_all("#leaderboard-table tbody tr")]

    def click(key: str) -> list[str]:
        page.locator(f"#leaderboard-table th[data-key='{key}']").click()
        return order()

    assert order() == ["hn", "sg", "ft"]  # by rank
    # Higher is better: the first click puts the highest first, the second reverses.
    assert click("CL_score") == ["hn", "sg", "ft"]
    assert page.get_attribute("th[data-key='CL_score']", "aria-sort") == "descending"
    assert click("CL_score") == ["ft", "sg", "hn"]
    assert click("BWT") == ["ft", "hn", "sg"]  # 0.0 > -0.1 > -0.5
    # Lower is better (costs, failures): the lowest first.
    assert click("train_time_s") == ["ft", "sg", "hn"]
    assert page.get_attribute("th[data-key='train_time_s']", "aria-sort") == "ascending"
    assert click("exec_failures") == ["ft", "sg", "hn"]
    assert "higher is better" in page.get_attribute("th[data-key='ACC']", "title")
    assert "lower is better" in page.get_attribute("th[data-key='train_time_s']", "title")

    marks = {key: {m: (best, tie, mark) for m, best, tie, mark in page.evaluate(_COLUMN, key)}
             for key in ("CL_score", "ACC", "MS", "train_time_s", "BWT", "exec_failures")}
    assert marks["CL_score"] == {"hn": (True, False, "★"), "sg": (False, False, None),
                                 "ft": (False, False, None)}
    # A tie at the shown precision is marked on both cells.
    assert marks["ACC"] == {"sg": (True, True, "★="), "ft": (True, True, "★="),
                            "hn": (False, False, None)}
    assert not any(best for best, _, _ in marks["MS"].values())  # all equal: no mark
    for key in ("train_time_s", "BWT", "exec_failures"):
        assert [m for m, (best, _, _) in marks[key].items() if best] == ["ft"], key
    page.close()


def test_tables_fit_a_laptop_and_scroll_under_their_key_columns(synthetic_site, browser):
    """At 1280 px nothing is off the page; in a narrow window the leaderboard scrolls inside
    its own box, its rank and method columns staying in view."""
    page = browser.new_page(viewport={"width": 1280, "height": 800})
    page.goto((synthetic_site / "index.html").as_uri())
    assert page.evaluate("document.documentElement.scrollWidth") <= 1280
    page.set_viewport_size({"width": 640, "height": 800})
    assert page.evaluate("document.documentElement.scrollWidth") <= 640
    box = page.locator("#leaderboard .scroll")
    assert box.evaluate("b => b.scrollWidth > b.clientWidth")  # the table scrolls in its box
    method = page.locator("#leaderboard-table tbody tr:first-child td.key-method")
    rank = page.locator("#leaderboard-table tbody tr:first-child td.key-rank")
    runs = page.locator("#leaderboard-table tbody tr:first-child td:nth-child(3)")
    before = [c.bounding_box()["x"] for c in (rank, method, runs)]
    box.evaluate("b => { b.scrollLeft = 300; }")
    assert box.evaluate("b => b.scrollLeft") > 0
    after = [c.bounding_box()["x"] for c in (rank, method, runs)]
    assert after[:2] == pytest.approx(before[:2], abs=1)  # (border-collapse: half pixels)
    assert after[2] < before[2] - 100  # the other columns scrolled
    page.close()
