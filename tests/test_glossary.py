"""The glossary has one source (``clfd_bench/metrics/glossary.py``): the README's glossary is
generated from it, and every column header of the results site's leaderboard carries its
definition as a tooltip. No training, no simulation: the site's index page is rendered from a
made-up one-row leaderboard."""

from __future__ import annotations

import os
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import pytest

from clfd_bench.execution.execute import FAILURE_KINDS
from clfd_bench.leaderboard import report
from clfd_bench.metrics import glossary
from clfd_bench.site import build

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
SCRIPT = ROOT / "eval" / "make_readme_glossary.py"


def _script(*args: str) -> subprocess.CompletedProcess:
    """``eval/make_readme_glossary.py`` run with this checkout's ``clfd_bench`` first on the
    path (an editable install may point at another checkout)."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          cwd=ROOT, env={**os.environ, "PYTHONPATH": path})


def test_readme_glossary_is_the_generated_one():
    block = glossary.readme_block(README.read_text(encoding="utf-8"))
    assert block == glossary.markdown(), (
        "README.md's glossary differs from clfd_bench/metrics/glossary.py: edit the module, "
        "then run python eval/make_readme_glossary.py")


def test_script_checks_and_rewrites(tmp_path):
    stale = tmp_path / "README.md"
    text = glossary.replace_readme_block(README.read_text(encoding="utf-8"))
    stale.write_text(text.replace("- **REM**: ", "- **REM**: (edited) "), encoding="utf-8")
    assert _script("--check", "--readme", str(stale)).returncode == 1
    assert _script("--readme", str(stale)).returncode == 0
    assert stale.read_text(encoding="utf-8") == text
    assert _script("--check", "--readme", str(stale)).returncode == 0


def test_script_without_markers_says_what_to_add(tmp_path):
    bare = tmp_path / "README.md"
    bare.write_text("# nothing here\n", encoding="utf-8")
    done = _script("--check", "--readme", str(bare))
    assert done.returncode == 2 and glossary.BEGIN in done.stderr


def test_every_table_column_has_an_entry():
    # leaderboard.md / .csv / .json: the key and the header the Markdown table prints
    # and the site's table, which is written from the same list
    for key, head, group in report.COLUMNS:
        assert key in glossary.GLOSSARY, f"leaderboard column {key!r} has no glossary entry"
        assert glossary.GLOSSARY[key].name == head, key
        assert group in build._GROUPS, key
    # the run page's CL metrics and the failure kinds
    for key in (*build._HEADER_KEYS, *build._RUN_METRICS, *FAILURE_KINDS, "paper_cl_score"):
        assert key in glossary.GLOSSARY, key
    with pytest.raises(KeyError, match="glossary.py"):
        glossary.tooltip("no such column")


class _Headers(HTMLParser):
    """The ``title`` and text of each header cell of the leaderboard table's last head row."""

    def __init__(self) -> None:
        super().__init__()
        self.in_table = self.in_head = False
        self.rows: list[list[dict[str, str]]] = []
        self.cell: dict[str, str] | None = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "table" and attrs.get("id") == "leaderboard-table":
            self.in_table = True
        elif self.in_table and tag == "thead":
            self.in_head = True
        elif self.in_head and tag == "tr":
            self.rows.append([])
        elif self.in_head and tag == "th":
            self.cell = {"title": attrs.get("title") or "", "text": ""}
            self.rows[-1].append(self.cell)

    def handle_endtag(self, tag):
        if tag == "thead":
            self.in_head = self.in_table = False
        elif tag == "th":
            self.cell = None

    def handle_data(self, data):
        if self.cell is not None:
            self.cell["text"] += data.strip()


def _index_html() -> str:
    """The site's index page for a one-row leaderboard that matches a paper table."""
    metrics = {key: {"median": 0.5, "q1": 0.4, "q3": 0.6, "values": [0.4, 0.5, 0.6]}
               for key, *_ in report.COLUMNS}
    doc = {"meta": {"dataset": "helloworld", "profile": "fast"},
           "rows": [{"rank": 1, "method": "hn", "runs_ok": 3, "runs_failed": 0,
                     "paper_rank": 2, "metrics": metrics, "exec_failures": {"task": 2},
                     "not_provided": [], "errors": []}]}
    paper = {"hn": {"CL_score": 0.9, "ACC": 0.97}}
    env = build._environment()
    return env.get_template("index.html").render(
        version="test", dataset="helloworld", built="now", root="", title="t",
        profile="fast", grid="g", table=build._table(doc, paper, {}),
        paper_table="tab:hw_cl_explicit_time", paper_note="", profiles=None, figures=[],
        downloads=[], wall=[], wall_tasks=[], wall_style=build.WALL_STYLE, demo=0,
        videos=False, runs=[])


def test_every_site_column_header_shows_its_definition():
    parser = _Headers()
    parser.feed(_index_html())
    heads = parser.rows[-1]
    keys = ["rank", "method", "paper_rank", "runs", *(k for k, *_ in report.COLUMNS),
            "exec_failures"]
    assert [h["text"] for h in heads][:4] == ["#", "method", "paper #", "runs"]
    assert len(heads) == len(keys)
    for head, key in zip(heads, keys, strict=True):
        assert head["title"], f"site column {head['text']!r} has no tooltip"
        better = glossary.GLOSSARY[key].better  # and which way is better, where one is
        assert head["title"] == glossary.tooltip(key) + (
            f" ({better} is better)" if better else ""), head["text"]
    # the tooltips are plain text: Markdown's backticks and links are gone
    assert not any("`" in h["title"] or "](" in h["title"] for h in heads)
