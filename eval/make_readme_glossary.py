"""Writes the README's glossary from its single source, ``clfd_bench/metrics/glossary.py``.

    python eval/make_readme_glossary.py            # rewrite the glossary in README.md
    python eval/make_readme_glossary.py --check    # exit 1 if README.md is out of date

Only the lines between the two glossary markers in README.md are replaced; edit the
definitions in ``clfd_bench/metrics/glossary.py``, never in README.md. The results site takes
its column tooltips from the same module, and ``tests/test_glossary.py`` fails while the
README differs from it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from clfd_bench.metrics.glossary import markdown, readme_block, replace_readme_block

README = Path(__file__).resolve().parent.parent / "README.md"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="change nothing; exit 1 if the README's glossary is out of date")
    parser.add_argument("--readme", type=Path, default=README,
                        help="the README to write or check (default: the repository's)")
    args = parser.parse_args()
    text = args.readme.read_text(encoding="utf-8")
    try:
        current = readme_block(text)
    except ValueError as exc:
        print(f"make_readme_glossary: error: {exc}", file=sys.stderr)
        return 2
    if args.check:
        if current == markdown():
            print(f"{args.readme}: the glossary is up to date")
            return 0
        print(f"{args.readme}: the glossary differs from clfd_bench/metrics/glossary.py; run "
              "python eval/make_readme_glossary.py", file=sys.stderr)
        return 1
    new = replace_readme_block(text)
    if new != text:
        args.readme.write_text(new, encoding="utf-8")
        print(f"{args.readme}: glossary rewritten")
    else:
        print(f"{args.readme}: the glossary is up to date")
    return 0


if __name__ == "__main__":
    sys.exit(main())
