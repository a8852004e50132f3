"""A static results site for a leaderboard's output folder (``clfd-bench site``).

:func:`build_site` reads a results folder (``leaderboard.json``, its figures and run
directories, through their owner modules) and writes plain HTML, CSS, PNG and mp4 files that
open from disk (``file://``) and from any static host: no server, relative links only.
"""

from __future__ import annotations

from clfd_bench.site.build import WALL_STYLE, SiteResult, build_site

__all__ = ["WALL_STYLE", "SiteResult", "build_site"]
